//! One sweep of ALG2 (docs/ALGORITHM.md) from a state x, the map x -> G(x) of
//! [`super::uzawa`]: the method's three steps at this rank's contact nodes, and the local
//! sums that the sweep's one all-reduce turns into its line of the history.

use super::kernels::{coulomb_threshold, project_normal, shrink, state, update_multiplier};
use super::{ContactNodes, LinearStep, Reduce};
use crate::error::Result;

/// One line of the convergence history (one linear solve).
///
/// The three changes are what one sweep moved the reported quantities, each relative to
/// its own size (see `SweepSums::changes`); `error` is their largest, divided by
/// 1 - `contraction`: the estimated relative error of the reported answer, which the loop
/// stops on (`error <= tol`).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sweep {
    pub iter: usize,
    /// |lambda+ - lambda|_W / |lambda+|_W: the contact pressure p_n.
    pub pressure: f64,
    /// |mu+ - mu|_W / |mu+|_W: the tangential traction p_t (0 without friction).
    pub traction: f64,
    /// |G(x) - x|_W / (|Nu|_W + |Tu|_W): the displacement at the contact nodes.
    pub displacement: f64,
    /// The estimated contraction factor of the plain sweep (0 until two points are known).
    pub contraction: f64,
    /// max(pressure, traction, displacement) / (1 - contraction).
    pub error: f64,
    pub active: usize,
    /// Active nodes that slip (0 without friction: there is no stick or slip then).
    pub slip: usize,
    /// Contact nodes whose status (free, stick, slip) in the image of this sweep differs
    /// from the one in the image of the sweep before.
    pub changed: usize,
    /// Contact directions (normal and, with friction, tangential) whose r in this
    /// sweep's linear step is raised above the reference r, and lowered below it.
    pub stiff: usize,
    pub soft: usize,
    /// The adaptive policy's counts (`adaptive::Adaptive::count`; 0 under a given r):
    /// directions whose r differs from what their status asks for; nodes whose normal is
    /// among them, or whose tangent is while the tangents follow their statuses; and
    /// directions whose r differs from what the settled statuses' retune would give.
    pub mistuned: usize,
    pub mistuned_n: usize,
    pub unsettled: usize,
    /// Contact nodes whose status could still flip: the state of a direction lies closer
    /// to its status boundary (the gap, the slip threshold) than the estimated error of
    /// the sweep before.
    pub uncertain: usize,
    /// A fingerprint of the statuses in this sweep's image, the same whatever the ranks,
    /// for the adaptive policy's test of a cycle (0 under a given r).
    pub pattern: u64,
    /// Retunes of r before this sweep.
    pub retunes: usize,
    /// Accelerated points the safeguard refused so far, this sweep's included (a sweep
    /// that evaluated a refused point counts it).
    pub refused: usize,
    /// The round-off floor, relative as the three changes are, of the quantities whose
    /// change in this sweep was below their round-off and counted as none (0 where no
    /// change was hidden): the accuracy the run can confirm at best
    /// ([`SweepSums::changes`]).
    pub roundoff: f64,
}

/// The augmentation parameter of each contact direction on this rank: ALG2 converges
/// for any positive r per direction (it is the method in a rescaled constraint).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Augmentation {
    pub(super) r_n: Vec<f64>,
    pub(super) r_t: Vec<f64>,
}

impl Augmentation {
    /// The reference r in every direction of n contact nodes.
    pub(super) fn uniform(n: usize, r: f64) -> Self {
        Augmentation {
            r_n: vec![r; n],
            r_t: vec![r; n],
        }
    }
}

/// What holds a contact node's directions, as its status in an image says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Held {
    /// The normal: pressed onto the foundation.
    pub(super) n: bool,
    /// The tangent (with friction): sticking, below a positive slip threshold.
    pub(super) t: bool,
    /// The tangent (with friction) has a zero slip threshold (an open node under
    /// Coulomb, a frictionless contact among frictional ones): no force acts on it.
    pub(super) loose: bool,
}

