//! The contact problem of one body: K's factor, the contact matrices, the condensed
//! dual, and the history of a quasistatic simulation. This is the safe Rust API that
//! the C boundary wraps.

use crate::compliance::Compliance;
use crate::contact_rows::{check_shapes, stack_rows};
use crate::dual::{Condensation, Dual, Made, Primal};
use crate::error::{ErrorKind, Result, fail};
use crate::factor::Factor;
use crate::friction::Friction;
use crate::history::{History, Increments};
use crate::host::KSolve;
use crate::info::Info;
use crate::load_span::LoadSpan;
use crate::memory::{self, Claim};
use crate::methods::{self, DualProblem, End, Monitor, Progress};
use crate::options::{DualForm, Method, Options};
use crate::plan;
use crate::report::Report;
use crate::report::{SolveStatus, contact_states};
use crate::sizes::Sizes;
use crate::sparse::{Csc, MatrixView, TripletSlots};
use std::sync::Arc;
use std::time::{Duration, Instant};

mod iteration;
mod solve;
mod stiffness;
#[cfg(test)]
pub(crate) mod tests;

pub use iteration::HostIteration;

use stiffness::Stiffness;

/// The result of one solve.
#[derive(Clone, Debug)]
pub struct Solution {
    /// Displacement, length n.
    pub u: Vec<f64>,
    /// Normal contact forces (compressive >= 0), length m.
    pub lambda_n: Vec<f64>,
    /// Tangential contact forces, length (d-1) m, contact by contact.
    pub lambda_t: Vec<f64>,
    /// Error measure, counts, timings, status.
    pub report: Report,
}

/// One contact problem: K factored once, N and T, the condensed dual, and the
/// history of a quasistatic simulation (the accumulated u and the last multipliers).
pub struct ContactProblem {
    d: usize,
    /// K and its factor, or the host's solves.
    stiff: Stiffness,
    n: Csc,
    t: Csc,
    dual: Dual,
    /// The sizes memory predictions are made from.
    sizes: Sizes,
    /// The bytes of K, N and T on the problem's ledger (the factor's).
    inputs: Claim,
    /// `Options::max_memory` at creation: the limit of `refactor` and
    /// `set_contacts`, which take no options.
    max_memory: usize,
    /// The history: u_k, the last converged multipliers and the predictor's
    /// loads.
    history: History,
    /// The interface law of each contact (rigid unless set).
    compliance: Compliance,
    /// The last total loads solved for, with K^-1 or the forward half L^-1 P
    /// of each as the route needs (`load_span`): a step whose load lies in
    /// their span takes its right-hand side from them instead of a solve.
    loads: LoadSpan,
    /// The multipliers of the last converged host iteration (c; empty before
    /// the first), where the next one starts (`iteration.rs`).
    iteration_start: Vec<f64>,
    /// The multipliers of the converged host iteration before that, in the
    /// same increment (empty: none), the other end of the line a later
    /// iteration starts on (`solve::iteration_line`).
    iteration_before: Vec<f64>,
    /// The predictor of a host's increments (`history::Increments`).
    increments: Increments,
    /// What the last `refactor` cost (zero before the first).
    last_refactor: RefactorCost,
    /// Where the matrix-free dual's contact blocks are an earlier K's.
    kept_blocks: Option<KeptBlocks>,
    /// Where a host's COO triplets fell at the last refactor: guesses only,
    /// checked at each use (a refactor that fails after placing them
    /// changes no later result); and the pattern's mirror places, for the
    /// symmetry check of a refill in full storage (COO or CSC).
    coo_slots: TripletSlots,
    /// The values of the factor the last refactor replaced, the next
    /// refactor's storage (`Factor::refactor_into`; empty before the first).
    spare: SpareValues,
}

/// L's values of a replaced factor, with their count on the ledger.
#[derive(Default)]
struct SpareValues {
    values: Vec<f64>,
    _claim: Option<memory::Claim>,
}

/// The most err may grow by a refactor that keeps the contact blocks of an
/// earlier K (`Drift::err_factor`): beyond it they are computed afresh.
/// Computing them costs 0.7-1.4 factorisations; kept ones cost err's
/// scaling (a solve to tol / err_factor on their rho) and a preconditioner
/// a little off. A host's first tangent of an increment drifts 1.7-2.6 from
/// the last increment's blocks on the 3D host example (the geometry moved),
/// the later ones 1.0-1.3 more: at 3 (1.5 before) a refactor there cost
/// 1.12-1.13 factorisations on average instead of 1.31, for 3 % more Krylov
/// products (docs/design.md section 9).
pub(crate) const KEEP_BLOCKS_MAX_ERR_FACTOR: f64 = 3.0;

/// A matrix-free dual's contact blocks computed on an earlier K than the one
/// the problem holds (see [`ContactProblem::refactor`]).
struct KeptBlocks {
    /// The values of the K they were computed on (the pattern is K's).
    k_values: Vec<f64>,
    /// Refactors since they were computed (at least 1).
    refactors: usize,
    /// The drift of the K last refactored from the one they were computed
    /// on: the next refactor composes it with a small step
    /// ([`crate::drift::Drift::then`]).
    drift: crate::drift::Drift,
    /// The bytes of `k_values` on the factor's ledger.
    _claim: memory::Claim,
}

/// What one [`ContactProblem::refactor`] cost, in seconds of wall clock.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct RefactorCost {
    /// The numeric factorisation of the new K (its symbolic analysis reused).
    pub factor_seconds: f64,
    /// The estimate of the contact blocks' drift (a matrix-free dual: see
    /// [`ContactProblem::refactor`]); 0 on a dense dual.
    pub drift_seconds: f64,
    /// Solves with the new K that estimate took.
    pub drift_solves: usize,
    /// Whether the refactor kept the contact blocks of an earlier K.
    pub blocks_kept: bool,
    /// The condensed dual on the new factor: A from the trailing block (a
    /// dense dual) or the contact blocks, the lumped G = B K B^T and the
    /// layered Dirichlet preconditioner (a matrix-free one).
    pub dual_seconds: f64,
}

fn check_vec(name: &str, x: &[f64], len: usize) -> Result<()> {
    if x.len() != len {
        return fail(
            ErrorKind::BadSize,
            format!("{name} has length {}, expected {len}", x.len()),
        );
    }
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return fail(
            ErrorKind::NotFinite,
            format!("{name}[{i}] = {} is not finite", x[i]),
        );
    }
    Ok(())
}

