//! Matrix Market matrices, plain-text vectors and problem folders.
//!
//! A *problem folder* holds one increment problem (design.md section 1) so that it
//! can be taken out of a simulation, replayed alone (`dualsplit solve DIR`), sent
//! in a bug report and tried with other methods:
//!
//! | file | content |
//! |---|---|
//! | `K.mtx` | K, n x n, symmetric (both triangles, or a `symmetric` header) |
//! | `N.mtx` | N, m x n |
//! | `T.mtx` | T, (d-1) m x n, contact by contact |
//! | `f.txt` | f, n numbers |
//! | `g.txt` | g, m numbers |
//! | `mu.txt` *or* `p.txt` | Coulomb coefficients or Tresca bounds, m numbers |
//!
//! Exactly one of `mu.txt` and `p.txt` must be present. Any other file in the
//! folder is ignored. d is inferred from rows(T) = (d-1) rows(N); with no contacts
//! (m = 0) it cannot be, and d = 2 is taken (the solution, u = K^-1 f, does not
//! depend on d then).
//!
//! # Matrix Market
//!
//! Read: `%%MatrixMarket matrix coordinate real general` or `... symmetric`
//! (`integer` instead of `real` is accepted too; keywords are case-insensitive).
//! Comment lines (starting with `%`) and blank lines may appear anywhere after the
//! header line. Indices are 1-based. Duplicate entries are summed. A `symmetric`
//! file stores one triangle (the lower one, as the format says, or the upper one,
//! but not a mix) and is mirrored. Every malformed file is rejected with
//! [`ErrorKind::Io`] and a message that names the file and the line: a bad header,
//! a bad size line, an entry count that does not match the size line, an index out
//! of range, a token that is not a number, a NaN or an infinity.
//!
//! Written: `coordinate real general`, 1-based, every stored entry (explicit zeros
//! included) column by column, values in Rust's shortest round-trip exponent form
//! (`{:e}`, e.g. `-6.5119912894458026e-4`), which reads back bit for bit.
//!
//! # Vectors
//!
//! One number per line, in the same number format. Blank lines and lines starting
//! with `%` or `#` are skipped on reading.

use crate::error::{Error, ErrorKind, Result};
use crate::problem::Friction;
use crate::sparse::{Csc, Format, Indices, MatrixView, Storage};
use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// The friction data of a problem folder, owned.
#[derive(Clone, Debug, PartialEq)]
pub enum FrictionData {
    /// `p.txt`: Tresca slip bounds, one per contact.
    Tresca(Vec<f64>),
    /// `mu.txt`: Coulomb coefficients, one per contact.
    Coulomb(Vec<f64>),
}

impl FrictionData {
    /// Borrows the data as the solver's [`Friction`].
    pub fn as_friction(&self) -> Friction<'_> {
        match self {
            FrictionData::Tresca(p) => Friction::Tresca(p),
            FrictionData::Coulomb(mu) => Friction::Coulomb(mu),
        }
    }

    /// "tresca" or "coulomb".
    pub fn law_name(&self) -> &'static str {
        match self {
            FrictionData::Tresca(_) => "tresca",
            FrictionData::Coulomb(_) => "coulomb",
        }
    }

    /// The per-contact values (p or mu).
    pub fn values(&self) -> &[f64] {
        match self {
            FrictionData::Tresca(v) | FrictionData::Coulomb(v) => v,
        }
    }
}

/// One problem read from a folder by [`read_problem`].
#[derive(Clone, Debug, PartialEq)]
pub struct ProblemFolder {
    /// Contact dimension, 2 or 3 (2 when there are no contacts).
    pub d: usize,
    /// K, n x n, both triangles (checked symmetric, or mirrored from a
    /// `symmetric` file).
    pub k: Csc,
    /// N, m x n.
    pub n: Csc,
    /// T, (d-1) m x n.
    pub t: Csc,
    /// f, length n.
    pub f: Vec<f64>,
    /// g, length m.
    pub g: Vec<f64>,
    /// mu (Coulomb) or p (Tresca), length m.
    pub friction: FrictionData,
}

