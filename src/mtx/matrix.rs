//! Matrix Market files (coordinate or array, real, general or symmetric) and the vectors of a
//! folder (one number per line): parse, read, format, write.

use super::text::*;
use crate::error::{Error, ErrorKind, Result};
use crate::sparse::{Csc, Format, Indices, MatrixView, Storage};
use std::fmt::Write as _;
use std::path::Path;

/// The banner and the size line of a Matrix Market file, read before any entry.
#[derive(Clone, Copy, Debug)]
pub(super) struct Header {
    pub(super) nrows: usize,
    pub(super) ncols: usize,
    pub(super) nnz: usize,
    pub(super) symmetric: bool,
    /// `array` (dense, one value per line, column-major; symmetric: the lower
    /// triangle) rather than `coordinate`.
    pub(super) array: bool,
    /// 1-based number of the size line; the entries follow it.
    pub(super) size_line: usize,
}

/// Reads the banner and the size line. Allocates nothing sized by the file.
pub(super) fn parse_header(text: &str, path: &Path) -> Result<Header> {
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
    let array = match words[2] {
        "coordinate" => false,
        "array" => true,
        other => {
            return Err(line_err(
                path,
                1,
                format!(
                    "unsupported format \"{}\": only coordinate and array matrices are read",
                    clip(other)
                ),
            ));
        }
    };
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
    let (want, form) = if array {
        (2, "two integers \"rows columns\" (array)")
    } else {
        (3, "three integers \"rows columns entries\"")
    };
    if tokens.len() != want {
        return Err(line_err(
            path,
            size_line,
            format!("bad size line \"{}\": expected {form}", clip(size_text)),
        ));
    }
    let nrows = parse_count(tokens[0], path, size_line, "row count")?;
    let ncols = parse_count(tokens[1], path, size_line, "column count")?;
    if symmetric && nrows != ncols {
        return Err(line_err(
            path,
            size_line,
            format!("a symmetric matrix must be square, got {nrows} x {ncols}"),
        ));
    }
    // An array holds every value (symmetric: the lower triangle).
    let nnz = match (array, symmetric) {
        (false, _) => Some(parse_count(tokens[2], path, size_line, "entry count")?),
        (true, true) => nrows.checked_mul(nrows.saturating_add(1)).map(|v| v / 2),
        (true, false) => nrows.checked_mul(ncols),
    };
    let Some(nnz) = nnz else {
        return Err(line_err(
            path,
            size_line,
            format!("a {nrows} x {ncols} array has too many entries"),
        ));
    };
    Ok(Header {
        nrows,
        ncols,
        nnz,
        symmetric,
        array,
        size_line,
    })
}

/// A line of a Matrix Market file that is neither blank nor a comment.
pub(super) fn is_content(line: &str) -> bool {
    let t = line.trim_start();
    !t.is_empty() && !t.starts_with('%')
}

/// Largest row or column count that a matrix file read on its own ([`parse_matrix`],
/// [`read_matrix`]) may declare whatever its length: 2^22 = 4,194,304. Above it a
/// dimension must not exceed the length of the file in bytes (see the module
/// documentation, "Sizes and memory").
pub const MAX_UNCONFIRMED_DIM: usize = 1 << 22;

/// The size check of a matrix read on its own: rows and columns cost memory
/// (O(rows + columns) to assemble) that a short file cannot justify.
pub(super) fn check_unconfirmed(h: &Header, text: &str, path: &Path) -> Result<()> {
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
pub(super) fn parse_entries(text: &str, path: &Path, h: &Header) -> Result<Csc> {
    let Header {
        nrows,
        ncols,
        nnz,
        symmetric,
        array,
        size_line,
    } = *h;
    let declared = || format!("a {nrows} x {ncols} matrix with {nnz} entries, as declared");
    // Room for the entries, capped so that an absurd count in a short file cannot
    // exhaust memory before the count check below; it grows if ever needed (an
    // entry line takes 6 bytes or more, an array value 2).
    let cap = nnz.min(text.len() / if array { 2 } else { 6 } + 1);
    // The array position of the k-th value: column-major, the lower triangle of
    // a symmetric file.
    let (mut next_r, mut next_c) = (0usize, 0usize);
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
        if array {
            if tokens.len() != 1 {
                return Err(line_err(
                    path,
                    line,
                    format!("bad array value \"{}\": expected one number", clip(entry)),
                ));
            }
            let v = parse_real(tokens[0], path, line, "value")?;
            try_push(&mut rows, next_r as i64 + 1, path, "entries")?;
            try_push(&mut cols, next_c as i64 + 1, path, "entries")?;
            try_push(&mut vals, v, path, "entries")?;
            next_r += 1;
            if next_r == nrows {
                next_c += 1;
                next_r = if symmetric { next_c } else { 0 };
            }
            continue;
        }
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
    // Array files keep every value (zeros too): a dense K stays dense.
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
/// and columns are limited as in [`parse_matrix`] ([`super::read_problem`] checks a
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

/// As [`parse_vector`], with `inf` (or `+inf`, `infinity`, any case) read as
/// +infinity: the interface files, where it means a rigid contact.
pub(super) fn parse_vector_with_inf(text: &str, path: &Path) -> Result<Vec<f64>> {
    let mut v = Vec::new();
    for (line, l) in numbered(text) {
        let t = l.trim();
        if t.is_empty() || t.starts_with('%') || t.starts_with('#') {
            continue;
        }
        let word = t.trim_start_matches('+').to_ascii_lowercase();
        let x = if word == "inf" || word == "infinity" {
            f64::INFINITY
        } else {
            parse_real(t, path, line, "value")?
        };
        try_push(&mut v, x, path, "values")?;
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
