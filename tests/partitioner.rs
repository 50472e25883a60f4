//! The mesh cut by PT-Scotch on every rank (`--partitioner ptscotch`) gives the answer
//! of one rank, on 2, 3 and 4 ranks: a body against an obstacle with Coulomb friction
//! (a Gmsh file) and two bodies in contact (whose ties the cut must see), compared node
//! by node (also two subdomains per rank), with the contact conditions checked; the
//! same parts run after run (the outputs byte for byte); and its parts as good as the
//! first rank's METIS cut. Also `contact-par split` on several ranks, which cut
//! together: runs from its parts give the same answer. And the cut the ranks make from
//! their shares of a Gmsh file read together (`--mesh-read shared`), before any rank
//! holds the mesh: ASCII, binary and a shuffled copy, the one-rank answer on 2-4 ranks,
//! each rank then building its own part where it holds one, and the first rank only
//! the conditions, no rank holding the whole mesh;
//! two bodies, whose ties only the problem knows, and a file with a repeated triangle,
//! whose records are not the problem's triangles, are cut on the first rank's graph.

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
        assert!(metis.contains("(the first rank, METIS)"), "{what}: {metis}");
        // The first rank's straight cuts (the default on one node): the same answer.
        let geo = run(p, np, &format!("geo{np}"), "geometric");
        assert!(
            geo.contains("(the first rank, straight cuts)"),
            "{what}: {geo}"
        );
        let rows = read_contact(&p.join(format!("geo{np}")).join("contact.csv"));
        assert_same_columns(
            &one,
            &rows,
            1e-8,
            &format!("{what}, 1 vs {np} ranks, lines"),
        );
        near_metis(&geo, &metis, &format!("{what}, {np} ranks, lines"));
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
        near_metis(&line, &metis, &format!("{what}, {np} ranks"));
    }
}

#[test]
fn a_body_on_an_obstacle_cut_by_every_rank_agrees_with_one_rank() {
    let case = disc_case();
    let mesh = gmsh_dir().join("quarter_disc_v41_ascii.msh");
    let dir = case_dir(&case, &mesh, "mesh.msh");
    check(dir.path(), Law::Coulomb(0.2), "quarter disc");
}

