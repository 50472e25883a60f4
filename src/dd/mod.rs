//! Domain decomposition over MPI ranks.
//!
//! `split` and `condense` are pure (testable without MPI); `comm` is the only module
//! that calls MPI.

pub mod comm;
pub mod condense;
pub mod split;
