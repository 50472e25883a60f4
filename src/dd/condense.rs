//! The contact response of the condensed system, pure dense linear algebra (no MPI).
//!
//! The boundary system S x = b lives on B = the contact dofs of every rank (the dofs of
//! own contact nodes that no other part touches and that the contact reads:
//! `split::contact_components`) and the interface dofs. A contact dof
//! belongs to one subdomain only, so S_cc is block diagonal by rank and each rank
//! eliminates its own contact dofs with the dense trailing block of its sparse factor
//! (`LocalFactor::forward` / `backward`). What is left is the interface system
//! S' = sum_s (L_gg L_gg' - alpha I)_s, summed and factored once on the first rank.
//!
//! A sweep needs (Nu, Tu) = C x + c0 on the contact nodes, with b = g + C' f (g: the
//! condensed constant loads, f: the contact forces):
//! 1. each rank: b_s = g_s + C_s' f_s, then `forward` (n_c^2 + 2 n_c n_g flops);
//! 2. first rank: sums the interface tails into the global interface vector, solves with
//!    S' (2 n_G^2 flops) and hands each rank its interface values;
//! 3. each rank: `backward` (the same flops as 1), then reads C_s x_s + c0.
//!
//! On one rank there is no interface and the sweep is two dense triangular solves with
//! the trailing block of the sparse factor. The first rank's dense work is set by the
//! interface alone (n_G^3 / 3 once, 2 n_G^2 a sweep), not by the contact boundary.

use crate::contact::operators::{row_nodes, ContactRowsGeometry};
use crate::contact::tangent_of;
use crate::dd::local_factor::LocalFactor;
use crate::error::{Error, Result};
use crate::host;
use crate::linear::SparseCholesky;
use faer::sparse::linalg::cholesky::SymmetricOrdering;
use faer::{Mat, Side};
use rayon::prelude::*;

/// C restricted to one rank's own contact nodes: packed rows (the normal value of each
/// own contact node, then, with friction, the tangential ones) against positions in B.
#[derive(Debug, Clone)]
pub struct ContactRows {
    /// (packed row, B position, coefficient).
    entries: Vec<(usize, usize, f64)>,
    /// The prescribed part of each packed row.
    c0: Vec<f64>,
}

impl ContactRows {
    /// `rows.nodes` are local node ids, `fixed` the prescribed value of each local dof,
    /// `boundary_dofs` the local dof of each position in B. A row's own node is read
    /// along its step normal (in its frame where it has one), its master nodes along m.
    pub fn new(
        rows: &ContactRowsGeometry,
        fixed: &[Option<f64>],
        boundary_dofs: &[usize],
    ) -> Result<Self> {
        let (contact_nodes, masters, frictional) = (rows.nodes, rows.masters, rows.frictional);
        let mut position = std::collections::HashMap::with_capacity(boundary_dofs.len());
        for (k, &d) in boundary_dofs.iter().enumerate() {
            position.insert(d, k);
        }
        let n = contact_nodes.len();
        let per = if frictional { 2 } else { 1 };
        let mut entries = Vec::with_capacity(2 * per * n);
        let mut c0 = vec![0.0; per * n];
        for (k, &v) in contact_nodes.iter().enumerate() {
            // u_n = -m.u, u_t = t.u, at the row's own node along its step normal.
            let kinds = |normal: [f64; 2]| -> Vec<(usize, [f64; 2])> {
                let tangent = tangent_of(normal);
                let mut kinds = vec![(k, [-normal[0], -normal[1]])];
                if frictional {
                    kinds.push((n + k, tangent));
                }
                kinds
            };
            let on = row_nodes(v, masters.get(k).map_or(&[][..], |m| &m[..]));
            let (own, others) = (kinds(rows.step_normals[k]), kinds(rows.normals[k]));
            for d in 0..own.len() {
                for (i, &(node, factor)) in on.iter().enumerate() {
                    let (row, coef) = if i == 0 { own[d] } else { others[d] };
                    for comp in 0..2 {
                        let dof = 2 * node + comp;
                        if coef[comp] == 0.0 {
                            // Not read (and maybe not in B: see `split::contact_components`).
                            continue;
                        }
                        let coef = factor * coef[comp];
                        match fixed[dof] {
                            Some(value) => c0[row] += coef * value,
                            None => {
                                let b = *position.get(&dof).ok_or_else(|| {
                                    Error::Numerical(format!(
                                        "internal: contact dof {dof} is not a boundary dof"
                                    ))
                                })?;
                                entries.push((row, b, coef));
                            }
                        }
                    }
                }
            }
        }
        Ok(ContactRows { entries, c0 })
    }

