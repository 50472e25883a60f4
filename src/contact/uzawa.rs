//! The Uzawa block relaxation loop (ALG2 of ALGORITHM.md), written once for any rank
//! count: it sees only this rank's contact nodes, a [`LinearStep`] and a [`Reduce`].
//!
//! ## The sweep as a fixed-point map
//! Steps 2 and 3 of a sweep only read s = Nu + lambda / r (normal) and z = Tu + mu / r
//! (tangential) at each node: p = min(g, s), lambda = r (s - p); q = shrink(z, s_f / r),
//! mu = r (z - q). So one sweep is a map x -> G(x) of the state x = (s, z), one value
//! (two with friction) per contact node:
//!   1. from x: p, lambda, q, mu and the forces w (r p - lambda), w (r q - mu);
//!   2. the linear step: (Nu, Tu);
//!   3. G(x) = (Nu + lambda / r, Tu + mu / r).
//!
//! Iterating G is exactly ALG2; this form lets an accelerator act on x. Each contact
//! direction may have its own r (an [`Augmentation`], retuned once the statuses settle:
//! see [`retuned`]); the formulas above then read r_n or r_t of the node.
//!
//! ## Acceleration
//! Anderson mixing (type II, memory m) on G, with an inner product in force units (each
//! direction weighted by w (r / r_ref)^2, see [`metric`]) summed over all ranks, so every
//! rank computes the same mixing coefficients and the iterates do not depend on the rank
//! count. Safeguard: a mixed point is kept only if its fixed-point residual |G(y) - y|
//! (same norm) does not exceed the residual of the last kept point; otherwise the plain
//! step G(x) is taken and the memory is cleared. The plain method therefore bounds the
//! accelerated one (at the price of one extra solve per refusal).
//!
//! ## Communication per sweep
//! One linear step, and one all-reduce of 15 + m(m+1)/2 + m numbers: the squared
//! W-norms of the residuals, displacements and multipliers, the active, slip, changed,
//! stiff, soft and mistuned counts, and the Anderson Gram matrix and right-hand side.
//!
//! ## Residuals
//! Both are in force units and relative to S = max(|lambda|_W + |mu|_W, r (|Nu|_W +
//! |Tu|_W)): primal = |lambda+ - lambda|_W + |mu+ - mu|_W (= r |Nu - p+|), dual =
//! r (|p+ - p|_W + |q+ - q|_W), with the reference r whatever the r of each direction,
//! so that a retune does not move the test. The multipliers set the scale when there is contact,
//! the displacements when there is none: a displacement-only scale fails when contact
//! nodes sit exactly on the foundation (Nu -> g = 0).

use super::kernels::{coulomb_threshold, normal_from_state, tangential_from_state};
use super::{ContactNodes, LinearStep, Reduce, Status};
use crate::contact::{Acceleration, CoulombMode, Friction};
use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// Augmentation parameter r > 0.
    pub r: f64,
    /// Relative tolerance on both residuals.
    pub tol: f64,
    /// Budget of sweeps (linear solves), over all outer iterations.
    pub max_iter: usize,
    pub friction: Friction,
    pub coulomb: CoulombMode,
    pub acceleration: Acceleration,
    /// Retune r per contact direction when the loop settles (see [`retuned`]).
    pub adapt_r: bool,
}

/// One line of the convergence history (one linear solve).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sweep {
    pub iter: usize,
    pub primal: f64,
    pub dual: f64,
    pub active: usize,
    pub slip: usize,
    /// Contact nodes whose status (free, stick, slip) in the image of this sweep differs
    /// from the one in the image of the sweep before.
    pub changed: usize,
    /// Contact directions (normal and, with friction, tangential) whose r in this
    /// sweep's linear step is raised above the reference r, and lowered below it.
    pub stiff: usize,
    pub soft: usize,
    /// Directions whose r differs from what their status in the image asks for.
    pub mistuned: usize,
    /// Retunes of r before this sweep.
    pub retunes: usize,
}

/// The converged (or last) state on this rank's contact nodes.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub converged: bool,
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
    /// Coulomb outer mode: the frozen thresholds and the outer iteration.
    pub outer: Option<(Vec<f64>, usize)>,
    /// This rank's r per contact direction at the last accepted point.
    pub aug: Augmentation,
    /// Retunes of r so far.
    pub retunes: usize,
}

/// The augmentation parameter of each contact direction on this rank: ALG2 converges
/// for any positive r per direction (it is the method in a rescaled constraint), and
/// the best r differs between held and free directions (see [`retuned`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Augmentation {
    pub r_n: Vec<f64>,
    pub r_t: Vec<f64>,
}

impl Augmentation {
    pub fn uniform(n: usize, r: f64) -> Self {
        Augmentation {
            r_n: vec![r; n],
            r_t: vec![r; n],
        }
    }
}

