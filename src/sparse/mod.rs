//! Sparse matrices: the borrowed input views (CSR, CSC or COO; 0- or 1-based;
//! 32- or 64-bit indices; full or one-triangle storage) and the one internal form,
//! `Csc`, with sorted row indices and no duplicates. All validation of caller
//! matrices happens here.
//!
//! Every conversion is O(nnz + nrows + ncols): two stable counting sorts (by row,
//! then by column) sort the entries and bring duplicates together, and one pass
//! sums them. Explicit zeros are kept, so the internal pattern depends only on the
//! input pattern (K's symbolic factorisation stays valid across refactorisations).
//!
//! Error messages give entry numbers, rows and columns in the caller's index base,
//! and pointer positions as `p[k]` (base 0) or `p(k)` (base 1).

mod assemble;
mod congruence;
mod refill;
#[cfg(test)]
mod tests;
mod validate;

use crate::error::{ErrorKind, Result, fail};
use assemble::{Triplets, assemble, filled, try_copy, zeroed};
pub(crate) use congruence::{congruence, congruence_bytes};
pub(crate) use refill::{TripletSlots, mirror_bytes};
use validate::{
    check_base, check_dense_len, check_pointers, check_sums_finite, check_symmetric, collect,
    collect_dense, dense_not_finite, index0,
};

/// The CSC arrays of `view`, whose pointers [`check_pointers`] passed (`p[0]
/// = base`, non-decreasing, `nnz` entries in i and x), as a Csc, copied as
/// they are, where every column's row indices are in range and strictly
/// increasing and every value is finite: what [`collect`] and
/// [`assemble()`] would make of them, without the triplets and their sort (a third of a
/// second for the 5 million entries of a 3D K). None where any of that
/// fails: the general path then sums the duplicates or names the bad entry.
///
/// Errors: `OutOfMemory`.
fn csc_in_order(view: &MatrixView<'_>, base: usize, nnz: usize) -> Result<Option<Csc>> {
    let (nrows, ncols) = (view.nrows, view.ncols);
    let mut col_ptr = zeroed(ncols + 1)?;
    let mut row_idx = zeroed(nnz)?;
    for j in 0..ncols {
        // base <= p[j] <= p[j + 1] <= base + nnz (checked).
        let lo = (view.p.get(j) - base as i64) as usize;
        let hi = (view.p.get(j + 1) - base as i64) as usize;
        let mut next = 0;
        for (k, slot) in (lo..hi).zip(&mut row_idx[lo..hi]) {
            match index0(view.i.get(k), base, nrows) {
                Some(r) if r >= next && view.x[k].is_finite() => {
                    *slot = r;
                    next = r + 1;
                }
                _ => return Ok(None),
            }
        }
        col_ptr[j + 1] = hi;
    }
    Ok(Some(Csc {
        nrows,
        ncols,
        col_ptr,
        row_idx,
        values: try_copy(view.x)?,
    }))
}
pub(crate) use validate::{check_internal, check_internal_symmetric, dense_len};

/// Layout of a borrowed sparse matrix, named as in CSparse.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Format {
    /// Compressed sparse row: `p` holds nrows+1 row pointers, `i` the column indices.
    Csr,
    /// Compressed sparse column (CSparse `cs`, CHOLMOD packed `cholmod_sparse`):
    /// `p` holds ncols+1 column pointers, `i` the row indices.
    Csc,
    /// Triplets (CSparse convention): `i` holds the row indices, `p` the column
    /// indices, both of length nnz. Duplicates are summed.
    Coo,
    /// Dense, column-major (LAPACK): entry (r, c) at `x[r + c ld]`, `ld >= nrows`;
    /// `p`, `i` and the index base are not used. A symmetric K keeps every entry
    /// (of its triangle, mirrored, for one-triangle storage; the other triangle
    /// is not read) and is factored by dense Cholesky; N and T keep their nonzeros.
    Dense {
        /// The leading dimension: x holds `ld (ncols - 1) + nrows` values.
        ld: usize,
    },
}

