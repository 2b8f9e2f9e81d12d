//! The fill-reducing ordering (`Options::ordering`: AMD, METIS or the cheaper of
//! the two) and the problem's own threads (`Options::threads`).
//!
//! Checked: AMD and METIS give the same solution (to 1e-12, and each one passes
//! the KKT check) on a 3D block and a 2D strip; AUTO follows its rule, METIS on
//! the 3D block, AMD on the 2D strip (asserted on the symbolic flop counts the
//! report carries, not on times), and in 3D METIS alone, also where AMD's factor
//! would need fewer flops (FCLib's small cubes); one and two threads
//! give the same answer to rounding, one thread has no pool and two threads
//! have one of two; bad values are refused through the C interface with
//! DS_STATUS_BAD_ARGUMENT.

mod common;

use common::{Mesh, Owned, Scene, kkt_of, max_diff, norm_inf};
use dualsplit::internals::ffi::*;
use dualsplit::{ContactProblem, Friction, Method, Options, Ordering, Solution, SolveStatus};
use std::ptr::{null, null_mut};

/// A 3D block of nx x nx x nz H8 cells pressed and sheared from the top, every
/// bottom node a contact over a paraboloid gap.
fn block3d(nx: usize, nz: usize) -> Scene {
    let mesh = Mesh::grid3d(nx, nx, nz, 2.0, 2.0, 1.0);
    Scene::pressed_block(mesh, &[0.004, 0.002, -0.03], 0.02, &[1.0, 1.0])
}

/// A long 2D strip of nx x ny Q4 cells, pressed and sheared from the top.
fn strip2d(nx: usize, ny: usize) -> Scene {
    let mesh = Mesh::grid2d(nx, ny, 20.0, 1.0);
    Scene::pressed_block(mesh, &[0.004, -0.02], 0.002, &[10.0])
}

fn problem(sc: &Scene, ordering: Ordering, threads: usize) -> ContactProblem {
    let opts = Options {
        ordering,
        threads,
        ..Options::default()
    };
    ContactProblem::from_csc_with(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone(), &opts)
        .expect("valid problem")
}

fn solve(sc: &Scene, pb: &mut ContactProblem, mu: &[f64]) -> Solution {
    let opts = Options {
        method: Method::Newton,
        tol: 1e-12,
        ..Options::default()
    };
    let sol = pb
        .solve(&sc.f, &sc.g, Friction::Coulomb(mu), &opts)
        .expect("solve");
    assert_eq!(
        sol.report.status,
        SolveStatus::Converged,
        "{:?}",
        sol.report
    );
    kkt_of(sc, Friction::Coulomb(mu), &sol).assert_ok("kkt", 1e-8);
    sol
}

fn agree(what: &str, a: &Solution, b: &Solution, tol: f64) {
    for (name, x, y) in [
        ("u", &a.u, &b.u),
        ("lambda_n", &a.lambda_n, &b.lambda_n),
        ("lambda_t", &a.lambda_t, &b.lambda_t),
    ] {
        let scale = norm_inf(x).max(f64::MIN_POSITIVE);
        let d = max_diff(x, y) / scale;
        assert!(d <= tol, "{what}: {name} differs by {d:.2e} (relative)");
    }
}

#[test]
fn amd_and_metis_agree_and_auto_keeps_the_cheaper_one() {
    for (name, sc, want) in [
        ("3D block", block3d(16, 8), Ordering::Metis),
        ("2D strip", strip2d(200, 4), Ordering::Amd),
    ] {
        let mu = vec![0.3; sc.m()];
        let mut amd = problem(&sc, Ordering::Amd, 1);
        let mut metis = problem(&sc, Ordering::Metis, 1);
        let mut auto = problem(&sc, Ordering::Auto, 1);
        let (sa, sm, so) = (
            solve(&sc, &mut amd, &mu),
            solve(&sc, &mut metis, &mu),
            solve(&sc, &mut auto, &mu),
        );
        assert_eq!(sa.report.ordering, Ordering::Amd);
        assert_eq!(sm.report.ordering, Ordering::Metis);
        let (fa, fm) = (sa.report.factor_flops, sm.report.factor_flops);
        let per_entry = fa / sa.report.factor_nnz as f64;
        println!("{name}: flops AMD {fa:.3e} ({per_entry:.0} per entry of L), METIS {fm:.3e}");
        // AUTO's rule: in 3D METIS alone (AMD where METIS fails); in 2D METIS
        // is tried only where AMD's fronts are large (more than 500 flops per
        // entry of L), and then the cheaper is kept.
        let auto = if sc.d == 3 || (per_entry > 500.0 && fm < fa) {
            Ordering::Metis
        } else {
            Ordering::Amd
        };
        if sc.d == 3 {
            assert!(fm < fa, "{name}: AMD {fa:.3e} flops, METIS {fm:.3e}");
        }
        assert_eq!(so.report.ordering, auto, "{name}: AUTO's rule");
        let kept = if auto == Ordering::Metis { fm } else { fa };
        assert_eq!(so.report.factor_flops, kept);
        assert_eq!(auto, want, "{name}: AMD {fa:.3e} flops, METIS {fm:.3e}");
        agree(name, &sa, &sm, 1e-12);
    }
}