/// Periodic snapshots of the loop, and an optional one to resume from.
pub struct Checkpoints<'a> {
    /// Save every this many sweeps (0: never).
    pub every: usize,
    pub save: &'a mut dyn FnMut(&Snapshot) -> Result<()>,
    pub resume: Option<Snapshot>,
}

/// The slip thresholds seen by one run of sweeps.
#[derive(Clone, Copy)]
enum Law<'a> {
    Frictionless,
    Fixed(&'a [f64]),
    Coulomb(f64),
}

impl Law<'_> {
    fn frictional(&self) -> bool {
        !matches!(self, Law::Frictionless)
    }

    fn threshold(&self, i: usize, lambda: f64) -> f64 {
        match *self {
            Law::Frictionless => 0.0,
            Law::Fixed(s) => s[i],
            Law::Coulomb(c) => coulomb_threshold(c, lambda),
        }
    }
}

/// Multipliers and auxiliary variables derived from a state.
struct Derived {
    p: Vec<f64>,
    lambda: Vec<f64>,
    q: Vec<f64>,
    mu: Vec<f64>,
}

fn derive(x: &[f64], nodes: &ContactNodes, law: Law, aug: &Augmentation) -> Derived {
    let n = nodes.len();
    let mut d = Derived {
        p: vec![0.0; n],
        lambda: vec![0.0; n],
        q: vec![0.0; n],
        mu: vec![0.0; n],
    };
    for i in 0..n {
        let (p, lambda) = normal_from_state(x[i], nodes.g[i], aug.r_n[i]);
        d.p[i] = p;
        d.lambda[i] = lambda;
        if law.frictional() {
            let (q, mu) = tangential_from_state(x[n + i], law.threshold(i, lambda), aug.r_t[i]);
            d.q[i] = q;
            d.mu[i] = mu;
        }
    }
    d
}

impl Derived {
    /// Whether node i's normal and tangential directions are held: pressed onto the
    /// foundation, and sticking (with friction).
    fn held(&self, i: usize, frictional: bool) -> (bool, bool) {
        (self.lambda[i] > 0.0, frictional && self.q[i] == 0.0)
    }
}

/// Local sums of one evaluation, reduced over the ranks with the Anderson sums.
const N_SUMS: usize = 14;

/// One evaluation of G: its value, the quantities derived from the input and output,
/// and the local sums of the residual statistics.
struct Eval {
    gx: Vec<f64>,
    out: Derived,
    sums: [f64; N_SUMS],
}

struct Sweeper<'a, S: LinearStep> {
    step: &'a mut S,
    nodes: &'a ContactNodes,
    /// The reference r: the scale of the residuals, and the r of a direction not retuned.
    r_ref: f64,
    aug: Augmentation,
    /// The statuses in the image of the last evaluation (empty before the first).
    last_held: Vec<(bool, bool)>,
    force_n: Vec<f64>,
    force_t: Vec<f64>,
    un: Vec<f64>,
    ut: Vec<f64>,
}

impl<S: LinearStep> Sweeper<'_, S> {
    fn eval(&mut self, x: &[f64], law: Law) -> Result<Eval> {
        let (n, r, aug) = (self.nodes.len(), self.r_ref, &self.aug);
        let frictional = law.frictional();
        let w = &self.nodes.w;
        let inp = derive(x, self.nodes, law, aug);
        for i in 0..n {
            self.force_n[i] = w[i] * (aug.r_n[i] * inp.p[i] - inp.lambda[i]);
            self.force_t[i] = w[i] * (aug.r_t[i] * inp.q[i] - inp.mu[i]);
        }
        self.step
            .solve(&self.force_n, &self.force_t, &mut self.un, &mut self.ut)?;
        let mut gx = vec![0.0; x.len()];
        for i in 0..n {
            gx[i] = self.un[i] + inp.lambda[i] / aug.r_n[i];
            if frictional {
                gx[n + i] = self.ut[i] + inp.mu[i] / aug.r_t[i];
            }
        }
        let out = derive(&gx, self.nodes, law, aug);
        let mut sums = [0.0; N_SUMS];
        // The residuals are measured with the reference r whatever the r of each
        // direction, so that a retune does not move the stopping test.
        for i in 0..n {
            sums[0] += w[i] * (out.lambda[i] - inp.lambda[i]).powi(2);
            sums[1] += w[i] * (out.mu[i] - inp.mu[i]).powi(2);
            sums[2] += w[i] * (r * (out.p[i] - inp.p[i])).powi(2);
            sums[3] += w[i] * (r * (out.q[i] - inp.q[i])).powi(2);
            sums[4] += w[i] * (r * self.un[i]).powi(2);
            sums[5] += w[i] * (r * self.ut[i]).powi(2);
            sums[6] += w[i] * out.lambda[i].powi(2);
            sums[7] += w[i] * out.mu[i].powi(2);
            if out.lambda[i] > 0.0 {
                sums[8] += 1.0;
                if !frictional || out.q[i] != 0.0 {
                    sums[9] += 1.0;
                }
            }
            let held = out.held(i, frictional);
            // The first sweep compares with the statuses of its input.
            let before = self.last_held.get(i).copied();
            if before.unwrap_or_else(|| inp.held(i, frictional)) != held {
                sums[10] += 1.0;
            }
            let (want_n, want_t) = tuned(held, frictional, r);
            for (have, want) in [(aug.r_n[i], want_n), (aug.r_t[i], want_t)] {
                if have > r {
                    sums[11] += 1.0;
                } else if have < r {
                    sums[12] += 1.0;
                }
                if have != want {
                    sums[13] += 1.0;
                }
            }
        }
        self.last_held = (0..n).map(|i| out.held(i, frictional)).collect();
        Ok(Eval { gx, out, sums })
    }
}

