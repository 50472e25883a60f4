//! Phases 1-2 of a run from a mesh file or a built-in mesh: the first rank reads the
//! case and the mesh, builds the problem, cuts it into the run's subdomains (straight
//! cuts, METIS where they leave a part in pieces) and splits it along the cut; phase 3
//! then scatters the parts. `contact-par split` cuts the same way ([`Cut`]).

use super::split_dir::Facts;
use super::{check_linear, Layout, Setup};
use crate::case::{self, BuiltinMesh, Case, MeshSource};
use crate::dd::split::{split, split_whole, SubProblem};
use crate::error::{Error, Result};
use crate::host;
use crate::mesh::{builtin, gmsh, Mesh};
use crate::options::{LinearMode, Options, Partitioner};
use crate::problem::{self, Problem};
use crate::run::Printer;
use crate::timer::{self, Phase, Timer};

/// Phases 1-2 on the first rank: the set-up and every subproblem. Prints the run's
/// first line once the case and the mesh are read and checked, and each phase's line.
pub(super) fn setup(
    opts: &Options,
    layout: Layout,
    timer: &Timer,
    print: &Printer,
) -> Result<(Setup, Vec<SubProblem>)> {
    let (case, prob, mesh_name) = timer.time(Phase::Read, || read(opts, timer))?;
    check_linear(opts, &case)?;
    let triangles = prob.mesh.triangles.len();
    let per_rank = per_rank(opts, layout, triangles);
    // Checked before the first line: bad input prints nothing but its error.
    let nparts = check_subdomains(&mesh_name, triangles, layout.ranks, per_rank)?;
    let mut setup = Setup::new(opts, (case, facts(&prob)), None, layout, per_rank)?;
    print.line(&setup.header);
    print.line(read_line(&setup, &mesh_name, timer));
    let cut = Cut {
        nparts,
        partitioner: opts.partitioner,
        mesh_name: &mesh_name,
    };
    let (case, facts) = (&setup.case, &mut setup.facts);
    let (subs, method) = timer.time(Phase::Partition, || cut.split(case, facts, prob, timer))?;
    print.line(timer::phase_line(
        Phase::Partition,
        timer.seconds(Phase::Partition),
        &partition_figure(nparts, method, &setup.facts, timer),
    ));
    Ok((setup, subs))
}

/// The case, its problem on its mesh, and the mesh's name for messages; the mesh and the
/// problem timed as parts of the read.
fn read(opts: &Options, timer: &Timer) -> Result<(Case, Problem, String)> {
    let case = opts.load_case()?;
    let (mesh, mesh_name) = timer.time(Phase::Mesh, || load_mesh(&case))?;
    let prob = timer.time(Phase::Problem, || problem::build(&case, mesh, &mesh_name))?;
    Ok((case, prob, mesh_name))
}

/// The read's line: the mesh's size, and for a file the seconds of its parts.
fn read_line(setup: &Setup, mesh_name: &str, timer: &Timer) -> String {
    let f = &setup.facts;
    let parts = match setup.case.mesh {
        MeshSource::File(_) => format!("; {}", timer.figure(&[Phase::Mesh, Phase::Problem])),
        MeshSource::Builtin { .. } => String::new(),
    };
    let figure = format!(
        "{mesh_name}: {} nodes, {} triangles, {} contact nodes{parts}",
        f.nodes, f.elements, f.contact_nodes,
    );
    timer::phase_line(Phase::Read, timer.seconds(Phase::Read), &figure)
}

/// The partition's line: the seconds of its parts, the method that cut, the quality.
fn partition_figure(nparts: usize, method: &str, facts: &Facts, timer: &Timer) -> String {
    if nparts == 1 {
        return "one subdomain, no partition".to_string();
    }
    let [graph, cut, split] = [Phase::Graph, Phase::Cut, Phase::Split].map(|p| timer.figure(&[p]));
    format!("{graph}, {cut} ({method}), {split}: {}", facts.partition)
}

/// Subdomains per rank of a run from a mesh of `triangles` triangles: as asked, else
/// one for `--linear full`, else [`host::subdomains_per_rank`].
fn per_rank(opts: &Options, layout: Layout, triangles: usize) -> usize {
    match opts.subdomains_per_rank {
        Some(k) => k,
        None if opts.linear == LinearMode::Full => 1,
        None => host::subdomains_per_rank(layout.threads, layout.ranks, triangles),
    }
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

/// How the first rank cuts a problem into `nparts` parts.
pub(super) struct Cut<'a> {
    pub nparts: usize,
    pub partitioner: Partitioner,
    pub mesh_name: &'a str,
}

