//! The lumped preconditioner restricted to the unknowns of a Newton step's
//! reduced system: an approximate inverse of M = T^T A T + Delta (T the
//! reduced unknowns' test vectors, Delta >= 0 diagonal) rather than of A.
//!
//! The reduced systems' general preconditioner S T^T H T S (`reduced_krylov`)
//! restricts an approximate inverse H of A to the free components, which
//! approximates the Schur complement of A^-1 onto them, not M^-1; its error
//! grows with the components a step fixes (open contacts, the slip
//! direction of each slipping contact), and gross slip took about 14
//! products per digit with it. This one is the reduced system's own inverse
//! with A^-1 replaced by the lumped H = G = B K_FF B^T (F the face):
//! P = (T^T G^-1 T + Delta)^-1, exact for G. With the components sorted into
//! - prescribed ones (a unit test vector, Delta = 0): nu_j = x_j,
//! - slipping pairs (a tangential pair with test t, Delta > 0), and
//! - fixed ones (no reduced unknown), U with the pairs,
//!
//! it solves E nu_U = r_U - G_UP x_P with E = (G + D')_UU, D' = t t^T /
//! Delta on a pair and r = t x / Delta there; then (P x)_j = (G nu)_j on a
//! prescribed component and (x - t^T nu) / Delta on a pair. E is SPD where
//! B has full row rank. Each step factors E, in the order of U's
//! components in G's own fill-reducing order (analysed once, so that E's
//! factor is no larger than G's: the prediction's bound), its analysis kept
//! while U stays the same; each application is one solve with E and
//! products with G's prescribed columns.
//!
//! The layered Dirichlet H_D of `dirichlet.rs` approximates A^-1 better than
//! G. Its restriction (a bordered matrix [G + D', B K_FI; K_IF B^T, K_II]
//! to factor per step) cost 8 times the flops of E, so the step adds P's
//! first-order change instead, X^T (H_D - G) X with X = G^-1 T P the
//! extension of x that `apply` computes (nu): the quadratic form then lies
//! between those of P(G) and P(H_D) (the Schur complement is concave in H,
//! and H_D <= G), and it costs one application of H_D and one more solve
//! with E ([`Restricted::add_extension_t`]).

use crate::factor::Factor;
use crate::memory::{Claim, Ledger};
use crate::options::Ordering;
use crate::sparse::Csc;
use crate::threads::Threads;
use faer::MatMut;
use faer::dyn_stack::{MemBuffer, MemStack};
use std::cell::RefCell;
use std::sync::Arc;

/// A slipping contact's tangential pair in a reduced system: components
/// `j` and `j + 1`, test vector `t` on them, diagonal term `delta` > 0.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pair {
    pub j: usize,
    pub t: [f64; 2],
    pub delta: f64,
}

/// G, its fill-reducing order, and the state of the last step E was
/// factored for.
pub(crate) struct Restricted {
    /// G = B K B^T (c x c, both triangles, sorted rows; the diagonal stored
    /// wherever B's row is not empty, K's diagonal being stored).
    g: Csc,
    /// Position of each component in G's fill-reducing order.
    order: Vec<usize>,
    /// Components whose row of B is empty (G's column holds no entry).
    empty: Vec<bool>,
    /// Bytes of G's own factor, its factorisation's and its solve's
    /// workspace: bounds of E's.
    factor_bytes: (usize, usize, usize),
    threads: Arc<Threads>,
    ledger: Arc<Ledger>,
    step: RefCell<Step>,
    /// What it holds, counted once the preconditioner is formed
    /// ([`Restricted::count`]).
    claim: Option<Claim>,
}

/// What a step writes: its components, E and E's factor.
struct Step {
    prescribed: Vec<bool>,
    /// Position in U of each component (usize::MAX where prescribed).
    at: Vec<usize>,
    /// The components U (not prescribed), ascending.
    u: Vec<usize>,
    e: Csc,
    factor: Option<Factor>,
    /// Whether `u` was analysed (E's factor made, or refused: `refused`).
    analysed: bool,
    refused: bool,
    factored: bool,
    rhs: Vec<f64>,
    mem: MemBuffer,
}

