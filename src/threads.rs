//! The thread pool a problem owns (`Options::threads`): its own rayon pool, not the
//! global one, so that problems solved in different threads of a host program do
//! not compete for one pool, and none at all for one thread.

use crate::error::{Error, ErrorKind, Result};
use faer::Par;
use std::num::NonZeroUsize;

/// Dense kernels with fewer entries than this run sequentially even with a pool:
/// below it the hand-over to the pool costs more than the threads save.
pub(crate) const PARALLEL_MIN_ENTRIES: usize = 1 << 18;

/// A problem's threads: a pool of `count` threads, or none (the calling thread).
pub struct Threads {
    pool: Option<rayon::ThreadPool>,
}

impl Threads {
    /// `threads` = 0: all cores (`std::thread::available_parallelism`); 1: no
    /// pool, everything on the calling thread; k: a pool of k threads.
    ///
    /// Errors: `OutOfMemory` when the threads cannot be started.
    pub fn new(threads: usize) -> Result<Threads> {
        let count = match threads {
            0 => std::thread::available_parallelism().map_or(1, NonZeroUsize::get),
            k => k,
        };
        let pool = if count <= 1 {
            None
        } else {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(count)
                .thread_name(|i| format!("dualsplit-{i}"))
                .build()
                .map_err(|e| {
                    Error::new(
                        ErrorKind::OutOfMemory,
                        format!("could not start {count} threads: {e}"),
                    )
                })?;
            Some(pool)
        };
        Ok(Threads { pool })
    }

    /// The calling thread only.
    #[cfg(any(test, feature = "internals"))]
    pub const SEQUENTIAL: Threads = Threads { pool: None };

    /// The calling thread only.
    #[cfg(any(test, feature = "internals"))]
    pub fn sequential() -> Threads {
        Threads::SEQUENTIAL
    }

    /// Threads the work may use (1 without a pool).
    pub fn count(&self) -> usize {
        self.pool
            .as_ref()
            .map_or(1, rayon::ThreadPool::current_num_threads)
    }

    /// Runs `f` with this pool's parallelism inside the pool when `parallel` and
    /// there is a pool; otherwise on the calling thread with `Par::Seq`.
    pub fn run<R: Send>(&self, parallel: bool, f: impl FnOnce(Par) -> R + Send) -> R {
        match &self.pool {
            Some(pool) if parallel => {
                let par = Par::rayon(pool.current_num_threads());
                pool.install(|| f(par))
            }
            _ => f(Par::Seq),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_thread_has_no_pool_and_runs_on_the_calling_thread() {
        let t = Threads::new(1).unwrap();
        assert!(t.pool.is_none());
        assert_eq!(t.count(), 1);
        let caller = std::thread::current().id();
        let (id, par) = t.run(true, |par| (std::thread::current().id(), par));
        assert_eq!(id, caller);
        assert_eq!(par, Par::Seq);
    }

    #[test]
    fn k_threads_run_in_their_own_pool() {
        let t = Threads::new(2).unwrap();
        assert_eq!(t.count(), 2);
        let (name, par) = t.run(true, |par| {
            (std::thread::current().name().map(str::to_string), par)
        });
        assert!(name.unwrap().starts_with("dualsplit-"));
        assert_eq!(par, Par::rayon(2));
        // Small work stays on the calling thread.
        let caller = std::thread::current().id();
        assert_eq!(t.run(false, |_| std::thread::current().id()), caller);
    }

    #[test]
    fn zero_means_every_core() {
        let cores = std::thread::available_parallelism().map_or(1, NonZeroUsize::get);
        assert_eq!(Threads::new(0).unwrap().count(), cores);
    }
}
