//! The factorisation benchmark: what one factorisation of K costs with
//! each fill-reducing ordering, plain and with the contact DOFs last, on 1 and 2
//! threads, next to CHOLMOD's own factorisation of the same K.
//!
//! ```text
//! cargo run --release --example factor -- [--scenes A,B,..] [--reps N]
//!     [--threads 1,2] [--no-cholmod] [--no-last-amd]
//! ```
//!
//! Scenes as in the benchmark (`examples/bench/scene.rs`: 2D Q4 / 3D H8 blocks, every
//! bottom node a contact). For each scene and thread count, the median of `reps`
//! runs (default 3) of:
//!
//! - `plain amd`, `plain metis`: `Factor::with_last(K, [], ordering)`, the analysis
//!   (ordering and symbolic factor) plus the numeric factorisation; the best of the
//!   two is the baseline every ratio reads against;
//! - `plain auto`: what `Ordering::Auto` picks, and its cost (both analyses and
//!   the numeric factorisation of the cheaper one);
//! - `last amd`, `last metis`: the same with the contact DOFs ordered last (the
//!   factor the dense condensed dual is formed from);
//! - `setup`: `ContactProblem::from_csc_with` with the default options (ordering
//!   Auto): the factor with the contacts last and the dense condensation;
//! - `cholmod`, `cholmod metis`: CHOLMOD's `cholmod_analyze` + `cholmod_factorize`
//!   (supernodal) with its default ordering policy and with METIS alone, through
//!   `examples/cholmod_factor.c` built here with `cc` against SuiteSparse
//!   (`libsuitesparse-dev`); BLAS threads set to the thread count through
//!   OPENBLAS_NUM_THREADS and OMP_NUM_THREADS. Without SuiteSparse the rows say
//!   so. Install an optimised BLAS first (Debian: libopenblas0-pthread): with the
//!   reference BLAS CHOLMOD is several times slower.
//!
//! Prints a Markdown table: seconds (analysis + numeric, measured around the call),
//! the analysis and the numeric factorisation apart, nnz(L), flops, and the ratio to
//! the best plain factorisation of the same thread count.

#[path = "bench/cholmod.rs"]
#[allow(dead_code)]
mod cholmod;
#[path = "bench/scene.rs"]
#[allow(dead_code)]
mod scene;
#[path = "bench/stats.rs"]
#[allow(dead_code)]
mod stats;

use dualsplit::internals::{Factor, Threads, contact_dofs, stack_rows};
use dualsplit::{ContactProblem, Options, Ordering};
use scene::{Scene, Spec};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

const DEFAULT_SCENES: &[&str] = &["2d-800x100", "2d-2000x250", "3d-30x30x15", "3d-40x40x20"];

struct Args {
    scenes: Vec<String>,
    reps: usize,
    threads: Vec<usize>,
    cholmod: bool,
    last_amd: bool,
}

fn parse_args() -> Args {
    let mut args = Args {
        scenes: DEFAULT_SCENES.iter().map(|s| s.to_string()).collect(),
        reps: 3,
        threads: vec![1, 2],
        cholmod: true,
        last_amd: true,
    };
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let mut k = 0;
    while k < argv.len() {
        let value = |k: usize| {
            argv.get(k + 1)
                .unwrap_or_else(|| panic!("{} needs a value", argv[k]))
                .clone()
        };
        match argv[k].as_str() {
            "--scenes" => {
                args.scenes = value(k).split(',').map(str::to_string).collect();
                k += 1;
            }
            "--reps" => {
                args.reps = value(k).parse().expect("--reps N");
                k += 1;
            }
            "--threads" => {
                args.threads = value(k)
                    .split(',')
                    .map(|t| t.parse().expect("--threads 1,2"))
                    .collect();
                k += 1;
            }
            "--no-cholmod" => args.cholmod = false,
            "--no-last-amd" => args.last_amd = false,
            other => panic!("unknown argument {other}"),
        }
        k += 1;
    }
    args
}

/// One measured configuration: medians over the repetitions.
struct Meas {
    what: String,
    seconds: f64,
    analyse: f64,
    numeric: f64,
    nnz: f64,
    flops: f64,
}

