//! The library's error type: a kind (mapped one to one onto the C status codes)
//! and a human-readable message.

use std::fmt;

/// What went wrong. Each kind maps onto one C status code (see `ffi::status`;
/// the C API has statuses of its own besides: a NULL pointer, a caught panic).
/// A solve that does not converge is not an error: it is
/// [`crate::SolveStatus`] in the report. Later versions may add kinds
/// (`#[non_exhaustive]`).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// An array length or matrix dimension is inconsistent.
    BadSize,
    /// A sparse index is out of range or a pointer array is not monotone.
    BadIndex,
    /// A NaN or infinity was found in the input.
    NotFinite,
    /// K is not symmetric within the documented tolerance.
    NotSymmetric,
    /// The Cholesky factorisation of K met a non-positive pivot.
    NotPositiveDefinite,
    /// A Tresca bound p or a Coulomb coefficient mu is negative.
    NegativeFriction,
    /// An allocation failed.
    OutOfMemory,
    /// An argument has an invalid value (unknown enum, d not 2 or 3, bad option).
    BadArgument,
    /// A file could not be read or written, or is malformed.
    Io,
    /// The host's solver of K (a problem built on it: [`crate::KSolve`])
    /// returned an error code, or a NaN or infinity; the message carries the
    /// host's code.
    HostSolve,
}

/// An error with a message that says which argument and which entry is at fault.
#[derive(Clone, Debug, PartialEq)]
pub struct Error {
    /// The category of the failure.
    pub kind: ErrorKind,
    /// A one-line description, e.g. "K: column 3 has row index 17 >= nrows 10".
    pub message: String,
}

impl Error {
    /// Builds an error of the given kind.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Error {
            kind,
            message: message.into(),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?}: {}", self.kind, self.message)
    }
}

impl std::error::Error for Error {}

/// The library's result type.
pub type Result<T> = std::result::Result<T, Error>;

/// Shorthand for `Err(Error::new(kind, msg))`.
pub(crate) fn fail<T>(kind: ErrorKind, message: impl Into<String>) -> Result<T> {
    Err(Error::new(kind, message))
}