impl Held {
    #[cfg(test)]
    pub(super) fn new(n: bool, t: bool) -> Self {
        Held { n, t, loose: false }
    }

    /// Whether only its spring holds the tangent's motion: a loose one, and an open
    /// node's slipping one, whose force is a threshold no normal force sets.
    pub(super) fn free_tangent(self) -> bool {
        self.loose || (!self.n && !self.t)
    }
}

/// The slip thresholds seen by one run of sweeps.
#[derive(Clone, Copy)]
pub(super) enum Law<'a> {
    Frictionless,
    Fixed(&'a [f64]),
    /// The coefficient of each node.
    Coulomb(&'a [f64]),
    /// Tresca and Coulomb contacts in one run: s_i = fixed_i + coefficient_i p_n,i.
    Mixed {
        fixed: &'a [f64],
        coefficient: &'a [f64],
    },
}

impl Law<'_> {
    pub(super) fn frictional(&self) -> bool {
        !matches!(self, Law::Frictionless)
    }

    /// Whether an open node may carry a slip threshold (Tresca, mixed): such thresholds
    /// hold a body along the foundation before it touches, so no glide crosses the air.
    pub(super) fn holds_open_nodes(&self) -> bool {
        matches!(self, Law::Fixed(_) | Law::Mixed { .. })
    }

    fn threshold(&self, i: usize, lambda: f64) -> f64 {
        match *self {
            Law::Frictionless => 0.0,
            Law::Fixed(s) => s[i],
            Law::Coulomb(c) => coulomb_threshold(c[i], lambda),
            Law::Mixed { fixed, coefficient } => {
                fixed[i] + coulomb_threshold(coefficient[i], lambda)
            }
        }
    }
}

/// Multipliers and auxiliary variables of a state (see [`project_and_update`]).
pub(super) struct Derived {
    pub(super) p: Vec<f64>,
    pub(super) lambda: Vec<f64>,
    pub(super) q: Vec<f64>,
    pub(super) mu: Vec<f64>,
    /// The slip threshold s_f of each node (0 without friction).
    pub(super) threshold: Vec<f64>,
}

impl Derived {
    /// Whether node i's normal and tangential directions are held: pressed onto the
    /// foundation, and sticking (with friction).
    pub(super) fn held(&self, i: usize, frictional: bool) -> Held {
        let loose = frictional && self.threshold[i] <= 0.0;
        Held {
            n: self.lambda[i] > 0.0,
            t: frictional && !loose && self.q[i] == 0.0,
            loose,
        }
    }

    pub(super) fn statuses(&self, frictional: bool) -> Vec<Held> {
        (0..self.p.len())
            .map(|i| self.held(i, frictional))
            .collect()
    }
}

/// Steps 2 and 3 of ALG2 at every node, from the states x = (s, z) (s = Nu + lambda / r,
/// z = Tu + mu / r): 2. the projection p = min(g, s) and the shrinkage
/// q = shrink(z, s_f / r); 3. the multiplier updates lambda = r (s - p), mu = r (z - q).
pub(super) fn project_and_update(
    x: &[f64],
    nodes: &ContactNodes,
    law: Law,
    aug: &Augmentation,
) -> Derived {
    let n = nodes.len();
    let mut d = Derived {
        p: vec![0.0; n],
        lambda: vec![0.0; n],
        q: vec![0.0; n],
        mu: vec![0.0; n],
        threshold: vec![0.0; n],
    };
    for i in 0..n {
        let s = x[i];
        d.p[i] = project_normal(nodes.g[i], s);
        d.lambda[i] = update_multiplier(aug.r_n[i], s, d.p[i]);
        if law.frictional() {
            let z = x[n + i];
            d.threshold[i] = law.threshold(i, d.lambda[i]);
            d.q[i] = shrink(z, d.threshold[i] / aug.r_t[i]);
            d.mu[i] = update_multiplier(aug.r_t[i], z, d.q[i]);
        }
    }
    d
}

