//! Bad input through the C ABI, beyond what tests/ffi_errors.rs covers
//! (null pointers and null handles, negative sizes, out-of-range indices, NaN in
//! K/N/f/g/p, a grossly unsymmetric K, small dense singular/indefinite K, negative
//! p/mu, d = 4, 1, 0, -2, bad enums and options are all there):
//!
//! - unsorted and duplicate entries in CSC, CSR and COO are accepted, duplicates
//!   summed (as in Matrix Market), and give the same answer as the clean matrices;
//! - NaN and infinity in every other place: T, mu, K at refactorisation, the
//!   options' tol, a duplicate pair whose sum overflows to infinity;
//! - the symmetry tolerance `sparse::SYMMETRY_TOL` (relative to max |K|): a
//!   difference just inside is accepted, just outside is `NotSymmetric`;
//! - singular and indefinite K of a real finite element model (a floating body
//!   with rigid-body modes, one element with a negative modulus, a zero diagonal)
//!   are `NotPositiveDefinite`, not a crash and not a silently wrong answer;
//! - d = i32::MAX, i32::MIN, 5.
//!
//! After every error the status is the expected one, the message is non-empty and
//! the handle still solves the reference problem with the same answer.

mod common;

use common::{Mesh, Scene};
use dualsplit::SYMMETRY_TOL;
use dualsplit::internals::ffi::*;
use std::ffi::CStr;
use std::ptr::{null, null_mut};

// ---------------------------------------------------------------------------------
// Matrices as C holds them

/// A matrix in caller layout (any format) with int64 indices.
#[derive(Clone, Debug)]
struct Owned {
    format: DsFormat,
    storage: DsStorage,
    nrows: i64,
    ncols: i64,
    p: Vec<i64>,
    i: Vec<i64>,
    x: Vec<f64>,
}

impl Owned {
    /// COO from (row, col, value) triplets in the given order.
    fn coo(nrows: usize, ncols: usize, t: &[(usize, usize, f64)]) -> Owned {
        Owned {
            format: DsFormat::Coo,
            storage: DsStorage::Full,
            nrows: nrows as i64,
            ncols: ncols as i64,
            p: t.iter().map(|e| e.1 as i64).collect(),
            i: t.iter().map(|e| e.0 as i64).collect(),
            x: t.iter().map(|e| e.2).collect(),
        }
    }

    /// CSC from triplets: grouped by column, within a column in the given order
    /// (so unsorted rows and duplicates survive).
    fn csc(nrows: usize, ncols: usize, t: &[(usize, usize, f64)]) -> Owned {
        let mut p = vec![0i64];
        let (mut i, mut x) = (vec![], vec![]);
        for c in 0..ncols {
            for e in t.iter().filter(|e| e.1 == c) {
                i.push(e.0 as i64);
                x.push(e.2);
            }
            p.push(i.len() as i64);
        }
        Owned {
            format: DsFormat::Csc,
            storage: DsStorage::Full,
            nrows: nrows as i64,
            ncols: ncols as i64,
            p,
            i,
            x,
        }
    }

    /// CSR from triplets (grouped by row, given order within a row).
    fn csr(nrows: usize, ncols: usize, t: &[(usize, usize, f64)]) -> Owned {
        let tt: Vec<_> = t.iter().map(|&(r, c, v)| (c, r, v)).collect();
        let mut o = Owned::csc(ncols, nrows, &tt);
        o.format = DsFormat::Csr;
        o.nrows = nrows as i64;
        o.ncols = ncols as i64;
        o
    }

    fn ds(&self) -> DsMatrix {
        DsMatrix {
            format: self.format as i32,
            index_type: DsIndexType::I64 as i32,
            base: 0,
            storage: self.storage as i32,
            nrows: self.nrows,
            ncols: self.ncols,
            nnz: if self.format == DsFormat::Coo {
                self.x.len() as i64
            } else {
                0
            },
            p: self.p.as_ptr().cast(),
            i: self.i.as_ptr().cast(),
            x: self.x.as_ptr(),
        }
    }
}

fn triplets(a: &dualsplit::Csc) -> Vec<(usize, usize, f64)> {
    let mut out = Vec::new();
    for j in 0..a.ncols {
        for k in a.col_ptr[j]..a.col_ptr[j + 1] {
            out.push((a.row_idx[k], j, a.values[k]));
        }
    }
    out
}

// ---------------------------------------------------------------------------------
// The reference problem: a small Q4 block (6 x 2 elements) on a curved foundation.

