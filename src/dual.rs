//! The condensed dual problem of docs/design.md section 2: with B = [N; T],
//! A = B K^-1 B^T (dense, c x c with c = d m) and, per increment,
//! b = B K^-1 f - [g; 0]. Unknown ordering: lambda_N (m), then lambda_T ((d-1) m,
//! contact by contact).

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

    /// Forms A in the way asked for (`TrailingBlock` requires the contact DOFs to
    /// be among the factor's trailing DOFs).
    pub fn build_with(
        factor: &Arc<Factor>,
        n: &Csc,
        t: &Csc,
        d: usize,
        how: Condensation,
    ) -> Result<Dual> {
        let start = Instant::now();
        let m = n.nrows;
        check_shapes(factor.n(), d, n, t)?;
        let b = stack_rows(n, t);
        let c = b.nrows;
        let trailing = Self::trailing_of(factor, &b);
        let ledger = factor.ledger();
        if how == Condensation::MatrixFree {
            let free = Operator::new(factor, &b, m, d)?;
            let rho = rho_of(m, d, |j| free.diag[j]);
            return Ok(Dual {
                _claim: ledger.claim_f64(d * c),
                ledger: ledger.clone(),
                d,
                m,
                c,
                a: Vec::new(),
                free: Some(free),
                rho,
                rows: b,
                condense_seconds: start.elapsed().as_secs_f64(),
                condensation: how,
                trailing,
                threads: factor.threads().clone(),
                shift: Vec::new(),
                rigid_diag: Vec::new(),
            });
        }
        let mut a = alloc_zeroed(c, c, "condensed dual")?;
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
        })
    }

    /// Makes the operator A + D for the compliance diagonal `shift` (length c;
    /// empty: A itself, every contact rigid), replacing the last one, and
    /// recomputes rho from the new diagonal. Exact: A's own diagonal is kept
    /// while D is added to it, so an empty shift restores A bitwise.
    pub(crate) fn set_shift(&mut self, shift: &[f64]) {
        debug_assert!(shift.is_empty() || shift.len() == self.c);
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
    /// the layered Dirichlet preconditioner (`dirichlet.rs`); nothing on a
    /// dense dual.
    pub(crate) fn set_lumped(&mut self, k: &Csc) {
        if let Some(f) = &mut self.free {
            let g = crate::sparse::congruence(k, &self.rows, &f.bt);
            let claim = self.ledger.claim(g.bytes());
            f.lumped = Some((g, claim));
            let plan = crate::dirichlet::Plan::of(
                k,
                &self.rows,
                &f.factor,
                f.factor.threads().clone(),
                self.ledger.clone(),
            );
            f.dirichlet = plan.and_then(|p| p.form(&self.ledger));
        }
    }

    /// y := P x, P the approximate inverse of A that preconditions Newton's
    /// reduced systems on a matrix-free dual: the layered Dirichlet one
    /// (`dirichlet.rs`) where it was formed, else the lumped G = B K B^T.
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
        let threads = f.factor.threads().clone();
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
        if let Some(f) = &self.free {
            f.narrow.borrow_mut().split = None;
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
    /// on a dense one.
    pub(crate) fn apply_rough(&self, x: &[f64], y: &mut [f64]) {
        match &self.free {
            Some(f) => {
                f.apply_single(x, y);
                self.add_shift(x, y);
            }
            None => self.apply(x, y),
        }
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

/// A zeroed rows x cols column-major array, or `OutOfMemory` naming `what`.
fn alloc_zeroed(rows: usize, cols: usize, what: &str) -> Result<Vec<f64>> {
    crate::memory::try_zeros(rows.saturating_mul(cols), what)
}

/// The matrix-free form of A = B K^-1 B^T: each product is one solve with K's
/// factor (whatever its ordering); nothing c x c is formed. The contacts' d x d
/// diagonal blocks of A are computed once (`contact_blocks`), for rho, the
/// diagonal and Newton's preconditioner.
struct Operator {
    factor: Arc<Factor>,
    /// B^T, n x c: column r holds row r of B.
    bt: Csc,
    /// A_jj, j < c.
    diag: Vec<f64>,
    /// Per contact, its d x d diagonal block of A, row-major (see
    /// [`crate::factor_tree::contact_blocks::contact_blocks`]).
    blocks: Vec<f64>,
    /// Workspace of one product: the n-vector and the solve's scratch.
    work: std::cell::RefCell<(Vec<f64>, MemBuffer)>,
    /// L's values in single precision, for the rough products of
    /// [`Dual::apply_rough`], with their workspace; and their bytes on the ledger.
    single: Vec<f32>,
    work_single: std::cell::RefCell<(Vec<f32>, MemBuffer)>,
    _single_claim: Claim,
    /// G = B K B^T (c x c, sparse), the lumped approximation of A^-1 that
    /// preconditions Newton's reduced systems, once K is handed over
    /// ([`Dual::set_lumped`]), with its bytes on the ledger.
    lumped: Option<(Csc, Claim)>,
    /// The layered Dirichlet preconditioner, where it pays (`dirichlet.rs`).
    dirichlet: Option<crate::dirichlet::Dirichlet>,
    /// The products' own solves (see [`OwnSolves`]); None on a dense
    /// factor: its plain solve.
    own: Option<OwnSolves>,
    /// The narrowed products of Newton's reduced solves (see
    /// [`Dual::narrow_to`]).
    narrow: std::cell::RefCell<Narrow>,
}

/// Products narrowed to a set of dual rows: x vanishes outside them and y is
/// wanted only there (a Newton step's reduced unknowns and explicit part), so
/// the solves take the supernodes on the paths of their DOFs alone
/// (`tree_solve.rs`). The split is replaced at each narrowing; its scratch in
/// double and single precision is made at the first one, refitted after,
/// and claimed on the ledger (`TreeSolve::bytes_bound` in the prediction).
#[derive(Default)]
struct Narrow {
    /// The rows, ascending, and the split for their DOFs; None: the products
    /// are not narrowed.
    rows: Vec<usize>,
    split: Option<crate::factor_tree::tree_solve::TreeSolve>,
    /// The factor's elimination tree, made at the first narrowing.
    tree: Option<crate::factor_tree::supernode_tree::Tree>,
    /// The DOFs of the rows (scratch of [`Dual::narrow_to`]).
    dofs: Vec<usize>,
    work: Option<NarrowWork>,
    /// The bytes of all this at their bound ([`narrow_bytes`]), claimed at
    /// the first narrowing.
    claim: Option<Claim>,
}

struct NarrowWork {
    double: crate::factor_tree::tree_solve::TreeScratch<f64>,
    single: crate::factor_tree::tree_solve::TreeScratch<f32>,
}

/// Bytes the narrowed products of a dual with c rows on `factor` (sparse)
/// claim at most: the split and its scratch (`TreeSolve::bytes_bound`), the
/// elimination tree, and the lists of DOFs and rows.
fn narrow_bytes(factor: &Factor, c: usize) -> usize {
    crate::factor_tree::tree_solve::TreeSolve::bytes_bound(factor)
        + crate::factor_tree::supernode_tree::Tree::bytes_of(factor)
        + (factor.n() + c) * std::mem::size_of::<usize>()
}

/// The solves a matrix-free dual's products take instead of the factor's
/// plain solve (`tree_solve.rs`: restricted to the contact DOFs' paths where
/// those hold few of L's entries, split between threads where there are
/// several, and skipping the supernodes a sparse x leaves zero in the forward
/// solve: a Newton direction on a large face's closed zone), with their
/// scratch in double and single precision and its bytes on the ledger.
struct OwnSolves {
    split: crate::factor_tree::tree_solve::TreeSolve,
    work: std::cell::RefCell<crate::factor_tree::tree_solve::TreeScratch<f64>>,
    work_single: std::cell::RefCell<crate::factor_tree::tree_solve::TreeScratch<f32>>,
    _claim: Claim,
}

impl OwnSolves {
    /// The solves of B's DOFs on `factor`; None on a dense factor.
    fn of(factor: &Factor, b: &Csc) -> Option<OwnSolves> {
        let split = crate::factor_tree::tree_solve::TreeSolve::of(factor, &contact_dofs(b))?;
        let n = factor.n();
        Some(OwnSolves {
            _claim: factor.ledger().claim(split.bytes_with_scratch(n)),
            work: std::cell::RefCell::new(split.scratch(n)),
            work_single: std::cell::RefCell::new(split.scratch(n)),
            split,
        })
    }
}

/// Bytes the products of a matrix-free dual of B (`b`) on `factor` claim for
/// their own solves ([`OwnSolves`]), and at most for their narrowed ones
/// ([`narrow_bytes`], and Newton's list of the rows).
pub(crate) fn own_solves_bytes(factor: &Factor, b: &Csc) -> usize {
    if factor.is_dense() {
        return 0;
    }
    crate::factor_tree::tree_solve::TreeSolve::of(factor, &contact_dofs(b))
        .map_or(0, |split| split.bytes_with_scratch(factor.n()))
        + narrow_bytes(factor, b.nrows)
        + b.nrows * std::mem::size_of::<usize>()
}

impl Operator {
    /// Errors: `OutOfMemory` when the allocator refuses its work space or the
    /// single-precision copy of the factor.
    fn new(factor: &Arc<Factor>, b: &Csc, m: usize, d: usize) -> Result<Operator> {
        let blocks = crate::factor_tree::contact_blocks::contact_blocks(factor, b, m, d);
        let mut diag = vec![0.0; b.nrows];
        for i in 0..m {
            diag[i] = blocks[i * d * d];
            for s in 0..d - 1 {
                diag[m + (d - 1) * i + s] = blocks[i * d * d + (s + 1) * (d + 1)];
            }
        }
        let single = factor.single_values()?;
        let own = OwnSolves::of(factor, b);
        let what = "the matrix-free dual's work space";
        Ok(Operator {
            factor: factor.clone(),
            bt: b.transpose(),
            diag,
            blocks,
            work: std::cell::RefCell::new((
                try_zeros(factor.n(), what)?,
                try_scratch(factor.solve_scratch(1), what)?,
            )),
            _single_claim: factor.ledger().claim(single.len() * 4),
            lumped: None,
            dirichlet: None,
            own,
            narrow: std::cell::RefCell::new(Narrow::default()),
            single,
            work_single: std::cell::RefCell::new((
                try_zeros(factor.n(), what)?,
                try_scratch(factor.solve_scratch_single(), what)?,
            )),
        })
    }

    /// y ~= A x with the solve in single precision (the products with B in
    /// double): relative error about 1e-7 times the conditioning of K's factor.
    fn apply_single(&self, x: &[f64], y: &mut [f64]) {
        self.apply_in(x, y, true);
    }

    /// y := A x (leading blocks for shorter x and y, as [`Dual::apply`]).
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.apply_in(x, y, false);
    }

    /// y := A x with the solve in single precision where `rough`, else in
    /// double: B^T x scattered into the n-vector, the solve (the own one,
    /// else the factor's plain one), B z gathered. No solve for a zero x
    /// (Newton's explicit part near convergence, often Tresca's).
    fn apply_in(&self, x: &[f64], y: &mut [f64], rough: bool) {
        if x.iter().all(|&v| v == 0.0) {
            y.iter_mut().for_each(|v| *v = 0.0);
            return;
        }
        let (bt, factor) = (&self.bt, &self.factor);
        macro_rules! whole {
            ($work:expr, $t:ty, $values:expr, $own_work:ident, $solve:ident) => {{
                let mut work = $work.borrow_mut();
                let (z, mem) = &mut *work;
                z.iter_mut().for_each(|v| *v = 0.0);
                for (r, &xr) in x.iter().enumerate() {
                    if xr != 0.0 {
                        for k in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                            z[bt.row_idx[k]] += (bt.values[k] * xr) as $t;
                        }
                    }
                }
                match &self.own {
                    Some(own) => {
                        let mut scratch = own.$own_work.borrow_mut();
                        own.split
                            .$solve(factor, $values, z, &mut scratch, factor.threads());
                    }
                    None => {
                        let n = z.len();
                        let zm = MatMut::from_column_major_slice_mut(&mut z[..], n, 1);
                        factor.solve_values($values, zm, MemStack::new(mem));
                    }
                }
                for (r, yr) in y.iter_mut().enumerate() {
                    *yr = (bt.col_ptr[r]..bt.col_ptr[r + 1])
                        .map(|k| bt.values[k] * f64::from(z[bt.row_idx[k]]))
                        .sum();
                }
            }};
        }
        if rough {
            whole!(
                self.work_single,
                f32,
                &self.single,
                work_single,
                solve_single
            );
        } else {
            whole!(self.work, f64, factor.values(), work, solve);
        }
    }
}

impl Operator {
    /// See [`Dual::narrow_to`].
    fn narrow_to(&self, rows: &[usize]) -> bool {
        let mut narrow = self.narrow.borrow_mut();
        if self.factor.is_dense() {
            return false;
        }
        let Narrow {
            rows: held,
            split,
            tree,
            dofs,
            work,
            claim,
        } = &mut *narrow;
        dofs.clear();
        for &r in rows {
            dofs.extend_from_slice(&self.bt.row_idx[self.bt.col_ptr[r]..self.bt.col_ptr[r + 1]]);
        }
        dofs.sort_unstable();
        dofs.dedup();
        if claim.is_none() {
            *claim = Some(
                self.factor
                    .ledger()
                    .claim(narrow_bytes(&self.factor, self.bt.ncols)),
            );
        }
        let tree =
            tree.get_or_insert_with(|| crate::factor_tree::supernode_tree::Tree::of(&self.factor));
        *split = Some(crate::factor_tree::tree_solve::TreeSolve::on(
            &self.factor,
            tree,
            dofs,
        ))
        .filter(|s| s.restricted());
        let Some(split) = split else {
            return false;
        };
        held.clear();
        held.extend_from_slice(rows);
        match work {
            Some(work) => {
                split.refit(&mut work.double);
                split.refit(&mut work.single);
            }
            None => {
                let n = self.factor.n();
                *work = Some(NarrowWork {
                    double: split.scratch(n),
                    single: split.scratch(n),
                });
            }
        }
        true
    }

    /// See [`Dual::apply_narrow`].
    fn apply_narrow(&self, x: &[f64], y: &mut [f64], rough: bool) {
        let mut narrow = self.narrow.borrow_mut();
        let Narrow {
            rows,
            split: Some(split),
            work: Some(work),
            ..
        } = &mut *narrow
        else {
            drop(narrow);
            return if rough {
                self.apply_single(x, y)
            } else {
                self.apply(x, y)
            };
        };
        debug_assert!(
            x.iter()
                .enumerate()
                .all(|(r, &v)| v == 0.0 || rows.binary_search(&r).is_ok()),
            "x vanishes outside the narrowed rows"
        );
        y.iter_mut().for_each(|v| *v = 0.0);
        if rows.iter().all(|&r| x[r] == 0.0) {
            return;
        }
        let (bt, threads) = (&self.bt, self.factor.threads());
        // The solve reads and writes z on the paths' columns, which hold the
        // rows' DOFs: z is cleared there (`TreeSolve::clear`), B^T x
        // scattered into it, and A x gathered at the rows.
        macro_rules! narrowed {
            ($z:expr, $t:ty, $solve:ident, $values:expr, $scratch:expr) => {{
                let z = $z;
                split.clear(&self.factor, z);
                for &r in rows.iter() {
                    if x[r] != 0.0 {
                        for k in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                            z[bt.row_idx[k]] += (bt.values[k] * x[r]) as $t;
                        }
                    }
                }
                split.$solve(&self.factor, $values, z, $scratch, threads);
                for &r in rows.iter() {
                    y[r] = (bt.col_ptr[r]..bt.col_ptr[r + 1])
                        .map(|k| bt.values[k] * f64::from(z[bt.row_idx[k]]))
                        .sum();
                }
            }};
        }
        if rough {
            let mut w = self.work_single.borrow_mut();
            narrowed!(&mut w.0, f32, solve_single, &self.single, &mut work.single);
        } else {
            let mut w = self.work.borrow_mut();
            narrowed!(&mut w.0, f64, solve, self.factor.values(), &mut work.double);
        }
    }
}

