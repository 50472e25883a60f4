//! contact-par: 2D elastic contact with a rigid foundation by Uzawa block relaxation.
//!
//! ```text
//! contact-par                          # the default built-in case (Hertz)
//! contact-par case.toml --out results  # a case file with a Gmsh mesh
//! mpirun -n 2 contact-par case.toml
//! ```
//! Exit codes: 0 converged, 2 bad input, 3 not converged (outputs written, marked so),
//! 4 numerical failure, 5 outputs could not be written.

use clap::Parser;
use contact_par::app::{self, InterfaceMode, LinearMode, MeshRead, Options, Partitioner, Printer};
use contact_par::case;
use contact_par::contact::{Acceleration, CoulombMode, DEFAULT_ANDERSON_MEMORY};
use contact_par::dd::comm::Mpi;
use contact_par::error::Error;
use contact_par::host;
use contact_par::linear::Ordering;
use mpi::Threading;
use std::path::PathBuf;

/// `--help`'s worked example of each output and of what a run prints, from
/// `contact-par --builtin hertz --level 1 --out ex1` (tests/cli.rs checks that every
/// sample has the shape of what the program writes and prints).
const OUTPUTS_HELP: &str = r#"Outputs, in --out DIR; a worked example: contact-par --builtin hertz --level 1 --out ex1

contact.csv: one row per contact node, sorted by x then y, with the index of its [[contact]]; numbers round-trip exactly
    x,y,u_n,u_t,p_n,p_t,gap,contact
    0,0,-0.0000000000000003219783990750409,0,7507.894399144059,0,0,0
    0.2052403205637102,0.0004212376662626599,0.0004212376662625075,-0.003400414774257441,7739.099958734696,0,0.0004212376662626599,0
history.csv: one row per sweep; retunes (of r) and refused_accelerations count up to it
    iteration,error_estimate,pressure_change,traction_change,displacement_change,contraction,active_nodes,slip_nodes,changed_nodes,uncertain_nodes,stiff_directions,soft_directions,retunes,refused_accelerations,roundoff_floor
    1,0.9999999999999399,0.9999999999999399,0,0.9999371161615976,0,10,0,10,111,0,0,0,0,0.00000000000006004561171114102
summary.json: the run's figures, among them
    "converged": true, "iterations": 9, "active_nodes": 17, "stick_nodes": null,
    "total_normal_force": 20178.66655210865, "r": 38623.28141784163, "r_retunes": 4,
    "refused_accelerations": 0, "timings_s": {"factor": 0.04532733, "loop": 0.00083076},
    "peak_memory_bytes": 32116736, "per_subdomain": [...]
contact.png: 1200 x 900 pixels: p_n, p_t (with friction) and u_n with the initial gap
    (dashed) against the position along the foundation, one colour per contact pair
convergence.png: 1200 x 700 pixels: the estimated error and the relative changes of
    p_n, p_t (with friction) and u per sweep on a log scale, tol (dashed), retunes of r
    (dashed verticals), refused accelerations (crosses); --no-plots: no pictures
solution.pvtu and solution_R_K.vtu: for ParaView (open the .pvtu)
nodes.csv, with --nodes-csv: x,y,ux,uy per node

Printed by rank 0 (--quiet: nothing but errors and warnings): the first line, a line per
phase as it ends (its seconds as the closing table shows them, and what it did), a
monitor line every --monitor-every sweeps, the outcome and the table:
    contact-par: Hertz line contact: quarter cylinder on a rigid plane (symmetry at x = 0) | 4839 nodes, 9408 triangles, 111 contact nodes | friction none | r = 3.862328141784163e4, tol = 1e-8 | 1 rank(s) x 2 thread(s)
    read      done in    0.002 s: built-in mesh (level 1): 4839 nodes, 9408 triangles, 111 contact nodes
    factor    done in    0.045 s: 0.059 Gflop, 6.581e5 factor entries in 1 subdomain(s), gnd ordering
          1  error 1.00e0  (p_n 1.0e0  u 1.0e0  rho 0.0000)  active     10
      r retuned per contact direction (raised on 10 held, lowered on 101 free), again whenever a status changes
          9  error 9.72e-10  (p_n 9.4e-10  u 0.0e0  rho 0.0342)  active     17
    loop      done in    0.001 s: 9 sweeps (0.092 ms each), converged
    output    done in    0.041 s: 7 files, 1.3 MB in ex1
    converged after 9 iterations: 17 active contact nodes, total normal force 20178.66655210865
