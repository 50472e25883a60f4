//! The friction law and the variants of the method that a case chooses.

use serde::{Deserialize, Serialize};

/// Friction law on the contact boundary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Friction {
    None,
    /// Tresca: a given slip threshold s (force per unit length).
    Tresca {
        threshold: f64,
    },
    /// Coulomb: s = coefficient * p_n.
    Coulomb {
        coefficient: f64,
    },
}

/// How the Coulomb threshold s = nu_f * lambda is refreshed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CoulombMode {
    /// Every sweep, from the current normal multiplier (one fixed-point loop).
    Inner,
    /// A sequence of Tresca solves, s frozen during each.
    Outer,
}

/// Anderson memory by default: measured against 5 on every built-in case and law at
/// levels 1-4, 10 saved about 12% of the sweeps (fewer in 20 of 24 runs). 20 against 10,
/// over the built-in cases at levels 1-3, the held-out, slender and beam cases and the
/// unstructured Gmsh meshes of 20k-1.05M nodes: never more sweeps, fewer where the loop
/// runs long on one set of statuses, which is where the memory fills (it is cleared at
/// each retune): hertz level 5 187 -> 133, block level 5 93 -> 82 (above the retunes'
/// 2048 contact dofs), the Gmsh Hertz mesh of 1.05M nodes 229 -> 189 and block 81 -> 75,
/// the tube with Tresca friction 198 -> 157, the shallow arch 83 -> 74. The time of a
/// sweep did not move (the mixing's work is m contact vectors, next to a sparse solve).
/// 5 took that tube to 3494 sweeps: the memory must cover the slow modes of a piece.
pub const DEFAULT_ANDERSON_MEMORY: usize = 20;

/// Acceleration of the Uzawa fixed point (see `contact::uzawa`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Acceleration {
    /// Plain ALG2.
    None,
    /// Safeguarded Anderson mixing with this memory.
    Anderson { memory: usize },
}
