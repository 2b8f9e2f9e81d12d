//! Memory: the library's own large allocations counted as they are made (a
//! [`Ledger`] per problem, with its peak) and the limit a route must fit in
//! before any work starts ([`limit`]); the predictions checked against it are
//! `crate::sizes`'.
//!
//! "Large" means every allocation whose size grows with the problem: the copies of
//! K, N and T, the Cholesky factor and its workspace, the condensed dual A and the
//! dense blocks it is formed from, the dense systems of the methods, and the
//! vectors of length n of a solve. Index arrays of the analysis and O(c) vectors
//! are not counted (they are small next to those).

use crate::error::{Error, ErrorKind, Result};
use faer::dyn_stack::MemBuffer;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Bytes of one f64.
pub(crate) const F64: usize = std::mem::size_of::<f64>();

/// Live and peak bytes of a problem's large allocations.
#[derive(Debug, Default)]
pub(crate) struct Ledger {
    live: AtomicUsize,
    peak: AtomicUsize,
}

/// Bytes claimed on a [`Ledger`] while this value lives (held next to the
/// allocation it counts, or for the scope of a temporary).
#[derive(Debug)]
pub(crate) struct Claim {
    ledger: Arc<Ledger>,
    bytes: usize,
}

impl Ledger {
    /// A new, empty ledger.
    pub fn new() -> Arc<Ledger> {
        Arc::new(Ledger::default())
    }

    /// Counts `bytes` until the returned claim is dropped.
    pub fn claim(self: &Arc<Self>, bytes: usize) -> Claim {
        let live = self.live.fetch_add(bytes, Ordering::Relaxed) + bytes;
        self.peak.fetch_max(live, Ordering::Relaxed);
        Claim {
            ledger: self.clone(),
            bytes,
        }
    }

    /// Counts `count` f64 values (see [`Ledger::claim`]).
    pub fn claim_f64(self: &Arc<Self>, count: usize) -> Claim {
        self.claim(count.saturating_mul(F64))
    }

    /// Bytes held now.
    pub fn live(&self) -> usize {
        self.live.load(Ordering::Relaxed)
    }

    /// The most bytes held at once since the last [`Ledger::reset_peak`].
    pub fn peak(&self) -> usize {
        self.peak.load(Ordering::Relaxed)
    }

    /// Starts a new peak from the bytes held now.
    pub fn reset_peak(&self) {
        self.peak.store(self.live(), Ordering::Relaxed);
    }
}

impl Claim {
    /// Changes the bytes of this claim (an allocation that grew or shrank).
    pub fn resize(&mut self, bytes: usize) {
        if bytes >= self.bytes {
            let more = bytes - self.bytes;
            let live = self.ledger.live.fetch_add(more, Ordering::Relaxed) + more;
            self.ledger.peak.fetch_max(live, Ordering::Relaxed);
        } else {
            self.ledger
                .live
                .fetch_sub(self.bytes - bytes, Ordering::Relaxed);
        }
        self.bytes = bytes;
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        self.ledger.live.fetch_sub(self.bytes, Ordering::Relaxed);
    }
}

/// The memory limit the routes must fit in: `max_memory` when it is not 0, else
/// what this process can have: the smaller of its address-space limit
/// (RLIMIT_AS) and the machine's physical memory; None when neither is known.
pub(crate) fn limit(max_memory: usize) -> Option<usize> {
    if max_memory > 0 {
        return Some(max_memory);
    }
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes the struct it is given and nothing else.
    let rc = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut lim) };
    let address_space = (rc == 0 && lim.rlim_cur != libc::RLIM_INFINITY)
        .then(|| usize::try_from(lim.rlim_cur).unwrap_or(usize::MAX));
    // SAFETY: sysconf reads a system constant; it has no memory effects.
    let (pages, page) = unsafe {
        (
            libc::sysconf(libc::_SC_PHYS_PAGES),
            libc::sysconf(libc::_SC_PAGESIZE),
        )
    };
    let physical = (pages > 0 && page > 0).then(|| (pages as usize).saturating_mul(page as usize));
    match (address_space, physical) {
        (Some(a), Some(p)) => Some(a.min(p)),
        (a, p) => a.or(p),
    }
}

/// `OutOfMemory` for an allocation of `bytes` that the allocator refused.
fn refused(what: &str, bytes: usize) -> Error {
    Error::new(
        ErrorKind::OutOfMemory,
        format!(
            "{what}: the allocation of {} ({bytes} bytes) failed",
            human(bytes)
        ),
    )
}

