//! The panic boundary and the pointer checks shared by every entry point.
//!
//! [`entry`] runs the body of an entry point under `catch_unwind`, turns an
//! `Err(Error)` into its status and records the message; the `*_in` / `*_out`
//! helpers turn raw C pointers into borrowed Rust references after checking them for
//! NULL (allowed for empty arrays only), alignment and size.

use super::error::{CError as Error, CResult as Result};
use super::last_error;
use super::status::DsStatus;
use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind};

/// Runs the body of the entry point `name` with the boundary rules: clears the last
/// error (before the body, and after it on success, so that a message a callback's
/// refused call left inside it does not outlive the call), catches panics (->
/// `DsStatus::Panic`), maps `Err(e)` to its status `e.status` and records "name:
/// message" as the last error.
pub(crate) fn entry(name: &str, body: impl FnOnce() -> Result<()>) -> DsStatus {
    last_error::clear();
    // AssertUnwindSafe: after a panic the caller only sees a status; the core keeps
    // its state consistent by validating before mutating.
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            last_error::clear();
            DsStatus::Ok
        }
        Ok(Err(e)) => {
            last_error::set(&format!("{name}: {}", e.message));
            e.status
        }
        Err(payload) => {
            let what = panic_message(&payload);
            last_error::set(&format!(
                "{name}: internal panic (a bug in dualsplit, please report): {what}"
            ));
            drop_payload(payload);
            DsStatus::Panic
        }
    }
}

/// The text of a panic payload (`panic!("...")` gives `&str` or `String`).
pub(crate) fn panic_message(payload: &Box<dyn Any + Send>) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "(no message)".to_string()
    }
}

/// Drops a panic payload without letting a panicking destructor escape.
pub(crate) fn drop_payload(payload: Box<dyn Any + Send>) {
    if let Err(again) = catch_unwind(AssertUnwindSafe(move || drop(payload))) {
        std::mem::forget(again);
    }
}

/// `Err(NullPointer)` naming the argument.
fn null(what: &str, len: usize) -> Error {
    Error::new(
        DsStatus::NullPointer,
        format!("argument {what} is NULL but must point to {len} values"),
    )
}

/// Checks a non-NULL pointer for alignment and `len` elements for the address space.
fn check_ptr<T>(ptr: *const T, len: usize, what: &str) -> Result<()> {
    if !ptr.is_aligned() {
        return Err(Error::new(
            DsStatus::BadArgument,
            format!(
                "argument {what} = {ptr:p} is not aligned to {} bytes",
                std::mem::align_of::<T>()
            ),
        ));
    }
    let too_big = len
        .checked_mul(std::mem::size_of::<T>())
        .is_none_or(|bytes| bytes > isize::MAX as usize);
    if too_big {
        return Err(Error::new(
            DsStatus::BadSize,
            format!("argument {what}: {len} values do not fit in memory"),
        ));
    }
    Ok(())
}

/// Borrows `len` values at `ptr` (an input array). NULL is accepted when `len` is 0.
///
/// Errors: `NullPointer` (NULL with `len > 0`), `BadArgument` (misaligned),
/// `BadSize` (`len` too large for the address space).
///
/// # Safety
/// If `ptr` is not NULL and `len > 0`, `ptr` must be valid for reads of `len`
/// values of `T` that are not written to during `'a`.
pub(crate) unsafe fn slice_in<'a, T>(ptr: *const T, len: usize, what: &str) -> Result<&'a [T]> {
    if len == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(null(what, len));
    }
    check_ptr(ptr, len, what)?;
    // SAFETY: non-NULL, aligned, size checked; validity for `len` reads is the
    // caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// As [`slice_in`] for an optional input array: NULL is None (the caller's
/// "use the default"), else `len` values.
///
/// # Safety
/// As [`slice_in`].
pub(crate) unsafe fn optional_in<'a, T>(
    ptr: *const T,
    len: usize,
    what: &str,
) -> Result<Option<&'a [T]>> {
    if ptr.is_null() {
        return Ok(None);
    }
    // SAFETY: non-NULL; validity for `len` reads is the caller's contract.
    unsafe { slice_in(ptr, len, what) }.map(Some)
}

/// A checked, caller-owned output array, written only by [`OutArray::write`].
/// Holding the raw pointer (instead of a `&mut [T]`) allows outputs to alias inputs
/// that are no longer read when the outputs are written.
pub(crate) struct OutArray<T> {
    /// The caller's array (NULL allowed when `len` is 0).
    ptr: *mut T,
    /// Number of values the caller's array holds.
    len: usize,
    /// The argument's name, for messages.
    what: &'static str,
}

