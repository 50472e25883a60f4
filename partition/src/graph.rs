//! The crate's internal graph form, shared by the dual graph, the coarse graphs and the
//! METIS calls: CSR arrays in METIS' own index type, so that no graph is converted on
//! its way to METIS, and at half the memory traffic of `usize` arrays (which is what
//! the large meshes are bound by).

use crate::{triangle_fault, PartitionError};
use metis::Idx;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicI32, Ordering::Relaxed};

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

/// Triangles from which [`Stars::new`] counts by pieces on the pool.
const STARS_PIECE_MIN: usize = 1 << 16;

/// At most this many pieces: each holds a count per node.
const STARS_PIECES_MAX: usize = 4;

impl Stars {
    /// The stars of `triangles`, checked on the way (a pass of its own over the
    /// triangles cost as much as the count).
    ///
    /// # Errors
    /// [`PartitionError::NodeOutOfRange`] or [`PartitionError::DegenerateTriangle`] for
    /// the first invalid triangle; [`PartitionError::TooLarge`] beyond 2^31 entries.
    ///
    /// On one thread this pass was a run's longest one-thread step of the partition
    /// (about 30 ms at 1M nodes, the pool's other threads waiting). So each piece of
    /// the triangles counts its nodes on its own thread; a node's slots are then given
    /// out piece by piece, in triangle order, and each piece fills its own slots. The
    /// lists are those of one pass in triangle order, on any number of threads.
    pub fn new(num_nodes: usize, triangles: &[[usize; 3]]) -> Result<Self, PartitionError> {
        to_idx(3 * triangles.len())?;
        let pieces = (triangles.len() / STARS_PIECE_MIN)
            .min(rayon::current_num_threads())
            .clamp(1, STARS_PIECES_MAX);
        let len = triangles.len().div_ceil(pieces).max(1);
        let counted: Vec<Result<Vec<Idx>, PartitionError>> = triangles
            .par_chunks(len)
            .enumerate()
            .map(|(k, piece)| {
                let mut count = vec![0 as Idx; num_nodes];
                for (i, t) in piece.iter().enumerate() {
                    if let Some(fault) = triangle_fault(num_nodes, k * len + i, t) {
                        return Err(fault);
                    }
                    for &n in t {
                        count[n] += 1;
                    }
                }
                Ok(count)
            })
            .collect();
        // The first piece's fault is the first triangle's.
        let mut next = counted.into_iter().collect::<Result<Vec<_>, _>>()?;
        let start = first_slots(&mut next, num_nodes);
        let mut tris = vec![0 as Idx; 3 * triangles.len()];
        let slots = atomic_view(&mut tris);
        triangles
            .par_chunks(len)
            .zip(next.par_iter_mut())
            .enumerate()
            .for_each(|(k, (piece, next))| {
                for (i, t) in piece.iter().enumerate() {
                    for &n in t {
                        slots[next[n] as usize].store((k * len + i) as Idx, Relaxed);
                        next[n] += 1;
                    }
                }
            });
        Ok(Self { start, tris })
    }

    pub fn num_nodes(&self) -> usize {
        self.start.len() - 1
    }

    pub fn of(&self, n: usize) -> &[Idx] {
        &self.tris[self.start[n] as usize..self.start[n + 1] as usize]
    }
}

/// Triangles of a block of rows built on one thread (see [`join_rows`]).
const ROW_BLOCK: usize = 1 << 15;

