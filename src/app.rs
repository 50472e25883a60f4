//! One run of the program, told as numbered steps: read, build, assemble and factor,
//! iterate, write. `main.rs` only wires the command line and MPI to this.

use crate::case::{self, BuiltinMesh, Case, CoulombMode, Friction, MeshSource};
use crate::contact::{self, NoComm, Status, Sweep};
use crate::error::{Error, Result};
use crate::fem;
use crate::linear::{ContactDofs, DirectStep};
use crate::mesh::{builtin, gmsh, Mesh};
use crate::output::{self, ContactRow, HistoryRow};
use crate::problem::{self, Problem};
use serde::Serialize;
use std::path::{Path, PathBuf};
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
    pub monitor_every: usize,
}

/// Prints on the first rank only, and not at all with --quiet.
pub struct Printer {
    pub enabled: bool,
}

impl Printer {
    pub fn line(&self, s: impl AsRef<str>) {
        if self.enabled {
            println!("{}", s.as_ref());
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
    assemble: f64,
    factor: f64,
    #[serde(rename = "loop")]
    uzawa: f64,
    output: f64,
    total: f64,
}

#[derive(Serialize)]
struct Residuals {
    primal: f64,
    dual: f64,
}

#[derive(Serialize)]
struct Summary<'a> {
    title: &'a str,
    case: &'a str,
    converged: bool,
    iterations: usize,
    outer_iterations: usize,
    ranks: usize,
    threads: usize,
    nodes: usize,
    elements: usize,
    dofs: usize,
    free_dofs: usize,
    contact_nodes: usize,
    active_nodes: usize,
    stick_nodes: usize,
    slip_nodes: usize,
    total_normal_force: f64,
    total_tangential_force: f64,
    friction: &'a str,
    r: f64,
    tol: f64,
    final_residuals: Residuals,
    factor_nnz: usize,
    timings_s: Timings,
    peak_memory_bytes: u64,
}

/// Resolves the case: a file, or a built-in case at a refinement level; then applies the
/// command-line overrides.
pub fn load_case(opts: &Options) -> Result<Case> {
    let mut case = match &opts.case_file {
        Some(path) => case::read_case(path)?,
        None => case::builtin_case(&opts.builtin, opts.level)?,
    };
    if let Some(r) = opts.r {
        case.solver.r = Some(r);
    }
    if let Some(tol) = opts.tol {
        case.solver.tol = tol;
    }
    if let Some(m) = opts.max_iter {
        case.solver.max_iter = m;
    }
    if let Some(c) = opts.coulomb {
        case.solver.coulomb = c;
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

/// The whole single-rank run.
pub fn run(opts: &Options, print: &Printer) -> Result<RunReport> {
    let t_start = Instant::now();
    let mut times = Timings::default();

    // 1. Read and validate the case and the mesh, build the discrete problem.
    let case = load_case(opts)?;
    let (mesh, mesh_name) = load_mesh(&case)?;
    let prob = problem::build(&case, mesh, &mesh_name)?;
    times.read = t_start.elapsed().as_secs_f64();
    let r = case.solver.r.unwrap_or_else(|| prob.default_r(&case));
    let frictional = Problem::is_frictional(&case);
    print.line(format!(
        "contact-par: {} | {} nodes, {} triangles, {} contact nodes | friction {} | r = {r:e}, tol = {:e}",
        if case.title.is_empty() { &case.origin } else { &case.title },
        prob.mesh.num_nodes(),
        prob.mesh.triangles.len(),
        prob.contact_nodes.len(),
        friction_name(&case.contact.friction),
        case.solver.tol
    ));

    // 2. Assemble A = K + r N'WN (+ r T'WT) and factor it once.
    let (mut step, setup) = DirectStep::new(
        &prob.mesh.nodes,
        &prob.mesh.triangles,
        &case.material,
        &prob.fixed,
        &prob.load,
        &ContactDofs {
            nodes: &prob.contact_nodes,
            w: &prob.contact.w,
            normal: prob.normal,
            tangent: prob.tangent,
            frictional,
        },
        r,
    )?;
    times.assemble = setup.assemble;
    times.factor = setup.factor;

    // 3. The Uzawa loop.
    let t_loop = Instant::now();
    let params = contact::Params {
        r,
        tol: case.solver.tol,
        max_iter: case.solver.max_iter,
        friction: case.contact.friction,
        coulomb: case.solver.coulomb,
    };
    let every = opts.monitor_every.max(1);
    let mut monitor = |s: &Sweep| {
        if s.iter == 1 || s.iter % every == 0 {
            print.line(monitor_line(s));
        }
    };
    let outcome = contact::solve(&mut step, &NoComm, &prob.contact, &params, &mut monitor)?;
    times.uzawa = t_loop.elapsed().as_secs_f64();
    if let Some(last) = outcome.history.last() {
        if last.iter % every != 0 {
            print.line(monitor_line(last));
        }
    }

    // 4. Outputs.
    let t_out = Instant::now();
    let u = step.displacement();
    write_outputs(
        opts,
        &case,
        &prob,
        &u,
        &outcome,
        r,
        step.factor_nnz(),
        times,
        t_out,
        t_start,
    )?;
    let total_normal: f64 = prob
        .contact
        .w
        .iter()
        .zip(&outcome.lambda)
        .map(|(w, l)| w * l)
        .sum();
    let status_count = |s: Status| outcome.status.iter().filter(|&&x| x == s).count();

    times.output = t_out.elapsed().as_secs_f64();
    times.total = t_start.elapsed().as_secs_f64();
    print.line(format!(
        "{} after {} iterations: {} active contact nodes ({} stick, {} slip), total normal force {}",
        if outcome.converged { "converged" } else { "NOT CONVERGED" },
        outcome.iterations,
        status_count(Status::Stick) + status_count(Status::Slip),
        status_count(Status::Stick),
        status_count(Status::Slip),
        total_normal
    ));
    print_timings(print, &times, outcome.iterations);
    print.line(format!("outputs in {}", opts.out.display()));
    Ok(RunReport {
        converged: outcome.converged,
    })
}

fn print_timings(print: &Printer, t: &Timings, iterations: usize) {
    print.line("phase         seconds");
    for (name, v) in [
        ("read", t.read),
        ("assemble", t.assemble),
        ("factor", t.factor),
        ("loop", t.uzawa),
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
    use rayon::prelude::*;
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

#[allow(clippy::too_many_arguments)]
fn write_outputs(
    opts: &Options,
    case: &Case,
    prob: &Problem,
    u: &[[f64; 2]],
    o: &contact::Outcome,
    r: f64,
    factor_nnz: usize,
    mut times: Timings,
    t_out: Instant,
    t_start: Instant,
) -> Result<()> {
    let dir = &opts.out;
    std::fs::create_dir_all(dir).map_err(|e| {
        Error::Output(format!(
            "cannot create the output directory {}: {e}; choose another with --out",
            dir.display()
        ))
    })?;
    let mesh = &prob.mesh;
    let n = mesh.num_nodes();

    let rows: Vec<ContactRow> = prob
        .contact_nodes
        .iter()
        .enumerate()
        .map(|(k, &node)| ContactRow {
            x: mesh.nodes[node][0],
            y: mesh.nodes[node][1],
            u_n: o.un[k],
            u_t: o.ut[k],
            p_n: o.lambda[k],
            p_t: -o.mu[k],
            gap: prob.contact.g[k],
        })
        .collect();
    output::write_atomic(
        &dir.join("contact.csv"),
        output::contact_csv(&rows).as_bytes(),
    )?;
    if opts.nodes_csv {
        output::write_atomic(
            &dir.join("nodes.csv"),
            output::nodes_csv(&mesh.nodes, u).as_bytes(),
        )?;
    }
    let history: Vec<HistoryRow> = o
        .history
        .iter()
        .map(|s| HistoryRow {
            iter: s.iter,
            primal: s.primal,
            dual: s.dual,
            active: s.active,
            slip: s.slip,
        })
        .collect();
    output::write_atomic(
        &dir.join("history.csv"),
        output::history_csv(&history).as_bytes(),
    )?;

    let (stress, vm) = element_stresses(case, mesh, u);
    let mut pressure = vec![0.0; n];
    let mut traction = vec![0.0; n];
    let mut status = vec![-1i32; n];
    for (k, &node) in prob.contact_nodes.iter().enumerate() {
        pressure[node] = o.lambda[k];
        traction[node] = -o.mu[k];
        status[node] = o.status[k] as i32;
    }
    let rank = vec![0i32; mesh.triangles.len()];
    let piece = output::Piece {
        nodes: &mesh.nodes,
        triangles: &mesh.triangles,
        displacement: u,
        stress: &stress,
        von_mises: &vm,
        rank: &rank,
        contact_pressure: &pressure,
        tangential_traction: &traction,
        contact_status: &status,
    };
    output::write_atomic(&dir.join("solution.vtu"), &output::vtu_bytes(&piece)?)?;

    let count = |s: Status| o.status.iter().filter(|&&x| x == s).count();
    let last = o.history.last();
    times.output = t_out.elapsed().as_secs_f64();
    times.total = t_start.elapsed().as_secs_f64();
    let summary = Summary {
        title: &case.title,
        case: &case.origin,
        converged: o.converged,
        iterations: o.iterations,
        outer_iterations: o.outer_iterations,
        ranks: 1,
        threads: rayon::current_num_threads(),
        nodes: n,
        elements: mesh.triangles.len(),
        dofs: 2 * n,
        free_dofs: prob.fixed.iter().filter(|f| f.is_none()).count(),
        contact_nodes: prob.contact_nodes.len(),
        active_nodes: count(Status::Stick) + count(Status::Slip),
        stick_nodes: count(Status::Stick),
        slip_nodes: count(Status::Slip),
        total_normal_force: prob
            .contact
            .w
            .iter()
            .zip(&o.lambda)
            .map(|(w, l)| w * l)
            .sum(),
        total_tangential_force: prob.contact.w.iter().zip(&o.mu).map(|(w, m)| -w * m).sum(),
        friction: friction_name(&case.contact.friction),
        r,
        tol: case.solver.tol,
        final_residuals: Residuals {
            primal: last.map_or(f64::NAN, |s| s.primal),
            dual: last.map_or(f64::NAN, |s| s.dual),
        },
        factor_nnz,
        timings_s: times,
        peak_memory_bytes: peak_memory_bytes(),
    };
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::Output(format!("cannot format summary.json: {e}")))?;
    output::write_atomic(&dir.join("summary.json"), json.as_bytes())?;
    Ok(())
}

/// For messages: a path relative to where the user ran the program when possible.
pub fn display_path(p: &Path) -> String {
    p.display().to_string()
}
