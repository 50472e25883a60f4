//! Two-dimensional mortar coupling of a slave line with a master line of another body,
//! with dual (biorthogonal) multipliers: the geometry of each slave node's contact row
//! (pure: no mesh, no MPI).
//!
//! On a slave segment with linear shape functions phi_a, phi_b the dual functions are
//! psi_a = 2 phi_a - phi_b and psi_b = 2 phi_b - phi_a, so that the integral of psi_j
//! phi_k over the slave line is delta_jk D_j, D_j the node's lumped weight (half the
//! length of its slave segments). The weighted gap of node j,
//! D_j m_j . (x_j + u_j) - sum_k M_jk m_j . (x_k + u_k) with M_jk the integral of psi_j
//! times the master shape function N_k, divided by D_j, reads
//!
//!   g_j + m_j . (u_j - sum_k c_jk u_k),   c_jk = M_jk / D_j:
//!
//! one slave node and the few master nodes facing it. The non-penetration condition, the
//! friction law and their projections stay node-wise, the multiplier of node j is a
//! pressure p_j with force w_j p_j, and the augmentation r B'WB is a constant matrix.
//! Because the dual functions reproduce linear fields, a flat interface pressed by a
//! uniform load carries a uniform pressure wherever each slave node lands on its master
//! segment (the contact patch test), which node-to-segment pairing does not.
//!
//! A slave node whose support is only partly faced by the master line (at the end of
//! the master, or where the lines turn away from each other) is kept when the faced part
//! carries at least half of its weight; its row is then the phi_j-weighted mean of the
//! master over that part. Every row's coefficients sum to one (a rigid translation of
//! both bodies leaves every gap unchanged, and the master takes exactly the slave's
//! force); a node faced less is left out of the contact.

use std::collections::BTreeMap;

/// A boundary segment (nodes a, b) and the unit normal pointing out of its body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    pub nodes: [usize; 2],
    pub outward: [f64; 2],
}

/// The contact row of one slave node.
#[derive(Debug, Clone, PartialEq)]
pub struct MortarRow {
    /// The slave node.
    pub node: usize,
    /// D_j: half the length of its slave segments.
    pub w: f64,
    /// Unit normal m_j from the master into the slave body (minus the slave's mean
    /// outward normal).
    pub normal: [f64; 2],
    /// Initial gap g_j = m_j . (x_j - sum_k c_jk x_k).
    pub gap: f64,
    /// Master nodes and c_jk, summing to one, by increasing node.
    pub masters: Vec<(usize, f64)>,
}

/// Share of a node's dual weight the master line must face for the node to be kept.
pub const MIN_FACED: f64 = 0.5;

/// How far (in the master segment's parameter) a normal line may cross a master line
/// outside the segment it was paired with: round-off of the projections.
const ETA_SLACK: f64 = 1e-6;

/// Relative shortfall of the faced share below which a node counts as faced over its
/// whole support (round-off of the projections).
const FULLY_FACED: f64 = 1e-9;

/// A slave and a master segment pair only where their outward normals are opposed within
/// 60 degrees (cos = 0.5): beyond that the slave's normal meets the master line at a
/// grazing angle, far from where the bodies could touch under small deformation (the
/// sides of a disc resting on a block would otherwise be paired with the block's top,
/// their normals' rays crossing it behind them).
pub const FACING_COS: f64 = 0.5;

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// The rows of every slave node faced by the master line (by increasing node).
///
/// The slave line carries a continuous normal field, each node's mean normal
/// interpolated along its segments, and master points are paired with slave points along
/// it (as the established 2D mortar methods do): every master point is seen from exactly
/// one slave point, with no gap or overlap at a slave node where the slave line turns, so
/// that a curved interface keeps the weighted gaps of neighbouring nodes consistent. A
/// master segment counts where its outward normal opposes the slave segment's within
/// [`FACING_COS`] and it does not lie behind the slave segment. The
/// products psi_j N_k are integrated with four Gauss points on each overlap (exact on a
/// flat interface, where the pairing is affine).
pub fn mortar_rows(nodes: &[[f64; 2]], slave: &[Segment], master: &[Segment]) -> Vec<MortarRow> {
    let mut acc = supports(nodes, slave);
    let unit = |v: [f64; 2]| {
        let n = v[0].hypot(v[1]);
        [v[0] / n, v[1] / n]
    };
    let normals: BTreeMap<usize, [f64; 2]> =
        acc.iter().map(|(&v, a)| (v, unit(a.normal))).collect();
    for s in slave {
        let side = SlaveSide::new(nodes, s, &normals);
        for m in master {
            if dot(s.outward, m.outward) > -FACING_COS {
                continue;
            }
            if let Some(overlap) = side.overlap(nodes, m) {
                side.integrate(s, m, overlap, nodes, &mut acc);
            }
        }
    }
    (acc.into_iter())
        .filter_map(|(node, a)| a.row(node, normals[&node], nodes))
        .collect()
}

