//! A problem on the host's own solver of K (`ContactProblem::with_host_solver`):
//! the host here is a callback written in the test that factors K
//! itself. Its answers must pass the KKT check and agree with the library's
//! own path (same K, N, T) for Newton and MPRGP, 2D and 3D, Tresca and
//! Coulomb, single solves and histories, with and without K handed over; a
//! solve that fails or returns NaN must give `HostSolve` with the host's
//! code, leave the history where it was and the problem usable; bad sizes
//! and the methods that need A's entries are refused.

mod common;

use common::{Mesh, Owned, Scene, assert_converged, kkt_of, max_diff, norm_inf};
use dualsplit::internals::Factor;
use dualsplit::{
    ContactProblem, DualForm, ErrorKind, Friction, HostBlocks, KSolve, Method, Options, Solution,
    SolveStatus,
};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The host: K's Cholesky factor, one right-hand side at a time; call number
/// `fail_at` (counted from 1, 0 never) fails with code -42, or returns a NaN
/// where `nan` is set.
struct Host {
    factor: Arc<Factor>,
    n: usize,
    calls: Arc<AtomicUsize>,
    fail_at: Arc<AtomicUsize>,
    nan: bool,
}

impl KSolve for Host {
    fn n(&self) -> usize {
        self.n
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> Result<(), i32> {
        assert_eq!(x.len(), self.n * ncols, "the block is n x ncols");
        let call = self.calls.fetch_add(1, Ordering::SeqCst) + 1;
        if call == self.fail_at.load(Ordering::SeqCst) && !self.nan {
            x.iter_mut().for_each(|v| *v = 1e300);
            return Err(-42);
        }
        for col in x.chunks_mut(self.n) {
            self.factor.solve_vec(col);
        }
        if call == self.fail_at.load(Ordering::SeqCst) {
            x[self.n / 2] = f64::NAN;
        }
        Ok(())
    }
}

/// A host that also gives entries of K^-1 (as a direct solver's selected
/// inversion does), here column by column from its factor; `fail` makes
/// that call fail with code 9.
struct WithEntries {
    host: Host,
    entries: Arc<AtomicUsize>,
    fail: bool,
}

impl KSolve for WithEntries {
    fn n(&self) -> usize {
        self.host.n
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> Result<(), i32> {
        self.host.solve(x, ncols)
    }

    fn inverse_entries(
        &mut self,
        rows: &[usize],
        cols: &[usize],
        values: &mut [f64],
    ) -> Option<Result<(), i32>> {
        if self.fail {
            return Some(Err(9));
        }
        let n = self.host.n;
        let mut e = vec![0.0; n];
        let mut last = usize::MAX;
        for k in 0..rows.len() {
            if cols[k] != last {
                e.iter_mut().for_each(|v| *v = 0.0);
                e[cols[k]] = 1.0;
                self.host.factor.solve_vec(&mut e);
                last = cols[k];
            }
            values[k] = e[rows[k]];
        }
        self.entries.fetch_add(rows.len(), Ordering::SeqCst);
        Some(Ok(()))
    }
}

struct Handles {
    calls: Arc<AtomicUsize>,
    fail_at: Arc<AtomicUsize>,
}

fn host(scene: &Scene, nan: bool) -> (Box<dyn KSolve>, Handles) {
    let (h, handles) = concrete_host(scene, nan);
    (Box::new(h), handles)
}

fn concrete_host(scene: &Scene, nan: bool) -> (Host, Handles) {
    let calls = Arc::new(AtomicUsize::new(0));
    let fail_at = Arc::new(AtomicUsize::new(0));
    let h = Host {
        factor: Factor::new(&scene.k).expect("K factors"),
        n: scene.k.nrows,
        calls: calls.clone(),
        fail_at: fail_at.clone(),
        nan,
    };
    (h, Handles { calls, fail_at })
}

fn on_host(scene: &Scene, with_k: bool, nan: bool, opts: &Options) -> (ContactProblem, Handles) {
    let (solver, handles) = host(scene, nan);
    // The contact blocks by the host's solves, whose calls these tests count
    // (the default, `Auto`, takes the library's factor of K on these scenes).
    let opts = Options {
        host_blocks: HostBlocks::Solves,
        ..*opts
    };
    let pb = on_solver(scene, solver, with_k, &opts).expect("a valid host problem");
    (pb, handles)
}

/// The problem of `scene` on the host `solver`, with K handed over where
/// `with_k`.
fn on_solver(
    scene: &Scene,
    solver: Box<dyn KSolve>,
    with_k: bool,
    opts: &Options,
) -> dualsplit::Result<ContactProblem> {
    let k_owned = Owned::of(&scene.k);
    let k = k_owned.view();
    ContactProblem::with_host_solver(
        scene.d,
        solver,
        with_k.then_some(&k),
        &Owned::of(&scene.n).view(),
        &Owned::of(&scene.t).view(),
        opts,
    )
}

/// The first `rows` rows of `a`.
fn first_rows(a: &dualsplit::Csc, rows: usize) -> dualsplit::Csc {
    let mut t = a.transpose();
    t.ncols = rows;
    t.col_ptr.truncate(rows + 1);
    let nnz = t.col_ptr[rows];
    t.row_idx.truncate(nnz);
    t.values.truncate(nnz);
    t.transpose()
}

fn scene_2d() -> Scene {
    let mesh = Mesh::grid2d(24, 6, 2.0, 1.0);
    let mut prescribed = Vec::new();
    for &a in &mesh.top_nodes() {
        prescribed.push((2 * a, 0.006));
        prescribed.push((2 * a + 1, -0.02));
    }
    let f_ext = vec![0.0; mesh.n_dofs()];
    let bottom = mesh.bottom_nodes();
    Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, |x| {
        0.05 * (x[0] - 1.0).powi(2)
    })
}

fn scene_3d() -> Scene {
    let mesh = Mesh::grid3d(6, 6, 2, 2.0, 2.0, 1.0);
    let mut prescribed = Vec::new();
    for &a in &mesh.top_nodes() {
        prescribed.push((3 * a, 0.006));
        prescribed.push((3 * a + 1, 0.003));
        prescribed.push((3 * a + 2, -0.03));
    }
    let f_ext = vec![0.0; mesh.n_dofs()];
    let bottom = mesh.bottom_nodes();
    Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, |x| {
        0.05 * ((x[0] - 1.0).powi(2) + (x[1] - 1.0).powi(2))
    })
}

