//! The default log sink (stderr) where stderr cannot be written: a solve with
//! logging on and no sink, while fd 2 is a pipe whose reader is gone (writes
//! fail with EPIPE; Rust programs ignore SIGPIPE), still converges and returns
//! DS_STATUS_OK. With eprintln! the first log line panicked and the solve
//! returned DS_STATUS_PANIC after it had converged. A program of its own
//! (`harness = false` in Cargo.toml): fd 2 is the process's, no other test may
//! print while it is replaced, and the test harness would capture eprintln!'s
//! output before it reached fd 2.

mod common;

use common::{Mesh, Owned, Scene};
use dualsplit::internals::ffi::{
    DsProblem, DsReport, DsStatus, ds_problem_free, ds_problem_new, ds_problem_set_log, ds_solve,
};

fn main() {
    logging_to_a_broken_stderr_does_not_fail_the_solve();
    println!("test logging_to_a_broken_stderr_does_not_fail_the_solve ... ok");
}

fn logging_to_a_broken_stderr_does_not_fail_the_solve() {
    let sc = Scene::pressed_block(Mesh::grid2d(16, 4, 2.0, 1.0), &[0.006, -0.02], 0.05, &[1.0]);
    let (k, n, t) = (Owned::of(&sc.k), Owned::of(&sc.n), Owned::of(&sc.t));
    let mut h: *mut DsProblem = std::ptr::null_mut();
    // SAFETY: valid matrices and out pointer.
    assert_eq!(
        unsafe { ds_problem_new(2, &k.ds(), &n.ds(), &t.ds(), &mut h) },
        DsStatus::Ok
    );
    // SAFETY: a live handle; level 2 (every iteration), no sink: stderr.
    assert_eq!(
        unsafe { ds_problem_set_log(h, 2, None, std::ptr::null_mut()) },
        DsStatus::Ok
    );
    let mu = vec![0.3; sc.m()];
    let (mut u, mut ln, mut lt) = (vec![0.0; sc.f.len()], vec![0.0; sc.m()], vec![0.0; sc.m()]);
    // SAFETY: DsReport is plain old data; zero is a value.
    let mut rep: DsReport = unsafe { std::mem::zeroed() };
    // fd 2 onto the write end of a pipe whose read end is closed.
    let mut fds = [0i32; 2];
    // SAFETY: pipe writes two descriptors into the array it is given.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    // SAFETY: plain descriptor calls on descriptors this test owns (and fd 2,
    // saved and restored below).
    let saved = unsafe {
        let saved = libc::dup(2);
        libc::close(fds[0]);
        libc::dup2(fds[1], 2);
        libc::close(fds[1]);
        saved
    };
    // SAFETY: a live handle and arrays of the problem's sizes.
    let status = unsafe {
        ds_solve(
            h,
            std::ptr::null(),
            1,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            mu.as_ptr(),
            u.as_mut_ptr(),
            ln.as_mut_ptr(),
            lt.as_mut_ptr(),
            &mut rep,
        )
    };
    // SAFETY: restores fd 2 from the saved copy.
    unsafe {
        libc::dup2(saved, 2);
        libc::close(saved);
    }
    assert_eq!(status, DsStatus::Ok, "{rep:?}");
    assert!(rep.err <= 1e-8, "{rep:?}");
    assert!(rep.outer_iterations > 0);
    // SAFETY: the handle from ds_problem_new, freed once.
    unsafe { ds_problem_free(h) };
}
