//! Property test: random small SPD K and random N, T in 2D and 3D (a
//! deterministic SplitMix64 stream, no dependencies). For every case and every
//! method of `Method::ALL`:
//!
//! - the solve converges (err <= 1e-10) and the answer passes the independent KKT
//!   check of tests/common to 1e-9;
//! - the methods agree on u (unique: the primal problem is strictly convex) to
//!   1e-7, and on the multipliers when A is well conditioned (cond(A) < 1e8).
//!
//! Coulomb cases (mu <= 0.4) need not have a unique solution, so only KKT is
//! asserted for them. A failing case prints its seed; rerun it alone with
//! `DUALSPLIT_PROPERTY_SEED=<seed> cargo test --test property -- --nocapture`.

mod common;

use common::{Rng, kkt, max_diff, norm_inf, sym_cond};
use dualsplit::{ContactProblem, Csc, Friction, Method, Options, SolveStatus};

/// One random problem.
struct Case {
    k: Csc,
    n: Csc,
    t: Csc,
    f: Vec<f64>,
    g: Vec<f64>,
    bound: Vec<f64>,
    coulomb: bool,
}

fn random_case(seed: u64, d: usize) -> Case {
    let mut r = Rng(seed);
    let ndof = 3 + r.below(10);
    let m = 1 + r.below((ndof / d).clamp(1, 4));
    // K = M M^T + s I, with a random sparsity pattern in M, scaled by 10^[-3, 3].
    let scale = 10f64.powf(r.range(-3.0, 3.0));
    let mut mm = vec![0.0; ndof * ndof];
    for v in mm.iter_mut() {
        if r.chance(0.5) {
            *v = r.range(-1.0, 1.0);
        }
    }
    let shift = r.range(0.05, 1.0);
    let mut kt = Vec::new();
    for i in 0..ndof {
        for j in 0..ndof {
            let mut s: f64 = (0..ndof).map(|q| mm[i * ndof + q] * mm[j * ndof + q]).sum();
            if i == j {
                s += shift;
            }
            // Keep the exact symmetry of the computed value.
            if s != 0.0 || i == j {
                kt.push((i, j, scale * s));
            }
        }
    }
    // Symmetrise exactly (the sums above are computed in the same order for (i,j)
    // and (j,i) only up to rounding).
    let mut kd = vec![0.0; ndof * ndof];
    for &(i, j, v) in &kt {
        kd[i * ndof + j] = v;
    }
    let mut ks = Vec::new();
    for i in 0..ndof {
        for j in 0..ndof {
            let v = 0.5 * (kd[i * ndof + j] + kd[j * ndof + i]);
            if v != 0.0 || i == j {
                ks.push((i, j, v));
            }
        }
    }
    let k = Csc::from_triplets(ndof, ndof, &ks);
    // N, T: each row touches 1-3 random DOFs with random values; normals mostly
    // "downward" on a DOF of their own.
    let mut nt = Vec::new();
    let mut tt = Vec::new();
    for i in 0..m {
        for _ in 0..1 + r.below(3) {
            nt.push((i, r.below(ndof), r.range(-1.0, 1.0)));
        }
        for s in 0..d - 1 {
            for _ in 0..1 + r.below(3) {
                tt.push(((d - 1) * i + s, r.below(ndof), r.range(-1.0, 1.0)));
            }
        }
    }
    let n = Csc::from_triplets(m, ndof, &nt);
    let t = Csc::from_triplets((d - 1) * m, ndof, &tt);
    // f pushes the body into the foundation along N (so contacts close) plus noise.
    let mut f: Vec<f64> = (0..ndof).map(|_| scale * r.range(-1.0, 1.0)).collect();
    let push = scale * r.range(0.0, 3.0);
    let mut ntr = vec![0.0; ndof];
    n.mul_t_vec(&vec![push; m], &mut ntr);
    for (fi, v) in f.iter_mut().zip(&ntr) {
        *fi += v;
    }
    let g: Vec<f64> = (0..m).map(|_| r.range(-0.2, 0.5)).collect();
    let coulomb = r.chance(0.4);
    let bound: Vec<f64> = if coulomb {
        (0..m).map(|_| r.range(0.0, 0.4)).collect()
    } else {
        (0..m)
            .map(|_| {
                if r.chance(0.2) {
                    0.0
                } else {
                    scale * r.range(0.0, 1.0)
                }
            })
            .collect()
    };
    Case {
        k,
        n,
        t,
        f,
        g,
        bound,
        coulomb,
    }
}

