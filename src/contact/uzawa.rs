//! The Uzawa block relaxation loop (ALG2 of docs/ALGORITHM.md), written once for any rank
//! count: it sees only this rank's contact nodes, a [`LinearStep`] and a [`Reduce`].
//!
//! ## The sweep as a fixed-point map
//! Steps 2 and 3 of a sweep only read s = Nu + lambda / r (normal) and z = Tu + mu / r
//! (tangential) at each node: p = min(g, s), lambda = r (s - p); q = shrink(z, s_f / r),
//! mu = r (z - q). So one sweep is a map x -> G(x) of the state x = (s, z), one value
//! (two with friction) per contact node (the `sweep` module):
//!   1. from x: p, lambda, q, mu and the forces w (r p - lambda), w (r q - mu);
//!   2. the linear step: (Nu, Tu);
//!   3. G(x) = (Nu + lambda / r, Tu + mu / r).
//!
//! Iterating G is exactly ALG2; this form lets an accelerator act on x. Each contact
//! direction may have its own r, chosen by the loop's [`Policy`]: the given r
//! ([`Fixed`]) or the automatic r ([`Adaptive`]); the formulas above then read the
//! node's r_n or r_t.
//!
//! ## Acceleration
//! Anderson mixing (type II, memory m) on G, with an inner product in force units summed
//! over all ranks, so that every rank computes the same mixing coefficients and the
//! iterates do not depend on the rank count. Safeguard: a mixed point is kept only if its
//! fixed-point residual does not exceed that of the last kept point; otherwise the plain
//! step G(x) is taken and the memory is cleared. The plain method therefore bounds the
//! accelerated one (at the price of one extra solve per refusal).
//!
//! ## Communication per sweep
//! One linear step and one all-reduce (its numbers: `sweep::Reduced`).
//!
//! ## The stopping test
//! `tol` is the relative accuracy of p_n, p_t and u at the contact nodes, each against
//! its own size. A sweep's relative changes of the three are divided by 1 - rho, rho the
//! contraction of the plain map estimated from secants of the evaluated points
//! (`Run::contraction`): for a map contracting by rho, the distance to the fixed point is
//! at most |G(x) - x| / (1 - rho). The loop stops when that estimate is below
//! tol / [`STOP_MARGIN`] (docs/ALGORITHM.md, "The stopping test").

use super::adaptive::{Adaptive, AdaptiveParams};
use super::anderson::{dot, metric, span_secant, Anderson, FLAT_SECANT};
use super::kernels::{coulomb_threshold, first_crossing, state};
use super::policy::{Fixed, Image, Policy, PolicyState};
use super::sweep::{
    error_estimate, project_and_update, relative, Augmentation, Derived, Law, Reduced, Sweep,
    Sweeper, ROUNDOFF,
};
use super::{ContactNodes, LinearStep, Reduce, Status};
use crate::contact::{Acceleration, CoulombMode, Friction};
use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Augmentation parameter r > 0: the given r, or the automatic r that the adaptive
    /// policy starts from.
    pub r: f64,
    /// Relative accuracy asked of p_n, p_t and u at the contact nodes: the loop stops
    /// when the estimated error of each, relative to its own size, is below it.
    pub tol: f64,
    /// Budget of sweeps (linear solves), over all outer iterations.
    pub max_iter: usize,
    pub friction: Friction,
    pub coulomb: CoulombMode,
    pub acceleration: Acceleration,
    /// The automatic r's tuning; `None` keeps `r` in every direction (the paper's method).
    pub adaptive: Option<AdaptiveParams>,
    /// E_eff / h, the body's stiffness for mesh-scale modes (NaN when not known), the
    /// unit of the automatic r's floors.
    pub mesh_stiffness: f64,
}

/// The converged (or last) state on this rank's contact nodes.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub converged: bool,
    /// The reference r of the loop: the given or automatic r, or lower for a body far
    /// softer than a compact one (`Adaptive::start`).
    pub r: f64,
    /// The measured smooth-mode stiffness over E_eff / L (`None` when not measured).
    pub smooth_stiffness: Option<f64>,
    /// Linear solves.
    pub iterations: usize,
    /// Outer Tresca solves (Coulomb outer mode), else 1.
    pub outer_iterations: usize,
    /// Accelerated points refused by the safeguard.
    pub refused: usize,
    /// Retunes of r per contact direction.
    pub retunes: usize,
    /// Normal multiplier = contact pressure p_n (force per unit length).
    pub lambda: Vec<f64>,
    /// Tangential multiplier = -p_t.
    pub mu: Vec<f64>,
    /// Nu and Tu of the last solve.
    pub un: Vec<f64>,
    pub ut: Vec<f64>,
    /// Slip threshold s_i at the end (0 when frictionless).
    pub threshold: Vec<f64>,
    pub status: Vec<Status>,
    pub history: Vec<Sweep>,
}

/// Everything this rank needs to resume the loop exactly where it was, each part whole:
/// resuming from a snapshot gives the same iterates, bit for bit, as not stopping.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Snapshot {
    /// The reference r of the loop.
    r_ref: f64,
    progress: Progress,
    point: Point,
    anderson: Anderson,
    policy: PolicyState,
}

impl Snapshot {
    /// The layout of a snapshot, which a checkpoint file names: any change of a struct
    /// stored in it is a new format.
    pub const FORMAT: &'static str = "contact-par checkpoint 2";

    /// The sweeps made before it.
    pub fn sweeps(&self) -> usize {
        self.progress.history.len()
    }
}

/// What the loop carries from sweep to sweep besides its point and Anderson's memory.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct Progress {
    history: Vec<Sweep>,
    /// Accelerated points refused, and retunes of r, so far.
    refused: usize,
    retunes: usize,
    /// The smallest secant ratio |f(y) - f(x)| / |y - x| (f(x) = G(x) - x) since the map
    /// last changed (infinite before the first), behind the contraction estimate.
    min_secant: f64,
    /// Coulomb outer mode: the frozen thresholds, the outer iteration and the last
    /// relative change of the thresholds.
    outer: Option<(Vec<f64>, usize, f64)>,
    /// Every r per direction handed to the linear step, in order (the last is the r in
    /// force): a retune that moves few directions updates the factor in place, so the
    /// factor depends on the sequence, and a resumed run replays it.
    applied: Vec<Augmentation>,
    /// The piece (active and slipping nodes of the last accepted image, retunes) on which
    /// the safeguard last refused a mixed point (see [`Run::cut_back`]).
    refused_on: Option<(usize, usize, usize)>,
}

