//! The report of a solve: the error measure of docs/design.md section 5, the equilibrium
//! residual, the contact states, iteration counts and timings.

use crate::options::Method;

/// Outcome of a solve. Later versions may add statuses (`#[non_exhaustive]`).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SolveStatus {
    /// err <= tol was reached (checked on the recovered u, not only in the dual).
    Converged,
    /// The iteration limit was reached first, or the method found the problem
    /// infeasible (err is then infinite, see [`Report::err`]). At the limit every
    /// method returns the iterate with the lowest err it met (a Coulomb fixed point
    /// that cycles need not end on its best point).
    NotConverged,
    /// The monitor callback asked to stop; the iterate is the last one.
    Stopped,
    /// The method stopped making progress (the stagnation test of
    /// `Options::stall_window` and `Options::stall_factor`; Newton also when its
    /// natural residual |F| stops falling): the iterate with the lowest err. On a problem without a solution
    /// (no u with N u <= g) the Gauss-Seidel methods end this way.
    Stalled,
    /// The wall-clock budget `Options::max_seconds` ran out: the iterate with the
    /// lowest err.
    TimeLimit,
}

impl SolveStatus {
    /// Short lower-case name, as in report.json and the command line
    /// ("converged", "not-converged", "stopped", "stalled", "time-limit").
    pub fn name(self) -> &'static str {
        match self {
            SolveStatus::Converged => "converged",
            SolveStatus::NotConverged => "not-converged",
            SolveStatus::Stopped => "stopped",
            SolveStatus::Stalled => "stalled",
            SolveStatus::TimeLimit => "time-limit",
        }
    }
}

