//! Checks that a mesh is one sound elastic body before anything is built on it, and the
//! rigid-motion analysis that tells whether boundary conditions hold a body.
//!
//! Every check fails with one [`Error::Input`](crate::error::Error::Input) line that names
//! the mesh, the place and the fix. Nodes and triangles are numbered from 1 in file order
//! (Gmsh's own tags are not kept, though Gmsh numbers them the same way), so the messages
//! also give coordinates.

use crate::error::{input, Result};
use crate::mesh::{signed_area2, Mesh};
use rayon::prelude::*;
use std::collections::HashSet;

/// Two nodes within this fraction of the mesh size (in x and in y) are one point.
pub const SAME_POINT: f64 = 1e-12;

/// Constraint lines (see [`Holds`]) whose offsets differ by less than this fraction of the
/// mesh size are one line, and a line passing this close to a point goes through it: CAD
/// round-off along a straight line must not pass for a lever arm that holds a rotation.
pub const SAME_LINE: f64 = 1e-9;

/// Unit directions whose cross product is below this are parallel.
const PARALLEL: f64 = 1e-9;

/// Lower and upper corners of the box around `nodes` (infinite corners when empty).
///
/// The start of a run asks for the whole mesh's box several times (checks, order, r),
/// each on one thread where the pool's others wait: hence by pieces on the pool.
pub fn bounding_box(nodes: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    const PIECE: usize = 1 << 15;
    let of = |nodes: &[[f64; 2]]| {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in nodes {
            for c in 0..2 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        (lo, hi)
    };
    if nodes.len() <= PIECE {
        return of(nodes);
    }
    let both = |(a, b): ([f64; 2], [f64; 2]), (c, d): ([f64; 2], [f64; 2])| {
        (
            [a[0].min(c[0]), a[1].min(c[1])],
            [b[0].max(d[0]), b[1].max(d[1])],
        )
    };
    let empty = || ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    nodes.par_chunks(PIECE).map(of).reduce(empty, both)
}

/// The mesh size that relative tolerances refer to: the larger side of the bounding box.
pub fn size(mesh: &Mesh) -> f64 {
    let (lo, hi) = bounding_box(&mesh.nodes);
    (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.0)
}

/// Runs every mesh check in the order that gives the most useful message first, orients
/// the triangles counter-clockwise, and returns the boundary edges (node pairs
/// `(min, max)` that belong to exactly one triangle); and `with` the oriented mesh at the
/// same time as the last check (the edges), on another thread of the pool: e.g. the
/// mesh's separate parts, which need sound indices, not the edges' verdict.
pub fn check_with<T: Send>(
    mesh: &mut Mesh,
    name: &str,
    with: impl FnOnce(&Mesh) -> T + Send,
) -> Result<(HashSet<(usize, usize)>, T)> {
    references(mesh, name)?;
    let used = used_nodes(mesh);
    duplicate_nodes(mesh, &used, name)?;
    unused_nodes(mesh, &used, name)?;
    let listed_cw = orient(mesh, name)?;
    let mesh = &*mesh;
    let (boundary, also) = rayon::join(|| edges(mesh, &listed_cw, name), || with(mesh));
    Ok((boundary?, also))
}

/// Triangles exist, indices are in range and coordinates are finite. The Gmsh reader
/// already guarantees this; meshes built in code (the library API, the fuzzers) may not,
/// and must get an error rather than an index panic further on.
fn references(mesh: &Mesh, name: &str) -> Result<()> {
    let n = mesh.nodes.len();
    if mesh.triangles.is_empty() {
        return input(format!(
            "{name}: the mesh has no triangles; mesh the surface in 2D (`gmsh -2`)"
        ));
    }
    // On the pool, the first fault as a scan in order meets it: these scans of the whole
    // mesh ran on one core while the first rank's borrowed threads waited.
    if let Some(k) = mesh
        .nodes
        .par_iter()
        .position_first(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        let p = mesh.nodes[k];
        return input(format!(
            "{name}: node {} is at ({}, {}), not a finite point; fix the geometry",
            k + 1,
            p[0],
            p[1]
        ));
    }
    if let Some((t, &bad)) = mesh
        .triangles
        .par_iter()
        .enumerate()
        .find_map_first(|(t, tri)| tri.iter().find(|&&i| i >= n).map(|i| (t, i)))
    {
        return input(format!(
            "{name}: triangle {} uses node {}, but the mesh has {n} nodes; fix the mesh",
            t + 1,
            bad + 1
        ));
    }
    let lines = mesh
        .line_groups
        .iter()
        .flat_map(|(g, v)| v.iter().flatten().map(move |&i| (g, i)));
    let points = mesh
        .point_groups
        .iter()
        .flat_map(|(g, v)| v.iter().map(move |&i| (g, i)));
    if let Some((group, bad)) = lines.chain(points).find(|&(_, i)| i >= n) {
        return input(format!(
            "{name}: group \"{group}\" uses node {}, but the mesh has {n} nodes; fix the mesh",
            bad + 1
        ));
    }
    Ok(())
}

/// The set of the nodes a triangle uses ([`crate::mesh::bit_set`]: a flag per node set
/// by the threads at once was 80 ms of a 1M-node start).
fn used_nodes(mesh: &Mesh) -> Vec<u64> {
    crate::mesh::bit_set(mesh.nodes.len(), mesh.triangles.as_flattened())
}

/// Rejects two nodes at one place when a triangle uses at least one of them.
///
/// Why an error: coincident nodes cut the body along a slit (each side has its own node),
/// which only a crack model could use, and contact-par has none; far more often they are
/// a mesh whose pieces were never merged, and the body then falls apart under load.
fn duplicate_nodes(mesh: &Mesh, used: &[u64], name: &str) -> Result<()> {
    let used = |i: usize| crate::mesh::in_set(used, i);
    let nodes = &mesh.nodes;
    let (lo, _) = bounding_box(nodes);
    let tol = SAME_POINT * size(mesh);
    // Columns of width tol, then y: the duplicates of a node are in its column or the next
    // one, within tol in y. Sorting keeps this O(n log n) for any mesh, even one whose
    // nodes share a few x values (structured meshes).
    // Ties (one column, one y) may come in any order: the pairs found and the first one
    // reported do not depend on it.
    let mut order: Vec<(i64, f64, usize)> = nodes
        .par_iter()
        .enumerate()
        .map(|(i, p)| (column(p[0], lo[0], tol), p[1], i))
        .collect();
    order.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let close = |i: usize, j: usize| {
        (nodes[i][0] - nodes[j][0]).abs() <= tol && (nodes[i][1] - nodes[j][1]).abs() <= tol
    };
    let mut first: Option<(usize, usize)> = None;
    let mut pairs = 0usize;
    // Two bodies meshed on their own may touch: coincident nodes of different parts of
    // the mesh (no triangle path between them) are two bodies' nodes, not a crack.
    let mut part: Option<Vec<usize>> = None;
    column_pairs(
        &order,
        tol,
        |_| true,
        |i, j| {
            if close(i, j) && (used(i) || used(j)) {
                let part = part.get_or_insert_with(|| parts(mesh).0);
                if used(i) && used(j) && part[i] != part[j] {
                    return;
                }
                pairs += 1;
                let pair = (i.min(j), i.max(j));
                if first.is_none_or(|f| pair < f) {
                    first = Some(pair);
                }
            }
        },
    );
    let Some((i, j)) = first else {
        return Ok(());
    };
    input(duplicate_message(name, (i, nodes[i]), (j, nodes[j]), pairs))
}

/// The column of width `tol` (a tiny width for a zero one) from `lo` that holds `x`.
pub fn column(x: f64, lo: f64, tol: f64) -> i64 {
    ((x - lo) / tol.max(f64::MIN_POSITIVE)).floor() as i64
}

/// Every pair of entries of `order` (column, y, node), sorted by column then y, that
/// lie in one column or in two next to each other and within `tol` in y, the first of
/// them in a column that `from` takes: `found(first's node, other's node)`, each pair
/// once.
pub fn column_pairs(
    order: &[(i64, f64, usize)],
    tol: f64,
    from: impl Fn(i64) -> bool,
    mut found: impl FnMut(usize, usize),
) {
    // The first entry at or after (column + 1, y - tol): that bound only grows along the
    // sorted order, so one pointer walks it for all nodes.
    let mut next = 0;
    for (pos, &(column, y, i)) in order.iter().enumerate() {
        if !from(column) {
            continue;
        }
        while next < order.len()
            && (order[next].0 < column + 1
                || (order[next].0 == column + 1 && order[next].1 < y - tol))
        {
            next += 1;
        }
        let same = order[pos + 1..]
            .iter()
            .take_while(|e| e.0 == column && e.1 <= y + tol);
        let beside = order[next..]
            .iter()
            .take_while(|e| e.0 == column + 1 && e.1 <= y + tol);
        for &(_, _, j) in same.chain(beside) {
            found(i, j);
        }
    }
}

/// The message of two nodes at one place (`(index, point)` each, from 0), one of
/// `pairs` such pairs.
pub fn duplicate_message(
    name: &str,
    (i, a): (usize, [f64; 2]),
    (j, b): (usize, [f64; 2]),
    pairs: usize,
) -> String {
    let more = if pairs > 1 {
        format!(" ({pairs} such pairs)")
    } else {
        String::new()
    };
    format!(
        "{name}: nodes {} at ({}, {}) and {} at ({}, {}) are the same point (within {SAME_POINT:e} of the mesh size){more}: duplicate nodes cut the body apart and contact-par has no cracks; merge them (Gmsh: `Coherence Mesh;`) and export again",
        i + 1,
        a[0],
        a[1],
        j + 1,
        b[0],
        b[1]
    )
}

/// Rejects nodes that no triangle uses: their displacement has no stiffness at all, so
/// the matrix would be singular (or, under a condition, a load would act on nothing).
fn unused_nodes(mesh: &Mesh, used: &[u64], name: &str) -> Result<()> {
    let n = mesh.nodes.len();
    let Some(first) = (0..n)
        .into_par_iter()
        .position_first(|i| !crate::mesh::in_set(used, i))
    else {
        return Ok(());
    };
    // The set holds no index from `n` on.
    let count = n - used.iter().map(|w| w.count_ones() as usize).sum::<usize>();
    let group = mesh
        .line_groups
        .iter()
        .find(|(_, v)| v.iter().flatten().any(|&i| i == first))
        .map(|(g, _)| g)
        .or_else(|| {
            mesh.point_groups
                .iter()
                .find(|(_, v)| v.contains(&first))
                .map(|(g, _)| g)
        });
    input(unused_message(
        name,
        count,
        (first, mesh.nodes[first]),
        group.map(String::as_str),
    ))
}

/// The message of `count` unused nodes, the first (index from 0, point) in `group`.
pub fn unused_message(
    name: &str,
    count: usize,
    (first, p): (usize, [f64; 2]),
    group: Option<&str>,
) -> String {
    let group = group.map_or(String::new(), |g| format!(" (in group \"{g}\")"));
    let node = format!("node {} at ({}, {}){group}", first + 1, p[0], p[1]);
    let (what, them) = if count == 1 {
        (format!("{node} belongs"), "it")
    } else {
        (format!("{count} nodes, the first {node}, belong"), "them")
    };
    format!(
        "{name}: {what} to no triangle, so nothing holds {them}; remove {them} or re-export with Mesh.SaveAll = 0 (and keep construction points out of physical groups)"
    )
}

/// Orients every triangle counter-clockwise and rejects degenerate ones; returns, per
/// triangle, whether it was listed clockwise. A mesh listed all clockwise (a Gmsh surface
/// with normal -z) is flipped silently: the orientation of the listing carries no meaning
/// for a 2D body. Whether the flipped triangles fit their neighbours is [`edges`]' job.
pub fn orient(mesh: &mut Mesh, name: &str) -> Result<Vec<bool>> {
    let size = size(mesh);
    let nodes = &mesh.nodes;
    let clockwise = |t: &[usize; 3]| clockwise(nodes, *t, size);
    let listed_cw: Option<Vec<bool>> = mesh
        .triangles
        .par_iter_mut()
        .map(|t| {
            let cw = clockwise(t)?;
            if cw {
                t.swap(1, 2);
            }
            Some(cw)
        })
        .collect();
    if let Some(listed_cw) = listed_cw {
        return Ok(listed_cw);
    }
    // The threads stop at a degenerate triangle, not necessarily the first: the message
    // names the first in file order (never turned round, being degenerate).
    let t = mesh
        .triangles
        .iter()
        .position(|t| clockwise(t).is_none())
        .unwrap_or(0);
    let tri = mesh.triangles[t];
    input(degenerate_message(name, t, tri, nodes[tri[0]]))
}

/// Whether triangle `t` of `nodes` is listed clockwise; `None` for a degenerate one
/// (`size`: the mesh's, for its zero-length edges).
pub fn clockwise(nodes: &[[f64; 2]], [i, j, k]: [usize; 3], size: f64) -> Option<bool> {
    let a2 = signed_area2(nodes, [i, j, k]);
    // Squared lengths: hypot took a third of this check on millions of triangles.
    // The doubled area is a product of coordinate differences as well, so the squares
    // overflow or underflow no sooner than it does.
    let length2 = |a: usize, b: usize| {
        let (p, q) = (nodes[a], nodes[b]);
        (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)
    };
    let longest2 = length2(i, j).max(length2(j, k)).max(length2(k, i));
    // Relative to the element's own size (and the mesh's, for zero-length edges).
    let degenerate = a2.abs() <= 1e-12 * longest2 || longest2 <= (1e-14 * size).powi(2);
    (!degenerate).then_some(a2 < 0.0)
}

/// The message of degenerate triangle `t` with its `nodes` (indices from 0), the
/// first at `p`.
pub fn degenerate_message(name: &str, t: usize, [i, j, k]: [usize; 3], p: [f64; 2]) -> String {
    format!(
        "{name}: triangle {} (nodes {}, {}, {}, near ({}, {})) is degenerate (zero area); fix the mesh",
        t + 1,
        i + 1,
        j + 1,
        k + 1,
        p[0],
        p[1]
    )
}

/// After [`orient`]: rejects a mesh that folds over itself (inverted triangles) and
/// returns the boundary edges.
///
/// Why a geometric test rather than "every triangle listed the same way round": Gmsh lists
/// the triangles of each surface along that surface's normal, so a sound mesh of two
/// surfaces with opposite normals mixes both orientations, and turning such triangles
/// round is harmless. What must not happen is an inverted triangle, one whose corners
/// crossed over (a tangled mesh, e.g. after nodes were moved): it then lies on the same
/// side of an edge as its neighbour and overlaps it. Once every triangle is
/// counter-clockwise, each interior edge must be run once each way by its two triangles;
/// an edge run twice the same way, or shared by three triangles, is a fold. Of the two
/// triangles found there, the message names the one listed against the orientation of
/// most of the file, which is the inverted one in a mesh from Gmsh.
fn edges(mesh: &Mesh, listed_cw: &[bool], name: &str) -> Result<HashSet<(usize, usize)>> {
    let n = mesh.nodes.len();
    let nt = mesh.triangles.len();
    // 32-bit entries (half the memory of usize ones at millions of triangles).
    if n >= u32::MAX as usize || 3 * nt >= (u32::MAX >> 1) as usize {
        return input(format!(
            "{name}: {nt} triangles and {n} nodes are more than contact-par handles (2^30 edges)"
        ));
    }
    let cw_majority = 2 * listed_cw.iter().filter(|&&c| c).count() > nt;
    // Each edge in the row of its lower node: (other node, triangle << 1 | 1 when the
    // triangle runs the edge from low to high). The rows are scanned in node order, so
    // the first fold reported is the one a scan in order would meet first.
    let rows = NodeRows::new(n, &mesh.triangles, 3, |t, tri, put| {
        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            put(
                a.min(b),
                (a.max(b) as u32, (t as u32) << 1 | u32::from(a < b)),
            );
        }
    })
    .expect("fewer than 2^30 edges, checked above");
    let scanned = rows.scan(Vec::new, |found, low, row| {
        row.sort_unstable();
        for run in row.chunk_by(|x, y| x.0 == y.0) {
            let high = run[0].0 as usize;
            match run {
                [_] => found.push((low, high)),
                [x, y] if (x.1 ^ y.1) & 1 == 1 => {}
                _ => {
                    let (x, y) = same_way(run.iter().map(|e| u64::from(e.1)));
                    return Err(Fold {
                        edge: (low, high),
                        triangles: (x as usize, y as usize),
                    });
                }
            }
        }
        Ok(())
    });
    drop(rows);
    match scanned {
        Ok(found) => Ok(found.into_iter().flatten().collect()),
        Err(Fold {
            edge: (low, high),
            triangles: (x, y),
        }) => {
            let bad = inverted([x, y], |t| listed_cw[t] != cw_majority);
            let other = x + y - bad;
            input(fold_message(
                name,
                (bad, mesh.triangles[bad], centroid(mesh, bad)),
                [mesh.nodes[low], mesh.nodes[high]],
                other,
            ))
        }
    }
}

