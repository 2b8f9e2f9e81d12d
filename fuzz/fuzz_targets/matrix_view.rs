//! Fuzzes the input validation and conversion layer: `Csc::from_view` and
//! `Csc::symmetric_from_view` on arbitrary `MatrixView`s (any format, storage,
//! base, dimensions, index width, array lengths and values, including lengths
//! that do not match the dimensions). Neither may panic; an `Ok` result must
//! satisfy the documented invariants of `Csc`.
#![no_main]

use dualsplit::{Csc, Format, Indices, MatrixView, Storage};
use libfuzzer_sys::fuzz_target;

/// Reads bytes off the front of the input.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }
    fn i64(&mut self, wide: bool) -> i64 {
        // Mostly small indices (valid-ish), sometimes any value.
        let tag = self.u8();
        match tag % 8 {
            0 => {
                let mut v = [0u8; 8];
                for b in &mut v {
                    *b = self.u8();
                }
                let x = i64::from_le_bytes(v);
                if wide { x } else { i64::from(x as i32) }
            }
            1 => -i64::from(self.u8() % 4),
            _ => i64::from(self.u8() % 24),
        }
    }
    fn f64(&mut self) -> f64 {
        match self.u8() % 16 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => f64::NEG_INFINITY,
            3 => f64::MAX,
            4 => 0.0,
            5 => {
                let mut v = [0u8; 8];
                for b in &mut v {
                    *b = self.u8();
                }
                f64::from_le_bytes(v)
            }
            k => f64::from(k) - 9.5,
        }
    }
}

fn check(a: &Csc) {
    assert_eq!(a.col_ptr.len(), a.ncols + 1);
    assert_eq!(a.col_ptr[0], 0);
    assert_eq!(a.row_idx.len(), a.col_ptr[a.ncols]);
    assert_eq!(a.values.len(), a.row_idx.len());
    for j in 0..a.ncols {
        assert!(a.col_ptr[j] <= a.col_ptr[j + 1]);
        let rows = &a.row_idx[a.col_ptr[j]..a.col_ptr[j + 1]];
        assert!(
            rows.windows(2).all(|w| w[0] < w[1]),
            "rows not strictly increasing"
        );
        assert!(rows.iter().all(|&r| r < a.nrows));
    }
    assert!(a.values.iter().all(|v| v.is_finite()));
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let format = [Format::Csr, Format::Csc, Format::Coo][usize::from(b.u8() % 3)];
    let storage = [Storage::Full, Storage::Upper, Storage::Lower][usize::from(b.u8() % 3)];
    let base = usize::from(b.u8() % 3); // 2 is invalid on purpose
    let nrows = usize::from(b.u8() % 20);
    let ncols = if b.u8() % 2 == 0 {
        nrows
    } else {
        usize::from(b.u8() % 20)
    };
    let wide = b.u8() % 2 == 0;
    let np = usize::from(b.u8() % 40);
    let ni = usize::from(b.u8() % 40);
    let nx = if b.u8() % 4 == 0 {
        usize::from(b.u8() % 40)
    } else {
        ni
    };
    let p: Vec<i64> = (0..np).map(|_| b.i64(wide)).collect();
    let i: Vec<i64> = (0..ni).map(|_| b.i64(wide)).collect();
    let x: Vec<f64> = (0..nx).map(|_| b.f64()).collect();
    let (p32, i32_): (Vec<i32>, Vec<i32>) = (
        p.iter().map(|&v| v as i32).collect(),
        i.iter().map(|&v| v as i32).collect(),
    );
    let (pi, ii) = if wide {
        (Indices::I64(&p), Indices::I64(&i))
    } else {
        (Indices::I32(&p32), Indices::I32(&i32_))
    };
    let view = MatrixView {
        format,
        storage,
        base,
        nrows,
        ncols,
        p: pi,
        i: ii,
        x: &x,
    };
    if let Ok(a) = Csc::from_view(&view, "A") {
        check(&a);
        assert_eq!((a.nrows, a.ncols), (nrows, ncols));
    }
    if let Ok(a) = Csc::symmetric_from_view(&view, "K") {
        check(&a);
        assert_eq!(a.nrows, a.ncols);
    }
});
