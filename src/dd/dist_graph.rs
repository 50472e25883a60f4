//! The dual graph of a triangle mesh whose triangles are spread over the ranks in
//! consecutive ranges (rank r holds triangles `first_r..first_r + n_r` of one global
//! numbering, each as its three node tags), built by every rank at once, no rank
//! holding more than its range and its share of the edges: each edge of a triangle is
//! sent to the rank that a hash of its two node tags names ([`edge_rank`]); there the
//! triangles that run it are matched ([`match_edges`]), and each learns its neighbours.
//! The same matching finds the boundary edges (run by one triangle) and the folds (an
//! edge run twice the same way, or by three triangles or more).
//!
//! Why: it is the first step of a start in which every rank builds its part of the
//! problem from its share of the mesh file (docs/cost-model.md, "The start from one
//! Gmsh file"): the graph the partition cuts, the boundary that the contact groups must
//! lie on and the mesh check, without the whole mesh on one rank. Its rows are those of
//! `partition::dual_graph` on the same triangles (tested on 1-4 ranks). Runs build it
//! on the ranges of the ranks' locality order (`dd::locality`, `dd::share_cut`), where
//! most edges match on their own rank and only the others travel: 0.30 s for 2M
//! triangles on 2 ranks, where a first version that sent every edge took 0.70 s on
//! the shares in the file's order (docs/performance-history.md).

use crate::dd::comm::Mpi;

/// What the matching of the edges a rank was sent finds.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Matched {
    /// Pairs of triangles (global ids) that share an edge; every pair of the triangles
    /// of a non-manifold edge.
    pub pairs: Vec<[u64; 2]>,
    /// Edges run by one triangle: node tags (low, high), the triangle, and whether it
    /// runs the edge from low to high.
    pub boundary: Vec<BoundaryEdge>,
    /// Edges that two triangles run the same way, or three or more share: node tags
    /// (low, high) and two of the triangles.
    pub folds: Vec<([u64; 2], [u64; 2])>,
}

/// An edge of the mesh's boundary (see [`Matched::boundary`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoundaryEdge {
    pub nodes: [u64; 2],
    pub triangle: u64,
    pub low_to_high: bool,
}

/// The rank of `procs` that matches the edge between node tags `low < high`: a mix of
/// both tags (splitmix64), so that the edges spread evenly whatever the tags.
pub fn edge_rank(low: u64, high: u64, procs: usize) -> usize {
    let mut z = low
        .wrapping_mul(0x9e37_79b9_7f4a_7c15)
        .wrapping_add(high)
        .wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z % procs as u64) as usize
}

/// The edge records of triangles `first..`: per edge (low tag, high tag, triangle << 1
/// | 1 when the triangle runs it from low to high), in the order of the triangles.
pub fn edge_records(first: u64, triangles: &[[u64; 3]]) -> impl Iterator<Item = [u64; 3]> + '_ {
    triangles.iter().enumerate().flat_map(move |(i, t)| {
        let id = first + i as u64;
        [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]
            .map(move |(a, b)| [a.min(b), a.max(b), id << 1 | u64::from(a < b)])
    })
}

/// Matches the edge records a rank was sent (see [`edge_records`]), in any order.
pub fn match_edges(records: &mut [[u64; 3]]) -> Matched {
    use rayon::slice::ParallelSliceMut;
    records.par_sort_unstable();
    let mut m = Matched::default();
    for run in records.chunk_by(|x, y| x[0] == y[0] && x[1] == y[1]) {
        let nodes = [run[0][0], run[0][1]];
        match run {
            [one] => m.boundary.push(BoundaryEdge {
                nodes,
                triangle: one[2] >> 1,
                low_to_high: one[2] & 1 == 1,
            }),
            [x, y] => {
                m.pairs.push([x[2] >> 1, y[2] >> 1]);
                if (x[2] ^ y[2]) & 1 == 0 {
                    m.folds.push((nodes, [x[2] >> 1, y[2] >> 1]));
                }
            }
            _ => {
                for (k, x) in run.iter().enumerate() {
                    for y in &run[k + 1..] {
                        m.pairs.push([x[2] >> 1, y[2] >> 1]);
                    }
                }
                m.folds.push((nodes, [run[0][2] >> 1, run[1][2] >> 1]));
            }
        }
    }
    m
}