/// Entries that the triangles of a mesh give their nodes (e.g. each edge to its lower
/// node), in rows by node, for scans of every node's row by ranges of nodes on the pool.
///
/// Each piece of the triangles makes its own rows on a thread of its own (counted, then
/// filled); a node's row is then its rows in the pieces, in piece order, so in the
/// order of the triangles. Why pieces: ranges of nodes that each read every triangle
/// for their own nodes had to be few, and the last one ran alone while the pool's
/// other threads waited; with the rows made, the ranges can be many and small.
pub struct NodeRows<T> {
    /// Each piece's row starts (`n + 1`) and entries.
    pieces: Vec<(Vec<u32>, Vec<T>)>,
}

impl<T: Copy + Default + Send + Sync> NodeRows<T> {
    /// Nodes in a range of [`NodeRows::scan`].
    const RANGE: usize = 1 << 13;

    /// The rows of `n` nodes: `entries(t, triangle, put)` calls `put(node, entry)` for
    /// each of the at most `per_triangle` entries of triangle `t` (the same ones each
    /// time it is called). `None` where their count may not fit 32 bits.
    pub fn new(
        n: usize,
        triangles: &[[usize; 3]],
        per_triangle: usize,
        entries: impl Fn(usize, &[usize; 3], &mut dyn FnMut(usize, T)) + Sync,
    ) -> Option<Self> {
        let nt = triangles.len();
        if nt.checked_mul(per_triangle)? >= u32::MAX as usize {
            return None;
        }
        let pieces = rayon::current_num_threads()
            .clamp(1, 4)
            .min(nt.div_ceil(1 << 16))
            .max(1);
        let len = nt.div_ceil(pieces).max(1);
        let pieces = (triangles.par_chunks(len).enumerate())
            .map(|(k, piece)| {
                let mut start = vec![0u32; n + 1];
                for (i, t) in piece.iter().enumerate() {
                    entries(k * len + i, t, &mut |node, _| start[node + 1] += 1);
                }
                for i in 0..n {
                    start[i + 1] += start[i];
                }
                let mut fill = start.clone();
                let mut rows = vec![T::default(); start[n] as usize];
                for (i, t) in piece.iter().enumerate() {
                    entries(k * len + i, t, &mut |node, e| {
                        rows[fill[node] as usize] = e;
                        fill[node] += 1;
                    });
                }
                (start, rows)
            })
            .collect();
        Some(NodeRows { pieces })
    }

