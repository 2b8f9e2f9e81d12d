//! K's Cholesky factorisation (faer): the symbolic analysis (fill-reducing
//! ordering, elimination tree) is done once per sparsity pattern, the numeric
//! factorisation once per set of values, and each solve reuses both. A K with every
//! entry stored (a dense K: a Schur complement from the user's own solver) skips
//! the ordering and the symbolic analysis and is factored by dense Cholesky.

use crate::error::{ErrorKind, Result, fail};
use crate::memory::{Claim, Ledger};
use crate::options::Ordering;
use crate::sparse::Csc;
use crate::threads::{PARALLEL_MIN_ENTRIES, Threads};
use crate::tree_cholesky::Plan as TreePlan;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::perm::PermRef;
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, MatMut, Par, Side};
use std::sync::Arc;
use std::time::Instant;

/// A Cholesky pivot L_jj^2 below this fraction of K_jj makes K numerically
/// singular (`NotPositiveDefinite`): relative pivots that small come from rounding
/// (rigid-body modes of a body without enough Dirichlet conditions), and the solve
/// would lose every digit.
pub const PIVOT_TOL: f64 = 1e-14;

/// The solves with the factor, a dense factorisation and faer's supernodal
/// factorisation (where the tree split is not taken: L below
/// PARALLEL_MIN_ENTRIES entries, or a tree that does not split) hand the
/// threads to faer's dense kernels when the flops per entry of L, about the
/// mean front size, exceed this; they run sequentially below, where the work
/// is in small supernodes and threads only add overhead (measurements:
/// BENCHMARKS.md, "Tuning measurements"). The numeric factorisation of a
/// larger L on several threads goes by the elimination tree instead
/// (`Factor::tree_plan`), small fronts included.
const PARALLEL_FLOPS_PER_ENTRY: f64 = 500.0;

/// `Ordering::Auto` tries METIS besides AMD when AMD's factor needs more flops per
/// entry of L than this (about its mean front size, as CHOLMOD's default policy
/// decides): 3D meshes, where nested dissection saves several times its cost; in
/// 2D AMD's fronts are small and METIS's analysis costs more than it can save
/// (BENCHMARKS.md, "Orderings, threads and CHOLMOD").
const METIS_FLOPS_PER_ENTRY: f64 = 500.0;

/// The Cholesky factor L L^T = P K P^T of an SPD matrix K, with the pattern of K it
/// was computed for.
pub struct Factor {
    /// How L is stored.
    layout: Layout,
    /// L's values: the supernodes (sparse), or n x n column-major with L in the
    /// lower triangle (dense).
    l_values: Vec<f64>,
    /// The bytes of `l_values` on the ledger.
    l_claim: Option<Claim>,
    /// The problem's count of its large allocations.
    ledger: Arc<Ledger>,
    /// K's pattern (compressed columns), shared by the copies
    /// [`Factor::unfactored_copy`] makes.
    col_ptr: Arc<[usize]>,
    row_idx: Arc<[usize]>,
    /// The DOFs ordered last, in this order (empty for a plain AMD ordering).
    last: Vec<usize>,
    /// The fill-reducing ordering, new -> old (dense: the DOFs not in `last` in
    /// their order, then `last`).
    fwd: Vec<usize>,
    /// Which ordering that is (`Amd`, `Metis` or `Dense`, never `Auto`).
    ordering: Ordering,
    /// Seconds of the analysis: the ordering (both, where AUTO tries METIS) and
    /// the symbolic factorisation.
    pub analyse_seconds: f64,
    /// Seconds of the last numeric factorisation.
    pub factor_seconds: f64,
    /// The problem's threads.
    threads: Arc<Threads>,
    /// Whether the solves, a dense factorisation and faer's factorisation
    /// (where the tree split is not taken) hand them to the dense kernels
    /// (see PARALLEL_FLOPS_PER_ENTRY).
    parallel: bool,
}

/// How a factor's L is stored.
enum Layout {
    /// Supernodal (faer's sparse Cholesky); the symbolic analysis is shared by the
    /// copies [`Factor::unfactored_copy`] makes.
    Supernodal(Arc<SymbolicCholesky<usize>>),
    /// Dense n x n: K had every entry stored.
    Dense,
}

/// True when `k` (n x n) stores every entry: a dense K, factored by dense Cholesky
/// without ordering or symbolic analysis (a fill-reducing ordering cannot help).
fn is_dense(k: &Csc) -> bool {
    k.nrows > 0 && k.nnz() == k.nrows * k.ncols
}

/// The supernodal symbolic Cholesky factor of `k` in the ordering (`fwd`, `inv`).
/// Always supernodal: the pivots and the trailing block are read from the
/// supernodes.
fn analyse(k: &Csc, fwd: &[usize], inv: &[usize]) -> Result<SymbolicCholesky<usize>> {
    let n = k.nrows;
    let sym = SymbolicSparseColMatRef::new_checked(n, n, &k.col_ptr, None, &k.row_idx);
    let params = CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        ..Default::default()
    };
    factorize_symbolic_cholesky(
        sym,
        Side::Lower,
        SymmetricOrdering::Custom(PermRef::new_checked(fwd, inv, n)),
        params,
    )
    .map_err(|e| {
        crate::Error::new(
            ErrorKind::OutOfMemory,
            format!("K: symbolic analysis: {e:?}"),
        )
    })
}

/// (nonzeros of L, dense supernodal blocks included; flops of the numeric
/// factorisation, sum over columns of (rows below + 1)^2) of a supernodal symbolic
/// factor.
fn symbolic_size(symbolic: &SymbolicCholesky<usize>) -> (usize, f64) {
    let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
        unreachable!("always supernodal");
    };
    let mut flops = 0.0;
    for s in 0..sym.n_supernodes() {
        let node = sym.supernode(s);
        let width = sym.supernode_end()[s] - sym.supernode_begin()[s];
        let below = node.pattern().len();
        for jl in 0..width {
            let r = (width - jl + below) as f64;
            flops += r * r;
        }
    }
    (sym.len_val(), flops)
}

impl Factor {
    /// Analyses and factors `k` (both triangles stored, only the lower is read).
    ///
    /// Errors: `NotPositiveDefinite` (non-positive pivot: K singular or indefinite),
    /// `OutOfMemory`.
    #[cfg(any(test, feature = "internals"))]
    pub fn new(k: &Csc) -> Result<Arc<Factor>> {
        Self::with_last(k, &[], Ordering::Auto, Arc::new(Threads::sequential()))
    }

    /// Analyses and factors `k` with the DOFs `last` (distinct, in range) ordered
    /// last, in the given order, and the others by `ordering` (see
    /// [`crate::ordering`]; `Auto`: AMD, and METIS as well where AMD's factor
    /// needs more than METIS_FLOPS_PER_ENTRY flops per entry of L, the one with
    /// fewer flops kept): the trailing block of the factor then
    /// gives the Schur complement of K onto `last` (see
    /// [`Factor::trailing_block`]). `threads`: the pool the factorisation and the
    /// solves may use (they run sequentially where the fronts are small).
    ///
    /// Errors: as [`Factor::new`].
    #[cfg(any(test, feature = "internals"))]
    pub fn with_last(
        k: &Csc,
        last: &[usize],
        ordering: Ordering,
        threads: Arc<Threads>,
    ) -> Result<Arc<Factor>> {
        let mut f = Self::analyse(k, last, ordering, false, threads, Ledger::new())?;
        f.refactor(k)?;
        Ok(Arc::new(f))
    }

