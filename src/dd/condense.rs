//! The global condensed operator, pure dense linear algebra (no MPI).
//!
//! S = sum_s R_s' S_s R_s on the boundary dofs B, g = sum_s R_s' g_s. The sweep needs
//! only the normal and tangential displacements of the contact nodes,
//!   (Nu, Tu) = C S^-1 (g + C' f) + c0 = u0 + H f,
//! with H = C S^-1 C' (dense, contact-sized) and u0 = C S^-1 g + c0 (c0: prescribed
//! components). Contact values are laid out "packed": rank by rank, each rank's normal
//! values then (with friction) its tangential values, the layout of the per-sweep
//! all-gather, so each rank's rows of H are one contiguous block.

use super::split::ContactDof;
use crate::error::{Error, Result};
use faer::linalg::solvers::Solve;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::{Mat, Side};

/// Packed position of the normal (and tangential) value of each contact node in sweep
/// order, and the packed offset of each rank's block.
pub fn packed_layout(counts: &[usize], frictional: bool) -> (Vec<[usize; 2]>, Vec<usize>) {
    let per = if frictional { 2 } else { 1 };
    let mut pos = Vec::new();
    let mut offsets = Vec::with_capacity(counts.len() + 1);
    let mut off = 0;
    for &c in counts {
        offsets.push(off);
        for i in 0..c {
            pos.push([off + i, off + c + i]);
        }
        off += per * c;
    }
    offsets.push(off);
    (pos, offsets)
}

/// Adds one subdomain's Schur complement and condensed right-hand side into the global
/// ones, through its global boundary indices.
pub fn add_piece(
    s: &mut Mat<f64>,
    g: &mut [f64],
    index: &[usize],
    s_local: &Mat<f64>,
    g_local: &[f64],
) {
    for (a, &ia) in index.iter().enumerate() {
        g[ia] += g_local[a];
        for (b, &ib) in index.iter().enumerate() {
            s[(ia, ib)] += s_local[(a, b)];
        }
    }
}

/// The dense factor of S (contact dofs ordered last) and the contact operator.
pub struct Condensed {
    llt: faer::linalg::solvers::Llt<f64>,
    /// perm[new] = old boundary index: the non-contact (interface) dofs first.
    perm: Vec<usize>,
    pub g: Vec<f64>,
    /// H, packed rows and columns.
    pub h: Mat<f64>,
    pub u0: Vec<f64>,
}

/// C as (packed row, B index, coefficient) triples, and c0 as (packed row, value).
type ContactMatrix = (Vec<(usize, usize, f64)>, Vec<(usize, f64)>);

/// C as a list of (packed row, B index, coefficient) triples, and c0 per packed row.
fn contact_rows(
    dofs: &[ContactDof],
    pos: &[[usize; 2]],
    normal: [f64; 2],
    tangent: [f64; 2],
    frictional: bool,
) -> ContactMatrix {
    let mut c = Vec::new();
    let mut c0 = Vec::new();
    for (k, d) in dofs.iter().enumerate() {
        // u_n = -m.u, u_t = t.u.
        let kinds: &[(usize, [f64; 2])] = if frictional {
            &[(0, [-normal[0], -normal[1]]), (1, tangent)]
        } else {
            &[(0, [-normal[0], -normal[1]])]
        };
        for &(kind, coef) in kinds {
            let row = pos[k][kind];
            let mut fixed_part = 0.0;
            for comp in 0..2 {
                match d.b[comp] {
                    Some(b) => c.push((row, b, coef[comp])),
                    None => fixed_part += coef[comp] * d.fixed[comp],
                }
            }
            c0.push((row, fixed_part));
        }
    }
    (c, c0)
}

