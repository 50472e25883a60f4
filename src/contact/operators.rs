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

/// The nodes of a contact row and the factor each enters it with: the node itself (1),
/// then each master node of a mortar row (-c_k, `contact::mortar`): the row reads
/// u_n = -m . (sum of factor x u), u_t = t . (the same sum).
pub fn row_nodes(node: usize, masters: &[(usize, f64)]) -> Vec<(usize, f64)> {
    std::iter::once((node, 1.0))
        .chain(masters.iter().map(|&(v, c)| (v, -c)))
        .collect()
}

/// A subdomain's contact rows as the augmentation sees them.
#[derive(Clone, Copy)]
pub struct ContactRowsGeometry<'a> {
    /// Each row's node.
    pub nodes: &'a [usize],
    /// Each row's master nodes and coefficients (empty against an obstacle).
    pub masters: &'a [Vec<(usize, f64)>],
    pub w: &'a [f64],
    /// Each row's normal m (from the master into the slave body).
    pub normals: &'a [[f64; 2]],
    /// The normal of each row's own node as the linear step sees it: (1, 0) for a node
    /// whose dofs are turned into its frame (m . u, ...), else m. The master nodes are
    /// never turned: they read m.
    pub step_normals: &'a [[f64; 2]],
    /// Whether the tangential augmentation is part of A.
    pub frictional: bool,
}

/// The augmentation w (r_n b_n b_n' + r_t b_t b_t') of mortar rows (`masters[k]` not
/// empty; other rows are [`contact_blocks`]'), as 2 x 2 blocks between the row's nodes:
/// those on one node (a, a), which the assembly adds (they hold each body on its own),
/// and those between two nodes (a, b), each pair once, which couple the slave with its
/// masters and the masters with each other.
#[allow(clippy::type_complexity)]
pub fn mortar_blocks(
    rows: &ContactRowsGeometry,
    r_n: &[f64],
    r_t: &[f64],
) -> (
    Vec<(usize, [[f64; 2]; 2])>,
    Vec<(usize, usize, [[f64; 2]; 2])>,
) {
    let ContactRowsGeometry {
        nodes,
        masters,
        w,
        normals,
        step_normals,
        frictional,
    } = *rows;
    let (mut same, mut cross) = (Vec::new(), Vec::new());
    for (k, &node) in nodes.iter().enumerate() {
        let Some(row) = masters.get(k).filter(|m| !m.is_empty()) else {
            continue;
        };
        let (a, b) = (w[k] * r_n[k], if frictional { w[k] * r_t[k] } else { 0.0 });
        // The row's direction at each of its nodes: the slave's own frame, m elsewhere.
        let on = row_nodes(node, row);
        let dir = |i: usize| if i == 0 { step_normals[k] } else { normals[k] };
        let block = |i: usize, j: usize, f: f64| -> [[f64; 2]; 2] {
            let (mi, mj) = (dir(i), dir(j));
            let (ti, tj) = (tangent_of(mi), tangent_of(mj));
            std::array::from_fn(|x| {
                std::array::from_fn(|y| f * (a * mi[x] * mj[y] + b * ti[x] * tj[y]))
            })
        };
        for (i, &(p, fp)) in on.iter().enumerate() {
            same.push((p, block(i, i, fp * fp)));
            for (j, &(q, fq)) in on[..i].iter().enumerate() {
                cross.push((p, q, block(i, j, fp * fq)));
            }
        }
    }
    (same, cross)
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

    #[test]
    fn mortar_blocks_are_the_outer_product_of_the_row() {
        // Slave node 4 over master nodes 1 (0.25) and 2 (0.75), normal (0, 1).
        let masters = vec![vec![], vec![(1, 0.25), (2, 0.75)]];
        let rows = ContactRowsGeometry {
            nodes: &[3, 4],
            masters: &masters,
            w: &[1.0, 2.0],
            normals: &[[0.0, 1.0], [0.0, 1.0]],
            step_normals: &[[0.0, 1.0], [0.0, 1.0]],
            frictional: true,
        };
        let (same, cross) = mortar_blocks(&rows, &[5.0, 5.0], &[1.0, 1.0]);
        // Row: u_n = -(u4 - 0.25 u1 - 0.75 u2)_y, u_t = (u4 - 0.25 u1 - 0.75 u2)_x; the
        // obstacle row of node 3 is not a mortar row.
        let full = |p: usize, q: usize| -> [[f64; 2]; 2] {
            let f = |v: usize| match v {
                4 => 1.0,
                1 => -0.25,
                2 => -0.75,
                _ => 0.0,
            };
            [
                [2.0 * 1.0 * f(p) * f(q), 0.0],
                [0.0, 2.0 * 5.0 * f(p) * f(q)],
            ]
        };
        assert_eq!(same.iter().map(|b| b.0).collect::<Vec<_>>(), [4, 1, 2]);
        for (p, blk) in same {
            assert_eq!(blk, full(p, p));
        }
        assert_eq!(cross.len(), 3);
        for (p, q, blk) in cross {
            assert_ne!(p, q);
            assert_eq!(blk, full(p, q));
        }
    }
}
