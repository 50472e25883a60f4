//! The augmentation parameter r per contact direction: when to retune it and to what.

use super::sweep::Sweep;

/// The augmentation parameter of each contact direction on this rank: ALG2 converges
/// for any positive r per direction (it is the method in a rescaled constraint), and
/// the best r differs between held and free directions (see [`retuned`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Augmentation {
    pub r_n: Vec<f64>,
    pub r_t: Vec<f64>,
    /// Whether this r was set once the statuses had settled ([`Retune::ToStatus`]), or by
    /// a normals' retune after that ([`Retune::Normals`] from settled r): free directions
    /// are then lowered further ([`SETTLED_FREE_FACTOR`]).
    #[serde(default)]
    pub settled: bool,
    /// Whether this r ended the retunes of a cycle ([`Retune::EndCycle`]): no retune
    /// follows.
    #[serde(default)]
    pub ended: bool,
    /// Whether the tangents follow their stick/slip statuses at each retune, as the
    /// normals follow theirs ([`Augmentation::for_statuses`]): with fixed slip thresholds
    /// (Tresca), while at least two nodes are pressed ([`tangents_follow`]).
    #[serde(default)]
    pub follow_tangents: bool,
    /// Whether this r is the slow tail's ([`Retune::Tail`]): sticking tangents and free
    /// directions a further [`TAIL_FACTOR`] from the reference r, until a status changes.
    #[serde(default)]
    pub tail: bool,
}

impl Augmentation {
    /// The reference r in every direction of n contact nodes.
    pub fn uniform(n: usize, r: f64) -> Self {
        Augmentation {
            r_n: vec![r; n],
            r_t: vec![r; n],
            settled: false,
            ended: false,
            follow_tangents: false,
            tail: false,
        }
    }

    /// The r of each direction that `kind` asks for, given whether each node's normal and
    /// tangential directions are held (see [`tuned`]); `r` is the reference r,
    /// `mesh_stiffness` the body's E_eff / h (0 when not known), `from_settled`
    /// whether the r being replaced was [`Augmentation::settled`] and `follow_tangents`
    /// whether the tangents follow their statuses ([`tangents_follow`]).
    ///
    /// A normals' retune from settled r keeps the free directions (open normals, loose
    /// tangents) at their settled, lowered r: the statuses had settled, so the change that
    /// asks for it is the contact zone's edge moving by a node or a few, and returning
    /// every free direction to the moving zone's r / 1000 made each such node cost three
    /// sweeps (the normals' retune, two sweeps without a change, the settled retune)
    /// where it now costs one or two. Measured (one thread, default options) on the
    /// holed plate of `make_cases.py --heldout --scale 0.5` (7881 nodes), whose zone grows back
    /// from 5 nodes to 27 after its landing: 96 -> 61 sweeps; the Coulomb bridge of
    /// `--slender --scale 0.5` (6513 nodes) 87 -> 74; over the 113 runs of the held-out, slender,
    /// beam, Tresca and built-in cases, 14 787 -> 14 657 sweeps, the largest count
    /// against the built-in block's at the same size 2.79 -> 2.37 times, the worst
    /// losses the L-bracket 64 -> 71 and the half ring at 6636 nodes 60 -> 75. The
    /// tangents of pressed nodes still go to r / 10: kept settled too (sticking ones x
    /// 10) on a small change, a slab on a slope whose stick/slip statuses then flipped
    /// took 46 -> 928 sweeps, and with the stiff tangents kept only where no pressed
    /// node flipped, the 2 m Coulomb beam 61 -> 77.
    ///
    /// With `follow_tangents` ([`tangents_follow`]), a normals' retune gives the tangents
    /// the r of their stick/slip statuses too: the sweep is an active-set step in both
    /// directions.
    pub fn for_statuses(
        kind: Retune,
        held: &[Held],
        frictional: bool,
        (r, mesh_stiffness): (f64, f64),
        from_settled: bool,
        follow_tangents: bool,
    ) -> Self {
        let mut aug = Augmentation::uniform(held.len(), r);
        aug.settled = match kind {
            Retune::ToStatus | Retune::Tail => true,
            Retune::Normals => from_settled,
            Retune::BudgetSpent | Retune::EndCycle { .. } => false,
        };
        aug.follow_tangents = follow_tangents && frictional;
        aug.tail = kind == Retune::Tail;
        for (i, &h) in held.iter().enumerate() {
            let (r_n, r_t) = aug.tuned(h, frictional, r, mesh_stiffness);
            match kind {
                Retune::ToStatus | Retune::Tail => (aug.r_n[i], aug.r_t[i]) = (r_n, r_t),
                Retune::Normals => {
                    aug.r_n[i] = r_n;
                    if frictional {
                        aug.r_t[i] = if aug.follow_tangents || (aug.settled && h.free_tangent()) {
                            r_t
                        } else {
                            r / TANGENT_FACTOR
                        };
                    }
                }
                Retune::BudgetSpent | Retune::EndCycle { .. } => {}
            }
        }
        aug
    }

    /// The rules of [`tuned`] this augmentation was made by.
    pub fn rules(&self) -> Rules {
        Rules {
            settled: self.settled,
            follow_tangents: self.follow_tangents,
            tail: self.tail,
        }
    }

    /// The r that a node of statuses `status` asks for under this augmentation's rules.
    pub fn tuned(&self, status: Held, frictional: bool, r: f64, mesh_stiffness: f64) -> (f64, f64) {
        tuned(status, frictional, r, mesh_stiffness, self.rules())
    }

