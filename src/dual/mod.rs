//! The condensed dual problem of docs/design.md section 2: with B = [N; T],
//! A = B K^-1 B^T (dense, c x c with c = d m) and, per increment,
//! b = B K^-1 f - [g; 0]. Unknown ordering: lambda_N (m), then lambda_T ((d-1) m,
//! contact by contact).
//!
//! Files: this one (the dual, its forms, rho, the compliance's diagonal, the
//! products' entry points), `condense.rs` (the two dense condensations),
//! `operator.rs` (the matrix-free operator and its preconditioners), tests.rs.

use crate::contact_rows::{check_shapes, contact_dofs, stack_rows};
use crate::error::Result;
use crate::factor::Factor;
use crate::memory::{Claim, F64, Ledger, try_mat, try_scratch, try_zeros};
use crate::options::{DENSE_MAX, DualForm};
use crate::sparse::Csc;
use crate::threads::{PARALLEL_MIN_ENTRIES, Threads};
use faer::MatMut;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::inverse as llt_inverse;
use std::sync::Arc;
use std::time::Instant;

/// Number of right-hand sides solved together while forming A.
pub(crate) const BLOCK: usize = 32;

/// The dense condensed dual operator of one set of contact matrices.
pub struct Dual {
    /// Contact dimension (2 or 3).
    pub(crate) d: usize,
    /// Number of contacts.
    pub(crate) m: usize,
    /// Number of dual unknowns, d m.
    pub(crate) c: usize,
    /// A = B K^-1 B^T, c x c, column-major and exactly symmetric; empty when
    /// matrix-free (`condensation == Condensation::MatrixFree`).
    pub(crate) a: Vec<f64>,
    /// The products of the matrix-free form (None when A is assembled).
    free: Option<Operator>,
    /// Per contact: rho_i = d / trace of the contact's d x d diagonal block of A
    /// (0 when that block vanishes). Units: force / length.
    pub(crate) rho: Vec<f64>,
    /// The matrix B = [N; T] (the contact rows, stacked), c x n. (The dual's
    /// linear term, the vector b, lives in `methods::DualProblem::b`.)
    pub(crate) rows: Csc,
    /// Seconds spent forming A.
    pub(crate) condense_seconds: f64,
    /// How A was formed.
    pub(crate) condensation: Condensation,
    /// Whether every DOF B touches is among the factor's trailing DOFs (u is then
    /// recovered through the trailing block: `ContactProblem::recover_u`).
    pub(crate) trailing: bool,
    /// The problem's threads (those of the factor it was built from).
    pub(crate) threads: Arc<Threads>,
    /// The problem's count of its large allocations (the factor's).
    pub(crate) ledger: Arc<Ledger>,
    /// The bytes of A (or of the matrix-free form) on that ledger.
    _claim: Claim,
    /// The interface compliance's diagonal D (`compliance.rs`), length c, or
    /// empty where every contact is rigid: the operator is A + D. On a dense
    /// dual D is added to A's diagonal (entries read from `a` include it).
    shift: Vec<f64>,
    /// A's own diagonal while D is added to it (dense form; else empty).
    rigid_diag: Vec<f64>,
    /// MPRGP's estimate of |A + D|_2 (30 products of power iteration) as
    /// f64 bits, 0 while none was made: kept for the operator's life, so
    /// that the solves of a history that fall back to MPRGP, or run it, pay
    /// for it once (`whole_norm`, `keep_whole_norm`); cleared with the shift.
    whole_norm: std::sync::atomic::AtomicU64,
    /// The single-precision factor of the last dense Newton step's reduced
    /// system (`dense::Reused`; dense form only): kept with A, so that a
    /// history step's first Newton step solves on the last step's factor
    /// instead of a new one (at most 4 c^2 bytes, on the ledger while
    /// held); cleared with the shift.
    kept_factor: std::sync::Mutex<Option<crate::dense::Reused>>,
    /// A^-1 in single precision (dense form only; `dense::InverseF32`),
    /// made by the first warm 3D Newton step whose reduced system it
    /// preconditions for less than the system's own factor: c^2 single
    /// precision entries, on the ledger while held; cleared with the shift.
    /// Some(None) once making it failed (A not positive definite in single
    /// precision, or the allocator refused): not tried again on this A.
    kept_inverse: std::sync::Mutex<Option<Option<Arc<crate::dense::InverseF32>>>>,
    /// The factor err is multiplied by (>= 1): 1 where the contact blocks
    /// are those of this K, more where they are an earlier K's and rho with
    /// them (`drift.rs`), so that err bounds the err on this K's blocks.
    pub(crate) err_factor: f64,
}

/// How the condensed dual operator was formed.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Condensation {
    /// From the trailing block L_CC of K's factor with the contact DOFs C ordered
    /// last: A = B_C (L_CC L_CC^T)^-1 B_C^T (dense inverse from L_CC, sparse B_C).
    TrailingBlock,
    /// One forward and back solve with K's factor per dual unknown.
    Solves,
    /// A is not formed: each product is one solve with K's factor, whatever its
    /// ordering (see [`crate::DualForm::MatrixFree`]).
    MatrixFree,
}

