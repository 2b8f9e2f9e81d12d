//! The command-line solver `dualsplit` (src/bin/dualsplit.rs): runs the built
//! binary on small problem folders written by `mtx::write_problem` and checks the
//! outputs, report.json, the exit codes, --help and the error messages.

mod common;

use dualsplit::mtx;
use dualsplit::{ContactProblem, Csc, Friction, Method, Options, SolveStatus};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh, empty folder under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        static COUNT: AtomicUsize = AtomicUsize::new(0);
        let k = COUNT.fetch_add(1, Ordering::SeqCst);
        let p =
            std::env::temp_dir().join(format!("dualsplit-cli-{}-{tag}-{k}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }

    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dualsplit"))
        .args(args)
        .output()
        .expect("cannot run the dualsplit binary")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A small contact problem in d = 2 or 3: a chain of coupled DOFs (K SPD and
/// banded), m contacts, the load pushing every contact node into the foundation
/// and sideways: for m >= 3 one contact stays open, some stick and some slip.
struct Problem {
    d: usize,
    k: Csc,
    n: Csc,
    t: Csc,
    f: Vec<f64>,
    g: Vec<f64>,
    fr: Vec<f64>,
}

fn problem(d: usize, m: usize) -> Problem {
    let ndof = d * m + 2;
    let mut kt = Vec::new();
    for i in 0..ndof {
        kt.push((i, i, 2.5));
        if i + 1 < ndof {
            kt.push((i, i + 1, -0.1));
            kt.push((i + 1, i, -0.1));
        }
        if i + d < ndof {
            kt.push((i, i + d, -1.0));
            kt.push((i + d, i, -1.0));
        }
    }
    let n = Csc::from_triplets(
        m,
        ndof,
        &(0..m).map(|i| (i, d * i, 1.0)).collect::<Vec<_>>(),
    );
    let mut tt = Vec::new();
    for i in 0..m {
        for s in 0..d - 1 {
            tt.push(((d - 1) * i + s, d * i + 1 + s, 1.0));
        }
    }
    let t = Csc::from_triplets((d - 1) * m, ndof, &tt);
    let mut f = vec![0.0; ndof];
    for i in 0..m {
        f[d * i] = 1.0 + 0.2 * i as f64;
        for s in 0..d - 1 {
            f[d * i + 1 + s] = 0.4 * (i as f64 - 1.0) + 0.1 * s as f64;
        }
    }
    Problem {
        d,
        k: Csc::from_triplets(ndof, ndof, &kt),
        n,
        t,
        f,
        // The last contact starts far from the foundation: it stays open.
        g: (0..m)
            .map(|i| {
                if i + 1 == m && m > 2 {
                    5.0
                } else {
                    0.05 * i as f64
                }
            })
            .collect(),
        // Contact 1 has no tangential load of its own and a high coefficient: it sticks.
        fr: (0..m)
            .map(|i| if i == 1 { 0.9 } else { 0.2 + 0.1 * i as f64 })
            .collect(),
    }
}

fn write(dir: &Path, p: &Problem, coulomb: bool) {
    let fr = if coulomb {
        Friction::Coulomb(&p.fr)
    } else {
        Friction::Tresca(&p.fr)
    };
    mtx::write_problem(dir, p.d, &p.k, &p.n, &p.t, &p.f, &p.g, fr).unwrap();
}

/// A JSON value of report.json (a flat object of strings, numbers and nulls).
#[derive(Debug, PartialEq)]
enum Value {
    Str(String),
    Num(f64),
    Null,
}

/// Parses a flat JSON object strictly enough to reject malformed output.
fn parse_json(s: &str) -> BTreeMap<String, Value> {
    let mut out = BTreeMap::new();
    let b: Vec<char> = s.chars().collect();
    let mut i = 0;
    let ws = |i: &mut usize| {
        while *i < b.len() && b[*i].is_whitespace() {
            *i += 1;
        }
    };
    let string = |i: &mut usize| -> String {
        assert_eq!(b[*i], '"', "expected a string at {i}");
        *i += 1;
        let mut v = String::new();
        loop {
            let c = b[*i];
            *i += 1;
            match c {
                '"' => return v,
                '\\' => {
                    let e = b[*i];
                    *i += 1;
                    match e {
                        '"' => v.push('"'),
                        '\\' => v.push('\\'),
                        '/' => v.push('/'),
                        'n' => v.push('\n'),
                        'r' => v.push('\r'),
                        't' => v.push('\t'),
                        'u' => {
                            let hex: String = b[*i..*i + 4].iter().collect();
                            *i += 4;
                            v.push(char::from_u32(u32::from_str_radix(&hex, 16).unwrap()).unwrap());
                        }
                        other => panic!("bad escape \\{other}"),
                    }
                }
                c if (c as u32) < 0x20 => panic!("raw control character in a JSON string"),
                c => v.push(c),
            }
        }
    };
    ws(&mut i);
    assert_eq!(b[i], '{');
    i += 1;
    loop {
        ws(&mut i);
        let key = string(&mut i);
        ws(&mut i);
        assert_eq!(b[i], ':');
        i += 1;
        ws(&mut i);
        let value = if b[i] == '"' {
            Value::Str(string(&mut i))
        } else if b[i..].starts_with(&['n', 'u', 'l', 'l']) {
            i += 4;
            Value::Null
        } else {
            let start = i;
            while i < b.len() && matches!(b[i], '0'..='9' | '-' | '+' | '.' | 'e' | 'E') {
                i += 1;
            }
            let tok: String = b[start..i].iter().collect();
            // JSON numbers: no leading '+', no bare '.', digits around the point.
            assert!(
                !tok.starts_with('+') && !tok.starts_with('.') && !tok.contains(".e"),
                "bad JSON number {tok}"
            );
            Value::Num(tok.parse().unwrap_or_else(|_| panic!("bad number {tok}")))
        };
        assert!(
            out.insert(key.clone(), value).is_none(),
            "duplicate key {key}"
        );
        ws(&mut i);
        match b[i] {
            ',' => i += 1,
            '}' => {
                i += 1;
                ws(&mut i);
                assert_eq!(i, b.len(), "trailing text after the object");
                return out;
            }
            c => panic!("unexpected {c} in JSON"),
        }
    }
}

fn report(out: &Path) -> BTreeMap<String, Value> {
    parse_json(&std::fs::read_to_string(out.join("report.json")).unwrap())
}

fn num(r: &BTreeMap<String, Value>, key: &str) -> f64 {
    match r.get(key) {
        Some(Value::Num(v)) => *v,
        other => panic!("report.json: {key} = {other:?}, expected a number"),
    }
}

fn string<'a>(r: &'a BTreeMap<String, Value>, key: &str) -> &'a str {
    match r.get(key) {
        Some(Value::Str(v)) => v,
        other => panic!("report.json: {key} = {other:?}, expected a string"),
    }
}

fn close(a: &[f64], b: &[f64]) -> bool {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * scale)
}

