//! SVG figures (plotters): work-precision diagrams per scene and scaling curves.

use crate::report::{
    best_to, best_total, best_warm, find, frictions, methods, scenes, series, setup_of, time_of,
};
use crate::row::Row;
use plotters::prelude::*;
use std::error::Error;
use std::path::Path;

type Res = Result<(), Box<dyn Error>>;

fn color(i: usize) -> RGBColor {
    const C: [RGBColor; 12] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(0, 0, 128),
        RGBColor(128, 64, 0),
    ];
    C[i % C.len()]
}

/// Bounds of a log axis covering `v` with a margin (decades rounded outwards).
fn log_range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for x in v.filter(|x| *x > 0.0 && x.is_finite()) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if !lo.is_finite() {
        return (1e-3, 1.0);
    }
    (
        10f64.powf(lo.log10().floor()),
        10f64.powf((hi * 1.01).log10().ceil()),
    )
}

fn sci(x: &f64) -> String {
    format!("{x:.0e}")
}

type Chart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<
        plotters::coord::combinators::LogCoord<f64>,
        plotters::coord::combinators::LogCoord<f64>,
    >,
>;

/// A labelled line through `p`, solid or dashed (legend alike).
fn line(chart: &mut Chart, p: &[(f64, f64)], label: &str, style: ShapeStyle, dashed: bool) -> Res {
    if dashed {
        chart
            .draw_series(DashedLineSeries::new(p.to_vec(), 8, 5, style))?
            .label(label)
            .legend(move |(x, y)| {
                plotters::element::DashedPathElement::new(vec![(x, y), (x + 20, y)], 6, 3, style)
            });
    } else {
        chart
            .draw_series(LineSeries::new(p.to_vec(), style))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    Ok(())
}

/// Draws every figure into `out`.
pub fn draw_all(rows: &[Row], out: &Path) -> Res {
    for s in scenes(rows) {
        if find(rows, &s, "factor", None).is_some() {
            work_precision(rows, &s, &out.join(format!("wp_{s}.svg")))?;
        }
    }
    scaling(rows, &out.join("scaling.svg"))?;
    Ok(())
}

/// One scene: rows = frictions; columns = total time (setup + solve) and the solve
/// alone, against err, one line per method; the factorisation of K alone as a
/// horizontal line; Clarabel's runs as crosses (total time, Tresca).
fn work_precision(rows: &[Row], scene: &str, path: &Path) -> Res {
    let frs = frictions(rows);
    let ms = methods(rows);
    let nfr = frs.len().max(1);
    let root = SVGBackend::new(path, (1300, 480 * nfr as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let head = find(rows, scene, "factor", None).expect("scene has a factor row");
    let title = format!(
        "{scene}: n = {}, m = {}, c = {} - time against err",
        head.n, head.m, head.c
    );
    let (top, body) = root.split_vertically(36);
    top.titled(&title, ("sans-serif", 22))?;
    let panels = body.split_evenly((nfr, 2));
    let tf = time_of(rows, scene, "factor");
    let clar: Vec<&Row> = rows
        .iter()
        .filter(|r| r.scene == scene && r.kind == "clarabel" && r.time_s.is_some())
        .collect();
    for (fi, fr) in frs.iter().enumerate() {
        for (col, total) in [(0, true), (1, false)] {
            let area = &panels[fi * 2 + col];
            let pts = |m: &str| -> Vec<(f64, f64)> {
                let mut v: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| {
                        r.scene == scene
                            && r.kind == "solve"
                            && r.friction == *fr
                            && r.method == m
                            && r.err.is_some_and(|e| e > 0.0)
                            && r.time_s.is_some()
                    })
                    .map(|r| {
                        let setup = setup_of(rows, scene, m).unwrap_or(0.0);
                        let t = r.time_s.unwrap() + if total { setup } else { 0.0 };
                        (r.err.unwrap().max(1e-17), t)
                    })
                    .collect();
                v.sort_by(|a, b| b.0.total_cmp(&a.0));
                v
            };
            let all: Vec<(f64, f64)> = ms.iter().flat_map(|m| pts(m)).collect();
            let mut times: Vec<f64> = all.iter().map(|p| p.1).collect();
            times.extend(tf);
            if total && fr == "tresca" {
                times.extend(clar.iter().filter_map(|r| r.time_s));
            }
            let (ylo, yhi) = log_range(times.into_iter());
            let (xlo, _) = log_range(all.iter().map(|p| p.0).chain(std::iter::once(1e-13)));
            let caption = format!(
                "{fr}, {}",
                if total {
                    "total = setup + solve"
                } else {
                    "solve only (after setup)"
                }
            );
            let mut chart = ChartBuilder::on(area)
                .caption(caption, ("sans-serif", 17))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d((xlo..1.0f64).log_scale(), (ylo..yhi).log_scale())?;
            chart
                .configure_mesh()
                .x_desc("err (docs/design.md section 5)")
                .y_desc("time [s]")
                .x_label_formatter(&sci)
                .y_label_formatter(&sci)
                .draw()?;
            for (mi, m) in ms.iter().enumerate() {
                let p = pts(m);
                if p.is_empty() {
                    continue;
                }
                // A matrix-free series: the colour of its dense counterpart, dashed.
                let dense = m.strip_suffix("-free");
                let ci = dense
                    .and_then(|d| ms.iter().position(|x| x == d))
                    .unwrap_or(mi);
                let c = color(ci);
                line(&mut chart, &p, m, c.stroke_width(2), dense.is_some())?;
                chart.draw_series(p.iter().map(|&q| Circle::new(q, 3, c.filled())))?;
            }
            if let Some(t) = tf {
                chart
                    .draw_series(LineSeries::new(
                        vec![(xlo, t), (1.0, t)],
                        BLACK.stroke_width(1),
                    ))?
                    .label("factor of K alone")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
                if total {
                    chart
                        .draw_series(LineSeries::new(
                            vec![(xlo, 1.5 * t), (1.0, 1.5 * t)],
                            BLACK.mix(0.4).stroke_width(1),
                        ))?
                        .label("1.5 x factor")
                        .legend(|(x, y)| {
                            PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.4))
                        });
                }
            }
            if total && fr == "tresca" && !clar.is_empty() {
                let red = RGBColor(200, 0, 0);
                chart
                    .draw_series(clar.iter().filter_map(|r| {
                        let e = r.err?.max(1e-17);
                        Some(Cross::new((e, r.time_s?), 6, red.stroke_width(2)))
                    }))?
                    .label("Clarabel (total)")
                    .legend(move |(x, y)| Cross::new((x + 10, y), 5, red.stroke_width(2)));
            }
            chart
                .configure_series_labels()
                .position(if total {
                    SeriesLabelPosition::LowerLeft
                } else {
                    SeriesLabelPosition::UpperRight
                })
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .draw()?;
        }
    }
    root.present()?;
    Ok(())
}

