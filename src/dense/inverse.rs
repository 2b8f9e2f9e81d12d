//! A's inverse in single precision, and the preconditioner it gives every
//! Newton step's reduced system without a factorisation of its own.
//!
//! A Newton step's reduced system (on a dense dual) is S = T^T A T + Delta
//! (for Coulomb: its symmetric part, each direction cut to its test vector),
//! T (c x k) the reduced unknowns' test vectors, orthonormal, and Delta the
//! slipping contacts' curvature terms (diagonal, positive on the s slip
//! unknowns U = T E_s). With Tc (c x r) an orthonormal basis of the
//! components T leaves out (open contacts, the fixed slip directions) and
//! B = [Tc, U], S z = b is
//!
//! ```text
//! lambda = X (T b + B xi),   X = A^-1,
//! Z xi = -B^T X T b,         Z = B^T X B + diag(0, 1 / delta),
//! z = T^T lambda,
//! ```
//!
//! (Tc^T lambda = 0 keeps lambda in T's span; U's rows carry Delta.) Z is
//! symmetric positive definite of order r + s: where few components are
//! left out and few contacts slip (a history step on a closed face), its
//! factor costs (r + s)^3 / 3 flops against k^3 / 3 for S's own, and each
//! application two products with X. X costs c^3 flops once per A
//! (Cholesky and inversion in single precision), kept on the dual.

use super::cholesky_in_place;
use crate::memory::{Claim, Ledger, try_mat, try_scratch};
use faer::dyn_stack::MemStack;
use faer::linalg::cholesky::llt;
use faer::{Accum, Mat, MatRef, Par};
use std::sync::Arc;

/// A^-1 of a symmetric positive definite A, every entry, in single precision.
pub(crate) struct InverseF32 {
    x: Mat<f32>,
    /// The row sums of |A| (bounds of |M|_inf for the reduced systems).
    rows: Vec<f64>,
    _claim: Claim,
}

impl InverseF32 {
    /// The inverse of the c x c symmetric A whose column j is `col(j)` (the
    /// lower triangle factored, the whole column summed for
    /// [`InverseF32::abs_row_sums`]); None when A is not positive definite in single
    /// precision or the work space cannot be allocated. Claims c^2 single
    /// precision entries on `ledger` while held (three times that while
    /// formed).
    pub fn of<'a>(
        c: usize,
        col: impl Fn(usize) -> &'a [f64],
        ledger: &Arc<Ledger>,
        par: Par,
    ) -> Option<InverseF32> {
        let f32_bytes = std::mem::size_of::<f32>();
        let claim = ledger.claim(c * c * f32_bytes);
        let l_claim = ledger.claim(c * c * f32_bytes);
        let mut l = try_mat::<f32>(c, c, "").ok()?;
        let mut rows = vec![0.0f64; c];
        for j in 0..c {
            let a = col(j);
            for i in j..c {
                l[(i, j)] = a[i] as f32;
            }
            // Column j's sum is row j's (A symmetric).
            rows[j] = a.iter().map(|v| v.abs()).sum();
        }
        cholesky_in_place(l.as_mut(), par)?;
        let mut x = try_mat::<f32>(c, c, "").ok()?;
        {
            // The inversion's work space (L^-1, c^2 entries).
            let _work = ledger.claim(c * c * f32_bytes);
            let req = llt::inverse::inverse_scratch::<f32>(c, par);
            let mut mem = try_scratch(req, "").ok()?;
            llt::inverse::inverse(x.as_mut(), l.as_ref(), par, MemStack::new(&mut mem));
        }
        drop((l, l_claim));
        // The inverse fills the lower triangle: mirror it.
        for j in 0..c {
            for i in j + 1..c {
                x[(j, i)] = x[(i, j)];
            }
        }
        if !x.as_ref().is_all_finite() {
            return None;
        }
        Some(InverseF32 {
            x,
            rows,
            _claim: claim,
        })
    }

    /// The row sums of |A|, length c.
    pub fn abs_row_sums(&self) -> &[f64] {
        &self.rows
    }

    /// The order c of A.
    pub fn order(&self) -> usize {
        self.x.nrows()
    }

    /// Column j of X (= row j).
    fn col(&self, j: usize) -> &[f32] {
        self.x
            .col(j)
            .try_as_col_major()
            .expect("contiguous")
            .as_slice()
    }
}

