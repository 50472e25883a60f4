//! The mesh cut by the first rank, by straight cuts (`--partitioner geometric`, the
//! default) or METIS (`--partitioner metis`), gives the answer of one rank on 2, 3 and
//! 4 ranks: a body against an obstacle with Coulomb friction (a Gmsh file) and two
//! bodies in contact (whose ties the cut must see), compared node by node (also two
//! subdomains per rank), with the contact conditions checked; the same parts run after
//! run (the outputs byte for byte); the straight cuts' parts as good as METIS's. Also
//! `contact-par split` under mpirun (the first process cuts and writes, once): runs
//! from its parts give the same answer.

mod common;
use common::*;
use std::path::Path;
use tempfile::TempDir;

/// A directory holding `case.toml` and `file` (copied from `from`).
fn case_dir(case: &str, from: &Path, file: &str) -> TempDir {
    let dir = TempDir::new().unwrap();
    std::fs::write(dir.path().join("case.toml"), case).unwrap();
    std::fs::copy(from, dir.path().join(file)).unwrap();
    dir
}

/// Runs `dir`'s case on `np` ranks into `out`; returns its read and partition lines.
fn run(dir: &Path, np: usize, out: &str, partitioner: &str) -> String {
    run_with(dir, np, out, partitioner, &[])
}

/// [`run`] with `extra` arguments.
fn run_with(dir: &Path, np: usize, out: &str, partitioner: &str, extra: &[&str]) -> String {
    let mut args = vec![
        "case.toml",
        "--out",
        out,
        "--nodes-csv",
        "--no-plots",
        "--partitioner",
        partitioner,
    ];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = run_on_ranks(dir, np, &args);
    assert_eq!(code, 0, "{np} ranks, {partitioner} {extra:?}: {stderr}");
    let line = |start: &str| {
        let line = stdout.lines().find(|l| l.starts_with(start));
        line.unwrap_or_else(|| panic!("no {start}line:\n{stdout}"))
            .to_string()
    };
    format!("{}\n{}", line("read "), line("partition "))
}

/// The edge cut of a partition line.
fn edge_cut(line: &str) -> usize {
    let after = line.split("edge cut ").nth(1).expect("an edge cut");
    let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().unwrap()
}

/// The edge cut of another partitioner (partition line `line`) against METIS's
/// (`metis`): the fixtures are small (tens of cut edges), so within a quarter plus two
/// edges.
fn near_metis(line: &str, metis: &str, what: &str) {
    let (other, met) = (edge_cut(line), edge_cut(metis));
    assert!(
        4 * other <= 5 * met + 8,
        "{what}: {other} edges cut, METIS {met}"
    );
}

/// The quarter disc on `mesh.msh`, Coulomb 0.2.
fn disc_case() -> String {
    quarter_disc_case_on("mesh.msh", "friction = \"coulomb\"\ncoefficient = 0.2")
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
    run(p, 1, "one", "metis");
    let one = read_contact(&p.join("one/contact.csv"));
    check_kkt(&one, law, 1e-6, &format!("{what}, one rank"));
    for np in 2..=4 {
        let metis = run(p, np, &format!("metis{np}"), "metis");
        assert!(metis.contains("(METIS)"), "{what}: {metis}");
        let rows = read_contact(&p.join(format!("metis{np}")).join("contact.csv"));
        assert_same_columns(
            &one,
            &rows,
            1e-8,
            &format!("{what}, 1 vs {np} ranks, METIS"),
        );
        check_kkt(&rows, law, 1e-6, &format!("{what}, {np} ranks"));
        // The straight cuts (the default): the same answer, the same bytes run after
        // run, an edge cut near METIS's.
        let (out, again) = (format!("geo{np}"), format!("geo{np}b"));
        let geo = run(p, np, &out, "geometric");
        assert!(geo.contains("(straight cuts)"), "{what}: {geo}");
        let rows = read_contact(&p.join(&out).join("contact.csv"));
        assert_same_columns(
            &one,
            &rows,
            1e-8,
            &format!("{what}, 1 vs {np} ranks, lines"),
        );
        run(p, np, &again, "auto");
        same_bytes(p, &out, &again);
        near_metis(&geo, &metis, &format!("{what}, {np} ranks, lines"));
        // More parts than ranks: 2 per rank.
        let k2 = format!("geo{np}k2");
        let args = [
            "case.toml",
            "--out",
            &k2,
            "--no-plots",
            "--subdomains-per-rank",
            "2",
        ];
        let (code, stdout, stderr) = run_on_ranks(p, np, &args);
        assert_eq!(code, 0, "{what}, {np} ranks x 2: {stderr}");
        let parts = format!("in {} parts", 2 * np);
        assert!(stdout.contains(&parts), "{what}: {stdout}");
        let rows = read_contact(&p.join(&k2).join("contact.csv"));
        assert_same_columns(&one, &rows, 1e-8, &format!("{what}, 1 vs {np} ranks x 2"));
    }
}

