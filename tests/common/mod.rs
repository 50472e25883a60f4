//! Helpers shared by the integration tests: running the binary in a temporary directory,
//! reading its outputs, writing case files, and the KKT checks of the contact conditions.
//!
//! Every test file includes this module with `mod common;` and uses a part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use tempfile::TempDir;

pub const BIN: &str = env!("CARGO_BIN_EXE_contact-par");

/// `mpirun -n NP --oversubscribe BIN` started in `dir`, allowed to run as root.
///
/// `TMPDIR` is `dir` too. Open MPI 4 makes its session directory `$TMPDIR/ompi.HOST.UID`
/// by testing and then creating it, and fails ("File exists", orte_init failed) when
/// another mpirun creates it in between, which tests running in parallel do now and
/// then. A directory of its own per run cannot race.
pub fn mpirun(np: usize, dir: &Path) -> Command {
    mpirun_with(np, &[], dir)
}

/// [`mpirun`] with mpirun's own `options` (e.g. `--bind-to core`).
pub fn mpirun_with(np: usize, options: &[&str], dir: &Path) -> Command {
    let mut c = Command::new("mpirun");
    c.args(["-n", &np.to_string(), "--oversubscribe"])
        .args(options)
        .arg(BIN)
        .current_dir(dir)
        .env("TMPDIR", dir)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1");
    c
}

/// The first Python that runs `import_line`: `python3` on the PATH, else the system's (a
/// user's own Python, e.g. pyenv, may shadow the one Debian's packages install into).
#[allow(dead_code)]
pub fn python_with(import_line: &str) -> Option<&'static str> {
    ["python3", "/usr/bin/python3"].into_iter().find(|py| {
        Command::new(py)
            .args(["-c", import_line])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// A `TMPDIR` of its own for a run started without mpirun. As a singleton, Open MPI still
/// makes its session directory `$TMPDIR/ompi.HOST.UID/pid.PID`, and removes the shared
/// parent when it ends: a run starting meanwhile then fails in orte_init ("unable to create
/// the desired directory"), as one test did in CI. Not the run's own directory, whose
/// contents some tests check.
pub fn session_dir() -> TempDir {
    TempDir::new().expect("cannot make a session directory")
}

/// Directory of the committed Gmsh fixtures.
pub fn gmsh_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gmsh")
}

/// The two-body meshes and cases (`tests/data/bodies`).
pub fn bodies_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bodies")
}

/// One finished run of the binary. The temporary directory lives as long as this value.
pub struct Run {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
    /// The `--out` directory (may not exist if the run failed early).
    pub out: PathBuf,
    pub dir: TempDir,
}

impl Run {
    pub fn contact(&self) -> Vec<Row> {
        read_contact(&self.out.join("contact.csv"))
    }

    pub fn summary(&self) -> serde_json::Value {
        read_summary(&self.out.join("summary.json"))
    }

    /// A finished run in `dir` (its outputs in `dir/out`), which it keeps alive.
    pub fn kept(dir: TempDir, (code, stdout, stderr): (i32, String, String)) -> Run {
        Run {
            code,
            stdout,
            stderr,
            out: dir.path().join("out"),
            dir,
        }
    }

    /// Panics with the run's output unless it exited with `code`.
    pub fn expect_code(&self, code: i32) -> &Self {
        assert_eq!(
            self.code, code,
            "exit code {} (expected {code})\nstdout:\n{}\nstderr:\n{}",
            self.code, self.stdout, self.stderr
        );
        self
    }
}

