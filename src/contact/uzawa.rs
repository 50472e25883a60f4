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
//! direction may have its own r (an [`Augmentation`]: the normals retuned to their
//! statuses at every sweep that moves one, the tangents once the statuses settle; see
//! [`retuned`]); the formulas above then read r_n or r_t of the node.
//!
//! ## Acceleration
//! Anderson mixing (type II, memory m) on G, with an inner product in force units (each
//! direction weighted by w (r / r_ref)^2, see `metric` in the `anderson` module) summed over all
//! ranks, so every rank computes the same mixing coefficients and the iterates do not
//! depend on the rank count. Safeguard: a mixed point is kept only if its fixed-point
//! residual |G(y) - y| (same norm) does not exceed the residual of the last kept point;
//! otherwise the plain step G(x) is taken and the memory is cleared. The plain method
//! therefore bounds the accelerated one (at the price of one extra solve per refusal).
//!
//! ## Communication per sweep
//! One linear step, and one all-reduce of 21 + m(m+1)/2 + m numbers: the 17 sums of
//! `SweepSums` (the squared W-norms of the changes, displacements and multipliers, the
//! active, slip, changed, stiff, soft, mistuned (all and normal), uncertain and unsettled counts), the squared
//! fixed-point residual, the secant's three squared norms, and the Anderson Gram matrix
//! and right-hand side.
//!
//! ## The stopping test
//! `tol` is the relative accuracy of p_n, p_t and u at the contact nodes, each against
//! its own size. A sweep's relative changes of the three (`SweepSums::changes`)
//! are divided by 1 - rho, rho the contraction of the plain map estimated from secants of
//! the evaluated points (`Run::contraction`): for a map contracting by rho, the distance
//! to the fixed point is at most |G(x) - x| / (1 - rho). The loop stops when that
//! estimate is below tol (docs/ALGORITHM.md, "The stopping test").

use super::anderson::{dot, metric, span_secant, Anderson, FLAT_SECANT};
use super::kernels::{coulomb_threshold, first_crossing, state};
use super::retune::{retuned, tail, tangents_follow, Augmentation, Held, Retune};
use super::sweep::{
    error_estimate, project_and_update, relative, Derived, Law, Reduced, Sweep, Sweeper, ROUNDOFF,
};
use super::{ContactNodes, LinearStep, Reduce, Status};
use crate::contact::{Acceleration, CoulombMode, Friction};
use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Augmentation parameter r > 0.
    pub r: f64,
    /// Relative accuracy asked of p_n, p_t and u at the contact nodes: the loop stops
    /// when the estimated error of each, relative to its own size, is below it.
    pub tol: f64,
    /// Budget of sweeps (linear solves), over all outer iterations.
    pub max_iter: usize,
    pub friction: Friction,
    pub coulomb: CoulombMode,
    pub acceleration: Acceleration,
    /// Retune r per contact direction when the loop settles (see [`retuned`]), and
    /// lower r before the loop for a body far softer than a compact one (see
    /// [`super::probe`]).
    pub adapt_r: bool,
    /// E_eff / h, the stiffness of the body for mesh-scale modes (the stiffest), which
    /// the automatic r balances against the smooth modes'.
    pub mesh_stiffness: f64,
}

/// The converged (or last) state on this rank's contact nodes.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub converged: bool,
    /// The reference r of the loop: the given or automatic r, or lower for a body far
    /// softer than a compact one (see [`softened_r`]).
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

