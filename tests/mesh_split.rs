//! Split directories (`contact-par split`, `--mesh-split`): a run from a split gives the
//! unsplit run's files byte for byte, on every layout of its parts over the ranks (ranks
//! dividing the parts), without the mesh file at hand and after a change of material;
//! bad or mismatched directories get one line on the first rank, exit code 2 and no
//! output files.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;
use tempfile::TempDir;

/// A directory holding the unstructured Coulomb case on a slope (Gmsh mesh, relative
/// path) as `case.toml`.
fn wedge_dir() -> TempDir {
    let dir = TempDir::new().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tolerance");
    std::fs::copy(data.join("wedge.toml"), dir.path().join("case.toml")).unwrap();
    std::fs::copy(data.join("wedge.msh"), dir.path().join("wedge.msh")).unwrap();
    dir
}

fn mpirun(np: usize, dir: &Path, args: &[&str]) -> Output {
    common::mpirun(np, dir)
        .args(args)
        .args(["--threads", "1", "--quiet"])
        .output()
        .expect("mpirun")
}

fn split(dir: &Path, args: &[&str]) -> Output {
    let session = common::session_dir();
    std::process::Command::new(common::BIN)
        .arg("split")
        .args(args)
        .current_dir(dir)
        .env("TMPDIR", session.path())
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .expect("contact-par split")
}

