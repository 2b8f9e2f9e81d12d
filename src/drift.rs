//! How far the contacts' diagonal blocks of A = B K^-1 B^T can have moved
//! since an earlier K (`K_ref`): the extreme eigenvalues of
//! M = K^-1 (K - K_ref), estimated by a few Lanczos steps on the pencil
//! (K - K_ref, K), each one solve with K's factor in single precision.
//!
//! With mu_min <= eig(M) <= mu_max (and mu_max < 1), K_ref = K^1/2 (I - M~)
//! K^1/2 lies between (1 - mu_max) K and (1 - mu_min) K, so every block, and
//! every trace of a block, of the new A lies between (1 - mu_max) and
//! (1 - mu_min) times the old one. rho_i = d / trace(A_ii) (docs/design.md
//! section 5) then moves by at most those factors, and the natural map's
//! residual, non-decreasing in rho and no more than linear in it, moves with
//! it: err on the new K is at most [`Drift::err_factor`] times err measured
//! with the old blocks.

use crate::factor::Factor;
use crate::sparse::Csc;

/// Lanczos steps at most (each one solve with K).
const MAX_STEPS: usize = 8;

/// Lanczos steps of the estimate of a small step from the last K whose
/// drift is known ([`step_drift`]).
const STEP_STEPS: usize = 2;

/// The factor a small step's widened bounds are multiplied by
/// ([`step_drift`]): early Lanczos steps can fall short of the spectrum's
/// ends (on a material update of a slab, the first step's widened bounds
/// [-0.09, 0.02] against [-0.18, 0.06] from the fourth, below), and the
/// composition with the known drift holds only for bounds that contain
/// the step's spectrum. A margin on that figure, not a derived one; the
/// step is small (within [`SMALL_STEP`] once multiplied), so the margin
/// costs little in err_factor.
const STEP_INFLATION: f64 = 4.0;

/// A step's inflated bounds at most this (each end), for it to be composed
/// with the known drift ([`Drift::then`]) instead of a full estimate.
pub(crate) const SMALL_STEP: f64 = 0.05;

/// A step from the last K is tried only where its relative change
/// |K - K_last|_F / |K_last|_F is at most this: a larger one would seldom
/// be small in the sense of [`SMALL_STEP`], and its solves would be lost.
const SMALL_CHANGE: f64 = 0.01;

/// Lanczos steps at least before the widened bounds are trusted: the
/// extreme Ritz values of the first steps lie well inside the spectrum, and
/// their residual bounds can miss its ends (on a material update of a slab,
/// the first step's [-0.09, 0.02] against [-0.18, 0.06] from the fourth).
const MIN_STEPS: usize = 4;

/// The estimate: bounds of the spectrum of K^-1 (K - K_ref), each extreme
/// Ritz value widened by its residual bound, and by a tenth of the Ritz
/// values' spread at least (a Ritz value lies inside the spectrum, so the
/// widening is what stands for the part of it the steps did not see).
#[derive(Copy, Clone, Debug, PartialEq)]
pub(crate) struct Drift {
    /// Lower bound of the eigenvalues, at most 0.
    pub(crate) mu_min: f64,
    /// Upper bound of the eigenvalues, at least 0.
    pub(crate) mu_max: f64,
    /// Solves with K the estimate took.
    pub(crate) solves: usize,
}

impl Drift {
    /// The factor by which err on the new K's blocks can exceed err on the
    /// old ones: max(1, 1 - mu_min) / min(1, 1 - mu_max) (the natural map's
    /// part by the smaller rho, err's scale |b+| / trace(A) by the larger
    /// trace); infinite when mu_max >= 1 (K - K_ref not bounded by K).
    pub(crate) fn err_factor(&self) -> f64 {
        let lo = 1.0 - self.mu_max;
        let hi = 1.0 - self.mu_min;
        if lo <= 0.0 || !lo.is_finite() || !hi.is_finite() {
            return f64::INFINITY;
        }
        hi.max(1.0) / lo.min(1.0)
    }

