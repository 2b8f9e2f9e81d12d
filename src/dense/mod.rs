//! Dense factorisations with an explicit parallelism (faer's low-level calls), so
//! that they run on the problem's threads and never on rayon's global pool.
//!
//! Their dense copies and work space are allocated fallibly: where the
//! allocator refuses one, the call answers None (as for a matrix that is not
//! positive definite) and the caller takes its fallback.

use crate::memory::{try_mat, try_scratch};
pub(crate) use inverse::{Complement, InverseF32, Unknown};
use kept::Bordered;

mod inverse;
mod kept;
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
    let req = llt::factor::cholesky_in_place_scratch::<T>(l.nrows(), par, Default::default());
    let mut mem = try_scratch(req, "").ok()?;
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
    let mut l = copy(m)?;
    cholesky_in_place(l.as_mut(), par)?;
    let mut x = r.to_owned();
    let req = llt::solve::solve_in_place_scratch::<f64>(n, r.ncols(), par);
    let mut mem = try_scratch(req, "").ok()?;
    llt::solve::solve_in_place_with_conj(
        l.as_ref(),
        Conj::No,
        x.as_mut(),
        par,
        MemStack::new(&mut mem),
    );
    Some(x)
}

/// A copy of m, or None where the allocator refuses it.
fn copy(m: MatRef<'_, f64>) -> Option<Mat<f64>> {
    let mut a = try_mat::<f64>(m.nrows(), m.ncols(), "").ok()?;
    a.copy_from(m);
    Some(a)
}

/// The single-precision factor of the last dense reduced system, with the
/// unknowns it was formed on (`key`: each unknown's first test index and
/// kind), held for the next Newton step, on the dual
/// (`Dual::with_kept_factor`) so that the next solve's first step finds it
/// too: where that step has the same unknowns, or a few more or fewer (see
/// `Reused::positions` in the Newton method), its matrix differs in a few
/// directions (the slipping contacts' turned directions and the curvature
/// terms), and CG ([`pcg`]) or GMRES ([`gmres`]) preconditioned by this
/// factor, bordered for the unknowns that came and went (`dense::kept`),
/// solves it in a few iterations.
pub(crate) struct Reused {
    pub(crate) key: Vec<usize>,
    pub(crate) llt: LltF32,
    pub(crate) _claim: crate::memory::Claim,
}

/// Rounds of iterative refinement [`refine`] takes at most.
const REFINE_ROUNDS: usize = 6;

/// The Cholesky factor L L^T of a symmetric positive definite M rounded to
/// single precision (half the flops' time and memory of double): the
/// preconditioner of [`refine`], [`pcg`] and [`gmres`] (there of a symmetric
/// matrix near the non-symmetric one solved).
pub(crate) struct LltF32 {
    l: Mat<f32>,
}

impl LltF32 {
    /// The factor of M (its lower triangle read); None when M is not positive
    /// definite in single precision.
    pub fn of(m: MatRef<'_, f64>, par: Par) -> Option<LltF32> {
        Self::of_entries(m.nrows(), |i, j| m[(i, j)], par)
    }

    /// The factor of the symmetric M of order n whose lower entries
    /// `entry(i, j)` (i >= j) gives; None when M is not positive definite in
    /// single precision or the factor cannot be allocated.
    pub fn of_entries(n: usize, entry: impl Fn(usize, usize) -> f64, par: Par) -> Option<LltF32> {
        let mut l = try_mat::<f32>(n, n, "").ok()?;
        for j in 0..n {
            for i in j..n {
                l[(i, j)] = entry(i, j) as f32;
            }
        }
        cholesky_in_place(l.as_mut(), par)?;
        Some(LltF32 { l })
    }

    /// The order of M.
    pub fn order(&self) -> usize {
        self.l.nrows()
    }

    /// L's first entry (tests tell factors apart by it).
    #[cfg(test)]
    pub fn first_entry(&self) -> f32 {
        self.l[(0, 0)]
    }

    /// L := s L, the factor of s^2 L L^T (tests mark a factor with it: a
    /// preconditioner scaled so serves CG and GMRES as well).
    #[cfg(test)]
    pub fn scale(&mut self, s: f32) {
        for j in 0..self.l.ncols() {
            for v in self.l.col_mut(j).iter_mut() {
                *v *= s;
            }
        }
    }

    /// out := (L L^T)^-1 r, in single precision; `corr` and `mem` are scratch.
    fn apply(
        &self,
        r: &[f64],
        out: &mut [f64],
        corr: &mut Mat<f32>,
        mem: &mut MemBuffer,
        par: Par,
    ) {
        for (c, &v) in corr.col_mut(0).iter_mut().zip(r) {
            *c = v as f32;
        }
        llt::solve::solve_in_place_with_conj(
            self.l.as_ref(),
            Conj::No,
            corr.as_mut(),
            par,
            MemStack::new(mem),
        );
        for (o, &c) in out.iter_mut().zip(corr.col(0).iter()) {
            *o = f64::from(c);
        }
    }

