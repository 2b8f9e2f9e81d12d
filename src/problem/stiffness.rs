//! What a problem solves with K by: K and the library's factor of it, or the
//! host's solves (`host.rs`) with K where the host gave it.

use crate::factor::Factor;
use crate::host::Host;
use crate::memory::Ledger;
use crate::sparse::Csc;
use crate::threads::Threads;
use std::sync::Arc;

pub(super) enum Stiffness {
    /// K (both triangles) and its factor, shared with a matrix-free dual.
    Own { k: Csc, factor: Arc<Factor> },
    /// The host's solves; K where the host gave it (for the lumped
    /// preconditioner, K u_k and the equilibrium residual); the problem's
    /// threads and ledger (a factor holds them on the own route).
    Host {
        host: Arc<Host>,
        k: Option<Csc>,
        threads: Arc<Threads>,
        ledger: Arc<Ledger>,
    },
}

impl Stiffness {
    /// The number of DOFs n.
    pub(super) fn n(&self) -> usize {
        match self {
            Stiffness::Own { k, .. } => k.nrows,
            Stiffness::Host { host, .. } => host.n(),
        }
    }

    /// K, where the problem holds it.
    pub(super) fn k(&self) -> Option<&Csc> {
        match self {
            Stiffness::Own { k, .. } => Some(k),
            Stiffness::Host { k, .. } => k.as_ref(),
        }
    }

    /// The library's factor of K (None on the host's solves).
    pub(super) fn factor(&self) -> Option<&Arc<Factor>> {
        match self {
            Stiffness::Own { factor, .. } => Some(factor),
            Stiffness::Host { .. } => None,
        }
    }

    /// The host's solves (None on the library's factor).
    pub(super) fn host(&self) -> Option<&Arc<Host>> {
        match self {
            Stiffness::Own { .. } => None,
            Stiffness::Host { host, .. } => Some(host),
        }
    }

    /// The problem's count of its large allocations.
    pub(super) fn ledger(&self) -> &Arc<Ledger> {
        match self {
            Stiffness::Own { factor, .. } => factor.ledger(),
            Stiffness::Host { ledger, .. } => ledger,
        }
    }

    /// The problem's threads.
    pub(super) fn threads(&self) -> &Arc<Threads> {
        match self {
            Stiffness::Own { factor, .. } => factor.threads(),
            Stiffness::Host { threads, .. } => threads,
        }
    }
}
