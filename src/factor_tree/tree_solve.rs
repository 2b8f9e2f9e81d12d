//! Solves with K's factor for one right-hand side by the elimination tree:
//! the products of the matrix-free dual (B^T x in, B z out).
//!
//! Restricted to paths. With L L^T = P K P^T, the forward solve of a
//! right-hand side that vanishes outside a set of DOFs is zero outside the
//! supernodes on the elimination-tree paths from those DOFs to the root, and
//! the back solve needs only the same supernodes to give the values at those
//! DOFs; both passes then touch those supernodes alone. On a 2D strip whose
//! bottom row is the contact face they hold a third of L's entries; on a thin
//! 3D slab nearly all of them (then every supernode is taken: see
//! MAX_FRACTION).
//!
//! Sparse right-hand sides. The forward solve skips every supernode whose
//! part of the right-hand side is still zero when it is reached: where x
//! vanishes outside a few DOFs (a Newton direction on the closed contacts of
//! a large face), only the supernodes on their paths do work, whatever set
//! the split was made for; the back solve, which fills every column, cannot.
//!
//! On several threads. A solve with one right-hand side is memory-bound and
//! its dense kernels are matrix-vector products, which threads inside a kernel
//! do not speed up; the tree does: the subtrees below a top set of supernodes
//! are independent, so their forward and back substitutions run in parallel,
//! and only the top (the separators near the root) runs on one thread.
//! Forward (L y = P x): each thread takes whole subtrees; an update from a
//! subtree's supernode to a row of its own subtree goes into that subtree's
//! columns, which no other thread touches, an update to a top row into the
//! thread's own accumulator of the top rows, added in afterwards. The top
//! follows on the calling thread. Back (L^T z = y): the top first, then the
//! subtrees in parallel, reading the top's values from a copy.

use crate::factor::Factor;
use crate::factor_tree::supernode_tree::Tree;
use crate::threads::{PARALLEL_MIN_ENTRIES, Threads};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

/// Solves are restricted to the paths where those hold at most this fraction
/// of L's entries.
const MAX_FRACTION: f64 = 0.8;

/// Factors (or paths) with fewer entries than this are solved on one thread:
/// below it handing the subtrees to the pool costs more than it saves.
const MIN_ENTRIES: usize = 1 << 18;

/// Subtrees per thread the split aims at (the bins are balanced greedily).
const TASKS_PER_THREAD: usize = 2;

/// Marks a column outside the top in [`TreeSolve::top_at`].
const NONE: usize = usize::MAX;

/// The right-hand side shared by the threads of a solve, each writing only
/// the columns of its own subtrees (see the module docs).
#[derive(Copy, Clone)]
struct Shared<T>(*mut T);

// SAFETY: the threads of a solve write disjoint entries (their subtrees'
// columns) and read only those, so sharing the pointer is a data-race-free
// split of one &mut [T].
unsafe impl<T: Send> Send for Shared<T> {}
// SAFETY: as for Send.
unsafe impl<T: Send> Sync for Shared<T> {}

impl<T> Shared<T> {
    /// Entries at..at + len.
    ///
    /// # Safety
    /// Within the vector, and touched by no other thread while the slice lives.
    #[allow(clippy::mut_from_ref)]
    unsafe fn cols(&self, at: usize, len: usize) -> &mut [T] {
        // SAFETY: the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.0.add(at), len) }
    }
}

/// The split of a factor's elimination tree for a number of threads.
pub(crate) struct TreeSolve {
    /// Per thread, its subtrees' supernodes, children first.
    bins: Vec<Vec<usize>>,
    /// The top supernodes, children first.
    top: Vec<usize>,
    /// The top's columns, ascending, and per column of the factor its index
    /// among them (NONE outside the top; empty without a top).
    top_cols: Vec<usize>,
    top_at: Vec<usize>,
    /// The longest pattern below a supernode (one update's scratch).
    below: usize,
    /// The columns the solves read and write (the factor's order): those of
    /// the supernodes on the paths of the DOFs they were restricted to, or
    /// None for all.
    cols: Option<Vec<usize>>,
}

/// Scratch of [`TreeSolve`]'s solves in one precision: the right-hand side in
/// the factor's ordering, per thread an accumulator of the top rows and an
/// update's scratch, and the top's values for the back substitution.
pub(crate) struct TreeScratch<T> {
    work: Vec<T>,
    per_bin: Vec<(Vec<T>, Vec<T>)>,
    top_vals: Vec<T>,
    buf: Vec<T>,
}

