//! Assembly of the factor-once matrix A = K + (contact blocks) on the free dofs, with the
//! Dirichlet values lifted to the right-hand side once.

use super::{elasticity_matrix, element_stiffness};
use crate::case::Material;
use crate::error::{Error, Result};
use faer::sparse::{SparseColMat, Triplet};
use rayon::prelude::*;

/// Which dofs are free (and their equation number) and which are prescribed.
#[derive(Debug, Clone)]
pub struct DofMap {
    /// Equation number of each dof, `None` when prescribed.
    pub eq: Vec<Option<usize>>,
    /// Prescribed value of each dof (0 for free ones).
    pub value: Vec<f64>,
    pub n_free: usize,
}

impl DofMap {
    /// Free dofs numbered in dof order.
    pub fn new(fixed: &[Option<f64>]) -> Self {
        let mut n_free = 0;
        let eq = fixed
            .iter()
            .map(|f| {
                f.is_none().then(|| {
                    n_free += 1;
                    n_free - 1
                })
            })
            .collect();
        let value = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
        DofMap { eq, value, n_free }
    }

    /// Free dofs numbered in dof order except `last`, which come after all others in
    /// the given order (the interface and contact dofs of a subdomain, so that the
    /// trailing block of the Cholesky factor is their Schur complement).
    pub fn with_last(fixed: &[Option<f64>], last: &[usize]) -> Self {
        let mut is_last = vec![false; fixed.len()];
        for &d in last {
            is_last[d] = true;
        }
        let mut eq = vec![None; fixed.len()];
        let mut n_free = 0;
        for (d, f) in fixed.iter().enumerate() {
            if f.is_none() && !is_last[d] {
                eq[d] = Some(n_free);
                n_free += 1;
            }
        }
        for &d in last {
            debug_assert!(
                fixed[d].is_none(),
                "a prescribed dof cannot be condensed on"
            );
            eq[d] = Some(n_free);
            n_free += 1;
        }
        let value = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
        DofMap { eq, value, n_free }
    }

    /// Scatters a free-dof vector and the prescribed values into a full dof vector.
    pub fn expand(&self, free: &[f64]) -> Vec<f64> {
        self.eq
            .iter()
            .zip(&self.value)
            .map(|(e, v)| e.map_or(*v, |i| free[i]))
            .collect()
    }
}

/// The assembled system: lower triangle of A on the free dofs, and the constant
/// right-hand side part `-A_fc u_c` from the prescribed dofs.
pub struct Assembled {
    pub matrix: SparseColMat<usize, f64>,
    pub lifting: Vec<f64>,
}

/// One chunk's matrix triplets and its (equation, value) lifting contributions.
type ChunkPart = (Vec<Triplet<usize, usize, f64>>, Vec<(usize, f64)>);

/// Assembles A = K + sum of `node_blocks` (2 x 2 blocks added at a node, e.g. the
/// augmentation terms r w_i (m m' + t t') of the contact nodes).
///
/// Elements are processed in parallel chunks (rayon), each producing triplets that
/// faer sums when it builds the compressed matrix.
pub fn assemble(
    nodes: &[[f64; 2]],
    triangles: &[[usize; 3]],
    material: &Material,
    dofs: &DofMap,
    node_blocks: &[(usize, [[f64; 2]; 2])],
) -> Result<Assembled> {
    let d = elasticity_matrix(material);
    let chunk = (triangles.len() / (4 * rayon::current_num_threads())).max(1024);
    let parts: Vec<ChunkPart> = triangles
        .par_chunks(chunk)
        .map(|tris| {
            // 21 lower-triangle entries per element at most.
            let mut trip = Vec::with_capacity(tris.len() * 21);
            let mut lift = Vec::new();
            for t in tris {
                let p = [nodes[t[0]], nodes[t[1]], nodes[t[2]]];
                let k = element_stiffness(&p, &d);
                let dof = |a: usize| 2 * t[a / 2] + a % 2;
                for a in 0..6 {
                    let Some(i) = dofs.eq[dof(a)] else { continue };
                    for b in 0..6 {
                        match dofs.eq[dof(b)] {
                            Some(j) if i >= j => trip.push(Triplet::new(i, j, k[(a, b)])),
                            Some(_) => {}
                            None => lift.push((i, -k[(a, b)] * dofs.value[dof(b)])),
                        }
                    }
                }
            }
            (trip, lift)
        })
        .collect();

    let mut triplets =
        Vec::with_capacity(parts.iter().map(|p| p.0.len()).sum::<usize>() + 4 * node_blocks.len());
    let mut lifting = vec![0.0; dofs.n_free];
    for (trip, lift) in parts {
        triplets.extend(trip);
        for (i, v) in lift {
            lifting[i] += v;
        }
    }
    for &(node, blk) in node_blocks {
        for a in 0..2 {
            let Some(i) = dofs.eq[2 * node + a] else {
                continue;
            };
            for b in 0..2 {
                match dofs.eq[2 * node + b] {
                    Some(j) if i >= j => triplets.push(Triplet::new(i, j, blk[a][b])),
                    Some(_) => {}
                    None => lifting[i] -= blk[a][b] * dofs.value[2 * node + b],
                }
            }
        }
    }
    // Every free dof gets a diagonal entry even if no element touches it, so a missing
    // connection shows up as a clear "singular" error from the factorization rather than
    // a malformed pattern.
    triplets.extend((0..dofs.n_free).map(|i| Triplet::new(i, i, 0.0)));
    let matrix =
        SparseColMat::try_new_from_triplets(dofs.n_free, dofs.n_free, &triplets).map_err(|e| {
            Error::Numerical(format!("cannot build the sparse stiffness matrix: {e:?}"))
        })?;
    Ok(Assembled { matrix, lifting })
}

