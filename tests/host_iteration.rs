//! One iteration of a host's own Newton loop (`ContactProblem::solve_iteration`,
//! C `ds_solve_iteration`): friction on the slip of the whole increment, s_j +
//! T du, with the slip s_j the earlier iterations took.
//!
//! - closed forms on one node (docs/design.md section 9): a node that slipped in
//!   iteration 1 and sticks in iteration 2 (T du = -s_j), or slips back; a slip
//!   offset along a turning direction in 3D (the return mapping's direction);
//!   the elastic slip of a compliant contact from the increment's start force;
//!   each with every method and both dual forms, and checked by the KKT
//!   conditions of the offset problem;
//! - a host loop on a real scene: the first iteration on a wrong tangent (1.2 K),
//!   the second on K after `refactor`, lands on the increment's own solution
//!   (`solve` on the same K, N, T), which a third iteration leaves in place (du
//!   = 0, the same forces), with every method and both dual forms, 2D and 3D,
//!   Tresca and Coulomb;
//! - a warm start gives the cold answer;
//! - bad input: the slip of the wrong length or with a NaN, a K of another
//!   pattern: errors, and the handle's next iteration as before.

mod common;

use common::{Mesh, Owned, Scene, assert_close, assert_converged, mul, norm_inf, norm2};
use dualsplit::{
    ContactProblem, Csc, DualForm, ErrorKind, Friction, HostIteration, Method, Options, Solution,
};

/// Every method with each dual form it runs in.
fn configurations() -> Vec<Options> {
    let mut out = Vec::new();
    for method in Method::ALL {
        for form in [DualForm::Dense, DualForm::MatrixFree] {
            let matrix_free_ok = matches!(method, Method::Newton | Method::Mprgp | Method::Auto);
            if form == DualForm::MatrixFree && !matrix_free_ok {
                continue;
            }
            out.push(Options {
                method,
                dual_form: form,
                threads: 1,
                ..Options::default()
            });
        }
    }
    out
}

fn label(o: &Options) -> String {
    format!("{} / {}", o.method.name(), o.dual_form.name())
}

/// The KKT conditions of an iteration's problem (module docs), each violation
/// relative to the largest force or length: equilibrium K du = r - N^T
/// lambda_N - T^T lambda_T, N du <= g with complementarity, |lambda_T,i| <=
/// p_i, and the total slip w = s + T du zero inside the disc and a
/// non-negative multiple of lambda_T on its rim.
#[allow(clippy::too_many_arguments)]
fn kkt_iteration(
    d: usize,
    (k, n, t): (&Csc, &Csc, &Csc),
    (r, g, s): (&[f64], &[f64], &[f64]),
    p: &[f64],
    (du, ln, lt): (&[f64], &[f64], &[f64]),
) -> f64 {
    let dt = d - 1;
    let ku = mul(k, du);
    let ntl = common::mul_t(n, ln);
    let ttl = common::mul_t(t, lt);
    let res: Vec<f64> = (0..du.len())
        .map(|i| ku[i] - r[i] + ntl[i] + ttl[i])
        .collect();
    let eq = norm2(&res) / norm2(r).max(norm2(&ku)).max(f64::MIN_POSITIVE);
    let nu = mul(n, du);
    let mut w = mul(t, du);
    for (wi, si) in w.iter_mut().zip(s) {
        *wi += si;
    }
    let ls = norm_inf(ln).max(norm_inf(lt)).max(norm_inf(r));
    let us = norm_inf(du).max(norm_inf(g)).max(norm_inf(s));
    let mut worst = eq;
    for i in 0..n.nrows {
        let slack = g[i] - nu[i];
        worst = worst.max((-slack).max(0.0) / us);
        worst = worst.max((-ln[i]).max(0.0) / ls);
        worst = worst.max((ln[i].max(0.0) / ls).min(slack.abs() / us));
        let l = &lt[dt * i..dt * (i + 1)];
        let wi = &w[dt * i..dt * (i + 1)];
        let (ln_i, wn) = (norm2(l), norm2(wi));
        worst = worst.max((ln_i - p[i]).max(0.0) / ls);
        worst = worst.max(((p[i] - ln_i).max(0.0) / ls).min(wn / us));
        if p[i] > 0.0 && ln_i > 0.0 {
            let dot: f64 = wi.iter().zip(l).map(|(a, b)| a * b).sum();
            let alpha = dot.max(0.0) / (ln_i * ln_i);
            let off: Vec<f64> = wi.iter().zip(l).map(|(a, b)| a - alpha * b).collect();
            worst = worst.max(norm2(&off) / us);
        }
    }
    worst
}

/// One node: K = diag(kt, ..., 4) (tangential stiffness kt on each of the d - 1
/// horizontal DOFs, 4 on the vertical one), N = -e_vert (N du <= g reads du_vert
/// >= -g), T = the horizontal unit rows.
fn one_node(d: usize, kt: f64) -> (Csc, Csc, Csc) {
    let mut k: Vec<_> = (0..d - 1).map(|j| (j, j, kt)).collect();
    k.push((d - 1, d - 1, 4.0));
    let t: Vec<_> = (0..d - 1).map(|j| (j, j, 1.0)).collect();
    (
        Csc::from_triplets(d, d, &k),
        Csc::from_triplets(1, d, &[(0, d - 1, -1.0)]),
        Csc::from_triplets(d - 1, d, &t),
    )
}

struct Case<'a> {
    name: &'a str,
    d: usize,
    kt: f64,
    r: Vec<f64>,
    g: f64,
    slip: Vec<f64>,
    mu: f64,
    /// The closed form: du, lambda_N, lambda_T.
    want: (Vec<f64>, f64, Vec<f64>),
    /// (open, stick, slip).
    states: (usize, usize, usize),
}

