//! Work on the elimination tree of K's supernodal Cholesky factor: what the
//! matrix-free dual needs from the factor besides its plain solves.
//!
//! - `supernode_tree`: the tree itself (per column its supernode, per supernode
//!   its columns and parent);
//! - `tree_solve`: solves restricted to the paths of a set of DOFs, split
//!   between threads (the products of the matrix-free dual);
//! - `selected_inverse`: entries of K^-1 on the factor's pattern (Takahashi's
//!   recurrence);
//! - `contact_blocks`: the contacts' d x d diagonal blocks of A = B K^-1 B^T,
//!   by selected inversion or by sparse forward solves;
//! - `row_solves`: K^-1 on sparse right-hand sides wanted on their own rows,
//!   as a host's direct solver gives it (the benchmark's and tests' hosts).
//!
//! This layer sits on `factor` and below `dual`.

pub(crate) mod contact_blocks;
#[cfg(any(test, feature = "internals"))]
pub(crate) mod row_solves;
pub(crate) mod selected_inverse;
pub(crate) mod supernode_tree;
pub(crate) mod tree_solve;