/// d checked, then K (both triangles), N and T converted from the caller's views.
fn internal_form(
    d: usize,
    k: &MatrixView<'_>,
    n: &MatrixView<'_>,
    t: &MatrixView<'_>,
) -> Result<(Csc, Csc, Csc)> {
    plan::check_d(d)?;
    let k = Csc::symmetric_from_view(k, "K")?;
    let n = Csc::from_view(n, "N")?;
    let t = Csc::from_view(t, "T")?;
    Ok((k, n, t))
}

/// Checks matrices a Rust caller gave in internal form: K square, symmetric
/// and in the form's invariants, N and T in them (their shapes against K are
/// checked with the route).
fn check_internal_form(k: &Csc, n: &Csc, t: &Csc) -> Result<()> {
    crate::sparse::check_internal_symmetric(k, "K")?;
    crate::sparse::check_internal(n, "N")?;
    crate::sparse::check_internal(t, "T")
}

/// The dual of (N, T) on `factor` formed in the way `how`, holding the lumped
/// preconditioner G = B K B^T when it is matrix-free, its operator A + D for
/// the compliance diagonal `shift` (empty: rigid): every dual a problem holds
/// is formed here. A matrix-free one takes what `made` holds (a refactor's
/// kept contact blocks and single-precision factor: [`Dual::build_keeping`]).
fn form_dual(
    factor: &Arc<Factor>,
    k: &Csc,
    (n, t): (&Csc, &Csc),
    d: usize,
    (how, made): (Condensation, Made),
    shift: &[f64],
    layer: Option<crate::dirichlet::Plan>,
) -> Result<Dual> {
    let mut dual = Dual::build_keeping(factor, n, t, d, how, made)?;
    dual.set_lumped(k, layer);
    if !shift.is_empty() {
        dual.set_shift(shift);
    }
    Ok(dual)
}

/// The sizes of a dual on the host's solves of (N, T) (`plan::host_sizes`),
/// its layered Dirichlet preconditioner where K is handed over and it pays,
/// and where the contacts' blocks come from the library's own factor of K
/// (`how`, see [`crate::HostBlocks`]) that factor's analysis, its bytes in
/// the sizes' `blocks_work`. `Auto` takes the factor where it pays
/// (`dual::factor_blocks_pay`) and creation with it fits `max_memory`.
///
/// Errors: `BadArgument` (`HostBlocks::Factor` without K).
fn host_setup(
    k: Option<&Csc>,
    (n, t): (&Csc, &Csc),
    d: usize,
    how: crate::HostBlocks,
    (threads, ledger): (&Arc<crate::threads::Threads>, &Arc<memory::Ledger>),
    max_memory: usize,
) -> Result<(Sizes, Option<crate::dirichlet::Plan>, Option<Factor>)> {
    use crate::HostBlocks;
    let b = stack_rows(n, t);
    let mut sizes = plan::host_sizes(k, n, t, d);
    let Some(k) = k else {
        if how == HostBlocks::Factor {
            return fail(
                ErrorKind::BadArgument,
                "the contact blocks by the library's factor of K (HostBlocks::Factor, \
                 DS_HOST_BLOCKS_FACTOR) need K handed over",
            );
        }
        return Ok((sizes, None, None));
    };
    let (layer, analysis) = crate::dual::host_plan(k, &b, d, threads, ledger);
    sizes.dirichlet = layer.as_ref().map_or(0, |p| p.bytes());
    let analysis = match (how, analysis) {
        (HostBlocks::Solves, _) => None,
        (HostBlocks::Factor, Err(e)) => {
            return Err(crate::Error::new(
                e.kind,
                format!(
                    "the contact blocks by the library's factor of K: K's analysis failed: {}",
                    e.message
                ),
            ));
        }
        (_, analysis) => analysis.ok(),
    };
    let Some(analysis) = analysis else {
        return Ok((sizes, layer, None));
    };
    let with_factor = Sizes {
        blocks_work: sizes
            .blocks_work
            .max(crate::dual::factor_blocks_bytes(&analysis, &b, d)),
        ..sizes
    };
    let need = with_factor.setup(Condensation::MatrixFree);
    let fits = memory::limit(max_memory).is_none_or(|limit| need <= limit);
    if how == HostBlocks::Factor || (fits && crate::dual::factor_blocks_pay(&analysis, b.nrows)) {
        Ok((with_factor, layer, Some(analysis)))
    } else {
        Ok((sizes, layer, None))
    }
}

/// The matrix-free dual of (N, T) on the host's solves of `stiff`, with the
/// lumped preconditioner where K was given (and the layered Dirichlet one
/// where it pays: `layer`, its plan where the caller made it for the memory
/// prediction), its operator A + D for `shift`; the contacts' blocks by the
/// library's factor of K where `by_factor` holds its analysis (from
/// [`host_setup`]), else by the host.
fn host_dual(
    stiff: &Stiffness,
    nt: (&Csc, &Csc),
    d: usize,
    shift: &[f64],
    layer: Option<crate::dirichlet::Plan>,
    by_factor: Option<Factor>,
) -> Result<Dual> {
    let Stiffness::Host {
        host,
        k,
        threads,
        ledger,
    } = stiff
    else {
        unreachable!("the host's solves")
    };
    host.clear();
    let by_factor = by_factor.zip(k.as_ref());
    let mut dual = Dual::on_host(host, nt, d, threads.clone(), ledger.clone(), by_factor)?;
    if let Some(k) = k {
        dual.set_lumped(k, layer);
    }
    if !shift.is_empty() {
        dual.set_shift(shift);
    }
    Ok(dual)
}

