//! A one-rank run's one subdomain, the problem moved into it (`dd::split::split_whole`),
//! is the general split (`dd::split::split`) of the same problem into one part: the same
//! subproblem field for field, the same global map, and the same partition figures as
//! the first rank's one-part partition, for held-out cases (Dirichlet lines, tractions,
//! body forces, inclined and oblique obstacles, friction and none, two bodies in contact
//! with mortar rows) and the built-in cases.

use contact_par::case::{builtin_case, parse_case, Case};
use contact_par::dd::split::{split, split_whole};
use contact_par::problem::{self, Problem};
use contact_par::setup::load_mesh;
use std::path::Path;

fn data(dir: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(dir)
}

fn text(dir: &str, file: &str) -> String {
    std::fs::read_to_string(data(dir).join(file)).expect("a case")
}

fn cases() -> Vec<(String, Case)> {
    let parse = |name: &str, dir: &str, text: &str| {
        (
            name.to_string(),
            parse_case(text, name, &data(dir)).expect("the case"),
        )
    };
    // Oblique normals without friction: nodes turned into their frames.
    let wedge = text("tolerance", "wedge.toml");
    let frictionless = wedge.replace(
        "friction = \"coulomb\"\ncoefficient = 0.9",
        "friction = \"none\"",
    );
    assert_ne!(wedge, frictionless);
    let mut cases = vec![parse("frictionless wedge", "tolerance", &frictionless)];
    for file in [
        "wedge",
        "disc",
        "cantilever",
        "wall",
        "arch",
        "ring",
        "tube",
    ] {
        let file = format!("{file}.toml");
        cases.push(parse(&file, "tolerance", &text("tolerance", &file)));
    }
    for file in ["blocks.toml", "disc.toml"] {
        cases.push(parse(file, "bodies", &text("bodies", file)));
    }
    for name in ["hertz", "block", "block_flat", "punch", "cylinders"] {
        cases.push((name.into(), builtin_case(name, 1).expect("a built-in case")));
    }
    cases
}

#[test]
fn the_whole_problem_is_the_split_of_one_part() {
    for (name, case) in cases() {
        let (mesh, mesh_name) = load_mesh(&case).expect("the mesh");
        let prob = problem::build(&case, mesh, &mesh_name).expect("the problem");
        let frictional = Problem::is_frictional(&case);
        let (n, triangles) = (prob.mesh.num_nodes(), &prob.mesh.triangles);
        // What a one-part run did before: the ownership rules without a graph, then
        // the general split.
        let part = partition::MeshGraph::new(n, triangles, &[], false)
            .and_then(|g| g.finish(triangles, &prob.contact_nodes, 1, vec![0; triangles.len()]))
            .expect("one part");
        let (subs, map) = split(&prob, &part, frictional).expect("the split");
        let pieces = prob.holding.first.len();
        let quality = partition::Quality::one_part(triangles.len(), pieces);
        assert_eq!(quality.to_string(), part.quality.to_string(), "{name}");
        let (sub, whole_map) = split_whole(prob, frictional);
        assert_eq!(subs.len(), 1);
        assert_eq!(sub, subs[0], "{name}: the subproblem");
        assert_eq!(whole_map, map, "{name}: the global map");
    }
}
