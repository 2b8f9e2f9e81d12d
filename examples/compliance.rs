//! Interface compliance: per scene, the best plain factorisation of
//! K (the baseline, as in `history`), then one contact problem solved cold,
//! rigid and with a compliant interface at three stiffnesses, and a 10-step
//! history (press, then shear) per law. A contact's stiffness is measured in
//! units of its own: c_N,i = s / A_ii (A_ii the contact's normal entry of the
//! condensed dual, the inverse of the body's stiffness under that node), and
//! k_T,i = s / A_tt for its tangential rows; s = 0.1 (soft: the interface
//! carries most of the compliance), 10 (the penalty a commercial code would
//! use: an overclosure of a tenth of the body's deflection) and 1e4 (very
//! stiff, near the rigid limit), and the power law m_N = 2 with
//! c_N,i = 10 / (A_ii delta_ref), delta_ref the largest penetration of the
//! penalty row (the same force there; Newton on the law, docs/design.md
//! section 8). Per law: the cold solve's seconds (median of
//! `--reps`) over the baseline, Newton steps (outer), products or sweeps
//! (inner), open / stick / slip, err; the history's mean step over the
//! baseline and its Newton steps.
//!
//! ```text
//! cargo run --release --example compliance -- [--scenes A,B,..] [--threads K]
//!     [--reps R] [--laws tresca,coulomb] [--form auto|dense|matrix-free]
//! ```

#[path = "bench/baseline.rs"]
mod baseline;
#[path = "bench/scene.rs"]
#[allow(dead_code)]
mod scene;
#[path = "bench/stats.rs"]
#[allow(dead_code)]
mod stats;

use dualsplit::{ContactProblem, DualForm, Friction, Options, Solution, SolveStatus};
use scene::{Scene, Spec};
use std::time::Instant;

/// Runs of each plain factorisation whose median is the baseline.
const FACTOR_REPS: usize = 3;

/// Steps of each history.
const STEPS: usize = 10;

fn main() {
    let mut scenes = vec!["2d-400x50".to_string(), "3d-24x24x12".to_string()];
    let mut threads = 1;
    let mut reps = 3usize;
    let mut laws = vec!["tresca".to_string(), "coulomb".to_string()];
    let mut form = DualForm::Auto;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut k = 0;
    while k < args.len() {
        let value = || args.get(k + 1).expect("a value after the flag").clone();
        match args[k].as_str() {
            "--scenes" => scenes = value().split(',').map(str::to_string).collect(),
            "--threads" => threads = value().parse().expect("--threads K"),
            "--reps" => reps = value().parse().expect("--reps R"),
            "--laws" => laws = value().split(',').map(str::to_string).collect(),
            "--form" => form = DualForm::from_name(&value()).expect("a dual form"),
            a => panic!("unknown argument {a}"),
        }
        k += 2;
    }
    let mut rows = Vec::new();
    for name in &scenes {
        let spec = Spec::parse(name).unwrap_or_else(|| panic!("bad scene {name}"));
        let sc = Scene::build(spec);
        let (press, shear) = sc.press_and_shear();
        let t_factor = baseline::best_plain_factor(&sc.k, threads, FACTOR_REPS);
        let opts = Options {
            threads,
            dual_form: form,
            tol: 1e-10,
            ..Options::default()
        };
        let mut pb =
            ContactProblem::from_csc_with(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone(), &opts)
                .expect("the scene is valid");
        let (m, d) = (pb.n_contacts(), pb.dim());
        // The rigid dual's diagonal: the contacts' own compliances.
        let a_nn: Vec<f64> = (0..m).map(|i| pb.dual().diag(i)).collect();
        let a_tt: Vec<f64> = (0..m).map(|i| pb.dual().diag(m + (d - 1) * i)).collect();
        let load: Vec<f64> = press.iter().zip(&shear).map(|(p, s)| p + 0.5 * s).collect();
        println!(
            "\n{name} (n = {}, m = {m}, {}): best plain factor {t_factor:.3} s",
            sc.k.nrows,
            if pb.is_matrix_free() {
                "matrix-free"
            } else {
                "dense"
            }
        );
        for law in &laws {
            let friction = if law == "tresca" {
                Friction::Tresca(&sc.p)
            } else {
                Friction::Coulomb(&sc.mu)
            };
            let mut delta_ref = 0.0f64;
            for (label, s, e) in [
                ("rigid", f64::INFINITY, 1.0),
                ("soft 0.1", 0.1, 1.0),
                ("penalty 10", 10.0, 1.0),
                ("stiff 1e4", 1e4, 1.0),
                ("power m = 2", 10.0, 2.0),
            ] {
                let scale = if e == 1.0 {
                    1.0
                } else {
                    delta_ref.powf(e - 1.0)
                };
                let cn: Vec<f64> = a_nn.iter().map(|a| s / a / scale).collect();
                let kt: Vec<f64> = a_tt.iter().map(|a| s / a).collect();
                let mn = vec![e; m];
                pb.set_compliance(Some(&cn), Some(&mn), Some(&kt))
                    .expect("valid stiffnesses");
                let mut times = Vec::new();
                let mut last: Option<Solution> = None;
                for _ in 0..reps.max(1) {
                    let t0 = Instant::now();
                    let sol = pb.solve(&load, &sc.g, friction, &opts).expect("solves");
                    times.push(t0.elapsed().as_secs_f64());
                    last = Some(sol);
                }
                let sol = last.expect("one solve");
                if label == "penalty 10" {
                    let mut nu = vec![0.0; m];
                    sc.n.mul_vec(&sol.u, &mut nu);
                    delta_ref = (0..m).map(|i| nu[i] - sc.g[i]).fold(0.0, f64::max);
                }
                let r = &sol.report;
                assert_eq!(r.status, SolveStatus::Converged, "{r:?}");
                // The history: press in STEPS / 2, then shear.
                pb.reset_history();
                let (mut warm, mut outer) = (Vec::new(), 0);
                for k in 1..=STEPS {
                    let f =
                        stats::history_load(&press, &shear, stats::load_factors(k, STEPS, false));
                    let t0 = Instant::now();
                    let st = pb.step(&f, &sc.g, friction, &opts).expect("steps");
                    let t = t0.elapsed().as_secs_f64();
                    assert_eq!(st.report.status, SolveStatus::Converged, "{:?}", st.report);
                    if k > 1 {
                        warm.push(t);
                        outer += st.report.outer_iterations;
                    }
                }
                pb.reset_history();
                let mean = warm.iter().sum::<f64>() / warm.len() as f64;
                rows.push(format!(
                    "| {name} | {law} | {label} | {:.3} | {} | {} | {} / {} / {} | {:.1e} | {:.3} | {:.1} |",
                    stats::median(&times) / t_factor,
                    r.outer_iterations,
                    r.inner_iterations,
                    r.n_open,
                    r.n_stick,
                    r.n_slip,
                    r.err,
                    mean / t_factor,
                    outer as f64 / warm.len() as f64
                ));
                println!("{}", rows.last().unwrap());
            }
        }
    }
    println!(
        "\n| scene | law | interface | cold solve / factor | outer | inner | open / stick / slip | err | warm step / factor, mean | Newton steps per warm step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        println!("{r}");
    }
}
