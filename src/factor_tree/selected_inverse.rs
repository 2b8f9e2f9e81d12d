//! Selected entries of K^-1 from K's supernodal Cholesky factor (Takahashi's
//! recurrence), without any solve with a right-hand side.
//!
//! With L L^T = P K P^T and Z = (P K P^T)^-1, take a supernode s of width w, its
//! diagonal block L_ss and the r rows R below it (L_Rs). Then, with
//! U = L_Rs L_ss^-1 (r x w),
//!
//!   Z_Rs = -Z_RR U,    Z_ss = L_ss^-T L_ss^-1 - U^T Z_Rs,
//!
//! and Z_RR lies on the supernodal pattern of s's ancestors. So Z on the pattern
//! of L is computed from the root down, each supernode after its ancestors, and
//! only on the ancestors of the supernodes whose entries are asked for: Z_s is
//! kept while its subtree is visited (depth first) and dropped after, so the
//! memory is that of one path to the root per thread, not of L.
//!
//! An entry (i, j) of Z is on that pattern when j's supernode holds i among its
//! columns or rows below (i >= j); entries of two different trees of the forest
//! (components of K's graph) are zero. Others are not computed here.
//!
//! Work: about 2 r^2 w + 2 r w^2 + 2/3 w^3 flops per supernode on those paths,
//! close to twice the factorisation's on them; the top separators, which every
//! path crosses, are handled once (a forward solve per right-hand side pays w^2
//! for each column that crosses them).
//!
//! Every large product is a plain dense one, where the dense kernels run
//! fastest: L_ss^-1 is formed first (Z_ss needs it) and U taken as the product
//! L_Rs L_ss^-1 (2 r w^2 flops where a triangular solve takes r w^2; the cost
//! model above counts the recurrence's own r w^2), and Z_RR is gathered whole
//! (both triangles, mirrored by tiles) into one scratch buffer, reused from
//! supernode to supernode (one for the top, one per subtree visit), so that
//! Z_Rs is a single product. On the benchmark's 3d-64x64x6 (single precision,
//! 1 thread) that took the recurrence from 0.83 s to 0.63 s against two
//! triangular products on Z_RR's lower triangle, a triangular solve for U and
//! a fresh Z_RR per supernode.

use crate::factor::Factor;
use crate::factor_tree::supernode_tree::Tree;
use faer::linalg::matmul::matmul;
use faer::linalg::matmul::triangular::{BlockStructure, matmul as tri_matmul};
use faer::linalg::triangular_inverse::invert_lower_triangular;
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

/// Selections with fewer flops run on the calling thread.
const PARALLEL_MIN_FLOPS: f64 = 1e8;

/// Where an entry of Z is held, or why it is not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Place {
    /// In supernode `s`'s block of Z ((w + r) x w): `row` among its w columns
    /// then its r rows below, `col` among its columns.
    At { s: usize, row: usize, col: usize },
    /// Zero: the two indices lie in different components of K.
    Zero,
    /// Not on the factor's pattern: not computed here.
    Outside,
}

/// Where Z(i, j) is held (factor's column order; symmetric, so (j, i) too).
pub(crate) fn place(factor: &Factor, tree: &Tree, i: usize, j: usize) -> Place {
    let (lo, hi) = (i.min(j), i.max(j));
    let s = tree.of_col[lo];
    let (b, w) = (tree.begin[s], tree.width[s]);
    let col = lo - b;
    if hi < b + w {
        return Place::At {
            s,
            row: hi - b,
            col,
        };
    }
    let pattern = factor.supernodal_symbolic().supernode(s).pattern();
    match pattern.binary_search(&hi) {
        Ok(p) => Place::At { s, row: w + p, col },
        Err(_) if tree.root[s] != tree.root[tree.of_col[hi]] => Place::Zero,
        Err(_) => Place::Outside,
    }
}

/// One asked-for term: `coef` Z(place) is added to output `slot`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Term {
    pub slot: usize,
    pub s: usize,
    pub row: usize,
    pub col: usize,
    pub coef: f64,
}

