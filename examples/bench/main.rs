//! The work-precision benchmark of dualsplit (issue 4).
//!
//! ```text
//! cargo run --release --example bench -- [--quick | --big] [--scenes A,B,..]
//!     [--out DIR] [--cap SECONDS] [--rep-below S] [--solves-cap S]
//!     [--no-clarabel] [--clarabel-max-n N] [--clarabel-max-n-3d N]
//!     [--clarabel-limit S] [--only ours|clarabel] [--frictions tresca,coulomb]
//!     [--append] [--report-only]
//! ```
//!
//! For each scene (2D Q4 / 3D H8 blocks on a rigid foundation with a curved gap, see
//! `scene.rs`) a child process (this binary with `--child`) measures, so that each
//! scene gets its own peak memory:
//!
//! - the sparse Cholesky factorisation of K alone (plain AMD ordering), one solve;
//! - `ContactProblem::from_csc` (factor with the contact DOFs last + the condensed
//!   dual from the factor's trailing block), and the condensation by solves (run
//!   where its estimate is below a cap, extrapolated from a block of solves beyond);
//! - every method of `Method::ALL` at the tolerances 1e-2 .. 1e-12, Tresca and
//!   Coulomb: wall time (median of 3 when a run is short), err, iterations;
//! - a history: the first step (cold) and a second, warm-started step with the
//!   load raised by 5 %;
//! - in a second child: Clarabel on the same Tresca problem.
//!
//! The rows go to DIR/results.csv; the figures (SVG) and DIR/summary.md are drawn
//! from that file (`--report-only` redraws them without measuring).

mod clarabel_ref;
mod plot;
mod report;
mod row;
mod scene;

use dualsplit::dual::{Condensation, Dual};
use dualsplit::factor::Factor;
use dualsplit::{ContactProblem, Friction, Method, Options, SolveStatus};
use row::{Row, median, peak_mb};
use scene::{Scene, Spec};
use std::io::Write as _;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

/// Tolerances of the work-precision series.
const TOLS: [f64; 6] = [1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12];

/// The default scenes: the 2D family (aspect 8: m grows as sqrt(n)) from 1e4 to 1e6
/// DOFs, two off-family 2D scenes (few contacts; many contacts), the 3D family
/// (nx = ny = 2 nz) up to 2e5 DOFs.
const FULL: &[&str] = &[
    "2d-100x50",
    "2d-200x25",
    "2d-400x50",
    "2d-800x100",
    "2d-1400x175",
    "2d-2000x250",
    "3d-10x10x5",
    "3d-20x20x10",
    "3d-30x30x15",
    "3d-40x40x20",
];

/// Added by `--big`: 5,000 contacts in 2D (c = 10,002), and 2e5 DOFs in 3D.
const BIG: &[&str] = &["2d-5000x100", "3d-50x50x25"];

const QUICK: &[&str] = &["2d-100x50", "2d-200x25", "3d-10x10x5"];

#[derive(Clone, Debug)]
struct Config {
    quick: bool,
    scenes: Vec<String>,
    out: PathBuf,
    /// Time cap of one solve (a method stops its tolerance series past it).
    cap: f64,
    /// Runs shorter than this are repeated (3 runs, median).
    rep_below: f64,
    /// The condensation by solves runs only when its estimate is below this.
    solves_cap: f64,
    clarabel: bool,
    /// Clarabel runs on 2D scenes up to this many DOFs ...
    clarabel_max_n: usize,
    /// ... and on 3D scenes up to this many (its default direct solver, QDLDL,
    /// fills in badly in 3D: about 65 s on 13,230 DOFs).
    clarabel_max_n_3d: usize,
    /// Only this part of each scene ("ours" or "clarabel"); both when None.
    only: Option<String>,
    /// Append to an existing results.csv instead of starting a new one.
    append: bool,
    clarabel_limit: f64,
    frictions: Vec<String>,
    report_only: bool,
    child: Option<String>,
}

