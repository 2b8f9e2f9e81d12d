//! The analysis report of the C API: DsInfo, ds_analyse and ds_problem_info.

use super::boundary::{entry, ref_in, write_sized};
use super::error::{CError as Error, CResult as Result};
use super::matrix::DsMatrix;
use super::options::DsOptions;
use super::problem::{DsProblem, dimension};
use super::status::DsStatus;
use super::types::{DsDualForm, DsMethod, DsOrdering};
use crate::info::Info;
use crate::problem::ContactProblem;

/// What the analysis of a contact problem tells before any numeric work (as
/// MUMPS's analysis phase, JOB = 1): sizes, the factor's size and cost, the route
/// the options lead to and its predicted memory. Filled by ds_analyse (no handle
/// is made, nothing is factored) and ds_problem_info (for a handle).
///
/// Set struct_size = sizeof(DsInfo) before the call: the struct grows at its end
/// from version to version, and the library writes no byte past struct_size
/// (fields a newer library has and the caller's struct lacks are left out).
/// Added in version 0.5 (120 bytes); 136 bytes from version 0.8, 152 from
/// version 0.10.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DsInfo {
    /// sizeof(DsInfo) as the caller sees it; set by the caller, at least 8.
    pub struct_size: u32,
    /// Contact dimension (2 or 3).
    pub d: i32,
    /// DOFs (rows of K).
    pub n: i64,
    /// Contacts (rows of N).
    pub m: i64,
    /// Dual unknowns c = d m.
    pub c: i64,
    /// Stored entries of K, both triangles.
    pub nnz_k: i64,
    /// Entries of the Cholesky factor L (dense supernodal blocks included).
    pub factor_nnz: i64,
    /// Flops of one numeric factorisation of K.
    pub factor_flops: f64,
    /// The DsOrdering chosen: DS_ORDERING_AMD or DS_ORDERING_METIS
    /// (DS_ORDERING_DENSE for a K given dense).
    pub ordering: i32,
    /// The DsDualForm the handle is (or would be) created with:
    /// DS_DUAL_FORM_DENSE (A formed) or DS_DUAL_FORM_MATRIX_FREE.
    pub setup_form: i32,
    /// The DsMethod of the options passed (the default: DS_METHOD_AUTO).
    pub method: i32,
    /// The DsDualForm a solve with that method uses (DS_DUAL_FORM_DENSE for every
    /// method that reads entries of A).
    pub solve_form: i32,
    /// Predicted peak bytes of the library's large allocations while the handle
    /// is created (factorisation, then condensation).
    pub setup_bytes: u64,
    /// Predicted bytes the handle holds between calls (with the slots a
    /// refactor from a coordinate-format K keeps, once it has made them, the
    /// replaced factor's values a refactor keeps as the next one's storage,
    /// see ds_problem_refactor, and
    /// on a dense dual the single-precision factor of the last Newton step's
    /// reduced system, at most 4 c^2 bytes, once a solve has made it, and in
    /// 3D A^-1 in single precision, 4 c^2 bytes, once a warm Newton solve has
    /// made it; both are counted from creation on).
    pub resident_bytes: u64,
    /// Predicted peak bytes during one solve with that method (its largest
    /// case; the slots and the kept factor values of resident_bytes
    /// included: a solve whose max_memory this exceeds, and that fits it
    /// without the kept values, frees them first and predicts that much
    /// less in its report).
    pub solve_bytes: u64,
    /// Predicted peak bytes of ds_problem_refactor (the old and the new factor
    /// are held at once, the new one in the kept values of a replaced factor
    /// where the handle holds them; max_memory must allow for it), with the
    /// slots of resident_bytes; a refactor from a coordinate-format K makes its slots
    /// first (4 bytes per triplet, 8 where one triangle is given, and in
    /// full storage 4 bytes per entry of K off the diagonal; see
    /// ds_problem_refactor) and checks them with the rest. Until a refactor
    /// from a full-storage K (COO or CSC) has made them, the mirror places
    /// such a refactor makes are counted in, whatever the format K is given
    /// in: an upper bound for the others.
    pub refactor_bytes: u64,
    /// The memory limit the predictions are checked against, bytes
    /// (DsOptions.max_memory, else this process's address-space limit or the
    /// machine's physical memory; 0 when none is known).
    pub memory_limit: u64,
    /// Seconds of the ordering and the symbolic factorisation.
    pub analyse_seconds: f64,
    /// Contacts with a compliant interface law (finite c_N or k_T, see
    /// ds_problem_set_compliance); 0 from ds_analyse and where every contact is
    /// rigid. Added in version 0.8 (136 bytes).
    pub compliant_contacts: i64,
    /// Of those, the contacts whose normal law is a power law with m_N != 1
    /// (solved by Newton on the law: several dual solves per ds_solve). Added in
    /// version 0.8.
    pub power_law_contacts: i64,
    /// Refactors since the contact blocks of a matrix-free dual were
    /// computed: 0 where they are the current K's (always on a dense dual and
    /// from ds_analyse); k where ds_problem_refactor kept those of the K k
    /// refactors back because their drift was small. Added in version 0.10
    /// (152 bytes).
    pub blocks_age: i64,
    /// The factor err (DsReport.err) is multiplied by so that it bounds err
    /// on the current K's contact blocks: 1 where blocks_age is 0, at most
    /// 3 else (rho comes from the kept blocks; their drift, estimated by
    /// Lanczos steps and not certified, bounds how far it lies from the
    /// current K's). Added in version 0.10.
    pub err_factor: f64,
}

