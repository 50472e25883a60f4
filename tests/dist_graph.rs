//! The dual graph built by every rank from its range of the triangles
//! (`dd::dist_graph`) is the serial one (`partition::dual_graph`), on 1, 2, 3 and 4
//! ranks: a structured rectangle whose triangles come shuffled and whose node tags are
//! not their indices, spread unevenly (on 4 ranks one rank holds none); its boundary is
//! the rectangle's outline, its edge cut of given parts the serial count, and a triangle
//! turned round is found as a fold.
//!
//!
//! The locality order the ranks find together (`dd::locality`) is one order of the
//! whole mesh, whatever the ranks: its ranges put end to end are the triangles sorted
//! by their first node's Hilbert key, from shares whose tags and coordinates end at
//! different places; a triangle's first node that no rank holds makes every rank give
//! up. The cut of the
//! shares (`dd::share_cut`) reaches the first rank as a part per file triangle, its
//! edge cut the serial count. The nodes' parts found on the ranks' directory
//! (`dd::ownership`) follow the partition crate's ownership rules, node by node, with
//! its interface figures; and the lists of each part built on its own rank (its
//! triangles, nodes, owned nodes, interface and neighbours) are the crate's.
//!
//! The test binary runs itself under `mpirun` (`--oversubscribe`; as root, set
//! OMPI_ALLOW_RUN_AS_ROOT=1 and OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1); each rank then runs
//! [`child`] only.

mod common;
use common::uneven_range;

use contact_par::dd::comm::Mpi;
use contact_par::dd::{dist_graph, locality, ownership, share_cut};
use contact_par::mesh::renumber::hilbert_keys;
use mpi::collective::SystemOperation;
use mpi::traits::*;

const NX: usize = 23;
const NY: usize = 11;