impl TreeSolve {
    /// The solves of `factor` for right-hand sides that vanish outside `dofs`
    /// (original numbering), of which the values at `dofs` are wanted:
    /// restricted to the supernodes on their paths to the roots where those
    /// hold at most MAX_FRACTION of L's entries, else over all of them; split
    /// between the factor's threads where the supernodes taken are many enough
    /// and split into at least two subtrees, else in one bin on the calling
    /// thread. None for a dense factor (no tree).
    pub(crate) fn of(factor: &Factor, dofs: &[usize]) -> Option<TreeSolve> {
        if factor.is_dense() {
            return None;
        }
        Some(TreeSolve::on(factor, &Tree::of(factor), dofs))
    }

    /// As [`TreeSolve::of`] on a sparse factor, with its elimination tree
    /// `tree` (made once by a caller that splits often).
    pub(crate) fn on(factor: &Factor, tree: &Tree, dofs: &[usize]) -> TreeSolve {
        let threads = factor.threads().count();
        let sym = factor.supernodal_symbolic();
        let ns = tree.len();
        let pattern_len = |s: usize| sym.supernode(s).pattern().len();
        let mut weight: Vec<usize> = (0..ns)
            .map(|s| (tree.width[s] + pattern_len(s)) * tree.width[s])
            .collect();
        let new_of = factor.new_of_old();
        let on_paths = tree.on_paths(dofs.iter().map(|&dof| tree.of_col[new_of[dof]]));
        let all: usize = weight.iter().sum();
        let on: usize = (0..ns).filter(|&s| on_paths[s]).map(|s| weight[s]).sum();
        let restricted = all > 0 && on as f64 <= MAX_FRACTION * all as f64;
        let needed = if restricted { on_paths } else { vec![true; ns] };
        let mut children = vec![Vec::new(); ns];
        let mut roots = Vec::new();
        let on = || (0..ns).filter(|&s| needed[s]);
        let below = on().map(pattern_len).max().unwrap_or(0);
        // Children before parents: the subtrees' entries in one pass (the
        // paths are closed upwards: a needed supernode's parent is needed).
        for s in on() {
            match tree.parent[s] {
                NONE => roots.push(s),
                p => {
                    children[p].push(s);
                    weight[p] += weight[s];
                }
            }
        }
        let cols = restricted.then(|| {
            on().flat_map(|s| tree.begin[s]..tree.begin[s] + tree.width[s])
                .collect()
        });
        let total: usize = roots.iter().map(|&r| weight[r]).sum();
        // The top: the heaviest subtree is split while it holds more than its
        // share (as the selected inversion's split).
        // (Entry counts as f64: exact below 2^53, so the comparisons, the
        // integer limit and the bins' loads are those of the counts.)
        let as_f64 = |s: usize| weight[s] as f64;
        let split = threads >= 2 && total >= MIN_ENTRIES;
        let (mut top, tasks) = if split {
            let limit = total / (TASKS_PER_THREAD * threads);
            crate::tree_cholesky::split_top(as_f64, &children, roots, limit as f64)
        } else {
            (Vec::new(), roots)
        };
        if !split || tasks.len() < 2 {
            // No split: every supernode taken, in one bin.
            return TreeSolve {
                bins: vec![on().collect()],
                top: Vec::new(),
                top_cols: Vec::new(),
                top_at: Vec::new(),
                below,
                cols,
            };
        }
        top.sort_unstable();
        let mut top_cols = Vec::new();
        for &s in &top {
            top_cols.extend(tree.begin[s]..tree.begin[s] + tree.width[s]);
        }
        let mut top_at = vec![NONE; factor.n()];
        for (i, &col) in top_cols.iter().enumerate() {
            top_at[col] = i;
        }
        // Heaviest first into the lightest bin.
        let bins = crate::tree_cholesky::fill_bins(as_f64, &children, tasks, threads);
        TreeSolve {
            bins,
            top,
            top_cols,
            top_at,
            below,
            cols,
        }
    }

    /// Zeroes x (n, original numbering) where the solves read it: at the
    /// DOFs of the paths' columns, or everywhere when not restricted.
    pub(crate) fn clear<T: Copy + Default>(&self, factor: &Factor, x: &mut [T]) {
        match &self.cols {
            Some(cols) => {
                let old_of = factor.old_of_new();
                cols.iter().for_each(|&new| x[old_of[new]] = T::default());
            }
            None => x.fill(T::default()),
        }
    }

