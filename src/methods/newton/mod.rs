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
//! double from order MIXED_MIN on; where it is not (Coulomb), by GMRES on the
//! single-precision factor of its symmetric part from that order on, else
//! by LU (`solve_reduced`). The single-precision factor is kept for the next
//! step, and on the dual for the next solve's first step
//! (`Dual::with_kept_factor`): where that step has the same reduced
//! unknowns, or a few more or fewer (the active set settling, slip
//! directions turning; `Reused`), CG or GMRES preconditioned by it (bordered
//! for the unknowns that came and went, `dense::kept`) solves the next
//! system without a new factorisation. GMRES stops at the step's forcing
//! term (see `forcing`): the Coulomb steps' slip directions turn from step
//! to step, so an exact direction buys little (measured on the 3d-24x24x12
//! blocks' Coulomb histories: 1-4 GMRES iterations per step in place of
//! 7-22 in a traced run, and 27-30 Newton steps over nine warm steps in
//! place of 19-27); a step from such a solve that the backtracking rejects
//! is solved again exactly before the fallback.
//! On the warm solves of a 3D dual (a history's steps), a reduced system
//! whose left-out components and slipping unknowns number at most half of
//! its unknowns is not assembled: CG or GMRES run on products with A,
//! preconditioned by A^-1 in single precision, made once per A and kept on
//! the dual (`Dual::inverse`), through a bordered system of that order
//! (`dense::Complement`; `solve_on_inverse`).
//! The symmetric solves go on to the backward error of a solve in double:
//! refinement and CG get there in 1-3 rounds, and a Tresca step whose sort
//! is right then ends the solve (an inexact one doubled the Tresca warm
//! steps' Newton steps, 9 -> 18).
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
//! factor 1 - ARMIJO t, and of those lengths the one with the lowest |F| is
//! kept (each costs O(c), no product: A d is one product, or the
//! combination of a matrix-free reduced solve's own products where they
//! were not narrowed and the solve did not refine, `krylov_step`); err is
//! not the merit, since its
//! denominator grows with |lambda| and a step could "lower" it by inflating the
//! multipliers. Otherwise the iterate takes a few projected Gauss-Seidel sweeps (a
//! first-order descent step for Tresca) and Newton restarts from there, so it
//! cannot cycle. When neither has lowered |F| by STALL_DROP for STALL_WINDOW
//! iterations the solve gives up (stalled) instead of burning the iteration limit
//! on a problem without a solution.
//!
//! Warm-up: every solve on a dense A starts with up to PRESWEEPS projected
//! Gauss-Seidel sweeps (cheap against a Newton step), so that the first active
//! set Newton sees is near the answer (one chunk where the start is near
//! already: the later rounds of Newton on a nonlinear law, a 3D history step's
//! prediction); they, and the fallback's, read A in
//! single precision on a large dual (`sweeps::Rough`, `sweeps::ROUGH_MIN_C`). A
//! matrix-free dual has no entries to sweep: a cold solve starts instead at the projection of alpha G b, G = B K B^T
//! the lumped estimate of A^-1 (alpha minimising the dual energy along G b),
//! when that lowers |F|, and its steps sort and linearise with rho scaled by
//! COLD_C, leaning on the multipliers of that start; its reduced systems are
//! solved by CG / GMRES preconditioned with G too (`krylov_step`).
//!
//! Warm start: the first step of a warm-started solve sorts the components by the
//! multipliers (see WARM_C), not by the natural map, so that a history step starts
//! from the active set of the previous increment; where the start is a history's
//! prediction (`DualProblem::predicted`: the load increment is already in it), by
//! the natural map at it.
//!
//! Files: `step.rs` (the linearisation and the reduced unknowns; the dense
//! reduced system's assembly), `reduced_dense.rs` (its dense solves and the
//! factor kept between steps), `reduced_krylov.rs` (the Krylov solve on a
//! matrix-free dual, its preconditioner and refinement), this file (the outer
//! loop: warm-up, globalisation, fallback, stall).

use super::driver::{Flow, Gradient, OuterStep};
use super::mprgp::ConvexQp;
use super::subproblem::Mprgp;
use super::sweeps;
use super::{DualProblem, MethodSpec};
use crate::dense;
use crate::friction::Friction;
use crate::memory::{F64, Ledger};
use crate::threads::{PARALLEL_MIN_ENTRIES, Threads};
use faer::Mat;
use std::sync::Arc;

