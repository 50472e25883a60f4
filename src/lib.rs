//! contact-par: 2D unilateral contact of a linear elastic body with a rigid foundation
//! (frictionless, Tresca, Coulomb), P1 triangles, Uzawa block relaxation on an augmented
//! Lagrangian (see docs/ALGORITHM.md), on one rank or many MPI ranks.

// Index loops over several coupled arrays read closer to the formulas than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod app;
pub mod case;
pub mod checkpoint;
pub mod contact;
pub mod dd;
pub mod error;
pub mod fem;
pub mod host;
pub mod linear;
pub mod mesh;
pub mod output;
pub mod problem;
pub mod split_dir;
pub mod timer;
