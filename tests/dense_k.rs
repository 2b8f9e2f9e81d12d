//! A dense K (`Format::Dense` / DS_FORMAT_DENSE): the Schur-complement workflow of
//! Checked against independent truths:
//! - the same scene with K sparse (the library's other factorisation): u and the
//!   multipliers agree to 1e-12 relative at tol 1e-13, every method, Tresca and
//!   Coulomb, 2D and 3D, full / upper / lower storage with a padded leading
//!   dimension whose padding (and unread triangle) holds NaN;
//! - the KKT conditions of the full problem, and the frictionless patch test's
//!   closed form (uniform pressure, tributary lengths);
//! - the interface problem: K condensed onto the contact DOFs by hand (dense
//!   Schur complement S = K_CC - K_CI K_II^-1 K_IC, reduced load), solved by the
//!   library with S dense, gives the full problem's multipliers and, expanded,
//!   its u, over a history of steps;
//! - bad dense input gets its own status and the handle stays usable.

mod common;

use common::{Mesh, Scene, assert_close, assert_converged, dense, kkt_of, norm_inf, opts};
use dualsplit::internals::ffi::*;
use dualsplit::{
    ContactProblem, Csc, DualForm, Format, Friction, Indices, MatrixView, Method, Options,
    Ordering, Solution, Storage,
};
use faer::linalg::solvers::Solve;
use std::ffi::CStr;
use std::ptr::null_mut;

/// K (both triangles, n x n) as a column-major array with leading dimension `ld`,
/// NaN in the padding and, for one-triangle storage, in the triangle not stored.
fn laid_out(k: &Csc, ld: usize, storage: Storage) -> Vec<f64> {
    let n = k.nrows;
    let mut x = vec![f64::NAN; ld * n];
    for c in 0..n {
        for r in 0..n {
            let keep = match storage {
                Storage::Full => true,
                Storage::Upper => r <= c,
                Storage::Lower => r >= c,
            };
            if keep {
                x[r + c * ld] = 0.0;
            }
        }
        for p in k.col_ptr[c]..k.col_ptr[c + 1] {
            let r = k.row_idx[p];
            if !x[r + c * ld].is_nan() {
                x[r + c * ld] = k.values[p];
            }
        }
    }
    x
}

fn dense_view(x: &[f64], n: usize, ld: usize, storage: Storage) -> MatrixView<'_> {
    MatrixView {
        format: Format::Dense { ld },
        storage,
        base: 0,
        nrows: n,
        ncols: n,
        p: Indices::I64(&[]),
        i: Indices::I64(&[]),
        x,
    }
}

/// A borrowed CSC view of an internal matrix (full storage).
struct CscView {
    p: Vec<i64>,
    i: Vec<i64>,
}

impl CscView {
    fn of(a: &Csc) -> CscView {
        CscView {
            p: a.col_ptr.iter().map(|&v| v as i64).collect(),
            i: a.row_idx.iter().map(|&v| v as i64).collect(),
        }
    }

    fn view<'a>(&'a self, a: &'a Csc) -> MatrixView<'a> {
        MatrixView {
            format: Format::Csc,
            storage: Storage::Full,
            base: 0,
            nrows: a.nrows,
            ncols: a.ncols,
            p: Indices::I64(&self.p),
            i: Indices::I64(&self.i),
            x: &a.values,
        }
    }
}

/// The problem of `sc` with K given by `k` (N and T sparse).
fn create(sc: &Scene, k: &MatrixView<'_>, o: &Options) -> dualsplit::Result<ContactProblem> {
    let (nn, tt) = (CscView::of(&sc.n), CscView::of(&sc.t));
    ContactProblem::with_options(sc.d, k, &nn.view(&sc.n), &tt.view(&sc.t), o)
}

fn tight(method: Method) -> Options {
    Options {
        tol: 1e-13,
        ..opts(method)
    }
}

/// Asserts that two solutions agree to `rel` (u relative to max |u|, the
/// multipliers relative to max |lambda|).
fn assert_agree(what: &str, got: &Solution, want: &Solution, rel: f64) {
    let u_scale = norm_inf(&want.u);
    let l_scale = norm_inf(&want.lambda_n).max(norm_inf(&want.lambda_t));
    assert_close(&format!("{what}: u"), &got.u, &want.u, rel, u_scale);
    assert_close(
        &format!("{what}: lambda_N"),
        &got.lambda_n,
        &want.lambda_n,
        rel,
        l_scale,
    );
    assert_close(
        &format!("{what}: lambda_T"),
        &got.lambda_t,
        &want.lambda_t,
        rel,
        l_scale,
    );
}