/// In 3D AUTO takes METIS alone, also where METIS's fronts are small (a
/// thin slab: fewer than 500 flops per entry of L, where AMD used to be
/// analysed as well and lost): the report names METIS, the factor is METIS's
/// (the same flops, and the same answer to the last bit), and METIS's factor
/// needs fewer flops than AMD's, the fact the rule rests on. (The choice on
/// this slab was METIS before too; the next test tells the rules apart.)
#[test]
fn auto_in_3d_is_metis_on_small_fronts_too() {
    let sc = block3d(24, 4);
    let mu = vec![0.3; sc.m()];
    let sa = solve(&sc, &mut problem(&sc, Ordering::Amd, 1), &mu);
    let sm = solve(&sc, &mut problem(&sc, Ordering::Metis, 1), &mu);
    let so = solve(&sc, &mut problem(&sc, Ordering::Auto, 1), &mu);
    let (fa, fm) = (sa.report.factor_flops, sm.report.factor_flops);
    let per_entry = fm / sm.report.factor_nnz as f64;
    println!("3D slab: flops AMD {fa:.3e}, METIS {fm:.3e} ({per_entry:.0} per entry of L)");
    assert!(per_entry < 500.0, "small fronts: {per_entry:.0}");
    assert!(fm < fa, "AMD {fa:.3e} flops, METIS {fm:.3e}");
    assert_eq!(so.report.ordering, Ordering::Metis);
    assert_eq!(so.report.factor_flops, fm);
    agree("3D slab, AUTO and METIS", &so, &sm, 0.0);
}

/// AUTO in 3D analyses METIS alone, so it keeps METIS even where AMD's
/// factor would need fewer flops: FCLib's 3D problems (tests/data/fclib,
/// analysed only: `ContactProblem::analyse_csc`), at least one of which
/// (a 162-DOF cube, nearly dense) is such a case. Where the rule analysed
/// AMD as well (METIS's fronts small, as on these), AUTO would have kept
/// AMD there.
#[test]
fn auto_in_3d_keeps_metis_where_amd_would_be_cheaper() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fclib");
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .expect("tests/data/fclib")
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.join("K.mtx").exists())
        .collect();
    names.sort();
    let (mut three_d, mut amd_cheaper) = (0, 0);
    for path in names {
        let pf = dualsplit::mtx::read_problem(&path).expect("an FCLib folder");
        if pf.d != 3 {
            continue;
        }
        three_d += 1;
        let info = |ordering: Ordering| {
            let opts = Options {
                ordering,
                threads: 1,
                ..Options::default()
            };
            ContactProblem::analyse_csc(pf.d, &pf.k, &pf.n, &pf.t, &opts).expect("analysis")
        };
        let (amd, metis, auto) = (
            info(Ordering::Amd),
            info(Ordering::Metis),
            info(Ordering::Auto),
        );
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        println!(
            "{name}: flops AMD {:.3e}, METIS {:.3e}, AUTO {:?} {:.3e}",
            amd.factor_flops, metis.factor_flops, auto.ordering, auto.factor_flops
        );
        assert_eq!(auto.ordering, Ordering::Metis, "{name}");
        assert_eq!(auto.factor_flops, metis.factor_flops, "{name}");
        if amd.factor_flops < metis.factor_flops {
            amd_cheaper += 1;
        }
    }
    assert!(three_d >= 5, "{three_d} 3D FCLib problems");
    assert!(amd_cheaper >= 1, "no 3D problem where AMD is cheaper");
}