impl Condensation {
    /// How `Dual::build` forms a dual of `c` unknowns in the form asked for,
    /// `trailing` when every contact DOF is among the factor's trailing DOFs.
    pub(crate) fn of(trailing: bool, form: DualForm, c: usize) -> Condensation {
        let free = match form {
            DualForm::Dense => false,
            DualForm::MatrixFree => true,
            DualForm::Auto => c > DENSE_MAX,
        };
        match (trailing, free) {
            (_, true) => Condensation::MatrixFree,
            (false, false) => Condensation::Solves,
            (true, false) => Condensation::TrailingBlock,
        }
    }
}

impl Dual {
    /// Builds the dual operator in the form asked for: `Dense` assembles A, from the
    /// trailing block of the factor when every DOF that B touches is among the DOFs
    /// the factor ordered last, by solves otherwise; `MatrixFree` forms nothing
    /// c x c (products by solves with the factor, whatever its ordering); `Auto`
    /// is `Dense` up to [`DENSE_MAX`] dual unknowns, `MatrixFree` beyond.
    ///
    /// Errors: `BadSize` if the shapes of N and T do not match d and K,
    /// `OutOfMemory` if A does not fit.
    #[cfg(any(test, feature = "internals"))]
    pub fn build(factor: &Arc<Factor>, n: &Csc, t: &Csc, d: usize, form: DualForm) -> Result<Dual> {
        check_shapes(factor.n(), d, n, t)?;
        Self::build_with(
            factor,
            n,
            t,
            d,
            Self::condensation_for(factor, n, t, d, form),
        )
    }

    /// How `Dual::build` forms the dual of (N, T) on `factor` in `form`
    /// (shapes checked by the caller).
    pub(crate) fn condensation_for(
        factor: &Factor,
        n: &Csc,
        t: &Csc,
        d: usize,
        form: DualForm,
    ) -> Condensation {
        let trailing = Self::trailing_available(factor, n, t);
        Condensation::of(trailing, form, d * n.nrows)
    }

    /// True when every DOF that N or T touches is among the DOFs `factor` orders
    /// last (the condition of `TrailingBlock`).
    pub fn trailing_available(factor: &Factor, n: &Csc, t: &Csc) -> bool {
        Self::trailing_of(factor, &stack_rows(n, t))
    }

    /// A, c x c column-major, when it is formed (None when it is not: the
    /// matrix-free form, or no contacts).
    #[cfg(any(test, feature = "internals"))]
    pub fn dense(&self) -> Option<&[f64]> {
        (!self.a.is_empty()).then_some(&self.a[..])
    }

    /// Number of dual unknowns c = d m.
    #[cfg(any(test, feature = "internals"))]
    pub fn unknowns(&self) -> usize {
        self.c
    }

    /// Seconds spent forming A.
    #[cfg(any(test, feature = "internals"))]
    pub fn condense_seconds(&self) -> f64 {
        self.condense_seconds
    }

    /// The stacked contact rows B = [N; T], c x n.
    #[cfg(any(test, feature = "internals"))]
    pub fn rows(&self) -> &Csc {
        &self.rows
    }

    /// rho_i per contact (see the field), length m.
    #[cfg(any(test, feature = "internals"))]
    pub fn rho(&self) -> &[f64] {
        &self.rho
    }

    /// True when A is not assembled (products only).
    pub fn is_matrix_free(&self) -> bool {
        self.free.is_some()
    }

    /// Whether a matrix-free dual's rough products ([`Dual::apply_rough`])
    /// may run in single precision: on K's own factor (in double where its
    /// single-precision copy could not be allocated), or on a host solve
    /// until the host answers that it offers none (a host that solves on
    /// rows is passed the rough flag and never asked). False on an assembled
    /// dual.
    pub(crate) fn offers_rough(&self) -> bool {
        match &self.free {
            Some(Operator {
                solves: Solves::Factor(_),
                ..
            }) => true,
            Some(Operator {
                solves: Solves::Host(hs),
                ..
            }) => hs.host.offers_single(),
            None => false,
        }
    }

    /// [`Dual::build_keeping`] without blocks.
    #[cfg(any(test, feature = "internals"))]
    pub fn build_with(
        factor: &Arc<Factor>,
        n: &Csc,
        t: &Csc,
        d: usize,
        how: Condensation,
    ) -> Result<Dual> {
        Self::build_keeping(factor, n, t, d, how, Made::default())
    }

