//! Reading and writing the text of a problem folder's files: errors that name the
//! file and line, numbers parsed with their context, and allocations that fail
//! into `OutOfMemory` instead of aborting.

use crate::error::{Error, ErrorKind, Result};
use std::fs;
use std::io::Write as _;
use std::path::Path;

pub(super) fn io_err(message: impl Into<String>) -> Error {
    Error::new(ErrorKind::Io, message)
}

/// "`path` line `line`: `what`".
pub(super) fn line_err(path: &Path, line: usize, what: impl std::fmt::Display) -> Error {
    io_err(format!("{} line {line}: {what}", path.display()))
}

/// Reads a whole file. The text is allocated fallibly by the standard library
/// (sized from the file's length): a failure is `OutOfMemory`.
pub(super) fn read_text(path: &Path) -> Result<String> {
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
pub(super) fn clip(s: &str) -> std::borrow::Cow<'_, str> {
    match s.char_indices().nth(60) {
        None => s.into(),
        Some((end, _)) => format!("{}...", &s[..end]).into(),
    }
}

pub(super) fn write_text(path: &Path, text: &str) -> Result<()> {
    let mut file = fs::File::create(path)
        .map_err(|e| io_err(format!("cannot create {}: {e}", path.display())))?;
    file.write_all(text.as_bytes())
        .and_then(|_| file.flush())
        .map_err(|e| io_err(format!("cannot write {}: {e}", path.display())))
}

/// Parses one real number; accepts Fortran `D` exponents. Rejects NaN and
/// infinities.
pub(super) fn parse_real(token: &str, path: &Path, line: usize, what: &str) -> Result<f64> {
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
pub(super) fn parse_count(token: &str, path: &Path, line: usize, what: &str) -> Result<usize> {
    token.parse::<usize>().map_err(|_| {
        line_err(
            path,
            line,
            format!("{what} \"{}\" is not a non-negative integer", clip(token)),
        )
    })
}

/// Numbered lines of a text (1-based), without line terminators.
pub(super) fn numbered(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().map(|(k, l)| (k + 1, l))
}

/// "`path`: cannot allocate `what`" as [`ErrorKind::OutOfMemory`].
pub(super) fn oom_err(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::new(
        ErrorKind::OutOfMemory,
        format!("{}: cannot allocate {what}", path.display()),
    )
}

/// Makes room for `additional` more elements, or fails with `OutOfMemory` naming
/// the file and `what` the room is for.
pub(super) fn try_room<T>(
    v: &mut Vec<T>,
    additional: usize,
    path: &Path,
    what: impl std::fmt::Display,
) -> Result<()> {
    v.try_reserve_exact(additional)
        .map_err(|e| oom_err(path, format_args!("{what} ({e})")))
}

/// Pushes `x`, growing `v` (amortised) with a fallible allocation.
pub(super) fn try_push<T>(v: &mut Vec<T>, x: T, path: &Path, what: &str) -> Result<()> {
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
