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
use crate::graph::{pieces_and_cut, Graph};
use metis::Idx;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::sync::atomic::{AtomicU64, Ordering as Atomic};

/// Directions a line is tried across (unnormalised: only the order of the projections
/// counts).
const DIRECTIONS: [[f64; 2]; 4] = [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -1.0]];

/// Sets at least this large try their directions, and cut their two sides, at once on
/// the pool's threads; smaller ones are not worth a task.
const PARALLEL: usize = 20_000;

/// The part of every vertex of `graph`, whose vertex `v` lies at `centroids[v]`, cut
/// into `nparts` parts of equal size and refined (`max_weight`: the largest part
/// allowed, `passes`: refinement passes); `None` where the lines do not apply (weighted
/// vertices or edges, which they do not see; fewer vertices than parts) or left a part
/// in several pieces.
pub(crate) fn straight_cuts(
    graph: &Graph,
    centroids: &[[f64; 2]],
    nparts: usize,
    max_weight: i64,
    passes: usize,
) -> Option<Vec<Idx>> {
    let n = graph.num_vertices();
    assert_eq!(centroids.len(), n, "one position per vertex");
    if graph.vwgt.is_some() || graph.adjwgt.is_some() || nparts < 2 || n < nparts {
        return None;
    }
    let cuts = Cuts {
        graph,
        centroids,
        label: (0..n).map(|_| AtomicU64::new(1)).collect(),
        reach: reach(graph, centroids),
    };
    let mut ids: Vec<Idx> = (0..n as Idx).collect();
    cuts.cut(&mut ids, 1, nparts);
    // Each part is a run of `ids`, in part order, of the sizes the cuts gave it.
    let mut part = vec![0 as Idx; n];
    let mut start = 0;
    for (p, len) in run_lengths(n, nparts).into_iter().enumerate() {
        for &v in &ids[start..start + len] {
            part[v as usize] = p as Idx;
        }
        start += len;
    }
    drop(ids);
    let mut weight = vec![0i64; nparts];
    for &p in &part {
        weight[p as usize] += 1;
    }
    let boundary: Vec<Idx> = (0..n)
        .into_par_iter()
        .filter(|&v| {
            let p = part[v];
            graph.neighbours(v).iter().any(|&u| part[u as usize] != p)
        })
        .map(|v| v as Idx)
        .collect();
    coarsen::refine(graph, &mut part, &mut weight, max_weight, passes, boundary);
    let (pieces, _) = pieces_and_cut(graph, nparts, |v| part[v] as u32);
    pieces.iter().all(|&p| p == 1).then_some(part)
}

/// The sizes of the parts that [`Cuts::cut`] makes of `n` vertices, in part order.
fn run_lengths(n: usize, nparts: usize) -> Vec<usize> {
    if nparts == 1 {
        return vec![n];
    }
    let first = nparts / 2;
    let m = split_at(n, first, nparts);
    let mut runs = run_lengths(m, first);
    runs.extend(run_lengths(n - m, nparts - first));
    runs
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
}

/// Along each direction, the largest distance between the positions of two neighbours:
/// an edge a line crosses joins a vertex on its near side within this distance of the
/// line, so only those are searched.
fn reach(graph: &Graph, centroids: &[[f64; 2]]) -> [f64; DIRECTIONS.len()] {
    // Each edge once, from its lower end; the diagonals' distances from the axes'.
    let [dx, dy, sum, diff] = (0..graph.num_vertices())
        .into_par_iter()
        .fold(
            || [0.0f64; 4],
            |mut far, v| {
                let p = centroids[v];
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
                far
            },
        )
        .reduce(|| [0.0; 4], |a, b| std::array::from_fn(|d| a[d].max(b[d])));
    debug_assert_eq!(
        DIRECTIONS,
        [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -1.0]]
    );
    [dx, dy, sum, diff]
}

