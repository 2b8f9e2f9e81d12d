//! Small contact problems with answers derived by hand, run with every method.
//!
//! Conventions (docs/design.md section 1): K u = f - N^T lambda_N - T^T lambda_T,
//! N u <= g, lambda_N >= 0, |lambda_T,i| <= p_i, stick => (T u)_i = 0, slip =>
//! (T u)_i = alpha lambda_T,i with alpha >= 0.
//!
//! Unless stated otherwise a contact node has the DOFs (u_x, u_y) in 2D or
//! (u_x, u_y, u_z) in 3D, sits above a rigid foundation whose outward normal (of the
//! body) is -e_y (-e_z in 3D): N row = -1 on the vertical DOF, so N u <= g reads
//! u_vert >= -g, and lambda_N pushes the node up (+lambda_N in the vertical row of
//! K u = f + lambda_N ...). T rows = +1 on u_x (and u_y in 3D), so the tangential
//! rows of equilibrium read k u_t = f_t - lambda_T.
//!
//! Every case asserts, for every method in `Method::ALL`: status Converged,
//! err <= 1e-10, the closed-form u, lambda_N and lambda_T to 1e-10 relative (u
//! relative to max(|u|, |g|), multipliers relative to max(|lambda|, |f|)), the
//! contact state counts, and the independent KKT check of tests/common.

// The small dense helpers of the rotated cases read best with explicit indices.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{assert_close, assert_converged, kkt, norm_inf, opts};
use dualsplit::{ContactProblem, Csc, Friction, Method, Solution};

/// Relative accuracy asked of the closed-form values. The solver stops at
/// err <= 1e-10, a bound on the natural-map residual, not on the error of the
/// values: for a sticking contact, for instance, the residual leaves a slip of about
/// err * |lambda| * A_ii, a few times 1e-10 relative to |u| on these cases (measured:
/// up to 1.6e-10 for block-gs on `coupled_xy_tresca_stick`). Hence 1e-9.
const REL: f64 = 1e-9;

#[derive(Clone, Debug)]
enum Law {
    Tresca(Vec<f64>),
    Coulomb(Vec<f64>),
}

impl Law {
    fn friction(&self) -> Friction<'_> {
        match self {
            Law::Tresca(p) => Friction::Tresca(p),
            Law::Coulomb(mu) => Friction::Coulomb(mu),
        }
    }
}

/// The matrices of a small problem.
#[derive(Clone, Debug)]
struct Data {
    d: usize,
    ndof: usize,
    m: usize,
    /// K, both triangles.
    k: Vec<(usize, usize, f64)>,
    n: Vec<(usize, usize, f64)>,
    t: Vec<(usize, usize, f64)>,
}

impl Data {
    fn k(&self) -> Csc {
        Csc::from_triplets(self.ndof, self.ndof, &self.k)
    }
    fn n(&self) -> Csc {
        Csc::from_triplets(self.m, self.ndof, &self.n)
    }
    fn t(&self) -> Csc {
        Csc::from_triplets((self.d - 1) * self.m, self.ndof, &self.t)
    }
    fn problem(&self) -> ContactProblem {
        ContactProblem::from_csc(self.d, self.k(), self.n(), self.t())
            .expect("valid contact problem")
    }
}

/// Expected answer of one solve.
#[derive(Clone, Debug)]
struct Expect {
    u: Vec<f64>,
    lambda_n: Vec<f64>,
    lambda_t: Vec<f64>,
    /// (open, stick, slip); frictionless closed contacts count as slip. None where
    /// the answer is degenerate (|lambda_T| = p with zero slip, or lambda_N = 0 with
    /// a zero gap), where either classification is right.
    states: Option<(usize, usize, usize)>,
}

/// Checks one solution against the expected closed form and the KKT conditions.
fn check_solution(
    what: &str,
    data: &Data,
    f: &[f64],
    g: &[f64],
    law: &Law,
    sol: &Solution,
    want: &Expect,
) {
    assert_converged(what, sol);
    let u_scale = norm_inf(&want.u).max(norm_inf(g));
    let l_scale = norm_inf(&want.lambda_n)
        .max(norm_inf(&want.lambda_t))
        .max(norm_inf(f));
    assert_close(&format!("{what}: u"), &sol.u, &want.u, REL, u_scale);
    assert_close(
        &format!("{what}: lambda_N"),
        &sol.lambda_n,
        &want.lambda_n,
        REL,
        l_scale,
    );
    assert_close(
        &format!("{what}: lambda_T"),
        &sol.lambda_t,
        &want.lambda_t,
        REL,
        l_scale,
    );
    let r = &sol.report;
    if let Some(states) = want.states {
        assert_eq!(
            (r.n_open, r.n_stick, r.n_slip),
            states,
            "{what}: contact states (open, stick, slip)"
        );
    }
    assert!(
        r.equilibrium_residual <= 1e-12,
        "{what}: equilibrium residual {:.3e}",
        r.equilibrium_residual
    );
    let v = kkt(
        data.d,
        &data.k(),
        &data.n(),
        &data.t(),
        f,
        g,
        law.friction(),
        &sol.u,
        &sol.lambda_n,
        &sol.lambda_t,
    );
    v.assert_ok(what, REL);
}