    /// Number of packed rows.
    pub fn len(&self) -> usize {
        self.c0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.c0.is_empty()
    }
}

/// 2 x 2 blocks at nodes (local ids) as entries (i, j, v) at B positions, each pair of
/// positions once (i >= j); prescribed components, and zero entries on a component
/// outside B (see `split::contact_components`), are left out. For
/// `LocalFactor::update_boundary`.
pub fn boundary_entries(
    blocks: &[(usize, [[f64; 2]; 2])],
    fixed: &[Option<f64>],
    boundary_dofs: &[usize],
) -> Result<Vec<(usize, usize, f64)>> {
    let mut position = std::collections::HashMap::with_capacity(boundary_dofs.len());
    for (k, &d) in boundary_dofs.iter().enumerate() {
        position.insert(d, k);
    }
    let mut out = Vec::with_capacity(3 * blocks.len());
    for &(v, blk) in blocks {
        for a in 0..2 {
            for b in 0..=a {
                let (da, db) = (2 * v + a, 2 * v + b);
                if fixed[da].is_some() || fixed[db].is_some() {
                    continue;
                }
                let (Some(&i), Some(&j)) = (position.get(&da), position.get(&db)) else {
                    if blk[a][b] == 0.0 {
                        continue;
                    }
                    return Err(Error::Numerical(format!(
                        "internal: node {v} of a boundary block has a dof outside B"
                    )));
                };
                out.push((i.max(j), i.min(j), blk[a][b]));
            }
        }
    }
    Ok(out)
}

/// One rank's part of the boundary solve of every sweep.
pub struct LocalResponse {
    rows: ContactRows,
    /// Condensed constant loads on B.
    g: Vec<f64>,
    /// Work column; after `backward`, x_B.
    b: Mat<f64>,
    interface: Vec<f64>,
}

impl LocalResponse {
    pub fn new(rows: ContactRows, g: Vec<f64>) -> Self {
        let n = g.len();
        LocalResponse {
            rows,
            g,
            b: Mat::zeros(n, 1),
            interface: Vec::new(),
        }
    }

    /// b = g + C' f (packed own forces f), then the forward elimination of the contact
    /// dofs; returns this rank's part of the interface right-hand side.
    pub fn forward(&mut self, factor: &LocalFactor, f: &[f64]) -> &[f64] {
        for (i, v) in self.g.iter().enumerate() {
            self.b[(i, 0)] = *v;
        }
        for &(row, k, c) in &self.rows.entries {
            self.b[(k, 0)] += c * f[row];
        }
        factor.forward(self.b.as_mut());
        let nc = self.g.len() - factor.n_interface();
        self.interface.clear();
        self.interface
            .extend((nc..self.g.len()).map(|i| self.b[(i, 0)]));
        &self.interface
    }

    /// Back substitution with the interface values x_g; writes (Nu, Tu) packed in `out`.
    pub fn backward(&mut self, factor: &LocalFactor, x_g: &[f64], out: &mut [f64]) {
        factor.backward(self.b.as_mut(), x_g);
        out.copy_from_slice(&self.rows.c0);
        for &(row, k, c) in &self.rows.entries {
            out[row] += c * self.b[(k, 0)];
        }
    }

