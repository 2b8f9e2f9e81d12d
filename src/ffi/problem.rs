//! The opaque problem handle and the `extern "C"` entry points that use it.
//!
//! Sign conventions (docs/design.md section 1): K u = f - N^T lambda_N - T^T lambda_T;
//! N u <= g; lambda_N >= 0 is the compressive normal force; the friction force on
//! the body, -T^T lambda_T, opposes the slip T u.

use super::boundary::{OutArray, entry, optional_in, ref_in, ref_mut, slice_in};
use super::cost::DsCost;
use super::error::{CError as Error, CResult as Result};
use super::matrix::DsMatrix;
use super::monitor::{DsLogFn, DsMonitorFn, LOG_ITERATIONS, LOG_SILENT, Watch};
use super::options::DsOptions;
use super::status::DsStatus;
use super::types::{CEnum, DsFriction};
use crate::friction::Friction;
use crate::problem::ContactProblem;
use std::cell::UnsafeCell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering as AtomicOrdering};

/// An opaque contact problem: K factored once, the contact matrices N and T, the
/// condensed dual, and the history of a quasistatic simulation (ds_step). Created by
/// ds_problem_new, freed by ds_problem_free. A handle may be used from any thread,
/// but by one thread at a time. A call on a handle that is inside another call on it
/// (a monitor, log sink or host callback re-entering it) returns DS_STATUS_BUSY and
/// changes nothing.
pub struct DsProblem {
    /// Set while a call holds the handle (see [`lend`]).
    busy: AtomicBool,
    /// What the handle holds; reached only through a [`Lent`].
    state: UnsafeCell<Handle>,
}

/// What a handle holds.
pub(super) struct Handle {
    /// The safe Rust problem this handle owns.
    pub(super) inner: ContactProblem,
    /// Monitor callback and log settings.
    pub(super) watch: Watch,
    /// What the last ds_solve or ds_step that returned a report cost (see
    /// ds_problem_last_cost); None before any.
    pub(super) last_cost: Option<DsCost>,
}

impl DsProblem {
    /// A handle owning `inner`, without monitor, log or past solve.
    pub(super) fn boxed(inner: ContactProblem) -> *mut DsProblem {
        Box::into_raw(Box::new(DsProblem {
            busy: AtomicBool::new(false),
            state: UnsafeCell::new(Handle {
                inner,
                watch: Watch::default(),
                last_cost: None,
            }),
        }))
    }
}

/// A handle lent to one call: its state, exclusively, until the lease drops.
pub(super) struct Lent<'a> {
    busy: &'a AtomicBool,
    handle: &'a mut Handle,
}

impl std::ops::Deref for Lent<'_> {
    type Target = Handle;
    fn deref(&self) -> &Handle {
        self.handle
    }
}

impl std::ops::DerefMut for Lent<'_> {
    fn deref_mut(&mut self) -> &mut Handle {
        self.handle
    }
}

impl Drop for Lent<'_> {
    fn drop(&mut self) {
        self.busy.store(false, AtomicOrdering::Release);
    }
}

/// The handle at `ptr` for one call. The lease ends when the value drops,
/// also when the call panics.
///
/// Errors: `NullPointer`, `BadArgument` (misaligned), `Busy` (a call on the
/// handle is running: a callback re-entered it).
///
/// # Safety
/// If not NULL, `ptr` must point to a live handle from ds_problem_new*.
pub(super) unsafe fn lend<'a>(ptr: *const DsProblem, what: &str) -> Result<Lent<'a>> {
    // SAFETY: validity is the caller's contract. A shared reference may
    // coexist with the running call's lease: its state sits in an UnsafeCell
    // and `busy` is atomic.
    let problem: &'a DsProblem = unsafe { ref_in(ptr, what)? };
    if problem
        .busy
        .compare_exchange(
            false,
            true,
            AtomicOrdering::Acquire,
            AtomicOrdering::Relaxed,
        )
        .is_err()
    {
        return Err(Error::new(
            DsStatus::Busy,
            format!(
                "{what} is inside another call on it (a callback re-entered its own \
                 handle): nothing was changed"
            ),
        ));
    }
    Ok(Lent {
        busy: &problem.busy,
        // SAFETY: `busy` was false and is now ours: no other reference to the
        // state exists until this lease drops and clears it.
        handle: unsafe { &mut *problem.state.get() },
    })
}

