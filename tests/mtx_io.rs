//! Matrix Market and problem folder I/O (src/mtx.rs): bit-exact round trips, the
//! symmetric header, duplicates, comments, a line-numbered `Io` error for every
//! kind of malformed file, and sizes declared beyond what a file or its folder
//! justifies rejected (`BadSize`) at once, before anything of that size is
//! allocated.

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
            "sparse format name",
            "%%MatrixMarket matrix sparse real general\n1 1 1\n1 1 1.0\n".into(),
            1,
        ),
        (
            "array with a short value list",
            "%%MatrixMarket matrix array real general\n2 1\n1.0\n".into(),
            3,
        ),
        (
            "array value not a number",
            "%%MatrixMarket matrix array real general\n2 1\n1.0\nx\n".into(),
            4,
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
    assert_eq!(e.kind, ErrorKind::BadSize);
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
    assert_eq!(e.kind, ErrorKind::BadSize);
    assert!(e.message.contains("T.mtx has 3 rows"), "{}", e.message);
    // N with the wrong number of columns.
    let e = folder_error(|p| {
        mtx::write_matrix(&p.join("N.mtx"), &Csc::from_triplets(2, 8, &[])).unwrap()
    });
    assert_eq!(e.kind, ErrorKind::BadSize);
    assert!(e.message.contains("N.mtx has 8 columns"), "{}", e.message);
    // K not square.
    let e = folder_error(|p| {
        mtx::write_matrix(&p.join("K.mtx"), &Csc::from_triplets(9, 8, &[])).unwrap()
    });
    assert_eq!(e.kind, ErrorKind::BadSize);
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

// ---------------------------------------------------------------------------------
// Declared sizes that the file, or its folder, does not justify. Each must be
// answered at once (nothing of the declared size is allocated), with a message
// that names the file: `BadSize` for sizes that a file read on its own may not
// declare or that do not fit the folder, `Io` for an entry count the file does
// not hold or a format that is not read.

/// Runs `f` and returns its error. That nothing of the declared size was allocated
/// shows in the kind of the error (an allocation of the declared sizes was
/// OutOfMemory, or aborted the process); how fast the answer comes is the
/// benchmark's business, not a test's.
fn quick_error<T: std::fmt::Debug>(
    what: &str,
    f: impl FnOnce() -> dualsplit::Result<T>,
) -> dualsplit::Error {
    match f() {
        Ok(v) => panic!("{what}: accepted: {v:?}"),
        Err(e) => e,
    }
}

const COORD: &str = "%%MatrixMarket matrix coordinate real general\n";

#[test]
fn huge_declared_dimensions_are_bad_size_at_once() {
    // 4e8 x 4e8 with one entry: 63 bytes that asked for 4 arrays of 3.2 GB.
    let huge = format!("{COORD}400000000 400000000 1\n1 1 1.0\n");
    let e = quick_error("4e8 x 4e8", || parse(&huge));
    assert_eq!(e.kind, ErrorKind::BadSize, "{e}");
    assert!(e.message.contains("M.mtx line 2:"), "{}", e.message);
    assert!(e.message.contains("400000000 x 400000000"), "{}", e.message);
    // The same from a file: the message names it.
    let dir = TempDir::new("huge");
    let path = dir.path().join("Huge.mtx");
    std::fs::write(&path, &huge).unwrap();
    let e = quick_error("4e8 x 4e8 file", || mtx::read_matrix(&path));
    assert_eq!(e.kind, ErrorKind::BadSize, "{e}");
    assert!(e.message.contains("Huge.mtx line 2:"), "{}", e.message);
    // Symmetric header, and one huge dimension only (rows or columns), and the
    // fuzz seeds: no rows but 3.4e8 columns, 5.6e17 rows, 2^62 rows.
    for (what, size) in [
        (
            "symmetric",
            "%%MatrixMarket matrix coordinate real symmetric\n400000000 400000000 1\n1 1 1.0\n"
                .to_string(),
        ),
        ("rows", format!("{COORD}400000000 3 1\n1 1 1.0\n")),
        ("columns", format!("{COORD}3 400000000 1\n1 1 1.0\n")),
        ("no rows", format!("{COORD}%%\n0 344444444 0\n")),
        (
            "5.6e17 rows",
            format!("{COORD}555555555555555553 3 1\n1 1 1.0\n"),
        ),
        (
            "2^62 rows",
            format!("{COORD}4611686018427387904 3 1\n1 1 2.0\n"),
        ),
        ("usize::MAX", format!("{COORD}{} 1 0\n", usize::MAX)),
    ] {
        let e = quick_error(what, || parse(&size));
        assert_eq!(e.kind, ErrorKind::BadSize, "{what}: {e}");
        assert!(e.message.contains("M.mtx line"), "{what}: {}", e.message);
    }
}

#[test]
fn unconfirmed_dimension_limit_is_the_larger_of_the_floor_and_the_file_length() {
    let limit = mtx::MAX_UNCONFIRMED_DIM;
    assert_eq!(limit, 1 << 22);
    // At the floor: accepted, whatever the file's length.
    let a = parse(&format!("{COORD}1 {limit} 1\n1 {limit} 2.5\n")).unwrap();
    assert_eq!((a.nrows, a.ncols, a.nnz()), (1, limit, 1));
    assert_eq!(a.col_ptr[limit], 1);
    // One more: rejected, in a short file...
    let over = limit + 1;
    let e = parse(&format!("{COORD}{over} 1 0\n")).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadSize, "{e}");
    // ...but accepted from a file at least that long (here a long comment).
    let mut text = format!("{COORD}{over} 1 1\n{over} 1 -1\n%");
    text.push_str(&" ".repeat(over.saturating_sub(text.len())));
    text.push('\n');
    let a = parse(&text).unwrap();
    assert_eq!(
        (a.nrows, a.ncols, a.row_idx.clone()),
        (over, 1, vec![over - 1])
    );
}

