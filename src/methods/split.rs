//! N. Pop's dual splitting (design.md section 3) and the plain block Gauss-Seidel
//! variant: the tangential and the normal multipliers are solved in alternation,
//! each sub-problem by projected Gauss-Seidel.
//!
//! Schur variant, one outer iteration:
//! 1. tangential step on S = A22 - A21[:,a] A11[a,a]^-1 A12[a,:] with
//!    b_T' = b_T - A21[:,a] A11[a,a]^-1 b_N[a], a the contacts with lambda_N > 0
//!    (all of them at the start), bound from the previous lambda_N (Coulomb);
//! 2. normal step on A11 with b_N - A12 lambda_T, lambda_N >= 0.
//!
//! The block variant uses S = A22 and b_T' = b_T - A21 lambda_N. When A11[a,a] is
//! numerically singular (redundant contacts), the Schur variant takes the block
//! step for that iteration.
//!
//! Coulomb (design.md section 3: the fixed point p = mu lambda_N folded into the
//! outer loop). For one slipping contact the outer map is
//! lambda_N <- (b_N - s mu A_NT lambda_N) / A_NN: it contracts only while
//! mu |A_NT| < A_NN, and with strong normal-tangential coupling (an inclined
//! foundation under a body compliant sideways; tests/hard_scenes.rs
//! `large_coulomb_friction_fixed_point_does_not_contract`, A_NT / A_NN = 4 to 5.8)
//! it cycles for every mu >= 1. The outer loop is therefore relaxed by Aitken's
//! factor ([`Aitken`]; 1, the plain iteration, while the map does not oscillate):
//! the Schur variant, whose tangential step already carries the normal response of
//! the active set, relaxes the bound, p_k = p_k-1 + omega (mu lambda_N - p_k-1);
//! the block variant, whose steps ignore that response, relaxes the whole iterate.
//! At the iteration limit the iterate with the lowest error is returned.

use super::mprgp::Scratch;
use super::pgs::{Aitken, BestIterate, SubQp};
use super::{DualProblem, Outcome};
use crate::options::Options;
use faer::linalg::matmul::matmul;
use faer::prelude::Solve;
use faer::{Accum, Mat, Par, Side};

/// The Schur complement data of one contact set.
struct Schur {
    active: Vec<bool>,
    s: Vec<f64>,
    /// b_T - A21[:,a] A11[a,a]^-1 b_N[a].
    q: Vec<f64>,
}

/// Builds S and b_T' for the contact set `active`; None when A11[a,a] is not
/// numerically positive definite.
fn schur(problem: &DualProblem<'_>, active: &[bool]) -> Option<Schur> {
    let dual = problem.dual;
    let (m, c) = (dual.m, dual.c);
    let ct = c - m;
    let idx: Vec<usize> = (0..m).filter(|&i| active[i]).collect();
    let na = idx.len();
    let a11 = Mat::from_fn(na, na, |r, s| dual.a[idx[r] + idx[s] * c]);
    // Columns: A12[a,:] (ct columns) then b_N[a].
    let rhs = Mat::from_fn(na, ct + 1, |r, s| {
        if s < ct {
            dual.a[idx[r] + (m + s) * c]
        } else {
            problem.b[idx[r]]
        }
    });
    let x = if na > 0 {
        let llt = a11.llt(Side::Lower).ok()?;
        let x = llt.solve(&rhs);
        if !x.as_ref().is_all_finite() {
            return None;
        }
        x
    } else {
        rhs.clone()
    };
    // [S, b_T'] = [A22, b_T] - A21[:,a] [X, y] with one matrix product.
    let mut sq = Mat::from_fn(ct, ct + 1, |i, j| {
        if j < ct {
            dual.a[(m + i) + (m + j) * c]
        } else {
            problem.b[m + i]
        }
    });
    if na > 0 {
        matmul(
            sq.as_mut(),
            Accum::Add,
            rhs.subcols(0, ct).transpose(),
            x.as_ref(),
            -1.0,
            Par::Seq,
        );
    }
    let mut s = vec![0.0; ct * ct];
    for j in 0..ct {
        for i in 0..ct {
            s[i + j * ct] = sq[(i, j)];
        }
    }
    let q: Vec<f64> = (0..ct).map(|i| sq[(i, ct)]).collect();
    // Exact symmetry for the Gauss-Seidel sweeps.
    for j in 0..ct {
        for i in 0..j {
            let v = 0.5 * (s[i + j * ct] + s[j + i * ct]);
            s[i + j * ct] = v;
            s[j + i * ct] = v;
        }
    }
    Some(Schur {
        active: active.to_vec(),
        s,
        q,
    })
}

