//! Dense factorisations with an explicit parallelism (faer's low-level calls), so
//! that they run on the problem's threads and never on rayon's global pool.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::linalg::lu::partial_pivoting as lu;
use faer::linalg::svd::{self, ComputeSvdVectors};
use faer::{Conj, Mat, MatRef, Par};

/// L L^T = M in place (M's lower triangle read, L written there), in double
/// or single precision; None when M is not numerically positive definite.
fn cholesky_in_place<T: faer::traits::ComplexField>(
    l: faer::MatMut<'_, T>,
    par: Par,
) -> Option<()> {
    let mut mem = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<T>(
        l.nrows(),
        par,
        Default::default(),
    ));
    llt::factor::cholesky_in_place(
        l,
        Default::default(),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()
    .map(|_| ())
}

/// X = M^-1 R by Cholesky of the symmetric positive definite M (its lower triangle
/// is read); None when M is not numerically positive definite.
pub(crate) fn llt_solve(m: MatRef<'_, f64>, r: MatRef<'_, f64>, par: Par) -> Option<Mat<f64>> {
    let n = m.nrows();
    let mut l = m.to_owned();
    cholesky_in_place(l.as_mut(), par)?;
    let mut x = r.to_owned();
    let mut mem = MemBuffer::new(llt::solve::solve_in_place_scratch::<f64>(n, r.ncols(), par));
    llt::solve::solve_in_place_with_conj(
        l.as_ref(),
        Conj::No,
        x.as_mut(),
        par,
        MemStack::new(&mut mem),
    );
    Some(x)
}

/// Rounds of iterative refinement [`llt_solve_mixed`] takes at most.
const REFINE_ROUNDS: usize = 6;

/// x = M^-1 r (one right-hand side) by Cholesky of M rounded to single
/// precision (half the flops' time and memory of double) and iterative
/// refinement with residuals in double precision: each round solves for the
/// correction with the single-precision factor. Returns x once its residual
/// is at most `rtol` (|r - M x|_inf <= rtol (|M|_max |x|_inf + |r|_inf)); None
/// when M is not positive definite in single precision or the refinement
/// stalls (M too ill-conditioned for it: each round must halve the residual),
/// for the caller to solve in double. M's lower triangle is read.
pub(crate) fn llt_solve_mixed(
    m: MatRef<'_, f64>,
    r: &[f64],
    rtol: f64,
    par: Par,
) -> Option<Vec<f64>> {
    let n = m.nrows();
    let mut l = Mat::<f32>::from_fn(n, n, |i, j| if i >= j { m[(i, j)] as f32 } else { 0.0 });
    cholesky_in_place(l.as_mut(), par)?;
    let mut solve_mem = MemBuffer::new(llt::solve::solve_in_place_scratch::<f32>(n, 1, par));
    let mut corr = Mat::<f32>::zeros(n, 1);
    let mut x = vec![0.0; n];
    let mut res = r.to_vec();
    let m_max = (0..n)
        .flat_map(|j| (j..n).map(move |i| (i, j)))
        .fold(0.0f64, |a, (i, j)| a.max(m[(i, j)].abs()));
    let r_max = r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let mut last = f64::INFINITY;
    for _ in 0..REFINE_ROUNDS {
        for (c, &v) in corr.col_mut(0).iter_mut().zip(&res) {
            *c = v as f32;
        }
        llt::solve::solve_in_place_with_conj(
            l.as_ref(),
            Conj::No,
            corr.as_mut(),
            par,
            MemStack::new(&mut solve_mem),
        );
        for (xi, &c) in x.iter_mut().zip(corr.col(0).iter()) {
            *xi += f64::from(c);
        }
        // res = r - M x, with M's lower triangle (symmetric).
        let mx = symmetric_times(m, &x, par);
        for ((ri, &rv), mv) in res.iter_mut().zip(r).zip(&mx) {
            *ri = rv - mv;
        }
        let now = res.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let x_max = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        if !now.is_finite() || !x_max.is_finite() {
            return None;
        }
        if now <= rtol * (m_max * x_max + r_max) {
            return Some(x);
        }
        if now > 0.5 * last {
            return None;
        }
        last = now;
    }
    None
}