/// The supernodes to visit for a set of terms (their own and all ancestors),
/// the terms by supernode, and how the visit is split between threads.
pub(crate) struct Selection {
    /// Per supernode, its terms: `terms[first[s]..first[s + 1]]`.
    first: Vec<usize>,
    terms: Vec<Term>,
    /// Per supernode, whether it is visited, and its visited children.
    needed: Vec<bool>,
    children: Vec<Vec<usize>>,
    /// The visited roots.
    roots: Vec<usize>,
    /// Flops per visited supernode (0 for the others).
    flops: Vec<f64>,
}

/// Flops of one supernode of width w with r rows below.
fn node_flops(w: usize, r: usize) -> f64 {
    let (w, r) = (w as f64, r as f64);
    2.0 * r * r * w + 2.0 * r * w * w + 2.0 / 3.0 * w * w * w
}

impl Selection {
    /// The visit for `terms` (every place `At`).
    pub(crate) fn new(factor: &Factor, tree: &Tree, mut terms: Vec<Term>) -> Selection {
        let ns = tree.len();
        terms.sort_unstable_by_key(|t| t.s);
        let mut first = vec![0usize; ns + 1];
        for t in &terms {
            first[t.s + 1] += 1;
        }
        for s in 0..ns {
            first[s + 1] += first[s];
        }
        let needed = tree.on_paths(terms.iter().map(|t| t.s));
        let sym = factor.supernodal_symbolic();
        let mut children = vec![Vec::new(); ns];
        let mut roots = Vec::new();
        let mut flops = vec![0.0; ns];
        for s in (0..ns).filter(|&s| needed[s]) {
            flops[s] = node_flops(tree.width[s], sym.supernode(s).pattern().len());
            match tree.parent[s] {
                usize::MAX => roots.push(s),
                p => children[p].push(s),
            }
        }
        Selection {
            first,
            terms,
            needed,
            children,
            roots,
            flops,
        }
    }

    /// Flops of [`Selection::sums`].
    pub(crate) fn flops(&self) -> f64 {
        self.flops.iter().sum()
    }

    /// Per visited supernode, the flops of its subtree (0 for the others).
    fn subtree_flops(&self) -> Vec<f64> {
        let mut sub = self.flops.clone();
        for s in 0..sub.len() {
            for &ch in &self.children[s] {
                sub[s] += sub[ch];
            }
        }
        sub
    }

    /// The split between threads: the top supernodes, visited one after the other
    /// (each with all threads in its dense kernels), and the subtrees below them,
    /// visited in parallel, one thread each. With one thread: no top, the whole
    /// forest as subtrees.
    fn split(&self, threads: usize) -> (Vec<usize>, Vec<usize>) {
        let (mut top, tasks) = if threads > 1 {
            let sub = self.subtree_flops();
            let limit = self.flops() / (4 * threads) as f64;
            crate::tree_cholesky::split_top(|s| sub[s], &self.children, self.roots.clone(), limit)
        } else {
            (Vec::new(), self.roots.clone())
        };
        top.sort_unstable_by(|a, b| b.cmp(a));
        (top, tasks)
    }

    /// Bytes [`Selection::sums`] works in: the terms, the top's blocks of Z, and
    /// per thread (the top's scratch is dropped before the subtrees are
    /// visited) the blocks along the deepest path of a subtree with one
    /// supernode's U (twice over: room for the dense kernels' packing) and
    /// L_ss^-1, and the Z_RR scratch (kept from supernode to
    /// supernode, so as large as the largest r^2).
    pub(crate) fn work_bytes(&self, factor: &Factor, tree: &Tree, threads: usize) -> usize {
        let sym = factor.supernodal_symbolic();
        let ns = tree.len();
        let (top, _) = self.split(threads);
        let mut in_top = vec![false; ns];
        for &s in &top {
            in_top[s] = true;
        }
        let mut path = vec![0usize; ns];
        let (mut top_bytes, mut worst, mut zrr) = (0, 0, 0);
        for s in (0..ns).rev().filter(|&s| self.needed[s]) {
            let (w, r) = (tree.width[s], sym.supernode(s).pattern().len());
            let z = (w + r) * w;
            let scratch = 2 * r * w + w * w;
            zrr = zrr.max(r * r);
            if in_top[s] {
                top_bytes += z;
                worst = worst.max(scratch);
                continue;
            }
            let above = match tree.parent[s] {
                usize::MAX => 0,
                p if in_top[p] => 0,
                p => path[p],
            };
            path[s] = above + z;
            worst = worst.max(path[s] + scratch);
        }
        // The terms, and their values on the way out (slot and value each).
        let terms = self.terms.len() * (std::mem::size_of::<Term>() + 16);
        (top_bytes + threads.max(1) * (worst + zrr)) * std::mem::size_of::<f64>() + terms
    }