/// Solves one increment with every method and checks the closed form.
fn check(name: &str, data: &Data, f: &[f64], g: &[f64], law: &Law, want: &Expect) {
    // The hand-derived answer must itself satisfy the KKT conditions.
    kkt(
        data.d,
        &data.k(),
        &data.n(),
        &data.t(),
        f,
        g,
        law.friction(),
        &want.u,
        &want.lambda_n,
        &want.lambda_t,
    )
    .assert_ok(&format!("{name}: the closed form itself"), 1e-14);
    for method in Method::ALL {
        let mut pb = data.problem();
        let sol = pb
            .solve(f, g, law.friction(), &opts(method))
            .expect("solve accepts the data");
        check_solution(
            &format!("{name} [{}]", method.name()),
            data,
            f,
            g,
            law,
            &sol,
            want,
        );
    }
}

fn expect(u: &[f64], lambda_n: &[f64], lambda_t: &[f64], states: (usize, usize, usize)) -> Expect {
    Expect {
        u: u.to_vec(),
        lambda_n: lambda_n.to_vec(),
        lambda_t: lambda_t.to_vec(),
        states: Some(states),
    }
}

impl Expect {
    /// The same answer without a contact state classification.
    fn degenerate(mut self) -> Self {
        self.states = None;
        self
    }
}

// ---------------------------------------------------------------------------------
// One node in 2D, K = diag(kx, ky) = diag(2, 4): normal and tangential decouple.
//   x row: 2 u_x = f_x - lambda_T
//   y row: 4 u_y = f_y + lambda_N          (N = [0, -1])
// Closed contact: u_y = -g, so lambda_N = -4 g - f_y (must be > 0).
// Stick: u_x = 0, lambda_T = f_x (needs |f_x| < p).
// Slip: lambda_T = p sign(f_x), u_x = (f_x - lambda_T) / 2 (same sign as f_x).
// ---------------------------------------------------------------------------------

fn one_node_2d() -> Data {
    Data {
        d: 2,
        ndof: 2,
        m: 1,
        k: vec![(0, 0, 2.0), (1, 1, 4.0)],
        n: vec![(0, 1, -1.0)],
        t: vec![(0, 0, 1.0)],
    }
}

/// Separation: f = (1, -1), g = 0.5. Free solution u = K^-1 f = (0.5, -0.25):
/// N u = 0.25 <= 0.5, the gap stays open, lambda_N = 0 and, Coulomb, p = mu * 0 = 0
/// so lambda_T = 0 and u = K^-1 f.
#[test]
fn separation_2d_coulomb() {
    check(
        "separation 2D Coulomb",
        &one_node_2d(),
        &[1.0, -1.0],
        &[0.5],
        &Law::Coulomb(vec![0.5]),
        &expect(&[0.5, -0.25], &[0.0], &[0.0], (1, 0, 0)),
    );
}

/// Separation with a load pulling the node away: f = (1, 2), g = 0, Tresca p = 0:
/// u = K^-1 f = (0.5, 0.5), N u = -0.5 <= 0, lambda = 0.
#[test]
fn separation_2d_pulled_away() {
    check(
        "separation 2D pulled away",
        &one_node_2d(),
        &[1.0, 2.0],
        &[0.0],
        &Law::Tresca(vec![0.0]),
        &expect(&[0.5, 0.5], &[0.0], &[0.0], (1, 0, 0)),
    );
}

/// Stick, Tresca: f = (1, -6), g = 0.5, p = 2. Closed: u_y = -0.5,
/// lambda_N = -4 * 0.5 + 6 = 4. Stick: u_x = 0, lambda_T = f_x = 1 < 2.
#[test]
fn stick_2d_tresca() {
    check(
        "stick 2D Tresca",
        &one_node_2d(),
        &[1.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![2.0]),
        &expect(&[0.0, -0.5], &[4.0], &[1.0], (0, 1, 0)),
    );
}

/// Slip, Tresca: f = (5, -6), g = 0.5, p = 2. lambda_N = 4 as above; |f_x| = 5 > 2:
/// lambda_T = 2, u_x = (5 - 2) / 2 = 1.5 > 0 (slip along lambda_T).
#[test]
fn slip_2d_tresca() {
    check(
        "slip 2D Tresca",
        &one_node_2d(),
        &[5.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![2.0]),
        &expect(&[1.5, -0.5], &[4.0], &[2.0], (0, 0, 1)),
    );
}

/// Slip in the negative direction: f = (-5, -6): lambda_T = -2, u_x = -1.5.
#[test]
fn slip_2d_tresca_negative() {
    check(
        "slip 2D Tresca negative",
        &one_node_2d(),
        &[-5.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![2.0]),
        &expect(&[-1.5, -0.5], &[4.0], &[-2.0], (0, 0, 1)),
    );
}

/// Stick, Coulomb: f = (1, -6), g = 0.5, mu = 0.5: lambda_N = 4, p = 2 > |f_x| = 1:
/// lambda_T = 1, u_x = 0.
#[test]
fn stick_2d_coulomb() {
    check(
        "stick 2D Coulomb",
        &one_node_2d(),
        &[1.0, -6.0],
        &[0.5],
        &Law::Coulomb(vec![0.5]),
        &expect(&[0.0, -0.5], &[4.0], &[1.0], (0, 1, 0)),
    );
}

/// Slip, Coulomb: f = (5, -6), g = 0.5, mu = 0.25: lambda_N = 4 (K diagonal, so the
/// normal force does not depend on the tangential one), p = mu lambda_N = 1:
/// lambda_T = 1, u_x = (5 - 1) / 2 = 2.
#[test]
fn slip_2d_coulomb() {
    check(
        "slip 2D Coulomb",
        &one_node_2d(),
        &[5.0, -6.0],
        &[0.5],
        &Law::Coulomb(vec![0.25]),
        &expect(&[2.0, -0.5], &[1.0 * 4.0], &[1.0], (0, 0, 1)),
    );
}

