//! Unit tests of what a history step keeps for the next one, and the 2D
//! strip they and Newton's tests solve.
use super::*;
use crate::friction::Friction;
use crate::options::DualForm;

/// A 2D strip of `nodes` contact nodes (u_x, u_y each), tied to a rigid top
/// by vertical and shear springs and to each other by bars; contact i: N =
/// -e_y, T = e_x, gap 1e-3 (i - c)^2 / c^2 around the centre c. The problem
/// with the dual form `form`, and the gaps.
pub(crate) fn strip(nodes: usize, form: DualForm) -> (ContactProblem, Vec<f64>) {
    let n = 2 * nodes;
    let mut k = Vec::new();
    for i in 0..nodes {
        let (x, y) = (2 * i, 2 * i + 1);
        k.push((x, x, 0.02));
        k.push((y, y, 1.0));
        if i + 1 < nodes {
            for (a, b, s) in [(x, x + 2, 2.0), (y, y + 2, 0.5)] {
                k.push((a, a, s));
                k.push((b, b, s));
                k.push((a, b, -s));
                k.push((b, a, -s));
            }
        }
    }
    let nmat: Vec<_> = (0..nodes).map(|i| (i, 2 * i + 1, -1.0)).collect();
    let tmat: Vec<_> = (0..nodes).map(|i| (i, 2 * i, 1.0)).collect();
    let c = (nodes - 1) as f64 / 2.0;
    let g: Vec<f64> = (0..nodes)
        .map(|i| 1e-3 * (i as f64 - c).powi(2) / (c * c))
        .collect();
    let opts = Options {
        dual_form: form,
        ..Options::default()
    };
    let pb = ContactProblem::from_csc_with(
        2,
        Csc::from_triplets(n, n, &k),
        Csc::from_triplets(nodes, n, &nmat),
        Csc::from_triplets(nodes, n, &tmat),
        &opts,
    )
    .unwrap();
    (pb, g)
}

/// Asserts that `got` equals `want` (not zero) to `rel` of want's largest
/// entry, entry by entry.
fn assert_close(got: &[f64], want: &[f64], rel: f64, what: &str) {
    let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let diff = got
        .iter()
        .zip(want)
        .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    assert!(
        scale > 0.0 && diff <= rel * scale,
        "{what}: {diff:.2e} of {scale:.2e}"
    );
}

/// A converged history step keeps A lambda of its answer (b - v on the
/// recovered u), from which the next step's gradient at its start is
/// combined without a product: it equals A lambda computed afresh, on a
/// dense and a matrix-free dual, Tresca and Coulomb, at every step of a
/// proportional press and shear that closes more contacts step by step
/// (Tresca's slip from the third step, Coulomb's in the first three).
#[test]
fn a_history_step_keeps_a_times_its_multipliers() {
    let nodes = 40;
    for form in [DualForm::Dense, DualForm::MatrixFree] {
        let p = vec![2e-4; nodes];
        let mu = vec![0.3; nodes];
        for law in [Friction::Tresca(&p), Friction::Coulomb(&mu)] {
            let (mut pb, g) = strip(nodes, form);
            let opts = Options::default();
            let mut slipped = 0;
            for step in 1..=5 {
                let s = step as f64 / 5.0;
                let f: Vec<f64> = (0..2 * nodes)
                    .map(|j| s * if j % 2 == 0 { 4e-4 } else { -2e-3 })
                    .collect();
                let sol = pb.step(&f, &g, law, &opts).unwrap();
                assert_eq!(sol.report.status, SolveStatus::Converged);
                let lam = pb.history.lam.clone();
                let kept = pb.history.alam().expect("A lambda kept").to_vec();
                let mut exact = vec![0.0; lam.len()];
                pb.dual.apply(&lam, &mut exact);
                let scale = exact.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let diff = kept
                    .iter()
                    .zip(&exact)
                    .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
                let closed = lam[..nodes].iter().filter(|&&v| v > 0.0).count();
                let slipping = (0..nodes)
                    .filter(|&i| {
                        lam[i] > 0.0 && lam[nodes + i].abs() >= law.bound(i, lam[i]) * (1.0 - 1e-8)
                    })
                    .count();
                println!(
                    "{form:?} step {step}: {closed} closed, {slipping} slip, \
                     |kept - A lambda| {diff:.1e} of {scale:.1e}"
                );
                assert!(closed > 0 && scale > 0.0);
                slipped += slipping;
                assert!(
                    diff <= 1e-12 * scale,
                    "{form:?} step {step}: {diff:.2e} of {scale:.2e}"
                );
            }
            assert!(slipped > 0, "{form:?}: no contact slipped");
        }
    }
}

