//! `dualsplit`: the command-line solver of problem folders. Run `dualsplit --help`.
//!
//! This command line is a public interface: keep it stable (add, do not change).

use dualsplit::mtx::{self, ProblemFolder};

use dualsplit::{
    ContactProblem, DualForm, Error, ErrorKind, Method, Options, Ordering, Report, SolveStatus,
};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

const HELP: &str = "\
dualsplit: frictional contact solver (Signorini + Tresca or Coulomb friction)

USAGE:
    dualsplit solve DIR --out OUTDIR [--method NAME] [--tol X] [--max-iter N] [--max-seconds S] [--stall-window N] [--stall-factor X] [--dual-form F] [--ordering O] [--threads N] [--max-memory B] [--verbose] [--quiet]
    dualsplit info DIR [--method NAME] [--dual-form F] [--ordering O] [--threads N] [--max-memory B]
    dualsplit --help
    dualsplit --version

    Reads the problem folder DIR, solves it through the same code path as the C API
    (ds_problem_new + ds_solve: one increment, exactly as given, no history) and
    writes the solution and a report into OUTDIR (created if needed).

    `info` reads DIR and prints what the analysis alone tells (ds_analyse: K's
    ordering and symbolic factorisation, no numeric work): n, m, c, nnz(K), the
    ordering chosen, nnz(L) and the flops of the factorisation, the dual form the
    problem would be created with and the one a solve with the method uses, and
    the predicted peak memory of the setup, of what the problem holds and of one
    solve, against the memory limit. Exit status 0, or 3 when the problem is
    rejected, or 5 when the setup or the solve would exceed the limit.

PROBLEM FOLDER (DIR):
    K.mtx    K, n x n, symmetric positive definite (Matrix Market)
    N.mtx    N, m x n (Matrix Market)
    T.mtx    T, (d-1) m x n, tangent rows contact by contact (Matrix Market)
    f.txt    f, n numbers, one per line
    g.txt    g, m numbers, one per line
    mu.txt   Coulomb coefficients, m numbers      } exactly one
    p.txt    Tresca slip bounds, m numbers        } of these two
    Any other file is ignored. d (2 or 3) is inferred from rows(T) = (d-1) rows(N);
    with no contacts (m = 0) d = 2 is reported. Matrices: Matrix Market coordinate
    real, general or symmetric header (symmetric is mirrored), 1-based, duplicate
    entries summed; a full K must be symmetric to 1e-10 * max|K|.
    The problem is: K u = f - N^T lambda_n - T^T lambda_t, N u <= g, lambda_n >= 0,
    complementarity, |lambda_t,i| <= p_i (p_i = mu_i lambda_n,i for Coulomb), the
    friction force -T^T lambda_t opposing the slip T u.