    /// (L L^T)^-1 R for the columns of R, in single precision; None where
    /// the copies or the scratch cannot be allocated.
    fn solve_cols(&self, r: MatRef<'_, f64>, par: Par) -> Option<Mat<f64>> {
        let (n, k) = (r.nrows(), r.ncols());
        let mut x = try_mat::<f32>(n, k, "").ok()?;
        for j in 0..k {
            for i in 0..n {
                x[(i, j)] = r[(i, j)] as f32;
            }
        }
        let req = llt::solve::solve_in_place_scratch::<f32>(n, k, par);
        let mut mem = try_scratch(req, "").ok()?;
        llt::solve::solve_in_place_with_conj(
            self.l.as_ref(),
            Conj::No,
            x.as_mut(),
            par,
            MemStack::new(&mut mem),
        );
        let mut out = try_mat::<f64>(n, k, "").ok()?;
        for j in 0..k {
            for i in 0..n {
                out[(i, j)] = f64::from(x[(i, j)]);
            }
        }
        Some(out)
    }

    fn scratch(&self, par: Par) -> (Mat<f32>, MemBuffer) {
        let n = self.order();
        (
            Mat::<f32>::zeros(n, 1),
            MemBuffer::new(llt::solve::solve_in_place_scratch::<f32>(n, 1, par)),
        )
    }
}

/// |M|_inf (the largest row sum of |M|, M symmetric with its lower triangle
/// given) and |r|_inf: the scales of the normwise backward error
/// |r - M x|_inf / (|M|_inf |x|_inf + |r|_inf).
fn scales(m: MatRef<'_, f64>, r: &[f64]) -> (f64, f64) {
    let n = m.nrows();
    let mut rows = vec![0.0f64; n];
    for j in 0..n {
        // Column j from the diagonal down, as a slice: its entries add to
        // their rows' sums and, by symmetry, to row j's (the diagonal once).
        // 1.9 ms against 5.4 ms indexed entry by entry at order 1,600.
        let col = m.col(j).subrows(j, n - j);
        let mut below = 0.0;
        match col.try_as_col_major() {
            Some(col) => {
                for (row, &v) in rows[j..].iter_mut().zip(col.as_slice()) {
                    *row += v.abs();
                    below += v.abs();
                }
            }
            None => {
                for (row, &v) in rows[j..].iter_mut().zip(col.iter()) {
                    *row += v.abs();
                    below += v.abs();
                }
            }
        }
        rows[j] += below - m[(j, j)].abs();
    }
    (inf_norm(&rows), inf_norm(r))
}

fn inf_norm(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |a, v| a.max(v.abs()))
}

