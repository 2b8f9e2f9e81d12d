//! The history of a quasistatic simulation (docs/design.md section 1): the
//! accumulated displacement u_k, the last converged multipliers, and what the
//! predictor of the next step's multipliers needs.
//!
//! The predictor. A step's dual is that of the increment, but its multipliers
//! are total forces, and its right-hand side is b = l - [0; T u_k] with the
//! contact-space load l = B K^-1 f_total - [g0; 0]: l is affine in the host's
//! load. On a fixed contact state (the same contacts closed, sticking and
//! slipping in the same directions) the multipliers are affine in l too, so
//! under proportional loading they move along a straight line from step to
//! step, and the last two steps predict the next one far better than the last
//! one alone:
//!
//! ```text
//! s      = <l_k+1 - l_k, l_k - l_k-1> / |l_k - l_k-1|^2   (clamped to [0, S_MAX])
//! lam_0  = P(lam_k + s (lam_k - lam_k-1))
//! ```
//!
//! s is the least-squares fit of this step's load change to the last one's:
//! 1 for equal proportional increments, 0 where the load turns at right angles
//! (press, then shear: the plain warm start), and never negative (an unloading
//! step is not the last path backwards: friction sticks on reversal). The line
//! is used only where it carries at least CARRIED_MIN of the load change's
//! squared norm (s^2 |l_k - l_k-1|^2 against |l_k+1 - l_k|^2), else the plain
//! warm start: where the load turns from press to shear, s is a rounding
//! error (1e-15), and such a start, taken for a prediction, had Newton sort
//! it by the natural map, where the whole shear increment made every sticking
//! contact look slipping (measured on the 3d-32x32x4 slab's Coulomb
//! press-shear path: that step took 14 Newton steps; 2-9 % of the histories'
//! products). P is the
//! projection onto lambda_N >= 0, |lambda_T,i| <= p_i (mu_i lambda_N,i). Where
//! the contact state changes the prediction is still nearer than lam_k on the
//! contacts that keep theirs; Newton sorts such a start by the natural map at
//! it (a plain warm start by its multipliers).
//!
//! The gradient at the start. A converged step without a compliance keeps
//! A lambda_k (b - v on its recovered u): A x at the line's point x is the
//! same combination of the last two, and only what the projection moved
//! takes a product (solve.rs), none on a plain warm start. Forgotten with
//! the loads.

use crate::friction::{Friction, project_disk};

/// The largest extrapolation factor: a step more than S_MAX times the last
/// one's load change is predicted as S_MAX of it (the line is not trusted that
/// far out).
const S_MAX: f64 = 4.0;

/// The least share of this step's load change (squared norm) that the line
/// must carry to be used (CARRIED_MIN; else the plain warm start).
const CARRIED_MIN: f64 = 0.5;

/// The most a host increment's prediction may raise the natural residual
/// over lambda_n's and still be used (see [`Increments`]).
pub(crate) const INCREMENT_RISE: f64 = 4.0;

/// u_k and the last converged multipliers, with the contact-space loads of
/// the last two steps.
pub(crate) struct History {
    /// u_k, the accumulated displacement (n).
    pub u: Vec<f64>,
    /// lambda_k = [lambda_N; lambda_T] of the last converged step (c; zero
    /// before the first).
    pub lam: Vec<f64>,
    /// l_k, the contact-space load of the last converged step (c), when there
    /// was one since the history, K, N or T were last changed.
    load: Option<Vec<f64>>,
    /// lambda_k-1 and l_k - l_k-1, when the two last steps both converged on
    /// the same K, N and T.
    prev: Option<(Vec<f64>, Vec<f64>)>,
    /// A lambda_k (c), where the step that ended with it measured it
    /// (`advance`: b - v of the recovered u, exact to the rounding b
    /// carries: a solve's, or `load_span`'s bound where b was combined from
    /// kept loads) without a compliance, on the same K, N and T: the next
    /// step's gradient at its start then needs no product where the
    /// prediction's projection moved nothing ([`History::start_product`]).
    alam: Option<Vec<f64>>,
    /// A lambda_k-1 (c), as `alam`, paired with `prev`'s lambda_k-1.
    alam_prev: Option<Vec<f64>>,
    /// The tangential force the next step's return mapping starts from
    /// (interface compliance, `compliance.rs`): lambda_T of the last converged
    /// step ((d - 1) m), scaled where k_T changed since (`Compliance::carry`);
    /// empty for zero (before the first step, after a reset or a change of m).
    pub lt: Vec<f64>,
    /// K u_k as the sum of the right-hand sides u_k was solved from (n):
    /// f_total minus B^T lambda_k of the last converged step, kept by a
    /// problem on the host's solves without K; zero otherwise.
    pub ku: Vec<f64>,
    /// L^T P u_k, the forward half of K u_k (L^-1 P K = L^T P) under K's
    /// factor, summed from the forward halves u_k was back-substituted from
    /// by the steps on the dense dual from the factor's trailing block: with
    /// it a step's forward half L^-1 P (f_total - K u_k) needs no forward
    /// substitution where f_total lies in the span of the last loads
    /// (`load_span`). Empty for zero (u_k = 0); None where a step took
    /// another route or K was refactored since u_k was zero.
    pub lu: Option<Vec<f64>>,
}

