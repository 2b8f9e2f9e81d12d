//! The baseline of the history benchmarks: the best plain factorisation of K.

use dualsplit::Csc;
use dualsplit::Ordering;
use dualsplit::internals::{Factor, Threads};
use std::sync::Arc;
use std::time::Instant;

/// Seconds of the best plain factorisation of `k` on `threads`: per ordering
/// (AMD, METIS) the median of `reps` runs of analysis and numeric
/// factorisation, the faster ordering's (one run is at the mercy of a noisy
/// host: on the benchmark's 2-core host single runs of the same factorisation
/// varied by 35 %).
pub fn best_plain_factor(k: &Csc, threads: usize, reps: usize) -> f64 {
    let pool = Arc::new(Threads::new(threads));
    [Ordering::Amd, Ordering::Metis]
        .into_iter()
        .map(|ordering| {
            let t: Vec<f64> = (0..reps.max(1))
                .map(|_| {
                    let t0 = Instant::now();
                    drop(Factor::with_last(k, &[], ordering, pool.clone()).expect("K is SPD"));
                    t0.elapsed().as_secs_f64()
                })
                .collect();
            super::stats::median(&t)
        })
        .fold(f64::INFINITY, f64::min)
}