OPTIONS:
    --out OUTDIR      output folder (required)
    --method NAME     the method run on the condensed dual (default {DEFAULT_METHOD}):
{METHODS}
    --tol X           stop when err <= X (default {TOL}); err is the relative
                      natural-map residual of the contact conditions, measured on the
                      recovered u (docs/design.md section 5)
    --max-iter N      maximum number of outer iterations (default {MAX_ITER}): sweeps for
                      pgs, normal/tangential alternations for split and block-gs,
                      Newton steps for newton
    --max-seconds S   wall-clock budget of the solve in seconds, 0 for none (default
                      0); checked between outer iterations, the setup not counted;
                      the run ends with status \"time-limit\" and the iterate with
                      the lowest err
    --stall-window N  the stagnation test (default {STALL_WINDOW}, 0 turns it off):
                      the run ends with status \"stalled\" and the iterate with the
                      lowest err when the lowest err has not dropped by the factor
                      --stall-factor over the last N outer iterations
    --stall-factor X  in (0, 1] (default {STALL_FACTOR})
    --dual-form F     auto (default), dense or matrix-free: whether the condensed dual
                      A is assembled (dense while d m <= 8000) or applied through K's
                      factor; matrix-free runs with --method auto, newton or mprgp
    --ordering O      auto (default), amd or metis: the fill-reducing ordering of K
                      (auto: in 2D AMD, METIS as well on large fronts, the
                      one with fewer flops kept; in 3D METIS)
    --threads N       threads for the factorisation and the dense kernels: 0 for all
                      cores (default), 1 for this thread only
    --max-memory B    the most bytes the library's large allocations may take (K's
                      factor, the condensed dual, the method's dense work space);
                      0 (default) for the limit of this process or machine. A
                      number of bytes, or with a suffix K, M or G (2^10, 2^20,
                      2^30). A setup or solve predicted to need more is refused
                      before the work (status \"out-of-memory\", exit 3); the dual
                      form auto then creates the matrix-free dual where it fits
    --verbose         print the problem sizes and the timings of every stage
    --quiet           print nothing but errors (no progress, no summary)
    -h, --help        print this help
    -V, --version     print the version
    Options may also be written --name=VALUE.

OUTPUT (OUTDIR):
    u.txt             u, n numbers, one per line
    lambda_n.txt      lambda_n, m numbers (compressive normal forces, >= 0)
    lambda_t.txt      lambda_t, (d-1) m numbers, contact by contact
    report.json       one JSON object:
        status              \"converged\", \"not-converged\" (iteration limit, or
                            infeasible: err null), \"stalled\", \"time-limit\",
                            or the error that stopped the
                            run: \"io\" (missing or malformed file), \"bad-size\",
                            \"not-finite\", \"not-symmetric\", \"not-positive-definite\",
                            \"negative-friction\", \"out-of-memory\", \"bad-argument\"
        message             what went wrong (error statuses only)
        problem             DIR as given
        method, tol, max_iter, max_seconds, stall_window, stall_factor,
        friction (\"coulomb\" or \"tresca\")
        n, m, d             DOFs, contacts, contact dimension
        err                 the error reached (null if not finite)
        equilibrium_residual   |K u - f + N^T lambda_n + T^T lambda_t| / |f|
        iterations          outer iterations
        inner_iterations    projected Gauss-Seidel sweeps of the sub-problems
        open, stick, slip   contact state counts
        read_seconds, factor_seconds, condense_seconds, solve_seconds
                            times of reading DIR, of the Cholesky factorisation of K,
                            of forming the condensed dual, and of the iterations
        ordering, factor_nnz, factor_flops
                            the ordering K was factored with (amd or metis), the
                            nonzeros of its Cholesky factor and the flops of one
                            factorisation
        threads             threads the solve could use
        analyse_seconds     time of K's analysis (ordering, symbolic factor)
        method_run, choice  the method that gave the answer and, for --method
                            auto, why it was chosen (empty otherwise)
        memory_predicted, memory_peak
                            the solve's predicted and counted peak bytes of the
                            library's large allocations
        compliant_contacts  contacts with a compliant law (cn.txt or kt.txt
                            finite there; 0: the rigid problem was solved)
        rhs_seconds, iterate_seconds, recover_seconds
                            where solve_seconds went: the right-hand side, the
                            method's iterations, the recovery of u and its error
    Numbers are written with full precision (shortest round-trip form). The four
    files left in OUTDIR by an earlier run are removed first; on an error only
    report.json is written (when OUTDIR can be written).
    A short summary is printed on standard output, errors on standard error.

EXIT STATUS:
    0   converged (err <= tol)
    1   solved, but not converged: iteration limit, stalled or time limit
        (outputs written: the iterate with the lowest err)
    2   bad command line
    3   the problem could not be read or was rejected (missing or malformed file,
        K not symmetric or not positive definite, negative friction, ...)
    4   the outputs could not be written
    5   (info) the setup or a solve would exceed the memory limit
";

/// What each method is, for --help (by name, so that a method added to the
/// library shows up in the list even before it is described here).
fn method_description(name: &str) -> &'static str {
    match name {
        "split" => "Pop's dual splitting, Schur complement variant",
        "block-gs" => "block Gauss-Seidel on (lambda_n, lambda_t)",
        "pgs" => "projected Gauss-Seidel on the whole dual (Siconos NSGS)",
        "newton" => "semismooth Newton (primal-dual active set) on the dual",
        "auto" => {
            "the library's choice: newton on a dense dual (split-mprgp where it stalls), mprgp matrix-free"
        }
        _ => "",
    }
}