/// The contact dimension d as `usize`, or `BadArgument`.
pub(super) fn dimension(d: i32) -> Result<usize> {
    match d {
        2 => Ok(2),
        3 => Ok(3),
        _ => Err(Error::new(
            DsStatus::BadArgument,
            format!("d = {d} is not 2 or 3 (the contact dimension)"),
        )),
    }
}

/// Creates a contact problem: validates K, N, T, factors K (sparse Cholesky) and
/// forms the condensed dual on the contact interface. The matrices are only read
/// during the call; the caller keeps ownership.
///
/// - d: contact dimension, 2 or 3.
/// - k: stiffness K, n x n, symmetric positive definite (Dirichlet conditions
///   applied), FULL (checked for symmetry), UPPER or LOWER storage.
/// - n: normals N, m x n, FULL storage; row i gives (N u)_i, the displacement of
///   contact i towards the foundation, constrained by N u <= g.
/// - t: tangents T, (d-1) m x n, FULL storage; in 3D rows 2i and 2i+1 belong to
///   contact i.
/// - out: receives the new handle on success; untouched on error.
///
/// m = 0 is allowed (N and T with no rows). Returns DS_STATUS_OK, or
/// DS_STATUS_NULL_POINTER, DS_STATUS_BAD_ARGUMENT (d, enum fields, triangle storage of
/// N or T), DS_STATUS_BAD_SIZE (K not square, N or T not n columns, T not (d-1) m
/// rows, negative sizes), DS_STATUS_BAD_INDEX, DS_STATUS_NOT_FINITE,
/// DS_STATUS_NOT_SYMMETRIC, DS_STATUS_NOT_POSITIVE_DEFINITE, DS_STATUS_OUT_OF_MEMORY.
///
/// # Safety
/// Each pointer must be NULL or valid: k, n, t point to DsMatrix structs whose arrays
/// match their fields; out points to a writable DsProblem*.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_new(
    d: i32,
    k: *const DsMatrix,
    n: *const DsMatrix,
    t: *const DsMatrix,
    out: *mut *mut DsProblem,
) -> DsStatus {
    entry("ds_problem_new", || {
        // SAFETY: pointer validity is this function's contract; NULL is rejected.
        let (k, n, t, out) = unsafe {
            (
                ref_in(k, "k")?,
                ref_in(n, "n")?,
                ref_in(t, "t")?,
                ref_mut(out, "out")?,
            )
        };
        let d = dimension(d)?;
        // SAFETY: the matrices' arrays match their fields (contract).
        let (kv, nv, tv) = unsafe { (k.view("K")?, n.view("N")?, t.view("T")?) };
        let inner = ContactProblem::new(d, &kv, &nv, &tv)?;
        *out = DsProblem::boxed(inner);
        Ok(())
    })
}

/// As ds_problem_new, with the options that apply to the handle itself: opts->threads
/// (the handle's own thread pool, used by every later call on it) and
/// opts->ordering (the fill-reducing ordering of K). The other fields are checked
/// as ds_solve checks them, and not kept. opts = NULL: the defaults, as
/// ds_problem_new.
///
/// Returns what ds_problem_new returns; DS_STATUS_BAD_ARGUMENT also for invalid
/// options (see DsOptions).
///
/// # Safety
/// As ds_problem_new; opts must be NULL or point to a DsOptions initialised with
/// ds_options_init (at least struct_size readable bytes).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_new_opts(
    d: i32,
    k: *const DsMatrix,
    n: *const DsMatrix,
    t: *const DsMatrix,
    opts: *const DsOptions,
    out: *mut *mut DsProblem,
) -> DsStatus {
    entry("ds_problem_new_opts", || {
        // SAFETY: pointer validity is this function's contract; NULL is rejected.
        let (k, n, t, out) = unsafe {
            (
                ref_in(k, "k")?,
                ref_in(n, "n")?,
                ref_in(t, "t")?,
                ref_mut(out, "out")?,
            )
        };
        // SAFETY: opts is NULL or a readable DsOptions prefix (contract).
        let opts = unsafe { DsOptions::read(opts)? };
        let d = dimension(d)?;
        // SAFETY: the matrices' arrays match their fields (contract).
        let (kv, nv, tv) = unsafe { (k.view("K")?, n.view("N")?, t.view("T")?) };
        let inner = ContactProblem::with_options(d, &kv, &nv, &tv, &opts)?;
        *out = DsProblem::boxed(inner);
        Ok(())
    })
}