/// Nodal forces of a constant traction `t` on boundary edges (lumped = consistent for P1).
pub fn add_edge_traction(nodes: &[[f64; 2]], edges: &[[usize; 2]], t: [f64; 2], f: &mut [f64]) {
    for &[a, b] in edges {
        let len = edge_length(nodes, a, b);
        for n in [a, b] {
            f[2 * n] += 0.5 * len * t[0];
            f[2 * n + 1] += 0.5 * len * t[1];
        }
    }
}

/// Nodal forces of a constant body force (force per unit area).
pub fn add_body_force(nodes: &[[f64; 2]], triangles: &[[usize; 3]], b: [f64; 2], f: &mut [f64]) {
    if b == [0.0, 0.0] {
        return;
    }
    for t in triangles {
        let p = [nodes[t[0]], nodes[t[1]], nodes[t[2]]];
        let area = 0.5
            * ((p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
                - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]))
                .abs();
        for &n in t {
            f[2 * n] += area / 3.0 * b[0];
            f[2 * n + 1] += area / 3.0 * b[1];
        }
    }
}

pub fn edge_length(nodes: &[[f64; 2]], a: usize, b: usize) -> f64 {
    (nodes[b][0] - nodes[a][0]).hypot(nodes[b][1] - nodes[a][1])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::Hypothesis;

    #[test]
    fn dofmap_numbers_free_dofs_in_order() {
        let m = DofMap::new(&[None, Some(1.0), None, Some(-2.0)]);
        assert_eq!(m.eq, vec![Some(0), None, Some(1), None]);
        assert_eq!(m.n_free, 2);
        assert_eq!(m.expand(&[5.0, 6.0]), vec![5.0, 1.0, 6.0, -2.0]);
        let l = DofMap::with_last(&[None, Some(1.0), None, None], &[2, 0]);
        assert_eq!(l.eq, vec![Some(2), None, Some(1), Some(0)]);
        assert_eq!(l.n_free, 3);
    }

    #[test]
    fn traction_and_body_force_totals() {
        let nodes = [[0.0, 0.0], [2.0, 0.0], [0.0, 1.0]];
        let mut f = vec![0.0; 6];
        add_edge_traction(&nodes, &[[0, 1]], [1.0, -3.0], &mut f);
        assert_eq!(f.iter().step_by(2).sum::<f64>(), 2.0);
        assert_eq!(f.iter().skip(1).step_by(2).sum::<f64>(), -6.0);
        let mut g = vec![0.0; 6];
        add_body_force(&nodes, &[[0, 1, 2]], [0.0, -9.0], &mut g);
        assert!((g.iter().sum::<f64>() + 9.0).abs() < 1e-14);
    }

    #[test]
    fn lifting_equals_minus_a_fc_uc() {
        let nodes = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let tris = [[0, 1, 2], [1, 3, 2]];
        let mat = Material {
            young: 10.0,
            poisson: 0.25,
            hypothesis: Hypothesis::PlaneStress,
        };
        let mut fixed = vec![None; 8];
        fixed[0] = Some(0.5);
        fixed[5] = Some(-0.25);
        let dofs = DofMap::new(&fixed);
        let a = assemble(&nodes, &tris, &mat, &dofs, &[]).unwrap();
        // Reference: a dense K.
        let d = elasticity_matrix(&mat);
        let mut k = vec![[0.0; 8]; 8];
        for t in tris {
            let ke = element_stiffness(&[nodes[t[0]], nodes[t[1]], nodes[t[2]]], &d);
            for a in 0..6 {
                for b in 0..6 {
                    k[2 * t[a / 2] + a % 2][2 * t[b / 2] + b % 2] += ke[(a, b)];
                }
            }
        }
        for i in 0..8 {
            let Some(ei) = dofs.eq[i] else { continue };
            let expect = -(k[i][0] * 0.5 + k[i][5] * -0.25);
            assert!((a.lifting[ei] - expect).abs() < 1e-12);
            for j in 0..8 {
                if let Some(ej) = dofs.eq[j] {
                    if ei >= ej {
                        let v = a.matrix.as_ref().get(ei, ej).copied().unwrap_or(0.0);
                        assert!((v - k[i][j]).abs() < 1e-12);
                    }
                }
            }
        }
    }
}
