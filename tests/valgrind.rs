//! The C demo (c_examples/block2d.c, small mesh), the bad-input C program
//! (c_examples/bad_input.c) and the nonlinear host (c_examples/
//! hyperelastic_host.c, small meshes in 2D and 3D: a refactor and a
//! ds_solve_iteration per Newton iteration) under valgrind memcheck, built
//! against the static library cargo built for this test run:
//!
//!     valgrind --error-exitcode=1 --leak-check=full --errors-for-leak-kinds=definite
//!
//! Asserted: exit status 0 (the programs' own checks pass and valgrind found no
//! error), "ERROR SUMMARY: 0 errors" and no "definitely lost" bytes. ("Possibly
//! lost" blocks are the thread stacks of the global thread pool of the numerical
//! backend, which lives until exit; they are not errors here.)
//!
//! Without valgrind the test prints `SKIPPED: ...` and passes; with CI=true it
//! fails (.ci/run installs valgrind).

mod ctools;

use std::path::{Path, PathBuf};
use std::process::Command;

fn build(src: &str, exe_name: &str) -> PathBuf {
    let root = ctools::manifest_dir();
    let out = ctools::out_dir("valgrind");
    let exe = out.join(exe_name);
    let mut cmd = ctools::c_compiler();
    cmd.args(["-std=c99", "-Wall", "-Wextra", "-g", "-O1"])
        .arg("-I")
        .arg(root.join("include"))
        .arg("-I")
        .arg(root.join("c_examples"))
        .arg(root.join("c_examples").join(src))
        .arg(ctools::static_lib())
        .args(ctools::SYSTEM_LIBS)
        .arg("-o")
        .arg(&exe);
    ctools::run_ok(&mut cmd, &format!("compile {src}"));
    exe
}

fn memcheck(exe: &Path, args: &[&str]) {
    let out = Command::new("valgrind")
        .args([
            "--error-exitcode=1",
            "--leak-check=full",
            "--errors-for-leak-kinds=definite",
        ])
        .arg(exe)
        .args(args)
        .output()
        .expect("run valgrind");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let what = format!("valgrind {} {}", exe.display(), args.join(" "));
    println!("---- {what}\n{stdout}");
    eprintln!("{stderr}");
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{stdout}\n{stderr}",
        out.status
    );
    assert!(
        stderr.contains("ERROR SUMMARY: 0 errors"),
        "{what}: memcheck errors:\n{stderr}"
    );
    let definite = stderr
        .lines()
        .find(|l| l.contains("definitely lost:"))
        .unwrap_or("");
    assert!(
        definite.is_empty() || definite.contains("definitely lost: 0 bytes"),
        "{what}: {definite}"
    );
}

fn have_valgrind() -> bool {
    if ctools::have_program("valgrind") {
        return true;
    }
    ctools::tool_missing(
        "valgrind",
        "valgrind",
        "apt-get install valgrind; SKIPPED: valgrind not installed",
    );
    false
}

#[test]
fn c_demo_under_valgrind() {
    if !have_valgrind() {
        return;
    }
    let exe = build("block2d.c", "block2d_vg");
    memcheck(&exe, &["--method", "split", "--nx", "6", "--ny", "3"]);
}

#[test]
fn bad_input_c_under_valgrind() {
    if !have_valgrind() {
        return;
    }
    let exe = build("bad_input.c", "bad_input_vg");
    memcheck(&exe, &[]);
}

#[test]
fn hyperelastic_host_under_valgrind() {
    if !have_valgrind() {
        return;
    }
    let exe = build("hyperelastic_host.c", "hyperelastic_host_vg");
    memcheck(&exe, &["--nx", "6", "--ny", "3", "--increments", "1", "1"]);
    memcheck(
        &exe,
        &[
            "--dim",
            "3",
            "--nx",
            "3",
            "--ny",
            "3",
            "--nz",
            "2",
            "--increments",
            "1",
            "1",
        ],
    );
}
