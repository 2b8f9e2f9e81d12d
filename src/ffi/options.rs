//! The options struct of the C API, its defaults and its translation into
//! [`Options`].

use super::boundary::{check_struct, entry};
use super::error::{CError as Error, CResult as Result};
use super::status::DsStatus;
use super::types::{CEnum, DsDualForm, DsMethod, DsOrdering};
use crate::options::Options;
use std::panic::{AssertUnwindSafe, catch_unwind};

/// Options of ds_solve / ds_step. Fill with ds_options_init(&opts, sizeof opts)
/// (or the ds_options_default macro, which does the same), then change fields.
/// Passing NULL instead of a DsOptions uses the defaults.
///
/// The struct grows at its end from version to version; struct_size says which
/// version the caller was compiled against, and the library reads no byte past
/// it: 32 (version 0.1: up to max_inner), 40 (0.2: up to dual_form), 64 (0.3: up
/// to stall_factor), 72 (0.4: up to ordering), 80 (0.5: up to max_memory) and
/// 88 (0.10) are accepted, the fields an older struct lacks take their
/// defaults.
///
/// Errors when read: DS_STATUS_BAD_ARGUMENT if struct_size is not one of those
/// sizes, method is not a DsMethod, tol is not finite and positive, max_outer is
/// negative, max_inner is not positive, dual_form is not a DsDualForm,
/// max_seconds is negative or not finite, stall_window is negative,
/// stall_factor is not in (0, 1], threads is negative or above 4096, ordering
/// is not a DsOrdering, or host_loop is not 0 or 1.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DsOptions {
    /// The size in bytes of the caller's struct, sizeof(DsOptions), set by
    /// ds_options_init; checked so that the struct can grow in later versions
    /// without breaking compiled callers.
    pub struct_size: u32,
    /// A DsMethod value (default DS_METHOD_AUTO from 0.6, DS_METHOD_SPLIT before).
    pub method: i32,
    /// Stop when the relative error measure err (dimensionless, see DsReport) is at
    /// most tol; > 0 (default 1e-10).
    pub tol: f64,
    /// Maximum number of outer iterations, >= 0 (default 10000): sweeps for PGS,
    /// normal/tangential alternations for SPLIT and BLOCK_GS, Newton steps.
    pub max_outer: i64,
    /// Maximum number of inner iterations per sub-problem (Gauss-Seidel sweeps,
    /// MPRGP iterations), >= 1 (default 1000).
    pub max_inner: i64,
    /// A DsDualForm value (default DS_DUAL_FORM_AUTO): read by every solve, and by
    /// ds_problem_new_opts, which creates the handle in that form
    /// (DS_DUAL_FORM_MATRIX_FREE: K factored in the best plain ordering, nothing
    /// c x c formed; DS_DUAL_FORM_DENSE: contact DOFs last and A formed; AUTO: dense
    /// up to 8000 dual unknowns where it fits max_memory, except where the
    /// contact face ordered last would dominate the factor: see DsDualForm).
    /// Added in version 0.2.
    pub dual_form: i32,
    /// Wall-clock budget of one ds_solve / ds_step in seconds, >= 0, 0 for none
    /// (default 0). No outer iteration starts after it; the solve then returns
    /// DS_STATUS_TIME_LIMIT with the iterate with the lowest err. Checked between
    /// outer iterations (one Newton step or sub-problem solve may overrun it);
    /// the factorisation and condensation are not counted. Added in version 0.3.
    pub max_seconds: f64,
    /// Window of the stagnation test in outer iterations, >= 0, 0 to turn it off
    /// (default 100). After stall_window or more outer iterations, let r be the
    /// lowest err met divided by the lowest err met up to stall_window iterations
    /// earlier; the solve returns DS_STATUS_STALLED with the iterate with the
    /// lowest err when r > stall_factor and, at the pace r per window, tol would
    /// not be reached within max_outer (always when r = 1). Added in version 0.3.
    pub stall_window: i64,
    /// The factor by which the lowest err must drop over stall_window outer
    /// iterations to count as progress whatever max_outer, in (0, 1] (default 0.9:
    /// by 10 %). Added in version 0.3.
    pub stall_factor: f64,
    /// Threads for the factorisation, the condensation and the dense kernels:
    /// 0 for all cores (default), 1 for the calling thread only (the library
    /// starts no thread), k for at most k (k <= 4096). Each handle owns its pool,
    /// so handles used in different threads of a program do not compete for one;
    /// it is started by the first piece of work large enough to use it.
    /// Read by ds_problem_new_opts (ds_problem_new: 0); the handle keeps its
    /// pool for every later call, and ds_solve / ds_step ignore the field. With
    /// 1, results are bit-identical from run to run. Added in version 0.4.
    pub threads: i32,
    /// A DsOrdering value (default DS_ORDERING_AUTO): the fill-reducing ordering
    /// of K, used when K is analysed, by ds_problem_new_opts (ds_problem_refactor
    /// keeps the analysis; ds_solve and ds_step ignore it). Added in version 0.4.
    pub ordering: i32,
    /// The most bytes the library's large allocations (the copies of K, N and T,
    /// K's factor, the condensed dual, the dense work space of the method, the
    /// solve's vectors) may take at once; 0 (default) for no limit of the
    /// caller's: the limit is then this process's address-space limit
    /// (RLIMIT_AS) or the machine's physical memory, the smaller. The need is
    /// predicted from the sizes known after K's symbolic analysis (see
    /// ds_analyse and DsInfo), before the work that allocates it:
    /// ds_problem_new_opts refuses a problem whose setup would exceed it, and
    /// ds_solve / ds_step a solve whose method would, with
    /// DS_STATUS_OUT_OF_MEMORY and a message naming the need and a route that
    /// fits (the handle stays usable). With DS_DUAL_FORM_AUTO the problem is
    /// created matrix-free where the dense dual does not fit. Read by
    /// ds_problem_new_opts (the handle keeps it as the limit of
    /// ds_problem_refactor, which holds the old and the new factor at once, and of
    /// ds_problem_set_contacts; DsInfo.refactor_bytes is that need), ds_solve and
    /// ds_step. Added in version 0.5.
    pub max_memory: u64,
    /// 1 when the handle serves a host's Newton loop (ds_problem_refactor
    /// before nearly every ds_solve_iteration, docs/design.md section 9), 0
    /// (default) otherwise. DS_DUAL_FORM_AUTO then creates a 3D problem
    /// matrix-free where the method runs matrix-free (the dense route is not
    /// weighed):
    /// its refactor is the plain numeric factor with the contact blocks
    /// kept, where the dense route's orders the contact DOFs last (2.2-2.8
    /// times the plain factor on a 40 x 40 x 20 block) and condenses again.
    /// Read by ds_problem_new_opts. Added in version 0.10 (88 bytes).
    pub host_loop: i32,
}

