//! Solves with K's factor for a right-hand side that vanishes outside a set of
//! DOFs, of which only the values at the same DOFs are wanted: the products of
//! the matrix-free dual (B^T x in, B z out). With L L^T = P K P^T, the forward
//! solve of such a right-hand side is zero outside the supernodes on the
//! elimination-tree paths from those DOFs to the root, and the back solve needs
//! only the same supernodes to give the values there; both passes touch those
//! supernodes alone. On a 2D strip whose bottom row is the contact face they
//! hold a third of L's entries; on a thin 3D slab nearly all of them (then the
//! plain solve, which may use threads, is taken instead: see
//! [`Paths::worth_it`]).

use crate::factor::Factor;
use crate::supernode_tree::Tree;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::{Accum, MatMut, MatRef, Par};

/// Restricted solves pay where the paths hold at most this fraction of L's
/// entries (they run on one thread; the plain solve may use the pool).
const MAX_FRACTION: f64 = 0.8;

/// The supernodes on the paths from a set of DOFs to the root.
pub(crate) struct Paths {
    /// The supernodes, ascending (children before parents).
    on: Vec<usize>,
    /// Their columns of the factor (permuted order), and the DOF (original
    /// order) of each.
    cols: Vec<usize>,
    dofs: Vec<usize>,
    /// The longest pattern below one of them (the scratch of a product).
    below: usize,
    /// Their share of L's entries.
    fraction: f64,
}

impl Paths {
    /// The paths of `dofs` (original numbering) in a sparse factor.
    pub(crate) fn of(factor: &Factor, dofs: &[usize]) -> Paths {
        let tree = Tree::of(factor);
        let new_of = factor.new_of_old();
        let sym = factor.supernodal_symbolic();
        let needed = tree.on_paths(dofs.iter().map(|&dof| tree.of_col[new_of[dof]]));
        let on: Vec<usize> = (0..tree.len()).filter(|&s| needed[s]).collect();
        let old_of = factor.old_of_new();
        let (mut entries, mut all, mut below) = (0usize, 0usize, 0usize);
        for (s, &on_path) in needed.iter().enumerate() {
            let (w, r) = (tree.width[s], sym.supernode(s).pattern().len());
            all += (w + r) * w;
            if on_path {
                entries += (w + r) * w;
                below = below.max(r);
            }
        }
        let cols: Vec<usize> = on
            .iter()
            .flat_map(|&s| tree.begin[s]..tree.begin[s] + tree.width[s])
            .collect();
        let dofs = cols.iter().map(|&c| old_of[c]).collect();
        Paths {
            on,
            cols,
            dofs,
            below,
            fraction: if all > 0 {
                entries as f64 / all as f64
            } else {
                1.0
            },
        }
    }

    /// Whether restricted solves are taken (see MAX_FRACTION).
    pub(crate) fn worth_it(&self) -> bool {
        self.fraction <= MAX_FRACTION
    }

    /// Length of the scratch `solve` needs besides the n-vector.
    pub(crate) fn scratch_len(&self) -> usize {
        self.below
    }
}