/// A count or size as the C field (saturating; never reached in practice).
fn i64_of(v: usize) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

fn u64_of(v: usize) -> u64 {
    u64::try_from(v).unwrap_or(u64::MAX)
}

impl From<&Info> for DsInfo {
    fn from(i: &Info) -> DsInfo {
        DsInfo {
            struct_size: std::mem::size_of::<DsInfo>() as u32,
            d: i.d as i32,
            n: i64_of(i.n),
            m: i64_of(i.m),
            c: i64_of(i.c),
            nnz_k: i64_of(i.nnz_k),
            factor_nnz: i64_of(i.factor_nnz),
            factor_flops: i.factor_flops,
            ordering: DsOrdering::from(i.ordering) as i32,
            setup_form: DsDualForm::from(i.setup_form) as i32,
            method: DsMethod::from(i.method) as i32,
            solve_form: DsDualForm::from(i.solve_form) as i32,
            setup_bytes: u64_of(i.setup_bytes),
            resident_bytes: u64_of(i.resident_bytes),
            solve_bytes: u64_of(i.solve_bytes),
            refactor_bytes: u64_of(i.refactor_bytes),
            memory_limit: u64_of(i.memory_limit),
            analyse_seconds: i.analyse_seconds,
            compliant_contacts: i64_of(i.compliant_contacts),
            power_law_contacts: i64_of(i.power_law_contacts),
            blocks_age: i64_of(i.blocks_age),
            err_factor: i.err_factor,
        }
    }
}

/// Writes `info` into the caller's DsInfo at `out`, at most its struct_size
/// bytes (the caller's struct may be an older, shorter one: it is never
/// referenced as a whole DsInfo).
///
/// Errors: `NullPointer`; `BadArgument` when `out` is misaligned or struct_size
/// is below 8 (not set).
///
/// # Safety
/// `out` must be NULL or point to a writable DsInfo prefix of struct_size bytes.
unsafe fn write_info(out: *mut DsInfo, info: &Info) -> Result<()> {
    // SAFETY: out is NULL or writable for its struct_size bytes (contract).
    unsafe { write_sized(out, DsInfo::from(info), "info", "DsInfo") }
}

