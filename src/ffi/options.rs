//! The options struct of the C API, its defaults and its translation into
//! [`Options`].

use super::types::{CEnum, DsDualForm, DsMethod};
use crate::error::{Error, ErrorKind, Result};
use crate::options::Options;
use std::panic::{AssertUnwindSafe, catch_unwind};

/// Options of ds_solve / ds_step. Fill with ds_options_default, then change fields.
/// Passing NULL instead of a DsOptions uses the defaults.
///
/// Errors when read: DS_STATUS_BAD_ARGUMENT if struct_size is neither
/// sizeof(DsOptions) nor 32 (the struct of version 0.1, without dual_form, which
/// then reads as DS_DUAL_FORM_AUTO), method is not a DsMethod, tol is not finite and
/// positive, max_outer is negative, max_inner is not positive, or dual_form is not
/// a DsDualForm.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DsOptions {
    /// sizeof(DsOptions), set by ds_options_default; checked so that the struct can
    /// grow in later versions without breaking compiled callers.
    pub struct_size: u32,
    /// A DsMethod value (default DS_METHOD_SPLIT).
    pub method: i32,
    /// Stop when the relative error measure err (dimensionless, see DsReport) is at
    /// most tol; > 0 (default 1e-10).
    pub tol: f64,
    /// Maximum number of outer iterations, >= 0 (default 10000): sweeps for PGS,
    /// normal/tangential alternations for SPLIT and BLOCK_GS.
    pub max_outer: i64,
    /// Maximum number of projected Gauss-Seidel sweeps per sub-problem of SPLIT and
    /// BLOCK_GS, >= 1 (default 1000).
    pub max_inner: i64,
    /// A DsDualForm value (default DS_DUAL_FORM_AUTO). Added in version 0.2.
    pub dual_form: i32,
}

/// sizeof(DsOptions) of version 0.1 (struct_size, method, tol, max_outer,
/// max_inner): still accepted, with dual_form = DS_DUAL_FORM_AUTO.
const V01_SIZE: usize = 32;

impl DsOptions {
    /// The C struct holding `opts`.
    pub fn from_options(opts: &Options) -> DsOptions {
        DsOptions {
            struct_size: std::mem::size_of::<DsOptions>() as u32,
            method: DsMethod::from(opts.method) as i32,
            tol: opts.tol,
            max_outer: i64::try_from(opts.max_outer).unwrap_or(i64::MAX),
            max_inner: i64::try_from(opts.max_inner).unwrap_or(i64::MAX),
            dual_form: DsDualForm::from(opts.dual_form) as i32,
        }
    }

    /// Validates the fields and converts to [`Options`].
    ///
    /// Errors: `BadArgument` (see [`DsOptions`]).
    pub(crate) fn to_options(self) -> Result<Options> {
        let bad = |msg: String| Error::new(ErrorKind::BadArgument, msg);
        let method = DsMethod::parse(self.method, "opts.method")?;
        let dual_form = DsDualForm::parse(self.dual_form, "opts.dual_form")?;
        if !(self.tol.is_finite() && self.tol > 0.0) {
            return Err(bad(format!(
                "opts.tol = {} must be finite and positive",
                self.tol
            )));
        }
        let count = |v: i64, name: &str, min: i64| {
            if v < min {
                Err(bad(format!("opts.{name} = {v} must be at least {min}")))
            } else {
                usize::try_from(v).map_err(|_| bad(format!("opts.{name} = {v} is too large")))
            }
        };
        Ok(Options {
            method: method.into(),
            tol: self.tol,
            max_outer: count(self.max_outer, "max_outer", 0)?,
            max_inner: count(self.max_inner, "max_inner", 1)?,
            dual_form: dual_form.into(),
        })
    }

    /// Reads the options at `ptr` (NULL: the defaults). `struct_size` is read first,
    /// alone, so that a smaller struct is never read past its end.
    ///
    /// Errors: `BadArgument` (see [`DsOptions`]).
    ///
    /// # Safety
    /// `ptr` must be NULL or point to at least `struct_size` readable bytes that
    /// start with the `struct_size` field.
    pub(crate) unsafe fn read(ptr: *const DsOptions) -> Result<Options> {
        if ptr.is_null() {
            return Ok(Options::default());
        }
        if !ptr.is_aligned() {
            return Err(Error::new(
                ErrorKind::BadArgument,
                format!("argument opts = {ptr:p} is not aligned"),
            ));
        }
        // SAFETY: non-NULL and aligned; the first field is present whatever the
        // version of the caller's struct.
        let size = unsafe { std::ptr::addr_of!((*ptr).struct_size).read() };
        let expected = std::mem::size_of::<DsOptions>();
        if size as usize == V01_SIZE {
            // SAFETY: the caller's struct is the version 0.1 prefix of DsOptions:
            // the same fields at the same offsets (checked in the tests), 32 bytes.
            let v01 = unsafe {
                DsOptions {
                    struct_size: size,
                    method: std::ptr::addr_of!((*ptr).method).read(),
                    tol: std::ptr::addr_of!((*ptr).tol).read(),
                    max_outer: std::ptr::addr_of!((*ptr).max_outer).read(),
                    max_inner: std::ptr::addr_of!((*ptr).max_inner).read(),
                    dual_form: DsDualForm::Auto as i32,
                }
            };
            return v01.to_options();
        }
        if size as usize != expected {
            return Err(Error::new(
                ErrorKind::BadArgument,
                format!(
                    "opts.struct_size = {size} but sizeof(DsOptions) = {expected}: \
                     initialise the options with ds_options_default"
                ),
            ));
        }
        // SAFETY: the caller says the struct is struct_size = sizeof(DsOptions) bytes.
        unsafe { ptr.read() }.to_options()
    }
}

