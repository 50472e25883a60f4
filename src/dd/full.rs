//! The uncondensed step (`--linear full`, one rank, one subdomain): the whole matrix
//! A = K + r N'WN (+ r T'WT) factored once with faer's sparse Cholesky, and each sweep
//! one forward and backward solve. The textbook reference for the condensed path.

use crate::contact::operators::{add_contact_forces, contact_blocks, ContactDofs, NodalForces};
use crate::contact::{tangent_of, LinearStep};
use crate::error::Result;
use crate::fem::{assemble, AssemblyFigures, DofMap, Materials};
use crate::linear::SparseCholesky;
use crate::timer::{Phase, Timer};
use faer::sparse::linalg::cholesky::SymmetricOrdering;
use faer::Mat;

/// What [`DirectStep::new`] assembles: the mesh, its materials, the prescribed dofs
/// (`fixed`), the load per dof, the contact nodes and the augmentation `r` on them.
pub struct DirectSystem<'a> {
    pub nodes: &'a [[f64; 2]],
    pub triangles: &'a [[usize; 3]],
    pub materials: Materials<'a>,
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
    normals: Vec<[f64; 2]>,
    /// Without friction Tu is not part of the method: reported as 0, as the condensed
    /// step does, so both paths see the same residual scale.
    frictional: bool,
}

impl DirectStep {
    /// Assembles A on the free dofs of `fixed` with the same r on every contact
    /// direction, lifts the prescribed values into the right-hand side and factors A
    /// (AMD ordering), timed as [`Phase::Assemble`] and [`Phase::Factor`]; tells
    /// `assembled_figures` the matrix's size as soon as it is assembled.
    pub fn new(
        system: &DirectSystem,
        timer: &Timer,
        assembled_figures: &dyn Fn(AssemblyFigures),
    ) -> Result<Self> {
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
                contact.normals,
                contact.frictional,
            );
            let assembled = assemble(
                system.nodes,
                system.triangles,
                system.materials,
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
        assembled_figures(AssemblyFigures {
            equations: assembled.nrows(),
            entries: assembled.compute_nnz(),
        });
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
            normals: contact.normals.to_vec(),
            frictional: contact.frictional,
        })
    }

    /// Displacement of every node from the last solve, prescribed values included.
    pub(crate) fn displacement(&self) -> Vec<[f64; 2]> {
        let free: Vec<f64> = (0..self.dofs.n_free).map(|i| self.rhs[(i, 0)]).collect();
        self.dofs
            .expand(&free)
            .chunks_exact(2)
            .map(|c| [c[0], c[1]])
            .collect()
    }

    /// Non-zeros stored in the factor.
    pub(crate) fn factor_nnz(&self) -> usize {
        self.chol.factor_nnz()
    }

    /// See [`SparseCholesky::factor_flops`].
    pub(crate) fn factor_flops(&self) -> f64 {
        self.chol.factor_flops()
    }

    fn dof_value(&self, dof: usize) -> f64 {
        self.dofs.eq[dof].map_or(self.dofs.value[dof], |i| self.rhs[(i, 0)])
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
            &self.normals,
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
            &self.normals,
            NodalForces {
                normal: force_n,
                tangential: force_t,
            },
            rhs,
        );
        self.chol.solve_in_place(self.rhs.as_mut());
        for (k, &node) in self.contact_nodes.iter().enumerate() {
            let ([mx, my], [tx, ty]) = (self.normals[k], tangent_of(self.normals[k]));
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