/// Runs a one-node case with every method and form, each on a handle whose
/// previous iteration (the case with no slip offset) left other multipliers as
/// the start.
fn check_case(c: &Case<'_>) {
    let (k, n, t) = one_node(c.d, c.kt);
    let (want_u, want_n, want_t) = &c.want;
    let p = vec![c.mu * want_n];
    // The closed form satisfies the conditions itself.
    let exact = (&want_u[..], &[*want_n][..], &want_t[..]);
    let v = kkt_iteration(c.d, (&k, &n, &t), (&c.r, &[c.g], &c.slip), &p, exact);
    assert!(
        v <= 1e-14,
        "{}: the closed form violates KKT by {v:.2e}",
        c.name
    );
    let mu = [c.mu];
    for o in configurations() {
        let what = format!("{} [{}]", c.name, label(&o));
        let mut pb = ContactProblem::from_csc_with(c.d, k.clone(), n.clone(), t.clone(), &o)
            .expect("a valid problem");
        // An earlier iteration without offset (another answer: another start).
        let first = HostIteration {
            r: &c.r,
            g: &[c.g],
            slip: None,
            lt_start: None,
        };
        let s0 = pb
            .solve_iteration(&first, Friction::Coulomb(&mu), &o)
            .expect("the first iteration");
        assert_converged(&format!("{what}: first"), &s0);
        let it = HostIteration {
            slip: Some(&c.slip),
            ..first
        };
        let sol = pb
            .solve_iteration(&it, Friction::Coulomb(&mu), &o)
            .expect("the iteration");
        assert_converged(&what, &sol);
        assert_close(
            &format!("{what}: du"),
            &sol.u,
            want_u,
            1e-9,
            norm_inf(want_u),
        );
        let scale = want_n.abs().max(norm_inf(want_t));
        assert_close(
            &format!("{what}: lambda_N"),
            &sol.lambda_n,
            &[*want_n],
            1e-9,
            scale,
        );
        assert_close(
            &format!("{what}: lambda_T"),
            &sol.lambda_t,
            want_t,
            1e-9,
            scale,
        );
        let rep = &sol.report;
        assert_eq!(
            (rep.n_open, rep.n_stick, rep.n_slip),
            c.states,
            "{what}: states"
        );
        let got = (&sol.u[..], &sol.lambda_n[..], &sol.lambda_t[..]);
        let v = kkt_iteration(c.d, (&k, &n, &t), (&c.r, &[c.g], &c.slip), &p, got);
        assert!(v <= 1e-9, "{what}: KKT violated by {v:.2e}");
    }
}

/// Iteration 1 of the node (r = (10, -8), g = 0, mu = 0.5, kt = 2) slips:
/// lambda_N = 8, lambda_T = p = 4, du_x = (10 - 4) / 2 = 3. Iteration 2 with
/// the slip taken s = 3 and r = (-5, -8): sticking holds the total slip at
/// zero, du_x = -s = -3, so lambda_T = r_x - kt du_x = -5 + 6 = 1, inside the
/// disc |lambda_T| < 4.
#[test]
fn slipped_in_iteration_one_sticks_in_iteration_two() {
    check_case(&Case {
        name: "slip then stick",
        d: 2,
        kt: 2.0,
        r: vec![-5.0, -8.0],
        g: 0.0,
        slip: vec![3.0],
        mu: 0.5,
        want: (vec![-3.0, 0.0], 8.0, vec![1.0]),
        states: (0, 1, 0),
    });
}

/// As above with r = (-12, -8): the stick force r_x + kt s = -6 leaves the
/// disc, so the node slips back: lambda_T = -4, du_x = (-12 + 4) / 2 = -4, a
/// total slip s + du_x = -1 = 0.25 lambda_T (alpha >= 0).
#[test]
fn slipped_in_iteration_one_slips_back_in_iteration_two() {
    check_case(&Case {
        name: "slip then slip back",
        d: 2,
        kt: 2.0,
        r: vec![-12.0, -8.0],
        g: 0.0,
        slip: vec![3.0],
        mu: 0.5,
        want: (vec![-4.0, 0.0], 8.0, vec![-4.0]),
        states: (0, 0, 1),
    });
}

/// 3D, the slip taken s = (1, 0) and this iteration's load r_t = (0, 6) along
/// another direction (kt = 2, lambda_N = 8, mu = 0.5, p = 4). The total slip
/// s + (r_t - lambda_T) / kt must be parallel to lambda_T, so lambda_T lies
/// along the trial force r_t + kt s = (2, 6): lambda_T = 4 (2, 6) / sqrt(40),
/// du_t = (r_t - lambda_T) / kt.
#[test]
fn a_slip_offset_turns_the_slip_direction() {
    let q = 4.0 / 40f64.sqrt();
    let lt = vec![2.0 * q, 6.0 * q];
    let du = vec![(0.0 - lt[0]) / 2.0, (6.0 - lt[1]) / 2.0, 0.0];
    check_case(&Case {
        name: "turning slip",
        d: 3,
        kt: 2.0,
        r: vec![0.0, 6.0, -8.0],
        g: 0.0,
        slip: vec![1.0, 0.0],
        mu: 0.5,
        want: (du, 8.0, lt),
        states: (0, 0, 1),
    });
}