/// Weighted inner product of two states, one weight per component (see [`metric`]).
fn dot(a: &[f64], b: &[f64], omega: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .zip(omega)
        .map(|((x, y), o)| o * x * y)
        .sum()
}

/// The weights of the state norm: w (r / r_ref)^2 per direction, so that a state
/// difference is measured in force units, r times a displacement, with each direction's
/// own r. Once r is retuned, a held direction's state moves by its multiplier change over a
/// large r and a free one's by a displacement: unweighted, the mixing would fit the free
/// directions and neglect the held ones, which the stopping test weighs in force units.
fn metric(w: &[f64], aug: &Augmentation, r_ref: f64, frictional: bool) -> Vec<f64> {
    let scaled = |r: &[f64]| -> Vec<f64> {
        w.iter()
            .zip(r)
            .map(|(w, r)| w * (r / r_ref).powi(2))
            .collect()
    };
    let mut omega = scaled(&aug.r_n);
    if frictional {
        omega.extend(scaled(&aug.r_t));
    }
    omega
}

/// Anderson memory: differences of residuals and of images of the last iterations.
struct Anderson {
    m: usize,
    df: Vec<Vec<f64>>,
    dg: Vec<Vec<f64>>,
    last: Option<(Vec<f64>, Vec<f64>)>,
}

impl Anderson {
    fn new(m: usize) -> Self {
        Anderson {
            m,
            df: Vec::new(),
            dg: Vec::new(),
            last: None,
        }
    }

    fn clear(&mut self) {
        self.df.clear();
        self.dg.clear();
        self.last = None;
    }

    /// Records (f, g) of an accepted point.
    fn push(&mut self, f: &[f64], g: &[f64]) {
        if let Some((f0, g0)) = self.last.take() {
            if self.df.len() == self.m {
                self.df.remove(0);
                self.dg.remove(0);
            }
            self.df
                .push(f.iter().zip(&f0).map(|(a, b)| a - b).collect());
            self.dg
                .push(g.iter().zip(&g0).map(|(a, b)| a - b).collect());
        }
        self.last = Some((f.to_vec(), g.to_vec()));
    }

    /// Local parts of the Gram matrix DF'DF (upper triangle, row by row) and of DF' f,
    /// where DF is the memory as it will be once (f, g) is pushed: computing them with
    /// the evaluation lets one reduction per sweep serve both the statistics and the
    /// mixing.
    fn local_sums_with_new(&self, f: &[f64], omega: &[f64]) -> Vec<f64> {
        let mut diffs: Vec<&[f64]> = self.df.iter().map(Vec::as_slice).collect();
        let newest: Vec<f64>;
        if let Some((f0, _)) = &self.last {
            newest = f.iter().zip(f0).map(|(a, b)| a - b).collect();
            if diffs.len() == self.m {
                diffs.remove(0);
            }
            diffs.push(&newest);
        }
        let k = diffs.len();
        let mut v = Vec::with_capacity(k * (k + 1) / 2 + k);
        for a in 0..k {
            for b in a..k {
                v.push(dot(diffs[a], diffs[b], omega));
            }
        }
        for a in 0..k {
            v.push(dot(diffs[a], f, omega));
        }
        v
    }

