//! The worker pools. oesweep's parallel work (a sweep, a merge's nested pass, the result files,
//! `fit`'s bootstrap) runs on a local rayon pool of the caller's thread count, built here, never
//! on rayon's global pool: that pool is the host process's (a program linking the library, the
//! Python interpreter), and building it for the host, or taking every core when the caller
//! asked for fewer, would change the host beyond the call.
//!
//! A pool the system refuses (too many threads for its limits) is an error of the call, the one
//! way every caller handles it: neither a panic nor work left out, which would give a table that
//! differs from the one the same call gives elsewhere.

use crate::error::{Error, Result};

/// Most worker threads a call may ask for (`--threads`): more than any machine oesweep runs on
/// has cores, and each worker holds a workspace; `--threads 100000` made the process spend
/// minutes creating threads or abort when the system refused them.
pub const MAX_THREADS: usize = 1024;

/// The rule for a thread count (0: one per core), of `run --threads` and `fit --threads` alike.
pub fn check_threads(threads: usize) -> std::result::Result<(), String> {
    if threads <= MAX_THREADS {
        Ok(())
    } else {
        Err(format!("must be at most {MAX_THREADS} (0: all cores), got {threads}"))
    }
}

/// A pool of `threads` workers (0: one per core) for the work `purpose` names ("for the sweep":
/// the error reads "cannot start 8 threads for the sweep: ...").
pub fn local(threads: usize, purpose: &str) -> Result<rayon::ThreadPool> {
    let built = match crate::failpoint::refused_threads() {
        Some(why) => Err(why),
        None => rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| e.to_string()),
    };
    built.map_err(|e| {
        let count = if threads == 0 { "a thread per core".to_string() } else { format!("{threads} threads") };
        Error::Invalid(format!("cannot start {count} {purpose}: {e}"))
    })
}
