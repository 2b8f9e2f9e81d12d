//! A symmetric K with new values on a known pattern: a host's coordinate
//! (COO) tangent at every iteration of its Newton loop, with the triplets
//! of the K a handle already holds. Converting it in full sorts and sums
//! millions of triplets (on a 3D H8 mesh of 34,000 DOFs, 6.2 million: about
//! half a factorisation); on a known pattern each triplet is placed by a
//! binary search in its column, or, where the host sends its triplets in the
//! order of its last refill, at the slot it fell on then ([`TripletSlots`]),
//! each triplet then checked against its slot alone; a K in full storage is
//! checked for symmetry pair by pair at the mirror places of the pattern,
//! found once. A CSC K on the held pattern (a host's own compressed
//! tangent) is compared with it and its values copied: no index arrays
//! made anew, no sort, no symmetry walk through the pattern.

use super::validate::{check_base, check_symmetric, index0};
use super::{Csc, Format, Indices, MatrixView, Storage};
use crate::memory::{Claim, Ledger};
use std::sync::Arc;

/// Where each triplet of a host's COO K fell in the held pattern at the
/// last refill (stored triplets first, then their mirrors where one
/// triangle is given): a guess, checked triplet by triplet (the slot must
/// lie in the triplet's column and hold its row), so a host that reorders
/// or changes its triplets costs a binary search again, never a misplaced
/// value. A host that assembles its tangent in a fixed order (every FE
/// code's element loop) places each triplet in O(1): 3D H8 tangents of 2.4
/// million triplets in about a sixth of the binary search's time.
#[derive(Debug, Default)]
pub(crate) struct TripletSlots {
    slots: Vec<u32>,
    /// Whether the slots are those of a refill that met every entry of the
    /// pattern: triplets that all land on them cover it again.
    complete: bool,
    _claim: Option<Claim>,
    /// The held pattern's mirror places, for the symmetry check of a refill
    /// in full storage (made at the first one; a function of the pattern
    /// alone, which a handle keeps).
    mirrors: Option<Mirrors>,
}

/// The mirror places of a square pattern (sorted rows, [`Csc::mirror_pairs`]),
/// as positions in its values: each pair (r, c), r < c, stored on both
/// sides, and each entry off the diagonal whose mirror is not stored. The
/// symmetry check of a refill then reads the values pair by pair, with no
/// search of the pattern.
#[derive(Debug)]
struct Mirrors {
    pairs: Vec<[u32; 2]>,
    alone: Vec<u32>,
    _claim: Claim,
}

impl Mirrors {
    /// The mirror places of `a` (counted on `ledger`, exactly as
    /// [`Mirrors::bytes`] reports them); None where its positions do not
    /// fit in u32 or the memory is refused.
    fn of(a: &Csc, ledger: &Arc<Ledger>) -> Option<Mirrors> {
        if a.values.len() >= u32::MAX as usize {
            return None;
        }
        let (mut pairs, mut alone) = (Vec::new(), Vec::new());
        let off_diagonal = a.values.len() - a.ncols.min(a.values.len());
        pairs.try_reserve_exact(off_diagonal / 2).ok()?;
        // q < nnz < u32::MAX (checked above).
        a.mirror_pairs(|_, _, upper, lower| {
            match (upper, lower) {
                (Some(u), Some(l)) => pairs.push([u as u32, l as u32]),
                (Some(q), None) | (None, Some(q)) => alone.push(q as u32),
                (None, None) => {}
            }
            true
        })
        .ok()?;
        // Held as long as they are: what is counted is what is reported.
        pairs.shrink_to_fit();
        alone.shrink_to_fit();
        let bytes = (pairs.len() * 2 + alone.len()) * std::mem::size_of::<u32>();
        Some(Mirrors {
            pairs,
            alone,
            _claim: ledger.claim(bytes),
        })
    }

    fn bytes(&self) -> usize {
        (self.pairs.len() * 2 + self.alone.len()) * std::mem::size_of::<u32>()
    }