/// The last accepted point x, its image, the sums of its evaluation and the status
/// margin it set.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
struct Point {
    x: Vec<f64>,
    gx: Vec<f64>,
    res: f64,
    gram: Vec<f64>,
    worst: f64,
    secant: f64,
    margin: f64,
}

/// Periodic snapshots of the loop, and an optional one to resume from.
pub struct Checkpoints<'a> {
    /// Save every this many sweeps (0: never).
    pub every: usize,
    pub save: &'a mut dyn FnMut(&Snapshot) -> Result<()>,
    pub resume: Option<Snapshot>,
}

/// How many times the mean error a node's state must stay away from its status boundary
/// for its status to count as certain: one node may carry more than the mean.
const MARGIN_FACTOR: f64 = 3.0;

/// The loop stops at an estimated error of tol / STOP_MARGIN: rho estimated from secants
/// is a lower bound of the true contraction, exact only along the slowest mode.
pub const STOP_MARGIN: f64 = 4.0;

/// The smallest step |y - x| / |y| whose secant enters the contraction estimate: far
/// enough above the sweep's round-off ([`ROUNDOFF`]) that G(y) - G(x) keeps its digits,
/// yet below the steps of a slow tail whose |y| is dominated by held directions' large r.
const SECANT_FLOOR: f64 = 30.0 * ROUNDOFF;

/// Runs ALG2 (accelerated or not) to convergence or to the sweep budget.
pub fn solve(
    step: &mut impl LinearStep,
    comm: &impl Reduce,
    nodes: &ContactNodes,
    params: &Params,
    monitor: &mut dyn FnMut(&Sweep),
) -> Result<Outcome> {
    let mut none = |_: &Snapshot| Ok(());
    let mut ckpt = Checkpoints {
        every: 0,
        save: &mut none,
        resume: None,
    };
    solve_with(step, comm, nodes, params, monitor, &mut ckpt)
}

/// [`solve`] with periodic snapshots and an optional restart.
pub fn solve_with(
    step: &mut impl LinearStep,
    comm: &impl Reduce,
    nodes: &ContactNodes,
    params: &Params,
    monitor: &mut dyn FnMut(&Sweep),
    ckpt: &mut Checkpoints,
) -> Result<Outcome> {
    let mut policy: Box<dyn Policy> = match params.adaptive {
        Some(tuning) => Box::new(Adaptive::new(tuning, nodes, params.mesh_stiffness)),
        None => Box::new(Fixed),
    };
    let n = nodes.len();
    let (mut r, smooth_stiffness) = match ckpt.resume {
        None => policy.start(step, comm, nodes, params.r)?,
        Some(_) => (params.r, None),
    };
    let mut applied = Vec::new();
    if r != params.r {
        if step.set_r(&vec![r; n], &vec![r; n])? {
            applied.push(Augmentation::uniform(n, r));
        } else {
            r = params.r;
        }
    }
    let sweeper = Sweeper::new(step, nodes, r);
    let mut run = Run::new(sweeper, comm, params, monitor, ckpt, (policy, applied));
    let (converged, last, threshold, outer_iterations) = run.by_law()?;
    let frictional = !matches!(params.friction, Friction::None);
    Ok(Outcome {
        converged,
        r: run.sweeper.r_ref,
        smooth_stiffness,
        iterations: run.progress.history.len(),
        outer_iterations,
        refused: run.progress.refused,
        retunes: run.progress.retunes,
        status: statuses(&last, frictional),
        lambda: last.lambda,
        mu: last.mu,
        un: run.sweeper.un,
        ut: run.sweeper.ut,
        threshold,
        history: run.progress.history,
    })
}

/// The start: lambda = mu = 0, p = min(g, 0), q = 0, i.e. s = min(g, 0), z = 0.
fn initial_state(nodes: &ContactNodes, frictional: bool) -> Vec<f64> {
    let mut x: Vec<f64> = nodes.g.iter().map(|g| g.min(0.0)).collect();
    if frictional {
        x.resize(2 * nodes.len(), 0.0);
    }
    x
}

/// The Coulomb thresholds of the pressures `lambda`, each node with its coefficient.
/// s_i = fixed_i + c_i p_n,i: Tresca and Coulomb contacts mixed.
fn mixed_thresholds(fixed: &[f64], coefficient: &[f64], lambda: &[f64]) -> Vec<f64> {
    (fixed.iter().zip(coulomb_thresholds(coefficient, lambda)))
        .map(|(f, s)| f + s)
        .collect()
}

fn coulomb_thresholds(coefficient: &[f64], lambda: &[f64]) -> Vec<f64> {
    (coefficient.iter().zip(lambda))
        .map(|(&c, &l)| coulomb_threshold(c, l))
        .collect()
}

/// Each node's status in the last image.
fn statuses(last: &Derived, frictional: bool) -> Vec<Status> {
    (0..last.lambda.len())
        .map(|i| {
            if last.lambda[i] <= 0.0 {
                Status::Free
            } else if !frictional {
                Status::Contact
            } else if last.q[i] != 0.0 {
                Status::Slip
            } else {
                Status::Stick
            }
        })
        .collect()
}

/// One run of the loop on this rank: the sweeper, its communication, its policy, and the
/// state that outlives one call of [`Run::sweeps`] (history, counters, checkpoints).
struct Run<'r, 'a, S: LinearStep, C: Reduce> {
    sweeper: Sweeper<'r, S>,
    comm: &'r C,
    params: &'r Params,
    monitor: &'r mut dyn FnMut(&Sweep),
    policy: Box<dyn Policy>,
    /// Contact nodes over all ranks.
    n_contact: usize,
    /// The length of the contact boundary, sum of w over all ranks.
    length: f64,
    progress: Progress,
    /// False once the linear step has declined a change of r.
    can_retune: bool,
    ckpt: &'r mut Checkpoints<'a>,
    resume: Option<Snapshot>,
    /// The last accepted point x and G(x) - x, the base of the next secant.
    anchor: Option<(Vec<f64>, Vec<f64>)>,
}