    /// The mixed point g - DG gamma with (DF'DF) gamma = DF' f from the global sums;
    /// `None` when the memory is empty or the small system is singular.
    fn mix(&self, g: &[f64], sums: &[f64]) -> Option<Vec<f64>> {
        let k = self.df.len();
        if k == 0 {
            return None;
        }
        let mut a = vec![vec![0.0; k]; k];
        let mut idx = 0;
        for i in 0..k {
            for j in i..k {
                a[i][j] = sums[idx];
                a[j][i] = sums[idx];
                idx += 1;
            }
        }
        let mut b: Vec<f64> = sums[idx..idx + k].to_vec();
        // Jacobi scaling first: the differences in memory can span many orders of
        // magnitude (early sweeps against late ones), and a regularisation relative to
        // the largest would drown the newest, most useful ones.
        let scale: Vec<f64> = (0..k).map(|i| a[i][i].sqrt()).collect();
        // NaN-safe: a NaN diagonal fails this test too.
        if scale.iter().any(|d| d.is_nan() || *d <= 0.0) {
            return None;
        }
        for i in 0..k {
            for j in 0..k {
                a[i][j] /= scale[i] * scale[j];
            }
            b[i] /= scale[i];
            // A little Tikhonov regularisation keeps nearly dependent differences harmless.
            a[i][i] += 1e-10;
        }
        let mut gamma = solve_small_spd(a, &mut b)?;
        for (c, d) in gamma.iter_mut().zip(&scale) {
            *c /= d;
        }
        let mut y = g.to_vec();
        for (c, dg) in gamma.iter().zip(&self.dg) {
            for (yi, d) in y.iter_mut().zip(dg) {
                *yi -= c * d;
            }
        }
        Some(y)
    }
}

/// Cholesky solve of a small SPD system (the Anderson least-squares normal equations).
fn solve_small_spd(mut a: Vec<Vec<f64>>, b: &mut [f64]) -> Option<Vec<f64>> {
    let k = b.len();
    for j in 0..k {
        let mut d = a[j][j];
        for p in 0..j {
            d -= a[j][p] * a[j][p];
        }
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..k {
            let mut s = a[i][j];
            for p in 0..j {
                s -= a[i][p] * a[j][p];
            }
            a[i][j] = s / d;
        }
    }
    for i in 0..k {
        let mut s = b[i];
        for p in 0..i {
            s -= a[i][p] * b[p];
        }
        b[i] = s / a[i][i];
    }
    for i in (0..k).rev() {
        let mut s = b[i];
        for p in i + 1..k {
            s -= a[p][i] * b[p];
        }
        b[i] = s / a[i][i];
    }
    Some(b.to_vec())
}

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
    let mut sweeper = Sweeper {
        step,
        nodes,
        r_ref: params.r,
        aug: Augmentation::uniform(n, params.r),
        last_held: Vec::new(),
        force_n: vec![0.0; n],
        force_t: vec![0.0; n],
        un: vec![0.0; n],
        ut: vec![0.0; n],
    };
    // Start: lambda = mu = 0, p = min(g, 0), q = 0, i.e. s = min(g, 0), z = 0.
    let mut x: Vec<f64> = nodes.g.iter().map(|g| g.min(0.0)).collect();
    if frictional {
        x.resize(2 * n, 0.0);
    }
    let resume = ckpt.resume.take();
    let resume_outer = resume.as_ref().and_then(|r| r.outer.clone());
    let mut total = [n as f64];
    comm.sum_in_place(&mut total);
    let mut run = Run {
        n_contact: total[0] as usize,
        history: Vec::new(),
        retunes: 0,
        can_retune: true,
        refused: 0,
        ckpt,
        resume,
        outer: None,
    };
    let mut outer_iterations = 1;
    let (converged, last, threshold) = match (params.friction, params.coulomb) {
        (Friction::None, _) => {
            let (c, d) = run.sweeps(
                &mut sweeper,
                comm,
                params,
                Law::Frictionless,
                &mut x,
                monitor,
            )?;
            (c, d, vec![0.0; n])
        }
        (Friction::Tresca { threshold }, _) => {
            let s = vec![threshold; n];
            let (c, d) = run.sweeps(&mut sweeper, comm, params, Law::Fixed(&s), &mut x, monitor)?;
            (c, d, s)
        }
        (Friction::Coulomb { coefficient }, CoulombMode::Inner) => {
            let (c, d) = run.sweeps(
                &mut sweeper,
                comm,
                params,
                Law::Coulomb(coefficient),
                &mut x,
                monitor,
            )?;
            let s = d
                .lambda
                .iter()
                .map(|&l| coulomb_threshold(coefficient, l))
                .collect();
            (c, d, s)
        }
        (Friction::Coulomb { coefficient }, CoulombMode::Outer) => {
            let (mut s, mut done_outer) = resume_outer.unwrap_or((vec![0.0; n], 0));
            loop {
                outer_iterations = done_outer + 1;
                run.outer = Some((s.clone(), done_outer));
                let (inner_ok, d) =
                    run.sweeps(&mut sweeper, comm, params, Law::Fixed(&s), &mut x, monitor)?;
                let s_new: Vec<f64> = d
                    .lambda
                    .iter()
                    .map(|&l| coulomb_threshold(coefficient, l))
                    .collect();
                let mut sums = [0.0; 2];
                for i in 0..n {
                    sums[0] += nodes.w[i] * (s_new[i] - s[i]).powi(2);
                    sums[1] += nodes.w[i] * s_new[i].powi(2);
                }
                comm.sum_in_place(&mut sums);
                let change = relative(sums[0].sqrt(), sums[1].sqrt());
                let done = change <= params.tol;
                // The tangential state was converged for the old thresholds: keep it.
                s = s_new;
                done_outer += 1;
                if !inner_ok || run.history.len() >= params.max_iter || done {
                    break (inner_ok && done, d, s);
                }
            }
        }
    };
    let status = (0..n)
        .map(|i| {
            if last.lambda[i] <= 0.0 {
                Status::Free
            } else if !frictional || last.q[i] != 0.0 {
                Status::Slip
            } else {
                Status::Stick
            }
        })
        .collect();
    Ok(Outcome {
        converged,
        iterations: run.history.len(),
        outer_iterations,
        refused: run.refused,
        retunes: run.retunes,
        lambda: last.lambda,
        mu: last.mu,
        un: sweeper.un,
        ut: sweeper.ut,
        threshold,
        status,
        history: run.history,
    })
}