/// Initial penetration: g = -0.25, f = (1, 0). The contact forces u_y >= 0.25:
/// lambda_N = -4 g - f_y = 1. Tresca p = 0.5 < |f_x| = 1: slip, lambda_T = 0.5,
/// u_x = (1 - 0.5) / 2 = 0.25.
#[test]
fn negative_gap_2d_tresca() {
    check(
        "negative gap 2D Tresca",
        &one_node_2d(),
        &[1.0, 0.0],
        &[-0.25],
        &Law::Tresca(vec![0.5]),
        &expect(&[0.25, 0.25], &[1.0], &[0.5], (0, 0, 1)),
    );
}

/// Initial penetration with Coulomb: g = -0.25, f = (1, 0), mu = 2: lambda_N = 1,
/// p = 2 > 1: stick, lambda_T = 1, u = (0, 0.25).
#[test]
fn negative_gap_2d_coulomb() {
    check(
        "negative gap 2D Coulomb",
        &one_node_2d(),
        &[1.0, 0.0],
        &[-0.25],
        &Law::Coulomb(vec![2.0]),
        &expect(&[0.0, 0.25], &[1.0], &[1.0], (0, 1, 0)),
    );
}

/// Frictionless contact (Tresca p = 0): f = (3, -6), g = 0.5: lambda_N = 4,
/// lambda_T = 0, u_x = 3 / 2 = 1.5.
#[test]
fn frictionless_2d_tresca() {
    check(
        "frictionless 2D Tresca p = 0",
        &one_node_2d(),
        &[3.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![0.0]),
        &expect(&[1.5, -0.5], &[4.0], &[0.0], (0, 0, 1)),
    );
}

/// Frictionless contact (Coulomb mu = 0): same answer as with p = 0.
#[test]
fn frictionless_2d_coulomb() {
    check(
        "frictionless 2D Coulomb mu = 0",
        &one_node_2d(),
        &[3.0, -6.0],
        &[0.5],
        &Law::Coulomb(vec![0.0]),
        &expect(&[1.5, -0.5], &[4.0], &[0.0], (0, 0, 1)),
    );
}

// ---------------------------------------------------------------------------------
// Two independent nodes in 2D (K = diag(2, 4, 2, 4), DOFs x1, y1, x2, y2): one
// solve holding two different contact states.
// ---------------------------------------------------------------------------------

fn two_nodes_2d_diagonal() -> Data {
    Data {
        d: 2,
        ndof: 4,
        m: 2,
        k: vec![(0, 0, 2.0), (1, 1, 4.0), (2, 2, 2.0), (3, 3, 4.0)],
        n: vec![(0, 1, -1.0), (1, 3, -1.0)],
        t: vec![(0, 0, 1.0), (1, 2, 1.0)],
    }
}

/// f = (1, -6, -5, -6), g = (0.5, 0.5), Tresca p = (2, 2): node 1 sticks (as in
/// `stick_2d_tresca`), node 2 slips in -x: lambda_T,2 = -2, u_x2 = (-5 + 2)/2 = -1.5.
#[test]
fn two_nodes_stick_and_slip_2d() {
    check(
        "two nodes stick + slip 2D",
        &two_nodes_2d_diagonal(),
        &[1.0, -6.0, -5.0, -6.0],
        &[0.5, 0.5],
        &Law::Tresca(vec![2.0, 2.0]),
        &expect(
            &[0.0, -0.5, -1.5, -0.5],
            &[4.0, 4.0],
            &[1.0, -2.0],
            (0, 1, 1),
        ),
    );
}

/// f = (5, -1, 1, -6), g = (0.5, 0.5), Coulomb mu = (0.5, 0.5): node 1 stays open
/// (u_y1 = -0.25 > -0.5, lambda = 0, u_x1 = 2.5 free), node 2 closes with
/// lambda_N = 4, p = 2 > 1: sticks with lambda_T = 1.
#[test]
fn two_nodes_open_and_stick_2d() {
    check(
        "two nodes open + stick 2D",
        &two_nodes_2d_diagonal(),
        &[5.0, -1.0, 1.0, -6.0],
        &[0.5, 0.5],
        &Law::Coulomb(vec![0.5, 0.5]),
        &expect(
            &[2.5, -0.25, 0.0, -0.5],
            &[0.0, 4.0],
            &[0.0, 1.0],
            (1, 1, 0),
        ),
    );
}

// ---------------------------------------------------------------------------------
// Two nodes coupled by springs: each node tied to the ground by unit springs in x
// and y, and the two nodes tied to each other by unit springs in x and in y. DOFs
// (x1, y1, x2, y2):
//   x rows: [2 -1; -1 2] (x1, x2) = (f_x1 - lT1, f_x2 - lT2)
//   y rows: [2 -1; -1 2] (y1, y2) = (f_y1 + lN1, f_y2 + lN2)
// The contacts interact through the off-diagonal -1 entries.
// ---------------------------------------------------------------------------------

fn coupled_pair_2d() -> Data {
    Data {
        d: 2,
        ndof: 4,
        m: 2,
        k: vec![
            (0, 0, 2.0),
            (0, 2, -1.0),
            (2, 0, -1.0),
            (2, 2, 2.0),
            (1, 1, 2.0),
            (1, 3, -1.0),
            (3, 1, -1.0),
            (3, 3, 2.0),
        ],
        n: vec![(0, 1, -1.0), (1, 3, -1.0)],
        t: vec![(0, 0, 1.0), (1, 2, 1.0)],
    }
}

