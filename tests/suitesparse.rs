//! The SuiteSparse path: c_examples/suitesparse_block2d.c assembles K as a CHOLMOD
//! triplet matrix (upper triangle, stype 1, SuiteSparse_long indices) compressed by
//! cholmod_l_triplet_to_sparse, N and T with CXSparse (cs_di), and hands the
//! cholmod_sparse / cs arrays to the library as they are. Built against the static
//! library of this test run.
//!
//! - `suitesparse_example_builds_and_runs`: the Coulomb history converges, the
//!   matrices went in as CSC/I64/UPPER (K), CSC/I32 (N) and COO/I32 (T), and the
//!   frictionless reference check passes;
//! - `frictionless_u_matches_cholmod_reference`: on three scenes, u from the library
//!   (K factored by faer) equals, to 1e-10 relative, the solution of the
//!   equality-constrained system on the final active set solved with CHOLMOD
//!   ([K N_a^T; N_a 0] by its Schur complement), and that solution is feasible;
//! - `cholmod_operator_history_matches_the_own_path`: c_examples/cholmod_operator.c,
//!   the demo's history on CHOLMOD's solves (ds_problem_new_host), with and
//!   without K handed over, deviates from the library's own path by at most
//!   1e-10, and a callback failing mid-history gives DS_STATUS_HOST_SOLVE_FAILED
//!   with its code, outputs untouched, and a usable handle.
//!
//! Compiler and linker flags: $SUITESPARSE_CFLAGS / $SUITESPARSE_LIBS when set (as in
//! the Makefile), else pkg-config's CHOLMOD and CXSparse (SuiteSparse >= 7), else
//! -I/usr/include/suitesparse -lcholmod -lcxsparse -lsuitesparseconfig (Debian,
//! Ubuntu). Without SuiteSparse the tests print "SKIPPED: ... needs SuiteSparse" and
//! pass, unless CI=true (then they fail).

mod ctools;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Instant;

use ctools::*;

const HINT: &str = "apt-get install libsuitesparse-dev";

/// (cflags, libs) for CHOLMOD and CXSparse, or None when SuiteSparse is not found.
fn suitesparse_flags() -> Option<(Vec<String>, Vec<String>)> {
    let words = |s: &str| s.split_whitespace().map(String::from).collect::<Vec<_>>();
    if let (Ok(c), Ok(l)) = (
        std::env::var("SUITESPARSE_CFLAGS"),
        std::env::var("SUITESPARSE_LIBS"),
    ) {
        return Some((words(&c), words(&l)));
    }
    let pc = Command::new("pkg-config")
        .args(["--cflags", "--libs", "CHOLMOD", "CXSparse"])
        .output();
    if let Ok(out) = pc
        && out.status.success()
    {
        let flags = words(&String::from_utf8_lossy(&out.stdout));
        let (libs, cflags): (Vec<String>, Vec<String>) = flags
            .into_iter()
            .partition(|f| f.starts_with("-l") || f.starts_with("-L"));
        return Some((cflags, libs));
    }
    for dir in [
        "/usr/include/suitesparse",
        "/usr/local/include/suitesparse",
        "/usr/include",
    ] {
        let d = Path::new(dir);
        if d.join("cholmod.h").is_file() && d.join("cs.h").is_file() {
            return Some((
                vec![format!("-I{dir}")],
                words("-lcholmod -lcxsparse -lsuitesparseconfig"),
            ));
        }
    }
    None
}

/// The example, built once per run; None (after the SKIPPED notice) without
/// SuiteSparse.
fn example(test: &str) -> Option<&'static Path> {
    static EXE: OnceLock<Option<PathBuf>> = OnceLock::new();
    built(&EXE, "suitesparse_block2d", test)
}

/// c_examples/cholmod_operator.c, built once per run (as [`example`]).
fn operator_example(test: &str) -> Option<&'static Path> {
    static EXE: OnceLock<Option<PathBuf>> = OnceLock::new();
    built(&EXE, "cholmod_operator", test)
}