    /// x_B of the last `backward`.
    pub fn boundary_values(&self) -> Vec<f64> {
        (0..self.b.nrows()).map(|i| self.b[(i, 0)]).collect()
    }
}

/// The interface system of all ranks, summed and factored once on the first rank.
pub struct InterfaceSystem {
    factor: Option<InterfaceFactor>,
    /// Global interface index of each rank's interface dofs, rank by rank.
    index: Vec<Vec<usize>>,
    x: Mat<f64>,
}

/// The factor of the interface system: dense, or sparse when the subdomains' pieces
/// leave enough of it empty (see [`InterfaceSystem::new`]).
enum InterfaceFactor {
    /// The lower Cholesky factor, kept as a matrix so that retunes can update it in place.
    Dense(Mat<f64>),
    Sparse(Box<SparseCholesky>),
}

/// The sparse factor is taken when its work is at most this part of the dense one's:
/// both run the same dense kernels (the sparse one on its supernodes), but the sparse
/// one has its assembly, ordering and scatter on top.
const SPARSE_INTERFACE_WORK: f64 = 0.5;

/// Pieces whose squared sizes add up to more than this part of n^2 make the dense factor
/// without a sparse analysis: their pattern is at least that full before any fill, its
/// factor nearly dense, and the analysis (an ordering of up to n^2 entries) would cost
/// more than it could save (hertz level 5, 4 subdomains, 5473 dofs: about 1.2 s).
const DENSE_COVER: f64 = 0.6;

/// `f` with faer's process-wide parallelism set to `threads` threads of a pool of its
/// own on the node's cores ([`host::node_pool`]), whatever the threads of this rank,
/// and put back afterwards.
fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    if threads <= 1 {
        return f();
    }
    let Some(pool) = host::node_pool(threads) else {
        return f();
    };
    let previous = faer::get_global_parallelism();
    faer::set_global_parallelism(faer::Par::rayon(threads));
    let result = pool.install(f);
    faer::set_global_parallelism(previous);
    result
}

/// The work of a dense factor of order n as `SparseCholesky::factor_flops` counts it:
/// the squared lengths of its columns, about n^3 / 3.
fn dense_work(n: usize) -> f64 {
    (1..=n).map(|c| (c as f64) * (c as f64)).sum()
}

fn singular() -> Error {
    Error::Numerical(
        "the condensed stiffness matrix is singular: the body can still move rigidly; add Dirichlet conditions that fix the rigid motions (with frictionless contact, also the sliding along the foundation)".into(),
    )
}

/// The pattern of the lower triangle of the sum of `pieces` (columns of sorted rows):
/// entry (i, j) is there when a piece holds both i and j.
fn lower_pattern(n: usize, pieces: &[(Vec<usize>, Mat<f64>)]) -> (Vec<usize>, Vec<usize>) {
    let sorted: Vec<Vec<usize>> = pieces
        .iter()
        .map(|(idx, _)| {
            let mut v = idx.clone();
            v.sort_unstable();
            v
        })
        .collect();
    let mut pieces_of = vec![Vec::new(); n];
    for (p, idx) in sorted.iter().enumerate() {
        for &i in idx {
            pieces_of[i].push(p);
        }
    }
    let mut col_ptr = Vec::with_capacity(n + 1);
    col_ptr.push(0);
    let mut rows = Vec::new();
    let mut column = Vec::new();
    for (j, of) in pieces_of.iter().enumerate() {
        column.clear();
        for &p in of {
            let idx = &sorted[p];
            column.extend_from_slice(&idx[idx.partition_point(|&i| i < j)..]);
        }
        column.sort_unstable();
        column.dedup();
        // A dof that no piece holds still needs its diagonal: the factorization then
        // reports the sum singular instead of failing on a malformed pattern.
        if column.first() != Some(&j) {
            column.insert(0, j);
        }
        rows.extend_from_slice(&column);
        col_ptr.push(rows.len());
    }
    (col_ptr, rows)
}

