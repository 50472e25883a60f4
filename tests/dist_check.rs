//! The mesh checks made by the ranks on their parts (`dd::dist_check`) are the serial
//! check of the whole mesh (`mesh::validate::check`), on 1, 2, 3 and 4 ranks with one
//! and two parts per rank: the same message for each fault (a degenerate triangle, an
//! inverted one, an unused node, duplicate nodes, a slit), the same boundary edges, run
//! with the body on their left, and the same separate parts, numbered by their lowest
//! node; two bodies that touch through coincident nodes are no fault. The file lists
//! the triangles shuffled, some clockwise, and its node tags are not their indices; the
//! parts follow the file's triangle order, so that most nodes lie on an interface.
//!
//! The test binary runs itself under `mpirun` (`--oversubscribe`; as root, set
//! OMPI_ALLOW_RUN_AS_ROOT=1 and OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1); each rank then runs
//! [`child`] only.

mod common;
use common::uneven_range;

use contact_par::dd::comm::Mpi;
use contact_par::dd::dist_check::{self, Checked};
use contact_par::dd::{locality, ownership};
use contact_par::mesh::{validate, Mesh};
use mpi::traits::*;
use std::collections::HashSet;

const NAME: &str = "shapes.msh";

fn tag(node: usize) -> u64 {
    3 * node as u64 + 7
}

/// An `nx` by `ny` grid of unit cells from `x0`, two triangles each: its nodes and
/// triangles, numbered from `first`.
fn grid(nx: usize, ny: usize, x0: f64, first: usize) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let id = |i: usize, j: usize| first + j * (nx + 1) + i;
    let nodes = (0..=ny)
        .flat_map(|j| (0..=nx).map(move |i| [x0 + i as f64, j as f64 * 0.5]))
        .collect();
    let mut t = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (nodes, t)
}

