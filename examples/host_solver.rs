//! The library on a host's solves of K against its own matrix-free
//! path, per scene: the host here is a plain supernodal factor of K (faer,
//! the best ordering, as a CHOLMOD or MUMPS host would hold one) that solves
//! a block of right-hand sides in one call. Measured in one run, 1 thread:
//! the best plain factorisation (the baseline), the own path's creation (its
//! factorisation included) and the host path's creation (the host's
//! factorisation excluded: the host already holds it), the first solve and a
//! press-then-shear history of `--steps` steps, with the host's solves and
//! their seconds. `--single`: the host also solves in single precision
//! (`KSolve::solve_single`, from its factor's values rounded), which the
//! library takes for Newton's loose products. `--rows`: the host also
//! solves on rows (`KSolve::solve_rows`) by the paths of its factor's
//! elimination tree, as CHOLMOD's solves with Bset do (approximate ones in
//! single precision with `--single`), which the library takes for every
//! product with A. `--cholmod` (built with the feature `cholmod`, which
//! links -lcholmod): the host is CHOLMOD (`bench/cholmod_host.rs`), with
//! `--rows` its solves with Bset. `--blocks factor|auto`: the contact blocks
//! by the library's own factor of K (`HostBlocks`) instead of d m solves.
//!
//! ```text
//! cargo run --release --example host_solver [--features cholmod] -- [--scenes A,B,..]
//!     [--steps N] [--laws tresca,coulomb] [--no-k] [--single] [--rows] [--cholmod]
//!     [--blocks solves|factor|auto] [--threads K]
//! ```

#[path = "bench/baseline.rs"]
mod baseline;
#[cfg(feature = "cholmod")]
#[path = "bench/cholmod_host.rs"]
mod cholmod_host;
#[path = "bench/scene.rs"]
#[allow(dead_code)]
mod scene;
#[path = "bench/stats.rs"]
#[allow(dead_code)]
mod stats;

use dualsplit::internals::{Factor, RowSolves, Threads};
use dualsplit::{
    ContactProblem, Csc, DualForm, Format, Friction, HostBlocks, Indices, KSolve, MatrixView,
    Options, Ordering, SolveStatus, Storage,
};
use faer::dyn_stack::{MemBuffer, MemStack};
use scene::{Scene, Spec};
use std::sync::Arc;
use std::time::Instant;

/// Runs of each plain factorisation whose median is the baseline.
const FACTOR_REPS: usize = 3;

/// The host: a factor of K, solving a block of right-hand sides at once;
/// with `--single` also in single precision, from a copy of its factor's
/// values rounded to single precision (as a host holding a single-precision
/// factor, CHOLMOD 5 or SMUMPS, would), with the workspace of one solve.
struct Host {
    factor: Arc<Factor>,
    single: Option<(Arc<Vec<f32>>, MemBuffer)>,
    rows: Option<RowSolves>,
}

impl KSolve for Host {
    fn n(&self) -> usize {
        self.factor.n()
    }

    fn solve(&mut self, x: &mut [f64], ncols: usize) -> Result<(), i32> {
        let n = self.factor.n();
        let mut mem = MemBuffer::new(self.factor.solve_scratch(ncols));
        let m = faer::MatMut::from_column_major_slice_mut(x, n, ncols);
        self.factor.solve_in_place(m, MemStack::new(&mut mem));
        Ok(())
    }

    fn solve_single(&mut self, x: &mut [f32], _ncols: usize) -> Option<Result<(), i32>> {
        let (values, mem) = self.single.as_mut()?;
        let n = self.factor.n();
        for col in x.chunks_mut(n) {
            let m = faer::MatMut::from_column_major_slice_mut(col, n, 1);
            self.factor.solve_single(values, m, MemStack::new(mem));
        }
        Some(Ok(()))
    }

    fn solve_rows(
        &mut self,
        rows: &[usize],
        x: &mut [f64],
        ncols: usize,
        approximate: bool,
    ) -> Option<Result<(), i32>> {
        self.rows.as_mut()?.solve(rows, x, ncols, approximate);
        Some(Ok(()))
    }
}

