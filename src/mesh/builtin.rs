//! Built-in meshes: a rectangular block and a graded quarter disc (the Hertz line-contact
//! test), plus quality helpers. Pure functions: no I/O, same input gives the same mesh.

use super::Mesh;
use std::f64::consts::{FRAC_PI_2, PI};

/// The surface group of every built-in mesh: one body, all its triangles.
pub const BODY_GROUP: &str = "body";
/// Cells over the height of [`block_for_level`] at level 0.
const BLOCK_NY0: usize = 10;
/// Cells across [`quarter_disc_for_level`] at level 0: 1244 nodes, and level 5 is the
/// first past a million.
const DISC_N0: usize = 24;
/// Grading of [`quarter_disc_for_level`]: the uniform tip then covers the arc up to about
/// 0.1 R (a Hertz half-width of 0.05-0.15 R sits in fine, smoothly graded cells), and at
/// level 2 the arc elements there are R/487, inside the R/400 contract.
const DISC_GRADING: f64 = 8.0;

/// Index of node `(i, j)` in an `(nx + 1) x (ny + 1)` structured grid, row by row.
#[derive(Clone, Copy)]
struct Grid {
    nx: usize,
    ny: usize,
}

impl Grid {
    fn id(self, i: usize, j: usize) -> usize {
        j * (self.nx + 1) + i
    }

    fn num_nodes(self) -> usize {
        (self.nx + 1) * (self.ny + 1)
    }

    /// Edges between consecutive nodes of a grid line, in the order of `ids`.
    fn path(self, ids: impl Iterator<Item = (usize, usize)>) -> Vec<[usize; 2]> {
        let ids: Vec<usize> = ids.map(|(i, j)| self.id(i, j)).collect();
        ids.windows(2).map(|w| [w[0], w[1]]).collect()
    }
}

/// The two counter-clockwise triangles of cell `(a, b, c, d)` (counter-clockwise from the
/// bottom left), split along `a-c` or along `b-d`.
fn split_quad(tris: &mut Vec<[usize; 3]>, [a, b, c, d]: [usize; 4], along_ac: bool) {
    if along_ac {
        tris.extend([[a, b, c], [a, c, d]]);
    } else {
        tris.extend([[a, b, d], [b, c, d]]);
    }
}

fn cell(grid: Grid, i: usize, j: usize) -> [usize; 4] {
    [
        grid.id(i, j),
        grid.id(i + 1, j),
        grid.id(i + 1, j + 1),
        grid.id(i, j + 1),
    ]
}

/// The rectangle `[0, width] x [0, height]` cut into `nx x ny` cells of two
/// counter-clockwise triangles each.
///
/// Diagonals rise to the right in the left half and fall in the right half, so the mesh
/// is the mirror image of itself about `x = width / 2` and symmetric loads give symmetric
/// discrete solutions. With odd `nx` the middle column cannot be mirrored; its diagonals
/// alternate row by row so that no direction is favoured.
///
/// Line groups `bottom`, `top` (left to right), `left`, `right` (bottom to top); point
/// groups `bottom_left`, `bottom_right`.
///
/// # Panics
/// If a size is not positive and finite or a cell count is zero.
pub fn block(width: f64, height: f64, nx: usize, ny: usize) -> Mesh {
    assert!(
        width > 0.0 && height > 0.0 && width.is_finite() && height.is_finite(),
        "block: width and height must be positive and finite, got {width} x {height}"
    );
    assert!(nx > 0 && ny > 0, "block: need at least one cell each way");
    let grid = Grid { nx, ny };
    let xs = mirrored_coords(width, nx);
    let ys: Vec<f64> = (0..=ny).map(|j| height * j as f64 / ny as f64).collect();
    let mut nodes = Vec::with_capacity(grid.num_nodes());
    for &y in &ys {
        nodes.extend(xs.iter().map(|&x| [x, y]));
    }
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            split_quad(&mut triangles, cell(grid, i, j), block_rises(i, j, nx));
        }
    }
    let mut mesh = Mesh {
        nodes,
        triangles,
        ..Mesh::default()
    };
    let lines = &mut mesh.line_groups;
    lines.insert("bottom".into(), grid.path((0..=nx).map(|i| (i, 0))));
    lines.insert("top".into(), grid.path((0..=nx).map(|i| (i, ny))));
    lines.insert("left".into(), grid.path((0..=ny).map(|j| (0, j))));
    lines.insert("right".into(), grid.path((0..=ny).map(|j| (nx, j))));
    let points = &mut mesh.point_groups;
    points.insert("bottom_left".into(), vec![grid.id(0, 0)]);
    points.insert("bottom_right".into(), vec![grid.id(nx, 0)]);
    let all = (0..mesh.triangles.len()).collect();
    mesh.surface_groups.insert(BODY_GROUP.into(), all);
    mesh
}

/// `n + 1` evenly spaced coordinates on `[0, length]`; the right half is computed as
/// `length - x` of the left half so that the mirror pairs agree to the last bit of `x`.
fn mirrored_coords(length: f64, n: usize) -> Vec<f64> {
    let mut xs: Vec<f64> = (0..=n).map(|i| length * i as f64 / n as f64).collect();
    for i in (n / 2 + 1)..=n {
        xs[i] = length - xs[n - i];
    }
    xs
}

/// Whether cell `(i, j)` of the block takes the rising diagonal (bottom left to top
/// right).
fn block_rises(i: usize, j: usize, nx: usize) -> bool {
    match (2 * i + 1).cmp(&nx) {
        std::cmp::Ordering::Less => true,
        std::cmp::Ordering::Greater => false,
        std::cmp::Ordering::Equal => j % 2 == 0,
    }
}

