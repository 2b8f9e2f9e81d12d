//! The contacts' d x d diagonal blocks of A = B K^-1 B^T, from K's factor and
//! without forming anything c x c. Two ways, chosen by their flop counts:
//!
//! - **Selected inversion** (`crate::factor_tree::selected_inverse`): A_ii = B_i Z B_i^T needs
//!   the entries of Z = K^-1 between contact i's DOFs; when they all lie on the
//!   factor's pattern (the DOFs of one node, of neighbouring nodes, or of two
//!   bodies, whose entries are zero), they come from Takahashi's recurrence on
//!   the supernodes above the contact face, visited once for all contacts.
//!   About twice the factorisation's flops on those supernodes.
//! - **Forward solves**: with L L^T = P K P^T and W_i = L^-1 P B_i^T (B_i:
//!   contact i's d rows of B), A_ii = W_i^T W_i. Each W_i is a sparse forward
//!   solve whose nonzeros lie in the supernodes on the elimination-tree paths
//!   from the supernodes of B_i's DOFs to the root. Contacts are taken GROUP at a
//!   time, sorted by their first supernode so that a group's paths share most of
//!   their supernodes; a group's solve runs on a dense block of the rows of the
//!   union of its paths, by dense triangular solves and products per supernode
//!   (BLAS-3), and groups run in parallel on the problem's threads. Cheaper for
//!   a few contacts (each pays only its path; the selected inversion pays
//!   every top separator in full), and the only way for contacts whose DOFs are
//!   off the pattern.
//!
//! On the benchmark's slab (3d-64x64x6, c = 12,675) the forward solves need 3.5 x
//! the factorisation's flops (every contact's path crosses the top separators,
//! w^2 per column there), the selected inversion 2.0 x.
//!
//! Where the factor's single-precision copy is at hand (the matrix-free dual
//! makes it for its rough products) a selected inversion of at least
//! SINGLE_MIN_FLOPS runs on it in single precision, checked against a sample
//! of contacts solved forward in double precision ([`contact_blocks_single`]).
//!
//! The matrix-free dual needs these blocks for rho (the error measure,
//! docs/design.md section 5), for the diagonal of A and for Newton's
//! preconditioner.

use crate::factor::Factor;
use crate::factor_tree::selected_inverse::{Place, Selection, Term, place};
use crate::factor_tree::supernode_tree::Tree;
use crate::sparse::Csc;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Accum, Mat, MatMut, Par};
use rayon::prelude::*;

/// Contacts solved together (d right-hand sides each).
const GROUP: usize = 32;

/// The rows of B that belong to contact i of m (d rows: i, then the d-1 tangent
/// rows m + (d-1) i ..).
fn rows_of(i: usize, m: usize, d: usize) -> impl Iterator<Item = usize> {
    std::iter::once(i).chain((0..d - 1).map(move |s| m + (d - 1) * i + s))
}

/// One worker's scratch: the marks and local offsets of supernodes, the list of a
/// group's supernodes, and the buffer of a product.
struct Scratch {
    mark: Vec<usize>,
    offset: Vec<usize>,
    /// Per supernode of the group's union, the first and last of the group's
    /// columns whose path passes through it (the others are zero there).
    lo: Vec<usize>,
    hi: Vec<usize>,
    list: Vec<usize>,
    /// The local rows the pattern of the current supernode updates.
    dest: Vec<usize>,
    buf: Vec<f64>,
}

impl Scratch {
    fn new(ns: usize) -> Scratch {
        Scratch {
            mark: vec![usize::MAX; ns],
            offset: vec![0; ns],
            lo: vec![0; ns],
            hi: vec![0; ns],
            list: Vec::new(),
            dest: Vec::new(),
            buf: Vec::new(),
        }
    }
}

/// The contact face in the terms of a sparse factor: B^T, the factor's
/// supernodal tree and position of each DOF, and m contacts of d rows.
struct Face<'a> {
    factor: &'a Factor,
    tree: Tree,
    new_of: Vec<usize>,
    bt: Csc,
    m: usize,
    d: usize,
}

