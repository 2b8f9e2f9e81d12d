//! The loads a handle has solved for, kept with their solutions, so that a
//! load in their span is solved by combining them (histories).
//!
//! Under proportional loading, and along any straight stretch of a load path
//! (press ramped, then shear ramped at full press), the host's total load f
//! of a step lies in the span of the last two loads solved:
//! f = c_1 f_1 + c_2 f_2 (f_k = 2 f_k-1 - f_k-2 for equal increments, and
//! f_k = (k / (k-1)) f_k-1 for a proportional ramp). The maps a step's
//! right-hand side needs are linear (K^-1, or the forward half L^-1 P of K's
//! factor), so the solution of f is the same combination of the kept
//! solutions: a few passes over n-vectors instead of a solve with the factor,
//! or a call of the host's solve.
//!
//! A combination is taken only where it is as good as a solve:
//! - the fit leaves at most FIT_TOL |f| of f unexplained: the combination then
//!   solves a load within rounding of f, as a backward-stable solve does;
//! - it amplifies rounding at most [`max_amplification`] times: the
//!   amplification sum_j |c_j| |v_j| / |v| (with the norm of what the caller
//!   subtracts, see [`LoadSpan::combine`]) times ROUNDING stays a hundredth
//!   of the solve's tolerance. Measured on the 3d-64x64x6 slab's history
//!   (a combination against a solve of the same load, relative difference
//!   on B's rows): 1e-15 at amplification 3, 1.5e-14 at 53, about
//!   amplification x 3e-16; the factor's own rounding is linear in the load
//!   and cancels, only the triangular solves' rounding adds up.
//!
//! Else the caller solves and keeps the new pair (the older of two kept pairs
//! is dropped). Kept solutions come from solves, never from combinations, so
//! rounding does not build up along a history. The pairs are of one map at a
//! time ([`Map`]): keeping a pair of the other drops them.

use crate::memory::{Claim, Ledger};
use std::sync::Arc;

/// The largest relative residual |f - sum c_j f_j| / |f| of a fit that is
/// used: a few units of rounding (a load the host scales by k / N in floating
/// point fits to about 2e-16).
const FIT_TOL: f64 = 16.0 * f64::EPSILON;

/// The relative rounding of a solve the amplification bound is taken
/// against (see [`max_amplification`]): 64 eps, about 200 times the
/// measured 3e-16 per unit of amplification.
const ROUNDING: f64 = 64.0 * f64::EPSILON;

/// The largest amplification of rounding by a combination for a solve to
/// the relative tolerance `tol`: ROUNDING times it stays tol / 100 (70 for
/// tol = 1e-10, none below tol = 1.4e-12), at most 1e4.
pub(crate) fn max_amplification(tol: f64) -> f64 {
    (0.01 * tol / ROUNDING).min(1e4)
}

/// Pairs kept (the newest last).
const KEPT: usize = 2;

/// The linear map a kept solution is of.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(crate) enum Map {
    /// v = K^-1 f (a matrix-free dual, the dense dual by solves, the host's
    /// solves).
    Solve,
    /// v = L^-1 P f, the forward half of a solve with K's factor (the dense
    /// dual from the factor's trailing block).
    Forward,
}

/// One load and its solution, with the claim of their bytes.
struct Pair {
    f: Vec<f64>,
    v: Vec<f64>,
    _claim: Claim,
}

/// Up to KEPT loads with their solutions under one linear map ([`Map`]; a
/// pair of another map replaces them all). The handle clears it when the
/// map itself changes (K refactored).
#[derive(Default)]
pub(crate) struct LoadSpan {
    kept: Vec<Pair>,
    /// The map of the kept pairs (None before the first).
    map: Option<Map>,
}

fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

fn norm(x: &[f64]) -> f64 {
    dot(x, x).sqrt()
}

/// The least-squares coefficients of `rhs` on the loads of `pairs` (one or
/// two), None where they are (nearly) dependent or zero.
fn least_squares(pairs: &[Pair], rhs: &[f64]) -> Option<Vec<f64>> {
    let newest = &pairs.last()?.f;
    let n2 = dot(newest, newest);
    if n2.is_nan() || n2 <= 0.0 {
        return None;
    }
    if pairs.len() == 1 {
        return Some(vec![dot(rhs, newest) / n2]);
    }
    // span{f1, f2} = span{v, f2} with v = f1 - a f2 orthogonal to f2.
    let older = &pairs[0].f;
    let a = dot(older, newest) / n2;
    let v: Vec<f64> = older.iter().zip(newest).map(|(x, y)| x - a * y).collect();
    let nv2 = dot(&v, &v);
    if nv2.is_nan() || nv2 <= 1e-16 * dot(older, older) {
        return None;
    }
    let beta = dot(rhs, &v) / nv2;
    let gamma = dot(rhs, newest) / n2;
    Some(vec![beta, gamma - beta * a])
}