/// One reduced unknown as the preconditioner sees it: its test vector (one
/// or two entries of unit norm) and its diagonal term.
#[derive(Clone, Copy)]
pub(crate) struct Unknown {
    pub test: [(usize, f64); 2],
    pub n_test: usize,
    pub diag: f64,
}

/// The preconditioner of the module docs for one reduced system, with its
/// scratch (no allocation per application).
pub(crate) struct Complement<'a> {
    inv: &'a InverseF32,
    unknowns: &'a [Unknown],
    /// B's columns (one or two entries each): Tc's, then U's.
    b: Vec<[(usize, f64); 2]>,
    /// W = X B (c x (r + s)).
    w: Mat<f32>,
    /// Z's Cholesky factor (lower).
    z_l: Mat<f64>,
    v: Mat<f32>,
    p: Mat<f32>,
    xi: Mat<f64>,
    xi32: Mat<f32>,
    par: Par,
}

/// Tolerance on a test vector's norm: the construction needs T orthonormal.
const UNIT_TOL: f64 = 1e-12;

impl<'a> Complement<'a> {
    /// The preconditioner for the reduced unknowns `unknowns` on a dual of
    /// m contacts in dimension d (c = d m components), or None where it
    /// does not apply: a test vector of other than one or two distinct
    /// entries below c or not of unit norm, two unknowns of a contact that
    /// are not orthogonal, a negative diagonal term, more than
    /// `max_order` columns in B, or Z not positive definite.
    pub fn new(
        inv: &'a InverseF32,
        unknowns: &'a [Unknown],
        m: usize,
        d: usize,
        max_order: usize,
        par: Par,
    ) -> Option<Complement<'a>> {
        let c = inv.order();
        if c != d * m || !(2..=3).contains(&d) {
            return None;
        }
        // Per contact, its normal's unknown (if any) and its tangential
        // unknowns' test vectors.
        let mut normal = vec![false; m];
        let mut tangential: Vec<Vec<[f64; 2]>> = vec![Vec::new(); m];
        let mut slip = Vec::new();
        for (l, u) in unknowns.iter().enumerate() {
            if !(1..=2).contains(&u.n_test)
                || u.test[..u.n_test].iter().any(|&(j, _)| j >= c)
                || (u.n_test == 2 && u.test[0].0 == u.test[1].0)
            {
                return None;
            }
            let tests = &u.test[..u.n_test];
            let norm2: f64 = tests.iter().map(|&(_, v)| v * v).sum();
            if (norm2 - 1.0).abs() > UNIT_TOL || u.diag < 0.0 || !u.diag.is_finite() {
                return None;
            }
            let j0 = tests[0].0;
            if j0 < m {
                if u.n_test != 1 || normal[j0] {
                    return None;
                }
                normal[j0] = true;
            } else {
                let i = (j0 - m) / (d - 1);
                let mut t = [0.0; 2];
                for &(j, v) in tests {
                    if j < m || (j - m) / (d - 1) != i {
                        return None;
                    }
                    t[(j - m) % (d - 1)] = v;
                }
                tangential[i].push(t);
            }
            if u.diag > 0.0 {
                slip.push(l);
            }
        }
        // Tc: what the unknowns leave out, contact by contact.
        let mut b: Vec<[(usize, f64); 2]> = Vec::new();
        for i in 0..m {
            if !normal[i] {
                b.push([(i, 1.0), (i, 0.0)]);
            }
            let jt = m + (d - 1) * i;
            let ts = &tangential[i];
            match (d, ts.len()) {
                (_, 0) => {
                    for s in 0..d - 1 {
                        b.push([(jt + s, 1.0), (jt + s, 0.0)]);
                    }
                }
                (2, 1) => {}
                (3, 1) => {
                    let t = ts[0];
                    b.push([(jt, t[1]), (jt + 1, -t[0])]);
                }
                (3, 2) => {
                    let dot = ts[0][0] * ts[1][0] + ts[0][1] * ts[1][1];
                    if dot.abs() > UNIT_TOL {
                        return None;
                    }
                }
                _ => return None,
            }
        }
        let r = b.len();
        for &l in &slip {
            let u = &unknowns[l];
            b.push([
                u.test[0],
                if u.n_test > 1 {
                    u.test[1]
                } else {
                    (u.test[0].0, 0.0)
                },
            ]);
        }
        let q = b.len();
        if q > max_order {
            return None;
        }
        // W = X B, column by column from X's columns.
        let mut w = try_mat::<f32>(c, q, "").ok()?;
        for (col, &[(j0, c0), (j1, c1)]) in b.iter().enumerate() {
            let (x0, x1) = (inv.col(j0), inv.col(j1));
            let (c0, c1) = (c0 as f32, c1 as f32);
            let out = w
                .col_mut(col)
                .try_as_col_major_mut()
                .expect("contiguous")
                .as_slice_mut();
            for ((o, &a0), &a1) in out.iter_mut().zip(x0).zip(x1) {
                *o = c0 * a0 + c1 * a1;
            }
        }
        // Z = B^T W + diag(0, 1 / delta), its lower triangle.
        let mut z_l = try_mat::<f64>(q, q, "").ok()?;
        for col in 0..q {
            for row in col..q {
                let [(j0, c0), (j1, c1)] = b[row];
                z_l[(row, col)] = c0 * f64::from(w[(j0, col)]) + c1 * f64::from(w[(j1, col)]);
            }
        }
        for (s, &l) in slip.iter().enumerate() {
            z_l[(r + s, r + s)] += 1.0 / unknowns[l].diag;
        }
        cholesky_in_place(z_l.as_mut(), par)?;
        Some(Complement {
            inv,
            unknowns,
            b,
            w,
            z_l,
            v: Mat::zeros(c, 1),
            p: Mat::zeros(c, 1),
            xi: Mat::zeros(q, 1),
            xi32: Mat::zeros(q, 1),
            par,
        })
    }

    /// The order of Z (r + s).
    #[cfg(test)]
    pub fn order(&self) -> usize {
        self.b.len()
    }

    /// out := S^-1 res (module docs), S's inverse to single precision.
    pub fn apply(&mut self, res: &[f64], out: &mut [f64]) {
        let par = self.par;
        self.v.col_mut(0).iter_mut().for_each(|e| *e = 0.0);
        for (u, &rl) in self.unknowns.iter().zip(res) {
            for &(j, cf) in &u.test[..u.n_test] {
                self.v[(j, 0)] += (cf * rl) as f32;
            }
        }
        // p = X T res.
        faer::linalg::matmul::matmul(
            self.p.as_mut(),
            Accum::Replace,
            self.inv.x.as_ref(),
            self.v.as_ref(),
            1.0f32,
            par,
        );
        // Z xi = -B^T p.
        for (e, &[(j0, c0), (j1, c1)]) in self.xi.col_mut(0).iter_mut().zip(&self.b) {
            *e = -(c0 * f64::from(self.p[(j0, 0)]) + c1 * f64::from(self.p[(j1, 0)]));
        }
        solve_lower_then_upper(self.z_l.as_ref(), &mut self.xi);
        for (a, &b) in self.xi32.col_mut(0).iter_mut().zip(self.xi.col(0).iter()) {
            *a = b as f32;
        }
        // lambda = p + W xi.
        faer::linalg::matmul::matmul(
            self.p.as_mut(),
            Accum::Add,
            self.w.as_ref(),
            self.xi32.as_ref(),
            1.0f32,
            par,
        );
        for (u, o) in self.unknowns.iter().zip(out.iter_mut()) {
            *o = u.test[..u.n_test]
                .iter()
                .map(|&(j, cf)| cf * f64::from(self.p[(j, 0)]))
                .sum();
        }
    }
}