#[test]
fn solves_a_folder_and_writes_every_output() {
    for (d, m, coulomb, method) in [
        (2, 3, true, "split"),
        (3, 3, true, "pgs"),
        (3, 4, false, "block-gs"),
        (2, 5, false, "split"),
    ] {
        let dir = TempDir::new("ok");
        let prob = dir.path().join("problem");
        let out = dir.path().join("out");
        let p = problem(d, m);
        write(&prob, &p, coulomb);
        let o = run(&[
            "solve",
            prob.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--method",
            method,
            "--tol",
            "1e-11",
        ]);
        let stdout = text(&o.stdout);
        assert_eq!(o.status.code(), Some(0), "{stdout}{}", text(&o.stderr));
        assert!(stdout.contains("converged"), "{stdout}");
        assert!(
            stdout.contains(&format!("n = {}, m = {m}, d = {d}", p.k.nrows)),
            "{stdout}"
        );
        // Outputs: the lengths, and the same numbers as the library's own solve.
        let u = mtx::read_vector(&out.join("u.txt")).unwrap();
        let ln = mtx::read_vector(&out.join("lambda_n.txt")).unwrap();
        let lt = mtx::read_vector(&out.join("lambda_t.txt")).unwrap();
        assert_eq!((u.len(), ln.len(), lt.len()), (p.k.nrows, m, (d - 1) * m));
        let opts = Options {
            method: Method::from_name(method).unwrap(),
            tol: 1e-11,
            ..Options::default()
        };
        let fr = if coulomb {
            Friction::Coulomb(&p.fr)
        } else {
            Friction::Tresca(&p.fr)
        };
        let mut pb = ContactProblem::from_csc(d, p.k.clone(), p.n.clone(), p.t.clone()).unwrap();
        let sol = pb.solve(&p.f, &p.g, fr, &opts).unwrap();
        assert_eq!(sol.report.status, SolveStatus::Converged);
        assert!(close(&u, &sol.u) && close(&ln, &sol.lambda_n) && close(&lt, &sol.lambda_t));
        assert!(
            ln.iter().any(|&x| x > 0.0),
            "the test problem must have closed contacts"
        );
        // report.json
        let r = report(&out);
        assert_eq!(string(&r, "status"), "converged");
        assert_eq!(string(&r, "method"), method);
        assert_eq!(
            string(&r, "friction"),
            if coulomb { "coulomb" } else { "tresca" }
        );
        assert_eq!(num(&r, "n"), p.k.nrows as f64);
        assert_eq!(num(&r, "m"), m as f64);
        assert_eq!(num(&r, "d"), d as f64);
        assert_eq!(num(&r, "tol"), 1e-11);
        // The CLI reports what the library computes for the same folder.
        assert_eq!(num(&r, "err"), sol.report.err);
        assert!(num(&r, "equilibrium_residual") < 1e-12);
        assert_eq!(num(&r, "iterations"), sol.report.outer_iterations as f64);
        assert_eq!(
            num(&r, "inner_iterations"),
            sol.report.inner_iterations as f64
        );
        // The test problem exercises every contact state.
        for key in ["open", "stick", "slip"] {
            assert!(num(&r, key) >= 1.0, "no {key} contact: {r:?}");
        }
        let lib = &sol.report;
        assert_eq!(
            (num(&r, "open"), num(&r, "stick"), num(&r, "slip")),
            (lib.n_open as f64, lib.n_stick as f64, lib.n_slip as f64)
        );
        for key in [
            "read_seconds",
            "factor_seconds",
            "condense_seconds",
            "solve_seconds",
        ] {
            assert!(num(&r, key) >= 0.0, "{key}");
        }
        assert_eq!(string(&r, "problem"), prob.to_str().unwrap());
    }
}

