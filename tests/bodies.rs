//! Two elastic bodies in contact (`[[contact]]` with `master`), each meshed on its own:
//! the contact patch test on 1 to 4 ranks, two elastic cylinders against Hertz under
//! refinement, action and reaction, and a frictional pair on 1 and 3 ranks.
//!
//! `tests/data/bodies/blocks.msh` (made by `make_meshes.py` there): two unit-wide blocks
//! stacked at y = 0.5, meshed with sizes 0.09 (lower) and 0.065 (upper), so that the
//! nodes of the two sides of the contact do not coincide.

mod common;

use common::*;
use std::f64::consts::PI;

/// Runs `toml` (written beside a copy of blocks.msh) on `np` ranks with `--nodes-csv`.
fn run_blocks(toml: &str, np: usize) -> Run {
    let dir = tempfile::TempDir::new().unwrap();
    std::fs::copy(
        bodies_dir().join("blocks.msh"),
        dir.path().join("blocks.msh"),
    )
    .unwrap();
    std::fs::write(dir.path().join("case.toml"), toml).unwrap();
    let args = ["case.toml", "--out", "out", "--quiet", "--nodes-csv"];
    let result = run_on_ranks(dir.path(), np, &args);
    Run::kept(dir, result)
}

fn blocks_case() -> String {
    std::fs::read_to_string(bodies_dir().join("blocks.toml")).unwrap()
}

/// The contact's force on the slave body and the slave's on the master, from summary.json.
fn forces(run: &Run) -> ([f64; 2], [f64; 2]) {
    let c = &run.summary()["contacts"][0];
    let pair = |key: &str| [0, 1].map(|i| c[key][i].as_f64().expect(key));
    (pair("force"), pair("master_force"))
}

/// Action equals reaction: what the rows put on the master nodes is minus what they put
/// on the slave, to round-off. And every body of these cases is held at the answer,
/// through the other body where it rests on it: no warning of an answer that is not
/// unique (`problem::free_at_answer`).
fn assert_action_reaction(run: &Run, what: &str) {
    assert_eq!(
        not_unique_warnings(&run.summary()),
        Vec::<String>::new(),
        "{what}"
    );
    let (on_slave, on_master) = forces(run);
    let scale = on_slave[0].hypot(on_slave[1]);
    for c in 0..2 {
        assert!(
            (on_slave[c] + on_master[c]).abs() <= 1e-12 * scale,
            "{what}: force on the slave {on_slave:?}, on the master {on_master:?}"
        );
    }
}

/// The contact patch test: a uniform traction p on the upper block is carried across the
/// non-matching interface as a uniform pressure p, and each block is in uniform uniaxial
/// stress (plane strain, sigma_xx = 0), so P1 holds the exact displacement:
/// ux = nu (1 + nu) p x / E, uy = -(1 - nu^2) p (y - y0) / E + uy(y0) in each block.
/// Node-to-segment pairing fails this (pressures off by several per cent with where each
/// slave node lands on its master segment); the dual mortar rows pass it to round-off,
/// on every rank count (the pairs then cross subdomains: master nodes are ghosts).
#[test]
fn contact_patch_test_is_exact_on_one_to_four_ranks() {
    let p = 10.0;
    let (e_lo, nu_lo, e_up, nu_up) = (200.0, 0.3, 70.0, 0.25);
    let strain = |e: f64, nu: f64| ((nu * (1.0 + nu) * p / e), -(1.0 - nu * nu) * p / e);
    let (ex_lo, ey_lo) = strain(e_lo, nu_lo);
    let (ex_up, ey_up) = strain(e_up, nu_up);
    let uy_interface = ey_lo * 0.5;
    for np in 1..=4 {
        let run = run_blocks(&blocks_case(), np);
        run.expect_code(0);
        let what = format!("{np} rank(s)");
        let rows = run.contact();
        assert_eq!(rows.len(), 17, "{what}: every slave node is a contact row");
        for r in &rows {
            assert!(
                (r.p_n - p).abs() <= 1e-9 * p,
                "{what}: p_n = {} at x = {}",
                r.p_n,
                r.x
            );
        }
        check_kkt(&rows, Law::None, 1e-9, &what);
        let nodes = read_nodes(&run.out.join("nodes.csv"));
        let scale = uy_interface.abs() + ey_up.abs() * 0.5;
        let mut worst: f64 = 0.0;
        for [x, y, ux, uy] in nodes {
            let lower = [ex_lo * x, ey_lo * y];
            let upper = [ex_up * x, uy_interface + ey_up * (y - 0.5)];
            // A node on y = 0.5 belongs to either block: the nearer exact field.
            let off = |e: [f64; 2]| (ux - e[0]).abs().max((uy - e[1]).abs());
            let err = if y < 0.5 - 1e-9 {
                off(lower)
            } else if y > 0.5 + 1e-9 {
                off(upper)
            } else {
                off(lower).min(off(upper))
            };
            worst = worst.max(err);
        }
        println!("{what}: displacement off the exact one by {worst:e}");
        assert!(
            worst <= 1e-9 * scale,
            "{what}: displacement off by {worst:e}"
        );
        assert_action_reaction(&run, &what);
    }
}

