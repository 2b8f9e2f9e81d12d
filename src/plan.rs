//! The route of a problem, planned after K's analysis and before any numeric
//! work: which factor (contact DOFs last for the dense dual, the best plain
//! one for the matrix-free dual), which form of the dual, the sizes the
//! memory predictions are made of (`Sizes`), the check of those predictions
//! against the memory limit, and the analysis report (`Info`). Above `dual`
//! and `factor`, below `problem`.

use crate::contact_rows::{check_shapes, contact_dofs, stack_rows};
use crate::dual::{BLOCK, Condensation};
use crate::error::{ErrorKind, Result, fail};
use crate::factor::Factor;
use crate::info::Info;
use crate::memory::{self, F64, Ledger};
use crate::options::{DENSE_MAX, DualForm, Options};
use crate::sizes::Sizes;
use crate::sparse::Csc;
use crate::threads::Threads;
use std::sync::Arc;

/// Under `DualForm::Auto`, the dense route is taken only where its factor
/// (contact DOFs last) and condensation cost at most this many times the
/// flops of the best plain factor, which the matrix-free route uses: R =
/// (flops(L with C last) + c_C^3 / 3) / flops(plain L), c_C the number of
/// contact DOFs. On thin slabs and long 2D strips the trailing dense block of
/// the contact face dominates. Measured on the load-path family (Coulomb,
/// proportional oblique slip, 10 steps, 1 thread): R = 3.3-7.7 (3d-20x20x8,
/// 3d-24x24x6, 3d-16x16x4, 2d-400x50, 2d-800x100) still favoured the dense
/// route (creation + 10 steps 4.9-9.0 factorisations against 10.7-13.8
/// matrix-free), R = 15.7-37 (3d-24x24x4 to 3d-48x48x4, 2d-2000x50) the
/// matrix-free one (11-24 against 21-105; the cold increment 3.7-6.9 against
/// 9.6-54).
const DENSE_MAX_FLOP_RATIO: f64 = 10.0;

/// The share of the contacts-last factor's flops in its trailing dense block
/// (c_C^3 / 3 over the factor's flops) above which the plain factor is
/// analysed too, to weigh the routes by [`DENSE_MAX_FLOP_RATIO`]: 0.11-0.12 on
/// the 3D blocks (R = 2.6-2.8), 0.17-0.36 where the dense route wins, 0.5-0.76
/// where the matrix-free one does. Below it the dense route is kept without
/// the second analysis (thin 3D slabs are weighed whatever their share,
/// [`SLAB_SHARE`]).
const TRAILING_SHARE_TO_WEIGH: f64 = 0.4;

/// A 3D problem whose contact DOFs are more than this share of K's DOFs is a
/// thin slab (0.25 at 4 layers of elements, 0.14 at 6, at most 0.08 on the
/// benchmark's blocks): AUTO analyses its plain factor first, and where
/// [`SLAB_ESTIMATE`] already exceeds the bound skips the contacts-last
/// analysis (0.4-0.6 factorisations on those slabs).
const SLAB_SHARE: f64 = 0.15;

/// On a thin slab R is about this many times c_C^3 / 3 over the plain
/// factor's flops (the trailing block, about as much again in the rest of the
/// contacts-last factor, and the condensation; measured: the estimate within
/// 20 % of R, 6.1 against 7.7 to 36.9 against 32.8): the estimate made before
/// the contacts-last analysis.
const SLAB_ESTIMATE: f64 = 3.0;

/// Below this many flops in the trailing block c_C^3 / 3 (about a tenth of a
/// second in dense arithmetic) the dense route is taken without weighing:
/// whatever the plain factor costs, the dense one is cheap (3d-16x16x4: 2.2e8;
/// the weighed scenes of [`DENSE_MAX_FLOP_RATIO`] from 2.2e9).
const MIN_TRAILING_FLOPS: f64 = 1e9;

/// The flops of a factor's numeric factorisation (at least 1).
fn flops(factor: &Factor) -> f64 {
    factor.nnz_and_flops().1.max(1.0)
}

/// The route of a new problem, decided after K's analysis.
pub(crate) struct Plan {
    pub sizes: Sizes,
    /// `Dense` or `MatrixFree`.
    pub form: DualForm,
    /// The layered Dirichlet preconditioner's analysis, for a matrix-free
    /// dual (None on the dense route, or where it does not pay).
    pub layer: Option<crate::dirichlet::Plan>,
}

