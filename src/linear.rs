//! The factor-once sparse direct solve of step 1 on one (sub)domain, with faer's
//! supernodal Cholesky. Inside the Uzawa loop only the triangular solves run.

use crate::case::Material;
use crate::contact::LinearStep;
use crate::error::{Error, Result};
use crate::fem::{assemble, DofMap};
use crate::timer::{Phase, Timer};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SparseColMatRef;
use faer::{Conj, Mat, MatMut, Side};
use std::collections::BTreeMap;
use std::time::Instant;

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
    pub fn analyse(
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
    pub fn refactor(&mut self, a: SparseColMatRef<'_, usize, f64>) -> Result<()> {
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
    pub fn forward_in_place(&mut self, mut x: MatMut<'_, f64>) {
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
    pub fn backward_in_place(&mut self, mut x: MatMut<'_, f64>) {
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

    pub fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Non-zeros stored in the factor.
    pub fn factor_nnz(&self) -> usize {
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

/// The contact geometry a linear step needs: which nodes, their weights, the normal.
pub struct ContactDofs<'a> {
    /// Node ids (in the numbering of the mesh given to [`DirectStep::new`]).
    pub nodes: &'a [usize],
    pub w: &'a [f64],
    pub normal: [f64; 2],
    pub tangent: [f64; 2],
    /// Whether the tangential augmentation r T'WT is part of A.
    pub frictional: bool,
}

/// What [`DirectStep::new`] assembles: the mesh, its material, the prescribed dofs
/// (`fixed`), the load per dof, the contact nodes and the augmentation `r` on them.
pub struct DirectSystem<'a> {
    pub nodes: &'a [[f64; 2]],
    pub triangles: &'a [[usize; 3]],
    pub material: &'a Material,
    pub fixed: &'a [Option<f64>],
    pub load: &'a [f64],
    pub contact: ContactDofs<'a>,
    pub r: f64,
}

/// A = K + r N'WN (+ r T'WT), assembled and factored once; `solve` is two triangular
/// solves plus O(n) vector work.
pub struct DirectStep {
    chol: SparseCholesky,
    /// A as assembled (lower triangle) with r0 on every contact direction, and the
    /// contact weights: what a change of r adds.
    a0: faer::sparse::SparseColMat<usize, f64>,
    r0: f64,
    w: Vec<f64>,
    dofs: DofMap,
    /// F + lifting of the prescribed dofs, on the free dofs.
    base: Vec<f64>,
    rhs: Mat<f64>,
    contact_nodes: Vec<usize>,
    normal: [f64; 2],
    tangent: [f64; 2],
    /// Without friction Tu is not part of the method: reported as 0, as the condensed
    /// step does, so both paths see the same residual scale.
    frictional: bool,
}

impl DirectStep {
    /// Assembles and factors the system (timed as [`Phase::Assemble`] and
    /// [`Phase::Factor`]).
    pub fn new(system: &DirectSystem, timer: &Timer) -> Result<Self> {
        let DirectSystem {
            contact, load, r, ..
        } = system;
        let r = *r;
        let (dofs, assembled, base) = timer.time(Phase::Assemble, || -> Result<_> {
            let dofs = DofMap::new(system.fixed);
            let rr = vec![r; contact.nodes.len()];
            let blocks = contact_blocks(
                contact.nodes,
                contact.w,
                &rr,
                &rr,
                contact.normal,
                contact.frictional,
            );
            let assembled = assemble(
                system.nodes,
                system.triangles,
                system.material,
                &dofs,
                &blocks,
            )?;
            let mut base = assembled.lifting;
            for (dof, eq) in dofs.eq.iter().enumerate() {
                if let Some(i) = eq {
                    base[*i] += load[dof];
                }
            }
            Ok((dofs, assembled.matrix, base))
        })?;
        let chol = timer.time(Phase::Factor, || {
            SparseCholesky::factor(assembled.as_ref(), SymmetricOrdering::Amd)
        })?;
        let n = dofs.n_free;
        Ok(DirectStep {
            chol,
            a0: assembled,
            r0: r,
            w: contact.w.to_vec(),
            dofs,
            base,
            rhs: Mat::zeros(n, 1),
            contact_nodes: contact.nodes.to_vec(),
            normal: contact.normal,
            tangent: contact.tangent,
            frictional: contact.frictional,
        })
    }

    /// Displacement of every node from the last solve, prescribed values included.
    pub fn displacement(&self) -> Vec<[f64; 2]> {
        let free: Vec<f64> = (0..self.dofs.n_free).map(|i| self.rhs[(i, 0)]).collect();
        self.dofs
            .expand(&free)
            .chunks_exact(2)
            .map(|c| [c[0], c[1]])
            .collect()
    }

    pub fn factor_nnz(&self) -> usize {
        self.chol.factor_nnz()
    }

    /// See [`SparseCholesky::factor_flops`].
    pub fn factor_flops(&self) -> f64 {
        self.chol.factor_flops()
    }

    fn dof_value(&self, dof: usize) -> f64 {
        self.dofs.eq[dof].map_or(self.dofs.value[dof], |i| self.rhs[(i, 0)])
    }
}

/// Augmentation blocks w_i (r_n m m' + r_t t t') of the contact nodes (without friction
/// w_i r_n m m'), with t t' = I - m m' for the unit tangent t.
pub fn contact_blocks(
    nodes: &[usize],
    w: &[f64],
    r_n: &[f64],
    r_t: &[f64],
    m: [f64; 2],
    frictional: bool,
) -> Vec<(usize, [[f64; 2]; 2])> {
    let mm = [[m[0] * m[0], m[0] * m[1]], [m[1] * m[0], m[1] * m[1]]];
    nodes
        .iter()
        .enumerate()
        .map(|(k, &node)| {
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

/// Adds the contact forces N' force_n + T' force_t (N_i' = -m, T_i' = t) to a right-hand
/// side on the free dofs.
pub fn add_contact_forces(
    dofs: &DofMap,
    contact_nodes: &[usize],
    normal: [f64; 2],
    tangent: [f64; 2],
    force_n: &[f64],
    force_t: &[f64],
    rhs: &mut [f64],
) {
    let ([mx, my], [tx, ty]) = (normal, tangent);
    for (k, &node) in contact_nodes.iter().enumerate() {
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

impl LinearStep for DirectStep {
    /// A numeric refactorization of the whole matrix (this path is the textbook reference).
    fn set_r(&mut self, r_n: &[f64], r_t: &[f64]) -> Result<bool> {
        let mut a = self.a0.clone();
        let shift = |r: &[f64]| r.iter().map(|r| r - self.r0).collect::<Vec<f64>>();
        let delta = contact_blocks(
            &self.contact_nodes,
            &self.w,
            &shift(r_n),
            &shift(r_t),
            self.normal,
            self.frictional,
        );
        let (cp, ri): (Vec<usize>, Vec<usize>) = (
            a.symbolic().col_ptr().to_vec(),
            a.symbolic().row_idx().to_vec(),
        );
        let vals = a.val_mut();
        for &(node, blk) in &delta {
            for (ca, row) in blk.iter().enumerate() {
                for (cb, &v) in row.iter().enumerate() {
                    let (Some(i), Some(j)) =
                        (self.dofs.eq[2 * node + ca], self.dofs.eq[2 * node + cb])
                    else {
                        continue;
                    };
                    if i < j {
                        continue;
                    }
                    if let Some(p) = (cp[j]..cp[j + 1]).find(|&p| ri[p] == i) {
                        vals[p] += v;
                    }
                }
            }
        }
        // Same sparsity as a0: only the numeric factorization is redone.
        self.chol.refactor(a.as_ref())?;
        Ok(true)
    }

    fn solve(
        &mut self,
        force_n: &[f64],
        force_t: &[f64],
        un: &mut [f64],
        ut: &mut [f64],
    ) -> Result<()> {
        let rhs = self
            .rhs
            .col_mut(0)
            .try_as_col_major_mut()
            .expect("a one-column Mat is contiguous")
            .as_slice_mut();
        rhs.copy_from_slice(&self.base);
        add_contact_forces(
            &self.dofs,
            &self.contact_nodes,
            self.normal,
            self.tangent,
            force_n,
            force_t,
            rhs,
        );
        self.chol.solve_in_place(self.rhs.as_mut());
        let ([mx, my], [tx, ty]) = (self.normal, self.tangent);
        for (k, &node) in self.contact_nodes.iter().enumerate() {
            let (ux, uy) = (self.dof_value(2 * node), self.dof_value(2 * node + 1));
            un[k] = -(mx * ux + my * uy);
            ut[k] = if self.frictional {
                tx * ux + ty * uy
            } else {
                0.0
            };
        }
        Ok(())
    }
}

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
    rhs: Mat<f64>,
    /// Seconds spent in the fill-reducing ordering (part of the factor phase).
    pub ordering_s: f64,
    /// The ordering used (what `Auto` resolved to).
    pub ordering: Ordering,
}

/// Fill-reducing ordering of a subdomain's interior.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Ordering {
    /// Nested dissection from [`ND_MIN_INTERIOR_DOFS`] interior dofs on, minimum degree
    /// below: the default.
    ///
    /// On a 2D mesh of n nodes, nested dissection orders for O(n log n) fill and
    /// O(n^1.5) flops, the optimum (George): separators of O(sqrt n) nodes split the
    /// mesh recursively, and only the separators fill. Minimum degree is greedy and
    /// local; its factor is larger by a factor that grows with n (measured: x1.24 at
    /// 411k nodes, x1.6 at 1.2M), and its flops more. But METIS_NodeND costs several
    /// times AMD (1.7 s against 0.25 s at 411k nodes, 7.4 s against 3.1 s at 1.2M),
    /// so the smaller factor pays only on large subdomains. Factor phase, one thread
    /// per rank (ordering included): block level 5 on one rank (411k nodes, 0.82M
    /// interior dofs) 3.5 s AMD against 4.8 s ND; hertz level 5 on two ranks (600k
    /// nodes, 1.2M dofs per rank) 12.9 s AMD against 9.2 s ND; block level 6 on two
    /// ranks (820k nodes) 16.7 s against 12.1 s; hertz 5 on one rank (1.2M nodes)
    /// 32.4 s against 18.2 s. The crossover lies between 0.82M and 1.2M interior dofs:
    /// the threshold is 1M. Everything smaller (levels 4 and below, any rank count)
    /// stays on AMD, whose ordering is never more than a fraction of a second there.
    #[default]
    Auto,
    /// Approximate minimum degree (faer): cheapest to compute, the best total below
    /// about 1M interior dofs.
    Amd,
    /// METIS nested dissection on the node graph: less fill, for very large subdomains.
    NestedDissection,
}

/// Interior dofs from which [`Ordering::Auto`] chooses nested dissection (see there).
pub const ND_MIN_INTERIOR_DOFS: usize = 1_000_000;

impl Ordering {
    /// The name of the `--ordering` option.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Amd => "amd",
            Self::NestedDissection => "nd",
        }
    }

    /// The ordering actually used on a subdomain of `n_interior` interior dofs.
    pub fn resolve(self, n_interior: usize) -> Self {
        match self {
            Self::Auto if n_interior >= ND_MIN_INTERIOR_DOFS => Self::NestedDissection,
            Self::Auto => Self::Amd,
            other => other,
        }
    }
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
        let n = a.nrows();
        let n_interior = n - n_b;
        let t0 = Instant::now();
        let ordering = ordering.resolve(n_interior);
        // The interior is ordered on its node graph; the boundary equations stay last in
        // their order. AMD is also the fallback should METIS fail.
        let mut graph = NodeGraph::new(a, n_interior, groups);
        let node_perm = match ordering {
            Ordering::NestedDissection => {
                match partition::nested_dissection(&graph.xadj, &graph.adjncy) {
                    Ok(p) => p,
                    Err(_) => amd_node_order(&mut graph)?,
                }
            }
            _ => amd_node_order(&mut graph)?,
        };
        let (fwd, inv) = graph.boundary_last(&node_perm, n);
        drop(graph);
        let ordering_s = t0.elapsed().as_secs_f64();
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
            rhs: Mat::zeros(n, 1),
            ordering_s,
            ordering,
        })
    }

    pub fn n_boundary(&self) -> usize {
        self.l_bb.nrows()
    }

    pub fn factor_nnz(&self) -> usize {
        self.chol.factor_nnz()
    }

    /// See [`SparseCholesky::factor_flops`].
    pub fn factor_flops(&self) -> f64 {
        self.chol.factor_flops()
    }

    /// The subdomain's Schur complement onto its boundary dofs (dense, symmetric).
    pub fn schur(&self) -> Mat<f64> {
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
    pub fn update_boundary(&mut self, delta: &[(usize, usize, f64)]) -> Result<()> {
        let target = lower_entries(delta);
        let change = entry_difference(&self.applied, &target);
        if change.is_empty() {
            return Ok(());
        }
        let n = self.l_bb.nrows();
        // Before the block first changes: S~ must be that of the assembled matrix, also
        // when the first update is made in place and a later one falls back to refactoring.
        let l_bb = &self.l_bb;
        let s0 = self.s0.get_or_insert_with(|| lower_gram(l_bb.as_ref()));
        if let Some(l) = low_rank_updated(&self.l_bb, &change) {
            self.l_bb = l;
        } else {
            let mut s = s0.clone();
            for (&(i, j), &v) in &target {
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
        }
        self.applied = target;
        self.chol.set_trailing_block(self.n_interior, &self.l_bb);
        Ok(())
    }

    /// Number of interface dofs (the tail of B).
    pub fn n_interface(&self) -> usize {
        self.l_bb.nrows() - self.n_contact
    }

    /// This subdomain's part of the interface system left once the contact dofs are
    /// eliminated, S_gg - S_gc S_cc^-1 S_cg = L_gg L_gg' - alpha I (dense, symmetric).
    pub fn interface_schur(&self) -> Mat<f64> {
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

/// The graph between the nodes of the interior block of a matrix (in CSR form), the
/// input of the fill-reducing orderings.
pub struct NodeGraph {
    pub xadj: Vec<usize>,
    pub adjncy: Vec<usize>,
    /// First equation of each node (and the end), equations of a node consecutive.
    pub first_eq: Vec<usize>,
}

impl NodeGraph {
    /// From the LOWER triangle `a`, its first `n_interior` equations and `groups[eq]`,
    /// the node of each equation. A pair of nodes shows up in the columns of the node
    /// with the smaller equations; a marker per node skips repeats without sorting (two
    /// passes: count, then fill).
    pub fn new(a: SparseColMatRef<'_, usize, f64>, n_interior: usize, groups: &[usize]) -> Self {
        let mut group_of = vec![0usize; n_interior];
        let mut first_eq = Vec::new();
        for i in 0..n_interior {
            if i == 0 || groups[i] != groups[i - 1] {
                first_eq.push(i);
            }
            group_of[i] = first_eq.len() - 1;
        }
        let ng = first_eq.len();
        first_eq.push(n_interior);
        let mut marker = vec![usize::MAX; ng];
        let mut for_each_pair = |visit: &mut dyn FnMut(usize, usize)| {
            marker.fill(usize::MAX);
            for u in 0..ng {
                for j in first_eq[u]..first_eq[u + 1] {
                    for i in a.symbolic().row_idx_of_col(j) {
                        if i >= n_interior {
                            continue;
                        }
                        let v = group_of[i];
                        if v != u && marker[v] != u {
                            marker[v] = u;
                            visit(u, v);
                        }
                    }
                }
            }
        };
        let mut xadj = vec![0usize; ng + 1];
        for_each_pair(&mut |u, v| {
            xadj[u + 1] += 1;
            xadj[v + 1] += 1;
        });
        for v in 0..ng {
            xadj[v + 1] += xadj[v];
        }
        let mut next = xadj[..ng].to_vec();
        let mut adjncy = vec![0usize; xadj[ng]];
        for_each_pair(&mut |u, v| {
            adjncy[next[u]] = v;
            next[u] += 1;
            adjncy[next[v]] = u;
            next[v] += 1;
        });
        NodeGraph {
            xadj,
            adjncy,
            first_eq,
        }
    }

    /// Equation permutation (perm[new] = old) from a node permutation.
    pub fn expand(&self, node_perm: &[usize]) -> Vec<usize> {
        node_perm
            .iter()
            .flat_map(|&g| self.first_eq[g]..self.first_eq[g + 1])
            .collect()
    }

    /// The permutation of all `n` equations and its inverse: the interior in the order of
    /// `node_perm`, then the boundary equations (from the last interior one on) in place.
    pub fn boundary_last(&self, node_perm: &[usize], n: usize) -> (Vec<usize>, Vec<usize>) {
        let n_interior = self.first_eq[self.first_eq.len() - 1];
        let mut fwd = self.expand(node_perm);
        fwd.extend(n_interior..n);
        let mut inv = vec![0usize; n];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        (fwd, inv)
    }
}

/// Minimum degree (AMD) of a node graph (its rows sorted in place, as faer requires).
/// On the node graph rather than the dof graph: a quarter of the entries, and AMD finds
/// the dofs of a node indistinguishable anyway. Measured against the dof graph: factors
/// within 3% of the same size either way, the ordering 40-60% faster up to level 4
/// (hertz level 4, one rank: 0.46-0.72 s to 0.24-0.28 s), about as fast at level 5.
fn amd_node_order(graph: &mut NodeGraph) -> Result<Vec<usize>> {
    use faer::sparse::linalg::amd;
    use faer::sparse::SymbolicSparseColMatRef;
    let ng = graph.first_eq.len() - 1;
    for v in 0..ng {
        graph.adjncy[graph.xadj[v]..graph.xadj[v + 1]].sort_unstable();
    }
    let mut node_fwd = vec![0usize; ng];
    let mut node_inv = vec![0usize; ng];
    if ng > 0 {
        let pattern =
            SymbolicSparseColMatRef::new_checked(ng, ng, &graph.xadj, None, &graph.adjncy);
        let mut mem = MemBuffer::new(amd::order_scratch::<usize>(ng, graph.adjncy.len()));
        amd::order(
            &mut node_fwd,
            &mut node_inv,
            pattern,
            amd::Control::default(),
            MemStack::new(&mut mem),
        )
        .map_err(|e| Error::Numerical(format!("AMD ordering failed: {e:?}")))?;
    }
    Ok(node_fwd)
}

/// The node of each interior equation of a [`DofMap`] built by `DofMap::with_last`
/// (equations below `n_free - n_last`), for [`LocalFactor::new`].
pub fn interior_groups(dofs: &DofMap) -> Vec<usize> {
    let mut groups = vec![usize::MAX; dofs.n_free];
    for (dof, eq) in dofs.eq.iter().enumerate() {
        if let Some(e) = eq {
            groups[*e] = dof / 2;
        }
    }
    groups
}

impl SparseCholesky {
    /// Overwrites the trailing block of the factor with `l` (the inverse of
    /// [`SparseCholesky::trailing_block`]; the same structure is required).
    fn set_trailing_block(&mut self, first: usize, l: &Mat<f64>) {
        let values = &mut self.values;
        for_each_trailing_entry(&self.symbolic, first, |p, i, j| values[p] = l[(i, j)]);
    }

    /// The trailing `n - first` rows and columns of the Cholesky factor L (in the
    /// factor's own, permuted, order), dense. Requires an ordering that keeps those
    /// equations last in place.
    fn trailing_block(&self, first: usize) -> Mat<f64> {
        let nb = self.dim() - first;
        let mut l = Mat::<f64>::zeros(nb, nb);
        for_each_trailing_entry(&self.symbolic, first, |p, i, j| l[(i, j)] = self.values[p]);
        l
    }
}

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
/// the b^3 / 3 of a blocked factorization. Measured at b = 1000: refactoring 11.6 ms;
/// updating 4.6 ms at k = 2 (mostly the copy of the block), 5.5 ms at k = 62, 10.9 ms at
/// k = 125. A retune after the first moves 1-10 directions of hundreds to thousands.
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

/// The factor of L L' + D, with D the symmetric matrix of `change` (lower triangle),
/// by rank-one updates and downdates: D restricted to the dofs it touches is split into
/// its eigenpairs (lambda, v), and L L' + sum lambda v v' is refactored in place from the
/// first touched dof on (the columns before it do not change). `None` when D touches
/// more than [`LOW_RANK_MAX_SHARE`] of the dofs or an update fails (the caller then
/// refactors the whole block).
fn low_rank_updated(l: &Mat<f64>, change: &BTreeMap<(usize, usize), f64>) -> Option<Mat<f64>> {
    let n = l.nrows();
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
    let first = touched[0];
    let m = n - first;
    let mut w = Mat::<f64>::zeros(m, k);
    for (a, &dof) in touched.iter().enumerate() {
        for c in 0..k {
            w[(dof - first, c)] = eig.eigenvectors[(a, c)];
        }
    }
    let mut alpha = faer::Col::<f64>::from_fn(k, |c| eig.eigenvalues[c]);
    let mut updated = l.clone();
    faer::linalg::cholesky::llt::update::rank_r_update_clobber(
        updated.as_mut().submatrix_mut(first, first, m, m),
        w.as_mut(),
        alpha.as_diagonal_mut(),
    )
    .ok()?;
    // A downdate that nearly cancels a diagonal may leave a non-finite or zero pivot
    // without reporting it: refactor instead.
    let sound = (first..n).all(|j| {
        let d = updated[(j, j)];
        d.is_finite() && d > 0.0
    });
    sound.then_some(updated)
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
    use crate::case::{Hypothesis, Material};
    use crate::fem::{assemble, DofMap};
    use crate::mesh::builtin;
    use faer::prelude::Solve;

    fn material() -> Material {
        Material {
            young: 1000.0,
            poisson: 0.3,
            hypothesis: Hypothesis::PlaneStrain,
        }
    }

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
        let plain = assemble(&mesh.nodes, &mesh.triangles, &material(), &dofs, &[]).unwrap();
        let shift: Vec<(usize, [[f64; 2]; 2])> = right
            .iter()
            .map(|&v| (v, [[alpha, 0.0], [0.0, alpha]]))
            .collect();
        let shifted = assemble(&mesh.nodes, &mesh.triangles, &material(), &dofs, &shift).unwrap();
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
    fn contact_blocks_weigh_each_direction_by_its_r() {
        let m = [0.6, 0.8];
        let t = [-0.8, 0.6];
        let blocks = contact_blocks(&[7, 9], &[0.5, 2.0], &[10.0, 3.0], &[4.0, 3.0], m, true);
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
        let plain = contact_blocks(&[7], &[0.5], &[10.0], &[4.0], m, false);
        let want = [[1.8, 2.4], [2.4, 3.2]];
        for i in 0..2 {
            for j in 0..2 {
                assert!((plain[0].1[i][j] - want[i][j]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn auto_ordering_is_nested_dissection_on_large_subdomains_only() {
        assert_eq!(Ordering::default(), Ordering::Auto);
        assert_eq!(Ordering::Auto.resolve(1000), Ordering::Amd);
        assert_eq!(
            Ordering::Auto.resolve(ND_MIN_INTERIOR_DOFS),
            Ordering::NestedDissection
        );
        assert_eq!(Ordering::Amd.resolve(usize::MAX), Ordering::Amd);
        assert_eq!(
            Ordering::NestedDissection.resolve(0),
            Ordering::NestedDissection
        );
    }

    #[test]
    fn subdomains_of_one_rank_order_at_the_same_time() {
        // A binary of this crate binds libmetis's rand/srand to the partition crate's
        // per-thread generators; without them the orderings of a rank's subdomains
        // would queue on one lock.
        assert!(partition::metis_runs_concurrently());
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
        let (a, _) = spd(n);
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
        for (nx, ny) in [(4, 3), (40, 20), (120, 60)] {
            let mesh = builtin::block(2.0, 1.0, nx, ny);
            let mut fixed = vec![None; 2 * mesh.num_nodes()];
            for node in mesh.group_nodes("bottom").unwrap() {
                fixed[2 * node] = Some(0.0);
                fixed[2 * node + 1] = Some(0.0);
            }
            let dofs = DofMap::new(&fixed);
            let k = assemble(&mesh.nodes, &mesh.triangles, &material(), &dofs, &[]).unwrap();
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
        let l1 = low_rank_updated(&l, &raise).expect("4 of 80 dofs: updated in place");
        assert!((&l1 * l1.transpose() - &a1).norm_max() < 1e-12 * a1.norm_max());
        let lower = BTreeMap::from([
            ((20, 20), -0.999 * big),
            ((21, 20), -0.999 * 0.3 * big),
            ((21, 21), -0.999 * big),
        ]);
        let a2 = with_change(&a1, &lower);
        let l2 = low_rank_updated(&l1, &lower).expect("updated in place");
        // Cancellation costs digits relative to the removed spring, no more.
        assert!((&l2 * l2.transpose() - &a2).norm_max() < 1e-12 * big);
        // The columns before the first changed dof are untouched, bit for bit.
        assert_eq!(l2.submatrix(0, 0, n, 20), l.submatrix(0, 0, n, 20));
        // Too many dofs, or a change that makes the matrix indefinite: refactor instead.
        let wide: BTreeMap<(usize, usize), f64> = (0..6).map(|i| ((i, i), 1.0)).collect();
        assert!(low_rank_updated(&l, &wide).is_none());
        let indefinite = BTreeMap::from([((30, 30), -2.0 * a[(30, 30)])]);
        assert!(low_rank_updated(&l, &indefinite).is_none());
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
        let a = assemble(&mesh.nodes, &mesh.triangles, &material(), &dofs, &[]).unwrap();
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
}
