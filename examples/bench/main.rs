//! The work-precision benchmark of dualsplit.
//!
//! ```text
//! cargo run --release --example bench -- [--quick | --big | --slabs] [--scenes A,B,..]
//!     [--out DIR] [--cap SECONDS] [--rep-below S] [--solves-cap S]
//!     [--no-clarabel] [--no-free] [--clarabel-max-n N] [--clarabel-max-n-3d N]
//!     [--clarabel-limit S] [--only ours|ours-dense|ours-free|clarabel]
//!     [--frictions tresca,coulomb] [--append] [--report-only] [--threads K]
//!     [--no-cholmod]
//! ```
//!
//! For each scene (2D Q4 / 3D H8 blocks on a rigid foundation with a curved gap, see
//! `scene.rs`) child processes (this binary with `--child`) measure, so that each
//! part gets its own peak memory:
//!
//! - child `ours` (the dense condensed dual):
//!   - the baseline: the best plain sparse Cholesky factorisation of K alone
//!     (`Ordering::Auto`: AMD, and METIS where AMD's fronts are large, the one
//!     with fewer flops kept), one solve; and CHOLMOD's own factorisation of the
//!     same K (its default ordering policy, `examples/cholmod_factor.c` built with
//!     cc against SuiteSparse; rows absent, with a message, where it is not
//!     installed or with `--no-cholmod`);
//!   - the setup: `ContactProblem::from_csc` (factor with the contact DOFs last +
//!     the dual); where `DualForm::Auto` leaves it matrix-free (c > `DENSE_MAX`),
//!     the dense assembly of A that the dense methods need is forced before any
//!     method is timed and added to the setup row (row `condense_trailing`);
//!   - the condensation by solves (run where its estimate is below a cap,
//!     extrapolated from a block of solves beyond);
//!   - every method of `Method::ALL` with `DualForm::Dense` at the tolerances
//!     1e-2 .. 1e-12, Tresca and Coulomb: wall time (median of 3 when a run is
//!     short), err, iterations;
//!   - a history: the first step (cold) and a second, warm-started step with the
//!     load raised by 5 %;
//! - child `ours-free` (the matrix-free dual, `DualForm::MatrixFree`): the setup in
//!   matrix-free form (`from_csc_with` with `DualForm::MatrixFree`: the best plain
//!   factor of K and the contacts' diagonal blocks of A, nothing c x c), its peak
//!   memory, then `Method::Newton`, `Method::Mprgp` and `Method::Auto`
//!   matrix-free as the series `newton-free`, `mprgp-free`, `auto-free`
//!   (tolerances and history as above);
//! - child `clarabel`: Clarabel on the same Tresca problem.
//!
//! Every contact problem is built with `Options::threads = K` (`--threads`,
//! default 1), the baseline factor runs in a pool of K threads, CHOLMOD with K
//! BLAS threads: one run, one thread count.
//!
//! The rows go to DIR/results.csv (with `--append`, the rows of the scenes and parts
//! measured again replace the old ones); the figures (SVG) and DIR/summary.md are
//! drawn from that file (`--report-only` redraws them without measuring).

mod cholmod;
mod clarabel_ref;
mod plot;
mod report;
mod row;
mod scene;
#[allow(dead_code)]
mod stats;

use dualsplit::internals::{Condensation, Dual};
use dualsplit::internals::{Factor, Threads};
use dualsplit::{ContactProblem, DualForm, Friction, Method, Options, Ordering, SolveStatus};
use row::{Part, Row, peak_mb, reset_peak, rss_mb};
use scene::{Scene, Spec};
use stats::median;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
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