impl ProblemFolder {
    /// Number of DOFs n.
    pub fn n_dofs(&self) -> usize {
        self.k.nrows
    }

    /// Number of contacts m.
    pub fn n_contacts(&self) -> usize {
        self.n.nrows
    }
}

fn io_err(message: impl Into<String>) -> Error {
    Error::new(ErrorKind::Io, message)
}

/// "`path` line `line`: `what`".
fn line_err(path: &Path, line: usize, what: impl std::fmt::Display) -> Error {
    io_err(format!("{} line {line}: {what}", path.display()))
}

fn read_text(path: &Path) -> Result<String> {
    fs::read_to_string(path).map_err(|e| io_err(format!("cannot read {}: {e}", path.display())))
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    let mut file = fs::File::create(path)
        .map_err(|e| io_err(format!("cannot create {}: {e}", path.display())))?;
    file.write_all(text.as_bytes())
        .and_then(|_| file.flush())
        .map_err(|e| io_err(format!("cannot write {}: {e}", path.display())))
}

/// Parses one real number; accepts Fortran `D` exponents. Rejects NaN and
/// infinities.
fn parse_real(token: &str, path: &Path, line: usize, what: &str) -> Result<f64> {
    let parsed = token.parse::<f64>().ok().or_else(|| {
        if token.contains(['d', 'D']) {
            token.replace(['d', 'D'], "e").parse::<f64>().ok()
        } else {
            None
        }
    });
    match parsed {
        Some(v) if v.is_finite() => Ok(v),
        Some(v) => Err(line_err(
            path,
            line,
            format!("{what} is {v}: only finite numbers are allowed"),
        )),
        None => Err(line_err(
            path,
            line,
            format!("{what} \"{token}\" is not a number"),
        )),
    }
}

/// Parses a non-negative integer (a size or a 1-based index).
fn parse_count(token: &str, path: &Path, line: usize, what: &str) -> Result<usize> {
    token.parse::<usize>().map_err(|_| {
        line_err(
            path,
            line,
            format!("{what} \"{token}\" is not a non-negative integer"),
        )
    })
}

/// Numbered lines of a text (1-based), without line terminators.
fn numbered(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().map(|(k, l)| (k + 1, l))
}