/// What a slave node's row gathers.
#[derive(Default)]
struct Acc {
    /// D_j, and the sum of minus its segments' outward normals times their lengths.
    d: f64,
    normal: [f64; 2],
    /// Integrals of psi_j N_k (the dual row) and of phi_j N_k (its faced share).
    m: BTreeMap<usize, f64>,
    m_phi: BTreeMap<usize, f64>,
}

/// Each slave node's weight and normal, with nothing integrated yet.
fn supports(nodes: &[[f64; 2]], slave: &[Segment]) -> BTreeMap<usize, Acc> {
    let mut acc: BTreeMap<usize, Acc> = BTreeMap::new();
    for s in slave {
        let len = dot(
            sub(nodes[s.nodes[1]], nodes[s.nodes[0]]),
            sub(nodes[s.nodes[1]], nodes[s.nodes[0]]),
        )
        .sqrt();
        for v in s.nodes {
            let n = acc.entry(v).or_default();
            n.d += 0.5 * len;
            n.normal[0] -= s.outward[0] * len;
            n.normal[1] -= s.outward[1] * len;
        }
    }
    acc
}

impl Acc {
    /// The row of slave node `node` (of unit normal `normal`), if faced enough.
    fn row(self, node: usize, normal: [f64; 2], nodes: &[[f64; 2]]) -> Option<MortarRow> {
        // The faced share of the node's support, phi_j weighted (in [0, 1]).
        let faced: f64 = self.m_phi.values().sum();
        if faced < MIN_FACED * self.d {
            return None;
        }
        // Faced over its whole support: the dual row. Over part of it (the end of the
        // master, or the edge of the facing cone): the dual functions integrated over
        // part of their support no longer average the master around the node (they take
        // negative values), so the row is the phi_j-weighted mean of the master over the
        // faced part: non-negative weights near the node.
        let whole = faced >= (1.0 - FULLY_FACED) * self.d;
        let m = if whole { self.m } else { self.m_phi };
        let sum: f64 = m.values().sum();
        let masters: Vec<(usize, f64)> = (m.into_iter())
            .filter(|&(_, m)| m != 0.0)
            .map(|(k, m)| (k, m / sum))
            .collect();
        let mut mean = [0.0; 2];
        for &(k, c) in &masters {
            mean[0] += c * nodes[k][0];
            mean[1] += c * nodes[k][1];
        }
        Some(MortarRow {
            node,
            w: self.d,
            normal,
            gap: dot(normal, sub(nodes[node], mean)),
            masters,
        })
    }
}

/// Gauss-Legendre points and weights on [0, 1].
fn gauss() -> [(f64, f64); 4] {
    let (g1, g2) = (0.5 * 0.861_136_311_594_052_6, 0.5 * 0.339_981_043_584_856_3);
    let (w1, w2) = (0.5 * 0.347_854_845_137_453_9, 0.5 * 0.652_145_154_862_546_1);
    [
        (0.5 - g1, w1),
        (0.5 - g2, w2),
        (0.5 + g2, w2),
        (0.5 + g1, w1),
    ]
}

/// A slave segment from x_a along e, with its normal field n_a + xi dn.
struct SlaveSide {
    xa: [f64; 2],
    e: [f64; 2],
    len: f64,
    na: [f64; 2],
    dn: [f64; 2],
}

impl SlaveSide {
    fn new(nodes: &[[f64; 2]], s: &Segment, normals: &BTreeMap<usize, [f64; 2]>) -> Self {
        let [a, b] = s.nodes;
        let (xa, xb) = (nodes[a], nodes[b]);
        let e = sub(xb, xa);
        let (na, nb) = (normals[&a], normals[&b]);
        SlaveSide {
            xa,
            e,
            len: dot(e, e).sqrt(),
            na,
            dn: sub(nb, na),
        }
    }

    /// The slave point and normal at xi.
    fn at(&self, xi: f64) -> ([f64; 2], [f64; 2]) {
        let (xa, e, na, dn) = (self.xa, self.e, self.na, self.dn);
        (
            [xa[0] + xi * e[0], xa[1] + xi * e[1]],
            [na[0] + xi * dn[0], na[1] + xi * dn[1]],
        )
    }