impl<T: Copy> OutArray<T> {
    /// Checks an output array of `len` values. NULL is accepted when `len` is 0.
    ///
    /// Errors: as [`slice_in`].
    pub(crate) fn new(ptr: *mut T, len: usize, what: &'static str) -> Result<Self> {
        if len > 0 {
            if ptr.is_null() {
                return Err(null(what, len));
            }
            check_ptr(ptr, len, what)?;
        }
        Ok(OutArray { ptr, len, what })
    }

    /// Fails unless `src` has the length this array was checked for.
    pub(crate) fn check_len(&self, src: &[T]) -> Result<()> {
        if src.len() == self.len {
            Ok(())
        } else {
            Err(Error::new(
                DsStatus::Panic,
                format!(
                    "internal error: {} has {} values, expected {}",
                    self.what,
                    src.len(),
                    self.len
                ),
            ))
        }
    }

    /// Copies `src` into the caller's array. Check lengths of every output with
    /// [`OutArray::check_len`] before writing the first one.
    ///
    /// # Safety
    /// The pointer given to [`OutArray::new`] must be valid for writes of `len`
    /// values, and no Rust reference to that memory may be alive.
    pub(crate) unsafe fn write(&self, src: &[T]) -> Result<()> {
        self.check_len(src)?;
        if self.len > 0 {
            // SAFETY: ptr is non-NULL and aligned (checked in new), valid for len
            // writes (caller's contract); src is library memory, so no overlap.
            unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), self.ptr, self.len) };
        }
        Ok(())
    }
}

impl<T: Copy> OutArray<T> {
    /// Copies the first `bytes` bytes of `src` into the caller's single struct
    /// (an array of length 1): the fields of an older, shorter layout of `T`.
    ///
    /// # Safety
    /// The pointer given to [`OutArray::new`] (with length 1) must be valid for
    /// writes of `bytes` bytes, and no Rust reference to that memory may be alive.
    pub(crate) unsafe fn write_prefix(&self, src: &T, bytes: usize) {
        assert!(self.len == 1 && bytes <= std::mem::size_of::<T>());
        // SAFETY: ptr is non-NULL and aligned (checked in new), valid for `bytes`
        // writes (caller's contract); src is library memory, so no overlap.
        unsafe {
            std::ptr::copy_nonoverlapping(
                (src as *const T).cast::<u8>(),
                self.ptr.cast::<u8>(),
                bytes,
            )
        };
    }
}

/// Checks the pointer to one of the caller's versioned structs (DsOptions,
/// DsInfo, DsCost, DsHostSolver) before its struct_size is read: `NullPointer`
/// when NULL, `BadArgument` when misaligned, each naming the argument `what`.
pub(crate) fn check_struct<T>(ptr: *const T, what: &str) -> Result<()> {
    if ptr.is_null() {
        return Err(Error::new(
            DsStatus::NullPointer,
            format!("argument {what} is NULL"),
        ));
    }
    if !ptr.is_aligned() {
        return Err(Error::new(
            DsStatus::BadArgument,
            format!("argument {what} = {ptr:p} is not aligned"),
        ));
    }
    Ok(())
}

/// Writes `value` into the caller's versioned struct at `out` (DsInfo,
/// DsCost: a `#[repr(C)]` struct whose first field is the u32 struct_size the
/// caller set), at most struct_size bytes: a caller compiled against an older,
/// shorter struct gets the fields it has. struct_size keeps the caller's value.
///
/// Errors: `NullPointer`; `BadArgument` when `out` is misaligned or its
/// struct_size is below 8 (not set).
///
/// # Safety
/// `out` must be NULL or point to a writable prefix of struct_size bytes of a
/// `T` whose first field is a u32 struct_size.
pub(crate) unsafe fn write_sized<T: Copy>(
    out: *mut T,
    value: T,
    what: &str,
    type_name: &str,
) -> Result<()> {
    check_struct(out, what)?;
    // SAFETY: non-NULL and aligned; the first field, a u32, is present in every
    // version (contract).
    let struct_size = unsafe { out.cast::<u32>().read() };
    let size = struct_size as usize;
    if size < 8 {
        return Err(Error::new(
            DsStatus::BadArgument,
            format!("{what}->struct_size = {size}: set it to sizeof({type_name}) before the call"),
        ));
    }
    let len = size.min(std::mem::size_of::<T>());
    // SAFETY: `out` is writable for struct_size >= len >= 8 bytes (contract),
    // `value` is a whole T in library memory (no overlap); the u32 written last
    // is the first field, restored to the caller's value.
    unsafe {
        std::ptr::copy_nonoverlapping((&value as *const T).cast::<u8>(), out.cast::<u8>(), len);
        out.cast::<u32>().write(struct_size);
    }
    Ok(())
}

