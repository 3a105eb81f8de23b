//! Model choice (being written)
