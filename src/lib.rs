//! dualsplit: discrete frictional contact (Signorini with Tresca or Coulomb friction)
//! for finite element codes, by N. Pop's dual splitting on the condensed dual
//! problem, with a C ABI. See README.md, and docs/design.md for the mathematics.
//!
//! Sign conventions: K u = f - N^T lambda_N - T^T lambda_T; N u <= g; lambda_N >= 0
//! is the compressive normal force; the friction force on the body, -T^T lambda_T,
//! opposes the slip T u.

pub mod dual;
pub mod error;
pub mod factor;
pub mod ffi;
pub mod friction;
pub mod methods;
pub mod mtx;
pub mod options;
pub mod ordering;
pub mod problem;
pub mod report;
pub mod sparse;

pub use error::{Error, ErrorKind, Result};
pub use friction::Friction;
pub use methods::{Monitor, Progress};
pub use options::{DualForm, Method, Options};
pub use problem::{ContactProblem, Solution};
pub use report::{Report, SolveStatus};
pub use sparse::{Csc, Format, Indices, MatrixView, Storage};