    /// Forms A in the way asked for (`TrailingBlock` requires the contact
    /// DOFs to be among the factor's trailing DOFs); a matrix-free form takes
    /// what `made` holds instead of computing it: the contacts' d x d
    /// diagonal blocks (those of an earlier K, whose drift the caller
    /// weighed: see [`Dual::set_err_factor`]) and the factor's values in
    /// single precision; a dense form ignores them.
    pub(crate) fn build_keeping(
        factor: &Arc<Factor>,
        n: &Csc,
        t: &Csc,
        d: usize,
        how: Condensation,
        made: Made,
    ) -> Result<Dual> {
        let start = Instant::now();
        let m = n.nrows;
        check_shapes(factor.n(), d, n, t)?;
        let b = stack_rows(n, t);
        let c = b.nrows;
        let trailing = Self::trailing_of(factor, &b);
        let ledger = factor.ledger();
        if how == Condensation::MatrixFree {
            let free = Operator::new(factor, &b, m, d, made)?;
            let claim = ledger.claim_f64(d * c);
            let (threads, ledger) = (factor.threads().clone(), ledger.clone());
            return Ok(Self::of_operator(
                free,
                b,
                d,
                trailing,
                (threads, ledger, claim),
                start,
            ));
        }
        let mut a = try_zeros(c.saturating_mul(c), "condensed dual")?;
        let claim = ledger.claim_f64(c * c);
        match how {
            Condensation::Solves => a_by_solves(factor, &b, &mut a)?,
            Condensation::TrailingBlock => a_from_trailing_block(factor, &b, &mut a)?,
            Condensation::MatrixFree => unreachable!("returned above"),
        }
        for j in 0..c {
            for i in 0..j {
                let s = 0.5 * (a[i + j * c] + a[j + i * c]);
                a[i + j * c] = s;
                a[j + i * c] = s;
            }
        }
        let rho = rho_of(m, d, |j| a[j + j * c]);
        Ok(Dual {
            _claim: claim,
            ledger: ledger.clone(),
            d,
            m,
            c,
            a,
            free: None,
            rho,
            rows: b,
            condense_seconds: start.elapsed().as_secs_f64(),
            condensation: how,
            trailing,
            threads: factor.threads().clone(),
            shift: Vec::new(),
            rigid_diag: Vec::new(),
            whole_norm: Default::default(),
            kept_factor: Default::default(),
            kept_inverse: Default::default(),
            err_factor: 1.0,
        })
    }

    /// The matrix-free dual of (N, T) on the host's solves (`host.rs`), its
    /// contacts' diagonal blocks formed by c solves, [`BLOCK`] at a time;
    /// `threads` and `ledger` are the problem's.
    ///
    /// Errors: `BadSize` (shapes), `HostSolve`, `OutOfMemory`.
    pub(crate) fn on_host(
        host: &Arc<crate::host::Host>,
        (n, t): (&Csc, &Csc),
        d: usize,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
        by_factor: Option<(Factor, &Csc)>,
    ) -> Result<Dual> {
        let start = Instant::now();
        let m = n.nrows;
        check_shapes(host.n(), d, n, t)?;
        let b = stack_rows(n, t);
        let c = b.nrows;
        // Under `HostBlocks::Auto` the host's entries of K^-1 come first
        // where it gives them (one call), even where the factor would pay; a
        // failed entries call leaves the blocks to the factor.
        let entries = match by_factor {
            Some(_) if host.blocks() == crate::HostBlocks::Auto => {
                match operator::blocks_from_entries(host, &b.transpose(), m, d) {
                    Some(Ok(blocks)) => Some(blocks),
                    Some(Err(_)) => {
                        host.clear();
                        None
                    }
                    None => None,
                }
            }
            _ => None,
        };
        let blocks = match entries {
            Some(blocks) => Some(blocks),
            None => by_factor
                .map(|(analysis, k)| blocks_by_factor(analysis, k, &b, d))
                .transpose()?,
        };
        let free = Operator::on_host(host, &b, m, d, blocks)?;
        let claim = ledger.claim_f64(d * c + host.n());
        Ok(Self::of_operator(
            free,
            b,
            d,
            false,
            (threads, ledger, claim),
            start,
        ))
    }

    /// The matrix-free dual of B = `b` on the operator `free` (its products
    /// by K's factor or the host's solves), `trailing` as the field, with
    /// the problem's threads and ledger and the claim of its bytes; formed
    /// since `start`.
    fn of_operator(
        free: Operator,
        b: Csc,
        d: usize,
        trailing: bool,
        (threads, ledger, claim): (Arc<Threads>, Arc<Ledger>, Claim),
        start: Instant,
    ) -> Dual {
        let (m, c) = (b.nrows / d, b.nrows);
        Dual {
            _claim: claim,
            ledger,
            d,
            m,
            c,
            a: Vec::new(),
            rho: rho_of(m, d, |j| free.diag[j]),
            free: Some(free),
            rows: b,
            condense_seconds: start.elapsed().as_secs_f64(),
            condensation: Condensation::MatrixFree,
            trailing,
            threads,
            shift: Vec::new(),
            rigid_diag: Vec::new(),
            whole_norm: Default::default(),
            kept_factor: Default::default(),
            kept_inverse: Default::default(),
            err_factor: 1.0,
        }
    }

    /// The contacts' d x d diagonal blocks of A (row-major per contact) of
    /// a matrix-free dual on the library's own factor; None otherwise.
    pub(crate) fn own_blocks(&self) -> Option<&[f64]> {
        let f = self.free.as_ref()?;
        f.factor()?;
        Some(&f.blocks)
    }

    /// Takes out the single-precision copy of K's factor that the products
    /// of a matrix-free dual on the library's own factor hold, for a dual
    /// formed next to take instead of allocating one: a fresh copy's page
    /// faults cost more than the copy itself. A refactor writes the new
    /// factor's values into it; `set_contacts` takes it as it is, through
    /// [`Dual::lend_single_of`]. This dual stays whole: where it is kept
    /// after all (the new one failed), its next product in single precision
    /// makes the copy again (see `FactorSolves::single_copy`). None on any other
    /// dual.
    pub(crate) fn lend_single(&mut self) -> Option<Vec<f32>> {
        match &mut self.free.as_mut()?.solves {
            operator::Solves::Factor(fs) => Some(fs.lend_single()),
            operator::Solves::Host(_) => None,
        }
    }