/// Everything a solve reports besides u and the multipliers. Later versions
/// may add fields (`#[non_exhaustive]`: read it, do not build it).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Report {
    /// Converged, or why not.
    pub status: SolveStatus,
    /// The method that gave the answer: `Options::method`, or for `Auto` the
    /// method it chose (the last one it ran).
    pub method: Method,
    /// For `Method::Auto`: why it chose `method`, one line; empty otherwise.
    pub choice: String,
    /// |r| / max(|lambda|, |b+| / trace(A)), the natural-map error of
    /// docs/design.md section 5 (dimensionless), multiplied by
    /// `Info::err_factor` after a refactor that kept the contact blocks.
    /// Infinite when the contact constraints admit no displacement (no u
    /// with N u <= g): a penetrating contact without rows in N and T, or, for SplitMprgp and Mprgp, a dual unbounded below (a
    /// combination z >= 0 of normal rows with N^T z = 0 and g . z < 0, e.g. two
    /// opposite normals on one DOF with gaps that overlap). The other methods do not
    /// detect the latter: they end `Stalled` (their multipliers grow along the
    /// unbounded direction and err falls too slowly to reach tol).
    pub err: f64,
    /// |K u - f + N^T lambda_N + T^T lambda_T| / |f| (dimensionless; when f = 0 the
    /// denominator is max(|K u|, |B^T lambda|), and 0 when all three vanish).
    pub equilibrium_residual: f64,
    /// Outer iterations (see `Options::max_outer`).
    pub outer_iterations: usize,
    /// Inner iterations, in total; what one is depends on the route: a
    /// projected Gauss-Seidel sweep over the contacts (`Pgs`, where it equals
    /// the outer count; the splittings' sub-problems on a dense dual; Newton's
    /// warm-up and fallback sweeps on a dense dual), or one product with A
    /// (MPRGP, the sub-problems on a matrix-free dual, Newton's Krylov solves
    /// on a matrix-free dual). Newton's product for the explicit part of a
    /// step, its backtracking product (taken only where the Krylov solve's
    /// products were narrowed or refined; elsewhere A d is combined from
    /// them), the exact recomputations of the gradient (after a step whose
    /// single-precision products drifted too far, and before a convergence
    /// is accepted on such a gradient) and the lumped start's two products
    /// are not counted (one or two per Newton step).
    pub inner_iterations: usize,
    /// The dual unknowns the method iterated on: m when a frictionless increment
    /// was solved as the pure Signorini problem (docs/design.md section 2), d m
    /// otherwise.
    pub dual_unknowns: usize,
    /// Open contacts: lambda_N,i + rho_i v_N,i <= 0, read off the natural map of
    /// err (docs/design.md section 5), so the classification is as robust as err.
    pub n_open: usize,
    /// Closed, sticking contacts.
    pub n_stick: usize,
    /// Closed, slipping contacts: |lambda_T,i + rho_i v_T,i| >= p_i (frictionless
    /// closed contacts count here).
    pub n_slip: usize,
    /// Seconds spent in the last numeric factorisation of K.
    pub factor_seconds: f64,
    /// Seconds spent building the condensed dual (A and its diagonal) last time.
    pub condense_seconds: f64,
    /// Seconds of this solve: right-hand side, iterations and recovery of u.
    pub solve_seconds: f64,
    /// The fill-reducing ordering K's factor was computed with (`Amd` or `Metis`;
    /// `Options::ordering` = `Auto` picks one; `Dense` for a K given dense).
    pub ordering: crate::Ordering,
    /// Nonzeros of the Cholesky factor L (dense supernodal blocks included).
    pub factor_nnz: usize,
    /// Flops of one numeric factorisation of K, sum over the columns of L of
    /// (entries in the column)^2.
    pub factor_flops: f64,
    /// Threads the problem's pool has (1: the calling thread only).
    pub threads: usize,
    /// Seconds of K's analysis (ordering and symbolic factorisation) when the
    /// problem was created.
    pub analyse_seconds: f64,
    /// The predicted peak of the library's large allocations during this solve,
    /// bytes (what the problem holds, the solve's vectors, the method's dense
    /// work space in its largest case; see `Options::max_memory`).
    pub memory_predicted: usize,
    /// The measured peak of the same allocations during this solve, bytes
    /// (counted as they are made, not read from the operating system).
    pub memory_peak: usize,
    /// The law solved: the number of contacts with a compliant interface
    /// (finite c_N or k_T, `ContactProblem::set_compliance`); 0 for the rigid
    /// Signorini-Coulomb (or Tresca) law. Where it is not 0, err is the natural
    /// map of the regularised conditions (docs/design.md section 8).
    pub compliant_contacts: usize,
    /// Where `solve_seconds` went: the right-hand side b = B K^-1 f - [g; 0]
    /// (a forward and a back solve with K's factor, or the back solve's
    /// trailing part; a history step's start), ...
    pub rhs_seconds: f64,
    /// ... the method's iterations (every run, where the dual tolerance was
    /// tightened or a nonlinear law took rounds: `inner_iterations` says what
    /// they were), ...
    pub iterate_seconds: f64,
    /// ... and the recovery of u = K^-1 (f - B^T lambda) with the error measured
    /// on it, after each run. The rest of `solve_seconds` is the report
    /// (equilibrium residual, contact states).
    pub recover_seconds: f64,
    /// On a problem made on the host's solver
    /// ([`crate::ContactProblem::with_host_solver`]): right-hand sides the
    /// host's solve took during this call (0 on the library's own factor).
    pub host_solves: usize,
    /// ... and the seconds inside the host's solve, part of `solve_seconds`.
    pub host_seconds: f64,
}

