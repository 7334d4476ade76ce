//! The job's own small thread pool: inputs taken in order by `jobs` threads, results in
//! input order whatever finishes first.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// `work` over `items` on `jobs` threads, taking items in order; the results come back in item
/// order whatever finishes first, so nothing written depends on timing. `progress` sees every
/// slot (finished or not) after each item; it should be cheap unless it acts (the manifest
/// writer checks the time first).
pub(super) fn in_order<I: Sync, R: Send>(
    items: &[I],
    jobs: usize,
    work: impl Fn(&I) -> R + Sync,
    progress: impl Fn(&[Option<R>]) + Sync,
) -> Vec<R> {
    let done: Mutex<Vec<Option<R>>> = Mutex::new(items.iter().map(|_| None).collect());
    let next = AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..jobs.clamp(1, items.len().max(1)) {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(k) else { break };
                let result = work(item);
                let mut done = done.lock().unwrap_or_else(|e| e.into_inner());
                done[k] = Some(result);
                progress(&done);
            });
        }
    });
    done.into_inner().unwrap_or_else(|e| e.into_inner()).into_iter().flatten().collect()
}
