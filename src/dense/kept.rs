//! The preconditioner of a solve on a factor kept from an earlier matrix (a
//! Newton step's reduced system solved on the last step's factor, see
//! [`super::pcg`] and [`super::gmres`]): the kept matrix S0 restricted to the
//! unknowns both matrices share, bordered by the unknowns that are new.
//!
//! With F the shared unknowns, R those S0 has and M no longer has, N the new
//! ones, and S the symmetric matrix M's solve is preconditioned for (M
//! itself where M is symmetric; for a Newton step's reduced system that is
//! not, W^T A W + D, each direction cut to its test vector):
//!
//! ```text
//! X   = (S0_FF)^-1 = (S0^-1)_FF - Y_F C^-1 Y_F^T,   Y = S0^-1 E_R, C = Y_R,
//! Z   = X S_FN,   Sigma = S_NN - S_NF Z,
//! P   = [X + Z Sigma^-1 Z^T, -Z Sigma^-1; -Sigma^-1 Z^T, Sigma^-1],
//! ```
//!
//! the inverse of [S0_FF S_FN; S_NF S_NN] by blocks: exact where M's entries
//! on F are still S0's, so that the Krylov iterations only pay for the
//! entries that changed (slip directions turning), not for the unknowns that
//! came or went. Setting it up costs |R| + |N| pairs of triangular solves
//! with the kept factor (k0^2 flops each) and Sigma's |N|^2 k0 instead of a
//! new factorisation (k^3 / 3). Where S_FF has moved so far from S0_FF that Sigma is not
//! positive definite, the new unknowns are preconditioned by S's diagonal
//! alone.

use super::{LltF32, cholesky_in_place};
use crate::memory::try_mat;
use faer::dyn_stack::MemBuffer;
use faer::{Mat, Par};

/// The preconditioner of the module docs, with its scratch (no allocation
/// per application).
pub(super) struct Bordered<'a> {
    l: &'a LltF32,
    /// M's unknown j sits at S0's position `pos[j]` (None: a new one); None:
    /// the same unknowns in the same order.
    pos: Option<&'a [Option<usize>]>,
    /// R as S0's positions; Y (k0 x |R|) and C's Cholesky factor.
    removed: Vec<usize>,
    y: Mat<f64>,
    c_l: Mat<f64>,
    /// N as M's indices; S_FN at S0's positions (k0 x |N|, zero on R), Z
    /// likewise, and Sigma's Cholesky factor; `bordered` false (S_FN and Z
    /// empty) where Sigma was not positive definite and its factor is that
    /// of S's diagonal on N.
    new: Vec<usize>,
    bordered: bool,
    s_fn: Mat<f64>,
    z: Mat<f64>,
    sigma_l: Mat<f64>,
    corr: Mat<f32>,
    mem: MemBuffer,
    u: Vec<f64>,
    u2: Vec<f64>,
    t: Vec<f64>,
    tn: Vec<f64>,
    par: Par,
}

