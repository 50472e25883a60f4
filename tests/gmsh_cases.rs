//! Case files on real Gmsh meshes (the committed fixtures in tests/data/gmsh).

mod common;
use common::*;

/// The unstructured Gmsh quarter disc (radius 1, centre (0, 1), groups contact, axis,
/// top) pressed on y = 0 through its top, symmetry on the axis.
fn quarter_disc_case(friction: &str) -> String {
    let mesh = gmsh_dir().join("quarter_disc_v41_ascii.msh");
    format!(
        r#"title = "Gmsh quarter disc"
[mesh]
file = "{}"
[material]
young = 1000.0
poisson = 0.3
[[dirichlet]]
group = "axis"
ux = 0.0
[[dirichlet]]
group = "top"
uy = -0.01
[contact]
group = "contact"
obstacle_point = [0.0, 0.0]
obstacle_normal = [0.0, 1.0]
{friction}
[solver]
tol = 1e-10
"#,
        mesh.display()
    )
}

#[test]
fn gmsh_quarter_disc_frictionless_is_hertzian() {
    let run = run_case(&quarter_disc_case("friction = \"none\""), &[]);
    run.expect_code(0);
    let rows = run.contact();
    let s = run.summary();
    // KKT at the tolerance of contact_physics.rs (tol 1e-10, see KKT_REL there).
    check_kkt(&rows, Law::None, 1e-8, "Gmsh quarter disc, frictionless");
    let force = num(&s, "total_normal_force");
    assert!(force > 0.0, "total normal force {force}");
    // Hertz, loosely: the fixture is coarse (element 0.03 at the contact, a ~ 0.08 so
    // only 3 active nodes), so the peak is checked to 10% and the half-width to lie
    // between the last active node and the next one, widened by 10%.
    let p = 2.0 * force;
    let e_star = 1000.0 / (1.0 - 0.09);
    let a = (4.0 * p / (std::f64::consts::PI * e_star)).sqrt();
    let p0 = 2.0 * p / (std::f64::consts::PI * a);
    let last = rows.iter().rposition(|r| r.p_n > 0.0).unwrap();
    let pmax = rows.iter().map(|r| r.p_n).fold(0.0, f64::max);
    println!(
        "Gmsh quarter disc: P = {p}, a = {a}, active up to x = {} (next {}), p0 = {p0}, max p_n = {pmax} ({:+.3e})",
        rows[last].x,
        rows[last + 1].x,
        (pmax - p0) / p0
    );
    assert!(last >= 2, "only {} active nodes", last + 1);
    assert!(rows[last].x <= 1.1 * a && rows[last + 1].x >= 0.9 * a);
    assert!((pmax - p0).abs() <= 0.1 * p0);
}

#[test]
fn gmsh_quarter_disc_coulomb_kkt() {
    let run = run_case(
        &quarter_disc_case("friction = \"coulomb\"\ncoefficient = 0.2"),
        &[],
    );
    run.expect_code(0);
    let rows = run.contact();
    check_kkt(
        &rows,
        Law::Coulomb(0.2),
        1e-8,
        "Gmsh quarter disc, Coulomb 0.2",
    );
    assert!(num(&run.summary(), "total_normal_force") > 0.0);
    // On the curved boundary the contact nodes approach the foundation as it deforms
    // and rub along it: friction acts (some p_t non-zero).
    assert!(max_abs(&rows, 5) > 0.0, "no tangential traction at all");
}

/// The 2 x 1 rectangle of the Gmsh fixtures, sheared and pressed on y = -0.001.
fn rect_case(file: &str) -> String {
    format!(
        r#"[mesh]
file = "{}"
[material]
young = 1000.0
poisson = 0.3
[[dirichlet]]
group = "top"
ux = 0.002
uy = -0.01
[contact]
group = "bottom"
obstacle_point = [0.0, -0.001]
obstacle_normal = [0.0, 1.0]
friction = "coulomb"
coefficient = 0.3
[solver]
tol = 1e-10
"#,
        gmsh_dir().join(file).display()
    )
}

fn contact_text(file: &str) -> (String, Vec<Row>, serde_json::Value) {
    let run = run_case(&rect_case(file), &[]);
    run.expect_code(0);
    let text = std::fs::read_to_string(run.out.join("contact.csv")).unwrap();
    (text, run.contact(), run.summary())
}

#[test]
fn gmsh_formats_give_identical_results() {
    let (a41, rows, s) = contact_text("rect_v41_ascii.msh");
    let (a22, ..) = contact_text("rect_v22_ascii.msh");
    let (b22, rows_b, sb) = contact_text("rect_v22_binary.msh");
    let (b41, ..) = contact_text("rect_v41_binary.msh");
    assert!(rows.len() > 5 && rows.iter().all(|r| r.p_n > 0.0), "{a41}");
    assert!(
        num(&s, "stick_nodes") > 0.0 && num(&s, "slip_nodes") > 0.0,
        "{s}"
    );
    // Same mesh, same storage of the coordinates: the computation and the file are
    // identical byte for byte.
    assert!(
        a41 == a22,
        "MSH 4.1 and 2.2 ASCII files give different contact.csv"
    );
    assert!(
        b41 == b22,
        "MSH 4.1 and 2.2 binary files give different contact.csv"
    );
    // ASCII vs binary: Gmsh prints ASCII coordinates with 16 significant digits
    // (0.2499999999995475) but stores the exact double in binary files
    // (0.24999999999954753), so the inputs differ in the last bit and the results by
    // round-off only: coordinates to 1e-14, every column to 1e-12 of its max (measured
    // 4e-15).
    assert_eq!(rows.len(), rows_b.len());
    for (a, b) in rows.iter().zip(&rows_b) {
        assert!(
            (a.x - b.x).abs() <= 1e-14 * 2.0 && a.y == b.y,
            "{a:?} vs {b:?}"
        );
    }
    assert_same_columns(&rows, &rows_b, 1e-12, "rect v4.1 ASCII vs v2.2 binary");
    assert_eq!(s["iterations"], sb["iterations"]);
    assert_eq!(s["stick_nodes"], sb["stick_nodes"]);
}
