//! The crate's internal graph form, shared by the dual graph, the coarse graphs and the
//! METIS calls: CSR arrays in METIS' own index type, so that no graph is converted on
//! its way to METIS, and at half the memory traffic of `usize` arrays (which is what
//! the large meshes are bound by).

use crate::PartitionError;
use metis::Idx;
use rayon::prelude::*;
use std::ops::Range;

/// A graph in METIS' CSR form with optional vertex and edge weights (absent: all 1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Graph {
    pub xadj: Vec<Idx>,
    pub adjncy: Vec<Idx>,
    pub vwgt: Option<Vec<Idx>>,
    pub adjwgt: Option<Vec<Idx>>,
}

impl Graph {
    pub fn num_vertices(&self) -> usize {
        self.xadj.len() - 1
    }

    /// Positions of the neighbours of `v` in `adjncy` (and `adjwgt`).
    pub fn range(&self, v: usize) -> Range<usize> {
        self.xadj[v] as usize..self.xadj[v + 1] as usize
    }

    pub fn neighbours(&self, v: usize) -> &[Idx] {
        &self.adjncy[self.range(v)]
    }

    pub fn vertex_weight(&self, v: usize) -> Idx {
        self.vwgt.as_ref().map_or(1, |w| w[v])
    }

    /// Weight of the edge stored at position `k` of `adjncy`.
    pub fn edge_weight(&self, k: usize) -> Idx {
        self.adjwgt.as_ref().map_or(1, |w| w[k])
    }
}

pub(crate) fn to_idx(v: usize) -> Result<Idx, PartitionError> {
    Idx::try_from(v).map_err(|_| PartitionError::TooLarge)
}

/// Node-to-triangle incidence in CSR form: the triangles touching node `n` are
/// `tris[start[n]..start[n + 1]]`, in increasing order.
pub struct Stars {
    start: Vec<Idx>,
    tris: Vec<Idx>,
}

impl Stars {
    /// Needs valid triangles (node ids `< num_nodes`).
    pub fn new(num_nodes: usize, triangles: &[[usize; 3]]) -> Result<Self, PartitionError> {
        to_idx(3 * triangles.len())?;
        let mut start = vec![0 as Idx; num_nodes + 1];
        for t in triangles {
            for &n in t {
                start[n + 1] += 1;
            }
        }
        for i in 1..start.len() {
            start[i] += start[i - 1];
        }
        let mut fill = start.clone();
        let mut tris = vec![0 as Idx; 3 * triangles.len()];
        for (e, t) in triangles.iter().enumerate() {
            for &n in t {
                tris[fill[n] as usize] = e as Idx;
                fill[n] += 1;
            }
        }
        Ok(Self { start, tris })
    }

    pub fn num_nodes(&self) -> usize {
        self.start.len() - 1
    }

    pub fn of(&self, n: usize) -> &[Idx] {
        &self.tris[self.start[n] as usize..self.start[n + 1] as usize]
    }
}

/// The dual graph (see [`crate::DualGraph`]) of valid triangles.
///
/// The triangles across edge `(a, b)` are the other triangles of the star of `a` that
/// contain `b`: about six candidates, all numbered close to the triangle itself in any
/// mesh numbering with locality. Rows come out in triangle order, so the CSR arrays are
/// filled with no edge list to sort: each block of triangles builds its rows on its own
/// thread, and the blocks are joined in order.
pub(crate) fn dual_from_stars(
    triangles: &[[usize; 3]],
    stars: &Stars,
) -> Result<Graph, PartitionError> {
    const BLOCK: usize = 1 << 15;
    let ne = triangles.len();
    to_idx(ne)?;
    let blocks: Vec<(Vec<Idx>, Vec<Idx>)> = triangles
        .par_chunks(BLOCK)
        .enumerate()
        .map(|(blk, block)| {
            let mut row_len = Vec::with_capacity(block.len());
            // Exact for a manifold mesh (at most three neighbours per triangle).
            let mut adjncy: Vec<Idx> = Vec::with_capacity(3 * block.len());
            for (k, t) in block.iter().enumerate() {
                let row_start = adjncy.len();
                let e = (blk * BLOCK + k) as Idx;
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    for &f in stars.of(a) {
                        let tf = &triangles[f as usize];
                        if f != e && (tf[0] == b || tf[1] == b || tf[2] == b) {
                            adjncy.push(f);
                        }
                    }
                }
                // Two triangles with the same three nodes meet once per common edge, and
                // METIS rejects multi-edges.
                let kept = sort_and_dedup(&mut adjncy[row_start..]);
                adjncy.truncate(row_start + kept);
                row_len.push(kept as Idx);
            }
            (row_len, adjncy)
        })
        .collect();
    let total = blocks.iter().map(|b| b.1.len()).sum();
    to_idx(total)?;
    let mut xadj = Vec::with_capacity(ne + 1);
    xadj.push(0 as Idx);
    let mut adjncy = Vec::with_capacity(total);
    for (row_len, block) in blocks {
        for len in row_len {
            xadj.push(xadj[xadj.len() - 1] + len);
        }
        adjncy.extend_from_slice(&block);
    }
    Ok(Graph {
        xadj,
        adjncy,
        vwgt: None,
        adjwgt: None,
    })
}

