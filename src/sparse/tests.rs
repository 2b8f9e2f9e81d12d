//! Unit tests of the sparse module.

use super::*;

/// Caller-side arrays of a matrix, held in both index widths.
struct Owned {
    format: Format,
    storage: Storage,
    base: usize,
    nrows: usize,
    ncols: usize,
    p: Vec<i64>,
    i: Vec<i64>,
    x: Vec<f64>,
    p32: Vec<i32>,
    i32: Vec<i32>,
}

impl Owned {
    fn view(&self, wide: bool) -> MatrixView<'_> {
        let (p, i) = if wide {
            (Indices::I64(&self.p), Indices::I64(&self.i))
        } else {
            (Indices::I32(&self.p32), Indices::I32(&self.i32))
        };
        MatrixView {
            format: self.format,
            storage: self.storage,
            base: self.base,
            nrows: self.nrows,
            ncols: self.ncols,
            p,
            i,
            x: &self.x,
        }
    }
}

/// Raw arrays exactly as given (for the error cases).
#[allow(clippy::too_many_arguments)]
fn raw(
    format: Format,
    storage: Storage,
    base: usize,
    nrows: usize,
    ncols: usize,
    p: &[i64],
    i: &[i64],
    x: &[f64],
) -> Owned {
    let narrow = |v: &[i64]| {
        v.iter()
            .map(|&a| a.clamp(i32::MIN as i64, i32::MAX as i64) as i32)
            .collect()
    };
    Owned {
        format,
        storage,
        base,
        nrows,
        ncols,
        p: p.to_vec(),
        i: i.to_vec(),
        x: x.to_vec(),
        p32: narrow(p),
        i32: narrow(i),
    }
}

/// Encodes 0-based triplets in the given format and base, keeping their order
/// within each compressed column/row (so unsorted triplets give unsorted input).
fn encode(
    format: Format,
    storage: Storage,
    base: usize,
    nrows: usize,
    ncols: usize,
    trip: &[(usize, usize, f64)],
) -> Owned {
    let b = base as i64;
    let (p, i, x) = match format {
        Format::Coo => (
            trip.iter().map(|t| t.1 as i64 + b).collect(),
            trip.iter().map(|t| t.0 as i64 + b).collect(),
            trip.iter().map(|t| t.2).collect(),
        ),
        Format::Dense { .. } => unreachable!("the sparse tests lay out sparse formats"),
        Format::Csc | Format::Csr => {
            let csc = format == Format::Csc;
            let n = if csc { ncols } else { nrows };
            let key = |t: &(usize, usize, f64)| if csc { (t.1, t.0) } else { (t.0, t.1) };
            let mut p = vec![b; n + 1];
            let mut i = Vec::new();
            let mut x = Vec::new();
            for outer in 0..n {
                for t in trip.iter().filter(|t| key(t).0 == outer) {
                    i.push(key(t).1 as i64 + b);
                    x.push(t.2);
                }
                p[outer + 1] = i.len() as i64 + b;
            }
            (p, i, x)
        }
    };
    raw(format, storage, base, nrows, ncols, &p, &i, &x)
}

fn dense_to_csc(a: &[Vec<f64>], ncols: usize) -> Csc {
    let nrows = a.len();
    let mut col_ptr = vec![0];
    let mut row_idx = Vec::new();
    let mut values = Vec::new();
    for j in 0..ncols {
        for (r, row) in a.iter().enumerate() {
            if row[j] != 0.0 {
                row_idx.push(r);
                values.push(row[j]);
            }
        }
        col_ptr.push(row_idx.len());
    }
    Csc {
        nrows,
        ncols,
        col_ptr,
        row_idx,
        values,
    }
}

fn csc_to_dense(a: &Csc) -> Vec<Vec<f64>> {
    let mut d = vec![vec![0.0; a.ncols]; a.nrows];
    for (j, cols) in a.col_ptr.windows(2).enumerate() {
        for k in cols[0]..cols[1] {
            d[a.row_idx[k]][j] += a.values[k];
        }
    }
    d
}

/// Checks the internal-form invariants.
fn assert_valid(a: &Csc) {
    assert_eq!(a.col_ptr.len(), a.ncols + 1);
    assert_eq!(a.col_ptr[0], 0);
    assert_eq!(a.row_idx.len(), a.nnz());
    assert_eq!(a.values.len(), a.nnz());
    for j in 0..a.ncols {
        assert!(a.col_ptr[j] <= a.col_ptr[j + 1]);
        let rows = &a.row_idx[a.col_ptr[j]..a.col_ptr[j + 1]];
        assert!(
            rows.windows(2).all(|w| w[0] < w[1]),
            "column {j} not strictly sorted"
        );
        assert!(rows.iter().all(|&r| r < a.nrows));
    }
}