impl Step {
    /// No step yet, for c components.
    fn none(c: usize) -> Step {
        Step {
            prescribed: vec![false; c],
            at: vec![usize::MAX; c],
            u: Vec::new(),
            e: Csc {
                nrows: 0,
                ncols: 0,
                col_ptr: vec![0],
                row_idx: Vec::new(),
                values: Vec::new(),
            },
            factor: None,
            analysed: false,
            refused: false,
            factored: false,
            rhs: Vec::new(),
            mem: MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
        }
    }
}

impl Step {
    /// A step of c components holding this one's analysis of E (its
    /// components U and E's symbolic factor, unfactored), where it has one;
    /// else none.
    fn analysis(&self, c: usize) -> Step {
        let mut next = Step::none(c);
        if !self.analysed || self.refused || (self.factor.is_none() && !self.u.is_empty()) {
            return next;
        }
        if let Some(f) = &self.factor {
            let Ok(mem) = crate::memory::try_scratch(f.solve_scratch(1), "") else {
                return next;
            };
            (next.factor, next.mem) = (Some(f.unfactored_copy()), mem);
        }
        next.u.clone_from(&self.u);
        next.at.clone_from(&self.at);
        next.rhs = vec![0.0; self.u.len()];
        next.analysed = true;
        next
    }
}