impl ContactProblem {
    /// A problem on the host's own solver of K (`solver`, see [`KSolve`])
    /// instead of a factor of the library's: N (m x n) and T ((d-1) m x n) as
    /// for [`ContactProblem::new`], n = `solver.n()`, and optionally K itself
    /// (symmetric, any storage), which the problem then uses for the lumped
    /// preconditioner B K B^T of Newton's reduced systems, for K u_k in a
    /// history and for the report's equilibrium residual (without it: Jacobi
    /// on the contacts' diagonal, K u_k = f_total - B^T lambda_k from the last
    /// step's equilibrium, and a NaN residual, not measured).
    ///
    /// The dual is matrix-free: each product with A is one call of the
    /// host's solve; the contacts' d x d diagonal blocks of A are formed here
    /// as `opts.host_blocks` asks ([`crate::HostBlocks`]; `Auto` by default):
    /// from the host's entries of K^-1 where it gives them
    /// ([`KSolve::inverse_entries`], one call), by d m solves, 32 right-hand
    /// sides per call, or by the library's own factor of K, freed before this
    /// returns. The methods that read entries of A (and
    /// `DualForm::Dense`) are refused with `BadArgument`; `refactor` too
    /// (refactor on the host's side and create a new problem), and
    /// `write_folder` without K.
    ///
    /// Errors: `BadArgument` (d, options, `HostBlocks::Factor` without K),
    /// `BadSize` (shapes against n), `BadIndex`, `NotFinite`, `NotSymmetric`
    /// and `NotPositiveDefinite` (K, the latter where it is factored for the
    /// blocks), `HostSolve` (a solve
    /// failed or returned a NaN or infinity while the blocks were formed:
    /// the host's code is in the message), `OutOfMemory`.
    pub fn with_host_solver(
        d: usize,
        solver: Box<dyn KSolve>,
        k: Option<&MatrixView<'_>>,
        n: &MatrixView<'_>,
        t: &MatrixView<'_>,
        opts: &Options,
    ) -> Result<Self> {
        plan::check_d(d)?;
        opts.check("")?;
        if opts.dual_form == DualForm::Dense {
            return fail(
                ErrorKind::BadArgument,
                "dual_form dense: a problem on the host's solver is matrix-free \
                 (dual_form auto or matrix-free)",
            );
        }
        let k = k.map(|k| Csc::symmetric_from_view(k, "K")).transpose()?;
        let n = Csc::from_view(n, "N")?;
        let t = Csc::from_view(t, "T")?;
        let ndof = solver.n();
        if let Some(k) = &k
            && k.nrows != ndof
        {
            return fail(
                ErrorKind::BadSize,
                format!(
                    "K is {0} x {0}, but the host's solver has n = {ndof}",
                    k.nrows
                ),
            );
        }
        check_shapes(ndof, d, &n, &t)?;
        let threads = Arc::new(crate::threads::Threads::new(opts.threads));
        let ledger = memory::Ledger::new();
        let how = opts.host_blocks;
        let (sizes, layer, by_factor) = host_setup(
            k.as_ref(),
            (&n, &t),
            d,
            how,
            (&threads, &ledger),
            opts.max_memory,
        )?;
        memory::check(
            sizes.setup(Condensation::MatrixFree),
            memory::limit(opts.max_memory),
            opts.max_memory,
            "creating a problem on the host's solver",
            "a larger max_memory or a machine with more memory is needed",
        )?;
        let inputs = ledger.claim(sizes.inputs);
        let stiff = Stiffness::Host {
            host: Arc::new(crate::host::Host::new(solver, how)),
            k,
            threads,
            ledger,
        };
        let dual = host_dual(&stiff, (&n, &t), d, &[], layer, by_factor)?;
        let (c, m) = (dual.c, n.nrows);
        Ok(ContactProblem {
            d,
            stiff,
            n,
            t,
            dual,
            sizes,
            inputs,
            max_memory: opts.max_memory,
            history: History::new(ndof, c),
            compliance: Compliance::rigid(m),
            loads: LoadSpan::default(),
            iteration_start: Vec::new(),
            iteration_before: Vec::new(),
            increments: Increments::default(),
            last_refactor: RefactorCost::default(),
            kept_blocks: None,
            coo_slots: TripletSlots::default(),
            spare: SpareValues::default(),
        })
    }

    /// A new dual of (N, T) on this problem's K, formed as `how`, for the
    /// compliance diagonal `shift` (see [`form_dual`]).
    fn new_dual(
        &self,
        nt: (&Csc, &Csc),
        how: Condensation,
        shift: &[f64],
        layer: Option<crate::dirichlet::Plan>,
    ) -> Result<Dual> {
        match &self.stiff {
            Stiffness::Own { k, factor } => {
                form_dual(factor, k, nt, self.d, (how, Made::default()), shift, layer)
            }
            Stiffness::Host { .. } => host_dual(&self.stiff, nt, self.d, shift, layer, None),
        }
    }

    /// Validates K (symmetric, any storage), N (m x n) and T ((d-1) m x n), factors
    /// K and builds the condensed dual, with the default options (see
    /// [`ContactProblem::with_options`]). d must be 2 or 3.
    ///
    /// Errors: `BadArgument` (d), `BadSize` (shapes), `BadIndex`, `NotFinite`,
    /// `NotSymmetric`, `NotPositiveDefinite`, `OutOfMemory`.
    pub fn new(
        d: usize,
        k: &MatrixView<'_>,
        n: &MatrixView<'_>,
        t: &MatrixView<'_>,
    ) -> Result<Self> {
        Self::with_options(d, k, n, t, &Options::default())
    }

    /// As [`ContactProblem::new`], with `opts.ordering` for K's factorisation and
    /// `opts.threads` for the problem's thread pool, which every later call
    /// (refactor, solve, step) uses. The other fields are only checked here.
    ///
    /// Errors: those of `new`, and `BadArgument` for invalid options.
    pub fn with_options(
        d: usize,
        k: &MatrixView<'_>,
        n: &MatrixView<'_>,
        t: &MatrixView<'_>,
        opts: &Options,
    ) -> Result<Self> {
        let (k, n, t) = internal_form(d, k, n, t)?;
        Self::from_checked(d, k, n, t, opts)
    }

    /// As [`ContactProblem::new`], from matrices already in internal form (`k` holds
    /// both triangles; see [`Csc`] for the invariants, which are checked).
    ///
    /// Errors: as [`ContactProblem::new`].
    pub fn from_csc(d: usize, k: Csc, n: Csc, t: Csc) -> Result<Self> {
        Self::from_csc_with(d, k, n, t, &Options::default())
    }

    /// As [`ContactProblem::with_options`], from matrices in internal form
    /// (checked as in [`ContactProblem::from_csc`]).
    ///
    /// Errors: as [`ContactProblem::with_options`].
    pub fn from_csc_with(d: usize, k: Csc, n: Csc, t: Csc, opts: &Options) -> Result<Self> {
        check_internal_form(&k, &n, &t)?;
        Self::from_checked(d, k, n, t, opts)
    }

    /// [`ContactProblem::from_csc_with`] from matrices known to keep the
    /// internal form's invariants.
    fn from_checked(d: usize, k: Csc, n: Csc, t: Csc, opts: &Options) -> Result<Self> {
        let (mut factor, plan) = plan::analysed(d, &k, &n, &t, opts)?;
        let inputs = factor.ledger().claim(plan.sizes.inputs);
        factor.refactor(&k)?;
        let factor = Arc::new(factor);
        let how = Dual::condensation_for(&factor, &n, &t, d, plan.form);
        let dual = form_dual(
            &factor,
            &k,
            (&n, &t),
            d,
            (how, Made::default()),
            &[],
            plan.layer,
        )?;
        let ndof = k.nrows;
        let c = dual.c;
        let m = n.nrows;
        Ok(ContactProblem {
            d,
            stiff: Stiffness::Own { k, factor },
            n,
            t,
            dual,
            sizes: plan.sizes,
            inputs,
            max_memory: opts.max_memory,
            history: History::new(ndof, c),
            compliance: Compliance::rigid(m),
            loads: LoadSpan::default(),
            iteration_start: Vec::new(),
            iteration_before: Vec::new(),
            increments: Increments::default(),
            last_refactor: RefactorCost::default(),
            kept_blocks: None,
            coo_slots: TripletSlots::default(),
            spare: SpareValues::default(),
        })
    }

