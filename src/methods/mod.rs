//! The iterative methods on the condensed dual
//!
//! ```text
//! min 1/2 lambda^T A lambda - lambda^T b,  lambda_N >= 0,  |lambda_T,i| <= p_i,
//! ```
//!
//! all behind one entry point, [`run`], so that every method runs on the same data.
//! Projections onto the friction sets and the small local problems live in
//! `projection`; the projected Gauss-Seidel sweeps in `pgs`; Pop's splitting and
//! the block Gauss-Seidel variant in `split`.

mod mprgp;
mod newton;
mod pgs;
mod projection;
mod split;

pub use projection::{project_disk, solve_disk_qp};

use crate::dual::Dual;
use crate::options::{Method, Options};
use crate::report::{contact_states, natural_map_error};
use std::cell::RefCell;

/// The friction bound of one solve, per contact.
#[derive(Copy, Clone, Debug)]
pub enum Law<'a> {
    /// Fixed slip bound p_i.
    Tresca(&'a [f64]),
    /// p_i = mu_i lambda_N,i.
    Coulomb(&'a [f64]),
}

impl Law<'_> {
    /// The slip bound of contact i given its normal multiplier.
    #[inline]
    pub fn bound(&self, i: usize, lambda_n: f64) -> f64 {
        match self {
            Law::Tresca(p) => p[i],
            Law::Coulomb(mu) => mu[i] * lambda_n.max(0.0),
        }
    }

    /// True when every bound is zero whatever lambda_N (Tresca p = 0, Coulomb
    /// mu = 0): a frictionless increment, lambda_T = 0.
    pub fn frictionless(&self) -> bool {
        match self {
            Law::Tresca(p) => p.iter().all(|&v| v == 0.0),
            Law::Coulomb(mu) => mu.iter().all(|&v| v == 0.0),
        }
    }

    /// Writes every bound into `p` (length m) for the normal multipliers `lambda_n`.
    pub fn bounds(&self, lambda_n: &[f64], p: &mut [f64]) {
        for (i, pi) in p.iter_mut().enumerate() {
            *pi = self.bound(i, lambda_n[i]);
        }
    }
}

/// What a method reports back.
#[derive(Copy, Clone, Debug, Default)]
pub struct Outcome {
    /// Outer iterations done.
    pub outer: usize,
    /// Inner sweeps done in total.
    pub inner: usize,
    /// The error measured on the dual gradient at the last iterate.
    pub dual_err: f64,
    /// The monitor asked to stop.
    pub stopped: bool,
    /// An MPRGP solve found the dual unbounded below: the contact constraints
    /// admit no displacement (see [`mprgp::Unbounded`]); the method stopped.
    pub infeasible: bool,
}

impl Outcome {
    /// Adds a sub-problem solve's iterations to `inner`; true (and `infeasible`
    /// set) when the sub-problem was unbounded, and the method must stop.
    fn add_inner(&mut self, run: Result<usize, mprgp::Unbounded>) -> bool {
        match run {
            Ok(its) => {
                self.inner += its;
                false
            }
            Err(u) => {
                self.inner += u.iterations;
                self.infeasible = true;
                true
            }
        }
    }
}

/// What the monitor sees after every outer iteration.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Progress {
    /// Outer iterations done so far in this solve (1 after the first).
    pub iteration: usize,
    /// The current err (design.md section 5), measured on the dual gradient.
    pub err: f64,
    /// Open contacts at the current iterate.
    pub n_open: usize,
    /// Sticking contacts at the current iterate.
    pub n_stick: usize,
    /// Slipping contacts at the current iterate.
    pub n_slip: usize,
    /// Seconds since the solve started.
    pub elapsed_seconds: f64,
}

/// A progress callback: returns true to go on, false to stop the solve.
pub type Monitor<'a> = &'a mut dyn FnMut(&Progress) -> bool;