/// An evaluation of G after the global reduction.
struct Evaluated {
    /// G(x).
    gx: Vec<f64>,
    /// G(x) - x.
    f: Vec<f64>,
    /// The quantities derived from G(x).
    out: Derived,
    /// |G(x) - x|_W over all ranks.
    res: f64,
    /// Anderson Gram sums with this point's residual difference included.
    gram: Vec<f64>,
    /// The estimated relative error ([`Sweep::error`]).
    worst: f64,
    /// |f(x) - f(anchor)| / |x - anchor| (infinite without an anchor).
    secant: f64,
    /// Active and slipping nodes of G(x), over all ranks.
    active: usize,
    slip: usize,
}

impl<'r, 'a, S: LinearStep, C: Reduce> Run<'r, 'a, S, C> {
    /// A run that has swept nothing yet, or will resume from `ckpt.resume`.
    fn new(
        sweeper: Sweeper<'r, S>,
        comm: &'r C,
        params: &'r Params,
        monitor: &'r mut dyn FnMut(&Sweep),
        ckpt: &'r mut Checkpoints<'a>,
        (policy, applied): (Box<dyn Policy>, Vec<Augmentation>),
    ) -> Self {
        let mut total = [sweeper.nodes.len() as f64, sweeper.nodes.w.iter().sum()];
        comm.sum_in_place(&mut total);
        Run {
            sweeper,
            comm,
            params,
            monitor,
            policy,
            n_contact: total[0] as usize,
            length: total[1],
            progress: Progress {
                history: Vec::new(),
                refused: 0,
                retunes: 0,
                min_secant: f64::INFINITY,
                outer: None,
                applied,
                refused_on: None,
            },
            can_retune: true,
            resume: ckpt.resume.take(),
            ckpt,
            anchor: None,
        }
    }

    /// The loop under the case's friction law, from the start state: whether it
    /// converged, the last image, the slip thresholds and the outer iterations.
    fn by_law(&mut self) -> Result<(bool, Derived, Vec<f64>, usize)> {
        let (nodes, params) = (self.sweeper.nodes, self.params);
        let n = nodes.len();
        let mut x = initial_state(nodes, !matches!(params.friction, Friction::None));
        let mixed = !nodes.fixed_threshold.is_empty();
        let (fixed, coefficient) = (&nodes.fixed_threshold, &nodes.friction);
        Ok(match (params.friction, params.coulomb) {
            // Tresca and Coulomb contacts in one run (see `ContactNodes::fixed_threshold`).
            (_, CoulombMode::Inner) if mixed => {
                let (c, d) = self.sweeps(Law::Mixed { fixed, coefficient }, &mut x)?;
                let s = mixed_thresholds(fixed, coefficient, &d.lambda);
                (c, d, s, 1)
            }
            (_, CoulombMode::Outer) if mixed => self.coulomb_outer(fixed, coefficient, &mut x)?,
            (Friction::None, _) => {
                let (c, d) = self.sweeps(Law::Frictionless, &mut x)?;
                (c, d, vec![0.0; n], 1)
            }
            (Friction::Tresca { threshold }, _) => {
                let s = nodes.friction_values(threshold);
                let (c, d) = self.sweeps(Law::Fixed(&s), &mut x)?;
                (c, d, s, 1)
            }
            (Friction::Coulomb { coefficient }, CoulombMode::Inner) => {
                let coefficient = nodes.friction_values(coefficient);
                let (c, d) = self.sweeps(Law::Coulomb(&coefficient), &mut x)?;
                let s = coulomb_thresholds(&coefficient, &d.lambda);
                (c, d, s, 1)
            }
            (Friction::Coulomb { coefficient }, CoulombMode::Outer) => {
                let coefficient = nodes.friction_values(coefficient);
                self.coulomb_outer(&vec![0.0; n], &coefficient, &mut x)?
            }
        })
    }

    /// Iterates from `x` until both residuals are below tol (true) or the budget is
    /// spent (false); returns the quantities derived from the last image G(x).
    fn sweeps(&mut self, law: Law, x: &mut Vec<f64>) -> Result<(bool, Derived)> {
        let mut aa = Anderson::new(match self.params.acceleration {
            Acceleration::None => 0,
            Acceleration::Anderson { memory } => memory,
        });
        // The last accepted point is `x`, `cur` its evaluation.
        let mut cur = match self.resume.take() {
            Some(snap) => self.resume_from(snap, law, x, &mut aa)?,
            None => {
                self.forget_secants();
                self.evaluate(law, x, aa.active())?
            }
        };
        let mut next_save = self.next_checkpoint();
        loop {
            let converged = cur.worst <= self.stop_tol();
            if converged || self.progress.history.len() >= self.params.max_iter {
                *x = cur.gx;
                return Ok((converged, cur.out));
            }
            if self.progress.history.len() >= next_save {
                self.save(x, &cur, &aa)?;
                next_save = self.next_checkpoint();
            }
            self.anchor = Some((x.clone(), cur.f.clone()));
            cur = if self.retune(law, &cur.out, x)? {
                aa.clear();
                self.forget_secants();
                self.evaluate(law, x, aa.active())?
            } else if let Some(y) = aa.propose(x, &cur.gx, &cur.gram, cur.secant) {
                self.safeguard(law, y, cur, x, &mut aa)?
            } else if let Some(y) = self.glide(law, &cur, x, aa.active().is_some()) {
                *x = y;
                self.evaluate(law, x, aa.active())?
            } else {
                // The plain step: the image of the last accepted point.
                *x = cur.gx;
                self.evaluate(law, x, aa.active())?
            };
        }
    }

    /// What the error estimate must reach: tol / [`STOP_MARGIN`].
    fn stop_tol(&self) -> f64 {
        self.params.tol / STOP_MARGIN
    }