/// f = (3, -3, 0, 0), g = (1, 2), Tresca p = (1, 2).
/// Normal: the free solution K_y^-1 (-3, 0) = (-2, -1) penetrates at node 1
/// (-2 < -1) only. Node 1 closed: y1 = -1; row y2: 1 + 2 y2 = 0 -> y2 = -0.5 >= -2
/// (node 2 open, lN2 = 0); row y1: -2 + 0.5 = -3 + lN1 -> lN1 = 1.5.
/// Tangential (Tresca acts whatever the normal state): guess node 1 slips
/// (lT1 = 1) and node 2 sticks (x2 = 0): row x1: 2 x1 = 3 - 1 -> x1 = 1 > 0 (slip
/// along lT1); row x2: -1 = -lT2 -> lT2 = 1 < p2 = 2 (stick). Node 2 is open but
/// sticks: counted as open.
#[test]
fn coupled_pair_tresca() {
    check(
        "coupled pair Tresca",
        &coupled_pair_2d(),
        &[3.0, -3.0, 0.0, 0.0],
        &[1.0, 2.0],
        &Law::Tresca(vec![1.0, 2.0]),
        &expect(&[1.0, -1.0, 0.0, -0.5], &[1.5, 0.0], &[1.0, 1.0], (1, 0, 1)),
    );
}

/// As `coupled_pair_tresca` with Coulomb mu = (0.5, 0.5): lN = (1.5, 0), so
/// p = (0.75, 0). Node 2 is free tangentially: lT2 = 0, row x2: -x1 + 2 x2 = 0 ->
/// x2 = x1 / 2; row x1: 2 x1 - x1/2 = 3 - 0.75 -> x1 = 1.5, x2 = 0.75 (node 1 slips
/// along lT1 = 0.75 > 0).
#[test]
fn coupled_pair_coulomb_open_and_slip() {
    check(
        "coupled pair Coulomb open + slip",
        &coupled_pair_2d(),
        &[3.0, -3.0, 0.0, 0.0],
        &[1.0, 2.0],
        &Law::Coulomb(vec![0.5, 0.5]),
        &expect(
            &[1.5, -1.0, 0.75, -0.5],
            &[1.5, 0.0],
            &[0.75, 0.0],
            (1, 0, 1),
        ),
    );
}

/// f = (3, -3, 0, 0), g = (1, 0.25): with node 1 closed alone, y2 = -0.5 < -0.25
/// would penetrate, so both close: y = (-1, -0.25); row y1: -2 + 0.25 = -3 + lN1 ->
/// lN1 = 1.25; row y2: 1 - 0.5 = lN2 -> lN2 = 0.5.
/// Coulomb mu = (0.4, 4): p = (0.5, 2). Node 1 slips (lT1 = 0.5), node 2 sticks
/// (x2 = 0): 2 x1 = 3 - 0.5 -> x1 = 1.25; row x2: -1.25 = -lT2 -> lT2 = 1.25 < 2.
#[test]
fn coupled_pair_coulomb_slip_and_stick() {
    check(
        "coupled pair Coulomb slip + stick",
        &coupled_pair_2d(),
        &[3.0, -3.0, 0.0, 0.0],
        &[1.0, 0.25],
        &Law::Coulomb(vec![0.4, 4.0]),
        &expect(
            &[1.25, -1.0, 0.0, -0.25],
            &[1.25, 0.5],
            &[0.5, 1.25],
            (0, 1, 1),
        ),
    );
}

/// As above with mu = (0.4, 0.4): p = (0.5, 0.2). Both slip: lT = (0.5, 0.2);
/// 2 x1 - x2 = 2.5, -x1 + 2 x2 = -0.2 -> x1 = 1.6, x2 = 0.7 (both > 0, along lT).
#[test]
fn coupled_pair_coulomb_both_slip() {
    check(
        "coupled pair Coulomb both slip",
        &coupled_pair_2d(),
        &[3.0, -3.0, 0.0, 0.0],
        &[1.0, 0.25],
        &Law::Coulomb(vec![0.4, 0.4]),
        &expect(
            &[1.6, -1.0, 0.7, -0.25],
            &[1.25, 0.5],
            &[0.5, 0.2],
            (0, 0, 2),
        ),
    );
}

// ---------------------------------------------------------------------------------
// One node whose K couples the normal and the tangential DOF: K = [2 1; 1 2]
// (DOFs u_x, u_y), N = [0, -1], T = [1, 0], g = 0.5, f = (0.2, -3).
//   x row: 2 u_x + u_y = 0.2 - lT
//   y row: u_x + 2 u_y = -3 + lN
// ---------------------------------------------------------------------------------

fn coupled_xy_node() -> Data {
    Data {
        d: 2,
        ndof: 2,
        m: 1,
        k: vec![(0, 0, 2.0), (0, 1, 1.0), (1, 0, 1.0), (1, 1, 2.0)],
        n: vec![(0, 1, -1.0)],
        t: vec![(0, 0, 1.0)],
    }
}

/// Tresca p = 1, stick: u = (0, -0.5); x row: -0.5 = 0.2 - lT -> lT = 0.7 < 1;
/// y row: -1 = -3 + lN -> lN = 2.
#[test]
fn coupled_xy_tresca_stick() {
    check(
        "coupled x-y Tresca stick",
        &coupled_xy_node(),
        &[0.2, -3.0],
        &[0.5],
        &Law::Tresca(vec![1.0]),
        &expect(&[0.0, -0.5], &[2.0], &[0.7], (0, 1, 0)),
    );
}

