//! Quasistatic histories: per scene, the best plain factorisation of
//! K (the baseline: AMD and METIS, analysis and numeric factorisation, each the
//! median of FACTOR_REPS runs, the faster, measured in the same run), then a contact problem created with the
//! default options and a history of `--steps` calls of `step`: the first half
//! presses the top down in equal increments, the second half shears it at full
//! press (so contacts close, stick and slip change along the way), Tresca and
//! Coulomb. Per step: seconds (wall clock of `step`), their ratio to the
//! baseline, Newton steps (outer), products or sweeps (inner), open / stick /
//! slip, err and the equilibrium residual; per history: creation, the mean and worst warm step, and the
//! creation plus the first 10 steps and plus all steps, in units of the
//! baseline, and the cold increment at full load (the creation plus a
//! solve of the whole load from zero multipliers, with its phases).
//! `--csv FILE` writes the per-step rows; `--svg FILE` draws them:
//! the time of each step in units of the baseline along the history, one
//! line per scene and law.
//!
//! ```text
//! cargo run --release --example history -- [--scenes A,B,..] [--threads K]
//!     [--steps N] [--laws tresca,coulomb] [--form auto|dense|matrix-free]
//!     [--path press-shear|proportional|reversal] [--theta DEG --slip R]
//!     [--gap G] [--trace STEP] [--csv FILE] [--svg FILE]
//! ```
//!
//! `--theta DEG --slip R`: the shear moves the top by R mu delta (delta the
//! press, mu Coulomb's) in the direction DEG degrees off the x axis (off the
//! T rows), instead of 0.5 delta along x; R above 1 is gross slip. `--gap G`
//! scales the paraboloid gap by G (below 1: more of the face closes).
//! `--trace K` prints step K's progress per outer iteration (`--trace 0`: the
//! cold increment's).
//! `--path reversal`: press then shear as `press-shear`, the last quarter of
//! the steps taking the shear back to its negative.
//!
//! `--path proportional`: step k of N takes k / N of the whole top motion
//! (press and shear together), as a host that ramps one load does.

#[path = "bench/baseline.rs"]
mod baseline;
#[path = "bench/scene.rs"]
#[allow(dead_code)]
mod scene;
#[path = "bench/stats.rs"]
#[allow(dead_code)]
mod stats;

use dualsplit::{ContactProblem, DualForm, Friction, Options};
use scene::{Scene, Spec};
use std::io::Write;
use std::time::Instant;

/// Runs of each plain factorisation whose median is the baseline.
const FACTOR_REPS: usize = 3;

