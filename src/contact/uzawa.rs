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
//! Iterating G is exactly ALG2; this form lets an accelerator act on x.
//!
//! ## Acceleration
//! Anderson mixing (type II, memory m) on G, with the W-weighted inner product summed
//! over all ranks, so every rank computes the same mixing coefficients and the iterates
//! do not depend on the rank count. Safeguard: a mixed point is kept only if its
//! fixed-point residual |G(y) - y| does not exceed the residual of the last kept point;
//! otherwise the plain step G(x) is taken and the memory is cleared. The plain method
//! therefore bounds the accelerated one (at the price of one extra solve per refusal).
//!
//! ## Communication per sweep
//! One linear step, and one all-reduce of 10 + m(m+1)/2 + m numbers: the squared
//! W-norms of the residuals, displacements and multipliers, the active and slip counts,
//! and the Anderson Gram matrix and right-hand side.
//!
//! ## Residuals
//! Both are in force units and relative to S = max(|lambda|_W + |mu|_W, r (|Nu|_W +
//! |Tu|_W)): primal = |lambda+ - lambda|_W + |mu+ - mu|_W (= r |Nu - p+|), dual =
//! r (|p+ - p|_W + |q+ - q|_W). The multipliers set the scale when there is contact,
//! the displacements when there is none: a displacement-only scale fails when contact
//! nodes sit exactly on the foundation (Nu -> g = 0).

use super::kernels::{coulomb_threshold, normal_from_state, tangential_from_state};
use super::{ContactNodes, LinearStep, Reduce, Status};
use crate::case::{Acceleration, CoulombMode, Friction};
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
    /// Raise r when the loop settles into a linear regime (see [`raised_r`]).
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
    /// The r of this sweep's linear step.
    pub r: f64,
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
    /// The r of the last accepted point.
    pub r: f64,
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

fn derive(x: &[f64], nodes: &ContactNodes, law: Law, r: f64) -> Derived {
    let n = nodes.len();
    let mut d = Derived {
        p: vec![0.0; n],
        lambda: vec![0.0; n],
        q: vec![0.0; n],
        mu: vec![0.0; n],
    };
    for i in 0..n {
        let (p, lambda) = normal_from_state(x[i], nodes.g[i], r);
        d.p[i] = p;
        d.lambda[i] = lambda;
        if law.frictional() {
            let (q, mu) = tangential_from_state(x[n + i], law.threshold(i, lambda), r);
            d.q[i] = q;
            d.mu[i] = mu;
        }
    }
    d
}

/// One evaluation of G: its value, the quantities derived from the input and output,
/// and the local sums of the residual statistics.
struct Eval {
    gx: Vec<f64>,
    out: Derived,
    sums: [f64; 10],
}

struct Sweeper<'a, S: LinearStep> {
    step: &'a mut S,
    nodes: &'a ContactNodes,
    r: f64,
    force_n: Vec<f64>,
    force_t: Vec<f64>,
    un: Vec<f64>,
    ut: Vec<f64>,
}

impl<S: LinearStep> Sweeper<'_, S> {
    fn eval(&mut self, x: &[f64], law: Law) -> Result<Eval> {
        let (n, r) = (self.nodes.len(), self.r);
        let w = &self.nodes.w;
        let inp = derive(x, self.nodes, law, r);
        for i in 0..n {
            self.force_n[i] = w[i] * (r * inp.p[i] - inp.lambda[i]);
            self.force_t[i] = w[i] * (r * inp.q[i] - inp.mu[i]);
        }
        self.step
            .solve(&self.force_n, &self.force_t, &mut self.un, &mut self.ut)?;
        let mut gx = vec![0.0; x.len()];
        for i in 0..n {
            gx[i] = self.un[i] + inp.lambda[i] / r;
            if law.frictional() {
                gx[n + i] = self.ut[i] + inp.mu[i] / r;
            }
        }
        let out = derive(&gx, self.nodes, law, r);
        let mut sums = [0.0; 10];
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
                if !law.frictional() || out.q[i] != 0.0 {
                    sums[9] += 1.0;
                }
            }
        }
        Ok(Eval { gx, out, sums })
    }
}

