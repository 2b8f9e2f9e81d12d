//! The frictionless contact patch test: a plane-strain Q4 block on a flat rigid
//! foundation must transmit a uniform pressure exactly.
//!
//! Set-up (block [0, L] x [0, H], bottom edge y = 0 on the foundation, zero gap):
//! - top edge y = H: prescribed u_y = -delta on every top node (Dirichlet,
//!   eliminated into f), u_x free except u_x = 0 at the top-left corner (removes the
//!   horizontal rigid-body mode; the prescribed u_y remove the vertical one and the
//!   rotation, so K is positive definite);
//! - the vertical sides x = 0 and x = L are traction free;
//! - every bottom node is a frictionless contact (Tresca p = 0, and Coulomb mu = 0),
//!   N row = -1 on u_y, T row = +1 on u_x, g = 0.
//!
//! Exact solution. Try a homogeneous state with sigma_xx = sigma_xy = 0 (free sides,
//! frictionless bottom) and u_y = 0 on the bottom, u_y = -delta on top:
//!   eps_yy = -delta / H,
//!   plane strain, sigma_xx = E/((1+nu)(1-2nu)) ((1-nu) eps_xx + nu eps_yy) = 0
//!     => eps_xx = -nu/(1-nu) eps_yy,
//!   sigma_yy = E/((1+nu)(1-2nu)) (nu eps_xx + (1-nu) eps_yy) = E/(1-nu^2) eps_yy,
//!   u_x = eps_xx x, u_y = eps_yy y (u_x = 0 at the top-left corner x = 0).
//! It satisfies equilibrium (constant stress), the traction-free sides (vertical
//! sides: sigma n = (sigma_xx, sigma_xy) = 0), the Dirichlet data, and the contact
//! conditions: the bottom stays at the gap (N u = 0 = g) while it presses on the
//! foundation (sigma_yy < 0), and frictionless contact has no tangential force. By
//! uniqueness (K positive definite, convex constraints) it is the solution.
//! The field is linear, so Q4 elements reproduce it exactly, on distorted meshes too
//! (isoparametric bilinear elements contain the linear fields; with 2 x 2 Gauss the
//! integrals of B^T sigma are exact for constant sigma: dN/dx det J is bilinear in
//! (xi, eta)). The discrete contact forces are then the consistent nodal forces of
//! the uniform traction -sigma_yy on the straight bottom edge, for linear shape
//! functions along the edge:
//!   lambda_N,i = E/(1-nu^2) (delta/H) * (x_{i+1} - x_{i-1}) / 2
//! (half an element at the two corners), and lambda_T = 0.
//! Every method must reproduce these to 1e-10 relative when run to tol = 1e-12, and
//! to 1e-9 at the default tol = 1e-10 (err bounds a residual, not the error).

mod common;

use common::{Mesh, Scene, assert_close, assert_converged, kkt_of, norm_inf, opts};
use dualsplit::{Friction, Method, Options};

const E: f64 = 210.0;
const NU: f64 = 0.3;
const L: f64 = 3.0;
const H: f64 = 1.5;
const DELTA: f64 = 0.01;

/// The patch-test scene on `mesh` (bottom nodes on y = 0, top nodes on y = H).
fn scene(mesh: Mesh) -> Scene {
    let top = mesh.top_nodes();
    let bottom = mesh.bottom_nodes();
    for &a in &top {
        assert_eq!(mesh.coords[a][1], H, "top edge must be straight");
    }
    for &a in &bottom {
        assert_eq!(mesh.coords[a][1], 0.0, "bottom edge must be straight");
    }
    let mut prescribed: Vec<(usize, f64)> = top.iter().map(|&a| (2 * a + 1, -DELTA)).collect();
    assert_eq!(mesh.coords[top[0]][0], 0.0, "top-left corner at x = 0");
    prescribed.push((2 * top[0], 0.0));
    let f_ext = vec![0.0; mesh.n_dofs()];
    Scene::build(mesh, E, NU, &prescribed, &f_ext, &bottom, |_| 0.0)
}

