//! One run of the program, told as numbered phases: 1 read, 2 partition, 3 distribute,
//! 4 assemble and factor, 5 condense, 6 iterate, 7 recover, 8 write. Each phase is a
//! call into the module that owns it, timed by the one [`Timer`].

mod iterate;
mod subdomain;
mod write;

use crate::dd::comm::Mpi;
use crate::dd::full::DirectStep;
use crate::dd::split::SubProblem;
use crate::dd::step::{CondensedStep, LocalSystem};
use crate::error::{Error, Result};
use crate::host;
use crate::linear::Ordering;
use crate::options::{LinearMode, Options};
use crate::setup::{self, Layout};
use crate::timer::{Phase, Timer};
use subdomain::{FactorFigures, Solved, Subdomain};

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
    mpi.agree(opts.check(mpi.size))?;

    // 1-2. Read and partition, on the first rank while the others sleep (their cores
    // on its node are its to use): the set-up, and every subproblem unless each
    // subdomain reads its own from a split directory.
    let layout = Layout::of(&mpi);
    let (setup, subs) = setup::read_and_split(opts, &mpi, layout, &timer, print)?;

    // 3. Distribute: the set-up to every rank, every subdomain of a rank on a thread of
    // its own (this one included), then each its subproblem (`run_subdomain`).
    let setup = &timer.time(Phase::Scatter, || mpi.broadcast(setup))?;
    host::share_threads(layout.threads, setup.per_rank);
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

/// One subdomain's run, from its subproblem to its outputs (collective over all).
fn run_subdomain(ctx: &Subdomain, subs: Option<Vec<SubProblem>>) -> Result<RunReport> {
    let mpi = ctx.mpi;
    // Its part: from the split directory, or from the first subdomain.
    let sub = &ctx.timer.time(Phase::Scatter, || match &ctx.setup.split {
        Some(split) => mpi.agree(split.read_part(mpi.rank)),
        None => mpi.agree(mpi.scatter_parts(subs)),
    })?;
    let how = match ctx.setup.split {
        Some(_) => "read from the split",
        None => "handed out",
    };
    ctx.phase_done(Phase::Scatter, format!("{} part(s) {how}", mpi.size));

    // 4-7. Assemble and factor, condense, iterate, recover.
    let solved = match ctx.opts.linear {
        LinearMode::Condensed => solve_condensed(ctx, sub)?,
        LinearMode::Full => solve_full(ctx, sub)?,
    };

    // 8. Write: each subdomain its piece, the first the files of the whole run.
    let timings = write::write(ctx, sub, &solved)?;
    write::report(ctx, sub, &solved.outcome, &timings)
}

/// The default path: each subdomain factors its matrix with its boundary dofs last and
/// eliminates its own contact dofs with that factor; the interface system is summed and
/// factored once; the loop sweeps on the boundary system.
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
    let outcome = iterate::iterate(ctx, sub, &mut step)?;
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
    let outcome = iterate::iterate(ctx, sub, &mut step)?;
    let sweeps = outcome.iterations.max(1) as f64;
    timer.add(Phase::OneSolve, timer.seconds(Phase::Loop) / sweeps);
    let factors = FactorFigures::full(step.factor_nnz(), step.factor_flops());
    Ok(Solved::new(sub, outcome, step.displacement(), factors))
}
