//! Properties of the dual graph and of partitions on generated meshes.

mod common;

use common::{irregular, rectangle, rectangle_with, two_bodies};
use partition::{
    dual_graph, partition_mesh, partition_mesh_with_ties, MeshGraph, Partition, PartitionError,
    NO_PART,
};
use std::collections::BTreeSet;

type Mesh = (usize, Vec<[usize; 3]>, Vec<usize>);

fn check_dual_graph_symmetric(num_nodes: usize, tris: &[[usize; 3]]) {
    let g = dual_graph(num_nodes, tris).unwrap();
    assert_eq!(g.num_vertices(), tris.len());
    for e in 0..g.num_vertices() {
        let nb = g.neighbours(e);
        assert!(
            nb.windows(2).all(|w| w[0] < w[1]),
            "row {e} sorted, no repeats"
        );
        for &f in nb {
            assert_ne!(e, f);
            assert!(g.neighbours(f).contains(&e), "{e} -> {f} but not back");
            let common = tris[e].iter().filter(|n| tris[f].contains(n)).count();
            assert_eq!(common, 2, "{e} and {f} share an edge");
        }
    }
}

#[test]
fn dual_graph_of_rectangle() {
    let (nx, ny) = (7, 5);
    let (n, tris, _) = rectangle(nx, ny);
    check_dual_graph_symmetric(n, &tris);
    let g = dual_graph(n, &tris).unwrap();
    // Diagonals, interior vertical edges, interior horizontal edges.
    assert_eq!(g.num_edges(), nx * ny + (nx - 1) * ny + nx * (ny - 1));
    // A triangle has 3 neighbours exactly when none of its edges is on the boundary.
    let on_boundary = |a: usize, b: usize| {
        let (ia, ja, ib, jb) = (a % (nx + 1), a / (nx + 1), b % (nx + 1), b / (nx + 1));
        (ia == ib && (ia == 0 || ia == nx)) || (ja == jb && (ja == 0 || ja == ny))
    };
    for (e, t) in tris.iter().enumerate() {
        let boundary_edges = (0..3)
            .filter(|&k| on_boundary(t[k], t[(k + 1) % 3]))
            .count();
        assert_eq!(g.neighbours(e).len(), 3 - boundary_edges, "triangle {e}");
    }
}

