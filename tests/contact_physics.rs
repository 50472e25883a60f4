//! The contact solver against independent expectations, through the binary: exact
//! solutions (block pressed flat), the Hertz formulas, the KKT conditions of every
//! friction law, limits that must reproduce another law, mirror symmetry, the sign
//! convention of the tangential traction, and the two Coulomb modes.
//!
//! All runs use `tol = 1e-10` unless stated; the tolerances of the assertions are far
//! above what that leaves (the measured values are printed, run with `--no-capture`).

mod common;
use common::*;

/// The obstacle normal of a foundation tilted by 1 mrad, rising to the right: the gap
/// under the block grows like 0.001 + 1e-3 x, so a top displacement of -0.02 closes it
/// only for x < ~20 and the block is in partial contact (free, stick and slip nodes).
fn tilted() -> [f64; 2] {
    let t: f64 = 1e-3;
    [t.sin(), t.cos()]
}

const FLAT: [f64; 2] = [0.0, 1.0];

// ---- 3. block pressed flat ------------------------------------------------------------

#[test]
fn block_flat_has_the_applied_uniform_pressure() {
    // nu = 0, uniform traction 50 on top, frictionless: the exact solution is uniaxial
    // stress, pressure 50 everywhere on the bottom, the block translated down by the gap
    // 0.001 and no horizontal motion. P1 elements contain it, so only the solver tolerance
    // (1e-10) and round-off are left: 1e-6 is a wide margin.
    let run = run_builtin("block_flat", 0, &["--tol", "1e-10"]);
    run.expect_code(0);
    let rows = run.contact();
    let s = run.summary();
    assert_eq!(rows.len(), 41);
    let (mut dp, mut dun, mut ut) = (0.0f64, 0.0f64, 0.0f64);
    for r in &rows {
        dp = dp.max((r.p_n - 50.0).abs() / 50.0);
        dun = dun.max((r.u_n - r.gap).abs() / r.gap);
        ut = ut.max(r.u_t.abs());
        assert!((r.gap - 0.001).abs() < 1e-15, "{r:?}");
        assert_eq!(r.p_t, 0.0, "frictionless: p_t must be 0: {r:?}");
    }
    println!("block_flat: max |p_n - 50| / 50 = {dp:e}, max |u_n - gap| / gap = {dun:e}, max |u_t| = {ut:e}");
    assert!(dp <= 1e-6, "p_n off by {dp:e} relative");
    assert!(dun <= 1e-6, "u_n differs from the gap by {dun:e} relative");
    // u_t = ux at the bottom is exactly 0 (nu = 0, ux fixed at the left corner); compared
    // with the 0.001 vertical motion.
    assert!(ut <= 1e-9 * 0.001, "u_t = {ut:e}");
    let force = num(&s, "total_normal_force");
    assert!(
        (force - 50.0 * 40.0).abs() <= 1e-6 * 2000.0,
        "total normal force {force}"
    );
    assert_eq!(num(&s, "active_nodes"), 41.0);
}

#[test]
fn block_flat_with_body_force_carries_the_whole_load() {
    // The block_flat case plus a uniform body force (0, -0.5): the foundation is the only
    // vertical support, so by equilibrium the total normal force is the applied load,
    // 50 * 40 + 0.5 * 40 * 10 = 2200, exactly up to the solver tolerance (1e-10).
    let text = print_case("block_flat", 0) + "\n[body_force]\nf = [0.0, -0.5]\n";
    let run = run_case(&text, &["--tol", "1e-10"]);
    run.expect_code(0);
    let force = num(&run.summary(), "total_normal_force");
    println!("block_flat + body force: total normal force {force} (expected 2200)");
    assert!(
        (force - 2200.0).abs() <= 1e-8 * 2200.0,
        "total normal force {force}"
    );
    // With nu = 0 the columns barely interact: the pressure is the column weight
    // 50 + 0.5 * 10 = 55 everywhere, up to the P1 error of the quadratic displacement
    // that gravity causes (measured 0.15%; 1% allowed).
    for r in run.contact() {
        assert!((r.p_n - 55.0).abs() <= 0.01 * 55.0, "{r:?}");
    }
}

