//! P1 plane elasticity: element kernels (pure, unit-tested) and threaded assembly.
//!
//! Degrees of freedom are node-major: dof `2 * node + c`, c = 0 for x, 1 for y.

pub mod assembly;
mod material;

pub use assembly::{
    assemble, assemble_in_frames, from_frame, to_frame, Assembled, AssemblyFigures, DofMap,
};
pub use material::{Hypothesis, Material, Materials};

use nalgebra::{Matrix3, SMatrix, Vector3};

/// Hooke's law in Voigt form (sxx, syy, sxy) = D (exx, eyy, 2 exy).
pub fn elasticity_matrix(m: &Material) -> Matrix3<f64> {
    let (e, nu) = (m.young, m.poisson);
    match m.hypothesis {
        Hypothesis::PlaneStrain => {
            let c = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
            Matrix3::new(
                c * (1.0 - nu),
                c * nu,
                0.0,
                c * nu,
                c * (1.0 - nu),
                0.0,
                0.0,
                0.0,
                c * (1.0 - 2.0 * nu) / 2.0,
            )
        }
        Hypothesis::PlaneStress => {
            let c = e / (1.0 - nu * nu);
            Matrix3::new(
                c,
                c * nu,
                0.0,
                c * nu,
                c,
                0.0,
                0.0,
                0.0,
                c * (1.0 - nu) / 2.0,
            )
        }
    }
}

/// Strain-displacement matrix B (3 x 6) of a linear triangle and its area.
/// The area is signed: positive for counter-clockwise vertices.
pub fn strain_displacement(p: &[[f64; 2]; 3]) -> (SMatrix<f64, 3, 6>, f64) {
    let [[x1, y1], [x2, y2], [x3, y3]] = *p;
    let area2 = (x2 - x1) * (y3 - y1) - (x3 - x1) * (y2 - y1);
    let b = [y2 - y3, y3 - y1, y1 - y2];
    let c = [x3 - x2, x1 - x3, x2 - x1];
    let mut bm = SMatrix::<f64, 3, 6>::zeros();
    for i in 0..3 {
        bm[(0, 2 * i)] = b[i] / area2;
        bm[(1, 2 * i + 1)] = c[i] / area2;
        bm[(2, 2 * i)] = c[i] / area2;
        bm[(2, 2 * i + 1)] = b[i] / area2;
    }
    (bm, area2 / 2.0)
}

/// Element stiffness matrix (6 x 6, dofs x1 y1 x2 y2 x3 y3), thickness 1.
pub fn element_stiffness(p: &[[f64; 2]; 3], d: &Matrix3<f64>) -> SMatrix<f64, 6, 6> {
    let (b, area) = strain_displacement(p);
    b.transpose() * d * b * area.abs()
}

/// Row `l` (local dof 2 a + c: node a of the triangle, component c) of
/// [`element_stiffness`], at a third of its cost: (B' D B)_l = (D B_l)' B.
pub fn element_stiffness_row(p: &[[f64; 2]; 3], d: &Matrix3<f64>, l: usize) -> [f64; 6] {
    let (b, area) = strain_displacement(p);
    let w = d * b.column(l) * area.abs();
    let row = w.transpose() * b;
    std::array::from_fn(|m| row[m])
}

/// In-plane stress (sxx, syy, sxy) of an element, constant over a P1 triangle.
pub fn element_stress(p: &[[f64; 2]; 3], d: &Matrix3<f64>, u: &[f64; 6]) -> [f64; 3] {
    let (b, _) = strain_displacement(p);
    let s: Vector3<f64> = d * (b * SMatrix::<f64, 6, 1>::from_column_slice(u));
    [s[0], s[1], s[2]]
}

/// Out-of-plane stress: nu (sxx + syy) in plane strain, zero in plane stress.
pub fn stress_zz(m: &Material, sxx: f64, syy: f64) -> f64 {
    match m.hypothesis {
        Hypothesis::PlaneStrain => m.poisson * (sxx + syy),
        Hypothesis::PlaneStress => 0.0,
    }
}