fn norm2(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// x = M^-1 r (one right-hand side) by Cholesky of M rounded to single
/// precision and iterative refinement with residuals in double precision
/// ([`refine`]); None when M is not positive definite in single precision or
/// the refinement stalls, for the caller to solve in double. M's lower
/// triangle is read.
#[cfg(test)]
pub(crate) fn llt_solve_mixed(
    m: MatRef<'_, f64>,
    r: &[f64],
    rtol: f64,
    par: Par,
) -> Option<Vec<f64>> {
    refine(m, &LltF32::of(m, par)?, r, rtol, 0.0, par)
}

/// x = M^-1 r by iterative refinement with the single-precision factor `l`
/// of M: each round solves for the correction with `l`, the residual in
/// double precision. Returns x once its normwise backward error is at most
/// `rtol` (|r - M x|_inf <= rtol (|M|_inf |x|_inf + |r|_inf), |M|_inf the
/// largest row sum: what a Cholesky solve in double meets with rtol ~ 1e-15,
/// and what rounding lets a residual of a dense M reach), or once its
/// relative residual is at most `rel` (|r - M x|_2 <= rel |r|_2: an inexact
/// Newton step's forcing term; 0 for none); None when a round does not halve
/// the residual (M too ill-conditioned for single precision) or after
/// REFINE_ROUNDS rounds.
pub(crate) fn refine(
    m: MatRef<'_, f64>,
    l: &LltF32,
    r: &[f64],
    rtol: f64,
    rel: f64,
    par: Par,
) -> Option<Vec<f64>> {
    let n = m.nrows();
    let (mut corr, mut mem) = l.scratch(par);
    let mut dx = vec![0.0; n];
    let mut x = vec![0.0; n];
    let mut res = r.to_vec();
    let mut mx = vec![0.0; n];
    let (m_inf, r_max) = scales(m, r);
    let rel_stop = rel * norm2(r);
    let mut last = f64::INFINITY;
    for _ in 0..REFINE_ROUNDS {
        l.apply(&res, &mut dx, &mut corr, &mut mem, par);
        for (xi, &c) in x.iter_mut().zip(&dx) {
            *xi += c;
        }
        // res = r - M x, with M's lower triangle (symmetric).
        symmetric_times_into(m, &x, &mut mx, par);
        for ((ri, &rv), mv) in res.iter_mut().zip(r).zip(&mx) {
            *ri = rv - mv;
        }
        let now = inf_norm(&res);
        let x_max = inf_norm(&x);
        if !now.is_finite() || !x_max.is_finite() {
            return None;
        }
        if now <= rtol * (m_inf * x_max + r_max) || norm2(&res) <= rel_stop {
            return Some(x);
        }
        if now > 0.5 * last {
            return None;
        }
        last = now;
    }
    None
}

/// x = M^-1 r by conjugate gradients on the symmetric positive definite M
/// (double precision, its lower triangle read) preconditioned by `l`, the
/// single-precision factor of a nearby matrix M0 (the reduced system of an
/// earlier Newton step): where M differs from M0 in a few directions, CG
/// converges in about as many iterations, at O(k^2) each instead of a new
/// O(k^3) factorisation. `pos[j]` is unknown j's position in M0 (None for
/// one M0 does not have); None means the same unknowns in the same order.
/// The preconditioner is then the inverse of M0 restricted to the shared
/// unknowns and bordered by M's rows of the new ones (`kept::Bordered`:
/// |R| + |N| triangular solves with `l` for the unknowns that went and came),
/// symmetric positive definite as CG needs. The stopping tests are [`refine`]'s
/// (`rtol`, `rel`) on the true residual; None after `max_it`
/// iterations or on a breakdown (then factor M itself).
#[allow(clippy::too_many_arguments)]
pub(crate) fn pcg(
    m: MatRef<'_, f64>,
    l: &LltF32,
    pos: Option<&[Option<usize>]>,
    r: &[f64],
    rtol: f64,
    rel: f64,
    max_it: usize,
    par: Par,
) -> Option<Vec<f64>> {
    let mut pre = Bordered::new(l, pos, m.nrows(), &|i, j| m[(i, j)], par)?;
    let m_inf = scales(m, r).0;
    let mut op = |x: &[f64], y: &mut [f64]| symmetric_times_into(m, x, y, par);
    pcg_with(&mut op, m_inf, &mut pre, r, rtol, rel, max_it)
}

/// A preconditioner of [`pcg_with`] and [`gmres_with`]: out := P res.
pub(crate) trait Precondition {
    fn apply(&mut self, res: &[f64], out: &mut [f64]);
}

impl Precondition for Bordered<'_> {
    fn apply(&mut self, res: &[f64], out: &mut [f64]) {
        Bordered::apply(self, res, out);
    }
}

impl Precondition for Complement<'_> {
    fn apply(&mut self, res: &[f64], out: &mut [f64]) {
        Complement::apply(self, res, out);
    }
}

/// [`pcg`] on the operator y := M x `op` (M symmetric positive definite,
/// of order r.len(), |M|_inf = `m_inf`) with the preconditioner `pre`
/// (symmetric positive definite).
pub(crate) fn pcg_with(
    op: &mut dyn FnMut(&[f64], &mut [f64]),
    m_inf: f64,
    pre: &mut dyn Precondition,
    r: &[f64],
    rtol: f64,
    rel: f64,
    max_it: usize,
) -> Option<Vec<f64>> {
    let n = r.len();
    let mut precondition = |res: &[f64], z: &mut [f64]| pre.apply(res, z);
    let r_max = inf_norm(r);
    let rel_stop = rel * norm2(r);
    let met = |res: &[f64], x: &[f64]| {
        inf_norm(res) <= rtol * (m_inf * inf_norm(x) + r_max) || norm2(res) <= rel_stop
    };
    let mut x = vec![0.0; n];
    let mut res = r.to_vec();
    let mut z = vec![0.0; n];
    precondition(&res, &mut z);
    let mut p = z.clone();
    let (mut q, mut mx) = (vec![0.0; n], vec![0.0; n]);
    let mut rz: f64 = res.iter().zip(&z).map(|(a, b)| a * b).sum();
    for _ in 0..max_it {
        op(&p, &mut q);
        let pq: f64 = p.iter().zip(&q).map(|(a, b)| a * b).sum();
        if !(pq > 0.0 && rz.is_finite()) {
            return None;
        }
        let alpha = rz / pq;
        for j in 0..n {
            x[j] += alpha * p[j];
            res[j] -= alpha * q[j];
        }
        if met(&res, &x) {
            // Confirmed on the true residual (the recurrence drifts by rounding).
            op(&x, &mut mx);
            for ((ri, &rv), mv) in res.iter_mut().zip(r).zip(&mx) {
                *ri = rv - mv;
            }
            if met(&res, &x) {
                return Some(x);
            }
        }
        precondition(&res, &mut z);
        let rz_new: f64 = res.iter().zip(&z).map(|(a, b)| a * b).sum();
        let beta = rz_new / rz;
        rz = rz_new;
        for j in 0..n {
            p[j] = z[j] + beta * p[j];
        }
    }
    None
}

