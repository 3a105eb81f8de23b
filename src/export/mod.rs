//! Result files. (being written)
pub mod parquet;