    /// `scan(node, row)` on every node's row, by ranges of nodes on the pool, each with
    /// its own state from `state()`; the first error in node order, else every range's
    /// state in node order.
    pub fn scan<S: Send, E: Send>(
        &self,
        state: impl Fn() -> S + Sync,
        scan: impl Fn(&mut S, usize, &mut Vec<T>) -> std::result::Result<(), E> + Sync,
    ) -> std::result::Result<Vec<S>, E> {
        let n = self.pieces.first().map_or(0, |p| p.0.len() - 1);
        (0..n.div_ceil(Self::RANGE))
            .into_par_iter()
            .map(|r| {
                let mut s = state();
                let mut row = Vec::new();
                for node in r * Self::RANGE..((r + 1) * Self::RANGE).min(n) {
                    row.clear();
                    for (start, entries) in &self.pieces {
                        row.extend_from_slice(
                            &entries[start[node] as usize..start[node + 1] as usize],
                        );
                    }
                    scan(&mut s, node, &mut row)?;
                }
                Ok(s)
            })
            // Each range's outcome kept, then taken in node order: rayon's own collect
            // into a `Result` returns whichever error it meets first.
            .collect::<Vec<_>>()
            .into_iter()
            .collect()
    }
}

/// Two triangles that run one edge the same way, from its `run` of (triangle << 1 | 1
/// when it runs the edge from low to high), sorted: there are two among three or more,
/// whatever their directions; the first such pair in the run's order.
pub fn same_way(run: impl Iterator<Item = u64> + Clone) -> (u64, u64) {
    let codes: Vec<u64> = run.collect();
    (codes.iter().enumerate())
        .find_map(|(k, x)| {
            (codes[k + 1..].iter())
                .find(|y| (x ^ *y) & 1 == 0)
                .map(|y| (x >> 1, y >> 1))
        })
        .unwrap_or((codes[0] >> 1, codes[1] >> 1))
}