/// Coulomb mu = 0.3: sticking would need lT = 0.7 > 0.3 * 2 = 0.6, so it slips
/// with lT = 0.3 lN, and lN now depends on the slip u_x (the fixed point):
///   y row: lN = u_x + 2 (-0.5) + 3 = u_x + 2
///   x row: 2 u_x - 0.5 = 0.2 - 0.3 (u_x + 2)  ->  2.3 u_x = 0.1  ->  u_x = 1/23
/// lN = 47/23, lT = 0.3 * 47/23 = 14.1/23 (> 0, the same sign as u_x).
#[test]
fn coupled_xy_coulomb_slip() {
    let ux = 1.0 / 23.0;
    let ln = 47.0 / 23.0;
    check(
        "coupled x-y Coulomb slip (fixed point)",
        &coupled_xy_node(),
        &[0.2, -3.0],
        &[0.5],
        &Law::Coulomb(vec![0.3]),
        &expect(&[ux, -0.5], &[ln], &[0.3 * ln], (0, 0, 1)),
    );
}

// ---------------------------------------------------------------------------------
// One node in 3D, K = diag(2, 2, 4) (isotropic in the tangent plane), N = [0,0,-1],
// T rows e_x, e_y. With t = (f_x, f_y):
//   tangential rows: 2 u_t = t - lambda_T;  z row: 4 u_z = f_z + lambda_N.
// Slip: lambda_T = p t/|t| and u_t = (|t| - p)/2 t/|t|, parallel to lambda_T.
// ---------------------------------------------------------------------------------

fn one_node_3d() -> Data {
    Data {
        d: 3,
        ndof: 3,
        m: 1,
        k: vec![(0, 0, 2.0), (1, 1, 2.0), (2, 2, 4.0)],
        n: vec![(0, 2, -1.0)],
        t: vec![(0, 0, 1.0), (1, 1, 1.0)],
    }
}

/// f = (3, 4, -6), g = 0.5, Tresca p = 2.5: lambda_N = -4 * 0.5 + 6 = 4; |t| = 5 > 2.5:
/// lambda_T = 2.5 (0.6, 0.8) = (1.5, 2), u_t = (3 - 1.5, 4 - 2)/2 = (0.75, 1).
#[test]
fn slip_3d_tresca() {
    check(
        "slip 3D Tresca",
        &one_node_3d(),
        &[3.0, 4.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![2.5]),
        &expect(&[0.75, 1.0, -0.5], &[4.0], &[1.5, 2.0], (0, 0, 1)),
    );
}

/// f = (3, 4, -6), g = 0.5, Tresca p = 6 > |t| = 5: stick, lambda_T = (3, 4).
#[test]
fn stick_3d_tresca() {
    check(
        "stick 3D Tresca",
        &one_node_3d(),
        &[3.0, 4.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![6.0]),
        &expect(&[0.0, 0.0, -0.5], &[4.0], &[3.0, 4.0], (0, 1, 0)),
    );
}

/// f = (3, 4, -6), g = 0.5, Coulomb mu = 0.5: lambda_N = 4, p = 2 < 5: slip,
/// lambda_T = 2 (0.6, 0.8) = (1.2, 1.6), u_t = (3 - 1.2, 4 - 1.6)/2 = (0.9, 1.2).
#[test]
fn slip_3d_coulomb() {
    check(
        "slip 3D Coulomb",
        &one_node_3d(),
        &[3.0, 4.0, -6.0],
        &[0.5],
        &Law::Coulomb(vec![0.5]),
        &expect(&[0.9, 1.2, -0.5], &[4.0], &[1.2, 1.6], (0, 0, 1)),
    );
}

/// f = (3, 4, -6), g = 0.5, Coulomb mu = 2: p = 8 > 5: stick, lambda_T = (3, 4).
#[test]
fn stick_3d_coulomb() {
    check(
        "stick 3D Coulomb",
        &one_node_3d(),
        &[3.0, 4.0, -6.0],
        &[0.5],
        &Law::Coulomb(vec![2.0]),
        &expect(&[0.0, 0.0, -0.5], &[4.0], &[3.0, 4.0], (0, 1, 0)),
    );
}

/// Separation: f = (3, 4, 1), g = 0, Coulomb mu = 0.5: u = K^-1 f = (1.5, 2, 0.25),
/// N u = -0.25 <= 0, lambda = 0.
#[test]
fn separation_3d() {
    check(
        "separation 3D",
        &one_node_3d(),
        &[3.0, 4.0, 1.0],
        &[0.0],
        &Law::Coulomb(vec![0.5]),
        &expect(&[1.5, 2.0, 0.25], &[0.0], &[0.0, 0.0], (1, 0, 0)),
    );
}

/// Initial penetration: f = (3, 4, 0), g = -0.5: u_z = 0.5, lambda_N = 2; Coulomb
/// mu = 0.5: p = 1, slip: lambda_T = (0.6, 0.8), u_t = (2.4, 3.2)/2 = (1.2, 1.6).
#[test]
fn negative_gap_3d() {
    check(
        "negative gap 3D",
        &one_node_3d(),
        &[3.0, 4.0, 0.0],
        &[-0.5],
        &Law::Coulomb(vec![0.5]),
        &expect(&[1.2, 1.6, 0.5], &[2.0], &[0.6, 0.8], (0, 0, 1)),
    );
}

