//! Phases 1-2, the set-up: the case read and checked, and the facts every subdomain
//! starts from, computed once on the first rank ([`Setup`]); from a mesh file or a
//! built-in mesh the first rank also reads and cuts the problem (`from_file`), from a
//! split directory each subdomain later reads its own part (`split_dir`).

pub mod from_file;
pub mod split_dir;

use crate::case::Case;
use crate::contact::{self, operators::ContactDofs};
use crate::dd::comm::Mpi;
use crate::dd::full::DirectSystem;
use crate::dd::split::SubProblem;
use crate::dd::step::StepSetup;
use crate::error::{Error, Result};
use crate::fem::{Material, Materials};
use crate::host;
use crate::linear::Ordering;
use crate::options::{InterfaceMode, LinearMode, Options};
use crate::problem::{contact_modulus, Problem};
use crate::run::Printer;
use crate::timer::Timer;
use serde::{Deserialize, Serialize};
use split_dir::{Facts, Split};

pub use from_file::load_mesh;

/// The MPI ranks of the run, the threads of each, and whether MPI lets a rank run
/// subdomains on threads of their own.
#[derive(Clone, Copy)]
pub struct Layout {
    pub ranks: usize,
    /// The rank's own, not those of the pool the set-up borrows.
    pub threads: usize,
    pub funneled: bool,
}

impl Layout {
    pub fn of(mpi: &Mpi) -> Self {
        Layout {
            ranks: mpi.size,
            threads: rayon::current_num_threads(),
            funneled: mpi.funneled,
        }
    }
}

/// Phases 1-2, collective: on the first rank, the set-up and (from a mesh file or a
/// built-in mesh) every subproblem; the other ranks sleep meanwhile, so that the cores
/// of those on its node are its to use.
pub fn read_and_split(
    opts: &Options,
    mpi: &Mpi,
    layout: Layout,
    timer: &Timer,
    print: &Printer,
) -> Result<(Option<Setup>, Option<Vec<SubProblem>>)> {
    let done = mpi.is_root().then(|| {
        host::on_idle_cores(mpi.node_ranks, || match &opts.mesh_split {
            Some(dir) => split_dir::setup(opts, dir, layout, timer, print).map(|s| (s, None)),
            None => from_file::setup(opts, layout, timer, print).map(|(s, p)| (s, Some(p))),
        })
    });
    mpi.barrier_sleeping();
    let (setup, subs) = mpi.agree(done.transpose())?.unzip();
    Ok((setup, subs.flatten()))
}

/// What the first rank tells every rank before the distribution: each fact of the run's
/// set-up, computed once.
#[derive(Serialize, Deserialize)]
pub struct Setup {
    pub case: Case,
    /// Each body's material, by body index.
    pub materials: Vec<Material>,
    pub r: f64,
    /// E_eff / h (`Lengths::mesh_stiffness`).
    pub mesh_stiffness: f64,
    /// Shift of the interface block of every local matrix (see `LocalFactor`).
    pub alpha: f64,
    /// The figures of the whole problem and its partition.
    pub facts: Facts,
    /// Where each subdomain reads its part (`--mesh-split`), or `None`: from the first.
    pub split: Option<Split>,
    pub ordering: Ordering,
    /// Where the interface system is factored, resolved for the run's subdomains.
    pub interface: InterfaceMode,
    /// Subdomains per rank.
    pub per_rank: usize,
    /// The run's first line.
    pub header: String,
}

impl Setup {
    /// The set-up of a run of `per_rank` subdomains on each rank of `layout` (refused
    /// where MPI cannot run them on threads: [`check_thread_level`]).
    fn new(
        opts: &Options,
        (case, facts): (Case, Facts),
        split: Option<Split>,
        layout: Layout,
        per_rank: usize,
    ) -> Result<Self> {
        check_thread_level(layout.funneled, per_rank)?;
        let e_eff = contact_modulus(&case, &facts.contact_bodies);
        // The interface shift scales with the stiffest body: any body's elements may
        // meet at an interface.
        let alpha = (case.materials.iter())
            .map(|b| b.material.young / (1.0 - b.material.poisson * b.material.poisson))
            .fold(f64::NEG_INFINITY, f64::max);
        let r = (case.solver.r).unwrap_or_else(|| facts.lengths.default_r(e_eff));
        Ok(Setup {
            header: header_line(&case, &facts, r, layout, per_rank),
            r,
            mesh_stiffness: facts.lengths.mesh_stiffness(e_eff),
            alpha,
            materials: case.material_table(),
            facts,
            split,
            ordering: opts.ordering,
            interface: opts.interface.resolved(layout.ranks * per_rank),
            per_rank,
            case,
        })
    }

