//! The matrix-free form of the dual: A applied by solves with K's factor
//! (whole, narrowed to a Newton step's rows, in double or single precision)
//! or by the host's solves (`host.rs`), its contact blocks and diagonal, and
//! the preconditioners Newton's reduced systems take (lumped, layered
//! Dirichlet).

use super::*;

/// The matrix-free form of A = B K^-1 B^T: each product is one solve with K's
/// factor (whatever its ordering) or the host's; nothing c x c is formed. The
/// contacts' d x d diagonal blocks of A are computed once (`contact_blocks`,
/// or by the host's solves), for rho, the diagonal and Newton's
/// preconditioner.
pub(super) struct Operator {
    /// B^T, n x c: column r holds row r of B.
    pub(super) bt: Csc,
    /// A_jj, j < c.
    pub(super) diag: Vec<f64>,
    /// Per contact, its d x d diagonal block of A, row-major (see
    /// [`crate::factor_tree::contact_blocks::contact_blocks`]).
    pub(super) blocks: Vec<f64>,
    /// G = B K B^T (c x c, sparse), the lumped approximation of A^-1 that
    /// preconditions Newton's reduced systems, once K is handed over
    /// ([`Dual::set_lumped`]), with its bytes on the ledger.
    pub(super) lumped: Option<(Csc, Claim)>,
    /// The layered Dirichlet preconditioner, where it pays (`dirichlet.rs`).
    pub(super) dirichlet: Option<crate::dirichlet::Dirichlet>,
    /// What solves with K.
    pub(super) solves: Solves,
}

/// What a refactor (or `set_contacts`) made or lent before the matrix-free
/// dual is formed, for it to take instead of making it again.
#[derive(Default)]
pub(crate) struct Made {
    /// The contacts' d x d diagonal blocks (an earlier K's, kept).
    pub(crate) blocks: Option<Vec<f64>>,
    /// The factor's values in single precision ([`Factor::single_values`]);
    /// taken where its length is theirs. Only the length is checked: the
    /// caller vouches for the values (`Dual::lend_single_of`).
    pub(crate) single: Option<Vec<f32>>,
}

/// What a matrix-free dual's products solve with: K's factor, or the host.
pub(super) enum Solves {
    Factor(Box<FactorSolves>),
    Host(Box<HostSolves>),
}

/// The host's solves (`host.rs`) with one product's n-vector, in double and
/// (made at the first rough product, where the host offers single-precision
/// solves) in single precision.
pub(super) struct HostSolves {
    pub(super) host: Arc<crate::host::Host>,
    pub(super) work: std::cell::RefCell<Vec<f64>>,
    pub(super) work_single: std::cell::RefCell<Vec<f32>>,
    /// The products on the host's solve on rows (`KSolve::solve_rows`), where
    /// it offers one: the contact DOFs and B's entries' places among them.
    pub(super) contact_rows: OnRows,
    /// A Newton step's products narrowed to its rows' DOFs (see
    /// [`Dual::narrow_to`]); `held` empty: not narrowed.
    pub(super) narrow: std::cell::RefCell<OnRows>,
    /// A product's right-hand side on the rows.
    pub(super) work_rows: std::cell::RefCell<Vec<f64>>,
}

/// A set of DOFs the host's solve on rows takes, and for the dual rows
/// `held`, the place among `dofs` of each of B's entries in them (entry q
/// of `bt`: `at[q]`; other entries' places are stale).
#[derive(Default)]
pub(super) struct OnRows {
    pub(super) held: Vec<usize>,
    pub(super) dofs: Vec<usize>,
    pub(super) at: Vec<usize>,
}

impl OnRows {
    /// The DOFs of B's rows `rows` (ascending) and their entries' places.
    pub(super) fn set(&mut self, bt: &Csc, rows: &[usize]) {
        self.held.clear();
        self.held.extend_from_slice(rows);
        self.dofs.clear();
        for &r in rows {
            self.dofs
                .extend_from_slice(&bt.row_idx[bt.col_ptr[r]..bt.col_ptr[r + 1]]);
        }
        self.dofs.sort_unstable();
        self.dofs.dedup();
        self.at.resize(bt.row_idx.len(), 0);
        for &r in rows {
            for q in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                self.at[q] = self.dofs.partition_point(|&j| j < bt.row_idx[q]);
            }
        }
    }
}

