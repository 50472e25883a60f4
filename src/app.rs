//! One run of the program, told as numbered steps: read, build, assemble and factor,
//! iterate, write. `main.rs` only wires the command line and MPI to this.

use crate::case::{self, BuiltinMesh, Case, MeshSource};
use crate::contact::operators::{contact_blocks, ContactDofs};
use crate::contact::{
    self, Acceleration, CoulombMode, Friction, LinearStep, Reduce, Status, Sweep,
};
use crate::dd::comm::{decode, encode, Mpi};
use crate::dd::condense::{boundary_entries, ContactRows, InterfaceSystem, LocalResponse};
use crate::dd::full::DirectStep;
use crate::dd::local_factor::LocalFactor;
use crate::dd::split::{split, SubProblem};
use crate::error::{Error, Result};
use crate::fem::{self, assemble, DofMap};
use crate::linear::{interior_groups, Ordering};
use crate::mesh::{builtin, gmsh, Mesh};
use crate::output::{self, ContactRow};
use crate::problem::{self, Problem};
use faer::Mat;
use rayon::prelude::*;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// What the command line asks for, after parsing.
#[derive(Debug, Clone)]
pub struct Options {
    /// A case file, or `None` for a built-in case.
    pub case_file: Option<PathBuf>,
    pub builtin: String,
    pub level: u32,
    pub out: PathBuf,
    pub nodes_csv: bool,
    pub quiet: bool,
    pub r: Option<f64>,
    pub tol: Option<f64>,
    pub max_iter: Option<usize>,
    pub coulomb: Option<CoulombMode>,
    pub acceleration: Option<Acceleration>,
    pub monitor_every: usize,
    pub linear: LinearMode,
    /// Save the loop state every this many sweeps (0: never).
    pub checkpoint_every: usize,
    /// Resume from the checkpoint in `out/checkpoint/`.
    pub restart: bool,
    /// Fill-reducing ordering of the subdomain interiors.
    pub ordering: Ordering,
    /// Subdomains per rank, each on its own thread; `None`: [`subdomains_per_rank`].
    pub subdomains_per_rank: Option<usize>,
}

/// Prints on the first rank only, and not at all with --quiet.
pub struct Printer {
    pub enabled: bool,
}

impl Printer {
    pub fn line(&self, s: impl AsRef<str>) {
        use std::io::Write;
        if self.enabled {
            // A closed stdout (e.g. piped into `head`) must not stop the computation.
            let _ = writeln!(std::io::stdout(), "{}", s.as_ref());
        }
    }
}

/// The end of a run: whether it converged (exit code 0) or not (exit code 3).
pub struct RunReport {
    pub converged: bool,
}

#[derive(Serialize, Default, Clone, Copy)]
struct Timings {
    read: f64,
    partition: f64,
    /// Rank 0 sending every other rank its subproblem.
    scatter: f64,
    assemble: f64,
    factor: f64,
    condense: f64,
    #[serde(rename = "loop")]
    uzawa: f64,
    recover: f64,
    output: f64,
    total: f64,
}

/// Resolves the case: a file, or a built-in case at a refinement level; then applies the
/// command-line overrides.
pub fn load_case(opts: &Options) -> Result<Case> {
    let mut case = match &opts.case_file {
        Some(path) => case::read_case(path)?,
        None => case::builtin_case(&opts.builtin, opts.level)?,
    };
    case::override_solver(&mut case, opts.r, opts.tol, opts.max_iter, opts.coulomb)?;
    if let Some(acc) = opts.acceleration {
        case.solver.acceleration = acc;
    }
    Ok(case)
}

/// Reads or generates the mesh; returns it with the name used in messages.
pub fn load_mesh(case: &Case) -> Result<(Mesh, String)> {
    match &case.mesh {
        MeshSource::File(path) => Ok((gmsh::read_msh(path)?, path.display().to_string())),
        MeshSource::Builtin { name, level } => {
            let mesh = match name {
                BuiltinMesh::QuarterDisc => {
                    builtin::quarter_disc_for_level(case::HERTZ_RADIUS, *level)
                }
                BuiltinMesh::Block => {
                    builtin::block_for_level(case::BLOCK_WIDTH, case::BLOCK_HEIGHT, *level)
                }
            };
            Ok((mesh, format!("built-in mesh (level {level})")))
        }
    }
}

fn friction_name(f: &Friction) -> &'static str {
    match f {
        Friction::None => "none",
        Friction::Tresca { .. } => "tresca",
        Friction::Coulomb { .. } => "coulomb",
    }
}

/// From here on, blocks freed by this process stay in its heap for the next allocations.
///
/// Why: glibc serves each block above its mmap threshold with a fresh mapping and unmaps
/// it on free, so the next large buffer is page-faulted in and zeroed by the kernel again.
/// The VTU encoder copies each array through several nested buffers, which made the
/// output phase mostly page faults. Only the output phase gets this: its buffers are far
/// smaller than the factorization's, so the peak memory per rank does not move, whereas
/// the same setting for the whole run (`GLIBC_TUNABLES=glibc.malloc.mmap_max=0`, see the
/// README) raises it by 9-16%. Measured on hertz level 4, one rank: output 1.05 s before,
/// 0.81-0.87 s after; page faults 638k -> 535k-541k; peak 1036 MB both.
fn keep_freed_blocks_for_reuse() {
    // SAFETY: mallopt only changes glibc's allocation policy; it may be called at any
    // time, and blocks already mapped are still unmapped correctly when freed. A failed
    // call leaves the default policy, which is merely slower.
    #[cfg(target_env = "gnu")]
    unsafe {
        libc::mallopt(libc::M_MMAP_MAX, 0);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}

/// Peak resident memory of this process (VmHWM), 0 where /proc is not available.
pub fn peak_memory_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

fn monitor_line(s: &Sweep) -> String {
    format!(
        "{:>7}  primal {:.3e}  dual {:.3e}  active {:>6}  slip {:>6}",
        s.iter, s.primal, s.dual, s.active, s.slip
    )
}

/// What the first rank tells every rank before the distribution.
#[derive(Serialize, serde::Deserialize)]
struct Setup {
    case: Case,
    r: f64,
    /// Shift of the interface block of every local matrix (see `LocalFactor`).
    alpha: f64,
    n_boundary: usize,
    n_interface: usize,
    contact_counts: Vec<usize>,
    normal: [f64; 2],
    tangent: [f64; 2],
    nodes: usize,
    elements: usize,
    free_dofs: usize,
    contact_nodes: usize,
    partition: String,
    ordering: Ordering,
    /// Subdomains per rank.
    per_rank: usize,
    read_s: f64,
    partition_s: f64,
}

/// Per-subdomain figures, gathered for summary.json.
#[derive(Serialize, serde::Deserialize, Clone, Default)]
pub struct RankStats {
    subdomain: usize,
    /// The MPI rank that ran it.
    rank: usize,
    elements: usize,
    nodes: usize,
    interface_nodes: usize,
    boundary_dofs: usize,
    contact_nodes: usize,
    factor_nnz: usize,
    /// The numeric factorization's floating-point operations, 1e9 (`factor_flops`): the
    /// ranks' work and its balance, free of the machine's noise.
    factor_gflop: f64,
    peak_memory_bytes: u64,
    assemble_s: f64,
    factor_s: f64,
    /// Part of factor_s spent in the fill-reducing ordering.
    ordering_s: f64,
    /// The ordering used: amd or nd (or the full path's amd).
    ordering: String,
    /// Forming S_s = L_BB L_BB' and the condensed right-hand side.
    schur_s: f64,
    /// On the subdomain that factored the interface system: "dense" or "sparse"
    /// (null on the others).
    interface_factor: Option<String>,
    /// Its factorization's floating-point operations, 1e9 (0 on the others).
    interface_gflop: f64,
    loop_s: f64,
    /// One sparse forward+backward solve with this rank's factor (the cost a sweep
    /// would have without condensation).
    one_solve_s: f64,
    output_s: f64,
    /// `.vtu` files this rank wrote (its piece, split as [`output::file_ranges`] says).
    vtu_files: usize,
}

/// How step 1 is solved inside the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinearMode {
    /// Condensed onto the contact dofs: one small dense product per sweep (default).
    Condensed,
    /// A full sparse forward and backward solve per sweep (one rank; for comparison).
    Full,
}

