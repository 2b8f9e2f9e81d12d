//! The supernodal elimination tree of a sparse Cholesky factor: per column of
//! the factor its supernode, per supernode its first column, width, parent and
//! root. Supernodes are numbered so that a parent comes after its children.

use crate::factor::Factor;

/// The tree of [`Factor::supernodal_symbolic`] (a sparse factor only).
pub(crate) struct Tree {
    /// Per column of the factor (permuted order), its supernode.
    pub of_col: Vec<usize>,
    /// Per supernode, its parent (`usize::MAX` at a root).
    pub parent: Vec<usize>,
    /// Per supernode, the root of its tree (itself at a root): supernodes with
    /// different roots belong to different connected components of K.
    pub root: Vec<usize>,
    /// Per supernode, its first column.
    pub begin: Vec<usize>,
    /// Per supernode, its number of columns.
    pub width: Vec<usize>,
}

impl Tree {
    pub(crate) fn of(factor: &Factor) -> Tree {
        let sym = factor.supernodal_symbolic();
        let ns = sym.n_supernodes();
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        let mut of_col = vec![0usize; factor.n()];
        for s in 0..ns {
            of_col[begin[s]..end[s]].fill(s);
        }
        let parent: Vec<usize> = (0..ns)
            .map(|s| {
                sym.supernode(s)
                    .pattern()
                    .first()
                    .map_or(usize::MAX, |&row| of_col[row])
            })
            .collect();
        let mut root = vec![0usize; ns];
        for s in (0..ns).rev() {
            root[s] = match parent[s] {
                usize::MAX => s,
                p => root[p],
            };
        }
        Tree {
            of_col,
            parent,
            root,
            begin: begin[..ns].to_vec(),
            width: (0..ns).map(|s| end[s] - begin[s]).collect(),
        }
    }

    /// Per supernode, whether it lies on the path from one of `starts`
    /// (supernodes) to its root.
    pub(crate) fn on_paths(&self, starts: impl IntoIterator<Item = usize>) -> Vec<bool> {
        let mut on = vec![false; self.len()];
        for start in starts {
            let mut s = start;
            while s != usize::MAX && !on[s] {
                on[s] = true;
                s = self.parent[s];
            }
        }
        on
    }

    /// Bytes of the tree of `factor` (a sparse factor), before it is made.
    pub(crate) fn bytes_of(factor: &Factor) -> usize {
        let ns = factor.supernodal_symbolic().n_supernodes();
        (factor.n() + 4 * ns) * std::mem::size_of::<usize>()
    }

    /// Number of supernodes.
    pub(crate) fn len(&self) -> usize {
        self.parent.len()
    }
}
