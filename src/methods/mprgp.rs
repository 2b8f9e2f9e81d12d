//! MPRGP (Dostal: modified proportioning with reduced gradient projections) for a
//! convex quadratic over a product of simple sets, extended to the disks of 3D
//! friction (MPGP, Kucera / Dostal):
//!
//! ```text
//! min 1/2 x^T H x - q^T x,  x_j >= 0 (the first `n_nonneg` unknowns),
//!                           |x_b| <= r_b (then blocks of `block` = 1 or 2 unknowns).
//! ```
//!
//! Conjugate gradients run on the free set while the chopped gradient is small
//! against the free gradient (proportional iterate); an expansion step (feasible
//! CG step then a projected gradient step of length alpha < 2/|H|) adds constraints,
//! a proportioning step along the chopped gradient releases them. The rate depends
//! only on the spectrum of H, not on the size of the problem.

/// The quadratic and its constraint sets. H is the k x k block of a column-major
/// array with leading dimension `ld` starting at `h[0]`, or, when `op` is set, the
/// whole condensed dual A given by its products (matrix-free; `h` is then unused).
pub(super) struct ConvexQp<'a> {
    pub h: &'a [f64],
    pub ld: usize,
    pub op: Option<&'a crate::dual::Dual>,
    pub k: usize,
    pub q: &'a [f64],
    pub n_nonneg: usize,
    pub block: usize,
    pub radii: &'a [f64],
    /// The problem's threads, for the products with H.
    pub threads: &'a crate::threads::Threads,
}

impl<'a> ConvexQp<'a> {
    /// The whole dual of `problem` (its A, dense or by products, and its b) with
    /// the bounds `radii` (length m): lambda_N >= 0, |lambda_T,i| <= radii_i.
    pub fn whole<'p: 'a>(problem: &'a super::DualProblem<'p>, radii: &'a [f64]) -> ConvexQp<'a> {
        let dual = problem.dual;
        ConvexQp {
            h: &dual.a,
            ld: dual.c,
            op: dual.is_matrix_free().then_some(dual),
            k: dual.c,
            q: problem.b,
            n_nonneg: dual.m,
            block: dual.d - 1,
            radii,
            threads: &dual.threads,
        }
    }
}

/// Relative distance to the boundary under which a disk block counts as active.
const ON_BOUNDARY: f64 = 1e-14;

/// A direction p with p^T H p <= FLAT |H| |p|^2 has (numerically) no curvature:
/// below this the curvature is within the rounding of the product H p.
const FLAT: f64 = 1e-13;

/// A flat descent direction whose boundary lies further than REACH times the scale
/// of x (|x|, or |q| / |H| at x = 0) counts as unbounded: there the step would
/// leave the multipliers beyond what the dual resolves (w = A x - q is computed
/// with an absolute rounding of about eps |A| |x|, which then exceeds |q| 1e-8);
/// a boundary that rounding noise in p's components put at a finite distance
/// (7e18 on an infeasible test problem) is no boundary.
const REACH: f64 = 1e8;

/// Work vectors of MPRGP (five of length k), allocated once per method run and
/// reused by every sub-problem solve.
pub(super) struct Scratch {
    buf: Vec<f64>,
}

impl Scratch {
    /// Room for sub-problems of up to `k` unknowns.
    pub fn new(k: usize) -> Self {
        Scratch {
            buf: vec![0.0; 5 * k],
        }
    }

    /// Five vectors of length k (k at most the size given to `new`).
    fn vectors(&mut self, k: usize) -> [&mut [f64]; 5] {
        let (a, rest) = self.buf[..5 * k].split_at_mut(k);
        let (b, rest) = rest.split_at_mut(k);
        let (c, rest) = rest.split_at_mut(k);
        let (d, e) = rest.split_at_mut(k);
        [a, b, c, d, e]
    }
}

/// The quadratic is unbounded below on the feasible set: MPRGP met a descent
/// direction without curvature along which no constraint ever stops it (for the
/// condensed dual: B^T z = 0 with z_N >= 0 and g . z < 0, so no u satisfies
/// N u <= g; Farkas). `iterations` were done before it stopped; x is the last
/// iterate before the unbounded step.
#[derive(Copy, Clone, Debug, PartialEq)]
pub(super) struct Unbounded {
    pub iterations: usize,
}

impl ConvexQp<'_> {
    #[inline]
    fn col(&self, j: usize) -> &[f64] {
        &self.h[j * self.ld..j * self.ld + self.k]
    }

