//! Assembly of the factor-once matrix A = K + (contact blocks) on the free dofs, with the
//! Dirichlet values lifted to the right-hand side once.

use super::Materials;
use super::{elasticity_matrix, element_stiffness_row};
use crate::error::{Error, Result};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use partition::Stars;
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

/// The size of an assembled matrix, for the assembly phase's line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AssemblyFigures {
    pub equations: usize,
    /// Entries stored (the lower triangle).
    pub entries: usize,
}

impl Assembled {
    pub fn figures(&self) -> AssemblyFigures {
        AssemblyFigures {
            equations: self.matrix.nrows(),
            entries: self.matrix.compute_nnz(),
        }
    }
}

/// Assembles A = K + sum of `node_blocks` (2 x 2 blocks added at a node, e.g. the
/// augmentation terms r w_i (m m' + t t') of the contact nodes).
///
/// Built column by column straight into compressed form: column j of the lower
/// triangle, the equation of dof (v, c), holds row (v, c) of the element matrices of
/// the triangles around node v (A is symmetric), so each column is computed by one
/// thread from the triangles around its node, with no triplets to sort and no two
/// threads writing one entry. Against faer's triplet assembly (21 triplets of 24 bytes
/// per element, sorted) this uses the final matrix's memory only.
pub fn assemble(
    nodes: &[[f64; 2]],
    triangles: &[[usize; 3]],
    materials: Materials<'_>,
    dofs: &DofMap,
    node_blocks: &[(usize, [[f64; 2]; 2])],
) -> Result<Assembled> {
    assemble_in_frames(nodes, triangles, materials, dofs, node_blocks, &[])
}

/// The dofs (u'_0, u'_1) of a node turned into the frame of the unit vector m: u = Q u'
/// with Q = [[m_x, -m_y], [m_y, m_x]], so u'_0 = m . u and u'_1 = (-m_y, m_x) . u.
pub fn to_frame(m: [f64; 2], u: [f64; 2]) -> [f64; 2] {
    [m[0] * u[0] + m[1] * u[1], -m[1] * u[0] + m[0] * u[1]]
}

/// The inverse of [`to_frame`]: x and y components from the frame's.
pub fn from_frame(m: [f64; 2], v: [f64; 2]) -> [f64; 2] {
    [m[0] * v[0] - m[1] * v[1], m[1] * v[0] + m[0] * v[1]]
}