/// Everything this rank needs to resume the loop exactly where it was: resuming from a
/// snapshot gives the same iterates, bit for bit, as not stopping.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Snapshot {
    pub history: Vec<Sweep>,
    pub refused: usize,
    /// The last accepted state and its evaluation.
    pub x: Vec<f64>,
    pub gx: Vec<f64>,
    pub res: f64,
    pub gram: Vec<f64>,
    pub worst: f64,
    /// Anderson memory.
    pub df: Vec<Vec<f64>>,
    pub dg: Vec<Vec<f64>>,
    pub last: Option<(Vec<f64>, Vec<f64>)>,
    /// Coulomb outer mode: the frozen thresholds, the outer iteration and the last
    /// relative change of the thresholds.
    pub outer: Option<(Vec<f64>, usize, f64)>,
    /// This rank's r per contact direction at the last accepted point.
    pub aug: Augmentation,
    /// Retunes of r so far.
    pub retunes: usize,
    /// The smallest secant ratio so far, behind the contraction estimate.
    pub min_secant: f64,
    /// The secant ratio of the last accepted point, which the Anderson step reads.
    pub secant: f64,
    /// The reference r of the loop (see [`softened_r`]).
    pub r_ref: f64,
    /// Every r per direction handed to the linear step before this point, in order: a
    /// retune that moves few directions updates the factor in place, so the factor
    /// depends on the sequence, and a resumed run replays it to continue bit for bit.
    pub applied: Vec<Augmentation>,
    /// The piece of the last refusal (see [`Run::safeguard`]).
    #[serde(default)]
    pub refused_on: Option<(usize, usize, usize)>,
    /// The sweep of each of this rank's contact nodes' last status change, and of its
    /// normal's.
    #[serde(default)]
    pub changed_at: Vec<usize>,
    #[serde(default)]
    pub normal_changed_at: Vec<usize>,
    /// The sweep count when the retunes cycled with the tangents following their statuses.
    #[serde(default)]
    pub tangents_cycled_at: Option<usize>,
}

/// Periodic snapshots of the loop, and an optional one to resume from.
pub struct Checkpoints<'a> {
    /// Save every this many sweeps (0: never).
    pub every: usize,
    pub save: &'a mut dyn FnMut(&Snapshot) -> Result<()>,
    pub resume: Option<Snapshot>,
}

/// How many times the mean error a node's state must stay away from its status
/// boundary for its status to count as certain (see [`Sweep::uncertain`]).
const MARGIN_FACTOR: f64 = 3.0;

/// The loop stops when its error estimate is below tol / STOP_MARGIN. The estimate
/// divides the last change by 1 - rho, rho measured from secants of the sweep map: a
/// lower bound of the true contraction, exact only along the slowest mode. Measured on
/// the unseen cases of tests/data/tolerance at tol 1e-6, runs stopping at the estimate
/// landed up to 3.5 tol from the converged answer (the cantilever, rho = 0.9995), and
/// runs on 1 and 3 ranks 3.5 tol apart; with the margin of 4 (and the lowered r of
/// slender bodies), within 0.6 tol of it and 0.4 tol of each other. Cost: 0-2 more
/// sweeps on the built-in cases at levels 1-4, 8-18 at level 5 (83 -> 91 on block,
/// 162 -> 180 on hertz, where no retune runs).
pub const STOP_MARGIN: f64 = 4.0;

