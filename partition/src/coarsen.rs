//! The crate's own first levels of the multilevel scheme, for graphs too large to hand
//! to METIS whole (see [`crate::partition_mesh`]).
//!
//! METIS visits the vertices of its finest levels in random order, so on a dual graph
//! of millions of triangles nearly every access misses the caches: its time grows
//! faster than the graph, and most of it goes to matching and contracting the first
//! few levels. Here those levels are built in vertex order instead, which for a mesh
//! numbered with any locality walks memory almost sequentially; METIS then partitions
//! a graph small enough to stay in cache, and its parts are projected back through the
//! levels, each time refined by greedy boundary moves.

use crate::graph::Graph;
use metis::Idx;
use rayon::prelude::*;

/// Vertices per block of [`coarsen`]: a fixed size, so that the coarse graph (and the
/// partition) is the same on any number of threads.
const BLOCK: usize = 1 << 14;

/// Matches every vertex, in increasing order, with its unmatched neighbour across the
/// heaviest edge (the first one on ties), and contracts each pair to one vertex.
/// Returns the coarse graph, `cmap` (fine vertex -> coarse vertex) and the members of
/// each coarse vertex (the second one -1 for an unmatched vertex).
///
/// Ties go to the first neighbour, which is the lowest-numbered one: on the first level
/// (unit weights) this pairs the two triangles of a quad in the usual mesh numberings;
/// on the next ones, the heaviest edge keeps the merged cells compact.
///
/// The vertices are matched and contracted in blocks of [`BLOCK`] consecutive vertices,
/// on all threads: a vertex is matched within its block only, and the coarse vertices
/// of a block follow those of the blocks before. In a numbering with locality (the
/// program's, along a Hilbert curve) a block is a compact piece of the mesh, and the
/// pairs it forgoes across its border are a few per cent of its vertices.
pub(crate) fn coarsen(graph: &Graph) -> (Graph, Vec<Idx>, Vec<[Idx; 2]>) {
    let n = graph.num_vertices();
    let blocks: Vec<std::ops::Range<usize>> = (0..n)
        .step_by(BLOCK)
        .map(|s| s..(s + BLOCK).min(n))
        .collect();
    let matched: Vec<Vec<[Idx; 2]>> = blocks.par_iter().map(|r| matching(graph, r)).collect();
    let mut first = Vec::with_capacity(blocks.len() + 1);
    first.push(0usize);
    for m in &matched {
        first.push(first[first.len() - 1] + m.len());
    }
    let mut cmap = vec![-1 as Idx; n];
    cmap.par_chunks_mut(BLOCK)
        .zip(&blocks)
        .zip(matched.par_iter().zip(&first))
        .for_each(|((cmap, r), (pairs, &c0))| {
            for (k, pair) in pairs.iter().enumerate() {
                for &v in pair.iter().filter(|&&v| v >= 0) {
                    cmap[v as usize - r.start] = (c0 + k) as Idx;
                }
            }
        });
    let rows: Vec<Rows> = matched
        .par_iter()
        .map(|pairs| contract(graph, &cmap, pairs))
        .collect();
    let members = concat(&matched, |_, m| m);
    // Each block's rows start where the blocks before it end.
    let mut base = Vec::with_capacity(rows.len());
    let mut entries = 0 as Idx;
    for r in &rows {
        base.push(entries);
        entries += r.adjncy.len() as Idx;
    }
    let ends: Vec<&[Idx]> = rows.iter().map(|r| &r.ends[..]).collect();
    let mut xadj = vec![0 as Idx];
    xadj.append(&mut concat(&ends, |b, e| base[b] + e));
    let of =
        |field: fn(&Rows) -> &[Idx]| concat(&rows.iter().map(field).collect::<Vec<_>>(), |_, x| x);
    let coarse = Graph {
        xadj,
        adjncy: of(|r| &r.adjncy),
        vwgt: Some(of(|r| &r.vwgt)),
        adjwgt: Some(of(|r| &r.adjwgt)),
    };
    (coarse, cmap, members)
}

