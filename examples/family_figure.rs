//! The figure of the 3D load-path family (BENCHMARKS.md, "The load paths
//! hosts take"): reads the output of `examples/history.rs` run per scene and
//! path (each run headed by a line `=== SCENE path=P theta=T slip=R ...`, its
//! summary rows kept) and draws, per scene, path and law, the cold increment
//! at full load, the warm step's mean and worst, and the creation plus 10
//! steps, each in units of that run's best plain factorisation of K, with
//! the targets as lines.
//!
//! ```text
//! cargo run --release --example family_figure -- RAW.txt OUT.svg
//! ```

use plotters::prelude::*;

/// A quantity drawn: its name, how it is read from a row, its colour.
type Series = (&'static str, fn(&Row) -> f64, RGBColor);

/// One summary row of the family.
struct Row {
    label: String,
    cold: f64,
    mean: f64,
    worst: f64,
    ten: f64,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (raw, out) = match &args[..] {
        [raw, out] => (raw, out),
        _ => panic!("usage: family_figure RAW.txt OUT.svg"),
    };
    let rows = parse(&std::fs::read_to_string(raw)?);
    assert!(!rows.is_empty(), "no summary rows in {raw}");
    draw(&rows, out)
}

/// The summary rows, labelled "scene path law" (the path from the last
/// `===` line before them).
fn parse(text: &str) -> Vec<Row> {
    let mut path = String::new();
    let mut rows = Vec::new();
    for line in text.lines() {
        if let Some(head) = line.strip_prefix("=== ") {
            let p = head
                .split_whitespace()
                .find_map(|w| w.strip_prefix("path="))
                .unwrap_or("?");
            path = p.to_string();
            continue;
        }
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        // | scene | c | law | threads | factor | creation | cold increment |
        // first step | warm mean | worst | creation + 10 | creation + all |
        if cells.len() < 13 || !cells[1].starts_with("3d-") {
            continue;
        }
        let num = |i: usize| cells[i].parse::<f64>().unwrap_or(f64::NAN);
        let scene = cells[1].trim_start_matches("3d-");
        rows.push(Row {
            label: format!("{scene} {path} {}", cells[3].get(..1).unwrap_or("?")),
            cold: num(7),
            mean: num(9),
            worst: num(10),
            ten: num(11),
        });
    }
    rows
}

fn draw(rows: &[Row], path: &str) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (1200, 620)).into_drawing_area();
    root.fill(&WHITE)?;
    let n = rows.len();
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "3D load-path family: cost / best plain factorisation of K (1 thread)",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(110)
        .y_label_area_size(60)
        .build_cartesian_2d(-0.5f64..n as f64 - 0.5, (0.01f64..20.0).log_scale())?;
    chart
        .configure_mesh()
        .x_labels(n)
        .x_label_formatter(&|x| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < rows.len() {
                rows[i as usize].label.clone()
            } else {
                String::new()
            }
        })
        .x_label_style(
            ("sans-serif", 11)
                .into_font()
                .transform(FontTransform::Rotate90),
        )
        .y_desc("/ factorisation")
        .draw()?;
    let targets = [
        (0.15, "warm mean, dense: 0.15"),
        (0.5, "warm mean, matrix-free: 0.5"),
        (1.0, "warm worst: 1"),
        (3.0, "cold increment: 3"),
        (4.0, "creation + 10, dense: 4"),
        (8.0, "creation + 10, matrix-free: 8"),
    ];
    for (i, (level, what)) in targets.iter().enumerate() {
        let style = Palette99::pick(10 + i).mix(0.5).stroke_width(1);
        chart
            .draw_series(LineSeries::new(
                [(-0.5, *level), (n as f64 - 0.5, *level)],
                style,
            ))?
            .label(*what)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], style));
    }
    let series: [Series; 4] = [
        ("cold increment at full load", |r| r.cold, RED),
        ("warm step, mean", |r| r.mean, BLUE),
        ("warm step, worst", |r| r.worst, CYAN),
        ("creation + 10 steps", |r| r.ten, BLACK),
    ];
    for (name, value, colour) in series {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .enumerate()
            .map(|(i, r)| (i as f64, value(r)))
            .filter(|p| p.1.is_finite() && p.1 > 0.0)
            .collect();
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 4, colour.filled())))?
            .label(name)
            .legend(move |(x, y)| Circle::new((x + 8, y), 4, colour.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    root.present()?;
    Ok(())
}
