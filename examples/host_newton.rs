//! The host-Newton family: a nonlinear host's load increment on the
//! benchmark's 3D scenes, each iteration a new tangent K_j given to
//! `refactor` and a `solve_iteration`. The tangent is a material update of the
//! scene's K: a zone (the middle third of the DOFs, a horizontal layer of
//! the block) made stiffer or softer, K_j = D_j K D_j with D_j = 1 + eps_j on
//! the zone (same pattern, symmetric positive definite), eps_j = 0.04,
//! -0.01, 0.0025, ... tending to zero as a host's tangent settles; the
//! residual is r_j = f - K u_j (the material the loop converges to), the gaps
//! g - N u_j and the slip taken T (u_j - u_n). `--increments K` runs K
//! increments on one handle, the k-th (from 1) with the load f (3 + k) / 4
//! and the same tangents again, from the last increment's u (the handle is
//! created once: the later increments cost what a host's increments cost
//! after its first). Per iteration: refactor and solve in
//! units of the best plain factorisation of K (analysis and numeric factor,
//! AMD or METIS, the median of 3 runs, measured in the same run), the
//! refactor's phases (numeric factor; the drift of the contact blocks, with
//! its solves; the dual: condensation or contact blocks, lumped and layered
//! preconditioners; whether the blocks were kept), Newton steps and products,
//! and |du| / |u|.
//!
//! ```text
//! cargo run --release --example host_newton -- [--scenes A,B,..] [--threads K]
//!     [--iterations J] [--laws tresca,coulomb] [--form auto|dense|matrix-free]
//!     [--host-loop 1|0] [--trace J] [--increments K]
//! cargo run --release --example host_newton -- --baseline-of DIR [--threads K]
//! ```
//!
//! The handles are made with `Options::host_loop` (`--host-loop 0`: without,
//! as a handle for `ds_step` would be).
//!
//! `--trace J` prints iteration J's Newton steps (err, contact states,
//! seconds) as they are taken; J counts from 0 as the table's iteration
//! column does (of the first increment), and the printing is inside that
//! solve's time.
//!
//! `--baseline-of DIR` only times the best plain factorisation of the K of the
//! problem folder DIR (as `c_examples/hyperelastic_host.c --dump DIR` writes
//! its last tangent): the unit of that example's `--times` figures.

#[path = "bench/baseline.rs"]
mod baseline;
#[path = "bench/csc_view.rs"]
mod csc_view;
#[path = "bench/scene.rs"]
#[allow(dead_code)]
mod scene;
#[path = "bench/stats.rs"]
#[allow(dead_code)]
mod stats;

use csc_view::{indices, view};
use dualsplit::{ContactProblem, Csc, DualForm, Friction, HostIteration, Options};
use scene::{Scene, Spec};
use std::time::Instant;

/// Runs of each plain factorisation whose median is the baseline.
const FACTOR_REPS: usize = 3;

fn main() {
    let mut scenes = vec!["3d-40x40x20".to_string(), "3d-64x64x6".to_string()];
    let mut threads = 1;
    let mut iterations = 4usize;
    let mut increments = 1usize;
    let mut laws = vec!["coulomb".to_string()];
    let mut form = DualForm::Auto;
    let mut baseline_of: Option<String> = None;
    let mut host_loop = true;
    let mut trace: Option<usize> = None;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut k = 0;
    while k < args.len() {
        let value = || args.get(k + 1).expect("a value after the flag").clone();
        match args[k].as_str() {
            "--scenes" => scenes = value().split(',').map(str::to_string).collect(),
            "--threads" => threads = value().parse().expect("--threads K"),
            "--iterations" => iterations = value().parse().expect("--iterations J"),
            "--increments" => increments = value().parse().expect("--increments K"),
            "--host-loop" => host_loop = value() == "1",
            "--trace" => trace = Some(value().parse().expect("--trace J")),
            "--laws" => laws = value().split(',').map(str::to_string).collect(),
            "--form" => form = DualForm::from_name(&value()).expect("a dual form"),
            "--baseline-of" => baseline_of = Some(value()),
            a => panic!("unknown argument {a}"),
        }
        k += 2;
    }
    assert!(iterations >= 1, "--iterations J needs J >= 1");
    assert!(increments >= 1, "--increments K needs K >= 1");
    if let Some(dir) = baseline_of {
        let folder = dualsplit::mtx::read_problem(std::path::Path::new(&dir)).expect("a folder");
        let t = baseline::best_plain_factor(&folder.k, threads, FACTOR_REPS);
        println!(
            "{dir}: n = {}, best plain factor ({threads} thread(s), median of {FACTOR_REPS}): {t:.4} s",
            folder.k.nrows
        );
        return;
    }
    for name in &scenes {
        let spec = Spec::parse(name).unwrap_or_else(|| panic!("bad scene {name}"));
        let sc = Scene::build(spec);
        let t_factor = baseline::best_plain_factor(&sc.k, threads, FACTOR_REPS);
        let opts = Options {
            threads,
            dual_form: form,
            tol: 1e-10,
            host_loop,
            ..Options::default()
        };
        for law in &laws {
            let friction = if law == "tresca" {
                Friction::Tresca(&sc.p)
            } else {
                Friction::Coulomb(&sc.mu)
            };
            run(
                name,
                &sc,
                friction,
                law,
                &opts,
                t_factor,
                (iterations, increments, trace),
            );
        }
    }
}