/// Parses the text of a Matrix Market file; `path` is only used in messages.
/// Returns the matrix with duplicates summed and a symmetric file mirrored.
pub fn parse_matrix(text: &str, path: &Path) -> Result<Csc> {
    let mut lines = numbered(text);
    let Some((_, header)) = lines.next() else {
        return Err(line_err(
            path,
            1,
            "empty file: expected the header %%MatrixMarket matrix coordinate real general",
        ));
    };
    let words: Vec<String> = header
        .split_whitespace()
        .map(|w| w.to_ascii_lowercase())
        .collect();
    let words: Vec<&str> = words.iter().map(String::as_str).collect();
    if words.len() != 5 || words[0] != "%%matrixmarket" || words[1] != "matrix" {
        return Err(line_err(
            path,
            1,
            format!(
                "bad header \"{header}\": expected \
                 %%MatrixMarket matrix coordinate real general|symmetric"
            ),
        ));
    }
    if words[2] != "coordinate" {
        return Err(line_err(
            path,
            1,
            format!(
                "unsupported format \"{}\": only coordinate (sparse) matrices are read",
                words[2]
            ),
        ));
    }
    if words[3] != "real" && words[3] != "integer" {
        return Err(line_err(
            path,
            1,
            format!(
                "unsupported field \"{}\": only real (or integer) entries are read",
                words[3]
            ),
        ));
    }
    let symmetric = match words[4] {
        "general" => false,
        "symmetric" => true,
        other => {
            return Err(line_err(
                path,
                1,
                format!("unsupported symmetry \"{other}\": only general and symmetric are read"),
            ));
        }
    };
    let mut content = lines.filter(|(_, l)| {
        let t = l.trim_start();
        !t.is_empty() && !t.starts_with('%')
    });
    let Some((size_line, size_text)) = content.next() else {
        return Err(line_err(
            path,
            text.lines().count().max(1),
            "end of file before the size line \"rows columns entries\"",
        ));
    };
    let tokens: Vec<&str> = size_text.split_whitespace().collect();
    if tokens.len() != 3 {
        return Err(line_err(
            path,
            size_line,
            format!(
                "bad size line \"{size_text}\": expected three integers \"rows columns entries\""
            ),
        ));
    }
    let nrows = parse_count(tokens[0], path, size_line, "row count")?;
    let ncols = parse_count(tokens[1], path, size_line, "column count")?;
    let nnz = parse_count(tokens[2], path, size_line, "entry count")?;
    if symmetric && nrows != ncols {
        return Err(line_err(
            path,
            size_line,
            format!("a symmetric matrix must be square, got {nrows} x {ncols}"),
        ));
    }
    // Room for the entries, capped so that an absurd count in a short file cannot
    // exhaust memory before the count check below.
    let cap = nnz.min(text.len() / 6 + 1);
    let mut rows: Vec<i64> = Vec::with_capacity(cap);
    let mut cols: Vec<i64> = Vec::with_capacity(cap);
    let mut vals: Vec<f64> = Vec::with_capacity(cap);
    // Triangle of the off-diagonal entries of a symmetric file: the first
    // off-diagonal entry fixes it (line number kept for the message).
    let mut triangle: Option<(bool, usize)> = None;
    let mut last_line = size_line;
    for (line, entry) in content {
        last_line = line;
        if vals.len() == nnz {
            return Err(line_err(
                path,
                line,
                format!("more entries than the {nnz} announced on line {size_line}"),
            ));
        }
        let tokens: Vec<&str> = entry.split_whitespace().collect();
        if tokens.len() != 3 {
            return Err(line_err(
                path,
                line,
                format!("bad entry \"{entry}\": expected \"row column value\""),
            ));
        }
        let r = parse_count(tokens[0], path, line, "row index")?;
        let c = parse_count(tokens[1], path, line, "column index")?;
        if r == 0 || r > nrows {
            return Err(line_err(
                path,
                line,
                format!("row index {r} is out of range 1..={nrows}"),
            ));
        }
        if c == 0 || c > ncols {
            return Err(line_err(
                path,
                line,
                format!("column index {c} is out of range 1..={ncols}"),
            ));
        }
        let v = parse_real(tokens[2], path, line, "value")?;
        if symmetric && r != c {
            let lower = r > c;
            match triangle {
                None => triangle = Some((lower, line)),
                Some((tri, first)) if tri != lower => {
                    return Err(line_err(
                        path,
                        line,
                        format!(
                            "symmetric file with entries in both triangles: ({r},{c}) is in the \
                             {} triangle, but line {first} has an entry in the {} one",
                            if lower { "lower" } else { "upper" },
                            if tri { "lower" } else { "upper" }
                        ),
                    ));
                }
                Some(_) => {}
            }
        }
        rows.push(r as i64);
        cols.push(c as i64);
        vals.push(v);
    }
    if vals.len() < nnz {
        return Err(line_err(
            path,
            last_line,
            format!(
                "end of file after {} entries, but line {size_line} announces {nnz}",
                vals.len()
            ),
        ));
    }
    let storage = match (symmetric, triangle) {
        (false, _) => Storage::Full,
        (true, Some((false, _))) => Storage::Upper,
        (true, _) => Storage::Lower,
    };
    let view = MatrixView {
        format: Format::Coo,
        storage,
        base: 1,
        nrows,
        ncols,
        p: Indices::I64(&cols),
        i: Indices::I64(&rows),
        x: &vals,
    };
    let assembled = if symmetric {
        Csc::symmetric_from_view(&view, "matrix")
    } else {
        Csc::from_view(&view, "matrix")
    };
    // Indices and values are already checked: what remains is duplicates summing
    // to an infinity, or an absurd size.
    assembled.map_err(|e| io_err(format!("{}: {}", path.display(), e.message)))
}

