//! The outer loop every method shares: the gradient w = A lambda - b, the error of
//! each iterate, the best iterate, the monitor and the four stop tests (tolerance,
//! iteration limit, stagnation, wall clock). A method is an [`OuterStep`]: one
//! outer iteration from the current iterate, and the work before the first one.

use super::mprgp::Unbounded;
use super::{DualProblem, Progress};
use crate::options::Options;
use crate::report::contact_states;
use std::time::Instant;

/// Why a method run ended.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum End {
    /// The dual error met the target.
    #[default]
    Converged,
    /// `Options::max_outer` outer iterations were done.
    Limit,
    /// The stagnation test of [`Stagnation`] fired, or the method found that it
    /// makes no progress (Newton's test on |F|).
    Stalled,
    /// The wall-clock budget `Options::max_seconds` ran out.
    TimeLimit,
    /// The monitor asked to stop.
    Stopped,
    /// The method proved that no u satisfies N u <= g (an MPRGP sub-problem is
    /// unbounded below).
    Infeasible,
}

/// A fault injected by tests: a run whose caller measures the error on the
/// recovered u (`DualProblem::measured_after`) claims convergence at its
/// first drifted gradient whatever its err, as a drift that went unseen
/// would, so that the tests can show the caller catching it (the
/// increment solve's confirmed retry). Absent outside the unit tests.
pub(crate) mod fault {
    use super::Gradient;

    #[cfg(test)]
    thread_local! {
        /// Whether the fault is on (this thread's runs only), the
        /// convergences it claimed, and the runs that confirm every
        /// convergence on an exact gradient (`measured_after` false) begun
        /// while it was on.
        static CLAIM: std::cell::Cell<(bool, usize, usize)> =
            const { std::cell::Cell::new((false, 0, 0)) };
    }

    /// Turns the fault on or off for this thread's runs and returns the
    /// convergences claimed and the confirming runs begun since it was last
    /// set.
    #[cfg(test)]
    pub(crate) fn claim_drifted(on: bool) -> (usize, usize) {
        let (_, claimed, confirming) = CLAIM.with(|c| c.replace((on, 0, 0)));
        (claimed, confirming)
    }

    /// Whether the run ends converged here by the injected fault.
    #[cfg(test)]
    pub(super) fn claims(gradient: Gradient, measured_after: bool) -> bool {
        let (on, claimed, confirming) = CLAIM.with(|c| c.get());
        let hit = on && gradient == Gradient::Drifted && measured_after;
        if hit {
            CLAIM.with(|c| c.set((on, claimed + 1, confirming)));
        }
        hit
    }

    /// Counts a run that begins, where it confirms every convergence.
    #[cfg(test)]
    pub(super) fn begins(measured_after: bool) {
        let (on, claimed, confirming) = CLAIM.with(|c| c.get());
        if on && !measured_after {
            CLAIM.with(|c| c.set((on, claimed, confirming + 1)));
        }
    }

    /// Never, outside the unit tests.
    #[cfg(not(test))]
    #[inline(always)]
    pub(super) fn claims(_: Gradient, _: bool) -> bool {
        false
    }

    /// Nothing, outside the unit tests.
    #[cfg(not(test))]
    #[inline(always)]
    pub(super) fn begins(_: bool) {}
}

/// What a method run reports back.
#[derive(Copy, Clone, Debug, Default)]
pub struct Outcome {
    /// Outer iterations done.
    pub outer: usize,
    /// Inner iterations (sweeps, MPRGP iterations) done in total.
    pub inner: usize,
    /// The error measured on the dual gradient at the returned iterate.
    pub dual_err: f64,
    /// Why the run ended.
    pub end: End,
    /// The dual unknowns the method iterated on (m for a frictionless increment
    /// solved as the pure Signorini problem, d m otherwise).
    pub unknowns: usize,
    /// The method that gave the returned iterate (never `Auto`; None before a
    /// run).
    pub method: Option<crate::options::Method>,
    /// Why `Auto` chose it (empty for a method given by the options).
    pub choice: &'static str,
    /// The run ended converged on a drifted gradient, unconfirmed, where
    /// the caller measures the error on the recovered u
    /// (`DualProblem::measured_after`): `dual_err` is the drifted one.
    pub unconfirmed: bool,
}

