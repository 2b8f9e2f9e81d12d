//! Matrix Market and problem folder I/O (src/mtx.rs): bit-exact round trips, the
//! symmetric header, duplicates, comments, and a line-numbered `Io` error for
//! every kind of malformed file.

use dualsplit::mtx::{self, FrictionData};
use dualsplit::{Csc, ErrorKind, Friction};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh, empty folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        static COUNT: AtomicUsize = AtomicUsize::new(0);
        let k = COUNT.fetch_add(1, Ordering::SeqCst);
        let p =
            std::env::temp_dir().join(format!("dualsplit-mtx-io-{}-{tag}-{k}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }

    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Values that a lossy writer would not reproduce.
fn tricky_values() -> Vec<f64> {
    vec![
        0.1,
        1.0 / 3.0,
        -2.0 / 7.0,
        1.0,
        -0.0,
        0.0,
        f64::MAX,
        -f64::MAX,
        f64::MIN_POSITIVE,
        f64::MIN_POSITIVE / 3.0, // subnormal
        5e-324,                  // smallest subnormal
        f64::EPSILON,
        1.0 + f64::EPSILON,
        1e8 / 7.0,
        -(2f64.sqrt()) * 1e-4,
        1e300,
        1e-300,
        std::f64::consts::PI,
        9007199254740993.0, // 2^53 + 1 rounds to 2^53
    ]
}

/// A deterministic pseudo-random sequence of doubles over many magnitudes.
fn random_values(n: usize) -> Vec<f64> {
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let mantissa = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let exp = ((s & 0x3f) as i32) - 32;
            mantissa * 10f64.powi(exp)
        })
        .collect()
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

fn assert_same_matrix(a: &Csc, b: &Csc) {
    assert_eq!((a.nrows, a.ncols), (b.nrows, b.ncols));
    assert_eq!(a.col_ptr, b.col_ptr);
    assert_eq!(a.row_idx, b.row_idx);
    assert!(
        same_bits(&a.values, &b.values),
        "values differ in their bits"
    );
}

#[test]
fn matrix_round_trip_is_bit_exact() {
    let dir = TempDir::new("matrix");
    let mut vals = tricky_values();
    vals.extend(random_values(200));
    // A 13 x 17 matrix with entries spread over it, explicit zeros included.
    let (nr, nc) = (13, 17);
    let trip: Vec<(usize, usize, f64)> = vals
        .iter()
        .enumerate()
        .map(|(k, &v)| ((k * 7) % nr, (k * 11 + k / nr) % nc, v))
        .collect();
    // Keep the first value at each position (no summation, so no rounding).
    let mut seen = std::collections::HashSet::new();
    let trip: Vec<_> = trip
        .into_iter()
        .filter(|&(r, c, _)| seen.insert((r, c)))
        .collect();
    let a = Csc::from_triplets(nr, nc, &trip);
    let path = dir.path().join("A.mtx");
    mtx::write_matrix(&path, &a).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("%%MatrixMarket matrix coordinate real general\n"));
    let b = mtx::read_matrix(&path).unwrap();
    assert_same_matrix(&a, &b);
}

#[test]
fn vector_round_trip_is_bit_exact() {
    let dir = TempDir::new("vector");
    let mut x = tricky_values();
    x.extend(random_values(1000));
    let path = dir.path().join("x.txt");
    mtx::write_vector(&path, &x).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.lines().count(), x.len(), "one number per line");
    let y = mtx::read_vector(&path).unwrap();
    assert!(same_bits(&x, &y));
    // Empty vector.
    mtx::write_vector(&path, &[]).unwrap();
    assert!(mtx::read_vector(&path).unwrap().is_empty());
}

#[test]
fn empty_matrices_round_trip() {
    let dir = TempDir::new("empty");
    for (r, c) in [(0, 0), (0, 5), (4, 0), (3, 3)] {
        let a = Csc::from_triplets(r, c, &[]);
        let path = dir.path().join("E.mtx");
        mtx::write_matrix(&path, &a).unwrap();
        assert_same_matrix(&a, &mtx::read_matrix(&path).unwrap());
    }
}

fn parse(text: &str) -> dualsplit::Result<Csc> {
    mtx::parse_matrix(text, Path::new("M.mtx"))
}

