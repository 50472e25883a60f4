//! The contact method of docs/ALGORITHM.md: node-wise kernels and the Uzawa loop, written
//! once against two small traits so that one rank and many ranks run the same code.

mod adaptive;
mod anderson;
pub mod kernels;
mod law;
pub mod mortar;
pub mod obstacle;
pub mod operators;
mod policy;
pub mod probe;
mod sweep;
pub mod uzawa;

pub use adaptive::AdaptiveParams;
pub use law::{Acceleration, CoulombMode, Friction, DEFAULT_ANDERSON_MEMORY};
pub use sweep::{roundoff_warning, Sweep};
pub use uzawa::{solve, solve_with, Checkpoints, Outcome, Params, Snapshot};

use crate::error::Result;

/// Step 1 of ALG2, the linear elasticity solve with the constant matrix
/// A = K + r N'WN (+ r T'WT), seen from the contact nodes a rank owns.
///
/// `force_n[i]`, `force_t[i]` are the contact forces w_i (r p_i - lambda_i) and
/// w_i (r q_i - mu_i) at the i-th owned contact node; the implementation solves
/// A u = F + N' force_n + T' force_t and returns (N u)_i and (T u)_i at the same nodes.
/// A is factored once when the implementation is built; this call only solves.
pub trait LinearStep {
    fn solve(
        &mut self,
        force_n: &[f64],
        force_t: &[f64],
        un: &mut [f64],
        ut: &mut [f64],
    ) -> Result<()>;

    /// Sets the r of each owned contact node's normal and tangential direction in A
    /// (collective: every rank calls it at the same sweep). Returns false when this
    /// step cannot; r then stays as it was.
    fn set_r(&mut self, _r_n: &[f64], _r_t: &[f64]) -> Result<bool> {
        Ok(false)
    }
}

/// Global sums over all ranks (an all-reduce). One rank: the identity.
pub trait Reduce {
    fn sum_in_place(&self, values: &mut [f64]);
    /// The smallest of each entry over all ranks.
    fn min_in_place(&self, values: &mut [f64]);
}

/// The single-rank reduction.
pub struct NoComm;

impl Reduce for NoComm {
    fn sum_in_place(&self, _values: &mut [f64]) {}
    fn min_in_place(&self, _values: &mut [f64]) {}
}

/// The contact nodes a rank owns, with their lumped weights, frames and initial gaps.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct ContactNodes {
    /// Lumped boundary weight w_i (half the length of each contact edge at the node).
    pub w: Vec<f64>,
    /// Initial gap g_i along the node's normal (for a line (x_i - p0) . m).
    pub g: Vec<f64>,
    /// Position along the obstacle (for a line (x_i - p0) . t).
    pub s: Vec<f64>,
    /// Unit normal m_i of each node, obstacle -> body: u_n = -m_i . u; its tangent is
    /// t_i = (m_y, -m_x), u_t = t_i . u.
    pub normal: Vec<[f64; 2]>,
    /// The contact (the case's `[[contact]]` entry, from 0) each node belongs to.
    pub pair: Vec<u32>,
    /// The friction law's value at each node (Coulomb coefficient, Tresca threshold)
    /// where contacts give different ones; empty: the one of `Params::friction`. Filled
    /// from the case at each run (a split's parts leave it empty, so the values may
    /// change between runs of one split).
    #[serde(default)]
    pub friction: Vec<f64>,
    /// Where Tresca and Coulomb contacts are mixed: each node's fixed slip threshold
    /// (its Tresca threshold, 0 at a Coulomb node), `friction` then holding the Coulomb
    /// coefficients (0 at a Tresca node), so that s_i = threshold_i + c_i p_n,i at every
    /// node; empty otherwise. Filled from the case at each run, like `friction`.
    #[serde(default)]
    pub fixed_threshold: Vec<f64>,
    /// Each node's separate part of the mesh and its master nodes' part
    /// (`problem::NO_PART` against an obstacle), for the check of the answer
    /// (`problem::free_at_answer`); empty where not known.
    #[serde(default)]
    pub part: Vec<[u32; 2]>,
}

/// The tangent of a unit normal: m turned clockwise.
pub fn tangent_of(m: [f64; 2]) -> [f64; 2] {
    [m[1], -m[0]]
}

impl ContactNodes {
    /// The nodes `keep` (indices into self), in that order.
    pub fn select(&self, keep: &[usize]) -> ContactNodes {
        ContactNodes {
            w: keep.iter().map(|&k| self.w[k]).collect(),
            g: keep.iter().map(|&k| self.g[k]).collect(),
            s: keep.iter().map(|&k| self.s[k]).collect(),
            normal: keep.iter().map(|&k| self.normal[k]).collect(),
            pair: keep.iter().map(|&k| self.pair[k]).collect(),
            friction: keep
                .iter()
                .filter_map(|&k| self.friction.get(k).copied())
                .collect(),
            fixed_threshold: keep
                .iter()
                .filter_map(|&k| self.fixed_threshold.get(k).copied())
                .collect(),
            part: keep
                .iter()
                .filter_map(|&k| self.part.get(k).copied())
                .collect(),
        }
    }

    /// The friction law's value at every node: per node where given, else `value`.
    pub fn friction_values(&self, value: f64) -> Vec<f64> {
        if self.friction.is_empty() {
            vec![value; self.len()]
        } else {
            self.friction.clone()
        }
    }

    pub fn len(&self) -> usize {
        self.w.len()
    }

    pub fn is_empty(&self) -> bool {
        self.w.is_empty()
    }
}

/// Node status after convergence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    Free = 0,
    Stick = 1,
    Slip = 2,
    /// In contact, without friction: neither stick nor slip.
    Contact = 3,
}
