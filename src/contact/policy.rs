//! How the loop chooses r per contact direction. The loop ([`super::uzawa`]) asks its
//! policy only for the reference r before the first sweep and, after each accepted
//! point, whether r changes. [`Fixed`] keeps the given r: the paper's method, plain ALG2
//! with safeguarded Anderson mixing. [`super::adaptive::Adaptive`] is the automatic r.

use super::adaptive::AdaptiveState;
use super::sweep::{Augmentation, Derived, Held, Law, Sweep, SweepSums};
use super::{ContactNodes, LinearStep, Reduce};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// What a policy sees of the loop when it decides on r (counts over all ranks, so that
/// every rank decides the same).
pub(super) struct Image<'a> {
    /// The sweeps so far; the last evaluated the last accepted point.
    pub(super) history: &'a [Sweep],
    /// The quantities of that point's image on this rank's nodes.
    pub(super) last: &'a Derived,
    pub(super) law: Law<'a>,
    /// Contact nodes over all ranks.
    pub(super) n_contact: usize,
    /// The reference r of the loop.
    pub(super) r_ref: f64,
}

/// A choice of r per contact direction. The defaults are those of a given r.
pub(super) trait Policy {
    /// The reference r of a run that starts afresh from the given `r`, and the body's
    /// smooth-mode stiffness over E_eff / L where measured for it.
    fn start(
        &mut self,
        _step: &mut dyn LinearStep,
        _comm: &dyn Reduce,
        _nodes: &ContactNodes,
        r: f64,
    ) -> Result<(f64, Option<f64>)> {
        Ok((r, None))
    }

    /// Adds this rank's counts of the policy ([`Sweep::mistuned`], ...) to the sums of a
    /// sweep whose image has the statuses `now`, made with `aug` around the reference r.
    fn count(
        &self,
        _now: &[Held],
        _aug: &Augmentation,
        _r: f64,
        _frictional: bool,
        _sums: &mut SweepSums,
    ) {
    }

    /// Notes the statuses of sweep `sweep`'s image, `now`, after `before` (those of the
    /// sweep before; empty at the first).
    fn seen(&mut self, _sweep: usize, _before: &[Held], _now: &[Held]) {}

    /// The largest r of a direction raised above the reference r: the scale of the
    /// sweep's round-off.
    fn largest_r(&self, r: f64) -> f64 {
        r
    }

    /// The r per direction from the next sweep on, if it changes.
    fn retune(&mut self, _image: &Image) -> Option<Augmentation> {
        None
    }

    /// What the checkpoint stores of the policy, and its restoration.
    fn state(&self) -> PolicyState;
    fn restore(&mut self, state: PolicyState) -> Result<()>;
}

/// The policy's part of a checkpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) enum PolicyState {
    Fixed,
    Adaptive(AdaptiveState),
}

/// A given r, in every direction, for the whole run.
pub(super) struct Fixed;

impl Policy for Fixed {
    fn state(&self) -> PolicyState {
        PolicyState::Fixed
    }

    fn restore(&mut self, state: PolicyState) -> Result<()> {
        match state {
            PolicyState::Fixed => Ok(()),
            other => Err(another_policy(&other)),
        }
    }
}

/// The error of a checkpoint whose policy, `saved`, is not this run's.
pub(super) fn another_policy(saved: &PolicyState) -> Error {
    let (given, automatic) = ("a given r (--r)", "the automatic r (no --r)");
    let (then, now) = match saved {
        PolicyState::Fixed => (given, automatic),
        PolicyState::Adaptive(_) => (automatic, given),
    };
    Error::Input(format!(
        "the checkpoint was taken with {then} and this run has {now}; restart with the same options, or run without --restart"
    ))
}
