//! Unit tests of Newton's pieces and of its outer loop.
use super::*;
use crate::friction::Friction;
use crate::options::{Method, Options};
use crate::problem::ContactProblem;
use crate::sparse::Csc;
use crate::test_scenes::{lattice, slab_contacts};

/// The 2D strip of `crate::problem::tests::strip` (`nodes` contact nodes,
/// N = -e_y, T = e_x, gap 1e-3 (i - c)^2 / c^2 around the centre c) in the
/// default dual form, pressed down by `press` and sheared by `shear`
/// through the top ([`rhs`]), and its gaps.
fn strip(nodes: usize) -> (ContactProblem, Vec<f64>) {
    crate::problem::tests::strip(nodes, crate::options::DualForm::Auto)
}

/// b = B K^-1 f - [g; 0] of the strip under the top's load.
fn rhs(pb: &ContactProblem, g: &[f64], press: f64, shear: f64) -> Vec<f64> {
    let nodes = g.len();
    let mut u0: Vec<f64> = (0..2 * nodes)
        .map(|j| if j % 2 == 0 { 0.3 * shear } else { -press })
        .collect();
    pb.factor().solve_vec(&mut u0);
    let mut b = vec![0.0; 2 * nodes];
    pb.dual().rows.mul_vec(&u0, &mut b);
    for (bi, gi) in b.iter_mut().zip(g) {
        *bi -= gi;
    }
    b
}

/// Newton without its Gauss-Seidel warm-up from `lam`: the outer iterations.
fn newton_steps(
    pb: &ContactProblem,
    b: &[f64],
    mu: &[f64],
    lam: &mut [f64],
    warm_sort: bool,
) -> usize {
    let (out, _) = drive_newton(pb.dual(), b, Friction::Coulomb(mu), lam, |n| {
        n.presweeps = 0;
        n.warm_sort = warm_sort;
    });
    out.outer
}

#[test]
fn the_warm_start_sorts_by_the_multipliers_and_saves_newton_steps() {
    // A history step: the converged multipliers of one load, then the load
    // raised by 5 %. From the same starting iterate, the first step sorted by
    // the multipliers (the warm start) needs fewer Newton steps than the first
    // step sorted by the natural map at that iterate, where the load change
    // with the forces frozen makes the contacts look like slipping.
    let (pb, g) = strip(41);
    let mu = vec![0.3; 41];
    let (press, shear) = (4e-3, 3e-3);
    let b1 = rhs(&pb, &g, press, shear);
    let mut lam1 = vec![0.0; 82];
    newton_steps(&pb, &b1, &mu, &mut lam1, true);
    // Mostly sticking, two contacts slipping (at mu = 0.3, shear 3e-3).
    let slipping = (0..41)
        .filter(|&i| lam1[41 + i].abs() >= (1.0 - 1e-9) * 0.3 * lam1[i])
        .count();
    assert!((1..41).contains(&slipping), "{slipping} slipping");
    let b2 = rhs(&pb, &g, 1.05 * press, 1.05 * shear);
    let (mut warm, mut cold) = (lam1.clone(), lam1.clone());
    let with_sort = newton_steps(&pb, &b2, &mu, &mut warm, true);
    let without = newton_steps(&pb, &b2, &mu, &mut cold, false);
    println!(
        "warm step: {with_sort} Newton steps sorted by the multipliers, {without} by the \
         natural map"
    );
    assert!(with_sort < without, "{with_sort} vs {without}");
    assert!(with_sort <= 2, "{with_sort}");
}

/// `refine` against an operator whose single-precision products err by
/// `rough_error` (relative, a fixed non-symmetric perturbation): with
/// 1e-7 it reaches eta = 1e-12 on the exact residual with most products
/// rough; with 0.9 (single precision useless) it falls back to exact
/// products and still reaches it.
#[test]
fn refinement_reaches_the_exact_residual_with_rough_products() {
    let k = 300;
    let exact = |x: &[f64], y: &mut [f64]| {
        for i in 0..k {
            let mut s = (4.0 + 0.01 * i as f64) * x[i];
            if i > 0 {
                s -= x[i - 1];
            }
            if i + 1 < k {
                s -= x[i + 1];
            }
            y[i] = s;
        }
    };
    let rhs: Vec<f64> = (0..k).map(|i| (0.3 * i as f64).cos() + 0.2).collect();
    for (rough_error, most_rough) in [(1e-7, true), (0.9, false)] {
        for solver in [
            super::super::krylov::pcg as super::super::krylov::Solver,
            super::super::krylov::gmres,
        ] {
            let rough = std::cell::Cell::new(false);
            let (mut n_rough, mut n_exact) = (0, 0);
            let mut op = |x: &[f64], y: &mut [f64]| {
                exact(x, y);
                if rough.get() {
                    n_rough += 1;
                    let scale = norm(y) * rough_error / (k as f64).sqrt();
                    for (i, v) in y.iter_mut().enumerate() {
                        *v += scale * ((i * 7 % 13) as f64 / 6.0 - 1.0);
                    }
                } else {
                    n_exact += 1;
                }
            };
            let mut pre = |x: &[f64], y: &mut [f64]| y.copy_from_slice(x);
            let mut z = vec![0.0; k];
            let its = refine(solver, &mut op, &rough, &rhs, &mut pre, 1e-12, 500, &mut z)
                .expect("no breakdown");
            assert_eq!(its, n_rough + n_exact);
            let mut mz = vec![0.0; k];
            exact(&z, &mut mz);
            let r: Vec<f64> = mz.iter().zip(&rhs).map(|(a, b)| a - b).collect();
            assert!(
                norm(&r) <= 1e-12 * norm(&rhs),
                "{rough_error}: {}",
                norm(&r)
            );
            println!("rough error {rough_error}: {n_rough} rough, {n_exact} exact products");
            if most_rough {
                assert!(n_rough > 2 * n_exact, "{n_rough} rough, {n_exact} exact");
            }
        }
    }
}

/// Newton's warm-up sweeps read A in single precision: from the same
/// start they follow the exact sweeps to rounding, their w drifts from
/// A lam - b by rounding only, and the copy is on the ledger while it lives.
#[test]
fn rough_sweeps_follow_the_exact_ones() {
    let (pb, g) = strip(41);
    let p = vec![2e-3; 41];
    let b = rhs(&pb, &g, 4e-3, 3e-3);
    let problem = plain(pb.dual(), &b, Friction::Tresca(&p));
    let c = problem.dual.c;
    let (mut lam_exact, mut w_exact) = (vec![0.0; c], vec![0.0; c]);
    problem.gradient(&lam_exact, &mut w_exact);
    let (mut lam, mut w) = (lam_exact.clone(), w_exact.clone());
    let mut pgs = crate::methods::pgs::Pgs::new(&problem);
    let mut inner = 0;
    for k in 0..30 {
        pgs.step(&problem, &mut lam_exact, &mut w_exact, &mut inner, k);
    }
    let ledger = problem.dual.ledger.clone();
    let live = ledger.live();
    let mut rough = sweeps::Rough::new(problem.dual);
    assert_eq!(ledger.live(), live + c * c * 4);
    assert_eq!(
        sweeps::rough_sweeps(&problem, &mut rough, &mut lam, &mut w, 30),
        30
    );
    drop(rough);
    assert_eq!(ledger.live(), live);
    let scale = norm(&lam_exact);
    assert!(scale > 0.0);
    let dl: Vec<f64> = lam.iter().zip(&lam_exact).map(|(a, b)| a - b).collect();
    assert!(norm(&dl) <= 1e-5 * scale, "{}", norm(&dl) / scale);
    let mut w_true = vec![0.0; c];
    problem.gradient(&lam, &mut w_true);
    let dw: Vec<f64> = w.iter().zip(&w_true).map(|(a, b)| a - b).collect();
    let a_max = problem.dual.a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(norm(&dw) <= 1e-6 * a_max * norm(&lam) * (c as f64).sqrt());
    assert!(norm(&dw) > 0.0, "single precision leaves some drift");
}

fn mat(rows: &[&[f64]]) -> Mat<f64> {
    Mat::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
}

#[test]
fn the_reduced_solve_takes_cholesky_lu_or_least_squares_as_the_matrix_allows() {
    let rhs = mat(&[&[1.0], &[2.0]]);
    let seq = Threads::sequential();
    fn fresh(none: &mut Option<Reused>) -> Reduce<'_> {
        Reduce {
            sym_part: None,
            eta: 0.0,
            key: Vec::new(),
            reused: none,
        }
    }
    let mut none = None;
    // SPD: Cholesky; z solves M z = rhs.
    let spd = mat(&[&[4.0, 1.0], &[1.0, 3.0]]);
    let z = solve_reduced(&spd, &rhs, fresh(&mut none), &seq, &Ledger::new()).unwrap();
    assert!((4.0 * z[(0, 0)] + z[(1, 0)] - 1.0).abs() < 1e-15);
    assert!((z[(0, 0)] + 3.0 * z[(1, 0)] - 2.0).abs() < 1e-15);
    // Symmetric but indefinite: Cholesky fails, LU solves it: z = (2, 1).
    let indef = mat(&[&[0.0, 1.0], &[1.0, 0.0]]);
    let z = solve_reduced(&indef, &rhs, fresh(&mut none), &seq, &Ledger::new()).unwrap();
    assert!((z[(0, 0)] - 2.0).abs() < 1e-15 && (z[(1, 0)] - 1.0).abs() < 1e-15);
    // Singular: the minimum-norm least-squares solution of [1 1; 1 1] z = (1, 2)
    // is z = (0.75, 0.75).
    let sing = mat(&[&[1.0, 1.0], &[1.0, 1.0]]);
    let z = solve_reduced(&sing, &rhs, fresh(&mut none), &seq, &Ledger::new()).unwrap();
    assert!((z[(0, 0)] - 0.75).abs() < 1e-12 && (z[(1, 0)] - 0.75).abs() < 1e-12);
}