impl Restricted {
    /// G = B K B^T of K = `k` (n x n, both triangles) and B = `b` (c x n),
    /// with its fill-reducing order (AMD) and its factor's size; E's factors
    /// run on `threads` and are counted on `ledger`. None where the analysis
    /// fails. A contact's tangential pair is coupled where its two rows of B
    /// share a DOF, as nodal rows do, or K couples their DOFs.
    pub(crate) fn new(
        k: &Csc,
        b: &Csc,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Option<Restricted> {
        let g = crate::sparse::congruence(k, b, &b.try_transpose().ok()?);
        let c = g.ncols;
        let full = Factor::analyse(
            &g,
            &[],
            Ordering::Amd,
            false,
            threads.clone(),
            ledger.clone(),
        )
        .ok()?;
        let factor_bytes = (
            full.values_bytes(),
            full.factor_scratch_bytes(),
            full.solve_scratch(1).size_bytes(),
        );
        let order = full.new_of_old();
        let empty = (0..g.ncols)
            .map(|j| g.col_ptr[j] == g.col_ptr[j + 1])
            .collect();
        Some(Restricted {
            order,
            empty,
            factor_bytes,
            step: RefCell::new(Step::none(c)),
            g,
            threads,
            ledger,
            claim: None,
        })
    }

    /// The preconditioner of K = `k` of the pattern of the K it was made
    /// for, and the same B = `b` (`bt` its transpose): G formed afresh, its
    /// order and bounds kept (functions of G's pattern alone), no step
    /// factored yet, the last step's analysis of E kept for a step with the
    /// same components U (E's pattern is then the same: a host's next
    /// iteration whose contact states held). None where G's pattern differs.
    pub(crate) fn renewed(&self, k: &Csc, b: &Csc, bt: &Csc) -> Option<Restricted> {
        let g = crate::sparse::congruence(k, b, bt);
        if g.col_ptr != self.g.col_ptr || g.row_idx != self.g.row_idx {
            return None;
        }
        Some(Restricted {
            order: self.order.clone(),
            empty: self.empty.clone(),
            factor_bytes: self.factor_bytes,
            step: RefCell::new(self.step.borrow().analysis(g.ncols)),
            g,
            threads: self.threads.clone(),
            ledger: self.ledger.clone(),
            claim: None,
        })
    }

    /// Bytes held between steps: G and E (at most G's entries), the order,
    /// U's lists and the right-hand side (c each), the flags, and E's solve
    /// workspace (at most G's).
    fn held(g: &Csc, solve_scratch: usize) -> usize {
        2 * g.bytes() + 4 * g.nrows * 8 + 2 * g.nrows + solve_scratch
    }

    /// Counts what it holds on its ledger (when the preconditioner it
    /// belongs to is formed; E's factors count themselves).
    pub(crate) fn count(&mut self) {
        self.claim = Some(self.ledger.claim(Self::held(&self.g, self.factor_bytes.2)));
    }

    /// Bytes held at most once a step is factored: [`Restricted::held`] and
    /// E's factor with its factorisation's workspace, at most G's own (a
    /// step whose E would need more goes without this preconditioner).
    pub(crate) fn bytes(&self) -> usize {
        let (values, factor_scratch, solve_scratch) = self.factor_bytes;
        Self::held(&self.g, solve_scratch) + values + factor_scratch
    }

    /// Factors E for a step whose prescribed components are `prescribed` and
    /// whose slipping pairs are `pairs` (every other component fixed). False
    /// where a component is listed twice (prescribed twice, or in a pair
    /// and prescribed), a pair's components are not coupled in G's pattern,
    /// E's factor would exceed G's, or the factorisation fails (the step
    /// then goes without this preconditioner).
    pub(crate) fn factor(&self, prescribed: &[usize], pairs: &[Pair]) -> bool {
        let mut step = self.step.borrow_mut();
        let step = &mut *step;
        let g = &self.g;
        step.factored = false;
        step.prescribed.iter_mut().for_each(|p| *p = false);
        for &j in prescribed {
            if std::mem::replace(&mut step.prescribed[j], true) {
                return false;
            }
        }
        let in_pair = |j: usize| j < g.ncols && !step.prescribed[j];
        if !pairs.iter().all(|pr| in_pair(pr.j) && in_pair(pr.j + 1)) {
            return false;
        }
        let same = step.analysed
            && step.u.len() + prescribed.len() == g.ncols
            && step.u.iter().all(|&j| !step.prescribed[j]);
        if !same {
            step.u.clear();
            step.u.extend((0..g.ncols).filter(|&j| !step.prescribed[j]));
            step.at.iter_mut().for_each(|a| *a = usize::MAX);
            for (l, &j) in step.u.iter().enumerate() {
                step.at[j] = l;
            }
            // The old factor (if any) and its workspace go before the new
            // ones are made; U is analysed anew even where E is refused
            // below before its analysis.
            step.factor = None;
            step.analysed = false;
            step.mem = MemBuffer::new(faer::dyn_stack::StackReq::EMPTY);
            step.rhs.resize(step.u.len(), 0.0);
        } else if step.refused {
            return false;
        }
        // E = G_UU (rows ascending, as U is), 1 on the diagonal of a
        // component whose row of B is empty (nu = 0 there: it couples to
        // nothing), then D' on the pairs.
        let e = &mut step.e;
        let nu = step.u.len();
        (e.nrows, e.ncols) = (nu, nu);
        e.col_ptr.clear();
        e.row_idx.clear();
        e.values.clear();
        e.col_ptr.push(0);
        for &j in &step.u {
            if self.empty[j] {
                e.row_idx.push(step.at[j]);
                e.values.push(1.0);
            }
            for p in g.col_ptr[j]..g.col_ptr[j + 1] {
                let at = step.at[g.row_idx[p]];
                if at != usize::MAX {
                    e.row_idx.push(at);
                    e.values.push(g.values[p]);
                }
            }
            e.col_ptr.push(e.row_idx.len());
        }
        for pr in pairs {
            let s = 1.0 / pr.delta;
            for (a, ta) in [(pr.j, pr.t[0]), (pr.j + 1, pr.t[1])] {
                for (b, tb) in [(pr.j, pr.t[0]), (pr.j + 1, pr.t[1])] {
                    let (a, b) = (step.at[a], step.at[b]);
                    let col = &e.row_idx[e.col_ptr[b]..e.col_ptr[b + 1]];
                    let Ok(p) = col.binary_search(&a) else {
                        return false;
                    };
                    e.values[e.col_ptr[b] + p] += s * ta * tb;
                }
            }
        }
        if !same {
            step.analysed = true;
            step.refused = false;
            if nu > 0 {
                match self.analyse(e, &step.u, &step.at) {
                    Some((factor, mem)) => (step.factor, step.mem) = (Some(factor), mem),
                    None => {
                        step.refused = true;
                        return false;
                    }
                }
            }
        }
        step.factored = match step.factor.as_mut() {
            // Into E's old values: one factor's values held at a time, and
            // no new pages to fault in.
            Some(factor) => factor.refactor_in_place(e).is_ok(),
            None => nu == 0,
        };
        step.factored
    }

    /// E's analysis in G's order restricted to U (`u`, `at` its inverse),
    /// and the solve's workspace; None where it fails or where the factor
    /// would exceed the bounds the prediction counted (G's own: its filled
    /// graph is a subgraph of G's in this order, but the supernodes'
    /// padding may differ).
    fn analyse(&self, e: &Csc, u: &[usize], at: &[usize]) -> Option<(Factor, MemBuffer)> {
        let mut fwd = u.to_vec();
        fwd.sort_unstable_by_key(|&j| self.order[j]);
        fwd.iter_mut().for_each(|j| *j = at[*j]);
        let factor =
            Factor::analyse_in_order(e, fwd, self.threads.clone(), self.ledger.clone()).ok()?;
        let (values, factor_scratch, solve_scratch) = self.factor_bytes;
        if factor.values_bytes() > values
            || factor.factor_scratch_bytes() > factor_scratch
            || factor.solve_scratch(1).size_bytes() > solve_scratch
        {
            return None;
        }
        let mem = crate::memory::try_scratch(factor.solve_scratch(1), "").ok()?;
        Some((factor, mem))
    }

    /// r := E^-1 r (r of length |U|) with the step's factor.
    fn solve(step: &mut Step) {
        let n = step.rhs.len();
        if let (Some(f), true) = (&step.factor, n > 0) {
            f.solve_in_place(
                MatMut::from_column_major_slice_mut(&mut step.rhs, n, 1),
                MemStack::new(&mut step.mem),
            );
        }
    }

    /// z := P x for the step [`Restricted::factor`] was last called with (the
    /// same `prescribed` and `pairs`): x_p, z_p on the prescribed components
    /// (in `prescribed`'s order), x_s, z_s on the pairs; `nu` (length c)
    /// receives the extension X x = G^-1 T z. False where that
    /// factorisation failed.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn apply(
        &self,
        prescribed: &[usize],
        x_p: &[f64],
        pairs: &[Pair],
        x_s: &[f64],
        z_p: &mut [f64],
        z_s: &mut [f64],
        nu: &mut [f64],
    ) -> bool {
        let mut step = self.step.borrow_mut();
        let step = &mut *step;
        if !step.factored {
            return false;
        }
        let g = &self.g;
        // r = t x / Delta on the pairs - G_UP x_P.
        step.rhs.iter_mut().for_each(|v| *v = 0.0);
        for (pr, &x) in pairs.iter().zip(x_s) {
            step.rhs[step.at[pr.j]] += pr.t[0] * x / pr.delta;
            step.rhs[step.at[pr.j + 1]] += pr.t[1] * x / pr.delta;
        }
        for (&j, &x) in prescribed.iter().zip(x_p) {
            for p in g.col_ptr[j]..g.col_ptr[j + 1] {
                let at = step.at[g.row_idx[p]];
                if at != usize::MAX {
                    step.rhs[at] -= g.values[p] * x;
                }
            }
        }
        Self::solve(step);
        for (&j, &v) in step.u.iter().zip(&step.rhs) {
            nu[j] = v;
        }
        for (&j, &x) in prescribed.iter().zip(x_p) {
            nu[j] = x;
        }
        // (G nu)_j on the prescribed components, G symmetric.
        for (&j, zj) in prescribed.iter().zip(z_p.iter_mut()) {
            *zj = (g.col_ptr[j]..g.col_ptr[j + 1])
                .map(|p| g.values[p] * nu[g.row_idx[p]])
                .sum();
        }
        for ((pr, &x), zs) in pairs.iter().zip(x_s).zip(z_s.iter_mut()) {
            *zs = (x - pr.t[0] * nu[pr.j] - pr.t[1] * nu[pr.j + 1]) / pr.delta;
        }
        true
    }

