//! Interface compliance (docs/design.md section 8): the linear
//! normal compliance law lambda_N = c_N (N u - g)_+ and the elastic slip
//! lambda_T = proj_{|x| <= p}(lambda_T,prev + k_T T u), checked against
//! - closed forms on one node on springs (the forces by hand), in a single
//!   solve and along a history that sticks, slips, unloads and reverses,
//!   with k_T changed halfway (the elastic slip carries over);
//! - the regularised KKT conditions, computed here from u and the forces, on a
//!   2D and a 3D finite element scene, every method, dense and matrix-free,
//!   with rigid and compliant contacts mixed;
//! - the rigid limit: as c_N and k_T grow the answer tends to the
//!   Signorini-Coulomb one at the rate 1 / c (the order measured over three
//!   stiffnesses);
//! - bad input: its error kind, and the handle keeps its previous law.

mod common;

use common::{Mesh, Scene, max_diff, mul, mul_t, norm_inf, norm2, opts, slip_bounds};
use dualsplit::{
    ContactProblem, Csc, DualForm, ErrorKind, Friction, Method, Options, Solution, SolveStatus,
};

const INF: f64 = f64::INFINITY;

/// One node of dimension d on a spring of stiffness k in every direction,
/// above a foundation at distance g (N = -e_d, T = the other unit vectors).
fn one_node(d: usize, k: f64) -> ContactProblem {
    let kk = Csc {
        nrows: d,
        ncols: d,
        col_ptr: (0..=d).collect(),
        row_idx: (0..d).collect(),
        values: vec![k; d],
    };
    // N: one row, -1 on the last DOF.
    let mut n_ptr = vec![0; d + 1];
    n_ptr[d] = 1;
    let n = Csc {
        nrows: 1,
        ncols: d,
        col_ptr: n_ptr,
        row_idx: vec![0],
        values: vec![-1.0],
    };
    // T: row s = +1 on DOF s, s < d - 1.
    let t = Csc {
        nrows: d - 1,
        ncols: d,
        col_ptr: (0..=d).map(|j| j.min(d - 1)).collect(),
        row_idx: (0..d - 1).collect(),
        values: vec![1.0; d - 1],
    };
    ContactProblem::from_csc(d, kk, n, t).unwrap()
}

fn close(what: &str, got: f64, want: f64) {
    assert!(
        (got - want).abs() <= 1e-9 * want.abs().max(1.0),
        "{what}: got {got}, want {want}"
    );
}

fn converged(what: &str, sol: &Solution) {
    assert_eq!(
        sol.report.status,
        SolveStatus::Converged,
        "{what}: {:?}",
        sol.report
    );
    assert!(sol.report.err <= 1e-10, "{what}: err {}", sol.report.err);
}

#[test]
fn one_node_pressed_into_a_compliant_foundation() {
    // k u = f - N^T lambda_N on the last DOF: k u_z = -F + lambda_N; the
    // penetration delta = -u_z - g carries lambda_N = c_N delta, so
    // delta = (F - k g) / (k + c_N) and lambda_N = c_N (F - k g) / (k + c_N).
    let (k, f, g) = (10.0, 20.0, 0.1);
    for d in [2, 3] {
        for cn in [40.0, 1e3, INF] {
            let mut pb = one_node(d, k);
            pb.set_compliance(Some(&[cn]), None, None).unwrap();
            let mut load = vec![0.0; d];
            load[d - 1] = -f;
            let sol = pb
                .solve(&load, &[g], Friction::Tresca(&[0.0]), &Options::default())
                .unwrap();
            converged("pressed", &sol);
            let want = if cn.is_finite() {
                cn * (f - k * g) / (k + cn)
            } else {
                f - k * g
            };
            close(
                &format!("d = {d}, c_N = {cn}: lambda_N"),
                sol.lambda_n[0],
                want,
            );
            close("u_z", sol.u[d - 1], (-f + want) / k);
            assert_eq!(sol.report.compliant_contacts, usize::from(cn.is_finite()));
        }
        // A load too small to reach the foundation leaves it open.
        let mut pb = one_node(d, k);
        pb.set_compliance(Some(&[40.0]), None, None).unwrap();
        let mut load = vec![0.0; d];
        load[d - 1] = -0.5;
        let sol = pb
            .solve(&load, &[g], Friction::Tresca(&[0.0]), &Options::default())
            .unwrap();
        converged("open", &sol);
        assert_eq!(sol.lambda_n[0], 0.0);
        close("open u_z", sol.u[d - 1], -0.05);
    }
}

