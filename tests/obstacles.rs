//! Rigid obstacles of any shape (`[[contact]]` with `obstacle = { type = ... }`): Hertz
//! line contact of the elastic quarter cylinder against a rigid circle from outside
//! (convex-convex) and from inside (a pin in a hole), the discrete contact conditions at
//! every node against its own gap, the old `[contact]` table against the same line in the
//! new syntax and against a polyline of one segment, a block between two obstacles, and
//! agreement of 1 and 3 ranks.

mod common;

use common::*;
use std::f64::consts::PI;

/// The built-in hertz case at `level` with its `[contact]` table replaced by `contact`
/// (the table is the last of the built-in case).
fn hertz_with(level: u32, contact: &str) -> String {
    let text = contact_par::case::builtin_case_text("hertz", level).expect("hertz");
    let head = text.split("[contact]").next().unwrap().to_string();
    head + contact
}

/// The convex cylinder (R1 = 50, centre (0, 50)) on a rigid roller of radius 50 under it.
const ON_ROLLER: &str = r#"[[contact]]
slave = "contact"
obstacle = { type = "circle", centre = [0.0, -50.0], radius = 50.0, body = "outside" }
"#;
/// The cylinder in a rigid hole of radius 100 touching it at the origin.
const IN_HOLE: &str = r#"[[contact]]
slave = "contact"
obstacle = { type = "circle", centre = [0.0, 100.0], radius = 100.0, body = "inside" }
"#;

/// Hertz's half-width and peak pressure for the run's total force (quarter model: the
/// whole cylinder carries twice), E* of the elastic body only, 1/R = 1/R1 + 1/R2 (R2 < 0
/// for a hole).
fn hertz(run: &Run, r2: f64) -> (f64, f64) {
    let p = 2.0 * num(&run.summary(), "total_normal_force");
    let e_star = 210000.0 / (1.0 - 0.3 * 0.3);
    let radius = 1.0 / (1.0 / 50.0 + 1.0 / r2);
    let a = (4.0 * p * radius / (PI * e_star)).sqrt();
    (a, 2.0 * p / (PI * a))
}

/// (half-width error, peak error, worst profile error over x < 0.8 a, all relative) of
/// one Hertz run, after its bracketing and KKT checks.
fn hertz_errors(level: u32, contact: &str, r2: f64) -> (f64, f64, f64) {
    let run = run_case(&hertz_with(level, contact), &[]);
    run.expect_code(0);
    let rows = run.contact();
    let what = format!("level {level}, R2 = {r2}");
    check_kkt(&rows, Law::None, 1e-7, &what);
    let (a, p0) = hertz(&run, r2);
    hertz_errors_of(&rows, a, p0, &what)
}

/// Half-width and peak within 3% at every level, the profile's error shrinking level by
/// level (the half-width and peak errors are bounded by the node spacing and by Hertz's
/// a << R, so they need not fall monotonically).
fn hertz_study(contact: &str, r2: f64) {
    let mut previous = f64::INFINITY;
    for level in 1..=3 {
        let (e_a, e_p, profile) = hertz_errors(level, contact, r2);
        assert!(
            e_a.abs() <= 0.03,
            "level {level}: half-width off by {e_a:e}"
        );
        assert!(e_p.abs() <= 0.03, "level {level}: peak off by {e_p:e}");
        assert!(
            profile < previous,
            "level {level}: profile error {profile:e} did not shrink from {previous:e}"
        );
        previous = profile;
    }
    assert!(previous <= 0.015, "finest profile error {previous:e}");
}

#[test]
fn hertz_cylinder_on_a_rigid_roller() {
    hertz_study(ON_ROLLER, 50.0);
}

#[test]
fn hertz_cylinder_in_a_rigid_hole() {
    hertz_study(IN_HOLE, -100.0);
}