/// Which cases a test takes: well-conditioned A (cond < 1e8; all assertions) or
/// singular / nearly singular A (cond > 1e10: Converged implies KKT, the methods
/// that converge agree on u, and at least one converges; no rule on lambda, which
/// is not unique). Cases with 1e8 <= cond(A) <= 1e10 are in neither. Returns
/// whether the case was taken.
#[derive(Copy, Clone, PartialEq, Eq)]
enum Kind {
    Regular,
    Singular,
}

fn cond_of(c: &Case, d: usize) -> f64 {
    let pb = ContactProblem::from_csc(d, c.k.clone(), c.n.clone(), c.t.clone()).unwrap();
    let dual = pb.dual();
    let (c, da) = (dual.unknowns(), dual.dense().expect("A is formed"));
    let a = faer::Mat::<f64>::from_fn(c, c, |i, j| da[i + j * c]);
    sym_cond(a.as_ref())
}

fn check_case(seed: u64, d: usize, kind: Kind, tol: f64, kkt_tol: f64) -> bool {
    let c = random_case(seed, d);
    let cond_a = cond_of(&c, d);
    let take = match kind {
        Kind::Regular => cond_a < 1e8,
        Kind::Singular => cond_a > 1e10,
    };
    if !take {
        return false;
    }
    let friction = if c.coulomb {
        Friction::Coulomb(&c.bound)
    } else {
        Friction::Tresca(&c.bound)
    };
    let what = |m: Method| {
        format!(
            "seed {seed} d {d} n {} m {} {} [{}]",
            c.k.nrows,
            c.n.nrows,
            if c.coulomb { "Coulomb" } else { "Tresca" },
            m.name()
        )
    };
    let mut sols = Vec::new();
    for method in Method::ALL {
        let mut pb = ContactProblem::from_csc(d, c.k.clone(), c.n.clone(), c.t.clone())
            .unwrap_or_else(|e| panic!("{}: {e}", what(method)));
        let o = Options {
            method,
            tol,
            max_outer: if kind == Kind::Regular { 10_000 } else { 2000 },
            ..Options::default()
        };
        let sol = pb
            .solve(&c.f, &c.g, friction, &o)
            .unwrap_or_else(|e| panic!("{}: {e}", what(method)));
        if kind == Kind::Singular {
            println!(
                "{}: {:?} err {:.2e} outer {} (cond(A) {cond_a:.2e})",
                what(method),
                sol.report.status,
                sol.report.err,
                sol.report.outer_iterations
            );
            if sol.report.status != SolveStatus::Converged {
                continue;
            }
        }
        assert_eq!(
            sol.report.status,
            SolveStatus::Converged,
            "{}: {:?} (cond(A) = {cond_a:.2e})",
            what(method),
            sol.report
        );
        kkt(
            d,
            &c.k,
            &c.n,
            &c.t,
            &c.f,
            &c.g,
            friction,
            &sol.u,
            &sol.lambda_n,
            &sol.lambda_t,
        )
        .assert_ok(&what(method), kkt_tol);
        sols.push((method, sol));
    }
    if c.coulomb {
        return true;
    }
    // K is SPD, so u is unique even where A is singular (redundant contacts): the
    // methods that converge agree on it, and at least one converges.
    assert!(
        !sols.is_empty(),
        "seed {seed} d {d}: no method converged (cond(A) {cond_a:.2e})"
    );
    let (m0, s0) = &sols[0];
    for (m1, s1) in &sols[1..] {
        let us = norm_inf(&s0.u).max(norm_inf(&s1.u)).max(f64::MIN_POSITIVE);
        let du = max_diff(&s0.u, &s1.u);
        assert!(
            du <= 1e-7 * us,
            "{}: u differs from {} by {du:.3e} (scale {us:.3e})",
            what(*m1),
            m0.name()
        );
        if kind == Kind::Regular && cond_a < 1e8 {
            let l0: Vec<f64> = s0.lambda_n.iter().chain(&s0.lambda_t).copied().collect();
            let l1: Vec<f64> = s1.lambda_n.iter().chain(&s1.lambda_t).copied().collect();
            let ls = norm_inf(&l0).max(norm_inf(&l1)).max(f64::MIN_POSITIVE);
            let dl = max_diff(&l0, &l1);
            assert!(
                dl <= 1e-6 * ls * cond_a.max(1.0).sqrt().min(100.0),
                "{}: lambda differs from {} by {dl:.3e} (scale {ls:.3e}, cond(A) {cond_a:.2e})",
                what(*m1),
                m0.name()
            );
        }
    }
    true
}

