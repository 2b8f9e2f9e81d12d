//! The contact problem of one body: K's factor, the contact matrices, the condensed
//! dual, and the history of a quasistatic simulation. This is the safe Rust API that
//! the C boundary wraps.

use crate::compliance::Compliance;
use crate::contact_rows::{check_shapes, stack_rows};
use crate::dual::{Condensation, Dual};
use crate::error::{ErrorKind, Result, fail};
use crate::factor::Factor;
use crate::friction::Friction;
use crate::history::History;
use crate::info::Info;
use crate::memory::{self, Claim};
use crate::methods::{self, DualProblem, End, Monitor, Progress};
use crate::options::{DualForm, Method, Options};
use crate::plan;
use crate::report::Report;
use crate::report::{SolveStatus, contact_states, natural_map_error};
use crate::sizes::Sizes;
use crate::sparse::{Csc, MatrixView};
use std::sync::Arc;
use std::time::{Duration, Instant};

mod solve;

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
    k: Csc,
    n: Csc,
    t: Csc,
    /// K's factor, shared with a matrix-free dual (which solves with it).
    factor: Arc<Factor>,
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
/// is formed here.
fn form_dual(
    factor: &Arc<Factor>,
    k: &Csc,
    (n, t): (&Csc, &Csc),
    d: usize,
    how: Condensation,
    shift: &[f64],
    layer: Option<crate::dirichlet::Plan>,
) -> Result<Dual> {
    let mut dual = Dual::build_with(factor, n, t, d, how)?;
    dual.set_lumped(k, layer);
    if !shift.is_empty() {
        dual.set_shift(shift);
    }
    Ok(dual)
}

