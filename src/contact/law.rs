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

/// Anderson memory by default: it must cover the slow modes of one piece of the sweep
/// map (the memory is cleared at each retune), and costs only m contact vectors a sweep.
pub const DEFAULT_ANDERSON_MEMORY: usize = 20;

/// Acceleration of the Uzawa fixed point (see `contact::uzawa`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Acceleration {
    /// Plain ALG2.
    None,
    /// Safeguarded Anderson mixing with this memory.
    Anderson { memory: usize },
}