    /// Scratch for the solves in precision T on a factor of order n.
    pub(crate) fn scratch<T: Copy + Default>(&self, n: usize) -> TreeScratch<T> {
        let top = self.top_cols.len();
        TreeScratch {
            work: vec![T::default(); n],
            per_bin: self
                .bins
                .iter()
                .map(|_| (vec![T::default(); top], vec![T::default(); self.below]))
                .collect(),
            top_vals: vec![T::default(); top],
            buf: vec![T::default(); self.below],
        }
    }

    /// Fits `scratch`, made by another split of the same factor, to this
    /// one: its vectors keep their capacity, so refitting allocates only
    /// where this split needs more than any before it.
    pub(crate) fn refit<T: Copy + Default>(&self, scratch: &mut TreeScratch<T>) {
        let top = self.top_cols.len();
        scratch
            .per_bin
            .resize_with(self.bins.len(), || (Vec::new(), Vec::new()));
        for (acc, buf) in &mut scratch.per_bin {
            acc.resize(top, T::default());
            buf.resize(self.below, T::default());
        }
        scratch.top_vals.resize(top, T::default());
        scratch.buf.resize(self.below, T::default());
    }

    /// An upper bound on [`TreeSolve::bytes_with_scratch`] for the split of
    /// `factor` restricted to any set of DOFs: every column on the paths and
    /// in the top, a bin per thread, the longest pattern below a supernode.
    pub(crate) fn bytes_bound(factor: &Factor) -> usize {
        let n = factor.n();
        if factor.is_dense() {
            return 0;
        }
        let sym = factor.supernodal_symbolic();
        let ns = sym.n_supernodes();
        let below = (0..ns)
            .map(|s| sym.supernode(s).pattern().len())
            .max()
            .unwrap_or(0);
        let threads = factor.threads().count();
        // Without a split: one bin, no top (and no index of the top's columns).
        let (bins, top, top_index) = if threads >= 2 {
            (threads, n, n)
        } else {
            (1, 0, 0)
        };
        let scratch = n + (bins + 1) * (top + below);
        scratch * (std::mem::size_of::<f64>() + std::mem::size_of::<f32>())
            + (top_index + n + top + ns) * std::mem::size_of::<usize>()
    }

    /// Entries of [`TreeSolve::scratch`] (in its precision).
    pub(crate) fn scratch_len(&self, n: usize) -> usize {
        n + (self.bins.len() + 1) * (self.top_cols.len() + self.below)
    }

    /// Bytes of the split and of its scratch in double and single precision
    /// (what a holder of both claims), on a factor of order n.
    pub(crate) fn bytes_with_scratch(&self, n: usize) -> usize {
        self.scratch_len(n) * (std::mem::size_of::<f64>() + std::mem::size_of::<f32>())
            + self.bytes()
    }

    /// Bytes of the split itself besides its scratch (the top's index per
    /// column and the restricted columns).
    fn bytes(&self) -> usize {
        let cols = self.cols.as_ref().map_or(0, Vec::len);
        (self.top_at.len()
            + cols
            + self.top_cols.len()
            + self.bins.iter().map(Vec::len).sum::<usize>())
            * std::mem::size_of::<usize>()
    }

    /// Whether the solves are restricted to paths (see [`TreeSolve::of`]).
    pub(crate) fn restricted(&self) -> bool {
        self.cols.is_some()
    }

    /// The top's index of column `row`, NONE outside the top.
    fn top_of(&self, row: usize) -> usize {
        if self.top.is_empty() {
            NONE
        } else {
            self.top_at[row]
        }
    }

    /// Threads the solves use (one bin of subtrees each).
    #[cfg(test)]
    pub(crate) fn threads(&self) -> usize {
        self.bins.len()
    }
}

/// `f` on each bin with its scratch: on the pool's threads, one bin each,
/// unless `par` is sequential.
fn for_each_bin<T: Send>(
    par: Par,
    bins: &[Vec<usize>],
    scratch: &mut [(Vec<T>, Vec<T>)],
    f: impl Fn((&Vec<usize>, &mut (Vec<T>, Vec<T>))) + Sync + Send,
) {
    match par {
        Par::Seq => bins.iter().zip(scratch.iter_mut()).for_each(f),
        _ => (bins.par_iter(), scratch.par_iter_mut())
            .into_par_iter()
            .for_each(f),
    }
}