impl Condensed {
    /// Factors S and forms H and u0.
    ///
    /// Cost: with n_B boundary dofs, of which n_c on contact nodes, and n_h = rows of H:
    /// the Cholesky of S, n_B^3 / 3 flops; Y = L_cc^-1 C', n_c^2 n_h (C' is zero on
    /// the interface rows, which come first, so only the trailing triangle L_cc works);
    /// H = Y'Y, n_c n_h^2. Memory: n_B^2 + n_c n_h + n_h^2 doubles.
    pub fn new(
        s: Mat<f64>,
        g: Vec<f64>,
        dofs: &[ContactDof],
        counts: &[usize],
        normal: [f64; 2],
        tangent: [f64; 2],
        frictional: bool,
    ) -> Result<Self> {
        let nb = s.nrows();
        let (pos, offsets) = packed_layout(counts, frictional);
        let ncd = *offsets.last().unwrap_or(&0);
        let (c, c0) = contact_rows(dofs, &pos, normal, tangent, frictional);
        let mut on_contact = vec![false; nb];
        for &(_, b, _) in &c {
            on_contact[b] = true;
        }
        let mut perm: Vec<usize> = (0..nb).filter(|&b| !on_contact[b]).collect();
        let n_first = perm.len();
        perm.extend((0..nb).filter(|&b| on_contact[b]));
        let mut inv = vec![0; nb];
        for (new, &old) in perm.iter().enumerate() {
            inv[old] = new;
        }
        let sp = Mat::<f64>::from_fn(nb, nb, |i, j| s[(perm[i], perm[j])]);
        drop(s);
        let llt = sp.llt(Side::Lower).map_err(|_| {
            Error::Numerical(
                "the condensed stiffness matrix is singular: the body can still move rigidly; add Dirichlet conditions that fix the rigid motions (with frictionless contact, also the sliding along the foundation)".into(),
            )
        })?;
        drop(sp);
        let ncc = nb - n_first;
        let mut y = Mat::<f64>::zeros(ncc, ncd);
        for &(row, b, v) in &c {
            y[(inv[b] - n_first, row)] += v;
        }
        let par = faer::get_global_parallelism();
        solve_lower_triangular_in_place(
            llt.L().submatrix(n_first, n_first, ncc, ncc),
            y.as_mut(),
            par,
        );
        let h = y.transpose() * &y;
        drop(y);
        let mut cond = Condensed {
            llt,
            perm,
            g,
            h,
            u0: vec![0.0; ncd],
        };
        let w = cond.solve_s(&cond.g.clone());
        for &(row, b, v) in &c {
            cond.u0[row] += v * w[b];
        }
        for (row, v) in c0 {
            cond.u0[row] += v;
        }
        Ok(cond)
    }

    /// S^-1 x, in the original boundary numbering.
    fn solve_s(&self, x: &[f64]) -> Vec<f64> {
        let n = self.perm.len();
        let xp = faer::Col::<f64>::from_fn(n, |i| x[self.perm[i]]);
        let yp = self.llt.solve(xp.as_mat());
        let mut y = vec![0.0; n];
        for i in 0..n {
            y[self.perm[i]] = yp[(i, 0)];
        }
        y
    }

    /// x_B = S^-1 (g + C' f) for packed contact forces f.
    pub fn boundary_solution(
        &self,
        f: &[f64],
        dofs: &[ContactDof],
        counts: &[usize],
        normal: [f64; 2],
        tangent: [f64; 2],
        frictional: bool,
    ) -> Vec<f64> {
        let (pos, _) = packed_layout(counts, frictional);
        let (c, _) = contact_rows(dofs, &pos, normal, tangent, frictional);
        let mut rhs = self.g.clone();
        for &(row, b, v) in &c {
            rhs[b] += v * f[row];
        }
        self.solve_s(&rhs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packed_layout_groups_each_rank() {
        let (pos, off) = packed_layout(&[2, 1], true);
        assert_eq!(pos, vec![[0, 2], [1, 3], [4, 5]]);
        assert_eq!(off, vec![0, 4, 6]);
        let (pos, off) = packed_layout(&[2, 1], false);
        assert_eq!(pos[2][0], 2);
        assert_eq!(off, vec![0, 2, 3]);
    }

    #[test]
    fn contact_operator_matches_direct_solves() {
        // S = a small SPD matrix on 5 boundary dofs: two contact nodes (x, y each) and,
        // between them, one interface dof (exercises the contact-last reordering).
        let s = Mat::<f64>::from_fn(5, 5, |i, j| {
            if i == j {
                4.0
            } else {
                1.0 / (1.0 + (i + j) as f64)
            }
        });
        let g = vec![1.0, -2.0, 0.7, 0.5, 3.0];
        let dofs = [
            ContactDof {
                b: [Some(0), Some(1)],
                fixed: [0.0; 2],
            },
            ContactDof {
                b: [Some(3), Some(4)],
                fixed: [0.0; 2],
            },
        ];
        let (m, t) = ([0.6, 0.8], [0.8, -0.6]);
        let cond = Condensed::new(s.clone(), g.clone(), &dofs, &[2], m, t, true).unwrap();
        let f = [0.3, -0.1, 0.7, 0.2];
        // Direct: x = S^-1 (g + C' f), then (Nu, Tu).
        let x = cond.boundary_solution(&f, &dofs, &[2], m, t, true);
        let mut via_h = cond.u0.clone();
        for i in 0..4 {
            for j in 0..4 {
                via_h[i] += cond.h[(i, j)] * f[j];
            }
        }
        let xy = |k: usize| if k == 0 { [x[0], x[1]] } else { [x[3], x[4]] };
        let un = |k: usize| -(m[0] * xy(k)[0] + m[1] * xy(k)[1]);
        let ut = |k: usize| t[0] * xy(k)[0] + t[1] * xy(k)[1];
        let direct = [un(0), un(1), ut(0), ut(1)];
        for i in 0..4 {
            assert!(
                (via_h[i] - direct[i]).abs() < 1e-12,
                "{i}: {} {}",
                via_h[i],
                direct[i]
            );
        }
        // H is symmetric (C S^-1 C').
        assert!((&cond.h - cond.h.transpose()).norm_max() < 1e-13);
    }
}
