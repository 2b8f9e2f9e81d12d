//! Interface compliance (docs/design.md section 8): per contact, a normal
//! compliance law lambda_N = c_N (N u - g)_+^m_N and an elastic slip of
//! stiffness k_T, the "stick slope" of penalty codes. Both enter the dual as a
//! diagonal D added to A (`Dual::set_shift`): D = [1 / c_N; 1 / k_T per
//! tangential row], with the tangential term centred at the force the return
//! mapping starts from, which adds D_T lambda_T,prev to b. c_N = +inf and
//! k_T = +inf are the rigid laws (D = 0 there), so rigid and compliant
//! contacts mix in one problem.

use crate::error::{ErrorKind, Result, fail};

/// The largest normal compliance exponent m_N accepted (the power law of
/// rough surfaces and coatings lies between 1 and 3.5).
pub const MAX_EXPONENT: f64 = 10.0;

/// The interface data of m contacts, all of length m; +inf means rigid.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Compliance {
    /// Normal compliance stiffness c_N,i > 0 (force / length^m_N), +inf for
    /// Signorini.
    pub cn: Vec<f64>,
    /// Exponent m_N,i >= 1 (dimensionless).
    pub mn: Vec<f64>,
    /// Tangential stiffness k_T,i > 0 (force / length), +inf for rigid stick.
    pub kt: Vec<f64>,
}

/// Checks one per-contact array: length m, no NaN, each value in its range
/// (`ok`), +inf allowed where `inf_ok`.
fn check(
    name: &str,
    x: &[f64],
    m: usize,
    inf_ok: bool,
    ok: fn(f64) -> bool,
    what: &str,
) -> Result<()> {
    if x.len() != m {
        return fail(
            ErrorKind::BadSize,
            format!(
                "{name} has length {}, expected m = {m} (one value per contact)",
                x.len()
            ),
        );
    }
    for (i, &v) in x.iter().enumerate() {
        if v.is_nan() || (v.is_infinite() && !(inf_ok && v > 0.0)) {
            return fail(ErrorKind::NotFinite, format!("{name}[{i}] = {v}: {what}"));
        }
        if !ok(v) {
            return fail(ErrorKind::BadArgument, format!("{name}[{i}] = {v}: {what}"));
        }
    }
    Ok(())
}

/// Whether a contact with normal compliance `cn` and tangential stiffness
/// `kt` is compliant: either is finite (+inf is the rigid law).
pub(crate) fn compliant(cn: f64, kt: f64) -> bool {
    cn.is_finite() || kt.is_finite()
}

impl Compliance {
    /// Rigid contacts (Signorini, rigid stick), m of them.
    pub fn rigid(m: usize) -> Compliance {
        Compliance {
            cn: vec![f64::INFINITY; m],
            mn: vec![1.0; m],
            kt: vec![f64::INFINITY; m],
        }
    }

    /// The law of m contacts from the caller's arrays, each None for its
    /// default (c_N and k_T +inf: rigid; m_N 1).
    ///
    /// Errors: `BadSize` (a length is not m), `NotFinite` (NaN, or an infinite
    /// m_N or -inf), `BadArgument` (c_N <= 0, m_N < 1 or above
    /// [`MAX_EXPONENT`], k_T <= 0, a c_N or k_T whose reciprocal overflows,
    /// below about 5.6e-309).
    pub fn of(
        m: usize,
        cn: Option<&[f64]>,
        mn: Option<&[f64]>,
        kt: Option<&[f64]>,
    ) -> Result<Compliance> {
        let mut law = Compliance::rigid(m);
        if let Some(cn) = cn {
            check(
                "c_N",
                cn,
                m,
                true,
                |v| v > 0.0 && (1.0 / v).is_finite(),
                "the normal compliance stiffness must be > 0 with a finite reciprocal \
                 (+inf: rigid)",
            )?;
            law.cn.copy_from_slice(cn);
        }
        if let Some(mn) = mn {
            check(
                "m_N",
                mn,
                m,
                false,
                |v| (1.0..=MAX_EXPONENT).contains(&v),
                "the normal compliance exponent must be in [1, 10]",
            )?;
            law.mn.copy_from_slice(mn);
        }
        if let Some(kt) = kt {
            check(
                "k_T",
                kt,
                m,
                true,
                |v| v > 0.0 && (1.0 / v).is_finite(),
                "the tangential stiffness must be > 0 with a finite reciprocal \
                 (+inf: rigid stick)",
            )?;
            law.kt.copy_from_slice(kt);
        }
        Ok(law)
    }