    /// The analysis of a problem with these matrices and options, without any
    /// numeric work: validation, the ordering and the symbolic factorisation of
    /// K, the route `opts` leads to and its predicted memory (MUMPS's JOB = 1).
    /// `opts.method` is the method whose solve memory is predicted.
    ///
    /// Errors: as [`ContactProblem::with_options`] before the factorisation
    /// (`BadArgument`, `BadSize`, `BadIndex`, `NotFinite`, `NotSymmetric`, and
    /// `OutOfMemory` when the analysis itself does not fit). A route that does
    /// not fit the memory limit is not an error here: compare the predictions
    /// with `Info::memory_limit`.
    pub fn analyse(
        d: usize,
        k: &MatrixView<'_>,
        n: &MatrixView<'_>,
        t: &MatrixView<'_>,
        opts: &Options,
    ) -> Result<Info> {
        let (k, n, t) = internal_form(d, k, n, t)?;
        Self::analyse_checked(d, &k, &n, &t, opts)
    }

    /// As [`ContactProblem::analyse`], from matrices in internal form (`k` holds
    /// both triangles; checked as in [`ContactProblem::from_csc`]).
    ///
    /// Errors: as [`ContactProblem::analyse`].
    pub fn analyse_csc(d: usize, k: &Csc, n: &Csc, t: &Csc, opts: &Options) -> Result<Info> {
        check_internal_form(k, n, t)?;
        Self::analyse_checked(d, k, n, t, opts)
    }

    /// [`ContactProblem::analyse_csc`] from matrices known to keep the internal
    /// form's invariants.
    fn analyse_checked(d: usize, k: &Csc, n: &Csc, t: &Csc, opts: &Options) -> Result<Info> {
        let (factor, plan, limit) = plan::route(d, k, n, t, opts)?;
        let now = Condensation::of(true, plan.form, plan.sizes.c);
        Ok(plan::info_of(
            d,
            k,
            n,
            &factor,
            &plan.sizes,
            now,
            true,
            opts,
            limit,
        ))
    }

    /// The analysis of this problem as it is now ([`ContactProblem::analyse`]),
    /// with the solve memory predicted for `opts.method` and `opts.dual_form`.
    pub fn info(&self, opts: &Options) -> Info {
        let limit = memory::limit(opts.max_memory);
        let now = self.dual.condensation;
        let base = match &self.stiff {
            Stiffness::Own { k, factor } => {
                let trailing = Dual::trailing_available(factor, &self.n, &self.t);
                plan::info_of(
                    self.d,
                    k,
                    &self.n,
                    factor,
                    &self.sizes,
                    now,
                    trailing,
                    opts,
                    limit,
                )
            }
            Stiffness::Host { k, .. } => {
                plan::host_info(self.d, k.as_ref(), &self.n, &self.sizes, opts, limit)
            }
        };
        Info {
            compliant_contacts: self.compliant_contacts(),
            power_law_contacts: self.compliance.nonlinear().len(),
            blocks_age: self.kept_blocks.as_ref().map_or(0, |b| b.refactors),
            err_factor: self.dual.err_factor,
            ..base
        }
    }