/// [`block`] at refinement `level`: `10 * 2^level` cells over the height and near-square
/// cells (an even count across, so that the mirror symmetry is exact).
pub fn block_for_level(width: f64, height: f64, level: u32) -> Mesh {
    let ny = BLOCK_NY0 << level;
    let half = (ny as f64 * width / height / 2.0).round().max(1.0) as usize;
    block(width, height, 2 * half, ny)
}

// The quarter disc is the image of the quarter of the unit disc {|w| <= 1, w_a >= 0,
// w_b >= 0} under the Moebius map z = 2iR v / (1 + v), v = w_a - i w_b. The centre w = 0
// goes to the origin (where contact starts), w_b = 0 to the axis, w_a = 0 to the contact
// arc and |w| = 1 to the top. The map is conformal, so a polar grid around w = 0 whose
// rings are spaced like its rays gives square cells in z that grow with the distance to
// the origin: grading without long thin elements. Polar grids cannot reach their centre,
// so the inner disc of radius rho (the "tip") is covered by three blocks instead: a
// square at the centre and two ring blocks around it.

/// Side of the tip's central square, as a fraction of the tip radius.
const TIP_SQUARE: f64 = 0.4;
/// Radial cells of the tip's ring blocks per angular cell of the polar grid: makes the
/// ring-block cells about as long as they are wide.
const TIP_RING_CELLS: f64 = 0.45;

/// Where a node lies, so that nodes on the boundary are put exactly on their side.
#[derive(Clone, Copy)]
enum On {
    Inside,
    Axis,
    Arc,
    /// On the top, at polar angle `theta` of the w-plane.
    Top(f64),
    /// A corner of the domain, given by its final coordinates.
    Corner([f64; 2]),
}

/// The point of the arc at angle `phi` from the origin, measured at the centre `(0, R)`.
fn arc_point(radius: f64, phi: f64) -> [f64; 2] {
    // 1 - cos(phi) written as 2 sin^2(phi / 2) keeps the height accurate near the origin.
    let h = (0.5 * phi).sin();
    [radius * phi.sin(), 2.0 * radius * h * h]
}

/// The image in the quarter disc of the w-plane point `[a, b]`.
fn to_z(radius: f64, [a, b]: [f64; 2], on: On) -> [f64; 2] {
    match on {
        On::Axis => [0.0, 2.0 * radius * a / (1.0 + a)],
        On::Arc => arc_point(radius, 2.0 * b.atan()),
        On::Top(theta) => [radius * (0.5 * theta).tan(), radius],
        On::Corner(z) => z,
        On::Inside => {
            let d = (1.0 + a) * (1.0 + a) + b * b;
            [2.0 * radius * b / d, 2.0 * radius * (a + a * a + b * b) / d]
        }
    }
}

/// Point `j` of `n + 1` on the w-plane circle of radius `r`, from the axis (`j = 0`) to
/// the arc (`j = n`), exact at both ends.
fn polar(r: f64, j: usize, n: usize) -> [f64; 2] {
    match j {
        0 => [r, 0.0],
        _ if j == n => [0.0, r],
        _ => {
            let theta = FRAC_PI_2 * j as f64 / n as f64;
            [r * theta.cos(), r * theta.sin()]
        }
    }
}

/// The side of node `j` of a polar ring (`top`: the outermost ring).
fn polar_side(radius: f64, top: bool, j: usize, n: usize) -> On {
    match (top, j) {
        (true, 0) => On::Corner([0.0, radius]),
        (true, _) if j == n => On::Corner([radius, radius]),
        (true, _) => On::Top(FRAC_PI_2 * j as f64 / n as f64),
        (false, 0) => On::Axis,
        (false, _) if j == n => On::Arc,
        (false, _) => On::Inside,
    }
}

/// A side of a block: node ids with their w-plane coordinates, in order.
#[derive(Clone)]
struct Curve {
    ids: Vec<usize>,
    w: Vec<[f64; 2]>,
}

impl Curve {
    fn cells(&self) -> usize {
        self.ids.len() - 1
    }

    fn end(&self, k: usize) -> (usize, [f64; 2]) {
        (self.ids[k], self.w[k])
    }

    fn slice(&self, from: usize, to: usize) -> Curve {
        Curve {
            ids: self.ids[from..=to].to_vec(),
            w: self.w[from..=to].to_vec(),
        }
    }

    fn reversed(mut self) -> Curve {
        self.ids.reverse();
        self.w.reverse();
        self
    }
}

/// Nodes and triangles of the quarter disc as they are built.
struct DiscBuilder {
    radius: f64,
    nodes: Vec<[f64; 2]>,
    triangles: Vec<[usize; 3]>,
}

impl DiscBuilder {
    fn add(&mut self, w: [f64; 2], on: On) -> usize {
        self.nodes.push(to_z(self.radius, w, on));
        self.nodes.len() - 1
    }

    /// A straight w-plane segment between two existing nodes, cut at `fractions` (from 0
    /// to 1) of its length; the new nodes lie `on` one side.
    fn segment(
        &mut self,
        from: (usize, [f64; 2]),
        to: (usize, [f64; 2]),
        fractions: &[f64],
        on: On,
    ) -> Curve {
        let mut curve = Curve {
            ids: vec![from.0],
            w: vec![from.1],
        };
        for &f in &fractions[1..fractions.len() - 1] {
            let w = lerp(from.1, to.1, f);
            curve.ids.push(self.add(w, on));
            curve.w.push(w);
        }
        curve.ids.push(to.0);
        curve.w.push(to.1);
        curve
    }