fn with(method: Method) -> Options {
    Options {
        method,
        dual_form: DualForm::MatrixFree,
        ..Options::default()
    }
}

fn lambda(s: &Solution) -> Vec<f64> {
    s.lambda_n.iter().chain(&s.lambda_t).copied().collect()
}

fn assert_agree(name: &str, own: &Solution, host: &Solution, rel: f64) {
    let (l0, l1) = (lambda(own), lambda(host));
    let dl = max_diff(&l0, &l1);
    assert!(
        dl <= rel * norm_inf(&l0),
        "{name}: lambda differs by {dl:.2e}"
    );
    let du = max_diff(&own.u, &host.u);
    assert!(
        du <= rel * norm_inf(&own.u),
        "{name}: u differs by {du:.2e}"
    );
}

/// One solve on the host's solves against the library's own matrix-free
/// path: both converge, pass the KKT check and agree.
fn agree(name: &str, scene: &Scene, friction: Friction<'_>, method: Method, with_k: bool) {
    let opts = with(method);
    let own = scene
        .problem()
        .solve(&scene.f, &scene.g, friction, &opts)
        .unwrap();
    let (mut pb, handles) = on_host(scene, with_k, false, &opts);
    assert!(pb.is_matrix_free());
    let blocks = handles.calls.load(Ordering::SeqCst);
    // The contact blocks: d m right-hand sides, 32 per call.
    assert_eq!(
        blocks,
        pb.dual_unknowns().div_ceil(32),
        "{name}: block solves"
    );
    let sol = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
    let r = &sol.report;
    println!(
        "{name}: {:?} err {:.2e}, outer {}, inner {}, host solves {} ({:.3} s); own inner {}",
        r.status,
        r.err,
        r.outer_iterations,
        r.inner_iterations,
        r.host_solves,
        r.host_seconds,
        own.report.inner_iterations
    );
    assert_converged(name, &sol);
    kkt_of(scene, friction, &sol).assert_ok(name, 1e-8);
    assert_agree(name, &own, &sol, 1e-8);
    let calls = handles.calls.load(Ordering::SeqCst) - blocks;
    assert_eq!(r.host_solves, calls, "{name}: one right-hand side per call");
    assert!(r.host_solves >= 2 && r.host_seconds > 0.0);
    assert_eq!(r.factor_nnz, 0, "{name}: no factor of the library's");
    if with_k {
        assert!(r.equilibrium_residual < 1e-10, "{name}");
    } else {
        assert!(r.equilibrium_residual.is_nan(), "{name}: not measured");
    }
}

#[test]
fn newton_and_mprgp_on_the_hosts_solves_match_the_own_path() {
    let s2 = scene_2d();
    let (mu2, p2) = (vec![0.3; s2.m()], vec![0.02; s2.m()]);
    let s3 = scene_3d();
    let (mu3, p3) = (vec![0.3; s3.m()], vec![0.05; s3.m()]);
    for with_k in [true, false] {
        for method in [Method::Newton, Method::Mprgp, Method::Auto] {
            let tag = format!("{} with_k {with_k}", method.name());
            agree(
                &format!("2D Coulomb {tag}"),
                &s2,
                Friction::Coulomb(&mu2),
                method,
                with_k,
            );
            agree(
                &format!("2D Tresca {tag}"),
                &s2,
                Friction::Tresca(&p2),
                method,
                with_k,
            );
            agree(
                &format!("3D Coulomb {tag}"),
                &s3,
                Friction::Coulomb(&mu3),
                method,
                with_k,
            );
            agree(
                &format!("3D Tresca {tag}"),
                &s3,
                Friction::Tresca(&p3),
                method,
                with_k,
            );
        }
    }
}

/// A press-then-shear history of 6 steps: the host's problem (with K and
/// without it, where K u_k comes from the last step's equilibrium) gives the
/// own path's u and multipliers at every step.
#[test]
fn a_history_on_the_hosts_solves_matches_the_own_path() {
    let scene = scene_3d();
    let mu = vec![0.3; scene.m()];
    let friction = Friction::Coulomb(&mu);
    let opts = with(Method::Auto);
    let mut own = scene.problem();
    let (mut with_k, _) = on_host(&scene, true, false, &opts);
    let (mut without_k, _) = on_host(&scene, false, false, &opts);
    let n = scene.k.nrows;
    for step in 1..=6 {
        // Press, then shear: the load's tangential part grows after step 3.
        let s = step as f64 / 6.0;
        let shear = (step as f64 - 3.0).max(0.0) / 3.0;
        let f: Vec<f64> = (0..n)
            .map(|i| scene.f[i] * s * if i % 3 == 2 { 1.0 } else { 1.0 + shear })
            .collect();
        let a = own.step(&f, &scene.g, friction, &opts).unwrap();
        assert_converged(&format!("own step {step}"), &a);
        for (name, pb) in [("with K", &mut with_k), ("without K", &mut without_k)] {
            let b = pb.step(&f, &scene.g, friction, &opts).unwrap();
            let w = format!("host {name}, step {step}");
            assert_converged(&w, &b);
            assert_agree(&w, &a, &b, 1e-8);
        }
    }
}