/// A host iteration's line (`solve::iteration_line`) through two starts
/// whose errors are collinear, lambda* + e and lambda* + 2 e (e: a
/// thousandth of lambda* at the closed contacts, where that keeps the
/// sort: Tresca's slipping tangential pairs left alone), lands on lambda*
/// (s = 1 on the components the start holds free, where w* = 0), on a
/// dense and a matrix-free dual, Tresca and Coulomb. With a third error
/// that the line carries out of the feasible set (an open contact's normal
/// force, +eps at the start and +3 eps at the point before: -eps on the
/// line), the projection moves it back onto lambda*, and the gradient
/// handed back is A x - b at the moved point, computed afresh.
#[test]
fn a_host_iterations_line_lands_on_collinear_errors_answer() {
    let nodes = 40;
    for form in [DualForm::Dense, DualForm::MatrixFree] {
        let p = vec![2e-4; nodes];
        let mu = vec![1.0; nodes];
        for (name, law) in [
            ("Tresca", Friction::Tresca(&p)),
            ("Coulomb", Friction::Coulomb(&mu)),
        ] {
            let (mut pb, g) = strip(nodes, form);
            let opts = Options {
                tol: 1e-13,
                ..Options::default()
            };
            // A fifth of the strip tests' press, a shear growing along the
            // strip: the edges stay open, contacts stick at one end and
            // slip at the other.
            let f: Vec<f64> = (0..2 * nodes)
                .map(|j| {
                    if j % 2 == 0 {
                        3e-4 * (j / 2) as f64 / nodes as f64
                    } else {
                        -4e-4
                    }
                })
                .collect();
            let sol = pb.solve(&f, &g, law, &opts).unwrap();
            assert_eq!(sol.report.status, SolveStatus::Converged);
            let star: Vec<f64> = sol.lambda_n.iter().chain(&sol.lambda_t).copied().collect();
            let c = star.len();
            let mut u0 = f.clone();
            pb.factor().solve_vec(&mut u0);
            let mut b = vec![0.0; c];
            pb.dual.rows().mul_vec(&u0, &mut b);
            b[..nodes].iter_mut().zip(&g).for_each(|(x, gi)| *x -= gi);
            let mut e = vec![0.0; c];
            let mut open = None;
            let slipping = (0..nodes)
                .filter(|&i| {
                    star[i] > 0.0 && star[nodes + i].abs() >= law.bound(i, star[i]) * (1.0 - 1e-9)
                })
                .count();
            let closed = star[..nodes].iter().filter(|&&v| v > 0.0).count();
            println!("{form:?} {name}: {closed} closed, {slipping} slipping");
            assert!(slipping > 0 && slipping < closed && closed < nodes);
            for i in 0..nodes {
                if star[i] == 0.0 {
                    open.get_or_insert(i);
                    continue;
                }
                let bound = law.bound(i, star[i]);
                let lt = star[nodes + i];
                let slipping = lt.abs() >= bound * (1.0 - 1e-9);
                e[i] = 1e-3 * star[i];
                // Coulomb's rim grows with lambda_N: a slipping pair scaled
                // with it stays on the rim; a sticking one scaled stays
                // inside where it keeps a margin.
                let scaled = law.bound(i, star[i] + 2.0 * e[i]);
                if matches!(law, Friction::Coulomb(_)) && slipping
                    || !slipping && (1.002 * lt).abs() < scaled
                {
                    e[nodes + i] = 1e-3 * lt;
                }
            }
            for moved in [false, true] {
                let mut lam: Vec<f64> = star.iter().zip(&e).map(|(s, x)| s + x).collect();
                let mut before: Vec<f64> = star.iter().zip(&e).map(|(s, x)| s + 2.0 * x).collect();
                let what = format!("{form:?} {name}, moved {moved}");
                if moved {
                    let i = open.expect("an open contact");
                    let eps = 1e-3 * star.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                    lam[i] = eps;
                    before[i] = 3.0 * eps;
                }
                let at = DualProblem::new(&pb.dual, &b, law);
                let (w, from) = solve::iteration_line(&at, &before, 2, &mut lam, None, None);
                let res0 = from.unwrap_or_else(|| panic!("{what}: the line was not taken"));
                let scale = star.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let off = lam
                    .iter()
                    .zip(&star)
                    .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
                assert!(off <= 1e-8 * scale, "{what}: {off:.2e} from lambda*");
                let mut exact = vec![0.0; c];
                at.gradient(&lam, &mut exact);
                let wscale = b.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let diff = w
                    .iter()
                    .zip(&exact)
                    .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
                assert!(diff <= 1e-12 * wscale, "{what}: w off by {diff:.2e}");
                let res = at.natural_residual(&lam, &w);
                assert!(res <= 1e-4 * res0, "{what}: |F| {res0:.2e} -> {res:.2e}");
            }
        }
    }
}

