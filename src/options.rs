//! Solver options: which method, tolerances and iteration limits.

use crate::error::{ErrorKind, Result, fail};

/// The iterative method run on the condensed dual problem. Later versions
/// may add methods (`#[non_exhaustive]`). The order is the C enum's
/// (`DsMethod`); each variant's implementation is listed in
/// `methods::Method::spec`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Method {
    /// Pop's dual splitting, Schur complement variant (docs/design.md section 3): the
    /// tangential step on S = A22 - A21 A11^-1 A12 over the current contact set,
    /// then the normal step on A11; both sub-problems by projected Gauss-Seidel.
    Split,
    /// Plain block Gauss-Seidel on (lambda_N, lambda_T): tangential step on A22,
    /// normal step on A11, both by projected Gauss-Seidel.
    BlockGs,
    /// Projected Gauss-Seidel on the whole dual, contact by contact (Siconos NSGS).
    Pgs,
    /// Semismooth Newton (primal-dual active set) on the condensed dual with the
    /// generalised Jacobian of the friction projections. Up to 40 Gauss-Seidel
    /// sweeps first (counted as inner iterations); a step (or half, a quarter, an
    /// eighth of it) is kept when it lowers the natural residual |F|, otherwise
    /// Gauss-Seidel sweeps follow. One outer iteration is one Newton step (a dense
    /// Cholesky / LU on the free unknowns; on a matrix-free dual, preconditioned CG
    /// or GMRES on products with A, without the sweeps, falling back to projection
    /// steps).
    Newton,
    /// Pop's splitting (Schur variant) with MPRGP / MPGP for the sub-problems instead
    /// of projected Gauss-Seidel.
    SplitMprgp,
    /// MPRGP / MPGP (Dostal) on the whole dual; for Coulomb, the fixed point
    /// p = mu lambda_N outside (one outer iteration per Tresca solve).
    Mprgp,
    /// The library's choice for the problem at hand (see `methods/auto.rs`), and
    /// the default: `Newton` on a dense dual, falling back to `SplitMprgp` from
    /// Newton's best iterate when Newton stalls or reaches its iteration limit;
    /// on a matrix-free dual `Newton` (Krylov steps), then `Mprgp`. `Report::method` names the method that gave the
    /// answer and `Report::choice` says why.
    Auto,
}

impl Method {
    /// Every method, in the order of the C enum (a new variant goes here too:
    /// `methods::Method::spec` will not compile without it, and the C layer
    /// checks its enum's count against this one).
    pub const ALL: [Method; 7] = [
        Method::Split,
        Method::BlockGs,
        Method::Pgs,
        Method::Newton,
        Method::SplitMprgp,
        Method::Mprgp,
        Method::Auto,
    ];
}

/// How the products with the condensed dual operator A = B K^-1 B^T are formed.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DualForm {
    /// Dense A while c = d m <= [`DENSE_MAX`] (and it fits `max_memory`, and
    /// for a method that runs matrix-free the contact face ordered last does
    /// not dominate the factor: not on thin slabs and long 2D strips,
    /// docs/design.md section 6), matrix-free beyond; a method that needs the entries of A (every method but
    /// `Newton`, `Mprgp` and `Auto`) assembles it when needed.
    Auto,
    /// Assemble the dense c x c matrix A (c^2 doubles; `OutOfMemory` if it does not
    /// fit).
    Dense,
    /// Never form A, nor anything c x c: each product A x is one solve with K's
    /// factor. A problem created with it factors K in the best plain ordering
    /// (no contact DOFs last); the contacts' d x d diagonal blocks of A (for rho
    /// and Newton's preconditioner) are computed once from the factor by
    /// selected inversion or sparse forward solves, and the sparse lumped
    /// G = B K B^T once from K. `Newton` (its steps by CG / GMRES preconditioned
    /// with G),
    /// `Mprgp` and `Auto` run matrix-free; the others read entries of A.
    MatrixFree,
}

impl DualForm {
    /// Every form, in the order of the C enum.
    pub const ALL: [DualForm; 3] = [DualForm::Auto, DualForm::Dense, DualForm::MatrixFree];