#[test]
fn symmetric_header_is_mirrored() {
    let lower = "%%MatrixMarket matrix coordinate real symmetric\n\
                 % lower triangle, as the format says\n\
                 3 3 4\n\
                 1 1 4.0\n\
                 2 1 -1.0\n\
                 3 2 -2.5\n\
                 3 3 5.0\n";
    let a = parse(lower).unwrap();
    let expect = Csc::from_triplets(
        3,
        3,
        &[
            (0, 0, 4.0),
            (1, 0, -1.0),
            (0, 1, -1.0),
            (2, 1, -2.5),
            (1, 2, -2.5),
            (2, 2, 5.0),
        ],
    );
    assert_same_matrix(&a, &expect);
    // The upper triangle is accepted too.
    let upper = "%%MatrixMarket matrix coordinate real symmetric\n\
                 3 3 4\n\
                 1 1 4.0\n\
                 1 2 -1.0\n\
                 2 3 -2.5\n\
                 3 3 5.0\n";
    assert_same_matrix(&parse(upper).unwrap(), &expect);
    // Case-insensitive keywords, integer field.
    let shouty = "%%MatrixMarket MATRIX Coordinate INTEGER Symmetric\n2 2 2\n1 1 3\n2 1 1\n";
    assert_same_matrix(
        &parse(shouty).unwrap(),
        &Csc::from_triplets(2, 2, &[(0, 0, 3.0), (1, 0, 1.0), (0, 1, 1.0)]),
    );
}

#[test]
fn symmetric_header_rejects_both_triangles() {
    let both = "%%MatrixMarket matrix coordinate real symmetric\n\
                2 2 3\n\
                1 1 4.0\n\
                2 1 -1.0\n\
                1 2 -1.0\n";
    let e = parse(both).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("M.mtx line 5"), "{}", e.message);
    assert!(e.message.contains("line 4"), "{}", e.message);
    let not_square = "%%MatrixMarket matrix coordinate real symmetric\n2 3 0\n";
    let e = parse(not_square).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("M.mtx line 2"), "{}", e.message);
}

#[test]
fn duplicates_are_summed_and_comments_skipped() {
    let text = "%%MatrixMarket matrix coordinate real general\r\n\
                % a comment\r\n\
                \r\n\
                2 3 5\r\n\
                1 1 1.5\r\n\
                % a comment between entries\r\n\
                2 3 2\r\n\
                1 1 0.25\r\n\
                \t 2  3   -3e0  \r\n\
                1 2 1.0D+01\r\n";
    let a = parse(text).unwrap();
    let expect = Csc::from_triplets(2, 3, &[(0, 0, 1.75), (1, 2, -1.0), (0, 1, 10.0)]);
    assert_same_matrix(&a, &expect);
}

/// Every malformed matrix text, with the line the error must name.
#[test]
fn malformed_matrices_name_the_line() {
    let h = "%%MatrixMarket matrix coordinate real general\n";
    let cases: Vec<(&str, String, usize)> = vec![
        ("empty file", String::new(), 1),
        ("no header", "3 3 1\n1 1 1.0\n".into(), 1),
        (
            "bad banner",
            "%%MatrixMarked matrix coordinate real general\n1 1 0\n".into(),
            1,
        ),
        (
            "short header",
            "%%MatrixMarket matrix coordinate real\n1 1 0\n".into(),
            1,
        ),
        (
            "array format",
            "%%MatrixMarket matrix array real general\n1 1\n1.0\n".into(),
            1,
        ),
        (
            "complex field",
            "%%MatrixMarket matrix coordinate complex general\n1 1 0\n".into(),
            1,
        ),
        (
            "pattern field",
            "%%MatrixMarket matrix coordinate pattern general\n1 1 0\n".into(),
            1,
        ),
        (
            "skew-symmetric",
            "%%MatrixMarket matrix coordinate real skew-symmetric\n1 1 0\n".into(),
            1,
        ),
        ("no size line", format!("{h}% only comments\n"), 2),
        ("size line with two numbers", format!("{h}%\n3 3\n"), 3),
        ("size line with four numbers", format!("{h}3 3 1 1\n"), 2),
        ("size not a number", format!("{h}3 x 1\n1 1 1\n"), 2),
        ("negative size", format!("{h}-3 3 1\n1 1 1\n"), 2),
        (
            "too few entries",
            format!("{h}3 3 3\n1 1 1.0\n2 2 1.0\n"),
            4,
        ),
        (
            "too many entries",
            format!("{h}3 3 1\n1 1 1.0\n2 2 1.0\n"),
            4,
        ),
        ("row index 0", format!("{h}3 3 1\n0 1 1.0\n"), 3),
        (
            "row index too big",
            format!("{h}3 3 2\n1 1 1.0\n4 1 1.0\n"),
            4,
        ),
        ("column index too big", format!("{h}3 3 1\n1 4 1.0\n"), 3),
        ("negative index", format!("{h}3 3 1\n-1 1 1.0\n"), 3),
        ("index not a number", format!("{h}3 3 1\n1.5 1 1.0\n"), 3),
        ("value not a number", format!("{h}3 3 1\n1 1 abc\n"), 3),
        ("value NaN", format!("{h}%\n%\n3 3 1\n1 1 NaN\n"), 5),
        ("value inf", format!("{h}3 3 2\n1 1 1\n2 2 inf\n"), 4),
        ("value -infinity", format!("{h}3 3 1\n2 2 -infinity\n"), 3),
        ("value overflows", format!("{h}3 3 1\n2 2 1e999\n"), 3),
        ("missing value", format!("{h}3 3 1\n1 1\n"), 3),
        ("extra token", format!("{h}3 3 1\n1 1 1.0 2.0\n"), 3),
    ];
    for (what, text, line) in cases {
        let e = match parse(&text) {
            Ok(_) => panic!("{what}: accepted"),
            Err(e) => e,
        };
        assert_eq!(e.kind, ErrorKind::Io, "{what}: {e}");
        let needle = format!("M.mtx line {line}:");
        assert!(
            e.message.contains(&needle),
            "{what}: message \"{}\" lacks \"{needle}\"",
            e.message
        );
    }
}

