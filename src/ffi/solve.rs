//! ds_solve and ds_step: the checks of every pointer before the core runs, the
//! solve, and the outputs written per status after it returned.

use super::boundary::{OutArray, entry, optional_in, slice_in};
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

/// Which of the solve entry points runs.
#[derive(Copy, Clone, PartialEq, Eq)]
enum Mode {
    /// ds_solve: one increment as given, history untouched.
    Solve,
    /// ds_step: one step of the history.
    Step,
    /// ds_solve_iteration: one iteration of the host's Newton loop, with the
    /// slip already taken (NULL: the first iteration of an increment) and
    /// the increment's starting tangential forces (NULL for zero).
    Iteration {
        slip: *const f64,
        lt_start: *const f64,
    },
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
        Mode::Iteration { .. } => ("r", "g"),
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
    let (slip, lt_start) = match mode {
        // SAFETY: each is NULL (zero) or holds (d-1) m values (contract).
        Mode::Iteration { slip, lt_start } => unsafe {
            (
                optional_in(slip, mt, "slip")?,
                optional_in(lt_start, mt, "lambda_t_start")?,
            )
        },
        _ => (None, None),
    };
    let u_name = match mode {
        Mode::Iteration { .. } => "du",
        _ => "u",
    };
    let u = OutArray::new(u, n, u_name)?;
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
        Mode::Iteration { .. } => {
            let it = crate::problem::HostIteration {
                r: f,
                g,
                slip,
                lt_start,
            };
            problem
                .inner
                .solve_iteration_monitored(&it, law, &options, monitor)?
        }
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

/// One iteration of the host's own Newton loop (docs/design.md section 9): a
/// nonlinear host (plasticity, large deformation) that refactors its tangent
/// K at every iteration (ds_problem_refactor) asks here for the contact
/// solve of its linearised problem. Coulomb's and Tresca's stick and slip act
/// on the slip of the WHOLE load increment: the slip the earlier iterations
/// took plus this one's, s_j + T du.
///
/// The host's loop, on a handle made with DsOptions.host_loop = 1 (AUTO then
/// takes the route whose refactor is cheapest), per load increment from the
/// converged u_n:
///
/// 1. u_0 = u_n (j = 0).
/// 2. Assemble the tangent K_t(u_j), the residual r_j = f_ext - f_int(u_j)
///    WITHOUT contact forces, the gaps g_j at u_j and the slip already taken
///    s_j = T (u_j - u_n) (NULL at j = 0 only: NULL marks the first
///    iteration of an increment; zeros at a later one where nothing
///    slipped).
/// 3. ds_problem_refactor(problem, K_t) (same pattern).
/// 4. ds_solve_iteration(problem, opts, friction, r_j, g_j, bound, s_j,
///    lambda_t_start, du, lambda_n, lambda_t, report). The contact solve
///    need only be as accurate as the iteration's linearisation (an inexact
///    Newton step): opts.tol = max(tol, 0.1 |R_j|^2), capped at 1e-2, with
///    |R_j| the out-of-balance force of step 5 relative to the host's force
///    scale, keeps the loop's quadratic convergence and lets the last
///    iterations solve to tol. In c_examples/hyperelastic_host.c this
///    costs no host iteration and cuts the contact solves' Krylov products
///    by 40-45 % and their time by 30-40 %.
/// 5. u_j+1 = u_j + du; stop when |du| and the residual
///    |r_j+1 - N^T lambda_N - T^T lambda_T| are small, else j += 1 and go to 2.
///
/// This call solves, for du:
/// - K du = r - N^T lambda_N - T^T lambda_T;
/// - N du <= g, lambda_N >= 0, lambda_N,i (g_i - (N du)_i) = 0;
/// - |lambda_T,i| <= p_i; stick: |lambda_T,i| < p_i => s_i + (T du)_i = 0;
///   slip: |lambda_T,i| = p_i => s_i + (T du)_i = alpha_i lambda_T,i,
///   alpha_i >= 0;
///
/// with p = the Tresca bound or mu lambda_N, and lambda the TOTAL contact
/// forces at u_j + du. It starts from the multipliers of the last converged
/// ds_solve_iteration on the handle (zero before the first, after
/// ds_history_reset or a ds_problem_set_contacts that changed m), which
/// ds_problem_refactor keeps: at a converging host loop they are already
/// this iteration's answer. The first iteration of an increment (slip NULL)
/// starts, where the load changes of the last two increments lie on one
/// line, from the extrapolation of the multipliers that ended them (at
/// most two products more; not with an interface compliance; docs/design.md
/// section 9). A later iteration of an increment, from the third on, starts
/// on the line through the last two iterations' multipliers where that
/// lowers the natural map's residual (on a matrix-free dual on the
/// library's own factor its products ride along the right-hand side's
/// solve in one block; not with an interface compliance); new
/// contacts, a new compliance and ds_history_reset forget that line. A
/// host that cuts an increment back retries it from the
/// failed try's last multipliers and line (the answer does not depend on
/// the start; ds_history_reset starts it from zero). The history of ds_step
/// is neither used nor changed.
///
/// - problem, opts, friction, bound: as ds_solve.
/// - r: the host's residual f_ext - f_int(u_j), n values (force units).
/// - g: the gaps at u_j, m values (length units; g_i < 0 a penetration).
/// - slip: s_j = T (u_j - u_n), (d-1) m values, one per row of T (length
///   units), or NULL at the first iteration of an increment (zero slip).
/// - lambda_t_start: the tangential forces at the start of the increment,
///   (d-1) m values, or NULL for zero. Read only at contacts with an elastic
///   slip (ds_problem_set_compliance, finite k_t), whose law is
///   lambda_T = proj(lambda_t_start + k_t (s_j + T du)).
/// - du: out, the displacement correction, n values.
/// - lambda_n, lambda_t: out, the total contact forces as in ds_solve.
/// - report: out, may be NULL.
///
/// Statuses and what is written: as ds_solve (the multipliers are kept for
/// the next iteration only on DS_STATUS_OK); a slip or lambda_t_start with a
/// NaN or an infinity is DS_STATUS_NOT_FINITE. The handle stays usable in
/// every case.
///
/// # Safety
/// As ds_solve; `slip` and `lambda_t_start` NULL or valid for (d-1) m values.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ds_solve_iteration(
    problem: *mut DsProblem,
    opts: *const DsOptions,
    friction: i32,
    r: *const f64,
    g: *const f64,
    bound: *const f64,
    slip: *const f64,
    lambda_t_start: *const f64,
    du: *mut f64,
    lambda_n: *mut f64,
    lambda_t: *mut f64,
    report: *mut DsReport,
) -> DsStatus {
    entry("ds_solve_iteration", || {
        let mode = Mode::Iteration {
            slip,
            lt_start: lambda_t_start,
        };
        // SAFETY: forwarded contract of ds_solve_iteration.
        unsafe {
            solve_impl(
                mode, problem, opts, friction, r, g, bound, du, lambda_n, lambda_t, report,
            )
        }
    })
}