impl<'a> Face<'a> {
    fn new(factor: &'a Factor, b: &Csc, m: usize, d: usize) -> Face<'a> {
        Face {
            factor,
            tree: Tree::of(factor),
            new_of: factor.new_of_old(),
            bt: b.transpose(),
            m,
            d,
        }
    }

    /// Contact i's rows of B.
    fn rows(&self, i: usize) -> impl Iterator<Item = usize> + use<> {
        rows_of(i, self.m, self.d)
    }

    /// The DOFs (original numbering) of row r of B.
    fn dofs(&self, r: usize) -> &[usize] {
        &self.bt.row_idx[self.bt.col_ptr[r]..self.bt.col_ptr[r + 1]]
    }

    /// The supernode holding a DOF (original numbering).
    fn supernode(&self, dof: usize) -> usize {
        self.tree.of_col[self.new_of[dof]]
    }

    /// The plan of `route`.
    fn plan(&self, route: Route) -> Plan {
        let (factor, tree, bt) = (self.factor, &self.tree, &self.bt);
        let (m, d) = (self.m, self.d);
        let order = self.ordered();
        if route == Route::Forward {
            return Plan {
                selection: None,
                on: Vec::new(),
                forward: order,
            };
        }
        let dd = d * d;
        let mut terms = Vec::new();
        let (mut on, mut off) = (Vec::new(), Vec::new());
        let mut entries = Vec::new();
        let mut mine = Vec::new();
        'contacts: for &(s0, i) in &order {
            entries.clear();
            for (a, r) in rows_of(i, m, d).enumerate() {
                for p in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                    entries.push((a, self.new_of[bt.row_idx[p]], bt.values[p]));
                }
            }
            mine.clear();
            for &(a, j, x) in &entries {
                for &(e, k, y) in entries.iter().filter(|&&(e, _, _)| e >= a) {
                    match place(factor, tree, j, k) {
                        Place::At { s, row, col } => mine.push(Term {
                            slot: i * dd + a * d + e,
                            s,
                            row,
                            col,
                            coef: x * y,
                        }),
                        Place::Zero => {}
                        Place::Outside => {
                            off.push((s0, i));
                            continue 'contacts;
                        }
                    }
                }
            }
            terms.extend_from_slice(&mine);
            on.push((s0, i));
        }
        let selection = Selection::new(factor, tree, terms);
        let taken = route == Route::Selected || selection.flops() < self.forward_flops(&on);
        if taken {
            Plan {
                selection: Some(selection),
                on,
                forward: off,
            }
        } else {
            Plan {
                selection: None,
                on: Vec::new(),
                forward: order,
            }
        }
    }

    /// Flops of the forward solves of `contacts` ((first supernode, contact)
    /// pairs): per row of B, w^2 + 2 w r for each supernode (width w, r rows below)
    /// on the paths from its DOFs to the root.
    fn forward_flops(&self, contacts: &[(usize, usize)]) -> f64 {
        let tree = &self.tree;
        let sym = self.factor.supernodal_symbolic();
        let cost: Vec<f64> = (0..tree.len())
            .map(|s| {
                let (w, r) = (
                    tree.width[s] as f64,
                    sym.supernode(s).pattern().len() as f64,
                );
                w * w + 2.0 * w * r
            })
            .collect();
        let mut mark = vec![usize::MAX; tree.len()];
        let mut total = 0.0;
        for &(_, i) in contacts {
            for r in self.rows(i) {
                for &dof in self.dofs(r) {
                    let mut s = self.supernode(dof);
                    while s != usize::MAX && mark[s] != r {
                        mark[s] = r;
                        total += cost[s];
                        s = tree.parent[s];
                    }
                }
            }
        }
        total
    }

    /// Whether blocks from a selected inversion in single precision
    /// (`rough`, the upper triangles of the contacts of `on`) serve: every
    /// diagonal entry of `on`'s blocks finite and not negative, and the upper
    /// triangles of a sample of them within [`SINGLE_TOL`] of their forward
    /// solves in double precision (relative to the block's largest diagonal
    /// entry). The sample: [`SAMPLE`] contacts spread over `on` (ordered by
    /// supernode, so over the elimination tree's subtrees), and the contacts
    /// with the smallest and the largest trace. A check of the sampled
    /// contacts only: an error confined to a few unsampled contacts passes.
    fn confirms(&self, on: &[(usize, usize)], rough: &[f64]) -> bool {
        let d = self.d;
        let dd = d * d;
        let trace =
            |blocks: &[f64], i: usize| (0..d).map(|a| blocks[i * dd + a * d + a]).sum::<f64>();
        let diagonal_ok = on.iter().all(|&(_, i)| {
            (0..d).all(|a| {
                let v = rough[i * dd + a * d + a];
                v.is_finite() && v >= 0.0
            })
        });
        if !diagonal_ok || on.is_empty() {
            return diagonal_ok;
        }
        let step = on.len().div_ceil(SAMPLE).max(1);
        let mut sample: Vec<(usize, usize)> = on.iter().step_by(step).copied().collect();
        let by_trace = |a: &&(usize, usize), b: &&(usize, usize)| {
            trace(rough, a.1).total_cmp(&trace(rough, b.1))
        };
        sample.extend(on.iter().min_by(by_trace));
        sample.extend(on.iter().max_by(by_trace));
        sample.sort_unstable();
        sample.dedup();
        let mut exact = vec![0.0; self.m * dd];
        self.forward_blocks(&sample, &mut exact);
        sample.iter().all(|&(_, i)| {
            let scale = (0..d)
                .map(|a| exact[i * dd + a * d + a].abs())
                .fold(0.0, f64::max);
            (0..d).all(|a| {
                (a..d).all(|e| {
                    let at = i * dd + a * d + e;
                    (rough[at] - exact[at]).abs() <= SINGLE_TOL * scale
                })
            })
        })
    }

    /// The blocks of the contacts `order` ((first supernode, contact) pairs sorted
    /// by supernode) by grouped sparse forward solves, written into `blocks`.
    fn forward_blocks(&self, order: &[(usize, usize)], blocks: &mut [f64]) {
        let (factor, d) = (self.factor, self.d);
        let ns = self.tree.len();
        let groups: Vec<&[(usize, usize)]> = order.chunks(GROUP).collect();
        let solve_group = |group: &[(usize, usize)], ws: &mut Scratch| self.group_blocks(group, ws);
        let (nnz, flops) = factor.nnz_and_flops();
        let parallel = groups.len() > 1 && flops > 1e7 && nnz > 0;
        let results: Vec<Vec<f64>> = factor.threads().run(parallel, |par| match par {
            Par::Seq => {
                let mut ws = Scratch::new(ns);
                groups.iter().map(|g| solve_group(g, &mut ws)).collect()
            }
            _ => groups
                .par_iter()
                .map_init(|| Scratch::new(ns), |ws, g| solve_group(g, ws))
                .collect(),
        });
        let dd = d * d;
        for (group, res) in groups.iter().zip(&results) {
            for (slot, &(_, i)) in group.iter().enumerate() {
                blocks[i * dd..(i + 1) * dd].copy_from_slice(&res[slot * dd..(slot + 1) * dd]);
            }
        }
    }

    /// The contacts with entries in B (`bt` = B^T), as (first supernode, contact)
    /// pairs sorted by their first (deepest) supernode: the order they are solved in.
    fn ordered(&self) -> Vec<(usize, usize)> {
        let first = |i: usize| {
            self.rows(i)
                .flat_map(|r| self.dofs(r))
                .map(|&dof| self.supernode(dof))
                .min()
        };
        let mut order: Vec<(usize, usize)> = (0..self.m)
            .filter_map(|i| first(i).map(|s| (s, i)))
            .collect();
        order.sort_unstable();
        order
    }

    /// The bytes one thread works in while the contacts `order` are solved
    /// forward.
    fn forward_work_bytes(&self, order: &[(usize, usize)]) -> usize {
        let (tree, d) = (&self.tree, self.d);
        let ns = tree.len();
        let sym = self.factor.supernodal_symbolic();
        let mut mark = vec![usize::MAX; ns];
        let (mut block, mut buf) = (0, 0);
        for (g, group) in order.chunks(GROUP).enumerate() {
            let (mut rows, mut below) = (0, 0);
            for &(_, i) in group {
                for r in self.rows(i) {
                    for &dof in self.dofs(r) {
                        let mut s = self.supernode(dof);
                        while s != usize::MAX && mark[s] != g {
                            mark[s] = g;
                            rows += tree.width[s];
                            below = below.max(sym.supernode(s).pattern().len());
                            s = tree.parent[s];
                        }
                    }
                }
            }
            let k = group.len() * d;
            block = block.max(rows * k);
            buf = buf.max(below * k);
        }
        (block + buf) * std::mem::size_of::<f64>() + 4 * ns * std::mem::size_of::<usize>()
    }

    /// The blocks of one group of contacts ((first supernode, contact) pairs), in
    /// the group's order.
    fn group_blocks(&self, group: &[(usize, usize)], ws: &mut Scratch) -> Vec<f64> {
        let (factor, tree, bt, d) = (self.factor, &self.tree, &self.bt, self.d);
        let stamp = group[0].1;
        let cols = || {
            group
                .iter()
                .flat_map(move |&(_, i)| self.rows(i))
                .enumerate()
        };
        // The union of the paths to the root, in elimination order, and per
        // supernode the range of columns that reach it (columns come in increasing
        // order: a visited supernode only extends its range, up to the root, until
        // one already extended by this column).
        ws.list.clear();
        for (t, r) in cols() {
            for &dof in self.dofs(r) {
                let mut s = self.supernode(dof);
                while s != usize::MAX {
                    if ws.mark[s] != stamp {
                        ws.mark[s] = stamp;
                        ws.list.push(s);
                        (ws.lo[s], ws.hi[s]) = (t, t);
                    } else if ws.hi[s] == t {
                        break;
                    } else {
                        ws.hi[s] = t;
                    }
                    s = tree.parent[s];
                }
            }
        }
        ws.list.sort_unstable();
        let llt = factor.supernodal();
        let mut rows = 0;
        for &s in &ws.list {
            ws.offset[s] = rows;
            rows += llt.supernode(s).val().ncols();
        }
        let local = |col: usize| {
            let s = tree.of_col[col];
            ws.offset[s] + col - tree.begin[s]
        };
        let k = group.len() * d;
        let mut y = Mat::<f64>::zeros(rows, k);
        for (t, r) in cols() {
            for p in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                y[(local(self.new_of[bt.row_idx[p]]), t)] += bt.values[p];
            }
        }
        for &s in &ws.list {
            let node = llt.supernode(s);
            let val = node.val();
            let w = val.ncols();
            let pattern = node.pattern();
            let off = ws.offset[s];
            let (t0, kk) = (ws.lo[s], ws.hi[s] - ws.lo[s] + 1);
            solve_lower_triangular_in_place(
                val.submatrix(0, 0, w, w),
                y.as_mut().submatrix_mut(off, t0, w, kk),
                Par::Seq,
            );
            let below = pattern.len();
            if below == 0 {
                continue;
            }
            if ws.buf.len() < below * kk {
                ws.buf.resize(below * kk, 0.0);
            }
            let mut tmp = MatMut::from_column_major_slice_mut(&mut ws.buf[..below * kk], below, kk);
            matmul(
                tmp.as_mut(),
                Accum::Replace,
                val.submatrix(w, 0, below, w),
                y.as_ref().submatrix(off, t0, w, kk),
                1.0,
                Par::Seq,
            );
            ws.dest.clear();
            ws.dest.extend(pattern.iter().map(|&row| {
                let s2 = tree.of_col[row];
                ws.offset[s2] + row - tree.begin[s2]
            }));
            for t in 0..kk {
                let ycol = y
                    .col_mut(t0 + t)
                    .try_as_col_major_mut()
                    .expect("contiguous")
                    .as_slice_mut();
                let tcol = &ws.buf[t * below..(t + 1) * below];
                for (&at, &v) in ws.dest.iter().zip(tcol) {
                    ycol[at] -= v;
                }
            }
        }
        let dd = d * d;
        let mut out = vec![0.0; group.len() * dd];
        for slot in 0..group.len() {
            for a in 0..d {
                for b in 0..d {
                    let col =
                        |t: usize| y.col(t).try_as_col_major().expect("contiguous").as_slice();
                    let (ca, cb) = (col(slot * d + a), col(slot * d + b));
                    out[slot * dd + a * d + b] = ca.iter().zip(cb).map(|(x, z)| x * z).sum();
                }
            }
        }
        out
    }
}

