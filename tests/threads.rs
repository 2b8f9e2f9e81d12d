//! Several handles used at once from several threads. The documented rule
//! (src/ffi/problem.rs): a handle may be used from any thread, by one thread at a
//! time; distinct handles are independent; the last error message is per thread.
//!
//! Checked: the same solves done concurrently on distinct handles (one per thread,
//! different methods, Tresca and Coulomb, history steps, interleaved errors) give
//! results bit-identical to the same solves done one after another, and each
//! thread sees its own last error message. A handle moved to another thread (used
//! there alone) gives the same bits as well.

mod common;

use common::{Mesh, Owned, Scene};
use dualsplit::internals::ffi::*;
use std::ffi::CStr;
use std::ptr::{null, null_mut};
use std::sync::{Arc, Barrier};

/// Scenes of different sizes and dimensions.
fn scenes() -> Vec<Scene> {
    let mut out = Vec::new();
    for (nx, shear) in [(6, 0.004), (10, 0.006), (8, -0.003)] {
        let mesh = Mesh::grid2d(nx, 3, 2.0, 1.0);
        out.push(Scene::pressed_block(mesh, &[shear, -0.02], 0.05, &[1.0]));
    }
    let mesh = Mesh::grid3d(3, 3, 2, 2.0, 2.0, 1.0);
    out.push(Scene::pressed_block(
        mesh,
        &[0.006, 0.003, -0.03],
        0.05,
        &[1.0, 1.0],
    ));
    out
}

/// Everything one job produces, as raw bits.
#[derive(Debug, PartialEq, Eq)]
struct Bits(Vec<u64>);

fn push(out: &mut Vec<u64>, x: &[f64]) {
    out.extend(x.iter().map(|v| v.to_bits()));
}

const METHODS: [DsMethod; 4] = [
    DsMethod::Split,
    DsMethod::BlockGs,
    DsMethod::Pgs,
    DsMethod::Newton,
];

fn last_message() -> String {
    // SAFETY: non-NULL, NUL-terminated, valid until the next ds_ call here.
    unsafe { CStr::from_ptr(ds_last_error_message()) }
        .to_string_lossy()
        .into_owned()
}

