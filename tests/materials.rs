//! One material per body (`[[material]]`, each on a physical surface group), through the
//! binary: the bimaterial patch test (P1 holds the piecewise-linear exact solution), the
//! same materials written as one `[material]` or as two equal `[[material]]` entries, and
//! a two-material body on the rigid foundation on 1 and 3 ranks.
//!
//! The mesh is `tests/data/gmsh/bimaterial_v41_ascii.msh` (made by `make_fixtures.py
//! bimaterial`): the square [0, 2] x [0, 2], the bodies "lower" (y < 1) and "upper"
//! (y > 1) sharing the nodes of y = 1.

mod common;

use common::{gmsh_dir, read_nodes, Run, COLUMNS};
use std::path::Path;

const MESH: &str = "bimaterial_v41_ascii.msh";

/// A case on the bimaterial mesh: `materials` (TOML), then `rest`.
fn case(materials: &str, rest: &str) -> String {
    format!("[mesh]\nfile = \"{MESH}\"\n{materials}\n{rest}")
}

/// Writes `toml` and the mesh into a fresh directory and runs it on `np` ranks (1: no
/// mpirun) with `extra` arguments plus `--out out --quiet --nodes-csv`.
fn run(toml: &str, np: usize, extra: &[&str]) -> Run {
    let dir = tempfile::TempDir::new().unwrap();
    std::fs::copy(gmsh_dir().join(MESH), dir.path().join(MESH)).unwrap();
    std::fs::write(dir.path().join("case.toml"), toml).unwrap();
    let mut args = vec!["case.toml", "--out", "out", "--quiet", "--nodes-csv"];
    args.extend_from_slice(extra);
    let result = common::run_on_ranks(dir.path(), np, &args);
    Run::kept(dir, result)
}

fn material(group: &str, young: f64, poisson: f64, hypothesis: &str) -> String {
    format!(
        "[[material]]\ngroup = \"{group}\"\nyoung = {young:?}\npoisson = {poisson:?}\nhypothesis = \"{hypothesis}\"\n"
    )
}

/// Uniaxial compression of the two stacked bodies: traction p on the top, the bottom on
/// the frictionless plane y = 0, ux = 0 on the left side.
const UNIAXIAL: &str = "[[dirichlet]]\ngroup = \"left\"\nux = 0.0\n[[traction]]\ngroup = \"top\"\nt = [0.0, -10.0]\n[contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, 0.0]\nobstacle_normal = [0.0, 1.0]\n";

/// Plane stress, sigma_yy = -p in both bodies, sigma_xx = sigma_xy = 0. With nu / E the
/// same in both (1e-4) the lateral strains agree, so the exact displacement is
/// ux = nu p x / E (one line for both) and uy piecewise linear in y with its kink at the
/// interface: P1 holds it exactly, up to round-off and the loop's tolerance.
#[test]
fn bimaterial_patch_test_is_exact() {
    let p = 10.0;
    let (e1, nu1, e2, nu2) = (1000.0, 0.1, 3000.0, 0.3);
    let exact = |x: f64, y: f64| {
        let uy = if y <= 1.0 {
            -p * y / e1
        } else {
            -p / e1 - p * (y - 1.0) / e2
        };
        [nu1 * p / e1 * x, uy]
    };
    let materials =
        material("lower", e1, nu1, "plane_stress") + &material("upper", e2, nu2, "plane_stress");
    let r = run(&case(&materials, UNIAXIAL), 1, &["--tol", "1e-13"]);
    r.expect_code(0);
    let nodes = read_nodes(&r.out.join("nodes.csv"));
    assert!(nodes.len() > 50);
    let scale = p * 1.0 / e1 + p * 1.0 / e2;
    let worst = (nodes.iter())
        .map(|&[x, y, ux, uy]| {
            let e = exact(x, y);
            (ux - e[0]).abs().max((uy - e[1]).abs())
        })
        .fold(0.0, f64::max);
    println!(
        "bimaterial patch test: max |u - u_exact| / |u|max = {:e}",
        worst / scale
    );
    assert!(
        worst <= 1e-11 * scale,
        "off the exact solution by {worst:e}"
    );
    // The interface is where the slope changes: the soft lower body shortens three times
    // as much per unit height as the upper one.
    let top = nodes.iter().find(|n| n[1] == 2.0).unwrap();
    assert!((top[3] - (-p / e1 - p / e2)).abs() <= 1e-11 * scale);
    // summary.json lists the bodies in the case's order; only the lower one touches
    // the contact nodes (the scale of r is its E_eff).
    let bodies = r.summary()["bodies"].clone();
    assert_eq!(
        bodies,
        serde_json::json!([
            {"group": "lower", "young": e1, "poisson": nu1, "at_contact": true},
            {"group": "upper", "young": e2, "poisson": nu2, "at_contact": false}
        ])
    );
    // Every bottom node presses with p.
    for row in r.contact() {
        assert!((row.p_n - p).abs() <= 1e-9 * p, "{row:?}");
    }
}