/// Runs the splitting from `lam`; `use_schur` selects Pop's Schur variant.
pub(super) fn solve(
    problem: &DualProblem<'_>,
    lam: &mut [f64],
    opts: &Options,
    target: f64,
    use_schur: bool,
    mprgp: bool,
) -> Outcome {
    let dual = problem.dual;
    let (m, d, c) = (dual.m, dual.d, dual.c);
    let ct = c - m;
    let inner_tol = 0.1 * target;
    let mut out = Outcome::default();
    let mut w = vec![0.0; c];
    let mut p = vec![0.0; m];
    let mut v = vec![0.0; c];
    // Sub-problem work space, and MPRGP's estimates of |A_NN| (fixed) and of the
    // tangential matrix's norm (reset when that matrix changes).
    let mut scratch = Scratch::new(m.max(ct));
    let mut norm_n = None;
    let mut norm_t = None;
    let mut norm_t_of_schur = false;
    let mut qn = vec![0.0; m];
    let mut qt = vec![0.0; ct];
    let normal_step =
        |lam: &mut [f64], qn: &mut [f64], scratch: &mut Scratch, norm: &mut Option<f64>| {
            // q_N = b_N - A12 lambda_T
            qn.copy_from_slice(&problem.b[..m]);
            for j in 0..ct {
                let lt = lam[m + j];
                if lt != 0.0 {
                    let col = &dual.col(m + j)[..m];
                    qn.iter_mut().zip(col).for_each(|(q, a)| *q -= a * lt);
                }
            }
            let sub = SubQp {
                h: &dual.a,
                ld: c,
                k: m,
                q: qn,
                block: 1,
                radii: None,
            };
            sub.solve_with(
                mprgp,
                &mut lam[..m],
                scratch,
                norm,
                inner_tol,
                opts.max_inner,
            )
        };
    // Start: lambda_N of the frictionless problem unless warm-started.
    if lam.iter().all(|&x| x == 0.0)
        && out.add_inner(normal_step(lam, &mut qn, &mut scratch, &mut norm_n))
    {
        return out;
    }
    let mut cache: Option<Schur> = None;
    let mut active = vec![true; m];
    // Coulomb: the Schur variant relaxes the bound p, the block variant the whole
    // iterate (module documentation).
    let coulomb = matches!(problem.law, super::Law::Coulomb(_));
    let relaxed = match (coulomb, use_schur) {
        (false, _) => 0,
        (true, true) => m,
        (true, false) => c,
    };
    let mut relax = Aitken::new(relaxed);
    // The bound of the last tangential step (Schur variant) or the last iterate.
    let mut prev = vec![0.0; relaxed];
    if coulomb && use_schur {
        problem.law.bounds(&lam[..m], &mut prev);
    }
    let mut best = BestIterate::new(c);
    loop {
        problem.gradient(lam, &mut w);
        out.dual_err = problem.error(lam, &w, &mut p, &mut v);
        best.offer(lam, out.dual_err);
        if problem.should_stop(&mut out, lam, &p, &v, target, opts) {
            best.restore_at_limit(lam, &mut out, target);
            return out;
        }
        // Tangential step. Coulomb: the bound p = mu lambda_N of the last normal
        // step, relaxed in the Schur variant: p_k = p_k-1 + omega (mu lambda_N - p_k-1).
        problem.law.bounds(&lam[..m], &mut p);
        if coulomb {
            if use_schur {
                relax.relax_bound(&mut prev, &mut p, out.outer == 0);
            } else {
                prev.copy_from_slice(lam);
            }
        }
        if ct > 0 {
            if use_schur && cache.as_ref().is_none_or(|s| s.active != active) {
                cache = schur(problem, &active);
                norm_t = None;
            }
            // The tangential matrix is the cached Schur complement or A22.
            let of_schur = use_schur && cache.is_some();
            if of_schur != norm_t_of_schur {
                norm_t = None;
                norm_t_of_schur = of_schur;
            }
            let sub = match (&cache, use_schur) {
                (Some(sc), true) => SubQp {
                    h: &sc.s,
                    ld: ct,
                    k: ct,
                    q: &sc.q,
                    block: d - 1,
                    radii: Some(&p),
                },
                _ => {
                    // q_T = b_T - A21 lambda_N
                    qt.copy_from_slice(&problem.b[m..]);
                    for (i, &ln) in lam[..m].iter().enumerate() {
                        if ln != 0.0 {
                            let col = &dual.col(i)[m..];
                            qt.iter_mut().zip(col).for_each(|(q, a)| *q -= a * ln);
                        }
                    }
                    SubQp {
                        h: &dual.a[m + m * c..],
                        ld: c,
                        k: ct,
                        q: &qt,
                        block: d - 1,
                        radii: Some(&p),
                    }
                }
            };
            let run = sub.solve_with(
                mprgp,
                &mut lam[m..],
                &mut scratch,
                &mut norm_t,
                inner_tol,
                opts.max_inner,
            );
            if out.add_inner(run) {
                return out;
            }
        }
        // Normal step.
        if out.add_inner(normal_step(lam, &mut qn, &mut scratch, &mut norm_n)) {
            return out;
        }
        if coulomb && !use_schur {
            relax.relax(&prev, lam);
        }
        for (a, &ln) in active.iter_mut().zip(&lam[..m]) {
            *a = ln > 0.0;
        }
        out.outer += 1;
    }
}
