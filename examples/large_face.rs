//! The matrix-free path on large contact faces: per scene, the best
//! plain factorisation of K (the baseline: AMD and METIS, analysis and numeric
//! factorisation, each the median of FACTOR_REPS runs, the faster), then a
//! contact problem created matrix-free (the plain factor and the contacts'
//! diagonal blocks of A, nothing c x c), and one cold increment to tol with a
//! method, Tresca and Coulomb: seconds, their ratio to the baseline, err,
//! iterations and the counted peak memory of the library's large allocations;
//! then warm history steps (5 % more load each, warm-started from the step
//! before): the median of their times, with the first one's iterations and
//! err.
//!
//! ```text
//! cargo run --release --example large_face -- [--scenes A,B,..] [--threads K]
//!     [--tol X] [--methods newton,mprgp,auto] [--form matrix-free|dense|auto]
//!     [--warm N]
//! ```
//!
//! `--warm N`: N warm steps (default 1).
//!
//! `--form dense` (or `auto`) creates the problem in that form instead, for the
//! comparison with the dense route (the factor with the contact DOFs last and A).

#[path = "bench/baseline.rs"]
mod baseline;
#[path = "bench/scene.rs"]
#[allow(dead_code)]
mod scene;
#[path = "bench/stats.rs"]
#[allow(dead_code)]
mod stats;

use dualsplit::{ContactProblem, DualForm, Friction, Method, Options};
use scene::{Scene, Spec};
use std::time::Instant;

/// Runs of each plain factorisation whose median is the baseline.
const FACTOR_REPS: usize = 3;

fn main() {
    let mut scenes = vec!["3d-64x64x6".to_string()];
    let mut threads = 1;
    let mut tol = 1e-10;
    let mut methods = vec![Method::Newton];
    let mut form = DualForm::MatrixFree;
    let mut warm_steps = 1usize;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut k = 0;
    while k < args.len() {
        let value = || args.get(k + 1).expect("a value after the flag").clone();
        match args[k].as_str() {
            "--scenes" => scenes = value().split(',').map(str::to_string).collect(),
            "--threads" => threads = value().parse().expect("--threads K"),
            "--tol" => tol = value().parse().expect("--tol X"),
            "--form" => form = DualForm::from_name(&value()).expect("a dual form"),
            "--warm" => warm_steps = value().parse().expect("--warm N"),
            "--methods" => {
                methods = value()
                    .split(',')
                    .map(|s| Method::from_name(s).expect("a method name"))
                    .collect()
            }
            a => panic!("unknown argument {a}"),
        }
        k += 2;
    }
    println!(
        "| scene | n | c | factor s | setup s (x) | of which the dual s | method | law | solve s | increment / factor | err | outer | inner | peak MB | warm step s, median (/ factor, the first one: outer / inner, err) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for name in &scenes {
        let spec = Spec::parse(name).unwrap_or_else(|| panic!("bad scene {name}"));
        let sc = Scene::build(spec);
        // The best plain factorisation (`baseline.rs`).
        let t_factor = baseline::best_plain_factor(&sc.k, threads, FACTOR_REPS);
        let base = Options {
            dual_form: form,
            threads,
            tol,
            ..Options::default()
        };
        for &method in &methods {
            for law in ["tresca", "coulomb"] {
                let friction = if law == "tresca" {
                    Friction::Tresca(&sc.p)
                } else {
                    Friction::Coulomb(&sc.mu)
                };
                let t1 = Instant::now();
                let mut pb = ContactProblem::from_csc_with(
                    sc.d,
                    sc.k.clone(),
                    sc.n.clone(),
                    sc.t.clone(),
                    &base,
                )
                .expect("the scene is valid");
                let t_setup = t1.elapsed().as_secs_f64();
                let opts = Options { method, ..base };
                // The first step of a history (cold), then a warm one with 5 %
                // more load.
                let sol = pb.step(&sc.f, &sc.g, friction, &opts).expect("solves");
                let mut warm = Vec::new();
                for step in 1..=warm_steps.max(1) {
                    let scale = 1.0 + 0.05 * step as f64;
                    let f2: Vec<f64> = sc.f.iter().map(|v| scale * v).collect();
                    warm.push(pb.step(&f2, &sc.g, friction, &opts).expect("solves").report);
                }
                let times: Vec<f64> = warm.iter().map(|r| r.solve_seconds).collect();
                let warm_median = stats::median(&times);
                let r = &sol.report;
                let rw = &warm[0];
                let total = t_setup + r.solve_seconds;
                println!(
                    "| {name} | {} | {} | {t_factor:.2} | {t_setup:.2} ({:.2}) | {:.2} | {} | {law} | {:.2} | {:.2} | {:.1e} | {} | {} | {:.0} | {:.2} ({:.2}, {} / {}, {:.1e}) |",
                    sc.k.nrows,
                    sc.d * sc.g.len(),
                    t_setup / t_factor,
                    pb.dual().condense_seconds(),
                    r.method.name(),
                    r.solve_seconds,
                    total / t_factor,
                    r.err,
                    r.outer_iterations,
                    r.inner_iterations,
                    r.memory_peak as f64 / 1e6,
                    warm_median,
                    warm_median / t_factor,
                    rw.outer_iterations,
                    rw.inner_iterations,
                    rw.err,
                );
            }
        }
    }
}