/// Equal values in two entries are one material: the same contact.csv, byte for byte.
#[test]
fn two_equal_materials_are_one_material() {
    let friction = "[[dirichlet]]\ngroup = \"top\"\nux = 0.004\nuy = -0.02\n[contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, 0.0]\nobstacle_normal = [0.0, 1.0]\nfriction = \"coulomb\"\ncoefficient = 0.3\n";
    let one = run(
        &case("[material]\nyoung = 1000.0\npoisson = 0.3\n", friction),
        1,
        &[],
    );
    let two_entries = material("lower", 1000.0, 0.3, "plane_strain")
        + &material("upper", 1000.0, 0.3, "plane_strain");
    let two = run(&case(&two_entries, friction), 1, &[]);
    one.expect_code(0);
    two.expect_code(0);
    let read = |r: &Run| std::fs::read(r.out.join("contact.csv")).unwrap();
    assert_eq!(read(&one), read(&two));
    assert_eq!(
        std::fs::read(one.out.join("nodes.csv")).unwrap(),
        std::fs::read(two.out.join("nodes.csv")).unwrap()
    );
    // Some nodes slip and some stick: the comparison is not of a trivial answer.
    let rows = one.contact();
    assert!(rows.iter().any(|r| r.p_t.abs() > 0.0));
}

/// A soft body on a stiff one, sheared and pressed onto the foundation with Coulomb
/// friction: 1 and 3 ranks agree to round-off, and the answer is not the one-material
/// answer (the materials reach the elements of every subdomain).
#[test]
fn two_materials_agree_on_one_and_three_ranks() {
    let materials = material("lower", 5000.0, 0.25, "plane_strain")
        + &material("upper", 200.0, 0.45, "plane_strain");
    let rest = "[[dirichlet]]\ngroup = \"top\"\nux = 0.01\nuy = -0.03\n[contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, 0.0]\nobstacle_normal = [0.0, 1.0]\nfriction = \"coulomb\"\ncoefficient = 0.3\n";
    let toml = case(&materials, rest);
    let r1 = run(&toml, 1, &["--tol", "1e-12"]);
    let r3 = run(&toml, 3, &["--tol", "1e-12"]);
    r1.expect_code(0);
    r3.expect_code(0);
    let (a, b) = (r1.contact(), r3.contact());
    let d = common::column_diffs(&a, &b);
    println!("1 vs 3 ranks: relative column differences {d:?} ({COLUMNS:?})");
    // u_n is the gap, 0, at every node in contact: its own largest value is round-off,
    // so it is compared with the prescribed motion instead.
    for c in [0, 1, 3, 4, 5, 6] {
        assert!(d[c] <= 1e-8, "{} differs by {:e}", COLUMNS[c], d[c]);
    }
    for (p, q) in a.iter().zip(&b) {
        assert!((p.u_n - q.u_n).abs() <= 1e-10 * 0.03, "{p:?} {q:?}");
    }
    let n1 = read_nodes(&r1.out.join("nodes.csv"));
    let n3 = read_nodes(&r3.out.join("nodes.csv"));
    assert_eq!(n1.len(), n3.len());
    let umax = n1.iter().map(|n| n[3].abs()).fold(0.0, f64::max);
    for (p, q) in n1.iter().zip(&n3) {
        assert_eq!([p[0], p[1]], [q[0], q[1]]);
        assert!((p[2] - q[2]).abs() <= 1e-8 * umax && (p[3] - q[3]).abs() <= 1e-8 * umax);
    }
    // The soft upper body takes most of the shortening: the interface moves far less
    // than the half of the top's 0.03 it would in one material (0.004 here).
    let interface: Vec<f64> = (n1.iter()).filter(|n| n[1] == 1.0).map(|n| n[3]).collect();
    assert!(interface.len() > 4);
    let deepest = interface.iter().map(|v| v.abs()).fold(0.0, f64::max);
    println!("interface: largest |uy| {deepest:e}");
    assert!(deepest < 0.25 * 0.03, "interface uy down to {deepest:e}");
    let one = run(
        &case("[material]\nyoung = 5000.0\npoisson = 0.25\n", rest),
        1,
        &["--tol", "1e-12"],
    );
    one.expect_code(0);
    let d = common::column_diffs(&a, &one.contact());
    assert!(
        d[4] > 1e-3,
        "p_n the same as with one material: {d:?} ({COLUMNS:?})"
    );
    assert!(Path::new(&r3.out.join("solution.pvtu")).exists());
}