/// HELP with the methods and the defaults filled in from the library.
fn help_text() -> String {
    let mut list = String::new();
    for m in Method::ALL {
        let _ = writeln!(
            list,
            "                        {:<10}{}",
            m.name(),
            method_description(m.name())
        );
    }
    let defaults = Options::default();
    HELP.replace("{METHODS}\n", &list)
        .replace("{DEFAULT_METHOD}", defaults.method.name())
        .replace("{TOL}", &format!("{:e}", defaults.tol))
        .replace("{MAX_ITER}", &defaults.max_outer.to_string())
        .replace("{STALL_WINDOW}", &defaults.stall_window.to_string())
        .replace("{STALL_FACTOR}", &defaults.stall_factor.to_string())
}

/// Exit codes (documented in HELP).
const EXIT_NOT_CONVERGED: u8 = 1;
const EXIT_USAGE: u8 = 2;
const EXIT_PROBLEM: u8 = 3;
const EXIT_OUTPUT: u8 = 4;
const EXIT_TOO_BIG: u8 = 5;

/// The parsed `solve` command.
struct SolveArgs {
    dir: PathBuf,
    out: PathBuf,
    opts: Options,
    verbose: bool,
    quiet: bool,
}

enum Command {
    Help,
    Version,
    Solve(SolveArgs),
    /// `info DIR`: the analysis alone (`out` unused).
    Info(SolveArgs),
}