/// A dense reduced solve keeps its single-precision factor for the next
/// step; a next step with the same unknowns, or one more and one fewer,
/// solves its own (nearby) matrix by CG on that factor, exactly, without
/// factoring again; one with other unknowns factors its own and keeps it.
#[test]
fn a_reduced_solve_with_the_same_unknowns_reuses_the_last_factor() {
    let k = MIXED_MIN + 44;
    let seq = Threads::sequential();
    let ledger = Ledger::new();
    // M0: diagonally dominant SPD; M1 = M0 + 3 w w^T; the entries as
    // functions of the unknowns' keys, so that a system on other unknowns
    // shares the entries of the unknowns it shares.
    let e0 = |a: usize, b: usize| {
        if a == b {
            4.0 + (a % 7) as f64
        } else {
            1.0 / (1.0 + (a as f64 - b as f64).abs()).powi(2)
        }
    };
    let w = |a: usize| (a as f64 * 0.3 + 0.5).sin();
    let e1 = |a: usize, b: usize| e0(a, b) + 3.0 * w(a) * w(b);
    let on = |keys: &[usize], e: &dyn Fn(usize, usize) -> f64| {
        Mat::from_fn(keys.len(), keys.len(), |i, j| e(keys[i], keys[j]))
    };
    let m0 = on(&(0..k).collect::<Vec<_>>(), &e0);
    let m1 = on(&(0..k).collect::<Vec<_>>(), &e1);
    let rhs = Mat::from_fn(k, 1, |i, _| (i as f64 * 0.7).cos());
    let key: Vec<usize> = (0..k).collect();
    let mut reused = None;
    fn how<'a>(key: &[usize], reused: &'a mut Option<Reused>) -> Reduce<'a> {
        Reduce {
            sym_part: None,
            eta: 0.0,
            key: key.to_vec(),
            reused,
        }
    }
    let check = |m: &Mat<f64>, z: &Mat<f64>| {
        let r = m * z - &rhs;
        let res = (0..k).fold(0.0f64, |a, i| a.max(r[(i, 0)].abs()));
        assert!(res <= 1e-13, "{res}");
    };
    let z = solve_reduced(&m0, &rhs, how(&key, &mut reused), &seq, &ledger).unwrap();
    check(&m0, &z);
    let first = reused.as_ref().expect("kept").llt.order();
    assert_eq!(first, k);
    assert_eq!(ledger.live(), k * k * 4, "the kept factor is claimed");
    let l00 = |r: &Option<Reused>| r.as_ref().unwrap().llt.first_entry();
    let before = l00(&reused);
    let z = solve_reduced(&m1, &rhs, how(&key, &mut reused), &seq, &ledger).unwrap();
    check(&m1, &z);
    assert_eq!(l00(&reused), before, "M1 solved on M0's factor");
    // One unknown gone, one new: still on M0's factor, bordered (the shared
    // block is M1's, far from M0's along w: Sigma is not positive definite
    // and the new unknown goes on its diagonal).
    let near: Vec<usize> = (1..=k).collect();
    let m_near = on(&near, &e1);
    let z = solve_reduced(&m_near, &rhs, how(&near, &mut reused), &seq, &ledger).unwrap();
    check(&m_near, &z);
    assert_eq!(l00(&reused), before, "bordered");
    // Other unknowns: M1 factored and kept.
    let other: Vec<usize> = (k..2 * k).collect();
    let z = solve_reduced(&m1, &rhs, how(&other, &mut reused), &seq, &ledger).unwrap();
    check(&m1, &z);
    assert_ne!(l00(&reused), before);
    assert_eq!(reused.as_ref().unwrap().key, other);
    assert_eq!(ledger.live(), k * k * 4, "one factor held at a time");
}

/// A reduced system that is not symmetric (Coulomb's normals dragging their
/// slip forces: columns of M beyond its symmetric part S) is solved by GMRES
/// on the single-precision factor of S, to the residual a double solve
/// meets; that factor is kept, and the next step's M (other couplings, the
/// same unknowns) is solved on it without a new factorisation.
#[test]
fn a_reduced_system_that_is_not_symmetric_is_solved_on_its_symmetric_part() {
    let k = MIXED_MIN + 44;
    let seq = Threads::sequential();
    let ledger = Ledger::new();
    let s = Mat::from_fn(k, k, |i, j| {
        if i == j {
            4.0 + (i % 7) as f64
        } else {
            1.0 / (1.0 + (i as f64 - j as f64).abs()).powi(2)
        }
    });
    // Six coupled columns: M = S + 0.3 (a column that is not S's).
    let coupled = |j: usize| j % 50 == 3;
    let with = |shift: f64| {
        Mat::from_fn(k, k, |i, j| {
            s[(i, j)]
                + if coupled(j) {
                    0.3 * ((i + j) as f64 * 0.11 + shift).sin()
                } else {
                    0.0
                }
        })
    };
    let (m0, m1) = (with(0.0), with(0.5));
    let sym = |i: usize, j: usize| s[(i, j)];
    let rhs = Mat::from_fn(k, 1, |i, _| (i as f64 * 0.7).cos());
    let key: Vec<usize> = (0..k).collect();
    let mut reused = None;
    let check = |m: &Mat<f64>, z: &Mat<f64>| {
        let r = m * z - &rhs;
        let res = (0..k).fold(0.0f64, |a, i| a.max(r[(i, 0)].abs()));
        assert!(res <= 1e-13, "{res}");
    };
    let how = |reused: &mut Option<Reused>| -> Option<Mat<f64>> {
        let r = Reduce {
            sym_part: Some(&sym),
            eta: 0.0,
            key: key.clone(),
            reused,
        };
        solve_reduced(&m0, &rhs, r, &seq, &ledger)
    };
    let z = how(&mut reused).unwrap();
    check(&m0, &z);
    let kept = reused.as_ref().expect("S's factor kept");
    assert_eq!(kept.llt.order(), k);
    let before = kept.llt.first_entry();
    assert_eq!(before, (s[(0, 0)] as f32).sqrt(), "the factor is S's");
    // The next step's symmetric part differs from S (one diagonal entry): a
    // new factor of it would have another first entry.
    let s1 = Mat::from_fn(k, k, |i, j| s[(i, j)] + if i + j == 0 { 1.0 } else { 0.0 });
    let m1 = Mat::from_fn(k, k, |i, j| m1[(i, j)] + s1[(i, j)] - s[(i, j)]);
    let sym1 = |i: usize, j: usize| s1[(i, j)];
    let z = solve_reduced(
        &m1,
        &rhs,
        Reduce {
            sym_part: Some(&sym1),
            eta: 0.0,
            key: key.clone(),
            reused: &mut reused,
        },
        &seq,
        &ledger,
    )
    .unwrap();
    check(&m1, &z);
    assert_eq!(
        reused.as_ref().unwrap().llt.first_entry(),
        before,
        "M1 solved on S's factor"
    );
    assert_eq!(ledger.live(), k * k * 4, "one factor held");
}

/// The lattice slab's K (anchor 0.05), its factor with METIS on one thread
/// and its bottom face's contacts ([`slab_contacts`]).
fn lattice_slab(
    nx: usize,
    ny: usize,
    nz: usize,
) -> (Csc, std::sync::Arc<crate::factor::Factor>, Csc, Csc) {
    use crate::factor::Factor;
    use crate::options::Ordering;
    use std::sync::Arc;
    let k = lattice(nx, ny, nz, 0.05);
    let (nm, tm) = slab_contacts(nx, ny, k.nrows);
    let threads = Arc::new(Threads::new(1));
    let factor = Factor::with_last(&k, &[], Ordering::Metis, threads).unwrap();
    (k, factor, nm, tm)
}

/// A matrix-free dual on `factor` (of `k`) for the contacts `nm`, `tm` (3D),
/// with the lumped preconditioner (and the layered one where it pays).
fn lumped_free(
    k: &Csc,
    factor: &std::sync::Arc<crate::factor::Factor>,
    nm: &Csc,
    tm: &Csc,
) -> crate::dual::Dual {
    use crate::dual::{Condensation, Dual};
    let mut dual = Dual::build_with(factor, nm, tm, 3, Condensation::MatrixFree).unwrap();
    dual.set_lumped(k, None);
    dual
}

