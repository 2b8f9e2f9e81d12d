//! The summary tables (bench_results/summary.md) computed from the rows.

use crate::row::{Part, Row};
use crate::scene::Spec;
use std::collections::BTreeSet;
use std::fmt::Write as _;

/// Scenes in the order of their `factor` rows (the order of the run that measured
/// them; rows kept by `--append` come first in the file), then the others in order
/// of appearance.
pub fn scenes(rows: &[Row]) -> Vec<String> {
    let mut seen = BTreeSet::new();
    let mut v = Vec::new();
    for r in rows.iter().filter(|r| r.kind == "factor") {
        if seen.insert(r.scene.clone()) {
            v.push(r.scene.clone());
        }
    }
    for r in rows {
        if seen.insert(r.scene.clone()) {
            v.push(r.scene.clone());
        }
    }
    v
}

/// Methods of the solve rows, in order of appearance.
pub fn methods(rows: &[Row]) -> Vec<String> {
    let mut v: Vec<String> = Vec::new();
    for r in rows {
        if r.kind == "solve" && !v.contains(&r.method) {
            v.push(r.method.clone());
        }
    }
    v
}

pub fn frictions(rows: &[Row]) -> Vec<String> {
    let mut v: Vec<String> = Vec::new();
    for r in rows {
        if r.kind == "solve" && !v.contains(&r.friction) {
            v.push(r.friction.clone());
        }
    }
    v
}

/// The first row of a scene and kind (and method, when given).
pub fn find<'a>(rows: &'a [Row], scene: &str, kind: &str, method: Option<&str>) -> Option<&'a Row> {
    rows.iter()
        .find(|r| r.scene == scene && r.kind == kind && method.is_none_or(|m| r.method == m))
}

pub fn time_of(rows: &[Row], scene: &str, kind: &str) -> Option<f64> {
    find(rows, scene, kind, None).and_then(|r| r.time_s)
}

/// The fastest solve row of (scene, friction, method) whose err is at most `target`.
pub fn best_to<'a>(
    rows: &'a [Row],
    scene: &str,
    friction: &str,
    method: &str,
    target: f64,
) -> Option<&'a Row> {
    rows.iter()
        .filter(|r| {
            r.scene == scene
                && r.kind == "solve"
                && r.friction == friction
                && r.method == method
                && r.err.is_some_and(|e| e <= target)
                && r.time_s.is_some()
        })
        .min_by(|a, b| a.time_s.unwrap().total_cmp(&b.time_s.unwrap()))
}

/// The fastest method to `target`: (method, row).
pub fn best_method<'a>(
    rows: &'a [Row],
    scene: &str,
    friction: &str,
    target: f64,
) -> Option<(String, &'a Row)> {
    methods(rows)
        .into_iter()
        .filter_map(|m| best_to(rows, scene, friction, &m, target).map(|r| (m, r)))
        .min_by(|a, b| a.1.time_s.unwrap().total_cmp(&b.1.time_s.unwrap()))
}

/// Whether a scene belongs to the scaling family of its dimension: 2D blocks with
/// nx = 8 ny, 3D blocks with nx = ny = 2 nz, on uniform grids.
pub fn in_family(scene: &str) -> bool {
    match Spec::parse(scene) {
        Some(s) if s.graded => false,
        Some(s) if s.dim == 2 => s.nx == 8 * s.ny,
        Some(s) => s.nx == s.ny && s.nx == 2 * s.nz,
        None => false,
    }
}

/// Least-squares slope of log y against log x (None with fewer than 2 points).
pub fn slope(points: &[(f64, f64)]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let k = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / k;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / k;
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx > 0.0 { Some(sxy / sxx) } else { None }
}

fn f3(x: Option<f64>) -> String {
    match x {
        Some(v) if v >= 100.0 => format!("{v:.0}"),
        Some(v) if v >= 10.0 => format!("{v:.1}"),
        Some(v) if v >= 0.1 => format!("{v:.2}"),
        Some(v) => format!("{v:.3}"),
        None => "-".into(),
    }
}

fn e1(x: Option<f64>) -> String {
    x.map(|v| format!("{v:.1e}")).unwrap_or_else(|| "-".into())
}

/// A series over the scenes of one dimension in the family: (n, value).
pub fn series(
    rows: &[Row],
    dim: usize,
    value: impl Fn(&str) -> Option<f64>,
) -> Vec<(f64, f64, String)> {
    scenes(rows)
        .into_iter()
        .filter(|s| in_family(s))
        .filter_map(|s| {
            let r = find(rows, &s, "factor", None)?;
            if r.dim != dim {
                return None;
            }
            value(&s).map(|v| (r.n as f64, v, s.clone()))
        })
        .collect()
}