/// Of the two triangles of a fold, the one to name: the one listed against the
/// orientation of most of the file (`against`), which is the inverted one in a mesh
/// from Gmsh; else the later.
pub fn inverted<T: Copy + Ord>([x, y]: [T; 2], against: impl Fn(T) -> bool) -> T {
    match (against(x), against(y)) {
        (true, false) => x,
        (false, true) => y,
        _ => x.max(y),
    }
}

/// The message of a fold: the inverted triangle (index from 0, its nodes as turned
/// counter-clockwise, its centroid), the ends of the edge, the other triangle.
pub fn fold_message(
    name: &str,
    (bad, [i, j, k], c): (usize, [usize; 3], [f64; 2]),
    [p, q]: [[f64; 2]; 2],
    other: usize,
) -> String {
    format!(
        "{name}: triangle {} (nodes {}, {}, {}, near ({}, {})) is inverted: it lies on the same side of its edge ({}, {}) - ({}, {}) as triangle {}, so the mesh folds over itself; move the misplaced nodes back or re-mesh",
        bad + 1,
        i + 1,
        j + 1,
        k + 1,
        c[0],
        c[1],
        p[0],
        p[1],
        q[0],
        q[1],
        other + 1
    )
}

/// An edge run the same way by two triangles (see [`edges`]).
struct Fold {
    edge: (usize, usize),
    triangles: (usize, usize),
}

