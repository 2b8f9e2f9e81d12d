//! The report of a solve: the error measure of design.md section 5, the equilibrium
//! residual, the contact states, iteration counts and timings.

use crate::options::Method;

/// Outcome of a solve.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum SolveStatus {
    /// err <= tol was reached (checked on the recovered u, not only in the dual).
    Converged,
    /// The iteration limit was reached first; the iterate is the last one.
    NotConverged,
    /// The monitor callback asked to stop; the iterate is the last one.
    Stopped,
}

/// Everything a solve reports besides u and the multipliers.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Converged or not.
    pub status: SolveStatus,
    /// The method that ran.
    pub method: Method,
    /// |r| / max(|lambda|, |rho . b|), design.md section 5 (dimensionless).
    pub err: f64,
    /// |K u - f + N^T lambda_N + T^T lambda_T| / |f| (dimensionless; when f = 0 the
    /// denominator is max(|K u|, |B^T lambda|), and 0 when all three vanish).
    pub equilibrium_residual: f64,
    /// Outer iterations (see `Options::max_outer`).
    pub outer_iterations: usize,
    /// Total projected Gauss-Seidel sweeps of the sub-problems (equal to the outer
    /// count for `Pgs`).
    pub inner_iterations: usize,
    /// Open contacts (see [`contact_states`]).
    pub n_open: usize,
    /// Closed, sticking contacts.
    pub n_stick: usize,
    /// Closed, slipping contacts (frictionless closed contacts count here).
    pub n_slip: usize,
    /// Seconds spent in the last numeric factorisation of K.
    pub factor_seconds: f64,
    /// Seconds spent building the condensed dual (A and its diagonal) last time.
    pub condense_seconds: f64,
    /// Seconds of this solve: right-hand side, iterations and recovery of u.
    pub solve_seconds: f64,
}

/// The natural-map error of design.md section 5 for the dual unknowns
/// `lam` = [lambda_N; lambda_T] (length d m):
///
/// r_N,i = lambda_N,i - max(0, lambda_N,i + rho_i v_N,i),
/// r_T,i = lambda_T,i - proj_{|x| <= p_i}(lambda_T,i + rho_i v_T,i),
/// err = |r| / max(|lambda|, |rho . b+|)  (0 when r = 0),
///
/// with v = [N u - g; T u] (length d m), `b` the dual linear term, `rho` one value
/// per contact and `p` the slip bound per contact (mu_i lambda_N,i for Coulomb).
/// b+ keeps the tangential part of b and the positive part of its normal part,
/// max(0, (N K^-1 f - g)_i): the force scale the load creates. design.md writes
/// |rho . b|; with the raw normal part, the gaps of far-open contacts (b_N,i =
/// -g_i large) would set the scale and hide wrong forces on the closed ones.
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
    let mut rb2 = 0.0;
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
        rb2 += (rho[i] * b[i].max(0.0)).powi(2);
        let t0 = m + (d - 1) * i;
        let k = d - 1;
        for s in 0..k {
            y[s] = lam[t0 + s] + rho[i] * v[t0 + s];
        }
        crate::methods::project_disk(&mut y[..k], p[i]);
        for s in 0..k {
            let lt = lam[t0 + s];
            r2 += (lt - y[s]).powi(2);
            l2 += lt * lt;
            rb2 += (rho[i] * b[t0 + s]).powi(2);
        }
    }
    if r2 == 0.0 {
        return 0.0;
    }
    r2.sqrt() / l2.max(rb2).sqrt()
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
        // |r| = 0.5, scale max(|lambda| = 1, |rho . b+| = 0) = 1.
        assert_eq!(err, 0.5);
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
