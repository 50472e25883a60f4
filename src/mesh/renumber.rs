//! A numbering of a mesh's nodes and triangles along a Hilbert curve, whatever the order
//! its file listed them in.
//!
//! Why: the set-up walks the mesh in its own numbering. The partitioner coarsens the
//! dual graph in triangle order (partition/src/coarsen.rs), the assembly scatters each
//! triangle into the rows of its nodes, the output gathers the nodes of each piece: with
//! neighbours numbered close together they touch memory almost sequentially; with a
//! numbering that has no locality (a mesher's, a converter's, a shuffled file) nearly
//! every access misses the caches. Sorting by a space-filling curve is what the
//! established FEM libraries do right after reading (deal.II, MFEM, PETSc's DMPlex
//! reorder by Hilbert or RCM); the Hilbert order costs one sort, needs no graph and
//! gives every contiguous range of nodes a compact piece of the mesh.

use super::Mesh;
use rayon::prelude::*;

/// Bits per axis of the Hilbert grid: a 2^32 x 2^32 grid over the bounding box, far
/// finer than any mesh this program can hold, so that distinct nodes rarely share a
/// cell (ties go to the file's order).
const ORDER: u8 = 32;

/// The Hilbert-curve index of each point on a 2^32 x 2^32 grid over `bbox` (lower
/// corner, upper corner).
pub fn hilbert_keys(points: &[[f64; 2]], bbox: [[f64; 2]; 2]) -> Vec<u64> {
    let [lo, hi] = bbox;
    let cells = f64::from(u32::MAX);
    let scale = [0, 1].map(|c| {
        let span = hi[c] - lo[c];
        if span > 0.0 {
            cells / span
        } else {
            0.0
        }
    });
    points
        .par_iter()
        .map(|p| {
            // `as` saturates, so round-off just past the box stays on the grid.
            let q = [0, 1].map(|c| ((p[c] - lo[c]) * scale[c]) as u32);
            fast_hilbert::xy2h(q[0], q[1], ORDER)
        })
        .collect()
}

/// The bounding box of `points` (lower corner, upper corner).
pub fn bounding_box(points: &[[f64; 2]]) -> [[f64; 2]; 2] {
    let (lo, hi) = crate::mesh::validate::bounding_box(points);
    [lo, hi]
}

/// The indices of `keys` sorted by key, equal keys by index: position -> index.
pub fn sorted_order(keys: &[u64]) -> Vec<usize> {
    // Sorting the pairs themselves, not indices into `keys`: each comparison then reads
    // memory in order (an index sort missed the caches on every one, 4x slower at 2M).
    let mut pairs: Vec<(u64, usize)> = keys.par_iter().copied().zip(0..keys.len()).collect();
    pairs.par_sort_unstable();
    pairs.into_par_iter().map(|(_, i)| i).collect()
}

/// The inverse of the permutation `order` (position -> index): index -> position.
pub fn inverse(order: &[usize]) -> Vec<usize> {
    use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
    if order.len() < 1 << 16 {
        let mut inv = vec![0; order.len()];
        for (pos, &i) in order.iter().enumerate() {
            inv[i] = pos;
        }
        return inv;
    }
    // On the pool's threads: a scatter of millions of entries, random writes each. Each
    // slot is written once (`order` is a permutation), so relaxed stores do.
    let inv: Vec<AtomicUsize> = (0..order.len())
        .into_par_iter()
        .map(|_| AtomicUsize::new(0))
        .collect();
    (order.par_iter().enumerate()).for_each(|(pos, &i)| inv[i].store(pos, Relaxed));
    inv.into_iter().map(AtomicUsize::into_inner).collect()
}