/// The dual graph (see [`crate::DualGraph`]) of valid triangles.
///
/// Each node pairs the two triangles of every edge that leaves it for a higher node:
/// its star lists them, sorted by the edge's other end they fall in pairs, and each
/// goes into its partner's slot for that edge. So each triangle is read once from the
/// star of each of its nodes, where a search of one end's star for the other end reads
/// about six triangles per edge: the stars and the graph of the 1.88M triangles of a
/// 1M-node mesh took 0.070-0.080 s on two threads, against 0.083-0.094 s with the
/// search. An edge of three or more triangles (a non-manifold mesh) has no slot for all
/// its partners: such a mesh takes the search ([`dual_by_search`]), the same graph.
pub(crate) fn dual_from_stars(
    triangles: &[[usize; 3]],
    stars: &Stars,
) -> Result<Graph, PartitionError> {
    let ne = triangles.len();
    to_idx(3 * ne)?;
    // The edge keys pack a node and a triangle below 2^31 each.
    if to_idx(stars.num_nodes()).is_err() {
        return dual_by_search(triangles, stars);
    }
    let mut across = vec![-1 as Idx; 3 * ne];
    let slots = atomic_view(&mut across);
    let shared = std::sync::atomic::AtomicBool::new(false);
    (0..stars.num_nodes())
        .into_par_iter()
        .with_min_len(1 << 12)
        .for_each_init(Vec::new, |ends: &mut Vec<u64>, a| {
            ends.clear();
            for &f in stars.of(a) {
                let t = &triangles[f as usize];
                // Node `a` is corner i: edge i leaves it for corner i + 1, edge i + 2
                // comes to it from corner i + 2.
                let i = if t[0] == a {
                    0
                } else if t[1] == a {
                    1
                } else {
                    2
                };
                let (next, prev) = ((i + 1) % 3, (i + 2) % 3);
                if t[next] > a {
                    ends.push(edge_key(t[next], f as usize, i));
                }
                if t[prev] > a {
                    ends.push(edge_key(t[prev], f as usize, prev));
                }
            }
            ends.sort_unstable();
            for run in ends.chunk_by(|&x, &y| key_end(x) == key_end(y)) {
                match run {
                    [_] => {}
                    &[x, y] => {
                        let ((f, e), (g, d)) = (key_slot(x), key_slot(y));
                        // Each slot belongs to one edge, and so to one node's pass.
                        slots[3 * f + e].store(g as Idx, Relaxed);
                        slots[3 * g + d].store(f as Idx, Relaxed);
                    }
                    _ => shared.store(true, Relaxed),
                }
            }
        });
    if shared.into_inner() {
        return dual_by_search(triangles, stars);
    }
    let blocks: Vec<(Vec<Idx>, Vec<Idx>)> = across
        .par_chunks(3 * ROW_BLOCK)
        .map(|block| {
            let mut row_len = Vec::with_capacity(block.len() / 3);
            let mut adjncy: Vec<Idx> = Vec::with_capacity(block.len());
            for slots in block.chunks_exact(3) {
                let row_start = adjncy.len();
                adjncy.extend(slots.iter().copied().filter(|&f| f >= 0));
                close_row(&mut adjncy, row_start, &mut row_len);
            }
            (row_len, adjncy)
        })
        .collect();
    join_rows(ne, &blocks)
}

/// The sort key of edge `e` of triangle `f` at the node it leaves for `other`: the
/// other end first, so that the triangles of one edge sort next to each other (node and
/// triangle each below 2^31).
fn edge_key(other: usize, f: usize, e: usize) -> u64 {
    (other as u64) << 33 | (f as u64) << 2 | e as u64
}

/// The other end of an [`edge_key`].
fn key_end(k: u64) -> u64 {
    k >> 33
}

/// The triangle and its edge, the slot of an [`edge_key`].
fn key_slot(k: u64) -> (usize, usize) {
    ((k >> 2 & 0x7fff_ffff) as usize, (k & 3) as usize)
}