/// Bytes the products of a dual of B (`b`, c x n) on a host's solve on rows
/// hold at most: the rows, DOFs and places of the contact DOFs and of a
/// narrowing ([`OnRows`]), and a right-hand side on the DOFs.
pub(crate) fn host_rows_bytes(b: &Csc) -> usize {
    let (c, entries) = (b.nrows, b.nnz());
    let dofs = b.ncols.min(entries);
    2 * (c + dofs + entries) * std::mem::size_of::<usize>() + dofs * std::mem::size_of::<f64>()
}

/// The products' solves with K's factor and their workspace.
pub(super) struct FactorSolves {
    pub(super) factor: Arc<Factor>,
    /// Workspace of one product: the n-vector and the solve's scratch.
    pub(super) work: std::cell::RefCell<(Vec<f64>, MemBuffer)>,
    /// L's values in single precision, for the rough products of
    /// [`Dual::apply_rough`], with their workspace; and their bytes on the
    /// ledger. Empty where a refactor or `set_contacts` lent them to the dual
    /// it formed and then failed ([`Dual::lend_single`]): made again from the
    /// factor at the next rough product ([`FactorSolves::single_copy`]).
    /// The claim stays while they are lent (the ledger then counts the copy
    /// twice while the new dual is formed, as `Sizes::refactor` predicts).
    pub(super) single: std::cell::RefCell<Vec<f32>>,
    pub(super) work_single: std::cell::RefCell<(Vec<f32>, MemBuffer)>,
    pub(super) _single_claim: Claim,
    /// The products' own solves (see [`OwnSolves`]); None on a dense
    /// factor: its plain solve.
    pub(super) own: Option<OwnSolves>,
    /// The narrowed products of Newton's reduced solves (see
    /// [`Dual::narrow_to`]).
    pub(super) narrow: std::cell::RefCell<Narrow>,
}

impl FactorSolves {
    /// L's values in single precision, made again from the factor where they
    /// were lent away (see the field); None where the allocator refuses
    /// them: the products then solve in double precision (and the next one
    /// tries again).
    fn single_copy(&self) -> Option<std::cell::Ref<'_, Vec<f32>>> {
        let held = self.single.borrow().len() == self.factor.values().len();
        if !held {
            let made = self.factor.single_values().ok()?;
            *self.single.borrow_mut() = made;
        }
        Some(self.single.borrow())
    }

    /// Takes L's values in single precision out (see the field).
    pub(super) fn lend_single(&mut self) -> Vec<f32> {
        std::mem::take(self.single.get_mut())
    }
}

/// Products narrowed to a set of dual rows: x vanishes outside them and y is
/// wanted only there (a Newton step's reduced unknowns and explicit part), so
/// the solves take the supernodes on the paths of their DOFs alone
/// (`tree_solve.rs`). The split is replaced at each narrowing; its scratch in
/// double and single precision is made at the first one, refitted after,
/// and claimed on the ledger (`TreeSolve::bytes_bound` in the prediction).
#[derive(Default)]
pub(super) struct Narrow {
    /// The rows, ascending, and the split for their DOFs; None: the products
    /// are not narrowed.
    pub(super) rows: Vec<usize>,
    pub(super) split: Option<crate::factor_tree::tree_solve::TreeSolve>,
    /// The factor's elimination tree, made at the first narrowing.
    pub(super) tree: Option<crate::factor_tree::supernode_tree::Tree>,
    /// The DOFs of the rows (scratch of [`Dual::narrow_to`]).
    pub(super) dofs: Vec<usize>,
    pub(super) work: Option<NarrowWork>,
    /// The bytes of all this at their bound ([`narrow_bytes`]), claimed at
    /// the first narrowing.
    pub(super) claim: Option<Claim>,
}

pub(super) struct NarrowWork {
    pub(super) double: crate::factor_tree::tree_solve::TreeScratch<f64>,
    pub(super) single: crate::factor_tree::tree_solve::TreeScratch<f32>,
}

