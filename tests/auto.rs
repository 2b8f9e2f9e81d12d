//! `Method::Auto` (DS_METHOD_AUTO): its choices, asserted on the report (not
//! timed), and its answers against the method it chose run by name. The fallback
//! when Newton stalls is checked on infeasible problems in tests/property.rs
//! (Newton stalls there, split-mprgp then proves the dual unbounded).

mod common;

use common::{Mesh, Owned, Scene, assert_converged, kkt_of};
use dualsplit::internals::ffi::*;
use dualsplit::{ContactProblem, DualForm, Friction, Method, Options};

fn block3d() -> Scene {
    Scene::pressed_block(
        Mesh::grid3d(6, 6, 3, 2.0, 2.0, 1.0),
        &[0.004, 0.002, -0.03],
        0.02,
        &[1.0, 1.0],
    )
}

fn strip2d() -> Scene {
    Scene::pressed_block(
        Mesh::grid2d(60, 6, 20.0, 1.0),
        &[0.004, -0.02],
        0.002,
        &[10.0],
    )
}

fn opts(method: Method) -> Options {
    Options {
        method,
        threads: 1,
        ..Options::default()
    }
}

/// On a dense dual auto runs Newton: the same iterates, bit for bit (one thread),
/// and says why.
#[test]
fn auto_runs_newton_on_a_dense_dual() {
    for (name, sc) in [("3d block", block3d()), ("2d strip", strip2d())] {
        let mu = vec![0.3; sc.m()];
        for friction in [Friction::Coulomb(&mu), Friction::Tresca(&mu)] {
            let mut pb = ContactProblem::from_csc_with(
                sc.d,
                sc.k.clone(),
                sc.n.clone(),
                sc.t.clone(),
                &opts(Method::Newton),
            )
            .unwrap();
            assert!(!pb.is_matrix_free());
            let auto = pb
                .solve(&sc.f, &sc.g, friction, &opts(Method::Auto))
                .unwrap();
            let newton = pb
                .solve(&sc.f, &sc.g, friction, &opts(Method::Newton))
                .unwrap();
            assert_converged(name, &auto);
            assert_eq!(auto.report.method, Method::Newton, "{name}");
            assert!(
                auto.report.choice.contains("dense dual"),
                "{}",
                auto.report.choice
            );
            assert!(newton.report.choice.is_empty());
            assert_eq!(auto.u, newton.u, "{name}");
            assert_eq!(auto.lambda_n, newton.lambda_n, "{name}");
            assert_eq!(auto.lambda_t, newton.lambda_t, "{name}");
            assert_eq!(auto.report.outer_iterations, newton.report.outer_iterations);
            kkt_of(&sc, friction, &auto).assert_ok(name, 1e-8);
        }
    }
}

/// On a matrix-free dual auto runs MPRGP (the one method that needs no entries
/// of A) and keeps the dual matrix-free; the answer satisfies the KKT conditions
/// and matches dense Newton's.
#[test]
fn auto_runs_newton_on_a_matrix_free_dual() {
    let sc = block3d();
    let mu = vec![0.3; sc.m()];
    let friction = Friction::Coulomb(&mu);
    let (k, n, t) = (sc.k.clone(), sc.n.clone(), sc.t.clone());
    let mut pb = ContactProblem::from_csc_with(sc.d, k, n, t, &opts(Method::Auto)).unwrap();
    let free = Options {
        dual_form: DualForm::MatrixFree,
        ..opts(Method::Auto)
    };
    let sol = pb.solve(&sc.f, &sc.g, friction, &free).unwrap();
    assert!(pb.is_matrix_free());
    assert_converged("auto matrix-free", &sol);
    assert_eq!(sol.report.method, Method::Newton);
    assert!(
        sol.report.choice.contains("matrix-free"),
        "{}",
        sol.report.choice
    );
    kkt_of(&sc, friction, &sol).assert_ok("auto matrix-free", 1e-8);
    let dense = Options {
        dual_form: DualForm::Dense,
        ..opts(Method::Newton)
    };
    let reference = pb.solve(&sc.f, &sc.g, friction, &dense).unwrap();
    let scale = reference
        .lambda_n
        .iter()
        .fold(0.0f64, |a, x| a.max(x.abs()));
    for (a, b) in sol.lambda_n.iter().zip(&reference.lambda_n) {
        assert!((a - b).abs() <= 1e-7 * scale, "{a} vs {b}");
    }
}

