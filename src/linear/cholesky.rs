//! The sparse Cholesky factor of faer, wrapped to be factored once and solved many times:
//! the whole solve, its forward and backward halves, and the dense trailing block that
//! the condensation of a subdomain reads and updates (`dd::local_factor`).

use crate::error::{Error, Result};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SparseColMatRef;
use faer::{Conj, Mat, MatMut, Side};

/// `n` zeros, or `None` when the memory cannot be had.
///
/// Why not `resize`: the factor's values are the largest array of a run (1.2 GB per rank
/// at hertz level 5), and faer zeroes them itself before factoring. Taken from calloc,
/// the fresh pages come zeroed from the kernel and are first touched by faer, so the
/// buffer is written once instead of twice.
fn zeroed_f64(n: usize) -> Option<Vec<f64>> {
    if n == 0 {
        return Some(Vec::new());
    }
    let layout = std::alloc::Layout::array::<f64>(n).ok()?;
    // SAFETY: `layout` has a non-zero size. A non-null result is a fresh allocation of
    // the global allocator with exactly the layout of n f64, as `Vec::from_raw_parts`
    // requires (capacity n), and all-zero bytes are the f64 0.0, so all n are initialised.
    unsafe {
        let p = std::alloc::alloc_zeroed(layout).cast::<f64>();
        if p.is_null() {
            return None;
        }
        Some(Vec::from_raw_parts(p, n, n))
    }
}

/// A sparse symmetric positive definite matrix factored once (supernodal or simplicial
/// Cholesky chosen by faer, fill-reducing ordering), solved many times without
/// allocating: the scratch memory is kept between solves.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    scratch: MemBuffer,
}

impl SparseCholesky {
    /// Factors the matrix whose LOWER triangle is `a`.
    pub fn factor(
        a: SparseColMatRef<'_, usize, f64>,
        ordering: SymmetricOrdering<'_, usize>,
    ) -> Result<Self> {
        let mut chol = Self::analyse(a.symbolic(), ordering)?;
        chol.refactor(a)?;
        Ok(chol)
    }