    /// The xi whose normal line passes through y: (x(xi) - y) x n(xi) = 0, a quadratic;
    /// the root nearest the segment.
    fn seen_from(&self, y: [f64; 2]) -> Option<f64> {
        let (e, na, dn) = (self.e, self.na, self.dn);
        let r = sub(self.xa, y);
        let (qa, qb, qc) = (cross(e, dn), cross(r, dn) + cross(e, na), cross(r, na));
        let roots: Vec<f64> = if qa.abs() <= 1e-14 * (qb.abs() + qc.abs()) {
            (qb != 0.0).then(|| -qc / qb).into_iter().collect()
        } else {
            let disc = qb * qb - 4.0 * qa * qc;
            if disc < 0.0 {
                return None;
            }
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            [q / qa, if q != 0.0 { qc / q } else { q / qa }].to_vec()
        };
        roots
            .into_iter()
            .min_by(|p, q| (p - 0.5).abs().total_cmp(&(q - 0.5).abs()))
    }

    /// The part (lo, hi) of this segment that master segment `m` faces along the normal
    /// field, if they pair.
    fn overlap(&self, nodes: &[[f64; 2]], m: &Segment) -> Option<(f64, f64)> {
        let (yc, yd) = (nodes[m.nodes[0]], nodes[m.nodes[1]]);
        let (xc, xd) = (self.seen_from(yc)?, self.seen_from(yd)?);
        let (lo, hi) = (xc.min(xd).max(0.0), xc.max(xd).min(1.0));
        if hi <= lo {
            return None;
        }
        let f = sub(yd, yc);
        // At every Gauss point the normal line must cross this master segment (the
        // overlap came from the normal field, which a far master point can only reach by
        // extrapolating it beyond the segment), and not behind the slave point by more
        // than a segment (a master line across the slave body).
        let reach = self.len.max(dot(f, f).sqrt());
        let paired = gauss().iter().all(|&(q, _)| {
            let (x, n) = self.at(lo + q * (hi - lo));
            let den = cross(f, n);
            if den == 0.0 {
                return false;
            }
            let eta = cross(sub(x, yc), n) / den;
            let y = [yc[0] + eta * f[0], yc[1] + eta * f[1]];
            (-ETA_SLACK..=1.0 + ETA_SLACK).contains(&eta)
                && dot(sub(x, y), n) / dot(n, n).sqrt() >= -reach
        });
        paired.then_some((lo, hi))
    }

    /// Adds psi_j N_k and phi_j N_k over the overlap (lo, hi) of slave segment `s` (this
    /// side) with master segment `m` to the rows of the slave nodes.
    fn integrate(
        &self,
        s: &Segment,
        m: &Segment,
        (lo, hi): (f64, f64),
        nodes: &[[f64; 2]],
        acc: &mut BTreeMap<usize, Acc>,
    ) {
        let [c, d] = m.nodes;
        let (yc, f) = (nodes[c], sub(nodes[d], nodes[c]));
        for (q, wq) in gauss() {
            let xi = lo + q * (hi - lo);
            let (x, n) = self.at(xi);
            // The master point on the normal line of x: yc + eta f (within the segment,
            // checked by `overlap`; clamped for round-off).
            let eta = (cross(sub(x, yc), n) / cross(f, n)).clamp(0.0, 1.0);
            let psi = [2.0 - 3.0 * xi, 3.0 * xi - 1.0];
            let phi = [1.0 - xi, xi];
            let shape = [1.0 - eta, eta];
            let weight = wq * (hi - lo) * self.len;
            for (j, vj) in s.nodes.into_iter().enumerate() {
                let row = acc.get_mut(&vj).expect("a slave node");
                for (k, &vk) in [c, d].iter().enumerate() {
                    *row.m.entry(vk).or_insert(0.0) += weight * psi[j] * shape[k];
                    *row.m_phi.entry(vk).or_insert(0.0) += weight * phi[j] * shape[k];
                }
            }
        }
    }
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A line y = y0 from x0 to x1 in `n` segments, nodes numbered from `first`; the
    /// body below (outward +y) or above (outward -y).
    fn line(nodes: &mut Vec<[f64; 2]>, xs: &[f64], y: f64, outward_up: bool) -> Vec<Segment> {
        let first = nodes.len();
        nodes.extend(xs.iter().map(|&x| [x, y]));
        let outward = if outward_up { [0.0, 1.0] } else { [0.0, -1.0] };
        (0..xs.len() - 1)
            .map(|i| Segment {
                nodes: [first + i, first + i + 1],
                outward,
            })
            .collect()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-13 * (1.0 + b.abs())
    }