    /// H_jj.
    #[inline]
    fn diag(&self, j: usize) -> f64 {
        match self.op {
            Some(op) => op.diag(j),
            None => self.h[j * self.ld + j],
        }
    }

    /// y := H x.
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        match self.op {
            Some(op) => op.apply(x, y),
            None => crate::dual::leading_block_apply(self.h, self.ld, x, y, self.threads),
        }
    }

    /// y ~= H x for the norm estimate: on a matrix-free dual with products
    /// in single precision (`Dual::apply_rough`: relative error about 1e-7,
    /// far inside the estimate's 10 % margin), else exactly.
    fn apply_rough(&self, x: &[f64], y: &mut [f64]) {
        match self.op {
            Some(op) => op.apply_rough(x, y),
            None => self.apply(x, y),
        }
    }

    fn n_balls(&self) -> usize {
        (self.k - self.n_nonneg) / self.block
    }

    /// The unknowns of ball b.
    fn ball(&self, b: usize) -> std::ops::Range<usize> {
        let s = self.n_nonneg + b * self.block;
        s..s + self.block
    }

    /// x := P(x).
    fn project(&self, x: &mut [f64]) {
        for v in &mut x[..self.n_nonneg] {
            *v = v.max(0.0);
        }
        for b in 0..self.n_balls() {
            let r = self.ball(b);
            crate::friction::project_disk(&mut x[r], self.radii[b]);
        }
    }

    fn ball_active(&self, x: &[f64], b: usize) -> bool {
        let r = self.radii[b];
        let n = x[self.ball(b)].iter().map(|v| v * v).sum::<f64>().sqrt();
        n >= r * (1.0 - ON_BOUNDARY)
    }

    /// phi := the free gradient (g on free unknowns, 0 on active ones);
    /// beta := the chopped gradient (x - P(x - alpha g)) / alpha on active ones.
    fn split_gradient(&self, x: &[f64], g: &[f64], alpha: f64, phi: &mut [f64], beta: &mut [f64]) {
        for j in 0..self.n_nonneg {
            if x[j] > 0.0 {
                phi[j] = g[j];
                beta[j] = 0.0;
            } else {
                phi[j] = 0.0;
                beta[j] = g[j].min(0.0);
            }
        }
        let mut y = [0.0; 2];
        for b in 0..self.n_balls() {
            let r = self.ball(b);
            if self.ball_active(x, b) {
                for (s, j) in r.clone().enumerate() {
                    y[s] = x[j] - alpha * g[j];
                }
                crate::friction::project_disk(&mut y[..self.block], self.radii[b]);
                for (s, j) in r.enumerate() {
                    phi[j] = 0.0;
                    beta[j] = (x[j] - y[s]) / alpha;
                }
            } else {
                for j in r {
                    phi[j] = g[j];
                    beta[j] = 0.0;
                }
            }
        }
    }

    /// The scale of x for [`REACH`]: max(|x|, |q| / |H|), `norm` an estimate of |H|.
    fn scale(&self, x: &[f64], norm: f64) -> f64 {
        let n2 = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
        n2(x).max(n2(self.q) / norm)
    }

    /// The largest step a >= 0 with x - a p feasible.
    fn feasible_step(&self, x: &[f64], p: &[f64]) -> f64 {
        let mut a = f64::INFINITY;
        for j in 0..self.n_nonneg {
            if p[j] > 0.0 {
                a = a.min(x[j] / p[j]);
            }
        }
        for b in 0..self.n_balls() {
            let rg = self.ball(b);
            let r = self.radii[b];
            let (mut xp, mut pp, mut xx) = (0.0, 0.0, 0.0);
            for j in rg {
                xp += x[j] * p[j];
                pp += p[j] * p[j];
                xx += x[j] * x[j];
            }
            if pp > 0.0 {
                // |x - a p|^2 = r^2, the positive root.
                let disc = (xp * xp + pp * (r * r - xx)).max(0.0);
                a = a.min(((xp + disc.sqrt()) / pp).max(0.0));
            }
        }
        a
    }

    /// Relative natural-map residual, rho_j = 1/H_jj per scalar, the inverse mean
    /// diagonal per ball, scaled as err (crate::report::natural_map_error):
    /// |r| / max(|x|, |q+| / trace(H)), q+ with the negative parts of the
    /// nonnegative unknowns' q cut (gaps, not forces): the scale of err, so that a
    /// sub-problem does not stop early where err would not.
    pub fn residual(&self, x: &[f64], g: &[f64]) -> f64 {
        let (mut r2, mut x2, mut q2, mut tr) = (0.0, 0.0, 0.0, 0.0);
        let diag = |j: usize| self.diag(j);
        for j in 0..self.n_nonneg {
            let rho = if diag(j) > 0.0 { 1.0 / diag(j) } else { 0.0 };
            let y = (x[j] - rho * g[j]).max(0.0);
            r2 += (x[j] - y).powi(2);
            x2 += x[j] * x[j];
            // Force scale: a negative q_j is a gap, not a force.
            q2 += self.q[j].max(0.0).powi(2);
            tr += diag(j).max(0.0);
        }
        let mut y = [0.0; 2];
        for b in 0..self.n_balls() {
            let rg = self.ball(b);
            let tb: f64 = rg.clone().map(diag).sum();
            tr += tb.max(0.0);
            let rho = if tb > 0.0 {
                self.block as f64 / tb
            } else {
                0.0
            };
            for (s, j) in rg.clone().enumerate() {
                y[s] = x[j] - rho * g[j];
            }
            crate::friction::project_disk(&mut y[..self.block], self.radii[b]);
            for (s, j) in rg.enumerate() {
                r2 += (x[j] - y[s]).powi(2);
                x2 += x[j] * x[j];
                q2 += self.q[j].powi(2);
            }
        }
        if r2 == 0.0 {
            0.0
        } else {
            let load = if tr > 0.0 { q2.sqrt() / tr } else { 0.0 };
            r2.sqrt() / x2.sqrt().max(load)
        }
    }

    /// An upper estimate of |H|_2: power iteration, with a 10% margin, capped by
    /// the Gershgorin bound; on a matrix-free dual in single precision (30
    /// products: on the 3d-40x40x20 block's first shear step, where Newton
    /// fell back to MPRGP, they were 2 of its 10 seconds in double).
    fn norm_estimate(&self, v: &mut [f64], hv: &mut [f64]) -> f64 {
        let k = self.k;
        // Matrix-free: no entries for Gershgorin; the power iteration's margin alone.
        let gersh = match self.op {
            Some(_) => f64::INFINITY,
            None => (0..k)
                .map(|j| self.col(j).iter().map(|a| a.abs()).sum::<f64>())
                .fold(0.0, f64::max),
        };
        v.iter_mut()
            .enumerate()
            .for_each(|(j, x)| *x = 1.0 + (j % 7) as f64 * 0.1);
        let mut lam = 0.0;
        for _ in 0..30 {
            let nv = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if nv == 0.0 {
                break;
            }
            v.iter_mut().for_each(|x| *x /= nv);
            self.apply_rough(v, hv);
            lam = hv.iter().zip(v.iter()).map(|(a, b)| a * b).sum::<f64>();
            v.copy_from_slice(hv);
        }
        (1.1 * lam).min(gersh).max(f64::MIN_POSITIVE)
    }

    /// [`ConvexQp::solve_in`] with its own scratch (allocates 5 k values).
    #[cfg(test)]
    pub fn solve(&self, x: &mut [f64], tol: f64, max: usize) -> Result<usize, Unbounded> {
        self.solve_in(x, (tol, 0.0), max, &mut Scratch::new(self.k), &mut None)
    }

    /// Runs MPRGP from x (projected first) until the relative residual is at most
    /// `tol`, or (where `drop` > 0) at most `drop` times its value at the
    /// projected start, or for `max` iterations (matrix-vector products), at
    /// least one; `(tol, drop)` is the stop. Returns the iterations, or
    /// [`Unbounded`] when the quadratic has no minimiser.
    ///
    /// `scratch` holds at least k values per vector (no allocation here); `norm`
    /// caches the estimate of |H| (30 products): None is filled in, Some is used,
    /// so the caller resets it to None when H changes.
    pub fn solve_in(
        &self,
        x: &mut [f64],
        (tol, drop): (f64, f64),
        max: usize,
        scratch: &mut Scratch,
        norm: &mut Option<f64>,
    ) -> Result<usize, Unbounded> {
        let k = self.k;
        if k == 0 {
            return Ok(0);
        }
        let [g, p, hp, phi, beta] = scratch.vectors(k);
        let norm = *norm.get_or_insert_with(|| self.norm_estimate(p, hp));
        let alpha = 1.9 / norm;
        let gamma2 = 1.0;
        self.project(x);
        let gradient = |x: &[f64], g: &mut [f64]| {
            self.apply(x, g);
            g.iter_mut().zip(self.q).for_each(|(gi, qi)| *gi -= qi);
        };
        gradient(x, g);
        // The relative stop, on the residual at the projected start (no
        // product: g is the start's).
        let tol = if drop > 0.0 {
            tol.max(drop * self.residual(x, g))
        } else {
            tol
        };
        self.split_gradient(x, g, alpha, phi, beta);
        p.copy_from_slice(phi);
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        // At least one iteration, so that an outer loop around it cannot stall.
        for it in 0..max {
            if it > 0 && self.residual(x, g) <= tol {
                return Ok(it);
            }
            let (bb, pf) = (dot(beta, beta), dot(phi, phi));
            if bb <= gamma2 * pf {
                // Proportional: conjugate gradient step, or expansion.
                self.apply(p, hp);
                let (php, pp) = (dot(p, hp), dot(p, p));
                if pp == 0.0 {
                    // x is stationary: the residual test ends the loop.
                    continue;
                }
                let a_f = self.feasible_step(x, p);
                // CG's p descends (g . p = |phi|^2 > 0). Without curvature the
                // minimiser along p is the boundary, or there is none.
                let flat = php <= FLAT * norm * pp;
                if flat && a_f * pp.sqrt() > REACH * self.scale(x, norm) {
                    return Err(Unbounded { iterations: it + 1 });
                }
                let a_cg = if flat { f64::INFINITY } else { dot(g, p) / php };
                if a_cg <= a_f {
                    for j in 0..k {
                        x[j] -= a_cg * p[j];
                        g[j] -= a_cg * hp[j];
                    }
                    self.split_gradient(x, g, alpha, phi, beta);
                    let gamma = dot(phi, hp) / php;
                    for j in 0..k {
                        p[j] = phi[j] - gamma * p[j];
                    }
                } else {
                    // Expansion: to the boundary, then a projected free-gradient step.
                    for j in 0..k {
                        x[j] -= a_f * p[j];
                        g[j] -= a_f * hp[j];
                    }
                    self.split_gradient(x, g, alpha, phi, beta);
                    for j in 0..k {
                        x[j] -= alpha * phi[j];
                    }
                    self.project(x);
                    gradient(x, g);
                    self.split_gradient(x, g, alpha, phi, beta);
                    p.copy_from_slice(phi);
                }
            } else {
                // Proportioning: release active constraints along the chopped gradient.
                self.apply(beta, hp);
                let bhb = dot(beta, hp);
                // The exact line minimiser, cut at the boundary. An active disk
                // block moves along -beta on a chord that leaves the circle: there the
                // step is alpha, which is the projected gradient step (it lands on
                // the circle and descends since alpha < 2/|H|).
                let disk_moves = (0..self.n_balls()).any(|b| self.ball(b).any(|j| beta[j] != 0.0));
                let a = if disk_moves {
                    alpha
                } else {
                    let a_cg = if bhb > 0.0 { dot(g, beta) / bhb } else { alpha };
                    a_cg.min(self.feasible_step(x, beta))
                };
                for j in 0..k {
                    x[j] -= a * beta[j];
                }
                self.project(x);
                gradient(x, g);
                self.split_gradient(x, g, alpha, phi, beta);
                p.copy_from_slice(phi);
            }
        }
        Ok(max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    static SEQ: crate::threads::Threads = crate::threads::Threads::sequential();

    /// A small SPD matrix with off-diagonal coupling.
    fn spd(k: usize) -> Vec<f64> {
        let mut h = vec![0.0; k * k];
        for i in 0..k {
            h[i + i * k] = 4.0 + i as f64 * 0.1;
            if i + 1 < k {
                h[i + (i + 1) * k] = -1.0;
                h[i + 1 + i * k] = -1.0;
            }
        }
        h
    }

    #[test]
    fn mprgp_matches_the_kkt_conditions_of_a_bound_constrained_qp() {
        let k = 12;
        let h = spd(k);
        let q: Vec<f64> = (0..k)
            .map(|i| if i % 3 == 0 { -1.0 } else { 1.0 + i as f64 })
            .collect();
        let qp = ConvexQp {
            h: &h,
            ld: k,
            op: None,
            k,
            q: &q,
            n_nonneg: k,
            block: 1,
            radii: &[],
            threads: &SEQ,
        };
        let mut x = vec![0.0; k];
        let its = qp.solve(&mut x, 1e-14, 1000).expect("bounded");
        assert!(its < 100, "{its} iterations");
        // KKT: x >= 0, g >= 0, x g = 0.
        let mut g = vec![0.0; k];
        qp.apply(&x, &mut g);
        for j in 0..k {
            g[j] -= q[j];
            assert!(x[j] >= 0.0);
            assert!(g[j] >= -1e-12, "g[{j}] = {}", g[j]);
            assert!((x[j] * g[j]).abs() <= 1e-12);
        }
        assert!(x.contains(&0.0) && x.iter().any(|&v| v > 0.0));
    }

    #[test]
    fn mpgp_matches_the_kkt_conditions_with_disks() {
        let k = 10;
        let h = spd(k);
        let q: Vec<f64> = (0..k).map(|i| (i as f64 - 4.5) * 2.0).collect();
        // Two nonnegative unknowns, then four disks of radius 0.3.
        let radii = [0.3; 4];
        let qp = ConvexQp {
            h: &h,
            ld: k,
            op: None,
            k,
            q: &q,
            n_nonneg: 2,
            block: 2,
            radii: &radii,
            threads: &SEQ,
        };
        let mut x = vec![0.0; k];
        let its = qp.solve(&mut x, 1e-13, 2000).expect("bounded");
        assert!(its < 100, "{its} iterations");
        let mut g = vec![0.0; k];
        qp.apply(&x, &mut g);
        g.iter_mut().zip(&q).for_each(|(a, b)| *a -= b);
        // KKT, checked block by block without the solver's own projection. The
        // nonnegative unknowns: x >= 0, g >= 0, x g = 0.
        for j in 0..2 {
            assert!(x[j] >= 0.0 && g[j] >= -1e-11, "{j}: x {} g {}", x[j], g[j]);
            assert!((x[j] * g[j]).abs() <= 1e-11, "{j}: x {} g {}", x[j], g[j]);
        }
        // Each disk: |x_b| <= r; inside, g_b = 0; on the circle, g_b = -nu x_b
        // with nu >= 0 (g_b antiparallel to x_b).
        let mut on_circle = 0;
        for (b, &r) in radii.iter().enumerate() {
            let (x0, x1) = (x[2 + 2 * b], x[3 + 2 * b]);
            let (g0, g1) = (g[2 + 2 * b], g[3 + 2 * b]);
            let nx = x0.hypot(x1);
            assert!(nx <= r * (1.0 + 1e-14), "disk {b}: |x| = {nx} > {r}");
            if nx < r * (1.0 - 1e-9) {
                assert!(g0.hypot(g1) <= 1e-11, "disk {b} inside: g = ({g0}, {g1})");
            } else {
                on_circle += 1;
                assert!(
                    (x0 * g1 - x1 * g0).abs() <= 1e-11,
                    "disk {b}: g not along x"
                );
                assert!(x0 * g0 + x1 * g1 <= 1e-11, "disk {b}: g points outwards");
            }
        }
        assert!(on_circle > 0, "no disk constraint is active: a weak test");
    }

    /// H = [1 -1; -1 1] (singular, null vector z = (1, 1) >= 0) over x >= 0.
    fn singular_qp<'a>(h: &'a [f64], q: &'a [f64]) -> ConvexQp<'a> {
        ConvexQp {
            h,
            ld: 2,
            op: None,
            k: 2,
            q,
            n_nonneg: 2,
            block: 1,
            radii: &[],
            threads: &SEQ,
        }
    }

    #[test]
    fn an_unbounded_quadratic_is_detected_before_x_blows_up() {
        // q . z = 2 > 0: 1/2 x^T H x - q^T x -> -infinity along z (no x >= 0 is a
        // minimiser; for a contact dual: no u with N u <= g).
        let h = [1.0, -1.0, -1.0, 1.0];
        let q = [1.0, 1.0];
        let mut x = [0.0; 2];
        let run = singular_qp(&h, &q).solve(&mut x, 1e-14, 1000);
        assert!(run.is_err(), "{run:?}, x = {x:?}");
        assert!(x.iter().all(|v| v.abs() < 1e3), "x = {x:?}");
    }

    #[test]
    fn a_bounded_singular_quadratic_is_solved() {
        // q . z = 0: bounded; the minimisers are x1 - x2 = 1, x >= 0 (KKT: g = 0).
        let h = [1.0, -1.0, -1.0, 1.0];
        let q = [1.0, -1.0];
        let mut x = [0.0; 2];
        singular_qp(&h, &q)
            .solve(&mut x, 1e-14, 1000)
            .expect("bounded");
        assert!((x[0] - x[1] - 1.0).abs() < 1e-12, "x = {x:?}");
        assert!(x[0] >= 0.0 && x[1] >= 0.0);
    }
}