/// A compliant contact (k_T = 1) with the increment's start force lt_start = 1
/// and the slip taken s = 0.5: lambda_T = lt_start + k_T (s + du_x) with
/// 2 du_x = r_x - lambda_T, r_x = 1: lambda_T (1 + 1/2) = 1 + 0.5 + 0.5, so
/// lambda_T = 4/3 (inside p = 4) and du_x = -1/6. (Tresca p = 4, lambda_N = 8.)
#[test]
fn the_elastic_slip_starts_from_the_increments_force() {
    let (k, n, t) = one_node(2, 2.0);
    let r = [1.0, -8.0];
    for o in configurations() {
        let what = label(&o);
        let mut pb = ContactProblem::from_csc_with(2, k.clone(), n.clone(), t.clone(), &o)
            .expect("a valid problem");
        pb.set_compliance(None, None, Some(&[1.0])).expect("k_T");
        let it = HostIteration {
            r: &r,
            g: &[0.0],
            slip: Some(&[0.5]),
            lt_start: Some(&[1.0]),
        };
        let sol = pb
            .solve_iteration(&it, Friction::Tresca(&[4.0]), &o)
            .expect("the iteration");
        assert_converged(&what, &sol);
        assert_close(
            &format!("{what}: du"),
            &sol.u,
            &[-1.0 / 6.0, 0.0],
            1e-9,
            1.0,
        );
        assert_close(&format!("{what}: lambda"), &sol.lambda_n, &[8.0], 1e-9, 8.0);
        assert_close(
            &format!("{what}: lambda_T"),
            &sol.lambda_t,
            &[4.0 / 3.0],
            1e-9,
            8.0,
        );
    }
}

fn scenes() -> Vec<(&'static str, Scene)> {
    vec![
        (
            "2D strip",
            Scene::pressed_block(Mesh::grid2d(16, 4, 2.0, 1.0), &[0.006, -0.02], 0.05, &[1.0]),
        ),
        (
            "3D block, oblique",
            Scene::pressed_block(
                Mesh::grid3d(5, 5, 2, 2.0, 2.0, 1.0),
                &[0.005, 0.002, -0.03],
                0.02,
                &[1.0, 1.0],
            ),
        ),
    ]
}

/// `k` scaled by `s`.
fn scaled(k: &Csc, s: f64) -> Owned {
    let mut o = Owned::of(k);
    o.x.iter_mut().for_each(|v| *v *= s);
    o
}

/// A host loop on a linear body whose first tangent is wrong (1.2 K, a
/// modified Newton's stale tangent): the second iteration, on K itself after
/// `refactor`, with r = f - K u_1, g = g0 - N u_1 and s = T u_1, is the exact
/// linearisation, so it lands on the increment's own solution (`solve` on K);
/// a third iteration finds du = 0 and the same forces. Every method, both
/// dual forms, 2D and 3D, Tresca and Coulomb.
#[test]
fn a_host_loop_with_a_stale_tangent_lands_on_the_increments_solution() {
    for (name, sc) in scenes() {
        let m = sc.m();
        let mu = vec![0.4; m];
        let p = vec![0.02; m];
        for law in [Friction::Coulomb(&mu), Friction::Tresca(&p)] {
            let law_name = if matches!(law, Friction::Coulomb(_)) {
                "Coulomb"
            } else {
                "Tresca"
            };
            for o in configurations() {
                let what = format!("{name}, {law_name} [{}]", label(&o));
                host_loop(&what, &sc, law, &o);
            }
        }
    }
}

fn host_loop(what: &str, sc: &Scene, law: Friction<'_>, o: &Options) {
    let mut reference =
        ContactProblem::from_csc_with(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone(), o)
            .expect("a valid problem");
    let want = reference
        .solve(&sc.f, &sc.g, law, o)
        .expect("the increment");
    assert_converged(&format!("{what}: reference"), &want);
    let stale = scaled(&sc.k, 1.2);
    let k_stale = Csc::from_view(&stale.view(), "K").expect("K");
    let mut pb = ContactProblem::from_csc_with(sc.d, k_stale, sc.n.clone(), sc.t.clone(), o)
        .expect("a valid problem");
    let ndof = sc.f.len();
    let mut u = vec![0.0; ndof];
    let mut last = None;
    for j in 0..3 {
        if j == 1 {
            pb.refactor(&Owned::of(&sc.k).view())
                .expect("refactor onto K");
        }
        let ku = mul(&sc.k, &u);
        let r: Vec<f64> = sc.f.iter().zip(&ku).map(|(f, k)| f - k).collect();
        let nu = mul(&sc.n, &u);
        let g: Vec<f64> = sc.g.iter().zip(&nu).map(|(g, x)| g - x).collect();
        let s = mul(&sc.t, &u);
        let it = HostIteration {
            r: &r,
            g: &g,
            slip: (j > 0).then_some(&s[..]),
            lt_start: None,
        };
        let sol = pb.solve_iteration(&it, law, o).expect("an iteration");
        assert_converged(&format!("{what}: iteration {j}"), &sol);
        for (ui, di) in u.iter_mut().zip(&sol.u) {
            *ui += di;
        }
        if j == 2 {
            let du = norm_inf(&sol.u) / norm_inf(&u);
            assert!(
                du <= 1e-8,
                "{what}: the third iteration moved |du| / |u| = {du:.2e}"
            );
        }
        last = Some(sol);
    }
    let sol = last.expect("three iterations");
    let u_scale = norm_inf(&want.u);
    assert_close(&format!("{what}: u"), &u, &want.u, 1e-7, u_scale);
    let l_scale = norm_inf(&want.lambda_n).max(norm_inf(&want.lambda_t));
    assert_close(
        &format!("{what}: lambda_N"),
        &sol.lambda_n,
        &want.lambda_n,
        1e-7,
        l_scale,
    );
    assert_close(
        &format!("{what}: lambda_T"),
        &sol.lambda_t,
        &want.lambda_t,
        1e-7,
        l_scale,
    );
}