/// 64-bit CSC arrays of a Csc, for a MatrixView.
struct Arrays {
    p: Vec<i64>,
    i: Vec<i64>,
}

impl Arrays {
    fn of(a: &Csc) -> Arrays {
        Arrays {
            p: a.col_ptr.iter().map(|&v| v as i64).collect(),
            i: a.row_idx.iter().map(|&v| v as i64).collect(),
        }
    }

    fn view<'a>(&'a self, a: &'a Csc) -> MatrixView<'a> {
        MatrixView {
            format: Format::Csc,
            storage: Storage::Full,
            base: 0,
            nrows: a.nrows,
            ncols: a.ncols,
            p: Indices::I64(&self.p),
            i: Indices::I64(&self.i),
            x: &a.values,
        }
    }
}

fn main() {
    let mut scenes = vec!["3d-24x24x12".to_string(), "3d-40x40x20".to_string()];
    let mut steps = 10usize;
    let mut laws = vec!["tresca".to_string(), "coulomb".to_string()];
    let mut with_k = true;
    let mut single = false;
    let mut rows = false;
    let mut on_cholmod = false;
    let mut blocks = HostBlocks::Solves;
    let mut threads = 1;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut k = 0;
    while k < args.len() {
        let value = || args.get(k + 1).expect("a value after the flag").clone();
        match args[k].as_str() {
            "--scenes" => scenes = value().split(',').map(str::to_string).collect(),
            "--steps" => steps = value().parse().expect("--steps N"),
            "--laws" => laws = value().split(',').map(str::to_string).collect(),
            "--threads" => threads = value().parse().expect("--threads K"),
            "--blocks" => {
                blocks = match value().as_str() {
                    "solves" => HostBlocks::Solves,
                    "factor" => HostBlocks::Factor,
                    "auto" => HostBlocks::Auto,
                    v => panic!("--blocks solves|factor|auto, not {v}"),
                }
            }
            "--no-k" => {
                with_k = false;
                k += 1;
                continue;
            }
            "--single" => {
                single = true;
                k += 1;
                continue;
            }
            "--rows" => {
                rows = true;
                k += 1;
                continue;
            }
            "--cholmod" => {
                if !cfg!(feature = "cholmod") {
                    panic!("--cholmod needs the example built with --features cholmod");
                }
                on_cholmod = true;
                k += 1;
                continue;
            }
            a => panic!("unknown argument {a}"),
        }
        k += 2;
    }
    let mut summary = Vec::new();
    for name in &scenes {
        let spec = Spec::parse(name).unwrap_or_else(|| panic!("bad scene {name}"));
        let sc = Scene::build(spec);
        let (press, shear) = sc.press_and_shear();
        let t_factor = baseline::best_plain_factor(&sc.k, threads, FACTOR_REPS);
        let opts = Options {
            threads,
            dual_form: DualForm::MatrixFree,
            tol: 1e-10,
            ..Options::default()
        };
        let t0 = Instant::now();
        let ordering = if sc.d == 3 {
            Ordering::Metis
        } else {
            Ordering::Amd
        };
        let host_factor =
            Factor::with_last(&sc.k, &[], ordering, Arc::new(Threads::new(threads))).unwrap();
        let t_host_factor = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let single_values = single.then(|| Arc::new(host_factor.single_values().unwrap()));
        let t_host_single = t0.elapsed().as_secs_f64();
        let arrays = (Arrays::of(&sc.k), Arrays::of(&sc.n), Arrays::of(&sc.t));
        for law in &laws {
            let friction = if law == "tresca" {
                Friction::Tresca(&sc.p)
            } else {
                Friction::Coulomb(&sc.mu)
            };
            let t1 = Instant::now();
            let mut own = ContactProblem::from_csc_with(
                sc.d,
                sc.k.clone(),
                sc.n.clone(),
                sc.t.clone(),
                &opts,
            )
            .unwrap();
            let t_own = t1.elapsed().as_secs_f64();
            let kv = arrays.0.view(&sc.k);
            let solver: Box<dyn KSolve> = if on_cholmod {
                cholmod_host(&sc.k, rows)
            } else {
                Box::new(Host {
                    factor: host_factor.clone(),
                    single: single_values
                        .clone()
                        .map(|v| (v, MemBuffer::new(host_factor.solve_scratch_single()))),
                    rows: rows.then(|| RowSolves::new(host_factor.clone(), single).unwrap()),
                })
            };
            let t2 = Instant::now();
            let mut host = ContactProblem::with_host_solver(
                sc.d,
                solver,
                with_k.then_some(&kv),
                &arrays.1.view(&sc.n),
                &arrays.2.view(&sc.t),
                &Options {
                    host_blocks: blocks,
                    ..opts
                },
            )
            .unwrap();
            let t_host = t2.elapsed().as_secs_f64();
            println!(
                "\n{name} (n = {}, c = {}), {law}, {threads} thread(s), K {}: best plain factor {t_factor:.3} s; \
                 own creation {t_own:.3} s ({:.2} x); host's factor {t_host_factor:.3} s{}, host creation \
                 (the contact blocks {:?}, for {} dual unknowns) {t_host:.3} s ({:.2} x)",
                sc.k.nrows,
                own.dual_unknowns(),
                if with_k {
                    "handed over"
                } else {
                    "not handed over"
                },
                t_own / t_factor,
                if single {
                    format!(" (and its single-precision copy {t_host_single:.3} s)")
                } else {
                    String::new()
                },
                blocks,
                own.dual_unknowns(),
                t_host / t_factor,
            );
            println!(
                "| step | own s | own / factor | own outer / inner | host s | host / factor | host outer / inner | host solves | in host s | host / own |"
            );
            println!("|---|---|---|---|---|---|---|---|---|---|");
            let (mut sum_own, mut sum_host) = (0.0, 0.0);
            for k in 1..=steps {
                let f = stats::history_load(&press, &shear, stats::load_factors(k, steps, false));
                let t = Instant::now();
                let a = own.step(&f, &sc.g, friction, &opts).unwrap();
                let ta = t.elapsed().as_secs_f64();
                let t = Instant::now();
                let b = host.step(&f, &sc.g, friction, &opts).unwrap();
                let tb = t.elapsed().as_secs_f64();
                assert_eq!(a.report.status, SolveStatus::Converged);
                assert_eq!(b.report.status, SolveStatus::Converged);
                sum_own += ta;
                sum_host += tb;
                let (ra, rb) = (&a.report, &b.report);
                println!(
                    "| {k} | {ta:.3} | {:.3} | {} / {} | {tb:.3} | {:.3} | {} / {} | {} | {:.3} | {:.2} |",
                    ta / t_factor,
                    ra.outer_iterations,
                    ra.inner_iterations,
                    tb / t_factor,
                    rb.outer_iterations,
                    rb.inner_iterations,
                    rb.host_solves,
                    rb.host_seconds,
                    tb / ta
                );
            }
            summary.push(format!(
                "| {name} | {} | {law} | {t_factor:.2} | {:.2} | {:.2} | {:.3} | {:.3} | {:.2} |",
                own.dual_unknowns(),
                (t_own - t_factor).max(0.0) / t_factor,
                t_host / t_factor,
                sum_own / steps as f64 / t_factor,
                sum_host / steps as f64 / t_factor,
                sum_host / sum_own
            ));
        }
    }
    println!(
        "\n| scene | c | law | factor s | own creation - factor, / factor | host creation / factor | own step / factor | host step / factor | host steps / own steps |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for s in summary {
        println!("{s}");
    }
}

/// CHOLMOD's factor of `k` as the host (`bench/cholmod_host.rs`), with its
/// solves with Bset where `rows`; its factorisation's seconds printed.
#[cfg(feature = "cholmod")]
fn cholmod_host(k: &Csc, rows: bool) -> Box<dyn KSolve> {
    let t = Instant::now();
    let host = cholmod_host::Cholmod::new(k, rows).expect("CHOLMOD factors K");
    println!("CHOLMOD's factor of K: {:.3} s", t.elapsed().as_secs_f64());
    Box::new(host)
}

#[cfg(not(feature = "cholmod"))]
fn cholmod_host(_: &Csc, _: bool) -> Box<dyn KSolve> {
    unreachable!("--cholmod is refused without the feature")
}
