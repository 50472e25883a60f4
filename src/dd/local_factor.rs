//! The factored subdomain of the domain decomposition: its boundary (contact and
//! interface dofs) ordered last, so that one sparse Cholesky factorization also gives the
//! Schur complement onto the boundary; the shift that makes a floating subdomain's
//! factor exist; and the low-rank updates of the boundary block when r is retuned.

use crate::error::{Error, Result};
use crate::linear::{Ordering, SparseCholesky};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::sparse::linalg::cholesky::SymmetricOrdering;
use faer::sparse::SparseColMatRef;
use faer::{Mat, MatMut, Side};
use std::collections::BTreeMap;

/// A subdomain matrix factored once with its boundary dofs (interface and contact)
/// ordered last, so that the Schur complement onto them comes out of the same
/// factorization: with A = L L', the trailing block gives S = L_BB L_BB'.
///
/// The boundary dofs are the subdomain's own contact dofs c (first) and its interface
/// dofs g (last). The interface block is shifted by `alpha` I before factoring. A
/// subdomain without Dirichlet conditions ("floating") has a singular local matrix; with
/// its interface held, it is not, so the shift on g alone makes the factorization exist.
/// Since it touches only the boundary block, S = L_BB L_BB' - alpha E_g exactly, while
/// the condensed right-hand side and the interior recovery do not depend on it.
///
/// With L_BB = [L_cc 0; L_gc L_gg], L_cc L_cc' = S_cc and L_gc L_cc' = S_gc are the
/// unshifted blocks, so the contact dofs are eliminated from the boundary system with
/// the same factor: the remaining interface system is L_gg L_gg' - alpha I
/// ([`LocalFactor::interface_schur`]), and [`LocalFactor::forward`] /
/// [`LocalFactor::backward`] are the two halves of a boundary solve around it.
/// A subdomain's elimination order: the interior by a fill-reducing ordering, the
/// boundary last ([`LocalFactor::order`]).
pub struct Ordered {
    fwd: Vec<usize>,
    inv: Vec<usize>,
    n_interior: usize,
    ordering: Ordering,
}

pub struct LocalFactor {
    chol: SparseCholesky,
    n_interior: usize,
    /// L_BB, dense lower triangle (n_b x n_b).
    l_bb: Mat<f64>,
    /// Number of contact dofs, first in B (not shifted).
    n_contact: usize,
    alpha: f64,
    /// S~ = L_BB L_BB' of the matrix as assembled, kept from the first
    /// [`LocalFactor::update_boundary`] on, so that every update starts from it.
    s0: Option<Mat<f64>>,
    /// The update of the boundary block now in the factor, by position (i >= j).
    applied: BTreeMap<(usize, usize), f64>,
    /// The interface Schur complement of the factor, kept once a low-rank update of the
    /// contact block has changed it by its own low-rank term (see
    /// [`LocalFactor::update_boundary`]), so that it is not formed again (g^3 / 3).
    schur_g: Option<Mat<f64>>,
    rhs: Mat<f64>,
    /// The ordering used (what `Auto` resolved to).
    pub(crate) ordering: Ordering,
}

impl LocalFactor {
    /// [`LocalFactor::with_ordering`] with the default ordering ([`Ordering::Auto`]).
    pub fn new(
        a: SparseColMatRef<'_, usize, f64>,
        n_b: usize,
        n_contact: usize,
        alpha: f64,
        groups: &[usize],
    ) -> Result<Self> {
        Self::with_ordering(a, n_b, n_contact, alpha, groups, Ordering::Auto)
    }

    /// `a` is the LOWER triangle of the shifted matrix A + alpha E_g, in an equation
    /// order where the last `n_b` equations are the boundary dofs, the first `n_contact`
    /// of them the unshifted contact dofs. `groups` gives, for
    /// each interior equation, its node: the equations of a node are consecutive and
    /// are ordered together, so the fill-reducing ordering works on the 4x smaller
    /// node graph.
    pub fn with_ordering(
        a: SparseColMatRef<'_, usize, f64>,
        n_b: usize,
        n_contact: usize,
        alpha: f64,
        groups: &[usize],
        ordering: Ordering,
    ) -> Result<Self> {
        let ordered = Self::order(a, n_b, groups, &[], ordering)?;
        Self::with_order(a, n_contact, alpha, ordered)
    }

    /// The fill-reducing ordering of the interior of `a` (the first `a.nrows() - n_b`
    /// equations, grouped by node as [`LocalFactor::with_ordering`] says) with the
    /// boundary last: the part of the factorization a caller may want to time apart.
    /// `positions[node]` places the nodes `groups` names, for the geometric ordering
    /// (empty: none).
    pub fn order(
        a: SparseColMatRef<'_, usize, f64>,
        n_b: usize,
        groups: &[usize],
        positions: &[[f64; 2]],
        ordering: Ordering,
    ) -> Result<Ordered> {
        let n_interior = a.nrows() - n_b;
        let placed = groups[..n_interior]
            .iter()
            .all(|&node| node < positions.len());
        let ordering = ordering.resolve(n_interior, placed);
        let (fwd, inv) = ordering.boundary_last(a, n_interior, groups, positions)?;
        Ok(Ordered {
            fwd,
            inv,
            n_interior,
            ordering,
        })
    }