/// A warm start gives the cold answer: the same iteration after another one
/// on the same handle (its multipliers the start) and on a fresh handle.
#[test]
fn a_warm_start_gives_the_cold_answer() {
    let (_, sc) = scenes().remove(1);
    let mu = vec![0.3; sc.m()];
    let law = Friction::Coulomb(&mu);
    let o = Options {
        method: Method::Newton,
        threads: 1,
        ..Options::default()
    };
    let it = HostIteration {
        r: &sc.f,
        g: &sc.g,
        slip: None,
        lt_start: None,
    };
    let cold = sc.problem().solve_iteration(&it, law, &o).expect("cold");
    assert_converged("cold", &cold);
    let mut pb = sc.problem();
    let half: Vec<f64> = sc.f.iter().map(|v| 0.5 * v).collect();
    let other = HostIteration { r: &half, ..it };
    assert_converged(
        "other",
        &pb.solve_iteration(&other, law, &o).expect("other"),
    );
    let warm = pb.solve_iteration(&it, law, &o).expect("warm");
    assert_converged("warm", &warm);
    let scale = norm_inf(&cold.lambda_n);
    assert_close("warm lambda_N", &warm.lambda_n, &cold.lambda_n, 1e-8, scale);
    assert_close("warm lambda_T", &warm.lambda_t, &cold.lambda_t, 1e-8, scale);
    assert_close("warm du", &warm.u, &cold.u, 1e-8, norm_inf(&cold.u));
    // From its own answer the same iteration has nothing left to do.
    let again = pb.solve_iteration(&it, law, &o).expect("again");
    assert!(
        again.report.outer_iterations <= 1,
        "from its own answer: {} outer iterations",
        again.report.outer_iterations
    );
}

/// Bad input: errors, and the handle's next iteration is what it would have
/// been without the bad calls.
#[test]
fn bad_slip_and_bad_k_leave_the_handle_as_it_was() {
    let (_, sc) = scenes().remove(1);
    let m = sc.m();
    let mu = vec![0.3; m];
    let law = Friction::Coulomb(&mu);
    let o = Options {
        threads: 1,
        ..Options::default()
    };
    let s = vec![1e-3; 2 * m];
    let it = HostIteration {
        r: &sc.f,
        g: &sc.g,
        slip: Some(&s),
        lt_start: None,
    };
    // Both handles first converge on another iteration, whose multipliers
    // the next one starts from: a bad call must not lose them.
    let half: Vec<f64> = sc.f.iter().map(|v| 0.5 * v).collect();
    let before = HostIteration { r: &half, ..it };
    let mut clean = sc.problem();
    assert_converged(
        "clean before",
        &clean.solve_iteration(&before, law, &o).unwrap(),
    );
    let want = clean.solve_iteration(&it, law, &o).expect("clean");
    let mut pb = sc.problem();
    assert_converged("before", &pb.solve_iteration(&before, law, &o).unwrap());
    let short = vec![0.0; 2 * m - 1];
    let e = pb
        .solve_iteration(
            &HostIteration {
                slip: Some(&short),
                ..it
            },
            law,
            &o,
        )
        .unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadSize, "{e}");
    assert!(e.to_string().contains("slip"), "{e}");
    let mut nan = s.clone();
    nan[3] = f64::NAN;
    let e = pb
        .solve_iteration(
            &HostIteration {
                slip: Some(&nan),
                ..it
            },
            law,
            &o,
        )
        .unwrap_err();
    assert_eq!(e.kind, ErrorKind::NotFinite, "{e}");
    let lt_bad = vec![f64::INFINITY; 2 * m];
    let e = pb
        .solve_iteration(
            &HostIteration {
                lt_start: Some(&lt_bad),
                ..it
            },
            law,
            &o,
        )
        .unwrap_err();
    assert_eq!(e.kind, ErrorKind::NotFinite, "{e}");
    // K of another pattern: only its diagonal.
    let diag: Vec<_> = (0..sc.k.nrows).map(|i| (i, i, 1.0)).collect();
    let other = Owned::of(&Csc::from_triplets(sc.k.nrows, sc.k.nrows, &diag));
    let e = pb.refactor(&other.view()).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadArgument, "{e}");
    let got = pb
        .solve_iteration(&it, law, &o)
        .expect("after the bad calls");
    assert_converged("after the bad calls", &got);
    assert_eq!(got.u, want.u, "du after the bad calls");
    assert_eq!(got.lambda_n, want.lambda_n);
    assert_eq!(got.lambda_t, want.lambda_t);
    assert_eq!(got.report.outer_iterations, want.report.outer_iterations);
}

/// Where the next iteration starts: the last converged one's multipliers,
/// kept by `refactor` and by a solve that did not converge, forgotten by
/// `reset_history` and by `set_contacts` with another m. Observed through
/// the work of the same iteration (Newton steps and sweeps; one thread,
/// deterministic): from its own answer less than cold, from zero as much.
#[test]
fn the_start_is_kept_and_forgotten_where_documented() {
    let (_, sc) = scenes().remove(1);
    let mu = vec![0.3; sc.m()];
    let law = Friction::Coulomb(&mu);
    let o = Options {
        method: Method::Newton,
        threads: 1,
        ..Options::default()
    };
    let it = HostIteration {
        r: &sc.f,
        g: &sc.g,
        slip: None,
        lt_start: None,
    };
    let mut pb = sc.problem();
    let cold = pb.solve_iteration(&it, law, &o).expect("cold");
    assert_converged("cold", &cold);
    let work = |r: &dualsplit::Report| r.outer_iterations + r.inner_iterations;
    let cold_steps = work(&cold.report);
    let steps = |pb: &mut ContactProblem| {
        let s = pb.solve_iteration(&it, law, &o).expect("an iteration");
        assert_converged("again", &s);
        work(&s.report)
    };
    // Kept: the same iteration from its own answer.
    let warm = steps(&mut pb);
    assert!(
        warm < cold_steps,
        "from its own answer {warm}, cold {cold_steps}"
    );
    // Kept through a refactor (the same K).
    pb.refactor(&Owned::of(&sc.k).view()).expect("refactor");
    assert_eq!(steps(&mut pb), warm, "after refactor");
    // Kept through a solve that did not converge (one PGS sweep on another
    // load).
    let half: Vec<f64> = sc.f.iter().map(|v| 0.3 * v).collect();
    let one_sweep = Options {
        method: Method::Pgs,
        max_outer: 1,
        ..o
    };
    let other = pb
        .solve_iteration(&HostIteration { r: &half, ..it }, law, &one_sweep)
        .expect("a limited iteration");
    assert_ne!(other.report.status, dualsplit::SolveStatus::Converged);
    assert_eq!(steps(&mut pb), warm, "after a solve that did not converge");
    // Forgotten by reset_history.
    pb.reset_history();
    assert_eq!(steps(&mut pb), cold_steps, "after reset_history");
    // Forgotten by set_contacts with another m (the first contact dropped).
    let keep: Vec<usize> = (1..sc.m()).collect();
    let rows = |a: &Csc, per: usize| {
        let t: Vec<(usize, usize, f64)> = (0..a.ncols)
            .flat_map(|j| {
                (a.col_ptr[j]..a.col_ptr[j + 1]).map(move |p| (a.row_idx[p], j, a.values[p]))
            })
            .filter(|&(i, _, _)| i / per >= 1)
            .map(|(i, j, v)| (i - per, j, v))
            .collect();
        Csc::from_triplets(a.nrows - per, a.ncols, &t)
    };
    let (n1, t1) = (rows(&sc.n, 1), rows(&sc.t, 2));
    let mut fresh = ContactProblem::from_csc(3, sc.k.clone(), n1.clone(), t1.clone()).unwrap();
    pb.set_contacts(&Owned::of(&n1).view(), &Owned::of(&t1).view())
        .expect("new contacts");
    let g1: Vec<f64> = keep.iter().map(|&i| sc.g[i]).collect();
    let mu1 = vec![0.3; keep.len()];
    let it1 = HostIteration { g: &g1, ..it };
    let law1 = Friction::Coulomb(&mu1);
    let a = pb
        .solve_iteration(&it1, law1, &o)
        .expect("after set_contacts");
    let b = fresh
        .solve_iteration(&it1, law1, &o)
        .expect("a fresh handle");
    assert_converged("after set_contacts", &a);
    assert_eq!(
        work(&a.report),
        work(&b.report),
        "after set_contacts with another m, the start is zero as on a fresh handle"
    );
}

