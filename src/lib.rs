//! oesweep: robust (Huber) output-error identification and model-order search.
//!
//! The numerical specification is `../shared/METHOD.md`; module docs cite its sections.
//! Data flows one way: data -> estimate (per cell) -> (sweep -> reduce -> export).

pub mod checkpoint;
pub mod cli;
pub mod data;
pub mod error;
pub mod estimate;
pub mod export;
pub mod job;
pub mod kernels;
pub mod oe;
pub mod plan;
pub mod progress;
pub mod reduce;
pub mod report;
pub mod shard;
pub mod simulate;
pub mod spectral;
pub mod sweep;
pub mod table;

pub use error::{Error, Result};