#[test]
fn dual_graph_of_irregular_mesh() {
    let (n, tris, _) = irregular();
    check_dual_graph_symmetric(n, &tris);
    let g = dual_graph(n, &tris).unwrap();
    // Count mesh edges used by two triangles, independently of the implementation.
    let mut count = std::collections::BTreeMap::new();
    for t in &tris {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    assert_eq!(g.num_edges(), count.values().filter(|&&c| c == 2).count());
    // The fan's triangles: the one on the rectangle side has 3, the others 2.
    let fan = tris.len() - 6;
    let degrees: Vec<usize> = (fan..tris.len()).map(|e| g.neighbours(e).len()).collect();
    assert_eq!(degrees, vec![3, 2, 2, 2, 2, 2]);
}

/// Checks every invariant a partition promises, from scratch.
fn check_partition(mesh: &Mesh, p: &Partition) {
    let (num_nodes, tris, contact) = mesh;
    let nparts = p.nparts;
    assert_eq!(p.parts.len(), nparts);
    assert_eq!(p.element_part.len(), tris.len());

    // Elements: each in exactly one part, parts non-empty and sorted.
    let mut seen = vec![0; tris.len()];
    for (k, part) in p.parts.iter().enumerate() {
        assert!(!part.elements.is_empty(), "part {k} empty");
        assert!(part.elements.windows(2).all(|w| w[0] < w[1]));
        for &e in &part.elements {
            seen[e] += 1;
            assert_eq!(p.element_part[e] as usize, k);
        }
    }
    assert!(seen.iter().all(|&s| s == 1));

    // Which parts touch each node, computed naively.
    let mut touching = vec![BTreeSet::new(); *num_nodes];
    for (e, t) in tris.iter().enumerate() {
        for &n in t {
            touching[n].insert(p.element_part[e]);
        }
    }
    let mut owned_count = vec![0; *num_nodes];
    for (k, part) in p.parts.iter().enumerate() {
        let k = k as u32;
        let expect: Vec<usize> = (0..*num_nodes)
            .filter(|&n| touching[n].contains(&k))
            .collect();
        assert_eq!(part.nodes, expect, "nodes of part {k}");
        assert_eq!(part.owned.len(), part.nodes.len());
        for (&n, &o) in part.nodes.iter().zip(&part.owned) {
            assert_eq!(o, p.node_owner[n] == k);
            owned_count[n] += o as usize;
        }
        // Interface iff touched by another part.
        let expect: Vec<usize> = expect
            .into_iter()
            .filter(|&n| touching[n].len() > 1)
            .collect();
        assert_eq!(part.interface, expect, "interface of part {k}");
        // Neighbour lists: sorted by part, symmetric, exactly the shared nodes.
        assert!(part.neighbours.windows(2).all(|w| w[0].0 < w[1].0));
        for (q, list) in &part.neighbours {
            assert_ne!(*q, k);
            let expect: Vec<usize> = (0..*num_nodes)
                .filter(|&n| touching[n].contains(&k) && touching[n].contains(q))
                .collect();
            assert!(!expect.is_empty());
            assert_eq!(list, &expect);
            let back = p.parts[*q as usize]
                .neighbours
                .iter()
                .find(|(r, _)| *r == k)
                .expect("neighbour relation is symmetric");
            assert_eq!(&back.1, list);
        }
        let n_neighbours = (0..nparts as u32)
            .filter(|&q| q != k && part.interface.iter().any(|&n| touching[n].contains(&q)))
            .count();
        assert_eq!(part.neighbours.len(), n_neighbours);
        assert_eq!(p.quality.neighbours[k as usize], n_neighbours);
    }
    // Every used node owned exactly once, by the lowest touching part.
    for n in 0..*num_nodes {
        match touching[n].first() {
            Some(&low) => {
                assert_eq!(owned_count[n], 1, "node {n}");
                assert_eq!(p.node_owner[n], low);
            }
            None => {
                assert_eq!(owned_count[n], 0);
                assert_eq!(p.node_owner[n], NO_PART);
            }
        }
    }
    // Contact nodes: each owned by exactly one part, its owner.
    let unique: BTreeSet<usize> = contact.iter().copied().collect();
    let mut all_contact: Vec<usize> = Vec::new();
    for (k, part) in p.parts.iter().enumerate() {
        assert!(part.contact_nodes.windows(2).all(|w| w[0] < w[1]));
        for &n in &part.contact_nodes {
            assert_eq!(p.node_owner[n] as usize, k);
        }
        all_contact.extend(&part.contact_nodes);
    }
    all_contact.sort();
    assert_eq!(all_contact, unique.into_iter().collect::<Vec<_>>());

    // Quality figures recomputed naively.
    let g = dual_graph(*num_nodes, tris).unwrap();
    let cut = (0..tris.len())
        .flat_map(|e| g.neighbours(e).iter().map(move |&f| (e, f)))
        .filter(|&(e, f)| p.element_part[e] != p.element_part[f])
        .count()
        / 2;
    assert_eq!(p.quality.edge_cut, cut);
    let max = p.parts.iter().map(|q| q.elements.len()).max().unwrap();
    let imbalance = max as f64 * nparts as f64 / tris.len() as f64;
    assert!((p.quality.imbalance - imbalance).abs() < 1e-12);
    let n_interface = touching.iter().filter(|t| t.len() > 1).count();
    assert_eq!(p.quality.interface_nodes, n_interface);
    if nparts == 1 {
        assert_eq!(cut, 0);
        assert_eq!(n_interface, 0);
    }
}

#[test]
fn rectangle_40x40_into_1_to_8_parts() {
    let mesh = rectangle(40, 40);
    for nparts in 1..=8 {
        let p = partition_mesh(mesh.0, &mesh.1, &mesh.2, nparts).unwrap();
        check_partition(&mesh, &p);
        assert!(
            p.quality.imbalance <= 1.1,
            "{nparts} parts: imbalance {}",
            p.quality.imbalance
        );
        assert_eq!(
            p.quality.disconnected_parts, 0,
            "{nparts} parts: {}",
            p.quality
        );
    }
}

#[test]
fn irregular_mesh_into_1_to_8_parts() {
    let mesh = irregular();
    for nparts in 1..=8 {
        let p = partition_mesh(mesh.0, &mesh.1, &mesh.2, nparts).unwrap();
        check_partition(&mesh, &p);
    }
}

#[test]
fn two_separate_bodies_into_1_to_8_parts() {
    // The dual graph is disconnected, so METIS runs without its contiguity option.
    let mesh = two_bodies(12, 6);
    for nparts in 1..=8 {
        let p = partition_mesh(mesh.0, &mesh.1, &mesh.2, nparts).unwrap();
        check_partition(&mesh, &p);
    }
}

#[test]
fn as_many_parts_as_triangles() {
    let mesh = irregular();
    let p = partition_mesh(mesh.0, &mesh.1, &mesh.2, mesh.1.len()).unwrap();
    check_partition(&mesh, &p);
    assert!(p.parts.iter().all(|q| q.elements.len() == 1));
}

#[test]
fn partitions_are_deterministic() {
    for mesh in [rectangle(40, 40), irregular(), two_bodies(10, 5)] {
        for nparts in [2, 3, 5, 8] {
            let a = partition_mesh(mesh.0, &mesh.1, &mesh.2, nparts).unwrap();
            let b = partition_mesh(mesh.0, &mesh.1, &mesh.2, nparts).unwrap();
            assert_eq!(a, b);
        }
    }
}

#[test]
fn deterministic_across_threads() {
    // METIS' random state is process-wide: concurrent calls must not disturb each other.
    let mesh = rectangle(60, 30);
    let reference = partition_mesh(mesh.0, &mesh.1, &mesh.2, 6).unwrap();
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..4)
            .map(|_| s.spawn(|| partition_mesh(mesh.0, &mesh.1, &mesh.2, 6).unwrap()))
            .collect();
        for h in handles {
            assert_eq!(h.join().unwrap(), reference);
        }
    });
}