/// The products that ride along a right-hand side's solve
/// (`Dual::solve_with_products`, one block solve of [f, B^T x1, B^T x2])
/// equal K^-1 f by its own solve and A x1, A x2 by their own products, to
/// rounding; on the dense dual nothing rides and nothing is written.
#[test]
fn products_ride_along_a_right_hand_sides_solve() {
    let nodes = 40;
    let f: Vec<f64> = (0..2 * nodes)
        .map(|j| ((j * 7) % 11) as f64 - 5.0)
        .collect();
    let x1: Vec<f64> = (0..2 * nodes).map(|i| ((i % 5) as f64) * 1e-3).collect();
    let x2: Vec<f64> = (0..2 * nodes)
        .map(|i| if i % 3 == 0 { -2e-3 } else { 0.0 })
        .collect();
    for form in [DualForm::MatrixFree, DualForm::Dense] {
        let (pb, _) = strip(nodes, form);
        let factor = pb.stiff.factor().expect("its own factor").clone();
        let c = pb.dual.c;
        let mut u = f.clone();
        let mut ys = vec![vec![0.0; c]; 2];
        let rode = pb
            .dual
            .solve_with_products(&factor, &mut u, &[&x1, &x2], &mut ys, None)
            .unwrap();
        if form == DualForm::Dense {
            assert!(!rode);
            assert_eq!(u, f);
            assert!(ys.iter().flatten().all(|&v| v == 0.0));
            continue;
        }
        assert!(rode);
        let mut want = f.clone();
        factor.solve_vec(&mut want);
        assert_close(&u, &want, 1e-13, "K^-1 f");
        for (x, y) in [&x1, &x2].into_iter().zip(&ys) {
            let mut ax = vec![0.0; c];
            pb.dual.apply(x, &mut ax);
            assert_close(y, &ax, 1e-13, "A x");
        }
    }
}

/// The block of a host iteration's start gives u at its multipliers
/// (`dual::Primal`): K^-1 (f - B^T x1), with z = K^-1 B^T x2 of the line's
/// direction; a product that keeps its solution gives K^-1 B^T x. Each
/// against a solve of its own.
#[test]
fn the_start_block_and_a_kept_product_give_their_solutions() {
    let nodes = 40;
    let (pb, _) = strip(nodes, DualForm::MatrixFree);
    assert!(pb.dual.keeps_solutions());
    let factor = pb.stiff.factor().expect("its own factor").clone();
    let (n, c) = (2 * nodes, pb.dual.c);
    let solved = |mut x: Vec<f64>| {
        factor.solve_vec(&mut x);
        x
    };
    let bt = |x: &[f64]| {
        let mut y = vec![0.0; n];
        pb.dual.rows.mul_t_vec(x, &mut y);
        y
    };
    let f: Vec<f64> = (0..n).map(|j| ((j * 7) % 11) as f64 - 5.0).collect();
    let x1: Vec<f64> = (0..c).map(|i| ((i % 5) as f64) * 1e-3).collect();
    let x2: Vec<f64> = (0..c)
        .map(|i| if i % 3 == 0 { -2e-3 } else { 0.0 })
        .collect();
    let mut primal = crate::dual::Primal::new(n, c).expect("room");
    let mut u = f.clone();
    let mut ys = vec![vec![0.0; c]; 2];
    let rode = pb
        .dual
        .solve_with_products(&factor, &mut u, &[&x1, &x2], &mut ys, Some(&mut primal))
        .unwrap();
    assert!(rode && primal.holds_at(&x1));
    assert_close(&u, &solved(f.clone()), 1e-13, "K^-1 f");
    let r: Vec<f64> = f.iter().zip(bt(&x1)).map(|(a, b)| a - b).collect();
    let want = solved(r);
    assert_close(
        primal.u_at(&x1, 1e-10).expect("u at x1"),
        &want,
        1e-13,
        "u at x1",
    );
    assert_close(&primal.z, &solved(bt(&x2)), 1e-13, "z of x2");
    let mut ax = vec![0.0; c];
    let mut z = vec![f64::NAN; n];
    assert!(pb.dual.apply_keeping(&x2, &mut ax, &mut z));
    assert_close(&z, &solved(bt(&x2)), 1e-13, "the kept product's z");
    let mut want_ax = vec![0.0; c];
    pb.dual.apply(&x2, &mut want_ax);
    assert_close(&ax, &want_ax, 1e-13, "the kept product's A x");
}

