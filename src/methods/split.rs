//! N. Pop's dual splitting (docs/design.md section 3) and the plain block Gauss-Seidel
//! variant: the tangential and the normal multipliers are solved in alternation,
//! each sub-problem by a [`SubSolver`] (projected Gauss-Seidel for `split` and
//! `block-gs`, MPRGP for `split-mprgp`).
//!
//! Schur variant, one outer iteration:
//! 1. tangential step on `S = A22 - A21[:,a] A11[a,a]^-1 A12[a,:]` with
//!    `b_T' = b_T - A21[:,a] A11[a,a]^-1 b_N[a]`, a the contacts with lambda_N > 0
//!    (all of them at the start), bound from the previous lambda_N (Coulomb);
//! 2. normal step on A11 with b_N - A12 lambda_T, lambda_N >= 0.
//!
//! The block variant uses S = A22 and b_T' = b_T - A21 lambda_N. When `A11[a,a]` is
//! numerically singular (redundant contacts), the Schur variant takes the block
//! step for that iteration.
//!
//! Coulomb (docs/design.md section 3: the fixed point p = mu lambda_N folded into the
//! outer loop). For one slipping contact the outer map is
//! lambda_N <- (b_N - s mu A_NT lambda_N) / A_NN: it contracts only while
//! mu |A_NT| < A_NN, and with strong normal-tangential coupling (an inclined
//! foundation under a body compliant sideways; tests/hard_scenes.rs
//! `large_coulomb_friction_fixed_point_does_not_contract`, A_NT / A_NN = 4 to 5.8)
//! it cycles for every mu >= 1. The outer loop is therefore relaxed by Aitken's
//! factor ([`Aitken`]; 1, the plain iteration, while the map does not oscillate):
//! the Schur variant, whose tangential step already carries the normal response of
//! the active set, relaxes the bound, p_k = p_k-1 + omega (mu lambda_N - p_k-1);
//! the block variant, whose steps ignore that response, relaxes the whole iterate.
//! At the iteration limit the iterate with the lowest error is returned.

use super::aitken::Aitken;
use super::driver::{Flow, Gradient, OuterStep};
use super::signorini::frictionless;
use super::subproblem::{GaussSeidel, Mprgp, SubQp, SubSolver};
use super::{Built, DualProblem, MethodSpec, Options, inner_rule};
use crate::dense::llt_solve;
use crate::memory::{Claim, F64};
use crate::threads::PARALLEL_MIN_ENTRIES;
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat};

/// The Schur complement data of one contact set.
struct Schur {
    active: Vec<bool>,
    s: Vec<f64>,
    /// The bytes of `s` on the problem's ledger.
    _claim: Claim,
    /// `b_T - A21[:,a] A11[a,a]^-1 b_N[a]`.
    q: Vec<f64>,
}

/// Builds S and b_T' for the contact set `active`; None when `A11[a,a]` is not
/// numerically positive definite.
fn schur(problem: &DualProblem<'_>, active: &[bool]) -> Option<Schur> {
    let dual = problem.dual;
    let (m, c) = (dual.m, dual.c);
    let ct = c - m;
    let idx: Vec<usize> = (0..m).filter(|&i| active[i]).collect();
    let na = idx.len();
    let ledger = &dual.ledger;
    // A11[a,a], [A12[a,:], b_N[a]] and X held to the end; the Cholesky factor of
    // A11[a,a] while X is solved for.
    let _held = ledger.claim_f64(na * na + 2 * na * (ct + 1));
    let factor_claim = ledger.claim_f64(na * na);
    let a11 = Mat::from_fn(na, na, |r, s| dual.a[idx[r] + idx[s] * c]);
    // Columns: A12[a,:] (ct columns) then b_N[a].
    let rhs = Mat::from_fn(na, ct + 1, |r, s| {
        if s < ct {
            dual.a[idx[r] + (m + s) * c]
        } else {
            problem.b[idx[r]]
        }
    });
    let threads = &*dual.threads;
    let big = na * (na + ct) >= PARALLEL_MIN_ENTRIES;
    let x = if na > 0 {
        let x = threads.run(big, |par| llt_solve(a11.as_ref(), rhs.as_ref(), par))?;
        if !x.as_ref().is_all_finite() {
            return None;
        }
        x
    } else {
        rhs.clone()
    };
    drop(factor_claim);
    // [S, b_T'] = [A22, b_T] - A21[:,a] [X, y] with one matrix product.
    let _sq_claim = ledger.claim_f64(ct * (ct + 1));
    let mut sq = Mat::from_fn(ct, ct + 1, |i, j| {
        if j < ct {
            dual.a[(m + i) + (m + j) * c]
        } else {
            problem.b[m + i]
        }
    });
    if na > 0 {
        let lhs = rhs.subcols(0, ct).transpose();
        threads.run(big, |par| {
            matmul(sq.as_mut(), Accum::Add, lhs, x.as_ref(), -1.0, par);
        });
    }
    let s_claim = ledger.claim_f64(ct * ct);
    let mut s = vec![0.0; ct * ct];
    for j in 0..ct {
        for i in 0..ct {
            s[i + j * ct] = sq[(i, j)];
        }
    }
    let q: Vec<f64> = (0..ct).map(|i| sq[(i, ct)]).collect();
    // Exact symmetry for the Gauss-Seidel sweeps.
    for j in 0..ct {
        for i in 0..j {
            let v = 0.5 * (s[i + j * ct] + s[j + i * ct]);
            s[i + j * ct] = v;
            s[j + i * ct] = v;
        }
    }
    Some(Schur {
        active: active.to_vec(),
        s,
        _claim: s_claim,
        q,
    })
}

