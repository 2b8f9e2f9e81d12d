//! The reduced system of a Newton step on a matrix-free dual: CG (symmetric)
//! or GMRES on products with A, preconditioned by the lumped G restricted to
//! the reduced unknowns plus the layered Dirichlet one's first-order change
//! (`restricted.rs`) where the dual holds them, else by
//! the lumped G = B K B^T or the layered Dirichlet preconditioner cut by the
//! test vectors, with the Jacobi part of the compliance; rough products in
//! single precision where the forcing term allows (every solve where the dual
//! offers them: the forcing term's floor, `forcing`), and refinement with
//! exact residuals where it does not (`refine`). Where the products are not
//! narrowed, the step's A d is combined from them (`krylov_step`), so the
//! backtracking takes no product of its own.

use super::*;
use crate::dual::Dual;
use crate::restricted::{Pair, Restricted};

/// Most products with A in one reduced solve on a matrix-free dual.
pub(super) const KRYLOV_MAX_IT: usize = 200;

/// Reduced solves on a matrix-free dual whose forcing term is at least this use
/// products with the factor in single precision (half the memory traffic of a
/// solve): their error, about 1e-7 times the factor's conditioning, stays well
/// below the residual such a solve asks for. The step is still checked by the
/// exact gradient (the backtracking), so a rough step can only cost a step.
/// It is also the forcing term's floor where the dual offers such products
/// (`forcing`), so that a tighter reduced solve, which refines in mixed
/// precision (`refine`: rough products for the corrections, exact ones for
/// the residuals), is left to the duals whose host solves only in double.
pub(super) const ROUGH_ETA: f64 = 1e-4;

/// The Krylov solve of a Newton step on a matrix-free dual: its forcing term,
/// its budget, its scratch (two vectors of length c) and the products it used.
pub(super) struct Krylov {
    /// Relative residual the reduced solve must reach.
    pub eta: f64,
    /// Most products with A per reduced solve.
    pub max_it: usize,
    /// Products used so far (inner iterations).
    pub its: usize,
    /// Whether the reduced solve must use exact products whatever its forcing
    /// term (see ROUGH_ETA).
    pub exact: bool,
    pub(super) v: Vec<f64>,
    pub(super) av: Vec<f64>,
    /// The products A V x_i a reduced solve keeps, on every component, to
    /// make A V z from (`krylov_step`): the last one for CG, the last
    /// RESTART + 1 for GMRES; length c each, grown at first use.
    pub(super) kept: Vec<f64>,
    /// The rows a step's products are narrowed to (`Dual::narrow_to`).
    pub(super) rows: Vec<usize>,
    /// Steps whose products were narrowed.
    pub narrowed: usize,
    /// Reduced solves that combined their step's A d from their own
    /// products (`krylov_step`), so that the step took no product of its own.
    pub combined: usize,
    /// The scale of the last combined A d's rounding: |A e0| plus
    /// sum_i |coef_i| |A V x_i| over the products it was combined from
    /// (each product errs relative to its own size, and the combination
    /// may cancel).
    pub(super) spread: f64,
    /// Whether the last dense reduced solve stopped at the forcing term
    /// (GMRES on a system that is not symmetric, `exact` off): a step from
    /// it that the backtracking rejects is solved again exactly.
    pub(super) inexact_dense: bool,
    /// Whether a dense step may make A's inverse (`Dual::inverse`) and
    /// precondition its reduced system with it (`dense::Complement`): on
    /// the warm solves of a 3D dual, a history's steps.
    pub(super) inverse: bool,
    /// Dense steps whose reduced system was solved on A's inverse.
    pub(super) on_inverse: usize,
    /// The forcing term of a step on a matrix-free dual whose sort is the
    /// last step's, where that step paid for one of its own (see
    /// [`Krylov::settle`]): set with `eta` before each step, at most `eta`.
    pub settled_eta: f64,
    /// The key of the last step's sort (`sort_key`), and whether a tighter
    /// solve of it would pay (that step was taken whole and its A d took
    /// a product of its own); None at the start of a solve and after a
    /// fallback.
    pub(super) last_sort: Option<(u64, bool)>,
    /// Steps whose forcing term `settle` tightened.
    pub settled: usize,
    /// Whether `settle` may tighten a forcing term (off in tests that
    /// measure what it saves).
    pub(super) settle_on: bool,
}