    /// [`Dual::lend_single`] where this dual's products solve with `factor`
    /// itself (the copy then holds its values); None otherwise.
    pub(crate) fn lend_single_of(&mut self, factor: &Arc<Factor>) -> Option<Vec<f32>> {
        let same = self
            .free
            .as_ref()
            .and_then(|f| f.factor())
            .is_some_and(|own| Arc::ptr_eq(own, factor));
        if same { self.lend_single() } else { None }
    }

    /// The single-precision copy of K's factor that the products of a
    /// matrix-free dual on the library's own factor hold (empty where it was
    /// lent away), with the address of its values (feature `internals`:
    /// the tests of [`Dual::lend_single`]).
    #[cfg(any(test, feature = "internals"))]
    #[doc(hidden)]
    pub fn single_copy(&self) -> Option<(usize, Vec<f32>)> {
        match &self.free.as_ref()?.solves {
            operator::Solves::Factor(fs) => {
                let single = fs.single.borrow();
                Some((single.as_ptr() as usize, single.clone()))
            }
            operator::Solves::Host(_) => None,
        }
    }

    /// Sets the factor err is multiplied by (see the field): `factor` >= 1.
    pub(crate) fn set_err_factor(&mut self, factor: f64) {
        debug_assert!(factor >= 1.0);
        self.err_factor = factor;
    }

    /// err (docs/design.md section 5) of the multipliers `lam` with the
    /// constraint values `v`, the scale `rho` (this dual's, or one derived
    /// from it), the linear term `b` and the slip bounds `p`, multiplied by
    /// the factor of kept contact blocks (see the field `err_factor`): every
    /// err a solve reports or stops on is taken here.
    pub(crate) fn error(&self, lam: &[f64], v: &[f64], rho: &[f64], b: &[f64], p: &[f64]) -> f64 {
        self.err_factor * crate::report::natural_map_error(lam, v, rho, b, p, self.d)
    }

    /// The estimate of |A + D|_2 an earlier MPRGP run kept
    /// ([`Dual::keep_whole_norm`]), if any.
    pub(crate) fn whole_norm(&self) -> Option<f64> {
        let bits = self.whole_norm.load(std::sync::atomic::Ordering::Relaxed);
        (bits != 0).then(|| f64::from_bits(bits))
    }