/// The slab's contact-space load: the gap closed in a round central
/// patch, b_N = 0.1 - curve r^2, and a shear `shear` along x.
fn patch_load(nx: usize, ny: usize, curve: f64, shear: f64) -> Vec<f64> {
    let m = nx * ny;
    let centre = (nx as f64 - 1.0) / 2.0;
    (0..m)
        .map(|i| {
            let (x, y) = ((i % nx) as f64 - centre, (i / nx) as f64 - centre);
            0.1 - curve * (x * x + y * y)
        })
        .chain((0..2 * m).map(|r| if r % 2 == 0 { shear } else { 0.0 }))
        .collect()
}

/// Newton (target 1e-12) on `dual` from `lam`, set up by `setup`:
/// asserts that it converged; the driver's outcome and the method's state
/// (its Krylov counters).
fn drive_newton(
    dual: &crate::dual::Dual,
    b: &[f64],
    law: Friction<'_>,
    lam: &mut [f64],
    setup: impl FnOnce(&mut Newton),
) -> (super::super::driver::Outcome, Newton) {
    let problem = plain(dual, b, law);
    let mut newton = Newton::new(&problem, 1e-12);
    setup(&mut newton);
    let opts = Options {
        method: Method::Newton,
        ..Options::default()
    };
    let out = super::super::driver::drive(&problem, lam, &opts, 1e-12, &mut newton);
    assert_eq!(out.end, super::super::End::Converged, "{out:?}");
    (out, newton)
}

/// The dual problem on `dual` with load `b` and friction `law`
/// ([`DualProblem::new`]).
fn plain<'a>(dual: &'a crate::dual::Dual, b: &'a [f64], law: Friction<'a>) -> DualProblem<'a> {
    DualProblem::new(dual, b, law)
}

/// err at `lam` on a gradient computed afresh.
fn fresh_err(problem: &DualProblem<'_>, lam: &[f64]) -> f64 {
    let dual = problem.dual;
    let mut w = vec![0.0; dual.c];
    problem.gradient(lam, &mut w);
    let (mut p, mut v) = (vec![0.0; dual.m], vec![0.0; dual.c]);
    problem.error(lam, &w, &mut p, &mut v)
}

/// One Newton step at lam (w = A lam - b) with the Krylov state set by
/// `setup`: `newton_step`'s outcome, the step, what it left in `ae0` (A e0,
/// or A times the step where it combined that) and the Krylov state.
fn one_step(
    problem: &DualProblem<'_>,
    lam: &[f64],
    w: &[f64],
    cscale: f64,
    setup: impl FnOnce(&mut Krylov),
) -> (Option<bool>, Vec<f64>, Vec<f64>, Krylov) {
    let c = problem.dual.c;
    let (mut step, mut f, mut ae0) = (vec![0.0; c], vec![0.0; c], vec![0.0; c]);
    let mut krylov = Krylov::new(c);
    setup(&mut krylov);
    let out = newton_step(
        problem,
        lam,
        w,
        &mut step,
        &mut f,
        &mut ae0,
        cscale,
        &mut krylov,
        &mut None,
    );
    (out, step, ae0, krylov)
}