/// Through C: DS_METHOD_AUTO is accepted, DsReport.method names the method it
/// chose, and the summary log line says why.
#[test]
fn ds_method_auto_reports_the_method_it_chose() {
    let sc = block3d();
    let (k, n, t) = (Owned::of(&sc.k), Owned::of(&sc.n), Owned::of(&sc.t));
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    let opts = DsOptions {
        method: DsMethod::Auto as i32,
        threads: 1,
        ..DsOptions::default()
    };
    let mut h: *mut DsProblem = std::ptr::null_mut();
    // SAFETY: valid matrices, options and out pointer.
    assert_eq!(
        unsafe { ds_problem_new_opts(3, &kd, &nd, &td, &opts, &mut h) },
        DsStatus::Ok
    );
    let mut lines: Vec<String> = Vec::new();
    // SAFETY: a live handle; `lines` outlives every solve on it (freed below).
    let st =
        unsafe { ds_problem_set_log(h, 1, Some(collect), (&mut lines as *mut Vec<String>).cast()) };
    assert_eq!(st, DsStatus::Ok);
    let m = sc.m();
    let mu = vec![0.3; m];
    let (mut u, mut ln, mut lt) = (vec![0.0; sc.k.nrows], vec![0.0; m], vec![0.0; 2 * m]);
    let mut report = DsReport::default_for_test();
    // SAFETY: a live handle; every array is sized for the problem.
    let st = unsafe {
        ds_solve(
            h,
            &opts,
            DsFriction::Coulomb as i32,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            mu.as_ptr(),
            u.as_mut_ptr(),
            ln.as_mut_ptr(),
            lt.as_mut_ptr(),
            &mut report,
        )
    };
    assert_eq!(st, DsStatus::Ok);
    assert_eq!(report.method, DsMethod::Newton as i32);
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("auto chose newton: dense dual")),
        "{lines:?}"
    );
    // SAFETY: a handle from ds_problem_new_opts, freed once.
    unsafe { ds_problem_free(h) };
}

/// The log sink: appends each line to the Vec<String> behind `user_data`.
unsafe extern "C" fn collect(
    _level: i32,
    message: *const std::ffi::c_char,
    user_data: *mut std::ffi::c_void,
) {
    // SAFETY: the library passes a NUL-terminated line valid during the call, and
    // the Vec<String> the test registered as user_data.
    unsafe {
        let line = std::ffi::CStr::from_ptr(message)
            .to_string_lossy()
            .into_owned();
        (*user_data.cast::<Vec<String>>()).push(line);
    }
}

/// A zeroed DsReport (plain old data).
trait ZeroReport {
    fn default_for_test() -> Self;
}

impl ZeroReport for DsReport {
    fn default_for_test() -> Self {
        // SAFETY: DsReport is plain old data; all-zero bytes are a value.
        unsafe { std::mem::zeroed() }
    }
}

/// AUTO's route on a thin slab below c = 8,000 (docs/design.md section 6):
/// the contacts-last factor would be a dense block of the contact face, so
/// the analysis picks the matrix-free route; asked for dense, or with a
/// method that reads entries of A, the dense route stays; a thick block
/// stays dense. (Analysis only: nothing is factored.)
#[test]
fn auto_takes_the_matrix_free_route_on_a_thin_slab() {
    let slab = Scene::pressed_block(
        Mesh::grid3d(24, 24, 4, 4.0, 4.0, 0.7),
        &[0.004, 0.002, -0.02],
        0.02,
        &[2.0, 2.0],
    );
    let info = |sc: &Scene, o: &Options| {
        ContactProblem::analyse_csc(sc.d, &sc.k, &sc.n, &sc.t, o).expect("the analysis")
    };
    assert!(slab.n.nrows * 3 < 8000);
    let auto = info(&slab, &opts(Method::Auto));
    assert_eq!(auto.setup_form, DualForm::MatrixFree, "{auto:?}");
    let pgs = info(&slab, &opts(Method::Pgs));
    assert_eq!(
        pgs.setup_form,
        DualForm::Dense,
        "a method that reads A: {pgs:?}"
    );
    let dense = info(
        &slab,
        &Options {
            dual_form: DualForm::Dense,
            ..opts(Method::Newton)
        },
    );
    assert_eq!(dense.setup_form, DualForm::Dense, "{dense:?}");
    // The dense route's factor is many times the plain one's here.
    assert!(
        dense.factor_flops > 10.0 * auto.factor_flops,
        "{dense:?} {auto:?}"
    );
    let thick = Scene::pressed_block(
        Mesh::grid3d(12, 12, 8, 2.0, 2.0, 1.4),
        &[0.004, 0.002, -0.02],
        0.02,
        &[1.0, 1.0],
    );
    assert_eq!(
        info(&thick, &opts(Method::Auto)).setup_form,
        DualForm::Dense
    );
}

