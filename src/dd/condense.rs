//! The global condensed operator, pure dense linear algebra (no MPI).
//!
//! S = sum_s R_s' S_s R_s on the boundary dofs B, g = sum_s R_s' g_s. The sweep needs
//! only the normal and tangential displacements of the contact nodes,
//!   (Nu, Tu) = C S^-1 (g + C' f) + c0 = u0 + C S^-1 C' f,
//! with u0 = C S^-1 g + c0 (c0: prescribed components). With the contact dofs ordered
//! last in S = L L', C' f is zero on the interface rows, so S^-1 C' f restricted to the
//! contact dofs is L_cc^-T L_cc^-1 (C_c' f): two dense triangular solves with the
//! trailing n_c x n_c triangle, 2 n_c^2 flops a sweep, whatever the interface size.
//! (Forming H = C S^-1 C' explicitly would cost n_c^3 more flops once for about the
//! same per-sweep traffic; with the accelerated loop's ~100 sweeps it does not pay.)
//!
//! Contact values are laid out "packed": rank by rank, each rank's normal values then
//! (with friction) its tangential values, the layout of the per-sweep gather.

use super::split::ContactDof;
use crate::error::{Error, Result};
use faer::linalg::solvers::Solve;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
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

/// The dense factor of S (contact dofs ordered last) and what a sweep needs.
pub struct Condensed {
    llt: faer::linalg::solvers::Llt<f64>,
    /// perm[new] = old boundary index: the non-contact (interface) dofs first.
    perm: Vec<usize>,
    /// Number of interface (non-contact) boundary dofs, first in `perm`.
    n_first: usize,
    /// C restricted to the contact dofs: (packed row, trailing index, coefficient).
    c: Vec<(usize, usize, f64)>,
    pub g: Vec<f64>,
    /// C S^-1 g + c0, packed.
    pub u0: Vec<f64>,
    work: faer::Mat<f64>,
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
    /// Factors S (n_B^3 / 3 flops, n_B^2 doubles) and computes u0.
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
        let c_trailing: Vec<(usize, usize, f64)> = c
            .iter()
            .map(|&(row, b, v)| (row, inv[b] - n_first, v))
            .collect();
        let mut cond = Condensed {
            llt,
            perm,
            n_first,
            c: c_trailing,
            g,
            u0: vec![0.0; ncd],
            work: Mat::zeros(nb - n_first, 1),
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

    /// (Nu, Tu) = u0 + C S^-1 C' f for packed contact forces f, into `out` (packed):
    /// two triangular solves with the trailing block of the factor.
    pub fn contact_response(&mut self, f: &[f64], out: &mut [f64]) {
        let ncc = self.work.nrows();
        self.work.fill(0.0);
        for &(row, k, v) in &self.c {
            self.work[(k, 0)] += v * f[row];
        }
        let par = faer::get_global_parallelism();
        let l = self.llt.L();
        let l_cc = l.submatrix(self.n_first, self.n_first, ncc, ncc);
        solve_lower_triangular_in_place(l_cc, self.work.as_mut(), par);
        solve_upper_triangular_in_place(l_cc.transpose(), self.work.as_mut(), par);
        out.copy_from_slice(&self.u0);
        for &(row, k, v) in &self.c {
            out[row] += v * self.work[(k, 0)];
        }
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
        let mut cond = cond;
        let mut via_h = vec![0.0; 4];
        cond.contact_response(&f, &mut via_h);
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
        // The response is linear and symmetric in f (C S^-1 C' is): <e_i, R e_j> = <e_j, R e_i>.
        let resp = |cond: &mut Condensed, k: usize| {
            let mut e = [0.0; 4];
            e[k] = 1.0;
            let mut out = vec![0.0; 4];
            cond.contact_response(&e, &mut out);
            (0..4).map(|i| out[i] - cond.u0[i]).collect::<Vec<f64>>()
        };
        let cols: Vec<Vec<f64>> = (0..4).map(|k| resp(&mut cond, k)).collect();
        for i in 0..4 {
            for j in 0..4 {
                assert!((cols[j][i] - cols[i][j]).abs() < 1e-13);
            }
        }
    }
}