/// Frees a handle created by ds_problem_new or ds_problem_new_opts. NULL is a no-op. The handle must not be
/// used afterwards. A handle inside another call on it (freed by a callback of
/// that call) is not freed: ds_last_error_message() says so inside the callback
/// (the call that ran it clears the message when it succeeds).
///
/// # Safety
/// `problem` must be NULL or a handle from ds_problem_new not freed before.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_free(problem: *mut DsProblem) {
    if problem.is_null() {
        return;
    }
    // A handle freed from inside a call on it (by a callback) would be used
    // after the free when the callback returns: it is kept, and the message says so.
    // SAFETY: a live handle (contract): its `busy` flag is atomic and may be
    // read beside a running call.
    if unsafe { (*problem).busy.load(AtomicOrdering::Acquire) } {
        super::last_error::set(
            "ds_problem_free: the handle is inside another call on it (a callback \
             re-entered it): not freed; free it after that call returns",
        );
        return;
    }
    // SAFETY: the handle came from Box::into_raw in ds_problem_new (contract).
    let boxed = unsafe { Box::from_raw(problem) };
    if let Err(payload) = catch_unwind(AssertUnwindSafe(move || drop(boxed))) {
        super::last_error::set(&format!(
            "ds_problem_free: internal panic: {}",
            super::boundary::panic_message(&payload)
        ));
        super::boundary::drop_payload(payload);
    }
}

/// Refactors K with new values and the same sparsity pattern and storage as the K
/// given to ds_problem_new (e.g. after a geometric or material update); rebuilds the
/// condensed dual. The history of ds_step and the multipliers the next
/// ds_solve_iteration starts from are kept. On error the handle is unchanged.
/// What depends on K's pattern alone is not recomputed: K's analysis, and a
/// matrix-free dual's layered preconditioner's layers and analyses.
///
/// A matrix-free dual keeps the contacts' diagonal blocks of the K they were
/// computed on (they cost 0.7-1.4 factorisations to compute afresh) where a
/// few Lanczos steps (at most 10 single-precision solves with the new K; 2
/// where K moved by at most 1 % from the K of the last refactor, which kept
/// them too, and that step is small) estimate that they drifted so little
/// that err, with rho from them, is at
/// most 3 times err on the new K's own blocks; err is then reported
/// multiplied by that estimated factor (DsInfo.err_factor), so that it
/// bounds the err of the new K as far as the estimate holds, and
/// DsInfo.blocks_age counts the refactors since the blocks were computed.
/// Otherwise they are computed afresh (docs/design.md section 9).
///
/// A K in coordinate format (DS_FORMAT_COO, any storage) whose triplets all
/// fall on the pattern the handle holds and cover it is placed triplet by
/// triplet instead of sorted and summed afresh (the same matrix, bit for
/// bit): at the slot where the triplet of the same number fell at the last
/// refactor where it still lies there (a host that assembles in a fixed
/// order), else by a binary search in its column. The handle keeps those
/// slots: 4 bytes per triplet (8 where one triangle is given), and where K
/// comes in full storage the places of its pattern's mirror pairs for the
/// symmetry check (4 bytes per entry off the diagonal), counted from then on
/// in DsInfo.resident_bytes and the predictions made on it.
///
/// A K in compressed columns (DS_FORMAT_CSC) whose pointers and row indices
/// are those of the pattern the handle holds (full storage), or of its upper
/// or lower triangle (one-triangle storage), rows sorted in each column, has
/// its values copied instead of converted afresh (the same matrix, bit for
/// bit); in full storage the handle then keeps its pattern's mirror places
/// for the symmetry check, as above.
///
/// The replaced factor's values (8 DsInfo.factor_nnz bytes for a sparse
/// K, 8 n^2 for a dense one; the refactor held them beside the new ones
/// anyway) stay on the handle as the next refactor's storage, which then
/// factors into memory the process already has instead of new pages the
/// system must fault in and zero (0.1-0.3 s of a 0.6 s numeric
/// factorisation of a 38-million entry L, measured). A refactor that
/// fails keeps them. They count in DsInfo.resident_bytes and solve_bytes,
/// not in refactor_bytes, which does not grow; a solve or
/// ds_problem_set_contacts that fits its max_memory only without them
/// frees them first, and ds_problem_free frees them.
///
/// Returns DS_STATUS_OK, or the errors of ds_problem_new for K, and
/// DS_STATUS_BAD_ARGUMENT if the pattern differs.
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle; `k` NULL or a valid DsMatrix.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_refactor(
    problem: *mut DsProblem,
    k: *const DsMatrix,
) -> DsStatus {
    entry("ds_problem_refactor", || {
        // SAFETY: pointer validity is this function's contract; NULL is rejected.
        let (mut problem, k) = unsafe { (lend(problem, "problem")?, ref_in(k, "k")?) };
        // SAFETY: K's arrays match its fields (contract).
        let kv = unsafe { k.view("K")? };
        Ok(problem.inner.refactor(&kv)?)
    })
}