#[test]
fn one_node_sticks_elastically_then_slides() {
    // Tangentially k u_t = f_t - lambda_T with lambda_T = proj_p(k_T u_t):
    // sticking, lambda_T = k_T f_t / (k + k_T); sliding, lambda_T = p f_t / |f_t|.
    // Coulomb: p = mu lambda_N, lambda_N from the normal law above.
    let (k, kt, cn, f, g, mu) = (10.0, 30.0, 40.0, 20.0, 0.1, 0.4);
    let lambda_n = cn * (f - k * g) / (k + cn); // 15.2, p = 6.08
    let p = mu * lambda_n;
    for method in [
        Method::Auto,
        Method::Newton,
        Method::Pgs,
        Method::Split,
        Method::Mprgp,
    ] {
        for ft in [[2.0, -3.0], [12.0, 9.0]] {
            let mut pb = one_node(3, k);
            pb.set_compliance(Some(&[cn]), None, Some(&[kt])).unwrap();
            let sol = pb
                .solve(
                    &[ft[0], ft[1], -f],
                    &[g],
                    Friction::Coulomb(&[mu]),
                    &opts(method),
                )
                .unwrap();
            let what = format!("{} f_t = {ft:?}", method.name());
            converged(&what, &sol);
            close(&what, sol.lambda_n[0], lambda_n);
            let stick: Vec<f64> = ft.iter().map(|v| kt * v / (k + kt)).collect();
            let want = if norm2(&stick) < p {
                stick
            } else {
                ft.iter().map(|v| p * v / norm2(&ft)).collect()
            };
            close(&what, sol.lambda_t[0], want[0]);
            close(&what, sol.lambda_t[1], want[1]);
            close(&what, sol.u[0], (ft[0] - want[0]) / k);
        }
    }
}

#[test]
fn a_history_carries_the_elastic_slip() {
    // 2D, Tresca p = 6, k = 10, k_T = 30, the normal load held. Each step's
    // force starts from the last one: sticking, lambda = lambda_prev + k_T du
    // with k (u_prev + du) = f_t - lambda, i.e.
    // lambda = lambda_prev + k_T (f_t - f_t,prev) / (k + k_T) where the last
    // step was in equilibrium (k u_prev + lambda_prev = f_t,prev).
    let (k, kt, cn, f, g, p) = (10.0, 30.0, 40.0, 20.0, 0.1, 6.0);
    let mut pb = one_node(2, k);
    pb.set_compliance(Some(&[cn]), None, Some(&[kt])).unwrap();
    let law = Friction::Tresca(&[p]);
    let step = |pb: &mut ContactProblem, ft: f64| {
        let sol = pb.step(&[ft, -f], &[g], law, &Options::default()).unwrap();
        converged(&format!("f_t = {ft}"), &sol);
        close("lambda_N", sol.lambda_n[0], 15.2);
        sol
    };
    // Load to 4: sticks, 0.75 * 4 = 3.
    let s = step(&mut pb, 4.0);
    close("stick", s.lambda_t[0], 3.0);
    // To 12: the trial 3 + 0.75 * 8 = 9 > 6 slides.
    let s = step(&mut pb, 12.0);
    close("slide", s.lambda_t[0], 6.0);
    close("slide u", s.u[0], 0.6);
    // Back to 10: sticks again from 6: 6 - 0.75 * 2 = 4.5 (a single solve at
    // 10 would slide: 0.75 * 10 = 7.5 > 6).
    let s = step(&mut pb, 10.0);
    close("unload", s.lambda_t[0], 4.5);
    close("unload u", s.u[0], 0.55);
    let one = one_node(2, k);
    let mut one = one;
    one.set_compliance(Some(&[cn]), None, Some(&[kt])).unwrap();
    let fresh = one
        .solve(&[10.0, -f], &[g], law, &Options::default())
        .unwrap();
    close("single solve", fresh.lambda_t[0], 6.0);
    // Reversed to -8: 4.5 - 0.75 * 18 = -9 slides backwards.
    let s = step(&mut pb, -8.0);
    close("reverse", s.lambda_t[0], -6.0);
    close("reverse u", s.u[0], -0.2);
    // k_T doubled: the elastic slip -6 / 30 carries over, the start is -12.
    // At -6: lambda = -12 + 60 du, 10 du = -6 - lambda + 2 (k u_prev = -2),
    // so 7 lambda = -12 - 24 = -36: sticks at -36 / 7.
    pb.set_compliance(Some(&[cn]), None, Some(&[2.0 * kt]))
        .unwrap();
    let s = step(&mut pb, -6.0);
    close("k_T changed", s.lambda_t[0], -36.0 / 7.0);
    // Rigid stick (the normal law kept): no elastic slip, du = 0.
    pb.set_compliance(Some(&[cn]), None, None).unwrap();
    let s = step(&mut pb, -5.0);
    assert_eq!(s.report.compliant_contacts, 1);
    // u_x stays at (-6 + 36 / 7) / 10 = -0.6 / 7; lambda_T = -5 - k u_x.
    close("rigid u", s.u[0], -0.6 / 7.0);
    close("rigid", s.lambda_t[0], -29.0 / 7.0);
}