    /// The last retune, when the statuses cycle ([`Retune::EndCycle`]) or the budget is
    /// spent ([`Retune::BudgetSpent`]). `cycled`: each node's (any status, its normal's)
    /// change since the cycle began (the last sweep, for the budget).
    /// - A node that stayed open through the cycle keeps the r its settled status asks
    ///   for (lowered): at the reference r, the springs of the open nodes hold the smooth
    ///   modes of a body that the contact holds at few nodes (the held-out shallow arch,
    ///   standing on one slipping node of 253, its statuses cycling at two: 74 sweeps,
    ///   53 with this, the same answer).
    /// - A pressed node whose normal stayed pressed keeps its normal held (raised): at
    ///   the reference r a body that only its contact holds sinks through the foundation
    ///   onto the lowered open nodes, which then carry it at r / 10^4 and let it creep
    ///   (a strip balanced on a ridge on two nodes, make_cases.py --obstacles: not
    ///   converged in 10^4 sweeps; 118 with this and the floor below).
    /// - A pressed node's tangent returns to the reference r, but not below the held
    ///   tangents' floor: with friction, the reference r of a slender body lies far below
    ///   the mesh's stiffness (r_loop), where a sticking tangent that a stiff path holds
    ///   (the ridge's, along the strip to its end held along x) creeps by 1e-4 a sweep.
    /// - Every other direction (the normals that cycled) returns to the reference r,
    ///   where ALG2 converges whatever the statuses; keeping the directions that cycled
    ///   tuned never converged on the arch (10^4 sweeps): their r is what cycled. The
    ///   sticking tangents are not raised above the floor: with their held directions
    ///   raised, the two Coulomb blocks of tests/bodies.rs (corners moved apart, 17
    ///   pressed nodes) converged to another answer, one more node sticking, which every
    ///   fixed r misses (a discrete Coulomb problem need not have a unique answer).
    pub fn after_cycle(
        held: &[Held],
        cycled: &[(bool, bool)],
        frictional: bool,
        r: f64,
        mesh_stiffness: f64,
    ) -> Self {
        let mut aug = Augmentation::uniform(held.len(), r);
        aug.settled = true;
        aug.ended = true;
        for (i, (&h, &(any, normal))) in held.iter().zip(cycled).enumerate() {
            let settled = tuned(h, frictional, r, mesh_stiffness, Rules::SETTLED);
            if !h.n {
                if !any {
                    (aug.r_n[i], aug.r_t[i]) = settled;
                }
                continue;
            }
            if !normal {
                aug.r_n[i] = settled.0;
            }
            if frictional {
                aug.r_t[i] = r.max(HELD_TANGENT_FLOOR * mesh_stiffness);
            }
        }
        aug
    }
}

/// Sweeps without a status change that [`retuned`] waits for before it tunes the
/// tangents; one more with friction, whose stick/slip statuses follow the pressures and
/// settle later (retuning one sweep earlier scrambled them on the built-in frictional
/// cases).
pub const SETTLED_SWEEPS: usize = 1;
/// Factors from the reference r for a held normal (raised) and a free one (lowered).
/// 1000 x keeps the condition number of the contact block within three more decades;
/// measured on frictionless full contact (block, levels 1-4): 10 x, 9-11 sweeps; 100 x,
/// 7-8; 1000 x, 6. Held x 100 with the normals following their statuses every sweep:
/// hertz 13-17 sweeps at levels 1-3 against 9-13, the slender cases no better.
pub(super) const NORMAL_FACTOR: f64 = 1000.0;
/// The factor below the reference r of a free direction (an open normal, a loose
/// tangent) once the statuses have settled ([`Retune::ToStatus`]), in place of
/// [`NORMAL_FACTOR`] (normals) and [`TANGENT_FACTOR`] (loose tangents, which were tuned
/// as slipping ones). A free direction carries no force: its spring w r only pulls it
/// back towards its last value, and holds the body's modes of compliance c by r c / (1 +
/// r c) per sweep. While the contact zone moves, that pull keeps a sweep from throwing
/// the body far through the foundation; once the statuses have settled it only slows the
/// smooth modes of a body that the contact holds at few nodes. Measured on the thin half
/// ring of make_cases.py --heldout, which stands on one sticking node: its 262 open nodes
/// held its bending modes by r c of about 10^3 (normals at r / 1000) and 10^5 (tangents
/// at r / 10), the loop contracted by 0.9999 on one piece whose statuses no longer
/// changed, and took 455 sweeps (2 threads; 837 on 1, 531 on 2 ranks, 1410 on 3, the
/// path following round-off); with this factor 38 on each. 10^5: ring 24, but a Tresca
/// strip 73 -> 87 (its statuses flip back and forth, 50 retunes). Once lowered they stay
/// so: a later normals' retune keeps them ([`Augmentation::for_statuses`]); only the
/// pressed nodes' tangents return to the moving zone's r / 10.
pub(super) const SETTLED_FREE_FACTOR: f64 = 1.0e4;
/// The same for the tangents. Friction statuses are fragile (a sticking node flips to
/// slip when a large r amplifies the remaining tangential motion): over the built-in
/// frictional cases at levels 1-3, 10 x gave 22-42 sweeps, 30 x 19-56, 1000 x 20-112;
/// with the normals following their statuses, a sticking tangent x 100 or x 1000 took
/// block levels 2-3 from 33-36 to 51-214 sweeps and the Coulomb cantilever of
/// tests/data/tolerance from 73 to 322-505.
const TANGENT_FACTOR: f64 = 10.0;
/// The least r of a held normal and of a sticking tangent, in units of the body's
/// mesh-scale stiffness E_eff / h. A held direction is an equality, whose sweep contracts
/// each of its modes by 1 / (1 + r c), c the mode's compliance; the stiffest, mesh-scale
/// modes have c of order h / E_eff, so a held direction needs r of order E_eff / h,
/// whatever the reference r. The factors above give far more on compact bodies (the
/// automatic r is E_eff / sqrt(h L): held normals 40-220 E_eff / h, sticking tangents
/// 0.8-2.2 on the built-in cases at levels 1-4), but not once the smooth-mode probe has
/// lowered the reference r for a slender body's open nodes: a plank lying flat under its own weight
/// (r lowered 2300-fold) had its sticking tangents at 0.0015 E_eff / h, contracting by
/// 0.998 per sweep: 290 sweeps (Coulomb 0.6; frictionless, held normals at 0.15 E_eff / h,
/// 68). With these floors 36 and 20.
///
/// Both floors stay well below what the stiffest modes alone would ask for, because a
/// retune that jumps a direction's r by thousands moves statuses, and the retunes that
/// follow can cycle (docs/performance-history.md has the measurements). The normals'
/// floor: 1, 3 or 10 took the frictionless plank to 13, 9 and 7 sweeps, but with the
/// tangents' floor a slab on a slope (held out at first) cycled through the retune
/// budget (954-990 sweeps, 47 at 0.3 and 43 before the floors).
pub(super) const HELD_NORMAL_FLOOR: f64 = 0.3;
/// The tangents' floor: a sticking tangent much stiffer amplifies the tangential motion
/// left while the body still bends, its node flips to slip, and the stick/slip statuses
/// cycle. Measured (sweeps of the Coulomb cantilever of tests/data/tolerance, the 2 m
/// Coulomb beam, the Coulomb plank), with a normals' floor of 10: 0.1: 75, 71, 50; 0.15:
/// 72, 67, 54; 0.2: 67, 59, 44; 0.3: 71, 75, 35; 0.4: 310, 74, 30 (the cantilever's
/// statuses cycle: 30 retunes); 0.5: 322; 1: 59, 66, 21 but the 2 m beam and the
/// cantilever meshed finely 118 and 178; 3: the 1 and 2 m beams spent the retune budget
/// (396, 655). 0.2 is half the lowest floor where a case cycled.
pub(super) const HELD_TANGENT_FLOOR: f64 = 0.2;
/// How much further from the reference r the slow tail's retune ([`tail`]) sets the
/// tangents and the free directions: a sticking tangent x 10 more (its floor too, but at
/// most the held normals' r), a free direction (open normal, loose tangent) / 10 more. A
/// pressed node's slipping tangent keeps r / 10. The held normals keep r x 1000: their r
/// sets the sweep's round-off ([`largest_tuned`]), which the tail leaves as it was. x 10
/// more made it ten times larger (the Coulomb cantilever of tests/data/tolerance, whose
/// floor is 2e-8, then stopped 1.1e-8 apart in p_n on 1 and 2 ranks, 1.3e-9 without)
/// and saved no sweep on the six slowest cases; the sticking tangents' floor x 10 above
/// the normals' r (2 E_eff / h against 0.3) saved sweeps on slender bodies (a held-out
/// Tresca arch 60 -> 47, a Coulomb plank 30 -> 24), but raised their round-off with it:
/// of 232 held-out runs, 8 more warned that round-off bounds their accuracy above tol.
pub(super) const TAIL_FACTOR: f64 = 10.0;
/// Sweeps that changed no status with the settled r before [`tail`] may retune.
const TAIL_SWEEPS: usize = 2;
/// The plain map's contraction (estimated from secants) from which a tail counts as
/// slow ([`tail`]).
const TAIL_CONTRACTION: f64 = 0.6;
/// Tail retunes allowed in one run ([`tail`]).
pub const MAX_TAIL_RETUNES: usize = 3;