/// Bytes the narrowed products of a dual with c rows on `factor` (sparse)
/// claim at most: the split and its scratch (`TreeSolve::bytes_bound`), the
/// elimination tree, and the lists of DOFs and rows.
pub(super) fn narrow_bytes(factor: &Factor, c: usize) -> usize {
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
pub(super) struct OwnSolves {
    pub(super) split: crate::factor_tree::tree_solve::TreeSolve,
    pub(super) work: std::cell::RefCell<crate::factor_tree::tree_solve::TreeScratch<f64>>,
    pub(super) work_single: std::cell::RefCell<crate::factor_tree::tree_solve::TreeScratch<f32>>,
    pub(super) _claim: Claim,
}

impl OwnSolves {
    /// The solves of B's DOFs on `factor`; None on a dense factor.
    pub(super) fn of(factor: &Factor, b: &Csc) -> Option<OwnSolves> {
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
    /// `made`: the contacts' diagonal blocks where the caller has them (an
    /// earlier K's, see [`Dual::build_keeping`]) and the factor's
    /// single-precision values where it made or lent them (`Dual::lend_single`),
    /// taken where their length is the factor's; else computed here.
    pub(super) fn new(
        factor: &Arc<Factor>,
        b: &Csc,
        m: usize,
        d: usize,
        made: Made,
    ) -> Result<Operator> {
        let single = match made.single {
            Some(single) if single.len() == factor.values().len() => single,
            _ => factor.single_values()?,
        };
        let single_claim = factor.ledger().claim(single.len() * 4);
        let blocks = match made.blocks {
            Some(blocks) if blocks.len() == m * d * d => blocks,
            _ => {
                crate::factor_tree::contact_blocks::contact_blocks_single(factor, b, m, d, &single)
            }
        };
        let own = OwnSolves::of(factor, b);
        let what = "the matrix-free dual's work space";
        Ok(Operator {
            bt: b.transpose(),
            diag: diag_of(&blocks, m, d),
            blocks,
            lumped: None,
            dirichlet: None,
            solves: Solves::Factor(Box::new(FactorSolves {
                factor: factor.clone(),
                work: std::cell::RefCell::new((
                    try_zeros(factor.n(), what)?,
                    try_scratch(factor.solve_scratch(1), what)?,
                )),
                _single_claim: single_claim,
                own,
                narrow: std::cell::RefCell::new(Narrow::default()),
                single: std::cell::RefCell::new(single),
                work_single: std::cell::RefCell::new((
                    try_zeros(factor.n(), what)?,
                    try_scratch(factor.solve_scratch_single(), what)?,
                )),
            })),
        })
    }

    /// The operator on the host's solves: the contacts' diagonal blocks as
    /// given (`blocks`: by the library's own factor of K), else by the
    /// host ([`host_blocks`]).
    ///
    /// Errors: `HostSolve` when a solve fails, `OutOfMemory`.
    pub(super) fn on_host(
        host: &Arc<crate::host::Host>,
        b: &Csc,
        m: usize,
        d: usize,
        blocks: Option<Vec<f64>>,
    ) -> Result<Operator> {
        let bt = b.transpose();
        let blocks = match blocks {
            Some(blocks) => blocks,
            None => host_blocks(host, &bt, m, d)?,
        };
        let mut contact_rows = OnRows::default();
        if host.offers_rows() {
            contact_rows.set(&bt, &(0..bt.ncols).collect::<Vec<_>>());
        }
        Ok(Operator {
            diag: diag_of(&blocks, m, d),
            blocks,
            bt,
            lumped: None,
            dirichlet: None,
            solves: Solves::Host(Box::new(HostSolves {
                host: host.clone(),
                work: std::cell::RefCell::new(try_zeros(
                    host.n(),
                    "the matrix-free dual's work space",
                )?),
                work_single: std::cell::RefCell::new(Vec::new()),
                contact_rows,
                narrow: std::cell::RefCell::new(OnRows::default()),
                work_rows: std::cell::RefCell::new(Vec::new()),
            })),
        })
    }

    /// K's factor, where the products solve with it (None on the host's).
    pub(super) fn factor(&self) -> Option<&Arc<Factor>> {
        match &self.solves {
            Solves::Factor(s) => Some(&s.factor),
            Solves::Host(_) => None,
        }
    }

    /// f := K^-1 f and `ys[i] := A xs[i]` (each as long as its x, as
    /// [`Operator::apply`]), in double precision and in one solve of the
    /// block [f, B^T xs] with K's factor: the solve's time is mostly reading
    /// the factor, which a block reads once (on a 3D slab's factor of 3.8e7
    /// entries three columns took 0.068 s, one 0.051 s, timed in a build
    /// not kept; on the 3D host example's factor of 3d-52x52x4 two columns
    /// 1.15 times one, four 1.33 times). Where `primal` is given, the block
    /// also holds f - B^T `xs[0]`, whose solution is u at `xs[0]`
    /// ([`Primal::start_at`]), and z = K^-1 B^T `xs[1]` is left in it where
    /// there is an `xs[1]` (its line's direction). False, with nothing
    /// written, on the host's solves. Its bytes (the block and faer's
    /// scratch for it) are claimed on the ledger while it lives.
    ///
    /// Errors: `OutOfMemory` (the block or its scratch refused).
    pub(super) fn solve_with_products(
        &self,
        f: &mut [f64],
        xs: &[&[f64]],
        ys: &mut [Vec<f64>],
        primal: Option<&mut Primal>,
    ) -> Result<bool> {
        let Solves::Factor(fs) = &self.solves else {
            return Ok(false);
        };
        let factor = &fs.factor;
        let with_u = primal.is_some() && !xs.is_empty();
        let (n, k) = (factor.n(), 1 + xs.len() + usize::from(with_u));
        let what = "a solve's block of right-hand sides";
        let scratch = factor.solve_scratch(k);
        let _claim = factor.ledger().claim(8 * n * k + scratch.size_bytes());
        let mut z = try_zeros::<f64>(n * k, what)?;
        let mut mem = try_scratch(scratch, what)?;
        z[..n].copy_from_slice(f);
        let (head, tail) = z.split_at_mut((1 + xs.len()) * n);
        for (x, col) in xs.iter().zip(head[n..].chunks_exact_mut(n)) {
            scatter(&self.bt, x, 0..x.len(), col);
        }
        if with_u {
            // f - B^T x: the difference taken before the solve, as
            // `ContactProblem::recover_u` takes it.
            scatter(&self.bt, xs[0], 0..xs[0].len(), tail);
            tail.iter_mut().zip(&*f).for_each(|(t, fi)| *t = fi - *t);
        }
        let block = MatMut::from_column_major_slice_mut(&mut z, n, k);
        factor.solve_in_place(block, MemStack::new(&mut mem));
        f.copy_from_slice(&z[..n]);
        for (y, col) in ys.iter_mut().zip(z[n..].chunks_exact(n)) {
            gather(&self.bt, col, 0..y.len(), y);
        }
        if let Some(p) = primal.filter(|_| with_u) {
            p.start_mut().copy_from_slice(&z[(1 + xs.len()) * n..]);
            p.start_at(xs[0]);
            if xs.len() > 1 {
                p.z.copy_from_slice(&z[2 * n..3 * n]);
            }
        }
        Ok(true)
    }

    /// y ~= A x with the solve in single precision (the products with B in
    /// double): relative error about 1e-7 times the conditioning of K's factor.
    pub(super) fn apply_single(&self, x: &[f64], y: &mut [f64]) {
        self.apply_in(x, y, true);
    }

    /// y := A x (leading blocks for shorter x and y, as [`Dual::apply`]).
    pub(super) fn apply(&self, x: &[f64], y: &mut [f64]) {
        self.apply_in(x, y, false);
    }

    /// y := A x in double, as [`Operator::apply`], and z := K^-1 B^T x (n
    /// values), the solve's whole solution. False, with y and z untouched,
    /// where the products do not compute it whole: on the host's solves, and
    /// where they are restricted to the contact DOFs' paths (`tree_solve.rs`:
    /// the back substitution then gives only their values).
    pub(super) fn apply_keeping(&self, x: &[f64], y: &mut [f64], z: &mut [f64]) -> bool {
        let Solves::Factor(fs) = &self.solves else {
            return false;
        };
        if !self.keeps_solutions() {
            return false;
        }
        if x.iter().all(|&v| v == 0.0) {
            y.fill(0.0);
            z.fill(0.0);
            return true;
        }
        self.apply_in(x, y, false);
        z.copy_from_slice(&fs.work.borrow().0);
        true
    }

    /// Whether [`Operator::apply_keeping`] computes z.
    pub(super) fn keeps_solutions(&self) -> bool {
        match &self.solves {
            Solves::Factor(fs) => !fs.own.as_ref().is_some_and(|own| own.split.restricted()),
            Solves::Host(_) => false,
        }
    }

    /// y := A x with the solve in single precision where `rough`, else in
    /// double: B^T x scattered into the n-vector, the solve (the own one,
    /// else the factor's plain one), B z gathered. No solve for a zero x
    /// (Newton's explicit part near convergence, often Tresca's).
    pub(super) fn apply_in(&self, x: &[f64], y: &mut [f64], rough: bool) {
        if x.iter().all(|&v| v == 0.0) {
            y.iter_mut().for_each(|v| *v = 0.0);
            return;
        }
        let bt = &self.bt;
        let fs = match &self.solves {
            Solves::Factor(fs) => fs,
            Solves::Host(hs) => return hs.apply(bt, x, y, rough),
        };
        let factor = &fs.factor;
        macro_rules! whole {
            ($work:expr, $t:ty, $values:expr, $own_work:ident, $solve:ident) => {{
                let mut work = $work.borrow_mut();
                let (z, mem) = &mut *work;
                z.iter_mut().for_each(|v| *v = <$t>::default());
                scatter(bt, x, 0..x.len(), z);
                match &fs.own {
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
                gather(bt, z, 0..y.len(), y);
            }};
        }
        match rough.then(|| fs.single_copy()).flatten() {
            Some(single) => whole!(fs.work_single, f32, &single, work_single, solve_single),
            None => whole!(fs.work, f64, factor.values(), work, solve),
        }
    }
}

impl Operator {
    /// See [`Dual::narrow_to`].
    pub(super) fn narrow_to(&self, rows: &[usize]) -> bool {
        let fs = match &self.solves {
            Solves::Factor(fs) => fs,
            Solves::Host(hs) if hs.host.offers_rows() => {
                hs.narrow.borrow_mut().set(&self.bt, rows);
                return true;
            }
            Solves::Host(_) => return false,
        };
        let mut narrow = fs.narrow.borrow_mut();
        if fs.factor.is_dense() {
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
                fs.factor
                    .ledger()
                    .claim(narrow_bytes(&fs.factor, self.bt.ncols)),
            );
        }
        let tree =
            tree.get_or_insert_with(|| crate::factor_tree::supernode_tree::Tree::of(&fs.factor));
        *split = Some(crate::factor_tree::tree_solve::TreeSolve::on(
            &fs.factor, tree, dofs,
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
                let n = fs.factor.n();
                *work = Some(NarrowWork {
                    double: split.scratch(n),
                    single: split.scratch(n),
                });
            }
        }
        true
    }

    /// See [`Dual::apply_narrow`].
    pub(super) fn apply_narrow(&self, x: &[f64], y: &mut [f64], rough: bool) {
        let fs = match &self.solves {
            Solves::Factor(fs) => fs,
            Solves::Host(hs) => return hs.apply_narrow(&self.bt, x, y, rough),
        };
        let mut narrow = fs.narrow.borrow_mut();
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
        let (bt, factor) = (&self.bt, &fs.factor);
        let threads = factor.threads();
        // The solve reads and writes z on the paths' columns, which hold the
        // rows' DOFs: z is cleared there (`TreeSolve::clear`), B^T x
        // scattered into it, and A x gathered at the rows.
        macro_rules! narrowed {
            ($z:expr, $solve:ident, $values:expr, $scratch:expr) => {{
                let z = $z;
                split.clear(factor, z);
                scatter(bt, x, rows.iter().copied(), z);
                split.$solve(factor, $values, z, $scratch, threads);
                gather(bt, z, rows.iter().copied(), y);
            }};
        }
        if let Some(single) = rough.then(|| fs.single_copy()).flatten() {
            let mut w = fs.work_single.borrow_mut();
            narrowed!(&mut w.0, solve_single, &single, &mut work.single);
        } else {
            let mut w = fs.work.borrow_mut();
            narrowed!(&mut w.0, solve, factor.values(), &mut work.double);
        }
    }
}

/// A precision the products' solves run in: f64, or f32 for the rough ones.
pub(super) trait Real: Copy + Default + std::ops::AddAssign + Into<f64> {
    /// v rounded to this precision.
    fn of(v: f64) -> Self;
}

impl Real for f64 {
    fn of(v: f64) -> f64 {
        v
    }
}

impl Real for f32 {
    fn of(v: f64) -> f32 {
        v as f32
    }
}

/// z += B^T x over the rows in `rows` (x read there only): row r of B
/// (column r of `bt`) scattered into z's DOFs, times x_r.
fn scatter<T: Real>(bt: &Csc, x: &[f64], rows: impl Iterator<Item = usize>, z: &mut [T]) {
    scatter_at(bt, &bt.row_idx, x, rows, z);
}

/// As [`scatter`] with B's entries placed in z at `at` (entry q of `bt` at
/// `z[at[q]]`): the DOFs, or their places in a host's rows.
fn scatter_at<T: Real>(
    bt: &Csc,
    at: &[usize],
    x: &[f64],
    rows: impl Iterator<Item = usize>,
    z: &mut [T],
) {
    for r in rows {
        let xr = x[r];
        if xr != 0.0 {
            for k in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                z[at[k]] += T::of(bt.values[k] * xr);
            }
        }
    }
}

/// y_r := (B z)_r for the rows in `rows` (y untouched elsewhere).
fn gather<T: Real>(bt: &Csc, z: &[T], rows: impl Iterator<Item = usize>, y: &mut [f64]) {
    gather_at(bt, &bt.row_idx, z, rows, y);
}

/// As [`gather`] with B's entries placed in z at `at` (see [`scatter_at`]).
fn gather_at<T: Real>(
    bt: &Csc,
    at: &[usize],
    z: &[T],
    rows: impl Iterator<Item = usize>,
    y: &mut [f64],
) {
    for r in rows {
        y[r] = (bt.col_ptr[r]..bt.col_ptr[r + 1])
            .map(|k| bt.values[k] * z[at[k]].into())
            .sum();
    }
}

impl HostSolves {
    /// y := A x by one host solve, in single precision where `rough` and the
    /// host offers it (`KSolve::solve_single`); y is NaN where the solve
    /// failed (the failure is latched on the host and ends the solve:
    /// `host.rs`).
    fn apply(&self, bt: &Csc, x: &[f64], y: &mut [f64], rough: bool) {
        let (rows_x, rows_y) = (0..x.len(), 0..y.len());
        // On rows where the host offers it (approximate where rough).
        if self.host.offers_rows()
            && self.on_rows(
                &self.contact_rows,
                bt,
                x,
                rows_x.clone(),
                y,
                rows_y.clone(),
                rough,
            )
        {
            return;
        }
        // Not offered: known after the first try, then no single-precision
        // scatter on the way to the double solve.
        if rough && self.host.offers_single() {
            let mut z = self.work_single.borrow_mut();
            z.resize(self.host.n(), 0.0);
            let (from, to) = ((x, rows_x.clone()), (&mut *y, rows_y.clone()));
            if through(bt, &bt.row_idx, from, to, &mut z, |z| {
                self.host.solve_single(z, 1)
            }) {
                return;
            }
        }
        let mut z = self.work.borrow_mut();
        through(bt, &bt.row_idx, (x, rows_x), (y, rows_y), &mut z, |z| {
            Some(self.host.solve(z, 1))
        });
    }
}

impl HostSolves {
    /// As [`Operator::apply_narrow`] on the host: on the narrowed rows' DOFs
    /// where a narrowing is in force (y zero outside the rows), else whole.
    fn apply_narrow(&self, bt: &Csc, x: &[f64], y: &mut [f64], rough: bool) {
        let narrow = self.narrow.borrow();
        if !narrow.held.is_empty() && self.host.offers_rows() {
            y.iter_mut().for_each(|v| *v = 0.0);
            let rows = narrow.held.iter().copied();
            if self.on_rows(&narrow, bt, x, rows.clone(), y, rows, rough) {
                return;
            }
        }
        drop(narrow);
        self.apply(bt, x, y, rough);
    }

    /// y := B K^-1 B^T x at the rows `to`, x read at the rows `from`, by the
    /// host's solve on the DOFs of `set` (whose places cover both); y is NaN
    /// there where the solve failed. False (y untouched) where the host
    /// offers no solve on rows.
    #[allow(clippy::too_many_arguments)]
    fn on_rows(
        &self,
        set: &OnRows,
        bt: &Csc,
        x: &[f64],
        from: impl Iterator<Item = usize>,
        y: &mut [f64],
        to: impl Iterator<Item = usize>,
        rough: bool,
    ) -> bool {
        let mut z = self.work_rows.borrow_mut();
        z.resize(set.dofs.len(), 0.0);
        through(bt, &set.at, (x, from), (y, to), &mut z, |z| {
            self.host.solve_rows(&set.dofs, z, 1, rough)
        })
    }
}

/// y := B solve(B^T x) at the rows `to`, x read at the rows `from`, with
/// the vector `z` in either precision, B's entries placed in it at `at`
/// (see [`scatter_at`]: the DOFs of an n-vector, or their places among a
/// host's rows); y is NaN at `to` where the solve failed. False (y
/// untouched) where `solve` is not offered (None).
fn through<T: Real, F: Iterator<Item = usize>, G: Iterator<Item = usize>>(
    bt: &Csc,
    at: &[usize],
    (x, from): (&[f64], F),
    (y, to): (&mut [f64], G),
    z: &mut [T],
    solve: impl FnOnce(&mut [T]) -> Option<crate::error::Result<()>>,
) -> bool {
    z.iter_mut().for_each(|v| *v = T::default());
    scatter_at(bt, at, x, from, z);
    match solve(z) {
        Some(Ok(())) => gather_at(bt, at, z, to, y),
        Some(Err(_)) => to.for_each(|r| y[r] = f64::NAN),
        None => return false,
    }
    true
}

/// A's diagonal from the contacts' d x d blocks (row-major, contact by
/// contact): the normal unknowns, then the tangential ones contact by contact.
fn diag_of(blocks: &[f64], m: usize, d: usize) -> Vec<f64> {
    let mut diag = vec![0.0; d * m];
    for i in 0..m {
        diag[i] = blocks[i * d * d];
        for s in 0..d - 1 {
            diag[m + (d - 1) * i + s] = blocks[i * d * d + (s + 1) * (d + 1)];
        }
    }
    diag
}

/// The dual row of contact i's local unknown l (0 normal, 1.. tangential).
fn row_of(i: usize, l: usize, m: usize, d: usize) -> usize {
    if l == 0 { i } else { m + (d - 1) * i + l - 1 }
}

/// The contacts' d x d diagonal blocks of A = B K^-1 B^T (row-major, contact
/// by contact) from the host: from its entries of K^-1 where it offers them
/// ([`blocks_from_entries`]), else by its solves: the rows of B ([`BLOCK`] at a time, as
/// columns of B^T, `bt`) solved with K, each solution read by its own
/// contact's rows. c solves in all, exactly the blocks (up to the host's
/// solve), and symmetrised.
///
/// Errors: `HostSolve`, `OutOfMemory`.
pub(super) fn host_blocks(
    host: &crate::host::Host,
    bt: &Csc,
    m: usize,
    d: usize,
) -> Result<Vec<f64>> {
    if let Some(blocks) = blocks_from_entries(host, bt, m, d) {
        return blocks;
    }
    let (n, c) = (host.n(), bt.ncols);
    let mut blocks = try_zeros(m * d * d, "the contacts' diagonal blocks")?;
    let mut x: Vec<f64> = try_zeros(
        n * BLOCK.min(c.max(1)),
        "the contact blocks' right-hand sides",
    )?;
    // The columns in order of contact: contact i's d rows together.
    let order: Vec<(usize, usize)> = (0..m).flat_map(|i| (0..d).map(move |l| (i, l))).collect();
    for chunk in order.chunks(BLOCK) {
        let w = chunk.len();
        let x = &mut x[..n * w];
        x.iter_mut().for_each(|v| *v = 0.0);
        for (k, &(i, l)) in chunk.iter().enumerate() {
            let r = row_of(i, l, m, d);
            for q in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                x[k * n + bt.row_idx[q]] += bt.values[q];
            }
        }
        host.solve(x, w)?;
        for (k, &(i, lb)) in chunk.iter().enumerate() {
            let z = &x[k * n..(k + 1) * n];
            for la in 0..d {
                let r = row_of(i, la, m, d);
                let v: f64 = (bt.col_ptr[r]..bt.col_ptr[r + 1])
                    .map(|q| bt.values[q] * z[bt.row_idx[q]])
                    .sum();
                blocks[i * d * d + la * d + lb] = v;
            }
        }
    }
    for i in 0..m {
        for la in 0..d {
            for lb in 0..la {
                let (p, q) = (i * d * d + la * d + lb, i * d * d + lb * d + la);
                let s = 0.5 * (blocks[p] + blocks[q]);
                blocks[p] = s;
                blocks[q] = s;
            }
        }
    }
    Ok(blocks)
}

