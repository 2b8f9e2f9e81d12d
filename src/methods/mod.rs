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
//! described by a [`MethodSpec`] in its file and listed in the table that defines
//! [`Method`] (`methods!`). The sub-problems of the splittings are solved by a
//! [`subproblem::SubSolver`]: projected Gauss-Seidel or MPRGP. Projections onto
//! the friction sets and the small local problems live in `projection`.

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
mod whole;

pub use driver::{End, Outcome};

use crate::dual::Dual;
use crate::friction::Friction;

use crate::options::Options;
use crate::report::natural_map_error;
use driver::OuterStep;
use std::cell::RefCell;
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
    /// The starting multipliers are a history's prediction (src/history.rs):
    /// the load increment is already in them, so the natural map at them sorts
    /// the contacts (a plain warm start's is sorted by the multipliers alone).
    pub predicted: bool,
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

/// What the driver knows of a method: its name and how to build its outer step.
/// Each method's file holds its `MethodSpec` constant(s); the table of
/// [`methods!`] below lists them and defines [`Method`] from them.
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

/// Defines [`Method`] (public API; its order is the C enum's, `DsMethod`) from
/// the table of `Variant => spec` lines: adding a method is its file (with its
/// `MethodSpec`), its `mod` line above and one line here (and, for C, its
/// `DsMethod` value, whose count is checked against this table at compile time).
macro_rules! methods {
    ($( $(#[$doc:meta])* $variant:ident => $spec:path, )*) => {
        /// The iterative method run on the condensed dual problem. Later
        /// versions may add methods (`#[non_exhaustive]`).
        #[derive(Copy, Clone, Debug, PartialEq, Eq)]
        #[non_exhaustive]
        pub enum Method {
            $( $(#[$doc])* $variant, )*
        }

        impl Method {
            /// Every method, in the order of the C enum.
            pub const ALL: [Method; [$(stringify!($variant)),*].len()] = [$(Method::$variant),*];

            /// The method's entry in the table.
            fn spec(self) -> &'static MethodSpec {
                match self {
                    $( Method::$variant => &$spec, )*
                }
            }
        }
    };
}

methods! {
    /// Pop's dual splitting, Schur complement variant (docs/design.md section 3): the
    /// tangential step on S = A22 - A21 A11^-1 A12 over the current contact set,
    /// then the normal step on A11; both sub-problems by projected Gauss-Seidel.
    Split => split::SPLIT,
    /// Plain block Gauss-Seidel on (lambda_N, lambda_T): tangential step on A22,
    /// normal step on A11, both by projected Gauss-Seidel.
    BlockGs => split::BLOCK_GS,
    /// Projected Gauss-Seidel on the whole dual, contact by contact (Siconos NSGS).
    Pgs => pgs::PGS,
    /// Semismooth Newton (primal-dual active set) on the condensed dual with the
    /// generalised Jacobian of the friction projections. Up to 40 Gauss-Seidel
    /// sweeps first (counted as inner iterations); a step (or half, a quarter, an
    /// eighth of it) is kept when it lowers the natural residual |F|, otherwise
    /// Gauss-Seidel sweeps follow. One outer iteration is one Newton step (a dense
    /// Cholesky / LU on the free unknowns; on a matrix-free dual, preconditioned CG
    /// or GMRES on products with A, without the sweeps, falling back to projection
    /// steps).
    Newton => newton::NEWTON,
    /// Pop's splitting (Schur variant) with MPRGP / MPGP for the sub-problems instead
    /// of projected Gauss-Seidel.
    SplitMprgp => split::SPLIT_MPRGP,
    /// MPRGP / MPGP (Dostal) on the whole dual; for Coulomb, the fixed point
    /// p = mu lambda_N outside (one outer iteration per Tresca solve).
    Mprgp => whole::MPRGP,
    /// The library's choice for the problem at hand (see `methods/auto.rs`), and
    /// the default: `Newton` on a dense dual, falling back to `SplitMprgp` from
    /// Newton's best iterate when Newton stalls or reaches its iteration limit;
    /// on a matrix-free dual `Newton` (Krylov steps), then `Mprgp`. `Report::method` names the method that gave the
    /// answer and `Report::choice` says why.
    Auto => auto::AUTO,
}

impl Method {
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
