//! Every status of the C API, produced through the `extern "C"` entry points with raw
//! pointers exactly as a C caller would pass them. After each error: the status is
//! the expected one, `ds_last_error_message()` is non-empty and names the culprit,
//! the output arrays still hold their sentinel, and the same handle then solves a
//! valid problem.
//!
//! - DS_STATUS_IO_ERROR: ds_problem_dump into a folder that cannot be created.
//! - DS_STATUS_PANIC: no valid or invalid input may make the core panic (a T
//!   narrower than N once did, in stack_rows: now BAD_SIZE, in `bad_size`); the
//!   boundary's catch_unwind is unit-tested in src/ffi/boundary.rs (a panic inside
//!   an entry point gives DS_STATUS_PANIC and a message, never an abort).
//! - DS_STATUS_OUT_OF_MEMORY is produced here with absurd dimensions (the core
//!   reports failed allocations of caller-sized arrays instead of aborting).

use dualsplit::internals::ffi::*;
use std::ffi::CStr;
use std::ptr::{null, null_mut};

const SENTINEL: f64 = -777.25;

/// The signature shared by ds_solve and ds_step.
type SolveFn = unsafe extern "C" fn(
    *mut DsProblem,
    *const DsOptions,
    i32,
    *const f64,
    *const f64,
    *const f64,
    *mut f64,
    *mut f64,
    *mut f64,
    *mut DsReport,
) -> DsStatus;

// ---------------------------------------------------------------------------------
// Matrices owned by the test, handed to the library as DsMatrix (CSC, int64, base 0
// unless a test edits the fields).

/// A CSC matrix with int64 indices, base 0.
#[derive(Clone, Debug)]
struct Owned {
    nrows: i64,
    ncols: i64,
    p: Vec<i64>,
    i: Vec<i64>,
    x: Vec<f64>,
}

impl Owned {
    /// From a dense row-major array: stores the entries where `keep(r, c, v)`.
    fn from_dense(
        nrows: usize,
        ncols: usize,
        a: &[f64],
        keep: impl Fn(usize, usize, f64) -> bool,
    ) -> Owned {
        assert_eq!(a.len(), nrows * ncols);
        let (mut p, mut i, mut x) = (vec![0i64], vec![], vec![]);
        for c in 0..ncols {
            for r in 0..nrows {
                let v = a[r * ncols + c];
                if keep(r, c, v) {
                    i.push(r as i64);
                    x.push(v);
                }
            }
            p.push(i.len() as i64);
        }
        Owned {
            nrows: nrows as i64,
            ncols: ncols as i64,
            p,
            i,
            x,
        }
    }

    /// Every entry stored (a dense pattern).
    fn dense(nrows: usize, ncols: usize, a: &[f64]) -> Owned {
        Owned::from_dense(nrows, ncols, a, |_, _, _| true)
    }

    /// Only the nonzeros stored.
    fn sparse(nrows: usize, ncols: usize, a: &[f64]) -> Owned {
        Owned::from_dense(nrows, ncols, a, |_, _, v| v != 0.0)
    }

    fn ds(&self) -> DsMatrix {
        DsMatrix {
            format: DsFormat::Csc as i32,
            index_type: DsIndexType::I64 as i32,
            base: 0,
            storage: DsStorage::Full as i32,
            nrows: self.nrows,
            ncols: self.ncols,
            nnz: 0,
            p: self.p.as_ptr().cast(),
            i: self.i.as_ptr().cast(),
            x: self.x.as_ptr(),
        }
    }
}

// ---------------------------------------------------------------------------------
// The small problem: two 2D nodes (DOFs x0, y0, x1, y1), a dense 4 x 4 SPD K with
// coupling, two contacts with normal -e_y (N u = -u_y <= g) and tangent e_x.

const N_DOFS: usize = 4;
const M: usize = 2;

/// K = 3 I + ones(4): SPD (eigenvalues 3, 3, 3, 7), every entry stored.
fn k_values(diag: f64, off: f64) -> Vec<f64> {
    (0..16)
        .map(|e| if e / 4 == e % 4 { diag } else { off })
        .collect()
}

fn k_good() -> Owned {
    Owned::dense(4, 4, &k_values(4.0, 1.0))
}

fn n_good() -> Owned {
    #[rustfmt::skip]
    let a = [0.0, -1.0, 0.0, 0.0,
             0.0, 0.0, 0.0, -1.0];
    Owned::sparse(2, 4, &a)
}

fn t_good() -> Owned {
    #[rustfmt::skip]
    let a = [1.0, 0.0, 0.0, 0.0,
             0.0, 0.0, 1.0, 0.0];
    Owned::sparse(2, 4, &a)
}

/// Loads that push both nodes onto the foundation and sideways.
const F: [f64; N_DOFS] = [0.2, -1.0, -0.3, -1.0];
const G: [f64; M] = [0.0, 0.0];
const P: [f64; M] = [0.1, 0.5];
const MU: [f64; M] = [0.3, 0.3];

/// Caller-owned outputs, filled with a sentinel.
struct Outputs {
    u: Vec<f64>,
    lambda_n: Vec<f64>,
    lambda_t: Vec<f64>,
    report: DsReport,
}

fn sentinel_report() -> DsReport {
    DsReport {
        status: -99,
        method: -99,
        err: SENTINEL,
        equilibrium_residual: SENTINEL,
        outer_iterations: -99,
        inner_iterations: -99,
        n_open: -99,
        n_stick: -99,
        n_slip: -99,
        factor_seconds: SENTINEL,
        condense_seconds: SENTINEL,
        solve_seconds: SENTINEL,
        ordering: -99,
        threads: -99,
        factor_nnz: -99,
        factor_flops: SENTINEL,
        analyse_seconds: SENTINEL,
        memory_predicted: 99,
        memory_peak: 99,
    }
}

impl Outputs {
    fn new(n: usize, m: usize, d: usize) -> Outputs {
        Outputs {
            u: vec![SENTINEL; n],
            lambda_n: vec![SENTINEL; m],
            lambda_t: vec![SENTINEL; (d - 1) * m],
            report: sentinel_report(),
        }
    }

    fn small() -> Outputs {
        Outputs::new(N_DOFS, M, 2)
    }

    fn assert_untouched(&self, context: &str) {
        let all = self.u.iter().chain(&self.lambda_n).chain(&self.lambda_t);
        assert!(
            all.into_iter().all(|&v| v == SENTINEL),
            "{context}: an output array was written on error"
        );
        assert_eq!(
            self.report,
            sentinel_report(),
            "{context}: report written on error"
        );
    }
}

/// The last error message of this thread.
fn last_message() -> String {
    let p = ds_last_error_message();
    assert!(!p.is_null(), "ds_last_error_message returned NULL");
    // SAFETY: non-NULL, NUL-terminated, valid until the next ds_ call on this thread.
    unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
}

/// Whether `word` occurs in `msg` as a whole token (so "f" does not match "of").
fn mentions(msg: &str, word: &str) -> bool {
    let is_word = |c: char| c.is_alphanumeric() || c == '_';
    msg.match_indices(word).any(|(at, _)| {
        let before = msg[..at].chars().next_back();
        let after = msg[at + word.len()..].chars().next();
        !before.is_some_and(is_word) && !after.is_some_and(is_word)
    })
}

/// Asserts an error status, a non-empty message that mentions every word of
/// `culprits` (case-insensitive for words of more than one letter).
#[track_caller]
fn expect_error(status: DsStatus, expected: DsStatus, culprits: &[&str]) -> String {
    let msg = last_message();
    eprintln!("{expected:?}: {msg}");
    assert_eq!(status, expected, "message: {msg}");
    assert!(!msg.is_empty(), "no message for {expected:?}");
    for word in culprits {
        let found = if word.len() > 1 {
            mentions(&msg.to_lowercase(), &word.to_lowercase())
        } else {
            mentions(&msg, word)
        };
        assert!(
            found,
            "message for {expected:?} does not mention `{word}`: {msg}"
        );
    }
    msg
}

#[track_caller]
fn expect_ok(status: DsStatus) {
    let msg = last_message();
    assert_eq!(status, DsStatus::Ok, "message: {msg}");
    assert_eq!(msg, "", "a successful call leaves no message");
}

/// Creates the small problem.
fn new_problem() -> *mut DsProblem {
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut out: *mut DsProblem = null_mut();
    // SAFETY: the matrices live until the call returns; out is a valid location.
    let s = unsafe { ds_problem_new(2, &k.ds(), &n.ds(), &t.ds(), &mut out) };
    expect_ok(s);
    assert!(!out.is_null());
    out
}