impl History {
    /// The start of a history: u = 0, lambda = 0, nothing to predict from.
    pub fn new(n: usize, c: usize) -> History {
        History {
            u: vec![0.0; n],
            lam: vec![0.0; c],
            load: None,
            prev: None,
            alam: None,
            alam_prev: None,
            lt: Vec::new(),
            ku: vec![0.0; n],
            lu: Some(Vec::new()),
        }
    }

    /// Forgets everything: u = 0, lambda = 0.
    pub fn reset(&mut self) {
        self.u.iter_mut().for_each(|v| *v = 0.0);
        self.lam.iter_mut().for_each(|v| *v = 0.0);
        self.lt.clear();
        self.ku.iter_mut().for_each(|v| *v = 0.0);
        self.lu = Some(Vec::new());
        self.forget_loads();
    }

    /// Forgets the loads and the kept A lambda (K, N, T or the compliance
    /// changed: the last loads are not those of the new operator); u_k and
    /// lambda_k stay as the warm start.
    pub fn forget_loads(&mut self) {
        self.load = None;
        self.prev = None;
        self.alam = None;
        self.alam_prev = None;
    }

    /// New contacts with c unknowns: lambda is kept when c is unchanged
    /// (zero otherwise), the loads are forgotten.
    pub fn new_contacts(&mut self, c: usize) {
        if self.lam.len() != c {
            self.lam = vec![0.0; c];
            self.lt.clear();
        }
        self.forget_loads();
    }

    /// The contact-space load l = b + [0; T u_k] of a step whose right-hand
    /// side is `b` (c), given `bu` = B u_k = [N u_k; T u_k] (c) and m.
    pub fn load_of(b: &[f64], bu: &[f64], m: usize) -> Vec<f64> {
        let mut l = b.to_vec();
        for (x, y) in l[m..].iter_mut().zip(&bu[m..]) {
            *x += y;
        }
        l
    }

    /// The extrapolation factor s of the module docs for a step with load
    /// `load`; None when there is nothing to extrapolate from.
    pub fn factor_for(&self, load: &[f64]) -> Option<f64> {
        let (last, (_, dl)) = (self.load.as_ref()?, self.prev.as_ref()?);
        line_factor(load.iter().zip(last).map(|(x, y)| x - y), dl)
    }

    /// The warm start of a step with load `load` into `lam` (c): the
    /// prediction of the module docs where two steps are known, else lambda_k.
    /// Returns the extrapolation factor used (0: the plain warm start).
    pub fn start(&self, load: &[f64], law: Friction<'_>, d: usize, lam: &mut [f64]) -> f64 {
        lam.copy_from_slice(&self.lam);
        let (Some(s), Some((prev, _))) = (self.factor_for(load), self.prev.as_ref()) else {
            return 0.0;
        };
        along_line(lam, prev, s);
        project(lam, law, d);
        s
    }

