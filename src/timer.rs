//! One phase timer for the whole run: a scope guard per phase adds its wall-clock time
//! to the phase, and [`Timer::finish`] reads them all once, so that the printed table and
//! summary.json report the same numbers.
//!
//! ```
//! # use contact_par::timer::{Phase, Timer};
//! let timer = Timer::start();
//! {
//!     let _t = timer.phase(Phase::Assemble);
//!     // ... assemble ...
//! }
//! let n = timer.time(Phase::Factor, || 6 * 7);
//! assert_eq!(n, 42);
//! assert!(timer.finish().total >= timer.seconds(Phase::Assemble));
//! ```

use serde::Serialize;
use std::sync::Mutex;
use std::time::Instant;

/// A timed phase of the run, or a figure timed inside one (those after `Output`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    Read,
    Partition,
    /// Rank 0 sending every other rank its subproblem.
    Scatter,
    Assemble,
    Factor,
    Condense,
    /// The Uzawa loop.
    Loop,
    Recover,
    Output,
    /// Inside Factor: the fill-reducing ordering of the subdomain's interior.
    Ordering,
    /// Inside Condense: forming S_s = L_BB L_BB' and the condensed right-hand side.
    Schur,
    /// One sparse forward+backward solve with the subdomain's factor (on the condensed
    /// path, its forward half in Condense plus its backward half in Recover).
    OneSolve,
    /// Inside Output: this subdomain's own piece (its .vtu files and rows).
    Piece,
    /// Inside Read: the mesh read from its file (or generated).
    Mesh,
    /// Inside Read: the problem built on the mesh (`problem::build`).
    Problem,
    /// Inside Partition: the graph the cut reads.
    Graph,
    /// Inside Partition: the cut.
    Cut,
    /// Inside Partition: the split along the cut into subproblems.
    Split,
}

const PHASES: usize = Phase::Split as usize + 1;

/// The phases of the table, in the order they run.
pub const TABLE: [Phase; 9] = [
    Phase::Read,
    Phase::Partition,
    Phase::Scatter,
    Phase::Assemble,
    Phase::Factor,
    Phase::Condense,
    Phase::Loop,
    Phase::Recover,
    Phase::Output,
];

impl Phase {
    /// The phase's name in the table and in its line.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Read => "read",
            Phase::Partition => "partition",
            Phase::Scatter => "scatter",
            Phase::Assemble => "assemble",
            Phase::Factor => "factor",
            Phase::Condense => "condense",
            Phase::Loop => "loop",
            Phase::Recover => "recover",
            Phase::Output => "output",
            Phase::Ordering => "ordering",
            Phase::Schur => "schur",
            Phase::OneSolve => "one solve",
            Phase::Piece => "piece",
            Phase::Mesh => "mesh",
            Phase::Problem => "problem",
            Phase::Graph => "graph",
            Phase::Cut => "cut",
            Phase::Split => "split",
        }
    }
}

/// The line printed as `phase` ends: its name, its `seconds` as the table at the end
/// shows them, and a figure of what it did.
pub fn phase_line(phase: Phase, seconds: f64, figure: &str) -> String {
    let line = format!("{:<9} done in {seconds:>8.3} s", phase.name());
    match figure {
        "" => line,
        _ => format!("{line}: {figure}"),
    }
}

/// Wall-clock seconds per phase since [`Timer::start`], shared by the threads that may
/// time a phase (the first rank's set-up runs on borrowed threads).
pub struct Timer {
    start: Instant,
    spent: Mutex<[f64; PHASES]>,
}

/// Adds the time from its creation to its drop to its phase.
#[must_use = "the phase ends when the guard is dropped"]
pub struct Guard<'a> {
    timer: &'a Timer,
    phase: Phase,
    since: Instant,
}

impl Drop for Guard<'_> {
    fn drop(&mut self) {
        self.timer
            .add(self.phase, self.since.elapsed().as_secs_f64());
    }
}

impl Timer {
    /// A timer of a run starting now.
    pub fn start() -> Self {
        Timer {
            start: Instant::now(),
            spent: Mutex::new([0.0; PHASES]),
        }
    }

    /// A timer of the same run with nothing spent yet: another subdomain's.
    pub fn fork(&self) -> Self {
        Timer {
            start: self.start,
            spent: Mutex::new([0.0; PHASES]),
        }
    }