macro_rules! restricted_solve {
    ($name:ident, $t:ty) => {
        impl Paths {
            /// x := K^-1 x at the paths' DOFs, for an x (length n, original
            /// numbering) that vanishes outside them; x's other entries are left
            /// as they were. `work` (length n) and `buf` (at least
            /// [`Paths::scratch_len`]) are scratch; `values` are L's values in
            /// this precision.
            pub(crate) fn $name(
                &self,
                factor: &Factor,
                values: &[$t],
                x: &mut [$t],
                work: &mut [$t],
                buf: &mut [$t],
            ) {
                let sym = factor.supernodal_symbolic();
                let llt = SupernodalLltRef::<usize, $t>::new(sym, values);
                for (&c, &dof) in self.cols.iter().zip(&self.dofs) {
                    work[c] = x[dof];
                }
                let begin = sym.supernode_begin();
                for &s in &self.on {
                    let node = llt.supernode(s);
                    let val = node.val();
                    let (w, pattern) = (val.ncols(), node.pattern());
                    let r = pattern.len();
                    let b = begin[s];
                    solve_lower_triangular_in_place(
                        val.submatrix(0, 0, w, w),
                        MatMut::from_column_major_slice_mut(&mut work[b..b + w], w, 1),
                        Par::Seq,
                    );
                    if r == 0 {
                        continue;
                    }
                    matmul(
                        MatMut::from_column_major_slice_mut(&mut buf[..r], r, 1),
                        Accum::Replace,
                        val.submatrix(w, 0, r, w),
                        MatRef::from_column_major_slice(&work[b..b + w], w, 1),
                        1.0,
                        Par::Seq,
                    );
                    for (&row, &v) in pattern.iter().zip(&buf[..r]) {
                        work[row] -= v;
                    }
                }
                for &s in self.on.iter().rev() {
                    let node = llt.supernode(s);
                    let val = node.val();
                    let (w, pattern) = (val.ncols(), node.pattern());
                    let r = pattern.len();
                    let b = begin[s];
                    if r > 0 {
                        for (v, &row) in buf[..r].iter_mut().zip(pattern) {
                            *v = work[row];
                        }
                        matmul(
                            MatMut::from_column_major_slice_mut(&mut work[b..b + w], w, 1),
                            Accum::Add,
                            val.submatrix(w, 0, r, w).transpose(),
                            MatRef::from_column_major_slice(&buf[..r], r, 1),
                            -1.0,
                            Par::Seq,
                        );
                    }
                    solve_upper_triangular_in_place(
                        val.submatrix(0, 0, w, w).transpose(),
                        MatMut::from_column_major_slice_mut(&mut work[b..b + w], w, 1),
                        Par::Seq,
                    );
                }
                for (&c, &dof) in self.cols.iter().zip(&self.dofs) {
                    x[dof] = work[c];
                }
            }
        }
    };
}

restricted_solve!(solve, f64);
restricted_solve!(solve_single, f32);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dual::tests::grid;
    use crate::options::Ordering;
    use crate::threads::Threads;
    use std::sync::Arc;

    /// On a strip's bottom row: the restricted solve equals the full one at the
    /// row's DOFs (double to 1e-13, single to 1e-5), and the paths hold a small
    /// share of L.
    #[test]
    fn restricted_equals_full_at_the_dofs() {
        let (nx, ny) = (200, 12);
        let k = grid(nx, ny);
        let n = nx * ny;
        let dofs: Vec<usize> = (0..nx).collect();
        for ordering in [Ordering::Amd, Ordering::Metis] {
            let f = Factor::with_last(&k, &[], ordering, Arc::new(Threads::new(1))).unwrap();
            let paths = Paths::of(&f, &dofs);
            assert!(paths.worth_it(), "{ordering:?}: {}", paths.fraction);
            let mut x = vec![0.0; n];
            for (i, &d) in dofs.iter().enumerate() {
                x[d] = (i as f64 * 0.7).sin() + 0.2;
            }
            let mut full = x.clone();
            f.solve_vec(&mut full);
            let (mut work, mut buf) = (vec![0.0; n], vec![0.0; paths.scratch_len()]);
            let mut got = x.clone();
            paths.solve(&f, f.values(), &mut got, &mut work, &mut buf);
            let scale = full.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for &d in &dofs {
                assert!((got[d] - full[d]).abs() <= 1e-13 * scale, "{d}");
            }
            let single = f.single_values();
            let mut xs: Vec<f32> = x.iter().map(|&v| v as f32).collect();
            let (mut ws, mut bs) = (vec![0.0f32; n], vec![0.0f32; paths.scratch_len()]);
            paths.solve_single(&f, &single, &mut xs, &mut ws, &mut bs);
            for &d in &dofs {
                assert!((f64::from(xs[d]) - full[d]).abs() <= 1e-5 * scale, "{d}");
            }
        }
    }
}