/// `threads`: of each rank (for the default number of subdomains per rank).
fn prepare(opts: &Options, ranks: usize, threads: usize) -> Result<(Setup, Vec<SubProblem>)> {
    let t0 = Instant::now();
    let case = load_case(opts)?;
    let (mesh, mesh_name) = load_mesh(&case)?;
    let prob = problem::build(&case, mesh, &mesh_name)?;
    let read_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let triangles = prob.mesh.triangles.len();
    let per_rank = match opts.subdomains_per_rank {
        Some(k) => k.max(1),
        None if opts.linear == LinearMode::Full => 1,
        None => subdomains_per_rank(threads, ranks, triangles),
    };
    let nparts = ranks * per_rank;
    if nparts > triangles {
        return Err(Error::Input(if per_rank == 1 {
            format!("{mesh_name}: {ranks} ranks for {triangles} triangles; use at most as many ranks as triangles (better: thousands of triangles per rank)")
        } else {
            format!("{mesh_name}: {nparts} subdomains ({ranks} rank(s) x --subdomains-per-rank {per_rank}) for {triangles} triangles; use at most as many subdomains as triangles (better: thousands of triangles each): fewer ranks or subdomains per rank")
        }));
    }
    let part = partition::partition_mesh(
        prob.mesh.num_nodes(),
        &prob.mesh.triangles,
        &prob.contact_nodes,
        nparts,
    )
    .map_err(|e| Error::Input(format!("{mesh_name}: cannot partition the mesh: {e}")))?;
    let (subs, map) = split(&prob, &part, Problem::is_frictional(&case))?;
    let partition_s = t1.elapsed().as_secs_f64();
    let r = case.solver.r.unwrap_or_else(|| prob.default_r(&case));
    let m = &case.material;
    let setup = Setup {
        r,
        alpha: m.young / (1.0 - m.poisson * m.poisson),
        n_boundary: map.n_boundary,
        n_interface: map.n_interface,
        contact_counts: map.contact_counts.clone(),
        normal: prob.normal,
        tangent: prob.tangent,
        nodes: prob.mesh.num_nodes(),
        elements: prob.mesh.triangles.len(),
        free_dofs: prob.fixed.iter().filter(|f| f.is_none()).count(),
        contact_nodes: prob.contact_nodes.len(),
        partition: part.quality.to_string(),
        ordering: opts.ordering,
        per_rank,
        read_s,
        partition_s,
        case,
    };
    Ok((setup, subs))
}

/// Runs `work` with the threads of every rank of this node, `node_ranks` of them each
/// with this rank's thread count, while the others wait asleep: as many as the cores
/// this rank may run on allow (its CPU set, all of the node's cores under
/// `--bind-to none`, one under `--bind-to core`). Only where that is more than its own
/// threads; otherwise, or should the pool not start, on its own threads.
fn on_idle_cores<T: Send>(node_ranks: usize, work: impl FnOnce() -> T + Send) -> T {
    let own = rayon::current_num_threads();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = idle_core_threads(own, node_ranks, cores);
    if threads <= own {
        return work();
    }
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(work),
        Err(_) => work(),
    }
}

/// Triangles per subdomain from which [`subdomains_per_rank`] gives a thread a
/// subdomain of its own (see there).
pub const MIN_TRIANGLES_PER_SUBDOMAIN: usize = 5_000;

/// Subdomains of the whole job beyond which [`subdomains_per_rank`] splits no rank
/// further (see there).
pub const MAX_DEFAULT_SUBDOMAINS: usize = 8;

/// Subdomains per rank by default: one per thread of the rank, as long as each keeps
/// [`MIN_TRIANGLES_PER_SUBDOMAIN`] triangles and the job [`MAX_DEFAULT_SUBDOMAINS`]
/// subdomains; at least one.
///
/// Why split: a sparse Cholesky factorization spreads over threads only inside its
/// fronts (faer: 1 rank x 2 threads factored hertz level 5 1.14 times faster than one
/// thread), whereas k subdomains factor on k threads at once, each a piece whose factor
/// costs less than 1/k of the whole (O(n^1.5) flops in 2D). Measured with 2 threads,
/// one rank, 2 subdomains against 1 (whole runs, medians of 9): 0.99 at 1600 and 1200
/// triangles per subdomain, 0.98 at 4700, 0.91 at 6400, 0.82 at 18700, 0.77 at 25600,
/// 0.84 at 1.2M; below the threshold the partition and the interface cost what the
/// threads save.
///
/// Why stop at a few subdomains: the interface system is dense and solved by the first
/// rank (`dd`). In 2D its size grows as sqrt(nodes x subdomains), so its n_G^3 / 3 flops
/// grow as P^1.5 times those of the whole mesh while each subdomain's factor shrinks as
/// P^-1.5: their ratio grows as P^3, about 1.7e-3 P^3 from the hertz level 5 factors
/// (one subdomain's factor at P = 8). With many ranks each rank keeps one subdomain, as
/// before; more can still be asked for with `--subdomains-per-rank`.
pub fn subdomains_per_rank(threads: usize, ranks: usize, triangles: usize) -> usize {
    let ranks = ranks.max(1);
    let by_size = triangles / (ranks * MIN_TRIANGLES_PER_SUBDOMAIN);
    let by_interface = MAX_DEFAULT_SUBDOMAINS / ranks;
    threads.min(by_size).min(by_interface).max(1)
}