fn scenes() -> Vec<(&'static str, Scene)> {
    vec![
        (
            "2D 6x3",
            Scene::pressed_block(Mesh::grid2d(6, 3, 3.0, 1.5), &[0.004, -0.01], 0.02, &[1.4]),
        ),
        (
            "3D 3x3x2",
            Scene::pressed_block(
                Mesh::grid3d(3, 3, 2, 2.0, 2.0, 1.0),
                &[0.003, -0.002, -0.01],
                0.02,
                &[0.9, 1.1],
            ),
        ),
    ]
}

#[test]
fn a_dense_k_gives_the_sparse_answer_with_every_method() {
    for (name, sc) in scenes() {
        let n = sc.k.nrows;
        let m = sc.m();
        let p = vec![0.05; m];
        let mu = vec![0.3; m];
        let csc = CscView::of(&sc.k);
        for (law, friction) in [
            ("Tresca", Friction::Tresca(&p)),
            ("Coulomb", Friction::Coulomb(&mu)),
        ] {
            for method in Method::ALL {
                let o = tight(method);
                let mut sparse = create(&sc, &csc.view(&sc.k), &o).unwrap();
                let want = sparse.solve(&sc.f, &sc.g, friction, &o).unwrap();
                for (storage, ld) in [
                    (Storage::Full, n),
                    (Storage::Upper, n + 3),
                    (Storage::Lower, n + 1),
                ] {
                    let what = format!("{name}, {law}, {}, {storage:?} ld {ld}", method.name());
                    let x = laid_out(&sc.k, ld, storage);
                    let mut pb = create(&sc, &dense_view(&x, n, ld, storage), &o)
                        .unwrap_or_else(|e| panic!("{what}: {e}"));
                    let sol = pb.solve(&sc.f, &sc.g, friction, &o).unwrap();
                    assert_converged(&what, &sol);
                    assert_eq!(sol.report.ordering, Ordering::Dense, "{what}");
                    assert_eq!(sol.report.factor_nnz, n * (n + 1) / 2, "{what}");
                    assert_agree(&what, &sol, &want, 1e-12);
                    kkt_of(&sc, friction, &sol).assert_ok(&what, 1e-10);
                }
            }
        }
    }
}

#[test]
fn a_dense_k_runs_matrix_free_and_refactors() {
    let (_, sc) = scenes().remove(1);
    let n = sc.k.nrows;
    let mu = vec![0.3; sc.m()];
    let x = laid_out(&sc.k, n, Storage::Full);
    let o = tight(Method::Auto);
    let mut dense_pb = create(&sc, &dense_view(&x, n, n, Storage::Full), &o).unwrap();
    let want = dense_pb
        .solve(&sc.f, &sc.g, Friction::Coulomb(&mu), &o)
        .unwrap();
    // The matrix-free dual on the dense factor: products by dense solves, the
    // contact blocks by dense forward solves.
    let free = Options {
        dual_form: DualForm::MatrixFree,
        ..tight(Method::Newton)
    };
    let mut pb = create(&sc, &dense_view(&x, n, n, Storage::Full), &free).unwrap();
    assert!(pb.is_matrix_free());
    let sol = pb
        .solve(&sc.f, &sc.g, Friction::Coulomb(&mu), &free)
        .unwrap();
    assert_converged("matrix-free on a dense K", &sol);
    assert_agree("matrix-free on a dense K", &sol, &want, 1e-10);
    // Refactoring with 2 K: the answer of a problem created with 2 K.
    let x2: Vec<f64> = x.iter().map(|v| 2.0 * v).collect();
    dense_pb
        .refactor(&dense_view(&x2, n, n, Storage::Full))
        .unwrap();
    let got = dense_pb
        .solve(&sc.f, &sc.g, Friction::Coulomb(&mu), &o)
        .unwrap();
    let mut fresh = create(&sc, &dense_view(&x2, n, n, Storage::Full), &o).unwrap();
    let want2 = fresh
        .solve(&sc.f, &sc.g, Friction::Coulomb(&mu), &o)
        .unwrap();
    assert_agree("refactored dense K", &got, &want2, 1e-12);
}