/// Krylov vectors a cycle of [`gmres`] builds before it restarts from the
/// true residual.
pub(crate) const GMRES_RESTART: usize = 30;

/// A cycle of [`gmres`] stops once its estimated residual has dropped by this
/// factor (the true residual, in double, then starts the next cycle).
const GMRES_DROP: f64 = 1e-10;

/// x = M^-1 r by flexible GMRES on the square M (double precision, all of
/// it read: Coulomb's reduced system is not symmetric), right-preconditioned
/// by `l`, the single-precision factor of a symmetric matrix near M (for a
/// Newton step's reduced system W^T A W + D, each direction cut to its test
/// vector; or an earlier step's), bordered by `pos` as in
/// [`pcg`] with the lower entries `sym(i, j)` (i >= j) of M's symmetric part
/// on the new unknowns (`kept::Bordered`). Each cycle of at most GMRES_RESTART products starts from the
/// true residual in double precision (iterative refinement with GMRES as its
/// inner solver), so the answer meets [`refine`]'s bounds: a normwise
/// backward error at most `rtol`, |M|_inf the largest row sum of |M|, or a
/// relative residual at most `rel`. None
/// after `max_it` products with M, where a cycle does not halve the
/// residual, or on a breakdown (then the caller factors M itself).
#[allow(clippy::too_many_arguments)]
pub(crate) fn gmres(
    m: MatRef<'_, f64>,
    sym: &dyn Fn(usize, usize) -> f64,
    l: &LltF32,
    pos: Option<&[Option<usize>]>,
    r: &[f64],
    rtol: f64,
    rel: f64,
    max_it: usize,
    par: Par,
) -> Option<Vec<f64>> {
    let mut pre = Bordered::new(l, pos, m.nrows(), sym, par)?;
    let n = m.nrows();
    let mut rows = vec![0.0f64; n];
    for j in 0..n {
        for (i, row) in rows.iter_mut().enumerate() {
            *row += m[(i, j)].abs();
        }
    }
    let mut op = |x: &[f64], y: &mut [f64]| {
        let mut ym = faer::MatMut::from_column_major_slice_mut(y, n, 1);
        let xm = MatRef::from_column_major_slice(x, n, 1);
        faer::linalg::matmul::matmul(ym.as_mut(), faer::Accum::Replace, m, xm, 1.0, par);
    };
    gmres_with(&mut op, inf_norm(&rows), &mut pre, r, rtol, rel, max_it)
}

