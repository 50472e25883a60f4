//! The mesh: P1 triangles and named boundary groups, read from Gmsh or generated.

pub mod builtin;
pub mod gmsh;
pub mod renumber;
pub mod validate;

use std::collections::BTreeMap;

/// A 2D triangle mesh with named groups.
///
/// Node indices are 0-based and contiguous. Triangles are counter-clockwise once
/// [`validate::check_with`] has oriented them (see [`validate::orient`]). Groups keep the names of the Gmsh physical groups: line groups hold
/// 2-node edges (boundary conditions, contact), point groups hold single nodes (e.g. a
/// pinned point). Surface groups hold triangle indices: the bodies, each of which can
/// be given its own material.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub nodes: Vec<[f64; 2]>,
    pub triangles: Vec<[usize; 3]>,
    pub line_groups: BTreeMap<String, Vec<[usize; 2]>>,
    pub point_groups: BTreeMap<String, Vec<usize>>,
    /// Triangles (indices into `triangles`, increasing) of each physical surface group.
    pub surface_groups: BTreeMap<String, Vec<usize>>,
}

/// The set of `indices` (each below `n`) as bits, `n` of them: each piece of `indices`
/// marks a set of its own on the pool, and the sets are joined. A flag per index shared
/// by the threads moved its cache lines between the cores on every store; a set takes an
/// eighth of a byte per index and stays in the cache.
pub(crate) fn bit_set(n: usize, indices: &[usize]) -> Vec<u64> {
    use rayon::prelude::*;
    let words = n.div_ceil(64);
    (indices.par_chunks(1 << 15))
        .fold(
            || vec![0u64; words],
            |mut bits, piece| {
                for &i in piece {
                    bits[i / 64] |= 1 << (i % 64);
                }
                bits
            },
        )
        .reduce(
            || vec![0u64; words],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(a, b)| *a |= b);
                a
            },
        )
}

/// Whether `i` is in the set `bits` of [`bit_set`].
pub(crate) fn in_set(bits: &[u64], i: usize) -> bool {
    bits[i / 64] >> (i % 64) & 1 == 1
}

/// Twice the signed area of the triangle on `nodes` (positive when counter-clockwise).
pub fn signed_area2(nodes: &[[f64; 2]], [a, b, c]: [usize; 3]) -> f64 {
    let (pa, pb, pc) = (nodes[a], nodes[b], nodes[c]);
    (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pc[0] - pa[0]) * (pb[1] - pa[1])
}

impl Mesh {
    pub fn num_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Each triangle's centroid, on the pool's threads.
    pub fn centroids(&self) -> Vec<[f64; 2]> {
        use rayon::prelude::*;
        let xy = &self.nodes;
        self.triangles
            .par_iter()
            .map(|t| {
                let [a, b, c] = t.map(|n| xy[n]);
                [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0]
            })
            .collect()
    }

    /// Twice the signed area of triangle `t` (positive when counter-clockwise).
    pub fn signed_area2(&self, t: usize) -> f64 {
        signed_area2(&self.nodes, self.triangles[t])
    }

    /// The nodes of a group (line or point group), sorted and without repeats.
    pub fn group_nodes(&self, name: &str) -> Option<Vec<usize>> {
        let mut v: Vec<usize> = if let Some(lines) = self.line_groups.get(name) {
            lines.iter().flat_map(|e| e.iter().copied()).collect()
        } else {
            self.point_groups.get(name)?.clone()
        };
        v.sort_unstable();
        v.dedup();
        Some(v)
    }

    /// Every group name, lines first then points (for "did you mean" suggestions).
    pub fn group_names(&self) -> Vec<&str> {
        self.line_groups
            .keys()
            .chain(self.point_groups.keys())
            .map(String::as_str)
            .collect()
    }
}
