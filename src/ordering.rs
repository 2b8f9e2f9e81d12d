//! The fill-reducing ordering of K with a fixed set of DOFs (the contact DOFs)
//! ordered last, so that the trailing block of the Cholesky factor condenses K onto
//! them.
//!
//! AMD on the other DOFs alone does not see the fixed DOFs: the DOFs next to them
//! look cheap (their degree in the reduced graph is small), so AMD eliminates them
//! early, and each such elimination fills rows of the fixed DOFs that stay until the
//! end. Instead AMD runs on the whole graph of K with the fixed DOFs joined to each
//! other (a clique, or a band of `2 * BAND` neighbours when there are many): their
//! degree is then too high for AMD to pick them before the end, and the degrees of
//! the other DOFs count the fixed DOFs their eliminations touch. The fixed DOFs are
//! then moved to the end.
//!
//! AMD runs on the compressed graph: DOFs whose columns of K have the same pattern
//! (the d DOFs of a finite element node) are one vertex, so the graph has about
//! 1/d^2 of K's entries, and a clique among the contact nodes is affordable.
//!
//! The other ordering is nested dissection (METIS_NodeND, METIS 5 built from the
//! sources vendored by the `metis-sys` crate) on the same compressed graph without
//! the fixed vertices, which are then appended: the ordering of the field's direct
//! solvers for 3D meshes, where it needs a fraction of AMD's flops. `factor`
//! chooses between the two by the flop counts of their symbolic factors.
//!
//! Both orderings work on the pattern of K + K^T, never on K's stored pattern
//! alone: a FE code's K may store an entry on one side only (its mirror
//! cancelled to an exact zero in the assembly and was dropped), and METIS
//! corrupts its heap on a graph that is not symmetric. The graph handed to
//! METIS is checked (symmetric, no self-loop, indices in range) before the
//! call.
//!
//! The measurements behind these choices are in BENCHMARKS.md ("Tuning
//! measurements").

use crate::sparse::Csc;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::amd;
use metis_sys::idx_t;

const NONE: usize = usize::MAX;

/// METIS keeps its random number generator in a global (GKlib's `mt` array, not
/// thread-local) and seeds it at the start of every call: two calls at once from
/// different threads would race on it and give orderings that depend on timing.
/// One call at a time, so that every call is reproducible.
static METIS_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Up to this many fixed vertices (in the compressed graph) are joined into a
/// clique; beyond, each is joined to the `BAND` fixed vertices before it and the
/// `BAND` after it (in the order of `last`).
const CLIQUE_MAX: usize = 4096;
const BAND: usize = 1024;

/// The vertices of the compressed graph: `group[j]` of each DOF j, with the DOFs of
/// each group listed in `members[start[g]..start[g + 1]]` (increasing). Two DOFs are
/// in one group when their columns of K, each with its own diagonal added, have the
/// same pattern and both or neither are fixed.
struct Groups {
    group: Vec<usize>,
    start: Vec<usize>,
    members: Vec<usize>,
}

/// The pattern of column j of K with j itself added (K's rows are sorted).
fn closed_pattern(k: &Csc, j: usize) -> impl Iterator<Item = usize> + '_ {
    let rows = &k.row_idx[k.col_ptr[j]..k.col_ptr[j + 1]];
    let at = rows.partition_point(|&r| r < j);
    let own = (rows.get(at) != Some(&j)).then_some(j);
    rows[..at]
        .iter()
        .copied()
        .chain(own)
        .chain(rows[at..].iter().copied())
}

