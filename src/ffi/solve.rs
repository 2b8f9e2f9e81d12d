//! ds_solve and ds_step: the checks of every pointer before the core runs, the
//! solve, and the outputs written per status after it returned.

use super::boundary::{OutArray, entry, slice_in};
use super::cost::DsCost;
use super::error::{CError as Error, CResult as Result};
use super::monitor::LOG_ITERATIONS;
use super::options::DsOptions;
use super::problem::DsProblem;
use super::report::DsReport;
use super::status::DsStatus;
use super::types::{CEnum, DsFriction};
use crate::friction::Friction;
use crate::problem::Solution;
use crate::report::SolveStatus;

/// Which of the two solve entry points runs.
#[derive(Copy, Clone, PartialEq, Eq)]
enum Mode {
    /// ds_solve: one increment as given, history untouched.
    Solve,
    /// ds_step: one step of the history.
    Step,
}

/// The common body of ds_solve and ds_step: all pointers are checked before the
/// core runs, and outputs are written only after it returned.
///
/// # Safety
/// As ds_solve.
#[allow(clippy::too_many_arguments)]
unsafe fn solve_impl(
    mode: Mode,
    problem: *mut DsProblem,
    opts: *const DsOptions,
    friction: i32,
    f: *const f64,
    g: *const f64,
    bound: *const f64,
    u: *mut f64,
    lambda_n: *mut f64,
    lambda_t: *mut f64,
    report: *mut DsReport,
) -> Result<()> {
    let (f_name, g_name) = match mode {
        Mode::Solve => ("f", "g"),
        Mode::Step => ("f_total", "g0"),
    };
    // SAFETY: the handle pointer is NULL or live (contract); NULL is rejected.
    let mut lent = unsafe { super::problem::lend(problem, "problem")? };
    let problem = &mut *lent;
    // SAFETY: opts is NULL or a DsOptions of struct_size bytes (contract).
    let options = unsafe { DsOptions::read(opts)? };
    // SAFETY: as above; read accepted opts.
    let report_size = super::report::caller_size(unsafe { DsOptions::caller_size(opts) });
    let law = DsFriction::parse(friction, "friction")?;
    let bound_name = match law {
        DsFriction::Tresca => "bound (Tresca p)",
        DsFriction::Coulomb => "bound (Coulomb mu)",
    };
    let n = problem.inner.n_dofs();
    let m = problem.inner.n_contacts();
    let mt = (problem.inner.dim() - 1) * m;
    // SAFETY: the arrays hold n, m, m values (contract); NULL only if empty.
    let (f, g, bound) = unsafe {
        (
            slice_in(f, n, f_name)?,
            slice_in(g, m, g_name)?,
            slice_in(bound, m, bound_name)?,
        )
    };
    let u = OutArray::new(u, n, "u")?;
    let lambda_n = OutArray::new(lambda_n, m, "lambda_n")?;
    let lambda_t = OutArray::new(lambda_t, mt, "lambda_t")?;
    let report = if report.is_null() {
        None
    } else {
        Some(OutArray::new(report, 1, "report")?)
    };
    let law = match law {
        DsFriction::Tresca => Friction::Tresca(bound),
        DsFriction::Coulomb => Friction::Coulomb(bound),
    };
    let watch = &problem.watch;
    let name = options.method.name();
    let mut hook = |p: &crate::methods::Progress| watch.on_iteration(name, p);
    let monitor: Option<crate::methods::Monitor<'_>> =
        if watch.monitor.is_some() || watch.level >= LOG_ITERATIONS {
            Some(&mut hook)
        } else {
            None
        };
    let solution: Solution = match mode {
        Mode::Solve => problem
            .inner
            .solve_monitored(f, g, law, &options, monitor)?,
        Mode::Step => problem.inner.step_monitored(f, g, law, &options, monitor)?,
    };
    problem.watch.on_done(&solution.report);
    problem.last_cost = Some(DsCost::from(&solution.report));
    let ds_report = DsReport::from(&solution.report);
    let status = solution.report.status;
    if status != SolveStatus::NotConverged {
        u.check_len(&solution.u)?;
        lambda_n.check_len(&solution.lambda_n)?;
        lambda_t.check_len(&solution.lambda_t)?;
        // SAFETY: the output arrays are valid for their lengths (contract) and no
        // Rust reference to them exists; the inputs are no longer read.
        unsafe {
            u.write(&solution.u)?;
            lambda_n.write(&solution.lambda_n)?;
            lambda_t.write(&solution.lambda_t)?;
        }
    }
    if let Some(r) = &report {
        // SAFETY: report is valid for the DsReport of the caller's version, which
        // report_size is (contract).
        unsafe { r.write_prefix(&ds_report, report_size) };
    }
    let (r, name) = (&solution.report, options.method.name());
    let (err, outer) = (r.err, r.outer_iterations);
    let message = match status {
        SolveStatus::Converged => return Ok(()),
        SolveStatus::Stopped => (
            DsStatus::Stopped,
            format!(
                "{name} stopped by the monitor callback after {outer} outer iterations \
                 (err = {err:.3e}); the last iterate was written"
            ),
        ),
        SolveStatus::Stalled => (
            DsStatus::Stalled,
            format!(
                "{name} stalled: err = {err:.3e} > tol = {:.3e} after {outer} outer \
                 iterations, the best err not lowered by the factor {} over the last {} \
                 (stall_factor, stall_window); the iterate with the lowest err was written",
                options.tol, options.stall_factor, options.stall_window
            ),
        ),
        SolveStatus::TimeLimit => (
            DsStatus::TimeLimit,
            format!(
                "{name} reached max_seconds = {} with err = {err:.3e} > tol = {:.3e} after \
                 {outer} outer iterations; the iterate with the lowest err was written",
                options.max_seconds, options.tol
            ),
        ),
        SolveStatus::NotConverged => (
            DsStatus::NotConverged,
            format!(
                "{name} did not converge: err = {err:.3e} > tol = {:.3e} after {outer} outer \
                 iterations (max_outer = {}, max_inner = {}); outputs not written",
                options.tol, options.max_outer, options.max_inner
            ),
        ),
    };
    Err(Error::new(message.0, message.1))
}

