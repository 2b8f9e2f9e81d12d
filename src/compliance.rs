//! Interface compliance (docs/design.md section 8): per contact, a normal
//! compliance law lambda_N = c_N (N u - g)_+^m_N and an elastic slip of
//! stiffness k_T, the "stick slope" of penalty codes. Both enter the dual as a
//! diagonal D added to A (`Dual::set_shift`): D = [1 / c_N; 1 / k_T per
//! tangential row], with the tangential term centred at the force the return
//! mapping starts from, which adds D_T lambda_T,prev to b. c_N = +inf and
//! k_T = +inf are the rigid laws (D = 0 there), so rigid and compliant
//! contacts mix in one problem.

use crate::error::{ErrorKind, Result, fail};

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
    /// m_N or -inf), `BadArgument` (c_N <= 0, m_N < 1, k_T <= 0, or
    /// m_N != 1 on a compliant contact: the nonlinear law is not supported yet).
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
                |v| v > 0.0,
                "the normal compliance stiffness must be > 0 (+inf: rigid)",
            )?;
            law.cn.copy_from_slice(cn);
        }
        if let Some(mn) = mn {
            check(
                "m_N",
                mn,
                m,
                false,
                |v| v >= 1.0,
                "the normal compliance exponent must be finite and >= 1",
            )?;
            law.mn.copy_from_slice(mn);
        }
        if let Some(kt) = kt {
            check(
                "k_T",
                kt,
                m,
                true,
                |v| v > 0.0,
                "the tangential stiffness must be > 0 (+inf: rigid stick)",
            )?;
            law.kt.copy_from_slice(kt);
        }
        if let Some(i) = (0..m).find(|&i| law.mn[i] != 1.0 && law.cn[i].is_finite()) {
            return fail(
                ErrorKind::BadArgument,
                format!(
                    "m_N[{i}] = {}: only the linear normal compliance law (m_N = 1) is \
                     supported in this version",
                    law.mn[i]
                ),
            );
        }
        Ok(law)
    }

    /// True when every contact is rigid (D = 0).
    pub fn is_rigid(&self) -> bool {
        self.cn.iter().chain(&self.kt).all(|v| v.is_infinite())
    }

    /// D of the module docs for contact dimension d: length d m (1 / c_N,i
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
        let cases: [(Data<'_>, Data<'_>, Data<'_>, ErrorKind, &str); 8] = [
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
    fn a_nonlinear_law_is_refused_where_it_would_act() {
        let e = Compliance::of(1, Some(&[1.0]), Some(&[2.0]), None).unwrap_err();
        assert_eq!(e.kind, ErrorKind::BadArgument);
        assert!(e.message.contains("m_N = 1"), "{}", e.message);
        // On a rigid contact the exponent does not act.
        assert!(Compliance::of(1, None, Some(&[2.0]), None).is_ok());
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
