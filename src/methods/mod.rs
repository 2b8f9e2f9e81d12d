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
//! described by a [`MethodSpec`] in its file and listed in [`Method`]'s table
//! (`Method::spec`). The sub-problems of the splittings are solved by a
//! [`subproblem::SubSolver`]: projected Gauss-Seidel or MPRGP. Projections onto
//! the friction sets and the small local problems live in `projection`.

mod aitken;
mod auto;
mod driver;
mod krylov;
mod mprgp;
mod newton;
mod pgs;
mod projection;
mod signorini;
mod split;
mod subproblem;
mod sweeps;
mod whole;

pub use driver::{End, Outcome};

use crate::dual::Dual;
use crate::friction::Friction;

use crate::options::{Method, Options};
use driver::OuterStep;
use std::cell::{Cell, RefCell};
use std::time::Instant;

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
    /// The starting multipliers are a history's prediction (src/history.rs),
    /// or a host iteration's from its increments' or its iterations' line:
    /// the load increment is already in them, so the natural map at them sorts
    /// the contacts (a plain warm start's is sorted by the multipliers alone).
    pub predicted: bool,
    /// The starting multipliers are the answer of a neighbouring problem (a
    /// round of Newton on a nonlinear compliance law, docs/design.md section
    /// 8): Newton takes no warm-up sweeps and sorts the contacts by the
    /// natural map at the start, as for a prediction.
    pub near: bool,
    /// w = A lam - b at the starting multipliers, computed by the caller as
    /// exactly as the driver would (to the rounding b carries; length c):
    /// the driver takes it for its first gradient instead of a product with
    /// A. Taken by the first run on this problem (under `Auto`, the methods
    /// after the first start from another iterate and compute it).
    pub start_gradient: Cell<Option<&'a [f64]>>,
    /// The caller measures the error again on the u it recovers from the
    /// answer (one solve with K, as a product with A costs, or none where
    /// the solve carried u there, `primal`; a drifted gradient comes from
    /// single-precision products, which leave it behind): the driver may
    /// then end converged on a drifted gradient ([`driver::Gradient::Drifted`])
    /// without recomputing it, and says so ([`Outcome::unconfirmed`]); the
    /// caller runs again from there where the recovered error misses the
    /// tolerance. False: every convergence is confirmed on an exact
    /// gradient.
    pub measured_after: bool,
    /// The natural residual |F| (force units) of the point the start was
    /// predicted from, where a host iteration's line moved it there
    /// (`solve::iteration_line`, which takes the line only where it lowers
    /// |F|; None otherwise): Newton's forcing terms are taken relative to
    /// it, as after a step.
    pub start_from: Option<f64>,
    /// u = K^-1 (f - B^T lambda) carried along with the iterate
    /// ([`crate::dual::Primal`]), where the caller started it: a step whose
    /// A d is an exact product moves it too (None: nothing carried).
    pub(crate) primal: Option<&'a RefCell<crate::dual::Primal>>,
}

impl<'a> DualProblem<'a> {
    /// The dual problem on `dual` with load `b` and friction `law`: no
    /// monitor, no deadline, a start that is neither predicted nor near, no
    /// gradient handed over, every convergence confirmed on an exact one.
    pub fn new(dual: &'a Dual, b: &'a [f64], law: Friction<'a>) -> Self {
        DualProblem {
            dual,
            b,
            law,
            monitor: None,
            deadline: None,
            predicted: false,
            near: false,
            start_gradient: Cell::new(None),
            measured_after: false,
            start_from: None,
            primal: None,
        }
    }
    /// w := A lam - b (the negative of v = [N u - g; T u]).
    pub fn gradient(&self, lam: &[f64], w: &mut [f64]) {
        self.dual.apply(lam, w);
        for (wi, bi) in w.iter_mut().zip(self.b) {
            *wi -= bi;
        }
    }

    /// |F(lam)|_2, the natural map's residual in force units (Newton's merit,
    /// `newton.rs`), given w = A lam - b.
    pub fn natural_residual(&self, lam: &[f64], w: &[f64]) -> f64 {
        newton::residual_norm(self, lam, w)
    }

