//! Accuracy of the P1 elasticity discretisation, at library level (no contact):
//!
//! 1. the patch test: on distorted and unstructured meshes a linear displacement
//!    prescribed on the boundary is reproduced inside to round-off, and every element
//!    stress equals D * strain with D from the Lame constants (computed here, not by the
//!    crate), in plane strain and plane stress;
//! 2. a manufactured solution on the unit square with measured convergence rates in the
//!    L2 norm (about 2) and the energy norm / H1 seminorm (about 1).

use contact_par::fem::{
    assemble, elasticity_matrix, element_stress, DofMap, Hypothesis, Material, Materials,
};
use contact_par::linear::SparseCholesky;
use contact_par::mesh::{builtin, gmsh, Mesh};
use faer::sparse::linalg::cholesky::SymmetricOrdering;
use faer::Mat;
use std::collections::HashMap;
use std::f64::consts::PI;

/// Nodes on the boundary (on an edge of exactly one triangle), plus nodes that no
/// triangle uses (they must be fixed too, or the matrix is singular).
fn boundary_nodes(mesh: &Mesh) -> Vec<bool> {
    let mut count: HashMap<(usize, usize), u32> = HashMap::new();
    for t in &mesh.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut on = vec![false; mesh.num_nodes()];
    for ((a, b), c) in count {
        if c == 1 {
            on[a] = true;
            on[b] = true;
        }
    }
    let mut used = vec![false; mesh.num_nodes()];
    for t in &mesh.triangles {
        for &n in t {
            used[n] = true;
        }
    }
    on.iter().zip(&used).map(|(&b, &u)| b || !u).collect()
}

/// Solves K u = F on the free dofs with `fixed` prescribed; returns the full u.
fn solve(mesh: &Mesh, mat: &Material, fixed: &[Option<f64>], load: &[f64]) -> Vec<f64> {
    let dofs = DofMap::new(fixed);
    let a = assemble(
        &mesh.nodes,
        &mesh.triangles,
        Materials::One(mat),
        &dofs,
        &[],
    )
    .unwrap();
    let mut rhs = Mat::<f64>::zeros(dofs.n_free, 1);
    for (i, v) in a.lifting.iter().enumerate() {
        rhs[(i, 0)] = *v;
    }
    for (dof, eq) in dofs.eq.iter().enumerate() {
        if let Some(i) = eq {
            rhs[(*i, 0)] += load[dof];
        }
    }
    let mut chol = SparseCholesky::factor(a.matrix.as_ref(), SymmetricOrdering::Amd).unwrap();
    chol.solve_in_place(rhs.as_mut());
    let free: Vec<f64> = (0..dofs.n_free).map(|i| rhs[(i, 0)]).collect();
    dofs.expand(&free)
}

/// Hooke's law from the Lame constants, independent of `fem::elasticity_matrix`:
/// (sxx, syy, sxy) for the strain (exx, eyy, 2 exy).
fn hooke(m: &Material, e: [f64; 3]) -> [f64; 3] {
    let (young, nu) = (m.young, m.poisson);
    let mu = young / (2.0 * (1.0 + nu));
    let lambda3d = young * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    // Plane stress: szz = 0 eliminates ezz, lambda* = 2 lambda mu / (lambda + 2 mu).
    let lambda = match m.hypothesis {
        Hypothesis::PlaneStrain => lambda3d,
        Hypothesis::PlaneStress => 2.0 * lambda3d * mu / (lambda3d + 2.0 * mu),
    };
    let tr = e[0] + e[1];
    [
        lambda * tr + 2.0 * mu * e[0],
        lambda * tr + 2.0 * mu * e[1],
        mu * e[2],
    ]
}

/// Deterministic pseudo-random numbers in [-1, 1] (a 64-bit LCG), so the test is
/// reproducible without a dependency.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// The 4 x 3 block (8 x 6 cells) with every interior node moved by up to 0.2 of a cell
/// in each direction: no two elements alike.
fn distorted_block() -> Mesh {
    let (w, h, nx, ny) = (4.0, 3.0, 8, 6);
    let mut mesh = builtin::block(w, h, nx, ny);
    let on = boundary_nodes(&mesh);
    let mut rng = Lcg(12345);
    let (hx, hy) = (w / nx as f64, h / ny as f64);
    for (p, &b) in mesh.nodes.iter_mut().zip(&on) {
        if !b {
            p[0] += 0.2 * hx * rng.next();
            p[1] += 0.2 * hy * rng.next();
        }
    }
    // Distortion stays below the size that could fold an element: every triangle keeps
    // its counter-clockwise orientation.
    for t in 0..mesh.triangles.len() {
        assert!(
            mesh.signed_area2(t) > 0.0,
            "distorted block: triangle {t} folded"
        );
    }
    mesh
}

