//! The thread pool a problem owns (`Options::threads`): its own rayon pool, not the
//! global one, so that problems solved in different threads of a host program do
//! not compete for one pool, and none at all for one thread. The pool is started
//! by the first piece of work large enough to use it, so that a program holding
//! many small problems does not hold idle threads for each.

use faer::Par;
use std::num::NonZeroUsize;
use std::sync::OnceLock;

/// Dense kernels with fewer entries than this run sequentially even with a pool:
/// below it the hand-over to the pool costs more than the threads save.
pub(crate) const PARALLEL_MIN_ENTRIES: usize = 1 << 18;

/// A problem's threads: up to `count`, in a pool of its own started on first use,
/// or the calling thread alone (`count` = 1).
pub struct Threads {
    count: usize,
    /// The pool once started; None inside when it could not be started (a system
    /// limit on threads): the work then runs on the calling thread.
    pool: OnceLock<Option<rayon::ThreadPool>>,
}

impl Threads {
    /// `threads` = 0: all cores (`std::thread::available_parallelism`); 1:
    /// everything on the calling thread, no thread is ever started; k: a pool of
    /// k threads, started by the first parallel run.
    pub fn new(threads: usize) -> Threads {
        let count = match threads {
            0 => std::thread::available_parallelism().map_or(1, NonZeroUsize::get),
            k => k,
        };
        Threads {
            count,
            pool: OnceLock::new(),
        }
    }

    /// The calling thread only.
    #[cfg(any(test, feature = "internals"))]
    pub const fn sequential() -> Threads {
        Threads {
            count: 1,
            pool: OnceLock::new(),
        }
    }

    /// Threads the work may use (1: the calling thread only).
    pub fn count(&self) -> usize {
        self.count
    }

    /// Whether the pool's threads were started.
    #[cfg(any(test, feature = "internals"))]
    pub fn started(&self) -> bool {
        self.pool.get().is_some_and(Option::is_some)
    }

    /// Runs `f` with the pool's parallelism inside the pool when `parallel` and
    /// the problem may use more than one thread (starting the pool the first
    /// time); otherwise on the calling thread with `Par::Seq`.
    pub fn run<R: Send>(&self, parallel: bool, f: impl FnOnce(Par) -> R + Send) -> R {
        if parallel && self.count > 1 {
            let pool = self.pool.get_or_init(|| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(self.count)
                    .thread_name(|i| format!("dualsplit-{i}"))
                    .build()
                    .ok()
            });
            if let Some(pool) = pool {
                let par = Par::rayon(self.count);
                return pool.install(|| f(par));
            }
        }
        f(Par::Seq)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_thread_has_no_pool_and_runs_on_the_calling_thread() {
        let t = Threads::new(1);
        assert_eq!(t.count(), 1);
        let caller = std::thread::current().id();
        let (id, par) = t.run(true, |par| (std::thread::current().id(), par));
        assert_eq!(id, caller);
        assert_eq!(par, Par::Seq);
        assert!(!t.started() && t.pool.get().is_none());
    }

    #[test]
    fn k_threads_run_in_their_own_pool() {
        let t = Threads::new(2);
        assert_eq!(t.count(), 2);
        // Small work stays on the calling thread and starts no thread.
        let caller = std::thread::current().id();
        assert_eq!(t.run(false, |_| std::thread::current().id()), caller);
        assert!(!t.started());
        let (name, par) = t.run(true, |par| {
            (std::thread::current().name().map(str::to_string), par)
        });
        assert!(name.unwrap().starts_with("dualsplit-"));
        assert_eq!(par, Par::rayon(2));
        assert!(t.started());
    }

    #[test]
    fn zero_means_every_core() {
        let cores = std::thread::available_parallelism().map_or(1, NonZeroUsize::get);
        assert_eq!(Threads::new(0).count(), cores);
    }
}