/// The groups of DOFs of `k` (see [`Groups`]), `fixed` flagging the DOFs ordered
/// last. None when an allocation fails.
fn compress(k: &Csc, fixed: &[bool]) -> Option<Groups> {
    let n = k.nrows;
    // A DOF whose column equals the one before it (the usual numbering of the d
    // DOFs of a node) joins that DOF's group; the others (the leads) are grouped by
    // a hash of their pattern, then by comparing patterns within equal hashes.
    let same_as_before = |j: usize| {
        j > 0 && fixed[j] == fixed[j - 1] && closed_pattern(k, j).eq(closed_pattern(k, j - 1))
    };
    let mut key = Vec::new();
    key.try_reserve_exact(n).ok()?;
    for (j, &fj) in fixed.iter().enumerate() {
        if !same_as_before(j) {
            let h = closed_pattern(k, j).fold(0xcbf2_9ce4_8422_2325u64, |h, r| {
                (h ^ r as u64).wrapping_mul(0x0000_0100_0000_01b3)
            });
            key.push((h, fj, j));
        }
    }
    key.sort_unstable();
    // lead_of[j]: the first lead of j's group (usize::MAX until known).
    let mut lead_of = vec![usize::MAX; n];
    let mut q = 0;
    while q < key.len() {
        let mut r = q + 1;
        while r < key.len() && key[r].0 == key[q].0 && key[r].1 == key[q].1 {
            r += 1;
        }
        let run = &mut key[q..r];
        run.sort_unstable_by_key(|e| e.2);
        for a in 0..run.len() {
            let ja = run[a].2;
            if lead_of[ja] != usize::MAX {
                continue;
            }
            lead_of[ja] = ja;
            for e in &run[a + 1..] {
                if lead_of[e.2] == usize::MAX && closed_pattern(k, e.2).eq(closed_pattern(k, ja)) {
                    lead_of[e.2] = ja;
                }
            }
        }
        q = r;
    }
    // Number the groups in the order of their first DOF: AMD breaks ties by the
    // input order, and K's own numbering is usually local (hash order is not).
    let mut group = vec![usize::MAX; n];
    let mut size = Vec::new();
    for j in 0..n {
        let lead = if lead_of[j] == usize::MAX {
            group[j] = group[j - 1];
            size[group[j]] += 1;
            continue;
        } else {
            lead_of[j]
        };
        if lead == j {
            group[j] = size.len();
            size.push(1);
        } else {
            group[j] = group[lead];
            size[group[j]] += 1;
        }
    }
    let ng = size.len();
    let mut start = vec![0usize; ng + 1];
    for g in 0..ng {
        start[g + 1] = start[g] + size[g];
    }
    let mut fill = start.clone();
    let mut members = vec![0usize; n];
    for (j, &g) in group.iter().enumerate() {
        members[fill[g]] = j;
        fill[g] += 1;
    }
    Some(Groups {
        group,
        start,
        members,
    })
}