/// sizeof(DsOptions) of version 0.1 (struct_size, method, tol, max_outer,
/// max_inner).
const V01_SIZE: usize = 32;
/// sizeof(DsOptions) of version 0.2 (and dual_form, padded to 8 bytes).
const V02_SIZE: usize = 40;
/// sizeof(DsOptions) of version 0.3 (and max_seconds, stall_window, stall_factor).
const V03_SIZE: usize = 64;
/// sizeof(DsOptions) of version 0.4 (and threads, ordering).
pub(crate) const V04_SIZE: usize = 72;
/// sizeof(DsOptions) of version 0.5 (and max_memory).
pub(crate) const V05_SIZE: usize = 80;
/// sizeof(DsOptions) of version 0.10 (and host_loop, padded to 8 bytes).
pub(crate) const V10_SIZE: usize = 88;
/// sizeof(DsOptions) now.
const SIZE: usize = std::mem::size_of::<DsOptions>();
/// Every accepted struct_size.
const SIZES: [usize; 6] = [V01_SIZE, V02_SIZE, V03_SIZE, V04_SIZE, V05_SIZE, V10_SIZE];
const _: () = assert!(SIZE == V10_SIZE);

/// Copies the first `size` bytes of `from` to `to` (size at most sizeof(DsOptions)).
///
/// # Safety
/// `to` must be valid for writing `size` bytes.
unsafe fn write_prefix(from: &DsOptions, to: *mut DsOptions, size: usize) {
    debug_assert!(size <= SIZE);
    // SAFETY: `from` is a whole DsOptions (SIZE >= size bytes); `to` is writable for
    // size bytes (contract); a Rust value and caller memory do not overlap.
    unsafe {
        std::ptr::copy_nonoverlapping(
            (from as *const DsOptions).cast::<u8>(),
            to.cast::<u8>(),
            size,
        )
    };
}

