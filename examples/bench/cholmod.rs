//! CHOLMOD's own factorisation of a K, for the benchmarks' second baseline column:
//! `examples/cholmod_factor.c` built once with `cc` against SuiteSparse
//! (`libsuitesparse-dev`) and run on K written as Matrix Market.

use std::path::{Path, PathBuf};
use std::process::Command;

/// One CHOLMOD measurement: medians over the repetitions.
pub struct Cholmod {
    /// The ordering CHOLMOD ran (amd, metis, nesdis, ...).
    pub ordering: String,
    /// Analysis + numeric factorisation, seconds (median).
    pub seconds: f64,
    /// The runs of `seconds`.
    pub walls: Vec<f64>,
    /// `cholmod_analyze` alone, seconds (median).
    pub analyse: f64,
    /// `cholmod_factorize` alone, seconds (median).
    pub numeric: f64,
    /// nnz(L) and flops as CHOLMOD counts them.
    pub nnz: f64,
    pub flops: f64,
}

use super::stats::median;

/// The CHOLMOD shim, compiled once into `target/factor-bench`; the reason as
/// the error where it cannot be built (no SuiteSparse, no C compiler).
pub fn shim() -> Result<PathBuf, String> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/factor-bench");
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let exe = dir.join("cholmod_factor");
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/cholmod_factor.c");
    let fresh = |exe: &Path| {
        let (Ok(a), Ok(b)) = (exe.metadata(), src.metadata()) else {
            return false;
        };
        matches!((a.modified(), b.modified()), (Ok(x), Ok(y)) if x >= y)
    };
    if fresh(&exe) {
        return Ok(exe);
    }
    let out = Command::new(std::env::var("CC").unwrap_or_else(|_| "cc".into()))
        .args(["-O2", "-I/usr/include/suitesparse", "-o"])
        .arg(&exe)
        .arg(&src)
        .args(["-lcholmod", "-lsuitesparseconfig", "-lm"])
        .output()
        .map_err(|e| format!("cc: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "cc could not build the CHOLMOD shim (libsuitesparse-dev installed?): {}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(exe)
}

/// `reps` CHOLMOD factorisations of the K in `mtx` with `threads` BLAS threads
/// (OPENBLAS_NUM_THREADS, OMP_NUM_THREADS); its default ordering policy, or
/// METIS alone.
pub fn run(
    exe: &Path,
    mtx: &Path,
    reps: usize,
    threads: usize,
    metis: bool,
) -> Result<Cholmod, String> {
    let mut cmd = Command::new(exe);
    cmd.arg(mtx).arg(reps.to_string());
    if metis {
        cmd.arg("metis");
    }
    let out = cmd
        .env("OPENBLAS_NUM_THREADS", threads.to_string())
        .env("OMP_NUM_THREADS", threads.to_string())
        .output()
        .map_err(|e| format!("run the CHOLMOD shim: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "CHOLMOD shim: {}",
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let (mut walls, mut analyse, mut numeric) = (Vec::new(), Vec::new(), Vec::new());
    let (mut nnz, mut flops, mut ordering) = (0.0, 0.0, String::new());
    for line in text.lines() {
        let v: Vec<&str> = line.split_whitespace().collect();
        let num = |i: usize| -> Result<f64, String> {
            v.get(i)
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| format!("CHOLMOD shim: bad line {line:?}"))
        };
        let (a, f) = (num(0)?, num(1)?);
        walls.push(a + f);
        analyse.push(a);
        numeric.push(f);
        (nnz, flops) = (num(2)?, num(3)?);
        ordering = v.get(4).unwrap_or(&"?").to_string();
    }
    if walls.is_empty() {
        return Err("CHOLMOD shim printed nothing".into());
    }
    Ok(Cholmod {
        ordering,
        seconds: median(&walls),
        walls,
        analyse: median(&analyse),
        numeric: median(&numeric),
        nnz,
        flops,
    })
}