/// Time against n, log-log, 2D and 3D side by side, for each friction law.
fn scaling(rows: &[Row], path: &Path) -> Res {
    let frs = frictions(rows);
    let nfr = frs.len().max(1);
    let root = SVGBackend::new(path, (1300, 520 * nfr as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, body) = root.split_vertically(36);
    top.titled(
        "Scaling with n (families: 2D nx = 8 ny, 3D nx = ny = 2 nz)",
        ("sans-serif", 22),
    )?;
    let panels = body.split_evenly((nfr, 2));
    let ms = methods(rows);
    for (fi, fr) in frs.iter().enumerate() {
        for (col, dim) in [(0, 2usize), (1, 3usize)] {
            let area = &panels[fi * 2 + col];
            type Value<'a> = Box<dyn Fn(&str) -> Option<f64> + 'a>;
            let mut curves: Vec<(String, Value)> = vec![
                (
                    "factor of K alone".into(),
                    Box::new(|s: &str| time_of(rows, s, "factor")),
                ),
                (
                    "setup (factor + condensation)".into(),
                    Box::new(|s: &str| time_of(rows, s, "setup")),
                ),
                (
                    "setup matrix-free".into(),
                    Box::new(|s: &str| time_of(rows, s, "setup_free")),
                ),
                (
                    "condensation by solves".into(),
                    Box::new(|s: &str| time_of(rows, s, "condense_solves")),
                ),
                (
                    "best total to 1e-10".into(),
                    Box::new(|s: &str| best_total(rows, s, fr, 1e-10)),
                ),
                (
                    "best warm step".into(),
                    Box::new(|s: &str| best_warm(rows, s, fr).map(|x| x.1)),
                ),
            ];
            for m in &ms {
                curves.push((
                    format!("{m}: solve to 1e-10"),
                    Box::new(move |s: &str| best_to(rows, s, fr, m, 1e-10).and_then(|r| r.time_s)),
                ));
            }
            let data: Vec<(String, Vec<(f64, f64)>)> = curves
                .iter()
                .map(|(l, f)| {
                    let p = series(rows, dim, f)
                        .into_iter()
                        .map(|(n, t, _)| (n, t))
                        .collect();
                    (l.clone(), p)
                })
                .collect();
            let (xlo, xhi) = log_range(data.iter().flat_map(|d| d.1.iter().map(|p| p.0)));
            let (ylo, yhi) = log_range(data.iter().flat_map(|d| d.1.iter().map(|p| p.1)));
            let mut chart = ChartBuilder::on(area)
                .caption(format!("{dim}D, {fr}"), ("sans-serif", 17))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d((xlo..xhi).log_scale(), (ylo..yhi).log_scale())?;
            chart
                .configure_mesh()
                .x_desc("n (DOFs)")
                .y_desc("time [s]")
                .x_label_formatter(&sci)
                .y_label_formatter(&sci)
                .draw()?;
            for (i, (label, p)) in data.iter().enumerate() {
                if p.is_empty() {
                    continue;
                }
                let c = if i == 0 { BLACK } else { color(i - 1) };
                let w = if i == 0 { 3 } else { 2 };
                let dashed = label.contains("-free") || label.contains("matrix-free");
                line(&mut chart, p, label, c.stroke_width(w), dashed)?;
                chart.draw_series(p.iter().map(|&q| Circle::new(q, 3, c.filled())))?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 12))
                .draw()?;
        }
    }
    root.present()?;
    Ok(())
}
