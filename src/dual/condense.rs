//! The two dense condensations A = B K^-1 B^T: by blocks of solves with K's
//! factor, or from the inverse of the factor's trailing block where the
//! contact DOFs were ordered last.

use super::*;

/// A := B K^-1 B^T by blocks of solves with K's factor (c x c, column-major).
/// Errors: `OutOfMemory` when the block of right-hand sides cannot be allocated.
pub(super) fn a_by_solves(factor: &Factor, b: &Csc, a: &mut [f64]) -> Result<()> {
    let (ndof, c) = (factor.n(), b.nrows);
    let bt = b.transpose();
    let width = BLOCK.min(c.max(1));
    let _work = factor
        .ledger()
        .claim(ndof * width * F64 + factor.solve_scratch(width).size_bytes());
    let what = "the block of solves forming A";
    let mut rhs = try_mat(ndof, width, what)?;
    let mut mem = try_scratch(factor.solve_scratch(width), what)?;
    let mut col = vec![0.0; c];
    let mut j0 = 0;
    while j0 < c {
        let w = width.min(c - j0);
        rhs.fill(0.0);
        for jj in 0..w {
            let j = j0 + jj;
            for k in bt.col_ptr[j]..bt.col_ptr[j + 1] {
                rhs[(bt.row_idx[k], jj)] = bt.values[k];
            }
        }
        factor.solve_in_place(rhs.as_mut().subcols_mut(0, w), MemStack::new(&mut mem));
        for jj in 0..w {
            let z = rhs
                .col(jj)
                .try_as_col_major()
                .expect("contiguous")
                .as_slice();
            b.mul_vec(z, &mut col);
            a[(j0 + jj) * c..(j0 + jj + 1) * c].copy_from_slice(&col);
        }
        j0 += w;
    }
    Ok(())
}

/// A := B_C S_CC^-1 B_C^T, with S_CC = L_CC L_CC^T the Schur complement of K onto
/// the trailing DOFs C (L_CC the factor's trailing block).
///
/// S_CC^-1 = L_CC^-T L_CC^-1 costs nc^3 / 3 + nc^3 / 3 flops (triangular inverse and
/// a triangular product, faer's `llt::inverse`); the sandwich with the sparse B_C
/// then costs O(nc c r) with r the nonzeros per row of B (1 to d). Forming
/// W = L_CC^-1 B_C^T and W^T W instead costs about nc c^2 + c^2 nc flops.
///
/// Errors: `OutOfMemory` when the nc x nc blocks cannot be allocated.
pub(super) fn a_from_trailing_block(factor: &Factor, b: &Csc, a: &mut [f64]) -> Result<()> {
    let c = b.nrows;
    let last = factor.last();
    let nc = last.len();
    let mut pos = vec![usize::MAX; factor.n()];
    for (q, &j) in last.iter().enumerate() {
        pos[j] = q;
    }
    let l_claim = factor.ledger().claim_f64(nc * nc);
    let l = factor.trailing_block()?;
    let _x_claim = factor.ledger().claim_f64(nc * nc);
    let what = "the inverse of the trailing block";
    let mut x = try_mat(nc, nc, what)?;
    // On the problem's threads: the inverse is dense c^3/3 work (the sparse
    // factorisation decides for itself, see `Factor::tree_plan`).
    factor
        .threads()
        .run(nc * nc >= PARALLEL_MIN_ENTRIES, |par| {
            let mut mem = try_scratch(llt_inverse::inverse_scratch::<f64>(nc, par), what)?;
            llt_inverse::inverse(x.as_mut(), l.as_ref(), par, MemStack::new(&mut mem));
            Ok::<(), crate::Error>(())
        })?;
    drop(l);
    drop(l_claim);
    // Only the lower triangle of X = S_CC^-1 is written: mirror it, by tiles so
    // that both the reads and the writes stay in cache.
    const TILE: usize = 64;
    for j0 in (0..nc).step_by(TILE) {
        for i0 in (j0..nc).step_by(TILE) {
            for j in j0..(j0 + TILE).min(nc) {
                for i in i0.max(j + 1)..(i0 + TILE).min(nc) {
                    x[(j, i)] = x[(i, j)];
                }
            }
        }
    }
    // B^T by rows of B: row r of B lists (trailing position, value).
    let bt = b.transpose();
    let mut y = vec![0.0; nc];
    for r in 0..c {
        // y = X B_C^T e_r = sum over the nonzeros of row r of X's columns.
        y.iter_mut().for_each(|v| *v = 0.0);
        for k in bt.col_ptr[r]..bt.col_ptr[r + 1] {
            let q = pos[bt.row_idx[k]];
            let w = bt.values[k];
            let xq = x.col(q).try_as_col_major().expect("contiguous").as_slice();
            for (yi, xi) in y.iter_mut().zip(xq) {
                *yi += w * xi;
            }
        }
        // Column r of A = B_C y.
        let col = &mut a[r * c..(r + 1) * c];
        col.iter_mut().for_each(|v| *v = 0.0);
        for &j in last {
            let yj = y[pos[j]];
            if yj != 0.0 {
                for k in b.col_ptr[j]..b.col_ptr[j + 1] {
                    col[b.row_idx[k]] += b.values[k] * yj;
                }
            }
        }
    }
    Ok(())
}
