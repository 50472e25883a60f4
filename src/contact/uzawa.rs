//! The Uzawa block relaxation loop (ALG2 of ALGORITHM.md), written once for any rank
//! count: it sees only this rank's contact nodes, a [`LinearStep`] and a [`Reduce`].
//!
//! Per sweep it calls the linear step once and the reduction once (10 numbers: the
//! squared W-norms of the primal and dual residuals, of the normal and tangential
//! displacements and multipliers, and the active and slip counts).
//!
//! Both residuals are measured in force units and relative to
//! S = max(|lambda|_W + |mu|_W, r (|Nu|_W + |Tu|_W)): the multipliers when there is
//! contact, the displacements when there is none. A purely displacement-based scale
//! fails when the contact nodes sit exactly on the foundation (Nu -> g = 0), and a
//! purely multiplier-based one when nothing touches.

use super::kernels::{coulomb_threshold, project_normal, shrink, update_multiplier};
use super::{ContactNodes, LinearStep, Reduce, Status};
use crate::case::{CoulombMode, Friction};
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
}

/// One line of the convergence history.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sweep {
    pub iter: usize,
    /// r (|Nu - p|_W + |Tu - q|_W) / S (the change of the multipliers).
    pub primal: f64,
    /// r (|p - p_prev|_W + |q - q_prev|_W) / S.
    pub dual: f64,
    pub active: usize,
    pub slip: usize,
}

/// The converged (or last) state on this rank's contact nodes.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub converged: bool,
    pub iterations: usize,
    /// Outer Tresca solves (Coulomb outer mode), else 1.
    pub outer_iterations: usize,
    /// Normal multiplier = contact pressure p_n (force per unit length).
    pub lambda: Vec<f64>,
    /// Tangential multiplier = -p_t.
    pub mu: Vec<f64>,
    pub un: Vec<f64>,
    pub ut: Vec<f64>,
    /// Slip threshold s_i at the end (0 when frictionless).
    pub threshold: Vec<f64>,
    pub status: Vec<Status>,
    pub history: Vec<Sweep>,
}

/// The slip thresholds seen by one run of sweeps.
enum Thresholds<'a> {
    Frictionless,
    Fixed(&'a [f64]),
    Coulomb(f64),
}

struct State {
    lambda: Vec<f64>,
    mu: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    un: Vec<f64>,
    ut: Vec<f64>,
}

/// Runs ALG2 to convergence (or to the sweep budget) from zero multipliers.
pub fn solve(
    step: &mut impl LinearStep,
    comm: &impl Reduce,
    nodes: &ContactNodes,
    params: &Params,
    monitor: &mut dyn FnMut(&Sweep),
) -> Result<Outcome> {
    let n = nodes.len();
    let mut st = State {
        lambda: vec![0.0; n],
        mu: vec![0.0; n],
        // The foundation's own position is the natural start for nodes in contact and
        // is never above an open gap.
        p: nodes.g.iter().map(|g| g.min(0.0)).collect(),
        q: vec![0.0; n],
        un: vec![0.0; n],
        ut: vec![0.0; n],
    };
    let mut history = Vec::new();
    let mut outer_iterations = 1;
    let (converged, threshold) = match (params.friction, params.coulomb) {
        (Friction::None, _) => {
            let c = sweeps(
                step,
                comm,
                nodes,
                params,
                Thresholds::Frictionless,
                &mut st,
                &mut history,
                monitor,
            )?;
            (c, vec![0.0; n])
        }
        (Friction::Tresca { threshold }, _) => {
            let s = vec![threshold; n];
            let c = sweeps(
                step,
                comm,
                nodes,
                params,
                Thresholds::Fixed(&s),
                &mut st,
                &mut history,
                monitor,
            )?;
            (c, s)
        }
        (Friction::Coulomb { coefficient }, CoulombMode::Inner) => {
            let c = sweeps(
                step,
                comm,
                nodes,
                params,
                Thresholds::Coulomb(coefficient),
                &mut st,
                &mut history,
                monitor,
            )?;
            (
                c,
                st.lambda
                    .iter()
                    .map(|&l| coulomb_threshold(coefficient, l))
                    .collect(),
            )
        }
        (Friction::Coulomb { coefficient }, CoulombMode::Outer) => {
            outer_iterations = 0;
            let mut s: Vec<f64> = vec![0.0; n];
            loop {
                outer_iterations += 1;
                let inner_ok = sweeps(
                    step,
                    comm,
                    nodes,
                    params,
                    Thresholds::Fixed(&s),
                    &mut st,
                    &mut history,
                    monitor,
                )?;
                let s_new: Vec<f64> = st
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
                s = s_new;
                let change = relative(sums[0].sqrt(), sums[1].sqrt());
                if !inner_ok || history.len() >= params.max_iter {
                    break (false, s);
                }
                if change <= params.tol {
                    break (true, s);
                }
            }
        }
    };

    let status = (0..n)
        .map(|i| node_status(&params.friction, &st, &threshold, params.r, i))
        .collect();
    Ok(Outcome {
        converged,
        iterations: history.len(),
        outer_iterations,
        lambda: st.lambda,
        mu: st.mu,
        un: st.un,
        ut: st.ut,
        threshold,
        status,
        history,
    })
}