    /// The drift of K_next from K_ref, where `self` bounds that of K from
    /// K_ref and `step` that of K_next from K. In the order of symmetric
    /// matrices, `self` says (1 - mu_max) K <= K_ref <= (1 - mu_min) K
    /// and `step` (1 - mu_max') K_next <= K <= (1 - mu_min') K_next, so
    /// (1 - mu_max)(1 - mu_max') K_next <= K_ref <= (1 - mu_min)(1 -
    /// mu_min') K_next (each factor at least 0 where err_factor is finite).
    /// The solves are the step's.
    /// Unbounded where either is (an infinite err_factor).
    pub(crate) fn then(&self, step: &Drift) -> Drift {
        if !(self.err_factor().is_finite() && step.err_factor().is_finite()) {
            return unbounded(step.solves);
        }
        Drift {
            mu_min: 1.0 - (1.0 - self.mu_min) * (1.0 - step.mu_min),
            mu_max: 1.0 - (1.0 - self.mu_max) * (1.0 - step.mu_max),
            solves: step.solves,
        }
    }

    /// Whether both ends lie within [`SMALL_STEP`] of 0.
    pub(crate) fn is_small(&self) -> bool {
        -self.mu_min <= SMALL_STEP && self.mu_max <= SMALL_STEP
    }
}

/// The drift of `k` from the K last refactored, `last_values` (its
/// pattern's), where that change is small: None where its relative size
/// exceeds [`SMALL_CHANGE`]; else the estimate of [`drift`] after
/// [`STEP_STEPS`] Lanczos steps with its bounds multiplied by
/// [`STEP_INFLATION`] (an estimate of a small step, to be composed with
/// the known drift of the last K by [`Drift::then`], where
/// [`Drift::is_small`]).
pub(crate) fn step_drift(
    factor: &Factor,
    single: &[f32],
    k: &Csc,
    last_values: &[f64],
) -> Option<Drift> {
    let (mut change, mut size) = (0.0, 0.0);
    for (a, b) in k.values.iter().zip(last_values) {
        change += (a - b) * (a - b);
        size += b * b;
    }
    // (A NaN sum, from values at the edge of the doubles, is no small change.)
    let small = change <= SMALL_CHANGE * SMALL_CHANGE * size;
    if !small {
        return None;
    }
    let d = lanczos(
        factor,
        single,
        k,
        last_values,
        f64::INFINITY,
        (STEP_STEPS, STEP_STEPS),
    );
    Some(Drift {
        mu_min: STEP_INFLATION * d.mu_min,
        mu_max: STEP_INFLATION * d.mu_max,
        solves: d.solves,
    })
}

/// The drift of `k`'s blocks from those of the matrix with `k`'s pattern and
/// the values `ref_values` (`factor` holds k's factor). Stops early where the
/// Ritz values alone put [`Drift::err_factor`] beyond `give_up`, or from
/// [`MIN_STEPS`] on where the widened bounds put it within.
///
/// The solves run in single precision on `single` (k's factor's values,
/// [`Factor::single_values`]): half the memory traffic, and an error in K's
/// energy norm near 1e-7 cond(K)^(1/2) relative, which a spectrum estimate
/// of a few digits does not see below cond(K) = 1e8.
///
/// The result is an estimate, not a certified bound: the widened Ritz
/// values can miss an end of the spectrum that the steps did not reach.
pub(crate) fn drift(
    factor: &Factor,
    single: &[f32],
    k: &Csc,
    ref_values: &[f64],
    give_up: f64,
) -> Drift {
    lanczos(
        factor,
        single,
        k,
        ref_values,
        give_up,
        (MIN_STEPS, MAX_STEPS),
    )
}

