//! The host's own solver of K across the C boundary: `DsHostSolver` (the
//! callback and its context) and `ds_problem_new_host`, a handle whose every
//! solve with K is the host's (the Rust side: `host.rs`,
//! [`crate::ContactProblem::with_host_solver`]).

use super::boundary::{check_struct, entry, ref_in, ref_mut};
use super::error::{CError as Error, CResult as Result};
use super::matrix::DsMatrix;
use super::options::DsOptions;
use super::problem::{DsProblem, dimension};
use super::status::DsStatus;
use super::types::{CEnum, DsHostBlocks};
use crate::host::KSolve;
use crate::problem::ContactProblem;
use std::ffi::c_void;

/// The host's solve with K: overwrite x (n x ncols, column-major, leading
/// dimension ld, ld = n) with K^-1 x, for the `context` given in
/// DsHostSolver. Return 0 on success; any other value is an error code of the
/// host's, which the library reports as DS_STATUS_HOST_SOLVE_FAILED with the
/// code in ds_last_error_message(). A NaN or infinity in x afterwards is
/// reported the same way. The library calls it only from the thread that
/// called into the handle, one call at a time; it must not call into the same
/// handle, and must not longjmp out of (or throw a C++ exception through) the
/// library.
///
/// SPMD over MPI: every rank creates its handle with the same N, T, K (or
/// none), options and load, and runs the same calls. The library's contact
/// iteration then takes the same branches on every rank and calls `solve` the
/// same number of times, in the same order, so the callback may be a
/// collective distributed solve (a PETSc KSP); given bitwise identical
/// outputs of the callback on every rank, and threads = 1 in the options,
/// every rank computes bitwise identical multipliers and u
/// (c_examples/petsc_operator.c checks it on 2 ranks). With more threads the
/// library's own parallel kernels may sum in another order on each rank.
/// The same calls take the same branches only where nothing local to a rank
/// decides one:
/// - max_seconds = 0 (a time limit ends each rank's solve at its own
///   iteration);
/// - the same nonzero max_memory on every rank (with 0 the limit is each
///   machine's own memory, and the AUTO choices that weigh memory, such as
///   DS_HOST_BLOCKS_AUTO's factor, may differ between ranks);
/// - a monitor that returns the same value on every rank, and a callback that
///   fails on every rank or on none (a failure on one rank ends its call
///   there while the others wait in the next collective solve);
/// - no allocation that fails on one rank alone (the library's fallbacks for
///   a failed large allocation, such as AMD where METIS runs out of memory,
///   are taken per rank): size max_memory below what every rank has.
pub type DsHostSolveFn = Option<
    unsafe extern "C" fn(context: *mut c_void, n: i64, ncols: i64, x: *mut f64, ld: i64) -> i32,
>;

/// Optional: the host's solve with K in single precision: as DsHostSolveFn,
/// on floats. The library calls it for the products whose accuracy allows a
/// relative error of about 1e-7 cond(K)^(1/2) (the Krylov solves of
/// Newton's reduced systems, none asked for less than a relative residual
/// of 1e-4 where this is offered, as its own factor's single-precision copy
/// of L serves them): half
/// the memory traffic of a solve in double where the host holds its factor in
/// single precision too (CHOLMOD 5, MUMPS's SMUMPS, PARDISO); an iterative
/// host may answer with a solve to a looser tolerance (relative residual
/// about 1e-7). Every gradient and residual the library trusts comes from
/// `solve`, so a rougher answer here costs iterations, never accuracy. Errors
/// and the rules of calling as DsHostSolveFn; on MPI, as collective as
/// `solve`. Added in version 0.10.
pub type DsHostSolveSingleFn = Option<
    unsafe extern "C" fn(context: *mut c_void, n: i64, ncols: i64, x: *mut f32, ld: i64) -> i32,
>;

/// Optional: the host's solve with K on a sparse right-hand side, wanted on
/// its own rows: x (nrows x ncols, column-major, leading dimension ld =
/// nrows) holds the right-hand sides' entries at the DOFs rows[0..nrows]
/// (0-based, ascending, distinct; every other entry of the right-hand sides
/// is zero), and is overwritten with the solutions' entries at the same
/// DOFs. A direct solver may answer it on the paths of those DOFs in its
/// elimination tree alone (PARDISO's partial solve, iparm(31) in Fortran
/// numbering), a fraction of a whole solve where the contact DOFs lie in few
/// of its subtrees. Offer
/// it only where it is cheaper than your whole solve: answered by a whole
/// solve (scatter the entries into an n-vector, solve, gather) it gains
/// nothing, and CHOLMOD's cholmod_solve2 with Bset, column by column on a
/// simplicial copy of the factor, was slower than its supernodal whole solve
/// on the benchmark's 3D blocks. The library calls it for every product
/// with the condensed operator, one right-hand side per call (rows: the
/// contact DOFs, or those of a Newton step's reduced unknowns, which change
/// from call to call); the contacts' diagonal blocks at creation (32
/// right-hand sides per call), the right-hand side B K^-1 f and the recovery
/// of u stay calls of `solve`. approximate = 1: a relative
/// error of about 1e-7 cond(K)^(1/2) serves (a single-precision solve, a
/// looser tolerance), as for DsHostSolveSingleFn; approximate = 0: the answer
/// must be as accurate as `solve`'s. Errors and the rules of calling as
/// DsHostSolveFn; on MPI, as collective as `solve`. Added in version 0.10.
pub type DsHostSolveRowsFn = Option<
    unsafe extern "C" fn(
        context: *mut c_void,
        nrows: i64,
        rows: *const i64,
        ncols: i64,
        x: *mut f64,
        ld: i64,
        approximate: i32,
    ) -> i32,