/// The interface data of a check: c_N and k_T per contact, and where the
/// increment started, u_prev (n) and lambda_T,prev ((d - 1) m).
struct Law<'a> {
    cn: &'a [f64],
    mn: Option<&'a [f64]>,
    kt: &'a [f64],
    u_prev: &'a [f64],
    lt_prev: &'a [f64],
}

/// The regularised KKT conditions of `sol` for the total load `f`,
/// relative: equilibrium; per compliant normal lambda_N = c_N (N u - g)_+,
/// per rigid one N u <= g, lambda_N >= 0 and complementarity; per compliant
/// tangent lambda_T = proj_p(lambda_T,prev + k_T T du), per rigid one the
/// bound, stick and the slip direction of T du (du = u - u_prev).
fn regularised_kkt(
    sc: &Scene,
    f: &[f64],
    friction: Friction<'_>,
    law: &Law<'_>,
    sol: &Solution,
) -> f64 {
    let (cn, kt) = (law.cn, law.kt);
    let (d, m) = (sc.d, sc.m());
    let dt = d - 1;
    let ku = mul(&sc.k, &sol.u);
    let (ntl, ttl) = (mul_t(&sc.n, &sol.lambda_n), mul_t(&sc.t, &sol.lambda_t));
    let res: Vec<f64> = (0..ku.len())
        .map(|i| ku[i] - f[i] + ntl[i] + ttl[i])
        .collect();
    let mut worst = norm2(&res) / norm2(f).max(norm2(&ku));
    let du: Vec<f64> = sol.u.iter().zip(law.u_prev).map(|(a, b)| a - b).collect();
    let (nu, tu) = (mul(&sc.n, &sol.u), mul(&sc.t, &du));
    let p = slip_bounds(friction, &sol.lambda_n);
    let ls = norm_inf(&sol.lambda_n).max(norm_inf(&sol.lambda_t));
    let us = norm_inf(&sol.u).max(norm_inf(&sc.g));
    for i in 0..m {
        let v = nu[i] - sc.g[i];
        let l = sol.lambda_n[i];
        let e = if cn[i].is_finite() {
            let e = law.mn.map_or(1.0, |mn| mn[i]);
            (l - cn[i] * v.max(0.0).powf(e)).abs() / ls
        } else {
            (v.max(0.0) / us)
                .max((-l).max(0.0) / ls)
                .max((l / ls).min(v.abs() / us))
        };
        worst = worst.max(e);
        let lt = &sol.lambda_t[dt * i..dt * (i + 1)];
        let s = &tu[dt * i..dt * (i + 1)];
        let e = if kt[i].is_finite() {
            let prev = &law.lt_prev[dt * i..dt * (i + 1)];
            let mut trial: Vec<f64> = s.iter().zip(prev).map(|(x, l)| l + kt[i] * x).collect();
            let nt = norm2(&trial);
            if nt > p[i] {
                trial.iter_mut().for_each(|x| *x *= p[i] / nt);
            }
            max_diff(lt, &trial) / ls
        } else {
            let (nl, ns) = (norm2(lt), norm2(s));
            let bound = (nl - p[i]).max(0.0) / ls;
            let stick = ((p[i] - nl).max(0.0) / ls).min(ns / us);
            let dir = if nl > 0.0 {
                let dot: f64 = s.iter().zip(lt).map(|(a, b)| a * b).sum();
                let a = dot.max(0.0) / (nl * nl);
                norm2(&s.iter().zip(lt).map(|(x, y)| x - a * y).collect::<Vec<_>>()) / us
            } else {
                ns / us
            };
            bound.max(stick).max(if p[i] > 0.0 { dir } else { 0.0 })
        };
        worst = worst.max(e);
    }
    worst
}

fn scene(d: usize) -> Scene {
    if d == 2 {
        Scene::pressed_block(Mesh::grid2d(16, 4, 2.0, 1.0), &[0.006, -0.02], 0.05, &[1.0])
    } else {
        Scene::pressed_block(
            Mesh::grid3d(6, 6, 2, 2.0, 2.0, 1.0),
            &[0.006, 0.003, -0.03],
            0.05,
            &[1.0, 1.0],
        )
    }
}

