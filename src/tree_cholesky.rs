//! The numeric supernodal Cholesky factorisation on several threads, by the
//! elimination tree.
//!
//! faer's supernodal factorisation visits the supernodes one after the other
//! and hands its threads to the dense kernels of each: on a thin 3D slab
//! (fronts of a few hundred columns) a second thread took 4 % off it
//! (BENCHMARKS.md, "Orderings, threads and CHOLMOD"). The work of a
//! left-looking factorisation splits along the tree instead: supernode s is
//! formed from K's entries in its columns and the updates of the supernodes
//! below it (its descendants, whose patterns meet its columns), so the
//! subtrees below a top set of supernodes are independent. Each thread
//! factors whole subtrees with sequential kernels; the top (the separators
//! near the root) follows with the dense kernels on all threads.
//!
//! The layout of L is faer's (`SymbolicSupernodalCholesky`): supernode s is a
//! column-major block of (w + r) x w values, its w x w diagonal block lower
//! triangular (the upper part stays zero), then the r rows of its pattern.
//! The values are those of faer's factorisation up to rounding (the updates
//! are summed in the same order, by other kernels); a subtree's supernodes
//! come out the same whichever thread factors them.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::sparse::SparseColMatRef;
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering as AtomicOrdering};

const NONE: usize = usize::MAX;

/// Columns of an update formed at once by a dense product: its scratch holds
/// at most this many columns of the longest pattern.
const CHUNK: usize = 256;

/// Updates of at most this many multiply-adds are summed entry by entry,
/// without a product call (the leaves' supernodes are one to a few columns
/// wide, and a call costs more than their work).
const SMALL: usize = 4096;

/// Subtrees per thread the split aims at (the bins are balanced greedily).
const TASKS_PER_THREAD: usize = 2;

/// How the factorisation of one symbolic structure is split between threads.
pub(crate) struct Plan {
    /// Where each supernode's updates start in `updates`.
    update_ptr: Vec<usize>,
    /// Per supernode s, the supernodes below it whose patterns meet its
    /// columns (the updates s receives), ascending:
    /// `updates[update_ptr[s]..update_ptr[s + 1]]`.
    updates: Vec<usize>,
    /// Per thread, its subtrees' supernodes, children first (ascending).
    bins: Vec<Vec<usize>>,
    /// The top supernodes, children first (ascending), factored after the
    /// bins with the kernels on all threads.
    top: Vec<usize>,
    /// The longest pattern below a supernode.
    longest: usize,
    /// The widest supernode (columns).
    widest: usize,
}

impl Plan {
    /// The plan of `sym` for `threads` threads; None where the tree does not
    /// split into two subtrees at least (one thread, or a chain), or where an
    /// update would cross from one bin to another (never, in a supernodal
    /// elimination tree; checked, since the split's soundness rests on it).
    pub(crate) fn of(sym: &SymbolicSupernodalCholesky<usize>, threads: usize) -> Option<Plan> {
        if threads < 2 {
            return None;
        }
        let ns = sym.n_supernodes();
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        let pattern = |s: usize| sym.supernode(s).pattern();
        // The supernodal elimination tree: each column's supernode, and each
        // supernode's parent (the one holding its pattern's first row).
        let mut of_col = vec![0usize; sym.nrows()];
        for s in 0..ns {
            of_col[begin[s]..end[s]].fill(s);
        }
        let parent: Vec<usize> = (0..ns)
            .map(|s| pattern(s).first().map_or(NONE, |&row| of_col[row]))
            .collect();
        let width: Vec<usize> = (0..ns).map(|s| end[s] - begin[s]).collect();
        // Per supernode its flops as a right-looking step (factor, solve
        // below, the update it sends), summed over each subtree.
        let mut weight: Vec<f64> = (0..ns)
            .map(|s| {
                let (w, r) = (width[s] as f64, pattern(s).len() as f64);
                w * w * w / 3.0 + w * w * r + w * r * r
            })
            .collect();
        let mut children = vec![Vec::new(); ns];
        let mut roots = Vec::new();
        for s in 0..ns {
            match parent[s] {
                NONE => roots.push(s),
                p => {
                    children[p].push(s);
                    weight[p] += weight[s];
                }
            }
        }
        let total: f64 = roots.iter().map(|&r| weight[r]).sum();
        // The heaviest subtree is moved to the top, its children becoming
        // tasks, while it holds more than its share.
        let limit = total / (TASKS_PER_THREAD * threads) as f64;
        let (mut top, tasks) = split_top(|s| weight[s], &children, roots, limit);
        if tasks.len() < 2 {
            return None;
        }
        top.sort_unstable();
        let bins = fill_bins(|s| weight[s], &children, tasks, threads);
        // The updates: d updates every supernode holding a row of its
        // pattern (the rows are sorted, so each one's rows come together).
        let mut count = vec![0usize; ns + 1];
        let each = |visit: &mut dyn FnMut(usize, usize)| {
            for d in 0..ns {
                let mut last = NONE;
                for &row in pattern(d) {
                    let s = of_col[row];
                    if s != last {
                        visit(s, d);
                        last = s;
                    }
                }
            }
        };
        each(&mut |s, _| count[s + 1] += 1);
        for s in 0..ns {
            count[s + 1] += count[s];
        }
        let update_ptr = count.clone();
        let mut updates = vec![0usize; count[ns]];
        each(&mut |s, d| {
            updates[count[s]] = d;
            count[s] += 1;
        });
        // What makes the split free of races (see Shared): every update comes
        // from a supernode before its destination and in the same bin, or
        // goes to the top. (Supernodal elimination trees give it; a structure
        // that did not is factored sequentially instead.)
        let mut owner = vec![NONE; ns];
        for (b, bin) in bins.iter().enumerate() {
            bin.iter().for_each(|&s| owner[s] = b);
        }
        let safe = (0..ns).all(|s| {
            updates[update_ptr[s]..update_ptr[s + 1]]
                .iter()
                .all(|&d| d < s && (owner[s] == NONE || owner[s] == owner[d]))
        });
        if !safe {
            return None;
        }
        Some(Plan {
            update_ptr,
            updates,
            bins,
            top,
            longest: (0..ns).map(|s| pattern(s).len()).max().unwrap_or(0),
            widest: width.iter().copied().max().unwrap_or(0),
        })
    }
}