impl DsOptions {
    /// The C struct holding `opts`.
    pub fn from_options(opts: &Options) -> DsOptions {
        DsOptions {
            struct_size: SIZE as u32,
            method: DsMethod::from(opts.method) as i32,
            tol: opts.tol,
            max_outer: i64::try_from(opts.max_outer).unwrap_or(i64::MAX),
            max_inner: i64::try_from(opts.max_inner).unwrap_or(i64::MAX),
            dual_form: DsDualForm::from(opts.dual_form) as i32,
            max_seconds: opts.max_seconds,
            stall_window: i64::try_from(opts.stall_window).unwrap_or(i64::MAX),
            stall_factor: opts.stall_factor,
            threads: i32::try_from(opts.threads).unwrap_or(i32::MAX),
            ordering: DsOrdering::from(opts.ordering) as i32,
            max_memory: u64::try_from(opts.max_memory).unwrap_or(u64::MAX),
            host_loop: i32::from(opts.host_loop),
        }
    }

    /// Validates the fields and converts to [`Options`].
    ///
    /// Errors: `BadArgument` (see [`DsOptions`]).
    pub(crate) fn to_options(self) -> Result<Options> {
        let bad = |msg: String| Error::new(DsStatus::BadArgument, msg);
        let method = DsMethod::parse(self.method, "opts.method")?;
        let dual_form = DsDualForm::parse(self.dual_form, "opts.dual_form")?;
        let ordering = DsOrdering::parse(self.ordering, "opts.ordering")?;
        let count = |v: i64, name: &str, min: i64| {
            if v < min {
                Err(bad(format!("opts.{name} = {v} must be at least {min}")))
            } else {
                usize::try_from(v).map_err(|_| bad(format!("opts.{name} = {v} is too large")))
            }
        };
        let opts = Options {
            method: method.into(),
            tol: self.tol,
            max_outer: count(self.max_outer, "max_outer", 0)?,
            max_inner: count(self.max_inner, "max_inner", 1)?,
            dual_form: dual_form.into(),
            max_seconds: self.max_seconds,
            stall_window: count(self.stall_window, "stall_window", 0)?,
            stall_factor: self.stall_factor,
            threads: count(i64::from(self.threads), "threads", 0)?,
            ordering: ordering.into(),
            max_memory: usize::try_from(self.max_memory).unwrap_or(usize::MAX),
            host_loop: match self.host_loop {
                0 => false,
                1 => true,
                v => return Err(bad(format!("opts.host_loop = {v} must be 0 or 1"))),
            },
            // Set from DsHostSolver.blocks by ds_problem_new_host.
            host_blocks: crate::HostBlocks::Auto,
        };
        opts.check("opts.")?;
        Ok(opts)
    }

    /// The struct_size of the options at `ptr`, 0 for NULL. Call after
    /// [`DsOptions::read`] accepted `ptr`.
    ///
    /// # Safety
    /// As [`DsOptions::read`].
    pub(crate) unsafe fn caller_size(ptr: *const DsOptions) -> usize {
        if ptr.is_null() || !ptr.is_aligned() {
            return 0;
        }
        // SAFETY: non-NULL and aligned; the first field is always present.
        (unsafe { std::ptr::addr_of!((*ptr).struct_size).read() }) as usize
    }