    /// Factors `a` in the order of [`LocalFactor::order`].
    pub fn with_order(
        a: SparseColMatRef<'_, usize, f64>,
        n_contact: usize,
        alpha: f64,
        ordered: Ordered,
    ) -> Result<Self> {
        let n = a.nrows();
        let Ordered {
            fwd,
            inv,
            n_interior,
            ordering,
        } = ordered;
        let chol = SparseCholesky::factor(
            a,
            SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(&fwd, &inv, n)),
        )?;
        let l_bb = chol.trailing_block(n_interior);
        Ok(LocalFactor {
            chol,
            n_interior,
            l_bb,
            n_contact,
            alpha,
            s0: None,
            applied: BTreeMap::new(),
            schur_g: None,
            rhs: Mat::zeros(n, 1),
            ordering,
        })
    }

    /// Number of boundary dofs (contact, then interface).
    pub(crate) fn n_boundary(&self) -> usize {
        self.l_bb.nrows()
    }

    /// Non-zeros stored in the sparse factor.
    pub(crate) fn factor_nnz(&self) -> usize {
        self.chol.factor_nnz()
    }

    /// See [`SparseCholesky::factor_flops`].
    pub(crate) fn factor_flops(&self) -> f64 {
        self.chol.factor_flops()
    }

    /// The subdomain's Schur complement onto its boundary dofs (dense, symmetric): what
    /// the tests check the factor against.
    #[cfg(test)]
    fn schur(&self) -> Mat<f64> {
        unshifted_gram(self.l_bb.as_ref(), self.n_contact, self.alpha)
    }

    /// Refactors for the matrix as assembled plus `delta` on the boundary block: (i, j, v)
    /// adds v at B positions (i, j) and (j, i). Only the dense trailing block of the
    /// factor changes (the interior block and the coupling L_BI do not depend on A_BB),
    /// and the updated block is written back into the sparse factor, which stays the
    /// factor of the updated matrix.
    ///
    /// When `delta` differs from the one in the factor on few positions (a retune after
    /// the first moves the r of a few contact directions), the difference, a symmetric
    /// matrix on those few dofs, is split into k rank-one terms and L_BB is updated in
    /// place, about k b^2 flops ([`LOW_RANK_MAX_SHARE`]). Otherwise, and whenever an
    /// update would lose positive definiteness, the block is refactored from the
    /// assembled matrix, b^3 / 3 flops.
    ///
    /// Returns how the interface Schur complement changed: by a low-rank term when the
    /// update was made in place (see [`schur_change`]), else in full.
    pub(crate) fn update_boundary(&mut self, delta: &[(usize, usize, f64)]) -> Result<SchurChange> {
        let target = lower_entries(delta);
        let change = entry_difference(&self.applied, &target);
        if change.is_empty() {
            return Ok(SchurChange::None);
        }
        let n = self.l_bb.nrows();
        let (nc, ng) = (self.n_contact, self.n_interface());
        // Before the block first changes: S~ must be that of the assembled matrix, also
        // when the first update is made in place and a later one falls back to refactoring.
        let l_bb = &self.l_bb;
        self.s0.get_or_insert_with(|| lower_gram(l_bb.as_ref()));
        let terms = RankOneTerms::of(&change, n);
        // The interface Schur complement's change, from the factor before the update.
        let woodbury = match &terms {
            Some(t) if ng > 0 => {
                if self.schur_g.is_none() {
                    self.schur_g = Some(self.formed_schur());
                }
                schur_change(&self.l_bb, nc, t)
            }
            _ => None,
        };
        let in_place = terms
            .as_ref()
            .is_some_and(|t| low_rank_update(&mut self.l_bb, t));
        if !in_place {
            self.refactor_boundary(&target)?;
            self.schur_g = None;
        }
        self.applied = target;
        self.chol.set_trailing_block(self.n_interior, &self.l_bb);
        if ng == 0 {
            return Ok(SchurChange::None);
        }
        match (woodbury, self.schur_g.as_mut()) {
            (Some((w, alpha)), Some(s)) => {
                add_rank_one_terms(s, &w, &alpha);
                Ok(SchurChange::LowRank { w, alpha })
            }
            _ => {
                self.schur_g = None;
                Ok(SchurChange::Full)
            }
        }
    }

    /// L_BB of the assembled matrix plus `target`, factored from S~ (b^3 / 3 flops).
    fn refactor_boundary(&mut self, target: &BTreeMap<(usize, usize), f64>) -> Result<()> {
        let n = self.l_bb.nrows();
        let mut s = self.s0.clone().expect("S~ kept before the first update");
        for (&(i, j), &v) in target {
            s[(i, j)] += v;
        }
        let llt = s.llt(Side::Lower).map_err(|_| {
            Error::Numerical(
                "the boundary block refactored for a retuned r is not positive definite; set solver.r to keep r fixed".into(),
            )
        })?;
        drop(s);
        let l = llt.L();
        self.l_bb = Mat::from_fn(n, n, |i, j| if i >= j { l[(i, j)] } else { 0.0 });
        Ok(())
    }

    /// Number of interface dofs (the tail of B).
    pub(crate) fn n_interface(&self) -> usize {
        self.l_bb.nrows() - self.n_contact
    }

    /// This subdomain's part of the interface system left once the contact dofs are
    /// eliminated, S_gg - S_gc S_cc^-1 S_cg = L_gg L_gg' - alpha I (dense, symmetric).
    pub fn interface_schur(&self) -> Mat<f64> {
        self.schur_g.clone().unwrap_or_else(|| self.formed_schur())
    }

    /// [`LocalFactor::interface_schur`] formed from the factor, g^3 / 3 flops.
    fn formed_schur(&self) -> Mat<f64> {
        let (nc, ng) = (self.n_contact, self.n_interface());
        unshifted_gram(self.l_bb.submatrix(nc, nc, ng, ng), 0, self.alpha)
    }

    /// First half of a solve of S x = b on B, in place on `b` (n_b x 1):
    /// b_c <- L_cc^-1 b_c, b_g <- b_g - L_gc b_c. The tail is then this subdomain's part
    /// of the interface right-hand side.
    pub fn forward(&self, b: MatMut<'_, f64>) {
        let (nc, ng) = (self.n_contact, self.n_interface());
        let par = faer::get_global_parallelism();
        let (mut b_c, b_g) = b.split_at_row_mut(nc);
        solve_lower_triangular_in_place(self.l_bb.submatrix(0, 0, nc, nc), b_c.as_mut(), par);
        faer::linalg::matmul::matmul(
            b_g,
            faer::Accum::Add,
            self.l_bb.submatrix(nc, 0, ng, nc),
            b_c.as_ref(),
            -1.0,
            par,
        );
    }

    /// Second half: given the interface values x_g, b_c <- L_cc^-T (b_c - L_gc' x_g) and
    /// b_g <- x_g, so that `b` holds x_B.
    pub fn backward(&self, b: MatMut<'_, f64>, x_g: &[f64]) {
        let (nc, ng) = (self.n_contact, self.n_interface());
        let par = faer::get_global_parallelism();
        let (mut b_c, mut b_g) = b.split_at_row_mut(nc);
        for (i, v) in x_g.iter().enumerate() {
            b_g[(i, 0)] = *v;
        }
        faer::linalg::matmul::matmul(
            b_c.as_mut(),
            faer::Accum::Add,
            self.l_bb.submatrix(nc, 0, ng, nc).transpose(),
            b_g.as_ref(),
            -1.0,
            par,
        );
        solve_upper_triangular_in_place(self.l_bb.submatrix(0, 0, nc, nc).transpose(), b_c, par);
    }

    /// The condensed right-hand side g = f_B - A_BI A_II^-1 f_I, from the first half of
    /// a solve only: with y = L^-1 P f, g = L_BB y_B (the shift cancels). The interior
    /// part of y is returned for [`LocalFactor::recover`].
    pub fn condensed_rhs(&mut self, f: &[f64]) -> (Vec<f64>, InteriorForward) {
        let ni = self.n_interior;
        for (i, v) in f.iter().enumerate() {
            self.rhs[(i, 0)] = *v;
        }
        self.chol.forward_in_place(self.rhs.as_mut());
        let y_b = self.rhs.subrows(ni, self.n_boundary());
        let g = &self.l_bb * y_b.col(0);
        let interior = (0..ni).map(|i| self.rhs[(i, 0)]).collect();
        (g.iter().copied().collect(), InteriorForward(interior))
    }

    /// The subdomain solution whose boundary values are `x_b`: u_I = A_II^-1 (f_I - A_IB x_B),
    /// from the second half of a solve only. The forward solve of [f_I; f_B + z] with
    /// z = S~ x_B - g (which pins u_B = x_B) is [y_I; L_BB' x_B]: y_I comes from
    /// `condensed_rhs(f)`, and no value of f on B matters, so the contact forces on B
    /// need not be added to f.
    pub fn recover(&mut self, interior: &InteriorForward, x_b: &[f64]) -> Vec<f64> {
        let ni = self.n_interior;
        let xb = faer::Col::<f64>::from_fn(x_b.len(), |k| x_b[k]);
        let y_b = self.l_bb.transpose() * &xb;
        for (i, v) in interior.0.iter().enumerate() {
            self.rhs[(i, 0)] = *v;
        }
        for (k, v) in y_b.iter().enumerate() {
            self.rhs[(ni + k, 0)] = *v;
        }
        self.chol.backward_in_place(self.rhs.as_mut());
        (0..self.rhs.nrows()).map(|i| self.rhs[(i, 0)]).collect()
    }
}