fn scene() -> Scene {
    let mesh = Mesh::grid2d(6, 2, 2.0, 1.0);
    Scene::pressed_block(mesh, &[0.004, -0.02], 0.05, &[1.0])
}

fn last_message() -> String {
    let p = ds_last_error_message();
    assert!(!p.is_null());
    // SAFETY: non-NULL, NUL-terminated, valid until the next ds_ call.
    unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
}

#[track_caller]
fn expect(status: DsStatus, expected: DsStatus, what: &str) {
    let msg = last_message();
    eprintln!("{what}: {status:?}: {msg}");
    assert_eq!(status, expected, "{what}: message: {msg}");
    if expected != DsStatus::Ok {
        assert!(!msg.is_empty(), "{what}: no message");
    }
}

fn new_problem(d: i32, k: &Owned, n: &Owned, t: &Owned) -> (DsStatus, *mut DsProblem) {
    let mut out: *mut DsProblem = null_mut();
    // SAFETY: the matrices outlive the call; out is a valid location.
    let s = unsafe { ds_problem_new(d, &k.ds(), &n.ds(), &t.ds(), &mut out) };
    (s, out)
}

struct Answer {
    u: Vec<f64>,
    ln: Vec<f64>,
    lt: Vec<f64>,
    report: DsReport,
}

/// ds_solve with Coulomb mu (or Tresca p) on the scene's f and g.
fn solve(h: *mut DsProblem, sc: &Scene, friction: DsFriction, bound: &[f64]) -> (DsStatus, Answer) {
    let m = sc.m();
    let mut a = Answer {
        u: vec![0.0; sc.k.nrows],
        ln: vec![0.0; m],
        lt: vec![0.0; m],
        report: DsReport {
            status: 0,
            method: 0,
            err: 0.0,
            equilibrium_residual: 0.0,
            outer_iterations: 0,
            inner_iterations: 0,
            n_open: 0,
            n_stick: 0,
            n_slip: 0,
            factor_seconds: 0.0,
            condense_seconds: 0.0,
            solve_seconds: 0.0,
            ordering: 0,
            threads: 0,
            factor_nnz: 0,
            factor_flops: 0.0,
            analyse_seconds: 0.0,
            memory_predicted: 0,
            memory_peak: 0,
        },
    };
    // SAFETY: arrays sized for the problem.
    let s = unsafe {
        ds_solve(
            h,
            null(),
            friction as i32,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            bound.as_ptr(),
            a.u.as_mut_ptr(),
            a.ln.as_mut_ptr(),
            a.lt.as_mut_ptr(),
            &mut a.report,
        )
    };
    (s, a)
}

fn mu(sc: &Scene) -> Vec<f64> {
    vec![0.3; sc.m()]
}

/// The reference answer, checked against KKT.
fn reference(sc: &Scene) -> Answer {
    let (k, n, t) = clean(sc);
    let (s, h) = new_problem(2, &k, &n, &t);
    expect(s, DsStatus::Ok, "reference problem");
    let (s, a) = solve(h, sc, DsFriction::Coulomb, &mu(sc));
    expect(s, DsStatus::Ok, "reference solve");
    let mu = mu(sc);
    common::kkt(
        2,
        &sc.k,
        &sc.n,
        &sc.t,
        &sc.f,
        &sc.g,
        dualsplit::Friction::Coulomb(&mu),
        &a.u,
        &a.ln,
        &a.lt,
    )
    .assert_ok("reference", 1e-8);
    // SAFETY: created above, freed once.
    unsafe { ds_problem_free(h) };
    a
}

fn clean(sc: &Scene) -> (Owned, Owned, Owned) {
    let m = sc.m();
    let nd = sc.k.nrows;
    (
        Owned::csc(nd, nd, &triplets(&sc.k)),
        Owned::csc(m, nd, &triplets(&sc.n)),
        Owned::csc(m, nd, &triplets(&sc.t)),
    )
}

#[track_caller]
fn assert_same(what: &str, a: &Answer, b: &Answer, rel: f64) {
    let pairs = [(&a.u, &b.u), (&a.ln, &b.ln), (&a.lt, &b.lt)];
    for (x, y) in pairs {
        let s = common::norm_inf(x).max(1e-300);
        let d = common::max_diff(x, y);
        assert!(d <= rel * s, "{what}: differs by {d:.3e} (scale {s:.3e})");
    }
}

/// Solves the reference problem on `h` and compares with `want`.
#[track_caller]
fn assert_usable(h: *mut DsProblem, sc: &Scene, want: &Answer) {
    let (s, a) = solve(h, sc, DsFriction::Coulomb, &mu(sc));
    expect(s, DsStatus::Ok, "handle still usable");
    assert_same("handle still usable", &a, want, 1e-10);
}

