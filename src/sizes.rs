//! The memory a route will need, predicted from the sizes known after the
//! symbolic analysis ([`Sizes`]): what the counted allocations of
//! `crate::memory`'s ledger will reach while the problem is created, held,
//! refactored and solved, per way of forming the dual ([`Condensation`]).

use crate::dual::Condensation;
use crate::memory::F64;

/// The sizes a prediction is made from, all known after the symbolic analysis.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub(crate) struct Sizes {
    /// DOFs (rows of K).
    pub n: usize,
    /// Dual unknowns (c = d m).
    pub c: usize,
    /// The dimension d (2 or 3; 0 where unknown).
    pub d: usize,
    /// DOFs that N and T touch (the trailing DOFs of the factor).
    pub nc: usize,
    /// Bytes of K, N and T as the problem stores them.
    pub inputs: usize,
    /// Bytes of L's values.
    pub factor: usize,
    /// Bytes of the numeric factorisation's workspace.
    pub factor_scratch: usize,
    /// Bytes of one solve's workspace with [`crate::dual::BLOCK`] right-hand sides.
    pub solve_scratch: usize,
    /// Bytes the threads work in together while the matrix-free dual's contact
    /// blocks are formed (`contact_blocks::work_bytes`).
    pub blocks_work: usize,
    /// Bytes of G = B K B^T, the lumped preconditioner a matrix-free dual holds.
    pub lumped: usize,
    /// Bytes of a matrix-free dual's own solves by the elimination tree and
    /// their scratch, with a bound on those of Newton's narrowed products
    /// (`dual::own_solves_bytes`); on the host's solves, what its products on
    /// rows hold (`dual::host_rows_bytes`).
    pub own_solves: usize,
    /// Bytes of the layered Dirichlet preconditioner a matrix-free dual holds
    /// where it pays, with the restricted one of Newton's reduced systems
    /// analysed beside it (`dirichlet::Plan::bytes`; 0 where it does not).
    pub dirichlet: usize,
    /// Bytes of the slots a refactor from a coordinate-format K keeps, with
    /// the mirror places of the symmetry check of a refactor from a K in
    /// full storage, COO or CSC (`sparse::TripletSlots`; 0 until one made
    /// them).
    pub slots: usize,
    /// Bytes of the mirror places the first refactor from a K in full
    /// storage will make, while the slots do not hold them yet: 4 per
    /// entry of K off the diagonal (`sparse::mirror_bytes`), 0 once made.
    pub mirrors_to_make: usize,
    /// Bytes of the replaced factor's values a refactor keeps as the next
    /// one's storage (0 before the first refactor; else `factor`).
    pub spare: usize,
}

/// Predicted bytes, what the counted allocations will reach.
impl Sizes {
    /// K, N, T, the factor and what a refactor keeps (see `slots`, `spare`).
    fn base(&self) -> usize {
        self.inputs + self.factor + self.slots + self.spare
    }

    /// Bytes above [`Sizes::base`] while the dual is formed in the way `how`, and
    /// once it is formed.
    fn forming(&self, how: Condensation) -> (usize, usize) {
        let a = self.c * self.c * F64;
        let lcc = self.nc * self.nc * F64;
        // Held beside a dense A once a solve made them: the single-precision
        // factor of the last Newton step's reduced system (k <= c unknowns;
        // `Dual::with_kept_factor`) and, in 3D, A^-1 in single precision
        // (c x c; `Dual::inverse`, made by a warm Newton solve).
        let copies = if self.d == 3 { 2 } else { 1 };
        let kept = copies * self.c * self.c * std::mem::size_of::<f32>();
        match how {
            // A, then L_CC and X = S_CC^-1 (L_CC dropped once X is formed).
            Condensation::TrailingBlock => (a + 2 * lcc, a + kept),
            // A and one block of right-hand sides with the solve's workspace.
            Condensation::Solves => (
                a + crate::dual::BLOCK * self.n * F64 + self.solve_scratch,
                a + kept,
            ),
            // The contacts' diagonal blocks (d c doubles at most) and, while
            // they are formed, what their selected inversion or forward solves
            // work in on all threads (`blocks_work`), beside all that is held
            // after: one product's n-vector and solve workspace in double
            // and single precision, L's values in single precision (the rough
            // products; made first, the selected inversion may run on them),
            // the lumped
            // preconditioner G = B K B^T and the layered Dirichlet one, and the
            // tree solves with their scratch (where they are taken).
            Condensation::MatrixFree => {
                let held = 3 * self.c * F64
                    + self.n * (F64 + 4)
                    + self.own_solves
                    + self.solve_scratch
                    + self.factor / 2
                    + self.lumped
                    + self.dirichlet;
                (held + self.blocks_work, held)
            }
        }
    }