fn cases() -> Vec<u64> {
    if let Ok(s) = std::env::var("DUALSPLIT_PROPERTY_SEED") {
        return vec![s.parse().expect("DUALSPLIT_PROPERTY_SEED is a u64")];
    }
    (0..300).map(|i| 0x5EED_0000 + i).collect()
}

/// Infeasible problems (two contact rows on one DOF with opposite normals and
/// incompatible gaps: no u satisfies N u <= g; cond(A) ~ 1e17). The dual is
/// unbounded below along z with B^T z = 0, z_N >= 0. A method that follows z makes
/// err = |r| / max(|lambda|, ...) tiny with |lambda| ~ 1e15..1e18 while u, from
/// f - B^T lambda with total cancellation, penetrates: SplitMprgp and Mprgp used to
/// report Converged there (|lambda| 3e15, penetration 0.19 of max|u| on the first
/// seed), and Newton before its stall exit and minimum-norm steps.
const INFEASIBLE: [(u64, usize); 2] = [(1592590493, 2), (1592590535, 2)];

fn run(d: usize, kind: Kind, tol: f64, kkt_tol: f64) {
    let mut taken = 0;
    let mut failed = Vec::new();
    for seed in cases() {
        if INFEASIBLE.iter().any(|&(b, bd)| b == seed && bd == d) {
            continue;
        }
        match std::panic::catch_unwind(|| check_case(seed, d, kind, tol, kkt_tol)) {
            Ok(true) => taken += 1,
            Ok(false) => {}
            Err(_) => failed.push(seed),
        }
    }
    println!("d = {d}: {taken} cases passed");
    assert!(failed.is_empty(), "d = {d}: failing seeds {failed:?}");
    if std::env::var("DUALSPLIT_PROPERTY_SEED").is_err() {
        assert!(taken >= 20, "only {taken} cases taken");
    }
}

#[test]
fn random_problems_2d() {
    run(2, Kind::Regular, 1e-10, 1e-8);
}

#[test]
fn random_singular_problems_2d_terminate_honestly() {
    run(2, Kind::Singular, 1e-10, 1e-7);
}

#[test]
fn random_singular_problems_3d_terminate_honestly() {
    run(3, Kind::Singular, 1e-10, 1e-7);
}

#[test]
fn random_problems_3d() {
    run(3, Kind::Regular, 1e-10, 1e-8);
}