/// Which part of a symmetric matrix is stored (only meaningful for K).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Storage {
    /// Every entry is stored; K is checked for symmetry.
    Full,
    /// Only entries with row <= column are stored (CHOLMOD stype = 1);
    /// entries below the diagonal are an error.
    Upper,
    /// Only entries with row >= column are stored (CHOLMOD stype = -1);
    /// entries above the diagonal are an error.
    Lower,
}

/// A borrowed index array of either integer width.
#[derive(Copy, Clone, Debug)]
pub enum Indices<'a> {
    /// 32-bit signed indices (C `int32_t`, Fortran default INTEGER).
    I32(&'a [i32]),
    /// 64-bit signed indices (C `int64_t`, SuiteSparse_long).
    I64(&'a [i64]),
}

/// A borrowed sparse matrix exactly as the caller holds it. Nothing is copied until
/// it is converted with [`Csc::from_view`].
#[derive(Copy, Clone, Debug)]
pub struct MatrixView<'a> {
    /// Layout of `p` and `i`.
    pub format: Format,
    /// Full or one-triangle storage.
    pub storage: Storage,
    /// Index base: 0 (C) or 1 (Fortran). Applies to pointers and indices alike.
    pub base: usize,
    /// Number of rows.
    pub nrows: usize,
    /// Number of columns.
    pub ncols: usize,
    /// Pointers (CSR/CSC) or column indices (COO).
    pub p: Indices<'a>,
    /// Row indices (CSC, COO) or column indices (CSR).
    pub i: Indices<'a>,
    /// Values, one per stored entry.
    pub x: &'a [f64],
}

/// The internal sparse form: compressed columns, 0-based, row indices strictly
/// increasing within each column (sorted, duplicates summed), all values finite.
#[derive(Clone, Debug, PartialEq)]
pub struct Csc {
    /// Number of rows.
    pub nrows: usize,
    /// Number of columns.
    pub ncols: usize,
    /// Column pointers, length `ncols + 1`, `col_ptr[0] == 0`, non-decreasing.
    pub col_ptr: Vec<usize>,
    /// Row indices, length `col_ptr[ncols]`, strictly increasing in each column.
    pub row_idx: Vec<usize>,
    /// Values, length `col_ptr[ncols]` (explicit zeros may be stored).
    pub values: Vec<f64>,
}

/// Relative tolerance of the symmetry check of a fully stored K:
/// |K_ij - K_ji| <= SYMMETRY_TOL * max_kl |K_kl| for every pair.
pub const SYMMETRY_TOL: f64 = 1e-10;