    /// A x for the line's point before its projection, x = lambda_k + s
    /// (lambda_k - lambda_k-1) (s as [`History::start`] returned it; 0: x =
    /// lambda_k), from the products the last steps measured; None where
    /// they are not known.
    pub fn start_product(&self, s: f64) -> Option<Vec<f64>> {
        let alam = self.alam.as_ref()?;
        if s == 0.0 {
            return Some(alam.clone());
        }
        let prev = self.alam_prev.as_ref()?;
        let mut ax = alam.clone();
        along_line(&mut ax, prev, s);
        Some(ax)
    }

    /// A lambda_k where the last step kept it ([`History::advance`]).
    #[cfg(test)]
    pub(crate) fn alam(&self) -> Option<&[f64]> {
        self.alam.as_deref()
    }

    /// x = lambda_k + s (lambda_k - lambda_k-1), the line's point before its
    /// projection (lambda_k where no line is known).
    pub fn line_point(&self, s: f64) -> Vec<f64> {
        let mut x = self.lam.clone();
        if let (Some((prev, _)), true) = (&self.prev, s > 0.0) {
            along_line(&mut x, prev, s);
        }
        x
    }

    /// Records a converged step: its total displacement `u`, multipliers `lam`
    /// and load `load`, the forward half `forward` its displacement was
    /// back-substituted from (None: another route; see the field `lu`), and
    /// A lam where it was measured (`alam`; None: not known).
    pub fn advance(
        &mut self,
        u: &[f64],
        lam: &[f64],
        load: Vec<f64>,
        forward: Option<Vec<f64>>,
        alam: Option<Vec<f64>>,
    ) {
        self.lu = match (self.lu.take(), forward) {
            (Some(lu), Some(y)) if lu.is_empty() => Some(y),
            (Some(mut lu), Some(y)) => {
                lu.iter_mut().zip(&y).for_each(|(a, b)| *a += b);
                Some(lu)
            }
            _ => None,
        };
        self.u.copy_from_slice(u);
        self.prev = self.load.take().map(|last| {
            let dl = load.iter().zip(&last).map(|(x, y)| x - y).collect();
            (std::mem::replace(&mut self.lam, lam.to_vec()), dl)
        });
        // A lambda_k-1 pairs with lambda_k-1 only where a line is kept.
        self.alam_prev = match self.prev {
            Some(_) => std::mem::replace(&mut self.alam, alam),
            None => {
                self.alam = alam;
                None
            }
        };
        self.lam.copy_from_slice(lam);
        self.load = Some(load);
    }
}

/// x := x + s (x - prev): the point at s on the line through prev and x
/// (the predictions of [`History`] and [`Increments`], and A times them).
fn along_line(x: &mut [f64], prev: &[f64], s: f64) {
    for (v, p) in x.iter_mut().zip(prev) {
        *v += s * (*v - p);
    }
}

/// The extrapolation factor s of the module docs for a load change `change`
/// (this step's, component by component) on the line of the last one,
/// `last`: None where the line carries less than CARRIED_MIN of the change,
/// s <= 0, or nothing is finite.
fn line_factor(change: impl Iterator<Item = f64>, last: &[f64]) -> Option<f64> {
    let (mut num, mut den, mut sq) = (0.0, 0.0, 0.0);
    for (x, z) in change.zip(last) {
        num += x * z;
        den += z * z;
        sq += x * x;
    }
    let s = num / den;
    // The share of |l_k+1 - l_k|^2 that the line carries (cos^2 of the
    // angle between the two load changes), as s times num / sq so that no
    // product of squared norms can overflow.
    let carried = s * (num / sq);
    (den > 0.0 && s.is_finite() && s > 0.0 && carried >= CARRIED_MIN).then(|| s.min(S_MAX))
}

