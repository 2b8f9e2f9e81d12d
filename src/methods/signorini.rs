//! The pure Signorini problem of a frictionless increment (every slip bound zero:
//! lambda_T = 0): min 1/2 y^T A_NN y - y^T b_N over y >= 0 in the m normal
//! unknowns alone (docs/design.md section 2: the cost follows the physics switched on),
//! on the leading m x m block of A (dense) or on products with it (matrix-free,
//! MPRGP only). One outer iteration is one sub-problem solve (to a tenth of the
//! target); the stopping test is the whole problem's err.

use super::driver::{Flow, Gradient, OuterStep};
use super::subproblem::{SubQp, SubSolver};
use super::{Built, DualProblem, Options, inner_rule};

/// The outer step of a frictionless increment (every slip bound zero) for the
/// methods that solve it as the pure Signorini problem in the m normal unknowns
/// (the splittings and whole-dual MPRGP), its sub-problems by `solver(k, tol,
/// max)`; None when the increment has friction.
pub(super) fn frictionless<S: SubSolver + 'static>(
    problem: &DualProblem<'_>,
    opts: &Options,
    target: f64,
    solver: fn(usize, f64, usize) -> S,
) -> Option<Built> {
    if !problem.law.frictionless() {
        return None;
    }
    let (tol, max) = inner_rule(opts, target);
    let m = problem.dual.m;
    Some((Box::new(Signorini::new(solver(m, tol, max))), m))
}

/// The frictionless increment solved by the sub-problem solver `S`.
pub(super) struct Signorini<S> {
    solver: S,
    /// The cached estimate of |A_NN| (MPRGP).
    norm: Option<f64>,
}

impl<S: SubSolver> Signorini<S> {
    pub fn new(solver: S) -> Self {
        Signorini { solver, norm: None }
    }
}

impl<S: SubSolver> OuterStep for Signorini<S> {
    fn start(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        _w: &mut [f64],
        _inner: &mut usize,
    ) -> Flow {
        lam[problem.dual.m..].iter_mut().for_each(|x| *x = 0.0);
        Flow::Go(Gradient::Stale)
    }

    fn step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        _w: &mut [f64],
        inner: &mut usize,
        _k: usize,
    ) -> Flow {
        let dual = problem.dual;
        let m = dual.m;
        let qp = SubQp {
            h: &dual.a,
            ld: dual.c,
            k: m,
            q: &problem.b[..m],
            block: 1,
            radii: None,
            op: dual.is_matrix_free().then_some(dual),
            threads: &dual.threads,
        };
        let run = self.solver.solve(&qp, &mut lam[..m], &mut self.norm);
        Flow::after(run, inner, Gradient::Stale)
    }
}
