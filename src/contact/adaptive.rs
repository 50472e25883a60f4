//! The automatic r (docs/ALGORITHM.md, "The augmentation parameter per direction"): the
//! r of each contact direction follows its status as the loop runs. Its tuning is
//! [`AdaptiveParams`], its state [`AdaptiveState`]; a given r is [`super::policy::Fixed`].
//!
//! Why: r acts as a spring r w on each contact direction. A held direction (a pressed
//! normal, a sticking tangent) is an equality that a sweep enforces by contracting each of
//! its modes by 1 / (1 + r c), c a compliance: large r is best. A free one (open,
//! slipping) moves by r c / (1 + r c) of the way: small r is best. Held raised and free
//! lowered, a sweep is one step of a primal-dual active-set method.

use super::policy::{Image, Policy, PolicyState};
use super::probe::smooth_stiffness;
use super::sweep::{Augmentation, Held, Law, Sweep, SweepSums};
use super::{ContactNodes, LinearStep, Reduce};
use crate::error::Result;
use serde::{Deserialize, Serialize};

/// The adaptive policy's tuning: what its rules compare with and move r by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveParams {
    /// Smooth-mode stiffness, over a compact body's (E_eff / L), below which r is lowered
    /// before the loop: the open nodes' springs would otherwise hold a slender body's bending.
    pub soft_body: f64,
    /// The power of that ratio (over `soft_body`) the r is lowered by.
    pub soft_body_power: i32,
    /// The least ratio over `soft_body` counted, so that r is lowered by a bounded factor.
    pub soft_body_least: f64,
    /// Power iterations of the smooth-mode probe (one linear step each): enough to damp
    /// the stiff modes.
    pub probe_steps: usize,
    /// A held normal's r over the reference r, and the reference over a free normal's
    /// while the zone moves: an active-set step that keeps the contact block's condition
    /// within three more decades.
    pub normal_factor: f64,
    /// The same for the tangents: lower, since a stiffer sticking tangent amplifies the
    /// motion left and flips its node to slip.
    pub tangent_factor: f64,
    /// The reference r over a free direction's once the statuses have settled: its
    /// spring then only slows the smooth modes of a body held at few nodes.
    pub settled_free_factor: f64,
    /// The least r of a held normal in units of E_eff / h: the mesh-scale modes need r of
    /// that order, whatever the reference r.
    pub held_normal_floor: f64,
    /// The least r of a sticking tangent in units of E_eff / h: below the normals', since
    /// a stiffer tangent flips its node and the retunes then cycle.
    pub held_tangent_floor: f64,
    /// Sweeps without a status change before the tangents are tuned (one more with
    /// friction, whose statuses settle after the pressures).
    pub settled_sweeps: usize,
    /// Retunes in one run, all kinds: enough for a zone found node by node; the last
    /// returns every direction to the reference r, where ALG2 converges for any statuses.
    pub max_retunes: usize,
    /// Returns to one set of statuses, each after the retunes had left it, from which the
    /// retunes count as cycling.
    pub cycle_returns: usize,
    /// Contact dofs (over all ranks) above which r is not retuned: the first retune's
    /// refactoring of the dense contact blocks then costs more than the sweeps it saves.
    pub max_retune_dofs: usize,
    /// The slow tail's further factor for sticking tangents and free directions (the held
    /// normals keep theirs: they set the sweep's round-off).
    pub tail_factor: f64,
    /// Sweeps without a status change, made with the settled r, before the tail's retune.
    pub tail_sweeps: usize,
    /// The plain map's contraction from which the tail counts as slow.
    pub tail_contraction: f64,
    /// Tail retunes in one run.
    pub max_tail_retunes: usize,
}

impl Default for AdaptiveParams {
    fn default() -> Self {
        AdaptiveParams {
            soft_body: 0.05,
            soft_body_power: 2,
            soft_body_least: 1e-3,
            probe_steps: 6,
            normal_factor: 1000.0,
            tangent_factor: 10.0,
            settled_free_factor: 1.0e4,
            held_normal_floor: 0.3,
            held_tangent_floor: 0.2,
            settled_sweeps: 1,
            max_retunes: 100,
            cycle_returns: 3,
            max_retune_dofs: 2048,
            tail_factor: 10.0,
            tail_sweeps: 2,
            tail_contraction: 0.6,
            max_tail_retunes: 3,
        }
    }
}

/// Which of [`AdaptiveParams::tuned`]'s rules apply: the settled ones (free directions
/// lowered further), the tangents following their stick/slip statuses
/// ([`tangents_follow`]), and the slow tail's further factor (only with `settled`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub(super) struct Rules {
    pub(super) settled: bool,
    pub(super) follow_tangents: bool,
    pub(super) tail: bool,
}

impl Rules {
    /// The settled rules, tangents not following.
    pub(super) const SETTLED: Rules = Rules {
        settled: true,
        follow_tangents: false,
        tail: false,
    };
}

/// What a retune does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Retune {
    /// Each direction to the r its status asks for ([`AdaptiveParams::tuned`]).
    ToStatus,
    /// Each normal to the r its status asks for; the tangents lowered as if slipping
    /// while the zone moves ([`AdaptiveParams::for_statuses`]).
    Normals,
    /// The budget spent: the last retune, as a cycle's end with the statuses the last
    /// sweep changed as those that cycled.
    BudgetSpent,
    /// The statuses cycle (since sweep `since`): the last retune
    /// ([`AdaptiveParams::after_cycle`]).
    EndCycle { since: usize },
    /// The settled statuses hold and the loop contracts slowly: as `ToStatus`, sticking
    /// tangents and free directions a further `tail_factor` from the reference r.
    Tail,
}

