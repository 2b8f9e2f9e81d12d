//! Semismooth Newton (primal-dual active set) on the condensed dual, for the
//! natural map of docs/design.md section 5:
//!
//! ```text
//! F(lambda) = lambda - P(lambda - rho (A lambda - b)),
//! ```
//!
//! P the projection onto lambda_N >= 0, |lambda_T,i| <= p_i. At each iteration the
//! trial y = lambda - rho (A lambda - b) sorts every component: a closed normal or a
//! sticking tangential component is free (its equation is (A d)_j = -F_j / rho_i),
//! an open normal or a 2D slipping tangential component is fixed (d_j = -F_j). In 3D
//! a slipping contact splits along n = y_T/|y_T| (fixed: the bound) and the
//! orthogonal t (free, with the curvature term (1 - s)/(s rho), s = p/|y_T|), the
//! generalised Jacobian of the disk projection (Hueber, Stadler, Wohlmuth). For
//! Coulomb the bound mu lambda_N is differentiated too: the slipping tangential
//! force follows the normal one. The reduced system on the free unknowns is solved
//! densely (a free row's equation is (A d)_j = -w_j, w = A lambda - b): by
//! Cholesky where it is symmetric, in single precision with refinement in
//! double from order MIXED_MIN on, else by LU (`solve_reduced`). The single-
//! precision factor is kept for the next step: where that step has the same
//! reduced unknowns, or a few more or fewer (the active set settling, slip
//! directions turning; `Reused`), CG preconditioned by it solves the next
//! system without a new factorisation.
//!
//! A numerically singular reduced system (A singular: redundant or dependent
//! contact rows) is solved in the least-squares sense with the minimum norm
//! (truncated SVD), never by the LU's arbitrary, possibly enormous, null-space
//! component: on an infeasible problem (no u satisfies N u <= g) the dual is
//! unbounded along a direction z with B^T z = 0, and a step of size 1e15 along z
//! would make err = |F| / max(|lambda|, ...) tiny without solving anything.
//!
//! Globalisation: a Newton step (or, backtracking, half, a quarter or an eighth
//! of it) is kept only if it lowers the natural residual |F| (force units) by the
//! factor 1 - ARMIJO t; err is not the merit, since its
//! denominator grows with |lambda| and a step could "lower" it by inflating the
//! multipliers. Otherwise the iterate takes a few projected Gauss-Seidel sweeps (a
//! first-order descent step for Tresca) and Newton restarts from there, so it
//! cannot cycle. When neither has lowered |F| by STALL_DROP for STALL_WINDOW
//! iterations the solve gives up (stalled) instead of burning the iteration limit
//! on a problem without a solution.
//!
//! Warm-up: every solve on a dense A starts with up to PRESWEEPS projected
//! Gauss-Seidel sweeps (cheap against a Newton step), so that the first active
//! set Newton sees is near the answer; they, and the fallback's, read A in
//! single precision on a large dual (`pgs::Rough`, `pgs::ROUGH_MIN_C`). A
//! matrix-free dual has no entries to sweep: a cold solve starts instead at the projection of alpha G b, G = B K B^T
//! the lumped estimate of A^-1 (alpha minimising the dual energy along G b),
//! when that lowers |F|; its reduced systems are solved by CG / GMRES
//! preconditioned with G too (`krylov_step`).
//!
//! Warm start: the first step of a warm-started solve sorts the components by the
//! multipliers (see WARM_C), not by the natural map, so that a history step starts
//! from the active set of the previous increment; where the start is a history's
//! prediction (`DualProblem::predicted`: the load increment is already in it), by
//! the natural map at it.

use super::driver::{Flow, Gradient, OuterStep};
use super::mprgp::ConvexQp;
use super::pgs;
use super::subproblem::Mprgp;
use super::{DualProblem, MethodSpec};
use crate::dense;
use crate::friction::Friction;
use crate::memory::{F64, Ledger};
use crate::threads::{PARALLEL_MIN_ENTRIES, Threads};
use faer::Mat;
use std::sync::Arc;

/// Gauss-Seidel sweeps taken when a Newton step is rejected.
const FALLBACK_SWEEPS: usize = 5;

/// MPRGP iterations taken instead when a Newton step on a matrix-free dual is
/// rejected (each one product with A, as a Krylov iteration of a step).
const FALLBACK_MPRGP: usize = 20;

/// Projected Gauss-Seidel sweeps before the first Newton step, in chunks of
/// PRESWEEP_CHUNK with the error checked in between. From a cold start (every
/// closed contact then looks like slipping) or after a load change, Newton's first
/// active sets are far from the answer and it spends many steps (one dense LU
/// each) and fallbacks getting near; sweeps cost O(c^2) each against O(k^3) for a
/// step (measurements: BENCHMARKS.md, "Tuning measurements").
const PRESWEEPS: usize = 40;
const PRESWEEP_CHUNK: usize = 10;

/// Step lengths tried along a Newton direction before the Gauss-Seidel fallback:
/// 1, 1/2, ..., 2^-(BACKTRACKS-1) (each costs one product with A); without them
/// Newton can reject every full step (the slender beam of tests/hard_scenes.rs).
const BACKTRACKS: usize = 4;

/// Most products with A in one reduced solve on a matrix-free dual.
const KRYLOV_MAX_IT: usize = 200;

/// Reduced solves on a matrix-free dual whose forcing term is at least this use
/// products with the factor in single precision (half the memory traffic of a
/// solve): their error, about 1e-7 times the factor's conditioning, stays well
/// below the residual such a solve asks for. The step is still checked by the
/// exact gradient (the backtracking), so a rough step can only cost a step.
/// A tighter reduced solve refines in mixed precision (`refine`): rough
/// products for the corrections, exact ones for the residuals.
const ROUGH_ETA: f64 = 1e-4;

/// Sufficient decrease for keeping a Newton step: |F(lam + d)| <= (1 - ARMIJO) |F(lam)|.
const ARMIJO: f64 = 1e-4;

/// The first step of a warm start sorts the components with rho scaled by WARM_C
/// (F_c(lambda) = lambda - P(lambda - c (A lambda - b)) has the same zeros for every
/// c > 0): in the limit c -> 0 the active set is the one the multipliers carry
/// (lambda_N > 0: closed; |lambda_T| < p: stick; |lambda_T| = p: slip), w only
/// breaking the ties. With c = rho the first step of a history step would sort by
/// lambda + rho v at the warm start, where v is the response to the load change
/// with the contact forces frozen (the increment of a free body): every contact
/// then looks like slipping, and Newton spends its first iterations in an all-slip
/// active set (on 2D Coulomb blocks the centre contact flips the sign of its
/// friction force at every step) before it finds the sticking zone again.
const WARM_C: f64 = 1e-6;

/// Singular values below RCOND times the largest are dropped in the reduced solve,
/// and an LU solution z with |M|_max |z|_inf > |rhs|_inf / RCOND is taken as the
/// sign of a (numerically) singular M.
const RCOND: f64 = 1e-12;

/// The solve gives up when the best |F| has not dropped by STALL_DROP (relative)
/// within STALL_WINDOW outer iterations.
const STALL_WINDOW: usize = 50;
const STALL_DROP: f64 = 1e-2;

/// One reduced unknown: its test row and its direction in lambda-space (sparse,
/// at most three entries each), a diagonal term and the right-hand side.
struct Reduced {
    test: [(usize, f64); 2],
    n_test: usize,
    dir: [(usize, f64); 3],
    n_dir: usize,
    diag: f64,
    rhs: f64,
}

impl Reduced {
    fn unit(j: usize, rhs: f64) -> Reduced {
        Reduced {
            test: [(j, 1.0), (0, 0.0)],
            n_test: 1,
            dir: [(j, 1.0), (0, 0.0), (0, 0.0)],
            n_dir: 1,
            diag: 0.0,
            rhs,
        }
    }
}