/// The contacts' blocks from the host's entries of K^-1 (None where it
/// offers none): per contact i, the DOFs S_i its d rows touch, the entries
/// (p, q) of K^-1 for p <= q in S_i asked in one call, and block (la, lb) =
/// sum over p, q in S_i of B_la,p (K^-1)_pq B_lb,q.
pub(super) fn blocks_from_entries(
    host: &crate::host::Host,
    bt: &Csc,
    m: usize,
    d: usize,
) -> Option<Result<Vec<f64>>> {
    // Each contact's DOFs, sorted, and the pairs p <= q among them.
    let mut dofs: Vec<Vec<usize>> = Vec::with_capacity(m);
    let (mut rows, mut cols) = (Vec::new(), Vec::new());
    for i in 0..m {
        let mut s: Vec<usize> = (0..d)
            .flat_map(|l| {
                let r = row_of(i, l, m, d);
                bt.row_idx[bt.col_ptr[r]..bt.col_ptr[r + 1]].iter().copied()
            })
            .collect();
        s.sort_unstable();
        s.dedup();
        for (a, &p) in s.iter().enumerate() {
            for &q in &s[a..] {
                rows.push(p);
                cols.push(q);
            }
        }
        dofs.push(s);
    }
    let mut values = vec![0.0; rows.len()];
    if let Err(e) = host.inverse_entries(&rows, &cols, &mut values)? {
        return Some(Err(e));
    }
    let mut blocks = vec![0.0; m * d * d];
    let mut at = 0;
    let (mut dense, mut ca, mut cb) = (Vec::new(), Vec::new(), Vec::new());
    for (i, s) in dofs.iter().enumerate() {
        // K^-1 on S_i, dense and symmetric.
        let k = s.len();
        dense.clear();
        dense.resize(k * k, 0.0);
        for a in 0..k {
            for b in a..k {
                dense[a * k + b] = values[at];
                dense[b * k + a] = values[at];
                at += 1;
            }
        }
        for la in 0..d {
            row_on_dofs(bt, row_of(i, la, m, d), s, &mut ca);
            for lb in 0..d {
                row_on_dofs(bt, row_of(i, lb, m, d), s, &mut cb);
                let mut v = 0.0;
                for a in 0..k {
                    for b in 0..k {
                        v += ca[a] * dense[a * k + b] * cb[b];
                    }
                }
                blocks[i * d * d + la * d + lb] = v;
            }
        }
    }
    Some(Ok(blocks))
}

/// Row r of B (column r of `bt`) on the sorted DOFs `s`, which hold its
/// nonzeros, into `coef`.
fn row_on_dofs(bt: &Csc, r: usize, s: &[usize], coef: &mut Vec<f64>) {
    coef.clear();
    coef.resize(s.len(), 0.0);
    for q in bt.col_ptr[r]..bt.col_ptr[r + 1] {
        if let Ok(pos) = s.binary_search(&bt.row_idx[q]) {
            coef[pos] += bt.values[q];
        }
    }
}