/// The interior part of L^-1 P f: what [`LocalFactor::condensed_rhs`] leaves for
/// [`LocalFactor::recover`].
pub struct InteriorForward(Vec<f64>);

/// The full symmetric L L' with the shift alpha taken off the diagonal from row
/// `shifted_from` on (the shifted interface dofs).
fn unshifted_gram(l: faer::MatRef<'_, f64>, shifted_from: usize, alpha: f64) -> Mat<f64> {
    let n = l.nrows();
    let mut s = lower_gram(l);
    for j in 0..n {
        if j >= shifted_from {
            s[(j, j)] -= alpha;
        }
        for i in j + 1..n {
            s[(j, i)] = s[(i, j)];
        }
    }
    s
}

/// Share of the boundary dofs up to which a changed boundary block is updated in place
/// rather than refactored: k rank-one updates cost about k b^2 flops at a lower rate than
/// the b^3 / 3 of a blocked factorization; the two meet near k = b / 8. A retune after
/// the first moves a few directions of hundreds to thousands.
const LOW_RANK_MAX_SHARE: f64 = 1.0 / 16.0;

/// Entries (i, j, v) as a map on the lower triangle (i >= j), duplicates summed.
fn lower_entries(delta: &[(usize, usize, f64)]) -> BTreeMap<(usize, usize), f64> {
    let mut m = BTreeMap::new();
    for &(i, j, v) in delta {
        *m.entry((i.max(j), i.min(j))).or_insert(0.0) += v;
    }
    m
}