/// [`drift`] with `(min_steps, max_steps)` Lanczos steps in place of
/// ([`MIN_STEPS`], [`MAX_STEPS`]).
fn lanczos(
    factor: &Factor,
    single: &[f32],
    k: &Csc,
    ref_values: &[f64],
    give_up: f64,
    (min_steps, max_steps): (usize, usize),
) -> Drift {
    let n = k.nrows;
    if k.values.iter().zip(ref_values).all(|(a, b)| a == b) {
        return Drift {
            mu_min: 0.0,
            mu_max: 0.0,
            solves: 0,
        };
    }
    // A fixed pseudo-random start (the same from run to run).
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut q: Vec<f64> = (0..n)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect();
    let mut kq = vec![0.0; n];
    // K is stored whole and symmetric: K^T q, the gathering product, is K q.
    k.mul_t_vec(&q, &mut kq);
    let norm = dot(&q, &kq).sqrt();
    if norm.is_nan() || norm <= 0.0 {
        return unbounded(0);
    }
    q.iter_mut().for_each(|x| *x /= norm);
    kq.iter_mut().for_each(|x| *x /= norm);
    // The basis and K times it, for full reorthogonalisation in K's inner
    // product (at most MAX_STEPS vectors).
    let mut basis: Vec<(Vec<f64>, Vec<f64>)> = Vec::with_capacity(MAX_STEPS + 1);
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    let (mut p, mut kp) = (vec![0.0; n], vec![0.0; n]);
    // On several threads the solves go by the elimination tree: faer's
    // single-column solve slowed down on two (a 3D slab's factor with 4.7e7
    // entries, single precision: 0.048 s against 0.038 s on one thread, the
    // tree's split 0.023 s; the same to rounding on one thread).
    let tree = match factor.threads().count() {
        1 => None,
        _ => {
            let all: Vec<usize> = (0..n).collect();
            crate::factor_tree::tree_solve::TreeSolve::of(factor, &all).map(|ts| {
                let scratch = ts.scratch::<f32>(n);
                (ts, scratch)
            })
        }
    };
    // Either the tree's split with its scratch, or faer's solve scratch.
    let mut solves =
        tree.ok_or_else(|| faer::dyn_stack::MemBuffer::new(factor.solve_scratch_single()));
    let mut rhs = vec![0.0f32; n];
    let mut last = Drift {
        mu_min: 0.0,
        mu_max: 0.0,
        solves: 0,
    };
    for step in 0..max_steps {
        mul_change(k, ref_values, &q, &mut p);
        alpha.push(dot(&q, &p));
        // K times the solve's result is (K - K_ref) q, up to the solve's
        // rounding: kept instead of a product with K.
        kp.copy_from_slice(&p);
        rhs.iter_mut().zip(&p).for_each(|(r, x)| *r = *x as f32);
        match &mut solves {
            Ok((ts, scratch)) => {
                ts.solve_single(factor, single, &mut rhs, scratch, factor.threads())
            }
            Err(mem) => factor.solve_single(
                single,
                faer::MatMut::from_column_major_slice_mut(&mut rhs, n, 1),
                faer::dyn_stack::MemStack::new(mem),
            ),
        }
        p.iter_mut().zip(&rhs).for_each(|(x, r)| *x = f64::from(*r));
        basis.push((std::mem::take(&mut q), std::mem::take(&mut kq)));
        for _ in 0..2 {
            for (qi, kqi) in &basis {
                let c = dot(kqi, &p);
                p.iter_mut().zip(qi).for_each(|(x, y)| *x -= c * y);
                kp.iter_mut().zip(kqi).for_each(|(x, y)| *x -= c * y);
            }
        }
        let mut b = dot(&p, &kp).max(0.0).sqrt();
        let scale = alpha.iter().fold(0.0_f64, |s, a| s.max(a.abs()));
        let tiny = 1e-5 * scale.max(f64::MIN_POSITIVE);
        if b <= tiny {
            // The kept K p carries the solve's rounding K e, which can
            // cancel p^T K p on an ill-conditioned K: a product with K
            // confirms the end before the widening is dropped.
            k.mul_vec(&p, &mut kp);
            b = dot(&p, &kp).max(0.0).sqrt();
        }
        if !b.is_finite() || alpha.iter().any(|a| !a.is_finite()) {
            return unbounded(step + 1);
        }
        // An invariant subspace: the Ritz values are eigenvalues (up to the
        // single-precision solves' rounding).
        let exhausted = b <= tiny;
        let (theta, last_row) = tridiagonal_eigen(&alpha, &beta);
        // Each end widened by its residual bound, and by a tenth of the
        // Ritz values' spread at least: the residual only says that some
        // eigenvalue lies that near, and four steps can stop short of the
        // ends (a chain with scattered 3 % changes and stiff spikes: [-0.041,
        // 0.261] against the exact [-0.029, 0.276]).
        let spread = 0.1 * (theta[theta.len() - 1] - theta[0]);
        let res = |j: usize| {
            if exhausted {
                0.0
            } else {
                (b * last_row[j].abs()).max(spread)
            }
        };
        let (lo, hi) = (0, theta.len() - 1);
        last = Drift {
            mu_min: (theta[lo] - res(lo)).min(0.0),
            mu_max: (theta[hi] + res(hi)).max(0.0),
            solves: step + 1,
        };
        // Ritz values lie inside the spectrum: beyond give_up for certain.
        let inner = Drift {
            mu_min: theta[lo].min(0.0),
            mu_max: theta[hi].max(0.0),
            solves: step + 1,
        };
        let settled = step + 1 >= min_steps && last.err_factor() <= give_up;
        if exhausted || settled || inner.err_factor() > give_up {
            return last;
        }
        beta.push(b);
        p.iter_mut().for_each(|x| *x /= b);
        kp.iter_mut().for_each(|x| *x /= b);
        q = std::mem::replace(&mut p, vec![0.0; n]);
        kq = std::mem::replace(&mut kp, vec![0.0; n]);
    }
    last
}