// ---- 4. Hertz -------------------------------------------------------------------------

#[test]
fn hertz_half_width_peak_and_profile() {
    // Default tol (1e-8): far below the 5% and 10% tolerances of this test.
    let run = run_builtin("hertz", 2, &[]);
    run.expect_code(0);
    let rows = run.contact();
    let s = run.summary();
    // Quarter model, symmetric about x = 0: the whole cylinder carries twice the force.
    let p = 2.0 * num(&s, "total_normal_force");
    let (e, nu, radius) = (210000.0, 0.3, 50.0);
    let e_star = e / (1.0 - nu * nu);
    let a = (4.0 * p * radius / (std::f64::consts::PI * e_star)).sqrt();
    let p0 = 2.0 * p / (std::f64::consts::PI * a);
    println!("Hertz: P = {p}, a = {a} (a/R = {}), p0 = {p0}", a / radius);
    assert!(
        (0.04..0.1).contains(&(a / radius)),
        "a/R = {} is outside the range where Hertz holds and the case is meant to be",
        a / radius
    );

    // Rows are sorted by x; the arc is a graph over x near the contact.
    let last = rows
        .iter()
        .rposition(|r| r.p_n > 0.0)
        .expect("no active node");
    assert!(
        rows[..last].iter().all(|r| r.p_n > 0.0),
        "contact zone is not one interval"
    );
    let (x_in, x_out) = (rows[last].x, rows[last + 1].x);
    let half_width = 0.5 * (x_in + x_out);
    let e_a = (half_width - a) / a;
    let pmax = rows.iter().map(|r| r.p_n).fold(0.0, f64::max);
    let e_p = (pmax - p0) / p0;
    println!(
        "Hertz: discrete half-width in [{x_in}, {x_out}], midpoint error {e_a:+.4e}; max p_n = {pmax}, error {e_p:+.4e}"
    );
    // 5%: the discretisation error at level 2 (about 33 active nodes, arc elements
    // R/487 ~ 3% of a) plus the a << R approximation of the formula (a/R ~ 0.07).
    assert!(e_a.abs() <= 0.05, "half-width off by {e_a:e}");
    assert!(
        x_in <= a * 1.05 && x_out >= a * 0.95,
        "a = {a} not between the nodes {x_in}, {x_out}"
    );
    assert!(e_p.abs() <= 0.05, "peak pressure off by {e_p:e}");

    // Profile: within 10% of p0 wherever the square root is well resolved (x < 0.8 a).
    let mut worst = 0.0f64;
    let mut checked = 0;
    for r in rows.iter().filter(|r| r.p_n > 0.0 && r.x < 0.8 * a) {
        let exact = p0 * (1.0 - (r.x / a).powi(2)).sqrt();
        worst = worst.max((r.p_n - exact).abs() / p0);
        checked += 1;
    }
    println!("Hertz: profile at {checked} nodes with x < 0.8a, max |p_n - p(x)| / p0 = {worst:e}");
    assert!(checked >= 10, "only {checked} nodes in the contact zone");
    assert!(worst <= 0.10, "profile off by {worst:e} of p0");
}

// ---- 5. KKT conditions for each law ---------------------------------------------------

/// Relative tolerance of the KKT checks: the runs stop when both relative residuals
/// (W-norms over the contact nodes) are below 1e-10; a pointwise value can be
/// sqrt(sum w / min w) = sqrt(40 / 0.5) ~ 10 times the W-norm, and the residuals' scale
/// (multiplier and displacement norms) differs from max p_n, max |u| by up to ~10, so
/// the pointwise defects are ~1e-8 at worst. Measured worst: 6.4e-10 (Coulomb outer,
/// penetration), printed with --no-capture.
const KKT_REL: f64 = 1e-8;