/// Replaces the contact matrices N (m x n) and T ((d-1) m x n) without refactoring
/// K; m may change. Rebuilds the condensed dual. On error the handle is unchanged.
///
/// Returns DS_STATUS_OK, or the errors of ds_problem_new for N and T.
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle; `n`, `t` NULL or valid DsMatrix structs.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_set_contacts(
    problem: *mut DsProblem,
    n: *const DsMatrix,
    t: *const DsMatrix,
) -> DsStatus {
    entry("ds_problem_set_contacts", || {
        // SAFETY: pointer validity is this function's contract; NULL is rejected.
        let (mut problem, n, t) =
            unsafe { (lend(problem, "problem")?, ref_in(n, "n")?, ref_in(t, "t")?) };
        // SAFETY: the matrices' arrays match their fields (contract).
        let (nv, tv) = unsafe { (n.view("N")?, t.view("T")?) };
        Ok(problem.inner.set_contacts(&nv, &tv)?)
    })
}

/// The sizes of a problem: *n_dofs = n (length of f and u), *n_contacts = m (length
/// of g, bound and lambda_n), *d = contact dimension (lambda_t has (d-1) m values).
///
/// Returns DS_STATUS_OK or DS_STATUS_NULL_POINTER (any argument NULL); outputs are
/// written only on success, in the order n_dofs, n_contacts, d (two of them may be
/// the same address: the later value stays).
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle; the outputs NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_sizes(
    problem: *const DsProblem,
    n_dofs: *mut i64,
    n_contacts: *mut i64,
    d: *mut i32,
) -> DsStatus {
    entry("ds_problem_sizes", || {
        // SAFETY: the handle is NULL or live (contract); NULL is rejected.
        let problem = unsafe { lend(problem, "problem")? };
        // The outputs are written through raw pointers, never as references: a
        // caller may pass the same address twice.
        let n_dofs = OutArray::new(n_dofs, 1, "n_dofs")?;
        let n_contacts = OutArray::new(n_contacts, 1, "n_contacts")?;
        let d = OutArray::new(d, 1, "d")?;
        let p = &problem.inner;
        let too_big = |_| Error::new(DsStatus::BadSize, "size does not fit in int64_t");
        let (nd, nc) = (
            i64::try_from(p.n_dofs()).map_err(too_big)?,
            i64::try_from(p.n_contacts()).map_err(too_big)?,
        );
        let dim = i32::try_from(p.dim()).map_err(too_big)?;
        // SAFETY: each output is non-NULL, aligned and writable (checked above and
        // the contract); the writes are sequential, so equal addresses are fine.
        unsafe {
            n_dofs.write(&[nd])?;
            n_contacts.write(&[nc])?;
            d.write(&[dim])?;
        }
        Ok(())
    })
}

