//! What the analysis of a contact problem tells before any numeric work (as
//! MUMPS's JOB = 1 or CHOLMOD's analyze): its sizes, the factor's size and cost,
//! the route the options lead to, and that route's predicted memory.

use crate::options::{DualForm, Method, Ordering};

/// The analysis of a contact problem: everything known after the ordering and
/// the symbolic factorisation of K, before the numeric factorisation
/// ([`crate::ContactProblem::analyse`], or [`crate::ContactProblem::info`] for a
/// problem already created). Later versions may add fields
/// (`#[non_exhaustive]`: read it, do not build it).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Info {
    /// Contact dimension (2 or 3).
    pub d: usize,
    /// DOFs (rows of K).
    pub n: usize,
    /// Contacts (rows of N).
    pub m: usize,
    /// Dual unknowns c = d m.
    pub c: usize,
    /// Stored entries of K, both triangles.
    pub nnz_k: usize,
    /// The fill-reducing ordering chosen (`Amd` or `Metis`; `Dense` for a K
    /// given dense, factored by dense Cholesky).
    pub ordering: Ordering,
    /// Entries of the Cholesky factor L (dense supernodal blocks included).
    pub factor_nnz: usize,
    /// Flops of one numeric factorisation (sum over the columns of L of the
    /// squared column counts).
    pub factor_flops: f64,
    /// The form of the condensed dual the problem is created with: `Dense` (A
    /// formed) or `MatrixFree` (A applied by products).
    pub setup_form: DualForm,
    /// The method of the options, and the form its solves use (`Dense` for every
    /// method that reads entries of A: a problem created matrix-free forms A at
    /// its first such solve).
    pub method: Method,
    pub solve_form: DualForm,
    /// Predicted peak bytes of the library's large allocations while the problem
    /// is created (factorisation, then condensation), held between calls, during
    /// one solve with that method (its largest case), and during a refactorisation
    /// with new values of K (the old and the new factor at once). Held between
    /// calls and during a solve include, after a refactor, the replaced
    /// factor's values kept as the next refactor's storage (see
    /// [`crate::ContactProblem::refactor`]). Held between
    /// calls, during a solve and during a refactorisation include the slots
    /// that a refactor from a coordinate-format K keeps (4 bytes per triplet,
    /// 8 where one triangle is given; in full storage also 4 bytes per entry
    /// of K off the diagonal, the mirror places of its symmetry check).
    pub setup_bytes: usize,
    pub resident_bytes: usize,
    pub solve_bytes: usize,
    pub refactor_bytes: usize,
    /// The memory limit the predictions were checked against, bytes
    /// (`Options::max_memory`, else this process's address-space limit or the
    /// machine's physical memory; 0 when none is known).
    pub memory_limit: usize,
    /// Seconds of the ordering and the symbolic factorisation.
    pub analyse_seconds: f64,
    /// Contacts with a compliant interface law (finite c_N or k_T, see
    /// [`crate::ContactProblem::set_compliance`]); 0 for an analysis without a
    /// problem, and where every contact is rigid (Signorini, rigid stick).
    pub compliant_contacts: usize,
    /// Of those, the contacts whose normal law is a power law with m_N != 1
    /// (solved by Newton on the law: several dual solves per solve).
    pub power_law_contacts: usize,
    /// Refactors since the matrix-free dual's contact blocks were computed:
    /// 0 where they are the current K's (always on a dense dual and for an
    /// analysis), k where [`crate::ContactProblem::refactor`] kept those of
    /// the K k refactors back, their drift small by an estimate
    /// (docs/design.md section 9).
    pub blocks_age: usize,
    /// The factor err is multiplied by so that it bounds err on the current
    /// K's contact blocks (>= 1, at most 3; 1 where `blocks_age` is 0): rho
    /// comes from the kept blocks, and the estimate of their drift bounds how
    /// far it lies from the current K's (an estimate by Lanczos steps, not a
    /// certified bound).
    pub err_factor: f64,
}