/// The d x d diagonal blocks of A = B K^-1 B^T for the m contacts of B (c x n,
/// c = d m, rows ordered as in [`crate::dual`]): block i at
/// `[i d^2 .. (i+1) d^2]`, row-major, its rows and columns contact i's rows of B
/// (normal first). Contacts without entries in B get a zero block.
pub(crate) fn contact_blocks(factor: &Factor, b: &Csc, m: usize, d: usize) -> Vec<f64> {
    contact_blocks_by(factor, b, m, d, Route::Cheaper, None)
}

/// [`contact_blocks`] where the factor's values in single precision are at
/// hand (`single`: [`Factor::single_values`]): a selected inversion of at
/// least [`SINGLE_MIN_FLOPS`] runs in single precision, about half the time
/// (3d-64x64x6: 2.18 s -> 1.18 s, against 2.2 s for the factorisation), its
/// blocks within about 2e-7 of the double-precision ones there (relative, per
/// trace). Kept only where a sample of contacts' blocks, solved in double
/// precision by forward solves, agrees within [`SINGLE_TOL`] (`Face::confirms`)
/// and no diagonal entry is negative or not finite; else the selected
/// inversion runs again in double precision. The blocks
/// serve as rho (an error of 1e-5 moves err by as little: the natural map's
/// residual is non-decreasing in rho and no more than linear in it), as the
/// diagonal of A and in Newton's preconditioner.
pub(crate) fn contact_blocks_single(
    factor: &Factor,
    b: &Csc,
    m: usize,
    d: usize,
    single: &[f32],
) -> Vec<f64> {
    contact_blocks_by(
        factor,
        b,
        m,
        d,
        Route::Cheaper,
        Some((single, SINGLE_MIN_FLOPS)),
    )
}