>;

/// Optional: the entries of K^-1 at given positions, as a direct solver with
/// selected inversion computes them (MUMPS's ICNTL(30), PETSc's
/// MatMumpsGetInverse, PARDISO's selected inversion): entry k of values :=
/// the entry of K^-1 at row (entry k of rows) and column (entry k of cols),
/// for k < count, 0-based DOFs, row <= column.
/// Called once at creation (and by ds_problem_set_contacts) for the DOFs of
/// each contact with each other, instead of d m solves. Return 0, or an error
/// code as DsHostSolveFn does; the same rules of calling apply.
pub type DsHostInverseFn = Option<
    unsafe extern "C" fn(
        context: *mut c_void,
        count: i64,
        rows: *const i64,
        cols: *const i64,
        values: *mut f64,
    ) -> i32,
>;

/// The host's solver of K, handed to ds_problem_new_host. Set struct_size =
/// sizeof(DsHostSolver), and the optional callbacks to NULL where not given
/// (zero the struct first): later versions may add optional callbacks at the
/// end and will accept this size. 40 bytes (version 0.9: up to
/// inverse_entries) is accepted too; the library reads no byte past
/// struct_size.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct DsHostSolver {
    /// sizeof(DsHostSolver) as the caller's header defines it.
    pub struct_size: u32,
    /// The number of DOFs n (K is n x n, symmetric positive definite), >= 1.
    pub n: i64,
    /// K^-1 applied to a block of right-hand sides (required).
    pub solve: DsHostSolveFn,
    /// Passed to `solve` unchanged; the library never reads it. Must stay
    /// valid until the handle is freed.
    pub context: *mut c_void,
    /// Entries of K^-1 (optional, NULL: the contacts' blocks by solves).
    pub inverse_entries: DsHostInverseFn,
    /// The solve in single precision (optional, NULL: every product calls
    /// `solve`). Added in version 0.10.
    pub solve_single: DsHostSolveSingleFn,
    /// The solve on a sparse right-hand side wanted on its own rows
    /// (optional, NULL: every product is a whole solve). Added in version
    /// 0.10.
    pub solve_rows: DsHostSolveRowsFn,
    /// How the contacts' blocks are obtained: a DsHostBlocks value (0,
    /// DS_HOST_BLOCKS_AUTO, in a zeroed struct). Added in version 0.10.
    pub blocks: i32,
}

/// sizeof(DsHostSolver) of version 0.9 (up to inverse_entries).
const HOST_V09_SIZE: usize = 40;
const _: () = assert!(std::mem::offset_of!(DsHostSolver, solve_single) == HOST_V09_SIZE);

impl DsHostSolver {
    /// The caller's DsHostSolver of its version (40 bytes, or the whole
    /// struct): the fields an older struct lacks are NULL.
    ///
    /// Errors: `NullPointer`, `BadArgument` (misaligned, or struct_size not
    /// an accepted size).
    ///
    /// # Safety
    /// `ptr` must be NULL or point to struct_size readable bytes of a
    /// DsHostSolver.
    unsafe fn read(ptr: *const DsHostSolver) -> Result<DsHostSolver> {
        check_struct(ptr, "solver")?;
        // SAFETY: non-NULL and aligned; struct_size, a u32 at offset 0, is in
        // every version.
        let size = unsafe { ptr.cast::<u32>().read() } as usize;
        let full = std::mem::size_of::<DsHostSolver>();
        if size != HOST_V09_SIZE && size != full {
            return Err(Error::new(
                DsStatus::BadArgument,
                format!(
                    "solver->struct_size = {size}: set it to sizeof(DsHostSolver) = {full} \
                     ({HOST_V09_SIZE} from version 0.9 headers is accepted too)"
                ),
            ));
        }
        // SAFETY: every field of DsHostSolver is valid at all-zero bits (an
        // integer, a NULL pointer, None for a callback).
        let mut value: DsHostSolver = unsafe { std::mem::zeroed() };
        // SAFETY: ptr is readable for `size` <= sizeof(DsHostSolver) bytes
        // (contract); value is a whole local DsHostSolver, no overlap.
        unsafe {
            std::ptr::copy_nonoverlapping(
                ptr.cast::<u8>(),
                (&mut value as *mut DsHostSolver).cast::<u8>(),
                size,
            )
        };
        Ok(value)
    }
}

