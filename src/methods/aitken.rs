//! Aitken's relaxation of the Coulomb fixed point, shared by every method
//! that iterates it (PGS, the splittings, MPRGP on the whole dual).

/// The smallest relaxation factor of [`Aitken`]: enough for a coupling
/// mu |A_NT| / A_NN up to about 1e3.
const OMEGA_MIN: f64 = 1e-3;

/// Aitken's dynamic relaxation of a fixed-point iteration x -> G(x) (Irons and
/// Tuck; Kuettler and Wall): x_k+1 = x_k + omega_k r_k with r_k = G(x_k) - x_k and
/// omega_k = -omega_k-1 r_k-1 . (r_k - r_k-1) / |r_k - r_k-1|^2, cut to
/// [`OMEGA_MIN`, 1] (omega_0 = 1). For a map that converges monotonically omega
/// stays 1 (the plain iteration); for one that oscillates with slope -kappa
/// (kappa >= 1: no contraction) omega tends to 1 / (1 + kappa), the factor that
/// makes the relaxed map contract. omega is a ratio: the same in any units. The
/// relaxed iterate is a convex combination of x_k and G(x_k), so it stays in any
/// convex set (the friction cones, lambda_N >= 0) that both lie in.
pub(super) struct Aitken {
    r_old: Vec<f64>,
    have_old: bool,
    omega: f64,
}

impl Aitken {
    pub fn new(n: usize) -> Self {
        Aitken {
            r_old: vec![0.0; n],
            have_old: false,
            omega: 1.0,
        }
    }

    /// `x` holds G(x_prev) on entry and the relaxed iterate on exit; returns the
    /// factor used.
    pub fn relax(&mut self, x_prev: &[f64], x: &mut [f64]) -> f64 {
        if self.have_old {
            let (mut rd, mut dd) = (0.0, 0.0);
            for ((xn, xp), ro) in x.iter().zip(x_prev).zip(&self.r_old) {
                let d = (xn - xp) - ro;
                rd += ro * d;
                dd += d * d;
            }
            if dd > 0.0 {
                let omega = -self.omega * rd / dd;
                // omega <= 0: r grew along itself (slope > 1), which no damping
                // cures: back to the plain iteration.
                self.omega = if omega > 0.0 && omega.is_finite() {
                    omega.clamp(OMEGA_MIN, 1.0)
                } else {
                    1.0
                };
            }
        }
        for ((xn, xp), ro) in x.iter_mut().zip(x_prev).zip(self.r_old.iter_mut()) {
            *ro = *xn - xp;
            *xn = xp + self.omega * *ro;
        }
        self.have_old = true;
        self.omega
    }

    /// The Coulomb bound of an outer loop: relaxes the new bound `p` (mu lambda_N)
    /// against `prev`, the bound the last step used (not on the first step), and
    /// keeps the result in `prev` for the next one.
    pub fn relax_bound(&mut self, prev: &mut [f64], p: &mut [f64], first: bool) {
        if !first {
            self.relax(prev, p);
        }
        prev.copy_from_slice(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aitken_makes_an_oscillating_fixed_point_contract() {
        // x -> G(x) = 1 - 3 x (slope -3: the plain iteration diverges, oscillating);
        // the fixed point is 1/4. Aitken finds omega = 1 / (1 + 3) after one step.
        let g = |x: f64| 1.0 - 3.0 * x;
        let mut relax = Aitken::new(1);
        let mut x = [0.0];
        let mut omegas = Vec::new();
        for _ in 0..6 {
            let prev = x;
            x[0] = g(x[0]);
            omegas.push(relax.relax(&prev, &mut x));
        }
        assert!((x[0] - 0.25).abs() < 1e-14, "x = {}", x[0]);
        assert_eq!(omegas[0], 1.0);
        assert!((omegas[1] - 0.25).abs() < 1e-14, "{omegas:?}");
        // A monotone contraction (slope 0.5) keeps the plain iteration.
        let mut relax = Aitken::new(1);
        let mut x = [0.0];
        for _ in 0..5 {
            let prev = x;
            x[0] = 1.0 + 0.5 * x[0];
            assert_eq!(relax.relax(&prev, &mut x), 1.0);
        }
    }
}