    /// Per slot, the sum of its terms' coef Z(place), `nslots` slots; on the
    /// problem's threads when the work is large enough.
    pub(crate) fn sums(&self, factor: &Factor, tree: &Tree, nslots: usize) -> Vec<f64> {
        let llt = factor.supernodal();
        self.sums_with(
            factor,
            &llt,
            tree,
            nslots,
            self.flops() > PARALLEL_MIN_FLOPS,
        )
    }

    /// [`Selection::sums`] from the factor's values in single precision
    /// (`single`: [`Factor::single_values`]), the recurrence run in single
    /// precision throughout: about half the time (twice the flops per cycle in
    /// its dense kernels, half the memory), each entry with a relative error
    /// near 1e-7 times the conditioning of K restricted to the supernodes
    /// visited (see [`crate::factor_tree::contact_blocks`] for what it serves).
    pub(crate) fn sums_single(
        &self,
        factor: &Factor,
        single: &[f32],
        tree: &Tree,
        nslots: usize,
    ) -> Vec<f64> {
        let llt = SupernodalLltRef::<usize, f32>::new(factor.supernodal_symbolic(), single);
        self.sums_with(
            factor,
            &llt,
            tree,
            nslots,
            self.flops() > PARALLEL_MIN_FLOPS,
        )
    }

    /// [`Selection::sums`] on `llt` (the factor's values in the precision T),
    /// on the problem's threads when `parallel`.
    fn sums_with<T: Real>(
        &self,
        factor: &Factor,
        llt: &SupernodalLltRef<'_, usize, T>,
        tree: &Tree,
        nslots: usize,
        parallel: bool,
    ) -> Vec<f64> {
        let threads = factor.threads();
        let parallel = parallel && threads.count() > 1;
        let (top, tasks) = self.split(if parallel { threads.count() } else { 1 });
        let mut out = vec![0.0; nslots];
        let parts: Vec<Vec<(usize, f64)>> = threads.run(parallel, |par| {
            // The top, root first, every block kept for the subtrees.
            let mut held: Vec<Option<Mat<T>>> = (0..tree.len()).map(|_| None).collect();
            let mut top_part = Vec::new();
            {
                // The top's Z_RR scratch, dropped before the subtrees take theirs.
                let mut buf = Vec::new();
                for &s in &top {
                    let z = {
                        let find = |t: usize| held[t].as_ref().expect("ancestor in the top");
                        node_block(llt, tree, s, &find, par, &mut buf)
                    };
                    self.collect(s, &z, &mut top_part);
                    held[s] = Some(z);
                }
            }
            let held = &held;
            let visit = |root: usize| self.visit_subtree(llt, tree, root, held);
            let mut parts: Vec<Vec<(usize, f64)>> = match par {
                Par::Seq => tasks.iter().map(|&t| visit(t)).collect(),
                _ => tasks.par_iter().map(|&t| visit(t)).collect(),
            };
            parts.push(top_part);
            parts
        });
        for (slot, v) in parts.into_iter().flatten() {
            out[slot] += v;
        }
        out
    }

    /// The terms of supernode s from its block z.
    fn collect<T: Real>(&self, s: usize, z: &Mat<T>, out: &mut Vec<(usize, f64)>) {
        for t in &self.terms[self.first[s]..self.first[s + 1]] {
            out.push((t.slot, t.coef * z[(t.row, t.col)].to_f64()));
        }
    }