/// A handle that serves a host's Newton loop (`Options::host_loop`) is made
/// matrix-free in 3D under AUTO, where the method runs matrix-free: a block
/// that AUTO otherwise condenses densely; a method that reads entries of A,
/// an explicit dense form and a 2D strip keep the dense route. (Analysis
/// only.) Its first refactor keeps its contact blocks (the same K: no drift).
#[test]
fn a_host_loop_takes_the_matrix_free_route_in_3d() {
    let info = |sc: &Scene, o: &Options| {
        ContactProblem::analyse_csc(sc.d, &sc.k, &sc.n, &sc.t, o).expect("the analysis")
    };
    let host = |o: Options| Options {
        host_loop: true,
        ..o
    };
    let block = block3d();
    assert_eq!(
        info(&block, &opts(Method::Auto)).setup_form,
        DualForm::Dense
    );
    assert_eq!(
        info(&block, &host(opts(Method::Auto))).setup_form,
        DualForm::MatrixFree
    );
    assert_eq!(
        info(&block, &host(opts(Method::Newton))).setup_form,
        DualForm::MatrixFree
    );
    assert_eq!(
        info(&block, &host(opts(Method::Pgs))).setup_form,
        DualForm::Dense,
        "a method that reads A"
    );
    let dense = Options {
        dual_form: DualForm::Dense,
        ..host(opts(Method::Auto))
    };
    assert_eq!(info(&block, &dense).setup_form, DualForm::Dense);
    let strip = strip2d();
    assert_eq!(
        info(&strip, &host(opts(Method::Auto))).setup_form,
        DualForm::Dense,
        "2D"
    );
    // The handle: matrix-free, and a refactor onto the same K keeps its blocks.
    let o = host(opts(Method::Auto));
    let mut pb = ContactProblem::from_csc_with(
        block.d,
        block.k.clone(),
        block.n.clone(),
        block.t.clone(),
        &o,
    )
    .expect("a valid problem");
    assert!(pb.is_matrix_free());
    pb.refactor(&Owned::of(&block.k).view()).expect("refactor");
    let info = pb.info(&o);
    assert_eq!((info.blocks_age, info.err_factor), (1, 1.0));
    let mu = vec![0.3; block.m()];
    let sol = pb
        .solve(&block.f, &block.g, Friction::Coulomb(&mu), &o)
        .expect("a solve");
    assert_converged("host loop", &sol);
    kkt_of(&block, Friction::Coulomb(&mu), &sol).assert_ok("host loop", 1e-8);
}

/// DsOptions.host_loop through C: 1 takes the matrix-free route on the 3D
/// block, 2 is refused with the field named.
#[test]
fn ds_options_host_loop_reaches_the_route() {
    let block = block3d();
    let (k, n, t) = (
        Owned::of(&block.k),
        Owned::of(&block.n),
        Owned::of(&block.t),
    );
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    let mut o = DsOptions {
        threads: 1,
        host_loop: 1,
        ..DsOptions::default()
    };
    let mut info = DsInfo {
        struct_size: std::mem::size_of::<DsInfo>() as u32,
        // SAFETY: DsInfo is plain old data; all zeros is a value.
        ..unsafe { std::mem::zeroed() }
    };
    // SAFETY: valid matrices, options and DsInfo.
    let st = unsafe { ds_analyse(3, &kd, &nd, &td, &o, &mut info) };
    assert_eq!(st, DsStatus::Ok);
    assert_eq!(info.setup_form, DsDualForm::MatrixFree as i32);
    o.host_loop = 2;
    let before = info;
    // SAFETY: as above.
    let st = unsafe { ds_analyse(3, &kd, &nd, &td, &o, &mut info) };
    assert_eq!(st, DsStatus::BadArgument);
    assert_eq!(info, before, "info written on error");
    // SAFETY: the message is a NUL-terminated string the library owns.
    let msg = unsafe { std::ffi::CStr::from_ptr(ds_last_error_message()) }
        .to_string_lossy()
        .into_owned();
    assert!(msg.contains("host_loop = 2"), "{msg}");
}