/// Through C: the slip-then-stick node of
/// `slipped_in_iteration_one_sticks_in_iteration_two` by `ds_solve_iteration`
/// (slip NULL in iteration 1), then a NaN slip and a NULL residual: their
/// statuses, the outputs untouched, and the next iteration as before.
#[test]
fn ds_solve_iteration_through_c() {
    use dualsplit::internals::ffi::*;
    let (k, n, t) = one_node(2, 2.0);
    let (k, n, t) = (Owned::of(&k), Owned::of(&n), Owned::of(&t));
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    let mut h: *mut DsProblem = std::ptr::null_mut();
    // SAFETY: valid matrices and out pointer.
    assert_eq!(
        unsafe { ds_problem_new(2, &kd, &nd, &td, &mut h) },
        DsStatus::Ok
    );
    let mu = [0.5];
    let coulomb = DsFriction::Coulomb as i32;
    let (mut du, mut ln, mut lt) = ([0.0; 2], [0.0; 1], [0.0; 1]);
    let null = std::ptr::null::<f64>();
    // SAFETY: a live handle; every array sized for n = 2, m = 1, d = 2; NULLs
    // where the call allows them (opts, slip, lambda_t_start, report).
    let call = |r: *const f64, slip: *const f64, du: &mut [f64], ln: &mut [f64], lt: &mut [f64]| unsafe {
        ds_solve_iteration(
            h,
            std::ptr::null(),
            coulomb,
            r,
            [0.0].as_ptr(),
            mu.as_ptr(),
            slip,
            null,
            du.as_mut_ptr(),
            ln.as_mut_ptr(),
            lt.as_mut_ptr(),
            std::ptr::null_mut(),
        )
    };
    // Iteration 1 slips: du_x = 3, lambda = (8, 4).
    assert_eq!(
        call([10.0, -8.0].as_ptr(), null, &mut du, &mut ln, &mut lt),
        DsStatus::Ok
    );
    assert_close("C iteration 1: du", &du, &[3.0, 0.0], 1e-9, 3.0);
    assert_close("C iteration 1: lambda_T", &lt, &[4.0], 1e-9, 8.0);
    // Bad calls: nothing written.
    let (mut du2, mut ln2, mut lt2) = ([7.0; 2], [7.0; 1], [7.0; 1]);
    let r2 = [-5.0, -8.0];
    let st = call(
        r2.as_ptr(),
        [f64::NAN].as_ptr(),
        &mut du2,
        &mut ln2,
        &mut lt2,
    );
    assert_eq!(st, DsStatus::NotFinite);
    let st = call(null, [3.0].as_ptr(), &mut du2, &mut ln2, &mut lt2);
    assert_eq!(st, DsStatus::NullPointer);
    assert_eq!(
        (du2, ln2, lt2),
        ([7.0; 2], [7.0; 1], [7.0; 1]),
        "outputs written on error"
    );
    // Iteration 2 sticks: du_x = -s = -3, lambda_T = 1.
    let st = call(r2.as_ptr(), [3.0].as_ptr(), &mut du, &mut ln, &mut lt);
    assert_eq!(st, DsStatus::Ok);
    assert_close("C iteration 2: du", &du, &[-3.0, 0.0], 1e-9, 3.0);
    assert_close("C iteration 2: lambda_N", &ln, &[8.0], 1e-9, 8.0);
    assert_close("C iteration 2: lambda_T", &lt, &[1.0], 1e-9, 8.0);
    // SAFETY: a handle from ds_problem_new, freed once.
    unsafe { ds_problem_free(h) };
}

/// err of a solution on K's own contact blocks (docs/design.md section 5),
/// from the dense A = B K^-1 B^T and b = B K^-1 f - [g; 0] (an independent
/// condensation by dense LU).
fn exact_err(sc: &Scene, k: &Csc, sol: &Solution, mu: &[f64]) -> f64 {
    exact_err_scaled(sc, k, sol, mu, 1.0)
}

