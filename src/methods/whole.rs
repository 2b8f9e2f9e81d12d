//! MPRGP / MPGP on the whole dual, with the Coulomb fixed point p = mu lambda_N
//! outside: each outer iteration solves the Tresca problem of the current bound
//! (one outer iteration for Tresca). The Coulomb bound is relaxed as in the
//! splittings (`aitken::Aitken`; the plain fixed point while it does not oscillate).

use super::aitken::Aitken;
use super::driver::{Flow, Gradient, OuterStep};
use super::mprgp::ConvexQp;
use super::signorini::frictionless;
use super::subproblem::Mprgp;
use super::{DualProblem, MethodSpec, inner_rule};

/// `mprgp`: MPRGP / MPGP on the whole dual (a frictionless increment: on the m
/// normal unknowns); the one method that runs on products with A alone.
pub(super) const MPRGP: MethodSpec = MethodSpec {
    name: "mprgp",
    needs_entries: false,
    workspace: super::no_workspace,
    build: |problem, opts, target| {
        if let Some(signorini) = frictionless(problem, opts, target, Mprgp::new) {
            return signorini;
        }
        let (tol, max) = inner_rule(opts, target);
        let c = problem.dual.c;
        (
            Box::new(WholeMprgp::new(problem, Mprgp::new(c, tol, max))),
            c,
        )
    },
};

pub(super) struct WholeMprgp {
    solver: Mprgp,
    /// The cached estimate of |A| (A is the same matrix for every outer iteration).
    norm: Option<f64>,
    coulomb: bool,
    relax: Aitken,
    /// The bound of the last outer iteration (Coulomb).
    prev: Vec<f64>,
    radii: Vec<f64>,
}

impl WholeMprgp {
    /// `solver` holds the sub-problem stopping rule.
    pub fn new(problem: &DualProblem<'_>, solver: Mprgp) -> Self {
        let m = problem.dual.m;
        let coulomb = problem.law.is_coulomb();
        let relaxed = if coulomb { m } else { 0 };
        WholeMprgp {
            solver,
            norm: None,
            coulomb,
            relax: Aitken::new(relaxed),
            prev: vec![0.0; relaxed],
            radii: vec![0.0; m],
        }
    }
}

impl OuterStep for WholeMprgp {
    fn step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        _w: &mut [f64],
        inner: &mut usize,
        k: usize,
    ) -> Flow {
        let m = problem.dual.m;
        problem.law.bounds(&lam[..m], &mut self.radii);
        if self.coulomb {
            self.relax
                .relax_bound(&mut self.prev, &mut self.radii, k == 0);
        }
        let qp = ConvexQp::whole(problem, &self.radii);
        // |A + D| estimated once per operator (see `Dual::whole_norm`).
        if self.norm.is_none() {
            self.norm = problem.dual.whole_norm();
        }
        let run = self.solver.solve_convex(&qp, lam, &mut self.norm);
        if let Some(norm) = self.norm {
            problem.dual.keep_whole_norm(norm);
        }
        Flow::after(run, inner, Gradient::Stale)
    }
}