/// `split`: the Schur variant, sub-problems by projected Gauss-Seidel.
pub(super) const SPLIT: MethodSpec = MethodSpec {
    name: "split",
    needs_entries: true,
    workspace: schur_workspace,
    build: |problem, opts, target| build(problem, opts, target, Variant::Schur, GaussSeidel::new),
};

/// `block-gs`: the block variant, sub-problems by projected Gauss-Seidel.
pub(super) const BLOCK_GS: MethodSpec = MethodSpec {
    name: "block-gs",
    needs_entries: true,
    workspace: super::no_workspace,
    build: |problem, opts, target| build(problem, opts, target, Variant::Block, GaussSeidel::new),
};

/// `split-mprgp`: the Schur variant, sub-problems by MPRGP / MPGP.
pub(super) const SPLIT_MPRGP: MethodSpec = MethodSpec {
    name: "split-mprgp",
    needs_entries: true,
    workspace: schur_workspace,
    build: |problem, opts, target| build(problem, opts, target, Variant::Schur, Mprgp::new),
};

/// Bytes of the Schur variant's dense work space on m contacts and c unknowns
/// (ct = c - m tangential ones): the S of the previous contact set (ct x ct)
/// while the next is formed from `A11[a,a]` (held with its Cholesky factor, then
/// with S and `[S, b_T']`), `[A12[a,:], b_N[a]]` and its solve X, for a contact set
/// a of up to m contacts (see [`schur`]).
fn schur_workspace(m: usize, c: usize, _matrix_free: bool) -> usize {
    let ct = c - m;
    let held = m * m + 2 * m * (ct + 1);
    F64 * (ct * ct + held + (m * m).max(ct * (ct + 1) + ct * ct))
}

/// The splitting `variant` with sub-problems by `solver(k, tol, max)`; a
/// frictionless increment as the pure Signorini problem (m unknowns).
fn build<S: SubSolver + 'static>(
    problem: &DualProblem<'_>,
    opts: &Options,
    target: f64,
    variant: Variant,
    solver: fn(usize, f64, usize) -> S,
) -> Built {
    if let Some(signorini) = frictionless(problem, opts, target, solver) {
        return signorini;
    }
    let (m, c) = (problem.dual.m, problem.dual.c);
    let (tol, max) = inner_rule(opts, target);
    let sub = solver(m.max(c - m), tol, max);
    (Box::new(Split::new(problem, variant, sub)), c)
}

/// Which tangential matrix the splitting uses.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Variant {
    /// Pop's: the Schur complement S of the current contact set.
    Schur,
    /// Plain block Gauss-Seidel: A22.
    Block,
}

/// The splitting with sub-problem solver `S`.
pub(super) struct Split<S> {
    variant: Variant,
    /// The sub-problem solver, with the sub-problem stopping rule.
    solver: S,
    /// MPRGP's estimates of |A_NN| (fixed) and of the tangential matrix's norm
    /// (reset when that matrix changes).
    norm_n: Option<f64>,
    norm_t: Option<f64>,
    norm_t_of_schur: bool,
    qn: Vec<f64>,
    qt: Vec<f64>,
    p: Vec<f64>,
    cache: Option<Schur>,
    active: Vec<bool>,
    coulomb: bool,
    relax: Aitken,
    /// The bound of the last tangential step (Schur variant) or the last iterate
    /// (block variant), Coulomb only.
    prev: Vec<f64>,
}

impl<S: SubSolver> Split<S> {
    pub fn new(problem: &DualProblem<'_>, variant: Variant, solver: S) -> Self {
        let dual = problem.dual;
        let (m, c) = (dual.m, dual.c);
        // Coulomb: the Schur variant relaxes the bound p, the block variant the
        // whole iterate (module documentation).
        let coulomb = problem.law.is_coulomb();
        let relaxed = match (coulomb, variant) {
            (false, _) => 0,
            (true, Variant::Schur) => m,
            (true, Variant::Block) => c,
        };
        Split {
            variant,
            solver,
            norm_n: None,
            norm_t: None,
            norm_t_of_schur: false,
            qn: vec![0.0; m],
            qt: vec![0.0; c - m],
            p: vec![0.0; m],
            cache: None,
            active: vec![true; m],
            coulomb,
            relax: Aitken::new(relaxed),
            prev: vec![0.0; relaxed],
        }
    }