#[test]
fn huge_entry_count_is_an_io_error_at_once() {
    let text = format!("{COORD}3 3 1000000000000\n1 1 1.0\n");
    let e = quick_error("1e12 entries", || parse(&text));
    assert_eq!(e.kind, ErrorKind::Io, "{e}");
    assert!(
        e.message
            .contains("M.mtx line 3: end of file after 1 entries"),
        "{}",
        e.message
    );
    let text = format!("{COORD}3 3 {}\n", usize::MAX);
    let e = quick_error("usize::MAX entries", || parse(&text));
    assert_eq!(e.kind, ErrorKind::Io, "{e}");
    assert!(e.message.contains("M.mtx line 2:"), "{}", e.message);
}

/// A dense `array` file declaring 1e9 x 1 in a few bytes is refused on its size
/// line before anything of that size is allocated (as a coordinate file's rows).
/// A vector file with such a header is rejected on the size line (two numbers on
/// a line).
#[test]
fn array_header_with_huge_size_is_rejected_at_once() {
    let text = "%%MatrixMarket matrix array real general\n1000000000 1\n1.0\n2.0\n";
    let e = quick_error("array 1e9", || parse(text));
    assert_eq!(e.kind, ErrorKind::BadSize, "{e}");
    assert!(e.message.contains("M.mtx line 2:"), "{}", e.message);
    // Within the dimension limit, an absurd value count is cheap too: the room
    // is capped by the text, and the missing values are an error.
    let text = "%%MatrixMarket matrix array real general\n4000000 4000000\n1.0\n";
    let e = quick_error("array 1.6e13 values", || parse(text));
    assert_eq!(e.kind, ErrorKind::Io, "{e}");
    assert!(
        e.message.contains("end of file after 1 entries"),
        "{}",
        e.message
    );
    let e = quick_error("array 1e9 as a vector", || {
        mtx::parse_vector(text, Path::new("v.txt"))
    });
    assert_eq!(e.kind, ErrorKind::Io, "{e}");
    assert!(e.message.contains("v.txt line 2:"), "{}", e.message);
}