/// What the adaptive policy carries from sweep to sweep, stored whole in the checkpoint
/// (a change of its fields is a new `Snapshot::FORMAT`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct AdaptiveState {
    /// The rules the r in force was made by.
    rules: Rules,
    /// Whether the r in force ended the retunes (a cycle's end, the budget's last).
    ended: bool,
    /// Tail retunes so far.
    tails: usize,
    /// The sweep count when the retunes cycled with the tangents following their
    /// statuses: from there they no longer follow, and a cycle counts from there.
    tangents_cycled_at: Option<usize>,
    /// The sweep of each of this rank's nodes' last status change (0: never), and of its
    /// normal's: what cycled at a cycle's end.
    changed_at: Vec<usize>,
    normal_changed_at: Vec<usize>,
}

impl AdaptiveState {
    fn new(n: usize) -> Self {
        AdaptiveState {
            rules: Rules::default(),
            ended: false,
            tails: 0,
            tangents_cycled_at: None,
            changed_at: vec![0; n],
            normal_changed_at: vec![0; n],
        }
    }
}

/// The automatic r on this rank's contact nodes.
pub(super) struct Adaptive {
    params: AdaptiveParams,
    /// E_eff / h, which sets the least r of a held direction (0 when not known).
    mesh_stiffness: f64,
    /// Each node's key for the status fingerprint ([`node_key`]).
    keys: Vec<u64>,
    state: AdaptiveState,
}

impl Adaptive {
    /// The policy for `nodes`, with the body's E_eff / h (NaN or 0 when not known: no
    /// floors and no softened r).
    pub(super) fn new(params: AdaptiveParams, nodes: &ContactNodes, mesh_stiffness: f64) -> Self {
        Adaptive {
            params,
            mesh_stiffness: mesh_stiffness.max(0.0),
            keys: (0..nodes.len()).map(|i| node_key(nodes, i)).collect(),
            state: AdaptiveState::new(nodes.len()),
        }
    }

    /// What the next retune does, if any (every rank decides the same: global counts).
    fn next_retune(&mut self, image: &Image) -> Option<Retune> {
        let (p, s, history) = (&self.params, &self.state, image.history);
        if s.ended {
            return None;
        }
        // The sweeps of the tangents' own cycle no longer count towards one.
        let since = s.tangents_cycled_at.unwrap_or(0);
        let kind = match p.retuned(&history[since..], image.law.frictional(), image.n_contact) {
            Some(kind) => kind,
            None if p.tail(history, s) => Retune::Tail,
            None => return None,
        };
        // Tangents that followed their statuses and cycled take the settled rules instead.
        let fixed_thresholds = matches!(image.law, Law::Fixed(_));
        if fixed_thresholds
            && s.tangents_cycled_at.is_none()
            && matches!(kind, Retune::EndCycle { .. })
        {
            self.state.tangents_cycled_at = Some(history.len());
            return Some(Retune::ToStatus);
        }
        Some(kind)
    }

    /// Each node's (any status, its normal's) change after sweep `since`.
    fn changed_since(&self, since: usize) -> Vec<(bool, bool)> {
        let s = &self.state;
        (s.changed_at.iter().zip(&s.normal_changed_at))
            .map(|(&any, &normal)| (any > since, normal > since))
            .collect()
    }
}

impl Policy for Adaptive {
    /// The reference r: where the body is far softer for smooth contact modes than a
    /// compact one ([`smooth_stiffness`] below `soft_body` E_eff / L), r lowered by a
    /// power of the ratio; else the given r. Also returns the measured ratio.
    fn start(
        &mut self,
        step: &mut dyn LinearStep,
        comm: &dyn Reduce,
        nodes: &ContactNodes,
        r: f64,
    ) -> Result<(f64, Option<f64>)> {
        let p = &self.params;
        if self.mesh_stiffness <= 0.0 {
            return Ok((r, None));
        }
        let Some(k) = smooth_stiffness(step, comm, nodes, r, p.probe_steps)? else {
            return Ok((r, None));
        };
        // The given r is sqrt(mesh stiffness x compact stiffness).
        let ratio = k * self.mesh_stiffness / (r * r);
        let factor = (ratio / p.soft_body)
            .clamp(p.soft_body_least, 1.0)
            .powi(p.soft_body_power);
        Ok((if factor >= 1.0 { r } else { r * factor }, Some(ratio)))
    }

    fn count(
        &self,
        now: &[Held],
        aug: &Augmentation,
        r: f64,
        frictional: bool,
        sums: &mut SweepSums,
    ) {
        let (p, rules, stiffness) = (&self.params, self.state.rules, self.mesh_stiffness);
        let settled_rules = Rules {
            settled: true,
            ..rules
        };
        let differ = |a: f64, b: f64| f64::from(u8::from(a != b));
        for (i, &held) in now.iter().enumerate() {
            let (r_n, r_t) = (aug.r_n[i], aug.r_t[i]);
            let (want_n, want_t) = p.tuned(held, frictional, r, stiffness, rules);
            sums.mistuned += differ(r_n, want_n) + differ(r_t, want_t);
            if r_n != want_n || (rules.follow_tangents && r_t != want_t) {
                sums.mistuned_n += 1.0;
            }
            let (settled_n, settled_t) = p.tuned(held, frictional, r, stiffness, settled_rules);
            sums.unsettled += differ(r_n, settled_n) + differ(r_t, settled_t);
            sums.pattern += status_tag(self.keys[i], held);
        }
    }

    fn seen(&mut self, sweep: usize, before: &[Held], now: &[Held]) {
        let s = &mut self.state;
        for (i, (a, b)) in before.iter().zip(now).enumerate() {
            if a != b {
                s.changed_at[i] = sweep;
            }
            if a.n != b.n {
                s.normal_changed_at[i] = sweep;
            }
        }
    }

    fn largest_r(&self, r: f64) -> f64 {
        self.params.largest_tuned(r, self.mesh_stiffness)
    }

