//! Projected Gauss-Seidel sweeps over the contacts, keeping w = A lam - b
//! current by rank-one updates (a sweep costs one column of A per changed
//! unknown): PGS's outer iteration, Newton's warm-up and fallback; on a large
//! dense dual the columns may be read in single precision (`Rough`).

use super::DualProblem;
use super::projection::{project_disk, solve_disk_qp};

/// One PGS sweep over all contacts, keeping w = A lam - b current (exact
/// columns of A).
pub(super) fn sweep(problem: &DualProblem<'_>, lam: &mut [f64], w: &mut [f64]) {
    sweep_with(problem, lam, w, &mut Exact(problem.dual));
}

/// Where a sweep's updates of w take A's columns from.
trait Columns {
    /// w += delta A[:, j].
    fn axpy(&mut self, w: &mut [f64], delta: f64, j: usize);
}

/// A's own columns.
struct Exact<'a>(&'a crate::dual::Dual);

impl Columns for Exact<'_> {
    fn axpy(&mut self, w: &mut [f64], delta: f64, j: usize) {
        for (wi, ci) in w.iter_mut().zip(self.0.col(j)) {
            *wi += delta * ci;
        }
    }
}

/// One PGS sweep over all contacts, w kept with the columns of `cols`. The
/// local problems read A's diagonal blocks in double precision either way.
fn sweep_with(problem: &DualProblem<'_>, lam: &mut [f64], w: &mut [f64], cols: &mut dyn Columns) {
    let dual = problem.dual;
    let (m, d, c) = (dual.m, dual.d, dual.c);
    for i in 0..m {
        let ann = dual.a[i + i * c];
        if ann > 0.0 {
            let y = (lam[i] - w[i] / ann).max(0.0);
            let delta = y - lam[i];
            if delta != 0.0 {
                lam[i] = y;
                cols.axpy(w, delta, i);
            }
        }
        let r = problem.law.bound(i, lam[i]);
        let t = m + (d - 1) * i;
        if d == 2 {
            let att = dual.a[t + t * c];
            if att > 0.0 {
                let mut y = [lam[t] - w[t] / att];
                project_disk(&mut y, r);
                let delta = y[0] - lam[t];
                if delta != 0.0 {
                    lam[t] = y[0];
                    cols.axpy(w, delta, t);
                }
            } else if lam[t].abs() > r {
                let y = lam[t].clamp(-r, r);
                cols.axpy(w, y - lam[t], t);
                lam[t] = y;
            }
        } else {
            let (h00, h01, h11) = (
                dual.a[t + t * c],
                dual.a[t + (t + 1) * c],
                dual.a[t + 1 + (t + 1) * c],
            );
            let cc = [
                h00 * lam[t] + h01 * lam[t + 1] - w[t],
                h01 * lam[t] + h11 * lam[t + 1] - w[t + 1],
            ];
            let y = solve_disk_qp(h00, h01, h11, cc, r);
            for s in 0..2 {
                let delta = y[s] - lam[t + s];
                if delta != 0.0 {
                    lam[t + s] = y[s];
                    cols.axpy(w, delta, t + s);
                }
            }
        }
    }
}

/// A's columns rounded to single precision, each at its first use, for
/// sweeps that only need to bring an iterate near the answer (Newton's
/// warm-up and fallback): half the memory traffic of a sweep, which reads a
/// column of A per changed unknown. w drifts by rounding at about
/// 1e-7 |A| |lam|; the caller recomputes it exactly after the sweeps. The
/// whole c x c copy is claimed on the problem's ledger (the pages of columns
/// never used are never touched).
pub(super) struct Rough {
    a: Vec<f32>,
    ready: Vec<bool>,
    _claim: crate::memory::Claim,
}

impl Rough {
    /// An empty copy of an assembled dual's A.
    pub fn new(dual: &crate::dual::Dual) -> Rough {
        let claim = dual.ledger.claim(dual.a.len() * std::mem::size_of::<f32>());
        Rough {
            a: vec![0.0; dual.a.len()],
            ready: vec![false; dual.c],
            _claim: claim,
        }
    }
}

/// The columns of a [`Rough`] copy, converted from `dual`'s at first use.
struct RoughColumns<'r> {
    rough: &'r mut Rough,
    dual: &'r crate::dual::Dual,
}

impl Columns for RoughColumns<'_> {
    fn axpy(&mut self, w: &mut [f64], delta: f64, j: usize) {
        let c = self.dual.c;
        let col = &mut self.rough.a[j * c..(j + 1) * c];
        if !self.rough.ready[j] {
            for (x, &v) in col.iter_mut().zip(self.dual.col(j)) {
                *x = v as f32;
            }
            self.rough.ready[j] = true;
        }
        for (wi, &ci) in w.iter_mut().zip(col.iter()) {
            *wi += delta * f64::from(ci);
        }
    }
}

/// Duals with at least this many unknowns sweep with [`Rough`] columns in
/// Newton's warm-up and fallback (`sweeps_for_newton`): below, A (c^2 doubles,
/// 32 MB here) stays in the caches and the copy only costs its conversion
/// (measured: 3d-20x20x10, c = 1,323, Coulomb warm step 0.025-0.030 ->
/// 0.027-0.035 s with the copy; 3d-30x30x15, c = 2,883, Tresca warm step
/// 0.43-0.50 -> 0.375-0.41 s).
pub(super) const ROUGH_MIN_C: usize = 2000;

/// `count` sweeps for Newton: with A's columns in single precision (`rough`,
/// made at the first call) from ROUGH_MIN_C unknowns on, exact below; w is
/// up to rounding on exit either way (recompute it). Returns `count`.
pub(super) fn sweeps_for_newton(
    problem: &DualProblem<'_>,
    rough: &mut Option<Rough>,
    lam: &mut [f64],
    w: &mut [f64],
    count: usize,
) -> usize {
    if problem.dual.c < ROUGH_MIN_C {
        for _ in 0..count {
            sweep(problem, lam, w);
        }
        return count;
    }
    let rough = rough.get_or_insert_with(|| Rough::new(problem.dual));
    rough_sweeps(problem, rough, lam, w, count)
}

/// `count` PGS sweeps from lam with the columns of `rough`; w = A lam - b on
/// entry, up to rounding on exit (recompute it before relying on it). Returns
/// `count`.
pub(super) fn rough_sweeps(
    problem: &DualProblem<'_>,
    rough: &mut Rough,
    lam: &mut [f64],
    w: &mut [f64],
    count: usize,
) -> usize {
    let mut cols = RoughColumns {
        rough,
        dual: problem.dual,
    };
    for _ in 0..count {
        sweep_with(problem, lam, w, &mut cols);
    }
    count
}
