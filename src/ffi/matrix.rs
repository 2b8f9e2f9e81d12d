//! The borrowed sparse matrix of the C API and its translation into a
//! [`MatrixView`] (no copy: the view borrows the caller's arrays).

use super::boundary::slice_in;
use super::error::{CError as Error, CResult as Result};
use super::status::DsStatus;
use super::types::{CEnum, DsFormat, DsIndexType, DsStorage};
use crate::sparse::{Format, Indices, MatrixView};
use std::ffi::c_void;

/// A sparse matrix borrowed from the caller, with CSparse naming. The library reads
/// it during the call only; it never frees or keeps the arrays.
///
/// A CSparse `cs` or a packed `cholmod_sparse` maps field by field: format CSC (or
/// COO for a `cs` triplet matrix, nz >= 0, with nnz = nz), p, i, x; CHOLMOD stype 1
/// is DS_STORAGE_UPPER, -1 DS_STORAGE_LOWER, 0 DS_STORAGE_FULL.
///
/// Errors when a matrix is read: DS_STATUS_BAD_ARGUMENT (unknown format, index_type
/// or storage, base not 0 or 1), DS_STATUS_BAD_INDEX (last pointer below base, index
/// out of range, pointers not monotone), DS_STATUS_BAD_SIZE (negative nrows, ncols or
/// COO nnz, DENSE leading dimension below nrows), DS_STATUS_NULL_POINTER (p, i or x
/// NULL for a non-empty array), DS_STATUS_NOT_FINITE (NaN or infinity in x).
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct DsMatrix {
    /// A DsFormat value: DS_FORMAT_CSR, DS_FORMAT_CSC, DS_FORMAT_COO or
    /// DS_FORMAT_DENSE.
    pub format: i32,
    /// A DsIndexType value: p and i point to int32_t (DS_INDEX_TYPE_I32) or int64_t
    /// (DS_INDEX_TYPE_I64).
    pub index_type: i32,
    /// Index base of p and i alike: 0 (C) or 1 (Fortran).
    pub base: i32,
    /// A DsStorage value; only K may be DS_STORAGE_UPPER or DS_STORAGE_LOWER.
    pub storage: i32,
    /// Number of rows, >= 0.
    pub nrows: i64,
    /// Number of columns, >= 0.
    pub ncols: i64,
    /// COO: number of triplets (>= 0). CSR/CSC: ignored; the number of entries is
    /// `p[last] - base`. DENSE: the leading dimension (>= nrows); x holds
    /// `nnz * (ncols - 1) + nrows` values.
    pub nnz: i64,
    /// CSC: ncols+1 column pointers; CSR: nrows+1 row pointers; COO: nnz column
    /// indices. Never NULL for CSR/CSC. DENSE: not read.
    pub p: *const c_void,
    /// CSC: row indices; CSR: column indices; COO: row indices. NULL allowed when
    /// there are no entries. DENSE: not read.
    pub i: *const c_void,
    /// Values, one per entry (DENSE: column-major with leading dimension `nnz`).
    /// NULL allowed when there are no entries.
    pub x: *const f64,
}

/// A non-negative dimension field as `usize`, or `BadSize`.
fn size(value: i64, what: &str, field: &str) -> Result<usize> {
    usize::try_from(value).map_err(|_| {
        Error::new(
            DsStatus::BadSize,
            format!("{what}: {field} = {value} is negative"),
        )
    })
}

/// Borrows an index array of `len` entries of the given width.
///
/// # Safety
/// If `ptr` is not NULL and `len > 0`, it must be valid for `len` reads of the
/// width `ty` during `'a`.
unsafe fn indices<'a>(
    ptr: *const c_void,
    len: usize,
    ty: DsIndexType,
    what: &str,
) -> Result<Indices<'a>> {
    // SAFETY: forwarded contract of this function.
    unsafe {
        Ok(match ty {
            DsIndexType::I32 => Indices::I32(slice_in(ptr.cast::<i32>(), len, what)?),
            DsIndexType::I64 => Indices::I64(slice_in(ptr.cast::<i64>(), len, what)?),
        })
    }
}