/// Sets the interface law of every contact (docs/design.md section 8), kept on
/// the handle until changed; each array holds m values (one per contact), NULL
/// for its default:
///
/// - c_n: normal compliance c_N,i > 0, lambda_N,i = c_N,i (N u - g)_i+^m_N,i
///   (force / length^m_N; fold the nodal area in, as for every nodal force);
///   INFINITY (the default) is Signorini's rigid contact;
/// - m_n: its exponent 1 <= m_N,i <= 10 (default 1; above 1 the law is
///   solved by Newton on the law, a few solves of its tangent);
/// - k_t: tangential stiffness k_T,i > 0 (force / length), the elastic slip
///   ("stick slope") of penalty codes: lambda_T,i is the projection onto the
///   friction disc of lambda_T,prev + k_T,i T u, lambda_T,prev zero in ds_solve
///   and the last step's force in a ds_step history (u then the increment);
///   INFINITY (the default) is rigid stick.
///
/// Rigid and compliant contacts mix. In a history the elastic slip
/// lambda_T / k_T carries over: where k_T,i changes, the next step starts from
/// the force scaled by k_T,new / k_T,old (zero where either is INFINITY).
/// ds_problem_set_contacts with another m makes every contact rigid. All
/// three NULL: every contact rigid. The report's err is then the natural map
/// of the regularised conditions; ds_problem_info counts the compliant
/// contacts (DsInfo.compliant_contacts, power_law_contacts). Added in version
/// 0.8.
///
/// Returns DS_STATUS_OK, DS_STATUS_NULL_POINTER (problem), DS_STATUS_NOT_FINITE
/// (NaN, -INFINITY, an infinite m_N), DS_STATUS_BAD_ARGUMENT (c_N <= 0, m_N
/// outside [1, 10], k_T <= 0, a c_N or k_T below about 5.6e-309 whose
/// reciprocal overflows). On error the handle keeps its previous law.
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle; each array NULL or valid for m
/// reads.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_set_compliance(
    problem: *mut DsProblem,
    c_n: *const f64,
    m_n: *const f64,
    k_t: *const f64,
) -> DsStatus {
    entry("ds_problem_set_compliance", || {
        // SAFETY: NULL is rejected; otherwise a live handle (contract).
        let mut problem = unsafe { lend(problem, "problem")? };
        let m = problem.inner.n_contacts();
        // SAFETY: each array is NULL or holds m values (contract).
        let (cn, mn, kt) = unsafe {
            (
                optional_in(c_n, m, "c_n")?,
                optional_in(m_n, m, "m_n")?,
                optional_in(k_t, m, "k_t")?,
            )
        };
        Ok(problem.inner.set_compliance(cn, mn, kt)?)
    })
}

/// Forgets the history of ds_step (u_0 = 0 and no warm start) and the
/// multipliers the next ds_solve_iteration would start from.
///
/// Returns DS_STATUS_OK or DS_STATUS_NULL_POINTER.
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_history_reset(problem: *mut DsProblem) -> DsStatus {
    entry("ds_history_reset", || {
        // SAFETY: NULL is rejected; otherwise a live handle (contract).
        let mut problem = unsafe { lend(problem, "problem")? };
        problem.inner.reset_history();
        Ok(())
    })
}

/// Sets (or, with monitor = NULL, clears) the monitor callback of the handle: it is
/// called after every outer iteration of ds_solve and ds_step with a DsProgress and
/// `user_data`; a nonzero return stops the solve, which then returns
/// DS_STATUS_STOPPED with the last iterate written to u, lambda_n, lambda_t and the
/// report (the history of ds_step does not advance). See DsMonitorFn for what the
/// callback must not do.
///
/// Returns DS_STATUS_OK or DS_STATUS_NULL_POINTER (problem).
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle; `monitor` NULL or a function that is
/// safe to call with any DsProgress and `user_data` while the handle is in use.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_set_monitor(
    problem: *mut DsProblem,
    monitor: DsMonitorFn,
    user_data: *mut std::ffi::c_void,
) -> DsStatus {
    entry("ds_problem_set_monitor", || {
        // SAFETY: NULL is rejected; otherwise a live handle (contract).
        let mut problem = unsafe { lend(problem, "problem")? };
        problem.watch.monitor = monitor;
        problem.watch.monitor_data = user_data;
        Ok(())
    })
}