/// The upper block dragged sideways on the lower one, held along x by Coulomb friction
/// alone (as in tests/bodies.rs): partial slip, so that every column moves.
#[test]
fn two_bodies_in_contact_cut_by_every_rank_agree_with_one_rank() {
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

/// `mpirun -n 3 contact-par split --partitioner ptscotch` cuts on its 3 ranks (one line,
/// from the first). With 3 or 6 parts each rank builds its own parts from its share of
/// the file and writes them, the first rank the manifest; with 4 the first rank splits
/// the ranks' cut and writes every part. Runs from each split agree with the unsplit
/// run on every rank count that divides its parts; on the quarter disc against a line
/// and on a disc pressed on a block (two bodies: mortar rows, whose masters are ghosts
/// where the cut runs through the contact).
#[test]
fn a_split_cut_by_every_rank_gives_the_same_answer() {
    let bodies = bodies_dir();
    let two_bodies = std::fs::read_to_string(bodies.join("disc.toml"))
        .unwrap()
        .replace("\"disc.msh\"", "\"mesh.msh\"");
    split_by_every_rank(&disc_case(), &gmsh_dir().join("quarter_disc_v41_ascii.msh"));
    split_by_every_rank(&two_bodies, &bodies.join("disc.msh"));
}

fn split_by_every_rank(case: &str, mesh: &Path) {
    let dir = case_dir(case, mesh, "mesh.msh");
    let p = dir.path();
    run(p, 1, "one", "metis");
    let one = read_contact(&p.join("one/contact.csv"));
    for (parts, who, ranks) in [
        (
            3,
            "built on their 3 ranks from their shares of the file",
            &[1, 3][..],
        ),
        (
            6,
            "built on their 3 ranks from their shares of the file",
            &[2, 6][..],
        ),
        (4, "cut by PT-Scotch on 3 ranks", &[1, 4][..]),
    ] {
        let out = format!("parts{parts}");
        let n = parts.to_string();
        let split = [
            "split",
            "case.toml",
            "--parts",
            &n,
            "--out",
            &out,
            "--partitioner",
            "ptscotch",
        ];
        let (code, stdout, stderr) = run_on_ranks(p, 3, &split);
        assert_eq!(code, 0, "{stderr}");
        let lines: Vec<&str> = stdout.lines().filter(|l| l.starts_with("split:")).collect();
        assert_eq!(lines.len(), 1, "{stdout}");
        assert!(lines[0].contains(who), "{parts} parts: {stdout}");
        assert!(
            lines[0].contains(&format!("into {parts} parts")),
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

const SHARED: [&str; 2] = ["--mesh-read", "shared"];

/// The cut from the ranks' shares on 2, 3 and 4 ranks (and 2 subdomains per rank):
/// the one-rank answer (`law`: checked against the contact conditions), the same bytes
/// on a second run, an edge cut near METIS's.
fn check_from_shares(p: &Path, law: Option<Law>, what: &str) {
    run(p, 1, "one", "metis");
    let one = read_contact(&p.join("one/contact.csv"));
    for np in 2..=4 {
        for k in [1, 2] {
            let (out, again) = (format!("sh{np}x{k}"), format!("sh{np}x{k}b"));
            let k_arg = k.to_string();
            let extra = [SHARED[0], SHARED[1], "--subdomains-per-rank", &k_arg];
            let line = run_with(p, np, &out, "ptscotch", &extra);
            let from = format!("PT-Scotch on {np} ranks from their shares of the file");
            assert!(line.contains(&from), "{what}, {np} x {k}: {line}");
            assert!(line.contains(&format!("in {} parts", np * k)), "{line}");
            // Each rank builds its own parts (`dd::dist_split`), one or several, and
            // the first rank only the conditions (`dd::dist_problem`).
            let built = line.contains("parts built on their ranks");
            assert!(built, "{what}, {np} x {k}: {line}");
            let whole = line.contains("no rank holding it whole");
            assert!(whole, "{what}, {np} x {k}: {line}");
            let rows = read_contact(&p.join(&out).join("contact.csv"));
            let name = format!("{what}, 1 vs {np} ranks x {k} from the shares");
            assert_same_columns(&one, &rows, 1e-8, &name);
            if let Some(law) = law {
                check_kkt(&rows, law, 1e-6, &name);
            }
            run_with(p, np, &again, "ptscotch", &extra);
            same_bytes(p, &out, &again);
            if k == 1 {
                let metis = run(p, np, &format!("metis{np}"), "metis");
                near_metis(
                    &line,
                    &metis,
                    &format!("{what} from the shares, {np} ranks"),
                );
            }
        }
    }
}

#[test]
fn a_mesh_cut_from_the_ranks_shares_of_the_file_agrees_with_one_rank() {
    let disc = disc_case();
    let text = std::fs::read_to_string(gmsh_dir().join("quarter_disc_v41_ascii.msh")).unwrap();
    for (case, mesh, law, what) in [
        (
            disc.clone(),
            text.clone(),
            Some(Law::Coulomb(0.2)),
            "quarter disc",
        ),
        // Node tags permuted, nodes and elements in another order.
        (
            disc,
            shuffled_msh41(&text, 11),
            Some(Law::Coulomb(0.2)),
            "shuffled disc",
        ),
    ] {
        let dir = TempDir::new().unwrap();
        std::fs::write(dir.path().join("case.toml"), case).unwrap();
        std::fs::write(dir.path().join("mesh.msh"), mesh).unwrap();
        check_from_shares(dir.path(), law, what);
    }
    let rect = rect_case_on("mesh.msh");
    let dir = case_dir(&rect, &gmsh_dir().join("rect_v41_binary.msh"), "mesh.msh");
    check_from_shares(dir.path(), None, "binary rectangle");
}

/// Two bodies cut from the ranks' shares: the first rank finds the mortar rows' ties
/// from the groups' elements (the third corners of the contact lines' triangles from
/// the ranks) and the cut keeps them together, as METIS does on the first rank's graph:
/// as few interface dofs as METIS's within 15% (untied, PT-Scotch cuts between the
/// bodies, every master node across the cut an interface node: twice as many on the
/// 29k-node disc). The one-rank answer and the contact conditions on 2 and 3 ranks.
#[test]
fn two_bodies_read_by_every_rank_are_cut_with_their_ties() {
    let bodies = bodies_dir();
    let disc = std::fs::read_to_string(bodies.join("disc.toml"))
        .unwrap()
        .replace("\"disc.msh\"", "\"mesh.msh\"");
    let blocks = dragged_blocks().replace("\"blocks.msh\"", "\"mesh.msh\"");
    for (case, mesh, what) in [
        (disc, bodies.join("disc.msh"), "disc on a block"),
        (blocks, bodies_dir().join("blocks.msh"), "two blocks"),
    ] {
        let dir = case_dir(&case, &mesh, "mesh.msh");
        let p = dir.path();
        run(p, 1, "one", "metis");
        let one = read_contact(&p.join("one/contact.csv"));
        let interface = |out: &str| {
            num(
                &read_summary(&p.join(out).join("summary.json")),
                "interface_dofs",
            )
        };
        for np in [2, 3] {
            let out = format!("sh{np}");
            let line = run_with(p, np, &out, "ptscotch", &SHARED);
            let from = format!("PT-Scotch on {np} ranks from their shares of the file");
            assert!(line.contains(&from), "{what}, {np} ranks: {line}");
            assert!(line.contains("parts built on their ranks"), "{line}");
            let rows = read_contact(&p.join(&out).join("contact.csv"));
            let name = format!("{what}, {np} ranks");
            assert_same_columns(&one, &rows, 1e-8, &name);
            check_kkt(&rows, Law::Coulomb(0.3), 1e-6, &name);
            let metis = format!("metis{np}");
            run(p, np, &metis, "metis");
            let (tied, by_metis) = (interface(&out), interface(&metis));
            assert!(
                tied <= 1.15 * by_metis,
                "{name}: {tied} interface dofs against METIS's {by_metis}"
            );
        }
    }
}

/// Runs read by every rank on 2 and 3 ranks, cut by PT-Scotch on the first rank's
/// graph (not from the shares): the one-rank answer (`law`: and the contact
/// conditions).
fn cut_on_the_first_ranks_graph(p: &Path, law: Option<Law>, what: &str) {
    run(p, 1, "one", "metis");
    let one = read_contact(&p.join("one/contact.csv"));
    for np in [2, 3] {
        let out = format!("sh{np}");
        let line = run_with(p, np, &out, "ptscotch", &SHARED);
        assert!(
            line.contains(&format!("(PT-Scotch on {np} ranks)")),
            "{what}, {np} ranks: {line}"
        );
        let rows = read_contact(&p.join(&out).join("contact.csv"));
        let name = format!("{what}, {np} ranks");
        assert_same_columns(&one, &rows, 1e-8, &name);
        if let Some(law) = law {
            check_kkt(&rows, law, 1e-6, &name);
        }
    }
}

/// The disc's file with its last block of triangles' first triangle listed twice (a new
/// element tag), which the reading keeps once.
fn disc_with_a_repeated_triangle() -> String {
    let text = std::fs::read_to_string(gmsh_dir().join("quarter_disc_v41_ascii.msh")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let at = lines.iter().position(|l| l == "$Elements").unwrap();
    let head: Vec<usize> = (lines[at + 1].split_whitespace())
        .map(|w| w.parse().unwrap())
        .collect();
    let (mut j, mut last) = (at + 2, None);
    while lines[j] != "$EndElements" {
        let block: Vec<&str> = lines[j].split_whitespace().collect();
        if block[2] == "2" {
            last = Some(j);
        }
        j += 1 + block[3].parse::<usize>().unwrap();
    }
    let b = last.expect("a block of triangles");
    let block: Vec<String> = lines[b].split_whitespace().map(str::to_string).collect();
    let count: usize = block[3].parse().unwrap();
    let first: Vec<&str> = lines[b + 1].split_whitespace().collect();
    let repeat = format!("{} {}", head[3] + 1, first[1..].join(" "));
    lines.insert(b + 1 + count, repeat);
    lines[b] = format!("{} {} {} {}", block[0], block[1], block[2], count + 1);
    lines[at + 1] = format!("{} {} {} {}", head[0], head[1] + 1, head[2], head[3] + 1);
    lines.join("\n") + "\n"
}

/// A repeated triangle: the ranks' cut of the file's triangle records does not match
/// the problem's triangles, so the ranks cut the first rank's graph instead, and the
/// answer is the one-rank answer.
#[test]
fn a_file_with_a_repeated_triangle_is_cut_on_the_first_ranks_graph() {
    let dir = TempDir::new().unwrap();
    std::fs::write(dir.path().join("case.toml"), disc_case()).unwrap();
    std::fs::write(dir.path().join("mesh.msh"), disc_with_a_repeated_triangle()).unwrap();
    let law = Some(Law::Coulomb(0.2));
    cut_on_the_first_ranks_graph(dir.path(), law, "a repeated triangle");
}

/// Where the ranks cut a Gmsh file from their shares and build their own parts, the
/// first rank builds only the conditions, from the groups' elements, the boundary and
/// the separate parts the ranks find (`dd::dist_problem`): the same problem as the
/// whole mesh gives, shown on 2 and 3 ranks by the same first line (its sizes and r,
/// which the contact edges, the bounding box and the bodies at the contact set) and the
/// one-rank answer, for cases with Coulomb and Tresca friction, a wedge against an
/// inclined line, tractions, a body force, two materials and two bodies in contact.
#[test]
fn conditions_found_without_the_whole_mesh_are_the_whole_problems() {
    let tolerance = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tolerance");
    let two_materials = "title = \"two materials\"\n[mesh]\nfile = \"mesh.msh\"\n\
        [[material]]\ngroup = \"lower\"\nyoung = 1.0e3\npoisson = 0.3\n\
        [[material]]\ngroup = \"upper\"\nyoung = 5.0e3\npoisson = 0.25\n\
        [[dirichlet]]\ngroup = \"left\"\nux = 0.0\n[[traction]]\ngroup = \"top\"\nt = [0.5, -10.0]\n\
        [body_force]\nf = [0.0, -2.0]\n\
        [contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, -0.002]\nobstacle_normal = [0.0, 1.0]\n\
        friction = \"tresca\"\nthreshold = 2.0\n";
    let mut cases = vec![(
        two_materials.to_string(),
        gmsh_dir().join("bimaterial_v41_ascii.msh"),
        "two materials",
    )];
    for name in ["wedge", "wall", "cantilever"] {
        let case = std::fs::read_to_string(tolerance.join(format!("{name}.toml"))).unwrap();
        let case = case.replace(&format!("\"{name}.msh\""), "\"mesh.msh\"");
        cases.push((case, tolerance.join(format!("{name}.msh")), name));
    }
    // Two bodies: each slave node's mortar row and its masters, ghosts of its part where
    // the cut runs through the contact.
    let bodies = bodies_dir();
    for (name, what) in [("blocks", "two blocks"), ("disc", "a disc on a block")] {
        let case = std::fs::read_to_string(bodies.join(format!("{name}.toml"))).unwrap();
        let case = case.replace(&format!("\"{name}.msh\""), "\"mesh.msh\"");
        cases.push((case, bodies.join(format!("{name}.msh")), what));
    }
    for (case, mesh, what) in cases {
        let dir = case_dir(&case, &mesh, "mesh.msh");
        let p = dir.path();
        let first_line = |np: usize, out: &str, extra: &[&str]| {
            let mut args = vec!["case.toml", "--out", out, "--no-plots", "--nodes-csv"];
            args.extend_from_slice(extra);
            let (code, stdout, stderr) = run_on_ranks(p, np, &args);
            assert_eq!(code, 0, "{what}, {np} ranks: {stderr}");
            let head = stdout.lines().next().unwrap_or_default();
            // The layout ends the line: the rest must be the same.
            let head = head.split(" | ").take(4).collect::<Vec<_>>().join(" | ");
            (head, stdout)
        };
        let (one_head, _) = first_line(1, "one", &[]);
        let one = read_contact(&p.join("one/contact.csv"));
        for np in [2, 3] {
            let out = format!("groups{np}");
            let extra = [SHARED[0], SHARED[1], "--partitioner", "ptscotch"];
            let (head, stdout) = first_line(np, &out, &extra);
            assert!(
                stdout.contains("no rank holding it whole"),
                "{what}, {np} ranks:\n{stdout}"
            );
            assert_eq!(head, one_head, "{what}, {np} ranks");
            let rows = read_contact(&p.join(&out).join("contact.csv"));
            same_answer(p, "one", &out, &one, &rows, &format!("{what}, {np} ranks"));
        }
    }
}

/// The contact pressures of runs `a` and `b` (their rows `ra`, `rb`) within 1e-8 of
/// their largest, and every node's displacement (matched by its point) within 1e-8 of
/// the largest: the contact nodes' own displacements may all be zero (a body pressed
/// flat and stuck), where only round-off tells them apart.
fn same_answer(p: &Path, a: &str, b: &str, ra: &[Row], rb: &[Row], what: &str) {
    for (c, name) in [(4, "p_n"), (5, "p_t")] {
        let scale = max_abs(ra, c).max(f64::MIN_POSITIVE);
        let d = ra
            .iter()
            .zip(rb)
            .map(|(x, y)| (x.col(c) - y.col(c)).abs())
            .fold(0.0, f64::max);
        assert!(
            d <= 1e-8 * scale,
            "{what}: {name} differs by {d} of {scale}"
        );
    }
    // Two bodies meshed on their own may have a node each at one point: a point holds
    // a list of nodes.
    let key = |n: &[f64; 4]| (n[0].to_bits(), n[1].to_bits());
    let mut nb: std::collections::HashMap<(u64, u64), Vec<[f64; 4]>> = Default::default();
    let b_nodes = read_nodes(&p.join(b).join("nodes.csv"));
    for n in &b_nodes {
        nb.entry(key(n)).or_default().push(*n);
    }
    let na = read_nodes(&p.join(a).join("nodes.csv"));
    assert_eq!(na.len(), b_nodes.len(), "{what}");
    let scale = na.iter().map(|n| n[2].hypot(n[3])).fold(0.0, f64::max);
    assert!(scale > 0.0, "{what}: nothing moves");
    for n in &na {
        let at = nb
            .get(&key(n))
            .unwrap_or_else(|| panic!("{what}: no node at {n:?}"));
        let d = (at.iter())
            .map(|m| (n[2] - m[2]).hypot(n[3] - m[3]))
            .fold(f64::INFINITY, f64::min);
        assert!(
            d <= 1e-8 * scale,
            "{what}: u at ({}, {}) differs by {d}",
            n[0],
            n[1]
        );
    }
}
