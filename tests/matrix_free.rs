//! The matrix-free dual (`DualForm::MatrixFree`: each product with A one solve
//! with K's factor, A never formed) against the dense one on finite element
//! scenes: MPRGP and Newton (its steps by Krylov iterations) must converge to the
//! same answer (KKT checked independently), the methods that read entries of A
//! must be refused with `BadArgument` without harming the problem, and `Auto`
//! must assemble A when a method needs it.

mod common;

use common::{Mesh, Scene, assert_converged, kkt_of, max_diff, norm_inf};
use dualsplit::{DualForm, ErrorKind, Friction, Method, Options, Solution};

fn scene_2d() -> Scene {
    let mesh = Mesh::grid2d(24, 6, 2.0, 1.0);
    let mut prescribed = Vec::new();
    for &a in &mesh.top_nodes() {
        prescribed.push((2 * a, 0.006));
        prescribed.push((2 * a + 1, -0.02));
    }
    let f_ext = vec![0.0; mesh.n_dofs()];
    let bottom = mesh.bottom_nodes();
    Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, |x| {
        0.05 * (x[0] - 1.0).powi(2)
    })
}

fn scene_3d() -> Scene {
    let mesh = Mesh::grid3d(6, 6, 2, 2.0, 2.0, 1.0);
    let mut prescribed = Vec::new();
    for &a in &mesh.top_nodes() {
        prescribed.push((3 * a, 0.006));
        prescribed.push((3 * a + 1, 0.003));
        prescribed.push((3 * a + 2, -0.03));
    }
    let f_ext = vec![0.0; mesh.n_dofs()];
    let bottom = mesh.bottom_nodes();
    Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, |x| {
        0.05 * ((x[0] - 1.0).powi(2) + (x[1] - 1.0).powi(2))
    })
}

fn mprgp(form: DualForm) -> Options {
    Options {
        method: Method::Mprgp,
        dual_form: form,
        ..Options::default()
    }
}

fn lambda(s: &Solution) -> Vec<f64> {
    s.lambda_n.iter().chain(&s.lambda_t).copied().collect()
}

fn dense_and_free_agree(name: &str, scene: &Scene, friction: Friction<'_>) {
    agree(name, scene, friction, Method::Mprgp, 1e-8);
}

fn with(method: Method, form: DualForm) -> Options {
    Options {
        method,
        dual_form: form,
        ..Options::default()
    }
}

/// `method` on the dense and on the matrix-free dual of one problem, each
/// solved to a hundredth of `rel` (or the default tolerance where that is
/// tighter): both converge, pass the KKT check, and agree to `rel` in
/// lambda and u.
fn agree(name: &str, scene: &Scene, friction: Friction<'_>, method: Method, rel: f64) {
    let mut pb = scene.problem();
    let opts = |form| {
        let o = with(method, form);
        Options {
            tol: o.tol.min(rel / 100.0),
            ..o
        }
    };
    let dense = pb
        .solve(&scene.f, &scene.g, friction, &opts(DualForm::Dense))
        .unwrap();
    assert!(!pb.dual().is_matrix_free());
    let free = pb
        .solve(&scene.f, &scene.g, friction, &opts(DualForm::MatrixFree))
        .unwrap();
    assert!(pb.dual().is_matrix_free(), "{name}: the form is kept");
    assert!(pb.dual().dense().is_none(), "{name}: A is not formed");
    for (what, s) in [("dense", &dense), ("matrix-free", &free)] {
        let w = format!("{name} [{what}]");
        let r = &s.report;
        println!(
            "{w}: {:?}, err {:.2e}, outer {}, inner {}",
            r.status, r.err, r.outer_iterations, r.inner_iterations
        );
        assert_converged(&w, s);
        kkt_of(scene, friction, s).assert_ok(&w, 1e-8);
    }
    let (l0, l1) = (lambda(&dense), lambda(&free));
    let dl = max_diff(&l0, &l1);
    assert!(
        dl <= rel * norm_inf(&l0),
        "{name}: lambda differs by {dl:.2e}"
    );
    let du = max_diff(&dense.u, &free.u);
    assert!(
        du <= rel * norm_inf(&dense.u),
        "{name}: u differs by {du:.2e}"
    );
}

/// Semismooth Newton on the matrix-free dual (its steps by CG / GMRES on
/// products with A) gives dense Newton's answer, 2D and 3D, Tresca and Coulomb.
#[test]
fn newton_matrix_free_matches_dense_newton() {
    let s2 = scene_2d();
    let mu2 = vec![0.3; s2.m()];
    let p2 = vec![0.02; s2.m()];
    agree(
        "2D Coulomb newton",
        &s2,
        Friction::Coulomb(&mu2),
        Method::Newton,
        1e-10,
    );
    agree(
        "2D Tresca newton",
        &s2,
        Friction::Tresca(&p2),
        Method::Newton,
        1e-10,
    );
    let s3 = scene_3d();
    let p3 = vec![0.05; s3.m()];
    let mu3 = vec![0.3; s3.m()];
    agree(
        "3D Tresca newton",
        &s3,
        Friction::Tresca(&p3),
        Method::Newton,
        1e-10,
    );
    agree(
        "3D Coulomb newton",
        &s3,
        Friction::Coulomb(&mu3),
        Method::Newton,
        1e-10,
    );
}