With friction (--builtin block --level 1) p_t and the stick and slip counts are shown:
          1  error 1.00e0  (p_n 1.0e0  p_t 1.0e0  u 1.0e0  rho 0.0000)  active     81  stick     66  slip     15
"#;

#[derive(Parser, Debug)]
#[command(
    name = "contact-par",
    version,
    about = "2D elastic contact (frictionless, Tresca, Coulomb) with a rigid foundation, Uzawa block relaxation, on one core or many MPI ranks",
    after_long_help = OUTPUTS_HELP,
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Case file (TOML). Without it, the built-in case given by --builtin runs.
    case: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Also write nodes.csv (x,y,ux,uy for every node).
    #[arg(long)]
    nodes_csv: bool,
    /// Draw no pictures (contact.png, convergence.png); those of an earlier run in the
    /// output directory are removed.
    #[arg(long)]
    no_plots: bool,
    /// Print nothing but errors and warnings: no first line, phase lines, monitor lines
    /// or final table.
    #[arg(long)]
    quiet: bool,
    /// Built-in case to run when no case file is given: hertz, block, block_flat, punch, cylinders.
    #[arg(long, default_value = "hertz")]
    builtin: String,
    /// Refinement level of the built-in case (each level halves the mesh size).
    #[arg(long, default_value_t = 1)]
    level: u32,
    /// Print the TOML text of the built-in case (at --level) and exit.
    #[arg(long)]
    print_case: bool,
    /// Override solver.r (augmentation parameter).
    #[arg(long)]
    r: Option<f64>,
    /// Override solver.tol.
    #[arg(long)]
    tol: Option<f64>,
    /// Override solver.max_iter.
    #[arg(long)]
    max_iter: Option<usize>,
    /// Override solver.coulomb: inner (threshold refreshed every sweep) or outer.
    #[arg(long, value_parser = parse_coulomb)]
    coulomb: Option<CoulombMode>,
    /// Override solver.acceleration: anderson (default) or none (plain ALG2).
    #[arg(long, value_parser = parse_acc)]
    acceleration: Option<Acceleration>,
    /// Fill-reducing ordering of each subdomain: auto (default: gnd), gnd (nested
    /// dissection by straight cuts from the nodes' positions: about the least fill, as
    /// fast as amd), amd (minimum degree) or nd (METIS nested dissection: the least
    /// fill, a slower ordering).
    #[arg(long, default_value = "auto", value_parser = parse_ordering)]
    ordering: Ordering,
    /// Where the interface system is factored and solved: rank0 (summed and factored on
    /// the first rank), mumps (assembled where its parts are and factored across the
    /// ranks by MUMPS, solved with distributed right-hand side and solution) or auto
    /// (default: mumps from 16 subdomains on).
    #[arg(long, default_value = "auto", value_parser = parse_interface)]
    interface: InterfaceMode,
    /// Save the loop state every N sweeps in OUT/checkpoint/ (atomically).
    #[arg(long, default_value_t = 0)]
    checkpoint_every: usize,
    /// Resume from OUT/checkpoint/ (same case, same number of ranks).
    #[arg(long)]
    restart: bool,
    /// Print a monitor line every K sweeps.
    #[arg(long, default_value_t = 10)]
    monitor_every: usize,
    /// Threads per rank (assembly, factorization, sweep); default: the cores this rank
    /// may run on / the ranks on its node.
    #[arg(long)]
    threads: Option<usize>,
    /// Whether the first rank runs its work alone (the read and partition of a mesh
    /// file, the interface system's factorization) on the cores of its node's ranks
    /// while they sleep, also where each rank is bound to a core of its own; false keeps
    /// every rank to its own threads (to measure that work on one core).
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    borrow_idle_cores: bool,
    /// Subdomains per rank, each factored and swept on a thread of its own; default:
    /// one per thread of the rank while each keeps 5000 triangles and the job has at
    /// most 8 subdomains, else fewer (1 for --linear full). 1 gives a rank one
    /// subdomain whose factorization uses its threads.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    subdomains_per_rank: Option<u64>,
    /// Linear solve in the loop: condensed (default) or full (one rank only, for
    /// comparison: a sparse forward and backward solve per sweep).
    #[arg(long, default_value = "condensed", value_parser = parse_linear)]
    linear: LinearMode,
    /// A directory written by `contact-par split`: each subdomain reads its own part
    /// there, and no rank reads the whole mesh. The ranks must divide its parts (each
    /// runs parts / ranks subdomains).
    #[arg(long, value_name = "DIR")]
    mesh_split: Option<PathBuf>,
    /// Who reads a Gmsh mesh file on several ranks: first (the first rank, on the idle
    /// cores of its node), shared (every rank parses a share of an MSH 4.1 file's nodes
    /// and elements, the first puts them together; the file must be readable by every
    /// rank, else the first reads it alone) or auto (default: shared when the ranks span
    /// several nodes).
    #[arg(long, default_value = "auto", value_parser = parse_mesh_read)]
    mesh_read: MeshRead,
    /// Who cuts a mesh read from one file into subdomains: geometric (the first rank
    /// alone: recursive straight cuts through the triangles' centroids, refined; METIS
    /// where a part would be in pieces), metis (the first rank alone:
    /// the dual graph coarsened, METIS, refined back), ptscotch (every rank: PT-Scotch
    /// on the graph spread over the ranks) or auto (default: ptscotch when the ranks
    /// span several nodes, else geometric; see docs/performance.md).
    #[arg(long, default_value = "auto", value_parser = parse_partitioner)]
    partitioner: Partitioner,
}