/// Nonzero triplets of a dense matrix in reverse column-major order (unsorted
/// within every column and row), optionally restricted by `keep(r, c)`.
fn triplets_of(a: &[Vec<f64>], keep: impl Fn(usize, usize) -> bool) -> Vec<(usize, usize, f64)> {
    let mut t = Vec::new();
    for (r, row) in a.iter().enumerate() {
        for (c, &v) in row.iter().enumerate() {
            if v != 0.0 && keep(r, c) {
                t.push((r, c, v));
            }
        }
    }
    t.reverse();
    t
}

fn k_dense() -> Vec<Vec<f64>> {
    vec![
        vec![4.0, 1.0, 0.0, 2.0],
        vec![1.0, 5.0, 1.0, 0.0],
        vec![0.0, 1.0, 6.0, 1.0],
        vec![2.0, 0.0, 1.0, 7.0],
    ]
}

fn n_dense() -> Vec<Vec<f64>> {
    vec![vec![1.0, 0.0, -1.0, 0.0], vec![0.0, 2.0, 0.0, 3.0]]
}

const FORMATS: [Format; 3] = [Format::Csr, Format::Csc, Format::Coo];

fn err_of(r: Result<Csc>) -> crate::error::Error {
    match r {
        Ok(a) => panic!("expected an error, got {a:?}"),
        Err(e) => e,
    }
}

fn general_err(o: &Owned) -> crate::error::Error {
    let e64 = err_of(Csc::from_view(&o.view(true), "N"));
    let e32 = err_of(Csc::from_view(&o.view(false), "N"));
    assert_eq!(e64.kind, e32.kind);
    e64
}

fn sym_err(o: &Owned) -> crate::error::Error {
    err_of(Csc::symmetric_from_view(&o.view(true), "K"))
}

#[test]
fn general_all_formats_bases_widths_agree() {
    let expect = dense_to_csc(&n_dense(), 4);
    let trip = triplets_of(&n_dense(), |_, _| true);
    for format in FORMATS {
        for base in [0, 1] {
            let o = encode(format, Storage::Full, base, 2, 4, &trip);
            for wide in [false, true] {
                let a = Csc::from_view(&o.view(wide), "N").unwrap();
                assert_valid(&a);
                assert_eq!(a, expect, "{format:?} base {base} wide {wide}");
            }
        }
    }
}

#[test]
fn symmetric_all_formats_bases_widths_storages_agree() {
    let k = k_dense();
    let expect = dense_to_csc(&k, 4);
    for (storage, keep) in [
        (Storage::Full, (|_, _| true) as fn(usize, usize) -> bool),
        (Storage::Upper, |r, c| r <= c),
        (Storage::Lower, |r, c| r >= c),
    ] {
        let trip = triplets_of(&k, keep);
        for format in FORMATS {
            for base in [0, 1] {
                let o = encode(format, storage, base, 4, 4, &trip);
                for wide in [false, true] {
                    let a = Csc::symmetric_from_view(&o.view(wide), "K").unwrap();
                    assert_valid(&a);
                    assert_eq!(a, expect, "{storage:?} {format:?} base {base} wide {wide}");
                }
            }
        }
    }
}

#[test]
fn mixed_index_widths() {
    let o = encode(
        Format::Csc,
        Storage::Full,
        1,
        2,
        4,
        &triplets_of(&n_dense(), |_, _| true),
    );
    let v = MatrixView {
        p: Indices::I32(&o.p32),
        i: Indices::I64(&o.i),
        ..o.view(true)
    };
    assert_eq!(
        Csc::from_view(&v, "N").unwrap(),
        dense_to_csc(&n_dense(), 4)
    );
}

#[test]
fn duplicates_are_summed_in_every_format() {
    let k = k_dense();
    let expect = dense_to_csc(&k, 4);
    for (storage, keep) in [
        (Storage::Full, (|_, _| true) as fn(usize, usize) -> bool),
        (Storage::Upper, |r, c| r <= c),
        (Storage::Lower, |r, c| r >= c),
    ] {
        // Every entry split into 1/4 + 3/4 (exact in binary), interleaved.
        let base_trip = triplets_of(&k, keep);
        let mut trip: Vec<_> = base_trip
            .iter()
            .map(|&(r, c, v)| (r, c, 0.25 * v))
            .collect();
        trip.extend(base_trip.iter().rev().map(|&(r, c, v)| (r, c, 0.75 * v)));
        for format in FORMATS {
            for base in [0, 1] {
                let o = encode(format, storage, base, 4, 4, &trip);
                assert_eq!(o.x.len(), 2 * base_trip.len());
                let a = Csc::symmetric_from_view(&o.view(true), "K").unwrap();
                assert_valid(&a);
                assert_eq!(a, expect, "{storage:?} {format:?} base {base}");
            }
        }
    }
}

