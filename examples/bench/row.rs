//! One measurement: a row of bench_results/results.csv.

use std::fmt::Write as _;

/// The CSV header, in the order of [`Row::to_csv`].
pub const HEADER: &str = "scene,dim,n,m,c,friction,kind,method,tol,reps,time_s,time_min_s,\
err,eq_res,outer,inner,status,open,stick,slip,mem_mb,note";

/// One measurement. Empty fields are written as empty CSV cells.
///
/// `kind` is one of: `assembly`, `factor` (sparse Cholesky of K alone, plain AMD,
/// symbolic + numeric wall time), `factor_numeric` (its numeric part),
/// `solve1` (one forward and back solve with that factor), `setup`
/// (`ContactProblem::from_csc` wall time: factor with the contact DOFs last +
/// condensation), `setup_factor` (its numeric factorisation), `condense_trailing`,
/// `condense_solves` (status `measured` or `extrapolated`), `solve` (one method at
/// one tolerance), `step_cold` / `step_warm` (history mode), `clarabel`, `mem`
/// (peak resident memory of a stage, in `mem_mb`; `method` names the stage).
#[derive(Clone, Debug, Default)]
pub struct Row {
    pub scene: String,
    pub dim: usize,
    pub n: usize,
    pub m: usize,
    pub c: usize,
    pub friction: String,
    pub kind: String,
    pub method: String,
    pub tol: Option<f64>,
    pub reps: Option<usize>,
    pub time_s: Option<f64>,
    pub time_min_s: Option<f64>,
    pub err: Option<f64>,
    pub eq_res: Option<f64>,
    pub outer: Option<usize>,
    pub inner: Option<usize>,
    pub status: String,
    pub open: Option<usize>,
    pub stick: Option<usize>,
    pub slip: Option<usize>,
    pub mem_mb: Option<f64>,
    pub note: String,
}

fn opt<T: std::fmt::Display>(x: &Option<T>) -> String {
    x.as_ref().map(|v| v.to_string()).unwrap_or_default()
}

fn optf(x: &Option<f64>) -> String {
    x.map(|v| format!("{v:.6e}")).unwrap_or_default()
}

fn clean(s: &str) -> String {
    s.replace([',', '\n', '\r'], ";")
}

impl Row {
    pub fn to_csv(&self) -> String {
        let mut s = String::new();
        let _ = write!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            clean(&self.scene),
            self.dim,
            self.n,
            self.m,
            self.c,
            clean(&self.friction),
            clean(&self.kind),
            clean(&self.method),
            optf(&self.tol),
            opt(&self.reps),
            optf(&self.time_s),
            optf(&self.time_min_s),
            optf(&self.err),
            optf(&self.eq_res),
            opt(&self.outer),
            opt(&self.inner),
            clean(&self.status),
            opt(&self.open),
            opt(&self.stick),
            opt(&self.slip),
            self.mem_mb.map(|v| format!("{v:.1}")).unwrap_or_default(),
            clean(&self.note),
        );
        s
    }

    pub fn from_csv(line: &str) -> Option<Row> {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 22 {
            return None;
        }
        let u = |s: &str| s.parse::<usize>().ok();
        let x = |s: &str| s.parse::<f64>().ok();
        Some(Row {
            scene: f[0].to_string(),
            dim: f[1].parse().ok()?,
            n: f[2].parse().ok()?,
            m: f[3].parse().ok()?,
            c: f[4].parse().ok()?,
            friction: f[5].to_string(),
            kind: f[6].to_string(),
            method: f[7].to_string(),
            tol: x(f[8]),
            reps: u(f[9]),
            time_s: x(f[10]),
            time_min_s: x(f[11]),
            err: x(f[12]),
            eq_res: x(f[13]),
            outer: u(f[14]),
            inner: u(f[15]),
            status: f[16].to_string(),
            open: u(f[17]),
            stick: u(f[18]),
            slip: u(f[19]),
            mem_mb: x(f[20]),
            note: f[21].to_string(),
        })
    }
}

/// Peak resident memory of this process so far (VmHWM), in MB; None where
/// /proc is not available.
pub fn peak_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// The 1-minute load average of the machine (other processes compete for the
/// cores: the benchmark records it next to its memory readings).
pub fn load1() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(String::from))
        .unwrap_or_default()
}

/// Median of a non-empty list.
pub fn median(v: &[f64]) -> f64 {
    let mut w = v.to_vec();
    w.sort_by(|a, b| a.total_cmp(b));
    let k = w.len();
    if k % 2 == 1 {
        w[k / 2]
    } else {
        0.5 * (w[k / 2 - 1] + w[k / 2])
    }
}