#[test]
fn duplicates_summing_to_infinity_are_rejected() {
    let text = "%%MatrixMarket matrix coordinate real general\n1 1 2\n1 1 1e308\n1 1 1e308\n";
    let e = parse(text).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("M.mtx"), "{}", e.message);
}

#[test]
fn malformed_vectors_name_the_line() {
    let path = Path::new("v.txt");
    let ok = mtx::parse_vector("1\n\n% comment\n# comment\n  -2.5e-3  \r\n3D0\n", path).unwrap();
    assert_eq!(ok, vec![1.0, -2.5e-3, 3.0]);
    for (what, text, line) in [
        ("not a number", "1\n2\nx\n", 3),
        ("NaN", "1\nNaN\n", 2),
        ("inf", "inf\n", 1),
        ("two numbers", "1\n2 3\n", 2),
        ("comma", "1,5\n", 1),
    ] {
        let e = mtx::parse_vector(text, path).unwrap_err();
        assert_eq!(e.kind, ErrorKind::Io, "{what}");
        assert!(
            e.message.contains(&format!("v.txt line {line}:")),
            "{what}: {}",
            e.message
        );
    }
}

#[test]
fn missing_file_names_the_file() {
    let dir = TempDir::new("missing");
    let path = dir.path().join("nothing.mtx");
    let e = mtx::read_matrix(&path).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("nothing.mtx"), "{}", e.message);
    let e = mtx::read_vector(&dir.path().join("nothing.txt")).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("nothing.txt"), "{}", e.message);
}

/// A small 3D problem: K SPD tridiagonal-ish (n = 9), m = 2 contacts.
struct Data {
    d: usize,
    k: Csc,
    n: Csc,
    t: Csc,
    f: Vec<f64>,
    g: Vec<f64>,
    fr: Vec<f64>,
}

fn data(d: usize, m: usize) -> Data {
    let ndof = 9;
    let mut kt = Vec::new();
    for i in 0..ndof {
        kt.push((i, i, 4.0 + 0.1 * i as f64));
        if i + 1 < ndof {
            kt.push((i, i + 1, -1.0 / 3.0));
            kt.push((i + 1, i, -1.0 / 3.0));
        }
    }
    let n = Csc::from_triplets(
        m,
        ndof,
        &(0..m).map(|i| (i, d * i, 0.7)).collect::<Vec<_>>(),
    );
    let mut tt = Vec::new();
    for i in 0..m {
        for s in 0..d - 1 {
            tt.push(((d - 1) * i + s, d * i + 1 + s, 1.0 / 7.0));
        }
    }
    let t = Csc::from_triplets((d - 1) * m, ndof, &tt);
    Data {
        d,
        k: Csc::from_triplets(ndof, ndof, &kt),
        n,
        t,
        f: random_values(ndof),
        g: (0..m).map(|i| 0.01 * i as f64 - 1.0 / 3.0).collect(),
        fr: (0..m).map(|i| 0.3 + 0.1 * i as f64).collect(),
    }
}