/// The dual data of one increment: operator, linear term and friction law.
pub struct DualProblem<'a> {
    /// A and rho.
    pub dual: &'a Dual,
    /// The linear term b = B K^-1 f - [g; 0], length d m.
    pub b: &'a [f64],
    /// Friction bound.
    pub law: Law<'a>,
    /// Called after every outer iteration with the iteration number relative to
    /// this run; None for no monitoring.
    pub monitor: Option<RefCell<Monitor<'a>>>,
}

impl DualProblem<'_> {
    /// The common end-of-iteration test of every method: reports progress to the
    /// monitor (after the first iteration), then says whether to stop: the monitor
    /// asked to (`out.stopped`), `out.dual_err <= target`, or the iteration limit.
    /// `p` and `v` are the bounds and v = -(A lam - b) left by [`DualProblem::error`].
    pub fn should_stop(
        &self,
        out: &mut Outcome,
        lam: &[f64],
        p: &[f64],
        v: &[f64],
        target: f64,
        opts: &Options,
    ) -> bool {
        if out.outer > 0
            && let Some(cell) = &self.monitor
        {
            let (n_open, n_stick, n_slip) = contact_states(lam, v, &self.dual.rho, p, self.dual.d);
            let progress = Progress {
                iteration: out.outer,
                err: out.dual_err,
                n_open,
                n_stick,
                n_slip,
                elapsed_seconds: 0.0,
            };
            if !(cell.borrow_mut())(&progress) {
                out.stopped = true;
                return true;
            }
        }
        out.dual_err <= target || out.outer >= opts.max_outer
    }

    /// w := A lam - b (the negative of v = [N u - g; T u]).
    pub fn gradient(&self, lam: &[f64], w: &mut [f64]) {
        self.dual.apply(lam, w);
        for (wi, bi) in w.iter_mut().zip(self.b) {
            *wi -= bi;
        }
    }

    /// The error of design.md section 5 at `lam`, given w = A lam - b; `p` and `v`
    /// are scratch of length m and d m.
    pub fn error(&self, lam: &[f64], w: &[f64], p: &mut [f64], v: &mut [f64]) -> f64 {
        let m = self.dual.m;
        self.law.bounds(&lam[..m], p);
        for (vi, wi) in v.iter_mut().zip(w) {
            *vi = -wi;
        }
        natural_map_error(lam, v, &self.dual.rho, self.b, p, self.dual.d)
    }
}

/// Runs `opts.method` from the starting point in `lam` (length d m; a warm start or
/// zeros) until the dual error is at most `target` or the iteration limit.
pub fn run(problem: &DualProblem<'_>, lam: &mut [f64], opts: &Options, target: f64) -> Outcome {
    if problem.law.frictionless() {
        match opts.method {
            Method::Split | Method::BlockGs => return signorini(problem, lam, opts, target, false),
            Method::SplitMprgp | Method::Mprgp => {
                return signorini(problem, lam, opts, target, true);
            }
            // PGS's tangential local steps cost O(1) per contact with a zero bound,
            // and Newton drops unknowns at zero bounds from its linear systems.
            Method::Pgs | Method::Newton => {}
        }
    }
    match opts.method {
        Method::Pgs => pgs::solve(problem, lam, opts, target),
        Method::Split => split::solve(problem, lam, opts, target, true, false),
        Method::BlockGs => split::solve(problem, lam, opts, target, false, false),
        Method::SplitMprgp => split::solve(problem, lam, opts, target, true, true),
        Method::Mprgp => whole_mprgp(problem, lam, opts, target),
        Method::Newton => newton::solve(problem, lam, opts, target),
    }
}