/// The scene condensed onto its contact DOFs C by hand: (S, N_C, T_C, f_C - K_CI
/// K_II^-1 f_I), with the maps to expand a u_C.
struct Interface {
    c: Vec<usize>,
    i: Vec<usize>,
    s: Vec<f64>,
    n_c: Csc,
    t_c: Csc,
    k_dense: faer::Mat<f64>,
}

impl Interface {
    fn of(sc: &Scene) -> Interface {
        let ndof = sc.k.nrows;
        let mut is_c = vec![false; ndof];
        for a in [&sc.n, &sc.t] {
            for (j, c) in is_c.iter_mut().enumerate() {
                *c |= a.col_ptr[j + 1] > a.col_ptr[j];
            }
        }
        let c: Vec<usize> = (0..ndof).filter(|&j| is_c[j]).collect();
        let i: Vec<usize> = (0..ndof).filter(|&j| !is_c[j]).collect();
        let k = dense(&sc.k);
        let sub = |rows: &[usize], cols: &[usize]| {
            faer::Mat::from_fn(rows.len(), cols.len(), |a, b| k[(rows[a], cols[b])])
        };
        let (k_ii, k_ic, k_cc) = (sub(&i, &i), sub(&i, &c), sub(&c, &c));
        let x = k_ii.llt(faer::Side::Lower).unwrap().solve(&k_ic);
        let s_mat = &k_cc - k_ic.transpose() * &x;
        let nc = c.len();
        // Exactly symmetric, as a user's solver returns it (or one triangle).
        let s = (0..nc * nc)
            .map(|p| {
                let (r, q) = (p % nc, p / nc);
                0.5 * (s_mat[(r, q)] + s_mat[(q, r)])
            })
            .collect();
        let restrict = |a: &Csc| {
            let mut t = Vec::new();
            for (q, &j) in c.iter().enumerate() {
                for p in a.col_ptr[j]..a.col_ptr[j + 1] {
                    t.push((a.row_idx[p], q, a.values[p]));
                }
            }
            Csc::from_triplets(a.nrows, nc, &t)
        };
        Interface {
            n_c: restrict(&sc.n),
            t_c: restrict(&sc.t),
            c,
            i,
            s,
            k_dense: k,
        }
    }

    /// f_C - K_CI K_II^-1 f_I.
    fn reduce(&self, f: &[f64]) -> Vec<f64> {
        let k = &self.k_dense;
        let k_ii = faer::Mat::from_fn(self.i.len(), self.i.len(), |a, b| k[(self.i[a], self.i[b])]);
        let f_i = faer::Mat::from_fn(self.i.len(), 1, |a, _| f[self.i[a]]);
        let y = k_ii.llt(faer::Side::Lower).unwrap().solve(&f_i);
        self.c
            .iter()
            .map(|&r| {
                f[r] - (0..self.i.len())
                    .map(|a| k[(r, self.i[a])] * y[(a, 0)])
                    .sum::<f64>()
            })
            .collect()
    }

    /// u from u_C: u_I = K_II^-1 (f_I - K_IC u_C).
    fn expand(&self, f: &[f64], u_c: &[f64]) -> Vec<f64> {
        let k = &self.k_dense;
        let ni = self.i.len();
        let k_ii = faer::Mat::from_fn(ni, ni, |a, b| k[(self.i[a], self.i[b])]);
        let r = faer::Mat::from_fn(ni, 1, |a, _| {
            f[self.i[a]]
                - (0..self.c.len())
                    .map(|q| k[(self.i[a], self.c[q])] * u_c[q])
                    .sum::<f64>()
        });
        let u_i = k_ii.llt(faer::Side::Lower).unwrap().solve(&r);
        let mut u = vec![0.0; k.nrows()];
        for (q, &j) in self.c.iter().enumerate() {
            u[j] = u_c[q];
        }
        for (a, &j) in self.i.iter().enumerate() {
            u[j] = u_i[(a, 0)];
        }
        u
    }
}

