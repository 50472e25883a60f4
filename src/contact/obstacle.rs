//! Rigid obstacles and the contact geometry they give a node: its unit normal (obstacle
//! -> body), its initial gap and its position along the obstacle, from the closest point
//! of the obstacle in the reference configuration (small deformation: the geometry is
//! computed once and kept).
//!
//! Whatever supplies the geometry (a rigid obstacle here; later a master segment of
//! another body) hands the rest of the program the same [`NodeGeometry`], so the method
//! only ever sees a frame and a gap per node.

use serde::{Deserialize, Serialize};

/// Which side of a circle the body lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Side {
    /// The body outside the rigid disc (a cylinder resting on a rigid roller).
    Outside,
    /// The body inside the rigid hole (a pin in a hole).
    Inside,
}

/// A rigid obstacle in the plane.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Obstacle {
    /// The straight line through `point` with unit normal `normal` pointing into the body.
    Line { point: [f64; 2], normal: [f64; 2] },
    Circle {
        centre: [f64; 2],
        radius: f64,
        body: Side,
    },
    /// Segments between consecutive points, the body on their left walking from the
    /// first point to the last; the first and last segments run on as half-lines, so
    /// that a node beyond an end sees a straight obstacle (and a polyline of one segment
    /// is a line).
    Polyline { points: Vec<[f64; 2]> },
}

/// What contact with an obstacle needs to know of one node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeGeometry {
    /// Unit normal m, from the obstacle into the body; the tangent is (m_y, -m_x).
    pub normal: [f64; 2],
    /// Signed distance to the obstacle along m, negative when the node is through it.
    pub gap: f64,
    /// Position of the closest point along the obstacle (for pictures and sorting).
    pub s: f64,
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

impl Obstacle {
    /// The short name of its kind, as the case file spells it.
    pub fn kind(&self) -> &'static str {
        match self {
            Obstacle::Line { .. } => "line",
            Obstacle::Circle { .. } => "circle",
            Obstacle::Polyline { .. } => "polyline",
        }
    }

    /// The geometry of a node at `x` against this obstacle.
    pub fn geometry(&self, x: [f64; 2]) -> NodeGeometry {
        match self {
            Obstacle::Line { point, normal: m } => {
                // Kept to the letter of the single-line solver, so that old cases give
                // the same numbers bit for bit.
                let d = sub(x, *point);
                NodeGeometry {
                    normal: *m,
                    gap: d[0] * m[0] + d[1] * m[1],
                    s: d[0] * m[1] - d[1] * m[0],
                }
            }
            Obstacle::Circle {
                centre,
                radius,
                body,
            } => circle(*centre, *radius, *body, x),
            Obstacle::Polyline { points } => polyline(points, x),
        }
    }
}

fn circle(c: [f64; 2], radius: f64, body: Side, x: [f64; 2]) -> NodeGeometry {
    let d = sub(x, c);
    let dist = d[0].hypot(d[1]);
    // The centre itself has no closest point; any direction serves (such a node is deep
    // inside a hole or through the disc, and is refused or far from contact).
    let radial = if dist > 0.0 {
        [d[0] / dist, d[1] / dist]
    } else {
        [0.0, 1.0]
    };
    let (normal, gap) = match body {
        Side::Outside => (radial, dist - radius),
        Side::Inside => ([-radial[0], -radial[1]], radius - dist),
    };
    NodeGeometry {
        normal,
        gap,
        // Arc length, counter-clockwise from the positive x direction.
        s: radius * radial[1].atan2(radial[0]),
    }
}

impl Obstacle {
    /// For a circle, the positions along it of the contact nodes at `xs` (all of one
    /// contact): arc length along each node's tangent (m_y, -m_x), from the point of the
    /// circle that faces the middle of the nodes. [`NodeGeometry::s`] counts from the
    /// positive x direction and jumps by 2 pi R there, which a contact zone on the far
    /// side of a circle would straddle (its pictures and sorting broken). `None` for
    /// the other kinds, whose `s` is already continuous.
    pub fn arc_positions(&self, xs: &[[f64; 2]]) -> Option<Vec<f64>> {
        let Obstacle::Circle {
            centre,
            radius,
            body,
        } = self
        else {
            return None;
        };
        let angle = |x: [f64; 2]| (x[1] - centre[1]).atan2(x[0] - centre[0]);
        let (sy, sx) = xs.iter().fold((0.0, 0.0), |(sy, sx), &x| {
            let a = angle(x);
            (sy + a.sin(), sx + a.cos())
        });
        let middle = if sx == 0.0 && sy == 0.0 {
            0.0
        } else {
            sy.atan2(sx)
        };
        // The tangent turns clockwise round a disc (m outwards), counter-clockwise
        // round a hole (m inwards).
        let sense = match body {
            Side::Outside => -1.0,
            Side::Inside => 1.0,
        };
        let tau = std::f64::consts::TAU;
        Some(
            xs.iter()
                .map(|&x| {
                    let turn = (angle(x) - middle + tau / 2.0).rem_euclid(tau) - tau / 2.0;
                    sense * radius * turn
                })
                .collect(),
        )
    }
}