/// The bar: KKT to 1e-9, asked for with tol = 1e-11 (worst over the 600
/// cases: 4.6e-10, seed 1592590579 d 3, Coulomb, PGS).
///
/// err does not bound the slip-direction residual by a constant. err is a force
/// residual relative to |lambda|; slip_direction is kinematic,
/// |T u - alpha lambda_T| / max|u|. For a slipping contact whose force points off
/// by an angle delta, r_T ~ p_i delta but slip_direction ~ |T u|_i delta / max|u|,
/// so slip_direction ~ err (|lambda| / p_i) (|T u|_i / max|u|). On seed 1592590343
/// (d = 3, Tresca, p = 0.13 against lambda_N = 18.5) the factor is about 205: there
/// BlockGs used to stop at err 6.7e-12 (1.5e-11 at err's honest scale) with
/// slip_direction 3.0e-9. Since err's force scale no longer hides the residual
/// (report.rs) the sub-problems are solved to the honest tolerance and BlockGs ends
/// at err 8.4e-14 (KKT 1.7e-11); the largest KKT / err over all cases is 206 (that
/// seed, SplitMprgp, err 1.1e-13). So 1e-9 holds with a margin of 2, not by a
/// bound: a contact with p_i << |lambda| turns err = 1e-11 into a slip-direction
/// violation of about (|lambda| / p_i) 1e-11. (The Split stall at err 2.0e-11 on
/// seed 1592590399 no longer occurs: Split converges in 2 outer iterations, err
/// 1.4e-12.)
#[test]
fn random_problems_kkt_1e9() {
    run(2, Kind::Regular, 1e-11, 1e-9);
    run(3, Kind::Regular, 1e-11, 1e-9);
}

/// The infeasible seeds: no method may report Converged; the MPRGP methods detect
/// the unbounded dual (err infinite, NotConverged) within a few outer iterations,
/// stopping before the multipliers blow up. The other methods cannot tell: their
/// multipliers grow along the unbounded direction, |lambda| ~ k, so err ~ 1/k
/// falls ever slower, and the stagnation test (10 % per 100 iterations) ends them
/// Stalled after about 1,000 outer iterations, before their limit of 5,000 (and
/// long before err could creep to the tolerance).
#[test]
fn infeasible_problems_are_never_reported_converged() {
    for (seed, d) in INFEASIBLE {
        let c = random_case(seed, d);
        let friction = if c.coulomb {
            Friction::Coulomb(&c.bound)
        } else {
            Friction::Tresca(&c.bound)
        };
        for method in Method::ALL {
            let mut pb = ContactProblem::from_csc(d, c.k.clone(), c.n.clone(), c.t.clone())
                .expect("valid problem");
            let o = Options {
                method,
                tol: 1e-10,
                max_outer: 5000,
                ..Options::default()
            };
            let sol = pb.solve(&c.f, &c.g, friction, &o).expect("valid solve");
            let r = &sol.report;
            let lmax = sol
                .lambda_n
                .iter()
                .chain(&sol.lambda_t)
                .fold(0.0f64, |a, x| a.max(x.abs()));
            println!(
                "seed {seed} [{}]: {:?} err {:.2e} outer {} inner {} max|lambda| {lmax:.2e}",
                method.name(),
                r.status,
                r.err,
                r.outer_iterations,
                r.inner_iterations
            );
            if method == Method::Auto {
                // Newton stalls (as below), then auto's fallback, split-mprgp,
                // detects the unbounded dual from Newton's best iterate.
                assert_eq!(r.method, Method::SplitMprgp, "seed {seed}: {r:?}");
                assert!(r.choice.contains("stalled"), "{}", r.choice);
                assert_eq!(r.status, SolveStatus::NotConverged, "seed {seed}: {r:?}");
                assert_eq!(r.err, f64::INFINITY, "seed {seed}");
                assert!(r.outer_iterations < 2000, "seed {seed}: {r:?}");
            } else if matches!(method, Method::SplitMprgp | Method::Mprgp) {
                assert_eq!(
                    r.status,
                    SolveStatus::NotConverged,
                    "seed {seed} [{}]",
                    method.name()
                );
            } else {
                assert_eq!(
                    r.status,
                    SolveStatus::Stalled,
                    "seed {seed} [{}]",
                    method.name()
                );
                assert!(
                    r.outer_iterations < 2000,
                    "seed {seed} [{}]: {r:?}",
                    method.name()
                );
            }
            if matches!(method, Method::SplitMprgp | Method::Mprgp) {
                assert_eq!(r.err, f64::INFINITY, "seed {seed} [{}]", method.name());
                assert!(r.outer_iterations <= 5, "seed {seed} [{}]", method.name());
                assert!(
                    lmax < 1e6,
                    "seed {seed} [{}]: max|lambda| {lmax:.2e}",
                    method.name()
                );
            }
        }
    }
}
