//! cells.parquet (being written)