impl LoadSpan {
    /// Forgets every kept pair (the map changed: K refactored).
    pub fn clear(&mut self) {
        self.kept.clear();
        self.map = None;
    }

    /// Keeps f with its solution v (both n) under `map`, dropping the oldest
    /// pair when KEPT are held (all of them when they are of another map);
    /// `ledger` counts their bytes.
    pub fn keep(&mut self, map: Map, f: &[f64], v: Vec<f64>, ledger: &Arc<Ledger>) {
        if self.map != Some(map) {
            self.kept.clear();
            self.map = Some(map);
        }
        if self.kept.len() == KEPT {
            self.kept.remove(0);
        }
        let _claim = ledger.claim_f64(f.len() + v.len());
        self.kept.push(Pair {
            f: f.to_vec(),
            v,
            _claim,
        });
    }

    /// The coefficients (one per kept pair, oldest first) of the best fit of
    /// f by the kept loads, when it leaves at most FIT_TOL |f|: the newest
    /// load alone first, then the last two. Each fit is refined once by the
    /// fit of its residual (dot products over n values carry errors of order
    /// sqrt(n) eps: about 1e-13 at n = 76,050 without the refinement).
    fn fit(&self, f: &[f64]) -> Option<Vec<f64>> {
        let nf = norm(f);
        if nf.is_nan() || nf <= 0.0 || self.kept.is_empty() {
            return None;
        }
        for terms in 1..=self.kept.len().min(2) {
            let pairs = &self.kept[self.kept.len() - terms..];
            let residual = |c: &[f64]| -> Vec<f64> {
                let mut r = f.to_vec();
                for (p, &cj) in pairs.iter().zip(c) {
                    r.iter_mut().zip(&p.f).for_each(|(x, y)| *x -= cj * y);
                }
                r
            };
            let Some(mut c) = least_squares(pairs, f) else {
                continue;
            };
            if let Some(dc) = least_squares(pairs, &residual(&c)) {
                c.iter_mut().zip(dc).for_each(|(x, y)| *x += y);
            }
            if norm(&residual(&c)) <= FIT_TOL * nf {
                let mut all = vec![0.0; self.kept.len() - terms];
                all.extend(c);
                return Some(all);
            }
        }
        None
    }

