//! The friction law of one increment and the projection onto its friction sets:
//! the one friction type of the library (the C boundary's `DsFriction` selects it).

/// Friction law of one increment, per contact.
#[derive(Copy, Clone, Debug)]
pub enum Friction<'a> {
    /// Given slip bound p_i >= 0 per contact (force units), length m.
    Tresca(&'a [f64]),
    /// Coulomb coefficient mu_i >= 0 per contact (dimensionless), length m:
    /// the bound is p_i = mu_i lambda_N,i, found by fixed point.
    Coulomb(&'a [f64]),
}

impl Friction<'_> {
    /// The per-contact values: p (Tresca) or mu (Coulomb).
    pub fn values(&self) -> &[f64] {
        match self {
            Friction::Tresca(p) => p,
            Friction::Coulomb(mu) => mu,
        }
    }

    /// True for Coulomb friction.
    pub fn is_coulomb(&self) -> bool {
        matches!(self, Friction::Coulomb(_))
    }

    /// The slip bound of contact i given its normal multiplier (force units).
    #[inline]
    pub fn bound(&self, i: usize, lambda_n: f64) -> f64 {
        match self {
            Friction::Tresca(p) => p[i],
            Friction::Coulomb(mu) => mu[i] * lambda_n.max(0.0),
        }
    }

    /// True when every bound is zero whatever lambda_N (Tresca p = 0, Coulomb
    /// mu = 0): a frictionless increment, lambda_T = 0.
    pub fn frictionless(&self) -> bool {
        self.values().iter().all(|&v| v == 0.0)
    }

    /// Writes every bound into `p` (length m) for the normal multipliers `lambda_n`.
    pub fn bounds(&self, lambda_n: &[f64], p: &mut [f64]) {
        for (i, pi) in p.iter_mut().enumerate() {
            *pi = self.bound(i, lambda_n[i]);
        }
    }
}

/// Projects y (1 or 2 entries) onto {|x| <= r} (interval in 2D, disk in 3D).
#[inline]
pub fn project_disk(y: &mut [f64], r: f64) {
    let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm > r {
        let s = if norm > 0.0 { r / norm } else { 0.0 };
        y.iter_mut().for_each(|v| *v *= s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_onto_interval_and_disk() {
        let mut y = [3.0];
        project_disk(&mut y, 2.0);
        assert_eq!(y, [2.0]);
        let mut y = [-3.0];
        project_disk(&mut y, 2.0);
        assert_eq!(y, [-2.0]);
        let mut y = [3.0, 4.0];
        project_disk(&mut y, 1.0);
        assert!((y[0] - 0.6).abs() < 1e-15 && (y[1] - 0.8).abs() < 1e-15);
        let mut y = [0.1, 0.1];
        project_disk(&mut y, 1.0);
        assert_eq!(y, [0.1, 0.1]);
    }

    #[test]
    fn bounds_follow_the_law() {
        let (p, mu) = ([0.5, 0.0], [0.3, 0.0]);
        let mut out = [0.0; 2];
        Friction::Tresca(&p).bounds(&[10.0, 10.0], &mut out);
        assert_eq!(out, [0.5, 0.0]);
        Friction::Coulomb(&mu).bounds(&[10.0, -1.0], &mut out);
        assert_eq!(out, [3.0, 0.0]);
        assert!(!Friction::Tresca(&p).frictionless());
        assert!(Friction::Coulomb(&[0.0, 0.0]).frictionless());
    }
}
