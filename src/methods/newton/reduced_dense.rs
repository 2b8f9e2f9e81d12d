//! The reduced system of a Newton step on a dense dual: Cholesky (in single
//! precision with refinement in double from MIXED_MIN unknowns on); where it
//! is not symmetric, GMRES on the single-precision factor of its symmetric
//! part from MIXED_MIN on, LU below or where GMRES fails; the truncated SVD
//! where it is numerically singular. The single-precision factor is kept to
//! precondition CG or GMRES on the next step's system where the reduced
//! unknowns barely changed (`Reused`). On the warm solves of a 3D dual, a
//! system that leaves few components out is solved without being
//! assembled, on products with A preconditioned by A^-1
//! (`solve_on_inverse`).

use super::*;

/// Singular values below RCOND times the largest are dropped in the reduced solve,
/// and an LU solution z with |M|_max |z|_inf > |rhs|_inf / RCOND is taken as the
/// sign of a (numerically) singular M.
pub(super) const RCOND: f64 = 1e-12;

/// Reduced systems of at least this order are first solved on a Cholesky
/// factor in single precision (of M where M is symmetric, by refinement,
/// `dense::refine`; of M's symmetric part where it is not, by GMRES,
/// `dense::gmres`) to the normwise backward error MIXED_RTOL, that of a
/// Cholesky solve in double; below it the factorisation in double is cheap
/// anyway.
pub(super) const MIXED_MIN: usize = 256;
pub(super) const MIXED_RTOL: f64 = 1e-15;

/// Most CG iterations a reduced solve spends on the last step's factor
/// before it factors its own matrix: an iteration costs about 3 k^2 flops
/// (a product with M in double, two triangular solves in single precision),
/// a factorisation k^3 / 3 at the faster rate of blocked kernels.
pub(super) const REUSE_MAX_IT: usize = 20;

/// The same for GMRES on a non-symmetric M: its preconditioner is the kept
/// factor of an earlier symmetric part, two steps of changes away from M.
pub(super) const REUSE_GMRES_MAX_IT: usize = 30;

pub(super) use crate::dense::Reused;

impl Reused {
    /// Each of `key`'s unknowns' position in the kept factor (None for a new
    /// one); empty when the unknowns are the same, in the same order. None
    /// when more than max(REUSE_MAX_CHANGED, k / REUSE_CHANGED_DIV) unknowns
    /// came or went: bordering them would cost about half a factorisation.
    pub(super) fn positions(&self, key: &[usize]) -> Option<Vec<Option<usize>>> {
        if self.key == key {
            return Some(Vec::new());
        }
        let old: std::collections::HashMap<usize, usize> = self
            .key
            .iter()
            .enumerate()
            .map(|(q, &kq)| (kq, q))
            .collect();
        let pos: Vec<Option<usize>> = key.iter().map(|kj| old.get(kj).copied()).collect();
        let shared = pos.iter().flatten().count();
        let changed = (key.len() - shared) + (self.key.len() - shared);
        (changed <= REUSE_MAX_CHANGED.max(key.len() / REUSE_CHANGED_DIV)).then_some(pos)
    }
}

/// Most reduced unknowns that may come or go between two Newton steps for
/// the second to solve on the first one's factor (see [`Reused`]): at
/// least REUSE_MAX_CHANGED, and up to k / REUSE_CHANGED_DIV. Each costs a
/// pair of triangular solves with the kept factor (2 k^2 flops, in blocks;
/// `dense::kept`), a new factorisation k^3 / 3: at k / 16 the bordering
/// costs under half of it.
pub(super) const REUSE_MAX_CHANGED: usize = 8;
pub(super) const REUSE_CHANGED_DIV: usize = 16;

/// How `solve_reduced` may solve: M's symmetric part where M is not
/// symmetric (its lower entries (i, j), i >= j), the relative residual the
/// iterative solves may stop at (the Newton step's forcing term; 0: to the
/// backward error of a solve in double), the unknowns' key, and the factor
/// kept from the last step (replaced by this step's).
pub(super) struct Reduce<'a> {
    pub(super) sym_part: Option<&'a (dyn Fn(usize, usize) -> f64 + Sync)>,
    pub(super) eta: f64,
    pub(super) key: Vec<usize>,
    pub(super) reused: &'a mut Option<Reused>,
}

/// Most products with M a GMRES solve of a non-symmetric M spends on the
/// single-precision factor of its symmetric part (a new one, or the last
/// step's) before the LU in double: an iteration costs about 3 k^2 flops,
/// the LU 2 k^3 / 3.
pub(super) const GMRES_MAX_IT: usize = 60;