    /// The analysis of `Factor::with_last` alone (ordering and symbolic
    /// factorisation, no numeric work), where `nd_first` makes `Auto` take
    /// METIS alone (3D problems; AMD where METIS fails) rather than AMD and
    /// METIS where AMD's fronts are large: the factor's size is known
    /// ([`Factor::nnz_and_flops`], [`Factor::factor_scratch_bytes`]) and
    /// [`Factor::refactor`] computes its values. Allocations of the numeric
    /// factor and its workspace are counted on `ledger`.
    ///
    /// Errors: `OutOfMemory` (the ordering or the symbolic analysis).
    pub(crate) fn analyse(
        k: &Csc,
        last: &[usize],
        ordering: Ordering,
        nd_first: bool,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Result<Factor> {
        let n = k.nrows;
        if is_dense(k) {
            return Ok(Self::analyse_dense(n, last, threads, ledger));
        }
        let start = Instant::now();
        // The orderings' graphs come from the pattern of K + K^T (a FE code's
        // K may store an entry on one side only), made once for both.
        let sym = crate::ordering::symmetric_pattern(k)
            .ok_or_else(|| crate::Error::new(ErrorKind::OutOfMemory, "K: its pattern's mirror"))?;
        let order = |how: Ordering| match how {
            Ordering::Metis => crate::ordering::metis_with_last(&sym, last),
            _ => crate::ordering::amd_with_last(&sym, last),
        };
        let failed = |how: Ordering| {
            let why = match how {
                Ordering::Metis => "out of memory, or METIS refused K's graph",
                _ => "out of memory",
            };
            fail(
                ErrorKind::OutOfMemory,
                format!("K: the {} ordering failed ({why})", how.name()),
            )
        };
        let mut first = match ordering {
            Ordering::Metis => Ordering::Metis,
            Ordering::Auto if nd_first => Ordering::Metis,
            _ => Ordering::Amd,
        };
        // AUTO goes on with AMD where METIS fails (and does not try METIS
        // again as its second ordering).
        let mut fell_back = false;
        let (fwd, inv) = match order(first) {
            Some(p) => p,
            None if ordering == Ordering::Auto && first == Ordering::Metis => {
                first = Ordering::Amd;
                fell_back = true;
                match order(first) {
                    Some(p) => p,
                    None => return failed(first),
                }
            }
            None => return failed(first),
        };
        let mut symbolic = analyse(k, &fwd, &inv)?;
        let (mut ordering_used, mut fwd) = (first, fwd);
        // AUTO in 2D: METIS after AMD too where AMD's factor has large fronts
        // (flops per entry of L, about the mean front size, above
        // METIS_FLOPS_PER_ENTRY), the cheaper kept; elsewhere the second
        // analysis costs more than it can save. In 3D (`nd_first`) METIS alone:
        // AMD's factor needed 1.1 to 3.8 times METIS's flops on every 3D mesh
        // of the benchmark (3d-10x10x5 to 3d-64x64x6), small fronts included
        // (the thin slabs 3d-24x24x4 to 3d-48x48x4, 230-370 flops per entry of
        // L: 1.9-3.0 times), and its analysis, thrown away, cost 0.15-0.22 of
        // a factorisation on those slabs; AMD won only on tiny, nearly dense
        // K (FCLib's 162-DOF cubes, by up to 10 %; BENCHMARKS.md, "Orderings,
        // threads and CHOLMOD"). A failed METIS leaves AMD.
        let (nnz, flops) = symbolic_size(&symbolic);
        let large = flops > METIS_FLOPS_PER_ENTRY * nnz as f64;
        if ordering == Ordering::Auto
            && !fell_back
            && first == Ordering::Amd
            && large
            && let Some((fwd_2, inv_2)) = order(Ordering::Metis)
        {
            let symbolic_2 = analyse(k, &fwd_2, &inv_2)?;
            let (f1, f2) = (flops, symbolic_size(&symbolic_2).1);
            // Ties to AMD (the first).
            if f2 < f1 {
                (symbolic, ordering_used, fwd) = (symbolic_2, Ordering::Metis, fwd_2);
            }
        }
        drop(sym);
        let analyse_seconds = start.elapsed().as_secs_f64();
        let f = Self::unfactored(
            k,
            symbolic,
            fwd,
            (last.to_vec(), ordering_used, analyse_seconds),
            threads,
            ledger,
        );
        debug_assert_eq!(f.n(), n);
        Ok(f)
    }

    /// The factor of `k` analysed as `symbolic` in the order `fwd`, with no
    /// values yet: `last`, the ordering that made `fwd` and the analysis's
    /// seconds as given, the numeric work on threads where its fronts are
    /// large enough.
    fn unfactored(
        k: &Csc,
        symbolic: SymbolicCholesky<usize>,
        fwd: Vec<usize>,
        (last, ordering, analyse_seconds): (Vec<usize>, Ordering, f64),
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Factor {
        let mut f = Factor {
            l_values: Vec::new(),
            l_claim: None,
            ledger,
            layout: Layout::Supernodal(Arc::new(symbolic)),
            col_ptr: Arc::from(&k.col_ptr[..]),
            row_idx: Arc::from(&k.row_idx[..]),
            last,
            fwd,
            ordering,
            analyse_seconds,
            factor_seconds: 0.0,
            threads,
            parallel: false,
        };
        f.parallel = f.fronts_are_large();
        f
    }

    /// Whether the numeric work pays on threads: more than
    /// PARALLEL_FLOPS_PER_ENTRY flops per entry of L.
    fn fronts_are_large(&self) -> bool {
        let (nnz, flops) = self.nnz_and_flops();
        flops > PARALLEL_FLOPS_PER_ENTRY * nnz as f64
    }

    /// The analysis of `k` in the order `fwd` (the DOF at each position),
    /// made elsewhere: no ordering computed. A principal submatrix analysed in
    /// the order of its DOFs in a larger matrix's factor has no more fill than
    /// that factor (its filled graph is a subgraph). Allocations counted as in
    /// [`Factor::analyse`].
    ///
    /// Errors: `OutOfMemory` (the symbolic analysis).
    pub(crate) fn analyse_in_order(
        k: &Csc,
        fwd: Vec<usize>,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Result<Factor> {
        let mut inv = vec![0; fwd.len()];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        let symbolic = analyse(k, &fwd, &inv)?;
        let how = (Vec::new(), Ordering::Amd, 0.0);
        Ok(Self::unfactored(k, symbolic, fwd, how, threads, ledger))
    }

    /// The analysis of a dense K (n x n, every entry stored): no ordering beyond
    /// moving `last` to the end, no symbolic factorisation.
    fn analyse_dense(
        n: usize,
        last: &[usize],
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Factor {
        let mut is_last = vec![false; n];
        last.iter().for_each(|&j| is_last[j] = true);
        let mut fwd: Vec<usize> = (0..n).filter(|&j| !is_last[j]).collect();
        fwd.extend_from_slice(last);
        let mut f = Factor {
            layout: Layout::Dense,
            l_values: Vec::new(),
            l_claim: None,
            ledger,
            col_ptr: Arc::from([]),
            row_idx: Arc::from([]),
            last: last.to_vec(),
            fwd,
            ordering: Ordering::Dense,
            analyse_seconds: 0.0,
            factor_seconds: 0.0,
            threads,
            parallel: false,
        };
        f.parallel = f.fronts_are_large();
        f
    }

    /// True when K was dense and L is held dense.
    pub(crate) fn is_dense(&self) -> bool {
        matches!(self.layout, Layout::Dense)
    }

    /// The sparse symbolic analysis; panics on a dense factor.
    fn symbolic(&self) -> &SymbolicCholesky<usize> {
        match &self.layout {
            Layout::Supernodal(s) => s,
            Layout::Dense => unreachable!("a dense factor has no symbolic analysis"),
        }
    }

    /// L of a dense factor (n x n, lower triangle).
    fn dense_l(&self) -> faer::MatRef<'_, f64> {
        let n = self.n();
        faer::MatRef::from_column_major_slice(&self.l_values, n, n)
    }

    /// The problem's count of its large allocations.
    pub(crate) fn ledger(&self) -> &Arc<Ledger> {
        &self.ledger
    }

    /// The parallelism of the factorisation and the solves.
    fn par(&self) -> Par {
        match self.parallel {
            true => Par::rayon(self.threads.count()),
            false => Par::Seq,
        }
    }

    /// Bytes of the numeric factorisation's workspace.
    pub(crate) fn factor_scratch_bytes(&self) -> usize {
        match &self.layout {
            Layout::Supernodal(symbolic) => {
                let faer = symbolic
                    .factorize_numeric_llt_scratch::<f64>(self.par(), Default::default())
                    .size_bytes();
                // Split by the tree (`Factor::tree_plan`): P K P^T's lower
                // triangle as faer forms it, and the plan and the threads'
                // scratch on top.
                match symbolic.raw() {
                    SymbolicCholeskyRaw::Supernodal(sym)
                        if self.threads.count() >= 2 && sym.len_val() >= PARALLEL_MIN_ENTRIES =>
                    {
                        faer + crate::tree_cholesky::bytes_bound(sym, self.threads.count())
                    }
                    _ => faer,
                }
            }
            Layout::Dense => faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(
                self.n(),
                self.par(),
                Default::default(),
            )
            .size_bytes(),
        }
    }

    /// The threads the factorisation and the solves use.
    pub(crate) fn threads(&self) -> &Arc<Threads> {
        &self.threads
    }

    /// The ordering that was used: `Amd` or `Metis`.
    pub fn ordering(&self) -> Ordering {
        self.ordering
    }

    /// The smallest relative pivot L_jj^2 / K_jj of a numeric factor `values` (j in
    /// the factor's ordering), or None for n = 0.
    fn smallest_pivot(&self, values: &[f64], k: &Csc) -> Option<(usize, f64)> {
        // Rows are sorted within a column (`Csc`): the diagonal by bisection.
        let diag_k = |old: usize| {
            let (lo, hi) = (k.col_ptr[old], k.col_ptr[old + 1]);
            k.row_idx[lo..hi]
                .binary_search(&old)
                .map_or(0.0, |at| k.values[lo + at])
        };
        let ratio = |l_jj: f64, k_jj: f64| if k_jj > 0.0 { l_jj * l_jj / k_jj } else { 0.0 };
        if self.is_dense() {
            let n = self.n();
            return (0..n)
                .map(|j| (j, ratio(values[j * n + j], diag_k(self.fwd[j]))))
                .min_by(|a, b| a.1.total_cmp(&b.1));
        }
        let sym = self.supernodal_symbolic();
        let llt = SupernodalLltRef::<usize, f64>::new(sym, values);
        let mut worst: Option<(usize, f64)> = None;
        for s in 0..sym.n_supernodes() {
            let node = llt.supernode(s);
            let val = node.val();
            for jl in 0..val.ncols() {
                let j = node.start() + jl;
                let ratio = ratio(val[(jl, jl)], diag_k(self.fwd[j]));
                if worst.is_none_or(|(_, r)| ratio < r) {
                    worst = Some((j, ratio));
                }
            }
        }
        worst
    }

    /// The size of the factor: (nonzeros of L, dense supernodal blocks included;
    /// flops of the numeric factorisation, sum over columns of (rows below + 1)^2).
    pub fn nnz_and_flops(&self) -> (usize, f64) {
        match &self.layout {
            Layout::Supernodal(symbolic) => symbolic_size(symbolic),
            Layout::Dense => {
                let n = self.n();
                let flops = (1..=n).map(|r| (r * r) as f64).sum();
                (n * (n + 1) / 2, flops)
            }
        }
    }

    /// The DOFs ordered last (empty when the ordering is plain AMD).
    pub fn last(&self) -> &[usize] {
        &self.last
    }

    /// The trailing nc x nc block L_CC of the factor, nc = `last().len()`: with
    /// C = `last`, L_CC L_CC^T is the Schur complement of K onto C, so
    /// (K^-1)_CC = L_CC^-T L_CC^-1. Lower triangular, rows and columns in the order
    /// of `last`.
    ///
    /// Errors: `OutOfMemory` when the nc x nc block cannot be allocated.
    pub fn trailing_block(&self) -> Result<Mat<f64>> {
        let n = self.n();
        let nc = self.last.len();
        let mut l = crate::memory::try_mat(nc, nc, "the trailing block of the factor")?;
        if nc == 0 {
            return Ok(l);
        }
        let first = n - nc;
        if self.is_dense() {
            let dense = self.dense_l().submatrix(first, first, nc, nc);
            for j in 0..nc {
                for i in j..nc {
                    l[(i, j)] = dense[(i, j)];
                }
            }
            return Ok(l);
        }
        let sym = self.supernodal_symbolic();
        let llt = SupernodalLltRef::<usize, f64>::new(sym, &self.l_values);
        for s in 0..sym.n_supernodes() {
            let node = llt.supernode(s);
            let start = node.start();
            let val = node.val();
            let width = val.ncols();
            if start + width <= first {
                continue;
            }
            let pattern = node.pattern();
            for jl in first.saturating_sub(start)..width {
                let j = start + jl;
                let src = val
                    .col(jl)
                    .try_as_col_major()
                    .expect("contiguous")
                    .as_slice();
                let dst = l
                    .col_mut(j - first)
                    .try_as_col_major_mut()
                    .expect("contiguous")
                    .as_slice_mut();
                dst[j - first..start + width - first].copy_from_slice(&src[jl..width]);
                for (&row, &v) in pattern.iter().zip(&src[width..]) {
                    dst[row - first] = v;
                }
            }
        }
        Ok(l)
    }

    /// Number of rows of K.
    pub fn n(&self) -> usize {
        self.fwd.len()
    }

    /// True when `k` has exactly the pattern this factor was analysed for (dense:
    /// every entry stored, the same n).
    pub fn same_pattern(&self, k: &Csc) -> bool {
        match self.layout {
            Layout::Supernodal(_) => {
                k.col_ptr[..] == self.col_ptr[..] && k.row_idx[..] == self.row_idx[..]
            }
            Layout::Dense => k.nrows == self.n() && is_dense(k),
        }
    }

    /// Numeric refactorisation with new values on the same pattern, reusing the
    /// symbolic analysis. On error the previous factor is kept (a caller that must
    /// keep it whatever happens after refactors an [`Factor::unfactored_copy`]).
    ///
    /// Errors: `BadArgument` (pattern differs), `NotPositiveDefinite`, `OutOfMemory`.
    pub fn refactor(&mut self, k: &Csc) -> Result<()> {
        self.refactor_into(k, &mut Vec::new())
    }

    /// [`Factor::refactor`] into `spare`'s storage where it has the length of
    /// L's values (the values of a replaced factor of the same analysis, see
    /// [`Factor::into_values`]): the factorisation then writes over memory
    /// the process already has, where a new vector's pages are each faulted
    /// in and zeroed by the system first (0.1-0.3 s of a 0.6 s numeric
    /// factorisation of 3d-64x64x6's 38 M entries measured on the
    /// benchmark host, bench_results/refactor_probe_1t.txt). `spare` is
    /// left empty where it was taken; else it is left as it was. Where the factorisation fails (a pivot not
    /// positive or too small, its workspace refused), it holds that storage
    /// again, with other values (and a new vector's where it had another
    /// length).
    pub(crate) fn refactor_into(&mut self, k: &Csc, spare: &mut Vec<f64>) -> Result<()> {
        if !self.same_pattern(k) {
            return fail(
                ErrorKind::BadArgument,
                "K: the sparsity pattern differs from the one the problem was created with",
            );
        }
        let start = Instant::now();
        let scratch_claim = self.ledger.claim(self.factor_scratch_bytes());
        let values_claim = self.ledger.claim_f64(self.values_len());
        let mut values = if spare.len() == self.values_len() {
            let mut values = std::mem::take(spare);
            // The supernodal factorisations (faer's, the tree's) zero the
            // values themselves; a dense factor's solves rely on zeros above
            // the diagonal.
            if matches!(self.layout, Layout::Dense) {
                values.fill(0.0);
            }
            values
        } else {
            self.values_vec()?
        };
        let result = match &self.layout {
            Layout::Supernodal(symbolic) => self.factor_supernodal(symbolic, k, &mut values),
            Layout::Dense => self.factor_dense(k, &mut values),
        };
        drop(scratch_claim);
        let result = match result {
            Ok(result) => result,
            Err(e) => {
                *spare = values;
                return Err(e);
            }
        };
        let message = match result {
            Err(e) => format!(
                "K is not positive definite (Cholesky: {e}): singular, indefinite, \
                 or missing Dirichlet conditions"
            ),
            Ok(()) => match self.smallest_pivot(&values, k) {
                Some((j, ratio)) if ratio < PIVOT_TOL => format!(
                    "K is numerically singular: the Cholesky pivot of DOF {} is {ratio:.1e} \
                     of its diagonal entry (< {PIVOT_TOL:e}); a rigid-body mode, missing \
                     Dirichlet conditions, or cond(K) beyond about 1e14",
                    self.fwd[j]
                ),
                _ => {
                    self.l_values = values;
                    self.l_claim = Some(values_claim);
                    self.factor_seconds = start.elapsed().as_secs_f64();
                    return Ok(());
                }
            },
        };
        // The storage goes back where it came from (a new vector to a caller
        // that gave none).
        *spare = values;
        fail(ErrorKind::NotPositiveDefinite, message)
    }

    /// Bytes of L's values once factored (sparse: the supernodes; dense: n^2).
    pub(crate) fn values_bytes(&self) -> usize {
        self.values_len() * std::mem::size_of::<f64>()
    }

    /// The number of values of L (sparse: the supernodes; dense: n^2).
    fn values_len(&self) -> usize {
        match &self.layout {
            Layout::Supernodal(symbolic) => symbolic.len_val(),
            Layout::Dense => self.n() * self.n(),
        }
    }

    /// A zeroed vector for L's values, or `OutOfMemory`.
    fn values_vec(&self) -> Result<Vec<f64>> {
        zeroed(self.values_len())
            .ok_or_else(|| crate::Error::new(ErrorKind::OutOfMemory, "K: Cholesky factor values"))
    }

    /// L's values with their count on the ledger, this factor dropped: the
    /// storage [`Factor::refactor_into`] reuses (empty where it holds none).
    pub(crate) fn into_values(self) -> (Vec<f64>, Option<Claim>) {
        (self.l_values, self.l_claim)
    }

    /// The numeric supernodal factorisation of `k` into `values` (L's length,
    /// any contents): Err(message) inside where a pivot was not positive.
    fn factor_supernodal(
        &self,
        symbolic: &SymbolicCholesky<usize>,
        k: &Csc,
        values: &mut [f64],
    ) -> Result<std::result::Result<(), String>> {
        let n = self.n();
        let a = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx),
            &k.values,
        );
        if let Some(plan) = self.tree_plan(symbolic) {
            return self.factor_on_tree(symbolic, a, &plan, values);
        }
        self.threads.run(self.parallel, |par| {
            let req = symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default());
            let mut mem = workspace(req)?;
            let result = symbolic.factorize_numeric_llt::<f64>(
                values,
                a,
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            );
            Ok(result.map(|_| ()).map_err(|e| format!("{e:?}")))
        })
    }

