//! Solving an increment on the handle: the dual made ready in the form the
//! method needs, the right-hand side, the method's run, the rounds of Newton
//! on a nonlinear interface law, the recovery of u and its error check (with
//! the dual tolerance tightened where rounding in A needs it).

use super::*;
use crate::history::INCREMENT_RISE;
use crate::load_span::{Map, max_amplification};

/// Times the dual error is tightened when the error measured on the recovered u
/// misses the tolerance although the dual one met it (rounding in A).
const REFINEMENTS: usize = 3;

/// Rounds of Newton on a nonlinear normal compliance law (m_N != 1) before a
/// solve ends `NotConverged`: each round is one solve of the linear law of
/// the tangent (docs/design.md section 8).
const LAW_ROUNDS: usize = 30;

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// The load of an increment solve: f = f_total - K u_k, with u_k (None for
/// zero) and L^T P u_k as `History::lu` holds it (None: unknown).
struct Load<'a> {
    f: &'a [f64],
    f_total: &'a [f64],
    u_k: Option<&'a [f64]>,
    lu: Option<&'a [f64]>,
}

/// Where an increment solve starts.
pub(super) enum Warm<'a> {
    /// From the multipliers it is given.
    Given,
    /// A step of the history: from its prediction.
    History(&'a History),
    /// The first iteration of a host's increment, from lambda_n given: from
    /// the increments' prediction (`history::Increments`).
    Increment(&'a Increments),
    /// A later iteration of a host's increment, from the last iteration's
    /// answer given, with the answer of the iteration before it: from the
    /// best point of their line (`iteration_line`).
    Line(&'a [f64]),
}

/// What an increment solve gives: the solution, and for a step of the
/// history its contact-space load (for the first iteration of a host's
/// increment its load change q; the predictors') and the forward half its
/// u was back-substituted from (`History::lu`; None off the dense dual from
/// the trailing block).
pub(super) struct Solved {
    pub sol: Solution,
    pub load: Option<Vec<f64>>,
    pub forward: Option<Vec<f64>>,
    /// For a history step, A lambda at the answer, b - v of the recovered u
    /// (`History::advance`'s `alam`), where the solve converged with neither
    /// a compliance nor a nonlinear law (its b is then the dual's).
    pub alam: Option<Vec<f64>>,
}

impl ContactProblem {
    /// Puts the dual operator in the form `opts` asks for (see [`DualForm`]),
    /// rebuilding it from the factor when the form changes; the new form is kept
    /// for later solves. On error the problem is unchanged.
    ///
    /// Checks the solve's predicted memory against the limit first, and starts
    /// a new peak on the ledger; returns the prediction (bytes).
    ///
    /// Errors: `BadArgument` (`MatrixFree` with a method that reads entries of A),
    /// `OutOfMemory` (the solve's predicted need exceeds the memory limit, or A
    /// does not fit).
    pub(super) fn prepare_dual(&mut self, opts: &Options) -> Result<usize> {
        if opts.dual_form == DualForm::MatrixFree && opts.method.needs_entries() {
            return fail(
                ErrorKind::BadArgument,
                format!(
                    "method {} reads entries of the condensed dual A and cannot run \
                     matrix-free: use auto, newton or mprgp, or the dense or auto dual form",
                    opts.method.name()
                ),
            );
        }
        if self.stiff.host().is_some()
            && (opts.dual_form == DualForm::Dense || opts.method.needs_entries())
        {
            return fail(
                ErrorKind::BadArgument,
                format!(
                    "method {} with dual_form {}: a problem on the host's solver is \
                     matrix-free (use auto, newton or mprgp, dual_form auto or matrix-free)",
                    opts.method.name(),
                    opts.dual_form.name()
                ),
            );
        }
        let trailing = self
            .stiff
            .factor()
            .is_some_and(|f| Dual::trailing_available(f, &self.n, &self.t));
        let now = self.dual.condensation;
        let next = plan::solve_condensation(now, trailing, opts);
        let free = Condensation::MatrixFree;
        let (m, c) = (self.n_contacts(), self.dual.c);
        let workspace = opts.method.workspace(m, c, next == free);
        // The storage a refactor keeps for the next one gives way to a solve
        // that fits only without it.
        let limit = memory::limit(opts.max_memory);
        let need = self.spare_gives_way(|s| s.solve(now, next, workspace), limit);
        let hint = if next != free {
            let free_need = self
                .sizes
                .solve(now, free, Method::Newton.workspace(m, c, true));
            format!(
                "the matrix-free dual (dual_form auto or matrix-free, method auto, \
                 newton or mprgp) would need about {}",
                memory::human(free_need)
            )
        } else {
            "a larger max_memory or a machine with more memory is needed".to_string()
        };
        memory::check(
            need,
            memory::limit(opts.max_memory),
            opts.max_memory,
            &format!("a solve with method {}", opts.method.name()),
            &hint,
        )?;
        self.stiff.ledger().reset_peak();
        if let Some(host) = self.stiff.host() {
            host.clear();
        }
        if next != now {
            let shift = self.compliance.shift(self.d);
            let nt = (&self.n, &self.t);
            self.dual = self.new_dual(nt, next, &shift, None)?;
            self.kept_blocks = None;
        }
        Ok(need)
    }

    /// u := K^-1 (f - B^T lambda), `bt_lam` = B^T lambda. When the contact DOFs
    /// are the factor's trailing DOFs, given y_f = L^-1 P f (the forward half
    /// of the solve for K^-1 f): B^T lambda lives on them, so its forward half
    /// touches only the trailing block and the whole recovery costs about half
    /// a solve. The difference is taken between the forward halves, not
    /// between K^-1 f and K^-1 B^T lambda: those two nearly cancel where the
    /// contact carries the load, and on the slender beam of
    /// tests/hard_scenes.rs (cond(K) 1.6e9) their difference left an
    /// equilibrium residual of 3e-8 against 3e-12 here. For the same reason
    /// b's K^-1 f comes from the same substitution (`Factor::backward_to_last`
    /// repeats `Factor::backward`'s arithmetic exactly). Otherwise (a
    /// matrix-free dual on a plain factor, the dense dual by solves, the
    /// host's solves) one solve of f - B^T lambda, the difference taken
    /// before it. `forward` receives the forward half u was back-substituted
    /// from in the trailing case (L^-1 P (f - B^T lambda), for
    /// `History::lu`); it is left alone otherwise.
    ///
    /// Errors: `HostSolve` (the host's solve failed).
    pub(super) fn recover_u(
        &self,
        f: &[f64],
        y_f: &[f64],
        bt_lam: &[f64],
        u: &mut [f64],
        forward: &mut Vec<f64>,
    ) -> Result<()> {
        let factor = match &self.stiff {
            Stiffness::Own { factor, .. } => factor,
            Stiffness::Host { host, .. } => {
                for i in 0..u.len() {
                    u[i] = f[i] - bt_lam[i];
                }
                return host.solve(u, 1);
            }
        };
        if self.dual.condensation == Condensation::Solves {
            for i in 0..u.len() {
                u[i] = f[i] - bt_lam[i];
            }
            factor.solve_vec(u);
            return Ok(());
        }
        let mut y = vec![0.0; u.len()];
        if self.dual.trailing {
            let r_last: Vec<f64> = factor.last().iter().map(|&j| bt_lam[j]).collect();
            factor.forward_from_last(&r_last, &mut y);
            for (yi, fi) in y.iter_mut().zip(y_f) {
                *yi = fi - *yi;
            }
            forward.clone_from(&y);
        } else {
            let r: Vec<f64> = f.iter().zip(bt_lam).map(|(a, b)| a - b).collect();
            factor.forward(&r, &mut y);
        }
        factor.backward(&mut y, u);
        Ok(())
    }

    /// u0 = K^-1 f where B reads it, for the increment `load` of a solve to
    /// the tolerance `tol`, and where the contact DOFs are the factor's
    /// trailing DOFs y_f = L^-1 P f (the forward half, kept for
    /// [`Self::recover_u`]; else empty).
    ///
    /// Where f_total lies in the span of the last loads solved for
    /// (`load_span`), from their solutions without a solve, where that
    /// amplifies rounding at most `load_span::max_amplification(tol)` times;
    /// else by a solve, whose solution of f_total is kept.
    /// - Trailing DOFs: y_f is the combination of the kept L^-1 P f_total
    ///   minus L^T P u_k (the forward half of K u_k; where it is known), else
    ///   the forward substitution of f; u0 at the trailing DOFs alone (their
    ///   back substitution needs the trailing block of L only).
    /// - Else u0 everywhere: the combination of the kept K^-1 f_total minus
    ///   u_k, else one solve (of the factor or the host's).
    ///
    /// `ride` (each of length c): multipliers x whose products A x are wanted
    /// at the start; returned where they rode along the solve of f in one
    /// block (`Dual::solve_with_products`: a matrix-free dual on K's own
    /// factor, the load not combined, the block allowed by the allocator),
    /// else None (the caller takes them itself). Where they ride and
    /// `primal` is given, u at `ride[0]` goes into it, with z = K^-1 B^T
    /// `ride[1]` (`Dual::solve_with_products`).
    ///
    /// Errors: `HostSolve`.
    fn solve_load(
        &mut self,
        Load {
            f,
            f_total,
            u_k,
            lu,
        }: Load<'_>,
        tol: f64,
        y_f: &mut Vec<f64>,
        u0: &mut [f64],
        (ride, primal): (&[&[f64]], Option<&mut Primal>),
    ) -> Result<Option<Vec<Vec<f64>>>> {
        let amp = max_amplification(tol);
        if !self.dual.trailing {
            y_f.clear();
            if self.loads.combine(Map::Solve, f_total, u_k, u0, amp) {
                return Ok(None);
            }
        }
        let mut rode = None;
        match &self.stiff {
            Stiffness::Own { factor, .. } if self.dual.trailing => {
                // L^-1 P (f_total - K u_k) = L^-1 P f_total - L^T P u_k.
                let lu = lu.map(|s| (!s.is_empty()).then_some(s));
                let combined =
                    lu.is_some_and(|s| self.loads.combine(Map::Forward, f_total, s, y_f, amp));
                if !combined {
                    factor.forward(f, y_f);
                    if let Some(s) = lu {
                        let mut y_total = y_f.clone();
                        if let Some(s) = s {
                            y_total.iter_mut().zip(s).for_each(|(a, b)| *a += b);
                        }
                        let ledger = factor.ledger().clone();
                        self.loads.keep(Map::Forward, f_total, y_total, &ledger);
                    }
                }
                let last = factor.last();
                let mut u_last = vec![0.0; last.len()];
                factor.backward_to_last(y_f, &mut u_last);
                for (&j, &v) in last.iter().zip(&u_last) {
                    u0[j] = v;
                }
                return Ok(None);
            }
            Stiffness::Own { factor, .. } => {
                u0.copy_from_slice(f);
                let mut ys = vec![vec![0.0; self.dual.c]; ride.len()];
                // A block the allocator refuses is no error: the products
                // are then taken one by one, as without a ride.
                let rides = !ride.is_empty()
                    && self
                        .dual
                        .solve_with_products(factor, u0, ride, &mut ys, primal)
                        .unwrap_or(false);
                if rides {
                    rode = Some(ys);
                } else {
                    factor.solve_vec(u0);
                }
            }
            Stiffness::Host { host, .. } => {
                u0.copy_from_slice(f);
                host.solve(u0, 1)?;
            }
        }
        let mut x = u0.to_vec();
        if let Some(u_k) = u_k {
            x.iter_mut().zip(u_k).for_each(|(a, b)| *a += b);
        }
        let ledger = self.stiff.ledger().clone();
        self.loads.keep(Map::Solve, f_total, x, &ledger);
        Ok(rode)
    }

    /// The increment solve of the load `f` (in a history f = f_total - K u_k,
    /// else f_total = f), starting from the multipliers in `lam`, or, for a
    /// step of the history or the first iteration of a host's increment
    /// (`warm`), from the prediction (then the step's contact-space load or
    /// the increment's load change is returned too, for the predictor), the elastic
    /// slip's return mapping from `lt_prev` (empty: zero); `predicted` is the
    /// solve's memory prediction (from `prepare_dual`), for the report.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn solve_from(
        &mut self,
        (f, f_total): (&[f64], &[f64]),
        g: &[f64],
        friction: Friction<'_>,
        opts: &Options,
        lam: &mut [f64],
        (warm, lt_prev): (Warm<'_>, &[f64]),
        mut monitor: Option<Monitor<'_>>,
        predicted: usize,
    ) -> Result<Solved> {
        let start = Instant::now();
        let (ndof, m, c) = (self.n_dofs(), self.n_contacts(), self.dual.c);
        // y_f, K^-1 f, u, B^T lambda, K u and the residual below.
        let _vectors = self.stiff.ledger().claim_f64(6 * ndof);
        let host = self.stiff.host().cloned();
        let counts = host.as_ref().map(|h| h.counts()).unwrap_or_default();
        // (f, g, the friction data and opts were checked by the caller.)
        // b = B K^-1 f - [g; 0] ([g; -s] for a host iteration), with the
        // forward half y_f = L^-1 P f kept for the
        // recovery of u.
        let mut y_f = vec![0.0; ndof];
        let mut u0 = vec![0.0; ndof];
        let history = match warm {
            Warm::History(h) => Some(h),
            _ => None,
        };
        let u_k = history.map(|h| &h.u[..]);
        let lu = match history {
            Some(h) => h.lu.as_deref(),
            None => Some(&[][..]),
        };
        let load = Load {
            f,
            f_total,
            u_k,
            lu,
        };
        // The products at a given start (A lambda; a host iteration's A d
        // along its line too) ride along the right-hand side's solve where
        // the dual is matrix-free on K's own factor
        // (`Dual::solve_with_products`): one block solve instead of two or
        // three solves.
        let plain = self.dual.shift().is_empty() && self.dual.is_matrix_free();
        let dir: Option<Vec<f64>> = match warm {
            Warm::Line(before) if before.len() == c => {
                Some(lam.iter().zip(before).map(|(l, p)| l - p).collect())
            }
            _ => None,
        };
        let mut ride: Vec<&[f64]> = Vec::new();
        let given = matches!(warm, Warm::Given | Warm::Line(_) | Warm::Increment(_));
        if plain && given && lam.iter().any(|&x| x != 0.0) {
            ride.push(lam);
            ride.extend(dir.as_deref());
        }
        // u = K^-1 (f - B^T lambda) carried with the iterate from the start
        // where the block gives it and the products can move it
        // (`dual::Primal`; with its bytes on the ledger).
        let carry = !ride.is_empty() && !self.dual.trailing && self.dual.keeps_solutions();
        let mut primal = if carry { Primal::new(ndof, c) } else { None };
        let _primal_claim = primal
            .as_ref()
            .map(|_| self.stiff.ledger().claim(Primal::bytes(ndof, c)));
        let rode = self.solve_load(load, opts.tol, &mut y_f, &mut u0, (&ride, primal.as_mut()))?;
        drop(ride);
        let mut b = vec![0.0; c];
        self.dual.rows.mul_vec(&u0, &mut b);
        // g: the gaps of the normal rows (m), or of every row (c: a host
        // iteration's slip offset on the tangential ones, `iteration.rs`).
        for (bi, gi) in b.iter_mut().zip(g) {
            *bi -= gi;
        }
        let mut extrapolated = false;
        // w = A lambda - b at the start, where a host increment's prediction
        // computed it or a history step's combines it from the A lambda the
        // last steps kept (the driver then takes no product for it).
        let mut start_w: Option<Vec<f64>> = None;
        // |F| where a host iteration's line moved the start (the driver's
        // forcing terms start from it).
        let mut line_from: Option<f64> = None;
        let load = match warm {
            Warm::Given => {
                if let Some(al) = rode.as_ref().and_then(|p| p.first()) {
                    start_w = Some(al.iter().zip(&b).map(|(a, bj)| a - bj).collect());
                }
                None
            }
            Warm::History(h) => {
                let mut bu = vec![0.0; c];
                self.dual.rows.mul_vec(&h.u, &mut bu);
                let load = History::load_of(&b, &bu, m);
                let s = h.start(&load, friction, self.d, lam);
                extrapolated = s > 0.0;
                // The gradient at the start from the last steps' A lambda
                // (no compliance: b is the solve's): A x on the line, plus
                // one product of what the projection moved, if anything
                // beyond rounding (a saturated slip force rescaled by an
                // ulp moves w less than a product's own rounding).
                if self.dual.shift().is_empty()
                    && let Some(mut ax) = h.start_product(s)
                {
                    add_projection_move(&self.dual, lam, h.line_point(s), &mut ax, None);
                    ax.iter_mut().zip(&b).for_each(|(a, bj)| *a -= bj);
                    start_w = Some(ax);
                }
                Some(load)
            }
            Warm::Line(_) if !self.dual.shift().is_empty() => None,
            Warm::Line(before) => {
                let at = DualProblem::new(&self.dual, &b, friction);
                let (w, from) = iteration_line(&at, before, self.d, lam, rode, primal.as_mut());
                extrapolated = from.is_some();
                line_from = from;
                start_w = Some(w);
                None
            }
            // Not with an interface compliance: A + D would mix D lambda_n
            // into q, and the solve's b is shifted below.
            Warm::Increment(_) if !self.dual.shift().is_empty() => None,
            Warm::Increment(incs) => {
                let at = DualProblem::new(&self.dual, &b, friction);
                // w = A lambda_n - b and q = b + [g; 0] - A lambda_n = [g; 0]
                // - w (`history::Increments`).
                let mut w = vec![0.0; c];
                match rode.as_ref().and_then(|p| p.first()) {
                    Some(al) => w
                        .iter_mut()
                        .zip(al)
                        .zip(&b)
                        .for_each(|((x, a), bj)| *x = a - bj),
                    None => at.gradient(lam, &mut w),
                }
                let q: Vec<f64> = g.iter().zip(&w).map(|(gj, wj)| gj - wj).collect();
                let mut start = lam.to_vec();
                if incs.start(&q, friction, self.d, &mut start) > 0.0 {
                    // The prediction is kept unless its natural residual
                    // exceeds lambda_n's more than INCREMENT_RISE times (one
                    // product; `history::Increments`): the product of the
                    // move where it carries u along (`dual::Primal`), else
                    // of the start.
                    let before = at.natural_residual(lam, &w);
                    let mut ws = vec![0.0; c];
                    let mut carried = primal.as_mut().filter(|p| p.holds_at(lam));
                    let moved = carried.as_mut().is_some_and(|p| {
                        let d: Vec<f64> =
                            start.iter().zip(lam.iter()).map(|(s, l)| s - l).collect();
                        let kept = self.dual.apply_keeping(&d, &mut ws, &mut p.z);
                        if kept {
                            ws.iter_mut().zip(&w).for_each(|(a, wj)| *a += wj);
                        }
                        kept
                    });
                    if !moved {
                        at.gradient(&start, &mut ws);
                    }
                    if at.natural_residual(&start, &ws) <= INCREMENT_RISE * before {
                        lam.copy_from_slice(&start);
                        extrapolated = true;
                        w = ws;
                        if let Some(p) = carried {
                            match moved {
                                true => p.moved_by(1.0, lam),
                                false => p.drop_u(),
                            }
                        }
                    }
                }
                // The gradient at the start, whichever it is, for the
                // driver (this branch runs without a compliance: its b is
                // the solve's).
                start_w = Some(w);
                Some(q)
            }
        };
        // From here the methods carry it (`DualProblem::primal`).
        let primal = primal.map(std::cell::RefCell::new);
        // The compliance's tangential term is centred at the force the return
        // mapping starts from: b += D_T lambda_T,prev (a history's last force;
        // zero in a single solve).
        let shift = self.dual.shift();
        if !shift.is_empty() {
            for ((bj, dj), lj) in b[m..].iter_mut().zip(&shift[m..]).zip(lt_prev) {
                *bj += dj * lj;
            }
        }
        // A nonlinear normal law (m_N != 1) is solved by Newton on the law
        // (docs/design.md section 8): each round solves the linear law of its
        // tangent at the last penetrations delta, from the last multipliers,
        // until the error of the nonlinear law meets the tolerance. The first
        // tangent is taken where the start's forces put the contacts.
        let nonlinear = self.compliance.nonlinear();
        let (mut delta, mut d_max) = (vec![0.0; m], vec![0.0; m]);
        for &i in &nonlinear {
            delta[i] = self.compliance.penetration(i, lam[i]);
            // An open tangent carries nothing: 1e4 times A_ii's compliance.
            d_max[i] = 1e4 * (self.dual.diag(i) - self.dual.shift()[i]);
        }
        let cold = nonlinear.iter().all(|&i| lam[i] == 0.0);
        let mut offset = vec![0.0; m];
        let mut b_round = b.clone();
        let mut rounds = 0;
        // A round's tolerance: the solve's, or for Newton on a nonlinear law
        // a hundredth of the law's last error (inexact Newton), not below it.
        let mut round_tol = if nonlinear.is_empty() {
            opts.tol
        } else {
            opts.tol.max(1e-6)
        };
        // The monitor sees iteration numbers and times of the whole solve.
        let base = std::cell::Cell::new(0usize);
        let mut relay = |p: &Progress| -> bool {
            // A failed host solve ends the run (the call returns its error).
            if host.as_ref().is_some_and(|h| h.failure().is_some()) {
                return false;
            }
            match monitor.as_mut() {
                Some(user) => user(&Progress {
                    iteration: base.get() + p.iteration,
                    elapsed_seconds: start.elapsed().as_secs_f64(),
                    ..*p
                }),
                None => true,
            }
        };
        let deadline =
            (opts.max_seconds > 0.0).then(|| start + Duration::from_secs_f64(opts.max_seconds));
        let mut target = round_tol;
        let rhs_seconds = start.elapsed().as_secs_f64();
        let (mut iterate_seconds, mut recover_seconds) = (0.0, 0.0);
        let mut end;
        let mut outer = 0;
        let mut inner = 0;
        let mut unknowns;
        let mut method = opts.method;
        let mut choice;
        let mut u = vec![0.0; ndof];
        let mut bt_lam = vec![0.0; ndof];
        // The forward half of the last recovery (dense dual from the
        // trailing block; empty otherwise).
        let mut forward = Vec::new();
        let mut v = vec![0.0; c];
        let mut p = vec![0.0; m];
        let mut err;
        // rho of the nonlinear law's error (empty: the dual's own).
        let mut law_rho = Vec::new();
        // The prediction's gradient serves the first run (one round: its b
        // is the solve's where no law is nonlinear).
        let mut first_w = start_w.filter(|_| nonlinear.is_empty());
        loop {
            if !nonlinear.is_empty() {
                // A cold start's first round is rigid at the nonlinear
                // contacts (D = 0); its forces give the first tangent.
                let rigid = vec![0.0; m];
                let cap = if rounds == 0 && cold { &rigid } else { &d_max };
                offset = self.take_tangent(&nonlinear, (&delta, cap), &b, &mut b_round);
                target = round_tol;
            }
            // Where a run ended converged on a drifted gradient
            // (`Outcome::unconfirmed`) and the error on the recovered u
            // missed the tolerance, the run goes on from there with every
            // convergence confirmed on an exact gradient (not a refinement:
            // the target stays).
            let mut confirm = false;
            let mut refinements = 0;
            loop {
                let first = first_w.take();
                let problem = DualProblem {
                    dual: &self.dual,
                    b: &b_round,
                    law: friction,
                    monitor: Some(std::cell::RefCell::new(&mut relay)),
                    deadline,
                    predicted: extrapolated && rounds == 0,
                    near: rounds > 0,
                    start_gradient: std::cell::Cell::new(first.as_deref()),
                    measured_after: !confirm,
                    start_from: line_from.filter(|_| first.is_some()),
                    primal: primal.as_ref(),
                };
                let local = Options {
                    max_outer: opts.max_outer.saturating_sub(outer),
                    ..*opts
                };
                let t0 = Instant::now();
                let o = methods::run(&problem, lam, &local, target);
                if let Some(e) = host.as_ref().and_then(|h| h.failure()) {
                    return Err(e);
                }
                let t1 = Instant::now();
                iterate_seconds += (t1 - t0).as_secs_f64();
                outer += o.outer;
                inner += o.inner;
                unknowns = o.unknowns;
                method = o.method.unwrap_or(method);
                choice = o.choice;
                base.set(outer);
                end = o.end;
                // u = K^-1 (f - B^T lambda), and the error measured on it.
                let recovered = Recovered {
                    u: &mut u,
                    bt_lam: &mut bt_lam,
                    v: &mut v,
                    p: &mut p,
                    forward: &mut forward,
                };
                let at = Increment {
                    f,
                    y_f: &y_f,
                    g,
                    lt_prev,
                };
                let carried = primal.as_ref().map(|p| p.borrow());
                // Its rounding is weighed against the solve's tolerance, not
                // a nonlinear law's looser round's.
                #[cfg(test)]
                if carried
                    .as_ref()
                    .and_then(|p| p.u_at(lam, opts.tol))
                    .is_some()
                {
                    CARRIED.with(|n| n.set(n.get() + 1));
                }
                err = self.recover_and_measure(
                    lam,
                    at,
                    (&nonlinear, &offset),
                    friction,
                    &b_round,
                    recovered,
                    carried.as_ref().and_then(|p| p.u_at(lam, opts.tol)),
                )?;
                drop(carried);
                recover_seconds += t1.elapsed().as_secs_f64();
                if end == End::Infeasible {
                    // No u satisfies N u <= g: no error can be small (report.rs).
                    err = f64::INFINITY;
                    break;
                }
                // Tighten the dual target only when the dual run met it on an
                // exact gradient but the error on the recovered u missed the
                // tolerance (rounding in A), REFINEMENTS times at most (the
                // end then stays as the last run left it).
                if end != End::Converged || err <= round_tol || outer >= opts.max_outer {
                    if end == End::Converged && err > round_tol {
                        end = End::Limit;
                    }
                    break;
                }
                if problem.deadline.is_some_and(|d| Instant::now() >= d) {
                    end = End::TimeLimit;
                    break;
                }
                if o.unconfirmed {
                    confirm = true;
                    continue;
                }
                target *= 0.1;
                refinements += 1;
                if refinements > REFINEMENTS {
                    break;
                }
            }
            if nonlinear.is_empty() || end == End::Infeasible {
                // (An infeasible round's v is its tangent's: the dual's rho.)
                law_rho.clear();
                break;
            }
            // The error of the nonlinear law, whatever way the round ended (a
            // round's own err is its tangent's), and the penetrations the next
            // tangent is taken at.
            let raw = self.law_gaps(&nonlinear, lam, &offset, &mut v);
            for (&i, &x) in nonlinear.iter().zip(&raw) {
                delta[i] = if rounds == 0 && cold {
                    self.compliance.penetration(i, lam[i])
                } else {
                    x
                };
            }
            law_rho = self.dual.rho_rigid_at(&nonlinear);
            err = self.dual.error(lam, &v, &law_rho, &b, &p);
            if end != End::Converged {
                break;
            }
            rounds += 1;
            if err <= opts.tol {
                break;
            }
            round_tol = (0.01 * err).max(opts.tol);
            if rounds >= LAW_ROUNDS || outer >= opts.max_outer {
                end = End::Limit;
                break;
            }
            if deadline.is_some_and(|d| Instant::now() >= d) {
                end = End::TimeLimit;
                break;
            }
        }
        let equilibrium_residual = match self.stiff.k() {
            Some(k) => equilibrium_residual(k, &u, f, &bt_lam),
            None => f64::NAN,
        };
        if err.is_nan() {
            // Non-finite arithmetic (an input at the edge of the doubles):
            // nothing was measured, and NaN compares as neither side of tol.
            err = f64::INFINITY;
        }
        let rho = if law_rho.is_empty() {
            &self.dual.rho
        } else {
            &law_rho
        };
        let (n_open, n_stick, n_slip) = contact_states(lam, &v, rho, &p, self.d);
        let status = match end {
            End::Stopped => SolveStatus::Stopped,
            _ if err <= opts.tol => SolveStatus::Converged,
            End::Stalled => SolveStatus::Stalled,
            End::TimeLimit => SolveStatus::TimeLimit,
            End::Converged | End::Limit | End::Infeasible => SolveStatus::NotConverged,
        };
        let (factor_nnz, factor_flops, factor_seconds, ordering, analyse_seconds) =
            match self.stiff.factor() {
                Some(factor) => {
                    let (nnz, flops) = factor.nnz_and_flops();
                    let (fs, order, an) = (
                        factor.factor_seconds,
                        factor.ordering(),
                        factor.analyse_seconds,
                    );
                    (nnz, flops, fs, order, an)
                }
                None => (0, 0.0, 0.0, crate::options::Ordering::Auto, 0.0),
            };
        let host_counts = host.as_ref().map(|h| h.counts()).unwrap_or_default();
        let sol = Solution {
            u,
            lambda_n: lam[..m].to_vec(),
            lambda_t: lam[m..].to_vec(),
            report: Report {
                status,
                method,
                choice: choice.to_string(),
                err,
                equilibrium_residual,
                outer_iterations: outer,
                inner_iterations: inner,
                dual_unknowns: unknowns,
                n_open,
                n_stick,
                n_slip,
                factor_seconds,
                condense_seconds: self.dual.condense_seconds,
                solve_seconds: start.elapsed().as_secs_f64(),
                ordering,
                factor_nnz,
                factor_flops,
                threads: self.threads(),
                analyse_seconds,
                memory_predicted: predicted,
                memory_peak: self.stiff.ledger().peak(),
                compliant_contacts: self.compliant_contacts(),
                rhs_seconds,
                iterate_seconds,
                recover_seconds,
                host_solves: host_counts.columns - counts.columns,
                host_seconds: host_counts.seconds - counts.seconds,
            },
        };
        // A lambda = b - v (v = -w on the recovered u), where b is the dual's,
        // for a history step that converged (however its last run ended).
        let alam = (history.is_some()
            && sol.report.status == SolveStatus::Converged
            && nonlinear.is_empty()
            && self.dual.shift().is_empty())
        .then(|| b.iter().zip(&v).map(|(bj, vj)| bj - vj).collect());
        Ok(Solved {
            sol,
            load,
            forward: (!forward.is_empty()).then_some(forward),
            alam,
        })
    }
}

#[cfg(test)]
thread_local! {
    /// Recoveries that took the u carried with the iterate (`dual::Primal`)
    /// on this thread, for the tests.
    pub(super) static CARRIED: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// What an increment's error is measured against: the load f, its forward
/// half y_f (see [`ContactProblem::recover_u`]), the gaps g and the force the
/// elastic slip's return mapping starts from (empty: zero).
struct Increment<'a> {
    f: &'a [f64],
    y_f: &'a [f64],
    g: &'a [f64],
    lt_prev: &'a [f64],
}

/// What the recovery of an iterate writes: u (n), B^T lambda (n), v = [N u -
/// g; T u] less the compliance's part (c), the friction bounds p (m) and the
/// forward half u came from (see [`ContactProblem::recover_u`]).
struct Recovered<'a> {
    u: &'a mut [f64],
    bt_lam: &'a mut [f64],
    v: &'a mut [f64],
    p: &'a mut [f64],
    forward: &'a mut Vec<f64>,
}

impl ContactProblem {
    /// The error measure of the iterate `lam` (docs/design.md section 5):
    /// u = K^-1 (f - B^T lambda) recovered, v = [N u - g; T u] (less a host
    /// iteration's tangential gaps -s: T u + s) - D (lambda -
    /// [0; lt_prev]) less the round's gap offset `s` at the nonlinear
    /// contacts (`law` = (those contacts, s)), the bounds p of `friction`, and
    /// the natural map's err against `b` (the round's right-hand side) with
    /// the dual's rho. `carried`: u at `lam` where the solve carried it
    /// there (`dual::Primal`), taken instead of a solve.
    ///
    /// Errors: `HostSolve` (the recovery's solve on the host failed).
    #[allow(clippy::too_many_arguments)]
    fn recover_and_measure(
        &self,
        lam: &[f64],
        at: Increment<'_>,
        (nonlinear, offset): (&[usize], &[f64]),
        friction: Friction<'_>,
        b: &[f64],
        out: Recovered<'_>,
        carried: Option<&[f64]>,
    ) -> Result<f64> {
        let m = self.n_contacts();
        self.dual.rows.mul_t_vec(lam, out.bt_lam);
        match carried {
            Some(u) => out.u.copy_from_slice(u),
            None => self.recover_u(at.f, at.y_f, out.bt_lam, out.u, out.forward)?,
        }
        let v = out.v;
        self.dual.rows.mul_vec(out.u, v);
        for (vi, gi) in v.iter_mut().zip(at.g) {
            *vi -= gi;
        }
        // The compliance's part of the gap: v := v - D (lambda - [0; lt_prev]).
        let shift = self.dual.shift();
        if !shift.is_empty() {
            for ((vj, dj), lj) in v.iter_mut().zip(shift).zip(lam.iter()) {
                *vj -= dj * lj;
            }
            for ((vj, dj), lj) in v[m..].iter_mut().zip(&shift[m..]).zip(at.lt_prev) {
                *vj += dj * lj;
            }
        }
        for &i in nonlinear {
            v[i] -= offset[i];
        }
        friction.bounds(&lam[..m], out.p);
        Ok(self.dual.error(lam, v, &self.dual.rho, b, out.p))
    }

    /// Puts the tangent of the nonlinear normal laws (`nonlinear`) at the
    /// penetrations `delta`, D capped at `cap`, on the dual
    /// (`Compliance::linearised`), and `b_round` := `b` less its gap offset s
    /// at those contacts; returns s (m).
    fn take_tangent(
        &mut self,
        nonlinear: &[usize],
        (delta, cap): (&[f64], &[f64]),
        b: &[f64],
        b_round: &mut [f64],
    ) -> Vec<f64> {
        let (shift, s) = self.compliance.linearised(self.d, delta, cap);
        self.dual.set_shift(&shift);
        b_round.copy_from_slice(b);
        for &i in nonlinear {
            b_round[i] -= s[i];
        }
        s
    }

    /// Turns `v` (the last round's v = [N u - g; T u] - D lambda - s, its
    /// tangent law's) into the nonlinear law's at the contacts `nonlinear`:
    /// v_N,i = N u - g - (lambda_N,i / c_N,i)^(1 / m_N,i). Returns their
    /// penetrations N u - g (in the order of `nonlinear`), where the next
    /// tangent is taken. `offset` is the round's s.
    fn law_gaps(
        &self,
        nonlinear: &[usize],
        lam: &[f64],
        offset: &[f64],
        v: &mut [f64],
    ) -> Vec<f64> {
        let shift = self.dual.shift();
        nonlinear
            .iter()
            .map(|&i| {
                let raw = v[i] + offset[i] + shift[i] * lam[i];
                v[i] = raw - self.compliance.penetration(i, lam[i]);
                raw
            })
            .collect()
    }
}

/// The equilibrium residual |K u - f + B^T lambda| / |f| (`bt_lam` = B^T
/// lambda; the denominator |K u| or |B^T lambda| where f vanishes).
fn equilibrium_residual(k: &Csc, u: &[f64], f: &[f64], bt_lam: &[f64]) -> f64 {
    let ndof = u.len();
    let mut ku = vec![0.0; ndof];
    k.mul_vec(u, &mut ku);
    let res: Vec<f64> = (0..ndof).map(|i| ku[i] - f[i] + bt_lam[i]).collect();
    let denom = {
        let nf = norm(f);
        if nf > 0.0 {
            nf
        } else {
            norm(&ku).max(norm(bt_lam))
        }
    };
    let rn = norm(&res);
    if rn == 0.0 { 0.0 } else { rn / denom }
}

/// The start of a host iteration on the line through the last iteration's
/// answer `lam` and the answer of the one before, `before` (docs/design.md
/// section 9): a converging host loop moves its multipliers along nearly
/// one direction from iteration to iteration (on host_newton's material
/// updates of 3d-32x32x4 the last two changes were collinear to 4e-5 and
/// 8e-3 of their size, measured in a build not kept). With d = lam - before, w = A lam - b and a = A d (two products),
/// s minimises the natural map's linear part along d, sum rho_i^2 (w_i +
/// s a_i)^2 over the components the start holds free (closed normals,
/// sticking tangential pairs); the point P(lam + s d) is taken where its
/// natural residual is below lam's (one more product where the projection
/// moved it). `lam` and `before` (c values each, force units): the start,
/// overwritten with the point taken; `products`: A lam and A d (c values
/// each) where the caller has them, else computed here. `primal`: u at
/// lam with z = K^-1 B^T d (from the block the products rode in), moved to
/// the point taken where the projection's product computes its own z
/// (`Dual::apply_keeping`), else left behind. Returns w = A x - b at the
/// start x (c values, length units), and |F| at the given lam where the
/// start moved.
pub(super) fn iteration_line(
    at: &DualProblem<'_>,
    before: &[f64],
    dim: usize,
    lam: &mut [f64],
    products: Option<Vec<Vec<f64>>>,
    primal: Option<&mut Primal>,
) -> (Vec<f64>, Option<f64>) {
    let dual = at.dual;
    let (m, c) = (dual.m, dual.c);
    let dir: Vec<f64> = lam.iter().zip(before).map(|(l, p)| l - p).collect();
    // z of d is known where A d rode along with u.
    let rode_both = products.as_ref().is_some_and(|p| p.len() == 2);
    let mut primal = primal.filter(|p| rode_both && p.holds_at(lam));
    // A lam and A d where they rode along the right-hand side's solve.
    let mut given = products.unwrap_or_default().into_iter();
    let mut w = given.next().unwrap_or_else(|| {
        let mut w = vec![0.0; c];
        dual.apply(lam, &mut w);
        w
    });
    let a = given.next();
    w.iter_mut().zip(at.b).for_each(|(wi, bi)| *wi -= bi);
    if before.len() != c || dir.iter().all(|&x| x == 0.0) {
        return (w, None);
    }
    let a = a.unwrap_or_else(|| {
        let mut a = vec![0.0; c];
        dual.apply(&dir, &mut a);
        a
    });
    let rho = &dual.rho;
    let (mut num, mut den) = (0.0, 0.0);
    let mut add = |j: usize, r: f64| {
        num += r * r * w[j] * a[j];
        den += r * r * a[j] * a[j];
    };
    for i in 0..m {
        // Sorted as Newton sorts (`newton::step`): closed where the trial
        // normal force is positive, sticking where the trial tangential
        // force lies inside the disk (a slipping contact's w_T is its slip,
        // not an error).
        if lam[i] - rho[i] * w[i] <= 0.0 {
            continue;
        }
        add(i, rho[i]);
        let jt = m + (dim - 1) * i;
        let bound = at.law.bound(i, lam[i]);
        let t2: f64 = (jt..jt + dim - 1)
            .map(|j| (lam[j] - rho[i] * w[j]).powi(2))
            .sum();
        if t2.sqrt() < bound {
            for j in jt..jt + dim - 1 {
                add(j, rho[i]);
            }
        }
    }
    let s = -num / den;
    if !(den > 0.0 && s.is_finite() && s != 0.0) {
        return (w, None);
    }
    let s = s.clamp(-LINE_S_MAX, LINE_S_MAX);
    let mut x: Vec<f64> = lam.iter().zip(&dir).map(|(l, d)| l + s * d).collect();
    let line = x.clone();
    crate::history::project_point(&mut x, at.law, dim);
    let mut wx: Vec<f64> = w.iter().zip(&a).map(|(wi, ai)| wi + s * ai).collect();
    let carried = match primal.as_mut() {
        Some(p) => {
            p.trial_along(s);
            add_projection_move(dual, &x, line, &mut wx, Some(&mut p.z))
        }
        None => add_projection_move(dual, &x, line, &mut wx, None),
    };
    let res = at.natural_residual(lam, &w);
    if at.natural_residual(&x, &wx) < res {
        lam.copy_from_slice(&x);
        if let Some(p) = primal {
            match carried {
                true => p.take_trial(lam),
                false => p.drop_u(),
            }
        }
        return (wx, Some(res));
    }
    (w, None)
}

/// ax += A (projected - line): what a projection moved a start off its
/// line, in one product, where it moved anything beyond rounding (a
/// saturated slip force rescaled by an ulp moves A x less than a product's
/// own rounding); `line` gives the point before the projection. `keep`
/// (n values, zero on entry) receives K^-1 B^T (projected - line) where
/// given; returns false where it was given and that product could not
/// compute it (`Dual::apply_keeping`).
fn add_projection_move(
    dual: &Dual,
    projected: &[f64],
    line: impl IntoIterator<Item = f64>,
    ax: &mut [f64],
    keep: Option<&mut [f64]>,
) -> bool {
    let delta: Vec<f64> = projected
        .iter()
        .zip(line)
        .map(|(&l, x)| {
            let d = l - x;
            if d.abs() <= 8.0 * f64::EPSILON * l.abs().max(x.abs()) {
                0.0
            } else {
                d
            }
        })
        .collect();
    if !delta.iter().any(|&d| d != 0.0) {
        return true;
    }
    let mut ad = vec![0.0; ax.len()];
    let kept = match keep {
        Some(z) => dual.apply_keeping(&delta, &mut ad, z),
        None => false,
    };
    if !kept {
        dual.apply(&delta, &mut ad);
    }
    ax.iter_mut().zip(&ad).for_each(|(a, d)| *a += d);
    kept
}

/// The largest |s| of a host iteration's line (`iteration_line`).
const LINE_S_MAX: f64 = 4.0;