/// Every method, dense and (where it runs on products) matrix-free, on `sc`
/// with compliant normals on even contacts and elastic slip on contacts
/// i % 3 != 0 (the rest rigid): each converges, passes the regularised KKT
/// check and agrees with the others.
fn every_method(
    sc: &Scene,
    friction: Friction<'_>,
    stiffness: f64,
    exponent: f64,
    methods: &[Method],
) {
    let m = sc.m();
    // Contacts i % 4 == 0 follow the power law lambda = c delta^exponent, its
    // c set so that it carries about what the linear law does at a
    // penetration of 0.01 (the scenes' scale).
    let mn: Vec<f64> = (0..m)
        .map(|i| if i % 4 == 0 { exponent } else { 1.0 })
        .collect();
    let cn: Vec<f64> = (0..m)
        .map(|i| match i % 2 {
            0 => stiffness / 0.01f64.powf(mn[i] - 1.0),
            _ => INF,
        })
        .collect();
    let kt: Vec<f64> = (0..m)
        .map(|i| if i % 3 != 0 { 0.5 * stiffness } else { INF })
        .collect();
    let mut first: Option<Vec<f64>> = None;
    for &method in methods {
        for form in [DualForm::Dense, DualForm::MatrixFree] {
            if form == DualForm::MatrixFree && method.needs_entries() {
                continue;
            }
            let what = format!("d = {} {} {form:?}", sc.d, method.name());
            let mut pb = sc.problem();
            pb.set_compliance(Some(&cn), Some(&mn), Some(&kt)).unwrap();
            let o = Options {
                dual_form: form,
                ..opts(method)
            };
            let sol = pb.solve(&sc.f, &sc.g, friction, &o).unwrap();
            converged(&what, &sol);
            let r = &sol.report;
            println!(
                "{what}: err {:.2e}, outer {}, open/stick/slip {}/{}/{}",
                r.err, r.outer_iterations, r.n_open, r.n_stick, r.n_slip
            );
            let (u0, l0) = (vec![0.0; sc.f.len()], vec![0.0; (sc.d - 1) * m]);
            let law = Law {
                cn: &cn,
                mn: Some(&mn),
                kt: &kt,
                u_prev: &u0,
                lt_prev: &l0,
            };
            let e = regularised_kkt(sc, &sc.f, friction, &law, &sol);
            assert!(e <= 1e-8, "{what}: regularised KKT violated by {e:.2e}");
            let lam: Vec<f64> = sol.lambda_n.iter().chain(&sol.lambda_t).copied().collect();
            match &first {
                None => {
                    // The compliance acts: the answer differs from the rigid one.
                    let rigid = sc.problem().solve(&sc.f, &sc.g, friction, &o).unwrap();
                    let lr: Vec<f64> = rigid
                        .lambda_n
                        .iter()
                        .chain(&rigid.lambda_t)
                        .copied()
                        .collect();
                    assert!(
                        max_diff(&lam, &lr) > 1e-3 * norm_inf(&lr),
                        "{what}: compliance changed nothing"
                    );
                    first = Some(lam)
                }
                Some(f) => {
                    let dl = max_diff(&lam, f);
                    assert!(
                        dl <= 1e-8 * norm_inf(f),
                        "{what}: differs from the first method by {dl:.2e}"
                    );
                }
            }
        }
    }
}

#[test]
fn every_method_solves_the_regularised_law_2d() {
    let sc = scene(2);
    let mu = vec![0.3; sc.m()];
    every_method(&sc, Friction::Coulomb(&mu), 200.0, 1.0, &Method::ALL);
    every_method(&sc, Friction::Coulomb(&mu), 200.0, 2.0, &Method::ALL);
}

#[test]
fn every_method_solves_the_regularised_law_3d() {
    let sc = scene(3);
    let p = vec![0.05; sc.m()];
    every_method(&sc, Friction::Tresca(&p), 200.0, 1.0, &Method::ALL);
    // The power law in 3D: the methods whose rounds are cheap in a debug
    // build (MPRGP and Pop's splitting with MPRGP sub-problems solve it on
    // the 2D scene and the one-node foundations).
    let cheap = [
        Method::Auto,
        Method::Newton,
        Method::Split,
        Method::BlockGs,
        Method::Pgs,
    ];
    every_method(&sc, Friction::Tresca(&p), 200.0, 3.5, &cheap);
    let mu = vec![0.3; sc.m()];
    every_method(&sc, Friction::Coulomb(&mu), 200.0, 1.0, &Method::ALL);
    every_method(&sc, Friction::Coulomb(&mu), 200.0, 1.5, &cheap);
}

