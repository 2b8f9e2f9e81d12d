//! Matrix Market matrices, plain-text vectors and problem folders.
//!
//! A *problem folder* holds one increment problem (docs/design.md section 1) so that it
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
//! depend on d then). Sizes that do not fit together are [`ErrorKind::BadSize`].
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
//!
//! # Sizes and memory
//!
//! The readers never allocate from a size a file declares beyond what the file
//! itself, or the folder around it, justifies, and every allocation they make
//! themselves is fallible, so a tiny file declaring huge sizes is an error, at
//! once, not an abort or gigabytes of memory:
//!
//! - The entries of a matrix are stored as they are read, in room reserved for at
//!   most the declared count *and* at most what the text can hold (an entry line
//!   takes 6 bytes or more). An absurd entry count is then an `Io` error, with the
//!   line, for the missing entries.
//! - Assembling the compressed columns takes memory in O(rows + columns), which
//!   no entry count bounds (N of a large model has few entries and many columns).
//!   A matrix read on its own ([`parse_matrix`], [`read_matrix`]) may declare at
//!   most `max(`[`MAX_UNCONFIRMED_DIM`]` = 2^22, length of the file in bytes)` rows
//!   and columns; more is [`ErrorKind::BadSize`], before any allocation. In a
//!   problem folder ([`read_problem`]) the vectors confirm the sizes instead: the
//!   headers of K.mtx, N.mtx and T.mtx are read first and checked against each
//!   other and against the lengths of f.txt, g.txt and mu.txt / p.txt (which
//!   their own bytes justify), so sizes that do not fit are `BadSize`, with the
//!   files and the declared sizes named, before any entry is read.
//! - A vector has no declared length: it grows as its values are read.
//! - An allocation that fails all the same (sizes that are consistent, on a
//!   machine without the memory) is [`ErrorKind::OutOfMemory`], with the file and
//!   the declared sizes in the message.
//!
//! The `array` (dense) Matrix Market format is not read (an `Io` error on the
//! header line, before the size line), so a dense size is never allocated.

use crate::error::{Error, ErrorKind, Result};
use crate::friction::Friction;
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

/// Reads a whole file. The text is allocated fallibly by the standard library
/// (sized from the file's length): a failure is `OutOfMemory`.
fn read_text(path: &Path) -> Result<String> {
    fs::read_to_string(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::OutOfMemory {
            Error::new(
                ErrorKind::OutOfMemory,
                format!("cannot read {}: out of memory ({e})", path.display()),
            )
        } else {
            io_err(format!("cannot read {}: {e}", path.display()))
        }
    })
}

/// At most the first 60 characters of a piece of a file, for a message ("..."
/// marks a cut), so that a huge line does not make a huge message.
fn clip(s: &str) -> std::borrow::Cow<'_, str> {
    match s.char_indices().nth(60) {
        None => s.into(),
        Some((end, _)) => format!("{}...", &s[..end]).into(),
    }
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
            format!("{what} \"{}\" is not a number", clip(token)),
        )),
    }
}

/// Parses a non-negative integer (a size or a 1-based index).
fn parse_count(token: &str, path: &Path, line: usize, what: &str) -> Result<usize> {
    token.parse::<usize>().map_err(|_| {
        line_err(
            path,
            line,
            format!("{what} \"{}\" is not a non-negative integer", clip(token)),
        )
    })
}

/// Numbered lines of a text (1-based), without line terminators.
fn numbered(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().map(|(k, l)| (k + 1, l))
}

/// The banner and the size line of a Matrix Market file, read before any entry.
#[derive(Clone, Copy, Debug)]
struct Header {
    nrows: usize,
    ncols: usize,
    nnz: usize,
    symmetric: bool,
    /// 1-based number of the size line; the entries follow it.
    size_line: usize,
}

