//! Recursive straight cuts: parts of a 2D mesh from its triangles' positions.
//!
//! A set of triangles is cut in two by a straight line across one of four directions
//! (the axes and the diagonals), placed at the quantile that gives each side its share
//! of the parts; the direction whose line crosses the fewest dual-graph edges wins, and
//! each side is cut again until every part is one set. The greedy refinement that
//! follows METIS's cut elsewhere in this crate then smooths the parts' boundaries where
//! the lines cross the mesh's rows of triangles.
//!
//! On the connected meshes measured (docs/performance.md of contact-par) the edge cut
//! is that of the coarsened METIS cut within a few percent either way, from 2 to 64
//! parts, for a few linear passes over the triangles: no coarsening levels, no METIS.
//! The parts are not always connected (a line across a bent body can leave one side
//! in two pieces): the caller then gets `None`, and cuts with METIS. A graph with ties
//! between bodies is cut as any other: a tie is one more edge a line may cross, as it
//! is for METIS.

use crate::coarsen;
use crate::graph::{atomic_view, pieces_and_cut, Graph};
use metis::Idx;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::sync::atomic::{AtomicI32, AtomicU64, Ordering as Atomic};
use std::sync::Mutex;

/// Directions a line is tried across (unnormalised: only the order of the projections
/// counts).
const DIRECTIONS: [[f64; 2]; 4] = [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -1.0]];

/// Sets at least this large try their directions, and cut their two sides, at once on
/// the pool's threads; smaller ones are not worth a task.
const PARALLEL: usize = 20_000;

/// Vertices a task of a pass over a large set takes at least.
const CHUNK: usize = 1 << 14;

/// Buckets per direction of [`Cuts::lines_by_buckets`]'s counts.
const BUCKETS: usize = 1024;

/// The part of every vertex of `graph`, whose vertex `v` lies at `centroids[v]`, cut
/// into `nparts` parts of equal size and refined (`max_weight`: the largest part
/// allowed, `passes`: refinement passes), and the edges cut; `None` where the lines do
/// not apply (weighted vertices or edges, which they do not see; fewer vertices than
/// parts) or left a part in several pieces.
pub(crate) fn straight_cuts(
    graph: &Graph,
    centroids: &[[f64; 2]],
    nparts: usize,
    max_weight: i64,
    passes: usize,
) -> Option<(Vec<Idx>, usize)> {
    let n = graph.num_vertices();
    assert_eq!(centroids.len(), n, "one position per vertex");
    if graph.vwgt.is_some() || graph.adjwgt.is_some() || nparts < 2 || n < nparts {
        return None;
    }
    let (mut part, boundary) = lines(graph, centroids, nparts);
    let mut weight = vec![0i64; nparts];
    for &p in &part {
        weight[p as usize] += 1;
    }
    coarsen::refine(graph, &mut part, &mut weight, max_weight, passes, boundary);
    let (pieces, cut) = pieces_and_cut(graph, nparts, |v| part[v] as u32);
    pieces.iter().all(|&p| p == 1).then_some((part, cut))
}

/// The parts of the straight lines alone, and the vertices on the parts' boundaries
/// (in increasing order).
fn lines(graph: &Graph, centroids: &[[f64; 2]], nparts: usize) -> (Vec<Idx>, Vec<Idx>) {
    let n = graph.num_vertices();
    let cuts = Cuts::new(graph, centroids);
    let mut ids: Vec<Idx> = (0..n as Idx).collect();
    // Every vertex is in one part, whose cut writes it.
    let mut part = vec![0 as Idx; n];
    cuts.cut(&mut ids, 1, nparts, 0, atomic_view(&mut part));
    drop(ids);
    // Every edge between two parts was crossed by the line that first set its ends
    // apart: the ends of those edges are the parts' boundary, found without a pass over
    // the graph. In order, so that the refinement sees them in the same order on any
    // number of threads.
    let mut boundary = cuts.boundary.into_inner().expect("no task panicked");
    boundary.par_sort_unstable();
    boundary.dedup();
    (part, boundary)
}