    #[test]
    fn matching_lines_give_the_facing_node() {
        let mut nodes = Vec::new();
        let xs = [0.0, 0.5, 1.0, 1.5];
        let master = line(&mut nodes, &xs, 0.0, true);
        let slave = line(&mut nodes, &xs, 0.0, false);
        let rows = mortar_rows(&nodes, &slave, &master);
        assert_eq!(rows.len(), 4);
        for (i, r) in rows.iter().enumerate() {
            assert_eq!(r.node, 4 + i);
            assert_eq!(r.normal, [0.0, 1.0]);
            assert!(close(r.gap, 0.0), "{}", r.gap);
            let want = if i == 0 || i == 3 { 0.25 } else { 0.5 };
            assert!(close(r.w, want));
            for &(k, c) in &r.masters {
                let expect = if k == i { 1.0 } else { 0.0 };
                assert!(close(c, expect), "node {i}: c_{k} = {c}");
            }
        }
    }

    #[test]
    fn non_matching_lines_reproduce_linear_fields_and_the_gap() {
        // A master line of uneven segments, a slave line 0.01 above it inside its span.
        let mut nodes = Vec::new();
        let master = line(&mut nodes, &[-0.3, 0.13, 0.41, 0.77, 1.02, 1.4], 0.0, true);
        let slave = line(&mut nodes, &[0.0, 0.2, 0.45, 0.6, 0.9, 1.0], 0.01, false);
        let rows = mortar_rows(&nodes, &slave, &master);
        assert_eq!(rows.len(), 6);
        for r in &rows {
            let sum: f64 = r.masters.iter().map(|m| m.1).sum();
            assert!(close(sum, 1.0));
            assert!(close(r.gap, 0.01), "gap {}", r.gap);
            // A linear field u = a + b x on the master is read at the slave node.
            let field = |x: [f64; 2]| 0.3 - 2.0 * x[0];
            let read: f64 = r.masters.iter().map(|&(k, c)| c * field(nodes[k])).sum();
            assert!(close(read, field(nodes[r.node])), "{read}");
        }
    }

    #[test]
    fn a_slave_node_beyond_the_master_is_left_out() {
        let mut nodes = Vec::new();
        let master = line(&mut nodes, &[0.0, 1.0], 0.0, true);
        let slave = line(&mut nodes, &[0.5, 0.9, 1.5, 2.0], 0.0, false);
        let rows = mortar_rows(&nodes, &slave, &master);
        let kept: Vec<usize> = rows.iter().map(|r| r.node).collect();
        // The master faces all of the node at 0.5, 3/4 of the one at 0.9's dual weight,
        // under a third of the one at 1.5's, none of the one at 2.0's.
        assert_eq!(kept, [2, 3]);
        // Segments facing the same way (the far side of the master body) do not pair.
        let mut nodes = Vec::new();
        let master = line(&mut nodes, &[0.0, 1.0], 0.0, false);
        let slave = line(&mut nodes, &[0.0, 1.0], 0.1, false);
        assert!(mortar_rows(&nodes, &slave, &master).is_empty());
        // Nor a master line across the slave body, five segments behind it.
        let mut nodes = Vec::new();
        let master = line(&mut nodes, &[-1.0, 3.0], 5.0, true);
        let slave = line(&mut nodes, &[0.0, 1.0, 2.0], 0.0, false);
        assert!(mortar_rows(&nodes, &slave, &master).is_empty());
    }

    #[test]
    fn a_side_seen_at_a_grazing_angle_does_not_pair() {
        // The lower left side of a disc (outward normal 80 degrees from straight down)
        // above a flat master: its normal's ray would cross the master far away.
        let (c, s) = (80f64.to_radians().cos(), 80f64.to_radians().sin());
        let mut nodes = vec![[-20.0, 0.0], [20.0, 0.0]];
        let master = vec![Segment {
            nodes: [0, 1],
            outward: [0.0, 1.0],
        }];
        nodes.extend([[-10.0, 9.0], [-9.8, 8.0]]);
        let slave = vec![Segment {
            nodes: [2, 3],
            outward: [-s, -c],
        }];
        assert!(mortar_rows(&nodes, &slave, &master).is_empty());
    }

    #[test]
    fn a_curved_slave_gets_the_mean_normal() {
        // Two slave segments meeting at node 3 at a right angle above a flat master.
        let mut nodes = vec![[-2.0, 0.0], [2.0, 0.0]];
        let master = vec![Segment {
            nodes: [0, 1],
            outward: [0.0, 1.0],
        }];
        nodes.extend([[-1.0, 1.0], [0.0, 0.5], [1.0, 1.0]]);
        let s = 0.5f64.sqrt();
        let slave = vec![
            Segment {
                nodes: [2, 3],
                outward: [-s, -s],
            },
            Segment {
                nodes: [3, 4],
                outward: [s, -s],
            },
        ];
        let rows = mortar_rows(&nodes, &slave, &master);
        let mid = rows.iter().find(|r| r.node == 3).unwrap();
        assert!(close(mid.normal[0], 0.0) && close(mid.normal[1], 1.0));
    }
}