/// [`dual_from_stars`] by a search: the triangles across edge `(a, b)` are the other
/// triangles of the star of `a` that contain `b`. Rows come out in triangle order, so
/// the CSR arrays are filled with no edge list to sort: each block of triangles builds
/// its rows on its own thread, and the blocks are joined in order.
pub(crate) fn dual_by_search(
    triangles: &[[usize; 3]],
    stars: &Stars,
) -> Result<Graph, PartitionError> {
    let ne = triangles.len();
    to_idx(ne)?;
    let blocks: Vec<(Vec<Idx>, Vec<Idx>)> = triangles
        .par_chunks(ROW_BLOCK)
        .enumerate()
        .map(|(blk, block)| {
            let mut row_len = Vec::with_capacity(block.len());
            // Exact for a manifold mesh (at most three neighbours per triangle).
            let mut adjncy: Vec<Idx> = Vec::with_capacity(3 * block.len());
            for (k, t) in block.iter().enumerate() {
                let row_start = adjncy.len();
                let e = (blk * ROW_BLOCK + k) as Idx;
                for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    for &f in stars.of(a) {
                        let tf = &triangles[f as usize];
                        if f != e && (tf[0] == b || tf[1] == b || tf[2] == b) {
                            adjncy.push(f);
                        }
                    }
                }
                close_row(&mut adjncy, row_start, &mut row_len);
            }
            (row_len, adjncy)
        })
        .collect();
    join_rows(ne, &blocks)
}

/// Ends the row that starts at `row_start` of `adjncy`: its entries sorted, each once
/// (two triangles with the same three nodes meet once per common edge, and METIS
/// rejects multi-edges), and its length recorded.
fn close_row(adjncy: &mut Vec<Idx>, row_start: usize, row_len: &mut Vec<Idx>) {
    let kept = sort_and_dedup(&mut adjncy[row_start..]);
    adjncy.truncate(row_start + kept);
    row_len.push(kept as Idx);
}

/// The CSR graph of `ne` rows given block by block (each block's row lengths and
/// entries, in row order).
fn join_rows(ne: usize, blocks: &[(Vec<Idx>, Vec<Idx>)]) -> Result<Graph, PartitionError> {
    let total = blocks.iter().map(|b| b.1.len()).sum();
    to_idx(total)?;
    // Joined on the pool too: each block's rows and entries go to their places from
    // the block's first entry (on one thread this took 10-20 ms at 1M nodes).
    let mut xadj = vec![0 as Idx; ne + 1];
    let mut adjncy = vec![0 as Idx; total];
    let mut rows_left = &mut xadj[1..];
    let mut entries_left = &mut adjncy[..];
    let mut places = Vec::with_capacity(blocks.len());
    let mut first = 0 as Idx;
    for (row_len, block) in blocks {
        let (rows, rest) = rows_left.split_at_mut(row_len.len());
        let (entries, more) = entries_left.split_at_mut(block.len());
        (rows_left, entries_left) = (rest, more);
        places.push((rows, entries, first));
        first += block.len() as Idx;
    }
    places
        .into_par_iter()
        .zip(blocks)
        .for_each(|((rows, entries, mut at), (row_len, block))| {
            for (x, &len) in rows.iter_mut().zip(row_len) {
                at += len;
                *x = at;
            }
            entries.copy_from_slice(block);
        });
    Ok(Graph {
        xadj,
        adjncy,
        vwgt: None,
        adjwgt: None,
    })
}