/// The callback as the safe core sees it.
struct CHost {
    n: usize,
    solve: unsafe extern "C" fn(*mut c_void, i64, ncols: i64, *mut f64, i64) -> i32,
    solve_single: DsHostSolveSingleFn,
    solve_rows: DsHostSolveRowsFn,
    /// The rows of the last call of `solve_rows`, as the callback takes them.
    rows: Vec<i64>,
    inverse: DsHostInverseFn,
    context: *mut c_void,
}

// SAFETY: the context pointer is only passed back to the host's callback, which
// the library calls from the thread that calls into the handle, one call at a
// time; DsHostSolver's documentation makes the same promise to the caller.
unsafe impl Send for CHost {}

impl KSolve for CHost {
    fn n(&self) -> usize {
        self.n
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> std::result::Result<(), i32> {
        let n = self.n as i64;
        // SAFETY: x holds n x ncols doubles, column-major with leading
        // dimension n, as the callback's contract states; the context is the
        // caller's, passed back unchanged.
        let rc = unsafe { (self.solve)(self.context, n, ncols as i64, x.as_mut_ptr(), n) };
        if rc == 0 { Ok(()) } else { Err(rc) }
    }

    fn solve_single(
        &mut self,
        x: &mut [f32],
        ncols: usize,
    ) -> Option<std::result::Result<(), i32>> {
        let f = self.solve_single?;
        let n = self.n as i64;
        // SAFETY: x holds n x ncols floats, column-major with leading
        // dimension n, as the callback's contract states; the context is the
        // caller's, passed back unchanged.
        let rc = unsafe { f(self.context, n, ncols as i64, x.as_mut_ptr(), n) };
        Some(if rc == 0 { Ok(()) } else { Err(rc) })
    }

    fn solve_rows(
        &mut self,
        rows: &[usize],
        x: &mut [f64],
        ncols: usize,
        approximate: bool,
    ) -> Option<std::result::Result<(), i32>> {
        let f = self.solve_rows?;
        self.rows.clear();
        self.rows.extend(rows.iter().map(|&r| r as i64));
        let len = rows.len() as i64;
        // SAFETY: the rows hold nrows entries and x holds nrows x ncols
        // doubles, column-major with leading dimension nrows, as the
        // callback's contract states; the context is the caller's.
        let rc = unsafe {
            f(
                self.context,
                len,
                self.rows.as_ptr(),
                ncols as i64,
                x.as_mut_ptr(),
                len,
                i32::from(approximate),
            )
        };
        Some(if rc == 0 { Ok(()) } else { Err(rc) })
    }

    fn inverse_entries(
        &mut self,
        rows: &[usize],
        cols: &[usize],
        values: &mut [f64],
    ) -> Option<std::result::Result<(), i32>> {
        let f = self.inverse?;
        let r: Vec<i64> = rows.iter().map(|&v| v as i64).collect();
        let c: Vec<i64> = cols.iter().map(|&v| v as i64).collect();
        // SAFETY: rows, cols and values hold `count` entries each, as the
        // callback's contract states; the context is the caller's.
        let rc = unsafe {
            f(
                self.context,
                r.len() as i64,
                r.as_ptr(),
                c.as_ptr(),
                values.as_mut_ptr(),
            )
        };
        Some(if rc == 0 { Ok(()) } else { Err(rc) })
    }
}

/// Checks the caller's DsHostSolver and wraps its callback.
fn host_of(s: &DsHostSolver) -> Result<CHost> {
    if s.n < 1 {
        return Err(Error::new(
            DsStatus::BadSize,
            format!("solver->n = {}: the host's K must have n >= 1", s.n),
        ));
    }
    let Some(solve) = s.solve else {
        return Err(Error::new(
            DsStatus::NullPointer,
            "solver->solve is NULL: the host's solve callback is required",
        ));
    };
    let n = usize::try_from(s.n).map_err(|_| {
        Error::new(
            DsStatus::BadSize,
            format!("solver->n = {} is too large", s.n),
        )
    })?;
    Ok(CHost {
        n,
        solve,
        solve_single: s.solve_single,
        solve_rows: s.solve_rows,
        rows: Vec::new(),
        inverse: s.inverse_entries,
        context: s.context,
    })
}

/// Creates a contact problem on the host's own solver of K (a CHOLMOD, MUMPS
/// or PARDISO factor it holds, a PETSc KSP over MPI) instead of a factor of
/// the library's. The dual is matrix-free: every product with the condensed
/// operator, the right-hand side and the recovery of u is one call of
/// solver->solve; the contacts' d x d diagonal blocks of A are formed here
/// from solver->inverse_entries where given (one call), else by d m solves,
/// 32 right-hand sides per call, or, as solver->blocks asks
/// (DS_HOST_BLOCKS_FACTOR, or DS_HOST_BLOCKS_AUTO where it pays), by the
/// library's own factor of K, freed before the call returns. ds_solve and
/// ds_step then work
/// as on any handle, with the methods that need no entries of A (AUTO, NEWTON,
/// MPRGP; the others, and dual_form DENSE, return DS_STATUS_BAD_ARGUMENT);
/// ds_problem_refactor returns DS_STATUS_BAD_ARGUMENT (refactor on the host's
/// side and create a new handle), and so does ds_problem_dump without K.
///
/// - d: contact dimension, 2 or 3.
/// - solver: the callbacks, their context and n (see DsHostSolver; with
///   solver->solve_single, the loose products are solved in single
///   precision; with solver->solve_rows, every product is a solve on the
///   contact DOFs alone).
/// - k: K itself, optional (NULL: none), as ds_problem_new takes it. Where
///   given it serves the lumped preconditioner B K B^T of Newton's reduced
///   systems (about half the products of Jacobi), K u_k in a history and the
///   report's equilibrium residual; without it the residual is NaN (not
///   measured) and K u_k is taken from the last step's equilibrium,
///   f_total - N^T lambda_N - T^T lambda_T.
/// - n, t: N (m x n) and T ((d-1) m x n), FULL storage, as ds_problem_new.
/// - opts: NULL or options as ds_problem_new_opts (threads for the library's
///   own contact-space work; ordering unused).
/// - out: receives the new handle on success; untouched on error.
///
/// Returns DS_STATUS_OK, or DS_STATUS_NULL_POINTER (solver, solver->solve,
/// n, t, out), DS_STATUS_BAD_ARGUMENT (d, struct_size, options, dual_form
/// DENSE, solver->blocks, DS_HOST_BLOCKS_FACTOR without K),
/// DS_STATUS_BAD_SIZE (n < 1, N or T not n columns, K not n x n),
/// DS_STATUS_BAD_INDEX, DS_STATUS_NOT_FINITE, DS_STATUS_NOT_SYMMETRIC (K),
/// DS_STATUS_NOT_POSITIVE_DEFINITE (K, factored for the blocks),
/// DS_STATUS_HOST_SOLVE_FAILED (a solve for the contact blocks failed),
/// DS_STATUS_OUT_OF_MEMORY. Added in version 0.9.
///
/// # Safety
/// Each pointer must be NULL or valid: solver points to a DsHostSolver of
/// struct_size readable bytes whose callbacks and context stay valid until
/// the handle is freed; k (if not
/// NULL), n, t point to DsMatrix structs whose arrays match their fields; opts
/// as for ds_problem_new_opts; out points to a writable DsProblem*.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_new_host(
    d: i32,
    solver: *const DsHostSolver,
    k: *const DsMatrix,
    n: *const DsMatrix,
    t: *const DsMatrix,
    opts: *const DsOptions,
    out: *mut *mut DsProblem,
) -> DsStatus {
    entry("ds_problem_new_host", || {
        // SAFETY: pointer validity is this function's contract; NULL is
        // rejected (k may be NULL: no K).
        let (solver, n, t, out) = unsafe {
            (
                DsHostSolver::read(solver)?,
                ref_in(n, "n")?,
                ref_in(t, "t")?,
                ref_mut(out, "out")?,
            )
        };
        let k = if k.is_null() {
            None // no K
        } else {
            // SAFETY: k is a valid DsMatrix (contract), not NULL.
            Some(unsafe { ref_in(k, "k")? })
        };
        // SAFETY: opts is NULL or a readable DsOptions prefix (contract).
        let mut opts = unsafe { DsOptions::read(opts)? };
        let d = dimension(d)?;
        let host = host_of(&solver)?;
        opts.host_blocks = DsHostBlocks::parse(solver.blocks, "solver->blocks")?.into();
        // SAFETY: the matrices' arrays match their fields (contract).
        let (nv, tv) = unsafe { (n.view("N")?, t.view("T")?) };
        // SAFETY: as above, for K where given.
        let kv = unsafe { k.map(|k| k.view("K")).transpose()? };
        let inner =
            ContactProblem::with_host_solver(d, Box::new(host), kv.as_ref(), &nv, &tv, &opts)?;
        *out = DsProblem::boxed(inner);
        Ok(())
    })
}