/// The rectangle's triangles (node indices), counter-clockwise, in a shuffled order.
fn triangles() -> Vec<[usize; 3]> {
    let id = |i: usize, j: usize| j * (NX + 1) + i;
    let mut t = Vec::new();
    for j in 0..NY {
        for i in 0..NX {
            t.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            t.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    // A fixed permutation: stride coprime with the count.
    let n = t.len();
    let stride = (1..n)
        .rev()
        .find(|s| gcd(*s, n) == 1 && *s < n / 2 + 7)
        .unwrap();
    (0..n).map(|k| t[(k * stride) % n]).collect()
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

fn tag(node: usize) -> u64 {
    3 * node as u64 + 7
}

fn child() {
    let universe = mpi::initialize().expect("MPI");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let all = triangles();
    let nodes = (NX + 1) * (NY + 1);
    let serial = partition::dual_graph(nodes, &all).expect("a valid mesh");
    let mine = uneven_range(rank, size, all.len());
    let tags: Vec<[u64; 3]> = all[mine.clone()].iter().map(|t| t.map(tag)).collect();
    let mpi = Mpi::new(world.duplicate());
    let d = dist_graph::dual_graph(&mpi, &tags);
    assert_eq!(d.first as usize, mine.start);
    assert_eq!(d.xadj.len(), mine.len() + 1);
    for (i, g) in mine.clone().enumerate() {
        let row: Vec<usize> = d.adjncy[d.xadj[i]..d.xadj[i + 1]]
            .iter()
            .map(|&v| v as usize)
            .collect();
        assert_eq!(row, serial.neighbours(g), "triangle {g} on rank {rank}");
    }
    let mut edges = 0u64;
    world.all_reduce_into(
        &(d.boundary.len() as u64),
        &mut edges,
        SystemOperation::sum(),
    );
    assert_eq!(edges as usize, 2 * (NX + NY), "the outline");
    for e in &d.boundary {
        let on = |t: u64| {
            let n = ((t - 7) / 3) as usize;
            let (i, j) = (n % (NX + 1), n / (NX + 1));
            (i == 0 || i == NX, j == 0 || j == NY)
        };
        let (a, b) = (on(e.nodes[0]), on(e.nodes[1]));
        assert!((a.0 && b.0) || (a.1 && b.1), "{e:?} is not on the outline");
    }
    assert!(d.folds.is_empty(), "{:?}", d.folds);

    // The edge cut of parts given by the global ids, counted across the ranks.
    let part = |g: usize| ((g * 7) / all.len()) as i32;
    let parts: Vec<i32> = mine.clone().map(part).collect();
    let counts: Vec<usize> = (0..size)
        .map(|r| uneven_range(r, size, all.len()).len())
        .collect();
    let cut = dist_graph::edge_cut(&mpi, &d, &parts, &counts);
    let serial_cut = (0..all.len())
        .map(|g| {
            serial
                .neighbours(g)
                .iter()
                .filter(|&&h| part(h) != part(g))
                .count()
        })
        .sum::<usize>()
        / 2;
    assert!(serial_cut > 0);
    assert_eq!(cut, serial_cut, "rank {rank}");

    // One triangle turned round (clockwise): its three edges are run twice one way,
    // except on the outline.
    let mut turned = tags.clone();
    if rank == 0 && !turned.is_empty() {
        turned[0].swap(1, 2);
    }
    let d = dist_graph::dual_graph(&mpi, &turned);
    let mut folds = 0u64;
    world.all_reduce_into(&(d.folds.len() as u64), &mut folds, SystemOperation::sum());
    assert!((1..=3).contains(&folds), "{folds} folds");
}

#[test]
fn the_dual_graph_built_on_1_to_4_ranks_is_the_serial_one() {
    common::on_1_to_4_ranks(
        "the_dual_graph_built_on_1_to_4_ranks_is_the_serial_one",
        child,
    );
}

#[test]
fn the_locality_order_and_the_cut_of_the_shares_on_1_to_4_ranks() {
    common::on_1_to_4_ranks(
        "the_locality_order_and_the_cut_of_the_shares_on_1_to_4_ranks",
        locality_child,
    );
}

/// The rectangle's node coordinates, by node index.
fn xy(node: usize) -> [f64; 2] {
    [
        (node % (NX + 1)) as f64 * 0.7,
        (node / (NX + 1)) as f64 * 0.4,
    ]
}

/// Rank r's range of `n` items on `size` ranks, weighted `weight(r)`.
fn weighted(
    r: usize,
    size: usize,
    n: usize,
    weight: impl Fn(usize) -> usize,
) -> std::ops::Range<usize> {
    let total: usize = (0..size).map(&weight).sum();
    let before: usize = (0..r).map(&weight).sum();
    n * before / total..n * (before + weight(r)) / total
}

fn locality_child() {
    let universe = mpi::initialize().expect("MPI");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let mpi = Mpi::new(world.duplicate());
    let all = triangles();
    let nodes = (NX + 1) * (NY + 1);
    // The file lists the nodes backwards; the shares of the tags and of the coordinates
    // end at different nodes.
    let file_node = |k: usize| nodes - 1 - k;
    let tags_at = weighted(rank, size, nodes, |q| q + 1);
    let coords_at = weighted(rank, size, nodes, |q| size - q);
    let tags: Vec<u64> = tags_at.map(|k| tag(file_node(k))).collect();
    let coords: Vec<f64> = (coords_at.map(file_node))
        .flat_map(|n| [xy(n)[0], xy(n)[1], 0.0])
        .collect();
    let mine = uneven_range(rank, size, all.len());
    let tris: Vec<[u64; 3]> = all[mine].iter().map(|t| t.map(tag)).collect();

    let sorted = locality::sort_triangles(&mpi, &tags, &coords, &tris).expect("a mesh");
    // The serial order: by the first node's key on the grid over all nodes, then by
    // the file's index.
    let points: Vec<[f64; 2]> = all.iter().map(|t| xy(t[0])).collect();
    let bbox = [[0.0, 0.0], [NX as f64 * 0.7, NY as f64 * 0.4]];
    let keys = hilbert_keys(&points, bbox);
    let mut serial: Vec<usize> = (0..all.len()).collect();
    serial.sort_by_key(|&i| (keys[i], i));
    let n = sorted.file.len();
    assert_eq!(sorted.counts[rank], n);
    assert_eq!(sorted.counts.iter().sum::<usize>(), all.len());
    let first = sorted.first as usize;
    let expected: Vec<u64> = serial[first..first + n].iter().map(|&i| i as u64).collect();
    assert_eq!(sorted.file, expected, "rank {rank}");
    for (t, &f) in sorted.triangles.iter().zip(&sorted.file) {
        assert_eq!(*t, all[f as usize].map(tag));
    }
    let mean = all.len() / size;
    assert!(
        n <= 2 * mean + 1,
        "rank {rank}: {n} triangles of {}",
        all.len()
    );

    // A triangle whose first node no rank holds: every rank gives up.
    let mut bad = tris.clone();
    if let Some(t) = bad.first_mut() {
        t[0] = 1_000_000;
    }
    assert!(locality::sort_triangles(&mpi, &tags, &coords, &bad).is_none());

    // The cut, with parts not a multiple of the ranks (from 2 ranks): a part per file
    // triangle on the first rank, the serial edge cut; with as many parts on every rank
    // (one, two): each rank its parts' lists, none gathered.
    for nparts in [size + 1, size, 2 * size] {
        let cut = share_cut::cut_shares(&mpi, (&tags, &coords), &tris, (nparts, 0.03), |_, _| {
            Vec::new()
        })
        .expect("a cut");
        check_cut(&mpi, &cut, nparts, &all, nodes);
    }

    // Each node's parts on the directory, for parts given by the file's index (the
    // shuffled file scatters them: most nodes lie on the interface).
    let nparts = 5;
    let part_of = |f: usize| (f * nparts / all.len()) as u32;
    let parts: Vec<u32> = sorted.file.iter().map(|&f| part_of(f as usize)).collect();
    let share = locality::share_nodes(&mpi, &tags, &coords);
    let known = locality::directory(&mpi, &share).expect("a directory");
    // The directory the order was found with is the same.
    assert_eq!(sorted.nodes, known);
    let around = ownership::node_parts(&mpi, &sorted.triangles, &parts, &known).expect("nodes");
    let element_part: Vec<u32> = (0..all.len()).map(part_of).collect();
    let serial = partition::partition_from_element_parts(nodes, &all, &[], nparts, element_part)
        .expect("a partition");
    for (k, &t) in around.tags.iter().enumerate() {
        let n = ((t - 7) / 3) as usize;
        assert_eq!(around.owner(k), serial.node_owner[n], "node {n}");
        assert_eq!(
            (around.file[k], around.xy[k]),
            ((nodes - 1 - n) as u64, xy(n))
        );
        let touching: Vec<u32> = (0..nparts as u32)
            .filter(|&q| serial.parts[q as usize].nodes.binary_search(&n).is_ok())
            .collect();
        assert_eq!(around.of(k), &touching[..], "node {n}");
    }
    let mut held = 0u64;
    world.all_reduce_into(
        &(around.tags.len() as u64),
        &mut held,
        SystemOperation::sum(),
    );
    assert_eq!(held as usize, nodes, "every node on one rank");
    let figures = ownership::interface_figures(&mpi, &around, nparts);
    assert_eq!(figures.interface_nodes, serial.quality.interface_nodes);
    let per_part: Vec<usize> = serial.parts.iter().map(|q| q.interface.len()).collect();
    assert_eq!(figures.per_part, per_part);
    assert_eq!(figures.neighbours, serial.quality.neighbours);
    assert!(figures.interface_nodes > 0);
    // A triangle on a node no share holds: every rank gives up.
    let bad_tris: Vec<[u64; 3]> = (sorted.triangles.iter().enumerate())
        .map(|(i, t)| if i == 0 { [t[0], t[1], 5_000_000] } else { *t })
        .collect();
    assert!(ownership::node_parts(&mpi, &bad_tris, &parts, &known).is_none());

    // Each rank's two parts, on their rank: the partition crate's lists of each.
    let nparts = 2 * size;
    let part_of = |f: usize| (f * nparts / all.len()) as u32;
    let parts: Vec<u32> = sorted.file.iter().map(|&f| part_of(f as usize)).collect();
    let around = ownership::node_parts(&mpi, &sorted.triangles, &parts, &known).expect("nodes");
    let lists = ownership::part_lists(&mpi, &sorted.file, &sorted.triangles, &parts, &around, 2);
    let element_part: Vec<u32> = (0..all.len()).map(part_of).collect();
    let serial = partition::partition_from_element_parts(nodes, &all, &[], nparts, element_part)
        .expect("a partition");
    let tags = |v: &[usize]| -> Vec<u64> { v.iter().map(|&n| tag(n)).collect() };
    assert_eq!(lists.len(), 2);
    for l in &lists {
        let q = &serial.parts[l.part as usize];
        assert_eq!(l.part as usize / 2, rank);
        let elements: Vec<u64> = q.elements.iter().map(|&e| e as u64).collect();
        assert_eq!(l.elements, elements, "part {}", l.part);
        for (t, &e) in l.triangles.iter().zip(&l.elements) {
            assert_eq!(*t, all[e as usize].map(tag));
        }
        assert_eq!(l.nodes, tags(&q.nodes), "part {}", l.part);
        let places: Vec<(u64, [f64; 2])> = (q.nodes.iter())
            .map(|&n| ((nodes - 1 - n) as u64, xy(n)))
            .collect();
        let got: Vec<(u64, [f64; 2])> = l.file_nodes.iter().copied().zip(l.xy.clone()).collect();
        assert_eq!(got, places, "part {}", l.part);
        assert_eq!(l.owned, q.owned, "part {}", l.part);
        assert_eq!(l.interface, tags(&q.interface), "part {}", l.part);
        let neighbours: Vec<(u32, Vec<u64>)> =
            q.neighbours.iter().map(|(p, n)| (*p, tags(n))).collect();
        assert_eq!(l.neighbours, neighbours, "part {}", l.part);
    }
}

/// The cut's parts (gathered, or from the ranks' lists) on the first rank: every part
/// used, and the serial count of the edges cut.
fn check_cut(
    mpi: &Mpi,
    cut: &share_cut::ShareCut,
    nparts: usize,
    all: &[[usize; 3]],
    nodes: usize,
) {
    let (rank, size) = (mpi.rank, mpi.size);
    assert_eq!(cut.nparts, nparts);
    assert_eq!(cut.triangles, all.len());
    let listed = nparts % size == 0;
    assert_eq!(
        cut.lists.is_some(),
        listed,
        "{nparts} parts on {size} ranks"
    );
    assert_eq!(cut.figures.is_some(), listed);
    // Each part's triangles from its lists, to the first rank.
    let mut send = vec![Vec::new(); size];
    for l in cut.lists.iter().flatten() {
        assert_eq!(
            l.part as usize / (nparts / size),
            rank,
            "part {} here",
            l.part
        );
        send[0].extend(l.elements.iter().flat_map(|&e| [e, u64::from(l.part)]));
    }
    let listed_parts = mpi.exchange(send);
    if rank != 0 {
        assert!(cut.parts.is_none());
        return;
    }
    let parts = match &cut.parts {
        Some(parts) => {
            assert!(!listed, "the parts were gathered");
            parts.clone()
        }
        None => {
            assert!(
                listed,
                "{nparts} parts on {size} ranks: none reached the first rank"
            );
            let mut parts = vec![u32::MAX; all.len()];
            for r in listed_parts.iter().flat_map(|v| v.chunks_exact(2)) {
                parts[r[0] as usize] = r[1] as u32;
            }
            parts
        }
    };
    assert_eq!(parts.len(), all.len());
    for q in 0..nparts as u32 {
        assert!(parts.contains(&q), "part {q} is empty");
    }
    let serial_graph = partition::dual_graph(nodes, all).expect("a valid mesh");
    let serial_cut = (0..all.len())
        .map(|g| {
            (serial_graph.neighbours(g).iter())
                .filter(|&&h| parts[h] != parts[g])
                .count()
        })
        .sum::<usize>()
        / 2;
    assert_eq!(cut.edge_cut, serial_cut);
}
