//! Case files on real Gmsh meshes (the committed fixtures in tests/data/gmsh).

mod common;
use common::*;

/// The unstructured Gmsh quarter disc of the fixtures with `friction`.
fn quarter_disc_case(friction: &str) -> String {
    let mesh = gmsh_dir().join("quarter_disc_v41_ascii.msh");
    quarter_disc_case_on(&mesh.display().to_string(), friction)
}

#[test]
fn gmsh_quarter_disc_frictionless_is_hertzian() {
    let run = run_case(&quarter_disc_case("friction = \"none\""), &[]);
    run.expect_code(0);
    let rows = run.contact();
    let s = run.summary();
    // KKT at the tolerance of contact_physics.rs (tol 1e-10, see KKT_REL there).
    check_kkt(&rows, Law::None, 1e-8, "Gmsh quarter disc, frictionless");
    let force = num(&s, "total_normal_force");
    assert!(force > 0.0, "total normal force {force}");
    // Hertz, loosely: the fixture is coarse (element 0.03 at the contact, a ~ 0.08 so
    // only 3 active nodes), so the peak is checked to 10% and the half-width to lie
    // between the last active node and the next one, widened by 10%.
    let p = 2.0 * force;
    let e_star = 1000.0 / (1.0 - 0.09);
    let a = (4.0 * p / (std::f64::consts::PI * e_star)).sqrt();
    let p0 = 2.0 * p / (std::f64::consts::PI * a);
    let last = rows.iter().rposition(|r| r.p_n > 0.0).unwrap();
    let pmax = rows.iter().map(|r| r.p_n).fold(0.0, f64::max);
    println!(
        "Gmsh quarter disc: P = {p}, a = {a}, active up to x = {} (next {}), p0 = {p0}, max p_n = {pmax} ({:+.3e})",
        rows[last].x,
        rows[last + 1].x,
        (pmax - p0) / p0
    );
    assert!(last >= 2, "only {} active nodes", last + 1);
    assert!(rows[last].x <= 1.1 * a && rows[last + 1].x >= 0.9 * a);
    assert!((pmax - p0).abs() <= 0.1 * p0);
}

#[test]
fn gmsh_quarter_disc_coulomb_kkt() {
    let run = run_case(
        &quarter_disc_case("friction = \"coulomb\"\ncoefficient = 0.2"),
        &[],
    );
    run.expect_code(0);
    let rows = run.contact();
    check_kkt(
        &rows,
        Law::Coulomb(0.2),
        1e-8,
        "Gmsh quarter disc, Coulomb 0.2",
    );
    assert!(num(&run.summary(), "total_normal_force") > 0.0);
    // On the curved boundary the contact nodes approach the foundation as it deforms
    // and rub along it: friction acts (some p_t non-zero).
    assert!(max_abs(&rows, 5) > 0.0, "no tangential traction at all");
}

/// The 2 x 1 rectangle of the Gmsh fixtures, sheared and pressed on y = -0.001.
fn rect_case(file: &str) -> String {
    rect_case_on(&gmsh_dir().join(file).display().to_string())
}

fn contact_text(file: &str) -> (String, Vec<Row>, serde_json::Value) {
    let run = run_case(&rect_case(file), &[]);
    run.expect_code(0);
    let text = std::fs::read_to_string(run.out.join("contact.csv")).unwrap();
    (text, run.contact(), run.summary())
}

#[test]
fn gmsh_formats_give_identical_results() {
    let (a41, rows, s) = contact_text("rect_v41_ascii.msh");
    let (a22, ..) = contact_text("rect_v22_ascii.msh");
    let (b22, rows_b, sb) = contact_text("rect_v22_binary.msh");
    let (b41, ..) = contact_text("rect_v41_binary.msh");
    assert!(rows.len() > 5 && rows.iter().all(|r| r.p_n > 0.0), "{a41}");
    assert!(
        num(&s, "stick_nodes") > 0.0 && num(&s, "slip_nodes") > 0.0,
        "{s}"
    );
    // Same mesh, same storage of the coordinates: the computation and the file are
    // identical byte for byte.
    assert!(
        a41 == a22,
        "MSH 4.1 and 2.2 ASCII files give different contact.csv"
    );
    assert!(
        b41 == b22,
        "MSH 4.1 and 2.2 binary files give different contact.csv"
    );
    // ASCII vs binary: Gmsh prints ASCII coordinates with 16 significant digits
    // (0.2499999999995475) but stores the exact double in binary files
    // (0.24999999999954753), so the inputs differ in the last bit and the results by
    // round-off only: coordinates to 1e-14, every column to 1e-12 of its max (measured
    // 4e-15).
    assert_eq!(rows.len(), rows_b.len());
    for (a, b) in rows.iter().zip(&rows_b) {
        assert!(
            (a.x - b.x).abs() <= 1e-14 * 2.0 && a.y == b.y,
            "{a:?} vs {b:?}"
        );
    }
    assert_same_columns(&rows, &rows_b, 1e-12, "rect v4.1 ASCII vs v2.2 binary");
    assert_eq!(s["iterations"], sb["iterations"]);
    assert_eq!(s["stick_nodes"], sb["stick_nodes"]);
}

