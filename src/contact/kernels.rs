//! The node-wise steps 2 and 3 of ALG2 (docs/ALGORITHM.md): projection, shrinkage and the
//! multiplier updates. Pure functions of one contact node, no MPI, no I/O.
//!
//! Step 2 reads a multiplier and a displacement only through their state
//! s = Nu + lambda / r ([`state`]), so the kernels take that state: the loop keeps it as
//! its iterate, and step 3 written in it, lambda = r (s - p), is >= 0 exactly, where the
//! textbook lambda + r (Nu - p) often comes out a tiny negative on a free node (the two
//! agree to round-off: see the unit tests and tests/kernels_props.rs).

/// The state of one direction, s = value + multiplier / r: Nu + lambda / r (normal) or
/// Tu + mu / r (tangential), the argument of step 2.
#[inline]
pub fn state(value: f64, multiplier: f64, r: f64) -> f64 {
    value + multiplier / r
}

/// How far along the step from the normal states `x` to `y` (a fraction in (0, 1]) the
/// first node crosses its gap g, the boundary between open (s < g) and pressed (s > g):
/// the end of the piece on which the sweep map is the affine map seen at `x`. 1 when no
/// node crosses.
pub fn first_crossing(x: &[f64], y: &[f64], g: &[f64]) -> f64 {
    let mut t = 1.0f64;
    for ((&x, &y), &g) in x.iter().zip(y).zip(g) {
        let (a, b) = (x - g, y - g);
        if (a < 0.0) != (b < 0.0) {
            t = t.min(a / (a - b));
        }
    }
    t
}

/// Step 2, normal: the auxiliary variable p = min(g, s), the projection of the state onto
/// p <= g.
#[inline]
pub fn project_normal(g: f64, s: f64) -> f64 {
    g.min(s)
}

/// Step 2, tangential: soft thresholding of the state z = Tu + mu / r at s / r,
/// q = sign(z) max(|z| - s / r, 0). A non-zero q means the node slips.
#[inline]
pub fn shrink(z: f64, s_over_r: f64) -> f64 {
    let m = z.abs() - s_over_r;
    if m > 0.0 {
        m.copysign(z)
    } else {
        0.0
    }
}

/// Step 3: the multiplier update lambda + r (Nu - p), written in the state
/// s = Nu + lambda / r as r (s - p). With p from [`project_normal`] this is
/// r max(s - g, 0) >= 0; with q from [`shrink`], r z clamped to the friction interval.
#[inline]
pub fn update_multiplier(r: f64, state: f64, aux: f64) -> f64 {
    r * (state - aux)
}

/// Coulomb threshold s = coefficient * p_n, with the pressure clipped at zero so that a
/// round-off negative multiplier never yields a negative threshold.
#[inline]
pub fn coulomb_threshold(coefficient: f64, lambda: f64) -> f64 {
    coefficient * lambda.max(0.0)
}

/// Steps 2 and 3 of one normal direction: (p, lambda) from the state s.
#[inline]
pub fn normal_from_state(s: f64, g: f64, r: f64) -> (f64, f64) {
    let p = project_normal(g, s);
    (p, update_multiplier(r, s, p))
}

