//! Properties of the node-wise kernels of ALG2 (steps 2 and 3 of docs/ALGORITHM.md),
//! checked on random inputs: the projection, the shrinkage, the multiplier updates and
//! the Coulomb threshold, as the loop calls them (on the state s = Nu + lambda / r), and
//! their agreement with the textbook updates lambda + r (Nu - p), mu + r (Tu - q).
//!
//! Where a property is an identity of real numbers evaluated along two different float
//! paths, it holds to a few ulps of the magnitudes involved (`close`); where both sides
//! take the same path (oddness, |shrink|, idempotence), it holds exactly.

use contact_par::contact::kernels::{
    coulomb_threshold, normal_from_state, project_normal, shrink, state, tangential_from_state,
    update_multiplier,
};
use proptest::prelude::*;

/// Values on every scale the solver meets (displacements of 1e-9 to forces of 1e6), both
/// signs, and exact zeros.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        -1.0..1.0f64,
        -1e6..1e6f64,
        (-9.0..3.0f64, any::<bool>()).prop_map(|(e, neg)| {
            let v = 10f64.powf(e);
            if neg {
                -v
            } else {
                v
            }
        }),
    ]
}

/// An augmentation parameter r > 0 (from soft rubber to steel on a fine mesh).
fn augmentation() -> impl Strategy<Value = f64> {
    (-3.0..9.0f64).prop_map(|e| 10f64.powf(e))
}

/// A threshold or slip bound s >= 0.
fn threshold() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        0.0..1e6f64,
        (-9.0..3.0f64).prop_map(|e| 10f64.powf(e))
    ]
}