    /// Whether `values` (on the pattern these places are of) are symmetric
    /// as [`check_symmetric`] asks: |A_ij - A_ji| <= SYMMETRY_TOL max|A|
    /// for every pair, a missing entry counting as 0.
    fn symmetric(&self, values: &[f64]) -> bool {
        let max_abs = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let tol = super::SYMMETRY_TOL * max_abs;
        self.pairs
            .iter()
            .all(|&[u, l]| (values[u as usize] - values[l as usize]).abs() <= tol)
            && self.alone.iter().all(|&q| values[q as usize].abs() <= tol)
    }
}

/// Bytes of the mirror places of `a`'s pattern ([`Mirrors::of`]): 4 per
/// entry off the diagonal (a pair holds two positions, an entry alone one).
pub(crate) fn mirror_bytes(a: &Csc) -> usize {
    let diagonal = (0..a.ncols)
        .filter(|&c| {
            a.row_idx[a.col_ptr[c]..a.col_ptr[c + 1]]
                .binary_search(&c)
                .is_ok()
        })
        .count();
    (a.values.len() - diagonal) * std::mem::size_of::<u32>()
}

impl TripletSlots {
    /// Some where `a`, given in full storage on `pattern` (index base
    /// `base`), is symmetric: checked pair by pair at the pattern's mirror
    /// places, made here at the first use, or (memory refused) by the walk
    /// through the pattern.
    fn symmetric(
        &mut self,
        pattern: &Csc,
        a: &Csc,
        base: usize,
        ledger: &Arc<Ledger>,
    ) -> Option<()> {
        if self.mirrors.is_none() {
            self.mirrors = Mirrors::of(pattern, ledger);
        }
        match &self.mirrors {
            Some(mirrors) => mirrors.symmetric(&a.values).then_some(()),
            None => check_symmetric(a, "K", base).ok(),
        }
    }

    /// Whether the pattern's mirror places are held (made by a refill in
    /// full storage).
    pub(crate) fn has_mirrors(&self) -> bool {
        self.mirrors.is_some()
    }

    /// Bytes the slots take: 4 per triplet, twice that where one triangle
    /// is given, and the mirror places of a refill in full storage, 4 per
    /// entry off the diagonal, held from the first such refill on (kept
    /// between refactors: `Sizes::slots`).
    pub(crate) fn held_bytes(&self) -> usize {
        self.slots.len() * std::mem::size_of::<u32>()
            + self.mirrors.as_ref().map_or(0, Mirrors::bytes)
    }

    /// Slots for `count` placements, reused where they have that length,
    /// else made afresh (counted on `ledger`) with no guess in them; None
    /// where the pattern's slots do not fit in u32 or the memory is refused
    /// (the placements then search).
    fn ready(&mut self, count: usize, nnz: usize, ledger: &Arc<Ledger>) -> Option<&mut [u32]> {
        if nnz >= u32::MAX as usize {
            return None;
        }
        if self.slots.len() != count {
            (self.slots, self.complete, self._claim) = (Vec::new(), false, None);
            let mut slots = Vec::new();
            slots.try_reserve_exact(count).ok()?;
            slots.resize(count, u32::MAX);
            self._claim = Some(ledger.claim(count * std::mem::size_of::<u32>()));
            self.slots = slots;
        }
        Some(&mut self.slots)
    }
}