/// Whether to retune r for the slow tail ([`Retune::Tail`]) when [`retuned`] asks for
/// nothing: `aug` is the r in force, settled and not already the tail's, not the end of a
/// cycle; `tails` the tail retunes so far (at most [`MAX_TAIL_RETUNES`]); the last
/// [`TAIL_SWEEPS`] sweeps changed no status and were made with this r, which is the one
/// their statuses ask for; and the plain map contracts by [`TAIL_CONTRACTION`] or more.
/// The tail's r holds until a status changes: the retune that follows is made by the
/// other rules ([`Augmentation::for_statuses`]), which are not the tail's.
///
/// Why: the settled factors (sticking tangents x 10, free directions / 10^4) are as far
/// as r can go while statuses still move, a stiffer sticking tangent amplifying the
/// motion left and flipping its node ([`HELD_TANGENT_FLOOR`]). Once the statuses hold,
/// what is left is a linear tail, slow in the modes that the sticking tangents pin too
/// loosely or the free directions too tightly: the Coulomb cantilever of
/// tests/data/tolerance, its 65 slipping and 56 sticking nodes settled by sweep 39, had
/// a plain map contracting by 0.89 for its last 26 sweeps (67 in all); with the tail's r
/// from sweep 45, by 0.39-0.47, 55 in all. The half ring of `make_cases.py --heldout
/// --scale 0.5` 75 -> 44, a Tresca arch of `--heldout` 65 -> 60 (docs/
/// performance-history.md has the sets measured). Kept for the rest of the run (not
/// undone at a status change), and a second one allowed on top, a Tresca cantilever did
/// not converge in 10^4 sweeps; sticking tangents x 100 in the tail, the Coulomb one did
/// not either; a pressed node's slipping tangent / 10 more too, the 2 m Coulomb beam 61
/// -> 193.
pub fn tail(history: &[Sweep], aug: &Augmentation, tails: usize) -> bool {
    let Some(last) = history.last() else {
        return false;
    };
    if !aug.settled || aug.tail || aug.ended || tails >= MAX_TAIL_RETUNES {
        return false;
    }
    // The last retune of the budget is the return to the reference r.
    if last.retunes + 2 > MAX_RETUNES || last.mistuned > 0 || history.len() < TAIL_SWEEPS {
        return false;
    }
    let quiet = history[history.len() - TAIL_SWEEPS..]
        .iter()
        .all(|s| s.changed == 0 && s.retunes == last.retunes);
    quiet && last.contraction >= TAIL_CONTRACTION
}

/// Retunes allowed in one run, all kinds together. The normals follow their statuses at
/// every sweep that changes one, so a run that finds its contact zone node by node
/// retunes as often (measured: at most 47 on the slender cases of
/// docs/performance-history.md, 1-7 on the built-in and compact ones). A run that
/// reaches the budget has statuses that cycle: every direction returns once to the
/// reference r (the last retune), where ALG2 converges for any r.
pub const MAX_RETUNES: usize = 100;

/// The r of a node's normal and tangential directions for its statuses: raised where
/// held (pressed, sticking), at least to the floors above in units of `mesh_stiffness`
/// (E_eff / h, 0 when not known); lowered where free (open, slipping), further once
/// `rules.settled` for the directions that nothing but their spring holds
/// ([`SETTLED_FREE_FACTOR`]); with `rules.follow_tangents`, an open node's slipping
/// tangent counts as free at once, settled or not; with `rules.tail` (and settled),
/// sticking tangents and free directions a further [`TAIL_FACTOR`] away. Without
/// friction the tangent is not part of the method and keeps r.
pub fn tuned(
    status: Held,
    frictional: bool,
    r: f64,
    mesh_stiffness: f64,
    rules: Rules,
) -> (f64, f64) {
    let Rules {
        settled,
        follow_tangents,
        tail,
    } = rules;
    let further = if settled && tail { TAIL_FACTOR } else { 1.0 };
    let pick = |held: bool, factor: f64, floor: f64| {
        if held {
            (r * factor).max(floor * mesh_stiffness)
        } else {
            r / factor
        }
    };
    let free = if settled {
        r / (SETTLED_FREE_FACTOR * further)
    } else {
        r / NORMAL_FACTOR
    };
    let t = if frictional && status.free_tangent() && (settled || (follow_tangents && !status.n)) {
        free
    } else if frictional && status.t {
        // The tail's sticking tangent stays at most at the held normals' r, which sets
        // the sweep's round-off (`largest_tuned`, never below a sticking tangent's r).
        (pick(true, TANGENT_FACTOR, HELD_TANGENT_FLOOR) * further)
            .min(largest_tuned(r, mesh_stiffness))
    } else if frictional {
        pick(false, TANGENT_FACTOR, HELD_TANGENT_FLOOR)
    } else {
        r
    };
    let n = if status.n {
        pick(true, NORMAL_FACTOR, HELD_NORMAL_FLOOR)
    } else {
        free
    };
    (n, t)
}