/// Writes `first_part`, plus one where `second(v)`, as the part of each vertex `v` of
/// `ids` (on the pool's threads where `large`).
fn mark_parts(
    ids: &[Idx],
    large: bool,
    part: &[AtomicI32],
    first_part: usize,
    second: impl Fn(Idx) -> bool + Sync,
) {
    let mark = |&v: &Idx| {
        let p = first_part + usize::from(second(v));
        part[v as usize].store(p as Idx, Atomic::Relaxed);
    };
    match large {
        true => ids.par_iter().for_each(mark),
        false => ids.iter().for_each(mark),
    }
}

/// How many of `n` vertices go to the side of `first` of `nparts` parts.
fn split_at(n: usize, first: usize, nparts: usize) -> usize {
    ((n as u128 * first as u128) / nparts as u128) as usize
}

struct Cuts<'a> {
    graph: &'a Graph,
    centroids: &'a [[f64; 2]],
    /// The set a vertex is in while its set is being cut, numbered as a binary heap (the
    /// sides of set `s` are `2s` and `2s + 1`): a set's vertices read their neighbours'
    /// labels to tell their own set from the others, which other tasks relabel at once.
    label: Vec<AtomicU64>,
    /// Along each direction, the farthest apart two neighbours lie ([`reach`]).
    reach: [f64; DIRECTIONS.len()],
    /// Along each direction, the lowest and highest position of a vertex.
    range: [[f64; 2]; DIRECTIONS.len()],
    /// The ends of the edges the chosen lines cross: where the parts meet.
    boundary: Mutex<Vec<Idx>>,
}

/// A line tried: the edges it crosses inside its set, and the vertices on its near side
/// at which they start.
struct Tried {
    edges: usize,
    line: Line,
    band: Vec<Idx>,
}

/// Along each direction, the largest distance between the positions of two neighbours:
/// an edge a line crosses joins a vertex on its near side within this distance of the
/// line, so only those are searched.
fn reach(graph: &Graph, centroids: &[[f64; 2]]) -> Reach {
    // Each edge once, from its lower end; the diagonals' distances from the axes'.
    let (far, range) = (0..graph.num_vertices())
        .into_par_iter()
        .fold(
            || ([0.0f64; 4], [[f64::INFINITY, f64::NEG_INFINITY]; 4]),
            |(mut far, mut range), v| {
                let p = centroids[v];
                for (r, k) in range.iter_mut().zip(keys(p)) {
                    *r = [r[0].min(k), r[1].max(k)];
                }
                for &u in graph.neighbours(v).iter().filter(|&&u| u as usize > v) {
                    let q = centroids[u as usize];
                    let (x, y) = (q[0] - p[0], q[1] - p[1]);
                    far = [
                        far[0].max(x.abs()),
                        far[1].max(y.abs()),
                        far[2].max((x + y).abs()),
                        far[3].max((x - y).abs()),
                    ];
                }
                (far, range)
            },
        )
        .reduce(
            || ([0.0; 4], [[f64::INFINITY, f64::NEG_INFINITY]; 4]),
            |a, b| {
                let far = std::array::from_fn(|d| a.0[d].max(b.0[d]));
                let range =
                    std::array::from_fn(|d| [a.1[d][0].min(b.1[d][0]), a.1[d][1].max(b.1[d][1])]);
                (far, range)
            },
        );
    Reach { far, range }
}

/// Along each direction: the largest distance between two neighbours' positions, and
/// the lowest and highest position.
struct Reach {
    far: [f64; DIRECTIONS.len()],
    range: [[f64; 2]; DIRECTIONS.len()],
}

/// Where position `p` lies along each direction.
fn keys(p: [f64; 2]) -> [f64; DIRECTIONS.len()] {
    std::array::from_fn(|d| along(p, d))
}

