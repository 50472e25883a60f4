//! Phase 6: the Uzawa loop on a subdomain's contact nodes (the one call into
//! `contact::solve_with`), its checkpoint files and the monitor lines.

use super::subdomain::Subdomain;
use super::Printer;
use crate::checkpoint::CheckpointFiles;
use crate::contact::{self, Friction, LinearStep, Outcome, Status, Sweep};
use crate::dd::split::SubProblem;
use crate::error::Result;
use crate::problem::{self, Problem};
use crate::timer::Phase;

/// Phase 6: the Uzawa loop on this subdomain's contact nodes, with its checkpoint files
/// and the monitor lines.
pub(super) fn iterate(
    ctx: &Subdomain,
    sub: &SubProblem,
    step: &mut impl LinearStep,
) -> Result<Outcome> {
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