/// ds_solve on caller arrays, Tresca by default.
#[allow(clippy::too_many_arguments)]
fn solve_raw(
    problem: *mut DsProblem,
    opts: *const DsOptions,
    friction: i32,
    f: *const f64,
    g: *const f64,
    bound: *const f64,
    out: &mut Outputs,
) -> DsStatus {
    // SAFETY: every array is NULL or as long as the problem needs (the tests pass
    // the small problem's sizes); report points to a DsReport.
    unsafe {
        ds_solve(
            problem,
            opts,
            friction,
            f,
            g,
            bound,
            out.u.as_mut_ptr(),
            out.lambda_n.as_mut_ptr(),
            out.lambda_t.as_mut_ptr(),
            &mut out.report,
        )
    }
}

fn solve_small(
    problem: *mut DsProblem,
    f: &[f64],
    g: &[f64],
    p: &[f64],
    out: &mut Outputs,
) -> DsStatus {
    solve_raw(
        problem,
        null(),
        DsFriction::Tresca as i32,
        f.as_ptr(),
        g.as_ptr(),
        p.as_ptr(),
        out,
    )
}

/// Solves the valid small problem on `problem` and checks the answer: OK, the report
/// written, Signorini and the friction bound satisfied.
#[track_caller]
fn assert_usable(problem: *mut DsProblem) -> Outputs {
    let mut out = Outputs::small();
    let s = solve_small(problem, &F, &G, &P, &mut out);
    expect_ok(s);
    assert_eq!(out.report.status, DsStatus::Ok as i32);
    assert!(out.report.err <= 1e-10, "err = {}", out.report.err);
    assert!(out.report.equilibrium_residual <= 1e-10);
    for i in 0..M {
        let nu = -out.u[2 * i + 1];
        assert!(nu <= G[i] + 1e-9, "penetration at contact {i}");
        assert!(out.lambda_n[i] >= 0.0);
        assert!(out.lambda_t[i].abs() <= P[i] * (1.0 + 1e-9));
    }
    assert!(
        out.lambda_n.iter().all(|&l| l > 0.0),
        "both contacts are closed"
    );
    out
}

fn free(problem: *mut DsProblem) {
    // SAFETY: problem came from ds_problem_new and is freed once.
    unsafe { ds_problem_free(problem) };
}

fn options() -> DsOptions {
    let mut o = DsOptions::default();
    // SAFETY: o is a whole, writable DsOptions.
    let st = unsafe { ds_options_init(&mut o, std::mem::size_of::<DsOptions>()) };
    assert_eq!(st, DsStatus::Ok);
    o
}

// ---------------------------------------------------------------------------------

#[test]
fn small_problem_solves_and_reports() {
    let h = new_problem();
    let (mut nd, mut nc, mut d) = (-1i64, -1i64, -1i32);
    // SAFETY: h is live; the outputs are valid locations.
    expect_ok(unsafe { ds_problem_sizes(h, &mut nd, &mut nc, &mut d) });
    assert_eq!((nd, nc, d), (4, 2, 2));
    let a = assert_usable(h);
    // opts NULL and report NULL are accepted.
    let mut b = Outputs::small();
    // SAFETY: arrays sized for the problem; report NULL is allowed.
    let s = unsafe {
        ds_solve(
            h,
            null(),
            DsFriction::Tresca as i32,
            F.as_ptr(),
            G.as_ptr(),
            P.as_ptr(),
            b.u.as_mut_ptr(),
            b.lambda_n.as_mut_ptr(),
            b.lambda_t.as_mut_ptr(),
            null_mut(),
        )
    };
    expect_ok(s);
    assert_eq!(
        (&a.u, &a.lambda_n, &a.lambda_t),
        (&b.u, &b.lambda_n, &b.lambda_t)
    );
    assert_eq!(b.report, sentinel_report());
    // ds_step from a reset history equals ds_solve (u_0 = 0).
    // SAFETY: h is live.
    expect_ok(unsafe { ds_history_reset(h) });
    let mut c = Outputs::small();
    let o = options();
    // SAFETY: arrays sized for the problem.
    let s = unsafe {
        ds_step(
            h,
            &o,
            DsFriction::Tresca as i32,
            F.as_ptr(),
            G.as_ptr(),
            P.as_ptr(),
            c.u.as_mut_ptr(),
            c.lambda_n.as_mut_ptr(),
            c.lambda_t.as_mut_ptr(),
            &mut c.report,
        )
    };
    expect_ok(s);
    for (x, y) in a.u.iter().zip(&c.u) {
        assert!((x - y).abs() <= 1e-12 * (1.0 + x.abs()), "{x} vs {y}");
    }
    free(h);
    free(null_mut());
}

#[test]
fn null_pointer_ds_problem_new() {
    let (k, n, t) = (k_good(), n_good(), t_good());
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    let mut out: *mut DsProblem = null_mut();
    // SAFETY: (every call below) the matrices outlive the call; NULL is what is tested.
    unsafe {
        expect_error(
            ds_problem_new(2, null(), &nd, &td, &mut out),
            DsStatus::NullPointer,
            &["k"],
        );
        expect_error(
            ds_problem_new(2, &kd, null(), &td, &mut out),
            DsStatus::NullPointer,
            &["n"],
        );
        expect_error(
            ds_problem_new(2, &kd, &nd, null(), &mut out),
            DsStatus::NullPointer,
            &["t"],
        );
        expect_error(
            ds_problem_new(2, &kd, &nd, &td, null_mut()),
            DsStatus::NullPointer,
            &["out"],
        );
        // Pointers inside the matrices.
        for (which, culprit) in [
            ("K.p", "K.p"),
            ("K.i", "K.i"),
            ("K.x", "K.x"),
            ("N.p", "N.p"),
            ("N.i", "N.i"),
            ("N.x", "N.x"),
            ("T.p", "T.p"),
            ("T.i", "T.i"),
            ("T.x", "T.x"),
        ] {
            let (mut k2, mut n2, mut t2) = (kd, nd, td);
            let m = match &which[..1] {
                "K" => &mut k2,
                "N" => &mut n2,
                _ => &mut t2,
            };
            match &which[2..] {
                "p" => m.p = null(),
                "i" => m.i = null(),
                _ => m.x = null(),
            }
            let s = ds_problem_new(2, &k2, &n2, &t2, &mut out);
            expect_error(s, DsStatus::NullPointer, &[culprit]);
        }
    }
    assert!(out.is_null(), "out written on error");
    // A problem without contacts: N and T with no rows, every array NULL.
    let empty = DsMatrix {
        format: DsFormat::Coo as i32,
        index_type: DsIndexType::I32 as i32,
        base: 0,
        storage: DsStorage::Full as i32,
        nrows: 0,
        ncols: 4,
        nnz: 0,
        p: null(),
        i: null(),
        x: null(),
    };
    // SAFETY: no array of the empty matrices is read.
    expect_ok(unsafe { ds_problem_new(2, &kd, &empty, &empty, &mut out) });
    let mut u = vec![SENTINEL; 4];
    let mut report = sentinel_report();
    // SAFETY: m = 0, so g, bound, lambda_n, lambda_t may be NULL; f and u hold 4 values.
    let s = unsafe {
        ds_solve(
            out,
            null(),
            DsFriction::Coulomb as i32,
            F.as_ptr(),
            null(),
            null(),
            u.as_mut_ptr(),
            null_mut(),
            null_mut(),
            &mut report,
        )
    };
    expect_ok(s);
    // u = K^-1 f.
    let kf: Vec<f64> = (0..4)
        .map(|r| (0..4).map(|c| k_values(4.0, 1.0)[r * 4 + c] * u[c]).sum())
        .collect();
    for (a, b) in kf.iter().zip(F) {
        assert!((a - b).abs() < 1e-12);
    }
    free(out);
    // The handle-free failures leave nothing behind; a fresh handle works.
    let h = new_problem();
    assert_usable(h);
    free(h);
}