/// The parallelism of one supernode's kernels (w columns, r rows below):
/// `par` where the block is large enough to pay for it.
fn kernel_par(w: usize, r: usize, par: Par) -> Par {
    if (w + r) * w >= PARALLEL_MIN_ENTRIES {
        par
    } else {
        Par::Seq
    }
}

/// One supernode's forward step on the right-hand side at `x` (the factor's
/// ordering): x_s := L_ss^-1 x_s, then `scatter(row, v)` for each row of its
/// pattern with v = (L_Rs x_s)_row, to be subtracted there; nothing where x_s
/// is zero.
macro_rules! forward_node {
    ($llt:expr, $begin:expr, $s:expr, $x:expr, $buf:expr, $scatter:expr, $par:expr) => {{
        let node = $llt.supernode($s);
        let val = node.val();
        let (w, pattern) = (val.ncols(), node.pattern());
        let r = pattern.len();
        let par = kernel_par(w, r, $par);
        let xs = $x($begin[$s], w);
        // A supernode whose right-hand side is zero has a zero solution and
        // scatters nothing (see the module docs: sparse right-hand sides).
        if xs.iter().any(|v| *v != 0.0) {
            solve_lower_triangular_in_place(
                val.submatrix(0, 0, w, w),
                MatMut::from_column_major_slice_mut(&mut *xs, w, 1),
                par,
            );
            if r > 0 {
                matmul(
                    MatMut::from_column_major_slice_mut(&mut $buf[..r], r, 1),
                    Accum::Replace,
                    val.submatrix(w, 0, r, w),
                    MatRef::from_column_major_slice(xs, w, 1),
                    1.0,
                    par,
                );
                for (&row, &v) in pattern.iter().zip(&$buf[..r]) {
                    $scatter(row, v);
                }
            }
        }
    }};
}

/// One supernode's back step: x_s := L_ss^-T (x_s - L_Rs^T x_R), x_R read by
/// `gather(row)`.
macro_rules! back_node {
    ($llt:expr, $begin:expr, $s:expr, $x:expr, $buf:expr, $gather:expr, $par:expr) => {{
        let node = $llt.supernode($s);
        let val = node.val();
        let (w, pattern) = (val.ncols(), node.pattern());
        let r = pattern.len();
        let par = kernel_par(w, r, $par);
        for (v, &row) in $buf[..r].iter_mut().zip(pattern) {
            *v = $gather(row);
        }
        let xs = $x($begin[$s], w);
        if r > 0 {
            matmul(
                MatMut::from_column_major_slice_mut(&mut *xs, w, 1),
                Accum::Add,
                val.submatrix(w, 0, r, w).transpose(),
                MatRef::from_column_major_slice(&$buf[..r], r, 1),
                -1.0,
                par,
            );
        }
        solve_upper_triangular_in_place(
            val.submatrix(0, 0, w, w).transpose(),
            MatMut::from_column_major_slice_mut(xs, w, 1),
            par,
        );
    }};
}