/// The predictor of a nonlinear host's increments (`solve_iteration`,
/// docs/design.md section 9): the line of the module docs through the
/// multipliers that ended the last two increments.
///
/// A host iteration's multipliers are total forces, but its K, r and gaps
/// are those of its iterate, so there is no total contact-space load to fit.
/// The first iteration of an increment (no slip taken yet) has instead its
/// load change with the contact forces frozen at lambda_n, those that ended
/// the last increment: q = B K^-1 (r - B^T lambda_n) = b + [g; 0] - A lambda_n
/// (one product), the response of the contact rows to the out-of-balance
/// force the increment's load made. q of two successive increments take the
/// place of l_k+1 - l_k and l_k - l_k-1 in s, and the start is
/// P(lambda_n + s (lambda_n - lambda_n-1)).
///
/// The line is not trusted where its start's natural residual |F| exceeds
/// lambda_n's more than INCREMENT_RISE times (`ContactProblem::solve_iteration`
/// measures both: one product more). The first iteration's |F| at lambda_n
/// is large (the whole load change is in it), and a good prediction can
/// raise it 2-4 times (its contact states not yet sorted); one that raises
/// it 16-25 times (an increment where most sticking contacts start to slip)
/// took more Newton steps than lambda_n, and a host that repeats an
/// iteration from its own answer (|F| near zero there) must not be moved
/// off it.
#[derive(Default)]
pub(crate) struct Increments {
    /// lambda_n-1 (the multipliers the first iteration of the last
    /// increment started from) and that iteration's q, once it converged;
    /// None before, after the contacts, the compliance or the history
    /// changed, and after a first iteration that recorded nothing.
    last: Option<(Vec<f64>, Vec<f64>)>,
}

impl Increments {
    /// Forgets the last increment (a reset, new contacts or compliance, a
    /// first iteration that recorded nothing).
    pub fn forget(&mut self) {
        self.last = None;
    }

    /// The start of an increment's first iteration with load change `q` (c)
    /// from lambda_n in `lam` (c): the prediction of the type docs where the
    /// last increment is known and its line carries q, else lambda_n
    /// unchanged. Returns the extrapolation factor used (0: none).
    pub fn start(&self, q: &[f64], law: Friction<'_>, d: usize, lam: &mut [f64]) -> f64 {
        let Some((prev, last_q)) = self.last.as_ref() else {
            return 0.0;
        };
        if prev.len() != lam.len() || last_q.len() != q.len() {
            return 0.0;
        }
        let Some(s) = line_factor(q.iter().copied(), last_q) else {
            return 0.0;
        };
        along_line(lam, prev, s);
        project(lam, law, d);
        s
    }

    /// Records a converged first iteration of an increment: the multipliers
    /// it started from (lambda_n, before any prediction) and its load
    /// change q.
    pub fn advance(&mut self, start: Vec<f64>, q: Vec<f64>) {
        self.last = Some((start, q));
    }
}

/// Projects [lambda_N; lambda_T] onto lambda_N >= 0, |lambda_T,i| <= the
/// friction bound of contact i (of the projected lambda_N), for the
/// predictors outside this module (a host iteration's line).
pub(crate) fn project_point(lam: &mut [f64], law: Friction<'_>, d: usize) {
    project(lam, law, d)
}