/// The order of `triangles` by their sorted node triples: by their smallest node, then
/// the next ones; only a triangle listed twice ties, and goes by its index. So the order
/// does not depend on the order the triangles come in. One parallel sort of packed
/// keys: faster than a counting sort on the smallest node (serial) or the Hilbert keys
/// of the centroids, and with 64-bit keys (up to 2^21 nodes) than with 128-bit ones.
pub fn order_by_nodes(triangles: &[[usize; 3]], num_nodes: usize) -> Vec<usize> {
    // The sorted triple packed into one key (nodes fit 42 bits: far beyond any mesh a
    // machine holds), sorted with the triangle's index on all threads.
    debug_assert!(num_nodes < 1 << 42);
    // Up to 2^21 nodes the triple packs into 64 bits, and the pairs (key, index) take
    // half the memory that the sort moves.
    if num_nodes <= 1 << 21 {
        sorted_by_key(triangles, |k| (k[0] << 42) | (k[1] << 21) | k[2])
    } else {
        sorted_by_key(triangles, |k| {
            let k = k.map(u128::from);
            (k[0] << 84) | (k[1] << 42) | k[2]
        })
    }
}

/// The order of `triangles` by `pack` of their sorted node triples, on all threads.
fn sorted_by_key<K: Ord + Send>(
    triangles: &[[usize; 3]],
    pack: impl Fn([u64; 3]) -> K + Sync,
) -> Vec<usize> {
    let mut keyed: Vec<(K, usize)> = triangles
        .par_iter()
        .enumerate()
        .map(|(i, t)| {
            let mut k = t.map(|v| v as u64);
            k.sort_unstable();
            (pack(k), i)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_par_iter().map(|(_, i)| i).collect()
}

/// The numbering [`by_hilbert_curve`] gives a mesh.
pub struct Renumbering {
    /// Each new node's index before (new -> old).
    pub old_of: Vec<usize>,
    /// Each old node's new index (old -> new).
    pub new_of: Vec<usize>,
    /// Each new triangle's index before (new -> old).
    pub tri_old_of: Vec<usize>,
}

/// `mesh` with its nodes in Hilbert order of their coordinates and its triangles in
/// the order of their nodes ([`order_by_nodes`]) (each keeps its vertices' cyclic order, so its
/// orientation), its groups renumbered with it. Returns the mesh and the renumbering.
pub fn by_hilbert_curve(mesh: Mesh) -> (Mesh, Renumbering) {
    let bbox = bounding_box(&mesh.nodes);
    let old_of = sorted_order(&hilbert_keys(&mesh.nodes, bbox));
    let new_of = inverse(&old_of);
    let nodes: Vec<[f64; 2]> = old_of.par_iter().map(|&o| mesh.nodes[o]).collect();
    let renamed: Vec<[usize; 3]> = mesh
        .triangles
        .par_iter()
        .map(|t| t.map(|v| new_of[v]))
        .collect();
    let tri_order = order_by_nodes(&renamed, nodes.len());
    let triangles = tri_order.par_iter().map(|&t| renamed[t]).collect();
    let new_tri = inverse(&tri_order);
    let surface_groups = mesh
        .surface_groups
        .into_iter()
        .map(|(name, tris)| (name, renamed_group(&tris, &new_tri, &tri_order)))
        .collect();
    let line_groups = mesh
        .line_groups
        .into_iter()
        .map(|(name, edges)| (name, edges.iter().map(|e| e.map(|v| new_of[v])).collect()))
        .collect();
    let point_groups = mesh
        .point_groups
        .into_iter()
        .map(|(name, pts)| (name, pts.iter().map(|&v| new_of[v]).collect()))
        .collect();
    let mesh = Mesh {
        nodes,
        triangles,
        line_groups,
        point_groups,
        surface_groups,
    };
    let numbering = Renumbering {
        old_of,
        new_of,
        tri_old_of: tri_order,
    };
    (mesh, numbering)
}

/// A group's triangles `tris` (old indices) by their new indices (`new_tri`: old -> new;
/// `tri_order`: new -> old), in increasing order. A large group (a body is often every
/// triangle) is read off the new order through a set of its members, where sorting its
/// new indices was the Hilbert order's longest step; a small one is sorted.
fn renamed_group(tris: &[usize], new_tri: &[usize], tri_order: &[usize]) -> Vec<usize> {
    let nt = tri_order.len();
    if tris.len() < nt / 8 {
        let mut t: Vec<usize> = tris.par_iter().map(|&t| new_tri[t]).collect();
        t.par_sort_unstable();
        // A triangle named twice (two physical groups of one name) once, as below.
        t.dedup();
        return t;
    }
    let member = crate::mesh::bit_set(nt, tris);
    (0..nt)
        .into_par_iter()
        .filter(|&t| crate::mesh::in_set(&member, tri_order[t]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::builtin;

    #[test]
    fn keys_follow_the_curve_through_the_four_quadrants() {
        // The order-1 Hilbert curve visits (0,0), (0,1), (1,1), (1,0).
        let p = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let k = hilbert_keys(&p, bounding_box(&p));
        assert_eq!(sorted_order(&k), [0, 3, 2, 1]);
    }

    #[test]
    fn a_point_on_the_box_and_a_degenerate_box_stay_on_the_grid() {
        let line = [[0.0, 2.0], [1.0, 2.0], [0.5, 2.0]];
        let k = hilbert_keys(&line, bounding_box(&line));
        assert_eq!(sorted_order(&k), [0, 2, 1]);
        let outside = hilbert_keys(&[[-1e-300, 1.0 + 1e-15]], [[0.0, 0.0], [1.0, 1.0]]);
        assert_eq!(outside.len(), 1);
    }

    #[test]
    fn a_large_inverse_on_several_threads_undoes_the_order() {
        let n = 300_007;
        let order: Vec<usize> = (0..n).map(|i| (i * 7919 + 11) % n).collect();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build();
        let inv = pool.unwrap().install(|| inverse(&order));
        assert_eq!(inv.len(), n);
        for (pos, &i) in order.iter().enumerate() {
            assert_eq!(inv[i], pos);
        }
    }

    #[test]
    fn ties_keep_the_given_order_and_inverse_undoes_the_order() {
        let order = sorted_order(&[5, 1, 5, 0]);
        assert_eq!(order, [3, 1, 0, 2]);
        let inv = inverse(&order);
        for (pos, &i) in order.iter().enumerate() {
            assert_eq!(inv[i], pos);
        }
    }

    #[test]
    fn triangles_are_ordered_by_their_nodes_whatever_their_order() {
        let tris = [[4, 2, 3], [0, 5, 1], [2, 3, 1], [1, 2, 0], [3, 2, 1]];
        let order = order_by_nodes(&tris, 6);
        assert_eq!(order, [3, 1, 2, 4, 0]);
        // The same order from the wide keys of more than 2^21 nodes.
        assert_eq!(order_by_nodes(&tris, (1 << 21) + 1), order);
        let far = [[1 << 21, 0, 5], [(1 << 21) - 1, 3, 2], [0, 1 << 21, 4]];
        assert_eq!(order_by_nodes(&far, (1 << 21) + 1), [2, 0, 1]);
        // Listed the other way round: the same triangles in the same order ([2, 3, 1]
        // and [3, 2, 1] are the same node set and stay in their given order).
        let rev: Vec<[usize; 3]> = tris.iter().rev().copied().collect();
        let back: Vec<[usize; 3]> = order_by_nodes(&rev, 6).iter().map(|&i| rev[i]).collect();
        let fwd: Vec<[usize; 3]> = order.iter().map(|&i| tris[i]).collect();
        assert_eq!(back[..2], fwd[..2]);
        assert_eq!(back[4], fwd[4]);
    }

    /// The same mesh in the new numbering: every triangle and group edge joins the same
    /// points, in the same cyclic order, and neighbours are close in the new order.
    #[test]
    fn renumbering_keeps_the_mesh_and_gives_locality() {
        let mesh = builtin::quarter_disc_for_level(50.0, 1);
        // A numbering with no locality: the nodes reversed and interleaved.
        let n = mesh.nodes.len();
        let scramble: Vec<usize> = (0..n).map(|i| (i * 7919) % n).collect();
        assert_eq!(inverse(&scramble).len(), n);
        let new_of = inverse(&scramble);
        let scrambled = Mesh {
            nodes: (0..n).map(|i| mesh.nodes[scramble[i]]).collect(),
            triangles: mesh
                .triangles
                .iter()
                .rev()
                .map(|t| t.map(|v| new_of[v]))
                .collect(),
            line_groups: mesh
                .line_groups
                .iter()
                .map(|(k, e)| (k.clone(), e.iter().map(|e| e.map(|v| new_of[v])).collect()))
                .collect(),
            point_groups: Default::default(),
            surface_groups: Default::default(),
        };
        // A body: the triangles left of x = 20 (in the scrambled, reversed order).
        let mut scrambled = scrambled;
        let left = |m: &Mesh, t: usize| m.triangles[t].iter().all(|&v| m.nodes[v][0] < 20.0);
        let body: Vec<usize> = (0..scrambled.triangles.len())
            .filter(|&t| left(&scrambled, t))
            .collect();
        assert!(!body.is_empty() && body.len() < scrambled.triangles.len());
        scrambled.surface_groups.insert("left".into(), body.clone());
        let (re, Renumbering { old_of, .. }) = by_hilbert_curve(scrambled.clone());
        let carried = &re.surface_groups["left"];
        assert_eq!(carried.len(), body.len());
        // A large group goes through a set of its members, a small one is sorted: the
        // same list either way, a triangle named twice once.
        assert!(8 * body.len() >= re.triangles.len() && 8 * 3 < re.triangles.len());
        let (_, Renumbering { tri_old_of, .. }) = by_hilbert_curve(scrambled.clone());
        let new_tri = inverse(&tri_old_of);
        let few = [body[3], body[0], body[3]];
        let mut expected: Vec<usize> = few.iter().map(|&t| new_tri[t]).collect();
        expected.sort_unstable();
        expected.dedup();
        assert_eq!(renamed_group(&few, &new_tri, &tri_old_of), expected);
        let mut twice = body.clone();
        twice.extend_from_slice(&body[..10]);
        assert_eq!(&renamed_group(&twice, &new_tri, &tri_old_of), carried);
        assert!(carried.windows(2).all(|w| w[0] < w[1]));
        assert!(carried.iter().all(|&t| left(&re, t)));
        assert_eq!(re.nodes.len(), n);
        for (i, &o) in old_of.iter().enumerate() {
            assert_eq!(re.nodes[i], scrambled.nodes[o]);
        }
        let as_points = |m: &Mesh| {
            let mut t: Vec<[[u64; 2]; 3]> = m
                .triangles
                .iter()
                .map(|t| {
                    let p = t.map(|v| m.nodes[v].map(f64::to_bits));
                    // Rotated to start at the smallest point: same cyclic order.
                    let k = (0..3).min_by_key(|&k| p[k]).unwrap();
                    [p[k], p[(k + 1) % 3], p[(k + 2) % 3]]
                })
                .collect();
            t.sort_unstable();
            t
        };
        assert_eq!(as_points(&re), as_points(&scrambled));
        let edges = |m: &Mesh| -> Vec<[[u64; 2]; 2]> {
            m.line_groups["contact"]
                .iter()
                .map(|e| e.map(|v| m.nodes[v].map(f64::to_bits)))
                .collect()
        };
        assert_eq!(edges(&re), edges(&scrambled));
        // Locality: the mean index distance across an edge of a triangle.
        let spread = |m: &Mesh| {
            let s: usize = m
                .triangles
                .iter()
                .map(|t| t[0].abs_diff(t[1]) + t[1].abs_diff(t[2]))
                .sum();
            s as f64 / m.triangles.len() as f64
        };
        assert!(
            spread(&scrambled) > 10.0 * spread(&re),
            "{} {}",
            spread(&scrambled),
            spread(&re)
        );
    }
}
