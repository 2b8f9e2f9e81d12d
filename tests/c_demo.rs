//! Builds the C demo c_examples/block2d.c against the static library cargo built for
//! this test run (target/<profile>/libdualsplit.a) and runs it with every method:
//! a plane-strain block pressed onto a curved rigid foundation, sheared until it
//! slips, unloaded and lifted off, with Coulomb friction in history mode (ds_step).
//!
//! Checked: every step converges (the status of every ds_step), the resultants balance (the C
//! program checks them itself), the shear phase shows both sticking and slipping
//! contacts, every contact is open after lift-off, and all methods give the
//! same contact force resultants at every step.

mod ctools;

use ctools::{manifest_dir, static_lib, target_triple};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

const METHODS: [&str; 6] = ["split", "block-gs", "pgs", "newton", "split-mprgp", "mprgp"];
/// A small mesh, so that the debug build stays fast: 17 contacts, 272 free DOFs.
const MESH: [&str; 4] = ["--nx", "16", "--ny", "8"];

/// Compiles and links block2d once per test run; returns the executable.
fn block2d() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| {
        let root = manifest_dir();
        let header = root.join("include").join("dualsplit.h");
        assert!(
            header.is_file(),
            "the C header {} does not exist",
            header.display()
        );
        let lib = static_lib();
        let out_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("c_demo");
        std::fs::create_dir_all(&out_dir).expect("create the output folder");
        let exe = out_dir.join("block2d");

        let triple = target_triple();
        let compiler = cc::Build::new()
            .target(&triple)
            .host(&triple)
            .opt_level(2)
            .debug(false)
            .cargo_metadata(false)
            .cargo_warnings(false)
            .try_get_compiler()
            .expect("cc: find a C compiler");
        let mut cmd = compiler.to_command();
        cmd.arg("-std=c99")
            .arg("-Wall")
            .arg("-Wextra")
            .arg("-I")
            .arg(root.join("include"))
            .arg(root.join("c_examples").join("block2d.c"))
            .arg(&lib)
            .args(["-lm", "-lpthread", "-ldl"])
            .arg("-o")
            .arg(&exe);
        let out = cmd
            .output()
            .unwrap_or_else(|e| panic!("run the C compiler {cmd:?}: {e}"));
        let diagnostics = String::from_utf8_lossy(&out.stderr);
        if !diagnostics.trim().is_empty() {
            eprintln!("C compiler output:\n{diagnostics}");
        }
        assert!(
            out.status.success(),
            "compiling block2d failed: {cmd:?}\n{diagnostics}"
        );
        exe
    })
}

/// One row of the per-step table.
#[derive(Debug, Clone)]
struct Step {
    step: usize,
    phase: String,
    open: usize,
    stick: usize,
    slip: usize,
    sum_n: f64,
    sum_t: f64,
}

#[derive(Debug)]
struct Run {
    stdout: String,
    steps: Vec<Step>,
    summary: HashMap<String, String>,
}

impl Run {
    fn get(&self, key: &str) -> &str {
        self.summary
            .get(key)
            .unwrap_or_else(|| panic!("SUMMARY has no {key}:\n{}", self.stdout))
    }
    fn num(&self, key: &str) -> f64 {
        self.get(key)
            .parse()
            .unwrap_or_else(|_| panic!("SUMMARY {key}={} is not a number", self.get(key)))
    }
}

fn run_block2d(method: &str) -> Run {
    let exe = block2d();
    let out = Command::new(exe)
        .args(["--method", method])
        .args(MESH)
        .output()
        .expect("run block2d");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    println!("---- block2d --method {method}\n{stdout}{stderr}");
    assert!(
        out.status.success(),
        "block2d --method {method} failed ({}):\n{stdout}\n{stderr}",
        out.status
    );

    let mut steps = Vec::new();
    let mut summary = HashMap::new();
    for line in stdout.lines() {
        let tok: Vec<&str> = line.split_whitespace().collect();
        if tok.first() == Some(&"SUMMARY") {
            for kv in &tok[1..] {
                let (k, v) = kv.split_once('=').expect("SUMMARY entries are key=value");
                summary.insert(k.to_string(), v.to_string());
            }
        } else if tok.len() == 13 && tok[0].parse::<usize>().is_ok() {
            let f = |i: usize| -> f64 {
                tok[i]
                    .parse()
                    .unwrap_or_else(|_| panic!("bad number {} in: {line}", tok[i]))
            };
            let z = |i: usize| -> usize {
                tok[i]
                    .parse()
                    .unwrap_or_else(|_| panic!("bad count {} in: {line}", tok[i]))
            };
            steps.push(Step {
                step: z(0),
                phase: tok[1].to_string(),
                open: z(4),
                stick: z(5),
                slip: z(6),
                sum_n: f(7),
                sum_t: f(8),
            });
        }
    }
    assert!(
        !summary.is_empty(),
        "no SUMMARY line in the output of block2d --method {method}"
    );
    Run {
        stdout,
        steps,
        summary,
    }
}

