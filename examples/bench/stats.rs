//! Small statistics and load paths shared by the benchmark and the examples.

/// Median of a non-empty list (the mean of the two middle values for an even
/// length).
pub fn median(v: &[f64]) -> f64 {
    let mut w = v.to_vec();
    w.sort_by(f64::total_cmp);
    let k = w.len();
    if k % 2 == 1 {
        w[k / 2]
    } else {
        0.5 * (w[k / 2 - 1] + w[k / 2])
    }
}

/// The factors (a, b) of the press and shear loads of step k (1-based) of a
/// `steps`-step history: press ramped in the first half, then shear ramped at
/// full press (contacts close, stick, then slip); `proportional`: both ramped
/// together, as a host that scales one load does.
pub fn load_factors(k: usize, steps: usize, proportional: bool) -> (f64, f64) {
    let half = steps / 2;
    if proportional {
        let s = k as f64 / steps as f64;
        (s, s)
    } else if k <= half {
        (k as f64 / half as f64, 0.0)
    } else {
        (1.0, (k - half) as f64 / (steps - half) as f64)
    }
}

/// a press + b shear.
pub fn history_load(press: &[f64], shear: &[f64], (a, b): (f64, f64)) -> Vec<f64> {
    press
        .iter()
        .zip(shear)
        .map(|(p, s)| a * p + b * s)
        .collect()
}