/// The permutation (forward: new -> old, inverse: old -> new) that orders the DOFs
/// outside `last` by AMD (on K's compressed graph with the fixed DOFs present, see
/// the module documentation), then `last` in its given order. `k` stores both
/// triangles and `last` holds distinct DOFs in range. None when AMD runs out of
/// memory.
pub fn amd_with_last(k: &Csc, last: &[usize]) -> Option<(Vec<usize>, Vec<usize>)> {
    let k = symmetric_pattern(k)?;
    let k = &*k;
    let (_, groups) = compress_with_fixed(k, last)?;
    let ng = groups.start.len() - 1;
    // The fixed vertices, in the order of their first DOF in `last`.
    let mut seen = vec![false; ng];
    let mut fixed_groups = Vec::new();
    for &j in last {
        let g = groups.group[j];
        if !seen[g] {
            seen[g] = true;
            fixed_groups.push(g);
        }
    }
    let mut pos = vec![NONE; ng];
    for (q, &g) in fixed_groups.iter().enumerate() {
        pos[g] = q;
    }
    let nf = fixed_groups.len();
    let band = if nf <= CLIQUE_MAX { nf } else { BAND };
    let mut col_ptr = Vec::new();
    col_ptr.try_reserve_exact(ng + 1).ok()?;
    col_ptr.push(0);
    let mut row_idx: Vec<usize> = Vec::new();
    let mut col: Vec<usize> = Vec::new();
    for (g, &q) in pos.iter().enumerate() {
        let j = groups.members[groups.start[g]];
        col.clear();
        col.extend(closed_pattern(k, j).map(|r| groups.group[r]));
        if q != NONE {
            col.extend_from_slice(&fixed_groups[q.saturating_sub(band)..(q + band + 1).min(nf)]);
        }
        col.sort_unstable();
        col.dedup();
        // AMD wants each row once and ignores the diagonal.
        row_idx.try_reserve(col.len()).ok()?;
        row_idx.extend(col.iter().copied().filter(|&r| r != g));
        col_ptr.push(row_idx.len());
    }
    let mut perm = vec![0usize; ng];
    let mut perm_inv = vec![0usize; ng];
    let mut mem = MemBuffer::try_new(amd::order_scratch::<usize>(ng, row_idx.len())).ok()?;
    amd::order(
        &mut perm,
        &mut perm_inv,
        SymbolicSparseColMatRef::new_checked(ng, ng, &col_ptr, None, &row_idx),
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .ok()?;
    drop(mem);
    expand(&groups, perm.into_iter().filter(|&g| pos[g] == NONE), last)
}

/// The permutation (forward: new -> old, inverse: old -> new) that orders the DOFs
/// outside `last` by METIS_NodeND on the compressed graph of K without the fixed
/// DOFs (vertex weights: the DOFs per vertex), then `last` in its given order. `k`
/// is square with sorted rows (its pattern is taken as that of K + K^T) and
/// `last` holds distinct DOFs in range. None when an allocation fails, the graph
/// does not fit METIS's 32-bit indices, fails the check of [`valid_graph`] (a
/// bug: METIS is then not called), or METIS reports an error.
pub fn metis_with_last(k: &Csc, last: &[usize]) -> Option<(Vec<usize>, Vec<usize>)> {
    let k = symmetric_pattern(k)?;
    let k = &*k;
    let (fixed, groups) = compress_with_fixed(k, last)?;
    let ng = groups.start.len() - 1;
    // The free groups, numbered 0..nv in the order of their first DOF.
    let mut vertex = vec![NONE; ng];
    let mut free = Vec::new();
    for g in 0..ng {
        if !fixed[groups.members[groups.start[g]]] {
            vertex[g] = free.len();
            free.push(g);
        }
    }
    let nv = free.len();
    let idx = |v: usize| idx_t::try_from(v).ok();
    let mut xadj: Vec<idx_t> = Vec::new();
    xadj.try_reserve_exact(nv + 1).ok()?;
    xadj.push(0);
    let mut adjncy: Vec<idx_t> = Vec::new();
    let mut vwgt: Vec<idx_t> = Vec::new();
    vwgt.try_reserve_exact(nv).ok()?;
    let mut col: Vec<usize> = Vec::new();
    for &g in &free {
        let j = groups.members[groups.start[g]];
        col.clear();
        col.extend(
            closed_pattern(k, j)
                .map(|r| groups.group[r])
                .filter(|&h| h != g && vertex[h] != NONE)
                .map(|h| vertex[h]),
        );
        col.sort_unstable();
        col.dedup();
        adjncy.try_reserve(col.len()).ok()?;
        for &v in &col {
            adjncy.push(idx(v)?);
        }
        xadj.push(idx(adjncy.len())?);
        vwgt.push(idx(groups.start[g + 1] - groups.start[g])?);
    }
    let order = node_nd(nv, &mut xadj, &mut adjncy, &mut vwgt)?;
    drop((xadj, adjncy, vwgt));
    expand(&groups, order.into_iter().map(|v| free[v]), last)
}

/// `k` itself when its pattern is symmetric, else the pattern of K + K^T
/// (values zero: only the pattern is read here). None when an allocation
/// fails. The check takes one pass and no copy ([`Csc::mirror_pairs`]);
/// [`crate::factor`] calls it once per analysis, so that both orderings find
/// a symmetric pattern and use it as it is.
pub(crate) fn symmetric_pattern(k: &Csc) -> Option<std::borrow::Cow<'_, Csc>> {
    use std::borrow::Cow;
    if k.mirror_pairs(|_, _, upper, lower| upper.is_some() && lower.is_some())
        .ok()?
    {
        return Some(Cow::Borrowed(k));
    }
    // One-sided entries (rare): their mirrors from the transpose.
    let kt = k.try_transpose().ok()?;
    let n = k.ncols;
    let mut col_ptr = Vec::new();
    col_ptr.try_reserve_exact(n + 1).ok()?;
    col_ptr.push(0);
    let mut row_idx = Vec::new();
    row_idx.try_reserve(k.nnz() + k.nnz() / 8).ok()?;
    for j in 0..n {
        let a = &k.row_idx[k.col_ptr[j]..k.col_ptr[j + 1]];
        let b = &kt.row_idx[kt.col_ptr[j]..kt.col_ptr[j + 1]];
        let (mut p, mut q) = (0, 0);
        while p < a.len() || q < b.len() {
            let r = match (a.get(p), b.get(q)) {
                (Some(&x), Some(&y)) if x == y => {
                    p += 1;
                    q += 1;
                    x
                }
                (Some(&x), Some(&y)) if x < y => {
                    p += 1;
                    x
                }
                (Some(&x), None) => {
                    p += 1;
                    x
                }
                (_, Some(&y)) => {
                    q += 1;
                    y
                }
                (None, None) => unreachable!("the loop runs while one list has entries"),
            };
            row_idx.try_reserve(1).ok()?;
            row_idx.push(r);
        }
        col_ptr.push(row_idx.len());
    }
    drop(kt);
    let mut values = Vec::new();
    values.try_reserve_exact(row_idx.len()).ok()?;
    values.resize(row_idx.len(), 0.0);
    Some(Cow::Owned(Csc {
        nrows: n,
        ncols: n,
        col_ptr,
        row_idx,
        values,
    }))
}