/// The pure Signorini problem of a frictionless increment (every slip bound zero:
/// lambda_T = 0): min 1/2 y^T A_NN y - y^T b_N over y >= 0 in the m normal
/// unknowns alone (design.md section 2: the cost follows the physics switched on),
/// by projected Gauss-Seidel or MPRGP on the leading m x m block of A (dense) or
/// on products with it (matrix-free). One outer iteration is one sub-problem solve
/// to a tenth of the target; the stopping test is the whole problem's err.
fn signorini(
    problem: &DualProblem<'_>,
    lam: &mut [f64],
    opts: &Options,
    target: f64,
    use_mprgp: bool,
) -> Outcome {
    let dual = problem.dual;
    let (m, c) = (dual.m, dual.c);
    lam[m..].iter_mut().for_each(|x| *x = 0.0);
    let mut out = Outcome::default();
    let mut w = vec![0.0; c];
    let mut scratch = mprgp::Scratch::new(m);
    let mut norm = None;
    let mut p = vec![0.0; m];
    let mut v = vec![0.0; c];
    loop {
        problem.gradient(lam, &mut w);
        out.dual_err = problem.error(lam, &w, &mut p, &mut v);
        if problem.should_stop(&mut out, lam, &p, &v, target, opts) {
            return out;
        }
        let sub = pgs::SubQp {
            h: &dual.a,
            ld: c,
            k: m,
            q: &problem.b[..m],
            block: 1,
            radii: None,
        };
        let run = if use_mprgp {
            let mut qp = sub.as_convex();
            qp.op = dual.is_matrix_free().then_some(dual);
            qp.solve_in(
                &mut lam[..m],
                0.1 * target,
                opts.max_inner,
                &mut scratch,
                &mut norm,
            )
        } else {
            Ok(sub.solve(&mut lam[..m], scratch.one(m), 0.1 * target, opts.max_inner))
        };
        out.outer += 1;
        if out.add_inner(run) {
            return out;
        }
    }
}

/// MPRGP / MPGP on the whole dual, with the Coulomb fixed point p = mu lambda_N
/// outside: each outer iteration solves the Tresca problem of the current bound
/// (one outer iteration for Tresca).
fn whole_mprgp(problem: &DualProblem<'_>, lam: &mut [f64], opts: &Options, target: f64) -> Outcome {
    let dual = problem.dual;
    let (m, c) = (dual.m, dual.c);
    let mut out = Outcome::default();
    let mut w = vec![0.0; c];
    let mut p = vec![0.0; m];
    let mut v = vec![0.0; c];
    let mut radii = vec![0.0; m];
    // Coulomb: the bound is relaxed as in split.rs (Aitken; the plain fixed point
    // while it does not oscillate), and the limit returns the best iterate.
    let coulomb = matches!(problem.law, Law::Coulomb(_));
    let mut relax = pgs::Aitken::new(if coulomb { m } else { 0 });
    let mut prev = vec![0.0; if coulomb { m } else { 0 }];
    let mut best = pgs::BestIterate::new(c);
    // H = A for every outer iteration: one scratch and one norm estimate.
    let mut scratch = mprgp::Scratch::new(c);
    let mut norm = None;
    loop {
        problem.gradient(lam, &mut w);
        out.dual_err = problem.error(lam, &w, &mut p, &mut v);
        best.offer(lam, out.dual_err);
        if problem.should_stop(&mut out, lam, &p, &v, target, opts) {
            best.restore_at_limit(lam, &mut out, target);
            return out;
        }
        problem.law.bounds(&lam[..m], &mut radii);
        if coulomb {
            relax.relax_bound(&mut prev, &mut radii, out.outer == 0);
        }
        let qp = mprgp::ConvexQp {
            h: &dual.a,
            ld: c,
            op: dual.is_matrix_free().then_some(dual),
            k: c,
            q: problem.b,
            n_nonneg: m,
            block: dual.d - 1,
            radii: &radii,
        };
        let run = qp.solve_in(lam, 0.1 * target, opts.max_inner, &mut scratch, &mut norm);
        out.outer += 1;
        if out.add_inner(run) {
            return out;
        }
    }
}