#[test]
fn unsorted_csc_is_sorted_and_summed() {
    // 3 x 2: column 0 given as rows 2, 0, 2, 1; column 1 as rows 1, 0.
    let o = raw(
        Format::Csc,
        Storage::Full,
        0,
        3,
        2,
        &[0, 4, 6],
        &[2, 0, 2, 1, 1, 0],
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
    );
    let a = Csc::from_view(&o.view(false), "N").unwrap();
    assert_eq!(
        a,
        Csc {
            nrows: 3,
            ncols: 2,
            col_ptr: vec![0, 3, 5],
            row_idx: vec![0, 1, 2, 0, 1],
            values: vec![2.0, 4.0, 4.0, 6.0, 5.0],
        }
    );
}

#[test]
fn explicit_zeros_are_kept() {
    // An explicit zero and two duplicates cancelling to zero stay in the pattern.
    let trip = [(0, 0, 1.0), (1, 2, 0.0), (0, 3, 2.5), (0, 3, -2.5)];
    for format in FORMATS {
        let o = encode(format, Storage::Full, 0, 2, 4, &trip);
        let a = Csc::from_view(&o.view(true), "N").unwrap();
        assert_eq!(a.col_ptr, vec![0, 1, 1, 2, 3]);
        assert_eq!(a.row_idx, vec![0, 1, 0]);
        assert_eq!(a.values, vec![1.0, 0.0, 0.0]);
    }
    // Also for K: an explicit zero off the diagonal is mirrored.
    let trip = [(0, 0, 1.0), (0, 1, 0.0), (1, 1, 1.0)];
    let o = encode(Format::Coo, Storage::Upper, 0, 2, 2, &trip);
    let a = Csc::symmetric_from_view(&o.view(true), "K").unwrap();
    assert_eq!(a.nnz(), 4);
    assert_eq!(a.values, vec![1.0, 0.0, 0.0, 1.0]);
}

#[test]
fn empty_matrices() {
    for base in [0, 1] {
        let b = base as i64;
        // 0 x 0 K.
        for format in FORMATS {
            let p: &[i64] = if format == Format::Coo { &[] } else { &[b] };
            let o = raw(format, Storage::Upper, base, 0, 0, p, &[], &[]);
            let a = Csc::symmetric_from_view(&o.view(true), "K").unwrap();
            assert_eq!(a, Csc::from_triplets(0, 0, &[]));
            assert_eq!(a.col_ptr, vec![0]);
        }
        // 0 x 4 N (no contacts) and 3 x 4 with no entries.
        let o = raw(Format::Csc, Storage::Full, base, 0, 4, &[b; 5], &[], &[]);
        let a = Csc::from_view(&o.view(false), "N").unwrap();
        assert_eq!((a.nrows, a.ncols, a.nnz()), (0, 4, 0));
        let o = raw(Format::Csr, Storage::Full, base, 0, 4, &[b], &[], &[]);
        let a = Csc::from_view(&o.view(false), "N").unwrap();
        assert_eq!((a.nrows, a.ncols, a.col_ptr.len()), (0, 4, 5));
        let o = raw(Format::Coo, Storage::Full, base, 3, 4, &[], &[], &[]);
        let a = Csc::from_view(&o.view(false), "N").unwrap();
        assert_eq!((a.nrows, a.ncols, a.col_ptr), (3, 4, vec![0; 5]));
    }
}

/// A small deterministic generator (xorshift).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn random_with_duplicates_against_dense() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    for _ in 0..50 {
        let (m, n) = (1 + rng.below(7), 1 + rng.below(7));
        let nnz = rng.below(3 * m * n);
        let trip: Vec<_> = (0..nnz)
            .map(|_| (rng.below(m), rng.below(n), (rng.below(9) as f64) - 4.0))
            .collect();
        let mut dense = vec![vec![0.0; n]; m];
        let mut present = vec![vec![false; n]; m];
        for &(r, c, v) in &trip {
            dense[r][c] += v;
            present[r][c] = true;
        }
        let expect = Csc::from_triplets(m, n, &trip);
        assert_valid(&expect);
        assert_eq!(csc_to_dense(&expect), dense);
        let npattern = present.iter().flatten().filter(|&&b| b).count();
        assert_eq!(expect.nnz(), npattern);
        for format in FORMATS {
            for base in [0, 1] {
                let o = encode(format, Storage::Full, base, m, n, &trip);
                for wide in [false, true] {
                    assert_eq!(Csc::from_view(&o.view(wide), "N").unwrap(), expect);
                }
            }
        }
    }
}

