//! Each node's parts, found by the ranks from the parts of their triangles (a range of
//! the mesh's triangles each, as node tags: the locality order's of `dd::locality`), no
//! rank holding more than its triangles and its share of the nodes: every triangle
//! corner's (node tag, part) goes to the rank that a hash of the tag names
//! ([`locality::tag_rank`], the nodes' directory), which then sees every part around
//! the node. The rules are those of the `partition` crate (`partition::Part`): the
//! lowest part touching a node owns it; a node that several parts touch lies on the
//! interface of each, and those parts are neighbours. Then each part's lists
//! ([`part_lists`]: its triangles, nodes, owned nodes, interface and neighbours, those
//! of `partition::Part`) are put together on the rank that holds the part.
//!
//! Why: it is the step after the cut of a start in which each rank builds its own part
//! of the problem from its share of the mesh file (docs/cost-model.md, "The partition
//! from the ranks' shares of the file"): the nodes each part holds and which of them it
//! owns and shares, and the partition's figures, without the whole mesh on one rank.
//! Runs use it where the ranks cut the mesh from their shares, the same number of
//! parts on every rank (`dd::share_cut`, `dd::dist_split`).

use crate::dd::comm::Mpi;
use crate::dd::locality::{tag_rank, Directory};
use rayon::prelude::*;

/// This rank's share of the nodes' directory: each node of the triangles, its place in
/// the file and the parts around it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NodeParts {
    /// The nodes' tags, increasing.
    pub tags: Vec<u64>,
    /// Their indices among the file's nodes, and their x, y.
    pub file: Vec<u64>,
    pub xy: Vec<[f64; 2]>,
    /// The parts touching node `k`: `parts[start[k]..start[k + 1]]`, increasing.
    pub start: Vec<usize>,
    pub parts: Vec<u32>,
}

impl NodeParts {
    /// The parts touching node `k` (of this share), increasing.
    pub fn of(&self, k: usize) -> &[u32] {
        &self.parts[self.start[k]..self.start[k + 1]]
    }

    /// The part owning node `k`: the lowest touching it.
    pub fn owner(&self, k: usize) -> u32 {
        self.of(k)[0]
    }
}

/// The parts around every node of the ranks' triangles (`parts[i]`: the part of
/// `triangles[i]`), on the nodes' directory ranks, with the nodes' places in the file
/// and coordinates from this rank's share of the directory (`known`). `None` on every
/// rank where a triangle's node is not in the directory. Collective; one subdomain per
/// rank.
pub fn node_parts(
    mpi: &Mpi,
    triangles: &[[u64; 3]],
    parts: &[u32],
    known: &Directory,
) -> Option<NodeParts> {
    let p = mpi.size;
    let mut corners: Vec<[u64; 2]> = (triangles.par_iter().zip(parts))
        .flat_map_iter(|(t, &q)| t.map(|tag| [tag, u64::from(q)]))
        .collect();
    corners.par_sort_unstable();
    corners.dedup();
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for c in &corners {
        send[tag_rank(c[0], p)].extend_from_slice(c);
    }
    drop(corners);
    let mut mine: Vec<[u64; 2]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(2).map(|c| [c[0], c[1]]))
        .collect();
    mine.par_sort_unstable();
    mine.dedup();
    let mut out = NodeParts {
        start: vec![0],
        ..NodeParts::default()
    };
    let mut ok = true;
    let mut i = 0;
    for run in mine.chunk_by(|a, b| a[0] == b[0]) {
        let tag = run[0][0];
        while i < known.tags.len() && known.tags[i] < tag {
            i += 1;
        }
        if known.tags.get(i) != Some(&tag) {
            ok = false;
            continue;
        }
        out.tags.push(tag);
        out.file.push(known.file[i]);
        out.xy.push(known.xy[i]);
        out.parts.extend(run.iter().map(|c| c[1] as u32));
        out.start.push(out.parts.len());
    }
    mpi.all_ok(ok).then_some(out)
}

/// The figures of the interface that `partition::Quality` reports, from every rank's
/// [`NodeParts`] (every rank gets them).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InterfaceFigures {
    /// Nodes touched by more than one part.
    pub interface_nodes: usize,
    /// Each part's interface nodes.
    pub per_part: Vec<usize>,
    /// Each part's neighbouring parts (sharing at least a node).
    pub neighbours: Vec<usize>,
}

/// The interface's figures for `nparts` parts. Collective; one subdomain per rank.
pub fn interface_figures(mpi: &Mpi, nodes: &NodeParts, nparts: usize) -> InterfaceFigures {
    let p = mpi.size;
    let mut counts = vec![0.0; nparts + 1];
    // Each pair of neighbouring parts once, on the rank of the lower part.
    let mut send: Vec<Vec<u32>> = vec![Vec::new(); p];
    for k in 0..nodes.tags.len() {
        let around = nodes.of(k);
        if around.len() < 2 {
            continue;
        }
        counts[nparts] += 1.0;
        for (i, &a) in around.iter().enumerate() {
            counts[a as usize] += 1.0;
            for &b in &around[i + 1..] {
                send[a as usize % p].extend_from_slice(&[a, b]);
            }
        }
    }
    crate::contact::Reduce::sum_in_place(mpi, &mut counts);
    let mut pairs: Vec<[u32; 2]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(2).map(|c| [c[0], c[1]]))
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let mut neighbours = vec![0.0; nparts];
    for [a, b] in pairs {
        neighbours[a as usize] += 1.0;
        neighbours[b as usize] += 1.0;
    }
    crate::contact::Reduce::sum_in_place(mpi, &mut neighbours);
    InterfaceFigures {
        interface_nodes: counts[nparts] as usize,
        per_part: counts[..nparts].iter().map(|&c| c as usize).collect(),
        neighbours: neighbours.iter().map(|&c| c as usize).collect(),
    }
}