fn ok(o: &Output, what: &str) {
    assert!(
        o.status.success(),
        "{what}: exit {:?}\n{}\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The files a run writes for the whole mesh, which must match byte for byte (the
/// pictures too: they are drawn from the same rows).
const FILES: [&str; 5] = [
    "contact.csv",
    "nodes.csv",
    "history.csv",
    "contact.png",
    "convergence.png",
];

fn assert_same_files(a: &Path, b: &Path, what: &str) {
    for f in FILES {
        let (x, y) = (std::fs::read(a.join(f)), std::fs::read(b.join(f)));
        let (x, y) = (x.unwrap(), y.unwrap_or_else(|e| panic!("{what}: {f}: {e}")));
        assert!(x == y, "{what}: {f} differs from the unsplit run's");
    }
    let sweeps =
        |d: &Path| common::num(&common::read_summary(&d.join("summary.json")), "iterations");
    assert_eq!(sweeps(a), sweeps(b), "{what}: sweeps");
}

/// Runs on (ranks, subdomains per rank) layouts of 4 subdomains, unsplit and from one
/// split of 4 parts.
fn compare_layouts(dir: &Path, case: &[&str], split_dir: &str) {
    for (np, k) in [(1, 4), (2, 2), (4, 1)] {
        let k_arg = k.to_string();
        let plain = format!("plain-{np}");
        let from_split = format!("split-{np}");
        let mut args = case.to_vec();
        args.extend([
            "--nodes-csv",
            "--subdomains-per-rank",
            &k_arg,
            "--out",
            &plain,
        ]);
        ok(&mpirun(np, dir, &args), &format!("unsplit on {np} ranks"));
        let mut args = case.to_vec();
        args.extend([
            "--nodes-csv",
            "--mesh-split",
            split_dir,
            "--out",
            &from_split,
        ]);
        ok(&mpirun(np, dir, &args), &format!("split on {np} ranks"));
        assert_same_files(
            &dir.join(&plain),
            &dir.join(&from_split),
            &format!("{np} ranks x {k}"),
        );
        let s = common::read_summary(&dir.join(&from_split).join("summary.json"));
        assert_eq!(s["subdomains"], 4, "{np} ranks");
        assert_eq!(s["subdomains_per_rank"], k, "{np} ranks");
    }
}

#[test]
fn a_split_gmsh_case_runs_as_the_unsplit_one_on_1_2_and_4_ranks() {
    let dir = wedge_dir();
    let p = dir.path();
    ok(
        &split(p, &["case.toml", "--parts", "4", "--out", "parts"]),
        "split",
    );
    compare_layouts(p, &["case.toml"], "parts");
}

#[test]
fn a_split_builtin_case_runs_as_the_unsplit_one() {
    let dir = TempDir::new().unwrap();
    let p = dir.path();
    let case = ["--builtin", "block", "--level", "2"];
    let mut args = case.to_vec();
    args.extend(["--parts", "4", "--out", "parts"]);
    ok(&split(p, &args), "split");
    compare_layouts(p, &case, "parts");
}

/// A pin in a rigid hole, frictionless (its contact nodes turned into their frames in the
/// parts): from a split as unsplit, and a split of another hole refused.
#[test]
fn a_split_obstacle_case_runs_as_the_unsplit_one_and_keeps_its_obstacle() {
    let dir = TempDir::new().unwrap();
    let p = dir.path();
    let text = contact_par::case::builtin_case_text("hertz", 1).unwrap();
    let head = text.split("[contact]").next().unwrap();
    let hole = |radius: f64| {
        format!(
            "{head}[[contact]]\nslave = \"contact\"\nobstacle = {{ type = \"circle\", centre = [0.0, {radius:?}], radius = {radius:?}, body = \"inside\" }}\n"
        )
    };
    std::fs::write(p.join("case.toml"), hole(100.0)).unwrap();
    ok(
        &split(p, &["case.toml", "--parts", "4", "--out", "parts"]),
        "split",
    );
    compare_layouts(p, &["case.toml"], "parts");
    std::fs::write(p.join("other.toml"), hole(120.0)).unwrap();
    refused(
        p,
        2,
        &["other.toml", "--mesh-split", "parts"],
        "contact section differs",
    );
}

/// The split keeps what the parts are made of, not the material: a new Young's modulus,
/// friction coefficient and tolerance run from the old split, and the mesh file need not
/// be there.
#[test]
fn material_friction_and_solver_may_change_and_the_mesh_may_be_absent() {
    let dir = wedge_dir();
    let p = dir.path();
    ok(
        &split(p, &["case.toml", "--parts", "2", "--out", "parts"]),
        "split",
    );
    let text = std::fs::read_to_string(p.join("case.toml")).unwrap();
    let changed = text
        .replace("young = 3.0e9", "young = 1.0e9")
        .replace("coefficient = 0.9", "coefficient = 0.4");
    assert_ne!(text, changed);
    std::fs::write(p.join("case.toml"), changed).unwrap();
    let args = ["case.toml", "--tol", "1e-9", "--nodes-csv"];
    ok(
        &mpirun(2, p, &[&args[..], &["--out", "plain"]].concat()),
        "unsplit",
    );
    std::fs::remove_file(p.join("wedge.msh")).unwrap();
    let from_split = [&args[..], &["--mesh-split", "parts", "--out", "split"]].concat();
    ok(&mpirun(2, p, &from_split), "split without the mesh file");
    assert_same_files(&p.join("plain"), &p.join("split"), "changed material");
}

/// A run from `dir` that must fail: exit code 2, one line naming `expect` from the first
/// rank only, and no output file.
fn refused(dir: &Path, np: usize, args: &[&str], expect: &str) {
    let out = dir.join("refused-out");
    let _ = std::fs::remove_dir_all(&out);
    let o = mpirun(np, dir, &[args, &["--out", out.to_str().unwrap()]].concat());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{expect}: {stderr}");
    // mpirun adds notes of its own on a failed job.
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("contact-par"))
        .collect();
    assert_eq!(lines.len(), 1, "{expect}: one line expected:\n{stderr}");
    assert!(
        lines[0].starts_with("contact-par: error: ") && lines[0].contains(expect),
        "{expect}: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    for f in ["contact.csv", "summary.json", "nodes.csv"] {
        assert!(!out.join(f).exists(), "{expect}: {f} written");
    }
}

#[test]
fn bad_or_mismatched_split_directories_are_refused_with_one_line() {
    let dir = wedge_dir();
    let p = dir.path();
    ok(
        &split(p, &["case.toml", "--parts", "4", "--out", "parts"]),
        "split",
    );
    fn from(d: &str) -> Vec<&str> {
        vec!["case.toml", "--mesh-split", d]
    }

    refused(p, 2, &from("nowhere"), "cannot read the split's manifest");
    refused(p, 3, &from("parts"), "4 parts for 3 ranks");
    refused(
        p,
        2,
        &[&from("parts")[..], &["--subdomains-per-rank", "1"]].concat(),
        "--subdomains-per-rank 1",
    );

    // Another case: a traction changed, then another mesh file of the same name.
    let text = std::fs::read_to_string(p.join("case.toml")).unwrap();
    let other = text.replace("t = [2.0e5, 3.5e4]", "t = [2.5e5, 3.5e4]");
    std::fs::write(p.join("other.toml"), &other).unwrap();
    refused(
        p,
        2,
        &["other.toml", "--mesh-split", "parts"],
        "traction section differs",
    );
    let mut mesh = std::fs::read(p.join("wedge.msh")).unwrap();
    let original = mesh.clone();
    mesh.extend_from_slice(b"$Comment\nanother mesh\n$EndComment\n");
    std::fs::write(p.join("wedge.msh"), &mesh).unwrap();
    refused(p, 2, &from("parts"), "split from another wedge.msh");
    std::fs::write(p.join("wedge.msh"), &original).unwrap();

    // Damaged parts: one missing, one cut short, one from another split.
    let copy = |name: &str| -> PathBuf {
        let d = p.join(name);
        std::fs::create_dir_all(&d).unwrap();
        for e in std::fs::read_dir(p.join("parts")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), d.join(e.file_name())).unwrap();
        }
        d
    };
    let missing = copy("missing");
    std::fs::remove_file(missing.join("part-00001.bin")).unwrap();
    refused(
        p,
        2,
        &from("missing"),
        "part-00001.bin: cannot read part 1 of 4",
    );
    let cut = copy("cut");
    let bytes = std::fs::read(cut.join("part-00002.bin")).unwrap();
    std::fs::write(cut.join("part-00002.bin"), &bytes[..bytes.len() / 2]).unwrap();
    refused(p, 4, &from("cut"), "part-00002.bin: truncated or corrupt");
    ok(
        &split(p, &["case.toml", "--parts", "2", "--out", "two"]),
        "split in 2",
    );
    let mixed = copy("mixed");
    std::fs::copy(p.join("two/part-00000.bin"), mixed.join("part-00000.bin")).unwrap();
    refused(p, 1, &from("mixed"), "belongs to another split");
    let foreign = copy("foreign");
    std::fs::write(foreign.join("part-00003.bin"), b"not a part").unwrap();
    refused(
        p,
        4,
        &from("foreign"),
        "not a part file of contact-par split",
    );
}