/// `a` and `b` agree to a few ulps of `scale` (the largest magnitude in the computation).
fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 8.0 * f64::EPSILON * scale.max(f64::MIN_POSITIVE)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// p = min(g, un + lambda / r) never exceeds the gap.
    #[test]
    fn projection_stays_below_the_gap(g in value(), un in value(), lambda in value(), r in augmentation()) {
        prop_assert!(project_normal(g, state(un, lambda, r)) <= g);
    }

    /// Projecting a projected value changes nothing.
    #[test]
    fn projection_is_idempotent(g in value(), s in value()) {
        let p = project_normal(g, s);
        prop_assert_eq!(project_normal(g, p), p);
    }

    /// Below the gap, the projection is the identity.
    #[test]
    fn projection_keeps_admissible_values(s in value(), room in 0.0..1e3f64) {
        prop_assert_eq!(project_normal(s + room, s), s);
    }

    /// The update r (s - p) with p the projection is the textbook lambda + r (un - p)
    /// and max(0, lambda + r (un - g)) to round-off, and >= 0 exactly (s - min(g, s) is
    /// never negative in floating point), where the textbook form often comes out a tiny
    /// negative, of order -r eps |un|, on a free node (about one random draw in seven):
    /// which is why the loop updates in the state and the Coulomb threshold clips the
    /// pressure.
    #[test]
    fn normal_update_is_the_positive_part(g in value(), un in value(), lambda in value(), r in augmentation()) {
        let s = state(un, lambda, r);
        let p = project_normal(g, s);
        let updated = update_multiplier(r, s, p);
        let textbook = lambda + r * (un - p);
        let expected = (lambda + r * (un - g)).max(0.0);
        let scale = lambda.abs() + r * (un.abs() + g.abs());
        prop_assert!(close(updated, expected, scale), "{} vs {}", updated, expected);
        prop_assert!(close(updated, textbook, scale), "{} vs {}", updated, textbook);
        prop_assert!(updated >= 0.0, "{}", updated);
        prop_assert!(textbook >= -8.0 * f64::EPSILON * scale, "{}", textbook);
    }

    /// A node pressed past its gap (un >= g) with a multiplier >= 0 is active: p = g, and
    /// the update stays >= 0.
    #[test]
    fn normal_update_of_an_active_node(g in value(), past in 0.0..1e3f64, lambda in 0.0..1e6f64, r in augmentation()) {
        let s = state(g + past, lambda, r);
        let p = project_normal(g, s);
        prop_assert_eq!(p, g);
        prop_assert!(update_multiplier(r, s, p) >= 0.0);
    }

    /// State form, normal: lambda = r (s - min(g, s)) is r max(s - g, 0), zero exactly
    /// when the node is free.
    #[test]
    fn normal_update_is_zero_exactly_on_a_free_node(s in value(), g in value(), r in augmentation()) {
        let lambda = update_multiplier(r, s, project_normal(g, s));
        prop_assert!(lambda >= 0.0);
        prop_assert_eq!(lambda == 0.0, s <= g);
        prop_assert!(close(lambda, r * (s - g).max(0.0), r * (s.abs() + g.abs())));
    }

    /// Shrinkage is odd: shrink(-z, a) = -shrink(z, a).
    #[test]
    fn shrink_is_odd(z in value(), a in threshold()) {
        prop_assert_eq!(shrink(-z, a), -shrink(z, a));
    }

    /// |shrink(z, a)| = max(|z| - a, 0), with the sign of z when it is not zero.
    #[test]
    fn shrink_has_the_soft_threshold_magnitude(z in value(), a in threshold()) {
        let q = shrink(z, a);
        prop_assert_eq!(q.abs(), (z.abs() - a).max(0.0));
        prop_assert!(q == 0.0 || q.signum() == z.signum());
        prop_assert_eq!(q == 0.0, z.abs() <= a);
    }

    /// Shrinkage never moves two points apart (it is a proximal map, so 1-Lipschitz).
    #[test]
    fn shrink_is_non_expansive(z1 in value(), z2 in value(), a in threshold()) {
        let d = (shrink(z1, a) - shrink(z2, a)).abs();
        // Round-off of |z| - a is relative to |z| and a, not to |z1 - z2|.
        let slack = 4.0 * f64::EPSILON * (z1.abs() + z2.abs() + a);
        prop_assert!(d <= (z1 - z2).abs() + slack,
            "{} > {}", d, (z1 - z2).abs());
    }

    /// Moreau's decomposition: z = shrink(z, a) + clamp(z, -a, a).
    #[test]
    fn shrink_plus_clamp_is_the_identity(z in value(), a in threshold()) {
        let sum = shrink(z, a) + z.clamp(-a, a);
        prop_assert!(close(sum, z, z.abs() + a), "{} vs {}", sum, z);
    }

    /// Shrinking by zero is the identity; shrinking twice by a and b is shrinking by a + b.
    #[test]
    fn shrink_composes(z in value(), a in threshold(), b in threshold()) {
        prop_assert_eq!(shrink(z, 0.0), z);
        let twice = shrink(shrink(z, a), b);
        prop_assert!(close(twice, shrink(z, a + b), z.abs() + a + b), "{} vs {}", twice, shrink(z, a + b));
    }

    /// The tangential update r (z - q), q = shrink(z, s / r), is the textbook
    /// mu + r (ut - q) and the clamp of mu + r ut onto [-s, s] (to round-off): the
    /// tangential multiplier never leaves the friction interval.
    #[test]
    fn tangential_update_is_the_clamp(ut in value(), mu in value(), s in threshold(), r in augmentation()) {
        let z = state(ut, mu, r);
        let q = shrink(z, s / r);
        let updated = update_multiplier(r, z, q);
        let textbook = mu + r * (ut - q);
        let expected = (mu + r * ut).clamp(-s, s);
        let scale = mu.abs() + r * ut.abs() + s;
        prop_assert!(close(updated, expected, scale), "{} vs {}", updated, expected);
        prop_assert!(close(updated, textbook, scale), "{} vs {}", updated, textbook);
        prop_assert!(updated.abs() <= s + 8.0 * f64::EPSILON * scale);
    }

    /// s = coefficient * max(lambda, 0): never negative, linear in the pressure, and zero
    /// for a node that pulls away.
    #[test]
    fn coulomb_threshold_is_the_clipped_pressure(c in 0.0..2.0f64, lambda in value(), extra in 0.0..1e6f64) {
        let s = coulomb_threshold(c, lambda);
        prop_assert!(s >= 0.0);
        prop_assert_eq!(s, c * lambda.max(0.0));
        prop_assert!(coulomb_threshold(c, lambda + extra) >= s * (1.0 - 4.0 * f64::EPSILON));
    }

    /// One call per direction is step 2 then step 3, bit for bit.
    #[test]
    fn node_calls_are_steps_2_and_3(s in value(), g in value(), th in threshold(), r in augmentation()) {
        let p = project_normal(g, s);
        prop_assert_eq!(normal_from_state(s, g, r), (p, update_multiplier(r, s, p)));
        let q = shrink(s, th / r);
        prop_assert_eq!(tangential_from_state(s, th, r), (q, update_multiplier(r, s, q)));
    }
}