    fn retune(&mut self, image: &Image) -> Option<Augmentation> {
        let kind = self.next_retune(image)?;
        let (history, frictional) = (image.history, image.law.frictional());
        let held: Vec<Held> = (0..image.last.p.len())
            .map(|i| image.last.held(i, frictional))
            .collect();
        let scale = (image.r_ref, self.mesh_stiffness);
        let since = match kind {
            Retune::EndCycle { since } => since,
            // The spent budget's statuses still moving: those the last sweep changed.
            Retune::BudgetSpent => history.len().saturating_sub(1),
            _ => {
                let fixed_thresholds = matches!(image.law, Law::Fixed(_));
                let pressed = history.last().map_or(0, |s| s.active);
                let cycled = self.state.tangents_cycled_at.is_some();
                let follow = tangents_follow(fixed_thresholds, pressed, cycled);
                let from = (self.state.rules.settled, follow);
                let (aug, rules) = self
                    .params
                    .for_statuses(kind, &held, frictional, scale, from);
                self.state.rules = rules;
                self.state.tails += usize::from(kind == Retune::Tail);
                return Some(aug);
            }
        };
        let cycled = self.changed_since(since);
        let aug = self.params.after_cycle(&held, &cycled, frictional, scale);
        (self.state.rules, self.state.ended) = (Rules::SETTLED, true);
        Some(aug)
    }

    fn state(&self) -> PolicyState {
        PolicyState::Adaptive(self.state.clone())
    }

    fn restore(&mut self, state: PolicyState) -> Result<()> {
        match state {
            PolicyState::Adaptive(s) => {
                self.state = s;
                Ok(())
            }
            other => Err(super::policy::another_policy(&other)),
        }
    }
}

impl AdaptiveParams {
    /// The r of a node's normal and tangential directions for its statuses (`r` the
    /// reference r, `mesh_stiffness` E_eff / h): raised where held, at least to the
    /// floors; lowered where free, further once `rules.settled`; with
    /// `rules.follow_tangents` an open node's slipping tangent counts as free at once;
    /// with `rules.tail` (and settled) sticking tangents and free directions a further
    /// `tail_factor` away. Without friction the tangent is not used and keeps r.
    pub(super) fn tuned(
        &self,
        status: Held,
        frictional: bool,
        r: f64,
        mesh_stiffness: f64,
        rules: Rules,
    ) -> (f64, f64) {
        let Rules {
            settled,
            follow_tangents,
            tail,
        } = rules;
        let further = if settled && tail {
            self.tail_factor
        } else {
            1.0
        };
        let pick = |held: bool, factor: f64, floor: f64| {
            if held {
                (r * factor).max(floor * mesh_stiffness)
            } else {
                r / factor
            }
        };
        let free = if settled {
            r / (self.settled_free_factor * further)
        } else {
            r / self.normal_factor
        };
        let t =
            if frictional && status.free_tangent() && (settled || (follow_tangents && !status.n)) {
                free
            } else if frictional && status.t {
                // At most the held normals' r, which sets the sweep's round-off.
                (pick(true, self.tangent_factor, self.held_tangent_floor) * further)
                    .min(self.largest_tuned(r, mesh_stiffness))
            } else if frictional {
                pick(false, self.tangent_factor, self.held_tangent_floor)
            } else {
                r
            };
        let n = if status.n {
            pick(true, self.normal_factor, self.held_normal_floor)
        } else {
            free
        };
        (n, t)
    }

    /// The largest r that [`AdaptiveParams::tuned`] gives any direction: the scale of
    /// the sweep's round-off.
    pub(super) fn largest_tuned(&self, r: f64, mesh_stiffness: f64) -> f64 {
        (r * self.normal_factor).max(self.held_normal_floor * mesh_stiffness)
    }

    /// The r of each direction that `kind` (not a cycle's end) asks for, given each node's
    /// statuses `held`, the `scale` (reference r, E_eff / h), and `from`: whether the r
    /// replaced was settled, and whether the tangents follow ([`tangents_follow`]);
    /// returns it with its rules. A normals' retune from settled r keeps the free
    /// directions at their settled r (the zone's edge moving by a node is no reason to
    /// raise them again); the tangents of pressed nodes go to r / `tangent_factor`.
    pub(super) fn for_statuses(
        &self,
        kind: Retune,
        held: &[Held],
        frictional: bool,
        (r, mesh_stiffness): (f64, f64),
        (from_settled, follow_tangents): (bool, bool),
    ) -> (Augmentation, Rules) {
        let mut aug = Augmentation::uniform(held.len(), r);
        let rules = Rules {
            settled: match kind {
                Retune::ToStatus | Retune::Tail => true,
                Retune::Normals => from_settled,
                Retune::BudgetSpent | Retune::EndCycle { .. } => false,
            },
            follow_tangents: follow_tangents && frictional,
            tail: kind == Retune::Tail,
        };
        for (i, &h) in held.iter().enumerate() {
            let (r_n, r_t) = self.tuned(h, frictional, r, mesh_stiffness, rules);
            match kind {
                Retune::ToStatus | Retune::Tail => (aug.r_n[i], aug.r_t[i]) = (r_n, r_t),
                Retune::Normals => {
                    aug.r_n[i] = r_n;
                    if frictional {
                        let keep = rules.follow_tangents || (rules.settled && h.free_tangent());
                        aug.r_t[i] = if keep { r_t } else { r / self.tangent_factor };
                    }
                }
                Retune::BudgetSpent | Retune::EndCycle { .. } => {}
            }
        }
        (aug, rules)
    }