#[test]
fn kkt_frictionless_partial_contact() {
    let run = run_case(
        &block_case(
            0,
            "ux = 0.0\nuy = -0.02",
            "friction = \"none\"",
            tilted(),
            "",
        ),
        &[],
    );
    run.expect_code(0);
    let rows = run.contact();
    let c = check_kkt(&rows, Law::None, KKT_REL, "frictionless, tilted");
    assert!(
        rows.iter().all(|r| r.p_t == 0.0),
        "frictionless: p_t must be 0"
    );
    assert!(
        c.free > 0 && c.free < rows.len(),
        "expected partial contact: {c:?}"
    );
    // Contact closes from the low end of the tilted foundation (x = 0).
    let active: Vec<bool> = rows.iter().map(|r| r.p_n > 0.0).collect();
    let first_free = active.iter().position(|a| !a).unwrap();
    assert!(active[..first_free].iter().all(|a| *a) && active[first_free..].iter().all(|a| !*a));
}

/// Without friction only the normal component of a contact node is read and loaded, so
/// on a foundation along an axis only that component enters the condensed boundary system
/// (one boundary dof per contact node), the other is eliminated with the interior; with
/// friction, or with an inclined normal, both do. The frictionless answer on the smaller
/// system must still satisfy the contact conditions (`ranks.rs` also compares it with the
/// uncondensed solve).
#[test]
fn condensed_system_keeps_the_contact_components_that_are_read() {
    for (friction, normal, per_node) in [
        ("friction = \"none\"", FLAT, 1),
        // Turned into each node's frame: the normal dof only.
        ("friction = \"none\"", tilted(), 1),
        ("friction = \"coulomb\"\ncoefficient = 0.3", FLAT, 2),
    ] {
        let what = format!("{friction}, normal {normal:?}");
        let run = run_case(
            &block_case(0, "ux = 0.0\nuy = -0.02", friction, normal, ""),
            &[],
        );
        run.expect_code(0);
        let rows = run.contact();
        let s = run.summary();
        assert_eq!(
            num(&s, "boundary_dofs") as usize,
            per_node * rows.len(),
            "{what}"
        );
        if per_node == 1 {
            let c = check_kkt(&rows, Law::None, KKT_REL, &what);
            assert!(c.slip > 0, "{what}: nothing in contact: {c:?}");
        }
    }
}

#[test]
fn kkt_tresca_partial_contact_with_stick_and_slip() {
    let s = 20.0;
    let run = run_case(
        &block_case(
            0,
            "ux = 0.01\nuy = -0.02",
            &format!("friction = \"tresca\"\nthreshold = {s:?}"),
            tilted(),
            "",
        ),
        &[],
    );
    run.expect_code(0);
    let c = check_kkt(&run.contact(), Law::Tresca(s), KKT_REL, "Tresca, tilted");
    let sum = run.summary();
    assert!(c.free > 0, "{c:?}");
    assert!(
        num(&sum, "stick_nodes") > 0.0 && num(&sum, "slip_nodes") > 0.0,
        "{sum}"
    );
    assert!(c.stick > 0 && c.slip > 0, "{c:?}");
}

fn coulomb_kkt(mode: &str, normal: [f64; 2]) {
    let coef = 0.3;
    let run = run_case(
        &block_case(
            0,
            "ux = 0.01\nuy = -0.02",
            &format!("friction = \"coulomb\"\ncoefficient = {coef:?}"),
            normal,
            &format!("coulomb = \"{mode}\""),
        ),
        &[],
    );
    run.expect_code(0);
    let what = format!("Coulomb {mode}, normal {normal:?}");
    let c = check_kkt(&run.contact(), Law::Coulomb(coef), KKT_REL, &what);
    let sum = run.summary();
    println!(
        "{what}: summary stick {} slip {}",
        sum["stick_nodes"], sum["slip_nodes"]
    );
    assert!(
        num(&sum, "stick_nodes") > 0.0 && num(&sum, "slip_nodes") > 0.0,
        "{sum}"
    );
    assert!(c.stick > 0 && c.slip > 0, "{what}: {c:?}");
}

#[test]
fn kkt_coulomb_inner_stick_and_slip() {
    coulomb_kkt("inner", FLAT);
}

#[test]
fn kkt_coulomb_outer_stick_and_slip() {
    coulomb_kkt("outer", FLAT);
}