/// new - old on the positions where they differ (both given on the lower triangle).
fn entry_difference(
    old: &BTreeMap<(usize, usize), f64>,
    new: &BTreeMap<(usize, usize), f64>,
) -> BTreeMap<(usize, usize), f64> {
    let mut d = BTreeMap::new();
    for (&k, &v) in new {
        let before = old.get(&k).copied().unwrap_or(0.0);
        if v != before {
            d.insert(k, v - before);
        }
    }
    for (&k, &v) in old {
        if !new.contains_key(&k) && v != 0.0 {
            d.insert(k, -v);
        }
    }
    d
}

/// How [`LocalFactor::update_boundary`] changed the interface Schur complement.
pub enum SchurChange {
    /// Not at all: no change of the block, or no interface.
    None,
    /// By the sum of alpha_i w_i w_i' over the columns w_i of `w` (g x p).
    LowRank { w: Mat<f64>, alpha: Vec<f64> },
    /// To be formed again ([`LocalFactor::interface_schur`] does).
    Full,
}

/// A symmetric change D of the boundary block on the few dofs it touches, as rank-one
/// terms: D = sum_c values[c] v_c v_c', v_c the columns of `vectors` on `touched`.
struct RankOneTerms {
    touched: Vec<usize>,
    values: Vec<f64>,
    vectors: nalgebra::DMatrix<f64>,
}

impl RankOneTerms {
    /// The terms of `change` (lower triangle) on a block of order n; `None` when it
    /// touches more than [`LOW_RANK_MAX_SHARE`] of the dofs (refactoring is cheaper).
    fn of(change: &BTreeMap<(usize, usize), f64>, n: usize) -> Option<Self> {
        let mut touched: Vec<usize> = change.keys().flat_map(|&(i, j)| [i, j]).collect();
        touched.sort_unstable();
        touched.dedup();
        let k = touched.len();
        if k as f64 > LOW_RANK_MAX_SHARE * n as f64 {
            return None;
        }
        let at = |dof: usize| touched.binary_search(&dof).expect("a touched dof");
        let mut d = nalgebra::DMatrix::<f64>::zeros(k, k);
        for (&(i, j), &v) in change {
            let (a, b) = (at(i), at(j));
            d[(a, b)] = v;
            d[(b, a)] = v;
        }
        let eig = nalgebra::SymmetricEigen::new(d);
        Some(RankOneTerms {
            touched,
            values: eig.eigenvalues.iter().copied().collect(),
            vectors: eig.eigenvectors,
        })
    }
}

/// Updates the factor `l` of L L' to that of L L' + D, D given by its rank-one `terms`,
/// in place from the first touched dof on (the columns before it do not change; no copy
/// of the block, which at b = 1300 took most of a retune's time). False when an update
/// fails: `l` is then spoilt, and the caller refactors the whole block.
fn low_rank_update(l: &mut Mat<f64>, terms: &RankOneTerms) -> bool {
    let n = l.nrows();
    let k = terms.touched.len();
    let first = terms.touched[0];
    let m = n - first;
    let mut w = Mat::<f64>::zeros(m, k);
    for (a, &dof) in terms.touched.iter().enumerate() {
        for c in 0..k {
            w[(dof - first, c)] = terms.vectors[(a, c)];
        }
    }
    let mut alpha = faer::Col::<f64>::from_fn(k, |c| terms.values[c]);
    if faer::linalg::cholesky::llt::update::rank_r_update_clobber(
        l.as_mut().submatrix_mut(first, first, m, m),
        w.as_mut(),
        alpha.as_diagonal_mut(),
    )
    .is_err()
    {
        return false;
    }
    // A downdate that nearly cancels a diagonal may leave a non-finite or zero pivot
    // without reporting it: refactor instead.
    (first..n).all(|j| {
        let d = l[(j, j)];
        d.is_finite() && d > 0.0
    })
}

/// The change of the interface Schur complement when the boundary matrix
/// S = [S_cc S_cg; S_gc S_gg] (factored as `l`, contact dofs first) changes by
/// D = U Lambda U' (`terms`; U = [U_c; U_g], on contact and interface dofs): with
/// T = [I 0; -S_gc S_cc^-1 I], T S T' = diag(S_cc, S_g) and the Schur complement is the
/// same for T (S + D) T', so by Woodbury's identity
///
///     S_g(new) - S_g = Y M Y',   Y = U_g - L_gc Z,  Z = L_cc^-1 U_c,  M = (Lambda^-1 + Z'Z)^-1,
///
/// since S_gc S_cc^-1 = L_gc L_cc^-1 and U_c' S_cc^-1 U_c = Z'Z (a mortar row's
/// retune touches interface dofs too: the master nodes of other subdomains). Returned
/// as rank-one terms (w, alpha) with M = Q diag(alpha) Q', w = Y Q: p (c^2 + c g + g^2)
/// flops for p terms, where forming S_g again costs g^3 / 3. `None` when M is not finite
/// (a downdate that cancels a pivot: the update in place fails as well).
fn schur_change(l: &Mat<f64>, nc: usize, terms: &RankOneTerms) -> Option<(Mat<f64>, Vec<f64>)> {
    let ng = l.nrows() - nc;
    let keep: Vec<usize> = (0..terms.values.len())
        .filter(|&c| terms.values[c] != 0.0)
        .collect();
    let p = keep.len();
    let mut z = Mat::<f64>::zeros(nc, p);
    let mut u_g = Mat::<f64>::zeros(ng, p);
    for (j, &c) in keep.iter().enumerate() {
        for (a, &dof) in terms.touched.iter().enumerate() {
            if dof < nc {
                z[(dof, j)] = terms.vectors[(a, c)];
            } else {
                u_g[(dof - nc, j)] = terms.vectors[(a, c)];
            }
        }
    }
    let par = faer::get_global_parallelism();
    solve_lower_triangular_in_place(l.submatrix(0, 0, nc, nc), z.as_mut(), par);
    let y = u_g - l.submatrix(nc, 0, ng, nc) * &z;
    let ztz = z.transpose() * &z;
    // M = (Lambda^-1 + Z'Z)^-1 = (I + Lambda Z'Z)^-1 Lambda: no division by a small value.
    let lambda: Vec<f64> = keep.iter().map(|&c| terms.values[c]).collect();
    let a = nalgebra::DMatrix::from_fn(p, p, |i, j| {
        f64::from(u8::from(i == j)) + lambda[i] * ztz[(i, j)]
    });
    let m = a.lu().solve(&nalgebra::DMatrix::from_diagonal(
        &nalgebra::DVector::from_vec(lambda),
    ))?;
    let m = (&m + m.transpose()) * 0.5;
    if m.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let eig = m.symmetric_eigen();
    let q = Mat::<f64>::from_fn(p, p, |i, j| eig.eigenvectors[(i, j)]);
    Some((y * q, eig.eigenvalues.iter().copied().collect()))
}

