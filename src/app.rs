//! One run of the program, told as numbered phases: 1 read, 2 partition, 3 distribute,
//! 4 assemble and factor, 5 condense, 6 iterate, 7 recover, 8 write. Each phase is a call
//! into the module that owns it, timed by one [`Timer`]; `main.rs` only wires the
//! command line and MPI to this.

use crate::case::{self, BuiltinMesh, Case, MeshSource};
use crate::checkpoint::CheckpointFiles;
use crate::contact::obstacle::Obstacle;
use crate::contact::operators::ContactDofs;
use crate::contact::roundoff_warning;
use crate::contact::tangent_of;
use crate::contact::{
    self, Acceleration, CoulombMode, Friction, LinearStep, Outcome, Reduce, Status, Sweep,
};
use crate::dd::comm::Mpi;
use crate::dd::dist_problem;
use crate::dd::dist_split::{self, Conditions, PartCase};
use crate::dd::full::{DirectStep, DirectSystem};
use crate::dd::local_factor::LocalFactor;
use crate::dd::ownership::{InterfaceFigures, PartLists};
use crate::dd::share_cut::{cut_shares, ShareCut};
use crate::dd::split::{split, split_whole, GlobalMap, SubProblem};
use crate::dd::step::{CondensedStep, LocalSystem, StepSetup};
use crate::error::{Error, Result};
use crate::fem::{AssemblyFigures, Material, Materials};
use crate::host;
use crate::linear::Ordering;
use crate::mesh::{builtin, gmsh, Mesh};
use crate::output::plot::{Foundation, ACROSS_NORMALS, ALONG_OBSTACLES};
use crate::output::{
    self, blocks, BodySummary, ContactRow, Gathered, PieceRows, PlotFacts, RankStats, RunFacts,
    SharedFile, SubdomainSolution, Written,
};
use crate::problem::{self, contact_modulus, free_at_answer, NodeAtAnswer, Problem};
use crate::split_dir::{self, Facts, Split};
use crate::timer::{self, Phase, Timer, Timings};
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
    /// Draw contact.png and convergence.png.
    pub plots: bool,
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
    /// Where the interface system is factored.
    pub interface: InterfaceMode,
    /// Subdomains per rank, each on its own thread; `None`: [`host::subdomains_per_rank`].
    pub subdomains_per_rank: Option<usize>,
    /// A directory of `contact-par split`: each subdomain reads its own part there.
    pub mesh_split: Option<PathBuf>,
    /// Who reads a Gmsh file on several ranks.
    pub mesh_read: MeshRead,
    /// Who cuts the mesh into subdomains (a run from one mesh, not from a split).
    pub partitioner: Partitioner,
}

/// Who cuts the mesh's dual graph into subdomains in a run from one mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Partitioner {
    /// [`Partitioner::PtScotch`] when the ranks span several nodes, else
    /// [`Partitioner::Geometric`]: on one node the first rank borrows every core the
    /// others would cut on, and cut 2M triangles faster there than PT-Scotch
    /// (docs/performance.md); on a cluster the first rank has its node's cores only,
    /// and into many parts it alone slows down (docs/cost-model.md).
    Auto,
    /// The first rank alone: recursive straight cuts through the triangles' centroids,
    /// refined (`partition::MeshGraph::cut_straight`): edge cuts within a few percent of
    /// METIS's on the meshes measured, at a fraction of its cost; METIS where they leave
    /// a part in pieces (docs/performance.md).
    Geometric,
    /// The first rank alone: the graph coarsened, METIS on the coarsest, refined back
    /// (the `partition` crate).
    Metis,
    /// Every rank: PT-Scotch on the graph spread over the ranks in consecutive ranges.
    PtScotch,
}

impl Partitioner {
    /// Whether the ranks cut the graph into `nparts` parts together.
    fn on_ranks(self, mpi: &Mpi, nparts: usize) -> bool {
        mpi.size > 1
            && nparts > 1
            && match self {
                Partitioner::Auto => mpi.node_ranks < mpi.size,
                Partitioner::Geometric | Partitioner::Metis => false,
                Partitioner::PtScotch => true,
            }
    }

    /// Whether the first rank tries straight cuts before METIS.
    fn straight_first(self) -> bool {
        matches!(self, Partitioner::Auto | Partitioner::Geometric)
    }
}

/// The first rank's cut of `graph` (of `prob`'s triangles) into `nparts` parts: straight
/// cuts where `straight` asks for them and they apply, else METIS; with the name of the
/// method that made it.
fn first_rank_cut(
    graph: &partition::MeshGraph,
    prob: &Problem,
    nparts: usize,
    straight: bool,
) -> (
    std::result::Result<Parts, partition::PartitionError>,
    &'static str,
) {
    if straight {
        if let Some(parts) = graph.cut_straight(&prob.mesh.centroids(), nparts) {
            return (Ok(Parts::Straight(parts)), "straight cuts");
        }
    }
    (graph.cut(nparts).map(Parts::Graph), "METIS")
}

/// Who reads a Gmsh mesh file when the job has several ranks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshRead {
    /// [`MeshRead::Shared`] when the ranks span several nodes, else [`MeshRead::First`].
    Auto,
    /// The first rank, on the idle cores of its node.
    First,
    /// Every rank parses a share of an MSH 4.1 file's nodes and elements
    /// ([`read_together`]).
    Shared,
}

/// Where the interface system (the subdomains' condensed parts, summed) is factored and
/// solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum InterfaceMode {
    /// [`InterfaceMode::Mumps`] from [`AUTO_MUMPS_SUBDOMAINS`] subdomains on, else
    /// [`InterfaceMode::Rank0`].
    Auto,
    /// Gathered, summed and factored on the first rank, which solves each sweep.
    Rank0,
    /// Assembled where its parts are and factored across the ranks by MUMPS.
    Mumps,
}

