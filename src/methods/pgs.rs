//! Projected Gauss-Seidel on the whole dual, contact by contact (Siconos's NSGS
//! in its local form): one sweep (`sweeps.rs`) per outer iteration, Aitken's
//! relaxation (`aitken.rs`) on the Coulomb fixed point. The stopping test costs
//! O(c): the sweeps keep w = A lam - b current.

use super::aitken::Aitken;
use super::driver::{Flow, Gradient, OuterStep};
use super::sweeps::sweep;
use super::{DualProblem, MethodSpec};

/// `pgs`: one sweep per outer iteration, on frictionless increments as well (a
/// tangential step at a zero bound costs O(1) per contact).
pub(super) const PGS: MethodSpec = MethodSpec {
    name: "pgs",
    needs_entries: true,
    workspace: super::no_workspace,
    build: |problem, _opts, _target| (Box::new(Pgs::new(problem)), problem.dual.c),
};

/// Projected Gauss-Seidel on the whole dual, contact by contact: the normal
/// multiplier first, then the tangential block with the bound of the updated
/// normal multiplier (Coulomb). One outer iteration is one sweep.
///
/// Coulomb: the sweep is not a descent step of a fixed problem, and with strong
/// coupling between the normal and the tangential response (mu |A_NT| > A_NN) it
/// can cycle; each sweep is then relaxed by [`Aitken`] (a factor of 1, the plain
/// sweep, while the sweeps do not oscillate).
pub(super) struct Pgs {
    coulomb: bool,
    relax: Aitken,
    /// The iterate and w before the sweep (Coulomb).
    prev: Vec<f64>,
}

impl Pgs {
    pub fn new(problem: &DualProblem<'_>) -> Self {
        let c = problem.dual.c;
        let coulomb = problem.law.is_coulomb();
        Pgs {
            coulomb,
            relax: Aitken::new(if coulomb { c } else { 0 }),
            prev: vec![0.0; if coulomb { 2 * c } else { 0 }],
        }
    }
}

impl OuterStep for Pgs {
    fn step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        w: &mut [f64],
        inner: &mut usize,
        _k: usize,
    ) -> Flow {
        let c = problem.dual.c;
        if self.coulomb {
            self.prev[..c].copy_from_slice(lam);
            self.prev[c..].copy_from_slice(w);
        }
        sweep(problem, lam, w);
        if self.coulomb {
            // w = A lam - b is affine in lam: relaxed the same way.
            let omega = self.relax.relax(&self.prev[..c], lam);
            for (wi, wp) in w.iter_mut().zip(&self.prev[c..]) {
                *wi = wp + omega * (*wi - wp);
            }
        }
        *inner += 1;
        Flow::Go(Gradient::Updated)
    }
}