    /// Fills the block bounded by four curves (bottom and top run along the first grid
    /// direction, left and right along the second, and they share the four corners) by
    /// transfinite interpolation in the w-plane, and triangulates it.
    fn block(&mut self, bottom: &Curve, right: &Curve, top: &Curve, left: &Curve) {
        let (ns, nt) = (bottom.cells(), left.cells());
        debug_assert!(top.cells() == ns && right.cells() == nt);
        let corners = [bottom.w[0], bottom.w[ns], top.w[ns], top.w[0]];
        let mut ids = Vec::with_capacity((ns + 1) * (nt + 1));
        for j in 0..=nt {
            for i in 0..=ns {
                let id = match (i, j) {
                    (_, 0) => bottom.ids[i],
                    _ if j == nt => top.ids[i],
                    (0, _) => left.ids[j],
                    _ if i == ns => right.ids[j],
                    _ => {
                        let (s, t) = (i as f64 / ns as f64, j as f64 / nt as f64);
                        let across = lerp(bottom.w[i], top.w[i], t);
                        let along = lerp(left.w[j], right.w[j], s);
                        let [c00, c10, c11, c01] = corners;
                        let bilinear = lerp(lerp(c00, c10, s), lerp(c01, c11, s), t);
                        let w = [
                            across[0] + along[0] - bilinear[0],
                            across[1] + along[1] - bilinear[1],
                        ];
                        self.add(w, On::Inside)
                    }
                };
                ids.push(id);
            }
        }
        self.triangulate(&ids, ns, nt);
    }

    /// Two triangles per cell of a structured grid of node ids (`ns + 1` per row).
    fn triangulate(&mut self, ids: &[usize], ns: usize, nt: usize) {
        let row = ns + 1;
        self.triangles.reserve(2 * ns * nt);
        for j in 0..nt {
            for i in 0..ns {
                let k = j * row + i;
                let quad = ccw(
                    &self.nodes,
                    [ids[k], ids[k + 1], ids[k + row + 1], ids[k + row]],
                );
                let along_ac = split_along_ac(&self.nodes, quad);
                split_quad(&mut self.triangles, quad, along_ac);
            }
        }
    }

    /// The tip: the w-plane quarter disc inside `ring` (radius rho), as a central square
    /// of uniform cells and two ring blocks with `r` cells across. Returns the axis and arc
    /// curves from the origin to the ring.
    fn tip(&mut self, origin: usize, ring: &Curve, r: usize) -> (Curve, Curve) {
        let n = ring.cells();
        let jm = n / 2;
        let s = TIP_SQUARE * ring.w[0][0];
        let e1 = ([s, 0.0], On::Axis);
        let e3 = ([0.0, s], On::Arc);
        let m = ([s, s], On::Inside);
        let [e1, e3, m] = [e1, e3, m].map(|(w, on)| (self.add(w, on), w));
        let o = (origin, [0.0, 0.0]);
        let axis_in = self.segment(o, e1, &graded(n - jm, 1.0), On::Axis);
        let arc_in = self.segment(o, e3, &graded(jm, 1.0), On::Arc);
        let e1_m = self.segment(e1, m, &graded(jm, 1.0), On::Inside);
        let e3_m = self.segment(e3, m, &graded(n - jm, 1.0), On::Inside);
        // Across the ring blocks the cells grow from the size of the square's cells to
        // that of the first polar ring, so that the contact arc has no jump in size.
        let polar_step = ring.w[0][0] * (FRAC_PI_2 / n as f64).exp_m1();
        let across = graded(r, polar_step / (2.0 * s / n as f64));
        let axis_out = self.segment(e1, ring.end(0), &across, On::Axis);
        let arc_out = self.segment(e3, ring.end(n), &across, On::Arc);
        let m_e2 = self.segment(m, ring.end(jm), &across, On::Inside);
        let ring_c = ring.slice(jm, n).reversed();
        self.block(&axis_in, &e1_m, &e3_m, &arc_in);
        self.block(&axis_out, &ring.slice(0, jm), &m_e2, &e1_m);
        self.block(&e3_m, &m_e2, &ring_c, &arc_out);
        (join(&axis_in, &axis_out), join(&arc_in, &arc_out))
    }

    /// The polar grid outside the tip: rings at `radii` (the first is the tip's `ring`).
    /// Returns its axis, arc and top curves.
    fn polar_zone(&mut self, ring: &Curve, radii: &[f64]) -> (Curve, Curve, Curve) {
        let n = ring.cells();
        let m = radii.len() - 1;
        let mut ids = Vec::with_capacity((n + 1) * (m + 1));
        ids.extend_from_slice(&ring.ids);
        for (i, &r) in radii.iter().enumerate().skip(1) {
            for j in 0..=n {
                ids.push(self.add(polar(r, j, n), polar_side(self.radius, i == m, j, n)));
            }
        }
        self.triangulate(&ids, n, m);
        let column = |j: usize| Curve {
            ids: (0..=m).map(|i| ids[i * (n + 1) + j]).collect(),
            w: radii.iter().map(|&r| polar(r, j, n)).collect(),
        };
        let top = Curve {
            ids: ids[m * (n + 1)..].to_vec(),
            w: (0..=n).map(|j| polar(1.0, j, n)).collect(),
        };
        (column(0), column(n), top)
    }
}