/// Subdomains from which `--interface auto` takes MUMPS. Measured on hertz level 4 with
/// one subdomain per rank (docs/performance-history.md): up to 8, the first rank's
/// factor is small (1.2 Gflop at 2187 interface dofs) and its solve per sweep faster
/// (3 ms against 7 ms on 2 ranks); at 16 its factor is 25.8 Gflop, 9 times any
/// subdomain's, and rank 0's peak memory 7 times the median rank's (MUMPS: 1.4 Gflop on
/// the largest rank, 1.2 times the median memory); at 32, 107 Gflop.
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
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinearMode {
    /// Condensed onto the contact dofs: one small dense product per sweep (default).
    Condensed,
    /// A full sparse forward and backward solve per sweep (one rank; for comparison).
    Full,
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

/// The whole run, on any number of ranks, each running its subdomains on threads of
/// its own (`mpi` is this rank's; on return every thread of the rank has ended).
pub fn run(opts: &Options, mpi: Mpi, print: &Printer) -> Result<RunReport> {
    let timer = Timer::start();
    if opts.linear == LinearMode::Full
        && (mpi.size > 1 || opts.subdomains_per_rank.is_some_and(|k| k > 1))
    {
        return mpi.agree(Err(Error::Input(
            "--linear full runs on one rank and one subdomain only; use the default (condensed) with mpirun or --subdomains-per-rank"
                .into(),
        )));
    }

    // 1-2. First rank: read, partition, split. The other ranks sleep meanwhile, so
    // that the cores of those on its node are its to use; where they keep their shares
    // of the file, they cut the mesh and check it together, and the first rank builds
    // only the conditions (`split_on_groups`). `threads`: the rank's own, not those of
    // the pool the set-up borrows.
    let threads = rayon::current_num_threads();
    let layout = Layout {
        ranks: mpi.size,
        threads,
    };
    let (setup, subs) = read_and_split(opts, &mpi, layout, &timer, print)?;

    // 3. Distribute: the set-up to every rank, every subdomain of a rank on a thread of
    // its own (this one included), then each its subproblem (`run_subdomain`).
    let setup = &timer.time(Phase::Scatter, || mpi.broadcast(setup))?;
    host::share_threads(threads, setup.per_rank);
    let (leader, members) = mpi.into_team(setup.per_rank);
    let member = |m| {
        let (mpi, timer) = (Mpi::member(m), timer.fork());
        let print = &Printer { enabled: false };
        let ctx = Subdomain::new(opts, &mpi, setup, &timer, print);
        // The first subdomain to fail holds the message (see Mpi::agree).
        if let Err(e) = run_subdomain(&ctx, None) {
            if !matches!(e, Error::Silent(_)) {
                eprintln!("contact-par: error: {e}");
            }
        }
    };
    let ctx = Subdomain::new(opts, &leader, setup, &timer, print);
    host::on_subdomain_threads(members, leader.rank, member, || run_subdomain(&ctx, subs))
}

/// Phases 1-2, collective: the set-up on the first rank, and the subproblems: all of
/// them on the first rank, or each rank's own where the ranks built them.
fn read_and_split(
    opts: &Options,
    mpi: &Mpi,
    layout: Layout,
    timer: &Timer,
    print: &Printer,
) -> Result<(Option<Setup>, Option<Vec<SubProblem>>)> {
    let (early, shares) = read_together(opts, mpi, layout, timer);
    if let Some(shares) = shares {
        return split_on_groups(opts, mpi, layout, timer, print, (early, shares));
    }
    let prepared = mpi.is_root().then(|| {
        host::on_idle_cores(mpi.node_ranks, || {
            prepare(opts, layout, timer, print, early)
                .and_then(|r| with_graph(r, None, false, timer))
        })
    });
    mpi.barrier_sleeping();
    let prepared = mpi.agree(prepared.transpose())?;
    let phase1 = Phase1 {
        prepared,
        lists: None,
    };
    cut_and_split(opts, mpi, layout, timer, print, phase1)
}

/// One subdomain's run, from its subproblem to its outputs (collective over all).
fn run_subdomain(ctx: &Subdomain, subs: Option<Vec<SubProblem>>) -> Result<RunReport> {
    let mpi = ctx.mpi;
    // From the first subdomain, or each its own: from the split directory, or built
    // on its rank (`dd::dist_split`).
    let own = ctx.setup.own_parts;
    let sub = &ctx.timer.time(Phase::Scatter, || match &ctx.setup.split {
        Some(split) => mpi.agree(split.read_part(mpi.rank)),
        None if own => {
            // The rank's leader built its team's parts, one per subdomain thread.
            let k = mpi.per_rank();
            let dealt = subs.map(|s| {
                let mut s: Vec<Result<SubProblem>> = s.into_iter().map(Ok).collect();
                s.resize_with(k, || {
                    Err(Error::Numerical(
                        "internal: a rank has too few parts of its own".into(),
                    ))
                });
                s
            });
            mpi.agree(mpi.deal(dealt))
        }
        None => mpi.agree(mpi.scatter_parts(subs)),
    })?;
    ctx.phase_done(
        Phase::Scatter,
        match (&ctx.setup.split, own) {
            (Some(_), _) => format!("{} part(s) read from the split", mpi.size),
            (None, true) => format!("{} part(s) built on their ranks", mpi.size),
            (None, false) => format!("{} part(s) handed out", mpi.size),
        },
    );

    // 4-7. Assemble and factor, condense, iterate, recover.
    let solved = match ctx.opts.linear {
        LinearMode::Condensed => solve_condensed(ctx, sub)?,
        LinearMode::Full => solve_full(ctx, sub)?,
    };

    // 8. Write: each subdomain its piece, the first the files of the whole run.
    let timings = write(ctx, sub, &solved)?;
    report(ctx, sub, &solved.outcome, &timings)
}

/// The default path: each subdomain factors its matrix with its boundary dofs last and
/// eliminates its own contact dofs with that factor; the first rank factors the summed
/// interface system; the loop sweeps on the boundary system.
fn solve_condensed(ctx: &Subdomain, sub: &SubProblem) -> Result<Solved> {
    let (mpi, timer, setup) = (ctx.mpi, ctx.timer, ctx.setup.step());
    // 4. Assemble and factor this subdomain.
    let assembled = |a| ctx.assembled(a);
    let local = mpi.agree(LocalSystem::new(&setup, sub, timer, &assembled))?;
    let f = &local.factor;
    ctx.factored(f.factor_flops(), f.factor_nnz(), f.ordering);
    // 5. Condense onto the boundary; the interface system, summed and factored once.
    let condense = || CondensedStep::condense(mpi, setup, sub, local, timer);
    let mut step = timer.time(Phase::Condense, condense)?;
    ctx.condensed(&step);
    // 6. Iterate.
    let outcome = iterate(ctx, sub, &mut step)?;
    // 7. Recover the interior from the boundary values of the last sweep.
    let u = timer.time(Phase::Recover, || step.recover(outcome.iterations, timer))?;
    ctx.phase_done(
        Phase::Recover,
        format!("the displacement of {} nodes", ctx.setup.facts.nodes),
    );
    let factors = FactorFigures::condensed(&step);
    host::drop_in_background(step.into_local());
    Ok(Solved::new(sub, outcome, u, factors))
}

/// The uncondensed path (one rank): a sparse forward and backward solve per sweep, so
/// nothing to condense or recover.
fn solve_full(ctx: &Subdomain, sub: &SubProblem) -> Result<Solved> {
    let (setup, timer) = (ctx.setup, ctx.timer);
    // 4. Assemble and factor the whole mesh.
    let assembled = |a| ctx.assembled(a);
    let mut step = DirectStep::new(&setup.direct_system(sub), timer, &assembled)?;
    ctx.factored(step.factor_flops(), step.factor_nnz(), Ordering::Amd);
    // 6. Iterate.
    let outcome = iterate(ctx, sub, &mut step)?;
    let sweeps = outcome.iterations.max(1) as f64;
    timer.add(Phase::OneSolve, timer.seconds(Phase::Loop) / sweeps);
    let factors = FactorFigures::full(step.factor_nnz(), step.factor_flops());
    Ok(Solved::new(sub, outcome, step.displacement(), factors))
}

/// Phase 6: the Uzawa loop on this subdomain's contact nodes, with its checkpoint files
/// and the monitor lines.
fn iterate(ctx: &Subdomain, sub: &SubProblem, step: &mut impl LinearStep) -> Result<Outcome> {
    let (opts, mpi) = (ctx.opts, ctx.mpi);
    let frictional = Problem::is_frictional(&ctx.setup.case);
    let mut monitor = Monitor::new(ctx.print, opts.monitor_every, frictional);
    let sent_before = crate::dd::comm::bytes_sent();
    let outcome = {
        let _t = ctx.timer.phase(Phase::Loop);
        let files = CheckpointFiles::new(&opts.out, opts.checkpoint_every, opts.restart, mpi);
        let n = sub.contact_nodes.len();
        let mut save = |snap: &contact::Snapshot| files.save(mpi.rank, n, snap);
        let mut ckpt = contact::Checkpoints {
            every: files.every,
            save: &mut save,
            resume: files.resume(mpi, n)?,
        };
        let params = ctx.setup.params();
        let mut on_sweep = |s: &Sweep| monitor.sweep(s);
        let nodes = problem::with_friction_values(&ctx.setup.case, &sub.contact);
        let mut o = contact::solve_with(step, mpi, &nodes, &params, &mut on_sweep, &mut ckpt)?;
        // A frictionless contact's nodes in a frictional run (a zero threshold) neither
        // stick nor slip: in contact, as in a frictionless run.
        for (status, &pair) in o.status.iter_mut().zip(&sub.contact.pair) {
            let none = ctx.setup.case.contacts[pair as usize].friction == Friction::None;
            if none && matches!(status, Status::Stick | Status::Slip) {
                *status = Status::Contact;
            }
        }
        o
    };
    monitor.last(&outcome);
    let sweeps = outcome.iterations;
    let per_sweep = 1e3 * ctx.timer.seconds(Phase::Loop) / sweeps.max(1) as f64;
    ctx.phase_done(
        Phase::Loop,
        format!(
            "{sweeps} sweeps ({per_sweep:.3} ms each), {}",
            if outcome.converged {
                "converged"
            } else {
                "NOT converged"
            }
        ),
    );
    let sent = crate::dd::comm::bytes_sent() - sent_before;
    ctx.sent_per_sweep
        .set(sent as f64 / outcome.iterations.max(1) as f64);
    Ok(outcome)
}

/// Phase 8: every subdomain writes its piece and sends its rows to the first, which
/// writes the files of the whole run. The timer is read once, at the end of this
/// phase, for both summary.json and the printed table.
fn write(ctx: &Subdomain, sub: &SubProblem, solved: &Solved) -> Result<Timings> {
    let (opts, mpi, timer) = (ctx.opts, ctx.mpi, ctx.timer);
    let output = timer.phase(Phase::Output);
    let piece = write_piece(ctx, sub, solved);
    let tables = gather(mpi, piece).and_then(|gathered| {
        let Some(mut all) = gathered else {
            return Ok(None);
        };
        let tables = all.write_tables(&opts.out, &solved.outcome)?;
        let plots = write_plots(ctx, &all, &solved.outcome);
        let written = all.pieces + tables + plots;
        Ok(Some((all, written)))
    });
    // Every subdomain takes part, also where the tables failed (see write_nodes_csv).
    let nodes = match opts.nodes_csv {
        true => write_nodes_csv(ctx, sub, &solved.u),
        false => {
            // An earlier run's table would not match this run's answer.
            if mpi.is_root() {
                let _ = std::fs::remove_file(opts.out.join("nodes.csv"));
            }
            Ok(Written::default())
        }
    };
    let tables = nodes.and_then(|nodes| Ok(tables?.map(|(all, w)| (all, w + nodes))));
    drop(output);
    let timings = timer.finish();
    let summary = tables.and_then(|all| match all {
        Some((all, written)) => {
            let mut facts = run_facts(ctx);
            facts.warnings = free_at_answer(&ctx.setup.facts.holding, &at_answer(&all.contact));
            facts.warnings.extend(roundoff_warning(
                solved.outcome.history.last(),
                ctx.setup.case.solver.tol,
            ));
            for w in &facts.warnings {
                eprintln!("contact-par: warning: {w}");
            }
            let summary = all.write_summary(&opts.out, facts, &solved.outcome, timings)?;
            Ok(written + summary)
        }
        None => Ok(Written::default()),
    });
    let written = mpi.agree(summary)?;
    let figure = format!(
        "{} files, {:.1} MB in {}",
        written.files,
        written.bytes as f64 / 1e6,
        opts.out.display()
    );
    ctx.print
        .line(timer::phase_line(Phase::Output, timings.output, &figure));
    Ok(timings)
}

/// The pictures, on the first subdomain (`--no-plots`: none). They are a view of
/// contact.csv and history.csv, already written: one that cannot be drawn or written is
/// a warning, not a failure of the run. Pictures of an earlier run in the same directory
/// that this run does not replace are removed, as they would not match its tables.
fn write_plots(ctx: &Subdomain, all: &Gathered, o: &Outcome) -> Written {
    let dir = &ctx.opts.out;
    let results = match ctx.opts.plots {
        true => all.write_plots(dir, &plot_facts(ctx), o).map(Some),
        false => [None, None],
    };
    let mut written = Written::default();
    for (name, result) in output::PLOT_FILES.iter().zip(results) {
        match result {
            Some(Ok(w)) => written = written + w,
            Some(Err(e)) => {
                eprintln!("contact-par: warning: {e}; the run goes on without it (its data are in contact.csv and history.csv)");
                let _ = std::fs::remove_file(dir.join(name));
            }
            None => {
                let _ = std::fs::remove_file(dir.join(name));
            }
        }
    }
    written
}

/// What the pictures say of the run beside the rows.
fn plot_facts<'a>(ctx: &Subdomain<'a>) -> PlotFacts<'a> {
    let case = &ctx.setup.case;
    let bodies_only = case.contacts.iter().all(|c| c.master.is_some());
    PlotFacts {
        title: if case.title.is_empty() {
            &case.origin
        } else {
            &case.title
        },
        pairs: case.contacts.iter().map(|c| c.group.clone()).collect(),
        abscissa: match &case.contacts[..] {
            [c] => match c.obstacle {
                Some(Obstacle::Line { point, normal }) => Foundation {
                    point,
                    tangent: tangent_of(normal),
                }
                .axis_label(),
                _ if bodies_only => ACROSS_NORMALS,
                _ => ALONG_OBSTACLES,
            },
            _ if bodies_only => ACROSS_NORMALS,
            _ => ALONG_OBSTACLES,
        },
        along: match &case.contacts[..] {
            _ if bodies_only => "between the bodies",
            [_] => "along the foundation",
            _ => "along the obstacles",
        },
        friction: format!("friction {}", case.friction_name()),
        frictional: Problem::is_frictional(case),
        tol: case.solver.tol,
    }
}

/// `nodes.csv` from every rank (collective): the rows of the nodes each subdomain owns go
/// to the rank whose block of global ids holds them (`output::blocks`), and each rank
/// writes its block's text at its offset in one shared file, which the first renames
/// into place once all have written. No rank holds more than its block.
fn write_nodes_csv(ctx: &Subdomain, sub: &SubProblem, u: &[[f64; 2]]) -> Result<Written> {
    let rows: Vec<(u64, [f64; 4])> = (0..sub.nodes.len())
        .filter(|&l| sub.owned[l])
        .map(|l| {
            let (p, d) = (sub.nodes[l], u[l]);
            (sub.global_nodes[l] as u64, [p[0], p[1], d[0], d[1]])
        })
        .collect();
    let n = ctx.setup.facts.nodes;
    let path = ctx.opts.out.join("nodes.csv");
    ctx.mpi.on_leader(rows, move |leader, parts| {
        let (ranks, me) = (leader.ranks(), leader.mpi_rank());
        let mut ids = vec![Vec::new(); ranks];
        let mut values = vec![Vec::new(); ranks];
        for (id, v) in parts.into_iter().flatten() {
            let q = blocks::block_of(id as usize, n, ranks);
            ids[q].push(id);
            values[q].extend_from_slice(&v);
        }
        let (ids, values) = (leader.exchange(ids), leader.exchange(values));
        let rows = ids.iter().zip(&values).flat_map(|(ids, values)| {
            ids.iter()
                .zip(values.chunks_exact(4))
                .map(|(&id, v)| (id as usize, [v[0], v[1], v[2], v[3]]))
        });
        let text = blocks::block_text(me, n, ranks, rows)
            .map_err(|e| Error::Numerical(format!("internal: nodes.csv: {e}")));
        let lengths = leader.all_gather_u64(text.as_ref().map_or(0, |t| t.len() as u64));
        let offset: u64 = lengths[..me].iter().sum();
        let file = SharedFile::new(&path, leader.broadcast_u64(std::process::id() as u64));
        let created = match (&text, me) {
            (Ok(_), 0) => file.create(lengths.iter().sum()),
            _ => Ok(()),
        };
        let text = created.and(text);
        // A rank that failed reports; the others stay quiet (Mpi::agree).
        let quiet = || Err(Error::Silent(Error::Output(String::new()).exit_code()));
        if !leader.all_true(text.is_ok()) {
            file.discard();
            return text.and_then(|_| quiet());
        }
        let wrote = text.and_then(|t| file.write_at(offset, t.as_bytes()));
        if !leader.all_true(wrote.is_ok()) {
            file.discard();
            return wrote.and_then(|_| quiet());
        }
        match me {
            0 => file.commit(),
            _ => Ok(()),
        }?;
        Ok(Written {
            files: 1,
            bytes: lengths.iter().sum(),
        })
    })
}