fn check_run(method: &str, run: &Run) {
    let steps = run.num("steps") as usize;
    let contacts = run.num("contacts") as usize;
    assert_eq!(run.get("method"), method);
    assert_eq!(run.steps.len(), steps, "{method}: one table row per step");
    assert_eq!(
        run.get("all_converged"),
        "1",
        "{method}: not every step converged"
    );
    assert_eq!(
        run.get("resultant_ok"),
        "1",
        "{method}: resultants do not balance"
    );
    assert!(
        run.stdout.contains("resultant check: ok"),
        "{method}: no 'resultant check: ok'"
    );

    for (i, s) in run.steps.iter().enumerate() {
        assert_eq!(s.step, i + 1);
        assert!(
            s.sum_n >= 0.0,
            "{method}: step {} negative normal resultant",
            s.step
        );
    }

    let shear: Vec<&Step> = run.steps.iter().filter(|s| s.phase == "shear").collect();
    assert!(!shear.is_empty(), "{method}: no shear phase");
    assert!(
        shear.iter().any(|s| s.slip > 0),
        "{method}: no slipping contact while shearing"
    );
    assert!(
        shear.iter().any(|s| s.stick > 0),
        "{method}: no sticking contact while shearing"
    );
    assert!(run.num("shear_max_slip") >= 1.0 && run.num("shear_max_stick") >= 1.0);
    // The load pushes the block along +x, so friction resists with lambda_T > 0.
    let last_shear = shear.last().unwrap();
    assert!(
        last_shear.sum_t > 0.0,
        "{method}: friction resultant has the wrong sign"
    );
    // Friction can never exceed mu times the normal force (mu = 0.3 in the demo).
    for s in &run.steps {
        assert!(
            s.sum_t.abs() <= 0.3 * s.sum_n * (1.0 + 1e-8) + 1e-12 * run.steps[4].sum_n,
            "{method}: step {}: |sum lambda_T| > mu sum lambda_N",
            s.step
        );
    }

    let last = run.steps.last().unwrap();
    assert_eq!(
        last.open, contacts,
        "{method}: not every contact is open after lift-off"
    );
    assert_eq!(run.num("final_open") as usize, contacts);
    let peak = run.steps.iter().map(|s| s.sum_n).fold(0.0, f64::max);
    assert!(
        last.sum_n.abs() <= 1e-10 * peak && last.sum_t.abs() <= 1e-10 * peak,
        "{method}: contact forces after lift-off: {:e}, {:e}",
        last.sum_n,
        last.sum_t
    );
}

#[test]
fn block2d_all_methods_converge_and_agree() {
    let runs: Vec<(&str, Run)> = METHODS.iter().map(|&m| (m, run_block2d(m))).collect();
    for (m, run) in &runs {
        check_run(m, run);
    }

    // Every method solves the same problems: the resultants must agree at every step,
    // relative to the largest normal resultant of the history.
    let (ref_name, reference) = &runs[0];
    let peak = reference
        .steps
        .iter()
        .map(|s| s.sum_n.abs())
        .fold(0.0, f64::max);
    assert!(peak > 0.0);
    for (m, run) in &runs[1..] {
        assert_eq!(run.steps.len(), reference.steps.len());
        for (a, b) in reference.steps.iter().zip(&run.steps) {
            for (what, x, y) in [
                ("sum lambda_N", a.sum_n, b.sum_n),
                ("sum lambda_T", a.sum_t, b.sum_t),
            ] {
                let scale = x.abs().max(y.abs()).max(peak);
                assert!(
                    (x - y).abs() <= 1e-8 * scale,
                    "step {}: {what}: {ref_name} {x:.12e} vs {m} {y:.12e}",
                    a.step
                );
            }
        }
    }
}

#[test]
fn block2d_rejects_bad_options() {
    let exe = block2d();
    for args in [
        &["--method", "simplex"][..],
        &["--nx", "0"][..],
        &["--bogus"][..],
    ] {
        let out = Command::new(exe).args(args).output().expect("run block2d");
        assert_eq!(
            out.status.code(),
            Some(3),
            "block2d {args:?} should exit with 3"
        );
    }
}
