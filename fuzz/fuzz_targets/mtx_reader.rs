//! Fuzzes the Matrix Market reader on arbitrary text: `mtx::parse_matrix` and
//! `mtx::parse_vector` must return an error or a valid matrix, never panic; a
//! matrix that parses must survive `format_matrix` and parse again to the same
//! matrix.
#![no_main]

use dualsplit::mtx;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz.mtx");
    if let Ok(a) = mtx::parse_matrix(text, path) {
        assert_eq!(a.col_ptr.len(), a.ncols + 1);
        assert_eq!(a.row_idx.len(), a.values.len());
        let again =
            mtx::parse_matrix(&mtx::format_matrix(&a), path).expect("a written matrix parses");
        assert_eq!((again.nrows, again.ncols), (a.nrows, a.ncols));
        assert_eq!(again.col_ptr, a.col_ptr);
        assert_eq!(again.row_idx, a.row_idx);
        for (x, y) in again.values.iter().zip(&a.values) {
            assert!(x == y || (x.is_nan() && y.is_nan()), "{x} vs {y}");
        }
    }
    let _ = mtx::parse_vector(text, Path::new("fuzz.vec"));
});