impl Csc {
    /// The symmetric matrix of `view` (COO, any storage) where it has
    /// exactly `self`'s pattern (`self` a symmetric matrix in internal form,
    /// both triangles): every triplet falls on it, every entry of it is
    /// met, and the result is what [`Csc::symmetric_from_view`] returns
    /// (duplicates summed in the given order, then the mirrored triangle);
    /// of a CSC view, see [`Csc::refill_csc`].
    /// None where the view is of another format (CSR, dense) or anything is amiss (an
    /// index out of range or off the pattern, an entry missing, a value not
    /// finite, K not symmetric): the full conversion then gives the matrix
    /// or the error.
    ///
    /// `slots` are the placements of the last refill, checked and updated
    /// here (see [`TripletSlots`]); `ledger` counts them where they are made.
    pub(crate) fn refill_symmetric(
        &self,
        view: &MatrixView<'_>,
        slots: &mut TripletSlots,
        ledger: &Arc<Ledger>,
    ) -> Option<Csc> {
        let n = self.nrows;
        if view.nrows != n || view.ncols != n {
            return None;
        }
        if view.format == Format::Csc {
            return self.refill_csc(view, slots, ledger);
        }
        if view.format != Format::Coo {
            return None;
        }
        let base = check_base(view, "K").ok()?;
        let len = view.i.len();
        if view.p.len() != len || view.x.len() != len {
            return None;
        }
        let nnz = self.values.len();
        // -0.0 + x is x bit for bit (-0.0 included): each entry's sum is the
        // full conversion's, which starts from its first triplet.
        let mut values = vec![-0.0; nnz];
        let (upper, lower) = match view.storage {
            Storage::Full => (false, false),
            Storage::Upper => (true, false),
            Storage::Lower => (false, true),
        };
        let passes = if upper || lower { 2 } else { 1 };
        let complete = std::mem::take(&mut slots.complete);
        let mut guesses = slots.ready(passes * len, nnz, ledger);
        let usable = guesses.is_some();
        // Full storage on slots that vouch for every entry: each triplet
        // checked against its slot alone, the general placement below only
        // where one is off it (from the start again: `values` reset).
        let fast = match (usable && complete && !(upper || lower), view.i, view.p) {
            (true, Indices::I32(i), Indices::I32(p)) => {
                self.place_on_slots((i, p), view.x, base, guesses.as_deref(), &mut values)
            }
            (true, Indices::I64(i), Indices::I64(p)) => {
                self.place_on_slots((i, p), view.x, base, guesses.as_deref(), &mut values)
            }
            _ => false,
        };
        if !fast && usable && complete {
            values.iter_mut().for_each(|v| *v = -0.0);
        }
        // The entries met, where the slots cannot vouch for them: made at the
        // first triplet off its slot (those before it marked from theirs).
        let mut met = (!(usable && complete)).then(|| vec![false; nnz]);
        // The stored triplets, then (one triangle given) their mirrors: the
        // order in which the full conversion sums them.
        for mirror in [false, true] {
            if fast || (mirror && !(upper || lower)) {
                break;
            }
            let offset = if mirror { len } else { 0 };
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
                    true => {
                        // No slot: none read by `met_so_far` either. Where
                        // the last refill placed a triplet here (K sent in
                        // another storage), the slots no longer vouch for
                        // the entries it met: the marks are made now.
                        if let Some(s) = guesses.as_deref_mut() {
                            if met.is_none() && s[offset + k] != u32::MAX {
                                met = Some(met_so_far(&s[..offset + k], nnz));
                            }
                            s[offset + k] = u32::MAX;
                        }
                        continue;
                    }
                };
                let (lo, hi) = (self.col_ptr[c], self.col_ptr[c + 1]);
                let guess = guesses
                    .as_deref()
                    .map_or(usize::MAX, |s| s[offset + k] as usize);
                let q = if (lo..hi).contains(&guess) && self.row_idx[guess] == r {
                    guess
                } else {
                    let q = lo + self.row_idx[lo..hi].binary_search(&r).ok()?;
                    if let Some(s) = guesses.as_deref_mut() {
                        if met.is_none() {
                            met = Some(met_so_far(&s[..offset + k], nnz));
                        }
                        // q < nnz < u32::MAX (`TripletSlots::ready`).
                        s[offset + k] = q as u32;
                    }
                    q
                };
                values[q] += x;
                if let Some(met) = met.as_mut() {
                    met[q] = true;
                }
            }
        }
        let missing = met.is_some_and(|met| met.iter().any(|&m| !m));
        if missing || values.iter().any(|v| !v.is_finite()) {
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
            slots.symmetric(self, &a, base, ledger)?;
        }
        // Every entry met, by these slots' triplets.
        slots.complete = usable;
        Some(a)
    }
}