/// Where position `p` lies along direction `d`: the one definition of a key, so that
/// every search and [`Line::beyond`] order the same values (a product by 0 would turn
/// -0 into +0, which the total order tells apart).
fn along(p: [f64; 2], d: usize) -> f64 {
    debug_assert_eq!(
        DIRECTIONS,
        [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -1.0]]
    );
    let [x, y] = p;
    match d {
        0 => x,
        1 => y,
        2 => x + y,
        _ => x - y,
    }
}

impl<'a> Cuts<'a> {
    fn new(graph: &'a Graph, centroids: &'a [[f64; 2]]) -> Self {
        let Reach { far, range } = reach(graph, centroids);
        Cuts {
            graph,
            centroids,
            label: (0..graph.num_vertices())
                .into_par_iter()
                .map(|_| AtomicU64::new(1))
                .collect(),
            reach: far,
            range,
            boundary: Mutex::new(Vec::new()),
        }
    }

    /// Cuts `ids` (all labelled `set`) into `nparts` parts, numbered from `first_part`
    /// in `part`; where it cuts again, each side keeps the order its vertices had, so
    /// that the sides keep the locality of the graph's numbering.
    fn cut(&self, ids: &mut [Idx], set: u64, nparts: usize, first_part: usize, part: &[AtomicI32]) {
        let large = ids.len() >= PARALLEL;
        if nparts == 1 {
            mark_parts(ids, large, part, first_part, |_| false);
            return;
        }
        // At most 2^31 vertices, so no chain of cuts is 63 deep: the heap numbers fit.
        let first = nparts / 2;
        let m = split_at(ids.len(), first, nparts);
        let try_direction = |d: usize| self.try_line(ids, set, m, d);
        let tried: Vec<Tried> = if set == 1 && large {
            self.lines_by_buckets(ids, set, m).into()
        } else if large {
            (0..DIRECTIONS.len())
                .into_par_iter()
                .map(try_direction)
                .collect()
        } else {
            (0..DIRECTIONS.len()).map(try_direction).collect()
        };
        // The fewest edges crossed, the first direction on a tie: the same parts on any
        // number of threads.
        let Tried { line, band, .. } = tried
            .into_iter()
            .reduce(|a, b| if b.edges < a.edges { b } else { a })
            .expect("four directions");
        // The crossed edges' far ends, while their labels still tell the set.
        let mut ends = Vec::with_capacity(2 * band.len());
        for &v in &band {
            ends.push(v);
            ends.extend(
                (self.graph.neighbours(v as usize).iter()).filter(|&&u| self.across(set, &line, u)),
            );
        }
        self.boundary
            .lock()
            .expect("no task panicked")
            .append(&mut ends);
        if nparts == 2 {
            debug_assert_eq!(
                ids.iter().filter(|&&v| !line.beyond(self, v)).count(),
                m,
                "the pivot is the m-th of distinct keys"
            );
            // Both sides are parts: each vertex's part at once, with no sides to gather.
            mark_parts(ids, large, part, first_part, |v| line.beyond(self, v));
            return;
        }
        let (near, far): (Vec<Idx>, Vec<Idx>) = match large {
            true => ids.par_iter().partition(|&&v| !line.beyond(self, v)),
            false => ids.iter().partition(|&&v| !line.beyond(self, v)),
        };
        debug_assert_eq!(near.len(), m, "the pivot is the m-th of distinct keys");
        ids[..near.len()].copy_from_slice(&near);
        ids[near.len()..].copy_from_slice(&far);
        drop((near, far));
        let (a, b) = ids.split_at_mut(m);
        // A side that is a part is not cut again: its labels are read no more.
        let relabel = |side: &[Idx], to: u64, parts: usize| {
            if parts > 1 {
                for &v in side {
                    self.label[v as usize].store(to, Atomic::Relaxed);
                }
            }
        };
        let second = first_part + first;
        if large {
            rayon::join(
                || relabel(a, 2 * set, first),
                || relabel(b, 2 * set + 1, nparts - first),
            );
            rayon::join(
                || self.cut(a, 2 * set, first, first_part, part),
                || self.cut(b, 2 * set + 1, nparts - first, second, part),
            );
        } else {
            relabel(a, 2 * set, first);
            relabel(b, 2 * set + 1, nparts - first);
            self.cut(a, 2 * set, first, first_part, part);
            self.cut(b, 2 * set + 1, nparts - first, second, part);
        }
    }