#[test]
fn null_pointer_handle_functions() {
    let h = new_problem();
    let (k, n, t) = (k_good(), n_good(), t_good());
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    // SAFETY: (every call below) valid or NULL pointers; NULL is what is tested.
    unsafe {
        expect_error(
            ds_problem_refactor(null_mut(), &kd),
            DsStatus::NullPointer,
            &["problem"],
        );
        expect_error(
            ds_problem_refactor(h, null()),
            DsStatus::NullPointer,
            &["k"],
        );
        assert_usable(h);
        expect_error(
            ds_problem_set_contacts(null_mut(), &nd, &td),
            DsStatus::NullPointer,
            &["problem"],
        );
        expect_error(
            ds_problem_set_contacts(h, null(), &td),
            DsStatus::NullPointer,
            &["n"],
        );
        expect_error(
            ds_problem_set_contacts(h, &nd, null()),
            DsStatus::NullPointer,
            &["t"],
        );
        assert_usable(h);
        let (mut a, mut b, mut c) = (-5i64, -5i64, -5i32);
        expect_error(
            ds_problem_sizes(null(), &mut a, &mut b, &mut c),
            DsStatus::NullPointer,
            &["problem"],
        );
        expect_error(
            ds_problem_sizes(h, null_mut(), &mut b, &mut c),
            DsStatus::NullPointer,
            &["n_dofs"],
        );
        expect_error(
            ds_problem_sizes(h, &mut a, null_mut(), &mut c),
            DsStatus::NullPointer,
            &["n_contacts"],
        );
        expect_error(
            ds_problem_sizes(h, &mut a, &mut b, null_mut()),
            DsStatus::NullPointer,
            &["d"],
        );
        assert_eq!((a, b, c), (-5, -5, -5), "sizes written on error");
        expect_error(
            ds_history_reset(null_mut()),
            DsStatus::NullPointer,
            &["problem"],
        );
    }
    // ds_solve and ds_step: each pointer argument NULL in turn.
    for step in [false, true] {
        let names = if step {
            [
                "problem", "f_total", "g0", "bound", "u", "lambda_n", "lambda_t",
            ]
        } else {
            ["problem", "f", "g", "bound", "u", "lambda_n", "lambda_t"]
        };
        for (which, culprit) in names.iter().enumerate() {
            let mut out = Outputs::small();
            let nul = |j: usize, p: *const f64| if j == which { null() } else { p };
            let nul_mut = |j: usize, p: *mut f64| if j == which { null_mut() } else { p };
            let problem = if which == 0 { null_mut() } else { h };
            let entry: SolveFn = if step { ds_step } else { ds_solve };
            // SAFETY: arrays sized for the problem, one of them NULL.
            let s = unsafe {
                entry(
                    problem,
                    null(),
                    DsFriction::Tresca as i32,
                    nul(1, F.as_ptr()),
                    nul(2, G.as_ptr()),
                    nul(3, P.as_ptr()),
                    nul_mut(4, out.u.as_mut_ptr()),
                    nul_mut(5, out.lambda_n.as_mut_ptr()),
                    nul_mut(6, out.lambda_t.as_mut_ptr()),
                    &mut out.report,
                )
            };
            expect_error(s, DsStatus::NullPointer, &[culprit]);
            out.assert_untouched(culprit);
            assert_usable(h);
        }
    }
    // ds_solve_iteration: each required pointer NULL in turn (slip and
    // lambda_t_start may be NULL).
    let names = ["problem", "r", "g", "bound", "du", "lambda_n", "lambda_t"];
    for (which, culprit) in names.iter().enumerate() {
        let mut out = Outputs::small();
        let nul = |j: usize, p: *const f64| if j == which { null() } else { p };
        let nul_mut = |j: usize, p: *mut f64| if j == which { null_mut() } else { p };
        let problem = if which == 0 { null_mut() } else { h };
        // SAFETY: arrays sized for the problem, one of them NULL.
        let s = unsafe {
            ds_solve_iteration(
                problem,
                null(),
                DsFriction::Tresca as i32,
                nul(1, F.as_ptr()),
                nul(2, G.as_ptr()),
                nul(3, P.as_ptr()),
                null(),
                null(),
                nul_mut(4, out.u.as_mut_ptr()),
                nul_mut(5, out.lambda_n.as_mut_ptr()),
                nul_mut(6, out.lambda_t.as_mut_ptr()),
                &mut out.report,
            )
        };
        expect_error(s, DsStatus::NullPointer, &[culprit]);
        out.assert_untouched(culprit);
        assert_usable(h);
    }
    free(h);
}