/// A dense symmetric K (`view.format` = `Dense { ld }`, square) in the internal
/// form with every entry stored, explicit zeros too, so that it stays dense and is
/// factored by dense Cholesky whatever its values: column j holds rows 0..n.
/// Built straight from the array (no triplets, no sorts): the n^2 values and row
/// indices are all it allocates. One-triangle storage reads only that triangle;
/// full storage is checked for symmetry with [`SYMMETRY_TOL`].
///
/// Errors: `BadSize` (ld < n, x too short), `NotFinite` (a value read),
/// `NotSymmetric` (the worst pair), `OutOfMemory`.
fn symmetric_from_dense(view: &MatrixView<'_>, ld: usize, what: &str, base: usize) -> Result<Csc> {
    let n = view.nrows;
    check_dense_len(view, ld, what)?;
    let entries = n.checked_mul(n).ok_or_else(|| {
        crate::Error::new(
            ErrorKind::OutOfMemory,
            format!("{what}: {n} x {n} is too large"),
        )
    })?;
    // The array position holding entry (r, c) of the stored part.
    let at = |r: usize, c: usize| match view.storage {
        Storage::Upper if r > c => c + r * ld,
        Storage::Lower if r < c => c + r * ld,
        _ => r + c * ld,
    };
    let mut values = filled(entries, 0.0, "values")?;
    let mut row_idx = filled(entries, 0usize, "indices")?;
    let mut max_abs = 0.0f64;
    for c in 0..n {
        for r in 0..n {
            let v = view.x[at(r, c)];
            if !v.is_finite() {
                // Named where it is stored (the stored triangle for UPPER / LOWER).
                let (sr, sc) = if at(r, c) == r + c * ld {
                    (r, c)
                } else {
                    (c, r)
                };
                return dense_not_finite(what, sr, sc, ld, base, v);
            }
            values[r + c * n] = v;
            row_idx[r + c * n] = r;
            max_abs = max_abs.max(v.abs());
        }
    }
    if view.storage == Storage::Full {
        let tol = SYMMETRY_TOL * max_abs;
        let mut worst: Option<(usize, usize, f64)> = None;
        for c in 0..n {
            for r in 0..c {
                let diff = (values[r + c * n] - values[c + r * n]).abs();
                if diff > tol && worst.is_none_or(|w| diff > w.2) {
                    worst = Some((r, c, diff));
                }
            }
        }
        if let Some((r, c, diff)) = worst {
            return fail(
                ErrorKind::NotSymmetric,
                format!(
                    "{what} is not symmetric: {what}({},{}) = {} but {what}({},{}) = {}; \
                     |difference| {diff:e} > {SYMMETRY_TOL:e} * max|{what}| = {tol:e}",
                    r + base,
                    c + base,
                    values[r + c * n],
                    c + base,
                    r + base,
                    values[c + r * n]
                ),
            );
        }
    }
    Ok(Csc {
        nrows: n,
        ncols: n,
        col_ptr: (0..=n).map(|j| j * n).collect(),
        row_idx,
        values,
    })
}

impl Indices<'_> {
    /// Number of stored indices.
    fn len(&self) -> usize {
        match self {
            Indices::I32(s) => s.len(),
            Indices::I64(s) => s.len(),
        }
    }

    /// The `k`-th index, widened to i64 (no range check on the value).
    fn get(&self, k: usize) -> i64 {
        match self {
            Indices::I32(s) => i64::from(s[k]),
            Indices::I64(s) => s[k],
        }
    }
}

impl Csc {
    /// Converts and validates a general matrix (N or T). `what` names the matrix in
    /// error messages ("N", "T"). `view.storage` must be `Full`.
    ///
    /// The result is 0-based, with row indices strictly increasing in each column:
    /// unsorted input is sorted and duplicate entries are summed (in every format,
    /// not only COO). Explicit zeros are kept, so the pattern depends only on the
    /// input pattern. The cost is O(nnz + nrows + ncols).
    ///
    /// Error messages give entry numbers, rows and columns in the caller's index
    /// base (entry k is `x[k]` for base 0, `x(k)` for base 1).
    ///
    /// Errors: `BadArgument` (base not 0 or 1, triangle storage),
    /// `BadSize` (array lengths inconsistent with the dimensions and pointers),
    /// `BadIndex` (index out of range, negative, pointers not starting at the base
    /// or decreasing), `NotFinite` (NaN or infinity in `x`, or duplicates summing
    /// to an infinity), `OutOfMemory` (absurd dimensions).
    pub fn from_view(view: &MatrixView<'_>, what: &str) -> Result<Csc> {
        let base = check_base(view, what)?;
        if view.storage != Storage::Full {
            return fail(
                ErrorKind::BadArgument,
                format!(
                    "{what}: storage must be Full for a general matrix, got {:?}",
                    view.storage
                ),
            );
        }
        let t = match view.format {
            Format::Dense { .. } => collect_dense(view, what, base)?,
            _ => collect(view, what, base, 0)?,
        };
        let a = assemble(view.nrows, view.ncols, &t)?;
        check_sums_finite(&a, what, base)?;
        Ok(a)
    }