/// Gauss-Seidel sweeps taken when a Newton step is rejected.
const FALLBACK_SWEEPS: usize = 5;

/// MPRGP iterations taken at most instead when a Newton step on a matrix-free
/// dual is rejected (each one product with A, as a Krylov iteration of a step).
const FALLBACK_MPRGP: usize = 20;

/// The fallback's MPRGP stops once its residual (that of the Tresca problem
/// of the current bound) has fallen to this fraction of the one at its
/// start (Newton's iterate projected onto the bounds): Newton restarts from
/// there. On the host example's 3D scenes, whose first shear iterations
/// reject Newton steps, the contact solves' products fell from 385 to 366
/// (3d-32x32x4, Newton steps 110 -> 109) and from 588 to 556 (3d-52x52x4,
/// Newton steps 141 -> 147): 3 % and 1.7 % less work, a Newton step
/// weighed as 2.7 products. Fallbacks of 5 iterations instead saved more
/// products on 3d-32x32x4 (346) but took 161 Newton steps on 3d-52x52x4,
/// and a fifth in place of half never stopped early (BENCHMARKS.md, "What
/// is slow, and why", item 12).
const FALLBACK_DROP: f64 = 0.5;

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

mod reduced_dense;
mod reduced_krylov;
mod step;

use reduced_dense::*;
use reduced_krylov::*;
use step::*;

/// The relative error assumed of a product with A in single precision
/// (`Dual::apply_rough`): an estimate, not a bound (the error grows with the
/// factor's conditioning; measured at most 6.3e-7 on the 3d-64x64x6 slab's
/// steps, 2.9e-7 on 3d-116x116x4, about 1e-6 on a nearly floating lattice
/// slab in `newton::tests`). A step of length t whose A d was combined
/// from such products moves w by t A d to within about ROUGH_DRIFT t s, s
/// the sum of the sizes combined (`Krylov::spread`). Where the estimate
/// falls short, the recomputation comes late; a convergence is still
/// accepted only on an exact w, or on the error the increment solve
/// measures on the recovered u (`DualProblem::measured_after`).
const ROUGH_DRIFT: f64 = 1e-6;

/// w is recomputed (one exact product) after a Newton step where the
/// estimate of its drift, in |F|'s units, exceeds 1 / RESYNC of |F|: the
/// next sort, the backtracking and the driver's err read w. Measured on the
/// 3d-32x32x4 slab's proportional histories (two runs each): 10 and 100
/// gave the same warm steps, 1000 up to 10 % slower ones, and no
/// recomputation before the driver's confirmation 15-30 % slower ones.
/// Not where the drift is below ENOUGH of the target (in |F|'s units, err's
/// scale taken as |lambda|, as in [`forcing`]): it then moves err by about
/// a tenth of the target at most (times the dual's err factor, 1 but on
/// kept contact blocks; the drift is an estimate), and the last step of a
/// solve, whose |F| fell below RESYNC times the drift, need not be
/// followed by a recomputation (on the 3d-32x32x4 slab's proportional
/// histories, nine warm steps: 27 exact products fell to 19 for Tresca,
/// 31 to 26 for Coulomb, whose first steps are narrowed).
const RESYNC: f64 = 100.0;

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

/// Every step of a solve that began at the lumped start (a cold solve on a
/// matrix-free dual, `Newton::lumped_start`) sorts and linearises with rho
/// scaled by COLD_C (the same zeros, as for WARM_C): between the multipliers of
/// that start and the natural map's trial. With rho itself the trial overshoots
/// in a cold gross slip: on 3d-64x64x6g (Coulomb, proportional, 17 degrees,
/// full load) the first four steps took lengths 0.25, 1, 0.5 and 0.5 and
/// lowered |F| by 1.4-2.3 times each (err 1.7e-1, 8.0e-2, 4.0e-2, 1.7e-2), the
/// stick and slip zones settled after the second; 9 steps in all, 6 with 0.5.
/// On the load-path family's matrix-free slabs (3d-24x24x4 to 3d-116x116x4,
/// uniform and graded faces, three paths, both laws: 42 cold increments at full
/// load) 0.5 took the Newton steps from 250 to 218 and the Krylov products from
/// 924 to 859: Tresca fewer steps or products on 19 of 21 rows, more on none;
/// Coulomb fewer on 11 (the row above 9 -> 6 steps, 38 -> 29 products), more on
/// 6 by one step or 1-3 products at most. 0.3 and 0.1 took Tresca lower still
/// and some Coulomb rows higher (BENCHMARKS.md, "The load paths hosts take"). A
/// warm solve keeps rho after its first step: 0.3 there took 1-3 more Newton
/// steps on four of six Coulomb histories of 3d-32x32x4. A dense dual's cold
/// solve starts from Gauss-Seidel sweeps instead; its counts did not move with
/// the scale (3d-16x16x8, 3d-24x24x12, 2d-400x50).
const COLD_C: f64 = 0.5;