/// `n + 1` increasing fractions from 0 to 1 whose spacing grows geometrically, the last
/// spacing `grading` times the first (`grading = 1`: uniform).
fn graded(n: usize, grading: f64) -> Vec<f64> {
    let log_q = if n > 1 {
        grading.ln() / (n - 1) as f64
    } else {
        0.0
    };
    // expm1 keeps the fractions accurate when the ratio per cell is close to 1.
    let total = (n as f64 * log_q).exp_m1();
    let mut f: Vec<f64> = (0..=n)
        .map(|i| {
            if log_q == 0.0 {
                i as f64 / n as f64
            } else {
                (i as f64 * log_q).exp_m1() / total
            }
        })
        .collect();
    f[n] = 1.0;
    f
}

/// Curve `a` followed by curve `b`, which starts where `a` ends.
fn join(a: &Curve, b: &Curve) -> Curve {
    let mut c = a.clone();
    c.ids.extend_from_slice(&b.ids[1..]);
    c.w.extend_from_slice(&b.w[1..]);
    c
}

/// Quad `[a, b, c, d]` in counter-clockwise order (the w-to-z map reverses orientation,
/// and the blocks are not all laid out the same way).
fn ccw(nodes: &[[f64; 2]], [a, b, c, d]: [usize; 4]) -> [usize; 4] {
    let p = [nodes[a], nodes[b], nodes[c], nodes[d]];
    let area2: f64 = (0..4).map(|k| cross(p[k], p[(k + 1) % 4])).sum();
    if area2 >= 0.0 {
        [a, b, c, d]
    } else {
        [a, d, c, b]
    }
}

/// Polar rings beyond the tip for `n` angular cells and arc grading `grading`.
fn rings_for(n: usize, grading: f64) -> usize {
    // The finest arc cells (in the tip's square) are about 4 R TIP_SQUARE rho / n long,
    // the coarsest (at (R, R)) about pi R / (2 n): their ratio fixes the tip radius rho.
    let rho = (PI / (8.0 * TIP_SQUARE * grading)).min(1.0);
    (-rho.ln() * 2.0 * n as f64 / PI).round() as usize
}

/// The quarter disc with `n` angular cells and `m` polar rings (see the top of this
/// section); the tip radius in the w-plane is exp(-m pi / (2 n)), so that the polar
/// cells are square.
fn disc(radius: f64, n: usize, m: usize) -> Mesh {
    assert!(
        radius > 0.0 && radius.is_finite(),
        "quarter_disc: radius must be positive and finite, got {radius}"
    );
    assert!(
        n >= 2,
        "quarter_disc: need at least 2 cells across, got {n}"
    );
    let step = FRAC_PI_2 / n as f64;
    let mut radii: Vec<f64> = (0..=m).map(|i| (-((m - i) as f64) * step).exp()).collect();
    radii[m] = 1.0;
    let r = ((TIP_RING_CELLS * n as f64).round() as usize).max(1);
    let polar_nodes = (n + 1) * m;
    let tip_nodes = (n + 1) * (r + 1) + (n / 2 + 1) * (n - n / 2 + 1);
    let mut b = DiscBuilder {
        radius,
        nodes: Vec::with_capacity(polar_nodes + tip_nodes),
        triangles: Vec::with_capacity(2 * n * (m + r) + n * n),
    };
    let origin = b.add([0.0, 0.0], On::Corner([0.0, 0.0]));
    let ring_ids = (0..=n)
        .map(|j| b.add(polar(radii[0], j, n), polar_side(radius, m == 0, j, n)))
        .collect();
    let ring = Curve {
        ids: ring_ids,
        w: (0..=n).map(|j| polar(radii[0], j, n)).collect(),
    };
    let (mut axis, mut arc) = b.tip(origin, &ring, r);
    let mut top = ring.clone();
    if m > 0 {
        let (axis_out, arc_out, top_out) = b.polar_zone(&ring, &radii);
        axis = join(&axis, &axis_out);
        arc = join(&arc, &arc_out);
        top = top_out;
    }
    let path = |c: &Curve| c.ids.windows(2).map(|w| [w[0], w[1]]).collect();
    let mut mesh = Mesh {
        nodes: b.nodes,
        triangles: b.triangles,
        ..Mesh::default()
    };
    mesh.line_groups.insert("axis".into(), path(&axis));
    mesh.line_groups.insert("top".into(), path(&top));
    mesh.line_groups.insert("contact".into(), path(&arc));
    mesh.point_groups.insert("origin".into(), vec![origin]);
    let all = (0..mesh.triangles.len()).collect();
    mesh.surface_groups.insert(BODY_GROUP.into(), all);
    mesh
}

/// The part of the disc of radius `radius` centred at `(0, radius)` with `x >= 0` and
/// `y <= radius`: it touches the line `y = 0` at the origin, where the elements are
/// smallest.
///
/// A conformal polar grid around the origin (square cells that grow with the distance)
/// with `n` cells across, i.e. along the top and around the origin, and a three-block tip
/// of near-uniform cells at the origin. `grading` (>= 1) is about the ratio of the largest
/// to the smallest element along the contact arc (grading 1 gives a near-uniform mesh,
/// whose ratio is still about 1.4); the uniform part of the tip covers the arc up to
/// about `0.8 R / grading` with elements of about `1.6 R / (grading n)`.
/// Every quad is cut along the diagonal that gives the larger smallest angle: the smallest
/// angle is about 40 degrees for `n >= 8`, above 29 degrees for `n = 4`.
/// About `(0.7 + 0.64 ln(grading)) n^2` nodes (2 n^2 at grading 8); node 0 is the origin.
///
/// Line groups: `axis` (x = 0, from the origin up), `top` (y = R, from `(0, R)` to
/// `(R, R)`), `contact` (the arc, from the origin to `(R, R)`; its nodes lie on the circle
/// to round-off). Point group `origin`.
///
/// # Panics
/// If `radius` is not positive and finite, `n < 2` or `grading` is below 1.
pub fn quarter_disc(radius: f64, n: usize, grading: f64) -> Mesh {
    assert!(
        grading >= 1.0 && grading.is_finite(),
        "quarter_disc: grading must be >= 1, got {grading}"
    );
    disc(radius, n, rings_for(n, grading))
}

