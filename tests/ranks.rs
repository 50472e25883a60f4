//! The answer must not depend on the number of ranks: every built-in case and friction
//! law on 1, 2, 3 and 4 ranks (oversubscribed), and on 3 and 4 subdomains run as
//! threads of 1 and 2 ranks (`--subdomains-per-rank`), compared node by node. Also the
//! condensed sweep against the full sparse solve, and clean failures under mpirun.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

/// Iterations, contact.csv rows and nodes.csv rows of one run.
type RunResult = (i64, Vec<Vec<f64>>, Vec<Vec<f64>>);

fn mpirun(np: usize, args: &[&str], dir: &Path) -> Output {
    common::mpirun(np, dir)
        .args(args)
        .output()
        .expect("mpirun must be installed (openmpi-bin)")
}

/// The lines of `stderr` that contact-par wrote (not mpirun's).
fn our_lines(stderr: &str) -> Vec<&str> {
    stderr
        .lines()
        .filter(|l| l.starts_with("contact-par:"))
        .collect()
}

fn read_csv(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

/// The built-in case `name` at `level` with its friction law replaced by `friction`
/// (TOML lines for the [contact] table), written to `dir/case.toml`.
fn case_file(dir: &Path, name: &str, level: u32, friction: &str, extra: &str) -> PathBuf {
    let text = common::builtin_with_friction(name, level, friction) + extra;
    let path = dir.join("case.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// `case` on `np` ranks of `k` subdomains each, writing nodes.csv too into
/// `dir/out{np}x{k}`: that directory and mpirun's output.
fn run_layout(case: &Path, np: usize, k: usize, dir: &Path) -> (PathBuf, Output) {
    let out = dir.join(format!("out{np}x{k}"));
    let o = mpirun(
        np,
        &[
            case.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--nodes-csv",
            "--quiet",
            "--subdomains-per-rank",
            &k.to_string(),
        ],
        dir,
    );
    (out, o)
}

/// Largest difference over the given columns, relative to `scale`.
fn max_diff(a: &[Vec<f64>], b: &[Vec<f64>], cols: &[usize], scale: f64) -> f64 {
    assert_eq!(a.len(), b.len(), "row counts differ");
    let mut worst: f64 = 0.0;
    for (ra, rb) in a.iter().zip(b) {
        for &c in cols {
            worst = worst.max((ra[c] - rb[c]).abs() / scale);
        }
    }
    worst
}

fn max_abs(rows: &[Vec<f64>], cols: &[usize]) -> f64 {
    rows.iter()
        .flat_map(|r| cols.iter().map(move |&c| r[c].abs()))
        .fold(0.0, f64::max)
        .max(1e-300)
}

/// Compares two runs: coordinates to 1e-14 of their size, displacements (nodes.csv ux,
/// uy and contact.csv u_n, u_t) to `tol` of the largest displacement, tractions
/// (contact.csv p_n, p_t) to `tol` of the largest pressure.
fn compare(
    c1: &[Vec<f64>],
    n1: &[Vec<f64>],
    c2: &[Vec<f64>],
    n2: &[Vec<f64>],
    tol: f64,
    what: &str,
) {
    let xs = max_abs(n1, &[0, 1]);
    let us = max_abs(n1, &[2, 3]);
    let ps = max_abs(c1, &[4]);
    let d = max_diff(n1, n2, &[0, 1], xs);
    assert!(d < 1e-14, "{what}: node coordinates differ by {d:e}");
    let d = max_diff(c1, c2, &[0, 1, 6], xs);
    assert!(
        d < 1e-14,
        "{what}: contact coordinates or gaps differ by {d:e}"
    );
    let d = max_diff(n1, n2, &[2, 3], us);
    assert!(d < tol, "{what}: displacements differ by {d:e}");
    let d = max_diff(c1, c2, &[2, 3], us);
    assert!(d < tol, "{what}: u_n, u_t differ by {d:e}");
    let d = max_diff(c1, c2, &[4, 5], ps);
    assert!(d < tol, "{what}: p_n, p_t differ by {d:e}");
}

/// (ranks, subdomains per rank) of every run: one subdomain per rank on 1 to 4 ranks,
/// then several per rank (threads of one process, and threads of two ranks).
const LAYOUTS: [(usize, usize); 6] = [(1, 1), (2, 1), (3, 1), (4, 1), (1, 3), (2, 2)];

/// Runs the case in every [`LAYOUTS`] and checks iteration counts (+-1), contact.csv and
/// nodes.csv (1e-8 relative per column; u_n is compared through the gap column's scale
/// because it sits at round-off level on flat contact).
fn check_rank_independence(name: &str, level: u32, friction: &str) {
    check_rank_independence_with(name, level, friction, "");
}

/// As [`check_rank_independence`], with extra `[solver]` lines.
fn check_rank_independence_with(name: &str, level: u32, friction: &str, solver: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let case = case_file(
        tmp.path(),
        name,
        level,
        friction,
        &format!("[solver]\ntol = 1e-10\n{solver}"),
    );
    let mut reference: Option<RunResult> = None;
    for (np, k) in LAYOUTS {
        let parts = np * k;
        let (out, o) = run_layout(&case, np, k, tmp.path());
        assert!(
            o.status.success(),
            "{name} {friction} on {np} ranks x {k} subdomains: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let s = summary(&out);
        assert_eq!(s["ranks"], np as i64);
        assert_eq!(s["subdomains"], parts as i64);
        assert_eq!(s["converged"], true);
        assert_eq!(
            s["peak_memory_bytes_per_rank"].as_array().unwrap().len(),
            np
        );
        // Every subdomain reports the work of its factorization, at least one square per
        // column, and the rank that ran it.
        let per_subdomain = s["per_subdomain"].as_array().unwrap();
        assert_eq!(per_subdomain.len(), parts);
        for (i, r) in per_subdomain.iter().enumerate() {
            assert_eq!(r["subdomain"], i as i64);
            assert_eq!(r["rank"], (i / k) as i64);
            let flops = r["factor_gflop"].as_f64().unwrap() * 1e9;
            let nodes = r["nodes"].as_f64().unwrap();
            assert!(
                flops.is_finite() && flops >= nodes,
                "{name} {friction}: {r}"
            );
        }
        // Every built-in case settles and retunes r: the test covers the refactored
        // dense blocks and interface system on every rank count.
        assert!(
            s["r_retunes"].as_u64().unwrap() >= 1,
            "{name} {friction}: {s}"
        );
        let iters = s["iterations"].as_i64().unwrap();
        let contact = read_csv(&out.join("contact.csv"));
        let nodes = read_csv(&out.join("nodes.csv"));
        assert!(!contact.is_empty() && !nodes.is_empty());
        match &reference {
            None => reference = Some((iters, contact, nodes)),
            Some((it1, c1, n1)) => {
                assert!(
                    (iters - it1).abs() <= 1,
                    "{name} {friction}: {iters} iterations on {np} ranks x {k}, {it1} on 1"
                );
                compare(
                    c1,
                    n1,
                    &contact,
                    &nodes,
                    1e-8,
                    &format!("{name} {friction} on {np} ranks x {k} subdomains"),
                );
            }
        }
        // The .pvtu index lists one .vtu file per subdomain (these meshes are far below
        // the size at which a piece is split), every one on disk.
        let pvtu = std::fs::read_to_string(out.join("solution.pvtu")).unwrap();
        let sources: Vec<&str> = pvtu
            .split("Source=\"")
            .skip(1)
            .map(|s| s.split('"').next().unwrap())
            .collect();
        let expected: Vec<String> = (0..parts).map(|r| format!("solution_{r}_0.vtu")).collect();
        assert_eq!(sources, expected);
        for s in sources {
            assert!(out.join(s).exists(), "{s}");
        }
    }
}

#[test]
fn hertz_frictionless_1_to_4_ranks() {
    check_rank_independence("hertz", 0, "friction = \"none\"");
}

#[test]
fn hertz_tresca_1_to_4_ranks() {
    check_rank_independence("hertz", 0, "friction = \"tresca\"\nthreshold = 500.0");
}

#[test]
fn hertz_coulomb_1_to_4_ranks() {
    check_rank_independence("hertz", 0, "friction = \"coulomb\"\ncoefficient = 0.2");
}

/// Every node pressed onto the foundation at zero gap: the automatic r is retuned
/// during the loop (a refactorization of every rank's dense block and of the interface
/// system), and the answer still does not depend on the rank count.
#[test]
fn block_frictionless_1_to_4_ranks() {
    check_rank_independence("block", 0, "friction = \"none\"");
}

#[test]
fn block_tresca_1_to_4_ranks() {
    check_rank_independence("block", 0, "friction = \"tresca\"\nthreshold = 20.0");
}

#[test]
fn block_coulomb_1_to_4_ranks() {
    check_rank_independence("block", 0, "friction = \"coulomb\"\ncoefficient = 0.3");
}

#[test]
fn block_coulomb_outer_1_to_4_ranks() {
    let f = "friction = \"coulomb\"\ncoefficient = 0.3";
    check_rank_independence_with("block", 0, f, "coulomb = \"outer\"\n");
}

#[test]
fn block_flat_1_to_4_ranks() {
    check_rank_independence("block_flat", 0, "friction = \"none\"");
}

/// The condensed sweep and the full sparse solve give the same iterates: same
/// iteration count and the same fields to round-off, for each law.
#[test]
fn condensed_sweep_equals_full_solve() {
    for (name, friction) in [
        ("hertz", "friction = \"none\""),
        // r is retuned during the loop: both paths refactor.
        ("block", "friction = \"none\""),
        ("block", "friction = \"tresca\"\nthreshold = 20.0"),
        ("block", "friction = \"coulomb\"\ncoefficient = 0.3"),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        // Tight enough that a stop one sweep apart is far below the 1e-9 comparison.
        let case = case_file(tmp.path(), name, 0, friction, "[solver]\ntol = 1e-11\n");
        let mut runs = Vec::new();
        for linear in ["condensed", "full"] {
            let out = tmp.path().join(linear);
            let o = mpirun(
                1,
                &[
                    case.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                    "--nodes-csv",
                    "--quiet",
                    "--linear",
                    linear,
                ],
                tmp.path(),
            );
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            runs.push((
                summary(&out)["iterations"].as_i64().unwrap(),
                read_csv(&out.join("contact.csv")),
                read_csv(&out.join("nodes.csv")),
            ));
        }
        assert!(
            (runs[0].0 - runs[1].0).abs() <= 1,
            "{name}: {} vs {} iterations",
            runs[0].0,
            runs[1].0
        );
        compare(
            &runs[0].1,
            &runs[0].2,
            &runs[1].1,
            &runs[1].2,
            1e-9,
            &format!("{name} {friction} condensed vs full"),
        );
    }
}

/// A bad case under mpirun: one error line (from one rank), exit code 2, no hang, no
/// output files.
#[test]
fn bad_input_on_four_ranks_fails_once_and_cleanly() {
    let tmp = tempfile::tempdir().unwrap();
    let text = contact_par::case::builtin_case_text("block", 0)
        .unwrap()
        .replace("poisson = 0.33", "poison = 0.33");
    std::fs::write(tmp.path().join("bad.toml"), text).unwrap();
    let start = std::time::Instant::now();
    let o = mpirun(4, &["bad.toml", "--out", "res"], tmp.path());
    assert!(start.elapsed().as_secs() < 60, "took {:?}", start.elapsed());
    let err = String::from_utf8_lossy(&o.stderr);
    let ours = our_lines(&err);
    assert_eq!(ours.len(), 1, "{err}");
    assert!(
        ours[0].contains("bad.toml") && ours[0].contains("poison"),
        "{}",
        ours[0]
    );
    assert!(String::from_utf8_lossy(&o.stdout).trim().is_empty());
    assert!(!tmp.path().join("res").exists());
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn more_ranks_than_triangles_is_an_input_error() {
    let tmp = tempfile::tempdir().unwrap();
    // A unit square of two triangles (MSH 2.2).
    let msh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n1 1 \"bottom\"\n1 2 \"top\"\n$EndPhysicalNames\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n$EndNodes\n$Elements\n4\n1 1 2 1 1 1 2\n2 1 2 2 2 3 4\n3 2 2 3 3 1 2 3\n4 2 2 3 3 1 3 4\n$EndElements\n";
    std::fs::write(tmp.path().join("two.msh"), msh).unwrap();
    let case = "[mesh]\nfile = \"two.msh\"\n[material]\nyoung = 1.0\npoisson = 0.3\n[[dirichlet]]\ngroup = \"top\"\nuy = -0.01\nux = 0.0\n[contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, 0.0]\nobstacle_normal = [0.0, 1.0]\n";
    std::fs::write(tmp.path().join("c.toml"), case).unwrap();
    let ok = mpirun(2, &["c.toml", "--out", "ok", "--quiet"], tmp.path());
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let o = mpirun(3, &["c.toml", "--out", "res"], tmp.path());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("3 ranks for 2 triangles"), "{err}");
    assert!(!tmp.path().join("res").exists());
}

/// A failure after the subdomains have started on their threads (here the output
/// directory, which only the end of the run creates) ends every rank and thread: one
/// line, the output error's exit code, no hang.
#[test]
fn failure_inside_the_threads_of_two_ranks_is_reported_once() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("blocker"), "a file, not a directory").unwrap();
    let start = std::time::Instant::now();
    let o = mpirun(
        2,
        &[
            "--builtin",
            "block",
            "--level",
            "1",
            "--subdomains-per-rank",
            "2",
            "--out",
            "blocker/res",
            "--quiet",
        ],
        tmp.path(),
    );
    assert!(start.elapsed().as_secs() < 60, "took {:?}", start.elapsed());
    let err = String::from_utf8_lossy(&o.stderr);
    let ours = our_lines(&err);
    assert_eq!(ours.len(), 1, "{err}");
    assert!(ours[0].contains("blocker/res"), "{}", ours[0]);
    assert_eq!(o.status.code(), Some(5), "{err}");
}

/// The default number of subdomains per rank follows the rank's own threads (not the
/// threads the first rank borrows for the set-up): one subdomain per thread on a mesh
/// large enough, one per rank with one thread each.
#[test]
fn default_subdomains_follow_the_threads_of_each_rank() {
    let tmp = tempfile::tempdir().unwrap();
    // Hertz level 2: 37440 triangles, over 5000 per subdomain in every layout below.
    for (np, threads, expected) in [(1, 1, 1), (1, 2, 2), (1, 3, 3), (2, 1, 2), (2, 2, 4)] {
        let out = format!("o{np}x{threads}");
        let t = threads.to_string();
        let o = mpirun(
            np,
            &[
                "--builtin",
                "hertz",
                "--level",
                "2",
                "--threads",
                &t,
                "--out",
                &out,
                "--quiet",
            ],
            tmp.path(),
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s = summary(&tmp.path().join(&out));
        assert_eq!(s["threads"], threads as i64);
        assert_eq!(
            s["subdomains"], expected as i64,
            "{np} ranks x {threads} threads"
        );
        assert_eq!(s["subdomains_per_rank"], (expected / np) as i64);
    }
}

/// Ranks bound to a core each (`--bind-to core`, Open MPI's default for two ranks): the
/// first rank's read and partition run on the other rank's core too while that rank
/// sleeps, as with unbound ranks, unless told not to; the answer is the same.
#[test]
fn ranks_bound_to_their_cores_lend_them_to_the_first_ranks_start() {
    let tmp = tempfile::tempdir().unwrap();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut answers = Vec::new();
    // The last run keeps every rank to its own threads (`--borrow-idle-cores false`).
    let runs = [
        ("core:overload-allowed", "bound", "true", cores.min(2)),
        ("none", "unbound", "true", cores.min(2)),
        ("none", "own", "false", 1),
    ];
    for (bind, out, borrow, threads) in runs {
        let o = common::mpirun_with(2, &["--bind-to", bind], tmp.path())
            .args(["--builtin", "block", "--level", "2", "--threads", "1"])
            .args([
                "--borrow-idle-cores",
                borrow,
                "--out",
                out,
                "--quiet",
                "--no-plots",
            ])
            .output()
            .expect("mpirun must be installed (openmpi-bin)");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s = summary(&tmp.path().join(out));
        assert_eq!(s["threads"], 1);
        assert_eq!(
            s["idle_core_threads"], threads as i64,
            "--bind-to {bind}, {out}"
        );
        answers.push(read_csv(&tmp.path().join(out).join("contact.csv")));
    }
    assert!(answers.iter().all(|a| *a == answers[0]));
}

/// Many subdomains: the interface system is factored as a sparse matrix (each
/// subdomain's piece touches a few neighbours' interface dofs only), and the answer is
/// still that of one rank.
#[test]
fn many_subdomains_factor_the_interface_sparsely_with_the_same_answer() {
    let tmp = tempfile::tempdir().unwrap();
    let case = case_file(
        tmp.path(),
        "block",
        2,
        "friction = \"coulomb\"\ncoefficient = 0.3\n",
        "[solver]\ntol = 1e-10\n",
    );
    let mut runs = Vec::new();
    for (np, k) in [(1, 1), (2, 6)] {
        let (out, o) = run_layout(&case, np, k, tmp.path());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s = summary(&out);
        assert_eq!(s["converged"], true);
        runs.push((
            s,
            read_csv(&out.join("contact.csv")),
            read_csv(&out.join("nodes.csv")),
        ));
    }
    let (s12, c12, n12) = &runs[1];
    assert_eq!(s12["subdomains"], 12);
    assert_eq!(s12["interface_factor"], "sparse", "{s12}");
    let n = s12["interface_dofs"].as_f64().unwrap();
    let gflop = s12["interface_gflop"].as_f64().unwrap();
    assert!(
        gflop > 0.0 && gflop * 1e9 <= 0.5 * n * n * n / 3.0 * 1.01,
        "interface work {gflop} Gflop for {n} dofs"
    );
    assert!(runs[0].0["interface_factor"].is_null());
    compare(
        &runs[0].1,
        &runs[0].2,
        c12,
        n12,
        1e-8,
        "block coulomb on 2 ranks x 6 subdomains",
    );
}