/// Sorts `row` and moves its distinct values to its head; returns how many there are.
fn sort_and_dedup(row: &mut [Idx]) -> usize {
    row.sort_unstable();
    let mut kept = row.len().min(1);
    for i in 1..row.len() {
        if row[i] != row[kept - 1] {
            row[kept] = row[i];
            kept += 1;
        }
    }
    kept
}

/// `graph` with an edge between the first triangles around the two nodes of each tie
/// (node pairs coupled by something other than the mesh, e.g. the two sides of a contact
/// between bodies), where not already adjacent: the partitioner then pays for cutting a
/// tie as for cutting an edge of the mesh.
pub(crate) fn with_ties(
    graph: Graph,
    stars: &Stars,
    ties: &[[usize; 2]],
) -> Result<Graph, PartitionError> {
    if ties.is_empty() {
        return Ok(graph);
    }
    let n = graph.num_vertices();
    let mut extra: Vec<Vec<Idx>> = vec![Vec::new(); n];
    for &[a, b] in ties {
        let (Some(&ta), Some(&tb)) = (stars.of(a).first(), stars.of(b).first()) else {
            continue;
        };
        if ta != tb {
            extra[ta as usize].push(tb);
            extra[tb as usize].push(ta);
        }
    }
    let mut xadj = Vec::with_capacity(n + 1);
    xadj.push(0 as Idx);
    let mut adjncy = Vec::with_capacity(graph.adjncy.len() + 2 * ties.len());
    for (v, more) in extra.iter_mut().enumerate() {
        let start = adjncy.len();
        adjncy.extend_from_slice(&graph.adjncy[graph.range(v)]);
        adjncy.append(more);
        let kept = sort_and_dedup(&mut adjncy[start..]);
        adjncy.truncate(start + kept);
        xadj.push(to_idx(adjncy.len())?);
    }
    Ok(Graph {
        xadj,
        adjncy,
        vwgt: graph.vwgt,
        adjwgt: None,
    })
}

/// For each colour `c < ncolours`, the number of connected pieces of the subgraph
/// induced by the vertices of colour `c`; and the total weight of the edges between
/// different colours.
///
/// Union-find over the edges in vertex order rather than a graph search: the search
/// jumps around the graph, while this scan reads it in order and its find steps stay
/// near the current vertex: 1.5 to 3 times faster on meshes of millions of triangles.
pub(crate) fn pieces_and_cut(
    graph: &Graph,
    ncolours: usize,
    colour: impl Fn(usize) -> u32 + Sync,
) -> (Vec<usize>, usize) {
    /// The root of `x`, halving its path; `parent` holds the entries from `lo` on.
    fn root(parent: &mut [Idx], lo: usize, mut x: usize) -> usize {
        while parent[x - lo] as usize != x {
            let grandparent = parent[parent[x - lo] as usize - lo];
            parent[x - lo] = grandparent;
            x = grandparent as usize;
        }
        x
    }
    fn union(parent: &mut [Idx], lo: usize, u: usize, v: usize) {
        let (a, b) = (root(parent, lo, u), root(parent, lo, v));
        match a.cmp(&b) {
            std::cmp::Ordering::Less => parent[b - lo] = a as Idx,
            std::cmp::Ordering::Greater => parent[a - lo] = b as Idx,
            std::cmp::Ordering::Equal => {}
        }
    }
    // Blocks of consecutive vertices join their own edges on all threads (a mesh
    // numbered with locality keeps most edges inside a block); the edges between
    // blocks are joined after, on one thread. The counts do not depend on the order.
    const BLOCK: usize = 1 << 15;
    let n = graph.num_vertices();
    let mut parent: Vec<Idx> = (0..n as Idx).collect();
    let blocks: Vec<(usize, Vec<[usize; 2]>)> = parent
        .par_chunks_mut(BLOCK)
        .enumerate()
        .map(|(b, parent)| {
            let lo = b * BLOCK;
            let (mut cut, mut across) = (0usize, Vec::new());
            for v in lo..lo + parent.len() {
                let c = colour(v);
                for k in graph.range(v) {
                    let u = graph.adjncy[k] as usize;
                    if u >= v {
                        continue;
                    }
                    if colour(u) != c {
                        cut += graph.edge_weight(k) as usize;
                    } else if u >= lo {
                        union(parent, lo, u, v);
                    } else {
                        across.push([u, v]);
                    }
                }
            }
            (cut, across)
        })
        .collect();
    let mut cut = 0;
    for (c, across) in blocks {
        cut += c;
        for [u, v] in across {
            union(&mut parent, 0, u, v);
        }
    }
    let mut pieces = vec![0usize; ncolours];
    for (v, &p) in parent.iter().enumerate() {
        if p as usize == v {
            pieces[colour(v) as usize] += 1;
        }
    }
    (pieces, cut)
}
