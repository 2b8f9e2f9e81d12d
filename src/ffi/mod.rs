//! The C boundary: `extern "C"` entry points, the status enum, the thread-local last
//! error message, the panic boundary, pointer and slice checks, and the `#[repr(C)]`
//! options, report and matrix structs. Nothing here does numerics: every entry point
//! validates what C hands it, borrows it as Rust slices (never copying, never taking
//! ownership), calls the safe API ([`crate::ContactProblem`]), and writes outputs back.
//!
//! The header `include/dualsplit.h` is generated from these files by cbindgen
//! (`DUALSPLIT_BLESS=1 cargo test --test header`); `tests/header.rs` fails when it
//! is out of date.
//!
//! Rules shared by every entry point:
//! - panics are caught and reported as [`DsStatus::Panic`]; none crosses the boundary;
//! - on an error status the outputs are untouched, the handle is unchanged and
//!   [`ds_last_error_message`] describes the failure; the statuses of an
//!   unconverged solve (NOT_CONVERGED, STOPPED, STALLED, TIME_LIMIT) write what the
//!   header's opening comment lists, and keep the dual form the options asked for;
//! - array pointers may be NULL when the array has length 0;
//! - caller memory is only borrowed for the duration of the call.

// The re-exports below gather the C-facing items for the tests (through
// `internals::ffi`, with the `internals` feature); without it nothing in the
// crate reads them (the symbols are exported either way).
#![cfg_attr(not(feature = "internals"), allow(unused_imports))]

mod boundary;
mod cost;
mod error;
mod host;
mod info;
mod last_error;
mod matrix;
mod monitor;
mod options;
mod problem;
mod report;
mod solve;
mod status;
mod types;
mod version;

pub use cost::{DsCost, ds_problem_last_cost};
pub use host::{
    DsHostInverseFn, DsHostSolveFn, DsHostSolveSingleFn, DsHostSolver, ds_problem_new_host,
};
pub use info::{DsInfo, ds_analyse, ds_problem_info};
pub use last_error::ds_last_error_message;
pub use matrix::DsMatrix;
pub use monitor::{DsLogFn, DsMonitorFn, DsProgress};
pub use options::{DsOptions, ds_options_default, ds_options_init};
pub use problem::{
    DsProblem, ds_history_reset, ds_problem_dump, ds_problem_free, ds_problem_new,
    ds_problem_new_opts, ds_problem_refactor, ds_problem_set_compliance, ds_problem_set_contacts,
    ds_problem_set_log, ds_problem_set_monitor, ds_problem_sizes,
};
pub use report::DsReport;
pub use solve::{ds_solve, ds_solve_iteration, ds_step};
pub use status::{DsStatus, ds_status_string};
pub use types::{
    DsDualForm, DsFormat, DsFriction, DsHostBlocks, DsIndexType, DsMethod, DsOrdering, DsStorage,
};
pub use version::ds_version;