#[test]
fn the_rigid_limit_is_reached_at_the_rate_one_over_c() {
    for d in [2, 3] {
        let sc = scene(d);
        let mu = vec![0.3; sc.m()];
        let law = Friction::Coulomb(&mu);
        let o = Options::default();
        let rigid = sc.problem().solve(&sc.f, &sc.g, law, &o).unwrap();
        let lr: Vec<f64> = rigid
            .lambda_n
            .iter()
            .chain(&rigid.lambda_t)
            .copied()
            .collect();
        let errs: Vec<f64> = [1e4, 1e5, 1e6]
            .iter()
            .map(|&s| {
                let mut pb = sc.problem();
                pb.set_compliance(Some(&vec![s; sc.m()]), None, Some(&vec![s; sc.m()]))
                    .unwrap();
                let sol = pb.solve(&sc.f, &sc.g, law, &o).unwrap();
                converged("stiff", &sol);
                let lam: Vec<f64> = sol.lambda_n.iter().chain(&sol.lambda_t).copied().collect();
                max_diff(&lam, &lr) / norm_inf(&lr)
            })
            .collect();
        let order = (errs[0] / errs[2]).log10() / 2.0;
        println!("d = {d}: deviation from the rigid answer {errs:?}, order {order:.3}");
        assert!(
            (0.9..=1.1).contains(&order),
            "d = {d}: order {order} from {errs:?}"
        );
        assert!(errs[2] < 1e-3, "d = {d}: {errs:?}");
    }
}