/// Threads for the first rank's work alone: its own `own` times the `node_ranks` ranks
/// of its node, within the `cores` it may run on, and never fewer than its own.
fn idle_core_threads(own: usize, node_ranks: usize, cores: usize) -> usize {
    own.saturating_mul(node_ranks).min(cores).max(own)
}

/// This rank's factored subdomain and its condensed contribution.
struct LocalSystem {
    dofs: DofMap,
    factor: LocalFactor,
    /// Load + lifting of the prescribed dofs, per local equation.
    base: Vec<f64>,
    assemble_s: f64,
    factor_s: f64,
}

impl LocalSystem {
    fn new(setup: &Setup, sub: &SubProblem) -> Result<Self> {
        let t0 = Instant::now();
        let frictional = Problem::is_frictional(&setup.case);
        let dofs = DofMap::with_last(&sub.fixed, &sub.boundary_dofs);
        let rr = vec![setup.r; sub.contact_nodes.len()];
        let mut blocks = contact_blocks(
            &sub.contact_nodes,
            &sub.contact.w,
            &rr,
            &rr,
            setup.normal,
            frictional,
        );
        let mut g_nodes: Vec<usize> = sub.boundary_dofs[sub.n_contact_dofs..]
            .iter()
            .map(|d| d / 2)
            .collect();
        g_nodes.dedup();
        blocks.extend(
            g_nodes
                .iter()
                .map(|&v| (v, [[setup.alpha, 0.0], [0.0, setup.alpha]])),
        );
        let assembled = assemble(
            &sub.nodes,
            &sub.triangles,
            &setup.case.material,
            &dofs,
            &blocks,
        )?;
        let mut base = assembled.lifting;
        for (dof, eq) in dofs.eq.iter().enumerate() {
            if let Some(i) = eq {
                base[*i] += sub.load[dof];
            }
        }
        let assemble_s = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let factor = LocalFactor::with_ordering(
            assembled.matrix.as_ref(),
            sub.boundary_dofs.len(),
            sub.n_contact_dofs,
            setup.alpha,
            &interior_groups(&dofs),
            setup.ordering,
        )?;
        Ok(LocalSystem {
            dofs,
            factor,
            base,
            assemble_s,
            factor_s: t1.elapsed().as_secs_f64(),
        })
    }
}

/// Step 1 on the condensed boundary system: each rank eliminates its own contact dofs,
/// the first rank solves the interface system (one MPI_Gatherv of the ranks' interface
/// right-hand sides, one MPI_Scatterv of the interface values), each rank back-substitutes
/// and reads (Nu, Tu) on its own contact nodes. No communication without an interface.
struct CondensedStep<'a> {
    mpi: &'a Mpi,
    setup: &'a Setup,
    sub: &'a SubProblem,
    factor: &'a mut LocalFactor,
    response: LocalResponse,
    /// The interface system, on the first rank only.
    interface: Option<InterfaceSystem>,
    interface_counts: Vec<usize>,
    /// Scratch: the packed own forces of the sweep being solved.
    forces: Vec<f64>,
    gathered: Vec<f64>,
    solved: Vec<f64>,
    x_g: Vec<f64>,
    out: Vec<f64>,
}

impl LinearStep for CondensedStep<'_> {
    /// Each rank refactors the dense trailing block of its factor with the new
    /// augmentation on its contact dofs; the first rank rebuilds the interface system.
    fn set_r(&mut self, r_n: &[f64], r_t: &[f64]) -> Result<bool> {
        let frictional = Problem::is_frictional(&self.setup.case);
        let shift = |r: &[f64]| r.iter().map(|r| r - self.setup.r).collect::<Vec<f64>>();
        let blocks = contact_blocks(
            &self.sub.contact_nodes,
            &self.sub.contact.w,
            &shift(r_n),
            &shift(r_t),
            self.setup.normal,
            frictional,
        );
        let updated = boundary_entries(&blocks, &self.sub.fixed, &self.sub.boundary_dofs)
            .and_then(|delta| self.factor.update_boundary(&delta));
        self.mpi.agree(updated)?;
        if self.setup.n_interface > 0 {
            self.interface = build_interface(
                self.mpi,
                self.sub,
                self.factor.interface_schur(),
                self.setup.n_interface,
            )?;
        }
        Ok(true)
    }

    fn solve(
        &mut self,
        force_n: &[f64],
        force_t: &[f64],
        un: &mut [f64],
        ut: &mut [f64],
    ) -> Result<()> {
        let frictional = Problem::is_frictional(&self.setup.case);
        self.forces.clear();
        self.forces.extend_from_slice(force_n);
        if frictional {
            self.forces.extend_from_slice(force_t);
        }
        let z = self.response.forward(self.factor, &self.forces);
        self.x_g.resize(z.len(), 0.0);
        if self.setup.n_interface > 0 {
            self.mpi
                .gather_to_root(z, &self.interface_counts, &mut self.gathered);
            if let Some(sys) = self.interface.as_mut() {
                sys.solve_packed(&self.gathered, &mut self.solved);
            }
            self.mpi
                .scatter_from_root(&self.solved, &self.interface_counts, &mut self.x_g);
        }
        self.out.resize(self.forces.len(), 0.0);
        self.response
            .backward(self.factor, &self.x_g, &mut self.out);
        let n_own = force_n.len();
        un.copy_from_slice(&self.out[..n_own]);
        if frictional {
            ut.copy_from_slice(&self.out[n_own..]);
        } else {
            ut.fill(0.0);
        }
        Ok(())
    }
}