fn centroid(mesh: &Mesh, t: usize) -> [f64; 2] {
    let [i, j, k] = mesh.triangles[t];
    let (a, b, c) = (mesh.nodes[i], mesh.nodes[j], mesh.nodes[k]);
    [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
}

/// The separate parts of a mesh (triangles joined through at least one node): the part of
/// each node, numbered from 0 in the order of their lowest node, and the number of parts.
pub fn parts(mesh: &Mesh) -> (Vec<usize>, usize) {
    let n = mesh.nodes.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, t[0]), root(&mut parent, t[k]));
            // The lower index as the root, so that a part is known by its lowest node.
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut label = vec![usize::MAX; n];
    let mut count = 0;
    let mut part = vec![0; n];
    for i in 0..n {
        let r = root(&mut parent, i);
        if label[r] == usize::MAX {
            label[r] = count;
            count += 1;
        }
        part[i] = label[r];
    }
    (part, count)
}

/// A rigid motion that the conditions on a part leave free (see [`Holds`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Free {
    /// Nothing holds the part.
    Everything,
    /// Every condition acts along one line, through `point` with direction `dir`: the part
    /// can translate across that line and rotate about any point of it.
    SlideAndTurn { point: [f64; 2], dir: [f64; 2] },
    /// Every condition acts along parallel lines: the part can translate along `along`,
    /// across them.
    Slide { along: [f64; 2] },
    /// Every condition acts along lines through `centre`: the part can rotate about it.
    Turn { centre: [f64; 2] },
}

/// The conditions on a rigid part, as lines of action (planar statics).
///
/// A condition that fixes the displacement of a point x along a unit direction d (a
/// Dirichlet component: d = e_x or e_y; a contact node: d = the obstacle normal m, and
/// with friction also the tangent t, both held by the augmentation r N'WN + r T'WT)
/// removes the rigid motions u(y) = (a_x - w y_2, a_y + w y_1) for which d . u(x) = 0, a
/// row [d_x, d_y, x × d] whose third entry is the moment arm of the line through x
/// along d. Lines remove all three rigid motions exactly when they are neither all
/// parallel nor all through one point: parallel lines leave the translation across them
/// free, concurrent lines the rotation about their common point, a single line both. So
/// the test is structural: it sorts the lines into directions and, per direction, into
/// distinct lines; it never ranks a matrix against a pivot threshold. How many conditions
/// lie on one line does not matter. Lines count as one when they agree to [`SAME_LINE`]
/// of the mesh size.
///
/// Frictionless contact holds the body along m only (by the augmentation of the linear
/// step; physically only when the load presses the body onto the foundation), so it
/// always leaves the sliding along t to the Dirichlet conditions.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Holds {
    tol: f64,
    classes: Vec<Class>,
}

/// The lines of one direction: the first one, and whether another, distinct one exists.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
struct Class {
    dir: [f64; 2],
    point: [f64; 2],
    two_lines: bool,
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

impl Holds {
    /// `tol` is the length under which two parallel lines are one, e.g. `SAME_LINE * size`.
    pub fn new(tol: f64) -> Self {
        Holds {
            tol,
            classes: Vec::new(),
        }
    }

    /// Adds the condition "the displacement of `at` along `dir` is fixed" (`dir` non-zero).
    pub fn add(&mut self, at: [f64; 2], dir: [f64; 2]) {
        let norm = dir[0].hypot(dir[1]);
        let dir = [dir[0] / norm, dir[1] / norm];
        match self
            .classes
            .iter_mut()
            .find(|c| cross(c.dir, dir).abs() <= PARALLEL)
        {
            Some(c) => {
                if !c.two_lines {
                    let offset = cross([at[0] - c.point[0], at[1] - c.point[1]], c.dir);
                    c.two_lines = offset.abs() > self.tol;
                }
            }
            None => self.classes.push(Class {
                dir,
                point: at,
                two_lines: false,
            }),
        }
    }