/// The left unit normal of the segment a -> b and its unit direction.
fn segment_frame(a: [f64; 2], b: [f64; 2]) -> ([f64; 2], [f64; 2], f64) {
    let d = sub(b, a);
    let len = d[0].hypot(d[1]);
    let u = [d[0] / len, d[1] / len];
    ([-u[1], u[0]], u, len)
}

fn polyline(points: &[[f64; 2]], x: [f64; 2]) -> NodeGeometry {
    let last = points.len() - 2;
    // (distance, segment, parameter along it, vertex the closest point sits on).
    let mut best: Option<(f64, usize, f64, Option<usize>)> = None;
    let mut start = 0.0;
    let mut starts = Vec::with_capacity(points.len() - 1);
    for k in 0..=last {
        let (a, b) = (points[k], points[k + 1]);
        let (_, u, len) = segment_frame(a, b);
        starts.push(start);
        let tau = dot(sub(x, a), u);
        // A node on a corner, up to round-off, belongs to the corner (its normal is the
        // corner's, not one face's by the chance of a rounding).
        let tol = 1e-12 * len;
        let (tau, vertex) = if tau < tol && k > 0 {
            (0.0, Some(k))
        } else if tau > len - tol && k < last {
            (len, Some(k + 1))
        } else {
            (tau, None)
        };
        let c = [a[0] + tau * u[0], a[1] + tau * u[1]];
        let dist = sub(x, c)[0].hypot(sub(x, c)[1]);
        if best.is_none_or(|(bd, ..)| dist < bd) {
            best = Some((dist, k, tau, vertex));
        }
        start += len;
    }
    let (dist, k, tau, vertex) = best.expect("a polyline has a segment");
    let s = starts[k] + tau;
    match vertex {
        None => {
            let (n, ..) = segment_frame(points[k], points[k + 1]);
            NodeGeometry {
                normal: n,
                gap: dot(sub(x, points[k]), n),
                s,
            }
        }
        Some(v) => {
            // At a corner the side is that of the mean of the two segments' normals (the
            // corner's pseudo-normal): the closest point is the corner itself, and the
            // normal runs from it to the node.
            let (n1, ..) = segment_frame(points[v - 1], points[v]);
            let (n2, ..) = segment_frame(points[v], points[v + 1]);
            let pn = [n1[0] + n2[0], n1[1] + n2[1]];
            let pn_len = pn[0].hypot(pn[1]);
            let d = sub(x, points[v]);
            let scale = sub(points[v], points[v - 1])[0]
                .hypot(sub(points[v], points[v - 1])[1])
                .min(sub(points[v + 1], points[v])[0].hypot(sub(points[v + 1], points[v])[1]));
            if dist > 1e-12 * scale {
                let sign = if dot(d, pn) >= 0.0 { 1.0 } else { -1.0 };
                NodeGeometry {
                    normal: [sign * d[0] / dist, sign * d[1] / dist],
                    gap: sign * dist,
                    s,
                }
            } else {
                let normal = [pn[0] / pn_len, pn[1] / pn_len];
                NodeGeometry {
                    normal,
                    gap: dot(d, normal),
                    s,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * (1.0 + a.abs().max(b.abs()))
    }

    #[test]
    fn line_gives_the_foundation_normal_gap_and_abscissa() {
        let g = Obstacle::Line {
            point: [1.0, -2.0],
            normal: [0.6, 0.8],
        }
        .geometry([4.0, 2.0]);
        assert_eq!(g.normal, [0.6, 0.8]);
        assert!(close(g.gap, 3.0 * 0.6 + 4.0 * 0.8));
        assert!(close(g.s, 3.0 * 0.8 - 4.0 * 0.6));
    }

    #[test]
    fn circle_outside_and_inside() {
        let out = Obstacle::Circle {
            centre: [0.0, -10.0],
            radius: 10.0,
            body: Side::Outside,
        };
        let g = out.geometry([0.0, 0.5]);
        assert_eq!(g.normal, [0.0, 1.0]);
        assert!(close(g.gap, 0.5));
        let g = out.geometry([6.0, -2.0]);
        assert!(close(g.gap, 0.0));
        assert!(close(g.normal[0], 0.6) && close(g.normal[1], 0.8));
        assert!(close(g.s, 10.0 * 0.8f64.atan2(0.6)));
        // Through the disc: a negative gap.
        assert!(out.geometry([0.0, -1.0]).gap < 0.0);

        let hole = Obstacle::Circle {
            centre: [0.0, 10.0],
            radius: 10.0,
            body: Side::Inside,
        };
        let g = hole.geometry([0.0, 0.5]);
        assert_eq!(g.normal, [0.0, 1.0]);
        assert!(close(g.gap, 0.5));
        let g = hole.geometry([6.0, 2.0]);
        assert!(close(g.gap, 0.0));
        assert!(close(g.normal[0], -0.6) && close(g.normal[1], 0.8));
        assert!(hole.geometry([0.0, -1.0]).gap < 0.0);
    }

    #[test]
    fn a_polyline_of_one_segment_is_its_line() {
        let (p0, m) = ([1.0, -2.0], [0.6, 0.8]);
        let line = Obstacle::Line {
            point: p0,
            normal: m,
        };
        let poly = Obstacle::Polyline {
            points: vec![p0, [p0[0] + 5.0 * m[1], p0[1] - 5.0 * m[0]]],
        };
        for x in [[4.0, 2.0], [-30.0, 7.0], [50.0, -1.0], [1.0, -2.0]] {
            let (a, b) = (line.geometry(x), poly.geometry(x));
            assert!(close(a.gap, b.gap), "{x:?}: {a:?} {b:?}");
            assert!(close(a.normal[0], b.normal[0]) && close(a.normal[1], b.normal[1]));
            assert!(close(a.s, b.s), "{x:?}: {a:?} {b:?}");
        }
    }

    #[test]
    fn polyline_corners_and_sides() {
        // A convex roof: up from (-1, 0) to (0, 1), down to (1, 0); the body above.
        let roof = Obstacle::Polyline {
            points: vec![[-1.0, 0.0], [0.0, 1.0], [1.0, 0.0]],
        };
        let h = 0.5f64.sqrt();
        // On a face: that face's normal.
        let g = roof.geometry([-0.5, 0.5 + 0.1]);
        assert!(close(g.normal[0], -h) && close(g.normal[1], h));
        assert!(close(g.gap, 0.1 * h));
        // Above the ridge: the ridge is the closest point, the normal points up to the node.
        let g = roof.geometry([0.0, 3.0]);
        assert!(close(g.gap, 2.0) && close(g.normal[1], 1.0));
        // On the ridge: the mean normal.
        let g = roof.geometry([0.0, 1.0]);
        assert!(close(g.gap, 0.0) && close(g.normal[0], 0.0) && close(g.normal[1], 1.0));
        assert!(close(g.s, 2.0f64.sqrt()));
        // Below a face: through the roof.
        assert!(roof.geometry([0.5, 0.2]).gap < 0.0);
        // A valley (concave): a node above its bottom sees both faces alike.
        let valley = Obstacle::Polyline {
            points: vec![[-1.0, 1.0], [0.0, 0.0], [1.0, 1.0]],
        };
        let g = valley.geometry([0.0, 0.5]);
        assert!(close(g.gap, 0.5 * h));
        // Below the valley's bottom: through it.
        let g = valley.geometry([0.0, -0.5]);
        assert!(close(g.gap, -0.5) && close(g.normal[1], 1.0));
        // Beyond an end the end segment runs on.
        let g = roof.geometry([-3.0, -2.0 + 0.1]);
        assert!(close(g.gap, 0.1 * h));
    }

    #[test]
    fn arc_positions_run_along_the_tangent_across_the_far_side() {
        // Nodes on the circle of radius 2 round (1, 1), on both sides of its -x point,
        // where the angle from +x jumps by 2 pi.
        let disc = Obstacle::Circle {
            centre: [1.0, 1.0],
            radius: 2.0,
            body: Side::Outside,
        };
        let angles: Vec<f64> = (-3..=3)
            .map(|k| std::f64::consts::PI + 0.1 * k as f64)
            .collect();
        let xs: Vec<[f64; 2]> = angles
            .iter()
            .map(|a| [1.0 + 2.0 * a.cos(), 1.0 + 2.0 * a.sin()])
            .collect();
        let s = disc.arc_positions(&xs).unwrap();
        for (k, (&sk, &x)) in s.iter().zip(&xs).enumerate() {
            // 0 at the middle node, 0.2 of arc per step, along the tangent (m_y, -m_x).
            assert!(
                (sk - (-0.2 * (k as f64 - 3.0))).abs() < 1e-12,
                "node {k}: s {sk}"
            );
            if k > 0 {
                let g = disc.geometry(x);
                let t = [g.normal[1], -g.normal[0]];
                let step = [x[0] - xs[k - 1][0], x[1] - xs[k - 1][1]];
                let along = step[0] * t[0] + step[1] * t[1];
                assert!(
                    (along > 0.0) == (sk > s[k - 1]),
                    "node {k}: s against the tangent"
                );
            }
        }
        let hole = Obstacle::Circle {
            centre: [1.0, 1.0],
            radius: 2.0,
            body: Side::Inside,
        };
        let h = hole.arc_positions(&xs).unwrap();
        assert!(h.iter().zip(&s).all(|(a, b)| (a + b).abs() < 1e-12));
        let line = Obstacle::Line {
            point: [0.0, 0.0],
            normal: [0.0, 1.0],
        };
        assert!(line.arc_positions(&xs).is_none());
    }
}
