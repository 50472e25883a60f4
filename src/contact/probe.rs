//! How soft the body is, seen from its contact boundary, for smooth contact modes:
//! measured with a few linear steps before the loop (see [`smooth_stiffness`]).

use super::{ContactNodes, LinearStep, Reduce};
use crate::error::Result;

/// The quadratic in the position along the foundation, W-orthogonal to constants and
/// to linear functions of the position (the normal components of rigid translations
/// and rotations, which a body that only the contact holds meets without any
/// stiffness). `None` when the contact nodes have fewer than three distinct positions.
pub fn smooth_shape(nodes: &ContactNodes, comm: &(impl Reduce + ?Sized)) -> Option<Vec<f64>> {
    let (w, s) = (&nodes.w, &nodes.s);
    let mut m = [
        w.iter().sum::<f64>(),
        w.iter().zip(s).map(|(w, s)| w * s).sum(),
    ];
    comm.sum_in_place(&mut m);
    if m[0] <= 0.0 {
        return None;
    }
    let mean = m[1] / m[0];
    let c: Vec<f64> = s.iter().map(|s| s - mean).collect();
    let mut k = [0.0; 3];
    for (w, c) in w.iter().zip(&c) {
        k[0] += w * c * c;
        k[1] += w * c * c * c;
        k[2] += w * c * c * c * c;
    }
    comm.sum_in_place(&mut k);
    let [m2, m3, m4] = k;
    if m2 <= 0.0 {
        return None;
    }
    let (a, b) = (m2 / m[0], m3 / m2);
    let norm2 = m4 - m2 * m2 / m[0] - m3 * m3 / m2;
    if norm2 <= 1e-12 * m4 {
        return None;
    }
    Some(c.iter().map(|c| c * c - a - b * c).collect())
}

/// The stiffness of the body for its smooth contact modes (force per unit length per unit
/// length, like r), measured with the linear step A = K + r B'WB:
/// a normal contact force r sigma W v moves the contact nodes by d = B A^-1 B' (r sigma W v),
/// and mode by mode d = mu sigma v with mu = r c / (1 + r c), c the mode's compliance.
/// Powers of that map keep the soft modes (mu near 1) and damp the stiff ones (mu near 0);
/// after `steps` of them, the energy of the displacement u over the square of its
/// contact displacement, u'Ku / |d|^2 = r (sigma v'Wd / |d|^2 - 1) (K u = r sigma B'W v - r B'W d),
/// is the stiffness of the soft modes alone. The start is [`smooth_shape`], W-orthogonal
/// to the rigid motions, and so is every iterate. `None` without a smooth shape.
pub fn smooth_stiffness(
    step: &mut (impl LinearStep + ?Sized),
    comm: &(impl Reduce + ?Sized),
    nodes: &ContactNodes,
    r: f64,
    steps: usize,
) -> Result<Option<f64>> {
    let Some(mut v) = smooth_shape(nodes, comm) else {
        return Ok(None);
    };
    let (w, n) = (&nodes.w, nodes.len());
    let zero = vec![0.0; n];
    let (mut un0, mut ut) = (vec![0.0; n], vec![0.0; n]);
    // The response to the load alone, taken off each probe's.
    step.solve(&zero, &zero, &mut un0, &mut ut)?;
    let mut sizes = [0.0; 2];
    for i in 0..n {
        sizes[0] += w[i] * un0[i] * un0[i];
        sizes[1] += w[i] * v[i] * v[i];
    }
    comm.sum_in_place(&mut sizes);
    // Probes of the load's own size, so that their difference from it keeps its digits.
    let size = if sizes[0] > 0.0 { sizes[0].sqrt() } else { 1.0 };
    let mut norm = sizes[1].sqrt();
    let mut d = vec![0.0; n];
    let mut k = None;
    for _ in 0..steps {
        let sigma = size / norm;
        let force: Vec<f64> = (0..n).map(|i| r * sigma * w[i] * v[i]).collect();
        step.solve(&force, &zero, &mut d, &mut ut)?;
        let mut q = [0.0; 2];
        for i in 0..n {
            d[i] -= un0[i];
            q[0] += w[i] * v[i] * d[i];
            q[1] += w[i] * d[i] * d[i];
        }
        comm.sum_in_place(&mut q);
        if q[1] <= 0.0 {
            break;
        }
        k = Some(r * (sigma * q[0] / q[1] - 1.0));
        v.clone_from(&d);
        norm = q[1].sqrt();
    }
    Ok(k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::NoComm;

    #[test]
    fn the_smooth_shape_is_w_orthogonal_to_rigid_motions() {
        let s: Vec<f64> = [0.0, 0.3, 1.1, 1.7, 2.0, 3.5, 4.0].to_vec();
        let nodes = ContactNodes {
            w: vec![0.15, 0.55, 0.7, 0.45, 0.9, 1.0, 0.25],
            g: vec![0.0; 7],
            s: s.clone(),
            ..Default::default()
        };
        let e = smooth_shape(&nodes, &NoComm).unwrap();
        let dot =
            |a: &[f64], b: &[f64]| -> f64 { (0..a.len()).map(|i| nodes.w[i] * a[i] * b[i]).sum() };
        let ones = vec![1.0; 7];
        let norm = dot(&e, &e).sqrt();
        assert!(norm > 0.1);
        assert!(dot(&e, &ones).abs() <= 1e-12 * norm);
        assert!(dot(&e, &s).abs() <= 1e-12 * norm * dot(&s, &s).sqrt());
        // Two positions carry no quadratic.
        let two = ContactNodes {
            w: vec![1.0; 4],
            g: vec![0.0; 4],
            s: vec![0.0, 1.0, 0.0, 1.0],
            ..Default::default()
        };
        assert!(smooth_shape(&two, &NoComm).is_none());
    }
}