impl Csc {
    /// The symmetric matrix of `view` (CSC, any storage, `self`'s order)
    /// where its arrays are `self`'s pattern as it stands (full storage),
    /// or its upper or lower triangle (one-triangle storage), row indices
    /// in the same order: the values copied, the other triangle's taken
    /// from their mirrors. What [`Csc::symmetric_from_view`] returns, bit
    /// for bit, without its index arrays made anew or its symmetry walk
    /// through the pattern (full storage is checked pair by pair at the
    /// mirror places kept in `slots`). None where anything differs or is
    /// amiss (a pointer, an index, a value not finite, K not symmetric):
    /// the full conversion then gives the matrix or the error.
    fn refill_csc(
        &self,
        view: &MatrixView<'_>,
        slots: &mut TripletSlots,
        ledger: &Arc<Ledger>,
    ) -> Option<Csc> {
        let n = self.ncols;
        let base = check_base(view, "K").ok()?;
        let stored = view.i.len();
        if view.p.len() != n + 1
            || view.x.len() != stored
            || view.p.get(0) != base as i64
            || view.p.get(n) != stored as i64 + base as i64
        {
            return None;
        }
        if view.x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let nnz = self.values.len();
        let mut values = Vec::new();
        values.try_reserve_exact(nnz).ok()?;
        if view.storage == Storage::Full {
            let same = (0..=n).all(|j| view.p.get(j) == self.col_ptr[j] as i64 + base as i64)
                && match view.i {
                    Indices::I32(i) => same_rows(i, &self.row_idx, base),
                    Indices::I64(i) => same_rows(i, &self.row_idx, base),
                };
            if !same {
                return None;
            }
            values.extend_from_slice(view.x);
        } else {
            values.resize(nnz, 0.0);
            self.mirror_triangle(view, base, &mut values)?;
        }
        let mut col_ptr = Vec::new();
        let mut row_idx = Vec::new();
        col_ptr.try_reserve_exact(n + 1).ok()?;
        row_idx.try_reserve_exact(nnz).ok()?;
        col_ptr.extend_from_slice(&self.col_ptr);
        row_idx.extend_from_slice(&self.row_idx);
        let a = Csc {
            nrows: n,
            ncols: n,
            col_ptr,
            row_idx,
            values,
        };
        if view.storage == Storage::Full {
            slots.symmetric(self, &a, base, ledger)?;
        }
        Some(a)
    }

    /// Places the one triangle of `view` (CSC, upper or lower storage,
    /// values finite) on `self`'s pattern (both triangles, sorted rows)
    /// into `values`, each of its columns the part of `self`'s column on
    /// that side of the diagonal, and fills the other triangle from the
    /// mirrors: the entries (c, r) of a column r are met in increasing c as
    /// the columns c are walked, so one cursor per column finds them (as
    /// CSparse's transpose). None where a column or a mirror differs.
    fn mirror_triangle(
        &self,
        view: &MatrixView<'_>,
        base: usize,
        values: &mut [f64],
    ) -> Option<()> {
        let n = self.ncols;
        let upper = view.storage == Storage::Upper;
        // The cursor of each column: its first entry below the diagonal.
        let mut next = Vec::new();
        next.try_reserve_exact(n).ok()?;
        next.extend((0..n).map(|j| {
            let rows = &self.row_idx[self.col_ptr[j]..self.col_ptr[j + 1]];
            self.col_ptr[j] + rows.partition_point(|&r| r <= j)
        }));
        for c in 0..n {
            let (lo, hi) = (self.col_ptr[c], self.col_ptr[c + 1]);
            // The stored part: rows <= c (upper) or >= c (lower).
            let split = lo + self.row_idx[lo..hi].partition_point(|&r| r < c);
            let has_diagonal = split < hi && self.row_idx[split] == c;
            let (from, to) = match upper {
                true => (lo, split + usize::from(has_diagonal)),
                false => (split, hi),
            };
            let p0 = view.p.get(c).checked_sub(base as i64)?;
            let p1 = view.p.get(c + 1).checked_sub(base as i64)?;
            if p0 < 0 || p1 < p0 || p1 as usize > view.x.len() || (p1 - p0) as usize != to - from {
                return None;
            }
            for (k, q) in (p0 as usize..p1 as usize).zip(from..to) {
                if view.i.get(k) != self.row_idx[q] as i64 + base as i64 {
                    return None;
                }
                values[q] = view.x[k];
            }
            // The entries above the diagonal, each (r, c) with its mirror
            // (c, r) at column r's cursor.
            for q in lo..split {
                let r = self.row_idx[q];
                let m = next[r];
                if m >= self.col_ptr[r + 1] || self.row_idx[m] != c {
                    return None;
                }
                next[r] += 1;
                match upper {
                    true => values[m] = values[q],
                    false => values[q] = values[m],
                }
            }
        }
        // Every entry below the diagonal met as a mirror.
        (0..n).all(|j| next[j] == self.col_ptr[j + 1]).then_some(())
    }

