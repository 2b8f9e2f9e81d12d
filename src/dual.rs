//! The condensed dual problem of design.md section 2: with B = [N; T],
//! A = B K^-1 B^T (dense, c x c with c = d m) and, per increment,
//! b = B K^-1 f - [g; 0]. Unknown ordering: lambda_N (m), then lambda_T ((d-1) m,
//! contact by contact).

use crate::error::{ErrorKind, Result, fail};
use crate::factor::Factor;
use crate::sparse::Csc;
use faer::dyn_stack::{MemBuffer, MemStack};
use std::time::Instant;

/// Number of right-hand sides solved together while forming A.
const BLOCK: usize = 32;

/// The dense condensed dual operator of one set of contact matrices.
pub struct Dual {
    /// Contact dimension (2 or 3).
    pub d: usize,
    /// Number of contacts.
    pub m: usize,
    /// Number of dual unknowns, d m.
    pub c: usize,
    /// A = B K^-1 B^T, c x c, column-major and exactly symmetric.
    pub a: Vec<f64>,
    /// Per contact: rho_i = d / trace of the contact's d x d diagonal block of A
    /// (0 when that block vanishes). Units: force / length.
    pub rho: Vec<f64>,
    /// B = [N; T], c x n.
    pub b: Csc,
    /// Seconds spent forming A.
    pub condense_seconds: f64,
}

/// Stacks N (m x n) and T ((d-1) m x n) into B = [N; T].
pub fn stack_rows(n: &Csc, t: &Csc) -> Csc {
    let ncols = n.ncols;
    let mut col_ptr = Vec::with_capacity(ncols + 1);
    let mut row_idx = Vec::with_capacity(n.nnz() + t.nnz());
    let mut values = Vec::with_capacity(n.nnz() + t.nnz());
    col_ptr.push(0);
    for j in 0..ncols {
        for k in n.col_ptr[j]..n.col_ptr[j + 1] {
            row_idx.push(n.row_idx[k]);
            values.push(n.values[k]);
        }
        for k in t.col_ptr[j]..t.col_ptr[j + 1] {
            row_idx.push(n.nrows + t.row_idx[k]);
            values.push(t.values[k]);
        }
        col_ptr.push(row_idx.len());
    }
    Csc {
        nrows: n.nrows + t.nrows,
        ncols,
        col_ptr,
        row_idx,
        values,
    }
}

impl Dual {
    /// Forms A = B K^-1 B^T with one solve per dual unknown (blocked).
    ///
    /// Errors: `BadSize` if the shapes of N and T do not match d and K,
    /// `OutOfMemory` if A does not fit.
    pub fn build(factor: &Factor, n: &Csc, t: &Csc, d: usize) -> Result<Dual> {
        let start = Instant::now();
        let ndof = factor.n();
        let m = n.nrows;
        if n.ncols != ndof || t.ncols != ndof {
            return fail(
                ErrorKind::BadSize,
                format!(
                    "N has {} columns and T has {}, but K has {ndof} rows",
                    n.ncols, t.ncols
                ),
            );
        }
        if t.nrows != (d - 1) * m {
            return fail(
                ErrorKind::BadSize,
                format!(
                    "T has {} rows, expected (d-1) * rows(N) = {}",
                    t.nrows,
                    (d - 1) * m
                ),
            );
        }
        let b = stack_rows(n, t);
        let c = b.nrows;
        let mut a = Vec::new();
        a.try_reserve_exact(c * c).map_err(|_| {
            crate::Error::new(
                ErrorKind::OutOfMemory,
                format!("condensed dual: {c} x {c} dense matrix does not fit in memory"),
            )
        })?;
        a.resize(c * c, 0.0);
        let bt = b.transpose();
        let width = BLOCK.min(c.max(1));
        let mut rhs = faer::Mat::<f64>::zeros(ndof, width);
        let mut mem = MemBuffer::new(factor.solve_scratch(width));
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
        for j in 0..c {
            for i in 0..j {
                let s = 0.5 * (a[i + j * c] + a[j + i * c]);
                a[i + j * c] = s;
                a[j + i * c] = s;
            }
        }
        let rho = (0..m)
            .map(|i| {
                let mut tr = a[i + i * c];
                for k in 0..d - 1 {
                    let t = m + (d - 1) * i + k;
                    tr += a[t + t * c];
                }
                if tr > 0.0 { d as f64 / tr } else { 0.0 }
            })
            .collect();
        Ok(Dual {
            d,
            m,
            c,
            a,
            rho,
            b,
            condense_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Column (= row) j of A.
    #[inline]
    pub fn col(&self, j: usize) -> &[f64] {
        &self.a[j * self.c..(j + 1) * self.c]
    }

    /// y := A x.
    pub fn apply(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for (j, &xj) in x.iter().enumerate() {
            if xj != 0.0 {
                for (yi, aij) in y.iter_mut().zip(self.col(j)) {
                    *yi += aij * xj;
                }
            }
        }
    }
}