#[test]
fn from_triplets_sums_and_sorts() {
    let a = Csc::from_triplets(3, 3, &[(2, 1, 1.0), (0, 1, 2.0), (2, 1, 3.0), (1, 0, 0.0)]);
    assert_eq!(
        a,
        Csc {
            nrows: 3,
            ncols: 3,
            col_ptr: vec![0, 1, 3, 3],
            row_idx: vec![1, 0, 2],
            values: vec![0.0, 2.0, 4.0],
        }
    );
}

#[test]
#[should_panic(expected = "outside 2 x 3")]
fn from_triplets_panics_out_of_range() {
    Csc::from_triplets(2, 3, &[(0, 0, 1.0), (2, 0, 1.0)]);
}

#[test]
fn transpose_and_products_against_dense() {
    let mut rng = Rng(12345);
    let mats = [
        (dense_to_csc(&n_dense(), 4), n_dense()),
        (dense_to_csc(&k_dense(), 4), k_dense()),
    ];
    let mut all: Vec<(Csc, Vec<Vec<f64>>)> = mats.to_vec();
    for _ in 0..20 {
        let (m, n) = (1 + rng.below(6), 1 + rng.below(6));
        let trip: Vec<_> = (0..rng.below(2 * m * n))
            .map(|_| (rng.below(m), rng.below(n), rng.below(11) as f64 - 5.0))
            .collect();
        let a = Csc::from_triplets(m, n, &trip);
        let d = csc_to_dense(&a);
        all.push((a, d));
    }
    for (a, d) in &all {
        let (m, n) = (a.nrows, a.ncols);
        let at = a.transpose();
        assert_valid(&at);
        assert_eq!((at.nrows, at.ncols, at.nnz()), (n, m, a.nnz()));
        let dt = csc_to_dense(&at);
        for r in 0..m {
            for c in 0..n {
                assert_eq!(dt[c][r], d[r][c]);
            }
        }
        assert_eq!(&at.transpose(), a);
        let x: Vec<f64> = (0..n).map(|j| 1.0 + j as f64 * 0.5).collect();
        let z: Vec<f64> = (0..m).map(|i| 2.0 - i as f64).collect();
        let mut y = vec![f64::NAN; m];
        a.mul_vec(&x, &mut y);
        for r in 0..m {
            let e: f64 = (0..n).map(|c| d[r][c] * x[c]).sum();
            assert!((y[r] - e).abs() <= 1e-12 * (1.0 + e.abs()));
        }
        let mut w = vec![f64::NAN; n];
        a.mul_t_vec(&z, &mut w);
        for c in 0..n {
            let e: f64 = (0..m).map(|r| d[r][c] * z[r]).sum();
            assert!((w[c] - e).abs() <= 1e-12 * (1.0 + e.abs()));
        }
    }
}

// ----- errors -----

#[test]
fn base_other_than_0_or_1() {
    let o = encode(
        Format::Csc,
        Storage::Full,
        2,
        2,
        4,
        &triplets_of(&n_dense(), |_, _| true),
    );
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::BadArgument);
    assert!(
        e.message.contains("base must be 0 or 1, got 2"),
        "{}",
        e.message
    );
    let o = encode(Format::Coo, Storage::Upper, 2, 4, 4, &[(0, 0, 1.0)]);
    assert_eq!(sym_err(&o).kind, ErrorKind::BadArgument);
}

#[test]
fn triangle_storage_rejected_for_general() {
    for storage in [Storage::Upper, Storage::Lower] {
        let o = encode(Format::Coo, storage, 0, 2, 2, &[(0, 0, 1.0)]);
        let e = general_err(&o);
        assert_eq!(e.kind, ErrorKind::BadArgument);
        assert!(
            e.message.starts_with("N: storage must be Full"),
            "{}",
            e.message
        );
    }
}