/// Runs the binary with `args` inside `dir` (its working directory), MPI allowed as root.
pub fn run_in(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let session = session_dir();
    let out = Command::new(BIN)
        .args(args)
        .current_dir(dir)
        .env("TMPDIR", session.path())
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        // One thread per run: the suite runs tests in parallel, and results must not
        // depend on the thread count anyway.
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .expect("cannot start the contact-par binary");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Runs with `args` (plus `--out out --quiet`) in a fresh temporary directory.
pub fn run_args(args: &[&str]) -> Run {
    run_fresh(TempDir::new().unwrap(), args)
}

/// Writes `toml` to `case.toml` in a fresh temporary directory and runs it with `extra`
/// arguments (plus `--out out --quiet`).
pub fn run_case(toml: &str, extra: &[&str]) -> Run {
    let dir = TempDir::new().unwrap();
    std::fs::write(dir.path().join("case.toml"), toml).unwrap();
    let mut all = vec!["case.toml"];
    all.extend_from_slice(extra);
    run_fresh(dir, &all)
}

/// Runs `args` plus `--out out --quiet` in `dir`, which the returned run keeps alive.
fn run_fresh(dir: TempDir, args: &[&str]) -> Run {
    let mut all: Vec<&str> = args.to_vec();
    all.extend(["--out", "out", "--quiet"]);
    let result = run_in(dir.path(), &all);
    Run::kept(dir, result)
}

/// Runs the binary with `args` inside `dir` on `np` ranks (1: without mpirun).
pub fn run_on_ranks(dir: &Path, np: usize, args: &[&str]) -> (i32, String, String) {
    if np == 1 {
        return run_in(dir, args);
    }
    let o = mpirun(np, dir)
        .args(args)
        .output()
        .expect("mpirun must be installed (openmpi-bin)");
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Runs a built-in case at `level` with `extra` arguments.
pub fn run_builtin(name: &str, level: u32, extra: &[&str]) -> Run {
    let level = level.to_string();
    let mut all = vec!["--builtin", name, "--level", &level];
    all.extend_from_slice(extra);
    run_args(&all)
}

/// The TOML text of a built-in case, from `--print-case`.
pub fn print_case(name: &str, level: u32) -> String {
    let dir = TempDir::new().unwrap();
    let (code, stdout, stderr) = run_in(
        dir.path(),
        &[
            "--builtin",
            name,
            "--level",
            &level.to_string(),
            "--print-case",
        ],
    );
    assert_eq!(code, 0, "--print-case failed: {stderr}");
    stdout
}

/// One row of contact.csv.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    pub x: f64,
    pub y: f64,
    pub u_n: f64,
    pub u_t: f64,
    pub p_n: f64,
    pub p_t: f64,
    pub gap: f64,
    /// The index of the node's contact (`[[contact]]` entry).
    pub contact: u32,
}

impl Row {
    pub fn col(&self, c: usize) -> f64 {
        [
            self.x, self.y, self.u_n, self.u_t, self.p_n, self.p_t, self.gap,
        ][c]
    }
}

pub const COLUMNS: [&str; 7] = ["x", "y", "u_n", "u_t", "p_n", "p_t", "gap"];

/// The numeric rows of a CSV file with exactly `header`, each of `header`'s width and
/// every value finite (NaN or infinities would slip through max-based comparisons).
fn read_rows(path: &Path, header: &str) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(header));
    let width = header.split(',').count();
    lines
        .map(|l| {
            let v: Vec<f64> = l
                .split(',')
                .map(|f| {
                    f.parse()
                        .unwrap_or_else(|_| panic!("bad number {f:?} in {l:?}"))
                })
                .collect();
            assert_eq!(v.len(), width, "row {l:?}");
            assert!(v.iter().all(|x| x.is_finite()), "non-finite value in {l:?}");
            v
        })
        .collect()
}

pub fn read_contact(path: &Path) -> Vec<Row> {
    read_rows(path, "x,y,u_n,u_t,p_n,p_t,gap,contact")
        .into_iter()
        .map(|v| Row {
            contact: v[7] as u32,
            x: v[0],
            y: v[1],
            u_n: v[2],
            u_t: v[3],
            p_n: v[4],
            p_t: v[5],
            gap: v[6],
        })
        .collect()
}