#[cfg(test)]
impl Plan {
    /// The bins and the top.
    pub(crate) fn split(&self) -> (&[Vec<usize>], &[usize]) {
        (&self.bins, &self.top)
    }
}

/// Bytes a factorisation of `sym` split between `threads` threads takes
/// besides faer's own scratch (P K P^T's lower triangle, which it forms the
/// same way), at most: the tree while the plan is made, the plan (an update
/// per supernode met by each pattern, at most the patterns' length), and per
/// thread a map of the n rows, an update's product and rows, and the dense
/// Cholesky's scratch.
pub(crate) fn bytes_bound(sym: &SymbolicSupernodalCholesky<usize>, threads: usize) -> usize {
    let word = std::mem::size_of::<usize>();
    let (n, ns) = (sym.nrows(), sym.n_supernodes());
    let longest = (0..ns)
        .map(|s| sym.supernode(s).pattern().len())
        .max()
        .unwrap_or(0);
    let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
    let widest = (0..ns).map(|s| end[s] - begin[s]).max().unwrap_or(0);
    let tree = (n + 3 * ns) * word;
    let plan = (sym.row_idx().len() + 3 * ns + 1) * word;
    let per_thread = (n + longest) * word
        + longest * CHUNK * std::mem::size_of::<f64>()
        + cholesky_in_place_scratch::<f64>(widest, Par::Seq, Default::default()).size_bytes();
    tree + plan + threads * per_thread
}

/// The top of a forest's split between threads (this factorisation's, the
/// tree solves' and the selected inversion's): while the heaviest task (by
/// `weight`, its subtree's) weighs more than `limit` and has children, it
/// moves to the top and its children become tasks, starting from `roots`.
/// Returns the top, in the order moved, and the tasks.
pub(crate) fn split_top(
    weight: impl Fn(usize) -> f64,
    children: &[Vec<usize>],
    roots: Vec<usize>,
    limit: f64,
) -> (Vec<usize>, Vec<usize>) {
    let (mut top, mut tasks) = (Vec::new(), roots);
    while let Some((at, &s)) = tasks
        .iter()
        .enumerate()
        .max_by(|a, b| weight(*a.1).total_cmp(&weight(*b.1)))
    {
        if weight(s) <= limit || children[s].is_empty() {
            break;
        }
        tasks.swap_remove(at);
        top.push(s);
        tasks.extend(&children[s]);
    }
    (top, tasks)
}