    /// Reads the options at `ptr` (NULL: the defaults). `struct_size` is read first,
    /// alone, and no byte past it is read; the fields an older struct lacks take
    /// their defaults.
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
        check_struct(ptr, "opts")?;
        // SAFETY: non-NULL and aligned; the first field is present whatever the
        // version of the caller's struct.
        let size = unsafe { std::ptr::addr_of!((*ptr).struct_size).read() } as usize;
        if !SIZES.contains(&size) {
            return Err(Error::new(
                DsStatus::BadArgument,
                format!(
                    "opts.struct_size = {size} is not the size of a DsOptions of any version \
                     ({V01_SIZE}, {V02_SIZE}, {V03_SIZE}, {V04_SIZE}, {V05_SIZE} or {SIZE}): initialise \
                     the options with ds_options_init(&opts, sizeof opts)"
                ),
            ));
        }
        let mut value = DsOptions::default();
        // SAFETY: the caller's struct has `size` readable bytes (contract), a prefix
        // of DsOptions with the same fields at the same offsets (checked in the
        // tests); bytes are copied into a whole, initialised DsOptions.
        unsafe {
            std::ptr::copy_nonoverlapping(
                ptr.cast::<u8>(),
                (&mut value as *mut DsOptions).cast::<u8>(),
                size,
            )
        };
        if size == V01_SIZE {
            // The 4 bytes after max_inner were never the caller's: the default.
            value.dual_form = DsDualForm::Auto as i32;
        }
        // Fields past `size` keep the defaults `value` was made with.
        value.to_options()
    }
}

impl Default for DsOptions {
    fn default() -> Self {
        DsOptions::from_options(&Options::default())
    }
}

/// Fills the first `size` bytes of *opts with the defaults of the DsOptions of
/// that size: struct_size = size, method DS_METHOD_AUTO (from 0.6;
/// DS_METHOD_SPLIT before), tol 1e-10, max_outer 10000, max_inner 1000,
/// dual_form DS_DUAL_FORM_AUTO, max_seconds 0 (none), stall_window 100,
/// stall_factor 0.9, threads 0 (all cores), ordering DS_ORDERING_AUTO,
/// max_memory 0 (the machine's limit), host_loop 0. Pass sizeof(DsOptions) as
/// the caller sees it (the ds_options_default macro does): a program compiled
/// against an older header then gets its older struct filled, and nothing is
/// written past it.
///
/// Returns DS_STATUS_OK, DS_STATUS_NULL_POINTER (opts NULL) or
/// DS_STATUS_BAD_ARGUMENT (size is not the size of a DsOptions of any version: 32,
/// 40, 64, 72, 80 or 88; opts misaligned); nothing is written on error.
///
/// # Safety
/// `opts` must be NULL or point to `size` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_options_init(opts: *mut DsOptions, size: usize) -> DsStatus {
    entry("ds_options_init", || {
        check_struct(opts, "opts")?;
        if !SIZES.contains(&size) {
            return Err(Error::new(
                DsStatus::BadArgument,
                format!(
                    "size = {size} is not the size of a DsOptions of any version \
                     ({V01_SIZE}, {V02_SIZE}, {V03_SIZE}, {V04_SIZE} or {SIZE})"
                ),
            ));
        }
        let value = DsOptions {
            struct_size: size as u32,
            ..DsOptions::default()
        };
        // SAFETY: opts is non-NULL, aligned and writable for `size` bytes (contract).
        unsafe { write_prefix(&value, opts, size) };
        Ok(())
    })
}

