//! The command line: a run's options and `contact-par split`'s, parsed by clap into the
//! types the library reads (`main.rs` flattens them into its parser, no copies).

use crate::case::{self, Case};
use crate::contact::{Acceleration, CoulombMode, DEFAULT_ANDERSON_MEMORY};
use crate::error::{Error, Result};
use crate::linear::Ordering;
use clap::builder::RangedU64ValueParser;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Which case: a case file, or a built-in case at a refinement level.
#[derive(clap::Args, Debug, Clone)]
pub struct CaseArgs {
    /// Case file (TOML). Without it, the built-in case given by --builtin runs.
    pub case: Option<PathBuf>,
    /// Built-in case to run when no case file is given: hertz, block, block_flat, punch, cylinders.
    #[arg(long, default_value = "hertz")]
    pub builtin: String,
    /// Refinement level of the built-in case (each level halves the mesh size).
    #[arg(long, default_value_t = 1)]
    pub level: u32,
}

impl CaseArgs {
    /// The case file, or without one the built-in case.
    pub fn case(&self) -> Result<Case> {
        match &self.case {
            Some(path) => case::read_case(path),
            None => case::builtin_case(&self.builtin, self.level),
        }
    }

    /// How the case is named on a command line.
    pub fn command_line(&self) -> String {
        match &self.case {
            Some(p) => p.display().to_string(),
            None => format!("--builtin {} --level {}", self.builtin, self.level),
        }
    }
}

/// What a run is asked for.
#[derive(clap::Args, Debug, Clone)]
pub struct Options {
    #[command(flatten)]
    pub case: CaseArgs,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    /// Also write nodes.csv (x,y,ux,uy for every node).
    #[arg(long)]
    pub nodes_csv: bool,
    /// Draw no pictures (contact.png, convergence.png); those of an earlier run in the
    /// output directory are removed.
    #[arg(long)]
    pub no_plots: bool,
    /// Print nothing but errors and warnings: no first line, phase lines, monitor lines
    /// or final table.
    #[arg(long)]
    pub quiet: bool,
    /// Override solver.r (augmentation parameter).
    #[arg(long)]
    pub r: Option<f64>,
    /// Override solver.tol.
    #[arg(long)]
    pub tol: Option<f64>,
    /// Override solver.max_iter.
    #[arg(long)]
    pub max_iter: Option<usize>,
    /// Override solver.coulomb: inner (threshold refreshed every sweep) or outer.
    #[arg(long, value_parser = parse_coulomb)]
    pub coulomb: Option<CoulombMode>,
    /// Override solver.acceleration: anderson (default) or none (plain ALG2).
    #[arg(long, value_parser = parse_acceleration)]
    pub acceleration: Option<Acceleration>,
    /// Fill-reducing ordering of each subdomain: auto (default: gnd), gnd (nested
    /// dissection by straight cuts from the nodes' positions: about the least fill, as
    /// fast as amd), amd (minimum degree) or nd (METIS nested dissection: the least
    /// fill, a slower ordering).
    #[arg(long, default_value = "auto", value_parser = parse_ordering)]
    pub ordering: Ordering,
    /// Where the interface system is factored and solved: rank0 (summed and factored on
    /// the first rank), mumps (assembled where its parts are and factored across the
    /// ranks by MUMPS, solved with distributed right-hand side and solution) or auto
    /// (default: mumps from 16 subdomains on).
    #[arg(long, value_enum, default_value_t = InterfaceMode::Auto, hide_possible_values = true)]
    pub interface: InterfaceMode,
    /// Save the loop state every N sweeps in OUT/checkpoint/ (atomically).
    #[arg(long, default_value_t = 0)]
    pub checkpoint_every: usize,
    /// Resume from OUT/checkpoint/ (same case, same number of ranks).
    #[arg(long)]
    pub restart: bool,
    /// Print a monitor line every K sweeps.
    #[arg(long, default_value_t = 10)]
    pub monitor_every: usize,
    /// Threads per rank (assembly, factorization, sweep); default: the cores this rank
    /// may run on / the ranks on its node.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Whether the first rank runs its work alone (the read and partition of a mesh
    /// file, the interface system's factorization) on the cores of its node's ranks
    /// while they sleep, also where each rank is bound to a core of its own; false keeps
    /// every rank to its own threads (to measure that work on one core).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub borrow_idle_cores: bool,
    /// Subdomains per rank, each factored and swept on a thread of its own; default:
    /// one per thread of the rank while each keeps 5000 triangles and the job has at
    /// most 8 subdomains, else fewer (1 for --linear full). 1 gives a rank one
    /// subdomain whose factorization uses its threads.
    #[arg(long, value_parser = RangedU64ValueParser::<usize>::new().range(1..))]
    pub subdomains_per_rank: Option<usize>,
    /// Linear solve in the loop: condensed (default) or full (one rank only, for
    /// comparison: a sparse forward and backward solve per sweep).
    #[arg(long, value_enum, default_value_t = LinearMode::Condensed, hide_possible_values = true)]
    pub linear: LinearMode,
    /// A directory written by `contact-par split`: each subdomain reads its own part
    /// there, and no rank reads the whole mesh. The ranks must divide its parts (each
    /// runs parts / ranks subdomains).
    #[arg(long, value_name = "DIR")]
    pub mesh_split: Option<PathBuf>,
    /// How the first rank cuts a mesh read from one file into subdomains: geometric
    /// (recursive straight cuts through the triangles' centroids, refined; METIS where
    /// a part would be in pieces), metis (the dual graph coarsened, METIS, refined back)
    /// or auto (default: geometric). The partition line names the method used.
    #[arg(long, value_enum, default_value_t = Partitioner::Auto, hide_possible_values = true)]
    pub partitioner: Partitioner,
}