/// [`assemble`] with the dofs of some nodes in a frame of their own: `frames[v]` is
/// `Some(m)` for a node whose two dofs are (m . u, (-m_y, m_x) . u) ([`to_frame`]), A
/// then being Q'AQ; empty: every node in x, y. `node_blocks` are given in the nodes'
/// frames. A node in a frame must have both dofs free (its lifting is not turned).
pub fn assemble_in_frames(
    nodes: &[[f64; 2]],
    triangles: &[[usize; 3]],
    materials: Materials<'_>,
    dofs: &DofMap,
    node_blocks: &[(usize, [[f64; 2]; 2])],
    frames: &[Option<[f64; 2]>],
) -> Result<Assembled> {
    // One elasticity matrix per body, not per element: a handful for any mesh.
    let d: Vec<_> = materials.table().iter().map(elasticity_matrix).collect();
    let n = dofs.n_free;
    let stars = Stars::new(nodes.len(), triangles)
        .map_err(|e| Error::Numerical(format!("cannot assemble the stiffness matrix: {e}")))?;
    let mut dof_of_eq = vec![0usize; n];
    for (dof, eq) in dofs.eq.iter().enumerate() {
        if let Some(i) = eq {
            dof_of_eq[*i] = dof;
        }
    }
    let mesh = ColumnSource {
        nodes,
        triangles,
        d: &d,
        materials,
        dofs,
        stars: &stars,
        frames,
    };
    let chunk = (n / (4 * rayon::current_num_threads())).max(1024);
    let parts: Vec<Columns> = dof_of_eq
        .par_chunks(chunk)
        .enumerate()
        .map(|(k, chunk_dofs)| {
            let mut cols = Columns::default();
            for (off, &dof) in chunk_dofs.iter().enumerate() {
                cols.push_column(k * chunk + off, dof, &mesh);
            }
            cols
        })
        .collect();

    let nnz = parts.iter().map(|p| p.rows.len()).sum();
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::with_capacity(nnz);
    let mut values = Vec::with_capacity(nnz);
    let mut lifting = Vec::with_capacity(n);
    col_ptr.push(0);
    for p in parts {
        col_ptr.extend(p.ends.iter().map(|e| e + row_idx.len()));
        row_idx.extend(p.rows);
        values.extend(p.values);
        lifting.extend(p.lifting);
    }
    for &(node, blk) in node_blocks {
        for a in 0..2 {
            let Some(i) = dofs.eq[2 * node + a] else {
                continue;
            };
            for b in 0..2 {
                match dofs.eq[2 * node + b] {
                    Some(j) if i >= j => {
                        let col = col_ptr[j]..col_ptr[j + 1];
                        // Every column holds its own node's dofs (see `push_column`).
                        let at = row_idx[col.clone()]
                            .binary_search(&i)
                            .expect("a node's dofs are in each other's columns");
                        values[col.start + at] += blk[a][b];
                    }
                    Some(_) => {}
                    None => lifting[i] -= blk[a][b] * dofs.value[2 * node + b],
                }
            }
        }
    }
    let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    Ok(Assembled {
        matrix: SparseColMat::new(symbolic, values),
        lifting,
    })
}

/// What every column is computed from.
#[derive(Clone, Copy)]
struct ColumnSource<'a> {
    nodes: &'a [[f64; 2]],
    triangles: &'a [[usize; 3]],
    /// The elasticity matrix of each entry of `materials`' table.
    d: &'a [nalgebra::Matrix3<f64>],
    materials: Materials<'a>,
    dofs: &'a DofMap,
    stars: &'a Stars,
    /// See [`assemble_in_frames`].
    frames: &'a [Option<[f64; 2]>],
}

impl ColumnSource<'_> {
    fn frame(&self, v: usize) -> Option<[f64; 2]> {
        self.frames.get(v).copied().flatten()
    }
}

/// Consecutive columns of the lower triangle, built by one thread.
#[derive(Default)]
struct Columns {
    /// End of each column in `rows`.
    ends: Vec<usize>,
    rows: Vec<usize>,
    values: Vec<f64>,
    /// The lifting -A_fc u_c of each column's equation.
    lifting: Vec<f64>,
    /// One column's rows before sorting.
    scratch: Vec<usize>,
}