impl Config {
    fn parse() -> Config {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let quick = args.iter().any(|a| a == "--quick");
        let mut c = Config {
            quick,
            scenes: Vec::new(),
            out: PathBuf::from("bench_results"),
            cap: if quick { 1.0 } else { 20.0 },
            rep_below: if quick { 0.1 } else { 0.5 },
            solves_cap: if quick { 2.0 } else { 30.0 },
            clarabel: true,
            clarabel_max_n: 1_100_000,
            clarabel_max_n_3d: 15_000,
            only: None,
            append: false,
            clarabel_limit: if quick { 20.0 } else { 150.0 },
            frictions: vec!["tresca".into(), "coulomb".into()],
            report_only: false,
            child: None,
        };
        let mut big = false;
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut val = || it.next().cloned().unwrap_or_else(|| usage(a));
            match a.as_str() {
                "--quick" => {}
                "--big" => big = true,
                "--scenes" => c.scenes = val().split(',').map(String::from).collect(),
                "--out" => c.out = PathBuf::from(val()),
                "--cap" => c.cap = val().parse().unwrap_or_else(|_| usage(a)),
                "--rep-below" => c.rep_below = val().parse().unwrap_or_else(|_| usage(a)),
                "--solves-cap" => c.solves_cap = val().parse().unwrap_or_else(|_| usage(a)),
                "--no-clarabel" => c.clarabel = false,
                "--clarabel-max-n" => c.clarabel_max_n = val().parse().unwrap_or_else(|_| usage(a)),
                "--clarabel-max-n-3d" => {
                    c.clarabel_max_n_3d = val().parse().unwrap_or_else(|_| usage(a))
                }
                "--only" => c.only = Some(val()),
                "--append" => c.append = true,
                "--clarabel-limit" => c.clarabel_limit = val().parse().unwrap_or_else(|_| usage(a)),
                "--frictions" => c.frictions = val().split(',').map(String::from).collect(),
                "--report-only" => c.report_only = true,
                "--child" => c.child = Some(val()),
                "-h" | "--help" => usage(""),
                _ => usage(a),
            }
        }
        if c.scenes.is_empty() {
            let list = if quick { QUICK } else { FULL };
            c.scenes = list.iter().map(|s| s.to_string()).collect();
            if big {
                c.scenes.extend(BIG.iter().map(|s| s.to_string()));
            }
        }
        for s in &c.scenes {
            if Spec::parse(s).is_none() {
                eprintln!("bad scene name {s:?} (expected 2d-NXxNY or 3d-NXxNYxNZ)");
                std::process::exit(2);
            }
        }
        for f in &c.frictions {
            if f != "tresca" && f != "coulomb" {
                usage(f);
            }
        }
        c
    }

    /// The arguments that hand this configuration to a child.
    fn child_args(&self, what: &str, scene: &str) -> Vec<String> {
        let mut v = vec![
            "--child".to_string(),
            what.to_string(),
            "--scenes".into(),
            scene.to_string(),
            "--cap".into(),
            self.cap.to_string(),
            "--rep-below".into(),
            self.rep_below.to_string(),
            "--solves-cap".into(),
            self.solves_cap.to_string(),
            "--clarabel-limit".into(),
            self.clarabel_limit.to_string(),
            "--frictions".into(),
            self.frictions.join(","),
        ];
        if self.quick {
            v.push("--quick".into());
        }
        v
    }
}

fn usage(bad: &str) -> ! {
    if !bad.is_empty() {
        eprintln!("bench: bad argument {bad:?}");
    }
    eprintln!(
        "usage: cargo run --release --example bench -- [--quick | --big] [--scenes 2d-200x25,3d-20x20x10,..]\n\
         \x20   [--out DIR] [--cap S] [--rep-below S] [--solves-cap S] [--frictions tresca,coulomb]\n\
         \x20   [--no-clarabel] [--clarabel-max-n N] [--clarabel-max-n-3d N] [--clarabel-limit S]\n\
         \x20   [--only ours|clarabel] [--append] [--report-only]\n\
         scenes: 2d-NXxNY (Q4 plane strain, NX x NY cells) or 3d-NXxNYxNZ (H8)"
    );
    std::process::exit(2);
}