#[derive(clap::Subcommand, Debug)]
enum Command {
    /// Read, partition and split a case once, on one process, into one file per part,
    /// for runs with --mesh-split (where no rank then reads the whole mesh).
    Split(SplitArgs),
}

#[derive(clap::Args, Debug)]
struct SplitArgs {
    /// Case file (TOML). Without it, the built-in case given by --builtin.
    case: Option<PathBuf>,
    /// Number of parts: the subdomains of the runs (ranks x subdomains per rank).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    parts: u64,
    /// Directory of the part files and their manifest (split.json).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Built-in case when no case file is given: hertz, block, block_flat, punch, cylinders.
    #[arg(long, default_value = "hertz")]
    builtin: String,
    /// Refinement level of the built-in case.
    #[arg(long, default_value_t = 1)]
    level: u32,
    /// Who cuts the mesh: geometric or metis (this process, or the first rank; as in a
    /// run) or ptscotch (every rank of `mpirun -n N contact-par split ...`, PT-Scotch);
    /// auto (default): as in a run, ptscotch when the ranks span several nodes, else
    /// geometric. The first rank reads the mesh and writes the parts.
    #[arg(long, default_value = "auto", value_parser = parse_partitioner)]
    partitioner: Partitioner,
}

fn parse_linear(s: &str) -> Result<LinearMode, String> {
    match s {
        "condensed" => Ok(LinearMode::Condensed),
        "full" => Ok(LinearMode::Full),
        _ => Err(format!("\"{s}\" is not condensed or full")),
    }
}

fn parse_ordering(s: &str) -> Result<Ordering, String> {
    match s {
        "auto" => Ok(Ordering::Auto),
        "amd" => Ok(Ordering::Amd),
        "nd" => Ok(Ordering::NestedDissection),
        "gnd" => Ok(Ordering::Geometric),
        _ => Err(format!("\"{s}\" is not auto, amd, nd or gnd")),
    }
}

fn parse_mesh_read(s: &str) -> Result<MeshRead, String> {
    match s {
        "auto" => Ok(MeshRead::Auto),
        "first" => Ok(MeshRead::First),
        "shared" => Ok(MeshRead::Shared),
        _ => Err(format!("\"{s}\" is not auto, first or shared")),
    }
}

fn parse_partitioner(s: &str) -> Result<Partitioner, String> {
    match s {
        "auto" => Ok(Partitioner::Auto),
        "geometric" => Ok(Partitioner::Geometric),
        "metis" => Ok(Partitioner::Metis),
        "ptscotch" => Ok(Partitioner::PtScotch),
        _ => Err(format!("\"{s}\" is not auto, geometric, metis or ptscotch")),
    }
}

fn parse_interface(s: &str) -> Result<InterfaceMode, String> {
    match s {
        "auto" => Ok(InterfaceMode::Auto),
        "rank0" => Ok(InterfaceMode::Rank0),
        "mumps" => Ok(InterfaceMode::Mumps),
        _ => Err(format!("\"{s}\" is not auto, rank0 or mumps")),
    }
}

