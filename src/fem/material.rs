//! The elastic material of the body and the plane hypothesis of the 2D model.

use serde::{Deserialize, Serialize};

/// Plane hypothesis of the 2D model (thickness 1 in both).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Hypothesis {
    PlaneStrain,
    PlaneStress,
}

/// A linear isotropic elastic material.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Young's modulus E.
    pub young: f64,
    /// Poisson's ratio nu.
    pub poisson: f64,
    pub hypothesis: Hypothesis,
}

#[cfg(test)]
impl Material {
    /// A plane-strain material of the solver's unit tests (E = 1000, nu = 0.3).
    pub(crate) fn for_tests() -> Self {
        Material {
            young: 1000.0,
            poisson: 0.3,
            hypothesis: Hypothesis::PlaneStrain,
        }
    }
}