impl Columns {
    /// Appends column `j`, the equation of free dof `dof`: rows `>= j` among the free
    /// dofs of the dof's node and of the nodes that share a triangle with it (so the
    /// diagonal is always there: a node on no triangle gives a zero diagonal, which the
    /// factorization reports as singular instead of a malformed pattern).
    fn push_column(&mut self, j: usize, dof: usize, mesh: &ColumnSource) {
        let ColumnSource {
            nodes,
            triangles,
            d,
            dofs,
            stars,
            ..
        } = *mesh;
        let (v, c) = (dof / 2, dof % 2);
        self.scratch.clear();
        // The node's own dofs even on no triangle, where a node block may still land.
        self.scratch.extend(
            (0..2)
                .filter_map(|comp| dofs.eq[2 * v + comp])
                .filter(|&i| i >= j),
        );
        for &e in stars.of(v) {
            for &u in &triangles[e as usize] {
                for comp in 0..2 {
                    match dofs.eq[2 * u + comp] {
                        Some(i) if i > j => self.scratch.push(i),
                        _ => {}
                    }
                }
            }
        }
        self.scratch.sort_unstable();
        self.scratch.dedup();
        let first = self.rows.len();
        self.rows.extend_from_slice(&self.scratch);
        self.values.resize(self.rows.len(), 0.0);
        let mut lift = 0.0;
        for &e in stars.of(v) {
            let t = triangles[e as usize];
            let a = t.iter().position(|&u| u == v).unwrap_or(0);
            let p = [nodes[t[0]], nodes[t[1]], nodes[t[2]]];
            let d = &d[mesh.materials.index(e as usize)];
            let mut k = match mesh.frame(v) {
                None => element_stiffness_row(&p, d, 2 * a + c),
                Some(m) => {
                    // Column c of Q: the element rows of x and y combined.
                    let q = from_frame(m, if c == 0 { [1.0, 0.0] } else { [0.0, 1.0] });
                    let (kx, ky) = (
                        element_stiffness_row(&p, d, 2 * a),
                        element_stiffness_row(&p, d, 2 * a + 1),
                    );
                    std::array::from_fn(|i| q[0] * kx[i] + q[1] * ky[i])
                }
            };
            for (b, &u) in t.iter().enumerate() {
                if let Some(m) = mesh.frame(u) {
                    [k[2 * b], k[2 * b + 1]] = to_frame(m, [k[2 * b], k[2 * b + 1]]);
                }
            }
            for (m, km) in k.iter().enumerate() {
                let other = 2 * t[m / 2] + m % 2;
                match dofs.eq[other] {
                    Some(i) if i >= j => {
                        let at = self
                            .scratch
                            .binary_search(&i)
                            .expect("the column pattern holds every neighbour");
                        self.values[first + at] += km;
                    }
                    Some(_) => {}
                    None => lift -= km * dofs.value[other],
                }
            }
        }
        self.ends.push(self.rows.len());
        self.lifting.push(lift);
    }
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
    use crate::fem::element_stiffness;
    use crate::fem::{Hypothesis, Material};

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

    /// Dense K of a small mesh, the reference for the compressed assembly.
    fn dense_k(nodes: &[[f64; 2]], tris: &[[usize; 3]], mat: Materials) -> Vec<Vec<f64>> {
        let n = 2 * nodes.len();
        let mut k = vec![vec![0.0; n]; n];
        for (e, t) in tris.iter().enumerate() {
            let d = elasticity_matrix(mat.of(e));
            let ke = element_stiffness(&[nodes[t[0]], nodes[t[1]], nodes[t[2]]], &d);
            for a in 0..6 {
                for b in 0..6 {
                    k[2 * t[a / 2] + a % 2][2 * t[b / 2] + b % 2] += ke[(a, b)];
                }
            }
        }
        k
    }

    /// Every stored entry and every lower-triangle position of A against the dense
    /// reference, the pattern sorted and holding the diagonal.
    fn assert_matches_dense(a: &Assembled, dofs: &DofMap, k: &[Vec<f64>]) {
        let m = a.matrix.as_ref();
        for j in 0..dofs.n_free {
            let rows = m.symbolic().row_idx_of_col_raw(j);
            assert!(rows.windows(2).all(|w| w[0] < w[1]), "column {j} unsorted");
            assert!(rows.contains(&j), "column {j} has no diagonal");
            assert!(
                rows.iter().all(|&i| i >= j),
                "column {j} above the diagonal"
            );
        }
        let scale = k.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
        for (di, ei) in dofs.eq.iter().enumerate() {
            let Some(ei) = *ei else { continue };
            for (dj, ej) in dofs.eq.iter().enumerate() {
                let Some(ej) = *ej else { continue };
                if ei >= ej {
                    let v = m.get(ei, ej).copied().unwrap_or(0.0);
                    assert!((v - k[di][dj]).abs() <= 1e-12 * scale, "({di}, {dj})");
                }
            }
        }
    }