impl Krylov {
    /// Whether this reduced solve may use products in single precision (see
    /// ROUGH_ETA).
    pub(super) fn rough(&self) -> bool {
        !self.exact && self.eta >= ROUGH_ETA
    }

    pub(super) fn new(c: usize) -> Krylov {
        Krylov {
            eta: 0.1,
            max_it: KRYLOV_MAX_IT,
            its: 0,
            exact: false,
            v: vec![0.0; c],
            av: vec![0.0; c],
            kept: Vec::new(),
            rows: Vec::with_capacity(c),
            narrowed: 0,
            combined: 0,
            spread: 0.0,
            inexact_dense: false,
            inverse: false,
            on_inverse: 0,
            settled_eta: 0.1,
            last_sort: None,
            settled: 0,
            settle_on: true,
        }
    }

    /// Takes `settled_eta` as this step's forcing term where its sort
    /// (`key`, [`sort_key`]) is the last step's and that step was taken
    /// whole, its A d by a product of its own (narrowed products, or a
    /// refinement: `krylov_step` combined none). The linear model the last
    /// step solved is then this step's too (but for the slip directions'
    /// turn in 3D), and the whole step showed it true: a tighter solve of
    /// it shrinks |F| as much in fewer steps (Eisenstat and Walker's first
    /// choice, whose measure of the model's disagreement vanishes where
    /// the sort does not change), and each step saved saves its own
    /// products around the solve (the explicit part's, the backtracking's
    /// exact one: about five narrowed rough products on the 3d-64x64x6
    /// slab). Where the step's A d was combined from the solve's products
    /// a step saved saves about one product, and the tighter solves' last
    /// decades cost more (on the load-path family's Tresca histories, 2-4
    /// fewer Newton steps over nine warm steps for up to 10 more products),
    /// so the forcing term stands there. Records `key` for the next step (see
    /// [`Krylov::taken`]).
    pub(super) fn settle(&mut self, key: u64) {
        if self.settle_on && self.last_sort == Some((key, true)) && self.settled_eta < self.eta {
            self.eta = self.settled_eta;
            self.settled += 1;
        }
        self.last_sort = Some((key, false));
    }

    /// Records for [`Krylov::settle`] how the step just kept was taken:
    /// `whole` (length 1) and `combined` (its A d from the solve's own
    /// products).
    pub(super) fn taken(&mut self, whole: bool, combined: bool) {
        if let Some((_, pays)) = self.last_sort.as_mut() {
            *pays = whole && !combined;
        }
    }
}

/// A key of a step's sort: which components are free and which directions
/// its reduced unknowns take (their test and direction rows; in 2D, `d`,
/// the signs of the directions' coefficients too, which a Coulomb slip
/// force that reverses changes in its coupling), not the coefficients
/// themselves (a 3D slip direction turns from step to step, its
/// components' signs with it where it lies near an axis: keyed, they took
/// the 3D host example's Newton steps from 57 back to 61 on 3d-32x32x4);
/// FNV-1a over them. A fixed component leaves no unknown: a 2D Tresca slip
/// that reverses keeps the key, and costs at most a tighter solve than its
/// step needed.
pub(super) fn sort_key(red: &[Reduced], d: usize) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |x: u64| {
        h ^= x;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    mix(red.len() as u64);
    for u in red {
        mix(((u.n_test as u64) << 8) | u.n_dir as u64);
        u.test[..u.n_test].iter().for_each(|&(j, _)| mix(j as u64));
        u.dir[..u.n_dir]
            .iter()
            .for_each(|&(j, coef)| mix(((j as u64) << 1) | u64::from(d == 2 && coef < 0.0)));
    }
    h
}