impl ContactProblem {
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
        let dual = form_dual(&factor, &k, (&n, &t), d, how, &[], plan.layer)?;
        let ndof = k.nrows;
        let c = dual.c;
        let m = n.nrows;
        Ok(ContactProblem {
            d,
            k,
            n,
            t,
            factor,
            dual,
            sizes: plan.sizes,
            inputs,
            max_memory: opts.max_memory,
            history: History::new(ndof, c),
            compliance: Compliance::rigid(m),
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
        let trailing = Dual::trailing_available(&self.factor, &self.n, &self.t);
        Info {
            compliant_contacts: self.compliant_contacts(),
            power_law_contacts: self.compliance.nonlinear().len(),
            ..plan::info_of(
                self.d,
                &self.k,
                &self.n,
                &self.factor,
                &self.sizes,
                now,
                trailing,
                opts,
                limit,
            )
        }
    }

    /// Refactors K with new values and the same sparsity pattern (same storage);
    /// rebuilds the condensed dual. On error the problem is unchanged.
    ///
    /// Errors: those of `new`, and `BadArgument` if the pattern differs.
    pub fn refactor(&mut self, k: &MatrixView<'_>) -> Result<()> {
        let k = Csc::symmetric_from_view(k, "K")?;
        if !self.factor.same_pattern(&k) {
            return fail(
                ErrorKind::BadArgument,
                "K: the sparsity pattern differs from the one the problem was created with",
            );
        }
        memory::check(
            self.sizes.refactor(self.dual.condensation, k.bytes()),
            memory::limit(self.max_memory),
            self.max_memory,
            "refactoring K (the old and the new factor are held at once)",
            "the problem's max_memory (set at creation) must allow for it; see the \
             refactor bytes of ds_problem_info",
        )?;
        // The new factor and dual are formed beside the old ones, which stay in
        // place until both succeeded.
        let mut fresh = self.factor.unfactored_copy();
        fresh.refactor(&k)?;
        let fresh = Arc::new(fresh);
        let how = Dual::condensation_for(&fresh, &self.n, &self.t, self.d, self.current_form());
        let shift = self.compliance.shift(self.d);
        self.dual = form_dual(&fresh, &k, (&self.n, &self.t), self.d, how, &shift, None)?;
        self.factor = fresh;
        self.k = k;
        self.history.forget_loads();
        Ok(())
    }

    /// Replaces N and T (m may change) without refactoring K; rebuilds the condensed
    /// dual in the form the handle holds (dense or matrix-free: the form is kept,
    /// whatever c becomes). The warm start is kept when m is unchanged. On error the
    /// problem is unchanged.
    pub fn set_contacts(&mut self, n: &MatrixView<'_>, t: &MatrixView<'_>) -> Result<()> {
        let n = Csc::from_view(n, "N")?;
        let t = Csc::from_view(t, "T")?;
        check_shapes(self.factor.n(), self.d, &n, &t)?;
        let b = stack_rows(&n, &t);
        let layer = crate::dirichlet::layer_of(&self.k, &b, &self.factor);
        let next = Sizes {
            c: self.d * n.nrows,
            inputs: self.k.bytes() + n.bytes() + t.bytes(),
            blocks_work: crate::factor_tree::contact_blocks::work_bytes(
                &self.factor,
                &b,
                n.nrows,
                self.d,
            ),
            lumped: crate::sparse::congruence_bytes(&self.k, &b, &b.transpose()),
            own_solves: crate::dual::own_solves_bytes(&self.factor, &b),
            dirichlet: layer.as_ref().map_or(0, |p| p.bytes()),
            ..self.sizes
        };
        // The handle keeps its form (dense or matrix-free), as `refactor` does.
        let how = Dual::condensation_for(&self.factor, &n, &t, self.d, self.current_form());
        let need =
            self.sizes
                .replace_contacts(self.dual.condensation, n.bytes() + t.bytes(), &next, how);
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
        let dual = form_dual(
            &self.factor,
            &self.k,
            (&n, &t),
            self.d,
            how,
            &compliance.shift(self.d),
            layer,
        )?;
        self.history.new_contacts(dual.c);
        self.compliance = compliance;
        self.sizes = next;
        self.inputs.resize(self.sizes.inputs);
        self.dual = dual;
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
    /// (its dual operator is A + D, `compliance.rs`).
    ///
    /// Errors (the handle keeps its previous law): `BadSize` (a length is not
    /// m), `NotFinite` (NaN, -inf, an infinite m_N), `BadArgument` (c_N <= 0,
    /// m_N outside [1, 10], k_T <= 0).
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
        self.compliance = law;
        Ok(())
    }

    /// The number of contacts with a compliant law (finite c_N or k_T).
    pub fn compliant_contacts(&self) -> usize {
        let law = &self.compliance;
        (0..law.cn.len())
            .filter(|&i| law.cn[i].is_finite() || law.kt[i].is_finite())
            .count()
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
        self.factor.threads().count()
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
        self.solve_from_force(f, g, friction, None, opts, monitor)
    }

    /// As [`ContactProblem::solve_monitored`], with the tangential force the
    /// return mapping of the elastic slip starts from (`lt_prev`, (d - 1) m,
    /// one value per row of T; None for zero, as in a single solve): replays
    /// one increment of a compliant history on its own (docs/design.md
    /// section 8; a problem folder's `lt_prev.txt`). It acts only on contacts
    /// with a finite k_T ([`ContactProblem::set_compliance`]).
    ///
    /// Errors: those of `solve`, and `BadSize` / `NotFinite` for `lt_prev`.
    pub fn solve_from_force(
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
        let (sol, _) = self.solve_from(
            f,
            g,
            friction,
            opts,
            &mut lam,
            (None, lt),
            monitor,
            predicted,
        )?;
        Ok(sol)
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
        let _vectors = self.factor.ledger().claim_f64(2 * ndof);
        let mut ku = vec![0.0; ndof];
        self.k.mul_vec(&self.history.u, &mut ku);
        let f: Vec<f64> = (0..ndof).map(|i| f_total[i] - ku[i]).collect();
        let mut nu = vec![0.0; m];
        self.n.mul_vec(&self.history.u, &mut nu);
        let g: Vec<f64> = (0..m).map(|i| g0[i] - nu[i]).collect();
        let mut lam = vec![0.0; self.dual.c];
        // The history is lent to the solve (which needs the handle mutable:
        // a nonlinear law changes the dual's diagonal) and put back after.
        let history = std::mem::replace(&mut self.history, History::new(0, 0));
        let hist = (Some(&history), &history.lt[..]);
        let solved = self.solve_from(&f, &g, friction, opts, &mut lam, hist, monitor, predicted);
        self.history = history;
        let (mut sol, load) = solved?;
        for (ui, uh) in sol.u.iter_mut().zip(&self.history.u) {
            *ui += uh;
        }
        if sol.report.status == SolveStatus::Converged {
            let load = load.expect("a step's load");
            self.history.advance(&sol.u, &lam, load);
            self.history.lt = lam[m..].to_vec();
        }
        Ok(sol)
    }

    /// Forgets the history: u_0 = 0 and no warm start.
    pub fn reset_history(&mut self) {
        self.history.reset();
    }

    /// Contact dimension d (2 or 3).
    pub fn dim(&self) -> usize {
        self.d
    }

    /// Number of DOFs n.
    pub fn n_dofs(&self) -> usize {
        self.k.nrows
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
    /// `lt_prev.txt` (replayed by [`ContactProblem::solve_from_force`]); a
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
        crate::mtx::write_problem(dir, self.d, &self.k, &self.n, &self.t, f, g, friction)?;
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
        &self.factor
    }
}
