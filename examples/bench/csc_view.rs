//! A Csc matrix handed to the library as the C layer would hand it over
//! (64-bit indices), shared by the examples that call `refactor` and
//! `set_contacts`.

use dualsplit::{Csc, Format, Indices, MatrixView, Storage};

/// The matrix's index arrays as 64-bit integers (column pointers, rows).
pub fn indices(k: &Csc) -> (Vec<i64>, Vec<i64>) {
    (
        k.col_ptr.iter().map(|&v| v as i64).collect(),
        k.row_idx.iter().map(|&v| v as i64).collect(),
    )
}

/// A view of `k` over its 64-bit index arrays (from [`indices`]).
pub fn view<'a>(k: &'a Csc, (p, i): &'a (Vec<i64>, Vec<i64>)) -> MatrixView<'a> {
    MatrixView {
        format: Format::Csc,
        storage: Storage::Full,
        base: 0,
        nrows: k.nrows,
        ncols: k.ncols,
        p: Indices::I64(p),
        i: Indices::I64(i),
        x: &k.values,
    }
}