/// Entry (ja, jb) of A where both lie in one contact's d x d diagonal block
/// (every pair a reduced unknown couples), read from the matrix-free dual's blocks.
pub(super) fn block_entry(problem: &DualProblem<'_>, ja: usize, jb: usize) -> f64 {
    let dual = problem.dual;
    let (m, d) = (dual.m, dual.d);
    let at = |j: usize| {
        if j < m {
            (j, 0)
        } else {
            ((j - m) / (d - 1), 1 + (j - m) % (d - 1))
        }
    };
    let ((ia, la), (ib, lb)) = (at(ja), at(jb));
    match dual.block_entry(ia, la, lb) {
        Some(v) if ia == ib => v,
        _ => 0.0,
    }
}

/// The reduced system M z = rhs of a Newton step on a matrix-free dual, by
/// preconditioned CG (symmetric M) or GMRES to the relative residual
/// `krylov.eta`, each product M x one product with A (M = T^T A V + diag,
/// T the reduced unknowns' test vectors, V their directions). The
/// preconditioner is the restricted one of `restricted.rs` (with the
/// layered Dirichlet one's first-order change) where the dual holds it, no
/// compliance is set, every reduced unknown fits it (a unit one, or a
/// slipping tangential pair), some component is not prescribed, the
/// reduced system holds at least MIN_REDUCED_SHARE of the components and E
/// factors within G's bounds (`Restriction::of`); else S V^T G T S with G the dual's approximate inverse of A
/// (`Dual::precondition`: the layered Dirichlet one B S_l B^T of
/// `dirichlet.rs` where it was formed, else the lumped G = B K B^T that FETI
/// codes use for the same operator) and S_l = sqrt(a_l / M_ll),
/// a_l = v_l^T A v_l (so that it is G where the diagonal term of M vanishes and
/// tends to 1 / M_ll where that term dominates, as for a fast slip); M's
/// diagonal (Jacobi) when the dual holds no G. Both from the contacts'
/// diagonal blocks of A. Adds V z to `step`.
///
/// `ae0` = A e0 on entry. Where `whole` (the products are not narrowed:
/// each gives A V x on every component) and the solve is not a refinement,
/// A V z is combined from the products the solve took (`Solver`'s `made`)
/// and added to `ae0`, which then holds A (e0 + V z) without another
/// product, to the precision of those products (`krylov.spread` the scale
/// of their rounding): Some(true). Some(false) where `ae0` is left as it
/// was; None when the Krylov iteration broke down (`ae0` may then hold
/// part of the combination: the step is solved again or given up).
pub(super) fn krylov_step(
    problem: &DualProblem<'_>,
    red: &[Reduced],
    step: &mut [f64],
    ae0: &mut [f64],
    krylov: &mut Krylov,
    whole: bool,
) -> Option<bool> {
    let dual = problem.dual;
    let k = red.len();
    let rhs: Vec<f64> = red.iter().map(|u| u.rhs_after(ae0)).collect();
    // Per reduced unknown, the entry of T^T A V + diag it sits on, from the
    // contacts' diagonal blocks of A.
    let mdiag: Vec<f64> = red
        .iter()
        .map(|u| {
            let mut mll = u.diag;
            for &(ja, ca) in &u.test[..u.n_test] {
                for &(jb, cb) in &u.dir[..u.n_dir] {
                    mll += ca * cb * block_entry(problem, ja, jb);
                }
            }
            mll
        })
        .collect();
    let symmetric = red
        .iter()
        .all(|u| u.n_test == u.n_dir && u.test[..u.n_test] == u.dir[..u.n_dir]);
    // A loose inner solve tolerates products in single precision (see
    // ROUGH_ETA); a tight one, asked only where the dual offers no such
    // products, refines with exact residuals (see `refine`).
    let rough = std::cell::Cell::new(krylov.rough());
    let refines = !(krylov.exact || rough.get());
    // The products kept for A V z: CG combines z as it goes (the last
    // product serves), GMRES at the end of a cycle (its RESTART products
    // and the restart's).
    let c = dual.c;
    let slots = match (whole && !refines, symmetric) {
        (false, _) => 0,
        (true, true) => 1,
        (true, false) => crate::methods::krylov::RESTART + 1,
    };
    if krylov.kept.len() < slots * c {
        krylov.kept.resize(slots * c, 0.0);
    }
    let kept = std::cell::RefCell::new(&mut krylov.kept);
    let sizes = vec![std::cell::Cell::new(0.0); slots];
    let mut spread = norm(ae0);
    let (v, av) = (&mut krylov.v, &mut krylov.av);
    let mut products = 0;
    let mut op = |x: &[f64], y: &mut [f64]| {
        v.iter_mut().for_each(|e| *e = 0.0);
        add_directions(red, x.iter().copied(), v);
        dual.apply_narrow(v, av, rough.get());
        for ((u, &xl), yl) in red.iter().zip(x).zip(y.iter_mut()) {
            *yl = u.diag * xl + u.test_dot(av);
        }
        if slots > 0 {
            let at = products % slots;
            kept.borrow_mut()[at * c..(at + 1) * c].copy_from_slice(av);
            sizes[at].set(norm(av));
        }
        products += 1;
    };
    let mut made = |i: usize, coef: f64| {
        if slots > 0 {
            let at = i % slots;
            let kept = kept.borrow();
            for (a, &p) in ae0.iter_mut().zip(&kept[at * c..(at + 1) * c]) {
                *a += coef * p;
            }
            spread += coef.abs() * sizes[at].get();
        }
    };
    let (mut gv, mut gg) = (vec![0.0; dual.c], vec![0.0; dual.c]);
    // The preconditioner S V^T G T S, S_l = sqrt(a_l / (a_l + diag_l)) with
    // a_l = v_l^T A v_l (G ~ A^-1 where diag vanishes, 1 / M_ll where it
    // dominates), G the dual's approximate inverse of A (`Dual::precondition`:
    // layered Dirichlet or lumped); Jacobi without one. A residual enters
    // lambda-space by the test vectors and the correction leaves by the
    // directions. T and V differ only where a Coulomb normal drags its slip
    // force (its direction e_N + mu n, its test e_N): there the residual of
    // its gap row is no longer spread over its slip row by mu n. A measured
    // choice, not a derived one (T^T V = I, so the square case's inverse
    // is T^T A^-1 V, which this P is the transpose of): V on both sides,
    // as before, took 3-6 % more products over the load-path family's warm
    // Coulomb histories (BENCHMARKS.md); the transpose, S T^T G V S, took
    // as many as this one (within 3 %, either way) on 3d-24x24x4,
    // 3d-32x32x4 and 3d-64x64x6.
    // The interface compliance's D (`Dual::set_shift`) counts with the
    // diagonal term (G approximates A^-1, not (A + D)^-1), and the Jacobi
    // part (1 - S_l^2) / M_ll is added where D is present: a soft interface
    // (D ten times A's diagonal) took 37 products against the rigid 20 on
    // the 3d-32x32x4 slab without it, 21 with it.
    let shift = dual.shift();
    let scale: Vec<f64> = red
        .iter()
        .zip(&mdiag)
        .map(|(u, &mll)| {
            let mut a = mll - u.diag;
            if !shift.is_empty() {
                for &(ja, ca) in &u.test[..u.n_test] {
                    for &(jb, cb) in &u.dir[..u.n_dir] {
                        if ja == jb {
                            a -= ca * cb * shift[ja];
                        }
                    }
                }
            }
            if a > 0.0 && mll > 0.0 {
                (a / mll).sqrt()
            } else {
                1.0
            }
        })
        .collect();
    // The lumped preconditioner restricted to the reduced unknowns, with the
    // layered one's first-order change (`restricted.rs`), where the dual
    // holds them and every unknown fits it.
    let mut restricted = Restriction::of(dual, red);
    let mut pre = |x: &[f64], y: &mut [f64]| {
        if let Some(r) = &mut restricted
            && r.apply(dual, x, y)
        {
            return;
        }
        gv.iter_mut().for_each(|e| *e = 0.0);
        for ((u, &xl), &sl) in red.iter().zip(x).zip(&scale) {
            for &(j, c) in &u.test[..u.n_test] {
                gv[j] += c * sl * xl;
            }
        }
        if dual.precondition(&gv, &mut gg) {
            for ((((u, yl), &sl), &xl), &mll) in
                red.iter().zip(y.iter_mut()).zip(&scale).zip(x).zip(&mdiag)
            {
                *yl = sl
                    * u.dir[..u.n_dir]
                        .iter()
                        .map(|&(j, c)| c * gg[j])
                        .sum::<f64>();
                if !shift.is_empty() && mll > 0.0 {
                    *yl += (1.0 - sl * sl) * xl / mll;
                }
            }
        } else {
            for ((yl, &xl), &mll) in y.iter_mut().zip(x).zip(&mdiag) {
                *yl = if mll > 0.0 { xl / mll } else { xl };
            }
        }
    };
    let mut z = vec![0.0; k];
    let solver = if symmetric {
        crate::methods::krylov::pcg
    } else {
        crate::methods::krylov::gmres
    };
    let (eta, max_it) = (krylov.eta, krylov.max_it);
    let its = if refines {
        refine(solver, &mut op, &rough, &rhs, &mut pre, eta, max_it, &mut z)
    } else {
        solver(&mut op, &rhs, &mut pre, eta, max_it, &mut z, &mut made)
    };
    let its = its?;
    krylov.its += its;
    krylov.spread = spread;
    add_directions(red, z, step);
    Some(slots > 0)
}

