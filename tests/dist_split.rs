//! Each rank's subproblems built on its own rank (`dd::dist_split`) from its parts' lists
//! (found on the ranks from their ranges of the file, `dd::ownership`) and the first
//! rank's conditions are the first rank's split (`dd::split::split`) of the same
//! partition, on 1, 2, 3 and 4 ranks with one and two parts per rank, for held-out cases with Dirichlet lines, tractions,
//! body forces, inclined and oblique obstacles, friction and none, two materials, and
//! two bodies in contact (mortar rows, whose masters are ghosts where the cut runs
//! through the contact):
//! the same nodes, coordinates, owners, prescribed values, triangles and bodies, contact
//! nodes in the same order with the same geometry, the same frames, contact dofs and
//! interface dofs, the same ghosts and mortar rows, one global number per interface dof,
//! the same global map and the same partition figures; the parts' loads sum to the
//! whole problem's.
//!
//! The test binary runs itself under `mpirun` (`--oversubscribe`; as root, set
//! OMPI_ALLOW_RUN_AS_ROOT=1 and OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1); each rank then runs
//! [`child`] only.

mod common;

use contact_par::case::{parse_case, Case};
use contact_par::dd::comm::Mpi;
use contact_par::dd::dist_split::{self, Conditions, PartCase};
use contact_par::dd::split::{split, SubProblem};
use contact_par::dd::{locality, ownership};
use contact_par::problem::{self, Problem};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn data(dir: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(dir)
}

/// The cases: (name, directory, case text).
fn cases() -> Vec<(String, PathBuf, String)> {
    let tolerance = data("tolerance");
    let read = |f: &str| std::fs::read_to_string(tolerance.join(f)).expect("a case");
    let wedge = read("wedge.toml");
    let frictionless_wedge = wedge.replace(
        "friction = \"coulomb\"\ncoefficient = 0.9",
        "friction = \"none\"",
    );
    assert_ne!(wedge, frictionless_wedge);
    let two_materials = "title = \"two materials\"\n[mesh]\nfile = \"bimaterial_v41_ascii.msh\"\n\
        [[material]]\ngroup = \"lower\"\nyoung = 1.0e3\npoisson = 0.3\n\
        [[material]]\ngroup = \"upper\"\nyoung = 5.0e3\npoisson = 0.25\n\
        [[dirichlet]]\ngroup = \"left\"\nux = 0.0\n[[traction]]\ngroup = \"top\"\nt = [0.5, -10.0]\n\
        [body_force]\nf = [0.0, -2.0]\n\
        [contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, 0.0]\nobstacle_normal = [0.0, 1.0]\n\
        friction = \"coulomb\"\ncoefficient = 0.3\n";
    vec![
        ("wedge".into(), tolerance.clone(), wedge),
        (
            "frictionless wedge".into(),
            tolerance.clone(),
            frictionless_wedge,
        ),
        ("disc".into(), tolerance.clone(), read("disc.toml")),
        (
            "cantilever".into(),
            tolerance.clone(),
            read("cantilever.toml"),
        ),
        ("wall".into(), tolerance.clone(), read("wall.toml")),
        ("two materials".into(), data("gmsh"), two_materials.into()),
        (
            "two blocks".into(),
            data("bodies"),
            std::fs::read_to_string(data("bodies").join("blocks.toml")).expect("a case"),
        ),
        (
            "disc on a block".into(),
            data("bodies"),
            std::fs::read_to_string(data("bodies").join("disc.toml")).expect("a case"),
        ),
    ]
}

/// Whether any part of `subs` holds a ghost, on any rank. Collective.
fn any_ghost(mpi: &Mpi, subs: &[SubProblem]) -> bool {
    !mpi.all_ok(subs.iter().all(|s| s.ghosts == 0))
}

#[test]
fn each_rank_builds_the_first_ranks_split_of_its_part_on_1_to_4_ranks() {
    common::on_1_to_4_ranks(
        "each_rank_builds_the_first_ranks_split_of_its_part_on_1_to_4_ranks",
        child,
    );
}

fn child() {
    let universe = mpi::initialize().expect("MPI");
    let mpi = Mpi::new(universe.world());
    for (name, dir, text) in cases() {
        let case = parse_case(&text, &name, &dir).expect("a case");
        for k in [1, 2] {
            check(&mpi, &name, &case, k);
        }
    }
}

/// A node's tag in the ranks' file: not its index.
fn tag(file: usize) -> u64 {
    3 * file as u64 + 7
}

fn range(r: usize, size: usize, n: usize) -> std::ops::Range<usize> {
    n * r / size..n * (r + 1) / size
}