/// The tasks' subtrees in `threads` bins, heaviest first into the lightest
/// (by `weight`), each bin's supernodes ascending (children first); empty
/// bins dropped.
pub(crate) fn fill_bins(
    weight: impl Fn(usize) -> f64,
    children: &[Vec<usize>],
    mut tasks: Vec<usize>,
    threads: usize,
) -> Vec<Vec<usize>> {
    tasks.sort_unstable_by(|a, b| weight(*b).total_cmp(&weight(*a)));
    let mut bins: Vec<Vec<usize>> = vec![Vec::new(); threads];
    let mut load = vec![0.0f64; threads];
    for root in tasks {
        let b = (0..threads)
            .min_by(|x, y| load[*x].total_cmp(&load[*y]))
            .expect("at least one bin");
        load[b] += weight(root);
        let mut stack = vec![root];
        while let Some(s) = stack.pop() {
            bins[b].push(s);
            stack.extend(&children[s]);
        }
    }
    for bin in &mut bins {
        bin.sort_unstable();
    }
    bins.retain(|b| !b.is_empty());
    bins
}

/// L's values shared by the threads of a factorisation, each writing only
/// the blocks of its own supernodes.
#[derive(Copy, Clone)]
struct Shared(*mut f64);

// SAFETY: each supernode's block is written by one thread alone, and read by
// others only after that thread finished it (a descendant in the same bin,
// or a bin that ended before the top began): a data-race-free split of one
// &mut [f64].
unsafe impl Send for Shared {}
// SAFETY: as for Send.
unsafe impl Sync for Shared {}

/// A thread's scratch: the position of each row in the supernode being
/// formed (NONE elsewhere), an update's product and its destination rows,
/// and the dense Cholesky's workspace.
struct Work {
    map: Vec<usize>,
    product: Vec<f64>,
    dest: Vec<usize>,
    chol: MemBuffer,
}

impl Work {
    fn new(n: usize, plan: &Plan, par: Par) -> Work {
        Work {
            map: vec![NONE; n],
            product: vec![0.0; plan.longest * CHUNK],
            dest: vec![0; plan.longest],
            chol: MemBuffer::new(cholesky_in_place_scratch::<f64>(
                plan.widest,
                par,
                Default::default(),
            )),
        }
    }
}

/// Factors P K P^T into `values` (of `sym`'s length, any contents: each
/// supernode's block is zeroed before it is written) as `plan` splits
/// it, on the pool of the caller (a rayon pool of `par`'s threads, installed;
/// `Par::Seq`: every bin on the calling thread, where the pool could not be
/// started): `a` holds the lower triangle of P K P^T (rows in any order
/// within a column). Err(column) at the first non-positive pivot, in the
/// factor's order, as a sequential factorisation would meet it: each bin
/// stops at its own first, then the top's supernodes before the first of the
/// bins are factored (their descendants all come before them, so no bin
/// stopped short of one), and the first of all is reported.
pub(crate) fn factor(
    plan: &Plan,
    sym: &SymbolicSupernodalCholesky<usize>,
    a: SparseColMatRef<'_, usize, f64>,
    values: &mut [f64],
    par: Par,
) -> Result<(), usize> {
    assert_eq!(values.len(), sym.len_val());
    assert_eq!(
        plan.update_ptr.len(),
        sym.n_supernodes() + 1,
        "a plan of this structure"
    );
    let n = sym.nrows();
    let shared = Shared(values.as_mut_ptr());
    let failed = AtomicUsize::new(NONE);
    let bin = |bin: &Vec<usize>| {
        let mut work = Work::new(n, plan, Par::Seq);
        for &s in bin {
            if let Err(col) = supernode(s, plan, sym, a, shared, &mut work, Par::Seq) {
                failed.fetch_min(col, AtomicOrdering::Relaxed);
                break;
            }
        }
    };
    match par {
        Par::Seq => plan.bins.iter().for_each(bin),
        _ => plan.bins.par_iter().for_each(bin),
    }
    let failed = failed.into_inner();
    let begin = sym.supernode_begin();
    let mut work = Work::new(n, plan, par);
    for &s in plan.top.iter().take_while(|&&s| begin[s] < failed) {
        supernode(s, plan, sym, a, shared, &mut work, par)?;
    }
    match failed {
        NONE => Ok(()),
        col => Err(col),
    }
}