#[test]
fn the_interface_problem_on_a_schur_complement_gives_the_full_answer_over_a_history() {
    for (name, sc) in scenes() {
        let ifc = Interface::of(&sc);
        let nc = ifc.c.len();
        assert!(nc < sc.k.nrows, "{name}: the scene has interior DOFs");
        let mu = vec![0.3; sc.m()];
        let o = tight(Method::Auto);
        let csc = CscView::of(&sc.k);
        let mut full = create(&sc, &csc.view(&sc.k), &o).unwrap();
        let (nnc, ttc) = (CscView::of(&ifc.n_c), CscView::of(&ifc.t_c));
        let mut interface = ContactProblem::with_options(
            sc.d,
            &dense_view(&ifc.s, nc, nc, Storage::Lower),
            &nnc.view(&ifc.n_c),
            &ttc.view(&ifc.t_c),
            &o,
        )
        .unwrap();
        // Three increments of a history: load and gap scaled up.
        for step in 1..=3 {
            let s = step as f64 / 3.0;
            let f: Vec<f64> = sc.f.iter().map(|v| v * s).collect();
            let g: Vec<f64> = sc.g.iter().map(|v| v * (2.0 - s)).collect();
            let want = full.step(&f, &g, Friction::Coulomb(&mu), &o).unwrap();
            let got = interface
                .step(&ifc.reduce(&f), &g, Friction::Coulomb(&mu), &o)
                .unwrap();
            let what = format!("{name}, step {step}");
            assert_converged(&what, &want);
            assert_converged(&what, &got);
            assert!(got.report.err <= 1e-10, "{what}: err {}", got.report.err);
            let expanded = Solution {
                u: ifc.expand(&f, &got.u),
                ..got.clone()
            };
            assert_agree(&what, &expanded, &want, 1e-10);
        }
    }
}

/// The C API with a dense K: bad input gets its own status and message, and the
/// handle stays usable.
#[test]
fn bad_dense_input_is_refused_and_the_handle_stays_usable() {
    let (_, sc) = scenes().remove(0);
    let n = sc.k.nrows;
    let m = sc.m();
    let x = laid_out(&sc.k, n, Storage::Full);
    let dense_ds = |x: &[f64], ld: usize, storage: DsStorage| DsMatrix {
        format: DsFormat::Dense as i32,
        index_type: 77, // not read for a dense matrix
        base: 0,
        storage: storage as i32,
        nrows: n as i64,
        ncols: n as i64,
        nnz: ld as i64,
        p: std::ptr::null(),
        i: std::ptr::null(),
        x: x.as_ptr(),
    };
    let (nn, tt) = (common::Owned::of(&sc.n), common::Owned::of(&sc.t));
    let (nd, td) = (nn.ds(), tt.ds());
    let new = |k: &DsMatrix| {
        let mut pb: *mut DsProblem = null_mut();
        // SAFETY: every matrix borrows live arrays of the sizes its fields give.
        let st = unsafe { ds_problem_new(2, k, &nd, &td, &mut pb) };
        (st, pb)
    };
    let message = || {
        // SAFETY: the message is a valid C string until the next call.
        unsafe { CStr::from_ptr(ds_last_error_message()) }
            .to_string_lossy()
            .into_owned()
    };
    let mut nan = x.clone();
    nan[3 + 2 * n] = f64::NAN;
    let mut nonsym = x.clone();
    nonsym[1 + 4 * n] += 1.0;
    let mut indefinite = x.clone();
    indefinite[5 + 5 * n] = -1.0;
    let cases: Vec<(&str, DsMatrix, DsStatus, &str)> = vec![
        (
            "ld < n",
            dense_ds(&x, n - 1, DsStorage::Full),
            DsStatus::BadSize,
            "leading dimension",
        ),
        (
            "ld < 0",
            dense_ds(&x, usize::MAX, DsStorage::Full),
            DsStatus::BadSize,
            "nnz",
        ),
        (
            "NaN",
            dense_ds(&nan, n, DsStorage::Full),
            DsStatus::NotFinite,
            "NaN",
        ),
        (
            "nonsymmetric",
            dense_ds(&nonsym, n, DsStorage::Full),
            DsStatus::NotSymmetric,
            "K",
        ),
        (
            "indefinite",
            dense_ds(&indefinite, n, DsStorage::Lower),
            DsStatus::NotPositiveDefinite,
            "positive definite",
        ),
        (
            "x NULL",
            DsMatrix {
                x: std::ptr::null(),
                ..dense_ds(&x, n, DsStorage::Full)
            },
            DsStatus::NullPointer,
            "K.x",
        ),
    ];
    for (what, k, status, words) in &cases {
        let (st, pb) = new(k);
        assert_eq!(st, *status, "{what}: {}", message());
        assert!(pb.is_null(), "{what}: no handle on error");
        let msg = message();
        assert!(
            msg.contains(words),
            "{what}: message {msg:?} lacks {words:?}"
        );
    }
    // A good handle; each bad K refused by refactor leaves it answering as before.
    let (st, pb) = new(&dense_ds(&x, n, DsStorage::Full));
    assert_eq!(st, DsStatus::Ok, "{}", message());
    let opts = {
        let mut o = std::mem::MaybeUninit::<DsOptions>::uninit();
        // SAFETY: ds_options_init writes a whole DsOptions.
        unsafe {
            ds_options_init(o.as_mut_ptr(), std::mem::size_of::<DsOptions>());
            o.assume_init()
        }
    };
    let p = vec![0.05; m];
    let solve = || {
        let (mut u, mut ln, mut lt) = (vec![0.0; n], vec![0.0; m], vec![0.0; m]);
        let mut report = std::mem::MaybeUninit::<DsReport>::zeroed();
        // SAFETY: the arrays have the lengths n, m, (d-1) m the handle expects.
        let st = unsafe {
            ds_solve(
                pb,
                &opts,
                DsFriction::Tresca as i32,
                sc.f.as_ptr(),
                sc.g.as_ptr(),
                p.as_ptr(),
                u.as_mut_ptr(),
                ln.as_mut_ptr(),
                lt.as_mut_ptr(),
                report.as_mut_ptr().cast(),
            )
        };
        assert_eq!(st, DsStatus::Ok, "{}", message());
        (u, ln, lt)
    };
    let before = solve();
    for (what, k, status, _) in &cases {
        // SAFETY: pb is live; k borrows live arrays.
        let st = unsafe { ds_problem_refactor(pb, k) };
        assert_eq!(st, *status, "refactor, {what}: {}", message());
        assert_eq!(
            solve(),
            before,
            "refactor, {what}: the handle answers as before"
        );
    }
    // SAFETY: pb is live and freed once.
    unsafe { ds_problem_free(pb) };
}