    /// The error of docs/design.md section 5 at `lam`, given w = A lam - b; `p` and `v`
    /// are scratch of length m and d m.
    pub fn error(&self, lam: &[f64], w: &[f64], p: &mut [f64], v: &mut [f64]) -> f64 {
        let m = self.dual.m;
        self.law.bounds(&lam[..m], p);
        for (vi, wi) in v.iter_mut().zip(w) {
            *vi = -wi;
        }
        self.dual.error(lam, v, &self.dual.rho, self.b, p)
    }
}

/// What the driver knows of a method: its name and how to build its outer step.
/// Each method's file holds its `MethodSpec` constant(s); the table of
/// `methods!` below lists them and defines [`Method`] from them.
struct MethodSpec {
    /// Short lower-case name (CLI, report.json, C's `ds_method_name`).
    name: &'static str,
    /// True when the method reads entries of A (and so needs it assembled).
    needs_entries: bool,
    /// Bytes of the method's dense work space on a dual of m contacts and c
    /// unknowns, dense (false) or matrix-free (true), in its largest case
    /// (vectors of length c left out).
    workspace: fn(usize, usize, bool) -> usize,
    /// The outer step for a problem and dual target, and the number of dual
    /// unknowns it iterates on (d m; m for a frictionless increment solved as the
    /// pure Signorini problem).
    build: fn(&DualProblem<'_>, &Options, f64) -> Built,
}

/// A method's outer step and the number of dual unknowns it iterates on.
type Built = (Box<dyn OuterStep>, usize);

/// No dense work space (vectors of length c only).
fn no_workspace(_m: usize, _c: usize, _matrix_free: bool) -> usize {
    0
}

/// The sub-problem stopping rule of the methods that solve sub-problems: a tenth
/// of the dual target, within `opts.max_inner` iterations.
fn inner_rule(opts: &Options, target: f64) -> (f64, usize) {
    (0.1 * target, opts.max_inner)
}

impl Method {
    /// The method's entry in the table: adding a method is its file (with its
    /// `MethodSpec`), its `mod` line above, its variant in [`Method`]
    /// (options.rs; the C enum `DsMethod` follows it, its count checked at
    /// compile time) and its line here.
    fn spec(self) -> &'static MethodSpec {
        match self {
            Method::Split => &split::SPLIT,
            Method::BlockGs => &split::BLOCK_GS,
            Method::Pgs => &pgs::PGS,
            Method::Newton => &newton::NEWTON,
            Method::SplitMprgp => &split::SPLIT_MPRGP,
            Method::Mprgp => &whole::MPRGP,
            Method::Auto => &auto::AUTO,
        }
    }

    /// Short lower-case name ("split", "block-gs", "pgs", "newton",
    /// "split-mprgp", "mprgp").
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// True when the method reads entries of A (and so needs it assembled);
    /// `Newton`, `Mprgp` and `Auto` run on products alone.
    pub fn needs_entries(self) -> bool {
        self.spec().needs_entries
    }

    /// Bytes of the method's dense work space on a dual of `m` contacts and `c`
    /// unknowns held dense or `matrix_free`, in its largest case (see each
    /// method's documentation).
    pub(crate) fn workspace(self, m: usize, c: usize, matrix_free: bool) -> usize {
        (self.spec().workspace)(m, c, matrix_free)
    }

    /// Parses a name as returned by [`Method::name`].
    pub fn from_name(s: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// Runs `opts.method` from the starting point in `lam` (length d m; a warm start or
/// zeros) until the dual error is at most `target` or another stop test fires
/// (see [`End`]).
pub fn run(problem: &DualProblem<'_>, lam: &mut [f64], opts: &Options, target: f64) -> Outcome {
    if opts.method == Method::Auto {
        return auto::run(problem, lam, opts, target);
    }
    run_one(problem, lam, opts, target)
}

/// Runs `opts.method` (not `Auto`).
fn run_one(problem: &DualProblem<'_>, lam: &mut [f64], opts: &Options, target: f64) -> Outcome {
    let (mut method, unknowns) = (opts.method.spec().build)(problem, opts, target);
    let mut out = driver::drive(problem, lam, opts, target, method.as_mut());
    out.unknowns = unknowns;
    out.method = Some(opts.method);
    out
}