/// What a step leaves in w.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Gradient {
    /// w must be recomputed.
    Stale,
    /// w = A lambda - b, computed from lambda.
    Exact,
    /// w was kept by rank-one updates: current up to the rounding they gather, so
    /// it is recomputed before a convergence is accepted.
    Updated,
    /// w was kept by updates from single-precision products (Newton on a
    /// matrix-free dual): off by up to about 1 % of |F|, or where that is
    /// more, about a tenth of the target in err's units (Newton's
    /// `needs_resync`), so it is recomputed before a convergence is
    /// accepted (or the convergence is left to the caller's measurement on
    /// the recovered u, where it makes one: `DualProblem::measured_after`),
    /// before the solve ends otherwise, and before its err is kept as the
    /// best.
    Drifted,
}

/// How a step (or the start) ended.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Flow {
    /// Go on; w as said.
    Go(Gradient),
    /// No u satisfies N u <= g (see [`End::Infeasible`]).
    Infeasible,
    /// The method's own progress test says it cannot get further.
    Stalled,
}

impl Flow {
    /// The flow after a sub-problem solve: inner iterations added to `inner`.
    pub fn after(run: Result<usize, Unbounded>, inner: &mut usize, then: Gradient) -> Flow {
        match run {
            Ok(its) => {
                *inner += its;
                Flow::Go(then)
            }
            Err(u) => {
                *inner += u.iterations;
                Flow::Infeasible
            }
        }
    }
}

/// One method: the work before the first outer iteration and one outer iteration.
pub(super) trait OuterStep {
    /// Work before the first iteration (a warm-up, a first sub-problem), from
    /// `lam` with w = A lam - b. The default does nothing.
    fn start(
        &mut self,
        _problem: &DualProblem<'_>,
        _lam: &mut [f64],
        _w: &mut [f64],
        _inner: &mut usize,
    ) -> Flow {
        Flow::Go(Gradient::Exact)
    }

    /// Outer iteration number `k` (0 for the first) from `lam`, with
    /// w = A lam - b on entry: exact, or as the method's last step kept it
    /// where that returned [`Gradient::Updated`] or [`Gradient::Drifted`].
    /// Adds its inner iterations to `inner`.
    fn step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        w: &mut [f64],
        inner: &mut usize,
        k: usize,
    ) -> Flow;

    /// Told that the driver recomputed w = A lambda - b after a step that
    /// returned [`Gradient::Updated`] or [`Gradient::Drifted`] (before it
    /// accepts a convergence, or ends the solve after a drifted one): w is
    /// exact again. The default does nothing.
    fn refreshed(&mut self, _problem: &DualProblem<'_>, _lam: &[f64], _w: &[f64]) {}
}

/// The stagnation test. After outer iteration k >= `window`, let r be the ratio of
/// the lowest err of iterations 0..=k to the lowest err of iterations
/// 0..=k-window (the pace of the last window). The run has stalled when r is
/// above `factor` (the best err did not drop by the factor over the window) and,
/// at that pace, the target would not be reached within the iteration limit
/// (always so when r = 1: no progress at all). The second condition keeps a slow
/// but steady run that will meet the target in time (a warm start a few orders
/// of magnitude from the tolerance, say) from being cut short. `window` = 0 turns
/// the test off.
pub(super) struct Stagnation {
    window: usize,
    factor: f64,
    /// (iteration, best err from that iteration on) at each drop of the best err
    /// within the window, and the last one before it: memory grows with the
    /// drops met, never with the window the caller asks for.
    drops: std::collections::VecDeque<(usize, f64)>,
}

impl Stagnation {
    pub fn new(window: usize, factor: f64) -> Self {
        Stagnation {
            window,
            factor,
            drops: std::collections::VecDeque::new(),
        }
    }

    /// Records `best` (the lowest err so far) after iteration `k`; true when the
    /// run has stalled short of `target` with `limit` outer iterations allowed.
    pub fn stalled(&mut self, k: usize, best: f64, target: f64, limit: usize) -> bool {
        if self.window == 0 {
            return false;
        }
        if self.drops.back().is_none_or(|&(_, b)| best < b) {
            self.drops.push_back((k, best));
        }
        if k < self.window {
            return false;
        }
        // The best err after iteration k - window: the last drop at or before it.
        let then = k - self.window;
        while self.drops.len() >= 2 && self.drops[1].0 <= then {
            self.drops.pop_front();
        }
        let before = self.drops[0].1;
        if best == before {
            // No progress at all (also an err that stayed infinite).
            return true;
        }
        // best < before here (a running minimum): enough progress, or at the target.
        if best <= self.factor * before || best <= target || best.is_nan() {
            return false;
        }
        let pace = best / before;
        // Iterations still needed at this pace: window ln(target / best) / ln(pace).
        let needed = self.window as f64 * (target / best).ln() / pace.ln();
        k as f64 + needed > limit as f64
    }
}