#[test]
fn bad_size() {
    let h = new_problem();
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut out: *mut DsProblem = null_mut();
    // Negative dimensions, caught at the boundary.
    for field in ["nrows", "ncols"] {
        let mut kd = k.ds();
        if field == "nrows" {
            kd.nrows = -4;
        } else {
            kd.ncols = -1;
        }
        // SAFETY: valid matrices apart from the tested field.
        let s = unsafe { ds_problem_new(2, &kd, &n.ds(), &t.ds(), &mut out) };
        expect_error(s, DsStatus::BadSize, &["K", field]);
        // SAFETY: h is live.
        let s = unsafe { ds_problem_refactor(h, &kd) };
        expect_error(s, DsStatus::BadSize, &["K", field]);
        assert_usable(h);
    }
    // COO with a negative nnz.
    let coo = DsMatrix {
        format: DsFormat::Coo as i32,
        nnz: -3,
        ..n.ds()
    };
    // SAFETY: rejected before any array is read.
    let s = unsafe { ds_problem_set_contacts(h, &coo, &t.ds()) };
    expect_error(s, DsStatus::BadSize, &["N", "nnz"]);
    assert_usable(h);
    // K not square.
    let k45 = Owned::dense(4, 5, &[1.0; 20]);
    // SAFETY: valid matrices.
    let s = unsafe { ds_problem_new(2, &k45.ds(), &n.ds(), &t.ds(), &mut out) };
    expect_error(s, DsStatus::BadSize, &["K"]);
    // SAFETY: valid matrix.
    let s = unsafe { ds_problem_refactor(h, &k45.ds()) };
    expect_error(s, DsStatus::BadSize, &["K"]);
    assert_usable(h);
    // N with 3 columns for 4 DOFs; T with 1 row for 2 contacts.
    let n3 = Owned::sparse(2, 3, &[0.0, -1.0, 0.0, 0.0, 0.0, -1.0]);
    let t1 = Owned::sparse(1, 4, &[1.0, 0.0, 0.0, 0.0]);
    // SAFETY: valid matrices.
    unsafe {
        expect_error(
            ds_problem_set_contacts(h, &n3.ds(), &t.ds()),
            DsStatus::BadSize,
            &["N"],
        );
        expect_error(
            ds_problem_set_contacts(h, &n.ds(), &t1.ds()),
            DsStatus::BadSize,
            &["T"],
        );
        expect_error(
            ds_problem_new(2, &k.ds(), &n3.ds(), &t.ds(), &mut out),
            DsStatus::BadSize,
            &["N"],
        );
        expect_error(
            ds_problem_new(3, &k.ds(), &n.ds(), &t.ds(), &mut out),
            DsStatus::BadSize,
            &["T"],
        );
    }
    assert!(out.is_null());
    assert_usable(h);
    // T narrower than N and K (3 columns): checked before any code indexes T by
    // N's columns (it used to panic in stack_rows: DS_STATUS_PANIC).
    let t3 = Owned::sparse(2, 3, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    // SAFETY: valid matrices.
    unsafe {
        expect_error(
            ds_problem_set_contacts(h, &n.ds(), &t3.ds()),
            DsStatus::BadSize,
            &["T"],
        );
        expect_error(
            ds_problem_set_contacts(h, &n3.ds(), &t3.ds()),
            DsStatus::BadSize,
            &["N"],
        );
        expect_error(
            ds_problem_new(2, &k.ds(), &n.ds(), &t3.ds(), &mut out),
            DsStatus::BadSize,
            &["T"],
        );
    }
    assert!(out.is_null());
    assert_usable(h);
    free(h);
}

/// The same shape mismatches through the safe Rust API: errors, not panics.
#[test]
fn bad_shapes_in_rust() {
    use dualsplit::{Format, MatrixView, Storage};
    fn view(o: &Owned) -> MatrixView<'_> {
        MatrixView {
            format: Format::Csc,
            storage: Storage::Full,
            base: 0,
            nrows: o.nrows as usize,
            ncols: o.ncols as usize,
            p: dualsplit::Indices::I64(&o.p),
            i: dualsplit::Indices::I64(&o.i),
            x: &o.x,
        }
    }
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut pb = dualsplit::ContactProblem::new(2, &view(&k), &view(&n), &view(&t)).unwrap();
    let n3 = Owned::sparse(2, 3, &[0.0, -1.0, 0.0, 0.0, 0.0, -1.0]);
    let t3 = Owned::sparse(2, 3, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let t1 = Owned::sparse(1, 4, &[1.0, 0.0, 0.0, 0.0]);
    for (nn, tt) in [(&n3, &t), (&n, &t3), (&n, &t1), (&n3, &t3)] {
        let e = pb.set_contacts(&view(nn), &view(tt)).unwrap_err();
        assert_eq!(e.kind, dualsplit::ErrorKind::BadSize, "{}", e.message);
        let e = dualsplit::ContactProblem::new(2, &view(&k), &view(nn), &view(tt))
            .err()
            .expect("a shape error");
        assert_eq!(e.kind, dualsplit::ErrorKind::BadSize, "{}", e.message);
    }
    // Still usable.
    let sol = pb
        .solve(
            &F,
            &G,
            dualsplit::Friction::Tresca(&P),
            &dualsplit::Options::default(),
        )
        .unwrap();
    assert_eq!(sol.report.status, dualsplit::SolveStatus::Converged);
}

#[test]
fn bad_index() {
    let h = new_problem();
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut out: *mut DsProblem = null_mut();
    // A row index of N beyond its 2 rows.
    let mut n_bad = n.clone();
    n_bad.i[1] = 2;
    // SAFETY: valid arrays; the index value is what is tested.
    let s = unsafe { ds_problem_set_contacts(h, &n_bad.ds(), &t.ds()) };
    expect_error(s, DsStatus::BadIndex, &["N"]);
    assert_usable(h);
    // A negative row index in T.
    let mut t_bad = t.clone();
    t_bad.i[0] = -1;
    // SAFETY: as above.
    let s = unsafe { ds_problem_set_contacts(h, &n.ds(), &t_bad.ds()) };
    expect_error(s, DsStatus::BadIndex, &["T"]);
    assert_usable(h);
    // Decreasing column pointers of K (p[last] still = nnz).
    let mut k_bad = k.clone();
    k_bad.p[2] = 1;
    // SAFETY: as above.
    let s = unsafe { ds_problem_refactor(h, &k_bad.ds()) };
    expect_error(s, DsStatus::BadIndex, &["K"]);
    // SAFETY: as above.
    let s = unsafe { ds_problem_new(2, &k_bad.ds(), &n.ds(), &t.ds(), &mut out) };
    expect_error(s, DsStatus::BadIndex, &["K"]);
    assert_usable(h);
    // Last pointer below the base: p[ncols] - base < 0, caught at the boundary.
    let mut k_neg = k.clone();
    k_neg.p[4] = -2;
    // SAFETY: rejected before i and x are read.
    let s = unsafe { ds_problem_refactor(h, &k_neg.ds()) };
    expect_error(s, DsStatus::BadIndex, &["K"]);
    assert_usable(h);
    // K declared UPPER but holding entries below the diagonal.
    let upper = DsMatrix {
        storage: DsStorage::Upper as i32,
        ..k.ds()
    };
    // SAFETY: valid arrays.
    let s = unsafe { ds_problem_new(2, &upper, &n.ds(), &t.ds(), &mut out) };
    expect_error(s, DsStatus::BadIndex, &["K"]);
    assert!(out.is_null());
    assert_usable(h);
    free(h);
}

#[test]
fn not_finite() {
    let h = new_problem();
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut out: *mut DsProblem = null_mut();
    // In K, at creation and at refactorisation (same pattern).
    let mut k_nan = k.clone();
    k_nan.x[5] = f64::NAN;
    // SAFETY: valid arrays.
    unsafe {
        expect_error(
            ds_problem_new(2, &k_nan.ds(), &n.ds(), &t.ds(), &mut out),
            DsStatus::NotFinite,
            &["K"],
        );
        expect_error(
            ds_problem_refactor(h, &k_nan.ds()),
            DsStatus::NotFinite,
            &["K"],
        );
    }
    assert!(out.is_null());
    let before = assert_usable(h);
    // In N.
    let mut n_inf = n.clone();
    n_inf.x[0] = f64::INFINITY;
    // SAFETY: valid arrays.
    let s = unsafe { ds_problem_set_contacts(h, &n_inf.ds(), &t.ds()) };
    expect_error(s, DsStatus::NotFinite, &["N"]);
    let after = assert_usable(h);
    assert_eq!(before.u, after.u, "a failed call changed the handle");
    // In f, g and p.
    let mut out = Outputs::small();
    let mut f = F;
    f[2] = f64::NAN;
    expect_error(
        solve_small(h, &f, &G, &P, &mut out),
        DsStatus::NotFinite,
        &["f"],
    );
    out.assert_untouched("NaN in f");
    let mut g = G;
    g[1] = f64::NEG_INFINITY;
    expect_error(
        solve_small(h, &F, &g, &P, &mut out),
        DsStatus::NotFinite,
        &["g"],
    );
    out.assert_untouched("-inf in g");
    let mut p = P;
    p[0] = f64::NAN;
    expect_error(
        solve_small(h, &F, &G, &p, &mut out),
        DsStatus::NotFinite,
        &["p"],
    );
    out.assert_untouched("NaN in p");
    // ds_step names its own arguments.
    // SAFETY: arrays sized for the problem.
    let s = unsafe {
        ds_step(
            h,
            null(),
            DsFriction::Tresca as i32,
            f.as_ptr(),
            G.as_ptr(),
            P.as_ptr(),
            out.u.as_mut_ptr(),
            out.lambda_n.as_mut_ptr(),
            out.lambda_t.as_mut_ptr(),
            &mut out.report,
        )
    };
    expect_error(s, DsStatus::NotFinite, &["f_total"]);
    out.assert_untouched("NaN in f_total");
    let after = assert_usable(h);
    assert_eq!(before.u, after.u);
    free(h);
}

#[test]
fn not_symmetric() {
    let h = new_problem();
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut out: *mut DsProblem = null_mut();
    // K(0,1) = 1 but K(1,0) = 1.5 (column 0 holds row 1 at position 1).
    let mut k_bad = k.clone();
    k_bad.x[1] = 1.5;
    // SAFETY: valid arrays.
    unsafe {
        expect_error(
            ds_problem_new(2, &k_bad.ds(), &n.ds(), &t.ds(), &mut out),
            DsStatus::NotSymmetric,
            &["K"],
        );
        expect_error(
            ds_problem_refactor(h, &k_bad.ds()),
            DsStatus::NotSymmetric,
            &["K"],
        );
    }
    assert!(out.is_null());
    assert_usable(h);
    free(h);
}

#[test]
fn not_positive_definite() {
    let h = new_problem();
    let before = assert_usable(h);
    let (n, t) = (n_good(), t_good());
    let mut out: *mut DsProblem = null_mut();
    // Indefinite: I + 2 (ones - I), eigenvalues 7 and -1 (three times).
    // Singular: ones(4), rank 1; every Cholesky order meets an exact 0 pivot.
    for (what, k_bad) in [
        ("indefinite", Owned::dense(4, 4, &k_values(1.0, 2.0))),
        ("singular", Owned::dense(4, 4, &k_values(1.0, 1.0))),
        (
            "negative definite",
            Owned::dense(4, 4, &k_values(-4.0, -1.0)),
        ),
    ] {
        // SAFETY: valid arrays.
        unsafe {
            let s = ds_problem_new(2, &k_bad.ds(), &n.ds(), &t.ds(), &mut out);
            expect_error(s, DsStatus::NotPositiveDefinite, &["K"]);
            assert!(out.is_null(), "{what}");
            let s = ds_problem_refactor(h, &k_bad.ds());
            expect_error(s, DsStatus::NotPositiveDefinite, &["K"]);
        }
        // The old factor is kept: the same answer, bit for bit.
        let after = assert_usable(h);
        assert_eq!(
            before.u, after.u,
            "{what}: refactor failure changed the handle"
        );
        assert_eq!(before.lambda_n, after.lambda_n);
        assert_eq!(before.lambda_t, after.lambda_t);
    }
    // A successful refactorisation with the same pattern still works afterwards.
    let k2 = Owned::dense(4, 4, &k_values(8.0, 2.0));
    // SAFETY: valid arrays.
    expect_ok(unsafe { ds_problem_refactor(h, &k2.ds()) });
    // SAFETY: valid arrays.
    expect_ok(unsafe { ds_problem_refactor(h, &k_good().ds()) });
    assert_usable(h);
    free(h);
}

#[test]
fn negative_friction() {
    let h = new_problem();
    let mut out = Outputs::small();
    let p = [0.1, -0.5];
    expect_error(
        solve_small(h, &F, &G, &p, &mut out),
        DsStatus::NegativeFriction,
        &["p"],
    );
    out.assert_untouched("negative p");
    let mu = [-0.3, 0.3];
    let s = solve_raw(
        h,
        null(),
        DsFriction::Coulomb as i32,
        F.as_ptr(),
        G.as_ptr(),
        mu.as_ptr(),
        &mut out,
    );
    expect_error(s, DsStatus::NegativeFriction, &["mu"]);
    out.assert_untouched("negative mu");
    // Coulomb with valid mu works on the same handle.
    let s = solve_raw(
        h,
        null(),
        DsFriction::Coulomb as i32,
        F.as_ptr(),
        G.as_ptr(),
        MU.as_ptr(),
        &mut out,
    );
    expect_ok(s);
    for ((lt, ln), mu) in out.lambda_t.iter().zip(&out.lambda_n).zip(MU) {
        assert!(lt.abs() <= mu * ln * (1.0 + 1e-8) + 1e-14);
    }
    assert_usable(h);
    free(h);
}

#[test]
fn bad_argument() {
    let h = new_problem();
    let (k, n, t) = (k_good(), n_good(), t_good());
    let (kd, nd, td) = (k.ds(), n.ds(), t.ds());
    let mut out: *mut DsProblem = null_mut();
    // d not 2 or 3.
    for d in [4, 1, 0, -2] {
        // SAFETY: valid matrices.
        let s = unsafe { ds_problem_new(d, &kd, &nd, &td, &mut out) };
        expect_error(s, DsStatus::BadArgument, &["d"]);
    }
    // Enum fields of a matrix, and the base.
    for (field, edit) in [
        (
            "format",
            (|m: &mut DsMatrix| m.format = 9) as fn(&mut DsMatrix),
        ),
        ("format", |m| m.format = -1),
        ("index_type", |m| m.index_type = 2),
        ("storage", |m| m.storage = 3),
        ("base", |m| m.base = 2),
    ] {
        let mut k2 = kd;
        edit(&mut k2);
        // SAFETY: rejected before any array is read.
        let s = unsafe { ds_problem_new(2, &k2, &nd, &td, &mut out) };
        expect_error(s, DsStatus::BadArgument, &["K", field]);
        // SAFETY: as above.
        let s = unsafe { ds_problem_refactor(h, &k2) };
        expect_error(s, DsStatus::BadArgument, &["K", field]);
        let mut n2 = nd;
        edit(&mut n2);
        // SAFETY: as above.
        let s = unsafe { ds_problem_set_contacts(h, &n2, &td) };
        expect_error(s, DsStatus::BadArgument, &["N", field]);
        assert_usable(h);
    }
    // Triangle storage for N.
    let n_upper = DsMatrix {
        storage: DsStorage::Upper as i32,
        ..nd
    };
    // SAFETY: valid arrays.
    let s = unsafe { ds_problem_set_contacts(h, &n_upper, &td) };
    expect_error(s, DsStatus::BadArgument, &["N"]);
    // A K whose pattern differs from the factored one.
    let k_diag = Owned::sparse(4, 4, &k_values(4.0, 0.0));
    // SAFETY: valid arrays.
    let s = unsafe { ds_problem_refactor(h, &k_diag.ds()) };
    expect_error(s, DsStatus::BadArgument, &["K", "pattern"]);
    assert_usable(h);
    assert!(out.is_null());
    // Friction enum.
    let mut o = Outputs::small();
    for friction in [2, -1, 1000] {
        let s = solve_raw(
            h,
            null(),
            friction,
            F.as_ptr(),
            G.as_ptr(),
            P.as_ptr(),
            &mut o,
        );
        expect_error(s, DsStatus::BadArgument, &["friction"]);
        o.assert_untouched("bad friction");
    }
    // Options: struct_size, method, tol, iteration limits.
    let good = options();
    for (field, opts) in [
        (
            "struct_size",
            DsOptions {
                struct_size: good.struct_size - 4,
                ..good
            },
        ),
        (
            "struct_size",
            DsOptions {
                struct_size: 0,
                ..good
            },
        ),
        ("method", DsOptions { method: 7, ..good }),
        ("method", DsOptions { method: -1, ..good }),
        ("tol", DsOptions { tol: -1e-8, ..good }),
        (
            "tol",
            DsOptions {
                tol: f64::NAN,
                ..good
            },
        ),
        ("tol", DsOptions { tol: 0.0, ..good }),
        (
            "max_outer",
            DsOptions {
                max_outer: -1,
                ..good
            },
        ),
        (
            "max_inner",
            DsOptions {
                max_inner: 0,
                ..good
            },
        ),
        (
            "dual_form",
            DsOptions {
                dual_form: 3,
                ..good
            },
        ),
        (
            // Matrix-free products with a method that reads entries of A.
            "mprgp",
            DsOptions {
                dual_form: 2,
                method: 0,
                ..good
            },
        ),
    ] {
        let s = solve_raw(
            h,
            &opts,
            DsFriction::Tresca as i32,
            F.as_ptr(),
            G.as_ptr(),
            P.as_ptr(),
            &mut o,
        );
        expect_error(s, DsStatus::BadArgument, &[field]);
        o.assert_untouched(field);
        assert_usable(h);
    }
    // Every method with valid options works on the same handle.
    for method in [
        DsMethod::Split,
        DsMethod::BlockGs,
        DsMethod::Pgs,
        DsMethod::Newton,
        DsMethod::SplitMprgp,
        DsMethod::Mprgp,
    ] {
        let opts = DsOptions {
            method: method as i32,
            ..good
        };
        let mut o = Outputs::small();
        let s = solve_raw(
            h,
            &opts,
            DsFriction::Tresca as i32,
            F.as_ptr(),
            G.as_ptr(),
            P.as_ptr(),
            &mut o,
        );
        expect_ok(s);
        assert_eq!(o.report.method, method as i32);
    }
    free(h);
}

#[test]
fn out_of_memory() {
    let h = new_problem();
    let (n, t) = (n_good(), t_good());
    let mut out: *mut DsProblem = null_mut();
    // An empty K with absurd dimensions: its column pointers cannot be allocated.
    let huge = DsMatrix {
        format: DsFormat::Coo as i32,
        index_type: DsIndexType::I64 as i32,
        base: 0,
        storage: DsStorage::Full as i32,
        nrows: i64::MAX / 2,
        ncols: i64::MAX / 2,
        nnz: 0,
        p: null(),
        i: null(),
        x: null(),
    };
    // SAFETY: nnz = 0, so no array is read.
    let s = unsafe { ds_problem_new(2, &huge, &n.ds(), &t.ds(), &mut out) };
    expect_error(s, DsStatus::OutOfMemory, &[]);
    assert!(out.is_null());
    // SAFETY: as above.
    let s = unsafe { ds_problem_refactor(h, &huge) };
    // Converting the caller's K comes first: its arrays cannot be allocated.
    expect_error(s, DsStatus::OutOfMemory, &["allocate"]);
    assert_usable(h);
    free(h);
}

// ---------------------------------------------------------------------------------
// DS_STATUS_NOT_CONVERGED on a problem with several closed contacts.

/// A 2D chain of 6 nodes on the foundation (see tests/ffi_formats.rs): inclined
/// ground springs and bars couple x and y; every node is a contact.
fn chain() -> (Owned, Owned, Owned, Vec<f64>, Vec<f64>, Vec<f64>) {
    let nodes = 6;
    let ndof = 2 * nodes;
    let mut k = vec![0.0; ndof * ndof];
    let mut add = |dofs: &[usize], c: &[f64], stiffness: f64, sign: &[f64]| {
        for (a, &ra) in dofs.iter().enumerate() {
            for (b, &rb) in dofs.iter().enumerate() {
                k[ra * ndof + rb] += stiffness * ((sign[a] * c[a]) * (sign[b] * c[b]));
            }
        }
    };
    for j in 0..nodes {
        let (x, y) = (2 * j, 2 * j + 1);
        add(&[x, y], &[1.0, 0.0], 1.0 + 0.1 * j as f64, &[1.0, 1.0]);
        add(&[x, y], &[0.0, 1.0], 2.0, &[1.0, 1.0]);
        add(&[x, y], &[0.6, 0.8], 1.5, &[1.0, 1.0]);
        if j + 1 < nodes {
            let (x2, y2) = (x + 2, y + 2);
            add(&[x, x2], &[1.0, 1.0], 4.0, &[1.0, -1.0]);
            add(
                &[x, y, x2, y2],
                &[0.6, 0.8, 0.6, 0.8],
                3.0,
                &[1.0, 1.0, -1.0, -1.0],
            );
            add(&[y, y2], &[1.0, 1.0], 2.5, &[1.0, -1.0]);
        }
    }
    let k = Owned::sparse(ndof, ndof, &k);
    let mut nm = vec![0.0; nodes * ndof];
    let mut tm = vec![0.0; nodes * ndof];
    for j in 0..nodes {
        nm[j * ndof + 2 * j + 1] = -1.0;
        tm[j * ndof + 2 * j] = 1.0;
    }
    let f: Vec<f64> = (0..nodes)
        .flat_map(|j| [[0.6, 0.1, -0.3, 0.9, 0.0, 0.2][j], -2.0])
        .collect();
    let g = vec![0.0, 0.01, 0.0, 0.02, 3.0, 0.0];
    let p = vec![0.2, 1.0, 1.0, 0.3, 1.0, 0.5];
    (
        k,
        Owned::sparse(nodes, ndof, &nm),
        Owned::sparse(nodes, ndof, &tm),
        f,
        g,
        p,
    )
}

#[test]
fn not_converged() {
    let (k, n, t, f, g, p) = chain();
    let (ndof, m) = (f.len(), g.len());
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: valid matrices; h is a valid location.
    expect_ok(unsafe { ds_problem_new(2, &k.ds(), &n.ds(), &t.ds(), &mut h) });
    let run = |entry: SolveFn, opts: &DsOptions, out: &mut Outputs| {
        // SAFETY: arrays sized for the chain problem.
        unsafe {
            entry(
                h,
                opts,
                DsFriction::Tresca as i32,
                f.as_ptr(),
                g.as_ptr(),
                p.as_ptr(),
                out.u.as_mut_ptr(),
                out.lambda_n.as_mut_ptr(),
                out.lambda_t.as_mut_ptr(),
                &mut out.report,
            )
        }
    };
    let good = options();
    // The converged answer first, to know the contacts are closed.
    let mut reference = Outputs::new(ndof, m, 2);
    expect_ok(run(ds_solve, &good, &mut reference));
    let closed = reference.lambda_n.iter().filter(|&&l| l > 0.0).count();
    assert!(closed >= 4, "only {closed} contacts closed");
    for method in [
        DsMethod::Split,
        DsMethod::BlockGs,
        DsMethod::Pgs,
        DsMethod::Newton,
    ] {
        // One outer iteration cannot reach 1e-30 (Newton's Gauss-Seidel warm-up and
        // one step reach 1e-16 here, which 1e-15 would have called converged).
        let tight = DsOptions {
            method: method as i32,
            tol: 1e-30,
            max_outer: 1,
            ..good
        };
        let entries: [(&str, SolveFn); 2] = [("ds_solve", ds_solve), ("ds_step", ds_step)];
        for (name, entry) in entries {
            let mut out = Outputs::new(ndof, m, 2);
            let s = run(entry, &tight, &mut out);
            expect_error(s, DsStatus::NotConverged, &[name]);
            assert!(last_message().contains("converge"), "{}", last_message());
            // Only the report is written.
            let all = out.u.iter().chain(&out.lambda_n).chain(&out.lambda_t);
            assert!(
                all.into_iter().all(|&v| v == SENTINEL),
                "{name}: outputs written"
            );
            assert_eq!(out.report.status, DsStatus::NotConverged as i32);
            assert_eq!(out.report.method, method as i32);
            // The method used its one outer iteration (it did not end at 0).
            assert_eq!(out.report.outer_iterations, 1, "{name}");
            assert!(out.report.err > tight.tol);
        }
    }
    // The failed ds_step calls did not advance the history: the next step from the
    // same handle equals the first step of a fresh handle, and the same handle still
    // solves.
    let mut stepped = Outputs::new(ndof, m, 2);
    expect_ok(run(ds_step, &good, &mut stepped));
    let mut fresh: *mut DsProblem = null_mut();
    // SAFETY: valid matrices.
    expect_ok(unsafe { ds_problem_new(2, &k.ds(), &n.ds(), &t.ds(), &mut fresh) });
    let mut first = Outputs::new(ndof, m, 2);
    // SAFETY: arrays sized for the chain problem.
    let s = unsafe {
        ds_step(
            fresh,
            &good,
            DsFriction::Tresca as i32,
            f.as_ptr(),
            g.as_ptr(),
            p.as_ptr(),
            first.u.as_mut_ptr(),
            first.lambda_n.as_mut_ptr(),
            first.lambda_t.as_mut_ptr(),
            &mut first.report,
        )
    };
    expect_ok(s);
    assert_eq!(
        stepped.u, first.u,
        "a non-converged ds_step advanced the history"
    );
    let mut again = Outputs::new(ndof, m, 2);
    expect_ok(run(ds_solve, &good, &mut again));
    assert_eq!(again.u, reference.u);
    free(fresh);
    free(h);
}

#[test]
fn status_strings_and_messages() {
    for v in 0..=17 {
        let p = ds_status_string(v);
        assert!(!p.is_null());
        // SAFETY: static NUL-terminated string.
        let s = unsafe { CStr::from_ptr(p) }.to_str().unwrap();
        assert!(!s.is_empty() && s != "unknown status", "{v}");
    }
    // SAFETY: static NUL-terminated string.
    let s = unsafe { CStr::from_ptr(ds_status_string(18)) };
    assert_eq!(s.to_str().unwrap(), "unknown status");
    // The message is per thread, and cleared by the next successful call.
    let h = new_problem();
    // SAFETY: NULL is what is tested.
    let s = unsafe { ds_history_reset(null_mut()) };
    expect_error(s, DsStatus::NullPointer, &["ds_history_reset", "problem"]);
    std::thread::spawn(|| assert_eq!(last_message(), ""))
        .join()
        .unwrap();
    assert!(!last_message().is_empty());
    // SAFETY: h is live.
    expect_ok(unsafe { ds_history_reset(h) });
    free(h);
}

#[test]
fn io_error_from_a_dump_into_a_folder_that_cannot_exist() {
    let h = new_problem();
    // A regular file where the dump's folder should go.
    let base = std::env::temp_dir().join(format!("dualsplit-io-{}", std::process::id()));
    std::fs::write(&base, b"a file, not a folder").unwrap();
    let dir = std::ffi::CString::new(base.join("sub").to_str().unwrap()).unwrap();
    // SAFETY: h is live; dir is NUL-terminated; the arrays have the problem's sizes.
    let s = unsafe {
        ds_problem_dump(
            h,
            dir.as_ptr(),
            DsFriction::Tresca as i32,
            F.as_ptr(),
            G.as_ptr(),
            P.as_ptr(),
        )
    };
    expect_error(s, DsStatus::IoError, &["sub"]);
    assert_usable(h);
    std::fs::remove_file(&base).ok();
    free(h);
}

#[test]
fn set_compliance_checks_its_arrays_and_keeps_the_law_on_error() {
    let h = new_problem();
    let cn = [50.0, f64::INFINITY];
    type Case = ([f64; M], [f64; M], [f64; M], DsStatus, &'static str);
    let bad_cases: [Case; 5] = [
        ([0.0, 1.0], [1.0; M], [1.0; M], DsStatus::BadArgument, "c_N"),
        (
            [f64::NAN, 1.0],
            [1.0; M],
            [1.0; M],
            DsStatus::NotFinite,
            "c_N",
        ),
        ([1.0; M], [0.5, 1.0], [1.0; M], DsStatus::BadArgument, "m_N"),
        (
            [1.0; M],
            [11.0, 1.0],
            [1.0; M],
            DsStatus::BadArgument,
            "m_N",
        ),
        (
            [1.0; M],
            [1.0; M],
            [1.0, -2.0],
            DsStatus::BadArgument,
            "k_T",
        ),
    ];
    // SAFETY: NULL handle; the arrays hold m values.
    let s = unsafe { ds_problem_set_compliance(null_mut(), cn.as_ptr(), null(), null()) };
    expect_error(s, DsStatus::NullPointer, &["problem"]);
    for (c, e, k, status, name) in &bad_cases {
        // SAFETY: a live handle; each array holds m values.
        let s = unsafe { ds_problem_set_compliance(h, c.as_ptr(), e.as_ptr(), k.as_ptr()) };
        expect_error(s, *status, &[name]);
        // Still rigid: the Signorini answer.
        assert_usable(h);
    }
    // Contact 0 compliant, 1 rigid: lambda_N,0 = c_N (N u - g)_0+ with N u = -u_1.
    // SAFETY: a live handle; c_n holds m values, the others are NULL.
    expect_ok(unsafe { ds_problem_set_compliance(h, cn.as_ptr(), null(), null()) });
    let mut soft = Outputs::small();
    expect_ok(solve_small(h, &F, &G, &P, &mut soft));
    assert!(soft.report.err <= 1e-10, "err = {}", soft.report.err);
    let pen = -soft.u[1] - G[0];
    assert!(pen > 0.0, "the compliant contact penetrates");
    let want = cn[0] * pen;
    assert!(
        (soft.lambda_n[0] - want).abs() <= 1e-9 * want,
        "lambda_N = {} against c_N (N u - g)+ = {want}",
        soft.lambda_n[0]
    );
    assert!(
        -soft.u[3] <= G[1] + 1e-12,
        "the rigid contact does not penetrate"
    );
    for (c, e, k, status, name) in &bad_cases {
        // SAFETY: as above.
        let s = unsafe { ds_problem_set_compliance(h, c.as_ptr(), e.as_ptr(), k.as_ptr()) };
        expect_error(s, *status, &[name]);
        let mut again = Outputs::small();
        expect_ok(solve_small(h, &F, &G, &P, &mut again));
        assert_eq!(
            again.lambda_n, soft.lambda_n,
            "the law changed after an error"
        );
    }
    assert_eq!(compliant_counts(h), (1, 0), "c_N on contact 0, m_N = 1");
    let mn = [2.0, 1.0];
    // SAFETY: a live handle; c_n and m_n hold m values, k_t is NULL.
    expect_ok(unsafe { ds_problem_set_compliance(h, cn.as_ptr(), mn.as_ptr(), null()) });
    assert_eq!(compliant_counts(h), (1, 1), "a power law on contact 0");
    let kt = [f64::INFINITY, 30.0];
    // SAFETY: a live handle; k_t holds m values.
    expect_ok(unsafe { ds_problem_set_compliance(h, null(), null(), kt.as_ptr()) });
    assert_eq!(compliant_counts(h), (1, 0), "k_T alone on contact 1");
    // All NULL: rigid again.
    // SAFETY: a live handle; NULL arrays mean the defaults.
    expect_ok(unsafe { ds_problem_set_compliance(h, null(), null(), null()) });
    assert_eq!(compliant_counts(h), (0, 0), "every contact rigid");
    assert_usable(h);
    free(h);
}

/// DsInfo.compliant_contacts and power_law_contacts of a live handle; a DsInfo
/// of version 0.5 (120 bytes) gets nothing past its end.
fn compliant_counts(h: *mut DsProblem) -> (i64, i64) {
    // SAFETY: DsInfo is plain old data; zero is a value.
    let mut info: DsInfo = unsafe { std::mem::zeroed() };
    info.struct_size = std::mem::size_of::<DsInfo>() as u32;
    // SAFETY: a live handle, default options, a whole DsInfo.
    expect_ok(unsafe { ds_problem_info(h, null(), &mut info) });
    let mut old: DsInfo = unsafe { std::mem::zeroed() };
    old.struct_size = 120;
    old.compliant_contacts = -7;
    old.power_law_contacts = -7;
    // SAFETY: as above; the library writes at most 120 bytes.
    expect_ok(unsafe { ds_problem_info(h, null(), &mut old) });
    assert_eq!(old.m, info.m);
    assert_eq!((old.compliant_contacts, old.power_law_contacts), (-7, -7));
    (info.compliant_contacts, info.power_law_contacts)
}

/// K^-1 x for the small problem, in either precision: K = 3 I + ones(4), so
/// K^-1 x = (x - sum(x) / 7) / 3 (Sherman-Morrison); the context, an i64,
/// counts the columns.
///
/// # Safety
/// As a DsHostSolveFn: x holds ld x ncols values; the context is the test's
/// i64 counter, alive and not otherwise borrowed during the call.
unsafe fn small_k_apply<T>(context: *mut std::ffi::c_void, n: i64, ncols: i64, x: *mut T, ld: i64)
where
    T: Copy + From<f32> + std::iter::Sum + std::ops::Sub<Output = T> + std::ops::Div<Output = T>,
{
    // SAFETY: the context is the i64 counter (this function's contract).
    let count = unsafe { &mut *context.cast::<i64>() };
    *count += ncols;
    for j in 0..ncols {
        // SAFETY: x holds ld x ncols values (this function's contract).
        let col = unsafe { std::slice::from_raw_parts_mut(x.add((j * ld) as usize), n as usize) };
        let s: T = col.iter().copied().sum();
        col.iter_mut()
            .for_each(|v| *v = (*v - s / T::from(7.0)) / T::from(3.0));
    }
}

/// The host's solve for the small problem (see `small_k_apply`).
unsafe extern "C" fn small_k_solve(
    context: *mut std::ffi::c_void,
    n: i64,
    ncols: i64,
    x: *mut f64,
    ld: i64,
) -> i32 {
    // SAFETY: the callback's contract is small_k_apply's.
    unsafe { small_k_apply(context, n, ncols, x, ld) };
    0
}

/// A DsHostSolver of the current size for the small problem: small_k_solve
/// with `context` (its column counter), no optional callback, the blocks by
/// solves.
fn small_host_solver(context: *mut std::ffi::c_void) -> DsHostSolver {
    DsHostSolver {
        struct_size: std::mem::size_of::<DsHostSolver>() as u32,
        n: N_DOFS as i64,
        solve: Some(small_k_solve),
        context,
        inverse_entries: None,
        solve_single: None,
        solve_rows: None,
        blocks: 0,
    }
}

/// Calls of small_k_solve_single (only the test below uses it).
static SINGLE_CALLS: std::sync::atomic::AtomicI64 = std::sync::atomic::AtomicI64::new(0);

/// small_k_solve in single precision; SINGLE_CALLS counts its calls.
unsafe extern "C" fn small_k_solve_single(
    context: *mut std::ffi::c_void,
    n: i64,
    ncols: i64,
    x: *mut f32,
    ld: i64,
) -> i32 {
    SINGLE_CALLS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    // SAFETY: the callback's contract is small_k_apply's.
    unsafe { small_k_apply(context, n, ncols, x, ld) };
    0
}

/// ds_problem_new_host with the single-precision solve: the handle solves
/// the small problem (assert_usable's checks) and its loose products call
/// it; a DsHostSolver of version 0.9 (40 bytes, no solve_single) is
/// accepted and reads nothing past its end (the field there holds a
/// pointer that would crash if called); any other struct_size is refused.
#[test]
fn the_hosts_single_precision_solve_through_the_c_abi() {
    let mut columns: i64 = 0;
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut solver = DsHostSolver {
        solve_single: Some(small_k_solve_single),
        ..small_host_solver((&raw mut columns).cast())
    };
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: the solver and the matrices live until the call returns, the
    // counter until the handle is freed.
    let s = unsafe { ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut h) };
    expect_ok(s);
    let mut cost = DsCost {
        struct_size: std::mem::size_of::<DsCost>() as u32,
        ..DsCost::default()
    };
    let out = assert_usable(h);
    // SAFETY: a live handle, a whole DsCost.
    expect_ok(unsafe { ds_problem_last_cost(h, &mut cost) });
    let singles = SINGLE_CALLS.load(std::sync::atomic::Ordering::SeqCst);
    assert!(singles > 0, "the loose products in single precision");
    assert!(cost.host_solves > singles, "and the exact ones in double");
    free(h);
    // Version 0.9: 40 bytes; solve_single past them is never read.
    solver.struct_size = 40;
    // SAFETY: a non-NULL function pointer that must never be called: the
    // library reads no byte past struct_size.
    solver.solve_single = Some(unsafe {
        std::mem::transmute::<
            usize,
            unsafe extern "C" fn(*mut std::ffi::c_void, i64, i64, *mut f32, i64) -> i32,
        >(8)
    });
    let mut old: *mut DsProblem = null_mut();
    // SAFETY: as above.
    let s = unsafe { ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut old) };
    expect_ok(s);
    let again = assert_usable(old);
    assert_eq!(
        SINGLE_CALLS.load(std::sync::atomic::Ordering::SeqCst),
        singles
    );
    for (a, b) in again.lambda_n.iter().zip(&out.lambda_n) {
        assert!((a - b).abs() <= 1e-10 * b.abs(), "{a} against {b}");
    }
    free(old);
    for bad in [0u32, 8, 44, 48, 56, 72] {
        solver.struct_size = bad;
        let mut none: *mut DsProblem = null_mut();
        // SAFETY: as above; refused before any callback is read.
        let s = unsafe {
            ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut none)
        };
        expect_error(s, DsStatus::BadArgument, &["struct_size"]);
        assert!(none.is_null());
    }
}

