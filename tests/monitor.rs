//! Watching a solve: the monitor callback sees err fall to the reported
//! err, stopping after k iterations stops after exactly k with the last iterate
//! written, and the log sink is silent unless asked.

mod common;

use common::{Mesh, Scene, opts};
use dualsplit::internals::ffi::{
    DsInfo, DsMatrix, DsProblem, DsProgress, DsReport, DsStatus, ds_history_reset, ds_problem_free,
    ds_problem_info, ds_problem_new, ds_problem_refactor, ds_problem_set_log,
    ds_problem_set_monitor, ds_solve, ds_step,
};
use dualsplit::{Csc, Friction, Method, Progress, SolveStatus};
use std::ffi::{CStr, c_char, c_void};

/// The 2D block of tests/methods_agree.rs: curved gap, pressed and sheared, with
/// open, sticking and slipping contacts under Coulomb mu = 0.3.
fn scene() -> Scene {
    let mesh = Mesh::grid2d(16, 4, 2.0, 1.0);
    Scene::pressed_block(mesh, &[0.006, -0.02], 0.05, &[1.0])
}

#[test]
fn callback_sees_err_fall_to_the_reported_err() {
    let sc = scene();
    let mu = vec![0.3; sc.m()];
    for method in Method::ALL {
        let mut pb = sc.problem();
        let mut seen: Vec<Progress> = Vec::new();
        let mut record = |p: &Progress| {
            seen.push(*p);
            true
        };
        let sol = pb
            .solve_monitored(
                &sc.f,
                &sc.g,
                Friction::Coulomb(&mu),
                &opts(method),
                Some(&mut record),
            )
            .unwrap();
        let r = &sol.report;
        assert_eq!(r.status, SolveStatus::Converged, "{method:?}");
        assert_eq!(
            seen.len(),
            r.outer_iterations,
            "{method:?}: one call per outer iteration"
        );
        for (k, p) in seen.iter().enumerate() {
            assert_eq!(p.iteration, k + 1);
        }
        assert!(
            seen.windows(2)
                .all(|w| w[1].elapsed_seconds >= w[0].elapsed_seconds)
        );
        // Newton after its Gauss-Seidel warm-up may need a single step, and then
        // the monitor sees one err only.
        let (first, last) = (seen[0].err, seen.last().unwrap().err);
        assert!(
            seen.len() == 1 || last < first,
            "{method:?}: err did not fall ({first:e} -> {last:e})"
        );
        assert!(last <= 1e-10, "{method:?}: last monitored err {last:e}");
        // The monitored err is measured on the dual gradient, the reported one on the
        // recovered u: both are below tol and agree to rounding of A.
        assert!(
            (last - r.err).abs() <= 1e-12,
            "{method:?}: {last:e} vs {:e}",
            r.err
        );
        // The last call reports the final contact states.
        let p = seen.last().unwrap();
        assert_eq!(
            (p.n_open, p.n_stick, p.n_slip),
            (r.n_open, r.n_stick, r.n_slip)
        );
    }
}

fn csc_i64(a: &Csc) -> (Vec<i64>, Vec<i64>) {
    (
        a.col_ptr.iter().map(|&v| v as i64).collect(),
        a.row_idx.iter().map(|&v| v as i64).collect(),
    )
}

fn view(a: &Csc, p: &[i64], i: &[i64]) -> DsMatrix {
    DsMatrix {
        format: 1,
        index_type: 1,
        base: 0,
        storage: 0,
        nrows: a.nrows as i64,
        ncols: a.ncols as i64,
        nnz: 0,
        p: p.as_ptr().cast(),
        i: i.as_ptr().cast(),
        x: a.values.as_ptr(),
    }
}

/// Stops when the iteration number reaches *user_data.
unsafe extern "C" fn stop_at(progress: *const DsProgress, user_data: *mut c_void) -> i32 {
    // SAFETY: the library passes a valid progress; the test passes a *mut i64.
    let (p, k) = unsafe { (&*progress, *(user_data as *const i64)) };
    i32::from(p.iteration >= k)
}

/// Collects every log line into the Vec<String> behind user_data.
unsafe extern "C" fn collect(level: i32, message: *const c_char, user_data: *mut c_void) {
    // SAFETY: the library passes a NUL-terminated line; the test a *mut Vec<String>.
    let (msg, lines) = unsafe {
        (
            CStr::from_ptr(message),
            &mut *(user_data as *mut Vec<String>),
        )
    };
    lines.push(format!("{level}: {}", msg.to_string_lossy()));
}

struct Handle(*mut DsProblem);

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: a handle from ds_problem_new, freed once.
        unsafe { ds_problem_free(self.0) };
    }
}