/// Sweeps without a status change that [`retuned`] waits for; one more with friction,
/// whose stick/slip statuses follow the pressures and settle later (retuning one sweep
/// earlier scrambled them on the built-in frictional cases).
const SETTLED_SWEEPS: usize = 1;
/// Factors from the reference r for a held normal (raised) and a free one (lowered).
/// 1000 x keeps the condition number of the contact block within three more decades;
/// measured on frictionless full contact (block, levels 1-4): 10 x, 9-11 sweeps; 100 x,
/// 7-8; 1000 x, 6.
const NORMAL_FACTOR: f64 = 1000.0;
/// The same for the tangents. Friction statuses are fragile (a sticking node flips to
/// slip when a large r amplifies the remaining tangential motion): over the built-in
/// frictional cases at levels 1-3, 10 x gave 22-42 sweeps, 30 x 19-56, 1000 x 20-112.
const TANGENT_FACTOR: f64 = 10.0;
/// Retunes to the statuses allowed; after them, a further settled change of the
/// statuses returns every direction to the reference r (once).
const MAX_RETUNES: usize = 4;

/// The r of a node's normal and tangential directions once their statuses have settled:
/// raised where held (pressed, sticking), lowered where free (open, slipping). Without
/// friction the tangent is not part of the method and keeps r.
fn tuned((held_n, held_t): (bool, bool), frictional: bool, r: f64) -> (f64, f64) {
    let pick = |held: bool, factor: f64| if held { r * factor } else { r / factor };
    let t = if frictional {
        pick(held_t, TANGENT_FACTOR)
    } else {
        r
    };
    (pick(held_n, NORMAL_FACTOR), t)
}

/// What [`retuned`] asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Retune {
    /// Each direction to the r its status asks for ([`tuned`]).
    ToStatus,
    /// Every direction back to the reference r.
    ToReference,
}

/// Whether to retune r now, from the history alone (global counts: every rank decides
/// the same, whatever the rank count).
///
/// Why: r acts as a spring r w on each contact direction. A held direction (an active
/// normal, a sticking tangent) is an equality the sweep enforces by contracting each of
/// its modes by 1 / (1 + r c) (c a contact compliance): large r is best. A free
/// direction (an open node, a slipping tangent) is pinned by the spring near its last
/// value and moves by r c / (1 + r c) of the way: small r is best. One r for all
/// balances the two and sweeps slowly (plain Hertz: 423 sweeps at level 3, Anderson
/// 54). Once the statuses stop changing, the held and free sets are known and each
/// direction gets its own r (ALG2 converges for any positive r per direction: it is the
/// same method for rescaled constraints).
///
/// When: the last [`SETTLED_SWEEPS`] sweeps, all with the current r, changed no status,
/// and some direction's r differs from what its status asks for. At most
/// [`MAX_RETUNES`] times, then once back to the reference r if the statuses move
/// again: a retune costs one dense refactorization of the contact blocks.
pub fn retuned(history: &[Sweep], frictional: bool, n_contact: usize) -> Option<Retune> {
    let last = history.last()?;
    let settled = if frictional {
        SETTLED_SWEEPS + 1
    } else {
        SETTLED_SWEEPS
    };
    if history.len() < settled || last.mistuned == 0 {
        return None;
    }
    let tail = &history[history.len() - settled..];
    if !tail
        .iter()
        .all(|s| s.changed == 0 && s.retunes == last.retunes)
    {
        return None;
    }
    match last.retunes {
        k if k < MAX_RETUNES && 2 * n_contact <= MAX_RETUNE_DOFS => Some(Retune::ToStatus),
        MAX_RETUNES if last.stiff + last.soft > 0 => Some(Retune::ToReference),
        _ => None,
    }
}

