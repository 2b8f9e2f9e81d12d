//! What new contact matrices cost on a matrix-free handle: a host whose
//! contact geometry moves (normals and tangents turning with the
//! deformation) calls `set_contacts` between iterations or increments. On
//! the benchmark's 3D scenes, with `Options::host_loop` (the matrix-free
//! dual) and Coulomb friction: the creation, then three times T's tangent
//! frame turned about each normal (by 0.01, 0.02, 0.03 rad), `set_contacts`
//! with it and a cold solve; each in units of the best plain factorisation
//! of K (analysis and numeric factor, the median of 3 runs, same run).
//!
//! ```text
//! cargo run --release --example set_contacts -- [SCENE ..]
//! ```

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
use dualsplit::{ContactProblem, Csc, Friction, Options};
use scene::{Scene, Spec};
use std::time::Instant;

/// Runs of each plain factorisation whose median is the baseline.
const FACTOR_REPS: usize = 3;

fn main() {
    let mut scenes: Vec<String> = std::env::args().skip(1).collect();
    if scenes.is_empty() {
        scenes = vec!["3d-32x32x4".into(), "3d-64x64x6".into()];
    }
    for name in &scenes {
        let sc = Scene::build(Spec::parse(name).unwrap_or_else(|| panic!("bad scene {name}")));
        assert_eq!(sc.d, 3, "{name}: a 3D scene (its tangent frame turns)");
        let t_factor = baseline::best_plain_factor(&sc.k, 1, FACTOR_REPS);
        let opts = Options {
            threads: 1,
            tol: 1e-10,
            host_loop: true,
            ..Options::default()
        };
        let friction = Friction::Coulomb(&sc.mu);
        let t0 = Instant::now();
        let mut pb =
            ContactProblem::from_csc_with(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone(), &opts)
                .expect("the scene is valid");
        let t_create = t0.elapsed().as_secs_f64();
        let sol = pb.solve(&sc.f, &sc.g, friction, &opts).expect("solves");
        println!(
            "{name} (n = {}, c = {}, {}): best plain factor {t_factor:.3} s; creation {:.2}, cold solve {} Newton steps",
            sc.k.nrows,
            pb.dual_unknowns(),
            if pb.is_matrix_free() {
                "matrix-free"
            } else {
                "dense"
            },
            t_create / t_factor,
            sol.report.outer_iterations
        );
        for turn in [0.01, 0.02, 0.03] {
            let t = turned(&sc.t, turn);
            let (ni, ti) = (indices(&sc.n), indices(&t));
            let t0 = Instant::now();
            pb.set_contacts(&view(&sc.n, &ni), &view(&t, &ti))
                .expect("valid contacts");
            let t_set = t0.elapsed().as_secs_f64();
            let t0 = Instant::now();
            let sol = pb.solve(&sc.f, &sc.g, friction, &opts).expect("solves");
            let t_solve = t0.elapsed().as_secs_f64();
            assert_eq!(sol.report.status, dualsplit::SolveStatus::Converged);
            println!(
                "  frame turned {turn} rad: set_contacts {:.2}, cold solve {:.2} ({} Newton steps, err {:.1e})",
                t_set / t_factor,
                t_solve / t_factor,
                sol.report.outer_iterations,
                sol.report.err
            );
        }
    }
}

/// T (2 m x n, contact i's tangent rows 2 i and 2 i + 1) with each contact's
/// two tangent rows turned by `angle` about its normal.
fn turned(t: &Csc, angle: f64) -> Csc {
    let rows = t.transpose();
    let (c, s) = (angle.cos(), angle.sin());
    let mut trip = Vec::new();
    for r in 0..t.nrows {
        let (own, other, sign) = if r % 2 == 0 {
            (r, r + 1, 1.0)
        } else {
            (r, r - 1, -1.0)
        };
        for p in rows.col_ptr[own]..rows.col_ptr[own + 1] {
            trip.push((r, rows.row_idx[p], c * rows.values[p]));
        }
        for p in rows.col_ptr[other]..rows.col_ptr[other + 1] {
            trip.push((r, rows.row_idx[p], sign * s * rows.values[p]));
        }
    }
    Csc::from_triplets(t.nrows, t.ncols, &trip)
}