/// Borrows the struct at `ptr`.
///
/// Errors: `NullPointer`, `BadArgument` (misaligned).
///
/// # Safety
/// If not NULL, `ptr` must point to a valid `T` that is not written during `'a`.
pub(crate) unsafe fn ref_in<'a, T>(ptr: *const T, what: &str) -> Result<&'a T> {
    if ptr.is_null() {
        return Err(Error::new(
            DsStatus::NullPointer,
            format!("argument {what} is NULL"),
        ));
    }
    check_ptr(ptr, 1, what)?;
    // SAFETY: non-NULL and aligned; validity is the caller's contract.
    Ok(unsafe { &*ptr })
}

/// Borrows the struct at `ptr` mutably.
///
/// Errors: `NullPointer`, `BadArgument` (misaligned).
///
/// # Safety
/// If not NULL, `ptr` must point to a valid `T` not accessed otherwise during `'a`.
pub(crate) unsafe fn ref_mut<'a, T>(ptr: *mut T, what: &str) -> Result<&'a mut T> {
    if ptr.is_null() {
        return Err(Error::new(
            DsStatus::NullPointer,
            format!("argument {what} is NULL"),
        ));
    }
    check_ptr(ptr, 1, what)?;
    // SAFETY: non-NULL and aligned; validity and exclusivity are the caller's contract.
    Ok(unsafe { &mut *ptr })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn panic_becomes_status() {
        let status = entry("ds_test", || panic!("boom {}", 42));
        assert_eq!(status, DsStatus::Panic);
        let msg = last_error::get();
        assert!(msg.contains("ds_test") && msg.contains("boom 42"), "{msg}");
        let status = entry("ds_test", || Ok(()));
        assert_eq!(status, DsStatus::Ok);
        assert_eq!(last_error::get(), "");
    }

    #[test]
    fn error_becomes_status() {
        let status = entry("ds_test", || {
            Err(Error::new(DsStatus::NotFinite, "f[3] is NaN"))
        });
        assert_eq!(status, DsStatus::NotFinite);
        assert_eq!(last_error::get(), "ds_test: f[3] is NaN");
    }

    #[test]
    fn slices() {
        let v = [1.0f64, 2.0];
        // SAFETY: v is valid for 2 reads; NULL with len 0 is never dereferenced.
        unsafe {
            assert_eq!(slice_in(v.as_ptr(), 2, "v").unwrap(), &v[..]);
            assert!(
                slice_in::<f64>(std::ptr::null(), 0, "v")
                    .unwrap()
                    .is_empty()
            );
            let e = slice_in::<f64>(std::ptr::null(), 3, "v").unwrap_err();
            assert_eq!(e.status, DsStatus::NullPointer);
            assert!(e.message.contains("argument v "));
            let bytes = [0u8; 16];
            let odd = bytes.as_ptr().add(1).cast::<f64>();
            assert_eq!(
                slice_in(odd, 1, "v").unwrap_err().status,
                DsStatus::BadArgument
            );
            let e = slice_in(v.as_ptr(), usize::MAX / 4, "v").unwrap_err();
            assert_eq!(e.status, DsStatus::BadSize);
        }
        assert!(OutArray::<f64>::new(std::ptr::null_mut(), 0, "u").is_ok());
        let e = OutArray::<f64>::new(std::ptr::null_mut(), 1, "u")
            .err()
            .unwrap();
        assert_eq!(e.status, DsStatus::NullPointer);
        let mut out = [0.0f64; 2];
        let o = OutArray::new(out.as_mut_ptr(), 2, "u").unwrap();
        assert_eq!(o.check_len(&[1.0]).unwrap_err().status, DsStatus::Panic);
        // SAFETY: out is valid for 2 writes and not borrowed.
        unsafe { o.write(&[3.0, 4.0]).unwrap() };
        assert_eq!(out, [3.0, 4.0]);
    }
}