/// The whole run, on any number of ranks, each running its subdomains on threads of
/// its own (`mpi` is this rank's; on return every thread of the rank has ended).
pub fn run(opts: &Options, mpi: Mpi, print: &Printer) -> Result<RunReport> {
    let t_start = Instant::now();
    if opts.linear == LinearMode::Full
        && (mpi.size > 1 || opts.subdomains_per_rank.is_some_and(|k| k > 1))
    {
        return mpi.agree(Err(Error::Input(
            "--linear full runs on one rank and one subdomain only; use the default (condensed) with mpirun or --subdomains-per-rank"
                .into(),
        )));
    }

    // 1. First rank: read and validate the case and the mesh, partition, split. The
    // other ranks sleep meanwhile, so that the cores of those on its node are its to use.
    // The rank's own threads, not those of the pool the set-up borrows.
    let threads = rayon::current_num_threads();
    let prepared = mpi
        .is_root()
        .then(|| on_idle_cores(mpi.node_ranks, || prepare(opts, mpi.size, threads)));
    mpi.barrier_sleeping();
    let prepared = mpi.agree(prepared.transpose())?;
    let t_scatter = Instant::now();
    let (setup, subs) = match prepared {
        Some((setup, subs)) => (Some(setup), Some(subs)),
        None => (None, None),
    };
    let setup = mpi.broadcast(setup)?;

    // 2. Every subdomain of this rank on a thread of its own, this one included.
    faer::set_global_parallelism(match threads / setup.per_rank {
        0 | 1 => faer::Par::Seq,
        t => faer::Par::rayon(t),
    });
    let (leader, members) = mpi.into_team(setup.per_rank);
    let setup = &setup;
    std::thread::scope(|scope| {
        for (i, m) in members.into_iter().enumerate() {
            let name = format!("subdomain {}", leader.rank + i + 1);
            let work = move || {
                let mpi = Mpi::member(m);
                let quiet = Printer { enabled: false };
                if let Err(e) = run_subdomain(opts, &mpi, setup, None, t_start, t_scatter, &quiet) {
                    // The first subdomain to fail holds the message (see Mpi::agree).
                    if !matches!(e, Error::Silent(_)) {
                        eprintln!("contact-par: error: {e}");
                    }
                }
            };
            // A rank that cannot start its threads cannot run: the panic ends the job
            // (main's hook) rather than leaving the other subdomains waiting.
            std::thread::Builder::new()
                .name(name)
                .stack_size(SUBDOMAIN_STACK_BYTES)
                .spawn_scoped(scope, work)
                .expect("cannot start a subdomain thread");
        }
        run_subdomain(opts, &leader, setup, subs, t_start, t_scatter, print)
    })
}

/// Stack of a subdomain thread: the main thread's usual 8 MiB.
const SUBDOMAIN_STACK_BYTES: usize = 8 << 20;

/// One subdomain's run, from its subproblem to its outputs (collective over all).
fn run_subdomain(
    opts: &Options,
    mpi: &Mpi,
    setup: &Setup,
    subs: Option<Vec<SubProblem>>,
    t_start: Instant,
    t_scatter: Instant,
    print: &Printer,
) -> Result<RunReport> {
    let sub = &mpi.agree(mpi.scatter_parts(subs))?;
    let scatter_s = t_scatter.elapsed().as_secs_f64();
    let case = &setup.case;
    print.line(format!(
        "contact-par: {} | {} nodes, {} triangles, {} contact nodes | friction {} | r = {:e}, tol = {:e} | {} rank(s) x {} thread(s){}",
        if case.title.is_empty() { &case.origin } else { &case.title },
        setup.nodes,
        setup.elements,
        setup.contact_nodes,
        friction_name(&case.contact.friction),
        setup.r,
        case.solver.tol,
        mpi.mpi_size,
        rayon::current_num_threads(),
        if setup.per_rank > 1 {
            format!(" | {} subdomains per rank, one thread each", setup.per_rank)
        } else {
            String::new()
        }
    ));
    if mpi.size > 1 {
        print.line(format!("partition: {}", setup.partition));
    }

    // 2-4. Factor once, then the Uzawa loop on this rank's contact nodes.
    let params = contact::Params {
        r: setup.r,
        tol: case.solver.tol,
        max_iter: case.solver.max_iter,
        friction: case.contact.friction,
        coulomb: case.solver.coulomb,
        acceleration: case.solver.acceleration,
        // A given r is the user's: kept as it is.
        adapt_r: case.solver.r.is_none(),
    };
    let every = opts.monitor_every.max(1);
    let mut retunes = 0;
    let mut monitor = |s: &Sweep| {
        if s.retunes != retunes {
            print.line(if s.stiff + s.soft == 0 {
                "  r back to the reference on every contact direction (the statuses kept moving); the dense factor blocks refactored".to_string()
            } else {
                format!(
                    "  r retuned (statuses settled): raised on {} held contact directions, lowered on {} free ones; the dense factor blocks refactored",
                    s.stiff, s.soft
                )
            });
            retunes = s.retunes;
        }
        if s.iter == 1 || s.iter % every == 0 {
            print.line(monitor_line(s));
        }
    };
    let ckpt = CheckpointFiles {
        dir: opts.out.join("checkpoint"),
        every: opts.checkpoint_every,
        restart: opts.restart,
        ranks: mpi.mpi_size,
        per_rank: mpi.per_rank(),
    };
    let (mut outcome, u_local, phases) = match opts.linear {
        LinearMode::Condensed => solve_condensed(mpi, setup, sub, &params, &mut monitor, &ckpt)?,
        LinearMode::Full => solve_full(mpi, setup, sub, &params, &mut monitor, &ckpt)?,
    };
    // Report u_n and u_t of the recovered field (frictionless sweeps do not compute u_t).
    for (k, &node) in sub.contact_nodes.iter().enumerate() {
        let u = u_local[node];
        outcome.un[k] = -(setup.normal[0] * u[0] + setup.normal[1] * u[1]);
        outcome.ut[k] = setup.tangent[0] * u[0] + setup.tangent[1] * u[1];
    }
    if let Some(last) = outcome.history.last() {
        if last.iter % every != 0 {
            print.line(monitor_line(last));
        }
    }

    // 5. Outputs: each rank its piece, the first rank the gathered files.
    let t_out = Instant::now();
    let stats = RankStats {
        subdomain: mpi.rank,
        rank: mpi.mpi_rank,
        elements: sub.triangles.len(),
        nodes: sub.nodes.len(),
        interface_nodes: sub.interface_nodes,
        boundary_dofs: sub.boundary_dofs.len(),
        contact_nodes: sub.contact_nodes.len(),
        factor_nnz: phases.factor_nnz,
        factor_gflop: phases.factor_flops / 1e9,
        peak_memory_bytes: 0,
        assemble_s: phases.assemble,
        factor_s: phases.factor,
        ordering_s: phases.ordering,
        ordering: phases.ordering_used.name().to_string(),
        schur_s: phases.schur,
        interface_factor: phases.interface_factor.map(str::to_string),
        interface_gflop: phases.interface_flops / 1e9,
        loop_s: phases.uzawa,
        one_solve_s: phases.one_solve,
        output_s: 0.0,
        vtu_files: 0,
    };
    let times = Timings {
        read: setup.read_s,
        partition: setup.partition_s,
        scatter: scatter_s,
        assemble: phases.assemble,
        factor: phases.factor,
        condense: phases.condense,
        uzawa: phases.uzawa,
        recover: phases.recover,
        output: 0.0,
        total: 0.0,
    };
    let piece = write_piece(opts, mpi, setup, sub, &u_local, &outcome, stats, t_out);
    let result = write_outputs(opts, mpi, setup, &outcome, piece, times, t_out, t_start);
    mpi.agree(result)?;

    let sums = {
        let mut v = [
            sub.contact
                .w
                .iter()
                .zip(&outcome.lambda)
                .map(|(w, l)| w * l)
                .sum::<f64>(),
            outcome
                .status
                .iter()
                .filter(|&&s| s == Status::Stick)
                .count() as f64,
            outcome
                .status
                .iter()
                .filter(|&&s| s == Status::Slip)
                .count() as f64,
        ];
        mpi.sum_in_place(&mut v);
        v
    };
    let mut times = times;
    times.output = t_out.elapsed().as_secs_f64();
    times.total = t_start.elapsed().as_secs_f64();
    // Without friction there is no stick or slip to report.
    let split = if Problem::is_frictional(case) {
        format!(" ({} stick, {} slip)", sums[1] as usize, sums[2] as usize)
    } else {
        String::new()
    };
    print.line(format!(
        "{} after {} iterations: {} active contact nodes{split}, total normal force {}",
        if outcome.converged {
            "converged"
        } else {
            "NOT CONVERGED"
        },
        outcome.iterations,
        (sums[1] + sums[2]) as usize,
        sums[0]
    ));
    print_timings(print, &times, outcome.iterations);
    print.line(format!("outputs in {}", opts.out.display()));
    Ok(RunReport {
        converged: outcome.converged,
    })
}