/// Bytes [`drift`] works in for K of order `n`: the basis and K times it,
/// and four more n-vectors (the change of K is applied from the two sets
/// of values, not stored).
pub(crate) fn work_bytes(n: usize) -> usize {
    (2 * (MAX_STEPS + 1) + 4) * n * std::mem::size_of::<f64>()
}

/// A drift nothing can be said of (a non-finite value on the way).
fn unbounded(solves: usize) -> Drift {
    Drift {
        mu_min: f64::NEG_INFINITY,
        mu_max: f64::INFINITY,
        solves,
    }
}

/// y := (K - K_ref)^T x, K = `k` and K_ref the matrix of its pattern with
/// the values `ref_values`: (K - K_ref) x, both being stored whole and
/// symmetric. Column by column, each entry of y one sum (a gather: no
/// scattered updates of y, and no copy of the differences).
fn mul_change(k: &Csc, ref_values: &[f64], x: &[f64], y: &mut [f64]) {
    for (cols, yj) in k.col_ptr.windows(2).zip(y.iter_mut()) {
        let range = cols[0]..cols[1];
        *yj = k.row_idx[range.clone()]
            .iter()
            .zip(&k.values[range.clone()])
            .zip(&ref_values[range])
            .map(|((&r, &a), &b)| (a - b) * x[r])
            .sum();
    }
}

fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