#[test]
fn same_graph_and_parts_on_any_number_of_threads() {
    // The dual graph is built in blocks of triangles on rayon's threads: 234 000
    // triangles make several blocks, and past 200 000 the coarsening runs as well, in
    // blocks of its own.
    let (nx, ny) = (450, 260);
    let mesh = rectangle(nx, ny);
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                (
                    dual_graph(mesh.0, &mesh.1).unwrap(),
                    partition_mesh(mesh.0, &mesh.1, &mesh.2, 3).unwrap(),
                )
            })
    };
    let (graph, parts) = on(1);
    assert_eq!(graph.num_vertices(), mesh.1.len());
    assert_eq!(graph.num_edges(), nx * ny + (nx - 1) * ny + nx * (ny - 1));
    for threads in [2, 4] {
        let (g, p) = on(threads);
        assert_eq!(g, graph, "dual graph on {threads} threads");
        assert_eq!(p, parts, "partition on {threads} threads");
    }
    check_dual_graph_symmetric(mesh.0, &mesh.1);
}

#[test]
fn errors_are_reported() {
    let (n, tris, contact) = rectangle(2, 1);
    assert_eq!(
        partition_mesh(n, &tris, &contact, 5),
        Err(PartitionError::TooManyParts {
            nparts: 5,
            elements: 4
        })
    );
    let msg = partition_mesh(n, &tris, &contact, 5)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("4 triangles") && msg.contains("5 parts"),
        "{msg}"
    );
    assert_eq!(
        partition_mesh(n, &tris, &contact, 0),
        Err(PartitionError::NoParts)
    );
    assert_eq!(
        partition_mesh(n, &tris, &[n], 2),
        Err(PartitionError::ContactNodeOutOfRange {
            node: n,
            num_nodes: n
        })
    );
    assert_eq!(
        partition_mesh(n + 1, &tris, &[n], 2),
        Err(PartitionError::ContactNodeUnused { node: n })
    );
    assert_eq!(
        partition_mesh(0, &[], &[], 1),
        Err(PartitionError::TooManyParts {
            nparts: 1,
            elements: 0
        })
    );
}

#[test]
fn given_element_parts_are_checked_and_may_leave_parts_empty() {
    let mesh = rectangle(4, 2);
    let (n, tris, contact) = &mesh;
    // Left and right halves as parts 0 and 2; part 1 stays empty.
    let halves: Vec<u32> = (0..tris.len())
        .map(|e| if e % 8 < 4 { 0 } else { 2 })
        .collect();
    let p = partition::partition_from_element_parts(*n, tris, contact, 3, halves.clone()).unwrap();
    assert!(p.parts[1].elements.is_empty() && p.parts[1].nodes.is_empty());
    assert_eq!(p.parts[0].neighbours.len(), 1);
    assert_eq!(p.parts[0].neighbours[0], (2, vec![2, 7, 12]));
    assert_eq!(p.parts[2].neighbours[0], (0, vec![2, 7, 12]));
    assert_eq!(
        partition::partition_from_element_parts(*n, tris, contact, 2, halves),
        Err(PartitionError::PartOutOfRange {
            element: 4,
            part: 2,
            nparts: 2
        })
    );
}

