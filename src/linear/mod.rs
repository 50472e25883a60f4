//! Sparse direct solves: faer's Cholesky factor, factored once and solved many times, and
//! the fill-reducing orderings of a subdomain's interior.

mod cholesky;
mod dissection;
mod ordering;

pub use cholesky::SparseCholesky;
pub use dissection::geometric_nested_dissection;
pub use ordering::{interior_groups, NodeGraph, Ordering, ND_MIN_INTERIOR_DOFS};