fn main() {
    let cfg = Config::parse();
    if let Some(what) = cfg.child.clone() {
        let spec = Spec::parse(&cfg.scenes[0]).expect("checked");
        let rows = match what.as_str() {
            "ours" => child_ours(&cfg, spec),
            "clarabel" => child_clarabel(&cfg, spec),
            "profile-setup" => {
                // Only the scene and the contact problem (for a profiler).
                let sc = Scene::build(spec);
                let (pb, t) = time(|| {
                    ContactProblem::from_csc(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone())
                        .expect("valid scene")
                });
                eprintln!(
                    "setup {t:.3} s, condensation {:.3} s",
                    pb.dual().condense_seconds
                );
                Vec::new()
            }
            _ => usage(&what),
        };
        let stdout = std::io::stdout();
        let mut lock = stdout.lock();
        for r in rows {
            writeln!(lock, "ROW,{}", r.to_csv()).expect("stdout");
        }
        return;
    }
    std::fs::create_dir_all(&cfg.out).expect("create the output folder");
    let csv = cfg.out.join("results.csv");
    if !cfg.report_only {
        scene::check_assembly();
        let mut file = if cfg.append && csv.exists() {
            std::fs::OpenOptions::new()
                .append(true)
                .open(&csv)
                .expect("open results.csv")
        } else {
            let mut f = std::fs::File::create(&csv).expect("create results.csv");
            writeln!(f, "{}", row::HEADER).expect("write");
            f
        };
        let exe = std::env::current_exe().expect("own path");
        let total = Instant::now();
        for name in &cfg.scenes {
            let spec = Spec::parse(name).expect("checked");
            let mut parts = vec!["ours"];
            let limit = if spec.dim == 2 {
                cfg.clarabel_max_n
            } else {
                cfg.clarabel_max_n_3d
            };
            if cfg.clarabel && spec.n_dofs() <= limit {
                parts.push("clarabel");
            }
            if let Some(only) = &cfg.only {
                parts.retain(|p| p == only);
            }
            for part in parts {
                eprintln!(
                    "[{:7.1} s] scene {name} (n = {}, m = {}): {part}",
                    total.elapsed().as_secs_f64(),
                    spec.n_dofs(),
                    spec.n_contacts()
                );
                let out = Command::new(&exe)
                    .args(cfg.child_args(part, name))
                    .stderr(std::process::Stdio::inherit())
                    .output()
                    .expect("run the child");
                if !out.status.success() {
                    eprintln!("  child {part} for {name} failed: {}", out.status);
                }
                let text = String::from_utf8_lossy(&out.stdout);
                for line in text.lines() {
                    if let Some(r) = line.strip_prefix("ROW,") {
                        writeln!(file, "{r}").expect("write");
                    }
                }
                file.flush().expect("flush");
            }
        }
        eprintln!("measured in {:.1} s", total.elapsed().as_secs_f64());
    }
    let text = std::fs::read_to_string(&csv).expect("read results.csv");
    let rows: Vec<Row> = text.lines().skip(1).filter_map(Row::from_csv).collect();
    if let Err(e) = plot::draw_all(&rows, &cfg.out) {
        eprintln!("plotting failed: {e}");
    }
    let md = report::summary(&rows);
    std::fs::write(cfg.out.join("summary.md"), &md).expect("write summary.md");
    println!("{md}");
}

fn time<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let x = f();
    (x, t.elapsed().as_secs_f64())
}

fn base_row(sc: &Scene) -> Row {
    Row {
        scene: sc.spec.name(),
        dim: sc.d,
        n: sc.k.nrows,
        m: sc.n.nrows,
        c: sc.d * sc.n.nrows,
        ..Row::default()
    }
}

fn mem_row(base: &Row, stage: &str) -> Row {
    Row {
        kind: "mem".into(),
        method: stage.into(),
        mem_mb: peak_mb(),
        note: format!("load1={}", row::load1()),
        ..base.clone()
    }
}

/// Repeats `f` (which returns its own wall time first) while the runs are short.
fn repeated<T>(rep_below: f64, mut f: impl FnMut() -> (f64, T)) -> (Vec<f64>, T) {
    let (t0, mut last) = f();
    let mut times = vec![t0];
    while times.len() < 3 && t0 < rep_below {
        let (t, x) = f();
        times.push(t);
        last = x;
    }
    (times, last)
}

