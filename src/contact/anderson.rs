//! Anderson mixing (type II) on the sweep map G of [`super::uzawa`], with an inner product
//! in force units summed over all ranks, so that every rank computes the same mixing
//! coefficients and the iterates do not depend on the rank count.

use super::sweep::Augmentation;

/// Weighted inner product of two states, one weight per component (see [`metric`]).
pub(super) fn dot(a: &[f64], b: &[f64], omega: &[f64]) -> f64 {
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
pub(super) fn metric(w: &[f64], aug: &Augmentation, r_ref: f64, frictional: bool) -> Vec<f64> {
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

/// The secant ratio below which the sweep map counts as a translation (see
/// [`Anderson::propose`]); far below the slowest contraction worth accelerating (1e-6 is
/// rho = 0.999999).
pub(super) const FLAT_SECANT: f64 = 1e-8;

/// Anderson memory (m = 0: no acceleration): differences of residuals and of images of the last iterations.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(super) struct Anderson {
    m: usize,
    pub(super) df: Vec<Vec<f64>>,
    pub(super) dg: Vec<Vec<f64>>,
    pub(super) last: Option<(Vec<f64>, Vec<f64>)>,
}

impl Anderson {
    pub(super) fn new(m: usize) -> Self {
        Anderson {
            m,
            df: Vec::new(),
            dg: Vec::new(),
            last: None,
        }
    }

    /// Itself when mixing is on, so that the sweep's reduction carries its Gram sums.
    pub(super) fn active(&self) -> Option<&Self> {
        (self.m > 0).then_some(self)
    }

    /// The Anderson step after the accepted point x with image gx: records
    /// (G(x) - x, G(x)) and mixes with the global Gram sums `gram` of that point.
    /// `None` without acceleration, with an empty memory or a singular system.
    /// `secant` is |f(x) - f(x_prev)| / |x - x_prev| for the previous accepted point: below
    /// [`FLAT_SECANT`] the map is a translation along the step (a body that nothing holds
    /// yet, moving towards the contact by the same amount each sweep), the newest
    /// difference is noise and the least-squares coefficients would blow up: the memory
    /// restarts.
    pub(super) fn propose(
        &mut self,
        x: &[f64],
        gx: &[f64],
        gram: &[f64],
        secant: f64,
    ) -> Option<Vec<f64>> {
        if self.m == 0 {
            return None;
        }
        let f: Vec<f64> = gx.iter().zip(x).map(|(a, b)| a - b).collect();
        if secant < FLAT_SECANT {
            self.clear();
            self.push(&f, gx);
            return None;
        }
        self.push(&f, gx);
        self.mix(gx, gram)
    }

    pub(super) fn clear(&mut self) {
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

    /// Local parts of the Gram matrix DF'DF (upper triangle, row by row), of DF' f and of
    /// the Gram matrix DX'DX of the state differences (DX = DG - DF), where DF, DG are the
    /// memory as it will be once (f, g) is pushed: computing them with the evaluation lets
    /// one reduction per sweep serve the statistics, the mixing and the contraction
    /// estimate ([`span_secant`]).
    pub(super) fn local_sums_with_new(&self, f: &[f64], g: &[f64], omega: &[f64]) -> Vec<f64> {
        let mut df: Vec<&[f64]> = self.df.iter().map(Vec::as_slice).collect();
        let mut dg: Vec<&[f64]> = self.dg.iter().map(Vec::as_slice).collect();
        let (newest_f, newest_g): (Vec<f64>, Vec<f64>);
        if let Some((f0, g0)) = &self.last {
            newest_f = f.iter().zip(f0).map(|(a, b)| a - b).collect();
            newest_g = g.iter().zip(g0).map(|(a, b)| a - b).collect();
            if df.len() == self.m {
                df.remove(0);
                dg.remove(0);
            }
            df.push(&newest_f);
            dg.push(&newest_g);
        }
        let dx: Vec<Vec<f64>> = df
            .iter()
            .zip(&dg)
            .map(|(f, g)| g.iter().zip(*f).map(|(a, b)| a - b).collect())
            .collect();
        let k = df.len();
        let mut v = Vec::with_capacity(k * (k + 2));
        for a in 0..k {
            for b in a..k {
                v.push(dot(df[a], df[b], omega));
            }
        }
        for a in df.iter().take(k) {
            v.push(dot(a, f, omega));
        }
        for a in 0..k {
            for b in a..k {
                v.push(dot(&dx[a], &dx[b], omega));
            }
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

/// The smallest secant ratio over the span of the memory, min over gamma of
/// |DF gamma| / |DX gamma|, from the global sums of [`Anderson::local_sums_with_new`]
/// (`None` without two differences or with dependent ones).
///
/// Why: on a piece of the sweep map where it is affine, G(x) = J x + c, DF = (J - I) DX,
/// and the distance to the fixed point is |(I - J)^-1 f| <= |f| / sigma_min(I - J). A
/// single secant gives |(J - I) d| / |d| for one step d, which can miss the slowest
/// mode; the minimum over the memory's span is the smallest Ritz value of I - J on the
/// steps taken (a Krylov space, where the slowest modes show first), never above the
/// single secants'.
pub(super) fn span_secant(sums: &[f64]) -> Option<f64> {
    // k(k+1)/2 + k + k(k+1)/2 = k(k+2) numbers.
    let k = ((sums.len() + 1) as f64).sqrt().round() as usize - 1;
    if k < 2 || k * (k + 2) != sums.len() {
        return None;
    }
    let tri = k * (k + 1) / 2;
    let unpack = |part: &[f64]| {
        let mut a = nalgebra::DMatrix::<f64>::zeros(k, k);
        let mut idx = 0;
        for i in 0..k {
            for j in i..k {
                a[(i, j)] = part[idx];
                a[(j, i)] = part[idx];
                idx += 1;
            }
        }
        a
    };
    let (ff, xx) = (unpack(&sums[..tri]), unpack(&sums[tri + k..]));
    // Scaled to a unit diagonal of DX'DX, then directions that DX does not resolve to
    // 1e-10 of its largest are dropped: there the ratio is round-off over round-off.
    let d: Vec<f64> = (0..k).map(|i| xx[(i, i)].sqrt()).collect();
    if d.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return None;
    }
    let scale = |a: &nalgebra::DMatrix<f64>| {
        nalgebra::DMatrix::from_fn(k, k, |i, j| a[(i, j)] / (d[i] * d[j]))
    };
    let (ff, xx) = (scale(&ff), scale(&xx));
    let eig = xx.symmetric_eigen();
    let top = eig.eigenvalues.max();
    let keep: Vec<usize> = (0..k)
        .filter(|&i| eig.eigenvalues[i] > 1e-10 * top)
        .collect();
    if keep.is_empty() {
        return None;
    }
    // On the kept eigenvectors q_i of DX'DX (eigenvalues s_i): the ratio's square is the
    // Rayleigh quotient of Q' DF'DF Q / s_i s_j scaled, whose smallest eigenvalue is
    // min |DF g|^2 / |DX g|^2 over that part of the span.
    let q = nalgebra::DMatrix::from_fn(k, keep.len(), |i, j| {
        eig.eigenvectors[(i, keep[j])] / eig.eigenvalues[keep[j]].sqrt()
    });
    let reduced = q.transpose() * ff * &q;
    let low = reduced.symmetric_eigen().eigenvalues.min();
    low.is_finite().then(|| low.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn a_flat_secant_restarts_the_memory() {
        // G(x) = x + c: a translation, f constant. The newest difference of f is round-off.
        let omega = [1.0, 1.0];
        let mut aa = Anderson::new(5);
        let (x0, g0) = ([0.0, 0.0], [1.0, 2.0]);
        assert!(aa.propose(&x0, &g0, &[], f64::INFINITY).is_none());
        let (x1, g1) = (g0, [2.0, 4.0 + 1e-15]);
        let f1: Vec<f64> = g1.iter().zip(&x1).map(|(a, b)| a - b).collect();
        let gram = aa.local_sums_with_new(&f1, &g1, &omega);
        // Mixing would divide by |f1 - f0| ~ 1e-15.
        assert!(aa.propose(&x1, &g1, &gram, 1e-15).is_none());
        assert!(aa.df.is_empty() && aa.dg.is_empty());
        assert_eq!(aa.last.as_ref().map(|(f, _)| f.clone()), Some(f1));
        // A contracting step mixes as before.
        let (x2, g2) = (g1, [2.5, 4.5]);
        let f2: Vec<f64> = g2.iter().zip(&x2).map(|(a, b)| a - b).collect();
        let gram = aa.local_sums_with_new(&f2, &g2, &omega);
        assert!(aa.propose(&x2, &g2, &gram, 0.5).is_some());
    }
}