macro_rules! tree_solve {
    ($name:ident, $t:ty) => {
        impl TreeSolve {
            /// x := K^-1 x (x: n, original numbering) for an x that vanishes
            /// outside the DOFs [`TreeSolve::of`] was given, with L's values
            /// `values` in this precision, on `threads`; restricted to paths,
            /// only at their DOFs, x's other entries left as they were.
            pub(crate) fn $name(
                &self,
                factor: &Factor,
                values: &[$t],
                x: &mut [$t],
                scratch: &mut TreeScratch<$t>,
                threads: &Threads,
            ) {
                let sym = factor.supernodal_symbolic();
                let llt = SupernodalLltRef::<usize, $t>::new(sym, values);
                let begin = sym.supernode_begin();
                let old_of = factor.old_of_new();
                let TreeScratch {
                    work,
                    per_bin,
                    top_vals,
                    buf,
                } = scratch;
                match &self.cols {
                    Some(cols) => cols.iter().for_each(|&new| work[new] = x[old_of[new]]),
                    None => old_of
                        .iter()
                        .enumerate()
                        .for_each(|(new, &old)| work[new] = x[old]),
                }
                threads.run(self.bins.len() > 1, |par| {
                    let shared = Shared(work.as_mut_ptr());
                    // SAFETY (both closures): a bin's threads touch only the
                    // columns of its own subtrees' supernodes: the x_s of a
                    // supernode it holds, and rows of its pattern outside the
                    // top, which are those of its ancestors in the same subtree
                    // (see `Shared`); `work` is not used otherwise meanwhile.
                    let cols = |at: usize, len: usize| unsafe { shared.cols(at, len) };
                    let entry = |at: usize| unsafe { &mut shared.cols(at, 1)[0] };
                    // Forward, the subtrees: each bin's accumulator of the top rows.
                    let forward = |(bin, scratch): (&Vec<usize>, &mut (Vec<$t>, Vec<$t>))| {
                        let (acc, buf) = (&mut scratch.0, &mut scratch.1);
                        acc.iter_mut().for_each(|v| *v = 0.0);
                        for &s in bin {
                            forward_node!(
                                llt,
                                begin,
                                s,
                                cols,
                                buf,
                                |row: usize, v: $t| match self.top_of(row) {
                                    NONE => *entry(row) -= v,
                                    i => acc[i] -= v,
                                },
                                Par::Seq
                            );
                        }
                    };
                    for_each_bin(par, &self.bins, per_bin, forward);
                    for (acc, _) in per_bin.iter() {
                        for (&col, &v) in self.top_cols.iter().zip(acc) {
                            *entry(col) += v;
                        }
                    }
                    // The top, forward then back, on this thread.
                    for &s in &self.top {
                        forward_node!(
                            llt,
                            begin,
                            s,
                            cols,
                            buf,
                            |row: usize, v: $t| *entry(row) -= v,
                            par
                        );
                    }
                    for &s in self.top.iter().rev() {
                        back_node!(llt, begin, s, cols, buf, |row: usize| *entry(row), par);
                    }
                    for (v, &col) in top_vals.iter_mut().zip(&self.top_cols) {
                        *v = *entry(col);
                    }
                    // Back, the subtrees, reading the top from its copy.
                    let top_vals = &*top_vals;
                    let back = |(bin, scratch): (&Vec<usize>, &mut (Vec<$t>, Vec<$t>))| {
                        let buf = &mut scratch.1;
                        for &s in bin.iter().rev() {
                            back_node!(
                                llt,
                                begin,
                                s,
                                cols,
                                buf,
                                |row: usize| match self.top_of(row) {
                                    NONE => *entry(row),
                                    i => top_vals[i],
                                },
                                Par::Seq
                            );
                        }
                    };
                    for_each_bin(par, &self.bins, per_bin, back);
                });
                match &self.cols {
                    Some(cols) => cols.iter().for_each(|&new| x[old_of[new]] = work[new]),
                    None => old_of
                        .iter()
                        .enumerate()
                        .for_each(|(new, &old)| x[old] = work[new]),
                }
            }
        }
    };
}