impl Cut<'_> {
    /// Phase 2: `prob` cut and split into its subproblems; `facts` take the split's
    /// figures. Returns them with the name of the method that cut.
    pub fn split(
        &self,
        case: &Case,
        facts: &mut Facts,
        prob: Problem,
        timer: &Timer,
    ) -> Result<(Vec<SubProblem>, &'static str)> {
        let frictional = Problem::is_frictional(case);
        if self.nparts == 1 {
            // One part is the problem itself, moved: no graph.
            let pieces = prob.holding.first.len();
            let quality = partition::Quality::one_part(prob.mesh.triangles.len(), pieces);
            let (sub, map) = timer.time(Phase::Split, || split_whole(prob, frictional));
            facts.n_boundary = map.n_boundary;
            facts.partition = quality.to_string();
            return Ok((vec![sub], "no cut"));
        }
        let graph = timer.time(Phase::Graph, || self.graph(&prob))?;
        let (parts, method) = timer.time(Phase::Cut, || self.parts(&graph, &prob))?;
        let (subs, map, quality) = timer.time(Phase::Split, || -> Result<_> {
            let (triangles, contact) = (&prob.mesh.triangles, &prob.contact_nodes);
            let part = match parts {
                Parts::Graph(parts) => graph.finish(triangles, contact, self.nparts, parts),
                Parts::Straight(parts) => graph.finish_straight(triangles, contact, parts),
            }
            .map_err(|e| self.cannot(e))?;
            let (subs, map) = split(&prob, &part, frictional)?;
            Ok((subs, map, part.quality.to_string()))
        })?;
        // The whole problem is not needed past here; the other ranks wait for their parts.
        host::drop_in_background(prob);
        facts.n_boundary = map.n_boundary;
        facts.n_interface = map.n_interface;
        facts.partition = quality;
        Ok((subs, method))
    }

    /// The graph the partition cuts (see [`partition::MeshGraph`]).
    fn graph(&self, prob: &Problem) -> Result<partition::MeshGraph> {
        // Each slave node of a contact between bodies tied to its master nodes: the
        // parts then keep a contact zone's two sides together.
        let ties: Vec<[usize; 2]> = (prob.contact_nodes.iter().zip(&prob.contact_masters))
            .flat_map(|(&s, masters)| masters.iter().map(move |&(m, _)| [s, m]))
            .collect();
        let (nodes, triangles) = (prob.mesh.num_nodes(), &prob.mesh.triangles);
        partition::MeshGraph::new(nodes, triangles, &ties, true).map_err(|e| self.cannot(e))
    }

    /// The triangles' parts: straight cuts unless METIS is asked for, METIS where they
    /// do not apply; with the name of the method that made them.
    fn parts(&self, graph: &partition::MeshGraph, prob: &Problem) -> Result<(Parts, &'static str)> {
        if self.partitioner.straight_first() {
            if let Some(parts) = graph.cut_straight(&prob.mesh.centroids(), self.nparts) {
                return Ok((Parts::Straight(parts), "straight cuts"));
            }
        }
        let parts = graph.cut(self.nparts).map_err(|e| self.cannot(e))?;
        Ok((Parts::Graph(parts), "METIS"))
    }

    fn cannot(&self, e: partition::PartitionError) -> Error {
        Error::Input(format!(
            "{}: cannot partition the mesh: {e}",
            self.mesh_name
        ))
    }
}

/// Each triangle's part, and what the partitioner counted of them.
enum Parts {
    /// Cut from the graph, which the quality report counts on.
    Graph(Vec<u32>),
    /// Straight cuts, which counted their pieces and edges cut as they made them.
    Straight(partition::StraightParts),
}

/// The figures of the whole problem; the split's (the boundary and interface dofs, the
/// partition's report) are filled in by [`Cut::split`].
pub(super) fn facts(prob: &Problem) -> Facts {
    Facts {
        lengths: prob.lengths(),
        contact_bodies: prob.contact_bodies.clone(),
        n_boundary: 0,
        n_interface: 0,
        nodes: prob.mesh.num_nodes(),
        elements: prob.mesh.triangles.len(),
        free_dofs: prob.fixed.iter().filter(|f| f.is_none()).count(),
        contact_nodes: prob.contact_nodes.len(),
        partition: String::new(),
        holding: prob.holding.clone(),
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