/// The blocks' `parts` one after the other, each element through `f(block, element)`,
/// copied on all threads: one thread copying a level's tens of megabytes (and faulting
/// their pages in) was most of what the coarsening left on one thread.
fn concat<T, U, P>(parts: &[P], f: impl Fn(usize, T) -> U + Sync) -> Vec<U>
where
    T: Copy + Sync,
    U: Copy + Default + Send,
    P: AsRef<[T]> + Sync,
{
    let total = parts.iter().map(|p| p.as_ref().len()).sum();
    let mut out = vec![U::default(); total];
    let mut slots = Vec::with_capacity(parts.len());
    let mut rest = &mut out[..];
    for p in parts {
        let (head, tail) = rest.split_at_mut(p.as_ref().len());
        slots.push(head);
        rest = tail;
    }
    (slots.into_par_iter().zip(parts.par_iter().enumerate())).for_each(|(slot, (b, p))| {
        (slot.iter_mut().zip(p.as_ref())).for_each(|(s, &x)| *s = f(b, x));
    });
    out
}

/// The pairs of the vertices `r` (see [`coarsen`]), matched within `r`.
fn matching(graph: &Graph, r: &std::ops::Range<usize>) -> Vec<[Idx; 2]> {
    let mut taken = vec![false; r.len()];
    let mut pairs = Vec::with_capacity(r.len() / 2 + 1);
    for v in r.clone() {
        if taken[v - r.start] {
            continue;
        }
        taken[v - r.start] = true;
        let mut mate = -1;
        let mut heaviest = 0;
        for k in graph.range(v) {
            let u = graph.adjncy[k] as usize;
            let w = graph.edge_weight(k);
            if r.contains(&u) && !taken[u - r.start] && w > heaviest {
                mate = u as Idx;
                heaviest = w;
            }
        }
        if mate >= 0 {
            taken[mate as usize - r.start] = true;
        }
        pairs.push([v as Idx, mate]);
    }
    pairs
}

/// The coarse rows of one block's pairs: each row's end (from the block's first entry),
/// neighbours, edge weights and vertex weights.
struct Rows {
    ends: Vec<Idx>,
    adjncy: Vec<Idx>,
    adjwgt: Vec<Idx>,
    vwgt: Vec<Idx>,
}

fn contract(graph: &Graph, cmap: &[Idx], pairs: &[[Idx; 2]]) -> Rows {
    let mut rows = Rows {
        ends: Vec::with_capacity(pairs.len()),
        adjncy: Vec::new(),
        adjwgt: Vec::new(),
        vwgt: Vec::with_capacity(pairs.len()),
    };
    for pair in pairs {
        let c = cmap[pair[0] as usize];
        let row_start = rows.adjncy.len();
        let mut weight = 0;
        for &w in pair.iter().filter(|&&w| w >= 0) {
            let w = w as usize;
            weight += graph.vertex_weight(w);
            for k in graph.range(w) {
                let d = cmap[graph.adjncy[k] as usize];
                if d == c {
                    continue;
                }
                let ew = graph.edge_weight(k);
                // A coarse row has a handful of entries: a scan finds d as fast as a
                // lookup table, which each block would need of the whole coarse size.
                match rows.adjncy[row_start..].iter().position(|&e| e == d) {
                    Some(s) => rows.adjwgt[row_start + s] += ew,
                    None => {
                        rows.adjncy.push(d);
                        rows.adjwgt.push(ew);
                    }
                }
            }
        }
        rows.vwgt.push(weight);
        rows.ends.push(rows.adjncy.len() as Idx);
    }
    rows
}

/// How far [`refine`] looks, in vertices, for another path between the neighbours of a
/// vertex before it gives up on moving it.
const BFS_BUDGET: usize = 20;