/// The triangles in a fixed shuffled order, every third listed clockwise.
fn shuffled(t: &[[usize; 3]]) -> Vec<[usize; 3]> {
    let n = t.len();
    let stride = (n / 2 + 1..n).find(|s| gcd(*s, n) == 1).unwrap_or(1);
    (0..n)
        .map(|k| {
            let mut tri = t[(k * stride) % n];
            if k % 3 == 0 {
                tri.swap(0, 1);
            }
            tri
        })
        .collect()
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The meshes, each a name, its nodes and its triangles (file order).
#[allow(clippy::type_complexity)]
fn meshes() -> Vec<(&'static str, Vec<[f64; 2]>, Vec<[usize; 3]>)> {
    let (nx, ny) = (9, 6);
    let (nodes, tris) = grid(nx, ny, 0.0, 0);
    let sound = shuffled(&tris);
    let mut out = vec![("sound", nodes.clone(), sound.clone())];

    // Two bodies apart, and two touching along x = 9 through their own nodes.
    for (name, x0) in [("apart", 11.0), ("touching", 9.0)] {
        let (more, more_tris) = grid(4, ny, x0, nodes.len());
        let mut all = nodes.clone();
        all.extend(more);
        let mut t = tris.clone();
        t.extend(more_tris);
        out.push((name, all, shuffled(&t)));
    }

    // A node moved onto the line of two others: a degenerate triangle (and more faults
    // after it).
    let mut flat = nodes.clone();
    let at = |i: usize, j: usize| j * (nx + 1) + i;
    flat[at(4, 3)] = [5.0, 1.25];
    out.push(("degenerate", flat, sound.clone()));

    // A node moved across its neighbours: inverted triangles.
    let mut folded = nodes.clone();
    folded[at(4, 3)] = [5.6, 1.7];
    out.push(("folded", folded, sound.clone()));

    // Two nodes no triangle uses, one of them far away.
    let mut idle = nodes.clone();
    idle.push([40.0, 1.0]);
    idle.insert(5, [-3.0, 2.0]);
    let moved: Vec<[usize; 3]> = (sound.iter())
        .map(|t| t.map(|v| if v >= 5 { v + 1 } else { v }))
        .collect();
    out.push(("unused", idle, moved));

    // An unused node on top of a used one.
    let mut twice = nodes.clone();
    twice.push(nodes[at(2, 2)]);
    out.push(("duplicate", twice, sound.clone()));

    // A slit: the lower half of the line x = 4 has a second node on the right side.
    let mut slit = nodes.clone();
    let mut copy = std::collections::HashMap::new();
    for j in 0..=2 {
        copy.insert(at(4, j), slit.len());
        slit.push(nodes[at(4, j)]);
    }
    let right = |t: &[usize; 3]| t.iter().any(|&v| v % (nx + 1) > 4);
    let cut: Vec<[usize; 3]> = (tris.iter())
        .map(|t| match right(t) {
            true => t.map(|v| *copy.get(&v).unwrap_or(&v)),
            false => *t,
        })
        .collect();
    out.push(("slit", slit, shuffled(&cut)));
    out
}

fn child() {
    let universe = mpi::initialize().expect("MPI");
    let world = universe.world();
    let mpi = Mpi::new(world.duplicate());
    let mut faults = 0;
    for (name, nodes, tris) in meshes() {
        for per_rank in [1, 2] {
            faults += compare(&mpi, name, &nodes, &tris, per_rank) as usize;
        }
    }
    assert_eq!(faults, 2 * 5, "every faulty mesh refused");
}

/// The ranks' check of the mesh against the serial one; whether it found a fault.
fn compare(
    mpi: &Mpi,
    name: &str,
    nodes: &[[f64; 2]],
    tris: &[[usize; 3]],
    per_rank: usize,
) -> bool {
    let (rank, size) = (mpi.rank, mpi.size);
    let what = format!("{name}, {size} ranks x {per_rank}");
    let mut mesh = Mesh {
        nodes: nodes.to_vec(),
        triangles: tris.to_vec(),
        ..Mesh::default()
    };
    let serial = validate::check(&mut mesh, NAME);

    let mine = uneven_range(rank, size, nodes.len());
    let tags: Vec<u64> = mine.clone().map(tag).collect();
    let coords: Vec<f64> = (mine.map(|v| nodes[v]))
        .flat_map(|p| [p[0], p[1], 0.0])
        .collect();
    let share: Vec<[u64; 3]> = tris[uneven_range(rank, size, tris.len())]
        .iter()
        .map(|t| t.map(tag))
        .collect();
    let sorted = locality::sort_triangles(mpi, &tags, &coords, &share).expect("a mesh");
    let nparts = size * per_rank;
    let parts: Vec<u32> = (sorted.file.iter())
        .map(|&f| (f as usize * nparts / tris.len()) as u32)
        .collect();
    let around =
        ownership::node_parts(mpi, &sorted.triangles, &parts, &sorted.nodes).expect("nodes");
    let lists = ownership::part_lists(
        mpi,
        &sorted.file,
        &sorted.triangles,
        &parts,
        &around,
        per_rank,
    );
    let bbox = dist_check::bounding_box(mpi, &sorted.nodes.xy);
    let checked = dist_check::check(mpi, (&sorted.nodes, &around), &lists, bbox);
    let checked = checked.expect("no MPI fault");
    match (serial, checked) {
        (Err(e), Err(fault)) => {
            assert_eq!(fault.message(NAME, |_| None), e.to_string(), "{what}");
            true
        }
        (Ok(boundary), Ok(c)) => {
            same_boundary(mpi, &c, &boundary, &mesh, &what);
            same_parts(&c, &lists, &mesh, &what);
            false
        }
        (s, d) => panic!("{what}: serial {s:?}, on the ranks {d:?}"),
    }
}

/// The boundary edges found on every rank are the serial ones, each once, with the
/// third corner of its triangle on its left.
fn same_boundary(
    mpi: &Mpi,
    c: &Checked,
    serial: &HashSet<(usize, usize)>,
    mesh: &Mesh,
    what: &str,
) {
    let mine: Vec<u64> = c.boundary.iter().flatten().copied().collect();
    let counts = mpi.all_gather_counts(mine.len());
    let Some(all) = mpi.gather_varcount(&mine, &counts) else {
        return;
    };
    let edges: Vec<[usize; 2]> = (all.chunks_exact(2))
        .map(|e| [e[0] as usize, e[1] as usize])
        .collect();
    let got: HashSet<(usize, usize)> = edges
        .iter()
        .map(|e| (e[0].min(e[1]), e[0].max(e[1])))
        .collect();
    assert_eq!(got.len(), edges.len(), "{what}: an edge twice");
    assert_eq!(&got, serial, "{what}");
    for [a, b] in edges {
        let t = (mesh.triangles.iter())
            .find(|t| t.contains(&a) && t.contains(&b))
            .expect("its triangle");
        let third = t.iter().find(|&&v| v != a && v != b).copied().unwrap();
        let area = contact_par::mesh::signed_area2(&mesh.nodes, [a, b, third]);
        assert!(area > 0.0, "{what}: edge {a} -> {b} runs clockwise");
    }
}

/// Each node's separate part is the serial one, and so is each part's lowest node.
fn same_parts(c: &Checked, lists: &[ownership::PartLists], mesh: &Mesh, what: &str) {
    let (part, count) = validate::parts(mesh);
    assert_eq!(c.part_first.len(), count, "{what}");
    for (k, &first) in c.part_first.iter().enumerate() {
        assert_eq!(part[first as usize], k, "{what}: part {k}");
        assert!(part[..first as usize].iter().all(|&p| p != k), "{what}");
    }
    for (l, parts) in lists.iter().zip(&c.node_part) {
        for (&f, &q) in l.file_nodes.iter().zip(parts) {
            assert_eq!(q as usize, part[f as usize], "{what}: node {f}");
        }
    }
    let (lo, hi) = validate::bounding_box(&mesh.nodes);
    assert_eq!(c.bbox, (lo, hi), "{what}");
}

#[test]
fn the_checks_on_1_to_4_ranks_are_the_serial_ones() {
    common::on_1_to_4_ranks("the_checks_on_1_to_4_ranks_are_the_serial_ones", child);
}