fn patch_meshes() -> Vec<(&'static str, Mesh)> {
    let gmsh_file = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gmsh/quarter_disc_v41_ascii.msh");
    vec![
        ("distorted block", distorted_block()),
        (
            "built-in quarter disc (n 8, grading 4)",
            builtin::quarter_disc(1.0, 8, 4.0),
        ),
        ("Gmsh quarter disc", gmsh::read_msh(&gmsh_file).unwrap()),
    ]
}

#[test]
fn patch_test_linear_field_is_exact_on_distorted_and_unstructured_meshes() {
    // u = c + G x with every gradient entry non-zero: stretch, shear and rotation.
    let (c, g) = ([1e-3, -5e-4], [[2e-3, -1e-3], [7e-4, 1.5e-3]]);
    let exact = |p: [f64; 2]| {
        [
            c[0] + g[0][0] * p[0] + g[0][1] * p[1],
            c[1] + g[1][0] * p[0] + g[1][1] * p[1],
        ]
    };
    let strain = [g[0][0], g[1][1], g[0][1] + g[1][0]];
    for (name, mesh) in patch_meshes() {
        let on = boundary_nodes(&mesh);
        let interior = on.iter().filter(|b| !**b).count();
        assert!(interior >= 20, "{name}: only {interior} interior nodes");
        let mut fixed = vec![None; 2 * mesh.num_nodes()];
        for (i, p) in mesh.nodes.iter().enumerate() {
            if on[i] {
                let u = exact(*p);
                fixed[2 * i] = Some(u[0]);
                fixed[2 * i + 1] = Some(u[1]);
            }
        }
        let umax = mesh
            .nodes
            .iter()
            .map(|p| exact(*p)[0].abs().max(exact(*p)[1].abs()))
            .fold(0.0, f64::max);
        for hyp in [Hypothesis::PlaneStrain, Hypothesis::PlaneStress] {
            let mat = Material {
                young: 210e3,
                poisson: 0.3,
                hypothesis: hyp,
            };
            let u = solve(&mesh, &mat, &fixed, &vec![0.0; 2 * mesh.num_nodes()]);
            // The exact solution is in the P1 space, so the only error is round-off:
            // about eps * cond(K) ~ 1e-16 * (L / h_min)^2 <= 1e-12 on these meshes.
            let mut err = 0.0f64;
            for (i, p) in mesh.nodes.iter().enumerate() {
                let e = exact(*p);
                err = err.max((u[2 * i] - e[0]).abs().max((u[2 * i + 1] - e[1]).abs()));
            }
            let rel = err / umax;
            println!(
                "{name}, {hyp:?}: {interior} interior nodes, max nodal error / max |u| = {rel:e}"
            );
            assert!(rel <= 1e-10, "{name}, {hyp:?}: interior error {rel:e}");

            // Element stresses: constant, equal to D strain (D from Lame, not the crate).
            let want = hooke(&mat, strain);
            let scale = want.iter().map(|s| s.abs()).fold(0.0, f64::max);
            let d = elasticity_matrix(&mat);
            let mut serr = 0.0f64;
            for t in &mesh.triangles {
                let p = [mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]]];
                let ue = [
                    u[2 * t[0]],
                    u[2 * t[0] + 1],
                    u[2 * t[1]],
                    u[2 * t[1] + 1],
                    u[2 * t[2]],
                    u[2 * t[2] + 1],
                ];
                let s = element_stress(&p, &d, &ue);
                for k in 0..3 {
                    serr = serr.max((s[k] - want[k]).abs());
                }
            }
            // Round-off in the nodal values divided by h_min, as above.
            println!(
                "{name}, {hyp:?}: max element stress error / |sigma| = {:e}",
                serr / scale
            );
            assert!(
                serr <= 1e-9 * scale,
                "{name}, {hyp:?}: element stress off by {:e} relative",
                serr / scale
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// Manufactured solution on the unit square, plane strain, E = 1, nu = 0.3:
//   u1 = sin(pi x) cos(pi y),  u2 = e^x y^2
// (non-zero on the boundary, so the Dirichlet lifting is exercised too), body force
// f = -div sigma(u) = -[(lambda + mu) grad div u + mu laplace u].

const E: f64 = 1.0;
const NU: f64 = 0.3;

fn lame() -> (f64, f64) {
    (
        E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU)),
        E / (2.0 * (1.0 + NU)),
    )
}