    /// The split of the numeric factorisation between the factor's threads
    /// by its elimination tree (`tree_cholesky`), where there are
    /// several, L has PARALLEL_MIN_ENTRIES entries at least and the tree
    /// splits into subtrees. Small fronts too: the subtrees are what the
    /// threads share, not the dense kernels (measured on 2 threads: 1.5 x
    /// on the thin slab 3d-48x48x4, 1.7 x on 2d-2000x250, whose fronts are
    /// small; BENCHMARKS.md, "Orderings, threads and CHOLMOD").
    fn tree_plan(&self, symbolic: &SymbolicCholesky<usize>) -> Option<TreePlan> {
        let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
            return None;
        };
        if self.threads.count() < 2 || sym.len_val() < PARALLEL_MIN_ENTRIES {
            return None;
        }
        TreePlan::of(sym, self.threads.count())
    }

    /// [`Factor::factor_supernodal`] split by `plan`: P K P^T's lower
    /// triangle formed as faer forms it (in its scratch's place), then the
    /// subtrees on the threads and the top on all of them.
    fn factor_on_tree(
        &self,
        symbolic: &SymbolicCholesky<usize>,
        a: SparseColMatRef<'_, usize, f64>,
        plan: &TreePlan,
        values: &mut [f64],
    ) -> Result<std::result::Result<(), String>> {
        let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
            unreachable!("a tree plan is made for a supernodal factor only");
        };
        let n = self.n();
        let nnz = a.compute_nnz();
        let what = "K: the factorisation's scratch";
        let mut new_values = crate::memory::try_zeros::<f64>(nnz, what)?;
        let mut new_col_ptr = crate::memory::try_zeros::<usize>(n + 1, what)?;
        let mut new_row_idx = crate::memory::try_zeros::<usize>(nnz, what)?;
        let mut mem = workspace(StackReq::new::<usize>(n))?;
        let permuted;
        let lower = match symbolic.perm() {
            Some(perm) => {
                permuted = faer::sparse::utils::permute_self_adjoint_to_unsorted(
                    &mut new_values,
                    &mut new_col_ptr,
                    &mut new_row_idx,
                    a,
                    perm,
                    Side::Lower,
                    Side::Lower,
                    MemStack::new(&mut mem),
                );
                faer::reborrow::Reborrow::rb(&permuted)
            }
            None => a,
        };
        let result = self.threads.run(true, |par| {
            crate::tree_cholesky::factor(plan, sym, lower, values, par)
        });
        Ok(result.map_err(|index| format!("NonPositivePivot {{ index: {index} }}")))
    }

    /// The dense Cholesky factorisation of P K P^T (k stores every entry): as
    /// [`Factor::factor_supernodal`].
    fn factor_dense(&self, k: &Csc, values: &mut [f64]) -> Result<std::result::Result<(), String>> {
        use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
        let n = self.n();
        let new_of = self.new_of_old();
        // The lower triangle of P K P^T, column-major.
        for j in 0..n {
            let jn = new_of[j];
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                let i_n = new_of[k.row_idx[p]];
                if i_n >= jn {
                    values[jn * n + i_n] = k.values[p];
                }
            }
        }
        self.threads.run(self.parallel, |par| {
            let req = cholesky_in_place_scratch::<f64>(n, par, Default::default());
            let mut mem = workspace(req)?;
            let l = faer::MatMut::from_column_major_slice_mut(values, n, n);
            let result = cholesky_in_place(
                l,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            );
            Ok(result.map(|_| ()).map_err(|e| format!("{e:?}")))
        })
    }

    /// Workspace needed by [`Factor::solve_in_place`] for `ncols` right-hand sides.
    pub fn solve_scratch(&self, ncols: usize) -> StackReq {
        match &self.layout {
            Layout::Supernodal(symbolic) => {
                symbolic.solve_in_place_scratch::<f64>(ncols, self.par())
            }
            Layout::Dense => faer::linalg::temp_mat_scratch::<f64>(self.n(), ncols),
        }
    }

    /// Overwrites `rhs` (n x k) with K^-1 rhs, using `stack` as workspace (at least
    /// `solve_scratch(k)`).
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>, stack: &mut MemStack) {
        self.solve_values(&self.l_values, rhs, stack);
    }

    /// K^-1 rhs with L's values `values` (of this factor, in double or single
    /// precision), `stack` as workspace.
    pub(crate) fn solve_values<T: faer::traits::ComplexField>(
        &self,
        values: &[T],
        rhs: MatMut<'_, T>,
        stack: &mut MemStack,
    ) {
        match &self.layout {
            Layout::Supernodal(symbolic) => {
                let llt = LltRef::new(symbolic, values);
                self.threads.run(self.parallel, |par| {
                    llt.solve_in_place_with_conj(Conj::No, rhs, par, stack);
                });
            }
            Layout::Dense => self.threads.run(self.parallel, |par| {
                dense_solve(values, &self.fwd, rhs, par, stack);
            }),
        }
    }

    /// The fill-reducing ordering: the DOF at each position of the factor
    /// (new -> old; [`Factor::new_of_old`] is its inverse).
    pub(crate) fn old_of_new(&self) -> &[usize] {
        &self.fwd
    }

    /// L's values (supernodal layout of [`Factor::supernodal_symbolic`]).
    pub(crate) fn values(&self) -> &[f64] {
        &self.l_values
    }

    /// L's values rounded to single precision (for [`Factor::solve_single`]).
    ///
    /// Errors: `OutOfMemory` when the copy cannot be allocated.
    pub fn single_values(&self) -> Result<Vec<f32>> {
        self.single_values_in(Vec::new())
    }

    /// [`Factor::single_values`] written into `buffer` where it has their
    /// length (a copy of an earlier factor with this analysis: its pages are
    /// already mapped), else into a new allocation.
    pub(crate) fn single_values_in(&self, buffer: Vec<f32>) -> Result<Vec<f32>> {
        let mut v = if buffer.len() == self.l_values.len() {
            buffer
        } else {
            drop(buffer);
            crate::memory::try_zeros(
                self.l_values.len(),
                "the single-precision copy of the factor",
            )?
        };
        for (s, &d) in v.iter_mut().zip(&self.l_values) {
            *s = d as f32;
        }
        Ok(v)
    }

    /// Workspace of [`Factor::solve_single`] for one right-hand side.
    pub fn solve_scratch_single(&self) -> StackReq {
        match &self.layout {
            Layout::Supernodal(symbolic) => symbolic.solve_in_place_scratch::<f32>(1, self.par()),
            Layout::Dense => faer::linalg::temp_mat_scratch::<f32>(self.n(), 1),
        }
    }

    /// Overwrites `rhs` (n x 1) with an approximation of K^-1 rhs in single
    /// precision, with `values` = [`Factor::single_values`]: half the memory
    /// traffic of a solve, relative error about 1e-7 cond(K)^(1/2) per factor
    /// solve; for the inexact inner solves of a Newton step only.
    pub fn solve_single(&self, values: &[f32], rhs: MatMut<'_, f32>, stack: &mut MemStack) {
        self.solve_values(values, rhs, stack);
    }

    /// The forward half of a solve: y := L^-1 P x, y in the factor's ordering
    /// (`x`, `y`: n). Allocates its workspace.
    pub fn forward(&self, x: &[f64], y: &mut [f64]) {
        let n = self.n();
        for (new, &old) in self.fwd.iter().enumerate() {
            y[new] = x[old];
        }
        if self.is_dense() {
            let y = faer::MatMut::from_column_major_slice_mut(y, n, 1);
            self.threads.run(self.parallel, |par| {
                solve_lower_triangular_in_place(self.dense_l(), y, par);
            });
            return;
        }
        let mut mem = MemBuffer::new(self.solve_scratch(1));
        let llt = self.supernodal();
        self.threads.run(self.parallel, |par| {
            let y = faer::MatMut::from_column_major_slice_mut(y, n, 1);
            llt.l_solve_with_conj(Conj::No, y, par, MemStack::new(&mut mem));
        });
    }

    /// As [`Factor::forward`] for an x that vanishes outside the trailing DOFs:
    /// `x_last[q]` is x at DOF `last()[q]`. y is zero before the trailing block,
    /// so only the trailing supernodes are touched: O(nc^2) work, not O(nnz(L)).
    /// Panics unless `x_last.len() == last().len()` and `y.len() == n()`.
    pub fn forward_from_last(&self, x_last: &[f64], y: &mut [f64]) {
        let n = self.n();
        assert_eq!(x_last.len(), self.last.len());
        assert_eq!(y.len(), n);
        let first = n - self.last.len();
        y[..first].iter_mut().for_each(|v| *v = 0.0);
        y[first..].copy_from_slice(x_last);
        if self.is_dense() {
            let nc = n - first;
            let l = self.dense_l().submatrix(first, first, nc, nc);
            let y = faer::MatMut::from_column_major_slice_mut(&mut y[first..], nc, 1);
            self.threads.run(self.parallel, |par| {
                solve_lower_triangular_in_place(l, y, par);
            });
            return;
        }
        let sym = self.supernodal_symbolic();
        let llt = self.supernodal();
        // Column-oriented L y = rhs over the supernodes that end after `first`.
        let from = sym.supernode_end().partition_point(|&end| end <= first);
        for s in from..sym.n_supernodes() {
            let node = llt.supernode(s);
            let (start, val) = (node.start(), node.val());
            let width = val.ncols();
            let pattern = node.pattern();
            for jl in 0..width {
                let j = start + jl;
                y[j] /= val[(jl, jl)];
                let yj = y[j];
                if yj == 0.0 {
                    continue;
                }
                for il in jl + 1..width {
                    y[start + il] -= val[(il, jl)] * yj;
                }
                for (q, &row) in pattern.iter().enumerate() {
                    y[row] -= val[(width + q, jl)] * yj;
                }
            }
        }
    }

    /// The backward half of a solve: x := P^T L^-T y (`y`, in the factor's
    /// ordering, is overwritten; `x`: n). `backward(forward(b))` = K^-1 b.
    /// Allocates its workspace.
    pub fn backward(&self, y: &mut [f64], x: &mut [f64]) {
        let n = self.n();
        if self.is_dense() {
            let ym = faer::MatMut::from_column_major_slice_mut(y, n, 1);
            self.threads.run(self.parallel, |par| {
                solve_upper_triangular_in_place(self.dense_l().transpose(), ym, par);
            });
            for (new, &old) in self.fwd.iter().enumerate() {
                x[old] = y[new];
            }
            return;
        }
        let mut mem = MemBuffer::new(self.solve_scratch(1));
        let llt = self.supernodal();
        self.threads.run(self.parallel, |par| {
            let y = faer::MatMut::from_column_major_slice_mut(y, n, 1);
            llt.l_transpose_solve_with_conj(Conj::No, y, par, MemStack::new(&mut mem));
        });
        for (new, &old) in self.fwd.iter().enumerate() {
            x[old] = y[new];
        }
    }

    /// As [`Factor::backward`] where only the values at the trailing DOFs are
    /// wanted: `x_last[q]` := x at DOF `last()[q]`, x = P^T L^-T y. L^T is upper
    /// triangular, so the trailing part of x depends on the trailing part of y
    /// alone: only the supernodes that end in the trailing block are touched,
    /// O(nc^2) work, not O(nnz(L)). The arithmetic is `backward`'s, kernel for
    /// kernel on the same supernodes (a supernode that straddles the block is
    /// solved whole from its rows of y): the values are bitwise those of
    /// `backward`, so quantities formed from both (b and the recovered u of a
    /// solve) keep their rounding correlated. `y` is read only. Panics unless
    /// `y.len() == n()` and `x_last.len() == last().len()`.
    pub fn backward_to_last(&self, y: &[f64], x_last: &mut [f64]) {
        let n = self.n();
        assert_eq!(y.len(), n);
        assert_eq!(x_last.len(), self.last.len());
        let first = n - self.last.len();
        if self.is_dense() {
            let mut x = y.to_vec();
            let xm = faer::MatMut::from_column_major_slice_mut(&mut x, n, 1);
            self.threads.run(self.parallel, |par| {
                solve_upper_triangular_in_place(self.dense_l().transpose(), xm, par);
            });
            x_last.copy_from_slice(&x[first..]);
            return;
        }
        let sym = self.supernodal_symbolic();
        let llt = self.supernodal();
        let from = sym.supernode_end().partition_point(|&end| end <= first);
        if from == sym.n_supernodes() {
            return;
        }
        // x over the rows of the supernodes from `from` on (all rows their
        // patterns reach), as in l_transpose_solve_with_conj.
        let base = sym.supernode_begin()[from];
        let mut x = y[base..].to_vec();
        let below = (from..sym.n_supernodes())
            .map(|s| sym.supernode(s).pattern().len())
            .max()
            .unwrap_or(0);
        let mut tmp = vec![0.0; below];
        self.threads.run(self.parallel, |par| {
            for s in (from..sym.n_supernodes()).rev() {
                let node = llt.supernode(s);
                let (start, val) = (node.start(), node.val());
                let width = val.ncols();
                let pattern = node.pattern();
                let (top, bot) = val.split_at_row(width);
                let tmp = &mut tmp[..pattern.len()];
                for (t, &row) in tmp.iter_mut().zip(pattern) {
                    *t = x[row - base];
                }
                let tmp = faer::MatRef::from_column_major_slice(tmp, pattern.len(), 1);
                let mut x_top = faer::MatMut::from_column_major_slice_mut(
                    &mut x[start - base..start - base + width],
                    width,
                    1,
                );
                faer::linalg::matmul::matmul(
                    x_top.as_mut(),
                    faer::Accum::Add,
                    bot.transpose(),
                    tmp,
                    -1.0,
                    par,
                );
                solve_upper_triangular_in_place(top.transpose(), x_top, par);
            }
        });
        x_last.copy_from_slice(&x[first - base..]);
    }

    /// [`Factor::refactor`] into this factor's own storage: its values are
    /// gone whether or not it succeeds (refactor again before use after a
    /// failure), and one factor's values are held at a time, not two.
    pub(crate) fn refactor_in_place(&mut self, k: &Csc) -> Result<()> {
        let mut values = std::mem::take(&mut self.l_values);
        self.l_claim = None;
        self.refactor_into(k, &mut values)
    }

    /// The analysis of this factor without its values (refactor it before use):
    /// the symbolic factor is shared, so a new factorisation can be formed beside
    /// this one and replace it only once everything built on it succeeded.
    pub(crate) fn unfactored_copy(&self) -> Factor {
        Factor {
            layout: match &self.layout {
                Layout::Supernodal(s) => Layout::Supernodal(s.clone()),
                Layout::Dense => Layout::Dense,
            },
            l_values: Vec::new(),
            l_claim: None,
            ledger: self.ledger.clone(),
            col_ptr: self.col_ptr.clone(),
            row_idx: self.row_idx.clone(),
            last: self.last.clone(),
            fwd: self.fwd.clone(),
            ordering: self.ordering,
            analyse_seconds: self.analyse_seconds,
            factor_seconds: 0.0,
            threads: self.threads.clone(),
            parallel: self.parallel,
        }
    }

    /// The inverse of the fill-reducing ordering: position in the factor of each
    /// DOF (old -> new).
    pub(crate) fn new_of_old(&self) -> Vec<usize> {
        let mut inv = vec![0usize; self.n()];
        for (new, &old) in self.fwd.iter().enumerate() {
            inv[old] = new;
        }
        inv
    }

    pub(crate) fn supernodal(&self) -> SupernodalLltRef<'_, usize, f64> {
        SupernodalLltRef::<usize, f64>::new(self.supernodal_symbolic(), &self.l_values)
    }

    /// Flops of one sparse forward solve L^-1 P b_r per row b_r of `b` (c x n),
    /// each through the supernodes on the elimination-tree paths from its
    /// nonzeros to the root only (w^2 + 2 w r per supernode of width w with r rows
    /// below): what the diagonal of B K^-1 B^T costs from this factor without
    /// forming anything c x c (`examples/dual_cost.rs` measures it).
    #[cfg(any(test, feature = "internals"))]
    pub fn forward_flops_per_row(&self, b: &Csc) -> f64 {
        let sym = self.supernodal_symbolic();
        let ns = sym.n_supernodes();
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        let mut of_col = vec![0usize; self.n()];
        let mut parent = vec![usize::MAX; ns];
        let mut cost = vec![0.0; ns];
        for s in 0..ns {
            of_col[begin[s]..end[s]].fill(s);
        }
        for s in 0..ns {
            let below = sym.supernode(s).pattern();
            let w = (end[s] - begin[s]) as f64;
            cost[s] = w * w + 2.0 * w * below.len() as f64;
            if let Some(&first) = below.first() {
                parent[s] = first;
            }
        }
        // Parents as supernodes (pattern rows are columns of the factor).
        for p in parent.iter_mut().filter(|p| **p != usize::MAX) {
            *p = of_col[*p];
        }
        let mut inv = vec![0usize; self.n()];
        for (new, &old) in self.fwd.iter().enumerate() {
            inv[old] = new;
        }
        let bt = b.transpose();
        let mut mark = vec![usize::MAX; ns];
        let mut total = 0.0;
        for r in 0..bt.ncols {
            for k in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                let mut s = of_col[inv[bt.row_idx[k]]];
                while s != usize::MAX && mark[s] != r {
                    mark[s] = r;
                    total += cost[s];
                    s = parent[s];
                }
            }
        }
        total
    }

    /// The symbolic factor: always supernodal (`with_last` forces it), since the
    /// pivots and the trailing block are read from the supernodes. Panics on a
    /// dense factor ([`Factor::is_dense`]).
    pub(crate) fn supernodal_symbolic(&self) -> &SymbolicSupernodalCholesky<usize> {
        let SymbolicCholeskyRaw::Supernodal(sym) = self.symbolic().raw() else {
            unreachable!("the sparse factorisation is always supernodal");
        };
        sym
    }

    /// Solves K x = rhs for one vector, in place (allocates its workspace).
    pub fn solve_vec(&self, x: &mut [f64]) {
        let mut mem = MemBuffer::new(self.solve_scratch(1));
        let n = x.len();
        let m = faer::MatMut::from_column_major_slice_mut(x, n, 1);
        self.solve_in_place(m, MemStack::new(&mut mem));
    }
}

