//! An allocation sized by caller data that fails after the first one succeeded must
//! still be DS_STATUS_OUT_OF_MEMORY, not an abort (which `catch_unwind` cannot
//! catch). The test runs itself again as a child process under an address-space
//! limit of 3 GiB (setrlimit), and hands ds_problem_new a K of 250 million rows
//! with one entry: its first index array (2 GB) fits, a second one does not.

use dualsplit::internals::ffi::*;
use std::process::Command;
use std::ptr::null_mut;

const CHILD: &str = "DUALSPLIT_OOM_CHILD";
const ROWS: i64 = 250_000_000;

fn coo(nrows: i64, ncols: i64, nnz: i64, p: &[i64], i: &[i64], x: &[f64]) -> DsMatrix {
    DsMatrix {
        format: DsFormat::Coo as i32,
        index_type: DsIndexType::I64 as i32,
        base: 0,
        storage: DsStorage::Full as i32,
        nrows,
        ncols,
        nnz,
        p: p.as_ptr().cast(),
        i: i.as_ptr().cast(),
        x: x.as_ptr(),
    }
}

fn child() {
    let limit = libc::rlimit {
        rlim_cur: 3 << 30,
        rlim_max: 3 << 30,
    };
    // SAFETY: setrlimit reads the struct and changes this (child) process only.
    let rc = unsafe { libc::setrlimit(libc::RLIMIT_AS, &limit) };
    assert_eq!(rc, 0, "setrlimit");
    let (p, i, x) = ([0i64], [0i64], [1.0]);
    let k = coo(ROWS, ROWS, 1, &p, &i, &x);
    let n = coo(0, ROWS, 0, &[], &[], &[]);
    let mut out: *mut DsProblem = null_mut();
    // SAFETY: the arrays hold nnz entries; out is a valid location.
    let s = unsafe { ds_problem_new(2, &k, &n, &n, &mut out) };
    // SAFETY: a static or thread-local NUL-terminated string.
    let msg = unsafe { std::ffi::CStr::from_ptr(ds_last_error_message()) };
    println!("CHILD status {s:?}: {}", msg.to_string_lossy());
    assert!(out.is_null());
}

#[test]
fn a_later_allocation_that_fails_is_out_of_memory() {
    if std::env::var(CHILD).is_ok() {
        child();
        return;
    }
    let exe = std::env::current_exe().unwrap();
    let out = Command::new(exe)
        .args([
            "--exact",
            "a_later_allocation_that_fails_is_out_of_memory",
            "--test-threads=1",
            "--nocapture",
        ])
        .env(CHILD, "1")
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(
        out.status.success(),
        "the child died ({:?}):\n{stdout}\n{stderr}",
        out.status
    );
    assert!(
        stdout.contains("CHILD status OutOfMemory"),
        "{stdout}\n{stderr}"
    );
}