    /// Times `phase` until the guard is dropped.
    pub fn phase(&self, phase: Phase) -> Guard<'_> {
        Guard {
            timer: self,
            phase,
            since: Instant::now(),
        }
    }

    /// Times `phase` around `work`.
    pub fn time<T>(&self, phase: Phase, work: impl FnOnce() -> T) -> T {
        let _t = self.phase(phase);
        work()
    }

    /// Adds `seconds` measured elsewhere to `phase`.
    pub fn add(&self, phase: Phase, seconds: f64) {
        self.spent()[phase as usize] += seconds;
    }

    /// Seconds spent in `phase` so far (its guards dropped).
    pub fn seconds(&self, phase: Phase) -> f64 {
        self.spent()[phase as usize]
    }

    /// The seconds of `phases` as a phase's line shows its parts: "mesh 0.012 s,
    /// problem 0.034 s".
    pub fn figure(&self, phases: &[Phase]) -> String {
        let part = |&p: &Phase| format!("{} {:.3} s", p.name(), self.seconds(p));
        phases.iter().map(part).collect::<Vec<_>>().join(", ")
    }

    /// The phases of the table and the total since the start, read once.
    pub fn finish(&self) -> Timings {
        let s = |p: Phase| self.seconds(p);
        Timings {
            read: s(Phase::Read),
            partition: s(Phase::Partition),
            scatter: s(Phase::Scatter),
            assemble: s(Phase::Assemble),
            factor: s(Phase::Factor),
            condense: s(Phase::Condense),
            uzawa: s(Phase::Loop),
            recover: s(Phase::Recover),
            output: s(Phase::Output),
            total: self.start.elapsed().as_secs_f64(),
        }
    }

    fn spent(&self) -> std::sync::MutexGuard<'_, [f64; PHASES]> {
        // A thread that panicked while adding leaves a valid array.
        self.spent.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The run's phases in seconds (summary.json `timings_s`, and the printed table).
#[derive(Serialize, Default, Clone, Copy, Debug, PartialEq)]
pub struct Timings {
    pub read: f64,
    pub partition: f64,
    /// Rank 0 sending every other rank its subproblem.
    pub scatter: f64,
    pub assemble: f64,
    pub factor: f64,
    pub condense: f64,
    #[serde(rename = "loop")]
    pub uzawa: f64,
    pub recover: f64,
    pub output: f64,
    pub total: f64,
}

impl Timings {
    /// The table printed at the end of a run, one line each; the loop's line also gives
    /// the time per sweep of its `iterations`.
    pub fn table(&self, iterations: usize) -> Vec<String> {
        let mut lines = vec!["phase         seconds".to_string()];
        let phases = TABLE.iter().map(|&p| (p.name(), self.seconds(p)));
        for (name, v) in phases.chain([("total", self.total)]) {
            let extra = if name == "loop" && iterations > 0 {
                format!(
                    "   ({iterations} sweeps, {:.3} ms/sweep)",
                    1e3 * self.uzawa / iterations as f64
                )
            } else {
                String::new()
            };
            lines.push(format!("{name:<10} {v:>10.3}{extra}"));
        }
        lines
    }

    /// The seconds of a phase of the table (0 for the figures timed inside one).
    pub fn seconds(&self, phase: Phase) -> f64 {
        match phase {
            Phase::Read => self.read,
            Phase::Partition => self.partition,
            Phase::Scatter => self.scatter,
            Phase::Assemble => self.assemble,
            Phase::Factor => self.factor,
            Phase::Condense => self.condense,
            Phase::Loop => self.uzawa,
            Phase::Recover => self.recover,
            Phase::Output => self.output,
            _ => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn guards_add_up_per_phase_and_the_table_reads_what_finish_read() {
        let timer = Timer::start();
        timer.add(Phase::Loop, 2.0);
        timer.time(Phase::Loop, || ());
        {
            let _a = timer.phase(Phase::Condense);
            let _b = timer.phase(Phase::Schur);
        }
        assert!(timer.seconds(Phase::Loop) >= 2.0);
        assert!(timer.seconds(Phase::Condense) >= timer.seconds(Phase::Schur));
        let t = timer.finish();
        assert_eq!(t.uzawa, timer.seconds(Phase::Loop));
        assert!(t.total >= 0.0);
        let table = t.table(4);
        assert_eq!(table.len(), 11);
        assert!(table[7].starts_with("loop") && table[7].contains("4 sweeps"));
        assert_eq!(timer.fork().seconds(Phase::Loop), 0.0);
    }

    #[test]
    fn a_phase_line_shows_the_seconds_as_the_table_does() {
        let t = Timings {
            read: 12.3456,
            factor: 0.0004,
            total: 20.0,
            ..Timings::default()
        };
        let table = t.table(0);
        for phase in TABLE {
            let line = phase_line(phase, t.seconds(phase), "a figure");
            let row = table
                .iter()
                .find(|r| r.split_whitespace().next() == Some(phase.name()));
            let row = row.unwrap_or_else(|| panic!("no row for {}", phase.name()));
            let shown = |s: &str| s.split_whitespace().nth(1).map(str::to_string);
            let in_line = line.split_whitespace().nth(3).map(str::to_string);
            assert_eq!(in_line, shown(row), "{line} / {row}");
            assert!(line.ends_with(" s: a figure"), "{line}");
        }
        assert_eq!(
            phase_line(Phase::Read, 12.3456, ""),
            "read      done in   12.346 s"
        );
    }
}
