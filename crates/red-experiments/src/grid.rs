//! One worker pool for the experiments' grids: the simple domain's runs
//! ([`crate::toy`]) and the MuJoCo table's cells
//! ([`crate::mujoco::table::run_grid`]).

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// What the pool does after a job fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnFailure {
    /// No worker starts another job (what finished stays finished).
    StopAll,
    /// The other jobs go on.
    Continue,
}

/// Runs `job(i)` for every `i` in `0..n`, `workers` threads at a time
/// (at least one), each worker taking the next index as it frees up. A
/// set `stop` flag ends every worker before its next job. Returns the
/// failed jobs' errors with their indices, in the order they failed.
///
/// A job's numbers must not depend on which thread runs it or when: each
/// job carries its own seeds.
pub fn run_pool<E, F>(
    n: usize,
    workers: usize,
    stop: &AtomicBool,
    on_failure: OnFailure,
    job: F,
) -> Vec<(usize, E)>
where
    E: Send,
    F: Fn(usize) -> Result<(), E> + Sync,
{
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let failures: Mutex<Vec<(usize, E)>> = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..workers.max(1) {
            scope.spawn(|| {
                loop {
                    if stop.load(Ordering::SeqCst) || failed.load(Ordering::SeqCst) {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    if i >= n {
                        break;
                    }
                    if let Err(e) = job(i) {
                        if let Ok(mut f) = failures.lock() {
                            f.push((i, e));
                        }
                        if on_failure == OnFailure::StopAll {
                            failed.store(true, Ordering::SeqCst);
                        }
                    }
                }
            });
        }
    });
    failures.into_inner().unwrap_or_else(|p| p.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_job_runs_once_and_failures_are_kept() {
        let stop = AtomicBool::new(false);
        let count: Vec<AtomicUsize> = (0..20).map(|_| AtomicUsize::new(0)).collect();
        let failures = run_pool(20, 3, &stop, OnFailure::Continue, |i| {
            count[i].fetch_add(1, Ordering::SeqCst);
            if i % 7 == 3 { Err(i) } else { Ok(()) }
        });
        assert!(count.iter().all(|c| c.load(Ordering::SeqCst) == 1));
        let mut failed: Vec<usize> = failures
            .iter()
            .map(|(i, e)| {
                assert_eq!(i, e);
                *i
            })
            .collect();
        failed.sort_unstable();
        assert_eq!(failed, vec![3, 10, 17]);
    }

    #[test]
    fn stop_all_and_the_stop_flag_end_the_workers() {
        let stop = AtomicBool::new(false);
        let ran = AtomicUsize::new(0);
        // One worker: after job 2 fails no other job starts.
        let failures = run_pool(10, 1, &stop, OnFailure::StopAll, |i| {
            ran.fetch_add(1, Ordering::SeqCst);
            if i == 2 { Err("bad") } else { Ok(()) }
        });
        assert_eq!(failures.len(), 1);
        assert_eq!(ran.load(Ordering::SeqCst), 3);
        stop.store(true, Ordering::SeqCst);
        let ran = AtomicUsize::new(0);
        let f: Vec<(usize, ())> = run_pool(10, 2, &stop, OnFailure::Continue, |_| {
            ran.fetch_add(1, Ordering::SeqCst);
            Ok(())
        });
        assert!(f.is_empty());
        assert_eq!(ran.load(Ordering::SeqCst), 0);
    }
}