/// Which of [`tuned`]'s rules apply: the settled ones (free directions lowered further),
/// and whether the tangents follow their stick/slip statuses ([`tangents_follow`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rules {
    pub settled: bool,
    pub follow_tangents: bool,
    /// The slow tail's further factor for sticking tangents and free directions
    /// ([`TAIL_FACTOR`]; only with `settled`).
    pub tail: bool,
}

impl Rules {
    /// The settled rules, tangents not following.
    pub const SETTLED: Rules = Rules {
        settled: true,
        follow_tangents: false,
        tail: false,
    };
    /// The moving zone's rules, tangents not following.
    pub const MOVING: Rules = Rules {
        settled: false,
        follow_tangents: false,
        tail: false,
    };
}

/// The largest r that [`tuned`] gives any direction: the scale of the sweep's round-off.
pub fn largest_tuned(r: f64, mesh_stiffness: f64) -> f64 {
    (r * NORMAL_FACTOR).max(HELD_NORMAL_FLOOR * mesh_stiffness)
}

/// Whether the tangents follow their stick/slip statuses at each retune
/// ([`Augmentation::for_statuses`], [`Rules::follow_tangents`]): where the slip thresholds are
/// fixed (Tresca: `fixed_thresholds`), while at least two nodes are pressed
/// (`pressed_nodes`), unless the retunes have cycled with them (`cycled`).
///
/// Why: with a fixed threshold the tangential problem is the same kind of problem as
/// the normal one, a bound on a force that does not move, and the sweep becomes a
/// primal-dual active-set step in both directions: a sticking tangent held at 10 r, an
/// open node's slipping one free (r / 1000, settled r / 10^4), a pressed node's slipping
/// one at r / 10. Otherwise a tangent keeps r / 10 until every status has settled, and a
/// slip zone is found a node a sweep, or collapses when the settled retune stiffens its
/// sticking tangents and grows back: a held-out Tresca bridge (`make_cases.py --slender
/// --scale 0.7`, threshold 0.3 times the Coulomb answer's coefficient times its mean
/// pressure) went from 133 slipping nodes to 45 at sweep 29 and back to 121 by sweep
/// 96, 109 sweeps in all; its tangents following, 45.
///
/// Not under Coulomb: the thresholds move with the pressures, and tangents retuned at
/// every status change cycle (see [`retuned`]). Not while at most one node is pressed:
/// a body in the air, or standing on one node, is held along the foundation by its open
/// nodes' thresholds alone, and with their tangents following, tens of them flipped at
/// each retune (the thin tube of tests/data/tolerance, which stands on one node: 22 ->
/// 303 sweeps). Not once the retunes have cycled: the statuses then take the settled
/// rules. With the cycle's end retune instead, the held-out Tresca cantilevers of
/// `make_cases.py --scale 0.7` and `0.6` (threshold 0.3) did not converge in 10^4
/// sweeps (50 and 46 with the settled rules).
pub fn tangents_follow(fixed_thresholds: bool, pressed_nodes: usize, cycled: bool) -> bool {
    fixed_thresholds && pressed_nodes >= 2 && !cycled
}

/// What holds a contact node's directions, as its status in an image says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Held {
    /// The normal: pressed onto the foundation.
    pub n: bool,
    /// The tangent (with friction): sticking, below a positive slip threshold.
    pub t: bool,
    /// The tangent (with friction) has a zero slip threshold (an open node under
    /// Coulomb, a frictionless contact among frictional ones): no force acts on it at
    /// all. Tuned as a slipping tangent while the contact zone moves, as an open normal
    /// once the statuses have settled ([`SETTLED_FREE_FACTOR`]).
    pub loose: bool,
}

impl Held {
    pub fn new(n: bool, t: bool) -> Self {
        Held { n, t, loose: false }
    }

    /// Whether the tangent carries no force that a status sets, so that only its spring
    /// holds its motion: a loose one, and an open node's slipping one, whose force is the
    /// threshold, which no normal force sets (Tresca). A pressed node's slipping tangent
    /// is not free: its threshold follows the normal force (Coulomb) and its stick/slip
    /// status flips with it.
    pub fn free_tangent(self) -> bool {
        self.loose || (!self.n && !self.t)
    }
}