/// N and T given dense keep their nonzeros: the same problem as sparse N and T.
#[test]
fn dense_n_and_t_are_their_nonzeros() {
    let (_, sc) = scenes().remove(0);
    let csc = CscView::of(&sc.k);
    let to_dense = |a: &Csc| {
        let d = dense(a);
        (0..a.nrows * a.ncols)
            .map(|p| d[(p % a.nrows, p / a.nrows)])
            .collect::<Vec<f64>>()
    };
    let (xn, xt) = (to_dense(&sc.n), to_dense(&sc.t));
    fn general<'a>(x: &'a [f64], a: &Csc) -> MatrixView<'a> {
        MatrixView {
            format: Format::Dense { ld: a.nrows },
            storage: Storage::Full,
            base: 1,
            nrows: a.nrows,
            ncols: a.ncols,
            p: Indices::I32(&[]),
            i: Indices::I32(&[]),
            x,
        }
    }
    let p = vec![0.05; sc.m()];
    let o = tight(Method::Auto);
    let mut a = create(&sc, &csc.view(&sc.k), &o).unwrap();
    let mut b = ContactProblem::with_options(
        sc.d,
        &csc.view(&sc.k),
        &general(&xn, &sc.n),
        &general(&xt, &sc.t),
        &o,
    )
    .unwrap();
    let want = a.solve(&sc.f, &sc.g, Friction::Tresca(&p), &o).unwrap();
    let got = b.solve(&sc.f, &sc.g, Friction::Tresca(&p), &o).unwrap();
    assert_eq!(got.u, want.u);
    assert_eq!(got.lambda_n, want.lambda_n);
    assert_eq!(got.lambda_t, want.lambda_t);
}

