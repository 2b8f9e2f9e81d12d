//! One Newton step: the linearisation of the natural map at lambda (each
//! component sorted free or fixed, 3D slip split along the slip direction,
//! Coulomb's bound differentiated), the reduced unknowns it leaves, and on a
//! dense dual the reduced system assembled from A's columns (its solve:
//! `reduced_dense`; on a matrix-free dual: `reduced_krylov`).

use super::*;

/// One reduced unknown: its test row and its direction in lambda-space (sparse,
/// at most three entries each), a diagonal term and the right-hand side.
pub(super) struct Reduced {
    pub(super) test: [(usize, f64); 2],
    pub(super) n_test: usize,
    pub(super) dir: [(usize, f64); 3],
    pub(super) n_dir: usize,
    pub(super) diag: f64,
    pub(super) rhs: f64,
}

impl Reduced {
    /// test . v: this unknown's test vector against `v` (length c).
    pub(super) fn test_dot(&self, v: &[f64]) -> f64 {
        self.test[..self.n_test]
            .iter()
            .map(|&(j, coef)| coef * v[j])
            .sum::<f64>()
    }

    /// The right-hand side of this unknown's row once the explicit part of
    /// the step is moved over: rhs - test . (A e0) (`ae0` = A e0, length c).
    pub(super) fn rhs_after(&self, ae0: &[f64]) -> f64 {
        self.rhs - self.test_dot(ae0)
    }