#[test]
fn kkt_coulomb_inner_partial_contact() {
    coulomb_kkt("inner", tilted());
}

// ---- 6. limits that reproduce another law ---------------------------------------------

#[test]
fn zero_friction_is_frictionless() {
    let top = "ux = 0.01\nuy = -0.02";
    let none = run_case(
        &block_case(0, top, "friction = \"none\"", tilted(), ""),
        &[],
    );
    let tresca = run_case(
        &block_case(
            0,
            top,
            "friction = \"tresca\"\nthreshold = 0.0",
            tilted(),
            "",
        ),
        &[],
    );
    let coulomb = run_case(
        &block_case(
            0,
            top,
            "friction = \"coulomb\"\ncoefficient = 0.0",
            tilted(),
            "",
        ),
        &[],
    );
    for r in [&none, &tresca, &coulomb] {
        r.expect_code(0);
    }
    let reference = none.contact();
    // The limits are exact (s = 0 makes the shrinkage the identity): only the stopping
    // tolerance 1e-10 separates the runs.
    assert_same_columns(
        &reference,
        &tresca.contact(),
        1e-6,
        "Tresca s = 0 vs frictionless",
    );
    assert_same_columns(
        &reference,
        &coulomb.contact(),
        1e-6,
        "Coulomb 0 vs frictionless",
    );
    // The frictionless answer has tangential motion, so the comparison is not vacuous.
    assert!(max_abs(&reference, 3) > 1e-3, "u_t is trivially 0");
}

#[test]
fn huge_tresca_threshold_is_bonded_contact() {
    // Built-in block: every contact node is in contact, so bonding = a Dirichlet ux = 0
    // on the contact group (t = (1, 0)) with frictionless normal contact.
    let top = "ux = 0.01\nuy = -0.02";
    let tresca = run_case(
        &block_case(0, top, "friction = \"tresca\"\nthreshold = 1.0e7", FLAT, ""),
        &["--nodes-csv"],
    );
    let bonded = run_case(
        &block_case(
            0,
            top,
            "friction = \"none\"",
            FLAT,
            "[[dirichlet]]\ngroup = \"bottom\"\nux = 0.0",
        ),
        &["--nodes-csv"],
    );
    tresca.expect_code(0);
    bonded.expect_code(0);
    let (a, b) = (bonded.contact(), tresca.contact());
    assert!(a.iter().all(|r| r.p_n > 0.0), "not every node in contact");
    // p_t differs by construction (0 in the frictionless run, the friction traction in
    // the Tresca one); compare the rest: displacements and pressure to 1e-5 (the Tresca
    // run's u_t -> 0 only to the stopping tolerance, relative to |u|).
    let d = column_diffs(&a, &b);
    println!("bonded vs Tresca 1e7: relative column differences {d:?}");
    for c in [0, 1, 2, 4, 6] {
        assert!(d[c] <= 1e-5, "column {} differs by {:e}", COLUMNS[c], d[c]);
    }
    let umax = max_abs(&a, 2);
    let ut = max_abs(&b, 3);
    assert!(ut <= 1e-5 * umax, "Tresca 1e7: |u_t| = {ut:e}, not stuck");
    assert_eq!(tresca.summary()["slip_nodes"], 0);
    // The whole displacement field.
    let na = read_nodes(&bonded.out.join("nodes.csv"));
    let nb = read_nodes(&tresca.out.join("nodes.csv"));
    assert_eq!(na.len(), nb.len());
    let scale = na
        .iter()
        .map(|v| v[2].abs().max(v[3].abs()))
        .fold(0.0, f64::max);
    let diff = na
        .iter()
        .zip(&nb)
        .map(|(x, y)| {
            assert_eq!((x[0], x[1]), (y[0], y[1]));
            (x[2] - y[2]).abs().max((x[3] - y[3]).abs())
        })
        .fold(0.0, f64::max);
    println!(
        "bonded vs Tresca 1e7: max nodal displacement difference / max |u| = {:e}",
        diff / scale
    );
    assert!(
        diff <= 1e-5 * scale,
        "displacements differ by {:e}",
        diff / scale
    );
}