/// `--slabs`: thin 3D slabs whose whole bottom face is a contact, c =
/// 3,267, 12,675 and 41,067, and the 2D strip of `--big` (c = 10,002). Run them
/// with `--only ours-free`: the dense dual of the largest does not fit 24 GB.
const SLABS: &[&str] = &["3d-32x32x4", "3d-64x64x6", "3d-116x116x4", "2d-5000x100"];

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
    /// Run the matrix-free child (`ours-free`).
    free: bool,
    /// Clarabel runs on 2D scenes up to this many DOFs ...
    clarabel_max_n: usize,
    /// ... and on 3D scenes up to this many (its default direct solver, QDLDL,
    /// fills in badly in 3D: about 65 s on 13,230 DOFs).
    clarabel_max_n_3d: usize,
    /// Only these parts of each scene: "ours" (= ours-dense and ours-free),
    /// "ours-dense", "ours-free", "clarabel"; all when None.
    only: Option<String>,
    /// Append to an existing results.csv instead of starting a new one (the rows of
    /// a scene and part measured again replace the old ones).
    append: bool,
    clarabel_limit: f64,
    frictions: Vec<String>,
    /// `Options::threads` of every contact problem and the thread count of the
    /// baseline factorisations (faer's pool; CHOLMOD's BLAS threads).
    threads: usize,
    /// Measure CHOLMOD's factorisation of K next to ours (where SuiteSparse is
    /// installed).
    cholmod: bool,
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
            free: true,
            clarabel_max_n: 1_100_000,
            clarabel_max_n_3d: 15_000,
            only: None,
            append: false,
            clarabel_limit: if quick { 20.0 } else { 150.0 },
            frictions: vec!["tresca".into(), "coulomb".into()],
            threads: 1,
            cholmod: true,
            report_only: false,
            child: None,
        };
        let mut big = false;
        let mut slabs = false;
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut val = || it.next().cloned().unwrap_or_else(|| usage(a));
            match a.as_str() {
                "--quick" => {}
                "--big" => big = true,
                "--slabs" => slabs = true,
                "--scenes" => c.scenes = val().split(',').map(String::from).collect(),
                "--out" => c.out = PathBuf::from(val()),
                "--cap" => c.cap = val().parse().unwrap_or_else(|_| usage(a)),
                "--rep-below" => c.rep_below = val().parse().unwrap_or_else(|_| usage(a)),
                "--solves-cap" => c.solves_cap = val().parse().unwrap_or_else(|_| usage(a)),
                "--no-clarabel" => c.clarabel = false,
                "--no-free" => c.free = false,
                "--clarabel-max-n" => c.clarabel_max_n = val().parse().unwrap_or_else(|_| usage(a)),
                "--clarabel-max-n-3d" => {
                    c.clarabel_max_n_3d = val().parse().unwrap_or_else(|_| usage(a))
                }
                "--only" => c.only = Some(val()),
                "--append" => c.append = true,
                "--clarabel-limit" => c.clarabel_limit = val().parse().unwrap_or_else(|_| usage(a)),
                "--frictions" => c.frictions = val().split(',').map(String::from).collect(),
                "--report-only" => c.report_only = true,
                "--threads" => c.threads = val().parse().unwrap_or_else(|_| usage(a)),
                "--no-cholmod" => c.cholmod = false,
                "--child" => c.child = Some(val()),
                "-h" | "--help" => usage(""),
                _ => usage(a),
            }
        }
        if c.scenes.is_empty() {
            let list = if slabs {
                SLABS
            } else if quick {
                QUICK
            } else {
                FULL
            };
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
        if let Some(o) = &c.only
            && !["ours", "ours-dense", "ours-free", "clarabel"].contains(&o.as_str())
        {
            usage(o);
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
            "--threads".into(),
            self.threads.to_string(),
        ];
        if !self.cholmod {
            v.push("--no-cholmod".into());
        }
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
        "usage: cargo run --release --example bench -- [--quick | --big | --slabs] [--scenes 2d-200x25,3d-20x20x10,..]\n\
         \x20   [--out DIR] [--cap S] [--rep-below S] [--solves-cap S] [--frictions tresca,coulomb]\n\
         \x20   [--no-clarabel] [--no-free] [--clarabel-max-n N] [--clarabel-max-n-3d N]\n\
         \x20   [--clarabel-limit S] [--only ours|ours-dense|ours-free|clarabel] [--append]\n\
         \x20   [--report-only] [--threads K] [--no-cholmod]\n\
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
            "ours-free" => child_free(&cfg, spec),
            "clarabel" => child_clarabel(&cfg, spec),
            "info" => {
                // The analysis alone (ds_analyse): sizes, ordering, predicted memory.
                let sc = Scene::build(spec);
                let opts = Options {
                    threads: cfg.threads,
                    ..Options::default()
                };
                let (info, t) = time(|| {
                    ContactProblem::analyse_csc(sc.d, &sc.k, &sc.n, &sc.t, &opts)
                        .expect("valid scene")
                });
                eprintln!("analysed in {t:.3} s: {info:#?}");
                Vec::new()
            }
            "profile-setup" => {
                // Only the scene and the contact problem (for a profiler).
                let sc = Scene::build(spec);
                let (pb, t) = time(|| problem(&cfg, &sc));
                eprintln!(
                    "setup {t:.3} s, condensation {:.3} s (matrix-free: {})",
                    pb.dual().condense_seconds(),
                    pb.dual().is_matrix_free()
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
        // What runs: (scene, part) in order.
        let mut plan: Vec<(String, Part)> = Vec::new();
        for name in &cfg.scenes {
            let spec = Spec::parse(name).expect("checked");
            let mut parts = vec![Part::Dense];
            if cfg.free {
                parts.push(Part::Free);
            }
            let limit = if spec.dim == 2 {
                cfg.clarabel_max_n
            } else {
                cfg.clarabel_max_n_3d
            };
            if cfg.clarabel && spec.n_dofs() <= limit {
                parts.push(Part::Clarabel);
            }
            if let Some(only) = &cfg.only {
                parts.retain(|p| match only.as_str() {
                    "ours" => *p != Part::Clarabel,
                    // The dense child's part is named "ours" in results.csv.
                    "ours-dense" => *p == Part::Dense,
                    o => p.name() == o,
                });
            }
            plan.extend(parts.into_iter().map(|p| (name.clone(), p)));
        }
        // With --append, the rows of a (scene, part) measured again are dropped first.
        let kept: Vec<String> = if cfg.append && csv.exists() {
            let text = std::fs::read_to_string(&csv).expect("read results.csv");
            text.lines()
                .skip(1)
                .filter(|l| match Row::from_csv(l) {
                    Some(r) => !plan.iter().any(|(s, p)| *s == r.scene && *p == r.part()),
                    None => false,
                })
                .map(String::from)
                .collect()
        } else {
            Vec::new()
        };
        if cfg.append {
            eprintln!("keeping {} rows of {}", kept.len(), csv.display());
        }
        let mut file = std::fs::File::create(&csv).expect("create results.csv");
        writeln!(file, "{}", row::HEADER).expect("write");
        for l in &kept {
            writeln!(file, "{l}").expect("write");
        }
        file.flush().expect("flush");
        let exe = std::env::current_exe().expect("own path");
        let total = Instant::now();
        for (name, part) in &plan {
            let spec = Spec::parse(name).expect("checked");
            eprintln!(
                "[{:7.1} s] scene {name} (n = {}, m = {}, c = {}): {} (load {})",
                total.elapsed().as_secs_f64(),
                spec.n_dofs(),
                spec.n_contacts(),
                spec.dim * spec.n_contacts(),
                part.name(),
                row::load1()
            );
            let out = Command::new(&exe)
                .args(cfg.child_args(part.name(), name))
                .stderr(std::process::Stdio::inherit())
                .output()
                .expect("run the child");
            if !out.status.success() {
                eprintln!("  child {} for {name} failed: {}", part.name(), out.status);
            }
            let text = String::from_utf8_lossy(&out.stdout);
            for line in text.lines() {
                if let Some(r) = line.strip_prefix("ROW,") {
                    writeln!(file, "{r}").expect("write");
                }
            }
            file.flush().expect("flush");
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

/// A row of one timed quantity.
fn time_row(base: &Row, kind: &str, walls: &[f64], note: String) -> Row {
    Row {
        kind: kind.into(),
        reps: Some(walls.len()),
        time_s: Some(median(walls)),
        time_min_s: walls.iter().copied().reduce(f64::min),
        note,
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

fn friction_of<'a>(sc: &'a Scene, name: &str) -> Friction<'a> {
    if name == "tresca" {
        Friction::Tresca(&sc.p)
    } else {
        Friction::Coulomb(&sc.mu)
    }
}

/// The contact problem of a scene with the run's thread count.
/// The scene's contact problem created matrix-free (the plain factor of K).
fn problem_free(cfg: &Config, sc: &Scene) -> ContactProblem {
    let opts = Options {
        threads: cfg.threads,
        dual_form: DualForm::MatrixFree,
        ..Options::default()
    };
    ContactProblem::from_csc_with(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone(), &opts)
        .expect("valid scene")
}

fn problem(cfg: &Config, sc: &Scene) -> ContactProblem {
    let opts = Options {
        threads: cfg.threads,
        ..Options::default()
    };
    ContactProblem::from_csc_with(sc.d, sc.k.clone(), sc.n.clone(), sc.t.clone(), &opts)
        .expect("valid scene")
}

/// CHOLMOD's factorisation of the scene's K (rows `cholmod`, `cholmod_numeric`);
/// no rows, with the reason on stderr, where the shim cannot be built or run.
fn cholmod_rows(cfg: &Config, sc: &Scene, base: &Row) -> Vec<Row> {
    let exe = match cholmod::shim() {
        Ok(exe) => exe,
        Err(why) => {
            eprintln!("  CHOLMOD column left out: {why}");
            return Vec::new();
        }
    };
    let mtx = std::env::temp_dir().join(format!(
        "dualsplit-bench-{}-{}.mtx",
        sc.spec.name(),
        std::process::id()
    ));
    if let Err(e) = dualsplit::mtx::write_matrix(&mtx, &sc.k) {
        eprintln!("  CHOLMOD column left out: cannot write K: {e}");
        return Vec::new();
    }
    // One run first; two more where it is short (as `repeated`).
    let mut res = cholmod::run(&exe, &mtx, 1, cfg.threads, false);
    if let Ok(r) = &res
        && r.seconds < cfg.rep_below
    {
        res = cholmod::run(&exe, &mtx, 3, cfg.threads, false);
    }
    let _ = std::fs::remove_file(&mtx);
    match res {
        Ok(r) => {
            eprintln!(
                "  CHOLMOD: {:.3} s (numeric {:.3} s, ordering {}, nnz(L) {:.3e}, flops {:.3e})",
                r.seconds, r.numeric, r.ordering, r.nnz, r.flops
            );
            let note = format!(
                "ordering={} nnz_L={} flops={:.3e} threads={} analyse={:.3}",
                r.ordering, r.nnz, r.flops, cfg.threads, r.analyse
            );
            vec![
                time_row(base, "cholmod", &r.walls, note),
                time_row(base, "cholmod_numeric", &[r.numeric], String::new()),
            ]
        }
        Err(why) => {
            eprintln!("  CHOLMOD column left out: {why}");
            Vec::new()
        }
    }
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
    let pool = Arc::new(Threads::new(cfg.threads));
    let (walls, (fac, numeric)) = repeated(cfg.rep_below, || {
        let (f, t) =
            time(|| Factor::with_last(&sc.k, &[], Ordering::Auto, pool.clone()).expect("K is SPD"));
        let num = f.factor_seconds;
        (t, (f, num))
    });
    let t_fac = median(&walls);
    eprintln!("  factor of K alone: {t_fac:.3} s (numeric {numeric:.3} s)");
    let (nnz_l, flops_l) = fac.nnz_and_flops();
    let fac_note = format!(
        "ordering={} nnz_L={nnz_l} flops={flops_l:.3e} threads={}",
        fac.ordering().name(),
        cfg.threads
    );
    rows.push(time_row(&base, "factor", &walls, fac_note));
    rows.push(time_row(&base, "factor_numeric", &[numeric], String::new()));
    let (ts, _) = repeated(cfg.rep_below, || {
        let mut x = sc.f.clone();
        let ((), t) = time(|| fac.solve_vec(&mut x));
        (t, ())
    });
    rows.push(time_row(&base, "solve1", &ts, String::new()));
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
            status: "measured".into(),
            ..time_row(
                &base,
                "condense_solves",
                &[t],
                format!("estimate={est:.3e}"),
            )
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
    if cfg.cholmod {
        rows.extend(cholmod_rows(cfg, &sc, &base));
    }

    // The contact problem: factor with the contact DOFs last + the dual. The peak
    // memory from here on is that of the setup (and the scene, still resident).
    reset_peak();
    rows.push(Row {
        mem_mb: rss_mb(),
        ..mem_row(&base, "setup-start")
    });
    let (walls, mut pb) = repeated(cfg.rep_below, || {
        let (pb, t) = time(|| problem(cfg, &sc));
        (t, pb)
    });
    let t_from_csc = median(&walls);
    let auto_free = pb.dual().is_matrix_free();
    let mut t_setup = walls.clone();
    let mut note = String::new();
    if auto_free {
        // DualForm::Auto left it matrix-free (c > DENSE_MAX): the dense methods need
        // A, assembled by the first solve with DualForm::Dense. Force it here (one
        // outer iteration), and charge the assembly to the setup.
        let t_free_build = pb.dual().condense_seconds();
        let opts = Options {
            method: Method::Pgs,
            max_outer: 1,
            dual_form: DualForm::Dense,
            ..Options::default()
        };
        let (_, t_first) = time(|| {
            pb.solve(&sc.f, &sc.g, Friction::Tresca(&sc.p), &opts)
                .expect("valid input")
        });
        assert!(!pb.dual().is_matrix_free());
        let t_asm = pb.dual().condense_seconds();
        t_setup.iter_mut().for_each(|t| *t += t_asm);
        note = format!(
            "from_csc (auto: matrix-free) {t_from_csc:.3} s incl. matrix-free build \
             {t_free_build:.3} s + dense assembly {t_asm:.3} s (first dense solve {t_first:.3} s)"
        );
        rows.push(time_row(&base, "setup_auto", &walls, "matrix-free".into()));
    }
    let t_cond = pb.dual().condense_seconds();
    eprintln!(
        "  setup (factor with contacts last + dense dual): {:.3} s (dense condensation {t_cond:.3} s){}",
        median(&t_setup),
        if auto_free {
            " [auto: matrix-free, then assembled]"
        } else {
            ""
        }
    );
    rows.push(time_row(&base, "setup", &t_setup, note));
    rows.push(time_row(
        &base,
        "condense_trailing",
        &[t_cond],
        String::new(),
    ));
    rows.push(mem_row(&base, "setup"));
    // The solves: peak from here on (A, the factor, the scene, the iterations).
    reset_peak();

    let mut setup_factor_logged = false;
    for fr_name in &cfg.frictions {
        for method in Method::ALL {
            let (r, fs) = method_series(
                cfg,
                &sc,
                &base,
                &mut pb,
                fr_name,
                method,
                DualForm::Dense,
                method.name(),
            );
            if !setup_factor_logged {
                rows.push(time_row(&base, "setup_factor", &[fs], String::new()));
                setup_factor_logged = true;
            }
            rows.extend(r);
        }
    }
    rows.push(mem_row(&base, "ours"));
    rows
}

/// The matrix-free child: setup in matrix-free form, then Newton, MPRGP and
/// auto matrix-free.
fn child_free(cfg: &Config, spec: Spec) -> Vec<Row> {
    let mut rows = Vec::new();
    let sc = Scene::build(spec);
    let base = base_row(&sc);
    rows.push(mem_row(&base, "free-assembly"));
    reset_peak();
    rows.push(Row {
        mem_mb: rss_mb(),
        ..mem_row(&base, "free-setup-start")
    });
    // The setup in matrix-free form, without ever forming A: the problem created
    // with `DualForm::MatrixFree` (the best plain factor of K, the contacts'
    // diagonal blocks of A).
    let (walls, (t_factor, t_build, pb)) = repeated(cfg.rep_below, || {
        let (pb, t) = time(|| problem_free(cfg, &sc));
        assert!(pb.dual().is_matrix_free());
        let tb = pb.dual().condense_seconds();
        (t, (0.0, tb, pb))
    });
    let how = "from_csc_with (dual_form matrix-free: plain factor)";
    eprintln!(
        "  setup matrix-free: {:.3} s (contact blocks {t_build:.3} s) by {how}",
        median(&walls)
    );
    rows.push(time_row(&base, "setup_free", &walls, how.into()));
    rows.push(time_row(&base, "condense_free", &[t_build], String::new()));
    rows.push(mem_row(&base, "free-setup"));
    let mut pb = pb;
    let mut t_factor = t_factor;
    for fr_name in &cfg.frictions {
        for (method, label) in [
            (Method::Newton, "newton-free"),
            (Method::Mprgp, "mprgp-free"),
            (Method::Auto, "auto-free"),
        ] {
            let (r, fs) = method_series(
                cfg,
                &sc,
                &base,
                &mut pb,
                fr_name,
                method,
                DualForm::MatrixFree,
                label,
            );
            assert!(pb.dual().is_matrix_free());
            if t_factor == 0.0 {
                t_factor = fs;
            }
            rows.extend(r);
        }
    }
    rows.push(time_row(
        &base,
        "setup_free_factor",
        &[t_factor],
        String::new(),
    ));
    rows.push(mem_row(&base, "free"));
    rows
}

/// One method in one dual form on one friction law: the tolerance series and the
/// history steps. Returns the rows and the numeric factorisation time of the
/// problem's factor (from a report).
#[allow(clippy::too_many_arguments)]
fn method_series(
    cfg: &Config,
    sc: &Scene,
    base: &Row,
    pb: &mut ContactProblem,
    fr_name: &str,
    method: Method,
    form: DualForm,
    label: &str,
) -> (Vec<Row>, f64) {
    let mut rows = Vec::new();
    let fr = friction_of(sc, fr_name);
    let solve = |pb: &mut ContactProblem, tol: f64, max_outer: usize| {
        let opts = Options {
            method,
            tol,
            max_outer,
            dual_form: form,
            ..Options::default()
        };
        time(|| pb.solve(&sc.f, &sc.g, fr, &opts).expect("valid input"))
    };
    // A first, untimed call puts the dual in the form asked for (a change of form
    // rebuilds it: not part of any method's time).
    if pb.dual().is_matrix_free() != (form == DualForm::MatrixFree) {
        solve(pb, 1e-15, 1);
    }
    // Cost of one outer iteration: (4 iterations - 1 iteration) / 3.
    let (s1, t1) = solve(pb, 1e-15, 1);
    let (s4, t4) = solve(pb, 1e-15, 4);
    let factor_seconds = s1.report.factor_seconds;
    let di = s4
        .report
        .outer_iterations
        .saturating_sub(s1.report.outer_iterations)
        .max(1);
    // A safety net against runaway runs on a loaded machine: twice the iterations
    // that fit in the cap, raised below when a run hits it early.
    let t_it = ((t4 - t1) / di as f64).max(1e-7);
    let mut max_outer = ((2.0 * cfg.cap / t_it) as usize).max(10);
    let mut stopped = false;
    let mut reached = false;
    for tol in TOLS {
        let r0 = Row {
            friction: fr_name.into(),
            kind: "solve".into(),
            method: label.into(),
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
                let (s, t) = solve(pb, tol, max_outer);
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
            "  {fr_name:7} {label:11} tol {tol:.0e}: {t:8.3} s err {:.2e} outer {} inner {} {:?}",
            r.err, r.outer_iterations, r.inner_iterations, r.status
        );
        let converged = r.status == SolveStatus::Converged;
        rows.push(
            Row {
                reps: Some(times.len()),
                time_s: Some(t),
                time_min_s: times.iter().copied().reduce(f64::min),
                note: format!("max_outer={max_outer}"),
                ..r0
            }
            .with_report(r),
        );
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
                friction: fr_name.into(),
                kind: kind.into(),
                method: label.into(),
                tol: Some(1e-10),
                status: "skipped".into(),
                ..base.clone()
            });
        }
        return (rows, factor_seconds);
    }
    // History: a cold first step, then a warm-started one with 5 % more load.
    let f2 = sc.scaled_load(1.05);
    let opts = Options {
        method,
        tol: 1e-10,
        max_outer,
        dual_form: form,
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
        rows.push(
            Row {
                friction: fr_name.into(),
                kind: kind.into(),
                method: label.into(),
                tol: Some(1e-10),
                reps: Some(reps),
                time_s: Some(t),
                ..base.clone()
            }
            .with_report(r),
        );
    }
    eprintln!(
        "  {fr_name:7} {label:11} history: cold {t1:.3} s ({} outer), warm {:.3} s ({} outer, err {:.1e})",
        s1.report.outer_iterations,
        median(&walls),
        s2.report.outer_iterations,
        s2.report.err
    );
    (rows, factor_seconds)
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
