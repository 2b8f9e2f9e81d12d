//! K^-1 on sparse right-hand sides wanted on their own rows, by the paths
//! of the factor's elimination tree (`tree_solve.rs`): what a host's
//! `KSolve::solve_rows` computes with a direct solver that prunes its solves
//! (PARDISO's partial solve). For the benchmark's and the tests' hosts
//! (`internals`); the
//! library's own products call `tree_solve.rs` directly.

use super::supernode_tree::Tree;
use super::tree_solve::{TreeScratch, TreeSolve};
use crate::error::Result;
use crate::factor::Factor;
use std::sync::Arc;

/// Solves on rows with one factor, the split of the last rows kept (a host
/// is asked for the same rows again and again: the contact DOFs) and the
/// scratch of both precisions refitted, not remade, when the rows change.
pub struct RowSolves {
    factor: Arc<Factor>,
    tree: Tree,
    /// L's values in single precision, for the approximate solves (None:
    /// every solve in double).
    single: Option<Vec<f32>>,
    held: Vec<usize>,
    split: Option<TreeSolve>,
    double: Option<TreeScratch<f64>>,
    narrow: Option<TreeScratch<f32>>,
    z: Vec<f64>,
    zs: Vec<f32>,
}

impl RowSolves {
    /// Solves on rows with `factor` (sparse), in single precision too where
    /// `single` (for the approximate ones).
    ///
    /// Errors: `OutOfMemory` for the single-precision copy of L.
    pub fn new(factor: Arc<Factor>, single: bool) -> Result<RowSolves> {
        let n = factor.n();
        Ok(RowSolves {
            tree: Tree::of(&factor),
            single: single.then(|| factor.single_values()).transpose()?,
            factor,
            held: Vec::new(),
            split: None,
            double: None,
            narrow: None,
            z: vec![0.0; n],
            zs: vec![0.0; n],
        })
    }

    /// x (rows.len() x ncols, column-major): the right-hand sides' entries
    /// at the DOFs `rows` (ascending, distinct; zero elsewhere) := the
    /// solutions' entries there; in single precision where `approximate`
    /// and the copy was made.
    pub fn solve(&mut self, rows: &[usize], x: &mut [f64], ncols: usize, approximate: bool) {
        let factor = &*self.factor;
        if self.split.is_none() || self.held != rows {
            let split = TreeSolve::on(factor, &self.tree, rows);
            let n = factor.n();
            match &mut self.double {
                Some(s) => split.refit(s),
                None => self.double = Some(split.scratch(n)),
            }
            match &mut self.narrow {
                Some(s) => split.refit(s),
                None => self.narrow = Some(split.scratch(n)),
            }
            self.split = Some(split);
            self.held.clear();
            self.held.extend_from_slice(rows);
        }
        let split = self.split.as_ref().expect("made above");
        let threads = factor.threads();
        let len = rows.len();
        for col in x.chunks_mut(len.max(1)).take(ncols) {
            match (&self.single, approximate) {
                (Some(values), true) => {
                    let (z, s) = (&mut self.zs, self.narrow.as_mut().expect("made above"));
                    split.clear(factor, z);
                    rows.iter()
                        .zip(col.iter())
                        .for_each(|(&r, &v)| z[r] = v as f32);
                    split.solve_single(factor, values, z, s, threads);
                    rows.iter()
                        .zip(col.iter_mut())
                        .for_each(|(&r, c)| *c = z[r] as f64);
                }
                _ => {
                    let (z, s) = (&mut self.z, self.double.as_mut().expect("made above"));
                    split.clear(factor, z);
                    rows.iter().zip(col.iter()).for_each(|(&r, &v)| z[r] = v);
                    split.solve(factor, factor.values(), z, s, threads);
                    rows.iter()
                        .zip(col.iter_mut())
                        .for_each(|(&r, c)| *c = z[r]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::Ordering;
    use crate::threads::Threads;

    /// On a grid (`dual::tests::grid`), the solve on a few rows gives the
    /// whole solve's entries there, in double to 1e-12 and in single
    /// precision to 1e-5, for two sets of rows in turn.
    #[test]
    fn a_solve_on_rows_gives_the_whole_solves_entries() {
        let k = crate::dual::tests::grid(20, 20);
        let n = k.nrows;
        let factor = Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap();
        let mut rs = RowSolves::new(factor.clone(), true).unwrap();
        for rows in [vec![3usize, 17, 45, 46, 399], vec![0usize, 200, 201]] {
            let mut b = vec![0.0; n];
            for (k, &r) in rows.iter().enumerate() {
                b[r] = 1.0 + k as f64;
            }
            let mut whole = b.clone();
            factor.solve_vec(&mut whole);
            for (approximate, tol) in [(false, 1e-12), (true, 1e-5)] {
                let mut x: Vec<f64> = rows.iter().map(|&r| b[r]).collect();
                rs.solve(&rows, &mut x, 1, approximate);
                for (&r, v) in rows.iter().zip(&x) {
                    assert!(
                        (v - whole[r]).abs() <= tol * whole[r].abs(),
                        "row {r}: {v} against {}",
                        whole[r]
                    );
                }
            }
        }
    }
}