fn u_exact(x: f64, y: f64) -> [f64; 2] {
    [(PI * x).sin() * (PI * y).cos(), x.exp() * y * y]
}

/// [[du1/dx, du1/dy], [du2/dx, du2/dy]].
fn grad_exact(x: f64, y: f64) -> [[f64; 2]; 2] {
    let (sx, cx, sy, cy) = (
        (PI * x).sin(),
        (PI * x).cos(),
        (PI * y).sin(),
        (PI * y).cos(),
    );
    [
        [PI * cx * cy, -PI * sx * sy],
        [x.exp() * y * y, 2.0 * x.exp() * y],
    ]
}

fn body_force(x: f64, y: f64) -> [f64; 2] {
    let (lambda, mu) = lame();
    let (sx, cx, sy, cy) = (
        (PI * x).sin(),
        (PI * x).cos(),
        (PI * y).sin(),
        (PI * y).cos(),
    );
    let ex = x.exp();
    let u1_xx = -PI * PI * sx * cy;
    let u1_yy = -PI * PI * sx * cy;
    let u1_xy = -PI * PI * cx * sy;
    let u2_xx = ex * y * y;
    let u2_yy = 2.0 * ex;
    let u2_xy = 2.0 * ex * y;
    [
        -((lambda + mu) * (u1_xx + u2_xy) + mu * (u1_xx + u1_yy)),
        -((lambda + mu) * (u1_xy + u2_yy) + mu * (u2_xx + u2_yy)),
    ]
}

/// Dunavant's 7-point rule, exact for degree 5: (barycentric coordinates, weight / area).
fn quadrature() -> Vec<([f64; 3], f64)> {
    let (a1, b1, w1) = (0.059715871789770, 0.470142064105115, 0.132394152788506);
    let (a2, b2, w2) = (0.797426985353087, 0.101286507323456, 0.125939180544827);
    vec![
        ([1.0 / 3.0; 3], 0.225),
        ([a1, b1, b1], w1),
        ([b1, a1, b1], w1),
        ([b1, b1, a1], w1),
        ([a2, b2, b2], w2),
        ([b2, a2, b2], w2),
        ([b2, b2, a2], w2),
    ]
}

struct Errors {
    l2: f64,
    h1: f64,
    energy: f64,
}