#[test]
fn problem_folder_round_trip() {
    for (d, m) in [(2, 3), (3, 2), (3, 3)] {
        for coulomb in [true, false] {
            let dir = TempDir::new("folder");
            let x = data(d, m);
            let fr = if coulomb {
                Friction::Coulomb(&x.fr)
            } else {
                Friction::Tresca(&x.fr)
            };
            mtx::write_problem(dir.path(), x.d, &x.k, &x.n, &x.t, &x.f, &x.g, fr).unwrap();
            let pf = mtx::read_problem(dir.path()).unwrap();
            assert_eq!(pf.d, d);
            assert_same_matrix(&pf.k, &x.k);
            assert_same_matrix(&pf.n, &x.n);
            assert_same_matrix(&pf.t, &x.t);
            assert!(same_bits(&pf.f, &x.f));
            assert!(same_bits(&pf.g, &x.g));
            match (&pf.friction, coulomb) {
                (FrictionData::Coulomb(v), true) | (FrictionData::Tresca(v), false) => {
                    assert!(same_bits(v, &x.fr))
                }
                other => panic!("wrong friction law read back: {other:?}"),
            }
            assert_eq!(pf.n_dofs(), 9);
            assert_eq!(pf.n_contacts(), m);
        }
    }
}

#[test]
fn rewriting_a_folder_replaces_the_friction_file() {
    let dir = TempDir::new("switch");
    let x = data(3, 2);
    mtx::write_problem(
        dir.path(),
        3,
        &x.k,
        &x.n,
        &x.t,
        &x.f,
        &x.g,
        Friction::Coulomb(&x.fr),
    )
    .unwrap();
    std::fs::write(dir.path().join("notes.md"), "ignored by readers").unwrap();
    mtx::write_problem(
        dir.path(),
        3,
        &x.k,
        &x.n,
        &x.t,
        &x.f,
        &x.g,
        Friction::Tresca(&x.fr),
    )
    .unwrap();
    assert!(!dir.path().join("mu.txt").exists());
    assert!(dir.path().join("notes.md").exists(), "other files are kept");
    let pf = mtx::read_problem(dir.path()).unwrap();
    assert!(matches!(pf.friction, FrictionData::Tresca(_)));
}

#[test]
fn no_contacts_reads_as_d_2() {
    let dir = TempDir::new("nocontact");
    let x = data(3, 0);
    mtx::write_problem(
        dir.path(),
        3,
        &x.k,
        &x.n,
        &x.t,
        &x.f,
        &x.g,
        Friction::Coulomb(&[]),
    )
    .unwrap();
    let pf = mtx::read_problem(dir.path()).unwrap();
    assert_eq!((pf.d, pf.n_contacts(), pf.t.nrows), (2, 0, 0));
}

#[test]
fn write_problem_rejects_inconsistent_data() {
    let dir = TempDir::new("badwrite");
    let x = data(3, 2);
    let p = dir.path();
    let fr = Friction::Coulomb(&x.fr);
    let e = mtx::write_problem(p, 4, &x.k, &x.n, &x.t, &x.f, &x.g, fr).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadArgument);
    // d = 2 with a T made for d = 3.
    let e = mtx::write_problem(p, 2, &x.k, &x.n, &x.t, &x.f, &x.g, fr).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadSize);
    let e = mtx::write_problem(p, 3, &x.k, &x.n, &x.t, &x.f[1..], &x.g, fr).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadSize);
    let e = mtx::write_problem(p, 3, &x.k, &x.n, &x.t, &x.f, &x.g[1..], fr).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadSize);
    let e = mtx::write_problem(
        p,
        3,
        &x.k,
        &x.n,
        &x.t,
        &x.f,
        &x.g,
        Friction::Tresca(&x.fr[1..]),
    )
    .unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadSize);
    let mut f = x.f.clone();
    f[2] = f64::NAN;
    let e = mtx::write_problem(p, 3, &x.k, &x.n, &x.t, &f, &x.g, fr).unwrap_err();
    assert_eq!(e.kind, ErrorKind::NotFinite);
    assert!(
        std::fs::read_dir(p).unwrap().next().is_none(),
        "nothing is written on error"
    );
}

/// Writes a valid folder, then applies `edit` to it, and returns read_problem's error.
fn folder_error(edit: impl Fn(&Path)) -> dualsplit::Error {
    let dir = TempDir::new("badfolder");
    let x = data(3, 2);
    mtx::write_problem(
        dir.path(),
        3,
        &x.k,
        &x.n,
        &x.t,
        &x.f,
        &x.g,
        Friction::Coulomb(&x.fr),
    )
    .unwrap();
    edit(dir.path());
    mtx::read_problem(dir.path()).unwrap_err()
}

