//! How many worker threads a job's render uses: `--threads` (at most
//! [`MAX_THREADS`]), else the batch job's allocation
//! ([`allocated_threads`]), else every core.

use thiserror::Error;

/// The most worker threads `--threads` starts.
pub const MAX_THREADS: usize = 1024;

/// A worker count out of range, or a pool that could not start.
#[derive(Debug, Error)]
pub enum ThreadsError {
    #[error("--threads {0}: at most {MAX_THREADS} (default: one per core)")]
    TooMany(usize),
    #[error("cannot start worker threads")]
    Pool(#[source] rayon::ThreadPoolBuildError),
}

/// Checks `--threads` against [`MAX_THREADS`] (rayon would try to start them all).
pub fn check_threads(threads: Option<usize>) -> Result<(), ThreadsError> {
    match threads {
        Some(t) if t > MAX_THREADS => Err(ThreadsError::TooMany(t)),
        _ => Ok(()),
    }
}

/// The CPUs a batch system gave this process, with the variable that says
/// so: `LUCENT_THREADS` (set by the Kubernetes Job `lucent run --emit k8s`
/// writes, from the pod's CPU request), else Slurm's `SLURM_CPUS_PER_TASK`
/// (set when the job asks for `--cpus-per-task`). A value that is not a
/// whole number in 1 … [`MAX_THREADS`] is ignored.
pub fn allocated_threads(var: impl Fn(&str) -> Option<String>) -> Option<(usize, &'static str)> {
    ["LUCENT_THREADS", "SLURM_CPUS_PER_TASK"].into_iter().find_map(|k| {
        let n: usize = var(k)?.trim().parse().ok()?;
        (1..=MAX_THREADS).contains(&n).then_some((n, k))
    })
}

/// The worker pool of `threads` (default: the allocation, else all cores; 0: all cores).
pub fn worker_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, ThreadsError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.or_else(|| allocated_threads(|k| std::env::var(k).ok()).map(|(n, _)| n)).unwrap_or(0))
        .build()
        .map_err(ThreadsError::Pool)
}