/// A huge matrix in a folder is checked against the other files before its
/// entries are read: `BadSize`, naming the files and the declared sizes.
#[test]
fn folder_with_huge_declared_dimensions_is_bad_size_at_once() {
    let huge_k = format!("{COORD}400000000 400000000 1\n1 1 1.0\n");
    // (what, files replaced, pieces of the message)
    type Case = (&'static str, Vec<(&'static str, String)>, Vec<&'static str>);
    let cases: Vec<Case> = vec![
        (
            "huge K",
            vec![("K.mtx", huge_k.clone())],
            vec![
                "N.mtx has 9 columns",
                "K.mtx has 400000000 rows and columns",
            ],
        ),
        (
            "huge N (the fuzz seed)",
            vec![("N.mtx", format!("{COORD}%%\n0 344444444 0\n"))],
            vec!["N.mtx has 344444444 columns", "K.mtx has 9 rows"],
        ),
        (
            "huge T",
            vec![("T.mtx", format!("{COORD}400000000 9 0\n"))],
            vec!["T.mtx has 400000000 rows", "N.mtx has 2 rows"],
        ),
        (
            "huge K, N, T that agree, but f.txt has 9 values",
            vec![
                ("K.mtx", huge_k.clone()),
                ("N.mtx", format!("{COORD}2 400000000 0\n")),
                ("T.mtx", format!("{COORD}4 400000000 0\n")),
            ],
            vec![
                "f.txt has 9 values, expected 400000000",
                "K.mtx, line 2: 400000000 x 400000000",
            ],
        ),
        (
            "huge N and T rows that agree, but g.txt has 2 values",
            vec![
                ("N.mtx", format!("{COORD}400000000 9 0\n")),
                ("T.mtx", format!("{COORD}800000000 9 0\n")),
            ],
            vec![
                "g.txt has 2 values, expected 400000000",
                "N.mtx, line 2: 400000000 x 9",
            ],
        ),
    ];
    for (what, files, needles) in cases {
        let e = quick_error(what, || {
            let e = folder_error(|p| {
                for (name, text) in &files {
                    std::fs::write(p.join(name), text).unwrap();
                }
            });
            Err::<(), _>(e)
        });
        assert_eq!(e.kind, ErrorKind::BadSize, "{what}: {e}");
        for needle in needles {
            assert!(e.message.contains(needle), "{what}: {}", e.message);
        }
    }
}

/// The inputs the fuzz target `mtx_reader` found (fuzz/seeds/mtx_reader_regressions),
/// replayed without nightly: each is answered at once, never with `OutOfMemory`
/// (none is large enough to need memory), and those known to declare huge sizes
/// are `BadSize`.
#[test]
fn fuzz_regression_seeds_are_answered_at_once() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds/mtx_reader_regressions");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let Ok(text) = std::fs::read_to_string(&path) else {
            continue;
        };
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let r = mtx::parse_matrix(&text, &path);
        let _ = mtx::parse_vector(&text, &path);
        if let Err(e) = &r {
            assert_ne!(e.kind, ErrorKind::OutOfMemory, "{name}: {e}");
            assert!(e.message.contains(&name), "{name}: {}", e.message);
        }
        let huge = [
            "crash-be393bab4797ec7a3b6af2890daef459843162ec",
            "oom-9ce59e6c99040e32c17d83779f6d9d66a34cd350",
            "oom-e61455419cf76244db0a79667aa1508d2bebdd73",
        ];
        if huge.contains(&name.as_str()) {
            let e = r.expect_err(&name);
            assert_eq!(e.kind, ErrorKind::BadSize, "{name}: {e}");
            seen += 1;
        }
    }
    assert_eq!(seen, 3, "the known seeds are in {}", dir.display());
}