/// M x for the symmetric M whose lower triangle is given.
fn symmetric_times(m: MatRef<'_, f64>, x: &[f64], par: Par) -> Vec<f64> {
    let n = m.nrows();
    let mut y = Mat::<f64>::zeros(n, 1);
    let xm = MatRef::from_column_major_slice(x, n, 1);
    faer::linalg::matmul::triangular::matmul(
        y.as_mut(),
        faer::linalg::matmul::triangular::BlockStructure::Rectangular,
        faer::Accum::Replace,
        m,
        faer::linalg::matmul::triangular::BlockStructure::TriangularLower,
        xm,
        faer::linalg::matmul::triangular::BlockStructure::Rectangular,
        1.0,
        par,
    );
    faer::linalg::matmul::triangular::matmul(
        y.as_mut(),
        faer::linalg::matmul::triangular::BlockStructure::Rectangular,
        faer::Accum::Add,
        m.transpose(),
        faer::linalg::matmul::triangular::BlockStructure::StrictTriangularUpper,
        xm,
        faer::linalg::matmul::triangular::BlockStructure::Rectangular,
        1.0,
        par,
    );
    y.col(0).iter().copied().collect()
}

/// X = M^-1 R by LU with partial pivoting of the square M (the result may be
/// infinite or NaN when M is singular).
pub(crate) fn lu_solve(m: MatRef<'_, f64>, r: MatRef<'_, f64>, par: Par) -> Mat<f64> {
    let n = m.nrows();
    let mut a = m.to_owned();
    let (mut perm, mut perm_inv) = (vec![0usize; n], vec![0usize; n]);
    let mut mem = MemBuffer::new(
        lu::factor::lu_in_place_scratch::<usize, f64>(n, n, par, Default::default()).or(
            lu::solve::solve_in_place_scratch::<usize, f64>(n, r.ncols(), par),
        ),
    );
    let (_, p) = lu::factor::lu_in_place(
        a.as_mut(),
        &mut perm,
        &mut perm_inv,
        par,
        MemStack::new(&mut mem),
        Default::default(),
    );
    let mut x = r.to_owned();
    lu::solve::solve_in_place(
        a.as_ref(),
        a.as_ref(),
        p,
        x.as_mut(),
        par,
        MemStack::new(&mut mem),
    );
    x
}