#[test]
fn malformed_folders_say_which_file() {
    for file in ["K.mtx", "N.mtx", "T.mtx", "f.txt", "g.txt", "mu.txt"] {
        let e = folder_error(|p| std::fs::remove_file(p.join(file)).unwrap());
        assert_eq!(e.kind, ErrorKind::Io, "{file}");
        assert!(
            e.message.contains(file) || (file == "mu.txt" && e.message.contains("neither")),
            "{file}: {}",
            e.message
        );
    }
    let e = folder_error(|p| std::fs::write(p.join("p.txt"), "1\n1\n").unwrap());
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("both"), "{}", e.message);
    let e = folder_error(|p| std::fs::write(p.join("g.txt"), "1\n2\n3\n").unwrap());
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(
        e.message.contains("g.txt has 3 values, expected 2"),
        "{}",
        e.message
    );
    let e = folder_error(|p| std::fs::write(p.join("f.txt"), "1\nzz\n").unwrap());
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("f.txt line 2:"), "{}", e.message);
    // T with 3 rows for 2 contacts: no d fits.
    let e = folder_error(|p| {
        mtx::write_matrix(&p.join("T.mtx"), &Csc::from_triplets(3, 9, &[])).unwrap()
    });
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("T.mtx has 3 rows"), "{}", e.message);
    // N with the wrong number of columns.
    let e = folder_error(|p| {
        mtx::write_matrix(&p.join("N.mtx"), &Csc::from_triplets(2, 8, &[])).unwrap()
    });
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("N.mtx has 8 columns"), "{}", e.message);
    // K not square.
    let e = folder_error(|p| {
        mtx::write_matrix(&p.join("K.mtx"), &Csc::from_triplets(9, 8, &[])).unwrap()
    });
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("K.mtx"), "{}", e.message);
    // K not symmetric: the library's own check, 1-based as in the file.
    let e = folder_error(|p| {
        let mut k = mtx::read_matrix(&p.join("K.mtx")).unwrap();
        // Entry (1,2) (0-based (0,1)) is the second of column 2.
        let j = 1;
        let pos = (k.col_ptr[j]..k.col_ptr[j + 1])
            .find(|&q| k.row_idx[q] == 0)
            .unwrap();
        k.values[pos] *= 1.0 + 1e-6;
        mtx::write_matrix(&p.join("K.mtx"), &k).unwrap();
    });
    assert_eq!(e.kind, ErrorKind::NotSymmetric);
    assert!(e.message.contains("K.mtx"), "{}", e.message);
    assert!(e.message.contains("K(1,2)"), "{}", e.message);
    // A malformed line inside K.
    let e = folder_error(|p| {
        let text = std::fs::read_to_string(p.join("K.mtx")).unwrap();
        let mut lines: Vec<&str> = text.lines().collect();
        lines[5] = "1 1 1..0";
        std::fs::write(p.join("K.mtx"), lines.join("\n")).unwrap();
    });
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("K.mtx line 6:"), "{}", e.message);
    // Not a folder.
    let e = mtx::read_problem(Path::new("/nonexistent/dualsplit/problem")).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Io);
    assert!(e.message.contains("no such folder"), "{}", e.message);
}

#[test]
fn symmetric_k_file_is_accepted_in_a_folder() {
    let dir = TempDir::new("symk");
    let x = data(2, 2);
    mtx::write_problem(
        dir.path(),
        2,
        &x.k,
        &x.n,
        &x.t,
        &x.f,
        &x.g,
        Friction::Tresca(&x.fr),
    )
    .unwrap();
    // Rewrite K as its lower triangle with a symmetric header.
    let mut text = String::from("%%MatrixMarket matrix coordinate real symmetric\n");
    let k = &x.k;
    let lower: Vec<(usize, usize, f64)> = (0..k.ncols)
        .flat_map(|j| (k.col_ptr[j]..k.col_ptr[j + 1]).map(move |q| (k.row_idx[q], j, q)))
        .filter(|&(r, j, _)| r >= j)
        .map(|(r, j, q)| (r, j, k.values[q]))
        .collect();
    text.push_str(&format!("{} {} {}\n", k.nrows, k.ncols, lower.len()));
    for (r, c, v) in lower {
        text.push_str(&format!("{} {} {v:e}\n", r + 1, c + 1));
    }
    std::fs::write(dir.path().join("K.mtx"), text).unwrap();
    let pf = mtx::read_problem(dir.path()).unwrap();
    assert_same_matrix(&pf.k, &x.k);
}
