//! The status code returned by every fallible entry point, and its description.

use crate::error::ErrorKind;
use std::ffi::{CStr, c_char};

/// Result of a call. `DS_STATUS_OK` is 0; every other value is an error, one to one
/// with the library's error kinds. After an error, `ds_last_error_message()` says
/// which argument and which entry is at fault.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum DsStatus {
    /// Success: all outputs written.
    Ok = 0,
    /// A required pointer argument (or a pointer inside a DsMatrix) is NULL while the
    /// array it should point to is not empty.
    NullPointer = 1,
    /// A dimension or length is negative or inconsistent (e.g. N has a column count
    /// different from K's size, T does not have (d-1) m rows).
    BadSize = 2,
    /// A sparse index is out of range, pointers do not start at the base or decrease,
    /// or an entry of an UPPER or LOWER K lies in the wrong triangle.
    BadIndex = 3,
    /// A NaN or infinity in a matrix or vector input.
    NotFinite = 4,
    /// A fully stored K is not symmetric (relative tolerance 1e-10 of max |K_ij|).
    NotSymmetric = 5,
    /// The Cholesky factorisation of K met a zero or negative pivot (K singular or
    /// indefinite, e.g. missing Dirichlet conditions).
    NotPositiveDefinite = 6,
    /// A Tresca bound p_i or a Coulomb coefficient mu_i is negative.
    NegativeFriction = 7,
    /// The iteration limit was reached before the tolerance. ds_solve / ds_step
    /// write the report (if given) but not u, lambda_n, lambda_t.
    NotConverged = 8,
    /// An allocation failed.
    OutOfMemory = 9,
    /// An argument has an invalid value: unknown enum value, d not 2 or 3, a matrix
    /// base not 0 or 1, options with a wrong struct_size or out-of-range values,
    /// triangle storage for N or T, a new K whose sparsity pattern differs from the
    /// factored one, a misaligned pointer.
    BadArgument = 10,
    /// A file could not be read or written, or is malformed.
    IoError = 11,
    /// A panic was caught at the boundary: a bug in dualsplit (please report it with
    /// the message). The handle stays valid.
    Panic = 12,
    /// The monitor callback asked to stop. ds_solve / ds_step write the last iterate
    /// to u, lambda_n, lambda_t and the report; the history does not advance.
    Stopped = 13,
    /// The method stopped making progress: its lowest err did not drop by the
    /// factor DsOptions.stall_factor over DsOptions.stall_window outer iterations,
    /// and at that pace tol would not be reached within max_outer (Newton also
    /// when its natural residual stops falling). ds_solve / ds_step
    /// write the iterate with the lowest err to u, lambda_n, lambda_t and the
    /// report; the history does not advance. A problem without a solution (no u
    /// with N u <= g) ends this way under the Gauss-Seidel methods.
    Stalled = 14,
    /// The wall-clock budget DsOptions.max_seconds ran out. ds_solve / ds_step write
    /// the iterate with the lowest err to u, lambda_n, lambda_t and the report; the
    /// history does not advance.
    TimeLimit = 15,
    /// The host's solve of K (a problem made by ds_problem_new_host) returned
    /// a nonzero code, or a NaN or infinity. The message gives the host's code
    /// and which call failed; no output is written and the handle stays usable
    /// (the history does not advance).
    HostSolveFailed = 16,
    /// The handle is inside another call on it: a callback (monitor, log sink,
    /// the host's solve) called an entry point on the handle whose call is
    /// running it. Nothing is changed or written; the running call goes on.
    /// Added in version 0.10.
    Busy = 17,
}

impl From<ErrorKind> for DsStatus {
    fn from(kind: ErrorKind) -> Self {
        match kind {
            ErrorKind::BadSize => DsStatus::BadSize,
            ErrorKind::BadIndex => DsStatus::BadIndex,
            ErrorKind::NotFinite => DsStatus::NotFinite,
            ErrorKind::NotSymmetric => DsStatus::NotSymmetric,
            ErrorKind::NotPositiveDefinite => DsStatus::NotPositiveDefinite,
            ErrorKind::NegativeFriction => DsStatus::NegativeFriction,
            ErrorKind::OutOfMemory => DsStatus::OutOfMemory,
            ErrorKind::BadArgument => DsStatus::BadArgument,
            ErrorKind::Io => DsStatus::IoError,
            ErrorKind::HostSolve => DsStatus::HostSolveFailed,
        }
    }
}

