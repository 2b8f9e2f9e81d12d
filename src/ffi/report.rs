//! The report struct of the C API.

use super::status::DsStatus;
use super::types::DsMethod;
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
/// so a program's DsReport is never written past its end. Versions 0.1 to 0.4 have
/// the same 88-byte report.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DsReport {
    /// A DsStatus value: DS_STATUS_OK, DS_STATUS_NOT_CONVERGED, DS_STATUS_STOPPED,
    /// DS_STATUS_STALLED or DS_STATUS_TIME_LIMIT (the status ds_solve returned).
    pub status: i32,
    /// The DsMethod that ran.
    pub method: i32,
    /// Relative KKT error |r| / max(|lambda|, |b+| / trace(A)) of the natural map
    /// with rho_i = d / trace(A_ii) (dimensionless, invariant under scaling K and f;
    /// b+ = b with the negative parts of b_N cut). Infinite when no u satisfies
    /// N u <= g (a penetrating contact without rows in N and T, or an unbounded
    /// dual found by the MPRGP methods); the status is then
    /// DS_STATUS_NOT_CONVERGED.
    pub err: f64,
    /// |K u - f + N^T lambda_N + T^T lambda_T| / |f| (dimensionless).
    pub equilibrium_residual: f64,
    /// Outer iterations done.
    pub outer_iterations: i64,
    /// Projected Gauss-Seidel sweeps of the sub-problems, in total.
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
        }
    }
}