#[test]
fn quality_summary_reads_well() {
    let mesh = rectangle(20, 10);
    let p = partition_mesh(mesh.0, &mesh.1, &mesh.2, 4).unwrap();
    let s = p.quality.to_string();
    assert!(s.contains("400 triangles in 4 parts"), "{s}");
    assert!(
        s.contains(&format!("edge cut {}", p.quality.edge_cut)),
        "{s}"
    );
}

#[test]
fn large_meshes_are_coarsened_before_metis() {
    // Past 200 000 triangles the crate coarsens the graph itself before METIS, then
    // refines the projected parts: the same promises must hold.
    for (mesh, connected) in [(rectangle(400, 260), true), (two_bodies(300, 180), false)] {
        for nparts in [2, 5] {
            let p = partition_mesh(mesh.0, &mesh.1, &mesh.2, nparts).unwrap();
            check_partition(&mesh, &p);
            assert!(p.quality.imbalance <= 1.03, "{}", p.quality);
            if connected {
                assert_eq!(p.quality.disconnected_parts, 0, "{}", p.quality);
            }
            assert_eq!(p, partition_mesh(mesh.0, &mesh.1, &mesh.2, nparts).unwrap());
        }
    }
}

/// The node graph of a triangle mesh in CSR form, without self loops.
fn node_graph(num_nodes: usize, triangles: &[[usize; 3]]) -> (Vec<usize>, Vec<usize>) {
    let mut adj: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); num_nodes];
    for t in triangles {
        for a in 0..3 {
            for b in 0..3 {
                if a != b {
                    adj[t[a]].insert(t[b]);
                }
            }
        }
    }
    let mut xadj = vec![0];
    let mut adjncy = Vec::new();
    for s in &adj {
        adjncy.extend(s.iter().copied());
        xadj.push(adjncy.len());
    }
    (xadj, adjncy)
}

