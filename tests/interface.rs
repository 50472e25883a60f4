//! The interface system factored across the ranks by MUMPS (`--interface mumps`) gives
//! the answer of the first rank's factor (`--interface rank0`), both converged to 1e-11,
//! to 1e-9 of the largest displacement and traction, in the same sweeps (within one):
//! on 2, 3, 4 and 8 ranks, on teams of subdomains per rank, with retunes of r (each
//! refactors it), and on 32 oversubscribed ranks; and the answer of one rank to 1e-8.
//! Node by node, for contact.csv and nodes.csv.

mod common;

use std::path::{Path, PathBuf};

fn read_csv(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// Runs `source` on `np` ranks of `k` subdomains each with `--interface which`.
fn run(source: &[&str], np: usize, k: usize, which: &str, dir: &Path) -> PathBuf {
    let out = dir.join(format!("{which}-{np}x{k}"));
    let k = k.to_string();
    let o = common::mpirun(np, dir)
        .args(source)
        .args([
            "--interface",
            which,
            "--subdomains-per-rank",
            &k,
            "--threads",
            "1",
        ])
        // Converged far below the comparison: two runs stopping a sweep apart agree.
        .args(["--tol", "1e-11"])
        .args(["--nodes-csv", "--quiet", "--out", out.to_str().unwrap()])
        .output()
        .expect("mpirun");
    assert!(
        o.status.success(),
        "{which} on {np} ranks: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

/// Columns `cols` of every row within `rel` of the largest value over all of them (a
/// displacement against the largest displacement, a traction against the largest one).
fn assert_close(a: &[Vec<f64>], b: &[Vec<f64>], cols: &[usize], rel: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: rows");
    let scale = b
        .iter()
        .flat_map(|r| cols.iter().map(move |&c| r[c].abs()))
        .fold(0.0, f64::max)
        .max(1e-300);
    for (ra, rb) in a.iter().zip(b) {
        assert_eq!((ra[0], ra[1]), (rb[0], rb[1]), "{what}: nodes differ");
        for &c in cols {
            let d = (ra[c] - rb[c]).abs();
            assert!(
                d <= rel * scale,
                "{what}: column {c} differs by {:e}",
                d / scale
            );
        }
    }
}

fn compare(source: &[&str], np: usize, k: usize) {
    let dir = tempfile::tempdir().unwrap();
    let a = run(source, np, k, "rank0", dir.path());
    let b = run(source, np, k, "mumps", dir.path());
    let what = format!("{source:?} on {np} x {k}");
    // And against one rank, one subdomain: no interface at all.
    let one = run(source, 1, 1, "rank0", dir.path());
    let (c1, cb) = (
        read_csv(&one.join("contact.csv")),
        read_csv(&b.join("contact.csv")),
    );
    assert_close(&cb, &c1, &[2, 3], 1e-8, &format!("{what} against 1 rank"));
    assert_close(&cb, &c1, &[4, 5], 1e-8, &format!("{what} against 1 rank"));
    let (ca, cb) = (
        read_csv(&a.join("contact.csv")),
        read_csv(&b.join("contact.csv")),
    );
    assert_close(&cb, &ca, &[2, 3], 1e-9, &what);
    assert_close(&cb, &ca, &[4, 5], 1e-9, &what);
    let (na, nb) = (
        read_csv(&a.join("nodes.csv")),
        read_csv(&b.join("nodes.csv")),
    );
    assert_close(&nb, &na, &[2, 3], 1e-9, &what);
    let (sa, sb) = (
        common::read_summary(&a.join("summary.json")),
        common::read_summary(&b.join("summary.json")),
    );
    let (ia, ib) = (
        common::num(&sa, "iterations"),
        common::num(&sb, "iterations"),
    );
    assert!((ia - ib).abs() <= 1.0, "{what}: {ia} against {ib} sweeps");
    assert_eq!(sb["interface_factor"], "mumps", "{what}");
    // MUMPS's work is the ranks', each on its leader subdomain; the first rank's path
    // does it all on subdomain 0.
    let per: Vec<f64> = sb["per_subdomain"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["interface_gflop"].as_f64().unwrap())
        .collect();
    let total: f64 = per.iter().sum();
    assert!(total > 0.0, "{what}: {per:?}");
    assert!((common::num(&sb, "interface_gflop") - total).abs() <= 1e-9 * total);
    // The factor holds at least the diagonal, at most the dense triangle.
    for s in [&sa, &sb] {
        let (e, n) = (
            common::num(s, "interface_factor_entries"),
            common::num(s, "interface_dofs"),
        );
        assert!(
            e >= n && e <= n * (n + 1.0) / 2.0,
            "{what}: {e} entries, {n} dofs"
        );
    }
    // Each sweep every rank sends at least its part of the sweep's sums (one
    // all-reduce of 14 or more values); on the rank0 path the others also send their
    // interface right-hand sides to the first.
    for s in [&sa, &sb] {
        for p in s["per_subdomain"].as_array().unwrap() {
            let sent = p["sent_bytes_per_sweep"].as_f64().unwrap();
            assert!(sent >= 8.0 * 14.0, "{what}: {sent} bytes per sweep");
        }
    }
}

#[test]
fn mumps_interface_equals_rank0_on_2_3_4_8_ranks_frictionless() {
    for np in [2, 3, 4, 8] {
        compare(&["--builtin", "hertz", "--level", "2"], np, 1);
    }
}

/// Coulomb friction, with retunes of r (each refactors the interface system), and
/// teams of 2 and 3 subdomains per rank.
#[test]
fn mumps_interface_equals_rank0_with_retunes_and_teams() {
    compare(&["--builtin", "block", "--level", "1"], 2, 2);
    compare(&["--builtin", "block", "--level", "1"], 3, 3);
    compare(&["--builtin", "block", "--level", "2"], 4, 1);
}

#[test]
fn mumps_interface_equals_rank0_on_32_ranks() {
    compare(&["--builtin", "block", "--level", "3"], 32, 1);
}

/// `--interface auto` (the default) keeps the first rank's factor below 16 subdomains
/// and takes MUMPS from 16 on, counting subdomains, not ranks.
#[test]
fn auto_takes_mumps_from_16_subdomains() {
    let dir = tempfile::tempdir().unwrap();
    for (np, k, expected) in [(4, 1, false), (4, 3, false), (16, 1, true), (4, 4, true)] {
        let out = dir.path().join(format!("auto-{np}x{k}"));
        let k = k.to_string();
        let o = common::mpirun(np, dir.path())
            .args(["--builtin", "block", "--level", "2"])
            .args(["--subdomains-per-rank", &k, "--threads", "1"])
            .args(["--quiet", "--out", out.to_str().unwrap()])
            .output()
            .expect("mpirun");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s = common::read_summary(&out.join("summary.json"));
        assert_eq!(
            s["interface_factor"] == "mumps",
            expected,
            "{np} x {k}: {}",
            s["interface_factor"]
        );
    }
}