fn parse_args(args: &[String]) -> Result<Command, String> {
    let Some(first) = args.first() else {
        return Err("no command given".into());
    };
    match first.as_str() {
        "-h" | "--help" | "help" => return Ok(Command::Help),
        "-V" | "--version" => return Ok(Command::Version),
        "solve" | "info" => {}
        other => return Err(format!("unknown command \"{other}\"")),
    }
    let info = first == "info";
    let mut dir: Option<PathBuf> = None;
    let mut out: Option<PathBuf> = None;
    let mut opts = Options::default();
    let mut verbose = false;
    let mut quiet = false;
    let mut k = 1;
    while k < args.len() {
        let arg = &args[k];
        k += 1;
        if arg == "-h" || arg == "--help" {
            return Ok(Command::Help);
        }
        if !arg.starts_with("--") {
            if dir.is_some() {
                return Err(format!(
                    "unexpected argument \"{arg}\": DIR is already given"
                ));
            }
            dir = Some(PathBuf::from(arg));
            continue;
        }
        let (name, inline) = match arg.split_once('=') {
            Some((n, v)) => (n, Some(v.to_string())),
            None => (arg.as_str(), None),
        };
        if name == "--verbose" {
            if inline.is_some() {
                return Err("--verbose takes no value".into());
            }
            verbose = true;
            continue;
        }
        if name == "--quiet" {
            if inline.is_some() {
                return Err("--quiet takes no value".into());
            }
            quiet = true;
            continue;
        }
        if !matches!(
            name,
            "--out"
                | "--method"
                | "--tol"
                | "--max-iter"
                | "--max-seconds"
                | "--stall-window"
                | "--stall-factor"
                | "--dual-form"
                | "--ordering"
                | "--threads"
                | "--max-memory"
        ) {
            return Err(format!("unknown option \"{name}\""));
        }
        if info
            && !matches!(
                name,
                "--method" | "--dual-form" | "--ordering" | "--threads" | "--max-memory"
            )
        {
            return Err(format!("info: option \"{name}\" applies to solve only"));
        }
        let value = match inline {
            Some(v) => v,
            None => {
                let Some(v) = args.get(k) else {
                    return Err(format!("{name} needs a value"));
                };
                k += 1;
                v.clone()
            }
        };
        match name {
            "--out" => out = Some(PathBuf::from(value)),
            "--method" => {
                opts.method = Method::from_name(&value).ok_or_else(|| {
                    let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
                    format!(
                        "unknown method \"{value}\": expected one of {}",
                        names.join(", ")
                    )
                })?;
            }
            "--ordering" => {
                opts.ordering = Ordering::from_name(&value).ok_or_else(|| {
                    format!("unknown ordering \"{value}\": expected one of auto, amd, metis")
                })?;
            }
            "--threads" => {
                opts.threads = value
                    .parse::<usize>()
                    .ok()
                    .filter(|&t| t <= 4096)
                    .ok_or_else(|| {
                        format!("--threads \"{value}\": expected an integer from 0 to 4096")
                    })?;
            }
            "--max-memory" => {
                opts.max_memory = parse_bytes(&value).ok_or_else(|| {
                    format!(
                        "--max-memory \"{value}\": expected a number of bytes, optionally \
                         with a suffix K, M or G"
                    )
                })?;
            }
            "--dual-form" => {
                opts.dual_form = DualForm::from_name(&value).ok_or_else(|| {
                    format!(
                        "unknown dual form \"{value}\": expected one of auto, dense, matrix-free"
                    )
                })?;
            }
            "--tol" => {
                opts.tol = value
                    .parse::<f64>()
                    .ok()
                    .filter(|t| t.is_finite() && *t > 0.0)
                    .ok_or_else(|| {
                        format!("--tol \"{value}\": expected a positive finite number")
                    })?;
            }
            "--max-iter" => {
                opts.max_outer =
                    value
                        .parse::<usize>()
                        .ok()
                        .filter(|n| *n > 0)
                        .ok_or_else(|| {
                            format!("--max-iter \"{value}\": expected a positive integer")
                        })?;
            }
            "--max-seconds" => {
                opts.max_seconds = value
                    .parse::<f64>()
                    .ok()
                    .filter(|t| t.is_finite() && *t >= 0.0)
                    .ok_or_else(|| {
                        format!("--max-seconds \"{value}\": expected a finite number >= 0")
                    })?;
            }
            "--stall-window" => {
                opts.stall_window = value
                    .parse::<usize>()
                    .map_err(|_| format!("--stall-window \"{value}\": expected an integer >= 0"))?;
            }
            "--stall-factor" => {
                opts.stall_factor = value
                    .parse::<f64>()
                    .ok()
                    .filter(|x| *x > 0.0 && *x <= 1.0)
                    .ok_or_else(|| {
                        format!("--stall-factor \"{value}\": expected a number in (0, 1]")
                    })?;
            }
            _ => unreachable!("option names are checked above"),
        }
    }
    let Some(dir) = dir else {
        return Err(format!("{first}: the problem folder DIR is missing"));
    };
    if info {
        return Ok(Command::Info(SolveArgs {
            dir,
            out: PathBuf::new(),
            opts,
            verbose: false,
            quiet: false,
        }));
    }
    let Some(out) = out else {
        return Err("solve: --out OUTDIR is missing".into());
    };
    Ok(Command::Solve(SolveArgs {
        dir,
        out,
        opts,
        verbose: verbose && !quiet,
        quiet,
    }))
}

/// A byte count: digits, optionally followed by K, M or G (2^10, 2^20, 2^30).
fn parse_bytes(text: &str) -> Option<usize> {
    let (digits, shift) = match text.as_bytes().last()? {
        b'K' | b'k' => (&text[..text.len() - 1], 10),
        b'M' | b'm' => (&text[..text.len() - 1], 20),
        b'G' | b'g' => (&text[..text.len() - 1], 30),
        _ => (text, 0),
    };
    digits.parse::<usize>().ok()?.checked_mul(1 << shift)
}

/// A JSON object written by hand, keys in insertion order.
struct Json {
    text: String,
}

impl Json {
    fn new() -> Self {
        Json {
            text: String::from("{\n"),
        }
    }

    fn key(&mut self, key: &str) {
        if self.text.len() > 2 {
            self.text.push_str(",\n");
        }
        self.text.push_str("  ");
        push_json_string(&mut self.text, key);
        self.text.push_str(": ");
    }

    fn string(&mut self, key: &str, value: &str) {
        self.key(key);
        push_json_string(&mut self.text, value);
    }