/// The consecutive ranges of the triangles' global ids, rank after rank.
struct Ranges {
    /// The first id of each rank's range.
    starts: Vec<u64>,
}

impl Ranges {
    fn new(counts: &[usize]) -> Self {
        let mut at = 0u64;
        let starts = (counts.iter())
            .map(|&c| {
                let s = at;
                at += c as u64;
                s
            })
            .collect();
        Ranges { starts }
    }

    /// The rank whose range holds `t` (the last of the ranks starting at or before it:
    /// empty ranges share their start with the next).
    fn owner(&self, t: u64) -> usize {
        self.starts.partition_point(|&s| s <= t) - 1
    }
}

/// A rank's part of the dual graph (see the module's documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DistDual {
    /// Global id of this rank's first triangle.
    pub first: u64,
    /// Rows of this rank's triangles: the neighbours of its `i`-th are
    /// `adjncy[xadj[i]..xadj[i + 1]]`, global ids, increasing, without repeats.
    pub xadj: Vec<usize>,
    pub adjncy: Vec<u64>,
    /// The boundary edges and folds this rank matched (each edge is matched on one rank).
    pub boundary: Vec<BoundaryEdge>,
    pub folds: Vec<([u64; 2], [u64; 2])>,
}

/// `dual`'s rows (of this rank's `triangles`, node tags) with an edge between the first
/// triangles (lowest ids) around the two nodes of each tie (pairs of node tags, the same
/// list on every rank) where not already adjacent, as the `partition` crate ties a
/// contact's slave nodes to their masters: the cut then pays for cutting a tie as for
/// cutting an edge of the mesh. Collective.
pub fn with_ties(
    mpi: &Mpi,
    dual: &DistDual,
    triangles: &[[u64; 3]],
    ties: &[[u64; 2]],
) -> (Vec<usize>, Vec<u64>) {
    let mut nodes: Vec<u64> = ties.iter().flatten().copied().collect();
    nodes.sort_unstable();
    nodes.dedup();
    let mut lowest = vec![u64::MAX; nodes.len()];
    for (i, t) in triangles.iter().enumerate() {
        for tag in t {
            if let Ok(k) = nodes.binary_search(tag) {
                lowest[k] = lowest[k].min(dual.first + i as u64);
            }
        }
    }
    // Boundary-sized: every rank's lowest ids to every rank.
    for other in &mpi.exchange(vec![lowest.clone(); mpi.size]) {
        for (l, &o) in lowest.iter_mut().zip(other) {
            *l = (*l).min(o);
        }
    }
    let around = |tag: u64| lowest[nodes.binary_search(&tag).expect("a tied node")];
    let rows = dual.xadj.len() - 1;
    let mine = |t: u64| t >= dual.first && t < dual.first + rows as u64;
    let mut extra: Vec<Vec<u64>> = vec![Vec::new(); rows];
    for &[a, b] in ties {
        let (ta, tb) = (around(a), around(b));
        if ta == u64::MAX || tb == u64::MAX || ta == tb {
            continue;
        }
        for (from, to) in [(ta, tb), (tb, ta)] {
            if mine(from) {
                extra[(from - dual.first) as usize].push(to);
            }
        }
    }
    let mut xadj = Vec::with_capacity(rows + 1);
    xadj.push(0);
    let mut adjncy = Vec::with_capacity(dual.adjncy.len() + 2 * ties.len());
    for (i, more) in extra.iter_mut().enumerate() {
        let start = adjncy.len();
        adjncy.extend_from_slice(&dual.adjncy[dual.xadj[i]..dual.xadj[i + 1]]);
        adjncy.append(more);
        adjncy[start..].sort_unstable();
        let mut row: Vec<u64> = adjncy.split_off(start);
        row.dedup();
        adjncy.extend(row);
        xadj.push(adjncy.len());
    }
    (xadj, adjncy)
}