fn new_handle(sc: &Scene) -> Handle {
    let (kp, ki) = csc_i64(&sc.k);
    let (np, ni) = csc_i64(&sc.n);
    let (tp, ti) = csc_i64(&sc.t);
    let (k, n, t) = (
        view(&sc.k, &kp, &ki),
        view(&sc.n, &np, &ni),
        view(&sc.t, &tp, &ti),
    );
    let mut h = std::ptr::null_mut();
    // SAFETY: the views point to live arrays matching their fields.
    let s = unsafe { ds_problem_new(2, &k, &n, &t, &mut h) };
    assert_eq!(s, DsStatus::Ok);
    Handle(h)
}

#[test]
fn stopping_after_k_iterations_stops_after_exactly_k() {
    let sc = scene();
    let mu = vec![0.3; sc.m()];
    for k in [1i64, 2, 3] {
        let h = new_handle(&sc);
        let mut stop = k;
        // SAFETY: live handle; the callback reads the i64 that outlives the solves.
        let s =
            unsafe { ds_problem_set_monitor(h.0, Some(stop_at), (&mut stop as *mut i64).cast()) };
        assert_eq!(s, DsStatus::Ok);
        // PGS: many iterations on this scene.
        let opts = dualsplit::internals::ffi::DsOptions {
            method: 2,
            ..Default::default()
        };
        let (mut u, mut ln, mut lt) = (
            vec![f64::NAN; sc.f.len()],
            vec![f64::NAN; sc.m()],
            vec![f64::NAN; sc.m()],
        );
        let mut rep = std::mem::MaybeUninit::<DsReport>::zeroed();
        // SAFETY: all arrays have the sizes of the problem.
        let s = unsafe {
            ds_solve(
                h.0,
                &opts,
                1,
                sc.f.as_ptr(),
                sc.g.as_ptr(),
                mu.as_ptr(),
                u.as_mut_ptr(),
                ln.as_mut_ptr(),
                lt.as_mut_ptr(),
                rep.as_mut_ptr(),
            )
        };
        assert_eq!(s, DsStatus::Stopped);
        // SAFETY: written by ds_solve on DS_STATUS_STOPPED.
        let rep = unsafe { rep.assume_init() };
        assert_eq!(rep.status, DsStatus::Stopped as i32);
        assert_eq!(rep.outer_iterations, k);
        assert!(rep.err > 1e-10, "stopped before convergence");
        assert!(
            u.iter().chain(&ln).chain(&lt).all(|v| v.is_finite()),
            "last iterate written"
        );
        // A stopped step does not advance the history: the next unmonitored step
        // from the same state gives what a fresh handle gives.
        // SAFETY: clearing the monitor of a live handle.
        unsafe { ds_problem_set_monitor(h.0, None, std::ptr::null_mut()) };
        let mut u2 = vec![0.0; sc.f.len()];
        let (mut ln2, mut lt2) = (vec![0.0; sc.m()], vec![0.0; sc.m()]);
        let run_step = |h: &Handle, u: &mut [f64], ln: &mut [f64], lt: &mut [f64]| {
            // SAFETY: arrays sized for the problem; report may be NULL.
            unsafe {
                ds_step(
                    h.0,
                    &opts,
                    1,
                    sc.f.as_ptr(),
                    sc.g.as_ptr(),
                    mu.as_ptr(),
                    u.as_mut_ptr(),
                    ln.as_mut_ptr(),
                    lt.as_mut_ptr(),
                    std::ptr::null_mut(),
                )
            }
        };
        // SAFETY: as above, with the monitor set again for one stopped step.
        unsafe { ds_problem_set_monitor(h.0, Some(stop_at), (&mut stop as *mut i64).cast()) };
        assert_eq!(run_step(&h, &mut u2, &mut ln2, &mut lt2), DsStatus::Stopped);
        // SAFETY: clearing the monitor.
        unsafe { ds_problem_set_monitor(h.0, None, std::ptr::null_mut()) };
        assert_eq!(run_step(&h, &mut u2, &mut ln2, &mut lt2), DsStatus::Ok);
        let fresh = new_handle(&sc);
        let (mut u3, mut ln3, mut lt3) =
            (vec![0.0; sc.f.len()], vec![0.0; sc.m()], vec![0.0; sc.m()]);
        assert_eq!(run_step(&fresh, &mut u3, &mut ln3, &mut lt3), DsStatus::Ok);
        assert_eq!(u2, u3);
        assert_eq!(ln2, ln3);
    }
}