    /// Converts and validates a symmetric matrix (K), returning BOTH triangles
    /// (the full symmetric matrix). One-triangle input is mirrored (the diagonal
    /// once); full input is checked for symmetry with [`SYMMETRY_TOL`] (a missing
    /// entry counts as 0) and then used as given, sorted and with duplicates summed.
    /// Explicit zeros are kept, so the pattern depends only on the input pattern.
    ///
    /// Errors: those of [`Csc::from_view`] (any storage is accepted), plus
    /// `BadSize` if not square, `BadIndex` for an entry in the wrong triangle
    /// (whatever its value), `NotSymmetric` naming the worst pair.
    pub fn symmetric_from_view(view: &MatrixView<'_>, what: &str) -> Result<Csc> {
        let base = check_base(view, what)?;
        if view.nrows != view.ncols {
            return fail(
                ErrorKind::BadSize,
                format!("{what} must be square, got {} x {}", view.nrows, view.ncols),
            );
        }
        if let Format::Dense { ld } = view.format {
            return symmetric_from_dense(view, ld, what, base);
        }
        let n = view.nrows;
        // The common case, whole CSC arrays in order: taken as they are.
        if view.format == Format::Csc && view.storage == Storage::Full {
            let nnz = check_pointers(view, what, base)?;
            if let Some(a) = csc_in_order(view, base, nnz)? {
                check_symmetric(&a, what, base)?;
                return Ok(a);
            }
        }
        // Room for the mirrored entries of a one-triangle K.
        let extra = if view.storage == Storage::Full {
            0
        } else {
            view.i.len()
        };
        let mut t = collect(view, what, base, extra)?;
        match view.storage {
            Storage::Full => {
                let a = assemble(n, n, &t)?;
                check_sums_finite(&a, what, base)?;
                check_symmetric(&a, what, base)?;
                Ok(a)
            }
            Storage::Upper | Storage::Lower => {
                let upper = view.storage == Storage::Upper;
                let stored = t.len();
                for k in 0..stored {
                    let (r, c) = (t.rows[k], t.cols[k]);
                    if (upper && r > c) || (!upper && r < c) {
                        let (tri, side) = if upper {
                            ("upper", "below")
                        } else {
                            ("lower", "above")
                        };
                        return fail(
                            ErrorKind::BadIndex,
                            format!(
                                "{what} stored as {tri} triangle has entry ({},{}) {side} the \
                                 diagonal (entry {})",
                                r + base,
                                c + base,
                                k + base
                            ),
                        );
                    }
                }
                for k in 0..stored {
                    let (r, c, v) = (t.rows[k], t.cols[k], t.vals[k]);
                    if r != c {
                        t.push(c, r, v);
                    }
                }
                let a = assemble(n, n, &t)?;
                check_sums_finite(&a, what, base)?;
                Ok(a)
            }
        }
    }

    /// Builds a matrix from 0-based `(row, column, value)` triplets, in the internal
    /// form: duplicates summed (in the given order), explicit zeros kept. Values are
    /// not checked for finiteness. For internal use and tests.
    ///
    /// # Panics
    ///
    /// If a row index is `>= nrows` or a column index `>= ncols` (or if the
    /// dimensions are too large to allocate).
    pub fn from_triplets(nrows: usize, ncols: usize, triplets: &[(usize, usize, f64)]) -> Csc {
        let mut t = Triplets::default();
        for (k, &(r, c, v)) in triplets.iter().enumerate() {
            assert!(
                r < nrows && c < ncols,
                "Csc::from_triplets: triplet {k} at ({r}, {c}) is outside {nrows} x {ncols}"
            );
            t.push(r, c, v);
        }
        assemble(nrows, ncols, &t).expect("Csc::from_triplets: out of memory")
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.col_ptr[self.ncols]
    }

    /// Bytes of the stored arrays (column pointers, row indices, values).
    pub(crate) fn bytes(&self) -> usize {
        let idx = std::mem::size_of::<usize>();
        (self.ncols + 1) * idx + self.nnz() * (idx + std::mem::size_of::<f64>())
    }