/// [`gmres`] on the operator y := M x `op` (M square of order r.len(),
/// |M|_inf = `m_inf`) with the preconditioner `pre`.
pub(crate) fn gmres_with(
    op: &mut dyn FnMut(&[f64], &mut [f64]),
    m_inf: f64,
    pre: &mut dyn Precondition,
    r: &[f64],
    rtol: f64,
    rel: f64,
    max_it: usize,
) -> Option<Vec<f64>> {
    let n = r.len();
    let rel_stop = rel * norm2(r);
    let r_max = inf_norm(r);
    let restart = GMRES_RESTART.min(n.max(1));
    // The Arnoldi basis V (n x (restart + 1)), the preconditioned vectors Z
    // (n x restart), the Hessenberg matrix after its Givens rotations, and
    // the rotated right-hand side g.
    let mut v = try_mat::<f64>(n, restart + 1, "").ok()?;
    let mut z = try_mat::<f64>(n, restart, "").ok()?;
    let mut h = vec![0.0f64; (restart + 1) * restart];
    let (mut cs, mut sn, mut g, mut y) = (
        vec![0.0f64; restart],
        vec![0.0f64; restart],
        vec![0.0f64; restart + 1],
        vec![0.0f64; restart],
    );
    let mut x = vec![0.0; n];
    let mut res = r.to_vec();
    let mut w = vec![0.0; n];
    let mut last = f64::INFINITY;
    let mut its = 0;
    loop {
        let now = inf_norm(&res);
        let x_max = inf_norm(&x);
        if !now.is_finite() || !x_max.is_finite() {
            return None;
        }
        let bound = rtol * (m_inf * x_max + r_max);
        let now2 = norm2(&res);
        if now <= bound || now2 <= rel_stop {
            return Some(x);
        }
        if its >= max_it || now > 0.5 * last {
            return None;
        }
        last = now;
        let beta = res.iter().map(|a| a * a).sum::<f64>().sqrt();
        for (vi, &ri) in v.col_mut(0).iter_mut().zip(&res) {
            *vi = ri / beta;
        }
        g.iter_mut().for_each(|a| *a = 0.0);
        g[0] = beta;
        // The cycle aims past the bound (its 2-norm estimate against the
        // inf-norm bound) or the relative residual, or at GMRES_DROP where
        // both are out of reach.
        let aim = (bound * 0.5).max(0.5 * rel_stop).max(beta * GMRES_DROP);
        let mut cols = 0;
        while cols < restart && its < max_it {
            let j = cols;
            {
                let vj = v.col(j).try_as_col_major().expect("contiguous");
                let zj = z.col_mut(j).try_as_col_major_mut().expect("contiguous");
                pre.apply(vj.as_slice(), zj.as_slice_mut());
            }
            {
                let zj = z.col(j).try_as_col_major().expect("contiguous");
                op(zj.as_slice(), &mut w);
            }
            its += 1;
            // Modified Gram-Schmidt against V's columns 0..=j.
            let hj = &mut h[j * (restart + 1)..(j + 1) * (restart + 1)];
            for (i, hij) in hj.iter_mut().enumerate().take(j + 1) {
                let vi = v.col(i);
                let dot: f64 = w.iter().zip(vi.iter()).map(|(a, b)| a * b).sum();
                for (wk, &vk) in w.iter_mut().zip(vi.iter()) {
                    *wk -= dot * vk;
                }
                *hij = dot;
            }
            let wn = w.iter().map(|a| a * a).sum::<f64>().sqrt();
            hj[j + 1] = wn;
            if !(wn.is_finite()) {
                return None;
            }
            if wn > 0.0 {
                for (vk, &wk) in v.col_mut(j + 1).iter_mut().zip(&w) {
                    *vk = wk / wn;
                }
            }
            // The earlier rotations, then a new one zeroing h[j + 1, j].
            for i in 0..j {
                let (a, b) = (hj[i], hj[i + 1]);
                hj[i] = cs[i] * a + sn[i] * b;
                hj[i + 1] = -sn[i] * a + cs[i] * b;
            }
            let (a, b) = (hj[j], hj[j + 1]);
            let rr = a.hypot(b);
            if rr == 0.0 {
                return None;
            }
            (cs[j], sn[j]) = (a / rr, b / rr);
            hj[j] = rr;
            hj[j + 1] = 0.0;
            g[j + 1] = -sn[j] * g[j];
            g[j] *= cs[j];
            cols += 1;
            if g[j + 1].abs() <= aim || wn == 0.0 {
                break;
            }
        }
        // y = H^-1 g (upper triangular), x += Z y.
        let y = &mut y[..cols];
        for i in (0..cols).rev() {
            let mut s = g[i];
            for (k, yk) in y.iter().enumerate().skip(i + 1) {
                s -= h[k * (restart + 1) + i] * yk;
            }
            y[i] = s / h[i * (restart + 1) + i];
        }
        for (k, &yk) in y.iter().enumerate() {
            for (xi, &zi) in x.iter_mut().zip(z.col(k).iter()) {
                *xi += yk * zi;
            }
        }
        // The true residual, in double precision.
        op(&x, &mut w);
        for ((ri, &rv), &mv) in res.iter_mut().zip(r).zip(&w) {
            *ri = rv - mv;
        }
    }
}

/// M x for the symmetric M whose lower triangle is given (the tests' checks).
#[cfg(test)]
fn symmetric_times(m: MatRef<'_, f64>, x: &[f64], par: Par) -> Vec<f64> {
    let mut y = vec![0.0; m.nrows()];
    symmetric_times_into(m, x, &mut y, par);
    y
}

/// y := M x for the symmetric M whose lower triangle is given, into the
/// caller's `y` (the iterations' scratch: no allocation).
fn symmetric_times_into(m: MatRef<'_, f64>, x: &[f64], y: &mut [f64], par: Par) {
    let n = m.nrows();
    let mut y = faer::MatMut::from_column_major_slice_mut(y, n, 1);
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
}