#[test]
fn the_old_table_and_the_new_line_give_the_same_numbers() {
    let old = std::fs::read(
        run_builtin("hertz", 1, &[])
            .expect_code(0)
            .out
            .join("contact.csv"),
    );
    let line = r#"[[contact]]
slave = "contact"
obstacle = { type = "line", point = [0.0, 0.0], normal = [0.0, 1.0] }
friction = "none"
"#;
    let new = run_case(&hertz_with(1, line), &[]);
    new.expect_code(0);
    assert_eq!(
        old.unwrap(),
        std::fs::read(new.out.join("contact.csv")).unwrap(),
        "contact.csv differs"
    );
    // Coulomb on a tilted foundation, as a polyline of one segment.
    let t: f64 = 1e-3;
    let m = [t.sin(), t.cos()];
    let old = run_case(
        &block_case(
            1,
            "ux = 0.01\nuy = -0.02",
            "friction = \"coulomb\"\ncoefficient = 0.3",
            m,
            "",
        ),
        &[],
    );
    old.expect_code(0);
    let p0 = [0.0, -0.001];
    let along = |l: f64| [p0[0] + l * m[1], p0[1] - l * m[0]];
    let (a, b) = (along(-5.0), along(60.0));
    let poly = block_case(1, "ux = 0.01\nuy = -0.02", "", m, "").replace(
        &format!(
            "[contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, -0.001]\nobstacle_normal = [{:?}, {:?}]\n",
            m[0], m[1]
        ),
        &format!(
            "[[contact]]\nslave = \"bottom\"\nobstacle = {{ type = \"polyline\", points = [[{:?}, {:?}], [{:?}, {:?}]] }}\nfriction = \"coulomb\"\ncoefficient = 0.3\n",
            a[0], a[1], b[0], b[1]
        ),
    );
    assert!(poly.contains("polyline"), "{poly}");
    let new = run_case(&poly, &[]);
    new.expect_code(0);
    let counts = check_kkt(&new.contact(), Law::Coulomb(0.3), 1e-7, "polyline");
    assert!(
        counts.stick > 0 && counts.slip > 0 && counts.free > 0,
        "{counts:?}"
    );
    assert_same_columns(
        &old.contact(),
        &new.contact(),
        1e-8,
        "line vs one-segment polyline",
    );
}

/// The block pushed right and down by its top, frictionless on a floor and against a
/// wall at its right: the obstacles carry the load, each its own share.
#[test]
fn a_block_between_a_floor_and_a_wall() {
    let case = r#"title = "block between a floor and a wall"
[mesh]
builtin = "block"
level = 1
[material]
young = 70000.0
poisson = 0.3
[[traction]]
group = "top"
t = [20.0, -50.0]
[[contact]]
slave = "bottom"
obstacle = { type = "polyline", points = [[-10.0, -0.001], [50.0, -0.001]] }
[[contact]]
slave = "right"
obstacle = { type = "line", point = [40.002, 0.0], normal = [-1.0, 0.0] }
[solver]
tol = 1e-10
"#;
    let run = run_case(case, &[]);
    run.expect_code(0);
    check_kkt(&run.contact(), Law::None, 1e-7, "floor and wall");
    // contact.csv names each row's contact: the wall's are the right side's nodes above
    // the corner, which is the floor's (both as near, the first contact wins).
    for r in run.contact() {
        let on_wall = r.x == 40.0 && r.y > 0.0;
        assert_eq!(r.contact, u32::from(on_wall), "row at ({}, {})", r.x, r.y);
    }
    let s = run.summary();
    let pairs = s["contacts"].as_array().expect("contacts");
    assert_eq!(pairs.len(), 2);
    let force = |i: usize| -> [f64; 2] {
        let f = pairs[i]["force"].as_array().unwrap();
        [f[0].as_f64().unwrap(), f[1].as_f64().unwrap()]
    };
    println!("floor {:?}, wall {:?}", force(0), force(1));
    assert_eq!(pairs[0]["slave"], "bottom");
    assert_eq!(pairs[1]["obstacle"], "line");
    // Equilibrium: the top's traction over its 40 mm.
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * b.abs();
    assert!(close(force(0)[1], 2000.0) && force(0)[0].abs() < 1e-9);
    assert!(close(force(1)[0], -800.0) && force(1)[1].abs() < 1e-9);
    assert!(close(num(&s, "total_normal_force"), 2800.0));
}