    /// Adds the triplets (`rows`, `cols`, `x`; full storage, index base
    /// `base`) at `slots`, the places they fell on at the last refill, into
    /// `values` (on `self`'s pattern): true where every triplet's slot lies
    /// in its column and holds its row. False at the first that does not,
    /// or where an index is out of range or there are no slots (`values`
    /// then partly summed: the caller starts over). A value that is not
    /// finite leaves its entry's sum not finite, which the caller checks.
    fn place_on_slots<I: Copy + Into<i64>>(
        &self,
        (rows, cols): (&[I], &[I]),
        x: &[f64],
        base: usize,
        slots: Option<&[u32]>,
        values: &mut [f64],
    ) -> bool {
        let n = self.ncols;
        let Some(slots) = slots else { return false };
        if slots.len() != x.len() || rows.len() != x.len() || cols.len() != x.len() {
            return false;
        }
        for (k, &q) in slots.iter().enumerate() {
            let (Some(r), Some(c)) = (
                index0(rows[k].into(), base, n),
                index0(cols[k].into(), base, n),
            ) else {
                return false;
            };
            let q = q as usize;
            if q < self.col_ptr[c] || q >= self.col_ptr[c + 1] || self.row_idx[q] != r {
                return false;
            }
            values[q] += x[k];
        }
        true
    }
}

/// Whether the row indices `rows` (index base `base`) are `want`.
fn same_rows<I: Copy + Into<i64>>(rows: &[I], want: &[usize], base: usize) -> bool {
    rows.len() == want.len()
        && rows
            .iter()
            .zip(want)
            .all(|(&r, &w)| r.into() == w as i64 + base as i64)
}