#[test]
fn length_mismatches() {
    let x3 = [1.0, 2.0, 3.0];
    // CSC: p too short, too long, empty.
    for p in [&[0i64, 1, 3][..], &[0, 1, 2, 3, 3, 3], &[]] {
        let o = raw(Format::Csc, Storage::Full, 0, 2, 4, p, &[0, 1, 1], &x3);
        let e = general_err(&o);
        assert_eq!(e.kind, ErrorKind::BadSize, "{}", e.message);
        assert!(
            e.message.contains("needs 5 column pointers"),
            "{}",
            e.message
        );
    }
    // CSR: wrong number of row pointers.
    let o = raw(
        Format::Csr,
        Storage::Full,
        0,
        2,
        4,
        &[0, 3],
        &[0, 1, 1],
        &x3,
    );
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::BadSize);
    assert!(
        e.message.contains("needs 3 row pointers, p has 2"),
        "{}",
        e.message
    );
    // i shorter / longer than p[n] - base, x shorter.
    for (i, x) in [
        (&[0i64, 1][..], &x3[..]),
        (&[0, 1, 1, 0], &x3),
        (&[0, 1, 1], &x3[..2]),
    ] {
        let o = raw(Format::Csc, Storage::Full, 1, 2, 4, &[1, 2, 3, 4, 4], i, x);
        let e = general_err(&o);
        assert_eq!(e.kind, ErrorKind::BadSize);
        assert!(
            e.message.contains("p(5) - base = 3 entries"),
            "{}",
            e.message
        );
    }
    // COO: the three arrays differ.
    for (p, i, x) in [
        (&[0i64, 1][..], &[0i64, 1, 1][..], &x3[..]),
        (&[0, 1, 2], &[0, 1], &x3),
        (&[0, 1, 2], &[0, 1, 1], &x3[..1]),
    ] {
        let o = raw(Format::Coo, Storage::Full, 0, 2, 4, p, i, x);
        let e = general_err(&o);
        assert_eq!(e.kind, ErrorKind::BadSize);
        assert!(
            e.message.contains("COO arrays differ in length"),
            "{}",
            e.message
        );
    }
    // Huge pointer total must not be mistaken for a small one.
    let o = raw(
        Format::Csc,
        Storage::Full,
        0,
        2,
        1,
        &[0, i64::MAX],
        &[0],
        &[1.0],
    );
    assert_eq!(
        err_of(Csc::from_view(&o.view(true), "N")).kind,
        ErrorKind::BadSize
    );
}

#[test]
fn pointer_not_starting_at_base() {
    for (base, p0) in [(0usize, 1i64), (1, 0), (0, -1), (1, 2)] {
        let b = base as i64;
        let p = [p0, b + 1, b + 2, b + 3, b + 3];
        let o = raw(
            Format::Csc,
            Storage::Full,
            base,
            2,
            4,
            &p,
            &[b, b, b],
            &[1.0; 3],
        );
        let e = general_err(&o);
        assert_eq!(e.kind, ErrorKind::BadIndex, "{}", e.message);
        assert!(
            e.message.contains("expected the index base"),
            "{}",
            e.message
        );
    }
    let o = raw(
        Format::Csr,
        Storage::Full,
        0,
        2,
        2,
        &[i64::MIN, 0, 0],
        &[],
        &[],
    );
    assert_eq!(
        err_of(Csc::from_view(&o.view(true), "N")).kind,
        ErrorKind::BadIndex
    );
}

#[test]
fn decreasing_pointer() {
    let o = raw(
        Format::Csc,
        Storage::Full,
        0,
        2,
        4,
        &[0, 2, 1, 3, 3],
        &[0, 1, 1],
        &[1.0; 3],
    );
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::BadIndex);
    assert_eq!(
        e.message,
        "N: column pointers decrease: p[1] = 2 > p[2] = 1"
    );
    let o = raw(
        Format::Csr,
        Storage::Full,
        1,
        2,
        4,
        &[1, 3, 2],
        &[1, 2],
        &[1.0; 2],
    );
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::BadIndex);
    assert_eq!(e.message, "N: row pointers decrease: p(2) = 3 > p(3) = 2");
}