/// What one subdomain's phases share.
struct Subdomain<'a> {
    opts: &'a Options,
    /// The subdomain's own: `mpi.rank` is the subdomain, `mpi.mpi_rank` its MPI rank.
    mpi: &'a Mpi,
    setup: &'a Setup,
    /// The subdomain's own; the first subdomain's also holds the set-up's phases.
    timer: &'a Timer,
    print: &'a Printer,
    /// Bytes this subdomain's rank sent per sweep of the loop (all its subdomains').
    sent_per_sweep: std::cell::Cell<f64>,
}

impl<'a> Subdomain<'a> {
    fn new(
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
    fn phase_done(&self, phase: Phase, figure: impl AsRef<str>) {
        let seconds = self.timer.seconds(phase);
        self.print
            .line(timer::phase_line(phase, seconds, figure.as_ref()));
    }

    fn assembled(&self, a: AssemblyFigures) {
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
    fn factored(&self, flops: f64, entries: usize, ordering: Ordering) {
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
    fn condensed(&self, step: &CondensedStep) {
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

/// What the first rank tells every rank before the distribution.
#[derive(Serialize, serde::Deserialize)]
struct Setup {
    case: Case,
    /// Each body's material, by body index.
    materials: Vec<Material>,
    r: f64,
    /// E_eff / h (`Lengths::mesh_stiffness`).
    mesh_stiffness: f64,
    /// Shift of the interface block of every local matrix (see `LocalFactor`).
    alpha: f64,
    /// The figures of the whole problem and its partition.
    facts: Facts,
    /// Where each subdomain reads its part (`--mesh-split`), or `None`: from the first.
    split: Option<Split>,
    ordering: Ordering,
    interface: InterfaceMode,
    /// Subdomains per rank.
    per_rank: usize,
    /// Whether each rank built its own part (`dd::dist_split`) instead of receiving it.
    own_parts: bool,
}

impl Setup {
    fn new(
        opts: &Options,
        case: Case,
        facts: Facts,
        split: Option<Split>,
        ranks: usize,
        per_rank: usize,
    ) -> Self {
        let e_eff = contact_modulus(&case, &facts.contact_bodies);
        // The interface shift scales with the stiffest body: any body's elements may
        // meet at an interface.
        let alpha = (case.materials.iter())
            .map(|b| b.material.young / (1.0 - b.material.poisson * b.material.poisson))
            .fold(f64::NEG_INFINITY, f64::max);
        Setup {
            r: case
                .solver
                .r
                .unwrap_or_else(|| facts.lengths.default_r(e_eff)),
            mesh_stiffness: facts.lengths.mesh_stiffness(e_eff),
            alpha,
            materials: case.material_table(),
            facts,
            split,
            ordering: opts.ordering,
            interface: opts.interface.resolved(ranks * per_rank),
            per_rank,
            own_parts: false,
            case,
        }
    }

    /// What every subdomain's condensed step shares.
    fn step(&self) -> StepSetup<'_> {
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
    fn direct_system<'a>(&'a self, sub: &'a SubProblem) -> DirectSystem<'a> {
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
    fn params(&self) -> contact::Params {
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

/// The MPI ranks of the run and the threads of each.
#[derive(Clone, Copy)]
struct Layout {
    ranks: usize,
    threads: usize,
}

/// [`read_and_split`] where the ranks kept their shares of a Gmsh file: they cut it
/// into their parts, check the mesh on them and find the conditions of the groups'
/// nodes (`dd::dist_problem`), so that no rank holds the whole mesh; each then builds
/// its own parts. A fault of the input found there is named as the first rank's reading
/// names it; should the conditions fall back (`dist_problem::Outcome::FallBack`), the
/// first rank reads the whole file and builds the problem as it does without the
/// shares, and names any fault.
fn split_on_groups(
    opts: &Options,
    mpi: &Mpi,
    layout: Layout,
    timer: &Timer,
    print: &Printer,
    (early, shares): (Option<Early>, Shares),
) -> Result<(Option<Setup>, Option<Vec<SubProblem>>)> {
    // The nodes' z, for the check that the mesh is planar once the cut has taken the
    // coordinates.
    let z: Vec<f64> = shares.coords.chunks_exact(3).map(|c| c[2]).collect();
    let first = || {
        early.as_ref().and_then(|e| {
            let together = e.mesh.as_ref()?;
            let (scan, group_values) = together.groups.as_ref()?;
            Some(dist_problem::First {
                name: &together.name,
                case: e.case.as_ref().ok()?,
                scan,
                group_values,
            })
        })
    };
    let mut cut = timer.time(Phase::Partition, || shares.cut(mpi, first()));
    let start = Instant::now();
    let outcome = match cut.as_mut() {
        Some(ShareCut {
            lists: Some(lists),
            directory: Some((directory, around)),
            triangles,
            ..
        }) => {
            let first = first();
            timer.time(Phase::Read, || {
                dist_problem::build(mpi, first, lists, (directory, around), *triangles, &z)
            })?
        }
        _ => dist_problem::Outcome::FallBack,
    };
    let built_s = start.elapsed().as_secs_f64();
    if let Some(c) = cut.as_mut() {
        c.directory = None;
    }
    let lists = cut.as_mut().and_then(|c| {
        Some(OwnPart {
            lists: c.lists.take()?,
            figures: c.figures.take()?,
            edge_cut: c.edge_cut,
        })
    });
    let prepared = match outcome {
        dist_problem::Outcome::Fault(message) => message.map(|m| Err(Error::Input(m))),
        dist_problem::Outcome::Built(on_groups) => {
            early
                .zip(on_groups)
                .zip(cut.as_ref())
                .map(|((early, og), cut)| {
                    let start = GroupsStart { og, cut, built_s };
                    done_on_groups(opts, layout, print, timer, early, start)
                        .map(|d| Stage::Split(Box::new(d)))
                })
        }
        dist_problem::Outcome::FallBack => {
            let start = Instant::now();
            let own = lists.is_some();
            let read = early.map(|e| prepare(opts, layout, timer, print, Some(e)));
            let after = start.elapsed().as_secs_f64();
            let cut = cut.map(|c| (c, after));
            read.map(|r| {
                r.and_then(|r| {
                    host::on_idle_cores(mpi.node_ranks, || with_graph(r, cut, own, timer))
                })
            })
        }
    };
    mpi.barrier_sleeping();
    let prepared = mpi.agree(prepared.transpose())?;
    cut_and_split(opts, mpi, layout, timer, print, Phase1 { prepared, lists })
}

/// A start on the groups' nodes: the conditions, the ranks' cut and the seconds of the
/// checks and the conditions on the ranks.
struct GroupsStart<'a> {
    og: dist_problem::OnGroups,
    cut: &'a ShareCut,
    /// Seconds of the checks and the conditions on the ranks.
    built_s: f64,
}

/// The first rank's set-up of a start on the groups' nodes ([`split_on_groups`]): the
/// run's first lines, and the conditions the ranks build their parts from.
fn done_on_groups(
    opts: &Options,
    layout: Layout,
    print: &Printer,
    timer: &Timer,
    early: Early,
    start: GroupsStart,
) -> Result<SplitDone> {
    let og = start.og;
    let case = early.case?;
    check_linear(opts, &case)?;
    let cut = start.cut;
    let per_rank = cut.nparts / layout.ranks;
    let facts = og.facts;
    let size = Size {
        nodes: facts.nodes,
        elements: facts.elements,
        contact_nodes: facts.contact_nodes,
    };
    let e_eff = contact_modulus(&case, &facts.contact_bodies);
    let r = case
        .solver
        .r
        .unwrap_or_else(|| facts.lengths.default_r(e_eff));
    print.line(header_line(&case, &size, r, layout, per_rank));
    let (name, how) = match &early.mesh {
        Some(t) => (
            t.name.clone(),
            format!(
                "; mesh read on {} ranks in {:.3} s (the first rank alone {:.3} s: case, file \
                 and scan), checked and its conditions found on the ranks in {:.3} s, no \
                 rank holding it whole",
                t.ranks,
                t.alone_s + t.together_s,
                t.alone_s,
                start.built_s
            ),
        ),
        None => (String::new(), String::new()),
    };
    print.line(timer::phase_line(
        Phase::Read,
        timer.seconds(Phase::Read),
        &format!(
            "{name}: {} nodes, {} triangles, {} contact nodes{how}",
            size.nodes, size.elements, size.contact_nodes
        ),
    ));
    let part_case = PartCase {
        body_force: case.body_force,
        frictional: Problem::is_frictional(&case),
    };
    let [order, graph, cut_s, lists] = cut.seconds;
    Ok(SplitDone {
        case,
        facts,
        per_rank,
        out: SplitOut::OnRanks(og.conditions, part_case),
        figure: PartitionFigure {
            nparts: cut.nparts,
            graph_s: 0.0,
            cut_s: order + graph + cut_s + lists,
            who: format!(
                "PT-Scotch on {} ranks from their shares of the file: order {order:.3} s, \
                 graph {graph:.3} s, cut {cut_s:.3} s, part lists {lists:.3} s",
                layout.ranks
            ),
            split_s: 0.0,
            on_ranks_s: None,
        },
    })
}

/// Phases 1 and 2 on the first rank: the set-up, and the subproblems unless each
/// subdomain reads its own from a split directory. Prints the run's first line once the
/// case is read and checked, and each phase's line.
fn prepare(
    opts: &Options,
    layout: Layout,
    timer: &Timer,
    print: &Printer,
    early: Option<Early>,
) -> Result<Read> {
    let Layout { ranks, threads } = layout;
    let read_line = |figure: String| {
        print.line(timer::phase_line(
            Phase::Read,
            timer.seconds(Phase::Read),
            &figure,
        ))
    };
    if let Some(dir) = &opts.mesh_split {
        let (case, split) = timer.time(Phase::Read, || -> Result<_> {
            let case = load_case(opts)?;
            check_linear(opts, &case)?;
            let split = split_dir::open(dir, &case)?;
            Ok((case, split))
        })?;
        let per_rank = split_per_rank(opts, &split, ranks)?;
        let facts = split.facts.clone();
        let parts = split.parts;
        let setup = Setup::new(opts, case, facts, Some(split), ranks, per_rank);
        let f = &setup.facts;
        let size = Size {
            nodes: f.nodes,
            elements: f.elements,
            contact_nodes: f.contact_nodes,
        };
        print.line(header_line(&setup.case, &size, setup.r, layout, per_rank));
        read_line(format!(
            "the split {} of {parts} parts ({} nodes, {} triangles, {} contact nodes): {}",
            dir.display(),
            f.nodes,
            f.elements,
            f.contact_nodes,
            f.partition
        ));
        return Ok(Stage::Ready(Box::new(setup)));
    }
    // 1. Read and validate the case and the mesh.
    let (case, prob, mesh_name, how) = timer.time(Phase::Read, || read(opts, early))?;
    check_linear(opts, &case)?;
    let triangles = prob.mesh.triangles.len();
    let per_rank = match opts.subdomains_per_rank {
        Some(k) => k.max(1),
        None if opts.linear == LinearMode::Full => 1,
        None => host::subdomains_per_rank(threads, ranks, triangles),
    };
    // Checked before the first line: bad input prints nothing but its error.
    let nparts = check_subdomains(&mesh_name, triangles, ranks, per_rank)?;
    let size = Size {
        nodes: prob.mesh.num_nodes(),
        elements: triangles,
        contact_nodes: prob.contact_nodes.len(),
    };
    let r = case.solver.r.unwrap_or_else(|| prob.default_r(&case));
    print.line(header_line(&case, &size, r, layout, per_rank));
    read_line(format!(
        "{mesh_name}: {} nodes, {} triangles, {} contact nodes{how}",
        size.nodes, size.elements, size.contact_nodes
    ));
    Ok(Stage::Problem(Box::new(ReadProblem {
        case,
        prob,
        mesh_name,
        nparts,
        per_rank,
    })))
}

/// Where the first rank stands in phases 1-2: a run from a split directory is ready
/// (nothing to cut); otherwise the problem, read ([`ReadProblem`]) and then with its
/// graph ([`ToCut`]).
enum Stage<T> {
    Ready(Box<Setup>),
    Problem(Box<T>),
    /// The conditions the ranks build their own parts from, found without the whole
    /// mesh ([`split_on_groups`]).
    Split(Box<SplitDone>),
}

/// Phase 1 on the first rank.
type Read = Stage<ReadProblem>;

/// The start of phase 2 on the first rank.
type Prepared = Stage<ToCut>;

/// The problem to cut into `nparts` subdomains.
struct ReadProblem {
    case: Case,
    prob: Problem,
    mesh_name: String,
    nparts: usize,
    per_rank: usize,
}

/// The start of phase 2 on the first rank: the graph the partition cuts
/// ([`cut_and_split`] cuts it), unless the ranks cut the file from their shares
/// (`share_cut`, with the seconds the first rank's reading went on after it): then only
/// the triangles around each node, which the ownership rules read, or nothing where
/// each rank builds its own parts from the lists it made (`own_parts`).
fn with_graph(
    read: Read,
    share_cut: Option<(ShareCut, f64)>,
    own_parts: bool,
    timer: &Timer,
) -> Result<Prepared> {
    let read = match read {
        Stage::Ready(setup) => return Ok(Stage::Ready(setup)),
        Stage::Split(done) => return Ok(Stage::Split(done)),
        Stage::Problem(r) => *r,
    };
    let (prob, mesh_name, nparts) = (&read.prob, &read.mesh_name, read.nparts);
    let graph_start = Instant::now();
    let cut = share_cut.and_then(|(c, after)| ShareParts::of(c, after, prob, nparts, own_parts));
    // Where each rank builds its own part, the first rank needs no graph at all.
    let on_ranks = own_parts && cut.is_some();
    let graph = timer.time(Phase::Partition, || match (&cut, on_ranks) {
        (_, true) => Ok(None),
        (Some(_), false) => {
            partition::MeshGraph::new(prob.mesh.num_nodes(), &prob.mesh.triangles, &[], false)
                .map(Some)
                .map_err(|e| cannot_partition(mesh_name, e))
        }
        // One part is the problem itself (`whole`): no graph, no stars.
        (None, false) if nparts == 1 => Ok(None),
        (None, false) => mesh_graph(prob, mesh_name, nparts).map(Some),
    })?;
    let graph_s = graph_start.elapsed().as_secs_f64();
    Ok(Stage::Problem(Box::new(ToCut {
        read,
        graph,
        graph_s,
        cut,
        on_ranks,
    })))
}

/// The ranks' cut of the file's triangles ([`Shares::cut`]) in the problem's triangle
/// order.
struct ShareParts {
    /// `None` where the ranks made their part lists, which then stand for it.
    element_part: Option<Vec<u32>>,
    edge_cut: usize,
    /// Seconds of the ranks' locality order, graph, cut, and part lists.
    seconds: [f64; 4],
    /// Seconds the first rank's reading (the mesh put together, the problem) went on
    /// after the ranks had cut, which they did meanwhile.
    read_after: f64,
}

impl ShareParts {
    /// `None` where the problem does not match the cut: another number of parts, a
    /// triangle the reading dropped as a repeat. The first rank
    /// then cuts the problem as it does without the shares.
    /// `lists`: whether the ranks made their part lists.
    fn of(
        cut: ShareCut,
        read_after: f64,
        prob: &Problem,
        nparts: usize,
        lists: bool,
    ) -> Option<Self> {
        let made = cut.parts.is_some() || lists;
        if !made || cut.nparts != nparts || cut.triangles != prob.file_triangle.len() {
            return None;
        }
        Some(ShareParts {
            element_part: (cut.parts)
                .map(|by_file| prob.file_triangle.iter().map(|&f| by_file[f]).collect()),
            edge_cut: cut.edge_cut,
            seconds: cut.seconds,
            read_after,
        })
    }
}

/// The problem read, and the graph its partition needs.
struct ToCut {
    read: ReadProblem,
    /// `None` where each rank builds its own part (`on_ranks`).
    graph: Option<partition::MeshGraph>,
    /// Seconds the graph took.
    graph_s: f64,
    /// The ranks' cut from their shares of the file, if they made it.
    cut: Option<ShareParts>,
    /// Whether each rank builds its own part from the lists it made with the cut
    /// (`dd::dist_split`).
    on_ranks: bool,
}

/// What phase 1 leaves on a rank.
struct Phase1 {
    /// The first rank's problem, or its set-up.
    prepared: Option<Prepared>,
    /// This rank's part, where the ranks cut the mesh from their shares of the file.
    lists: Option<OwnPart>,
}

/// This rank's part as the ranks' cut from their shares of the file leaves it, with the
/// partition's figures found on the ranks.
struct OwnPart {
    lists: Vec<PartLists>,
    figures: InterfaceFigures,
    edge_cut: usize,
}

/// Phase 2, collective: the problem the first rank prepared cut into subdomains (by
/// every rank, or by the first alone, [`Partitioner`]) and split along the cut; returns
/// the set-up on the first rank, and the subproblems it hands out, or where the ranks
/// cut the mesh from their shares of the file (`lists`: this rank's part), every
/// rank's own, built on it.
fn cut_and_split(
    opts: &Options,
    mpi: &Mpi,
    layout: Layout,
    timer: &Timer,
    print: &Printer,
    phase1: Phase1,
) -> Result<(Option<Setup>, Option<Vec<SubProblem>>)> {
    let Phase1 { prepared, lists } = phase1;
    let asked = prepared.as_ref().map(|p| match p {
        Stage::Problem(t) if t.cut.is_none() && opts.partitioner.on_ranks(mpi, t.read.nparts) => {
            Some((t.read.prob.mesh.triangles.len(), t.read.nparts))
        }
        _ => None,
    });
    // The first rank's lists stand for every rank's: the ranks make them together.
    let on_ranks = (prepared.as_ref())
        .map(|p| matches!(p, Stage::Split(_)) || matches!(p, Stage::Problem(t) if t.on_ranks));
    let (asked, on_ranks) = match mpi.size {
        1 => (asked.flatten(), false),
        _ => mpi.broadcast(asked.zip(on_ranks))?,
    };
    let cut = match asked {
        Some((triangles, nparts)) => {
            let graph = match &prepared {
                Some(Stage::Problem(t)) => t.graph.as_ref(),
                _ => None,
            };
            let start = Instant::now();
            let parts = cut_on_ranks(mpi, graph, triangles, nparts)?;
            let seconds = start.elapsed().as_secs_f64();
            timer.add(Phase::Partition, if mpi.is_root() { seconds } else { 0.0 });
            parts.map(|p| (p, seconds))
        }
        None => None,
    };
    let done = prepared.map(|p| match p {
        Stage::Ready(setup) => Ok(Err(*setup)),
        Stage::Split(done) => Ok(Ok(*done)),
        Stage::Problem(t) => host::on_idle_cores(mpi.node_ranks, || {
            let straight = opts.partitioner.straight_first();
            split_cut(*t, cut, on_ranks, straight, layout, timer).map(Ok)
        }),
    });
    mpi.barrier_sleeping();
    let done = mpi.agree(done.transpose())?;
    if !on_ranks {
        let (setup, subs) = done
            .map(|d| match d {
                Err(setup) => (setup, None),
                Ok(d) => match d.setup(opts, layout, timer, print) {
                    (setup, SplitOut::Here(subs)) => (setup, Some(subs)),
                    (setup, SplitOut::OnRanks(..)) => (setup, None),
                },
            })
            .unzip();
        return Ok((setup, subs.flatten()));
    }
    let mut done = done.and_then(|d| d.ok());
    let (conditions, part_case) = match done.as_mut().map(|d| &mut d.out) {
        Some(SplitOut::OnRanks(c, on)) => (Some(std::mem::take(c)), Some(*on)),
        _ => (None, None),
    };
    let part_case = mpi.broadcast(part_case)?;
    let own =
        mpi.agree(lists.ok_or_else(|| {
            Error::Numerical("internal: a rank has no part lists of its own".into())
        }))?;
    let start = Instant::now();
    let (subs, map, quality) = timer.time(Phase::Partition, || {
        let (subs, map) = dist_split::build(mpi, &own.lists, conditions, part_case)?;
        let quality = dist_split::quality(mpi, &subs, &own.figures, own.edge_cut);
        Ok::<_, Error>((subs, map, quality))
    })?;
    drop(own);
    let built_s = start.elapsed().as_secs_f64();
    let setup = done.map(|mut d| {
        d.facts.n_boundary = map.n_boundary;
        d.facts.n_interface = map.n_interface;
        d.facts.partition = quality.to_string();
        d.figure.on_ranks_s = Some(built_s);
        d.setup(opts, layout, timer, print).0
    });
    Ok((setup, Some(subs)))
}

/// The first rank's graph cut into `nparts` parts by PT-Scotch on every rank, each
/// holding a consecutive range of its vertices (the triangles, in the problem's
/// locality order, so that a range is a compact piece of the mesh): the triangles'
/// parts on the first rank, `None` on the others. Collective.
fn cut_on_ranks(
    mpi: &Mpi,
    graph: Option<&partition::MeshGraph>,
    triangles: usize,
    nparts: usize,
) -> Result<Option<Vec<u32>>> {
    let p = mpi.size;
    let counts: Vec<usize> = (0..p)
        .map(|r| triangles * (r + 1) / p - triangles * r / p)
        .collect();
    let csr = graph.and_then(partition::MeshGraph::csr);
    // Each rank's number of graph entries, and which weights the graph has.
    let spread = csr.map(|c| {
        let mut start = 0;
        let edges: Vec<usize> = (counts.iter())
            .map(|&n| {
                let e = (c.xadj[start + n] - c.xadj[start]) as usize;
                start += n;
                e
            })
            .collect();
        (edges, c.adjwgt.is_some(), c.vwgt.is_some())
    });
    let (edges, edge_weights, vertex_weights) = mpi.broadcast(spread)?;
    let degrees: Option<Vec<i32>> = csr.map(|c| c.xadj.windows(2).map(|w| w[1] - w[0]).collect());
    let degrees = mpi.scatter_varcount(degrees.as_deref(), &counts);
    let adjncy = mpi.scatter_varcount(csr.map(|c| c.adjncy), &edges);
    let adjwgt = edge_weights.then(|| mpi.scatter_varcount(csr.and_then(|c| c.adjwgt), &edges));
    let vwgt = vertex_weights.then(|| mpi.scatter_varcount(csr.and_then(|c| c.vwgt), &counts));
    let mut xadj = Vec::with_capacity(degrees.len() + 1);
    xadj.push(0);
    for d in degrees {
        xadj.push(xadj[xadj.len() - 1] + d);
    }
    let local = ptscotch::LocalGraph {
        xadj: &xadj,
        adjncy: &adjncy,
        adjwgt: adjwgt.as_deref(),
        vwgt: vwgt.as_deref(),
    };
    let parts = mpi.agree(mpi.part_graph(local, nparts, PART_IMBALANCE))?;
    let all = mpi.gather_varcount(&parts, &counts);
    Ok(all.map(|a| a.into_iter().map(|q| q as u32).collect()))
}

/// The load imbalance the partition allows: METIS's default (`ufactor` 30), which the
/// first rank's partition uses too.
const PART_IMBALANCE: f64 = 0.03;

/// The first rank's end of phase 2: the graph cut (here, unless `cut` holds the parts
/// the ranks found and their seconds), the ownership rules, and the split, here or (with
/// `on_ranks`) only the conditions that the ranks build their own parts from.
fn split_cut(
    t: ToCut,
    cut: Option<(Vec<u32>, f64)>,
    on_ranks: bool,
    straight: bool,
    layout: Layout,
    timer: &Timer,
) -> Result<SplitDone> {
    let ToCut {
        read:
            ReadProblem {
                case,
                prob,
                mesh_name,
                nparts,
                per_rank,
            },
        graph,
        graph_s,
        cut: from_shares,
        ..
    } = t;
    let by_ranks = cut.as_ref().map(|c| c.1);
    let (mut cut_s, mut split_s) = (by_ranks.unwrap_or(0.0), 0.0);
    let mut method = "METIS";
    let shares_s = from_shares.as_ref().map(|c| (c.seconds, c.read_after));
    let (facts, out) = timer.time(Phase::Partition, || {
        if on_ranks {
            let start = Instant::now();
            let conditions = conditions(&case, &prob);
            split_s = start.elapsed().as_secs_f64();
            return conditions;
        }
        if nparts == 1 && cut.is_none() && from_shares.is_none() {
            let start = Instant::now();
            let done = whole(&case, prob);
            split_s = start.elapsed().as_secs_f64();
            return Ok(done);
        }
        let parts = match (cut, from_shares) {
            (_, Some(c)) => {
                let parts = c.element_part.ok_or_else(|| {
                    Error::Numerical("internal: the ranks' cut did not reach the first rank".into())
                })?;
                Parts::Elsewhere(parts, c.edge_cut)
            }
            (Some((parts, _)), None) => Parts::Graph(parts),
            (None, None) => {
                let start = Instant::now();
                let no_graph = || Error::Numerical("internal: no graph to cut".into());
                let graph = graph.as_ref().ok_or_else(no_graph)?;
                let parts;
                (parts, method) = first_rank_cut(graph, &prob, nparts, straight);
                cut_s = start.elapsed().as_secs_f64();
                parts.map_err(|e| cannot_partition(&mesh_name, e))?
            }
        };
        let start = Instant::now();
        let cut = Cut { nparts, parts };
        let split = match graph {
            Some(graph) => split_parts(&case, &prob, &mesh_name, graph, cut)
                .map(|(facts, subs)| (facts, SplitOut::Here(subs))),
            None => Err(Error::Numerical("internal: no graph to split".into())),
        };
        split_s = start.elapsed().as_secs_f64();
        // The whole problem is not needed past here; the other ranks wait for their parts.
        host::drop_in_background(prob);
        split
    })?;
    let who = match (by_ranks, shares_s) {
        (_, Some(([order, graph, cut, lists], after))) => {
            cut_s = order + graph + cut + lists;
            format!(
                "PT-Scotch on {} ranks from their shares of the file while the first rank \
                 read, which went on {after:.3} s longer: order {order:.3} s, graph \
                 {graph:.3} s, cut {cut:.3} s, part lists {lists:.3} s",
                layout.ranks
            )
        }
        (Some(_), None) => format!("PT-Scotch on {} ranks", layout.ranks),
        (None, None) => format!("the first rank, {method}"),
    };
    Ok(SplitDone {
        case,
        facts,
        per_rank,
        out,
        figure: PartitionFigure {
            nparts,
            graph_s,
            cut_s,
            who,
            split_s,
            on_ranks_s: None,
        },
    })
}

/// What the first rank's end of phase 2 leaves for the set-up.
struct SplitDone {
    case: Case,
    /// The figures of the whole problem; where the ranks build their parts, without the
    /// counts of boundary and interface dofs, which they find.
    facts: Facts,
    per_rank: usize,
    out: SplitOut,
    figure: PartitionFigure,
}

impl SplitDone {
    /// The set-up, once the partition's line is printed, and the split.
    fn setup(
        self,
        opts: &Options,
        layout: Layout,
        timer: &Timer,
        print: &Printer,
    ) -> (Setup, SplitOut) {
        print.line(timer::phase_line(
            Phase::Partition,
            timer.seconds(Phase::Partition),
            &self.figure.line(&self.facts.partition),
        ));
        let own_parts = matches!(self.out, SplitOut::OnRanks(..));
        let mut setup = Setup::new(
            opts,
            self.case,
            self.facts,
            None,
            layout.ranks,
            self.per_rank,
        );
        setup.own_parts = own_parts;
        (setup, self.out)
    }
}

/// The seconds of the partition's line.
struct PartitionFigure {
    nparts: usize,
    graph_s: f64,
    cut_s: f64,
    /// Who cut.
    who: String,
    split_s: f64,
    /// The seconds of the ranks' build of their own parts, where they built them.
    on_ranks_s: Option<f64>,
}

impl PartitionFigure {
    fn line(&self, quality: &str) -> String {
        let PartitionFigure {
            nparts,
            graph_s,
            cut_s,
            split_s,
            ..
        } = *self;
        let split = match self.on_ranks_s {
            Some(s) => format!("conditions {split_s:.3} s, parts built on their ranks {s:.3} s"),
            None => format!("split {split_s:.3} s"),
        };
        match nparts {
            1 => "one subdomain, no partition".to_string(),
            _ => format!(
                "graph {graph_s:.3} s, cut {cut_s:.3} s ({}), {split}: {quality}",
                self.who
            ),
        }
    }
}

/// Subdomains per rank of a run from `split`: its parts over the ranks, which must
/// divide them.
fn split_per_rank(opts: &Options, split: &Split, ranks: usize) -> Result<usize> {
    let (parts, dir) = (split.parts, split.dir.display());
    if parts % ranks != 0 {
        let divisors: Vec<String> = (1..=parts)
            .filter(|k| parts % k == 0)
            .map(|k| k.to_string())
            .collect();
        return Err(Error::Input(format!(
            "{dir}: the split has {parts} parts for {ranks} ranks; run on a number of ranks that divides {parts} ({}), or split again with --parts {ranks}",
            divisors.join(", ")
        )));
    }
    let per_rank = parts / ranks;
    match opts.subdomains_per_rank {
        Some(k) if k != per_rank => Err(Error::Input(format!(
            "{dir}: --subdomains-per-rank {k} on {ranks} ranks makes {} subdomains, the split has {parts} parts; leave --subdomains-per-rank out (it is {per_rank} here)",
            k * ranks
        ))),
        _ if opts.linear == LinearMode::Full && parts > 1 => Err(Error::Input(format!(
            "{dir}: --linear full runs on one subdomain, the split has {parts} parts; use the default (condensed) or a split with --parts 1"
        ))),
        _ => Ok(per_rank),
    }
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

/// Partitions `prob` into `nparts` subdomains and splits it along the cut.
/// The graph the partition cuts (see [`partition::MeshGraph`]); none for one part.
fn mesh_graph(prob: &Problem, mesh_name: &str, nparts: usize) -> Result<partition::MeshGraph> {
    // Each slave node of a contact between bodies tied to its master nodes: the parts
    // then keep a contact zone's two sides together (see `partition_mesh_with_ties`).
    let ties: Vec<[usize; 2]> = (prob.contact_nodes.iter().zip(&prob.contact_masters))
        .flat_map(|(&s, masters)| masters.iter().map(move |&(m, _)| [s, m]))
        .collect();
    partition::MeshGraph::new(
        prob.mesh.num_nodes(),
        &prob.mesh.triangles,
        &ties,
        nparts > 1,
    )
    .map_err(|e| cannot_partition(mesh_name, e))
}

fn cannot_partition(mesh_name: &str, e: partition::PartitionError) -> Error {
    Error::Input(format!("{mesh_name}: cannot partition the mesh: {e}"))
}

/// The triangles' parts.
struct Cut {
    nparts: usize,
    parts: Parts,
}

/// Each triangle's part, and what the partitioner counted of them.
enum Parts {
    /// Cut from the graph the first rank holds, which the quality report counts on.
    Graph(Vec<u32>),
    /// Cut from a graph that the first rank does not hold ([`ShareParts`]), with the
    /// edges cut counted there.
    Elsewhere(Vec<u32>, usize),
    /// Straight cuts, which counted their pieces and edges cut as they made them.
    Straight(partition::StraightParts),
}

/// The problem split along the cut.
fn split_parts(
    case: &Case,
    prob: &Problem,
    mesh_name: &str,
    graph: partition::MeshGraph,
    cut: Cut,
) -> Result<(Facts, Vec<SubProblem>)> {
    let (triangles, contact) = (&prob.mesh.triangles, &prob.contact_nodes);
    let Cut { nparts, parts } = cut;
    let part = match parts {
        Parts::Graph(parts) => graph.finish(triangles, contact, nparts, parts),
        Parts::Elsewhere(parts, cut) => graph.finish_cut(triangles, contact, nparts, parts, cut),
        Parts::Straight(parts) => graph.finish_straight(triangles, contact, parts),
    }
    .map_err(|e| cannot_partition(mesh_name, e))?;
    let (subs, map) = split(prob, &part, Problem::is_frictional(case))?;
    Ok((facts(prob, part.quality.to_string(), Some(&map)), subs))
}

/// What the ranks build their own parts from ([`SplitOut::OnRanks`]), and the figures of
/// the whole problem but those the ranks find (the partition's, the boundary's and the
/// interface's).
fn conditions(case: &Case, prob: &Problem) -> Result<(Facts, SplitOut)> {
    let conditions = Conditions::of(case, prob)?;
    let on = PartCase {
        body_force: case.body_force,
        frictional: Problem::is_frictional(case),
    };
    Ok((
        facts(prob, String::new(), None),
        SplitOut::OnRanks(conditions, on),
    ))
}

/// The figures of the whole problem, its partition's report and the split's map (the
/// ranks fill in the counts of boundary and interface dofs where they split).
fn facts(prob: &Problem, partition: String, map: Option<&GlobalMap>) -> Facts {
    Facts {
        lengths: prob.lengths(),
        contact_bodies: prob.contact_bodies.clone(),
        n_boundary: map.map_or(0, |m| m.n_boundary),
        n_interface: map.map_or(0, |m| m.n_interface),
        nodes: prob.mesh.num_nodes(),
        elements: prob.mesh.triangles.len(),
        free_dofs: prob.fixed.iter().filter(|f| f.is_none()).count(),
        contact_nodes: prob.contact_nodes.len(),
        partition,
        holding: prob.holding.clone(),
    }
}

/// The split made by the first rank, or what the ranks build their own parts from.
enum SplitOut {
    Here(Vec<SubProblem>),
    OnRanks(Conditions, PartCase),
}

/// The one subdomain of `prob`: the problem itself, moved ([`split_whole`]). Its
/// pieces are the mesh's separate parts, which the problem's checks counted.
fn whole(case: &Case, prob: Problem) -> (Facts, SplitOut) {
    let pieces = prob.holding.first.len();
    let quality = partition::Quality::one_part(prob.mesh.triangles.len(), pieces);
    let mut facts = facts(&prob, quality.to_string(), None);
    let (sub, map) = split_whole(prob, Problem::is_frictional(case));
    facts.n_boundary = map.n_boundary;
    (facts, SplitOut::Here(vec![sub]))
}

/// What `contact-par split` is asked for.
#[derive(Debug, Clone)]
pub struct SplitOptions {
    /// A case file, or `None` for a built-in case.
    pub case_file: Option<PathBuf>,
    pub builtin: String,
    pub level: u32,
    pub parts: usize,
    pub out: PathBuf,
    /// Who cuts the graph (as in a run).
    pub partitioner: Partitioner,
}

/// `contact-par split`: reads the case and its mesh, partitions and splits them into
/// `parts` subdomains, the same as a run on that many would, and writes one file per
/// part (see `split_dir`). The first rank reads the whole mesh and makes the parts, or
/// the ranks make their own (`split_on_ranks`), and then no rank holds the whole mesh.
pub fn split_case(opts: &SplitOptions, mpi: &Mpi, print: &Printer) -> Result<()> {
    if mpi.size > 1 && opts.parts % mpi.size == 0 && opts.partitioner.on_ranks(mpi, opts.parts) {
        return split_on_ranks(opts, mpi, print);
    }
    // The first rank reads and builds the problem while the others sleep; all cut the
    // graph (PT-Scotch) when there are several; the first splits and writes the parts.
    let prepared = mpi.is_root().then(|| {
        host::on_idle_cores(mpi.node_ranks, || -> Result<_> {
            let case =
                case_file_or_builtin(opts.case_file.as_deref(), &opts.builtin, opts.level)?;
            let (mesh, mesh_name) = load_mesh(&case)?;
            let prob = problem::build(&case, mesh, &mesh_name)?;
            let triangles = prob.mesh.triangles.len();
            if opts.parts > triangles {
                return Err(Error::Input(format!(
                    "{mesh_name}: --parts {} for {triangles} triangles; use at most as many parts as triangles (better: thousands of triangles each)",
                    opts.parts
                )));
            }
            let graph = mesh_graph(&prob, &mesh_name, opts.parts)?;
            Ok((case, prob, mesh_name, graph))
        })
    });
    mpi.barrier_sleeping();
    let prepared = mpi.agree(prepared.transpose())?;
    let on_ranks = opts.partitioner.on_ranks(mpi, opts.parts);
    let cut = match on_ranks {
        true => {
            let graph = prepared.as_ref().map(|p| &p.3);
            let triangles = prepared.as_ref().map(|p| p.1.mesh.triangles.len());
            let triangles = mpi.broadcast(triangles)?;
            cut_on_ranks(mpi, graph, triangles, opts.parts)?
        }
        false => None,
    };
    let ranks = mpi.size;
    let done = prepared.map(|(case, prob, mesh_name, graph)| {
        host::on_idle_cores(mpi.node_ranks, || -> Result<()> {
            let straight = opts.partitioner.straight_first();
            let (parts, method) = match cut {
                Some(parts) => (Parts::Graph(parts), "PT-Scotch"),
                None => {
                    let (parts, method) = first_rank_cut(&graph, &prob, opts.parts, straight);
                    (parts.map_err(|e| cannot_partition(&mesh_name, e))?, method)
                }
            };
            let cut = Cut {
                nparts: opts.parts,
                parts,
            };
            let (facts, subs) = split_parts(&case, &prob, &mesh_name, graph, cut)?;

            drop(prob);
            let split = split_dir::write(&opts.out, &case, &facts, &subs)?;
            let who = match on_ranks {
                true => format!("cut by PT-Scotch on {ranks} ranks: "),
                false => format!("cut by {method}: "),
            };
            print_split(print, opts, &facts, split.parts, &who);
            Ok(())
        })
    });
    mpi.barrier_sleeping();
    mpi.agree(done.unwrap_or(Ok(())))
}

/// `contact-par split` on several ranks, the parts a multiple of them, cut by every
/// rank: the start of a run on them (`read_and_split`, the file read in shares), after
/// which, where the ranks built their own parts (`dd::dist_split`), each writes its
/// parts' files and the first the manifest, so that no rank holds the others' parts;
/// otherwise (a built-in mesh) the first rank writes the split it made.
fn split_on_ranks(opts: &SplitOptions, mpi: &Mpi, print: &Printer) -> Result<()> {
    let k = opts.parts / mpi.size;
    let run = Options {
        case_file: opts.case_file.clone(),
        builtin: opts.builtin.clone(),
        level: opts.level,
        out: opts.out.clone(),
        nodes_csv: false,
        plots: false,
        quiet: true,
        r: None,
        tol: None,
        max_iter: None,
        coulomb: None,
        acceleration: None,
        monitor_every: 0,
        linear: LinearMode::Condensed,
        checkpoint_every: 0,
        restart: false,
        ordering: Ordering::Auto,
        interface: InterfaceMode::Auto,
        subdomains_per_rank: Some(k),
        mesh_split: None,
        mesh_read: MeshRead::Shared,
        partitioner: opts.partitioner,
    };
    let layout = Layout {
        ranks: mpi.size,
        threads: rayon::current_num_threads(),
    };
    let quiet = Printer { enabled: false };
    let (setup, subs) = read_and_split(&run, mpi, layout, &Timer::start(), &quiet)?;
    let own = mpi.broadcast(setup.as_ref().map(|s| s.own_parts))?;
    let dir = &opts.out;
    let split = match own {
        true => {
            let begin = |s: &Setup| split_dir::begin(dir, &s.case, opts.parts);
            let begun = mpi.agree(setup.as_ref().map(begin).transpose())?;
            let id = mpi.broadcast(begun.as_ref().map(|b| b.id.clone()))?;
            let wrote = (subs.iter().flatten().enumerate()).try_for_each(|(j, sub)| {
                split_dir::write_part(dir, &id, mpi.rank * k + j, opts.parts, sub)
            });
            mpi.agree(wrote)?;
            let finish =
                |(s, b): (&Setup, _)| split_dir::finish(dir, &s.case, &s.facts, opts.parts, b);
            mpi.agree(setup.as_ref().zip(begun).map(finish).transpose())?
        }
        false => {
            let subs = subs.unwrap_or_default();
            let write = |s: &Setup| split_dir::write(dir, &s.case, &s.facts, &subs);
            mpi.agree(setup.as_ref().map(write).transpose())?
        }
    };
    if let Some((split, setup)) = split.zip(setup) {
        let f = &setup.facts;
        let who = match own {
            true => format!(
                "built on their {} ranks from their shares of the file: ",
                mpi.size
            ),
            false => format!("cut by PT-Scotch on {} ranks: ", mpi.size),
        };
        print_split(print, opts, f, split.parts, &who);
    }
    Ok(())
}

/// The split's two lines: what was split, by whom (`who`), and how to run it.
fn print_split(print: &Printer, opts: &SplitOptions, facts: &Facts, parts: usize, who: &str) {
    print.line(format!(
        "split: {} nodes, {} triangles, {} contact nodes into {parts} parts ({who}{}) in {}",
        facts.nodes,
        facts.elements,
        facts.contact_nodes,
        facts.partition,
        opts.out.display()
    ));
    let case_arg = match &opts.case_file {
        Some(p) => p.display().to_string(),
        None => format!("--builtin {} --level {}", opts.builtin, opts.level),
    };
    print.line(format!(
        "run it with: mpirun -n N contact-par {case_arg} --mesh-split {}   (N dividing {parts})",
        opts.out.display(),
    ));
}

/// The case, its problem on its mesh, the mesh's name for messages, and for a Gmsh
/// file how its reading went (the end of the read line: who read it, the seconds of
/// each part).
fn read(opts: &Options, early: Option<Early>) -> Result<(Case, Problem, String, String)> {
    let start = Instant::now();
    let (case, together, numbering) = match early {
        Some(e) => {
            let numbering = match e.own_parts {
                true => problem::Numbering::File,
                false => problem::Numbering::Locality,
            };
            (e.case?, e.mesh, numbering)
        }
        None => (load_case(opts)?, None, problem::Numbering::Locality),
    };
    let file = matches!(case.mesh, MeshSource::File(_));
    let (mesh, mesh_name, mut how) = match together {
        Some(mut t) => {
            let mesh_start = Instant::now();
            let (mesh, who) = t.mesh()?;
            let last = mesh_start.elapsed().as_secs_f64();
            let how = format!(
                "; mesh {who} in {:.3} s (the first rank alone {:.3} s: case, file and scan \
                 {:.3} s, assembly {last:.3} s)",
                t.alone_s + t.together_s + last,
                t.alone_s + last,
                t.alone_s,
            );
            (mesh, t.name, how)
        }
        None => {
            let (mesh, name) = load_mesh(&case)?;
            let how = match file {
                true => format!("; mesh {:.3} s", start.elapsed().as_secs_f64()),
                false => String::new(),
            };
            (mesh, name, how)
        }
    };
    let problem_start = Instant::now();
    let prob = problem::build_numbered(&case, mesh, &mesh_name, numbering)?;
    if file {
        how += &format!(", problem {:.3} s", problem_start.elapsed().as_secs_f64());
    }
    Ok((case, prob, mesh_name, how))
}

/// Phase 1 as far as the first rank has it before [`prepare`]: the case, and the Gmsh
/// file when the ranks took part in reading it.
struct Early {
    case: Result<Case>,
    mesh: Option<Together>,
    /// Whether the ranks cut the file into their parts from their shares (as many on
    /// every rank), and so will build them: the first rank's problem is then only where the
    /// conditions come from, and keeps the file's numbering ([`problem::Numbering`]).
    own_parts: bool,
}

/// Every rank's share of a Gmsh file read together, kept for the partition on the
/// ranks ([`Shares::cut`]).
struct Shares {
    /// The share's node tags and coordinates (x, y, z each), and its triangles.
    tags: Vec<u64>,
    coords: Vec<f64>,
    triangles: Vec<[u64; 3]>,
    nparts: usize,
}

impl Shares {
    /// The file's triangles cut into `nparts` parts by every rank from its share
    /// (`dd::share_cut`). Collective.
    /// `first`: the first rank's case and groups, which tie a contact's two bodies
    /// together (`dist_problem::ties`).
    fn cut(self, mpi: &Mpi, first: Option<dist_problem::First>) -> Option<ShareCut> {
        let shares = (&self.tags[..], &self.coords[..]);
        let ties = |triangles: &[[u64; 3]], directory: &crate::dd::locality::Directory| {
            dist_problem::ties(mpi, first, triangles, directory)
        };
        let parts = (self.nparts, PART_IMBALANCE);
        cut_shares(mpi, shares, &self.triangles, parts, ties)
    }
}

/// What the first rank gathers from the ranks' shares of a Gmsh file.
enum FromShares {
    /// Every record's values: node tags, coordinates, elements' node tags.
    Whole(Option<Vec<u64>>, Option<Vec<f64>>, Option<Vec<u64>>),
    /// The groups' elements' values alone, where the ranks keep their shares.
    Groups(Option<Vec<u64>>),
}

/// A Gmsh file read by every rank: the file, and from the ranks its records' values.
struct Together {
    name: String,
    path: std::path::PathBuf,
    /// `None` where the records were not shared or a share could not be parsed: the
    /// first rank then reads the file itself.
    shared: Option<(gmsh::shares::Scan, [Vec<u64>; 2], Vec<f64>)>,
    /// Where the ranks keep their shares: the scan and the groups' elements' values,
    /// which the conditions are built from without the whole mesh
    /// (`dd::dist_problem`). Should that fall back, the first rank reads the file.
    groups: Option<(gmsh::shares::Scan, Vec<u64>)>,
    ranks: usize,
    /// Seconds of the first rank alone (the case, the file, the scan), then of all
    /// ranks (their shares, the gathers).
    alone_s: f64,
    together_s: f64,
}

impl Together {
    /// The mesh put together from the ranks' values, else parsed here; and who read it.
    fn mesh(&mut self) -> Result<(Mesh, String)> {
        let assembled = (self.shared.take())
            .and_then(|(scan, [tags, elements], coords)| scan.assemble(&tags, &coords, &elements));
        match assembled {
            Some(mesh) => Ok((mesh, format!("read on {} ranks", self.ranks))),
            None => Ok((
                gmsh::read_msh(&self.path)?,
                "read by the first rank alone".to_string(),
            )),
        }
    }
}

/// The first part of phase 1, collective: with several ranks and a Gmsh MSH 4.1 file,
/// the first rank reads the case and the file and finds where its records lie (its
/// `$Nodes` and `$Elements`), every rank parses a share of them, and the first gathers
/// their values (one gather per array), to put the mesh together in [`prepare`].
/// `None` on the other ranks, and where the first reads alone (one rank, a split
/// directory, [`MeshRead`]): [`prepare`] then reads everything.
///
/// Where the ranks will cut the mesh (PT-Scotch, [`Partitioner`]), every rank also keeps
/// its share ([`Shares`]), to cut the mesh from it before the first rank builds the
/// problem. That cut does not tie a contact's slave nodes to their masters, as the
/// first rank's graph does (`mesh_graph`), which it does not have: a cut through a
/// contact zone leaves master nodes as ghosts of their slaves' parts.
///
/// Why: on a cluster the first rank has only its node's cores; here the cores of every
/// node parse the numbers' text, most of the read. Any fault (a share that cannot be parsed, a file
/// another rank cannot open, a layout the shares do not expect) sends every rank back to
/// the first rank's reading, which names the fault as it always has.
fn read_together(
    opts: &Options,
    mpi: &Mpi,
    layout: Layout,
    timer: &Timer,
) -> (Option<Early>, Option<Shares>) {
    // On one node the first rank's reading borrows every core the others would parse
    // on, without the scan, the gathers and the assembly (docs/performance.md).
    let shared = match opts.mesh_read {
        MeshRead::Auto => mpi.node_ranks < mpi.size,
        MeshRead::First => false,
        MeshRead::Shared => true,
    };
    if !shared || mpi.size == 1 || mpi.per_rank() > 1 || opts.mesh_split.is_some() {
        return (None, None);
    }
    let _read = timer.phase(Phase::Read);
    let start = Instant::now();
    let ranks = mpi.size;
    let first = mpi.is_root().then(|| {
        host::on_idle_cores(mpi.node_ranks, || {
            let case = load_case(opts);
            let path = match case.as_ref().map(|c| &c.mesh) {
                Ok(MeshSource::File(path)) => Some(path.clone()),
                _ => None,
            };
            // A file that cannot be read gets its message from `load_mesh`.
            let file = path.and_then(|p| Some((std::fs::File::open(&p).ok()?, p)));
            let scanned = file.as_ref().and_then(|(f, path)| {
                // The scan parses the other sections and the blocks' heads where the
                // mapping puts them, and counts the records' lines in windows read from
                // the file: the first rank never holds the records, most of the file.
                // SAFETY: the mapping is only read, and dropped before the ranks parse;
                // a file changed meanwhile gives a plan whose shares fail to parse, and
                // every rank falls back to the first rank's reading.
                let map = unsafe { memmap2::Mmap::map(f) }.ok()?;
                let text = gmsh::shares::Text {
                    bytes: &map,
                    file: Some(f),
                };
                let scan = gmsh::shares::scan(text, &path.display().to_string())?;
                let plan = scan.plan(text, path, ranks)?;
                Some((scan, plan))
            });
            (case, file.map(|(_, path)| path), scanned)
        })
    });
    mpi.barrier_sleeping();
    let alone_s = start.elapsed().as_secs_f64();
    let plan = first.as_ref().map(|(case, _, s)| {
        s.as_ref().map(|(scan, plan)| {
            // A case that cannot be read gets its message from the first rank's reading.
            let nparts = (case.is_ok())
                .then(|| parts_from_shares(opts, mpi, layout, scan.triangles()))
                .flatten();
            (plan.clone(), nparts)
        })
    });
    let plan = mpi.broadcast(plan).ok().flatten();
    let nparts = plan.as_ref().and_then(|p| p.1);
    let plan = plan.map(|p| p.0);
    let (case, file, scanned) = match first {
        Some((case, file, scanned)) => (Some(case), file, scanned),
        None => (None, None, None),
    };
    let gathered = plan.and_then(|plan| {
        let share = gmsh::shares::read_share(&plan, mpi.rank, None);
        if !mpi.all_ok(share.is_some()) {
            return None;
        }
        let share = share.unwrap_or_default();
        let [tags, coords, elements] = plan.counts();
        let stretches = plan.share(mpi.rank);
        // Where the ranks keep their shares they build their own parts, and the first
        // rank needs only the groups' elements (`dd::dist_problem`).
        let Some(nparts) = nparts else {
            let tags_all = mpi.gather_varcount(&share.tags, &tags);
            let coords_all = mpi.gather_varcount(&share.coords, &coords);
            let elements_all = mpi.gather_varcount(&share.elements, &elements);
            return Some((FromShares::Whole(tags_all, coords_all, elements_all), None));
        };
        let groups = share.group_values(stretches);
        let groups = mpi.gather_varcount(&groups, &mpi.all_gather_counts(groups.len()));
        let kept = Shares {
            triangles: share.triangles(stretches),
            tags: share.tags,
            coords: share.coords,
            nparts,
        };
        Some((FromShares::Groups(groups), Some(kept)))
    });
    let (gathered, shares) = match gathered {
        Some((gathered, kept)) => (Some(gathered), kept),
        None => (None, None),
    };
    let together_s = start.elapsed().as_secs_f64() - alone_s;
    let Some(case) = case else {
        return (None, shares);
    };
    let (shared, groups) = match (scanned, gathered) {
        (Some((scan, _)), Some(FromShares::Whole(Some(tags), Some(coords), Some(elements)))) => {
            (Some((scan, [tags, elements], coords)), None)
        }
        (Some((scan, _)), Some(FromShares::Groups(Some(values)))) => (None, Some((scan, values))),
        _ => (None, None),
    };
    let mesh = file.map(|path| Together {
        name: path.display().to_string(),
        path,
        shared,
        groups,
        ranks: mpi.size,
        alone_s,
        together_s,
    });
    // The ranks keep shares only to cut them into ranks x per-rank parts.
    let own_parts = shares.is_some();
    (
        Some(Early {
            case,
            mesh,
            own_parts,
        }),
        shares,
    )
}

/// The number of subdomains the ranks cut a file of `triangles` triangle records into
/// from their shares ([`Shares`]), as [`prepare`] will count them; `None` where the
/// ranks do not cut ([`Partitioner`], one part).
fn parts_from_shares(opts: &Options, mpi: &Mpi, layout: Layout, triangles: usize) -> Option<usize> {
    if opts.linear == LinearMode::Full {
        return None;
    }
    let per_rank = match opts.subdomains_per_rank {
        Some(k) => k.max(1),
        None => host::subdomains_per_rank(layout.threads, layout.ranks, triangles),
    };
    let nparts = layout.ranks * per_rank;
    (nparts <= triangles && opts.partitioner.on_ranks(mpi, nparts)).then_some(nparts)
}

/// The number of subdomains, `ranks` x `per_rank`, if the mesh has a triangle for each.
fn check_subdomains(mesh: &str, triangles: usize, ranks: usize, per_rank: usize) -> Result<usize> {
    let nparts = ranks * per_rank;
    if nparts <= triangles {
        return Ok(nparts);
    }
    Err(Error::Input(if per_rank == 1 {
        format!("{mesh}: {ranks} ranks for {triangles} triangles; use at most as many ranks as triangles (better: thousands of triangles per rank)")
    } else {
        format!("{mesh}: {nparts} subdomains ({ranks} rank(s) x --subdomains-per-rank {per_rank}) for {triangles} triangles; use at most as many subdomains as triangles (better: thousands of triangles each): fewer ranks or subdomains per rank")
    }))
}

/// Resolves the case: a file, or a built-in case at a refinement level; then applies the
/// command-line overrides.
pub fn load_case(opts: &Options) -> Result<Case> {
    let mut case = case_file_or_builtin(opts.case_file.as_deref(), &opts.builtin, opts.level)?;
    case::override_solver(&mut case, opts.r, opts.tol, opts.max_iter, opts.coulomb)?;
    if let Some(acc) = opts.acceleration {
        case.solver.acceleration = acc;
    }
    Ok(case)
}

/// The case file, or without one the built-in case `builtin` at `level`.
fn case_file_or_builtin(file: Option<&std::path::Path>, builtin: &str, level: u32) -> Result<Case> {
    match file {
        Some(path) => case::read_case(path),
        None => case::builtin_case(builtin, level),
    }
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
                BuiltinMesh::Cylinders => builtin::cylinders_for_level(
                    case::HERTZ_RADIUS,
                    case::LOWER_CYLINDER_RADIUS,
                    *level,
                ),
            };
            Ok((mesh, format!("built-in mesh (level {level})")))
        }
    }
}

/// The size of the problem, for the first line.
struct Size {
    nodes: usize,
    elements: usize,
    contact_nodes: usize,
}

/// The first line of the run: the case, its size, its parameters, the layout.
fn header_line(case: &Case, size: &Size, r: f64, layout: Layout, per_rank: usize) -> String {
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

/// The loop's lines: a sweep every `every`, and each retune of r.
struct Monitor<'a> {
    print: &'a Printer,
    every: usize,
    retunes: usize,
    /// With friction: the lines show p_t's change and the stick and slip counts.
    frictional: bool,
}

impl<'a> Monitor<'a> {
    fn new(print: &'a Printer, every: usize, frictional: bool) -> Self {
        Monitor {
            print,
            every: every.max(1),
            retunes: 0,
            frictional,
        }
    }

    fn sweep(&mut self, s: &Sweep) {
        // The normals follow their statuses at every sweep that moves one: a line for the
        // first retune and for a return to the reference r; the count is in summary.json.
        if s.retunes != self.retunes {
            if s.stiff + s.soft == 0 {
                self.print.line("  r back to the reference on every contact direction (the statuses kept moving); the dense factor blocks refactored");
            } else if self.retunes == 0 {
                self.print.line(format!(
                    "  r retuned per contact direction (raised on {} held, lowered on {} free), again whenever a status changes",
                    s.stiff, s.soft
                ));
            }
            self.retunes = s.retunes;
        }
        if s.iter == 1 || s.iter % self.every == 0 {
            self.print.line(monitor_line(s, self.frictional));
        }
    }

    /// The last sweep, unless already printed.
    fn last(&self, o: &Outcome) {
        if let Some(last) = o.history.last() {
            if last.iter % self.every != 0 {
                self.print.line(monitor_line(last, self.frictional));
            }
        }
    }
}

/// A sweep's line: what the friction law has. Without friction there is no p_t, and no
/// stick or slip: the active count only.
fn monitor_line(s: &Sweep, frictional: bool) -> String {
    let head = format!(
        "{:>7}  error {:.2e}  (p_n {:.1e}",
        s.iter, s.error, s.pressure
    );
    let (u, rho) = (s.displacement, s.contraction);
    match frictional {
        true => format!(
            "{head}  p_t {:.1e}  u {u:.1e}  rho {rho:.4})  active {:>6}  stick {:>6}  slip {:>6}",
            s.traction,
            s.active,
            s.active - s.slip,
            s.slip
        ),
        false => format!("{head}  u {u:.1e}  rho {rho:.4})  active {:>6}", s.active),
    }
}

/// A subdomain's solution and the figures of its factors.
struct Solved {
    outcome: Outcome,
    /// Displacement of every node of the subdomain.
    u: Vec<[f64; 2]>,
    factors: FactorFigures,
}

impl Solved {
    /// Reports u_n and u_t of the recovered field `u` in `outcome` (frictionless sweeps
    /// do not compute u_t); for a mortar row, of the slave node relative to its masters.
    fn new(
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
struct FactorFigures {
    nnz: usize,
    flops: f64,
    ordering: Ordering,
    /// "dense" or "sparse" where the interface system was factored.
    interface: Option<&'static str>,
    interface_flops: f64,
    interface_entries: f64,
}

impl FactorFigures {
    fn condensed(step: &CondensedStep) -> Self {
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

    fn full(nnz: usize, flops: f64) -> Self {
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

/// This subdomain's .vtu files, and its rows for the first subdomain.
fn write_piece(ctx: &Subdomain, sub: &SubProblem, solved: &Solved) -> Result<PieceRows> {
    let dir = &ctx.opts.out;
    let solution = SubdomainSolution {
        subdomain: ctx.mpi.rank,
        case: &ctx.setup.case,
        sub,
        u: &solved.u,
        outcome: &solved.outcome,
    };
    let written = ctx.timer.time(Phase::Piece, || -> Result<_> {
        host::keep_freed_blocks_for_reuse();
        output::create_output_dir(dir)?;
        let vtu = solution.write_vtu(dir)?;
        let contact = solution.contact_rows();
        Ok((contact, vtu, host::peak_memory_bytes()))
    });
    let (contact, vtu, peak_memory_bytes) = written?;
    let stats = RankStats {
        vtu_files: vtu.files,
        peak_memory_bytes,
        ..rank_stats(ctx, sub, &solved.factors)
    };
    Ok(PieceRows {
        contact,
        stats,
        written: vtu,
    })
}

/// The subdomain's figures for summary.json, its phases read from its timer.
fn rank_stats(ctx: &Subdomain, sub: &SubProblem, f: &FactorFigures) -> RankStats {
    let t = |phase| ctx.timer.seconds(phase);
    RankStats {
        subdomain: ctx.mpi.rank,
        rank: ctx.mpi.mpi_rank,
        elements: sub.triangles.len(),
        nodes: sub.nodes.len(),
        interface_nodes: sub.interface_nodes,
        boundary_dofs: sub.boundary_dofs.len(),
        contact_nodes: sub.contact_nodes.len(),
        factor_nnz: f.nnz,
        factor_gflop: f.flops / 1e9,
        peak_memory_bytes: 0,
        assemble_s: t(Phase::Assemble),
        factor_s: t(Phase::Factor),
        ordering_s: t(Phase::Ordering),
        ordering: f.ordering.name().to_string(),
        schur_s: t(Phase::Schur),
        interface_factor: f.interface.map(str::to_string),
        interface_gflop: f.interface_flops / 1e9,
        interface_factor_entries: f.interface_entries,
        sent_bytes_per_sweep: ctx.sent_per_sweep.get(),
        loop_s: t(Phase::Loop),
        one_solve_s: t(Phase::OneSolve),
        output_s: t(Phase::Piece),
        vtu_files: 0,
    }
}

/// Every subdomain's rows on the first one (`None` elsewhere, or where one failed: that
/// subdomain reports its own error). Every subdomain reaches the gather, failed or
/// not, so that none waits for another.
fn gather(mpi: &Mpi, piece: Result<PieceRows>) -> Result<Option<Gathered>> {
    let (mine, failure) = match piece {
        Ok(v) => (Some(v), None),
        Err(e) => (None, Some(e)),
    };
    let gathered = mpi.gather_parts(mine);
    if let Some(e) = failure {
        return Err(e);
    }
    let pieces = gathered?.and_then(|all| all.into_iter().collect::<Option<Vec<_>>>());
    Ok(pieces.map(Gathered::new))
}

/// What summary.json says of the run beside the rows.
fn run_facts(ctx: &Subdomain) -> RunFacts {
    let (setup, case) = (ctx.setup, &ctx.setup.case);
    RunFacts {
        title: case.title.clone(),
        origin: case.origin.clone(),
        acceleration: format!("{:?}", case.solver.acceleration),
        ranks: ctx.mpi.mpi_size,
        threads: rayon::current_num_threads(),
        idle_core_threads: host::idle_core_threads_used(),
        linear: format!("{:?}", ctx.opts.linear).to_lowercase(),
        nodes: setup.facts.nodes,
        elements: setup.facts.elements,
        dofs: 2 * setup.facts.nodes,
        free_dofs: setup.facts.free_dofs,
        boundary_dofs: setup.facts.n_boundary,
        interface_dofs: setup.facts.n_interface,
        contact_nodes: setup.facts.contact_nodes,
        friction: case.friction_name(),
        pairs: (case.contacts.iter())
            .map(|c| (c.group.clone(), c.kind(), c.master.clone()))
            .collect(),
        bodies: (case.materials.iter().enumerate())
            .map(|(i, b)| BodySummary {
                group: b.group.clone(),
                young: b.material.young,
                poisson: b.material.poisson,
                at_contact: setup.facts.contact_bodies.contains(&(i as u32)),
            })
            .collect(),
        r: setup.r,
        tol: case.solver.tol,
        partition: setup.facts.partition.clone(),
        subdomains: ctx.mpi.size,
        subdomains_per_rank: setup.per_rank,
        warnings: Vec::new(),
    }
}

/// The contact rows as [`free_at_answer`] reads them.
fn at_answer(rows: &[ContactRow]) -> Vec<NodeAtAnswer> {
    (rows.iter())
        .map(|r| NodeAtAnswer {
            part: r.part,
            at: [r.x, r.y],
            normal: r.normal,
            pressed: r.status != Status::Free,
            sticks: r.status == Status::Stick,
        })
        .collect()
}

/// The closing lines: the outcome with the contact totals over all subdomains
/// (collective), the phase table, where the outputs are.
fn report(ctx: &Subdomain, sub: &SubProblem, o: &Outcome, t: &Timings) -> Result<RunReport> {
    let count = |s: Status| o.status.iter().filter(|&&x| x == s).count() as f64;
    let force = sub.contact.w.iter().zip(&o.lambda).map(|(w, l)| w * l);
    let mut sums = [
        force.sum::<f64>(),
        count(Status::Stick),
        count(Status::Slip),
        count(Status::Contact),
    ];
    ctx.mpi.sum_in_place(&mut sums);
    let [force, stick, slip, frictionless] = sums;
    // Without friction there is no stick or slip to report.
    let split = if Problem::is_frictional(&ctx.setup.case) {
        format!(" ({} stick, {} slip)", stick as usize, slip as usize)
    } else {
        String::new()
    };
    ctx.print.line(format!(
        "{} after {} iterations: {} active contact nodes{split}, total normal force {force}",
        if o.converged {
            "converged"
        } else {
            "NOT CONVERGED"
        },
        o.iterations,
        (stick + slip + frictionless) as usize,
    ));
    if o.r != ctx.setup.r {
        ctx.print.line(format!(
            "r lowered to {:e}: the body is {:.3} times as stiff as a compact one for smooth contact modes (it bends)",
            o.r,
            o.smooth_stiffness.unwrap_or(f64::NAN)
        ));
    }
    for line in t.table(o.iterations) {
        ctx.print.line(line);
    }
    ctx.print
        .line(format!("outputs in {}", ctx.opts.out.display()));
    Ok(RunReport {
        converged: o.converged,
    })
}