/// A solve whose host fails mid-solve (code -42, or a NaN): `HostSolve`
/// naming the code, the history where it was, and the next solve as if
/// nothing had happened.
#[test]
fn a_failing_host_solve_is_an_error_and_the_problem_stays_usable() {
    let scene = scene_3d();
    let mu = vec![0.3; scene.m()];
    let friction = Friction::Coulomb(&mu);
    let opts = with(Method::Auto);
    for nan in [false, true] {
        let (mut pb, handles) = on_host(&scene, false, nan, &opts);
        let first = pb.step(&scene.f, &scene.g, friction, &opts).unwrap();
        assert_converged("first step", &first);
        // The second step fails at its third host call (a product, after the
        // right-hand side's solve).
        let done = handles.calls.load(Ordering::SeqCst);
        handles.fail_at.store(done + 3, Ordering::SeqCst);
        let f2: Vec<f64> = scene.f.iter().map(|v| 1.5 * v).collect();
        let e = pb.step(&f2, &scene.g, friction, &opts).unwrap_err();
        assert_eq!(e.kind, ErrorKind::HostSolve, "{e}");
        let what = if nan { "returned NaN" } else { "code -42" };
        assert!(e.message.contains(what), "{}", e.message);
        // Nothing was called after the failure within that step.
        assert_eq!(handles.calls.load(Ordering::SeqCst), done + 3);
        // The history did not advance: the step redone now gives what a
        // fresh problem gives after one step.
        handles.fail_at.store(0, Ordering::SeqCst);
        let again = pb.step(&f2, &scene.g, friction, &opts).unwrap();
        let mut own = scene.problem();
        own.step(&scene.f, &scene.g, friction, &opts).unwrap();
        let want = own.step(&f2, &scene.g, friction, &opts).unwrap();
        assert_converged("the step redone", &again);
        assert_agree("the step redone", &want, &again, 1e-8);
        assert_eq!(again.report.status, SolveStatus::Converged);
    }
}

/// A failure while the contact blocks are formed fails the creation.
#[test]
fn a_failure_while_forming_the_blocks_fails_the_creation() {
    let scene = scene_2d();
    let (solver, handles) = host(&scene, false);
    handles.fail_at.store(1, Ordering::SeqCst);
    let e = ContactProblem::with_host_solver(
        2,
        solver,
        None,
        &Owned::of(&scene.n).view(),
        &Owned::of(&scene.t).view(),
        &Options::default(),
    )
    .err()
    .expect("the first solve fails");
    assert_eq!(e.kind, ErrorKind::HostSolve);
    assert!(e.message.contains("code -42"), "{}", e.message);
}

#[test]
fn bad_sizes_and_methods_that_need_entries_are_refused() {
    let scene = scene_2d();
    let opts = Options::default();
    // The creation on the 2D scene's host with dimension d, K, N and T
    // (another scene's where given) refused with `want`.
    let refused = |d: usize, k: Option<&dualsplit::Csc>, nt: &Scene, o: &Options, want| {
        let (solver, _) = host(&scene, false);
        let k_owned = k.map(Owned::of);
        let kv = k_owned.as_ref().map(Owned::view);
        let (n, t) = (Owned::of(&nt.n), Owned::of(&nt.t));
        let e = ContactProblem::with_host_solver(d, solver, kv.as_ref(), &n.view(), &t.view(), o)
            .err()
            .expect("refused");
        assert_eq!(e.kind, want, "{e}");
    };
    let small = scene_3d();
    // K of another size than the host's n; N with another column count.
    refused(2, Some(&small.k), &scene, &opts, ErrorKind::BadSize);
    refused(2, None, &small, &opts, ErrorKind::BadSize);
    // d = 4, and the dense form.
    refused(4, None, &scene, &opts, ErrorKind::BadArgument);
    let dense = Options {
        dual_form: DualForm::Dense,
        ..opts
    };
    refused(2, None, &scene, &dense, ErrorKind::BadArgument);
    // On a valid problem: the methods that read A's entries, the dense form,
    // refactor and a folder without K are refused; a solve still works.
    let (mut pb, _) = on_host(&scene, false, false, &opts);
    let mu = vec![0.3; scene.m()];
    let friction = Friction::Coulomb(&mu);
    for bad in [
        Options {
            method: Method::Split,
            ..opts
        },
        dense,
    ] {
        let e = pb.solve(&scene.f, &scene.g, friction, &bad).unwrap_err();
        assert_eq!(e.kind, ErrorKind::BadArgument, "{e}");
        assert!(e.message.contains("host"), "{}", e.message);
    }
    let e = pb.refactor(&Owned::of(&scene.k).view()).unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadArgument);
    let dir = std::env::temp_dir().join("dualsplit_host_folder");
    let e = pb
        .write_folder(&dir, &scene.f, &scene.g, friction)
        .unwrap_err();
    assert_eq!(e.kind, ErrorKind::BadArgument);
    let sol = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
    assert_converged("after the refusals", &sol);
    kkt_of(&scene, friction, &sol).assert_ok("after the refusals", 1e-8);
    // The analysis report: no factor, matrix-free.
    let info = pb.info(&opts);
    assert_eq!(
        (info.factor_nnz, info.n, info.m),
        (0, scene.k.nrows, scene.m())
    );
    assert_eq!(info.setup_form, DualForm::MatrixFree);
}