/// The smallest step |y - x| / |y| whose secant enters the contraction estimate: a
/// thousand times the sweep's round-off ([`ROUNDOFF`], relative to the largest forces,
/// r |u| and the multipliers, which the state norm measures), so that the round-off of
/// G(y) - G(x) stays below a thousandth of the difference. Measured on the cantilever of
/// tests/data/tolerance, where the held normals' r x 1000 makes |y| (in force units) 1e8
/// times the contact forces: its last 20 steps lay at 2e-12 to 8e-10 of |y| and gave
/// smooth ratios (0.13-0.19); with a floor of 1e-9 none counted, rho stayed 0 and a run
/// at tol 1e-6 stopped with p_t 2.7e-6 off.
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
    let n = nodes.len();
    let frictional = !matches!(params.friction, Friction::None);
    let mut x = initial_state(nodes, frictional);
    let (r, smooth_stiffness) = if params.adapt_r && ckpt.resume.is_none() {
        softened_r(step, comm, nodes, params)?
    } else {
        (params.r, None)
    };
    // Not known (a caller without a mesh): no floor under the held directions' r.
    let mesh_stiffness = if params.mesh_stiffness > 0.0 {
        params.mesh_stiffness
    } else {
        0.0
    };
    let sweeper = Sweeper::new(step, nodes, r, mesh_stiffness);
    let mut run = Run::new(sweeper, comm, params, monitor, ckpt);
    if r != params.r {
        run.applied.push(Augmentation::uniform(n, r));
    }
    let mut outer_iterations = 1;
    let mixed = !nodes.fixed_threshold.is_empty();
    let (converged, last, threshold) = match (params.friction, params.coulomb) {
        // Tresca and Coulomb contacts in one run (see `ContactNodes::fixed_threshold`).
        (_, CoulombMode::Inner) if mixed => {
            let (fixed, coefficient) = (&nodes.fixed_threshold, &nodes.friction);
            let (c, d) = run.sweeps(Law::Mixed { fixed, coefficient }, &mut x)?;
            let s = mixed_thresholds(fixed, coefficient, &d.lambda);
            (c, d, s)
        }
        (_, CoulombMode::Outer) if mixed => {
            let (fixed, coefficient) = (&nodes.fixed_threshold, &nodes.friction);
            let (c, d, s, outer) = run.coulomb_outer(fixed, coefficient, &mut x)?;
            outer_iterations = outer;
            (c, d, s)
        }
        (Friction::None, _) => {
            let (c, d) = run.sweeps(Law::Frictionless, &mut x)?;
            (c, d, vec![0.0; n])
        }
        (Friction::Tresca { threshold }, _) => {
            let s = nodes.friction_values(threshold);
            let (c, d) = run.sweeps(Law::Fixed(&s), &mut x)?;
            (c, d, s)
        }
        (Friction::Coulomb { coefficient }, CoulombMode::Inner) => {
            let coefficient = nodes.friction_values(coefficient);
            let (c, d) = run.sweeps(Law::Coulomb(&coefficient), &mut x)?;
            let s = coulomb_thresholds(&coefficient, &d.lambda);
            (c, d, s)
        }
        (Friction::Coulomb { coefficient }, CoulombMode::Outer) => {
            let coefficient = nodes.friction_values(coefficient);
            let (c, d, s, outer) = run.coulomb_outer(&vec![0.0; n], &coefficient, &mut x)?;
            outer_iterations = outer;
            (c, d, s)
        }
    };
    Ok(Outcome {
        converged,
        r: run.sweeper.r_ref,
        smooth_stiffness,
        iterations: run.history.len(),
        outer_iterations,
        refused: run.refused,
        retunes: run.retunes,
        status: statuses(&last, frictional),
        lambda: last.lambda,
        mu: last.mu,
        un: run.sweeper.un,
        ut: run.sweeper.ut,
        threshold,
        history: run.history,
    })
}

/// How much softer than a compact body (E_eff / L) a body must be for smooth contact
/// modes before r is lowered below the automatic r, by (ratio / SOFT_BODY)^2. Above it
/// the automatic r stands: the compact bodies measured lie at 1.3-2.3 (hertz, block, and
/// the unstructured wall, disc and wedge of tests/data/tolerance), a floating block at
/// 0.14; clamped steel beams 0.04 m deep at 0.16, 0.042, 0.016 and 0.008 for 0.2, 0.4,
/// 1 and 2 m of length, the cantilever case 0.008 (1760 nodes) and 0.012 (12858).
/// Sweeps (frictionless / Coulomb 0.5) of the 0.4, 1 and 2 m beams and the cantilever,
/// with the undoing of cycling retunes: r kept, 58/95, 173/258, 517/483, 478/643 (before
/// that rule); r x ratio / 0.05, 58/91, 173/152, 380/401, 350/440, and the 12858-node
/// cantilever 535/1854; its square, 70/80, 250/150, 364/253, 312/230, and 246/623; its
/// cube, 82/104, 209/193, 466/455, 548/424, and 316/294. On beams meshed twice as finely
/// (not used for the choice), the first power gave 72/53, 281/308, 566/988, the square
/// 87/53, 198/181, 433/280. Thresholds 0.1 and 1 slowed the shorter beams.
const SOFT_BODY: f64 = 0.05;