#[test]
fn log_is_silent_by_default_and_per_iteration_when_asked() {
    let sc = scene();
    let mu = vec![0.3; sc.m()];
    let h = new_handle(&sc);
    let mut lines: Vec<String> = Vec::new();
    let solve = |h: &Handle| {
        let (mut u, mut ln, mut lt) = (vec![0.0; sc.f.len()], vec![0.0; sc.m()], vec![0.0; sc.m()]);
        let mut rep = std::mem::MaybeUninit::<DsReport>::zeroed();
        // SAFETY: arrays sized for the problem.
        let s = unsafe {
            ds_solve(
                h.0,
                std::ptr::null(),
                1,
                sc.f.as_ptr(),
                sc.g.as_ptr(),
                mu.as_ptr(),
                u.as_mut_ptr(),
                ln.as_mut_ptr(),
                lt.as_mut_ptr(),
                rep.as_mut_ptr(),
            )
        };
        assert_eq!(s, DsStatus::Ok);
        // SAFETY: written on success.
        unsafe { rep.assume_init() }.outer_iterations
    };
    let data = (&mut lines as *mut Vec<String>).cast::<c_void>();
    // Level 0 with a sink: the sink is never called.
    // SAFETY: live handle; `lines` outlives every solve below.
    assert_eq!(
        unsafe { ds_problem_set_log(h.0, 0, Some(collect), data) },
        DsStatus::Ok
    );
    solve(&h);
    assert!(lines.is_empty(), "silent level printed: {lines:?}");
    // Level 1: the default method (auto) says what it chose, then one summary line.
    // SAFETY: as above.
    unsafe { ds_problem_set_log(h.0, 1, Some(collect), data) };
    solve(&h);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(lines[0].starts_with("1: auto chose newton: "), "{lines:?}");
    assert!(lines[1].starts_with("1: newton: converged"), "{lines:?}");
    // Level 2: one line per outer iteration plus the summary.
    lines.clear();
    // SAFETY: as above.
    unsafe { ds_problem_set_log(h.0, 2, Some(collect), data) };
    let outer = solve(&h);
    assert_eq!(lines.len() as i64, outer + 2, "{lines:?}");
    let per_iteration = lines
        .iter()
        .filter(|l| l.starts_with("2: auto iteration "))
        .count();
    assert_eq!(per_iteration as i64, outer, "{lines:?}");
    // A bad level is refused and changes nothing.
    // SAFETY: as above.
    assert_eq!(
        unsafe { ds_problem_set_log(h.0, 3, None, std::ptr::null_mut()) },
        DsStatus::BadArgument
    );
    lines.clear();
    solve(&h);
    assert_eq!(lines.len() as i64, outer + 2);
}

#[test]
fn a_panic_inside_a_step_leaves_the_handle_and_its_history_usable() {
    // Own route (2D, the dense dual from the trailing block) and a power-law
    // interface (its rounds change the dual's diagonal).
    let sc = scene();
    let mu = vec![0.3; sc.m()];
    let law = Friction::Coulomb(&mu);
    let o = opts(Method::Auto);
    let scaled = |s: f64| sc.f.iter().map(|v| s * v).collect::<Vec<f64>>();
    let (f1, f2) = (scaled(0.5), scaled(1.0));
    for power_law in [false, true] {
        let setup = |pb: &mut dualsplit::ContactProblem| {
            if power_law {
                let m = sc.m();
                pb.set_compliance(Some(&vec![5e4; m]), Some(&vec![1.5; m]), None)
                    .unwrap();
            }
        };
        let (mut pb, mut twin) = (sc.problem(), sc.problem());
        setup(&mut pb);
        setup(&mut twin);
        pb.step(&f1, &sc.g, law, &o).unwrap();
        twin.step(&f1, &sc.g, law, &o).unwrap();
        let mut calls = 0;
        let mut boom = |_: &Progress| -> bool {
            calls += 1;
            panic!("a monitor's bug");
        };
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pb.step_monitored(&f2, &sc.g, law, &o, Some(&mut boom))
        }));
        assert!(caught.is_err() && calls == 1, "the monitor panicked once");
        // The next step is the step the twin takes from the same history.
        let got = pb.step(&f2, &sc.g, law, &o).unwrap();
        let want = twin.step(&f2, &sc.g, law, &o).unwrap();
        assert_eq!(got.report.status, SolveStatus::Converged);
        let d = got
            .lambda_n
            .iter()
            .zip(&want.lambda_n)
            .chain(got.u.iter().zip(&want.u))
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let scale = want.lambda_n.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        assert!(d <= 1e-9 * scale, "power law {power_law}: differs by {d:e}");
        // Reset gives a fresh handle's first step.
        pb.reset_history();
        let mut fresh = sc.problem();
        setup(&mut fresh);
        let got = pb.step(&f2, &sc.g, law, &o).unwrap();
        let want = fresh.step(&f2, &sc.g, law, &o).unwrap();
        let d = got
            .lambda_n
            .iter()
            .zip(&want.lambda_n)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            d <= 1e-9 * scale,
            "power law {power_law}: after reset {d:e}"
        );
    }
}