/// nodes.csv: (x, y, ux, uy) per node, every value finite.
pub fn read_nodes(path: &Path) -> Vec<[f64; 4]> {
    read_rows(path, "x,y,ux,uy")
        .into_iter()
        .map(|v| [v[0], v[1], v[2], v[3]])
        .collect()
}

/// The rows of `out/history.csv` by column name: the header and each row's values.
pub fn read_history(out: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

/// The column `name` of [`read_history`]'s rows.
pub fn history_column(header: &[String], rows: &[Vec<f64>], name: &str) -> Vec<f64> {
    let k = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no {name}"));
    rows.iter().map(|r| r[k]).collect()
}

pub fn read_summary(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

pub fn num(s: &serde_json::Value, key: &str) -> f64 {
    s[key]
        .as_f64()
        .unwrap_or_else(|| panic!("summary.json has no number {key}: {s}"))
}

pub fn max_abs(rows: &[Row], c: usize) -> f64 {
    rows.iter().map(|r| r.col(c).abs()).fold(0.0, f64::max)
}

/// Largest difference of each column between two runs on the same mesh, relative to the
/// column's largest magnitude in `a` (absolute when that is 0). Rows are matched by order
/// (both files are sorted by x then y); the coordinates x, y are compared like the rest.
pub fn column_diffs(a: &[Row], b: &[Row]) -> [f64; 7] {
    assert_eq!(a.len(), b.len(), "different contact node counts");
    let mut out = [0.0; 7];
    for (c, o) in out.iter_mut().enumerate() {
        let scale = max_abs(a, c);
        let d = a
            .iter()
            .zip(b)
            .map(|(ra, rb)| (ra.col(c) - rb.col(c)).abs())
            .fold(0.0, f64::max);
        *o = if scale > 0.0 { d / scale } else { d };
    }
    out
}

/// Asserts that every column of `b` agrees with `a` to `rel` (see [`column_diffs`]).
pub fn assert_same_columns(a: &[Row], b: &[Row], rel: f64, what: &str) {
    let d = column_diffs(a, b);
    println!("{what}: relative column differences {:?}", d);
    let bad: Vec<String> = (0..7)
        .filter(|&c| d[c] > rel)
        .map(|c| format!("{} by {:e}", COLUMNS[c], d[c]))
        .collect();
    assert!(
        bad.is_empty(),
        "{what}: columns differ relative to their max (allowed {rel:e}): {}",
        bad.join(", ")
    );
}

/// Lumped weights of contact nodes on a straight horizontal line, from the sorted x
/// coordinates: half of each neighbouring segment.
pub fn line_weights(rows: &[Row]) -> Vec<f64> {
    let n = rows.len();
    (0..n)
        .map(|i| {
            let left = if i > 0 {
                rows[i].x - rows[i - 1].x
            } else {
                0.0
            };
            let right = if i + 1 < n {
                rows[i + 1].x - rows[i].x
            } else {
                0.0
            };
            0.5 * (left + right)
        })
        .collect()
}

/// The friction law of a run, for the KKT checks.
#[derive(Debug, Clone, Copy)]
pub enum Law {
    None,
    Tresca(f64),
    Coulomb(f64),
}

/// Node counts by state as seen in contact.csv by [`check_kkt`].
#[derive(Debug, Default, Clone, Copy)]
pub struct KktCounts {
    pub free: usize,
    pub stick: usize,
    pub slip: usize,
}

/// Checks the discrete contact conditions (docs/ALGORITHM.md) at every row of contact.csv:
///
/// - p_n >= -eps_p, u_n <= gap + eps_u, |p_n (u_n - gap)| <= eps_p * eps_u-scale;
/// - |p_t| <= s + eps_p (s = threshold, coefficient * p_n, or 0 when frictionless);
/// - stick (|p_t| < s (1 - delta)): |u_t| <= eps_u;
/// - slip (|u_t| > eps_u): | |p_t| - s | <= eps_p and p_t u_t <= 0.
///
/// eps_p = `rel` * max p_n and eps_u = `rel` * max(|u_n|, |u_t|) over the contact rows.
/// Returns the counts of free (p_n <= eps_p), stick and slip contact nodes (among active
/// ones for stick/slip).
pub fn check_kkt(rows: &[Row], law: Law, rel: f64, what: &str) -> KktCounts {
    let pmax = max_abs(rows, 4);
    let umax = max_abs(rows, 2).max(max_abs(rows, 3));
    assert!(pmax > 0.0 && umax > 0.0, "{what}: no contact at all");
    let eps_p = rel * pmax;
    let eps_u = rel * umax;
    let delta = 1e-3;
    let mut counts = KktCounts::default();
    // Worst values, printed for the record.
    let (mut w_pen, mut w_comp, mut w_pt, mut w_stick, mut w_slip) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for r in rows {
        let ctx = format!("{what}: node ({}, {}): {r:?}", r.x, r.y);
        assert!(r.p_n >= -eps_p, "{ctx}: negative pressure");
        assert!(
            r.u_n <= r.gap + eps_u,
            "{ctx}: penetration {:e}",
            r.u_n - r.gap
        );
        w_pen = w_pen.max((r.u_n - r.gap) / umax);
        let comp = (r.p_n * (r.u_n - r.gap)).abs();
        w_comp = w_comp.max(comp / (pmax * umax));
        assert!(
            comp <= rel * pmax * umax,
            "{ctx}: complementarity p_n (u_n - gap) = {comp:e}"
        );
        let s = match law {
            Law::None => 0.0,
            Law::Tresca(s) => s,
            Law::Coulomb(c) => c * r.p_n.max(0.0),
        };
        w_pt = w_pt.max((r.p_t.abs() - s) / pmax);
        assert!(
            r.p_t.abs() <= s + eps_p,
            "{ctx}: |p_t| = {} above the threshold {s}",
            r.p_t.abs()
        );
        let active = r.p_n > eps_p;
        if !active {
            counts.free += 1;
        }
        if r.p_t.abs() < s * (1.0 - delta) {
            w_stick = w_stick.max(r.u_t.abs() / umax);
            assert!(
                r.u_t.abs() <= eps_u,
                "{ctx}: sticks (|p_t| < s) but u_t = {:e}",
                r.u_t
            );
            if active {
                counts.stick += 1;
            }
        } else if r.u_t.abs() > eps_u {
            w_slip = w_slip.max((r.p_t.abs() - s).abs() / pmax);
            assert!(
                (r.p_t.abs() - s).abs() <= eps_p,
                "{ctx}: slips but |p_t| = {} differs from s = {s}",
                r.p_t.abs()
            );
            assert!(
                r.p_t * r.u_t <= 0.0,
                "{ctx}: friction does not oppose the slip"
            );
            if active {
                counts.slip += 1;
            }
        }
    }
    println!(
        "{what}: KKT worst (relative): penetration {w_pen:e}, complementarity {w_comp:e}, |p_t| - s {w_pt:e}, stick |u_t| {w_stick:e}, slip ||p_t| - s| {w_slip:e}; counts {counts:?}"
    );
    counts
}

/// The built-in block (40 x 10 on y = 0) as a TOML case, with the given extra
/// `[[dirichlet]]`/`[[traction]]` blocks and `[contact]` friction lines.
///
/// `top` is the body of the top `[[dirichlet]]` block (e.g. `"ux = 0.01\nuy = -0.02"`),
/// `friction` the friction lines of `[contact]` (e.g. `"friction = \"none\""`), `normal`
/// the obstacle normal and `extra` any further TOML appended at the end (after
/// `[solver]`, so a bare `key = value` there is a solver setting).
///
/// The foundation passes through (0, -0.001): an initial gap of 0.001 under the block,
/// so u_n is never identically 0 (the zero-gap case has its own regression test,
/// `zero_gap_full_contact_converges`).
pub fn block_case(level: u32, top: &str, friction: &str, normal: [f64; 2], extra: &str) -> String {
    format!(
        r#"title = "test block"
[mesh]
builtin = "block"
level = {level}
[material]
young = 70000.0
poisson = 0.33
hypothesis = "plane_strain"
[[dirichlet]]
group = "top"
{top}
[contact]
group = "bottom"
obstacle_point = [0.0, -0.001]
obstacle_normal = [{:?}, {:?}]
{friction}
[solver]
tol = 1e-10
{extra}
"#,
        normal[0], normal[1]
    )
}

/// The TOML of built-in case `name` at `level` with its friction lines (friction,
/// threshold, coefficient) replaced by `friction`.
pub fn builtin_with_friction(name: &str, level: u32, friction: &str) -> String {
    let text = contact_par::case::builtin_case_text(name, level).expect("a built-in case");
    let mut out = String::new();
    for line in text.lines() {
        let key = line.split('=').next().unwrap_or("").trim();
        if ["friction", "threshold", "coefficient"].contains(&key) {
            continue;
        }
        out.push_str(line);
        out.push('\n');
        if line.starts_with("obstacle_normal") {
            out.push_str(friction);
            out.push('\n');
        }
    }
    out
}

/// Against Hertz's half-width `a` and peak `p0`: the relative errors of the half-width
/// (the midpoint between the last node in contact and the next), of the peak pressure,
/// and the largest error of the profile p0 sqrt(1 - x^2/a^2) over x < 0.8 a, relative to
/// p0. Checks first that the contact zone is one interval from x = 0 and that a lies
/// between those two nodes (within 3%). `rows` sorted by x.
pub fn hertz_errors_of(rows: &[Row], a: f64, p0: f64, what: &str) -> (f64, f64, f64) {
    let last = rows.iter().rposition(|r| r.p_n > 0.0).expect("no contact");
    assert!(
        rows[..last].iter().all(|r| r.p_n > 0.0),
        "{what}: the contact zone is not one interval"
    );
    let (x_in, x_out) = (rows[last].x, rows[last + 1].x);
    assert!(
        x_in <= a * 1.03 && x_out >= a * 0.97,
        "{what}: a = {a} not between the nodes {x_in}, {x_out}"
    );
    let e_a = (0.5 * (x_in + x_out) - a) / a;
    let pmax = rows.iter().map(|r| r.p_n).fold(0.0, f64::max);
    let e_p = (pmax - p0) / p0;
    let profile = (rows.iter().filter(|r| r.x < 0.8 * a))
        .map(|r| (r.p_n - p0 * (1.0 - (r.x / a).powi(2)).sqrt()).abs() / p0)
        .fold(0.0, f64::max);
    println!(
        "{what}: a = {a}, p0 = {p0}: half-width {e_a:+.3e}, peak {e_p:+.3e}, profile {profile:.3e}"
    );
    (e_a, e_p, profile)
}

/// The 2 x 1 rectangle of the Gmsh fixtures (`tests/data/gmsh/rect_*`) on the mesh file
/// `mesh`, its top sheared and pressed, on the line y = -0.001 with Coulomb 0.3.
pub fn rect_case_on(mesh: &str) -> String {
    format!(
        r#"[mesh]
file = "{mesh}"
[material]
young = 1000.0
poisson = 0.3
[[dirichlet]]
group = "top"
ux = 0.002
uy = -0.01
[contact]
group = "bottom"
obstacle_point = [0.0, -0.001]
obstacle_normal = [0.0, 1.0]
friction = "coulomb"
coefficient = 0.3
[solver]
tol = 1e-10
"#
    )
}

/// The unstructured Gmsh quarter disc of the fixtures (radius 1, centre (0, 1), groups
/// contact, axis, top) on the mesh file `mesh`, pressed on y = 0 through its top,
/// symmetry on the axis, with the contact's `friction` lines.
pub fn quarter_disc_case_on(mesh: &str, friction: &str) -> String {
    format!(
        r#"title = "Gmsh quarter disc"
[mesh]
file = "{mesh}"
[material]
young = 1000.0
poisson = 0.3
[[dirichlet]]
group = "axis"
ux = 0.0
[[dirichlet]]
group = "top"
uy = -0.01
[contact]
group = "contact"
obstacle_point = [0.0, 0.0]
obstacle_normal = [0.0, 1.0]
{friction}
[solver]
tol = 1e-10
"#
    )
}

/// The warnings of `summary` (`warnings` in summary.json), split into the one that says
/// round-off bounds the accuracy and the others.
fn warnings_by_round_off(summary: &serde_json::Value) -> (Vec<String>, Vec<String>) {
    summary["warnings"]
        .as_array()
        .expect("warnings")
        .iter()
        .map(|w| w.as_str().expect("a warning").to_string())
        .partition(|w| w.starts_with("round-off"))
}

/// The warnings of `summary` that say the answer is not unique, leaving out the one
/// that says round-off bounds the accuracy.
#[allow(dead_code)]
pub fn not_unique_warnings(summary: &serde_json::Value) -> Vec<String> {
    warnings_by_round_off(summary).1
}

/// The warning of `summary` that says round-off bounds the accuracy, if any.
#[allow(dead_code)]
pub fn roundoff_warnings(summary: &serde_json::Value) -> Vec<String> {
    warnings_by_round_off(summary).0
}

/// A copy of an MSH 4.1 ASCII file with its node tags permuted and the nodes and
/// elements of every block listed in another order: the same mesh as a mesher with
/// another numbering would write it. `seed` drives a small LCG, so the copy is fixed.
pub fn shuffled_msh41(text: &str, seed: u64) -> String {
    let mut state = seed;
    let mut next = move |n: usize| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 33) % n as u64) as usize
    };
    let mut shuffle = |v: &mut Vec<usize>| {
        for i in (1..v.len()).rev() {
            v.swap(i, next(i + 1));
        }
    };
    let lines: Vec<&str> = text.lines().collect();
    let mut out: Vec<String> = Vec::new();
    let mut new_tag = std::collections::HashMap::new();
    let mut i = 0;
    while i < lines.len() {
        out.push(lines[i].to_string());
        i += 1;
        let section = lines[i - 1];
        if section != "$Nodes" && section != "$Elements" {
            continue;
        }
        let head: Vec<usize> = lines[i]
            .split_whitespace()
            .map(|w| w.parse().unwrap())
            .collect();
        out.push(lines[i].to_string());
        i += 1;
        let mut tags: Vec<usize> = (1..=head[1]).collect();
        if section == "$Nodes" {
            shuffle(&mut tags);
        }
        let mut k = 0;
        for _ in 0..head[0] {
            out.push(lines[i].to_string());
            let count: usize = lines[i].split_whitespace().nth(3).unwrap().parse().unwrap();
            i += 1;
            let mut order: Vec<usize> = (0..count).collect();
            shuffle(&mut order);
            if section == "$Nodes" {
                for j in 0..count {
                    new_tag.insert(lines[i + j].trim().to_string(), tags[k + j]);
                }
                k += count;
                out.extend(
                    order
                        .iter()
                        .map(|&j| new_tag[lines[i + j].trim()].to_string()),
                );
                out.extend(order.iter().map(|&j| lines[i + count + j].to_string()));
                i += 2 * count;
            } else {
                out.extend(order.iter().map(|&j| {
                    let mut w = lines[i + j].split_whitespace();
                    let tag = w.next().unwrap().to_string();
                    let nodes = w.map(|t| new_tag[t].to_string());
                    std::iter::once(tag)
                        .chain(nodes)
                        .collect::<Vec<_>>()
                        .join(" ")
                }));
                i += count;
            }
        }
    }
    out.join("\n") + "\n"
}