/// Sorts the components at lam for the natural map F_c with c = cscale rho and
/// returns the reduced unknowns and the explicit part e0 of the step (written into
/// `e0`); `f` receives F_c(lam). A free row's right-hand side is -F_c/c = -w, taken
/// from w directly (no cancellation when c is small).
fn linearise(
    problem: &DualProblem<'_>,
    lam: &[f64],
    w: &[f64],
    e0: &mut [f64],
    f: &mut [f64],
    cscale: f64,
) -> Vec<Reduced> {
    let dual = problem.dual;
    let (m, d) = (dual.m, dual.d);
    let coulomb_mu = match problem.law {
        Friction::Coulomb(mu) => Some(mu),
        Friction::Tresca(_) => None,
    };
    e0.iter_mut().for_each(|v| *v = 0.0);
    let mut red = Vec::with_capacity(dual.c);
    for i in 0..m {
        let rho = cscale * dual.rho[i];
        let jt = m + (d - 1) * i;
        let r = problem.law.bound(i, lam[i]);
        if rho <= 0.0 {
            // The contact does not act on u: project and keep it there.
            f[i] = lam[i] - lam[i].max(0.0);
            e0[i] = -f[i];
            let mut y = [0.0; 2];
            y[..d - 1].copy_from_slice(&lam[jt..jt + d - 1]);
            crate::friction::project_disk(&mut y[..d - 1], r);
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s] - y[s];
                e0[jt + s] = -f[jt + s];
            }
            continue;
        }
        let yn = lam[i] - rho * w[i];
        f[i] = lam[i] - yn.max(0.0);
        let normal_free = yn > 0.0;
        let mut yt = [0.0; 2];
        for s in 0..d - 1 {
            yt[s] = lam[jt + s] - rho * w[jt + s];
        }
        let ny = yt[..d - 1].iter().map(|v| v * v).sum::<f64>().sqrt();
        // Coupling of the slipping tangential force to lambda_N (Coulomb).
        let mut coupling: Option<[f64; 2]> = None;
        if r > 0.0 && ny < r {
            // Stick: every tangential component free.
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s] - yt[s];
                red.push(Reduced::unit(jt + s, -w[jt + s]));
            }
        } else if ny == 0.0 {
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s];
                e0[jt + s] = -f[jt + s];
            }
        } else {
            let nvec = [yt[0] / ny, if d == 3 { yt[1] / ny } else { 0.0 }];
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s] - r * nvec[s];
            }
            let fn_ = (0..d - 1).map(|s| f[jt + s] * nvec[s]).sum::<f64>();
            for s in 0..d - 1 {
                e0[jt + s] -= fn_ * nvec[s];
            }
            if d == 3 {
                let t = [-nvec[1], nvec[0]];
                let ft = f[jt] * t[0] + f[jt + 1] * t[1];
                let sr = r / ny;
                if sr > 0.0 {
                    red.push(Reduced {
                        test: [(jt, t[0]), (jt + 1, t[1])],
                        n_test: 2,
                        dir: [(jt, t[0]), (jt + 1, t[1]), (0, 0.0)],
                        n_dir: 2,
                        diag: (1.0 - sr) / (sr * rho),
                        rhs: -ft / (sr * rho),
                    });
                } else {
                    e0[jt] -= ft * t[0];
                    e0[jt + 1] -= ft * t[1];
                }
            }
            if let Some(mu) = coulomb_mu {
                coupling = Some([mu[i] * nvec[0], mu[i] * nvec[1]]);
            }
        }
        if normal_free {
            let mut u = Reduced::unit(i, -w[i]);
            if let Some(cp) = coupling {
                for (s, &cs) in cp[..d - 1].iter().enumerate() {
                    u.dir[1 + s] = (jt + s, cs);
                }
                u.n_dir = d;
            }
            red.push(u);
        } else {
            e0[i] = -f[i];
            if let Some(cp) = coupling {
                // lambda_N moves by -F_N: the bound, hence the slip force, follows.
                for s in 0..d - 1 {
                    e0[jt + s] += cp[s] * e0[i];
                }
            }
        }
    }
    red
}

/// Solves for the Newton step `step` at lam (w = A lam - b). False when the
/// reduced system is singular.
#[allow(clippy::too_many_arguments)]
fn newton_step(
    problem: &DualProblem<'_>,
    lam: &[f64],
    w: &[f64],
    step: &mut [f64],
    f: &mut [f64],
    ae0: &mut [f64],
    cscale: f64,
    krylov: &mut Krylov,
    reused: &mut Option<Reused>,
) -> bool {
    let dual = problem.dual;
    let red = linearise(problem, lam, w, step, f, cscale);
    let k = red.len();
    if k == 0 {
        return true;
    }
    if dual.is_matrix_free() {
        // The products of this step read and give only the rows of the
        // reduced unknowns and of the explicit part: narrowed to them (where
        // their DOFs' paths hold few of L's entries; Coulomb's open contacts
        // leave the reduced system).
        let rows = &mut krylov.rows;
        rows.clear();
        for u in &red {
            rows.extend(u.dir[..u.n_dir].iter().map(|&(j, _)| j));
            rows.extend(u.test[..u.n_test].iter().map(|&(j, _)| j));
        }
        rows.extend((0..dual.c).filter(|&j| step[j] != 0.0));
        rows.sort_unstable();
        rows.dedup();
        if dual.narrow_to(rows) {
            krylov.narrowed += 1;
        }
        // The fixed components' part of the right-hand side, to the accuracy
        // the reduced solve asks for.
        dual.apply_narrow(step, ae0, krylov.rough());
        let solved = krylov_step(problem, &red, step, ae0, krylov);
        dual.widen();
        return solved;
    }
    dual.apply(step, ae0);
    // M = T^T A V + diag, column by column: column l is the sum over the entries of
    // dir_l of coef times T^T A[:, j], gathered from one column of A.
    let _mat_claim = dual.ledger.claim_f64(k * k);
    // Where the allocator refuses the k x k system the step fails as a singular
    // one does (the fallback sweeps take over) instead of aborting the host.
    let Ok(mut mat) = crate::memory::try_mat::<f64>(k, k, "") else {
        return false;
    };
    let mut rhs = Mat::<f64>::zeros(k, 1);
    for (l, u) in red.iter().enumerate() {
        let col = mat
            .col_mut(l)
            .try_as_col_major_mut()
            .expect("contiguous")
            .as_slice_mut();
        for &(jd, cd) in &u.dir[..u.n_dir] {
            let a = dual.col(jd);
            for (x, ur) in col.iter_mut().zip(&red) {
                let t = &ur.test[..ur.n_test];
                *x += cd * t.iter().map(|&(jt, ct)| ct * a[jt]).sum::<f64>();
            }
        }
        col[l] += u.diag;
        let mut g = u.rhs;
        for &(j, coef) in &u.test[..u.n_test] {
            g -= coef * ae0[j];
        }
        rhs[(l, 0)] = g;
    }
    // Test and direction vectors equal (every unknown but a Coulomb normal that
    // drags its slip force): M is symmetric, positive definite unless A is singular.
    let symmetric = red
        .iter()
        .all(|u| u.n_test == u.n_dir && u.test[..u.n_test] == u.dir[..u.n_dir]);
    let key: Vec<usize> = red.iter().map(|u| 4 * u.test[0].0 + u.n_test).collect();
    let how = Reduce {
        symmetric,
        key,
        reused,
    };
    let Some(z) = solve_reduced(&mat, &rhs, how, &dual.threads, &dual.ledger) else {
        return false;
    };
    for (l, u) in red.iter().enumerate() {
        for &(j, coef) in &u.dir[..u.n_dir] {
            step[j] += coef * z[(l, 0)];
        }
    }
    true
}

/// The Krylov solve of a Newton step on a matrix-free dual: its forcing term,
/// its budget, its scratch (two vectors of length c) and the products it used.
pub(super) struct Krylov {
    /// Relative residual the reduced solve must reach.
    pub eta: f64,
    /// Most products with A per reduced solve.
    pub max_it: usize,
    /// Products used so far (inner iterations).
    pub its: usize,
    /// Whether the reduced solve must use exact products whatever its forcing
    /// term (see ROUGH_ETA).
    pub exact: bool,
    v: Vec<f64>,
    av: Vec<f64>,
    /// The rows a step's products are narrowed to (`Dual::narrow_to`).
    rows: Vec<usize>,
    /// Steps whose products were narrowed.
    pub narrowed: usize,
}

impl Krylov {
    /// Whether this reduced solve may use products in single precision (see
    /// ROUGH_ETA).
    fn rough(&self) -> bool {
        !self.exact && self.eta >= ROUGH_ETA
    }

    fn new(c: usize) -> Krylov {
        Krylov {
            eta: 0.1,
            max_it: KRYLOV_MAX_IT,
            its: 0,
            exact: false,
            v: vec![0.0; c],
            av: vec![0.0; c],
            rows: Vec::with_capacity(c),
            narrowed: 0,
        }
    }
}

/// Entry (ja, jb) of A where both lie in one contact's d x d diagonal block
/// (every pair a reduced unknown couples), read from the matrix-free dual's blocks.
fn block_entry(problem: &DualProblem<'_>, ja: usize, jb: usize) -> f64 {
    let dual = problem.dual;
    let (m, d) = (dual.m, dual.d);
    let at = |j: usize| {
        if j < m {
            (j, 0)
        } else {
            ((j - m) / (d - 1), 1 + (j - m) % (d - 1))
        }
    };
    let ((ia, la), (ib, lb)) = (at(ja), at(jb));
    match dual.block_entry(ia, la, lb) {
        Some(v) if ia == ib => v,
        _ => 0.0,
    }
}