    /// The line across direction `d` with `m` of `ids` on its near side, the dual-graph
    /// edges it crosses inside the set, and the vertices they start from.
    fn try_line(&self, ids: &[Idx], set: u64, m: usize, d: usize) -> Tried {
        let mut keys: Vec<(f64, Idx)> = ids.iter().map(|&v| (self.key(d, v), v)).collect();
        if m == keys.len() {
            // Nothing on the far side: no vertex is beyond, no edge crossed.
            let line = Line(d, (f64::INFINITY, Idx::MAX));
            return self.crossings(set, line, &[]);
        }
        keys.select_nth_unstable_by(m, |a, b| order(*a, *b));
        let line = Line(d, keys[m]);
        // Twice the reach: a margin far beyond the round-off of the keys' differences.
        let from = line.1 .0 - 2.0 * self.reach[d];
        let near: Vec<Idx> = (keys[..m].iter())
            .filter(|&&(k, _)| k >= from)
            .map(|&(_, v)| v)
            .collect();
        self.crossings(set, line, &near)
    }

    /// [`Cuts::try_line`] across every direction at once: the m-th key is found from
    /// counts of the keys in buckets of equal width over the whole graph's range (a
    /// histogram), then among the keys of its bucket alone, which are gathered with
    /// those near enough below it to start an edge the line may cross. Two passes, each
    /// reading the positions once for all four directions, where sorting out the m-th
    /// key of each direction on its own takes a copy of the keys and several passes
    /// over it. For the first cut of a large graph only: the smaller sets after it were
    /// slower so than with [`Cuts::try_line`] on a thread per direction (at 1M nodes,
    /// into 4 to 64 parts), a set's keys filling few of the buckets.
    fn lines_by_buckets(&self, ids: &[Idx], set: u64, m: usize) -> [Tried; 4] {
        const D: usize = DIRECTIONS.len();
        let chunks = || ids.par_iter().with_min_len(CHUNK);
        let lo: [f64; D] = std::array::from_fn(|d| self.range[d][0]);
        // Monotone in the key (a difference from one value, times one positive
        // factor, rounded down), so a bucket's keys all lie between those of the
        // buckets before and after it, and equal keys share a bucket.
        let scale: [f64; D] = std::array::from_fn(|d| {
            let [lo, hi] = self.range[d];
            match hi > lo {
                true => BUCKETS as f64 / (hi - lo),
                false => 0.0,
            }
        });
        let bucket = |d: usize, k: f64| (((k - lo[d]) * scale[d]) as usize).min(BUCKETS - 1);
        let counts = chunks()
            .fold(
                || vec![0usize; D * BUCKETS],
                |mut c, &v| {
                    for (d, k) in self.keys(v).into_iter().enumerate() {
                        c[d * BUCKETS + bucket(d, k)] += 1;
                    }
                    c
                },
            )
            .reduce(
                || vec![0usize; D * BUCKETS],
                |mut a, b| {
                    a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                    a
                },
            );
        // The bucket holding the m-th key, and how many keys lie in the buckets below.
        let pivot_bucket: [(usize, usize); D] = std::array::from_fn(|d| {
            let mut below = 0;
            for (j, &c) in counts[d * BUCKETS..(d + 1) * BUCKETS].iter().enumerate() {
                if below + c > m {
                    return (j, below);
                }
                below += c;
            }
            unreachable!("m is below the set's size")
        });
        // Keys of the pivot's bucket are at least one bucket above `lo`, less
        // round-off far below a bucket's width: so from one bucket lower, less twice
        // the reach, every key is gathered that may start a crossed edge.
        let from: [f64; D] = std::array::from_fn(|d| match pivot_bucket[d].0 {
            0 => f64::NEG_INFINITY,
            j => lo[d] + (j - 1) as f64 / scale[d] - 2.0 * self.reach[d],
        });
        type Gathered = [(Vec<(f64, Idx)>, Vec<(f64, Idx)>); D];
        let empty = || -> Gathered { std::array::from_fn(|_| (Vec::new(), Vec::new())) };
        let mut gathered = chunks()
            .fold(empty, |mut got, &v| {
                for (d, k) in self.keys(v).into_iter().enumerate() {
                    let b = bucket(d, k);
                    if b == pivot_bucket[d].0 {
                        got[d].0.push((k, v));
                    }
                    if b <= pivot_bucket[d].0 && k >= from[d] {
                        got[d].1.push((k, v));
                    }
                }
                got
            })
            .reduce(empty, |mut a, b| {
                for (x, (mut members, mut near)) in a.iter_mut().zip(b) {
                    x.0.append(&mut members);
                    x.1.append(&mut near);
                }
                a
            });
        // The (key, index) order is total: the same pivot whatever order the members
        // were gathered in.
        std::array::from_fn(|d| {
            let (members, near) = &mut gathered[d];
            let (_, below) = pivot_bucket[d];
            let (_, &mut pivot, _) =
                members.select_nth_unstable_by(m - below, |a, b| order(*a, *b));
            let line = Line(d, pivot);
            let from = pivot.0 - 2.0 * self.reach[d];
            let near: Vec<Idx> = (near.iter())
                .filter(|&&(k, v)| k >= from && order((k, v), pivot) == Ordering::Less)
                .map(|&(_, v)| v)
                .collect();
            self.crossings(set, line, &near)
        })
    }