/// The natural-map error of docs/design.md section 5 for the dual unknowns
/// `lam` = [lambda_N; lambda_T] (length d m):
///
/// r_N,i = lambda_N,i - max(0, lambda_N,i + rho_i v_N,i),
/// r_T,i = lambda_T,i - proj_{|x| <= p_i}(lambda_T,i + rho_i v_T,i),
/// err = |r| / max(|lambda|, |b+| / trace(A))  (0 when r = 0),
///
/// with v = [N u - g; T u] (length d m), `b` the dual linear term, `rho` one value
/// per contact (rho_i = d / trace of contact i's d x d block of A) and `p` the slip
/// bound per contact (mu_i lambda_N,i for Coulomb). b+ keeps the tangential part of
/// b and the positive part of its normal part, max(0, (N K^-1 f - g)_i), and
/// trace(A) = sum_i d / rho_i.
///
/// Two deviations from the founding design notes, which wrote the scale as
/// max(|lambda|, |rho . b|) (docs/design.md section 5 records both):
///
/// - The positive part of b_N: with the raw normal part, the gaps of far-open
///   contacts (b_N,i = -g_i large) would set the scale and hide wrong forces on the
///   closed ones.
/// - |b+| / trace(A) instead of |rho . b+|. rho_i b_i is the force contact i would
///   carry if it alone stopped the load's free displacement b_i; when contacts share
///   the load through a compliant body, that overstates the forces by the coupling.
///   On the slender beam of tests/hard_scenes.rs (100 contacts, cond(A) 7e7)
///   |rho . b+| is 1250 times |lambda|: err would pass an answer that penetrates
///   by 3.7e-5 of max|u|. Since trace(A) >= |A|_2, the load scale never exceeds
///   |b+| / |A|_2 <= |A^-1 b+| (the forces if every contact were tied): on the
///   beam it is 1.5e-2, and |lambda| is the scale as soon as the answer carries
///   forces. The load scale is still what keeps err finite and small when the
///   exact answer has (nearly) no force: grazing contact under a tangential load
///   leaves lambda ~ 1e-15 and residuals at rounding level. Both scales are force
///   units, so err stays invariant under K, f -> s K, s f and under units of length.
///
/// What err cannot see. err measures forces relative to forces, with rho_i = 1/A_ii
/// per contact, so a displacement error e at a compliant contact costs only
/// rho_i e: on the beam rho runs from 26 (at the clamp) to 7.7e-5 (at the tip), and
/// the rounding floor of r (4.6e-13, err 2.3e-11 for Newton, set by the stiff
/// contacts: u is recovered from f - B^T lambda, which cancels a free deflection of
/// 2,000 down to 0.1) hides tip displacement errors below ~6e-10. Gauss-Seidel
/// iterates leave exactly such errors (smooth modes at the compliant end): BlockGs
/// at err 2.5e-11 has KKT feasibility 1.3e-8 of max|u| and lambda 2.6e-5 off at the
/// tip, where Newton and MPRGP at the same err have 2.8e-10. A dual, scale-
/// invariant err cannot do better: the dual problem (A, b) is the same for data
/// (f, g) whose free displacements differ by a common shift, while max|u| is not, so
/// a bound on displacements relative to max|u| needs u, which this function does
/// not see.
///
/// A contact with rho_i = 0 (empty rows of N and T) and v_N,i > 0 is a penetration
/// no force can remove: err is then infinite (the problem is infeasible).
pub fn natural_map_error(
    lam: &[f64],
    v: &[f64],
    rho: &[f64],
    b: &[f64],
    p: &[f64],
    d: usize,
) -> f64 {
    let m = rho.len();
    let mut r2 = 0.0;
    let mut l2 = 0.0;
    let mut b2 = 0.0;
    let mut trace = 0.0;
    let mut y = [0.0; 2];
    for i in 0..m {
        if rho[i] == 0.0 && v[i] > 0.0 {
            // A contact whose rows of N and T are empty cannot act on u: a
            // penetration there (g_i < 0) is infeasible, and no lambda fixes it.
            return f64::INFINITY;
        }
        let ln = lam[i];
        let rn = ln - (ln + rho[i] * v[i]).max(0.0);
        r2 += rn * rn;
        l2 += ln * ln;
        b2 += b[i].max(0.0).powi(2);
        if rho[i] > 0.0 {
            trace += d as f64 / rho[i];
        }
        let t0 = m + (d - 1) * i;
        let k = d - 1;
        for s in 0..k {
            y[s] = lam[t0 + s] + rho[i] * v[t0 + s];
        }
        crate::friction::project_disk(&mut y[..k], p[i]);
        for s in 0..k {
            let lt = lam[t0 + s];
            r2 += (lt - y[s]).powi(2);
            l2 += lt * lt;
            b2 += b[t0 + s].powi(2);
        }
    }
    if r2 == 0.0 {
        return 0.0;
    }
    let load = if trace > 0.0 { b2.sqrt() / trace } else { 0.0 };
    r2.sqrt() / l2.sqrt().max(load)
}