    /// Refactors K with new values and the same sparsity pattern (same storage);
    /// rebuilds the condensed dual. On error the problem is unchanged.
    ///
    /// A matrix-free dual on the library's factor keeps its contact blocks
    /// (those of the K they were computed on) where their drift, the spectrum
    /// of K^-1 (K - K_then) estimated by at most 8 Lanczos steps
    /// (`drift.rs`), bounds err's growth by at most 3 (an estimate, not a
    /// certified bound): err is then multiplied by that estimated bound
    /// ([`Info::err_factor`], [`Info::blocks_age`]); else they are computed
    /// afresh. Where the last refactor kept them too and K moved by at most
    /// 1 % from that refactor's K, the step from it is estimated in 2
    /// Lanczos steps and composed with that refactor's drift where it is
    /// small (`Drift::then`); a step tried and not taken adds its 2 solves
    /// to the full estimate's (10 at most).
    ///
    /// The replaced factor's values stay on the problem as the next
    /// refactor's storage ([`Info::resident_bytes`] counts them,
    /// [`Info::refactor_bytes`] does not grow): it factors into memory the
    /// process already has, not into new pages the system faults in and
    /// zeroes first. A refactor that fails keeps them; a solve or
    /// `set_contacts` that fits its `max_memory` only without them frees
    /// them.
    ///
    /// Errors: those of `new`, and `BadArgument` if the pattern differs.
    pub fn refactor(&mut self, k: &MatrixView<'_>) -> Result<()> {
        let Stiffness::Own { factor, k: old_k } = &self.stiff else {
            return fail(
                ErrorKind::BadArgument,
                "this problem solves with the host's solver of K: refactor K on the \
                 host's side and create a new problem",
            );
        };
        let factor = factor.clone();
        // A host's COO tangent on the pattern the handle holds is placed
        // triplet by triplet, a CSC one on it copied; anything else is
        // converted in full.
        let refilled = old_k.refill_symmetric(k, &mut self.coo_slots, factor.ledger());
        // The slots the refill made or kept stay held, whatever follows.
        self.sizes.slots = self.coo_slots.held_bytes();
        if self.coo_slots.has_mirrors() {
            self.sizes.mirrors_to_make = 0;
        }
        let k = match refilled {
            Some(k) => k,
            None => Csc::symmetric_from_view(k, "K")?,
        };
        if !factor.same_pattern(&k) {
            return fail(
                ErrorKind::BadArgument,
                "K: the sparsity pattern differs from the one the problem was created with",
            );
        }
        // The refill above made whatever mirror places this refactor makes
        // (counted in the slots): none are still to come in this one.
        let now = Sizes {
            mirrors_to_make: 0,
            ..self.sizes
        };
        memory::check(
            now.refactor(self.dual.condensation, k.bytes(), self.threads()),
            memory::limit(self.max_memory),
            self.max_memory,
            "refactoring K (the old and the new factor are held at once)",
            "the problem's max_memory (set at creation) must allow for it; see the \
             refactor bytes of ds_problem_info",
        )?;
        // The new factor and dual are formed beside the old ones, which stay in
        // place until both succeeded.
        let start = Instant::now();
        let mut fresh = factor.unfactored_copy();
        // The spare's storage becomes the new factor's (the factor counts it
        // on the ledger); a refactor that fails gives it back.
        let SpareValues { mut values, .. } = std::mem::take(&mut self.spare);
        let spare_bytes = std::mem::take(&mut self.sizes.spare);
        if let Err(e) = fresh.refactor_into(&k, &mut values) {
            let claim = fresh.ledger().claim_f64(values.len());
            self.keep_spare(values, Some(claim), spare_bytes);
            return Err(e);
        }
        drop(values);
        let fresh = Arc::new(fresh);
        let factored = Instant::now();
        let how = Dual::condensation_for(&fresh, &self.n, &self.t, self.d, self.current_form());
        let shift = self.compliance.shift(self.d);
        // A matrix-free dual's single-precision copy of the factor, made
        // first: the drift's solves run on it. It is written into the old
        // dual's copy where that has its length (see `Dual::lend_single`:
        // the old dual stays whole if what follows fails).
        let single = match how {
            Condensation::MatrixFree if !fresh.is_dense() => {
                let lent = self.dual.lend_single().unwrap_or_default();
                match fresh.single_values_in(lent) {
                    Ok(single) => Some(single),
                    Err(e) => {
                        self.give_back(fresh, spare_bytes);
                        return Err(e);
                    }
                }
            }
            _ => None,
        };
        let copied = Instant::now();
        let kept = single
            .as_ref()
            .and_then(|single| self.weigh_kept_blocks(how, (&fresh, single), old_k, &k));
        let weighed = Instant::now();
        let (blocks, kept) = match kept {
            Some((blocks, drift)) => (Some(blocks), Some(drift)),
            None => (None, None),
        };
        // The layered preconditioner's face, layers and analyses serve the
        // new K as they are (the same pattern, the same B).
        let layer = match how {
            Condensation::MatrixFree => self.dual.renewed_layer(&k),
            _ => None,
        };
        let dual = form_dual(
            &fresh,
            &k,
            (&self.n, &self.t),
            self.d,
            (how, Made { blocks, single }),
            &shift,
            layer,
        );
        let mut dual = match dual {
            Ok(dual) => dual,
            Err(e) => {
                self.give_back(fresh, spare_bytes);
                return Err(e);
            }
        };
        self.last_refactor = RefactorCost {
            factor_seconds: (factored - start).as_secs_f64(),
            drift_seconds: (weighed - copied).as_secs_f64(),
            dual_seconds: (copied - factored).as_secs_f64() + weighed.elapsed().as_secs_f64(),
            drift_solves: kept.map_or(0, |d| d.solves),
            blocks_kept: kept.is_some(),
        };
        self.kept_blocks = match (kept, self.kept_blocks.take()) {
            (Some(drift), before) => {
                dual.set_err_factor(drift.err_factor());
                // The K the blocks were computed on: the one replaced, or
                // the one an earlier refactor kept them from.
                Some(match before {
                    Some(kept) => KeptBlocks {
                        refactors: kept.refactors + 1,
                        drift,
                        ..kept
                    },
                    None => KeptBlocks {
                        _claim: fresh.ledger().claim_f64(old_k.values.len()),
                        k_values: old_k.values.clone(),
                        refactors: 1,
                        drift,
                    },
                })
            }
            (None, _) => None,
        };
        let fresh_bytes = fresh.values_bytes();
        self.dual = dual;
        self.stiff = Stiffness::Own { k, factor: fresh };
        // The replaced factor's values become the next refactor's storage
        // where nothing else holds that factor any more.
        if let Ok(old) = Arc::try_unwrap(factor) {
            let (values, claim) = old.into_values();
            self.keep_spare(values, claim, fresh_bytes);
        }
        self.history.forget_loads();
        self.history.lu = None;
        self.loads.clear();
        Ok(())
    }

    /// Keeps `values` (counted by `claim`) as the next refactor's storage
    /// where they have `bytes`, the length of L's values (0: none to keep).
    fn keep_spare(&mut self, values: Vec<f64>, claim: Option<memory::Claim>, bytes: usize) {
        if bytes > 0 && values.len() * std::mem::size_of::<f64>() == bytes {
            self.sizes.spare = bytes;
            self.spare = SpareValues {
                values,
                _claim: claim,
            };
        }
    }

    /// The spare's storage (`bytes`; 0 where none was held) back from the
    /// factor `fresh` of a refactor that failed after its factorisation,
    /// where nothing else holds that factor: the handle holds what it held
    /// before the refactor.
    fn give_back(&mut self, fresh: Arc<Factor>, bytes: usize) {
        if let Ok(fresh) = Arc::try_unwrap(fresh) {
            let (values, claim) = fresh.into_values();
            self.keep_spare(values, claim, bytes);
        }
    }

    /// The bytes `need` predicts for the work about to start, where the
    /// storage the last refactor kept for the next one (`spare`) gives way
    /// to it: freed where the prediction with it held exceeds `limit` and
    /// the one without it does not (the next refactor then allocates its
    /// own again); kept otherwise, whether or not the work then fits.
    fn spare_gives_way(&mut self, need: impl Fn(&Sizes) -> usize, limit: Option<usize>) -> usize {
        let held = need(&self.sizes);
        let without = need(&Sizes {
            spare: 0,
            ..self.sizes
        });
        if self.sizes.spare > 0 && limit.is_some_and(|l| held > l && without <= l) {
            self.spare = SpareValues::default();
            self.sizes.spare = 0;
            return without;
        }
        held
    }