/// The entries of a pattern of `nnz` met by the triplets placed at `slots`
/// (u32::MAX where none was: the mirror of a diagonal triplet).
fn met_so_far(slots: &[u32], nnz: usize) -> Vec<bool> {
    let mut met = vec![false; nnz];
    for &q in slots {
        if let Some(m) = met.get_mut(q as usize) {
            *m = true;
        }
    }
    met
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

    /// The first two arrays of `a` (the indices) in 32 bits.
    fn narrow(a: &Arrays) -> [Vec<i32>; 2] {
        [&a.0, &a.1].map(|v| v.iter().map(|&x| x as i32).collect())
    }

    /// The bits of each value (-0.0 and 0.0 apart).
    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// `got` is `want`, bit for bit.
    fn assert_same(got: &Csc, want: &Csc, what: &str) {
        assert_eq!(got.col_ptr, want.col_ptr, "{what}");
        assert_eq!(got.row_idx, want.row_idx, "{what}");
        assert_eq!(bits(&got.values), bits(&want.values), "{what}");
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
                let (mut slots, ledger) = (TripletSlots::default(), Ledger::new());
                // Slots made, slots reused, then the triplets in the reverse
                // order (every guess wrong, as many triplets).
                let mut reversed = triplets(0.9);
                reversed.reverse();
                // The third and fourth in 32-bit indices (each width's
                // placement on the slots).
                for (r, t) in [triplets(1.7), triplets(2.3), triplets(2.9), reversed]
                    .into_iter()
                    .enumerate()
                {
                    let new = [arrays(&t, storage, base as i64)];
                    let narrow = narrow(&new[0]);
                    let mut view = coo(&new, storage, base);
                    if r >= 2 {
                        (view.i, view.p) = (Indices::I32(&narrow[0]), Indices::I32(&narrow[1]));
                    }
                    let want = Csc::symmetric_from_view(&view, "K").unwrap();
                    let got = k0
                        .refill_symmetric(&view, &mut slots, &ledger)
                        .expect("the same pattern");
                    assert_same(&got, &want, &format!("{storage:?}, base {base}"));
                    let passes = if storage == Storage::Full { 1 } else { 2 };
                    // A refill in full storage keeps the pattern's six
                    // mirror pairs (the chain's five links and the long one)
                    // for its symmetry check, two positions each.
                    let mirrors = if storage == Storage::Full {
                        4 * 2 * 6
                    } else {
                        0
                    };
                    assert_eq!(slots.held_bytes(), 4 * passes * new[0].0.len() + mirrors);
                    assert_eq!(ledger.live(), slots.held_bytes());
                }
            }
        }
    }

    /// The kept mirror places judge symmetry as the full check does, on a
    /// pattern with an entry whose mirror is not stored (its value counts
    /// against 0) and pairs off by just under and just over the tolerance.
    #[test]
    fn the_kept_mirrors_judge_symmetry_as_the_full_check() {
        let mut t = triplets(1.0);
        t.push((2, 5, 0.0));
        let arrs = [arrays(&t, Storage::Full, 0)];
        let mut a = Csc::symmetric_from_view(&coo(&arrs, Storage::Full, 0), "K").unwrap();
        let mirrors = Mirrors::of(&a, &Ledger::new()).expect("mirror places");
        assert_eq!((mirrors.pairs.len(), mirrors.alone.len()), (6, 1));
        let alone = mirrors.alone[0] as usize;
        let pair = mirrors.pairs[2];
        let tol = crate::sparse::SYMMETRY_TOL * a.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (at, by) in [
            (pair[0] as usize, 0.9 * tol),
            (pair[0] as usize, 1.1 * tol),
            (alone, 0.9 * tol),
            (alone, 1.1 * tol),
        ] {
            let kept = a.values[at];
            a.values[at] += by;
            let full = check_symmetric(&a, "K", 0).is_ok();
            assert_eq!(mirrors.symmetric(&a.values), full, "{at} {by:e}");
            assert_eq!(full, by < tol, "{at} {by:e}");
            a.values[at] = kept;
        }
    }

    /// A refill whose triplets leave their slots near the end (two swapped)
    /// starts over from nothing: the triplets placed before are not summed
    /// twice. And the mirror places of a pattern with entries whose mirror
    /// is not stored are counted on the ledger as they are reported.
    #[test]
    fn a_placement_that_leaves_its_slots_late_starts_over() {
        let mut t = triplets(1.0);
        t.extend([(0, 2, 0.0), (1, 3, 0.0), (2, 4, 0.0)]);
        let old = [arrays(&t, Storage::Full, 0)];
        let k0 = Csc::symmetric_from_view(&coo(&old, Storage::Full, 0), "K").unwrap();
        let (mut slots, ledger) = (TripletSlots::default(), Ledger::new());
        for _ in 0..2 {
            let got = k0.refill_symmetric(&coo(&old, Storage::Full, 0), &mut slots, &ledger);
            assert!(got.is_some());
        }
        assert_eq!(ledger.live(), slots.held_bytes());
        let mut late = t.clone();
        let n = late.len();
        late.swap(n - 5, n - 6);
        let new = [arrays(&late, Storage::Full, 0)];
        let view = coo(&new, Storage::Full, 0);
        let want = Csc::symmetric_from_view(&view, "K").unwrap();
        let got = k0
            .refill_symmetric(&view, &mut slots, &ledger)
            .expect("the same pattern");
        assert_eq!(bits(&got.values), bits(&want.values));
        assert_eq!(ledger.live(), slots.held_bytes());
    }

    /// CSC arrays (pointers, rows, values; `base`) of the part of `a`
    /// that `storage` keeps.
    fn csc_arrays(a: &Csc, storage: Storage, base: i64) -> Arrays {
        let (mut p, mut i, mut x) = (vec![base], Vec::new(), Vec::new());
        for c in 0..a.ncols {
            for q in a.col_ptr[c]..a.col_ptr[c + 1] {
                let r = a.row_idx[q];
                let keep = match storage {
                    Storage::Full => true,
                    Storage::Upper => r <= c,
                    Storage::Lower => r >= c,
                };
                if keep {
                    i.push(r as i64 + base);
                    x.push(a.values[q]);
                }
            }
            p.push(i.len() as i64 + base);
        }
        (p, i, x)
    }

    fn csc<'a>(a: &'a Arrays, storage: Storage, base: usize) -> MatrixView<'a> {
        MatrixView {
            format: Format::Csc,
            storage,
            base,
            nrows: 6,
            ncols: 6,
            p: Indices::I64(&a.0),
            i: Indices::I64(&a.1),
            x: &a.2,
        }
    }

    /// A CSC K on the held pattern, in each storage, base and index width,
    /// is what the full conversion makes of it, bit for bit (-0.0 kept);
    /// a pointer, a row, a value not finite, an entry in the wrong
    /// triangle or K not symmetric is left to the full conversion.
    #[test]
    fn a_csc_refill_is_the_full_conversion_bit_for_bit() {
        let old = [arrays(&triplets(1.0), Storage::Full, 0)];
        let k0 = Csc::symmetric_from_view(&coo(&old, Storage::Full, 0), "K").unwrap();
        let mut k1 = Csc::symmetric_from_view(
            &coo(
                &[arrays(&triplets(1.3), Storage::Full, 0)],
                Storage::Full,
                0,
            ),
            "K",
        )
        .unwrap();
        // A signed zero on the diagonal, mirrored nowhere.
        k1.values[k1.col_ptr[2]..k1.col_ptr[3]]
            .iter_mut()
            .zip(&k1.row_idx[k1.col_ptr[2]..k1.col_ptr[3]])
            .filter(|(_, r)| **r == 2)
            .for_each(|(v, _)| *v = -0.0);
        let ledger = Ledger::new();
        for storage in [Storage::Full, Storage::Upper, Storage::Lower] {
            for base in [0, 1] {
                let mut slots = TripletSlots::default();
                let a = csc_arrays(&k1, storage, base as i64);
                let narrow = narrow(&a);
                for wide in [true, false] {
                    let mut view = csc(&a, storage, base);
                    if !wide {
                        (view.p, view.i) = (Indices::I32(&narrow[0]), Indices::I32(&narrow[1]));
                    }
                    let want = Csc::symmetric_from_view(&view, "K").unwrap();
                    let got = k0
                        .refill_symmetric(&view, &mut slots, &ledger)
                        .expect("the same pattern");
                    assert_same(&got, &want, &format!("{storage:?} {base}"));
                }
                // Each edit leaves the refill to the full conversion.
                let edits: [&dyn Fn(&mut Arrays); 7] = [
                    &|a| a.2[3] = f64::NAN,
                    &|a| a.1[0] += 1,
                    &|a| {
                        a.0[3] += 1;
                    },
                    &|a| {
                        a.1.pop();
                        a.2.pop();
                        *a.0.last_mut().unwrap() -= 1;
                    },
                    &|a| a.2[1] *= 1.5,
                    // Indices no subtraction of the base may overflow on.
                    &|a| a.0[3] = i64::MIN,
                    &|a| a.1[0] = i64::MIN,
                ];
                for (e, edit) in edits.iter().enumerate() {
                    let mut bad = a.clone();
                    edit(&mut bad);
                    let view = csc(&bad, storage, base);
                    let got = k0.refill_symmetric(&view, &mut slots, &ledger);
                    // A value changed in one triangle is K's new value
                    // there (one-triangle storage): it must be refilled as
                    // the full conversion makes it; in full storage it
                    // breaks the symmetry.
                    if e == 4 && storage != Storage::Full {
                        let want = Csc::symmetric_from_view(&view, "K").unwrap();
                        assert_eq!(bits(&got.expect("refilled").values), bits(&want.values));
                    } else {
                        assert!(got.is_none(), "{storage:?} {base} edit {e}");
                    }
                }
            }
        }
        // An entry in the wrong triangle, with its own value: upper storage
        // given the lower triangle.
        let lower = csc_arrays(&k1, Storage::Lower, 0);
        let view = csc(&lower, Storage::Upper, 0);
        let mut slots = TripletSlots::default();
        assert!(k0.refill_symmetric(&view, &mut slots, &ledger).is_none());
        assert!(Csc::symmetric_from_view(&view, "K").is_err());
    }

    #[test]
    fn anything_amiss_is_left_to_the_full_conversion() {
        let t = triplets(1.0);
        let old = [arrays(&t, Storage::Full, 0)];
        let k0 = Csc::symmetric_from_view(&coo(&old, Storage::Full, 0), "K").unwrap();
        // One set of slots throughout: the bad triplets meet the guesses
        // of the good ones.
        let (slots, ledger) = (
            std::cell::RefCell::new(TripletSlots::default()),
            Ledger::new(),
        );
        let refill = |edit: &dyn Fn(&mut Arrays)| {
            let mut a = arrays(&t, Storage::Full, 0);
            edit(&mut a);
            let arrs = [a];
            k0.refill_symmetric(
                &coo(&arrs, Storage::Full, 0),
                &mut slots.borrow_mut(),
                &ledger,
            )
        };
        assert!(refill(&|_| {}).is_some());
        // An entry missing with as many triplets, after a refill whose
        // slots met every entry: (0, 5) and (5, 0) moved onto the diagonal.
        assert!(
            refill(&|a| {
                for k in 0..a.0.len() {
                    if matches!((a.0[k], a.1[k]), (0, 5) | (5, 0)) {
                        a.1[k] = a.0[k];
                    }
                }
            })
            .is_none()
        );
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
        // Upper storage after a full refill of as many placements: the
        // upper triangle without (0, 5), whose mirrors fall on the slots of
        // the full triplets and whose diagonal's mirrors skip the slots
        // that held (0, 5) and (5, 0).
        let diag = [(0, 0), (1, 1), (2, 2), (3, 3), (4, 4), (5, 5)];
        let links = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5)];
        let mut full: Vec<(i64, i64)> = diag.iter().chain(&links).copied().collect();
        full.extend([(0, 5), (5, 0), (0, 0), (0, 0), (0, 0), (0, 0)]);
        full.extend(links.iter().map(|&(r, c)| (c, r)));
        let upper = &full[..diag.len() + links.len()];
        let view_of = |t: &[(i64, i64)]| -> Arrays {
            (
                t.iter().map(|e| e.0).collect(),
                t.iter().map(|e| e.1).collect(),
                vec![1.0; t.len()],
            )
        };
        let (a_full, a_upper) = ([view_of(&full)], [view_of(upper)]);
        let mut own = TripletSlots::default();
        assert!(
            k0.refill_symmetric(&coo(&a_full, Storage::Full, 0), &mut own, &ledger)
                .is_some()
        );
        assert!(
            k0.refill_symmetric(&coo(&a_upper, Storage::Upper, 0), &mut own, &ledger)
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