#[test]
fn metis_on_several_threads_at_once_gives_the_results_of_one_at_a_time() {
    // Subdomains are ordered on threads of their own; METIS draws random numbers, so
    // this holds only if every thread has a generator of its own (or calls queue up).
    assert!(
        partition::metis_runs_concurrently(),
        "rand/srand are not bound to the partition crate's: METIS calls are serialized"
    );
    let (n, tris, contact) = rectangle(120, 90);
    let (xadj, adjncy) = node_graph(n, &tris);
    let order = partition::nested_dissection(&xadj, &adjncy).unwrap();
    let parts = partition_mesh(n, &tris, &contact, 5).unwrap();
    // Four threads, three rounds each: the calls overlap in many ways.
    let together: Vec<(Vec<usize>, Partition)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..4)
            .map(|_| {
                s.spawn(|| {
                    (0..3)
                        .map(|_| {
                            (
                                partition::nested_dissection(&xadj, &adjncy).unwrap(),
                                partition_mesh(n, &tris, &contact, 5).unwrap(),
                            )
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    for (o, p) in together {
        assert_eq!(o, order);
        assert_eq!(p, parts);
    }
}

/// One part builds no dual graph, and gives the partition the graph would have given:
/// the same parts, ownership and quality (pieces joined through nodes, which for these
/// meshes are the edge-connected ones).
#[test]
fn one_part_is_the_whole_mesh_without_a_dual_graph() {
    for (n, tris, contact) in [rectangle(30, 20), irregular(), two_bodies(40, 30)] {
        let one = partition_mesh(n, &tris, &contact, 1).unwrap();
        let given =
            partition::partition_from_element_parts(n, &tris, &contact, 1, vec![0; tris.len()])
                .unwrap();
        assert_eq!(one, given);
    }
    let (n, tris, contact) = two_bodies(40, 30);
    let one = partition_mesh(n, &tris, &contact, 1).unwrap();
    assert_eq!(one.quality.disconnected_parts, 1, "{}", one.quality);
    assert_eq!(one.quality.edge_cut, 0);
}

#[test]
fn ties_keep_two_bodies_in_contact_together() {
    // Two flat bodies, the top of the first against the bottom of the second. Alone,
    // the dual graph is two pieces and two parts take one body each, so every contact
    // pair straddles the cut; tied, the cut crosses the contact once instead.
    let (nx, ny) = (40, 6);
    let mesh = two_bodies(nx, ny);
    let n = mesh.0 / 2;
    let ties: Vec<[usize; 2]> = (0..=nx).map(|i| [ny * (nx + 1) + i, n + i]).collect();
    let split = |p: &Partition| {
        (ties.iter())
            .filter(|[a, b]| p.node_owner[*a] != p.node_owner[*b])
            .count()
    };
    let alone = partition_mesh(mesh.0, &mesh.1, &mesh.2, 2).unwrap();
    assert_eq!(split(&alone), nx + 1, "the bodies were not split apart");
    let tied = partition_mesh_with_ties(mesh.0, &mesh.1, &mesh.2, &ties, 2).unwrap();
    check_partition(&mesh, &tied);
    assert!(
        split(&tied) <= 2,
        "{} tied pairs across the cut",
        split(&tied)
    );
    // No ties: the same parts as without the argument.
    assert_eq!(
        partition_mesh_with_ties(mesh.0, &mesh.1, &mesh.2, &[], 2).unwrap(),
        alone
    );
}

/// `MeshGraph` cut and finished is `partition_mesh_with_ties` (ties included); parts
/// given by hand go through the same ownership rules,
/// an empty part is filled, a part id out of range is refused.
#[test]
fn a_mesh_graph_cut_and_finished_gets_the_same_ownership_rules() {
    let mesh = two_bodies(10, 5);
    let ties = [[0, mesh.0 - 1], [3, mesh.0 - 4]];
    for nparts in [1, 2, 5] {
        let g = MeshGraph::new(mesh.0, &mesh.1, &ties, nparts > 1).unwrap();
        let parts = g.cut(nparts).unwrap();
        let via = g.finish(&mesh.1, &mesh.2, nparts, parts).unwrap();
        let direct = partition_mesh_with_ties(mesh.0, &mesh.1, &mesh.2, &ties, nparts).unwrap();
        assert_eq!(via, direct, "{nparts} parts");
    }
    let g = MeshGraph::new(mesh.0, &mesh.1, &ties, true).unwrap();
    // Halves by triangle index, part 2 left empty: it takes a triangle.
    let half: Vec<u32> = (0..mesh.1.len())
        .map(|e| u32::from(2 * e >= mesh.1.len()))
        .collect();
    let p = g.finish(&mesh.1, &mesh.2, 3, half).unwrap();
    check_partition(&mesh, &p);
    assert!(p.parts.iter().all(|q| !q.elements.is_empty()));
    let g = MeshGraph::new(mesh.0, &mesh.1, &ties, true).unwrap();
    let mut bad = vec![0u32; mesh.1.len()];
    bad[7] = 3;
    assert!(matches!(
        g.finish(&mesh.1, &mesh.2, 3, bad),
        Err(PartitionError::PartOutOfRange {
            element: 7,
            part: 3,
            nparts: 3
        })
    ));
}

/// Straight cuts count their pieces and cut as they make the parts: `finish_straight`
/// gives what `finish` counts again from the graph for the same parts.
#[test]
fn straight_parts_finish_as_counted_again() {
    let flipped = |i: usize, j: usize| (i * 7 + j * 13) % 5 < 2;
    let (nx, ny) = (50, 30);
    let meshes = [rectangle(nx, ny), rectangle_with(nx, ny, flipped)];
    let node_at = |n: usize| [(n % (nx + 1)) as f64, (n / (nx + 1)) as f64];
    let mut finished = 0;
    for mesh in &meshes {
        let centroids: Vec<[f64; 2]> = (mesh.1.iter())
            .map(|t| {
                let p = t.map(node_at);
                [
                    (p[0][0] + p[1][0] + p[2][0]) / 3.0,
                    (p[0][1] + p[1][1] + p[2][1]) / 3.0,
                ]
            })
            .collect();
        for nparts in [2, 3, 5, 8] {
            let g = MeshGraph::new(mesh.0, &mesh.1, &[], true).unwrap();
            let parts = g
                .cut_straight(&centroids, nparts)
                .expect("a rectangle's parts are whole");
            assert_eq!(parts.nparts(), nparts);
            let element_part = parts.element_part().to_vec();
            let edge_cut = parts.edge_cut();
            let counted = g.finish_straight(&mesh.1, &mesh.2, parts).unwrap();
            let g = MeshGraph::new(mesh.0, &mesh.1, &[], true).unwrap();
            let again = g.finish(&mesh.1, &mesh.2, nparts, element_part).unwrap();
            assert_eq!(counted, again, "{nparts} parts");
            assert_eq!(counted.quality.edge_cut, edge_cut);
            assert!(edge_cut > 0);
            finished += 1;
        }
    }
    assert_eq!(finished, 8);
}