    /// Keeps MPRGP's estimate of |A + D|_2 for the later runs on this
    /// operator (see the field).
    pub(crate) fn keep_whole_norm(&self, norm: f64) {
        if norm > 0.0 && norm.is_finite() {
            let bits = norm.to_bits();
            self.whole_norm
                .store(bits, std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// Runs `f` on the slot of the kept Newton factor (the field
    /// `kept_factor`): the factor of the last reduced system solved on this
    /// A, or None. A slot left by a panic is emptied first (the factor in it may
    /// be half replaced); where the slot is in use (a solve within a solve,
    /// which no method does), `f` gets an empty slot of its own.
    pub(crate) fn with_kept_factor<R>(
        &self,
        f: impl FnOnce(&mut Option<crate::dense::Reused>) -> R,
    ) -> R {
        match take_slot(&self.kept_factor) {
            Some(mut slot) => f(&mut slot),
            None => f(&mut None),
        }
    }

    /// A^-1 in single precision (see the field `kept_inverse`): the one
    /// kept, else, where `make` is set, A is dense and no earlier attempt
    /// failed, a new one (kept for the later calls). None on a matrix-free
    /// dual, where `make` is off and none is kept, where A is not positive
    /// definite in single precision or its inverse cannot be allocated, and
    /// where the slot is in use (a solve within a solve, which no method
    /// does). A slot left by a panic is emptied first.
    pub(crate) fn inverse(&self, make: bool) -> Option<Arc<crate::dense::InverseF32>> {
        let mut slot = take_slot(&self.kept_inverse)?;
        if slot.is_none() && make && self.free.is_none() && !self.a.is_empty() {
            let (c, a, ledger) = (self.c, &self.a[..], &self.ledger);
            let big = c * c >= PARALLEL_MIN_ENTRIES;
            let made = self.threads.run(big, |par| {
                crate::dense::InverseF32::of(c, |j| &a[j * c..(j + 1) * c], ledger, par)
            });
            *slot = Some(made.map(Arc::new));
        }
        slot.clone().flatten()
    }

    /// Makes the operator A + D for the compliance diagonal `shift` (length c;
    /// empty: A itself, every contact rigid), replacing the last one, and
    /// recomputes rho from the new diagonal. Exact: A's own diagonal is kept
    /// while D is added to it, so an empty shift restores A bitwise.
    pub(crate) fn set_shift(&mut self, shift: &[f64]) {
        debug_assert!(shift.is_empty() || shift.len() == self.c);
        *self.whole_norm.get_mut() = 0;
        clear_slot(&mut self.kept_factor);
        clear_slot(&mut self.kept_inverse);
        if self.free.is_none() && !self.a.is_empty() {
            let c = self.c;
            if self.rigid_diag.is_empty() {
                self.rigid_diag = (0..c).map(|j| self.a[j + j * c]).collect();
            }
            for j in 0..c {
                self.a[j + j * c] = self.rigid_diag[j] + shift.get(j).copied().unwrap_or(0.0);
            }
            if shift.is_empty() {
                self.rigid_diag = Vec::new();
            }
        }
        self.shift = shift.to_vec();
        self.rho = rho_of(self.m, self.d, |j| self.diag(j));
    }

    /// rho (section 5) of A + D with D left out at the normal components
    /// `rigid` (contact indices below m): the rho of a nonlinear normal law's
    /// error, which no round's tangent may scale (at an open contact the
    /// tangent's D, capped at 1e4 A_ii, would discount a penetration there
    /// about 1e4 times).
    pub(crate) fn rho_rigid_at(&self, rigid: &[usize]) -> Vec<f64> {
        let mut own = vec![false; self.m];
        for &i in rigid {
            own[i] = true;
        }
        rho_of(self.m, self.d, |j| match self.shift.get(j) {
            Some(&s) if j < self.m && own[j] => self.diag(j) - s,
            _ => self.diag(j),
        })
    }

    /// The compliance diagonal D of [`Dual::set_shift`] (empty: rigid).
    pub(crate) fn shift(&self) -> &[f64] {
        &self.shift
    }

    /// y += D x on the leading entries both reach (a matrix-free product's
    /// compliance part; on a dense dual D is in A).
    fn add_shift(&self, x: &[f64], y: &mut [f64]) {
        for ((yi, xi), di) in y.iter_mut().zip(x).zip(&self.shift) {
            *yi += di * xi;
        }
    }

    /// Column (= row) j of A. Panics when matrix-free (the solver checks
    /// [`crate::Method::needs_entries`] before running a method).
    #[inline]
    pub fn col(&self, j: usize) -> &[f64] {
        &self.a[j * self.c..(j + 1) * self.c]
    }

    /// (A + D)_jj (D the compliance diagonal, zero for rigid contacts).
    #[inline]
    pub fn diag(&self, j: usize) -> f64 {
        match &self.free {
            Some(f) => f.diag[j] + self.shift.get(j).copied().unwrap_or(0.0),
            None => self.a[j + j * self.c],
        }
    }

    /// Entry (la, lb) of contact i's d x d diagonal block of A + D (0 the
    /// normal unknown, 1.. the tangential ones), when matrix-free (None when A
    /// is assembled: read its entries).
    pub(crate) fn block_entry(&self, i: usize, la: usize, lb: usize) -> Option<f64> {
        let (d, m) = (self.d, self.m);
        let f = self.free.as_ref()?;
        let mut v = f.blocks[i * d * d + la * d + lb];
        if la == lb && !self.shift.is_empty() {
            let j = if la == 0 { i } else { m + (d - 1) * i + la - 1 };
            v += self.shift[j];
        }
        Some(v)
    }

    /// Hands K over to a matrix-free dual, which forms G = B K B^T from it (the
    /// lumped preconditioner of Newton's reduced systems) and, where it pays,
    /// the layered Dirichlet preconditioner (`dirichlet.rs`, with the
    /// restricted one of `restricted.rs` that serves Newton's reduced
    /// systems first; `layer`: its analysis where the caller made it for the
    /// memory prediction, else analysed here); nothing on a dense dual.
    pub(crate) fn set_lumped(&mut self, k: &Csc, layer: Option<crate::dirichlet::Plan>) {
        let Some(f) = &mut self.free else { return };
        // The layered Dirichlet preconditioner: the caller's plan, else
        // weighed here against the cost of a product with K's factor (on the
        // host's solves made as `host_layer` makes it for the memory
        // prediction).
        let plan = match (layer, f.factor()) {
            (Some(plan), _) => Some(plan),
            (None, None) => host_layer(k, &self.rows, self.d, &self.threads, &self.ledger),
            (None, Some(factor)) => crate::dirichlet::Plan::of(
                k,
                &self.rows,
                factor,
                factor.threads().clone(),
                self.ledger.clone(),
            ),
        };
        // G = B K B^T: formed once, by the plan's restricted preconditioner
        // where there is one (its copy, the same matrix), else here.
        let g = match plan.as_ref().and_then(|p| p.lumped()) {
            Some(g) => g.clone(),
            None => crate::sparse::congruence(k, &self.rows, &f.bt),
        };
        let claim = self.ledger.claim(g.bytes());
        f.lumped = Some((g, claim));
        f.dirichlet = plan.and_then(|p| p.form(&self.ledger));
    }

    /// The plan of this dual's layered Dirichlet preconditioner for K = `k`
    /// of the pattern of the K it was formed on (a refactor: B unchanged),
    /// its analyses kept ([`crate::dirichlet::Dirichlet::renewed`]); None
    /// where the dual holds none, or the patterns differ.
    pub(crate) fn renewed_layer(&self, k: &Csc) -> Option<crate::dirichlet::Plan> {
        let f = self.free.as_ref()?;
        f.dirichlet.as_ref()?.renewed(k, &self.rows, &f.bt)
    }

    /// y := P x, P the approximate inverse of A that preconditions Newton's
    /// reduced systems on a matrix-free dual (cut by their test vectors, or
    /// as the first-order change of the restricted one of `restricted.rs`):
    /// the layered Dirichlet one (`dirichlet.rs`) where it was formed, else
    /// the lumped G = B K B^T.
    /// False (y untouched) where the dual holds neither (a dense dual, or K
    /// not handed over).
    pub(crate) fn precondition(&self, x: &[f64], y: &mut [f64]) -> bool {
        let Some(f) = &self.free else { return false };
        if let Some(dn) = &f.dirichlet {
            dn.apply(&self.rows, x, y);
            return true;
        }
        match &f.lumped {
            Some((g, _)) => {
                g.mul_vec(x, y);
                true
            }
            None => false,
        }
    }

    /// The lumped preconditioner restricted to Newton's reduced systems
    /// (`restricted.rs`), where the dual holds the layered Dirichlet one
    /// (analysed with it) and no compliance shift (it approximates A^-1,
    /// not (A + D)^-1).
    pub(crate) fn restricted(&self) -> Option<&crate::restricted::Restricted> {
        let f = self.free.as_ref()?;
        if !self.shift.is_empty() {
            return None;
        }
        f.dirichlet.as_ref()?.restricted()
    }

    /// Drops the restricted preconditioner of Newton's reduced systems and
    /// keeps the layered Dirichlet one (the tests that measure what the
    /// restriction buys).
    #[cfg(test)]
    pub(crate) fn drop_restricted(&mut self) {
        if let Some(d) = self.free.as_mut().and_then(|f| f.dirichlet.as_mut()) {
            d.drop_restricted();
        }
    }

    /// Drops the layered Dirichlet preconditioner (the tests that measure what
    /// it buys against the lumped one).
    #[cfg(test)]
    pub(crate) fn drop_dirichlet(&mut self) {
        if let Some(f) = &mut self.free {
            f.dirichlet = None;
        }
    }

    /// Forms the layered Dirichlet preconditioner whatever it costs (the tests
    /// that measure what it buys, on scenes too small for it to pay); true
    /// where it was formed.
    #[cfg(test)]
    pub(crate) fn force_dirichlet(&mut self, k: &Csc) -> bool {
        let Some(f) = &mut self.free else {
            return false;
        };
        let threads = self.threads.clone();
        f.dirichlet =
            crate::dirichlet::Plan::unguarded(k, &self.rows, threads, self.ledger.clone())
                .and_then(|p| p.form(&self.ledger));
        f.dirichlet.is_some()
    }

    /// G = B K B^T when a matrix-free dual holds it ([`Dual::set_lumped`]).
    pub(crate) fn lumped(&self) -> Option<&Csc> {
        self.free
            .as_ref()
            .and_then(|f| f.lumped.as_ref().map(|(g, _)| g))
    }

    /// True when every DOF B touches is among the DOFs `factor` orders last.
    pub(crate) fn trailing_of(factor: &Factor, b: &Csc) -> bool {
        !factor.last().is_empty() && {
            let mut in_last = vec![false; factor.n()];
            factor.last().iter().for_each(|&j| in_last[j] = true);
            contact_dofs(b)
                .iter()
                .all(|&j| j < in_last.len() && in_last[j])
        }
    }

    /// Narrows the products of [`Dual::apply_narrow`] to the dual rows `rows`
    /// (ascending, no repeats): the x they are given vanishes outside them and
    /// y is wanted only there (Newton's reduced solves: their unknowns' rows
    /// and the explicit part's). The solves then take only the supernodes of
    /// K's factor on the paths of those rows' DOFs (`tree_solve.rs`); on a
    /// matrix-free dual where those hold at most MAX_FRACTION of L's entries.
    /// False, and the products stay whole, where they hold more, and on an
    /// assembled dual. In force until the next call or [`Dual::widen`].
    pub(crate) fn narrow_to(&self, rows: &[usize]) -> bool {
        self.free.as_ref().is_some_and(|f| f.narrow_to(rows))
    }

    /// Ends a narrowing (see [`Dual::narrow_to`]).
    pub(crate) fn widen(&self) {
        match &self.free {
            Some(Operator {
                solves: Solves::Factor(fs),
                ..
            }) => fs.narrow.borrow_mut().split = None,
            Some(Operator {
                solves: Solves::Host(hs),
                ..
            }) => hs.narrow.borrow_mut().held.clear(),
            None => {}
        }
    }

    /// y := A x, in single precision where `rough` (as [`Dual::apply_rough`]),
    /// where a narrowing is in force ([`Dual::narrow_to`]) only at its rows
    /// and zero elsewhere (x must vanish outside them); else as
    /// [`Dual::apply`] / [`Dual::apply_rough`].
    pub(crate) fn apply_narrow(&self, x: &[f64], y: &mut [f64], rough: bool) {
        match &self.free {
            Some(f) => {
                f.apply_narrow(x, y, rough);
                self.add_shift(x, y);
            }
            None => self.apply(x, y),
        }
    }

    /// y ~= A x for an inexact inner solve: on a matrix-free dual the solve with
    /// K's factor runs in single precision (relative error about 1e-7 times the
    /// factor's conditioning, half the memory traffic); exactly [`Dual::apply`]
    /// on a dense one, and on a matrix-free one whose single-precision copy
    /// was lent away and cannot be made again (the allocator refuses it; see
    /// `FactorSolves::single_copy`).
    pub(crate) fn apply_rough(&self, x: &[f64], y: &mut [f64]) {
        match &self.free {
            Some(f) => {
                f.apply_single(x, y);
                self.add_shift(x, y);
            }
            None => self.apply(x, y),
        }
    }

    /// f := K^-1 f with the factor `factor` and `ys[i] := A xs[i]` (length c
    /// each), in one block solve where the dual is matrix-free on that
    /// factor ([`Operator::solve_with_products`]), with u at `xs[0]` into
    /// `primal` where it is given (and z of `xs[1]`, the line's direction,
    /// where there is one); false, with nothing written, otherwise (an
    /// assembled dual, the host's solves, another factor).
    ///
    /// Errors: `OutOfMemory`.
    pub(crate) fn solve_with_products(
        &self,
        factor: &Arc<Factor>,
        f: &mut [f64],
        xs: &[&[f64]],
        ys: &mut [Vec<f64>],
        primal: Option<&mut Primal>,
    ) -> Result<bool> {
        let Some(op) = &self.free else {
            return Ok(false);
        };
        if !op.factor().is_some_and(|own| Arc::ptr_eq(own, factor)) {
            return Ok(false);
        }
        if !op.solve_with_products(f, xs, ys, primal)? {
            return Ok(false);
        }
        for (x, y) in xs.iter().zip(ys.iter_mut()) {
            self.add_shift(x, y);
        }
        Ok(true)
    }

    /// y := A x (length c each) in double and z := K^-1 B^T x (n values)
    /// where a matrix-free dual's product computes that whole (see
    /// [`Operator::apply_keeping`]: on K's own factor, its solves not
    /// restricted to the contact DOFs' paths); false, with y and z
    /// untouched, otherwise.
    pub(crate) fn apply_keeping(&self, x: &[f64], y: &mut [f64], z: &mut [f64]) -> bool {
        let Some(f) = &self.free else {
            return false;
        };
        if !f.apply_keeping(x, y, z) {
            return false;
        }
        self.add_shift(x, y);
        true
    }

    /// Whether [`Dual::apply_keeping`] computes z.
    pub(crate) fn keeps_solutions(&self) -> bool {
        self.free.as_ref().is_some_and(|f| f.keeps_solutions())
    }

    /// y := A x. x and y may be shorter than c: then y is the leading block of A
    /// (rows 0..len(y), columns 0..len(x)) times x, e.g. A_NN x_N for the normal
    /// unknowns alone.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        if let Some(f) = &self.free {
            // A cold start's first gradient: a zero x needs no solve (the
            // back substitution, unlike the forward one, skips nothing).
            if x.iter().all(|&v| v == 0.0) {
                y.fill(0.0);
                return;
            }
            f.apply(x, y);
            self.add_shift(x, y);
            return;
        }
        leading_block_apply(&self.a, self.c, x, y, &self.threads);
    }
}

/// The guard of a slot the dual keeps between solves (the kept factor, A^-1):
/// one left by a panic is emptied first (what it holds may be half
/// replaced) and its poison cleared; None where the slot is in use.
fn take_slot<T: Default>(slot: &std::sync::Mutex<T>) -> Option<std::sync::MutexGuard<'_, T>> {
    use std::sync::TryLockError;
    match slot.try_lock() {
        Ok(guard) => Some(guard),
        Err(TryLockError::Poisoned(poisoned)) => {
            let mut guard = poisoned.into_inner();
            *guard = T::default();
            slot.clear_poison();
            Some(guard)
        }
        Err(TryLockError::WouldBlock) => None,
    }
}