/// [`exact_err`] with rho_i multiplied by `s` (the rho of the blocks of
/// K / s, whose trace is K's over s).
fn exact_err_scaled(sc: &Scene, k: &Csc, sol: &Solution, mu: &[f64], s: f64) -> f64 {
    let (d, m) = (sc.d, sc.m());
    let c = d * m;
    let rows: Vec<Vec<f64>> = (0..c)
        .map(|r| {
            let mut e = vec![0.0; c];
            e[r] = 1.0;
            let (en, et) = e.split_at(m);
            let bt: Vec<f64> = common::mul_t(&sc.n, en)
                .iter()
                .zip(common::mul_t(&sc.t, et))
                .map(|(a, b)| a + b)
                .collect();
            common::dense_solve(k, &bt)
        })
        .collect();
    let b_of = |x: &[f64]| -> Vec<f64> {
        let mut y = mul(&sc.n, x);
        y.extend(mul(&sc.t, x));
        y
    };
    let diag: Vec<f64> = (0..c).map(|r| b_of(&rows[r])[r]).collect();
    let rho: Vec<f64> = (0..m)
        .map(|i| {
            let tr = diag[i] + (0..d - 1).map(|s| diag[m + (d - 1) * i + s]).sum::<f64>();
            s * d as f64 / tr
        })
        .collect();
    let mut b = b_of(&common::dense_solve(k, &sc.f));
    for (bi, gi) in b.iter_mut().zip(&sc.g) {
        *bi -= gi;
    }
    let mut v = b_of(&sol.u);
    for (vi, gi) in v.iter_mut().zip(&sc.g) {
        *vi -= gi;
    }
    let mut lam = sol.lambda_n.clone();
    lam.extend(&sol.lambda_t);
    let p: Vec<f64> = sol.lambda_n.iter().zip(mu).map(|(l, m)| l * m).collect();
    dualsplit::internals::natural_map_error(&lam, &v, &rho, &b, &p, d)
}

/// A refactor of a matrix-free dual keeps the contact blocks of the K they
/// were computed on while their drift bounds err's growth by 3, and says
/// so: from K_0 = 1.2 K onto K, M = K^-1 (K - K_0) = -0.2 I, so the blocks of
/// K are 1.2 times K_0's and err's factor is 1.2 (one Lanczos step, to the
/// single-precision solves' rounding); the solution is the fresh handle's,
/// and the reported err bounds err on K's own blocks. Onto 1.1 K the drift is still measured from K_0 (factor
/// 1.2 / 1.1, age 2); onto 1.1 * 1.004 K, a small step from 1.1 K, it is
/// composed from that step's (age 3); onto 5 K (factor 4.2) the blocks are
/// computed afresh, and new contacts start afresh too.
#[test]
fn a_refactor_keeps_the_contact_blocks_while_they_drift_little() {
    let (_, sc) = scenes().pop().expect("the 3D scene");
    let m = sc.m();
    let mu = vec![0.4; m];
    let law = Friction::Coulomb(&mu);
    let o = Options {
        method: Method::Newton,
        dual_form: DualForm::MatrixFree,
        threads: 1,
        ..Options::default()
    };
    let k0 = Csc::from_view(&scaled(&sc.k, 1.2).view(), "K").expect("K");
    let mut pb = ContactProblem::from_csc_with(sc.d, k0, sc.n.clone(), sc.t.clone(), &o)
        .expect("a valid problem");
    let info = pb.info(&o);
    assert_eq!((info.blocks_age, info.err_factor), (0, 1.0));
    let (at, _) = pb.dual().single_copy().expect("a copy in single precision");
    pb.refactor(&Owned::of(&sc.k).view())
        .expect("refactor onto K");
    let cost = pb.last_refactor();
    assert!(cost.blocks_kept && cost.drift_solves == 1, "{cost:?}");
    // The refactor wrote the new factor's single-precision values into the
    // old dual's copy, not into a new allocation.
    let (at_now, values) = pb.dual().single_copy().expect("a copy in single precision");
    assert_eq!(at_now, at, "the copy was allocated anew");
    assert_eq!(values, pb.factor().single_values().unwrap());
    let info = pb.info(&o);
    assert_eq!(info.blocks_age, 1);
    assert!((info.err_factor - 1.2).abs() < 1e-6, "{}", info.err_factor);
    let got = pb.solve(&sc.f, &sc.g, law, &o).expect("a solve");
    assert_converged("kept blocks", &got);
    let mut fresh =
        ContactProblem::from_csc_with(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone(), &o)
            .expect("a valid problem");
    let want = fresh.solve(&sc.f, &sc.g, law, &o).expect("a solve");
    assert_converged("fresh handle", &want);
    let scale = norm_inf(&want.lambda_n);
    assert_close("lambda_N", &got.lambda_n, &want.lambda_n, 1e-7, scale);
    assert_close("lambda_T", &got.lambda_t, &want.lambda_t, 1e-7, scale);
    let exact = exact_err(&sc, &sc.k, &got, &mu);
    // The reported err is err_factor times err with K_0's blocks (rho 1.2
    // times K's): the factor is applied.
    let with_kept = exact_err_scaled(&sc, &sc.k, &got, &mu, 1.2);
    assert!(
        (got.report.err - info.err_factor * with_kept).abs() <= 1e-6 * got.report.err,
        "reported err {:.6e} against {} x {with_kept:.6e}",
        got.report.err,
        info.err_factor
    );
    // The dense condensation reproduces the fresh handle's own err.
    let of_fresh = exact_err(&sc, &sc.k, &want, &mu);
    assert!(
        (of_fresh - want.report.err).abs() <= 1e-6 * want.report.err,
        "err by the dense condensation {of_fresh:.6e} against the fresh handle's {:.6e}",
        want.report.err
    );
    assert!(
        exact <= got.report.err * (1.0 + 1e-6) && got.report.err <= o.tol,
        "reported err {:.3e} does not bound err on K's blocks {exact:.3e}",
        got.report.err
    );
    // Onto 1.1 K: measured from K_0 = 1.2 K, not from K.
    pb.refactor(&scaled(&sc.k, 1.1).view())
        .expect("refactor onto 1.1 K");
    let info = pb.info(&o);
    assert_eq!(info.blocks_age, 2);
    assert!(
        (info.err_factor - 1.2 / 1.1).abs() < 1e-9,
        "{}",
        info.err_factor
    );
    // Onto 1.1 * 1.004 K, 0.4 % from the last K: the step from it is
    // estimated in two solves and composed with its drift; the factor
    // bounds the exact 1.2 / (1.1 * 1.004), the step's margin (its bounds
    // times 4) costing 1-3 % (a full estimate, exact in one step on a
    // scaled K, would give the exact factor: the margin shows the
    // composition ran).
    let exact = 1.2 / (1.1 * 1.004);
    pb.refactor(&scaled(&sc.k, 1.1 * 1.004).view())
        .expect("refactor onto 1.1 * 1.004 K");
    let cost = pb.last_refactor();
    assert!(cost.blocks_kept && cost.drift_solves <= 2, "{cost:?}");
    let info = pb.info(&o);
    assert_eq!(info.blocks_age, 3);
    assert!(
        info.err_factor >= 1.01 * exact && info.err_factor <= 1.03 * exact,
        "{} against {exact}",
        info.err_factor
    );
    // Onto 5 K (from K_0 = 1.2 K: mu = 0.76, factor 4.2): beyond the bound,
    // computed afresh.
    pb.refactor(&scaled(&sc.k, 5.0).view())
        .expect("refactor onto 5 K");
    let cost = pb.last_refactor();
    assert!(!cost.blocks_kept, "{cost:?}");
    let info = pb.info(&o);
    assert_eq!((info.blocks_age, info.err_factor), (0, 1.0));
    // Kept again from 5 K, then new contacts: their blocks are new.
    pb.refactor(&scaled(&sc.k, 4.9).view())
        .expect("refactor onto 4.9 K");
    assert_eq!(pb.info(&o).blocks_age, 1);
    let (at, values) = pb.dual().single_copy().expect("a copy in single precision");
    pb.set_contacts(&Owned::of(&sc.n).view(), &Owned::of(&sc.t).view())
        .expect("the same contacts");
    let info = pb.info(&o);
    assert_eq!((info.blocks_age, info.err_factor), (0, 1.0));
    // New contacts on the same factor take its copy as it is.
    assert_eq!(pb.dual().single_copy(), Some((at, values)));
}