/// The factorisation's workspace, or `OutOfMemory`.
fn workspace(req: StackReq) -> Result<MemBuffer> {
    MemBuffer::try_new(req)
        .map_err(|_| crate::Error::new(ErrorKind::OutOfMemory, "K: factorisation workspace"))
}

/// `len` zeros in a new vector, None where the allocator refuses them. The
/// allocator's zeroed memory (fresh pages from the system for a large
/// vector, zero already) spares a pass that writes every value (the
/// supernodal factorisation zeroes L's values again itself; the dense one
/// relies on the zeros above the diagonal).
fn zeroed(len: usize) -> Option<Vec<f64>> {
    if len == 0 {
        return Some(Vec::new());
    }
    let layout = std::alloc::Layout::array::<f64>(len).ok()?;
    // SAFETY: the layout has a nonzero size (len > 0, f64 is 8 bytes).
    let ptr = unsafe { std::alloc::alloc_zeroed(layout) }.cast::<f64>();
    if ptr.is_null() {
        return None;
    }
    // SAFETY: ptr comes from the global allocator with the layout of `len`
    // f64 (what a Vec of capacity len holds), and all-zero bits are 0.0 in
    // every element: the Vec owns an initialised allocation of its own.
    Some(unsafe { Vec::from_raw_parts(ptr, len, len) })
}