    /// Whether a refactor onto `k` (factored in `fresh`; `old_k` the K it
    /// replaces) keeps the matrix-free dual's contact blocks: where the dual
    /// stays matrix-free on the library's own factor and the blocks' drift
    /// from the K they were computed on (`drift.rs`) bounds err's growth by
    /// at most [`KEEP_BLOCKS_MAX_ERR_FACTOR`]: the blocks and the drift. None:
    /// the blocks are computed afresh.
    fn weigh_kept_blocks(
        &self,
        how: Condensation,
        (fresh, single): (&Factor, &[f32]),
        old_k: &Csc,
        k: &Csc,
    ) -> Option<(Vec<f64>, crate::drift::Drift)> {
        if how != Condensation::MatrixFree {
            return None;
        }
        // None unless the dual held is matrix-free on the library's factor.
        let blocks = self.dual.own_blocks()?;
        if old_k.col_ptr != k.col_ptr || old_k.row_idx != k.row_idx {
            return None;
        }
        // Where the blocks were kept by the last refactor too, its drift is
        // known: a small step from the K it left (a host's Newton loop
        // settling) is estimated in two solves and composed with it, else
        // the drift from the blocks' K is estimated afresh.
        let mut spent = 0;
        if let Some(kept) = &self.kept_blocks
            && let Some(step) = crate::drift::step_drift(fresh, single, k, &old_k.values)
        {
            spent = step.solves;
            let drift = kept.drift.then(&step);
            if step.is_small() && drift.err_factor() <= KEEP_BLOCKS_MAX_ERR_FACTOR {
                return Some((blocks.to_vec(), drift));
            }
        }
        let values = match &self.kept_blocks {
            Some(kept) => &kept.k_values,
            None => &old_k.values,
        };
        let mut drift = crate::drift::drift(fresh, single, k, values, KEEP_BLOCKS_MAX_ERR_FACTOR);
        // The solves of a step tried and not taken count too (reported
        // where the blocks are kept; a refactor that drops them reports
        // none).
        drift.solves += spent;
        (drift.err_factor() <= KEEP_BLOCKS_MAX_ERR_FACTOR).then(|| (blocks.to_vec(), drift))
    }

    /// Replaces N and T (m may change) without refactoring K; rebuilds the condensed
    /// dual in the form the handle holds (dense or matrix-free: the form is kept,
    /// whatever c becomes). The warm start is kept when m is unchanged. On error the
    /// problem is unchanged.
    pub fn set_contacts(&mut self, n: &MatrixView<'_>, t: &MatrixView<'_>) -> Result<()> {
        let n = Csc::from_view(n, "N")?;
        let t = Csc::from_view(t, "T")?;
        check_shapes(self.n_dofs(), self.d, &n, &t)?;
        let b = stack_rows(&n, &t);
        let mut by_factor = None;
        let (next, how, layer) = match &self.stiff {
            Stiffness::Own { k, factor } => {
                let layer = crate::dirichlet::layer_of(k, &b, factor);
                let next = Sizes {
                    c: self.d * n.nrows,
                    inputs: k.bytes() + n.bytes() + t.bytes(),
                    blocks_work: crate::factor_tree::contact_blocks::work_bytes(
                        factor, &b, n.nrows, self.d,
                    ),
                    lumped: crate::sparse::congruence_bytes(k, &b, &b.transpose()),
                    own_solves: crate::dual::own_solves_bytes(factor, &b),
                    dirichlet: layer.as_ref().map_or(0, |p| p.bytes()),
                    ..self.sizes
                };
                // The handle keeps its form (dense or matrix-free), as
                // `refactor` does.
                let form = self.current_form();
                let how = Dual::condensation_for(factor, &n, &t, self.d, form);
                (next, how, layer)
            }
            Stiffness::Host {
                host,
                k,
                threads,
                ledger,
            } => {
                let (next, layer, analysis) = host_setup(
                    k.as_ref(),
                    (&n, &t),
                    self.d,
                    host.blocks(),
                    (threads, ledger),
                    self.max_memory,
                )?;
                by_factor = analysis;
                (next, Condensation::MatrixFree, layer)
            }
        };
        let (now, nt_bytes) = (self.dual.condensation, n.bytes() + t.bytes());
        let limit = memory::limit(self.max_memory);
        let need = self.spare_gives_way(|s| s.replace_contacts(now, nt_bytes, &next, how), limit);
        // (The spare, where it gave way, is no longer held after either.)
        let next = Sizes {
            spare: self.sizes.spare,
            ..next
        };
        memory::check(
            need,
            memory::limit(self.max_memory),
            self.max_memory,
            "replacing N and T (the new dual is formed beside the old one)",
            "the problem's max_memory (set at creation) must allow for it",
        )?;
        // Per-contact interface data follow the contacts when m is unchanged;
        // a new m makes every contact rigid.
        let m = n.nrows;
        let compliance = if m == self.n_contacts() {
            self.compliance.clone()
        } else {
            Compliance::rigid(m)
        };
        let shift = compliance.shift(self.d);
        let dual = match &self.stiff {
            Stiffness::Host { .. } => {
                host_dual(&self.stiff, (&n, &t), self.d, &shift, layer, by_factor)?
            }
            Stiffness::Own { k, factor } => {
                // The factor's single-precision copy serves the new dual as
                // it is (see `Dual::lend_single`).
                let single = match how {
                    Condensation::MatrixFree => self.dual.lend_single_of(factor),
                    _ => None,
                };
                let made = Made {
                    single,
                    blocks: None,
                };
                form_dual(factor, k, (&n, &t), self.d, (how, made), &shift, layer)?
            }
        };
        self.history.new_contacts(dual.c);
        if self.iteration_start.len() != dual.c {
            self.iteration_start.clear();
        }
        self.iteration_before.clear();
        self.increments.forget();
        self.compliance = compliance;
        self.sizes = next;
        self.inputs.resize(self.sizes.inputs);
        self.dual = dual;
        self.kept_blocks = None;
        self.n = n;
        self.t = t;
        Ok(())
    }

    /// Sets the interface law of every contact (docs/design.md section 8),
    /// kept on the handle until changed (a change of m by `set_contacts`
    /// makes every contact rigid again). Per contact i, each array of length m
    /// or None for its default:
    ///
    /// - `cn`: normal compliance c_N,i > 0, lambda_N,i = c_N,i (N u - g)_i+
    ///   (force / length; the caller folds the nodal area in, as for every
    ///   nodal force); +inf (the default) is Signorini's rigid law;
    /// - `mn`: its exponent, 1 <= m_N,i <= 10 (default 1): lambda_N,i =
    ///   c_N,i (N u - g)_i+^m_N,i (c_N in force / length^m_N); above 1 a solve
    ///   runs Newton on the law, each round a solve of its tangent's linear
    ///   law, until the nonlinear law's err meets the tolerance;
    /// - `kt`: tangential stiffness k_T,i > 0 (force / length), the elastic
    ///   slip of penalty codes: lambda_T,i is the projection onto the friction
    ///   disc of lambda_T,prev + k_T,i T u, lambda_T,prev zero in a single
    ///   solve and the last step's force in a history; +inf (the default) is
    ///   rigid stick.
    ///
    /// In a history what carries over is the elastic slip lambda_T / k_T:
    /// where k_T,i changes the next step starts from the force scaled by
    /// k_T,new / k_T,old (from zero where either is +inf). Mixing rigid and
    /// compliant contacts is allowed. Every method solves the compliant law
    /// (its dual operator is A + D, `compliance.rs`). The history's predictor
    /// forgets its loads (they were those of the old A + D); u_k and the
    /// multipliers stay as the warm start.
    ///
    /// Errors (the handle keeps its previous law): `BadSize` (a length is not
    /// m), `NotFinite` (NaN, -inf, an infinite m_N), `BadArgument` (c_N <= 0,
    /// m_N outside [1, 10], k_T <= 0, a c_N or k_T whose reciprocal
    /// overflows).
    pub fn set_compliance(
        &mut self,
        cn: Option<&[f64]>,
        mn: Option<&[f64]>,
        kt: Option<&[f64]>,
    ) -> Result<()> {
        let law = Compliance::of(self.n_contacts(), cn, mn, kt)?;
        if !self.history.lt.is_empty() {
            self.compliance.carry(&law, &mut self.history.lt, self.d);
        }
        self.dual.set_shift(&law.shift(self.d));
        // The predictors' loads were those of the old A + D.
        self.history.forget_loads();
        self.increments.forget();
        self.iteration_before.clear();
        self.compliance = law;
        Ok(())
    }

