//! Anderson acceleration changes the path, not the answer: on every built-in case and
//! friction law the accelerated and plain methods agree to 1e-8, and the accelerated one
//! needs fewer sweeps. (The safeguard is exercised by a disturbed solve in the unit
//! tests of `contact::uzawa`.)

mod common;
use common::*;

/// Runs `case` (TOML) with --acceleration none and anderson at tol 1e-12.
fn compare(case: &str, what: &str) {
    // The residuals are W-norms over the whole contact boundary and plain ALG2
    // contracts slowly, so the pointwise error at stopping is a few hundred times tol:
    // 1e-12 makes the 1e-8 comparison a statement about the two limits, not about the
    // stopping test.
    let args = |acc: &'static str| ["--acceleration", acc, "--tol", "1e-12", "--nodes-csv"];
    let plain = run_case(case, &args("none"));
    plain.expect_code(0);
    let fast = run_case(case, &args("anderson"));
    fast.expect_code(0);
    let (a, b) = (plain.contact(), fast.contact());
    // u_n and u_t against the largest displacement (u_n sits at round-off on a flat
    // foundation with no gap), p_n and p_t against the largest pressure.
    let u_scale = a
        .iter()
        .map(|r| r.col(2).abs().max(r.col(3).abs()).max(r.col(6).abs()))
        .fold(0.0, f64::max);
    let p_scale = max_abs(&a, 4);
    for (ra, rb) in a.iter().zip(&b) {
        for (c, scale) in [(2, u_scale), (3, u_scale), (4, p_scale), (5, p_scale)] {
            let d = (ra.col(c) - rb.col(c)).abs();
            assert!(
                d <= 1e-8 * scale,
                "{what}: column {c} differs by {:e} at x = {}",
                d / scale,
                ra.col(0)
            );
        }
    }
    let (n1, n2) = (
        read_nodes(&plain.out.join("nodes.csv")),
        read_nodes(&fast.out.join("nodes.csv")),
    );
    let scale = n1
        .iter()
        .map(|r| r[2].abs().max(r[3].abs()))
        .fold(0.0, f64::max);
    let d = n1
        .iter()
        .zip(&n2)
        .map(|(a, b)| (a[2] - b[2]).abs().max((a[3] - b[3]).abs()))
        .fold(0.0, f64::max);
    assert!(
        d <= 1e-8 * scale,
        "{what}: displacements differ by {:e}",
        d / scale
    );
    let (ip, ia) = (
        num(&plain.summary(), "iterations"),
        num(&fast.summary(), "iterations"),
    );
    println!("{what}: plain {ip} sweeps, anderson {ia}");
    assert!(ia < ip, "{what}: anderson {ia} sweeps, plain {ip}");
}

#[test]
fn hertz_every_law() {
    for f in [
        "friction = \"none\"",
        "friction = \"tresca\"\nthreshold = 500.0",
        "friction = \"coulomb\"\ncoefficient = 0.2",
    ] {
        compare(&builtin_with_friction("hertz", 1, f), &format!("hertz {f}"));
    }
}

#[test]
fn block_every_law() {
    for f in [
        "friction = \"none\"",
        "friction = \"tresca\"\nthreshold = 20.0",
        "friction = \"coulomb\"\ncoefficient = 0.3",
        "friction = \"coulomb\"\ncoefficient = 0.3\n[solver]\ncoulomb = \"outer\"",
    ] {
        compare(&builtin_with_friction("block", 1, f), &format!("block {f}"));
    }
}

#[test]
fn block_flat() {
    // Converges in a handful of sweeps either way; only the answer is compared.
    let case = builtin_with_friction("block_flat", 1, "friction = \"none\"");
    let plain = run_case(&case, &["--acceleration", "none", "--tol", "1e-12"]);
    let fast = run_case(&case, &["--acceleration", "anderson", "--tol", "1e-12"]);
    plain.expect_code(0);
    fast.expect_code(0);
    assert_same_columns(&plain.contact(), &fast.contact(), 1e-8, "block_flat");
}

/// A body that nothing holds before it touches: while every contact node is open, the
/// sweep map is a translation (each sweep moves the block by the same amount towards the
/// foundation), so the newest Anderson difference is zero up to round-off, and mixing
/// with it would throw the state far away. With a given r (the paper's method, no
/// retune) the accelerated run must find the exact answer: every node pressed, the
/// contact force equal to the applied load.
#[test]
fn floating_body_over_a_gap() {
    for r in ["6e4", "1e5", "1e6"] {
        let run = run_builtin("block_flat", 1, &["--r", r, "--max-iter", "200"]);
        run.expect_code(0);
        let s = run.summary();
        assert_eq!(s["converged"], true, "r = {r}");
        assert_eq!(num(&s, "active_nodes"), num(&s, "contact_nodes"), "r = {r}");
        // 50 MPa on a top of length 40 (the case's traction and mesh).
        let force = num(&s, "total_normal_force");
        assert!(
            (force - 2000.0).abs() <= 1e-7 * 2000.0,
            "r = {r}: contact force {force}"
        );
        assert!(num(&s, "iterations") <= 50.0, "r = {r}");
    }
}