#[test]
fn one_and_two_threads_agree_and_one_thread_has_no_pool() {
    let sc = block3d(8, 4);
    let mu = vec![0.3; sc.m()];
    let mut one = problem(&sc, Ordering::Auto, 1);
    let mut two = problem(&sc, Ordering::Auto, 2);
    assert_eq!(one.threads(), 1);
    assert_eq!(two.threads(), 2);
    let (s1, s2) = (solve(&sc, &mut one, &mu), solve(&sc, &mut two, &mu));
    assert_eq!(s1.report.threads, 1);
    assert_eq!(s2.report.threads, 2);
    agree("1 vs 2 threads", &s1, &s2, 1e-12);
    // One thread: the same bits every time.
    let again = solve(&sc, &mut problem(&sc, Ordering::Auto, 1), &mu);
    assert_eq!(s1.u, again.u);
    assert_eq!(s1.lambda_n, again.lambda_n);
}

#[test]
fn bad_threads_and_orderings_are_refused() {
    let sc = strip2d(10, 2);
    let (k, n, t) = (Owned::of(&sc.k), Owned::of(&sc.n), Owned::of(&sc.t));
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    for (threads, ordering, what) in [(-1, 0, "threads"), (5000, 0, "threads"), (1, 7, "ordering")]
    {
        let opts = DsOptions {
            threads,
            ordering,
            ..DsOptions::default()
        };
        let mut out: *mut DsProblem = null_mut();
        // SAFETY: the matrices, options and out pointer are valid.
        let st = unsafe { ds_problem_new_opts(2, &kd, &nd, &td, &opts, &mut out) };
        assert_eq!(st, DsStatus::BadArgument, "{what}");
        assert!(out.is_null(), "out untouched on error");
        // SAFETY: the message is a valid NUL-terminated string.
        let msg = unsafe { std::ffi::CStr::from_ptr(ds_last_error_message()) };
        assert!(msg.to_string_lossy().contains(what), "{msg:?}");
    }
    // A valid call with NULL options works and gives a usable handle.
    let mut out: *mut DsProblem = null_mut();
    // SAFETY: as above; NULL options mean the defaults.
    let st = unsafe { ds_problem_new_opts(2, &kd, &nd, &td, null(), &mut out) };
    assert_eq!(st, DsStatus::Ok);
    // SAFETY: a handle from ds_problem_new_opts, freed once.
    unsafe { ds_problem_free(out) };
}