    /// Short lower-case name ("auto", "dense", "matrix-free").
    pub fn name(self) -> &'static str {
        match self {
            DualForm::Auto => "auto",
            DualForm::Dense => "dense",
            DualForm::MatrixFree => "matrix-free",
        }
    }

    /// Parses a name as returned by [`DualForm::name`].
    pub fn from_name(s: &str) -> Option<DualForm> {
        DualForm::ALL.into_iter().find(|f| f.name() == s)
    }
}

/// The fill-reducing ordering of K's sparse Cholesky factorisation (as CHOLMOD's
/// ordering policy or MUMPS's ICNTL(7)). Both orderings work on K's compressed
/// graph (one vertex per node: the DOFs whose columns of K share a pattern), with
/// the contact DOFs ordered last where the condensation needs them there.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Ordering {
    /// In 2D (d = 2): AMD, and METIS as well where AMD's factor has large fronts
    /// (more than 500 flops per entry of L, as CHOLMOD's default policy decides),
    /// the one whose symbolic factor needs fewer flops kept (AMD on a tie); in
    /// 3D (d = 3): METIS (AMD where METIS fails). In 2D AMD's fronts
    /// are small and METIS's analysis would cost more than it saves; on 3D
    /// meshes nested dissection needed fewer flops than AMD, small fronts
    /// included (AMD won only on tiny, nearly dense K, by up to 10 %), and
    /// AMD's analysis would be thrown away.
    Auto,
    /// Approximate minimum degree (faer's AMD).
    Amd,
    /// Nested dissection: METIS_NodeND (METIS 5, built from vendored sources).
    Metis,
    /// Reported only (never an option: `BadArgument`): K has every entry stored (a
    /// dense K, `Format::Dense`, or a sparse pattern that is full) and was factored
    /// by dense Cholesky, without a fill-reducing ordering or a symbolic analysis.
    Dense,
}

impl Ordering {
    /// Every ordering an option may name, in the order of the C enum.
    pub const ALL: [Ordering; 3] = [Ordering::Auto, Ordering::Amd, Ordering::Metis];

    /// Short lower-case name ("auto", "amd", "metis").
    pub fn name(self) -> &'static str {
        match self {
            Ordering::Auto => "auto",
            Ordering::Amd => "amd",
            Ordering::Metis => "metis",
            Ordering::Dense => "dense",
        }
    }

    /// Parses a name as returned by [`Ordering::name`] (of the options in
    /// [`Ordering::ALL`]).
    pub fn from_name(s: &str) -> Option<Ordering> {
        Ordering::ALL.into_iter().find(|o| o.name() == s)
    }
}

/// Number of dual unknowns c = d m up to which `DualForm::Auto` assembles A
/// (8,000: A then takes at most 512 MB).
pub const DENSE_MAX: usize = 8_000;

/// How a problem on the host's solves (`ContactProblem::with_host_solver`)
/// obtains the contacts' d x d diagonal blocks of A = B K^-1 B^T: once at
/// creation, and again when the contacts are replaced.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum HostBlocks {
    /// The host's entries of K^-1 where it gives them
    /// (`KSolve::inverse_entries`, one call); else `Factor` where K is
    /// handed over, its factor fits `max_memory` and its flops are fewer than
    /// the solves' (c solves of 4 nnz(L) flops each against 2.5 times the
    /// factorisation's flops); else `Solves`. The default: a host that hands
    /// K over expects it used (its analysis is made at creation for the
    /// memory prediction even where the host's entries then serve).
    #[default]
    Auto,
    /// By d m of the host's solves, 32 right-hand sides per call, or by its
    /// entries of K^-1 where it gives them: nothing of K's factor in the
    /// library's memory. Each column is a whole solve: 9-75 factorisations of
    /// K on the benchmark's 3D blocks.
    Solves,
    /// By the library's own factor of K, which must be handed over
    /// (`BadArgument` without it): analysed and factored at creation, its
    /// selected inversion giving the blocks, and freed before creation
    /// returns (its bytes in the creation's prediction and under
    /// max_memory); the same when the contacts are replaced. 1.5-2.5
    /// factorisations of K in all on the benchmark's 3D blocks. The host's
    /// entries of K^-1 are not asked for; the products still call the host.
    Factor,
}