/// Frictionless (each node's dofs turned into its frame, one dof per contact node in the
/// condensed system) and Coulomb (both dofs, in x, y): the same answer on 1 and 3 ranks,
/// and without friction the same as the uncondensed solve in x, y (`--linear full`).
#[test]
fn a_roller_gives_the_same_answer_on_1_and_3_ranks() {
    for friction in [
        "friction = \"none\"",
        "friction = \"coulomb\"\ncoefficient = 0.2",
    ] {
        let case = hertz_with(1, ON_ROLLER) + friction + "\n[solver]\ntol = 1e-10\n";
        let dir = tempfile::TempDir::new().unwrap();
        std::fs::write(dir.path().join("case.toml"), &case).unwrap();
        let mut runs: Vec<(&str, &[&str])> = vec![("1", &[]), ("3", &[])];
        if !friction.contains("coulomb") {
            runs.push(("1", &["--linear", "full"]));
        }
        let mut outs = Vec::new();
        for (k, (np, extra)) in runs.iter().enumerate() {
            let out = format!("out{k}");
            let o = mpirun(np.parse().unwrap(), dir.path())
                .args([
                    "case.toml",
                    "--out",
                    &out,
                    "--quiet",
                    "--subdomains-per-rank",
                    "1",
                ])
                .args(*extra)
                .output()
                .expect("mpirun");
            assert!(
                o.status.success(),
                "{np} ranks {extra:?}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            let out = dir.path().join(out);
            outs.push((
                read_contact(&out.join("contact.csv")),
                read_summary(&out.join("summary.json")),
            ));
        }
        let rows = &outs[0].0;
        if friction.contains("coulomb") {
            let counts = check_kkt(&outs[1].0, Law::Coulomb(0.2), 1e-7, "3 ranks");
            assert!(counts.stick + counts.slip > 0, "{counts:?}");
            // Both ends of the arc have a prescribed component (ux on the axis, uy under
            // the top).
            assert_eq!(
                num(&outs[0].1, "boundary_dofs") as usize,
                2 * rows.len() - 2
            );
        } else {
            check_kkt(&outs[1].0, Law::None, 1e-7, "3 ranks");
            // One dof per node: the normal one where turned; at the ends of the arc the
            // free one of x, y (their other component is prescribed).
            assert_eq!(num(&outs[0].1, "boundary_dofs") as usize, rows.len());
            assert_same_columns(rows, &outs[2].0, 1e-8, "condensed in frames against full");
        }
        assert_same_columns(rows, &outs[1].0, 1e-8, "1 against 3 ranks");
    }
}

/// The built-in punch (a rigid roller pressed into the block's top and dragged along it,
/// Coulomb): the same answer on 1 and 3 ranks, the discrete conditions at every node, one
/// sticking interval beside slipping nodes (on the side away from the drag: the thin
/// clamped block couples normal and tangential response, so the stick zone is not
/// centred as on a half-space), and the punch's force pushing the block down and
/// dragging it along +x, within the friction cone.
#[test]
fn the_punch_sticks_and_slips() {
    let dir = tempfile::TempDir::new().unwrap();
    let mut outs = Vec::new();
    for np in [1, 3] {
        let out = format!("out{np}");
        let o = mpirun(np, dir.path())
            .args([
                "--builtin",
                "punch",
                "--level",
                "2",
                "--out",
                &out,
                "--quiet",
            ])
            .args(["--tol", "1e-10", "--subdomains-per-rank", "1"])
            .output()
            .expect("mpirun");
        assert!(
            o.status.success(),
            "{np} ranks: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let out = dir.path().join(out);
        outs.push((
            read_contact(&out.join("contact.csv")),
            read_summary(&out.join("summary.json")),
        ));
    }
    assert_same_columns(&outs[0].0, &outs[1].0, 1e-8, "punch, 1 against 3 ranks");
    let (rows, s) = &outs[0];
    let counts = check_kkt(rows, Law::Coulomb(0.3), 1e-7, "punch");
    assert!(counts.stick >= 3 && counts.slip >= 3, "{counts:?}");
    // Rows are sorted by x along the top: the sticking nodes lie between slipping ones.
    let active: Vec<_> = rows.iter().filter(|r| r.p_n > 0.0).collect();
    let sticks = |r: &&Row| r.p_t.abs() < 0.3 * r.p_n * (1.0 - 1e-6);
    let first = active.iter().position(sticks).expect("a sticking node");
    let last = active.iter().rposition(sticks).unwrap();
    assert!(last + 1 < active.len(), "no slip beyond the stick zone");
    assert!(
        active[first..=last].iter().all(sticks),
        "stick zone not one interval"
    );
    let force = &s["contacts"][0]["force"];
    let (fx, fy) = (force[0].as_f64().unwrap(), force[1].as_f64().unwrap());
    println!("punch force on the block: ({fx}, {fy})");
    assert!(fy < 0.0 && fx > 0.0 && fx < 0.3 * -fy, "({fx}, {fy})");
}

/// Two contacts with their own friction: the block pushed by its left side slides
/// against a wall (Coulomb 0.1, frictionless, or Tresca 2: laws mixed) while its floor
/// (Coulomb 0.3) holds it; each node obeys its own contact's law, and the mixed laws
/// agree on 1 and 3 ranks and with the outer Coulomb loop.
#[test]
fn each_contact_has_its_own_friction() {
    for wall_law in [
        "friction = \"coulomb\"\ncoefficient = 0.1",
        "friction = \"none\"",
        "friction = \"tresca\"\nthreshold = 2.0",
    ] {
        let case = format!(
            r#"title = "block on a floor against a wall"
[mesh]
builtin = "block"
level = 1
[material]
young = 70000.0
poisson = 0.33
[[dirichlet]]
group = "top"
uy = -0.02
[[traction]]
group = "left"
t = [40.0, 0.0]
[[contact]]
slave = "bottom"
obstacle = {{ type = "line", point = [0.0, 0.0], normal = [0.0, 1.0] }}
friction = "coulomb"
coefficient = 0.3
[[contact]]
slave = "right"
obstacle = {{ type = "line", point = [40.001, 0.0], normal = [-1.0, 0.0] }}
{wall_law}
[solver]
tol = 1e-10
"#
        );
        let run = run_case(&case, &[]);
        run.expect_code(0);
        let rows = run.contact();
        // The corner (40, 0) is the floor's: both obstacles are as near, the floor first.
        let (wall, floor): (Vec<Row>, Vec<Row>) = rows.iter().partition(|r| r.contact == 1);
        assert!(wall.iter().all(|r| r.x == 40.0 && r.y > 0.0));
        assert_eq!(wall.len(), 20);
        check_kkt(&floor, Law::Coulomb(0.3), 1e-7, "floor");
        let f = &run.summary()["contacts"][1]["force"];
        let (fx, fy) = (f[0].as_f64().unwrap(), f[1].as_f64().unwrap());
        println!("{wall_law}: wall force on the block ({fx}, {fy})");
        assert!(fx < 0.0, "({fx}, {fy})");
        if wall_law.contains("none") {
            check_kkt(&wall, Law::None, 1e-7, "frictionless wall");
            assert!(wall.iter().all(|r| r.p_t == 0.0), "friction on the wall");
            assert_eq!(fy, 0.0);
            // Its nodes are in contact, neither sticking nor slipping.
            let s = run.summary();
            assert_eq!(s["contacts"][1]["active_nodes"], 20);
            assert_eq!(num(&s, "stick_nodes") + num(&s, "slip_nodes"), 81.0);
        } else if wall_law.contains("tresca") {
            assert_eq!(run.summary()["friction"], "tresca+coulomb");
            let counts = check_kkt(&wall, Law::Tresca(2.0), 1e-7, "Tresca wall");
            assert!(counts.slip >= 10, "the wall should slip: {counts:?}");
            // Every slipping node carries the threshold, not a share of its pressure.
            let slipping = wall.iter().filter(|r| r.u_t.abs() > 1e-9);
            assert!(slipping.clone().all(|r| (r.p_t.abs() - 2.0).abs() < 1e-6));
            let dir = tempfile::TempDir::new().unwrap();
            std::fs::write(dir.path().join("case.toml"), &case).unwrap();
            let args = ["case.toml", "--out", "out", "--quiet"];
            let (code, _, err) = run_on_ranks(dir.path(), 3, &args);
            assert_eq!(code, 0, "{err}");
            let three = read_contact(&dir.path().join("out/contact.csv"));
            assert_same_columns(&rows, &three, 1e-8, "mixed laws, 1 vs 3 ranks");
            let outer = run_case(
                &case.replace("tol = 1e-10", "tol = 1e-10\ncoulomb = \"outer\""),
                &[],
            );
            outer.expect_code(0);
            assert_same_columns(&rows, &outer.contact(), 1e-7, "mixed laws, inner vs outer");
        } else {
            let counts = check_kkt(&wall, Law::Coulomb(0.1), 1e-7, "wall");
            assert!(counts.slip >= 10, "the wall should slip: {counts:?}");
            assert!((fy / fx + 0.1).abs() < 1e-6, "({fx}, {fy})");
        }
    }
}
