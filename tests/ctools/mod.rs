//! Shared helpers of the tests that build foreign code against the library:
//! `fortran` (gfortran), `suitesparse` (CHOLMOD, CXSparse) and `install` (make,
//! pkg-config).
//!
//! - where the library cargo built for this test run lives, and the C compiler the
//!   `cc` crate finds;
//! - the rule for a missing tool: outside CI the test prints a loud
//!   `SKIPPED: <test> needs <tool> (<how to install>)` to stderr and passes; with
//!   `CI=true` (set by .ci/run, which installs the tools) it fails;
//! - running a command and failing with its output.
//!
//! Each test binary uses only part of this module.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A fresh folder for the outputs of one test under target/tmp.
pub fn out_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir)
        .unwrap_or_else(|e| panic!("create the output folder {}: {e}", dir.display()));
    dir
}

/// True when running in CI (.ci/run exports CI=true): missing tools are failures.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// Reports a missing tool. Outside CI: prints the SKIPPED banner and returns (the
/// caller then returns early and the test passes). In CI: panics.
pub fn tool_missing(test: &str, tool: &str, hint: &str) {
    let line = format!("SKIPPED: {test} needs {tool} ({hint})");
    if in_ci() {
        panic!("{line}, and CI=true: CI must install it (see .ci/run)");
    }
    let bar = "=".repeat(line.len().min(100));
    // Written to the process's stderr directly: eprintln! would be captured by the
    // test harness and shown only for failing tests.
    let _ = writeln!(std::io::stderr(), "\n{bar}\n{line}\n{bar}\n");
}

/// True when `program --version` runs and succeeds.
pub fn have_program(program: impl AsRef<OsStr>) -> bool {
    Command::new(program)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// The Fortran compiler: $FC when set, else gfortran; None when it does not run.
pub fn fortran_compiler() -> Option<String> {
    let fc = std::env::var("FC")
        .ok()
        .filter(|s| !s.trim().is_empty())
        .unwrap_or_else(|| "gfortran".to_string());
    have_program(&fc).then_some(fc)
}

/// Runs a command; panics with its output unless it succeeds.
pub fn run_ok(cmd: &mut Command, what: &str) -> Output {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot run {cmd:?}: {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "{what} failed ({}): {cmd:?}\n--- stdout\n{stdout}\n--- stderr\n{stderr}",
        out.status
    );
    if !stderr.trim().is_empty() {
        eprintln!("{what}: stderr:\n{stderr}");
    }
    out
}

pub fn stdout_of(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The static library cargo built for this test run, found from the path of this
/// test executable (target/<profile>/deps/<test>-<hash>); the newer of the copies in
/// deps/ and in target/<profile>/ (as tests/c_demo.rs).
pub fn static_lib() -> PathBuf {
    let exe = std::env::current_exe().expect("path of the test executable");
    let deps = exe
        .parent()
        .expect("the test executable has a parent folder");
    let profile_dir = if deps.file_name().is_some_and(|n| n == "deps") {
        deps.parent().expect("deps has a parent folder")
    } else {
        deps
    };
    let name = "libdualsplit.a";
    let modified = |p: &PathBuf| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    [deps.join(name), profile_dir.join(name)]
        .into_iter()
        .filter(|p| p.is_file())
        .max_by_key(modified)
        .unwrap_or_else(|| {
            panic!(
                "the static library {name} exists neither in {} nor in {}",
                deps.display(),
                profile_dir.display()
            )
        })
}

/// The system libraries a Rust static library needs.
pub const SYSTEM_LIBS: [&str; 3] = ["-lm", "-lpthread", "-ldl"];

/// The target triple this test was compiled for (the cc crate needs it outside a
/// build script).
pub fn target_triple() -> String {
    let arch = std::env::consts::ARCH;
    if cfg!(target_os = "linux") {
        let env = if cfg!(target_env = "musl") {
            "musl"
        } else {
            "gnu"
        };
        format!("{arch}-unknown-linux-{env}")
    } else if cfg!(target_os = "macos") {
        format!("{arch}-apple-darwin")
    } else if cfg!(target_os = "freebsd") {
        format!("{arch}-unknown-freebsd")
    } else {
        panic!("no target triple known for {}", std::env::consts::OS)
    }
}

/// The C compiler the `cc` crate finds, with -O2 and no debug information.
fn c_tool() -> cc::Tool {
    let triple = target_triple();
    cc::Build::new()
        .target(&triple)
        .host(&triple)
        .opt_level(2)
        .debug(false)
        .cargo_metadata(false)
        .cargo_warnings(false)
        .try_get_compiler()
        .expect("cc: find a C compiler")
}

/// A command that runs the C compiler, flags included.
pub fn c_compiler() -> Command {
    c_tool().to_command()
}

/// The path of the C compiler (to call it with nothing but one's own flags).
pub fn c_compiler_path() -> PathBuf {
    c_tool().path().to_path_buf()
}

/// `readelf -d` of a file (None when readelf is missing).
pub fn readelf_dynamic(file: &Path) -> Option<String> {
    let out = Command::new("readelf").arg("-d").arg(file).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The bracketed names of the `readelf -d` lines containing `tag` (e.g. "SONAME",
/// "NEEDED").
pub fn dynamic_entries(readelf: &str, tag: &str) -> Vec<String> {
    readelf
        .lines()
        .filter(|l| l.contains(&format!("({tag})")))
        .filter_map(|l| {
            let a = l.find('[')?;
            let b = l.rfind(']')?;
            Some(l[a + 1..b].to_string())
        })
        .collect()
}