/// Reads a Matrix Market file (see the module documentation).
///
/// Errors: `Io` for a missing or malformed file, with the file name and the line.
pub fn read_matrix(path: &Path) -> Result<Csc> {
    parse_matrix(&read_text(path)?, path)
}

/// The text of a matrix in Matrix Market `coordinate real general` form.
pub fn format_matrix(a: &Csc) -> String {
    let mut s = String::with_capacity(64 + 32 * a.nnz());
    s.push_str("%%MatrixMarket matrix coordinate real general\n");
    s.push_str("% written by dualsplit\n");
    let _ = writeln!(s, "{} {} {}", a.nrows, a.ncols, a.nnz());
    for j in 0..a.ncols {
        for k in a.col_ptr[j]..a.col_ptr[j + 1] {
            let _ = writeln!(s, "{} {} {:e}", a.row_idx[k] + 1, j + 1, a.values[k]);
        }
    }
    s
}

/// Writes a matrix in Matrix Market `coordinate real general` form, 1-based, every
/// stored entry, values with full (round-trip) precision.
///
/// Errors: `Io` if the file cannot be written.
pub fn write_matrix(path: &Path, a: &Csc) -> Result<()> {
    write_text(path, &format_matrix(a))
}

/// Parses a vector: one number per line; blank lines and lines starting with `%`
/// or `#` are skipped. `path` is only used in messages.
pub fn parse_vector(text: &str, path: &Path) -> Result<Vec<f64>> {
    let mut v = Vec::new();
    for (line, l) in numbered(text) {
        let t = l.trim();
        if t.is_empty() || t.starts_with('%') || t.starts_with('#') {
            continue;
        }
        if t.split_whitespace().nth(1).is_some() {
            return Err(line_err(
                path,
                line,
                format!("\"{t}\": expected one number per line"),
            ));
        }
        v.push(parse_real(t, path, line, "value")?);
    }
    Ok(v)
}

/// Reads a vector file (one number per line).
///
/// Errors: `Io` for a missing or malformed file, with the file name and the line.
pub fn read_vector(path: &Path) -> Result<Vec<f64>> {
    parse_vector(&read_text(path)?, path)
}

/// The text of a vector: one number per line, full (round-trip) precision.
pub fn format_vector(x: &[f64]) -> String {
    let mut s = String::with_capacity(24 * x.len());
    for v in x {
        let _ = writeln!(s, "{v:e}");
    }
    s
}

/// Writes a vector, one number per line with full (round-trip) precision.
///
/// Errors: `Io` if the file cannot be written.
pub fn write_vector(path: &Path, x: &[f64]) -> Result<()> {
    write_text(path, &format_vector(x))
}

fn check_len(name: &str, x: &[f64], len: usize, of: &str) -> Result<()> {
    if x.len() == len {
        Ok(())
    } else {
        Err(Error::new(
            ErrorKind::BadSize,
            format!("{name} has length {}, expected {len} ({of})", x.len()),
        ))
    }
}

fn check_finite(name: &str, x: &[f64]) -> Result<()> {
    match x.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::new(
            ErrorKind::NotFinite,
            format!("{name}[{i}] = {} is not finite", x[i]),
        )),
    }
}

