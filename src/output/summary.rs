//! The files the first subdomain writes for the whole run from every subdomain's rows:
//! `contact.csv`, `history.csv`, `solution.pvtu`, `contact.png`, `convergence.png` and
//! `summary.json`.

use super::piece::{vtu_file_name, PieceRows};
use super::plot::{contact_png, convergence_png, convergence_series, pair_series};
use super::{contact_csv, history_csv, pvtu_bytes, write_atomic, ContactRow, Written};
use crate::contact::{tangent_of, Outcome, Status};
use crate::error::{Error, Result};
use crate::timer::Timings;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Per-subdomain figures, gathered for summary.json.
#[derive(Serialize, Deserialize, Clone, Default)]
pub struct RankStats {
    pub subdomain: usize,
    /// The MPI rank that ran it.
    pub rank: usize,
    pub elements: usize,
    pub nodes: usize,
    pub interface_nodes: usize,
    pub boundary_dofs: usize,
    pub contact_nodes: usize,
    pub factor_nnz: usize,
    /// The numeric factorization's floating-point operations, 1e9 (`factor_flops`): the
    /// ranks' work and its balance, free of the machine's noise.
    pub factor_gflop: f64,
    pub peak_memory_bytes: u64,
    pub assemble_s: f64,
    pub factor_s: f64,
    /// Part of factor_s spent in the fill-reducing ordering.
    pub ordering_s: f64,
    /// The ordering used: gnd, amd or nd (or the full path's amd).
    pub ordering: String,
    /// Forming S_s = L_BB L_BB' and the condensed right-hand side.
    pub schur_s: f64,
    /// On the subdomain that factored the interface system: "dense" or "sparse"
    /// (null on the others).
    pub interface_factor: Option<String>,
    /// Its factorization's floating-point operations, 1e9 (0 on the others).
    pub interface_gflop: f64,
    /// Entries of the interface factor (all ranks' with MUMPS, its INFOG(29)), on the
    /// first subdomain; 0 on the others.
    pub interface_factor_entries: f64,
    /// Bytes the subdomain's rank handed MPI to send per sweep of the loop (the payloads
    /// of its reductions, gathers, scatters and all-to-alls; MUMPS's own messages not
    /// counted). The same on every subdomain of a rank.
    pub sent_bytes_per_sweep: f64,
    pub loop_s: f64,
    /// One sparse forward+backward solve with this rank's factor (the cost a sweep
    /// would have without condensation).
    pub one_solve_s: f64,
    pub output_s: f64,
    /// `.vtu` files this rank wrote (its piece, split as [`super::file_ranges`] says).
    pub vtu_files: usize,
}

/// What summary.json says of the run that the rows do not: the case, the mesh, the
/// layout, as the first rank set them up.
#[derive(Serialize)]
pub struct RunFacts {
    pub title: String,
    #[serde(rename = "case")]
    pub origin: String,
    pub acceleration: String,
    pub ranks: usize,
    pub threads: usize,
    /// Threads the first rank's start (read, partition) ran on: its own and those of
    /// the node's sleeping ranks, whose cores it borrows (`host::on_idle_cores`).
    pub idle_core_threads: usize,
    pub linear: String,
    pub nodes: usize,
    pub elements: usize,
    pub dofs: usize,
    pub free_dofs: usize,
    pub boundary_dofs: usize,
    pub interface_dofs: usize,
    pub contact_nodes: usize,
    pub friction: &'static str,
    pub r: f64,
    pub tol: f64,
    pub partition: String,
    pub subdomains: usize,
    pub subdomains_per_rank: usize,
    /// Each contact's boundary group, obstacle type and master group (against another
    /// body), in the case's order (the rows' `pair`): summed per contact into `contacts`.
    #[serde(skip)]
    pub pairs: Vec<(String, &'static str, Option<String>)>,
    /// Each body (its `[[material]]` entry, or the one `[material]`), by body index: the
    /// `body` cell array of the .vtu pieces.
    pub bodies: Vec<BodySummary>,
    /// What the run warns of about its answer (`problem::free_at_answer`), one line each.
    pub warnings: Vec<String>,
}

/// One body in summary.json.
#[derive(Debug, Clone, Serialize)]
pub struct BodySummary {
    /// Its surface group; null for a lone `[material]` (the whole mesh).
    pub group: Option<String>,
    pub young: f64,
    pub poisson: f64,
    /// Whether its triangles touch contact nodes (their E_eff sets r's scale).
    pub at_contact: bool,
}

/// One contact's figures in summary.json.
#[derive(Serialize)]
struct PairSums {
    slave: String,
    obstacle: &'static str,
    contact_nodes: usize,
    active_nodes: usize,
    /// Sums of w_i p_n and w_i p_t over its nodes.
    normal_force: f64,
    tangential_force: f64,
    /// The force of the obstacle on the body (x, y): the sum of w_i (p_n m_i + p_t t_i).
    force: [f64; 2],
    /// Against another body: its master group, and the force of the slave body on it
    /// (the rows' forces carried to the master nodes by their mortar coefficients;
    /// minus `force`: action and reaction).
    #[serde(skip_serializing_if = "Option::is_none")]
    master: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    master_force: Option<[f64; 2]>,
}

/// Every subdomain's rows, in subdomain order.
pub struct Gathered {
    pub contact: Vec<ContactRow>,
    pub stats: Vec<RankStats>,
    /// The subdomains' own files (their `.vtu` pieces).
    pub pieces: Written,
}

/// What the pictures say of the run beside the rows.
pub struct PlotFacts<'a> {
    /// The case's title (or where it came from).
    pub title: &'a str,
    /// Each contact pair's name (its boundary group), by pair index.
    pub pairs: Vec<String>,
    /// The name of the abscissa s (see `plot::Foundation::axis_label`).
    pub abscissa: &'a str,
    /// Where the contact is, for the picture's title: "along the foundation", "along
    /// the obstacles", "between the bodies".
    pub along: &'a str,
    /// The friction law, as the first line names it ("friction none", ...).
    pub friction: String,
    pub frictional: bool,
    pub tol: f64,
}

