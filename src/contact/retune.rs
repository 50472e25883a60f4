//! The augmentation parameter r per contact direction: when to retune it and to what.

use super::sweep::Sweep;

/// The augmentation parameter of each contact direction on this rank: ALG2 converges
/// for any positive r per direction (it is the method in a rescaled constraint), and
/// the best r differs between held and free directions (see [`retuned`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Augmentation {
    pub r_n: Vec<f64>,
    pub r_t: Vec<f64>,
}

impl Augmentation {
    /// The reference r in every direction of n contact nodes.
    pub fn uniform(n: usize, r: f64) -> Self {
        Augmentation {
            r_n: vec![r; n],
            r_t: vec![r; n],
        }
    }

    /// The r of each direction that `kind` asks for, given whether each node's normal and
    /// tangential directions are held (see [`tuned`]); `r` is the reference r.
    pub fn for_statuses(kind: Retune, held: &[(bool, bool)], frictional: bool, r: f64) -> Self {
        let mut aug = Augmentation::uniform(held.len(), r);
        if kind == Retune::ToStatus {
            for (i, &h) in held.iter().enumerate() {
                (aug.r_n[i], aug.r_t[i]) = tuned(h, frictional, r);
            }
        }
        aug
    }
}

/// Sweeps without a status change that [`retuned`] waits for; one more with friction,
/// whose stick/slip statuses follow the pressures and settle later (retuning one sweep
/// earlier scrambled them on the built-in frictional cases).
pub const SETTLED_SWEEPS: usize = 1;
/// Factors from the reference r for a held normal (raised) and a free one (lowered).
/// 1000 x keeps the condition number of the contact block within three more decades;
/// measured on frictionless full contact (block, levels 1-4): 10 x, 9-11 sweeps; 100 x,
/// 7-8; 1000 x, 6.
pub(super) const NORMAL_FACTOR: f64 = 1000.0;
/// The same for the tangents. Friction statuses are fragile (a sticking node flips to
/// slip when a large r amplifies the remaining tangential motion): over the built-in
/// frictional cases at levels 1-3, 10 x gave 22-42 sweeps, 30 x 19-56, 1000 x 20-112.
const TANGENT_FACTOR: f64 = 10.0;
/// Retunes allowed in one run, all kinds together: up to MAX_RETUNES - 1 to the statuses;
/// after them, a further settled change of the statuses returns every direction to the
/// reference r (the last one).
pub const MAX_RETUNES: usize = 4;

/// The r of a node's normal and tangential directions once their statuses have settled:
/// raised where held (pressed, sticking), lowered where free (open, slipping). Without
/// friction the tangent is not part of the method and keeps r.
pub fn tuned((held_n, held_t): (bool, bool), frictional: bool, r: f64) -> (f64, f64) {
    let pick = |held: bool, factor: f64| if held { r * factor } else { r / factor };
    let t = if frictional {
        pick(held_t, TANGENT_FACTOR)
    } else {
        r
    };
    (pick(held_n, NORMAL_FACTOR), t)
}

/// What [`retuned`] asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Retune {
    /// Each direction to the r its status asks for ([`tuned`]).
    ToStatus,
    /// Every direction back to the reference r.
    ToReference,
}

/// Whether to retune r now, from the history alone (global counts: every rank decides
/// the same, whatever the rank count).
///
/// Why: r acts as a spring r w on each contact direction. A held direction (an active
/// normal, a sticking tangent) is an equality the sweep enforces by contracting each of
/// its modes by 1 / (1 + r c) (c a contact compliance): large r is best. A free
/// direction (an open node, a slipping tangent) is pinned by the spring near its last
/// value and moves by r c / (1 + r c) of the way: small r is best. One r for all
/// balances the two and sweeps slowly (plain Hertz: 423 sweeps at level 3, Anderson
/// 54). Once the statuses stop changing, the held and free sets are known and each
/// direction gets its own r (ALG2 converges for any positive r per direction: it is the
/// same method for rescaled constraints).
///
/// Undone: when more than half of the [`CYCLE_WINDOW`] sweeps since a retune changed a
/// status, every direction returns to the reference r (within the budget).
///
/// When: the last [`SETTLED_SWEEPS`] sweeps, all with the current r, changed no status,
/// and some direction's r differs from what its status asks for. At most
/// [`MAX_RETUNES`] - 1 times, then once back to the reference r if the statuses move
/// again, [`MAX_RETUNES`] in all: a retune costs one dense refactorization of the
/// contact blocks.
pub fn retuned(history: &[Sweep], frictional: bool, n_contact: usize) -> Option<Retune> {
    let last = history.last()?;
    let settled = if frictional {
        SETTLED_SWEEPS + 1
    } else {
        SETTLED_SWEEPS
    };
    // A retune whose statuses keep flipping: the node at the edge of the contact zone
    // alternates between r x 1000 (held) and r / 1000 (free), a factor 1e6 that its
    // projection overshoots, a cycle no settling ends (seen: one node flipping every
    // sweep for 10000 sweeps on a beam). ALG2 with one r converges: back to it.
    if last.stiff + last.soft > 0 && last.retunes < MAX_RETUNES && history.len() >= CYCLE_WINDOW {
        let tail = &history[history.len() - CYCLE_WINDOW..];
        if tail.iter().all(|s| s.retunes == last.retunes)
            && 2 * tail.iter().filter(|s| s.changed > 0).count() > CYCLE_WINDOW
        {
            return Some(Retune::ToReference);
        }
    }
    if history.len() < settled || last.mistuned == 0 {
        return None;
    }
    let tail = &history[history.len() - settled..];
    if !tail
        .iter()
        .all(|s| s.changed == 0 && s.retunes == last.retunes)
    {
        return None;
    }
    match last.retunes + 1 {
        k if k < MAX_RETUNES && 2 * n_contact <= MAX_RETUNE_DOFS => Some(Retune::ToStatus),
        MAX_RETUNES if last.stiff + last.soft > 0 => Some(Retune::ToReference),
        _ => None,
    }
}