/// The reduced system M z = rhs of a Newton step on a matrix-free dual, by
/// preconditioned CG (symmetric M) or GMRES to the relative residual
/// `krylov.eta`, each product M x one product with A. The preconditioner is
/// S V^T G V S with G the dual's approximate inverse of A
/// (`Dual::precondition`: the layered Dirichlet one B S_l B^T of
/// `dirichlet.rs` where it was formed, else the lumped G = B K B^T that FETI
/// codes use for the same operator) and S_l = sqrt(a_l / M_ll),
/// a_l = v_l^T A v_l (so that it is G where the diagonal term of M vanishes and
/// tends to 1 / M_ll where that term dominates, as for a fast slip); M's
/// diagonal (Jacobi) when the dual holds no G. Both from the contacts'
/// diagonal blocks of A. Adds V z to `step`. False when the Krylov iteration
/// broke down.
fn krylov_step(
    problem: &DualProblem<'_>,
    red: &[Reduced],
    step: &mut [f64],
    ae0: &[f64],
    krylov: &mut Krylov,
) -> bool {
    let dual = problem.dual;
    let k = red.len();
    let rhs: Vec<f64> = red
        .iter()
        .map(|u| {
            u.rhs
                - u.test[..u.n_test]
                    .iter()
                    .map(|&(j, c)| c * ae0[j])
                    .sum::<f64>()
        })
        .collect();
    // Per reduced unknown, the entry of T^T A V + diag it sits on, from the
    // contacts' diagonal blocks of A.
    let mdiag: Vec<f64> = red
        .iter()
        .map(|u| {
            let mut mll = u.diag;
            for &(ja, ca) in &u.test[..u.n_test] {
                for &(jb, cb) in &u.dir[..u.n_dir] {
                    mll += ca * cb * block_entry(problem, ja, jb);
                }
            }
            mll
        })
        .collect();
    let symmetric = red
        .iter()
        .all(|u| u.n_test == u.n_dir && u.test[..u.n_test] == u.dir[..u.n_dir]);
    // A loose inner solve tolerates products in single precision (see
    // ROUGH_ETA); a tight one refines with exact residuals (see `refine`).
    let rough = std::cell::Cell::new(krylov.rough());
    let (v, av) = (&mut krylov.v, &mut krylov.av);
    let mut op = |x: &[f64], y: &mut [f64]| {
        v.iter_mut().for_each(|e| *e = 0.0);
        for (u, &xl) in red.iter().zip(x) {
            for &(j, c) in &u.dir[..u.n_dir] {
                v[j] += c * xl;
            }
        }
        dual.apply_narrow(v, av, rough.get());
        for ((u, &xl), yl) in red.iter().zip(x).zip(y.iter_mut()) {
            *yl = u.diag * xl
                + u.test[..u.n_test]
                    .iter()
                    .map(|&(j, c)| c * av[j])
                    .sum::<f64>();
        }
    };
    let (mut gv, mut gg) = (vec![0.0; dual.c], vec![0.0; dual.c]);
    // The preconditioner S V^T G V S, S_l = sqrt(a_l / (a_l + diag_l)) with
    // a_l = v_l^T A v_l (G ~ A^-1 where diag vanishes, 1 / M_ll where it
    // dominates), G the dual's approximate inverse of A (`Dual::precondition`:
    // layered Dirichlet or lumped); Jacobi without one.
    // The interface compliance's D (`Dual::set_shift`) counts with the
    // diagonal term (G approximates A^-1, not (A + D)^-1), and the Jacobi
    // part (1 - S_l^2) / M_ll is added where D is present: a soft interface
    // (D ten times A's diagonal) took 37 products against the rigid 20 on
    // the 3d-32x32x4 slab without it, 21 with it.
    let shift = dual.shift();
    let scale: Vec<f64> = red
        .iter()
        .zip(&mdiag)
        .map(|(u, &mll)| {
            let mut a = mll - u.diag;
            if !shift.is_empty() {
                for &(ja, ca) in &u.test[..u.n_test] {
                    for &(jb, cb) in &u.dir[..u.n_dir] {
                        if ja == jb {
                            a -= ca * cb * shift[ja];
                        }
                    }
                }
            }
            if a > 0.0 && mll > 0.0 {
                (a / mll).sqrt()
            } else {
                1.0
            }
        })
        .collect();
    let mut pre = |x: &[f64], y: &mut [f64]| {
        gv.iter_mut().for_each(|e| *e = 0.0);
        for ((u, &xl), &sl) in red.iter().zip(x).zip(&scale) {
            for &(j, c) in &u.dir[..u.n_dir] {
                gv[j] += c * sl * xl;
            }
        }
        if dual.precondition(&gv, &mut gg) {
            for ((((u, yl), &sl), &xl), &mll) in
                red.iter().zip(y.iter_mut()).zip(&scale).zip(x).zip(&mdiag)
            {
                *yl = sl
                    * u.dir[..u.n_dir]
                        .iter()
                        .map(|&(j, c)| c * gg[j])
                        .sum::<f64>();
                if !shift.is_empty() && mll > 0.0 {
                    *yl += (1.0 - sl * sl) * xl / mll;
                }
            }
        } else {
            for ((yl, &xl), &mll) in y.iter_mut().zip(x).zip(&mdiag) {
                *yl = if mll > 0.0 { xl / mll } else { xl };
            }
        }
    };
    let mut z = vec![0.0; k];
    let solver = if symmetric {
        super::krylov::pcg
    } else {
        super::krylov::gmres
    };
    let (eta, max_it) = (krylov.eta, krylov.max_it);
    let its = if krylov.exact || rough.get() {
        solver(&mut op, &rhs, &mut pre, eta, max_it, &mut z)
    } else {
        refine(solver, &mut op, &rough, &rhs, &mut pre, eta, max_it, &mut z)
    };
    let Some(its) = its else {
        return false;
    };
    krylov.its += its;
    for (u, &zl) in red.iter().zip(&z) {
        for &(j, coef) in &u.dir[..u.n_dir] {
            step[j] += coef * zl;
        }
    }
    true
}

/// Rounds of `refine` before it falls back to exact products.
const REFINE_ROUNDS: usize = 4;

/// A tight reduced solve (relative residual `eta` < ROUGH_ETA) by iterative
/// refinement in mixed precision: each round solves M dz = r for the
/// correction with products in single precision (`rough` set) to the relative
/// residual ROUGH_ETA, or to what the target needs when that is looser, then
/// measures r = rhs - M z with one exact product. A round that does not halve
/// |r| (single precision too rough for this factor) hands the rest to the
/// solver with exact products, from the z reached. Same contract as the
/// solvers: the products used, None on a breakdown.
#[allow(clippy::too_many_arguments)]
fn refine(
    solver: super::krylov::Solver,
    op: &mut dyn FnMut(&[f64], &mut [f64]),
    rough: &std::cell::Cell<bool>,
    rhs: &[f64],
    pre: &mut dyn FnMut(&[f64], &mut [f64]),
    eta: f64,
    max_it: usize,
    z: &mut [f64],
) -> Option<usize> {
    let k = rhs.len();
    let stop = eta * norm(rhs);
    z.iter_mut().for_each(|v| *v = 0.0);
    let mut r = rhs.to_vec();
    let (mut dz, mut mz, mut saved) = (vec![0.0; k], vec![0.0; k], vec![0.0; k]);
    let mut r_norm = norm(&r);
    let mut its = 0;
    for _ in 0..REFINE_ROUNDS {
        if r_norm <= stop || its >= max_it {
            return Some(its);
        }
        saved.copy_from_slice(&r);
        rough.set(true);
        let inner = ROUGH_ETA.max(stop / r_norm);
        its += solver(op, &r, pre, inner, max_it - its, &mut dz)?;
        z.iter_mut().zip(&dz).for_each(|(a, b)| *a += b);
        rough.set(false);
        op(z, &mut mz);
        its += 1;
        for j in 0..k {
            r[j] = rhs[j] - mz[j];
        }
        let before = r_norm;
        r_norm = norm(&r);
        if !r_norm.is_finite() || r_norm >= before {
            // Worse (or not finite): undo the round.
            z.iter_mut().zip(&dz).for_each(|(a, b)| *a -= b);
            r.copy_from_slice(&saved);
            r_norm = before;
            break;
        }
        if r_norm > 0.5 * before {
            break;
        }
    }
    if r_norm <= stop || its >= max_it {
        return Some(its);
    }
    // Exact products for the rest.
    rough.set(false);
    its += solver(op, &r, pre, stop / r_norm, max_it - its, &mut dz)?;
    z.iter_mut().zip(&dz).for_each(|(a, b)| *a += b);
    Some(its)
}

/// Reduced systems of at least this order, when symmetric, are first solved by
/// Cholesky in single precision with refinement (`dense::refine`) to the
/// normwise backward error MIXED_RTOL, that of a Cholesky solve in double;
/// below it the factorisation is cheap anyway.
const MIXED_MIN: usize = 256;
const MIXED_RTOL: f64 = 1e-15;

/// Most CG iterations a reduced solve spends on the last step's factor
/// before it factors its own matrix: an iteration costs about 3 k^2 flops
/// (a product with M in double, two triangular solves in single precision),
/// a factorisation k^3 / 3 at the faster rate of blocked kernels.
const REUSE_MAX_IT: usize = 20;

/// The single-precision factor of the last dense reduced system, with the
/// unknowns it was formed on (`key`: each unknown's first test index and
/// kind), held for the next Newton step: where that step has the same
/// unknowns, or a few more or fewer (REUSE_MAX_CHANGED), its matrix differs
/// in a few directions (those unknowns, the slipping contacts' turned
/// directions and the curvature terms), and CG preconditioned by this
/// factor solves it in a few iterations (`dense::pcg`).
pub(super) struct Reused {
    key: Vec<usize>,
    llt: dense::LltF32,
    _claim: crate::memory::Claim,
}