/// A zeroed vector of `len` values, or `OutOfMemory` naming `what`: the
/// allocations that grow with the problem return an error instead of aborting
/// the host when the allocator refuses them (where no memory limit is known the
/// predictions are not checked before the work starts).
pub(crate) fn try_zeros<T: Copy + Default>(len: usize, what: &str) -> Result<Vec<T>> {
    let bytes = len.saturating_mul(std::mem::size_of::<T>());
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| refused(what, bytes))?;
    v.resize(len, T::default());
    Ok(v)
}

/// A zeroed rows x cols matrix, or `OutOfMemory` naming `what` (see
/// [`try_zeros`]).
pub(crate) fn try_mat<T: Copy + Default>(
    rows: usize,
    cols: usize,
    what: &str,
) -> Result<faer::Mat<T>> {
    let bytes = rows
        .saturating_mul(cols)
        .saturating_mul(std::mem::size_of::<T>());
    let mut m = faer::Mat::new();
    m.try_reserve(rows, cols)
        .map_err(|_| refused(what, bytes))?;
    m.resize_with(rows, cols, |_, _| T::default());
    Ok(m)
}

/// Scratch memory for faer's kernels, or `OutOfMemory` naming `what` (see
/// [`try_zeros`]).
pub(crate) fn try_scratch(req: faer::dyn_stack::StackReq, what: &str) -> Result<MemBuffer> {
    MemBuffer::try_new(req).map_err(|_| refused(what, req.size_bytes()))
}

/// `bytes` in the units a user reads (MB below 10 GB, else GB), for messages.
pub(crate) fn human(bytes: usize) -> String {
    let b = bytes as f64;
    if b < 10e9 {
        format!("{:.1} MB", b / 1e6)
    } else {
        format!("{:.1} GB", b / 1e9)
    }
}

/// `OutOfMemory` when `need` exceeds `limit` (None: no check): "`what` needs
/// about N bytes, more than the limit L (`source`); `hint`".
pub(crate) fn check(
    need: usize,
    limit: Option<usize>,
    max_memory: usize,
    what: &str,
    hint: &str,
) -> Result<()> {
    let Some(limit) = limit else {
        return Ok(());
    };
    if need <= limit {
        return Ok(());
    }
    let source = if max_memory > 0 {
        "max_memory"
    } else {
        "this process's address-space limit or the machine's memory"
    };
    Err(Error::new(
        ErrorKind::OutOfMemory,
        format!(
            "{what} needs about {} ({need} bytes, predicted after the analysis), more than \
             the {} allowed by {source}; {hint}",
            human(need),
            human(limit)
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refused_allocations_are_errors_not_aborts() {
        let e = try_zeros::<f64>(usize::MAX / 8, "a test vector").unwrap_err();
        assert_eq!(e.kind, ErrorKind::OutOfMemory);
        assert!(e.message.contains("a test vector"), "{}", e.message);
        let e = try_mat::<f64>(1 << 31, 1 << 31, "a test matrix").unwrap_err();
        assert_eq!(e.kind, ErrorKind::OutOfMemory);
        let req = faer::dyn_stack::StackReq::new::<f64>(usize::MAX / 16);
        assert!(try_scratch(req, "test scratch").is_err());
        let m = try_mat::<f64>(3, 2, "small").unwrap();
        assert_eq!((m.nrows(), m.ncols()), (3, 2));
        assert!(m.col_iter().all(|c| c.iter().all(|&v| v == 0.0)));
        assert_eq!(try_zeros::<f32>(4, "small").unwrap(), vec![0.0f32; 4]);
    }

    #[test]
    fn claims_count_live_and_peak_bytes() {
        let l = Ledger::new();
        let a = l.claim(100);
        {
            let mut b = l.claim_f64(10);
            assert_eq!(l.live(), 180);
            b.resize(100);
            assert_eq!(l.live(), 200);
        }
        assert_eq!((l.live(), l.peak()), (100, 200));
        l.reset_peak();
        assert_eq!(l.peak(), 100);
        drop(a);
        assert_eq!(l.live(), 0);
    }

    #[test]
    fn the_limit_is_max_memory_when_set() {
        assert_eq!(limit(12345), Some(12345));
        // The machine's own limit is positive where it is known.
        assert!(limit(0).is_none_or(|b| b > 0));
        let e = check(2000, Some(1000), 1000, "the dense dual", "try less").unwrap_err();
        assert_eq!(e.kind, ErrorKind::OutOfMemory);
        assert!(e.message.contains("2000 bytes") && e.message.contains("max_memory"));
        assert!(check(1000, Some(1000), 0, "x", "y").is_ok());
        assert!(check(usize::MAX, None, 0, "x", "y").is_ok());
    }
}