/// Hertz for two cylinders: 1/R = 1/R1 + 1/R2, 1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2,
/// a = sqrt(4 P R / (pi E*)), p0 = 2 P / (pi a), P the force of the whole cylinder (the
/// quarter model carries half).
fn hertz(run: &Run) -> (f64, f64) {
    let p = 2.0 * num(&run.summary(), "total_normal_force");
    let e_star = 1.0 / ((1.0 - 0.3f64.powi(2)) / 210000.0 + (1.0 - 0.33f64.powi(2)) / 70000.0);
    let radius = 1.0 / (1.0 / 50.0 + 1.0 / 90.0);
    let a = (4.0 * p * radius / (PI * e_star)).sqrt();
    (a, 2.0 * p / (PI * a))
}

/// Two elastic cylinders (steel R1 = 50 on aluminium R2 = 90, the built-in `cylinders`)
/// against Hertz at levels 0 to 2: the half-width (where the pressure ends, between two
/// nodes) and the profile over x < 0.8 a converge; on the finest mesh half-width, peak
/// and profile are within 1%. The pressure is the mortar multiplier at the slave nodes.
#[test]
fn two_elastic_cylinders_against_hertz() {
    let mut previous = (f64::INFINITY, f64::INFINITY);
    let mut finest = (0.0, 0.0, 0.0);
    for level in 0..=2 {
        let run = run_builtin("cylinders", level, &[]);
        run.expect_code(0);
        let what = format!("level {level}");
        let rows = run.contact();
        check_kkt(&rows, Law::None, 1e-7, &what);
        assert_action_reaction(&run, &what);
        let (a, p0) = hertz(&run);
        let (e_a, e_p, profile) = hertz_errors_of(&rows, a, p0, &what);
        assert!(e_p.abs() <= 0.015, "{what}: peak off by {e_p:e}");
        assert!(
            e_a.abs() < previous.0 && profile < previous.1,
            "{what}: errors {e_a:e}, {profile:e} did not shrink from {previous:?}"
        );
        previous = (e_a.abs(), profile);
        finest = (e_a, e_p, profile);
    }
    let (e_a, e_p, profile) = finest;
    assert!(
        e_a.abs() <= 0.01 && e_p.abs() <= 0.01 && profile <= 0.01,
        "finest: half-width {e_a:e}, peak {e_p:e}, profile {profile:e}"
    );
    // The same answer on 3 ranks (the contact zone's rows and masters across the cut).
    let one = run_builtin("cylinders", 1, &[]);
    let dir = tempfile::TempDir::new().unwrap();
    let args = [
        "--builtin",
        "cylinders",
        "--level",
        "1",
        "--out",
        "out",
        "--quiet",
    ];
    let (code, _, err) = run_on_ranks(dir.path(), 3, &args);
    assert_eq!(code, 0, "{err}");
    let three = read_contact(&dir.path().join("out/contact.csv"));
    let d = column_diffs(&one.contact(), &three);
    assert!(d[4] <= 1e-9, "p_n differs on 3 ranks by {d:?}");
}

/// The upper block dragged sideways on the lower one with Coulomb friction (held along x
/// by friction alone): partial slip, the same answer on 1 and 3 ranks, the friction cone
/// and complementarity at every slave node, action and reaction.
#[test]
fn a_frictional_pair_agrees_on_one_and_three_ranks() {
    let case = blocks_case()
        .replace("[[dirichlet]]\ngroup = \"upper_left\"\nux = 0.0\n\n", "")
        .replace("t = [0.0, -10.0]", "t = [2.5, -10.0]")
        .replace(
            "friction = \"none\"",
            "friction = \"coulomb\"\ncoefficient = 0.3\n\n[solver]\ntol = 1e-10",
        );
    assert!(!case.contains("upper_left"), "the case kept its roller");
    let one = run_blocks(&case, 1);
    one.expect_code(0);
    let three = run_blocks(&case, 3);
    three.expect_code(0);
    let rows = one.contact();
    let counts = check_kkt(&rows, Law::Coulomb(0.3), 1e-6, "1 rank");
    println!("{counts:?}");
    assert!(counts.slip > 0, "no slip: {counts:?}");
    assert_same_columns(&rows, &three.contact(), 1e-8, "1 vs 3 ranks");
    for run in [&one, &three] {
        assert_action_reaction(run, "coulomb");
        // The drag is carried across the interface.
        let (on_slave, _) = forces(run);
        assert!(
            (on_slave[0] + 2.5).abs() <= 1e-6 * 2.5,
            "tangential force {on_slave:?}"
        );
    }
}