/// W-weighted inner product of two states (normal and tangential parts alike).
fn dot(a: &[f64], b: &[f64], w: &[f64]) -> f64 {
    let n = w.len();
    let mut s = 0.0;
    for i in 0..n {
        s += w[i] * a[i] * b[i];
        if a.len() > n {
            s += w[i] * a[n + i] * b[n + i];
        }
    }
    s
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
    fn local_sums_with_new(&self, f: &[f64], w: &[f64]) -> Vec<f64> {
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
                v.push(dot(diffs[a], diffs[b], w));
            }
        }
        for a in 0..k {
            v.push(dot(diffs[a], f, w));
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
        // A little Tikhonov regularisation keeps nearly dependent differences harmless.
        let diag = (0..k).map(|i| a[i][i]).fold(0.0, f64::max);
        // NaN-safe: a NaN diagonal fails this test too.
        if diag.is_nan() || diag <= 0.0 {
            return None;
        }
        for i in 0..k {
            a[i][i] += 1e-10 * diag;
        }
        let gamma = solve_small_spd(a, &mut b)?;
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
        r: params.r,
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
        lambda: last.lambda,
        mu: last.mu,
        un: sweeper.un,
        ut: sweeper.ut,
        threshold,
        status,
        history: run.history,
    })
}

/// Sweeps with the same active and slip counts that [`raised_r`] waits for.
const SETTLED_SWEEPS: usize = 2;
/// How much the primal residual must exceed the dual one.
const PRIMAL_DOMINANCE: f64 = 10.0;
/// Factor of the raise, and the number of raises allowed. Measured on frictionless full
/// contact (block, levels 1-4, plain and accelerated): 10 x 2 raises after 3 settled
/// sweeps, 9-11 sweeps; 100 x 1 after 2, 7-8; 1000 x 1 after 2, 6; 10^4, 5; the best
/// fixed r of a sweep over four decades, 5-6. 1000 keeps the condition number of the
/// boundary block within three more decades.
const RAISE: f64 = 1000.0;
const MAX_RAISES: usize = 1;