    /// Visits the subtree of `root` depth first on the calling thread (its
    /// ancestors' blocks in `held`), returning its terms' values.
    fn visit_subtree<T: Real>(
        &self,
        llt: &SupernodalLltRef<'_, usize, T>,
        tree: &Tree,
        root: usize,
        held: &[Option<Mat<T>>],
    ) -> Vec<(usize, f64)> {
        let mut out = Vec::new();
        // The blocks of the current path (supernode, block), root first, and per
        // frame the next child to visit.
        let mut path: Vec<(usize, Mat<T>)> = Vec::new();
        let mut next: Vec<usize> = Vec::new();
        let mut enter = Some(root);
        let mut buf = Vec::new();
        loop {
            if let Some(s) = enter.take() {
                let z = {
                    let find = |t: usize| match &held[t] {
                        Some(z) => z,
                        None => {
                            let at = path.partition_point(|(u, _)| *u > t);
                            debug_assert_eq!(path[at].0, t);
                            &path[at].1
                        }
                    };
                    node_block(llt, tree, s, &find, Par::Seq, &mut buf)
                };
                self.collect(s, &z, &mut out);
                path.push((s, z));
                next.push(0);
            }
            let Some(&(s, _)) = path.last() else { break };
            let k = next.last_mut().expect("one frame per block");
            if let Some(&ch) = self.children[s].get(*k) {
                *k += 1;
                enter = Some(ch);
            } else {
                path.pop();
                next.pop();
            }
        }
        out
    }
}

/// Supernode s's block of Z, (w + r) x w: Z_ss (lower triangle) on top of Z_Rs,
/// from its ancestors' blocks (`find`); `buf`: the scratch Z_RR is gathered
/// into (grown as needed, reused from supernode to supernode).
fn node_block<'z, T: Real>(
    llt: &SupernodalLltRef<'_, usize, T>,
    tree: &Tree,
    s: usize,
    find: &dyn Fn(usize) -> &'z Mat<T>,
    par: Par,
    buf: &mut Vec<T>,
) -> Mat<T> {
    let node = llt.supernode(s);
    let val = node.val();
    let pattern = node.pattern();
    let (w, r) = (val.ncols(), pattern.len());
    let lss = val.submatrix(0, 0, w, w);
    let mut linv = Mat::<T>::zeros(w, w);
    invert_lower_triangular(linv.as_mut(), lss, par);
    // U = L_Rs L_ss^-1 (r x w; linv's upper triangle is zero).
    let mut u = Mat::<T>::zeros(r, w);
    matmul(
        u.as_mut(),
        Accum::Replace,
        val.submatrix(w, 0, r, w),
        linv.as_ref(),
        T::of(1.0),
        par,
    );
    let zrr = gather(llt, tree, pattern, find, buf);
    let mut z = Mat::<T>::zeros(w + r, w);
    let (mut zss, mut zrs) = z.as_mut().split_at_row_mut(w);
    // Z_Rs = -Z_RR U.
    matmul(
        zrs.as_mut(),
        Accum::Replace,
        zrr,
        u.as_ref(),
        T::of(-1.0),
        par,
    );
    tri_matmul(
        zss.as_mut(),
        BlockStructure::TriangularLower,
        Accum::Replace,
        linv.transpose(),
        BlockStructure::TriangularUpper,
        linv.as_ref(),
        BlockStructure::TriangularLower,
        T::of(1.0),
        par,
    );
    tri_matmul(
        zss.as_mut(),
        BlockStructure::TriangularLower,
        Accum::Add,
        u.transpose(),
        BlockStructure::Rectangular,
        zrs.as_ref(),
        BlockStructure::Rectangular,
        T::of(-1.0),
        par,
    );
    z
}

/// Column j of a block of Z as a slice.
fn column<T: Real>(z: MatRef<'_, T>, j: usize) -> &[T] {
    z.col(j).try_as_col_major().expect("contiguous").as_slice()
}