/// K_j = D K D, D = 1 + eps on the zone (the middle third of the DOFs).
fn tangent(k: &Csc, eps: f64) -> Csc {
    let n = k.nrows;
    let zone = |i: usize| (n / 3..2 * n / 3).contains(&i);
    let s = |i: usize| if zone(i) { 1.0 + eps } else { 1.0 };
    let mut out = k.clone();
    for j in 0..n {
        for p in k.col_ptr[j]..k.col_ptr[j + 1] {
            out.values[p] = k.values[p] * s(k.row_idx[p]) * s(j);
        }
    }
    out
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn mul(a: &Csc, x: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; a.nrows];
    a.mul_vec(x, &mut y);
    y
}

fn run(
    name: &str,
    sc: &Scene,
    friction: Friction<'_>,
    law: &str,
    opts: &Options,
    t_factor: f64,
    (iterations, increments, trace): (usize, usize, Option<usize>),
) {
    let eps: Vec<f64> = (0..iterations)
        .map(|j| 0.04 * (-0.25f64).powi(j as i32))
        .collect();
    let t0 = Instant::now();
    let k0 = tangent(&sc.k, eps[0]);
    let mut pb = ContactProblem::from_csc_with(sc.d, k0, sc.n.clone(), sc.t.clone(), opts)
        .expect("the scene is valid");
    let t_create = t0.elapsed().as_secs_f64();
    println!(
        "\n{name} (n = {}, c = {}), {law}, {} thread(s), {} dual: best plain factor {t_factor:.3} s, creation {t_create:.3} s ({:.2} x)",
        sc.k.nrows,
        pb.dual_unknowns(),
        opts.threads,
        if pb.is_matrix_free() {
            "matrix-free"
        } else {
            "dense"
        },
        t_create / t_factor
    );
    let ndof = sc.k.nrows;
    let mut u = vec![0.0; ndof];
    for inc in 0..increments {
        // Increment inc + 1 loads f (1 + inc / 4): the same tangents again,
        // from the last increment's u.
        let scale = 1.0 + 0.25 * inc as f64;
        let f: Vec<f64> = sc.f.iter().map(|x| scale * x).collect();
        println!(
            "| iteration | eps | refactor / factor | of which factor / drift (solves) / dual | solve / factor | outer | inner | open / stick / slip | err | \\|du\\| / \\|u\\| |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|");
        let u_n = u.clone();
        let mut total = if inc == 0 { t_create } else { 0.0 };
        for (j, &e) in eps.iter().enumerate() {
            let (mut t_refactor, mut phases) = (0.0, String::from("-"));
            if inc > 0 || j > 0 {
                let kj = tangent(&sc.k, e);
                let pi = indices(&kj);
                let t0 = Instant::now();
                pb.refactor(&view(&kj, &pi)).expect("refactor");
                t_refactor = t0.elapsed().as_secs_f64();
                let info = pb.last_refactor();
                phases = format!(
                    "{:.3} / {:.3} ({}) / {:.3}{}",
                    info.factor_seconds / t_factor,
                    info.drift_seconds / t_factor,
                    info.drift_solves,
                    info.dual_seconds / t_factor,
                    if info.blocks_kept { ", kept" } else { "" }
                );
            }
            let ku = mul(&sc.k, &u);
            let r: Vec<f64> = f.iter().zip(&ku).map(|(f, k)| f - k).collect();
            let nu = mul(&sc.n, &u);
            let g: Vec<f64> = sc.g.iter().zip(&nu).map(|(g, x)| g - x).collect();
            let taken: Vec<f64> = u.iter().zip(&u_n).map(|(a, b)| a - b).collect();
            let s = mul(&sc.t, &taken);
            let it = HostIteration {
                r: &r,
                g: &g,
                slip: (j > 0).then_some(&s[..]),
                lt_start: None,
            };
            let t0 = Instant::now();
            let mut show = |p: &dualsplit::Progress| {
                println!(
                    "    iteration {j}, Newton step {}: err {:.2e}, open / stick / slip {} / {} / {}, {:.3} s",
                    p.iteration, p.err, p.n_open, p.n_stick, p.n_slip, p.elapsed_seconds
                );
                true
            };
            let monitor: Option<dualsplit::Monitor<'_>> =
                (inc == 0 && trace == Some(j)).then_some(&mut show as dualsplit::Monitor<'_>);
            let sol = pb
                .solve_iteration_monitored(&it, friction, opts, monitor)
                .expect("the iteration");
            let t_solve = t0.elapsed().as_secs_f64();
            let rep = &sol.report;
            assert_eq!(rep.status, dualsplit::SolveStatus::Converged, "{rep:?}");
            for (ui, di) in u.iter_mut().zip(&sol.u) {
                *ui += di;
            }
            total += t_refactor + t_solve;
            println!(
                "| {j} | {e:+.4} | {:.3} | {phases} | {:.3} | {} | {} | {} / {} / {} | {:.1e} | {:.1e} |",
                t_refactor / t_factor,
                t_solve / t_factor,
                rep.outer_iterations,
                rep.inner_iterations,
                rep.n_open,
                rep.n_stick,
                rep.n_slip,
                rep.err,
                norm(&sol.u) / norm(&u)
            );
        }
        println!(
            "whole increment {} ({}{iterations} iterations): {:.2} factorisations, {:.2} per iteration",
            inc + 1,
            if inc == 0 { "creation, " } else { "" },
            total / t_factor,
            total / t_factor / iterations as f64
        );
    }
}
