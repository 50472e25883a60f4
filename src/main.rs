//! contact-par: 2D elastic contact by Uzawa block relaxation: MPI and the command line,
//! then `run::run` (or `contact-par split`).
//!
//! ```text
//! contact-par                          # the default built-in case (Hertz)
//! contact-par case.toml --out results  # a case file with a Gmsh mesh
//! mpirun -n 2 contact-par case.toml
//! ```
//! Exit codes: 0 converged, 2 bad input, 3 not converged (outputs written, marked so),
//! 4 numerical failure, 5 outputs could not be written.

use clap::Parser;
use contact_par::case;
use contact_par::dd::comm::Mpi;
use contact_par::error::Error;
use contact_par::host;
use contact_par::options::{CaseArgs, Options, SplitOptions};
use contact_par::run::{self, Printer};
use contact_par::setup::split_dir;
use mpi::Threading;

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
    about = "2D elastic contact (frictionless, Tresca, Coulomb) of one or two bodies against rigid obstacles (lines, circles, polylines) or each other, Uzawa block relaxation, on one core or many MPI ranks",
    after_long_help = OUTPUTS_HELP,
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    run: Options,
    /// Print the TOML text of the built-in case (at --level) and exit.
    #[arg(long)]
    print_case: bool,
}

#[derive(clap::Subcommand, Debug)]
enum Command {
    /// Read, partition and split a case once into one file per part, for runs with
    /// --mesh-split (where no rank then reads the whole mesh). The first process does
    /// it all; under mpirun the others sleep, lending it their cores.
    Split(SplitOptions),
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
    let mpi = Mpi::new(universe.world(), granted >= Threading::Funneled);
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            if mpi.is_root() {
                let _ = e.print();
            }
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    let print = |quiet: bool| Printer {
        enabled: mpi.is_root() && !quiet,
    };
    let done = match cli.command {
        Some(Command::Split(opts)) => split_dir::split(&opts, &mpi, &print(false)).map(|()| 0),
        None if cli.print_case => print_case(&cli.run.case, mpi.is_root()).map(|()| 0),
        None => {
            let opts = cli.run;
            host::start_threads(opts.threads, opts.borrow_idle_cores, mpi.node_ranks);
            let print = print(opts.quiet);
            run::run(&opts, mpi, &print).map(|report| if report.converged { 0 } else { 3 })
        }
    };
    done.unwrap_or_else(report)
}

/// `--print-case`: the built-in case's text, on the first rank.
fn print_case(case: &CaseArgs, root: bool) -> Result<(), Error> {
    if !root {
        return Ok(());
    }
    let text = case::builtin_case_text(&case.builtin, case.level).ok_or_else(|| {
        Error::Input(format!(
            "unknown built-in case \"{}\"; choose one of {}",
            case.builtin,
            case::BUILTIN_CASES.join(", ")
        ))
    })?;
    print!("{text}");
    Ok(())
}

/// Prints an error that this rank holds and returns its exit code. Only the rank that
/// failed first holds the message (see `Mpi::agree`); the others are [`Error::Silent`].
fn report(e: Error) -> i32 {
    if !matches!(e, Error::Silent(_)) {
        eprintln!("contact-par: error: {e}");
    }
    e.exit_code()
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
