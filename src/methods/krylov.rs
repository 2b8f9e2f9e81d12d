//! Krylov solvers for Newton's reduced systems on a matrix-free dual
//! (`newton.rs`): preconditioned conjugate gradients where the system is
//! symmetric (Tresca, and Coulomb contacts whose normal force does not drag a
//! slip force), restarted flexible GMRES with right preconditioning otherwise. Both take
//! the operator as a closure (one product with A each) and the preconditioner
//! as another (y := P x, P symmetric positive definite), stop at |M z - rhs| <= eta |rhs| or after `max_it` products,
//! and return the products used; None when the iteration broke down (a
//! non-finite value, or CG meeting a direction of non-positive curvature).
//! Both tell a third closure how z is made of the operator's inputs
//! (`made(i, coef)`: z += coef x_i, x_i the input of the solve's product i,
//! counted from 0), so that a caller whose products give more than M x
//! (Newton's give A V x on every component) can combine those into the
//! same function of z without another product.

/// Restart length of GMRES.
pub(super) const RESTART: usize = 40;

/// The signature [`pcg`] and [`gmres`] share: (op, rhs, pre, eta, max_it, z,
/// made) -> the products used.
pub(super) type Solver = fn(
    &mut dyn FnMut(&[f64], &mut [f64]),
    &[f64],
    &mut dyn FnMut(&[f64], &mut [f64]),
    f64,
    usize,
    &mut [f64],
    &mut dyn FnMut(usize, f64),
) -> Option<usize>;

/// z := approximately M^-1 rhs by preconditioned CG from z = 0 (`pre`: y := P x,
/// P ~ M^-1). `made(i, alpha)` follows each update z += alpha p, p the
/// input of product i.
pub(super) fn pcg(
    op: &mut dyn FnMut(&[f64], &mut [f64]),
    rhs: &[f64],
    pre: &mut dyn FnMut(&[f64], &mut [f64]),
    eta: f64,
    max_it: usize,
    z: &mut [f64],
    made: &mut dyn FnMut(usize, f64),
) -> Option<usize> {
    let k = rhs.len();
    z.iter_mut().for_each(|v| *v = 0.0);
    let mut r = rhs.to_vec();
    let stop = eta * norm(rhs);
    let mut y = vec![0.0; k];
    pre(&r, &mut y);
    let mut p = y.clone();
    let mut q = vec![0.0; k];
    let mut ry = dot(&r, &y);
    let mut its = 0;
    while its < max_it && norm(&r) > stop {
        op(&p, &mut q);
        its += 1;
        let pq = dot(&p, &q);
        // Non-positive curvature (or NaN): M is not positive definite here.
        if pq.is_nan() || pq <= 0.0 {
            return (its > 1 && z.iter().all(|v| v.is_finite())).then_some(its);
        }
        let alpha = ry / pq;
        for j in 0..k {
            z[j] += alpha * p[j];
            r[j] -= alpha * q[j];
        }
        made(its - 1, alpha);
        pre(&r, &mut y);
        let ry_next = dot(&r, &y);
        let beta = ry_next / ry;
        ry = ry_next;
        for j in 0..k {
            p[j] = y[j] + beta * p[j];
        }
    }
    z.iter().all(|v| v.is_finite()).then_some(its)
}

/// The relative residual below which GMRES confirms a met target with one
/// product (see [`gmres`]): the rounding of products in single precision
/// (newton.rs's rough ones), about 1e-7 times the conditioning they see,
/// stays well below the looser targets (the rough solves of newton.rs ask
/// for 1e-4 at the tightest).
pub(super) const CONFIRM_BELOW: f64 = 1e-4;