/// A host loop on a thin 3D lattice slab (matrix-free, Coulomb, pressed
/// in a patch and dragged, three increments of three iterations; each
/// iteration's load perturbed so that it has Newton steps to take): from
/// its second solve on, the recovery takes the u carried with the iterate
/// (`dual::Primal`) through the block's start, the increments' prediction,
/// the iterations' line and the Newton steps; du equals K^-1 (r - B^T
/// lambda) by a solve of its own to rounding, and each iteration's answer
/// a fresh handle's solve of the same iteration.
#[test]
fn a_host_iteration_carries_u_to_its_answer() {
    use crate::test_scenes::{lattice, slab_contacts};
    let (nx, ny, nz) = (12, 12, 3);
    let k = lattice(nx, ny, nz, 0.05);
    let (n, m) = (k.nrows, nx * ny);
    let (nm, tm) = slab_contacts(nx, ny, n);
    let opts = Options {
        dual_form: DualForm::MatrixFree,
        ..Options::default()
    };
    let make =
        || ContactProblem::from_csc_with(3, k.clone(), nm.clone(), tm.clone(), &opts).unwrap();
    let mut pb = make();
    assert!(!pb.dual.trailing && pb.dual.keeps_solutions());
    let factor = pb.stiff.factor().expect("its own factor").clone();
    let mu = vec![0.3; m];
    let law = Friction::Coulomb(&mu);
    // The gap closes in a round central patch.
    let centre = (nx as f64 - 1.0) / 2.0;
    let g0: Vec<f64> = (0..m)
        .map(|i| {
            let (x, y) = ((i % nx) as f64 - centre, (i / nx) as f64 - centre);
            0.02 * (x * x + y * y)
        })
        .collect();
    // The top layer pushed towards the face (N = e_z) and dragged along x,
    // more at each increment; the "host" linear: r = f_j - K u_j, g_j = g0
    // - N u_j, s_j = T (u_j - u_n).
    let top = 3 * nx * ny * (nz - 1);
    let mut u = vec![0.0; n];
    let before = solve::CARRIED.with(|x| x.get());
    let mut solves = 0;
    for inc in 1..=3 {
        let u_n = u.clone();
        for j in 0..3 {
            let what = format!("increment {inc}, iteration {j}");
            let scale = inc as f64 * (1.0 + 0.03 * (j as f64));
            let f: Vec<f64> = (0..n)
                .map(|i| match (i >= top, i % 3) {
                    (true, 2) => 0.01 * scale,
                    (true, 0) => 0.002 * scale,
                    _ => 0.0,
                })
                .collect();
            let mut ku = vec![0.0; n];
            k.mul_vec(&u, &mut ku);
            let r: Vec<f64> = f.iter().zip(&ku).map(|(a, b)| a - b).collect();
            let mut nu = vec![0.0; m];
            nm.mul_vec(&u, &mut nu);
            let g: Vec<f64> = g0.iter().zip(&nu).map(|(a, b)| a - b).collect();
            let taken: Vec<f64> = u.iter().zip(&u_n).map(|(a, b)| a - b).collect();
            let mut s = vec![0.0; 2 * m];
            tm.mul_vec(&taken, &mut s);
            let it = HostIteration {
                r: &r,
                g: &g,
                slip: (j > 0).then_some(&s[..]),
                lt_start: None,
            };
            let sol = pb.solve_iteration(&it, law, &opts).unwrap();
            solves += 1;
            assert_eq!(sol.report.status, SolveStatus::Converged, "{what}");
            let lam: Vec<f64> = sol.lambda_n.iter().chain(&sol.lambda_t).copied().collect();
            let closed = sol.lambda_n.iter().filter(|&&v| v > 0.0).count();
            assert!(closed > 0 && closed < m, "{what}: {closed} closed");
            let mut btl = vec![0.0; n];
            pb.dual.rows.mul_t_vec(&lam, &mut btl);
            let mut want: Vec<f64> = r.iter().zip(&btl).map(|(a, b)| a - b).collect();
            factor.solve_vec(&mut want);
            assert_close(&sol.u, &want, 1e-12, &format!("{what}: du"));
            // A fresh handle on the same iteration answers the same.
            let cold = make().solve_iteration(&it, law, &opts).unwrap();
            let cold_lam: Vec<f64> = cold
                .lambda_n
                .iter()
                .chain(&cold.lambda_t)
                .copied()
                .collect();
            assert_close(&lam, &cold_lam, 1e-7, &format!("{what}: lambda"));
            for (ui, di) in u.iter_mut().zip(&sol.u) {
                *ui += di;
            }
        }
    }
    // Every solve but the first (from zero, with no block to start from).
    let carried = solve::CARRIED.with(|x| x.get()) - before;
    assert_eq!(carried, solves - 1, "recoveries carried");
}
