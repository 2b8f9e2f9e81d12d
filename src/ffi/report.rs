//! The report struct of the C API.

use super::status::DsStatus;
use super::types::{DsMethod, DsOrdering};
use crate::report::{Report, SolveStatus};

/// What a solve reports besides u and the multipliers. Written by ds_solve / ds_step
/// on DS_STATUS_OK, DS_STATUS_STALLED, DS_STATUS_TIME_LIMIT, DS_STATUS_STOPPED
/// (then it describes the iterate written to u and the multipliers) and on
/// DS_STATUS_NOT_CONVERGED (then it describes the lowest-err iterate, which is not
/// written).
///
/// Versions: fields are only ever appended. The library writes the fields of the
/// version whose DsOptions the caller passed (DsOptions.struct_size identifies the
/// header a program was built with; with opts = NULL, the fields of version 0.1),
/// so a program's DsReport is never written past its end. Versions 0.1 to 0.3 have
/// the same 88-byte report; 0.4 appends ordering, threads, factor_nnz,
/// factor_flops and analyse_seconds (120 bytes), written when the caller's
/// DsOptions is of version 0.4 (struct_size 72); 0.5 appends memory_predicted and
/// memory_peak (136 bytes), written when it is of version 0.5 (struct_size 80).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DsReport {
    /// A DsStatus value: DS_STATUS_OK, DS_STATUS_NOT_CONVERGED, DS_STATUS_STOPPED,
    /// DS_STATUS_STALLED or DS_STATUS_TIME_LIMIT (the status ds_solve returned).
    pub status: i32,
    /// The DsMethod that gave the answer (for DS_METHOD_AUTO: the method it
    /// chose, never DS_METHOD_AUTO itself).
    pub method: i32,
    /// Relative KKT error |r| / max(|lambda|, |b+| / trace(A)) of the natural map
    /// with rho_i = d / trace(A_ii) (dimensionless, invariant under scaling K and f;
    /// b+ = b with the negative parts of b_N cut), multiplied by
    /// DsInfo.err_factor after a ds_problem_refactor that kept the contact
    /// blocks. Infinite when no u satisfies
    /// N u <= g (a penetrating contact without rows in N and T, or an unbounded
    /// dual found by the MPRGP methods); the status is then
    /// DS_STATUS_NOT_CONVERGED.
    pub err: f64,
    /// |K u - f + N^T lambda_N + T^T lambda_T| / |f| (dimensionless).
    pub equilibrium_residual: f64,
    /// Outer iterations done.
    pub outer_iterations: i64,
    /// Inner iterations, in total; what one is depends on the route: a
    /// projected Gauss-Seidel sweep over the contacts (DS_METHOD_PGS, where it equals
    /// the outer count; the splittings' sub-problems on a dense dual; Newton's
    /// warm-up and fallback sweeps on a dense dual), or one product with A
    /// (MPRGP, the sub-problems on a matrix-free dual, Newton's Krylov solves
    /// on a matrix-free dual). Newton's product for the explicit part of a
    /// step, its backtracking product (taken only where the Krylov solve's
    /// products were narrowed or refined; elsewhere A d is combined from
    /// them), the exact recomputations of the gradient (after a step whose
    /// single-precision products drifted too far, and before a convergence
    /// is accepted on such a gradient) and the lumped start's two products
    /// are not counted (one or two per Newton step).
    pub inner_iterations: i64,
    /// Contacts with lambda_N = 0.
    pub n_open: i64,
    /// Closed contacts with |lambda_T| < p (sticking).
    pub n_stick: i64,
    /// Closed contacts with |lambda_T| = p (slipping; frictionless closed contacts
    /// count here).
    pub n_slip: i64,
    /// Seconds of the last numeric factorisation of K.
    pub factor_seconds: f64,
    /// Seconds spent forming the condensed dual last time.
    pub condense_seconds: f64,
    /// Seconds of this solve (right-hand side, iterations, recovery of u).
    pub solve_seconds: f64,
    /// The DsOrdering K's factor was computed with: DS_ORDERING_AMD or
    /// DS_ORDERING_METIS (DS_ORDERING_AUTO picks one); DS_ORDERING_DENSE for a
    /// K given dense (dense Cholesky). Added in version 0.4.
    pub ordering: i32,
    /// Threads the handle's pool has (1: the calling thread only). Added in
    /// version 0.4.
    pub threads: i32,
    /// Nonzeros of the Cholesky factor of K (dense supernodal blocks included).
    /// Added in version 0.4.
    pub factor_nnz: i64,
    /// Flops of one numeric factorisation of K (sum over the columns of L of the
    /// squared column counts). Added in version 0.4.
    pub factor_flops: f64,
    /// Seconds of K's analysis (ordering and symbolic factorisation) when the
    /// handle was created. Added in version 0.4.
    pub analyse_seconds: f64,
    /// The predicted peak of the library's large allocations during this solve,
    /// bytes: what the handle holds, the solve's vectors and the method's dense
    /// work space in its largest case (see DsOptions.max_memory and DsInfo).
    /// Added in version 0.5.
    pub memory_predicted: u64,
    /// The measured peak of the same allocations during this solve, bytes,
    /// counted by the library as it allocates (not read from the operating
    /// system). Added in version 0.5.
    pub memory_peak: u64,
}

/// sizeof(DsReport) of versions 0.1 to 0.3.
pub(crate) const V03_SIZE: usize = 88;
/// sizeof(DsReport) of version 0.4.
pub(crate) const V04_SIZE: usize = 120;

/// The bytes of DsReport the caller has room for, from the struct_size of the
/// DsOptions it passed (0 for NULL): the report of the same version.
pub(crate) fn caller_size(options_size: usize) -> usize {
    if options_size >= super::options::V05_SIZE {
        std::mem::size_of::<DsReport>()
    } else if options_size >= super::options::V04_SIZE {
        V04_SIZE
    } else {
        V03_SIZE
    }
}

/// A count as int64_t (saturating, never reached in practice).
fn count(v: usize) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

impl From<&Report> for DsReport {
    fn from(r: &Report) -> DsReport {
        DsReport {
            status: match r.status {
                SolveStatus::Converged => DsStatus::Ok,
                SolveStatus::NotConverged => DsStatus::NotConverged,
                SolveStatus::Stopped => DsStatus::Stopped,
                SolveStatus::Stalled => DsStatus::Stalled,
                SolveStatus::TimeLimit => DsStatus::TimeLimit,
            } as i32,
            method: DsMethod::from(r.method) as i32,
            err: r.err,
            equilibrium_residual: r.equilibrium_residual,
            outer_iterations: count(r.outer_iterations),
            inner_iterations: count(r.inner_iterations),
            n_open: count(r.n_open),
            n_stick: count(r.n_stick),
            n_slip: count(r.n_slip),
            factor_seconds: r.factor_seconds,
            condense_seconds: r.condense_seconds,
            solve_seconds: r.solve_seconds,
            ordering: DsOrdering::from(r.ordering) as i32,
            threads: i32::try_from(r.threads).unwrap_or(i32::MAX),
            factor_nnz: count(r.factor_nnz),
            factor_flops: r.factor_flops,
            analyse_seconds: r.analyse_seconds,
            memory_predicted: u64::try_from(r.memory_predicted).unwrap_or(u64::MAX),
            memory_peak: u64::try_from(r.memory_peak).unwrap_or(u64::MAX),
        }
    }
}
