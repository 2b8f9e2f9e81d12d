//! Semismooth Newton (primal-dual active set) on the condensed dual, for the
//! natural map of design.md section 5:
//!
//! ```text
//! F(lambda) = lambda - P(lambda - rho (A lambda - b)),
//! ```
//!
//! P the projection onto lambda_N >= 0, |lambda_T,i| <= p_i. At each iteration the
//! trial y = lambda - rho (A lambda - b) sorts every component: a closed normal or a
//! sticking tangential component is free (its equation is (A d)_j = -F_j / rho_i),
//! an open normal or a 2D slipping tangential component is fixed (d_j = -F_j). In 3D
//! a slipping contact splits along n = y_T/|y_T| (fixed: the bound) and the
//! orthogonal t (free, with the curvature term (1 - s)/(s rho), s = p/|y_T|), the
//! generalised Jacobian of the disk projection (Hueber, Stadler, Wohlmuth). For
//! Coulomb the bound mu lambda_N is differentiated too: the slipping tangential
//! force follows the normal one. The reduced system on the free unknowns is solved
//! by a dense LU.
//!
//! Globalisation: a Newton step is kept only if it lowers err; otherwise the
//! iterate takes a few projected Gauss-Seidel sweeps (a first-order descent step
//! for Tresca) and Newton restarts from there, so it cannot cycle.

use super::pgs;
use super::{DualProblem, Outcome};
use crate::options::Options;
use faer::Mat;
use faer::prelude::Solve;

/// Gauss-Seidel sweeps taken when a Newton step is rejected.
const FALLBACK_SWEEPS: usize = 5;

/// One reduced unknown: its test row and its direction in lambda-space (sparse,
/// at most three entries each), a diagonal term and the right-hand side.
struct Reduced {
    test: [(usize, f64); 2],
    n_test: usize,
    dir: [(usize, f64); 3],
    n_dir: usize,
    diag: f64,
    rhs: f64,
}

impl Reduced {
    fn unit(j: usize, rhs: f64) -> Reduced {
        Reduced {
            test: [(j, 1.0), (0, 0.0)],
            n_test: 1,
            dir: [(j, 1.0), (0, 0.0), (0, 0.0)],
            n_dir: 1,
            diag: 0.0,
            rhs,
        }
    }
}

/// Sorts the components at lam and returns the reduced unknowns and the explicit
/// part e0 of the step (written into `e0`); `f` receives F(lam).
fn linearise(
    problem: &DualProblem<'_>,
    lam: &[f64],
    w: &[f64],
    e0: &mut [f64],
    f: &mut [f64],
) -> Vec<Reduced> {
    let dual = problem.dual;
    let (m, d) = (dual.m, dual.d);
    let coulomb_mu = match problem.law {
        super::Law::Coulomb(mu) => Some(mu),
        super::Law::Tresca(_) => None,
    };
    e0.iter_mut().for_each(|v| *v = 0.0);
    let mut red = Vec::with_capacity(dual.c);
    for i in 0..m {
        let rho = dual.rho[i];
        let jt = m + (d - 1) * i;
        let r = problem.law.bound(i, lam[i]);
        if rho <= 0.0 {
            // The contact does not act on u: project and keep it there.
            f[i] = lam[i] - lam[i].max(0.0);
            e0[i] = -f[i];
            let mut y = [0.0; 2];
            y[..d - 1].copy_from_slice(&lam[jt..jt + d - 1]);
            super::project_disk(&mut y[..d - 1], r);
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s] - y[s];
                e0[jt + s] = -f[jt + s];
            }
            continue;
        }
        let yn = lam[i] - rho * w[i];
        f[i] = lam[i] - yn.max(0.0);
        let normal_free = yn > 0.0;
        let mut yt = [0.0; 2];
        for s in 0..d - 1 {
            yt[s] = lam[jt + s] - rho * w[jt + s];
        }
        let ny = yt[..d - 1].iter().map(|v| v * v).sum::<f64>().sqrt();
        // Coupling of the slipping tangential force to lambda_N (Coulomb).
        let mut coupling: Option<[f64; 2]> = None;
        if r > 0.0 && ny < r {
            // Stick: every tangential component free.
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s] - yt[s];
                red.push(Reduced::unit(jt + s, -f[jt + s] / rho));
            }
        } else if ny == 0.0 {
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s];
                e0[jt + s] = -f[jt + s];
            }
        } else {
            let nvec = [yt[0] / ny, if d == 3 { yt[1] / ny } else { 0.0 }];
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s] - r * nvec[s];
            }
            let fn_ = (0..d - 1).map(|s| f[jt + s] * nvec[s]).sum::<f64>();
            for s in 0..d - 1 {
                e0[jt + s] -= fn_ * nvec[s];
            }
            if d == 3 {
                let t = [-nvec[1], nvec[0]];
                let ft = f[jt] * t[0] + f[jt + 1] * t[1];
                let sr = r / ny;
                if sr > 0.0 {
                    red.push(Reduced {
                        test: [(jt, t[0]), (jt + 1, t[1])],
                        n_test: 2,
                        dir: [(jt, t[0]), (jt + 1, t[1]), (0, 0.0)],
                        n_dir: 2,
                        diag: (1.0 - sr) / (sr * rho),
                        rhs: -ft / (sr * rho),
                    });
                } else {
                    e0[jt] -= ft * t[0];
                    e0[jt + 1] -= ft * t[1];
                }
            }
            if let Some(mu) = coulomb_mu {
                coupling = Some([mu[i] * nvec[0], mu[i] * nvec[1]]);
            }
        }
        if normal_free {
            let mut u = Reduced::unit(i, -f[i] / rho);
            if let Some(cp) = coupling {
                for (s, &cs) in cp[..d - 1].iter().enumerate() {
                    u.dir[1 + s] = (jt + s, cs);
                }
                u.n_dir = d;
            }
            red.push(u);
        } else {
            e0[i] = -f[i];
            if let Some(cp) = coupling {
                // lambda_N moves by -F_N: the bound, hence the slip force, follows.
                for s in 0..d - 1 {
                    e0[jt + s] += cp[s] * e0[i];
                }
            }
        }
    }
    red
}

