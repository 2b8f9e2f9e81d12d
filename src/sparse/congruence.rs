//! G = B K B^T for a sparse B (c x n) and a sparse symmetric K (n x n, both
//! triangles stored), column by column: column r of G is B (K b_r), b_r the r-th
//! row of B. Nothing dense beyond three work vectors of length n and c.

use super::Csc;

/// Visits the columns of B K B^T in order: `each(rows, col)` gets a column's
/// row indices (sorted) and the dense column they index.
fn columns(k: &Csc, b: &Csc, bt: &Csc, mut each: impl FnMut(&[usize], &[f64])) {
    let (n, c) = (k.nrows, b.nrows);
    let mut kb = vec![0.0; n];
    let mut mark = vec![false; n];
    let mut touched = Vec::new();
    let mut col = vec![0.0; c];
    let mut in_col = vec![false; c];
    let mut rows = Vec::new();
    for r in 0..bt.ncols {
        for p in bt.col_ptr[r]..bt.col_ptr[r + 1] {
            let (j, v) = (bt.row_idx[p], bt.values[p]);
            for q in k.col_ptr[j]..k.col_ptr[j + 1] {
                let i = k.row_idx[q];
                if !mark[i] {
                    mark[i] = true;
                    touched.push(i);
                }
                kb[i] += k.values[q] * v;
            }
        }
        for &i in &touched {
            for p in b.col_ptr[i]..b.col_ptr[i + 1] {
                let q = b.row_idx[p];
                if !in_col[q] {
                    in_col[q] = true;
                    rows.push(q);
                }
                col[q] += b.values[p] * kb[i];
            }
            kb[i] = 0.0;
            mark[i] = false;
        }
        touched.clear();
        rows.sort_unstable();
        each(&rows, &col);
        for &q in &rows {
            col[q] = 0.0;
            in_col[q] = false;
        }
        rows.clear();
    }
}

/// B K B^T (c x c), `bt` = B^T.
pub(crate) fn congruence(k: &Csc, b: &Csc, bt: &Csc) -> Csc {
    let c = b.nrows;
    let mut g = Csc {
        nrows: c,
        ncols: c,
        col_ptr: Vec::with_capacity(c + 1),
        row_idx: Vec::new(),
        values: Vec::new(),
    };
    g.col_ptr.push(0);
    columns(k, b, bt, |rows, col| {
        g.row_idx.extend_from_slice(rows);
        g.values.extend(rows.iter().map(|&q| col[q]));
        g.col_ptr.push(g.row_idx.len());
    });
    g
}

/// Bytes of [`congruence`]'s result, without keeping it.
pub(crate) fn congruence_bytes(k: &Csc, b: &Csc, bt: &Csc) -> usize {
    let mut nnz = 0;
    columns(k, b, bt, |rows, _| nnz += rows.len());
    (b.nrows + 1) * std::mem::size_of::<usize>()
        + nnz * (std::mem::size_of::<usize>() + std::mem::size_of::<f64>())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the dense product B K B^T on a small case with a repeated DOF,
    /// an empty row of B and a K with off-diagonal couplings.
    #[test]
    fn congruence_is_the_dense_product() {
        let n = 6;
        let mut kt = Vec::new();
        for i in 0..n {
            kt.push((i, i, 4.0 + i as f64));
            if i + 2 < n {
                kt.push((i, i + 2, -1.5));
                kt.push((i + 2, i, -1.5));
            }
        }
        let k = Csc::from_triplets(n, n, &kt);
        let bt_trip = [
            (0, 0, 1.0),
            (0, 3, -0.5),
            (1, 2, 2.0),
            (3, 5, 1.0),
            (3, 0, 0.25),
        ];
        let b = Csc::from_triplets(4, n, &bt_trip);
        let g = congruence(&k, &b, &b.transpose());
        let dense = |m: &Csc| {
            let mut d = vec![0.0; m.nrows * m.ncols];
            for j in 0..m.ncols {
                for p in m.col_ptr[j]..m.col_ptr[j + 1] {
                    d[m.row_idx[p] + j * m.nrows] = m.values[p];
                }
            }
            d
        };
        let (kd, bd) = (dense(&k), dense(&b));
        for r in 0..4 {
            for q in 0..4 {
                let mut want = 0.0;
                for i in 0..n {
                    for j in 0..n {
                        want += bd[r + i * 4] * kd[i + j * n] * bd[q + j * 4];
                    }
                }
                let got = dense(&g)[r + q * 4];
                assert!((got - want).abs() <= 1e-14, "({r},{q}): {got} vs {want}");
            }
        }
        // Row 2 of B is empty: its row and column of G hold nothing.
        assert!(g.col_ptr[3] == g.col_ptr[2]);
        assert!(congruence_bytes(&k, &b, &b.transpose()) == g.bytes());
    }
}