/// "Tresca" or "Coulomb", for the tests' messages.
fn law_name(law: Friction<'_>) -> &'static str {
    match law {
        Friction::Tresca(_) => "Tresca",
        Friction::Coulomb(_) => "Coulomb",
    }
}

/// |a - b|_2.
fn norm_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The largest entrywise difference.
fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Matrix-free Newton on a thin 3D lattice slab anchored as
/// `lattice_slab`'s, Tresca, with the layered Dirichlet preconditioner and
/// with the lumped one: both converge to dense Newton's multipliers (1e-10
/// relative); on the same reduced systems (one Newton step from each of
/// three iterates between zero and the answer, solved to 1e-10 with exact
/// products) both give the same step, the layered one with fewer products.
/// The whole solves' products are only printed: their paths part with
/// rounding (which steps backtrack, where a fallback runs), and with them
/// the products. (On a nearly floating slab, anchor 1e-4, the layered one
/// takes more products on the same systems than the lumped one: 46
/// against 42 on 16 x 16 x 4.)
#[test]
fn the_layered_dirichlet_preconditioner_saves_products() {
    use crate::dual::{Condensation, Dual};
    use crate::factor::Factor;
    use crate::options::Ordering;
    use std::sync::Arc;
    // A thin slab on its bottom face (every bottom node a contact), pressed
    // in a round patch and sheared.
    let (nx, ny, nz) = (24, 24, 4);
    let k = lattice(nx, ny, nz, 0.05);
    let m = nx * ny;
    let (nm, tm) = slab_contacts(nx, ny, k.nrows);
    let factor =
        Arc::new(Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap());
    let b = patch_load(nx, ny, 0.002, 0.01);
    let p = vec![0.05; m];
    let solve = |dual: &Dual| {
        let mut lam = vec![0.0; dual.c];
        let (out, _) = drive_newton(dual, &b, Friction::Tresca(&p), &mut lam, |_| {});
        (lam, out.inner)
    };
    let mut lumped = lumped_free(&k, &factor, &nm, &tm);
    lumped.drop_dirichlet();
    let mut layered = lumped_free(&k, &factor, &nm, &tm);
    assert!(layered.force_dirichlet(&k));
    let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    let (l_dense, _) = solve(&dense);
    let (l_lumped, its_lumped) = solve(&lumped);
    let (l_layered, its_layered) = solve(&layered);
    // Some contacts open, some closed: the active set is not trivial.
    assert!(l_dense[..m].contains(&0.0) && l_dense[..m].iter().any(|&v| v > 0.0));
    let scale = norm(&l_dense);
    for (what, l) in [("lumped", &l_lumped), ("layered", &l_layered)] {
        let diff = max_diff(l, &l_dense);
        assert!(diff <= 1e-10 * scale, "{what}: {diff:.2e}");
    }
    println!("whole solves' products: lumped {its_lumped}, layered Dirichlet {its_layered}");
    let step_products = |dual: &Dual, lam: &[f64]| {
        let problem = plain(dual, &b, Friction::Tresca(&p));
        let mut w = vec![0.0; dual.c];
        problem.gradient(lam, &mut w);
        let (solved, step, _, krylov) = one_step(&problem, lam, &w, 1.0, |krylov| {
            (krylov.exact, krylov.eta) = (true, 1e-10);
        });
        assert!(solved.is_some());
        (step, krylov.its)
    };
    let (mut sum_lumped, mut sum_layered) = (0, 0);
    for s in [0.25, 0.5, 0.9] {
        let lam: Vec<f64> = l_dense.iter().map(|v| s * v).collect();
        let (d_lumped, n_lumped) = step_products(&lumped, &lam);
        let (d_layered, n_layered) = step_products(&layered, &lam);
        let diff = max_diff(&d_lumped, &d_layered);
        assert!(diff <= 1e-7 * norm(&d_lumped), "{s}: {diff:.2e}");
        println!("from {s} of the answer: lumped {n_lumped}, layered Dirichlet {n_layered}");
        assert!(
            n_layered < n_lumped,
            "{s}: layered {n_layered}, lumped {n_lumped}"
        );
        (sum_lumped, sum_layered) = (sum_lumped + n_lumped, sum_layered + n_layered);
    }
    assert!(
        (sum_layered as f64) < 0.85 * sum_lumped as f64,
        "products: layered {sum_layered}, lumped {sum_lumped}"
    );
}

/// The A d a matrix-free reduced solve combines from its own products
/// (`krylov_step`) is A times the step it gives, against one product of
/// A with that step, within the rounding its combination gathers
/// (`Krylov::spread`, the sum of the sizes combined): 1e-13 of it with
/// exact products, 1e-5 of it with products in single precision. CG on
/// Tresca, GMRES on Coulomb (with the lumped preconditioner, and with
/// Jacobi alone, where GMRES restarts), on the nearly floating lattice
/// slab (anchor 1e-4), whose reduced systems take many products and whose
/// combinations cancel (the spread is 20-500 times |A d|). Its K is so
/// ill-conditioned that the single-precision products err by about 1e-6
/// of the spread, at ROUGH_DRIFT's estimate.
#[test]
fn the_combined_product_is_a_times_the_step() {
    use crate::dual::{Condensation, Dual};
    use crate::factor::Factor;
    use crate::options::Ordering;
    use std::sync::Arc;
    let (nx, ny, nz) = (16, 16, 4);
    let k = lattice(nx, ny, nz, 1e-4);
    let (nm, tm) = slab_contacts(nx, ny, k.nrows);
    let factor =
        Arc::new(Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap());
    let m = nx * ny;
    let jacobi = Dual::build_with(&factor, &nm, &tm, 3, Condensation::MatrixFree).unwrap();
    let lumped = lumped_free(&k, &factor, &nm, &tm);
    let p = vec![0.01; m];
    let mu = vec![0.3; m];
    let b = patch_load(nx, ny, 0.0005, 0.02);
    let mut restarted = false;
    for (free, law) in [
        (&lumped, Friction::Tresca(&p)),
        (&lumped, Friction::Coulomb(&mu)),
        (&jacobi, Friction::Coulomb(&mu)),
    ] {
        let mut answer = vec![0.0; free.c];
        drive_newton(free, &b, law, &mut answer, |_| {});
        let problem = plain(free, &b, law);
        let lam: Vec<f64> = answer.iter().map(|v| 0.7 * v).collect();
        let mut w = vec![0.0; free.c];
        problem.gradient(&lam, &mut w);
        for (exact, eta, tol) in [(true, 1e-12, 1e-13), (false, 1e-4, 1e-5)] {
            let (combined, step, ae0, krylov) = one_step(&problem, &lam, &w, 1.0, |krylov| {
                (krylov.exact, krylov.eta) = (exact, eta);
            });
            assert_eq!(combined, Some(true), "exact {exact}");
            let mut ad = vec![0.0; free.c];
            free.apply(&step, &mut ad);
            let (off, spread) = (norm_diff(&ad, &ae0), krylov.spread);
            println!(
                "exact {exact}: {} products, A d off by {:.1e} of |A d|, spread {:.1e} |A d|",
                krylov.its,
                off / norm(&ad),
                spread / norm(&ad)
            );
            assert!(
                off <= tol * spread,
                "exact {exact}: {off:.2e} for {spread:.2e}"
            );
            restarted |=
                matches!(law, Friction::Coulomb(_)) && krylov.its > crate::methods::krylov::RESTART;
        }
    }
    assert!(restarted, "no GMRES solve restarted");
}

/// A matrix-free Newton step takes no product of its own for the
/// backtracking: its reduced solve combines A d from its products
/// (`krylov_step`), in single precision where the forcing term allows, so
/// w drifts and is recomputed before the end. On the lattice slab pressed
/// and sheared, a cold solve and a warm one at 2 % more load, Tresca and
/// Coulomb: every step combined its A d, and each answer is dense Newton's
/// (1e-10 relative) with err at most the target 1e-12 on a gradient
/// computed afresh, the err the driver reports.
#[test]
fn a_step_s_product_is_combined_from_its_reduced_solve() {
    use crate::dual::{Condensation, Dual};
    let (nx, ny, nz) = (16, 16, 4);
    let (k, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let m = nx * ny;
    let free = lumped_free(&k, &factor, &nm, &tm);
    let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    let p = vec![0.01; m];
    let mu = vec![0.3; m];
    let b1 = patch_load(nx, ny, 0.0005, 0.02);
    let b2: Vec<f64> = b1.iter().map(|v| 1.02 * v).collect();
    for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
        let (mut l_dense, mut l_free) = (vec![0.0; dense.c], vec![0.0; free.c]);
        for b in [&b1, &b2] {
            drive_newton(&dense, b, law, &mut l_dense, |_| {});
            let (out, newton) = drive_newton(&free, b, law, &mut l_free, |_| {});
            let diff = max_diff(&l_free, &l_dense);
            assert!(diff <= 1e-10 * norm(&l_dense), "{diff:.2e}");
            // Every step combined its A d (none was narrowed: the patch
            // closes the whole face).
            assert!(out.outer > 0);
            assert_eq!(newton.krylov.combined, out.outer, "{out:?}");
            let err = fresh_err(&plain(&free, b, law), &l_free);
            assert!(err <= 1e-12, "{err:.2e}");
            // The err reported is that of an exact gradient too.
            assert!(
                (out.dual_err - err).abs() <= 1e-3 * err,
                "{:.3e} reported, {err:.3e}",
                out.dual_err
            );
        }
    }
}

/// w is recomputed after a step where its drift exceeds a hundredth of |F|
/// and a tenth of the target (err's scale |lambda|), not otherwise: the
/// last step of a solve, its |F| far below its own products' drift, is
/// not followed by a recomputation.
#[test]
fn w_is_recomputed_where_its_drift_matters() {
    let (target, lam) = (1e-10, 0.01);
    // A middle step: |F| 1e-9, drift 1e-8 (both above the target's scale).
    assert!(needs_resync(1e-9, 1e-8, target, lam));
    // Drift below a hundredth of |F|.
    assert!(!needs_resync(1e-9, 0.9e-11, target, lam));
    // The last step: |F| 1e-13 under a drift of 5e-15, below a tenth of
    // target |lambda| = 1e-12.
    assert!(!needs_resync(1e-13, 5e-15, target, lam));
    // The same drift at a target a hundred times tighter: recomputed.
    assert!(needs_resync(1e-13, 5e-15, 1e-12, lam));
    // Exact w (no drift): never.
    assert!(!needs_resync(0.0, 0.0, target, 0.0));
}

/// Where the caller measures the error on the recovered u
/// (`DualProblem::measured_after`), the driver ends converged on a drifted
/// gradient without recomputing it, and says so; where it does not, it
/// recomputes. On the lattice slab pressed and sheared, a cold solve and a
/// warm one at 2 % more load, Tresca and Coulomb: the same iterates either
/// way (the recomputation changes no step here), some end unconfirmed, and
/// every answer's err on a gradient computed afresh meets the target 1e-12
/// and is within a tenth of the target of the drifted err reported (the
/// drift Newton leaves unrecomputed). A start gradient handed over
/// (`start_gradient`) is taken once and gives the same run. A run cut
/// short by the iteration limit reports the err of a fresh gradient at the
/// iterate it returns, measured caller or not.
#[test]
fn a_drifted_convergence_is_left_to_a_caller_that_measures() {
    let (nx, ny, nz) = (16, 16, 4);
    let (k, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let m = nx * ny;
    let free = lumped_free(&k, &factor, &nm, &tm);
    let p = vec![0.01; m];
    let mu = vec![0.3; m];
    let b1 = patch_load(nx, ny, 0.0005, 0.02);
    let b2: Vec<f64> = b1.iter().map(|v| 1.02 * v).collect();
    let opts = Options {
        method: Method::Newton,
        ..Options::default()
    };
    let target = 1e-12;
    let mut unconfirmed = 0;
    for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
        let (mut l_measured, mut l_plain) = (vec![0.0; free.c], vec![0.0; free.c]);
        for b in [&b1, &b2] {
            // The start's gradient, handed over on the measured run.
            let mut w0 = vec![0.0; free.c];
            plain(&free, b, law).gradient(&l_measured, &mut w0);
            let mut measured = plain(&free, b, law);
            measured.measured_after = true;
            measured.start_gradient.set(Some(&w0));
            let mut newton = Newton::new(&measured, target);
            let out =
                super::super::driver::drive(&measured, &mut l_measured, &opts, target, &mut newton);
            assert!(measured.start_gradient.get().is_none(), "not taken");
            assert_eq!(out.end, super::super::End::Converged, "{out:?}");
            let problem = plain(&free, b, law);
            let mut newton = Newton::new(&problem, target);
            let ref_out =
                super::super::driver::drive(&problem, &mut l_plain, &opts, target, &mut newton);
            assert!(!ref_out.unconfirmed);
            assert_eq!(out.outer, ref_out.outer, "{out:?} {ref_out:?}");
            assert_eq!(out.inner, ref_out.inner, "{out:?} {ref_out:?}");
            assert_eq!(max_diff(&l_measured, &l_plain), 0.0);
            let err = fresh_err(&problem, &l_measured);
            assert!(err <= target, "{err:.2e}");
            if out.unconfirmed {
                // Within the drift Newton leaves unrecomputed: about a
                // tenth of the target (`needs_resync`; measured within
                // 1 % of err here).
                unconfirmed += 1;
                assert!(
                    (out.dual_err - err).abs() <= ENOUGH * target,
                    "{:.3e} reported, {err:.3e}",
                    out.dual_err
                );
            } else {
                assert_eq!(out.dual_err, ref_out.dual_err);
            }
        }
    }
    assert!(unconfirmed > 0, "no run ended on a drifted gradient");
    // A run that ends otherwise (here the iteration limit, after two
    // steps) recomputes a drifted gradient whatever the caller measures:
    // the err it reports is that of the iterate it returns, on a fresh
    // gradient.
    for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
        let mut lam = vec![0.0; free.c];
        let mut measured = plain(&free, &b1, law);
        measured.measured_after = true;
        let mut newton = Newton::new(&measured, target);
        let short = Options {
            max_outer: 2,
            ..opts
        };
        let out = super::super::driver::drive(&measured, &mut lam, &short, target, &mut newton);
        assert_eq!(out.end, super::super::End::Limit, "{out:?}");
        assert!(!out.unconfirmed);
        let err = fresh_err(&plain(&free, &b1, law), &lam);
        assert!(err > target);
        assert!(
            (out.dual_err - err).abs() <= 1e-10 * err,
            "{:.3e} reported, {err:.3e}",
            out.dual_err
        );
    }
}