#[test]
fn index_out_of_range() {
    // The message of the brief, for a 10 x 4 CSC with row 12 at entry 17.
    let mut i = vec![0i64; 20];
    i[17] = 12;
    let o = raw(
        Format::Csc,
        Storage::Full,
        0,
        10,
        4,
        &[0, 5, 10, 15, 20],
        &i,
        &[1.0; 20],
    );
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::BadIndex);
    assert_eq!(
        e.message,
        "N: entry 17 (column 3) has row index 12, expected 0..10"
    );

    // Base 1: 0 is out of range, as is nrows + 1; numbers in the caller's base.
    for bad in [
        0i64,
        3,
        -1,
        i64::MIN,
        i64::MAX,
        i32::MIN as i64,
        u32::MAX as i64 + 1,
    ] {
        let o = raw(
            Format::Csc,
            Storage::Full,
            1,
            2,
            2,
            &[1, 2, 3],
            &[1, bad],
            &[1.0; 2],
        );
        let e = err_of(Csc::from_view(&o.view(true), "N"));
        assert_eq!(e.kind, ErrorKind::BadIndex);
        assert_eq!(
            e.message,
            format!("N: entry 2 (column 2) has row index {bad}, expected 1..=2")
        );
    }
    // Negative i32 indices.
    for bad in [-1i64, i32::MIN as i64] {
        let o = raw(
            Format::Coo,
            Storage::Full,
            0,
            2,
            2,
            &[0, 1],
            &[bad, 1],
            &[1.0; 2],
        );
        let e = err_of(Csc::from_view(&o.view(false), "N"));
        assert_eq!(e.kind, ErrorKind::BadIndex);
        assert_eq!(
            e.message,
            format!("N: entry 0 has row index {bad}, expected 0..2")
        );
        let o = raw(
            Format::Coo,
            Storage::Full,
            0,
            2,
            2,
            &[0, bad],
            &[0, 1],
            &[1.0; 2],
        );
        let e = err_of(Csc::from_view(&o.view(false), "N"));
        assert_eq!(e.kind, ErrorKind::BadIndex);
        assert_eq!(
            e.message,
            format!("N: entry 1 has column index {bad}, expected 0..2")
        );
    }
    // CSR: the inner index is a column.
    let o = raw(
        Format::Csr,
        Storage::Full,
        0,
        2,
        4,
        &[0, 1, 2],
        &[3, 4],
        &[1.0; 2],
    );
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::BadIndex);
    assert_eq!(
        e.message,
        "N: entry 1 (row 1) has column index 4, expected 0..4"
    );
    // COO column too large.
    let o = raw(Format::Coo, Storage::Full, 1, 2, 4, &[5], &[1], &[1.0]);
    assert_eq!(general_err(&o).kind, ErrorKind::BadIndex);
    // Any index into a dimension of size 0.
    let o = raw(Format::Coo, Storage::Full, 0, 0, 4, &[0], &[0], &[1.0]);
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::BadIndex);
    assert!(e.message.contains("dimension is 0"), "{}", e.message);
    // K too.
    let o = raw(
        Format::Coo,
        Storage::Upper,
        0,
        2,
        2,
        &[0, 2],
        &[0, 1],
        &[1.0; 2],
    );
    assert_eq!(sym_err(&o).kind, ErrorKind::BadIndex);
}

#[test]
fn non_finite_values() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for format in FORMATS {
            let trip = [(0, 0, 1.0), (1, 3, bad)];
            let o = encode(format, Storage::Full, 1, 2, 4, &trip);
            let e = general_err(&o);
            assert_eq!(e.kind, ErrorKind::NotFinite);
            assert_eq!(e.message, format!("N: entry 2 (row 2, column 4) is {bad}"));
            let o = encode(format, Storage::Lower, 0, 2, 2, &[(1, 0, bad)]);
            assert_eq!(sym_err(&o).kind, ErrorKind::NotFinite);
        }
    }
    // Finite duplicates whose sum overflows.
    let o = encode(
        Format::Coo,
        Storage::Full,
        0,
        2,
        2,
        &[(1, 0, 1e308), (1, 0, 1e308)],
    );
    let e = general_err(&o);
    assert_eq!(e.kind, ErrorKind::NotFinite);
    assert!(
        e.message.contains("(row 1, column 0) sum to inf"),
        "{}",
        e.message
    );
    let o = encode(
        Format::Coo,
        Storage::Upper,
        0,
        2,
        2,
        &[(0, 0, -1e308), (0, 0, -1e308)],
    );
    assert_eq!(sym_err(&o).kind, ErrorKind::NotFinite);
}