/// rhs := P^T L^-T L^-1 P rhs for a dense L (`values`, n x n column-major, lower
/// triangle) and the ordering `fwd` (new -> old); `stack` holds an n x k copy.
fn dense_solve<T: faer::traits::ComplexField>(
    values: &[T],
    fwd: &[usize],
    mut rhs: MatMut<'_, T>,
    par: Par,
    stack: &mut MemStack,
) {
    let (n, k) = (rhs.nrows(), rhs.ncols());
    let l = faer::MatRef::from_column_major_slice(values, n, n);
    let (mut tmp, _) = faer::linalg::temp_mat_zeroed::<T, _, _>(n, k, stack);
    let mut tmp = faer::mat::AsMatMut::as_mat_mut(&mut tmp);
    for j in 0..k {
        for (new, &old) in fwd.iter().enumerate() {
            tmp[(new, j)] = rhs[(old, j)].clone();
        }
    }
    solve_lower_triangular_in_place(l, tmp.as_mut(), par);
    solve_upper_triangular_in_place(l.transpose(), tmp.as_mut(), par);
    for j in 0..k {
        for (new, &old) in fwd.iter().enumerate() {
            rhs[(old, j)] = tmp[(new, j)].clone();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An SPD matrix on a 9 x 7 grid: 5-point stencil with varied coefficients.
    fn spd() -> Csc {
        let (nx, ny) = (9, 7);
        let id = |i: usize, j: usize| i + nx * j;
        let mut t = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let w = 1.0 + 0.1 * ((i * 7 + j * 3) % 5) as f64;
                t.push((id(i, j), id(i, j), 4.5 * w));
                if i + 1 < nx {
                    t.push((id(i, j), id(i + 1, j), -w));
                    t.push((id(i + 1, j), id(i, j), -w));
                }
                if j + 1 < ny {
                    t.push((id(i, j), id(i, j + 1), -w));
                    t.push((id(i, j + 1), id(i, j), -w));
                }
            }
        }
        Csc::from_triplets(nx * ny, nx * ny, &t)
    }

    /// |x - reference| <= rel max|reference|, entry by entry.
    fn assert_close(x: &[f64], reference: &[f64], rel: f64) {
        let scale = reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (i, (a, b)) in x.iter().zip(reference).enumerate() {
            assert!((a - b).abs() <= rel * scale, "{i}: {a} vs {b}");
        }
    }

    /// The supernodes on a row's elimination-tree paths are those where the
    /// forward solve L^-1 P e_j has nonzeros (checked numerically).
    #[test]
    fn forward_flops_follow_the_nonzeros_of_the_forward_solve() {
        let k = spd();
        let n = k.nrows;
        let f = Factor::with_last(
            &k,
            &[],
            crate::Ordering::Amd,
            std::sync::Arc::new(crate::threads::Threads::sequential()),
        )
        .unwrap();
        let sym = f.supernodal_symbolic();
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        for j in [0, 17, 31, n - 1] {
            let row = Csc::from_triplets(1, n, &[(0, j, 1.0)]);
            let mut e = vec![0.0; n];
            e[j] = 1.0;
            let mut y = vec![0.0; n];
            f.forward(&e, &mut y);
            let mut want = 0.0;
            for s in 0..sym.n_supernodes() {
                if y[begin[s]..end[s]].iter().any(|&v| v != 0.0) {
                    let w = (end[s] - begin[s]) as f64;
                    let below = sym.supernode(s).pattern().len() as f64;
                    want += w * w + 2.0 * w * below;
                }
            }
            assert_eq!(f.forward_flops_per_row(&row), want, "DOF {j}");
        }
    }

    #[test]
    fn the_halves_of_a_solve_make_the_full_solve() {
        let k = spd();
        halves_make_the_full_solve(&k);
        // The same K with every entry stored: a dense factor.
        let n = k.nrows;
        let mut full = vec![0.0; n * n];
        for j in 0..n {
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                full[k.row_idx[p] + n * j] = k.values[p];
            }
        }
        let t: Vec<_> = (0..n * n).map(|e| (e % n, e / n, full[e])).collect();
        let dense = Csc::from_triplets(n, n, &t);
        assert!(is_dense(&dense));
        halves_make_the_full_solve(&dense);
    }

    fn halves_make_the_full_solve(k: &Csc) {
        let n = k.nrows;
        // The bottom row and a column in the middle, in no particular order.
        let last = [5, 0, 8, 1, 2, 3, 4, 6, 7, 40, 31, 49];
        let f = Factor::with_last(
            k,
            &last,
            crate::Ordering::Auto,
            std::sync::Arc::new(crate::threads::Threads::sequential()),
        )
        .unwrap();
        let x_last: Vec<f64> = (0..last.len())
            .map(|q| (q as f64 * 0.7).sin() + 0.2)
            .collect();
        let mut x = vec![0.0; n];
        for (q, &j) in last.iter().enumerate() {
            x[j] = x_last[q];
        }
        // forward_from_last = forward of the scattered vector.
        let (mut y1, mut y2) = (vec![f64::NAN; n], vec![f64::NAN; n]);
        f.forward(&x, &mut y1);
        f.forward_from_last(&x_last, &mut y2);
        assert_close(&y2, &y1, 1e-15);
        // backward(forward(x)) = solve_vec(x), and K of it is x (independent check).
        let mut full = x.clone();
        f.solve_vec(&mut full);
        let mut z = vec![f64::NAN; n];
        let mut z_last = vec![f64::NAN; last.len()];
        f.backward_to_last(&y2, &mut z_last);
        f.backward(&mut y2, &mut z);
        assert_close(&z, &full, 1e-14);
        // backward_to_last = backward at the trailing DOFs, to the bit.
        let at_last: Vec<f64> = last.iter().map(|&j| z[j]).collect();
        assert_eq!(z_last, at_last);
        let mut kz = vec![0.0; n];
        k.mul_vec(&z, &mut kz);
        assert!((0..n).all(|i| (kz[i] - x[i]).abs() <= 1e-13));
    }
}