/// Wall-clock seconds and sizes of the solve phases of one rank.
struct Phases {
    assemble: f64,
    factor: f64,
    condense: f64,
    uzawa: f64,
    recover: f64,
    ordering: f64,
    ordering_used: Ordering,
    schur: f64,
    /// "dense" or "sparse" where the interface system was factored.
    interface_factor: Option<&'static str>,
    interface_flops: f64,
    factor_nnz: usize,
    factor_flops: f64,
    /// One sparse forward+backward solve with this rank's factor (on the condensed
    /// path, its forward half in the condensation plus its backward half in the recovery).
    one_solve: f64,
}

/// The interface system, summed from every rank's part and factored on the first rank
/// (collective; `None` on the other ranks).
fn build_interface(
    mpi: &Mpi,
    sub: &SubProblem,
    s_local: Mat<f64>,
    n_interface: usize,
) -> Result<Option<InterfaceSystem>> {
    let n = s_local.nrows();
    let flat: Vec<f64> = (0..n * n).map(|k| s_local[(k % n, k / n)]).collect();
    drop(s_local);
    let gathered = mpi.gather_parts((sub.interface_global.clone(), flat));
    let interface = match gathered {
        Ok(Some(parts)) => {
            let pieces = parts.into_iter().map(|(index, flat)| {
                let n = index.len();
                (index, Mat::<f64>::from_fn(n, n, |i, j| flat[i + n * j]))
            });
            // The other subdomains sleep meanwhile (below): the factorization may use
            // every core this rank can run on, not only its own threads, once it is
            // worth a thread pool (n^3 / 3 flops: 0.36 Gflop, tens of milliseconds, at
            // n = 1024).
            let threads = if n_interface >= 1024 {
                std::thread::available_parallelism().map_or(1, |n| n.get())
            } else {
                1
            };
            Some(InterfaceSystem::new(n_interface, pieces, threads))
        }
        Ok(None) => None,
        Err(e) => Some(Err(e)),
    };
    mpi.barrier_sleeping();
    mpi.agree(interface.transpose())
}

/// The default path: each rank factors its subdomain with its boundary dofs last and
/// eliminates its own contact dofs with that factor; the first rank factors the summed
/// interface system; the loop sweeps on the boundary system.
fn solve_condensed(
    mpi: &Mpi,
    setup: &Setup,
    sub: &SubProblem,
    params: &contact::Params,
    monitor: &mut dyn FnMut(&Sweep),
    ckpt: &CheckpointFiles,
) -> Result<(contact::Outcome, Vec<[f64; 2]>, Phases)> {
    let frictional = Problem::is_frictional(&setup.case);
    let mut local = mpi.agree(LocalSystem::new(setup, sub))?;
    let t_condense = Instant::now();
    let (g_local, interior_forward) = local.factor.condensed_rhs(&local.base);
    let forward_s = t_condense.elapsed().as_secs_f64();
    let s_local = local.factor.interface_schur();
    let rows = mpi.agree(ContactRows::new(
        &sub.contact_nodes,
        &sub.fixed,
        &sub.boundary_dofs,
        setup.normal,
        setup.tangent,
        frictional,
    ))?;
    let schur_s = t_condense.elapsed().as_secs_f64();

    // 3. First rank: the interface system, summed and factored once.
    let has_interface = setup.n_interface > 0;
    let interface = if has_interface {
        build_interface(mpi, sub, s_local, setup.n_interface)?
    } else {
        None
    };
    let interface_counts = if has_interface {
        let mut counts = Vec::new();
        mpi.all_gather(
            &[sub.interface_global.len() as f64],
            &vec![1; mpi.size],
            &mut counts,
        );
        counts.iter().map(|&c| c as usize).collect()
    } else {
        vec![0; mpi.size]
    };
    let condense_s = t_condense.elapsed().as_secs_f64();
    let interface_factor = interface
        .as_ref()
        .map(|i| if i.is_sparse() { "sparse" } else { "dense" });
    let interface_flops = interface
        .as_ref()
        .map_or(0.0, InterfaceSystem::factor_flops);

    let t_loop = Instant::now();
    let n_own = sub.contact_nodes.len();
    let mut step = CondensedStep {
        mpi,
        setup,
        sub,
        factor: &mut local.factor,
        response: LocalResponse::new(rows, g_local),
        interface,
        interface_counts,
        forces: Vec::new(),
        gathered: Vec::new(),
        solved: Vec::new(),
        x_g: Vec::new(),
        out: Vec::new(),
    };
    let outcome = run_loop(&mut step, mpi, sub, params, monitor, ckpt)?;
    let loop_s = t_loop.elapsed().as_secs_f64();

    // Recover the displacement from the boundary values of the last sweep, which every
    // rank holds: the backward half of a sparse solve for the interior.
    let t_recover = Instant::now();
    if outcome.iterations == 0 {
        // A loop that never solved: the boundary values of zero forces.
        let zero = vec![0.0; n_own];
        let (mut un, mut ut) = (zero.clone(), zero.clone());
        step.solve(&zero, &zero, &mut un, &mut ut)?;
    }
    let x_b = step.response.boundary_values();
    drop(step);
    let t_solves = Instant::now();
    let u_free = local.factor.recover(&interior_forward, &x_b);
    let one_solve = forward_s + t_solves.elapsed().as_secs_f64();
    let u_local: Vec<[f64; 2]> = local
        .dofs
        .expand(&u_free)
        .chunks_exact(2)
        .map(|c| [c[0], c[1]])
        .collect();
    Ok((
        outcome,
        u_local,
        Phases {
            assemble: local.assemble_s,
            factor: local.factor_s,
            condense: condense_s,
            uzawa: loop_s,
            recover: t_recover.elapsed().as_secs_f64(),
            ordering: local.factor.ordering_s,
            ordering_used: local.factor.ordering,
            schur: schur_s,
            interface_factor,
            interface_flops,
            factor_nnz: local.factor.factor_nnz(),
            factor_flops: local.factor.factor_flops(),
            one_solve,
        },
    ))
}