#[test]
fn entry_in_wrong_triangle() {
    let k = k_dense();
    // Upper storage given the full matrix: the first stored entry below the
    // diagonal is reported, in the caller's base.
    let o = encode(
        Format::Coo,
        Storage::Upper,
        1,
        4,
        4,
        &[(0, 0, 4.0), (3, 0, 2.0)],
    );
    let e = sym_err(&o);
    assert_eq!(e.kind, ErrorKind::BadIndex);
    assert_eq!(
        e.message,
        "K stored as upper triangle has entry (4,1) below the diagonal (entry 2)"
    );
    let o = encode(
        Format::Csc,
        Storage::Lower,
        0,
        4,
        4,
        &[(0, 0, 4.0), (1, 3, 0.0)],
    );
    let e = sym_err(&o);
    assert_eq!(e.kind, ErrorKind::BadIndex);
    assert_eq!(
        e.message,
        "K stored as lower triangle has entry (1,3) above the diagonal (entry 1)"
    );
    for format in FORMATS {
        for (storage, keep) in [
            (Storage::Upper, (|r, c| r >= c) as fn(usize, usize) -> bool),
            (Storage::Lower, |r, c| r <= c),
        ] {
            let o = encode(format, storage, 0, 4, 4, &triplets_of(&k, keep));
            assert_eq!(
                sym_err(&o).kind,
                ErrorKind::BadIndex,
                "{format:?} {storage:?}"
            );
            let o = encode(format, storage, 0, 4, 4, &triplets_of(&k, |_, _| true));
            assert_eq!(
                sym_err(&o).kind,
                ErrorKind::BadIndex,
                "{format:?} {storage:?}"
            );
        }
    }
}

#[test]
fn symmetry_check() {
    let k = k_dense();
    // A perturbation within tolerance is accepted and kept as given.
    let mut kp = k.clone();
    kp[0][3] += 7.0 * SYMMETRY_TOL * 0.5;
    for format in FORMATS {
        let o = encode(
            format,
            Storage::Full,
            0,
            4,
            4,
            &triplets_of(&kp, |_, _| true),
        );
        let a = Csc::symmetric_from_view(&o.view(true), "K").unwrap();
        assert_eq!(a, dense_to_csc(&kp, 4));
    }
    // Beyond tolerance: the worst pair is named, in the caller's base.
    let mut kb = k.clone();
    kb[0][1] = 1.0 + 1e-6;
    kb[3][2] = 1.5;
    for format in FORMATS {
        let o = encode(
            format,
            Storage::Full,
            1,
            4,
            4,
            &triplets_of(&kb, |_, _| true),
        );
        let e = sym_err(&o);
        assert_eq!(e.kind, ErrorKind::NotSymmetric);
        assert!(
            e.message
                .starts_with("K is not symmetric: K(3,4) = 1 but K(4,3) = 1.5;"),
            "{}",
            e.message
        );
    }
    // A missing counterpart counts as 0 (here only the lower entry is stored).
    let trip = triplets_of(&k, |r, c| !(r == 0 && c == 3));
    let o = encode(Format::Csr, Storage::Full, 0, 4, 4, &trip);
    let e = sym_err(&o);
    assert_eq!(e.kind, ErrorKind::NotSymmetric);
    assert!(
        e.message
            .starts_with("K is not symmetric: K(0,3) = 0 but K(3,0) = 2;"),
        "{}",
        e.message
    );
    // A missing counterpart of an explicit zero is fine.
    let mut trip = triplets_of(&k, |_, _| true);
    trip.push((1, 3, 0.0));
    let o = encode(Format::Coo, Storage::Full, 0, 4, 4, &trip);
    let a = Csc::symmetric_from_view(&o.view(true), "K").unwrap();
    assert_eq!(a.nnz(), dense_to_csc(&k, 4).nnz() + 1);
    // Duplicates are summed before the check.
    let trip = [
        (0, 1, 1.0),
        (0, 1, 1.0),
        (1, 0, 2.0),
        (0, 0, 1.0),
        (1, 1, 1.0),
    ];
    let o = encode(Format::Coo, Storage::Full, 0, 2, 2, &trip);
    assert!(Csc::symmetric_from_view(&o.view(true), "K").is_ok());
}

#[test]
fn non_square_k() {
    for storage in [Storage::Full, Storage::Upper, Storage::Lower] {
        let o = encode(Format::Csc, storage, 0, 2, 4, &[(0, 0, 1.0)]);
        let e = sym_err(&o);
        assert_eq!(e.kind, ErrorKind::BadSize);
        assert_eq!(e.message, "K must be square, got 2 x 4");
    }
}