    /// `line` tried: the edges from `near` (vertices of set `set` on its near side,
    /// all those within twice the reach of it) to vertices of the set beyond it.
    fn crossings(&self, set: u64, line: Line, near: &[Idx]) -> Tried {
        let count = |&v: &Idx| {
            (self.graph.neighbours(v as usize).iter())
                .filter(|&&u| self.across(set, &line, u))
                .count()
        };
        let counted: Vec<usize> = match near.len() >= PARALLEL {
            true => near.par_iter().map(count).collect(),
            false => near.iter().map(count).collect(),
        };
        Tried {
            edges: counted.iter().sum(),
            line,
            band: (near.iter().zip(&counted))
                .filter(|&(_, &c)| c > 0)
                .map(|(&v, _)| v)
                .collect(),
        }
    }

    /// Whether `u` is in set `set` and beyond `line`.
    fn across(&self, set: u64, line: &Line, u: Idx) -> bool {
        self.label[u as usize].load(Atomic::Relaxed) == set && line.beyond(self, u)
    }

    /// Where vertex `v` lies along each direction.
    fn keys(&self, v: Idx) -> [f64; DIRECTIONS.len()] {
        keys(self.centroids[v as usize])
    }

    /// Where vertex `v` lies along direction `d`.
    fn key(&self, d: usize, v: Idx) -> f64 {
        along(self.centroids[v as usize], d)
    }
}

/// A line across direction `.0` through the vertex `.1` (its key and index): the far
/// side holds that vertex and those after it, keys ordered and ties broken by index.
#[derive(Clone, Copy)]
struct Line(usize, (f64, Idx));

impl Line {
    fn beyond(&self, cuts: &Cuts, v: Idx) -> bool {
        order((cuts.key(self.0, v), v), self.1) != Ordering::Less
    }
}