/// The (x, y) of every node of an MSH 4.1 ASCII file, in the file's order.
fn file_nodes_msh41(text: &str) -> Vec<[f64; 2]> {
    let lines: Vec<&str> = text.lines().collect();
    let mut i = lines.iter().position(|&l| l == "$Nodes").unwrap() + 1;
    let blocks: usize = lines[i].split_whitespace().next().unwrap().parse().unwrap();
    i += 1;
    let mut xy = Vec::new();
    for _ in 0..blocks {
        let count: usize = lines[i].split_whitespace().nth(3).unwrap().parse().unwrap();
        i += 1 + count;
        for l in &lines[i..i + count] {
            let v: Vec<f64> = l
                .split_whitespace()
                .take(2)
                .map(|x| x.parse().unwrap())
                .collect();
            xy.push([v[0], v[1]]);
        }
        i += count;
    }
    xy
}

/// The nodes.csv rows (x, y, ux, uy) sorted by position.
fn node_rows_by_position(out: &std::path::Path) -> Vec<[f64; 4]> {
    let text = std::fs::read_to_string(out.join("nodes.csv")).unwrap();
    let mut rows: Vec<[f64; 4]> = text
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect();
    rows.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    rows
}

/// The order in which the file lists nodes and elements changes nothing: the program
/// numbers the mesh along a Hilbert curve after reading it, so both files give the same
/// computation, bit for bit. Each nodes.csv row is the node of that row of its file.
#[test]
fn the_order_of_the_file_changes_nothing() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tolerance");
    let text = std::fs::read_to_string(data.join("wedge.msh")).unwrap();
    let case = std::fs::read_to_string(data.join("wedge.toml")).unwrap();
    let run = |msh: &str, np: usize| {
        let dir = tempfile::TempDir::new().unwrap();
        std::fs::write(dir.path().join("wedge.msh"), msh).unwrap();
        std::fs::write(dir.path().join("case.toml"), &case).unwrap();
        let o = mpirun(np, dir.path())
            .args([
                "case.toml",
                "--nodes-csv",
                "--out",
                "out",
                "--quiet",
                "--threads",
                "1",
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s = read_summary(&dir.path().join("out/summary.json"));
        let nodes_text = std::fs::read_to_string(dir.path().join("out/nodes.csv")).unwrap();
        (dir, s, nodes_text)
    };
    let shuffled = shuffled_msh41(&text, 7);
    assert_ne!(shuffled, text);
    let (a, sa, nodes_a) = run(&text, 2);
    let (b, sb, nodes_b) = run(&shuffled, 2);
    assert_eq!(sa["iterations"], sb["iterations"]);
    assert_eq!(sa["stick_nodes"], sb["stick_nodes"]);
    // The same numbering after the renumbering, so the same computation: contact.csv
    // is the same file byte for byte.
    let contact = |d: &tempfile::TempDir| std::fs::read(d.path().join("out/contact.csv")).unwrap();
    assert!(contact(&a) == contact(&b), "contact.csv differs");
    // nodes.csv follows each file's own order: the rows differ, the nodes do not.
    assert_ne!(nodes_a, nodes_b);
    // Row k of nodes.csv is the k-th node the file lists.
    for (msh, nodes) in [(&text, &nodes_a), (&shuffled, &nodes_b)] {
        let rows: Vec<[f64; 2]> = nodes
            .lines()
            .skip(1)
            .map(|l| {
                let v: Vec<f64> = l.split(',').take(2).map(|x| x.parse().unwrap()).collect();
                [v[0], v[1]]
            })
            .collect();
        assert_eq!(rows, file_nodes_msh41(msh));
    }
    let (ra, rb) = (
        node_rows_by_position(&a.path().join("out")),
        node_rows_by_position(&b.path().join("out")),
    );
    assert_eq!(ra.len(), rb.len());
    assert_eq!(ra, rb);
}

/// The fill-reducing ordering changes the factor, not the answer: the unstructured
/// quarter disc with Coulomb friction under each ordering (the default is the
/// geometric nested dissection), on one subdomain and on two.
#[test]
fn every_ordering_gives_the_same_answer() {
    let case = quarter_disc_case("friction = \"coulomb\"\ncoefficient = 0.3");
    for subdomains in ["1", "2"] {
        let runs: Vec<(String, Run)> = ["auto", "gnd", "amd", "nd"]
            .iter()
            .map(|o| {
                let run = run_case(
                    &case,
                    &["--ordering", o, "--subdomains-per-rank", subdomains],
                );
                run.expect_code(0);
                (o.to_string(), run)
            })
            .collect();
        let used: Vec<String> = runs
            .iter()
            .map(|(_, r)| {
                r.summary()["per_subdomain"][0]["ordering"]
                    .as_str()
                    .unwrap()
                    .to_string()
            })
            .collect();
        assert_eq!(
            used,
            ["gnd", "gnd", "amd", "nd"],
            "{subdomains} subdomain(s)"
        );
        let reference = runs[2].1.contact();
        for (name, run) in &runs {
            check_kkt(&run.contact(), Law::Coulomb(0.3), 1e-8, name);
            assert_same_columns(
                &reference,
                &run.contact(),
                1e-8,
                &format!("--ordering {name} against amd on {subdomains} subdomain(s)"),
            );
        }
    }
}