tree_solve!(solve, f64);
tree_solve!(solve_single, f32);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::factor_tree::selected_inverse::tests::grid3;
    use crate::options::Ordering;
    use std::sync::Arc;

    /// Restricted to the paths of a strip's bottom row, on one thread (one
    /// bin, no top) and split between two: the tree solve equals the full
    /// solve at the row's DOFs (double to 1e-13, single to 1e-5) and touches
    /// no other entry of x.
    #[test]
    fn restricted_tree_solve_equals_the_full_one_at_the_dofs() {
        let (nx, ny) = (2000, 20);
        let k = crate::dual::tests::grid(nx, ny);
        let n = nx * ny;
        let dofs: Vec<usize> = (0..nx).collect();
        for (ordering, threads) in [Ordering::Amd, Ordering::Metis]
            .into_iter()
            .flat_map(|o| [(o, 1), (o, 2)])
        {
            let pool = Arc::new(Threads::new(threads));
            let f = Factor::with_last(&k, &[], ordering, pool).unwrap();
            let ts = TreeSolve::of(&f, &dofs).expect("restricted");
            assert!(ts.restricted() && ts.threads() == threads);
            assert_eq!(ts.top.is_empty(), threads == 1);
            assert!(
                ts.cols.as_ref().unwrap().len() < n / 2,
                "paths hold few columns"
            );
            let mut x = vec![0.0; n];
            for (i, &d) in dofs.iter().enumerate() {
                x[d] = (i as f64 * 0.7).sin() + 0.2;
            }
            let mut full = x.clone();
            f.solve_vec(&mut full);
            let scale = full.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            // Entries off the paths keep a marker.
            let mut got = x.clone();
            got[n - 1] = 7.0;
            let mut scratch = ts.scratch::<f64>(n);
            ts.solve(&f, f.values(), &mut got, &mut scratch, f.threads());
            for &d in &dofs {
                assert!(
                    (got[d] - full[d]).abs() <= 1e-13 * scale,
                    "{ordering:?} {d}"
                );
            }
            let on_paths = ts.cols.as_ref().unwrap().contains(&f.new_of_old()[n - 1]);
            assert!(on_paths || got[n - 1] == 7.0);
            let values = f.single_values().unwrap();
            let mut xs: Vec<f32> = x.iter().map(|&v| v as f32).collect();
            let mut ss = ts.scratch::<f32>(n);
            ts.solve_single(&f, &values, &mut xs, &mut ss, f.threads());
            for &d in &dofs {
                assert!((f64::from(xs[d]) - full[d]).abs() <= 1e-5 * scale, "{d}");
            }
        }
    }

    /// The tree solve equals faer's solve (double to 1e-13, single to 1e-5),
    /// with 2 and 3 threads, AMD and METIS, and on two components; one thread
    /// gives no split.
    #[test]
    fn tree_solve_equals_the_plain_solve() {
        let one = grid3(24, 20, 10);
        // Two disconnected copies: two roots.
        let n1 = one.nrows;
        let mut t = Vec::new();
        for j in 0..n1 {
            for k in one.col_ptr[j]..one.col_ptr[j + 1] {
                t.push((one.row_idx[k], j, one.values[k]));
                t.push((one.row_idx[k] + n1, j + n1, one.values[k]));
            }
        }
        let two = crate::sparse::Csc::from_triplets(2 * n1, 2 * n1, &t);
        for k in [&one, &two] {
            let n = k.nrows;
            // Every DOF: the paths are all of L, never restricted.
            let all: Vec<usize> = (0..n).collect();
            for ordering in [Ordering::Amd, Ordering::Metis] {
                for threads in [1, 2, 3] {
                    let f = Factor::with_last(k, &[], ordering, Arc::new(Threads::new(threads)))
                        .unwrap();
                    let ts = TreeSolve::of(&f, &all).expect("a split");
                    assert!(!ts.restricted());
                    assert_eq!(ts.threads(), threads);
                    assert!(threads == 1 || !ts.top.is_empty() || k.nrows == 2 * n1);
                    sparse_rhs_solves_equal_the_plain_one(&f, &ts);
                    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() + 0.1).collect();
                    let mut full = x.clone();
                    f.solve_vec(&mut full);
                    let scale = full.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                    let mut got = x.clone();
                    let mut scratch = ts.scratch::<f64>(n);
                    ts.solve(&f, f.values(), &mut got, &mut scratch, f.threads());
                    for i in 0..n {
                        assert!(
                            (got[i] - full[i]).abs() <= 1e-13 * scale,
                            "{ordering:?} {i}"
                        );
                    }
                    // Again with the same scratch (the accumulators are reset).
                    let mut again = x.clone();
                    ts.solve(&f, f.values(), &mut again, &mut scratch, f.threads());
                    assert_eq!(again, got);
                    let values = f.single_values().unwrap();
                    let mut xs: Vec<f32> = x.iter().map(|&v| v as f32).collect();
                    let mut ss = ts.scratch::<f32>(n);
                    ts.solve_single(&f, &values, &mut xs, &mut ss, f.threads());
                    for i in 0..n {
                        assert!((f64::from(xs[i]) - full[i]).abs() <= 1e-5 * scale, "{i}");
                    }
                }
            }
        }
    }

    /// Right-hand sides that vanish outside a few DOFs (the forward solve
    /// skips the supernodes where they are still zero): the whole solution
    /// equals the plain solve's, in double and single precision.
    fn sparse_rhs_solves_equal_the_plain_one(f: &Factor, ts: &TreeSolve) {
        let n = f.n();
        for (stride, len) in [(97, n / 10), (13, n), (1, 7)] {
            let mut x = vec![0.0; n];
            for i in (0..len).step_by(stride) {
                x[i] = 1.0 + (i as f64 * 0.61).cos();
            }
            let mut full = x.clone();
            f.solve_vec(&mut full);
            let scale = full.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let mut got = x.clone();
            ts.solve(f, f.values(), &mut got, &mut ts.scratch(n), f.threads());
            for i in 0..n {
                assert!((got[i] - full[i]).abs() <= 1e-13 * scale, "{stride} {i}");
            }
            let mut xs: Vec<f32> = x.iter().map(|&v| v as f32).collect();
            let values = f.single_values().unwrap();
            ts.solve_single(f, &values, &mut xs, &mut ts.scratch(n), f.threads());
            for i in 0..n {
                assert!((f64::from(xs[i]) - full[i]).abs() <= 1e-5 * scale, "{i}");
            }
        }
    }
}