/// A := B K^-1 B^T by blocks of solves with K's factor (c x c, column-major).
/// Errors: `OutOfMemory` when the block of right-hand sides cannot be allocated.
fn a_by_solves(factor: &Factor, b: &Csc, a: &mut [f64]) -> Result<()> {
    let (ndof, c) = (factor.n(), b.nrows);
    let bt = b.transpose();
    let width = BLOCK.min(c.max(1));
    let _work = factor
        .ledger()
        .claim(ndof * width * F64 + factor.solve_scratch(width).size_bytes());
    let what = "the block of solves forming A";
    let mut rhs = try_mat(ndof, width, what)?;
    let mut mem = try_scratch(factor.solve_scratch(width), what)?;
    let mut col = vec![0.0; c];
    let mut j0 = 0;
    while j0 < c {
        let w = width.min(c - j0);
        rhs.fill(0.0);
        for jj in 0..w {
            let j = j0 + jj;
            for k in bt.col_ptr[j]..bt.col_ptr[j + 1] {
                rhs[(bt.row_idx[k], jj)] = bt.values[k];
            }
        }
        factor.solve_in_place(rhs.as_mut().subcols_mut(0, w), MemStack::new(&mut mem));
        for jj in 0..w {
            let z = rhs
                .col(jj)
                .try_as_col_major()
                .expect("contiguous")
                .as_slice();
            b.mul_vec(z, &mut col);
            a[(j0 + jj) * c..(j0 + jj + 1) * c].copy_from_slice(&col);
        }
        j0 += w;
    }
    Ok(())
}

