//! Projected Gauss-Seidel: the local steps, the sweeps of a bound-constrained
//! sub-problem (used inside the splittings), and PGS on the whole dual, contact by
//! contact (Siconos's NSGS in its local form).
//!
//! Every sweep keeps w = H x - q current by rank-one updates, so a sweep costs one
//! column of H per changed unknown and the stopping test costs O(k).

use super::mprgp::{ConvexQp, Scratch, Unbounded};
use super::projection::{project_disk, solve_disk_qp};
use super::{DualProblem, Outcome};
use crate::options::Options;

/// w += delta * col.
#[inline]
fn axpy(w: &mut [f64], delta: f64, col: &[f64]) {
    for (wi, ci) in w.iter_mut().zip(col) {
        *wi += delta * ci;
    }
}

/// A bound-constrained quadratic sub-problem min 1/2 x^T H x - q^T x over
/// x >= 0 (`radii` = None) or over |x_i| <= radii_i for blocks of `block` (1 or 2)
/// unknowns. H is the k x k block of a column-major array with leading dimension
/// `ld` starting at `h[0]`.
pub(super) struct SubQp<'a> {
    pub h: &'a [f64],
    pub ld: usize,
    pub k: usize,
    pub q: &'a [f64],
    pub block: usize,
    pub radii: Option<&'a [f64]>,
}

impl<'a> SubQp<'a> {
    /// The same sub-problem for MPRGP.
    pub fn as_convex(&self) -> ConvexQp<'a> {
        let (n_nonneg, radii): (usize, &'a [f64]) = match self.radii {
            None => (self.k, &[]),
            Some(r) => (0, r),
        };
        ConvexQp {
            h: self.h,
            ld: self.ld,
            op: None,
            k: self.k,
            q: self.q,
            n_nonneg,
            block: self.block,
            radii,
        }
    }

    /// Solves by projected Gauss-Seidel (`mprgp` false) or MPRGP; returns the
    /// sweeps or iterations, or MPRGP's [`Unbounded`] (Gauss-Seidel does not
    /// detect an unbounded sub-problem). `scratch` holds sub-problems of size k;
    /// `norm` is MPRGP's cached estimate of |H| (see [`ConvexQp::solve_in`]).
    pub fn solve_with(
        &self,
        mprgp: bool,
        x: &mut [f64],
        scratch: &mut Scratch,
        norm: &mut Option<f64>,
        tol: f64,
        max: usize,
    ) -> Result<usize, Unbounded> {
        if mprgp {
            self.as_convex().solve_in(x, tol, max, scratch, norm)
        } else {
            Ok(self.solve(x, scratch.one(self.k), tol, max))
        }
    }
    #[inline]
    fn col(&self, j: usize) -> &[f64] {
        &self.h[j * self.ld..j * self.ld + self.k]
    }

    #[inline]
    fn diag(&self, j: usize) -> f64 {
        self.h[j * self.ld + j]
    }

    /// w := H x - q.
    pub fn gradient(&self, x: &[f64], w: &mut [f64]) {
        w.iter_mut().zip(self.q).for_each(|(wi, qi)| *wi = -qi);
        for (j, &xj) in x.iter().enumerate() {
            if xj != 0.0 {
                axpy(w, xj, self.col(j));
            }
        }
    }

    /// One Gauss-Seidel sweep: each block minimised exactly with the others fixed.
    fn sweep(&self, x: &mut [f64], w: &mut [f64]) {
        let nb = self.k / self.block;
        for ib in 0..nb {
            let j = ib * self.block;
            if self.block == 1 {
                let hjj = self.diag(j);
                if hjj <= 0.0 {
                    continue;
                }
                let mut y = [x[j] - w[j] / hjj];
                match self.radii {
                    None => y[0] = y[0].max(0.0),
                    Some(r) => project_disk(&mut y, r[ib]),
                }
                let delta = y[0] - x[j];
                if delta != 0.0 {
                    x[j] = y[0];
                    axpy(w, delta, self.col(j));
                }
            } else {
                let r = self.radii.expect("disk blocks have radii")[ib];
                let (h00, h01, h11) = (self.diag(j), self.col(j + 1)[j], self.diag(j + 1));
                let c = [
                    h00 * x[j] + h01 * x[j + 1] - w[j],
                    h01 * x[j] + h11 * x[j + 1] - w[j + 1],
                ];
                let y = solve_disk_qp(h00, h01, h11, c, r);
                let (d0, d1) = (y[0] - x[j], y[1] - x[j + 1]);
                if d0 != 0.0 {
                    x[j] = y[0];
                    axpy(w, d0, self.col(j));
                }
                if d1 != 0.0 {
                    x[j + 1] = y[1];
                    axpy(w, d1, self.col(j + 1));
                }
            }
        }
    }

    /// Relative natural-map residual of the sub-problem, with rho_j = 1/H_jj
    /// (a block uses the inverse mean of its diagonal): the measure MPRGP uses too.
    fn residual(&self, x: &[f64], w: &[f64]) -> f64 {
        self.as_convex().residual(x, w)
    }

    /// Sweeps from x until the relative residual is at most `tol` or `max` sweeps;
    /// `w` is scratch of length k. Always sweeps at least once, so that an outer
    /// iteration around it cannot stall on a sub-problem that already meets `tol`.
    /// Returns the number of sweeps.
    pub fn solve(&self, x: &mut [f64], w: &mut [f64], tol: f64, max: usize) -> usize {
        self.gradient(x, w);
        for it in 1..=max {
            self.sweep(x, w);
            if self.residual(x, w) <= tol {
                return it;
            }
        }
        max
    }
}