impl Reused {
    /// Each of `key`'s unknowns' position in the kept factor (None for a new
    /// one); empty when the unknowns are the same, in the same order. None
    /// when more than REUSE_MAX_CHANGED unknowns came or went: CG on the
    /// kept factor would need about as many iterations as a factorisation.
    fn positions(&self, key: &[usize]) -> Option<Vec<Option<usize>>> {
        if self.key == key {
            return Some(Vec::new());
        }
        let old: std::collections::HashMap<usize, usize> = self
            .key
            .iter()
            .enumerate()
            .map(|(q, &kq)| (kq, q))
            .collect();
        let pos: Vec<Option<usize>> = key.iter().map(|kj| old.get(kj).copied()).collect();
        let shared = pos.iter().flatten().count();
        let changed = (key.len() - shared) + (self.key.len() - shared);
        (changed <= REUSE_MAX_CHANGED).then_some(pos)
    }
}

/// Most reduced unknowns that may come or go between two Newton steps for
/// the second to solve on the first one's factor (see [`Reused`]).
const REUSE_MAX_CHANGED: usize = 8;

/// How `solve_reduced` may solve: whether M is symmetric, the unknowns'
/// key, and the factor kept from the last step (replaced by this step's).
struct Reduce<'a> {
    symmetric: bool,
    key: Vec<usize>,
    reused: &'a mut Option<Reused>,
}

/// Solves the reduced system M z = rhs: by Cholesky when M is `symmetric` (half the
/// flops of LU), else or when that fails by a partially pivoted LU, unless M is numerically
/// singular (the solution is not finite or much larger than M and rhs warrant),
/// then by the minimum-norm least-squares solution with singular values below
/// RCOND sigma_max dropped. None when no finite solution is found.
fn solve_reduced(
    mat: &Mat<f64>,
    rhs: &Mat<f64>,
    how: Reduce<'_>,
    threads: &Threads,
    ledger: &Arc<Ledger>,
) -> Option<Mat<f64>> {
    let Reduce {
        symmetric,
        key,
        reused,
    } = how;
    let max_abs = |a: faer::MatRef<'_, f64>| {
        let mut v = 0.0f64;
        for j in 0..a.ncols() {
            for i in 0..a.nrows() {
                v = v.max(a[(i, j)].abs());
            }
        }
        v
    };
    let (mn, rn) = (max_abs(mat.as_ref()), max_abs(rhs.as_ref()));
    let acceptable =
        |z: &Mat<f64>| z.as_ref().is_all_finite() && mn * max_abs(z.as_ref()) * RCOND <= rn;
    let big = mat.nrows() * mat.ncols() >= PARALLEL_MIN_ENTRIES;
    let (m, r) = (mat.as_ref(), rhs.as_ref());
    let k2 = mat.nrows() * mat.ncols();
    let rv: Vec<f64> = r.col(0).iter().copied().collect();
    // The last step's factor, where this step has the same unknowns: CG
    // preconditioned by it (see REUSE_MAX_IT).
    if symmetric
        && let Some(old) = reused.as_ref()
        && let Some(pos) = old.positions(&key)
        && let Some(z) = threads.run(big, |par| {
            let pos = (!pos.is_empty()).then_some(&pos[..]);
            dense::pcg(m, &old.llt, pos, &rv, MIXED_RTOL, REUSE_MAX_IT, par)
        })
    {
        let z = Mat::from_fn(z.len(), 1, |i, _| z[i]);
        if acceptable(&z) {
            return Some(z);
        }
    }
    // A new factor replaces the old one (never both held: the workspace).
    *reused = None;
    if symmetric && mat.nrows() >= MIXED_MIN {
        let k = mat.nrows();
        let claim = ledger.claim(k * k * std::mem::size_of::<f32>());
        if let Some(llt) = threads.run(big, |par| dense::LltF32::of(m, par))
            && let Some(z) = threads.run(big, |par| dense::refine(m, &llt, &rv, MIXED_RTOL, par))
        {
            let z = Mat::from_fn(z.len(), 1, |i, _| z[i]);
            if acceptable(&z) {
                *reused = Some(Reused {
                    key,
                    llt,
                    _claim: claim,
                });
                return Some(z);
            }
        }
    }
    // The double-precision solvers work on a copy of M (the SVD on two k x k
    // factors too); the single-precision factor above is claimed by itself.
    let copy_claim = ledger.claim_f64(k2);
    if symmetric
        && let Some(z) = threads.run(big, |par| dense::llt_solve(m, r, par))
        && acceptable(&z)
    {
        return Some(z);
    }
    if let Some(z) = threads.run(big, |par| dense::lu_solve(m, r, par))
        && acceptable(&z)
    {
        return Some(z);
    }
    drop(copy_claim);
    let _svd_claim = ledger.claim_f64(3 * k2);
    let (u, sv, v) = threads.run(big, |par| dense::thin_svd(m, par))?;
    let smax = sv.iter().fold(0.0f64, |a, &s| a.max(s));
    let mut z = Mat::<f64>::zeros(mat.ncols(), 1);
    for l in 0..sv.len() {
        if sv[l] > RCOND * smax {
            let coef = (0..u.nrows()).map(|r| u[(r, l)] * rhs[(r, 0)]).sum::<f64>() / sv[l];
            for r in 0..v.nrows() {
                z[(r, 0)] += coef * v[(r, l)];
            }
        }
    }
    z.as_ref().is_all_finite().then_some(z)
}

/// |F(lam)|_2, the natural map of the module docs at lam (w = A lam - b), in force
/// units: unlike err it does not shrink when lambda grows without bound.
fn residual_norm(problem: &DualProblem<'_>, lam: &[f64], w: &[f64]) -> f64 {
    let dual = problem.dual;
    let (m, d) = (dual.m, dual.d);
    let mut r2 = 0.0;
    for i in 0..m {
        let rho = dual.rho[i].max(0.0);
        let jt = m + (d - 1) * i;
        let rn = lam[i] - (lam[i] - rho * w[i]).max(0.0);
        r2 += rn * rn;
        let mut y = [0.0; 2];
        for s in 0..d - 1 {
            y[s] = lam[jt + s] - rho * w[jt + s];
        }
        crate::friction::project_disk(&mut y[..d - 1], problem.law.bound(i, lam[i]));
        for s in 0..d - 1 {
            r2 += (lam[jt + s] - y[s]).powi(2);
        }
    }
    r2.sqrt()
}

/// `newton`: one semismooth Newton step per outer iteration, on frictionless
/// increments as well (the unknowns at zero bounds leave its linear systems).
pub(super) const NEWTON: MethodSpec = MethodSpec {
    name: "newton",
    needs_entries: false,
    // Dense: the reduced matrix, the copy its solver factors and, on a large
    // dual, A in single precision for the sweeps. Matrix-free: the Krylov
    // vectors (GMRES's basis and a few more, length c at most).
    workspace: |_m, c, matrix_free| {
        if matrix_free {
            (super::krylov::RESTART + 10) * c * F64
        } else {
            let rough = if c >= pgs::ROUGH_MIN_C {
                c * c * std::mem::size_of::<f32>()
            } else {
                0
            };
            2 * c * c * F64 + rough
        }
    },
    build: |problem, _opts, target| (Box::new(Newton::new(problem, target)), problem.dual.c),
};

/// The globalised semismooth Newton method.
pub(super) struct Newton {
    /// The dual target: the warm-up sweeps stop when err meets it.
    target: f64,
    warm: bool,
    /// Gauss-Seidel sweeps before the first step (PRESWEEPS; 0 in the tests of
    /// the warm start itself).
    presweeps: usize,
    /// Whether a warm start's first step sorts by the multipliers (WARM_C); off
    /// only in the tests that measure what that sorting buys.
    warm_sort: bool,
    /// Whether a cold start on a matrix-free dual begins at the lumped estimate
    /// (`Newton::lumped_start`); off only in the test that measures what it buys.
    lumped_start_on: bool,
    step: Vec<f64>,
    f: Vec<f64>,
    ae0: Vec<f64>,
    trial: Vec<f64>,
    wt: Vec<f64>,
    /// The reduced solves' Krylov state on a matrix-free dual.
    krylov: Krylov,
    /// The last dense reduced system's factor (see [`Reused`]).
    reused: Option<Reused>,
    /// A's columns in single precision for the warm-up and fallback sweeps on
    /// a large assembled dual (made at their first use; see pgs::ROUGH_MIN_C).
    rough_a: Option<pgs::Rough>,
    /// The matrix-free fallback's MPRGP (made at its first use), the bounds it
    /// works with and its estimate of |A|.
    fallback: Option<Mprgp>,
    radii: Vec<f64>,
    norm: Option<f64>,
    /// |F| at the start (the forcing terms' reference).
    res0: f64,
    /// |F| at the current iterate, and the lowest |F| with the iteration it was met.
    res: f64,
    best: f64,
    best_at: usize,
}

