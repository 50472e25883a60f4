//! contact-par: 2D unilateral contact of linear elastic bodies against rigid obstacles
//! (lines, circles, polylines) or each other (frictionless, Tresca, Coulomb), P1
//! triangles, Uzawa block relaxation on an augmented Lagrangian (see docs/ALGORITHM.md),
//! on one rank or many MPI ranks. `run::run` tells a run's phases.

// Index loops over several coupled arrays read closer to the formulas than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod case;
pub mod checkpoint;
pub mod contact;
pub mod dd;
pub mod error;
pub mod fem;
pub mod host;
pub mod linear;
pub mod mesh;
pub mod options;
pub mod output;
pub mod problem;
pub mod run;
pub mod setup;
pub mod timer;