/// Where the loop state is saved and whether to resume from it.
pub struct CheckpointFiles {
    dir: PathBuf,
    every: usize,
    restart: bool,
    /// MPI ranks and subdomains per rank: a checkpoint resumes on the same layout.
    ranks: usize,
    per_rank: usize,
}

/// One subdomain's checkpoint (`rank` is the subdomain, as in the file name).
#[derive(Serialize, serde::Deserialize)]
struct CheckpointFile {
    ranks: usize,
    per_rank: usize,
    rank: usize,
    contact_nodes: usize,
    snapshot: contact::Snapshot,
}

impl CheckpointFiles {
    fn path(&self, rank: usize) -> PathBuf {
        self.dir.join(format!("rank_{rank}.bin"))
    }
}

/// The Uzawa loop with the checkpoint files of this rank. The snapshots are written
/// atomically; on restart every rank checks that all ranks resume from the same sweep.
fn run_loop(
    step: &mut impl LinearStep,
    mpi: &Mpi,
    sub: &SubProblem,
    params: &contact::Params,
    monitor: &mut dyn FnMut(&Sweep),
    files: &CheckpointFiles,
) -> Result<contact::Outcome> {
    let resume = if files.restart {
        let path = files.path(mpi.rank);
        let read = std::fs::read(&path)
            .map_err(|e| Error::Input(format!("{}: cannot read the checkpoint: {e}; run without --restart, or with the --out of the interrupted run", path.display())))
            .and_then(|b| {
                decode::<CheckpointFile>(&b).map_err(|_| {
                    Error::Input(format!("{}: not a contact-par checkpoint of this version; run without --restart", path.display()))
                })
            })
            .and_then(|c| {
                if c.ranks != files.ranks || c.per_rank != files.per_rank || c.rank != mpi.rank || c.contact_nodes != sub.contact_nodes.len() {
                    Err(Error::Input(format!(
                        "{}: written by a run on {} rank(s) x {} subdomain(s) per rank, or of another case or mesh; restart the same case with mpirun -n {} and --subdomains-per-rank {}",
                        path.display(),
                        c.ranks,
                        c.per_rank,
                        c.ranks,
                        c.per_rank
                    )))
                } else {
                    Ok(c.snapshot)
                }
            });
        let snap = mpi.agree(read)?;
        let mut sweeps = [snap.history.len() as f64, -(snap.history.len() as f64)];
        mpi.max_in_place(&mut sweeps);
        if sweeps[0] != -sweeps[1] {
            return mpi.agree(Err(Error::Input(format!(
                "{}: the ranks' checkpoints are from different sweeps (a crash while saving); run without --restart",
                files.dir.display()
            ))));
        }
        Some(snap)
    } else {
        None
    };
    let every = files.every;
    let mut save = |snap: &contact::Snapshot| -> Result<()> {
        std::fs::create_dir_all(&files.dir)
            .map_err(|e| Error::Output(format!("cannot create {}: {e}", files.dir.display())))?;
        let file = CheckpointFile {
            ranks: files.ranks,
            per_rank: files.per_rank,
            rank: mpi.rank,
            contact_nodes: sub.contact_nodes.len(),
            snapshot: snap.clone(),
        };
        output::write_atomic(&files.path(mpi.rank), &encode(&file)?)
    };
    let mut ckpt = contact::Checkpoints {
        every,
        save: &mut save,
        resume,
    };
    contact::solve_with(step, mpi, &sub.contact, params, monitor, &mut ckpt)
}

/// The uncondensed path (one rank): a sparse forward and backward solve per sweep.
fn solve_full(
    mpi: &Mpi,
    setup: &Setup,
    sub: &SubProblem,
    params: &contact::Params,
    monitor: &mut dyn FnMut(&Sweep),
    ckpt: &CheckpointFiles,
) -> Result<(contact::Outcome, Vec<[f64; 2]>, Phases)> {
    let (mut step, times) = DirectStep::new(
        &sub.nodes,
        &sub.triangles,
        &setup.case.material,
        &sub.fixed,
        &sub.load,
        &ContactDofs {
            nodes: &sub.contact_nodes,
            w: &sub.contact.w,
            normal: setup.normal,
            tangent: setup.tangent,
            frictional: Problem::is_frictional(&setup.case),
        },
        setup.r,
    )?;
    let t_loop = Instant::now();
    let outcome = run_loop(&mut step, mpi, sub, params, monitor, ckpt)?;
    let one_solve = t_loop.elapsed().as_secs_f64() / outcome.iterations.max(1) as f64;
    Ok((
        outcome,
        step.displacement(),
        Phases {
            assemble: times.assemble,
            factor: times.factor,
            condense: 0.0,
            uzawa: t_loop.elapsed().as_secs_f64(),
            recover: 0.0,
            ordering: 0.0,
            ordering_used: Ordering::Amd,
            schur: 0.0,
            interface_factor: None,
            interface_flops: 0.0,
            factor_nnz: step.factor_nnz(),
            factor_flops: step.factor_flops(),
            one_solve,
        },
    ))
}

fn print_timings(print: &Printer, t: &Timings, iterations: usize) {
    print.line("phase         seconds");
    for (name, v) in [
        ("read", t.read),
        ("partition", t.partition),
        ("scatter", t.scatter),
        ("assemble", t.assemble),
        ("factor", t.factor),
        ("condense", t.condense),
        ("loop", t.uzawa),
        ("recover", t.recover),
        ("output", t.output),
        ("total", t.total),
    ] {
        let extra = if name == "loop" && iterations > 0 {
            format!(
                "   ({iterations} sweeps, {:.3} ms/sweep)",
                1e3 * t.uzawa / iterations as f64
            )
        } else {
            String::new()
        };
        print.line(format!("{name:<10} {v:>10.3}{extra}"));
    }
}