/// Solves one increment exactly as given (the history of ds_step is neither used nor
/// changed): K u = f - N^T lambda_N - T^T lambda_T with N u <= g, lambda_N >= 0,
/// complementarity, and the friction law on the slip T u.
///
/// - problem: the handle.
/// - opts: options, or NULL for the defaults.
/// - friction: a DsFriction value; selects what `bound` holds.
/// - f: load vector, n values (force units).
/// - g: gaps, m values (length units; g_i < 0 is an initial penetration).
/// - bound: m values: Tresca slip bounds p_i >= 0 (force units) or Coulomb
///   coefficients mu_i >= 0.
/// - u: out, displacement, n values.
/// - lambda_n: out, normal contact forces, m values, >= 0 (compressive).
/// - lambda_t: out, tangential contact forces, (d-1) m values, contact by contact;
///   the friction force on the body is -T^T lambda_T.
/// - report: out, may be NULL.
///
/// Arrays of length 0 may be NULL. Returns DS_STATUS_OK (u, lambda_n, lambda_t and
/// report written); DS_STATUS_NOT_CONVERGED (only the report written);
/// DS_STATUS_STOPPED (the last iterate and the report written), DS_STATUS_STALLED
/// and DS_STATUS_TIME_LIMIT (the iterate with the lowest err and the report
/// written);
/// DS_STATUS_NULL_POINTER, DS_STATUS_BAD_ARGUMENT (friction, options),
/// DS_STATUS_NOT_FINITE, DS_STATUS_NEGATIVE_FRICTION, DS_STATUS_OUT_OF_MEMORY,
/// DS_STATUS_HOST_SOLVE_FAILED (a handle on the host's solves), DS_STATUS_BUSY
/// (called from a callback of a call on the same handle), DS_STATUS_PANIC (a
/// bug) (nothing written). The handle stays usable in every case.
///
/// # Safety
/// `problem` must be NULL or a live handle; `opts` NULL or a DsOptions; each array
/// NULL or valid for its length (n, m or (d-1) m values); `report` NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_solve(
    problem: *mut DsProblem,
    opts: *const DsOptions,
    friction: i32,
    f: *const f64,
    g: *const f64,
    bound: *const f64,
    u: *mut f64,
    lambda_n: *mut f64,
    lambda_t: *mut f64,
    report: *mut DsReport,
) -> DsStatus {
    entry("ds_solve", || {
        // SAFETY: forwarded contract of ds_solve.
        unsafe {
            solve_impl(
                Mode::Solve,
                problem,
                opts,
                friction,
                f,
                g,
                bound,
                u,
                lambda_n,
                lambda_t,
                report,
            )
        }
    })
}

/// One step of a quasistatic history. The caller passes the TOTAL load f_total
/// (n values) and the INITIAL gaps g0 (m values) of the step; with the held
/// displacement u_k the library solves the increment with f = f_total - K u_k and
/// g = g0 - N u_k, friction acting on the tangential increment T du, warm-started
/// from the last multipliers (after two steps, from the multipliers extrapolated
/// along the load: under proportional loading they move on a straight line while
/// no contact changes state, so a step costs a few solves), and returns the total
/// displacement u_k+1 = u_k + du in u and the total contact forces in lambda_n and
/// lambda_t. The history advances only on DS_STATUS_OK; ds_problem_refactor and
/// ds_problem_set_contacts keep u_k and, for the same m, the multipliers, but
/// restart the extrapolation.
///
/// Arguments, outputs and statuses as ds_solve.
///
/// # Safety
/// As ds_solve.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_step(
    problem: *mut DsProblem,
    opts: *const DsOptions,
    friction: i32,
    f_total: *const f64,
    g0: *const f64,
    bound: *const f64,
    u: *mut f64,
    lambda_n: *mut f64,
    lambda_t: *mut f64,
    report: *mut DsReport,
) -> DsStatus {
    entry("ds_step", || {
        // SAFETY: forwarded contract of ds_step.
        unsafe {
            solve_impl(
                Mode::Step,
                problem,
                opts,
                friction,
                f_total,
                g0,
                bound,
                u,
                lambda_n,
                lambda_t,
                report,
            )
        }
    })
}
