//! The factor-once sparse direct solve of step 1 on one (sub)domain, with faer's
//! supernodal Cholesky. Inside the Uzawa loop only the triangular solves run.

use crate::case::Material;
use crate::contact::LinearStep;
use crate::error::{Error, Result};
use crate::fem::{assemble, DofMap};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SparseColMatRef;
use faer::{Conj, Mat, MatMut, Side};
use std::time::Instant;

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
        let par = faer::get_global_parallelism();
        let symbolic =
            factorize_symbolic_cholesky(a.symbolic(), Side::Lower, ordering, Default::default())
                .map_err(|e| {
                    Error::Numerical(format!("symbolic Cholesky factorization failed: {e:?}"))
                })?;
        let mut values = Vec::new();
        values.try_reserve_exact(symbolic.len_val()).map_err(|_| {
            Error::Numerical(format!(
                "out of memory for the Cholesky factor ({} non-zeros); use more ranks or a coarser mesh",
                symbolic.len_val()
            ))
        })?;
        values.resize(symbolic.len_val(), 0.0);
        let mut mem =
            MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut values,
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
        let scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, par));
        Ok(SparseCholesky {
            symbolic,
            values,
            scratch,
        })
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

    pub fn dim(&self) -> usize {
        self.symbolic.nrows()
    }

    /// Non-zeros stored in the factor.
    pub fn factor_nnz(&self) -> usize {
        self.values.len()
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

/// Wall-clock seconds of the set-up phases.
#[derive(Debug, Clone, Copy, Default)]
pub struct SetupTimes {
    pub assemble: f64,
    pub factor: f64,
}

/// A = K + r N'WN (+ r T'WT), assembled and factored once; `solve` is two triangular
/// solves plus O(n) vector work.
pub struct DirectStep {
    chol: SparseCholesky,
    dofs: DofMap,
    /// F + lifting of the prescribed dofs, on the free dofs.
    base: Vec<f64>,
    rhs: Mat<f64>,
    contact_nodes: Vec<usize>,
    normal: [f64; 2],
    tangent: [f64; 2],
}

impl DirectStep {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        nodes: &[[f64; 2]],
        triangles: &[[usize; 3]],
        material: &Material,
        fixed: &[Option<f64>],
        load: &[f64],
        contact: &ContactDofs,
        r: f64,
    ) -> Result<(Self, SetupTimes)> {
        let t0 = Instant::now();
        let dofs = DofMap::new(fixed);
        let [mx, my] = contact.normal;
        let blocks: Vec<(usize, [[f64; 2]; 2])> = contact
            .nodes
            .iter()
            .zip(contact.w)
            .map(|(&node, &w)| {
                let rw = r * w;
                // N_i'N_i = m m'; with friction also T_i'T_i = t t', and m m' + t t' = I.
                let blk = if contact.frictional {
                    [[rw, 0.0], [0.0, rw]]
                } else {
                    [[rw * mx * mx, rw * mx * my], [rw * my * mx, rw * my * my]]
                };
                (node, blk)
            })
            .collect();
        let assembled = assemble(nodes, triangles, material, &dofs, &blocks)?;
        let mut base = assembled.lifting;
        for (dof, eq) in dofs.eq.iter().enumerate() {
            if let Some(i) = eq {
                base[*i] += load[dof];
            }
        }
        let assemble_s = t0.elapsed().as_secs_f64();

        let t1 = Instant::now();
        let chol = SparseCholesky::factor(assembled.matrix.as_ref(), SymmetricOrdering::Amd)?;
        let factor_s = t1.elapsed().as_secs_f64();
        let n = dofs.n_free;
        Ok((
            DirectStep {
                chol,
                dofs,
                base,
                rhs: Mat::zeros(n, 1),
                contact_nodes: contact.nodes.to_vec(),
                normal: contact.normal,
                tangent: contact.tangent,
            },
            SetupTimes {
                assemble: assemble_s,
                factor: factor_s,
            },
        ))
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

    fn dof_value(&self, dof: usize) -> f64 {
        self.dofs.eq[dof].map_or(self.dofs.value[dof], |i| self.rhs[(i, 0)])
    }
}

impl LinearStep for DirectStep {
    fn solve(
        &mut self,
        force_n: &[f64],
        force_t: &[f64],
        un: &mut [f64],
        ut: &mut [f64],
    ) -> Result<()> {
        for (i, b) in self.base.iter().enumerate() {
            self.rhs[(i, 0)] = *b;
        }
        let ([mx, my], [tx, ty]) = (self.normal, self.tangent);
        for (k, &node) in self.contact_nodes.iter().enumerate() {
            // N_i' = -m, T_i' = t.
            let f = [
                -mx * force_n[k] + tx * force_t[k],
                -my * force_n[k] + ty * force_t[k],
            ];
            for c in 0..2 {
                if let Some(i) = self.dofs.eq[2 * node + c] {
                    self.rhs[(i, 0)] += f[c];
                }
            }
        }
        self.chol.solve_in_place(self.rhs.as_mut());
        for (k, &node) in self.contact_nodes.iter().enumerate() {
            let (ux, uy) = (self.dof_value(2 * node), self.dof_value(2 * node + 1));
            un[k] = -(mx * ux + my * uy);
            ut[k] = tx * ux + ty * uy;
        }
        Ok(())
    }
}