/// Writes one increment problem to the folder `dir` (created if needed): `K.mtx`,
/// `N.mtx`, `T.mtx`, `f.txt`, `g.txt` and `mu.txt` (Coulomb) or `p.txt` (Tresca).
/// Existing files of these names are replaced, and the other friction file
/// (`p.txt` when writing `mu.txt` and the reverse) is removed, so that the folder
/// always describes exactly this problem. Other files are left alone.
///
/// `k` is written as given (pass both triangles: a reader expects a full symmetric
/// K). Nothing is checked beyond what a reader needs: shapes, finiteness, d.
///
/// Errors: `BadArgument` (d not 2 or 3), `BadSize` (shapes or lengths do not fit
/// together), `NotFinite` (a NaN or infinity, which the folder could not hold),
/// `Io` (a file cannot be written).
#[allow(clippy::too_many_arguments)]
pub fn write_problem(
    dir: &Path,
    d: usize,
    k: &Csc,
    n: &Csc,
    t: &Csc,
    f: &[f64],
    g: &[f64],
    friction: Friction<'_>,
) -> Result<()> {
    if d != 2 && d != 3 {
        return Err(Error::new(
            ErrorKind::BadArgument,
            format!("d = {d}: the contact dimension must be 2 or 3"),
        ));
    }
    let ndof = k.nrows;
    let m = n.nrows;
    let shape = |ok: bool, msg: String| {
        if ok {
            Ok(())
        } else {
            Err(Error::new(ErrorKind::BadSize, msg))
        }
    };
    shape(
        k.ncols == ndof,
        format!("K is {} x {}, not square", k.nrows, k.ncols),
    )?;
    shape(
        n.ncols == ndof,
        format!("N has {} columns, K has {ndof}", n.ncols),
    )?;
    shape(
        t.ncols == ndof,
        format!("T has {} columns, K has {ndof}", t.ncols),
    )?;
    shape(
        t.nrows == (d - 1) * m,
        format!(
            "T has {} rows, expected (d-1) * rows(N) = {}",
            t.nrows,
            (d - 1) * m
        ),
    )?;
    let (fname, other, values) = match friction {
        Friction::Coulomb(mu) => ("mu", "p", mu),
        Friction::Tresca(p) => ("p", "mu", p),
    };
    check_len("f", f, ndof, "rows of K")?;
    check_len("g", g, m, "rows of N")?;
    check_len(fname, values, m, "rows of N")?;
    for (name, a) in [("K", k), ("N", n), ("T", t)] {
        check_finite(name, &a.values)?;
    }
    check_finite("f", f)?;
    check_finite("g", g)?;
    check_finite(fname, values)?;
    fs::create_dir_all(dir)
        .map_err(|e| io_err(format!("cannot create folder {}: {e}", dir.display())))?;
    write_matrix(&dir.join("K.mtx"), k)?;
    write_matrix(&dir.join("N.mtx"), n)?;
    write_matrix(&dir.join("T.mtx"), t)?;
    write_vector(&dir.join("f.txt"), f)?;
    write_vector(&dir.join("g.txt"), g)?;
    write_vector(&dir.join(format!("{fname}.txt")), values)?;
    let stale = dir.join(format!("{other}.txt"));
    match fs::remove_file(&stale) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(io_err(format!(
            "cannot remove {} (it would contradict {fname}.txt): {e}",
            stale.display()
        ))),
        _ => Ok(()),
    }
}

/// A file of the folder that may be missing.
fn existing(dir: &Path, name: &str) -> Option<PathBuf> {
    let p = dir.join(name);
    p.is_file().then_some(p)
}

