//! Every method on the same finite element scenes: each must converge (err <= 1e-10)
//! to a point that passes the independent KKT check of tests/common, and all of
//! them must agree with each other:
//!   max |lambda_a - lambda_b| <= 1e-8 max |lambda|,  max |u_a - u_b| <= 1e-8 max |u|.
//!
//! Scenes:
//! - 2D: a plane-strain Q4 block [0, 2] x [0, 1] (16 x 4 elements, E = 100,
//!   nu = 0.3) above a curved foundation, gap g(x) = 0.05 (x - 1)^2 at the bottom
//!   nodes; the top edge is moved by (0.006, -0.02) (Dirichlet, eliminated into f):
//!   a vertical and a horizontal load. Coulomb mu = 0.3. The centre closes, the
//!   ends stay open, and the closed zone sticks in the middle and slips at its edges
//!   (Cattaneo-Mindlin partial slip): open, stick and slip contacts at once.
//! - 3D: a trilinear H8 block [0, 2]^2 x [0, 1] (6 x 6 x 2 elements) above a
//!   spherical foundation, g = 0.05 ((x - 1)^2 + (y - 1)^2), the top face moved by
//!   (0.006, 0.003, -0.03), with Tresca p = 0.05 (and a Coulomb variant, mu = 0.3).
//!
//! Run with `--nocapture` to see the iteration counts and errors of each method.

mod common;

use common::{Mesh, Scene, assert_converged, kkt_of, max_diff, norm_inf, opts};
use dualsplit::{Friction, Method, Solution};

fn scene_2d() -> Scene {
    let mesh = Mesh::grid2d(16, 4, 2.0, 1.0);
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

/// Solves `scene` with every method; checks convergence and the KKT conditions,
/// prints the iteration counts, and checks that the methods agree.
fn run_all(name: &str, scene: &Scene, friction: Friction<'_>) -> Vec<(Method, Solution)> {
    let mut out = Vec::new();
    for method in Method::ALL {
        let what = format!("{name} [{}]", method.name());
        let mut pb = scene.problem();
        let sol = pb
            .solve(&scene.f, &scene.g, friction, &opts(method))
            .expect("solve accepts the data");
        let r = &sol.report;
        println!(
            "{what}: {:?}, err = {:.3e}, equilibrium = {:.3e}, outer = {}, inner = {}, \
             open/stick/slip = {}/{}/{}",
            r.status,
            r.err,
            r.equilibrium_residual,
            r.outer_iterations,
            r.inner_iterations,
            r.n_open,
            r.n_stick,
            r.n_slip
        );
        assert_converged(&what, &sol);
        kkt_of(scene, friction, &sol).assert_ok(&what, 1e-8);
        out.push((method, sol));
    }
    for (a, sa) in &out {
        for (b, sb) in &out {
            if a.name() >= b.name() {
                continue;
            }
            let what = format!("{name}: {} vs {}", a.name(), b.name());
            let lam_a: Vec<f64> = sa.lambda_n.iter().chain(&sa.lambda_t).copied().collect();
            let lam_b: Vec<f64> = sb.lambda_n.iter().chain(&sb.lambda_t).copied().collect();
            let lam_scale = norm_inf(&lam_a).max(norm_inf(&lam_b));
            let dl = max_diff(&lam_a, &lam_b);
            assert!(
                dl <= 1e-8 * lam_scale,
                "{what}: max |lambda_a - lambda_b| = {dl:.3e} > 1e-8 * {lam_scale:.3e}"
            );
            let u_scale = norm_inf(&sa.u).max(norm_inf(&sb.u));
            let du = max_diff(&sa.u, &sb.u);
            assert!(
                du <= 1e-8 * u_scale,
                "{what}: max |u_a - u_b| = {du:.3e} > 1e-8 * {u_scale:.3e}"
            );
            let (ra, rb) = (&sa.report, &sb.report);
            assert_eq!(
                (ra.n_open, ra.n_stick, ra.n_slip),
                (rb.n_open, rb.n_stick, rb.n_slip),
                "{what}: contact states (open, stick, slip)"
            );
        }
    }
    out
}

#[test]
fn q4_block_coulomb_open_stick_slip() {
    let sc = scene_2d();
    let mu = vec![0.3; sc.m()];
    let sols = run_all("2D Q4 Coulomb mu = 0.3", &sc, Friction::Coulomb(&mu));
    for (method, sol) in &sols {
        let r = &sol.report;
        assert!(
            r.n_open > 0 && r.n_stick > 0 && r.n_slip > 0,
            "[{}] the scene must hold open, stick and slip contacts at once: {}/{}/{}",
            method.name(),
            r.n_open,
            r.n_stick,
            r.n_slip
        );
        // The horizontal motion of the top drags the body in +x: the net friction
        // force on the body, -sum lambda_T, points in -x (single contacts may carry
        // either sign: the Poisson expansion of the compressed zone pushes its two
        // ends outward).
        let net: f64 = sol.lambda_t.iter().sum();
        assert!(net > 0.0, "[{}] sum lambda_T = {net}", method.name());
    }
}

#[test]
fn h8_block_tresca() {
    let sc = scene_3d();
    let p = vec![0.05; sc.m()];
    let sols = run_all("3D H8 Tresca p = 0.05", &sc, Friction::Tresca(&p));
    for (method, sol) in &sols {
        let r = &sol.report;
        assert!(
            r.n_open > 0 && r.n_stick > 0 && r.n_slip > 0,
            "[{}] expected open, stick and slip contacts: {}/{}/{}",
            method.name(),
            r.n_open,
            r.n_stick,
            r.n_slip
        );
    }
}

#[test]
fn h8_block_coulomb() {
    let sc = scene_3d();
    let mu = vec![0.3; sc.m()];
    run_all("3D H8 Coulomb mu = 0.3", &sc, Friction::Coulomb(&mu));
}