/// Contact dofs (two per contact node, over all ranks) above which r is not retuned. The
/// first retune refactors the dense contact blocks, about c^3 / 3 flops for c contact
/// dofs, which costs as much as 30-80 sweeps (measured on hertz, frictionless, one rank:
/// 28, 38, 62, 78, 80 sweeps at c = 222, 440, 878, 1756, 3508; 0.5 s at c = 3508, 1.2 s
/// on two ranks); the later ones move a few directions and update the factor in place
/// (`LocalFactor::update_boundary`) for a fraction of that. Up to 2048 a retune takes at
/// most about 0.1 s, negligible next to the factorization; above, the seconds it takes
/// exceed what the sweeps it saves cost, and Anderson mixing alone is faster.
const MAX_RETUNE_DOFS: usize = 2048;

fn relative(value: f64, scale: f64) -> f64 {
    if scale > 0.0 {
        value / scale
    } else {
        value
    }
}

struct Run<'c, 'a> {
    /// Contact nodes over all ranks.
    n_contact: usize,
    history: Vec<Sweep>,
    retunes: usize,
    /// False once the linear step has declined a change of r.
    can_retune: bool,
    refused: usize,
    ckpt: &'c mut Checkpoints<'a>,
    resume: Option<Snapshot>,
    outer: Option<(Vec<f64>, usize)>,
}

/// An evaluation of G after the global reduction.
struct Evaluated {
    e: Eval,
    /// |G(x) - x|_W over all ranks.
    res: f64,
    /// Anderson Gram sums with this point's residual difference included.
    gram: Vec<f64>,
    /// max(primal, dual) relative residual.
    worst: f64,
}

impl Run<'_, '_> {
    /// Evaluates G at `x` with one global reduction (statistics and, when accelerating,
    /// the Gram sums of `aa` at the new residual); records the sweep.
    fn evaluate<S: LinearStep>(
        &mut self,
        sweeper: &mut Sweeper<S>,
        comm: &impl Reduce,
        law: Law,
        x: &[f64],
        aa: Option<&Anderson>,
        monitor: &mut dyn FnMut(&Sweep),
    ) -> Result<Evaluated> {
        let r = sweeper.r_ref;
        let e = sweeper.eval(x, law)?;
        let f: Vec<f64> = e.gx.iter().zip(x).map(|(a, b)| a - b).collect();
        let mut buf: Vec<f64> = e.sums.to_vec();
        let omega = metric(&sweeper.nodes.w, &sweeper.aug, r, law.frictional());
        buf.push(dot(&f, &f, &omega));
        if let Some(aa) = aa {
            buf.extend(aa.local_sums_with_new(&f, &omega));
        }
        comm.sum_in_place(&mut buf);
        let s = &buf;
        let scale = (s[6].sqrt() + s[7].sqrt()).max(s[4].sqrt() + s[5].sqrt());
        let sweep = Sweep {
            iter: self.history.len() + 1,
            primal: relative(s[0].sqrt() + s[1].sqrt(), scale),
            dual: relative(s[2].sqrt() + s[3].sqrt(), scale),
            active: s[8] as usize,
            slip: s[9] as usize,
            changed: s[10] as usize,
            stiff: s[11] as usize,
            soft: s[12] as usize,
            mistuned: s[13] as usize,
            retunes: self.retunes,
        };
        if !(sweep.primal.is_finite() && sweep.dual.is_finite() && scale.is_finite()) {
            return Err(Error::Numerical(format!(
                "iteration {}: the residuals are not finite (NaN or overflow); the problem may be unstable (check the Dirichlet conditions and the material) or r = {r} unsuitable",
                sweep.iter
            )));
        }
        self.history.push(sweep);
        monitor(&sweep);
        Ok(Evaluated {
            worst: sweep.primal.max(sweep.dual),
            res: s[N_SUMS].sqrt(),
            gram: s[N_SUMS + 1..].to_vec(),
            e,
        })
    }

    fn next_checkpoint(&self) -> usize {
        match self.ckpt.every {
            0 => usize::MAX,
            k => (self.history.len() / k + 1) * k,
        }
    }

    fn save(
        &mut self,
        x: &[f64],
        cur: &Evaluated,
        aa: &Anderson,
        aug: &Augmentation,
    ) -> Result<()> {
        let snap = Snapshot {
            history: self.history.clone(),
            refused: self.refused,
            x: x.to_vec(),
            gx: cur.e.gx.clone(),
            res: cur.res,
            gram: cur.gram.clone(),
            worst: cur.worst,
            df: aa.df.clone(),
            dg: aa.dg.clone(),
            last: aa.last.clone(),
            outer: self.outer.clone(),
            aug: aug.clone(),
            retunes: self.retunes,
        };
        (self.ckpt.save)(&snap)
    }