fn main() {
    let mut scenes = vec!["3d-40x40x20".to_string(), "3d-64x64x6".to_string()];
    let mut threads = 1;
    let mut steps = 20usize;
    let mut laws = vec!["tresca".to_string(), "coulomb".to_string()];
    let mut csv: Option<String> = None;
    let mut svg: Option<String> = None;
    let mut form = DualForm::Auto;
    let mut proportional = false;
    let mut reversal = false;
    let mut oblique: Option<(f64, f64)> = None;
    let (mut theta, mut slip) = (0.0, None);
    let mut gap_scale = 1.0;
    let mut trace: Option<usize> = None;
    // (scene and law, time / factor per step) for the figure.
    let mut lines: Vec<(String, Vec<f64>)> = Vec::new();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut k = 0;
    while k < args.len() {
        let value = || args.get(k + 1).expect("a value after the flag").clone();
        match args[k].as_str() {
            "--scenes" => scenes = value().split(',').map(str::to_string).collect(),
            "--threads" => threads = value().parse().expect("--threads K"),
            "--steps" => steps = value().parse().expect("--steps N"),
            "--laws" => laws = value().split(',').map(str::to_string).collect(),
            "--csv" => csv = Some(value()),
            "--svg" => svg = Some(value()),
            "--path" => {
                let v = value();
                proportional = v == "proportional";
                reversal = v == "reversal";
            }
            "--theta" => theta = value().parse().expect("--theta DEG"),
            "--slip" => slip = Some(value().parse().expect("--slip R")),
            "--gap" => gap_scale = value().parse().expect("--gap G"),
            "--trace" => trace = Some(value().parse().expect("--trace STEP")),
            "--form" => form = DualForm::from_name(&value()).expect("a dual form"),
            a => panic!("unknown argument {a}"),
        }
        k += 2;
    }
    let steps = steps.max(2);
    // The scenes' assembly (graded grids included) against its checks.
    scene::check_assembly();
    if let Some(r) = slip {
        oblique = Some((r, theta));
    } else {
        assert!(theta == 0.0, "--theta needs --slip");
    }
    let mut csv = csv.map(|p| {
        let mut f = std::fs::File::create(&p).expect("the csv file");
        writeln!(
            f,
            "scene,threads,law,step,seconds,per_factor,rhs_s,iterate_s,recover_s,outer,inner,open,stick,slip,err,equilibrium_residual"
        )
        .unwrap();
        f
    });
    let mut summary = Vec::new();
    for name in &scenes {
        let spec = Spec::parse(name).unwrap_or_else(|| panic!("bad scene {name}"));
        let mut sc = Scene::build(spec);
        sc.g.iter_mut().for_each(|g| *g *= gap_scale);
        let (press, mut shear) = sc.press_and_shear();
        if let Some((r, th)) = oblique {
            shear = sc.oblique_shear(r, th);
        }
        let t_factor = baseline::best_plain_factor(&sc.k, threads, FACTOR_REPS);
        let opts = Options {
            threads,
            dual_form: form,
            tol: 1e-10,
            ..Options::default()
        };
        for law in &laws {
            let friction = if law == "tresca" {
                Friction::Tresca(&sc.p)
            } else {
                Friction::Coulomb(&sc.mu)
            };
            let t1 = Instant::now();
            let mut pb = ContactProblem::from_csc_with(
                sc.d,
                sc.k.clone(),
                sc.n.clone(),
                sc.t.clone(),
                &opts,
            )
            .expect("the scene is valid");
            let t_create = t1.elapsed().as_secs_f64();
            println!(
                "\n{name} (n = {}, c = {}), {law}, {threads} thread(s): best plain factor {t_factor:.3} s, creation {t_create:.3} s ({:.2} x), {} dual",
                sc.k.nrows,
                pb.dual_unknowns(),
                t_create / t_factor,
                if pb.is_matrix_free() {
                    "matrix-free"
                } else {
                    "dense"
                }
            );
            println!(
                "| step | press | shear | s | / factor | rhs / iterations / recovery, / factor | method | outer | inner | open / stick / slip | err | equilibrium residual |"
            );
            println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
            let mut times = Vec::new();
            for k in 1..=steps {
                let (a, mut b) = stats::load_factors(k, steps, proportional);
                // The reversal: the shear reaches +1 at three quarters of the
                // steps, then goes back to -1 at the last.
                let (half, back) = (steps / 2, steps - steps / 4);
                if reversal && k > half {
                    b = if k <= back {
                        (k - half) as f64 / (back - half) as f64
                    } else {
                        1.0 - 2.0 * (k - back) as f64 / (steps - back) as f64
                    };
                }
                let f = stats::history_load(&press, &shear, (a, b));
                let t0 = Instant::now();
                let label = format!("step {k}");
                let mut show = |p: &dualsplit::Progress| print_progress(&label, p);
                let monitor: Option<dualsplit::Monitor<'_>> =
                    (trace == Some(k)).then_some(&mut show as dualsplit::Monitor<'_>);
                let sol = pb
                    .step_monitored(&f, &sc.g, friction, &opts, monitor)
                    .expect("solves");
                let t = t0.elapsed().as_secs_f64();
                times.push(t);
                let r = &sol.report;
                assert_eq!(r.status, dualsplit::SolveStatus::Converged, "{r:?}");
                println!(
                    "| {k} | {a:.2} | {b:.2} | {t:.3} | {:.3} | {:.3} / {:.3} / {:.3} | {} | {} | {} | {} / {} / {} | {:.1e} | {:.1e} |",
                    t / t_factor,
                    r.rhs_seconds / t_factor,
                    r.iterate_seconds / t_factor,
                    r.recover_seconds / t_factor,
                    r.method.name(),
                    r.outer_iterations,
                    r.inner_iterations,
                    r.n_open,
                    r.n_stick,
                    r.n_slip,
                    r.err,
                    r.equilibrium_residual
                );
                if let Some(f) = csv.as_mut() {
                    writeln!(
                        f,
                        "{name},{threads},{law},{k},{t},{},{},{},{},{},{},{},{},{},{},{}",
                        t / t_factor,
                        r.rhs_seconds,
                        r.iterate_seconds,
                        r.recover_seconds,
                        r.outer_iterations,
                        r.inner_iterations,
                        r.n_open,
                        r.n_stick,
                        r.n_slip,
                        r.err,
                        r.equilibrium_residual
                    )
                    .unwrap();
                }
            }
            // The cold increment at full load: the creation, then a solve
            // from zero multipliers of the whole load (press and shear at
            // +1), as a host's first increment that takes the full load.
            let full = stats::history_load(&press, &shear, (1.0, 1.0));
            let t0 = Instant::now();
            let mut show = |p: &dualsplit::Progress| print_progress("cold", p);
            let monitor: Option<dualsplit::Monitor<'_>> =
                (trace == Some(0)).then_some(&mut show as dualsplit::Monitor<'_>);
            let cold = pb
                .solve_monitored(&full, &sc.g, friction, &opts, monitor)
                .expect("solves");
            let t_cold = t0.elapsed().as_secs_f64();
            let r = &cold.report;
            assert_eq!(r.status, dualsplit::SolveStatus::Converged, "{r:?}");
            println!(
                "cold increment at full load: creation {:.2} (analysis {:.2}, factor {:.2}, condensation {:.2}) + solve {:.2} (rhs {:.3}, iterations {:.3}, recovery {:.3}) = {:.2} factorisations; {} outer, {} inner, err {:.1e}",
                t_create / t_factor,
                r.analyse_seconds / t_factor,
                r.factor_seconds / t_factor,
                r.condense_seconds / t_factor,
                t_cold / t_factor,
                r.rhs_seconds / t_factor,
                r.iterate_seconds / t_factor,
                r.recover_seconds / t_factor,
                (t_create + t_cold) / t_factor,
                r.outer_iterations,
                r.inner_iterations,
                r.err
            );
            lines.push((
                format!("{name} {law}, {threads} thread(s)"),
                times.iter().map(|t| t / t_factor).collect(),
            ));
            let warm = &times[1..];
            let mean = warm.iter().sum::<f64>() / warm.len() as f64;
            let worst = warm.iter().cloned().fold(0.0, f64::max);
            let ten: f64 = t_create + times.iter().take(10).sum::<f64>();
            let all: f64 = t_create + times.iter().sum::<f64>();
            summary.push(format!(
                "| {name} | {} | {law} | {threads} | {t_factor:.2} | {:.2} | {:.2} | {:.2} | {:.3} | {:.3} | {:.2} | {:.2} |",
                pb.dual_unknowns(),
                t_create / t_factor,
                (t_create + t_cold) / t_factor,
                times[0] / t_factor,
                mean / t_factor,
                worst / t_factor,
                ten / t_factor,
                all / t_factor
            ));
        }
    }
    println!(
        "\n| scene | c | law | threads | factor s | creation / factor | cold increment at full load / factor | first step / factor | warm step / factor, mean | worst | creation + 10 steps / factor | creation + {steps} steps / factor |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for s in summary {
        println!("{s}");
    }
    if let Some(path) = svg {
        draw(&lines, steps, &path).expect("the figure");
    }
}

/// Time per step / factor along the history, one line per scene and law
/// (log scale).
fn draw(
    lines: &[(String, Vec<f64>)],
    steps: usize,
    path: &str,
) -> Result<(), Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (1000, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let all = lines.iter().flat_map(|(_, v)| v.iter().copied());
    let (lo, hi) = all.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = ((lo * 0.7).min(0.1), (hi * 1.4).max(1.2));
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "history steps (press, then shear): time per step / best plain factorisation of K",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5f64..steps as f64 + 0.5, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("step (the first is cold)")
        .y_desc("step time / factor")
        .draw()?;
    // The lines: one factorisation, and the targets of the mean warm step
    // (0.5 of a factorisation on a large face, 0.15 on the dense route).
    for (level, what) in [(1.0, "1 factorisation"), (0.5, "0.5"), (0.15, "0.15")] {
        chart
            .draw_series(LineSeries::new(
                [(0.5, level), (steps as f64 + 0.5, level)],
                BLACK.mix(0.3).stroke_width(1),
            ))?
            .label(what)
            .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.mix(0.3)));
    }
    for (i, (label, v)) in lines.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let pts: Vec<(f64, f64)> = v
            .iter()
            .enumerate()
            .map(|(k, &t)| ((k + 1) as f64, t))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(2)));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// One line of a traced solve's progress (`--trace`), `label` naming the
/// solve ("step K" or "cold"); true: go on.
fn print_progress(label: &str, p: &dualsplit::Progress) -> bool {
    println!(
        "    {label} iteration {}: err {:.2e}, open / stick / slip {} / {} / {}, {:.3} s",
        p.iteration, p.err, p.n_open, p.n_stick, p.n_slip, p.elapsed_seconds
    );
    true
}