/// Builds the dual graph of the triangles spread over the ranks: this rank's are
/// `triangles` (node tags), its share of one global numbering in rank order.
/// Collective; one subdomain per rank.
///
/// The edges are matched on this rank first; only those it runs once travel (to the
/// rank [`edge_rank`] names), so ranges in a locality order (`dd::locality`) send
/// little more than their outlines. An edge that three triangles or more run is a
/// fold wherever two of them lie on one rank; should exactly two lie on one rank and
/// the others elsewhere, those others are taken for boundary edges: the mesh check of
/// the whole file refuses such a mesh anyway.
pub fn dual_graph(mpi: &Mpi, triangles: &[[u64; 3]]) -> DistDual {
    let p = mpi.size;
    let ranges = Ranges::new(&mpi.all_gather_counts(triangles.len()));
    let first = ranges.starts[mpi.rank];
    let mut records: Vec<[u64; 3]> = edge_records(first, triangles).collect();
    let here = match_edges(&mut records);
    drop(records);
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for e in &here.boundary {
        let [low, high] = e.nodes;
        let id = e.triangle << 1 | u64::from(e.low_to_high);
        send[edge_rank(low, high, p)].extend_from_slice(&[low, high, id]);
    }
    let received = mpi.exchange(send);
    let mut records: Vec<[u64; 3]> = (received.iter())
        .flat_map(|v| v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]))
        .collect();
    let there = match_edges(&mut records);
    drop(records);
    // Each pair matched elsewhere to the owners of both triangles.
    let owner = |t: u64| ranges.owner(t);
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for &[a, b] in &there.pairs {
        send[owner(a)].extend_from_slice(&[a, b]);
        send[owner(b)].extend_from_slice(&[b, a]);
    }
    let received = mpi.exchange(send);
    let entries = (here.pairs.iter())
        .flat_map(|&[a, b]| [[a, b], [b, a]])
        .chain(
            received
                .iter()
                .flat_map(|v| v.chunks_exact(2).map(|c| [c[0], c[1]])),
        );
    let (xadj, adjncy) = rows(first, triangles.len(), entries);
    let mut folds = here.folds;
    folds.extend(there.folds);
    DistDual {
        first,
        xadj,
        adjncy,
        boundary: there.boundary,
        folds,
    }
}

/// The rows of `n` triangles from `first` in CSR form, from their entries (row,
/// neighbour), in any order: each row increasing, without repeats.
fn rows(
    first: u64,
    n: usize,
    entries: impl Iterator<Item = [u64; 2]> + Clone,
) -> (Vec<usize>, Vec<u64>) {
    let mut xadj = vec![0usize; n + 1];
    for [a, _] in entries.clone() {
        xadj[(a - first) as usize + 1] += 1;
    }
    for i in 0..n {
        xadj[i + 1] += xadj[i];
    }
    let mut at = xadj.clone();
    let mut adjncy = vec![0u64; xadj[n]];
    for [a, b] in entries {
        let i = (a - first) as usize;
        adjncy[at[i]] = b;
        at[i] += 1;
    }
    // Rows of a mesh's dual graph hold three entries at most (more at a fold):
    // sorted in place, repeats squeezed out.
    let mut out = 0;
    let mut start = 0;
    for i in 0..n {
        let end = xadj[i + 1];
        adjncy[start..end].sort_unstable();
        let row_start = out;
        for k in start..end {
            if out == row_start || adjncy[out - 1] != adjncy[k] {
                adjncy[out] = adjncy[k];
                out += 1;
            }
        }
        start = end;
        xadj[i + 1] = out;
    }
    adjncy.truncate(out);
    (xadj, adjncy)
}

