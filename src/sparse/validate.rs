//! Validation of borrowed views: index base, pointer arrays, index ranges,
//! finiteness, triangle storage, and (after assembly) the sums of duplicates and
//! the symmetry of a fully stored K. Messages name entries in the caller's index
//! base.

use super::assemble::Triplets;
use super::{Csc, Format, MatrixView, SYMMETRY_TOL};
use crate::error::{ErrorKind, Result, fail};

/// An array position in the caller's notation: `p[3]` (base 0, C) or `p(4)`
/// (base 1, Fortran).
pub(super) fn at(name: &str, k: usize, base: usize) -> String {
    if base == 0 {
        format!("{name}[{k}]")
    } else {
        format!("{name}({})", k + 1)
    }
}

/// The valid range of an index of a dimension of size `dim`, in the caller's base.
pub(super) fn range_text(base: usize, dim: usize) -> String {
    if dim == 0 {
        "none (the dimension is 0)".to_string()
    } else if base == 0 {
        format!("0..{dim}")
    } else {
        format!("1..={dim}")
    }
}

/// Checks the index base and returns it.
pub(super) fn check_base(view: &MatrixView<'_>, what: &str) -> Result<usize> {
    match view.base {
        0 | 1 => Ok(view.base),
        b => fail(
            ErrorKind::BadArgument,
            format!("{what}: index base must be 0 or 1, got {b}"),
        ),
    }
}

/// Converts index `v` (caller's base) to 0-based if it lies in `[base, base + dim)`.
pub(super) fn index0(v: i64, base: usize, dim: usize) -> Option<usize> {
    // base is 0 or 1, so `v < base` rules out every negative value and `v - base`
    // cannot overflow; the u64 comparison avoids truncating a huge i64.
    let base = base as i64;
    if v < base {
        return None;
    }
    let off = (v - base) as u64;
    if off < dim as u64 {
        Some(off as usize)
    } else {
        None
    }
}

/// Validates the pointer array of a CSR/CSC view (length, start, monotonicity) and
/// the lengths of `i` and `x` against it. Returns the number of entries.
pub(super) fn check_pointers(view: &MatrixView<'_>, what: &str, base: usize) -> Result<usize> {
    let (fmt, n, dim_name, ptr_name) = match view.format {
        Format::Csc => ("CSC", view.ncols, "columns", "column"),
        Format::Csr => ("CSR", view.nrows, "rows", "row"),
        Format::Coo | Format::Dense { .. } => unreachable!("only CSR and CSC have pointers"),
    };
    let plen = view.p.len();
    if plen == 0 || plen - 1 != n {
        let need = match n.checked_add(1) {
            Some(k) => k.to_string(),
            None => format!("{n}+1"),
        };
        return fail(
            ErrorKind::BadSize,
            format!(
                "{what}: {fmt} with {n} {dim_name} needs {need} {ptr_name} pointers, p has {plen}"
            ),
        );
    }
    let p0 = view.p.get(0);
    if p0 != base as i64 {
        return fail(
            ErrorKind::BadIndex,
            format!(
                "{what}: {ptr_name} pointer {} = {p0}, expected the index base {base}",
                at("p", 0, base)
            ),
        );
    }
    for k in 0..n {
        let (a, b) = (view.p.get(k), view.p.get(k + 1));
        if b < a {
            return fail(
                ErrorKind::BadIndex,
                format!(
                    "{what}: {ptr_name} pointers decrease: {} = {a} > {} = {b}",
                    at("p", k, base),
                    at("p", k + 1, base)
                ),
            );
        }
    }
    // p[n] >= p[0] = base, so the difference is a non-negative count.
    let last = view.p.get(n);
    let count = (last - base as i64) as u64;
    let (ilen, xlen) = (view.i.len(), view.x.len());
    if count != ilen as u64 || count != xlen as u64 {
        return fail(
            ErrorKind::BadSize,
            format!(
                "{what}: {} - base = {count} entries, but i has {ilen} and x has {xlen}",
                at("p", n, base)
            ),
        );
    }
    Ok(ilen)
}