#[cfg(test)]
mod tree_tests {
    use super::*;

    /// A 3D block of nx x ny x nz nodes with 3 DOFs each, a 27-point
    /// coupling of varied weights between the DOFs of neighbouring nodes
    /// (each DOF with the same component of its 26 neighbours), diagonally
    /// dominant: SPD, with the fronts of a 3D mesh (symmetric weights: the
    /// factor reads one triangle). `shift` is taken off the diagonal (0:
    /// SPD; large: indefinite).
    fn block(nx: usize, ny: usize, nz: usize, shift: f64) -> Csc {
        let id = |i: usize, j: usize, l: usize| i + nx * (j + ny * l);
        let mut t = Vec::new();
        for l in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let a = id(i, j, l);
                    let mut diag = 0.0;
                    for off in 0..27usize {
                        let o = [off % 3, (off / 3) % 3, off / 9].map(|v| v as i64 - 1);
                        let (i2, j2, l2) = (i as i64 + o[0], j as i64 + o[1], l as i64 + o[2]);
                        if off == 13 || i2 < 0 || j2 < 0 || l2 < 0 {
                            continue;
                        }
                        let (i2, j2, l2) = (i2 as usize, j2 as usize, l2 as usize);
                        if i2 >= nx || j2 >= ny || l2 >= nz {
                            continue;
                        }
                        let b = id(i2, j2, l2);
                        let w = 1.0 + 0.25 * (((a + b) * 7 + (a * b) % 3) % 5) as f64;
                        diag += w;
                        for r in 0..3 {
                            t.push((3 * a + r, 3 * b + r, -w));
                        }
                    }
                    for r in 0..3 {
                        t.push((3 * a + r, 3 * a + r, 1.05 * diag + 0.1 - shift));
                    }
                }
            }
        }
        let n = 3 * nx * ny * nz;
        Csc::from_triplets(n, n, &t)
    }

    /// The analysis of `k` in `ordering` for `threads` threads, and its
    /// supernodal symbolic factor.
    fn analysed(
        k: &Csc,
        ordering: Ordering,
        threads: usize,
    ) -> (Factor, Arc<SymbolicCholesky<usize>>) {
        let f = Factor::analyse(
            k,
            &[],
            ordering,
            true,
            Arc::new(Threads::new(threads)),
            Ledger::new(),
        )
        .unwrap();
        let Layout::Supernodal(symbolic) = &f.layout else {
            panic!("a sparse K");
        };
        let symbolic = symbolic.clone();
        (f, symbolic)
    }

    /// The factor of `k` as faer computes it on one thread, and as the tree
    /// split computes it on `threads` threads (the factor's values, or the
    /// failure's message).
    fn both(
        k: &Csc,
        ordering: Ordering,
        threads: usize,
    ) -> (
        std::result::Result<Vec<f64>, String>,
        std::result::Result<Vec<f64>, String>,
    ) {
        let run = |t: usize| {
            let (mut f, symbolic) = analysed(k, ordering, t);
            let planned = f.tree_plan(&symbolic).is_some();
            assert_eq!(planned, t >= 2, "the tree split taken on {t} threads");
            let mut values = f.values_vec().unwrap();
            let result = f.factor_supernodal(&symbolic, k, &mut values).unwrap();
            f.l_values = Vec::new();
            result.map(|()| values)
        };
        (run(1), run(threads))
    }

    /// Split by the tree on 2, 3 and 4 threads, the factor of an SPD 3D block
    /// is faer's sequential one to rounding (every supernode's updates are
    /// summed in the same order, by other kernels), under METIS (large
    /// fronts) and AMD (small ones), and the tree split is what a factor
    /// with several threads takes.
    #[test]
    fn the_factor_split_by_the_tree_is_faers() {
        let k = block(16, 16, 8, 0.0);
        for ordering in [Ordering::Metis, Ordering::Amd] {
            for threads in [2, 3, 4] {
                let (faer, tree) = both(&k, ordering, threads);
                let (faer, tree) = (faer.unwrap(), tree.unwrap());
                assert!(faer.len() >= PARALLEL_MIN_ENTRIES, "{}", faer.len());
                let scale = faer.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let diff = faer
                    .iter()
                    .zip(&tree)
                    .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                println!(
                    "{ordering:?}, {threads} threads: max |difference| {diff:.1e} of {scale:.1e}"
                );
                assert!(diff <= 1e-13 * scale, "{ordering:?}, {threads}: {diff:.2e}");
            }
        }
    }

    /// An indefinite K fails on the tree split at the column where faer's
    /// sequential factorisation fails, whatever the number of threads: a
    /// diagonal entry made negative at one column of the factor's order (a
    /// subtree's, or the top's: the last column), at two (the first met is
    /// reported, though a later one may lie in a subtree another thread
    /// finishes first), and the whole diagonal shifted down.
    #[test]
    fn the_tree_split_meets_the_first_non_positive_pivot_faer_meets() {
        let spd = block(16, 16, 8, 0.0);
        let n = spd.nrows;
        let fwd = analysed(&spd, Ordering::Metis, 2).0.fwd;
        let negative = |cols: &[usize]| negative_at(&spd, &fwd, cols);
        let cases = [
            (negative(&[n / 3]), Some(n / 3)),
            (negative(&[n - 1]), Some(n - 1)),
            (negative(&[n / 5, 3 * n / 5]), Some(n / 5)),
            (negative(&[3 * n / 5, n - 2]), Some(3 * n / 5)),
            (block(16, 16, 8, 40.0), None),
        ];
        for (k, col) in cases {
            for threads in [2, 4] {
                let (faer, tree) = both(&k, Ordering::Metis, threads);
                let (faer, tree) = (faer.unwrap_err(), tree.unwrap_err());
                if let Some(col) = col {
                    assert_eq!(faer, format!("NonPositivePivot {{ index: {col} }}"));
                }
                assert_eq!(faer, tree, "{threads} threads");
            }
        }
    }

    /// `k` with the diagonal entries of the factor's columns `cols` (`fwd`:
    /// the factor's order, new -> old) set to -1.
    fn negative_at(k: &Csc, fwd: &[usize], cols: &[usize]) -> Csc {
        let mut k = k.clone();
        for &col in cols {
            let old = fwd[col];
            let at = k.col_ptr[old]
                + k.row_idx[k.col_ptr[old]..k.col_ptr[old + 1]]
                    .binary_search(&old)
                    .unwrap();
            k.values[at] = -1.0;
        }
        k
    }

    /// A top supernode numbered before a subtree of a bin fails first where
    /// both fail: the top's supernodes before the bins' first failure are
    /// still factored (their descendants all come before them), on every
    /// split of the block that has such a pair (2, 3 and 4 threads).
    #[test]
    fn a_top_supernode_before_a_failing_subtree_is_met_first() {
        let spd = block(16, 16, 8, 0.0);
        let mut checked = 0;
        for threads in [2, 3, 4] {
            let (f, symbolic) = analysed(&spd, Ordering::Metis, threads);
            let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
                panic!("supernodal");
            };
            let plan = TreePlan::of(sym, threads).expect("the block splits");
            let (bins, top) = plan.split();
            let pair = top
                .iter()
                .find_map(|&a| bins.iter().flatten().find(|&&b| b > a).map(|&b| (a, b)));
            let Some((a, b)) = pair else {
                continue;
            };
            let begin = sym.supernode_begin();
            let k = negative_at(&spd, &f.fwd, &[begin[a], begin[b]]);
            let (faer, tree) = both(&k, Ordering::Metis, threads);
            let (faer, tree) = (faer.unwrap_err(), tree.unwrap_err());
            println!("{threads} threads: top supernode {a} before bin supernode {b}: {tree}");
            assert_eq!(faer, format!("NonPositivePivot {{ index: {} }}", begin[a]));
            assert_eq!(tree, faer, "{threads} threads");
            checked += 1;
        }
        assert!(checked > 0, "no split put a top supernode before a bin's");
    }

    /// A refactor on several threads is the refactor on one: the same
    /// solves to rounding, and the same result on one thread after.
    #[test]
    fn a_factor_on_threads_solves_as_on_one() {
        let k = block(16, 16, 8, 0.0);
        let n = k.nrows;
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let solve = |threads: usize| {
            let f = Factor::with_last(&k, &[], Ordering::Metis, Arc::new(Threads::new(threads)))
                .unwrap();
            let mut x = b.clone();
            let mut mem = MemBuffer::new(f.solve_scratch(1));
            f.solve_in_place(
                MatMut::from_column_major_slice_mut(&mut x, n, 1),
                MemStack::new(&mut mem),
            );
            x
        };
        let (one, two) = (solve(1), solve(2));
        let mut r = vec![0.0; n];
        k.mul_vec(&two, &mut r);
        let res = r
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (a, c)| m.max((a - c).abs()));
        assert!(
            res <= 1e-10 * b.iter().fold(0.0f64, |m, v| m.max(v.abs())),
            "{res:.2e}"
        );
        let scale = one.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = one
            .iter()
            .zip(&two)
            .fold(0.0f64, |m, (a, c)| m.max((a - c).abs()));
        assert!(diff <= 1e-12 * scale, "{diff:.2e} of {scale:.2e}");
    }

    /// A refactor into a spare holding other values (NaN here) gives the
    /// factor a new vector gives, bit for bit, and takes the spare: faer's
    /// supernodal factorisation on one thread, the tree's on two, and a
    /// dense K's; a spare of another length is left as it was.
    #[test]
    fn a_refactor_into_a_spare_is_a_refactor_into_new_memory() {
        let n = 12;
        let mut dense = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let v = if i == j {
                    2.0 * n as f64
                } else {
                    1.0 / (1 + i + j) as f64
                };
                dense.push((i, j, v));
            }
        }
        let dense = Csc::from_triplets(n, n, &dense);
        let sparse = block(16, 16, 8, 0.0);
        for (k, threads) in [(&sparse, 1), (&sparse, 2), (&dense, 1)] {
            let factor =
                Factor::with_last(k, &[], Ordering::Metis, Arc::new(Threads::new(threads)));
            let mut f = Arc::try_unwrap(factor.unwrap()).ok().unwrap();
            assert_eq!(f.is_dense(), std::ptr::eq(k, &dense));
            if let Layout::Supernodal(symbolic) = &f.layout {
                let planned = f.tree_plan(symbolic).is_some();
                assert_eq!(planned, threads >= 2, "the tree split on {threads} threads");
            }
            let new_memory = f.values().to_vec();
            let mut other = vec![f64::NAN; 3];
            f.refactor_into(k, &mut other).unwrap();
            assert_eq!(other.len(), 3, "a spare of another length is left");
            let mut spare = vec![f64::NAN; f.values_len()];
            f.refactor_into(k, &mut spare).unwrap();
            assert!(spare.is_empty(), "the spare was taken");
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(f.values()), bits(&new_memory), "{threads} thread(s)");
        }
    }
}