/// The reference r of the loop. The automatic r is the geometric mean of the body's
/// mesh-scale stiffness E_eff / h and a compact body's smooth-mode stiffness E_eff / L.
/// A slender body bends: its smooth modes are far softer than E_eff / L, every open
/// contact node is held by a spring far stiffer than the body and creeps towards its
/// place (the loop's contraction for it is r c / (1 + r c), c its compliance). Where
/// the measured smooth-mode stiffness ([`super::probe::smooth_stiffness`]) is below
/// [`SOFT_BODY`] times E_eff / L, r is lowered by the square of the ratio (the linear
/// step refactors its contact blocks, as for a retune); else kept. Returns r and the
/// measured ratio.
fn softened_r(
    step: &mut impl LinearStep,
    comm: &impl Reduce,
    nodes: &ContactNodes,
    params: &Params,
) -> Result<(f64, Option<f64>)> {
    let r = params.r;
    // Not known (a caller without a mesh): nothing to compare with.
    if params.mesh_stiffness.is_nan() || params.mesh_stiffness <= 0.0 {
        return Ok((r, None));
    }
    let Some(k) = super::probe::smooth_stiffness(step, comm, nodes, r)? else {
        return Ok((r, None));
    };
    // r = sqrt(mesh stiffness x compact stiffness).
    let ratio = k * params.mesh_stiffness / (r * r);
    let factor = (ratio / SOFT_BODY).clamp(1e-3, 1.0).powi(2);
    if factor >= 1.0 {
        return Ok((r, Some(ratio)));
    }
    let lowered = r * factor;
    let n = nodes.len();
    if step.set_r(&vec![lowered; n], &vec![lowered; n])? {
        Ok((lowered, Some(ratio)))
    } else {
        Ok((r, Some(ratio)))
    }
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

/// One run of the loop on this rank: the sweeper, its communication, and the state that
/// outlives one call of [`Run::sweeps`] (history, counters, checkpoints).
struct Run<'r, 'a, S: LinearStep, C: Reduce> {
    sweeper: Sweeper<'r, S>,
    comm: &'r C,
    params: &'r Params,
    monitor: &'r mut dyn FnMut(&Sweep),
    /// Contact nodes over all ranks.
    n_contact: usize,
    /// The length of the contact boundary, sum of w over all ranks.
    length: f64,
    history: Vec<Sweep>,
    retunes: usize,
    /// False once the linear step has declined a change of r.
    can_retune: bool,
    refused: usize,
    ckpt: &'r mut Checkpoints<'a>,
    resume: Option<Snapshot>,
    outer: Option<(Vec<f64>, usize, f64)>,
    /// Every r per direction handed to the linear step, in order (see
    /// [`Snapshot::applied`]).
    applied: Vec<Augmentation>,
    /// The last accepted point x and G(x) - x, the base of the next secant.
    anchor: Option<(Vec<f64>, Vec<f64>)>,
    /// The smallest secant ratio |f(y) - f(x)| / |y - x| (f(x) = G(x) - x) since the map
    /// last changed (infinite before the first).
    min_secant: f64,
    /// The piece (active and slipping nodes of the last accepted image, retunes) on which
    /// the safeguard last refused a mixed point (see [`Run::safeguard`]).
    refused_on: Option<(usize, usize, usize)>,
    /// The sweep count when the retunes cycled with the tangents following their
    /// statuses ([`tangents_follow`]): from there they no longer follow.
    tangents_cycled_at: Option<usize>,
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
    ) -> Self {
        let mut total = [sweeper.nodes.len() as f64, sweeper.nodes.w.iter().sum()];
        comm.sum_in_place(&mut total);
        Run {
            sweeper,
            comm,
            params,
            monitor,
            n_contact: total[0] as usize,
            length: total[1],
            history: Vec::new(),
            retunes: 0,
            can_retune: true,
            refused: 0,
            resume: ckpt.resume.take(),
            ckpt,
            outer: None,
            applied: Vec::new(),
            anchor: None,
            min_secant: f64::INFINITY,
            refused_on: None,
            tangents_cycled_at: None,
        }
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
            if converged || self.history.len() >= self.params.max_iter {
                *x = cur.gx;
                return Ok((converged, cur.out));
            }
            if self.history.len() >= next_save {
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
                self.plain_step(law, cur, x, aa.active())?
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
        self.min_secant = f64::INFINITY;
    }

    /// The contraction estimate after the secant `secant2` (squared |y - x| and
    /// |f(y) - f(x)|, zero without an anchor): rho = 1 - min |f(y) - f(x)| / |y - x| over
    /// every secant since the map last changed. If G contracts by rho, every secant ratio
    /// is at least 1 - rho, and a secant along the slowest mode gives 1 - rho exactly: the
    /// plain loop's consecutive points follow that mode, Anderson's explore it. Why every
    /// secant, not the latest: Anderson's last points may all lie off the slowest mode,
    /// which the error still contains (measured on the cantilever of tests/data/tolerance:
    /// the last 12 secants gave rho = 0.999 where the error implied 0.99995).
    ///
    /// `span`, the smallest ratio over the span of the Anderson memory
    /// ([`span_secant`]), enters as one more secant: it is never above the newest single
    /// secant, and sees the slow modes a run of single secants can miss.
    fn contraction(&mut self, secant2: [f64; 3], span: Option<f64>, statuses_changed: bool) -> f64 {
        let [dx2, df2, x2] = secant2;
        // A step at round-off's scale gives a ratio of noise. A step across a change of
        // status joins two pieces of the piecewise affine map: its ratio belongs to
        // neither (a floating body's open piece is a translation, ratio 0, which would
        // hold rho at 1 long after the contact has closed).
        if !statuses_changed && dx2 > SECANT_FLOOR * SECANT_FLOOR * x2 {
            self.min_secant = self.min_secant.min((df2 / dx2).sqrt());
            if let Some(span) = span {
                self.min_secant = self.min_secant.min(span);
            }
        }
        if self.min_secant.is_finite() {
            (1.0 - self.min_secant).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// Evaluates G at `x` (one sweep) with the sweep's one all-reduce: its sums,
    /// |G(x) - x|^2 and, when accelerating, the Gram sums of `aa` at the new residual;
    /// records the sweep.
    fn evaluate(&mut self, law: Law, x: &[f64], aa: Option<&Anderson>) -> Result<Evaluated> {
        let r = self.sweeper.r_ref;
        let e = self.sweeper.eval(x, law, self.history.len() + 1)?;
        let omega = metric(
            &self.sweeper.nodes.w,
            &self.sweeper.aug,
            r,
            law.frictional(),
        );
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
        let contraction = self.contraction(
            global.secant2,
            span_secant(&global.gram),
            global.sums.changed > 0.0,
        );
        let [dx2, df2, _] = global.secant2;
        let secant = if dx2 > 0.0 {
            (df2 / dx2).sqrt()
        } else {
            f64::INFINITY
        };
        let sweep = Sweep {
            refused: self.refused,
            ..global.sums.sweep(
                self.history.len() + 1,
                self.retunes,
                (r, self.sweeper.mesh_stiffness),
                contraction,
            )
        };
        // The next sweep's margin: this one's state error, |G(x) - x|_W / (1 - rho), made
        // a value per node (the W-norm's mean square over the contact length) and tripled
        // because one node may carry more than the mean.
        let state_change = global.sums.state_change_n.sqrt() + global.sums.state_change_t.sqrt();
        self.sweeper.margin =
            MARGIN_FACTOR * error_estimate(state_change, contraction) / self.length.sqrt();
        if !(global.sums.finite() && global.residual2.is_finite()) {
            return Err(Error::Numerical(format!(
                "iteration {}: the residuals are not finite (NaN or overflow); the problem may be unstable (check the Dirichlet conditions and the material) or r = {r} unsuitable",
                sweep.iter
            )));
        }
        self.history.push(sweep);
        (self.monitor)(&sweep);
        Ok(Evaluated {
            gx: e.gx,
            f: e.f,
            out: e.out,
            res: global.residual2.sqrt(),
            gram: global.gram,
            worst: sweep.error,
            secant,
            active: sweep.active,
            slip: sweep.slip,
        })
    }

    /// The plain step: the image of the last accepted point is the next point.
    fn plain_step(
        &mut self,
        law: Law,
        cur: Evaluated,
        x: &mut Vec<f64>,
        aa: Option<&Anderson>,
    ) -> Result<Evaluated> {
        *x = cur.gx;
        self.evaluate(law, x, aa)
    }

    /// The safeguard on the Anderson point y: kept if its fixed-point residual does not
    /// exceed that of the last accepted point (or it meets the tolerance); otherwise
    /// refused, the memory cleared, and the plain step taken from the last accepted point.
    ///
    /// **A second refusal on one piece.** G is affine on each set of statuses, and
    /// Anderson's point extrapolates the piece of the last accepted point. Where that
    /// piece contracts slowly along one mode (a body that nothing holds in the normal
    /// direction but friction, creeping towards the foundation), the extrapolation
    /// lands far through the foundation, on a piece where the residual is large, and is
    /// refused; the plain steps creep on, the memory refills and the same happens again
    /// (the pressed strip of docs/performance-history.md: a refusal every 5 sweeps for
    /// 460 sweeps with no node in contact). So when the safeguard refuses a point again
    /// with the same piece behind it (the same active and slipping counts, no retune
    /// since), the step is cut back to where its first node crosses its gap, the end of
    /// the piece on which the extrapolation holds ([`first_crossing`]), and that point
    /// goes through the same safeguard before the plain step is taken. Not at the first
    /// refusal: there the plain step often crosses into a closer piece than the cut
    /// point (beams meshed finely: 19 and 29 sweeps with the plain step, 28 and 35 with
    /// the cut at every refusal).
    ///
    /// **The first touch.** Where no node is pressed yet, the cut point is the body's
    /// first touch, and it is kept whatever its residual, as [`Run::glide`] keeps its
    /// point: its image presses the nodes the body sinks onto, so its residual exceeds
    /// that of a body still in the air, and the safeguard would send the body back up to
    /// creep down again. Measured on a held-out Tresca bridge (`make_cases.py --slender
    /// --scale 0.6`, threshold 0.3 times the Coulomb answer's coefficient times its mean
    /// pressure): the cut point pressed 155 nodes and was refused, 25 plain sweeps
    /// followed in the air with a refusal every four, and the run took 122 sweeps; with
    /// the cut point kept, 84 (at `--scale 0.65`, 86 -> 76: tests/tolerance.rs). Nothing
    /// else changed among the 113 runs of docs/performance-history.md and the 48 cases of
    /// `make_cases.py` at scales 0.7 and 0.6; of the 60 Tresca variants of the latter one
    /// more, 69 -> 71. What follows the touch moves either way: at `--scale 0.9` the
    /// bounce that the kept point saves is one sweep in the air, and the stick/slip
    /// statuses then took another path, 65 -> 75 sweeps.
    ///
    /// **A body held aloft by thresholds.** Where open nodes carry a slip threshold
    /// (Tresca, mixed laws), nothing pressed yet, the cut comes at the first refusal
    /// too: those thresholds hold the body along the foundation, it creeps down through
    /// the air with no glide ([`Run::glide`] needs zero thresholds), and the plain step
    /// after a refused point was a step back up. Measured on held-out Tresca strips
    /// (`make_cases.py --slender` at scales 1, 0.7 and 0.6): 55 -> 51, 61 -> 48 and 72
    /// -> 57 sweeps, no other of the 232 runs of docs/performance-history.md changed.
    /// With zero thresholds (frictionless, Coulomb) the first refusal keeps its plain
    /// step: the cut there took a 2 m frictionless beam from 25 to 34 sweeps.
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
        self.refused += 1;
        // The refused point's sweep is already in the history: it counts there.
        if let Some(last) = self.history.last_mut() {
            last.refused = self.refused;
        }
        aa.clear();
        let piece = (cur.active, cur.slip, self.retunes);
        let held_aloft = cur.active == 0 && law.holds_open_nodes();
        if self.refused_on.replace(piece) == Some(piece) || held_aloft {
            let n = self.sweeper.nodes.len();
            let mut t = [first_crossing(&x[..n], &y[..n], &self.sweeper.nodes.g)];
            self.comm.min_in_place(&mut t);
            if t[0] > 0.0 && t[0] < 1.0 {
                let cut: Vec<f64> = x.iter().zip(&y).map(|(a, b)| a + t[0] * (b - a)).collect();
                let next = self.evaluate(law, &cut, Some(aa))?;
                if cur.active == 0 || next.res <= cur.res || next.worst <= self.stop_tol() {
                    *x = cut;
                    return Ok(next);
                }
            }
        }
        self.plain_step(law, cur, x, Some(aa))
    }

    /// The point where a body that the sweep map translates (a floating body that no
    /// contact holds yet) first touches: on such a piece G(x) = x + f, so the plain steps
    /// walk the line x + t f at one unit of t per sweep until a node's state crosses its
    /// gap, where the piece ends. That walk is skipped: the point on the line where the
    /// first node reaches its gap, t the smallest (g - x) / f over the nodes moving
    /// towards the foundation (over all ranks). Only when accelerating, from a point
    /// whose image presses no node, with a zero slip threshold at every open node (no
    /// stick/slip status can change on the way), and further than the plain step.
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

    /// Retunes r per contact direction when [`retuned`] asks for it and the linear step
    /// can change r; then moves `x` to the state, with the new r, that keeps p, lambda, q
    /// and mu of the last image exactly: s = p + lambda / r, z = q + mu / r. Returns
    /// whether r changed.
    fn retune(&mut self, law: Law, last: &Derived, x: &mut [f64]) -> Result<bool> {
        let frictional = law.frictional();
        if !(self.params.adapt_r && self.can_retune) {
            return Ok(false);
        }
        if self.sweeper.aug.ended {
            return Ok(false);
        }
        // The sweeps of the tangents' own cycle no longer count towards one.
        let since = self.tangents_cycled_at.unwrap_or(0);
        // The tail's retunes so far are among those applied.
        let tails = self.applied.iter().filter(|a| a.tail).count();
        let mut kind = match retuned(&self.history[since..], frictional, self.n_contact) {
            Some(kind) => kind,
            None if tail(&self.history, &self.sweeper.aug, tails) => Retune::Tail,
            None => return Ok(false),
        };
        let fixed_thresholds = matches!(law, Law::Fixed(_));
        if fixed_thresholds
            && self.tangents_cycled_at.is_none()
            && matches!(kind, Retune::EndCycle { .. })
        {
            self.tangents_cycled_at = Some(self.history.len());
            kind = Retune::ToStatus;
        }
        let pressed = self.history.last().map_or(0, |s| s.active);
        let follow = tangents_follow(fixed_thresholds, pressed, self.tangents_cycled_at.is_some());
        let n = last.p.len();
        let held: Vec<Held> = (0..n).map(|i| last.held(i, frictional)).collect();
        let (r, stiffness) = (self.sweeper.r_ref, self.sweeper.mesh_stiffness);
        let aug = match kind {
            Retune::EndCycle { since } => {
                let cycled = self.sweeper.changed_since(since);
                Augmentation::after_cycle(&held, &cycled, frictional, r, stiffness)
            }
            // The spent budget's statuses still moving: those the last sweep changed.
            Retune::BudgetSpent => {
                let cycled = self
                    .sweeper
                    .changed_since(self.history.len().saturating_sub(1));
                Augmentation::after_cycle(&held, &cycled, frictional, r, stiffness)
            }
            _ => {
                let from_settled = self.sweeper.aug.settled;
                Augmentation::for_statuses(
                    kind,
                    &held,
                    frictional,
                    (r, stiffness),
                    from_settled,
                    follow,
                )
            }
        };
        if !self.sweeper.step.set_r(&aug.r_n, &aug.r_t)? {
            self.can_retune = false;
            return Ok(false);
        }
        for i in 0..n {
            x[i] = state(last.p[i], last.lambda[i], aug.r_n[i]);
            if frictional {
                x[n + i] = state(last.q[i], last.mu[i], aug.r_t[i]);
            }
        }
        self.applied.push(aug.clone());
        self.sweeper.aug = aug;
        self.retunes += 1;
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
        let resumed = self.resume.as_ref().and_then(|r| r.outer.clone());
        let (mut s, mut done_outer, mut last_change) =
            resumed.unwrap_or((vec![0.0; n], 0, f64::INFINITY));
        loop {
            let outer_iterations = done_outer + 1;
            self.outer = Some((s.clone(), done_outer, last_change));
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
            if !inner_ok || self.history.len() >= self.params.max_iter || done {
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

    /// Resumes from a snapshot: r per direction, the counters and history, the last
    /// accepted point with its evaluation, and the Anderson memory.
    fn resume_from(
        &mut self,
        snap: Snapshot,
        law: Law,
        x: &mut Vec<f64>,
        aa: &mut Anderson,
    ) -> Result<Evaluated> {
        let sweeper = &mut self.sweeper;
        for aug in &snap.applied {
            if aug.r_n.len() != sweeper.aug.r_n.len() || !sweeper.step.set_r(&aug.r_n, &aug.r_t)? {
                return Err(Error::Input(
                    "the checkpoint was taken with r retuned per contact direction and this linear step cannot change r; restart without --restart".into(),
                ));
            }
        }
        sweeper.aug = snap.aug;
        self.applied = snap.applied;
        sweeper.r_ref = snap.r_ref;
        let out = project_and_update(&snap.gx, sweeper.nodes, law, &sweeper.aug);
        let (active, slip) = snap.history.last().map_or((0, 0), |s| (s.active, s.slip));
        self.refused_on = snap.refused_on;
        self.tangents_cycled_at = snap.tangents_cycled_at;
        sweeper.remember_statuses(&out, law.frictional(), 0);
        if snap.changed_at.len() == sweeper.changed_at.len() {
            // A checkpoint from before the normals' own record: their last change taken
            // as the node's (a normal then counts as cycling where its node did).
            sweeper.normal_changed_at = if snap.normal_changed_at.len() == snap.changed_at.len() {
                snap.normal_changed_at
            } else {
                snap.changed_at.clone()
            };
            sweeper.changed_at = snap.changed_at;
        }
        self.retunes = snap.retunes;
        self.min_secant = snap.min_secant;
        self.anchor = None;
        self.history = snap.history;
        self.refused = snap.refused;
        let f = snap.gx.iter().zip(&snap.x).map(|(a, b)| a - b).collect();
        *x = snap.x;
        (aa.df, aa.dg, aa.last) = (snap.df, snap.dg, snap.last);
        Ok(Evaluated {
            f,
            gx: snap.gx,
            out,
            res: snap.res,
            gram: snap.gram,
            worst: snap.worst,
            secant: snap.secant,
            active,
            slip,
        })
    }

    fn next_checkpoint(&self) -> usize {
        match self.ckpt.every {
            0 => usize::MAX,
            k => (self.history.len() / k + 1) * k,
        }
    }

    /// Saves a snapshot of the last accepted point `x` and everything needed to resume
    /// from it.
    fn save(&mut self, x: &[f64], cur: &Evaluated, aa: &Anderson) -> Result<()> {
        let snap = Snapshot {
            history: self.history.clone(),
            refused: self.refused,
            x: x.to_vec(),
            gx: cur.gx.clone(),
            res: cur.res,
            gram: cur.gram.clone(),
            worst: cur.worst,
            df: aa.df.clone(),
            dg: aa.dg.clone(),
            last: aa.last.clone(),
            outer: self.outer.clone(),
            aug: self.sweeper.aug.clone(),
            retunes: self.retunes,
            min_secant: self.min_secant,
            secant: cur.secant,
            r_ref: self.sweeper.r_ref,
            applied: self.applied.clone(),
            refused_on: self.refused_on,
            tangents_cycled_at: self.tangents_cycled_at,
            changed_at: self.sweeper.changed_at.clone(),
            normal_changed_at: self.sweeper.normal_changed_at.clone(),
        };
        (self.ckpt.save)(&snap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::retune::MAX_RETUNES;
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
            adapt_r: false,
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

    fn tunable(friction: Friction, adapt_r: bool) -> (Outcome, usize) {
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
        p.adapt_r = adapt_r;
        let o = solve(&mut s, &NoComm, &nodes, &p, &mut |_| {}).unwrap();
        (o, s.set_calls)
    }

    #[test]
    fn r_is_lowered_for_a_body_far_softer_than_a_compact_one() {
        // r = 10 and E_eff / h = 100: a compact body would have the stiffness
        // r^2 / 100 = 1 per unit W-length. Springs k on weights w = 0.5 have k / w.
        for (k, lowered) in [(1e-3, Some(10.0 * (2e-3 / SOFT_BODY).powi(2))), (2.0, None)] {
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
            p.adapt_r = true;
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
            assert!(last.stiff + last.soft > 0 || tuned.retunes == MAX_RETUNES);
            assert!(tuned.retunes <= MAX_RETUNES);
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