/// Z_RR (r x r, both triangles) for the rows R below a supernode, from the
/// blocks of the ancestors that hold R's columns, gathered into `buf` (grown
/// to r^2 as needed; every entry of the r x r block is written).
fn gather<'z, 'b, T: Real>(
    llt: &SupernodalLltRef<'_, usize, T>,
    tree: &Tree,
    rows: &[usize],
    find: &dyn Fn(usize) -> &'z Mat<T>,
    buf: &'b mut Vec<T>,
) -> MatRef<'b, T> {
    let r = rows.len();
    if buf.len() < r * r {
        buf.resize(r * r, T::of(0.0));
    }
    let zrr = &mut buf[..r * r];
    let mut loc = vec![0usize; r];
    // Per row p, the end of the run of rows from p whose local rows follow
    // each other (copied as one slice).
    let mut run_end = vec![0usize; r];
    let mut q0 = 0;
    while q0 < r {
        let t = tree.of_col[rows[q0]];
        let (b, w) = (tree.begin[t], tree.width[t]);
        let q1 = q0 + rows[q0..].partition_point(|&i| i < b + w);
        let zt: MatRef<'_, T> = find(t).as_ref();
        // Local rows in t's block: R[q0..q1] among its columns, the later rows
        // of R in its pattern (sorted, and holding them all: R and s's columns
        // form a clique of the filled graph).
        for p in q0..q1 {
            loc[p] = rows[p] - b;
        }
        let pattern = llt.supernode(t).pattern();
        let mut at = 0;
        for p in q1..r {
            at += pattern[at..].partition_point(|&i| i < rows[p]);
            debug_assert_eq!(pattern[at], rows[p]);
            loc[p] = w + at;
        }
        run_end[r - 1] = r;
        for p in (q0..r - 1).rev() {
            run_end[p] = if loc[p + 1] == loc[p] + 1 {
                run_end[p + 1]
            } else {
                p + 1
            };
        }
        for q in q0..q1 {
            let from = column(zt, rows[q] - b);
            let to = &mut zrr[q * r..(q + 1) * r];
            let mut p = q;
            while p < r {
                let e = run_end[p];
                to[p..e].copy_from_slice(&from[loc[p]..loc[p] + (e - p)]);
                p = e;
            }
        }
        q0 = q1;
    }
    mirror_lower(zrr, r);
    MatRef::from_column_major_slice(&buf[..r * r], r, r)
}

/// Copies the strict lower triangle of the r x r column-major `z` onto its
/// upper triangle, by tiles that stay in the first-level cache (each column
/// of the upper triangle written in order).
fn mirror_lower<T: Copy>(z: &mut [T], r: usize) {
    const TILE: usize = 64;
    for ib in (0..r).step_by(TILE) {
        let ie = (ib + TILE).min(r);
        for jb in (0..ie).step_by(TILE) {
            let je = (jb + TILE).min(r);
            for i in ib..ie {
                // Column i's rows jb..min(je, i) from row i of columns jb...
                let (left, right) = z.split_at_mut(i * r);
                for (k, v) in right[jb..je.min(i)].iter_mut().enumerate() {
                    *v = left[(jb + k) * r + i];
                }
            }
        }
    }
}

/// The precisions the recurrence runs in: f64, and f32 on the factor's
/// single-precision copy ([`Selection::sums_single`]).
pub(crate) trait Real: faer::traits::RealField + Copy + Send + Sync {
    /// x rounded to this precision.
    fn of(x: f64) -> Self;
    /// The value in double precision (exact).
    fn to_f64(self) -> f64;
}

impl Real for f64 {
    fn of(x: f64) -> f64 {
        x
    }
    fn to_f64(self) -> f64 {
        self
    }
}