/// The solve gives up when the best |F| has not dropped by STALL_DROP (relative)
/// within STALL_WINDOW outer iterations.
const STALL_WINDOW: usize = 50;
const STALL_DROP: f64 = 1e-2;

/// |F(lam)|_2, the natural map of the module docs at lam (w = A lam - b), in force
/// units: unlike err it does not shrink when lambda grows without bound.
pub(super) fn residual_norm(problem: &DualProblem<'_>, lam: &[f64], w: &[f64]) -> f64 {
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
    // vectors (GMRES's basis, its preconditioned vectors, the products kept
    // for A d and a few more, length c at most).
    workspace: |_m, c, matrix_free| {
        if matrix_free {
            (3 * super::krylov::RESTART + 12) * c * F64
        } else {
            let rough = if c >= sweeps::ROUGH_MIN_C {
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
    /// Whether a warm 3D solve on a dense dual may precondition its reduced
    /// systems with A's inverse (`dense::Complement`); off only in the
    /// test of the kept factor.
    inverse_on: bool,
    /// The scale of rho in the steps of a solve that began at the lumped
    /// start (COLD_C; 1 only in the test that measures what it buys).
    cold_c: f64,
    /// Whether this solve began at the lumped start (a cold solve on a
    /// matrix-free dual whose lumped estimate lowered |F|).
    from_lumped: bool,
    step: Vec<f64>,
    f: Vec<f64>,
    ae0: Vec<f64>,
    trial: Vec<f64>,
    wt: Vec<f64>,
    /// The reduced solves' Krylov state on a matrix-free dual.
    krylov: Krylov,
    /// A's columns in single precision for the warm-up and fallback sweeps on
    /// a large assembled dual (made at their first use; see sweeps::ROUGH_MIN_C).
    rough_a: Option<sweeps::Rough>,
    /// The matrix-free fallback's MPRGP (made at its first use), the bounds it
    /// works with and its estimate of |A|.
    fallback: Option<Mprgp>,
    radii: Vec<f64>,
    norm: Option<f64>,
    /// |F| at the start (the forcing terms' reference).
    res0: f64,
    /// |F| at the current iterate, and the lowest |F| with the iteration it was met.
    res: f64,
    /// The last Newton step, when the last outer iteration was one (the
    /// forcing term's history; None at the start and after a fallback).
    last: Option<LastStep>,
    /// An estimate of how far w has drifted from A lam - b (2-norm, w's
    /// units) through steps whose A d came from rough products (see
    /// ROUGH_DRIFT); 0 where w is exact.
    drift: f64,
    /// The largest rho: |F| moves by at most rho_max times w's drift.
    rho_max: f64,
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
            inverse_on: true,
            cold_c: COLD_C,
            from_lumped: false,
            step: vec![0.0; c],
            f: vec![0.0; c],
            ae0: vec![0.0; c],
            trial: vec![0.0; c],
            wt: vec![0.0; c],
            krylov: Krylov::new(c),
            rough_a: None,
            fallback: None,
            radii: Vec::new(),
            norm: None,
            res0: 0.0,
            res: 0.0,
            last: None,
            drift: 0.0,
            rho_max: 0.0,
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
        if !self.warm {
            // A cold start's first sorts have nothing in common with the
            // last solve's: its factor would only cost failed iterations.
            problem.dual.with_kept_factor(|kept| *kept = None);
        }
        // The error's scratch: `f` and `ae0` are overwritten by every step.
        let (p, v) = (&mut self.f[..m], &mut self.ae0[..c]);
        let mut swept = 0;
        // Gauss-Seidel reads entries of A: no sweeps on a matrix-free dual.
        let presweeps = if problem.dual.is_matrix_free() {
            0
        } else if problem.near || (self.warm && problem.predicted && problem.dual.d == 3) {
            // One chunk where the start is already near the answer: a later
            // round of Newton on a nonlinear law (the last round's answer), and
            // in 3D a history step's prediction. Measured (BENCHMARKS.md,
            // "Quasistatic histories"): the 3D dense blocks' warm Tresca steps
            // 0.139 -> 0.099 and 0.200 -> 0.167 of a factorisation; in 2D the
            // strip's Newton steps went 0.7 -> 3.4 per warm step (0.170 ->
            // 0.302), so 2D histories keep the 40 sweeps.
            self.presweeps.min(PRESWEEP_CHUNK)
        } else {
            self.presweeps
        };
        while swept < presweeps && problem.error(lam, w, p, v) > self.target {
            let n = PRESWEEP_CHUNK.min(presweeps - swept);
            *inner += sweeps::sweeps_for_newton(problem, &mut self.rough_a, lam, w, n);
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
        self.from_lumped = false;
        if let Some(g) = problem.dual.lumped()
            && !self.warm
            && self.lumped_start_on
        {
            self.from_lumped = self.lumped_start(problem, g, lam, w);
        }
        self.res = residual_norm(problem, lam, w);
        self.res0 = problem.start_from.map_or(self.res, |r| r.max(self.res));
        self.last = None;
        self.krylov.last_sort = None;
        self.drift = 0.0;
        self.rho_max = problem.dual.rho.iter().fold(0.0, |a: f64, &r| a.max(r));
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
        // (see WARM_C), the steps of a solve that began at the lumped start
        // lean on its multipliers (COLD_C); every other step sorts by the
        // natural map.
        let cscale = if self.warm && self.warm_sort && !problem.predicted && !problem.near && k == 0
        {
            WARM_C
        } else if self.from_lumped {
            self.cold_c
        } else {
            1.0
        };
        self.krylov.inverse = self.inverse_on && self.warm && problem.dual.d == 3;
        // No tighter than ROUGH_ETA where a matrix-free dual's products run
        // in single precision (see `forcing`).
        let floor = if problem.dual.offers_rough() {
            ROUGH_ETA
        } else {
            0.0
        };
        let lam_norm = norm(lam);
        self.krylov.eta = forcing(self.res, self.res0, self.target, lam_norm, self.last, floor);
        // Where the sort is the last whole step's (`Krylov::settle`): no
        // looser than the floor and the target's need.
        self.krylov.settled_eta =
            settled_forcing(self.res, self.target, lam_norm, floor).min(self.krylov.eta);
        // A step from rough (single-precision) products that the backtracking
        // rejects is solved again with exact ones before any fallback: on an
        // ill-conditioned K the rough products can be too rough. So is a
        // dense step whose GMRES stopped at the forcing term.
        self.krylov.inexact_dense = false;
        for exact in [false, true] {
            let rough = if problem.dual.is_matrix_free() {
                self.krylov.eta >= ROUGH_ETA
            } else {
                self.krylov.inexact_dense
            };
            self.krylov.exact = exact;
            if exact && !rough {
                break;
            }
            if exact && self.drift > 0.0 {
                // The exact solve starts from an exact gradient: the
                // rejection may be the drift's.
                self.resync(problem, lam, w);
            }
            let (step, trial, wt) = (&mut self.step, &mut self.trial, &mut self.wt);
            let before = self.krylov.its;
            // The last dense reduced system's factor (see [`Reused`]) is
            // kept on the dual, from step to step and from solve to solve.
            let solved = problem.dual.with_kept_factor(|reused| {
                newton_step(
                    problem,
                    lam,
                    w,
                    step,
                    &mut self.f,
                    &mut self.ae0,
                    cscale,
                    &mut self.krylov,
                    reused,
                )
            });
            *inner += self.krylov.its - before;
            let Some(combined) = solved else {
                continue;
            };
            // Backtracking: the full step and halves of it, their gradients
            // w + t A d (A is linear). A d is the reduced solve's own
            // combination of its products where it made one (`krylov_step`:
            // a matrix-free dual whose products were not narrowed), else one
            // exact product: that leaves w one addition's rounding away from
            // A (lam + t d) - b, as current as a gradient computed afresh,
            // so the driver need not recompute it before it accepts a
            // convergence (one product per solve saved). A combination of
            // single-precision products drifts (see ROUGH_DRIFT), and w is
            // then recomputed where the drift nears |F| and matters against
            // the target (`needs_resync`), and before a convergence is
            // accepted (by the driver, or by the increment solve's error
            // on the recovered u). (A single-precision product in place
            // of the exact one, on the narrowed steps, saved nothing on the
            // host example's solves of three or four Newton steps, whose
            // products are narrowed: half a product a step against the
            // exact one that confirms the convergence, and one more Newton
            // step in one of its solves; tried again once the recovered u
            // confirmed drifted convergences: nothing measurable on
            // 3d-64x64x6, one more Newton step in two of 3d-32x32x4's host
            // iterations.) Every
            // length is tried (each costs O(c), no product) and the one
            // with the lowest |F| among those that meet the sufficient
            // decrease is kept, not the first: where the step flips many
            // contacts (the onset of gross slip) a shorter step can lower
            // |F| more than a longer one that barely meets it (BENCHMARKS.md,
            // "The nonlinear host": 6-8 % fewer Newton steps on the host
            // example).
            let rough_ad = combined && self.krylov.rough() && problem.dual.offers_rough();
            let ad = &mut self.ae0;
            // The displacement carried with lam moves with an exact
            // product's solution (`dual::Primal`); any other step leaves it
            // behind.
            let mut primal = problem.primal.map(|p| p.borrow_mut());
            let mut carried = false;
            if combined {
                self.krylov.combined += 1;
            } else {
                carried = primal.as_mut().is_some_and(|p| {
                    p.holds_at(lam) && problem.dual.apply_keeping(step, ad, &mut p.z)
                });
                if !carried {
                    problem.dual.apply(step, ad);
                }
            }
            let (mut t, mut kept) = (1.0, None);
            for _ in 0..BACKTRACKS {
                for j in 0..c {
                    trial[j] = lam[j] + t * step[j];
                    wt[j] = w[j] + t * ad[j];
                }
                kept = better_length(self.res, kept, (t, residual_norm(problem, trial, wt)));
                t *= 0.5;
            }
            if let Some((t, r)) = kept {
                for j in 0..c {
                    lam[j] += t * step[j];
                    w[j] += t * ad[j];
                }
                if let Some(p) = primal.as_mut() {
                    if carried {
                        p.moved_by(t, lam);
                    } else {
                        p.drop_u();
                    }
                }
                self.last = Some(LastStep {
                    ratio: r / self.res,
                    full: t == 1.0,
                });
                self.krylov.taken(t == 1.0, combined);
                self.res = r;
                if rough_ad {
                    self.drift += ROUGH_DRIFT * t * self.krylov.spread;
                }
                // w drifted too far to trust |F| against it (the next sort,
                // the backtracking, the driver's err): recomputed.
                if needs_resync(self.res, self.rho_max * self.drift, self.target, norm(lam)) {
                    self.resync(problem, lam, w);
                }
                return Flow::Go(if self.drift > 0.0 {
                    Gradient::Drifted
                } else {
                    Gradient::Exact
                });
            }
        }
        if problem.dual.is_matrix_free() {
            return self.mprgp_fallback(problem, lam, w, inner);
        }
        // Fallback: a first-order step.
        *inner += sweeps::sweeps_for_newton(problem, &mut self.rough_a, lam, w, FALLBACK_SWEEPS);
        problem.gradient(lam, w);
        self.res = residual_norm(problem, lam, w);
        self.drift = 0.0;
        self.last = None;
        self.krylov.last_sort = None;
        Flow::Go(Gradient::Exact)
    }

    fn refreshed(&mut self, problem: &DualProblem<'_>, lam: &[f64], w: &[f64]) {
        self.res = residual_norm(problem, lam, w);
        self.drift = 0.0;
    }
}

impl Newton {
    /// w := A lam - b afresh (one exact product), and |F| with it.
    fn resync(&mut self, problem: &DualProblem<'_>, lam: &[f64], w: &mut [f64]) {
        problem.gradient(lam, w);
        self.res = residual_norm(problem, lam, w);
        self.drift = 0.0;
    }

    /// A cold start on a matrix-free dual: lam = P(alpha G b), the projection
    /// onto the feasible set of the minimiser of the dual energy along G b
    /// (G = B K B^T ~ A^-1: the lumped estimate of the unconstrained
    /// multipliers), kept when it lowers |F| below its value at lam = 0
    /// (then true). Two products with A.
    fn lumped_start(
        &mut self,
        problem: &DualProblem<'_>,
        g: &crate::sparse::Csc,
        lam: &mut [f64],
        w: &mut [f64],
    ) -> bool {
        let dual = problem.dual;
        let (m, d, c) = (dual.m, dual.d, dual.c);
        let (y, ay) = (&mut self.trial, &mut self.wt);
        g.mul_vec(problem.b, y);
        dual.apply_rough(y, ay);
        let yay: f64 = y.iter().zip(ay.iter()).map(|(a, b)| a * b).sum();
        let by: f64 = y.iter().zip(problem.b).map(|(a, b)| a * b).sum();
        if !(yay > 0.0 && by > 0.0 && yay.is_finite()) {
            return false;
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
            return true;
        }
        false
    }

    /// The fallback on a matrix-free dual (no Gauss-Seidel without entries of A):
    /// MPRGP / MPGP (one product with A an iteration) on the Tresca problem of
    /// the current bound, from lam, until its residual halves (FALLBACK_DROP)
    /// or for FALLBACK_MPRGP iterations: a first-order descent step
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
            .get_or_insert_with(|| Mprgp::new(c, 0.0, FALLBACK_MPRGP).with_drop(FALLBACK_DROP));
        // |A + D| estimated once per operator (see `Dual::whole_norm`).
        if self.norm.is_none() {
            self.norm = dual.whole_norm();
        }
        let run = solver.solve_convex(&qp, lam, &mut self.norm);
        if let Some(norm) = self.norm {
            dual.keep_whole_norm(norm);
        }
        if let Flow::Infeasible = Flow::after(run, inner, Gradient::Stale) {
            return Flow::Infeasible;
        }
        problem.gradient(lam, w);
        self.res = residual_norm(problem, lam, w);
        self.drift = 0.0;
        self.last = None;
        self.krylov.last_sort = None;
        Flow::Go(Gradient::Exact)
    }
}

/// The step length (and |F| after it) to keep of `kept` and `tried`, for a
/// step from |F| = `res`: the one with the lower |F| among those that meet
/// the sufficient decrease |F| <= (1 - ARMIJO t) res; None when neither does.
fn better_length(res: f64, kept: Option<(f64, f64)>, tried: (f64, f64)) -> Option<(f64, f64)> {
    let (t, r) = tried;
    let meets = r <= (1.0 - ARMIJO * t) * res;
    match kept {
        Some((_, rk)) if !meets || rk <= r => kept,
        _ if meets => Some(tried),
        _ => None,
    }
}

/// The fraction of the target a step's error aims at (see [`forcing`]).
const ENOUGH: f64 = 0.1;

/// Whether w is recomputed after a step that left |F| = `res`, with w's
/// estimated drift `drift` in |F|'s units (rho_max times its 2-norm), for
/// the dual target `target` at |lambda| = `lam_norm` (see RESYNC): where
/// the drift exceeds 1 / RESYNC of |F| and ENOUGH of the target.
fn needs_resync(res: f64, drift: f64, target: f64, lam_norm: f64) -> bool {
    drift > 0.0 && res < RESYNC * drift && drift > ENOUGH * target * lam_norm
}

/// A Newton step's outcome that the next step's forcing term reads.
#[derive(Copy, Clone, Debug)]
struct LastStep {
    /// |F| after it over |F| before.
    ratio: f64,
    /// Whether it was taken whole (no backtracking).
    full: bool,
}

/// A whole step that left more than POOR of |F| learnt little from its
/// linear model: the next reduced solve is only asked for LOOSE (see
/// [`forcing`]).
const POOR: f64 = 0.5;
const LOOSE: f64 = 0.5;

/// Eisenstat and Walker's second choice of forcing term, as a floor after a
/// whole step that shrank |F| by `ratio` (at most POOR): eta >=
/// min(SEEN_GAMMA ratio^2, 0.1) (their gamma = 0.9, alpha = 2; see
/// [`forcing`]).
const SEEN_GAMMA: f64 = 0.9;

/// The forcing term of an inexact Newton step on a matrix-free dual, and of
/// GMRES on a dense dual's non-symmetric (Coulomb) reduced system: the
/// relative residual its reduced system is solved to.
///
/// - By default eta = |F| / |F_0|, capped at 0.1: superlinear convergence.
/// - After a whole step (no backtracking) that left more than POOR of |F|,
///   eta = LOOSE. The sort its model was built on was far from the answer
///   (on the slabs' cold Coulomb increments a band of contacts flips
///   between stick and slip for several steps), and a tighter solve of
///   such a model buys no more: traced on the 64 x 64 x 6 slab, the cold
///   increments' steps there fell from 4 products to 2-3 each with as many
///   steps. After a backtracked step the direction itself fell short and
///   the default holds: loose directions there took up to twice the steps
///   on the lattice slabs of the tests.
/// - After a whole step that shrank |F| by `ratio` (at most POOR), never
///   tighter than SEEN_GAMMA ratio^2 (capped at 0.1; Eisenstat and
///   Walker's second choice, SIAM J. Sci. Comput. 17, 1996, as a floor).
///   Where the steps converge only linearly, a few contacts changing
///   state at each, the default asks every reduced solve for |F| / |F_0|
///   (1e-3 to 1e-4 late in a warm step) while the step can shrink |F| by
///   its linear rate only (about 0.2 on the 64 x 64 x 6 slab's
///   proportional Coulomb history).
///   Measured on eight rows of the load-path family's matrix-free slabs
///   (3d-32x32x4 and its graded face, 3d-64x64x6 and its graded face,
///   3d-116x116x4; products counted): Coulomb histories' warm steps took
///   up to 6 % fewer products (234 -> 220, 233 -> 218, 188 -> 181 over
///   nine steps; one row 1 more), their cold increments 0-4 fewer (30 ->
///   29, 29 -> 26, 23 -> 19); Tresca's, which converge superlinearly,
///   the same counts on the uniform slabs and 1-2 fewer products on the
///   graded one, the dense duals' the same counts.
/// - Never tighter than a step whose error leaves |F| at ENOUGH of the
///   target (err's scale taken as |lambda|; the history benchmark's last
///   steps then end at err 1e-12 to 8e-11 for the target 1e-10, and a
///   hundredth spent 2-3 more products per increment for errors a decade
///   lower).
/// - Never tighter than `floor`: ROUGH_ETA where a matrix-free dual's
///   products run in single precision, so that every reduced solve runs
///   on them (a tighter one refines with exact products, about twice the
///   time each, and `refine`'s rounds). The last steps of a solve then
///   shrink |F| by about 1e-4 each at best, and may take one more Newton
///   step; measured on the load-path family's matrix-free slabs (BENCHMARKS.md,
///   "The matrix-free route: no reduced solve tighter than its rough
///   products"): 3-16 % fewer products over a history's warm steps, 0-2
///   more Newton steps, the warm mean 5 % lower summed over the rows. A
///   solve now ends nearer its tolerance (err 9e-11 for 1e-10 where it
///   overshot to 1e-13).
///
/// A step whose sort is the last whole step's, where that step's A d took
/// a product of its own, is solved to the floor instead (no tighter than
/// the target's need: [`settled_forcing`], `Krylov::settle`).
fn forcing(
    res: f64,
    res0: f64,
    target: f64,
    lam_norm: f64,
    last: Option<LastStep>,
    floor: f64,
) -> f64 {
    let eta = match last {
        Some(l) if l.full && l.ratio > POOR => LOOSE,
        Some(l) if l.full && res0 > 0.0 => {
            (res / res0).max(SEEN_GAMMA * l.ratio * l.ratio).min(0.1)
        }
        _ if res0 > 0.0 => (res / res0).min(0.1),
        _ => 0.1,
    };
    eta.max(enough(res, target, lam_norm)).max(floor).max(1e-14)
}

/// The forcing term of a step whose sort is the last whole step's
/// (`Krylov::settle`): the floor, and no tighter than a step whose error
/// leaves |F| at ENOUGH of the target, as in [`forcing`] (at most 0.1).
fn settled_forcing(res: f64, target: f64, lam_norm: f64, floor: f64) -> f64 {
    enough(res, target, lam_norm).max(floor).max(1e-14)
}

/// The forcing term whose step leaves |F| at ENOUGH of the target (err's
/// scale taken as |lambda| = `lam_norm`), at most 0.1: no reduced solve
/// is asked for less (see [`forcing`]).
fn enough(res: f64, target: f64, lam_norm: f64) -> f64 {
    if res > 0.0 {
        (ENOUGH * target * lam_norm / res).min(0.1)
    } else {
        0.1
    }
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests;