#[test]
fn bad_interface_data_is_refused_and_the_law_kept() {
    let sc = scene(2);
    let m = sc.m();
    let mu = vec![0.3; m];
    let law = Friction::Coulomb(&mu);
    let mut pb = sc.problem();
    let cn = vec![200.0; m];
    pb.set_compliance(Some(&cn), None, None).unwrap();
    let before = pb.solve(&sc.f, &sc.g, law, &Options::default()).unwrap();
    let mut zero = cn.clone();
    zero[3] = 0.0;
    let mut nan = cn.clone();
    nan[1] = f64::NAN;
    type Data<'a> = Option<&'a [f64]>;
    let cases: [(Data<'_>, Data<'_>, Data<'_>, ErrorKind); 6] = [
        (Some(&zero), None, None, ErrorKind::BadArgument),
        (Some(&nan), None, None, ErrorKind::NotFinite),
        (Some(&cn[1..]), None, None, ErrorKind::BadSize),
        (None, Some(&vec![0.5; m]), None, ErrorKind::BadArgument),
        (
            Some(&cn),
            Some(&vec![11.0; m]),
            None,
            ErrorKind::BadArgument,
        ),
        (None, None, Some(&vec![-1.0; m]), ErrorKind::BadArgument),
    ];
    for (c, e, k, kind) in cases {
        let err = pb.set_compliance(c, e, k).unwrap_err();
        assert_eq!(err.kind, kind, "{}", err.message);
        let after = pb.solve(&sc.f, &sc.g, law, &Options::default()).unwrap();
        assert_eq!(
            after.lambda_n, before.lambda_n,
            "the law changed after: {}",
            err.message
        );
        assert_eq!(after.report.compliant_contacts, m);
    }
}

#[test]
fn a_compliant_history_meets_the_incremental_law_at_every_step() {
    // The 3D scene's load raised in four steps, then lowered in two (the
    // contacts stick on the way back): every step's answer meets the return
    // mapping from the last step's force, dense and matrix-free alike; a
    // quarter of the contacts on the power law m_N = 2.
    let sc = scene(3);
    let m = sc.m();
    let mu = vec![0.3; m];
    let friction = Friction::Coulomb(&mu);
    let mn: Vec<f64> = (0..m).map(|i| if i % 4 == 0 { 2.0 } else { 1.0 }).collect();
    let cn: Vec<f64> = (0..m)
        .map(|i| match i % 2 {
            0 => 300.0 / 0.01f64.powf(mn[i] - 1.0),
            _ => INF,
        })
        .collect();
    let kt = vec![150.0; m];
    let loads: Vec<Vec<f64>> = [0.25, 0.5, 0.75, 1.0, 0.8, 0.6]
        .iter()
        .map(|&a| sc.f.iter().map(|v| a * v).collect())
        .collect();
    let mut answers: Vec<Vec<Vec<f64>>> = Vec::new();
    for form in [DualForm::Dense, DualForm::MatrixFree] {
        let mut pb = sc.problem();
        pb.set_compliance(Some(&cn), Some(&mn), Some(&kt)).unwrap();
        let o = Options {
            dual_form: form,
            ..Options::default()
        };
        let (mut u_prev, mut lt_prev) = (vec![0.0; sc.f.len()], vec![0.0; 2 * m]);
        let mut lams = Vec::new();
        for (s, f) in loads.iter().enumerate() {
            let sol = pb.step(f, &sc.g, friction, &o).unwrap();
            let what = format!("{form:?} step {s}");
            converged(&what, &sol);
            let law = Law {
                cn: &cn,
                mn: Some(&mn),
                kt: &kt,
                u_prev: &u_prev,
                lt_prev: &lt_prev,
            };
            let e = regularised_kkt(&sc, f, friction, &law, &sol);
            assert!(e <= 1e-8, "{what}: incremental law violated by {e:.2e}");
            u_prev = sol.u.clone();
            lt_prev = sol.lambda_t.clone();
            lams.push(sol.lambda_n.iter().chain(&sol.lambda_t).copied().collect());
        }
        answers.push(lams);
    }
    for (a, b) in answers[0].iter().zip(&answers[1]) {
        assert!(
            max_diff(a, b) <= 1e-8 * norm_inf(a),
            "dense and matrix-free histories differ"
        );
    }
}

#[test]
fn a_compliant_increment_replays_from_its_folder() {
    // Two steps of a compliant history; the third step's increment written
    // to a problem folder (cn.txt, mn.txt, kt.txt and the history's
    // lt_prev.txt beside K, N, T, f, g, mu) and replayed through the Rust
    // reader and the command line: the same forces and displacement
    // increment as the step on the handle.
    let sc = scene(2);
    let m = sc.m();
    let mu = vec![0.3; m];
    let friction = Friction::Coulomb(&mu);
    let cn: Vec<f64> = (0..m)
        .map(|i| if i % 2 == 0 { 300.0 } else { INF })
        .collect();
    let kt: Vec<f64> = (0..m)
        .map(|i| if i % 3 == 0 { INF } else { 150.0 })
        .collect();
    let mut pb = sc.problem();
    pb.set_compliance(Some(&cn), None, Some(&kt)).unwrap();
    let o = Options::default();
    let load = |a: f64| -> Vec<f64> { sc.f.iter().map(|v| a * v).collect() };
    let mut u = vec![0.0; sc.f.len()];
    for a in [0.4, 0.8] {
        u = pb.step(&load(a), &sc.g, friction, &o).unwrap().u;
    }
    let f3 = load(0.6);
    let ku = mul(&sc.k, &u);
    let nu = mul(&sc.n, &u);
    let f_inc: Vec<f64> = f3.iter().zip(&ku).map(|(a, b)| a - b).collect();
    let g_inc: Vec<f64> = sc.g.iter().zip(&nu).map(|(a, b)| a - b).collect();
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("compliant_increment");
    let _ = std::fs::remove_dir_all(&dir);
    pb.write_folder(&dir, &f_inc, &g_inc, friction).unwrap();
    for file in ["cn.txt", "mn.txt", "kt.txt", "lt_prev.txt"] {
        assert!(dir.join(file).is_file(), "{file} not written");
    }
    let step = pb.step(&f3, &sc.g, friction, &o).unwrap();
    converged("step 3", &step);
    let du: Vec<f64> = step.u.iter().zip(&u).map(|(a, b)| a - b).collect();

    let folder = dualsplit::mtx::read_problem(&dir).unwrap();
    let law = &folder.interface;
    assert_eq!(
        law.cn.as_deref(),
        Some(&cn[..]),
        "cn.txt with inf round trip"
    );
    let mut replay = ContactProblem::from_csc(2, folder.k, folder.n, folder.t).unwrap();
    replay
        .set_compliance(law.cn.as_deref(), law.mn.as_deref(), law.kt.as_deref())
        .unwrap();
    let fric = folder.friction.as_friction();
    let lt = law.lt_prev.as_deref();
    let sol = replay
        .solve_history_increment(&folder.f, &folder.g, fric, lt, &o, None)
        .unwrap();
    converged("replay", &sol);
    let scale = norm_inf(&step.lambda_n);
    assert!(max_diff(&sol.lambda_n, &step.lambda_n) <= 1e-8 * scale);
    assert!(max_diff(&sol.lambda_t, &step.lambda_t) <= 1e-8 * scale);
    assert!(max_diff(&sol.u, &du) <= 1e-8 * norm_inf(&du));
    // Without lt_prev the increment is another problem (the history matters).
    let plain = replay.solve(&folder.f, &folder.g, fric, &o).unwrap();
    assert!(max_diff(&plain.lambda_t, &step.lambda_t) > 1e-4 * scale);

    // The command line reads the same folder.
    let out = dir.join("out");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_dualsplit"))
        .args([
            "solve",
            dir.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let lt_cli = dualsplit::mtx::read_vector(&out.join("lambda_t.txt")).unwrap();
    assert!(max_diff(&lt_cli, &step.lambda_t) <= 1e-8 * scale);
    let compliant = (0..m).filter(|&i| i % 2 == 0 || i % 3 != 0).count();
    assert_eq!(pb.info(&o).compliant_contacts, compliant);
    let json = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(
        json.contains(&format!("\"compliant_contacts\": {compliant}")),
        "{json}"
    );
    let info = std::process::Command::new(env!("CARGO_BIN_EXE_dualsplit"))
        .args(["info", dir.to_str().unwrap()])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&info.stdout);
    assert!(
        said.contains(&format!("compliant on {compliant} contacts")),
        "{said}"
    );

    // A short kt.txt, a NaN in cn.txt and -inf are refused by the reader.
    std::fs::write(dir.join("kt.txt"), "1\n2\n").unwrap();
    let e = dualsplit::mtx::read_problem(&dir).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadSize, "{}", e.message);
    assert!(e.message.contains("kt.txt"), "{}", e.message);
    std::fs::remove_file(dir.join("kt.txt")).unwrap();
    for bad in ["nan", "-inf"] {
        let text = format!("{bad}\n{}", "1\n".repeat(m - 1));
        std::fs::write(dir.join("cn.txt"), text).unwrap();
        let e = dualsplit::mtx::read_problem(&dir).unwrap_err();
        assert_eq!(e.kind, ErrorKind::Io, "{}", e.message);
        assert!(e.message.contains("cn.txt"), "{}", e.message);
    }

    // A rigid handle's dump removes the interface files.
    pb.set_compliance(None, None, None).unwrap();
    pb.write_folder(&dir, &f_inc, &g_inc, friction).unwrap();
    assert!(!dir.join("cn.txt").exists() && !dir.join("lt_prev.txt").exists());
}

#[test]
fn one_node_on_a_power_law_foundation() {
    // lambda_N = c delta^m with k u_z = -F + lambda_N, delta = -u_z - g:
    // c delta^m + k delta = F - k g, solved here by bisection (the left side
    // increases): the independent truth for every method, cold and along a
    // history of growing loads (each step warm).
    let (k, g) = (10.0, 0.1);
    let root = |c: f64, e: f64, rhs: f64| {
        let (mut lo, mut hi) = (0.0f64, rhs / k);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if c * mid.powf(e) + k * mid > rhs {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        0.5 * (lo + hi)
    };
    for (d, c, e) in [(2, 400.0, 2.0), (3, 5e3, 3.0), (3, 40.0, 1.5)] {
        for method in [
            Method::Auto,
            Method::Newton,
            Method::Pgs,
            Method::Split,
            Method::Mprgp,
        ] {
            let mut pb = one_node(d, k);
            pb.set_compliance(Some(&[c]), Some(&[e]), None).unwrap();
            for f in [20.0, 5.0, 30.0] {
                let mut load = vec![0.0; d];
                load[d - 1] = -f;
                let what = format!("d = {d}, m = {e}, {} F = {f}", method.name());
                let sol = pb
                    .solve(&load, &[g], Friction::Tresca(&[0.0]), &opts(method))
                    .unwrap();
                converged(&what, &sol);
                let delta = root(c, e, f - k * g);
                close(&what, sol.lambda_n[0], c * delta.powf(e));
                close(&what, sol.u[d - 1], -delta - g);
            }
            let mut pb = one_node(d, k);
            pb.set_compliance(Some(&[c]), Some(&[e]), None).unwrap();
            for f in [5.0, 10.0, 20.0, 40.0] {
                let mut load = vec![0.0; d];
                load[d - 1] = -f;
                let what = format!("history d = {d}, m = {e}, {} F = {f}", method.name());
                let sol = pb
                    .step(&load, &[g], Friction::Tresca(&[0.0]), &opts(method))
                    .unwrap();
                converged(&what, &sol);
                let delta = root(c, e, f - k * g);
                close(&what, sol.lambda_n[0], c * delta.powf(e));
            }
        }
    }
}

#[test]
fn a_power_law_step_that_loads_an_unloaded_contact_meets_the_law() {
    // K = I on two 2D nodes, both on power-law foundations (c = 1e4, m = 2),
    // frictionless. Step 1 presses node A with 1e6; step 2 adds 0.1 at node B,
    // which starts the round open. Node B's penetration x solves
    // x + c x^2 = 0.1 (u_y = -0.1 + lambda, lambda = c x^2): closed form.
    let (c, e) = (1e4, 2.0);
    let k = Csc {
        nrows: 4,
        ncols: 4,
        col_ptr: (0..=4).collect(),
        row_idx: (0..4).collect(),
        values: vec![1.0; 4],
    };
    let n = Csc {
        nrows: 2,
        ncols: 4,
        col_ptr: vec![0, 0, 1, 1, 2],
        row_idx: vec![0, 1],
        values: vec![-1.0, -1.0],
    };
    let t = Csc {
        nrows: 2,
        ncols: 4,
        col_ptr: vec![0, 1, 1, 2, 2],
        row_idx: vec![0, 1],
        values: vec![1.0, 1.0],
    };
    let x_b = (-1.0 + (1.0f64 + 4.0 * c * 0.1).sqrt()) / (2.0 * c);
    let x_a = (-1.0 + (1.0f64 + 4.0 * c * 1e6).sqrt()) / (2.0 * c);
    for method in [Method::Auto, Method::Newton, Method::Pgs, Method::Mprgp] {
        let mut pb = ContactProblem::from_csc(2, k.clone(), n.clone(), t.clone()).unwrap();
        pb.set_compliance(Some(&[c, c]), Some(&[e, e]), None)
            .unwrap();
        let law = Friction::Tresca(&[0.0, 0.0]);
        let o = opts(method);
        let what = format!("{} step 1", method.name());
        let s1 = pb
            .step(&[0.0, -1e6, 0.0, 0.0], &[0.0, 0.0], law, &o)
            .unwrap();
        converged(&what, &s1);
        close(&what, s1.lambda_n[0], c * x_a * x_a);
        assert_eq!(s1.lambda_n[1], 0.0, "{what}");
        let what = format!("{} step 2", method.name());
        let s2 = pb
            .step(&[0.0, -1e6, 0.0, -0.1], &[0.0, 0.0], law, &o)
            .unwrap();
        converged(&what, &s2);
        // err <= tol is relative to |lambda| (about 1e6 here): node B's force
        // within a few tol |lambda| of the law's (0 before the law's own err
        // was measured: 1e-7 |lambda| off, reported converged).
        let scale = s2.lambda_n[0];
        assert!(
            (s2.lambda_n[1] - c * x_b * x_b).abs() <= 4.0 * o.tol * scale,
            "{what}: lambda_N,B = {}, the law gives {} ({:?})",
            s2.lambda_n[1],
            c * x_b * x_b,
            s2.report
        );
        assert!(
            (s2.u[3] + x_b).abs() <= 4.0 * o.tol * scale,
            "{what}: u {}",
            s2.u[3]
        );
        close(&what, s2.lambda_n[0], c * x_a * x_a);
    }
}

#[test]
fn a_stiffness_whose_reciprocal_overflows_is_refused() {
    let mut pb = one_node(2, 10.0);
    for (cn, kt) in [(Some(&[1e-310][..]), None), (None, Some(&[4e-309][..]))] {
        let err = pb.set_compliance(cn, None, kt).unwrap_err();
        assert_eq!(err.kind, ErrorKind::BadArgument, "{}", err.message);
        assert!(err.message.contains("reciprocal"), "{}", err.message);
    }
    // A very soft law whose reciprocal is finite is taken: the node sinks
    // freely (k u_y = -20 + lambda_N, lambda_N = c (-u_y - 0.1)), lambda_N
    // = c (2 - 0.1) / (1 + c / 10) to rounding, and slides (|lambda_T| <=
    // k_T |u_x| = 0: no tangential force).
    let c = 1e-300;
    pb.set_compliance(Some(&[c]), None, Some(&[c])).unwrap();
    let sol = pb
        .solve(
            &[0.0, -20.0],
            &[0.1],
            Friction::Tresca(&[1.0]),
            &opts(Method::Auto),
        )
        .unwrap();
    converged("c = 1e-300", &sol);
    close("u_y", sol.u[1], -2.0);
    assert!(
        sol.lambda_n[0] >= 0.0 && sol.lambda_n[0] <= 1e-299,
        "{:?}",
        sol.lambda_n
    );
}