/// Steps 2 and 3 of one tangential direction: (q, mu) from the state z and the slip
/// threshold.
#[inline]
pub fn tangential_from_state(z: f64, threshold: f64, r: f64) -> (f64, f64) {
    let q = shrink(z, threshold / r);
    (q, update_multiplier(r, z, q))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_crossing_ends_the_piece() {
        let g = [1.0, 0.0, 2.0];
        // Node 0 reaches its gap a quarter of the way, node 1 leaves its half way.
        let (x, y) = ([0.0, 1.0, 0.0], [4.0, -1.0, 1.0]);
        assert_eq!(first_crossing(&x, &y, &g), 0.25);
        // The point at that fraction sits on node 0's gap; no node crosses before it.
        let at: Vec<f64> = (0..3).map(|i| x[i] + 0.25 * (y[i] - x[i])).collect();
        assert_eq!(at[0], g[0]);
        assert_eq!(first_crossing(&x, &at[..], &g), 1.0);
        // No crossing: the whole step.
        assert_eq!(first_crossing(&[0.0, 1.0], &[0.5, 3.0], &[1.0, 0.0]), 1.0);
    }

    #[test]
    fn projection_keeps_p_below_the_gap() {
        assert_eq!(project_normal(1.0, state(0.5, 0.0, 10.0)), 0.5);
        assert_eq!(project_normal(1.0, state(0.9, 5.0, 10.0)), 1.0);
        assert_eq!(project_normal(-0.5, state(0.0, 0.0, 1.0)), -0.5);
    }

    #[test]
    fn normal_update_equals_the_textbook_form() {
        // r (s - min(g, s)) == lambda + r (un - p) == max(0, lambda + r (un - g)).
        for &(g, un, lambda, r) in &[
            (0.1, 0.3, 2.0, 7.0),
            (0.1, -0.3, 2.0, 7.0),
            (0.0, 0.0, 0.0, 1.0),
            (1e-3, 2e-3, 1e4, 1e6),
        ] {
            let s = state(un, lambda, r);
            let p = project_normal(g, s);
            let a = update_multiplier(r, s, p);
            let textbook = lambda + r * (un - p);
            let b = (lambda + r * (un - g)).max(0.0);
            assert!(a >= 0.0);
            assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "{a} {b}");
            assert!(
                (a - textbook).abs() <= 1e-12 * b.abs().max(1.0),
                "{a} {textbook}"
            );
        }
    }

    #[test]
    fn shrinkage_is_soft_thresholding() {
        assert_eq!(shrink(3.0, 1.0), 2.0);
        assert_eq!(shrink(-3.0, 1.0), -2.0);
        assert_eq!(shrink(0.5, 1.0), 0.0);
        assert_eq!(shrink(-0.5, 1.0), 0.0);
        assert_eq!(shrink(2.0, 0.0), 2.0);
    }

    #[test]
    fn tangential_update_projects_onto_the_friction_disc() {
        // r (z - shrink(z, s/r)) == mu + r (ut - q) == clamp(mu + r ut, -s, s).
        for &(ut, mu, s, r) in &[
            (0.3, 1.0, 2.0, 10.0),
            (-0.3, 1.0, 2.0, 10.0),
            (0.01, 0.5, 2.0, 10.0),
        ] {
            let z = state(ut, mu, r);
            let q = shrink(z, s / r);
            let a = update_multiplier(r, z, q);
            let textbook = mu + r * (ut - q);
            let b = (mu + r * ut).clamp(-s, s);
            assert!((a - b).abs() < 1e-12, "{a} {b}");
            assert!((a - textbook).abs() < 1e-12, "{a} {textbook}");
        }
    }

    #[test]
    fn one_call_per_direction_is_steps_2_and_3() {
        for &(s, g, r) in &[(0.3, 0.1, 7.0), (-0.3, 0.1, 7.0), (0.1, 0.1, 3.0)] {
            let p = project_normal(g, s);
            assert_eq!(normal_from_state(s, g, r), (p, update_multiplier(r, s, p)));
        }
        for &(z, th, r) in &[(0.3, 2.0, 10.0), (-0.3, 2.0, 10.0), (0.01, 2.0, 10.0)] {
            let q = shrink(z, th / r);
            assert_eq!(
                tangential_from_state(z, th, r),
                (q, update_multiplier(r, z, q))
            );
        }
    }

    #[test]
    fn coulomb_threshold_never_negative() {
        assert_eq!(coulomb_threshold(0.3, -1e-12), 0.0);
        assert_eq!(coulomb_threshold(0.5, 4.0), 2.0);
    }
}