/// Whether (`xadj`, `adjncy`) is a graph METIS_NodeND accepts: `nv + 1`
/// non-decreasing pointers from 0 to `adjncy.len()`, each list sorted without
/// repeats, every neighbour in range and not the vertex itself, and every edge
/// present in both directions. METIS checks none of this and corrupts its heap
/// on an asymmetric graph.
fn valid_graph(nv: usize, xadj: &[idx_t], adjncy: &[idx_t]) -> bool {
    let at = |v: usize| usize::try_from(xadj[v]).ok();
    if xadj.len() != nv + 1 || at(0) != Some(0) || at(nv) != Some(adjncy.len()) {
        return false;
    }
    let list = |v: usize| -> Option<&[idx_t]> { adjncy.get(at(v)?..at(v + 1)?) };
    for v in 0..nv {
        let Some(adj) = list(v) else {
            return false;
        };
        let mut prev: Option<usize> = None;
        for &w in adj {
            let Some(w) = usize::try_from(w).ok().filter(|&w| w < nv && w != v) else {
                return false;
            };
            if prev.is_some_and(|p| p >= w) {
                return false;
            }
            prev = Some(w);
            // The mirror edge (w, v): w's list is sorted (checked when w's turn
            // comes; an unsorted one fails there).
            let mirrored = list(w).is_some_and(|l| l.binary_search(&(v as idx_t)).is_ok());
            if !mirrored {
                return false;
            }
        }
    }
    true
}

/// The flags of the DOFs in `last` (distinct, in range) and the groups of `k`
/// with them fixed (see [`compress`]). None when an allocation fails.
fn compress_with_fixed(k: &Csc, last: &[usize]) -> Option<(Vec<bool>, Groups)> {
    let mut fixed = vec![false; k.nrows];
    for &j in last {
        fixed[j] = true;
    }
    let groups = compress(k, &fixed)?;
    Some((fixed, groups))
}

/// The permutation (forward: new -> old, inverse: old -> new) that takes the DOFs
/// of the free groups in `order`, then `last` in its given order. None when an
/// allocation fails.
fn expand(
    groups: &Groups,
    order: impl Iterator<Item = usize>,
    last: &[usize],
) -> Option<(Vec<usize>, Vec<usize>)> {
    let n = groups.group.len();
    let mut fwd = Vec::new();
    fwd.try_reserve_exact(n).ok()?;
    for g in order {
        fwd.extend_from_slice(&groups.members[groups.start[g]..groups.start[g + 1]]);
    }
    fwd.extend_from_slice(last);
    debug_assert_eq!(fwd.len(), n);
    let mut inv = vec![0usize; n];
    for (new, &old) in fwd.iter().enumerate() {
        inv[old] = new;
    }
    Some((fwd, inv))
}