/// A := B_C S_CC^-1 B_C^T, with S_CC = L_CC L_CC^T the Schur complement of K onto
/// the trailing DOFs C (L_CC the factor's trailing block).
///
/// S_CC^-1 = L_CC^-T L_CC^-1 costs nc^3 / 3 + nc^3 / 3 flops (triangular inverse and
/// a triangular product, faer's `llt::inverse`); the sandwich with the sparse B_C
/// then costs O(nc c r) with r the nonzeros per row of B (1 to d). Forming
/// W = L_CC^-1 B_C^T and W^T W instead costs about nc c^2 + c^2 nc flops.
///
/// Errors: `OutOfMemory` when the nc x nc blocks cannot be allocated.
fn a_from_trailing_block(factor: &Factor, b: &Csc, a: &mut [f64]) -> Result<()> {
    let c = b.nrows;
    let last = factor.last();
    let nc = last.len();
    let mut pos = vec![usize::MAX; factor.n()];
    for (q, &j) in last.iter().enumerate() {
        pos[j] = q;
    }
    let l_claim = factor.ledger().claim_f64(nc * nc);
    let l = factor.trailing_block()?;
    let _x_claim = factor.ledger().claim_f64(nc * nc);
    let what = "the inverse of the trailing block";
    let mut x = try_mat(nc, nc, what)?;
    // On the problem's threads: the inverse is dense c^3/3 work (the sparse
    // factorisation decides for itself, see factor::PARALLEL_FLOPS_PER_ENTRY).
    factor
        .threads()
        .run(nc * nc >= PARALLEL_MIN_ENTRIES, |par| {
            let mut mem = try_scratch(llt_inverse::inverse_scratch::<f64>(nc, par), what)?;
            llt_inverse::inverse(x.as_mut(), l.as_ref(), par, MemStack::new(&mut mem));
            Ok::<(), crate::Error>(())
        })?;
    drop(l);
    drop(l_claim);
    // Only the lower triangle of X = S_CC^-1 is written: mirror it, by tiles so
    // that both the reads and the writes stay in cache.
    const TILE: usize = 64;
    for j0 in (0..nc).step_by(TILE) {
        for i0 in (j0..nc).step_by(TILE) {
            for j in j0..(j0 + TILE).min(nc) {
                for i in i0.max(j + 1)..(i0 + TILE).min(nc) {
                    x[(j, i)] = x[(i, j)];
                }
            }
        }
    }
    // B^T by rows of B: row r of B lists (trailing position, value).
    let bt = b.transpose();
    let mut y = vec![0.0; nc];
    for r in 0..c {
        // y = X B_C^T e_r = sum over the nonzeros of row r of X's columns.
        y.iter_mut().for_each(|v| *v = 0.0);
        for k in bt.col_ptr[r]..bt.col_ptr[r + 1] {
            let q = pos[bt.row_idx[k]];
            let w = bt.values[k];
            let xq = x.col(q).try_as_col_major().expect("contiguous").as_slice();
            for (yi, xi) in y.iter_mut().zip(xq) {
                *yi += w * xi;
            }
        }
        // Column r of A = B_C y.
        let col = &mut a[r * c..(r + 1) * c];
        col.iter_mut().for_each(|v| *v = 0.0);
        for &j in last {
            let yj = y[pos[j]];
            if yj != 0.0 {
                for k in b.col_ptr[j]..b.col_ptr[j + 1] {
                    col[b.row_idx[k]] += b.values[k] * yj;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A 2D grid Laplacian plus a small shift (SPD), nx x ny nodes, one DOF each.
    pub(crate) fn grid(nx: usize, ny: usize) -> Csc {
        let id = |i: usize, j: usize| i + nx * j;
        let mut t = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                t.push((id(i, j), id(i, j), 4.1));
                if i + 1 < nx {
                    t.push((id(i, j), id(i + 1, j), -1.0));
                    t.push((id(i + 1, j), id(i, j), -1.0));
                }
                if j + 1 < ny {
                    t.push((id(i, j), id(i, j + 1), -1.0));
                    t.push((id(i, j + 1), id(i, j), -1.0));
                }
            }
        }
        Csc::from_triplets(nx * ny, nx * ny, &t)
    }

    /// d = 2 contacts at `dofs` of a body with `ndof` DOFs: contact i's
    /// normal row is -e_j, its tangent row e_(j+1 mod ndof), j = dofs[i].
    fn contacts_at(dofs: &[usize], ndof: usize) -> (Csc, Csc) {
        let m = dofs.len();
        let nt: Vec<_> = dofs
            .iter()
            .enumerate()
            .map(|(i, &j)| (i, j, -1.0))
            .collect();
        let tt: Vec<_> = (dofs.iter().enumerate())
            .map(|(i, &j)| (i, (j + 1) % ndof, 1.0))
            .collect();
        (
            Csc::from_triplets(m, ndof, &nt),
            Csc::from_triplets(m, ndof, &tt),
        )
    }

    /// K's factor in the METIS ordering on `threads`.
    fn metis_factor(k: &Csc, threads: usize) -> std::sync::Arc<Factor> {
        let pool = std::sync::Arc::new(crate::threads::Threads::new(threads));
        Factor::with_last(k, &[], crate::Ordering::Metis, pool).unwrap()
    }

    #[test]
    fn trailing_block_and_solves_give_the_same_a() {
        let (nx, ny) = (9, 7);
        let k = grid(nx, ny);
        // Contacts on the bottom row, normals and tangents touching two DOFs each.
        let m = 5;
        let mut nt = Vec::new();
        let mut tt = Vec::new();
        for i in 0..m {
            nt.push((i, 2 * i, -1.0));
            nt.push((i, 2 * i + 1, 0.25));
            tt.push((i, 2 * i + 1, 1.0));
            tt.push((i, 2 * i, 0.5 + i as f64));
        }
        let n = Csc::from_triplets(m, nx * ny, &nt);
        let t = Csc::from_triplets(m, nx * ny, &tt);
        let last = contact_dofs(&stack_rows(&n, &t));
        let f1 = Factor::with_last(
            &k,
            &last,
            crate::Ordering::Auto,
            std::sync::Arc::new(crate::threads::Threads::sequential()),
        )
        .unwrap();
        let f0 = Factor::new(&k).unwrap();
        let a1 = Dual::build(&f1, &n, &t, 2, DualForm::Auto).unwrap();
        assert_eq!(a1.condensation, Condensation::TrailingBlock);
        let a0 = Dual::build(&f0, &n, &t, 2, DualForm::Auto).unwrap();
        assert_eq!(a0.condensation, Condensation::Solves);
        let scale = a0.a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        for (x, y) in a0.a.iter().zip(&a1.a) {
            assert!((x - y).abs() <= 1e-13 * scale, "{x} vs {y}");
        }
        // And A is positive definite here: its diagonal is positive.
        for j in 0..a0.c {
            assert!(a0.a[j + j * a0.c] > 0.0);
        }
    }

    /// The products take the tree solves, split on two threads and in one
    /// bin on one, and agree: over the whole factor for contacts spread over
    /// the body (their paths cover L), and restricted to the paths of a
    /// strip's bottom row.
    #[test]
    fn matrix_free_products_on_two_threads_take_the_tree_solves() {
        for (nx, ny, step, restricted) in [(160, 160, 7, false), (2000, 20, 1, true)] {
            let k = grid(nx, ny);
            // d = 2: a normal and a tangent row per contact, on every step-th
            // DOF of the body or along the bottom row.
            let dofs: Vec<usize> = if restricted {
                (0..nx).collect()
            } else {
                (0..nx * ny).step_by(step).collect()
            };
            let (n, t) = contacts_at(&dofs, nx * ny);
            let free_on = |threads: usize| {
                let f = metis_factor(&k, threads);
                let dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
                // The own solves' bytes, besides the bound on the narrowed ones'.
                let b = stack_rows(&n, &t);
                let own = own_solves_bytes(&f, &b)
                    - narrow_bytes(&f, b.nrows)
                    - b.nrows * std::mem::size_of::<usize>();
                (dual, own)
            };
            let (one, own_one) = free_on(1);
            let (two, own_two) = free_on(2);
            fn own(d: &Dual) -> Option<&OwnSolves> {
                d.free.as_ref().expect("matrix-free").own.as_ref()
            }
            let on_one = &own(&one).expect("a sparse factor takes the tree").split;
            assert_eq!(on_one.restricted(), restricted);
            assert!(on_one.threads() == 1 && own_one > 0);
            let split = &own(&two).expect("two threads take the tree").split;
            assert_eq!(split.restricted(), restricted);
            assert_eq!(split.threads(), 2);
            assert!(own_two >= nx * ny * (F64 + 4), "{own_two}");
            let c = one.c;
            let x: Vec<f64> = (0..c).map(|i| (i as f64 * 0.31).cos()).collect();
            let (mut y1, mut y2) = (vec![0.0; c], vec![0.0; c]);
            one.apply(&x, &mut y1);
            two.apply(&x, &mut y2);
            let scale = y1.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (a, b) in y1.iter().zip(&y2) {
                assert!((a - b).abs() <= 1e-13 * scale, "{a} vs {b}");
            }
            two.apply_rough(&x, &mut y2);
            for (a, b) in y1.iter().zip(&y2) {
                assert!((a - b).abs() <= 1e-5 * scale, "{a} vs {b}");
            }
        }
    }

    /// Products narrowed to some contacts' rows (`Dual::narrow_to`) equal the
    /// whole products there, in double and single precision, on one and two
    /// threads, and are zero elsewhere; each narrowing replaces the last
    /// (the second set overlaps the first, so values a solve left behind
    /// would show); no narrowing where the rows' paths cover the factor.
    #[test]
    fn narrowed_products_equal_the_whole_ones_at_their_rows() {
        // A strip with contacts along its bottom row (d = 2): the paths of a
        // stretch of them hold a small part of the factor.
        let (nx, ny) = (2000, 20);
        let k = grid(nx, ny);
        let (n, t) = contacts_at(&(0..nx).collect::<Vec<_>>(), nx * ny);
        for threads in [1, 2] {
            let f = metis_factor(&k, threads);
            let dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
            let c = dual.c;
            for stretch in [300..700, 600..650] {
                let mut rows: Vec<usize> = stretch.clone().chain(stretch.map(|i| nx + i)).collect();
                rows.sort_unstable();
                assert!(dual.narrow_to(&rows), "{threads} thread(s)");
                let mut x = vec![0.0; c];
                for &r in &rows {
                    x[r] = (r as f64 * 0.37).sin();
                }
                let mut whole = vec![0.0; c];
                dual.apply(&x, &mut whole);
                let scale = whole.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                for (rough, tol) in [(false, 1e-13), (true, 1e-5)] {
                    let mut y = vec![f64::NAN; c];
                    dual.apply_narrow(&x, &mut y, rough);
                    for r in 0..c {
                        let want = if rows.binary_search(&r).is_ok() {
                            whole[r]
                        } else {
                            0.0
                        };
                        assert!(
                            (y[r] - want).abs() <= tol * scale,
                            "row {r}: {} vs {want} ({threads} thread(s), rough {rough})",
                            y[r]
                        );
                    }
                }
            }
            dual.widen();
        }
        // Contacts spread over a square: their paths hold the whole factor.
        let (nx, step) = (60, 7);
        let k = grid(nx, nx);
        let dofs: Vec<usize> = (0..nx * nx).step_by(step).collect();
        let (n, t) = contacts_at(&dofs, nx * nx);
        let f = metis_factor(&k, 1);
        let dual = Dual::build(&f, &n, &t, 2, DualForm::MatrixFree).unwrap();
        let all: Vec<usize> = (0..dual.c).collect();
        assert!(!dual.narrow_to(&all));
    }

    #[test]
    fn matrix_free_products_and_diagonal_match_the_dense_a() {
        let (nx, ny) = (11, 6);
        let k = grid(nx, ny);
        // Contacts on the bottom row, rows touching two DOFs each, one contact with
        // empty rows (its A block is zero), d = 3 (two tangent rows per contact).
        let m = 5;
        let (mut nt, mut tt) = (Vec::new(), Vec::new());
        for i in 0..m - 1 {
            nt.push((i, 2 * i, -1.0));
            nt.push((i, 2 * i + 1, 0.3));
            tt.push((2 * i, 2 * i + 1, 1.0));
            tt.push((2 * i + 1, 2 * i, 0.5));
            tt.push((2 * i + 1, 2 * i + 1, -0.25 * i as f64));
        }
        let n = Csc::from_triplets(m, nx * ny, &nt);
        let t = Csc::from_triplets(2 * m, nx * ny, &tt);
        let last = contact_dofs(&stack_rows(&n, &t));
        let f = Factor::with_last(
            &k,
            &last,
            crate::Ordering::Auto,
            std::sync::Arc::new(crate::threads::Threads::sequential()),
        )
        .unwrap();
        let dense = Dual::build(&f, &n, &t, 3, DualForm::Dense).unwrap();
        let free = Dual::build(&f, &n, &t, 3, DualForm::MatrixFree).unwrap();
        assert_eq!(dense.condensation, Condensation::TrailingBlock);
        assert_eq!(free.condensation, Condensation::MatrixFree);
        assert!(free.is_matrix_free() && free.a.is_empty());
        // The contact DOFs are the factor's last: their paths are the trailing
        // supernodes, and the products take the restricted solves.
        assert!(
            free.free
                .as_ref()
                .and_then(|o| o.own.as_ref())
                .is_some_and(|o| o.split.restricted())
        );
        let c = dense.c;
        let scale = dense.a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        for j in 0..c {
            let dj = dense.a[j + j * c];
            assert!((free.diag(j) - dj).abs() <= 1e-13 * scale, "diag {j}");
        }
        for (x, y) in dense.rho.iter().zip(&free.rho) {
            assert!((x - y).abs() <= 1e-12 * x.abs(), "rho {x} vs {y}");
        }
        // Products with a few vectors, sparse and dense.
        let mut y0 = vec![0.0; c];
        let mut y1 = vec![0.0; c];
        for s in 0..4 {
            let x: Vec<f64> = (0..c)
                .map(|i| {
                    if s < 2 && (i + s) % 3 == 0 {
                        0.0
                    } else {
                        (i as f64 * 0.7 + s as f64).sin()
                    }
                })
                .collect();
            dense.apply(&x, &mut y0);
            free.apply(&x, &mut y1);
            let xs = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (a, b) in y0.iter().zip(&y1) {
                assert!((a - b).abs() <= 1e-13 * scale * xs * c as f64, "{a} vs {b}");
            }
            // In single precision (the rough products): to about 1e-7.
            free.apply_rough(&x, &mut y1);
            for (a, b) in y0.iter().zip(&y1) {
                assert!((a - b).abs() <= 1e-5 * scale * xs * c as f64, "{a} vs {b}");
            }
        }
        // A leading block (the normal unknowns alone), with a dense x.
        let m = dense.m;
        let x: Vec<f64> = (0..m).map(|i| 1.0 + i as f64).collect();
        let (mut z0, mut z1) = (vec![0.0; m], vec![0.0; m]);
        dense.apply(&x, &mut z0);
        free.apply(&x, &mut z1);
        for i in 0..m {
            let want: f64 = (0..m).map(|j| dense.a[i + j * c] * x[j]).sum();
            assert!((z0[i] - want).abs() <= 1e-13 * scale * m as f64 * m as f64);
            assert!((z1[i] - want).abs() <= 1e-12 * scale * m as f64 * m as f64);
        }
        // Auto picks dense at this size; without trailing DOFs the dense form is
        // formed by solves, and the matrix-free one works on the plain factor,
        // with the same products.
        let auto = Dual::build(&f, &n, &t, 3, DualForm::Auto).unwrap();
        assert!(!auto.is_matrix_free());
        let plain = Factor::new(&k).unwrap();
        let by_solves = Dual::build(&plain, &n, &t, 3, DualForm::Dense).unwrap();
        assert_eq!(by_solves.condensation, Condensation::Solves);
        let free_plain = Dual::build(&plain, &n, &t, 3, DualForm::MatrixFree).unwrap();
        assert_eq!(free_plain.condensation, Condensation::MatrixFree);
        assert!(!free_plain.trailing);
        let x: Vec<f64> = (0..c).map(|i| (i as f64 * 0.3).cos()).collect();
        dense.apply(&x, &mut y0);
        free_plain.apply(&x, &mut y1);
        for (a, b) in y0.iter().zip(&y1) {
            assert!((a - b).abs() <= 1e-12 * scale * c as f64, "{a} vs {b}");
        }
    }
}