fn child_ours(cfg: &Config, spec: Spec) -> Vec<Row> {
    let mut rows = Vec::new();
    let (sc, t_asm) = time(|| Scene::build(spec));
    let base = base_row(&sc);
    let (d, ndof, c) = (sc.d, sc.k.nrows, base.c);
    eprintln!(
        "  assembled in {t_asm:.2} s: n = {ndof}, nnz(K) = {}, m = {}",
        sc.k.nnz(),
        sc.n.nrows
    );
    rows.push(Row {
        kind: "assembly".into(),
        reps: Some(1),
        time_s: Some(t_asm),
        note: format!("nnz_K={}", sc.k.nnz()),
        ..base.clone()
    });
    rows.push(mem_row(&base, "assembly"));

    // The factorisation of K alone: the floor every method pays.
    let (walls, (fac, numeric)) = repeated(cfg.rep_below, || {
        let (f, t) = time(|| Factor::new(&sc.k).expect("K is SPD"));
        let num = f.factor_seconds;
        (t, (f, num))
    });
    let t_fac = median(&walls);
    eprintln!("  factor of K alone: {t_fac:.3} s (numeric {numeric:.3} s)");
    rows.push(Row {
        kind: "factor".into(),
        reps: Some(walls.len()),
        time_s: Some(t_fac),
        time_min_s: walls.iter().copied().reduce(f64::min),
        ..base.clone()
    });
    rows.push(Row {
        kind: "factor_numeric".into(),
        reps: Some(1),
        time_s: Some(numeric),
        ..base.clone()
    });
    let (ts, _) = repeated(cfg.rep_below, || {
        let mut x = sc.f.clone();
        let ((), t) = time(|| fac.solve_vec(&mut x));
        (t, ())
    });
    rows.push(Row {
        kind: "solve1".into(),
        reps: Some(ts.len()),
        time_s: Some(median(&ts)),
        ..base.clone()
    });
    // Condensation by one solve per dual unknown (blocks of 32): estimate from one
    // block of 32 solves, run it when the estimate is below the cap.
    let t_block = {
        let w = 32.min(c);
        let mut rhs = faer::Mat::<f64>::zeros(ndof, w);
        for j in 0..w {
            rhs[((j * 7919) % ndof, j)] = 1.0;
        }
        let mut mem = faer::dyn_stack::MemBuffer::new(fac.solve_scratch(w));
        let ((), t) =
            time(|| fac.solve_in_place(rhs.as_mut(), faer::dyn_stack::MemStack::new(&mut mem)));
        t
    };
    let est = t_block * c.div_ceil(32) as f64;
    if est <= cfg.solves_cap {
        let (dual, t) =
            time(|| Dual::build_with(&fac, &sc.n, &sc.t, d, Condensation::Solves).expect("fits"));
        rows.push(Row {
            kind: "condense_solves".into(),
            reps: Some(1),
            time_s: Some(t),
            status: "measured".into(),
            note: format!("estimate={est:.3e}"),
            ..base.clone()
        });
        drop(dual);
    } else {
        rows.push(Row {
            kind: "condense_solves".into(),
            time_s: Some(est),
            status: "extrapolated".into(),
            note: format!("one block of 32 solves {t_block:.3e} s"),
            ..base.clone()
        });
    }
    drop(fac);
    rows.push(mem_row(&base, "factor"));

    // The contact problem: factor with the contact DOFs last + condensation.
    let (walls, mut pb) = repeated(cfg.rep_below, || {
        let (pb, t) = time(|| {
            ContactProblem::from_csc(d, sc.k.clone(), sc.n.clone(), sc.t.clone())
                .expect("valid scene")
        });
        (t, pb)
    });
    let t_setup = median(&walls);
    let t_cond = pb.dual().condense_seconds;
    eprintln!(
        "  setup (factor with contacts last + condensation): {t_setup:.3} s (condensation {t_cond:.3} s)"
    );
    rows.push(Row {
        kind: "setup".into(),
        reps: Some(walls.len()),
        time_s: Some(t_setup),
        time_min_s: walls.iter().copied().reduce(f64::min),
        ..base.clone()
    });
    rows.push(Row {
        kind: "condense_trailing".into(),
        reps: Some(1),
        time_s: Some(t_cond),
        ..base.clone()
    });
    rows.push(mem_row(&base, "setup"));
    let mut setup_factor_logged = false;

    for fr_name in &cfg.frictions {
        let fr = if fr_name == "tresca" {
            Friction::Tresca(&sc.p)
        } else {
            Friction::Coulomb(&sc.mu)
        };
        for method in Method::ALL {
            let solve = |pb: &mut ContactProblem, tol: f64, max_outer: usize| {
                let opts = Options {
                    method,
                    tol,
                    max_outer,
                    ..Options::default()
                };
                time(|| pb.solve(&sc.f, &sc.g, fr, &opts).expect("valid input"))
            };
            // Cost of one outer iteration: (4 iterations - 1 iteration) / 3.
            let (s1, t1) = solve(&mut pb, 1e-15, 1);
            let (s4, t4) = solve(&mut pb, 1e-15, 4);
            if !setup_factor_logged {
                rows.push(Row {
                    kind: "setup_factor".into(),
                    reps: Some(1),
                    time_s: Some(s1.report.factor_seconds),
                    ..base.clone()
                });
                setup_factor_logged = true;
            }
            let di = s4
                .report
                .outer_iterations
                .saturating_sub(s1.report.outer_iterations)
                .max(1);
            // A safety net against runaway runs on a loaded machine: twice the
            // iterations that fit in the cap, raised below when a run hits it early.
            let t_it = ((t4 - t1) / di as f64).max(1e-7);
            let mut max_outer = ((2.0 * cfg.cap / t_it) as usize).max(10);
            let mut stopped = false;
            let mut reached = false;
            for tol in TOLS {
                let r0 = Row {
                    friction: fr_name.clone(),
                    kind: "solve".into(),
                    method: method.name().into(),
                    tol: Some(tol),
                    ..base.clone()
                };
                if stopped {
                    rows.push(Row {
                        status: "skipped".into(),
                        ..r0
                    });
                    continue;
                }
                let (times, sol) = loop {
                    let (times, sol) = repeated(cfg.rep_below, || {
                        let (s, t) = solve(&mut pb, tol, max_outer);
                        (t, s)
                    });
                    let r = &sol.report;
                    let t = median(&times);
                    if r.status == SolveStatus::Converged
                        || r.outer_iterations < max_outer
                        || t >= 0.5 * cfg.cap
                    {
                        break (times, sol);
                    }
                    // The iteration limit, not the time cap, stopped it: allow more.
                    let per = t / r.outer_iterations.max(1) as f64;
                    max_outer = ((0.9 * cfg.cap / per) as usize).max(2 * max_outer);
                };
                let r = &sol.report;
                let t = median(&times);
                eprintln!(
                    "  {fr_name:7} {:10} tol {tol:.0e}: {t:8.3} s err {:.2e} outer {} inner {} {:?}",
                    method.name(),
                    r.err,
                    r.outer_iterations,
                    r.inner_iterations,
                    r.status
                );
                let converged = r.status == SolveStatus::Converged;
                rows.push(Row {
                    reps: Some(times.len()),
                    time_s: Some(t),
                    time_min_s: times.iter().copied().reduce(f64::min),
                    err: Some(r.err),
                    eq_res: Some(r.equilibrium_residual),
                    outer: Some(r.outer_iterations),
                    inner: Some(r.inner_iterations),
                    status: format!("{:?}", r.status),
                    open: Some(r.n_open),
                    stick: Some(r.n_stick),
                    slip: Some(r.n_slip),
                    note: format!("max_outer={max_outer}"),
                    ..r0
                });
                if converged && tol <= 1e-10 {
                    reached = true;
                }
                if !converged || t > cfg.cap {
                    stopped = true;
                }
            }
            if !reached {
                for kind in ["step_cold", "step_warm"] {
                    rows.push(Row {
                        friction: fr_name.clone(),
                        kind: kind.into(),
                        method: method.name().into(),
                        tol: Some(1e-10),
                        status: "skipped".into(),
                        ..base.clone()
                    });
                }
                continue;
            }
            // History: a cold first step, then a warm-started one with 5 % more load.
            let f2 = sc.scaled_load(1.05);
            let opts = Options {
                method,
                tol: 1e-10,
                max_outer,
                ..Options::default()
            };
            let (walls, (s1, t1, s2)) = repeated(cfg.rep_below, || {
                pb.reset_history();
                let (s1, t1) = time(|| pb.step(&sc.f, &sc.g, fr, &opts).expect("valid"));
                let (s2, t2) = time(|| pb.step(&f2, &sc.g, fr, &opts).expect("valid"));
                (t2, (s1, t1, s2))
            });
            pb.reset_history();
            for (kind, s, t, reps) in [
                ("step_cold", &s1, t1, 1),
                ("step_warm", &s2, median(&walls), walls.len()),
            ] {
                let r = &s.report;
                rows.push(Row {
                    friction: fr_name.clone(),
                    kind: kind.into(),
                    method: method.name().into(),
                    tol: Some(1e-10),
                    reps: Some(reps),
                    time_s: Some(t),
                    err: Some(r.err),
                    eq_res: Some(r.equilibrium_residual),
                    outer: Some(r.outer_iterations),
                    inner: Some(r.inner_iterations),
                    status: format!("{:?}", r.status),
                    open: Some(r.n_open),
                    stick: Some(r.n_stick),
                    slip: Some(r.n_slip),
                    ..base.clone()
                });
            }
            eprintln!(
                "  {fr_name:7} {:10} history: cold {t1:.3} s ({} outer), warm {:.3} s ({} outer, err {:.1e})",
                method.name(),
                s1.report.outer_iterations,
                median(&walls),
                s2.report.outer_iterations,
                s2.report.err
            );
        }
    }
    rows.push(mem_row(&base, "ours"));
    rows
}

fn child_clarabel(cfg: &Config, spec: Spec) -> Vec<Row> {
    let sc = Scene::build(spec);
    let base = base_row(&sc);
    // Clarabel's default tolerance (1e-8), and a tighter one where it is quick.
    let tols: &[f64] = if cfg.quick || spec.n_dofs() > 200_000 {
        &[1e-8]
    } else {
        &[1e-8, 1e-10]
    };
    clarabel_ref::run(&sc, &base, tols, cfg.clarabel_limit)
}