/// Reads the banner and the size line. Allocates nothing sized by the file.
fn parse_header(text: &str, path: &Path) -> Result<Header> {
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
        .take(6)
        .map(|w| w.to_ascii_lowercase())
        .collect();
    let words: Vec<&str> = words.iter().map(String::as_str).collect();
    if words.len() != 5 || words[0] != "%%matrixmarket" || words[1] != "matrix" {
        return Err(line_err(
            path,
            1,
            format!(
                "bad header \"{}\": expected \
                 %%MatrixMarket matrix coordinate real general|symmetric",
                clip(header)
            ),
        ));
    }
    if words[2] != "coordinate" {
        return Err(line_err(
            path,
            1,
            format!(
                "unsupported format \"{}\": only coordinate (sparse) matrices are read",
                clip(words[2])
            ),
        ));
    }
    if words[3] != "real" && words[3] != "integer" {
        return Err(line_err(
            path,
            1,
            format!(
                "unsupported field \"{}\": only real (or integer) entries are read",
                clip(words[3])
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
                format!(
                    "unsupported symmetry \"{}\": only general and symmetric are read",
                    clip(other)
                ),
            ));
        }
    };
    let mut content = lines.filter(|(_, l)| is_content(l));
    let Some((size_line, size_text)) = content.next() else {
        return Err(line_err(
            path,
            text.lines().count().max(1),
            "end of file before the size line \"rows columns entries\"",
        ));
    };
    let tokens: Vec<&str> = size_text.split_whitespace().take(4).collect();
    if tokens.len() != 3 {
        return Err(line_err(
            path,
            size_line,
            format!(
                "bad size line \"{}\": expected three integers \"rows columns entries\"",
                clip(size_text)
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
    Ok(Header {
        nrows,
        ncols,
        nnz,
        symmetric,
        size_line,
    })
}

/// A line of a Matrix Market file that is neither blank nor a comment.
fn is_content(line: &str) -> bool {
    let t = line.trim_start();
    !t.is_empty() && !t.starts_with('%')
}

/// "`path`: cannot allocate `what`" as [`ErrorKind::OutOfMemory`].
fn oom_err(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::new(
        ErrorKind::OutOfMemory,
        format!("{}: cannot allocate {what}", path.display()),
    )
}

/// Makes room for `additional` more elements, or fails with `OutOfMemory` naming
/// the file and `what` the room is for.
fn try_room<T>(
    v: &mut Vec<T>,
    additional: usize,
    path: &Path,
    what: impl std::fmt::Display,
) -> Result<()> {
    v.try_reserve_exact(additional)
        .map_err(|e| oom_err(path, format_args!("{what} ({e})")))
}

/// Pushes `x`, growing `v` (amortised) with a fallible allocation.
fn try_push<T>(v: &mut Vec<T>, x: T, path: &Path, what: &str) -> Result<()> {
    if v.len() == v.capacity() {
        v.try_reserve(1).map_err(|e| {
            oom_err(
                path,
                format_args!("room for {} {what} ({e})", v.len().saturating_add(1)),
            )
        })?;
    }
    v.push(x);
    Ok(())
}

/// Largest row or column count that a matrix file read on its own ([`parse_matrix`],
/// [`read_matrix`]) may declare whatever its length: 2^22 = 4,194,304. Above it a
/// dimension must not exceed the length of the file in bytes (see the module
/// documentation, "Sizes and memory").
pub const MAX_UNCONFIRMED_DIM: usize = 1 << 22;

/// The size check of a matrix read on its own: rows and columns cost memory
/// (O(rows + columns) to assemble) that a short file cannot justify.
fn check_unconfirmed(h: &Header, text: &str, path: &Path) -> Result<()> {
    let limit = MAX_UNCONFIRMED_DIM.max(text.len());
    if h.nrows <= limit && h.ncols <= limit {
        return Ok(());
    }
    Err(Error::new(
        ErrorKind::BadSize,
        format!(
            "{} line {}: declares a {} x {} matrix with {} entries in a file of {} bytes: \
             a file read on its own may declare at most max({MAX_UNCONFIRMED_DIM}, its length \
             in bytes) = {limit} rows or columns (in a problem folder the vectors confirm \
             larger sizes)",
            path.display(),
            h.size_line,
            h.nrows,
            h.ncols,
            h.nnz,
            text.len()
        ),
    ))
}

/// Parses the text of a Matrix Market file; `path` is only used in messages.
/// Returns the matrix with duplicates summed and a symmetric file mirrored.
///
/// Memory: the entries are stored as they are read, in room reserved for at most
/// the declared count and at most what the text can hold (an entry line takes 6
/// bytes or more), so an absurd entry count costs nothing; rows and columns are
/// limited to `max(`[`MAX_UNCONFIRMED_DIM`]`, text.len())` before anything of
/// their size is allocated.
///
/// Errors: `Io` for a malformed text (the message names `path` and the line);
/// `BadSize` (naming `path`, the line and the declared sizes) for a row or column
/// count above that limit; `OutOfMemory` (naming `path` and the declared sizes) if
/// an allocation fails.
pub fn parse_matrix(text: &str, path: &Path) -> Result<Csc> {
    let h = parse_header(text, path)?;
    check_unconfirmed(&h, text, path)?;
    parse_entries(text, path, &h)
}

/// Reads the entries after the header `h` (of the same text) and assembles them.
/// The dimensions of `h` have been checked by the caller.
fn parse_entries(text: &str, path: &Path, h: &Header) -> Result<Csc> {
    let Header {
        nrows,
        ncols,
        nnz,
        symmetric,
        size_line,
    } = *h;
    let declared = || format!("a {nrows} x {ncols} matrix with {nnz} entries, as declared");
    // Room for the entries, capped so that an absurd count in a short file cannot
    // exhaust memory before the count check below; it grows if ever needed.
    let cap = nnz.min(text.len() / 6 + 1);
    let mut rows: Vec<i64> = Vec::new();
    let mut cols: Vec<i64> = Vec::new();
    let mut vals: Vec<f64> = Vec::new();
    let room = || format!("room for {cap} entries of {}", declared());
    try_room(&mut rows, cap, path, room())?;
    try_room(&mut cols, cap, path, room())?;
    try_room(&mut vals, cap, path, room())?;
    // Triangle of the off-diagonal entries of a symmetric file: the first
    // off-diagonal entry fixes it (line number kept for the message).
    let mut triangle: Option<(bool, usize)> = None;
    let mut last_line = size_line;
    let content = numbered(text)
        .skip(size_line)
        .filter(|(_, l)| is_content(l));
    for (line, entry) in content {
        last_line = line;
        if vals.len() == nnz {
            return Err(line_err(
                path,
                line,
                format!("more entries than the {nnz} announced on line {size_line}"),
            ));
        }
        let tokens: Vec<&str> = entry.split_whitespace().take(4).collect();
        if tokens.len() != 3 {
            return Err(line_err(
                path,
                line,
                format!(
                    "bad entry \"{}\": expected \"row column value\"",
                    clip(entry)
                ),
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
        try_push(&mut rows, r as i64, path, "entries")?;
        try_push(&mut cols, c as i64, path, "entries")?;
        try_push(&mut vals, v, path, "entries")?;
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
    // Indices and values are already checked: what remains is an allocation that
    // fails (O(rows + columns + entries)), or duplicates summing to an infinity.
    assembled.map_err(|e| match e.kind {
        ErrorKind::OutOfMemory => oom_err(path, format_args!("{} ({})", declared(), e.message)),
        _ => io_err(format!("{}: {}", path.display(), e.message)),
    })
}

/// Reads a Matrix Market file (see the module documentation) on its own: rows
/// and columns are limited as in [`parse_matrix`] ([`read_problem`] checks a
/// folder's matrices against its vectors instead).
///
/// Errors: `Io` for a missing or malformed file, with the file name and the line;
/// `BadSize` and `OutOfMemory` as in [`parse_matrix`] (reading the text itself
/// may also fail with `OutOfMemory`).
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
///
/// Memory: the vector grows as values are read (it has no declared length), with
/// fallible allocations.
///
/// Errors: `Io` for a malformed text (the message names `path` and the line);
/// `OutOfMemory` (naming `path`) if the vector cannot grow.
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
                format!("\"{}\": expected one number per line", clip(t)),
            ));
        }
        try_push(&mut v, parse_real(t, path, line, "value")?, path, "values")?;
    }
    Ok(v)
}

/// Reads a vector file (one number per line).
///
/// Errors: `Io` for a missing or malformed file, with the file name and the line;
/// `OutOfMemory` (naming the file) if the text or the vector cannot be allocated.
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

/// A matrix file of a folder, read whole, with its header parsed.
struct MatrixFile {
    path: PathBuf,
    text: String,
    h: Header,
}

impl MatrixFile {
    fn read(path: PathBuf) -> Result<MatrixFile> {
        let text = read_text(&path)?;
        let h = parse_header(&text, &path)?;
        Ok(MatrixFile { path, text, h })
    }

    /// "line `l`: `r` x `c`", the declared size and where.
    fn size(&self) -> String {
        format!(
            "line {}: {} x {}",
            self.h.size_line, self.h.nrows, self.h.ncols
        )
    }

    fn name(&self) -> std::path::Display<'_> {
        self.path.display()
    }

    /// Reads the entries (the dimensions are checked by the caller) and frees the
    /// text.
    fn parse(self) -> Result<Csc> {
        parse_entries(&self.text, &self.path, &self.h)
    }
}

fn bad_size(message: String) -> Error {
    Error::new(ErrorKind::BadSize, message)
}

/// Reads a problem folder (see the module documentation). K is checked for
/// symmetry with the library's own test (`sparse::SYMMETRY_TOL`, the same as the C
/// API's) unless the file has a `symmetric` header.
///
/// Sizes are checked before anything of their size is allocated: first the header
/// (banner and size line) of K.mtx, N.mtx and T.mtx, then the vectors, whose
/// lengths the files themselves justify (a number takes 2 bytes or more); then K
/// must be n x n with n = len(f), N m x n with m = len(g) = len(mu or p), T
/// (d-1) m x n with d = 2 or 3 (T has no rows when m = 0). Only then are the
/// entries of the matrices read, so a file that declares sizes the folder does not
/// confirm (such as a 63-byte N.mtx declaring 3.4e8 columns) costs nothing. The
/// [`MAX_UNCONFIRMED_DIM`] limit of [`read_matrix`] does not apply here.
///
/// Errors: `Io` for a missing or malformed file (the message names the file, and
/// the line where there is one); `BadSize` for files whose sizes do not fit
/// together (the message names the files and the declared sizes); `NotSymmetric`
/// if K is not symmetric (the message names K.mtx and the pair, 1-based as in the
/// file); `OutOfMemory` if an allocation fails for sizes the folder confirms (the
/// message names the file).
pub fn read_problem(dir: &Path) -> Result<ProblemFolder> {
    if !dir.is_dir() {
        return Err(io_err(format!(
            "{}: no such folder (a problem folder holds K.mtx N.mtx T.mtx f.txt g.txt \
             and mu.txt or p.txt)",
            dir.display()
        )));
    }
    let name = |f: &str| dir.join(f).display().to_string();
    let kfile = MatrixFile::read(dir.join("K.mtx"))?;
    let nfile = MatrixFile::read(dir.join("N.mtx"))?;
    let tfile = MatrixFile::read(dir.join("T.mtx"))?;
    let (kh, nh, th) = (kfile.h, nfile.h, tfile.h);
    if kh.nrows != kh.ncols {
        return Err(bad_size(format!(
            "{}: K is {} x {} ({}), not square",
            kfile.name(),
            kh.nrows,
            kh.ncols,
            kfile.size()
        )));
    }
    let ndof = kh.nrows;
    let m = nh.nrows;
    for file in [&nfile, &tfile] {
        if file.h.ncols != ndof {
            return Err(bad_size(format!(
                "{} has {} columns ({}), but {} has {ndof} rows and columns ({})",
                file.name(),
                file.h.ncols,
                file.size(),
                kfile.name(),
                kfile.size()
            )));
        }
    }
    let d = if m == 0 {
        if th.nrows != 0 {
            return Err(bad_size(format!(
                "{} has {} rows ({}), but {} has none ({}: no contacts, so T must have none)",
                tfile.name(),
                th.nrows,
                tfile.size(),
                nfile.name(),
                nfile.size()
            )));
        }
        2
    } else if th.nrows == m {
        2
    } else if m.checked_mul(2) == Some(th.nrows) {
        3
    } else {
        return Err(bad_size(format!(
            "{} has {} rows ({}), but rows(T) must be (d-1) * rows(N) with d = 2 or 3, \
             and {} has {m} rows ({})",
            tfile.name(),
            th.nrows,
            tfile.size(),
            nfile.name(),
            nfile.size()
        )));
    };
    let vector = |file: &str, len: usize, of: &MatrixFile| -> Result<Vec<f64>> {
        let v = read_vector(&dir.join(file))?;
        if v.len() != len {
            return Err(bad_size(format!(
                "{} has {} values, expected {len} (the rows of {}, {})",
                name(file),
                v.len(),
                of.name(),
                of.size()
            )));
        }
        Ok(v)
    };
    let f = vector("f.txt", ndof, &kfile)?;
    let g = vector("g.txt", m, &nfile)?;
    let friction = match (existing(dir, "mu.txt"), existing(dir, "p.txt")) {
        (Some(_), Some(_)) => {
            return Err(io_err(format!(
                "{} holds both mu.txt (Coulomb) and p.txt (Tresca): keep only one",
                dir.display()
            )));
        }
        (Some(_), None) => FrictionData::Coulomb(vector("mu.txt", m, &nfile)?),
        (None, Some(_)) => FrictionData::Tresca(vector("p.txt", m, &nfile)?),
        (None, None) => {
            return Err(io_err(format!(
                "{} holds neither mu.txt (Coulomb coefficients) nor p.txt (Tresca bounds)",
                dir.display()
            )));
        }
    };
    // Every size is now confirmed by the vectors: read the entries, one file at a
    // time (each text is freed once parsed).
    let kpath = kfile.path.clone();
    let k = symmetric_checked(kfile.parse()?, &kpath)?;
    let n = nfile.parse()?;
    let t = tfile.parse()?;
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
    let mut rows = Vec::new();
    let mut cols = Vec::new();
    let what = || format!("the {} entries of K for its symmetry check", k.nnz());
    try_room(&mut rows, k.nnz(), path, what())?;
    try_room(&mut cols, k.nnz(), path, what())?;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An allocation that cannot succeed (more than isize::MAX bytes, refused
    /// without touching memory) is `OutOfMemory`, naming the file.
    #[test]
    fn mtx_failed_allocations_are_out_of_memory() {
        let path = Path::new("dir/X.mtx");
        let mut v: Vec<u64> = Vec::new();
        let e = try_room(&mut v, usize::MAX / 4, path, "room for the test").unwrap_err();
        assert_eq!(e.kind, ErrorKind::OutOfMemory);
        assert!(
            e.message.starts_with(&format!(
                "{}: cannot allocate room for the test",
                path.display()
            )),
            "{}",
            e.message
        );
        // Growing one by one is fallible too, and keeps amortised doubling.
        let mut v: Vec<u64> = Vec::new();
        for k in 0..100 {
            try_push(&mut v, k, path, "values").unwrap();
        }
        assert_eq!(v, (0..100).collect::<Vec<_>>());
    }

    /// The entries' room is capped by the text: an absurd count reserves nothing
    /// of its size, and the header alone allocates nothing of the declared sizes.
    #[test]
    fn mtx_header_and_unconfirmed_limit() {
        let path = Path::new("H.mtx");
        let text = "%%MatrixMarket matrix coordinate real general\n% c\n\n7 5 3\n";
        let h = parse_header(text, path).unwrap();
        assert_eq!(
            (h.nrows, h.ncols, h.nnz, h.symmetric, h.size_line),
            (7, 5, 3, false, 4)
        );
        check_unconfirmed(&h, text, path).unwrap();
        let big = Header {
            ncols: MAX_UNCONFIRMED_DIM + 1,
            ..h
        };
        let e = check_unconfirmed(&big, text, path).unwrap_err();
        assert_eq!(e.kind, ErrorKind::BadSize);
        assert!(e.message.starts_with("H.mtx line 4: "), "{}", e.message);
        // A file at least as long as the dimension confirms it.
        let long = " ".repeat(MAX_UNCONFIRMED_DIM + 1);
        check_unconfirmed(&big, &long, path).unwrap();
    }

    #[test]
    fn mtx_messages_clip_long_lines() {
        assert_eq!(clip("short"), "short");
        let long = "é".repeat(100);
        let c = clip(&long);
        assert_eq!(c.chars().count(), 63);
        assert!(c.ends_with("..."));
        let e = parse_vector(
            &format!("1\n{} 2\n", "9".repeat(10_000)),
            Path::new("v.txt"),
        )
        .unwrap_err();
        assert!(e.message.len() < 200, "{}", e.message);
    }
}