/// The analysis alone: validates K, N, T and the options, orders K and computes
/// its symbolic factorisation, decides the route the options lead to and
/// predicts its memory, and fills *info; no handle is made and nothing is
/// factored (the cost is that of the ordering, well under the factorisation's).
/// opts = NULL: the defaults. The memory limit (DsOptions.max_memory) is not
/// enforced here: compare setup_bytes and solve_bytes with memory_limit.
///
/// Returns DS_STATUS_OK, or what ds_problem_new_opts returns before it factors:
/// DS_STATUS_NULL_POINTER, DS_STATUS_BAD_ARGUMENT (also info->struct_size below
/// 8), DS_STATUS_BAD_SIZE, DS_STATUS_BAD_INDEX, DS_STATUS_NOT_FINITE,
/// DS_STATUS_NOT_SYMMETRIC, DS_STATUS_OUT_OF_MEMORY (the analysis itself does not
/// fit). *info is written only on DS_STATUS_OK.
///
/// # Safety
/// As ds_problem_new_opts; info must point to a writable DsInfo of at least
/// info->struct_size bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_analyse(
    d: i32,
    k: *const DsMatrix,
    n: *const DsMatrix,
    t: *const DsMatrix,
    opts: *const DsOptions,
    info: *mut DsInfo,
) -> DsStatus {
    entry("ds_analyse", || {
        // SAFETY: pointer validity is this function's contract; NULL is rejected.
        let (k, n, t) = unsafe { (ref_in(k, "k")?, ref_in(n, "n")?, ref_in(t, "t")?) };
        if info.is_null() {
            return Err(Error::new(DsStatus::NullPointer, "argument info is NULL"));
        }
        // SAFETY: opts is NULL or a readable DsOptions prefix (contract).
        let opts = unsafe { DsOptions::read(opts)? };
        let d = dimension(d)?;
        // SAFETY: the matrices' arrays match their fields (contract).
        let (kv, nv, tv) = unsafe { (k.view("K")?, n.view("N")?, t.view("T")?) };
        let result = ContactProblem::analyse(d, &kv, &nv, &tv, &opts)?;
        // SAFETY: info is writable for its struct_size bytes (contract).
        unsafe { write_info(info, &result) }
    })
}

/// The analysis of a handle as it is now (see DsInfo), with the solve memory
/// predicted for opts->method and opts->dual_form (opts = NULL: the defaults).
///
/// Returns DS_STATUS_OK, DS_STATUS_NULL_POINTER or DS_STATUS_BAD_ARGUMENT
/// (invalid options, info->struct_size below 8). *info is written only on
/// DS_STATUS_OK.
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// problem must be NULL or a live handle; opts NULL or a DsOptions initialised
/// with ds_options_init; info a writable DsInfo of at least info->struct_size
/// bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_info(
    problem: *const DsProblem,
    opts: *const DsOptions,
    info: *mut DsInfo,
) -> DsStatus {
    entry("ds_problem_info", || {
        // SAFETY: pointer validity is this function's contract; NULL is rejected.
        let p = unsafe { super::problem::lend(problem, "problem")? };
        // SAFETY: opts is NULL or a readable DsOptions prefix (contract).
        let opts = unsafe { DsOptions::read(opts)? };
        // SAFETY: info is NULL or writable for its struct_size bytes (contract).
        unsafe { write_info(info, &p.inner.info(&opts)) }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    #[test]
    fn layout_of_version_0_10() {
        assert_eq!(size_of::<DsInfo>(), 152);
        assert_eq!(offset_of!(DsInfo, n), 8);
        assert_eq!(offset_of!(DsInfo, ordering), 56);
        assert_eq!(offset_of!(DsInfo, setup_bytes), 72);
        assert_eq!(offset_of!(DsInfo, refactor_bytes), 96);
        assert_eq!(offset_of!(DsInfo, analyse_seconds), 112);
        assert_eq!(offset_of!(DsInfo, compliant_contacts), 120);
        assert_eq!(offset_of!(DsInfo, power_law_contacts), 128);
        assert_eq!(offset_of!(DsInfo, blocks_age), 136);
        assert_eq!(offset_of!(DsInfo, err_factor), 144);
    }
}