impl InterfaceFactor {
    fn new(
        n: usize,
        pieces: &[(Vec<usize>, Mat<f64>)],
        threads: usize,
        sparse_work: f64,
    ) -> Result<Self> {
        let covered: f64 = pieces.iter().map(|(i, _)| (i.len() as f64).powi(2)).sum();
        if covered > DENSE_COVER * (n as f64).powi(2) {
            return Self::dense(n, pieces, threads);
        }
        let (col_ptr, rows) = lower_pattern(n, pieces);
        let pattern =
            faer::sparse::SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &rows);
        let mut sparse = SparseCholesky::analyse(pattern, SymmetricOrdering::Amd)?;
        if sparse.factor_flops() <= sparse_work * dense_work(n) {
            let mut values = vec![0.0; rows.len()];
            for (idx, piece) in pieces {
                for (b, &j) in idx.iter().enumerate() {
                    let column = &rows[col_ptr[j]..col_ptr[j + 1]];
                    for (a, &i) in idx.iter().enumerate() {
                        if i >= j {
                            // The pattern holds every (i, j) of every piece.
                            let at = column.binary_search(&i).expect("in the pattern");
                            values[col_ptr[j] + at] += piece[(a, b)];
                        }
                    }
                }
            }
            let a = faer::sparse::SparseColMatRef::new(pattern, &values);
            with_threads(threads, || sparse.refactor(a)).map_err(|_| singular())?;
            Ok(InterfaceFactor::Sparse(Box::new(sparse)))
        } else {
            drop(sparse);
            Self::dense(n, pieces, threads)
        }
    }

    fn dense(n: usize, pieces: &[(Vec<usize>, Mat<f64>)], threads: usize) -> Result<Self> {
        // Each piece's column of each dof of the system (a piece's dofs are distinct).
        let columns: Vec<Vec<usize>> = (pieces.iter())
            .map(|(idx, _)| {
                let mut at = vec![usize::MAX; n];
                for (b, &ib) in idx.iter().enumerate() {
                    at[ib] = b;
                }
                at
            })
            .collect();
        let l = with_threads(threads, || {
            // The sum on the pool, a column a job, the pieces added in their order as one
            // thread adds them: on one thread it was the factorization's serial part.
            let mut s = Mat::<f64>::zeros(n, n);
            let sum = |(j, mut col): (usize, faer::ColMut<f64>)| {
                for ((idx, piece), at) in pieces.iter().zip(&columns) {
                    if let Some(&b) = at.get(j).filter(|&&b| b != usize::MAX) {
                        for (a, &ia) in idx.iter().enumerate() {
                            col[ia] += piece[(a, b)];
                        }
                    }
                }
            };
            s.as_mut().par_col_iter_mut().enumerate().for_each(sum);
            faer::linalg::solvers::Llt::new(s.as_ref(), Side::Lower).map(|llt| llt.L().to_owned())
        })
        .map_err(|_| singular())?;
        Ok(InterfaceFactor::Dense(l))
    }

    fn solve_in_place(&mut self, mut x: faer::MatMut<'_, f64>) {
        match self {
            InterfaceFactor::Dense(l) => {
                let par = faer::get_global_parallelism();
                faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                    l.as_ref(),
                    x.as_mut(),
                    par,
                );
                faer::linalg::triangular_solve::solve_upper_triangular_in_place(
                    l.transpose(),
                    x,
                    par,
                );
            }
            InterfaceFactor::Sparse(chol) => chol.solve_in_place(x),
        }
    }
}

impl InterfaceSystem {
    /// Sums the pieces (one per rank, in rank order: global indices and the dense
    /// interface Schur complement) and factors the sum with `threads` threads: dense
    /// (n^3 / 3 flops, n^2 doubles) while the pieces overlap so much that a sparse
    /// factor would not save half of that (two subdomains: one piece covers it all);
    /// sparse, with an AMD ordering, once they do not (many subdomains, each touching a
    /// few neighbours' interfaces only).
    pub fn new(
        n: usize,
        pieces: impl IntoIterator<Item = (Vec<usize>, Mat<f64>)>,
        threads: usize,
    ) -> Result<Self> {
        Self::with_sparse_work(n, pieces, threads, SPARSE_INTERFACE_WORK)
    }