/// [`quarter_disc`] at refinement `level`: `24 * 2^level` cells across with grading 8,
/// the ring count doubling with `n` so that each level halves every element. Level 0
/// has 1244 nodes, level 5 1.2 M, level 6 4.8 M; the arc elements near the origin are
/// `radius / (122 * 2^level)`, below `radius / 400` from level 2 on.
pub fn quarter_disc_for_level(radius: f64, level: u32) -> Mesh {
    disc(
        radius,
        DISC_N0 << level,
        rings_for(DISC_N0, DISC_GRADING) << level,
    )
}

/// Two elastic quarter cylinders touching at the origin, each meshed on its own
/// ([`quarter_disc_for_level`]): the upper one of radius `r1` centred at `(0, r1)` at
/// `level`, the lower one of radius `r2` centred at `(0, -r2)` one level finer (the
/// upper's mesh mirrored and scaled), so that with `r2` a little under `2 r1` the arc
/// elements at the contact are about as long on both sides (`r2 / 2 r1` of the upper's
/// below) and the nodes of the two arcs do not coincide (but at the origin).
///
/// Why about as long: the mortar coupling reads each master segment as a chord, whose
/// sag (h^2 / 8 R) enters the slave nodes' gaps; a master twice as coarse as the slave
/// makes the pressure alternate node by node by a few per cent (measured: 3.3% at
/// level 2), one as fine keeps it smooth (0.3%).
///
/// Surface groups `upper` and `lower`; line groups `upper_axis`, `upper_top`,
/// `upper_contact`, `lower_axis`, `lower_bottom`, `lower_contact`; point groups
/// `upper_origin`, `lower_origin`.
pub fn cylinders_for_level(r1: f64, r2: f64, level: u32) -> Mesh {
    let upper = quarter_disc_for_level(r1, level);
    let lower = quarter_disc_for_level(r2, level + 1);
    let offset = upper.nodes.len();
    let first_lower = upper.triangles.len();
    let mut mesh = Mesh {
        nodes: upper.nodes,
        triangles: upper.triangles,
        ..Mesh::default()
    };
    mesh.nodes.extend(lower.nodes.iter().map(|p| [p[0], -p[1]]));
    // Mirrored, so listed the other way round to stay counter-clockwise.
    mesh.triangles
        .extend((lower.triangles.iter()).map(|t| [t[0] + offset, t[2] + offset, t[1] + offset]));
    for (name, lines) in upper.line_groups {
        mesh.line_groups.insert(format!("upper_{name}"), lines);
    }
    for (name, lines) in lower.line_groups {
        let name = if name == "top" {
            "bottom".to_string()
        } else {
            name
        };
        let lines = lines
            .iter()
            .map(|l| [l[0] + offset, l[1] + offset])
            .collect();
        mesh.line_groups.insert(format!("lower_{name}"), lines);
    }
    for (name, points) in upper.point_groups {
        mesh.point_groups.insert(format!("upper_{name}"), points);
    }
    for (name, points) in lower.point_groups {
        let points = points.iter().map(|v| v + offset).collect();
        mesh.point_groups.insert(format!("lower_{name}"), points);
    }
    mesh.surface_groups
        .insert("upper".into(), (0..first_lower).collect());
    mesh.surface_groups.insert(
        "lower".into(),
        (first_lower..mesh.triangles.len()).collect(),
    );
    mesh
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn cross(u: [f64; 2], v: [f64; 2]) -> f64 {
    u[0] * v[1] - u[1] * v[0]
}

fn dot(u: [f64; 2], v: [f64; 2]) -> f64 {
    u[0] * v[0] + u[1] * v[1]
}

/// Whether quad `(a, b, c, d)` should be cut along `a-c`: the Delaunay choice, which for
/// a convex quad gives the larger smallest angle; a non-convex quad takes the only
/// diagonal that leaves both triangles counter-clockwise.
fn split_along_ac(nodes: &[[f64; 2]], [a, b, c, d]: [usize; 4]) -> bool {
    let [pa, pb, pc, pd] = [nodes[a], nodes[b], nodes[c], nodes[d]];
    // sin and cos (times the same positive lengths) of the angles at b and d.
    let sin_b = cross(sub(pc, pb), sub(pa, pb));
    let sin_d = cross(sub(pa, pd), sub(pc, pd));
    if sin_b <= 0.0 || sin_d <= 0.0 {
        return false;
    }
    let sin_a = cross(sub(pb, pa), sub(pd, pa));
    let sin_c = cross(sub(pd, pc), sub(pb, pc));
    if sin_a <= 0.0 || sin_c <= 0.0 {
        return true;
    }
    let cos_b = dot(sub(pc, pb), sub(pa, pb));
    let cos_d = dot(sub(pa, pd), sub(pc, pd));
    // a-c is Delaunay when the angles at b and d add up to at most 180 degrees.
    sin_b * cos_d + cos_b * sin_d >= 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::{HashMap, HashSet};

    /// Angles of triangle `t` in radians.
    fn angles(mesh: &Mesh, t: usize) -> [f64; 3] {
        let [a, b, c] = mesh.triangles[t].map(|k| mesh.nodes[k]);
        let at = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
            let (u, v) = (sub(q, p), sub(r, p));
            cross(u, v).abs().atan2(dot(u, v))
        };
        [at(a, b, c), at(b, c, a), at(c, a, b)]
    }

    /// The smallest angle of the mesh, in degrees (180 for a mesh without triangles).
    fn min_angle_deg(mesh: &Mesh) -> f64 {
        (0..mesh.triangles.len())
            .flat_map(|t| angles(mesh, t))
            .fold(std::f64::consts::PI, f64::min)
            .to_degrees()
    }

    /// The sum of the signed triangle areas (the domain area when all are counter-clockwise).
    fn total_area(mesh: &Mesh) -> f64 {
        0.5 * (0..mesh.triangles.len())
            .map(|t| mesh.signed_area2(t))
            .sum::<f64>()
    }

    fn dist(p: [f64; 2], q: [f64; 2]) -> f64 {
        (p[0] - q[0]).hypot(p[1] - q[1])
    }

    fn edge_len(mesh: &Mesh, [a, b]: [usize; 2]) -> f64 {
        dist(mesh.nodes[a], mesh.nodes[b])
    }

    fn assert_all_ccw(mesh: &Mesh) {
        let bad = (0..mesh.triangles.len())
            .filter(|&t| mesh.signed_area2(t) <= 0.0)
            .count();
        assert_eq!(bad, 0, "{bad} triangles are not counter-clockwise");
    }

    /// Every interior edge is shared by two triangles that run it in opposite directions
    /// (no hanging or duplicated nodes), and the boundary is exactly the union of the
    /// line groups.
    fn assert_conforming(mesh: &Mesh) {
        let n = mesh.num_nodes();
        let mut directed = HashSet::new();
        for tri in &mesh.triangles {
            assert!(tri.iter().all(|&k| k < n), "triangle {tri:?} out of range");
            for k in 0..3 {
                let e = (tri[k], tri[(k + 1) % 3]);
                assert!(directed.insert(e), "edge {e:?} used twice in one direction");
            }
        }
        let mut boundary: Vec<[usize; 2]> = directed
            .iter()
            .filter(|&&(a, b)| !directed.contains(&(b, a)))
            .map(|&(a, b)| [a.min(b), a.max(b)])
            .collect();
        let mut groups: Vec<[usize; 2]> = mesh
            .line_groups
            .values()
            .flatten()
            .map(|&[a, b]| [a.min(b), a.max(b)])
            .collect();
        boundary.sort_unstable();
        groups.sort_unstable();
        assert_eq!(boundary, groups, "boundary edges and line groups differ");
        let used: HashSet<usize> = mesh.triangles.iter().flatten().copied().collect();
        assert_eq!(used.len(), n, "some nodes belong to no triangle");
        // Euler's formula for a triangulated disc (no holes, nothing detached).
        let edges = (directed.len() + boundary.len()) / 2;
        assert_eq!(n + mesh.triangles.len(), edges + 1, "not a disc");
    }

    /// The group's edges chain head to tail; returns its nodes in order.
    fn chain(mesh: &Mesh, name: &str) -> Vec<usize> {
        let edges = &mesh.line_groups[name];
        for w in edges.windows(2) {
            assert_eq!(w[0][1], w[1][0], "group {name} is not a chain");
        }
        let mut nodes = vec![edges[0][0]];
        nodes.extend(edges.iter().map(|e| e[1]));
        nodes
    }

    fn group_length(mesh: &Mesh, name: &str) -> f64 {
        mesh.line_groups[name]
            .iter()
            .map(|&e| edge_len(mesh, e))
            .sum()
    }

    #[test]
    fn helpers_on_single_triangles() {
        let mut mesh = Mesh {
            nodes: vec![[0.0, 0.0], [1.0, 0.0], [0.5, 3f64.sqrt() / 2.0], [0.0, 1.0]],
            triangles: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        assert!((min_angle_deg(&mesh) - 60.0).abs() < 1e-12);
        assert!((total_area(&mesh) - 3f64.sqrt() / 4.0).abs() < 1e-15);
        mesh.triangles = vec![[0, 3, 1]];
        assert!((min_angle_deg(&mesh) - 45.0).abs() < 1e-12);
        assert_eq!(
            total_area(&mesh),
            -0.5,
            "clockwise triangles count negative"
        );
    }

    #[test]
    fn block_counts_orientation_and_area() {
        for (nx, ny) in [(1, 1), (2, 1), (3, 2), (8, 5), (7, 3)] {
            let mesh = block(4.0, 1.5, nx, ny);
            assert_eq!(mesh.num_nodes(), (nx + 1) * (ny + 1));
            assert_eq!(mesh.triangles.len(), 2 * nx * ny);
            assert_all_ccw(&mesh);
            assert_conforming(&mesh);
            assert!((total_area(&mesh) - 6.0).abs() < 1e-12);
        }
    }

    #[test]
    fn block_groups_cover_their_sides_in_order() {
        let (w, h, nx, ny) = (3.0, 2.0, 6, 4);
        let mesh = block(w, h, nx, ny);
        // (name, edge count, start, end, length)
        let sides = [
            ("bottom", nx, [0.0, 0.0], [w, 0.0], w),
            ("top", nx, [0.0, h], [w, h], w),
            ("left", ny, [0.0, 0.0], [0.0, h], h),
            ("right", ny, [w, 0.0], [w, h], h),
        ];
        for (name, count, start, end, length) in sides {
            let nodes = chain(&mesh, name);
            assert_eq!(nodes.len(), count + 1, "{name}");
            assert_eq!(mesh.nodes[nodes[0]], start, "{name} start");
            assert_eq!(mesh.nodes[*nodes.last().unwrap()], end, "{name} end");
            // On the side: the coordinate that is fixed along it does not move.
            let fixed = if start[0] == end[0] { 0 } else { 1 };
            assert!(nodes.iter().all(|&k| mesh.nodes[k][fixed] == start[fixed]));
            assert!((group_length(&mesh, name) - length).abs() < 1e-12, "{name}");
        }
        assert_eq!(mesh.nodes[mesh.point_groups["bottom_left"][0]], [0.0, 0.0]);
        assert_eq!(mesh.nodes[mesh.point_groups["bottom_right"][0]], [w, 0.0]);
        assert!(min_angle_deg(&mesh) > 30.0);
    }

    /// The mirror image of every node is a node and that of every triangle a triangle.
    fn assert_mirror_symmetric(mesh: &Mesh, width: f64) {
        let key = |p: [f64; 2]| ((p[0] * 1e9).round() as i64, (p[1] * 1e9).round() as i64);
        let index: HashMap<_, usize> = mesh
            .nodes
            .iter()
            .enumerate()
            .map(|(k, &p)| (key(p), k))
            .collect();
        let mirror: Vec<usize> = mesh
            .nodes
            .iter()
            .map(|&[x, y]| index[&key([width - x, y])])
            .collect();
        let sorted = |t: [usize; 3]| {
            let mut t = t;
            t.sort_unstable();
            t
        };
        let tris: HashSet<[usize; 3]> = mesh.triangles.iter().map(|&t| sorted(t)).collect();
        for &t in &mesh.triangles {
            assert!(
                tris.contains(&sorted(t.map(|k| mirror[k]))),
                "{t:?} has no mirror"
            );
        }
    }

    #[test]
    fn block_is_mirror_symmetric_about_its_middle() {
        for (nx, ny) in [(2, 1), (6, 3), (40, 10)] {
            assert_mirror_symmetric(&block(4.0, 1.0, nx, ny), 4.0);
        }
        assert_mirror_symmetric(&block_for_level(2.7, 1.3, 1), 2.7);
    }

    #[test]
    fn block_levels_double_the_cells_each_way() {
        let coarse = block_for_level(4.0, 1.0, 0);
        assert_eq!(coarse.line_groups["left"].len(), 10);
        assert_eq!(coarse.line_groups["bottom"].len(), 40);
        let fine = block_for_level(4.0, 1.0, 3);
        assert_eq!(fine.line_groups["left"].len(), 80);
        assert_eq!(fine.line_groups["bottom"].len(), 320);
        // Odd width-to-height ratios still give an even count across.
        assert_eq!(block_for_level(1.3, 1.0, 0).line_groups["bottom"].len(), 14);
    }

    #[test]
    fn block_level_6_passes_a_million_nodes() {
        let mesh = block_for_level(4.0, 1.0, 6);
        assert_eq!(mesh.num_nodes(), 2561 * 641);
        assert!(mesh.num_nodes() >= 1_000_000);
    }

    #[test]
    #[should_panic(expected = "at least one cell")]
    fn block_rejects_zero_cells() {
        block(1.0, 1.0, 0, 3);
    }

    const GRADINGS: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];

    #[test]
    fn quarter_disc_is_a_valid_conforming_mesh() {
        for n in [2, 3, 4, 5, 8, 17, 64] {
            for grading in GRADINGS {
                let mesh = quarter_disc(1.0, n, grading);
                assert_all_ccw(&mesh);
                assert_conforming(&mesh);
                assert_eq!(mesh.nodes[0], [0.0, 0.0]);
                assert_eq!(mesh.point_groups["origin"], vec![0]);
            }
        }
    }

    #[test]
    fn quarter_disc_angles_stay_large() {
        for grading in GRADINGS {
            for n in [2, 3, 5, 7] {
                let angle = min_angle_deg(&quarter_disc(1.0, n, grading));
                assert!(angle > 18.0, "n = {n}, grading {grading}: {angle}");
            }
            for n in [4, 6] {
                let angle = min_angle_deg(&quarter_disc(1.0, n, grading));
                assert!(angle > 28.0, "n = {n}, grading {grading}: {angle}");
            }
            for n in [8, 16, 64, 256] {
                let angle = min_angle_deg(&quarter_disc(1.0, n, grading));
                assert!(angle > 35.0, "n = {n}, grading {grading}: {angle}");
            }
        }
        let angle = min_angle_deg(&quarter_disc(1.0, 128, 100.0));
        assert!(angle > 35.0, "steep grading: {angle}");
    }

    /// 8 M nodes and 0.5 GB: run with `cargo test --release -- --ignored`.
    #[test]
    #[ignore]
    fn quarter_disc_angles_stay_large_at_n_2000() {
        let mesh = quarter_disc(1.0, 2000, 8.0);
        assert_all_ccw(&mesh);
        let angle = min_angle_deg(&mesh);
        assert!(angle > 35.0, "{angle}");
    }

    #[test]
    fn quarter_disc_boundary_nodes_lie_exactly_on_their_sides() {
        let r = 2.5;
        let mesh = quarter_disc(r, 40, 8.0);
        let arc = chain(&mesh, "contact");
        for &k in &arc {
            let off = dist(mesh.nodes[k], [0.0, r]) - r;
            assert!(off.abs() < 1e-12 * r, "node {k} is {off} off the circle");
        }
        assert!(chain(&mesh, "axis")
            .iter()
            .all(|&k| mesh.nodes[k][0] == 0.0));
        assert!(chain(&mesh, "top").iter().all(|&k| mesh.nodes[k][1] == r));
        let xs: Vec<f64> = chain(&mesh, "top")
            .iter()
            .map(|&k| mesh.nodes[k][0])
            .collect();
        assert!(xs.windows(2).all(|w| w[0] < w[1]), "top runs left to right");
        let ys: Vec<f64> = chain(&mesh, "axis")
            .iter()
            .map(|&k| mesh.nodes[k][1])
            .collect();
        assert!(ys.windows(2).all(|w| w[0] < w[1]), "axis runs upwards");
    }

    #[test]
    fn quarter_disc_groups_run_between_the_right_corners() {
        let r = 0.7;
        for mesh in [quarter_disc(r, 4, 1.0), quarter_disc(r, 24, 8.0)] {
            let ends = |name: &str| {
                let nodes = chain(&mesh, name);
                (mesh.nodes[nodes[0]], mesh.nodes[*nodes.last().unwrap()])
            };
            assert_eq!(ends("contact"), ([0.0, 0.0], [r, r]));
            assert_eq!(ends("axis"), ([0.0, 0.0], [0.0, r]));
            assert_eq!(ends("top"), ([0.0, r], [r, r]));
            // The arc is walked monotonically: the angle at the centre keeps growing.
            let angles: Vec<f64> = chain(&mesh, "contact")
                .iter()
                .map(|&k| mesh.nodes[k][0].atan2(r - mesh.nodes[k][1]))
                .collect();
            assert!(angles.windows(2).all(|w| w[0] < w[1]));
            assert!((group_length(&mesh, "axis") - r).abs() < 1e-12);
            assert!((group_length(&mesh, "top") - r).abs() < 1e-12);
        }
    }

    /// The exact area of the mesh: the quarter disc minus the circular segments cut off
    /// by the chords of the arc.
    fn polygon_area(mesh: &Mesh, r: f64) -> f64 {
        let segments: f64 = mesh.line_groups["contact"]
            .iter()
            .map(|&e| {
                let angle = 2.0 * (0.5 * edge_len(mesh, e) / r).asin();
                0.5 * r * r * (angle - angle.sin())
            })
            .sum();
        PI * r * r / 4.0 - segments
    }

    #[test]
    fn quarter_disc_area_converges_at_second_order() {
        let r = 1.5;
        let exact = PI * r * r / 4.0;
        let mut previous = f64::INFINITY;
        for n in [8, 16, 32, 64, 128] {
            let mesh = quarter_disc(r, n, 8.0);
            let area = total_area(&mesh);
            assert!((area - polygon_area(&mesh, r)).abs() < 1e-12 * exact);
            let error = exact - area;
            assert!(error > 0.0, "chords cut inside the circle");
            assert!(previous / error > 3.0, "n = {n}: {previous} -> {error}");
            previous = error;
        }
    }

    fn contact_edges_within(mesh: &Mesh, x: f64) -> Vec<f64> {
        mesh.line_groups["contact"]
            .iter()
            .filter(|e| mesh.nodes[e[1]][0] <= x)
            .map(|&e| edge_len(mesh, e))
            .collect()
    }

    #[test]
    fn quarter_disc_grading_is_the_arc_size_ratio() {
        for grading in [2.0, 4.0, 8.0, 16.0] {
            let mesh = quarter_disc(1.0, 64, grading);
            let sizes = contact_edges_within(&mesh, 1.0);
            let max = sizes.iter().copied().fold(0.0, f64::max);
            let min = sizes.iter().copied().fold(f64::INFINITY, f64::min);
            let ratio = max / min;
            assert!(
                (0.85 * grading..1.15 * grading).contains(&ratio),
                "grading {grading}: ratio {ratio}"
            );
            // No jumps along the arc: neighbours differ by less than 20 %.
            let jump = sizes
                .windows(2)
                .map(|w| (w[1] / w[0]).max(w[0] / w[1]))
                .fold(1.0, f64::max);
            assert!(jump < 1.2, "grading {grading}: jump {jump}");
        }
    }

    #[test]
    fn quarter_disc_levels_meet_the_contact_contract() {
        let r = 3.0;
        let mut previous_h = f64::INFINITY;
        for level in 0..=4 {
            let mesh = quarter_disc_for_level(r, level);
            let near = contact_edges_within(&mesh, 0.08 * r);
            let h = near.iter().copied().fold(0.0, f64::max);
            assert!(
                previous_h / h > 1.9,
                "level {level}: h {h} after {previous_h}"
            );
            if level >= 2 {
                assert!(h <= r / 400.0, "level {level}: h = R/{}", r / h);
                assert!(near.len() >= 30, "level {level}: {} edges", near.len());
            }
            previous_h = h;
        }
    }

    #[test]
    fn quarter_disc_level_sizes() {
        let nodes: Vec<usize> = (0..=4)
            .map(|level| quarter_disc_for_level(1.0, level).num_nodes())
            .collect();
        assert!((1000..=3000).contains(&nodes[0]), "level 0: {}", nodes[0]);
        for w in nodes.windows(2) {
            let ratio = w[1] as f64 / w[0] as f64;
            assert!((3.8..4.1).contains(&ratio), "{nodes:?}");
        }
        let level5 = quarter_disc_for_level(1.0, 5);
        assert!(level5.num_nodes() >= 1_000_000, "{}", level5.num_nodes());
    }

    #[test]
    #[should_panic(expected = "grading must be >= 1")]
    fn quarter_disc_rejects_grading_below_one() {
        quarter_disc(1.0, 8, 0.5);
    }

    #[test]
    #[should_panic(expected = "at least 2 cells")]
    fn quarter_disc_rejects_too_few_cells() {
        quarter_disc(1.0, 1, 2.0);
    }
}