    /// Adds X^T w to z (z_p on the prescribed components, z_s on the pairs,
    /// of the step last factored and applied), X the extension of
    /// [`Restricted::apply`], w of length c: one more solve with E. Nothing
    /// where that step's factorisation failed.
    pub(crate) fn add_extension_t(
        &self,
        prescribed: &[usize],
        pairs: &[Pair],
        w: &[f64],
        z_p: &mut [f64],
        z_s: &mut [f64],
    ) {
        let mut step = self.step.borrow_mut();
        let step = &mut *step;
        if !step.factored {
            return;
        }
        let g = &self.g;
        for (r, &j) in step.rhs.iter_mut().zip(&step.u) {
            *r = w[j];
        }
        Self::solve(step);
        let (at, y) = (&step.at, &step.rhs);
        for (&j, zj) in prescribed.iter().zip(z_p.iter_mut()) {
            *zj += w[j]
                - (g.col_ptr[j]..g.col_ptr[j + 1])
                    .filter(|&p| at[g.row_idx[p]] != usize::MAX)
                    .map(|p| g.values[p] * y[at[g.row_idx[p]]])
                    .sum::<f64>();
        }
        for (pr, zs) in pairs.iter().zip(z_s.iter_mut()) {
            *zs += (pr.t[0] * y[at[pr.j]] + pr.t[1] * y[at[pr.j + 1]]) / pr.delta;
        }
    }