/// One part's share of the mesh, found on the rank that will hold it: the lists of
/// `partition::Part`, in the file's numbering (triangles by their index among the
/// file's triangle records, nodes by tag).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PartLists {
    pub part: u32,
    /// The part's triangles (file indices, increasing) and their node tags.
    pub elements: Vec<u64>,
    pub triangles: Vec<[u64; 3]>,
    /// Every node of those triangles (tags, increasing), its index among the file's
    /// nodes, its x, y, and whether the part owns it.
    pub nodes: Vec<u64>,
    pub file_nodes: Vec<u64>,
    pub xy: Vec<[f64; 2]>,
    pub owned: Vec<bool>,
    /// The nodes other parts touch too (tags, increasing).
    pub interface: Vec<u64>,
    /// Each neighbouring part (increasing) and the nodes the two share (tags,
    /// increasing): the same list on both sides.
    pub neighbours: Vec<(u32, Vec<u64>)>,
}

/// The parts that rank `rank` holds (`per_rank` each, parts `rank * per_rank ..`, as
/// the run's subdomains), built from the ranks' triangles (`file`: their indices in
/// the file, `parts`: their parts) and the nodes' directory (`around`): each triangle
/// travels to its part's rank, each node's parts to the ranks of those parts. Two
/// all-to-alls. Collective; one subdomain per rank.
pub fn part_lists(
    mpi: &Mpi,
    file: &[u64],
    triangles: &[[u64; 3]],
    parts: &[u32],
    around: &NodeParts,
    per_rank: usize,
) -> Vec<PartLists> {
    let p = mpi.size;
    let rank_of = |q: u32| (q as usize / per_rank).min(p - 1);
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for ((&f, t), &q) in file.iter().zip(triangles).zip(parts) {
        send[rank_of(q)].extend_from_slice(&[u64::from(q), f, t[0], t[1], t[2]]);
    }
    let mut lists: Vec<PartLists> = (0..per_rank)
        .map(|i| PartLists {
            part: (mpi.rank * per_rank + i) as u32,
            ..PartLists::default()
        })
        .collect();
    let first = (mpi.rank * per_rank) as u32;
    let mut elements: Vec<Vec<(u64, [u64; 3])>> = vec![Vec::new(); per_rank];
    for c in mpi.exchange(send).iter().flat_map(|v| v.chunks_exact(5)) {
        elements[(c[0] as u32 - first) as usize].push((c[1], [c[2], c[3], c[4]]));
    }
    for (l, mut e) in lists.iter_mut().zip(elements) {
        e.sort_unstable();
        l.elements = e.iter().map(|x| x.0).collect();
        l.triangles = e.iter().map(|x| x.1).collect();
    }
    // Each node to the ranks of its parts: part, tag, file index, x, y, then the parts
    // around it.
    const HEAD: usize = 6;
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for (k, &tag) in around.tags.iter().enumerate() {
        let touching = around.of(k);
        let [x, y] = around.xy[k].map(f64::to_bits);
        for &q in touching {
            let to = &mut send[rank_of(q)];
            let n = touching.len() as u64;
            to.extend_from_slice(&[u64::from(q), tag, around.file[k], x, y, n]);
            to.extend(touching.iter().map(|&x| u64::from(x)));
        }
    }
    let mut nodes: Vec<Vec<Arrived>> = vec![Vec::new(); per_rank];
    for v in mpi.exchange(send) {
        let mut at = 0;
        while at < v.len() {
            let (q, tag, file, n) = (v[at] as u32, v[at + 1], v[at + 2], v[at + 5] as usize);
            let xy = [f64::from_bits(v[at + 3]), f64::from_bits(v[at + 4])];
            let touching = (v[at + HEAD..at + HEAD + n].iter())
                .map(|&x| x as u32)
                .collect();
            nodes[(q - first) as usize].push(Arrived {
                tag,
                file,
                xy,
                touching,
            });
            at += HEAD + n;
        }
    }
    for (l, mut n) in lists.iter_mut().zip(nodes) {
        n.sort_unstable_by_key(|x| x.tag);
        let mut shared: std::collections::BTreeMap<u32, Vec<u64>> = Default::default();
        for Arrived {
            tag,
            file,
            xy,
            touching,
        } in n
        {
            l.nodes.push(tag);
            l.file_nodes.push(file);
            l.xy.push(xy);
            l.owned.push(touching[0] == l.part);
            if touching.len() > 1 {
                l.interface.push(tag);
                for &q in touching.iter().filter(|&&q| q != l.part) {
                    shared.entry(q).or_default().push(tag);
                }
            }
        }
        l.neighbours = shared.into_iter().collect();
    }
    lists
}

/// A node as it reaches a part's rank ([`part_lists`]).
#[derive(Clone)]
struct Arrived {
    tag: u64,
    file: u64,
    xy: [f64; 2],
    touching: Vec<u32>,
}