// ---- 7. mirror symmetry ---------------------------------------------------------------

/// Largest mirror defects |p_n(x) - p_n(40 - x)| / max p_n and
/// |u_t(x) + u_t(40 - x)| / max |u_t|, and max |u_t|.
fn mirror_defects(rows: &[Row], what: &str) -> (f64, f64, f64) {
    // Rows are sorted by x and the mesh is exactly mirror symmetric about x = 20 (the
    // mirrored coordinates are computed as 40 - x), so row k pairs with row n-1-k.
    let n = rows.len();
    let pmax = max_abs(rows, 4);
    let umax = max_abs(rows, 3);
    assert!(pmax > 0.0, "{what}: no contact pressure");
    let (mut ep, mut et) = (0.0f64, 0.0f64);
    for k in 0..n {
        let (a, b) = (&rows[k], &rows[n - 1 - k]);
        assert_eq!(
            a.x,
            40.0 - b.x,
            "{what}: the contact nodes are not mirror images"
        );
        ep = ep.max((a.p_n - b.p_n).abs() / pmax);
        et = et.max((a.u_t + b.u_t).abs() / umax.max(f64::MIN_POSITIVE));
    }
    println!("{what}: max |p_n(x) - p_n(40-x)| / max p_n = {ep:e}, max |u_t(x) + u_t(40-x)| / max |u_t| = {et:e}, max |u_t| = {umax:e}");
    (ep, et, umax)
}

#[test]
fn symmetric_load_gives_symmetric_solution() {
    // Frictionless: the top is clamped horizontally (ux = 0, itself symmetric) to remove
    // the rigid sliding; Coulomb: the top is only pushed down (no ux at all).
    let none = run_case(
        &block_case(0, "ux = 0.0\nuy = -0.02", "friction = \"none\"", FLAT, ""),
        &[],
    );
    let coulomb = run_case(
        &block_case(
            0,
            "uy = -0.02",
            "friction = \"coulomb\"\ncoefficient = 0.2",
            FLAT,
            "",
        ),
        &[],
    );
    none.expect_code(0);
    coulomb.expect_code(0);
    let (rn, rc) = (none.contact(), coulomb.contact());
    let (epn, etn, un) = mirror_defects(&rn, "frictionless");
    let (epc, etc, uc) = mirror_defects(&rc, "Coulomb 0.2");
    // The discrete problem is exactly symmetric; only round-off in the factorization
    // (and its propagation through the sweeps) breaks it: 1e-8 leaves a wide margin.
    assert!(
        epn <= 1e-8 && epc <= 1e-8,
        "p_n not symmetric: {epn:e}, {epc:e}"
    );
    assert!(etc <= 1e-8, "Coulomb: u_t not antisymmetric ({etc:e})");
    // Friction opposes the outward Poisson expansion: p_t points inwards at the ends.
    assert!(rc[0].p_t > 0.0 && rc[rc.len() - 1].p_t < 0.0, "{rc:?}");
    // The bottom spreads outwards (Poisson), more without friction than with it: the
    // frictionless u_t is not 0 (it is the sliding the frictionless contact allows).
    assert!(uc > 0.0, "Coulomb: u_t identically 0");
    assert!(
        un > uc,
        "frictionless: max |u_t| = {un:e} in contact.csv, expected the bottom to slide outwards more than with friction ({uc:e})"
    );
    assert!(etn <= 1e-8, "frictionless: u_t not antisymmetric ({etn:e})");
}

// ---- 8. sign convention ---------------------------------------------------------------