fn relative(value: f64, scale: f64) -> f64 {
    if scale > 0.0 {
        value / scale
    } else {
        value
    }
}

fn node_status(friction: &Friction, st: &State, s: &[f64], r: f64, i: usize) -> Status {
    if st.lambda[i] <= 0.0 {
        Status::Free
    } else if matches!(friction, Friction::None) || shrink(st.ut[i] + st.mu[i] / r, s[i] / r) != 0.0
    {
        Status::Slip
    } else {
        Status::Stick
    }
}

/// Sweeps until both residuals are below tol (true) or the budget is spent (false).
#[allow(clippy::too_many_arguments)]
fn sweeps(
    step: &mut impl LinearStep,
    comm: &impl Reduce,
    nodes: &ContactNodes,
    params: &Params,
    thresholds: Thresholds,
    st: &mut State,
    history: &mut Vec<Sweep>,
    monitor: &mut dyn FnMut(&Sweep),
) -> Result<bool> {
    let n = nodes.len();
    let r = params.r;
    let frictional = !matches!(thresholds, Thresholds::Frictionless);
    let mut force_n = vec![0.0; n];
    let mut force_t = vec![0.0; n];
    while history.len() < params.max_iter {
        // Step 1: linear elasticity with the constant matrix.
        for i in 0..n {
            force_n[i] = nodes.w[i] * (r * st.p[i] - st.lambda[i]);
            force_t[i] = if frictional {
                nodes.w[i] * (r * st.q[i] - st.mu[i])
            } else {
                0.0
            };
        }
        step.solve(&force_n, &force_t, &mut st.un, &mut st.ut)?;

        // Steps 2 and 3, node by node.
        let mut sums = [0.0; 10];
        for i in 0..n {
            let w = nodes.w[i];
            let p = project_normal(nodes.g[i], st.un[i], st.lambda[i], r);
            sums[0] += w * (st.un[i] - p).powi(2);
            sums[2] += w * (p - st.p[i]).powi(2);
            sums[4] += w * st.un[i].powi(2);
            let lambda_old = st.lambda[i];
            st.lambda[i] = update_multiplier(st.lambda[i], r, st.un[i], p);
            st.p[i] = p;
            sums[8] += w * st.lambda[i].powi(2);
            if st.lambda[i] > 0.0 {
                sums[6] += 1.0;
            }
            if !frictional {
                if st.lambda[i] > 0.0 {
                    sums[7] += 1.0;
                }
                continue;
            }
            // The Coulomb threshold uses the pressure before this sweep's update.
            let s = match thresholds {
                Thresholds::Fixed(s) => s[i],
                Thresholds::Coulomb(c) => coulomb_threshold(c, lambda_old),
                Thresholds::Frictionless => 0.0,
            };
            let q = shrink(st.ut[i] + st.mu[i] / r, s / r);
            sums[1] += w * (st.ut[i] - q).powi(2);
            sums[3] += w * (q - st.q[i]).powi(2);
            sums[5] += w * st.ut[i].powi(2);
            st.mu[i] = update_multiplier(st.mu[i], r, st.ut[i], q);
            st.q[i] = q;
            sums[9] += w * st.mu[i].powi(2);
            if q != 0.0 && st.lambda[i] > 0.0 {
                sums[7] += 1.0;
            }
        }
        comm.sum_in_place(&mut sums);

        let scale = (sums[8].sqrt() + sums[9].sqrt()).max(r * (sums[4].sqrt() + sums[5].sqrt()));
        let sweep = Sweep {
            iter: history.len() + 1,
            primal: relative(r * (sums[0].sqrt() + sums[1].sqrt()), scale),
            dual: relative(r * (sums[2].sqrt() + sums[3].sqrt()), scale),
            active: sums[6] as usize,
            slip: sums[7] as usize,
        };
        if !(sweep.primal.is_finite() && sweep.dual.is_finite() && scale.is_finite()) {
            return Err(Error::Numerical(format!(
                "iteration {}: the residuals are not finite (NaN or overflow); the problem may be unstable (check the Dirichlet conditions and material) or r = {r} unsuitable",
                sweep.iter
            )));
        }
        history.push(sweep);
        monitor(&sweep);
        if sweep.primal <= params.tol && sweep.dual <= params.tol {
            return Ok(true);
        }
    }
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::NoComm;

    /// One contact node on a spring of stiffness k (force per displacement), pushed
    /// towards the foundation by a force f: the exact answers are known in closed form.
    /// Normal and tangential directions are independent springs.
    struct Spring {
        k: f64,
        r_w: f64,
        f: [f64; 2],
    }

    impl LinearStep for Spring {
        fn solve(&mut self, fnn: &[f64], ft: &[f64], un: &mut [f64], ut: &mut [f64]) -> Result<()> {
            // (k + r w) u = f + force along each direction.
            un[0] = (self.f[0] + fnn[0]) / (self.k + self.r_w);
            ut[0] = (self.f[1] + ft[0]) / (self.k + self.r_w);
            Ok(())
        }
    }

    fn params(friction: Friction) -> Params {
        Params {
            r: 10.0,
            tol: 1e-12,
            max_iter: 10000,
            friction,
            coulomb: CoulombMode::Inner,
        }
    }

    fn run(friction: Friction, f: [f64; 2], g: f64) -> Outcome {
        let nodes = ContactNodes {
            w: vec![0.5],
            g: vec![g],
        };
        let mut spring = Spring {
            k: 2.0,
            r_w: 10.0 * 0.5,
            f,
        };
        solve(&mut spring, &NoComm, &nodes, &params(friction), &mut |_| {}).unwrap()
    }

    #[test]
    fn frictionless_spring_touches_with_the_right_pressure() {
        // Free displacement f/k = 3 > g = 1: contact, k g = f - w lambda.
        let o = run(Friction::None, [6.0, 0.0], 1.0);
        assert!(o.converged);
        assert!((o.un[0] - 1.0).abs() < 1e-9);
        assert!((o.lambda[0] * 0.5 - 4.0).abs() < 1e-8);
        assert_eq!(o.status[0], Status::Slip);
    }

    #[test]
    fn open_gap_leaves_no_pressure() {
        let o = run(Friction::None, [1.0, 0.0], 1.0);
        assert!(o.converged);
        assert!((o.un[0] - 0.5).abs() < 1e-9);
        assert_eq!(o.lambda[0], 0.0);
        assert_eq!(o.status[0], Status::Free);
    }

    #[test]
    fn tresca_stick_and_slip() {
        // Tangential spring force 1 per unit u_t; friction force w s.
        let stick = run(Friction::Tresca { threshold: 10.0 }, [6.0, 1.0], 1.0);
        assert!(stick.converged);
        assert!(stick.ut[0].abs() < 1e-9);
        assert_eq!(stick.status[0], Status::Stick);
        // f_t = 1, w s = 0.5 * 1.0 = 0.5: slips with k ut = 1 - 0.5.
        let slip = run(Friction::Tresca { threshold: 1.0 }, [6.0, 1.0], 1.0);
        assert!(slip.converged);
        assert!((slip.ut[0] - 0.25).abs() < 1e-9);
        assert_eq!(slip.status[0], Status::Slip);
        // p_t = -mu opposes the slip.
        assert!((-slip.mu[0] + 1.0).abs() < 1e-9);
    }

    #[test]
    fn coulomb_inner_and_outer_agree() {
        let mut p = params(Friction::Coulomb { coefficient: 0.2 });
        let nodes = ContactNodes {
            w: vec![0.5],
            g: vec![1.0],
        };
        let mut results = Vec::new();
        for mode in [CoulombMode::Inner, CoulombMode::Outer] {
            p.coulomb = mode;
            let mut spring = Spring {
                k: 2.0,
                r_w: 5.0,
                f: [6.0, 1.0],
            };
            results.push(solve(&mut spring, &NoComm, &nodes, &p, &mut |_| {}).unwrap());
        }
        // lambda = 8, s = 1.6, w s = 0.8 < 1: slips with k ut = 0.2.
        for o in &results {
            assert!(o.converged);
            assert!((o.lambda[0] - 8.0).abs() < 1e-8);
            assert!((o.ut[0] - 0.1).abs() < 1e-8, "{}", o.ut[0]);
        }
        assert!(results[1].outer_iterations > 1);
    }

    #[test]
    fn budget_exhaustion_is_reported_not_converged() {
        let nodes = ContactNodes {
            w: vec![0.5],
            g: vec![1.0],
        };
        let mut p = params(Friction::None);
        p.max_iter = 2;
        let mut spring = Spring {
            k: 2.0,
            r_w: 5.0,
            f: [6.0, 0.0],
        };
        let o = solve(&mut spring, &NoComm, &nodes, &p, &mut |_| {}).unwrap();
        assert!(!o.converged);
        assert_eq!(o.iterations, 2);
    }
}