/// Checks that `x[k]` (row `r`, column `c`, 0-based) is finite.
pub(super) fn check_finite(
    what: &str,
    k: usize,
    r: usize,
    c: usize,
    v: f64,
    base: usize,
) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        fail(
            ErrorKind::NotFinite,
            format!(
                "{what}: entry {} (row {}, column {}) is {v}",
                k + base,
                r + base,
                c + base
            ),
        )
    }
}

/// Validates a view of any format and returns its entries as 0-based triplets in
/// input order, with `extra` spare capacity (for mirroring).
pub(super) fn collect(
    view: &MatrixView<'_>,
    what: &str,
    base: usize,
    extra: usize,
) -> Result<Triplets> {
    let (nrows, ncols) = (view.nrows, view.ncols);
    match view.format {
        Format::Csc | Format::Csr => {
            let nnz = check_pointers(view, what, base)?;
            let mut t = Triplets::with_capacity(nnz.saturating_add(extra))?;
            let csc = view.format == Format::Csc;
            let (n, dim) = if csc { (ncols, nrows) } else { (nrows, ncols) };
            for outer in 0..n {
                let lo = (view.p.get(outer) - base as i64) as usize;
                let hi = (view.p.get(outer + 1) - base as i64) as usize;
                for k in lo..hi {
                    let v = view.i.get(k);
                    let Some(inner) = index0(v, base, dim) else {
                        let (o, i) = if csc {
                            ("column", "row")
                        } else {
                            ("row", "column")
                        };
                        return fail(
                            ErrorKind::BadIndex,
                            format!(
                                "{what}: entry {} ({o} {}) has {i} index {v}, expected {}",
                                k + base,
                                outer + base,
                                range_text(base, dim)
                            ),
                        );
                    };
                    let (r, c) = if csc { (inner, outer) } else { (outer, inner) };
                    check_finite(what, k, r, c, view.x[k], base)?;
                    t.push(r, c, view.x[k]);
                }
            }
            Ok(t)
        }
        Format::Dense { .. } => unreachable!("dense views are read by collect_dense"),
        Format::Coo => {
            let (ilen, plen, xlen) = (view.i.len(), view.p.len(), view.x.len());
            if ilen != plen || ilen != xlen {
                return fail(
                    ErrorKind::BadSize,
                    format!(
                        "{what}: COO arrays differ in length: i (rows) has {ilen}, \
                         p (columns) has {plen}, x has {xlen}"
                    ),
                );
            }
            let mut t = Triplets::with_capacity(ilen.saturating_add(extra))?;
            for k in 0..ilen {
                let (vr, vc) = (view.i.get(k), view.p.get(k));
                let Some(r) = index0(vr, base, nrows) else {
                    return fail(
                        ErrorKind::BadIndex,
                        format!(
                            "{what}: entry {} has row index {vr}, expected {}",
                            k + base,
                            range_text(base, nrows)
                        ),
                    );
                };
                let Some(c) = index0(vc, base, ncols) else {
                    return fail(
                        ErrorKind::BadIndex,
                        format!(
                            "{what}: entry {} has column index {vc}, expected {}",
                            k + base,
                            range_text(base, ncols)
                        ),
                    );
                };
                check_finite(what, k, r, c, view.x[k], base)?;
                t.push(r, c, view.x[k]);
            }
            Ok(t)
        }
    }
}

/// The number of values a dense view of `nrows` x `ncols` with leading dimension
/// `ld` reads: `ld (ncols - 1) + nrows`, 0 for an empty matrix; `BadSize` when ld
/// < nrows or the count overflows.
pub(crate) fn dense_len(nrows: usize, ncols: usize, ld: usize, what: &str) -> Result<usize> {
    if ld < nrows {
        return fail(
            ErrorKind::BadSize,
            format!("{what}: dense leading dimension {ld} is less than nrows = {nrows}"),
        );
    }
    if nrows == 0 || ncols == 0 {
        return Ok(0);
    }
    (ncols - 1)
        .checked_mul(ld)
        .and_then(|v| v.checked_add(nrows))
        .ok_or_else(|| {
            crate::Error::new(
                ErrorKind::BadSize,
                format!("{what}: {nrows} x {ncols} with leading dimension {ld} is too large"),
            )
        })
}