/// The iterate with the lowest error seen so far: what a run returns when it ends
/// without converging (unless the monitor stopped it: then the last iterate).
pub(super) struct BestIterate {
    lam: Vec<f64>,
    err: f64,
}

impl BestIterate {
    pub fn new(c: usize) -> Self {
        BestIterate {
            lam: vec![0.0; c],
            err: f64::INFINITY,
        }
    }

    /// Keeps a copy of `lam` when `err` is the lowest so far.
    pub fn offer(&mut self, lam: &[f64], err: f64) {
        if err < self.err {
            self.err = err;
            self.lam.copy_from_slice(lam);
        }
    }

    /// Puts the best iterate into `lam` and its error into `out` when it is better
    /// than the current one.
    pub fn restore(&self, lam: &mut [f64], out: &mut Outcome) {
        if self.err < out.dual_err {
            lam.copy_from_slice(&self.lam);
            out.dual_err = self.err;
        }
    }
}

/// Runs `method` from `lam` until the dual error is at most `target`, or another
/// stop test fires (see [`End`]).
pub(super) fn drive(
    problem: &DualProblem<'_>,
    lam: &mut [f64],
    opts: &Options,
    target: f64,
    method: &mut dyn OuterStep,
) -> Outcome {
    let (m, c) = (problem.dual.m, problem.dual.c);
    fault::begins(problem.measured_after);
    let mut out = Outcome::default();
    let mut w = vec![0.0; c];
    let mut p = vec![0.0; m];
    let mut v = vec![0.0; c];
    let mut best = BestIterate::new(c);
    let mut stagnation = Stagnation::new(opts.stall_window, opts.stall_factor);
    // The lowest err met, drifted ones included: the stagnation test's
    // running minimum (the best iterate keeps exact errs only).
    let mut lowest = f64::INFINITY;
    match problem.start_gradient.take() {
        Some(w0) => w.copy_from_slice(w0),
        None => problem.gradient(lam, &mut w),
    }
    let mut gradient = match method.start(problem, lam, &mut w, &mut out.inner) {
        Flow::Go(g) => g,
        Flow::Infeasible => {
            out.dual_err = f64::INFINITY;
            out.end = End::Infeasible;
            return out;
        }
        Flow::Stalled => Gradient::Stale,
    };
    loop {
        if gradient == Gradient::Stale {
            problem.gradient(lam, &mut w);
        }
        let mut err = problem.error(lam, &w, &mut p, &mut v);
        // A gradient kept by updates is recomputed before its err is
        // accepted as converged (rank-one updates gather rounding); a
        // drifted one also before the solve ends otherwise, and its err
        // serves the monitor and the stagnation test but is not kept as
        // the best (Newton's single-precision products: up to about 1 % of
        // |F| off). Where the caller measures the error on the recovered u
        // anyway (`measured_after`), a drifted convergence is left to that
        // measurement: the recovery's solve costs what the recomputation
        // would (a drifted gradient's steps left the carried u behind:
        // `DualProblem::primal`).
        let mut scratch = Scratch {
            w: &mut w,
            p: &mut p,
            v: &mut v,
        };
        if err <= target && !(gradient == Gradient::Drifted && problem.measured_after) {
            scratch.exact(problem, lam, &mut gradient, &mut err, method);
        }
        out.dual_err = err;
        lowest = lowest.min(err);
        if gradient != Gradient::Drifted {
            best.offer(lam, err);
        }
        if out.outer > 0 && !problem.progress(out.outer, err, lam, scratch.p, scratch.v) {
            scratch.undrift(problem, lam, &mut gradient, &mut err, method);
            out.dual_err = err;
            out.end = End::Stopped;
            return out;
        }
        let end = if err <= target || fault::claims(gradient, problem.measured_after) {
            out.unconfirmed = gradient == Gradient::Drifted;
            return out;
        } else if out.outer >= opts.max_outer {
            Some(End::Limit)
        } else if stagnation.stalled(out.outer, lowest, target, opts.max_outer) {
            Some(End::Stalled)
        } else if problem.deadline.is_some_and(|d| Instant::now() >= d) {
            Some(End::TimeLimit)
        } else {
            None
        };
        if let Some(end) = end {
            scratch.undrift(problem, lam, &mut gradient, &mut err, method);
            out.dual_err = err;
            if err <= target {
                // The drift alone kept err above the target.
                return out;
            }
            best.offer(lam, err);
            out.end = end;
            best.restore(lam, &mut out);
            return out;
        }
        let flow = method.step(problem, lam, &mut w, &mut out.inner, out.outer);
        out.outer += 1;
        match flow {
            Flow::Go(g) => gradient = g,
            Flow::Infeasible => {
                out.end = End::Infeasible;
                return out;
            }
            Flow::Stalled => {
                problem.gradient(lam, &mut w);
                out.dual_err = problem.error(lam, &w, &mut p, &mut v);
                if out.dual_err <= target {
                    // The method's own progress test read a drifted |F|.
                    return out;
                }
                best.offer(lam, out.dual_err);
                out.end = End::Stalled;
                best.restore(lam, &mut out);
                return out;
            }
        }
    }
}