    /// The contacts whose normal law is nonlinear (finite c_N, m_N != 1),
    /// ascending.
    pub fn nonlinear(&self) -> Vec<usize> {
        (0..self.cn.len())
            .filter(|&i| self.cn[i].is_finite() && self.mn[i] != 1.0)
            .collect()
    }

    /// The penetration (N u - g)_i at which contact i's normal law carries the
    /// force `lambda` >= 0: (lambda / c_N)^(1 / m_N).
    pub fn penetration(&self, i: usize, lambda: f64) -> f64 {
        if lambda > 0.0 && self.cn[i].is_finite() {
            (lambda / self.cn[i]).powf(1.0 / self.mn[i])
        } else {
            0.0
        }
    }

    /// The force contact i's normal law gives at penetration `delta`:
    /// c_N delta_+^m_N.
    #[cfg(test)]
    pub fn force(&self, i: usize, delta: f64) -> f64 {
        self.cn[i] * delta.max(0.0).powf(self.mn[i])
    }

    /// The tangent of the nonlinear normal laws at the penetrations `delta`
    /// (m), for Newton on the law (docs/design.md section 8): per nonlinear
    /// contact i the linear law lambda = c_t (N u - g - s)_+ with
    /// c_t = m c delta^(m - 1) and s = delta (1 - 1 / m), which touches
    /// c delta_+^m at delta. Returns the dual's diagonal ([`Compliance::shift`]
    /// with 1 / c_t at those contacts, at most `d_max[i]`: where
    /// delta <= 0 the tangent carries nothing, and d_max stands for that) and
    /// s (m, zero elsewhere).
    pub fn linearised(&self, d: usize, delta: &[f64], d_max: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let m = self.cn.len();
        let mut shift = self.shift(d);
        if shift.is_empty() {
            shift = vec![0.0; d * m];
        }
        let mut s = vec![0.0; m];
        for i in self.nonlinear() {
            let (c, e, x) = (self.cn[i], self.mn[i], delta[i]);
            let ct = if x > 0.0 {
                e * c * x.powf(e - 1.0)
            } else {
                0.0
            };
            shift[i] = if ct > 0.0 {
                (1.0 / ct).min(d_max[i])
            } else {
                d_max[i]
            };
            s[i] = x.max(0.0) * (1.0 - 1.0 / e);
        }
        (shift, s)
    }

    /// The number of contacts with a compliant law ([`compliant`]).
    pub fn compliant_count(&self) -> usize {
        (0..self.cn.len())
            .filter(|&i| compliant(self.cn[i], self.kt[i]))
            .count()
    }

    /// True when every contact is rigid (D = 0).
    pub fn is_rigid(&self) -> bool {
        self.cn.iter().chain(&self.kt).all(|v| v.is_infinite())
    }

    /// D of the module docs for contact dimension d (a nonlinear normal law
    /// counts as linear here; a solve replaces its entry by the tangent's,
    /// [`Compliance::linearised`]): length d m (1 / c_N,i
    /// for the normal unknowns, 1 / k_T,i for contact i's d - 1 tangential
    /// ones; units length / force); empty where every contact is rigid.
    pub fn shift(&self, d: usize) -> Vec<f64> {
        if self.is_rigid() {
            return Vec::new();
        }
        let mut s: Vec<f64> = self.cn.iter().map(|c| 1.0 / c).collect();
        for k in &self.kt {
            s.extend(std::iter::repeat_n(1.0 / k, d - 1));
        }
        s
    }