    fn number(&mut self, key: &str, value: f64) {
        self.key(key);
        if value.is_finite() {
            // Rust's shortest round-trip form is valid JSON ("1e-10", "0.5", "3").
            let _ = write!(self.text, "{value:?}");
        } else {
            self.text.push_str("null");
        }
    }

    fn integer(&mut self, key: &str, value: usize) {
        self.key(key);
        let _ = write!(self.text, "{value}");
    }

    fn finish(mut self) -> String {
        self.text.push_str("\n}\n");
        self.text
    }
}

fn push_json_string(s: &mut String, value: &str) {
    s.push('"');
    for ch in value.chars() {
        match ch {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\r' => s.push_str("\\r"),
            '\t' => s.push_str("\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(s, "\\u{:04x}", c as u32);
            }
            c => s.push(c),
        }
    }
    s.push('"');
}

/// "NotPositiveDefinite" -> "not-positive-definite": the status words of
/// report.json are the library's enum names in kebab case, so a kind or status
/// added to the library gets a word without a change here.
fn kebab(debug_name: &str) -> String {
    let mut w = String::new();
    for (k, c) in debug_name.chars().enumerate() {
        if c.is_ascii_uppercase() {
            if k > 0 {
                w.push('-');
            }
            w.push(c.to_ascii_lowercase());
        } else {
            w.push(c);
        }
    }
    w
}

/// The status word of an error kind ("io", "not-symmetric", ...).
fn error_word(kind: ErrorKind) -> String {
    kebab(&format!("{kind:?}"))
}

/// The status word of a solve ("converged", "not-converged", ...).
fn status_word(status: SolveStatus) -> String {
    status.name().to_string()
}

/// The common head of report.json.
fn report_head(status: &str) -> Json {
    let mut j = Json::new();
    j.string("status", status);
    j
}

fn report_options(j: &mut Json, args: &SolveArgs) {
    j.string("problem", &args.dir.display().to_string());
    j.string("method", args.opts.method.name());
    j.number("tol", args.opts.tol);
    j.integer("max_iter", args.opts.max_outer);
    j.number("max_seconds", args.opts.max_seconds);
    j.integer("stall_window", args.opts.stall_window);
    j.number("stall_factor", args.opts.stall_factor);
}

/// What report.json says about the problem.
struct Sizes {
    law: &'static str,
    n: usize,
    m: usize,
    d: usize,
}

fn report_problem(j: &mut Json, pf: &Sizes) {
    j.string("friction", pf.law);
    j.integer("n", pf.n);
    j.integer("m", pf.m);
    j.integer("d", pf.d);
}

fn success_report(args: &SolveArgs, pf: &Sizes, r: &Report, read_s: f64) -> String {
    let mut j = report_head(&status_word(r.status));
    report_options(&mut j, args);
    report_problem(&mut j, pf);
    j.number("err", r.err);
    j.number("equilibrium_residual", r.equilibrium_residual);
    j.integer("iterations", r.outer_iterations);
    j.integer("inner_iterations", r.inner_iterations);
    j.integer("open", r.n_open);
    j.integer("stick", r.n_stick);
    j.integer("slip", r.n_slip);
    j.number("read_seconds", read_s);
    j.number("factor_seconds", r.factor_seconds);
    j.number("condense_seconds", r.condense_seconds);
    j.number("solve_seconds", r.solve_seconds);
    j.string("ordering", r.ordering.name());
    j.integer("factor_nnz", r.factor_nnz);
    j.number("factor_flops", r.factor_flops);
    j.integer("threads", r.threads);
    j.number("analyse_seconds", r.analyse_seconds);
    j.string("method_run", r.method.name());
    j.string("choice", &r.choice);
    j.integer("memory_predicted", r.memory_predicted);
    j.integer("memory_peak", r.memory_peak);
    j.integer("compliant_contacts", r.compliant_contacts);
    j.number("rhs_seconds", r.rhs_seconds);
    j.number("iterate_seconds", r.iterate_seconds);
    j.number("recover_seconds", r.recover_seconds);
    j.finish()
}