/// Element stresses (sxx, syy, sxy, szz) and von Mises, in parallel.
pub fn element_stresses(case: &Case, mesh: &Mesh, u: &[[f64; 2]]) -> (Vec<[f64; 4]>, Vec<f64>) {
    let d = fem::elasticity_matrix(&case.material);
    let stress: Vec<[f64; 4]> = mesh
        .triangles
        .par_iter()
        .map(|t| {
            let p = [mesh.nodes[t[0]], mesh.nodes[t[1]], mesh.nodes[t[2]]];
            let ue = [
                u[t[0]][0], u[t[0]][1], u[t[1]][0], u[t[1]][1], u[t[2]][0], u[t[2]][1],
            ];
            let [sxx, syy, sxy] = fem::element_stress(&p, &d, &ue);
            [sxx, syy, sxy, fem::stress_zz(&case.material, sxx, syy)]
        })
        .collect();
    let vm = stress.par_iter().map(fem::von_mises).collect();
    (stress, vm)
}

/// What each rank sends the first rank for the gathered outputs: contact rows
/// (x, y, u_n, u_t, p_n, p_t, gap, status, w), owned nodes (global id; x, y, ux, uy), figures.
type RankOutput = (Vec<[f64; 9]>, Vec<(usize, [f64; 4])>, RankStats);

/// The `k`-th `.vtu` file of subdomain `subdomain`'s piece.
fn vtu_file_name(subdomain: usize, k: usize) -> String {
    format!("solution_{subdomain}_{k}.vtu")
}

/// This subdomain's .vtu files, and what the first subdomain needs of it for the rest.
#[allow(clippy::too_many_arguments)]
fn write_piece(
    opts: &Options,
    mpi: &Mpi,
    setup: &Setup,
    sub: &SubProblem,
    u: &[[f64; 2]],
    o: &contact::Outcome,
    mut stats: RankStats,
    t_out: Instant,
) -> Result<RankOutput> {
    let case = &setup.case;
    let dir = &opts.out;
    keep_freed_blocks_for_reuse();
    std::fs::create_dir_all(dir).map_err(|e| {
        Error::Output(format!(
            "cannot create the output directory {}: {e}; choose another with --out",
            dir.display()
        ))
    })?;

    // This rank's piece of the field output.
    let mesh = Mesh {
        nodes: sub.nodes.clone(),
        triangles: sub.triangles.clone(),
        ..Default::default()
    };
    let (stress, vm) = element_stresses(case, &mesh, u);
    let n = sub.nodes.len();
    let mut pressure = vec![0.0; n];
    let mut traction = vec![0.0; n];
    let mut status = vec![-1i32; n];
    for (k, &node) in sub.contact_nodes.iter().enumerate() {
        pressure[node] = o.lambda[k];
        traction[node] = -o.mu[k] + 0.0;
        status[node] = o.status[k] as i32;
    }
    let rank_field = vec![mpi.rank as i32; sub.triangles.len()];
    let piece = output::Piece {
        nodes: &sub.nodes,
        triangles: &sub.triangles,
        displacement: u,
        stress: &stress,
        von_mises: &vm,
        rank: &rank_field,
        contact_pressure: &pressure,
        tangential_traction: &traction,
        contact_status: &status,
    };
    let ranges = output::file_ranges(&piece)?;
    // The files are independent and vtkio encodes on one thread: a rank with several
    // threads encodes and writes several files at once.
    let rank = mpi.rank;
    ranges.par_iter().enumerate().try_for_each(|(k, range)| {
        let part = output::SubPiece::new(&piece, range.clone());
        output::write_atomic(
            &dir.join(vtu_file_name(rank, k)),
            &output::vtu_bytes(&part.piece())?,
        )
    })?;
    stats.vtu_files = ranges.len();

    // Contact rows and owned nodes travel to the first rank.
    let rows: Vec<[f64; 9]> = sub
        .contact_nodes
        .iter()
        .enumerate()
        .map(|(k, &node)| {
            let x = sub.nodes[node];
            [
                x[0],
                x[1],
                o.un[k],
                o.ut[k],
                o.lambda[k],
                -o.mu[k] + 0.0,
                sub.contact.g[k],
                o.status[k] as i32 as f64,
                sub.contact.w[k],
            ]
        })
        .collect();
    let owned: Vec<(usize, [f64; 4])> = if opts.nodes_csv {
        (0..n)
            .filter(|&l| sub.owned[l])
            .map(|l| {
                (
                    sub.global_nodes[l],
                    [sub.nodes[l][0], sub.nodes[l][1], u[l][0], u[l][1]],
                )
            })
            .collect()
    } else {
        Vec::new()
    };
    stats.peak_memory_bytes = peak_memory_bytes();
    stats.output_s = t_out.elapsed().as_secs_f64();
    Ok((rows, owned, stats))
}

