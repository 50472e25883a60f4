//! The contact operators of the linear step on the free dofs: the augmentation
//! r N'WN (+ r T'WT) added to the stiffness matrix, and the contact forces N' f_n + T' f_t
//! added to its right-hand side.

use super::tangent_of;
use crate::fem::DofMap;

/// The contact geometry a linear step needs: which nodes, their weights, their normals.
pub struct ContactDofs<'a> {
    /// Node ids (in the numbering of the mesh the step is built on).
    pub nodes: &'a [usize],
    /// Lumped weight of each contact node.
    pub w: &'a [f64],
    /// Unit normal m_i of each contact node, pointing into the body (tangent
    /// [`tangent_of`]).
    pub normals: &'a [[f64; 2]],
    /// Whether the tangential augmentation r T'WT is part of A.
    pub frictional: bool,
}

/// Augmentation blocks w_i (r_n m_i m_i' + r_t t_i t_i') of the contact nodes (without
/// friction w_i r_n m_i m_i'), with t t' = I - m m' for the unit tangent t.
pub fn contact_blocks(
    nodes: &[usize],
    w: &[f64],
    r_n: &[f64],
    r_t: &[f64],
    normals: &[[f64; 2]],
    frictional: bool,
) -> Vec<(usize, [[f64; 2]; 2])> {
    nodes
        .iter()
        .enumerate()
        .map(|(k, &node)| {
            let m = normals[k];
            let mm = [[m[0] * m[0], m[0] * m[1]], [m[1] * m[0], m[1] * m[1]]];
            let (a, b) = (w[k] * r_n[k], if frictional { w[k] * r_t[k] } else { 0.0 });
            let eye = |i: usize, j: usize| if i == j { 1.0 } else { 0.0 };
            // Equal r: exactly r w I (m m' + t t' = I), not its round-off.
            let blk = std::array::from_fn(|i| {
                std::array::from_fn(|j| {
                    if a == b {
                        a * eye(i, j)
                    } else {
                        a * mm[i][j] + b * (eye(i, j) - mm[i][j])
                    }
                })
            });
            (node, blk)
        })
        .collect()
}

/// The forces a sweep puts on the contact nodes, per node: w (r p - lambda) along the
/// normal and w (r q - mu) along the tangent.
pub(crate) struct NodalForces<'a> {
    pub normal: &'a [f64],
    pub tangential: &'a [f64],
}

/// Adds the contact forces N' f_n + T' f_t (N_i' = -m_i, T_i' = t_i) to a right-hand side
/// on the free dofs.
pub(crate) fn add_contact_forces(
    dofs: &DofMap,
    contact_nodes: &[usize],
    normals: &[[f64; 2]],
    forces: NodalForces,
    rhs: &mut [f64],
) {
    let (force_n, force_t) = (forces.normal, forces.tangential);
    for (k, &node) in contact_nodes.iter().enumerate() {
        let [mx, my] = normals[k];
        let [tx, ty] = tangent_of(normals[k]);
        let f = [
            -mx * force_n[k] + tx * force_t[k],
            -my * force_n[k] + ty * force_t[k],
        ];
        for c in 0..2 {
            if let Some(i) = dofs.eq[2 * node + c] {
                rhs[i] += f[c];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_blocks_weigh_each_direction_by_its_r() {
        let m = [0.6, 0.8];
        let t = tangent_of(m);
        let blocks = contact_blocks(
            &[7, 9],
            &[0.5, 2.0],
            &[10.0, 3.0],
            &[4.0, 3.0],
            &[m, m],
            true,
        );
        assert_eq!((blocks[0].0, blocks[1].0), (7, 9));
        // Different r: w (r_n m m' + r_t t t'); the quadratic forms on m and t give them back.
        let b = blocks[0].1;
        let form = |v: [f64; 2]| {
            (0..2)
                .map(|i| (0..2).map(|j| v[i] * b[i][j] * v[j]).sum::<f64>())
                .sum::<f64>()
        };
        assert!((form(m) - 0.5 * 10.0).abs() < 1e-12);
        assert!((form(t) - 0.5 * 4.0).abs() < 1e-12);
        assert!((b[0][1] - b[1][0]).abs() < 1e-15);
        // Equal r: exactly r w I.
        assert_eq!(blocks[1].1, [[6.0, 0.0], [0.0, 6.0]]);
        // Without friction only the normal direction.
        let plain = contact_blocks(&[7], &[0.5], &[10.0], &[4.0], &[m], false);
        let want = [[1.8, 2.4], [2.4, 3.2]];
        for i in 0..2 {
            for j in 0..2 {
                assert!((plain[0].1[i][j] - want[i][j]).abs() < 1e-12);
            }
        }
    }
}
