//! What the last solve on a handle cost, beyond DsReport: DsCost and
//! ds_problem_last_cost (where the seconds went, the host's solves).

use super::boundary::{entry, write_sized};
use super::error::CResult as Result;
use super::problem::DsProblem;
use super::status::DsStatus;
use crate::report::Report;

/// What the last ds_solve or ds_step on a handle cost, beyond DsReport: where
/// its seconds went and, on a handle made on the host's solver
/// (ds_problem_new_host), how many right-hand sides the host's solve took and
/// the seconds inside it against the library's own. Filled by
/// ds_problem_last_cost.
///
/// Set struct_size = sizeof(DsCost) before the call: the struct grows at its
/// end from version to version, and the library writes no byte past
/// struct_size. Added in version 0.10 (64 bytes).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct DsCost {
    /// sizeof(DsCost) as the caller sees it; set by the caller, at least 8.
    pub struct_size: u32,
    /// 1 when a ds_solve or ds_step on this handle has returned a report
    /// (DS_STATUS_OK, DS_STATUS_NOT_CONVERGED, DS_STATUS_STOPPED,
    /// DS_STATUS_STALLED or DS_STATUS_TIME_LIMIT): the fields below are that
    /// call's. 0 before any: every field below is 0. A call that failed
    /// before solving (a bad argument, a refused memory need, a failed host
    /// solve) leaves the last cost as it was.
    pub solved: i32,
    /// Seconds of that call's solve (DsReport.solve_seconds): the sum of the
    /// three phases below and of the report (equilibrium residual, contact
    /// states).
    pub solve_seconds: f64,
    /// Seconds of the right-hand side b = B K^-1 f - [g; 0] (one solve with
    /// K, or none where a history step's load lies in the span of the last
    /// loads).
    pub rhs_seconds: f64,
    /// Seconds of the method's iterations.
    pub iterate_seconds: f64,
    /// Seconds of the recovery of u = K^-1 (f - B^T lambda) and of err
    /// measured on it.
    pub recover_seconds: f64,
    /// Right-hand sides the host's solve callback took during that call
    /// (columns, summed over the calls); 0 on the library's own factor.
    pub host_solves: i64,
    /// Seconds inside the host's solve callback during that call (part of
    /// solve_seconds); 0 on the library's own factor.
    pub host_seconds: f64,
    /// solve_seconds - host_seconds: the library's own time in that call.
    pub library_seconds: f64,
}

impl From<&Report> for DsCost {
    fn from(r: &Report) -> DsCost {
        DsCost {
            struct_size: std::mem::size_of::<DsCost>() as u32,
            solved: 1,
            solve_seconds: r.solve_seconds,
            rhs_seconds: r.rhs_seconds,
            iterate_seconds: r.iterate_seconds,
            recover_seconds: r.recover_seconds,
            host_solves: i64::try_from(r.host_solves).unwrap_or(i64::MAX),
            host_seconds: r.host_seconds,
            library_seconds: (r.solve_seconds - r.host_seconds).max(0.0),
        }
    }
}

/// Writes what the last ds_solve or ds_step on the handle cost into *cost
/// (see DsCost; cost->solved = 0 before any). Set cost->struct_size =
/// sizeof(DsCost) first.
///
/// Returns DS_STATUS_OK; DS_STATUS_NULL_POINTER when problem or cost is NULL;
/// DS_STATUS_BAD_ARGUMENT when cost is misaligned or cost->struct_size is
/// below 8. *cost is written only on DS_STATUS_OK.
///
/// DS_STATUS_BUSY when called from a callback of a call on the same
/// handle (nothing changed).
///
/// # Safety
/// problem must be NULL or a live handle; cost must be NULL or point to a
/// writable DsCost of at least cost->struct_size bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_problem_last_cost(
    problem: *const DsProblem,
    cost: *mut DsCost,
) -> DsStatus {
    entry("ds_problem_last_cost", || -> Result<()> {
        // SAFETY: the handle pointer is NULL or live (contract); NULL is rejected.
        let problem = unsafe { super::problem::lend(problem, "problem")? };
        let value = problem.last_cost.unwrap_or_default();
        // SAFETY: cost is NULL or writable for its struct_size bytes (contract).
        unsafe { write_sized(cost, value, "cost", "DsCost") }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layout_is_that_of_the_header() {
        assert_eq!(std::mem::size_of::<DsCost>(), 64);
        assert_eq!(std::mem::offset_of!(DsCost, solve_seconds), 8);
        assert_eq!(std::mem::offset_of!(DsCost, library_seconds), 56);
    }
}