    /// The last retune, when the statuses cycle or the budget is spent; `cycled`: each
    /// node's (any status, its normal's) change since the cycle began. A node open
    /// through the cycle keeps its settled r (its spring would hold the smooth modes); a
    /// pressed normal that stayed pressed keeps its raised r (else the body sinks onto
    /// the lowered open nodes and creeps); a pressed node's tangent returns to the
    /// reference r, but not below the held tangents' floor; every other direction (what
    /// cycled) returns to the reference r, where ALG2 converges whatever the statuses.
    pub(super) fn after_cycle(
        &self,
        held: &[Held],
        cycled: &[(bool, bool)],
        frictional: bool,
        (r, mesh_stiffness): (f64, f64),
    ) -> Augmentation {
        let mut aug = Augmentation::uniform(held.len(), r);
        for (i, (&h, &(any, normal))) in held.iter().zip(cycled).enumerate() {
            let settled = self.tuned(h, frictional, r, mesh_stiffness, Rules::SETTLED);
            if !h.n {
                if !any {
                    (aug.r_n[i], aug.r_t[i]) = settled;
                }
                continue;
            }
            if !normal {
                aug.r_n[i] = settled.0;
            }
            if frictional {
                aug.r_t[i] = r.max(self.held_tangent_floor * mesh_stiffness);
            }
        }
        aug
    }

    /// The retune the history asks for, if any: the normals at every sweep where one is
    /// off the r its status asks for; every direction once the last `settled_sweeps`
    /// (+ 1 with friction) sweeps changed no status; the last retune once the budget is
    /// spent or the statuses cycle; none above `max_retune_dofs` or once back at the
    /// reference r. With friction the free directions not yet lowered ask for the
    /// settled retune too once some node is pressed.
    pub(super) fn retuned(
        &self,
        history: &[Sweep],
        frictional: bool,
        n_contact: usize,
    ) -> Option<Retune> {
        let last = history.last()?;
        if 2 * n_contact > self.max_retune_dofs || last.retunes >= self.max_retunes {
            return None;
        }
        let off_reference = last.stiff + last.soft > 0;
        if last.retunes + 1 == self.max_retunes {
            return off_reference.then_some(Retune::BudgetSpent);
        }
        if last.retunes > 0 && !off_reference {
            return None;
        }
        if let Some(since) = self.cycle_start(history) {
            return off_reference.then_some(Retune::EndCycle { since });
        }
        if last.mistuned_n > 0 {
            return Some(Retune::Normals);
        }
        let settled = self.settled_sweeps + usize::from(frictional);
        let wanted = last.mistuned > 0 || (frictional && last.active > 0 && last.unsettled > 0);
        if !wanted || history.len() < settled {
            return None;
        }
        let tail = &history[history.len() - settled..];
        tail.iter()
            .all(|s| s.changed == 0 && s.retunes == last.retunes)
            .then_some(Retune::ToStatus)
    }

    /// Where the retunes cycle, the sweep where the cycle began: the last sweep's statuses
    /// ([`Sweep::pattern`]) are a set that earlier retunes were made from and left
    /// `cycle_returns` times; the cycle began at the first of those retunes. A retune
    /// made twice from one set in a row (the normals', then the settled one) counts once.
    fn cycle_start(&self, history: &[Sweep]) -> Option<usize> {
        let last = history.last()?;
        // The statuses each retune was made from, with its sweep, repeats in a row merged.
        let mut from: Vec<(u64, usize)> = Vec::new();
        for w in history.windows(2) {
            if w[1].retunes > w[0].retunes && from.last().map(|f| f.0) != Some(w[0].pattern) {
                from.push((w[0].pattern, w[0].iter));
            }
        }
        let mut visits = from.iter().filter(|f| f.0 == last.pattern);
        let first = visits.next()?.1;
        // Still on the set the last retune was made from: that visit is not a return.
        let returns = match from.last().map(|f| f.0) == Some(last.pattern) {
            true => visits.count(),
            false => visits.count() + 1,
        };
        (returns >= self.cycle_returns).then_some(first)
    }

    /// Whether to retune for the slow tail ([`Retune::Tail`]): the r in force settled,
    /// not the tail's nor a cycle's end, tail retunes left; the last `tail_sweeps` sweeps
    /// changed no status and were made with this r, which their statuses ask for; the
    /// plain map contracts by `tail_contraction` or more; and not the budget's last
    /// retune. The tail's r holds until a status changes.
    pub(super) fn tail(&self, history: &[Sweep], state: &AdaptiveState) -> bool {
        let Some(last) = history.last() else {
            return false;
        };
        let rules = state.rules;
        if !rules.settled || rules.tail || state.ended || state.tails >= self.max_tail_retunes {
            return false;
        }
        if last.retunes + 2 > self.max_retunes
            || last.mistuned > 0
            || history.len() < self.tail_sweeps
        {
            return false;
        }
        let quiet = history[history.len() - self.tail_sweeps..]
            .iter()
            .all(|s| s.changed == 0 && s.retunes == last.retunes);
        quiet && last.contraction >= self.tail_contraction
    }
}

/// Whether the tangents follow their stick/slip statuses at each retune, as the normals
/// do: where the slip thresholds are fixed (Tresca), the tangential problem is a bound on
/// a force that does not move, like the normal one; not while at most one node is pressed
/// (the open nodes' thresholds alone hold the body along the foundation), nor once the
/// retunes have cycled with them.
pub(super) fn tangents_follow(fixed_thresholds: bool, pressed_nodes: usize, cycled: bool) -> bool {
    fixed_thresholds && pressed_nodes >= 2 && !cycled
}

/// Node i's key for [`status_tag`]: a hash of its weight, gap, position and normal, the
/// same on every rank.
fn node_key(nodes: &ContactNodes, i: usize) -> u64 {
    let [mx, my] = nodes.normal.get(i).copied().unwrap_or_default();
    let at = |v: &[f64]| v.get(i).copied().unwrap_or_default().to_bits();
    [
        at(&nodes.w),
        at(&nodes.g),
        at(&nodes.s),
        mx.to_bits(),
        my.to_bits(),
    ]
    .into_iter()
    .fold(0x9e37_79b9_7f4a_7c15, mix)
}

/// splitmix64's finaliser over `h` and the next word.
fn mix(h: u64, word: u64) -> u64 {
    let mut h = (h ^ word).wrapping_add(0x9e37_79b9_7f4a_7c15);
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^ (h >> 31)
}

