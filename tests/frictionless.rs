//! Frictionless increments (Tresca p = 0 or Coulomb mu = 0 at every contact) are the
//! pure Signorini problem in the m normal unknowns (docs/design.md section 2): split,
//! block-gs, split-mprgp and mprgp solve it on A_NN alone (the report's
//! dual_unknowns is m), Newton and PGS on the whole dual (d m). Every method must
//! give lambda_T = 0 exactly, pass the independent KKT check, and agree with Newton
//! (the reference, not compared with itself); MPRGP also matrix-free.

mod common;

use common::{Mesh, Scene, assert_converged, kkt_of, max_diff, norm_inf};
use dualsplit::{DualForm, Friction, Method, Options, Solution};

fn scene(d: usize) -> Scene {
    if d == 2 {
        let mesh = Mesh::grid2d(20, 5, 2.0, 1.0);
        let mut prescribed = Vec::new();
        for &a in &mesh.top_nodes() {
            prescribed.push((2 * a, 0.01));
            prescribed.push((2 * a + 1, -0.02));
        }
        let f_ext = vec![0.0; mesh.n_dofs()];
        let bottom = mesh.bottom_nodes();
        Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, |x| {
            0.05 * (x[0] - 1.0).powi(2)
        })
    } else {
        let mesh = Mesh::grid3d(6, 6, 2, 2.0, 2.0, 1.0);
        let mut prescribed = Vec::new();
        for &a in &mesh.top_nodes() {
            prescribed.push((3 * a, 0.01));
            prescribed.push((3 * a + 1, 0.004));
            prescribed.push((3 * a + 2, -0.03));
        }
        let f_ext = vec![0.0; mesh.n_dofs()];
        let bottom = mesh.bottom_nodes();
        Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, |x| {
            0.05 * ((x[0] - 1.0).powi(2) + (x[1] - 1.0).powi(2))
        })
    }
}

fn solve(s: &Scene, fr: Friction<'_>, method: Method, form: DualForm) -> Solution {
    let o = Options {
        method,
        dual_form: form,
        ..Options::default()
    };
    let what = format!("d = {} [{} {}]", s.d, method.name(), form.name());
    let sol = s.problem().solve(&s.f, &s.g, fr, &o).unwrap();
    let r = &sol.report;
    println!(
        "{what}: {:?}, err {:.2e}, outer {}, inner {}, open/stick/slip {}/{}/{}",
        r.status, r.err, r.outer_iterations, r.inner_iterations, r.n_open, r.n_stick, r.n_slip
    );
    assert_converged(&what, &sol);
    kkt_of(s, fr, &sol).assert_ok(&what, 1e-8);
    assert!(
        sol.lambda_t.iter().all(|&v| v == 0.0),
        "{what}: lambda_T = 0"
    );
    assert!(
        r.n_open > 0 && r.n_slip > 0,
        "{what}: open and closed contacts"
    );
    // Which branch ran: the Signorini problem in m unknowns, or the whole dual.
    // auto runs Newton on the dense dual.
    let whole = matches!(method, Method::Newton | Method::Pgs | Method::Auto);
    let want = if whole { s.d * s.m() } else { s.m() };
    assert_eq!(r.dual_unknowns, want, "{what}: dual unknowns");
    sol
}

fn all_methods_agree(d: usize) {
    let s = scene(d);
    let zero = vec![0.0; s.m()];
    for fr in [Friction::Tresca(&zero), Friction::Coulomb(&zero)] {
        let reference = solve(&s, fr, Method::Newton, DualForm::Dense);
        let mut runs: Vec<Solution> = Method::ALL
            .into_iter()
            .filter(|&m| m != Method::Newton)
            .map(|m| solve(&s, fr, m, DualForm::Dense))
            .collect();
        runs.push(solve(&s, fr, Method::Mprgp, DualForm::MatrixFree));
        let scale = norm_inf(&reference.lambda_n);
        for sol in &runs {
            let dl = max_diff(&sol.lambda_n, &reference.lambda_n);
            assert!(dl <= 1e-8 * scale, "d = {d}: lambda_N differs by {dl:.2e}");
            let du = max_diff(&sol.u, &reference.u);
            assert!(
                du <= 1e-8 * norm_inf(&reference.u),
                "d = {d}: u differs by {du:.2e}"
            );
        }
    }
}

#[test]
fn frictionless_2d_every_method() {
    all_methods_agree(2);
}

#[test]
fn frictionless_3d_every_method() {
    all_methods_agree(3);
}

#[test]
fn one_contact_with_friction_keeps_the_whole_dual() {
    // A single nonzero bound: not frictionless; the answer still passes KKT and
    // split agrees with Newton.
    let s = scene(2);
    let mut p = vec![0.0; s.m()];
    p[s.m() / 2] = 0.01;
    let fr = Friction::Tresca(&p);
    let a = solve_any(&s, fr, Method::Split);
    let b = solve_any(&s, fr, Method::Newton);
    let dl = max_diff(&a.lambda_n, &b.lambda_n);
    assert!(dl <= 1e-8 * norm_inf(&b.lambda_n));
    assert!(a.lambda_t.iter().any(|&v| v != 0.0));
}

fn solve_any(s: &Scene, fr: Friction<'_>, method: Method) -> Solution {
    let o = Options {
        method,
        ..Options::default()
    };
    let sol = s.problem().solve(&s.f, &s.g, fr, &o).unwrap();
    assert_converged(method.name(), &sol);
    kkt_of(s, fr, &sol).assert_ok(method.name(), 1e-8);
    // One bound is nonzero: the whole dual.
    assert_eq!(sol.report.dual_unknowns, s.d * s.m(), "{}", method.name());
    sol
}