/// Options of one solve. `Options::default()` gives the documented defaults.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Options {
    /// Method (default `Auto`: the library's choice, see [`Method::Auto`]).
    pub method: Method,
    /// Stop when err (docs/design.md section 5) is at most `tol` (default 1e-10).
    pub tol: f64,
    /// Maximum number of outer iterations: sweeps for `Pgs`, normal/tangential
    /// alternations for `Split` and `BlockGs` (default 10_000).
    pub max_outer: usize,
    /// Maximum number of inner iterations per sub-problem: Gauss-Seidel sweeps in
    /// `Split` and `BlockGs`, MPRGP iterations in `SplitMprgp` and `Mprgp`
    /// (default 1_000).
    pub max_inner: usize,
    /// Dense or matrix-free products with A (default `Auto`). Read by every solve
    /// and by `ContactProblem::with_options`, which creates the problem in that
    /// form: `MatrixFree` factors K in the best plain ordering, `Dense` with the
    /// contact DOFs last (whatever c, where it fits `max_memory`), `Auto` by
    /// [`DENSE_MAX`] and the memory limit.
    pub dual_form: DualForm,
    /// Wall-clock budget of one solve in seconds, 0 for none (default 0): no outer
    /// iteration starts after it, and the solve ends with `SolveStatus::TimeLimit`
    /// and the iterate with the lowest err. Checked between outer iterations, so
    /// one iteration (a Newton step, a sub-problem solve) may overrun it; the setup
    /// (factorisation, condensation) is not counted.
    pub max_seconds: f64,
    /// The stagnation test's window in outer iterations, 0 to turn it off
    /// (default [`STALL_WINDOW`]). After `stall_window` or more outer iterations,
    /// let r be the lowest err met divided by the lowest err met up to
    /// `stall_window` iterations earlier. The solve ends with
    /// `SolveStatus::Stalled` and the iterate with the lowest err when r is above
    /// `stall_factor` and, at the pace r per window, `tol` would not be reached
    /// within `max_outer` iterations (always when r = 1: no progress at all).
    pub stall_window: usize,
    /// The factor by which the lowest err must drop over `stall_window` outer
    /// iterations to count as progress whatever the iteration limit, in (0, 1]
    /// (default [`STALL_FACTOR`]; 1 stops only a run whose best err did not improve at
    /// all over the window).
    pub stall_factor: f64,
    /// Fill-reducing ordering of K (default `Auto`). Read where K is analysed, by
    /// `ContactProblem::with_options` (`refactor` keeps that analysis); `solve`
    /// and `step` ignore it.
    pub ordering: Ordering,
    /// Threads for the factorisation, the condensation and the dense kernels:
    /// 0 for all cores (default), 1 for the calling thread only (no thread is
    /// started), k for at most k (at most 4096). Read by
    /// `ContactProblem::with_options`: the problem holds its own thread pool of
    /// that size (not rayon's global one) for all its later calls, so problems in
    /// different threads of a program do not compete for one pool; `solve` and
    /// `step` ignore it. The pool is started by the first piece of work large
    /// enough to use it (a problem whose work stays small never starts one; if the
    /// system refuses the threads, the work runs on the calling thread). Results
    /// with 1 thread are bit-identical from run to run.
    pub threads: usize,
    /// The most bytes the problem's large allocations may take at once, 0 for no
    /// limit of the caller's (default 0: then the limit is this process's
    /// address-space limit, RLIMIT_AS, or the machine's physical memory, the
    /// smaller). The need of the factor, the condensed dual and the method's
    /// dense work space is predicted from the sizes known after the symbolic
    /// analysis, before the work that allocates them: a creation (or a solve)
    /// whose prediction exceeds the limit ends with `OutOfMemory` and a message
    /// that names the need; `DualForm::Auto` picks the matrix-free form where the
    /// dense one does not fit. Read by `ContactProblem::with_options` (the problem
    /// keeps it as the limit of `refactor`, which holds the old and the new factor
    /// at once, and of `set_contacts`) and by every `solve` and `step` (a refused
    /// call leaves the problem as it was).
    pub max_memory: usize,
    /// The problem serves a host's Newton loop: K refactored before nearly
    /// every solve (`ContactProblem::refactor`, then `solve_iteration`;
    /// docs/design.md section 9). `DualForm::Auto` then takes the
    /// matrix-free route on 3D problems where the method runs matrix-free
    /// (the dense route is not weighed): its refactor is the plain numeric factor
    /// with the contact blocks kept, where the dense route's orders the
    /// contact DOFs last (2.2-2.8 times the plain factor on a 40 x 40 x 20
    /// block) and condenses again. Default false. Read by
    /// `ContactProblem::with_options`.
    pub host_loop: bool,
    /// How a problem on the host's solves obtains the contacts' blocks (see
    /// [`HostBlocks`]; default `Auto`). Read by
    /// `ContactProblem::with_host_solver` (kept for `set_contacts`); ignored
    /// elsewhere.
    pub host_blocks: HostBlocks,
}