fn parse_acc(s: &str) -> Result<Acceleration, String> {
    case::parse_acceleration(s, DEFAULT_ANDERSON_MEMORY)
        .ok_or_else(|| format!("\"{s}\" is not anderson or none"))
}

fn parse_coulomb(s: &str) -> Result<CoulombMode, String> {
    case::parse_coulomb_mode(s).ok_or_else(|| format!("\"{s}\" is not inner or outer"))
}

/// Open MPI's default transport selection tries UCX first, which costs about 0.2 s of
/// MPI_Init on a machine without a fast network (0.33 s against 0.11 s for a whole
/// two-rank run of a small case). With every rank on one node the traffic goes
/// through shared memory whichever layer carries it, so unless the user chose a PML
/// (`--mca pml`, `OMPI_MCA_pml`), ask for ob1 there. Only where one node is certain:
/// mpirun says every rank is local, or the process was started alone (no mpirun, no
/// srun). Anything else (srun, several nodes) keeps Open MPI's own choice: UCX on
/// InfiniBand clusters.
fn prefer_shared_memory_on_one_node() {
    const PML: &str = "OMPI_MCA_pml";
    let var = |name: &str| std::env::var_os(name);
    let one_node = match (
        var("OMPI_COMM_WORLD_SIZE"),
        var("OMPI_COMM_WORLD_LOCAL_SIZE"),
    ) {
        (Some(all), Some(local)) => all == local,
        (None, None) => var("SLURM_PROCID").is_none() && var("PMIX_RANK").is_none(),
        _ => false,
    };
    if one_node && var(PML).is_none() {
        // Called first thing in main, before any other thread exists.
        std::env::set_var(PML, "ob1");
    }
}

fn run() -> i32 {
    prefer_shared_memory_on_one_node();
    // Only the main thread of a rank calls MPI, also when the rank runs several
    // subdomains on threads (dd::comm): MPI_THREAD_FUNNELED.
    let Some((universe, granted)) = mpi::initialize_with_threading(Threading::Funneled) else {
        eprintln!("contact-par: MPI could not be initialised");
        return 1;
    };
    use mpi::topology::Communicator;
    let world = universe.world();
    let rank = world.rank();
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            if rank == 0 {
                let _ = e.print();
            }
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    if let Some(Command::Split(args)) = cli.command {
        return split(args, Mpi::new(world));
    }
    if cli.print_case {
        if rank == 0 {
            match case::builtin_case_text(&cli.builtin, cli.level) {
                Some(t) => print!("{t}"),
                None => {
                    eprintln!(
                        "contact-par: unknown built-in case \"{}\"; choose one of {}",
                        cli.builtin,
                        case::BUILTIN_CASES.join(", ")
                    );
                    return 2;
                }
            }
        }
        return 0;
    }
    if !cli.borrow_idle_cores {
        host::keep_to_own_cores();
    }
    let mpi = Mpi::new(world);
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    // Per node, not per job: on a cluster the ranks of other nodes use other cores.
    let threads = cli
        .threads
        .unwrap_or_else(|| (cores / mpi.node_ranks).max(1))
        .max(1);
    let subdomain_threads = may_run_subdomain_threads(cli.subdomains_per_rank, cli.linear, threads);
    if let Err(e) = mpi.agree(check_thread_level(granted, subdomain_threads)) {
        return report(e);
    }
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    faer::set_global_parallelism(if threads == 1 {
        faer::Par::Seq
    } else {
        faer::Par::rayon(threads)
    });
    let opts = Options {
        case_file: cli.case,
        builtin: cli.builtin,
        level: cli.level,
        out: cli.out,
        nodes_csv: cli.nodes_csv,
        plots: !cli.no_plots,
        quiet: cli.quiet,
        r: cli.r,
        tol: cli.tol,
        max_iter: cli.max_iter,
        coulomb: cli.coulomb,
        acceleration: cli.acceleration,
        monitor_every: cli.monitor_every,
        linear: cli.linear,
        checkpoint_every: cli.checkpoint_every,
        restart: cli.restart,
        ordering: cli.ordering,
        interface: cli.interface,
        subdomains_per_rank: cli.subdomains_per_rank.map(|k| k as usize),
        mesh_split: cli.mesh_split,
        mesh_read: cli.mesh_read,
        partitioner: cli.partitioner,
    };
    let print = Printer {
        enabled: rank == 0 && !opts.quiet,
    };
    match app::run(&opts, mpi, &print) {
        Ok(report) if report.converged => 0,
        Ok(_) => 3,
        Err(e) => report(e),
    }
}