/// Matrix-free Newton on the thin lattice slab (anchored firmly), pressed
/// all over and sheared 17 degrees off the T rows far past the friction
/// bound (every contact slips), Tresca and Coulomb, with the lumped
/// preconditioner restricted to the reduced systems (`restricted.rs`) and
/// without it (the layered Dirichlet one, as restricted by the test
/// vectors): both converge to dense Newton's multipliers (1e-10 relative),
/// the restricted one with fewer products.
#[test]
fn the_restricted_preconditioner_saves_products_in_gross_slip() {
    use crate::dual::{Condensation, Dual};
    use crate::factor::Factor;
    use crate::options::Ordering;
    use std::sync::Arc;
    let (nx, ny, nz) = (16, 16, 4);
    let k = lattice(nx, ny, nz, 1.0);
    let m = nx * ny;
    let (nm, tm) = slab_contacts(nx, ny, k.nrows);
    let factor =
        Arc::new(Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap());
    // Pressed all over (more at the centre), sheared 17 degrees off the x
    // rows.
    let (cv, sh) = (0.1, 0.3);
    let centre = (nx as f64 - 1.0) / 2.0;
    let (cs, sn) = (17f64.to_radians().cos(), 17f64.to_radians().sin());
    let b: Vec<f64> = (0..m)
        .map(|i| {
            let (x, y) = ((i % nx) as f64 - centre, (i / nx) as f64 - centre);
            cv * (1.0 - 0.002 * (x * x + y * y))
        })
        .chain((0..2 * m).map(|r| sh * if r % 2 == 0 { cs } else { sn }))
        .collect();
    let p = vec![0.05; m];
    let mu = vec![0.3; m];
    let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    let formed = |restricted: bool| {
        let mut dual = lumped_free(&k, &factor, &nm, &tm);
        assert!(dual.force_dirichlet(&k));
        if !restricted {
            dual.drop_restricted();
        }
        dual
    };
    let (with, without) = (formed(true), formed(false));
    for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
        let solve = |dual: &Dual| {
            let mut lam = vec![0.0; dual.c];
            let (out, _) = drive_newton(dual, &b, law, &mut lam, |_| {});
            (lam, out.inner)
        };
        let (l_dense, _) = solve(&dense);
        // Most closed contacts slip, at the bound.
        let closed = (0..m).filter(|&i| l_dense[i] > 0.0).count();
        let slipping = (0..m)
            .filter(|&i| {
                let bound = law.bound(i, l_dense[i]);
                let lt = l_dense[m + 2 * i].hypot(l_dense[m + 2 * i + 1]);
                l_dense[i] > 0.0 && lt >= bound * (1.0 - 1e-8)
            })
            .count();
        assert!(
            slipping == m && closed == m,
            "{slipping} slip of {closed} closed"
        );
        let (l_with, its_with) = solve(&with);
        let (l_without, its_without) = solve(&without);
        let scale = norm(&l_dense);
        for (what, l) in [("restricted", &l_with), ("general", &l_without)] {
            let diff = max_diff(l, &l_dense);
            assert!(diff <= 1e-10 * scale, "{what}: {diff:.2e}");
        }
        let name = law_name(law);
        println!("{name}: products restricted {its_with}, general {its_without}");
        assert!(
            (its_with as f64) < 0.7 * its_without as f64,
            "products: restricted {its_with}, general {its_without}"
        );
    }
}