/// X = M^-1 R by LU with partial pivoting of the square M (the result may be
/// infinite or NaN when M is singular); None where the copy of M cannot be
/// allocated.
pub(crate) fn lu_solve(m: MatRef<'_, f64>, r: MatRef<'_, f64>, par: Par) -> Option<Mat<f64>> {
    let n = m.nrows();
    let mut a = copy(m)?;
    let (mut perm, mut perm_inv) = (vec![0usize; n], vec![0usize; n]);
    let req = lu::factor::lu_in_place_scratch::<usize, f64>(n, n, par, Default::default()).or(
        lu::solve::solve_in_place_scratch::<usize, f64>(n, r.ncols(), par),
    );
    let mut mem = try_scratch(req, "").ok()?;
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
    Some(x)
}

/// The thin SVD M = U diag(s) V^T of the square M: (U, s, V); None when it does
/// not converge or its factors cannot be allocated.
pub(crate) fn thin_svd(m: MatRef<'_, f64>, par: Par) -> Option<(Mat<f64>, Vec<f64>, Mat<f64>)> {
    let n = m.nrows();
    let (mut u, mut v) = (
        try_mat::<f64>(n, n, "").ok()?,
        try_mat::<f64>(n, n, "").ok()?,
    );
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let thin = ComputeSvdVectors::Thin;
    let req = svd::svd_scratch::<f64>(n, n, thin, thin, par, Default::default());
    let mut mem = try_scratch(req, "").ok()?;
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

    /// |M|_inf from the lower triangle alone is the largest row sum of the
    /// whole symmetric M, on a column-major M and on a view of it that is not.
    #[test]
    fn the_scales_read_the_lower_triangle_as_the_whole_matrix() {
        let n = 7;
        let full = Mat::from_fn(n, n, |i, j| {
            ((i + j) as f64 * 0.7).sin() + (i * j) as f64 * 0.1
        });
        let mut lower = full.clone();
        for j in 0..n {
            for i in 0..j {
                lower[(i, j)] = f64::NAN;
            }
        }
        let want = (0..n)
            .map(|i| (0..n).map(|j| full[(i, j)].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let r = [1.0, -3.0, 2.0];
        let (m_inf, r_max) = scales(lower.as_ref(), &r);
        assert!(
            (m_inf - want).abs() <= 1e-14 * want,
            "{m_inf} against {want}"
        );
        assert_eq!(r_max, 3.0);
        // The transpose of an upper triangle: rows not contiguous.
        let upper = Mat::from_fn(n, n, |i, j| if i <= j { full[(i, j)] } else { f64::NAN });
        let (m_inf, _) = scales(upper.transpose(), &r);
        assert!(
            (m_inf - want).abs() <= 1e-14 * want,
            "{m_inf} against {want}"
        );
    }

    #[test]
    fn llt_and_lu_solve_a_known_system() {
        let (m, r, x) = case();
        let y = llt_solve(m.as_ref(), r.as_ref(), Par::Seq).unwrap();
        assert!(max_diff(&y, &x) < 1e-14);
        let y = lu_solve(m.as_ref(), r.as_ref(), Par::Seq).unwrap();
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
        // |M|_inf, the largest row sum of |M|.
        let m_inf = (0..n).fold(0.0f64, |a, i| a.max((0..n).map(|j| m[(i, j)].abs()).sum()));
        let norm = |v: &[f64]| v.iter().fold(0.0f64, |a, e| a.max(e.abs()));
        assert!(res <= rtol * (m_inf * norm(&y) + norm(&b)), "{res}");
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

    /// CG preconditioned by the single-precision factor of a nearby matrix:
    /// where M differs from the factored M0 by a symmetric change of rank r,
    /// it meets refine's residual bound (and the known solution) in about r
    /// iterations and a few more, far fewer than the order; with fewer iterations allowed
    /// than the change needs, or a factor of another order, it gives up (None)
    /// for the caller to factor M itself.
    #[test]
    fn pcg_on_a_nearby_factor_converges_in_about_the_rank_of_the_change() {
        let n = 300;
        let (m0, _, _) = spd(n, 1e3);
        let l0 = LltF32::of(m0.as_ref(), Par::Seq).expect("SPD");
        // M = M0 + sum of 6 rank-one terms w w^T (SPD), b = M x.
        let rank = 6;
        let mut m = m0.clone();
        for t in 0..rank {
            let w: Vec<f64> = (0..n)
                .map(|i| ((i * (t + 2)) as f64 * 0.13).sin())
                .collect();
            for j in 0..n {
                for i in 0..n {
                    m[(i, j)] += 5.0 * w[i] * w[j];
                }
            }
        }
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        let b = symmetric_times(m.as_ref(), &x, Par::Seq);
        let rtol = 1e-15;
        let needed = (1..=60)
            .find(|&it| pcg(m.as_ref(), &l0, None, &b, rtol, 0.0, it, Par::Seq).is_some())
            .expect("converges");
        // The 6 outliers, then a few for the cluster single precision leaves
        // around 1 (width about cond eps_32): 13 here, of an order of 300.
        assert!(needed <= rank + 8, "{needed} iterations");
        let y = pcg(m.as_ref(), &l0, None, &b, rtol, 0.0, needed, Par::Seq).unwrap();
        let mx = symmetric_times(m.as_ref(), &y, Par::Seq);
        let res = inf_norm(&mx.iter().zip(&b).map(|(p, q)| p - q).collect::<Vec<_>>());
        let m_inf = (0..n).fold(0.0f64, |a, i| a.max((0..n).map(|j| m[(i, j)].abs()).sum()));
        assert!(res <= rtol * (m_inf * inf_norm(&y) + inf_norm(&b)), "{res}");
        let err = inf_norm(&y.iter().zip(&x).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(err <= 1e-9, "{err}");
        // A relative residual of 1e-4 (a Newton step's forcing term): met,
        // in fewer iterations.
        let rel = 1e-4;
        let loose = (1..=60)
            .find(|&it| pcg(m.as_ref(), &l0, None, &b, rtol, rel, it, Par::Seq).is_some())
            .expect("converges");
        assert!(loose < needed, "{loose} against {needed} iterations");
        let y = pcg(m.as_ref(), &l0, None, &b, rtol, rel, loose, Par::Seq).unwrap();
        let mx = symmetric_times(m.as_ref(), &y, Par::Seq);
        let r2 = norm2(&mx.iter().zip(&b).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(r2 <= rel * norm2(&b), "{r2:e}");
        // Too few iterations for a rank-6 change.
        assert!(pcg(m.as_ref(), &l0, None, &b, rtol, 0.0, 3, Par::Seq).is_none());
        // A factor of another order.
        let (small, _, _) = spd(10, 10.0);
        let ls = LltF32::of(small.as_ref(), Par::Seq).unwrap();
        assert!(pcg(m.as_ref(), &ls, None, &b, rtol, 0.0, 50, Par::Seq).is_none());
    }

    /// The same on other unknowns: M0's unknown 5 gone and two new ones
    /// appended (M's last rows), the factor bordered by `pos`; a `pos` that
    /// points outside the factor is refused.
    #[test]
    fn pcg_on_a_factor_of_other_unknowns_borders_it() {
        let n0 = 300;
        let (m0, _, _) = spd(n0, 1e3);
        let l0 = LltF32::of(m0.as_ref(), Par::Seq).expect("SPD");
        let kept: Vec<usize> = (0..n0).filter(|&i| i != 5).collect();
        let n = kept.len() + 2;
        let m = Mat::from_fn(n, n, |i, j| match (kept.get(i), kept.get(j)) {
            (Some(&a), Some(&b)) => m0[(a, b)],
            (None, None) => {
                if i == j {
                    50.0
                } else {
                    1.0
                }
            }
            (Some(&a), None) | (None, Some(&a)) => 0.1 * ((a + i + j) as f64).sin(),
        });
        let pos: Vec<Option<usize>> = (0..n).map(|i| kept.get(i).copied()).collect();
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        let b = symmetric_times(m.as_ref(), &x, Par::Seq);
        let rtol = 1e-15;
        let needed = (1..=60)
            .find(|&it| pcg(m.as_ref(), &l0, Some(&pos), &b, rtol, 0.0, it, Par::Seq).is_some())
            .expect("converges");
        // M restricted to the shared unknowns is M0's: the bordered
        // preconditioner is M^-1 up to single precision (3 here; the
        // diagonal on the new unknowns alone took 10).
        assert!(needed <= 3, "{needed} iterations");
        let y = pcg(m.as_ref(), &l0, Some(&pos), &b, rtol, 0.0, needed, Par::Seq).unwrap();
        let err = inf_norm(&y.iter().zip(&x).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(err <= 1e-9, "{err}");
        let mut bad = pos.clone();
        bad[0] = Some(n0);
        assert!(pcg(m.as_ref(), &l0, Some(&bad), &b, rtol, 0.0, 60, Par::Seq).is_none());
    }

    /// GMRES on a non-symmetric M = S + C (S symmetric positive definite,
    /// C of rank 4 and not symmetric: Coulomb's coupling columns) with S's
    /// single-precision factor: it meets refine's bound on the true residual
    /// and the known solution, in about the rank of C and a few more
    /// iterations; too few iterations or a factor of another order give None.
    /// Bordered by `pos` (S's unknown 7 gone, one new unknown) it converges in
    /// as many iterations as on S itself.
    #[test]
    fn gmres_on_the_symmetric_part_meets_the_backward_error_bound() {
        let n = 300;
        let (s0, _, _) = spd(n, 1e3);
        let l0 = LltF32::of(s0.as_ref(), Par::Seq).expect("SPD");
        let mut m = s0.clone();
        for t in 0..4 {
            let col = 10 + 40 * t;
            for i in 0..n {
                m[(i, col)] += 0.3 * ((i * (t + 3)) as f64 * 0.21).cos();
            }
        }
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        let xm = Mat::from_fn(n, 1, |i, _| x[i]);
        let bm = &m * &xm;
        let b: Vec<f64> = bm.col(0).iter().copied().collect();
        let sym = |i: usize, j: usize| s0[(i, j)];
        let rtol = 1e-15;
        let needed = (1..=60)
            .find(|&it| gmres(m.as_ref(), &sym, &l0, None, &b, rtol, 0.0, it, Par::Seq).is_some())
            .expect("converges");
        assert!(needed <= 4 + 10, "{needed} iterations");
        let y = gmres(m.as_ref(), &sym, &l0, None, &b, rtol, 0.0, needed, Par::Seq).unwrap();
        let ym = Mat::from_fn(n, 1, |i, _| y[i]);
        let my = &m * &ym;
        let res = (0..n).fold(0.0f64, |a, i| a.max((my[(i, 0)] - b[i]).abs()));
        let m_inf = (0..n).fold(0.0f64, |a, i| a.max((0..n).map(|j| m[(i, j)].abs()).sum()));
        assert!(res <= rtol * (m_inf * inf_norm(&y) + inf_norm(&b)), "{res}");
        let err = inf_norm(&y.iter().zip(&x).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(err <= 1e-9, "{err}");
        // A relative residual of 1e-4 (a Coulomb step's forcing term): met,
        // in fewer iterations.
        let rel = 1e-4;
        let loose = (1..=60)
            .find(|&it| gmres(m.as_ref(), &sym, &l0, None, &b, rtol, rel, it, Par::Seq).is_some())
            .expect("converges");
        assert!(loose < needed, "{loose} against {needed} iterations");
        let y = gmres(m.as_ref(), &sym, &l0, None, &b, rtol, rel, loose, Par::Seq).unwrap();
        let my = &m * Mat::from_fn(n, 1, |i, _| y[i]);
        let r2 = norm2(&(0..n).map(|i| my[(i, 0)] - b[i]).collect::<Vec<_>>());
        assert!(r2 <= rel * norm2(&b), "{r2:e}");
        assert!(gmres(m.as_ref(), &sym, &l0, None, &b, rtol, 0.0, 2, Par::Seq).is_none());
        let (small, _, _) = spd(10, 10.0);
        let ls = LltF32::of(small.as_ref(), Par::Seq).unwrap();
        assert!(gmres(m.as_ref(), &sym, &ls, None, &b, rtol, 0.0, 60, Par::Seq).is_none());
        // The factor of S on other unknowns: M without unknown 7, one new last.
        let kept: Vec<usize> = (0..n).filter(|&i| i != 7).collect();
        let n2 = kept.len() + 1;
        let border = |i: usize, j: usize, from: &Mat<f64>| match (kept.get(i), kept.get(j)) {
            (Some(&a), Some(&b)) => from[(a, b)],
            (None, None) => 40.0,
            (Some(&a), None) | (None, Some(&a)) => 0.1 * (a as f64).sin(),
        };
        let m2 = Mat::from_fn(n2, n2, |i, j| border(i, j, &m));
        let s2 = Mat::from_fn(n2, n2, |i, j| border(i, j, &s0));
        let sym2 = |i: usize, j: usize| s2[(i, j)];
        let pos: Vec<Option<usize>> = (0..n2).map(|i| kept.get(i).copied()).collect();
        let x2m = Mat::from_fn(n2, 1, |i, _| (i as f64 * 0.37).cos());
        let b2m = &m2 * &x2m;
        let b2: Vec<f64> = b2m.col(0).iter().copied().collect();
        let needed2 = (1..=60)
            .find(|&it| {
                gmres(
                    m2.as_ref(),
                    &sym2,
                    &l0,
                    Some(&pos),
                    &b2,
                    rtol,
                    0.0,
                    it,
                    Par::Seq,
                )
                .is_some()
            })
            .expect("converges");
        assert!(needed2 <= needed, "{needed2} against {needed} iterations");
        let y2 = gmres(
            m2.as_ref(),
            &sym2,
            &l0,
            Some(&pos),
            &b2,
            rtol,
            0.0,
            needed2,
            Par::Seq,
        )
        .unwrap();
        let err = (0..n2).fold(0.0f64, |a, i| a.max((y2[i] - x2m[(i, 0)]).abs()));
        assert!(err <= 1e-9, "{err}");
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
