//! dualsplit: discrete frictional contact (Signorini with Tresca or Coulomb friction)
//! for finite element codes, by N. Pop's dual splitting on the condensed dual
//! problem, with a C ABI. See README.md, and docs/design.md for the mathematics.
//!
//! Sign conventions: K u = f - N^T lambda_N - T^T lambda_T; N u <= g; lambda_N >= 0
//! is the compressive normal force; the friction force on the body, -T^T lambda_T,
//! opposes the slip T u.

mod compliance;
mod contact_rows;
mod dense;
mod dirichlet;
mod drift;
mod dual;
mod error;
mod factor;
mod factor_tree;
// The C boundary: its `extern "C"` functions are the library's exported
// symbols whatever this module's visibility; as Rust items they are the
// tests', through `internals::ffi`, not the Rust API.
mod ffi;
mod friction;
mod history;
mod host;
mod info;
mod load_span;
mod memory;
mod methods;
/// Matrix Market files and problem folders, for the `dualsplit` command-line
/// tool (and the tests and benchmarks): not part of the Rust API, it may change
/// without notice. Rust callers build [`Csc`] or [`MatrixView`] instead.
#[doc(hidden)]
pub mod mtx;
mod options;
mod ordering;
mod plan;
mod problem;
mod report;
mod restricted;
mod sizes;
mod sparse;
#[cfg(test)]
mod test_scenes;
mod threads;
mod tree_cholesky;

pub use error::{Error, ErrorKind, Result};
pub use friction::Friction;
pub use host::KSolve;
pub use info::Info;
pub use methods::{Monitor, Progress};
pub use options::{
    DENSE_MAX, DualForm, HostBlocks, Method, Options, Ordering, STALL_FACTOR, STALL_WINDOW,
};
pub use problem::{ContactProblem, HostIteration, RefactorCost, Solution};
pub use report::{Report, SolveStatus};
pub use sparse::{Csc, Format, Indices, MatrixView, SYMMETRY_TOL, Storage};

/// The library's internal pieces, for its own benchmark and tests only (feature
/// `internals`, which the crate's dev-dependency on itself turns on): the dense
/// dual operator, the Cholesky factor of K, the reference residual. Not part of
/// the API; they change without notice.
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod internals {
    pub use crate::contact_rows::{contact_dofs, stack_rows};
    pub use crate::dual::{Condensation, Dual};
    pub use crate::factor::Factor;
    pub use crate::factor_tree::row_solves::RowSolves;
    pub use crate::report::natural_map_error;
    pub use crate::threads::Threads;

    /// The C boundary's items (the `extern "C"` functions, `#[repr(C)]` types and
    /// enums), for the tests that call it from Rust.
    pub mod ffi {
        pub use crate::ffi::*;
    }
}