/// Matrix-free Newton on a 3D lattice slab, Coulomb, pressed in a small
/// central patch (most contacts open, so they leave the reduced systems)
/// and sheared so that its contacts slip: its steps' products are narrowed
/// to the patch's rows (`Dual::narrow_to`), and it converges to dense
/// Newton's multipliers (1e-10 relative).
#[test]
fn coulomb_steps_narrow_their_products_to_the_contact_zone() {
    use crate::dual::{Condensation, Dual};
    let (nx, ny, nz) = (24, 24, 3);
    let m = nx * ny;
    let (k, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let b = patch_load(nx, ny, 0.004, 0.005);
    let mu = vec![0.3; m];
    let solve = |dual: &Dual| {
        let mut lam = vec![0.0; dual.c];
        let (out, newton) = drive_newton(dual, &b, Friction::Coulomb(&mu), &mut lam, |_| {});
        (lam, out.outer, newton.krylov.narrowed)
    };
    let free = lumped_free(&k, &factor, &nm, &tm);
    let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    let (l_dense, _, _) = solve(&dense);
    let (l_free, outer, narrowed) = solve(&free);
    let closed = l_dense[..m].iter().filter(|&&v| v > 0.0).count();
    let slipping = (0..m)
        .filter(|&i| {
            let t = l_dense[m + 2 * i].hypot(l_dense[m + 2 * i + 1]);
            l_dense[i] > 0.0 && t >= 0.3 * l_dense[i] * (1.0 - 1e-9)
        })
        .count();
    println!(
        "closed {closed} of {m}, slipping {slipping}; {outer} Newton steps, {narrowed} narrowed"
    );
    assert!(closed > 0 && closed < m / 4, "closed {closed} of {m}");
    assert!(
        slipping > 0,
        "no contact slips: Coulomb's coupling untested"
    );
    assert!(
        narrowed >= outer.saturating_sub(1) && narrowed > 0,
        "{narrowed} of {outer}"
    );
    let diff = max_diff(&l_free, &l_dense);
    assert!(diff <= 1e-10 * norm(&l_dense), "{diff:.2e}");
}

/// The single-precision factor of a dense dual's last Newton step stays on
/// the dual: a history step from the last step's multipliers solves on it
/// (marked by a scaling, which leaves it as good a preconditioner: a new
/// factor would not carry the mark) to the same multipliers a cold solve
/// finds, its GMRES stopping at the forcing terms; a new compliance shift
/// drops it.
#[test]
fn the_kept_factor_serves_the_next_solve_on_the_same_dual() {
    use crate::dual::{Condensation, Dual};
    let (nx, ny, nz) = (20, 20, 3);
    let m = nx * ny;
    let (_, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let mut dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    let mu = vec![0.3; m];
    let b1 = patch_load(nx, ny, 0.0008, 0.004);
    let mut lam = vec![0.0; dense.c];
    drive_newton(&dense, &b1, Friction::Coulomb(&mu), &mut lam, |_| {});
    let first =
        |d: &Dual| d.with_kept_factor(|f| f.as_ref().map(|f| (f.llt.first_entry(), f.key.len())));
    let (l00, k1) = first(&dense).expect("a factor kept after the solve");
    assert!(
        k1 >= MIXED_MIN,
        "{k1} reduced unknowns: no single-precision factor"
    );
    dense.with_kept_factor(|f| f.as_mut().expect("kept").llt.scale(2.0));
    // The next step: the load 0.1 % larger.
    let b2: Vec<f64> = b1.iter().map(|v| 1.001 * v).collect();
    // A's inverse would precondition this warm step without the factor.
    let (out, newton) = drive_newton(&dense, &b2, Friction::Coulomb(&mu), &mut lam, |n| {
        n.inverse_on = false
    });
    assert!(
        out.outer > 0,
        "no Newton step: nothing solved on the factor"
    );
    // Coulomb's reduced system (slipping contacts' normals dragging their
    // forces) is not symmetric: GMRES stopped at the forcing term.
    assert!(newton.krylov.inexact_dense, "solved to the forcing term");
    assert_eq!(
        first(&dense).map(|f| f.0),
        Some(2.0 * l00),
        "solved on the kept factor"
    );
    let mut cold = vec![0.0; dense.c];
    drive_newton(&dense, &b2, Friction::Coulomb(&mu), &mut cold, |_| {});
    let diff = max_diff(&lam, &cold);
    println!(
        "{k1} reduced unknowns; the warm solve took {} Newton steps",
        out.outer
    );
    assert!(diff <= 1e-9 * norm(&cold), "{diff:.2e}");
    dense.set_shift(&vec![1e-3; dense.c]);
    assert!(first(&dense).is_none(), "a new shift drops the factor");
}

/// A warm 3D solve on a dense dual whose face is closed solves its reduced
/// systems on A's inverse (`dense::Complement`), made by its first step and
/// kept on the dual (a cold solve makes none), to the multipliers a cold
/// solve finds: Coulomb (GMRES, not symmetric) and Tresca (CG). A new
/// compliance shift drops the inverse.
#[test]
fn a_warm_3d_solve_runs_on_the_inverse_of_a() {
    use crate::dual::{Condensation, Dual};
    let (nx, ny, nz) = (20, 20, 3);
    let m = nx * ny;
    let (_, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let mut dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    // Tresca's bound largest at the centre, so that the edge slips.
    let centre = (nx as f64 - 1.0) / 2.0;
    let p: Vec<f64> = (0..m)
        .map(|i| {
            let (x, y) = ((i % nx) as f64 - centre, (i / nx) as f64 - centre);
            0.002 + 0.02 * (-(x * x + y * y) / 50.0).exp()
        })
        .collect();
    let mu = vec![0.3; m];
    // Pressed over the whole face, sheared so that its edge slips.
    let b1 = patch_load(nx, ny, 0.0002, 0.02);
    let b2: Vec<f64> = b1.iter().map(|v| 1.02 * v).collect();
    for law in [Friction::Coulomb(&mu), Friction::Tresca(&p)] {
        let mut lam = vec![0.0; dense.c];
        let (_, cold) = drive_newton(&dense, &b1, law, &mut lam, |_| {});
        assert_eq!(cold.krylov.on_inverse, 0, "a cold solve used the inverse");
        assert!(
            dense.inverse(false).is_none(),
            "a cold solve made the inverse"
        );
        // The warm solve's first Newton step (sorted by the multipliers,
        // WARM_C), solved exactly on the inverse (products with A) and on
        // the assembled reduced system: the same step.
        let problem = plain(&dense, &b2, law);
        let mut w = vec![0.0; dense.c];
        problem.gradient(&lam, &mut w);
        let step_with = |inverse: bool| {
            let (ok, step, _, krylov) = one_step(&problem, &lam, &w, WARM_C, |krylov| {
                (krylov.inverse, krylov.exact) = (inverse, true);
            });
            assert!(ok.is_some());
            (step, krylov.on_inverse)
        };
        let ((on, used), (off, unused)) = (step_with(true), step_with(false));
        assert_eq!((used, unused), (1, 0), "the step on the inverse");
        let diff = max_diff(&on, &off);
        // 6e-15 relative measured; a product that halves the slipping
        // unknowns' curvature terms gives 3e-9.
        assert!(diff <= 1e-12 * norm(&off), "steps differ by {diff:.2e}");
        let (out, warm) = drive_newton(&dense, &b2, law, &mut lam, |_| {});
        let slipping = (0..m)
            .filter(|&i| {
                let t = (lam[m + 2 * i].powi(2) + lam[m + 2 * i + 1].powi(2)).sqrt();
                t > 0.0 && t >= (1.0 - 1e-9) * law.bound(i, lam[i])
            })
            .count();
        println!(
            "{} Newton steps, {} on the inverse; {slipping} of {m} contacts slip",
            out.outer, warm.krylov.on_inverse
        );
        assert!(slipping > 0 && slipping < m / 2, "{slipping} slipping");
        assert!(warm.krylov.on_inverse > 0, "no step on the inverse");
        assert!(dense.inverse(false).is_some(), "the inverse is kept");
        let mut fresh = vec![0.0; dense.c];
        drive_newton(&dense, &b2, law, &mut fresh, |_| {});
        let diff = max_diff(&lam, &fresh);
        assert!(diff <= 1e-9 * norm(&fresh), "{diff:.2e}");
        dense.set_shift(&[]);
        assert!(
            dense.inverse(false).is_none(),
            "a new shift drops the inverse"
        );
    }
}

/// Matrix-free Newton on a grid's bottom row (d = 2: normal on the row's
/// DOFs, tangent on the row above), Tresca, with the lumped preconditioner
/// G = B K B^T (from zero and from the lumped start) and with Jacobi: all
/// converge to dense Newton's multipliers (1e-10 relative), the lumped
/// preconditioner with fewer products than Jacobi.
#[test]
fn the_lumped_preconditioner_saves_products() {
    use crate::dual::tests::grid;
    use crate::dual::{Condensation, Dual};
    use crate::factor::Factor;
    use crate::options::Ordering;
    use std::sync::Arc;
    let (nx, ny) = (60, 30);
    let k = grid(nx, ny);
    let m = nx;
    let nmat: Vec<_> = (0..m).map(|i| (i, i, 1.0)).collect();
    let tmat: Vec<_> = (0..m).map(|i| (i, i + nx, 1.0)).collect();
    let (nm, tm) = (
        Csc::from_triplets(m, nx * ny, &nmat),
        Csc::from_triplets(m, nx * ny, &tmat),
    );
    let factor =
        Arc::new(Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap());
    // Pressed in the middle, pulled off at the ends, sheared.
    let b: Vec<f64> = (0..m)
        .map(|i| 0.5 - ((i as f64 - 30.0) / 20.0).powi(2))
        .chain((0..m).map(|i| 0.3 * (i as f64 * 0.2).sin()))
        .collect();
    let p = vec![0.04; m];
    let solve = |dual: &Dual, start: bool| {
        let mut lam = vec![0.0; dual.c];
        let law = Friction::Tresca(&p);
        let (out, _) = drive_newton(dual, &b, law, &mut lam, |n| n.lumped_start_on = start);
        (lam, out.inner, out.outer)
    };
    let jacobi = Dual::build_with(&factor, &nm, &tm, 2, Condensation::MatrixFree).unwrap();
    let mut lumped = Dual::build_with(&factor, &nm, &tm, 2, Condensation::MatrixFree).unwrap();
    lumped.set_lumped(&k, None);
    assert!(jacobi.lumped().is_none() && lumped.lumped().is_some());
    let dense = Dual::build_with(&factor, &nm, &tm, 2, Condensation::Solves).unwrap();
    let (l_dense, _, _) = solve(&dense, true);
    let (l_jacobi, its_jacobi, _) = solve(&jacobi, true);
    let (l_lumped, its_lumped, steps_cold) = solve(&lumped, false);
    let (l_start, its_start, steps_start) = solve(&lumped, true);
    println!(
        "steps: from zero {steps_cold}, from the lumped start {steps_start}; products {its_start}"
    );
    assert!(its_start > 0 && steps_start > 0);
    let scale = norm(&l_dense);
    assert!(l_dense.contains(&0.0) && l_dense[..m].iter().any(|&v| v > 0.0));
    for (what, l) in [
        ("jacobi", &l_jacobi),
        ("lumped", &l_lumped),
        ("start", &l_start),
    ] {
        let diff = max_diff(l, &l_dense);
        assert!(diff <= 1e-10 * scale, "{what}: {diff:.2e}");
    }
    assert!(
        its_lumped < its_jacobi,
        "products: lumped {its_lumped}, jacobi {its_jacobi}"
    );
    println!("products: lumped {its_lumped}, jacobi {its_jacobi}");
}

#[test]
fn the_forcing_term_reads_the_last_step() {
    let (target, lam) = (1e-10, 1.0);
    // No last step: |F| / |F_0|, capped at 0.1.
    assert_eq!(forcing(0.5, 1.0, target, lam, None, 0.0), 0.1);
    assert_eq!(forcing(0.01, 1.0, target, lam, None, 0.0), 0.01);
    // A whole step that did its work: the default.
    let good = LastStep {
        ratio: 0.08,
        full: true,
    };
    assert_eq!(forcing(0.08, 1.0, target, lam, Some(good), 0.0), 0.08);
    // A whole step that left more than POOR of |F|: LOOSE.
    let poor = LastStep {
        ratio: 0.9,
        full: true,
    };
    assert_eq!(forcing(0.9, 1.0, target, lam, Some(poor), 0.0), LOOSE);
    // Unless it was backtracked: its direction, not its model, fell short.
    let damped = LastStep {
        full: false,
        ..poor
    };
    assert_eq!(forcing(0.9, 1.0, target, lam, Some(damped), 0.0), 0.1);
    // A whole step that shrank |F| only at a linear rate (0.2): no tighter
    // than SEEN_GAMMA 0.2^2 = 0.036, where |F| / |F_0| asks for 1e-3.
    let linear = LastStep {
        ratio: 0.2,
        full: true,
    };
    let seen = forcing(1e-3, 1.0, target, lam, Some(linear), 0.0);
    assert!((seen - 0.036).abs() < 1e-15, "{seen}");
    // Capped at 0.1: after 0.45, 0.9 0.45^2 = 0.182 would be looser.
    let slow = LastStep {
        ratio: 0.45,
        full: true,
    };
    assert_eq!(forcing(1e-3, 1.0, target, lam, Some(slow), 0.0), 0.1);
    // A backtracked one keeps |F| / |F_0|.
    let linear_damped = LastStep {
        full: false,
        ..linear
    };
    assert_eq!(
        forcing(1e-3, 1.0, target, lam, Some(linear_damped), 0.0),
        1e-3
    );
    // A superlinear step (1e-3) leaves |F| / |F_0|: 0.9e-6 < 1e-4.
    let fast = LastStep {
        ratio: 1e-3,
        full: true,
    };
    assert_eq!(forcing(1e-4, 1.0, target, lam, Some(fast), 0.0), 1e-4);
    // Never tighter than a step leaving |F| at ENOUGH of the target.
    let enough = ENOUGH * target * lam / 1e-8;
    assert!((forcing(1e-8, 1.0, target, lam, Some(fast), 0.0) - enough).abs() < 1e-18);
    // Nor than the floor (rough products), whatever |F| and the target ask.
    assert_eq!(
        forcing(1e-6, 1.0, target, lam, Some(fast), ROUGH_ETA),
        ROUGH_ETA
    );
    // A looser term is kept as it is.
    assert_eq!(forcing(1e-3, 1.0, target, lam, Some(fast), ROUGH_ETA), 1e-3);
}

/// A contact that closes in a Newton step (lambda_N = 0, y_N > 0) has the
/// bound mu lambda_N = 0, so the natural map calls it slipping whatever its
/// tangential trial; `linearise` sorts it against mu y_N instead. On the
/// strip from zero multipliers (every contact closing), at three shears:
/// each contact's tangential row is free exactly where |y_T| < mu y_N
/// (checked contact by contact from w). At the smallest shear every contact
/// sticks, and Newton from zero without warm-up sweeps then sorts every
/// contact as the answer does and converges in one step, its answer
/// sticking everywhere with w = 0 on every row (the KKT conditions of a
/// closed sticking zone).
#[test]
fn a_closing_contact_is_sorted_by_its_trial_normal_force() {
    let (pb, g) = strip(41);
    let mu = vec![0.3; 41];
    let dual = pb.dual();
    let c = dual.c;
    for (shear, want) in [(3e-5, Some(41)), (7e-5, None), (3e-4, Some(0))] {
        let b = rhs(&pb, &g, 4e-3, shear);
        let problem = plain(dual, &b, Friction::Coulomb(&mu));
        let lam = vec![0.0; c];
        let mut w = vec![0.0; c];
        problem.gradient(&lam, &mut w);
        let (mut e0, mut f) = (vec![0.0; c], vec![0.0; c]);
        let red = step::linearise(&problem, &lam, &w, &mut e0, &mut f, 1.0);
        let free: Vec<usize> = red.iter().map(|u| u.test[0].0).collect();
        let mut sticking = 0;
        for i in 0..41 {
            let rho = dual.rho[i];
            let (yn, yt) = (-rho * w[i], -rho * w[41 + i]);
            assert!(yn > 0.0, "contact {i} closes");
            assert!(free.contains(&i), "contact {i}'s normal is free");
            let stick = yt.abs() < 0.3 * yn;
            assert_eq!(
                free.contains(&(41 + i)),
                stick,
                "shear {shear}, contact {i}"
            );
            sticking += stick as usize;
        }
        println!("shear {shear}: {sticking} of 41 sorted sticking");
        match want {
            Some(n) => assert_eq!(sticking, n, "shear {shear}"),
            None => assert!((1..41).contains(&sticking), "shear {shear}: {sticking}"),
        }
        if want != Some(41) {
            continue;
        }
        let mut lam = vec![0.0; c];
        let (out, _) = drive_newton(dual, &b, Friction::Coulomb(&mu), &mut lam, |n| {
            n.presweeps = 0
        });
        assert_eq!(out.outer, 1, "{out:?}");
        problem.gradient(&lam, &mut w);
        let scale = lam.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for i in 0..41 {
            assert!(
                lam[i] > 0.0 && lam[41 + i].abs() < 0.3 * lam[i],
                "contact {i}"
            );
            // The gradient (a gap) in force units, rho w, against the forces.
            let rho = dual.rho[i];
            assert!(
                rho * w[i].abs() <= 1e-10 * scale && rho * w[41 + i].abs() <= 1e-10 * scale,
                "contact {i}: rho w = {:.1e}, {:.1e}; |lambda| {scale:.1e}",
                rho * w[i],
                rho * w[41 + i]
            );
        }
    }
}

/// The backtracking keeps the step length with the lowest |F| among those
/// that meet the sufficient decrease, not the first that does.
#[test]
fn the_backtracking_keeps_the_best_length_that_decreases_enough() {
    let pick = |tries: &[(f64, f64)]| {
        tries
            .iter()
            .fold(None, |kept, &tried| better_length(1.0, kept, tried))
    };
    // The full step barely decreases |F|, half of it decreases it most.
    let tries = [(1.0, 0.99), (0.5, 0.6), (0.25, 0.8), (0.125, 1.1)];
    assert_eq!(pick(&tries), Some((0.5, 0.6)));
    // A good full step is kept where no shorter one is lower.
    assert_eq!(
        pick(&[(1.0, 0.1), (0.5, 0.55), (0.25, 0.77)]),
        Some((1.0, 0.1))
    );
    // Sufficient decrease: 1 - ARMIJO t of |F|, so a full step that lowers
    // |F| by less than ARMIJO is refused where an eighth that lowers it by
    // more than ARMIJO / 8 is kept.
    let barely = 1.0 - 0.5 * ARMIJO;
    assert_eq!(
        pick(&[(1.0, barely), (0.125, barely)]),
        Some((0.125, barely))
    );
    // Nothing decreases enough: None (the fallback takes over).
    assert_eq!(pick(&[(1.0, 1.0), (0.5, 2.0)]), None);
    // A tie keeps the longer step, tried first.
    assert_eq!(pick(&[(1.0, 0.5), (0.5, 0.5)]), Some((1.0, 0.5)));
    // A length whose |F| is not a number (an overflow along the step) is
    // never kept, before or after one that is.
    assert_eq!(
        pick(&[(1.0, f64::NAN), (0.5, 0.7), (0.25, f64::NAN)]),
        Some((0.5, 0.7))
    );
    assert_eq!(pick(&[(1.0, f64::NAN), (0.5, f64::INFINITY)]), None);
}

/// The matrix-free fallback (MPRGP on the Tresca problem of the current
/// bound) stops once the residual of that problem, measured afresh, has
/// halved (FALLBACK_DROP), within FALLBACK_MPRGP iterations; from normal
/// forces of 0.01 on a slab pressed into a patch (a feasible start, so the
/// residual it starts from is the one at lam) it gets there in fewer, and
/// the multipliers stay feasible for the bound.
#[test]
fn the_fallback_stops_once_its_residual_halves() {
    use crate::methods::mprgp::ConvexQp;
    let (nx, ny, nz) = (16, 16, 3);
    let m = nx * ny;
    let (k, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let b = patch_load(nx, ny, 0.004, 0.005);
    let mu = vec![0.3; m];
    let dual = lumped_free(&k, &factor, &nm, &tm);
    let problem = plain(&dual, &b, Friction::Coulomb(&mu));
    // A start with some normal force, so that Coulomb's bound is not zero.
    let mut lam = vec![0.0; dual.c];
    lam[..m].iter_mut().for_each(|v| *v = 0.01);
    let mut w = vec![0.0; dual.c];
    problem.gradient(&lam, &mut w);
    let mut radii = vec![0.0; m];
    problem.law.bounds(&lam[..m], &mut radii);
    let before = ConvexQp::whole(&problem, &radii).residual(&lam, &w);
    let mut newton = Newton::new(&problem, 1e-12);
    let mut inner = 0;
    let flow = newton.mprgp_fallback(&problem, &mut lam, &mut w, &mut inner);
    assert!(matches!(flow, Flow::Go(Gradient::Exact)));
    // The same Tresca problem (the bound the fallback froze), on a
    // gradient computed afresh.
    let mut fresh = vec![0.0; dual.c];
    problem.gradient(&lam, &mut fresh);
    assert!(max_diff(&fresh, &w) <= 1e-12 * norm(&fresh), "w left exact");
    let after = ConvexQp::whole(&problem, &radii).residual(&lam, &fresh);
    println!("fallback: {inner} iterations, residual {before:.3e} -> {after:.3e}");
    assert!(before > 0.0);
    assert!(
        after <= FALLBACK_DROP * before * (1.0 + 1e-9),
        "{before:.3e} -> {after:.3e}"
    );
    assert!((1..FALLBACK_MPRGP).contains(&inner), "{inner} iterations");
    for i in 0..m {
        assert!(lam[i] >= 0.0);
        let t = lam[m + 2 * i].hypot(lam[m + 2 * i + 1]);
        assert!(t <= radii[i] * (1.0 + 1e-12) + 1e-300, "contact {i}");
    }
}

/// A cold matrix-free solve of gross slip on a 3D lattice slab (pressed over
/// about 70 % of its face, sheared 17 degrees off the x rows beyond the
/// slip bound everywhere): begun at the lumped start, with rho scaled by
/// COLD_C its steps reach dense Newton's multipliers (1e-10 relative) in
/// fewer Newton steps than with rho itself, for Tresca and Coulomb.
#[test]
fn a_cold_matrix_free_solve_leans_on_its_lumped_start() {
    use crate::dual::{Condensation, Dual};
    let (nx, ny, nz) = (16, 16, 4);
    let (k, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let m = nx * ny;
    let (cs, sn) = (17f64.to_radians().cos(), 17f64.to_radians().sin());
    let (curve, shear) = (0.001, 0.3);
    let b: Vec<f64> = patch_load(nx, ny, curve, 0.0)
        .into_iter()
        .enumerate()
        .map(|(j, v)| match j {
            j if j < m => v,
            j if (j - m) % 2 == 0 => shear * cs,
            _ => shear * sn,
        })
        .collect();
    let (p, mu) = (vec![0.02; m], vec![0.3; m]);
    let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    let free = lumped_free(&k, &factor, &nm, &tm);
    for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
        let solve = |dual: &Dual, cold_c: f64| {
            let mut lam = vec![0.0; dual.c];
            let (out, newton) = drive_newton(dual, &b, law, &mut lam, |n| n.cold_c = cold_c);
            assert_eq!(newton.from_lumped, dual.is_matrix_free());
            (lam, out.outer, out.inner)
        };
        let (l_dense, _, _) = solve(&dense, COLD_C);
        let (l_scaled, steps_scaled, its_scaled) = solve(&free, COLD_C);
        let (l_plain, steps_plain, its_plain) = solve(&free, 1.0);
        let scale = norm(&l_dense);
        for (what, l) in [("scaled", &l_scaled), ("plain", &l_plain)] {
            let diff = max_diff(l, &l_dense);
            assert!(diff <= 1e-10 * scale, "{what}: {diff:.2e}");
        }
        let slipping = (0..m)
            .filter(|&i| {
                let lt = l_dense[m + 2 * i].hypot(l_dense[m + 2 * i + 1]);
                l_dense[i] > 0.0 && lt >= law.bound(i, l_dense[i]) * (1.0 - 1e-8)
            })
            .count();
        let closed = (0..m).filter(|&i| l_dense[i] > 0.0).count();
        let name = law_name(law);
        println!(
            "{name}: {closed} closed, {slipping} slip; Newton steps / products: \
             COLD_C {steps_scaled} / {its_scaled}, rho {steps_plain} / {its_plain}"
        );
        assert!(
            slipping == closed && closed > m / 2,
            "{name}: {slipping} of {closed}"
        );
        assert!(
            steps_scaled < steps_plain,
            "{name}: Newton steps COLD_C {steps_scaled}, rho {steps_plain}"
        );
    }
}

/// The increment solve catches a drifted convergence that went unseen: with
/// the fault of `driver::fault` on, the first run of every matrix-free
/// solve (whose error is measured on the recovered u) claims convergence
/// at its first drifted gradient, far from the answer. The solve measures
/// the error on the recovered u, finds it above the tolerance and goes on
/// from there with every convergence confirmed on an exact gradient: it
/// ends converged within the tolerance, at the multipliers of the dense
/// route without the fault (the lattice slab pressed and sheared, Tresca
/// and Coulomb). A tightened target instead (the rounding path) would run
/// again with the error left to the recovered u, be cut short by the fault
/// again and end above the tolerance.
#[test]
fn the_increment_solve_confirms_a_drifted_convergence_it_catches() {
    use super::super::driver::fault;
    use crate::options::DualForm;
    let (nx, ny, nz) = (16, 16, 4);
    let k = lattice(nx, ny, nz, 0.05);
    let (nm, tm) = slab_contacts(nx, ny, k.nrows);
    let m = nx * ny;
    let centre = (nx as f64 - 1.0) / 2.0;
    let g: Vec<f64> = (0..m)
        .map(|i| {
            let (x, y) = ((i % nx) as f64 - centre, (i / nx) as f64 - centre);
            1e-3 * (x * x + y * y)
        })
        .collect();
    // Pressed up into the foundation (N = e_z) and sheared along x, at
    // the bottom nodes.
    let f: Vec<f64> = (0..k.nrows)
        .map(|j| match (j / 3 < m, j % 3) {
            (true, 2) => 0.01,
            (true, 0) => 0.003,
            _ => 0.0,
        })
        .collect();
    let p = vec![0.002; m];
    let mu = vec![0.3; m];
    let make = |form| {
        let opts = Options {
            dual_form: form,
            ..Options::default()
        };
        ContactProblem::from_csc_with(3, k.clone(), nm.clone(), tm.clone(), &opts).unwrap()
    };
    let opts = Options {
        method: Method::Newton,
        ..Options::default()
    };
    for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
        let name = law_name(law);
        let reference = make(DualForm::Dense).solve(&f, &g, law, &opts).unwrap();
        assert_eq!(reference.report.status, crate::SolveStatus::Converged);
        let mut pb = make(DualForm::MatrixFree);
        assert!(pb.is_matrix_free());
        fault::claim_drifted(true);
        let sol = pb.solve(&f, &g, law, &opts);
        let (claimed, confirming) = fault::claim_drifted(false);
        let sol = sol.unwrap();
        let closed = reference.lambda_n.iter().filter(|&&v| v > 0.0).count();
        println!(
            "{name}: {closed} of {m} closed; {claimed} convergence(s) claimed by the fault, \
             {confirming} confirming run(s), err {:.2e}, {} outer",
            sol.report.err, sol.report.outer_iterations
        );
        assert!(closed > 0 && closed < m, "{name}: {closed} closed");
        assert!(claimed > 0, "{name}: the fault never fired");
        assert!(
            confirming > 0,
            "{name}: no run confirmed on an exact gradient"
        );
        assert_eq!(sol.report.status, crate::SolveStatus::Converged, "{name}");
        assert!(sol.report.err <= opts.tol, "{name}: {:.2e}", sol.report.err);
        let scale = norm(&reference.lambda_n);
        for (a, b) in [
            (&sol.lambda_n, &reference.lambda_n),
            (&sol.lambda_t, &reference.lambda_t),
        ] {
            let diff = max_diff(a, b);
            assert!(diff <= 1e-7 * scale, "{name}: {diff:.2e} of {scale:.2e}");
        }
    }
}

/// A warm matrix-free solve whose sort does not change after its first
/// step (the lattice slab pressed in a central patch, most contacts open,
/// and sheared; the load then raised by 0.1 %, as a host's later
/// iterations change their problem): Coulomb's
/// steps, whose products are narrowed to the contact zone, solve each
/// later step to the floor of its forcing term (`Krylov::settle`), in
/// fewer Newton steps than with the forcing terms of `forcing` alone;
/// Tresca's, whose A d is combined from the solve's own products, keep
/// those forcing terms. Both end at the multipliers of the dense route.
#[test]
fn a_settled_sort_is_solved_to_the_floor() {
    use crate::dual::{Condensation, Dual};
    let (nx, ny, nz) = (24, 24, 3);
    let m = nx * ny;
    let (k, factor, nm, tm) = lattice_slab(nx, ny, nz);
    let dense = Dual::build_with(&factor, &nm, &tm, 3, Condensation::Solves).unwrap();
    let free = lumped_free(&k, &factor, &nm, &tm);
    let b1 = patch_load(nx, ny, 0.004, 0.005);
    let b2: Vec<f64> = b1.iter().map(|v| 1.001 * v).collect();
    let (p, mu) = (vec![0.01; m], vec![0.3; m]);
    for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
        let name = law_name(law);
        let mut start = vec![0.0; free.c];
        drive_newton(&free, &b1, law, &mut start, |_| {});
        let mut want = start.clone();
        drive_newton(&dense, &b2, law, &mut want, |_| {});
        let solve = |on: bool| {
            let mut lam = start.clone();
            let (out, newton) =
                drive_newton(&free, &b2, law, &mut lam, |n| n.krylov.settle_on = on);
            let diff = max_diff(&lam, &want);
            assert!(diff <= 1e-10 * norm(&want), "{name} {on}: {diff:.2e}");
            let k = &newton.krylov;
            (out.outer, out.inner, k.settled, k.narrowed, k.combined)
        };
        let (steps_on, its_on, settled, narrowed, combined) = solve(true);
        let (steps_off, its_off, _, _, _) = solve(false);
        println!(
            "{name}: Newton steps / products settled {steps_on} / {its_on} ({settled} \
             tightened; {narrowed} narrowed, {combined} combined), without {steps_off} / {its_off}"
        );
        match law {
            Friction::Coulomb(_) => {
                assert!(narrowed > 0 && settled > 0, "{name}: no step tightened");
                assert!(steps_on < steps_off, "{name}: {steps_on} >= {steps_off}");
            }
            Friction::Tresca(_) => {
                assert_eq!(narrowed, 0, "{name}: narrowed");
                assert_eq!(settled, 0, "{name}: a combined step tightened");
                assert_eq!((steps_on, its_on), (steps_off, its_off));
            }
        }
    }
}

/// The sort's key (`sort_key`) tells apart a 2D Coulomb slip that reverses
/// (its coupling's sign) and a contact that changes state, and keeps a 3D
/// slip direction that turns (its coefficients, signs included).
#[test]
fn the_sort_key_follows_the_states_not_the_slip_directions() {
    // A closed normal dragging its slip force (Coulomb), coupling mu n.
    let drag = |n: [f64; 2], d: usize| {
        let mut u = Reduced::unit(0, 1.0);
        u.dir[1] = (1, 0.3 * n[0]);
        u.n_dir = 2;
        if d == 3 {
            u.dir[2] = (2, 0.3 * n[1]);
            u.n_dir = 3;
        }
        u
    };
    let key = |red: &[Reduced], d: usize| super::reduced_krylov::sort_key(red, d);
    assert_ne!(
        key(&[drag([1.0, 0.0], 2)], 2),
        key(&[drag([-1.0, 0.0], 2)], 2)
    );
    let (a, b) = ([0.6, 0.8], [0.8, -0.6]);
    assert_eq!(key(&[drag(a, 3)], 3), key(&[drag(b, 3)], 3));
    // Sticking instead: two unit unknowns on the tangential rows.
    let stick = [
        Reduced::unit(0, 1.0),
        Reduced::unit(1, 0.0),
        Reduced::unit(2, 0.0),
    ];
    assert_ne!(key(&[drag(a, 3)], 3), key(&stick, 3));
    // An open contact leaves its normal row: not the same key as closed.
    assert_ne!(key(&stick[1..], 3), key(&stick, 3));
}