#[test]
fn the_c_report_carries_the_ordering_for_new_callers_only() {
    let sc = block3d(4, 2);
    let (k, n, t) = (Owned::of(&sc.k), Owned::of(&sc.n), Owned::of(&sc.t));
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    let opts = DsOptions {
        threads: 1,
        ordering: DsOrdering::Metis as i32,
        ..DsOptions::default()
    };
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: valid matrices, options and out pointer.
    let st = unsafe { ds_problem_new_opts(3, &kd, &nd, &td, &opts, &mut h) };
    assert_eq!(st, DsStatus::Ok);
    let m = sc.m();
    let mu = vec![0.3; m];
    let (mut u, mut ln, mut lt) = (vec![0.0; sc.k.nrows], vec![0.0; m], vec![0.0; 2 * m]);
    let solve = |opts: *const DsOptions, u: &mut [f64], ln: &mut [f64], lt: &mut [f64]| {
        // All bytes 0xA5: what the library does not write stays so.
        // SAFETY: DsReport is plain old data; any bit pattern is a value.
        let mut report: DsReport = unsafe { std::mem::transmute([0xA5u8; 136]) };
        // SAFETY: the handle is live and every array is sized for the problem.
        let st = unsafe {
            ds_solve(
                h,
                opts,
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
        report
    };
    // A 0.4 caller (DsOptions of 72 bytes) gets the 0.4 fields, nothing past
    // its 120-byte report.
    let v04 = DsOptions {
        struct_size: 72,
        ..opts
    };
    let r = solve(&v04, &mut u, &mut ln, &mut lt);
    assert_eq!(r.ordering, DsOrdering::Metis as i32);
    assert_eq!(r.threads, 1);
    assert!(r.factor_nnz > 0 && r.factor_flops > 0.0);
    // SAFETY: DsReport is plain old data.
    let bytes: [u8; 136] = unsafe { std::mem::transmute(r) };
    assert!(
        bytes[120..].iter().all(|&b| b == 0xA5),
        "wrote past 120 bytes"
    );
    // A 0.5 caller gets the memory fields too.
    let r = solve(&opts, &mut u, &mut ln, &mut lt);
    assert!(
        r.memory_peak > 0 && r.memory_peak <= r.memory_predicted,
        "{r:?}"
    );
    // NULL options (an old caller's way): the 0.1-0.3 report, nothing past it.
    let r = solve(null(), &mut u, &mut ln, &mut lt);
    assert_eq!(r.status, DsStatus::Ok as i32);
    // SAFETY: DsReport is plain old data.
    let bytes: [u8; 136] = unsafe { std::mem::transmute(r) };
    assert!(
        bytes[88..].iter().all(|&b| b == 0xA5),
        "wrote past 88 bytes"
    );
    // SAFETY: a handle from ds_problem_new_opts, freed once.
    unsafe { ds_problem_free(h) };
}

/// K as a FE code may write it: entries whose value cancelled in the assembly
/// (below 1e-13 max|K|) stored on one side only with a tiny value (`zeros`
/// false), or with an exact zero stored on the other side (`zeros` true),
/// the side chosen by a hash of the pair; and every diagonal entry given as
/// two duplicates that sum to it.
fn as_fe_codes_write_it(k: &dualsplit::Csc, zeros: bool) -> Owned {
    let max = k.values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let (mut p, mut i, mut x) = (vec![0i64], Vec::new(), Vec::new());
    for j in 0..k.ncols {
        for q in k.col_ptr[j]..k.col_ptr[j + 1] {
            let r = k.row_idx[q];
            let v = k.values[q];
            if r == j {
                i.extend([r as i64, r as i64]);
                x.extend([0.25 * v, 0.75 * v]);
                continue;
            }
            if v.abs() > 1e-13 * max {
                i.push(r as i64);
                x.push(v);
                continue;
            }
            let (a, b) = (r.min(j) as u64, r.max(j) as u64);
            let upper_kept = (a * 1_000_003 + b).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 63 == 0;
            if (r < j) == upper_kept {
                i.push(r as i64);
                x.push(3.5e-18 * max);
            } else if zeros {
                i.push(r as i64);
                x.push(0.0);
            }
        }
        p.push(i.len() as i64);
    }
    Owned {
        nrows: k.nrows as i64,
        ncols: k.ncols as i64,
        p,
        i,
        x,
    }
}

#[test]
fn a_k_with_one_sided_entries_zeros_and_duplicates_solves_under_every_ordering() {
    // A 3D block whose uniform hexahedra cancel many couplings exactly (as
    // GetFEM's K of a thin slab does, where METIS_NodeND used to corrupt its
    // heap on the one-sided graph).
    let sc = block3d(10, 4);
    let mu = vec![0.3; sc.m()];
    let mut whole = problem(&sc, Ordering::Amd, 1);
    let want = solve(&sc, &mut whole, &mu);
    let (n, t) = (Owned::of(&sc.n), Owned::of(&sc.t));
    for zeros in [false, true] {
        let k = as_fe_codes_write_it(&sc.k, zeros);
        // Every pair and the duplicated diagonal, less the dropped mirrors.
        let one_sided = k.i.len() < sc.k.nnz() + sc.k.nrows;
        assert_eq!(one_sided, !zeros, "the test K has one-sided entries");
        for ordering in [DsOrdering::Amd, DsOrdering::Metis, DsOrdering::Auto] {
            let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
            let opts = DsOptions {
                threads: 1,
                ordering: ordering as i32,
                tol: 1e-12,
                method: DsMethod::Newton as i32,
                ..DsOptions::default()
            };
            let mut h: *mut DsProblem = null_mut();
            // SAFETY: valid matrices, options and out pointer.
            let st = unsafe { ds_problem_new_opts(3, &kd, &nd, &td, &opts, &mut h) };
            assert_eq!(st, DsStatus::Ok, "zeros {zeros} {ordering:?}");
            let m = sc.m();
            let (mut u, mut ln, mut lt) = (vec![0.0; sc.k.nrows], vec![0.0; m], vec![0.0; 2 * m]);
            // SAFETY: DsReport is plain old data; zero is a value.
            let mut report: DsReport = unsafe { std::mem::zeroed() };
            // SAFETY: the handle is live and every array is sized for the problem.
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
            assert_eq!(st, DsStatus::Ok, "zeros {zeros} {ordering:?}");
            // SAFETY: a handle from ds_problem_new_opts, freed once.
            unsafe { ds_problem_free(h) };
            for (name, x, y) in [
                ("u", &u, &want.u),
                ("lambda_n", &ln, &want.lambda_n),
                ("lambda_t", &lt, &want.lambda_t),
            ] {
                let d = max_diff(x, y) / norm_inf(y);
                assert!(
                    d <= 1e-9,
                    "zeros {zeros} {ordering:?}: {name} differs by {d:.2e}"
                );
            }
        }
    }
}