/// c_examples/`name`.c built against SuiteSparse into `cell`, once.
fn built(
    cell: &'static OnceLock<Option<PathBuf>>,
    name: &str,
    test: &str,
) -> Option<&'static Path> {
    let exe = cell.get_or_init(|| {
        let (cflags, libs) = suitesparse_flags()?;
        let root = manifest_dir();
        let exe = out_dir("suitesparse").join(name);
        let t = Instant::now();
        run_ok(
            c_compiler()
                .args(["-std=c99", "-Wall", "-Wextra"])
                .arg("-I")
                .arg(root.join("include"))
                .args(&cflags)
                .arg(root.join(format!("c_examples/{name}.c")))
                .arg(static_lib())
                .args(&libs)
                .args(SYSTEM_LIBS)
                .arg("-o")
                .arg(&exe),
            &format!("compiling c_examples/{name}.c"),
        );
        println!("built in {:.2} s", t.elapsed().as_secs_f64());
        Some(exe)
    });
    if exe.is_none() {
        tool_missing(test, "SuiteSparse (CHOLMOD, CXSparse)", HINT);
    }
    exe.as_deref()
}

fn key_values(line: &str) -> HashMap<String, String> {
    line.split_whitespace()
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

fn line_with<'a>(stdout: &'a str, prefix: &str) -> &'a str {
    stdout
        .lines()
        .find(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no {prefix} line in:\n{stdout}"))
}

fn num(kv: &HashMap<String, String>, key: &str) -> f64 {
    kv.get(key)
        .unwrap_or_else(|| panic!("no {key} in {kv:?}"))
        .parse()
        .unwrap_or_else(|_| panic!("{key} is not a number: {kv:?}"))
}

/// Checks the REFERENCE line and returns (active contacts, u_rel_diff,
/// lambda_rel_diff).
fn check_reference(stdout: &str, contacts: f64, what: &str) -> (f64, f64, f64) {
    let r = key_values(line_with(stdout, "REFERENCE "));
    let active = num(&r, "active");
    let u_diff = num(&r, "u_rel_diff");
    let l_diff = num(&r, "lambda_rel_diff");
    assert_eq!(
        r["feasible"], "1",
        "{what}: the reference is not feasible: {r:?}"
    );
    assert_eq!(r["check"], "ok", "{what}: {r:?}");
    assert!(
        active >= 1.0 && active < contacts,
        "{what}: a scene with open and closed contacts: {r:?}"
    );
    assert!(
        u_diff <= 1e-10 && l_diff <= 1e-10,
        "{what}: library vs CHOLMOD reference: {r:?}"
    );
    (active, u_diff, l_diff)
}

#[test]
fn suitesparse_example_builds_and_runs() {
    let Some(exe) = example("suitesparse::suitesparse_example_builds_and_runs") else {
        return;
    };
    let t = Instant::now();
    let out = run_ok(
        Command::new(exe).args(["--nx", "16", "--ny", "8"]),
        "suitesparse_block2d",
    );
    let stdout = stdout_of(&out);
    println!("{stdout}ran in {:.2} s", t.elapsed().as_secs_f64());

    let s = key_values(line_with(&stdout, "SUMMARY "));
    assert_eq!(s["all_converged"], "1", "{stdout}");
    assert_eq!(s["steps"], "10");
    assert_eq!(s["contacts"], "17");
    assert_eq!(s["dofs"], "272");
    assert_eq!(
        s["k_index"], "i64",
        "K goes in with SuiteSparse_long indices"
    );
    assert_eq!(
        s["k_storage"], "upper",
        "K goes in as CHOLMOD's upper triangle"
    );
    assert!(num(&s, "max_err") <= 1e-10);
    assert!(num(&s, "shear_max_slip") >= 1.0 && num(&s, "shear_max_stick") >= 1.0);
    assert!(stdout.contains("stype 1"), "{stdout}");
    assert!(stdout.contains("T: cs_di triplet"), "{stdout}");

    // The history is the C demo's first ten steps on the same mesh: the normal and
    // tangential resultants of every step must match block2d.c's (assembled the
    // plain way, without SuiteSparse).
    let ours = resultants(&stdout);
    let demo = resultants(&c_demo_output(&["--nx", "16", "--ny", "8"]));
    assert_eq!(ours.len(), 10, "{stdout}");
    let peak = demo.values().fold(0.0f64, |a, &(n, _)| a.max(n.abs()));
    assert!(peak > 0.0);
    for (step, (n, t)) in &ours {
        let (dn, dt) = demo[step];
        assert!(
            (n - dn).abs() <= 1e-8 * peak && (t - dt).abs() <= 1e-8 * peak,
            "step {step}: SuiteSparse example ({n:e}, {t:e}), C demo ({dn:e}, {dt:e})"
        );
    }
    check_reference(&stdout, 17.0, "16 x 8");
}

