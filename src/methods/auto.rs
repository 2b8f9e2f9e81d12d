//! `auto`: the library's choice of method for the dual at hand, and the fallback
//! when that choice makes no progress.
//!
//! The rule follows the benchmark (BENCHMARKS.md, tables at tol 1e-10): on a dense
//! dual, semismooth Newton is the fastest method, or within 1.2 x of it, on every
//! scene of the 2D and 3D families, Tresca and Coulomb, cold and warm. Where it
//! stalls (FCLib's spheres-in-a-box: redundant contacts, A singular; Newton's |F|
//! stops falling) Pop's splitting with MPRGP sub-problems is the one method that
//! converges, and it continues from Newton's best iterate. On a matrix-free dual
//! (c above `DENSE_MAX`, or a dense A that does not fit `max_memory`) Newton
//! solves its steps by Krylov iterations (one product with A each), and MPRGP,
//! which also runs on products alone, takes over where it stalls.

use super::driver::{End, Outcome};
use super::{DualProblem, MethodSpec, run_one};
use crate::options::{Method, Options};

/// `auto` in the table of methods. It reads no entry of A itself (the dual is
/// kept in the form it has); its work space is that of the methods it may run.
pub(super) const AUTO: MethodSpec = MethodSpec {
    name: "auto",
    needs_entries: false,
    workspace: |m, c, matrix_free| {
        plan(matrix_free)
            .iter()
            .map(|&(method, _)| method.workspace(m, c, matrix_free))
            .max()
            .unwrap_or(0)
    },
    build: |problem, opts, target| {
        let first = plan(problem.dual.is_matrix_free())[0].0;
        (first.spec().build)(problem, opts, target)
    },
};

/// The methods `auto` runs, in order, each with why: the first, then the next
/// where the one before ended stalled or at its iteration limit.
pub(super) fn plan(matrix_free: bool) -> &'static [(Method, &'static str)] {
    if matrix_free {
        &[
            (
                Method::Newton,
                "matrix-free dual (c above DENSE_MAX, or the dense A does not fit \
                 max_memory): semismooth Newton with Krylov solves of its steps",
            ),
            (
                Method::Mprgp,
                "Newton stalled on the matrix-free dual: mprgp from Newton's best \
                 iterate",
            ),
        ]
    } else {
        &[
            (
                Method::Newton,
                "dense dual: semismooth Newton, the fastest to 1e-10 on the benchmark \
                 scenes",
            ),
            (
                Method::SplitMprgp,
                "Newton stalled: Pop's splitting with MPRGP sub-problems, from Newton's \
                 best iterate",
            ),
        ]
    }
}

/// Runs the plan from `lam`: each method with the outer iterations the ones
/// before left of `opts.max_outer`, from the iterate the one before returned
/// (its lowest-err one). The counts add up; the outcome names the last method.
pub(super) fn run(
    problem: &DualProblem<'_>,
    lam: &mut [f64],
    opts: &Options,
    target: f64,
) -> Outcome {
    let mut total = Outcome::default();
    for &(method, why) in plan(problem.dual.is_matrix_free()) {
        let left = Options {
            method,
            max_outer: opts.max_outer.saturating_sub(total.outer),
            ..*opts
        };
        let out = run_one(problem, lam, &left, target);
        total = Outcome {
            outer: total.outer + out.outer,
            inner: total.inner + out.inner,
            choice: why,
            ..out
        };
        let hopeless = matches!(out.end, End::Stalled | End::Limit);
        if !hopeless || total.outer >= opts.max_outer {
            break;
        }
    }
    total
}