/// `BadSize` unless the dense `view` (leading dimension `ld`) holds the
/// [`dense_len`] values its dimensions need.
pub(super) fn check_dense_len(view: &MatrixView<'_>, ld: usize, what: &str) -> Result<()> {
    let (nrows, ncols) = (view.nrows, view.ncols);
    let len = dense_len(nrows, ncols, ld, what)?;
    if view.x.len() < len {
        return fail(
            ErrorKind::BadSize,
            format!(
                "{what}: dense x has {} values, {nrows} x {ncols} with leading dimension {ld} \
                 needs {len}",
                view.x.len()
            ),
        );
    }
    Ok(())
}

/// `NotFinite` for the value `v` of a dense view at (r, c), 0-based, named in the
/// caller's `base` with its position in x.
pub(super) fn dense_not_finite<T>(
    what: &str,
    r: usize,
    c: usize,
    ld: usize,
    base: usize,
    v: f64,
) -> Result<T> {
    fail(
        ErrorKind::NotFinite,
        format!(
            "{what}: dense entry (row {}, column {}) = x[{}] is {v}",
            r + base,
            c + base,
            r + c * ld
        ),
    )
}

/// The nonzeros of a dense general view (N, T) as 0-based triplets, column by
/// column. Every value is checked for finiteness; messages give rows and columns
/// in `base`. (A dense K is read by `symmetric_from_dense`, every entry kept.)
pub(super) fn collect_dense(view: &MatrixView<'_>, what: &str, base: usize) -> Result<Triplets> {
    let Format::Dense { ld } = view.format else {
        unreachable!("collect_dense reads dense views");
    };
    let (nrows, ncols) = (view.nrows, view.ncols);
    check_dense_len(view, ld, what)?;
    let mut t = Triplets::default();
    for c in 0..ncols {
        for r in 0..nrows {
            let v = view.x[r + c * ld];
            if !v.is_finite() {
                return dense_not_finite(what, r, c, ld, base, v);
            }
            if v != 0.0 {
                t.push(r, c, v);
            }
        }
    }
    Ok(t)
}

/// After [`assemble`](super::assemble::assemble): every entry is finite, unless duplicates summed to an
/// infinity.
pub(super) fn check_sums_finite(a: &Csc, what: &str, base: usize) -> Result<()> {
    for j in 0..a.ncols {
        for k in a.col_ptr[j]..a.col_ptr[j + 1] {
            let v = a.values[k];
            if !v.is_finite() {
                return fail(
                    ErrorKind::NotFinite,
                    format!(
                        "{what}: duplicate entries at (row {}, column {}) sum to {v}",
                        a.row_idx[k] + base,
                        j + base
                    ),
                );
            }
        }
    }
    Ok(())
}

/// Checks |A_ij - A_ji| <= SYMMETRY_TOL * max|A| for every pair, a missing entry
/// counting as 0. `a` is square, sorted and duplicate-free.
pub(super) fn check_symmetric(a: &Csc, what: &str, base: usize) -> Result<()> {
    let max_abs = a.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let tol = SYMMETRY_TOL * max_abs;
    // Worst pair (r, c) with r < c: values A(r, c) and A(c, r) and |difference|,
    // a missing entry counting as 0.
    let mut worst: Option<(usize, usize, f64, f64, f64)> = None;
    let value = |q: Option<usize>| q.map_or(0.0, |q| a.values[q]);
    a.mirror_pairs(|r, c, upper, lower| {
        let (upper, lower) = (value(upper), value(lower));
        let diff = (upper - lower).abs();
        if diff > tol && worst.is_none_or(|w| diff > w.4) {
            worst = Some((r, c, upper, lower, diff));
        }
        true
    })
    .map_err(|e| crate::Error::new(e.kind, format!("{what}: the symmetry check: {}", e.message)))?;
    match worst {
        None => Ok(()),
        Some((r, c, upper, lower, diff)) => {
            let (r, c) = (r + base, c + base);
            fail(
                ErrorKind::NotSymmetric,
                format!(
                    "{what} is not symmetric: {what}({r},{c}) = {upper} but {what}({c},{r}) = {lower}; \
                     |difference| {diff:e} > {SYMMETRY_TOL:e} * max|{what}| = {tol:e} \
                     (a missing entry counts as 0)"
                ),
            )
        }
    }
}