/// A dense K dumped to a problem folder reads back dense (every entry, as
/// coordinate entries) and replays to the same answer.
#[test]
fn a_dense_problem_dumps_and_replays() {
    let (_, sc) = scenes().remove(1);
    let n = sc.k.nrows;
    let p = vec![0.05; sc.m()];
    let x = laid_out(&sc.k, n, Storage::Upper);
    let o = tight(Method::Auto);
    let mut pb = create(&sc, &dense_view(&x, n, n, Storage::Upper), &o).unwrap();
    let want = pb.solve(&sc.f, &sc.g, Friction::Tresca(&p), &o).unwrap();
    let dir = std::env::temp_dir().join(format!("dualsplit-dense-dump-{}", std::process::id()));
    pb.write_folder(&dir, &sc.f, &sc.g, Friction::Tresca(&p))
        .unwrap();
    let folder = dualsplit::mtx::read_problem(&dir).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(
        folder.k.nnz(),
        n * n,
        "every entry of the dense K is written"
    );
    let mut replay =
        ContactProblem::from_csc_with(folder.d, folder.k, folder.n, folder.t, &o).unwrap();
    let got = replay
        .solve(&folder.f, &folder.g, Friction::Tresca(&p), &o)
        .unwrap();
    assert_eq!(got.report.ordering, Ordering::Dense);
    assert_agree("replayed dense K", &got, &want, 1e-12);
}

/// The frictionless patch test (tests/patch_test.rs) with K given dense: a Q4
/// block on a flat foundation, top pressed down by delta, transmits the uniform
/// pressure E/(1-nu^2) delta/H exactly: lambda_N,i = that pressure times node i's
/// tributary length, lambda_T = 0; and the sparse path gives the same to 1e-12.
#[test]
fn the_patch_test_with_a_dense_k() {
    let (e, nu, l, h, delta) = (210.0, 0.3, 3.0, 1.5, 0.01);
    let mesh = Mesh::grid2d(6, 3, l, h);
    let top = mesh.top_nodes();
    let mut prescribed: Vec<(usize, f64)> = top.iter().map(|&a| (2 * a + 1, -delta)).collect();
    prescribed.push((2 * top[0], 0.0));
    let bottom = mesh.bottom_nodes();
    let f_ext = vec![0.0; mesh.n_dofs()];
    let sc = Scene::build(mesh, e, nu, &prescribed, &f_ext, &bottom, |_| 0.0);
    let m = sc.m();
    let xs: Vec<f64> = sc
        .contact_nodes
        .iter()
        .map(|&a| sc.mesh.coords[a][0])
        .collect();
    let pressure = e / (1.0 - nu * nu) * delta / h;
    let exact: Vec<f64> = (0..m)
        .map(|i| {
            let left = if i > 0 { xs[i] - xs[i - 1] } else { 0.0 };
            let right = if i + 1 < m { xs[i + 1] - xs[i] } else { 0.0 };
            pressure * 0.5 * (left + right)
        })
        .collect();
    let n = sc.k.nrows;
    let zeros = vec![0.0; m];
    let kk = CscView::of(&sc.k);
    let x = laid_out(&sc.k, n, Storage::Lower);
    for (law, friction) in [
        ("Tresca p = 0", Friction::Tresca(&zeros)),
        ("Coulomb mu = 0", Friction::Coulomb(&zeros)),
    ] {
        let o = tight(Method::Auto);
        let mut dense_pb = create(&sc, &dense_view(&x, n, n, Storage::Lower), &o).unwrap();
        let got = dense_pb.solve(&sc.f, &sc.g, friction, &o).unwrap();
        assert_converged(law, &got);
        assert_eq!(got.report.ordering, Ordering::Dense);
        let scale = norm_inf(&exact);
        assert_close(law, &got.lambda_n, &exact, 1e-10, scale);
        assert_close(law, &got.lambda_t, &zeros, 1e-10, scale);
        let mut sparse_pb = create(&sc, &kk.view(&sc.k), &o).unwrap();
        let want = sparse_pb.solve(&sc.f, &sc.g, friction, &o).unwrap();
        assert_agree(law, &got, &want, 1e-12);
    }
}

/// DS_ORDERING_DENSE is reported, never chosen: as an option it is refused.
#[test]
fn the_dense_ordering_is_not_an_option() {
    let (_, sc) = scenes().remove(0);
    let csc = CscView::of(&sc.k);
    let o = Options {
        ordering: Ordering::Dense,
        ..Options::default()
    };
    let e = create(&sc, &csc.view(&sc.k), &o).err().expect("refused");
    assert_eq!(e.kind, dualsplit::ErrorKind::BadArgument, "{e}");
    assert!(e.message.contains("reported, not chosen"), "{e}");
}