/// Eigenvalues (ascending) of the symmetric tridiagonal matrix with diagonal
/// `alpha` (k) and off-diagonal `beta` (k - 1), and the last component of
/// each eigenvector, by cyclic Jacobi rotations (k is at most a few tens).
fn tridiagonal_eigen(alpha: &[f64], beta: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let k = alpha.len();
    let mut a = vec![0.0; k * k];
    let mut v = vec![0.0; k * k];
    for i in 0..k {
        a[i * k + i] = alpha[i];
        v[i * k + i] = 1.0;
    }
    for (i, &b) in beta.iter().enumerate() {
        a[i * k + i + 1] = b;
        a[(i + 1) * k + i] = b;
    }
    for _sweep in 0..50 {
        let off: f64 = (0..k)
            .flat_map(|i| (0..k).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i * k + j] * a[i * k + j])
            .sum();
        let diag: f64 = (0..k).map(|i| a[i * k + i] * a[i * k + i]).sum();
        if off <= 1e-30 * diag.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..k {
            for q in p + 1..k {
                let apq = a[p * k + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q * k + q] - a[p * k + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for r in 0..k {
                    let (arp, arq) = (a[r * k + p], a[r * k + q]);
                    a[r * k + p] = c * arp - s * arq;
                    a[r * k + q] = s * arp + c * arq;
                }
                for r in 0..k {
                    let (apr, aqr) = (a[p * k + r], a[q * k + r]);
                    a[p * k + r] = c * apr - s * aqr;
                    a[q * k + r] = s * apr + c * aqr;
                }
                for r in 0..k {
                    let (vrp, vrq) = (v[r * k + p], v[r * k + q]);
                    v[r * k + p] = c * vrp - s * vrq;
                    v[r * k + q] = s * vrp + c * vrq;
                }
            }
        }
    }
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&i, &j| a[i * k + i].total_cmp(&a[j * k + j]));
    let theta = order.iter().map(|&j| a[j * k + j]).collect();
    let last_row = order.iter().map(|&j| v[(k - 1) * k + j]).collect();
    (theta, last_row)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1D Laplacian of order n (Dirichlet ends), scaled by `s`, with the
    /// entries of `zone` (rows and columns) scaled by another `z`.
    fn laplacian(n: usize, s: f64, zone: std::ops::Range<usize>, z: f64) -> Csc {
        let mut t = Vec::new();
        for i in 0..n {
            let w = |j: usize| {
                if zone.contains(&i) && zone.contains(&j) {
                    z
                } else {
                    1.0
                }
            };
            t.push((i, i, 2.0 * s * w(i)));
            if i + 1 < n {
                t.push((i, i + 1, -s * w(i + 1)));
                t.push((i + 1, i, -s * w(i + 1)));
            }
        }
        Csc::from_triplets(n, n, &t)
    }

    #[test]
    fn jacobi_finds_the_eigenvalues_of_a_known_tridiagonal() {
        // diag 2, off-diagonal -1, order 5: 2 - 2 cos(j pi / 6).
        let (theta, last) = tridiagonal_eigen(&[2.0; 5], &[-1.0; 4]);
        for (j, t) in theta.iter().enumerate() {
            let want = 2.0 - 2.0 * ((j + 1) as f64 * std::f64::consts::PI / 6.0).cos();
            assert!((t - want).abs() < 1e-12, "{j}: {t} against {want}");
        }
        // Eigenvector j's last component: sqrt(2/6) sin(5 (j+1) pi / 6), up to sign.
        for (j, l) in last.iter().enumerate() {
            let want =
                (2.0_f64 / 6.0).sqrt() * (5.0 * (j + 1) as f64 * std::f64::consts::PI / 6.0).sin();
            assert!(
                (l.abs() - want.abs()).abs() < 1e-12,
                "{j}: {l} against {want}"
            );
        }
    }

    #[test]
    fn a_scaled_k_drifts_by_its_scale_exactly() {
        // K_ref = 1.2 K: M = K^-1 (K - 1.2 K) = -0.2 I, one step.
        let k = laplacian(40, 1.0, 0..0, 1.0);
        let k_ref = laplacian(40, 1.2, 0..0, 1.0);
        let f = Factor::new(&k).unwrap();
        let single = f.single_values().unwrap();
        let d = drift(&f, &single, &k, &k_ref.values, 10.0);
        assert_eq!(d.solves, 1);
        assert!((d.mu_min + 0.2).abs() < 1e-6 && d.mu_max == 0.0, "{d:?}");
        assert!((d.err_factor() - 1.2).abs() < 1e-6);
        // The same K: no solve, factor 1.
        let d = drift(&f, &single, &k, &k.values, 10.0);
        assert_eq!((d.solves, d.err_factor()), (0, 1.0));
    }

    #[test]
    fn a_zone_made_stiffer_is_bounded_by_the_dense_spectrum() {
        // K's zone entries scaled by 1.1, its couplings out of the zone not
        // (so the zone's ends gain springs to ground); the exact spectrum of
        // K^-1 (K - K_ref)
        // from the dense symmetric K^-1/2 (K - K_ref) K^-1/2: the estimate
        // (four steps, as a refactor takes) must contain it and not lie far
        // beyond.
        let n = 60;
        let k = laplacian(n, 1.0, 20..35, 1.1);
        let k_ref = laplacian(n, 1.0, 0..0, 1.0);
        let f = Factor::new(&k).unwrap();
        let single = f.single_values().unwrap();
        let d = drift(&f, &single, &k, &k_ref.values, 10.0);
        assert_contains(&d, exact_spectrum(&k, &k_ref), 0.02);
        assert!(d.solves <= MAX_STEPS);
        // Beyond a bound of 1.5 (mu_max = 0.7: a factor 3.3),
        // it gives up as soon as the Ritz values alone say so.
        let early = drift(&f, &single, &k, &k_ref.values, 1.5);
        assert!(
            early.err_factor() > 1.5 && early.solves < d.solves,
            "{early:?}"
        );
    }

    /// A chain of springs (ground springs at its ends) whose elements change
    /// by up to 3 % here and there, three of them by 40 %: the four steps'
    /// estimate contains the exact spectrum.
    #[test]
    fn scattered_changes_are_contained() {
        let n = 80;
        let chain = |w: &dyn Fn(usize) -> f64| {
            let mut t = vec![(0, 0, 1.0), (n - 1, n - 1, 1.0)];
            for e in 0..n - 1 {
                let k = w(e);
                t.extend([(e, e, k), (e + 1, e + 1, k), (e, e + 1, -k), (e + 1, e, -k)]);
            }
            Csc::from_triplets(n, n, &t)
        };
        let k_ref = chain(&|_| 1.0);
        let k = chain(&|e| match e {
            11 | 40 | 67 => 1.4,
            e => 1.0 + 0.03 * ((e * 7919 % 13) as f64 / 6.0 - 1.0),
        });
        let f = Factor::new(&k).unwrap();
        let single = f.single_values().unwrap();
        let d = drift(&f, &single, &k, &k_ref.values, 1.5);
        assert_contains(&d, exact_spectrum(&k, &k_ref), f64::INFINITY);
    }

    /// Scalings compose exactly: K1 = 1.25 K0 drifts by 1 - 1 / 1.25 =
    /// 0.2 from K0, K2 = 1.004 K1 by 1 - 1 / 1.004 from K1, and the
    /// composition is K2's drift from K0, 1 - 1 / (1.25 * 1.004) (the
    /// bounds' other end is 0: a bound is never on the inner side of 0);
    /// the step is small and estimated in STEP_STEPS solves, exact but for
    /// the inflation.
    #[test]
    fn composed_scalings_give_the_drift_of_the_product() {
        let k0 = laplacian(40, 1.0, 0..0, 1.0);
        let k1 = laplacian(40, 1.25, 0..0, 1.0);
        let k2 = laplacian(40, 1.25 * 1.004, 0..0, 1.0);
        let f1 = Factor::new(&k1).unwrap();
        let d1 = drift(&f1, &f1.single_values().unwrap(), &k1, &k0.values, 10.0);
        assert!(d1.mu_min == 0.0 && (d1.mu_max - 0.2).abs() < 1e-6, "{d1:?}");
        let f2 = Factor::new(&k2).unwrap();
        let step = step_drift(&f2, &f2.single_values().unwrap(), &k2, &k1.values).unwrap();
        assert!(step.is_small() && step.solves <= STEP_STEPS, "{step:?}");
        let one = 1.0 - 1.0 / 1.004;
        assert!(
            step.mu_min == 0.0 && (step.mu_max - STEP_INFLATION * one).abs() < 1e-6,
            "{step:?}"
        );
        // Exact bounds compose to the exact drift of K2 from K0.
        let exact_step = Drift {
            mu_min: 0.0,
            mu_max: one,
            solves: 1,
        };
        let both = d1.then(&exact_step);
        let want = 1.0 - 1.0 / (1.25 * 1.004);
        assert!(
            both.mu_min == 0.0 && (both.mu_max - want).abs() < 1e-6,
            "{both:?}"
        );
        assert_eq!(both.solves, 1);
        // A change of 2 % is not tried as a step.
        let k3 = laplacian(40, 1.25 * 1.02, 0..0, 1.0);
        let f3 = Factor::new(&k3).unwrap();
        assert!(step_drift(&f3, &f3.single_values().unwrap(), &k3, &k1.values).is_none());
    }

    /// `k` with the entries whose row and column both lie in `zone` scaled
    /// by `f` (the same pattern).
    fn scale_zone(k: &Csc, zone: std::ops::Range<usize>, f: f64) -> Csc {
        let mut out = k.clone();
        for j in 0..k.ncols {
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                if zone.contains(&j) && zone.contains(&k.row_idx[p]) {
                    out.values[p] *= f;
                }
            }
        }
        out
    }

    /// A zone made stiffer by 10 %, then that zone by 0.3 % more and
    /// another softened by 0.3 % (a step of both signs): the two-step
    /// estimate of the step contains the step's exact spectrum, and
    /// composed with the full estimate of the first it contains the exact
    /// spectrum of the last K's drift from the first, within a few
    /// hundredths of it.
    #[test]
    fn a_small_step_composed_with_the_known_drift_contains_the_spectrum() {
        let n = 60;
        let k_ref = laplacian(n, 1.0, 0..0, 1.0);
        let k1 = laplacian(n, 1.0, 20..35, 1.1);
        let k2 = scale_zone(&scale_zone(&k1, 20..35, 1.003), 40..50, 0.997);
        let f1 = Factor::new(&k1).unwrap();
        let d1 = drift(&f1, &f1.single_values().unwrap(), &k1, &k_ref.values, 10.0);
        let f2 = Factor::new(&k2).unwrap();
        let step = step_drift(&f2, &f2.single_values().unwrap(), &k2, &k1.values).unwrap();
        assert!(step.is_small() && step.solves <= STEP_STEPS, "{step:?}");
        let (slo, shi) = exact_spectrum(&k2, &k1);
        assert!(
            slo < -1e-4 && shi > 1e-4,
            "a step of both signs: {slo} {shi}"
        );
        assert!(
            step.mu_min <= slo && step.mu_max >= shi,
            "{step:?} {slo} {shi}"
        );
        let both = d1.then(&step);
        assert_contains(&both, exact_spectrum(&k2, &k_ref), 0.05);
    }

    /// Bounds beyond 1 compose to none: K - K_ref not bounded by K.
    #[test]
    fn an_unbounded_drift_composes_to_an_unbounded_one() {
        let wild = Drift {
            mu_min: -0.1,
            mu_max: 1.6,
            solves: 4,
        };
        let step = Drift {
            mu_min: 0.0,
            mu_max: 1.6,
            solves: 2,
        };
        assert!(wild.then(&step).err_factor().is_infinite());
        let fine = Drift {
            mu_min: -0.1,
            mu_max: 0.1,
            solves: 4,
        };
        assert!(fine.then(&step).err_factor().is_infinite());
        assert!(wild.then(&fine).err_factor().is_infinite());
    }

    /// `d` contains [lo, hi] (to the single-precision solves' rounding,
    /// 1e-6) and lies no further than `beyond` outside it.
    fn assert_contains(d: &Drift, (lo, hi): (f64, f64), beyond: f64) {
        assert!(
            d.mu_min <= lo + 1e-6 && d.mu_max >= hi - 1e-6,
            "{d:?} {lo} {hi}"
        );
        assert!(
            d.mu_max <= hi + beyond && d.mu_min >= lo - beyond,
            "{d:?} {lo} {hi}"
        );
    }

    /// The extreme eigenvalues of K^-1 (K - K_ref), from the dense matrix
    /// C = K^-1/2 (K - K_ref) K^-1/2 (K^-1/2 by K's own eigenvectors).
    fn exact_spectrum(k: &Csc, k_ref: &Csc) -> (f64, f64) {
        let n = k.nrows;
        let dense = |a: &Csc| {
            let mut m = faer::Mat::<f64>::zeros(n, n);
            for j in 0..n {
                for p in a.col_ptr[j]..a.col_ptr[j + 1] {
                    m[(a.row_idx[p], j)] = a.values[p];
                }
            }
            m
        };
        let (kd, rd) = (dense(k), dense(k_ref));
        let eig = kd.self_adjoint_eigen(faer::Side::Lower).unwrap();
        let (u, s) = (eig.U(), eig.S());
        let mut half = faer::Mat::<f64>::zeros(n, n);
        for j in 0..n {
            let w = 1.0 / s[j].sqrt();
            for i in 0..n {
                half[(i, j)] = u[(i, j)] * w;
            }
        }
        let c = half.transpose() * (&kd - &rd) * &half;
        let ev = c.self_adjoint_eigen(faer::Side::Lower).unwrap();
        let s = ev.S();
        let vals: Vec<f64> = (0..n).map(|i| s[i]).collect();
        (
            vals.iter().cloned().fold(f64::INFINITY, f64::min),
            vals.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
        )
    }
}