fn mms_errors(n: usize) -> Errors {
    let mesh = builtin::block(1.0, 1.0, n, n);
    let mat = Material {
        young: E,
        poisson: NU,
        hypothesis: Hypothesis::PlaneStrain,
    };
    let quad = quadrature();
    let area = |p: &[[f64; 2]; 3]| {
        0.5 * ((p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
            - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]))
            .abs()
    };
    let at = |p: &[[f64; 2]; 3], l: [f64; 3]| {
        [
            l[0] * p[0][0] + l[1] * p[1][0] + l[2] * p[2][0],
            l[0] * p[0][1] + l[1] * p[1][1] + l[2] * p[2][1],
        ]
    };
    // Load vector: F_i = integral of f phi_i, phi_i = barycentric coordinate i.
    let mut load = vec![0.0; 2 * mesh.num_nodes()];
    for t in &mesh.triangles {
        let p = [mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]]];
        let a = area(&p);
        for (l, w) in &quad {
            let [x, y] = at(&p, *l);
            let f = body_force(x, y);
            for k in 0..3 {
                load[2 * t[k]] += w * a * f[0] * l[k];
                load[2 * t[k] + 1] += w * a * f[1] * l[k];
            }
        }
    }
    let on = boundary_nodes(&mesh);
    let mut fixed = vec![None; 2 * mesh.num_nodes()];
    for (i, p) in mesh.nodes.iter().enumerate() {
        if on[i] {
            let u = u_exact(p[0], p[1]);
            fixed[2 * i] = Some(u[0]);
            fixed[2 * i + 1] = Some(u[1]);
        }
    }
    let u = solve(&mesh, &mat, &fixed, &load);

    let (mut l2, mut h1, mut en) = (0.0, 0.0, 0.0);
    for t in &mesh.triangles {
        let p = [mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]]];
        let a2 =
            (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
        // Gradients of the barycentric coordinates (any orientation).
        let dl = [
            [(p[1][1] - p[2][1]) / a2, (p[2][0] - p[1][0]) / a2],
            [(p[2][1] - p[0][1]) / a2, (p[0][0] - p[2][0]) / a2],
            [(p[0][1] - p[1][1]) / a2, (p[1][0] - p[0][0]) / a2],
        ];
        let mut gh = [[0.0; 2]; 2];
        for k in 0..3 {
            for c in 0..2 {
                for d in 0..2 {
                    gh[c][d] += u[2 * t[k] + c] * dl[k][d];
                }
            }
        }
        let a = a2.abs() / 2.0;
        for (l, w) in &quad {
            let [x, y] = at(&p, *l);
            let ue = u_exact(x, y);
            let mut uh = [0.0; 2];
            for k in 0..3 {
                uh[0] += l[k] * u[2 * t[k]];
                uh[1] += l[k] * u[2 * t[k] + 1];
            }
            l2 += w * a * ((ue[0] - uh[0]).powi(2) + (ue[1] - uh[1]).powi(2));
            let g = grad_exact(x, y);
            let mut dg = [[0.0; 2]; 2];
            for c in 0..2 {
                for d in 0..2 {
                    dg[c][d] = g[c][d] - gh[c][d];
                    h1 += w * a * dg[c][d].powi(2);
                }
            }
            let e = [dg[0][0], dg[1][1], dg[0][1] + dg[1][0]];
            let s = hooke(&mat, e);
            en += w * a * (s[0] * e[0] + s[1] * e[1] + s[2] * e[2]);
        }
    }
    Errors {
        l2: l2.sqrt(),
        h1: h1.sqrt(),
        energy: en.sqrt(),
    }
}

#[test]
fn manufactured_solution_converges_at_the_p1_rates() {
    let levels = [8, 16, 32, 64];
    let errs: Vec<Errors> = levels.iter().map(|&n| mms_errors(n)).collect();
    println!(
        "{:>4} {:>12} {:>6} {:>12} {:>6} {:>12} {:>6}",
        "n", "L2", "rate", "H1 semi", "rate", "energy", "rate"
    );
    let rate = |a: f64, b: f64| (a / b).log2();
    let mut rates = Vec::new();
    for (k, (n, e)) in levels.iter().zip(&errs).enumerate() {
        let r = (k > 0).then(|| {
            let p = &errs[k - 1];
            [rate(p.l2, e.l2), rate(p.h1, e.h1), rate(p.energy, e.energy)]
        });
        let f = |i: usize| r.map_or(String::from("-"), |r| format!("{:.3}", r[i]));
        println!(
            "{n:>4} {:>12.4e} {:>6} {:>12.4e} {:>6} {:>12.4e} {:>6}",
            e.l2,
            f(0),
            e.h1,
            f(1),
            e.energy,
            f(2)
        );
        if let Some(r) = r {
            rates.push(r);
        }
    }
    // P1 elements: O(h^2) in L2 and O(h) in energy for a smooth solution. Asymptotic
    // rates are 2 and 1; the thresholds leave 5% for pre-asymptotic effects.
    let last = rates.last().unwrap();
    assert!(last[0] >= 1.9, "L2 rate {} < 1.9", last[0]);
    assert!(last[1] >= 0.95, "H1 seminorm rate {} < 0.95", last[1]);
    assert!(last[2] >= 0.95, "energy rate {} < 0.95", last[2]);
    // And the error really is small (not a converging wrong answer): on the finest mesh
    // the L2 error is below 1e-3 of |u| ~ 0.5 (the interpolation error is ~h^2/8 |u''|).
    assert!(errs[3].l2 < 1e-3, "L2 error {:e}", errs[3].l2);
}
