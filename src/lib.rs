//! oesweep: robust (Huber) output-error identification and model-order search.
//!
//! The method as implemented is `docs/METHOD.md`; module docs cite its sections ("METHOD.md N").
//! Data flows one way: data -> estimate (per cell) -> (sweep -> reduce -> export).

pub mod checkpoint;
pub mod cli;
pub mod data;
pub mod dense;
pub mod engine;
pub mod error;
pub mod estimate;
pub mod export;
pub mod failpoint;
pub mod job;
pub mod kernels;
pub mod lock;
pub(crate) mod names;
pub mod oe;
pub mod plan;
pub mod pool;
pub mod profile;
pub mod progress;
pub mod reduce;
pub mod report;
pub mod results;
pub(crate) mod rng;
pub mod schedule;
pub mod search;
pub mod shard;
pub mod simulate;
pub mod slurm;
pub mod spectral;
pub mod structure;
pub mod sweep;
pub mod table;
pub mod text;

pub use error::{Error, Result};