/// Selected inversions of fewer flops stay in double precision (below it the
/// saving was not measurable: 3d-24x24x4; from 3d-32x32x4, 1.9e9 flops, the
/// creation's dual fell from 0.63-0.90 to 0.55-0.68 of a factorisation,
/// BENCHMARKS.md).
pub(crate) const SINGLE_MIN_FLOPS: f64 = 1e9;

/// Contacts spread over the face whose blocks check a selected inversion in
/// single precision (with the contacts of the smallest and largest trace).
pub(crate) const SAMPLE: usize = 16;

/// Largest difference of a sampled block's entry, single against double
/// precision, relative to the block's largest diagonal entry, for which the
/// single-precision blocks are kept (50 x what the slabs of the benchmark
/// show per trace).
pub(crate) const SINGLE_TOL: f64 = 1e-5;

/// How the blocks of the contacts on the factor's pattern are computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Route {
    /// Selected inversion where it needs fewer flops than the forward solves.
    Cheaper,
    /// Forward solves for every contact.
    Forward,
    /// Selected inversion for every contact on the pattern.
    Selected,
}

/// [`contact_blocks`] by the given route (contacts off the pattern always by
/// forward solves).
/// `single`: the factor's values in single precision and the flops from
/// which the selected inversion runs on them (see [`contact_blocks_single`]).
pub(crate) fn contact_blocks_by(
    factor: &Factor,
    b: &Csc,
    m: usize,
    d: usize,
    route: Route,
    single: Option<(&[f32], f64)>,
) -> Vec<f64> {
    if factor.is_dense() {
        return dense_blocks(factor, b, m, d);
    }
    let face = Face::new(factor, b, m, d);
    let plan = face.plan(route);
    let dd = d * d;
    let mut blocks = match &plan.selection {
        Some(sel) => {
            let rough = match single {
                Some((values, min_flops)) if sel.flops() >= min_flops => {
                    let rough = sel.sums_single(factor, values, &face.tree, m * dd);
                    face.confirms(&plan.on, &rough).then_some(rough)
                }
                _ => None,
            };
            let mut upper = match rough {
                Some(rough) => rough,
                None => sel.sums(factor, &face.tree, m * dd),
            };
            for i in 0..m {
                for a in 0..d {
                    for e in 0..a {
                        upper[i * dd + a * d + e] = upper[i * dd + e * d + a];
                    }
                }
            }
            upper
        }
        None => vec![0.0; m * dd],
    };
    face.forward_blocks(&plan.forward, &mut blocks);
    blocks
}