/// `k` parts per rank.
fn check(mpi: &Mpi, name: &str, case: &Case, k: usize) {
    let (rank, size) = (mpi.rank, mpi.size);
    let nparts = size * k;
    let (mesh, mesh_name) = contact_par::app::load_mesh(case).expect("the mesh");
    let file_mesh = mesh.clone();
    let prob = problem::build(case, mesh, &mesh_name).expect("the problem");
    let nt = prob.mesh.triangles.len();
    // Compact parts: consecutive triangles of the problem's locality order.
    let element_part: Vec<u32> = (0..nt).map(|t| (t * nparts / nt) as u32).collect();
    let part = partition::partition_from_element_parts(
        prob.mesh.num_nodes(),
        &prob.mesh.triangles,
        &prob.contact_nodes,
        nparts,
        element_part.clone(),
    )
    .expect("a partition");
    let frictional = Problem::is_frictional(case);
    let (subs, map) = split(&prob, &part, frictional).expect("the split");

    // The ranks' ranges of the file: its triangles and nodes.
    let mut part_of_file = vec![0u32; nt];
    for (t, &f) in prob.file_triangle.iter().enumerate() {
        part_of_file[f] = element_part[t];
    }
    let tris = range(rank, size, nt);
    let triangles: Vec<[u64; 3]> = (file_mesh.triangles[tris.clone()].iter())
        .map(|t| t.map(tag))
        .collect();
    let file: Vec<u64> = tris.clone().map(|f| f as u64).collect();
    let parts: Vec<u32> = tris.map(|f| part_of_file[f]).collect();
    let nodes = range(rank, size, file_mesh.num_nodes());
    let tags: Vec<u64> = nodes.clone().map(tag).collect();
    let coords: Vec<f64> = (file_mesh.nodes[nodes].iter())
        .flat_map(|p| [p[0], p[1], 0.0])
        .collect();
    let share = locality::share_nodes(mpi, &tags, &coords);
    let known = locality::directory(mpi, &share).expect("a directory");
    let around = ownership::node_parts(mpi, &triangles, &parts, &known).expect("the nodes");
    let lists = ownership::part_lists(mpi, &file, &triangles, &parts, &around, k);
    let conditions = (rank == 0).then(|| Conditions::of(case, &prob).expect("conditions"));
    let on = PartCase {
        body_force: case.body_force,
        frictional,
    };
    let (built, got) = dist_split::build(mpi, &lists, conditions, on).expect("the parts");
    let what = format!("{name}, rank {rank} of {size}, {k} parts each");
    assert_eq!(built.len(), k, "{what}");
    assert_eq!(got.n_interface, map.n_interface, "{what}");
    assert_eq!(got.n_boundary, map.n_boundary, "{what}");
    assert_eq!(got.contact_counts, map.contact_counts, "{what}");
    for (j, sub) in built.iter().enumerate() {
        same_part(&subs[rank * k + j], sub, &format!("{what}, part {j}"));
    }
    // The partition's figures found on the ranks are the crate's, but that a part's
    // pieces are joined through shared nodes there, not only through edges.
    let figures = ownership::interface_figures(mpi, &around, nparts);
    let quality = dist_split::quality(mpi, &built, &figures, part.quality.edge_cut);
    let disconnected = (part.parts.iter())
        .filter(|q| {
            let t: Vec<[usize; 3]> = q.elements.iter().map(|&e| prob.mesh.triangles[e]).collect();
            partition::node_pieces(&t) > 1
        })
        .count();
    let want = partition::Quality {
        disconnected_parts: disconnected,
        ..part.quality.clone()
    };
    assert_eq!(quality, want, "{what}");
    // The cut runs through the contact somewhere on 3 and 4 ranks: a mortar row's master
    // is then held by another part than its slave node's.
    let tied = prob.contact_masters.iter().any(|m| !m.is_empty());
    if tied && nparts >= 3 {
        assert!(any_ghost(mpi, &built), "{what}: no ghost");
    }

    // Every interface dof has one number over the parts, and the numbers are 0..n; the
    // parts' loads sum to the problem's.
    let mut send = vec![Vec::new(); size];
    for sub in &built {
        for (&d, &b) in sub.boundary_dofs[sub.n_contact_dofs..]
            .iter()
            .zip(&sub.interface_global)
        {
            let f = sub.global_nodes[d / 2] as u64;
            send[0].extend_from_slice(&[f, (d % 2) as u64, b as u64]);
        }
    }
    let numbers = mpi.exchange(send);
    let mut send = vec![Vec::new(); size];
    for sub in &built {
        for (l, &f) in sub.global_nodes.iter().enumerate() {
            for c in 0..2 {
                send[0].extend_from_slice(&[(2 * f + c) as u64, sub.load[2 * l + c].to_bits()]);
            }
        }
    }
    let loads = mpi.exchange(send);
    if rank == 0 {
        let mut number: BTreeMap<[u64; 2], u64> = BTreeMap::new();
        for r in numbers.iter().flat_map(|v| v.chunks_exact(3)) {
            let before = number.insert([r[0], r[1]], r[2]);
            assert!(before.is_none_or(|b| b == r[2]), "{what}: two numbers");
        }
        let all: BTreeSet<u64> = number.values().copied().collect();
        assert_eq!(all.len(), number.len(), "{what}: a number given twice");
        assert_eq!(all, (0..map.n_interface as u64).collect(), "{what}");
        let mut load = vec![0.0; prob.load.len()];
        for r in loads.iter().flat_map(|v| v.chunks_exact(2)) {
            load[r[0] as usize] += f64::from_bits(r[1]);
        }
        // The discs are held by prescribed displacements alone: their loads are all zero.
        let scale = prob.load.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert_eq!(scale > 0.0, !name.starts_with("disc"), "{what}");
        for (v, &f) in prob.file_node.iter().enumerate() {
            for c in 0..2 {
                let (a, b) = (prob.load[2 * v + c], load[2 * f + c]);
                assert!(
                    (a - b).abs() <= 1e-13 * scale,
                    "{what}: load of node {f}: {a} against {b}"
                );
            }
        }
    }
}

