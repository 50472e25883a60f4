//! A Gmsh file read by every rank (each parses a share of its nodes and elements, the
//! first puts them together) gives the mesh the first rank reads alone: the same
//! contact.csv and nodes.csv byte for byte on 2 to 4 ranks, ASCII and binary; a file the
//! shares cannot take falls back to the first rank's reading; a malformed file gives
//! the first rank's one-line error, exit code 2, on any number of ranks, also where the
//! ranks cut the mesh from their shares first (`--partitioner ptscotch`).

mod common;
use common::*;
use std::path::Path;
use tempfile::TempDir;

/// The quarter disc of the fixtures pressed on y = 0 with Coulomb 0.2, on `mesh.msh`.
fn disc_case() -> String {
    quarter_disc_case_on("mesh.msh", "friction = \"coulomb\"\ncoefficient = 0.2")
}

/// A directory holding `case.toml` and its mesh `mesh.msh` (the given bytes).
fn case_dir(case: &str, mesh: &[u8]) -> TempDir {
    let dir = TempDir::new().unwrap();
    std::fs::write(dir.path().join("case.toml"), case).unwrap();
    std::fs::write(dir.path().join("mesh.msh"), mesh).unwrap();
    dir
}

fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(gmsh_dir().join(name)).unwrap()
}

/// Runs the case of `dir` on `np` ranks into `out`; returns its read line.
fn run(dir: &Path, np: usize, out: &str, extra: &[&str]) -> String {
    let mut args = vec!["case.toml", "--out", out, "--nodes-csv", "--no-plots"];
    args.extend_from_slice(extra);
    let (code, stdout, stderr) = run_on_ranks(dir, np, &args);
    assert_eq!(code, 0, "{np} ranks {extra:?}: {stderr}");
    let line = stdout.lines().find(|l| l.starts_with("read "));
    line.unwrap_or_else(|| panic!("no read line:\n{stdout}"))
        .to_string()
}

fn same_outputs(dir: &Path, a: &str, b: &str, what: &str) {
    for f in ["contact.csv", "nodes.csv"] {
        let x = std::fs::read(dir.join(a).join(f)).unwrap();
        let y = std::fs::read(dir.join(b).join(f)).unwrap();
        assert!(x == y, "{what}: {f} differs between {a} and {b}");
    }
}

#[test]
fn every_rank_reading_gives_the_first_ranks_mesh_ascii_and_binary() {
    let (disc, rect) = (disc_case(), rect_case_on("mesh.msh"));
    for (case, mesh) in [
        (disc.as_str(), "quarter_disc_v41_ascii.msh"),
        (rect.as_str(), "rect_v41_binary.msh"),
        (rect.as_str(), "rect_v41_ascii.msh"),
    ] {
        let dir = case_dir(case, &fixture(mesh));
        let p = dir.path();
        let line = run(p, 1, "one", &[]);
        assert!(!line.contains("ranks"), "{mesh}, one rank: {line}");
        for np in 2..=4 {
            let (shared, alone) = (format!("shared{np}"), format!("alone{np}"));
            let line = run(p, np, &shared, &["--mesh-read", "shared"]);
            assert!(
                line.contains(&format!("mesh read on {np} ranks")),
                "{mesh}: {line}"
            );
            let line = run(p, np, &alone, &["--mesh-read", "first"]);
            assert!(!line.contains("read on"), "{mesh}, first rank: {line}");
            // On one node the default is the first rank's reading.
            let line = run(p, np, &format!("auto{np}"), &[]);
            assert!(
                !line.contains("read on"),
                "{mesh}, auto on one node: {line}"
            );
            same_outputs(p, &shared, &alone, &format!("{mesh} on {np} ranks"));
        }
    }
}

/// The last triangle of the disc's `$Elements` written over two lines: the careful
/// reading takes it (tokens are tokens), the shares (a record a line) do not.
fn disc_with_a_record_over_two_lines() -> Vec<u8> {
    let text = String::from_utf8(fixture("quarter_disc_v41_ascii.msh")).unwrap();
    let end = text.find("$EndElements").unwrap();
    let last = text[..end - 1].rfind('\n').unwrap() + 1;
    let line = &text[last..end];
    let split = line.trim_end().replacen(' ', "\n", 1) + "\n";
    format!("{}{split}{}", &text[..last], &text[end..]).into_bytes()
}

#[test]
fn a_file_the_shares_cannot_take_is_read_by_the_first_rank_alone() {
    let dir = case_dir(&disc_case(), &disc_with_a_record_over_two_lines());
    let p = dir.path();
    let line = run(p, 3, "fallback", &["--mesh-read", "shared"]);
    assert!(line.contains("read by the first rank alone"), "{line}");
    run(p, 3, "alone", &["--mesh-read", "first"]);
    same_outputs(p, "fallback", "alone", "a record over two lines");
    // And the same mesh as the fixture read by the shares.
    let plain = case_dir(&disc_case(), &fixture("quarter_disc_v41_ascii.msh"));
    run(plain.path(), 3, "shared", &["--mesh-read", "shared"]);
    for f in ["contact.csv", "nodes.csv"] {
        let x = std::fs::read(p.join("fallback").join(f)).unwrap();
        let y = std::fs::read(plain.path().join("shared").join(f)).unwrap();
        assert!(x == y, "{f}: the fallback read another mesh");
    }
}