/// Runs the patch test on `mesh` with every method and both frictionless laws.
fn patch_test(name: &str, mesh: Mesh) {
    let sc = scene(mesh);
    let m = sc.m();
    let eps_yy = -DELTA / H;
    let eps_xx = -NU / (1.0 - NU) * eps_yy;
    let sigma_yy = E / (1.0 - NU * NU) * eps_yy;
    // Exact contact forces: uniform traction times the tributary length.
    let xs: Vec<f64> = sc
        .contact_nodes
        .iter()
        .map(|&a| sc.mesh.coords[a][0])
        .collect();
    let lambda_exact: Vec<f64> = (0..m)
        .map(|i| {
            let left = if i > 0 { xs[i] - xs[i - 1] } else { 0.0 };
            let right = if i + 1 < m { xs[i + 1] - xs[i] } else { 0.0 };
            -sigma_yy * 0.5 * (left + right)
        })
        .collect();
    let total: f64 = lambda_exact.iter().sum();
    assert!(
        (total - (-sigma_yy * L)).abs() <= 1e-12 * total,
        "tributary lengths add up to L"
    );
    // Exact displacement of every mesh DOF.
    let u_exact: Vec<f64> = sc
        .mesh
        .coords
        .iter()
        .flat_map(|x| [eps_xx * x[0], eps_yy * x[1]])
        .collect();
    let zeros = vec![0.0; m];
    for (law_name, friction) in [
        ("Tresca p = 0", Friction::Tresca(&zeros)),
        ("Coulomb mu = 0", Friction::Coulomb(&zeros)),
    ] {
        for method in Method::ALL {
            // At the default tolerance (err <= 1e-10, a residual bound) the values
            // are within a few 1e-10 (PGS on 4x2 stops at 1.7e-10 relative); at
            // tol = 1e-12 they must match to 1e-10.
            for (tol, rel) in [(1e-10, 1e-9), (1e-12, 1e-10)] {
                let what = format!("{name}, {law_name}, tol {tol:.0e} [{}]", method.name());
                let mut pb = sc.problem();
                let o = Options {
                    tol,
                    ..opts(method)
                };
                let sol = pb
                    .solve(&sc.f, &sc.g, friction, &o)
                    .expect("solve accepts the data");
                assert_converged(&what, &sol);
                let l_scale = norm_inf(&lambda_exact);
                assert_close(
                    &format!("{what}: lambda_N"),
                    &sol.lambda_n,
                    &lambda_exact,
                    rel,
                    l_scale,
                );
                assert_close(
                    &format!("{what}: lambda_T"),
                    &sol.lambda_t,
                    &zeros,
                    rel,
                    l_scale,
                );
                let u = sc.expand(&sol.u);
                assert_close(&format!("{what}: u"), &u, &u_exact, rel, norm_inf(&u_exact));
                let r = &sol.report;
                assert_eq!(
                    (r.n_open, r.n_stick, r.n_slip),
                    (0, 0, m),
                    "{what}: every contact closed and (frictionless) slipping"
                );
                kkt_of(&sc, friction, &sol).assert_ok(&what, rel);
            }
        }
    }
}

#[test]
fn patch_4x2() {
    patch_test("uniform 4x2", Mesh::grid2d(4, 2, L, H));
}

#[test]
fn patch_7x3() {
    patch_test("uniform 7x3", Mesh::grid2d(7, 3, L, H));
}

#[test]
fn patch_1x1() {
    patch_test("single element", Mesh::grid2d(1, 1, L, H));
}

/// A distorted 6x4 mesh: the bottom and top nodes are graded along x (the edges stay
/// straight), the side nodes move along the vertical sides, and the interior nodes
/// move in both directions (deterministic pseudo-random offsets up to a quarter of
/// an element).
#[test]
fn patch_distorted_6x4() {
    let (nx, ny) = (6, 4);
    let mut mesh = Mesh::grid2d(nx, ny, L, H);
    let (hx, hy) = (L / nx as f64, H / ny as f64);
    // Deterministic offsets in [-1, 1].
    let wobble = |i: usize, j: usize, s: usize| {
        let v = ((i * 7919 + j * 104_729 + s * 1_299_709) % 1000) as f64 / 500.0 - 1.0;
        v.clamp(-1.0, 1.0)
    };
    for j in 0..=ny {
        for i in 0..=nx {
            let a = j * (nx + 1) + i;
            let [x, y, _] = mesh.coords[a];
            let side = i == 0 || i == nx;
            let edge = j == 0 || j == ny;
            let (mut nxp, mut nyp) = (x, y);
            if !side {
                // graded along x on every row, plus a wobble inside
                let s = x / L;
                nxp = L * (s + 0.15 * (std::f64::consts::PI * s).sin() * (1.0 - s));
                if !edge {
                    nxp += 0.25 * hx * wobble(i, j, 0);
                }
            }
            if !edge {
                nyp = y + 0.25 * hy * wobble(i, j, 1);
            }
            mesh.coords[a] = [nxp, nyp, 0.0];
        }
    }
    // The bottom spacing is really non-uniform.
    let bx: Vec<f64> = mesh
        .bottom_nodes()
        .iter()
        .map(|&a| mesh.coords[a][0])
        .collect();
    let spacing: Vec<f64> = bx.windows(2).map(|w| w[1] - w[0]).collect();
    let (smin, smax) = spacing
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    assert!(
        smax > 1.2 * smin,
        "bottom spacing {spacing:?} is not graded"
    );
    patch_test("distorted 6x4", mesh);
}