/// `got` is `want` but for the local numbering, the interface's global numbers and the
/// loads (checked by the caller).
fn same_part(want: &SubProblem, got: &SubProblem, what: &str) {
    let by_file = |s: &SubProblem| -> BTreeMap<usize, usize> {
        s.global_nodes
            .iter()
            .enumerate()
            .map(|(l, &f)| (f, l))
            .collect()
    };
    let (w, g) = (by_file(want), by_file(got));
    assert_eq!(
        w.keys().collect::<Vec<_>>(),
        g.keys().collect::<Vec<_>>(),
        "{what}: nodes"
    );
    let frame = |s: &SubProblem, l: usize| s.frames.iter().find(|f| f.0 == l).map(|f| f.1);
    for (f, (&lw, &lg)) in w.iter().map(|(f, l)| (f, (l, &g[f]))) {
        assert_eq!(want.nodes[lw], got.nodes[lg], "{what}: node {f}");
        assert_eq!(want.owned[lw], got.owned[lg], "{what}: owner of {f}");
        assert_eq!(
            want.fixed[2 * lw..2 * lw + 2],
            got.fixed[2 * lg..2 * lg + 2],
            "{what}: {f}"
        );
        assert_eq!(frame(want, lw), frame(got, lg), "{what}: frame of {f}");
    }
    let triangles = |s: &SubProblem| -> Vec<([usize; 3], u32)> {
        let mut t: Vec<([usize; 3], u32)> = (s.triangles.iter().zip(&s.body))
            .map(|(t, &b)| {
                let mut f = t.map(|l| s.global_nodes[l]);
                f.sort_unstable();
                (f, b)
            })
            .collect();
        t.sort_unstable();
        t
    };
    assert_eq!(triangles(want), triangles(got), "{what}: triangles");
    assert!(got.triangles.iter().all(|t| {
        let [a, b, c] = t.map(|l| got.nodes[l]);
        (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]) > 0.0
    }));
    let files = |s: &SubProblem, l: &[usize]| -> Vec<usize> {
        l.iter().map(|&l| s.global_nodes[l]).collect()
    };
    assert_eq!(
        files(want, &want.contact_nodes),
        files(got, &got.contact_nodes),
        "{what}: contact nodes"
    );
    assert!(!want.contact_nodes.is_empty() || want.rank > 0 || want.contact.w.is_empty());
    let (a, b) = (&want.contact, &got.contact);
    assert_eq!((&a.w, &a.g, &a.s), (&b.w, &b.g, &b.s), "{what}");
    assert_eq!(
        (&a.normal, &a.pair, &a.part),
        (&b.normal, &b.pair, &b.part),
        "{what}"
    );
    let dofs = |s: &SubProblem, d: &[usize]| -> BTreeSet<(usize, usize)> {
        d.iter().map(|&d| (s.global_nodes[d / 2], d % 2)).collect()
    };
    let (wc, wi) = want.boundary_dofs.split_at(want.n_contact_dofs);
    let (gc, gi) = got.boundary_dofs.split_at(got.n_contact_dofs);
    assert_eq!(dofs(want, wc), dofs(got, gc), "{what}: contact dofs");
    assert_eq!(dofs(want, wi), dofs(got, gi), "{what}: interface dofs");
    assert!(
        got.interface_global.windows(2).all(|w| w[0] < w[1]),
        "{what}"
    );
    assert_eq!(want.interface_nodes, got.interface_nodes, "{what}");
    assert_eq!(want.ghosts, got.ghosts, "{what}");
    // The ghosts come last, and each mortar row reads the same nodes with the same
    // coefficients.
    let ghosts = |s: &SubProblem| -> BTreeSet<usize> {
        s.global_nodes[s.nodes.len() - s.ghosts..]
            .iter()
            .copied()
            .collect()
    };
    assert_eq!(ghosts(want), ghosts(got), "{what}: ghosts");
    let rows = |s: &SubProblem| -> Vec<Vec<(usize, f64)>> {
        (s.contact_masters.iter())
            .map(|m| m.iter().map(|&(l, c)| (s.global_nodes[l], c)).collect())
            .collect()
    };
    assert_eq!(rows(want), rows(got), "{what}: mortar rows");
}