#[test]
fn split_itself_refuses_bad_requests() {
    let dir = wedge_dir();
    let p = dir.path();
    // On several processes (they cut the mesh together): one message, from the first.
    let o = common::mpirun(2, p)
        .args(["split", "case.toml", "--parts", "100000", "--out", "parts"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    let ours = stderr.lines().filter(|l| l.starts_with("contact-par"));
    assert_eq!(ours.count(), 1, "{stderr}");
    assert!(stderr.contains("--parts 100000 for"), "{stderr}");
    assert!(!p.join("parts").exists());

    let o = split(p, &["case.toml", "--parts", "100000", "--out", "parts"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--parts 100000 for"), "{stderr}");
    assert!(!p.join("parts/split.json").exists());

    // A second split into fewer parts leaves no part of the first behind.
    ok(
        &split(p, &["case.toml", "--parts", "4", "--out", "parts"]),
        "4",
    );
    ok(
        &split(p, &["case.toml", "--parts", "2", "--out", "parts"]),
        "2",
    );
    let mut names: Vec<String> = std::fs::read_dir(p.join("parts"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["part-00000.bin", "part-00001.bin", "split.json"]);
}

/// Two bodies: a split keeps each triangle's body, so a run from it with new values of
/// the materials gives the unsplit run's files, and a case that assigns the bodies
/// otherwise (one lone [material]) is refused.
#[test]
fn bodies_are_in_the_parts_and_their_values_may_change() {
    let dir = TempDir::new().unwrap();
    let p = dir.path();
    let mesh = "bimaterial_v41_ascii.msh";
    std::fs::copy(common::gmsh_dir().join(mesh), p.join(mesh)).unwrap();
    let case = |lower: f64, upper: f64| {
        format!(
            "[mesh]\nfile = \"{mesh}\"\n[[material]]\ngroup = \"lower\"\nyoung = {lower:?}\npoisson = 0.3\n[[material]]\ngroup = \"upper\"\nyoung = {upper:?}\npoisson = 0.4\n[[dirichlet]]\ngroup = \"top\"\nux = 0.005\nuy = -0.02\n[contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, 0.0]\nobstacle_normal = [0.0, 1.0]\nfriction = \"coulomb\"\ncoefficient = 0.3\n"
        )
    };
    std::fs::write(p.join("case.toml"), case(1000.0, 300.0)).unwrap();
    ok(
        &split(p, &["case.toml", "--parts", "2", "--out", "parts"]),
        "split",
    );
    std::fs::write(p.join("case.toml"), case(2000.0, 100.0)).unwrap();
    let args = ["case.toml", "--nodes-csv"];
    ok(
        &mpirun(2, p, &[&args[..], &["--out", "plain"]].concat()),
        "unsplit",
    );
    let from_split = [&args[..], &["--mesh-split", "parts", "--out", "split"]].concat();
    ok(&mpirun(2, p, &from_split), "from the split");
    assert_same_files(&p.join("plain"), &p.join("split"), "new material values");
    let lone = std::fs::read_to_string(p.join("case.toml"))
        .unwrap()
        .replace(
            "[[material]]\ngroup = \"lower\"\nyoung = 2000.0\npoisson = 0.3\n[[material]]\ngroup = \"upper\"\nyoung = 100.0\npoisson = 0.4\n",
            "[material]\nyoung = 2000.0\npoisson = 0.3\n",
        );
    std::fs::write(p.join("lone.toml"), lone).unwrap();
    refused(
        p,
        2,
        &["lone.toml", "--mesh-split", "parts"],
        "material section differs",
    );
}