impl Newton {
    pub fn new(problem: &DualProblem<'_>, target: f64) -> Self {
        let c = problem.dual.c;
        Newton {
            target,
            warm: false,
            presweeps: PRESWEEPS,
            warm_sort: true,
            lumped_start_on: true,
            step: vec![0.0; c],
            f: vec![0.0; c],
            ae0: vec![0.0; c],
            trial: vec![0.0; c],
            wt: vec![0.0; c],
            krylov: Krylov::new(c),
            reused: None,
            rough_a: None,
            fallback: None,
            radii: Vec::new(),
            norm: None,
            res0: 0.0,
            res: 0.0,
            best: 0.0,
            best_at: 0,
        }
    }
}

impl OuterStep for Newton {
    /// First-order warm-up (module docs): PRESWEEPS sweeps, fewer when err meets
    /// the target first.
    fn start(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        w: &mut [f64],
        inner: &mut usize,
    ) -> Flow {
        let (m, c) = (problem.dual.m, problem.dual.c);
        self.warm = lam.iter().any(|&x| x != 0.0);
        // The error's scratch: `f` and `ae0` are overwritten by every step.
        let (p, v) = (&mut self.f[..m], &mut self.ae0[..c]);
        let mut swept = 0;
        // Gauss-Seidel reads entries of A: no sweeps on a matrix-free dual.
        let presweeps = if problem.dual.is_matrix_free() {
            0
        } else {
            self.presweeps
        };
        while swept < presweeps && problem.error(lam, w, p, v) > self.target {
            let n = PRESWEEP_CHUNK.min(presweeps - swept);
            *inner += pgs::sweeps_for_newton(problem, &mut self.rough_a, lam, w, n);
            swept += n;
        }
        if swept > 0 {
            // w was updated column by column (in single precision on a large
            // dual; the error tests between chunks read it so: they only decide
            // when to stop sweeping): recompute it.
            problem.gradient(lam, w);
        }
        // No sweeps on a matrix-free dual: a cold start begins at the lumped
        // estimate instead, when it is better than zero.
        if let Some(g) = problem.dual.lumped()
            && !self.warm
            && self.lumped_start_on
        {
            self.lumped_start(problem, g, lam, w);
        }
        self.res = residual_norm(problem, lam, w);
        self.res0 = self.res;
        (self.best, self.best_at) = (self.res, 0);
        Flow::Go(Gradient::Exact)
    }

    fn step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        w: &mut [f64],
        inner: &mut usize,
        k: usize,
    ) -> Flow {
        let c = problem.dual.c;
        if self.res < (1.0 - STALL_DROP) * self.best {
            (self.best, self.best_at) = (self.res, k);
        } else if k >= self.best_at + STALL_WINDOW {
            // Neither Newton nor Gauss-Seidel makes progress: no solution to find
            // (an infeasible problem), or none this method can reach.
            return Flow::Stalled;
        }
        // A warm start's first step takes its active set from the multipliers
        // (see WARM_C); every later step from the natural map.
        let cscale = if self.warm && self.warm_sort && !problem.predicted && !problem.near && k == 0
        {
            WARM_C
        } else {
            1.0
        };
        let (step, trial, wt) = (&mut self.step, &mut self.trial, &mut self.wt);
        self.krylov.eta = forcing(self.res, self.res0, self.target, norm(lam));
        // A step from rough (single-precision) products that the backtracking
        // rejects is solved again with exact ones before any fallback: on an
        // ill-conditioned K the rough products can be too rough.
        for exact in [false, true] {
            self.krylov.exact = exact;
            let rough = problem.dual.is_matrix_free() && self.krylov.eta >= ROUGH_ETA;
            if exact && !rough {
                break;
            }
            let before = self.krylov.its;
            let solved = newton_step(
                problem,
                lam,
                w,
                step,
                &mut self.f,
                &mut self.ae0,
                cscale,
                &mut self.krylov,
                &mut self.reused,
            );
            *inner += self.krylov.its - before;
            if !solved {
                continue;
            }
            // Backtracking: the full step, then halves of it, their gradients
            // w + t A d from one exact product (A is linear): one addition's
            // rounding away from A (lam + t d) - b, as current as a gradient
            // computed afresh, so the driver need not recompute it before it
            // accepts a convergence (one product per solve saved).
            let ad = &mut self.ae0;
            problem.dual.apply(step, ad);
            let mut t = 1.0;
            for _ in 0..BACKTRACKS {
                for j in 0..c {
                    trial[j] = lam[j] + t * step[j];
                    wt[j] = w[j] + t * ad[j];
                }
                let r = residual_norm(problem, trial, wt);
                if r <= (1.0 - ARMIJO * t) * self.res {
                    lam.copy_from_slice(trial);
                    w.copy_from_slice(wt);
                    self.res = r;
                    return Flow::Go(Gradient::Exact);
                }
                t *= 0.5;
            }
        }
        if problem.dual.is_matrix_free() {
            return self.mprgp_fallback(problem, lam, w, inner);
        }
        // Fallback: a first-order step.
        *inner += pgs::sweeps_for_newton(problem, &mut self.rough_a, lam, w, FALLBACK_SWEEPS);
        problem.gradient(lam, w);
        self.res = residual_norm(problem, lam, w);
        Flow::Go(Gradient::Exact)
    }
}

impl Newton {
    /// A cold start on a matrix-free dual: lam = P(alpha G b), the projection
    /// onto the feasible set of the minimiser of the dual energy along G b
    /// (G = B K B^T ~ A^-1: the lumped estimate of the unconstrained
    /// multipliers), kept when it lowers |F| below its value at lam = 0. Two
    /// products with A.
    fn lumped_start(
        &mut self,
        problem: &DualProblem<'_>,
        g: &crate::sparse::Csc,
        lam: &mut [f64],
        w: &mut [f64],
    ) {
        let dual = problem.dual;
        let (m, d, c) = (dual.m, dual.d, dual.c);
        let (y, ay) = (&mut self.trial, &mut self.wt);
        g.mul_vec(problem.b, y);
        dual.apply_rough(y, ay);
        let yay: f64 = y.iter().zip(ay.iter()).map(|(a, b)| a * b).sum();
        let by: f64 = y.iter().zip(problem.b).map(|(a, b)| a * b).sum();
        if !(yay > 0.0 && by > 0.0 && yay.is_finite()) {
            return;
        }
        let alpha = by / yay;
        y.iter_mut().for_each(|v| *v *= alpha);
        for i in 0..m {
            y[i] = y[i].max(0.0);
            let r = problem.law.bound(i, y[i]);
            let jt = m + (d - 1) * i;
            crate::friction::project_disk(&mut y[jt..jt + d - 1], r);
        }
        problem.gradient(y, ay);
        let r = residual_norm(problem, y, ay);
        if r < residual_norm(problem, lam, w) {
            lam[..c].copy_from_slice(&y[..c]);
            w[..c].copy_from_slice(&ay[..c]);
        }
    }

    /// The fallback on a matrix-free dual (no Gauss-Seidel without entries of A):
    /// FALLBACK_MPRGP iterations of MPRGP / MPGP (one product with A each) on the
    /// Tresca problem of the current bound, from lam: a first-order descent step
    /// that, unlike a projection step, makes progress where A is ill-conditioned
    /// (the slender beam of tests/hard_scenes.rs); Newton restarts from there.
    fn mprgp_fallback(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        w: &mut [f64],
        inner: &mut usize,
    ) -> Flow {
        let dual = problem.dual;
        let (m, c) = (dual.m, dual.c);
        self.radii.resize(m, 0.0);
        problem.law.bounds(&lam[..m], &mut self.radii);
        let qp = ConvexQp::whole(problem, &self.radii);
        let solver = self
            .fallback
            .get_or_insert_with(|| Mprgp::new(c, 0.0, FALLBACK_MPRGP));
        if let Flow::Infeasible = Flow::after(
            solver.solve_convex(&qp, lam, &mut self.norm),
            inner,
            Gradient::Stale,
        ) {
            return Flow::Infeasible;
        }
        problem.gradient(lam, w);
        self.res = residual_norm(problem, lam, w);
        Flow::Go(Gradient::Exact)
    }
}

/// The fraction of the target a step's error aims at (see [`forcing`]).
const ENOUGH: f64 = 0.1;