/// z := approximately M^-1 rhs by GMRES(RESTART) with right preconditioning
/// M P x = rhs, z = P x, from z = 0 (`pre`: y := P x), in its flexible form:
/// the preconditioned vectors t_l = P v_l are kept, and a cycle adds
/// sum_l y_l t_l to z, the very vectors its products were taken of (`made(i,
/// y_l)` for each, i the product t_l went into). So the cycle's residual
/// estimate is that of z even where `pre` is not linear to the last digit
/// (single precision), and z is the combination `made` reports. A cycle whose own
/// residual estimate meets eta |rhs| ends the solve without a product to
/// confirm it where eta >= CONFIRM_BELOW; a tighter one is confirmed on the
/// true residual, and a restart begins from there. The products used, None
/// on a breakdown.
pub(super) fn gmres(
    op: &mut dyn FnMut(&[f64], &mut [f64]),
    rhs: &[f64],
    pre: &mut dyn FnMut(&[f64], &mut [f64]),
    eta: f64,
    max_it: usize,
    z: &mut [f64],
    made: &mut dyn FnMut(usize, f64),
) -> Option<usize> {
    let k = rhs.len();
    z.iter_mut().for_each(|v| *v = 0.0);
    let stop = eta * norm(rhs);
    // The Krylov basis, RESTART + 1 vectors of length k, column by column;
    // the preconditioned vectors t_l = P v_l and the product each went into.
    let mut basis = vec![0.0; (RESTART + 1) * k];
    let mut pbasis = vec![0.0; RESTART * k];
    let mut product = [0usize; RESTART];
    let ld = RESTART + 1;
    let mut h = vec![0.0; ld * RESTART];
    let (mut cs, mut sn, mut g) = (vec![0.0; RESTART], vec![0.0; RESTART], vec![0.0; ld]);
    let mut r = vec![0.0; k];
    let mut its = 0;
    let mut first = true;
    loop {
        // r = rhs - M z (rhs itself in the first cycle, from z = 0).
        if first {
            r.copy_from_slice(rhs);
            first = false;
        } else {
            op(z, &mut r);
            its += 1;
            for j in 0..k {
                r[j] = rhs[j] - r[j];
            }
        }
        let beta = norm(&r);
        if !beta.is_finite() {
            return None;
        }
        if beta <= stop || its >= max_it {
            return Some(its);
        }
        for j in 0..k {
            basis[j] = r[j] / beta;
        }
        g.iter_mut().for_each(|v| *v = 0.0);
        g[0] = beta;
        let mut used = 0;
        // Whether the cycle met the target by its own residual estimate
        // |g[col + 1]|: the residual of the z it makes from the kept t_l,
        // whatever `pre` did, up to the products' rounding.
        let mut met = false;
        for col in 0..RESTART {
            let t = &mut pbasis[col * k..(col + 1) * k];
            pre(&basis[col * k..(col + 1) * k], t);
            let (done, next) = basis.split_at_mut((col + 1) * k);
            let w = &mut next[..k];
            op(t, w);
            product[col] = its;
            its += 1;
            // Modified Gram-Schmidt against the basis so far.
            for i in 0..=col {
                let v = &done[i * k..(i + 1) * k];
                let hij = dot(w, v);
                h[i + col * ld] = hij;
                for j in 0..k {
                    w[j] -= hij * v[j];
                }
            }
            let hn = norm(w);
            h[col + 1 + col * ld] = hn;
            // Apply the previous rotations, then a new one.
            for i in 0..col {
                let (a, b) = (h[i + col * ld], h[i + 1 + col * ld]);
                h[i + col * ld] = cs[i] * a + sn[i] * b;
                h[i + 1 + col * ld] = -sn[i] * a + cs[i] * b;
            }
            let (a, b) = (h[col + col * ld], h[col + 1 + col * ld]);
            let rr = a.hypot(b);
            if rr == 0.0 || !rr.is_finite() {
                break;
            }
            cs[col] = a / rr;
            sn[col] = b / rr;
            h[col + col * ld] = rr;
            h[col + 1 + col * ld] = 0.0;
            g[col + 1] = -sn[col] * g[col];
            g[col] *= cs[col];
            used = col + 1;
            met = g[col + 1].abs() <= stop || hn == 0.0;
            if met || its >= max_it {
                break;
            }
            w.iter_mut().for_each(|v| *v /= hn);
        }
        if used == 0 {
            return None;
        }
        // Back substitution for y (in g), then z += sum_l y_l t_l.
        for i in (0..used).rev() {
            let mut s = g[i];
            for l in i + 1..used {
                s -= h[i + l * ld] * g[l];
            }
            g[i] = s / h[i + i * ld];
        }
        // z += sum_l y_l t_l.
        for l in 0..used {
            let t = &pbasis[l * k..(l + 1) * k];
            for j in 0..k {
                z[j] += g[l] * t[j];
            }
            made(product[l], g[l]);
        }
        if !z.iter().all(|v| v.is_finite()) {
            return None;
        }
        // Met within a loose target: no product to confirm it (one of the
        // 3-6 a loose Newton step's solve takes; the step is judged by the
        // backtracking's |F|, a refinement round by its exact residual). A
        // tight target is confirmed on the true residual, since the
        // products' rounding can stand between the estimate and it.
        if (met && eta >= CONFIRM_BELOW) || its >= max_it {
            return Some(its);
        }
        // Next cycle (or the confirmation): from the true residual.
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tridiagonal test matrix: 4 on the diagonal, -1 and `skew` -1 beside it.
    fn tridiag(k: usize, skew: f64) -> impl FnMut(&[f64], &mut [f64]) {
        move |x: &[f64], y: &mut [f64]| {
            for i in 0..k {
                let mut s = (4.0 + i as f64 * 0.01) * x[i];
                if i > 0 {
                    s -= (1.0 + skew) * x[i - 1];
                }
                if i + 1 < k {
                    s -= x[i + 1];
                }
                y[i] = s;
            }
        }
    }

    fn residual(op: &mut dyn FnMut(&[f64], &mut [f64]), z: &[f64], rhs: &[f64]) -> f64 {
        let mut y = vec![0.0; z.len()];
        op(z, &mut y);
        norm(&y.iter().zip(rhs).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(rhs)
    }

    /// The tests' right-hand side of length k.
    fn rhs_of(k: usize) -> Vec<f64> {
        (0..k).map(|i| (i as f64 * 0.37).sin() + 0.1).collect()
    }

    /// Jacobi on `tridiag`'s diagonal.
    fn jacobi(x: &[f64], y: &mut [f64]) {
        for (i, (yi, xi)) in y.iter_mut().zip(x).enumerate() {
            *yi = xi / (4.0 + i as f64 * 0.01);
        }
    }

    /// `jacobi` rounded to single precision (as the layered Dirichlet
    /// preconditioner is): not linear to 1e-7.
    fn jacobi_single(x: &[f64], y: &mut [f64]) {
        jacobi(x, y);
        y.iter_mut().for_each(|v| *v = f64::from(*v as f32));
    }

    #[test]
    fn cg_and_gmres_solve_to_the_requested_residual() {
        let k = 200;
        let rhs = rhs_of(k);
        let mut pre = jacobi;
        let mut z = vec![0.0; k];
        let mut sym = tridiag(k, 0.0);
        let its = pcg(&mut sym, &rhs, &mut pre, 1e-12, 500, &mut z, &mut |_, _| {}).unwrap();
        assert!(residual(&mut sym, &z, &rhs) <= 1e-12, "cg");
        assert!(its < 100, "{its}");
        // Nonsymmetric: GMRES, across restarts (RESTART < iterations needed at
        // 1e-13 only when the matrix is harder; here one cycle may do).
        let mut skew = tridiag(k, 0.5);
        let its = gmres(
            &mut skew,
            &rhs,
            &mut pre,
            1e-13,
            500,
            &mut z,
            &mut |_, _| {},
        )
        .unwrap();
        assert!(residual(&mut skew, &z, &rhs) <= 1e-13, "gmres");
        assert!(its < 200, "{its}");
        // A loose eta stops early.
        let its_loose =
            gmres(&mut skew, &rhs, &mut pre, 1e-2, 500, &mut z, &mut |_, _| {}).unwrap();
        assert!(its_loose < its);
        assert!(residual(&mut skew, &z, &rhs) <= 1e-2);
    }

    #[test]
    fn gmres_confirms_only_a_tight_target() {
        // Three distinct eigenvalues: the Krylov space of any right-hand side
        // holds the exact solution after three products.
        let k = 30;
        let eig = |i: usize| [1.0, 2.5, 7.0][i % 3];
        let calls = std::cell::Cell::new(0);
        let mut op = |x: &[f64], y: &mut [f64]| {
            calls.set(calls.get() + 1);
            for i in 0..k {
                y[i] = eig(i) * x[i];
            }
        };
        let mut pre = |x: &[f64], y: &mut [f64]| y.copy_from_slice(x);
        let rhs: Vec<f64> = (0..k).map(|i| 1.0 + (i as f64 * 0.7).cos()).collect();
        // Tight: the three products, then one to confirm on the true residual.
        let mut z = vec![0.0; k];
        let its = gmres(&mut op, &rhs, &mut pre, 1e-12, 100, &mut z, &mut |_, _| {}).unwrap();
        assert_eq!((its, calls.get()), (4, 4));
        for i in 0..k {
            assert!(
                (z[i] - rhs[i] / eig(i)).abs() <= 1e-12 * rhs[i].abs(),
                "{i}"
            );
        }
        // Loose (0.5): one product leaves more than half the residual, two
        // meet it, and the solve spends exactly those two (it took a third
        // to confirm before).
        let residual_after = |z: &[f64]| {
            let mut az = vec![0.0; k];
            for i in 0..k {
                az[i] = eig(i) * z[i];
            }
            norm(&az.iter().zip(&rhs).map(|(a, b)| a - b).collect::<Vec<_>>())
        };
        let mut one = vec![0.0; k];
        gmres(&mut op, &rhs, &mut pre, 0.5, 1, &mut one, &mut |_, _| {}).unwrap();
        assert!(residual_after(&one) > 0.5 * norm(&rhs));
        calls.set(0);
        let its = gmres(&mut op, &rhs, &mut pre, 0.5, 100, &mut z, &mut |_, _| {}).unwrap();
        assert_eq!((its, calls.get()), (2, 2));
        assert!(residual_after(&z) <= 0.5 * norm(&rhs));
    }

    /// A preconditioner in single precision (as the layered Dirichlet one is)
    /// is not linear to 1e-7: flexible GMRES keeps the vectors it gave, so
    /// the cycle's residual estimate stays that of z, and a tight target is
    /// met on the true residual (which GMRES confirms before it stops).
    #[test]
    fn gmres_meets_a_tight_target_under_a_single_precision_preconditioner() {
        let k = 200;
        let rhs = rhs_of(k);
        let mut pre = jacobi_single;
        let mut skew = tridiag(k, 0.5);
        for eta in [1e-8, 1e-10, 1e-12] {
            let mut z = vec![0.0; k];
            gmres(&mut skew, &rhs, &mut pre, eta, 500, &mut z, &mut |_, _| {}).unwrap();
            let r = residual(&mut skew, &z, &rhs);
            assert!(r <= eta, "eta {eta:.0e}: true residual {r:.2e}");
        }
    }

    /// `made` reports z as a combination of the products' inputs, for CG and
    /// for GMRES across restarts and under a preconditioner in single
    /// precision: sum coef x_i equals z to rounding.
    #[test]
    fn made_reports_z_from_the_products_inputs() {
        let k = 120;
        let rhs = rhs_of(k);
        let mut pre = jacobi_single;
        for (skew, solver) in [(0.0, pcg as Solver), (0.5, gmres), (0.9, gmres)] {
            let inputs = std::cell::RefCell::new(Vec::<Vec<f64>>::new());
            let mut m = tridiag(k, skew);
            let mut op = |x: &[f64], y: &mut [f64]| {
                inputs.borrow_mut().push(x.to_vec());
                m(x, y);
            };
            let mut sum = vec![0.0; k];
            let mut made = |i: usize, coef: f64| {
                for (s, x) in sum.iter_mut().zip(&inputs.borrow()[i]) {
                    *s += coef * x;
                }
            };
            let mut z = vec![0.0; k];
            let its = solver(&mut op, &rhs, &mut pre, 1e-13, 500, &mut z, &mut made).unwrap();
            assert_eq!(its, inputs.borrow().len());
            let scale = norm(&z);
            for j in 0..k {
                assert!((sum[j] - z[j]).abs() <= 1e-13 * scale, "skew {skew}, {j}");
            }
            // Across restarts where the skew is large.
            if skew == 0.9 {
                assert!(its > RESTART, "{its}");
            }
        }
    }
}
