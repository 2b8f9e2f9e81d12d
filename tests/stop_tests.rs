//! The stop tests of the outer loop other than the tolerance: the stagnation test
//! must not cut a solve that converges slowly but steadily, and the wall-clock
//! budget ends a solve with TimeLimit and the best iterate, through Rust and C.

mod common;

use common::{Mesh, Owned, Scene, kkt_of};
use dualsplit::internals::ffi::*;
use dualsplit::{Friction, Method, Options, SolveStatus};

/// A nearly incompressible 2D block (nu = 0.499) pressed onto a curved
/// foundation: 61 contacts whose normal forces are coupled through the whole
/// block, where projected Gauss-Seidel converges slowly but steadily.
fn incompressible_block() -> Scene {
    let (nx, ny) = (100, 10);
    let mesh = Mesh::grid2d(nx, ny, 10.0, 1.0);
    let mut prescribed = Vec::new();
    for &a in &mesh.top_nodes() {
        prescribed.push((2 * a, 0.0));
        prescribed.push((2 * a + 1, -0.02));
    }
    let f_ext = vec![0.0; mesh.n_dofs()];
    let bottom = mesh.bottom_nodes();
    Scene::build(mesh, 1.0, 0.499, &prescribed, &f_ext, &bottom, |x| {
        0.001 * (x[0] - 5.0).powi(2) / 25.0
    })
}

#[test]
fn a_slow_steady_solve_is_not_cut_short() {
    let sc = incompressible_block();
    let p = vec![0.05; sc.m()];
    let friction = Friction::Tresca(&p);
    let o = Options {
        method: Method::Pgs,
        ..Options::default()
    };
    let mut errs = Vec::new();
    let mut seen = |pr: &dualsplit::Progress| {
        errs.push(pr.err);
        true
    };
    let sol = sc
        .problem()
        .solve_monitored(&sc.f, &sc.g, friction, &o, Some(&mut seen))
        .unwrap();
    let r = &sol.report;
    println!(
        "pgs: {:?} after {} sweeps, err {:.2e}",
        r.status, r.outer_iterations, r.err
    );
    assert_eq!(r.status, SolveStatus::Converged, "{r:?}");
    // Slow: many windows of the stagnation test went by.
    assert!(r.outer_iterations > 3 * o.stall_window, "{r:?}");
    kkt_of(&sc, friction, &sol).assert_ok("pgs on the incompressible block", 1e-8);
}

#[test]
fn the_time_limit_ends_a_solve_with_the_best_iterate() {
    let sc = incompressible_block();
    let p = vec![0.05; sc.m()];
    let friction = Friction::Tresca(&p);
    // A budget spent before the first outer iteration: the solve ends at once,
    // where 2,000+ sweeps were needed (test above).
    let o = Options {
        method: Method::Pgs,
        max_seconds: 1e-9,
        ..Options::default()
    };
    let mut best = f64::INFINITY;
    let mut seen = |pr: &dualsplit::Progress| {
        best = best.min(pr.err);
        true
    };
    let sol = sc
        .problem()
        .solve_monitored(&sc.f, &sc.g, friction, &o, Some(&mut seen))
        .unwrap();
    let r = &sol.report;
    assert_eq!(r.status, SolveStatus::TimeLimit, "{r:?}");
    assert!(r.outer_iterations <= 1, "{r:?}");
    assert!(r.err > o.tol && r.err <= best.max(r.err), "{r:?}");
    // A budget large enough changes nothing.
    let o = Options {
        max_seconds: 600.0,
        ..o
    };
    let sol = sc.problem().solve(&sc.f, &sc.g, friction, &o).unwrap();
    assert_eq!(sol.report.status, SolveStatus::Converged);
    // Bad budgets are refused.
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let o = Options {
            max_seconds: bad,
            ..o
        };
        let e = sc.problem().solve(&sc.f, &sc.g, friction, &o).unwrap_err();
        assert_eq!(e.kind, dualsplit::ErrorKind::BadArgument, "{bad}");
    }
}

/// Through C: DS_STATUS_TIME_LIMIT and DS_STATUS_STALLED write the iterate with
/// the lowest err to u, lambda_n, lambda_t and the report; NOT_CONVERGED writes
/// only the report.
#[test]
fn through_c_the_new_statuses_write_the_best_iterate() {
    let sc = incompressible_block();
    let (k, n, t) = (Owned::of(&sc.k), Owned::of(&sc.n), Owned::of(&sc.t));
    let m = sc.m();
    let mut h: *mut DsProblem = std::ptr::null_mut();
    // SAFETY: the matrices outlive the call.
    let s = unsafe { ds_problem_new(2, &k.ds(), &n.ds(), &t.ds(), &mut h) };
    assert_eq!(s, DsStatus::Ok);
    let p = vec![0.05; m];
    let cases = [
        // (max_seconds, stall_window, stall_factor, max_outer): the status
        (1e-9, 100, 0.9, 10_000, DsStatus::TimeLimit),
        // A factor no slow method meets (99.9 % per 5 sweeps), and a limit of 200
        // sweeps that the pace of PGS here cannot meet (it needs 2,386).
        (0.0, 5, 1e-3, 200, DsStatus::Stalled),
        (0.0, 100, 0.9, 3, DsStatus::NotConverged),
    ];
    for (max_seconds, stall_window, stall_factor, max_outer, want) in cases {
        let mut o = DsOptions::default();
        // SAFETY: o is a whole, writable DsOptions.
        let st = unsafe { ds_options_init(&mut o, std::mem::size_of::<DsOptions>()) };
        assert_eq!(st, DsStatus::Ok);
        o.method = DsMethod::Pgs as i32;
        o.max_seconds = max_seconds;
        o.stall_window = stall_window;
        o.stall_factor = stall_factor;
        o.max_outer = max_outer;
        let mut u = vec![f64::NAN; sc.k.nrows];
        let (mut ln, mut lt) = (vec![f64::NAN; m], vec![f64::NAN; m]);
        let mut r = std::mem::MaybeUninit::<DsReport>::zeroed();
        // SAFETY: arrays of the problem's sizes, report writable.
        let s = unsafe {
            ds_solve(
                h,
                &o,
                DsFriction::Tresca as i32,
                sc.f.as_ptr(),
                sc.g.as_ptr(),
                p.as_ptr(),
                u.as_mut_ptr(),
                ln.as_mut_ptr(),
                lt.as_mut_ptr(),
                r.as_mut_ptr(),
            )
        };
        assert_eq!(s, want);
        // SAFETY: the report is written on these statuses (zeroed before anyway).
        let r = unsafe { r.assume_init() };
        assert_eq!(r.status, want as i32);
        assert!(r.err > 1e-10 && r.err.is_finite(), "{r:?}");
        let written = u.iter().chain(&ln).chain(&lt).all(|v| v.is_finite());
        let untouched = u.iter().chain(&ln).chain(&lt).all(|v| v.is_nan());
        if want == DsStatus::NotConverged {
            assert!(untouched, "{want:?}: outputs written");
        } else {
            assert!(written, "{want:?}: outputs not written");
        }
    }
    // SAFETY: a live handle, freed once.
    unsafe { ds_problem_free(h) };
}