/// What [`retuned`] asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Retune {
    /// Each direction to the r its status asks for ([`tuned`]).
    ToStatus,
    /// Each normal to the r its status asks for, every tangent lowered (as if slipping)
    /// while the contact zone is still moving; free directions already lowered once the
    /// statuses settled stay so ([`Augmentation::for_statuses`]).
    Normals,
    /// The budget spent: the last retune, as a cycle's end with the statuses the last
    /// sweep changed as those that cycled ([`Augmentation::after_cycle`]).
    BudgetSpent,
    /// The statuses cycle (they began to at sweep `since`): the directions that did not
    /// change since keep their settled r (open nodes lowered, held normals raised), the
    /// others return to the reference r, the pressed tangents not below their floor
    /// ([`Augmentation::after_cycle`]); the last retune.
    EndCycle { since: usize },
    /// The settled statuses held and the loop contracts slowly: each direction to the r
    /// its status asks for, sticking tangents and free directions a further
    /// [`TAIL_FACTOR`] from the reference r ([`tail`]).
    Tail,
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
/// 54).
///
/// **Normals, at every sweep.** With held normals x 1000 and free ones / 1000, a sweep
/// pins the held nodes on the foundation and lets the free ones follow the body: it is
/// one step of a primal-dual active-set method, and the projection that follows moves
/// every node whose pressure came out negative or that went through the foundation. So
/// whenever some normal's r is not the one its status in the last image asks for, the
/// normals are retuned, at once. Waiting for the statuses to settle first (what the loop
/// did before) lets a body whose contact zone grows or shrinks node by node (a beam lying
/// down on a foundation) crawl: each node that joins or leaves the zone did so at the
/// reference r, a few sweeps each (measured: the 2 m clamped beam of
/// docs/performance-history.md, 364 sweeps, 39 with eager normals). Meanwhile every
/// tangent is lowered as if it slipped: the underside of a bending body stretches, and a
/// tangent held at the reference r holds the bending back (the Coulomb cantilever of
/// tests/data/tolerance at 12858 nodes: 203 sweeps with tangents at the reference r,
/// 90 lowered by 10; lowered by 100 or 1000 it did not converge).
///
/// **Tangents, once settled.** When the last [`SETTLED_SWEEPS`] + 1 sweeps (all with the
/// current r) changed no status and some tangent's r is not the one its stick or slip
/// status asks for, every direction goes to its status ([`Retune::ToStatus`]). Under
/// Coulomb the stick/slip statuses are not retuned eagerly: with r x 10 and / 10 they
/// cycle (block level 1 did not converge in 10000 sweeps; with a node's tangent kept at
/// the reference r after its second flip, the slender Coulomb cases took 300-1000
/// sweeps). Under Tresca they are, as part of the normals' retune, while
/// [`tangents_follow`] says so (`Sweep::mistuned_n` then counts the tangents too).
///
/// **Budget.** [`MAX_RETUNES`] - 1 retunes of these kinds; after them, if some direction
/// is still off the reference r, the last retune ([`Retune::BudgetSpent`]): at the
/// reference r in every direction, a strip that only its contact holds up, balanced on
/// a ridge (make_cases.py --obstacles, 13013 nodes, its zone shrinking at every sweep
/// until the budget was spent), sank onto its lowered open nodes and crept: 239 sweeps;
/// 118 as a cycle's end.
/// Nothing above [`MAX_RETUNE_DOFS`] contact dofs.
pub fn retuned(history: &[Sweep], frictional: bool, n_contact: usize) -> Option<Retune> {
    let last = history.last()?;
    if 2 * n_contact > MAX_RETUNE_DOFS || last.retunes >= MAX_RETUNES {
        return None;
    }
    let off_reference = last.stiff + last.soft > 0;
    if last.retunes + 1 == MAX_RETUNES {
        return off_reference.then_some(Retune::BudgetSpent);
    }
    // Once retuned back to the reference r in every direction, none again.
    if last.retunes > 0 && !off_reference {
        return None;
    }
    if let Some(since) = cycle_start(history) {
        return off_reference.then_some(Retune::EndCycle { since });
    }
    if last.mistuned_n > 0 {
        return Some(Retune::Normals);
    }
    let settled = SETTLED_SWEEPS + usize::from(frictional);
    // With friction, free directions ask for it too once some node is pressed (before
    // the first touch their springs keep a sweep from throwing the body through the
    // foundation).
    let wanted = last.mistuned > 0 || (frictional && last.active > 0 && last.unsettled > 0);
    if !wanted || history.len() < settled {
        return None;
    }
    let tail = &history[history.len() - settled..];
    tail.iter()
        .all(|s| s.changed == 0 && s.retunes == last.retunes)
        .then_some(Retune::ToStatus)
}

/// Returns to one set of statuses, each after the retunes had left it for another, after
/// which the retunes count as cycling ([`cycling`]). Measured on the held-out shallow
/// arch (Coulomb), whose statuses alternated between two sets at every retune until the
/// budget was spent: 179 sweeps, 100 retunes; with 3 returns 83, 20 retunes. 2 returns
/// also stopped the thin tube with Tresca friction, whose statuses came back twice on the
/// way and then settled: 198 -> 4071 sweeps at the reference r. No other case measured
/// (the held-out, slender, beam and built-in cases) meets either.
const CYCLE_RETURNS: usize = 3;

/// Whether the retunes cycle, and if so the sweep where the cycle began: the last
/// sweep's statuses ([`Sweep::pattern`]) are a set that earlier retunes were made from
/// and left [`CYCLE_RETURNS`] times; the cycle began at the first of those retunes' sweeps.
/// A retune made twice from one set in a row (the normals', then the settled one) counts
/// once.
fn cycle_start(history: &[Sweep]) -> Option<usize> {
    let last = history.last()?;
    // The statuses each retune was made from, with its sweep, repeats in a row merged.
    let mut from: Vec<(u64, usize)> = Vec::new();
    for w in history.windows(2) {
        if w[1].retunes > w[0].retunes && from.last().map(|f| f.0) != Some(w[0].pattern) {
            from.push((w[0].pattern, w[0].iter));
        }
    }
    let mut visits = from.iter().filter(|f| f.0 == last.pattern);
    let first = visits.next()?.1;
    // Still on the set the last retune was made from: that visit is not a return.
    let returns = match from.last().map(|f| f.0) == Some(last.pattern) {
        true => visits.count(),
        false => visits.count() + 1,
    };
    (returns >= CYCLE_RETURNS).then_some(first)
}

/// Contact dofs (two per contact node, over all ranks) above which r is not retuned. The
/// first retune refactors the dense contact blocks, about c^3 / 3 flops for c contact
/// dofs, which costs as much as 30-80 sweeps (measured: hertz, frictionless, one rank:
/// 28, 38, 62, 78, 80 sweeps at c = 222, 440, 878, 1756, 3508; 0.5 s at c = 3508, 1.2 s
/// on two ranks); the later ones move a few directions and update the factor in place
/// (`LocalFactor::update_boundary`) for a fraction of that. Up to 2048 a retune takes at
/// most about 0.1 s, negligible next to the factorization; above, the seconds it takes
/// exceed what the sweeps it saves cost, and Anderson mixing alone is faster.
const MAX_RETUNE_DOFS: usize = 2048;

#[cfg(test)]
mod tests {
    use super::*;