impl<'a> Bordered<'a> {
    /// The preconditioner for M of order n on `l`, S0's factor; `sym(i, j)`
    /// (i >= j) reads S's lower entries (only those of the new unknowns'
    /// rows and columns are read). None where `pos` does not fit n and S0's
    /// order, where C is not numerically positive definite, or where Sigma
    /// is not and S's diagonal on N is not positive either (then the caller
    /// factors M's own matrix).
    pub(super) fn new(
        l: &'a LltF32,
        pos: Option<&'a [Option<usize>]>,
        n: usize,
        sym: &dyn Fn(usize, usize) -> f64,
        par: Par,
    ) -> Option<Self> {
        let k0 = l.order();
        let (removed, new) = match pos {
            None if k0 != n => return None,
            None => (Vec::new(), Vec::new()),
            Some(pos) => {
                if pos.len() != n || pos.iter().flatten().any(|&q| q >= k0) {
                    return None;
                }
                let mut kept = vec![false; k0];
                for &q in pos.iter().flatten() {
                    if std::mem::replace(&mut kept[q], true) {
                        return None;
                    }
                }
                let removed: Vec<usize> = (0..k0).filter(|&q| !kept[q]).collect();
                let new: Vec<usize> = (0..n).filter(|&j| pos[j].is_none()).collect();
                (removed, new)
            }
        };
        let (rho, nu) = (removed.len(), new.len());
        let (corr, mem) = l.scratch(par);
        let mut me = Bordered {
            l,
            pos,
            removed,
            y: Mat::zeros(0, 0),
            c_l: Mat::zeros(0, 0),
            new,
            bordered: false,
            s_fn: Mat::zeros(0, 0),
            z: Mat::zeros(0, 0),
            sigma_l: Mat::zeros(0, 0),
            corr,
            mem,
            u: vec![0.0; k0],
            u2: vec![0.0; k0],
            t: vec![0.0; rho],
            tn: vec![0.0; nu],
            par,
        };
        if rho > 0 {
            let mut e = try_mat::<f64>(k0, rho, "").ok()?;
            for (a, &q) in me.removed.iter().enumerate() {
                e[(q, a)] = 1.0;
            }
            me.y = l.solve_cols(e.as_ref(), par)?;
            let mut c = try_mat::<f64>(rho, rho, "").ok()?;
            for a in 0..rho {
                for b in 0..rho {
                    c[(a, b)] = 0.5 * (me.y[(me.removed[a], b)] + me.y[(me.removed[b], a)]);
                }
            }
            cholesky_in_place(c.as_mut(), par)?;
            me.c_l = c;
        }
        if nu > 0 {
            let pos = pos.expect("new unknowns come with positions");
            let entry = |i: usize, j: usize| if i >= j { sym(i, j) } else { sym(j, i) };
            let mut s_fn = try_mat::<f64>(k0, nu, "").ok()?;
            for (a, &jn) in me.new.iter().enumerate() {
                for (j, q) in pos.iter().enumerate() {
                    if let Some(q) = *q {
                        s_fn[(q, a)] = entry(j, jn);
                    }
                }
            }
            // Z = X S_FN: S0^-1 S_FN, then the removed unknowns taken out.
            let mut z = l.solve_cols(s_fn.as_ref(), par)?;
            for a in 0..nu {
                let col = z.col_mut(a).try_as_col_major_mut().expect("contiguous");
                me.take_out_removed(col.as_slice_mut());
            }
            let mut sigma = try_mat::<f64>(nu, nu, "").ok()?;
            for a in 0..nu {
                for b in 0..=a {
                    let dot = |p: usize, q: usize| -> f64 {
                        s_fn.col(p)
                            .iter()
                            .zip(z.col(q).iter())
                            .map(|(x, y)| x * y)
                            .sum()
                    };
                    let v = entry(me.new[a], me.new[b]) - 0.5 * (dot(a, b) + dot(b, a));
                    sigma[(a, b)] = v;
                    sigma[(b, a)] = v;
                }
            }
            if cholesky_in_place(sigma.as_mut(), par).is_some() {
                me.s_fn = s_fn;
                me.z = z;
                me.sigma_l = sigma;
                me.bordered = true;
            } else {
                // Sigma is not positive definite where S_FF has moved far
                // from S0_FF: the new unknowns then go on S's diagonal alone
                // (S_FN, Z = 0 and Sigma = diag S_NN; positive definite).
                let mut diag = try_mat::<f64>(nu, nu, "").ok()?;
                for (a, &jn) in me.new.iter().enumerate() {
                    let v = entry(jn, jn);
                    if v.is_nan() || v <= 0.0 {
                        return None;
                    }
                    diag[(a, a)] = v.sqrt();
                }
                me.sigma_l = diag;
            }
        }
        Some(me)
    }

    /// u := u - Y C^-1 u_R: S0^-1 applied to a vector zero on R becomes
    /// (S0_FF)^-1 applied to it (its R part then vanishes up to rounding).
    fn take_out_removed(&mut self, u: &mut [f64]) {
        if self.removed.is_empty() {
            return;
        }
        for (t, &q) in self.t.iter_mut().zip(&self.removed) {
            *t = u[q];
        }
        chol_solve(&self.c_l, &mut self.t);
        for (a, &ta) in self.t.iter().enumerate() {
            for (ui, &ya) in u.iter_mut().zip(self.y.col(a).iter()) {
                *ui -= ta * ya;
            }
        }
    }

    /// out := P res (the module docs' P, in M's unknowns).
    pub(super) fn apply(&mut self, res: &[f64], out: &mut [f64]) {
        let Some(pos) = self.pos else {
            self.l
                .apply(res, out, &mut self.corr, &mut self.mem, self.par);
            return;
        };
        self.u2.iter_mut().for_each(|v| *v = 0.0);
        for (j, q) in pos.iter().enumerate() {
            if let Some(q) = *q {
                self.u2[q] = res[j];
            }
        }
        let mut u = std::mem::take(&mut self.u);
        self.l
            .apply(&self.u2, &mut u, &mut self.corr, &mut self.mem, self.par);
        self.take_out_removed(&mut u);
        if !self.new.is_empty() {
            // Sigma^-1 (res_N - S_NF u), then u -= Z of it.
            for (a, &jn) in self.new.iter().enumerate() {
                self.tn[a] = res[jn];
                if self.bordered {
                    let su: f64 = self.s_fn.col(a).iter().zip(&u).map(|(s, x)| s * x).sum();
                    self.tn[a] -= su;
                }
            }
            chol_solve(&self.sigma_l, &mut self.tn);
            for (a, &ta) in self.tn.iter().enumerate() {
                if self.bordered {
                    for (ui, &za) in u.iter_mut().zip(self.z.col(a).iter()) {
                        *ui -= ta * za;
                    }
                }
                out[self.new[a]] = ta;
            }
        }
        for (j, q) in pos.iter().enumerate() {
            if let Some(q) = *q {
                out[j] = u[q];
            }
        }
        self.u = u;
    }
}