/// The rows and columns the small problem's solves on rows were asked for
/// (only the test below uses it): calls, right-hand sides, and the fewest rows.
static ROWS_SEEN: std::sync::Mutex<(i64, i64, i64)> = std::sync::Mutex::new((0, 0, i64::MAX));

/// The small problem's solve on rows, the way any host may answer it: the
/// entries scattered into a whole vector, small_k_apply, the rows gathered.
/// It checks its side of the contract: rows ascending, distinct, within n,
/// ld = nrows.
unsafe extern "C" fn small_k_solve_rows(
    context: *mut std::ffi::c_void,
    nrows: i64,
    rows: *const i64,
    ncols: i64,
    x: *mut f64,
    ld: i64,
    approximate: i32,
) -> i32 {
    // SAFETY: rows holds nrows DOFs (the callback's contract).
    let rows = unsafe { std::slice::from_raw_parts(rows, nrows as usize) };
    assert!(
        rows.windows(2).all(|w| w[0] < w[1])
            && rows.iter().all(|&r| (0..N_DOFS as i64).contains(&r))
    );
    assert!(ld == nrows && (approximate == 0 || approximate == 1));
    {
        let mut seen = ROWS_SEEN.lock().unwrap();
        seen.0 += 1;
        seen.1 += ncols;
        seen.2 = seen.2.min(nrows);
    }
    let mut z = vec![0.0; N_DOFS];
    for j in 0..ncols as usize {
        // SAFETY: x holds ld x ncols doubles (the callback's contract).
        let col = unsafe { std::slice::from_raw_parts_mut(x.add(j * ld as usize), nrows as usize) };
        z.iter_mut().for_each(|v| *v = 0.0);
        rows.iter()
            .zip(col.iter())
            .for_each(|(&r, &v)| z[r as usize] = v);
        // SAFETY: z is one column of n doubles; the context is the counter.
        unsafe { small_k_apply(context, N_DOFS as i64, 1, z.as_mut_ptr(), N_DOFS as i64) };
        rows.iter()
            .zip(col.iter_mut())
            .for_each(|(&r, v)| *v = z[r as usize]);
    }
    0
}

