//! Running independent jobs on every core of a native build; sequential in WASM (one thread).

/// Calls `f` on every job, natively on up to `available_parallelism` threads (or
/// `MMDB_THREADS`). Jobs are handed
/// out one at a time so uneven jobs balance; each job owns its outputs, so the result does
/// not depend on the schedule.
pub fn for_each<J: Send, F: Fn(J) + Sync>(jobs: Vec<J>, f: F) {
    #[cfg(not(target_arch = "wasm32"))]
    {
        // MMDB_THREADS caps the thread count (benchmarks compare 1 thread with all).
        let cap = std::env::var("MMDB_THREADS").ok().and_then(|v| v.parse().ok()).unwrap_or(usize::MAX);
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(jobs.len()).min(cap);
        if threads > 1 {
            let queue = std::sync::Mutex::new(jobs.into_iter());
            std::thread::scope(|scope| {
                for _ in 0..threads {
                    scope.spawn(|| loop {
                        let job = queue.lock().unwrap().next();
                        match job {
                            Some(job) => f(job),
                            None => break,
                        }
                    });
                }
            });
            return;
        }
    }
    jobs.into_iter().for_each(f);
}