/// x := (L L^T)^-1 x with L the lower triangle of `l` (a small factor:
/// forward and back substitution).
fn chol_solve(l: &Mat<f64>, x: &mut [f64]) {
    let n = x.len();
    for i in 0..n {
        let mut s = x[i];
        for k in 0..i {
            s -= l[(i, k)] * x[k];
        }
        x[i] = s / l[(i, i)];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= l[(k, i)] * x[k];
        }
        x[i] = s / l[(i, i)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::MatRef;

    /// The bordered preconditioner of a kept factor on unknowns that came and
    /// went is the inverse of the new matrix when the shared entries are the
    /// kept matrix's: applied to M x it gives x back.
    #[test]
    fn bordered_is_the_inverse_where_the_shared_entries_are_kept() {
        let k = 40;
        let e = |a: usize, b: usize| {
            if a == b {
                4.0 + (a % 7) as f64
            } else {
                1.0 / (1.0 + (a as f64 - b as f64).abs()).powi(2)
            }
        };
        let old: Vec<usize> = (0..k).collect();
        // Keys 0 and 7 gone, 40 new in the middle of the order, 41 at its end.
        let new: Vec<usize> = (1..20)
            .filter(|&a| a != 7)
            .chain([k])
            .chain(20..k)
            .chain([k + 1])
            .collect();
        let m0 = Mat::from_fn(k, k, |i, j| e(old[i], old[j]));
        let l0 = LltF32::of(m0.as_ref(), Par::Seq).unwrap();
        let n = new.len();
        let m = Mat::from_fn(n, n, |i, j| e(new[i], new[j]));
        let pos: Vec<Option<usize>> = new
            .iter()
            .map(|a| old.iter().position(|b| b == a))
            .collect();
        let sym = |i: usize, j: usize| m[(i, j)];
        let mut p = Bordered::new(&l0, Some(&pos), n, &sym, Par::Seq).expect("SPD");
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).cos()).collect();
        let xm = MatRef::from_column_major_slice(&x, n, 1);
        let mx = &m * xm;
        let r: Vec<f64> = mx.col(0).iter().copied().collect();
        let mut y = vec![0.0; n];
        p.apply(&r, &mut y);
        let err = y
            .iter()
            .zip(&x)
            .fold(0.0f64, |a, (p, q)| a.max((p - q).abs()));
        assert!(err <= 1e-5, "{err}");
    }

    /// Where the shared block has moved far from the kept one (here by
    /// 50 w w^T), Sigma is not positive definite: the new unknowns go on
    /// the diagonal, and the preconditioner is still symmetric positive
    /// definite (x^T P x > 0 and P symmetric on probes).
    #[test]
    fn a_sigma_that_is_not_positive_definite_leaves_the_new_unknowns_on_the_diagonal() {
        let k = 40;
        let e = |a: usize, b: usize| {
            if a == b {
                4.0 + (a % 7) as f64
            } else {
                1.0 / (1.0 + (a as f64 - b as f64).abs()).powi(2)
            }
        };
        let w = |a: usize| ((a as f64) * 0.3 + 0.5).sin();
        let moved = |a: usize, b: usize| e(a, b) + 50.0 * w(a) * w(b);
        let old: Vec<usize> = (0..k).collect();
        let new: Vec<usize> = (1..k).chain([k]).collect();
        let m0 = Mat::from_fn(k, k, |i, j| e(old[i], old[j]));
        let l0 = LltF32::of(m0.as_ref(), Par::Seq).unwrap();
        let n = new.len();
        let m = Mat::from_fn(n, n, |i, j| moved(new[i], new[j]));
        let pos: Vec<Option<usize>> = new
            .iter()
            .map(|a| old.iter().position(|b| b == a))
            .collect();
        let sym = |i: usize, j: usize| m[(i, j)];
        let mut p = Bordered::new(&l0, Some(&pos), n, &sym, Par::Seq).expect("diagonal");
        assert!(!p.bordered, "Sigma should not be positive definite here");
        let probe = |t: usize| -> Vec<f64> {
            (0..n)
                .map(|i| ((i * (t + 2)) as f64 * 0.17).sin())
                .collect()
        };
        let (x, y) = (probe(0), probe(1));
        let (mut px, mut py) = (vec![0.0; n], vec![0.0; n]);
        p.apply(&x, &mut px);
        p.apply(&y, &mut py);
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>();
        assert!(dot(&x, &px) > 0.0);
        let (a, b) = (dot(&y, &px), dot(&x, &py));
        assert!((a - b).abs() <= 1e-5 * a.abs().max(b.abs()), "{a} {b}");
        // The new unknown's output is its input over S's diagonal.
        let mut unit = vec![0.0; n];
        unit[n - 1] = 1.0;
        let mut pu = vec![0.0; n];
        p.apply(&unit, &mut pu);
        assert!((pu[n - 1] - 1.0 / m[(n - 1, n - 1)]).abs() <= 1e-12);
    }
}