/// `reps` factorisations of `k` with `last` ordered last.
fn factor(
    what: &str,
    k: &dualsplit::Csc,
    last: &[usize],
    ordering: Ordering,
    threads: &Arc<Threads>,
    reps: usize,
) -> Meas {
    let (mut total, mut analyse, mut numeric) = (Vec::new(), Vec::new(), Vec::new());
    let (mut nnz, mut flops, mut chosen) = (0, 0.0, Ordering::Auto);
    for _ in 0..reps {
        let t0 = Instant::now();
        let f = Factor::with_last(k, last, ordering, threads.clone()).expect("K is SPD");
        total.push(t0.elapsed().as_secs_f64());
        analyse.push(f.analyse_seconds);
        numeric.push(f.factor_seconds);
        (nnz, flops) = f.nnz_and_flops();
        chosen = f.ordering();
    }
    let what = if ordering == Ordering::Auto {
        format!("{what} (-> {})", chosen.name())
    } else {
        what.to_string()
    };
    Meas {
        what,
        seconds: stats::median(&total),
        analyse: stats::median(&analyse),
        numeric: stats::median(&numeric),
        nnz: nnz as f64,
        flops,
    }
}

/// A CHOLMOD measurement as a row of the table.
fn cholmod_row(exe: &Path, mtx: &Path, reps: usize, threads: usize, metis: bool) -> Meas {
    let r = cholmod::run(exe, mtx, reps, threads, metis).expect("CHOLMOD runs");
    Meas {
        what: format!(
            "cholmod{} (-> {})",
            if metis { " metis" } else { "" },
            r.ordering
        ),
        seconds: r.seconds,
        analyse: r.analyse,
        numeric: r.numeric,
        nnz: r.nnz,
        flops: r.flops,
    }
}

fn main() {
    let args = parse_args();
    let shim = if args.cholmod {
        cholmod::shim()
    } else {
        Err("--no-cholmod".to_string())
    };
    if let Err(why) = &shim {
        eprintln!("CHOLMOD column left out: {why}");
    }
    println!(
        "| scene | threads | factorisation | seconds | analyse s | numeric s | nnz(L) | flops | x best plain |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in &args.scenes {
        let spec = Spec::parse(name).unwrap_or_else(|| panic!("unknown scene {name}"));
        let sc = Scene::build(spec);
        let last = contact_dofs(&stack_rows(&sc.n, &sc.t));
        let mtx = std::env::temp_dir().join(format!("dualsplit-factor-{name}.mtx"));
        if shim.is_ok() {
            dualsplit::mtx::write_matrix(&mtx, &sc.k).expect("write K");
        }
        for &th in &args.threads {
            let pool = Arc::new(Threads::new(th));
            let mut rows = vec![
                factor("plain amd", &sc.k, &[], Ordering::Amd, &pool, args.reps),
                factor("plain metis", &sc.k, &[], Ordering::Metis, &pool, args.reps),
                factor("plain auto", &sc.k, &[], Ordering::Auto, &pool, args.reps),
                factor(
                    "last metis",
                    &sc.k,
                    &last,
                    Ordering::Metis,
                    &pool,
                    args.reps,
                ),
            ];
            if args.last_amd {
                let r = factor("last amd", &sc.k, &last, Ordering::Amd, &pool, args.reps);
                rows.push(r);
            }
            let best = rows[0].seconds.min(rows[1].seconds);
            // The setup of the dense condensed dual, default options.
            let opts = Options {
                threads: th,
                ..Options::default()
            };
            let mut setup = Vec::new();
            let mut condense = Vec::new();
            for _ in 0..args.reps {
                let (k, n, t) = (sc.k.clone(), sc.n.clone(), sc.t.clone());
                let t0 = Instant::now();
                let pb = ContactProblem::from_csc_with(sc.d, k, n, t, &opts).expect("setup");
                setup.push(t0.elapsed().as_secs_f64());
                condense.push(pb.dual().condense_seconds());
            }
            rows.push(Meas {
                what: format!(
                    "setup (factor, contacts last + condense {:.2} s)",
                    stats::median(&condense)
                ),
                seconds: stats::median(&setup),
                analyse: f64::NAN,
                numeric: f64::NAN,
                nnz: f64::NAN,
                flops: f64::NAN,
            });
            if let Ok(exe) = &shim {
                rows.push(cholmod_row(exe, &mtx, args.reps, th, false));
                rows.push(cholmod_row(exe, &mtx, args.reps, th, true));
            }
            for r in rows {
                println!(
                    "| {name} | {th} | {} | {:.3} | {:.3} | {:.3} | {:.2e} | {:.2e} | {:.2} |",
                    r.what,
                    r.seconds,
                    r.analyse,
                    r.numeric,
                    r.nnz,
                    r.flops,
                    r.seconds / best
                );
            }
        }
        let _ = std::fs::remove_file(&mtx);
    }
}