/// Declares [`SweepSums`], its fields in the order of the all-reduce, and its packing.
macro_rules! sweep_sums {
    ($($(#[$doc:meta])* $field:ident,)*) => {
        /// The sums of one sweep over this rank's contact nodes (over all ranks once
        /// reduced): squared W-norms of the reported quantities and of their changes over
        /// the sweep, each in its own units (forces per unit length for the multipliers,
        /// lengths for the displacements), whatever the r of each direction; the counts
        /// are floats only to travel in the same all-reduce.
        #[derive(Debug, Clone, Copy, Default, PartialEq)]
        pub(super) struct SweepSums {
            $($(#[$doc])* pub(super) $field: f64,)*
        }

        impl SweepSums {
            /// The numbers [`SweepSums::pack`] puts in the all-reduce.
            pub(super) const LEN: usize = [$(stringify!($field)),*].len();

            pub(super) fn pack(&self) -> [f64; Self::LEN] {
                [$(self.$field),*]
            }

            pub(super) fn unpack(v: [f64; Self::LEN]) -> Self {
                let [$($field),*] = v;
                SweepSums { $($field),* }
            }
        }
    };
}

sweep_sums! {
    /// |lambda+ - lambda|^2 and |mu+ - mu|^2: the change of p_n and p_t.
    force_change_n,
    force_change_t,
    /// |G(x) - x|^2 per direction: the change of the state s = Nu + lambda / r, a
    /// displacement, which bounds both the move of p and the constraint's violation
    /// Nu - p+ = (lambda+ - lambda) / r.
    state_change_n,
    state_change_t,
    /// |Nu|^2 and |Tu|^2.
    displacement_n,
    displacement_t,
    /// |lambda+|^2 and |mu+|^2.
    force_n,
    force_t,
    /// The counts of [`Sweep`].
    active,
    slip,
    changed,
    stiff,
    soft,
    mistuned,
    uncertain,
    mistuned_n,
    unsettled,
    /// The sum of the nodes' status tags: whole numbers, exact in the all-reduce's sum.
    pattern,
}

/// The floor of each quantity's scale, a fraction of the other quantities of its kind (a
/// force's is the other force, u's the forces over r): where a quantity vanishes (p_t by
/// symmetry) relative accuracy would ask for digits that the others' round-off does not
/// leave; a thousandth keeps the floor far below every quantity that matters.
pub const SCALE_FLOOR: f64 = 1e-3;

/// The round-off of one sweep, relative to its largest forces (r |u| and the
/// multipliers): sixteen units of round-off. A change below it cannot be told from the
/// noise of the solve, so it counts as none.
pub const ROUNDOFF: f64 = 16.0 * f64::EPSILON;

impl SweepSums {
    /// Whether every norm is finite (no NaN, no overflow).
    pub(super) fn finite(&self) -> bool {
        self.pack()[..8].iter().all(|v| v.is_finite())
    }

    /// The relative changes (p_n, p_t, u) of the sweep: each quantity's change over its
    /// own size plus [`SCALE_FLOOR`] times the other force (p_n, p_t), or the forces
    /// over the reference r `r` (u); and the round-off floor of the sweep
    /// ([`Sweep::roundoff`]) for a plain sweep contracting by `contraction`. `r_raised`
    /// is the largest r of a direction raised above `r`.
    pub(super) fn changes(&self, (r, r_raised): (f64, f64), contraction: f64) -> ([f64; 3], f64) {
        let (pn, pt) = (self.force_n.sqrt(), self.force_t.sqrt());
        let u = self.displacement_n.sqrt() + self.displacement_t.sqrt();
        // The sweep's forces are formed from r u and the multipliers, with the largest r
        // where some direction is raised: a force change below their round-off is noise.
        let r_max = if self.stiff > 0.0 { r_raised } else { r };
        let noise = ROUNDOFF * (pn + pt + r_max * u);
        // (change, its noise, its scale) of p_n, p_t and u. The forces' floors are
        // forces: r u (a length times the augmentation) is no scale of p_n or p_t.
        let quantities = [
            (self.force_change_n.sqrt(), noise, pn + SCALE_FLOOR * pt),
            (self.force_change_t.sqrt(), noise, pt + SCALE_FLOOR * pn),
            (
                self.state_change_n.sqrt() + self.state_change_t.sqrt(),
                noise / r,
                u + SCALE_FLOOR * (pn + pt) / r,
            ),
        ];
        let changes =
            quantities.map(|(change, noise, scale)| relative((change - noise).max(0.0), scale));
        // The floor of each quantity whose change round-off hid (an exact fixed point
        // hides nothing): the noise, or what the hidden change may leave of the error,
        // change / (1 - rho), where the loop contracts slowly.
        let floor = quantities
            .iter()
            .filter(|&&(change, noise, _)| change > 0.0 && change <= noise)
            .map(|&(change, noise, scale)| {
                relative(noise, scale).max(error_estimate(relative(change, scale), contraction))
            })
            .fold(0.0, f64::max);
        (changes, floor)
    }

    /// The history line of sweep `iter` from the global sums, with the reference r and
    /// the largest raised r (see [`SweepSums::changes`]) and the estimated `contraction`
    /// of the plain sweep.
    pub(super) fn sweep(
        &self,
        iter: usize,
        retunes: usize,
        r: (f64, f64),
        contraction: f64,
    ) -> Sweep {
        let ([pressure, traction, displacement], roundoff) = self.changes(r, contraction);
        Sweep {
            iter,
            pressure,
            traction,
            displacement,
            contraction,
            error: error_estimate(pressure.max(traction).max(displacement), contraction),
            active: self.active as usize,
            slip: self.slip as usize,
            changed: self.changed as usize,
            stiff: self.stiff as usize,
            soft: self.soft as usize,
            mistuned: self.mistuned as usize,
            mistuned_n: self.mistuned_n as usize,
            unsettled: self.unsettled as usize,
            uncertain: self.uncertain as usize,
            pattern: self.pattern as u64,
            retunes,
            refused: 0,
            roundoff,
        }
    }
}

/// A warning when round-off, not `tol`, bounds the accuracy of the run that ended with
/// `last`: its changes below [`Sweep::roundoff`] were noise and counted as none, so the
/// loop could not confirm `tol`.
pub fn roundoff_warning(last: Option<&Sweep>, tol: f64) -> Option<String> {
    let last = last?;
    let (floor, rho) = (last.roundoff, last.contraction);
    (floor > tol).then(|| {
        format!(
            "round-off bounds the accuracy of this run to about {floor:.1e} (relative), above tol = {tol:e}: its last changes were below the sweep's round-off and count as noise, so the run cannot confirm tol; from that round-off and the loop's contraction (rho = {rho:.6}), p_n, p_t and u may be up to a few times {floor:.1e} from the exact discrete answer, a bound that can lie far above the actual error where rho is close to 1 (a tol of {:.0e} or more is within its reach)",
            4.0 * floor
        )
    })
}

/// The error left after a sweep that changed the answer by `change` (relative), when the
/// plain sweep contracts by `contraction`: for a map contracting by rho, the distance
/// from a point to the fixed point is at most |G(x) - x| / (1 - rho). No change (none
/// beyond round-off's noise) is a fixed point, whatever rho (a rho estimated at 1 from a
/// creep that has ended would otherwise keep the loop going).
pub fn error_estimate(change: f64, contraction: f64) -> f64 {
    if change == 0.0 {
        0.0
    } else if contraction >= 1.0 {
        f64::INFINITY
    } else {
        change / (1.0 - contraction.max(0.0))
    }
}

/// `value / scale`, or `value` itself when the scale is zero.
pub(super) fn relative(value: f64, scale: f64) -> f64 {
    if scale > 0.0 {
        value / scale
    } else {
        value
    }
}

/// What one sweep sums over all ranks, in its single all-reduce of
/// [`SweepSums::LEN`] + 4 + k(k + 2) numbers, k <= m the differences in the Anderson
/// memory: the sums, the residual, the secant's three norms and the Gram sums.
pub(super) struct Reduced {
    pub(super) sums: SweepSums,
    /// |G(x) - x|^2 in the norm of [`super::anderson::metric`].
    pub(super) residual2: f64,
    /// |y - x|^2 and |(G(y) - y) - (G(x) - x)|^2 in the same norm, between this point y
    /// and the last accepted one x (zeros without one): a secant of the sweep map.
    pub(super) secant2: [f64; 3],
    /// The Anderson Gram matrix and right-hand side ([`super::anderson::Anderson::local_sums_with_new`]),
    /// empty when not accelerating.
    pub(super) gram: Vec<f64>,
}

impl Reduced {
    /// Sums the local parts over all ranks, packed into one buffer.
    pub(super) fn all_reduce(
        comm: &impl Reduce,
        sums: &SweepSums,
        residual2: f64,
        secant2: [f64; 3],
        gram: Vec<f64>,
    ) -> Reduced {
        let mut buf = sums.pack().to_vec();
        buf.push(residual2);
        buf.extend(secant2);
        buf.extend(gram);
        comm.sum_in_place(&mut buf);
        let (head, tail) = buf.split_at(SweepSums::LEN);
        Reduced {
            // The split is at LEN: the conversion cannot fail.
            sums: SweepSums::unpack(head.try_into().expect("LEN sums")),
            residual2: tail[0],
            secant2: [tail[1], tail[2], tail[3]],
            gram: tail[4..].to_vec(),
        }
    }
}

/// One evaluation of G: its value, the quantities derived from it, and this rank's sums.
pub(super) struct Eval {
    pub(super) gx: Vec<f64>,
    /// G(x) - x.
    pub(super) f: Vec<f64>,
    pub(super) out: Derived,
    /// The statuses in the image.
    pub(super) now: Vec<Held>,
    pub(super) sums: SweepSums,
}

/// The sweep's working set on this rank: the linear step, the r of each direction, and
/// the buffers of the forces and of (Nu, Tu).
pub(super) struct Sweeper<'a, S: LinearStep> {
    pub(super) step: &'a mut S,
    pub(super) nodes: &'a ContactNodes,
    /// The reference r: the scale of the residuals, and the r of a direction not retuned.
    pub(super) r_ref: f64,
    pub(super) aug: Augmentation,
    /// The statuses in the image of the last evaluation (empty before the first).
    pub(super) last_held: Vec<Held>,
    /// How close (a length) a state may come to its status boundary before its status
    /// counts as uncertain: the estimated error of the last sweep.
    pub(super) margin: f64,
    force_n: Vec<f64>,
    force_t: Vec<f64>,
    pub(super) un: Vec<f64>,
    pub(super) ut: Vec<f64>,
}

impl<'a, S: LinearStep> Sweeper<'a, S> {
    /// A sweeper with the reference r in every direction.
    pub(super) fn new(step: &'a mut S, nodes: &'a ContactNodes, r: f64) -> Self {
        let n = nodes.len();
        Sweeper {
            step,
            nodes,
            r_ref: r,
            aug: Augmentation::uniform(n, r),
            last_held: Vec::new(),
            margin: f64::INFINITY,
            force_n: vec![0.0; n],
            force_t: vec![0.0; n],
            un: vec![0.0; n],
            ut: vec![0.0; n],
        }
    }

    /// One sweep of ALG2 from the state x, then this rank's sums of it (compared with
    /// the statuses of the last evaluation, which the caller then replaces).
    pub(super) fn eval(&mut self, x: &[f64], law: Law) -> Result<Eval> {
        let frictional = law.frictional();
        // (p, lambda, q, mu) of the state: steps 2 and 3 of the sweep that produced it.
        let inp = project_and_update(x, self.nodes, law, &self.aug);
        // 1. The linear step with the contact forces of (p, lambda) and (q, mu).
        self.linear_step(&inp)?;
        // 2. and 3. at the new states Nu + lambda / r, Tu + mu / r, which are G(x).
        let mut gx = vec![0.0; x.len()];
        self.new_states(&inp, frictional, &mut gx);
        let out = project_and_update(&gx, self.nodes, law, &self.aug);
        let f: Vec<f64> = gx.iter().zip(x).map(|(a, b)| a - b).collect();
        let now = out.statuses(frictional);
        let sums = self.local_sums(&inp, &out, &now, &f, frictional);
        Ok(Eval {
            gx,
            f,
            out,
            now,
            sums,
        })
    }

    /// Step 1: A u = F + N' w (r p - lambda) + T' w (r q - mu), seen as (Nu, Tu).
    fn linear_step(&mut self, inp: &Derived) -> Result<()> {
        let (w, aug) = (&self.nodes.w, &self.aug);
        for i in 0..w.len() {
            self.force_n[i] = w[i] * (aug.r_n[i] * inp.p[i] - inp.lambda[i]);
            self.force_t[i] = w[i] * (aug.r_t[i] * inp.q[i] - inp.mu[i]);
        }
        self.step
            .solve(&self.force_n, &self.force_t, &mut self.un, &mut self.ut)
    }

    /// The states s = Nu + lambda / r and (with friction) z = Tu + mu / r after step 1.
    fn new_states(&self, inp: &Derived, frictional: bool, gx: &mut [f64]) {
        let (n, aug) = (self.nodes.len(), &self.aug);
        for i in 0..n {
            gx[i] = state(self.un[i], inp.lambda[i], aug.r_n[i]);
            if frictional {
                gx[n + i] = state(self.ut[i], inp.mu[i], aug.r_t[i]);
            }
        }
    }

    /// How far node i's states lie from the boundaries of its statuses, as a length:
    /// g - p (open) or lambda / r_n (pressed) for the normal, |q| (slipping) or
    /// (s_f - |mu|) / r_t (sticking) for the tangent; the smaller of the two.
    fn status_margin(&self, d: &Derived, i: usize, frictional: bool) -> f64 {
        let aug = &self.aug;
        let normal = if d.lambda[i] > 0.0 {
            d.lambda[i] / aug.r_n[i]
        } else {
            self.nodes.g[i] - d.p[i]
        };
        if !frictional {
            return normal;
        }
        let tangent = if d.q[i] != 0.0 {
            d.q[i].abs()
        } else {
            (d.threshold[i] - d.mu[i].abs()) / aug.r_t[i]
        };
        normal.min(tangent)
    }

    /// This rank's sums of the sweep from `inp` to `out` (statuses `now`), whose state
    /// moved by `f`.
    fn local_sums(
        &self,
        inp: &Derived,
        out: &Derived,
        now: &[Held],
        f: &[f64],
        frictional: bool,
    ) -> SweepSums {
        let (w, r, aug) = (&self.nodes.w, self.r_ref, &self.aug);
        let n = w.len();
        let mut s = SweepSums::default();
        for i in 0..n {
            s.force_change_n += w[i] * (out.lambda[i] - inp.lambda[i]).powi(2);
            s.force_change_t += w[i] * (out.mu[i] - inp.mu[i]).powi(2);
            s.state_change_n += w[i] * f[i].powi(2);
            if frictional {
                s.state_change_t += w[i] * f[n + i].powi(2);
            }
            s.displacement_n += w[i] * self.un[i].powi(2);
            s.displacement_t += w[i] * self.ut[i].powi(2);
            s.force_n += w[i] * out.lambda[i].powi(2);
            s.force_t += w[i] * out.mu[i].powi(2);
            if out.lambda[i] > 0.0 {
                s.active += 1.0;
                if frictional && out.q[i] != 0.0 {
                    s.slip += 1.0;
                }
            }
            if self.status_margin(out, i, frictional) <= self.margin {
                s.uncertain += 1.0;
            }
            // The first sweep compares with the statuses of its input.
            let before = self.last_held.get(i).copied();
            if before.unwrap_or_else(|| inp.held(i, frictional)) != now[i] {
                s.changed += 1.0;
            }
            for have in [aug.r_n[i], aug.r_t[i]] {
                if have > r {
                    s.stiff += 1.0;
                } else if have < r {
                    s.soft += 1.0;
                }
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sweep_without_change_is_at_its_fixed_point_whatever_the_contraction() {
        assert_eq!(error_estimate(1e-6, 0.9), 1e-6 / (1.0 - 0.9));
        assert_eq!(error_estimate(1e-6, -0.5), 1e-6);
        assert_eq!(error_estimate(1e-6, 1.0), f64::INFINITY);
        for rho in [0.0, 0.5, 1.0] {
            assert_eq!(error_estimate(0.0, rho), 0.0, "rho {rho}");
        }
    }

    #[test]
    fn a_tangent_without_threshold_is_loose() {
        // Node 0 open under Coulomb (threshold 0), node 1 open under Tresca and stuck,
        // node 2 pressed and slipping.
        let d = Derived {
            p: vec![-1.0, -1.0, 0.0],
            lambda: vec![0.0, 0.0, 2.0],
            q: vec![0.3, 0.0, 0.1],
            mu: vec![0.0, 0.5, 1.0],
            threshold: vec![0.0, 1.0, 1.0],
        };
        assert_eq!(
            d.held(0, true),
            Held {
                n: false,
                t: false,
                loose: true
            }
        );
        assert_eq!(d.held(1, true), Held::new(false, true));
        assert_eq!(d.held(2, true), Held::new(true, false));
        // Without friction there is no tangent to hold or loosen.
        assert_eq!(d.held(0, false), Held::new(false, false));
    }

    #[test]
    fn sums_travel_by_name() {
        let v: [f64; SweepSums::LEN] = std::array::from_fn(|k| k as f64 + 0.5);
        let s = SweepSums::unpack(v);
        assert_eq!(s.pack(), v);
        assert_eq!((s.force_change_n, s.force_n), (0.5, 6.5));
        assert_eq!((s.active, s.uncertain), (8.5, 14.5));
    }

    #[test]
    fn round_off_above_tol_is_said() {
        let mut last = Sweep {
            iter: 9,
            active: 3,
            roundoff: 2e-8,
            ..Default::default()
        };
        assert_eq!(roundoff_warning(None, 1e-8), None);
        let w = roundoff_warning(Some(&last), 1e-8).expect("a warning");
        assert!(
            w.contains("2.0e-8") && w.contains("tol = 1e-8") && w.contains("8e-8"),
            "{w}"
        );
        assert_eq!(roundoff_warning(Some(&last), 1e-7), None);
        last.roundoff = 1e-8;
        assert_eq!(roundoff_warning(Some(&last), 1e-8), None);
    }

    #[test]
    fn a_change_round_off_hides_counts_as_the_error_it_may_leave() {
        // p_n and u of size 1 at r = 1: the noise is ROUNDOFF (p_n + r u), relative to p_n.
        let sums = SweepSums {
            force_n: 1.0,
            force_t: 0.0,
            displacement_n: 1.0,
            ..SweepSums::unpack([0.0; SweepSums::LEN])
        };
        let noise = 2.0 * ROUNDOFF;
        let hidden = noise / 4.0;
        let with_change = SweepSums {
            force_change_n: hidden * hidden,
            ..sums
        };
        // A fast loop: the noise itself bounds what the run can confirm.
        let (changes, floor) = with_change.changes((1.0, 1.0), 0.5);
        assert_eq!(changes[0], 0.0);
        assert_eq!(floor, noise);
        // A slow one: the hidden change over 1 - rho, far above the noise.
        let (changes, floor) = with_change.changes((1.0, 1.0), 0.999);
        assert_eq!(changes[0], 0.0);
        assert!((floor - hidden / 0.001).abs() <= 1e-9 * floor, "{floor}");
        // Nothing hidden, nothing to bound, however slow.
        assert_eq!(sums.changes((1.0, 1.0), 0.999).1, 0.0);
    }
}