/// x := (L L^T)^-1 x for the lower Cholesky factor L.
fn solve_lower_then_upper(l: MatRef<'_, f64>, x: &mut Mat<f64>) {
    let n = l.nrows();
    for j in 0..n {
        let xj = x[(j, 0)] / l[(j, j)];
        x[(j, 0)] = xj;
        let col = l.col(j).subrows(j + 1, n - j - 1);
        for (i, &lij) in col.iter().enumerate() {
            x[(j + 1 + i, 0)] -= lij * xj;
        }
    }
    for j in (0..n).rev() {
        let col = l.col(j).subrows(j + 1, n - j - 1);
        let s: f64 = col
            .iter()
            .enumerate()
            .map(|(i, &lij)| lij * x[(j + 1 + i, 0)])
            .sum();
        x[(j, 0)] = (x[(j, 0)] - s) / l[(j, j)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small SPD A (c = 3 m, d = 3) with off-diagonal coupling.
    fn spd(c: usize) -> Mat<f64> {
        let g = Mat::<f64>::from_fn(c, c, |i, j| (((i * 7 + j * 3) % 11) as f64 - 5.0) / 11.0);
        let mut a = &g * g.transpose();
        for i in 0..c {
            a[(i, i)] += 1.0;
        }
        a
    }

    /// S = T^T A T + Delta formed directly, against the preconditioner's
    /// S^-1: normals free on some contacts, sticking, slipping (a turned
    /// unit test vector with a curvature term) and open contacts.
    #[test]
    fn the_complement_inverts_the_reduced_system() {
        let (m, d) = (6, 3);
        let c = d * m;
        let a = spd(c);
        let ledger = Arc::new(Ledger::default());
        let inv = InverseF32::of(
            c,
            |j| a.col(j).try_as_col_major().unwrap().as_slice(),
            &ledger,
            Par::Seq,
        )
        .expect("SPD");
        let jt = |i: usize| m + (d - 1) * i;
        let unit = |j: usize| Unknown {
            test: [(j, 1.0), (0, 0.0)],
            n_test: 1,
            diag: 0.0,
        };
        let (ct, st) = (0.6f64, 0.8f64);
        let mut unknowns = vec![unit(0), unit(1), unit(2), unit(3)];
        // Contact 0 sticks, contact 1 slips, contacts 2 and 3 are closed
        // with their tangential components fixed, 4 and 5 open.
        unknowns.push(unit(jt(0)));
        unknowns.push(unit(jt(0) + 1));
        unknowns.push(Unknown {
            test: [(jt(1), ct), (jt(1) + 1, st)],
            n_test: 2,
            diag: 0.7,
        });
        let k = unknowns.len();
        let dense_test = |l: usize| {
            let mut t = vec![0.0; c];
            for &(j, v) in &unknowns[l].test[..unknowns[l].n_test] {
                t[j] += v;
            }
            t
        };
        let s = Mat::<f64>::from_fn(k, k, |p, q| {
            let (tp, tq) = (dense_test(p), dense_test(q));
            let mut v = 0.0;
            for i in 0..c {
                for j in 0..c {
                    v += tp[i] * a[(i, j)] * tq[j];
                }
            }
            if p == q {
                v += unknowns[p].diag;
            }
            v
        });
        let mut pre = Complement::new(&inv, &unknowns, m, d, c, Par::Seq).expect("applies");
        // B: the normals of contacts 4 and 5, the tangents of contacts 2-5
        // (two each), contact 1's fixed slip direction, the slip unknown.
        assert_eq!(pre.order(), 2 + 8 + 1 + 1);
        let b: Vec<f64> = (0..k)
            .map(|l| 1.0 + l as f64 * 0.3 - (l % 3) as f64)
            .collect();
        let mut z = vec![0.0; k];
        pre.apply(&b, &mut z);
        let sz = &s * Mat::<f64>::from_fn(k, 1, |i, _| z[i]);
        let err = (0..k)
            .map(|i| (sz[(i, 0)] - b[i]).abs())
            .fold(0.0, f64::max);
        let scale = b.iter().fold(0.0f64, |x, v| x.max(v.abs()));
        assert!(err <= 1e-4 * scale, "S z - b = {err:e}");
        // Too many columns for the bound: None.
        assert!(Complement::new(&inv, &unknowns, m, d, 5, Par::Seq).is_none());
        // A test vector that is not of unit norm: None.
        let mut bad = unknowns.clone();
        bad[6].test[0].1 = 0.5;
        assert!(Complement::new(&inv, &bad, m, d, c, Par::Seq).is_none());
    }
}