#[test]
fn not_converged_exits_1_with_outputs() {
    let dir = TempDir::new("nc");
    let prob = dir.path().join("problem");
    let out = dir.path().join("out");
    write(&prob, &problem(3, 4), true);
    let o = run(&[
        "solve",
        prob.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--method=pgs",
        "--tol=1e-15",
        "--max-iter=1",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stderr));
    assert!(
        text(&o.stdout).contains("NOT converged"),
        "{}",
        text(&o.stdout)
    );
    let r = report(&out);
    assert_eq!(string(&r, "status"), "not-converged");
    assert_eq!(num(&r, "iterations"), 1.0);
    assert_eq!(num(&r, "max_iter"), 1.0);
    assert!(num(&r, "err") > 1e-15);
    for f in ["u.txt", "lambda_n.txt", "lambda_t.txt"] {
        assert!(
            out.join(f).is_file(),
            "{f} is written also when not converged"
        );
    }
}

#[test]
fn matrix_free_dual_form_from_the_command_line() {
    let dir = TempDir::new("free");
    let prob = dir.path().join("problem");
    write(&prob, &problem(3, 4), true);
    let solve = |form: &str, method: &str| {
        let out = dir.path().join(format!("out-{form}-{method}"));
        let o = run(&[
            "solve",
            prob.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--method",
            method,
            "--dual-form",
            form,
            "--quiet",
        ]);
        (o, out)
    };
    let numbers = |path: &std::path::Path| -> Vec<f64> {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .map(|l| l.trim().parse().unwrap())
            .collect()
    };
    let (dense, out_d) = solve("dense", "mprgp");
    let (free, out_f) = solve("matrix-free", "mprgp");
    assert_eq!(dense.status.code(), Some(0), "{}", text(&dense.stderr));
    assert_eq!(free.status.code(), Some(0), "{}", text(&free.stderr));
    for f in ["lambda_n.txt", "lambda_t.txt", "u.txt"] {
        let (a, b) = (numbers(&out_d.join(f)), numbers(&out_f.join(f)));
        assert_eq!(a.len(), b.len(), "{f}: lengths differ");
        assert!(!a.is_empty(), "{f} is empty");
        let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-8 * scale, "{f}: {x} vs {y}");
        }
    }
    // A method that reads entries of A is refused, naming the way out.
    let (pgs, _) = solve("matrix-free", "pgs");
    assert_ne!(pgs.status.code(), Some(0));
    assert!(text(&pgs.stderr).contains("mprgp"), "{}", text(&pgs.stderr));
}

