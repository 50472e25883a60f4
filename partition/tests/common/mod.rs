//! Mesh generators shared by the tests and the timing example.
#![allow(dead_code)]

/// A structured rectangle of `nx` x `ny` cells, each split into two triangles by the
/// same diagonal. Node `(i, j)` is `j * (nx + 1) + i`. Returns (number of nodes,
/// triangles, nodes of the bottom side, which stand in for a contact boundary).
pub fn rectangle(nx: usize, ny: usize) -> (usize, Vec<[usize; 3]>, Vec<usize>) {
    rectangle_with(nx, ny, |_, _| false)
}

/// As [`rectangle`], but cell `(i, j)` uses the other diagonal when `flip(i, j)`.
pub fn rectangle_with(
    nx: usize,
    ny: usize,
    flip: impl Fn(usize, usize) -> bool,
) -> (usize, Vec<[usize; 3]>, Vec<usize>) {
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut tris = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if flip(i, j) {
                tris.push([a, b, d]);
                tris.push([b, c, d]);
            } else {
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
    }
    let bottom = (0..=nx).map(|i| id(i, 0)).collect();
    ((nx + 1) * (ny + 1), tris, bottom)
}

/// A small irregular mesh: a rectangle with pseudo-randomly chosen diagonals, a
/// hexagonal fan glued to its right side, and an unused node at the end. The
/// contact nodes are the bottom side of the rectangle and the outer hexagon nodes.
pub fn irregular() -> (usize, Vec<[usize; 3]>, Vec<usize>) {
    let (nx, ny) = (9, 7);
    let mut state = 12345u32;
    let flips: Vec<bool> = (0..nx * ny)
        .map(|_| {
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
            state >> 16 & 1 == 1
        })
        .collect();
    let (n, mut tris, mut contact) = rectangle_with(nx, ny, |i, j| flips[j * nx + i]);
    // Fan: centre c and six outer nodes; two of them are rectangle nodes of the right
    // side, so the fan shares an edge with the rectangle.
    let right = |j: usize| j * (nx + 1) + nx;
    let c = n;
    let outer = [right(3), right(4), n + 1, n + 2, n + 3, n + 4];
    for k in 0..6 {
        tris.push([c, outer[k], outer[(k + 1) % 6]]);
    }
    contact.extend_from_slice(&outer[2..]);
    // n + 5 is left unused on purpose.
    (n + 6, tris, contact)
}

/// Two separate bodies, as in a two-body contact problem: the rectangle and a copy
/// of it shifted to new node ids. Contact nodes: the top of the lower body and the
/// bottom of the upper one.
pub fn two_bodies(nx: usize, ny: usize) -> (usize, Vec<[usize; 3]>, Vec<usize>) {
    let (n, tris, bottom) = rectangle(nx, ny);
    let mut all = tris.clone();
    all.extend(tris.iter().map(|t| [t[0] + n, t[1] + n, t[2] + n]));
    let top: Vec<usize> = (0..=nx).map(|i| ny * (nx + 1) + i).collect();
    let mut contact = top;
    contact.extend(bottom.iter().map(|&b| b + n));
    (2 * n, all, contact)
}