/// Each piece's count per node (`counts[k][n]`) turned into the first slot of its
/// triangles around node `n`: after the slots of node `n - 1`, and of the pieces before
/// `k` around `n`. Returns where each node's list starts (and the end). By ranges of
/// nodes on the pool: the ranges' totals first, then each range from its base.
fn first_slots(counts: &mut [Vec<Idx>], num_nodes: usize) -> Vec<Idx> {
    const RANGE: usize = 1 << 14;
    let ranges = num_nodes.div_ceil(RANGE);
    let totals: Vec<Idx> = (0..ranges)
        .into_par_iter()
        .map(|r| {
            let span = r * RANGE..((r + 1) * RANGE).min(num_nodes);
            counts
                .iter()
                .map(|c| c[span.clone()].iter().sum::<Idx>())
                .sum()
        })
        .collect();
    let mut end = 0;
    let bases: Vec<Idx> = (totals.iter())
        .map(|&t| {
            end += t;
            end - t
        })
        .collect();
    let mut columns: Vec<Vec<&mut [Idx]>> = (0..ranges).map(|_| Vec::new()).collect();
    for c in counts.iter_mut() {
        for (r, piece) in c.chunks_mut(RANGE).enumerate() {
            columns[r].push(piece);
        }
    }
    let mut start = vec![0 as Idx; num_nodes + 1];
    start[num_nodes] = end;
    (start[..num_nodes].par_chunks_mut(RANGE))
        .zip(columns)
        .zip(bases)
        .for_each(|((start, mut columns), mut at)| {
            for (i, s) in start.iter_mut().enumerate() {
                *s = at;
                for c in columns.iter_mut() {
                    let n = c[i];
                    c[i] = at;
                    at += n;
                }
            }
        });
    start
}

/// `v` as atomics, which threads may store to at once.
pub(crate) fn atomic_view(v: &mut [Idx]) -> &[AtomicI32] {
    // SAFETY: `AtomicI32` has the size, alignment and bit validity of `i32` (`Idx`), and
    // the exclusive borrow of `v` lasts as long as the view.
    unsafe { &*(v as *mut [Idx] as *const [AtomicI32]) }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An `nx` x `ny` grid cut into triangles along pseudo-random diagonals, its nodes
    /// and triangles numbered in a pseudo-random order (no locality), each triangle
    /// listed from a pseudo-random corner.
    fn shuffled_grid(nx: usize, ny: usize, seed: u64) -> (usize, Vec<[usize; 3]>) {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as usize
        };
        let n = (nx + 1) * (ny + 1);
        let mut label: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            label.swap(i, next() % (i + 1));
        }
        let id = |i: usize, j: usize| label[j * (nx + 1) + i];
        let mut tris = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                if next() & 1 == 1 {
                    tris.extend([[a, b, c], [a, c, d]]);
                } else {
                    tris.extend([[a, b, d], [b, c, d]]);
                }
            }
        }
        for k in (1..tris.len()).rev() {
            tris.swap(k, next() % (k + 1));
        }
        for t in &mut tris {
            t.rotate_left(next() % 3);
        }
        (n, tris)
    }

    #[test]
    fn the_pairs_at_each_node_give_the_graph_of_the_search() {
        for (nx, ny, seed) in [(1, 1, 1), (7, 3, 2), (40, 25, 3), (300, 220, 4)] {
            let (n, tris) = shuffled_grid(nx, ny, seed);
            let stars = Stars::new(n, &tris).unwrap();
            let by_search = dual_by_search(&tris, &stars).unwrap();
            assert_eq!(dual_from_stars(&tris, &stars).unwrap(), by_search);
            // Every interior edge of the grid once from each side.
            let edges = 3 * nx * ny - nx - ny;
            assert_eq!(by_search.adjncy.len(), 2 * edges);
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
                let got = pool
                    .unwrap()
                    .install(|| dual_from_stars(&tris, &stars).unwrap());
                assert_eq!(got, by_search, "{threads} threads");
            }
        }
    }

    #[test]
    fn an_edge_of_three_triangles_takes_the_search() {
        let (n, mut tris) = shuffled_grid(6, 5, 9);
        // A third triangle on an interior edge, to a node of its own; and one listed
        // twice, whose every edge then has three triangles or two equal ones.
        let [a, b, _] = tris[10];
        tris.push([b, a, n]);
        tris.push(tris[3]);
        let stars = Stars::new(n + 1, &tris).unwrap();
        let graph = dual_from_stars(&tris, &stars).unwrap();
        assert_eq!(graph, dual_by_search(&tris, &stars).unwrap());
        let last = tris.len() - 1;
        assert!(graph.neighbours(last).contains(&3));
        assert!(graph.neighbours(tris.len() - 2).contains(&10));
    }
}