/// A node's share of a sweep's status fingerprint ([`Sweep::pattern`]): a 20-bit whole
/// number hashed from the node's key and its status, so that a sum over up to 2^33
/// nodes stays exact in an f64, and two sets of statuses that differ at a few nodes give
/// the same sum with a chance of about 2^-20.
fn status_tag(key: u64, held: Held) -> f64 {
    let code = u64::from(held.n) | u64::from(held.t) << 1 | u64::from(held.loose) << 2;
    (mix(key, code) >> 44) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::sweep::Derived;

    /// An open node under Coulomb: no threshold, its tangent carries no force.
    const OPEN: Held = Held {
        n: false,
        t: false,
        loose: true,
    };

    /// The moving zone's rules, tangents not following.
    const MOVING: Rules = Rules {
        settled: false,
        follow_tangents: false,
        tail: false,
    };

    fn p() -> AdaptiveParams {
        AdaptiveParams::default()
    }

    fn sweep(changed: usize, mistuned: usize, retunes: usize) -> Sweep {
        Sweep {
            iter: 1,
            pressure: 1e-3,
            traction: 1e-3,
            displacement: 1e-3,
            contraction: 0.5,
            error: 2e-3,
            active: 5,
            changed,
            mistuned,
            retunes,
            ..Default::default()
        }
    }

    /// Sweeps with statuses `p`, each followed by a retune, r off the reference.
    fn cycling(patterns: &[u64]) -> Vec<Sweep> {
        (patterns.iter().enumerate())
            .map(|(k, &p)| Sweep {
                iter: k + 1,
                pattern: p,
                stiff: 3,
                mistuned_n: 1,
                ..sweep(1, 1, k)
            })
            .collect()
    }

    #[test]
    fn statuses_that_the_retunes_keep_returning_to_end_the_retunes() {
        let p = p();
        // Two sets in turn: the fourth visit of one is its third return.
        assert_eq!(
            p.retuned(&cycling(&[1, 2, 1, 2, 1, 2]), true, 5),
            Some(Retune::Normals)
        );
        let cycle = cycling(&[3, 1, 2, 1, 2, 1, 2, 1]);
        // The cycle began at the first retune made from the set returned to.
        assert_eq!(
            p.retuned(&cycle, true, 5),
            Some(Retune::EndCycle { since: 2 })
        );
        // A retune made twice from one set in a row (normals, then settled) is one visit.
        let settling = cycling(&[1, 1, 2, 2, 1, 1, 3, 1, 1]);
        assert_eq!(p.retuned(&settling, true, 5), Some(Retune::Normals));
        // Back at the reference r, no retune again.
        let mut back = cycle.clone();
        back.push(Sweep {
            stiff: 0,
            ..back[back.len() - 1]
        });
        back.last_mut().unwrap().retunes += 1;
        assert_eq!(p.retuned(&back, true, 5), None);
        // Tuned to count more returns, the same history is no cycle yet.
        let patient = AdaptiveParams {
            cycle_returns: 4,
            ..p
        };
        assert_eq!(patient.retuned(&cycle, true, 5), Some(Retune::Normals));
    }

    /// The policy on `n` contact nodes (no mesh stiffness known).
    fn adaptive(n: usize) -> Adaptive {
        let nodes = ContactNodes {
            w: vec![1.0; n],
            g: vec![0.0; n],
            s: (0..n).map(|i| i as f64).collect(),
            ..Default::default()
        };
        Adaptive::new(p(), &nodes, f64::NAN)
    }

    #[test]
    fn a_cycle_ends_the_retunes_for_good() {
        let mut policy = adaptive(2);
        let last = Derived {
            p: vec![0.0, -1.0],
            lambda: vec![1.0, 0.0],
            q: vec![0.0; 2],
            mu: vec![0.0; 2],
            threshold: vec![0.0; 2],
        };
        let history = cycling(&[3, 1, 2, 1, 2, 1, 2, 1]);
        let image = Image {
            history: &history,
            last: &last,
            law: Law::Coulomb(&[0.3, 0.3]),
            n_contact: 2,
            r_ref: 10.0,
        };
        assert!(policy.retune(&image).is_some());
        let PolicyState::Adaptive(s) = policy.state() else {
            panic!("not the adaptive state")
        };
        assert!(s.ended && s.rules == Rules::SETTLED);
        assert_eq!(policy.retune(&image), None);
        // Under Tresca a cycle with the tangents following is not the end: they stop
        // following, and the retunes take the settled rules.
        let mut tresca = adaptive(2);
        let image = Image {
            law: Law::Fixed(&[1.0, 1.0]),
            ..image
        };
        assert!(tresca.retune(&image).is_some());
        let PolicyState::Adaptive(s) = tresca.state() else {
            panic!("not the adaptive state")
        };
        assert!(!s.ended && s.rules.settled);
        assert_eq!(s.tangents_cycled_at, Some(history.len()));
    }

    #[test]
    fn the_state_goes_through_the_checkpoint_whole() {
        let mut a = adaptive(3);
        a.seen(4, &[OPEN; 3], &[OPEN, Held::new(true, false), OPEN]);
        let saved = a.state();
        let mut b = adaptive(3);
        b.restore(saved.clone()).unwrap();
        assert_eq!(b.state(), saved);
        assert_eq!(
            b.changed_since(3),
            vec![(false, false), (true, true), (false, false)]
        );
        assert!(b.restore(PolicyState::Fixed).is_err());
    }

    #[test]
    fn normals_follow_their_statuses_at_once() {
        let p = p();
        let mut moving = sweep(3, 4, 0);
        moving.mistuned_n = 2;
        // Even while statuses change, with or without friction.
        assert_eq!(p.retuned(&[moving], false, 5), Some(Retune::Normals));
        assert_eq!(p.retuned(&[moving], true, 5), Some(Retune::Normals));
        // Not above the dofs whose first retune costs more than it saves.
        assert_eq!(p.retuned(&[moving], false, p.max_retune_dofs), None);
    }

    #[test]
    fn tangents_are_tuned_once_the_statuses_have_settled() {
        let p = p();
        // Normals right, tangents not (mistuned counts both kinds).
        let (moving, still) = (sweep(2, 5, 0), sweep(0, 5, 0));
        assert_eq!(p.retuned(&[moving, still], true, 5), None);
        assert_eq!(
            p.retuned(&[moving, still, still], true, 5),
            Some(Retune::ToStatus)
        );
        assert_eq!(p.retuned(&[still, moving], true, 5), None);
        // Nothing to change.
        assert_eq!(
            p.retuned(&[still, sweep(0, 0, 0), sweep(0, 0, 0)], true, 5),
            None
        );
        // The settled sweeps must all be with the current r.
        let after = Sweep {
            stiff: 3,
            ..sweep(0, 3, 1)
        };
        assert_eq!(p.retuned(&[still, after], true, 5), None);
        assert_eq!(
            p.retuned(&[still, after, after], true, 5),
            Some(Retune::ToStatus)
        );
    }

    #[test]
    fn free_directions_settle_once_the_body_touches_with_friction() {
        let p = p();
        // Nothing mistuned (every pressed node slips), but free directions not yet
        // lowered: settle once some node is pressed and the statuses rest.
        let mut still = sweep(0, 0, 0);
        still.unsettled = 4;
        assert_eq!(
            p.retuned(&[still, still, still], true, 5),
            Some(Retune::ToStatus)
        );
        // Not without friction, nor before the first touch.
        assert_eq!(p.retuned(&[still, still, still], false, 5), None);
        still.active = 0;
        assert_eq!(p.retuned(&[still, still, still], true, 5), None);
    }

    #[test]
    fn held_directions_are_at_least_as_stiff_as_the_mesh_asks() {
        let p = p();
        // A reference r lowered far below the mesh-scale stiffness (a slender body):
        // held directions rise to their floors, free ones stay below the reference.
        let (r, k) = (1.0, 1e6);
        let (n, t) = p.tuned(Held::new(true, true), true, r, k, MOVING);
        assert_eq!((n, t), (p.held_normal_floor * k, p.held_tangent_floor * k));
        assert_eq!(
            p.tuned(Held::new(false, false), true, r, k, MOVING),
            (r / p.normal_factor, r / p.tangent_factor)
        );
        // A compact body's reference r: the factors already exceed the floors.
        let r = 1e5;
        assert_eq!(
            p.tuned(Held::new(true, true), true, r, 1e6, MOVING),
            (r * p.normal_factor, r * p.tangent_factor)
        );
        assert_eq!(p.largest_tuned(r, 1e6), r * p.normal_factor);
        assert_eq!(p.largest_tuned(1.0, 1e6), p.held_normal_floor * 1e6);
        // Without friction the tangent keeps the reference r, floor or not.
        assert_eq!(p.tuned(Held::new(true, true), false, 1.0, k, MOVING).1, 1.0);
    }

    #[test]
    fn after_the_budget_every_direction_returns_once_to_the_reference() {
        let p = p();
        let mut spent = sweep(1, 3, p.max_retunes - 1);
        spent.mistuned_n = 3;
        spent.stiff = 2;
        assert_eq!(
            p.retuned(&[spent, spent], false, 5),
            Some(Retune::BudgetSpent)
        );
        // Already at the reference r: nothing to undo.
        spent.stiff = 0;
        assert_eq!(p.retuned(&[spent, spent], false, 5), None);
        let mut reset = sweep(1, 3, p.max_retunes);
        reset.mistuned_n = 3;
        assert_eq!(p.retuned(&[reset, reset], false, 5), None);
        // A smaller budget is spent sooner.
        let small = AdaptiveParams {
            max_retunes: 5,
            ..p
        };
        let mut early = sweep(1, 3, 4);
        (early.mistuned_n, early.stiff) = (3, 2);
        assert_eq!(
            small.retuned(&[early, early], false, 5),
            Some(Retune::BudgetSpent)
        );
    }

    #[test]
    fn free_directions_are_lowered_further_once_settled() {
        let p = p();
        let r = 10.0;
        // While the zone moves: the normal / 1000, the tangent as slipping.
        let moving = (r / p.normal_factor, r / p.tangent_factor);
        assert_eq!(p.tuned(OPEN, true, r, 0.0, MOVING), moving);
        let settled = r / p.settled_free_factor;
        assert_eq!(
            p.tuned(OPEN, true, r, 0.0, Rules::SETTLED),
            (settled, settled)
        );
        // An open node slipping under Tresca: its force is the threshold, its motion
        // free, so its tangent goes as low.
        let open_tresca = Held::new(false, false);
        assert_eq!(p.tuned(open_tresca, true, r, 0.0, MOVING), moving);
        assert_eq!(
            p.tuned(open_tresca, true, r, 0.0, Rules::SETTLED),
            (settled, settled)
        );
        // Held directions, and a pressed node's slipping tangent, keep their factors; so
        // does an open node's sticking tangent.
        assert_eq!(
            p.tuned(Held::new(true, true), true, r, 0.0, Rules::SETTLED),
            (r * p.normal_factor, r * p.tangent_factor)
        );
        assert_eq!(
            p.tuned(Held::new(true, false), true, r, 0.0, Rules::SETTLED)
                .1,
            r / p.tangent_factor
        );
        assert_eq!(
            p.tuned(Held::new(false, true), true, r, 0.0, Rules::SETTLED),
            (settled, r * p.tangent_factor)
        );
        // Settling is what the tangents' retune does; the normals' keeps it.
        let held = [
            OPEN,
            Held::new(true, true),
            open_tresca,
            Held::new(true, false),
        ];
        let (a, rules) = p.for_statuses(Retune::Normals, &held, true, (r, 0.0), (false, false));
        assert_eq!(a.r_n[..2], [r / p.normal_factor, r * p.normal_factor]);
        assert_eq!(a.r_t, vec![r / p.tangent_factor; 4]);
        assert!(!rules.settled);
        let (a, rules) = p.for_statuses(Retune::ToStatus, &held, true, (r, 0.0), (false, false));
        assert!(rules.settled);
        assert_eq!(a.r_n[..2], [settled, r * p.normal_factor]);
        // From settled r, the normals' retune keeps the free directions lowered (the open
        // nodes' normals and tangents) and lowers the pressed nodes' tangents, sticking
        // or not, as while the zone moves.
        let (a, rules) = p.for_statuses(Retune::Normals, &held, true, (r, 0.0), (true, false));
        assert!(rules.settled);
        let held_n = r * p.normal_factor;
        assert_eq!(a.r_n, vec![settled, held_n, settled, held_n]);
        let loose = r / p.tangent_factor;
        assert_eq!(a.r_t, vec![settled, loose, settled, loose]);
        // What the sweep then counts as mistuned: only the sticking tangent.
        for (i, &h) in held.iter().enumerate() {
            let want = p.tuned(h, true, r, 0.0, rules);
            assert_eq!(want.0, a.r_n[i], "node {i}");
            assert_eq!(want.1 == a.r_t[i], i != 1, "node {i}");
        }
    }

    #[test]
    fn statuses_ask_for_their_r() {
        let p = p();
        let r = 10.0;
        assert_eq!(
            p.tuned(Held::new(true, false), true, r, 0.0, MOVING),
            (r * p.normal_factor, r / p.tangent_factor)
        );
        assert_eq!(
            p.tuned(Held::new(false, true), true, r, 0.0, MOVING),
            (r / p.normal_factor, r * p.tangent_factor)
        );
        // Without friction the tangent keeps the reference r.
        assert_eq!(
            p.tuned(Held::new(true, false), false, r, 0.0, MOVING),
            (r * p.normal_factor, r)
        );
        // Normals alone: tangents lowered with friction, kept without.
        let held = [Held::new(true, true), Held::new(false, true)];
        let (a, _) = p.for_statuses(Retune::Normals, &held, true, (r, 0.0), (false, false));
        assert_eq!(a.r_n, vec![r * p.normal_factor, r / p.normal_factor]);
        assert_eq!(a.r_t, vec![r / p.tangent_factor; 2]);
        let (a, _) = p.for_statuses(Retune::Normals, &held, false, (r, 0.0), (false, false));
        assert_eq!(a.r_t, vec![r; 2]);
    }

    #[test]
    fn tangents_that_follow_take_their_statuses_r_at_each_normals_retune() {
        let p = p();
        let r = 10.0;
        // Pressed sticking, pressed slipping, open sticking, open slipping (Tresca: every
        // node has its threshold).
        let held = [
            Held::new(true, true),
            Held::new(true, false),
            Held::new(false, true),
            Held::new(false, false),
        ];
        let moving_free = r / p.normal_factor;
        let (a, rules) = p.for_statuses(Retune::Normals, &held, true, (r, 0.0), (false, true));
        assert!(rules.follow_tangents && !rules.settled);
        let stick = r * p.tangent_factor;
        assert_eq!(a.r_t, vec![stick, r / p.tangent_factor, stick, moving_free]);
        // Not following: every tangent at r / 10 while the zone moves.
        let (b, _) = p.for_statuses(Retune::Normals, &held, true, (r, 0.0), (false, false));
        assert_eq!(b.r_t, vec![r / p.tangent_factor; 4]);
        assert_eq!(a.r_n, b.r_n);
        // Settled, the open slipping tangent lowered further, the others as before.
        let (c, _) = p.for_statuses(Retune::ToStatus, &held, true, (r, 0.0), (false, true));
        let settled = r / p.settled_free_factor;
        assert_eq!(c.r_t, vec![stick, r / p.tangent_factor, stick, settled]);
        // What the sweep counts as mistuned follows the same rules: nothing here.
        for (i, &h) in held.iter().enumerate() {
            assert_eq!(
                p.tuned(h, true, r, 0.0, rules),
                (a.r_n[i], a.r_t[i]),
                "node {i}"
            );
        }
        // A flip to stick is a mistuned tangent for the next normals' retune.
        assert_ne!(
            p.tuned(Held::new(true, true), true, r, 0.0, rules).1,
            a.r_t[1]
        );
        // Without friction there is nothing to follow.
        let (d, rules) = p.for_statuses(Retune::Normals, &held, false, (r, 0.0), (false, true));
        assert!(!rules.follow_tangents);
        assert_eq!(d.r_t, vec![r; 4]);
    }

    #[test]
    fn only_fixed_thresholds_with_two_pressed_nodes_follow_until_a_cycle() {
        assert!(tangents_follow(true, 2, false));
        assert!(tangents_follow(true, 500, false));
        assert!(
            !tangents_follow(true, 1, false),
            "a body standing on one node"
        );
        assert!(!tangents_follow(true, 0, false), "a body in the air");
        assert!(!tangents_follow(false, 500, false), "Coulomb");
        assert!(!tangents_follow(true, 500, true), "after a cycle");
    }

    #[test]
    fn a_cycle_returns_its_changing_normals_to_the_reference_and_keeps_the_rest() {
        let p = p();
        let (r, stiffness) = (10.0, 1000.0);
        let held = [
            Held::new(true, true),
            OPEN,
            Held::new(true, false),
            OPEN,
            Held::new(true, false),
        ];
        // (any status, the normal) changed since the cycle began.
        let cycled = [
            (false, false),
            (false, false),
            (true, false),
            (true, true),
            (true, true),
        ];
        let a = p.after_cycle(&held, &cycled, true, (r, stiffness));
        let floor = p.held_tangent_floor * stiffness;
        let held_normal = p.tuned(held[2], true, r, stiffness, Rules::SETTLED).0;
        assert!(held_normal > r && floor > r);
        // Pressed nodes whose normal stayed pressed: held normal, tangent at the floor.
        assert_eq!((a.r_n[0], a.r_t[0]), (held_normal, floor));
        assert_eq!((a.r_n[2], a.r_t[2]), (held_normal, floor));
        // A node open through the cycle at its settled r.
        assert_eq!(
            (a.r_n[1], a.r_t[1]),
            p.tuned(OPEN, true, r, stiffness, Rules::SETTLED)
        );
        assert_eq!(a.r_n[1], r / p.settled_free_factor);
        // Normals that cycled at the reference r; an open node that cycled entirely so.
        assert_eq!((a.r_n[3], a.r_t[3]), (r, r));
        assert_eq!((a.r_n[4], a.r_t[4]), (r, floor));
        // Without friction the tangents are not used; below the floor's scale the
        // reference r stands.
        let b = p.after_cycle(&held, &cycled, false, (r, 0.0));
        assert_eq!(b.r_t, vec![r; 5]);
        assert_eq!(b.r_n[0], p.tuned(held[0], false, r, 0.0, Rules::SETTLED).0);
    }

    /// The state of a run whose r in force was made by `rules`, after `tails` tail retunes.
    fn made_by(rules: Rules, tails: usize) -> AdaptiveState {
        AdaptiveState {
            rules,
            tails,
            ..AdaptiveState::new(0)
        }
    }

    #[test]
    fn the_slow_tail_widens_the_tangents_and_free_factors_until_a_status_changes() {
        let p = p();
        let r = 10.0;
        let tail_rules = Rules {
            tail: true,
            ..Rules::SETTLED
        };
        let pressed_sticking = Held::new(true, true);
        let (n, t) = p.tuned(pressed_sticking, true, r, 0.0, Rules::SETTLED);
        assert_eq!(
            p.tuned(pressed_sticking, true, r, 0.0, tail_rules),
            (n, t * p.tail_factor),
            "the held normal keeps its r: it sets the round-off"
        );
        // The tangent's floor is widened too, up to the held normals' r, which sets the
        // round-off.
        let stiff = 1e3;
        let (_, t) = p.tuned(pressed_sticking, true, r, stiff, Rules::SETTLED);
        assert_eq!(t, p.held_tangent_floor * stiff);
        assert_eq!(
            p.tuned(pressed_sticking, true, r, stiff, tail_rules).1,
            t * p.tail_factor
        );
        let very_stiff = 1e6;
        let largest = p.largest_tuned(r, very_stiff);
        assert_eq!(
            p.tuned(pressed_sticking, true, r, very_stiff, tail_rules),
            (largest, largest)
        );
        let settled = r / p.settled_free_factor;
        assert_eq!(
            p.tuned(OPEN, true, r, 0.0, tail_rules),
            (settled / p.tail_factor, settled / p.tail_factor)
        );
        // A pressed node's slipping tangent keeps r / 10: its threshold follows the
        // pressure.
        let pressed_slipping = Held::new(true, false);
        assert_eq!(
            p.tuned(pressed_slipping, true, r, 0.0, tail_rules).1,
            r / p.tangent_factor
        );
        // Not while the zone moves.
        let moving_tail = Rules {
            tail: true,
            ..MOVING
        };
        assert_eq!(
            p.tuned(OPEN, true, r, 0.0, moving_tail),
            p.tuned(OPEN, true, r, 0.0, MOVING)
        );

        let held = [pressed_sticking, OPEN];
        let (settled_aug, settled_rules) =
            p.for_statuses(Retune::ToStatus, &held, true, (r, 0.0), (false, false));
        let slow = |changed: usize, retunes: usize| Sweep {
            contraction: 0.9,
            ..sweep(changed, 0, retunes)
        };
        let quiet = [slow(3, 4), slow(0, 5), slow(0, 5)];
        assert!(p.tail(&quiet, &made_by(settled_rules, 0)));
        assert!(
            !p.tail(&quiet, &made_by(settled_rules, p.max_tail_retunes)),
            "the allowance spent"
        );
        assert!(
            !p.tail(&quiet[..2], &made_by(settled_rules, 0)),
            "one quiet sweep only"
        );
        assert!(
            !p.tail(&[slow(0, 4), slow(0, 5)], &made_by(settled_rules, 0)),
            "the sweep before was made with another r"
        );
        let fast = [slow(3, 4), sweep(0, 0, 5), sweep(0, 0, 5)];
        assert!(
            !p.tail(&fast, &made_by(settled_rules, 0)),
            "contracting by 0.5"
        );
        let mistuned = [
            slow(3, 4),
            slow(0, 5),
            Sweep {
                mistuned: 2,
                ..slow(0, 5)
            },
        ];
        assert!(!p.tail(&mistuned, &made_by(settled_rules, 0)));
        let (_, moving) = p.for_statuses(Retune::Normals, &held, true, (r, 0.0), (false, false));
        assert!(!p.tail(&quiet, &made_by(moving, 0)), "not settled");
        let (in_tail, tail) = p.for_statuses(Retune::Tail, &held, true, (r, 0.0), (true, false));
        assert!(tail.tail && tail.settled);
        assert!(!p.tail(&quiet, &made_by(tail, 1)), "already the tail's r");
        assert_eq!(in_tail.r_n[0], settled_aug.r_n[0]);
        assert_eq!(in_tail.r_t[0], settled_aug.r_t[0] * p.tail_factor);
        assert_eq!(in_tail.r_n[1], settled_aug.r_n[1] / p.tail_factor);
        // A status change: the normals' retune that follows is not the tail's.
        let (after, rules) = p.for_statuses(Retune::Normals, &held, true, (r, 0.0), (true, false));
        assert!(!rules.tail);
        assert_eq!(after.r_n[1], settled_aug.r_n[1]);
        // The budget's last retune stays the return to the reference r.
        let late = [slow(0, p.max_retunes - 1), slow(0, p.max_retunes - 1)];
        assert!(!p.tail(&late, &made_by(settled_rules, 0)));
    }
}