/// s += sum_c alpha_c w_c w_c' (s symmetric, both triangles).
fn add_rank_one_terms(s: &mut Mat<f64>, w: &Mat<f64>, alpha: &[f64]) {
    let scaled = Mat::<f64>::from_fn(w.nrows(), w.ncols(), |i, c| w[(i, c)] * alpha[c]);
    faer::linalg::matmul::matmul(
        s.as_mut(),
        faer::Accum::Add,
        &scaled,
        w.transpose(),
        1.0,
        faer::get_global_parallelism(),
    );
}

/// The lower triangle of L L' for a lower triangular L (the upper one is left zero): a
/// sixth of the flops of a full product.
fn lower_gram(l: faer::MatRef<'_, f64>) -> Mat<f64> {
    use faer::linalg::matmul::triangular::{matmul, BlockStructure};
    let n = l.nrows();
    let mut s = Mat::<f64>::zeros(n, n);
    matmul(
        s.as_mut(),
        BlockStructure::TriangularLower,
        faer::Accum::Replace,
        l,
        BlockStructure::TriangularLower,
        l.transpose(),
        BlockStructure::TriangularUpper,
        1.0,
        faer::get_global_parallelism(),
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::{assemble, DofMap, Material, Materials};
    use crate::linear::interior_groups;
    use crate::mesh::builtin;
    use faer::prelude::Solve;

    /// Dense copy of a lower-triangle CSC matrix, symmetrised.
    fn dense(a: SparseColMatRef<'_, usize, f64>) -> Mat<f64> {
        let n = a.nrows();
        let mut d = Mat::<f64>::zeros(n, n);
        for j in 0..n {
            for (i, v) in a.row_idx_of_col(j).zip(a.val_of_col(j)) {
                d[(i, j)] += *v;
                if i != j {
                    d[(j, i)] += *v;
                }
            }
        }
        d
    }

    /// Checks S, the condensed rhs and the recovery against dense formulas, for a block
    /// mesh of nx x ny cells, with or without Dirichlet conditions.
    fn check(nx: usize, ny: usize, clamp_bottom: bool) {
        let mesh = builtin::block(2.0, 1.0, nx, ny);
        let material = Material::for_tests();
        let n = mesh.num_nodes();
        let mut fixed = vec![None; 2 * n];
        if clamp_bottom {
            for node in mesh.group_nodes("bottom").unwrap() {
                fixed[2 * node] = Some(0.0);
                fixed[2 * node + 1] = Some(1e-3);
            }
        }
        // Boundary: the free dofs of the top side ("contact", not shifted) and then of
        // the right side ("interface", shifted).
        let right: Vec<usize> = mesh.group_nodes("right").unwrap();
        let top: Vec<usize> = mesh
            .group_nodes("top")
            .unwrap()
            .into_iter()
            .filter(|v| !right.contains(v))
            .collect();
        let free_dofs = |nodes: &[usize]| -> Vec<usize> {
            nodes
                .iter()
                .flat_map(|&v| [2 * v, 2 * v + 1])
                .filter(|&d| fixed[d].is_none())
                .collect()
        };
        let mut last_dofs = free_dofs(&top);
        let nc = last_dofs.len();
        last_dofs.extend(free_dofs(&right));
        let dofs = DofMap::with_last(&fixed, &last_dofs);
        let nb = last_dofs.len();
        let ng = nb - nc;
        let alpha = 1000.0;
        let plain = assemble(
            &mesh.nodes,
            &mesh.triangles,
            Materials::One(&material),
            &dofs,
            &[],
        )
        .unwrap();
        let shift: Vec<(usize, [[f64; 2]; 2])> = right
            .iter()
            .map(|&v| (v, [[alpha, 0.0], [0.0, alpha]]))
            .collect();
        let shifted = assemble(
            &mesh.nodes,
            &mesh.triangles,
            Materials::One(&material),
            &dofs,
            &shift,
        )
        .unwrap();
        let groups = interior_groups(&dofs);
        let nd = LocalFactor::with_ordering(
            shifted.matrix.as_ref(),
            nb,
            nc,
            alpha,
            &groups,
            Ordering::NestedDissection,
        )
        .unwrap();
        let mut lf = LocalFactor::new(shifted.matrix.as_ref(), nb, nc, alpha, &groups).unwrap();
        // Both orderings give the same Schur complement.
        assert!((&nd.schur() - &lf.schur()).norm_max() < 1e-10 * lf.schur().norm_max());

        let a = dense(plain.matrix.as_ref());
        let ni = dofs.n_free - nb;
        let a_ii = a.submatrix(0, 0, ni, ni).to_owned();
        let a_ib = a.submatrix(0, ni, ni, nb).to_owned();
        let a_bb = a.submatrix(ni, ni, nb, nb).to_owned();
        let llt = a_ii.llt(Side::Lower).unwrap();
        let x = llt.solve(&a_ib);
        let s_ref = &a_bb - a_ib.transpose() * &x;
        let s = lf.schur();
        let scale = a_bb.norm_max();
        assert!(
            (&s - &s_ref).norm_max() < 1e-10 * scale,
            "{}",
            (&s - &s_ref).norm_max()
        );

        // The interface system left after eliminating the contact dofs, and a boundary
        // solve through forward, a dense interface solve and backward.
        let s_cc = s_ref.submatrix(0, 0, nc, nc).to_owned();
        let s_gc = s_ref.submatrix(nc, 0, ng, nc).to_owned();
        let s_gg = s_ref.submatrix(nc, nc, ng, ng).to_owned();
        let s_int_ref = &s_gg - &s_gc * s_cc.llt(Side::Lower).unwrap().solve(s_gc.transpose());
        let s_int = lf.interface_schur();
        assert!((&s_int - &s_int_ref).norm_max() < 1e-10 * scale);
        // (S may be singular here, floating: check the halves on a consistent b = S x.)
        let x_true = Mat::<f64>::from_fn(nb, 1, |i, _| 1e-3 * (((3 * i) % 7) as f64 - 3.0));
        let mut b = &s_ref * &x_true;
        lf.forward(b.as_mut());
        let x_g_true = x_true.submatrix(nc, 0, ng, 1).to_owned();
        let z_ref = &s_int_ref * &x_g_true;
        let z = b.submatrix(nc, 0, ng, 1).to_owned();
        assert!((&z - &z_ref).norm_max() < 1e-9 * z_ref.norm_max());
        let x_g: Vec<f64> = (0..ng).map(|i| x_g_true[(i, 0)]).collect();
        lf.backward(b.as_mut(), &x_g);
        assert!((&b - &x_true).norm_max() < 1e-9 * x_true.norm_max());

        let f: Vec<f64> = (0..dofs.n_free)
            .map(|i| ((i * 7919) % 13) as f64 - 6.0)
            .collect();
        let (g, interior) = lf.condensed_rhs(&f);
        let f_i = faer::Col::<f64>::from_fn(ni, |i| f[i]);
        let y = llt.solve(&f_i);
        let g_ref = faer::Col::<f64>::from_fn(nb, |k| f[ni + k]) - a_ib.transpose() * &y;
        for k in 0..nb {
            assert!((g[k] - g_ref[k]).abs() < 1e-9 * g_ref.norm_max().max(1.0));
        }

        let xb: Vec<f64> = (0..nb).map(|k| 1e-3 * (k as f64).sin()).collect();
        let xbc = faer::Col::<f64>::from_fn(nb, |k| xb[k]);
        let ui_ref = llt.solve(&(f_i - &a_ib * &xbc));
        // Loads on B (the contact forces) change g but not the recovery.
        let mut f_b_loaded = f.clone();
        for v in &mut f_b_loaded[ni..] {
            *v += 1e3;
        }
        let (g_loaded, interior_loaded) = lf.condensed_rhs(&f_b_loaded);
        assert!((g_loaded[0] - g[0] - 1e3).abs() < 1e-9 * g_ref.norm_max().max(1e3));
        for interior in [&interior, &interior_loaded] {
            let u = lf.recover(interior, &xb);
            for i in 0..ni {
                assert!((u[i] - ui_ref[i]).abs() < 1e-9 * ui_ref.norm_max());
            }
            for k in 0..nb {
                assert!((u[ni + k] - xb[k]).abs() < 1e-12 * xb[k].abs().max(1e-3));
            }
        }
    }

    #[test]
    fn schur_from_the_factor_small_simplicial() {
        check(4, 3, true);
    }

    #[test]
    fn schur_from_the_factor_supernodal() {
        check(40, 20, true);
    }

    #[test]
    fn schur_of_a_floating_subdomain() {
        check(12, 6, false);
    }

    /// A dense SPD test matrix and its lower Cholesky factor.
    fn spd(n: usize) -> (Mat<f64>, Mat<f64>) {
        let m = Mat::<f64>::from_fn(n, n, |i, j| ((i * 31 + j * 17) % 11) as f64 - 5.0);
        let a = &m * m.transpose() + Mat::<f64>::identity(n, n) * (n as f64);
        let l = a.llt(Side::Lower).unwrap().L().to_owned();
        (a, l)
    }

    fn with_change(a: &Mat<f64>, change: &BTreeMap<(usize, usize), f64>) -> Mat<f64> {
        let mut b = a.clone();
        for (&(i, j), &v) in change {
            b[(i, j)] += v;
            if i != j {
                b[(j, i)] += v;
            }
        }
        b
    }

    #[test]
    fn low_rank_update_and_downdate_match_the_changed_matrix() {
        let n = 80;
        let (a, l) = spd(n);
        // A node's 2 x 2 spring raised a thousandfold, another's nearly removed (a
        // downdate that cancels most of the diagonal), as a retune does.
        let big = 1000.0 * a[(20, 20)];
        let raise = BTreeMap::from([((20, 20), big), ((21, 20), 0.3 * big), ((21, 21), big)]);
        let a1 = with_change(&a, &raise);
        let updated = |l: &Mat<f64>, change: &BTreeMap<(usize, usize), f64>| {
            let mut l = l.clone();
            let t = RankOneTerms::of(change, n)?;
            low_rank_update(&mut l, &t).then_some(l)
        };
        let l1 = updated(&l, &raise).expect("4 of 80 dofs: updated in place");
        assert!((&l1 * l1.transpose() - &a1).norm_max() < 1e-12 * a1.norm_max());
        let lower = BTreeMap::from([
            ((20, 20), -0.999 * big),
            ((21, 20), -0.999 * 0.3 * big),
            ((21, 21), -0.999 * big),
        ]);
        let a2 = with_change(&a1, &lower);
        let l2 = updated(&l1, &lower).expect("updated in place");
        // Cancellation costs digits relative to the removed spring, no more.
        assert!((&l2 * l2.transpose() - &a2).norm_max() < 1e-12 * big);
        // The columns before the first changed dof are untouched, bit for bit.
        assert_eq!(l2.submatrix(0, 0, n, 20), l.submatrix(0, 0, n, 20));
        // Too many dofs, or a change that makes the matrix indefinite: refactor instead.
        let wide: BTreeMap<(usize, usize), f64> = (0..6).map(|i| ((i, i), 1.0)).collect();
        assert!(RankOneTerms::of(&wide, n).is_none());
        let indefinite = BTreeMap::from([((30, 30), -2.0 * a[(30, 30)])]);
        assert!(updated(&l, &indefinite).is_none());
    }

    /// The interface Schur complement S_gg - S_gc S_cc^-1 S_cg of a dense SPD matrix with
    /// its first `nc` dofs the contact ones.
    fn dense_schur(a: &Mat<f64>, nc: usize) -> Mat<f64> {
        let ng = a.nrows() - nc;
        let cc = a.submatrix(0, 0, nc, nc).to_owned();
        let cg = a.submatrix(0, nc, nc, ng).to_owned();
        let x = cc.llt(Side::Lower).unwrap().solve(&cg);
        a.submatrix(nc, nc, ng, ng).to_owned() - cg.transpose() * x
    }

    #[test]
    fn woodbury_gives_the_interface_schur_complement_of_the_changed_block() {
        let (n, nc) = (60, 24);
        let (a, l) = spd(n);
        let big = 1000.0 * a[(5, 5)];
        // A raised node (a rank-one 2 x 2 spring), a nearly removed one, a diagonal one.
        for change in [
            BTreeMap::from([((5, 5), big), ((6, 5), 0.5 * big), ((6, 6), 0.25 * big)]),
            // Lowered by half the smallest eigenvalue (spd adds n I): still positive.
            BTreeMap::from([((12, 12), -0.5 * n as f64)]),
            BTreeMap::from([((0, 0), 3.0), ((23, 23), 7.0), ((23, 0), 1.0)]),
            // A mortar row's: a contact dof coupled with interface dofs, and an
            // interface dof alone.
            BTreeMap::from([
                ((3, 3), 4.0),
                ((30, 3), -2.0),
                ((30, 30), 1.0),
                ((41, 3), -2.0),
                ((41, 30), 1.0),
                ((41, 41), 1.0),
            ]),
            BTreeMap::from([((50, 50), 9.0), ((55, 50), 3.0)]),
        ] {
            let terms = RankOneTerms::of(&change, n).unwrap();
            let (w, alpha) = schur_change(&l, nc, &terms).expect("finite");
            let mut s = dense_schur(&a, nc);
            add_rank_one_terms(&mut s, &w, &alpha);
            let expected = dense_schur(&with_change(&a, &change), nc);
            let err = (&s - &expected).norm_max();
            assert!(err < 1e-10 * expected.norm_max(), "{change:?}: {err:e}");
        }
    }

    #[test]
    fn entry_difference_keeps_changed_positions_only() {
        let old = lower_entries(&[(1, 0, 2.0), (0, 1, 1.0), (2, 2, 5.0), (3, 3, 1.0)]);
        assert_eq!(
            old,
            BTreeMap::from([((1, 0), 3.0), ((2, 2), 5.0), ((3, 3), 1.0)])
        );
        let new = lower_entries(&[(1, 0, 3.0), (2, 2, 4.0), (4, 4, 1.0)]);
        assert_eq!(
            entry_difference(&old, &new),
            BTreeMap::from([((2, 2), -1.0), ((3, 3), -1.0), ((4, 4), 1.0)])
        );
        assert!(entry_difference(&new, &new).is_empty());
    }

    /// A retune in steps (all contact dofs, then two of them; or two in place, then all)
    /// gives the factor of the assembled matrix plus the last update, as one refactoring
    /// does.
    #[test]
    fn boundary_updates_in_steps_equal_one_refactoring() {
        let mesh = builtin::block(2.0, 1.0, 40, 10);
        let material = Material::for_tests();
        let n = mesh.num_nodes();
        let mut fixed = vec![None; 2 * n];
        for node in mesh.group_nodes("bottom").unwrap() {
            fixed[2 * node] = Some(0.0);
            fixed[2 * node + 1] = Some(0.0);
        }
        let top: Vec<usize> = mesh.group_nodes("top").unwrap();
        let last: Vec<usize> = top.iter().flat_map(|&v| [2 * v, 2 * v + 1]).collect();
        let nb = last.len();
        let dofs = DofMap::with_last(&fixed, &last);
        let a = assemble(
            &mesh.nodes,
            &mesh.triangles,
            Materials::One(&material),
            &dofs,
            &[],
        )
        .unwrap();
        let groups = interior_groups(&dofs);
        let factor = || LocalFactor::new(a.matrix.as_ref(), nb, nb, 0.0, &groups).unwrap();
        let all: Vec<(usize, usize, f64)> = (0..nb).map(|k| (k, k, 5e4)).collect();
        let mut some = all.clone();
        some[7].2 = 5e-2;
        some[8].2 = 5e-2;
        // The factor after `first` then `last` against the factor after `last` alone.
        let stepped_and_direct = |first: &[(usize, usize, f64)], last: &[(usize, usize, f64)]| {
            let mut stepped = factor();
            stepped.update_boundary(first).unwrap();
            stepped.update_boundary(last).unwrap();
            let mut direct = factor();
            direct.update_boundary(last).unwrap();
            let (s, s_ref) = (stepped.schur(), direct.schur());
            assert!((&s - &s_ref).norm_max() < 1e-10 * s_ref.norm_max());
            (stepped, direct)
        };
        let (stepped, direct) = stepped_and_direct(&all, &some);
        // The stepped factor solves like the direct one.
        let solve = |lf: &LocalFactor| {
            let mut b = Mat::<f64>::from_fn(nb, 1, |k, _| (k as f64).cos());
            lf.forward(b.as_mut());
            lf.backward(b.as_mut(), &[]);
            b
        };
        let (x, x_ref) = (solve(&stepped), solve(&direct));
        assert!((&x - &x_ref).norm_max() < 1e-9 * x_ref.norm_max());
        // A first update in place (2 of the boundary dofs), then one that refactors.
        stepped_and_direct(&[(7, 7, 5e4), (8, 8, 5e4)], &all);
    }

    /// With interface dofs behind the contact ones: an update in place, on contact or
    /// interface dofs, changes the kept interface Schur complement by its low-rank term,
    /// which equals the complement formed from the updated factor; a refactoring forms it
    /// again.
    #[test]
    fn interface_schur_follows_the_updates_of_the_contact_block() {
        let mesh = builtin::block(2.0, 1.0, 40, 10);
        let material = Material::for_tests();
        let n = mesh.num_nodes();
        let mut fixed = vec![None; 2 * n];
        for node in mesh.group_nodes("bottom").unwrap() {
            fixed[2 * node] = Some(0.0);
            fixed[2 * node + 1] = Some(0.0);
        }
        let top: Vec<usize> = mesh.group_nodes("top").unwrap();
        let last: Vec<usize> = top.iter().flat_map(|&v| [2 * v, 2 * v + 1]).collect();
        let (nb, nc) = (last.len(), last.len() / 2);
        let dofs = DofMap::with_last(&fixed, &last);
        let a = assemble(
            &mesh.nodes,
            &mesh.triangles,
            Materials::One(&material),
            &dofs,
            &[],
        )
        .unwrap();
        let groups = interior_groups(&dofs);
        let mut lf = LocalFactor::new(a.matrix.as_ref(), nb, nc, 0.0, &groups).unwrap();
        let all: Vec<(usize, usize, f64)> = (0..nc).map(|k| (k, k, 5e4)).collect();
        let mut some = all.clone();
        some[7].2 = 5e-2;
        some[8].2 = 5e-2;
        let mut more = some.clone();
        more[30].2 = 5e-2;
        assert!(matches!(
            lf.update_boundary(&all).unwrap(),
            SchurChange::Full
        ));
        for (step, delta) in [&some, &more, &all].into_iter().enumerate() {
            let change = lf.update_boundary(delta).unwrap();
            assert!(matches!(change, SchurChange::LowRank { .. }), "step {step}");
            let (kept, formed) = (lf.interface_schur(), lf.formed_schur());
            let err = (&kept - &formed).norm_max();
            assert!(err < 1e-10 * formed.norm_max(), "step {step}: {err:e}");
        }
        // Interface dofs touched, alone and coupled with a contact dof (a mortar row
        // whose master nodes are interface nodes): a low-rank term all the same.
        let mut wide = all.clone();
        wide.push((nc + 3, nc + 3, 1.0));
        wide.push((nc + 5, 2, -0.5));
        let change = lf.update_boundary(&wide).unwrap();
        assert!(matches!(change, SchurChange::LowRank { .. }));
        let (kept, formed) = (lf.interface_schur(), lf.formed_schur());
        let err = (&kept - &formed).norm_max();
        assert!(err < 1e-10 * formed.norm_max(), "interface dofs: {err:e}");
        // Most of the block changed: refactored, formed again.
        let many: Vec<(usize, usize, f64)> = (0..nb).map(|k| (k, k, 3.0)).collect();
        assert!(matches!(
            lf.update_boundary(&many).unwrap(),
            SchurChange::Full
        ));
        assert!(lf.schur_g.is_none());
    }
}