    /// y := A x (x has ncols entries, y has nrows; y is overwritten).
    ///
    /// Panics if `x` is shorter than `ncols` or `y` shorter than `nrows`.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for (cols, &xj) in self.col_ptr.windows(2).zip(&x[..self.ncols]) {
            for k in cols[0]..cols[1] {
                y[self.row_idx[k]] += self.values[k] * xj;
            }
        }
    }

    /// y := A^T x (x has nrows entries, y has ncols; y is overwritten).
    ///
    /// Panics if `x` is shorter than `nrows` or `y` shorter than `ncols`.
    pub fn mul_t_vec(&self, x: &[f64], y: &mut [f64]) {
        for (cols, yj) in self.col_ptr.windows(2).zip(&mut y[..self.ncols]) {
            let mut s = 0.0;
            for k in cols[0]..cols[1] {
                s += self.values[k] * x[self.row_idx[k]];
            }
            *yj = s;
        }
    }

    /// The transpose, in the same internal form.
    ///
    /// Panics if it cannot be allocated; [`Csc::try_transpose`] returns
    /// `OutOfMemory` instead.
    pub fn transpose(&self) -> Csc {
        self.try_transpose().expect("memory for the transpose")
    }

    /// Visits every pair of mirror places (r, c), r < c, of a square matrix
    /// with sorted rows, in one pass with n cursors and no copy:
    /// `pair(r, c, upper, lower)` with the positions of A(r, c) and A(c, r)
    /// in `row_idx` / `values` (None where not stored). The entries (c, j)
    /// below the diagonal, met column by column, meet each column c's
    /// entries above its diagonal in their order; one passed over has no
    /// mirror. Stops at the first pair for which `pair` returns false and
    /// returns false then, true after every pair.
    ///
    /// Errors: `OutOfMemory` (the n cursors).
    pub(crate) fn mirror_pairs(
        &self,
        mut pair: impl FnMut(usize, usize, Option<usize>, Option<usize>) -> bool,
    ) -> Result<bool> {
        let n = self.ncols;
        // next[c]: the next entry of column c above its diagonal not yet met.
        let mut next = try_copy(&self.col_ptr[..n])?;
        for j in 0..n {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let c = self.row_idx[p];
                if c <= j {
                    continue;
                }
                // Column c's entries above its diagonal in rows before j: alone.
                let end = self.col_ptr[c + 1];
                let mut q = next[c];
                while q < end && self.row_idx[q] < j {
                    if !pair(self.row_idx[q], c, Some(q), None) {
                        return Ok(false);
                    }
                    q += 1;
                }
                let upper = (q < end && self.row_idx[q] == j).then_some(q);
                if !pair(j, c, upper, Some(p)) {
                    return Ok(false);
                }
                next[c] = q + usize::from(upper.is_some());
            }
        }
        for (c, &start) in next.iter().enumerate() {
            for q in start..self.col_ptr[c + 1] {
                let r = self.row_idx[q];
                if r >= c {
                    break;
                }
                if !pair(r, c, Some(q), None) {
                    return Ok(false);
                }
            }
        }
        Ok(true)
    }

    /// The transpose, in the same internal form.
    ///
    /// Errors: `OutOfMemory`.
    pub fn try_transpose(&self) -> Result<Csc> {
        let mut count = zeroed(self.nrows.saturating_add(1))?;
        for &r in &self.row_idx {
            count[r + 1] += 1;
        }
        for r in 0..self.nrows {
            count[r + 1] += count[r];
        }
        let col_ptr = try_copy(&count)?;
        let mut next = count;
        let nnz = self.nnz();
        let mut row_idx = zeroed(nnz)?;
        let mut values = filled(nnz, 0.0, "values")?;
        for j in 0..self.ncols {
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let r = self.row_idx[k];
                row_idx[next[r]] = j;
                values[next[r]] = self.values[k];
                next[r] += 1;
            }
        }
        Ok(Csc {
            nrows: self.ncols,
            ncols: self.nrows,
            col_ptr,
            row_idx,
            values,
        })
    }
}