/// The entry point of programs compiled against the headers of versions 0.1 and
/// 0.2 (the header of this version makes ds_options_default a macro that calls
/// ds_options_init with sizeof *opts). The caller's size is unknown here, so only
/// the 32 bytes of the smallest DsOptions (version 0.1) are written, with
/// struct_size = 32: a program built against 0.2 then runs with the default
/// dual_form, whatever it sets there. NULL is a no-op.
///
/// # Safety
/// `opts` must be NULL or point to at least 32 writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_options_default(opts: *mut DsOptions) {
    if opts.is_null() || !opts.is_aligned() {
        return;
    }
    let Ok(value) = catch_unwind(AssertUnwindSafe(|| DsOptions {
        struct_size: V01_SIZE as u32,
        ..DsOptions::default()
    })) else {
        return;
    };
    // SAFETY: non-NULL and aligned; at least 32 bytes writable per the contract.
    unsafe { write_prefix(&value, opts, V01_SIZE) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::{DualForm, Method};

    /// DsOptions as compiled against the 0.1 header.
    #[repr(C)]
    struct V01 {
        struct_size: u32,
        method: i32,
        tol: f64,
        max_outer: i64,
        max_inner: i64,
    }

    /// DsOptions as compiled against the 0.2 header.
    #[repr(C)]
    struct V02 {
        struct_size: u32,
        method: i32,
        tol: f64,
        max_outer: i64,
        max_inner: i64,
        dual_form: i32,
    }

    /// DsOptions as compiled against the 0.3 header.
    #[repr(C)]
    struct V03 {
        head: V02,
        max_seconds: f64,
        stall_window: i64,
        stall_factor: f64,
    }

    #[test]
    fn older_layouts_are_prefixes_of_this_one() {
        use std::mem::{offset_of, size_of};
        assert_eq!(size_of::<V01>(), V01_SIZE);
        assert_eq!(size_of::<V02>(), V02_SIZE);
        assert_eq!(SIZE, 88);
        assert_eq!(offset_of!(DsOptions, max_memory), V04_SIZE);
        assert_eq!(offset_of!(DsOptions, host_loop), V05_SIZE);
        assert_eq!(offset_of!(V01, tol), offset_of!(DsOptions, tol));
        assert_eq!(offset_of!(V01, max_inner), offset_of!(DsOptions, max_inner));
        assert_eq!(offset_of!(V02, dual_form), offset_of!(DsOptions, dual_form));
        assert_eq!(offset_of!(DsOptions, max_seconds), V02_SIZE);
        assert_eq!(
            offset_of!(DsOptions, stall_factor) + size_of::<f64>(),
            V03_SIZE
        );
        assert_eq!(offset_of!(DsOptions, threads), V03_SIZE);
        assert_eq!(size_of::<V03>(), V03_SIZE);
        assert_eq!(
            offset_of!(V03, stall_factor),
            offset_of!(DsOptions, stall_factor)
        );
    }

    #[test]
    fn init_fills_the_callers_size_and_nothing_past_it() {
        for size in SIZES {
            // A guard region after the caller's struct.
            let mut buf = [0xA5u8; 128];
            // An aligned start inside buf.
            let off = buf.as_ptr().align_offset(8);
            let ptr = buf.as_mut_ptr().wrapping_add(off).cast::<DsOptions>();
            // SAFETY: ptr is aligned and has at least 64 writable bytes of buf.
            assert_eq!(unsafe { ds_options_init(ptr, size) }, DsStatus::Ok);
            assert!(buf[off + size..].iter().all(|&b| b == 0xA5), "size {size}");
            // SAFETY: the struct just written has `size` bytes and says so.
            let read = unsafe { DsOptions::read(ptr) }.unwrap();
            assert_eq!(read, Options::default());
        }
        let mut o = DsOptions::default();
        // SAFETY: a whole DsOptions; the size is refused before any write.
        assert_eq!(
            unsafe { ds_options_init(&mut o, 48) },
            DsStatus::BadArgument
        );
        // SAFETY: NULL is refused.
        let st = unsafe { ds_options_init(std::ptr::null_mut(), SIZE) };
        assert_eq!(st, DsStatus::NullPointer);
    }

    #[test]
    fn the_legacy_default_writes_32_bytes_only() {
        let mut buf = [0xA5u8; 128];
        let off = buf.as_ptr().align_offset(8);
        let ptr = buf.as_mut_ptr().wrapping_add(off).cast::<DsOptions>();
        // SAFETY: aligned, 64 writable bytes.
        unsafe { ds_options_default(ptr) };
        assert!(buf[off + V01_SIZE..].iter().all(|&b| b == 0xA5));
        // SAFETY: a 0.1 struct that says so.
        let read = unsafe { DsOptions::read(ptr) }.unwrap();
        assert_eq!(read, Options::default());
        // SAFETY: NULL is a no-op.
        unsafe { ds_options_default(std::ptr::null_mut()) };
    }

    #[test]
    fn defaults_round_trip() {
        let o = DsOptions::default();
        assert_eq!(o.struct_size as usize, SIZE);
        assert_eq!(o.method, DsMethod::Auto as i32);
        assert_eq!((o.tol, o.max_outer, o.max_inner), (1e-10, 10_000, 1_000));
        assert_eq!(
            (o.max_seconds, o.stall_window, o.stall_factor),
            (0.0, 100, 0.9)
        );
        // SAFETY: o is a valid DsOptions.
        let read = unsafe { DsOptions::read(&o) };
        assert_eq!(read.unwrap(), Options::default());
        // SAFETY: NULL means defaults.
        let read = unsafe { DsOptions::read(std::ptr::null()) };
        assert_eq!(read.unwrap(), Options::default());
        let pgs = DsOptions {
            method: 2,
            max_seconds: 2.5,
            stall_window: 0,
            stall_factor: 1.0,
            ..o
        };
        // SAFETY: pgs is a valid DsOptions.
        let read = unsafe { DsOptions::read(&pgs) }.unwrap();
        assert_eq!(read.method, Method::Pgs);
        assert_eq!(
            (read.max_seconds, read.stall_window, read.stall_factor),
            (2.5, 0, 1.0)
        );
    }

    #[test]
    fn older_structs_read_with_the_defaults_of_the_fields_they_lack() {
        let old = V01 {
            struct_size: V01_SIZE as u32,
            method: DsMethod::Mprgp as i32,
            tol: 1e-8,
            max_outer: 7,
            max_inner: 9,
        };
        // SAFETY: old has the 0.1 layout and says so in struct_size.
        let read = unsafe { DsOptions::read(&old as *const V01 as *const DsOptions) }.unwrap();
        let want = Options {
            method: Method::Mprgp,
            tol: 1e-8,
            max_outer: 7,
            max_inner: 9,
            ..Options::default()
        };
        assert_eq!(read, want);
        let old = V02 {
            struct_size: V02_SIZE as u32,
            method: DsMethod::Mprgp as i32,
            tol: 1e-8,
            max_outer: 7,
            max_inner: 9,
            dual_form: DsDualForm::MatrixFree as i32,
        };
        // SAFETY: old has the 0.2 layout and says so in struct_size.
        let read = unsafe { DsOptions::read(&old as *const V02 as *const DsOptions) }.unwrap();
        let want = Options {
            dual_form: DualForm::MatrixFree,
            ..want
        };
        assert_eq!(read, want);
        // 0.3: threads and ordering take their defaults (all cores, AUTO), even
        // when the bytes after the caller's struct are not zero.
        let old = [
            V03 {
                head: V02 {
                    struct_size: V03_SIZE as u32,
                    ..old
                },
                max_seconds: 2.5,
                stall_window: 7,
                stall_factor: 0.5,
            },
            V03 {
                head: V02 {
                    struct_size: u32::MAX,
                    method: -1,
                    tol: f64::NAN,
                    max_outer: -1,
                    max_inner: -1,
                    dual_form: -1,
                },
                max_seconds: f64::NAN,
                stall_window: -1,
                stall_factor: f64::NAN,
            },
        ];
        // SAFETY: old[0] has the 0.3 layout and says so in struct_size; the bytes
        // after it (old[1], garbage as options) are never read.
        let read = unsafe { DsOptions::read(&old[0] as *const V03 as *const DsOptions) }.unwrap();
        let want = Options {
            max_seconds: 2.5,
            stall_window: 7,
            stall_factor: 0.5,
            ..want
        };
        assert_eq!(read, want);
        assert_eq!((read.threads, read.ordering), (0, crate::Ordering::Auto));
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
            (DsOptions { method: 7, ..o }, "opts.method = 7"),
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
            (
                DsOptions {
                    max_seconds: -1.0,
                    ..o
                },
                "opts.max_seconds = -1",
            ),
            (
                DsOptions {
                    max_seconds: f64::NAN,
                    ..o
                },
                "opts.max_seconds = NaN",
            ),
            (
                DsOptions {
                    stall_window: -2,
                    ..o
                },
                "opts.stall_window = -2",
            ),
            (
                DsOptions {
                    stall_factor: 0.0,
                    ..o
                },
                "opts.stall_factor = 0",
            ),
            (
                DsOptions {
                    stall_factor: 1.5,
                    ..o
                },
                "opts.stall_factor = 1.5",
            ),
            (DsOptions { threads: 5000, ..o }, "opts.threads = 5000"),
            (DsOptions { ordering: 3, ..o }, "opts.ordering = dense"),
            (DsOptions { host_loop: 2, ..o }, "opts.host_loop = 2"),
        ];
        for (bad, text) in cases {
            // SAFETY: bad is a valid DsOptions.
            let e = unsafe { DsOptions::read(&bad) }.unwrap_err();
            assert_eq!(e.status, DsStatus::BadArgument);
            assert!(e.message.contains(text), "{} lacks {text}", e.message);
        }
    }
}