/// METIS_NodeND on the graph (`xadj`, `adjncy`, `vwgt`) of `nv` vertices: the
/// vertices in elimination order (new -> old). Graphs of up to two vertices need
/// no ordering (and METIS wants at least one).
fn node_nd(
    nv: usize,
    xadj: &mut [idx_t],
    adjncy: &mut [idx_t],
    vwgt: &mut [idx_t],
) -> Option<Vec<usize>> {
    if nv <= 2 {
        return Some((0..nv).collect());
    }
    if !valid_graph(nv, xadj, adjncy) {
        return None;
    }
    let mut nvtxs = idx_t::try_from(nv).ok()?;
    let mut options = [0 as idx_t; metis_sys::METIS_NOPTIONS as usize];
    // SAFETY: `options` has METIS_NOPTIONS entries, all that METIS_SetDefaultOptions writes.
    unsafe { metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr()) };
    options[metis_sys::moptions_et_METIS_OPTION_NUMBERING as usize] = 0;
    let mut perm = vec![0 as idx_t; nv];
    let mut iperm = vec![0 as idx_t; nv];
    // A panic cannot happen while the lock is held (only the C call runs), so a
    // poisoned lock still guards nothing broken.
    let _one_at_a_time = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: xadj has nv + 1 entries, adjncy xadj[nv] (its length), vwgt, perm and
    // iperm nv: the sizes METIS_NodeND reads and writes for nvtxs = nv; every index
    // in adjncy is below nv, and METIS keeps no pointer after it returns.
    let status = unsafe {
        metis_sys::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            vwgt.as_mut_ptr(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return None;
    }
    // perm[new] = old (METIS manual: row i of the permuted matrix is row perm[i]).
    let order: Option<Vec<usize>> = perm
        .iter()
        .map(|&v| usize::try_from(v).ok().filter(|&v| v < nv))
        .collect();
    let order = order?;
    // A permutation, or nothing (never trust an index from C blindly).
    let mut seen = vec![false; nv];
    for &v in &order {
        if std::mem::replace(&mut seen[v], true) {
            return None;
        }
    }
    Some(order)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2D grid Laplacian (5-point), nx x ny nodes, one DOF each.
    fn grid(nx: usize, ny: usize) -> Csc {
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

    #[test]
    fn the_fixed_dofs_come_last_in_their_order_and_the_rest_is_a_permutation() {
        let k = grid(30, 8);
        // The bottom row, in reverse order, plus a DOF repeated by K's pattern.
        let last: Vec<usize> = (0..30).rev().collect();
        let (fwd, inv) = amd_with_last(&k, &last).unwrap();
        assert_eq!(&fwd[fwd.len() - 30..], &last[..]);
        let mut seen = vec![false; k.nrows];
        for (new, &old) in fwd.iter().enumerate() {
            assert!(!seen[old]);
            seen[old] = true;
            assert_eq!(inv[old], new);
        }
        // Nothing fixed: plain AMD on K.
        let (fwd0, _) = amd_with_last(&k, &[]).unwrap();
        assert_eq!(fwd0.len(), k.nrows);
    }

    /// The grid with two DOFs per node, coupled like the node's neighbours: DOF
    /// (node q, component s) is `2 q + s` node-wise, `q + nodes * s` component-wise.
    fn two_dofs(nx: usize, ny: usize, node_wise: bool) -> Csc {
        let g = grid(nx, ny);
        let nodes = nx * ny;
        let dof = |q: usize, s: usize| if node_wise { 2 * q + s } else { q + nodes * s };
        let mut t = Vec::new();
        for j in 0..nodes {
            for p in g.col_ptr[j]..g.col_ptr[j + 1] {
                let i = g.row_idx[p];
                for (si, sj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    let v = if i == j && si == sj {
                        8.2
                    } else {
                        g.values[p] * 0.5
                    };
                    t.push((dof(i, si), dof(j, sj), v));
                }
            }
        }
        Csc::from_triplets(2 * nodes, 2 * nodes, &t)
    }

    #[test]
    fn metis_orders_every_dof_once_with_the_fixed_ones_last_and_repeats_itself() {
        let k = two_dofs(30, 12, true);
        let last: Vec<usize> = (0..60).rev().collect();
        let (fwd, inv) = metis_with_last(&k, &last).unwrap();
        assert_eq!(&fwd[fwd.len() - 60..], &last[..]);
        let mut seen = vec![false; k.nrows];
        for (new, &old) in fwd.iter().enumerate() {
            assert!(!std::mem::replace(&mut seen[old], true));
            assert_eq!(inv[old], new);
        }
        // The two DOFs of a node stay together (one vertex of the graph).
        for pair in fwd[..fwd.len() - 60].chunks(2) {
            assert_eq!(pair[0] / 2, pair[1] / 2);
        }
        // Calls from several threads at once give the same ordering (METIS's
        // random state is global; the calls are serialised).
        let runs: Vec<Vec<usize>> = std::thread::scope(|s| {
            let hs: Vec<_> = (0..4)
                .map(|_| s.spawn(|| metis_with_last(&k, &last).unwrap().0))
                .collect();
            hs.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(runs.iter().all(|r| *r == fwd));
        // Tiny graphs (no free vertex, one, two) need no METIS call.
        let k1 = grid(1, 2);
        assert_eq!(metis_with_last(&k1, &[]).unwrap().0, vec![0, 1]);
        assert_eq!(metis_with_last(&k1, &[1, 0]).unwrap().0, vec![1, 0]);
    }

    /// `k` with about a third of its off-diagonal pairs stored on one side
    /// only (the side chosen by a hash of the pair), as a FE code writes K
    /// when a mirror cancels to an exact zero and is dropped.
    fn one_sided(k: &Csc) -> Csc {
        let mut t = Vec::new();
        for j in 0..k.ncols {
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                let i = k.row_idx[p];
                let (a, b) = (i.min(j), i.max(j));
                let h = ((a * 7919 + b * 104_729) as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
                let drop = i != j && h.is_multiple_of(3) && (h / 3) % 2 == u64::from(i < j);
                if !drop {
                    t.push((i, j, k.values[p]));
                }
            }
        }
        Csc::from_triplets(k.nrows, k.ncols, &t)
    }

    #[test]
    fn a_pattern_stored_on_one_side_orders_as_its_symmetric_whole() {
        let k = two_dofs(30, 12, true);
        let lop = one_sided(&k);
        assert!(
            lop.nnz() < k.nnz() * 9 / 10,
            "entries dropped: {}",
            k.nnz() - lop.nnz()
        );
        assert_ne!(lop.try_transpose().unwrap().row_idx, lop.row_idx);
        let sym = symmetric_pattern(&lop).unwrap();
        assert_eq!((&sym.col_ptr, &sym.row_idx), (&k.col_ptr, &k.row_idx));
        let last: Vec<usize> = (0..60).rev().collect();
        // METIS is called (a graph it would refuse gives None) on the graph of
        // K + K^T, which is the symmetric K's: the same orderings.
        let ordered = |o: Option<(Vec<usize>, Vec<usize>)>| o.expect("an ordering");
        assert_eq!(
            ordered(metis_with_last(&lop, &last)),
            ordered(metis_with_last(&k, &last))
        );
        assert_eq!(
            ordered(amd_with_last(&lop, &last)),
            ordered(amd_with_last(&k, &last))
        );
        // A symmetric pattern is used as it is.
        assert!(matches!(
            symmetric_pattern(&k).unwrap(),
            std::borrow::Cow::Borrowed(_)
        ));
    }

    #[test]
    fn graphs_without_edges_stars_and_pieces_are_ordered() {
        let n = 40;
        let diagonal = Csc::from_triplets(n, n, &(0..n).map(|i| (i, i, 1.0)).collect::<Vec<_>>());
        let mut star: Vec<(usize, usize, f64)> = (0..n).map(|i| (i, i, 50.0)).collect();
        for i in 1..n {
            star.extend([(0, i, -1.0), (i, 0, -1.0)]);
        }
        let star = Csc::from_triplets(n, n, &star);
        // Two grids side by side, not connected.
        let g = grid(6, 5);
        let mut pieces = Vec::new();
        for j in 0..g.ncols {
            for p in g.col_ptr[j]..g.col_ptr[j + 1] {
                pieces.push((g.row_idx[p], j, g.values[p]));
                pieces.push((g.row_idx[p] + 30, j + 30, g.values[p]));
            }
        }
        let pieces = Csc::from_triplets(60, 60, &pieces);
        for (name, k) in [("diagonal", diagonal), ("star", star), ("pieces", pieces)] {
            for last in [vec![], vec![3, 1]] {
                for (fwd, inv) in [
                    metis_with_last(&k, &last).expect(name),
                    amd_with_last(&k, &last).expect(name),
                ] {
                    assert_eq!(&fwd[fwd.len() - last.len()..], &last[..], "{name}");
                    for (new, &old) in fwd.iter().enumerate() {
                        assert_eq!(inv[old], new, "{name}");
                    }
                }
            }
        }
    }

    /// Whether `k`'s pattern is symmetric, as `symmetric_pattern` decides.
    fn symmetric(k: &Csc) -> Option<bool> {
        symmetric_pattern(k).map(|p| matches!(p, std::borrow::Cow::Borrowed(_)))
    }

    #[test]
    fn the_pattern_check_finds_every_one_sided_entry() {
        let k = two_dofs(9, 4, true);
        assert_eq!(symmetric(&k), Some(true));
        assert_eq!(symmetric(&one_sided(&k)), Some(false));
        // One entry above the diagonal only, one below only, in the last column.
        let n = k.ncols;
        for (r, c) in [(0, n - 1), (n - 1, 0), (3, 40)] {
            let mut t: Vec<(usize, usize, f64)> = (0..n).map(|i| (i, i, 1.0)).collect();
            t.push((r, c, 1e-18));
            let lop = Csc::from_triplets(n, n, &t);
            assert_eq!(symmetric(&lop), Some(false), "({r}, {c})");
            t.push((c, r, 0.0));
            let sym = Csc::from_triplets(n, n, &t);
            assert_eq!(symmetric(&sym), Some(true), "({r}, {c})");
        }
    }

    #[test]
    fn only_a_symmetric_simple_graph_reaches_metis() {
        // 0 - 1 - 2, sorted lists.
        let xadj = [0, 1, 3, 4];
        assert!(valid_graph(3, &xadj, &[1, 0, 2, 1]));
        // Asymmetric (2 lists 0, 0 does not list 2).
        assert!(!valid_graph(3, &[0, 1, 3, 5], &[1, 0, 2, 0, 1]));
        // A self-loop, an index out of range, a repeat, unsorted, bad pointers.
        assert!(!valid_graph(3, &xadj, &[1, 0, 1, 1]));
        assert!(!valid_graph(3, &xadj, &[1, 0, 3, 1]));
        assert!(!valid_graph(3, &[0, 1, 3, 4], &[1, 2, 2, 1]));
        assert!(!valid_graph(3, &[0, 1, 3, 4], &[1, 2, 0, 1]));
        assert!(!valid_graph(3, &[0, 3, 1, 4], &[1, 0, 2, 1]));
        assert!(!valid_graph(3, &[0, 1, 3], &[1, 0, 2]));
        assert!(!valid_graph(3, &[0, 1, 5, 4], &[1, 0, 2, 1]));
        // node_nd refuses it rather than calling METIS.
        let (mut x, mut a, mut w) = (vec![0, 1, 3, 5], vec![1, 0, 2, 0, 1], vec![1; 3]);
        assert!(node_nd(3, &mut x, &mut a, &mut w).is_none());
    }

    #[test]
    fn the_dofs_of_a_node_are_one_vertex_whatever_their_numbering() {
        let fixed = vec![false; 2 * 12 * 5];
        for node_wise in [true, false] {
            let k = two_dofs(12, 5, node_wise);
            let groups = compress(&k, &fixed).unwrap();
            assert_eq!(groups.start.len() - 1, 12 * 5);
            for g in 0..12 * 5 {
                let m = &groups.members[groups.start[g]..groups.start[g + 1]];
                let expect = if node_wise {
                    [2 * g, 2 * g + 1]
                } else {
                    [g, g + 60]
                };
                assert_eq!(m, expect);
                assert!(m.iter().all(|&j| groups.group[j] == g));
            }
        }
        // A fixed DOF is never in the group of a free one, even with equal columns.
        let k = two_dofs(12, 5, true);
        let mut fixed = fixed;
        fixed[6] = true;
        let groups = compress(&k, &fixed).unwrap();
        assert_eq!(groups.start.len() - 1, 12 * 5 + 1);
        assert_ne!(groups.group[6], groups.group[7]);
    }

    #[test]
    fn the_ordering_does_not_depend_on_how_the_dofs_of_a_node_are_numbered() {
        use crate::factor::Factor;
        let (nx, ny) = (40, 9);
        let nodes = nx * ny;
        let mut sizes = Vec::new();
        for node_wise in [true, false] {
            let k = two_dofs(nx, ny, node_wise);
            // The bottom row of nodes, both components, ordered last.
            let last: Vec<usize> = (0..nx)
                .flat_map(|q| {
                    if node_wise {
                        [2 * q, 2 * q + 1]
                    } else {
                        [q, q + nodes]
                    }
                })
                .collect();
            let (fwd, _) = amd_with_last(&k, &last).unwrap();
            assert_eq!(&fwd[fwd.len() - last.len()..], &last[..]);
            let f = Factor::with_last(
                &k,
                &last,
                crate::Ordering::Auto,
                std::sync::Arc::new(crate::threads::Threads::sequential()),
            )
            .unwrap();
            sizes.push(f.nnz_and_flops());
        }
        assert_eq!(sizes[0], sizes[1]);
    }
}