/// Splits every stored value of `t` into two duplicates (0.25 v and 0.75 v) and
/// reverses the order of all entries (so every column is unsorted).
fn messy(t: &[(usize, usize, f64)]) -> Vec<(usize, usize, f64)> {
    let mut out = Vec::new();
    for &(r, c, v) in t.iter().rev() {
        out.push((r, c, 0.75 * v));
    }
    for &(r, c, v) in t {
        out.push((r, c, 0.25 * v));
    }
    out
}

// ---------------------------------------------------------------------------------

#[test]
fn unsorted_and_duplicate_entries_are_summed() {
    let sc = scene();
    let want = reference(&sc);
    let (m, nd) = (sc.m(), sc.k.nrows);
    let (kt, nt, tt) = (
        messy(&triplets(&sc.k)),
        messy(&triplets(&sc.n)),
        messy(&triplets(&sc.t)),
    );
    for (name, k, n, t) in [
        (
            "CSC unsorted with duplicates",
            Owned::csc(nd, nd, &kt),
            Owned::csc(m, nd, &nt),
            Owned::csc(m, nd, &tt),
        ),
        (
            "CSR unsorted with duplicates",
            Owned::csr(nd, nd, &kt),
            Owned::csr(m, nd, &nt),
            Owned::csr(m, nd, &tt),
        ),
        (
            "COO unsorted with duplicates",
            Owned::coo(nd, nd, &kt),
            Owned::coo(m, nd, &nt),
            Owned::coo(m, nd, &tt),
        ),
    ] {
        let (s, h) = new_problem(2, &k, &n, &t);
        expect(s, DsStatus::Ok, name);
        let (s, a) = solve(h, &sc, DsFriction::Coulomb, &mu(&sc));
        expect(s, DsStatus::Ok, name);
        assert_same(name, &a, &want, 1e-9);
        // Refactor and set_contacts accept the same messy layout.
        // SAFETY: h is live; the matrices outlive the calls.
        unsafe {
            expect(ds_problem_refactor(h, &k.ds()), DsStatus::Ok, name);
            expect(
                ds_problem_set_contacts(h, &n.ds(), &t.ds()),
                DsStatus::Ok,
                name,
            );
        }
        assert_usable(h, &sc, &want);
        // SAFETY: freed once.
        unsafe { ds_problem_free(h) };
    }
}

#[test]
fn non_finite_values_everywhere() {
    let sc = scene();
    let want = reference(&sc);
    let (k, n, t) = clean(&sc);
    let (s, h) = new_problem(2, &k, &n, &t);
    expect(s, DsStatus::Ok, "create");
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        // T at creation and in set_contacts.
        let mut t_bad = t.clone();
        let mid = t_bad.x.len() / 2;
        t_bad.x[mid] = bad;
        let (s, h2) = new_problem(2, &k, &n, &t_bad);
        expect(s, DsStatus::NotFinite, "non-finite T at creation");
        assert!(h2.is_null());
        // SAFETY: h is live.
        let s = unsafe { ds_problem_set_contacts(h, &n.ds(), &t_bad.ds()) };
        expect(s, DsStatus::NotFinite, "non-finite T in set_contacts");
        assert_usable(h, &sc, &want);
        // K at refactorisation, in the last entry (a diagonal).
        let mut k_bad = k.clone();
        let last = k_bad.x.len() - 1;
        k_bad.x[last] = bad;
        // SAFETY: h is live.
        let s = unsafe { ds_problem_refactor(h, &k_bad.ds()) };
        expect(s, DsStatus::NotFinite, "non-finite K in refactor");
        assert_usable(h, &sc, &want);
        // mu.
        let mut mu_bad = mu(&sc);
        mu_bad[1] = bad;
        let (s, _) = solve(h, &sc, DsFriction::Coulomb, &mu_bad);
        expect(s, DsStatus::NotFinite, "non-finite mu");
        assert_usable(h, &sc, &want);
        // tol in the options.
        let mut o = DsOptions::default();
        // SAFETY: o is a whole, writable DsOptions.
        let st = unsafe { ds_options_init(&mut o, std::mem::size_of::<DsOptions>()) };
        assert_eq!(st, DsStatus::Ok);
        o.tol = bad;
        let mut u = vec![0.0; sc.k.nrows];
        let (mut ln, mut lt) = (vec![0.0; sc.m()], vec![0.0; sc.m()]);
        let mu_ok = mu(&sc);
        // SAFETY: arrays sized for the problem.
        let s = unsafe {
            ds_solve(
                h,
                &o,
                DsFriction::Coulomb as i32,
                sc.f.as_ptr(),
                sc.g.as_ptr(),
                mu_ok.as_ptr(),
                u.as_mut_ptr(),
                ln.as_mut_ptr(),
                lt.as_mut_ptr(),
                null_mut(),
            )
        };
        expect(s, DsStatus::BadArgument, "non-finite tol");
        assert!(u.iter().all(|&v| v == 0.0), "outputs written on error");
    }
    // Finite duplicates whose sum overflows: 1e308 + 1e308 = inf (COO, in N).
    let nd = sc.k.nrows;
    let mut nt = triplets(&sc.n);
    nt.push((0, nt[0].1, 1e308));
    nt.push((0, nt[0].1, 1e308));
    let n_over = Owned::coo(sc.m(), nd, &nt);
    let (s, h2) = new_problem(2, &k, &n_over, &t);
    expect(s, DsStatus::NotFinite, "duplicates summing to infinity");
    assert!(h2.is_null());
    // The same in K (diagonal entry, symmetric by construction).
    let mut kt = triplets(&sc.k);
    kt.push((3, 3, f64::MAX));
    kt.push((3, 3, f64::MAX));
    let k_over = Owned::coo(nd, nd, &kt);
    // SAFETY: h is live.
    let s = unsafe { ds_problem_refactor(h, &k_over.ds()) };
    expect(s, DsStatus::NotFinite, "K duplicates summing to infinity");
    assert!(last_message().contains("K:"), "{}", last_message());
    assert_usable(h, &sc, &want);
    // SAFETY: freed once.
    unsafe { ds_problem_free(h) };
}