/// The thin SVD M = U diag(s) V^T of the square M: (U, s, V); None when it does
/// not converge.
pub(crate) fn thin_svd(m: MatRef<'_, f64>, par: Par) -> Option<(Mat<f64>, Vec<f64>, Mat<f64>)> {
    let n = m.nrows();
    let (mut u, mut v) = (Mat::<f64>::zeros(n, n), Mat::<f64>::zeros(n, n));
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let mut mem = MemBuffer::new(svd::svd_scratch::<f64>(
        n,
        n,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::Thin,
        par,
        Default::default(),
    ));
    svd::svd(
        m,
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()?;
    let s = (0..n).map(|i| s[i]).collect();
    Some((u, s, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 x 3 SPD matrix and a right-hand side with a known solution.
    fn case() -> (Mat<f64>, Mat<f64>, Mat<f64>) {
        let m = faer::mat![[4.0, 1.0, 0.5], [1.0, 3.0, 0.25], [0.5, 0.25, 2.0]];
        let x = faer::mat![[1.0, -2.0], [0.5, 3.0], [-1.0, 0.25]];
        let r = &m * &x;
        (m, r, x)
    }

    fn max_diff(a: &Mat<f64>, b: &Mat<f64>) -> f64 {
        let mut d = 0.0f64;
        for j in 0..a.ncols() {
            for i in 0..a.nrows() {
                d = d.max((a[(i, j)] - b[(i, j)]).abs());
            }
        }
        d
    }

    #[test]
    fn llt_and_lu_solve_a_known_system() {
        let (m, r, x) = case();
        let y = llt_solve(m.as_ref(), r.as_ref(), Par::Seq).unwrap();
        assert!(max_diff(&y, &x) < 1e-14);
        let y = lu_solve(m.as_ref(), r.as_ref(), Par::Seq);
        assert!(max_diff(&y, &x) < 1e-14);
        // Not positive definite: no Cholesky.
        let neg = faer::mat![[1.0, 2.0], [2.0, 1.0]];
        assert!(llt_solve(neg.as_ref(), neg.as_ref(), Par::Seq).is_none());
    }

    /// An SPD matrix of order n with eigenvalues from 1 to `cond` (Q D Q^T,
    /// Q a product of Householder reflections), and b = M x for a known x.
    fn spd(n: usize, cond: f64) -> (Mat<f64>, Vec<f64>, Vec<f64>) {
        let v: Vec<f64> = (0..n).map(|i| (i as f64 * 0.61).sin() + 0.3).collect();
        let vv: f64 = v.iter().map(|a| a * a).sum();
        let q = Mat::from_fn(n, n, |i, j| {
            f64::from(u8::from(i == j)) - 2.0 * v[i] * v[j] / vv
        });
        let d = Mat::from_fn(n, n, |i, j| {
            if i == j {
                cond.powf(i as f64 / (n - 1) as f64)
            } else {
                0.0
            }
        });
        let m = &q * &d * q.transpose();
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        let xm = Mat::from_fn(n, 1, |i, _| x[i]);
        let b = &m * &xm;
        (m, b.col(0).iter().copied().collect(), x)
    }

    /// The mixed-precision Cholesky meets its residual bound on a moderately
    /// conditioned matrix (and so agrees with the known solution to about
    /// cond eps), and gives up, for the caller's double-precision solve, where
    /// single precision cannot factor the matrix or the refinement stalls.
    #[test]
    fn mixed_cholesky_refines_to_double_or_gives_up() {
        let n = 300;
        let (m, b, x) = spd(n, 1e4);
        let rtol = 1e-15;
        let y = llt_solve_mixed(m.as_ref(), &b, rtol, Par::Seq).expect("refines");
        let mx = symmetric_times(m.as_ref(), &y, Par::Seq);
        let res = mx
            .iter()
            .zip(&b)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        let m_max = (0..n).fold(0.0f64, |a, i| (0..n).fold(a, |a, j| a.max(m[(i, j)].abs())));
        let norm = |v: &[f64]| v.iter().fold(0.0f64, |a, e| a.max(e.abs()));
        assert!(res <= rtol * (m_max * norm(&y) + norm(&b)), "{res}");
        let err = y
            .iter()
            .zip(&x)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        assert!(err <= 1e-10, "{err}");
        // cond 1e12: beyond single precision (1 / eps_32 ~ 1.7e7).
        let (m, b, _) = spd(n, 1e12);
        assert!(llt_solve_mixed(m.as_ref(), &b, rtol, Par::Seq).is_none());
        // Indefinite: no Cholesky.
        let neg = faer::mat![[1.0, 2.0], [2.0, 1.0]];
        assert!(llt_solve_mixed(neg.as_ref(), &[1.0, 1.0], rtol, Par::Seq).is_none());
    }

    #[test]
    fn thin_svd_reconstructs_the_matrix() {
        let (m, _, _) = case();
        let (u, s, v) = thin_svd(m.as_ref(), Par::Seq).unwrap();
        let us = Mat::from_fn(3, 3, |i, j| u[(i, j)] * s[j]);
        let back = &us * v.transpose();
        assert!(max_diff(&back, &m) < 1e-14);
    }
}