/// Solves the reduced system M z = rhs: on the kept factor where it serves
/// (CG, or GMRES where M is not symmetric), else on a new single-precision
/// factor of M or of its symmetric part (from MIXED_MIN on), else by
/// Cholesky in double when M is symmetric (half the flops of LU), else or
/// when that fails by a partially pivoted LU, unless M is numerically
/// singular (the solution is not finite or much larger than M and rhs warrant),
/// then by the minimum-norm least-squares solution with singular values below
/// RCOND sigma_max dropped. None when no finite solution is found.
pub(super) fn solve_reduced(
    mat: &Mat<f64>,
    rhs: &Mat<f64>,
    how: Reduce<'_>,
    threads: &Threads,
    ledger: &Arc<Ledger>,
) -> Option<Mat<f64>> {
    let Reduce {
        sym_part,
        eta,
        key,
        reused,
    } = how;
    let symmetric = sym_part.is_none();
    let max_abs = |a: faer::MatRef<'_, f64>| {
        let mut v = 0.0f64;
        for j in 0..a.ncols() {
            for i in 0..a.nrows() {
                v = v.max(a[(i, j)].abs());
            }
        }
        v
    };
    let (mn, rn) = (max_abs(mat.as_ref()), max_abs(rhs.as_ref()));
    let acceptable =
        |z: &Mat<f64>| z.as_ref().is_all_finite() && mn * max_abs(z.as_ref()) * RCOND <= rn;
    let big = mat.nrows() * mat.ncols() >= PARALLEL_MIN_ENTRIES;
    let (m, r) = (mat.as_ref(), rhs.as_ref());
    let k2 = mat.nrows() * mat.ncols();
    let rv: Vec<f64> = r.col(0).iter().copied().collect();
    // The last step's factor, where this step has the same unknowns or a few
    // more or fewer: CG preconditioned by it (see REUSE_MAX_IT), GMRES where
    // M is not symmetric (REUSE_GMRES_MAX_IT).
    // The bordering's blocks (Y, S_FN and Z: k0 by the unknowns that went
    // and came) and GMRES's basis (2 GMRES_RESTART + 1 vectors of length k)
    // on the ledger while they are held.
    let basis = if symmetric {
        0
    } else {
        (2 * dense::GMRES_RESTART + 1) * mat.nrows()
    };
    let kept = reused
        .as_ref()
        .and_then(|old| old.positions(&key).map(|pos| (old, pos)));
    if let Some((old, pos)) = kept {
        let shared = pos.iter().flatten().count();
        let changed = (pos.len() - shared) + (old.key.len() - shared);
        let _blocks = ledger.claim_f64(3 * old.llt.order() * changed + basis);
        if let Some(z) = threads.run(big, |par| {
            let pos = (!pos.is_empty()).then_some(&pos[..]);
            match sym_part {
                None => dense::pcg(m, &old.llt, pos, &rv, MIXED_RTOL, eta, REUSE_MAX_IT, par),
                Some(s) => dense::gmres(
                    m,
                    s,
                    &old.llt,
                    pos,
                    &rv,
                    MIXED_RTOL,
                    eta,
                    REUSE_GMRES_MAX_IT,
                    par,
                ),
            }
        }) {
            let z = Mat::from_fn(z.len(), 1, |i, _| z[i]);
            if acceptable(&z) {
                return Some(z);
            }
        }
    }
    // A new factor replaces the old one (never both held: the workspace).
    *reused = None;
    if mat.nrows() >= MIXED_MIN {
        let k = mat.nrows();
        let claim = ledger.claim(k * k * std::mem::size_of::<f32>());
        let factor = |par| match sym_part {
            None => dense::LltF32::of(m, par),
            Some(s) => dense::LltF32::of_entries(k, s, par),
        };
        let _basis = ledger.claim_f64(basis);
        let solve = |llt: &dense::LltF32, par| match sym_part {
            None => dense::refine(m, llt, &rv, MIXED_RTOL, eta, par),
            Some(s) => dense::gmres(m, s, llt, None, &rv, MIXED_RTOL, eta, GMRES_MAX_IT, par),
        };
        if let Some(llt) = threads.run(big, factor)
            && let Some(z) = threads.run(big, |par| solve(&llt, par))
        {
            let z = Mat::from_fn(z.len(), 1, |i, _| z[i]);
            if acceptable(&z) {
                *reused = Some(Reused {
                    key,
                    llt,
                    _claim: claim,
                });
                return Some(z);
            }
        }
    }
    // The double-precision solvers work on a copy of M (the SVD on two k x k
    // factors too); the single-precision factor above is claimed by itself.
    let copy_claim = ledger.claim_f64(k2);
    if symmetric
        && let Some(z) = threads.run(big, |par| dense::llt_solve(m, r, par))
        && acceptable(&z)
    {
        return Some(z);
    }
    if let Some(z) = threads.run(big, |par| dense::lu_solve(m, r, par))
        && acceptable(&z)
    {
        return Some(z);
    }
    drop(copy_claim);
    let _svd_claim = ledger.claim_f64(3 * k2);
    let (u, sv, v) = threads.run(big, |par| dense::thin_svd(m, par))?;
    let smax = sv.iter().fold(0.0f64, |a, &s| a.max(s));
    let mut z = Mat::<f64>::zeros(mat.ncols(), 1);
    for l in 0..sv.len() {
        if sv[l] > RCOND * smax {
            let coef = (0..u.nrows()).map(|r| u[(r, l)] * rhs[(r, 0)]).sum::<f64>() / sv[l];
            for r in 0..v.nrows() {
                z[(r, 0)] += coef * v[(r, l)];
            }
        }
    }
    z.as_ref().is_all_finite().then_some(z)
}