    /// out := sum_j c_j v_j - `minus` (minus: n, or None for zero) for the fit
    /// of f by the kept loads of `map`, when the fit passes and the amplification
    /// (see the module docs, |minus| counting as a kept solution's size) is
    /// at most `max_amp`; false otherwise (then `out` holds nothing useful
    /// and the caller solves).
    pub fn combine(
        &self,
        map: Map,
        f: &[f64],
        minus: Option<&[f64]>,
        out: &mut [f64],
        max_amp: f64,
    ) -> bool {
        if self.map != Some(map) {
            return false;
        }
        let Some(c) = self.fit(f) else {
            return false;
        };
        out.iter_mut().for_each(|x| *x = 0.0);
        let mut size = 0.0;
        for (p, &cj) in self.kept.iter().zip(&c) {
            if cj != 0.0 {
                for (o, &vi) in out.iter_mut().zip(&p.v) {
                    *o += cj * vi;
                }
                size += cj.abs() * norm(&p.v);
            }
        }
        if let Some(m) = minus {
            for (o, &mi) in out.iter_mut().zip(m) {
                *o -= mi;
            }
            size += norm(m);
        }
        let got = norm(out);
        got.is_finite() && size <= max_amp * got
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound of a solve to 1e-10.
    const AMP: f64 = 70.0;

    #[test]
    fn the_bound_follows_the_tolerance() {
        assert!((max_amplification(1e-10) - AMP).abs() < 1.0);
        assert!(max_amplification(1e-13) < 1.0);
        assert_eq!(max_amplification(1e-3), 1e4);
    }

    fn ledger() -> Arc<Ledger> {
        Ledger::new()
    }

    /// A linear map to keep solutions of: v = M f with a fixed 3 x 3 M.
    fn map(f: &[f64]) -> Vec<f64> {
        vec![
            2.0 * f[0] + f[1],
            f[0] - 3.0 * f[1] + 0.5 * f[2],
            4.0 * f[2] - f[0],
        ]
    }

    #[test]
    fn nothing_kept_fits_nothing() {
        let span = LoadSpan::default();
        let mut out = vec![0.0; 3];
        assert!(!span.combine(Map::Solve, &[1.0, 2.0, 3.0], None, &mut out, AMP));
    }

    #[test]
    fn a_proportional_load_is_the_scaled_solution() {
        let l = ledger();
        let mut span = LoadSpan::default();
        let f1 = [1.0, -2.0, 0.5];
        span.keep(Map::Solve, &f1, map(&f1), &l);
        let f = [3.0, -6.0, 1.5];
        let mut out = vec![0.0; 3];
        assert!(span.combine(Map::Solve, &f, None, &mut out, AMP));
        for (o, w) in out.iter().zip(map(&f)) {
            assert!((o - w).abs() <= 1e-14 * w.abs().max(1.0), "{out:?}");
        }
        assert_eq!(l.live(), 6 * std::mem::size_of::<f64>());
    }

    #[test]
    fn an_affine_ramp_combines_the_last_two() {
        let l = ledger();
        let mut span = LoadSpan::default();
        let (p, s) = ([1.0, 0.0, -1.0], [0.0, 0.3, 0.2]);
        let at = |j: f64| [p[0] + j * s[0], p[1] + j * s[1], p[2] + j * s[2]];
        span.keep(Map::Solve, &at(1.0), map(&at(1.0)), &l);
        span.keep(Map::Solve, &at(2.0), map(&at(2.0)), &l);
        let f = at(3.0);
        let mut out = vec![0.0; 3];
        assert!(span.combine(Map::Solve, &f, None, &mut out, AMP));
        for (o, w) in out.iter().zip(map(&f)) {
            assert!((o - w).abs() <= 1e-13 * w.abs().max(1.0), "{out:?}");
        }
        // With a part subtracted: out = M f - x.
        let x = [0.1, 0.2, 0.3];
        assert!(span.combine(Map::Solve, &f, Some(&x), &mut out, AMP));
        for ((o, w), xi) in out.iter().zip(map(&f)).zip(x) {
            assert!((o - (w - xi)).abs() <= 1e-13 * w.abs().max(1.0));
        }
    }

    #[test]
    fn a_load_off_the_span_is_refused() {
        let l = ledger();
        let mut span = LoadSpan::default();
        span.keep(Map::Solve, &[1.0, 0.0, 0.0], map(&[1.0, 0.0, 0.0]), &l);
        span.keep(Map::Solve, &[0.0, 1.0, 0.0], map(&[0.0, 1.0, 0.0]), &l);
        let mut out = vec![0.0; 3];
        assert!(!span.combine(Map::Solve, &[1.0, 1.0, 1e-12], None, &mut out, AMP));
        // Three pairs kept: the oldest went, and its direction with it.
        span.keep(Map::Solve, &[0.0, 0.0, 1.0], map(&[0.0, 0.0, 1.0]), &l);
        assert!(!span.combine(Map::Solve, &[1.0, 0.0, 0.0], None, &mut out, AMP));
        assert!(span.combine(Map::Solve, &[0.0, 2.0, 1.0], None, &mut out, AMP));
        assert_eq!(l.live(), 12 * std::mem::size_of::<f64>());
        // A pair of the other map drops the pairs of this one.
        span.keep(Map::Forward, &[1.0, 0.0, 0.0], map(&[1.0, 0.0, 0.0]), &l);
        assert!(!span.combine(Map::Solve, &[2.0, 0.0, 0.0], None, &mut out, AMP));
        assert!(span.combine(Map::Forward, &[2.0, 0.0, 0.0], None, &mut out, AMP));
        assert_eq!(l.live(), 6 * std::mem::size_of::<f64>());
        span.clear();
        assert_eq!(l.live(), 0);
    }

    #[test]
    fn a_cancelling_combination_is_refused() {
        let l = ledger();
        let mut span = LoadSpan::default();
        let f1 = [1.0, 1.0, 1.0];
        span.keep(Map::Solve, &f1, map(&f1), &l);
        let mut out = vec![0.0; 3];
        // M f - x nearly cancels: the combination would lose the digits a
        // solve keeps.
        let x: Vec<f64> = map(&f1).iter().map(|v| v * (1.0 - 1e-3)).collect();
        assert!(!span.combine(Map::Solve, &f1, Some(&x), &mut out, AMP));
        let y: Vec<f64> = map(&f1).iter().map(|v| 0.5 * v).collect();
        assert!(span.combine(Map::Solve, &f1, Some(&y), &mut out, AMP));
    }
}