/// The names of the pictures, in the order [`Gathered::write_plots`] draws them.
pub const PLOT_FILES: [&str; 2] = ["contact.png", "convergence.png"];

impl Gathered {
    /// The subdomains' rows put together.
    pub fn new(pieces: Vec<PieceRows>) -> Self {
        let mut all = Gathered {
            contact: Vec::new(),
            stats: Vec::new(),
            pieces: Written::default(),
        };
        for p in pieces {
            all.contact.extend(p.contact);
            all.stats.push(p.stats);
            all.pieces = all.pieces + p.written;
        }
        all
    }

    /// Writes `contact.csv`, `history.csv` and `solution.pvtu` into `dir` (`nodes.csv` is
    /// written by all ranks: [`super::blocks`]).
    pub fn write_tables(&mut self, dir: &Path, o: &Outcome) -> Result<Written> {
        let sources: Vec<String> = self
            .stats
            .iter()
            .flat_map(|st| (0..st.vtu_files).map(|k| vtu_file_name(st.subdomain, k)))
            .collect();
        let files = [
            ("contact.csv", contact_csv(&self.contact).into_bytes()),
            ("history.csv", history_csv(&o.history).into_bytes()),
            ("solution.pvtu", pvtu_bytes(&sources)?),
        ];
        let mut written = Written::default();
        for (name, bytes) in files {
            write_atomic(&dir.join(name), &bytes)?;
            written = written + Written::file(bytes.len());
        }
        remove_stale_pieces(dir, &sources);
        Ok(written)
    }

    /// Draws `contact.png` and `convergence.png` into `dir` from the contact rows and the
    /// history of `o` (the data of contact.csv and history.csv); one result per picture,
    /// in the order of [`PLOT_FILES`]: a picture that cannot be drawn or written is an
    /// output error naming it, and does not keep the other from being written.
    pub fn write_plots(&self, dir: &Path, facts: &PlotFacts, o: &Outcome) -> [Result<Written>; 2] {
        let state = match o.converged {
            true => format!("converged after {} sweeps", o.iterations),
            false => format!("NOT converged after {} sweeps", o.iterations),
        };
        let contact = || {
            let pairs: Vec<_> = (facts.pairs.iter().enumerate())
                .map(|(i, name)| pair_series(name, i as u32, &self.contact, facts.frictional))
                .collect();
            let what = format!("Contact {}: {}, {state}", facts.along, facts.friction);
            contact_png([&what, facts.title], facts.abscissa, &pairs)
        };
        let convergence = || {
            let series = convergence_series(&o.history, facts.frictional, facts.tol);
            let what = format!("Convergence: {}, {state}", facts.friction);
            convergence_png([&what, facts.title], &series)
        };
        let draw = |name: &str, png: std::result::Result<Vec<u8>, String>| {
            let bytes = png.map_err(|e| Error::Output(format!("cannot draw {name}: {e}")))?;
            write_atomic(&dir.join(name), &bytes)?;
            Ok(Written::file(bytes.len()))
        };
        // Drawn and written at once: each is mostly its own encoding and fsync.
        let (a, b) = rayon::join(
            || draw(PLOT_FILES[0], contact()),
            || draw(PLOT_FILES[1], convergence()),
        );
        [a, b]
    }