#[test]
fn sliding_block_friction_opposes_the_shear() {
    let s = 1.0;
    for shear in [0.05, -0.05] {
        let run = run_case(
            &block_case(
                0,
                &format!("ux = {shear:?}\nuy = -0.02"),
                &format!("friction = \"tresca\"\nthreshold = {s:?}"),
                FLAT,
                "",
            ),
            &[],
        );
        run.expect_code(0);
        let rows = run.contact();
        let sum = run.summary();
        let w = line_weights(&rows);
        let mut active_weight = 0.0;
        for (r, w) in rows.iter().zip(&w) {
            if r.p_n <= 0.0 {
                continue;
            }
            active_weight += w;
            // Tangent t = (m_y, -m_x) = (1, 0): u_t = ux has the sign of the shear.
            assert!(
                r.u_t * shear > 0.0,
                "shear {shear}: u_t = {} at x = {}",
                r.u_t,
                r.x
            );
            // Full slip: p_t = -s sign(u_t), to the stopping tolerance.
            let want = -s * r.u_t.signum();
            assert!(
                (r.p_t - want).abs() <= 1e-6 * s,
                "shear {shear}: p_t = {} at x = {}, expected {want}",
                r.p_t,
                r.x
            );
        }
        assert_eq!(
            sum["slip_nodes"], sum["contact_nodes"],
            "not all slipping: {sum}"
        );
        assert!((active_weight - 40.0).abs() < 1e-12, "{active_weight}");
        let ft = num(&sum, "total_tangential_force");
        let want = -s * shear.signum() * active_weight;
        println!("shear {shear}: total tangential force {ft}, expected {want}");
        assert!(
            (ft - want).abs() <= 1e-6 * s * 40.0,
            "total tangential force {ft} vs {want}"
        );
    }
}

// ---- 9. Coulomb modes -----------------------------------------------------------------

#[test]
fn coulomb_inner_and_outer_agree() {
    let case = block_case(
        0,
        "ux = 0.01\nuy = -0.02",
        "friction = \"coulomb\"\ncoefficient = 0.3",
        tilted(),
        "",
    );
    let inner = run_case(&case, &["--coulomb", "inner"]);
    let outer = run_case(&case, &["--coulomb", "outer"]);
    inner.expect_code(0);
    outer.expect_code(0);
    assert!(outer.summary()["outer_iterations"].as_u64().unwrap() > 1);
    // Both converge to the same fixed point; the stopping tolerances (1e-10 on the sweeps
    // and on the threshold change) leave differences far below 1e-6.
    assert_same_columns(
        &inner.contact(),
        &outer.contact(),
        1e-6,
        "Coulomb inner vs outer",
    );
    let (si, so) = (inner.summary(), outer.summary());
    assert_eq!(si["stick_nodes"], so["stick_nodes"]);
    assert_eq!(si["slip_nodes"], so["slip_nodes"]);
}

// ---- regression: contact with zero gap -------------------------------------------------

/// The block pressed onto a foundation that it touches initially (gap 0), frictionless,
/// top clamped horizontally: every contact node ends in contact with u_n = 0. The same
/// problem shifted by 0.001 (foundation at y = -0.001, top pushed 0.001 further) has the
/// same deformation, hence the same pressures.
///
/// Regression test: when the residuals were divided by |Nu|_W + |Tu|_W alone (the contact
/// displacement, exactly 0 at this solution), the primal residual stayed at 1.0 for ever
/// and the run ended at max_iter with exit code 3 (fixed in e82cd93).
#[test]
fn zero_gap_full_contact_converges() {
    let shifted = run_case(
        &block_case(0, "ux = 0.0\nuy = -0.021", "friction = \"none\"", FLAT, ""),
        &[],
    );
    shifted.expect_code(0);
    let touching = block_case(0, "ux = 0.0\nuy = -0.02", "friction = \"none\"", FLAT, "").replace(
        "obstacle_point = [0.0, -0.001]",
        "obstacle_point = [0.0, 0.0]",
    );
    let run = run_case(&touching, &["--max-iter", "2000"]);
    let sum = run.summary();
    println!(
        "zero gap: exit {}, {} iterations, final residuals {}",
        run.code, sum["iterations"], sum["final_residuals"]
    );
    run.expect_code(0);
    let (a, b) = (shifted.contact(), run.contact());
    assert_eq!(a.len(), b.len());
    let pmax = max_abs(&a, 4);
    for (ra, rb) in a.iter().zip(&b) {
        assert!((ra.p_n - rb.p_n).abs() <= 1e-6 * pmax, "{ra:?} vs {rb:?}");
    }
}