impl Real for f32 {
    fn of(x: f64) -> f32 {
        x as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::options::Ordering;
    use crate::sparse::Csc;
    use crate::threads::Threads;
    use std::sync::Arc;

    /// A 3D grid Laplacian (7-point, shifted), nx ny nz nodes.
    pub(crate) fn grid3(nx: usize, ny: usize, nz: usize) -> Csc {
        let id = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
        let mut t = Vec::new();
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let a = id(i, j, k);
                    t.push((a, a, 6.2 + 0.01 * (a % 7) as f64));
                    let mut link = |b: usize| {
                        t.push((a, b, -1.0));
                        t.push((b, a, -1.0));
                    };
                    if i + 1 < nx {
                        link(id(i + 1, j, k));
                    }
                    if j + 1 < ny {
                        link(id(i, j + 1, k));
                    }
                    if k + 1 < nz {
                        link(id(i, j, k + 1));
                    }
                }
            }
        }
        Csc::from_triplets(nx * ny * nz, nx * ny * nz, &t)
    }

    /// The tiled mirror against the entry-by-entry one, on sizes below, at and
    /// across its tiles; the lower triangle is left as it was.
    #[test]
    fn mirror_copies_the_lower_triangle_onto_the_upper() {
        for r in [1, 2, 63, 64, 65, 130, 200] {
            let lower = |i: usize, j: usize| (i * 1000 + j) as f64;
            let mut z: Vec<f64> = (0..r * r)
                .map(|k| {
                    if k % r >= k / r {
                        lower(k % r, k / r)
                    } else {
                        -1.0
                    }
                })
                .collect();
            mirror_lower(&mut z, r);
            for j in 0..r {
                for i in 0..r {
                    let want = if i >= j { lower(i, j) } else { lower(j, i) };
                    assert_eq!(z[j * r + i], want, "r {r}: ({i}, {j})");
                }
            }
        }
    }

    /// Every entry of Z on the factor's pattern among the bottom face's DOFs and
    /// their neighbours, against K^-1 by full solves, on one thread and split
    /// between three (top and subtrees); entries off the pattern are reported
    /// as such, and entries between components as zero.
    #[test]
    fn entries_match_the_inverse() {
        let (nx, ny, nz) = (9, 8, 6);
        let k = grid3(nx, ny, nz);
        let n = k.nrows;
        for (ordering, threads) in [(Ordering::Amd, 1), (Ordering::Metis, 3)] {
            let f = Factor::with_last(&k, &[], ordering, Arc::new(Threads::new(threads))).unwrap();
            let tree = Tree::of(&f);
            let new_of = f.new_of_old();
            // K^-1 column by column (original numbering).
            let mut inv = vec![0.0; n * n];
            for j in 0..n {
                let col = &mut inv[j * n..(j + 1) * n];
                col[j] = 1.0;
                f.solve_vec(col);
            }
            let face: Vec<usize> = (0..nx * ny).collect();
            let mut terms = Vec::new();
            let mut want = Vec::new();
            let mut outside = 0;
            for &a in &face {
                for b in [a, a + 1, a + nx, a + nx * ny, (a * 13) % n] {
                    let b = b.min(n - 1);
                    match place(&f, &tree, new_of[a], new_of[b]) {
                        Place::At { s, row, col } => {
                            terms.push(Term {
                                slot: want.len(),
                                s,
                                row,
                                col,
                                coef: 2.0,
                            });
                            want.push(2.0 * inv[a + b * n]);
                        }
                        Place::Zero => panic!("one component"),
                        Place::Outside => outside += 1,
                    }
                }
            }
            assert!(outside > 0 && terms.len() > 3 * face.len());
            let sel = Selection::new(&f, &tree, terms);
            for parallel in [false, true] {
                let got = sel.sums_with(&f, &f.supernodal(), &tree, want.len(), parallel);
                for (slot, (g, w)) in got.iter().zip(&want).enumerate() {
                    assert!(
                        (g - w).abs() <= 1e-14 * w.abs().max(1.0),
                        "{slot}: {g} vs {w}"
                    );
                }
            }
            if threads > 1 {
                let (top, tasks) = sel.split(threads);
                assert!(
                    !top.is_empty() && tasks.len() > threads,
                    "{top:?} {tasks:?}"
                );
            }
            assert!(sel.work_bytes(&f, &tree, threads) > 0);
        }
        // Two components: the entries between them are zero.
        let mut t = Vec::new();
        for j in 0..n {
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                t.push((k.row_idx[p], j, k.values[p]));
                t.push((n + k.row_idx[p], n + j, k.values[p]));
            }
        }
        let two = Csc::from_triplets(2 * n, 2 * n, &t);
        let f = Factor::with_last(&two, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap();
        let tree = Tree::of(&f);
        let new_of = f.new_of_old();
        assert_eq!(place(&f, &tree, new_of[3], new_of[n + 3]), Place::Zero);
    }
}