    /// G = B K B^T (c x c, both triangles).
    pub(crate) fn g(&self) -> &Csc {
        &self.g
    }

    /// y := G x (x, y of length c).
    pub(crate) fn g_mul(&self, x: &[f64], y: &mut [f64]) {
        self.g.mul_vec(x, y);
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // dense index arithmetic reads plainer so
mod tests {
    use super::*;

    /// Two layers of `m` nodes in a chain, 3 DOFs each (the face layer
    /// first): K SPD (diagonally dominant, coupled 3 x 3 node blocks), and B
    /// nodal: normal row i on DOF 3i + 2, tangential rows m + 2i, m + 2i + 1
    /// on DOFs 3i, 3i + 1 (c = 3m).
    fn scene(m: usize) -> (Csc, Csc) {
        let n = 6 * m;
        let mut t = Vec::new();
        let block = [[1.0, 0.2, 0.1], [0.2, 0.8, 0.3], [0.1, 0.3, 1.1]];
        let node_pairs = (0..2 * m)
            .flat_map(|a| [(a, a + 1), (a, a + m)])
            .filter(|&(a, b)| b < 2 * m && (b != a + 1 || (a + 1) % m != 0));
        let mut diag = vec![6.0; n];
        for (a, b) in node_pairs {
            for r in 0..3 {
                for s in 0..3 {
                    let v = -0.4 * block[r][s] * (1.0 + 0.1 * (a % 5) as f64);
                    t.push((3 * a + r, 3 * b + s, v));
                    t.push((3 * b + s, 3 * a + r, v));
                    diag[3 * a + r] += v.abs();
                    diag[3 * b + s] += v.abs();
                }
            }
        }
        for a in 0..2 * m {
            for r in 0..3 {
                for s in 0..3 {
                    if r != s {
                        t.push((3 * a + r, 3 * a + s, 0.5 * block[r][s]));
                    }
                }
            }
        }
        t.extend(diag.iter().enumerate().map(|(i, &d)| (i, i, d)));
        let k = Csc::from_triplets(n, n, &t);
        let mut rows: Vec<_> = (0..m).map(|i| (i, 3 * i + 2, 1.0)).collect();
        rows.extend((0..2 * m).map(|r| (m + r, 3 * (r / 2) + r % 2, 1.0)));
        (k, Csc::from_triplets(3 * m, n, &rows))
    }

    fn dense(a: &Csc) -> Vec<Vec<f64>> {
        let mut d = vec![vec![0.0; a.ncols]; a.nrows];
        for j in 0..a.ncols {
            for p in a.col_ptr[j]..a.col_ptr[j + 1] {
                d[a.row_idx[p]][j] += a.values[p];
            }
        }
        d
    }

    /// x := A^-1 x by Gaussian elimination with partial pivoting.
    fn solve(mut a: Vec<Vec<f64>>, x: &mut [f64]) {
        let n = x.len();
        for k in 0..n {
            let p = (k..n)
                .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
                .unwrap();
            a.swap(k, p);
            x.swap(k, p);
            for i in k + 1..n {
                let f = a[i][k] / a[k][k];
                for j in k..n {
                    a[i][j] -= f * a[k][j];
                }
                x[i] -= f * x[k];
            }
        }
        for k in (0..n).rev() {
            x[k] = (x[k] - (k + 1..n).map(|j| a[k][j] * x[j]).sum::<f64>()) / a[k][k];
        }
    }

    /// The scene's K and B (the last contact's rows of B emptied where
    /// `empty_last`: a contact that does not act) and its G analysed.
    fn made(m: usize, empty_last: bool) -> (Csc, Csc, Restricted) {
        let (k, mut b) = scene(m);
        if empty_last {
            let gone = [m - 1, 3 * m - 2, 3 * m - 1];
            let mut t = Vec::new();
            for j in 0..b.ncols {
                for p in b.col_ptr[j]..b.col_ptr[j + 1] {
                    if !gone.contains(&b.row_idx[p]) {
                        t.push((b.row_idx[p], j, b.values[p]));
                    }
                }
            }
            b = Csc::from_triplets(b.nrows, b.ncols, &t);
        }
        let (threads, ledger) = (Arc::new(Threads::new(1)), Ledger::new());
        let r = Restricted::new(&k, &b, threads, ledger).expect("analysed");
        (k, b, r)
    }

    /// P x for the step last factored (x: the prescribed components' values,
    /// then the pairs'), in that order, and the extension nu.
    fn applied(
        r: &Restricted,
        prescribed: &[usize],
        pairs: &[Pair],
        x: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let (np, c) = (prescribed.len(), r.g.ncols);
        let (mut zp, mut zs, mut nu) = (vec![0.0; np], vec![0.0; pairs.len()], vec![0.0; c]);
        assert!(r.apply(
            prescribed,
            &x[..np],
            pairs,
            &x[np..],
            &mut zp,
            &mut zs,
            &mut nu
        ));
        (zp.into_iter().chain(zs).collect(), nu)
    }

    /// Contacts 0..m sorted: even ones stick (normal and both tangential
    /// components prescribed), every third slips (normal prescribed, a pair
    /// along a turning direction), the rest open (fixed).
    fn steps(m: usize) -> (Vec<usize>, Vec<Pair>) {
        let (mut prescribed, mut pairs) = (Vec::new(), Vec::new());
        for i in 0..m {
            let jt = m + 2 * i;
            if i % 3 == 1 {
                let a = 0.3 + i as f64;
                prescribed.push(i);
                pairs.push(Pair {
                    j: jt,
                    t: [a.cos(), a.sin()],
                    delta: 0.05 * (1.0 + i as f64),
                });
            } else if i % 2 == 0 {
                prescribed.extend([i, jt, jt + 1]);
            }
        }
        (prescribed, pairs)
    }

    /// P x against (T^T G^-1 T + Delta)^-1 x with G = B K_FF B^T formed
    /// densely: equal to rounding, on the prescribed components and the
    /// pairs; twice, the second time on the analysis the first one kept.
    #[test]
    fn it_is_the_reduced_systems_inverse_for_the_lumped_g() {
        check_inverse(false);
    }

    /// As above with a contact whose rows of B are empty (it does not act;
    /// its components fixed): they decouple, and the reference takes them
    /// out of G (a unit diagonal there).
    #[test]
    fn a_contact_that_does_not_act_decouples() {
        check_inverse(true);
    }

    /// A preconditioner renewed for a K of the same pattern keeps the last
    /// step's analysis of E: the same step on it (without an analysis of
    /// its own) applies as one made afresh on that K, to rounding; a step
    /// whose E is refused before its analysis (a pair on the contact whose
    /// rows of B are empty: G does not couple its components) leaves none
    /// to keep.
    #[test]
    fn a_renewed_preconditioner_keeps_the_analysis_of_e() {
        let m = 12;
        let (k, b, r) = made(m, true);
        let (prescribed, pairs) = steps(m);
        assert!(r.factor(&prescribed, &pairs));
        // K scaled by 1 + 0.02 on every entry of the first third of the
        // DOFs' columns and rows (a zone made stiffer), symmetrised.
        let mut k2 = k.clone();
        let zone = k.nrows / 3;
        for j in 0..k2.ncols {
            for p in k2.col_ptr[j]..k2.col_ptr[j + 1] {
                let i = k2.row_idx[p];
                let s = |x: usize| if x < zone { 1.02 } else { 1.0 };
                k2.values[p] *= s(i) * s(j);
            }
        }
        let bt = b.transpose();
        let renewed = r.renewed(&k2, &b, &bt).expect("G's pattern");
        assert!(renewed.step.borrow().analysed);
        let (threads, ledger) = (Arc::new(Threads::new(1)), Ledger::new());
        let fresh = Restricted::new(&k2, &b, threads, ledger).expect("analysed");
        assert!(renewed.factor(&prescribed, &pairs) && fresh.factor(&prescribed, &pairs));
        let x: Vec<f64> = (0..prescribed.len() + pairs.len())
            .map(|i| ((i * 7) % 5) as f64 - 2.0)
            .collect();
        let (got, _) = applied(&renewed, &prescribed, &pairs, &x);
        let (want, _) = applied(&fresh, &prescribed, &pairs, &x);
        let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let diff = got
            .iter()
            .zip(&want)
            .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(
            scale > 0.0 && diff <= 1e-12 * scale,
            "{diff:.2e} of {scale:.2e}"
        );
        // A pair whose components G does not couple (those of the contact
        // that does not act) is refused before E's analysis: nothing
        // analysed is kept for the next K.
        let bad = [Pair {
            j: 3 * m - 2,
            t: [1.0, 0.0],
            delta: 0.1,
        }];
        assert!(!renewed.factor(&[], &bad));
        let again = renewed.renewed(&k, &b, &bt).expect("G's pattern");
        assert!(!again.step.borrow().analysed);
    }

    fn check_inverse(empty_last: bool) {
        let m = 12;
        let (k, b, r) = made(m, empty_last);
        let c = 3 * m;
        // G = B K B^T densely (B touches the face alone).
        let (kd, bd) = (dense(&k), dense(&b));
        let mut g = vec![vec![0.0; c]; c];
        for i in 0..c {
            for j in 0..c {
                for p in 0..k.nrows {
                    for q in 0..k.nrows {
                        g[i][j] += bd[i][p] * kd[p][q] * bd[j][q];
                    }
                }
            }
        }
        if empty_last {
            for j in [m - 1, 3 * m - 2, 3 * m - 1] {
                assert_eq!(g[j][j], 0.0);
                g[j][j] = 1.0;
            }
        }
        let (prescribed, pairs) = steps(m);
        // T's columns: the prescribed unit vectors, then the pairs' t.
        let mut tcols: Vec<Vec<f64>> = prescribed
            .iter()
            .map(|&j| (0..c).map(|i| f64::from(i == j)).collect())
            .collect();
        for pr in &pairs {
            let mut v = vec![0.0; c];
            (v[pr.j], v[pr.j + 1]) = (pr.t[0], pr.t[1]);
            tcols.push(v);
        }
        let nk = tcols.len();
        let ginv_t: Vec<Vec<f64>> = tcols
            .iter()
            .map(|t| {
                let mut v = t.clone();
                solve(g.clone(), &mut v);
                v
            })
            .collect();
        let mut mat = vec![vec![0.0; nk]; nk];
        for a in 0..nk {
            for bb in 0..nk {
                mat[a][bb] = (0..c).map(|i| tcols[a][i] * ginv_t[bb][i]).sum();
            }
        }
        for (l, pr) in pairs.iter().enumerate() {
            mat[prescribed.len() + l][prescribed.len() + l] += pr.delta;
        }
        for _round in 0..2 {
            assert!(r.factor(&prescribed, &pairs));
            let x: Vec<f64> = (0..nk).map(|l| (0.7 * l as f64).sin() + 0.3).collect();
            let mut want = x.clone();
            solve(mat.clone(), &mut want);
            let (got, _) = applied(&r, &prescribed, &pairs, &x);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() <= 1e-11 * scale, "{g} against {w}");
            }
        }
    }