impl DsMatrix {
    /// Validates the header fields and borrows the arrays as a [`MatrixView`]. `what`
    /// names the matrix in messages ("K", "N", "T"). For CSR/CSC the pointer array is
    /// read first: its last entry minus `base` gives the number of entries of `i` and
    /// `x`. Index ranges, monotonicity, finiteness and storage rules are checked by
    /// the sparse module when the view is converted.
    ///
    /// Errors: see [`DsMatrix`].
    ///
    /// # Safety
    /// `p`, `i` and `x` must be NULL or valid for reads of the lengths the fields
    /// describe, and not written during `'a`.
    pub(crate) unsafe fn view<'a>(&self, what: &str) -> Result<MatrixView<'a>> {
        let format = DsFormat::parse(self.format, &format!("{what}.format"))?;
        if format == DsFormat::Dense {
            // SAFETY: the caller guarantees x holds the values the fields describe.
            return unsafe { self.dense_view(what) };
        }
        let index_type = DsIndexType::parse(self.index_type, &format!("{what}.index_type"))?;
        let storage = DsStorage::parse(self.storage, &format!("{what}.storage"))?;
        let base = self.base_of(what)?;
        let nrows = size(self.nrows, what, "nrows")?;
        let ncols = size(self.ncols, what, "ncols")?;
        let format = match format {
            DsFormat::Csr => Format::Csr,
            DsFormat::Csc => Format::Csc,
            _ => Format::Coo,
        };
        let (p, nnz) = match format {
            Format::Csr | Format::Csc => {
                let (outer, name) = if format == Format::Csr {
                    (nrows, "nrows")
                } else {
                    (ncols, "ncols")
                };
                let plen = outer.checked_add(1).ok_or_else(|| {
                    Error::new(DsStatus::BadSize, format!("{what}: {name} is too large"))
                })?;
                let p_name = format!("{what}.p");
                // SAFETY: the caller guarantees p holds outer+1 pointers.
                let p = unsafe { indices(self.p, plen, index_type, &p_name)? };
                let last = match p {
                    Indices::I32(s) => i64::from(s[outer]),
                    Indices::I64(s) => s[outer],
                };
                let nnz = last
                    .checked_sub(base as i64)
                    .and_then(|n| usize::try_from(n).ok())
                    .ok_or_else(|| {
                        Error::new(
                            DsStatus::BadIndex,
                            format!(
                                "{what}: p[{outer}] = {last} is below base {base} \
                                 (it must be base + the number of entries)"
                            ),
                        )
                    })?;
                (p, nnz)
            }
            Format::Coo => {
                let nnz = size(self.nnz, what, "nnz")?;
                // SAFETY: the caller guarantees p holds nnz column indices.
                let p = unsafe { indices(self.p, nnz, index_type, &format!("{what}.p"))? };
                (p, nnz)
            }
            Format::Dense { .. } => unreachable!("dense views are made by dense_view"),
        };
        // SAFETY: the caller guarantees i and x hold nnz entries.
        let i = unsafe { indices(self.i, nnz, index_type, &format!("{what}.i"))? };
        // SAFETY: as above.
        let x = unsafe { slice_in(self.x, nnz, &format!("{what}.x"))? };
        Ok(MatrixView {
            format,
            storage: storage.into(),
            base,
            nrows,
            ncols,
            p,
            i,
            x,
        })
    }
}

impl DsMatrix {
    /// The index base, 0 or 1, or `BadArgument`.
    fn base_of(&self, what: &str) -> Result<usize> {
        match self.base {
            0 => Ok(0),
            1 => Ok(1),
            b => Err(Error::new(
                DsStatus::BadArgument,
                format!("{what}: base = {b} is not 0 or 1"),
            )),
        }
    }

