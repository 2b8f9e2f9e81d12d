//! The host's own solver of K: a problem built on the solves a
//! host code already has (a CHOLMOD factor it holds, a distributed Krylov
//! solve) instead of a factor of the library's. Every matrix-free method needs
//! K only through solves: the products A x = B K^-1 B^T x, the right-hand side
//! B K^-1 f - g, the recovery u = K^-1 (f - B^T lambda), and the contacts' d x d
//! diagonal blocks of A, which the library obtains by blocked solves.
//!
//! A failed solve (an error code from the host, or a non-finite value in what
//! it returned) is latched on [`Host`]: later products return NaN without
//! calling the host, the solve stops at its next outer iteration, and the
//! call that ran it returns `ErrorKind::HostSolve` with the host's code.

#[cfg(doc)]
use crate::Options;
use crate::error::{Error, ErrorKind, Result};
use crate::options::HostBlocks;
use std::sync::Mutex;
use std::time::Instant;

/// K^-1 applied by the host code. The library calls it only from the thread
/// that calls into the problem, never concurrently.
pub trait KSolve: Send {
    /// The number of DOFs n (K is n x n, symmetric positive definite).
    fn n(&self) -> usize;

    /// Overwrites `x` (n x `ncols`, column-major, leading dimension n) with
    /// K^-1 x. `Err(code)` reports a failure with the host's own code, which
    /// the library passes on in its error message.
    fn solve(&mut self, x: &mut [f64], ncols: usize) -> std::result::Result<(), i32>;

    /// Optional: as [`KSolve::solve`], in single precision (a host that holds
    /// its factor in single precision too, or converts it: half the memory
    /// traffic of a solve). The library takes it for the products whose
    /// accuracy allows a relative error of about 1e-7 cond(K)^(1/2), as its
    /// own factor's single-precision copy serves them: the Krylov solves of
    /// Newton's reduced systems (none is asked for less than a relative
    /// residual of 1e-4 where this is offered); every gradient and residual
    /// it trusts is from
    /// [`KSolve::solve`], so a rougher answer (an iterative host's solve to
    /// a looser tolerance) costs iterations, never accuracy. `None` (the
    /// default): not offered; the library then calls `solve` for every
    /// product. `Some(Err(code))` reports a failure as `solve` does.
    fn solve_single(
        &mut self,
        x: &mut [f32],
        ncols: usize,
    ) -> Option<std::result::Result<(), i32>> {
        let _ = (x, ncols);
        None
    }

    /// Optional: K^-1 on right-hand sides that vanish outside the DOFs `rows`
    /// (0-based, ascending, distinct), wanted at those DOFs alone: `x`
    /// (rows.len() x `ncols`, column-major, leading dimension rows.len())
    /// holds the right-hand sides' entries at `rows`, and is overwritten with
    /// the solutions' entries there. A direct solver may answer it on the
    /// paths of `rows` in its elimination tree alone (PARDISO's partial
    /// solve, `iparm[30]`), a fraction of a whole solve where the contact DOFs
    /// lie in few subtrees; any host may answer by a whole solve (scatter
    /// into an n-vector, solve, gather), but then gains nothing: offer it
    /// only where it is cheaper than [`KSolve::solve`] (CHOLMOD's
    /// `cholmod_solve2` with `Bset` solves column by column on a simplicial
    /// copy of the factor, slower than its supernodal whole solve on the
    /// benchmark's 3D blocks). The library takes it for every product with
    /// A (`rows`: the contact DOFs, or those of a Newton step's reduced
    /// unknowns, one right-hand side per call); the contacts' diagonal
    /// blocks (many right-hand sides at once), the right-hand side and the
    /// recovery of u stay whole solves. `approximate`: a relative
    /// error of about 1e-7 cond(K)^(1/2) serves (single precision, a looser
    /// tolerance), as for [`KSolve::solve_single`]; where false the answer
    /// must be as accurate as [`KSolve::solve`]'s. `None` (the default): not
    /// offered. `Some(Err(code))` reports a failure as `solve` does.
    fn solve_rows(
        &mut self,
        rows: &[usize],
        x: &mut [f64],
        ncols: usize,
        approximate: bool,
    ) -> Option<std::result::Result<(), i32>> {
        let _ = (rows, x, ncols, approximate);
        None
    }