#[test]
fn frictionless_u_matches_cholmod_reference() {
    let Some(exe) = example("suitesparse::frictionless_u_matches_cholmod_reference") else {
        return;
    };
    let scenes: [(&[&str], f64); 3] = [
        (&["--nx", "16", "--ny", "8"], 17.0),
        (&["--nx", "40", "--ny", "20", "--quiet"], 41.0),
        (
            &["--nx", "30", "--ny", "10", "--uy", "-0.02", "--quiet"],
            31.0,
        ),
    ];
    for (args, contacts) in scenes {
        let t = Instant::now();
        let stdout = stdout_of(&run_ok(
            Command::new(exe).args(args),
            &format!("suitesparse_block2d {args:?}"),
        ));
        let (active, u_diff, l_diff) = check_reference(&stdout, contacts, &format!("{args:?}"));
        eprintln!(
            "{args:?}: {active} of {contacts} contacts active, |u - u_cholmod| / |u_cholmod| \
             = {u_diff:.3e}, lambda_N: {l_diff:.3e} ({:.2} s)",
            t.elapsed().as_secs_f64()
        );
    }
}

/// step -> (sum lambda_N, sum lambda_T) from the per-step table of block2d.c or
/// suitesparse_block2d.c (the same columns: step, phase, ..., then the two sums as
/// the 8th and 9th numbers).
fn resultants(stdout: &str) -> HashMap<usize, (f64, f64)> {
    stdout
        .lines()
        .filter_map(|l| {
            let tok: Vec<&str> = l.split_whitespace().collect();
            let step = tok.first()?.parse::<usize>().ok()?;
            if tok.len() < 9 || tok[1].parse::<f64>().is_ok() {
                return None;
            }
            Some((step, (tok[7].parse().ok()?, tok[8].parse().ok()?)))
        })
        .collect()
}

/// Builds c_examples/block2d.c (the plain C demo) and runs it with `args`.
fn c_demo_output(args: &[&str]) -> String {
    let dir = out_dir("suitesparse_c_demo");
    let exe = dir.join("block2d");
    run_ok(
        c_compiler()
            .arg("-std=c99")
            .arg("-O2")
            .arg("-I")
            .arg(manifest_dir().join("include"))
            .arg(manifest_dir().join("c_examples/block2d.c"))
            .arg(static_lib())
            .args(SYSTEM_LIBS)
            .arg("-o")
            .arg(&exe),
        "compiling block2d.c",
    );
    stdout_of(&run_ok(Command::new(&exe).args(args), "block2d"))
}

#[test]
fn cholmod_operator_history_matches_the_own_path() {
    let test = "suitesparse::cholmod_operator_history_matches_the_own_path";
    let Some(exe) = operator_example(test) else {
        return;
    };
    for args in [
        &["--nx", "40", "--ny", "20"][..],
        &["--nx", "40", "--ny", "20", "--no-k", "--quiet"],
        &["--nx", "80", "--ny", "40", "--quiet"],
    ] {
        let t = Instant::now();
        let stdout = stdout_of(&run_ok(
            Command::new(exe).args(args),
            &format!("cholmod_operator {args:?}"),
        ));
        println!("{stdout}{args:?} ran in {:.2} s", t.elapsed().as_secs_f64());
        let s = key_values(line_with(&stdout, "SUMMARY "));
        assert_eq!(s["steps"], "15", "{stdout}");
        assert_eq!(s["check"], "ok", "{stdout}");
        assert!(num(&s, "max_dev") <= 1e-10, "{stdout}");
        assert_eq!(
            s["with_k"],
            if args.contains(&"--no-k") { "0" } else { "1" }
        );
    }
    // A callback failing on its 300th call (within the fifth step).
    let stdout = stdout_of(&run_ok(
        Command::new(exe).args(["--fail-at", "300", "--quiet"]),
        "cholmod_operator --fail-at 300",
    ));
    let f = key_values(line_with(&stdout, "FAILURE "));
    assert_eq!(
        (f["named"].as_str(), f["untouched"].as_str()),
        ("1", "1"),
        "{stdout}"
    );
    assert!(stdout.contains("code 77"), "{stdout}");
    let s = key_values(line_with(&stdout, "SUMMARY "));
    assert_eq!(
        s["check"], "ok",
        "the history goes on after the failure: {stdout}"
    );
}