/// Sets the log level and sink of the handle. level: 0 silent (the default: the
/// library never prints unless asked), 1 one summary line per solve, 2 also one
/// line per outer iteration. Lines go to `log(level, message, user_data)`, or to
/// stderr when `log` is NULL.
///
/// Returns DS_STATUS_OK, DS_STATUS_NULL_POINTER (problem) or DS_STATUS_BAD_ARGUMENT
/// (level not 0, 1 or 2; nothing changed).
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle; `log` NULL or a function that is safe to
/// call with any level, message and `user_data` while the handle is in use.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_set_log(
    problem: *mut DsProblem,
    level: i32,
    log: DsLogFn,
    user_data: *mut std::ffi::c_void,
) -> DsStatus {
    entry("ds_problem_set_log", || {
        // SAFETY: NULL is rejected; otherwise a live handle (contract).
        let mut problem = unsafe { lend(problem, "problem")? };
        if !(LOG_SILENT..=LOG_ITERATIONS).contains(&level) {
            return Err(Error::new(
                DsStatus::BadArgument,
                format!("level = {level}: the log level must be 0, 1 or 2"),
            ));
        }
        problem.watch.level = level;
        problem.watch.log = log;
        problem.watch.log_data = user_data;
        Ok(())
    })
}

/// Writes the problem of the handle with one increment's f, g and friction data to
/// the folder `dir` as Matrix Market and text files (K.mtx, N.mtx, T.mtx, f.txt,
/// g.txt, and mu.txt for DS_FRICTION_COULOMB or p.txt for DS_FRICTION_TRESCA), so
/// that a failing increment can be replayed outside the host program with
/// `dualsplit solve DIR --out OUT`. The folder is created if needed; existing files
/// of those names are replaced. For a ds_step history, pass the increment's data
/// (f_total - K u_k and g0 - N u_k), or the step's totals after ds_history_reset.
/// A compliant interface (ds_problem_set_compliance) is written too: cn.txt,
/// mn.txt, kt.txt, and in a history lt_prev.txt, the tangential force the next
/// step's return mapping starts from; a rigid one removes those files.
///
/// - dir: a NUL-terminated path (UTF-8).
/// - friction, f (n), g (m), bound (m): as ds_solve.
///
/// Returns DS_STATUS_OK, DS_STATUS_NULL_POINTER, DS_STATUS_BAD_ARGUMENT (friction,
/// dir not UTF-8), DS_STATUS_NOT_FINITE, DS_STATUS_NEGATIVE_FRICTION or
/// DS_STATUS_IO_ERROR (the folder or a file cannot be written).
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// `problem` must be NULL or a live handle, `dir` NULL or a NUL-terminated string,
/// the arrays NULL or valid for n, m and m values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_dump(
    problem: *const DsProblem,
    dir: *const std::ffi::c_char,
    friction: i32,
    f: *const f64,
    g: *const f64,
    bound: *const f64,
) -> DsStatus {
    entry("ds_problem_dump", || {
        // SAFETY: NULL is rejected; otherwise a live handle (contract).
        let problem = unsafe { lend(problem, "problem")? };
        if dir.is_null() {
            return Err(Error::new(DsStatus::NullPointer, "dir is NULL"));
        }
        // SAFETY: dir is a NUL-terminated string (contract).
        let dir = unsafe { std::ffi::CStr::from_ptr(dir) }
            .to_str()
            .map_err(|_| Error::new(DsStatus::BadArgument, "dir is not valid UTF-8"))?;
        let law = DsFriction::parse(friction, "friction")?;
        let (n, m) = (problem.inner.n_dofs(), problem.inner.n_contacts());
        // SAFETY: the arrays hold n, m, m values (contract); NULL only if empty.
        let (f, g, bound) = unsafe {
            (
                slice_in(f, n, "f")?,
                slice_in(g, m, "g")?,
                slice_in(bound, m, "bound")?,
            )
        };
        let law = match law {
            DsFriction::Tresca => Friction::Tresca(bound),
            DsFriction::Coulomb => Friction::Coulomb(bound),
        };
        let dir = std::path::Path::new(dir);
        Ok(problem.inner.write_folder(dir, f, g, law)?)
    })
}