#[test]
fn symmetry_tolerance_just_inside_and_just_outside() {
    let sc = scene();
    let want = reference(&sc);
    let (k, n, t) = clean(&sc);
    let max_abs = k.x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    // Find an off-diagonal stored entry (r, c), r != c, in column c.
    let (pos, r, c) = (0..k.ncols as usize)
        .flat_map(|c| (k.p[c] as usize..k.p[c + 1] as usize).map(move |q| (q, c)))
        .map(|(q, c)| (q, k.i[q] as usize, c))
        .find(|&(q, r, c)| r != c && k.x[q].abs() > 0.1 * max_abs)
        .expect("an off-diagonal entry");
    println!("perturbing K({r},{c}) = {}, max |K| = {max_abs}", k.x[pos]);
    let (s, h) = new_problem(2, &k, &n, &t);
    expect(s, DsStatus::Ok, "create");
    for (factor, expected) in [
        (0.5, DsStatus::Ok),
        (0.9, DsStatus::Ok),
        (1.1, DsStatus::NotSymmetric),
        (2.0, DsStatus::NotSymmetric),
    ] {
        let mut kp = k.clone();
        kp.x[pos] += factor * SYMMETRY_TOL * max_abs;
        let what = format!("|K_ij - K_ji| = {factor} * SYMMETRY_TOL * max|K|");
        let (s, h2) = new_problem(2, &kp, &n, &t);
        expect(s, expected, &what);
        // SAFETY: h is live.
        let s2 = unsafe { ds_problem_refactor(h, &kp.ds()) };
        expect(s2, expected, &what);
        if expected == DsStatus::Ok {
            // Accepted as given: the answer moves by no more than the perturbation.
            let (s, a) = solve(h2, &sc, DsFriction::Coulomb, &mu(&sc));
            expect(s, DsStatus::Ok, &what);
            assert_same(&what, &a, &want, 1e-8);
            // SAFETY: freed once.
            unsafe { ds_problem_free(h2) };
            // Back to the exact K.
            // SAFETY: h is live.
            expect(
                unsafe { ds_problem_refactor(h, &k.ds()) },
                DsStatus::Ok,
                "restore",
            );
        } else {
            assert!(h2.is_null());
        }
        assert_usable(h, &sc, &want);
    }
    // SAFETY: freed once.
    unsafe { ds_problem_free(h) };
}

/// A scene whose K is singular in exact arithmetic (a floating body: no
/// Dirichlet condition at all; three rigid-body modes in 2D).
fn floating() -> Scene {
    let mesh = Mesh::grid2d(6, 2, 2.0, 1.0);
    let f_ext = vec![0.0; mesh.n_dofs()];
    let bottom = mesh.bottom_nodes();
    Scene::build(mesh, 100.0, 0.3, &[], &f_ext, &bottom, |_| 0.1)
}

