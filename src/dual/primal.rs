//! The displacement of a matrix-free solve's iterate, carried along with it
//! so that the recovery of u at the answer costs no solve.
//!
//! At multipliers lambda the increment's displacement is
//! u(lambda) = K^-1 (f - B^T lambda) (docs/design.md section 2), linear in
//! lambda: a move of lambda by t d moves u by -t z with z = K^-1 B^T d, and
//! an exact product A d = B z computes that z on its way
//! (`Dual::apply_keeping`). A solve whose start came with u (the
//! right-hand side's block solve, `Dual::solve_with_products`) and whose
//! steps all took exact products ends with u at its answer, where the
//! recovery would otherwise solve with K once more (on the 3D host
//! example's solves that solve was an eighth of the solve's time).
//!
//! Rounding: each move adds the rounding of its own solve, about eps |z|,
//! to u's; u is used only while the sum of the sizes moved,
//! |u_start| + sum |t| |z|, stays within
//! `load_span::max_amplification(tol)` times |u| (the bound the load's
//! combinations of solutions use: its rounding then stays a hundredth of
//! tol), else the recovery solves as before. (lambda's own rounding at
//! each move, fl(lambda + t d), adds about eps |K^-1 B^T lambda| to u's
//! error, the floor the rounding of the data and of the host's u_j + du
//! sets anyway.) u belongs to one lambda,
//! copied at each move: any other change of the iterate (a step from
//! single-precision products, a fallback, another method) leaves the copy
//! behind and u unused.

use crate::load_span::max_amplification;
use crate::memory::try_zeros;

/// u = K^-1 (f - B^T lambda) at the multipliers `at`, for one solve's f.
pub(crate) struct Primal {
    /// u (n values, length units), valid at `at` where `held`.
    u: Vec<f64>,
    /// The multipliers u belongs to (c values).
    at: Vec<f64>,
    /// Whether u and `at` hold a displacement.
    held: bool,
    /// |u_start|_2 + sum |t| |z|_2 over the moves since the start.
    moved: f64,
    /// K^-1 B^T d of the move being taken (n values), written by the
    /// product that measures it.
    pub(crate) z: Vec<f64>,
    /// The displacement at a trial point (n values; `Primal::trial_along`).
    spare: Vec<f64>,
    /// The size the trial point's first part moved.
    trial_moved: f64,
}

impl Primal {
    /// Room for n DOFs and c multipliers, holding nothing; None where the
    /// allocator refuses it (the solve then recovers u by a solve).
    pub(crate) fn new(n: usize, c: usize) -> Option<Primal> {
        let zeros = |len: usize| try_zeros::<f64>(len, "").ok();
        Some(Primal {
            u: zeros(n)?,
            at: zeros(c)?,
            held: false,
            moved: 0.0,
            z: zeros(n)?,
            spare: zeros(n)?,
            trial_moved: 0.0,
        })
    }

    /// Bytes it holds for n DOFs and c multipliers.
    pub(crate) fn bytes(n: usize, c: usize) -> usize {
        (3 * n + c) * std::mem::size_of::<f64>()
    }

    /// The start: u (written by the caller into `Primal::start_mut`) is u at
    /// `lam`.
    pub(crate) fn start_at(&mut self, lam: &[f64]) {
        self.at.copy_from_slice(lam);
        self.moved = norm(&self.u);
        self.held = true;
    }

    /// Where the start's u is written (n values).
    pub(crate) fn start_mut(&mut self) -> &mut [f64] {
        self.held = false;
        &mut self.u
    }

    /// Whether u is held at exactly `lam`.
    pub(crate) fn holds_at(&self, lam: &[f64]) -> bool {
        self.held && self.at == lam
    }

    /// Nothing held any more.
    pub(crate) fn drop_u(&mut self) {
        self.held = false;
    }

    /// lambda moved by t d to `lam`, where `z` holds K^-1 B^T d: u -= t z.
    pub(crate) fn moved_by(&mut self, t: f64, lam: &[f64]) {
        for (ui, zi) in self.u.iter_mut().zip(&self.z) {
            *ui -= t * zi;
        }
        self.moved += t.abs() * norm(&self.z);
        self.at.copy_from_slice(lam);
    }