    /// Forgets the secants of a map that is about to change (new r, new thresholds): a
    /// secant must join two points of one map, and the new map's contraction is its own.
    fn forget_secants(&mut self) {
        self.anchor = None;
        self.progress.min_secant = f64::INFINITY;
    }

    /// The contraction estimate after the secant `secant2` (squared |y - x| and
    /// |f(y) - f(x)|, and |y|^2; zeros without an anchor): rho = 1 - min |f(y) - f(x)| /
    /// |y - x| over every secant since the map last changed, and over the span of the
    /// Anderson memory (`span`, [`span_secant`]). If G contracts by rho, every secant
    /// ratio is at least 1 - rho, with equality along the slowest mode; every secant
    /// counts, not the latest, because Anderson's last points may all lie off that mode.
    fn contraction(&mut self, secant2: [f64; 3], span: Option<f64>, statuses_changed: bool) -> f64 {
        let [dx2, df2, x2] = secant2;
        // A step at round-off's scale gives a ratio of noise; a step across a change of
        // status joins two pieces of the piecewise affine map, and its ratio belongs to
        // neither.
        if !statuses_changed && dx2 > SECANT_FLOOR * SECANT_FLOOR * x2 {
            self.progress.min_secant = self.progress.min_secant.min((df2 / dx2).sqrt());
            if let Some(span) = span {
                self.progress.min_secant = self.progress.min_secant.min(span);
            }
        }
        if self.progress.min_secant.is_finite() {
            (1.0 - self.progress.min_secant).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// Evaluates G at `x` (one sweep) with the sweep's one all-reduce: its sums (the
    /// policy's counts among them), |G(x) - x|^2, the secant from the anchor and, when
    /// accelerating, the Gram sums of `aa` at the new residual; records the sweep.
    fn evaluate(&mut self, law: Law, x: &[f64], aa: Option<&Anderson>) -> Result<Evaluated> {
        let (r, frictional) = (self.sweeper.r_ref, law.frictional());
        let mut e = self.sweeper.eval(x, law)?;
        let sweeper = &mut self.sweeper;
        self.policy
            .count(&e.now, &sweeper.aug, r, frictional, &mut e.sums);
        self.policy
            .seen(self.progress.history.len() + 1, &sweeper.last_held, &e.now);
        sweeper.last_held = std::mem::take(&mut e.now);
        let omega = metric(&sweeper.nodes.w, &sweeper.aug, r, frictional);
        let residual2 = dot(&e.f, &e.f, &omega);
        let secant2 = match &self.anchor {
            Some((xa, fa)) => {
                let dx: Vec<f64> = x.iter().zip(xa).map(|(a, b)| a - b).collect();
                let df: Vec<f64> = e.f.iter().zip(fa).map(|(a, b)| a - b).collect();
                [
                    dot(&dx, &dx, &omega),
                    dot(&df, &df, &omega),
                    dot(x, x, &omega),
                ]
            }
            None => [0.0; 3],
        };
        let gram = aa.map_or_else(Vec::new, |aa| aa.local_sums_with_new(&e.f, &e.gx, &omega));
        let global = Reduced::all_reduce(self.comm, &e.sums, residual2, secant2, gram);
        let sweep = self.record(&global)?;
        let [dx2, df2, _] = global.secant2;
        Ok(Evaluated {
            gx: e.gx,
            f: e.f,
            out: e.out,
            res: global.residual2.sqrt(),
            gram: global.gram,
            worst: sweep.error,
            secant: if dx2 > 0.0 {
                (df2 / dx2).sqrt()
            } else {
                f64::INFINITY
            },
            active: sweep.active,
            slip: sweep.slip,
        })
    }

    /// The history line of the sweep whose global sums are `global`, recorded and shown
    /// to the monitor; sets the next sweep's status margin. Fails on a non-finite sum.
    fn record(&mut self, global: &Reduced) -> Result<Sweep> {
        let r = self.sweeper.r_ref;
        let changed = global.sums.changed > 0.0;
        let contraction = self.contraction(global.secant2, span_secant(&global.gram), changed);
        let scale = (r, self.policy.largest_r(r));
        let iter = self.progress.history.len() + 1;
        let sweep = Sweep {
            refused: self.progress.refused,
            ..global
                .sums
                .sweep(iter, self.progress.retunes, scale, contraction)
        };
        // The next sweep's margin: this one's state error, |G(x) - x|_W / (1 - rho), made
        // a value per node (the W-norm's mean square over the contact length).
        let state_change = global.sums.state_change_n.sqrt() + global.sums.state_change_t.sqrt();
        self.sweeper.margin =
            MARGIN_FACTOR * error_estimate(state_change, contraction) / self.length.sqrt();
        if !(global.sums.finite() && global.residual2.is_finite()) {
            return Err(Error::Numerical(format!(
                "iteration {iter}: the residuals are not finite (NaN or overflow); the problem may be unstable (check the Dirichlet conditions and the material) or r = {r} unsuitable"
            )));
        }
        self.progress.history.push(sweep);
        (self.monitor)(&sweep);
        Ok(sweep)
    }

    /// The safeguard on the Anderson point y: kept if its fixed-point residual does not
    /// exceed that of the last accepted point (or it meets the tolerance); otherwise
    /// refused, the memory cleared, and the plain step taken from the last accepted
    /// point, unless the step cut back to its first touch passes ([`Run::cut_back`]).
    fn safeguard(
        &mut self,
        law: Law,
        y: Vec<f64>,
        cur: Evaluated,
        x: &mut Vec<f64>,
        aa: &mut Anderson,
    ) -> Result<Evaluated> {
        let next = self.evaluate(law, &y, Some(aa))?;
        if next.res <= cur.res || next.worst <= self.stop_tol() {
            *x = y;
            return Ok(next);
        }
        self.progress.refused += 1;
        // The refused point's sweep is already in the history: it counts there.
        if let Some(last) = self.progress.history.last_mut() {
            last.refused = self.progress.refused;
        }
        aa.clear();
        match self.cut_back(law, &y, &cur, x, aa)? {
            Some(next) => Ok(next),
            None => {
                *x = cur.gx;
                self.evaluate(law, x, Some(aa))
            }
        }
    }

    /// The refused step from `x` to `y`, cut back to where its first node crosses its gap
    /// ([`first_crossing`]), if that point is kept. G is affine on each set of statuses,
    /// and Anderson's point extrapolates the piece of `x`: where that piece contracts
    /// slowly (a body creeping towards the foundation), it lands far through the
    /// foundation and is refused, again and again. So the cut comes at a second refusal
    /// on one piece (the same active and slipping counts, no retune since), not at the
    /// first, whose plain step often crosses into a closer piece; or at the first where
    /// open nodes carry thresholds and none is pressed (nothing glides there). The cut
    /// point passes the safeguard, or is the body's first touch (no node pressed at `x`),
    /// kept whatever its residual: a pressed body's residual exceeds one's in the air.
    fn cut_back(
        &mut self,
        law: Law,
        y: &[f64],
        cur: &Evaluated,
        x: &mut Vec<f64>,
        aa: &mut Anderson,
    ) -> Result<Option<Evaluated>> {
        let piece = (cur.active, cur.slip, self.progress.retunes);
        let held_aloft = cur.active == 0 && law.holds_open_nodes();
        if self.progress.refused_on.replace(piece) != Some(piece) && !held_aloft {
            return Ok(None);
        }
        let n = self.sweeper.nodes.len();
        let mut t = [first_crossing(&x[..n], &y[..n], &self.sweeper.nodes.g)];
        self.comm.min_in_place(&mut t);
        if !(t[0] > 0.0 && t[0] < 1.0) {
            return Ok(None);
        }
        let cut: Vec<f64> = x.iter().zip(y).map(|(a, b)| a + t[0] * (b - a)).collect();
        let next = self.evaluate(law, &cut, Some(aa))?;
        if cur.active == 0 || next.res <= cur.res || next.worst <= self.stop_tol() {
            *x = cut;
            return Ok(Some(next));
        }
        Ok(None)
    }

    /// The point where a body that the sweep map translates (a floating body that no
    /// contact holds yet) first touches: on such a piece G(x) = x + f, and the plain steps
    /// would walk the line x + t f at one unit of t per sweep; instead t is the smallest
    /// (g - x) / f over the nodes moving towards the foundation (over all ranks). Only
    /// when accelerating, from a point whose image presses no node, with no slip
    /// threshold at an open node (no stick/slip status can change on the way), and
    /// further than the plain step.
    fn glide(&self, law: Law, cur: &Evaluated, x: &[f64], accelerating: bool) -> Option<Vec<f64>> {
        if !accelerating || cur.active > 0 || cur.secant >= FLAT_SECANT || law.holds_open_nodes() {
            return None;
        }
        let g = &self.sweeper.nodes.g;
        let mut t = [f64::INFINITY];
        for i in 0..g.len() {
            if cur.f[i] > 0.0 && x[i] < g[i] {
                t[0] = t[0].min((g[i] - x[i]) / cur.f[i]);
            }
        }
        self.comm.min_in_place(&mut t);
        (t[0].is_finite() && t[0] > 1.0)
            .then(|| x.iter().zip(&cur.f).map(|(a, b)| a + t[0] * b).collect())
    }

    /// Retunes r per contact direction when the policy asks for it and the linear step
    /// can change r; then moves `x` to the state, with the new r, that keeps p, lambda, q
    /// and mu of the last image exactly: s = p + lambda / r, z = q + mu / r. Returns
    /// whether r changed.
    fn retune(&mut self, law: Law, last: &Derived, x: &mut [f64]) -> Result<bool> {
        if !self.can_retune {
            return Ok(false);
        }
        let image = Image {
            history: &self.progress.history,
            last,
            law,
            n_contact: self.n_contact,
            r_ref: self.sweeper.r_ref,
        };
        let Some(aug) = self.policy.retune(&image) else {
            return Ok(false);
        };
        if !self.sweeper.step.set_r(&aug.r_n, &aug.r_t)? {
            self.can_retune = false;
            return Ok(false);
        }
        let n = last.p.len();
        for i in 0..n {
            x[i] = state(last.p[i], last.lambda[i], aug.r_n[i]);
            if law.frictional() {
                x[n + i] = state(last.q[i], last.mu[i], aug.r_t[i]);
            }
        }
        self.progress.applied.push(aug.clone());
        self.sweeper.aug = aug;
        self.progress.retunes += 1;
        Ok(true)
    }

    /// Coulomb, outer mode: Tresca solves with the thresholds fixed + c p_n frozen at the
    /// last pressures (`fixed`: the Tresca nodes' thresholds where the laws are mixed,
    /// else zeros), until the thresholds change by less than tol. Returns the outcome of
    /// [`Run::sweeps`], the last thresholds and the outer iterations.
    fn coulomb_outer(
        &mut self,
        fixed: &[f64],
        coefficient: &[f64],
        x: &mut Vec<f64>,
    ) -> Result<(bool, Derived, Vec<f64>, usize)> {
        let n = self.sweeper.nodes.len();
        let resumed = self.resume.as_ref().and_then(|r| r.progress.outer.clone());
        let (mut s, mut done_outer, mut last_change) =
            resumed.unwrap_or((vec![0.0; n], 0, f64::INFINITY));
        loop {
            let outer_iterations = done_outer + 1;
            self.progress.outer = Some((s.clone(), done_outer, last_change));
            let (inner_ok, d) = self.sweeps(Law::Fixed(&s), x)?;
            let s_new = mixed_thresholds(fixed, coefficient, &d.lambda);
            // The outer iteration contracts too: its error is its change over 1 - rho,
            // rho the ratio of its last two changes.
            let change = self.threshold_change(&s, &s_new);
            let rho = if last_change.is_finite() && last_change > 0.0 {
                change / last_change
            } else {
                0.0
            };
            last_change = change;
            let done = error_estimate(change, rho) <= self.stop_tol();
            // The tangential state was converged for the old thresholds: keep it.
            s = s_new;
            done_outer += 1;
            if !inner_ok || self.progress.history.len() >= self.params.max_iter || done {
                return Ok((inner_ok && done, d, s, outer_iterations));
            }
        }
    }

    /// |s_new - s|_W / |s_new|_W over all ranks.
    fn threshold_change(&self, s: &[f64], s_new: &[f64]) -> f64 {
        let w = &self.sweeper.nodes.w;
        let mut sums = [0.0; 2];
        for i in 0..w.len() {
            sums[0] += w[i] * (s_new[i] - s[i]).powi(2);
            sums[1] += w[i] * s_new[i].powi(2);
        }
        self.comm.sum_in_place(&mut sums);
        relative(sums[0].sqrt(), sums[1].sqrt())
    }

    /// Resumes from a snapshot: the policy's state, every r handed to the linear step
    /// (replayed), the loop's progress, the last accepted point with its evaluation, and
    /// the Anderson memory.
    fn resume_from(
        &mut self,
        snap: Snapshot,
        law: Law,
        x: &mut Vec<f64>,
        aa: &mut Anderson,
    ) -> Result<Evaluated> {
        self.policy.restore(snap.policy)?;
        let (sweeper, progress) = (&mut self.sweeper, snap.progress);
        let n = sweeper.nodes.len();
        for aug in &progress.applied {
            if aug.r_n.len() != n || !sweeper.step.set_r(&aug.r_n, &aug.r_t)? {
                return Err(Error::Input(
                    "the checkpoint was taken with r retuned per contact direction and this linear step cannot change r; restart without --restart".into(),
                ));
            }
        }
        sweeper.r_ref = snap.r_ref;
        sweeper.aug = (progress.applied.last().cloned())
            .unwrap_or_else(|| Augmentation::uniform(n, snap.r_ref));
        let p = snap.point;
        let out = project_and_update(&p.gx, sweeper.nodes, law, &sweeper.aug);
        sweeper.last_held = out.statuses(law.frictional());
        sweeper.margin = p.margin;
        let last = progress.history.last();
        let (active, slip) = last.map_or((0, 0), |s| (s.active, s.slip));
        self.progress = progress;
        self.anchor = None;
        (aa.df, aa.dg, aa.last) = (snap.anderson.df, snap.anderson.dg, snap.anderson.last);
        let f = p.gx.iter().zip(&p.x).map(|(a, b)| a - b).collect();
        *x = p.x;
        Ok(Evaluated {
            f,
            gx: p.gx,
            out,
            res: p.res,
            gram: p.gram,
            worst: p.worst,
            secant: p.secant,
            active,
            slip,
        })
    }

    fn next_checkpoint(&self) -> usize {
        match self.ckpt.every {
            0 => usize::MAX,
            k => (self.progress.history.len() / k + 1) * k,
        }
    }

    /// Saves a snapshot of the last accepted point `x` and everything needed to resume
    /// from it.
    fn save(&mut self, x: &[f64], cur: &Evaluated, aa: &Anderson) -> Result<()> {
        let point = Point {
            x: x.to_vec(),
            gx: cur.gx.clone(),
            res: cur.res,
            gram: cur.gram.clone(),
            worst: cur.worst,
            secant: cur.secant,
            margin: self.sweeper.margin,
        };
        let snap = Snapshot {
            r_ref: self.sweeper.r_ref,
            progress: self.progress.clone(),
            point,
            anderson: aa.clone(),
            policy: self.policy.state(),
        };
        (self.ckpt.save)(&snap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::NoComm;

    /// Contact nodes on independent springs (normal and tangential), pushed towards
    /// the foundation: exact answers in closed form. Node i has spring stiffness k_i;
    /// the matrix seen by the solve is k_i + r w_i.
    struct Springs {
        k: Vec<f64>,
        rw: Vec<f64>,
        f: Vec<[f64; 2]>,
        calls: usize,
        /// Add this to Nu on the given call (a disturbed solve, for the safeguard).
        kick: Option<(usize, f64)>,
    }

    impl LinearStep for Springs {
        fn solve(&mut self, fnn: &[f64], ft: &[f64], un: &mut [f64], ut: &mut [f64]) -> Result<()> {
            self.calls += 1;
            for i in 0..un.len() {
                un[i] = (self.f[i][0] + fnn[i]) / (self.k[i] + self.rw[i]);
                ut[i] = (self.f[i][1] + ft[i]) / (self.k[i] + self.rw[i]);
                if self.kick.is_some_and(|(c, _)| c == self.calls) {
                    un[i] += self.kick.unwrap().1;
                }
            }
            Ok(())
        }
    }

    fn params(friction: Friction, acceleration: Acceleration) -> Params {
        Params {
            r: 10.0,
            tol: 1e-12,
            max_iter: 10000,
            friction,
            coulomb: CoulombMode::Inner,
            acceleration,
            adaptive: None,
            mesh_stiffness: f64::NAN,
        }
    }

    const PLAIN: Acceleration = Acceleration::None;
    const ANDERSON: Acceleration = Acceleration::Anderson { memory: 5 };

    fn run_with(friction: Friction, acc: Acceleration, f: [f64; 2], g: f64) -> Outcome {
        one_spring(2.0, friction, acc, f, g)
    }

    /// One contact node on a spring of stiffness `k`, weight 0.5, r w = 5.
    fn one_spring(k: f64, friction: Friction, acc: Acceleration, f: [f64; 2], g: f64) -> Outcome {
        let nodes = ContactNodes {
            w: vec![0.5],
            g: vec![g],
            s: vec![0.0; 1],
            ..Default::default()
        };
        let mut s = Springs {
            k: vec![k],
            rw: vec![5.0],
            f: vec![f],
            calls: 0,
            kick: None,
        };
        solve(&mut s, &NoComm, &nodes, &params(friction, acc), &mut |_| {}).unwrap()
    }

    #[test]
    fn frictionless_spring_touches_with_the_right_pressure() {
        for acc in [PLAIN, ANDERSON] {
            // Free displacement f/k = 3 > g = 1: contact, k g = f - w lambda.
            let o = run_with(Friction::None, acc, [6.0, 0.0], 1.0);
            assert!(o.converged);
            assert!((o.un[0] - 1.0).abs() < 1e-9);
            assert!((o.lambda[0] * 0.5 - 4.0).abs() < 1e-8);
            assert_eq!(o.status[0], Status::Contact);
        }
    }

    /// A node that nothing holds but the contact (k ~ 0), pushed by f = 2 towards the
    /// foundation at the gap `g`: while open, each sweep moves it by f / (r w) = 0.4.
    fn floating_node(g: f64, acc: Acceleration) -> Outcome {
        let o = one_spring(1e-13, Friction::None, acc, [2.0, 0.0], g);
        assert!(o.converged);
        assert!(o.iterations <= 20, "{} sweeps", o.iterations);
        assert!((o.un[0] - g).abs() < 1e-9);
        assert!((o.lambda[0] * 0.5 - 2.0).abs() < 1e-8);
        o
    }

    #[test]
    fn a_floating_node_crosses_its_gap_and_touches() {
        // A translation whose secants are round-off, plain or accelerated.
        for acc in [PLAIN, ANDERSON] {
            floating_node(1.0, acc);
        }
    }

    #[test]
    fn a_floating_node_far_from_its_gap_glides_there() {
        // The plain loop would walk about 1000 sweeps to a gap of 400; accelerated, the
        // loop skips the walk of a translation and lands where the node reaches its gap
        // (`floating_node` allows 20 sweeps).
        floating_node(400.0, ANDERSON);
    }

    #[test]
    fn open_gap_leaves_no_pressure() {
        for acc in [PLAIN, ANDERSON] {
            let o = run_with(Friction::None, acc, [1.0, 0.0], 1.0);
            assert!(o.converged);
            assert!((o.un[0] - 0.5).abs() < 1e-9);
            assert_eq!(o.lambda[0], 0.0);
            assert_eq!(o.status[0], Status::Free);
        }
    }

    #[test]
    fn tresca_stick_and_slip() {
        for acc in [PLAIN, ANDERSON] {
            let stick = run_with(Friction::Tresca { threshold: 10.0 }, acc, [6.0, 1.0], 1.0);
            assert!(stick.converged);
            assert!(stick.ut[0].abs() < 1e-9);
            assert_eq!(stick.status[0], Status::Stick);
            // f_t = 1, w s = 0.5: slips with k ut = 1 - 0.5, and p_t = -mu opposes it.
            let slip = run_with(Friction::Tresca { threshold: 1.0 }, acc, [6.0, 1.0], 1.0);
            assert!(slip.converged);
            assert!((slip.ut[0] - 0.25).abs() < 1e-9);
            assert_eq!(slip.status[0], Status::Slip);
            assert!((-slip.mu[0] + 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn coulomb_inner_and_outer_agree() {
        for acc in [PLAIN, ANDERSON] {
            let mut results = Vec::new();
            for mode in [CoulombMode::Inner, CoulombMode::Outer] {
                let mut p = params(Friction::Coulomb { coefficient: 0.2 }, acc);
                p.coulomb = mode;
                let nodes = ContactNodes {
                    w: vec![0.5],
                    g: vec![1.0],
                    s: vec![0.0; 1],
                    ..Default::default()
                };
                let mut s = Springs {
                    k: vec![2.0],
                    rw: vec![5.0],
                    f: vec![[6.0, 1.0]],
                    calls: 0,
                    kick: None,
                };
                results.push(solve(&mut s, &NoComm, &nodes, &p, &mut |_| {}).unwrap());
            }
            // lambda = 8, s = 1.6, w s = 0.8 < 1: slips with k ut = 0.2.
            for o in &results {
                assert!(o.converged);
                assert!((o.lambda[0] - 8.0).abs() < 1e-8);
                assert!((o.ut[0] - 0.1).abs() < 1e-8, "{}", o.ut[0]);
            }
            assert!(results[1].outer_iterations > 1);
        }
    }

    #[test]
    fn budget_exhaustion_is_reported_not_converged() {
        let nodes = ContactNodes {
            w: vec![0.5],
            g: vec![1.0],
            s: vec![0.0; 1],
            ..Default::default()
        };
        let mut p = params(Friction::None, PLAIN);
        p.max_iter = 2;
        let mut s = Springs {
            k: vec![2.0],
            rw: vec![5.0],
            f: vec![[6.0, 0.0]],
            calls: 0,
            kick: None,
        };
        let o = solve(&mut s, &NoComm, &nodes, &p, &mut |_| {}).unwrap();
        assert!(!o.converged);
        assert_eq!(o.iterations, 2);
    }

    /// 40 contact nodes on springs of stiffness spread over 400x, with growing gaps.
    fn spread_springs() -> (usize, ContactNodes, Vec<f64>) {
        let n = 40;
        let nodes = ContactNodes {
            w: vec![0.5; n],
            g: (0..n).map(|i| 0.02 * i as f64).collect(),
            s: (0..n).map(|i| i as f64).collect(),
            ..Default::default()
        };
        let k = (0..n)
            .map(|i| 0.05 + 20.0 * (i as f64 / n as f64).powi(2))
            .collect();
        (n, nodes, k)
    }

    /// Many springs with spread stiffness: plain ALG2 needs many sweeps, Anderson few,
    /// and both reach the same answer.
    fn many(acc: Acceleration, kick: Option<(usize, f64)>) -> Outcome {
        let (n, nodes, k) = spread_springs();
        let mut s = Springs {
            rw: vec![5.0; n],
            f: k.iter().map(|k| [0.5 * k + 0.3, 0.2]).collect(),
            k,
            calls: 0,
            kick,
        };
        let p = params(Friction::Coulomb { coefficient: 0.3 }, acc);
        solve(&mut s, &NoComm, &nodes, &p, &mut |_| {}).unwrap()
    }

    #[test]
    fn anderson_converges_to_the_plain_answer_in_fewer_sweeps() {
        let plain = many(PLAIN, None);
        let fast = many(ANDERSON, None);
        eprintln!(
            "plain {} {} fast {} {} {:?}",
            plain.converged,
            plain.iterations,
            fast.converged,
            fast.iterations,
            fast.history.last()
        );
        assert!(
            fast.iterations * 2 < plain.iterations,
            "{} vs {}",
            fast.iterations,
            plain.iterations
        );
        let scale = plain.lambda.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..plain.lambda.len() {
            assert!((plain.lambda[i] - fast.lambda[i]).abs() < 1e-9 * scale);
            assert!((plain.mu[i] - fast.mu[i]).abs() < 1e-9 * scale);
        }
    }

    #[test]
    fn safeguard_refuses_a_bad_accelerated_point_and_still_converges() {
        // Call 3 is the first accelerated point (1: start, 2: plain step); disturb it.
        let kicked = many(ANDERSON, Some((3, 50.0)));
        assert!(kicked.refused >= 1, "the safeguard did not engage");
        assert!(kicked.converged);
        // The history counts the refusal at the sweep that evaluated the kicked point.
        let counts: Vec<usize> = kicked.history.iter().map(|s| s.refused).collect();
        assert_eq!(&counts[..3], [0, 0, 1], "{counts:?}");
        assert_eq!(counts.last(), Some(&kicked.refused));
        assert!(counts.windows(2).all(|w| w[0] <= w[1]), "{counts:?}");
        let plain = many(PLAIN, None);
        let scale = plain.lambda.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..plain.lambda.len() {
            assert!((plain.lambda[i] - kicked.lambda[i]).abs() < 1e-9 * scale);
        }
    }

    /// Springs whose augmentation follows set_r: the retuned loop must reach the answer
    /// of the plain one (r is only a parameter of the method, not of the problem).
    struct Tunable {
        k: Vec<f64>,
        w: Vec<f64>,
        r_n: Vec<f64>,
        r_t: Vec<f64>,
        f: Vec<[f64; 2]>,
        set_calls: usize,
    }

    impl LinearStep for Tunable {
        fn solve(&mut self, fnn: &[f64], ft: &[f64], un: &mut [f64], ut: &mut [f64]) -> Result<()> {
            for i in 0..un.len() {
                un[i] = (self.f[i][0] + fnn[i]) / (self.k[i] + self.r_n[i] * self.w[i]);
                ut[i] = (self.f[i][1] + ft[i]) / (self.k[i] + self.r_t[i] * self.w[i]);
            }
            Ok(())
        }

        fn set_r(&mut self, r_n: &[f64], r_t: &[f64]) -> Result<bool> {
            self.set_calls += 1;
            (self.r_n, self.r_t) = (r_n.to_vec(), r_t.to_vec());
            Ok(true)
        }
    }

    fn tunable(friction: Friction, adaptive: bool) -> (Outcome, usize) {
        let (n, nodes, k) = spread_springs();
        let mut s = Tunable {
            f: k.iter().map(|k| [0.5 * k + 0.3, 0.2]).collect(),
            k,
            w: vec![0.5; n],
            r_n: vec![10.0; n],
            r_t: vec![10.0; n],
            set_calls: 0,
        };
        let mut p = params(friction, ANDERSON);
        p.adaptive = adaptive.then(AdaptiveParams::default);
        let o = solve(&mut s, &NoComm, &nodes, &p, &mut |_| {}).unwrap();
        (o, s.set_calls)
    }

    #[test]
    fn r_is_lowered_for_a_body_far_softer_than_a_compact_one() {
        // r = 10 and E_eff / h = 100: a compact body would have the stiffness
        // r^2 / 100 = 1 per unit W-length. Springs k on weights w = 0.5 have k / w.
        let soft_body = AdaptiveParams::default().soft_body;
        for (k, lowered) in [(1e-3, Some(10.0 * (2e-3 / soft_body).powi(2))), (2.0, None)] {
            let n = 40;
            let nodes = ContactNodes {
                w: vec![0.5; n],
                g: vec![0.01; n],
                s: (0..n).map(|i| i as f64).collect(),
                ..Default::default()
            };
            let mut step = Tunable {
                f: vec![[1.0, 0.0]; n],
                k: vec![k; n],
                w: vec![0.5; n],
                r_n: vec![10.0; n],
                r_t: vec![10.0; n],
                set_calls: 0,
            };
            let mut p = params(Friction::None, ANDERSON);
            p.adaptive = Some(AdaptiveParams::default());
            p.mesh_stiffness = 100.0;
            let o = solve(&mut step, &NoComm, &nodes, &p, &mut |_| {}).unwrap();
            assert!(o.converged);
            let ratio = o.smooth_stiffness.unwrap();
            assert!((ratio - k / 0.5).abs() <= 1e-9 * ratio, "{ratio}");
            match lowered {
                Some(r) => assert!((o.r - r).abs() <= 1e-9 * r, "r = {}", o.r),
                None => assert_eq!(o.r, 10.0),
            }
            // The answer does not depend on r: every node touches, k g + w lambda = f.
            for i in 0..n {
                assert!((o.un[i] - 0.01).abs() < 1e-9);
                assert!((k * 0.01 + 0.5 * o.lambda[i] - 1.0).abs() < 1e-8);
            }
        }
    }

    #[test]
    fn retuned_loop_reaches_the_plain_answer() {
        for friction in [
            Friction::None,
            Friction::Tresca { threshold: 0.4 },
            Friction::Coulomb { coefficient: 0.3 },
        ] {
            let (fixed, none) = tunable(friction, false);
            let (tuned, calls) = tunable(friction, true);
            assert_eq!(none, 0);
            assert!(
                fixed.converged && tuned.converged,
                "{friction:?} {} {} {:?}",
                fixed.iterations,
                tuned.iterations,
                tuned.history.last()
            );
            assert!(
                calls >= 1 && tuned.retunes == calls,
                "{friction:?}: {calls}"
            );
            let last = tuned.history.last().unwrap();
            let max_retunes = AdaptiveParams::default().max_retunes;
            assert!(last.stiff + last.soft > 0 || tuned.retunes == max_retunes);
            assert!(tuned.retunes <= max_retunes);
            let scale = fixed.lambda.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for i in 0..fixed.lambda.len() {
                assert!((fixed.lambda[i] - tuned.lambda[i]).abs() < 1e-8 * scale);
                assert!((fixed.mu[i] - tuned.mu[i]).abs() < 1e-8 * scale);
                // Displacements of order 0.1-1 here.
                assert!((fixed.un[i] - tuned.un[i]).abs() < 1e-8);
                assert!((fixed.ut[i] - tuned.ut[i]).abs() < 1e-8);
            }
        }
    }
}