/// The forcing term of an inexact Newton step on a matrix-free dual: the
/// reduced system is solved to the relative residual eta = |F| / |F_0| (capped
/// at 0.1: superlinear convergence), but no tighter than a step whose error
/// leaves |F| at a tenth of the target (err's scale taken as |lambda|; the
/// history benchmark's last steps then end at err 1e-12 to 8e-11 for the
/// target 1e-10, and a hundredth spent 2-3 more products per increment for
/// errors a decade lower).
fn forcing(res: f64, res0: f64, target: f64, lam_norm: f64) -> f64 {
    let eta = if res0 > 0.0 {
        (res / res0).min(0.1)
    } else {
        0.1
    };
    let enough = if res > 0.0 {
        ENOUGH * target * lam_norm / res
    } else {
        0.1
    };
    eta.max(enough.min(0.1)).max(1e-14)
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::friction::Friction;
    use crate::options::{Method, Options};
    use crate::problem::ContactProblem;
    use crate::sparse::Csc;

    /// A 2D strip of `nodes` contact nodes (u_x, u_y each), tied to a rigid top
    /// by vertical and shear springs and to each other by bars: pressed down by
    /// `press` and sheared by `shear` through the top; contact i: N = -e_y, T = e_x,
    /// gap 1e-3 (i - c)^2 / c^2 around the centre c.
    fn strip(nodes: usize) -> (ContactProblem, Vec<f64>) {
        let n = 2 * nodes;
        let mut k = Vec::new();
        for i in 0..nodes {
            let (x, y) = (2 * i, 2 * i + 1);
            k.push((x, x, 0.02));
            k.push((y, y, 1.0));
            if i + 1 < nodes {
                for (a, b, s) in [(x, x + 2, 2.0), (y, y + 2, 0.5)] {
                    k.push((a, a, s));
                    k.push((b, b, s));
                    k.push((a, b, -s));
                    k.push((b, a, -s));
                }
            }
        }
        let nmat: Vec<_> = (0..nodes).map(|i| (i, 2 * i + 1, -1.0)).collect();
        let tmat: Vec<_> = (0..nodes).map(|i| (i, 2 * i, 1.0)).collect();
        let c = (nodes - 1) as f64 / 2.0;
        let g: Vec<f64> = (0..nodes)
            .map(|i| 1e-3 * (i as f64 - c).powi(2) / (c * c))
            .collect();
        let pb = ContactProblem::from_csc(
            2,
            Csc::from_triplets(n, n, &k),
            Csc::from_triplets(nodes, n, &nmat),
            Csc::from_triplets(nodes, n, &tmat),
        )
        .unwrap();
        (pb, g)
    }

    /// b = B K^-1 f - [g; 0] of the strip under the top's load.
    fn rhs(pb: &ContactProblem, g: &[f64], press: f64, shear: f64) -> Vec<f64> {
        let nodes = g.len();
        let mut u0: Vec<f64> = (0..2 * nodes)
            .map(|j| if j % 2 == 0 { 0.3 * shear } else { -press })
            .collect();
        pb.factor().solve_vec(&mut u0);
        let mut b = vec![0.0; 2 * nodes];
        pb.dual().rows.mul_vec(&u0, &mut b);
        for (bi, gi) in b.iter_mut().zip(g) {
            *bi -= gi;
        }
        b
    }

    /// Newton without its Gauss-Seidel warm-up from `lam`: the outer iterations.
    fn newton_steps(
        pb: &ContactProblem,
        b: &[f64],
        mu: &[f64],
        lam: &mut [f64],
        warm_sort: bool,
    ) -> usize {
        let (out, _) = drive_newton(pb.dual(), b, Friction::Coulomb(mu), lam, |n| {
            n.presweeps = 0;
            n.warm_sort = warm_sort;
        });
        out.outer
    }

    #[test]
    fn the_warm_start_sorts_by_the_multipliers_and_saves_newton_steps() {
        // A history step: the converged multipliers of one load, then the load
        // raised by 5 %. From the same starting iterate, the first step sorted by
        // the multipliers (the warm start) needs fewer Newton steps than the first
        // step sorted by the natural map at that iterate, where the load change
        // with the forces frozen makes the contacts look like slipping.
        let (pb, g) = strip(41);
        let mu = vec![0.3; 41];
        let (press, shear) = (4e-3, 3e-3);
        let b1 = rhs(&pb, &g, press, shear);
        let mut lam1 = vec![0.0; 82];
        newton_steps(&pb, &b1, &mu, &mut lam1, true);
        // Mostly sticking, two contacts slipping (at mu = 0.3, shear 3e-3).
        let slipping = (0..41)
            .filter(|&i| lam1[41 + i].abs() >= (1.0 - 1e-9) * 0.3 * lam1[i])
            .count();
        assert!((1..41).contains(&slipping), "{slipping} slipping");
        let b2 = rhs(&pb, &g, 1.05 * press, 1.05 * shear);
        let (mut warm, mut cold) = (lam1.clone(), lam1.clone());
        let with_sort = newton_steps(&pb, &b2, &mu, &mut warm, true);
        let without = newton_steps(&pb, &b2, &mu, &mut cold, false);
        println!(
            "warm step: {with_sort} Newton steps sorted by the multipliers, {without} by the \
             natural map"
        );
        assert!(with_sort < without, "{with_sort} vs {without}");
        assert!(with_sort <= 2, "{with_sort}");
    }

    /// `refine` against an operator whose single-precision products err by
    /// `rough_error` (relative, a fixed non-symmetric perturbation): with
    /// 1e-7 it reaches eta = 1e-12 on the exact residual with most products
    /// rough; with 0.9 (single precision useless) it falls back to exact
    /// products and still reaches it.
    #[test]
    fn refinement_reaches_the_exact_residual_with_rough_products() {
        let k = 300;
        let exact = |x: &[f64], y: &mut [f64]| {
            for i in 0..k {
                let mut s = (4.0 + 0.01 * i as f64) * x[i];
                if i > 0 {
                    s -= x[i - 1];
                }
                if i + 1 < k {
                    s -= x[i + 1];
                }
                y[i] = s;
            }
        };
        let rhs: Vec<f64> = (0..k).map(|i| (0.3 * i as f64).cos() + 0.2).collect();
        for (rough_error, most_rough) in [(1e-7, true), (0.9, false)] {
            for solver in [
                super::super::krylov::pcg as super::super::krylov::Solver,
                super::super::krylov::gmres,
            ] {
                let rough = std::cell::Cell::new(false);
                let (mut n_rough, mut n_exact) = (0, 0);
                let mut op = |x: &[f64], y: &mut [f64]| {
                    exact(x, y);
                    if rough.get() {
                        n_rough += 1;
                        let scale = norm(y) * rough_error / (k as f64).sqrt();
                        for (i, v) in y.iter_mut().enumerate() {
                            *v += scale * ((i * 7 % 13) as f64 / 6.0 - 1.0);
                        }
                    } else {
                        n_exact += 1;
                    }
                };
                let mut pre = |x: &[f64], y: &mut [f64]| y.copy_from_slice(x);
                let mut z = vec![0.0; k];
                let its = refine(solver, &mut op, &rough, &rhs, &mut pre, 1e-12, 500, &mut z)
                    .expect("no breakdown");
                assert_eq!(its, n_rough + n_exact);
                let mut mz = vec![0.0; k];
                exact(&z, &mut mz);
                let r: Vec<f64> = mz.iter().zip(&rhs).map(|(a, b)| a - b).collect();
                assert!(
                    norm(&r) <= 1e-12 * norm(&rhs),
                    "{rough_error}: {}",
                    norm(&r)
                );
                println!("rough error {rough_error}: {n_rough} rough, {n_exact} exact products");
                if most_rough {
                    assert!(n_rough > 2 * n_exact, "{n_rough} rough, {n_exact} exact");
                }
            }
        }
    }

    /// Newton's warm-up sweeps read A in single precision: from the same
    /// start they follow the exact sweeps to rounding, their w drifts from
    /// A lam - b by rounding only, and the copy is on the ledger while it lives.
    #[test]
    fn rough_sweeps_follow_the_exact_ones() {
        let (pb, g) = strip(41);
        let p = vec![2e-3; 41];
        let b = rhs(&pb, &g, 4e-3, 3e-3);
        let problem = DualProblem {
            dual: pb.dual(),
            b: &b,
            law: Friction::Tresca(&p),
            monitor: None,
            deadline: None,
            predicted: false,
            near: false,
        };
        let c = problem.dual.c;
        let (mut lam_exact, mut w_exact) = (vec![0.0; c], vec![0.0; c]);
        problem.gradient(&lam_exact, &mut w_exact);
        let (mut lam, mut w) = (lam_exact.clone(), w_exact.clone());
        let mut pgs = pgs::Pgs::new(&problem);
        let mut inner = 0;
        for k in 0..30 {
            pgs.step(&problem, &mut lam_exact, &mut w_exact, &mut inner, k);
        }
        let ledger = problem.dual.ledger.clone();
        let live = ledger.live();
        let mut rough = pgs::Rough::new(problem.dual);
        assert_eq!(ledger.live(), live + c * c * 4);
        assert_eq!(
            pgs::rough_sweeps(&problem, &mut rough, &mut lam, &mut w, 30),
            30
        );
        drop(rough);
        assert_eq!(ledger.live(), live);
        let scale = norm(&lam_exact);
        assert!(scale > 0.0);
        let dl: Vec<f64> = lam.iter().zip(&lam_exact).map(|(a, b)| a - b).collect();
        assert!(norm(&dl) <= 1e-5 * scale, "{}", norm(&dl) / scale);
        let mut w_true = vec![0.0; c];
        problem.gradient(&lam, &mut w_true);
        let dw: Vec<f64> = w.iter().zip(&w_true).map(|(a, b)| a - b).collect();
        let a_max = problem.dual.a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(norm(&dw) <= 1e-6 * a_max * norm(&lam) * (c as f64).sqrt());
        assert!(norm(&dw) > 0.0, "single precision leaves some drift");
    }

    fn mat(rows: &[&[f64]]) -> Mat<f64> {
        Mat::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
    }

    #[test]
    fn the_reduced_solve_takes_cholesky_lu_or_least_squares_as_the_matrix_allows() {
        let rhs = mat(&[&[1.0], &[2.0]]);
        let seq = Threads::sequential();
        fn fresh(none: &mut Option<Reused>) -> Reduce<'_> {
            Reduce {
                symmetric: true,
                key: Vec::new(),
                reused: none,
            }
        }
        let mut none = None;
        // SPD: Cholesky; z solves M z = rhs.
        let spd = mat(&[&[4.0, 1.0], &[1.0, 3.0]]);
        let z = solve_reduced(&spd, &rhs, fresh(&mut none), &seq, &Ledger::new()).unwrap();
        assert!((4.0 * z[(0, 0)] + z[(1, 0)] - 1.0).abs() < 1e-15);
        assert!((z[(0, 0)] + 3.0 * z[(1, 0)] - 2.0).abs() < 1e-15);
        // Symmetric but indefinite: Cholesky fails, LU solves it: z = (2, 1).
        let indef = mat(&[&[0.0, 1.0], &[1.0, 0.0]]);
        let z = solve_reduced(&indef, &rhs, fresh(&mut none), &seq, &Ledger::new()).unwrap();
        assert!((z[(0, 0)] - 2.0).abs() < 1e-15 && (z[(1, 0)] - 1.0).abs() < 1e-15);
        // Singular: the minimum-norm least-squares solution of [1 1; 1 1] z = (1, 2)
        // is z = (0.75, 0.75).
        let sing = mat(&[&[1.0, 1.0], &[1.0, 1.0]]);
        let z = solve_reduced(&sing, &rhs, fresh(&mut none), &seq, &Ledger::new()).unwrap();
        assert!((z[(0, 0)] - 0.75).abs() < 1e-12 && (z[(1, 0)] - 0.75).abs() < 1e-12);
    }

    /// A dense reduced solve keeps its single-precision factor for the next
    /// step; a next step with the same unknowns, or one more and one fewer,
    /// solves its own (nearby) matrix by CG on that factor, exactly, without
    /// factoring again; one with other unknowns factors its own and keeps it.
    #[test]
    fn a_reduced_solve_with_the_same_unknowns_reuses_the_last_factor() {
        let k = MIXED_MIN + 44;
        let seq = Threads::sequential();
        let ledger = Ledger::new();
        // M0: diagonally dominant SPD; M1 = M0 + 3 w w^T.
        let m0 = Mat::from_fn(k, k, |i, j| {
            if i == j {
                4.0 + (i % 7) as f64
            } else {
                1.0 / (1.0 + (i as f64 - j as f64).abs()).powi(2)
            }
        });
        let w: Vec<f64> = (0..k).map(|i| (i as f64 * 0.3 + 0.5).sin()).collect();
        let m1 = Mat::from_fn(k, k, |i, j| m0[(i, j)] + 3.0 * w[i] * w[j]);
        let rhs = Mat::from_fn(k, 1, |i, _| (i as f64 * 0.7).cos());
        let key: Vec<usize> = (0..k).collect();
        let mut reused = None;
        fn how<'a>(key: &[usize], reused: &'a mut Option<Reused>) -> Reduce<'a> {
            Reduce {
                symmetric: true,
                key: key.to_vec(),
                reused,
            }
        }
        let check = |m: &Mat<f64>, z: &Mat<f64>| {
            let r = m * z - &rhs;
            let res = (0..k).fold(0.0f64, |a, i| a.max(r[(i, 0)].abs()));
            assert!(res <= 1e-13, "{res}");
        };
        let z = solve_reduced(&m0, &rhs, how(&key, &mut reused), &seq, &ledger).unwrap();
        check(&m0, &z);
        let first = reused.as_ref().expect("kept").llt.order();
        assert_eq!(first, k);
        assert_eq!(ledger.live(), k * k * 4, "the kept factor is claimed");
        let l00 = |r: &Option<Reused>| r.as_ref().unwrap().llt.first_entry();
        let before = l00(&reused);
        let z = solve_reduced(&m1, &rhs, how(&key, &mut reused), &seq, &ledger).unwrap();
        check(&m1, &z);
        assert_eq!(l00(&reused), before, "M1 solved on M0's factor");
        // One unknown gone, one new: still on M0's factor, embedded.
        let near: Vec<usize> = (1..=k).collect();
        let z = solve_reduced(&m1, &rhs, how(&near, &mut reused), &seq, &ledger).unwrap();
        check(&m1, &z);
        assert_eq!(l00(&reused), before, "embedded");
        // Other unknowns: M1 factored and kept.
        let other: Vec<usize> = (k..2 * k).collect();
        let z = solve_reduced(&m1, &rhs, how(&other, &mut reused), &seq, &ledger).unwrap();
        check(&m1, &z);
        assert_ne!(l00(&reused), before);
        assert_eq!(reused.as_ref().unwrap().key, other);
        assert_eq!(ledger.live(), k * k * 4, "one factor held at a time");
    }

    /// A thin slab of springs, nx x ny x nz nodes with 3 DOFs each: every two
    /// nodes at most one cell diagonal apart joined by a unit spring along
    /// their line (a lattice that resists shear through its diagonals, as an
    /// elastic solid does), plus `anchor` on the diagonal.
    fn lattice(nx: usize, ny: usize, nz: usize, anchor: f64) -> Csc {
        let id = |i: usize, j: usize, l: usize| i + nx * (j + ny * l);
        let mut t = Vec::new();
        for l in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let a = id(i, j, l);
                    for r in 0..3 {
                        t.push((3 * a + r, 3 * a + r, anchor));
                    }
                    // Offsets (di, dj, dl) in {-1, 0, 1}^3 after (0, 0, 0) in
                    // the order of off = (di + 1) + 3 (dj + 1) + 9 (dl + 1):
                    // each pair once.
                    for off in 14..27usize {
                        let o = [off % 3, (off / 3) % 3, off / 9].map(|v| v as i64 - 1);
                        let (i2, j2, l2) = (i as i64 + o[0], j as i64 + o[1], l as i64 + o[2]);
                        if i2 < 0 || j2 < 0 || l2 < 0 {
                            continue;
                        }
                        let (i2, j2, l2) = (i2 as usize, j2 as usize, l2 as usize);
                        if i2 >= nx || j2 >= ny || l2 >= nz {
                            continue;
                        }
                        let b = id(i2, j2, l2);
                        let len = ((o[0] * o[0] + o[1] * o[1] + o[2] * o[2]) as f64).sqrt();
                        let e = o.map(|v| v as f64 / len);
                        for r in 0..3 {
                            for s in 0..3 {
                                let v = e[r] * e[s];
                                t.push((3 * a + r, 3 * a + s, v));
                                t.push((3 * b + r, 3 * b + s, v));
                                t.push((3 * a + r, 3 * b + s, -v));
                                t.push((3 * b + r, 3 * a + s, -v));
                            }
                        }
                    }
                }
            }
        }
        let n = 3 * nx * ny * nz;
        Csc::from_triplets(n, n, &t)
    }

    /// Every bottom node of an nx x ny lattice slab a contact: N = e_z, T =
    /// e_x, e_y (3 DOFs per node, the bottom layer first), as matrices with
    /// `ndof` columns.
    fn slab_contacts(nx: usize, ny: usize, ndof: usize) -> (Csc, Csc) {
        let m = nx * ny;
        let nmat: Vec<_> = (0..m).map(|i| (i, 3 * i + 2, 1.0)).collect();
        let tmat: Vec<_> = (0..2 * m).map(|r| (r, 3 * (r / 2) + r % 2, 1.0)).collect();
        (
            Csc::from_triplets(m, ndof, &nmat),
            Csc::from_triplets(2 * m, ndof, &tmat),
        )
    }

    /// The slab's contact-space load: the gap closed in a round central
    /// patch, b_N = 0.1 - curve r^2, and a shear `shear` along x.
    fn patch_load(nx: usize, ny: usize, curve: f64, shear: f64) -> Vec<f64> {
        let m = nx * ny;
        let centre = (nx as f64 - 1.0) / 2.0;
        (0..m)
            .map(|i| {
                let (x, y) = ((i % nx) as f64 - centre, (i / nx) as f64 - centre);
                0.1 - curve * (x * x + y * y)
            })
            .chain((0..2 * m).map(|r| if r % 2 == 0 { shear } else { 0.0 }))
            .collect()
    }

    /// Newton (target 1e-12) on `dual` from `lam`, set up by `setup`:
    /// asserts that it converged; the driver's outcome and the method's state
    /// (its Krylov counters).
    fn drive_newton(
        dual: &crate::dual::Dual,
        b: &[f64],
        law: Friction<'_>,
        lam: &mut [f64],
        setup: impl FnOnce(&mut Newton),
    ) -> (super::super::driver::Outcome, Newton) {
        let problem = DualProblem {
            dual,
            b,
            law,
            monitor: None,
            deadline: None,
            predicted: false,
            near: false,
        };
        let mut newton = Newton::new(&problem, 1e-12);
        setup(&mut newton);
        let opts = Options {
            method: Method::Newton,
            ..Options::default()
        };
        let out = super::super::driver::drive(&problem, lam, &opts, 1e-12, &mut newton);
        assert_eq!(out.end, super::super::End::Converged, "{out:?}");
        (out, newton)
    }

    /// The largest entrywise difference.
    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    }

    /// Matrix-free Newton on a thin 3D lattice slab, Tresca, with the layered
    /// Dirichlet preconditioner and with the lumped one: both converge to dense
    /// Newton's multipliers (1e-10 relative), the layered one with fewer
    /// products.
    #[test]
    fn the_layered_dirichlet_preconditioner_saves_products() {
        use crate::dual::{Condensation, Dual};
        use crate::factor::Factor;
        use crate::options::Ordering;
        use std::sync::Arc;
        // A thin slab on its bottom face (every bottom node a contact), pressed
        // in a round patch and sheared.
        let (nx, ny, nz) = (16, 16, 4);
        let k = lattice(nx, ny, nz, 1e-4);
        let m = nx * ny;
        let (nm, tm) = slab_contacts(nx, ny, k.nrows);
        let factor =
            Arc::new(Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap());
        let b = patch_load(nx, ny, 0.002, 0.01);
        let p = vec![0.05; m];
        let solve = |dual: &Dual| {
            let mut lam = vec![0.0; dual.c];
            let (out, _) = drive_newton(dual, &b, Friction::Tresca(&p), &mut lam, |_| {});
            (lam, out.inner)
        };
        let mut lumped = Dual::build_with(&factor, &nm, &tm, 3, Condensation::MatrixFree).unwrap();
        lumped.set_lumped(&k);
        lumped.drop_dirichlet();
        let mut layered = Dual::build_with(&factor, &nm, &tm, 3, Condensation::MatrixFree).unwrap();
        layered.set_lumped(&k);
        assert!(layered.force_dirichlet(&k));
        let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
        let (l_dense, _) = solve(&dense);
        let (l_lumped, its_lumped) = solve(&lumped);
        let (l_layered, its_layered) = solve(&layered);
        // Some contacts open, some closed: the active set is not trivial.
        assert!(l_dense[..m].contains(&0.0) && l_dense[..m].iter().any(|&v| v > 0.0));
        let scale = norm(&l_dense);
        for (what, l) in [("lumped", &l_lumped), ("layered", &l_layered)] {
            let diff = max_diff(l, &l_dense);
            assert!(diff <= 1e-10 * scale, "{what}: {diff:.2e}");
        }
        println!("products: lumped {its_lumped}, layered Dirichlet {its_layered}");
        assert!(
            (its_layered as f64) < 0.85 * its_lumped as f64,
            "products: layered {its_layered}, lumped {its_lumped}"
        );
    }

    /// Matrix-free Newton on a 3D lattice slab, Coulomb, pressed in a small
    /// central patch (most contacts open, so they leave the reduced systems)
    /// and sheared so that its contacts slip: its steps' products are narrowed
    /// to the patch's rows (`Dual::narrow_to`), and it converges to dense
    /// Newton's multipliers (1e-10 relative).
    #[test]
    fn coulomb_steps_narrow_their_products_to_the_contact_zone() {
        use crate::dual::{Condensation, Dual};
        use crate::factor::Factor;
        use crate::options::Ordering;
        use std::sync::Arc;
        let (nx, ny, nz) = (24, 24, 3);
        let k = lattice(nx, ny, nz, 0.05);
        let m = nx * ny;
        let (nm, tm) = slab_contacts(nx, ny, k.nrows);
        let factor = Arc::new(
            Factor::with_last(&k, &[], Ordering::Metis, Arc::new(Threads::new(1))).unwrap(),
        );
        let b = patch_load(nx, ny, 0.004, 0.005);
        let mu = vec![0.3; m];
        let solve = |dual: &Dual| {
            let mut lam = vec![0.0; dual.c];
            let (out, newton) = drive_newton(dual, &b, Friction::Coulomb(&mu), &mut lam, |_| {});
            (lam, out.outer, newton.krylov.narrowed)
        };
        let mut free = Dual::build_with(&factor, &nm, &tm, 3, Condensation::MatrixFree).unwrap();
        free.set_lumped(&k);
        let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
        let (l_dense, _, _) = solve(&dense);
        let (l_free, outer, narrowed) = solve(&free);
        let closed = l_dense[..m].iter().filter(|&&v| v > 0.0).count();
        let slipping = (0..m)
            .filter(|&i| {
                let t = l_dense[m + 2 * i].hypot(l_dense[m + 2 * i + 1]);
                l_dense[i] > 0.0 && t >= 0.3 * l_dense[i] * (1.0 - 1e-9)
            })
            .count();
        println!(
            "closed {closed} of {m}, slipping {slipping}; {outer} Newton steps, {narrowed} narrowed"
        );
        assert!(closed > 0 && closed < m / 4, "closed {closed} of {m}");
        assert!(
            slipping > 0,
            "no contact slips: Coulomb's coupling untested"
        );
        assert!(
            narrowed >= outer.saturating_sub(1) && narrowed > 0,
            "{narrowed} of {outer}"
        );
        let diff = max_diff(&l_free, &l_dense);
        assert!(diff <= 1e-10 * norm(&l_dense), "{diff:.2e}");
    }

    /// Matrix-free Newton on a grid's bottom row (d = 2: normal on the row's
    /// DOFs, tangent on the row above), Tresca, with the lumped preconditioner
    /// G = B K B^T (from zero and from the lumped start) and with Jacobi: all
    /// converge to dense Newton's multipliers (1e-10 relative), the lumped
    /// preconditioner with fewer products than Jacobi.
    #[test]
    fn the_lumped_preconditioner_saves_products() {
        use crate::dual::tests::grid;
        use crate::dual::{Condensation, Dual};
        use crate::factor::Factor;
        use crate::options::Ordering;
        use std::sync::Arc;
        let (nx, ny) = (60, 30);
        let k = grid(nx, ny);
        let m = nx;
        let nmat: Vec<_> = (0..m).map(|i| (i, i, 1.0)).collect();
        let tmat: Vec<_> = (0..m).map(|i| (i, i + nx, 1.0)).collect();
        let (nm, tm) = (
            Csc::from_triplets(m, nx * ny, &nmat),
            Csc::from_triplets(m, nx * ny, &tmat),
        );
        let factor =
            Arc::new(Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap());
        // Pressed in the middle, pulled off at the ends, sheared.
        let b: Vec<f64> = (0..m)
            .map(|i| 0.5 - ((i as f64 - 30.0) / 20.0).powi(2))
            .chain((0..m).map(|i| 0.3 * (i as f64 * 0.2).sin()))
            .collect();
        let p = vec![0.04; m];
        let solve = |dual: &Dual, start: bool| {
            let mut lam = vec![0.0; dual.c];
            let law = Friction::Tresca(&p);
            let (out, _) = drive_newton(dual, &b, law, &mut lam, |n| n.lumped_start_on = start);
            (lam, out.inner, out.outer)
        };
        let jacobi = Dual::build_with(&factor, &nm, &tm, 2, Condensation::MatrixFree).unwrap();
        let mut lumped = Dual::build_with(&factor, &nm, &tm, 2, Condensation::MatrixFree).unwrap();
        lumped.set_lumped(&k);
        assert!(jacobi.lumped().is_none() && lumped.lumped().is_some());
        let dense = Dual::build_with(&factor, &nm, &tm, 2, Condensation::Solves).unwrap();
        let (l_dense, _, _) = solve(&dense, true);
        let (l_jacobi, its_jacobi, _) = solve(&jacobi, true);
        let (l_lumped, its_lumped, steps_cold) = solve(&lumped, false);
        let (l_start, its_start, steps_start) = solve(&lumped, true);
        println!(
            "steps: from zero {steps_cold}, from the lumped start {steps_start}; products {its_start}"
        );
        assert!(its_start > 0 && steps_start > 0);
        let scale = norm(&l_dense);
        assert!(l_dense.contains(&0.0) && l_dense[..m].iter().any(|&v| v > 0.0));
        for (what, l) in [
            ("jacobi", &l_jacobi),
            ("lumped", &l_lumped),
            ("start", &l_start),
        ] {
            let diff = max_diff(l, &l_dense);
            assert!(diff <= 1e-10 * scale, "{what}: {diff:.2e}");
        }
        assert!(
            its_lumped < its_jacobi,
            "products: lumped {its_lumped}, jacobi {its_jacobi}"
        );
        println!("products: lumped {its_lumped}, jacobi {its_jacobi}");
    }
}