    /// The normal step: lambda_N := argmin over y >= 0 of
    /// 1/2 y^T A11 y - y^T (b_N - A12 lambda_T).
    fn normal_step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        inner: &mut usize,
    ) -> Flow {
        let dual = problem.dual;
        let (m, c) = (dual.m, dual.c);
        self.qn.copy_from_slice(&problem.b[..m]);
        for j in 0..c - m {
            let lt = lam[m + j];
            if lt != 0.0 {
                let col = &dual.col(m + j)[..m];
                self.qn.iter_mut().zip(col).for_each(|(q, a)| *q -= a * lt);
            }
        }
        let sub = SubQp {
            h: &dual.a,
            ld: c,
            k: m,
            q: &self.qn,
            block: 1,
            radii: None,
            op: None,
            threads: &dual.threads,
        };
        let run = self.solver.solve(&sub, &mut lam[..m], &mut self.norm_n);
        Flow::after(run, inner, Gradient::Stale)
    }

    /// The tangential step with the bound in `self.p`.
    fn tangential_step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        inner: &mut usize,
    ) -> Flow {
        let dual = problem.dual;
        let (m, d, c) = (dual.m, dual.d, dual.c);
        let ct = c - m;
        let schur_variant = self.variant == Variant::Schur;
        if schur_variant && self.cache.as_ref().is_none_or(|s| s.active != self.active) {
            self.cache = schur(problem, &self.active);
            self.norm_t = None;
        }
        // The tangential matrix is the cached Schur complement or A22.
        let of_schur = schur_variant && self.cache.is_some();
        if of_schur != self.norm_t_of_schur {
            self.norm_t = None;
            self.norm_t_of_schur = of_schur;
        }
        let sub = match &self.cache {
            Some(sc) if schur_variant => SubQp {
                h: &sc.s,
                ld: ct,
                k: ct,
                q: &sc.q,
                block: d - 1,
                radii: Some(&self.p),
                op: None,
                threads: &dual.threads,
            },
            _ => {
                // q_T = b_T - A21 lambda_N
                self.qt.copy_from_slice(&problem.b[m..]);
                for (i, &ln) in lam[..m].iter().enumerate() {
                    if ln != 0.0 {
                        let col = &dual.col(i)[m..];
                        self.qt.iter_mut().zip(col).for_each(|(q, a)| *q -= a * ln);
                    }
                }
                SubQp {
                    h: &dual.a[m + m * c..],
                    ld: c,
                    k: ct,
                    q: &self.qt,
                    block: d - 1,
                    radii: Some(&self.p),
                    op: None,
                    threads: &dual.threads,
                }
            }
        };
        let run = self.solver.solve(&sub, &mut lam[m..], &mut self.norm_t);
        Flow::after(run, inner, Gradient::Stale)
    }
}

impl<S: SubSolver> OuterStep for Split<S> {
    /// Start: lambda_N of the frictionless problem unless warm-started.
    fn start(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        _w: &mut [f64],
        inner: &mut usize,
    ) -> Flow {
        let m = problem.dual.m;
        let mut flow = Flow::Go(Gradient::Exact);
        if lam.iter().all(|&x| x == 0.0) {
            flow = self.normal_step(problem, lam, inner);
        }
        if self.coulomb && self.variant == Variant::Schur {
            problem.law.bounds(&lam[..m], &mut self.prev);
        }
        flow
    }

    fn step(
        &mut self,
        problem: &DualProblem<'_>,
        lam: &mut [f64],
        _w: &mut [f64],
        inner: &mut usize,
        k: usize,
    ) -> Flow {
        let (m, c) = (problem.dual.m, problem.dual.c);
        // Tangential step. Coulomb: the bound p = mu lambda_N of the last normal
        // step, relaxed in the Schur variant: p_k = p_k-1 + omega (mu lambda_N - p_k-1).
        problem.law.bounds(&lam[..m], &mut self.p);
        if self.coulomb {
            match self.variant {
                Variant::Schur => self.relax.relax_bound(&mut self.prev, &mut self.p, k == 0),
                Variant::Block => self.prev.copy_from_slice(lam),
            }
        }
        if c > m && self.tangential_step(problem, lam, inner) == Flow::Infeasible {
            return Flow::Infeasible;
        }
        if self.normal_step(problem, lam, inner) == Flow::Infeasible {
            return Flow::Infeasible;
        }
        if self.coulomb && self.variant == Variant::Block {
            self.relax.relax(&self.prev, lam);
        }
        for (a, &ln) in self.active.iter_mut().zip(&lam[..m]) {
            *a = ln > 0.0;
        }
        Flow::Go(Gradient::Stale)
    }
}