    /// X^T of `add_extension_t` is the transpose of the extension `apply`
    /// returns: <X x, w> = <x, X^T w>.
    #[test]
    fn the_extensions_transpose_is_its_adjoint() {
        let m = 12;
        let (_, _, r) = made(m, false);
        let c = 3 * m;
        let (prescribed, pairs) = steps(m);
        assert!(r.factor(&prescribed, &pairs));
        let (np, ns) = (prescribed.len(), pairs.len());
        let x: Vec<f64> = (0..np + ns).map(|l| (1.3 * l as f64).cos()).collect();
        let w: Vec<f64> = (0..c).map(|i| (0.4 * i as f64).sin() - 0.1).collect();
        let (_, nu) = applied(&r, &prescribed, &pairs, &x);
        let (mut tp, mut ts) = (vec![0.0; np], vec![0.0; ns]);
        r.add_extension_t(&prescribed, &pairs, &w, &mut tp, &mut ts);
        let lhs: f64 = nu.iter().zip(&w).map(|(a, b)| a * b).sum();
        let rhs: f64 = x.iter().zip(tp.iter().chain(&ts)).map(|(a, b)| a * b).sum();
        assert!(
            (lhs - rhs).abs() <= 1e-12 * lhs.abs().max(1.0),
            "{lhs} against {rhs}"
        );
    }
}
