//! Phase 8 and the closing lines: every subdomain writes its piece and sends its rows
//! to the first, which writes the files of the whole run and prints the outcome and
//! the phase table.

use super::subdomain::{FactorFigures, Solved, Subdomain};
use super::RunReport;
use crate::contact::obstacle::Obstacle;
use crate::contact::{roundoff_warning, tangent_of, Outcome, Reduce, Status};
use crate::dd::comm::Mpi;
use crate::dd::split::SubProblem;
use crate::error::{Error, Result};
use crate::host;
use crate::output::plot::{Foundation, ACROSS_NORMALS, ALONG_OBSTACLES};
use crate::output::{
    self, blocks, BodySummary, ContactRow, Gathered, PieceRows, PlotFacts, RankStats, RunFacts,
    SharedFile, SubdomainSolution, Written,
};
use crate::problem::{free_at_answer, NodeAtAnswer, Problem};
use crate::timer::{self, Phase, Timings};

/// Phase 8: every subdomain writes its piece and sends its rows to the first, which
/// writes the files of the whole run. The timer is read once, at the end of this
/// phase, for both summary.json and the printed table.
pub(super) fn write(ctx: &Subdomain, sub: &SubProblem, solved: &Solved) -> Result<Timings> {
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
    let results = match !ctx.opts.no_plots {
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
pub(super) fn report(
    ctx: &Subdomain,
    sub: &SubProblem,
    o: &Outcome,
    t: &Timings,
) -> Result<RunReport> {
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