impl DsStatus {
    /// Every status, in the order of their values (index = value).
    pub const ALL: [DsStatus; 18] = [
        DsStatus::Ok,
        DsStatus::NullPointer,
        DsStatus::BadSize,
        DsStatus::BadIndex,
        DsStatus::NotFinite,
        DsStatus::NotSymmetric,
        DsStatus::NotPositiveDefinite,
        DsStatus::NegativeFriction,
        DsStatus::NotConverged,
        DsStatus::OutOfMemory,
        DsStatus::BadArgument,
        DsStatus::IoError,
        DsStatus::Panic,
        DsStatus::Stopped,
        DsStatus::Stalled,
        DsStatus::TimeLimit,
        DsStatus::HostSolveFailed,
        DsStatus::Busy,
    ];

    /// The status with C value `v`, if any.
    pub fn from_i32(v: i32) -> Option<DsStatus> {
        usize::try_from(v)
            .ok()
            .and_then(|i| Self::ALL.get(i).copied())
    }

    /// A static one-line description.
    pub fn description(self) -> &'static CStr {
        match self {
            DsStatus::Ok => c"success",
            DsStatus::NullPointer => c"a required pointer is NULL",
            DsStatus::BadSize => c"a size or length is negative or inconsistent",
            DsStatus::BadIndex => c"a sparse index is out of range or not monotone",
            DsStatus::NotFinite => c"an input holds a NaN or an infinity",
            DsStatus::NotSymmetric => c"K is not symmetric",
            DsStatus::NotPositiveDefinite => c"K is not positive definite",
            DsStatus::NegativeFriction => c"a friction bound or coefficient is negative",
            DsStatus::NotConverged => c"the iteration did not reach the tolerance",
            DsStatus::OutOfMemory => c"out of memory",
            DsStatus::BadArgument => c"an argument has an invalid value",
            DsStatus::IoError => c"a file could not be read or written",
            DsStatus::Panic => c"internal error (panic caught at the C boundary)",
            DsStatus::Stopped => c"stopped by the caller (monitor callback)",
            DsStatus::Stalled => c"the iteration stopped making progress",
            DsStatus::TimeLimit => c"the time limit was reached before the tolerance",
            DsStatus::HostSolveFailed => c"the host's solve of K failed",
            DsStatus::Busy => c"the handle is inside another call on it (a callback re-entered it)",
        }
    }
}

/// A static, NUL-terminated description of a status value (e.g. "K is not
/// symmetric"). Never NULL: unknown values give "unknown status". The string must
/// not be freed.
#[unsafe(no_mangle)]
pub extern "C" fn ds_status_string(status: i32) -> *const c_char {
    match DsStatus::from_i32(status) {
        Some(s) => s.description().as_ptr(),
        None => c"unknown status".as_ptr(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_indices() {
        for (i, s) in DsStatus::ALL.iter().enumerate() {
            assert_eq!(*s as i32, i as i32);
            assert_eq!(DsStatus::from_i32(i as i32), Some(*s));
        }
        assert_eq!(DsStatus::from_i32(-1), None);
        assert_eq!(DsStatus::from_i32(18), None);
    }

    #[test]
    fn error_kinds_map_one_to_one() {
        // Every kind of the Rust API has its own status; the rest (NULL
        // pointer, panic, the unconverged solves) are the C layer's alone.
        let kinds = [
            ErrorKind::BadSize,
            ErrorKind::BadIndex,
            ErrorKind::NotFinite,
            ErrorKind::NotSymmetric,
            ErrorKind::NotPositiveDefinite,
            ErrorKind::NegativeFriction,
            ErrorKind::OutOfMemory,
            ErrorKind::BadArgument,
            ErrorKind::Io,
            ErrorKind::HostSolve,
        ];
        let mapped: Vec<DsStatus> = kinds.iter().map(|&k| DsStatus::from(k)).collect();
        let c_only = [
            DsStatus::Ok,
            DsStatus::NullPointer,
            DsStatus::NotConverged,
            DsStatus::Panic,
            DsStatus::Stopped,
            DsStatus::Stalled,
            DsStatus::TimeLimit,
            DsStatus::Busy,
        ];
        for s in DsStatus::ALL {
            let from_kinds = mapped.iter().filter(|&&m| m == s).count();
            assert_eq!(from_kinds, usize::from(!c_only.contains(&s)), "{s:?}");
        }
    }

    #[test]
    fn strings_are_never_null() {
        for v in -3..20 {
            let p = ds_status_string(v);
            assert!(!p.is_null());
            // SAFETY: ds_status_string returns a pointer to a static C string.
            let s = unsafe { CStr::from_ptr(p) };
            assert!(!s.is_empty());
        }
        // SAFETY: as above.
        let s = unsafe { CStr::from_ptr(ds_status_string(99)) };
        assert_eq!(s, c"unknown status");
    }
}
