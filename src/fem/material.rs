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

/// The material of each element of a mesh: one for all, or a table of the bodies'
/// materials and each element's body (its index in the table).
#[derive(Debug, Clone, Copy)]
pub enum Materials<'a> {
    One(&'a Material),
    PerElement {
        table: &'a [Material],
        body: &'a [u32],
    },
}

impl<'a> Materials<'a> {
    /// The distinct materials: the table, or the one.
    pub fn table(&self) -> &'a [Material] {
        match *self {
            Materials::One(m) => std::slice::from_ref(m),
            Materials::PerElement { table, .. } => table,
        }
    }

    /// Element `e`'s index in [`Materials::table`].
    pub fn index(&self, e: usize) -> usize {
        match *self {
            Materials::One(_) => 0,
            Materials::PerElement { body, .. } => body[e] as usize,
        }
    }

    /// Element `e`'s material.
    pub fn of(&self, e: usize) -> &'a Material {
        &self.table()[self.index(e)]
    }
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