/// Every subdomain writes its piece; the first gathers the contact rows, the owned
/// nodes and the figures and writes the files of the whole run.
/// `piece` is this subdomain's [`write_piece`]: every subdomain reaches the gather,
/// failed or not, so that none waits for another.
#[allow(clippy::too_many_arguments)]
fn write_outputs(
    opts: &Options,
    mpi: &Mpi,
    setup: &Setup,
    o: &contact::Outcome,
    piece: Result<RankOutput>,
    mut times: Timings,
    t_out: Instant,
    t_start: Instant,
) -> Result<()> {
    let case = &setup.case;
    let dir = &opts.out;
    let (mine, failure) = match piece {
        Ok(v) => (Some(v), None),
        Err(e) => (None, Some(e)),
    };
    let gathered = mpi.gather_parts(mine);
    if let Some(e) = failure {
        return Err(e);
    }
    let Some(gathered) = gathered? else {
        return Ok(());
    };
    // A subdomain that failed reports its own error (the agreement after this call).
    let Some(gathered) = gathered.into_iter().collect::<Option<Vec<RankOutput>>>() else {
        return Ok(());
    };
    let mut all_rows = Vec::new();
    let mut all_nodes = Vec::new();
    let mut all_stats = Vec::new();
    for (rr, nn, ss) in gathered {
        all_rows.extend(rr);
        all_nodes.extend(nn);
        all_stats.push(ss);
    }

    let contact_rows: Vec<ContactRow> = all_rows
        .iter()
        .map(|r| ContactRow {
            x: r[0],
            y: r[1],
            u_n: r[2],
            u_t: r[3],
            p_n: r[4],
            p_t: r[5],
            gap: r[6],
        })
        .collect();
    output::write_atomic(
        &dir.join("contact.csv"),
        output::contact_csv(&contact_rows).as_bytes(),
    )?;
    if opts.nodes_csv {
        all_nodes.sort_unstable_by_key(|(g, _)| *g);
        let xy: Vec<[f64; 2]> = all_nodes.iter().map(|(_, v)| [v[0], v[1]]).collect();
        let uu: Vec<[f64; 2]> = all_nodes.iter().map(|(_, v)| [v[2], v[3]]).collect();
        output::write_atomic(
            &dir.join("nodes.csv"),
            output::nodes_csv(&xy, &uu).as_bytes(),
        )?;
    }
    output::write_atomic(
        &dir.join("history.csv"),
        output::history_csv(&o.history).as_bytes(),
    )?;
    let sources: Vec<String> = all_stats
        .iter()
        .flat_map(|st| (0..st.vtu_files).map(|k| vtu_file_name(st.subdomain, k)))
        .collect();
    output::write_atomic(&dir.join("solution.pvtu"), &output::pvtu_bytes(&sources)?)?;

    let with_status = |s: Status| all_rows.iter().filter(|r| r[7] == s as i32 as f64).count();
    let (stick, slip) = (with_status(Status::Stick), with_status(Status::Slip));
    let active = stick + slip;
    let last = o.history.last();
    times.output = t_out.elapsed().as_secs_f64();
    times.total = t_start.elapsed().as_secs_f64();
    let max_over =
        |f: &dyn Fn(&RankStats) -> f64| all_stats.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
    let min_over =
        |f: &dyn Fn(&RankStats) -> f64| all_stats.iter().map(f).fold(f64::INFINITY, f64::min);
    // The subdomains of a rank share its process, so its peak.
    let peak_per_rank: Vec<u64> = (0..mpi.mpi_size)
        .map(|r| {
            all_stats
                .iter()
                .filter(|s| s.rank == r)
                .map(|s| s.peak_memory_bytes)
                .max()
                .unwrap_or(0)
        })
        .collect();
    let summary = serde_json::json!({
        "title": case.title,
        "case": case.origin,
        "converged": o.converged,
        "iterations": o.iterations,
        "outer_iterations": o.outer_iterations,
        "acceleration": format!("{:?}", case.solver.acceleration),
        "refused_accelerations": o.refused,
        "ranks": mpi.mpi_size,
        "threads": rayon::current_num_threads(),
        "linear": format!("{:?}", opts.linear).to_lowercase(),
        "nodes": setup.nodes,
        "elements": setup.elements,
        "dofs": 2 * setup.nodes,
        "free_dofs": setup.free_dofs,
        "boundary_dofs": setup.n_boundary,
        "interface_dofs": setup.n_interface,
        "contact_nodes": setup.contact_nodes,
        "active_nodes": active,
        "stick_nodes": stick,
        "slip_nodes": slip,
        "total_normal_force": all_rows.iter().map(|r| r[8] * r[4]).sum::<f64>(),
        "total_tangential_force": all_rows.iter().map(|r| r[8] * r[5]).sum::<f64>(),
        "friction": friction_name(&case.contact.friction),
        "r": setup.r,
        "r_retunes": o.retunes,
        "tol": case.solver.tol,
        "final_residuals": { "primal": last.map(|s| s.primal), "dual": last.map(|s| s.dual) },
        "timings_s": times,
        "sweep_s": times.uzawa / o.iterations.max(1) as f64,
        "one_solve_s": max_over(&|s| s.one_solve_s),
        "peak_memory_bytes": all_stats.iter().map(|s| s.peak_memory_bytes).max().unwrap_or(0),
        "peak_memory_bytes_per_rank": peak_per_rank,
        "per_subdomain": all_stats,
        "per_subdomain_max": {
            "assemble_s": max_over(&|s| s.assemble_s), "factor_s": max_over(&|s| s.factor_s),
            "loop_s": max_over(&|s| s.loop_s), "elements": max_over(&|s| s.elements as f64),
            "interface_nodes": max_over(&|s| s.interface_nodes as f64),
        },
        "per_subdomain_min": {
            "assemble_s": min_over(&|s| s.assemble_s), "factor_s": min_over(&|s| s.factor_s),
            "loop_s": min_over(&|s| s.loop_s), "elements": min_over(&|s| s.elements as f64),
            "interface_nodes": min_over(&|s| s.interface_nodes as f64),
        },
        "partition": setup.partition,
    });
    // Past the json! macro's recursion limit.
    let mut summary = summary;
    summary["subdomains"] = mpi.size.into();
    summary["interface_factor"] = all_stats
        .iter()
        .find_map(|s| s.interface_factor.clone())
        .into();
    summary["interface_gflop"] = all_stats
        .iter()
        .map(|s| s.interface_gflop)
        .sum::<f64>()
        .into();
    summary["subdomains_per_rank"] = setup.per_rank.into();
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::Output(format!("cannot format summary.json: {e}")))?;
    output::write_atomic(&dir.join("summary.json"), json.as_bytes())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{
        idle_core_threads, subdomains_per_rank, MAX_DEFAULT_SUBDOMAINS, MIN_TRIANGLES_PER_SUBDOMAIN,
    };

    #[test]
    fn a_rank_splits_into_one_subdomain_per_thread_while_they_stay_large_and_few() {
        let m = MIN_TRIANGLES_PER_SUBDOMAIN;
        // A laptop: one rank, its threads, a large mesh.
        assert_eq!(subdomains_per_rank(2, 1, 2_400_000), 2);
        assert_eq!(subdomains_per_rank(4, 1, 2_400_000), 4);
        // Never more than the threads, never fewer than one.
        assert_eq!(subdomains_per_rank(1, 1, 2_400_000), 1);
        assert_eq!(subdomains_per_rank(0, 1, 2_400_000), 1);
        // Small meshes: as many subdomains as keep the threshold each.
        assert_eq!(subdomains_per_rank(8, 1, 3 * m + 1), 3);
        assert_eq!(subdomains_per_rank(8, 2, 3 * m), 1);
        assert_eq!(subdomains_per_rank(8, 1, m - 1), 1);
        // Few subdomains in the whole job: many ranks keep one each.
        assert_eq!(
            subdomains_per_rank(16, 1, 100_000_000),
            MAX_DEFAULT_SUBDOMAINS
        );
        assert_eq!(
            subdomains_per_rank(16, 2, 100_000_000),
            MAX_DEFAULT_SUBDOMAINS / 2
        );
        assert_eq!(subdomains_per_rank(16, 64, 100_000_000), 1);
        assert_eq!(subdomains_per_rank(4, 0, 100_000_000), 4);
    }

    #[test]
    fn the_first_rank_borrows_only_the_cores_of_its_node_it_may_run_on() {
        // Two ranks of one thread, unbound on two cores: both cores.
        assert_eq!(idle_core_threads(1, 2, 2), 2);
        // One rank told to use one thread: no other rank's cores to borrow.
        assert_eq!(idle_core_threads(1, 1, 2), 1);
        // Bound to one core (Open MPI's default for two ranks): that core.
        assert_eq!(idle_core_threads(1, 2, 1), 1);
        // More threads than cores asked for: never fewer than its own.
        assert_eq!(idle_core_threads(4, 2, 2), 4);
        // A cluster node of 64 cores with 16 ranks of 4 threads.
        assert_eq!(idle_core_threads(4, 16, 64), 64);
        assert_eq!(idle_core_threads(1, 32, 64), 32);
    }
}