#[test]
fn ordering_and_threads_from_the_command_line() {
    let dir = TempDir::new("ordering");
    let prob = dir.path().join("problem");
    write(&prob, &problem(3, 4), true);
    let mut answers = Vec::new();
    for ordering in ["amd", "metis", "auto"] {
        let out = dir.path().join(format!("out-{ordering}"));
        let o = run(&[
            "solve",
            prob.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--ordering",
            ordering,
            "--threads",
            "1",
            "--quiet",
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
        let r = report(&out);
        if ordering != "auto" {
            assert_eq!(string(&r, "ordering"), ordering);
        }
        assert_eq!(num(&r, "threads"), 1.0);
        assert!(num(&r, "factor_flops") > 0.0 && num(&r, "factor_nnz") > 0.0);
        answers.push(std::fs::read_to_string(out.join("u.txt")).unwrap());
    }
    let u: Vec<Vec<f64>> = answers
        .iter()
        .map(|t| t.lines().map(|l| l.trim().parse().unwrap()).collect())
        .collect();
    assert!(close(&u[0], &u[1]), "AMD and METIS give the same u");
}

#[test]
fn verbose_prints_more() {
    let dir = TempDir::new("verbose");
    let prob = dir.path().join("problem");
    let out = dir.path().join("out");
    write(&prob, &problem(2, 3), false);
    let quiet = run(&[
        "solve",
        prob.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let loud = run(&[
        "solve",
        prob.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--verbose",
        // A method whose every outer iteration shows (auto's Newton may converge
        // in its warm-up sweeps, before the first).
        "--method",
        "split",
    ]);
    assert_eq!(quiet.status.code(), Some(0));
    assert_eq!(loud.status.code(), Some(0));
    let (q, l) = (text(&quiet.stdout), text(&loud.stdout));
    assert!(l.lines().count() > q.lines().count(), "{q}\n---\n{l}");
    assert!(l.contains("nnz(K)") && l.contains("read seconds"), "{l}");
    // Piped, the progress goes to stderr as plain lines (no carriage return), the
    // first iteration always shown.
    let e = text(&loud.stderr);
    assert!(e.starts_with("iteration      1  err "), "{e}");
    assert!(!e.contains('\r'), "{e}");
    // --quiet prints nothing at all on success, and still writes the outputs.
    std::fs::remove_dir_all(&out).ok();
    let silent = run(&[
        "solve",
        prob.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(silent.status.code(), Some(0));
    assert!(silent.stdout.is_empty() && silent.stderr.is_empty());
    assert!(out.join("report.json").is_file());
}

#[test]
fn no_contacts_is_one_linear_solve() {
    let dir = TempDir::new("m0");
    let prob = dir.path().join("problem");
    let out = dir.path().join("out");
    let mut p = problem(2, 0);
    p.f = vec![1.0, -0.5];
    write(&prob, &p, true);
    let o = run(&[
        "solve",
        prob.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let r = report(&out);
    assert_eq!((num(&r, "m"), num(&r, "d")), (0.0, 2.0));
    assert!(
        mtx::read_vector(&out.join("lambda_n.txt"))
            .unwrap()
            .is_empty()
    );
    // u = K^-1 f, by an independent dense solve.
    let u = mtx::read_vector(&out.join("u.txt")).unwrap();
    let want = common::dense_solve(&p.k, &p.f);
    assert_eq!(u.len(), want.len());
    let scale = want.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    assert!(scale > 0.0);
    for (x, y) in u.iter().zip(&want) {
        assert!((x - y).abs() <= 1e-12 * scale, "u {x} vs K^-1 f {y}");
    }
}

#[test]
fn info_and_max_memory_from_the_command_line() {
    let dir = TempDir::new("memory");
    let prob = dir.path().join("problem");
    write(&prob, &problem(3, 4), true);
    let p = prob.to_str().unwrap();
    // The analysis alone: sizes, ordering, factor, forms and predicted memory.
    let o = run(&["info", p, "--threads", "1"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let shown = text(&o.stdout);
    for needle in [
        "m = 4",
        "d = 3",
        "c = 12",
        "nnz(L)",
        "dual form: dense",
        "split",
        "predicted memory",
    ] {
        assert!(shown.contains(needle), "info lacks \"{needle}\":\n{shown}");
    }
    // A limit too small: info says so (exit 5), solve refuses (exit 3,
    // status out-of-memory, no solution files).
    let o = run(&["info", p, "--max-memory", "1K"]);
    assert_eq!(o.status.code(), Some(5), "{}", text(&o.stdout));
    assert!(text(&o.stdout).contains("does not fit"));
    let out = dir.path().join("out-small");
    let o = run(&[
        "solve",
        p,
        "--out",
        out.to_str().unwrap(),
        "--max-memory",
        "1K",
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o.stderr));
    let r = report(&out);
    assert_eq!(string(&r, "status"), "out-of-memory");
    assert!(string(&r, "message").contains("max_memory"));
    assert!(!out.join("u.txt").exists());
    // A limit that fits: the report carries the predicted and counted peaks.
    let out = dir.path().join("out-fits");
    let o = run(&[
        "solve",
        p,
        "--out",
        out.to_str().unwrap(),
        "--max-memory",
        "1G",
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let r = report(&out);
    let (predicted, peak) = (num(&r, "memory_predicted"), num(&r, "memory_peak"));
    assert!(peak > 0.0 && peak <= predicted, "{predicted} {peak}");
    // Options of solve only, and bad values.
    let o = run(&["info", p, "--tol", "1e-8"]);
    assert_eq!(o.status.code(), Some(2));
    let o = run(&["info", p, "--max-memory", "lots"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("--max-memory"));
}

#[test]
fn help_documents_everything() {
    for flag in ["--help", "-h", "help"] {
        let o = run(&[flag]);
        assert_eq!(o.status.code(), Some(0));
        let h = text(&o.stdout);
        for needle in [
            "dualsplit solve DIR --out OUTDIR [--method NAME] [--tol X] [--max-iter N] \
             [--max-seconds S] [--stall-window N] [--stall-factor X] [--dual-form F] \
             [--ordering O] [--threads N] [--max-memory B] [--verbose]",
            "dualsplit info DIR",
            "--max-memory",
            "memory_predicted",
            "--ordering",
            "metis",
            "--threads",
            "factor_flops",
            "K.mtx",
            "N.mtx",
            "T.mtx",
            "f.txt",
            "g.txt",
            "mu.txt",
            "p.txt",
            "--out",
            "--method",
            "--tol",
            "--max-iter",
            "--max-seconds",
            "--stall-window",
            "--stall-factor",
            "stalled",
            "time-limit",
            "--dual-form",
            "matrix-free",
            "--verbose",
            "u.txt",
            "lambda_n.txt",
            "lambda_t.txt",
            "report.json",
            "status",
            "equilibrium_residual",
            "iterations",
            "open, stick, slip",
            "factor_seconds",
            "EXIT STATUS",
        ] {
            assert!(h.contains(needle), "--help lacks \"{needle}\"");
        }
        for m in Method::ALL {
            assert!(h.contains(m.name()), "--help lacks the method {}", m.name());
        }
    }
    let o = run(&["solve", "--help"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(text(&o.stdout).contains("EXIT STATUS"));
    let o = run(&["--version"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(text(&o.stdout).contains(env!("CARGO_PKG_VERSION")));
}

#[test]
fn bad_command_lines_exit_2() {
    let dir = TempDir::new("usage");
    let prob = dir.path().join("problem");
    write(&prob, &problem(2, 2), true);
    let p = prob.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![], "no command"),
        (vec!["frobnicate"], "unknown command"),
        (vec!["solve", p], "--out OUTDIR is missing"),
        (vec!["solve", "--out", "x"], "DIR is missing"),
        (vec!["solve", p, "--out"], "--out needs a value"),
        (
            vec!["solve", p, "--out", "x", "--method", "cg"],
            "unknown method \"cg\"",
        ),
        (
            vec!["solve", p, "--out", "x", "--dual-form", "sparse"],
            "unknown dual form \"sparse\"",
        ),
        (
            vec!["solve", p, "--out", "x", "--ordering", "rcm"],
            "unknown ordering \"rcm\"",
        ),
        (
            vec!["solve", p, "--out", "x", "--threads", "-1"],
            "--threads",
        ),
        (
            vec!["solve", p, "--out", "x", "--threads", "5000"],
            "--threads",
        ),
        (vec!["solve", p, "--out", "x", "--tol", "0"], "--tol"),
        (vec!["solve", p, "--out", "x", "--tol", "abc"], "--tol"),
        (
            vec!["solve", p, "--out", "x", "--max-iter", "-3"],
            "--max-iter",
        ),
        (
            vec!["solve", p, "--out", "x", "--max-iter", "0"],
            "--max-iter",
        ),
        (
            vec!["solve", p, "--out", "x", "--speed", "3"],
            "unknown option",
        ),
        (vec!["solve", p, p, "--out", "x"], "already given"),
    ];
    for (args, needle) in cases {
        let o = run(&args);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(needle),
            "{args:?}: \"{err}\" lacks \"{needle}\""
        );
        assert!(err.contains("usage:"), "{args:?}");
    }
    let o = run(&["solve", p, "--out", "x", "--method", "cg"]);
    for m in Method::ALL {
        assert!(
            text(&o.stderr).contains(m.name()),
            "the valid methods are listed"
        );
    }
}

#[test]
fn missing_and_malformed_files_exit_3_with_a_clear_message() {
    let dir = TempDir::new("bad");
    let prob = dir.path().join("problem");
    let out = dir.path().join("out");
    let p = problem(3, 3);
    let args = [
        "solve",
        prob.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    // A successful run first, so that stale outputs exist.
    write(&prob, &p, true);
    assert_eq!(run(&args).status.code(), Some(0));
    assert!(out.join("u.txt").is_file());

    // Missing file.
    std::fs::remove_file(prob.join("g.txt")).unwrap();
    let o = run(&args);
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(
        err.contains("g.txt") && err.contains("cannot read"),
        "{err}"
    );
    let r = report(&out);
    assert_eq!(string(&r, "status"), "io");
    assert!(string(&r, "message").contains("g.txt"));
    assert!(!out.join("u.txt").exists(), "stale outputs are removed");

    // Malformed matrix: the file and the line.
    write(&prob, &p, true);
    let kpath = prob.join("K.mtx");
    let ktext = std::fs::read_to_string(&kpath).unwrap();
    let mut lines: Vec<String> = ktext.lines().map(String::from).collect();
    lines[4] = "1 1 one".into();
    std::fs::write(&kpath, lines.join("\n")).unwrap();
    let o = run(&args);
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(
        err.contains("K.mtx line 5:") && err.contains("\"one\""),
        "{err}"
    );
    assert_eq!(string(&report(&out), "status"), "io");

    // Neither mu.txt nor p.txt.
    write(&prob, &p, true);
    std::fs::remove_file(prob.join("mu.txt")).unwrap();
    let o = run(&args);
    assert_eq!(o.status.code(), Some(3));
    assert!(
        text(&o.stderr).contains("neither mu.txt"),
        "{}",
        text(&o.stderr)
    );

    // A problem folder that does not exist.
    let o = run(&[
        "solve",
        dir.path().join("nowhere").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(3));
    assert!(text(&o.stderr).contains("no such folder"));

    // K not symmetric, and not positive definite: the library's error kinds.
    write(&prob, &p, true);
    let mut k = p.k.clone();
    let last = k.values.len() - 2; // an off-diagonal entry of the last column
    k.values[last] += 0.5;
    mtx::write_matrix(&kpath, &k).unwrap();
    let o = run(&args);
    assert_eq!(o.status.code(), Some(3));
    assert!(
        text(&o.stderr).contains("not symmetric"),
        "{}",
        text(&o.stderr)
    );
    assert_eq!(string(&report(&out), "status"), "not-symmetric");
    let mut k = p.k.clone();
    k.values.iter_mut().for_each(|v| *v = -*v);
    mtx::write_matrix(&kpath, &k).unwrap();
    let o = run(&args);
    assert_eq!(o.status.code(), Some(3));
    let r = report(&out);
    assert_eq!(string(&r, "status"), "not-positive-definite");
    assert_eq!(num(&r, "n"), p.k.nrows as f64);

    // A negative friction coefficient.
    write(&prob, &p, true);
    std::fs::write(prob.join("mu.txt"), "0.3\n-0.1\n0.3\n").unwrap();
    let o = run(&args);
    assert_eq!(o.status.code(), Some(3));
    assert_eq!(string(&report(&out), "status"), "negative-friction");
}