/// The setup a method needs: `setup_free` (matrix-free form) for the `-free`
/// series, `setup` (dense A) for the others.
pub fn setup_of(rows: &[Row], scene: &str, method: &str) -> Option<f64> {
    if method.ends_with("-free") {
        time_of(rows, scene, "setup_free")
    } else {
        time_of(rows, scene, "setup")
    }
}

/// The method with the smallest total (its setup + its fastest solve to `target`):
/// (method, total, solve row).
pub fn best_total_method<'a>(
    rows: &'a [Row],
    scene: &str,
    friction: &str,
    target: f64,
) -> Option<(String, f64, &'a Row)> {
    methods(rows)
        .into_iter()
        .filter_map(|m| {
            let r = best_to(rows, scene, friction, &m, target)?;
            let t = setup_of(rows, scene, &m)? + r.time_s?;
            Some((m, t, r))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Total time (setup + solve) of the method with the smallest total to `target`.
pub fn best_total(rows: &[Row], scene: &str, friction: &str, target: f64) -> Option<f64> {
    best_total_method(rows, scene, friction, target).map(|x| x.1)
}

/// The fastest warm step (err <= 1e-10, converged) of a scene: (method, time).
pub fn best_warm(rows: &[Row], scene: &str, friction: &str) -> Option<(String, f64)> {
    rows.iter()
        .filter(|r| {
            r.scene == scene
                && r.kind == "step_warm"
                && r.friction == friction
                && r.status == "Converged"
                && r.time_s.is_some()
        })
        .min_by(|a, b| a.time_s.unwrap().total_cmp(&b.time_s.unwrap()))
        .map(|r| (r.method.clone(), r.time_s.unwrap()))
}

/// The markdown summary.
pub fn summary(rows: &[Row]) -> String {
    let mut s = String::new();
    let sc = scenes(rows);
    let ms = methods(rows);
    let frs = frictions(rows);
    let _ = writeln!(
        s,
        "# Benchmark summary (generated by `cargo run --release --example bench`)\n"
    );
    let _ = writeln!(
        s,
        "Times in seconds (wall, median of up to 3 runs), memory in MB (peak resident, \
         per child process). `factor` = the best plain sparse Cholesky of K alone \
         (faer, `Ordering::Auto`: AMD, or METIS where it has fewer flops; ordering + \
         symbolic + numeric), the baseline of every `x factor` ratio; `CHOLMOD` = \
         CHOLMOD's own factorisation of the same K (its default ordering policy, \
         analyse + factorize, BLAS threads = the run's threads; `-` where SuiteSparse \
         is not installed); `setup` = `ContactProblem::from_csc` (factor with the contact DOFs \
         last + condensed dual A from the trailing block; where `DualForm::Auto` leaves \
         it matrix-free, c > 8,000, plus the dense assembly of A that the dense methods \
         need); `setup (m-free)` = the problem created matrix-free (the best plain \
         factor of K + the contacts' diagonal blocks of A, nothing c x c); `total` = the \
         method's setup + its solve; `newton-free`, `mprgp-free`, `auto-free` = those \
         methods matrix-free (the other series run on the dense A).\n"
    );
    // Scenes and setup costs.
    let _ = writeln!(s, "## Scenes and the cost of the setup\n");
    let _ = writeln!(
        s,
        "| scene | d | n | m | c | factor (ordering) | of which numeric | CHOLMOD (ordering) | CHOLMOD / factor | solve1 | setup | setup / factor | of which numeric factor (contacts last) | of which condensation | condensation by solves | peak MB (ours, dense) | peak MB (Clarabel) | load avg |"
    );
    let _ = writeln!(
        s,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for name in &sc {
        let Some(r) = find(rows, name, "factor", None) else {
            continue;
        };
        let solves = find(rows, name, "condense_solves", None).map(|r| {
            let tag = if r.status == "extrapolated" {
                " (extrap.)"
            } else {
                ""
            };
            format!("{}{tag}", f3(r.time_s))
        });
        // The peak of a child: the largest of its readings (they are stage peaks
        // where the peak was reset between stages).
        let mem = |part: Part| {
            rows.iter()
                .filter(|r| r.scene == *name && r.kind == "mem" && r.part() == part)
                .filter_map(|r| r.mem_mb)
                .reduce(f64::max)
                .map(|v| format!("{v:.0}"))
                .unwrap_or_else(|| "-".into())
        };
        let cholmod = find(rows, name, "cholmod", None);
        let loads: Vec<&str> = rows
            .iter()
            .filter(|r| r.scene == *name && r.kind == "mem")
            .filter_map(|r| r.note.strip_prefix("load1="))
            .collect();
        let _ = writeln!(
            s,
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.dim,
            r.n,
            r.m,
            r.c,
            with_ordering(f3(r.time_s), &r.note),
            f3(time_of(rows, name, "factor_numeric")),
            cholmod
                .map(|c| with_ordering(f3(c.time_s), &c.note))
                .unwrap_or_else(|| "-".into()),
            ratio(cholmod.and_then(|c| c.time_s), r.time_s),
            f3(time_of(rows, name, "solve1")),
            f3(time_of(rows, name, "setup")),
            ratio(time_of(rows, name, "setup"), r.time_s),
            f3(time_of(rows, name, "setup_factor")),
            f3(time_of(rows, name, "condense_trailing")),
            solves.unwrap_or_else(|| "-".into()),
            mem(Part::Dense),
            mem(Part::Clarabel),
            loads.join(" "),
        );
    }
    free_table(&mut s, rows, &sc, &frs);
    // Time to 1e-10.
    for fr in &frs {
        let _ = writeln!(
            s,
            "\n## {fr}: solve time to err <= 1e-10 (outer iterations), after the setup\n"
        );
        let mut head = "| scene | factor | setup |".to_string();
        let mut sep = "|---|---|---|".to_string();
        for m in &ms {
            let _ = write!(head, " {m} |");
            sep.push_str("---|");
        }
        head.push_str(
            " fastest solve | best total / factor (method) | warm step (best) | warm / factor |",
        );
        sep.push_str("---|---|---|---|");
        let _ = writeln!(s, "{head}\n{sep}");
        for name in &sc {
            let Some(tf) = time_of(rows, name, "factor") else {
                continue;
            };
            let mut line = format!(
                "| {name} | {} | {} |",
                f3(Some(tf)),
                f3(time_of(rows, name, "setup"))
            );
            for m in &ms {
                let cell = match best_to(rows, name, fr, m, 1e-10) {
                    Some(r) => format!("{} ({})", f3(r.time_s), r.outer.unwrap_or(0)),
                    None => "not reached".into(),
                };
                let _ = write!(line, " {cell} |");
            }
            let best = best_method(rows, name, fr, 1e-10).map(|(m, _)| m);
            let total = best_total_method(rows, name, fr, 1e-10);
            let warm = best_warm(rows, name, fr);
            let _ = write!(
                line,
                " {} | {} | {} | {} |",
                best.unwrap_or_else(|| "-".into()),
                total
                    .map(|(m, t, _)| format!("{:.2} ({m})", t / tf))
                    .unwrap_or_else(|| "-".into()),
                warm.as_ref()
                    .map(|(m, t)| format!("{} ({m})", f3(Some(*t))))
                    .unwrap_or_else(|| "-".into()),
                warm.map(|(_, t)| format!("{:.3}", t / tf))
                    .unwrap_or_else(|| "-".into()),
            );
            let _ = writeln!(s, "{line}");
        }
    }
    // Warm steps per method.
    let _ = writeln!(
        s,
        "\n## History: first step (cold) and the next step (warm start, load +5 %), tol 1e-10\n"
    );
    let _ = writeln!(
        s,
        "| scene | friction | method | cold [s] (outer) | warm [s] (outer) | warm / factor | warm err |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for name in &sc {
        let tf = time_of(rows, name, "factor");
        for fr in &frs {
            for m in &ms {
                let cold = rows.iter().find(|r| {
                    r.scene == *name && r.kind == "step_cold" && r.friction == *fr && r.method == *m
                });
                let warm = rows.iter().find(|r| {
                    r.scene == *name && r.kind == "step_warm" && r.friction == *fr && r.method == *m
                });
                if let (Some(c), Some(w)) = (cold, warm) {
                    let flag = |r: &Row| if r.status == "Converged" { "" } else { " NC" };
                    let _ = writeln!(
                        s,
                        "| {name} | {fr} | {m} | {} ({}){} | {} ({}){} | {} | {} |",
                        f3(c.time_s),
                        c.outer.unwrap_or(0),
                        flag(c),
                        f3(w.time_s),
                        w.outer.unwrap_or(0),
                        flag(w),
                        match (w.time_s, tf) {
                            (Some(a), Some(b)) => format!("{:.3}", a / b),
                            _ => "-".into(),
                        },
                        e1(w.err)
                    );
                }
            }
        }
    }
    // Clarabel.
    let _ = writeln!(
        s,
        "\n## Clarabel on the Tresca problem, against our fastest method at equal or better err (totals)\n"
    );
    let _ = writeln!(
        s,
        "| scene | Clarabel tol | Clarabel [s] | iterations | status | err (u from its multipliers) | err (its own u) | ours: method | ours total [s] | ours err | Clarabel / ours |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for name in &sc {
        for r in rows
            .iter()
            .filter(|r| r.scene == *name && r.kind == "clarabel")
        {
            let e = r.err.unwrap_or(f64::INFINITY);
            let (om, ot, oe) = match best_total_method(rows, name, "tresca", e) {
                Some((m, t, o)) => (m, Some(t), o.err),
                None => ("-".into(), None, None),
            };
            let _ = writeln!(
                s,
                "| {name} | {} | {} | {} | {} | {} | {} | {om} | {} | {} | {} |",
                e1(r.tol),
                f3(r.time_s),
                r.outer.unwrap_or(0),
                r.status,
                e1(r.err),
                r.note.strip_prefix("err_primal_u=").unwrap_or("-"),
                f3(ot),
                e1(oe),
                match (r.time_s, ot) {
                    (Some(a), Some(b)) => format!("{:.0}", a / b),
                    _ => "-".into(),
                }
            );
        }
    }
    // Exponents.
    let _ = writeln!(
        s,
        "\n## Scaling exponents (least-squares slope of log time against log n over the family: 2D nx = 8 ny, 3D nx = ny = 2 nz; number of scenes in brackets)\n"
    );
    let _ = writeln!(
        s,
        "| quantity | 2D, all | 2D, 3 largest | 3D, all | 3D, 3 largest |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    type Value<'a> = Box<dyn Fn(&str) -> Option<f64> + 'a>;
    let mut quantities: Vec<(String, Value)> = vec![
        (
            "factor of K alone".into(),
            Box::new(|sn: &str| time_of(rows, sn, "factor")),
        ),
        (
            "setup (factor contacts last + condensation)".into(),
            Box::new(|sn: &str| time_of(rows, sn, "setup")),
        ),
        (
            "condensation (trailing block)".into(),
            Box::new(|sn: &str| time_of(rows, sn, "condense_trailing")),
        ),
        (
            "setup, matrix-free (plain factor + contact blocks of A)".into(),
            Box::new(|sn: &str| time_of(rows, sn, "setup_free")),
        ),
        (
            "matrix-free build (contact blocks of A)".into(),
            Box::new(|sn: &str| time_of(rows, sn, "condense_free")),
        ),
        (
            "condensation by solves (measured or extrapolated)".into(),
            Box::new(|sn: &str| time_of(rows, sn, "condense_solves")),
        ),
    ];
    for fr in &frs {
        let fr2 = fr.clone();
        quantities.push((
            format!("{fr}: best solve to 1e-10 (after setup)"),
            Box::new(move |sn: &str| {
                best_method(rows, sn, &fr2, 1e-10).and_then(|(_, r)| r.time_s)
            }),
        ));
        let fr3 = fr.clone();
        quantities.push((
            format!("{fr}: best total to 1e-10"),
            Box::new(move |sn: &str| best_total(rows, sn, &fr3, 1e-10)),
        ));
        for m in &ms {
            let (fr4, m4) = (fr.clone(), m.clone());
            quantities.push((
                format!("{fr}: {m} solve to 1e-10"),
                Box::new(move |sn: &str| {
                    best_to(rows, sn, &fr4, &m4, 1e-10).and_then(|r| r.time_s)
                }),
            ));
        }
        let fr5 = fr.clone();
        quantities.push((
            format!("{fr}: best warm step"),
            Box::new(move |sn: &str| best_warm(rows, sn, &fr5).map(|x| x.1)),
        ));
    }
    for (label, f) in &quantities {
        let e = |dim, last: usize| {
            let mut pts: Vec<(f64, f64)> =
                series(rows, dim, f).iter().map(|p| (p.0, p.1)).collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let pts = &pts[pts.len().saturating_sub(last)..];
            match slope(pts) {
                Some(v) => format!("{v:.2} ({})", pts.len()),
                None => "-".into(),
            }
        };
        let _ = writeln!(
            s,
            "| {label} | {} | {} | {} | {} |",
            e(2, usize::MAX),
            e(2, 3),
            e(3, usize::MAX),
            e(3, 3)
        );
    }
    s
}

/// Dense against matrix-free: setup, peak memory, Newton, MPRGP and auto to
/// 1e-10.
fn free_table(s: &mut String, rows: &[Row], sc: &[String], frs: &[String]) {
    let has_free = sc.iter().any(|n| time_of(rows, n, "setup_free").is_some());
    if !has_free {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Dense against matrix-free condensed dual\n\n\
         `setup` builds the dense A (for c > 8,000 `from_csc` gives the matrix-free form and \
         the dense assembly follows: both counted); `setup (m-free)` builds the matrix-free \
         form only. Peak MB: resident peak during the setup (reset before it: \
         /proc/self/clear_refs), the scene (K, N, T, f) still resident, and in brackets \
         its rise over the resident memory at the start of the setup (the dense child \
         holds freed heap from the factorisation of K alone there); the matrix-free \
         setup forms nothing c x c. Newton to err <= 1e-10 on the dense A \
         (`newton`) and matrix-free (`newton-free`, its steps by CG / GMRES), MPRGP and \
         auto matrix-free, solve only (outer iterations), then the totals with each \
         form's setup.\n"
    );
    let mut head = "| scene | c | setup | of which dense condensation | setup (m-free) | of which m-free build | peak MB setup (dense) | peak MB setup (m-free) |".to_string();
    let mut sep = "|---|---|---|---|---|---|---|---|".to_string();
    for fr in frs {
        let _ = write!(
            head,
            " {fr}: newton | {fr}: newton-free | {fr}: mprgp-free | {fr}: auto-free | \
             {fr}: total newton / newton-free / auto-free |"
        );
        sep.push_str("---|---|---|---|---|");
    }
    let _ = writeln!(s, "{head}\n{sep}");
    // Peak of the setup stage, and its rise over the resident memory at its start.
    let mem = |name: &str, stage: &str| {
        let get = |st: &str| find(rows, name, "mem", Some(st)).and_then(|r| r.mem_mb);
        match (get(stage), get(&format!("{stage}-start"))) {
            (Some(p), Some(s0)) => format!("{p:.0} (+{:.0})", p - s0),
            (Some(p), None) => format!("{p:.0}"),
            _ => "-".into(),
        }
    };
    for name in sc {
        let Some(r) = find(rows, name, "factor", None) else {
            continue;
        };
        if time_of(rows, name, "setup_free").is_none() {
            continue;
        }
        let mut line = format!(
            "| {name} | {} | {} | {} | {} | {} | {} | {} |",
            r.c,
            f3(time_of(rows, name, "setup")),
            f3(time_of(rows, name, "condense_trailing")),
            f3(time_of(rows, name, "setup_free")),
            f3(time_of(rows, name, "condense_free")),
            mem(name, "setup"),
            mem(name, "free-setup"),
        );
        for fr in frs {
            let cell = |m: &str| match best_to(rows, name, fr, m, 1e-10) {
                Some(r) => format!("{} ({})", f3(r.time_s), r.outer.unwrap_or(0)),
                None => "not reached".into(),
            };
            let tot = |m: &str| {
                let r = best_to(rows, name, fr, m, 1e-10)?;
                Some(setup_of(rows, name, m)? + r.time_s?)
            };
            let _ = write!(
                line,
                " {} | {} | {} | {} | {} / {} / {} |",
                cell("newton"),
                cell("newton-free"),
                cell("mprgp-free"),
                cell("auto-free"),
                f3(tot("newton")),
                f3(tot("newton-free")),
                f3(tot("auto-free"))
            );
        }
        let _ = writeln!(s, "{line}");
    }
}

/// `time (ordering)` where the row's note names the ordering (`ordering=NAME`).
fn with_ordering(time: String, note: &str) -> String {
    match note
        .split_whitespace()
        .find_map(|w| w.strip_prefix("ordering="))
    {
        Some(o) => format!("{time} ({o})"),
        None => time,
    }
}

/// `a / b` to two decimals, `-` where either is missing.
fn ratio(a: Option<f64>, b: Option<f64>) -> String {
    match (a, b) {
        (Some(a), Some(b)) if b > 0.0 => format!("{:.2}", a / b),
        _ => "-".into(),
    }
}