/// Empties a slot the dual keeps between solves, poisoned or not.
fn clear_slot<T: Default>(slot: &mut std::sync::Mutex<T>) {
    *slot
        .get_mut()
        .unwrap_or_else(|poisoned| poisoned.into_inner()) = T::default();
    slot.clear_poison();
}

/// y := H x for the leading len(y) x len(x) block H of the column-major array `a`
/// with leading dimension `ld`. Mostly nonzero x: faer's matrix-vector product
/// (measured against a column loop: BENCHMARKS.md, "Tuning measurements"); sparse
/// x (open contacts, active bounds): only the columns of its nonzeros.
/// Large products run on `threads` (see [`PARALLEL_MIN_ENTRIES`]).
pub(crate) fn leading_block_apply(
    a: &[f64],
    ld: usize,
    x: &[f64],
    y: &mut [f64],
    threads: &Threads,
) {
    let nonzeros = x.iter().filter(|&&v| v != 0.0).count();
    if 4 * nonzeros >= 3 * x.len() && !x.is_empty() && !y.is_empty() {
        let h = faer::MatRef::from_column_major_slice_with_stride(a, y.len(), x.len(), ld);
        let xm = faer::MatRef::from_column_major_slice(x, x.len(), 1);
        let big = x.len() * y.len() >= PARALLEL_MIN_ENTRIES;
        let ym = MatMut::from_column_major_slice_mut(y, y.len(), 1);
        threads.run(big, |par| {
            faer::linalg::matmul::matmul(ym, faer::Accum::Replace, h, xm, 1.0, par);
        });
        return;
    }
    let k = y.len();
    y.iter_mut().for_each(|v| *v = 0.0);
    for (j, &xj) in x.iter().enumerate() {
        if xj != 0.0 {
            for (yi, aij) in y.iter_mut().zip(&a[j * ld..j * ld + k]) {
                *yi += aij * xj;
            }
        }
    }
}