    /// As [`Self::new`], sparse when its work is at most `sparse_work` times the dense one.
    fn with_sparse_work(
        n: usize,
        pieces: impl IntoIterator<Item = (Vec<usize>, Mat<f64>)>,
        threads: usize,
        sparse_work: f64,
    ) -> Result<Self> {
        let pieces: Vec<(Vec<usize>, Mat<f64>)> = pieces.into_iter().collect();
        let factor = if n == 0 {
            None
        } else {
            Some(InterfaceFactor::new(n, &pieces, threads, sparse_work)?)
        };
        Ok(InterfaceSystem {
            factor,
            index: pieces.into_iter().map(|(idx, _)| idx).collect(),
            x: Mat::zeros(n, 1),
        })
    }

    /// Adds to the factored sum the rank-one terms of each piece: (global indices, the
    /// columns w (column-major, one row per index), alpha), sum alpha_c w_c w_c', by
    /// updates and downdates of the dense factor in place (p n^2 flops for p terms, where
    /// factoring again costs n^3 / 3). False when the factor is sparse or an update loses
    /// positive definiteness: the factor is then spoilt and must be built again.
    pub fn update(&mut self, pieces: &[(Vec<usize>, Vec<f64>, Vec<f64>)]) -> bool {
        let Some(InterfaceFactor::Dense(l)) = &mut self.factor else {
            return false;
        };
        let n = l.nrows();
        let p: usize = pieces.iter().map(|(_, _, a)| a.len()).sum();
        if p == 0 {
            return true;
        }
        let mut w = Mat::<f64>::zeros(n, p);
        let mut alpha = faer::Col::<f64>::zeros(p);
        let mut c0 = 0;
        for (idx, cols, a) in pieces {
            let g = idx.len();
            for (c, &ac) in a.iter().enumerate() {
                alpha[c0 + c] = ac;
                for (k, &i) in idx.iter().enumerate() {
                    w[(i, c0 + c)] = cols[k + g * c];
                }
            }
            c0 += a.len();
        }
        if faer::linalg::cholesky::llt::update::rank_r_update_clobber(
            l.as_mut(),
            w.as_mut(),
            alpha.as_diagonal_mut(),
        )
        .is_err()
        {
            return false;
        }
        (0..n).all(|j| {
            let d = l[(j, j)];
            d.is_finite() && d > 0.0
        })
    }

    /// Whether the sum was factored as a sparse matrix.
    pub fn is_sparse(&self) -> bool {
        matches!(self.factor, Some(InterfaceFactor::Sparse(_)))
    }

    /// Floating-point operations of its factorization, counted as
    /// [`SparseCholesky::factor_flops`] counts them.
    pub fn factor_flops(&self) -> f64 {
        match &self.factor {
            None => 0.0,
            Some(InterfaceFactor::Dense(_)) => dense_work(self.x.nrows()),
            Some(InterfaceFactor::Sparse(chol)) => chol.factor_flops(),
        }
    }

    /// Entries stored in its factor (the lower triangle, diagonal included).
    pub fn factor_entries(&self) -> f64 {
        let n = self.x.nrows() as f64;
        match &self.factor {
            None => 0.0,
            Some(InterfaceFactor::Dense(_)) => n * (n + 1.0) / 2.0,
            Some(InterfaceFactor::Sparse(chol)) => chol.factor_nnz() as f64,
        }
    }

