//! From validated triplets to the internal compressed form: two stable counting
//! sorts and one pass that sums duplicates, O(nnz + nrows + ncols); and the
//! fallible allocations every array sized by caller data goes through.

use super::Csc;
use crate::error::{ErrorKind, Result, fail};

/// Validated 0-based triplets in input order (triplet `k` is entry `k` of the view,
/// mirrored entries of a one-triangle K are appended after the stored ones).
#[derive(Default)]
pub(super) struct Triplets {
    pub(super) rows: Vec<usize>,
    pub(super) cols: Vec<usize>,
    pub(super) vals: Vec<f64>,
}

impl Triplets {
    pub(super) fn with_capacity(n: usize) -> Result<Triplets> {
        let mut t = Triplets::default();
        let ok = t.rows.try_reserve_exact(n).is_ok()
            && t.cols.try_reserve_exact(n).is_ok()
            && t.vals.try_reserve_exact(n).is_ok();
        if ok {
            Ok(t)
        } else {
            fail(
                ErrorKind::OutOfMemory,
                format!("cannot allocate {n} matrix entries"),
            )
        }
    }

    pub(super) fn push(&mut self, r: usize, c: usize, v: f64) {
        self.rows.push(r);
        self.cols.push(c);
        self.vals.push(v);
    }

    pub(super) fn len(&self) -> usize {
        self.vals.len()
    }
}

/// A vector of `n` copies of `value`, or `OutOfMemory` instead of an abort: every
/// array whose size comes from caller data is allocated through here (or
/// [`try_copy`]), since `catch_unwind` does not catch an allocation failure.
/// `what` names the entries in the message ("indices", "values").
pub(super) fn filled<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    if v.try_reserve_exact(n).is_err() {
        return fail(
            ErrorKind::OutOfMemory,
            format!("cannot allocate an array of {n} {what}"),
        );
    }
    v.resize(n, value);
    Ok(v)
}

/// A zero-filled index vector of length `n` (see [`filled`]).
pub(super) fn zeroed(n: usize) -> Result<Vec<usize>> {
    filled(n, 0usize, "indices")
}

/// A copy of `v`, or `OutOfMemory` (see [`filled`]).
pub(super) fn try_copy<T: Copy>(v: &[T]) -> Result<Vec<T>> {
    let mut out = Vec::new();
    if out.try_reserve_exact(v.len()).is_err() {
        return fail(
            ErrorKind::OutOfMemory,
            format!("cannot allocate a copy of {} entries", v.len()),
        );
    }
    out.extend_from_slice(v);
    Ok(out)
}

/// Sorts triplets into compressed columns with strictly increasing row indices,
/// summing duplicates (in input order) and keeping explicit zeros.
///
/// Two stable counting sorts, by row then by column, so O(nnz + nrows + ncols).
/// Indices must already be in range.
pub(super) fn assemble(nrows: usize, ncols: usize, t: &Triplets) -> Result<Csc> {
    let nnz = t.len();
    // Pass 1: bucket by row (stable), keeping column and value.
    let mut row_ptr = zeroed(nrows.saturating_add(1))?;
    for &r in &t.rows {
        row_ptr[r + 1] += 1;
    }
    for r in 0..nrows {
        row_ptr[r + 1] += row_ptr[r];
    }
    let mut next = try_copy(&row_ptr)?;
    let mut by_row_col = zeroed(nnz)?;
    let mut by_row_val = filled(nnz, 0.0f64, "values")?;
    for k in 0..nnz {
        let r = t.rows[k];
        let d = next[r];
        by_row_col[d] = t.cols[k];
        by_row_val[d] = t.vals[k];
        next[r] += 1;
    }
    drop(next);
    // Pass 2: bucket by column, visiting rows in increasing order: rows come out
    // sorted within each column, duplicates adjacent in input order.
    let mut col_ptr = zeroed(ncols.saturating_add(1))?;
    for &c in &by_row_col {
        col_ptr[c + 1] += 1;
    }
    for c in 0..ncols {
        col_ptr[c + 1] += col_ptr[c];
    }
    let mut next = try_copy(&col_ptr)?;
    let mut row_idx = zeroed(nnz)?;
    let mut values = filled(nnz, 0.0f64, "values")?;
    for r in 0..nrows {
        for k in row_ptr[r]..row_ptr[r + 1] {
            let c = by_row_col[k];
            let d = next[c];
            row_idx[d] = r;
            values[d] = by_row_val[k];
            next[c] += 1;
        }
    }
    drop((next, row_ptr, by_row_col, by_row_val));
    // Pass 3: sum adjacent duplicates, compacting in place.
    let mut w = 0;
    for j in 0..ncols {
        let (lo, hi) = (col_ptr[j], col_ptr[j + 1]);
        col_ptr[j] = w;
        for k in lo..hi {
            if w > col_ptr[j] && row_idx[w - 1] == row_idx[k] {
                values[w - 1] += values[k];
            } else {
                row_idx[w] = row_idx[k];
                values[w] = values[k];
                w += 1;
            }
        }
    }
    col_ptr[ncols] = w;
    row_idx.truncate(w);
    values.truncate(w);
    Ok(Csc {
        nrows,
        ncols,
        col_ptr,
        row_idx,
        values,
    })
}
