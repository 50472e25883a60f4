//! The node-wise steps 2 and 3 of ALG2 (ALGORITHM.md): projection, shrinkage and the
//! multiplier updates. Pure functions of one contact node, no MPI, no I/O.

/// Normal auxiliary variable: p = min(g, un + lambda / r) (projection onto p <= g).
#[inline]
pub fn project_normal(g: f64, un: f64, lambda: f64, r: f64) -> f64 {
    g.min(un + lambda / r)
}

/// Tangential auxiliary variable by soft thresholding of z = ut + mu / r at s / r:
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

/// Multiplier update lambda += r (un - p). With p from [`project_normal`] this equals
/// max(0, lambda + r (un - g)), so lambda stays >= 0.
#[inline]
pub fn update_multiplier(multiplier: f64, r: f64, value: f64, aux: f64) -> f64 {
    multiplier + r * (value - aux)
}

/// Coulomb threshold s = coefficient * p_n, with the pressure clipped at zero so that a
/// round-off negative multiplier never yields a negative threshold.
#[inline]
pub fn coulomb_threshold(coefficient: f64, lambda: f64) -> f64 {
    coefficient * lambda.max(0.0)
}

/// Normal auxiliary variable and multiplier from the state s = Nu + lambda / r of the
/// previous sweep: p = min(g, s) (the projection) and lambda = r (s - p) >= 0 (the
/// update lambda + r (Nu - p) written in s).
#[inline]
pub fn normal_from_state(s: f64, g: f64, r: f64) -> (f64, f64) {
    let p = g.min(s);
    (p, r * (s - p))
}

/// Tangential auxiliary variable and multiplier from z = Tu + mu / r: q = shrink(z, s/r)
/// and mu = r (z - q), which is z r clamped to the friction interval [-s, s].
#[inline]
pub fn tangential_from_state(z: f64, threshold: f64, r: f64) -> (f64, f64) {
    let q = shrink(z, threshold / r);
    (q, r * (z - q))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_keeps_p_below_the_gap() {
        assert_eq!(project_normal(1.0, 0.5, 0.0, 10.0), 0.5);
        assert_eq!(project_normal(1.0, 0.9, 5.0, 10.0), 1.0);
        assert_eq!(project_normal(-0.5, 0.0, 0.0, 1.0), -0.5);
    }

    #[test]
    fn normal_update_equals_the_projected_form() {
        // lambda + r (un - min(g, un + lambda/r)) == max(0, lambda + r (un - g)).
        for &(g, un, lambda, r) in &[
            (0.1, 0.3, 2.0, 7.0),
            (0.1, -0.3, 2.0, 7.0),
            (0.0, 0.0, 0.0, 1.0),
            (1e-3, 2e-3, 1e4, 1e6),
        ] {
            let p = project_normal(g, un, lambda, r);
            let a = update_multiplier(lambda, r, un, p);
            let b = (lambda + r * (un - g)).max(0.0);
            assert!((a - b).abs() <= 1e-12 * b.abs().max(1.0), "{a} {b}");
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
        // mu + r (ut - shrink(ut + mu/r, s/r)) == clamp(mu + r ut, -s, s).
        for &(ut, mu, s, r) in &[
            (0.3, 1.0, 2.0, 10.0),
            (-0.3, 1.0, 2.0, 10.0),
            (0.01, 0.5, 2.0, 10.0),
        ] {
            let q = shrink(ut + mu / r, s / r);
            let a = update_multiplier(mu, r, ut, q);
            let b = (mu + r * ut).clamp(-s, s);
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
    }

    #[test]
    fn state_form_equals_the_sweep_form() {
        for &(un, lambda, g, r) in &[
            (0.3, 2.0, 0.1, 7.0),
            (-0.3, 0.0, 0.1, 7.0),
            (0.1, 1.0, 0.1, 3.0),
        ] {
            let s = un + lambda / r;
            let (p, l) = normal_from_state(s, g, r);
            assert_eq!(p, project_normal(g, un, lambda, r));
            assert!((l - update_multiplier(lambda, r, un, p)).abs() < 1e-12);
        }
        for &(ut, mu, th, r) in &[
            (0.3, 1.0, 2.0, 10.0),
            (-0.3, 1.0, 2.0, 10.0),
            (0.01, 0.5, 2.0, 10.0),
        ] {
            let z = ut + mu / r;
            let (q, m) = tangential_from_state(z, th, r);
            assert_eq!(q, shrink(z, th / r));
            assert!((m - (mu + r * ut).clamp(-th, th)).abs() < 1e-12);
        }
    }

    #[test]
    fn coulomb_threshold_never_negative() {
        assert_eq!(coulomb_threshold(0.3, -1e-12), 0.0);
        assert_eq!(coulomb_threshold(0.5, 4.0), 2.0);
    }
}