fn order(a: (f64, Idx), b: (f64, Idx)) -> Ordering {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dual graph of an `nx` x `ny` grid of squares, each cut into two triangles,
    /// and the triangles' centroids.
    fn grid(nx: usize, ny: usize) -> (Graph, Vec<[f64; 2]>) {
        squares(nx, ny, |_, _| true)
    }

    /// Moves each position off the lattice by its own amount, up to about a thousand
    /// times `dx` and `dy`: keys then differ by odd amounts.
    fn jitter(centroids: &mut [[f64; 2]], dx: f64, dy: f64) {
        for (v, c) in centroids.iter_mut().enumerate() {
            let h = (v as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
            c[0] += (h % 997) as f64 * dx;
            c[1] += (h % 991) as f64 * dy;
        }
    }

    fn cut_of(graph: &Graph, part: &[Idx]) -> usize {
        pieces_and_cut(graph, 1 + *part.iter().max().unwrap() as usize, |v| {
            part[v] as u32
        })
        .1
    }

    #[test]
    fn a_long_strip_is_cut_across_its_width() {
        // 40 x 4 squares: the line between columns 19 and 20 crosses one edge per row.
        let (graph, centroids) = grid(40, 4);
        let (part, cut) = straight_cuts(&graph, &centroids, 2, 160, 10).expect("connected parts");
        assert_eq!((cut_of(&graph, &part), cut), (4, 4));
        let left = (0..part.len()).filter(|&v| part[v] == 0).count();
        assert_eq!(left, 160);
        // The part of x < 20 is one side.
        for (v, c) in centroids.iter().enumerate() {
            assert_eq!(part[v], Idx::from(c[0] > 20.0), "triangle {v} at {c:?}");
        }
    }

    #[test]
    fn the_edges_a_line_crosses_are_all_counted() {
        let (graph, mut centroids) = grid(37, 23);
        jitter(&mut centroids, 1e-4, 7e-5);
        let n = graph.num_vertices();
        let cuts = Cuts::new(&graph, &centroids);
        let ids: Vec<Idx> = (0..n as Idx).collect();
        for m in [1, n / 3, n / 2, n - 1] {
            for d in 0..DIRECTIONS.len() {
                let Tried { edges, line, band } = cuts.try_line(&ids, 1, m, d);
                let beyond = |v: usize| line.beyond(&cuts, v as Idx);
                assert_eq!((0..n).filter(|&v| !beyond(v)).count(), m);
                let crossing = |v: usize| {
                    (graph.neighbours(v).iter())
                        .filter(|&&u| beyond(u as usize))
                        .count()
                };
                let near = || (0..n).filter(|&v| !beyond(v));
                let all: usize = near().map(crossing).sum();
                assert_eq!(edges, all, "direction {d}, {m} on the near side");
                let starts: Vec<Idx> = near()
                    .filter(|&v| crossing(v) > 0)
                    .map(|v| v as Idx)
                    .collect();
                assert_eq!(sorted(band), starts, "direction {d}, {m} on the near side");
            }
        }
    }

    #[test]
    fn the_buckets_find_the_lines_and_counts_of_the_sort() {
        // On the lattice (many equal keys, whole rows in one bucket) and off it.
        for shift in [false, true] {
            let (graph, mut centroids) = grid(61, 37);
            if shift {
                jitter(&mut centroids, 1e-3, -3e-3);
            }
            let n = graph.num_vertices();
            let cuts = Cuts::new(&graph, &centroids);
            // In an order other than the vertices', as a set's ids are after a cut.
            let ids: Vec<Idx> = (0..n as Idx).rev().collect();
            for m in [1, 7, n / 3, n / 2, n - 1] {
                let by_buckets = cuts.lines_by_buckets(&ids, 1, m);
                for (d, tried) in by_buckets.into_iter().enumerate() {
                    let by_sort = cuts.try_line(&ids, 1, m, d);
                    assert_eq!(
                        (
                            tried.edges,
                            tried.line.0,
                            tried.line.1 .1,
                            sorted(tried.band)
                        ),
                        (
                            by_sort.edges,
                            by_sort.line.0,
                            by_sort.line.1 .1,
                            sorted(by_sort.band)
                        ),
                        "shift {shift}, m {m}, direction {d}"
                    );
                }
            }
        }
    }

    #[test]
    fn parts_of_equal_size_for_any_count() {
        let (graph, centroids) = grid(30, 20);
        let n = graph.num_vertices();
        for nparts in [2, 3, 5, 7, 16] {
            let max = (n as i64 * 1030) / (1000 * nparts as i64);
            let (part, counted) =
                straight_cuts(&graph, &centroids, nparts, max, 10).expect("connected");
            let mut size = vec![0i64; nparts];
            for &p in &part {
                size[p as usize] += 1;
            }
            assert!(
                size.iter().all(|&s| s > 0 && s <= max),
                "{nparts}: {size:?}"
            );
            // A grid cut by lines: every part is a convex block of squares, so the cut
            // stays within a small multiple of the parts' perimeters.
            let cut = cut_of(&graph, &part);
            assert!(cut <= 30 * nparts, "{nparts} parts: cut {cut}");
            assert_eq!(counted, cut);
        }
    }

    #[test]
    fn the_lines_find_every_vertex_on_a_boundary() {
        // Large enough that the first line is found from buckets.
        let (graph, mut centroids) = grid(160, 90);
        jitter(&mut centroids, 2e-4, 0.0);
        for nparts in [2, 3, 7, 12] {
            let (part, boundary) = lines(&graph, &centroids, nparts);
            let expected: Vec<Idx> = (0..graph.num_vertices())
                .filter(|&v| (graph.neighbours(v).iter()).any(|&u| part[u as usize] != part[v]))
                .map(|v| v as Idx)
                .collect();
            assert!(expected.len() > 50 * (nparts - 1), "{nparts} parts");
            assert_eq!(boundary, expected, "{nparts} parts");
        }
    }

    fn sorted(mut v: Vec<Idx>) -> Vec<Idx> {
        v.sort_unstable();
        v
    }

    #[test]
    fn the_same_parts_on_one_thread_and_on_several() {
        let (graph, centroids) = grid(200, 150);
        let n = graph.num_vertices() as i64;
        let on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| straight_cuts(&graph, &centroids, 6, n * 1030 / 6000, 10))
        };
        assert_eq!(on(1), on(3));
    }

    /// The dual graph and centroids of the squares of an `nx` x `ny` grid that `keep`
    /// keeps, each cut into two triangles.
    fn squares(
        nx: usize,
        ny: usize,
        keep: impl Fn(usize, usize) -> bool,
    ) -> (Graph, Vec<[f64; 2]>) {
        let mut triangles = Vec::new();
        let node = |i: usize, j: usize| j * (nx + 1) + i;
        for j in 0..ny {
            for i in (0..nx).filter(|&i| keep(i, j)) {
                triangles.push([node(i, j), node(i + 1, j), node(i + 1, j + 1)]);
                triangles.push([node(i, j), node(i + 1, j + 1), node(i, j + 1)]);
            }
        }
        let xy = |n: usize| [(n % (nx + 1)) as f64, (n / (nx + 1)) as f64];
        let centroids = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(xy);
                [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
            })
            .collect();
        let stars = crate::graph::Stars::new((nx + 1) * (ny + 1), &triangles).unwrap();
        let graph = crate::graph::dual_from_stars(&triangles, &stars).unwrap();
        (graph, centroids)
    }

    #[test]
    fn a_part_in_two_pieces_is_refused() {
        // A U: a base 21 squares wide and 8 high, two legs 2 wide and 60 high. The legs
        // hold most of the area, so the line that crosses fewest edges runs across both
        // legs (4 edges, against 8 across the base), and their tops, one part, lie
        // apart.
        let (graph, centroids) = squares(21, 68, |i, j| j < 8 || !(2..19).contains(&i));
        let n = graph.num_vertices() as i64;
        assert_eq!(
            straight_cuts(&graph, &centroids, 2, n * 1030 / 2000, 10),
            None
        );
        // With a base 16 high, holding most of the area, the level line at the median
        // runs through the base (21 edges) and the upright one (16) wins: two whole
        // parts.
        let (graph, centroids) = squares(21, 68, |i, j| j < 16 || !(2..19).contains(&i));
        let n = graph.num_vertices() as i64;
        let part = straight_cuts(&graph, &centroids, 2, n * 1030 / 2000, 10);
        assert!(part.is_some());
    }
}