/// Projects [lambda_N; lambda_T] onto lambda_N >= 0, |lambda_T,i| <= the
/// friction bound of contact i (of the projected lambda_N).
fn project(lam: &mut [f64], law: Friction<'_>, d: usize) {
    let m = lam.len() / d;
    let (ln, lt) = lam.split_at_mut(m);
    for i in 0..m {
        ln[i] = ln[i].max(0.0);
        let r = law.bound(i, ln[i]);
        project_disk(&mut lt[(d - 1) * i..(d - 1) * (i + 1)], r);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two contacts in 2D (c = 4), Tresca bound 1.
    fn history() -> History {
        History::new(3, 4)
    }

    fn assert_close(got: &[f64], want: &[f64]) {
        let d = got
            .iter()
            .zip(want)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(d <= 1e-15, "{got:?} against {want:?}");
    }

    #[test]
    fn two_proportional_steps_predict_the_third_on_the_line() {
        let p = [1.0, 1.0];
        let law = Friction::Tresca(&p);
        let mut h = history();
        let mut lam = vec![0.0; 4];
        // Nothing to predict from before two steps: the plain warm start.
        let l1 = vec![1.0, 0.0, 0.5, 0.0];
        assert_eq!(h.start(&l1, law, 2, &mut lam), 0.0);
        h.advance(&[0.0; 3], &[1.0, 0.0, 0.2, 0.0], l1.clone(), None, None);
        let l2 = vec![2.0, 0.0, 1.0, 0.0];
        assert_eq!(h.start(&l2, law, 2, &mut lam), 0.0);
        assert_eq!(lam, [1.0, 0.0, 0.2, 0.0]);
        h.advance(&[0.0; 3], &[2.0, 0.0, 0.4, 0.0], l2.clone(), None, None);
        // A third equal increment: s = 1, the line continued.
        let l3 = vec![3.0, 0.0, 1.5, 0.0];
        assert_eq!(h.start(&l3, law, 2, &mut lam), 1.0);
        assert_close(&lam, &[3.0, 0.0, 0.6, 0.0]);
        // Half an increment: s = 0.5.
        let l3h = vec![2.5, 0.0, 1.25, 0.0];
        assert_eq!(h.start(&l3h, law, 2, &mut lam), 0.5);
        assert_close(&lam, &[2.5, 0.0, 0.5, 0.0]);
    }

    /// A x at the line's point x = lambda_k + s (lambda_k - lambda_k-1),
    /// from the A lambda the steps measured, equals A times that point (a
    /// 4 x 4 A); it is lambda_k's own at s = 0, unknown where a step did not
    /// measure it, and forgotten with the loads.
    #[test]
    fn the_start_product_is_a_times_the_line_point() {
        let a = [
            [4.0, 1.0, 0.5, 0.0],
            [1.0, 3.0, 0.0, 0.25],
            [0.5, 0.0, 2.0, 1.0],
            [0.0, 0.25, 1.0, 5.0],
        ];
        let times = |x: &[f64]| -> Vec<f64> {
            a.iter()
                .map(|row| row.iter().zip(x).map(|(r, v)| r * v).sum())
                .collect()
        };
        // Products agree to a few roundings of their largest entry (13.3).
        let assert_near = |got: &[f64], want: &[f64]| {
            let d = got
                .iter()
                .zip(want)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            assert!(d <= 1e-14, "{got:?} against {want:?}");
        };
        let p = [1.0, 1.0];
        let law = Friction::Tresca(&p);
        let mut h = history();
        let mut lam = vec![0.0; 4];
        let (lam1, lam2) = ([1.0, 0.0, 0.2, 0.0], [2.0, 0.5, 0.4, -0.1]);
        h.advance(
            &[0.0; 3],
            &lam1,
            vec![1.0, 0.0, 0.5, 0.0],
            None,
            Some(times(&lam1)),
        );
        assert_near(&h.start_product(0.0).unwrap(), &times(&lam1));
        assert!(h.start_product(1.0).is_none(), "no line yet");
        h.advance(
            &[0.0; 3],
            &lam2,
            vec![2.0, 0.0, 1.0, 0.0],
            None,
            Some(times(&lam2)),
        );
        let s = h.start(&[3.0, 0.0, 1.5, 0.0], law, 2, &mut lam);
        assert_eq!(s, 1.0);
        let x = h.line_point(s);
        assert_close(&x, &[3.0, 1.0, 0.6, -0.2]);
        assert_near(&h.start_product(s).unwrap(), &times(&x));
        assert_close(&h.line_point(0.0), &lam2);
        // A step that did not measure A lambda: nothing known after it.
        h.advance(&[0.0; 3], &lam1, vec![3.0, 0.0, 1.5, 0.0], None, None);
        assert!(h.start_product(0.0).is_none() && h.start_product(1.0).is_none());
        h.advance(
            &[0.0; 3],
            &lam2,
            vec![4.0, 0.0, 2.0, 0.0],
            None,
            Some(times(&lam2)),
        );
        assert!(h.start_product(0.0).is_some() && h.start_product(1.0).is_none());
        h.forget_loads();
        assert!(h.start_product(0.0).is_none());
    }

    #[test]
    fn a_line_that_carries_little_of_the_load_change_is_not_used() {
        let p = [1.0, 1.0];
        let law = Friction::Tresca(&p);
        let mut h = history();
        let mut lam = vec![0.0; 4];
        // Two press steps along the first component of l.
        h.advance(
            &[0.0; 3],
            &[1.0, 0.0, 0.2, 0.0],
            vec![1.0, 0.0, 0.0, 0.0],
            None,
            None,
        );
        h.advance(
            &[0.0; 3],
            &[2.0, 0.0, 0.4, 0.0],
            vec![2.0, 0.0, 0.0, 0.0],
            None,
            None,
        );
        // Then shear with a rounding error's worth of press: s = 1e-15 > 0,
        // yet the line carries 1e-30 of the change: the plain warm start.
        let turn = vec![2.0 + 1e-15, 0.0, 1.0, 0.0];
        assert!(h.factor_for(&turn).is_none());
        assert_eq!(h.start(&turn, law, 2, &mut lam), 0.0);
        assert_eq!(lam, [2.0, 0.0, 0.4, 0.0]);
        // At 45 degrees the line carries exactly half (cos^2 = 1/2): used,
        // s = 1 (the press part of the change equals the last change).
        let oblique = vec![3.0, 0.0, 1.0, 0.0];
        assert_eq!(h.start(&oblique, law, 2, &mut lam), 1.0);
        assert_close(&lam, &[3.0, 0.0, 0.6, 0.0]);
        // Beyond 45 degrees (cos^2 = 1/5): not used.
        let steep = vec![3.0, 0.0, 2.0, 0.0];
        assert_eq!(h.start(&steep, law, 2, &mut lam), 0.0);
        assert_eq!(lam, [2.0, 0.0, 0.4, 0.0]);
    }

    #[test]
    fn the_prediction_is_projected_and_clamped() {
        let p = [0.5, 0.5];
        let law = Friction::Tresca(&p);
        let mut h = history();
        let mut lam = vec![0.0; 4];
        h.advance(
            &[0.0; 3],
            &[1.0, 1.0, 0.1, -0.3],
            vec![0.0, 0.0, 1.0, 0.0],
            None,
            None,
        );
        h.advance(
            &[0.0; 3],
            &[0.5, 2.0, 0.3, -0.45],
            vec![0.0, 0.0, 2.0, 0.0],
            None,
            None,
        );
        // s = 1: lambda_N,0 = 0 (cut from -0.5), lambda_T,1 = -0.6 cut to -0.5.
        assert_eq!(h.start(&[0.0, 0.0, 3.0, 0.0], law, 2, &mut lam), 1.0);
        assert_close(&lam, &[0.0, 3.0, 0.5, -0.5]);
        // A load at right angles to the last change: the plain warm start.
        assert_eq!(h.start(&[0.0, 1.0, 2.0, 0.0], law, 2, &mut lam), 0.0);
        assert_eq!(lam, [0.5, 2.0, 0.3, -0.45]);
        // Unloading: no backwards extrapolation.
        assert_eq!(h.start(&[0.0, 0.0, 1.0, 0.0], law, 2, &mut lam), 0.0);
        // Ten increments at once: clamped to S_MAX.
        assert_eq!(h.start(&[0.0, 0.0, 12.0, 0.0], law, 2, &mut lam), S_MAX);
        // Coulomb: the bound of the projected normal force.
        let mu = [1.0, 0.1];
        let law = Friction::Coulomb(&mu);
        h.start(&[0.0, 0.0, 3.0, 0.0], law, 2, &mut lam);
        assert_eq!(lam[..2], [0.0, 3.0]);
        assert_eq!(lam[2], 0.0);
        assert!((lam[3] + 0.3).abs() < 1e-15, "{lam:?}");
    }

    #[test]
    fn new_contacts_and_reset_forget_the_loads() {
        let p = [1.0, 1.0];
        let law = Friction::Tresca(&p);
        let mut h = history();
        let mut lam = vec![0.0; 4];
        h.advance(
            &[1.0; 3],
            &[1.0, 0.0, 0.0, 0.0],
            vec![1.0, 0.0, 0.0, 0.0],
            None,
            None,
        );
        h.advance(
            &[2.0; 3],
            &[2.0, 0.0, 0.0, 0.0],
            vec![2.0, 0.0, 0.0, 0.0],
            None,
            None,
        );
        h.new_contacts(4);
        assert_eq!(h.start(&[3.0, 0.0, 0.0, 0.0], law, 2, &mut lam), 0.0);
        assert_eq!(lam, [2.0, 0.0, 0.0, 0.0], "lambda kept for the same c");
        h.new_contacts(6);
        assert_eq!(h.lam, vec![0.0; 6]);
        h.reset();
        assert_eq!((h.u.clone(), h.load.is_none()), (vec![0.0; 3], true));
    }

    #[test]
    fn the_forward_half_of_k_u_sums_the_steps_and_is_lost_off_the_route() {
        let mut h = History::new(3, 4);
        assert_eq!(h.lu.as_deref(), Some(&[][..]), "zero at the start");
        h.advance(
            &[0.0; 3],
            &[0.0; 4],
            vec![0.0; 4],
            Some(vec![1.0, 2.0, 3.0]),
            None,
        );
        h.advance(
            &[0.0; 3],
            &[0.0; 4],
            vec![0.0; 4],
            Some(vec![0.5, 0.0, -1.0]),
            None,
        );
        assert_eq!(h.lu.as_deref(), Some(&[1.5, 2.0, 2.0][..]));
        h.advance(&[0.0; 3], &[0.0; 4], vec![0.0; 4], None, None);
        assert_eq!(h.lu, None, "a step on another route");
        h.advance(
            &[0.0; 3],
            &[0.0; 4],
            vec![0.0; 4],
            Some(vec![1.0, 1.0, 1.0]),
            None,
        );
        assert_eq!(h.lu, None, "unknown until the history is reset");
        h.reset();
        assert_eq!(h.lu.as_deref(), Some(&[][..]));
    }

    /// The host's increments: the first increment records, the second
    /// extrapolates along the line of the two ends, by the fit of its load
    /// change q to the last one, projected onto the friction disc; a
    /// change at right angles, one of another length and a forgotten line
    /// give lambda_n unchanged.
    #[test]
    fn a_hosts_increments_continue_on_the_line_of_their_load_changes() {
        let p = [1.0, 1.0];
        let law = Friction::Tresca(&p);
        let mut incs = Increments::default();
        let q = vec![1.0, 0.0, 0.5, 0.0];
        // Nothing recorded: lambda_n.
        let mut lam = vec![1.0, 0.0, 0.2, 0.0];
        assert_eq!(incs.start(&q, law, 2, &mut lam), 0.0);
        assert_eq!(lam, [1.0, 0.0, 0.2, 0.0]);
        // The first increment started at zero with load change q.
        incs.advance(vec![0.0; 4], q.clone());
        // The next one, from lambda_n = [1, 0, 0.2, 0], with 1.5 q: s = 1.5.
        let mut lam = vec![1.0, 0.0, 0.2, 0.0];
        let q2: Vec<f64> = q.iter().map(|v| 1.5 * v).collect();
        assert_eq!(incs.start(&q2, law, 2, &mut lam), 1.5);
        assert_close(&lam, &[2.5, 0.0, 0.5, 0.0]);
        // Past the disc (|lambda_T| <= 1): projected onto it.
        let mut lam = vec![1.0, 0.0, 0.8, 0.0];
        assert_eq!(incs.start(&q, law, 2, &mut lam), 1.0);
        assert_close(&lam, &[2.0, 0.0, 1.0, 0.0]);
        // A load change at right angles to the last: lambda_n.
        let mut lam = vec![1.0, 0.0, 0.2, 0.0];
        let turn = vec![0.0, 1.0, 0.0, 0.0];
        assert_eq!(incs.start(&turn, law, 2, &mut lam), 0.0);
        assert_eq!(lam, [1.0, 0.0, 0.2, 0.0]);
        // Another number of unknowns (new contacts): lambda_n.
        let mut short = vec![1.0, 0.2];
        assert_eq!(incs.start(&[1.0, 0.5], law, 1, &mut short), 0.0);
        assert_eq!(short, [1.0, 0.2]);
        // Forgotten: lambda_n.
        incs.forget();
        let mut lam = vec![1.0, 0.0, 0.2, 0.0];
        assert_eq!(incs.start(&q, law, 2, &mut lam), 0.0);
        assert_eq!(lam, [1.0, 0.0, 0.2, 0.0]);
    }
}
