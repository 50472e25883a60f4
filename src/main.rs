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
use contact_par::app::{self, Options, Printer};
use contact_par::case::{self, CoulombMode};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "contact-par",
    version,
    about = "2D elastic contact (frictionless, Tresca, Coulomb) with a rigid foundation, Uzawa block relaxation, on one core or many MPI ranks"
)]
struct Cli {
    /// Case file (TOML). Without it, the built-in case given by --builtin runs.
    case: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Also write nodes.csv (x,y,ux,uy for every node).
    #[arg(long)]
    nodes_csv: bool,
    /// Print nothing but errors.
    #[arg(long)]
    quiet: bool,
    /// Built-in case to run when no case file is given: hertz, block, block_flat.
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
    /// Print a monitor line every K sweeps.
    #[arg(long, default_value_t = 10)]
    monitor_every: usize,
    /// Threads per rank (assembly and factorization); default: all cores / ranks.
    #[arg(long)]
    threads: Option<usize>,
}

fn parse_coulomb(s: &str) -> Result<CoulombMode, String> {
    case::parse_coulomb_mode(s).ok_or_else(|| format!("\"{s}\" is not inner or outer"))
}

fn run() -> i32 {
    let Some(universe) = mpi::initialize() else {
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
    if world.size() > 1 {
        if rank == 0 {
            eprintln!("contact-par: runs on one rank in this version; use mpirun -n 1");
        }
        return 2;
    }
    let threads = cli.threads.unwrap_or(0);
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    let opts = Options {
        case_file: cli.case,
        builtin: cli.builtin,
        level: cli.level,
        out: cli.out,
        nodes_csv: cli.nodes_csv,
        quiet: cli.quiet,
        r: cli.r,
        tol: cli.tol,
        max_iter: cli.max_iter,
        coulomb: cli.coulomb,
        monitor_every: cli.monitor_every,
    };
    let print = Printer {
        enabled: rank == 0 && !opts.quiet,
    };
    match app::run(&opts, &print) {
        Ok(report) if report.converged => 0,
        Ok(_) => 3,
        Err(e) => {
            if rank == 0 {
                eprintln!("contact-par: error: {e}");
            }
            e.exit_code()
        }
    }
}

fn main() {
    let code = run();
    std::process::exit(code);
}
