//! The C layer's error: a status of the C API and its message. The safe core's
//! [`crate::Error`] converts into it (its kind mapped onto the status); the
//! failures only a C caller can meet (a NULL pointer, a caught panic) and the
//! statuses of an unconverged solve are made here, so that the Rust API's
//! `ErrorKind` holds none of them.

use super::status::DsStatus;

/// A failed entry point: the status it returns and the message
/// `ds_last_error_message` gives.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CError {
    /// The status returned to C.
    pub(crate) status: DsStatus,
    /// One line naming the argument and entry at fault.
    pub(crate) message: String,
}

impl CError {
    /// An error with the given status.
    pub(crate) fn new(status: DsStatus, message: impl Into<String>) -> CError {
        CError {
            status,
            message: message.into(),
        }
    }
}

impl From<crate::Error> for CError {
    fn from(e: crate::Error) -> CError {
        CError {
            status: DsStatus::from(e.kind),
            message: e.message,
        }
    }
}

/// The C layer's result type.
pub(crate) type CResult<T> = std::result::Result<T, CError>;