    /// Optional: entry k of `values` := the entry of K^-1 at (entry k of
    /// `rows`, entry k of `cols`) for every k (0-based
    /// DOFs, as MUMPS's selected inversion, ICNTL(30), or PETSc's
    /// MatMumpsGetInverse compute them). `None` (the default): not offered;
    /// the library then forms the contacts' blocks by solves. `Some(Err(code))`
    /// reports a failure as [`KSolve::solve`] does.
    fn inverse_entries(
        &mut self,
        rows: &[usize],
        cols: &[usize],
        values: &mut [f64],
    ) -> Option<std::result::Result<(), i32>> {
        let _ = (rows, cols, values);
        None
    }
}

/// What the host's solver did for one problem: calls, right-hand sides,
/// seconds inside it, and the failure latched since the last [`Host::clear`].
#[derive(Default)]
struct Tally {
    counts: Counts,
    failure: Option<Error>,
}

impl Tally {
    /// Ok where `failure` is None; else latches it as a `HostSolve` error
    /// and returns it.
    fn latch(&mut self, failure: Option<String>) -> Result<()> {
        match failure {
            Some(message) => {
                let e = Error::new(ErrorKind::HostSolve, message);
                self.failure = Some(e.clone());
                Err(e)
            }
            None => Ok(()),
        }
    }
}

/// The host's solver as a problem holds it: the callback, behind a lock (it
/// takes `&mut self`), and what it did (see [`Tally`]).
pub(crate) struct Host {
    n: usize,
    solver: Mutex<Box<dyn KSolve>>,
    tally: Mutex<Tally>,
    /// False once the host answered that it offers no single-precision solve.
    single: std::sync::atomic::AtomicBool,
    /// False once the host answered that it offers no solve on rows.
    rows: std::sync::atomic::AtomicBool,
    /// How the contacts' blocks are obtained ([`Options::host_blocks`]).
    blocks: HostBlocks,
}

/// Counters of the host's solves (see [`Host::counts`]).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub(crate) struct Counts {
    /// Calls of the host's solve.
    pub calls: usize,
    /// Right-hand sides solved, over all calls.
    pub columns: usize,
    /// Entries of K^-1 the host gave (`KSolve::inverse_entries`).
    pub entries: usize,
    /// Seconds inside the host's solve.
    pub seconds: f64,
}

impl Host {
    /// The host `solver`, its contacts' blocks obtained as `blocks` asks.
    pub(crate) fn new(solver: Box<dyn KSolve>, blocks: HostBlocks) -> Host {
        Host {
            n: solver.n(),
            blocks,
            solver: Mutex::new(solver),
            tally: Mutex::new(Tally::default()),
            single: std::sync::atomic::AtomicBool::new(true),
            rows: std::sync::atomic::AtomicBool::new(true),
        }
    }

    /// The number of DOFs n.
    pub(crate) fn n(&self) -> usize {
        self.n
    }

    /// How the contacts' blocks are obtained ([`Options::host_blocks`]).
    pub(crate) fn blocks(&self) -> HostBlocks {
        self.blocks
    }

    /// The tally, locked (a poisoned lock still holds valid counters).
    fn tally(&self) -> std::sync::MutexGuard<'_, Tally> {
        self.tally.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// x (n x ncols, column-major) := K^-1 x by the host. On a failure (the
    /// host's code, or a non-finite value in its output) the failure is
    /// latched and returned; while one is latched the host is not called
    /// again and x is left as given.
    pub(crate) fn solve(&self, x: &mut [f64], ncols: usize) -> Result<()> {
        self.call(x, ncols, None, "", |s, x| Some(s.solve(x, ncols)))
            .unwrap_or_else(|| unreachable!("the double-precision solve is always offered"))
    }