#[test]
fn singular_and_indefinite_fe_stiffness_is_detected() {
    let sc = scene();
    let want = reference(&sc);
    let (k, n, t) = clean(&sc);
    let (s, h) = new_problem(2, &k, &n, &t);
    expect(s, DsStatus::Ok, "create");
    let nd = sc.k.nrows;
    let mut cases: Vec<(&str, Owned)> = Vec::new();
    // One element with a negative modulus: indefinite.
    {
        let mesh = Mesh::grid2d(6, 2, 2.0, 1.0);
        let mut prescribed = Vec::new();
        for &a in &mesh.top_nodes() {
            prescribed.push((2 * a, 0.0));
            prescribed.push((2 * a + 1, 0.0));
        }
        let f_ext = vec![0.0; mesh.n_dofs()];
        let bottom = mesh.bottom_nodes();
        let s2 = Scene::build_by(
            mesh,
            |e| if e == 3 { (-100.0, 0.3) } else { (100.0, 0.3) },
            &prescribed,
            &f_ext,
            &bottom,
            |_| 0.0,
        );
        assert_eq!(s2.k.nrows, nd);
        cases.push((
            "one element with E < 0",
            Owned::csc(nd, nd, &triplets(&s2.k)),
        ));
    }
    // A zero diagonal entry (row and column of DOF 5 zeroed, entries kept).
    {
        let kt: Vec<_> = triplets(&sc.k)
            .into_iter()
            .map(|(r, c, v)| {
                if r == 5 || c == 5 {
                    (r, c, 0.0)
                } else {
                    (r, c, v)
                }
            })
            .collect();
        cases.push(("a zero row and column", Owned::csc(nd, nd, &kt)));
    }
    for (what, kb) in &cases {
        let (s, h2) = new_problem(2, kb, &n, &t);
        expect(s, DsStatus::NotPositiveDefinite, what);
        assert!(h2.is_null());
        // SAFETY: h is live; same pattern as K.
        let s = unsafe { ds_problem_refactor(h, &kb.ds()) };
        expect(s, DsStatus::NotPositiveDefinite, what);
        assert_usable(h, &sc, &want);
    }
    // SAFETY: freed once.
    unsafe { ds_problem_free(h) };
}

#[test]
fn singular_floating_body_is_detected() {
    let fl = floating();
    let nd = fl.k.nrows;
    let m = fl.m();
    let k = Owned::csc(nd, nd, &triplets(&fl.k));
    let n = Owned::csc(m, nd, &triplets(&fl.n));
    let t = Owned::csc(m, nd, &triplets(&fl.t));
    let (s, h) = new_problem(2, &k, &n, &t);
    let msg = last_message();
    if !h.is_null() {
        // SAFETY: created above.
        unsafe { ds_problem_free(h) };
    }
    assert_eq!(s, DsStatus::NotPositiveDefinite, "floating body: {msg}");
}

#[test]
fn d_far_out_of_range() {
    let sc = scene();
    let (k, n, t) = clean(&sc);
    for d in [i32::MAX, i32::MIN, 5, -3] {
        let (s, h) = new_problem(d, &k, &n, &t);
        expect(s, DsStatus::BadArgument, &format!("d = {d}"));
        assert!(h.is_null());
    }
}

// ---------------------------------------------------------------------------------
// Regression inputs found by the fuzz targets (fuzz/), kept here so that `cargo
// test` replays them without nightly.

/// fuzz/ mtx_reader crash-be393bab: a coordinate header with 5.6e17 rows. The
/// reader must answer BadSize (a file read on its own may not declare more rows
/// than it can hold entries for; tests/mtx_io.rs), not abort the process on an
/// allocation of that size.
#[test]
fn fuzz_regression_mtx_huge_dimension() {
    let text = "%%MatrixMarket matrix coordinate real general\n% c\n\
                555555555555555553 3 4\n1 1 2.0\n2 1 -1\n3 3 4e0\n1 1 0.5\n";
    let r = dualsplit::mtx::parse_matrix(text, std::path::Path::new("fuzz.mtx"));
    let e = r.expect_err("a 5.6e17-row matrix cannot be read");
    assert_eq!(e.kind, dualsplit::ErrorKind::BadSize, "{e}");
    // And a size that fits in usize but not in memory.
    let text = "%%MatrixMarket matrix coordinate real general\n\
                4611686018427387904 3 1\n1 1 2.0\n";
    let r = dualsplit::mtx::parse_matrix(text, std::path::Path::new("fuzz.mtx"));
    let e = r.expect_err("a 4.6e18-row matrix cannot be allocated");
    assert_eq!(e.kind, dualsplit::ErrorKind::BadSize, "{e}");
}
