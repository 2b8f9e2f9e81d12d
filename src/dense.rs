//! Dense factorisations with an explicit parallelism (faer's low-level calls), so
//! that they run on the problem's threads and never on rayon's global pool.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt;
use faer::linalg::lu::partial_pivoting as lu;
use faer::linalg::svd::{self, ComputeSvdVectors};
use faer::{Conj, Mat, MatRef, Par};

/// X = M^-1 R by Cholesky of the symmetric positive definite M (its lower triangle
/// is read); None when M is not numerically positive definite.
pub(crate) fn llt_solve(m: MatRef<'_, f64>, r: MatRef<'_, f64>, par: Par) -> Option<Mat<f64>> {
    let n = m.nrows();
    let mut l = m.to_owned();
    let mut mem = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
        n,
        par,
        Default::default(),
    ));
    llt::factor::cholesky_in_place(
        l.as_mut(),
        Default::default(),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()?;
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

    #[test]
    fn thin_svd_reconstructs_the_matrix() {
        let (m, _, _) = case();
        let (u, s, v) = thin_svd(m.as_ref(), Par::Seq).unwrap();
        let us = Mat::from_fn(3, 3, |i, j| u[(i, j)] * s[j]);
        let back = &us * v.transpose();
        assert!(max_diff(&back, &m) < 1e-14);
    }
}