    /// The peak of creating a problem whose dual is formed in the way `how`: the
    /// numeric factorisation, then the condensation (a new problem holds no
    /// refactor's spare).
    pub fn setup(&self, how: Condensation) -> usize {
        let base = self.base() - self.spare;
        (base + self.factor_scratch).max(base + self.forming(how).0)
    }

    /// What the problem holds between calls: with the dual (a dense one with
    /// the kept factor of its last Newton step and A^-1), the last two
    /// loads solved for and their solutions (`load_span`, 4 n doubles) and
    /// the forward half of K u_k (`History::lu`, n).
    pub fn resident(&self, how: Condensation) -> usize {
        self.base() + self.forming(how).1 + 5 * self.n * F64
    }

    /// The peak of refactoring a problem whose dual is held as `how`: the new K
    /// (`k_bytes`) beside the old one, the new factor beside the old (kept until
    /// the dual is rebuilt, so that a failure restores it; formed in the
    /// spare's storage where one is held), and the larger of the
    /// factorisation's workspace and the dual's rebuild.
    /// A matrix-free dual may keep its contact blocks: the values of the K
    /// they were computed on are then held (at most `k_bytes`), and the
    /// estimate of their drift works in a few n-vectors
    /// (`drift::work_bytes`) and, on several `threads`, a split of the
    /// solves by the tree (at most what the dual's own solves hold) before
    /// the dual is rebuilt.
    pub fn refactor(&self, how: Condensation, k_bytes: usize, threads: usize) -> usize {
        let split = if threads > 1 { self.own_solves } else { 0 };
        let keep = if how == Condensation::MatrixFree {
            k_bytes + crate::drift::work_bytes(self.n) + split
        } else {
            0
        };
        self.resident(how)
            + k_bytes
            + self.mirrors_to_make
            + keep
            + self.factor.saturating_sub(self.spare)
            + self.factor_scratch.max(self.forming(how).0)
    }

    /// The peak of replacing N and T (new ones of `nt_bytes`, a dual described by
    /// `next` and formed as `how`) on a problem whose dual is held as `now`: the
    /// new matrices and the new dual are formed beside the old ones.
    pub fn replace_contacts(
        &self,
        now: Condensation,
        nt_bytes: usize,
        next: &Sizes,
        how: Condensation,
    ) -> usize {
        self.resident(now) + nt_bytes + next.forming(how).0
    }

    /// The peak of one solve (or history step) on a problem whose dual is held as
    /// `now` and is needed as `next` (rebuilt first when they differ), with a
    /// method whose dense work space is `workspace` bytes: the vectors of length
    /// n (f and its forward half, K^-1 f, u, B^T lambda, K u, the residual, and
    /// a step's effective f and K u_k, or a host iteration's block of three
    /// right-hand sides, `Dual::solve_with_products`) and the method's work
    /// space on top of the resident bytes; on a matrix-free dual also the
    /// displacement carried with the iterate (`dual::Primal`, 3 n + c
    /// values) and the fourth column of the block it starts from.
    pub fn solve(&self, now: Condensation, next: Condensation, workspace: usize) -> usize {
        let carried = match next {
            Condensation::MatrixFree => 4 * self.n + self.c,
            _ => 0,
        };
        let working = self.resident(next) + (9 * self.n + carried) * F64 + workspace;
        if now == next {
            working
        } else {
            working.max(self.resident(now) + self.forming(next).0)
        }
    }
}