/// ds_problem_new_host with the solve on rows: the handle solves the small
/// problem (assert_usable's checks) with every product a call on rows, and
/// agrees with the handle on whole solves; DsCost counts the right-hand
/// sides of both kinds of call.
#[test]
fn the_hosts_solve_on_rows_through_the_c_abi() {
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut whole_columns: i64 = 0;
    let mut solver = small_host_solver((&raw mut whole_columns).cast());
    let mut plain: *mut DsProblem = null_mut();
    // SAFETY: the solver and the matrices live until the call returns, the
    // counter until the handle is freed.
    let s =
        unsafe { ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut plain) };
    expect_ok(s);
    let want = assert_usable(plain);
    free(plain);
    let mut columns: i64 = 0;
    solver.context = (&raw mut columns).cast();
    solver.solve_rows = Some(small_k_solve_rows);
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: as above.
    let s = unsafe { ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut h) };
    expect_ok(s);
    let at_creation = columns;
    let out = assert_usable(h);
    let mut cost = DsCost {
        struct_size: std::mem::size_of::<DsCost>() as u32,
        ..DsCost::default()
    };
    // SAFETY: a live handle, a whole DsCost.
    expect_ok(unsafe { ds_problem_last_cost(h, &mut cost) });
    let (calls, rows_columns, fewest) = *ROWS_SEEN.lock().unwrap();
    assert!(calls > 0, "the products on rows");
    assert!(
        fewest <= 2 * M as i64,
        "the rows are the contact DOFs: {fewest}"
    );
    // Every column the host solved, of either kind, went through small_k_apply.
    assert_eq!(cost.host_solves, columns - at_creation);
    assert!(rows_columns < cost.host_solves, "and the loads whole");
    for (a, b) in out.lambda_n.iter().zip(&want.lambda_n) {
        assert!((a - b).abs() <= 1e-10 * b.abs(), "{a} against {b}");
    }
    free(h);
}

