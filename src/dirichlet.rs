//! The layered Dirichlet preconditioner of a matrix-free dual: an approximate
//! inverse of A = B K^-1 B^T stronger than the lumped G = B K B^T.
//!
//! Where B touches the face DOFs F alone, A = B S^-1 B^T with S the Schur
//! complement of K onto F (the body's stiffness seen from its contact face),
//! and B S B^T inverts A exactly where B is square and orthogonal on F (nodal
//! normal and tangent rows). The lumped preconditioner replaces S by K_FF:
//! the face with every other DOF clamped. FETI's Dirichlet preconditioner
//! uses S itself; this one the Schur complement of the LAYERS layers of DOFs
//! next to the face (graph distance in K at most LAYERS from F), clamped
//! beyond them:
//!
//! ```text
//! S_l y = K_FF y - K_FI K_II^-1 K_IF y,   G_D = B S_l B^T,
//! ```
//!
//! one sparse solve with the factor of K_II (a thin shell of the body, far
//! cheaper than a solve with K's factor) per application. S_l lies between S
//! and K_FF (Schur complements grow as DOFs are clamped), so G_D lies between
//! A^-1 and G. On the thin slabs of the benchmark one layer cuts the products
//! of a history step by a third (BENCHMARKS.md, "Quasistatic histories"). It
//! is applied in single precision (K_loc's entries and L_II's values rounded,
//! 32-bit row indices): the application is bound by memory traffic, and a
//! preconditioner's rounding of 1e-7 is far below what it approximates.

use crate::factor::Factor;
use crate::memory::{Claim, Ledger};
use crate::options::Ordering;
use crate::restricted::Restricted;
use crate::sparse::Csc;
use crate::threads::Threads;
use faer::MatMut;
use faer::dyn_stack::{MemBuffer, MemStack};
use std::cell::RefCell;
use std::sync::Arc;

/// Layers of DOFs next to the contact face that the preconditioner eliminates.
pub(crate) const LAYERS: usize = 1;

/// The preconditioner is formed only where one application (the entries of
/// K_loc read once, L_II's twice) costs at most this fraction of a product
/// with A (L's entries read twice).
const MAX_COST: f64 = 0.2;

/// The face, its layers and their matrices, analysed (no numeric factor yet),
/// with the restricted preconditioner of Newton's reduced systems analysed
/// (its G and order; counted on the ledger once formed).
pub(crate) struct Plan {
    /// Global DOF of each local one: the face DOFs first, then the layers'.
    global: Vec<usize>,
    nf: usize,
    /// K on the face and the layers (local indices, both triangles).
    k_loc: Csc,
    /// K_II, and its analysed factor.
    k_ii: Csc,
    factor: Factor,
    /// The lumped preconditioner restricted to Newton's reduced systems
    /// (`restricted.rs`), analysed; None where its analysis failed.
    restricted: Option<Restricted>,
}