    /// The number of contacts with a compliant law (finite c_N or k_T).
    pub fn compliant_contacts(&self) -> usize {
        self.compliance.compliant_count()
    }

    /// The checks every solve, step and dump makes of its data before any
    /// work: the load (length n) and the gap (length m), named as the caller
    /// names them, and the friction data.
    fn check_data(
        &self,
        (f_name, f): (&str, &[f64]),
        (g_name, g): (&str, &[f64]),
        friction: Friction<'_>,
    ) -> Result<()> {
        check_vec(f_name, f, self.n_dofs())?;
        check_vec(g_name, g, self.n_contacts())?;
        self.check_friction(friction)
    }

    fn check_friction(&self, friction: Friction<'_>) -> Result<()> {
        let m = self.n_contacts();
        let (name, x) = match friction {
            Friction::Tresca(p) => ("p", p),
            Friction::Coulomb(mu) => ("mu", mu),
        };
        check_vec(name, x, m)?;
        if let Some(i) = x.iter().position(|&v| v < 0.0) {
            return fail(
                ErrorKind::NegativeFriction,
                format!("{name}[{i}] = {} is negative", x[i]),
            );
        }
        Ok(())
    }

    /// The form the dual operator has now (`Dense` or `MatrixFree`).
    fn current_form(&self) -> DualForm {
        if self.dual.is_matrix_free() {
            DualForm::MatrixFree
        } else {
            DualForm::Dense
        }
    }

    /// The number of threads the problem's pool has (1: no pool, the calling
    /// thread only).
    pub fn threads(&self) -> usize {
        self.stiff.threads().count()
    }

    /// Solves one increment exactly as given (docs/design.md section 1): f (n), g (m),
    /// and the friction bound. Does not touch the history.
    ///
    /// Errors: `BadSize`, `NotFinite`, `NegativeFriction`, `BadArgument` (options).
    /// Non-convergence is not an error here: it is `report.status`.
    pub fn solve(
        &mut self,
        f: &[f64],
        g: &[f64],
        friction: Friction<'_>,
        opts: &Options,
    ) -> Result<Solution> {
        self.solve_monitored(f, g, friction, opts, None)
    }

    /// As [`ContactProblem::solve`], calling `monitor` after every outer iteration;
    /// when it returns false the solve stops with `SolveStatus::Stopped` and the
    /// last iterate.
    pub fn solve_monitored(
        &mut self,
        f: &[f64],
        g: &[f64],
        friction: Friction<'_>,
        opts: &Options,
        monitor: Option<Monitor<'_>>,
    ) -> Result<Solution> {
        self.solve_history_increment(f, g, friction, None, opts, monitor)
    }

    /// As [`ContactProblem::solve_monitored`], with the tangential force the
    /// return mapping of the elastic slip starts from (`lt_prev`, (d - 1) m,
    /// one value per row of T; None for zero, as in a single solve): replays
    /// one increment of a compliant history on its own (docs/design.md
    /// section 8; a problem folder's `lt_prev.txt`). It acts only on contacts
    /// with a finite k_T ([`ContactProblem::set_compliance`]).
    ///
    /// Errors: those of `solve`, and `BadSize` / `NotFinite` for `lt_prev`.
    pub fn solve_history_increment(
        &mut self,
        f: &[f64],
        g: &[f64],
        friction: Friction<'_>,
        lt_prev: Option<&[f64]>,
        opts: &Options,
        monitor: Option<Monitor<'_>>,
    ) -> Result<Solution> {
        self.check_data(("f", f), ("g", g), friction)?;
        opts.check("")?;
        if let Some(lt) = lt_prev {
            check_vec("lt_prev", lt, (self.d - 1) * self.n_contacts())?;
        }
        let predicted = self.prepare_dual(opts)?;
        let mut lam = vec![0.0; self.dual.c];
        let lt = lt_prev.unwrap_or(&[]);
        let solve::Solved { sol, .. } = self.solve_from(
            (f, f),
            g,
            friction,
            opts,
            &mut lam,
            (solve::Warm::Given, lt),
            monitor,
            predicted,
        )?;
        Ok(sol)
    }

    /// The name of [`ContactProblem::solve_history_increment`] before 0.10.
    #[deprecated(since = "0.10.0", note = "renamed solve_history_increment")]
    pub fn solve_from_force(
        &mut self,
        f: &[f64],
        g: &[f64],
        friction: Friction<'_>,
        lt_prev: Option<&[f64]>,
        opts: &Options,
        monitor: Option<Monitor<'_>>,
    ) -> Result<Solution> {
        self.solve_history_increment(f, g, friction, lt_prev, opts, monitor)
    }

    /// One step of a quasistatic history (docs/design.md section 1): with the held u_k,
    /// solves the increment with f := f_total - K u_k, g := g0 - N u_k, friction on
    /// the tangential increment, warm-started from the last multipliers; returns
    /// u_k+1 = u_k + du and the total multipliers. The history advances only when
    /// the solve converged.
    ///
    /// Errors: as [`ContactProblem::solve`].
    pub fn step(
        &mut self,
        f_total: &[f64],
        g0: &[f64],
        friction: Friction<'_>,
        opts: &Options,
    ) -> Result<Solution> {
        self.step_monitored(f_total, g0, friction, opts, None)
    }