/// What the re-entering monitor below did: the handle and a K to refactor
/// with, and the statuses its calls on the handle returned.
struct Reenter {
    handle: *mut DsProblem,
    k: DsMatrix,
    statuses: Vec<DsStatus>,
}

/// Calls every kind of entry point on its own handle, from inside the call
/// that runs the monitor.
unsafe extern "C" fn reenter(_: *const DsProgress, user_data: *mut c_void) -> i32 {
    // SAFETY: the test passes a *mut Reenter that outlives the solve.
    let r = unsafe { &mut *(user_data as *mut Reenter) };
    // SAFETY: DsInfo is plain old data; zero is a value.
    let mut info: DsInfo = unsafe { std::mem::zeroed() };
    info.struct_size = std::mem::size_of::<DsInfo>() as _;
    // SAFETY: live handle and K; the calls are refused before they read more.
    unsafe {
        r.statuses.push(ds_problem_refactor(r.handle, &r.k));
        r.statuses.push(ds_history_reset(r.handle));
        r.statuses
            .push(ds_problem_info(r.handle, std::ptr::null(), &mut info));
        r.statuses
            .push(ds_problem_set_monitor(r.handle, None, std::ptr::null_mut()));
        // Freed from inside its own call: kept (the call goes on with it).
        ds_problem_free(r.handle);
    }
    0
}

#[test]
fn a_callback_that_re_enters_its_handle_gets_busy_and_changes_nothing() {
    let sc = scene();
    let mu = vec![0.3; sc.m()];
    let h = new_handle(&sc);
    let (kp, ki) = csc_i64(&sc.k);
    let mut r = Reenter {
        handle: h.0,
        k: view(&sc.k, &kp, &ki),
        statuses: Vec::new(),
    };
    // SAFETY: live handle; r outlives the step.
    let s = unsafe { ds_problem_set_monitor(h.0, Some(reenter), (&mut r as *mut Reenter).cast()) };
    assert_eq!(s, DsStatus::Ok);
    let opts = dualsplit::internals::ffi::DsOptions {
        method: 2,
        ..Default::default()
    };
    let f2: Vec<f64> = sc.f.iter().map(|v| 1.3 * v).collect();
    let run_step = |h: *mut DsProblem, f: &[f64], u: &mut [f64], ln: &mut [f64], lt: &mut [f64]| {
        // SAFETY: arrays sized for the problem; report may be NULL.
        unsafe {
            ds_step(
                h,
                &opts,
                1,
                f.as_ptr(),
                sc.g.as_ptr(),
                mu.as_ptr(),
                u.as_mut_ptr(),
                ln.as_mut_ptr(),
                lt.as_mut_ptr(),
                std::ptr::null_mut(),
            )
        }
    };
    let (mut u, mut ln, mut lt) = (vec![0.0; sc.f.len()], vec![0.0; sc.m()], vec![0.0; sc.m()]);
    assert_eq!(run_step(h.0, &sc.f, &mut u, &mut ln, &mut lt), DsStatus::Ok);
    assert!(!r.statuses.is_empty(), "the monitor ran");
    assert!(
        r.statuses.iter().all(|&s| s == DsStatus::Busy),
        "{:?}",
        r.statuses
    );
    // Nothing changed: the monitor is still set (its set_monitor was refused),
    // and the step advanced the history as a fresh handle's does.
    let calls = r.statuses.len();
    let fresh = new_handle(&sc);
    let (mut u2, mut ln2, mut lt2) = (vec![0.0; sc.f.len()], vec![0.0; sc.m()], vec![0.0; sc.m()]);
    assert_eq!(
        run_step(fresh.0, &sc.f, &mut u2, &mut ln2, &mut lt2),
        DsStatus::Ok
    );
    assert_eq!((&u, &ln, &lt), (&u2, &ln2, &lt2));
    assert_eq!(run_step(h.0, &f2, &mut u, &mut ln, &mut lt), DsStatus::Ok);
    assert!(r.statuses.len() > calls, "the monitor is still set");
    assert_eq!(
        run_step(fresh.0, &f2, &mut u2, &mut ln2, &mut lt2),
        DsStatus::Ok
    );
    assert_eq!((&u, &ln, &lt), (&u2, &ln2, &lt2));
    // SAFETY: clearing the monitor before r goes.
    unsafe { ds_problem_set_monitor(h.0, None, std::ptr::null_mut()) };
}
