//! The mesh cut by PT-Scotch on every rank (`--partitioner ptscotch`) gives the answer
//! of one rank, on 2, 3 and 4 ranks: a body against an obstacle with Coulomb friction
//! (a Gmsh file) and two bodies in contact (whose ties the cut must see), compared node
//! by node (also two subdomains per rank), with the contact conditions checked; the
//! same parts run after run (the outputs byte for byte); and its parts as good as the
//! first rank's METIS cut. Also `contact-par split` on several ranks, which cut
//! together: runs from its parts give the same answer.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use tempfile::TempDir;

fn bodies_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bodies")
}

/// A directory holding `case.toml` and `file` (copied from `from`).
fn case_dir(case: &str, from: &Path, file: &str) -> TempDir {
    let dir = TempDir::new().unwrap();
    std::fs::write(dir.path().join("case.toml"), case).unwrap();
    std::fs::copy(from, dir.path().join(file)).unwrap();
    dir
}

/// Runs `dir`'s case on `np` ranks into `out`; returns its partition line.
fn run(dir: &Path, np: usize, out: &str, partitioner: &str) -> String {
    let args = [
        "case.toml",
        "--out",
        out,
        "--nodes-csv",
        "--no-plots",
        "--partitioner",
        partitioner,
    ];
    let (code, stdout, stderr) = run_on_ranks(dir, np, &args);
    assert_eq!(code, 0, "{np} ranks, {partitioner}: {stderr}");
    let line = stdout.lines().find(|l| l.starts_with("partition "));
    line.unwrap_or_else(|| panic!("no partition line:\n{stdout}"))
        .to_string()
}

/// The edge cut of a partition line.
fn edge_cut(line: &str) -> usize {
    let after = line.split("edge cut ").nth(1).expect("an edge cut");
    let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().unwrap()
}

fn same_bytes(dir: &Path, a: &str, b: &str) {
    for f in ["contact.csv", "nodes.csv"] {
        let x = std::fs::read(dir.join(a).join(f)).unwrap();
        let y = std::fs::read(dir.join(b).join(f)).unwrap();
        assert!(x == y, "{f} differs between {a} and {b}");
    }
}

fn check(dir: &Path, law: Law, what: &str) {
    let p = dir;
    run(p, 1, "one", "ptscotch");
    let one = read_contact(&p.join("one/contact.csv"));
    check_kkt(&one, law, 1e-6, &format!("{what}, one rank"));
    for np in 2..=4 {
        let (out, again) = (format!("pts{np}"), format!("pts{np}b"));
        let line = run(p, np, &out, "ptscotch");
        assert!(
            line.contains(&format!("(PT-Scotch on {np} ranks)")),
            "{what}: {line}"
        );
        let rows = read_contact(&p.join(&out).join("contact.csv"));
        assert_same_columns(&one, &rows, 1e-8, &format!("{what}, 1 vs {np} ranks"));
        check_kkt(&rows, law, 1e-6, &format!("{what}, {np} ranks"));
        run(p, np, &again, "ptscotch");
        same_bytes(p, &out, &again);
        let metis = run(p, np, &format!("metis{np}"), "metis");
        assert!(metis.contains("(the first rank)"), "{what}: {metis}");
        // More parts than ranks: PT-Scotch cuts 2 per rank.
        let k2 = format!("pts{np}k2");
        let args = [
            "case.toml",
            "--out",
            &k2,
            "--no-plots",
            "--partitioner",
            "ptscotch",
            "--subdomains-per-rank",
            "2",
        ];
        let (code, stdout, stderr) = run_on_ranks(p, np, &args);
        assert_eq!(code, 0, "{what}, {np} ranks x 2: {stderr}");
        let parts = format!("in {} parts", 2 * np);
        assert!(stdout.contains(&parts), "{what}: {stdout}");
        let rows = read_contact(&p.join(&k2).join("contact.csv"));
        assert_same_columns(&one, &rows, 1e-8, &format!("{what}, 1 vs {np} ranks x 2"));
        // The fixtures are small (tens of cut edges): within a quarter plus two edges.
        let (pts, met) = (edge_cut(&line), edge_cut(&metis));
        assert!(
            4 * pts <= 5 * met + 8,
            "{what}, {np} ranks: PT-Scotch cuts {pts} edges, METIS {met}"
        );
    }
}

#[test]
fn a_body_on_an_obstacle_cut_by_every_rank_agrees_with_one_rank() {
    let case = quarter_disc_case_on("mesh.msh", "friction = \"coulomb\"\ncoefficient = 0.2");
    let mesh = gmsh_dir().join("quarter_disc_v41_ascii.msh");
    let dir = case_dir(&case, &mesh, "mesh.msh");
    check(dir.path(), Law::Coulomb(0.2), "quarter disc");
}

/// The upper block dragged sideways on the lower one, held along x by Coulomb friction
/// alone (as in tests/bodies.rs): partial slip, so that every column moves.
#[test]
fn two_bodies_in_contact_cut_by_every_rank_agree_with_one_rank() {
    let case = std::fs::read_to_string(bodies_dir().join("blocks.toml")).unwrap();
    let case = case
        .replace("[[dirichlet]]\ngroup = \"upper_left\"\nux = 0.0\n\n", "")
        .replace("t = [0.0, -10.0]", "t = [2.5, -10.0]")
        .replace(
            "friction = \"none\"",
            "friction = \"coulomb\"\ncoefficient = 0.3\n\n[solver]\ntol = 1e-10",
        );
    assert!(case.contains("coefficient = 0.3") && !case.contains("upper_left"));
    let dir = case_dir(&case, &bodies_dir().join("blocks.msh"), "blocks.msh");
    check(dir.path(), Law::Coulomb(0.3), "two blocks");
}

/// `mpirun -n 3 contact-par split --partitioner ptscotch` cuts on its 3 ranks (one line,
/// from the first); runs from the split on 1 and 3 ranks agree with the unsplit run.
#[test]
fn a_split_cut_by_every_rank_gives_the_same_answer() {
    let case = quarter_disc_case_on("mesh.msh", "friction = \"coulomb\"\ncoefficient = 0.2");
    let mesh = gmsh_dir().join("quarter_disc_v41_ascii.msh");
    let dir = case_dir(&case, &mesh, "mesh.msh");
    let p = dir.path();
    let split = [
        "split",
        "case.toml",
        "--parts",
        "3",
        "--out",
        "parts",
        "--partitioner",
        "ptscotch",
    ];
    let (code, stdout, stderr) = run_on_ranks(p, 3, &split);
    assert_eq!(code, 0, "{stderr}");
    let lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with("split:")).collect();
    assert_eq!(lines.len(), 1, "{stdout}");
    assert!(lines[0].contains("cut by PT-Scotch on 3 ranks"), "{stdout}");
    run(p, 1, "one", "metis");
    let one = read_contact(&p.join("one/contact.csv"));
    for np in [1, 3] {
        let out = format!("from{np}");
        let args = [
            "case.toml",
            "--out",
            &out,
            "--no-plots",
            "--mesh-split",
            "parts",
        ];
        let (code, _, stderr) = run_on_ranks(p, np, &args);
        assert_eq!(code, 0, "{np} ranks: {stderr}");
        let rows = read_contact(&p.join(&out).join("contact.csv"));
        assert_same_columns(&one, &rows, 1e-8, &format!("split of 3, {np} ranks"));
    }
}