#[test]
fn a_body_on_an_obstacle_cut_by_the_first_rank_agrees_with_one_rank() {
    let case = disc_case();
    let mesh = gmsh_dir().join("quarter_disc_v41_ascii.msh");
    let dir = case_dir(&case, &mesh, "mesh.msh");
    check(dir.path(), Law::Coulomb(0.2), "quarter disc");
}

/// The upper block dragged sideways on the lower one, held along x by Coulomb friction
/// alone (as in tests/bodies.rs): partial slip, so that every column moves.
#[test]
fn two_bodies_in_contact_cut_by_the_first_rank_agree_with_one_rank() {
    let dir = case_dir(
        &dragged_blocks(),
        &bodies_dir().join("blocks.msh"),
        "blocks.msh",
    );
    check(dir.path(), Law::Coulomb(0.3), "two blocks");
}

fn dragged_blocks() -> String {
    let case = std::fs::read_to_string(bodies_dir().join("blocks.toml")).unwrap();
    let case = case
        .replace("[[dirichlet]]\ngroup = \"upper_left\"\nux = 0.0\n\n", "")
        .replace("t = [0.0, -10.0]", "t = [2.5, -10.0]")
        .replace(
            "friction = \"none\"",
            "friction = \"coulomb\"\ncoefficient = 0.3\n\n[solver]\ntol = 1e-10",
        );
    assert!(case.contains("coefficient = 0.3") && !case.contains("upper_left"));
    case
}

/// `mpirun -n 3 contact-par split` (the first process cuts and writes; one line, from
/// it) into 3, 4 and 6 parts: runs from each split agree with the unsplit run on every
/// rank count that divides its parts; on the quarter disc against a line and on a disc
/// pressed on a block (two bodies: mortar rows, whose masters are ghosts where the cut
/// runs through the contact).
#[test]
fn a_split_under_mpirun_gives_the_same_answer() {
    let bodies = bodies_dir();
    let two_bodies = std::fs::read_to_string(bodies.join("disc.toml"))
        .unwrap()
        .replace("\"disc.msh\"", "\"mesh.msh\"");
    split_on_three_ranks(&disc_case(), &gmsh_dir().join("quarter_disc_v41_ascii.msh"));
    split_on_three_ranks(&two_bodies, &bodies.join("disc.msh"));
}

fn split_on_three_ranks(case: &str, mesh: &Path) {
    let dir = case_dir(case, mesh, "mesh.msh");
    let p = dir.path();
    run(p, 1, "one", "metis");
    let one = read_contact(&p.join("one/contact.csv"));
    for (parts, ranks) in [(3, &[1, 3][..]), (6, &[2, 6][..]), (4, &[1, 4][..])] {
        let out = format!("parts{parts}");
        let n = parts.to_string();
        let split = ["split", "case.toml", "--parts", &n, "--out", &out];
        let (code, stdout, stderr) = run_on_ranks(p, 3, &split);
        assert_eq!(code, 0, "{stderr}");
        let lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with("split:")).collect();
        assert_eq!(lines.len(), 1, "{stdout}");
        assert!(
            lines[0].contains(&format!("into {parts} parts (straight cuts")),
            "{stdout}"
        );
        for &np in ranks {
            let run_out = format!("from{parts}_{np}");
            let args = [
                "case.toml",
                "--out",
                &run_out,
                "--no-plots",
                "--mesh-split",
                &out,
            ];
            let (code, _, stderr) = run_on_ranks(p, np, &args);
            assert_eq!(code, 0, "{parts} parts, {np} ranks: {stderr}");
            let rows = read_contact(&p.join(&run_out).join("contact.csv"));
            let what = format!("split of {parts}, {np} ranks");
            assert_same_columns(&one, &rows, 1e-8, &what);
        }
    }
}