impl Cuts<'_> {
    /// Cuts `ids` (all labelled `set`) into `nparts` runs, in place; each side keeps the
    /// order its vertices had, so that the runs keep the locality of the graph's
    /// numbering.
    fn cut(&self, ids: &mut [Idx], set: u64, nparts: usize) {
        // At most 2^31 vertices, so no chain of cuts is 63 deep: the heap numbers fit.
        if nparts == 1 {
            return;
        }
        let first = nparts / 2;
        let m = split_at(ids.len(), first, nparts);
        let large = ids.len() >= PARALLEL;
        let try_direction = |d: usize| self.try_line(ids, set, m, d);
        let tried: Vec<(usize, Line)> = if large {
            (0..DIRECTIONS.len())
                .into_par_iter()
                .map(try_direction)
                .collect()
        } else {
            (0..DIRECTIONS.len()).map(try_direction).collect()
        };
        // The fewest edges crossed, the first direction on a tie: the same parts on any
        // number of threads.
        let (_, line) = tried
            .into_iter()
            .reduce(|a, b| if b.0 < a.0 { b } else { a })
            .expect("four directions");
        let (near, far): (Vec<Idx>, Vec<Idx>) = match large {
            true => ids.par_iter().partition(|&&v| !line.beyond(self, v)),
            false => ids.iter().partition(|&&v| !line.beyond(self, v)),
        };
        debug_assert_eq!(near.len(), m, "the pivot is the m-th of distinct keys");
        ids[..near.len()].copy_from_slice(&near);
        ids[near.len()..].copy_from_slice(&far);
        drop((near, far));
        let (a, b) = ids.split_at_mut(m);
        let relabel = |side: &[Idx], to: u64| {
            for &v in side {
                self.label[v as usize].store(to, Atomic::Relaxed);
            }
        };
        if large {
            rayon::join(|| relabel(a, 2 * set), || relabel(b, 2 * set + 1));
            rayon::join(
                || self.cut(a, 2 * set, first),
                || self.cut(b, 2 * set + 1, nparts - first),
            );
        } else {
            relabel(a, 2 * set);
            relabel(b, 2 * set + 1);
            self.cut(a, 2 * set, first);
            self.cut(b, 2 * set + 1, nparts - first);
        }
    }

    /// The line across direction `d` with `m` of `ids` on its near side, and the
    /// dual-graph edges it crosses inside the set.
    fn try_line(&self, ids: &[Idx], set: u64, m: usize, d: usize) -> (usize, Line) {
        let mut keys: Vec<(f64, Idx)> = ids.iter().map(|&v| (self.key(d, v), v)).collect();
        if m == keys.len() {
            // Nothing on the far side: no vertex is beyond, no edge crossed.
            return (0, Line(d, (f64::INFINITY, Idx::MAX)));
        }
        keys.select_nth_unstable_by(m, |a, b| order(*a, *b));
        let line = Line(d, keys[m]);
        // Twice the reach: a margin far beyond the round-off of the keys' differences.
        let from = line.1 .0 - 2.0 * self.reach[d];
        let crossed = |&(k, v): &(f64, Idx)| match k < from {
            true => 0,
            false => (self.graph.neighbours(v as usize).iter())
                .filter(|&&u| {
                    self.label[u as usize].load(Atomic::Relaxed) == set && line.beyond(self, u)
                })
                .count(),
        };
        let near = &keys[..m];
        let edges = match near.len() >= PARALLEL {
            true => near.par_iter().map(crossed).sum(),
            false => near.iter().map(crossed).sum(),
        };
        (edges, line)
    }

    /// Where vertex `v` lies along direction `d`.
    fn key(&self, d: usize, v: Idx) -> f64 {
        let p = self.centroids[v as usize];
        p[0] * DIRECTIONS[d][0] + p[1] * DIRECTIONS[d][1]
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
        let part = straight_cuts(&graph, &centroids, 2, 160, 10).expect("connected parts");
        assert_eq!(cut_of(&graph, &part), 4);
        let left = (0..part.len()).filter(|&v| part[v] == 0).count();
        assert_eq!(left, 160);
        // The part of x < 20 is one side.
        for (v, c) in centroids.iter().enumerate() {
            assert_eq!(part[v], Idx::from(c[0] > 20.0), "triangle {v} at {c:?}");
        }
    }

    #[test]
    fn the_edges_a_line_crosses_are_all_counted() {
        // Positions moved off the grid's lattice, so that keys differ by odd amounts.
        let (graph, mut centroids) = grid(37, 23);
        for (v, c) in centroids.iter_mut().enumerate() {
            let h = (v as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
            c[0] += (h % 997) as f64 * 1e-4;
            c[1] += (h % 991) as f64 * 7e-5;
        }
        let n = graph.num_vertices();
        let cuts = Cuts {
            graph: &graph,
            centroids: &centroids,
            label: (0..n).map(|_| AtomicU64::new(1)).collect(),
            reach: reach(&graph, &centroids),
        };
        let ids: Vec<Idx> = (0..n as Idx).collect();
        for m in [1, n / 3, n / 2, n - 1] {
            for d in 0..DIRECTIONS.len() {
                let (edges, line) = cuts.try_line(&ids, 1, m, d);
                let beyond = |v: usize| line.beyond(&cuts, v as Idx);
                assert_eq!((0..n).filter(|&v| !beyond(v)).count(), m);
                let all: usize = (0..n)
                    .filter(|&v| !beyond(v))
                    .map(|v| {
                        graph
                            .neighbours(v)
                            .iter()
                            .filter(|&&u| beyond(u as usize))
                            .count()
                    })
                    .sum();
                assert_eq!(edges, all, "direction {d}, {m} on the near side");
            }
        }
    }

    #[test]
    fn parts_of_equal_size_for_any_count() {
        let (graph, centroids) = grid(30, 20);
        let n = graph.num_vertices();
        for nparts in [2, 3, 5, 7, 16] {
            let max = (n as i64 * 1030) / (1000 * nparts as i64);
            let part = straight_cuts(&graph, &centroids, nparts, max, 10).expect("connected");
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
        }
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
