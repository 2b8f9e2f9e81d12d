//! The version of the library a program runs against.

use std::ffi::c_char;

/// The library's version, "MAJOR.MINOR.PATCH" (the Cargo package version; the
/// header's DS_VERSION_MAJOR, _MINOR and _PATCH give the version a program was
/// compiled against). A static NUL-terminated string, never NULL, not to be freed.
#[unsafe(no_mangle)]
pub extern "C" fn ds_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    #[test]
    fn the_version_is_cargos() {
        // SAFETY: ds_version returns a static NUL-terminated string.
        let v = unsafe { CStr::from_ptr(ds_version()) };
        assert_eq!(v.to_str().unwrap(), env!("CARGO_PKG_VERSION"));
    }
}