impl Default for DsOptions {
    fn default() -> Self {
        DsOptions::from_options(&Options::default())
    }
}

/// Fills *opts with the defaults: struct_size = sizeof(DsOptions), method
/// DS_METHOD_SPLIT, tol 1e-10, max_outer 10000, max_inner 1000, dual_form
/// DS_DUAL_FORM_AUTO. NULL is a no-op.
///
/// # Safety
/// `opts` must be NULL or point to a writable DsOptions.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_options_default(opts: *mut DsOptions) {
    if opts.is_null() || !opts.is_aligned() {
        return;
    }
    let Ok(value) = catch_unwind(AssertUnwindSafe(DsOptions::default)) else {
        return;
    };
    // SAFETY: non-NULL and aligned; writable per the contract. write() does not
    // read or drop the old (possibly uninitialised) contents.
    unsafe { opts.write(value) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::Method;

    #[test]
    fn defaults_round_trip() {
        let mut o = DsOptions {
            struct_size: 0,
            method: -5,
            tol: f64::NAN,
            max_outer: -1,
            max_inner: -1,
            dual_form: 9,
        };
        // SAFETY: o is a valid, writable DsOptions.
        unsafe { ds_options_default(&mut o) };
        // SAFETY: NULL is a no-op.
        unsafe { ds_options_default(std::ptr::null_mut()) };
        assert_eq!(o.struct_size as usize, std::mem::size_of::<DsOptions>());
        assert_eq!(o.method, DsMethod::Split as i32);
        assert_eq!((o.tol, o.max_outer, o.max_inner), (1e-10, 10_000, 1_000));
        // SAFETY: o is a valid DsOptions.
        let read = unsafe { DsOptions::read(&o) };
        assert_eq!(read.unwrap(), Options::default());
        // SAFETY: NULL means defaults.
        let read = unsafe { DsOptions::read(std::ptr::null()) };
        assert_eq!(read.unwrap(), Options::default());
        let pgs = DsOptions { method: 2, ..o };
        // SAFETY: pgs is a valid DsOptions.
        let read = unsafe { DsOptions::read(&pgs) };
        assert_eq!(read.unwrap().method, Method::Pgs);
    }

    #[test]
    fn a_version_01_struct_reads_with_the_automatic_dual_form() {
        /// DsOptions as compiled against the 0.1 header.
        #[repr(C)]
        struct V01 {
            struct_size: u32,
            method: i32,
            tol: f64,
            max_outer: i64,
            max_inner: i64,
        }
        assert_eq!(std::mem::size_of::<V01>(), V01_SIZE);
        assert_eq!(
            std::mem::offset_of!(V01, max_inner),
            std::mem::offset_of!(DsOptions, max_inner)
        );
        assert_eq!(
            std::mem::offset_of!(V01, tol),
            std::mem::offset_of!(DsOptions, tol)
        );
        let old = V01 {
            struct_size: V01_SIZE as u32,
            method: DsMethod::Mprgp as i32,
            tol: 1e-8,
            max_outer: 7,
            max_inner: 9,
        };
        // SAFETY: old has the 0.1 layout and says so in struct_size.
        let read = unsafe { DsOptions::read(&old as *const V01 as *const DsOptions) }.unwrap();
        assert_eq!(
            read,
            Options {
                method: Method::Mprgp,
                tol: 1e-8,
                max_outer: 7,
                max_inner: 9,
                dual_form: crate::options::DualForm::Auto,
            }
        );
    }

    #[test]
    fn bad_fields() {
        let o = DsOptions::default();
        let cases = [
            (
                DsOptions {
                    struct_size: 8,
                    ..o
                },
                "struct_size = 8",
            ),
            (DsOptions { method: 6, ..o }, "opts.method = 6"),
            (DsOptions { tol: -1.0, ..o }, "opts.tol"),
            (
                DsOptions {
                    tol: f64::INFINITY,
                    ..o
                },
                "opts.tol",
            ),
            (DsOptions { max_outer: -1, ..o }, "opts.max_outer = -1"),
            (DsOptions { max_inner: -3, ..o }, "opts.max_inner = -3"),
            (DsOptions { dual_form: 3, ..o }, "opts.dual_form = 3"),
        ];
        for (bad, text) in cases {
            // SAFETY: bad is a valid DsOptions.
            let e = unsafe { DsOptions::read(&bad) }.unwrap_err();
            assert_eq!(e.kind, ErrorKind::BadArgument);
            assert!(e.message.contains(text), "{} lacks {text}", e.message);
        }
    }
}