    /// What every subdomain's condensed step shares.
    pub fn step(&self) -> StepSetup<'_> {
        StepSetup {
            materials: &self.materials,
            r: self.r,
            alpha: self.alpha,
            frictional: Problem::is_frictional(&self.case),
            n_interface: self.facts.n_interface,
            ordering: self.ordering,
            interface_mumps: self.interface == InterfaceMode::Mumps,
        }
    }

    /// The whole system of the uncondensed path: `sub` is the whole mesh.
    pub fn direct_system<'a>(&'a self, sub: &'a SubProblem) -> DirectSystem<'a> {
        DirectSystem {
            nodes: &sub.nodes,
            triangles: &sub.triangles,
            materials: Materials::PerElement {
                table: &self.materials,
                body: &sub.body,
            },
            fixed: &sub.fixed,
            load: &sub.load,
            contact: ContactDofs {
                nodes: &sub.contact_nodes,
                w: &sub.contact.w,
                normals: &sub.contact.normal,
                frictional: Problem::is_frictional(&self.case),
            },
            r: self.r,
        }
    }

    /// The parameters of the Uzawa loop.
    pub fn params(&self) -> contact::Params {
        let solver = &self.case.solver;
        contact::Params {
            r: self.r,
            tol: solver.tol,
            max_iter: solver.max_iter,
            friction: self.case.friction(),
            coulomb: solver.coulomb,
            acceleration: solver.acceleration,
            // A given r is the user's: kept as it is.
            adaptive: solver.r.is_none().then(contact::AdaptiveParams::default),
            mesh_stiffness: self.mesh_stiffness,
        }
    }
}

/// The first line of the run: the case, its size, its parameters, the layout.
fn header_line(case: &Case, size: &Facts, r: f64, layout: Layout, per_rank: usize) -> String {
    format!(
        "contact-par: {} | {} nodes, {} triangles, {} contact nodes | friction {} | r = {:e}, tol = {:e} | {} rank(s) x {} thread(s){}",
        if case.title.is_empty() { &case.origin } else { &case.title },
        size.nodes,
        size.elements,
        size.contact_nodes,
        case.friction_name(),
        r,
        case.solver.tol,
        layout.ranks,
        layout.threads,
        if per_rank > 1 {
            format!(" | {per_rank} subdomains per rank, one thread each")
        } else {
            String::new()
        }
    )
}

/// The uncondensed step assembles node-wise contact blocks only: it refuses a contact
/// with a master line (whose rows couple nodes of two bodies).
fn check_linear(opts: &Options, case: &Case) -> Result<()> {
    match case.contacts.iter().find(|c| c.master.is_some()) {
        Some(c) if opts.linear == LinearMode::Full => Err(Error::Input(format!(
            "command line: --linear full does not take a contact with a master line ({}: slave \"{}\"); drop --linear full (the default condensed step solves two bodies in contact)",
            case.origin, c.group
        ))),
        _ => Ok(()),
    }
}

/// Whether the thread support MPI granted suffices. Subdomain threads compute and wait
/// while their rank's main thread is inside MPI on their behalf: that is
/// MPI_THREAD_FUNNELED. With one subdomain per rank the rank's other threads (the
/// assembly's and the factorization's pools) run only between MPI calls, so the lowest
/// level, MPI_THREAD_SINGLE, serves; refusing it there would refuse runs that work.
fn check_thread_level(funneled: bool, per_rank: usize) -> Result<()> {
    if per_rank <= 1 || funneled {
        return Ok(());
    }
    Err(Error::Input(format!(
        "MPI granted the thread level MPI_THREAD_SINGLE, and {per_rank} subdomains per rank on threads of their own need MPI_THREAD_FUNNELED; run with --subdomains-per-rank 1, or use an MPI library built with thread support"
    )))
}

#[cfg(test)]
mod tests {
    use super::check_thread_level;

    #[test]
    fn a_single_threaded_mpi_is_refused_only_where_subdomain_threads_run() {
        assert_eq!(check_thread_level(true, 4), Ok(()));
        assert_eq!(check_thread_level(false, 1), Ok(()));
        let e = check_thread_level(false, 2).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let message = e.to_string();
        assert!(!message.contains('\n'));
        for part in [
            "MPI_THREAD_SINGLE",
            "MPI_THREAD_FUNNELED",
            "--subdomains-per-rank 1",
        ] {
            assert!(message.contains(part), "{message}");
        }
    }
}