    /// The ordering and symbolic analysis of the matrix whose LOWER triangle has the
    /// pattern `a`; [`Self::refactor`] then computes the factor (and takes its memory).
    /// [`Self::factor_flops`] already tells its cost.
    pub(crate) fn analyse(
        a: faer::sparse::SymbolicSparseColMatRef<'_, usize>,
        ordering: SymmetricOrdering<'_, usize>,
    ) -> Result<Self> {
        let par = faer::get_global_parallelism();
        let symbolic = factorize_symbolic_cholesky(a, Side::Lower, ordering, Default::default())
            .map_err(|e| {
                Error::Numerical(format!("symbolic Cholesky factorization failed: {e:?}"))
            })?;
        let scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, par));
        Ok(SparseCholesky {
            symbolic,
            // Taken by the first refactor: an analysis may decide against factoring.
            values: Vec::new(),
            scratch,
        })
    }

    /// Numeric factorization of `a` (LOWER triangle), which must have the sparsity of
    /// the matrix this factor was built for: the ordering and symbolic analysis are kept.
    pub(crate) fn refactor(&mut self, a: SparseColMatRef<'_, usize, f64>) -> Result<()> {
        let len = self.symbolic.len_val();
        if self.values.len() != len {
            self.values = zeroed_f64(len).ok_or_else(|| {
                Error::Numerical(format!(
                    "out of memory for the Cholesky factor ({len} non-zeros); use more ranks or a coarser mesh"
                ))
            })?;
        }
        let par = faer::get_global_parallelism();
        let mut mem = MemBuffer::new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        );
        self.symbolic
            .factorize_numeric_llt(
                &mut self.values,
                a,
                Side::Lower,
                LltRegularization::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|_| {
                Error::Numerical(
                    "the stiffness matrix is singular (not positive definite): the body can still move rigidly; add Dirichlet conditions that fix the rigid motions (with frictionless contact, also the sliding along the foundation)"
                        .into(),
                )
            })?;
        Ok(())
    }

    /// Overwrites `rhs` (one column) with A^-1 rhs.
    pub fn solve_in_place(&mut self, rhs: MatMut<'_, f64>) {
        let par = faer::get_global_parallelism();
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            par,
            MemStack::new(&mut self.scratch),
        );
    }

    /// The first half of a solve: `x` (one column) becomes L^-1 P x, in the factor's
    /// permuted order.
    pub(crate) fn forward_in_place(&mut self, mut x: MatMut<'_, f64>) {
        use faer::sparse::linalg::cholesky::{supernodal, SymbolicCholeskyRaw};
        use faer::sparse::linalg::triangular_solve;
        let par = faer::get_global_parallelism();
        if let Some(perm) = self.symbolic.perm() {
            let fwd = perm.arrays().0;
            let old: Vec<f64> = (0..x.nrows()).map(|i| x[(i, 0)]).collect();
            for (i, &p) in fwd.iter().enumerate() {
                x[(i, 0)] = old[p];
            }
        }
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                let l = SparseColMatRef::new(s.factor(), &self.values);
                triangular_solve::solve_lower_triangular_in_place(l, Conj::No, x, par);
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                supernodal::SupernodalLltRef::new(s, &self.values).l_solve_with_conj(
                    Conj::No,
                    x,
                    par,
                    MemStack::new(&mut self.scratch),
                );
            }
        }
    }

    /// The second half: `x`, in the factor's order, becomes P' L^-T x.
    pub(crate) fn backward_in_place(&mut self, mut x: MatMut<'_, f64>) {
        use faer::sparse::linalg::cholesky::{supernodal, SymbolicCholeskyRaw};
        use faer::sparse::linalg::triangular_solve;
        let par = faer::get_global_parallelism();
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                let l = SparseColMatRef::new(s.factor(), &self.values);
                triangular_solve::solve_lower_triangular_transpose_in_place(
                    l,
                    Conj::No,
                    x.as_mut(),
                    par,
                );
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                supernodal::SupernodalLltRef::new(s, &self.values).l_transpose_solve_with_conj(
                    Conj::No,
                    x.as_mut(),
                    par,
                    MemStack::new(&mut self.scratch),
                );
            }
        }
        if let Some(perm) = self.symbolic.perm() {
            let inv = perm.arrays().1;
            let permuted: Vec<f64> = (0..x.nrows()).map(|i| x[(i, 0)]).collect();
            for (i, &p) in inv.iter().enumerate() {
                x[(i, 0)] = permuted[p];
            }
        }
    }

    /// Order of the factored matrix.
    fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Non-zeros stored in the factor.
    pub(crate) fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Floating-point operations of one numeric factorization, about: the sum over the
    /// columns of L of the square of their non-zero count (a column of c entries updates
    /// c(c-1)/2 entries to its right with one multiply and one add each). A count of the
    /// work from the symbolic structure alone, so that the work of the ranks and its
    /// balance can be compared free of the machine's noise.
    pub fn factor_flops(&self) -> f64 {
        use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
        let squared = |c: usize| (c as f64) * (c as f64);
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                s.col_ptr().windows(2).map(|w| squared(w[1] - w[0])).sum()
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                let (begin, end) = (s.supernode_begin(), s.supernode_end());
                let rows = s.col_ptr_for_row_idx();
                (0..s.n_supernodes())
                    .map(|sn| {
                        // Column j of a supernode holds the diagonal block's rows j..end
                        // and every row of the supernode's pattern below it.
                        let below = rows[sn + 1] - rows[sn];
                        (1..=end[sn] - begin[sn])
                            .map(|d| squared(d + below))
                            .sum::<f64>()
                    })
                    .sum()
            }
        }
    }
}

impl SparseCholesky {
    /// Overwrites the trailing block of the factor with `l` (the inverse of
    /// [`SparseCholesky::trailing_block`]; the same structure is required).
    pub(crate) fn set_trailing_block(&mut self, first: usize, l: &Mat<f64>) {
        let values = &mut self.values;
        for_each_trailing_entry(&self.symbolic, first, |p, i, j| values[p] = l[(i, j)]);
    }

    /// The trailing `n - first` rows and columns of the Cholesky factor L (in the
    /// factor's own, permuted, order), dense. Requires an ordering that keeps those
    /// equations last in place.
    pub(crate) fn trailing_block(&self, first: usize) -> Mat<f64> {
        let nb = self.dim() - first;
        let mut l = Mat::<f64>::zeros(nb, nb);
        for_each_trailing_entry(&self.symbolic, first, |p, i, j| l[(i, j)] = self.values[p]);
        l
    }
}