/// A half disc (steel) pressed into an aluminium block and dragged along it, Coulomb 0.3,
/// both meshed unstructured on their own (`disc.msh`, `make_meshes.py --disc 0.1`): the
/// slave line is the whole lower half circle, whose sides face the block's top at a
/// grazing angle and must not be paired with it (they are kept as open rows, or left
/// out). Stick and slip, the contact conditions, action and reaction, 1 and 3 ranks.
#[test]
fn a_disc_dragged_on_a_block() {
    let case = std::fs::read_to_string(bodies_dir().join("disc.toml")).unwrap();
    let run = |np: usize| {
        let dir = tempfile::TempDir::new().unwrap();
        std::fs::copy(bodies_dir().join("disc.msh"), dir.path().join("disc.msh")).unwrap();
        std::fs::write(dir.path().join("case.toml"), &case).unwrap();
        let result = run_on_ranks(dir.path(), np, &["case.toml", "--out", "out", "--quiet"]);
        Run::kept(dir, result)
    };
    let (one, three) = (run(1), run(3));
    one.expect_code(0);
    three.expect_code(0);
    let rows = one.contact();
    let counts = check_kkt(&rows, Law::Coulomb(0.3), 1e-6, "disc");
    assert!(counts.stick > 0 && counts.slip > 0, "{counts:?}");
    // Every gap is that of a node facing the block from above: none below the block.
    assert!(
        rows.iter().all(|r| r.gap > -1e-9 && r.y >= 0.0),
        "a bad pairing"
    );
    // Contact only around the bottom of the disc.
    assert!(rows.iter().filter(|r| r.p_n > 0.0).all(|r| r.x.abs() < 1.0));
    assert_same_columns(&rows, &three.contact(), 1e-8, "disc, 1 vs 3 ranks");
    assert_action_reaction(&one, "disc");
    assert_action_reaction(&three, "disc, 3 ranks");
}

/// Non-zero displacements prescribed at a slave and at a master node (the blocks' left
/// corners moved apart), Coulomb 0.2: the retunes of r (a hundred here) leave the answer
/// that of a fixed r, on 1 and 3 ranks; the lifting of the prescribed values through the
/// rows' coupling is consistent.
#[test]
fn prescribed_values_at_mortar_nodes_and_retunes() {
    let case = blocks_case()
        .replace(
            "group = \"upper_left\"\nux = 0.0",
            "group = \"upper_left\"\nux = 0.01",
        )
        .replace(
            "group = \"lower_left\"\nux = 0.0",
            "group = \"lower_left\"\nux = 0.02",
        )
        .replace(
            "friction = \"none\"",
            "friction = \"coulomb\"\ncoefficient = 0.2\n\n[solver]\ntol = 1e-11",
        );
    assert!(case.contains("ux = 0.02") && case.contains("ux = 0.01"));
    let default = run_blocks(&case, 1);
    default.expect_code(0);
    assert!(
        num(&default.summary(), "r_retunes") > 0.0,
        "no retune to test"
    );
    let r = num(&default.summary(), "r");
    let fixed = run_blocks(
        &case.replace("tol = 1e-11", &format!("tol = 1e-11\nr = {r:?}")),
        1,
    );
    fixed.expect_code(0);
    assert_eq!(num(&fixed.summary(), "r_retunes"), 0.0);
    let rows = default.contact();
    check_kkt(&rows, Law::Coulomb(0.2), 1e-8, "retuned");
    // Every slave node is in contact: u_n is round-off around zero, so the pressures and
    // tractions are compared in contact.csv and the displacement in nodes.csv.
    let same = |other: &Run, what: &str| {
        let d = column_diffs(&rows, &other.contact());
        assert!(
            d[4] <= 1e-9 && d[5] <= 1e-9,
            "{what}: p_n, p_t differ by {d:?}"
        );
        let (a, b) = (
            read_nodes(&default.out.join("nodes.csv")),
            read_nodes(&other.out.join("nodes.csv")),
        );
        let scale = a.iter().map(|n| n[2].hypot(n[3])).fold(0.0, f64::max);
        let worst = (a.iter().zip(&b))
            .map(|(p, q)| (p[2] - q[2]).hypot(p[3] - q[3]))
            .fold(0.0, f64::max);
        println!(
            "{what}: p_n, p_t {:e} {:e}, u {:e}",
            d[4],
            d[5],
            worst / scale
        );
        assert!(
            worst <= 1e-9 * scale,
            "{what}: displacements differ by {worst:e}"
        );
    };
    same(&fixed, "retuned vs fixed r");
    same(&run_blocks(&case, 3), "1 vs 3 ranks");
}

/// A body that nothing holds but another body it only touches without friction slides
/// off: refused before any work, with one line naming it.
#[test]
fn a_body_held_by_nothing_is_refused() {
    let case = blocks_case().replace("[[dirichlet]]\ngroup = \"upper_left\"\nux = 0.0\n\n", "");
    let run = run_blocks(&case, 1);
    run.expect_code(2);
    let line = run.stderr.trim();
    assert_eq!(line.lines().count(), 1, "{line}");
    assert!(
        line.contains("sliding") && line.contains("0.5"),
        "not naming the free body: {line}"
    );
}