/// Solves for the Newton step `step` at lam (w = A lam - b). False when the
/// reduced system is singular.
fn newton_step(
    problem: &DualProblem<'_>,
    lam: &[f64],
    w: &[f64],
    step: &mut [f64],
    f: &mut [f64],
    ae0: &mut [f64],
) -> bool {
    let dual = problem.dual;
    let c = dual.c;
    let red = linearise(problem, lam, w, step, f);
    let k = red.len();
    if k == 0 {
        return true;
    }
    dual.apply(step, ae0);
    // AV: column l = A * dir_l.
    let mut av = Mat::<f64>::zeros(c, k);
    for (l, u) in red.iter().enumerate() {
        let col = av
            .col_mut(l)
            .try_as_col_major_mut()
            .expect("contiguous")
            .as_slice_mut();
        for &(j, coef) in &u.dir[..u.n_dir] {
            for (x, a) in col.iter_mut().zip(dual.col(j)) {
                *x += coef * a;
            }
        }
    }
    let mut mat = Mat::<f64>::zeros(k, k);
    let mut rhs = Mat::<f64>::zeros(k, 1);
    for (r, u) in red.iter().enumerate() {
        let mut g = u.rhs;
        for &(j, coef) in &u.test[..u.n_test] {
            g -= coef * ae0[j];
            for l in 0..k {
                mat[(r, l)] += coef * av[(j, l)];
            }
        }
        mat[(r, r)] += u.diag;
        rhs[(r, 0)] = g;
    }
    let z = mat.partial_piv_lu().solve(&rhs);
    if !z.as_ref().is_all_finite() {
        return false;
    }
    for (l, u) in red.iter().enumerate() {
        for &(j, coef) in &u.dir[..u.n_dir] {
            step[j] += coef * z[(l, 0)];
        }
    }
    true
}

/// Runs the globalised semismooth Newton method from `lam`.
pub(super) fn solve(
    problem: &DualProblem<'_>,
    lam: &mut [f64],
    opts: &Options,
    target: f64,
) -> Outcome {
    let dual = problem.dual;
    let (m, c) = (dual.m, dual.c);
    let mut out = Outcome::default();
    let mut w = vec![0.0; c];
    let mut p = vec![0.0; m];
    let mut v = vec![0.0; c];
    let mut step = vec![0.0; c];
    let mut f = vec![0.0; c];
    let mut ae0 = vec![0.0; c];
    let mut trial = vec![0.0; c];
    let mut wt = vec![0.0; c];
    problem.gradient(lam, &mut w);
    let mut err = problem.error(lam, &w, &mut p, &mut v);
    loop {
        out.dual_err = err;
        if problem.should_stop(&mut out, lam, &p, &v, target, opts) {
            return out;
        }
        out.outer += 1;
        let ok = newton_step(problem, lam, &w, &mut step, &mut f, &mut ae0);
        if ok {
            for j in 0..c {
                trial[j] = lam[j] + step[j];
            }
            problem.gradient(&trial, &mut wt);
            let e = problem.error(&trial, &wt, &mut p, &mut v);
            if e < err {
                lam.copy_from_slice(&trial);
                w.copy_from_slice(&wt);
                err = e;
                continue;
            }
        }
        // Fallback: a first-order step.
        out.inner += pgs::sweeps(problem, lam, &mut w, FALLBACK_SWEEPS);
        problem.gradient(lam, &mut w);
        err = problem.error(lam, &w, &mut p, &mut v);
    }
}
