//! The checker's bookkeeping: work no contact event waits for (the bodies' statistics, the
//! pairs' overlap, decoding the frames the overlap is measured on), done on a pool of its
//! own at a lower priority, so that the windows, the meshers and the transport take the
//! cores first and the bookkeeping the time they leave.
//!
//! A job that has not started when its outcome is needed is not waited for: whoever needs
//! it runs it, at its own priority ([`PoolJob::wait`]). Only a job already running is
//! waited for.

use std::sync::{Arc, Condvar, Mutex, OnceLock};

use super::episodes::low_priority_pool;

/// How much the bookkeeping pool's threads lower their priority: nice values added (Linux
/// gives a thread of nice +10 about a tenth of a core's time against a thread of the
/// process's own nice when both want the core). Contact events waited behind the
/// statistics of the pieces just accepted otherwise: docs/performance.md, "Bookkeeping
/// behind the contacts".
pub const BOOKKEEPING_NICE: i32 = 10;

/// Where the bookkeeping runs: a pool (rayon's own when `None`).
pub type BookkeepingPool = Option<Arc<rayon::ThreadPool>>;

/// The process's bookkeeping pool, made at first use with as many threads as rayon's, its
/// threads at [`BOOKKEEPING_NICE`]; `None` (rayon's pool) if it could not be made.
pub fn shared_bookkeeping_pool() -> BookkeepingPool {
    static POOL: OnceLock<BookkeepingPool> = OnceLock::new();
    POOL.get_or_init(
        || match low_priority_pool("bookkeeping", BOOKKEEPING_NICE) {
            Ok(p) => Some(Arc::new(p)),
            Err(e) => {
                tracing::warn!("checker: no bookkeeping pool of its own ({e}); using rayon's");
                None
            }
        },
    )
    .clone()
}

/// Runs `work` on `pool` (rayon's when `None`), catching a panic: a panic in a job rayon
/// spawned would abort the process.
fn spawn_on(pool: &BookkeepingPool, work: impl FnOnce() + Send + 'static) {
    let work = move || {
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
    };
    match pool {
        Some(p) => p.spawn(work),
        None => rayon::spawn(work),
    }
}

type Work<T> = Box<dyn FnOnce() -> T + Send>;

struct JobShared<T> {
    /// The work, until someone takes it to run it (the pool, or whoever waits first).
    work: Mutex<Option<Work<T>>>,
    /// Its outcome (or panic), once run by the pool.
    done: Mutex<Option<std::thread::Result<T>>>,
    ran: Condvar,
    /// Set once the outcome is in `done`: taking it back then does not wait.
    finished: std::sync::atomic::AtomicBool,
}

/// Work on the bookkeeping pool whose outcome the checker takes back later.
pub(super) struct PoolJob<T> {
    shared: Arc<JobShared<T>>,
}

impl<T> std::fmt::Debug for PoolJob<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PoolJob")
            .field("finished", &self.finished())
            .finish()
    }
}

fn lock<X>(m: &Mutex<X>) -> std::sync::MutexGuard<'_, X> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl<T: Send + 'static> PoolJob<T> {
    /// `work` spawned on `pool`.
    pub(super) fn spawn(pool: &BookkeepingPool, work: impl FnOnce() -> T + Send + 'static) -> Self {
        let shared = Arc::new(JobShared {
            work: Mutex::new(Some(Box::new(work) as Work<T>)),
            done: Mutex::new(None),
            ran: Condvar::new(),
            finished: std::sync::atomic::AtomicBool::new(false),
        });
        let on_pool = Arc::clone(&shared);
        let run = move || {
            let Some(work) = lock(&on_pool.work).take() else {
                return;
            };
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
            *lock(&on_pool.done) = Some(outcome);
            on_pool
                .finished
                .store(true, std::sync::atomic::Ordering::Release);
            on_pool.ran.notify_all();
        };
        spawn_on(pool, run);
        Self { shared }
    }

    /// The outcome: run here if the pool has not started it, else waited for; `None` if
    /// the work was lost (a pool that dropped it).
    pub(super) fn wait(self) -> Option<std::thread::Result<T>> {
        let work = lock(&self.shared.work).take();
        if let Some(work) = work {
            return Some(std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)));
        }
        let mut done = lock(&self.shared.done);
        loop {
            if let Some(outcome) = done.take() {
                return Some(outcome);
            }
            // Neither taken back nor running any more: lost (its closure was dropped).
            if Arc::strong_count(&self.shared) == 1 {
                return None;
            }
            done = self
                .shared
                .ran
                .wait_timeout(done, std::time::Duration::from_millis(50))
                .map(|(g, _)| g)
                .unwrap_or_else(|e| e.into_inner().0);
        }
    }
}

impl<T> PoolJob<T> {
    /// Whether the outcome is in (taking it back does not wait).
    pub(super) fn finished(&self) -> bool {
        self.shared
            .finished
            .load(std::sync::atomic::Ordering::Acquire)
    }
}

/// A pool of one thread (for tests).
#[cfg(test)]
pub(super) fn one_thread_pool() -> BookkeepingPool {
    Some(Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap(),
    ))
}

/// A pool of one thread held by a job until the sender is dropped or sent on: nothing
/// handed to it runs there meanwhile (for tests).
#[cfg(test)]
pub(super) fn held_pool() -> (BookkeepingPool, std::sync::mpsc::Sender<()>) {
    let pool = one_thread_pool();
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    if let Some(p) = &pool {
        p.spawn(move || {
            let _ = rx.recv();
        });
    }
    (pool, tx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_job_the_pool_has_not_started_is_run_by_whoever_waits() {
        let (pool, release) = held_pool();
        let here = std::thread::current().id();
        let job = PoolJob::spawn(&pool, move || std::thread::current().id());
        assert!(!job.finished());
        let ran_on = job.wait().unwrap().unwrap();
        assert_eq!(ran_on, here);
        drop(release);
    }

    #[test]
    fn a_job_the_pool_runs_is_waited_for_and_its_panic_comes_back() {
        let pool = one_thread_pool();
        let job = PoolJob::spawn(&pool, || 7);
        while !job.finished() {
            std::thread::yield_now();
        }
        assert_eq!(job.wait().unwrap().unwrap(), 7);
        let job = PoolJob::spawn(&pool, || -> u8 { panic!("a bug") });
        while !job.finished() {
            std::thread::yield_now();
        }
        assert!(job.wait().unwrap().is_err());
    }

    #[test]
    fn a_running_job_is_waited_for_not_run_twice() {
        let pool = one_thread_pool();
        let runs = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let (started_tx, started) = std::sync::mpsc::channel();
        let counted = Arc::clone(&runs);
        let job = PoolJob::spawn(&pool, move || {
            let _ = started_tx.send(());
            std::thread::sleep(std::time::Duration::from_millis(30));
            counted.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            5
        });
        started.recv().unwrap();
        assert_eq!(job.wait().unwrap().unwrap(), 5);
        assert_eq!(runs.load(std::sync::atomic::Ordering::SeqCst), 1);
    }
}