    /// [`DsMatrix::view`] of a DS_FORMAT_DENSE matrix: `nnz` is the leading
    /// dimension; `p`, `i` and `index_type` are not read.
    ///
    /// # Safety
    /// `x` must be NULL or valid for reads of `nnz (ncols - 1) + nrows` values.
    unsafe fn dense_view<'a>(&self, what: &str) -> Result<MatrixView<'a>> {
        let storage = DsStorage::parse(self.storage, &format!("{what}.storage"))?;
        let base = self.base_of(what)?;
        let nrows = size(self.nrows, what, "nrows")?;
        let ncols = size(self.ncols, what, "ncols")?;
        let ld = size(self.nnz, what, "nnz (the dense leading dimension)")?;
        let len = crate::sparse::dense_len(nrows, ncols, ld, what)?;
        // SAFETY: the caller guarantees x holds len values.
        let x = unsafe { slice_in(self.x, len, &format!("{what}.x"))? };
        Ok(MatrixView {
            format: Format::Dense { ld },
            storage: storage.into(),
            base,
            nrows,
            ncols,
            p: Indices::I32(&[]),
            i: Indices::I32(&[]),
            x,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ptr::null;

    fn csc(p: &[i64], i: &[i64], x: &[f64], base: i32) -> DsMatrix {
        DsMatrix {
            format: DsFormat::Csc as i32,
            index_type: DsIndexType::I64 as i32,
            base,
            storage: DsStorage::Full as i32,
            nrows: 2,
            ncols: (p.len() - 1) as i64,
            nnz: -7, // ignored for CSC
            p: p.as_ptr().cast(),
            i: i.as_ptr().cast(),
            x: x.as_ptr(),
        }
    }

    #[test]
    fn csc_reads_nnz_from_p() {
        let (p, i, x) = ([1i64, 2, 4], [1i64, 1, 2], [1.0, 2.0, 3.0]);
        let m = csc(&p, &i, &x, 1);
        // SAFETY: the arrays outlive the view and match the fields.
        let v = unsafe { m.view("K") }.unwrap();
        assert_eq!((v.nrows, v.ncols, v.base, v.x.len()), (2, 2, 1, 3));
        assert!(matches!(v.i, Indices::I64(s) if s.len() == 3));
        assert!(matches!(v.p, Indices::I64(s) if s.len() == 3));
    }

    #[test]
    fn header_errors() {
        let (p, i, x) = ([0i64, 1, 3], [0i64, 0, 1], [1.0, 2.0, 3.0]);
        let good = csc(&p, &i, &x, 0);
        let zeros = [0i64; 3];
        let cases: Vec<(DsMatrix, DsStatus, &str)> = vec![
            (
                DsMatrix { format: 4, ..good },
                DsStatus::BadArgument,
                "K.format = 4",
            ),
            (
                DsMatrix {
                    index_type: -1,
                    ..good
                },
                DsStatus::BadArgument,
                "K.index_type",
            ),
            (
                DsMatrix { storage: 9, ..good },
                DsStatus::BadArgument,
                "K.storage",
            ),
            (
                DsMatrix { base: 2, ..good },
                DsStatus::BadArgument,
                "base = 2",
            ),
            (
                DsMatrix { nrows: -1, ..good },
                DsStatus::BadSize,
                "nrows = -1",
            ),
            (
                DsMatrix { ncols: -2, ..good },
                DsStatus::BadSize,
                "ncols = -2",
            ),
            (DsMatrix { p: null(), ..good }, DsStatus::NullPointer, "K.p"),
            (DsMatrix { i: null(), ..good }, DsStatus::NullPointer, "K.i"),
            (DsMatrix { x: null(), ..good }, DsStatus::NullPointer, "K.x"),
            (
                DsMatrix {
                    base: 1,
                    p: zeros.as_ptr().cast(),
                    ..good
                },
                DsStatus::BadIndex,
                "p[2] = 0 is below base 1",
            ),
        ];
        for (m, kind, text) in cases {
            // SAFETY: arrays valid for the lengths the fields give (or rejected first).
            let e = unsafe { m.view("K") }.unwrap_err();
            assert_eq!(e.status, kind, "{}", e.message);
            assert!(e.message.contains(text), "{} lacks {text}", e.message);
        }
    }

    #[test]
    fn empty_coo_accepts_null() {
        let m = DsMatrix {
            format: DsFormat::Coo as i32,
            index_type: DsIndexType::I32 as i32,
            base: 0,
            storage: DsStorage::Full as i32,
            nrows: 0,
            ncols: 5,
            nnz: 0,
            p: null(),
            i: null(),
            x: null(),
        };
        // SAFETY: no array is read (nnz = 0).
        let v = unsafe { m.view("N") }.unwrap();
        assert_eq!((v.nrows, v.ncols, v.x.len()), (0, 5, 0));
        // SAFETY: a negative nnz is rejected before any read.
        let e = unsafe { DsMatrix { nnz: -1, ..m }.view("N") }.unwrap_err();
        assert_eq!(e.status, DsStatus::BadSize);
        // SAFETY: nnz = 1 with NULL arrays is rejected before any read.
        let e = unsafe { DsMatrix { nnz: 1, ..m }.view("N") }.unwrap_err();
        assert_eq!(e.status, DsStatus::NullPointer);
    }
}
