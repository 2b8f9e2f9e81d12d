//! A symmetric K with new values on a known pattern: a host's coordinate
//! (COO) tangent at every iteration of its Newton loop, with the triplets
//! of the K a handle already holds. Converting it in full sorts and sums
//! millions of triplets (on a 3D H8 mesh of 34,000 DOFs, 6.2 million: about
//! half a factorisation); on a known pattern each triplet is placed by a
//! binary search in its column.

use super::validate::{check_base, check_symmetric, index0};
use super::{Csc, Format, MatrixView, Storage};

impl Csc {
    /// The symmetric matrix of `view` (COO, any storage) where it has
    /// exactly `self`'s pattern (`self` a symmetric matrix in internal form,
    /// both triangles): every triplet falls on it, every entry of it is
    /// met, and the result is what [`Csc::symmetric_from_view`] returns
    /// (duplicates summed in the given order, then the mirrored triangle).
    /// None where the view is of another format or anything is amiss (an
    /// index out of range or off the pattern, an entry missing, a value not
    /// finite, K not symmetric): the full conversion then gives the matrix
    /// or the error.
    pub(crate) fn refill_symmetric(&self, view: &MatrixView<'_>) -> Option<Csc> {
        let n = self.nrows;
        if view.format != Format::Coo || view.nrows != n || view.ncols != n {
            return None;
        }
        let base = check_base(view, "K").ok()?;
        let len = view.i.len();
        if view.p.len() != len || view.x.len() != len {
            return None;
        }
        let mut values = vec![0.0; self.values.len()];
        let mut met = vec![false; self.values.len()];
        let (upper, lower) = match view.storage {
            Storage::Full => (false, false),
            Storage::Upper => (true, false),
            Storage::Lower => (false, true),
        };
        // The stored triplets, then (one triangle given) their mirrors: the
        // order in which the full conversion sums them.
        for mirror in [false, true] {
            if mirror && !(upper || lower) {
                break;
            }
            for k in 0..len {
                let r = index0(view.i.get(k), base, n)?;
                let c = index0(view.p.get(k), base, n)?;
                let x = view.x[k];
                if !x.is_finite() || (upper && r > c) || (lower && r < c) {
                    return None;
                }
                let (r, c) = match mirror {
                    false => (r, c),
                    true if r != c => (c, r),
                    true => continue,
                };
                let (lo, hi) = (self.col_ptr[c], self.col_ptr[c + 1]);
                let q = lo + self.row_idx[lo..hi].binary_search(&r).ok()?;
                values[q] = if met[q] { values[q] + x } else { x };
                met[q] = true;
            }
        }
        if met.iter().any(|&m| !m) || values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let a = Csc {
            nrows: n,
            ncols: n,
            col_ptr: self.col_ptr.clone(),
            row_idx: self.row_idx.clone(),
            values,
        };
        if !(upper || lower) {
            check_symmetric(&a, "K", base).ok()?;
        }
        Some(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sparse::Indices;

    /// COO arrays: rows, columns, values.
    type Arrays = (Vec<i64>, Vec<i64>, Vec<f64>);

    /// A symmetric 6 x 6 pattern (a 1D chain with a long link), as
    /// triplets (row, column, value) in both triangles, with duplicates:
    /// an assembly of element matrices in a host's order.
    fn triplets(scale: f64) -> Vec<(i64, i64, f64)> {
        let mut t = Vec::new();
        let links = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (0, 5), (1, 2)];
        for (e, &(a, b)) in links.iter().enumerate() {
            let k = scale * (1.0 + 0.1 * e as f64);
            t.extend([(a, a, k), (b, b, k), (a, b, -0.5 * k), (b, a, -0.5 * k)]);
        }
        t
    }

    fn coo<'a>(t: &'a [Arrays], storage: Storage, base: usize) -> MatrixView<'a> {
        let (i, p, x) = &t[0];
        MatrixView {
            format: Format::Coo,
            storage,
            base,
            nrows: 6,
            ncols: 6,
            p: Indices::I64(p),
            i: Indices::I64(i),
            x,
        }
    }

    /// The triplets of `storage` (Upper keeps r <= c) shifted to `base`.
    fn arrays(
        t: &[(i64, i64, f64)],
        storage: Storage,
        base: i64,
    ) -> (Vec<i64>, Vec<i64>, Vec<f64>) {
        let keep = |r: i64, c: i64| match storage {
            Storage::Full => true,
            Storage::Upper => r <= c,
            Storage::Lower => r >= c,
        };
        let kept: Vec<_> = t.iter().filter(|(r, c, _)| keep(*r, *c)).collect();
        (
            kept.iter().map(|(r, _, _)| r + base).collect(),
            kept.iter().map(|(_, c, _)| c + base).collect(),
            kept.iter().map(|(_, _, x)| *x).collect(),
        )
    }

    #[test]
    fn a_refill_is_the_full_conversion_bit_for_bit() {
        for storage in [Storage::Full, Storage::Upper, Storage::Lower] {
            for base in [0, 1] {
                let old = [arrays(&triplets(1.0), storage, base as i64)];
                let k0 = Csc::symmetric_from_view(&coo(&old, storage, base), "K").unwrap();
                let new = [arrays(&triplets(1.7), storage, base as i64)];
                let view = coo(&new, storage, base);
                let want = Csc::symmetric_from_view(&view, "K").unwrap();
                let got = k0.refill_symmetric(&view).expect("the same pattern");
                assert_eq!(got.col_ptr, want.col_ptr);
                assert_eq!(got.row_idx, want.row_idx);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&got.values),
                    bits(&want.values),
                    "{storage:?}, base {base}"
                );
            }
        }
    }

    #[test]
    fn anything_amiss_is_left_to_the_full_conversion() {
        let t = triplets(1.0);
        let old = [arrays(&t, Storage::Full, 0)];
        let k0 = Csc::symmetric_from_view(&coo(&old, Storage::Full, 0), "K").unwrap();
        let refill = |edit: &dyn Fn(&mut Arrays)| {
            let mut a = arrays(&t, Storage::Full, 0);
            edit(&mut a);
            let arrs = [a];
            k0.refill_symmetric(&coo(&arrs, Storage::Full, 0))
        };
        assert!(refill(&|_| {}).is_some());
        // An entry off the pattern (0, 3) and its mirror.
        assert!(
            refill(&|a| {
                a.0.extend([0, 3]);
                a.1.extend([3, 0]);
                a.2.extend([0.1, 0.1]);
            })
            .is_none()
        );
        // An entry of the pattern missing: (0, 5) and (5, 0) dropped.
        assert!(
            refill(&|a| {
                let keep: Vec<bool> = (0..a.0.len())
                    .map(|k| !matches!((a.0[k], a.1[k]), (0, 5) | (5, 0)))
                    .collect();
                for v in [&mut a.0, &mut a.1] {
                    let mut it = keep.iter();
                    v.retain(|_| *it.next().unwrap());
                }
                let mut it = keep.iter();
                a.2.retain(|_| *it.next().unwrap());
            })
            .is_none()
        );
        // Not finite, out of range, not symmetric, unequal lengths.
        assert!(refill(&|a| a.2[3] = f64::NAN).is_none());
        assert!(refill(&|a| a.0[0] = 6).is_none());
        assert!(refill(&|a| a.2[2] += 1.0).is_none());
        assert!(
            refill(&|a| {
                a.2.pop();
            })
            .is_none()
        );
    }
}