    /// False once the host answered that it offers no single-precision
    /// solve (true before it was asked).
    pub(crate) fn offers_single(&self) -> bool {
        self.single.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// As [`Host::solve`] in single precision where the host offers it
    /// ([`KSolve::solve_single`]); None where it does not (remembered: the
    /// host is not asked again).
    pub(crate) fn solve_single(&self, x: &mut [f32], ncols: usize) -> Option<Result<()>> {
        if !self.offers_single() {
            return None;
        }
        let outcome = self.call(x, ncols, None, " in single precision", |s, x| {
            s.solve_single(x, ncols)
        });
        if outcome.is_none() {
            self.single
                .store(false, std::sync::atomic::Ordering::Relaxed);
        }
        outcome
    }

    /// False once the host answered that it offers no solve on rows (true
    /// before it was asked).
    pub(crate) fn offers_rows(&self) -> bool {
        self.rows.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// As [`Host::solve`] for right-hand sides that vanish outside the DOFs
    /// `rows`, wanted there alone (x: rows.len() x ncols), where the host
    /// offers it ([`KSolve::solve_rows`]); None where it does not
    /// (remembered: the host is not asked again).
    pub(crate) fn solve_rows(
        &self,
        rows: &[usize],
        x: &mut [f64],
        ncols: usize,
        approximate: bool,
    ) -> Option<Result<()>> {
        if !self.offers_rows() {
            return None;
        }
        let outcome = self.call(x, ncols, Some(rows), " on rows", |s, x| {
            s.solve_rows(rows, x, ncols, approximate)
        });
        if outcome.is_none() {
            self.rows.store(false, std::sync::atomic::Ordering::Relaxed);
        }
        outcome
    }

    /// One call of the host's solve `f` on x (n x ncols, or rows.len() x
    /// ncols on `rows`) in either precision, counted, its failure latched;
    /// None where `f` is not offered (nothing counted).
    fn call<T: Copy + Into<f64>>(
        &self,
        x: &mut [T],
        ncols: usize,
        rows: Option<&[usize]>,
        precision: &str,
        f: impl FnOnce(&mut dyn KSolve, &mut [T]) -> Option<std::result::Result<(), i32>>,
    ) -> Option<Result<()>> {
        let len = rows.map_or(self.n, <[usize]>::len);
        debug_assert_eq!(x.len(), len * ncols);
        let mut tally = self.tally();
        if let Some(e) = &tally.failure {
            return Some(Err(e.clone()));
        }
        let start = Instant::now();
        let outcome = {
            let mut solver = self.solver.lock().unwrap_or_else(|e| e.into_inner());
            f(&mut **solver, x)?
        };
        let counts = &mut tally.counts;
        counts.seconds += start.elapsed().as_secs_f64();
        counts.calls += 1;
        counts.columns += ncols;
        let call = counts.calls;
        let failure = match outcome {
            Err(code) => Some(format!(
                "the host's solve of K{precision} failed with its code {code} (call {call} of \
                 this problem, {ncols} right-hand sides)"
            )),
            Ok(()) => x.iter().position(|&v| !v.into().is_finite()).map(|p| {
                format!(
                    "the host's solve of K{precision} returned {} at row {} of right-hand side \
                     {} (call {call} of this problem)",
                    x[p].into(),
                    rows.map_or(p % len.max(1), |r| r[p % len.max(1)]),
                    p / len.max(1),
                )
            }),
        };
        Some(tally.latch(failure))
    }

    /// The entries of K^-1 at (`rows`, `cols`) into `values` by the host where it offers
    /// them (None where it does not); failures as for [`Host::solve`].
    pub(crate) fn inverse_entries(
        &self,
        rows: &[usize],
        cols: &[usize],
        values: &mut [f64],
    ) -> Option<Result<()>> {
        let mut tally = self.tally();
        if let Some(e) = &tally.failure {
            return Some(Err(e.clone()));
        }
        let start = Instant::now();
        let outcome = {
            let mut solver = self.solver.lock().unwrap_or_else(|e| e.into_inner());
            solver.inverse_entries(rows, cols, values)?
        };
        tally.counts.seconds += start.elapsed().as_secs_f64();
        tally.counts.entries += rows.len();
        let failure = match outcome {
            Err(code) => Some(format!(
                "the host's entries of K^-1 failed with its code {code} ({} entries asked)",
                rows.len()
            )),
            Ok(()) => values.iter().position(|v| !v.is_finite()).map(|p| {
                format!(
                    "the host's entry ({}, {}) of K^-1 is {}",
                    rows[p], cols[p], values[p]
                )
            }),
        };
        Some(tally.latch(failure))
    }

    /// The failure latched since the last [`Host::clear`], if any.
    pub(crate) fn failure(&self) -> Option<Error> {
        self.tally().failure.clone()
    }

    /// Forgets a latched failure (each solve of the problem starts afresh).
    pub(crate) fn clear(&self) {
        self.tally().failure = None;
    }

    /// What the host's solver did so far.
    pub(crate) fn counts(&self) -> Counts {
        self.tally().counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// K = diag(1..=n), failing with code 7 on call `fail_at`, or returning
    /// NaN there when `nan`.
    struct Diagonal {
        n: usize,
        calls: usize,
        fail_at: usize,
        nan: bool,
    }

    impl KSolve for Diagonal {
        fn n(&self) -> usize {
            self.n
        }
        fn solve(&mut self, x: &mut [f64], ncols: usize) -> std::result::Result<(), i32> {
            self.calls += 1;
            if self.calls == self.fail_at && !self.nan {
                return Err(7);
            }
            for j in 0..ncols {
                for i in 0..self.n {
                    x[i + j * self.n] /= (i + 1) as f64;
                }
            }
            if self.calls == self.fail_at {
                x[1] = f64::NAN;
            }
            Ok(())
        }
    }

    fn host(fail_at: usize, nan: bool) -> Host {
        Host::new(
            Box::new(Diagonal {
                n: 3,
                calls: 0,
                fail_at,
                nan,
            }),
            HostBlocks::Solves,
        )
    }

    #[test]
    fn solves_are_counted_and_a_failure_is_latched_until_cleared() {
        let h = host(2, false);
        let mut x = vec![2.0, 4.0, 6.0, 1.0, 1.0, 1.0];
        h.solve(&mut x, 2).unwrap();
        assert_eq!(x, vec![2.0, 2.0, 2.0, 1.0, 0.5, 1.0 / 3.0]);
        let mut y = vec![1.0; 3];
        let e = h.solve(&mut y, 1).unwrap_err();
        assert_eq!(e.kind, ErrorKind::HostSolve);
        assert!(e.message.contains("code 7"), "{}", e.message);
        // Latched: the host is not called again, y stays as given.
        let mut z = vec![3.0; 3];
        assert!(h.solve(&mut z, 1).is_err());
        assert_eq!(z, vec![3.0; 3]);
        assert_eq!(h.counts().calls, 2);
        assert_eq!(h.counts().columns, 3);
        h.clear();
        assert!(h.failure().is_none());
        h.solve(&mut z, 1).unwrap();
        assert_eq!(z, vec![3.0, 1.5, 1.0]);
    }

    #[test]
    fn a_non_finite_output_is_a_failure_naming_its_place() {
        let h = host(1, true);
        let mut x = vec![1.0; 3];
        let e = h.solve(&mut x, 1).unwrap_err();
        assert_eq!(e.kind, ErrorKind::HostSolve);
        assert!(e.message.contains("NaN at row 1"), "{}", e.message);
        assert_eq!(h.failure(), Some(e));
    }
}