fn error_report(args: &SolveArgs, pf: Option<&Sizes>, e: &Error) -> String {
    let mut j = report_head(&error_word(e.kind));
    j.string("message", &e.message);
    report_options(&mut j, args);
    if let Some(pf) = pf {
        report_problem(&mut j, pf);
    }
    j.finish()
}

const SOLUTION_FILES: [&str; 3] = ["u.txt", "lambda_n.txt", "lambda_t.txt"];

/// Creates OUTDIR and removes the solution files of an earlier run.
fn prepare_out(out: &Path) -> Result<(), String> {
    std::fs::create_dir_all(out)
        .map_err(|e| format!("cannot create output folder {}: {e}", out.display()))?;
    for name in SOLUTION_FILES.iter().chain(&["report.json"]) {
        let p = out.join(name);
        match std::fs::remove_file(&p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(format!("cannot remove {}: {e}", p.display()));
            }
            _ => {}
        }
    }
    Ok(())
}

fn write_report(out: &Path, text: &str) -> Result<(), String> {
    let p = out.join("report.json");
    std::fs::write(&p, text).map_err(|e| format!("cannot write {}: {e}", p.display()))
}

/// Reports an error that stopped the run: on stderr, and in report.json.
fn fail_run(args: &SolveArgs, pf: Option<&Sizes>, e: &Error) -> ExitCode {
    eprintln!("dualsplit: error: {}", e.message);
    if let Err(w) = write_report(&args.out, &error_report(args, pf, e)) {
        eprintln!("dualsplit: error: {w}");
    }
    ExitCode::from(EXIT_PROBLEM)
}

fn solve(args: &SolveArgs) -> ExitCode {
    if let Err(e) = prepare_out(&args.out) {
        eprintln!("dualsplit: error: {e}");
        return ExitCode::from(EXIT_OUTPUT);
    }
    let verbose = args.verbose;
    let t0 = Instant::now();
    let pf = match mtx::read_problem(&args.dir) {
        Ok(pf) => pf,
        Err(e) => return fail_run(args, None, &e),
    };
    let read_s = t0.elapsed().as_secs_f64();
    let sizes = Sizes {
        law: pf.friction.law_name(),
        n: pf.n_dofs(),
        m: pf.n_contacts(),
        d: pf.d,
    };
    let (n, m, d) = (sizes.n, sizes.m, sizes.d);
    if verbose {
        println!(
            "read {} in {read_s:.3} s: n = {n}, m = {m}, d = {d}, {} friction, \
             nnz(K) = {}, nnz(N) = {}, nnz(T) = {}",
            args.dir.display(),
            sizes.law,
            pf.k.nnz(),
            pf.n.nnz(),
            pf.t.nnz()
        );
        println!(
            "method {}, tol {:e}, max-iter {}, max-inner {}",
            args.opts.method.name(),
            args.opts.tol,
            args.opts.max_outer,
            args.opts.max_inner
        );
    }
    let ProblemFolder {
        k,
        n: nmat,
        t,
        f,
        g,
        friction,
        interface,
        ..
    } = pf;
    let t1 = Instant::now();
    let mut problem = match ContactProblem::from_csc_with(d, k, nmat, t, &args.opts) {
        Ok(p) => p,
        Err(e) => return fail_run(args, Some(&sizes), &e),
    };
    if verbose {
        let c = problem.dual_unknowns();
        println!(
            "factored K and formed the condensed dual ({c} x {c}) in {:.3} s",
            t1.elapsed().as_secs_f64()
        );
    }
    let mut progress = Progress::new();
    let mut show = |p: &dualsplit::Progress| {
        progress.show(p);
        true
    };
    let monitor: Option<dualsplit::Monitor<'_>> = if args.quiet { None } else { Some(&mut show) };
    let law = &interface;
    let result = problem
        .set_compliance(law.cn.as_deref(), law.mn.as_deref(), law.kt.as_deref())
        .and_then(|()| {
            let lt = law.lt_prev.as_deref();
            problem.solve_history_increment(&f, &g, friction.as_friction(), lt, &args.opts, monitor)
        });
    progress.finish();
    let sol = match result {
        Ok(s) => s,
        Err(e) => return fail_run(args, Some(&sizes), &e),
    };
    let r = &sol.report;
    let outputs = [
        ("u.txt", &sol.u),
        ("lambda_n.txt", &sol.lambda_n),
        ("lambda_t.txt", &sol.lambda_t),
    ];
    for (name, x) in outputs {
        if let Err(e) = mtx::write_vector(&args.out.join(name), x) {
            eprintln!("dualsplit: error: {}", e.message);
            return ExitCode::from(EXIT_OUTPUT);
        }
    }
    if let Err(e) = write_report(&args.out, &success_report(args, &sizes, r, read_s)) {
        eprintln!("dualsplit: error: {e}");
        return ExitCode::from(EXIT_OUTPUT);
    }
    if !args.quiet {
        print_summary(args, &sizes, r, read_s);
    }
    exit_code(r)
}

