//! One iteration of a host's own Newton loop (docs/design.md section 9): the
//! linearised contact problem of a nonlinear host, whose friction acts on the
//! slip of the whole load increment, the slip the host's earlier iterations
//! already took included.
//!
//! The host at iteration j of an increment that started at u_n holds u_j, its
//! tangent K (refactored on the handle), its residual r = f_ext - f_int(u_j)
//! without contact forces, the gaps g_j at u_j and the slip already taken
//! s_j = T (u_j - u_n). The iteration's problem in du is that of docs/design.md
//! section 1 with f = r, g = g_j and the slip s_j + T du in place of T du:
//!
//! ```text
//! K du = r - N^T lambda_N - T^T lambda_T,   N du <= g_j,  Signorini,
//! stick: s_j + T du = 0,   slip: s_j + T du = alpha lambda_T,  |lambda_T,i| <= p_i
//! ```
//!
//! lambda are the TOTAL contact forces at u_j + du. In the dual the slip
//! offset is a tangential gap: b = B K^-1 r - [g_j; -s_j] (the Lagrangian's
//! friction term lambda_T^T (T du + s_j)), so every method and both dual forms
//! solve it unchanged, and the error measure reads v = [N du - g_j; T du + s_j].
//! The iteration starts from the multipliers of the last converged iteration
//! on the handle: at a converging host loop they are this iteration's answer.
//! The first iteration of an increment (no slip taken) starts from the line
//! through the multipliers that ended the last two increments, where the
//! load changes of the two increments lie on one line
//! (`history::Increments`): under a proportional load the increment's
//! answer lies near it, where the last one's is a whole increment away. A
//! later iteration, from the third of an increment on, starts on the line
//! through the last two iterations' answers, at the point that best cancels
//! the natural map there (`solve::iteration_line`), where that lowers |F|:
//! a loop whose tangent settles moves its multipliers along nearly one
//! direction.

use super::*;

/// The data of one host iteration: what a nonlinear host has at its iterate
/// u_j (module docs).
#[derive(Clone, Copy, Debug)]
pub struct HostIteration<'a> {
    /// r = f_ext - f_int(u_j), the host's residual without contact forces
    /// (n values, force units).
    pub r: &'a [f64],
    /// g_j = g_0 - N u_j as the host measures it at u_j (m values, length
    /// units; negative: penetration at u_j).
    pub g: &'a [f64],
    /// s_j = T (u_j - u_n), the slip already taken in the increment ((d - 1) m
    /// values, one per row of T, length units); None marks the first
    /// iteration of an increment (zero slip, and the increments' line of the
    /// module docs); a later iteration where nothing slipped passes zeros.
    pub slip: Option<&'a [f64]>,
    /// The tangential forces at the start of the increment ((d - 1) m values),
    /// where an interface compliance (`set_compliance`, k_T finite) makes
    /// lambda_T = proj(lambda_T,start + k_T (s_j + T du)); None for zero.
    /// Read only at contacts with a finite k_T.
    pub lt_start: Option<&'a [f64]>,
}

impl ContactProblem {
    /// Solves one iteration of the host's Newton loop (module docs): returns
    /// du in `Solution::u` and the total contact forces, starting from the
    /// multipliers of the last converged iteration on this handle (zero
    /// before the first, after [`ContactProblem::reset_history`] or a change
    /// of m), or, for the first iteration of an increment (`it.slip` None),
    /// from the line through the multipliers that ended the last two
    /// increments (module docs); from the third iteration of an increment
    /// on, from the line through the last two iterations' answers where
    /// that lowers the natural map's residual (module docs; not with an
    /// interface compliance). They are kept only when this one converges;
    /// a first iteration, `set_contacts`, `set_compliance` and
    /// [`ContactProblem::reset_history`] forget the line (an error or a
    /// later iteration that does not converge leaves it as it was). The history of
    /// [`ContactProblem::step`] is neither used nor changed.
    ///
    /// `opts.tol` may follow the host's residual, loose in the early
    /// iterations and `tol` in the last (an inexact Newton step; docs/design.md
    /// section 9).
    ///
    /// Errors: as [`ContactProblem::solve`], and `BadSize` / `NotFinite` for
    /// `slip` and `lt_start` (named slip and lambda_t_start in the message, as
    /// in C). Non-convergence is `report.status`.
    pub fn solve_iteration(
        &mut self,
        it: &HostIteration<'_>,
        friction: Friction<'_>,
        opts: &Options,
    ) -> Result<Solution> {
        self.solve_iteration_monitored(it, friction, opts, None)
    }

