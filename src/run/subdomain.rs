//! What one subdomain's phases share, the lines it prints as they end, and its
//! solution with the figures of its factors.

use super::Printer;
use crate::contact::{tangent_of, Outcome, Reduce};
use crate::dd::comm::Mpi;
use crate::dd::local_factor::LocalFactor;
use crate::dd::split::SubProblem;
use crate::dd::step::CondensedStep;
use crate::fem::AssemblyFigures;
use crate::linear::Ordering;
use crate::options::Options;
use crate::setup::Setup;
use crate::timer::{self, Phase, Timer};

/// What one subdomain's phases share.
pub(super) struct Subdomain<'a> {
    pub(super) opts: &'a Options,
    /// The subdomain's own: `mpi.rank` is the subdomain, `mpi.mpi_rank` its MPI rank.
    pub(super) mpi: &'a Mpi,
    pub(super) setup: &'a Setup,
    /// The subdomain's own; the first subdomain's also holds the set-up's phases.
    pub(super) timer: &'a Timer,
    pub(super) print: &'a Printer,
    /// Bytes this subdomain's rank sent per sweep of the loop (all its subdomains').
    pub(super) sent_per_sweep: std::cell::Cell<f64>,
}

impl<'a> Subdomain<'a> {
    pub(super) fn new(
        opts: &'a Options,
        mpi: &'a Mpi,
        setup: &'a Setup,
        timer: &'a Timer,
        print: &'a Printer,
    ) -> Self {
        Subdomain {
            opts,
            mpi,
            setup,
            timer,
            print,
            sent_per_sweep: std::cell::Cell::new(0.0),
        }
    }

    /// The line of `phase`, which has just ended, with `figure`: printed by the first
    /// subdomain, whose timer the table at the end reads too.
    pub(super) fn phase_done(&self, phase: Phase, figure: impl AsRef<str>) {
        let seconds = self.timer.seconds(phase);
        self.print
            .line(timer::phase_line(phase, seconds, figure.as_ref()));
    }

    pub(super) fn assembled(&self, a: AssemblyFigures) {
        let of = match self.mpi.size {
            1 => String::new(),
            n => format!(" (the first of {n} subdomains)"),
        };
        self.phase_done(
            Phase::Assemble,
            format!(
                "{} equations, {} stored entries{of}",
                a.equations, a.entries
            ),
        );
    }

    /// The factorization's line: the work and size of every subdomain's factor, summed
    /// (collective).
    pub(super) fn factored(&self, flops: f64, entries: usize, ordering: Ordering) {
        let mut sums = [flops, entries as f64];
        self.mpi.sum_in_place(&mut sums);
        self.phase_done(
            Phase::Factor,
            format!(
                "{:.3} Gflop, {:.3e} factor entries in {} subdomain(s), {} ordering",
                sums[0] / 1e9,
                sums[1],
                self.mpi.size,
                ordering.name()
            ),
        );
    }

    /// The condensation's line: the interface system's size and its factor's work, over
    /// all subdomains (collective).
    pub(super) fn condensed(&self, step: &CondensedStep) {
        let mut sums = [step.interface_flops(), step.interface_entries()];
        self.mpi.sum_in_place(&mut sums);
        let facts = &self.setup.facts;
        let figure = match step.interface_factor() {
            Some(kind) => format!(
                "{} interface dofs, {kind} interface factor: {:.3} Gflop, {:.3e} entries",
                facts.n_interface,
                sums[0] / 1e9,
                sums[1]
            ),
            None => format!(
                "{} contact dofs, one subdomain (no interface)",
                facts.n_boundary
            ),
        };
        self.phase_done(Phase::Condense, figure);
    }
}

/// A subdomain's solution and the figures of its factors.
pub(super) struct Solved {
    pub(super) outcome: Outcome,
    /// Displacement of every node of the subdomain.
    pub(super) u: Vec<[f64; 2]>,
    pub(super) factors: FactorFigures,
}

impl Solved {
    /// Reports u_n and u_t of the recovered field `u` in `outcome` (frictionless sweeps
    /// do not compute u_t); for a mortar row, of the slave node relative to its masters.
    pub(super) fn new(
        sub: &SubProblem,
        mut outcome: Outcome,
        u: Vec<[f64; 2]>,
        factors: FactorFigures,
    ) -> Self {
        for (k, &node) in sub.contact_nodes.iter().enumerate() {
            let mut rel = u[node];
            for &(v, c) in sub.contact_masters.get(k).map_or(&[][..], |m| &m[..]) {
                rel = [rel[0] - c * u[v][0], rel[1] - c * u[v][1]];
            }
            let u = rel;
            let (m, t) = (sub.contact.normal[k], tangent_of(sub.contact.normal[k]));
            outcome.un[k] = -(m[0] * u[0] + m[1] * u[1]);
            outcome.ut[k] = t[0] * u[0] + t[1] * u[1];
        }
        Solved {
            outcome,
            u,
            factors,
        }
    }
}

/// Sizes and work of a subdomain's factorizations, for summary.json.
pub(super) struct FactorFigures {
    pub(super) nnz: usize,
    pub(super) flops: f64,
    pub(super) ordering: Ordering,
    /// "dense" or "sparse" where the interface system was factored.
    pub(super) interface: Option<&'static str>,
    pub(super) interface_flops: f64,
    pub(super) interface_entries: f64,
}

impl FactorFigures {
    pub(super) fn condensed(step: &CondensedStep) -> Self {
        let factor: &LocalFactor = step.factor();
        FactorFigures {
            nnz: factor.factor_nnz(),
            flops: factor.factor_flops(),
            ordering: factor.ordering,
            interface: step.interface_factor(),
            interface_flops: step.interface_flops(),
            interface_entries: step.interface_entries(),
        }
    }

    pub(super) fn full(nnz: usize, flops: f64) -> Self {
        FactorFigures {
            nnz,
            flops,
            ordering: Ordering::Amd,
            interface: None,
            interface_flops: 0.0,
            interface_entries: 0.0,
        }
    }
}