    /// From the ranks' interface right-hand sides, concatenated in rank order, to their
    /// interface values, in the same layout.
    pub fn solve_packed(&mut self, z: &[f64], out: &mut Vec<f64>) {
        self.x.fill(0.0);
        let mut k = 0;
        for idx in &self.index {
            for &i in idx {
                self.x[(i, 0)] += z[k];
                k += 1;
            }
        }
        if let Some(factor) = &mut self.factor {
            factor.solve_in_place(self.x.as_mut());
        }
        out.clear();
        for idx in &self.index {
            out.extend(idx.iter().map(|&i| self.x[(i, 0)]));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_rows_read_normal_and_tangential_parts() {
        // Node 0: both dofs free; node 1: x prescribed to 0.5.
        let fixed = vec![None, None, Some(0.5), None];
        let boundary = vec![3, 0, 1];
        let geometry = |nodes: &'static [usize], frictional| ContactRowsGeometry {
            nodes,
            masters: &[],
            w: &[1.0, 1.0],
            normals: &[[0.0, 1.0], [0.0, 1.0]],
            step_normals: &[[0.0, 1.0], [0.0, 1.0]],
            frictional,
        };
        let rows = ContactRows::new(&geometry(&[0, 1], true), &fixed, &boundary).unwrap();
        assert_eq!(rows.len(), 4);
        // u_n = -m.u = -u_y, u_t = t.u = u_x.
        let mut e = rows.entries.clone();
        e.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let expected = vec![(0, 2, -1.0), (1, 0, -1.0), (2, 1, 1.0)];
        let nonzero: Vec<_> = e.into_iter().filter(|x| x.2 != 0.0).collect();
        assert_eq!(nonzero, expected);
        assert_eq!(rows.c0, vec![0.0, 0.0, 0.0, 0.5]);
        // A contact dof that is not in B is an internal error, not a panic.
        assert!(ContactRows::new(&geometry(&[0], false), &fixed, &[3]).is_err());
    }

    #[test]
    fn interface_system_sums_overlapping_pieces() {
        // Pieces on global dofs {0, 1} and {1, 2}: the sum is tridiagonal [2 -1 0; ...].
        let p = Mat::from_fn(2, 2, |i, j| if i == j { 1.5 } else { -1.0 });
        let mut sys =
            InterfaceSystem::new(3, [(vec![0, 1], p.clone()), (vec![1, 2], p)], 1).unwrap();
        assert_eq!(
            sys.index.iter().map(Vec::len).collect::<Vec<_>>(),
            vec![2, 2]
        );
        // Right-hand sides split between the ranks on the shared dof 1.
        let mut out = Vec::new();
        sys.solve_packed(&[1.0, 0.25, 0.75, 1.0], &mut out);
        let s = Mat::from_fn(3, 3, |i, j| match (i, j) {
            (1, 1) => 3.0,
            (i, j) if i == j => 1.5,
            (i, j) if i.abs_diff(j) == 1 => -1.0,
            _ => 0.0,
        });
        let x = [out[0], out[1], out[3]];
        assert_eq!(out[1], out[2]);
        let rhs = [1.0, 1.0, 1.0];
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| s[(i, j)] * x[j]).sum();
            assert!((r - rhs[i]).abs() < 1e-14, "{r}");
        }
        // A singular sum is reported.
        let z = Mat::<f64>::zeros(1, 1);
        assert!(InterfaceSystem::new(1, [(vec![0], z.clone())], 1).is_err());
        assert!(InterfaceSystem::new(1, [(vec![0], z)], 2).is_err());
    }

    /// A chain of subdomains: piece s holds the dofs of interfaces s and s + 1 (each
    /// `m` dofs), as strips cut a body. The sparse factor solves the sum as the dense
    /// one does, on one thread and on several, and needs less work.
    #[test]
    fn sparse_interface_factor_agrees_with_the_dense_one() {
        let (m, strips) = (30, 7);
        let n = m * (strips + 1);
        let pieces: Vec<(Vec<usize>, Mat<f64>)> = (0..strips)
            .map(|s| {
                let idx: Vec<usize> = (s * m..(s + 2) * m).collect();
                let k = idx.len();
                let a = Mat::<f64>::from_fn(k, k, |i, j| {
                    (((i * 7 + j * 13 + s * 5) % 11) as f64 / 11.0 - 0.5) * 0.3
                });
                (idx, &a * a.transpose() + Mat::<f64>::identity(k, k))
            })
            .collect();
        let rhs: Vec<f64> = pieces
            .iter()
            .flat_map(|(idx, _)| idx.iter().map(|&i| ((i * 3) as f64 * 0.1).cos()))
            .collect();
        let solve = |sparse_work: f64, threads: usize| {
            let mut sys =
                InterfaceSystem::with_sparse_work(n, pieces.clone(), threads, sparse_work).unwrap();
            let mut out = Vec::new();
            sys.solve_packed(&rhs, &mut out);
            (sys.is_sparse(), sys.factor_flops(), out)
        };
        let (dense_chosen, dense_flops, dense) = solve(0.0, 1);
        let (sparse_chosen, sparse_flops, sparse) = solve(f64::INFINITY, 1);
        let (_, _, sparse_threads) = solve(f64::INFINITY, 3);
        assert!(!dense_chosen && sparse_chosen);
        assert!(
            sparse_flops < 0.2 * dense_flops,
            "{sparse_flops} {dense_flops}"
        );
        // The default rule takes the sparse factor here.
        assert!(InterfaceSystem::new(n, pieces.clone(), 1)
            .unwrap()
            .is_sparse());
        let scale = dense.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for ((d, s), t) in dense.iter().zip(&sparse).zip(&sparse_threads) {
            assert!((d - s).abs() <= 1e-12 * scale, "{d} {s}");
            assert!((d - t).abs() <= 1e-12 * scale, "{d} {t}");
        }
        // And it solves the summed system: residual of S x = sum of the packed rhs.
        let mut b = vec![0.0; n];
        let mut x = vec![0.0; n];
        let mut k = 0;
        for (idx, _) in &pieces {
            for &i in idx {
                b[i] += rhs[k];
                x[i] = sparse[k];
                k += 1;
            }
        }
        for (idx, p) in &pieces {
            for (a, &i) in idx.iter().enumerate() {
                for (c, &j) in idx.iter().enumerate() {
                    b[i] -= p[(a, c)] * x[j];
                }
            }
        }
        assert!(b.iter().all(|r| r.abs() < 1e-10), "residual");
        // A singular sum is reported by the sparse factor too, as is a dof of no piece.
        let z = Mat::<f64>::zeros(2, 2);
        assert!(InterfaceSystem::with_sparse_work(2, [(vec![0, 1], z)], 1, f64::INFINITY).is_err());
        let one = Mat::<f64>::identity(1, 1);
        assert!(InterfaceSystem::with_sparse_work(2, [(vec![0], one)], 1, f64::INFINITY).is_err());
    }

    /// Factored on several threads (the first rank's cores while the others sleep), the
    /// system gives the answer of the one-thread factor, to round-off, and leaves the
    /// process-wide parallelism as it was.
    #[test]
    fn interface_factor_on_several_threads_agrees_with_one() {
        let n = 700;
        let a = Mat::<f64>::from_fn(n, n, |i, j| ((i * 31 + j * 17) % 13) as f64 / 13.0 - 0.5);
        let spd = &a * a.transpose() + Mat::<f64>::identity(n, n) * (n as f64);
        let rhs: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let before = faer::get_global_parallelism();
        let solve = |threads: usize| {
            let mut sys =
                InterfaceSystem::new(n, [((0..n).collect(), spd.clone())], threads).expect("SPD");
            let mut out = Vec::new();
            sys.solve_packed(&rhs, &mut out);
            out
        };
        let (one, four) = (solve(1), solve(4));
        let scale = one.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (x, y) in one.iter().zip(&four) {
            assert!((x - y).abs() <= 1e-12 * scale, "{x} {y}");
        }
        let r: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| spd[(i, j)] * four[j]).sum::<f64>() - rhs[i])
            .collect();
        assert!(r.iter().all(|v| v.abs() < 1e-10), "residual");
        assert_eq!(
            format!("{:?}", faer::get_global_parallelism()),
            format!("{before:?}")
        );
    }
}