/// `contact-par split`: on one process, or under mpirun with the ranks cutting (and
/// building and writing their own parts, `app::split_case`).
fn split(args: SplitArgs, mpi: Mpi) -> i32 {
    let opts = app::SplitOptions {
        case_file: args.case,
        builtin: args.builtin,
        level: args.level,
        parts: args.parts as usize,
        out: args.out,
        partitioner: args.partitioner,
    };
    let print = Printer {
        enabled: mpi.is_root(),
    };
    match app::split_case(&opts, &mpi, &print) {
        Ok(()) => 0,
        Err(e) => report(e),
    }
}

/// Prints an error that this rank holds and returns its exit code. Only the rank that
/// failed first holds the message (see `Mpi::agree`); the others are [`Error::Silent`].
fn report(e: Error) -> i32 {
    if !matches!(e, Error::Silent(_)) {
        eprintln!("contact-par: error: {e}");
    }
    e.exit_code()
}

/// Whether a rank of this run may run several subdomains, each on a thread of its own:
/// asked for (`--subdomains-per-rank` above 1), or left to the default, which gives a
/// rank at most one subdomain per thread and one with `--linear full`. The first rank
/// settles the count later, from the mesh; this answers for what the options allow.
fn may_run_subdomain_threads(per_rank: Option<u64>, linear: LinearMode, threads: usize) -> bool {
    match per_rank {
        Some(k) => k > 1,
        None => linear != LinearMode::Full && threads > 1,
    }
}

/// Whether the thread support MPI granted suffices. Subdomain threads compute and wait
/// while their rank's main thread is inside MPI on their behalf: that is
/// MPI_THREAD_FUNNELED. With one subdomain per rank the rank's other threads (the
/// assembly's and the factorization's pools) run only between MPI calls, so the lowest
/// level, MPI_THREAD_SINGLE, serves; refusing it there would refuse runs that work.
fn check_thread_level(granted: Threading, subdomain_threads: bool) -> Result<(), Error> {
    if !subdomain_threads || granted >= Threading::Funneled {
        return Ok(());
    }
    Err(Error::Input(format!(
        "MPI granted the thread level {}, and several subdomains per rank on threads of their own need MPI_THREAD_FUNNELED; run with --subdomains-per-rank 1, or use an MPI library built with thread support",
        thread_level_name(granted)
    )))
}

fn thread_level_name(level: Threading) -> &'static str {
    match level {
        Threading::Single => "MPI_THREAD_SINGLE",
        Threading::Funneled => "MPI_THREAD_FUNNELED",
        Threading::Serialized => "MPI_THREAD_SERIALIZED",
        Threading::Multiple => "MPI_THREAD_MULTIPLE",
    }
}

fn main() {
    // A panic on one rank must not leave the others waiting in a collective forever:
    // print it, then abort the whole job.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        default_hook(info);
        // SAFETY: MPI_Abort may be called at any time after MPI_Init; if MPI is not
        // initialised the process simply ends with the panic.
        unsafe {
            mpi::ffi::MPI_Abort(mpi::ffi::RSMPI_COMM_WORLD, 70);
        }
    }));
    let code = run();
    std::process::exit(code);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subdomain_threads_are_those_the_options_allow() {
        let (c, f) = (LinearMode::Condensed, LinearMode::Full);
        assert!(may_run_subdomain_threads(Some(2), c, 1));
        assert!(!may_run_subdomain_threads(Some(1), c, 8));
        assert!(may_run_subdomain_threads(None, c, 2));
        assert!(!may_run_subdomain_threads(None, c, 1));
        assert!(!may_run_subdomain_threads(None, f, 8));
    }

    #[test]
    fn a_single_threaded_mpi_is_refused_only_where_subdomain_threads_may_run() {
        for level in [
            Threading::Funneled,
            Threading::Serialized,
            Threading::Multiple,
        ] {
            assert_eq!(check_thread_level(level, true), Ok(()));
        }
        assert_eq!(check_thread_level(Threading::Single, false), Ok(()));
        let e = check_thread_level(Threading::Single, true).unwrap_err();
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