/// Calls `visit(p, i, j)` for every stored entry of a Cholesky factor in its trailing
/// columns: value `p` is L(first + i, first + j).
fn for_each_trailing_entry(
    symbolic: &SymbolicCholesky<usize>,
    first: usize,
    mut visit: impl FnMut(usize, usize, usize),
) {
    use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
    let n = symbolic.nrows();
    match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(s) => {
            let (cp, ri) = (s.col_ptr(), s.row_idx());
            for j in first..n {
                for p in cp[j]..cp[j + 1] {
                    visit(p, ri[p] - first, j - first);
                }
            }
        }
        SymbolicCholeskyRaw::Supernodal(s) => {
            let (begin, end) = (s.supernode_begin(), s.supernode_end());
            let (rp, vp, ri) = (s.col_ptr_for_row_idx(), s.col_ptr_for_val(), s.row_idx());
            for sn in 0..s.n_supernodes() {
                let (b, e) = (begin[sn], end[sn]);
                if e <= first {
                    continue;
                }
                let pattern = &ri[rp[sn]..rp[sn + 1]];
                let nrows = (e - b) + pattern.len();
                // Column-major dense block: the diagonal block rows b..e, then the
                // rows of the pattern.
                for j in b.max(first)..e {
                    let col = vp[sn] + (j - b) * nrows;
                    for i in j..e {
                        visit(col + i - b, i - first, j - first);
                    }
                    for (k, &i) in pattern.iter().enumerate() {
                        visit(col + (e - b) + k, i - first, j - first);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::{assemble, DofMap, Material, Materials};
    use crate::mesh::builtin;

    #[test]
    fn zeroed_buffers_are_zero_and_the_impossible_ones_refused() {
        for n in [0, 1, 7, 1 << 20] {
            let v = zeroed_f64(n).expect("a small buffer");
            assert_eq!((v.len(), v.capacity()), (n, n));
            assert!(v.iter().all(|x| x.to_bits() == 0));
        }
        // Too large for a layout, and too large for any allocator: an error, no abort.
        assert!(zeroed_f64(usize::MAX / 4).is_none());
        assert!(zeroed_f64(isize::MAX as usize / 16).is_none());
    }

    /// Column counts of the factor, read through the factor's entries one by one.
    fn column_counts(chol: &SparseCholesky) -> Vec<usize> {
        let mut counts = vec![0usize; chol.dim()];
        for_each_trailing_entry(&chol.symbolic, 0, |_, _, j| counts[j] += 1);
        counts
    }

    #[test]
    fn factor_flops_count_the_columns_of_the_factor() {
        use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
        use faer::sparse::{SparseColMat, Triplet};
        // Dense: column k has n - k entries, sum (n - k)^2 = n(n+1)(2n+1)/6.
        let n = 30;
        let m = Mat::<f64>::from_fn(n, n, |i, j| ((i * 31 + j * 17) % 11) as f64 - 5.0);
        let a = &m * m.transpose() + Mat::<f64>::identity(n, n) * (n as f64);
        let triplets: Vec<Triplet<usize, usize, f64>> = (0..n)
            .flat_map(|j| (j..n).map(move |i| (i, j)))
            .map(|(i, j)| Triplet::new(i, j, a[(i, j)]))
            .collect();
        let lower = SparseColMat::try_new_from_triplets(n, n, &triplets).unwrap();
        let dense = SparseCholesky::factor(lower.as_ref(), SymmetricOrdering::Amd).unwrap();
        assert_eq!(dense.factor_flops(), (n * (n + 1) * (2 * n + 1) / 6) as f64);
        // Mesh matrices, small (simplicial) and larger (supernodal): the same count as
        // the entries of each column, counted one by one.
        let mut kinds = Vec::new();
        let material = Material::for_tests();
        for (nx, ny) in [(4, 3), (40, 20), (120, 60)] {
            let mesh = builtin::block(2.0, 1.0, nx, ny);
            let mut fixed = vec![None; 2 * mesh.num_nodes()];
            for node in mesh.group_nodes("bottom").unwrap() {
                fixed[2 * node] = Some(0.0);
                fixed[2 * node + 1] = Some(0.0);
            }
            let dofs = DofMap::new(&fixed);
            let k = assemble(
                &mesh.nodes,
                &mesh.triangles,
                Materials::One(&material),
                &dofs,
                &[],
            )
            .unwrap();
            let chol = SparseCholesky::factor(k.matrix.as_ref(), SymmetricOrdering::Amd).unwrap();
            let counts = column_counts(&chol);
            let expected: f64 = counts.iter().map(|&c| (c * c) as f64).sum();
            assert_eq!(chol.factor_flops(), expected, "{nx} x {ny}");
            // The storage also holds the upper half of each supernode's diagonal block.
            assert!(counts.iter().sum::<usize>() <= chol.factor_nnz());
            kinds.push(matches!(
                chol.symbolic.raw(),
                SymbolicCholeskyRaw::Supernodal(_)
            ));
        }
        assert!(kinds.contains(&true) && kinds.contains(&false), "{kinds:?}");
    }
}