/// The raised r, if the history says the loop has settled into a linear regime where a
/// larger r can only help: the last [`SETTLED_SWEEPS`] sweeps with the current r had
/// every one of the `n_contact` contact nodes active and (with friction) sticking, and a
/// primal residual (the constraint violation) [`PRIMAL_DOMINANCE`] times the dual one.
/// The augmentation acts as a spring r w on every contact node: it speeds up the
/// directions that are constrained (active normal, sticking tangent), where the sweep
/// contracts each mode by 1 / (1 + r c_i) (c_i the contact compliances), and slows down
/// the free ones (an inactive node, a slipping tangent), which the spring pins near the
/// last projection. The default r balances the two; with no free direction left, the
/// conditions are linear equalities and r -> infinity is best (frictionless contact with
/// every node pressed onto the foundation at zero gap: 62-85 sweeps at the default r, 6
/// at 100 r, 6 with the raise). Raising r with free directions left was measured to hurt: plain Hertz at
/// tol 1e-12, 668 -> 5798 sweeps. A raise costs one dense refactorization of the
/// trailing factor blocks, hence at most [`MAX_RAISES`]. Uses only global counts and
/// residuals: every rank decides the same.
pub fn raised_r(history: &[Sweep], r: f64, n_contact: usize, frictional: bool) -> Option<f64> {
    let raises = history.windows(2).filter(|w| w[1].r != w[0].r).count();
    if raises >= MAX_RAISES || history.len() < SETTLED_SWEEPS {
        return None;
    }
    let tail = &history[history.len() - SETTLED_SWEEPS..];
    let settled = tail.iter().all(|s| {
        s.r == r
            && s.active == n_contact
            && n_contact > 0
            && (!frictional || s.slip == 0)
            && s.primal > PRIMAL_DOMINANCE * s.dual
    });
    settled.then_some(r * RAISE)
}

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
    /// The r it was evaluated with.
    r: f64,
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
        let r = sweeper.r;
        let e = sweeper.eval(x, law)?;
        let f: Vec<f64> = e.gx.iter().zip(x).map(|(a, b)| a - b).collect();
        let mut buf: Vec<f64> = e.sums.to_vec();
        buf.push(dot(&f, &f, &sweeper.nodes.w));
        if let Some(aa) = aa {
            buf.extend(aa.local_sums_with_new(&f, &sweeper.nodes.w));
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
            r,
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
            r,
            worst: sweep.primal.max(sweep.dual),
            res: s[10].sqrt(),
            gram: s[11..].to_vec(),
            e,
        })
    }

    fn next_checkpoint(&self) -> usize {
        match self.ckpt.every {
            0 => usize::MAX,
            k => (self.history.len() / k + 1) * k,
        }
    }

    fn save(&mut self, x: &[f64], cur: &Evaluated, aa: &Anderson) -> Result<()> {
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
            r: cur.r,
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
                if snap.r != sweeper.r {
                    if !sweeper.step.set_r(snap.r)? {
                        return Err(Error::Input(format!(
                            "the checkpoint was taken with r = {} and this linear step cannot change r; restart with --r {}",
                            snap.r, snap.r
                        )));
                    }
                    sweeper.r = snap.r;
                }
                self.history = snap.history;
                self.refused = snap.refused;
                *x = snap.x;
                (aa.df, aa.dg, aa.last) = (snap.df, snap.dg, snap.last);
                Evaluated {
                    e: Eval {
                        out: derive(&snap.gx, sweeper.nodes, law, sweeper.r),
                        gx: snap.gx,
                        sums: [0.0; 10],
                    },
                    res: snap.res,
                    gram: snap.gram,
                    worst: snap.worst,
                    r: snap.r,
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
                self.save(x, &cur, &aa)?;
                next_save = self.next_checkpoint();
            }
            if cur.worst <= params.tol || self.history.len() >= params.max_iter {
                *x = cur.e.gx;
                return Ok((cur.worst <= params.tol, cur.e.out));
            }
            if params.adapt_r {
                if let Some(r) =
                    raised_r(&self.history, sweeper.r, self.n_contact, law.frictional())
                {
                    if sweeper.step.set_r(r)? {
                        // The state with the new r that keeps p, lambda, q and mu of the
                        // last image exactly: s = p + lambda / r, z = q + mu / r.
                        let d = &cur.e.out;
                        let n = sweeper.nodes.len();
                        for i in 0..n {
                            x[i] = d.p[i] + d.lambda[i] / r;
                            if law.frictional() {
                                x[n + i] = d.q[i] + d.mu[i] / r;
                            }
                        }
                        sweeper.r = r;
                        aa.clear();
                        cur =
                            self.evaluate(sweeper, comm, law, x, aa_on.then_some(&aa), monitor)?;
                        continue;
                    }
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

    /// Many springs with spread stiffness: plain ALG2 needs many sweeps, Anderson few,
    /// and both reach the same answer.
    fn many(acc: Acceleration, kick: Option<(usize, f64)>) -> Outcome {
        let n = 40;
        let nodes = ContactNodes {
            w: vec![0.5; n],
            g: (0..n).map(|i| 0.02 * i as f64).collect(),
        };
        let k: Vec<f64> = (0..n)
            .map(|i| 0.05 + 20.0 * (i as f64 / n as f64).powi(2))
            .collect();
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

    fn sweep(iter: usize, primal: f64, dual: f64, active: usize, r: f64) -> Sweep {
        Sweep {
            iter,
            primal,
            dual,
            active,
            slip: 0,
            r,
        }
    }

    #[test]
    fn r_is_raised_once_when_every_node_is_held_with_the_primal_dominant() {
        let r = 10.0;
        let held = [sweep(1, 1.0, 0.0, 5, r), sweep(2, 0.1, 1e-3, 5, r)];
        assert_eq!(raised_r(&held, r, 5, false), Some(r * RAISE));
        // Too short a history, a free node, a slipping node, or a dual residual that
        // matters: no raise.
        assert_eq!(raised_r(&held[..1], r, 5, false), None);
        assert_eq!(raised_r(&held, r, 6, false), None);
        let mut slipping = held;
        slipping[1].slip = 1;
        assert_eq!(raised_r(&slipping, r, 5, true), None);
        let mut sticking = held;
        (sticking[0].slip, sticking[1].slip) = (0, 0);
        assert_eq!(raised_r(&sticking, r, 5, true), Some(r * RAISE));
        let dual = [sweep(1, 1.0, 0.5, 5, r), sweep(2, 0.1, 0.05, 5, r)];
        assert_eq!(raised_r(&dual, r, 5, false), None);
        assert_eq!(raised_r(&[sweep(1, 1.0, 0.0, 0, r); 2], r, 0, false), None);
        // Once raised, never again.
        let r2 = r * RAISE;
        let after = [
            sweep(1, 1.0, 0.0, 5, r),
            sweep(2, 0.1, 0.0, 5, r),
            sweep(3, 0.01, 0.0, 5, r2),
            sweep(4, 0.001, 0.0, 5, r2),
        ];
        assert_eq!(raised_r(&after, r2, 5, false), None);
    }
}