    /// As [`ContactProblem::step`], with a monitor as in
    /// [`ContactProblem::solve_monitored`]. A stopped step does not advance the
    /// history.
    pub fn step_monitored(
        &mut self,
        f_total: &[f64],
        g0: &[f64],
        friction: Friction<'_>,
        opts: &Options,
        monitor: Option<Monitor<'_>>,
    ) -> Result<Solution> {
        self.check_data(("f_total", f_total), ("g0", g0), friction)?;
        opts.check("")?;
        let (ndof, m) = (self.n_dofs(), self.n_contacts());
        let predicted = self.prepare_dual(opts)?;
        // The effective f and K u_k.
        let _vectors = self.stiff.ledger().claim_f64(2 * ndof);
        // K u_k: by K where the problem holds it, else the sum of the
        // right-hand sides u_k was solved from (`History::ku`).
        let mut ku = vec![0.0; ndof];
        match self.stiff.k() {
            Some(k) => k.mul_vec(&self.history.u, &mut ku),
            None => ku.copy_from_slice(&self.history.ku),
        }
        let f: Vec<f64> = (0..ndof).map(|i| f_total[i] - ku[i]).collect();
        let mut nu = vec![0.0; m];
        self.n.mul_vec(&self.history.u, &mut nu);
        let g: Vec<f64> = (0..m).map(|i| g0[i] - nu[i]).collect();
        let mut lam = vec![0.0; self.dual.c];
        // The history is lent to the solve (which needs the handle mutable:
        // a nonlinear law changes the dual's diagonal) and put back after,
        // also when the solve panics (a monitor's or a `KSolve`'s panic, or a
        // bug), so that the handle keeps its history and stays usable.
        let history = std::mem::replace(&mut self.history, History::new(0, 0));
        let solved = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let hist = (solve::Warm::History(&history), &history.lt[..]);
            self.solve_from(
                (&f, f_total),
                &g,
                friction,
                opts,
                &mut lam,
                hist,
                monitor,
                predicted,
            )
        }));
        self.history = history;
        let solved = solved.unwrap_or_else(|payload| std::panic::resume_unwind(payload));
        let solve::Solved {
            mut sol,
            load,
            forward,
            alam,
        } = solved?;
        for (ui, uh) in sol.u.iter_mut().zip(&self.history.u) {
            *ui += uh;
        }
        if sol.report.status == SolveStatus::Converged {
            let load = load.expect("a step's load");
            self.history.advance(&sol.u, &lam, load, forward, alam);
            self.history.lt = lam[m..].to_vec();
            if self.stiff.k().is_none() {
                // K u_k+1 = f_total - B^T lambda_k+1 (the step's equilibrium).
                self.dual.rows.mul_t_vec(&lam, &mut self.history.ku);
                for (ku, f) in self.history.ku.iter_mut().zip(f_total) {
                    *ku = f - *ku;
                }
            }
        }
        Ok(sol)
    }

    /// What the last [`ContactProblem::refactor`] cost (zero before the
    /// first).
    pub fn last_refactor(&self) -> RefactorCost {
        self.last_refactor
    }

    /// Forgets the history: u_0 = 0 and no warm start, for steps and host
    /// iterations alike.
    pub fn reset_history(&mut self) {
        self.history.reset();
        self.iteration_start.clear();
        self.iteration_before.clear();
        self.increments.forget();
    }

    /// Contact dimension d (2 or 3).
    pub fn dim(&self) -> usize {
        self.d
    }

    /// Number of DOFs n.
    pub fn n_dofs(&self) -> usize {
        self.stiff.n()
    }

    /// Number of contacts m.
    pub fn n_contacts(&self) -> usize {
        self.n.nrows
    }

    /// Writes this problem with one increment's f (n), g (m) and friction data to the
    /// problem folder `dir` (created if needed; see [`crate::mtx`]), so that the
    /// increment can be replayed with the `dualsplit` command line. For a history
    /// step, pass the increment's effective data (f_total - K u_k, g0 - N u_k); the
    /// warm start is not part of a folder. A compliant law
    /// ([`ContactProblem::set_compliance`]) is: `cn.txt`, `mn.txt`, `kt.txt`,
    /// and in a history the force the next step's return mapping starts from,
    /// `lt_prev.txt` (replayed by [`ContactProblem::solve_history_increment`]); a
    /// rigid one removes those files.
    ///
    /// Errors: `BadSize`, `NotFinite`, `NegativeFriction` (checked as in
    /// [`ContactProblem::solve`]), `Io` (the folder cannot be written).
    pub fn write_folder(
        &self,
        dir: &std::path::Path,
        f: &[f64],
        g: &[f64],
        friction: Friction<'_>,
    ) -> Result<()> {
        self.check_data(("f", f), ("g", g), friction)?;
        let Some(k) = self.stiff.k() else {
            return fail(
                ErrorKind::BadArgument,
                "this problem solves with the host's solver and was given no K: \
                 a problem folder needs K",
            );
        };
        crate::mtx::write_problem(dir, self.d, k, &self.n, &self.t, f, g, friction)?;
        crate::mtx::write_interface(dir, &self.interface())
    }

    /// The handle's interface law as a problem folder holds it (None for
    /// every array when all contacts are rigid), with the force the next
    /// step's return mapping starts from (`lt_prev`) where a compliant
    /// history has one.
    pub(crate) fn interface(&self) -> crate::mtx::Interface {
        let law = &self.compliance;
        if law.is_rigid() {
            return crate::mtx::Interface::default();
        }
        let lt = &self.history.lt;
        crate::mtx::Interface {
            cn: Some(law.cn.clone()),
            mn: Some(law.mn.clone()),
            kt: Some(law.kt.clone()),
            lt_prev: (!lt.is_empty() && lt.iter().any(|&v| v != 0.0)).then(|| lt.clone()),
        }
    }

    /// Number of dual unknowns c = d m: the size of the condensed dual operator
    /// A = B K^-1 B^T (an increment without friction works on its leading m x m
    /// block; `Report::dual_unknowns` says what a solve used).
    pub fn dual_unknowns(&self) -> usize {
        self.dual.c
    }

    /// Whether the condensed dual operator is applied without being formed
    /// (`DualForm::MatrixFree`, or `Auto` above its size limit).
    pub fn is_matrix_free(&self) -> bool {
        self.dual.is_matrix_free()
    }

    /// The condensed dual operator (feature `internals`: benchmark and tests).
    #[cfg(any(test, feature = "internals"))]
    #[doc(hidden)]
    pub fn dual(&self) -> &Dual {
        &self.dual
    }

    /// The Cholesky factor of K, contact DOFs last (feature `internals`).
    #[cfg(any(test, feature = "internals"))]
    #[doc(hidden)]
    pub fn factor(&self) -> &Factor {
        self.stiff.factor().expect("the library's own factor")
    }
}