/// Greedy boundary refinement of `part` on `graph`, like METIS' own (greedy k-way, edge
/// cut objective): boundary vertices, best gain first, move to the neighbouring part
/// that reduces the cut most while that part stays within `max_weight`, or at equal cut
/// to a lighter part. At most `passes` sweeps; stops when a sweep moves nothing.
///
/// A vertex moves only when its own part stays connected without it (its neighbours in
/// that part are joined by a short path avoiding it), and it joins a part it touches,
/// so the number of connected pieces of a part never grows: contiguous parts stay so.
///
/// `weight` holds the weight of each part (and is kept up to date); `candidates` must
/// include every boundary vertex (a vertex with a neighbour in another part). Returns
/// the boundary vertices after refinement.
pub(crate) fn refine(
    graph: &Graph,
    part: &mut [Idx],
    weight: &mut [i64],
    max_weight: i64,
    passes: usize,
    candidates: impl IntoIterator<Item = Idx>,
) -> Vec<Idx> {
    let n = graph.num_vertices();
    let on_boundary = |part: &[Idx], v: usize| {
        graph
            .neighbours(v)
            .iter()
            .any(|&u| part[u as usize] != part[v])
    };
    let mut boundary: Vec<Idx> = candidates
        .into_iter()
        .filter(|&v| on_boundary(part, v as usize))
        .collect();
    let mut listed = vec![false; n];
    for &v in &boundary {
        listed[v as usize] = true;
    }
    let mut scratch = Scratch {
        stamp: vec![0; n],
        current: 0,
        queue: Vec::new(),
        targets: Vec::new(),
    };
    let mut links: Vec<(Idx, i64)> = Vec::new();
    let mut order: Vec<(i64, Idx)> = Vec::new();
    for _ in 0..passes {
        order.clear();
        for &v in &boundary {
            let internal = part_links(graph, part, v as usize, &mut links);
            let external = links.iter().map(|l| l.1).max().unwrap_or(0);
            order.push((internal - external, v));
            listed[v as usize] = false;
        }
        order.sort_unstable();
        boundary.clear();
        let mut moved = 0;
        for &(_, v) in &order {
            let v = v as usize;
            let from = part[v];
            let internal = part_links(graph, part, v, &mut links);
            let w = i64::from(graph.vertex_weight(v));
            let mut best: Option<(Idx, i64)> = None;
            for &(to, ext) in &links {
                let wt = weight[to as usize];
                let allowed = (ext > internal && wt + w <= max_weight)
                    || (ext == internal && wt + w < weight[from as usize]);
                let better =
                    best.is_none_or(|(b, be)| ext > be || (ext == be && wt < weight[b as usize]));
                if allowed && better {
                    best = Some((to, ext));
                }
            }
            if let Some((to, _)) = best {
                if weight[from as usize] > w && scratch.removable(graph, part, v) {
                    part[v] = to;
                    weight[from as usize] -= w;
                    weight[to as usize] += w;
                    moved += 1;
                    for &u in graph.neighbours(v) {
                        if !listed[u as usize] {
                            listed[u as usize] = true;
                            boundary.push(u);
                        }
                    }
                }
            }
            // Moved or not, v may still be on the boundary.
            if !listed[v] {
                listed[v] = true;
                boundary.push(v as Idx);
            }
        }
        boundary.retain(|&v| {
            let keep = on_boundary(part, v as usize);
            listed[v as usize] = keep;
            keep
        });
        if moved == 0 {
            break;
        }
    }
    boundary
}

/// Fills `links` with the other parts `v` touches and its edge weight to each; returns
/// its edge weight to its own part.
fn part_links(graph: &Graph, part: &[Idx], v: usize, links: &mut Vec<(Idx, i64)>) -> i64 {
    links.clear();
    let mut internal = 0;
    for k in graph.range(v) {
        let p = part[graph.adjncy[k] as usize];
        let w = i64::from(graph.edge_weight(k));
        if p == part[v] {
            internal += w;
        } else if let Some(l) = links.iter_mut().find(|l| l.0 == p) {
            l.1 += w;
        } else {
            links.push((p, w));
        }
    }
    internal
}

/// Reusable buffers of the bounded search in [`Scratch::removable`].
struct Scratch {
    stamp: Vec<u32>,
    current: u32,
    queue: Vec<Idx>,
    targets: Vec<Idx>,
}

impl Scratch {
    /// Whether the neighbours of `v` in its part are connected to each other without
    /// `v`, found by a breadth-first search inside the part bounded to [`BFS_BUDGET`]
    /// vertices (false when it runs out: the move is then skipped, never unsafe).
    fn removable(&mut self, graph: &Graph, part: &[Idx], v: usize) -> bool {
        let p = part[v];
        self.targets.clear();
        self.targets.extend(
            graph
                .neighbours(v)
                .iter()
                .filter(|&&u| part[u as usize] == p),
        );
        if self.targets.len() <= 1 {
            return true;
        }
        self.current += 1;
        let s = self.current;
        self.stamp[v] = s;
        self.queue.clear();
        self.queue.push(self.targets[0]);
        self.stamp[self.targets[0] as usize] = s;
        let mut reached = 1;
        let mut head = 0;
        while head < self.queue.len() && self.queue.len() <= BFS_BUDGET {
            let x = self.queue[head] as usize;
            head += 1;
            for &y in graph.neighbours(x) {
                if self.stamp[y as usize] != s && part[y as usize] == p {
                    self.stamp[y as usize] = s;
                    self.queue.push(y);
                    if self.targets.contains(&y) {
                        reached += 1;
                        if reached == self.targets.len() {
                            return true;
                        }
                    }
                }
            }
        }
        false
    }
}