    /// Writes `summary.json` into `dir`: the `facts`, the outcome `o`, the totals of the
    /// rows, the `timings` and the per-subdomain figures.
    pub fn write_summary(
        &self,
        dir: &Path,
        facts: RunFacts,
        o: &Outcome,
        timings: Timings,
    ) -> Result<Written> {
        let summary = self.summary(facts, o, timings);
        // Through a `Value`, whose objects sort their keys: the file's order.
        let json = serde_json::to_value(&summary)
            .and_then(|v| serde_json::to_string_pretty(&v))
            .map_err(|e| Error::Output(format!("cannot format summary.json: {e}")))?;
        write_atomic(&dir.join("summary.json"), json.as_bytes())?;
        Ok(Written::file(json.len()))
    }

    fn summary(&self, facts: RunFacts, o: &Outcome, timings: Timings) -> Summary<'_> {
        let with_status = |s: Status| self.contact.iter().filter(|r| r.status == s).count();
        let (stick, slip) = (with_status(Status::Stick), with_status(Status::Slip));
        let frictionless = with_status(Status::Contact);
        // Without friction there is no stick or slip to count.
        let frictional = |n: usize| (facts.friction != "none").then_some(n);
        let last = o.history.last();
        let stats = &self.stats;
        let max_over =
            |f: fn(&RankStats) -> f64| stats.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
        // The subdomains of a rank share its process, so its peak.
        let peak_per_rank = (0..facts.ranks)
            .map(|r| {
                let of_rank = stats.iter().filter(|s| s.rank == r);
                of_rank.map(|s| s.peak_memory_bytes).max().unwrap_or(0)
            })
            .collect();
        let contacts = (facts.pairs.iter().enumerate())
            .map(|(i, (slave, obstacle, master))| {
                let rows = || self.contact.iter().filter(move |r| r.pair == i as u32);
                let force_of = |r: &ContactRow, c: usize| {
                    r.w * (r.p_n * r.normal[c] + r.p_t * tangent_of(r.normal)[c])
                };
                PairSums {
                    slave: slave.clone(),
                    obstacle,
                    contact_nodes: rows().count(),
                    active_nodes: rows().filter(|r| r.status != Status::Free).count(),
                    normal_force: rows().map(|r| r.w * r.p_n).sum(),
                    tangential_force: rows().map(|r| r.w * r.p_t).sum(),
                    force: [0, 1].map(|c| rows().map(|r| force_of(r, c)).sum()),
                    master: master.clone(),
                    master_force: master.as_ref().map(|_| {
                        [0, 1].map(|c| rows().map(|r| -r.to_master * force_of(r, c)).sum())
                    }),
                }
            })
            .collect();
        Summary {
            contacts,
            converged: o.converged,
            iterations: o.iterations,
            outer_iterations: o.outer_iterations,
            refused_accelerations: o.refused,
            active_nodes: stick + slip + frictionless,
            stick_nodes: frictional(stick),
            slip_nodes: frictional(slip),
            total_normal_force: self.contact.iter().map(|r| r.w * r.p_n).sum(),
            total_tangential_force: self.contact.iter().map(|r| r.w * r.p_t).sum(),
            r_retunes: o.retunes,
            r_loop: o.r,
            smooth_stiffness_ratio: o.smooth_stiffness,
            final_residuals: Residuals {
                error_estimate: last.map(|s| s.error),
                pressure_change: last.map(|s| s.pressure),
                traction_change: last.map(|s| s.traction),
                displacement_change: last.map(|s| s.displacement),
                contraction: last.map(|s| s.contraction),
            },
            timings_s: timings,
            sweep_s: timings.uzawa / o.iterations.max(1) as f64,
            one_solve_s: max_over(|s| s.one_solve_s),
            peak_memory_bytes: stats.iter().map(|s| s.peak_memory_bytes).max().unwrap_or(0),
            peak_memory_bytes_per_rank: peak_per_rank,
            per_subdomain: stats,
            per_subdomain_max: Extremes::of(stats, f64::NEG_INFINITY, f64::max),
            per_subdomain_min: Extremes::of(stats, f64::INFINITY, f64::min),
            interface_factor: stats.iter().find_map(|s| s.interface_factor.clone()),
            interface_gflop: stats.iter().map(|s| s.interface_gflop).sum(),
            interface_factor_entries: stats.iter().map(|s| s.interface_factor_entries).sum(),
            facts,
        }
    }
}