/// The driver's gradient w = A lam - b and the error's scratch (p: the
/// bounds, length m; v: -w, length c).
struct Scratch<'a> {
    w: &'a mut [f64],
    p: &'a mut [f64],
    v: &'a mut [f64],
}

impl Scratch<'_> {
    /// Where the gradient was kept by updates ([`Gradient::Updated`],
    /// [`Gradient::Drifted`]): w recomputed from lam, `err` with it, the
    /// method told ([`OuterStep::refreshed`]).
    fn exact(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &[f64],
        gradient: &mut Gradient,
        err: &mut f64,
        method: &mut dyn OuterStep,
    ) {
        if matches!(*gradient, Gradient::Updated | Gradient::Drifted) {
            problem.gradient(lam, self.w);
            *err = problem.error(lam, self.w, self.p, self.v);
            method.refreshed(problem, lam, self.w);
            *gradient = Gradient::Exact;
        }
    }

    /// As [`Scratch::exact`] where the gradient drifted
    /// ([`Gradient::Drifted`]) only.
    fn undrift(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &[f64],
        gradient: &mut Gradient,
        err: &mut f64,
        method: &mut dyn OuterStep,
    ) {
        if *gradient == Gradient::Drifted {
            self.exact(problem, lam, gradient, err, method);
        }
    }
}

impl DualProblem<'_> {
    /// Reports outer iteration `k` to the monitor; false when it asks to stop.
    fn progress(&self, k: usize, err: f64, lam: &[f64], p: &[f64], v: &[f64]) -> bool {
        let Some(cell) = &self.monitor else {
            return true;
        };
        let (n_open, n_stick, n_slip) = contact_states(lam, v, &self.dual.rho, p, self.dual.d);
        let progress = Progress {
            iteration: k,
            err,
            n_open,
            n_stick,
            n_slip,
            elapsed_seconds: 0.0,
        };
        (cell.borrow_mut())(&progress)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stagnation_fires_only_when_the_best_err_stops_dropping() {
        let (target, limit) = (1e-10, 10_000);
        // A steady pace of 0.99 per iteration drops by 0.99^10 = 0.904 over a
        // window of 10: enough with factor 0.95.
        let mut s = Stagnation::new(10, 0.95);
        assert!((0..200).all(|k| !s.stalled(k, 0.99f64.powi(k as i32), target, limit)));
        // With factor 0.9 that pace is too slow, yet it meets 1e-10 from 1 in about
        // 2,300 iterations, within the limit: not stalled.
        let mut s = Stagnation::new(10, 0.9);
        assert!((0..200).all(|k| !s.stalled(k, 0.99f64.powi(k as i32), target, limit)));
        // ... but with a limit of 1,000 it would not: stalled after the window.
        let mut s = Stagnation::new(10, 0.9);
        let fired: Vec<bool> = (0..=10)
            .map(|k| s.stalled(k, 0.99f64.powi(k as i32), target, 1_000))
            .collect();
        assert_eq!(fired.iter().position(|&f| f), Some(10));
        // A flat best err: stalled exactly after the window, whatever the limit.
        let mut s = Stagnation::new(5, 0.9);
        let fired: Vec<bool> = (0..8)
            .map(|k| s.stalled(k, 1.0, target, usize::MAX))
            .collect();
        assert_eq!(fired, [false, false, false, false, false, true, true, true]);
        // Off.
        let mut s = Stagnation::new(0, 0.9);
        assert!((0..100).all(|k| !s.stalled(k, 1.0, target, limit)));
    }

    #[test]
    fn the_best_iterate_comes_back_when_better() {
        let mut best = BestIterate::new(2);
        best.offer(&[1.0, 2.0], 0.1);
        best.offer(&[3.0, 4.0], 0.5);
        let mut lam = [5.0, 6.0];
        let mut out = Outcome {
            dual_err: 0.05,
            ..Outcome::default()
        };
        best.restore(&mut lam, &mut out);
        assert_eq!(lam, [5.0, 6.0]);
        out.dual_err = 0.3;
        best.restore(&mut lam, &mut out);
        assert_eq!(lam, [1.0, 2.0]);
        assert_eq!(out.dual_err, 0.1);
    }
}