/// A linear host that ramps its load proportionally, one iteration per
/// increment (K exact: r = f_k - K u_k-1, g = g0 - N u_k-1, no slip taken):
/// from the third increment on, each first iteration starts on the line
/// through the multipliers that ended the last two (`history::Increments`).
/// The same iterations with a zero slip passed (not a first iteration: from
/// lambda_n) reach the same answers, each meeting the KKT conditions of its
/// problem, with more work.
#[test]
fn a_proportional_ramp_starts_each_increment_on_the_line() {
    let (_, sc) = scenes().remove(1);
    let m = sc.m();
    let mu = vec![0.3; m];
    let law = Friction::Coulomb(&mu);
    for form in [DualForm::Dense, DualForm::MatrixFree] {
        let o = Options {
            method: Method::Newton,
            dual_form: form,
            threads: 1,
            ..Options::default()
        };
        let work = |r: &dualsplit::Report| r.outer_iterations + r.inner_iterations;
        let (mut first, mut later) = (sc.problem(), sc.problem());
        let ndof = sc.f.len();
        let zero = vec![0.0; 2 * m];
        let (mut u, mut total) = (vec![0.0; ndof], [0usize; 2]);
        let steps = 6;
        for k in 1..=steps {
            let scale = k as f64 / steps as f64;
            let ku = mul(&sc.k, &u);
            let r: Vec<f64> = sc.f.iter().zip(&ku).map(|(f, x)| scale * f - x).collect();
            let nu = mul(&sc.n, &u);
            let g: Vec<f64> = sc.g.iter().zip(&nu).map(|(g, x)| g - x).collect();
            let it = HostIteration {
                r: &r,
                g: &g,
                slip: None,
                lt_start: None,
            };
            let a = first.solve_iteration(&it, law, &o).expect("first");
            // New contacts (the same) forget the line of the iterations
            // before: a plain start from lambda_n.
            later
                .set_contacts(&Owned::of(&sc.n).view(), &Owned::of(&sc.t).view())
                .expect("the same contacts");
            let b = later
                .solve_iteration(
                    &HostIteration {
                        slip: Some(&zero),
                        ..it
                    },
                    law,
                    &o,
                )
                .expect("later");
            let what = format!("{} increment {k}", o.dual_form.name());
            assert_converged(&what, &a);
            assert_converged(&what, &b);
            let p = common::slip_bounds(law, &a.lambda_n);
            let kkt = kkt_iteration(
                3,
                (&sc.k, &sc.n, &sc.t),
                (&r, &g, &zero),
                &p,
                (&a.u, &a.lambda_n, &a.lambda_t),
            );
            assert!(kkt <= 1e-8, "{what}: KKT {kkt:.2e}");
            let scale = norm_inf(&b.lambda_n);
            assert_close(&what, &a.lambda_n, &b.lambda_n, 1e-7, scale);
            assert_close(&what, &a.lambda_t, &b.lambda_t, 1e-7, scale);
            assert_close(&what, &a.u, &b.u, 1e-7, norm_inf(&b.u));
            if k >= 3 {
                total[0] += work(&a.report);
                total[1] += work(&b.report);
            }
            for (ui, di) in u.iter_mut().zip(&a.u) {
                *ui += di;
            }
        }
        // The dense route's Newton starts with sweeps and is near the answer
        // from the line (11-12 against 30-40 here); the matrix-free one's
        // steps at tol 1e-10 hardly change with a start a few times nearer
        // (Newton's forcing terms are relative to the start's |F|: 102
        // against 102 here, the line's own two products not counted in
        // these iterations), so there the line must cost at most one
        // iteration per increment.
        let (line, plain) = (total[0], total[1]);
        match form {
            DualForm::Dense => assert!(
                2 * line < plain,
                "dense: increments 3-{steps} took {line} outer + inner iterations from the line, {plain} from lambda_n"
            ),
            _ => assert!(
                line <= plain + 2 * (steps - 2),
                "matrix-free: increments 3-{steps} took {line} from the line, {plain} from lambda_n"
            ),
        }
    }
}