/// `info DIR`: the analysis alone, printed.
fn info(args: &SolveArgs) -> ExitCode {
    let pf = match mtx::read_problem(&args.dir) {
        Ok(pf) => pf,
        Err(e) => {
            eprintln!("dualsplit: error: {}", e.message);
            return ExitCode::from(EXIT_PROBLEM);
        }
    };
    let i = match ContactProblem::analyse_csc(pf.d, &pf.k, &pf.n, &pf.t, &args.opts) {
        Ok(i) => i,
        Err(e) => {
            eprintln!("dualsplit: error: {}", e.message);
            return ExitCode::from(EXIT_PROBLEM);
        }
    };
    let mb = |b: usize| format!("{:.1} MB", b as f64 / 1e6);
    println!("{}", args.dir.display());
    let compliant = pf.interface.compliant_contacts(i.m);
    println!(
        "  n = {}, m = {}, d = {}, c = {} dual unknowns, nnz(K) = {}",
        i.n, i.m, i.d, i.c, i.nnz_k
    );
    if compliant > 0 {
        println!("  interface: compliant on {compliant} contacts (cn.txt, kt.txt)");
    }
    println!(
        "  ordering {}: nnz(L) = {}, {:.3e} flops per factorisation (analysed in {:.3} s)",
        i.ordering.name(),
        i.factor_nnz,
        i.factor_flops,
        i.analyse_seconds
    );
    println!(
        "  dual form: {} at setup; method {} solves on the {} dual",
        i.setup_form.name(),
        i.method.name(),
        i.solve_form.name()
    );
    let limit = if i.memory_limit > 0 {
        mb(i.memory_limit)
    } else {
        "unknown".to_string()
    };
    println!(
        "  predicted memory: setup {}, held {}, one solve {}, a refactorisation {} (limit {limit})",
        mb(i.setup_bytes),
        mb(i.resident_bytes),
        mb(i.solve_bytes),
        mb(i.refactor_bytes)
    );
    let fits = |b: usize| i.memory_limit == 0 || b <= i.memory_limit;
    if fits(i.setup_bytes) && fits(i.solve_bytes) {
        ExitCode::SUCCESS
    } else {
        println!("  does not fit the memory limit: see --max-memory, --dual-form, --method");
        ExitCode::from(EXIT_TOO_BIG)
    }
}

/// Exit code of a finished solve: 0 only when converged.
fn exit_code(r: &dualsplit::Report) -> ExitCode {
    if r.status == SolveStatus::Converged {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(EXIT_NOT_CONVERGED)
    }
}