    /// As [`ContactProblem::solve_iteration`], with a monitor as in
    /// [`ContactProblem::solve_monitored`].
    pub fn solve_iteration_monitored(
        &mut self,
        it: &HostIteration<'_>,
        friction: Friction<'_>,
        opts: &Options,
        monitor: Option<Monitor<'_>>,
    ) -> Result<Solution> {
        self.check_data(("r", it.r), ("g", it.g), friction)?;
        let mt = (self.d - 1) * self.n_contacts();
        if let Some(s) = it.slip {
            check_vec("slip", s, mt)?;
        }
        if let Some(lt) = it.lt_start {
            check_vec("lambda_t_start", lt, mt)?;
        }
        opts.check("")?;
        let predicted = self.prepare_dual(opts)?;
        let (m, c) = (self.n_contacts(), self.dual.c);
        // The gaps of every dual row: [g_j; -s_j].
        let mut gaps = vec![0.0; c];
        gaps[..m].copy_from_slice(it.g);
        if let Some(s) = it.slip {
            for (x, y) in gaps[m..].iter_mut().zip(s) {
                *x = -y;
            }
        }
        let mut lam = self.iteration_start.clone();
        if lam.len() != c {
            lam = vec![0.0; c];
        }
        // The first iteration of an increment (no slip taken yet) from the
        // multipliers that ended the last one starts from the increments'
        // prediction (`history::Increments`), a later one from the last
        // iteration's multipliers.
        let first = it.slip.is_none();
        let lam_n = first.then(|| lam.clone());
        // Lent to the solve (which needs the handle mutable) and put back
        // after; a panic inside forgets it (no prediction for the next
        // increment).
        let increments = std::mem::take(&mut self.increments);
        let before = std::mem::take(&mut self.iteration_before);
        let warm = if first {
            solve::Warm::Increment(&increments)
        } else if before.len() == c {
            solve::Warm::Line(&before)
        } else {
            solve::Warm::Given
        };
        let lt = it.lt_start.unwrap_or(&[]);
        let solved = self.solve_from(
            (it.r, it.r),
            &gaps,
            friction,
            opts,
            &mut lam,
            (warm, lt),
            monitor,
            predicted,
        );
        self.increments = increments;
        // The line of the next iteration: through this answer and the last
        // one of the same increment where this one converged; none after a
        // first iteration, whatever its outcome; the line as it was after a
        // later one that did not converge or returned an error.
        let solve::Solved { sol, load, .. } = match solved {
            Ok(solved) => solved,
            Err(e) => {
                self.iteration_before = if first { Vec::new() } else { before };
                return Err(e);
            }
        };
        let converged = sol.report.status == SolveStatus::Converged;
        self.iteration_before = match (first, converged) {
            (true, _) => Vec::new(),
            (false, true) => std::mem::take(&mut self.iteration_start),
            (false, false) => before,
        };
        if converged {
            self.iteration_start = lam;
        }
        // An increment's first iteration records its start and load change
        // for the next one; where it records nothing the line is forgotten,
        // so that the next increment does not pair lambda_n with an older
        // increment's end. Nothing is recorded where it did not converge, or
        // measured no load change (an interface compliance), or started from
        // zero: the line is drawn between increments that both started in
        // contact, as a history's (3d-52x52x4 host example: a line through
        // the zero start took the second increment's first solve from 54 to
        // 84 products).
        if let Some(start) = lam_n {
            match load {
                Some(q) if converged && start.iter().any(|&x| x != 0.0) => {
                    self.increments.advance(start, q)
                }
                _ => self.increments.forget(),
            }
        }
        Ok(sol)
    }
}