/// K with its middle third of DOFs scaled by 1 + eps (rows and columns): a
/// material update of the same pattern, symmetric positive definite.
fn zoned(k: &Csc, eps: f64) -> Csc {
    let n = k.nrows;
    let s = |i: usize| {
        if (n / 3..2 * n / 3).contains(&i) {
            1.0 + eps
        } else {
            1.0
        }
    };
    let mut o = k.clone();
    for j in 0..n {
        for p in k.col_ptr[j]..k.col_ptr[j + 1] {
            o.values[p] *= s(k.row_idx[p]) * s(j);
        }
    }
    o
}

/// A host loop whose tangent settles (K_j: the middle third of K's DOFs
/// scaled by 1 + eps_j, eps_j = 0.04 (-1/4)^j; r_j = f - K u_j, g_j = g -
/// N u_j, s_j = T u_j): from the third iteration on, each starts on the
/// line through the last two iterations' answers (docs/design.md section
/// 9). Every answer meets the KKT conditions of its iteration's problem and
/// agrees with a handle whose line is forgotten before each iteration (new
/// contacts, the same: a plain start from the last answer), which takes
/// no fewer iterations from the third on (more on the matrix-free form).
#[test]
fn a_settling_host_loop_starts_later_iterations_on_its_line() {
    let (_, sc) = scenes().remove(1);
    let m = sc.m();
    let (mu, p) = (vec![0.3; m], vec![2e-3; m]);
    // Newton steps and products the line saved on the matrix-free form,
    // both laws.
    let mut saved = 0;
    for form in [DualForm::Dense, DualForm::MatrixFree] {
        for (name, law) in [
            ("Tresca", Friction::Tresca(&p)),
            ("Coulomb", Friction::Coulomb(&mu)),
        ] {
            let o = Options {
                method: Method::Newton,
                dual_form: form,
                threads: 1,
                ..Options::default()
            };
            let work = |r: &dualsplit::Report| r.outer_iterations + r.inner_iterations;
            let (mut line, mut plain) = (sc.problem(), sc.problem());
            let ndof = sc.f.len();
            let (mut u, mut total) = (vec![0.0; ndof], [0usize; 2]);
            for j in 0..6 {
                let kj = zoned(&sc.k, 0.04 * (-0.25f64).powi(j));
                line.refactor(&Owned::of(&kj).view()).expect("refactor");
                plain.refactor(&Owned::of(&kj).view()).expect("refactor");
                plain
                    .set_contacts(&Owned::of(&sc.n).view(), &Owned::of(&sc.t).view())
                    .expect("the same contacts");
                let r: Vec<f64> =
                    sc.f.iter()
                        .zip(&mul(&sc.k, &u))
                        .map(|(f, x)| f - x)
                        .collect();
                let g: Vec<f64> =
                    sc.g.iter()
                        .zip(&mul(&sc.n, &u))
                        .map(|(g, x)| g - x)
                        .collect();
                let s = mul(&sc.t, &u);
                let it = HostIteration {
                    r: &r,
                    g: &g,
                    slip: (j > 0).then_some(&s[..]),
                    lt_start: None,
                };
                let a = line.solve_iteration(&it, law, &o).expect("on the line");
                let b = plain.solve_iteration(&it, law, &o).expect("plain");
                let what = format!("{} {name} iteration {j}", form.name());
                assert_converged(&what, &a);
                assert_converged(&what, &b);
                let bounds = common::slip_bounds(law, &a.lambda_n);
                let kkt = kkt_iteration(
                    3,
                    (&kj, &sc.n, &sc.t),
                    (&r, &g, &s),
                    &bounds,
                    (&a.u, &a.lambda_n, &a.lambda_t),
                );
                assert!(kkt <= 1e-8, "{what}: KKT {kkt:.2e}");
                let scale = norm_inf(&b.lambda_n);
                assert_close(&what, &a.lambda_n, &b.lambda_n, 1e-7, scale);
                assert_close(&what, &a.lambda_t, &b.lambda_t, 1e-7, scale);
                println!(
                    "{what}: {} / {} outer + inner on the line, {} / {} plain",
                    a.report.outer_iterations,
                    a.report.inner_iterations,
                    b.report.outer_iterations,
                    b.report.inner_iterations
                );
                if j >= 2 {
                    total[0] += work(&a.report);
                    total[1] += work(&b.report);
                }
                u.iter_mut().zip(&a.u).for_each(|(x, d)| *x += d);
            }
            let [on_line, from_last] = total;
            // The line is taken where it lowers |F| alone: never more work
            // than the plain start; fewer Newton steps and products on the
            // matrix-free form over both laws (43 against 45 and 34 against
            // 38 outer + inner when written; the dense form's warm-up sweeps
            // reach the tolerance from either start, 30 against 30, and for
            // Coulomb 32 against 60).
            assert!(
                on_line <= from_last,
                "{} {name}: {on_line} on the line, {from_last} plain",
                form.name()
            );
            if form == DualForm::MatrixFree {
                saved += from_last - on_line;
            }
            println!(
                "{} {name}: iterations 2-5 took {on_line} outer + inner on the line, {from_last} plain",
                form.name()
            );
        }
    }
    assert!(
        saved > 0,
        "the line saved no iteration on the matrix-free form"
    );
}