/// summary.json.
#[derive(Serialize)]
struct Summary<'a> {
    #[serde(flatten)]
    facts: RunFacts,
    converged: bool,
    iterations: usize,
    outer_iterations: usize,
    refused_accelerations: usize,
    active_nodes: usize,
    /// Null without friction.
    stick_nodes: Option<usize>,
    slip_nodes: Option<usize>,
    total_normal_force: f64,
    total_tangential_force: f64,
    /// Per contact, in the case's order.
    contacts: Vec<PairSums>,
    r_retunes: usize,
    /// The reference r of the loop: `r`, or lower for a body far softer than a compact
    /// one.
    r_loop: f64,
    /// The body's measured smooth-mode stiffness over E_eff / L (null when r was given).
    smooth_stiffness_ratio: Option<f64>,
    final_residuals: Residuals,
    timings_s: Timings,
    sweep_s: f64,
    one_solve_s: f64,
    peak_memory_bytes: u64,
    peak_memory_bytes_per_rank: Vec<u64>,
    per_subdomain: &'a [RankStats],
    per_subdomain_max: Extremes,
    per_subdomain_min: Extremes,
    interface_factor: Option<String>,
    interface_gflop: f64,
    interface_factor_entries: f64,
}

/// The stopping test's figures at the last sweep (null without one): see [`Sweep`].
#[derive(Serialize)]
struct Residuals {
    error_estimate: Option<f64>,
    pressure_change: Option<f64>,
    traction_change: Option<f64>,
    displacement_change: Option<f64>,
    contraction: Option<f64>,
}

/// The largest or the smallest of some per-subdomain figures.
#[derive(Serialize)]
struct Extremes {
    assemble_s: f64,
    factor_s: f64,
    loop_s: f64,
    elements: f64,
    interface_nodes: f64,
    sent_bytes_per_sweep: f64,
}

impl Extremes {
    fn of(stats: &[RankStats], init: f64, pick: fn(f64, f64) -> f64) -> Self {
        let over = |f: fn(&RankStats) -> f64| stats.iter().map(f).fold(init, pick);
        Extremes {
            assemble_s: over(|s| s.assemble_s),
            factor_s: over(|s| s.factor_s),
            loop_s: over(|s| s.loop_s),
            elements: over(|s| s.elements as f64),
            interface_nodes: over(|s| s.interface_nodes as f64),
            sent_bytes_per_sweep: over(|s| s.sent_bytes_per_sweep),
        }
    }
}

/// Removes the `.vtu` pieces of an earlier run in `dir` that this run's index (`sources`)
/// does not list: a run on fewer subdomains, or with smaller pieces, would otherwise leave
/// files that look like part of its answer. Only names of the pieces' own form go.
fn remove_stale_pieces(dir: &Path, sources: &[String]) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else {
            continue;
        };
        if is_piece_name(name) && !sources.iter().any(|s| s == name) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Whether `name` is a piece's file name: `solution_<subdomain>_<k>.vtu`.
fn is_piece_name(name: &str) -> bool {
    let Some(middle) = name
        .strip_prefix("solution_")
        .and_then(|n| n.strip_suffix(".vtu"))
    else {
        return false;
    };
    let numbers: Vec<&str> = middle.split('_').collect();
    numbers.len() == 2
        && numbers
            .iter()
            .all(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

#[cfg(test)]
mod tests {
    use super::{is_piece_name, remove_stale_pieces};

    #[test]
    fn only_the_pieces_an_index_does_not_list_are_removed() {
        assert!(is_piece_name("solution_0_12.vtu"));
        assert!(!is_piece_name("solution_0.vtu"));
        assert!(!is_piece_name("solution_0_x.vtu"));
        assert!(!is_piece_name("solution_0_1.vtu.tmp"));
        assert!(!is_piece_name("my_solution_0_1.vtu"));
        let dir = tempfile::TempDir::new().unwrap();
        let names = [
            "solution_0_0.vtu",
            "solution_0_1.vtu",
            "solution_3_0.vtu",
            "notes.vtu",
        ];
        for n in names {
            std::fs::write(dir.path().join(n), b"x").unwrap();
        }
        remove_stale_pieces(dir.path(), &["solution_0_0.vtu".to_string()]);
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        assert_eq!(left, ["notes.vtu", "solution_0_0.vtu"]);
    }
}
