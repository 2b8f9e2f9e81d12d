//! The thread-local message of the last error, as a NUL-terminated string owned by
//! the library.

use std::cell::RefCell;
use std::ffi::{CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// Records `message` as this thread's last error. Interior NUL bytes are replaced.
pub(crate) fn set(message: &str) {
    let c = CString::new(message.replace('\0', "\\0")).unwrap_or_default();
    // try_with: during thread teardown there is nowhere to store it; drop it.
    let _ = LAST_ERROR.try_with(|cell| {
        if let Ok(mut slot) = cell.try_borrow_mut() {
            *slot = c;
        }
    });
}

/// Forgets this thread's last error (every fallible entry point starts with this).
pub(crate) fn clear() {
    let _ = LAST_ERROR.try_with(|cell| {
        if let Ok(mut slot) = cell.try_borrow_mut() {
            *slot = CString::default();
        }
    });
}

/// This thread's last error message, for Rust callers and tests.
#[cfg(test)]
pub(crate) fn get() -> String {
    LAST_ERROR
        .try_with(|cell| {
            cell.try_borrow()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .unwrap_or_default()
}

/// The message of the last error on the calling thread, NUL-terminated, e.g.
/// "ds_solve: argument f is NULL but must point to 12 values". Never NULL:
/// "" when the last fallible call on this thread succeeded (every function returning
/// DsStatus clears it on entry). The string is owned by the library: do not free it;
/// it stays valid until the next ds_ call on the same thread.
#[unsafe(no_mangle)]
pub extern "C" fn ds_last_error_message() -> *const c_char {
    let ptr = catch_unwind(AssertUnwindSafe(|| {
        LAST_ERROR
            .try_with(|cell| cell.try_borrow().map(|s| s.as_ptr()).ok())
            .ok()
            .flatten()
    }));
    match ptr {
        Ok(Some(p)) => p,
        _ => c"".as_ptr(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    fn message() -> String {
        // SAFETY: ds_last_error_message never returns NULL and the string lives until
        // the next call on this thread.
        unsafe { CStr::from_ptr(ds_last_error_message()) }
            .to_string_lossy()
            .into_owned()
    }

    #[test]
    fn set_get_clear() {
        assert_eq!(message(), "");
        set("K: bad\0thing");
        assert_eq!(message(), "K: bad\\0thing");
        assert_eq!(get(), "K: bad\\0thing");
        clear();
        assert_eq!(message(), "");
    }

    #[test]
    fn per_thread() {
        set("main thread");
        std::thread::spawn(|| assert_eq!(message(), ""))
            .join()
            .unwrap();
        assert_eq!(message(), "main thread");
    }
}