/// Forms and factors supernode s: K's entries of its columns, minus the
/// updates of the supernodes below it, then the dense Cholesky of its
/// diagonal block and the triangular solve of the rows below.
fn supernode(
    s: usize,
    plan: &Plan,
    sym: &SymbolicSupernodalCholesky<usize>,
    a: SparseColMatRef<'_, usize, f64>,
    shared: Shared,
    work: &mut Work,
    par: Par,
) -> Result<(), usize> {
    let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
    let at = sym.col_ptr_for_val();
    let (s_start, s_end) = (begin[s], end[s]);
    let s_pattern = sym.supernode(s).pattern();
    let w = s_end - s_start;
    let rows = w + s_pattern.len();
    for (i, &row) in s_pattern.iter().enumerate() {
        work.map[row] = w + i;
    }
    // SAFETY: s's block lies within `values` (faer's layout) and no other
    // thread touches it (the module's split; see Shared).
    let ls = unsafe { std::slice::from_raw_parts_mut(shared.0.add(at[s]), at[s + 1] - at[s]) };
    // Written before anything reads it: fresh pages of a zeroed allocation
    // read first are the shared zero page, and the write after it is a
    // copy-on-write fault that flushes every thread's TLB.
    ls.fill(0.0);
    for j in s_start..s_end {
        let col = &mut ls[(j - s_start) * rows..(j - s_start + 1) * rows];
        for (&i, &v) in a.row_idx_of_col_raw(j).iter().zip(a.val_of_col(j)) {
            if i >= j {
                col[if i < s_end { i - s_start } else { work.map[i] }] += v;
            }
        }
    }
    for &d in &plan.updates[plan.update_ptr[s]..plan.update_ptr[s + 1]] {
        let d_pattern = sym.supernode(d).pattern();
        let dw = end[d] - begin[d];
        let d_rows = dw + d_pattern.len();
        // SAFETY: d is below s, factored before it on this thread (the same
        // subtree) or before the top began, and written by no one now.
        let ld = unsafe { std::slice::from_raw_parts(shared.0.add(at[d]), d_rows * dw) };
        let first = d_pattern.partition_point(|&r| r < s_start);
        let from = &d_pattern[first..];
        let mid = from.partition_point(|&r| r < s_end);
        for (slot, &row) in work.dest.iter_mut().zip(from) {
            *slot = if row < s_end {
                row - s_start
            } else {
                work.map[row]
            };
        }
        let dest = &work.dest[..from.len()];
        let low =
            MatRef::from_column_major_slice_with_stride(&ld[dw + first..], from.len(), dw, d_rows);
        update(ls, rows, low, dest, mid, &mut work.product, par);
    }
    for &row in s_pattern {
        work.map[row] = NONE;
    }
    let l = MatMut::from_column_major_slice_mut(ls, rows, w);
    let (mut l_top, l_bot) = l.split_at_row_mut(w);
    let stack = MemStack::new(&mut work.chol);
    if let Err(faer::linalg::cholesky::llt::factor::LltError::NonPositivePivot { index }) =
        cholesky_in_place(
            l_top.as_mut(),
            Default::default(),
            par,
            stack,
            Default::default(),
        )
    {
        return Err(index + s_start);
    }
    solve_lower_triangular_in_place(l_top.as_ref(), l_bot.transpose_mut(), par);
    Ok(())
}

/// Subtracts L_low L_mid^T from the block `ls` (`rows` rows, column-major),
/// L_low the rows of a descendant at or below the block's columns and L_mid
/// its first `mid` rows (those in the block's columns): row a of the update
/// goes to row `dest[a]`, column c to column `dest[c]`, the lower part only
/// (a >= c).
fn update(
    ls: &mut [f64],
    rows: usize,
    low: MatRef<'_, f64>,
    dest: &[usize],
    mid: usize,
    product: &mut [f64],
    par: Par,
) {
    let (m, k) = (low.nrows(), low.ncols());
    if m * mid * k <= SMALL {
        for c in 0..mid {
            let col = &mut ls[dest[c] * rows..(dest[c] + 1) * rows];
            for a in c..m {
                let mut sum = 0.0;
                for q in 0..k {
                    sum += low[(a, q)] * low[(c, q)];
                }
                col[dest[a]] -= sum;
            }
        }
        return;
    }
    for b0 in (0..mid).step_by(CHUNK) {
        let b1 = (b0 + CHUNK).min(mid);
        let (h, wc) = (m - b0, b1 - b0);
        let mut t = MatMut::from_column_major_slice_mut(&mut product[..h * wc], h, wc);
        matmul(
            t.as_mut(),
            Accum::Replace,
            low.subrows(b0, h),
            low.subrows(b0, wc).transpose(),
            1.0,
            par,
        );
        for c in 0..wc {
            let col = &mut ls[dest[b0 + c] * rows..(dest[b0 + c] + 1) * rows];
            let t = &product[c * h..(c + 1) * h];
            for (&to, &v) in dest[b0 + c..b0 + h].iter().zip(&t[c..]) {
                col[to] -= v;
            }
        }
    }
}