/// Reads a problem folder (see the module documentation). K is checked for
/// symmetry with the library's own test (`sparse::SYMMETRY_TOL`, the same as the C
/// API's) unless the file has a `symmetric` header.
///
/// Errors: `Io` for a missing or malformed file, or files whose sizes do not fit
/// together (the message names the files, and the line where there is one);
/// `NotSymmetric` if K is not symmetric (the message names K.mtx and the pair,
/// 1-based as in the file).
pub fn read_problem(dir: &Path) -> Result<ProblemFolder> {
    if !dir.is_dir() {
        return Err(io_err(format!(
            "{}: no such folder (a problem folder holds K.mtx N.mtx T.mtx f.txt g.txt \
             and mu.txt or p.txt)",
            dir.display()
        )));
    }
    let kpath = dir.join("K.mtx");
    let k = read_matrix(&kpath)?;
    if k.nrows != k.ncols {
        return Err(io_err(format!(
            "{}: K is {} x {}, not square",
            kpath.display(),
            k.nrows,
            k.ncols
        )));
    }
    let k = symmetric_checked(k, &kpath)?;
    let ndof = k.nrows;
    let n = read_matrix(&dir.join("N.mtx"))?;
    let t = read_matrix(&dir.join("T.mtx"))?;
    let m = n.nrows;
    let name = |f: &str| dir.join(f).display().to_string();
    for (file, a) in [("N.mtx", &n), ("T.mtx", &t)] {
        if a.ncols != ndof {
            return Err(io_err(format!(
                "{} has {} columns, but K.mtx has {ndof} rows and columns",
                name(file),
                a.ncols
            )));
        }
    }
    let d = if m == 0 {
        if t.nrows != 0 {
            return Err(io_err(format!(
                "{} has {} rows, but N.mtx has none (no contacts, so T must have none)",
                name("T.mtx"),
                t.nrows
            )));
        }
        2
    } else if t.nrows == m {
        2
    } else if t.nrows == 2 * m {
        3
    } else {
        return Err(io_err(format!(
            "{} has {} rows, but rows(T) must be (d-1) * rows(N) with d = 2 or 3, \
             and N.mtx has {m} rows",
            name("T.mtx"),
            t.nrows
        )));
    };
    let vector = |file: &str, len: usize, of: &str| -> Result<Vec<f64>> {
        let v = read_vector(&dir.join(file))?;
        if v.len() != len {
            return Err(io_err(format!(
                "{} has {} values, expected {len} ({of})",
                name(file),
                v.len()
            )));
        }
        Ok(v)
    };
    let f = vector("f.txt", ndof, "the rows of K.mtx")?;
    let g = vector("g.txt", m, "the rows of N.mtx")?;
    let friction = match (existing(dir, "mu.txt"), existing(dir, "p.txt")) {
        (Some(_), Some(_)) => {
            return Err(io_err(format!(
                "{} holds both mu.txt (Coulomb) and p.txt (Tresca): keep only one",
                dir.display()
            )));
        }
        (Some(_), None) => FrictionData::Coulomb(vector("mu.txt", m, "the rows of N.mtx")?),
        (None, Some(_)) => FrictionData::Tresca(vector("p.txt", m, "the rows of N.mtx")?),
        (None, None) => {
            return Err(io_err(format!(
                "{} holds neither mu.txt (Coulomb coefficients) nor p.txt (Tresca bounds)",
                dir.display()
            )));
        }
    };
    Ok(ProblemFolder {
        d,
        k,
        n,
        t,
        f,
        g,
        friction,
    })
}

/// Runs K (square, both triangles) through the library's symmetric validation, the
/// one the C API applies to a fully stored K, with 1-based messages.
fn symmetric_checked(k: Csc, path: &Path) -> Result<Csc> {
    let mut rows = Vec::with_capacity(k.nnz());
    let mut cols = Vec::with_capacity(k.nnz());
    for j in 0..k.ncols {
        for &r in &k.row_idx[k.col_ptr[j]..k.col_ptr[j + 1]] {
            rows.push(r as i64 + 1);
            cols.push(j as i64 + 1);
        }
    }
    let view = MatrixView {
        format: Format::Coo,
        storage: Storage::Full,
        base: 1,
        nrows: k.nrows,
        ncols: k.ncols,
        p: Indices::I64(&cols),
        i: Indices::I64(&rows),
        x: &k.values,
    };
    Csc::symmetric_from_view(&view, "K")
        .map_err(|e| Error::new(e.kind, format!("{}: {}", path.display(), e.message)))
}