/// DsHostSolver.blocks through the C ABI: DS_HOST_BLOCKS_FACTOR with K
/// handed over forms the contact blocks without a call of the host (and the
/// handle solves the small problem, assert_usable's checks); without K it
/// is refused, and so is a value that is no DsHostBlocks, naming the field.
#[test]
fn the_contact_blocks_by_the_librarys_factor_through_the_c_abi() {
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut columns: i64 = 0;
    let mut solver = DsHostSolver {
        blocks: DsHostBlocks::Factor as i32,
        ..small_host_solver((&raw mut columns).cast())
    };
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: the solver and the matrices live until the call returns, the
    // counter until the handle is freed.
    let s = unsafe { ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut h) };
    expect_ok(s);
    assert_eq!(columns, 0, "no host solve at creation");
    assert_usable(h);
    assert!(columns > 0, "the products call the host");
    free(h);
    let mut none: *mut DsProblem = null_mut();
    // SAFETY: as above, K NULL (none handed over).
    let s = unsafe { ds_problem_new_host(2, &solver, null(), &n.ds(), &t.ds(), null(), &mut none) };
    expect_error(s, DsStatus::BadArgument, &["need K handed over"]);
    assert!(none.is_null());
    solver.blocks = 7;
    // SAFETY: as above.
    let s =
        unsafe { ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut none) };
    expect_error(
        s,
        DsStatus::BadArgument,
        &["solver->blocks = 7", "DS_HOST_BLOCKS_AUTO"],
    );
    assert!(none.is_null());
}