    /// The rigid motion left free, or `None` when the part is held.
    pub fn free(&self) -> Option<Free> {
        match self.classes.as_slice() {
            [] => Some(Free::Everything),
            [c] if c.two_lines => Some(Free::Slide {
                along: [-c.dir[1], c.dir[0]],
            }),
            [c] => Some(Free::SlideAndTurn {
                point: c.point,
                dir: c.dir,
            }),
            all if all.iter().any(|c| c.two_lines) => None,
            [a, b, rest @ ..] => {
                // a.point + s a.dir on the line of b (a and b are not parallel).
                let s = cross([b.point[0] - a.point[0], b.point[1] - a.point[1]], b.dir)
                    / cross(a.dir, b.dir);
                let centre = [a.point[0] + s * a.dir[0], a.point[1] + s * a.dir[1]];
                rest.iter()
                    .all(|c| {
                        cross([centre[0] - c.point[0], centre[1] - c.point[1]], c.dir).abs()
                            <= self.tol
                    })
                    .then_some(Free::Turn { centre })
            }
        }
    }
}

/// A contact node as a condition on the separate parts of a mesh ([`hold_parts`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactHold {
    /// The node's part.
    pub part: usize,
    /// The part of its master nodes; `None` against an obstacle.
    pub master: Option<usize>,
    pub at: [f64; 2],
    pub normal: [f64; 2],
    /// Whether it holds along its tangent too (friction).
    pub tangent: bool,
}