/// A problem created matrix-free factors the plain K (no contact DOFs ordered
/// last) and solves on it with Newton, whose answer is the dense one's (both
/// solved to 1e-12, a hundredth of the agreement asserted).
#[test]
fn a_problem_created_matrix_free_uses_the_plain_factor() {
    let s = scene_3d();
    let mu = vec![0.3; s.m()];
    let fr = Friction::Coulomb(&mu);
    let tight = |form| Options {
        tol: 1e-12,
        ..with(Method::Newton, form)
    };
    let o = tight(DualForm::MatrixFree);
    let mut free =
        dualsplit::ContactProblem::from_csc_with(s.d, s.k.clone(), s.n.clone(), s.t.clone(), &o)
            .unwrap();
    assert!(free.dual().is_matrix_free());
    assert!(free.factor().last().is_empty(), "the plain factor of K");
    let a = free.solve(&s.f, &s.g, fr, &o).unwrap();
    let b = s
        .problem()
        .solve(&s.f, &s.g, fr, &tight(DualForm::Dense))
        .unwrap();
    assert_converged("plain factor", &a);
    kkt_of(&s, fr, &a).assert_ok("plain factor", 1e-8);
    let dl = max_diff(&lambda(&a), &lambda(&b));
    assert!(
        dl <= 1e-10 * norm_inf(&lambda(&b)),
        "lambda differs by {dl:.2e}"
    );
    let du = max_diff(&a.u, &b.u);
    assert!(du <= 1e-10 * norm_inf(&b.u), "u differs by {du:.2e}");
    // The err measure is the library's: rho from the same diagonal blocks.
    for (x, y) in free.dual().rho().iter().zip(s.problem().dual().rho()) {
        assert!((x - y).abs() <= 1e-12 * y.abs(), "rho {x} vs {y}");
    }
}

#[test]
fn mprgp_matrix_free_matches_dense_2d_coulomb() {
    let s = scene_2d();
    let mu = vec![0.3; s.m()];
    dense_and_free_agree("2D Coulomb", &s, Friction::Coulomb(&mu));
}

#[test]
fn mprgp_matrix_free_matches_dense_3d_tresca_and_coulomb() {
    let s = scene_3d();
    let p = vec![0.05; s.m()];
    dense_and_free_agree("3D Tresca", &s, Friction::Tresca(&p));
    let mu = vec![0.3; s.m()];
    dense_and_free_agree("3D Coulomb", &s, Friction::Coulomb(&mu));
}

#[test]
fn methods_that_read_entries_are_refused_matrix_free_and_auto_assembles() {
    let s = scene_2d();
    let mu = vec![0.3; s.m()];
    let fr = Friction::Coulomb(&mu);
    let mut pb = s.problem();
    let reference = pb.solve(&s.f, &s.g, fr, &mprgp(DualForm::Dense)).unwrap();
    // Put the problem in the matrix-free form.
    pb.solve(&s.f, &s.g, fr, &mprgp(DualForm::MatrixFree))
        .unwrap();
    for method in Method::ALL {
        let o = Options {
            method,
            dual_form: DualForm::MatrixFree,
            ..Options::default()
        };
        match pb.solve(&s.f, &s.g, fr, &o) {
            // newton and mprgp run on products alone; auto runs newton there.
            Ok(sol) => {
                assert!(!method.needs_entries(), "{}", method.name());
                let ran = if method == Method::Auto {
                    Method::Newton
                } else {
                    method
                };
                assert_eq!(sol.report.method, ran);
                assert_converged(method.name(), &sol);
            }
            Err(e) => {
                assert!(method.needs_entries(), "{}", method.name());
                assert_eq!(e.kind, ErrorKind::BadArgument);
                assert!(
                    e.message.contains(method.name()) && e.message.contains("mprgp"),
                    "{}",
                    e.message
                );
                // The problem is unharmed: still matrix-free, still solving.
                assert!(pb.dual().is_matrix_free());
            }
        }
    }
    // Auto keeps the matrix-free form for MPRGP ...
    let auto = pb.solve(&s.f, &s.g, fr, &mprgp(DualForm::Auto)).unwrap();
    assert!(pb.dual().is_matrix_free());
    assert_converged("auto mprgp", &auto);
    // ... and assembles A for a method that reads its entries.
    let o = Options {
        method: Method::Split,
        dual_form: DualForm::Auto,
        ..Options::default()
    };
    let split = pb.solve(&s.f, &s.g, fr, &o).unwrap();
    assert!(!pb.dual().is_matrix_free());
    assert_converged("auto split", &split);
    kkt_of(&s, fr, &split).assert_ok("auto split", 1e-8);
    let dl = max_diff(&lambda(&reference), &lambda(&split));
    assert!(dl <= 1e-8 * norm_inf(&lambda(&reference)));
}

#[test]
fn history_steps_run_matrix_free() {
    // Two increments of a history, matrix-free and dense, give the same states.
    let s = scene_3d();
    let p = vec![0.05; s.m()];
    let fr = Friction::Tresca(&p);
    let mut a = s.problem();
    let mut b = s.problem();
    let f2: Vec<f64> = s.f.iter().map(|v| 1.05 * v).collect();
    for f in [&s.f, &f2] {
        let sa = a.step(f, &s.g, fr, &mprgp(DualForm::Dense)).unwrap();
        let sb = b.step(f, &s.g, fr, &mprgp(DualForm::MatrixFree)).unwrap();
        assert_converged("dense step", &sa);
        assert_converged("matrix-free step", &sb);
        let du = max_diff(&sa.u, &sb.u);
        assert!(du <= 1e-8 * norm_inf(&sa.u), "u differs by {du:.2e}");
    }
}