#[test]
fn absurd_dimensions_do_not_panic() {
    let o = raw(
        Format::Coo,
        Storage::Full,
        0,
        usize::MAX / 2,
        3,
        &[],
        &[],
        &[],
    );
    assert_eq!(general_err(&o).kind, ErrorKind::OutOfMemory);
    let o = raw(Format::Coo, Storage::Full, 0, 3, usize::MAX, &[], &[], &[]);
    assert_eq!(general_err(&o).kind, ErrorKind::OutOfMemory);
    let o = raw(Format::Csc, Storage::Full, 0, 3, usize::MAX, &[0], &[], &[]);
    assert_eq!(general_err(&o).kind, ErrorKind::BadSize);
}

/// A whole symmetric K in CSC (`symmetric_from_view`'s fast path where the
/// rows are in order): in order, unsorted, with a duplicate split in two,
/// base 0 and 1, it gives the same Csc; a NaN or an index out of range in
/// ordered arrays is still named by the general path.
#[test]
fn symmetric_csc_in_order_or_not_agrees() {
    // K = [[4, 1, 0], [1, 5, 2], [0, 2, 6]].
    let expect = Csc {
        nrows: 3,
        ncols: 3,
        col_ptr: vec![0, 2, 5, 7],
        row_idx: vec![0, 1, 0, 1, 2, 1, 2],
        values: vec![4.0, 1.0, 1.0, 5.0, 2.0, 2.0, 6.0],
    };
    let cases: [(&[i64], &[i64], &[f64]); 3] = [
        (
            &[0, 2, 5, 7],
            &[0, 1, 0, 1, 2, 1, 2],
            &[4.0, 1.0, 1.0, 5.0, 2.0, 2.0, 6.0],
        ),
        (
            &[0, 2, 5, 7],
            &[1, 0, 2, 1, 0, 2, 1],
            &[1.0, 4.0, 2.0, 5.0, 1.0, 6.0, 2.0],
        ),
        (
            &[0, 3, 6, 8],
            &[0, 1, 0, 0, 1, 2, 1, 2],
            &[4.0, 1.0, 0.0, 1.0, 5.0, 2.0, 2.0, 6.0],
        ),
    ];
    for (p, i, x) in cases {
        for base in [0i64, 1] {
            let pb: Vec<i64> = p.iter().map(|v| v + base).collect();
            let ib: Vec<i64> = i.iter().map(|v| v + base).collect();
            let o = raw(Format::Csc, Storage::Full, base as usize, 3, 3, &pb, &ib, x);
            let a = Csc::symmetric_from_view(&o.view(false), "K").unwrap();
            assert_valid(&a);
            assert_eq!(a, expect, "{i:?} base {base}");
        }
    }
    let (p, i) = (&[0i64, 2, 5, 7], &[0i64, 1, 0, 1, 2, 1, 2]);
    let nan = raw(
        Format::Csc,
        Storage::Full,
        0,
        3,
        3,
        p,
        i,
        &[4.0, 1.0, 1.0, f64::NAN, 2.0, 2.0, 6.0],
    );
    assert_eq!(sym_err(&nan).kind, ErrorKind::NotFinite);
    let far = raw(
        Format::Csc,
        Storage::Full,
        0,
        3,
        3,
        p,
        &[0, 1, 0, 1, 3, 1, 2],
        &[4.0, 1.0, 1.0, 5.0, 2.0, 2.0, 6.0],
    );
    assert_eq!(sym_err(&far).kind, ErrorKind::BadIndex);
}

/// The symmetry check without a copy of K: an entry whose mirror is missing
/// is found whichever side it is on and wherever it lies (its mirror counts
/// as 0), and the worst pair is named.
#[test]
fn symmetry_check_finds_an_entry_on_one_side_anywhere() {
    let n = 6;
    for (r, c) in [(0, 5), (5, 0), (2, 3), (3, 2), (1, 4)] {
        let mut t: Vec<(usize, usize, f64)> = (0..n).map(|i| (i, i, 4.0)).collect();
        t.extend([(0, 1, -1.0), (1, 0, -1.0), (4, 5, -1.0), (5, 4, -1.0)]);
        t.push((r, c, 0.5));
        let a = Csc::from_triplets(n, n, &t);
        let e = super::validate::check_symmetric(&a, "K", 1).unwrap_err();
        assert_eq!(e.kind, ErrorKind::NotSymmetric);
        let (lo, hi) = (r.min(c) + 1, r.max(c) + 1);
        assert!(
            e.message.contains(&format!("K({lo},{hi})")),
            "({r}, {c}): {}",
            e.message
        );
        // Its mirror within the tolerance: symmetric.
        t.push((c, r, 0.5 * (1.0 + 1e-12)));
        let a = Csc::from_triplets(n, n, &t);
        assert!(super::validate::check_symmetric(&a, "K", 1).is_ok());
    }
}