/// Frictionless 3D (Tresca p = 0): f = (3, 4, -6), g = 0.5: lambda_T = 0,
/// u = (1.5, 2, -0.5), lambda_N = 4.
#[test]
fn frictionless_3d() {
    check(
        "frictionless 3D",
        &one_node_3d(),
        &[3.0, 4.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![0.0]),
        &expect(&[1.5, 2.0, -0.5], &[4.0], &[0.0, 0.0], (0, 0, 1)),
    );
}

/// Two nodes in 3D coupled by tangential springs. DOFs (x1, y1, z1, x2, y2, z2):
/// x rows [2 -1; -1 2] on (x1, x2), the same on (y1, y2), z rows diag(4, 4).
/// f = (3, 4, -8, 0, 0, -8), g = (0, 1), Tresca p = (1, 3).
/// Normal: u_z1 = 0 (free -2 < 0): lN1 = 8; u_z2 = -1 (free -2 < -1): -4 = -8 + lN2,
/// lN2 = 4.
/// Tangential: guess node 2 sticks (u_t2 = 0) and node 1 slips: 2 u_t1 = t1 - lT1
/// with lT1 = p1 u_t1/|u_t1| gives u_t1 parallel to t1 = (3, 4):
/// 2 |u_t1| = 5 - 1 -> u_t1 = 2 (0.6, 0.8) = (1.2, 1.6), lT1 = (0.6, 0.8);
/// rows of node 2: -u_t1 = -lT2 -> lT2 = (1.2, 1.6), |lT2| = 2 < 3 (stick).
fn coupled_pair_3d() -> Data {
    Data {
        d: 3,
        ndof: 6,
        m: 2,
        k: vec![
            (0, 0, 2.0),
            (0, 3, -1.0),
            (3, 0, -1.0),
            (3, 3, 2.0),
            (1, 1, 2.0),
            (1, 4, -1.0),
            (4, 1, -1.0),
            (4, 4, 2.0),
            (2, 2, 4.0),
            (5, 5, 4.0),
        ],
        n: vec![(0, 2, -1.0), (1, 5, -1.0)],
        t: vec![(0, 0, 1.0), (1, 1, 1.0), (2, 3, 1.0), (3, 4, 1.0)],
    }
}

#[test]
fn coupled_pair_3d_tresca() {
    let data = coupled_pair_3d();
    check(
        "coupled pair 3D Tresca",
        &data,
        &[3.0, 4.0, -8.0, 0.0, 0.0, -8.0],
        &[0.0, 1.0],
        &Law::Tresca(vec![1.0, 3.0]),
        &expect(
            &[1.2, 1.6, 0.0, 0.0, 0.0, -1.0],
            &[8.0, 4.0],
            &[0.6, 0.8, 1.2, 1.6],
            (0, 1, 1),
        ),
    );
}

// ---------------------------------------------------------------------------------
// History mode: ContactProblem::step with the total load (docs/design.md section 1):
// at step k the increment problem has f := f_total - K u_k, g := g0 - N u_k and
// friction acts on T du; the returned u is u_k + du and the multipliers are totals.
// ---------------------------------------------------------------------------------

/// Runs the steps on a fresh problem with each method; checks each step.
fn check_history(name: &str, data: &Data, g0: &[f64], law: &Law, steps: &[(Vec<f64>, Expect)]) {
    // Scales over the whole history (a step may have f_total = 0 and lambda = 0).
    let u_scale = steps
        .iter()
        .fold(norm_inf(g0), |a, (_, w)| a.max(norm_inf(&w.u)));
    let l_scale = steps.iter().fold(0.0f64, |a, (f, w)| {
        a.max(norm_inf(f))
            .max(norm_inf(&w.lambda_n))
            .max(norm_inf(&w.lambda_t))
    });
    for method in Method::ALL {
        let mut pb = data.problem();
        for (s, (f_total, want)) in steps.iter().enumerate() {
            let sol = pb
                .step(f_total, g0, law.friction(), &opts(method))
                .expect("step accepts the data");
            let what = format!("{name} step {} [{}]", s + 1, method.name());
            assert_converged(&what, &sol);
            assert_close(&format!("{what}: u"), &sol.u, &want.u, REL, u_scale);
            assert_close(
                &format!("{what}: lambda_N"),
                &sol.lambda_n,
                &want.lambda_n,
                REL,
                l_scale,
            );
            assert_close(
                &format!("{what}: lambda_T"),
                &sol.lambda_t,
                &want.lambda_t,
                REL,
                l_scale,
            );
            let r = &sol.report;
            if let Some(states) = want.states {
                assert_eq!(
                    (r.n_open, r.n_stick, r.n_slip),
                    states,
                    "{what}: contact states (open, stick, slip)"
                );
            }
        }
    }
}

/// One node 2D (K = diag(2, 4)), g0 = 0.5, Tresca p = 2, the same total load
/// f = (5, -6) twice. Step 1 is `slip_2d_tresca`: u = (1.5, -0.5), lN = 4, lT = 2.
/// Step 2: f := f - K u_1 = (5, -6) - (3, -2) = (2, -4) = N^T lN + T^T lT of step 1
/// (by the equilibrium of step 1), g := 0.5 - 0.5 = 0. du = 0 with the same
/// multipliers satisfies every condition (slip with alpha = 0), du = 0 is the unique
/// minimiser and B = [N; T] has full row rank: the totals are unchanged. Step 2 is
/// degenerate (|lambda_T| = p and zero slip increment): its state is not checked.
#[test]
fn history_same_load_twice() {
    let want = expect(&[1.5, -0.5], &[4.0], &[2.0], (0, 0, 1));
    let f = vec![5.0, -6.0];
    check_history(
        "history same load twice",
        &one_node_2d(),
        &[0.5],
        &Law::Tresca(vec![2.0]),
        &[(f.clone(), want.clone()), (f, want.degenerate())],
    );
}

