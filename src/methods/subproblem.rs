//! The bound-constrained sub-problems of the splittings and of the frictionless
//! increments, and the two solvers behind one trait, [`SubSolver`]: projected
//! Gauss-Seidel ([`GaussSeidel`]) and MPRGP / MPGP ([`Mprgp`]).
//!
//! Every Gauss-Seidel sweep keeps w = H x - q current by rank-one updates, so a
//! sweep costs one column of H per changed unknown and the stopping test costs O(k).

use super::mprgp::{ConvexQp, Scratch, Unbounded};
use super::projection::{project_disk, solve_disk_qp};
use crate::dual::Dual;
use crate::threads::Threads;

/// w += delta * col.
#[inline]
pub(super) fn axpy(w: &mut [f64], delta: f64, col: &[f64]) {
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
    /// The whole condensed dual by its products instead of `h` (matrix-free; only
    /// for MPRGP, and only when k = c and H = A).
    pub op: Option<&'a Dual>,
    /// The problem's threads, for the products with H.
    pub threads: &'a Threads,
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
            op: self.op,
            k: self.k,
            q: self.q,
            n_nonneg,
            block: self.block,
            radii,
            threads: self.threads,
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
    fn solve(&self, x: &mut [f64], w: &mut [f64], tol: f64, max: usize) -> usize {
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

/// A solver of [`SubQp`] sub-problems, holding its own work space (allocated once
/// per method run) and its stopping rule: a relative residual of at most `tol`, or
/// `max` iterations (a tenth of the outer target and `Options::max_inner`, set by
/// the method's `MethodSpec::build`).
pub(super) trait SubSolver {
    /// Solves `qp` from `x` (at most k unknowns, k the size given at creation)
    /// until the stopping rule holds; returns the iterations, or [`Unbounded`] when
    /// the solver can tell that the quadratic has no minimiser. `norm` caches an
    /// estimate of |H| for the matrix of `qp`: the caller resets it to None when H
    /// changes.
    fn solve(
        &mut self,
        qp: &SubQp<'_>,
        x: &mut [f64],
        norm: &mut Option<f64>,
    ) -> Result<usize, Unbounded>;
}

/// Projected Gauss-Seidel sweeps (at least one per solve); never reports an
/// unbounded sub-problem, and needs the entries of H (`qp.op` unset).
pub(super) struct GaussSeidel {
    w: Vec<f64>,
    tol: f64,
    max: usize,
}

impl GaussSeidel {
    /// Work space for sub-problems of up to `k` unknowns; stops at `tol` or after
    /// `max` sweeps.
    pub fn new(k: usize, tol: f64, max: usize) -> Self {
        GaussSeidel {
            w: vec![0.0; k],
            tol,
            max,
        }
    }
}

impl SubSolver for GaussSeidel {
    fn solve(
        &mut self,
        qp: &SubQp<'_>,
        x: &mut [f64],
        _norm: &mut Option<f64>,
    ) -> Result<usize, Unbounded> {
        debug_assert!(qp.op.is_none(), "Gauss-Seidel reads entries of H");
        Ok(qp.solve(x, &mut self.w[..qp.k], self.tol, self.max))
    }
}

/// MPRGP / MPGP (Dostal; see `mprgp`).
pub(super) struct Mprgp {
    scratch: Scratch,
    tol: f64,
    /// Where > 0, a solve also stops at this fraction of its residual at
    /// the (projected) start.
    drop: f64,
    max: usize,
}

impl Mprgp {
    /// Work space for sub-problems of up to `k` unknowns; stops at `tol` or after
    /// `max` iterations.
    pub fn new(k: usize, tol: f64, max: usize) -> Self {
        Mprgp {
            scratch: Scratch::new(k),
            tol,
            drop: 0.0,
            max,
        }
    }

    /// Also stops each solve once its residual is at most `drop` times the
    /// one at its projected start (0: never).
    pub fn with_drop(self, drop: f64) -> Self {
        Mprgp { drop, ..self }
    }

    /// Solves a quadratic with both nonnegative unknowns and disks (the whole dual).
    pub fn solve_convex(
        &mut self,
        qp: &ConvexQp<'_>,
        x: &mut [f64],
        norm: &mut Option<f64>,
    ) -> Result<usize, Unbounded> {
        qp.solve_in(x, (self.tol, self.drop), self.max, &mut self.scratch, norm)
    }
}

impl SubSolver for Mprgp {
    fn solve(
        &mut self,
        qp: &SubQp<'_>,
        x: &mut [f64],
        norm: &mut Option<f64>,
    ) -> Result<usize, Unbounded> {
        self.solve_convex(&qp.as_convex(), x, norm)
    }
}