/// Checks that `a` keeps the invariants of the internal form ([`Csc`]'s
/// docs): `ncols + 1` column pointers from 0, non-decreasing, ending at the
/// lengths of the index and value arrays; row indices below `nrows` and
/// strictly increasing in each column; every value finite. For matrices a
/// Rust caller built itself (`ContactProblem::from_csc` and its kin): the
/// views of the C boundary are checked as they are read instead.
///
/// Errors: `BadSize`, `BadIndex`, `NotFinite`.
pub(crate) fn check_internal(a: &Csc, what: &str) -> Result<()> {
    let n = a.ncols;
    if a.col_ptr.len() != n.saturating_add(1) {
        return fail(
            ErrorKind::BadSize,
            format!(
                "{what}: {n} columns need {} column pointers, col_ptr has {}",
                n.saturating_add(1),
                a.col_ptr.len()
            ),
        );
    }
    if a.col_ptr[0] != 0 {
        return fail(
            ErrorKind::BadIndex,
            format!("{what}: col_ptr[0] = {}, expected 0", a.col_ptr[0]),
        );
    }
    if let Some(j) = (0..n).find(|&j| a.col_ptr[j + 1] < a.col_ptr[j]) {
        return fail(
            ErrorKind::BadIndex,
            format!(
                "{what}: column pointers decrease: col_ptr[{j}] = {} > col_ptr[{}] = {}",
                a.col_ptr[j],
                j + 1,
                a.col_ptr[j + 1]
            ),
        );
    }
    let count = a.col_ptr[n];
    if a.row_idx.len() != count || a.values.len() != count {
        return fail(
            ErrorKind::BadSize,
            format!(
                "{what}: col_ptr[{n}] = {count} entries, but row_idx has {} and values {}",
                a.row_idx.len(),
                a.values.len()
            ),
        );
    }
    for j in 0..n {
        let rows = &a.row_idx[a.col_ptr[j]..a.col_ptr[j + 1]];
        for (q, &r) in rows.iter().enumerate() {
            if r >= a.nrows {
                return fail(
                    ErrorKind::BadIndex,
                    format!(
                        "{what}: row index {r} in column {j} is outside 0..{}",
                        a.nrows
                    ),
                );
            }
            if q > 0 && rows[q - 1] >= r {
                return fail(
                    ErrorKind::BadIndex,
                    format!(
                        "{what}: row indices of column {j} are not strictly increasing \
                         ({} then {r}): sort them and sum duplicates",
                        rows[q - 1]
                    ),
                );
            }
        }
    }
    for j in 0..n {
        for k in a.col_ptr[j]..a.col_ptr[j + 1] {
            if !a.values[k].is_finite() {
                return fail(
                    ErrorKind::NotFinite,
                    format!(
                        "{what}: entry (row {}, column {j}) is {}",
                        a.row_idx[k], a.values[k]
                    ),
                );
            }
        }
    }
    Ok(())
}

/// [`check_internal`] for a stiffness matrix: also square and symmetric
/// (both triangles stored, [`check_symmetric`]).
///
/// Errors: those of [`check_internal`], `BadSize`, `NotSymmetric`.
pub(crate) fn check_internal_symmetric(k: &Csc, what: &str) -> Result<()> {
    check_internal(k, what)?;
    if k.nrows != k.ncols {
        return fail(
            ErrorKind::BadSize,
            format!("{what} is {} x {}, not square", k.nrows, k.ncols),
        );
    }
    check_symmetric(k, what, 0)
}