/// Monotonic loading, 2D: step 1 f = (1, -6) sticks (u = (0, -0.5), lN = 4, lT = 1);
/// step 2 f = (5, -6): increment f = (5, -6) - K (0, -0.5) = (5, -4), g = 0:
/// du_y = 0 with lN = 4; 2 du_x = 5 - lT, slip lT = 2, du_x = 1.5. Totals as in
/// `slip_2d_tresca`.
#[test]
fn history_stick_then_slip() {
    check_history(
        "history stick then slip",
        &one_node_2d(),
        &[0.5],
        &Law::Tresca(vec![2.0]),
        &[
            (
                vec![1.0, -6.0],
                expect(&[0.0, -0.5], &[4.0], &[1.0], (0, 1, 0)),
            ),
            (
                vec![5.0, -6.0],
                expect(&[1.5, -0.5], &[4.0], &[2.0], (0, 0, 1)),
            ),
        ],
    );
}

/// Path dependence in 3D (K = diag(2, 2, 4), g0 = 0.5, Tresca p = 2):
/// step 1 f = (6, 0, -6): lN = 4, slip lT = (2, 0), u_t = (6 - 2, 0)/2 = (2, 0).
/// step 2 f = (6, 6, -6): increment tangential load (6, 6) - 2 (2, 0) = (2, 6),
/// |(2, 6)| = sqrt(40) > 2: slip along (2, 6): lT = 2 (2, 6)/sqrt(40) = (2, 6)/sqrt(10)
/// du_t = ((2, 6) - lT)/2 = (1, 3)(1 - 1/sqrt(10)); total u_t = (2, 0) + du_t.
/// (A single solve with f = (6, 6, -6) would give lT = sqrt(2) (1, 1) instead: the
/// friction acts on the increment.)
#[test]
fn history_path_dependent_3d() {
    let s = 1.0 - 1.0 / 10f64.sqrt();
    let r = 1.0 / 10f64.sqrt();
    check_history(
        "history path dependent 3D",
        &one_node_3d(),
        &[0.5],
        &Law::Tresca(vec![2.0]),
        &[
            (
                vec![6.0, 0.0, -6.0],
                expect(&[2.0, 0.0, -0.5], &[4.0], &[2.0, 0.0], (0, 0, 1)),
            ),
            (
                vec![6.0, 6.0, -6.0],
                expect(
                    &[2.0 + s, 3.0 * s, -0.5],
                    &[4.0],
                    &[2.0 * r, 6.0 * r],
                    (0, 0, 1),
                ),
            ),
        ],
    );
}

/// Unloading opens the contact (2D, K = diag(2, 4), g0 = 0.5, Coulomb mu = 0.5):
/// step 1 f = (1, -6): closed, stick: u = (0, -0.5), lN = 4, lT = 1.
/// step 2 f = (1, 2): increment f = (1, 2) - K (0, -0.5) = (1, 4), g = 0. The free
/// increment du = (0.5, 1) has N du = -1 <= 0: the contact opens, lN = 0, p = 0,
/// lT = 0, and the total u = (0.5, 0.5) = K^-1 f_total.
#[test]
fn history_unloading_opens() {
    check_history(
        "history unloading opens",
        &one_node_2d(),
        &[0.5],
        &Law::Coulomb(vec![0.5]),
        &[
            (
                vec![1.0, -6.0],
                expect(&[0.0, -0.5], &[4.0], &[1.0], (0, 1, 0)),
            ),
            (
                vec![1.0, 2.0],
                expect(&[0.5, 0.5], &[0.0], &[0.0], (1, 0, 0)),
            ),
        ],
    );
}

/// Full unloading of the coupled pair (2D, Coulomb):
/// step 1 as `coupled_pair_coulomb_slip_and_stick` (g0 = (1, 0.25));
/// step 2 f_total = 0: the increment f = -K u_1, g = g0 - N u_1 = 0. The free
/// increment du = -u_1 brings the body back to u = 0, where N u = 0 <= g0: both
/// contacts open, lambda = 0 and u = K^-1 0 = 0.
#[test]
fn history_coupled_unload_to_zero() {
    check_history(
        "history coupled unload",
        &coupled_pair_2d(),
        &[1.0, 0.25],
        &Law::Coulomb(vec![0.4, 4.0]),
        &[
            (
                vec![3.0, -3.0, 0.0, 0.0],
                expect(
                    &[1.25, -1.0, 0.0, -0.25],
                    &[1.25, 0.5],
                    &[0.5, 1.25],
                    (0, 1, 1),
                ),
            ),
            (
                vec![0.0; 4],
                expect(&[0.0; 4], &[0.0, 0.0], &[0.0, 0.0], (2, 0, 0)),
            ),
        ],
    );
}

// ---------------------------------------------------------------------------------
// General directions: the same problems in rotated coordinates. With an orthogonal
// R (block diagonal, one d x d rotation per node) and x = R^T x', the data
// K' = R K R^T, N' = N R^T, T' = T R^T, f' = R f, g' = g have the solution
// u' = R u with the same multipliers (every condition of section 1 is invariant:
// K' u' = R K u, N' u' = N u, T' u' = T u). N and T rows now have several entries.
// ---------------------------------------------------------------------------------