/// The restricted preconditioner serves reduced systems of at least this
/// share of the c components. Below it E's factor (about G's size whatever
/// the reduced system's) does not pay, and on a nearly floating lattice
/// slab with 4-12 of 256 contacts closed (anchor 1e-4; `newton::tests`'s
/// lattice) the restricted one took more products than the general one
/// at some loads (626 against 388): G misses the near-rigid mode of A
/// that the closed contacts' system is dominated by.
const MIN_REDUCED_SHARE: f64 = 0.1;

/// A reduced system's unknowns as the restricted preconditioner sees them
/// (`restricted.rs`): prescribed components (unit test vectors) and
/// slipping pairs, E factored for them, and the application's vectors.
struct Restriction<'a> {
    on: &'a Restricted,
    prescribed: Vec<usize>,
    pairs: Vec<Pair>,
    /// Per reduced unknown: whether it is a pair, and its index in
    /// `pairs` or `prescribed`.
    slot: Vec<(bool, usize)>,
    x: (Vec<f64>, Vec<f64>),
    z: (Vec<f64>, Vec<f64>),
    /// Length c: the extension nu, then (H_D - G) nu.
    nu: Vec<f64>,
    hd: Vec<f64>,
    g: Vec<f64>,
}

impl<'a> Restriction<'a> {
    /// The restriction for the reduced unknowns `red` where `dual` holds the
    /// restricted preconditioner, every unknown is a unit one without a
    /// diagonal term or a tangential pair (j, j + 1) with one, some
    /// component is not prescribed, and E's factorisation succeeds; None
    /// elsewhere (the general preconditioner serves).
    fn of(dual: &'a Dual, red: &[Reduced]) -> Option<Restriction<'a>> {
        let on = dual.restricted()?;
        let (mut prescribed, mut pairs) = (Vec::new(), Vec::new());
        let mut slot = Vec::with_capacity(red.len());
        for u in red {
            if u.n_test == 1 && u.diag == 0.0 {
                slot.push((false, prescribed.len()));
                prescribed.push(u.test[0].0);
            } else if u.n_test == 2 && u.diag > 0.0 && u.test[1].0 == u.test[0].0 + 1 {
                slot.push((true, pairs.len()));
                pairs.push(Pair {
                    j: u.test[0].0,
                    t: [u.test[0].1, u.test[1].1],
                    delta: u.diag,
                });
            } else {
                return None;
            }
        }
        // Every component prescribed: P x + X^T (H_D - G) X x is H_D's
        // restriction, the general preconditioner's, at a higher cost. A
        // small reduced system (a few closed contacts) does not pay for E,
        // whose factor is about G's whatever its size.
        if prescribed.len() == dual.c
            || (red.len() as f64) < MIN_REDUCED_SHARE * dual.c as f64
            || !on.factor(&prescribed, &pairs)
        {
            return None;
        }
        let (np, ns, c) = (prescribed.len(), pairs.len(), dual.c);
        Some(Restriction {
            on,
            prescribed,
            pairs,
            slot,
            x: (vec![0.0; np], vec![0.0; ns]),
            z: (vec![0.0; np], vec![0.0; ns]),
            nu: vec![0.0; c],
            hd: vec![0.0; c],
            g: vec![0.0; c],
        })
    }

    /// y := P x + X^T (H_D - G) X x (`restricted.rs`; H_D the dual's own
    /// approximate inverse of A, the layered Dirichlet one). False where E
    /// was not factored.
    fn apply(&mut self, dual: &Dual, x: &[f64], y: &mut [f64]) -> bool {
        let ((xp, xs), (zp, zs)) = (&mut self.x, &mut self.z);
        for (&(pair, at), &xl) in self.slot.iter().zip(x) {
            if pair {
                xs[at] = xl;
            } else {
                xp[at] = xl;
            }
        }
        let on = self.on;
        if !on.apply(&self.prescribed, xp, &self.pairs, xs, zp, zs, &mut self.nu) {
            return false;
        }
        if dual.precondition(&self.nu, &mut self.hd) {
            on.g_mul(&self.nu, &mut self.g);
            self.hd.iter_mut().zip(&self.g).for_each(|(h, g)| *h -= g);
            on.add_extension_t(&self.prescribed, &self.pairs, &self.hd, zp, zs);
        }
        for (&(pair, at), yl) in self.slot.iter().zip(y.iter_mut()) {
            *yl = if pair { zs[at] } else { zp[at] };
        }
        true
    }
}

/// Rounds of `refine` before it falls back to exact products.
pub(super) const REFINE_ROUNDS: usize = 4;

/// A tight reduced solve (relative residual `eta` < ROUGH_ETA) by iterative
/// refinement in mixed precision: each round solves M dz = r for the
/// correction with products in single precision (`rough` set) to the relative
/// residual ROUGH_ETA, or to what the target needs when that is looser, then
/// measures r = rhs - M z with one exact product. A round that does not halve
/// |r| (single precision too rough for this factor) hands the rest to the
/// solver with exact products, from the z reached. Same contract as the
/// solvers: the products used, None on a breakdown.
#[allow(clippy::too_many_arguments)]
pub(super) fn refine(
    solver: crate::methods::krylov::Solver,
    op: &mut dyn FnMut(&[f64], &mut [f64]),
    rough: &std::cell::Cell<bool>,
    rhs: &[f64],
    pre: &mut dyn FnMut(&[f64], &mut [f64]),
    eta: f64,
    max_it: usize,
    z: &mut [f64],
) -> Option<usize> {
    let k = rhs.len();
    let stop = eta * norm(rhs);
    z.iter_mut().for_each(|v| *v = 0.0);
    let mut r = rhs.to_vec();
    let (mut dz, mut mz, mut saved) = (vec![0.0; k], vec![0.0; k], vec![0.0; k]);
    let mut r_norm = norm(&r);
    let mut its = 0;
    for _ in 0..REFINE_ROUNDS {
        if r_norm <= stop || its >= max_it {
            return Some(its);
        }
        saved.copy_from_slice(&r);
        rough.set(true);
        let inner = ROUGH_ETA.max(stop / r_norm);
        its += solver(op, &r, pre, inner, max_it - its, &mut dz, &mut |_, _| {})?;
        z.iter_mut().zip(&dz).for_each(|(a, b)| *a += b);
        rough.set(false);
        op(z, &mut mz);
        its += 1;
        for j in 0..k {
            r[j] = rhs[j] - mz[j];
        }
        let before = r_norm;
        r_norm = norm(&r);
        if !r_norm.is_finite() || r_norm >= before {
            // Worse (or not finite): undo the round.
            z.iter_mut().zip(&dz).for_each(|(a, b)| *a -= b);
            r.copy_from_slice(&saved);
            r_norm = before;
            break;
        }
        if r_norm > 0.5 * before {
            break;
        }
    }
    if r_norm <= stop || its >= max_it {
        return Some(its);
    }
    // Exact products for the rest.
    rough.set(false);
    its += solver(
        op,
        &r,
        pre,
        stop / r_norm,
        max_it - its,
        &mut dz,
        &mut |_, _| {},
    )?;
    z.iter_mut().zip(&dz).for_each(|(a, b)| *a += b);
    Some(its)
}