/// One job: create a handle for `sc`, solve with `method` (Tresca and Coulomb),
/// provoke an error (checking the message of this thread), run a 3-step history,
/// refactor, solve again; free. Returns every output and report number as bits.
/// `tag` makes this job's bad input, and so its error message, its own.
fn job(sc: &Scene, method: DsMethod, tag: usize, barrier: Option<&Barrier>) -> Bits {
    let (k, n, t) = (Owned::of(&sc.k), Owned::of(&sc.n), Owned::of(&sc.t));
    let d = sc.d as i32;
    let m = sc.m();
    let nt = (sc.d - 1) * m;
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: matrices outlive the call.
    let s = unsafe { ds_problem_new(d, &k.ds(), &n.ds(), &t.ds(), &mut h) };
    assert_eq!(s, DsStatus::Ok, "{}", last_message());
    if let Some(b) = barrier {
        b.wait();
    }
    let mut o = DsOptions::default();
    // SAFETY: o is a whole, writable DsOptions.
    let st = unsafe { ds_options_init(&mut o, std::mem::size_of::<DsOptions>()) };
    assert_eq!(st, DsStatus::Ok);
    o.method = method as i32;
    let mut out = Vec::new();
    let p = vec![0.02; m];
    let mu = vec![0.3; m];
    let mut u = vec![0.0; sc.k.nrows];
    let mut ln = vec![0.0; m];
    let mut lt = vec![0.0; nt];
    let mut rep = std::mem::MaybeUninit::<DsReport>::zeroed();
    let record = |out: &mut Vec<u64>, u: &[f64], ln: &[f64], lt: &[f64], r: &DsReport| {
        push(out, u);
        push(out, ln);
        push(out, lt);
        push(out, &[r.err, r.equilibrium_residual]);
        out.extend([
            r.outer_iterations as u64,
            r.inner_iterations as u64,
            r.n_open as u64,
            r.n_stick as u64,
            r.n_slip as u64,
        ]);
    };
    type Entry = unsafe extern "C" fn(
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
    let mut call =
        |entry: Entry, friction: DsFriction, bound: &[f64], f: &[f64], out: &mut Vec<u64>| {
            // SAFETY: arrays sized for the problem; rep is a DsReport location.
            let s = unsafe {
                entry(
                    h,
                    &o,
                    friction as i32,
                    f.as_ptr(),
                    sc.g.as_ptr(),
                    bound.as_ptr(),
                    u.as_mut_ptr(),
                    ln.as_mut_ptr(),
                    lt.as_mut_ptr(),
                    rep.as_mut_ptr(),
                )
            };
            assert_eq!(s, DsStatus::Ok, "{}", last_message());
            // SAFETY: written by the successful call.
            let r = unsafe { rep.assume_init_ref() };
            record(out, &u, &ln, &lt, r);
        };
    call(ds_solve, DsFriction::Tresca, &p, &sc.f, &mut out);
    call(ds_solve, DsFriction::Coulomb, &mu, &sc.f, &mut out);
    // An error on this thread, with a bad input of its own: its message must name
    // exactly this thread's culprit (a shared message would name another's).
    let mut neg = p.clone();
    let bad_at = tag % m;
    let bad = -(1.0 + tag as f64);
    neg[bad_at] = bad;
    let mut junk = vec![0.0; sc.k.nrows.max(nt).max(m)];
    // SAFETY: arrays long enough.
    let s = unsafe {
        ds_solve(
            h,
            &o,
            DsFriction::Tresca as i32,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            neg.as_ptr(),
            junk.as_mut_ptr(),
            junk.as_mut_ptr(),
            junk.as_mut_ptr(),
            null_mut(),
        )
    };
    assert_eq!(s, DsStatus::NegativeFriction);
    let msg = last_message();
    let culprit = format!("p[{bad_at}] = {bad} is negative");
    assert!(
        msg.contains(&culprit),
        "this thread's message: {msg}, expected {culprit}"
    );
    // A history of three steps with growing load.
    // SAFETY: h is live.
    assert_eq!(unsafe { ds_history_reset(h) }, DsStatus::Ok);
    for s in [0.5, 1.0, 0.7] {
        let f: Vec<f64> = sc.f.iter().map(|v| v * s).collect();
        call(ds_step, DsFriction::Coulomb, &mu, &f, &mut out);
    }
    // Refactor with 2 K and solve again.
    let mut k2 = Owned::of(&sc.k);
    k2.x.iter_mut().for_each(|v| *v *= 2.0);
    // SAFETY: h is live; same pattern.
    assert_eq!(unsafe { ds_problem_refactor(h, &k2.ds()) }, DsStatus::Ok);
    call(ds_solve, DsFriction::Coulomb, &mu, &sc.f, &mut out);
    let _ = null::<f64>();
    // SAFETY: freed once.
    unsafe { ds_problem_free(h) };
    Bits(out)
}

#[test]
fn concurrent_handles_are_bit_identical_to_sequential() {
    let scenes = Arc::new(scenes());
    let jobs: Vec<(usize, DsMethod)> = (0..scenes.len())
        .flat_map(|s| METHODS.into_iter().map(move |m| (s, m)))
        .collect();
    // Sequential reference.
    let sequential: Vec<Bits> = jobs
        .iter()
        .enumerate()
        .map(|(q, &(s, m))| job(&scenes[s], m, q, None))
        .collect();
    // Concurrent, twice, all jobs released together.
    for round in 0..2 {
        let barrier = Arc::new(Barrier::new(jobs.len()));
        let handles: Vec<_> = jobs
            .iter()
            .enumerate()
            .map(|(q, &(s, m))| {
                let scenes = Arc::clone(&scenes);
                let barrier = Arc::clone(&barrier);
                std::thread::spawn(move || job(&scenes[s], m, q, Some(&barrier)))
            })
            .collect();
        for (q, h) in handles.into_iter().enumerate() {
            let bits = h.join().expect("thread panicked");
            assert_eq!(
                bits, sequential[q],
                "round {round}: job {q} ({:?}) differs from the sequential run",
                jobs[q]
            );
        }
    }
}

#[test]
fn last_error_is_per_thread() {
    // Thread A fails (negative d), thread B succeeds; each sees its own message.
    let barrier = Arc::new(Barrier::new(2));
    let b1 = Arc::clone(&barrier);
    let a = std::thread::spawn(move || {
        let mut h: *mut DsProblem = null_mut();
        // SAFETY: rejected before the matrices are read (d is checked first or the
        // NULL matrix is reported); out is a valid location.
        let s = unsafe { ds_problem_new(7, null(), null(), null(), &mut h) };
        assert_ne!(s, DsStatus::Ok);
        b1.wait();
        b1.wait();
        last_message()
    });
    let b2 = Arc::clone(&barrier);
    let b = std::thread::spawn(move || {
        b2.wait();
        let sc = &scenes()[0];
        let bits = job(sc, DsMethod::Split, 0, None);
        let msg = last_message();
        b2.wait();
        (bits, msg)
    });
    let msg_a = a.join().unwrap();
    let (_, msg_b) = b.join().unwrap();
    assert!(!msg_a.is_empty(), "thread A lost its message");
    assert_eq!(
        msg_b, "",
        "thread B sees a message after its successful calls"
    );
}

#[test]
fn handle_moved_between_threads() {
    // Created on one thread, used on another (one at a time): same bits.
    struct Send_(*mut DsProblem);
    // SAFETY: the handle is used by one thread at a time, as documented.
    unsafe impl Send for Send_ {}
    let sc = scenes().remove(3);
    let (k, n, t) = (Owned::of(&sc.k), Owned::of(&sc.n), Owned::of(&sc.t));
    let mut h: *mut DsProblem = null_mut();
    // SAFETY: matrices outlive the call.
    let s = unsafe { ds_problem_new(3, &k.ds(), &n.ds(), &t.ds(), &mut h) };
    assert_eq!(s, DsStatus::Ok);
    let run = move |h: Send_| -> (Send_, Vec<u64>) {
        let m = sc.m();
        let mu = vec![0.3; m];
        let mut u = vec![0.0; sc.k.nrows];
        let (mut ln, mut lt) = (vec![0.0; m], vec![0.0; 2 * m]);
        // SAFETY: arrays sized for the problem.
        let s = unsafe {
            ds_solve(
                h.0,
                null(),
                DsFriction::Coulomb as i32,
                sc.f.as_ptr(),
                sc.g.as_ptr(),
                mu.as_ptr(),
                u.as_mut_ptr(),
                ln.as_mut_ptr(),
                lt.as_mut_ptr(),
                null_mut(),
            )
        };
        assert_eq!(s, DsStatus::Ok);
        let mut out = Vec::new();
        push(&mut out, &u);
        push(&mut out, &ln);
        push(&mut out, &lt);
        (h, out)
    };
    let run = Arc::new(run);
    let (h, here) = run(Send_(h));
    let r2 = Arc::clone(&run);
    let (h, there) = std::thread::spawn(move || r2(h)).join().unwrap();
    assert_eq!(here, there);
    // SAFETY: freed once.
    unsafe { ds_problem_free(h.0) };
}
