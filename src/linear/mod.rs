//! Sparse direct solves.

mod cholesky;

pub use cholesky::*;