    pub(super) fn unit(j: usize, rhs: f64) -> Reduced {
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

/// Sorts the components at lam for the natural map F_c with c = cscale rho and
/// returns the reduced unknowns and the explicit part e0 of the step (written into
/// `e0`); `f` receives F_c(lam), except on the tangential rows of a Coulomb
/// contact that closes sticking (lambda_N = 0, sorted against mu y_N: there
/// F_c = lambda_T, and `f` holds lambda_T - y_T, the sticking model's; `f`
/// is read only here). A free row's right-hand side is -F_c/c = -w, taken
/// from w directly (no cancellation when c is small).
pub(super) fn linearise(
    problem: &DualProblem<'_>,
    lam: &[f64],
    w: &[f64],
    e0: &mut [f64],
    f: &mut [f64],
    cscale: f64,
) -> Vec<Reduced> {
    let dual = problem.dual;
    let (m, d) = (dual.m, dual.d);
    let coulomb_mu = match problem.law {
        Friction::Coulomb(mu) => Some(mu),
        Friction::Tresca(_) => None,
    };
    e0.iter_mut().for_each(|v| *v = 0.0);
    let mut red = Vec::with_capacity(dual.c);
    for i in 0..m {
        let rho = cscale * dual.rho[i];
        let jt = m + (d - 1) * i;
        let r = problem.law.bound(i, lam[i]);
        if rho <= 0.0 {
            // The contact does not act on u: project and keep it there.
            f[i] = lam[i] - lam[i].max(0.0);
            e0[i] = -f[i];
            let mut y = [0.0; 2];
            y[..d - 1].copy_from_slice(&lam[jt..jt + d - 1]);
            crate::friction::project_disk(&mut y[..d - 1], r);
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
        // Stick or slip is decided against the bound of the normal force,
        // except at a contact that closes in this step (lambda_N = 0, trial
        // y_N > 0): its bound mu lambda_N is 0, so the natural map calls it
        // slipping whatever its tangential trial, and its step would set
        // lambda_T = mu (lambda_N + d_N) y_T / |y_T|, a slip at the full
        // bound. It is sorted against mu y_N instead, the bound of its
        // trial normal force (as Alart and Curnier's function does): a
        // contact that closes sticking sticks from the first step (the
        // matrix-free Coulomb histories of BENCHMARKS.md, "The load paths
        // hosts take": up to 10 % fewer products, one path 2 % more).
        let r_sort = match coulomb_mu {
            Some(mu) if lam[i] <= 0.0 && normal_free => mu[i] * yn,
            _ => r,
        };
        if r_sort > 0.0 && ny < r_sort {
            // Stick: every tangential component free.
            for s in 0..d - 1 {
                f[jt + s] = lam[jt + s] - yt[s];
                red.push(Reduced::unit(jt + s, -w[jt + s]));
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
            let mut u = Reduced::unit(i, -w[i]);
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

/// step += V z: each reduced unknown's value along its direction.
pub(super) fn add_directions(red: &[Reduced], z: impl IntoIterator<Item = f64>, step: &mut [f64]) {
    for (u, zl) in red.iter().zip(z) {
        for &(j, coef) in &u.dir[..u.n_dir] {
            step[j] += coef * zl;
        }
    }
}

/// Solves for the Newton step `step` at lam (w = A lam - b). None when the
/// reduced system is singular; Some(true) where `ae0` then holds A `step`
/// (a matrix-free dual's reduced solve combined it from its own products:
/// `krylov_step`), Some(false) where it does not.
#[allow(clippy::too_many_arguments)]
pub(super) fn newton_step(
    problem: &DualProblem<'_>,
    lam: &[f64],
    w: &[f64],
    step: &mut [f64],
    f: &mut [f64],
    ae0: &mut [f64],
    cscale: f64,
    krylov: &mut Krylov,
    reused: &mut Option<Reused>,
) -> Option<bool> {
    let dual = problem.dual;
    let red = linearise(problem, lam, w, step, f, cscale);
    let k = red.len();
    if k == 0 {
        // No sort for the next step to keep (`Krylov::settle`).
        krylov.last_sort = None;
        return Some(false);
    }
    if dual.is_matrix_free() {
        krylov.settle(sort_key(&red, dual.d));
        // The products of this step read and give only the rows of the
        // reduced unknowns and of the explicit part: narrowed to them (where
        // their DOFs' paths hold few of L's entries; Coulomb's open contacts
        // leave the reduced system).
        let rows = &mut krylov.rows;
        rows.clear();
        for u in &red {
            rows.extend(u.dir[..u.n_dir].iter().map(|&(j, _)| j));
            rows.extend(u.test[..u.n_test].iter().map(|&(j, _)| j));
        }
        rows.extend((0..dual.c).filter(|&j| step[j] != 0.0));
        rows.sort_unstable();
        rows.dedup();
        let narrowed = dual.narrow_to(rows);
        if narrowed {
            krylov.narrowed += 1;
        }
        // The fixed components' part of the right-hand side, to the accuracy
        // the reduced solve asks for.
        dual.apply_narrow(step, ae0, krylov.rough());
        let solved = krylov_step(problem, &red, step, ae0, krylov, !narrowed);
        dual.widen();
        return solved;
    }
    dual.apply(step, ae0);
    // Test and direction vectors equal (every unknown but a Coulomb normal that
    // drags its slip force): M is symmetric, positive definite unless A is singular.
    let coupled: Vec<bool> = red.iter().map(|u| u.n_dir > u.n_test).collect();
    let symmetric = !coupled.iter().any(|&b| b);
    // The forcing term where GMRES solves (module docs); a symmetric
    // system, or a step solved again exactly, to the backward error of a
    // solve in double.
    let eta = if symmetric || krylov.exact {
        0.0
    } else {
        krylov.eta
    };
    krylov.inexact_dense = eta > 0.0;
    // A's inverse preconditions the reduced system through Z of order
    // q = (c - k) + s (`dense::Complement`) where that is at most half of
    // k: Z's factor then costs at most an eighth of the system's own, and
    // M is never assembled (each product is one with A). It is made once
    // per A, before any k x k work space is held.
    let slipping = red.iter().filter(|u| u.diag > 0.0).count();
    let q = dual.c - k + slipping;
    if krylov.inverse
        && k >= MIXED_MIN
        && 2 * q <= k
        && let Some(inv) = dual.inverse(true)
    {
        let rhs: Vec<f64> = red.iter().map(|u| u.rhs_after(ae0)).collect();
        if let Some(z) = solve_on_inverse(dual, &inv, &red, &rhs, symmetric, eta) {
            krylov.on_inverse += 1;
            add_directions(&red, z, step);
            return Some(false);
        }
    }
    // M = T^T A V + diag, column by column: column l is the sum over the entries of
    // dir_l of coef times T^T A[:, j], gathered from one column of A.
    let _mat_claim = dual.ledger.claim_f64(k * k);
    // Where the allocator refuses the k x k system the step fails as a singular
    // one does (the fallback sweeps take over) instead of aborting the host.
    let Ok(mut mat) = crate::memory::try_mat::<f64>(k, k, "") else {
        return None;
    };
    let mut rhs = Mat::<f64>::zeros(k, 1);
    // Each row's test vector as two (index, coefficient) entries, the second
    // (0, 0.0) where there is one: the gathers below run without branches.
    let tests: Vec<[(usize, f64); 2]> = red
        .iter()
        .map(|u| [u.test[0], if u.n_test > 1 { u.test[1] } else { (0, 0.0) }])
        .collect();
    for (l, u) in red.iter().enumerate() {
        let col = mat
            .col_mut(l)
            .try_as_col_major_mut()
            .expect("contiguous")
            .as_slice_mut();
        for &(jd, cd) in &u.dir[..u.n_dir] {
            let a = dual.col(jd);
            for (x, &[(i0, c0), (i1, c1)]) in col.iter_mut().zip(&tests) {
                *x += cd * (c0 * a[i0] + c1 * a[i1]);
            }
        }
        col[l] += u.diag;
        rhs[(l, 0)] = u.rhs_after(ae0);
    }
    // Where M is not symmetric, M's symmetric part S = W^T A W + diag (each
    // direction cut to its test vector), positive definite as M is where every unknown is
    // symmetric: its lower entries for the preconditioner of M's solve. A
    // column without a coupling is S's column; a coupled column's row that
    // is not coupled is S's by symmetry; where both are, from A.
    let (a_all, c) = (&dual.a[..], dual.c);
    let sym_entry = |i: usize, j: usize| -> f64 {
        if !coupled[j] {
            mat[(i, j)]
        } else if !coupled[i] {
            mat[(j, i)]
        } else {
            let (ui, uj) = (&red[i], &red[j]);
            let mut s = if i == j { uj.diag } else { 0.0 };
            for &(jd, cd) in &uj.test[..uj.n_test] {
                let a = &a_all[jd * c..(jd + 1) * c];
                s += cd
                    * ui.test[..ui.n_test]
                        .iter()
                        .map(|&(jt, ct)| ct * a[jt])
                        .sum::<f64>();
            }
            s
        }
    };
    let key: Vec<usize> = red.iter().map(|u| 4 * u.test[0].0 + u.n_test).collect();
    let how = Reduce {
        sym_part: (!symmetric).then_some(&sym_entry as &(dyn Fn(usize, usize) -> f64 + Sync)),
        eta,
        key,
        reused,
    };
    let z = solve_reduced(&mat, &rhs, how, &dual.threads, &dual.ledger)?;
    add_directions(&red, z.col(0).iter().copied(), step);
    Some(false)
}