/// The edges of the graph whose two triangles lie in different parts (`parts`: this
/// rank's triangles'; `counts`: every rank's number of triangles): each rank asks the
/// owners of its rows' other triangles for their parts, counts its rows' cut edges, and
/// the counts are summed (each edge is in two rows). Collective; every rank gets it.
pub fn edge_cut(mpi: &Mpi, dual: &DistDual, parts: &[i32], counts: &[usize]) -> usize {
    let p = mpi.size;
    let ranges = Ranges::new(counts);
    let owner = |t: u64| ranges.owner(t);
    let (first, mine) = (dual.first, parts.len() as u64);
    let local = |t: u64| t >= first && t < first + mine;
    let mut ask: Vec<Vec<u64>> = vec![Vec::new(); p];
    for &t in dual.adjncy.iter().filter(|&&t| !local(t)) {
        ask[owner(t)].push(t);
    }
    for a in &mut ask {
        a.sort_unstable();
        a.dedup();
    }
    let asked = mpi.exchange(ask.clone());
    let answers: Vec<Vec<i32>> = (asked.iter())
        .map(|ids| ids.iter().map(|&t| parts[(t - first) as usize]).collect())
        .collect();
    let got = mpi.exchange(answers);
    let part_of = |t: u64| -> i32 {
        if local(t) {
            return parts[(t - first) as usize];
        }
        let q = owner(t);
        let k = ask[q]
            .binary_search(&t)
            .expect("asked for every other triangle");
        got[q][k]
    };
    let mut cut = 0usize;
    for (i, &pi) in parts.iter().enumerate() {
        let row = &dual.adjncy[dual.xadj[i]..dual.xadj[i + 1]];
        cut += row.iter().filter(|&&t| part_of(t) != pi).count();
    }
    let mut total = [cut as f64];
    crate::contact::Reduce::sum_in_place(mpi, &mut total);
    total[0] as usize / 2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_triangles_share_one_edge_the_rest_is_boundary() {
        // 1-2-3 and 3-2-4 run the edge 2-3 opposite ways.
        let mut r: Vec<[u64; 3]> = edge_records(10, &[[1, 2, 3], [3, 2, 4]]).collect();
        r.reverse();
        let m = match_edges(&mut r);
        assert_eq!(m.pairs, vec![[10, 11]]);
        assert!(m.folds.is_empty());
        let mut b: Vec<[u64; 2]> = m.boundary.iter().map(|e| e.nodes).collect();
        b.sort_unstable();
        assert_eq!(b, vec![[1, 2], [1, 3], [2, 4], [3, 4]]);
        let e13 = m.boundary.iter().find(|e| e.nodes == [1, 3]).unwrap();
        assert_eq!((e13.triangle, e13.low_to_high), (10, false));
    }

    #[test]
    fn an_edge_run_twice_the_same_way_or_by_three_is_a_fold() {
        let mut r: Vec<[u64; 3]> = edge_records(0, &[[1, 2, 3], [2, 3, 4]]).collect();
        let m = match_edges(&mut r);
        assert_eq!(m.folds, vec![([2, 3], [0, 1])]);
        let mut r: Vec<[u64; 3]> = edge_records(0, &[[1, 2, 3], [3, 2, 4], [2, 3, 5]]).collect();
        let m = match_edges(&mut r);
        assert_eq!(m.pairs, vec![[0, 1], [0, 2], [1, 2]]);
        assert_eq!(m.folds.len(), 1);
    }

    #[test]
    fn edges_spread_over_the_ranks_and_the_hash_is_symmetric_in_use() {
        let mut hits = [0usize; 7];
        for a in 0..200u64 {
            for b in a + 1..a + 4 {
                hits[edge_rank(a, b, 7)] += 1;
            }
        }
        assert!(hits.iter().all(|&h| h > 50), "{hits:?}");
        assert_eq!(edge_rank(5, 9, 1), 0);
    }
}
