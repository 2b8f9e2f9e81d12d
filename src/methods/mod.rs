//! The iterative methods on the condensed dual
//!
//! ```text
//! min 1/2 lambda^T A lambda - lambda^T b,  lambda_N >= 0,  |lambda_T,i| <= p_i,
//! ```
//!
//! all behind one entry point, [`run`], so that every method runs on the same data.
//! `driver` owns the outer loop and its stop tests; a method is an
//! [`driver::OuterStep`] in a file of its own (`pgs`, `split`, `newton`,
//! `whole` for MPRGP on the whole dual, `signorini` for frictionless increments),
//! built by [`outer_step`]. The sub-problems of the splittings are solved by a
//! [`subproblem::SubSolver`]: projected Gauss-Seidel or MPRGP. Projections onto
//! the friction sets and the small local problems live in `projection`.

mod driver;
mod mprgp;
mod newton;
mod pgs;
mod projection;
mod signorini;
mod split;
mod subproblem;
mod whole;

pub use driver::{End, Outcome};

use crate::dual::Dual;
use crate::friction::Friction;
use crate::options::{Method, Options};
use crate::report::natural_map_error;
use driver::OuterStep;
use signorini::Signorini;
use split::Split;
use split::Variant::{Block, Schur};
use std::cell::RefCell;
use std::time::Instant;
use subproblem::{GaussSeidel, Mprgp};

/// What the monitor sees after every outer iteration.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Progress {
    /// Outer iterations done so far in this solve (1 after the first).
    pub iteration: usize,
    /// The current err (docs/design.md section 5), measured on the dual gradient.
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
    pub law: Friction<'a>,
    /// Called after every outer iteration with the iteration number relative to
    /// this run; None for no monitoring.
    pub monitor: Option<RefCell<Monitor<'a>>>,
    /// The wall-clock budget: no outer iteration starts after it.
    pub deadline: Option<Instant>,
}

impl DualProblem<'_> {
    /// w := A lam - b (the negative of v = [N u - g; T u]).
    pub fn gradient(&self, lam: &[f64], w: &mut [f64]) {
        self.dual.apply(lam, w);
        for (wi, bi) in w.iter_mut().zip(self.b) {
            *wi -= bi;
        }
    }

    /// The error of docs/design.md section 5 at `lam`, given w = A lam - b; `p` and `v`
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

/// The method `opts.method` as an outer step for `problem` and the dual target
/// `target`, and the number of dual unknowns it iterates on. Sub-problems are
/// solved to a tenth of the target within `opts.max_inner` iterations. A
/// frictionless increment (every slip bound zero) is the pure Signorini problem in
/// the m normal unknowns for the splittings and whole-dual MPRGP (docs/design.md
/// section 2); PGS's tangential steps cost O(1) per contact with a zero bound, and
/// Newton drops the unknowns at zero bounds from its linear systems, so those two
/// run as they are.
fn outer_step(
    problem: &DualProblem<'_>,
    opts: &Options,
    target: f64,
) -> (Box<dyn OuterStep>, usize) {
    let (m, c) = (problem.dual.m, problem.dual.c);
    let (tol, max) = (0.1 * target, opts.max_inner);
    if problem.law.frictionless() {
        match opts.method {
            Method::Split | Method::BlockGs => {
                return (Box::new(Signorini::new(GaussSeidel::new(m, tol, max))), m);
            }
            Method::SplitMprgp | Method::Mprgp => {
                return (Box::new(Signorini::new(Mprgp::new(m, tol, max))), m);
            }
            Method::Pgs | Method::Newton => {}
        }
    }
    let k = m.max(c - m);
    let step: Box<dyn OuterStep> = match opts.method {
        Method::Pgs => Box::new(pgs::Pgs::new(problem)),
        Method::Split => Box::new(Split::new(problem, Schur, GaussSeidel::new(k, tol, max))),
        Method::BlockGs => Box::new(Split::new(problem, Block, GaussSeidel::new(k, tol, max))),
        Method::SplitMprgp => Box::new(Split::new(problem, Schur, Mprgp::new(k, tol, max))),
        Method::Mprgp => Box::new(whole::WholeMprgp::new(problem, Mprgp::new(c, tol, max))),
        Method::Newton => Box::new(newton::Newton::new(problem, target)),
    };
    (step, c)
}

/// Runs `opts.method` from the starting point in `lam` (length d m; a warm start or
/// zeros) until the dual error is at most `target` or another stop test fires
/// (see [`End`]).
pub fn run(problem: &DualProblem<'_>, lam: &mut [f64], opts: &Options, target: f64) -> Outcome {
    let (mut method, unknowns) = outer_step(problem, opts, target);
    let mut out = driver::drive(problem, lam, opts, target, method.as_mut());
    out.unknowns = unknowns;
    out
}
