//! One measurement: a row of bench_results/results.csv.

use std::fmt::Write as _;

/// The CSV header, in the order of [`Row::to_csv`].
pub const HEADER: &str = "scene,dim,n,m,c,friction,kind,method,tol,reps,time_s,time_min_s,\
err,eq_res,outer,inner,status,open,stick,slip,mem_mb,note";

/// One measurement. Empty fields are written as empty CSV cells.
///
/// `kind` is one of: `assembly`, `factor` (the best plain sparse Cholesky of K
/// alone, `Ordering::Auto`, ordering + symbolic + numeric wall time; the note
/// names the ordering, nnz(L), flops and threads), `factor_numeric` (its numeric
/// part), `cholmod` / `cholmod_numeric` (CHOLMOD's analyse + factorize of the same
/// K and its numeric part; the note as for `factor`),
/// `solve1` (one forward and back solve with that factor), `setup`
/// (`ContactProblem::from_csc` wall time: factor with the contact DOFs last + dense
/// condensation; where Auto made it matrix-free, from_csc + the dense assembly, and
/// `setup_auto` is from_csc alone), `setup_factor` (its numeric factorisation),
/// `condense_trailing` (the dense condensation from the trailing block),
/// `condense_solves` (status `measured` or `extrapolated`), `setup_free` (the setup
/// in matrix-free form), `condense_free` (its matrix-free build: L_CC, B_C^T and
/// A's diagonal), `setup_free_factor` (its numeric factorisation), `solve` (one
/// method at one tolerance; `mprgp-free` = MPRGP matrix-free), `step_cold` /
/// `step_warm` (history mode), `clarabel`, `mem` (peak resident memory of a stage
/// of a child, in `mem_mb`; `method` names the stage: `assembly`, `factor`,
/// `setup`, `ours` in the dense child, `free-assembly`, `free-setup`, `free` in the
/// matrix-free child, `clarabel`; the peak is reset before `setup`, `ours` and
/// `free-setup`, and `setup-start` / `free-setup-start` hold the resident memory
/// at the reset before the setup: the floor of the reading that follows).
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
    /// This row with the outcome of a solve: err, equilibrium residual,
    /// iterations, status and contact states.
    pub fn with_report(self, r: &dualsplit::Report) -> Row {
        Row {
            err: Some(r.err),
            eq_res: Some(r.equilibrium_residual),
            outer: Some(r.outer_iterations),
            inner: Some(r.inner_iterations),
            status: format!("{:?}", r.status),
            open: Some(r.n_open),
            stick: Some(r.n_stick),
            slip: Some(r.n_slip),
            ..self
        }
    }

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

/// The child process (part of a scene's measurement) that writes a row.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Part {
    /// `ours`: the factorisation of K, the dense setup, the methods on the dense A.
    Dense,
    /// `ours-free`: the matrix-free setup and MPRGP matrix-free.
    Free,
    /// `clarabel`.
    Clarabel,
}

impl Part {
    /// The name of the child (`--child NAME`, `--only NAME`).
    pub fn name(self) -> &'static str {
        match self {
            Part::Dense => "ours",
            Part::Free => "ours-free",
            Part::Clarabel => "clarabel",
        }
    }
}

/// Kinds written by the matrix-free child only.
pub const FREE_KINDS: [&str; 3] = ["setup_free", "condense_free", "setup_free_factor"];

impl Row {
    /// The part that wrote this row.
    pub fn part(&self) -> Part {
        if self.kind == "clarabel" || (self.kind == "mem" && self.method == "clarabel") {
            Part::Clarabel
        } else if FREE_KINDS.contains(&self.kind.as_str())
            || self.method.ends_with("-free")
            || (self.kind == "mem" && self.method.starts_with("free"))
        {
            Part::Free
        } else {
            Part::Dense
        }
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

/// Resident memory of this process now (VmRSS), in MB.
pub fn rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Resets the peak resident memory of this process (VmHWM) to the current resident
/// size (Linux: `5` into /proc/self/clear_refs), so that the next [`peak_mb`]
/// reads the peak of what runs in between. Returns false where that is refused.
pub fn reset_peak() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// The 1-minute load average of the machine (other processes compete for the
/// cores: the benchmark records it next to its memory readings).
pub fn load1() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(String::from))
        .unwrap_or_default()
}