    /// The first part of a move to a trial point: u - s z into the spare
    /// vector, z = K^-1 B^T d of a direction d (a host iteration's line),
    /// and z cleared for what the second part moved (written by
    /// `Dual::apply_keeping`, or left zero). Taken with
    /// [`Primal::take_trial`]; u at `at` is kept until then.
    pub(crate) fn trial_along(&mut self, s: f64) {
        for ((v, ui), zi) in self.spare.iter_mut().zip(&self.u).zip(&self.z) {
            *v = ui - s * zi;
        }
        self.trial_moved = s.abs() * norm(&self.z);
        self.z.fill(0.0);
    }

    /// The trial point `lam` taken: u := u - s z_d - z (see
    /// [`Primal::trial_along`]).
    pub(crate) fn take_trial(&mut self, lam: &[f64]) {
        for (v, zi) in self.spare.iter_mut().zip(&self.z) {
            *v -= zi;
        }
        std::mem::swap(&mut self.u, &mut self.spare);
        self.moved += self.trial_moved + norm(&self.z);
        self.at.copy_from_slice(lam);
    }

    /// u at `lam` where it is held there and the sizes moved amplify its
    /// rounding at most `load_span::max_amplification(tol)` times (module
    /// docs).
    pub(crate) fn u_at(&self, lam: &[f64], tol: f64) -> Option<&[f64]> {
        let size = norm(&self.u);
        (self.holds_at(lam) && self.moved <= max_amplification(tol) * size && size > 0.0)
            .then_some(&self.u[..])
    }
}

/// |x|_2.
fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// u moves by -t z and by the trial's -s z - z2, belongs to the
    /// multipliers of its last move only, and is refused once the sizes
    /// moved exceed the amplification the tolerance allows.
    #[test]
    fn u_follows_its_moves_and_is_refused_beyond_the_rounding_allowed() {
        let (n, c) = (3, 2);
        let mut p = Primal::new(n, c).expect("room");
        let lam0 = [1.0, 2.0];
        assert!(!p.holds_at(&lam0));
        p.start_mut().copy_from_slice(&[3.0, 0.0, 4.0]);
        p.start_at(&lam0);
        assert!(p.holds_at(&lam0));
        assert_eq!(p.u_at(&lam0, 1e-10), Some(&[3.0, 0.0, 4.0][..]));
        // A step of length 0.5 along d with K^-1 B^T d = z.
        p.z.copy_from_slice(&[2.0, -2.0, 0.0]);
        let lam1 = [1.5, 2.0];
        p.moved_by(0.5, &lam1);
        assert!(!p.holds_at(&lam0) && p.holds_at(&lam1));
        assert_eq!(p.u_at(&lam1, 1e-10), Some(&[2.0, 1.0, 4.0][..]));
        assert_eq!(p.u_at(&lam0, 1e-10), None);
        // A line's move s = 2 along z, then what a projection moved (z2),
        // kept at lam1 until taken.
        p.z.copy_from_slice(&[1.0, 0.0, 0.0]);
        p.trial_along(2.0);
        assert!(p.z.iter().all(|&v| v == 0.0));
        p.z.copy_from_slice(&[0.0, 0.5, 0.0]);
        assert!(p.holds_at(&lam1));
        let lam2 = [0.0, 1.0];
        p.take_trial(&lam2);
        assert!(p.holds_at(&lam2));
        assert_eq!(p.u_at(&lam2, 1e-10), Some(&[0.0, 0.5, 4.0][..]));
        // Moved so far: |u_start| 5, then 0.5 |(2, -2, 0)|, 2 |(1, 0, 0)|
        // and |(0, 0.5, 0)|: 5 + sqrt(2) + 2.5 = 8.91 against |u| = 4.03;
        // a tolerance that allows an amplification of 2 refuses it
        // (max_amplification(tol) = 0.01 tol / (64 eps)).
        let allowing = |amp: f64| amp * 64.0 * f64::EPSILON / 0.01;
        assert!(p.u_at(&lam2, allowing(2.0)).is_none());
        assert!(p.u_at(&lam2, allowing(2.3)).is_some());
        p.drop_u();
        assert!(!p.holds_at(&lam2) && p.u_at(&lam2, 1e-10).is_none());
    }
}