/// Projected Gauss-Seidel on the whole dual, contact by contact: the normal
/// multiplier first, then the tangential block with the bound of the updated
/// normal multiplier (Coulomb). One outer iteration is one sweep.
///
/// Coulomb: the sweep is not a descent step of a fixed problem, and with strong
/// coupling between the normal and the tangential response (mu |A_NT| > A_NN) it
/// can cycle; each sweep is then relaxed by [`Aitken`] (a factor of 1, the plain
/// sweep, while the sweeps do not oscillate). At the iteration limit the iterate
/// with the lowest error is returned ([`BestIterate`]).
pub(super) fn solve(
    problem: &DualProblem<'_>,
    lam: &mut [f64],
    opts: &Options,
    target: f64,
) -> Outcome {
    let dual = problem.dual;
    let (m, c) = (dual.m, dual.c);
    let mut w = vec![0.0; c];
    let mut p = vec![0.0; m];
    let mut v = vec![0.0; c];
    let mut out = Outcome::default();
    let coulomb = matches!(problem.law, super::Law::Coulomb(_));
    let mut relax = Aitken::new(if coulomb { c } else { 0 });
    let mut prev = vec![0.0; if coulomb { 2 * c } else { 0 }];
    let mut best = BestIterate::new(c);
    problem.gradient(lam, &mut w);
    loop {
        let mut e = problem.error(lam, &w, &mut p, &mut v);
        if e <= target {
            // Confirm on an exact gradient: the rank-one updates drift by rounding.
            problem.gradient(lam, &mut w);
            e = problem.error(lam, &w, &mut p, &mut v);
        }
        out.dual_err = e;
        best.offer(lam, e);
        if problem.should_stop(&mut out, lam, &p, &v, target, opts) {
            best.restore_at_limit(lam, &mut out, target);
            return out;
        }
        if coulomb {
            prev[..c].copy_from_slice(lam);
            prev[c..].copy_from_slice(&w);
        }
        sweep(problem, lam, &mut w);
        if coulomb {
            // w = A lam - b is affine in lam: relaxed the same way.
            let omega = relax.relax(&prev[..c], lam);
            for (wi, wp) in w.iter_mut().zip(&prev[c..]) {
                *wi = wp + omega * (*wi - wp);
            }
        }
        out.outer += 1;
        out.inner += 1;
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

/// The iterate with the lowest error seen so far: what a method returns when it
/// stops at its iteration limit.
pub(super) struct BestIterate {
    lam: Vec<f64>,
    err: f64,
}

impl BestIterate {
    pub fn new(c: usize) -> Self {
        BestIterate {
            lam: vec![0.0; c],
            err: f64::INFINITY,
        }
    }

    /// Keeps a copy of `lam` when `err` is the lowest so far.
    pub fn offer(&mut self, lam: &[f64], err: f64) {
        if err < self.err {
            self.err = err;
            self.lam.copy_from_slice(lam);
        }
    }

    /// Called when the stopping test said stop: if the run ended at the iteration
    /// limit without meeting `target` (and the monitor did not stop it: then the
    /// last iterate is kept), puts the best iterate into `lam` and its error into
    /// `out`.
    pub fn restore_at_limit(&self, lam: &mut [f64], out: &mut Outcome, target: f64) {
        if !out.stopped && out.dual_err > target && self.err < out.dual_err {
            lam.copy_from_slice(&self.lam);
            out.dual_err = self.err;
        }
    }
}

/// One PGS sweep over all contacts, keeping w = A lam - b current.
fn sweep(problem: &DualProblem<'_>, lam: &mut [f64], w: &mut [f64]) {
    let dual = problem.dual;
    let (m, d, c) = (dual.m, dual.d, dual.c);
    for i in 0..m {
        let ann = dual.a[i + i * c];
        if ann > 0.0 {
            let y = (lam[i] - w[i] / ann).max(0.0);
            let delta = y - lam[i];
            if delta != 0.0 {
                lam[i] = y;
                axpy(w, delta, dual.col(i));
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
                    axpy(w, delta, dual.col(t));
                }
            } else if lam[t].abs() > r {
                let y = lam[t].clamp(-r, r);
                axpy(w, y - lam[t], dual.col(t));
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
                    axpy(w, delta, dual.col(t + s));
                }
            }
        }
    }
}

/// `count` PGS sweeps from lam (w = A lam - b on entry and exit); returns `count`.
pub(super) fn sweeps(
    problem: &DualProblem<'_>,
    lam: &mut [f64],
    w: &mut [f64],
    count: usize,
) -> usize {
    for _ in 0..count {
        sweep(problem, lam, w);
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

    #[test]
    fn the_best_iterate_comes_back_only_at_the_limit() {
        let mut best = BestIterate::new(2);
        best.offer(&[1.0, 2.0], 0.1);
        best.offer(&[3.0, 4.0], 0.5);
        let mut lam = [5.0, 6.0];
        let mut out = Outcome {
            dual_err: 0.3,
            ..Outcome::default()
        };
        // Converged: untouched.
        best.restore_at_limit(&mut lam, &mut out, 0.4);
        assert_eq!(lam, [5.0, 6.0]);
        // Stopped by the monitor: untouched.
        out.stopped = true;
        best.restore_at_limit(&mut lam, &mut out, 0.01);
        assert_eq!(lam, [5.0, 6.0]);
        // At the limit: the best one.
        out.stopped = false;
        best.restore_at_limit(&mut lam, &mut out, 0.01);
        assert_eq!(lam, [1.0, 2.0]);
        assert_eq!(out.dual_err, 0.1);
    }
}