/// The human summary: a verdict line, then a table.
fn print_summary(args: &SolveArgs, sizes: &Sizes, r: &dualsplit::Report, read_s: f64) {
    let (n, m, d, law) = (sizes.n, sizes.m, sizes.d, sizes.law);
    println!(
        "{}: n = {n}, m = {m}, d = {d}, {law} friction",
        args.dir.display()
    );
    let verdict = if r.status == SolveStatus::Converged {
        format!("converged: err {:.3e} <= tol {:e}", r.err, args.opts.tol)
    } else if r.status == SolveStatus::NotConverged {
        format!(
            "NOT converged: err {:.3e} > tol {:e} after the iteration limit",
            r.err, args.opts.tol
        )
    } else if r.status == SolveStatus::Stalled {
        format!(
            "NOT converged, stalled: err {:.3e} > tol {:e}, the best err not lowered by \
             the factor {} over {} outer iterations",
            r.err, args.opts.tol, args.opts.stall_factor, args.opts.stall_window
        )
    } else if r.status == SolveStatus::TimeLimit {
        format!(
            "NOT converged, time limit: err {:.3e} > tol {:e} after {} s",
            r.err, args.opts.tol, args.opts.max_seconds
        )
    } else {
        format!("{}: err {:.3e}", status_word(r.status), r.err)
    };
    println!("{verdict}");
    if args.verbose {
        println!("  {:<22}{read_s:.3e}", "read seconds");
    }
    println!("  {:<22}{}", "method", r.method.name());
    if !r.choice.is_empty() {
        println!("  {:<22}{}", "chosen by auto", r.choice);
    }
    println!("  {:<22}{:.3e} (tol {:e})", "err", r.err, args.opts.tol);
    println!(
        "  {:<22}{:.3e}",
        "equilibrium residual", r.equilibrium_residual
    );
    println!(
        "  {:<22}{} outer, {} inner",
        "iterations", r.outer_iterations, r.inner_iterations
    );
    println!(
        "  {:<22}{} open, {} stick, {} slip",
        "contacts", r.n_open, r.n_stick, r.n_slip
    );
    println!(
        "  {:<22}{}, nnz(L) {:.3e}, {:.3e} flops, {} thread(s)",
        "factor",
        r.ordering.name(),
        r.factor_nnz as f64,
        r.factor_flops,
        r.threads
    );
    println!(
        "  {:<22}factor {:.3e}, condense {:.3e}, solve {:.3e}",
        "seconds", r.factor_seconds, r.condense_seconds, r.solve_seconds
    );
    println!(
        "wrote u.txt, lambda_n.txt, lambda_t.txt, report.json in {}",
        args.out.display()
    );
}

/// The progress line on stderr: updated in place on a terminal (at most 20 times a
/// second), plain lines when piped (at most two a second, and the first iteration).
struct Progress {
    terminal: bool,
    last: Option<Instant>,
    shown: bool,
}

impl Progress {
    fn new() -> Progress {
        use std::io::IsTerminal;
        Progress {
            terminal: std::io::stderr().is_terminal(),
            last: None,
            shown: false,
        }
    }

    fn show(&mut self, p: &dualsplit::Progress) {
        let every = if self.terminal { 0.05 } else { 0.5 };
        if self.last.is_some_and(|t| t.elapsed().as_secs_f64() < every) {
            return;
        }
        self.last = Some(Instant::now());
        let line = format!(
            "iteration {:>6}  err {:.3e}  open {:>5} stick {:>5} slip {:>5}  {:8.3} s",
            p.iteration, p.err, p.n_open, p.n_stick, p.n_slip, p.elapsed_seconds
        );
        if self.terminal {
            eprint!("\r{line}");
        } else {
            eprintln!("{line}");
        }
        self.shown = true;
    }

    fn finish(&self) {
        if self.terminal && self.shown {
            eprintln!();
        }
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match parse_args(&args) {
        Ok(Command::Help) => {
            print!("{}", help_text());
            ExitCode::SUCCESS
        }
        Ok(Command::Version) => {
            println!("dualsplit {}", env!("CARGO_PKG_VERSION"));
            ExitCode::SUCCESS
        }
        Ok(Command::Solve(a)) => solve(&a),
        Ok(Command::Info(a)) => info(&a),
        Err(msg) => {
            eprintln!("dualsplit: error: {msg}");
            eprintln!(
                "usage: dualsplit solve DIR --out OUTDIR [--method NAME] [--tol X] [--max-iter N] [--max-seconds S] [--stall-window N] [--stall-factor X] [--dual-form F] [--ordering O] [--threads N] [--max-memory B] [--verbose] [--quiet]"
            );
            eprintln!(
                "       dualsplit info DIR [--method NAME] [--dual-form F] [--ordering O] [--threads N] [--max-memory B]"
            );
            eprintln!("       dualsplit --help");
            ExitCode::from(EXIT_USAGE)
        }
    }
}