/// A host that gives entries of K^-1: the blocks come from one call of it
/// (no solve at creation), also where K is handed over (`HostBlocks::Auto`
/// asks the host's entries first), and the answers are the own path's; a
/// failing entries call fails the creation with its code, unless K was
/// handed over: then the library's factor of K gives the blocks.
#[test]
fn the_contact_blocks_from_the_hosts_entries_of_the_inverse() {
    let scene = scene_3d();
    let mu = vec![0.3; scene.m()];
    let friction = Friction::Coulomb(&mu);
    let opts = with(Method::Auto);
    let own = scene
        .problem()
        .solve(&scene.f, &scene.g, friction, &opts)
        .unwrap();
    for (fail, with_k) in [(false, false), (false, true), (true, false), (true, true)] {
        let (inner, handles) = concrete_host(&scene, false);
        let entries = Arc::new(AtomicUsize::new(0));
        let with = WithEntries {
            host: inner,
            entries: entries.clone(),
            fail,
        };
        let made = on_solver(&scene, Box::new(with), with_k, &opts);
        if fail && with_k {
            // Auto leaves the blocks to the library's factor of K.
            let mut pb = made.expect("the factor serves where the entries fail");
            assert_eq!(
                handles.calls.load(Ordering::SeqCst),
                0,
                "no solve at creation"
            );
            let sol = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
            assert_converged("blocks by the factor after the entries", &sol);
            assert_agree("blocks by the factor after the entries", &own, &sol, 1e-8);
            continue;
        }
        if fail {
            let e = made.err().expect("the entries call fails");
            assert_eq!(e.kind, ErrorKind::HostSolve);
            assert!(e.message.contains("code 9"), "{}", e.message);
            continue;
        }
        let mut pb = made.unwrap();
        assert_eq!(
            handles.calls.load(Ordering::SeqCst),
            0,
            "no solve at creation"
        );
        // Node-to-node contacts: 3 DOFs each, 6 pairs p <= q.
        assert_eq!(entries.load(Ordering::SeqCst), 6 * scene.m());
        let sol = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
        assert_converged("blocks from entries", &sol);
        kkt_of(&scene, friction, &sol).assert_ok("blocks from entries", 1e-8);
        assert_agree("blocks from entries", &own, &sol, 1e-8);
        // The same blocks as by solves (to rounding): the same iterations.
        let (mut by_solves, _) = on_host(&scene, with_k, false, &opts);
        let b = by_solves
            .solve(&scene.f, &scene.g, friction, &opts)
            .unwrap();
        assert_eq!(sol.report.outer_iterations, b.report.outer_iterations);
        assert_eq!(sol.report.inner_iterations, b.report.inner_iterations);
    }
}

/// `set_contacts` on the host's solves: the blocks are formed again for the
/// new contacts (the first half of the bottom nodes), and the answer is the
/// own path's with the same contacts.
#[test]
fn set_contacts_on_the_hosts_solves_matches_the_own_path() {
    let scene = scene_2d();
    let opts = with(Method::Auto);
    let (mut pb, handles) = on_host(&scene, true, false, &opts);
    let m = scene.m();
    let half = m / 2;
    // The first `half` rows of N and T (one tangent row per contact in 2D).
    let keep = |a: &dualsplit::Csc| {
        let mut b = a.clone();
        b.nrows = half;
        let mut p = vec![0usize];
        let (mut ri, mut vx) = (Vec::new(), Vec::new());
        for j in 0..a.ncols {
            for k in a.col_ptr[j]..a.col_ptr[j + 1] {
                if a.row_idx[k] < half {
                    ri.push(a.row_idx[k]);
                    vx.push(a.values[k]);
                }
            }
            p.push(ri.len());
        }
        b.col_ptr = p;
        b.row_idx = ri;
        b.values = vx;
        b
    };
    let (n2, t2) = (keep(&scene.n), keep(&scene.t));
    let before = handles.calls.load(Ordering::SeqCst);
    pb.set_contacts(&Owned::of(&n2).view(), &Owned::of(&t2).view())
        .unwrap();
    // d half right-hand sides, 32 per call.
    let blocks = handles.calls.load(Ordering::SeqCst) - before;
    assert_eq!(blocks, (2 * half).div_ceil(32));
    let g = &scene.g[..half];
    let mu = vec![0.3; half];
    let friction = Friction::Coulomb(&mu);
    let sol = pb.solve(&scene.f, g, friction, &opts).unwrap();
    assert_converged("set_contacts on the host", &sol);
    let mut own =
        dualsplit::ContactProblem::from_csc_with(2, scene.k.clone(), n2.clone(), t2.clone(), &opts)
            .unwrap();
    let want = own.solve(&scene.f, g, friction, &opts).unwrap();
    assert_converged("the own path", &want);
    assert_agree("set_contacts on the host", &want, &sol, 1e-8);
}

/// A host that counts the calls whose right-hand side is nonzero off the
/// contact DOFs: loads (a step's right-hand side, the recovery of u), not
/// products with A (B^T x lives on the contact DOFs).
struct LoadCounter {
    host: Host,
    contact: Vec<bool>,
    loads: Arc<AtomicUsize>,
}

