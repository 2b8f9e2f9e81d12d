//! Projected Gauss-Seidel on the whole dual, contact by contact (Siconos's NSGS
//! in its local form), its sweeps (also Newton's warm-up and fallback), and
//! Aitken's relaxation of the Coulomb fixed point that every method shares.
//!
//! Every sweep keeps w = A lam - b current by rank-one updates, so a sweep costs
//! one column of A per changed unknown and the stopping test costs O(c).

use super::driver::{Flow, Gradient, OuterStep};
use super::projection::{project_disk, solve_disk_qp};
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

/// The smallest relaxation factor of [`Aitken`]: enough for a coupling
/// mu |A_NT| / A_NN up to about 1e3.
const OMEGA_MIN: f64 = 1e-3;

/// Aitken's dynamic relaxation of a fixed-point iteration x -> G(x) (Irons and
/// Tuck; Kuettler and Wall): x_k+1 = x_k + omega_k r_k with r_k = G(x_k) - x_k and
/// omega_k = -omega_k-1 r_k-1 . (r_k - r_k-1) / |r_k - r_k-1|^2, cut to
/// [`OMEGA_MIN`, 1] (omega_0 = 1). For a map that converges monotonically omega
/// stays 1 (the plain iteration); for one that oscillates with slope -kappa
/// (kappa >= 1: no contraction) omega tends to 1 / (1 + kappa), the factor that
/// makes the relaxed map contract. omega is a ratio: the same in any units. The
/// relaxed iterate is a convex combination of x_k and G(x_k), so it stays in any
/// convex set (the friction cones, lambda_N >= 0) that both lie in.
pub(super) struct Aitken {
    r_old: Vec<f64>,
    have_old: bool,
    omega: f64,
}

impl Aitken {
    pub fn new(n: usize) -> Self {
        Aitken {
            r_old: vec![0.0; n],
            have_old: false,
            omega: 1.0,
        }
    }

    /// `x` holds G(x_prev) on entry and the relaxed iterate on exit; returns the
    /// factor used.
    pub fn relax(&mut self, x_prev: &[f64], x: &mut [f64]) -> f64 {
        if self.have_old {
            let (mut rd, mut dd) = (0.0, 0.0);
            for ((xn, xp), ro) in x.iter().zip(x_prev).zip(&self.r_old) {
                let d = (xn - xp) - ro;
                rd += ro * d;
                dd += d * d;
            }
            if dd > 0.0 {
                let omega = -self.omega * rd / dd;
                // omega <= 0: r grew along itself (slope > 1), which no damping
                // cures: back to the plain iteration.
                self.omega = if omega > 0.0 && omega.is_finite() {
                    omega.clamp(OMEGA_MIN, 1.0)
                } else {
                    1.0
                };
            }
        }
        for ((xn, xp), ro) in x.iter_mut().zip(x_prev).zip(self.r_old.iter_mut()) {
            *ro = *xn - xp;
            *xn = xp + self.omega * *ro;
        }
        self.have_old = true;
        self.omega
    }

    /// The Coulomb bound of an outer loop: relaxes the new bound `p` (mu lambda_N)
    /// against `prev`, the bound the last step used (not on the first step), and
    /// keeps the result in `prev` for the next one.
    pub fn relax_bound(&mut self, prev: &mut [f64], p: &mut [f64], first: bool) {
        if !first {
            self.relax(prev, p);
        }
        prev.copy_from_slice(p);
    }
}

/// One PGS sweep over all contacts, keeping w = A lam - b current (exact
/// columns of A).
fn sweep(problem: &DualProblem<'_>, lam: &mut [f64], w: &mut [f64]) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aitken_makes_an_oscillating_fixed_point_contract() {
        // x -> G(x) = 1 - 3 x (slope -3: the plain iteration diverges, oscillating);
        // the fixed point is 1/4. Aitken finds omega = 1 / (1 + 3) after one step.
        let g = |x: f64| 1.0 - 3.0 * x;
        let mut relax = Aitken::new(1);
        let mut x = [0.0];
        let mut omegas = Vec::new();
        for _ in 0..6 {
            let prev = x;
            x[0] = g(x[0]);
            omegas.push(relax.relax(&prev, &mut x));
        }
        assert!((x[0] - 0.25).abs() < 1e-14, "x = {}", x[0]);
        assert_eq!(omegas[0], 1.0);
        assert!((omegas[1] - 0.25).abs() < 1e-14, "{omegas:?}");
        // A monotone contraction (slope 0.5) keeps the plain iteration.
        let mut relax = Aitken::new(1);
        let mut x = [0.0];
        for _ in 0..5 {
            let prev = x;
            x[0] = 1.0 + 0.5 * x[0];
            assert_eq!(relax.relax(&prev, &mut x), 1.0);
        }
    }
}
