//! oesweep: robust (Huber) output-error identification and model-order search.
//!
//! The method as implemented is `docs/METHOD.md`; module docs cite its sections ("METHOD.md N").
//! Data flows one way: data -> estimate (per cell) -> (sweep -> reduce -> export).

pub mod checkpoint;
pub mod cli;
pub mod data;
pub mod engine;
pub mod error;
pub mod estimate;
pub mod export;
pub mod failpoint;
pub mod job;
pub mod kernels;
pub mod lock;
pub mod oe;
pub mod plan;
pub mod profile;
pub mod progress;
pub mod reduce;
pub mod report;
pub mod results;
pub(crate) mod rng;
pub mod shard;
pub mod simulate;
pub mod slurm;
pub mod spectral;
pub mod sweep;
pub mod table;
pub mod text;

pub use error::{Error, Result};

/// Makes faer's dense routines (the ARX/IV regressions of the initial guess, the eigenvalue
/// fallback of the pole finder) run sequentially. oesweep parallelises across cells, one
/// rayon worker per cell; faer's default (all of rayon's threads) nested inside a worker only
/// added scheduling: 18 % of the L2 phase went to the initial guesses, much of it in thread
/// hand-offs, and a thread-count-dependent split of a product would put the table's
/// independence of `--threads` at risk. Called before each such routine; idempotent.
pub(crate) fn faer_sequential() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| faer::set_global_parallelism(faer::Par::Seq));
}