/// Counts of (open, stick, slip) contacts, read off the natural map of the error
/// measure so that the classification is as robust as err itself: contact i is open
/// when lambda_N,i + rho_i v_N,i <= 0 (the normal projection is inactive), slipping
/// when closed and |lambda_T,i + rho_i v_T,i| >= p_i (the friction projection is
/// active; frictionless closed contacts count here), sticking otherwise.
pub fn contact_states(
    lam: &[f64],
    v: &[f64],
    rho: &[f64],
    p: &[f64],
    d: usize,
) -> (usize, usize, usize) {
    let m = p.len();
    let (mut open, mut stick, mut slip) = (0, 0, 0);
    for i in 0..m {
        if lam[i] + rho[i] * v[i] <= 0.0 {
            open += 1;
            continue;
        }
        let t0 = m + (d - 1) * i;
        let trial = (t0..t0 + d - 1)
            .map(|j| (lam[j] + rho[i] * v[j]).powi(2))
            .sum::<f64>()
            .sqrt();
        if trial >= p[i] {
            slip += 1;
        } else {
            stick += 1;
        }
    }
    (open, stick, slip)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_open_gaps_do_not_set_the_force_scale() {
        // Two 2D contacts: contact 0 carries a wrong force (lambda 1 while its gap
        // is open by 0.5: r_N = 1 - max(0, 1 - 0.5) = 0.5), contact 1 is far open
        // (b_N = -1e8, r = 0). With |rho . b| as the scale err would be 5e-9.
        let lam = [1.0, 0.0, 0.0, 0.0];
        let v = [-0.5, -1e8, 0.0, 0.0];
        let b = [-0.5, -1e8, 0.0, 0.0];
        let rho = [1.0, 1.0];
        let err = natural_map_error(&lam, &v, &rho, &b, &[0.0, 0.0], 2);
        // |r| = 0.5, scale max(|lambda| = 1, |b+| / trace(A) = 0) = 1.
        assert_eq!(err, 0.5);
    }

    #[test]
    fn the_load_scale_is_the_load_over_the_trace_of_a() {
        // Two 2D contacts with A_ii = 1e3 (rho = 2 / trace of each 2 x 2 block of
        // A = 2 / 2e3), strongly coupled, sharing a load b_N = 100 each: the forces
        // are 0.05 each, while rho_i b_i = 0.1 (what one contact alone would carry).
        // Contact 0 penetrates by 1e-3 (r_N = -rho v_N = -1e-6).
        let rho = [1e-3, 1e-3];
        let b = [100.0, 100.0, 0.0, 0.0];
        let v = [1e-3, 0.0, 0.0, 0.0];
        let lam = [0.05, 0.05, 0.0, 0.0];
        let err = natural_map_error(&lam, &v, &rho, &b, &[0.0, 0.0], 2);
        // |r| = 1e-6; |lambda| = 0.0707; |b+| / trace(A) = 141.4 / 4000 = 0.0354.
        let want = 1e-6 / 0.05f64.hypot(0.05);
        assert!((err - want).abs() <= 1e-12 * want, "{err} vs {want}");
        // With no force yet, the load scale: err = 1e-6 / (100 sqrt 2 / 4000).
        let err = natural_map_error(&[0.0; 4], &v, &rho, &b, &[0.0, 0.0], 2);
        let want = 1e-6 / (100.0f64.hypot(100.0) / 4000.0);
        assert!((err - want).abs() <= 1e-12 * want, "{err} vs {want}");
    }

    #[test]
    fn penetration_at_a_contact_without_rows_is_infeasible() {
        let lam = [0.0, 0.0];
        let err = natural_map_error(&lam, &[0.1, 0.0], &[0.0], &[-0.1, 0.0], &[0.0], 2);
        assert_eq!(err, f64::INFINITY);
        let err = natural_map_error(&lam, &[-0.1, 0.0], &[0.0], &[0.1, 0.0], &[0.0], 2);
        assert_eq!(err, 0.0);
    }
}