/// Adds the lines of action of contact nodes to `holds`, each part's conditions so far
/// (its Dirichlet conditions). A node against an obstacle holds its own part. A node of
/// a contact between two parts holds one of them once the other is held, along the same
/// lines: repeated until nothing changes, so that a chain of bodies resting on each
/// other is held from its held end, and two bodies that only hold each other are not.
/// Returns per part whether some node held it along a normal, along a tangent, and
/// through another part.
pub fn hold_parts(holds: &mut [Holds], nodes: &[ContactHold]) -> Vec<[bool; 3]> {
    let mut kinds = vec![[false; 3]; holds.len()];
    let mut hold = |holds: &mut [Holds], p: usize, c: &ContactHold| {
        holds[p].add(c.at, c.normal);
        kinds[p][0] = true;
        kinds[p][2] |= c.master.is_some();
        if c.tangent {
            holds[p].add(c.at, [c.normal[1], -c.normal[0]]);
            kinds[p][1] = true;
        }
    };
    for c in nodes.iter().filter(|c| c.master.is_none()) {
        hold(holds, c.part, c);
    }
    let mut done = vec![[false; 2]; nodes.len()];
    loop {
        // Whether each part is held, once per pass: a part's test costs its directions.
        let held: Vec<bool> = holds.iter().map(|h| h.free().is_none()).collect();
        let mut changed = false;
        for (k, c) in nodes.iter().enumerate() {
            let Some(m) = c.master else {
                continue;
            };
            for (side, (from, to)) in [(m, c.part), (c.part, m)].into_iter().enumerate() {
                if from != to && !done[k][side] && held[from] {
                    hold(holds, to, c);
                    done[k][side] = true;
                    changed = true;
                }
            }
        }
        if !changed {
            return kinds;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::builtin;

    fn check(mesh: &mut Mesh, name: &str) -> Result<HashSet<(usize, usize)>> {
        check_with(mesh, name, |_| ()).map(|(boundary, ())| boundary)
    }

    /// The unit square as a 2 x 2 grid of cells, two counter-clockwise triangles each;
    /// nodes row by row from (0, 0), node 4 (0-based) in the middle.
    fn square() -> Mesh {
        let mut nodes = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                nodes.push([0.5 * i as f64, 0.5 * j as f64]);
            }
        }
        let mut triangles = Vec::new();
        for j in 0..2 {
            for i in 0..2 {
                let a = 3 * j + i;
                triangles.push([a, a + 1, a + 4]);
                triangles.push([a, a + 4, a + 3]);
            }
        }
        let mut mesh = Mesh {
            nodes,
            triangles,
            ..Default::default()
        };
        mesh.line_groups
            .insert("bottom".into(), vec![[0, 1], [1, 2]]);
        mesh.point_groups.insert("corner".into(), vec![0]);
        mesh
    }

    fn error(mut mesh: Mesh) -> String {
        let msg = check(&mut mesh, "m.msh").unwrap_err().to_string();
        assert!(msg.starts_with("m.msh: ") && !msg.contains('\n'), "{msg}");
        msg
    }

    #[test]
    fn a_sound_mesh_passes_and_has_its_outline_as_boundary() {
        let mut mesh = square();
        let boundary = check(&mut mesh, "m.msh").unwrap();
        assert_eq!(boundary.len(), 8);
        assert!(boundary.contains(&(0, 1)) && !boundary.contains(&(0, 4)));
    }

    #[test]
    fn builtin_meshes_pass() {
        for level in 0..2 {
            let mut block = builtin::block_for_level(40.0, 10.0, level);
            check(&mut block, "block").unwrap();
            let mut disc = builtin::quarter_disc_for_level(50.0, level);
            check(&mut disc, "disc").unwrap();
        }
    }

    #[test]
    fn clockwise_listing_is_flipped_whether_all_or_some() {
        let mut all_cw = square();
        for t in &mut all_cw.triangles {
            t.swap(0, 1);
        }
        check(&mut all_cw, "m.msh").unwrap();
        assert!((0..all_cw.triangles.len()).all(|t| all_cw.signed_area2(t) > 0.0));
        // Two surfaces with opposite normals: sound, only listed differently.
        let mut mixed = square();
        mixed.triangles[3].swap(1, 2);
        mixed.triangles[6].swap(0, 2);
        check(&mut mixed, "m.msh").unwrap();
        assert!((0..mixed.triangles.len()).all(|t| mixed.signed_area2(t) > 0.0));
    }

    #[test]
    fn a_folded_mesh_names_the_inverted_triangle() {
        let mut mesh = square();
        // The middle node pushed past the right side: the triangles between it and the
        // right side turn over.
        mesh.nodes[4] = [1.25, 0.5];
        let msg = error(mesh);
        assert!(
            msg.contains("is inverted") && msg.contains("folds"),
            "{msg}"
        );
        // Triangle 3 is [1, 2, 5] (1-based) listed counter-clockwise in a square listed
        // so; the turned-over ones are the ones named.
        let mut mesh = square();
        mesh.nodes[4] = [1.25, 0.5];
        let mut oriented = mesh.clone();
        let listed_cw = orient(&mut oriented, "m.msh").unwrap();
        let named: usize = msg
            .split("triangle ")
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .and_then(|s| s.parse().ok())
            .unwrap();
        assert!(listed_cw[named - 1], "{msg}: {listed_cw:?}");
    }

    #[test]
    fn a_triangle_listed_twice_the_same_way_is_a_fold() {
        let mut mesh = square();
        mesh.triangles.push([0, 1, 4]);
        assert!(error(mesh).contains("triangle 9"));
    }

    #[test]
    fn degenerate_triangles_are_named() {
        let mut mesh = square();
        // On the line from node 2 (0.5, 0) to node 6 (1, 0.5).
        mesh.nodes[4] = [0.75, 0.25];
        let msg = error(mesh);
        assert!(msg.contains("degenerate"), "{msg}");
    }

    /// `f` on a pool of `threads` threads.
    fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }

    #[test]
    fn on_several_threads_the_first_bad_triangle_is_named() {
        // 103 201 nodes, 204 800 triangles: the rows of the edge scan fall in several runs
        // and the triangles in several blocks; a fault is planted early and late in both
        // orders, and the message must name the one a scan in file order meets first.
        let block = builtin::block_for_level(40.0, 10.0, 4);
        let nt = block.triangles.len();
        for threads in [1, 4] {
            let mut mesh = block.clone();
            let boundary = on_threads(threads, || check(&mut mesh, "m.msh")).unwrap();
            let mut serial = block.clone();
            let serial_boundary = on_threads(1, || check(&mut serial, "m.msh")).unwrap();
            assert_eq!(mesh.triangles, serial.triangles);
            assert_eq!(boundary, serial_boundary);
            assert_eq!(boundary.len(), 2 * (640 + 160));

            // Degenerate (a corner repeated): triangles 7 and nt - 3 (1-based).
            let mut mesh = block.clone();
            for t in [nt - 4, 6] {
                let [a, b, _] = mesh.triangles[t];
                mesh.triangles[t] = [a, b, a];
            }
            let msg = on_threads(threads, || error(mesh));
            assert!(
                msg.contains("triangle 7 ") && msg.contains("degenerate"),
                "{msg}"
            );

            // Folds: the last triangle listed again, then the first one. The scan goes by
            // node, so the fold at the first triangle's edges comes first.
            let mut mesh = block.clone();
            mesh.triangles.push(block.triangles[nt - 1]);
            mesh.triangles.push(block.triangles[0]);
            let msg = on_threads(threads, || error(mesh));
            assert!(
                msg.contains(&format!("triangle {} ", nt + 2))
                    && msg.contains("as triangle 1, so the mesh folds"),
                "{threads} threads: {msg}"
            );
        }
    }

    #[test]
    fn duplicate_nodes_name_both_points() {
        let mut mesh = square();
        mesh.nodes.push([0.5, 0.5 + 1e-13]);
        let t = mesh.triangles.len() - 1;
        mesh.triangles[t] = [3, 9, 6];
        let msg = error(mesh);
        assert!(
            msg.contains("nodes 5 at (0.5, 0.5) and 10 at (0.5, 0.5000000000001)"),
            "{msg}"
        );
        assert!(msg.contains("Coherence Mesh"), "{msg}");
        // Just above the tolerance they are two nodes (here an unused one).
        let mut mesh = square();
        mesh.nodes.push([0.5, 0.5 + 1e-11]);
        assert!(error(mesh).contains("belongs to no triangle"));
    }

    #[test]
    fn duplicates_are_found_across_column_boundaries() {
        // Nodes a hair apart in x sit in different columns of the sort.
        let mut mesh = square();
        let x = 0.5 + 0.6e-12;
        mesh.nodes.push([x, 0.0]);
        mesh.triangles.push([9, 2, 5]);
        let msg = error(mesh);
        assert!(msg.contains("nodes 2 at (0.5, 0) and 10"), "{msg}");
    }

    #[test]
    fn unused_nodes_are_counted_and_their_group_named() {
        let mut mesh = square();
        mesh.nodes.extend([[3.0, 3.0], [4.0, 4.0]]);
        mesh.point_groups.insert("pin".into(), vec![9]);
        let msg = error(mesh);
        assert!(
            msg.contains(
                "2 nodes, the first node 10 at (3, 3) (in group \"pin\"), belong to no triangle"
            ),
            "{msg}"
        );
        assert!(msg.contains("Mesh.SaveAll = 0"), "{msg}");
    }

    #[test]
    fn bad_references_are_errors_not_panics() {
        let mut mesh = square();
        mesh.triangles[0][2] = 99;
        assert!(error(mesh).contains("uses node 100"));
        let mut mesh = square();
        mesh.point_groups.insert("p".into(), vec![42]);
        assert!(error(mesh).contains("group \"p\""));
        let mut mesh = square();
        mesh.nodes[3][1] = f64::NAN;
        assert!(error(mesh).contains("not a finite point"));
        assert!(error(Mesh::default()).contains("no triangles"));
    }

    #[test]
    fn parts_are_joined_through_nodes() {
        let mut mesh = square();
        let (part, count) = parts(&mesh);
        assert_eq!((count, part.iter().all(|&p| p == 0)), (1, true));
        mesh.nodes.extend([[5.0, 0.0], [6.0, 0.0], [5.0, 1.0]]);
        mesh.triangles.push([9, 10, 11]);
        let (part, count) = parts(&mesh);
        assert_eq!(count, 2);
        assert_eq!(part[10], 1);
    }

    const X: [f64; 2] = [1.0, 0.0];
    const Y: [f64; 2] = [0.0, 1.0];

    fn free(holds: &[([f64; 2], [f64; 2])]) -> Option<Free> {
        let mut h = Holds::new(1e-9);
        for &(at, dir) in holds {
            h.add(at, dir);
        }
        h.free()
    }

    #[test]
    fn rigid_motions_follow_the_lines_of_action() {
        assert_eq!(free(&[]), Some(Free::Everything));
        // A clamped edge holds everything.
        assert_eq!(
            free(&[([0., 1.], X), ([0., 1.], Y), ([1., 1.], X), ([1., 1.], Y)]),
            None
        );
        // uy along a horizontal edge: vertical lines at two x, the x translation is free.
        assert_eq!(
            free(&[([0., 0.], Y), ([1., 0.], Y)]),
            Some(Free::Slide { along: [-1.0, 0.0] })
        );
        // Plus ux anywhere: held.
        assert_eq!(free(&[([0., 0.], Y), ([1., 0.], Y), ([5., 3.], X)]), None);
        // A pinned point: both lines through it, the rotation about it is free.
        assert_eq!(
            free(&[([2., 3.], X), ([2., 3.], Y)]),
            Some(Free::Turn { centre: [2.0, 3.0] })
        );
        // ux on a horizontal line and uy at a point: rotation about their crossing.
        assert_eq!(
            free(&[([0., 1.], X), ([4., 1.], X), ([2., 7.], Y)]),
            Some(Free::Turn { centre: [2.0, 1.0] })
        );
        // ux at one point only: one line.
        assert!(matches!(
            free(&[([1., 1.], X)]),
            Some(Free::SlideAndTurn { .. })
        ));
        // An oblique normal through the pin as well: still concurrent.
        let m = [0.6, 0.8];
        assert!(matches!(
            free(&[([2., 3.], X), ([2., 3.], Y), ([2. + 0.6, 3. + 0.8], m)]),
            Some(Free::Turn { .. })
        ));
        // An oblique normal elsewhere: held.
        assert_eq!(free(&[([2., 3.], X), ([2., 3.], Y), ([0., 0.], m)]), None);
        // Antiparallel directions are one direction.
        assert_eq!(
            free(&[([0., 0.], Y), ([1., 0.], [0.0, -1.0])]),
            Some(Free::Slide { along: [-1.0, 0.0] })
        );
    }

    #[test]
    fn round_off_is_no_lever_arm() {
        // ux on a "horizontal" line whose y wobbles by round-off, uy at one point: the
        // rotation is still free.
        let held = free(&[([0., 1.0], X), ([4., 1.0 + 1e-15], X), ([2., 7.], Y)]);
        assert!(matches!(held, Some(Free::Turn { .. })), "{held:?}");
    }

    #[test]
    fn contacts_hold_their_part_and_through_a_held_part_the_other() {
        let (x, y) = ([1.0, 0.0], [0.0, 1.0]);
        let node = |part, master, at| ContactHold {
            part,
            master,
            at,
            normal: y,
            tangent: false,
        };
        // Part 1 is clamped along two lines; part 0 rests on it by two mortar rows, and
        // part 2 on an obstacle by one node.
        let mut clamped = Holds::new(1e-9);
        clamped.add([0.0, 0.0], x);
        clamped.add([0.0, 0.0], y);
        clamped.add([1.0, 0.0], y);
        let mut holds = vec![Holds::new(1e-9), clamped, Holds::new(1e-9)];
        let rows = [
            node(0, Some(1), [0.0, 1.0]),
            node(0, Some(1), [1.0, 1.0]),
            node(2, None, [5.0, 0.0]),
        ];
        let kinds = hold_parts(&mut holds, &rows);
        assert_eq!(
            kinds,
            [[true, false, true], [false; 3], [true, false, false]]
        );
        // Frictionless rows hold part 0 along y only: it can slide along x.
        assert_eq!(holds[0].free(), Some(Free::Slide { along: [-1.0, 0.0] }));
        assert!(holds[1].free().is_none());
        assert!(matches!(holds[2].free(), Some(Free::SlideAndTurn { .. })));
        // Two parts that only hold each other are not held.
        let mut two = vec![Holds::new(1e-9), Holds::new(1e-9)];
        hold_parts(
            &mut two,
            &[node(0, Some(1), [0.0, 1.0]), node(0, Some(1), [1.0, 1.0])],
        );
        assert_eq!(two[0].free(), Some(Free::Everything));
        assert_eq!(two[1].free(), Some(Free::Everything));
    }
}