/// rho_i = d / trace of contact i's d x d diagonal block of A (0 when it vanishes).
fn rho_of(m: usize, d: usize, diag: impl Fn(usize) -> f64) -> Vec<f64> {
    (0..m)
        .map(|i| {
            let mut tr = diag(i);
            for k in 0..d - 1 {
                tr += diag(m + (d - 1) * i + k);
            }
            if tr > 0.0 { d as f64 / tr } else { 0.0 }
        })
        .collect()
}

mod condense;
mod operator;
mod primal;

/// The layered Dirichlet preconditioner's plan on the host's solves (K
/// handed over, `b` = [N; T]), weighed as on the own path against a solve
/// with the factor the library would make of K: the symbolic analysis alone,
/// in the default ordering (a tenth of a factorisation or less, against the
/// d m solves the contact blocks take), or K's lower triangle where that
/// analysis fails. A direct host's factor is about that size; an iterative
/// host's solve reads far more. Weighed against K's lower triangle alone
/// the preconditioner was refused on most scenes, and the host's steps took
/// 30-50 % more products than the own path's (BENCHMARKS.md, "The host's solver of K").
pub(crate) fn host_layer(
    k: &Csc,
    b: &Csc,
    d: usize,
    threads: &Arc<Threads>,
    ledger: &Arc<Ledger>,
) -> Option<crate::dirichlet::Plan> {
    host_plan(k, b, d, threads, ledger).0
}