/// Von Mises equivalent stress of (sxx, syy, sxy, szz).
pub fn von_mises(s: &[f64; 4]) -> f64 {
    let [xx, yy, xy, zz] = *s;
    (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2)) + 3.0 * xy * xy).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steel() -> Material {
        Material {
            young: 210e3,
            poisson: 0.3,
            hypothesis: Hypothesis::PlaneStrain,
        }
    }

    const TRI: [[f64; 2]; 3] = [[0.1, 0.2], [1.3, 0.4], [0.5, 1.1]];

    #[test]
    fn stiffness_row_is_the_row_of_the_element_matrix() {
        let d = elasticity_matrix(&steel());
        let k = element_stiffness(&TRI, &d);
        // Clockwise too: the area enters by its absolute value in both.
        let cw = [TRI[0], TRI[2], TRI[1]];
        let k_cw = element_stiffness(&cw, &d);
        for l in 0..6 {
            let row = element_stiffness_row(&TRI, &d, l);
            let row_cw = element_stiffness_row(&cw, &d, l);
            for m in 0..6 {
                assert!((row[m] - k[(l, m)]).abs() <= 1e-12 * k.norm());
                assert!((row_cw[m] - k_cw[(l, m)]).abs() <= 1e-12 * k.norm());
            }
        }
    }

    #[test]
    fn stiffness_is_symmetric_with_rigid_modes_in_its_kernel() {
        let k = element_stiffness(&TRI, &elasticity_matrix(&steel()));
        assert!((k - k.transpose()).norm() < 1e-10 * k.norm());
        // Translations x, y and the infinitesimal rotation (-y, x) produce no force.
        let modes: [[f64; 6]; 3] = [
            [1.0, 0.0, 1.0, 0.0, 1.0, 0.0],
            [0.0, 1.0, 0.0, 1.0, 0.0, 1.0],
            [-0.2, 0.1, -0.4, 1.3, -1.1, 0.5],
        ];
        for m in modes {
            let f = k * SMatrix::<f64, 6, 1>::from_column_slice(&m);
            assert!(f.norm() < 1e-9 * k.norm(), "{f}");
        }
        // Positive on a deformation mode.
        let v = SMatrix::<f64, 6, 1>::from_column_slice(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        assert!((v.transpose() * k * v)[0] > 0.0);
    }

    #[test]
    fn constant_strain_is_reproduced_exactly() {
        // u = (a x + b y, c x + d y): exx = a, eyy = d, 2exy = b + c.
        let (a, b, c, dd) = (1e-3, 2e-4, -5e-4, 3e-4);
        let mut u = [0.0; 6];
        for (i, p) in TRI.iter().enumerate() {
            u[2 * i] = a * p[0] + b * p[1];
            u[2 * i + 1] = c * p[0] + dd * p[1];
        }
        let m = steel();
        let d = elasticity_matrix(&m);
        let s = element_stress(&TRI, &d, &u);
        let expect = d * Vector3::new(a, dd, b + c);
        for i in 0..3 {
            assert!((s[i] - expect[i]).abs() < 1e-9 * expect.norm());
        }
    }

    #[test]
    fn plane_stress_uniaxial_gives_young() {
        let m = Material {
            hypothesis: Hypothesis::PlaneStress,
            ..steel()
        };
        let d = elasticity_matrix(&m);
        // Uniaxial stress sxx = E exx when eyy = -nu exx.
        let s = d * Vector3::new(1.0, -m.poisson, 0.0);
        assert!((s[0] - m.young).abs() < 1e-9 * m.young);
        assert!(s[1].abs() < 1e-9 * m.young);
    }

    #[test]
    fn von_mises_of_pure_shear_and_uniaxial() {
        assert!((von_mises(&[0.0, 0.0, 1.0, 0.0]) - 3f64.sqrt()).abs() < 1e-14);
        assert!((von_mises(&[2.0, 0.0, 0.0, 0.0]) - 2.0).abs() < 1e-14);
    }
}