    /// Iterates from `x` until both residuals are below tol (true) or the budget is
    /// spent (false); returns the quantities derived from the last image G(x).
    fn sweeps<S: LinearStep>(
        &mut self,
        sweeper: &mut Sweeper<S>,
        comm: &impl Reduce,
        params: &Params,
        law: Law,
        x: &mut Vec<f64>,
        monitor: &mut dyn FnMut(&Sweep),
    ) -> Result<(bool, Derived)> {
        let memory = match params.acceleration {
            Acceleration::None => 0,
            Acceleration::Anderson { memory } => memory,
        };
        let mut aa = Anderson::new(memory);
        let aa_on = memory > 0;
        // The last accepted point is `x`, `cur` its evaluation.
        let mut cur = match self.resume.take() {
            Some(snap) => {
                if snap.aug != sweeper.aug {
                    if snap.aug.r_n.len() != sweeper.aug.r_n.len()
                        || !sweeper.step.set_r(&snap.aug.r_n, &snap.aug.r_t)?
                    {
                        return Err(Error::Input(
                            "the checkpoint was taken with r retuned per contact direction and this linear step cannot change r; restart without --restart".into(),
                        ));
                    }
                    sweeper.aug = snap.aug;
                }
                self.retunes = snap.retunes;
                let out = derive(&snap.gx, sweeper.nodes, law, &sweeper.aug);
                sweeper.last_held = (0..out.p.len())
                    .map(|i| out.held(i, law.frictional()))
                    .collect();
                self.history = snap.history;
                self.refused = snap.refused;
                *x = snap.x;
                (aa.df, aa.dg, aa.last) = (snap.df, snap.dg, snap.last);
                Evaluated {
                    e: Eval {
                        out,
                        gx: snap.gx,
                        sums: [0.0; N_SUMS],
                    },
                    res: snap.res,
                    gram: snap.gram,
                    worst: snap.worst,
                }
            }
            None => self.evaluate(sweeper, comm, law, x, aa_on.then_some(&aa), monitor)?,
        };
        let mut next_save = self.next_checkpoint();
        loop {
            if self.history.len() >= next_save
                && cur.worst > params.tol
                && self.history.len() < params.max_iter
            {
                self.save(x, &cur, &aa, &sweeper.aug)?;
                next_save = self.next_checkpoint();
            }
            if cur.worst <= params.tol || self.history.len() >= params.max_iter {
                *x = cur.e.gx;
                return Ok((cur.worst <= params.tol, cur.e.out));
            }
            if params.adapt_r && self.can_retune {
                if let Some(kind) = retuned(&self.history, law.frictional(), self.n_contact) {
                    let (n, r) = (sweeper.nodes.len(), sweeper.r_ref);
                    let d = &cur.e.out;
                    let frictional = law.frictional();
                    let mut aug = Augmentation::uniform(n, r);
                    if kind == Retune::ToStatus {
                        for i in 0..n {
                            (aug.r_n[i], aug.r_t[i]) = tuned(d.held(i, frictional), frictional, r);
                        }
                    }
                    if sweeper.step.set_r(&aug.r_n, &aug.r_t)? {
                        // The state with the new r that keeps p, lambda, q and mu of the
                        // last image exactly: s = p + lambda / r, z = q + mu / r.
                        for i in 0..n {
                            x[i] = d.p[i] + d.lambda[i] / aug.r_n[i];
                            if frictional {
                                x[n + i] = d.q[i] + d.mu[i] / aug.r_t[i];
                            }
                        }
                        sweeper.aug = aug;
                        self.retunes += 1;
                        aa.clear();
                        cur =
                            self.evaluate(sweeper, comm, law, x, aa_on.then_some(&aa), monitor)?;
                        continue;
                    }
                    self.can_retune = false;
                }
            }
            let proposal = if aa_on {
                let f: Vec<f64> = cur.e.gx.iter().zip(x.iter()).map(|(a, b)| a - b).collect();
                aa.push(&f, &cur.e.gx);
                aa.mix(&cur.e.gx, &cur.gram)
            } else {
                None
            };
            let Some(y) = proposal else {
                *x = std::mem::take(&mut cur.e.gx);
                cur = self.evaluate(sweeper, comm, law, x, aa_on.then_some(&aa), monitor)?;
                continue;
            };
            let next = self.evaluate(sweeper, comm, law, &y, Some(&aa), monitor)?;
            if next.res <= cur.res || next.worst <= params.tol {
                *x = y;
                cur = next;
            } else {
                // Refused: the plain step from the last accepted point, memory cleared.
                self.refused += 1;
                aa.clear();
                *x = std::mem::take(&mut cur.e.gx);
                cur = self.evaluate(sweeper, comm, law, x, Some(&aa), monitor)?;
            }
        }
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
            adapt_r: false,
        }
    }

    const PLAIN: Acceleration = Acceleration::None;
    const ANDERSON: Acceleration = Acceleration::Anderson { memory: 5 };

    fn run_with(friction: Friction, acc: Acceleration, f: [f64; 2], g: f64) -> Outcome {
        let nodes = ContactNodes {
            w: vec![0.5],
            g: vec![g],
        };
        let mut s = Springs {
            k: vec![2.0],
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
            assert_eq!(o.status[0], Status::Slip);
        }
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
        assert!(plain.converged && fast.converged);
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
        let plain = many(PLAIN, None);
        let scale = plain.lambda.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..plain.lambda.len() {
            assert!((plain.lambda[i] - kicked.lambda[i]).abs() < 1e-9 * scale);
        }
    }

    fn sweep(changed: usize, mistuned: usize, retunes: usize) -> Sweep {
        Sweep {
            iter: 1,
            primal: 1e-3,
            dual: 1e-3,
            active: 5,
            slip: 0,
            changed,
            stiff: 0,
            soft: 0,
            mistuned,
            retunes,
        }
    }

    #[test]
    fn r_is_retuned_once_the_statuses_have_settled() {
        let (moving, still) = (sweep(2, 5, 0), sweep(0, 5, 0));
        // Frictionless: one sweep without a change; with friction, two.
        assert_eq!(retuned(&[moving, still], false, 5), Some(Retune::ToStatus));
        assert_eq!(retuned(&[moving, still], true, 5), None);
        assert_eq!(
            retuned(&[moving, still, still], true, 5),
            Some(Retune::ToStatus)
        );
        assert_eq!(retuned(&[still, moving], false, 5), None);
        // Nothing to change, or a contact block too large to refactor cheaply.
        assert_eq!(retuned(&[moving, sweep(0, 0, 0)], false, 5), None);
        assert_eq!(retuned(&[moving, still], false, MAX_RETUNE_DOFS), None);
        // The settled sweeps must all be with the current r.
        let after = sweep(0, 3, 1);
        assert_eq!(retuned(&[still, after], true, 5), None);
        assert_eq!(
            retuned(&[still, after, after], true, 5),
            Some(Retune::ToStatus)
        );
        // After the budget, once back to the reference r, then never again.
        let mut spent = sweep(0, 3, MAX_RETUNES);
        spent.stiff = 2;
        assert_eq!(
            retuned(&[spent, spent], false, 5),
            Some(Retune::ToReference)
        );
        let reset = sweep(0, 3, MAX_RETUNES + 1);
        assert_eq!(retuned(&[reset, reset], false, 5), None);
    }

    #[test]
    fn tuned_r_raises_held_directions_and_lowers_free_ones() {
        let r = 10.0;
        assert_eq!(
            tuned((true, false), true, r),
            (r * NORMAL_FACTOR, r / TANGENT_FACTOR)
        );
        assert_eq!(
            tuned((false, true), true, r),
            (r / NORMAL_FACTOR, r * TANGENT_FACTOR)
        );
        // Without friction the tangent keeps the reference r.
        assert_eq!(tuned((true, false), false, r), (r * NORMAL_FACTOR, r));
    }

    #[test]
    fn metric_measures_state_differences_in_force_units() {
        let w = [2.0, 3.0];
        let r = 10.0;
        // One r everywhere: the weights are the contact weights, so the mixing is the same
        // as with the plain W inner product until the first retune.
        let uniform = Augmentation::uniform(2, r);
        assert_eq!(metric(&w, &uniform, r, false), vec![2.0, 3.0]);
        assert_eq!(metric(&w, &uniform, r, true), vec![2.0, 3.0, 2.0, 3.0]);
        // Retuned: a state change dx in a direction with spring r costs (r dx)^2 w / r_ref^2,
        // so a multiplier change r dx weighs the same whatever that direction's r.
        let aug = Augmentation {
            r_n: vec![1000.0 * r, r / 1000.0],
            r_t: vec![r / 10.0, 10.0 * r],
        };
        let omega = metric(&w, &aug, r, true);
        let dx = [1e-3, 1e3, 10.0, 0.1];
        let force: Vec<f64> = [aug.r_n.clone(), aug.r_t.clone()]
            .concat()
            .iter()
            .zip(dx)
            .map(|(r, d)| r * d)
            .collect();
        let expected: f64 = (0..4).map(|k| w[k % 2] * (force[k] / r).powi(2)).sum();
        assert!((dot(&dx, &dx, &omega) - expected).abs() <= 1e-12 * expected);
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
    fn retuned_loop_reaches_the_plain_answer() {
        for friction in [
            Friction::None,
            Friction::Tresca { threshold: 0.4 },
            Friction::Coulomb { coefficient: 0.3 },
        ] {
            let (fixed, none) = tunable(friction, false);
            let (tuned, calls) = tunable(friction, true);
            assert_eq!(none, 0);
            assert!(fixed.converged && tuned.converged, "{friction:?}");
            assert!(
                calls >= 1 && tuned.retunes == calls,
                "{friction:?}: {calls}"
            );
            let last = tuned.history.last().unwrap();
            assert!(last.stiff + last.soft > 0 || tuned.retunes > MAX_RETUNES);
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
