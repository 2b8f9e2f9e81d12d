//! Projected Gauss-Seidel: the local steps, the sweeps of a bound-constrained
//! sub-problem (used inside the splittings), and PGS on the whole dual, contact by
//! contact (Siconos's NSGS in its local form).
//!
//! Every sweep keeps w = H x - q current by rank-one updates, so a sweep costs one
//! column of H per changed unknown and the stopping test costs O(k).

use super::mprgp::ConvexQp;
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
    /// sweeps or iterations. `w` is scratch of length k.
    pub fn solve_with(
        &self,
        mprgp: bool,
        x: &mut [f64],
        w: &mut [f64],
        tol: f64,
        max: usize,
    ) -> usize {
        if mprgp {
            self.as_convex().solve(x, tol, max)
        } else {
            self.solve(x, w, tol, max)
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
    problem.gradient(lam, &mut w);
    loop {
        let mut e = problem.error(lam, &w, &mut p, &mut v);
        if e <= target {
            // Confirm on an exact gradient: the rank-one updates drift by rounding.
            problem.gradient(lam, &mut w);
            e = problem.error(lam, &w, &mut p, &mut v);
        }
        out.dual_err = e;
        if problem.should_stop(&mut out, lam, &p, &v, target, opts) {
            return out;
        }
        sweep(problem, lam, &mut w);
        out.outer += 1;
        out.inner += 1;
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