/// The block-diagonal rotation of `d`-DOF nodes, as a dense ndof x ndof matrix.
fn rotation(d: usize, ndof: usize) -> Vec<Vec<f64>> {
    let r: Vec<Vec<f64>> = if d == 2 {
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        vec![vec![c, -s], vec![s, c]]
    } else {
        // Rz(0.3) Rx(0.5)
        let (cz, sz) = (0.3f64.cos(), 0.3f64.sin());
        let (cx, sx) = (0.5f64.cos(), 0.5f64.sin());
        let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
        let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
        (0..3)
            .map(|i| {
                (0..3)
                    .map(|j| (0..3).map(|k| rz[i][k] * rx[k][j]).sum())
                    .collect()
            })
            .collect()
    };
    let mut big = vec![vec![0.0; ndof]; ndof];
    for b in 0..ndof / d {
        for i in 0..d {
            for j in 0..d {
                big[b * d + i][b * d + j] = r[i][j];
            }
        }
    }
    big
}

fn dense(nrows: usize, ncols: usize, trip: &[(usize, usize, f64)]) -> Vec<Vec<f64>> {
    let mut a = vec![vec![0.0; ncols]; nrows];
    for &(i, j, v) in trip {
        a[i][j] += v;
    }
    a
}

fn triplets(a: &[Vec<f64>]) -> Vec<(usize, usize, f64)> {
    let mut t = Vec::new();
    for (i, row) in a.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            if v != 0.0 {
                t.push((i, j, v));
            }
        }
    }
    t
}

/// a b^T-style products on dense matrices: a * b.
fn matmul(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let (n, k, m) = (a.len(), b.len(), b[0].len());
    (0..n)
        .map(|i| {
            (0..m)
                .map(|j| (0..k).map(|l| a[i][l] * b[l][j]).sum())
                .collect()
        })
        .collect()
}

fn transpose(a: &[Vec<f64>]) -> Vec<Vec<f64>> {
    (0..a[0].len())
        .map(|j| a.iter().map(|row| row[j]).collect())
        .collect()
}

fn matvec(a: &[Vec<f64>], x: &[f64]) -> Vec<f64> {
    a.iter()
        .map(|row| row.iter().zip(x).map(|(p, q)| p * q).sum())
        .collect()
}

/// Checks `data` rotated: the rotated load gives the rotated displacement and the
/// same multipliers.
fn check_rotated(name: &str, data: &Data, f: &[f64], g: &[f64], law: &Law, want: &Expect) {
    let r = rotation(data.d, data.ndof);
    let rt = transpose(&r);
    let k = dense(data.ndof, data.ndof, &data.k);
    let mut k_rot = matmul(&matmul(&r, &k), &rt);
    // R K R^T is symmetric up to rounding: make it exactly symmetric.
    for i in 0..data.ndof {
        for j in 0..i {
            let s = 0.5 * (k_rot[i][j] + k_rot[j][i]);
            k_rot[i][j] = s;
            k_rot[j][i] = s;
        }
    }
    let n_rot = matmul(&dense(data.m, data.ndof, &data.n), &rt);
    let t_rot = matmul(&dense((data.d - 1) * data.m, data.ndof, &data.t), &rt);
    let rotated = Data {
        k: triplets(&k_rot),
        n: triplets(&n_rot),
        t: triplets(&t_rot),
        ..data.clone()
    };
    let want_rot = Expect {
        u: matvec(&r, &want.u),
        ..want.clone()
    };
    check(name, &rotated, &matvec(&r, f), g, law, &want_rot);
}

/// `slip_2d_tresca` rotated by 0.3 rad.
#[test]
fn rotated_slip_2d_tresca() {
    check_rotated(
        "rotated slip 2D Tresca",
        &one_node_2d(),
        &[5.0, -6.0],
        &[0.5],
        &Law::Tresca(vec![2.0]),
        &expect(&[1.5, -0.5], &[4.0], &[2.0], (0, 0, 1)),
    );
}

/// `coupled_xy_coulomb_slip` rotated by 0.3 rad.
#[test]
fn rotated_coupled_xy_coulomb_slip() {
    let ln = 47.0 / 23.0;
    check_rotated(
        "rotated coupled x-y Coulomb slip",
        &coupled_xy_node(),
        &[0.2, -3.0],
        &[0.5],
        &Law::Coulomb(vec![0.3]),
        &expect(&[1.0 / 23.0, -0.5], &[ln], &[0.3 * ln], (0, 0, 1)),
    );
}

/// `slip_3d_coulomb` rotated by Rz(0.3) Rx(0.5).
#[test]
fn rotated_slip_3d_coulomb() {
    check_rotated(
        "rotated slip 3D Coulomb",
        &one_node_3d(),
        &[3.0, 4.0, -6.0],
        &[0.5],
        &Law::Coulomb(vec![0.5]),
        &expect(&[0.9, 1.2, -0.5], &[4.0], &[1.2, 1.6], (0, 0, 1)),
    );
}

/// `coupled_pair_3d_tresca` rotated node by node by Rz(0.3) Rx(0.5).
#[test]
fn rotated_coupled_pair_3d_tresca() {
    let data = coupled_pair_3d();
    check_rotated(
        "rotated coupled pair 3D Tresca",
        &data,
        &[3.0, 4.0, -8.0, 0.0, 0.0, -8.0],
        &[0.0, 1.0],
        &Law::Tresca(vec![1.0, 3.0]),
        &expect(
            &[1.2, 1.6, 0.0, 0.0, 0.0, -1.0],
            &[8.0, 4.0],
            &[0.6, 0.8, 1.2, 1.6],
            (0, 1, 1),
        ),
    );
}