    /// An open node under Coulomb: no threshold, its tangent carries no force.
    const OPEN: Held = Held {
        n: false,
        t: false,
        loose: true,
    };

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
            mistuned_n: 0,
            unsettled: 0,
            uncertain: 0,
            pattern: 0,
            retunes,
            refused: 0,
            roundoff: 0.0,
        }
    }

    #[test]
    fn statuses_that_the_retunes_keep_returning_to_end_the_retunes() {
        // Sweeps with statuses `p`, each followed by a retune, r off the reference.
        let run = |patterns: &[u64]| -> Vec<Sweep> {
            (patterns.iter().enumerate())
                .map(|(k, &p)| Sweep {
                    iter: k + 1,
                    pattern: p,
                    stiff: 3,
                    mistuned_n: 1,
                    ..sweep(1, 1, k)
                })
                .collect()
        };
        // Two sets in turn: the fourth visit of one is its third return.
        let cycle = run(&[1, 2, 1, 2, 1, 2]);
        assert_eq!(retuned(&cycle, true, 5), Some(Retune::Normals));
        let cycle = run(&[3, 1, 2, 1, 2, 1, 2, 1]);
        // The cycle began at the first retune made from the set returned to.
        assert_eq!(
            retuned(&cycle, true, 5),
            Some(Retune::EndCycle { since: 2 })
        );
        // A retune made twice from one set in a row (normals, then settled) is one visit.
        let settling = run(&[1, 1, 2, 2, 1, 1, 3, 1, 1]);
        assert_eq!(retuned(&settling, true, 5), Some(Retune::Normals));
        // Back at the reference r, no retune again.
        let mut back = cycle.clone();
        back.push(Sweep {
            stiff: 0,
            ..back[back.len() - 1]
        });
        back.last_mut().unwrap().retunes += 1;
        assert_eq!(retuned(&back, true, 5), None);
    }

    #[test]
    fn normals_follow_their_statuses_at_once() {
        let mut moving = sweep(3, 4, 0);
        moving.mistuned_n = 2;
        // Even while statuses change, with or without friction.
        assert_eq!(retuned(&[moving], false, 5), Some(Retune::Normals));
        assert_eq!(retuned(&[moving], true, 5), Some(Retune::Normals));
        // Not above the dofs whose first retune costs more than it saves.
        assert_eq!(retuned(&[moving], false, MAX_RETUNE_DOFS), None);
    }

    #[test]
    fn tangents_are_tuned_once_the_statuses_have_settled() {
        // Normals right, tangents not (mistuned counts both kinds).
        let (moving, still) = (sweep(2, 5, 0), sweep(0, 5, 0));
        assert_eq!(retuned(&[moving, still], true, 5), None);
        assert_eq!(
            retuned(&[moving, still, still], true, 5),
            Some(Retune::ToStatus)
        );
        assert_eq!(retuned(&[still, moving], true, 5), None);
        // Nothing to change.
        assert_eq!(
            retuned(&[still, sweep(0, 0, 0), sweep(0, 0, 0)], true, 5),
            None
        );
        // The settled sweeps must all be with the current r.
        let after = Sweep {
            stiff: 3,
            ..sweep(0, 3, 1)
        };
        assert_eq!(retuned(&[still, after], true, 5), None);
        assert_eq!(
            retuned(&[still, after, after], true, 5),
            Some(Retune::ToStatus)
        );
    }

    #[test]
    fn free_directions_settle_once_the_body_touches_with_friction() {
        // Nothing mistuned (every pressed node slips), but free directions not yet
        // lowered: settle once some node is pressed and the statuses rest.
        let mut still = sweep(0, 0, 0);
        still.unsettled = 4;
        assert_eq!(
            retuned(&[still, still, still], true, 5),
            Some(Retune::ToStatus)
        );
        // Not without friction (the frictionless half ring of make_cases.py --heldout
        // went from 178 to 1538 sweeps), nor before the first touch.
        assert_eq!(retuned(&[still, still, still], false, 5), None);
        still.active = 0;
        assert_eq!(retuned(&[still, still, still], true, 5), None);
    }

    #[test]
    fn held_directions_are_at_least_as_stiff_as_the_mesh_asks() {
        // A reference r lowered far below the mesh-scale stiffness (a slender body):
        // held directions rise to their floors, free ones stay below the reference.
        let (r, k) = (1.0, 1e6);
        let (n, t) = tuned(Held::new(true, true), true, r, k, Rules::MOVING);
        assert_eq!((n, t), (HELD_NORMAL_FLOOR * k, HELD_TANGENT_FLOOR * k));
        assert_eq!(
            tuned(Held::new(false, false), true, r, k, Rules::MOVING),
            (r / NORMAL_FACTOR, r / TANGENT_FACTOR)
        );
        // A compact body's reference r: the factors already exceed the floors.
        let r = 1e5;
        assert_eq!(
            tuned(Held::new(true, true), true, r, 1e6, Rules::MOVING),
            (r * NORMAL_FACTOR, r * TANGENT_FACTOR)
        );
        assert_eq!(largest_tuned(r, 1e6), r * NORMAL_FACTOR);
        assert_eq!(largest_tuned(1.0, 1e6), HELD_NORMAL_FLOOR * 1e6);
        // Without friction the tangent keeps the reference r, floor or not.
        assert_eq!(
            tuned(Held::new(true, true), false, 1.0, k, Rules::MOVING).1,
            1.0
        );
    }

    #[test]
    fn after_the_budget_every_direction_returns_once_to_the_reference() {
        let mut spent = sweep(1, 3, MAX_RETUNES - 1);
        spent.mistuned_n = 3;
        spent.stiff = 2;
        assert_eq!(
            retuned(&[spent, spent], false, 5),
            Some(Retune::BudgetSpent)
        );
        // Already at the reference r: nothing to undo.
        spent.stiff = 0;
        assert_eq!(retuned(&[spent, spent], false, 5), None);
        let mut reset = sweep(1, 3, MAX_RETUNES);
        reset.mistuned_n = 3;
        assert_eq!(retuned(&[reset, reset], false, 5), None);
    }

    #[test]
    fn free_directions_are_lowered_further_once_settled() {
        let r = 10.0;
        // While the zone moves, as before: the normal / 1000, the tangent as slipping.
        assert_eq!(
            tuned(OPEN, true, r, 0.0, Rules::MOVING),
            (r / NORMAL_FACTOR, r / TANGENT_FACTOR)
        );
        let settled = r / SETTLED_FREE_FACTOR;
        assert_eq!(
            tuned(OPEN, true, r, 0.0, Rules::SETTLED),
            (settled, settled)
        );
        // An open node slipping under Tresca: its force is the threshold, its motion
        // free, so its tangent goes as low.
        let open_tresca = Held::new(false, false);
        assert_eq!(
            tuned(open_tresca, true, r, 0.0, Rules::MOVING),
            (r / NORMAL_FACTOR, r / TANGENT_FACTOR)
        );
        assert_eq!(
            tuned(open_tresca, true, r, 0.0, Rules::SETTLED),
            (settled, settled)
        );
        // Held directions, and a pressed node's slipping tangent, keep their factors; so
        // does an open node's sticking tangent.
        assert_eq!(
            tuned(Held::new(true, true), true, r, 0.0, Rules::SETTLED),
            (r * NORMAL_FACTOR, r * TANGENT_FACTOR)
        );
        assert_eq!(
            tuned(Held::new(true, false), true, r, 0.0, Rules::SETTLED).1,
            r / TANGENT_FACTOR
        );
        assert_eq!(
            tuned(Held::new(false, true), true, r, 0.0, Rules::SETTLED),
            (settled, r * TANGENT_FACTOR)
        );
        // Settling is what the tangents' retune does; the normals' keeps it.
        let held = [
            OPEN,
            Held::new(true, true),
            open_tresca,
            Held::new(true, false),
        ];
        let a = Augmentation::for_statuses(Retune::Normals, &held, true, (r, 0.0), false, false);
        assert_eq!(a.r_n[..2], [r / NORMAL_FACTOR, r * NORMAL_FACTOR]);
        assert_eq!(a.r_t, vec![r / TANGENT_FACTOR; 4]);
        assert!(!a.settled);
        let a = Augmentation::for_statuses(Retune::ToStatus, &held, true, (r, 0.0), false, false);
        assert!(a.settled);
        assert_eq!(a.r_n[..2], [settled, r * NORMAL_FACTOR]);
        // From settled r, the normals' retune keeps the free directions lowered (the open
        // nodes' normals and tangents) and lowers the pressed nodes' tangents, sticking
        // or not, as while the zone moves.
        let a = Augmentation::for_statuses(Retune::Normals, &held, true, (r, 0.0), true, false);
        assert!(a.settled);
        assert_eq!(
            a.r_n,
            vec![settled, r * NORMAL_FACTOR, settled, r * NORMAL_FACTOR]
        );
        let loose = r / TANGENT_FACTOR;
        assert_eq!(a.r_t, vec![settled, loose, settled, loose]);
        // What the sweep then counts as mistuned: only the sticking tangent.
        for (i, &h) in held.iter().enumerate() {
            let want = a.tuned(h, true, r, 0.0);
            assert_eq!(want.0, a.r_n[i], "node {i}");
            assert_eq!(want.1 == a.r_t[i], i != 1, "node {i}");
        }
    }

    #[test]
    fn statuses_ask_for_their_r() {
        let r = 10.0;
        assert_eq!(
            tuned(Held::new(true, false), true, r, 0.0, Rules::MOVING),
            (r * NORMAL_FACTOR, r / TANGENT_FACTOR)
        );
        assert_eq!(
            tuned(Held::new(false, true), true, r, 0.0, Rules::MOVING),
            (r / NORMAL_FACTOR, r * TANGENT_FACTOR)
        );
        // Without friction the tangent keeps the reference r.
        assert_eq!(
            tuned(Held::new(true, false), false, r, 0.0, Rules::MOVING),
            (r * NORMAL_FACTOR, r)
        );
        // Normals alone: tangents lowered with friction, kept without.
        let held = [Held::new(true, true), Held::new(false, true)];
        let a = Augmentation::for_statuses(Retune::Normals, &held, true, (r, 0.0), false, false);
        assert_eq!(a.r_n, vec![r * NORMAL_FACTOR, r / NORMAL_FACTOR]);
        assert_eq!(a.r_t, vec![r / TANGENT_FACTOR; 2]);
        let a = Augmentation::for_statuses(Retune::Normals, &held, false, (r, 0.0), false, false);
        assert_eq!(a.r_t, vec![r; 2]);
    }

    #[test]
    fn tangents_that_follow_take_their_statuses_r_at_each_normals_retune() {
        let r = 10.0;
        // Pressed sticking, pressed slipping, open sticking, open slipping (Tresca: every
        // node has its threshold).
        let held = [
            Held::new(true, true),
            Held::new(true, false),
            Held::new(false, true),
            Held::new(false, false),
        ];
        let moving_free = r / NORMAL_FACTOR;
        let a = Augmentation::for_statuses(Retune::Normals, &held, true, (r, 0.0), false, true);
        assert!(a.follow_tangents && !a.settled);
        let stick = r * TANGENT_FACTOR;
        assert_eq!(a.r_t, vec![stick, r / TANGENT_FACTOR, stick, moving_free]);
        // Not following: every tangent at r / 10 while the zone moves.
        let b = Augmentation::for_statuses(Retune::Normals, &held, true, (r, 0.0), false, false);
        assert_eq!(b.r_t, vec![r / TANGENT_FACTOR; 4]);
        assert_eq!(a.r_n, b.r_n);
        // Settled, the open slipping tangent lowered further, the others as before.
        let c = Augmentation::for_statuses(Retune::ToStatus, &held, true, (r, 0.0), false, true);
        let settled = r / SETTLED_FREE_FACTOR;
        assert_eq!(c.r_t, vec![stick, r / TANGENT_FACTOR, stick, settled]);
        // What the sweep counts as mistuned follows the same rules: nothing here.
        for (i, &h) in held.iter().enumerate() {
            assert_eq!(a.tuned(h, true, r, 0.0), (a.r_n[i], a.r_t[i]), "node {i}");
        }
        // A flip to stick is a mistuned tangent for the next normals' retune.
        assert_ne!(a.tuned(Held::new(true, true), true, r, 0.0).1, a.r_t[1]);
        // Without friction there is nothing to follow.
        let d = Augmentation::for_statuses(Retune::Normals, &held, false, (r, 0.0), false, true);
        assert!(!d.follow_tangents);
        assert_eq!(d.r_t, vec![r; 4]);
    }

    #[test]
    fn only_fixed_thresholds_with_two_pressed_nodes_follow_until_a_cycle() {
        assert!(tangents_follow(true, 2, false));
        assert!(tangents_follow(true, 500, false));
        assert!(
            !tangents_follow(true, 1, false),
            "a body standing on one node"
        );
        assert!(!tangents_follow(true, 0, false), "a body in the air");
        assert!(!tangents_follow(false, 500, false), "Coulomb");
        assert!(!tangents_follow(true, 500, true), "after a cycle");
    }

    #[test]
    fn a_cycle_returns_its_changing_normals_to_the_reference_and_keeps_the_rest() {
        let (r, stiffness) = (10.0, 1000.0);
        let held = [
            Held::new(true, true),
            OPEN,
            Held::new(true, false),
            OPEN,
            Held::new(true, false),
        ];
        // (any status, the normal) changed since the cycle began.
        let cycled = [
            (false, false),
            (false, false),
            (true, false),
            (true, true),
            (true, true),
        ];
        let a = Augmentation::after_cycle(&held, &cycled, true, r, stiffness);
        assert!(a.ended && a.settled);
        let floor = HELD_TANGENT_FLOOR * stiffness;
        let held_normal = tuned(held[2], true, r, stiffness, Rules::SETTLED).0;
        assert!(held_normal > r && floor > r);
        // Pressed nodes whose normal stayed pressed: held normal, tangent at the floor.
        assert_eq!((a.r_n[0], a.r_t[0]), (held_normal, floor));
        assert_eq!((a.r_n[2], a.r_t[2]), (held_normal, floor));
        // A node open through the cycle at its settled r.
        assert_eq!(
            (a.r_n[1], a.r_t[1]),
            tuned(OPEN, true, r, stiffness, Rules::SETTLED)
        );
        assert_eq!(a.r_n[1], r / SETTLED_FREE_FACTOR);
        // Normals that cycled at the reference r; an open node that cycled entirely so.
        assert_eq!((a.r_n[3], a.r_t[3]), (r, r));
        assert_eq!((a.r_n[4], a.r_t[4]), (r, floor));
        // Without friction the tangents are not used; below the floor's scale the
        // reference r stands.
        let b = Augmentation::after_cycle(&held, &cycled, false, r, 0.0);
        assert_eq!(b.r_t, vec![r; 5]);
        assert_eq!(b.r_n[0], tuned(held[0], false, r, 0.0, Rules::SETTLED).0);
    }

    #[test]
    fn the_slow_tail_widens_the_tangents_and_free_factors_until_a_status_changes() {
        let r = 10.0;
        let tail_rules = Rules {
            tail: true,
            ..Rules::SETTLED
        };
        let pressed_sticking = Held::new(true, true);
        let (n, t) = tuned(pressed_sticking, true, r, 0.0, Rules::SETTLED);
        assert_eq!(
            tuned(pressed_sticking, true, r, 0.0, tail_rules),
            (n, t * TAIL_FACTOR),
            "the held normal keeps its r: it sets the round-off"
        );
        // The tangent's floor is widened too, up to the held normals' r, which sets the
        // round-off.
        let stiff = 1e3;
        let (_, t) = tuned(pressed_sticking, true, r, stiff, Rules::SETTLED);
        assert_eq!(t, HELD_TANGENT_FLOOR * stiff);
        assert_eq!(
            tuned(pressed_sticking, true, r, stiff, tail_rules).1,
            t * TAIL_FACTOR
        );
        let very_stiff = 1e6;
        assert_eq!(
            tuned(pressed_sticking, true, r, very_stiff, tail_rules),
            (largest_tuned(r, very_stiff), largest_tuned(r, very_stiff))
        );
        let settled = r / SETTLED_FREE_FACTOR;
        assert_eq!(
            tuned(OPEN, true, r, 0.0, tail_rules),
            (settled / TAIL_FACTOR, settled / TAIL_FACTOR)
        );
        // A pressed node's slipping tangent keeps r / 10: its threshold follows the
        // pressure.
        let pressed_slipping = Held::new(true, false);
        assert_eq!(
            tuned(pressed_slipping, true, r, 0.0, tail_rules).1,
            r / TANGENT_FACTOR
        );
        // Not while the zone moves.
        let moving_tail = Rules {
            tail: true,
            ..Rules::MOVING
        };
        assert_eq!(
            tuned(OPEN, true, r, 0.0, moving_tail),
            tuned(OPEN, true, r, 0.0, Rules::MOVING)
        );

        let held = [pressed_sticking, OPEN];
        let settled_aug =
            Augmentation::for_statuses(Retune::ToStatus, &held, true, (r, 0.0), false, false);
        let slow = |changed: usize, retunes: usize| Sweep {
            contraction: 0.9,
            ..sweep(changed, 0, retunes)
        };
        let quiet = [slow(3, 4), slow(0, 5), slow(0, 5)];
        assert!(tail(&quiet, &settled_aug, 0));
        assert!(
            !tail(&quiet, &settled_aug, MAX_TAIL_RETUNES),
            "the allowance spent"
        );
        assert!(!tail(&quiet[..2], &settled_aug, 0), "one quiet sweep only");
        assert!(
            !tail(&[slow(0, 4), slow(0, 5), slow(0, 5)][..2], &settled_aug, 0),
            "the sweep before was made with another r"
        );
        let fast = [slow(3, 4), sweep(0, 0, 5), sweep(0, 0, 5)];
        assert!(!tail(&fast, &settled_aug, 0), "contracting by 0.5");
        let mistuned = [
            slow(3, 4),
            slow(0, 5),
            Sweep {
                mistuned: 2,
                ..slow(0, 5)
            },
        ];
        assert!(!tail(&mistuned, &settled_aug, 0));
        let moving =
            Augmentation::for_statuses(Retune::Normals, &held, true, (r, 0.0), false, false);
        assert!(!tail(&quiet, &moving, 0), "not settled");
        let in_tail = Augmentation::for_statuses(Retune::Tail, &held, true, (r, 0.0), true, false);
        assert!(in_tail.tail && in_tail.settled);
        assert!(!tail(&quiet, &in_tail, 1), "already the tail's r");
        assert_eq!(in_tail.r_n[0], settled_aug.r_n[0]);
        assert_eq!(in_tail.r_t[0], settled_aug.r_t[0] * TAIL_FACTOR);
        assert_eq!(in_tail.r_n[1], settled_aug.r_n[1] / TAIL_FACTOR);
        // A status change: the normals' retune that follows is not the tail's.
        let after = Augmentation::for_statuses(Retune::Normals, &held, true, (r, 0.0), true, false);
        assert!(!after.tail);
        assert_eq!(after.r_n[1], settled_aug.r_n[1]);
        // The budget's last retune stays the return to the reference r.
        let late = [slow(0, MAX_RETUNES - 1), slow(0, MAX_RETUNES - 1)];
        assert!(!tail(&late, &settled_aug, 0));
    }
}