/// Solves the reduced system M z = rhs of the unknowns `red` (M = T^T A V +
/// diag, never assembled: each product is one with A) by CG where M is
/// symmetric, else GMRES, preconditioned by A's inverse through the
/// components the unknowns leave out (`dense::Complement`), with
/// [`solve_reduced`]'s stopping tests (`eta` the relative residual, 0 for
/// the backward error of a solve in double). None where the preconditioner
/// does not apply (more than k / 2 columns in its bordered system) or the
/// iteration fails: the caller assembles M and solves it so.
pub(super) fn solve_on_inverse(
    dual: &crate::dual::Dual,
    inv: &dense::InverseF32,
    red: &[Reduced],
    rhs: &[f64],
    symmetric: bool,
    eta: f64,
) -> Option<Vec<f64>> {
    let (c, k) = (dual.c, red.len());
    let unknowns: Vec<dense::Unknown> = red
        .iter()
        .map(|u| dense::Unknown {
            test: u.test,
            n_test: u.n_test,
            diag: u.diag,
        })
        .collect();
    // |M|_inf from above: a row's test entries times their rows of |A|,
    // times the largest 1-norm of a direction, plus its diagonal term. An
    // upper bound because no component lies in the directions of two
    // unknowns with more than that 1-norm between them (`linearise`: unit
    // vectors, a slip pair, a Coulomb normal's e_N + mu n), so that V's
    // row sums of |V| are at most it.
    let rows = inv.abs_row_sums();
    let dir_max = red
        .iter()
        .map(|u| u.dir[..u.n_dir].iter().map(|&(_, v)| v.abs()).sum::<f64>())
        .fold(0.0f64, f64::max);
    let m_inf = red
        .iter()
        .map(|u| {
            u.test[..u.n_test]
                .iter()
                .map(|&(j, v)| v.abs() * rows[j])
                .sum::<f64>()
                * dir_max
                + u.diag
        })
        .fold(0.0f64, f64::max);
    let q = k / 2;
    let ledger = &dual.ledger;
    let basis = if symmetric {
        0
    } else {
        (2 * dense::GMRES_RESTART + 1) * k
    };
    let _work = ledger.claim(c * q * std::mem::size_of::<f32>() + (q * q + 2 * c + basis) * F64);
    let (mut v, mut av) = (vec![0.0; c], vec![0.0; c]);
    let (a, threads, m, d) = (&dual.a[..], &*dual.threads, dual.m, dual.d);
    let mut op = |x: &[f64], y: &mut [f64]| {
        v.iter_mut().for_each(|e| *e = 0.0);
        add_directions(red, x.iter().copied(), &mut v);
        crate::dual::leading_block_apply(a, c, &v, &mut av, threads);
        for ((u, &xl), yl) in red.iter().zip(x).zip(y.iter_mut()) {
            *yl = u.diag * xl + u.test_dot(&av);
        }
    };
    let big = c * c >= PARALLEL_MIN_ENTRIES;
    let z = threads.run(big, |par| {
        let mut pre = dense::Complement::new(inv, &unknowns, m, d, q, par)?;
        if symmetric {
            dense::pcg_with(&mut op, m_inf, &mut pre, rhs, MIXED_RTOL, eta, REUSE_MAX_IT)
        } else {
            dense::gmres_with(
                &mut op,
                m_inf,
                &mut pre,
                rhs,
                MIXED_RTOL,
                eta,
                REUSE_GMRES_MAX_IT,
            )
        }
    })?;
    z.iter().all(|v| v.is_finite()).then_some(z)
}