impl Plan {
    /// The LAYERS layers of K (both triangles stored) around the DOFs B
    /// touches, with K_II analysed on `threads` (its numeric factor counted
    /// on `ledger`); None where the layer is empty, or where one application
    /// would cost more than MAX_COST of a product with K's factor `of_k`.
    pub(crate) fn of(
        k: &Csc,
        b: &Csc,
        of_k: &Factor,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Option<Plan> {
        Self::within(k, b, of_k.nnz_and_flops().0, threads, ledger)
    }

    /// As [`Plan::of`], for a solve with K that reads `l_nnz` entries of a
    /// factor (on the host's solves, whose factor the library does not know:
    /// the entries of K's lower triangle, which every factor of K holds).
    pub(crate) fn within(
        k: &Csc,
        b: &Csc,
        l_nnz: usize,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Option<Plan> {
        let budget = MAX_COST * 2.0 * l_nnz as f64;
        let plan = Self::with_layers(k, b, LAYERS, budget, threads, ledger)?;
        let (nnz, _) = plan.factor.nnz_and_flops();
        ((plan.k_loc.nnz() + 2 * nnz) as f64 <= budget).then(|| plan.restricted_to(k, b))
    }

    /// The plan of LAYERS layers whatever it costs (None where they are empty).
    #[cfg(test)]
    pub(crate) fn unguarded(
        k: &Csc,
        b: &Csc,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Option<Plan> {
        Self::with_layers(k, b, LAYERS, f64::INFINITY, threads, ledger)
            .map(|p| p.restricted_to(k, b))
    }

    /// The plan with the restricted preconditioner of K = `k` and B = `b`
    /// analysed.
    fn restricted_to(mut self, k: &Csc, b: &Csc) -> Plan {
        let (threads, ledger) = (self.factor.threads().clone(), self.factor.ledger().clone());
        self.restricted = Restricted::new(k, b, threads, ledger);
        self
    }

    /// The plan of `layers` layers; None where they are empty, or hold more
    /// entries of K than `budget`.
    fn with_layers(
        k: &Csc,
        b: &Csc,
        layers: usize,
        budget: f64,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    ) -> Option<Plan> {
        let face = crate::contact_rows::contact_dofs(b);
        let mut local = vec![usize::MAX; k.nrows];
        for (l, &j) in face.iter().enumerate() {
            local[j] = l;
        }
        let mut global = face.clone();
        let mut frontier = face.clone();
        for _ in 0..layers {
            let mut next = Vec::new();
            for &j in &frontier {
                for &i in &k.row_idx[k.col_ptr[j]..k.col_ptr[j + 1]] {
                    if local[i] == usize::MAX {
                        local[i] = global.len();
                        global.push(i);
                        next.push(i);
                    }
                }
            }
            frontier = next;
        }
        let nf = face.len();
        let (k_loc, k_ii) = gather(k, &global, nf, budget)?;
        let factor = Factor::analyse(&k_ii, &[], Ordering::Amd, false, threads, ledger).ok()?;
        Some(Plan {
            global,
            nf,
            k_loc,
            k_ii,
            factor,
            restricted: None,
        })
    }

    /// G = B K B^T of the restricted preconditioner, where its analysis
    /// succeeded: the lumped preconditioner of the dual the plan is for.
    pub(crate) fn lumped(&self) -> Option<&Csc> {
        self.restricted.as_ref().map(Restricted::g)
    }

    /// Bytes the formed preconditioner holds: K_loc's two blocks and L_II's
    /// values in single precision, L_II's own values and workspace, the
    /// solve's workspace and two vectors, and the restricted preconditioner
    /// of Newton's reduced systems ([`Restricted::bytes`]).
    pub(crate) fn bytes(&self) -> usize {
        let nl = self.global.len();
        let entries = self.k_loc.nnz();
        entries * 8
            + self.factor.values_bytes() * 3 / 2
            + self.factor.factor_scratch_bytes()
            + self.factor.solve_scratch_single().size_bytes()
            + 2 * nl * 4
            + self.restricted.as_ref().map_or(0, Restricted::bytes)
    }

    /// Factors K_II and keeps what the application reads in single precision;
    /// None where the factorisation fails (it cannot, K_II being a principal
    /// block of an SPD K, but rounding may say otherwise) or the allocator
    /// refuses its copy (the products then go without this preconditioner).
    pub(crate) fn form(mut self, ledger: &Arc<Ledger>) -> Option<Dirichlet> {
        self.factor.refactor(&self.k_ii).ok()?;
        let (nf, nl) = (self.nf, self.global.len());
        let k = &self.k_loc;
        // The face's columns (K_FF over K_IF), and the layer's columns cut to
        // the face's rows (K_FI).
        let face_cols = Block::of(k, 0..nf, nl);
        let layer_cols = Block::of(k, nf..nl, nf);
        let l_ii = self.factor.single_values().ok()?;
        let claim =
            ledger.claim(face_cols.bytes() + layer_cols.bytes() + l_ii.len() * 4 + 2 * nl * 4);
        Some(Dirichlet {
            mem: RefCell::new(
                crate::memory::try_scratch(self.factor.solve_scratch_single(), "").ok()?,
            ),
            work: RefCell::new((vec![0.0; nl], vec![0.0; nl])),
            global: self.global,
            nf,
            face_cols,
            layer_cols,
            l_ii,
            factor: self.factor,
            restricted: self.restricted.map(|mut r| {
                r.count();
                r
            }),
            _claim: claim,
        })
    }
}

/// K on the face and its layers (`global`: the face's `nf` DOFs first, then
/// the layers'), local indices, both triangles, and K_II its trailing block;
/// None where the layers are empty, their order does not fit the
/// application's 32-bit row indices, or K_loc holds more entries than
/// `budget`.
fn gather(k: &Csc, global: &[usize], nf: usize, budget: f64) -> Option<(Csc, Csc)> {
    let nl = global.len();
    // The application's blocks index rows in 32 bits.
    if nl == nf || u32::try_from(nl).is_err() {
        return None;
    }
    let mut local = vec![usize::MAX; k.nrows];
    for (l, &j) in global.iter().enumerate() {
        local[j] = l;
    }
    // K_loc column by column (K's column restricted to local rows, sorted
    // by local index), and K_II as its trailing block.
    let mut k_loc = Csc {
        nrows: nl,
        ncols: nl,
        col_ptr: Vec::with_capacity(nl + 1),
        row_idx: Vec::new(),
        values: Vec::new(),
    };
    let mut col: Vec<(usize, f64)> = Vec::new();
    k_loc.col_ptr.push(0);
    for &j in global {
        col.clear();
        for p in k.col_ptr[j]..k.col_ptr[j + 1] {
            let li = local[k.row_idx[p]];
            if li != usize::MAX {
                col.push((li, k.values[p]));
            }
        }
        col.sort_unstable_by_key(|e| e.0);
        k_loc.row_idx.extend(col.iter().map(|e| e.0));
        k_loc.values.extend(col.iter().map(|e| e.1));
        k_loc.col_ptr.push(k_loc.row_idx.len());
        if k_loc.row_idx.len() as f64 > budget {
            return None;
        }
    }
    let mut k_ii = Csc {
        nrows: nl - nf,
        ncols: nl - nf,
        col_ptr: Vec::with_capacity(nl - nf + 1),
        row_idx: Vec::new(),
        values: Vec::new(),
    };
    k_ii.col_ptr.push(0);
    for j in nf..nl {
        for p in k_loc.col_ptr[j]..k_loc.col_ptr[j + 1] {
            if k_loc.row_idx[p] >= nf {
                k_ii.row_idx.push(k_loc.row_idx[p] - nf);
                k_ii.values.push(k_loc.values[p]);
            }
        }
        k_ii.col_ptr.push(k_ii.row_idx.len());
    }
    Some((k_loc, k_ii))
}

/// Columns of K_loc cut to rows below `rows`, in single precision with
/// 32-bit row indices (the application is bound by memory traffic; a plan
/// exists only where K_loc's order fits them).
struct Block {
    col_ptr: Vec<usize>,
    row: Vec<u32>,
    val: Vec<f32>,
}

impl Block {
    fn of(k: &Csc, cols: std::ops::Range<usize>, rows: usize) -> Block {
        let mut b = Block {
            col_ptr: vec![0],
            row: Vec::new(),
            val: Vec::new(),
        };
        for j in cols {
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                if k.row_idx[p] < rows {
                    b.row.push(k.row_idx[p] as u32);
                    b.val.push(k.values[p] as f32);
                }
            }
            b.col_ptr.push(b.row.len());
        }
        b
    }

    fn bytes(&self) -> usize {
        self.col_ptr.len() * 8 + self.row.len() * 8
    }
}

/// The layer of K and B (`b`) on K's factor `of_k`, analysed on its threads
/// and counted on its ledger where it is formed (None where it does not pay):
/// kept by the caller from the memory prediction ([`Plan::bytes`]) to the
/// formation, so that the layer is analysed once (a symbolic factorisation
/// of K_II).
pub(crate) fn layer_of(k: &Csc, b: &Csc, of_k: &Factor) -> Option<Plan> {
    Plan::of(k, b, of_k, of_k.threads().clone(), of_k.ledger().clone())
}

/// G_D = B S_l B^T of the module docs, applied matrix-free in single
/// precision (a preconditioner: its rounding, about 1e-7 relative, is far
/// below what it approximates).
pub(crate) struct Dirichlet {
    /// Global DOF of each local one: the face's `nf` DOFs first, then the
    /// layers' (kept for a refactor on K's pattern: [`Dirichlet::renewed`]).
    global: Vec<usize>,
    nf: usize,
    face_cols: Block,
    layer_cols: Block,
    /// L_II's values in single precision, on `factor`'s pattern.
    l_ii: Vec<f32>,
    factor: Factor,
    /// Scratch: the local vector and K_loc times it; the solve's workspace.
    work: RefCell<(Vec<f32>, Vec<f32>)>,
    mem: RefCell<MemBuffer>,
    restricted: Option<Restricted>,
    _claim: Claim,
}

impl Dirichlet {
    /// The lumped preconditioner restricted to Newton's reduced systems, where
    /// its analysis succeeded.
    pub(crate) fn restricted(&self) -> Option<&Restricted> {
        self.restricted.as_ref()
    }

    /// The plan of this preconditioner for K = `k` of the pattern of the K
    /// it was formed on, and the same B = `b` (`bt` its transpose): the
    /// same face and layers, K_II's analysis and G's order kept (the
    /// values gathered from `k`, G formed afresh), for a refactor. None
    /// where K_II's pattern differs (the caller then analyses anew); where
    /// G's differs, the restricted preconditioner is analysed anew here.
    pub(crate) fn renewed(&self, k: &Csc, b: &Csc, bt: &Csc) -> Option<Plan> {
        let (k_loc, k_ii) = gather(k, &self.global, self.nf, f64::INFINITY)?;
        let factor = self.factor.unfactored_copy();
        if !factor.same_pattern(&k_ii) {
            return None;
        }
        let restricted = match &self.restricted {
            Some(r) => r.renewed(k, b, bt).or_else(|| {
                Restricted::new(k, b, factor.threads().clone(), factor.ledger().clone())
            }),
            None => None,
        };
        Some(Plan {
            global: self.global.clone(),
            nf: self.nf,
            k_loc,
            k_ii,
            factor,
            restricted,
        })
    }

    /// Drops the restricted preconditioner (the tests that measure what it
    /// buys).
    #[cfg(test)]
    pub(crate) fn drop_restricted(&mut self) {
        self.restricted = None;
    }

    /// y := B S_l B^T x (x and y of length c), B = `b`. B's columns outside
    /// the face are empty (the face is the DOFs B touches).
    pub(crate) fn apply(&self, b: &Csc, x: &[f64], y: &mut [f64]) {
        let mut work = self.work.borrow_mut();
        let (v, kv) = &mut *work;
        let (nf, nl) = (self.nf, self.global.len());
        // v_F = B^T x on the face.
        for (l, &j) in self.global[..nf].iter().enumerate() {
            v[l] = (b.col_ptr[j]..b.col_ptr[j + 1])
                .map(|p| b.values[p] * x[b.row_idx[p]])
                .sum::<f64>() as f32;
        }
        // kv = [K_FF; K_IF] v_F.
        kv.iter_mut().for_each(|e| *e = 0.0);
        let fc = &self.face_cols;
        for (j, &vj) in v[..nf].iter().enumerate() {
            if vj != 0.0 {
                for p in fc.col_ptr[j]..fc.col_ptr[j + 1] {
                    kv[fc.row[p] as usize] += fc.val[p] * vj;
                }
            }
        }
        // s = K_II^-1 K_IF v_F (in v's layer part), then S_l v_F = K_FF v_F - K_FI s.
        let s = &mut v[nf..nl];
        s.copy_from_slice(&kv[nf..nl]);
        self.factor.solve_single(
            &self.l_ii,
            MatMut::from_column_major_slice_mut(s, nl - nf, 1),
            MemStack::new(&mut self.mem.borrow_mut()),
        );
        let lc = &self.layer_cols;
        for (l, &sl) in v[nf..].iter().enumerate() {
            for p in lc.col_ptr[l]..lc.col_ptr[l + 1] {
                kv[lc.row[p] as usize] -= lc.val[p] * sl;
            }
        }
        // y = B (S_l v_F).
        y.iter_mut().for_each(|e| *e = 0.0);
        for (l, &j) in self.global[..nf].iter().enumerate() {
            let val = f64::from(kv[l]);
            if val != 0.0 {
                for p in b.col_ptr[j]..b.col_ptr[j + 1] {
                    y[b.row_idx[p]] += b.values[p] * val;
                }
            }
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::dual::tests::grid;
    use crate::dual::{Condensation, Dual};

    /// The grid of `dual::tests::grid` with its bottom row a contact face
    /// (one unit row of B per bottom DOF: B square and orthogonal on F), K's
    /// factor and the assembled A.
    fn scene(nx: usize, ny: usize) -> (Csc, Csc, Arc<Factor>, Dual) {
        let k = grid(nx, ny);
        let rows: Vec<_> = (0..nx).map(|i| (i, i, 1.0)).collect();
        let b = Csc::from_triplets(nx, nx * ny, &rows);
        let factor = Factor::with_last(&k, &[], Ordering::Amd, Arc::new(Threads::new(1))).unwrap();
        let empty = Csc::from_triplets(0, nx * ny, &[]);
        let dual = Dual::build_with(&factor, &b, &empty, 1, Condensation::Solves).unwrap();
        (k, b, factor, dual)
    }

    fn formed(k: &Csc, b: &Csc, layers: usize) -> Dirichlet {
        let ledger = Ledger::new();
        let threads = Arc::new(Threads::new(1));
        Plan::with_layers(k, b, layers, f64::INFINITY, threads, ledger.clone())
            .expect("layers")
            .form(&ledger)
            .expect("K_II is SPD")
    }

    fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    #[test]
    fn with_every_layer_it_is_the_inverse_of_a() {
        let (nx, ny) = (12, 9);
        let (k, b, _, dual) = scene(nx, ny);
        // ny - 1 layers reach every DOF: S_l is the Schur complement S itself.
        let dn = formed(&k, &b, ny - 1);
        let x: Vec<f64> = (0..nx).map(|i| (i as f64 * 0.7).sin() + 0.2).collect();
        let (mut gx, mut agx) = (vec![0.0; nx], vec![0.0; nx]);
        dn.apply(&b, &x, &mut gx);
        dual.apply(&gx, &mut agx);
        let err = agx
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // To the single precision the preconditioner is applied in.
        assert!(
            err <= 1e-5 * x.iter().fold(0.0f64, |m, v| m.max(v.abs())),
            "{err:.2e}"
        );
    }

    /// On the host's solves the preconditioner is weighed as on the own path,
    /// against the factor the library would make of K (`dual::host_layer`):
    /// where it pays on the own path it is formed there too, which the old
    /// weighing against K's lower triangle alone refused.
    #[test]
    fn on_the_hosts_solves_it_is_weighed_as_on_the_own_path() {
        let (nx, ny) = (60, 30);
        let (k, b, factor, _) = scene(nx, ny);
        let (threads, ledger) = (Arc::new(Threads::new(1)), Ledger::new());
        let own = Plan::of(&k, &b, &factor, threads.clone(), ledger.clone());
        let host = crate::dual::host_layer(&k, &b, 2, &threads, &ledger);
        let lower = Plan::within(&k, &b, (k.nnz() + k.nrows) / 2, threads, ledger);
        assert!(own.is_some(), "the preconditioner pays on this grid");
        assert_eq!(host.map(|p| p.bytes()), own.map(|p| p.bytes()));
        assert!(lower.is_none(), "K's lower triangle alone refuses it");
    }

    /// A matrix-free dual whose layered preconditioner pays takes its lumped
    /// G from the restricted preconditioner's analysis: the same matrix as
    /// B K B^T formed directly, bit for bit.
    #[test]
    fn the_lumped_g_taken_from_the_plan_is_b_k_bt() {
        let (nx, ny) = (60, 30);
        let (k, b, factor, _) = scene(nx, ny);
        let empty = Csc::from_triplets(0, nx * ny, &[]);
        let mut dual = Dual::build_with(&factor, &b, &empty, 1, Condensation::MatrixFree).unwrap();
        dual.set_lumped(&k, None);
        assert!(dual.restricted().is_some(), "the layer pays on this grid");
        let direct = crate::sparse::congruence(&k, &b, &b.transpose());
        let g = dual.lumped().expect("a lumped G");
        assert_eq!((&g.col_ptr, &g.row_idx), (&direct.col_ptr, &direct.row_idx));
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&g.values), bits(&direct.values));
        assert_eq!(
            bits(&dual.restricted().unwrap().g().values),
            bits(&direct.values)
        );
    }

    /// A refactor's plan, renewed from the preconditioner of the old K,
    /// is the plan analysed afresh on the new K (the same pattern, values
    /// D K D with D varying): the same application and the same G, bit for
    /// bit.
    #[test]
    fn a_renewed_plan_is_the_plan_made_afresh() {
        let (nx, ny) = (60, 30);
        let (k, b, factor, _) = scene(nx, ny);
        let d: Vec<f64> = (0..k.nrows)
            .map(|i| 1.0 + 0.05 * (i as f64 * 0.37).sin())
            .collect();
        let mut k2 = k.clone();
        for j in 0..k2.ncols {
            for p in k2.col_ptr[j]..k2.col_ptr[j + 1] {
                k2.values[p] *= d[k2.row_idx[p]] * d[j];
            }
        }
        let (threads, ledger) = (Arc::new(Threads::new(1)), Ledger::new());
        let plan = |k: &Csc| Plan::of(k, &b, &factor, threads.clone(), ledger.clone());
        let old = plan(&k).expect("it pays").form(&ledger).expect("formed");
        let renewed = old
            .renewed(&k2, &b, &b.transpose())
            .expect("the same pattern");
        let afresh = plan(&k2).expect("it pays");
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (g_renewed, g_afresh) = (renewed.lumped().unwrap(), afresh.lumped().unwrap());
        assert_eq!(bits(&g_renewed.values), bits(&g_afresh.values));
        let (renewed, afresh) = (
            renewed.form(&ledger).unwrap(),
            afresh.form(&ledger).unwrap(),
        );
        let x: Vec<f64> = (0..nx).map(|i| (i as f64 * 0.7).sin() + 0.2).collect();
        let (mut yr, mut ya, mut yo) = (vec![0.0; nx], vec![0.0; nx], vec![0.0; nx]);
        renewed.apply(&b, &x, &mut yr);
        afresh.apply(&b, &x, &mut ya);
        old.apply(&b, &x, &mut yo);
        assert_eq!(bits(&yr), bits(&ya));
        assert_ne!(
            bits(&yr),
            bits(&yo),
            "the new K's preconditioner, not the old one's"
        );
        // Another pattern: K with one more coupling inside the layer (two
        // DOFs of the grid's second row) is not renewed.
        let mut t = Vec::new();
        for j in 0..k.ncols {
            for p in k.col_ptr[j]..k.col_ptr[j + 1] {
                t.push((k.row_idx[p], j, k.values[p]));
            }
        }
        t.extend([(nx + 1, nx + 9, 1e-3), (nx + 9, nx + 1, 1e-3)]);
        let k3 = Csc::from_triplets(k.nrows, k.ncols, &t);
        assert!(old.renewed(&k3, &b, &b.transpose()).is_none());
    }

    #[test]
    fn one_layer_lies_between_the_inverse_of_a_and_the_lumped_one() {
        let (nx, ny) = (30, 20);
        let (k, b, _, _) = scene(nx, ny);
        let dn = formed(&k, &b, 1);
        // Every layer: A^-1 itself (the test above).
        let exact_inv = formed(&k, &b, ny - 1);
        let g = crate::sparse::congruence(&k, &b, &b.transpose());
        // x^T A^-1 x <= x^T G_D x <= x^T G x.
        for seed in 0..4 {
            let x: Vec<f64> = (0..nx)
                .map(|i| ((i * (seed + 3)) as f64 * 0.9).cos() + if seed == 0 { 1.0 } else { 0.0 })
                .collect();
            let mut ainv_x = vec![0.0; nx];
            exact_inv.apply(&b, &x, &mut ainv_x);
            let (mut gdx, mut gx) = (vec![0.0; nx], vec![0.0; nx]);
            dn.apply(&b, &x, &mut gdx);
            g.mul_vec(&x, &mut gx);
            let (exact, dirichlet, lumped) = (dot(&x, &ainv_x), dot(&x, &gdx), dot(&x, &gx));
            assert!(
                exact <= dirichlet * (1.0 + 1e-5) && dirichlet <= lumped * (1.0 + 1e-5),
                "{exact} {dirichlet} {lumped}"
            );
            // And strictly inside: the layer is neither the body nor nothing
            // (far inside for the smooth x, whose response reaches deep).
            let gap = if seed == 0 { 0.99 } else { 1.0 - 1e-4 };
            assert!(
                exact < gap * dirichlet && dirichlet < 0.99 * lumped,
                "{seed}: {exact} {dirichlet} {lumped}"
            );
        }
    }
}