    #[test]
    fn nodes_in_frames_give_q_transpose_a_q() {
        let nodes = [[0.0, 0.0], [1.0, 0.1], [0.1, 1.0], [1.2, 1.1], [2.0, 0.4]];
        let tris = [[0, 1, 2], [1, 3, 2], [1, 4, 3]];
        let mat = Material {
            young: 7.0,
            poisson: 0.3,
            hypothesis: Hypothesis::PlaneStrain,
        };
        let mut fixed = vec![None; 10];
        fixed[0] = Some(0.5);
        fixed[4] = Some(-0.25);
        let dofs = DofMap::new(&fixed);
        let (m1, m3) = ([0.6, 0.8], [-0.28, 0.96]);
        let mut frames = vec![None; 5];
        frames[1] = Some(m1);
        frames[3] = Some(m3);
        let blocks = [(3usize, [[2.0, 0.0], [0.0, 0.0]])];
        let a = assemble_in_frames(&nodes, &tris, Materials::One(&mat), &dofs, &blocks, &frames)
            .unwrap();
        // Q' K Q with the dense K, Q block-diagonal.
        let k = dense_k(&nodes, &tris, Materials::One(&mat));
        let mut q = vec![vec![0.0; 10]; 10];
        for v in 0..5 {
            for c in 0..2 {
                let unit = if c == 0 { [1.0, 0.0] } else { [0.0, 1.0] };
                let col = frames[v].map_or(unit, |m| from_frame(m, unit));
                q[2 * v][2 * v + c] = col[0];
                q[2 * v + 1][2 * v + c] = col[1];
            }
        }
        let mut qkq = vec![vec![0.0; 10]; 10];
        for (i, row) in qkq.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = (0..10)
                    .flat_map(|r| (0..10).map(move |s| (r, s)))
                    .map(|(r, s)| q[r][i] * k[r][s] * q[s][j])
                    .sum();
            }
        }
        qkq[6][6] += 2.0;
        assert_matches_dense(&a, &dofs, &qkq);
        // The lifting of the prescribed dofs lands on the turned equations turned.
        for i in 0..10 {
            let Some(ei) = dofs.eq[i] else { continue };
            let expect = -(qkq[i][0] * 0.5 + qkq[i][4] * -0.25);
            assert!((a.lifting[ei] - expect).abs() < 1e-12, "{i}");
        }
        // The frame's maps are inverse rotations.
        let u = [0.3, -1.7];
        let v = to_frame(m3, u);
        assert!((v[0] - (m3[0] * u[0] + m3[1] * u[1])).abs() < 1e-15);
        let back = from_frame(m3, v);
        assert!((back[0] - u[0]).abs() < 1e-15 && (back[1] - u[1]).abs() < 1e-15);
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
        let a = assemble(&nodes, &tris, Materials::One(&mat), &dofs, &[]).unwrap();
        let k = dense_k(&nodes, &tris, Materials::One(&mat));
        assert_matches_dense(&a, &dofs, &k);
        for i in 0..8 {
            let Some(ei) = dofs.eq[i] else { continue };
            let expect = -(k[i][0] * 0.5 + k[i][5] * -0.25);
            assert!((a.lifting[ei] - expect).abs() < 1e-12);
        }
    }

    #[test]
    fn boundary_dofs_last_and_node_blocks() {
        // A 3 x 3 grid of nodes, irregular, with a node on no triangle (8): its columns
        // hold its own dofs only, where its node block lands.
        let nodes = [
            [0.0, 0.0],
            [1.1, 0.0],
            [2.0, 0.1],
            [0.0, 0.9],
            [1.2, 1.1],
            [2.1, 1.0],
            [0.1, 2.0],
            [0.9, 2.2],
            [5.0, 5.0],
        ];
        let tris = [
            [0, 1, 4],
            [0, 4, 3],
            [1, 2, 5],
            [1, 5, 4],
            [3, 4, 7],
            [3, 7, 6],
            [4, 5, 7],
        ];
        let mat = Material {
            young: 3.0,
            poisson: 0.3,
            hypothesis: Hypothesis::PlaneStrain,
        };
        let mut fixed = vec![None; 18];
        fixed[0] = Some(0.1);
        fixed[1] = Some(0.0);
        fixed[13] = Some(-0.2);
        // Boundary dofs last, in an order of their own.
        let dofs = DofMap::with_last(&fixed, &[9, 4, 8, 12]);
        let blocks = [
            (4usize, [[2.0, 0.5], [0.5, 1.0]]),
            (6, [[0.7, -0.1], [-0.1, 0.3]]),
            (2, [[1.5, 0.0], [0.0, 1.5]]),
            (8, [[1.0, 0.25], [0.25, 2.0]]),
        ];
        let a = assemble(&nodes, &tris, Materials::One(&mat), &dofs, &blocks).unwrap();
        let mut k = dense_k(&nodes, &tris, Materials::One(&mat));
        for (v, b) in blocks {
            for r in 0..2 {
                for c in 0..2 {
                    k[2 * v + r][2 * v + c] += b[r][c];
                }
            }
        }
        assert_matches_dense(&a, &dofs, &k);
        assert_eq!(
            dofs.eq[16].map(|e| a.matrix.as_ref().symbolic().row_idx_of_col_raw(e).len()),
            Some(2)
        );
        for (di, ei) in dofs.eq.iter().enumerate() {
            let Some(ei) = *ei else { continue };
            let expect: f64 = -(0..18)
                .map(|dj| k[di][dj] * fixed[dj].unwrap_or(0.0))
                .sum::<f64>();
            assert!(
                (a.lifting[ei] - expect).abs() < 1e-12,
                "lifting of dof {di}"
            );
        }
    }

    /// Each element with its own material: the compressed matrix (nodes in frames too)
    /// matches the dense sum of each element's own matrix, and a table of two equal
    /// materials assembles bit for bit as one material.
    #[test]
    fn each_element_has_its_own_material() {
        let nodes = [[0.0, 0.0], [1.0, 0.1], [0.1, 1.0], [1.2, 1.1], [2.0, 0.4]];
        let tris = [[0, 1, 2], [1, 3, 2], [1, 4, 3]];
        let soft = Material {
            young: 7.0,
            poisson: 0.3,
            hypothesis: Hypothesis::PlaneStrain,
        };
        let stiff = Material {
            young: 700.0,
            poisson: 0.2,
            ..soft
        };
        let table = [soft, stiff];
        let body = [1u32, 0, 1];
        let two = Materials::PerElement {
            table: &table,
            body: &body,
        };
        let mut fixed = vec![None; 10];
        fixed[0] = Some(0.5);
        fixed[1] = Some(0.0);
        let dofs = DofMap::new(&fixed);
        let a = assemble(&nodes, &tris, two, &dofs, &[]).unwrap();
        let k = dense_k(&nodes, &tris, two);
        assert_matches_dense(&a, &dofs, &k);
        // Not the matrix of either material alone.
        for one in [&soft, &stiff] {
            let k1 = dense_k(&nodes, &tris, Materials::One(one));
            assert!(k
                .iter()
                .flatten()
                .zip(k1.iter().flatten())
                .any(|(x, y)| (x - y).abs() > 1.0));
        }
        let frames = [None, Some([0.6, 0.8]), None, None, None];
        let same = [soft, soft];
        let per = Materials::PerElement {
            table: &same,
            body: &body,
        };
        let a1 =
            assemble_in_frames(&nodes, &tris, Materials::One(&soft), &dofs, &[], &frames).unwrap();
        let a2 = assemble_in_frames(&nodes, &tris, per, &dofs, &[], &frames).unwrap();
        let bits = |a: &Assembled| -> Vec<u64> {
            let m = a.matrix.as_ref();
            (0..dofs.n_free)
                .flat_map(|j| (j..dofs.n_free).map(move |i| (i, j)))
                .map(|(i, j)| m.get(i, j).copied().unwrap_or(0.0).to_bits())
                .chain(a.lifting.iter().map(|v| v.to_bits()))
                .collect()
        };
        assert_eq!(bits(&a1), bits(&a2));
    }
}