/// What a dual on the host's solves makes of a K handed over: the layered
/// Dirichlet preconditioner where it pays ([`host_layer`]), and the analysis
/// of the factor the library would make of K (its error where the analysis
/// failed), its numeric allocations counted on `ledger`: the factor that
/// gives the contacts' blocks where [`crate::HostBlocks`] asks for it
/// ([`blocks_by_factor`]).
pub(crate) fn host_plan(
    k: &Csc,
    b: &Csc,
    d: usize,
    threads: &Arc<Threads>,
    ledger: &Arc<Ledger>,
) -> (Option<crate::dirichlet::Plan>, Result<Factor>) {
    let analysis = Factor::analyse(
        k,
        &[],
        crate::options::Ordering::Auto,
        d == 3,
        threads.clone(),
        ledger.clone(),
    );
    let l_nnz = analysis
        .as_ref()
        .map_or((k.nnz() + k.nrows) / 2, |a| a.nnz_and_flops().0);
    let layer = crate::dirichlet::Plan::within(k, b, l_nnz, threads.clone(), ledger.clone());
    (layer, analysis)
}

/// Bytes the contacts' blocks by the factor `analysis` of K take above the
/// dual's own while they are formed ([`blocks_by_factor`]): L's values, and
/// the larger of the factorisation's workspace and the blocks' selected
/// inversion or forward solves (`contact_blocks::work_bytes`).
pub(crate) fn factor_blocks_bytes(analysis: &Factor, b: &Csc, d: usize) -> usize {
    analysis.values_bytes()
        + analysis
            .factor_scratch_bytes()
            .max(crate::factor_tree::contact_blocks::work_bytes(
                analysis,
                b,
                b.nrows / d,
                d,
            ))
}

/// True where the blocks by the factor `analysis` take fewer flops than by
/// the host's solves: c solves of 4 nnz(L) flops each (forward and back)
/// against 2.5 times the factorisation's flops (the factorisation and the
/// selected inversion, which measured 1.5-2.5 factorisations in all on the
/// benchmark's 3D blocks).
pub(crate) fn factor_blocks_pay(analysis: &Factor, c: usize) -> bool {
    let (nnz, flops) = analysis.nnz_and_flops();
    4.0 * nnz as f64 * c as f64 >= 2.5 * flops
}

/// The contacts' d x d blocks of A = B K^-1 B^T (`b`: B) by the library's
/// own factor of K: `analysis` (of `k`) factored, its selected inversion or
/// forward solves (`contact_blocks`), the factor dropped on return.
///
/// Errors: `NotPositiveDefinite` (K), `OutOfMemory`.
pub(crate) fn blocks_by_factor(
    mut analysis: Factor,
    k: &Csc,
    b: &Csc,
    d: usize,
) -> Result<Vec<f64>> {
    analysis.refactor(k)?;
    Ok(crate::factor_tree::contact_blocks::contact_blocks(
        &analysis,
        b,
        b.nrows / d,
        d,
    ))
}

use condense::*;
use operator::*;
pub(crate) use operator::{Made, host_rows_bytes, own_solves_bytes};
pub(crate) use primal::Primal;

#[cfg(test)]
pub(crate) mod tests;