/// Which contacts go which way.
struct Plan {
    /// The selected inversion of the contacts whose blocks lie on the factor's
    /// pattern, when it is taken: the terms of entry (a, e), a <= e, of contact
    /// i go to slot i d^2 + a d + e.
    selection: Option<Selection>,
    /// The contacts of the selection, as (first supernode, contact) pairs in
    /// the order of `forward`.
    on: Vec<(usize, usize)>,
    /// The contacts solved forward, as (first supernode, contact) pairs sorted
    /// by their first (deepest) supernode: the order they are solved in.
    forward: Vec<(usize, usize)>,
}

/// [`contact_blocks`] of a dense factor (K had every entry stored): W_i = L^-1 P
/// B_i^T by d dense forward solves per contact, A_ii = W_i^T W_i. Sequential: a
/// dense K is an interface problem, and its dense dual is the usual route.
fn dense_blocks(factor: &Factor, b: &Csc, m: usize, d: usize) -> Vec<f64> {
    let (n, dd) = (factor.n(), d * d);
    let bt = b.transpose();
    let mut blocks = vec![0.0; m * dd];
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; d * n];
    for i in 0..m {
        for (a, r) in rows_of(i, m, d).enumerate() {
            x.fill(0.0);
            for k in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                x[bt.row_idx[k]] = bt.values[k];
            }
            factor.forward(&x, &mut w[a * n..(a + 1) * n]);
        }
        for a in 0..d {
            for e in 0..d {
                let (wa, we) = (&w[a * n..(a + 1) * n], &w[e * n..(e + 1) * n]);
                blocks[i * dd + a * d + e] = wa.iter().zip(we).map(|(p, q)| p * q).sum();
            }
        }
    }
    blocks
}