/// The error lines of a run that must fail with exit code 2 (`partitioner`: with
/// `ptscotch` the ranks also cut the mesh from their shares before the first rank
/// finds the fault).
fn refused(dir: &Path, np: usize, partitioner: &str) -> Vec<String> {
    let out = dir.join(format!("refused{np}"));
    let args = ["case.toml", "--out", out.to_str().unwrap(), "--no-plots"];
    let shared = ["--mesh-read", "shared", "--partitioner", partitioner];
    let args = [&args[..], &shared[..]].concat();
    let (code, _, stderr) = run_on_ranks(dir, np, &args);
    assert_eq!(code, 2, "{np} ranks: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out.join("contact.csv").exists());
    // mpirun adds notes of its own on a failed job.
    stderr
        .lines()
        .filter(|l| l.starts_with("contact-par"))
        .map(str::to_string)
        .collect()
}

#[test]
fn a_malformed_file_gives_the_first_ranks_one_line_on_any_number_of_ranks() {
    let text = String::from_utf8(fixture("quarter_disc_v41_ascii.msh")).unwrap();
    let nodes = text.find("$Nodes").unwrap();
    let elements = text.find("$Elements").unwrap();
    // A coordinate at the end of $Nodes (so in the last rank's share), a node tag
    // missing from $Nodes, a file cut in $Elements.
    let line_before = |tag: &str| {
        let at = text.find(tag).unwrap();
        text[..at - 1].rfind('\n').unwrap() + 1
    };
    let last_point = line_before("$EndNodes");
    let first_token = last_point + text[last_point..].find(' ').unwrap();
    let mut bad_number = text.clone();
    bad_number.replace_range(last_point..first_token, "0.5x");
    let last_triangle = line_before("$EndElements");
    let tag_end = last_triangle + text[last_triangle..].find(' ').unwrap();
    let mut unknown_node = text.clone();
    unknown_node.insert_str(tag_end + 1, "99999");
    let truncated = text[..elements + (text.len() - elements) / 2].to_string();
    assert!(nodes < last_point && last_point < elements);
    for (what, bad, expect) in [
        ("a bad number", bad_number, "bad number '0.5x'"),
        (
            "an unknown node",
            unknown_node,
            "which is not defined in $Nodes",
        ),
        ("a truncated file", truncated, "truncated"),
    ] {
        let dir = case_dir(&disc_case(), bad.as_bytes());
        let one = refused(dir.path(), 1, "metis");
        assert_eq!(one.len(), 1, "{what}: {one:?}");
        assert!(one[0].contains(expect), "{what}: {one:?}");
        for np in [2, 3] {
            for partitioner in ["metis", "ptscotch"] {
                let lines = refused(dir.path(), np, partitioner);
                assert_eq!(lines, one, "{what} on {np} ranks, {partitioner}");
            }
        }
    }
}

/// `text` (MSH 4.1 ASCII) with the point of node `tag` set to `xyz`.
fn with_point(text: &str, tag: u64, xyz: [f64; 3]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut at = lines.iter().position(|l| l == "$Nodes").unwrap() + 2;
    loop {
        let head: Vec<usize> = (lines[at].split_whitespace())
            .map(|v| v.parse().unwrap())
            .collect();
        let count = head[3];
        let tags = at + 1..at + 1 + count;
        if let Some(k) = tags
            .clone()
            .position(|i| lines[i].trim() == tag.to_string())
        {
            lines[at + 1 + count + k] = format!("{} {} {}", xyz[0], xyz[1], xyz[2]);
            return lines.join("\n") + "\n";
        }
        at += 1 + 2 * count;
    }
}

/// Where the ranks cut the mesh from their shares and the first rank builds only the
/// conditions (`dd::dist_problem`), a fault of the mesh or of the case is named as the
/// first rank's reading of the whole file names it: the one-rank line on 2 and 3 ranks;
/// also for two bodies, whose contact lines the first rank checks on the groups' elements.
#[test]
fn a_faulty_mesh_or_case_gives_the_one_rank_line_where_the_ranks_cut() {
    let text = String::from_utf8(fixture("quarter_disc_v41_ascii.msh")).unwrap();
    let disc = disc_case();
    let frictionless = quarter_disc_case_on("mesh.msh", "friction = \"none\"");
    // Node 60 lies inside the disc; node 61 is another one.
    let meshes = [
        (
            "a node moved out",
            with_point(&text, 60, [3.0, 3.0, 0.0]),
            disc.clone(),
        ),
        (
            "a node on another",
            with_point(&text, 60, point(&text, 61)),
            disc.clone(),
        ),
        (
            "a node off the plane",
            with_point(&text, 60, with_z(point(&text, 60))),
            disc.clone(),
        ),
        (
            "the first node off the plane of the others",
            with_point(&text, 1, with_z(point(&text, 1))),
            disc.clone(),
        ),
        (
            "a misspelled group",
            text.clone(),
            disc.replace("\"axis\"", "\"axes\""),
        ),
        (
            "a material on a line group",
            text.clone(),
            with_materials(&disc, &["contact"]),
        ),
        (
            "a material on no group of the mesh",
            text.clone(),
            with_materials(&disc, &["bodies"]),
        ),
        (
            "two materials on one triangle",
            with_second_surface(&text),
            with_materials(&disc, &["body", "other"]),
        ),
        (
            "two materials on one triangle and a misspelled group",
            with_second_surface(&text),
            with_materials(&disc, &["body", "other"]).replace("\"axis\"", "\"axes\""),
        ),
        (
            "no Dirichlet condition",
            text.clone(),
            without_dirichlet(&frictionless),
        ),
        (
            "a penetrating node",
            text.clone(),
            disc.replace("[0.0, 0.0]", "[0.0, 0.5]"),
        ),
    ];
    // Two bodies: faults of the contact's lines, found on the groups' elements.
    let blocks_mesh = std::fs::read_to_string(bodies_dir().join("blocks.msh")).unwrap();
    let blocks = std::fs::read_to_string(bodies_dir().join("blocks.toml"))
        .unwrap()
        .replace("\"blocks.msh\"", "\"mesh.msh\"");
    let two_bodies = [
        (
            "a master line that shares a node with its slave",
            blocks.replace("master = \"lower_top\"", "master = \"upper_left\""),
        ),
        (
            "a slave line that faces no master",
            blocks.replace("master = \"lower_top\"", "master = \"bottom\""),
        ),
    ];
    let meshes = (meshes.into_iter())
        .chain(two_bodies.map(|(what, case)| (what, blocks_mesh.clone(), case)));
    for (what, mesh, case) in meshes {
        let dir = case_dir(&case, mesh.as_bytes());
        let one = refused(dir.path(), 1, "metis");
        assert_eq!(one.len(), 1, "{what}: {one:?}");
        for np in [2, 3] {
            let lines = refused(dir.path(), np, "ptscotch");
            assert_eq!(lines, one, "{what} on {np} ranks");
        }
    }
}

/// The point of node `tag` in `text` (MSH 4.1 ASCII).
fn point(text: &str, tag: u64) -> [f64; 3] {
    let lines: Vec<&str> = text.lines().collect();
    let mut at = lines.iter().position(|l| *l == "$Nodes").unwrap() + 2;
    loop {
        let count: usize = lines[at]
            .split_whitespace()
            .nth(3)
            .unwrap()
            .parse()
            .unwrap();
        let tags = at + 1..at + 1 + count;
        if let Some(k) = tags
            .clone()
            .position(|i| lines[i].trim() == tag.to_string())
        {
            let v: Vec<f64> = (lines[at + 1 + count + k].split_whitespace())
                .map(|v| v.parse().unwrap())
                .collect();
            return [v[0], v[1], v[2]];
        }
        at += 1 + 2 * count;
    }
}

fn with_z(p: [f64; 3]) -> [f64; 3] {
    [p[0], p[1], 0.25]
}

/// The disc's mesh with its surface in a second physical surface, "other", too.
fn with_second_surface(text: &str) -> String {
    let (names, entity) = ("2 4 \"body\"\n", " 1 4 3 1 2 3 \n");
    assert!(text.contains(names) && text.contains(entity));
    (text.replace("$PhysicalNames\n4\n", "$PhysicalNames\n5\n"))
        .replace(names, "2 4 \"body\"\n2 5 \"other\"\n")
        .replace(entity, " 2 4 5 3 1 2 3 \n")
}

/// The disc's case with one `[[material]]` per group of `groups` for its `[material]`.
fn with_materials(case: &str, groups: &[&str]) -> String {
    let lone = "[material]\nyoung = 1000.0\npoisson = 0.3\n";
    assert!(case.contains(lone));
    let entries: String = (groups.iter().enumerate())
        .map(|(i, g)| {
            format!(
                "[[material]]\ngroup = \"{g}\"\nyoung = {}\npoisson = 0.3\n",
                1000 * (i + 1)
            )
        })
        .collect();
    case.replace(lone, &entries)
}

/// The disc's case without its `[[dirichlet]]` entries.
fn without_dirichlet(case: &str) -> String {
    let mut out = String::new();
    let mut skip = false;
    for line in case.lines() {
        if line.starts_with('[') {
            skip = line == "[[dirichlet]]";
        }
        if !skip {
            out += line;
            out += "\n";
        }
    }
    out
}