    /// The force the return mapping of an increment starts from, when the
    /// last one ended at `lt` (length (d - 1) m) under `self` and the next one
    /// runs under `next`: what carries over is the elastic slip lt / k_T, so
    /// contact i's force scales by k_T,next / k_T,self; zero where either is
    /// rigid (a rigid contact has no elastic slip).
    pub fn carry(&self, next: &Compliance, lt: &mut [f64], d: usize) {
        for (i, pair) in lt.chunks_mut(d - 1).enumerate() {
            let (old, new) = (self.kt[i], next.kt[i]);
            let s = if old.is_finite() && new.is_finite() {
                new / old
            } else {
                0.0
            };
            pair.iter_mut().for_each(|v| *v *= s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_rigid_and_shift_is_empty() {
        let law = Compliance::of(2, None, None, None).unwrap();
        assert!(law.is_rigid());
        assert!(law.shift(3).is_empty());
    }

    #[test]
    fn shift_holds_the_inverse_stiffnesses_contact_by_contact() {
        let cn = [2.0, f64::INFINITY];
        let kt = [4.0, 8.0];
        let law = Compliance::of(2, Some(&cn), None, Some(&kt)).unwrap();
        assert_eq!(law.shift(3), vec![0.5, 0.0, 0.25, 0.25, 0.125, 0.125]);
        assert_eq!(law.shift(2), vec![0.5, 0.0, 0.25, 0.125]);
    }

    #[test]
    fn bad_values_name_the_array_and_entry() {
        type Data<'a> = Option<&'a [f64]>;
        let cases: [(Data<'_>, Data<'_>, Data<'_>, ErrorKind, &str); 9] = [
            (
                None,
                Some(&[11.0, 1.0]),
                None,
                ErrorKind::BadArgument,
                "m_N[0]",
            ),
            (
                Some(&[1.0, 0.0]),
                None,
                None,
                ErrorKind::BadArgument,
                "c_N[1]",
            ),
            (
                Some(&[-1.0, 1.0]),
                None,
                None,
                ErrorKind::BadArgument,
                "c_N[0]",
            ),
            (
                Some(&[f64::NAN, 1.0]),
                None,
                None,
                ErrorKind::NotFinite,
                "c_N[0]",
            ),
            (
                Some(&[f64::NEG_INFINITY, 1.0]),
                None,
                None,
                ErrorKind::NotFinite,
                "c_N[0]",
            ),
            (
                None,
                Some(&[1.0, 0.5]),
                None,
                ErrorKind::BadArgument,
                "m_N[1]",
            ),
            (
                None,
                Some(&[f64::INFINITY, 1.0]),
                None,
                ErrorKind::NotFinite,
                "m_N[0]",
            ),
            (
                None,
                None,
                Some(&[1.0, 0.0]),
                ErrorKind::BadArgument,
                "k_T[1]",
            ),
            (
                None,
                None,
                Some(&[1.0]),
                ErrorKind::BadSize,
                "k_T has length 1",
            ),
        ];
        for (cn, mn, kt, kind, name) in cases {
            let e = Compliance::of(2, cn, mn, kt).unwrap_err();
            assert_eq!(e.kind, kind, "{}", e.message);
            assert!(e.message.contains(name), "{}", e.message);
        }
    }

    #[test]
    fn the_tangent_law_touches_the_power_law() {
        let law = Compliance::of(2, Some(&[3.0, 3.0]), Some(&[2.5, 1.0]), None).unwrap();
        assert_eq!(law.nonlinear(), vec![0]);
        let x = 0.4;
        let (shift, s) = law.linearised(2, &[x, 0.7], &[1e9, 1e9]);
        let ct = 1.0 / shift[0];
        // Equal value and slope at x: c_t (x - s) = c x^m, c_t = m c x^(m-1).
        assert!((ct * (x - s[0]) - law.force(0, x)).abs() < 1e-14);
        assert!((ct - 2.5 * 3.0 * x.powf(1.5)).abs() < 1e-14);
        // The linear contact keeps 1 / c_N and no offset.
        assert_eq!((shift[1], s[1]), (1.0 / 3.0, 0.0));
        // Open: the tangent carries nothing, d_max stands for it.
        let (shift, s) = law.linearised(2, &[-0.1, 0.0], &[7.0, 7.0]);
        assert_eq!((shift[0], s[0]), (7.0, 0.0));
        assert!((law.penetration(0, law.force(0, x)) - x).abs() < 1e-15);
    }

    #[test]
    fn the_elastic_slip_carries_over() {
        let old = Compliance::of(3, None, None, Some(&[2.0, f64::INFINITY, 2.0])).unwrap();
        let new = Compliance::of(3, None, None, Some(&[4.0, 4.0, f64::INFINITY])).unwrap();
        let mut lt = [1.0, -1.0, 3.0, 3.0, 5.0, 5.0];
        old.carry(&new, &mut lt, 3);
        assert_eq!(lt, [2.0, -2.0, 0.0, 0.0, 0.0, 0.0]);
    }
}