impl KSolve for LoadCounter {
    fn n(&self) -> usize {
        self.host.n
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> Result<(), i32> {
        for col in x.chunks(self.host.n) {
            if col.iter().zip(&self.contact).any(|(v, &c)| *v != 0.0 && !c) {
                self.loads.fetch_add(1, Ordering::SeqCst);
            }
        }
        self.host.solve(x, ncols)
    }
}

/// A history whose loads lie in the span of the last loads solved for
/// (a proportional press, then a shear ramp at full press) takes its
/// right-hand side from their solutions (`load_span`): one load solve per
/// step (the recovery of u) where two are needed otherwise. Its answers
/// agree with the own path given the same loads with a component of 1e-12
/// off the span added (so that every step solves afresh), and with the own
/// path on the exact loads; K's equilibrium holds at every step.
#[test]
fn a_history_in_the_span_of_its_loads_solves_once_per_step() {
    let scene = scene_3d();
    let mu = vec![0.3; scene.m()];
    let friction = Friction::Coulomb(&mu);
    let opts = with(Method::Auto);
    let n = scene.k.nrows;
    let mut contact = vec![false; n];
    for b in [&scene.n, &scene.t] {
        for (j, touched) in contact.iter_mut().enumerate() {
            *touched |= b.col_ptr[j] < b.col_ptr[j + 1];
        }
    }
    let (h, _) = concrete_host(&scene, false);
    let loads = Arc::new(AtomicUsize::new(0));
    let counter = LoadCounter {
        host: h,
        contact,
        loads: loads.clone(),
    };
    let mut pb = on_solver(&scene, Box::new(counter), true, &opts).unwrap();
    let mut own = scene.problem();
    let mut fresh = scene.problem();
    // The shear: the press load's horizontal components.
    let shear: Vec<f64> = (0..n)
        .map(|i| if i % 3 == 2 { 0.0 } else { scene.f[i] })
        .collect();
    let mut expected = Vec::new();
    for step in 1..=6 {
        let (a, b) = if step <= 3 {
            (step as f64 / 3.0, 0.0)
        } else {
            (1.0, (step - 3) as f64 / 3.0)
        };
        let f: Vec<f64> = (0..n).map(|i| a * scene.f[i] + b * shear[i]).collect();
        let before = loads.load(Ordering::SeqCst);
        let sol = pb.step(&f, &scene.g, friction, &opts).unwrap();
        let w = format!("step {step}");
        assert_converged(&w, &sol);
        assert!(
            sol.report.equilibrium_residual < 1e-10,
            "{w}: {:?}",
            sol.report
        );
        let solved = loads.load(Ordering::SeqCst) - before;
        // Steps 1 and 4 leave the span (the first load, the turn to shear):
        // a solve of the load and the recovery; the others the recovery.
        expected.push(if step == 1 || step == 4 { 2 } else { 1 });
        assert_eq!(solved, expected[step - 1], "{w}: load solves");
        let a_own = own.step(&f, &scene.g, friction, &opts).unwrap();
        assert_agree(&format!("{w}, own path"), &a_own, &sol, 1e-8);
        // Off the span: 1e-12 step^2 of |f| at a DOF that f does not load
        // (not affine in the step, so no two loads span a third).
        let mut off = f.clone();
        let far = (0..n)
            .rev()
            .find(|&i| f[i] == 0.0)
            .expect("an unloaded DOF");
        off[far] += 1e-12 * (step * step) as f64 * norm_inf(&scene.f);
        let a_fresh = fresh.step(&off, &scene.g, friction, &opts).unwrap();
        assert_converged(&format!("{w}, fresh"), &a_fresh);
        assert_agree(&format!("{w}, solved afresh"), &a_fresh, &sol, 1e-8);
    }
}

/// A host that also solves in single precision (`KSolve::solve_single`):
/// here K^-1 x from its factor with a relative error of 1e-6 put on each
/// entry and the result rounded to single precision, rougher than a
/// single-precision factor's 1e-7. Single call number `fail_at` (from 1, 0
/// never) fails with code 5, or returns a NaN where `nan` is set.
struct Single {
    host: Host,
    singles: Arc<AtomicUsize>,
    fail_at: usize,
    nan: bool,
}

impl KSolve for Single {
    fn n(&self) -> usize {
        self.host.n
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> Result<(), i32> {
        self.host.solve(x, ncols)
    }

    fn solve_single(&mut self, x: &mut [f32], ncols: usize) -> Option<Result<(), i32>> {
        assert_eq!(x.len(), self.host.n * ncols, "the block is n x ncols");
        let call = self.singles.fetch_add(1, Ordering::SeqCst) + 1;
        if call == self.fail_at && !self.nan {
            return Some(Err(5));
        }
        for col in x.chunks_mut(self.host.n) {
            let mut z: Vec<f64> = col.iter().map(|&v| v as f64).collect();
            self.host.factor.solve_vec(&mut z);
            for (i, (c, v)) in col.iter_mut().zip(&z).enumerate() {
                *c = (v * (1.0 + 1e-6 * (i as f64).sin())) as f32;
            }
        }
        if call == self.fail_at {
            x[0] = f32::NAN;
        }
        Some(Ok(()))
    }
}

/// The scene's problem on a `Single` host (K handed over) and its counter of
/// single-precision calls.
fn on_single(scene: &Scene, fail_at: usize, nan: bool) -> (ContactProblem, Arc<AtomicUsize>) {
    let (host, _) = concrete_host(scene, false);
    let singles = Arc::new(AtomicUsize::new(0));
    let solver = Single {
        host,
        singles: singles.clone(),
        fail_at,
        nan,
    };
    let opts = Options {
        host_blocks: HostBlocks::Solves,
        ..with(Method::Newton)
    };
    let pb = on_solver(scene, Box::new(solver), true, &opts).expect("a valid host problem");
    (pb, singles)
}

/// With the host's single-precision solve, Newton's loose products are
/// single-precision calls, and the answer still passes the KKT check and
/// agrees with the own path (Tresca and Coulomb, two history steps, then a
/// single solve checked against the KKT conditions); the report counts every
/// call of either precision.
#[test]
fn a_hosts_single_precision_solve_serves_the_loose_products() {
    let scene = scene_3d();
    let (mu, p) = (vec![0.3; scene.m()], vec![0.05; scene.m()]);
    let opts = with(Method::Newton);
    for (name, friction) in [
        ("Tresca", Friction::Tresca(&p)),
        ("Coulomb", Friction::Coulomb(&mu)),
    ] {
        let mut own = scene.problem();
        let (mut pb, singles) = on_single(&scene, 0, false);
        for step in 1..=2 {
            let f: Vec<f64> = scene.f.iter().map(|v| v * step as f64 / 2.0).collect();
            let want = own.step(&f, &scene.g, friction, &opts).unwrap();
            let before = singles.load(Ordering::SeqCst);
            let sol = pb.step(&f, &scene.g, friction, &opts).unwrap();
            let used = singles.load(Ordering::SeqCst) - before;
            let w = format!("{name} step {step}");
            println!(
                "{w}: {used} single-precision calls of {} host solves, err {:.2e}",
                sol.report.host_solves, sol.report.err
            );
            assert_converged(&w, &sol);
            assert!(used > 0, "{w}: no single-precision call");
            assert!(sol.report.host_solves > used, "{w}: exact solves too");
            assert_agree(&w, &want, &sol, 1e-8);
        }
        // A single solve of the whole load: the KKT point.
        let before = singles.load(Ordering::SeqCst);
        let sol = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
        assert_converged(name, &sol);
        assert!(
            singles.load(Ordering::SeqCst) > before,
            "{name}: no single-precision call"
        );
        kkt_of(&scene, friction, &sol).assert_ok(name, 1e-8);
    }
}

/// A single-precision solve that fails (code 5, or a NaN) ends the solve
/// with `HostSolve` naming it; the next solve succeeds.
#[test]
fn a_failing_single_precision_solve_is_an_error_and_the_problem_stays_usable() {
    let scene = scene_3d();
    let p = vec![0.05; scene.m()];
    let friction = Friction::Tresca(&p);
    let opts = with(Method::Newton);
    let want = scene
        .problem()
        .solve(&scene.f, &scene.g, friction, &opts)
        .unwrap();
    for nan in [false, true] {
        let (mut pb, _) = on_single(&scene, 1, nan);
        let e = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap_err();
        assert_eq!(e.kind, ErrorKind::HostSolve, "{e}");
        assert!(e.message.contains("single precision"), "{}", e.message);
        let what = if nan { "returned NaN" } else { "code 5" };
        assert!(e.message.contains(what), "{}", e.message);
        let again = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
        assert_converged("the solve again", &again);
        assert_agree("the solve again", &want, &again, 1e-8);
    }
}

/// What a `Rows` host saw: calls on rows (all, approximate ones), the
/// fewest rows of a call, and the failure to give (the call number, from
/// 1, 0 never; code 6, or a NaN where `nan`).
#[derive(Default)]
struct RowsLog {
    calls: AtomicUsize,
    approximate: AtomicUsize,
    fewest: AtomicUsize,
    fail_at: AtomicUsize,
}

/// A host that also solves on rows (`KSolve::solve_rows`) the way any host
/// may: the entries scattered into an n-vector, a whole solve, the rows
/// gathered; an approximate answer with a relative error of 1e-6 put on
/// each entry. It checks the library's side of the contract: rows
/// ascending and distinct, x rows.len() x ncols.
struct Rows {
    host: Host,
    log: Arc<RowsLog>,
    nan: bool,
}

impl KSolve for Rows {
    fn n(&self) -> usize {
        self.host.n
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> Result<(), i32> {
        self.host.solve(x, ncols)
    }

    fn solve_rows(
        &mut self,
        rows: &[usize],
        x: &mut [f64],
        ncols: usize,
        approximate: bool,
    ) -> Option<Result<(), i32>> {
        assert!(
            rows.windows(2).all(|w| w[0] < w[1]),
            "rows ascending, distinct"
        );
        assert!(rows.last().is_none_or(|&r| r < self.host.n));
        assert_eq!(x.len(), rows.len() * ncols, "the block is rows x ncols");
        let log = &self.log;
        let call = log.calls.fetch_add(1, Ordering::SeqCst) + 1;
        log.approximate
            .fetch_add(usize::from(approximate), Ordering::SeqCst);
        log.fewest.fetch_min(rows.len(), Ordering::SeqCst);
        let failing = call == log.fail_at.load(Ordering::SeqCst);
        if failing && !self.nan {
            return Some(Err(6));
        }
        let mut z = vec![0.0; self.host.n];
        for col in x.chunks_mut(rows.len().max(1)) {
            z.iter_mut().for_each(|v| *v = 0.0);
            rows.iter().zip(col.iter()).for_each(|(&r, &v)| z[r] = v);
            self.host.factor.solve_vec(&mut z);
            for (k, (&r, c)) in rows.iter().zip(col.iter_mut()).enumerate() {
                let e = if approximate {
                    1e-6 * (k as f64).sin()
                } else {
                    0.0
                };
                *c = z[r] * (1.0 + e);
            }
        }
        if failing {
            x[0] = f64::NAN;
        }
        Some(Ok(()))
    }
}

/// The scene's problem on a `Rows` host (K handed over), its log and its
/// counter of whole solves.
fn on_rows(scene: &Scene, nan: bool) -> (ContactProblem, Arc<RowsLog>, Arc<AtomicUsize>) {
    let (host, handles) = concrete_host(scene, false);
    let log = Arc::new(RowsLog {
        fewest: AtomicUsize::new(usize::MAX),
        ..RowsLog::default()
    });
    let solver = Rows {
        host,
        log: log.clone(),
        nan,
    };
    let opts = Options {
        host_blocks: HostBlocks::Solves,
        ..with(Method::Newton)
    };
    let pb = on_solver(scene, Box::new(solver), true, &opts).expect("a valid host problem");
    (pb, log, handles.calls)
}

/// With the host's solve on rows, every product with A is a call on rows
/// (the loose ones approximate; none at creation, where the contact blocks
/// take whole solves of many columns), and the whole solves are left to the
/// loads: at most three per step (the right-hand side, the recovery of u,
/// and the load span's). The answers agree with the own path (Tresca and
/// Coulomb, two history steps) and a single solve passes the KKT check.
#[test]
fn a_hosts_solve_on_rows_serves_the_products_and_the_blocks() {
    let scene = scene_3d();
    let contact_dofs =
        dualsplit::internals::contact_dofs(&dualsplit::internals::stack_rows(&scene.n, &scene.t))
            .len();
    let (mu, p) = (vec![0.3; scene.m()], vec![0.05; scene.m()]);
    let opts = with(Method::Newton);
    for (name, friction) in [
        ("Tresca", Friction::Tresca(&p)),
        ("Coulomb", Friction::Coulomb(&mu)),
    ] {
        let mut own = scene.problem();
        let (mut pb, log, whole) = on_rows(&scene, false);
        assert!(
            whole.load(Ordering::SeqCst) > 0,
            "{name}: the blocks by solves"
        );
        assert_eq!(
            log.calls.load(Ordering::SeqCst),
            0,
            "{name}: a call on rows at creation"
        );
        for step in 1..=2 {
            let f: Vec<f64> = scene.f.iter().map(|v| v * step as f64 / 2.0).collect();
            let want = own.step(&f, &scene.g, friction, &opts).unwrap();
            let (calls, loose, wholes) = (
                log.calls.load(Ordering::SeqCst),
                log.approximate.load(Ordering::SeqCst),
                whole.load(Ordering::SeqCst),
            );
            let sol = pb.step(&f, &scene.g, friction, &opts).unwrap();
            let w = format!("{name} step {step}");
            let on_rows = log.calls.load(Ordering::SeqCst) - calls;
            let loose = log.approximate.load(Ordering::SeqCst) - loose;
            let wholes = whole.load(Ordering::SeqCst) - wholes;
            println!(
                "{w}: {on_rows} calls on rows ({loose} approximate, the fewest rows {} of \
                 {contact_dofs}), {wholes} whole solves, err {:.2e}",
                log.fewest.load(Ordering::SeqCst),
                sol.report.err
            );
            assert_converged(&w, &sol);
            assert!(on_rows > 0 && loose > 0, "{w}: products on rows");
            assert!((1..=3).contains(&wholes), "{w}: {wholes} whole solves");
            assert_eq!(
                sol.report.host_solves,
                on_rows + wholes,
                "{w}: every call counted"
            );
            assert_agree(&w, &want, &sol, 1e-8);
        }
        let sol = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
        assert_converged(name, &sol);
        kkt_of(&scene, friction, &sol).assert_ok(name, 1e-8);
    }
}

/// A solve on rows that fails (code 6, or a NaN) ends the solve with
/// `HostSolve` naming it; the next solve succeeds.
#[test]
fn a_failing_solve_on_rows_is_an_error_and_the_problem_stays_usable() {
    let scene = scene_3d();
    let p = vec![0.05; scene.m()];
    let friction = Friction::Tresca(&p);
    let opts = with(Method::Newton);
    let want = scene
        .problem()
        .solve(&scene.f, &scene.g, friction, &opts)
        .unwrap();
    for nan in [false, true] {
        let (mut pb, log, _) = on_rows(&scene, nan);
        log.fail_at
            .store(log.calls.load(Ordering::SeqCst) + 1, Ordering::SeqCst);
        let e = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap_err();
        assert_eq!(e.kind, ErrorKind::HostSolve, "{e}");
        assert!(e.message.contains("on rows"), "{}", e.message);
        let what = if nan { "returned NaN" } else { "code 6" };
        assert!(e.message.contains(what), "{}", e.message);
        let again = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
        assert_converged("the solve again", &again);
        assert_agree("the solve again", &want, &again, 1e-8);
    }
}

/// The scene's problem on a host with the contact blocks asked `how`
/// (`Options::host_blocks`), with K handed over where `with_k`, and its
/// counter of solves.
fn on_blocks(
    scene: &Scene,
    how: HostBlocks,
    with_k: bool,
    opts: &Options,
) -> (dualsplit::Result<ContactProblem>, Arc<AtomicUsize>) {
    let (host, handles) = concrete_host(scene, false);
    let opts = Options {
        host_blocks: how,
        ..*opts
    };
    let pb = on_solver(scene, Box::new(host), with_k, &opts);
    (pb, handles.calls)
}

/// The contacts' blocks by the library's own factor of K
/// (`HostBlocks::Factor`, and `Auto` on these small scenes, where the
/// factor's flops are fewer than the solves'): no host solve at creation
/// nor at `set_contacts`, and the answers are the own path's (a history of
/// two steps in 3D, Coulomb; the 2D scene's first half of contacts after
/// `set_contacts`) and pass the KKT check. `Factor` without K is refused
/// with `BadArgument`; `Auto` without K takes the host's solves.
#[test]
fn the_contact_blocks_by_the_librarys_own_factor_of_k() {
    let scene = scene_3d();
    let mu = vec![0.3; scene.m()];
    let friction = Friction::Coulomb(&mu);
    let opts = with(Method::Auto);
    for how in [HostBlocks::Factor, HostBlocks::Auto] {
        let (pb, calls) = on_blocks(&scene, how, true, &opts);
        let mut pb = pb.expect("a valid host problem");
        assert_eq!(
            calls.load(Ordering::SeqCst),
            0,
            "{how:?}: a solve at creation"
        );
        let mut own = scene.problem();
        for step in 1..=2 {
            let f: Vec<f64> = scene.f.iter().map(|v| v * step as f64 / 2.0).collect();
            let want = own.step(&f, &scene.g, friction, &opts).unwrap();
            let sol = pb.step(&f, &scene.g, friction, &opts).unwrap();
            let w = format!("{how:?} step {step}");
            assert_converged(&w, &sol);
            assert_agree(&w, &want, &sol, 1e-8);
        }
        let sol = pb.solve(&scene.f, &scene.g, friction, &opts).unwrap();
        kkt_of(&scene, friction, &sol).assert_ok(&format!("{how:?}"), 1e-8);
    }
    let (pb, _) = on_blocks(&scene, HostBlocks::Factor, false, &opts);
    let Err(e) = pb else {
        panic!("HostBlocks::Factor without K must be refused");
    };
    assert_eq!(e.kind, ErrorKind::BadArgument, "{e}");
    assert!(e.message.contains("need K handed over"), "{}", e.message);
    let (pb, calls) = on_blocks(&scene, HostBlocks::Auto, false, &opts);
    pb.expect("a valid host problem");
    assert!(
        calls.load(Ordering::SeqCst) > 0,
        "Auto without K: by solves"
    );

    // set_contacts: the blocks of the new contacts by the factor again.
    let scene = scene_2d();
    let half = scene.m() / 2;
    let (n2, t2) = (first_rows(&scene.n, half), first_rows(&scene.t, half));
    let (pb, calls) = on_blocks(&scene, HostBlocks::Factor, true, &opts);
    let mut pb = pb.expect("a valid host problem");
    pb.set_contacts(&Owned::of(&n2).view(), &Owned::of(&t2).view())
        .unwrap();
    assert_eq!(calls.load(Ordering::SeqCst), 0, "a solve at set_contacts");
    let (g, mu) = (&scene.g[..half], vec![0.3; half]);
    let friction = Friction::Coulomb(&mu);
    let sol = pb.solve(&scene.f, g, friction, &opts).unwrap();
    let mut own =
        dualsplit::ContactProblem::from_csc_with(2, scene.k.clone(), n2, t2, &opts).unwrap();
    let want = own.solve(&scene.f, g, friction, &opts).unwrap();
    assert_converged("set_contacts, blocks by the factor", &sol);
    assert_agree("set_contacts, blocks by the factor", &want, &sol, 1e-8);
}

/// An interface law on the host's solves: with it set after creation, again
/// after `set_contacts` (another m makes every contact rigid) and across a
/// history step, the answers are the own path's with the same law, on the
/// own path in both dual forms (a form switch keeps the law).
#[test]
fn compliance_on_the_hosts_solves_matches_the_own_path() {
    let scene = scene_3d();
    let m = scene.m();
    let mu = vec![0.3; m];
    let friction = Friction::Coulomb(&mu);
    let opts = with(Method::Auto);
    // Every other contact compliant in both directions, one on a power law.
    let cn: Vec<f64> = (0..m)
        .map(|i| if i % 2 == 0 { 300.0 } else { f64::INFINITY })
        .collect();
    let kt: Vec<f64> = (0..m)
        .map(|i| if i % 2 == 0 { 150.0 } else { f64::INFINITY })
        .collect();
    let mut mn = vec![1.0; m];
    mn[0] = 1.5;
    let (mut host, _) = on_host(&scene, true, false, &opts);
    host.set_compliance(Some(&cn), Some(&mn), Some(&kt))
        .unwrap();
    let mut own = scene.problem();
    own.set_compliance(Some(&cn), Some(&mn), Some(&kt)).unwrap();
    let dense = Options {
        dual_form: DualForm::Dense,
        ..opts
    };
    for (name, o) in [("matrix-free", &opts), ("dense", &dense)] {
        let want = own.solve(&scene.f, &scene.g, friction, o).unwrap();
        let got = host.solve(&scene.f, &scene.g, friction, &opts).unwrap();
        let w = format!("compliant, own {name}");
        assert_converged(&w, &want);
        assert_converged(&w, &got);
        assert_eq!(got.report.compliant_contacts, m.div_ceil(2));
        assert_agree(&w, &want, &got, 1e-8);
    }
    // Two history steps: the elastic slip carries over alike; after a reset
    // the first step again.
    let half_load: Vec<f64> = scene.f.iter().map(|v| v / 2.0).collect();
    let mut first = None;
    for step in 1..=2 {
        let f: Vec<f64> = scene.f.iter().map(|v| v * step as f64 / 2.0).collect();
        let want = own.step(&f, &scene.g, friction, &opts).unwrap();
        let got = host.step(&f, &scene.g, friction, &opts).unwrap();
        assert_agree(&format!("compliant step {step}"), &want, &got, 1e-8);
        first.get_or_insert(got);
    }
    host.reset_history();
    let again = host.step(&half_load, &scene.g, friction, &opts).unwrap();
    assert_agree(
        "the first step after a reset",
        first.as_ref().unwrap(),
        &again,
        1e-10,
    );
    // New contacts (the first half): rigid again, then a law for them.
    let half = m / 2;
    let (n2, t2) = (first_rows(&scene.n, half), first_rows(&scene.t, 2 * half));
    host.set_contacts(&Owned::of(&n2).view(), &Owned::of(&t2).view())
        .unwrap();
    let mut own2 =
        dualsplit::ContactProblem::from_csc_with(3, scene.k.clone(), n2, t2, &opts).unwrap();
    let (g, mu2) = (&scene.g[..half], vec![0.3; half]);
    let friction = Friction::Coulomb(&mu2);
    let got = host.solve(&scene.f, g, friction, &opts).unwrap();
    assert_eq!(got.report.compliant_contacts, 0, "set_contacts: rigid");
    host.set_compliance(Some(&cn[..half]), None, Some(&kt[..half]))
        .unwrap();
    own2.set_compliance(Some(&cn[..half]), None, Some(&kt[..half]))
        .unwrap();
    let want = own2.solve(&scene.f, g, friction, &opts).unwrap();
    let got = host.solve(&scene.f, g, friction, &opts).unwrap();
    assert_converged("compliant after set_contacts", &got);
    assert_agree("compliant after set_contacts", &want, &got, 1e-8);
}