/// ds_problem_last_cost: zero (solved = 0) before any solve; after one, the
/// report's solve_seconds split into its phases, no host solves on the own
/// factor; on the host's solves the columns its callback counted and
/// library_seconds = solve_seconds - host_seconds; an older struct gets its
/// prefix only; NULL and an unset struct_size are refused; a solve refused
/// for a bad argument leaves the last cost as it was.
#[test]
fn last_cost_splits_the_solve_and_counts_the_hosts_solves() {
    let sentinel = DsCost {
        struct_size: std::mem::size_of::<DsCost>() as u32,
        solved: -7,
        solve_seconds: SENTINEL,
        rhs_seconds: SENTINEL,
        iterate_seconds: SENTINEL,
        recover_seconds: SENTINEL,
        host_solves: -7,
        host_seconds: SENTINEL,
        library_seconds: SENTINEL,
    };
    let cost_of = |h: *mut DsProblem| {
        let mut c = sentinel;
        // SAFETY: a live handle and a whole, writable DsCost.
        expect_ok(unsafe { ds_problem_last_cost(h, &mut c) });
        c
    };
    let h = new_problem();
    let before = cost_of(h);
    assert_eq!(before.solved, 0);
    assert_eq!((before.solve_seconds, before.host_solves), (0.0, 0));
    let out = assert_usable(h);
    let own = cost_of(h);
    assert_eq!(own.solved, 1);
    assert_eq!(own.solve_seconds, out.report.solve_seconds);
    let phases = own.rhs_seconds + own.iterate_seconds + own.recover_seconds;
    assert!(phases > 0.0 && phases <= own.solve_seconds, "{own:?}");
    assert_eq!((own.host_solves, own.host_seconds), (0, 0.0));
    assert_eq!(own.library_seconds, own.solve_seconds);
    // A struct of 8 bytes: struct_size and solved, nothing past them.
    let mut old = sentinel;
    old.struct_size = 8;
    // SAFETY: the library writes at most 8 bytes of the whole struct.
    expect_ok(unsafe { ds_problem_last_cost(h, &mut old) });
    assert_eq!((old.struct_size, old.solved), (8, 1));
    assert_eq!((old.solve_seconds, old.host_solves), (SENTINEL, -7));
    let mut unset = sentinel;
    unset.struct_size = 0;
    // SAFETY: as above; refused before anything is written.
    let s = unsafe { ds_problem_last_cost(h, &mut unset) };
    expect_error(s, DsStatus::BadArgument, &["struct_size"]);
    assert_eq!(unset.solved, -7);
    // SAFETY: NULL arguments are refused.
    let s = unsafe { ds_problem_last_cost(h, null_mut()) };
    expect_error(s, DsStatus::NullPointer, &["cost"]);
    let mut c = sentinel;
    // SAFETY: as above.
    let s = unsafe { ds_problem_last_cost(null(), &mut c) };
    expect_error(s, DsStatus::NullPointer, &["problem"]);
    // A solve refused (f NULL) keeps the last cost.
    let mut junk = Outputs::small();
    let s = solve_raw(
        h,
        null(),
        DsFriction::Tresca as i32,
        null(),
        G.as_ptr(),
        P.as_ptr(),
        &mut junk,
    );
    expect_error(s, DsStatus::NullPointer, &["f"]);
    assert_eq!(cost_of(h), own);
    free(h);

    // The same problem on the host's solves.
    let mut columns: i64 = 0;
    let solver = small_host_solver((&raw mut columns).cast());
    let (k, n, t) = (k_good(), n_good(), t_good());
    let mut hh: *mut DsProblem = null_mut();
    // SAFETY: the solver and the matrices live until the call returns, the
    // counter until the handle is freed. K is given for the equilibrium
    // residual that assert_usable checks; every solve is the host's.
    let s = unsafe { ds_problem_new_host(2, &solver, &k.ds(), &n.ds(), &t.ds(), null(), &mut hh) };
    expect_ok(s);
    let at_creation = columns;
    let on_host = assert_usable(hh);
    let host = cost_of(hh);
    assert_eq!(host.solved, 1);
    assert!(host.host_solves > 0);
    assert_eq!(host.host_solves, columns - at_creation);
    assert!(host.host_seconds > 0.0 && host.host_seconds <= host.solve_seconds);
    assert_eq!(host.library_seconds, host.solve_seconds - host.host_seconds);
    for (a, b) in on_host.lambda_n.iter().zip(&out.lambda_n) {
        assert!((a - b).abs() <= 1e-10 * b.abs(), "{a} against {b}");
    }
    free(hh);
}
