//! Watching a solve from C: the monitor callback (called after every outer
//! iteration, able to stop the solve) and the log sink with its level. Both are set
//! on the handle and stay until replaced.

use crate::methods::Progress;
use crate::report::{Report, SolveStatus};
use std::ffi::{CString, c_char, c_void};

/// What the monitor callback receives after every outer iteration.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DsProgress {
    /// Outer iterations done so far in this solve (1 after the first).
    pub iteration: i64,
    /// The current err (docs/design.md section 5), measured on the dual gradient;
    /// dimensionless. After a matrix-free Newton step whose gradient was kept
    /// by single-precision products it is within about 1 % of the exact one,
    /// or about a tenth of the tolerance where that is more (the err the
    /// report gives is measured on the recovered u); so are the contact
    /// counts.
    pub err: f64,
    /// Open contacts at the current iterate.
    pub n_open: i64,
    /// Sticking contacts at the current iterate.
    pub n_stick: i64,
    /// Slipping contacts at the current iterate.
    pub n_slip: i64,
    /// Seconds since the solve started.
    pub elapsed_seconds: f64,
}

/// A monitor callback: called after every outer iteration of ds_solve / ds_step
/// with the progress and the user pointer given to ds_problem_set_monitor. Return 0
/// to go on, any other value to stop: the solve then returns DS_STATUS_STOPPED with
/// the last iterate. The callback must not call back into the same handle, and must
/// not longjmp out (or throw a C++ exception through) the library: that skips Rust
/// frames and is undefined behaviour.
pub type DsMonitorFn =
    Option<unsafe extern "C" fn(progress: *const DsProgress, user_data: *mut c_void) -> i32>;

/// A log sink: receives each message (a NUL-terminated line without newline, valid
/// only during the call), its level (1 = one summary per solve, 2 = one line per
/// outer iteration) and the user pointer given to ds_problem_set_log.
pub type DsLogFn =
    Option<unsafe extern "C" fn(level: i32, message: *const c_char, user_data: *mut c_void)>;

/// Log levels accepted by ds_problem_set_log.
pub const LOG_SILENT: i32 = 0;
/// One summary line per solve.
pub const LOG_SUMMARY: i32 = 1;
/// One line per outer iteration, plus the summary.
pub const LOG_ITERATIONS: i32 = 2;

/// The monitor and log settings of a handle.
pub(super) struct Watch {
    pub monitor: DsMonitorFn,
    pub monitor_data: *mut c_void,
    pub log: DsLogFn,
    pub log_data: *mut c_void,
    pub level: i32,
}

impl Default for Watch {
    fn default() -> Self {
        Watch {
            monitor: None,
            monitor_data: std::ptr::null_mut(),
            log: None,
            log_data: std::ptr::null_mut(),
            level: LOG_SILENT,
        }
    }
}

fn count(v: usize) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

impl Watch {
    /// Sends one line to the log sink, or to stderr when there is none (a
    /// line stderr cannot take is dropped).
    pub fn log(&self, level: i32, message: &str) {
        if level > self.level {
            return;
        }
        match self.log {
            Some(sink) => {
                let line = CString::new(message.replace('\0', " ")).unwrap_or_default();
                // SAFETY: the sink is a C function supplied by the caller with this
                // user pointer; the string lives until the call returns.
                unsafe { sink(level, line.as_ptr(), self.log_data) };
            }
            // Not eprintln!, which panics where stderr cannot be written (a
            // closed pipe): a log line must never fail a solve.
            None => {
                use std::io::Write;
                let _ = writeln!(std::io::stderr(), "dualsplit: {message}");
            }
        }
    }

    /// The per-iteration hook given to the solver: logs and calls the monitor.
    /// Returns false when the monitor asks to stop.
    pub fn on_iteration(&self, method: &str, p: &Progress) -> bool {
        if self.level >= LOG_ITERATIONS {
            self.log(
                LOG_ITERATIONS,
                &format!(
                    "{method} iteration {}: err {:.3e}, open {} stick {} slip {}, {:.3} s",
                    p.iteration, p.err, p.n_open, p.n_stick, p.n_slip, p.elapsed_seconds
                ),
            );
        }
        let Some(monitor) = self.monitor else {
            return true;
        };
        let progress = DsProgress {
            iteration: count(p.iteration),
            err: p.err,
            n_open: count(p.n_open),
            n_stick: count(p.n_stick),
            n_slip: count(p.n_slip),
            elapsed_seconds: p.elapsed_seconds,
        };
        // SAFETY: the monitor is a C function supplied by the caller with this user
        // pointer; `progress` lives until the call returns.
        unsafe { monitor(&progress, self.monitor_data) == 0 }
    }

    /// The summary line of a finished solve.
    pub fn on_done(&self, r: &Report) {
        if self.level >= LOG_SUMMARY {
            let status = match r.status {
                SolveStatus::Converged => "converged",
                SolveStatus::NotConverged => "NOT converged",
                SolveStatus::Stopped => "stopped by the caller",
                SolveStatus::Stalled => "NOT converged (stalled)",
                SolveStatus::TimeLimit => "NOT converged (time limit)",
            };
            if !r.choice.is_empty() {
                self.log(
                    LOG_SUMMARY,
                    &format!("auto chose {}: {}", r.method.name(), r.choice),
                );
            }
            self.log(
                LOG_SUMMARY,
                &format!(
                    "{}: {status}, err {:.3e}, {} outer / {} inner iterations, open {} stick {} slip {}, \
                     equilibrium {:.1e}, solve {:.3e} s{}{}",
                    r.method.name(),
                    r.err,
                    r.outer_iterations,
                    r.inner_iterations,
                    r.n_open,
                    r.n_stick,
                    r.n_slip,
                    r.equilibrium_residual,
                    r.solve_seconds,
                    if r.compliant_contacts > 0 {
                        format!(", compliant interface on {} contacts", r.compliant_contacts)
                    } else {
                        String::new()
                    },
                    if r.host_solves > 0 {
                        format!(
                            ", {} host solves taking {:.3e} s",
                            r.host_solves, r.host_seconds
                        )
                    } else {
                        String::new()
                    }
                ),
            );
        }
    }
}