/// The bytes [`contact_blocks`] works in, from the symbolic factor alone (known
/// before the numeric factorisation): the selected inversion's terms and blocks
/// (`Selection::work_bytes`) when it is taken, or per thread, for the forward
/// solves, the largest group's dense block (the rows of the union of its
/// paths, times its columns), the largest product buffer (rows below a
/// supernode of a group's union, times the group's columns), and the
/// per-supernode marks.
pub(crate) fn work_bytes(factor: &Factor, b: &Csc, m: usize, d: usize) -> usize {
    if factor.is_dense() {
        return (d + 1) * factor.n() * std::mem::size_of::<f64>();
    }
    let face = Face::new(factor, b, m, d);
    let plan = face.plan(Route::Cheaper);
    let threads = factor.threads().count();
    let selected = plan
        .selection
        .as_ref()
        .map_or(0, |sel| sel.work_bytes(factor, &face.tree, threads));
    let forward = threads * face.forward_work_bytes(&plan.forward);
    selected.max(forward)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact_rows::stack_rows;
    use crate::dual::tests::grid;
    use crate::options::Ordering;
    use crate::threads::Threads;
    use std::sync::Arc;

    /// B K^-1 B^T formed column by column with full solves (c x c, column-major).
    fn dense_a(f: &Factor, b: &Csc) -> Vec<f64> {
        let (c, n) = (b.nrows, f.n());
        let bt = b.transpose();
        let mut dense = vec![0.0; c * c];
        for r in 0..c {
            let mut x = vec![0.0; n];
            for p in bt.col_ptr[r]..bt.col_ptr[r + 1] {
                x[bt.row_idx[p]] = bt.values[p];
            }
            f.solve_vec(&mut x);
            b.mul_vec(&x, &mut dense[r * c..(r + 1) * c]);
        }
        dense
    }

    /// Every contact's block by `route` against the dense A.
    fn check_blocks(f: &Factor, b: &Csc, m: usize, d: usize, route: Route, what: &str) {
        let c = b.nrows;
        let dense = dense_a(f, b);
        let blocks = contact_blocks_by(f, b, m, d, route, None);
        for i in 0..m {
            let rows: Vec<usize> = rows_of(i, m, d).collect();
            for a in 0..d {
                for bb in 0..d {
                    let want = dense[rows[a] + rows[bb] * c];
                    let got = blocks[i * d * d + a * d + bb];
                    assert!(
                        (got - want).abs() <= 1e-13 * want.abs().max(1e-3),
                        "{what} {route:?} contact {i} ({a},{bb}): {got} vs {want}"
                    );
                }
            }
        }
    }

    /// How many contacts `route` takes by selected inversion.
    fn selected(f: &Factor, b: &Csc, m: usize, d: usize, route: Route) -> usize {
        let face = Face::new(f, b, m, d);
        let plan = face.plan(route);
        let with_entries = face.ordered().len();
        if plan.selection.is_some() {
            with_entries - plan.forward.len()
        } else {
            0
        }
    }

    /// The blocks against B K^-1 B^T formed column by column with full solves,
    /// by every route, for both orderings, 1 and 2 threads, d = 2 and 3, with a
    /// contact whose rows are empty and contacts whose rows touch several DOFs,
    /// some of them far apart (off the factor's pattern: solved forward even on
    /// the selected route).
    #[test]
    fn blocks_match_the_dense_a() {
        let (nx, ny) = (23, 17);
        let k = grid(nx, ny);
        let n = nx * ny;
        for d in [2, 3] {
            let m = 40;
            let (mut nt, mut tt) = (Vec::new(), Vec::new());
            for i in 0..m - 1 {
                let dof = (7 * i + 3) % n;
                nt.push((i, dof, -1.0));
                nt.push((i, (dof + 1) % n, 0.3));
                for s in 0..d - 1 {
                    tt.push(((d - 1) * i + s, (dof + s * nx) % n, 1.0 - 0.2 * s as f64));
                    tt.push(((d - 1) * i + s, (dof + 2) % n, 0.1 * i as f64));
                }
            }
            let nm = Csc::from_triplets(m, n, &nt);
            let tm = Csc::from_triplets((d - 1) * m, n, &tt);
            let b = stack_rows(&nm, &tm);
            for (ordering, threads) in [(Ordering::Amd, 1), (Ordering::Metis, 2)] {
                let f =
                    Factor::with_last(&k, &[], ordering, Arc::new(Threads::new(threads))).unwrap();
                for route in [Route::Cheaper, Route::Forward, Route::Selected] {
                    check_blocks(&f, &b, m, d, route, &format!("d {d} {ordering:?}"));
                    // The last contact has no entries: a zero block.
                    let blocks = contact_blocks_by(&f, &b, m, d, route, None);
                    assert!(blocks[(m - 1) * d * d..].iter().all(|&v| v == 0.0));
                }
                let on = selected(&f, &b, m, d, Route::Selected);
                assert!(on > 0 && on < m - 1, "{on} of {} contacts selected", m - 1);
                assert_eq!(selected(&f, &b, m, d, Route::Forward), 0);
            }
        }
    }

    /// Contacts on the bottom row of a grid (each touching its node's DOF and a
    /// neighbour's, all on the factor's pattern) and two-body contacts between
    /// two disconnected grids (entries between the bodies are zeros of K^-1):
    /// every contact goes by selected inversion, which the cheaper route takes
    /// when the contacts are many, and the blocks match the dense A.
    #[test]
    fn selected_inversion_covers_face_and_two_body_contacts() {
        let (nx, ny) = (40, 12);
        let one = grid(nx, ny);
        let n1 = nx * ny;
        // Two copies of the grid, block diagonal.
        let mut t = Vec::new();
        for j in 0..n1 {
            for p in one.col_ptr[j]..one.col_ptr[j + 1] {
                t.push((one.row_idx[p], j, one.values[p]));
                t.push((n1 + one.row_idx[p], n1 + j, one.values[p]));
            }
        }
        let k = Csc::from_triplets(2 * n1, 2 * n1, &t);
        let n = 2 * n1;
        let d = 2;
        // Face contacts on the first body's bottom row, two-body contacts
        // between the first body's top row and the second's bottom row.
        let mut nt = Vec::new();
        let mut tt = Vec::new();
        let mut m = 0;
        for i in 0..nx - 1 {
            nt.push((m, i, -1.0));
            tt.push((m, i + 1, 0.5));
            tt.push((m, i, 1.0));
            m += 1;
        }
        for i in 0..nx {
            let top = i + nx * (ny - 1);
            nt.push((m, top, 1.0));
            nt.push((m, n1 + i, -1.0));
            tt.push((m, top, 0.7));
            tt.push((m, n1 + i, -0.7));
            m += 1;
        }
        let b = stack_rows(
            &Csc::from_triplets(m, n, &nt),
            &Csc::from_triplets(m, n, &tt),
        );
        for (ordering, threads) in [(Ordering::Amd, 1), (Ordering::Metis, 2)] {
            let f = Factor::with_last(&k, &[], ordering, Arc::new(Threads::new(threads))).unwrap();
            for route in [Route::Cheaper, Route::Selected] {
                check_blocks(&f, &b, m, d, route, &format!("{ordering:?}"));
            }
            assert_eq!(selected(&f, &b, m, d, Route::Selected), m);
        }
    }

    /// The selected inversion in single precision (forced here: the grid is
    /// below SINGLE_MIN_FLOPS): within SINGLE_TOL of the dense A, and not the
    /// double-precision route's result (it ran); on a factor copy that is not
    /// the factor's (its values 0.1 % larger: K^-1 0.2 % smaller) the sampled
    /// check refuses it, and the double-precision route's blocks come back
    /// exactly.
    #[test]
    fn single_precision_blocks_are_checked_against_double_solves() {
        let (nx, ny, d) = (40, 30, 2);
        let k = grid(nx, ny);
        let n = nx * ny;
        // Contacts on the bottom row (normal on the node, tangent towards its
        // right neighbour): all on the factor's pattern.
        let m = nx - 1;
        let (mut nt, mut tt) = (Vec::new(), Vec::new());
        for i in 0..m {
            nt.push((i, i, -1.0));
            tt.push((i, i, 1.0));
            tt.push((i, i + 1, 0.5));
        }
        let b = stack_rows(
            &Csc::from_triplets(m, n, &nt),
            &Csc::from_triplets(m, n, &tt),
        );
        for (ordering, threads) in [(Ordering::Amd, 1), (Ordering::Metis, 2)] {
            let f = Factor::with_last(&k, &[], ordering, Arc::new(Threads::new(threads))).unwrap();
            assert_eq!(selected(&f, &b, m, d, Route::Selected), m);
            let exact = contact_blocks_by(&f, &b, m, d, Route::Selected, None);
            let single = f.single_values().unwrap();
            let rough = contact_blocks_by(&f, &b, m, d, Route::Selected, Some((&single, 0.0)));
            assert_ne!(
                rough, exact,
                "{ordering:?}: the single-precision route did not run"
            );
            let dense = dense_a(&f, &b);
            let c = b.nrows;
            for i in 0..m {
                let rows: Vec<usize> = rows_of(i, m, d).collect();
                let scale = (0..d)
                    .map(|a| dense[rows[a] + rows[a] * c])
                    .fold(0.0, f64::max);
                for a in 0..d {
                    for e in 0..d {
                        let want = dense[rows[a] + rows[e] * c];
                        let got = rough[i * d * d + a * d + e];
                        assert!(
                            (got - want).abs() <= SINGLE_TOL * scale,
                            "{ordering:?} contact {i} ({a},{e}): {got} vs {want}"
                        );
                    }
                }
            }
            let off: Vec<f32> = single.iter().map(|v| v * 1.001).collect();
            let refused = contact_blocks_by(&f, &b, m, d, Route::Selected, Some((&off, 0.0)));
            assert_eq!(refused, exact, "{ordering:?}: a wrong copy was not refused");
            // A NaN in one value of the copy (the last supernode's, which
            // every contact's path crosses): refused by the diagonal check.
            let mut nan = single.clone();
            *nan.last_mut().unwrap() = f32::NAN;
            let refused = contact_blocks_by(&f, &b, m, d, Route::Selected, Some((&nan, 0.0)));
            assert_eq!(
                refused, exact,
                "{ordering:?}: a copy with a NaN was not refused"
            );
            // Below the threshold the route stays in double precision.
            let small = contact_blocks_by(&f, &b, m, d, Route::Selected, Some((&single, 1e30)));
            assert_eq!(small, exact);
        }
    }
}