/// `BadArgument` unless d is 2 or 3.
pub(crate) fn check_d(d: usize) -> Result<()> {
    if d == 2 || d == 3 {
        Ok(())
    } else {
        fail(
            ErrorKind::BadArgument,
            format!("d = {d}: the contact dimension must be 2 or 3"),
        )
    }
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn info_of(
    d: usize,
    k: &Csc,
    n: &Csc,
    factor: &Factor,
    sizes: &Sizes,
    now: Condensation,
    trailing: bool,
    opts: &Options,
    limit: Option<usize>,
) -> Info {
    let next = solve_condensation(now, trailing, opts);
    let (factor_nnz, factor_flops) = factor.nnz_and_flops();
    let form_of = |how| match how {
        Condensation::MatrixFree => DualForm::MatrixFree,
        _ => DualForm::Dense,
    };
    Info {
        d,
        n: k.nrows,
        m: n.nrows,
        c: sizes.c,
        nnz_k: k.nnz(),
        ordering: factor.ordering(),
        factor_nnz,
        factor_flops,
        setup_form: form_of(now),
        method: opts.method,
        solve_form: form_of(next),
        setup_bytes: sizes.setup(now),
        resident_bytes: sizes.resident(now),
        refactor_bytes: sizes.refactor(now, k.bytes(), factor.threads().count()),
        solve_bytes: sizes.solve(
            now,
            next,
            opts.method
                .workspace(n.nrows, sizes.c, next == Condensation::MatrixFree),
        ),
        memory_limit: limit.unwrap_or(0),
        analyse_seconds: factor.analyse_seconds,
        compliant_contacts: 0,
        power_law_contacts: 0,
        blocks_age: 0,
        err_factor: 1.0,
    }
}

/// The sizes of a problem's memory predictions, after K's analysis.
pub(crate) fn sizes_of(k: &Csc, n: &Csc, t: &Csc, d: usize, factor: &Factor) -> Sizes {
    sizes_and_layer(k, n, t, d, factor).0
}

/// [`sizes_of`], and the layered Dirichlet preconditioner's analysis that
/// sized it (for a matrix-free dual to form without analysing it again).
pub(crate) fn sizes_and_layer(
    k: &Csc,
    n: &Csc,
    t: &Csc,
    d: usize,
    factor: &Factor,
) -> (Sizes, Option<crate::dirichlet::Plan>) {
    let b = stack_rows(n, t);
    let layer = crate::dirichlet::layer_of(k, &b, factor);
    let sizes = Sizes {
        n: k.nrows,
        c: d * n.nrows,
        d,
        nc: factor.last().len(),
        inputs: k.bytes() + n.bytes() + t.bytes(),
        factor: factor.values_bytes(),
        factor_scratch: factor.factor_scratch_bytes(),
        solve_scratch: factor.solve_scratch(BLOCK).size_bytes(),
        blocks_work: crate::factor_tree::contact_blocks::work_bytes(factor, &b, n.nrows, d),
        lumped: crate::sparse::congruence_bytes(k, &b, &b.transpose()),
        own_solves: crate::dual::own_solves_bytes(factor, &b),
        dirichlet: layer.as_ref().map_or(0, |p| p.bytes()),
        slots: 0,
        mirrors_to_make: crate::sparse::mirror_bytes(k),
        spare: 0,
    };
    (sizes, layer)
}

/// How a solve with `opts` needs the dual, held as `now` (see `prepare_dual`).
pub(crate) fn solve_condensation(
    now: Condensation,
    trailing: bool,
    opts: &Options,
) -> Condensation {
    let free_now = now == Condensation::MatrixFree;
    let want_free = match opts.dual_form {
        DualForm::Dense => false,
        DualForm::MatrixFree => true,
        DualForm::Auto => free_now && !opts.method.needs_entries(),
    };
    match (want_free, free_now) {
        (true, true) | (false, false) => now,
        (true, false) => Condensation::MatrixFree,
        (false, true) => Condensation::of(trailing, DualForm::Dense, 0),
    }
}

/// Validation, K's analysis and the route of a new problem, and the memory
/// limit.
pub(crate) fn route(
    d: usize,
    k: &Csc,
    n: &Csc,
    t: &Csc,
    opts: &Options,
) -> Result<(Factor, Plan, Option<usize>)> {
    check_d(d)?;
    opts.check("")?;
    if k.nrows != k.ncols {
        return fail(
            ErrorKind::BadSize,
            format!("K is {} x {}, not square", k.nrows, k.ncols),
        );
    }
    check_shapes(k.nrows, d, n, t)?;
    let threads = Arc::new(Threads::new(opts.threads));
    let limit = memory::limit(opts.max_memory);
    let c = d * n.nrows;
    let dense_first = match opts.dual_form {
        DualForm::Dense => true,
        DualForm::MatrixFree => false,
        // A host's Newton loop refactors at every iteration: in 3D the
        // dense route's contacts-last factor costs 2-3 plain ones each time.
        DualForm::Auto => {
            c <= DENSE_MAX && !(opts.host_loop && d == 3 && !opts.method.needs_entries())
        }
    };
    if dense_first {
        // Contact DOFs last, so that the factor's trailing block condenses K
        // onto them.
        let last = contact_dofs(&stack_rows(n, t));
        let analyse = |last: &[usize]| {
            Factor::analyse(
                k,
                last,
                opts.ordering,
                d == 3,
                threads.clone(),
                Ledger::new(),
            )
        };
        let weigh = Weigh {
            contact_dofs: last.len(),
            dofs: k.nrows,
            d,
        };
        // AUTO weighs the routes where the trailing block is not negligible
        // and the method runs matrix-free (one that reads entries of A would
        // form them by c solves on the plain factor at every refactor).
        let weighable =
            opts.dual_form == DualForm::Auto && !opts.method.needs_entries() && weigh.weighable();
        // A thin 3D slab: the plain factor analysed first, and the
        // matrix-free route taken without the contacts-last analysis where
        // the estimate of the flop ratio already exceeds the bound (and that
        // route fits the memory limit).
        let mut plain = None;
        if weighable && weigh.slab() {
            let p = analyse(&[])?;
            let free = matrix_free_plan(k, n, t, d, p, limit);
            if weigh.estimate_exceeds(flops(&free.0)) && fits_limit(&free) {
                return Ok(free);
            }
            plain = Some(free.0);
        }
        let factor = analyse(&last)?;
        let sizes = sizes_of(k, n, t, d, &factor);
        let dense = Condensation::of(true, DualForm::Dense, sizes.c);
        let fits = limit.is_none_or(|l| sizes.setup(dense) <= l);
        // AUTO weighs the dense route's factor against the plain one where
        // the trailing block is a large share of it.
        let flops_last = flops(&factor);
        if weighable && !factor.is_dense() && (plain.is_some() || weigh.large_share(flops_last)) {
            let p = match plain.take() {
                Some(p) => p,
                None => analyse(&[])?,
            };
            let free = matrix_free_plan(k, n, t, d, p, limit);
            // The matrix-free route where it is cheaper and fits, or where
            // the dense one does not fit.
            if (weigh.ratio_exceeds(flops_last, flops(&free.0)) && fits_limit(&free)) || !fits {
                return Ok(free);
            }
        }
        // Asked for, the dense route is kept whatever it needs (`analysed`
        // refuses it with OutOfMemory); AUTO falls back to the matrix-free one.
        if opts.dual_form == DualForm::Dense || fits {
            let form = DualForm::Dense;
            let layer = None;
            return Ok((factor, Plan { sizes, form, layer }, limit));
        }
    }
    // The matrix-free dual works with the best plain factor of K.
    let factor = Factor::analyse(k, &[], opts.ordering, d == 3, threads, Ledger::new())?;
    Ok(matrix_free_plan(k, n, t, d, factor, limit))
}

/// Whether a route's predicted setup fits its memory limit.
fn fits_limit((_, plan, limit): &(Factor, Plan, Option<usize>)) -> bool {
    let how = Condensation::of(true, plan.form, plan.sizes.c);
    limit.is_none_or(|l| plan.sizes.setup(how) <= l)
}

/// AUTO's weighing of the dense route against the matrix-free one for a
/// problem with `contact_dofs` contact DOFs c_C among `dofs` DOFs in
/// dimension `d` (the constants above).
#[derive(Clone, Copy, Debug)]
struct Weigh {
    contact_dofs: usize,
    dofs: usize,
    d: usize,
}

impl Weigh {
    /// c_C^3 / 3, the flops of the dense trailing block.
    fn trailing(&self) -> f64 {
        let c = self.contact_dofs as f64;
        c * c * c / 3.0
    }

    /// Whether the trailing block is large enough to weigh the routes.
    fn weighable(&self) -> bool {
        self.trailing() > MIN_TRAILING_FLOPS
    }

    /// A thin 3D slab ([`SLAB_SHARE`]).
    fn slab(&self) -> bool {
        self.d == 3 && self.contact_dofs as f64 > SLAB_SHARE * self.dofs as f64
    }

    /// Whether the slab's estimate of the flop ratio, from the plain
    /// factor's flops alone, exceeds [`DENSE_MAX_FLOP_RATIO`].
    fn estimate_exceeds(&self, plain: f64) -> bool {
        SLAB_ESTIMATE * self.trailing() / plain > DENSE_MAX_FLOP_RATIO
    }

    /// Whether the trailing block is a large share of the contacts-last
    /// factor's flops ([`TRAILING_SHARE_TO_WEIGH`]).
    fn large_share(&self, last: f64) -> bool {
        self.trailing() > TRAILING_SHARE_TO_WEIGH * last
    }

    /// Whether (flops(L, C last) + c_C^3 / 3) / flops(plain L) exceeds
    /// [`DENSE_MAX_FLOP_RATIO`].
    fn ratio_exceeds(&self, last: f64, plain: f64) -> bool {
        (last + self.trailing()) / plain > DENSE_MAX_FLOP_RATIO
    }
}

/// The matrix-free route on the plain factor's analysis `factor`.
fn matrix_free_plan(
    k: &Csc,
    n: &Csc,
    t: &Csc,
    d: usize,
    factor: Factor,
    limit: Option<usize>,
) -> (Factor, Plan, Option<usize>) {
    let (sizes, layer) = sizes_and_layer(k, n, t, d, &factor);
    let form = DualForm::MatrixFree;
    (factor, Plan { sizes, form, layer }, limit)
}

/// [`route`], refused with `OutOfMemory` before any numeric
/// work when the route's predicted setup exceeds the memory limit.
pub(crate) fn analysed(
    d: usize,
    k: &Csc,
    n: &Csc,
    t: &Csc,
    opts: &Options,
) -> Result<(Factor, Plan)> {
    let (factor, plan, limit) = route(d, k, n, t, opts)?;
    let (sizes, form, layer) = (plan.sizes, plan.form, plan.layer);
    let how = Condensation::of(true, form, sizes.c);
    let need = sizes.setup(how);
    let free = Condensation::MatrixFree;
    let fits = limit.is_none_or(|l| need <= l);
    // Refused on the dense route: what the matrix-free one would need, from
    // the analysis it would use (the plain factor, not the contacts-last one).
    let free_need = match (fits, how != free) {
        (false, true) => {
            let plain = Factor::analyse(
                k,
                &[],
                opts.ordering,
                d == 3,
                factor.threads().clone(),
                Ledger::new(),
            )?;
            Some(sizes_of(k, n, t, d, &plain).setup(free))
        }
        _ => None,
    };
    let hint = if let Some(free_need) = free_need.filter(|&f| f < need) {
        format!(
            "the matrix-free dual (dual_form = matrix-free, method auto, newton or mprgp) would need \
             about {}",
            memory::human(free_need)
        )
    } else {
        format!(
            "K's factor alone takes {} (nnz(L) = {}); a larger max_memory or a \
             machine with more memory is needed",
            memory::human(sizes.factor),
            sizes.factor / F64
        )
    };
    let what = format!(
        "creating the problem (n = {}, c = {}, {} dual)",
        sizes.n,
        sizes.c,
        form.name()
    );
    memory::check(need, limit, opts.max_memory, &what, &hint)?;
    Ok((factor, Plan { sizes, form, layer }))
}

/// The sizes of a problem on the host's solves (`host.rs`): no factor of
/// the library's; K where the host gave it (`k`), and the lumped
/// preconditioner made of it; the contact blocks' [`BLOCK`] right-hand sides
/// while they are formed.
pub(crate) fn host_sizes(k: Option<&Csc>, n: &Csc, t: &Csc, d: usize) -> Sizes {
    let b = stack_rows(n, t);
    Sizes {
        n: n.ncols,
        c: d * n.nrows,
        d,
        inputs: k.map_or(0, |k| k.bytes()) + n.bytes() + t.bytes(),
        blocks_work: BLOCK.min(b.nrows) * n.ncols * F64,
        lumped: k.map_or(0, |k| {
            crate::sparse::congruence_bytes(k, &b, &b.transpose())
        }),
        own_solves: crate::dual::host_rows_bytes(&b),
        ..Sizes::default()
    }
}

/// The analysis report of a problem on the host's solves (see
/// [`host_sizes`]): no ordering or factor of the library's, the dual
/// matrix-free from creation on.
pub(crate) fn host_info(
    d: usize,
    k: Option<&Csc>,
    n: &Csc,
    sizes: &Sizes,
    opts: &Options,
    limit: Option<usize>,
) -> Info {
    let free = Condensation::MatrixFree;
    Info {
        d,
        n: n.ncols,
        m: n.nrows,
        c: sizes.c,
        nnz_k: k.map_or(0, |k| k.nnz()),
        ordering: crate::options::Ordering::Auto,
        factor_nnz: 0,
        factor_flops: 0.0,
        setup_form: DualForm::MatrixFree,
        method: opts.method,
        solve_form: DualForm::MatrixFree,
        setup_bytes: sizes.setup(free),
        resident_bytes: sizes.resident(free),
        refactor_bytes: 0,
        solve_bytes: sizes.solve(free, free, opts.method.workspace(n.nrows, sizes.c, true)),
        memory_limit: limit.unwrap_or(0),
        analyse_seconds: 0.0,
        compliant_contacts: 0,
        power_law_contacts: 0,
        blocks_age: 0,
        err_factor: 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The weighing's predicates on the flop counts measured for the load-path
    /// family (`Factor::analyse` in the route's orderings): the scenes where
    /// the dense route won stay dense, the others go matrix-free.
    #[test]
    fn the_weighing_separates_the_measured_scenes() {
        // 3d-40x40x20: a thick block, its trailing block a ninth of the factor.
        let block = Weigh {
            contact_dofs: 5043,
            dofs: 100_860,
            d: 3,
        };
        assert!(block.weighable() && !block.slab() && !block.large_share(3.955e11));
        // 3d-16x16x4: a slab whose trailing block is negligible.
        let small = Weigh {
            contact_dofs: 867,
            dofs: 3468,
            d: 3,
        };
        assert!(!small.weighable());
        // 3d-24x24x6: six layers, not a slab; a third of its factor trailing.
        let six = Weigh {
            contact_dofs: 1875,
            dofs: 13_125,
            d: 3,
        };
        assert!(six.weighable() && !six.slab() && !six.large_share(6.237e9));
        // 3d-32x32x4: a slab whose estimate exceeds the bound (R = 32.8).
        let slab = Weigh {
            contact_dofs: 3267,
            dofs: 13_068,
            d: 3,
        };
        assert!(slab.weighable() && slab.slab() && slab.estimate_exceeds(9.45e8));
        // 2d-2000x50 (R = 37.1) goes matrix-free, 2d-800x100 (R = 4.0) is not
        // even weighed.
        let long = Weigh {
            contact_dofs: 4002,
            dofs: 200_100,
            d: 2,
        };
        assert!(long.weighable() && !long.slab() && long.large_share(2.828e10));
        assert!(long.ratio_exceeds(2.828e10, 1.339e9));
        let strip = Weigh {
            contact_dofs: 1602,
            dofs: 160_200,
            d: 2,
        };
        assert!(strip.weighable() && !strip.large_share(8.123e9));
        // The bound itself: R = 9 stays dense, R = 11 does not.
        let c = Weigh {
            contact_dofs: 3000,
            dofs: 1_000_000,
            d: 3,
        };
        let t = c.trailing();
        assert!(!c.ratio_exceeds(2.0 * t, t / 3.0));
        assert!(c.ratio_exceeds(2.0 * t, 3.0 * t / 11.0 * 0.99));
    }
}