/// Default window of the stagnation test, in outer iterations.
pub const STALL_WINDOW: usize = 100;

/// Default factor of the stagnation test: with the defaults (100, 0.9) a method
/// that lowers its best err by 10 % or more every 100 outer iterations always
/// goes on; a slower one goes on while its pace still reaches `tol` within
/// `max_outer`. Plateaus of 50 iterations were seen while Aitken's factor settles
/// on a strongly coupled Coulomb fixed point (tests/hard_scenes.rs, the inclined
/// column), hence a window of 100.
pub const STALL_FACTOR: f64 = 0.9;

/// The largest `Options::threads` accepted (a guard against garbage values).
pub(crate) const MAX_THREADS: usize = 4096;

impl Options {
    /// Checks the values every entry point accepts; `prefix` is put before a
    /// field's name in the message (the C layer's "opts.", nothing for Rust
    /// callers). The C layer checks its own conversions (enum values, signed
    /// counts) before this.
    ///
    /// Errors: `BadArgument`: tol not positive and finite, max_inner 0,
    /// ordering `Dense` (reported, never chosen), max_seconds negative or not
    /// finite, threads above 4096, stall_factor outside (0, 1].
    pub(crate) fn check(&self, prefix: &str) -> Result<()> {
        let bad = |msg: String| fail(ErrorKind::BadArgument, msg);
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return bad(format!(
                "{prefix}tol = {} must be positive and finite",
                self.tol
            ));
        }
        if self.max_inner == 0 {
            return bad(format!("{prefix}max_inner = 0 must be at least 1"));
        }
        if self.ordering == Ordering::Dense {
            return bad(format!(
                "{prefix}ordering = dense is reported, not chosen: a K with every entry \
                 stored (the dense format) is factored densely whatever the ordering option"
            ));
        }
        if !(self.max_seconds.is_finite() && self.max_seconds >= 0.0) {
            return bad(format!(
                "{prefix}max_seconds = {} must be finite and >= 0 (0: no limit)",
                self.max_seconds
            ));
        }
        if self.threads > MAX_THREADS {
            return bad(format!(
                "{prefix}threads = {} is more than {MAX_THREADS} (0: all cores)",
                self.threads
            ));
        }
        if !(self.stall_factor > 0.0 && self.stall_factor <= 1.0) {
            return bad(format!(
                "{prefix}stall_factor = {} must be in (0, 1]",
                self.stall_factor
            ));
        }
        Ok(())
    }
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::Auto,
            tol: 1e-10,
            max_outer: 10_000,
            max_inner: 1_000,
            dual_form: DualForm::Auto,
            max_seconds: 0.0,
            stall_window: STALL_WINDOW,
            stall_factor: STALL_FACTOR,
            ordering: Ordering::Auto,
            threads: 0,
            max_memory: 0,
            host_loop: false,
            host_blocks: HostBlocks::Auto,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_bad_value_is_refused_with_the_field_named() {
        let o = Options::default();
        assert!(o.check("").is_ok());
        let cases = [
            (Options { tol: 0.0, ..o }, "tol = 0"),
            (Options { tol: f64::NAN, ..o }, "tol = NaN"),
            (Options { max_inner: 0, ..o }, "max_inner = 0"),
            (
                Options {
                    ordering: Ordering::Dense,
                    ..o
                },
                "ordering = dense",
            ),
            (
                Options {
                    max_seconds: f64::INFINITY,
                    ..o
                },
                "max_seconds = inf",
            ),
            (Options { threads: 4097, ..o }, "threads = 4097"),
            (
                Options {
                    stall_factor: 0.0,
                    ..o
                },
                "stall_factor = 0",
            ),
        ];
        for (bad, field) in cases {
            for prefix in ["", "opts."] {
                let e = bad.check(prefix).unwrap_err();
                assert_eq!(e.kind, ErrorKind::BadArgument);
                let want = format!("{prefix}{field}");
                assert!(e.message.starts_with(&want), "{} lacks {want}", e.message);
            }
        }
    }
}