/// Sweeps after a retune over which a majority of status changes undoes it (see
/// [`retuned`]). Measured on clamped beams and the cantilever of tests/data/tolerance
/// (sweeps, frictionless / Coulomb): without the rule 58/95, 173/258, 517/483 for the
/// 0.4, 1 and 2 m beams and 478/643 for the cantilever; with 20 sweeps 58/91, 173/152,
/// 380/401 and 350/440; with 10, 58/78, 157/144, 410/823, 403/1112; with 30, 58/95,
/// 173/158, 517/278, 478/445. The compact and built-in cases never trigger it.
const CYCLE_WINDOW: usize = 20;

/// Contact dofs (two per contact node, over all ranks) above which r is not retuned. The
/// first retune refactors the dense contact blocks, about c^3 / 3 flops for c contact
/// dofs, which costs as much as 30-80 sweeps (measured on hertz, frictionless, one rank:
/// 28, 38, 62, 78, 80 sweeps at c = 222, 440, 878, 1756, 3508; 0.5 s at c = 3508, 1.2 s
/// on two ranks); the later ones move a few directions and update the factor in place
/// (`LocalFactor::update_boundary`) for a fraction of that. Up to 2048 a retune takes at
/// most about 0.1 s, negligible next to the factorization; above, the seconds it takes
/// exceed what the sweeps it saves cost, and Anderson mixing alone is faster.
const MAX_RETUNE_DOFS: usize = 2048;

#[cfg(test)]
mod tests {
    use super::*;

    fn sweep(changed: usize, mistuned: usize, retunes: usize) -> Sweep {
        Sweep {
            iter: 1,
            pressure: 1e-3,
            traction: 1e-3,
            displacement: 1e-3,
            contraction: 0.5,
            error: 2e-3,
            active: 5,
            slip: 0,
            changed,
            stiff: 0,
            soft: 0,
            mistuned,
            uncertain: 0,
            retunes,
            refused: 0,
        }
    }

    #[test]
    fn r_is_retuned_once_the_statuses_have_settled() {
        let (moving, still) = (sweep(2, 5, 0), sweep(0, 5, 0));
        // Frictionless: one sweep without a change; with friction, two.
        assert_eq!(retuned(&[moving, still], false, 5), Some(Retune::ToStatus));
        assert_eq!(retuned(&[moving, still], true, 5), None);
        assert_eq!(
            retuned(&[moving, still, still], true, 5),
            Some(Retune::ToStatus)
        );
        assert_eq!(retuned(&[still, moving], false, 5), None);
        // Nothing to change, or a contact block too large to refactor cheaply.
        assert_eq!(retuned(&[moving, sweep(0, 0, 0)], false, 5), None);
        assert_eq!(retuned(&[moving, still], false, MAX_RETUNE_DOFS), None);
        // The settled sweeps must all be with the current r.
        let after = sweep(0, 3, 1);
        assert_eq!(retuned(&[still, after], true, 5), None);
        assert_eq!(
            retuned(&[still, after, after], true, 5),
            Some(Retune::ToStatus)
        );
        // After the budget, once back to the reference r, then never again.
        let mut spent = sweep(0, 3, MAX_RETUNES - 1);
        spent.stiff = 2;
        assert_eq!(
            retuned(&[spent, spent], false, 5),
            Some(Retune::ToReference)
        );
        let reset = sweep(0, 3, MAX_RETUNES);
        assert_eq!(retuned(&[reset, reset], false, 5), None);
    }

    #[test]
    fn a_retune_whose_statuses_keep_flipping_is_undone() {
        let mut flipping = sweep(1, 3, 1);
        flipping.stiff = 4;
        let mut quiet = flipping;
        quiet.changed = 0;
        // 11 of 20 sweeps since the retune changed a status: back to the reference r.
        let mut h: Vec<Sweep> = (0..CYCLE_WINDOW)
            .map(|i| if i % 2 == 0 { flipping } else { quiet })
            .collect();
        h[CYCLE_WINDOW - 1] = flipping;
        assert_eq!(retuned(&h, false, 5), Some(Retune::ToReference));
        // 10 of 20: not a majority (the last sweep changed nothing: the statuses settle).
        h[CYCLE_WINDOW - 1] = quiet;
        assert_eq!(retuned(&h, false, 5), Some(Retune::ToStatus));
        // The window must lie after the retune.
        let mut before = h.clone();
        before[0].retunes = 0;
        before[CYCLE_WINDOW - 1] = flipping;
        assert_ne!(retuned(&before, false, 5), Some(Retune::ToReference));
        // At the reference r there is nothing to undo.
        let at_reference: Vec<Sweep> = (0..CYCLE_WINDOW).map(|_| sweep(1, 3, 1)).collect();
        assert_eq!(retuned(&at_reference, false, 5), None);
    }

    #[test]
    fn tuned_r_raises_held_directions_and_lowers_free_ones() {
        let r = 10.0;
        assert_eq!(
            tuned((true, false), true, r),
            (r * NORMAL_FACTOR, r / TANGENT_FACTOR)
        );
        assert_eq!(
            tuned((false, true), true, r),
            (r / NORMAL_FACTOR, r * TANGENT_FACTOR)
        );
        // Without friction the tangent keeps the reference r.
        assert_eq!(tuned((true, false), false, r), (r * NORMAL_FACTOR, r));
    }
}
