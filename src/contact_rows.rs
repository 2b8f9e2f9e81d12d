//! The contact rows: N and T checked against K's size and stacked into
//! B = [N; T] (c x n, the normal rows first, then the d-1 tangent rows of
//! each contact), and the DOFs B touches.

use crate::error::{ErrorKind, Result, fail};
use crate::sparse::Csc;

/// The DOFs (columns of B) that B touches, in increasing order.
pub fn contact_dofs(b: &Csc) -> Vec<usize> {
    (0..b.ncols)
        .filter(|&j| b.col_ptr[j + 1] > b.col_ptr[j])
        .collect()
}

/// Checks that N (m x n) and T ((d-1) m x n) fit a K of `ndof` rows, before any
/// code indexes one by the other's sizes.
///
/// Errors: `BadSize`.
pub(crate) fn check_shapes(ndof: usize, d: usize, n: &Csc, t: &Csc) -> Result<()> {
    if n.ncols != ndof || t.ncols != ndof {
        return fail(
            ErrorKind::BadSize,
            format!(
                "N has {} columns and T has {}, but K has {ndof} rows",
                n.ncols, t.ncols
            ),
        );
    }
    if t.nrows != (d - 1) * n.nrows {
        return fail(
            ErrorKind::BadSize,
            format!(
                "T has {} rows, expected (d-1) * rows(N) = {}",
                t.nrows,
                (d - 1) * n.nrows
            ),
        );
    }
    Ok(())
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