impl Options {
    /// The case with the command line's overrides of its solver settings.
    pub fn load_case(&self) -> Result<Case> {
        let mut case = self.case.case()?;
        case::override_solver(&mut case, self.r, self.tol, self.max_iter, self.coulomb)?;
        if let Some(acc) = self.acceleration {
            case.solver.acceleration = acc;
        }
        Ok(case)
    }

    /// Refuses options that cannot run on `ranks` ranks.
    pub fn check(&self, ranks: usize) -> Result<()> {
        let several = ranks > 1 || self.subdomains_per_rank.is_some_and(|k| k > 1);
        if self.linear == LinearMode::Full && several {
            return Err(Error::Input(
                "--linear full runs on one rank and one subdomain only; use the default (condensed) with mpirun or --subdomains-per-rank"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// What `contact-par split` is asked for.
#[derive(clap::Args, Debug, Clone)]
pub struct SplitOptions {
    #[command(flatten)]
    pub case: CaseArgs,
    /// Number of parts: the subdomains of the runs (ranks x subdomains per rank).
    #[arg(long, value_parser = RangedU64ValueParser::<usize>::new().range(1..))]
    pub parts: usize,
    /// Directory of the part files and their manifest (split.json).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// How the mesh is cut, as in a run: geometric, metis or auto (default: geometric).
    #[arg(long, value_enum, default_value_t = Partitioner::Auto, hide_possible_values = true)]
    pub partitioner: Partitioner,
}

/// How the first rank cuts the mesh's dual graph into subdomains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Partitioner {
    /// [`Partitioner::Geometric`].
    Auto,
    /// Recursive straight cuts through the triangles' centroids, refined
    /// (`partition::MeshGraph::cut_straight`): edge cuts within a few percent of
    /// METIS's at a fraction of its cost; METIS where they leave a part in pieces.
    Geometric,
    /// The graph coarsened, METIS on the coarsest, refined back (the `partition` crate).
    Metis,
}

impl Partitioner {
    /// Whether straight cuts are tried before METIS.
    pub fn straight_first(self) -> bool {
        self != Partitioner::Metis
    }
}

/// Where the interface system (the subdomains' condensed parts, summed) is factored and
/// solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum InterfaceMode {
    /// [`InterfaceMode::Mumps`] from [`AUTO_MUMPS_SUBDOMAINS`] subdomains on, else
    /// [`InterfaceMode::Rank0`].
    Auto,
    /// Gathered, summed and factored on the first rank, which solves each sweep.
    #[value(name = "rank0")]
    Rank0,
    /// Assembled where its parts are and factored across the ranks by MUMPS.
    Mumps,
}

/// Subdomains from which `--interface auto` takes MUMPS: from there the first rank's
/// dense interface factor outgrows every subdomain's (work and memory).
pub const AUTO_MUMPS_SUBDOMAINS: usize = 16;

impl InterfaceMode {
    /// The mode a job of `subdomains` subdomains runs with.
    pub fn resolved(self, subdomains: usize) -> InterfaceMode {
        match self {
            InterfaceMode::Auto if subdomains >= AUTO_MUMPS_SUBDOMAINS => InterfaceMode::Mumps,
            InterfaceMode::Auto => InterfaceMode::Rank0,
            chosen => chosen,
        }
    }
}

/// How step 1 of the method (the linear solve) is made inside the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LinearMode {
    /// Condensed onto the contact dofs: one small dense product per sweep (default).
    Condensed,
    /// A full sparse forward and backward solve per sweep (one rank; for comparison).
    Full,
}

fn parse_ordering(s: &str) -> std::result::Result<Ordering, String> {
    match s {
        "auto" => Ok(Ordering::Auto),
        "amd" => Ok(Ordering::Amd),
        "nd" => Ok(Ordering::NestedDissection),
        "gnd" => Ok(Ordering::Geometric),
        _ => Err(format!("\"{s}\" is not auto, amd, nd or gnd")),
    }
}

fn parse_acceleration(s: &str) -> std::result::Result<Acceleration, String> {
    case::parse_acceleration(s, DEFAULT_ANDERSON_MEMORY)
        .ok_or_else(|| format!("\"{s}\" is not anderson or none"))
}

fn parse_coulomb(s: &str) -> std::result::Result<CoulombMode, String> {
    case::parse_coulomb_mode(s).ok_or_else(|| format!("\"{s}\" is not inner or outer"))
}
