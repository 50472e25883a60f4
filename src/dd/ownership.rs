//! Each node's parts, found by the ranks from the parts of their triangles (a range of
//! the mesh's triangles each, as node tags: the locality order's of `dd::locality`), no
//! rank holding more than its triangles and its share of the nodes: every triangle
//! corner's (node tag, part) goes to the rank that a hash of the tag names
//! ([`locality::tag_rank`], the nodes' directory), which then sees every part around
//! the node. The rules are those of the `partition` crate (`partition::Part`): the
//! lowest part touching a node owns it; a node that several parts touch lies on the
//! interface of each, and those parts are neighbours.
//!
//! Why: it is the step after the cut of a start in which each rank builds its own part
//! of the problem from its share of the mesh file (docs/cost-model.md, "The partition
//! from the ranks' shares of the file"): the nodes each part holds and which of them it
//! owns and shares, and the partition's figures, without the whole mesh on one rank.
//! Runs do not use it yet (the first rank still splits the whole problem).

use crate::dd::comm::Mpi;
use crate::dd::locality::tag_rank;
use rayon::prelude::*;

/// This rank's share of the nodes' directory: each node and the parts around it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct NodeParts {
    /// The nodes' tags, increasing.
    pub tags: Vec<u64>,
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
/// `triangles[i]`), on the nodes' directory ranks. Collective; one subdomain per rank.
pub fn node_parts(mpi: &Mpi, triangles: &[[u64; 3]], parts: &[u32]) -> NodeParts {
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
    for run in mine.chunk_by(|a, b| a[0] == b[0]) {
        out.tags.push(run[0][0]);
        out.parts.extend(run.iter().map(|c| c[1] as u32));
        out.start.push(out.parts.len());
    }
    out
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
