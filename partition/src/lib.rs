//! Mesh partitioning for contact-par.
//!
//! Rank 0 calls [`partition_mesh`] to split a P1 triangle mesh over `nparts` MPI ranks:
//!
//! 1. [`dual_graph`]: triangles are vertices, two triangles are adjacent when they
//!    share an edge;
//! 2. METIS k-way partitioning of that graph with fixed options, on large meshes after
//!    coarsening it here and followed by refinement (see [`partition_mesh`]), so the
//!    same mesh always gives the same parts; or, from the triangles' positions,
//!    recursive straight cuts followed by the same refinement
//!    ([`MeshGraph::cut_straight`]);
//! 3. ownership: an element belongs to its METIS part, a node to the lowest part id
//!    among the parts of the elements touching it;
//! 4. per-part bookkeeping: local elements and nodes, interface nodes, the shared node
//!    list of each neighbouring part, owned contact nodes;
//! 5. a [`Quality`] report.
//!
//! The crate knows no MPI, no physics and no file formats, so all of it is testable
//! in one process.
//!
//! ```
//! // A unit square split into two triangles, one per part.
//! let triangles = [[0, 1, 2], [0, 2, 3]];
//! let p = partition::partition_mesh(4, &triangles, &[0, 1], 2).unwrap();
//! assert_eq!(p.parts.len(), 2);
//! // Nodes 0 and 2 are on the shared edge: both parts see them, part 0 owns them.
//! let shared = &p.parts[0].neighbours[0];
//! assert_eq!(shared, &(1, vec![0, 2]));
//! assert_eq!(p.node_owner[2], 0);
//! ```

mod coarsen;
mod graph;
mod metis_rng;
mod straight;

pub use graph::Stars;
use graph::{dual_from_stars, pieces_and_cut, to_idx, Graph};
use metis::Idx;
pub use metis_rng::is_private as metis_runs_concurrently;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt;
use std::sync::Mutex;

/// Owner recorded in [`Partition::node_owner`] for a node that no triangle uses
/// (such a node belongs to no part).
pub const NO_PART: u32 = u32::MAX;

/// Seed of METIS' random number generator. 4321 is the seed METIS itself uses when
/// none is given, so the parts equal those of `gpmetis` run with default options on
/// the same graph, which makes them easy to cross-check.
pub const METIS_SEED: i32 = 4321;

/// Why a mesh could not be partitioned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PartitionError {
    /// `nparts` was zero.
    NoParts,
    /// More parts were requested than there are triangles.
    TooManyParts {
        /// Requested number of parts.
        nparts: usize,
        /// Number of triangles in the mesh.
        elements: usize,
    },
    /// A triangle refers to a node id `>= num_nodes`.
    NodeOutOfRange {
        /// Triangle index.
        element: usize,
        /// Offending node id.
        node: usize,
        /// Number of nodes of the mesh.
        num_nodes: usize,
    },
    /// A triangle uses the same node twice.
    DegenerateTriangle {
        /// Triangle index.
        element: usize,
    },
    /// A contact node id is `>= num_nodes`.
    ContactNodeOutOfRange {
        /// Offending node id.
        node: usize,
        /// Number of nodes of the mesh.
        num_nodes: usize,
    },
    /// A contact node is used by no triangle, so no part could own it.
    ContactNodeUnused {
        /// Offending node id.
        node: usize,
    },
    /// A given element-to-part map names a part `>= nparts`.
    PartOutOfRange {
        /// Triangle index.
        element: usize,
        /// Its part id.
        part: u32,
        /// Number of parts.
        nparts: usize,
    },
    /// The dual graph does not fit METIS' 32-bit indices.
    TooLarge,
    /// METIS itself failed.
    Metis(String),
}

impl fmt::Display for PartitionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoParts => write!(f, "cannot partition a mesh into 0 parts"),
            Self::TooManyParts { nparts, elements } => write!(
                f,
                "cannot split a mesh of {elements} triangles into {nparts} parts: \
                 use at most {elements} ranks or a finer mesh"
            ),
            Self::NodeOutOfRange {
                element,
                node,
                num_nodes,
            } => write!(
                f,
                "triangle {element} uses node {node}, but the mesh has only {num_nodes} nodes"
            ),
            Self::DegenerateTriangle { element } => {
                write!(f, "triangle {element} uses the same node twice")
            }
            Self::ContactNodeOutOfRange { node, num_nodes } => write!(
                f,
                "contact node {node} does not exist: the mesh has only {num_nodes} nodes"
            ),
            Self::ContactNodeUnused { node } => {
                write!(f, "contact node {node} belongs to no triangle")
            }
            Self::PartOutOfRange {
                element,
                part,
                nparts,
            } => write!(
                f,
                "triangle {element} is in part {part}, but there are only {nparts} parts"
            ),
            Self::TooLarge => write!(
                f,
                "the mesh is too large for METIS' 32-bit indices (more than 2^31 graph entries)"
            ),
            Self::Metis(msg) => write!(f, "METIS failed: {msg}"),
        }
    }
}

impl std::error::Error for PartitionError {}

/// The dual graph of a triangle mesh in CSR form: vertex `e` is triangle `e`, and its
/// neighbours `adjncy[xadj[e]..xadj[e + 1]]` are the triangles sharing an edge with it,
/// in increasing order, without duplicates. The graph is symmetric.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DualGraph {
    /// Row offsets, length `number of triangles + 1`.
    pub xadj: Vec<usize>,
    /// Concatenated neighbour lists.
    pub adjncy: Vec<usize>,
}

impl DualGraph {
    /// Number of vertices (triangles).
    pub fn num_vertices(&self) -> usize {
        self.xadj.len() - 1
    }

    /// Number of undirected edges (pairs of triangles sharing an edge).
    pub fn num_edges(&self) -> usize {
        self.adjncy.len() / 2
    }

    /// The triangles sharing an edge with triangle `e`, in increasing order.
    pub fn neighbours(&self, e: usize) -> &[usize] {
        &self.adjncy[self.xadj[e]..self.xadj[e + 1]]
    }
}

/// Builds the dual graph of a triangle mesh (see [`DualGraph`]).
///
/// Runs in O(number of triangles): the triangles across a mesh edge are the ones common
/// to the lists of triangles around its two nodes, which hold about six entries each.
/// An edge shared by more than two triangles (a non-manifold mesh) links all of them.
///
/// # Errors
/// [`PartitionError::NodeOutOfRange`] or [`PartitionError::DegenerateTriangle`] for an
/// invalid triangle; [`PartitionError::TooLarge`] beyond 2^31 graph entries.
pub fn dual_graph(num_nodes: usize, triangles: &[[usize; 3]]) -> Result<DualGraph, PartitionError> {
    let stars = Stars::new(num_nodes, triangles)?;
    let graph = dual_from_stars(triangles, &stars)?;
    Ok(DualGraph {
        xadj: graph.xadj.iter().map(|&v| v as usize).collect(),
        adjncy: graph.adjncy.iter().map(|&v| v as usize).collect(),
    })
}

/// What is wrong with triangle `element`, `t`, of a mesh of `num_nodes` nodes, if
/// anything.
pub(crate) fn triangle_fault(
    num_nodes: usize,
    element: usize,
    t: &[usize; 3],
) -> Option<PartitionError> {
    if let Some(&node) = t.iter().find(|&&n| n >= num_nodes) {
        return Some(PartitionError::NodeOutOfRange {
            element,
            node,
            num_nodes,
        });
    }
    (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
        .then_some(PartitionError::DegenerateTriangle { element })
}

/// One part (one MPI rank's share) of a partitioned mesh. All ids are global.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Part {
    /// The triangles of this part, in increasing order.
    pub elements: Vec<usize>,
    /// Every node of those triangles, in increasing order (the local numbering is the
    /// position in this list).
    pub nodes: Vec<usize>,
    /// `owned[i]` tells whether this part owns `nodes[i]`.
    pub owned: Vec<bool>,
    /// The nodes of this part also touched by another part, in increasing order.
    pub interface: Vec<usize>,
    /// For each neighbouring part, in increasing part order: its id and the nodes the
    /// two parts share, in increasing order. The list for `(p, q)` in part `p` equals
    /// the list for `(q, p)` in part `q`, so both sides can exchange values in it
    /// without further negotiation. Parts touching at a single vertex are neighbours.
    pub neighbours: Vec<(u32, Vec<usize>)>,
    /// The contact nodes this part owns, in increasing order.
    pub contact_nodes: Vec<usize>,
}

impl Part {
    /// Number of nodes this part owns.
    pub fn num_owned(&self) -> usize {
        self.owned.iter().filter(|&&o| o).count()
    }
}

/// Figures of merit of a partition.
#[derive(Debug, Clone, PartialEq)]
pub struct Quality {
    /// Number of parts.
    pub nparts: usize,
    /// Number of triangles.
    pub num_elements: usize,
    /// Dual-graph edges between different parts (mesh edges on part boundaries).
    pub edge_cut: usize,
    /// Smallest part, in triangles.
    pub min_part_elements: usize,
    /// Largest part, in triangles.
    pub max_part_elements: usize,
    /// Largest part size over mean part size (1.0 is perfect balance).
    pub imbalance: f64,
    /// Distinct nodes touched by more than one part.
    pub interface_nodes: usize,
    /// Largest interface of a single part, in nodes.
    pub max_part_interface_nodes: usize,
    /// Number of neighbouring parts of each part.
    pub neighbours: Vec<usize>,
    /// Parts whose triangles form more than one edge-connected piece. Such a part has
    /// several subdomains, some of which may float (carry no Dirichlet condition).
    pub disconnected_parts: usize,
}

impl Quality {
    /// The figures of the one part of a mesh of `num_elements` triangles in `pieces`
    /// pieces: no cut, no interface, no neighbours.
    pub fn one_part(num_elements: usize, pieces: usize) -> Quality {
        Quality {
            nparts: 1,
            num_elements,
            edge_cut: 0,
            min_part_elements: num_elements,
            max_part_elements: num_elements,
            imbalance: 1.0,
            interface_nodes: 0,
            max_part_interface_nodes: 0,
            neighbours: vec![0],
            disconnected_parts: usize::from(pieces > 1),
        }
    }
}

impl fmt::Display for Quality {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let nmin = self.neighbours.iter().copied().min().unwrap_or(0);
        let nmax = self.neighbours.iter().copied().max().unwrap_or(0);
        let nmean = self.neighbours.iter().sum::<usize>() as f64 / self.nparts.max(1) as f64;
        write!(
            f,
            "{} triangles in {} parts of {}..{} triangles (imbalance {:.3}); \
             edge cut {}; {} interface nodes (at most {} in one part); \
             {}..{} neighbours per part (mean {:.2}); ",
            self.num_elements,
            self.nparts,
            self.min_part_elements,
            self.max_part_elements,
            self.imbalance,
            self.edge_cut,
            self.interface_nodes,
            self.max_part_interface_nodes,
            nmin,
            nmax,
            nmean,
        )?;
        match self.disconnected_parts {
            0 => write!(f, "every part is connected."),
            n => write!(f, "{n} parts are not connected."),
        }
    }
}

/// A mesh split into parts, with element and node ownership.
#[derive(Debug, Clone, PartialEq)]
pub struct Partition {
    /// Number of parts.
    pub nparts: usize,
    /// The part of each triangle.
    pub element_part: Vec<u32>,
    /// The owner of each node: the lowest part id among the parts of the triangles
    /// touching it ([`NO_PART`] for a node no triangle uses).
    pub node_owner: Vec<u32>,
    /// The parts, indexed by part id.
    pub parts: Vec<Part>,
    /// Figures of merit.
    pub quality: Quality,
}

/// Splits a triangle mesh into `nparts` parts with METIS and works out ownership and
/// interfaces (see the crate documentation).
///
/// `contact_nodes` are the global ids of the nodes on the contact boundary (repeats
/// are ignored); each ends up in the `contact_nodes` of exactly one part, its owner.
/// Deterministic: the same input gives the same partition. `nparts == 1` does not
/// call METIS. Should METIS leave a part empty (possible on tiny meshes), the part
/// takes the highest-numbered triangle of the currently largest part, so every part
/// has at least one triangle.
///
/// # Method
/// A dual graph of at most 200 000 triangles goes to `METIS_PartGraphKway` as is, with
/// METIS' defaults (edge-cut objective, sorted heavy-edge matching, load imbalance
/// tolerance 1.03 (`ufactor` 30), one cut, 10 refinement iterations), set explicitly,
/// plus two choices: `seed` = [`METIS_SEED`], and `contig` = 1 (contiguous parts) when
/// the dual graph is connected. METIS refuses `contig` on a disconnected graph (e.g. two
/// separate bodies in contact), so it is off there. METIS draws random numbers; each
/// thread calling it has a generator of its own (see `metis_rng`), so parts do not
/// depend on what other threads do meanwhile.
///
/// A larger graph is first coarsened here, down to at most 200 000 vertices (and at
/// least 1000 per part): each level pairs every vertex with a neighbour, in vertex
/// order, and merges the pairs into weighted vertices. METIS partitions the coarsest
/// graph twice with the options above, from seeds [`METIS_SEED`] and the next one, at
/// once on the pool's threads, and keeps the lower cut (the first on a tie); the parts
/// are projected back level by level, each time refined by greedy boundary moves that
/// keep parts contiguous and within the 1.03 tolerance. METIS on the whole graph
/// spends most of its time in cache misses of its first levels; this is several times
/// faster at the same edge cut, give or take a few percent either way.
///
/// # Errors
/// `nparts == 0` or larger than the number of triangles, an invalid triangle, a
/// contact node outside the mesh or on no triangle, a graph too large for 32-bit
/// METIS, or a METIS failure.
pub fn partition_mesh(
    num_nodes: usize,
    triangles: &[[usize; 3]],
    contact_nodes: &[usize],
    nparts: usize,
) -> Result<Partition, PartitionError> {
    partition_mesh_with_ties(num_nodes, triangles, contact_nodes, &[], nparts)
}

/// [`partition_mesh`] with `ties`: pairs of nodes that something other than the mesh
/// couples (a slave node of a contact between two bodies and each master node of its
/// row). Each tie is an edge of the dual graph between a triangle around either node,
/// so that the parts keep tied nodes together where that costs no more than cutting
/// the mesh: two bodies in contact are then not split along their contact, whose
/// master nodes would all become interface nodes.
///
/// # Errors
/// As [`partition_mesh`].
pub fn partition_mesh_with_ties(
    num_nodes: usize,
    triangles: &[[usize; 3]],
    contact_nodes: &[usize],
    ties: &[[usize; 2]],
    nparts: usize,
) -> Result<Partition, PartitionError> {
    check_nparts(nparts, triangles.len())?;
    let graph = MeshGraph::new(num_nodes, triangles, ties, nparts > 1)?;
    let element_part = graph.cut(nparts)?;
    graph.finish(triangles, contact_nodes, nparts, element_part)
}

/// A mesh's dual graph, ties included (see [`partition_mesh_with_ties`]), to be cut
/// (METIS, [`MeshGraph::cut`], or straight cuts, [`MeshGraph::cut_straight`]), and what
/// the ownership rules need afterwards ([`MeshGraph::finish`]).
/// [`partition_mesh_with_ties`] is [`MeshGraph::new`], `cut`, then `finish`.
pub struct MeshGraph {
    triangles: usize,
    mesh: Connectivity,
    /// The graph to cut (the dual graph with the ties); `None` for one part.
    graph: Option<Graph>,
}

impl MeshGraph {
    /// The connectivity of `triangles`, and their dual graph with `ties` unless
    /// `with_graph` is false (one part needs none).
    ///
    /// # Errors
    /// As [`partition_mesh`].
    pub fn new(
        num_nodes: usize,
        triangles: &[[usize; 3]],
        ties: &[[usize; 2]],
        with_graph: bool,
    ) -> Result<Self, PartitionError> {
        // The stars check the triangles (`Stars::new`).
        if !with_graph {
            let mesh = Connectivity::without_graph(num_nodes, triangles)?;
            return Ok(MeshGraph {
                triangles: triangles.len(),
                mesh,
                graph: None,
            });
        }
        let mut mesh = Connectivity::new(num_nodes, triangles)?;
        let dual = mesh
            .graph
            .take()
            .expect("Connectivity::new builds the graph");
        // The ownership rules' figures read the untied dual graph; with no ties it is
        // the graph to cut, kept once (see `finish`).
        let graph = match ties.is_empty() {
            true => dual,
            false => {
                let tied = graph::with_ties(dual.clone(), &mesh.stars, ties)?;
                mesh.graph = Some(dual);
                tied
            }
        };
        let graph = Some(graph);
        Ok(MeshGraph {
            triangles: triangles.len(),
            mesh,
            graph,
        })
    }

    /// This crate's cut of the graph into `nparts` parts, on this process (see
    /// [`partition_mesh`]): each triangle's part.
    ///
    /// # Errors
    /// As [`partition_mesh`].
    pub fn cut(&self, nparts: usize) -> Result<Vec<u32>, PartitionError> {
        match &self.graph {
            Some(g) => partition_graph(g, nparts, METIS_MAX_VERTICES),
            None => Ok(vec![0; self.triangles]),
        }
    }

    /// Recursive straight cuts of the graph into `nparts` parts of equal size, refined
    /// as METIS's cut is (see the `straight` module), from each triangle's centroid
    /// `centroids[e]`; `None` where they do not apply: one part, no graph, a part left in
    /// several pieces (the caller cuts with [`MeshGraph::cut`] then).
    ///
    /// # Panics
    /// If `centroids` does not hold one position per triangle.
    pub fn cut_straight(&self, centroids: &[[f64; 2]], nparts: usize) -> Option<StraightParts> {
        let g = self.graph.as_ref()?;
        let max_weight = max_part_weight(g.num_vertices(), nparts);
        let (part, edge_cut) =
            straight::straight_cuts(g, centroids, nparts, max_weight, REFINE_PASSES)?;
        Some(StraightParts {
            nparts,
            element_part: part.into_iter().map(|p| p as u32).collect(),
            edge_cut,
        })
    }

    /// [`MeshGraph::finish`] for the parts of [`MeshGraph::cut_straight`], whose pieces
    /// and cut were counted as they were made: the quality report does not count them
    /// again.
    ///
    /// # Errors
    /// As [`MeshGraph::finish`].
    ///
    /// # Panics
    /// If the parts are not of `triangles`.
    pub fn finish_straight(
        self,
        triangles: &[[usize; 3]],
        contact_nodes: &[usize],
        parts: StraightParts,
    ) -> Result<Partition, PartitionError> {
        let StraightParts {
            nparts,
            element_part,
            edge_cut,
        } = parts;
        // No part is empty: none is filled from another, which would undo the counts.
        let counted = Counted::Connected(edge_cut);
        self.finish_with(triangles, contact_nodes, nparts, element_part, counted)
    }

    /// The [`Partition`] of the triangles' parts `element_part`, cut by any
    /// partitioner: an empty part first takes a triangle of the largest (as in
    /// [`partition_mesh`]), then the ownership rules apply.
    ///
    /// # Errors
    /// As [`partition_mesh`], and [`PartitionError::PartOutOfRange`] for a part id
    /// `>= nparts`.
    ///
    /// # Panics
    /// If `element_part.len() != triangles.len()`.
    pub fn finish(
        self,
        triangles: &[[usize; 3]],
        contact_nodes: &[usize],
        nparts: usize,
        element_part: Vec<u32>,
    ) -> Result<Partition, PartitionError> {
        self.finish_with(triangles, contact_nodes, nparts, element_part, Counted::No)
    }

    fn finish_with(
        mut self,
        triangles: &[[usize; 3]],
        contact_nodes: &[usize],
        nparts: usize,
        mut element_part: Vec<u32>,
        counted: Counted,
    ) -> Result<Partition, PartitionError> {
        assert_eq!(element_part.len(), triangles.len());
        check_nparts(nparts, triangles.len())?;
        check_part_ids(&element_part, nparts)?;
        fill_empty_parts(&mut element_part, nparts);
        if self.mesh.graph.is_none() {
            self.mesh.graph = self.graph.take();
        }
        build_partition(
            triangles,
            contact_nodes,
            nparts,
            element_part,
            &self.mesh,
            counted,
        )
    }
}

/// The parts of [`MeshGraph::cut_straight`]: each in one piece, none empty.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StraightParts {
    nparts: usize,
    element_part: Vec<u32>,
    edge_cut: usize,
}

impl StraightParts {
    /// How many parts.
    pub fn nparts(&self) -> usize {
        self.nparts
    }

    /// Each triangle's part.
    pub fn element_part(&self) -> &[u32] {
        &self.element_part
    }

    /// The dual-graph edges between parts.
    pub fn edge_cut(&self) -> usize {
        self.edge_cut
    }
}

/// Builds a [`Partition`] from a given element-to-part map (e.g. one computed
/// elsewhere or made by hand), applying the same ownership rules as
/// [`partition_mesh`]. Empty parts are allowed here.
///
/// # Errors
/// As [`partition_mesh`] (except that `nparts` may exceed the number of triangles),
/// and [`PartitionError::PartOutOfRange`] for a part id `>= nparts`.
///
/// # Panics
/// If `element_part.len() != triangles.len()`.
pub fn partition_from_element_parts(
    num_nodes: usize,
    triangles: &[[usize; 3]],
    contact_nodes: &[usize],
    nparts: usize,
    element_part: Vec<u32>,
) -> Result<Partition, PartitionError> {
    if nparts == 0 {
        return Err(PartitionError::NoParts);
    }
    assert_eq!(
        element_part.len(),
        triangles.len(),
        "one part id per triangle"
    );
    check_part_ids(&element_part, nparts)?;
    let mesh = Connectivity::new(num_nodes, triangles)?;
    build_partition(
        triangles,
        contact_nodes,
        nparts,
        element_part,
        &mesh,
        Counted::No,
    )
}

/// Every part id below `nparts`, else the first triangle whose is not.
fn check_part_ids(element_part: &[u32], nparts: usize) -> Result<(), PartitionError> {
    match element_part
        .par_iter()
        .position_first(|&p| p as usize >= nparts)
    {
        Some(element) => Err(PartitionError::PartOutOfRange {
            element,
            part: element_part[element],
            nparts,
        }),
        None => Ok(()),
    }
}

fn check_nparts(nparts: usize, elements: usize) -> Result<(), PartitionError> {
    if nparts == 0 {
        return Err(PartitionError::NoParts);
    }
    if nparts > elements {
        return Err(PartitionError::TooManyParts { nparts, elements });
    }
    Ok(())
}

/// Largest graph handed to METIS whole (see [`partition_mesh`]). Beyond a few hundred
/// thousand vertices METIS' time grows faster than the graph (cache misses), while its
/// edge cut on the coarsened graph, once projected and refined, is as good.
const METIS_MAX_VERTICES: usize = 200_000;

/// Coarsening stops before the graph has fewer vertices than this per part, so that
/// the parts are made of many coarse vertices and METIS can balance them finely.
const MIN_COARSE_VERTICES_PER_PART: usize = 1000;

/// METIS' load imbalance tolerance, in thousandths above 1.
const UFACTOR: Idx = 30;

/// The heaviest part the refinement allows of `n` unit-weight vertices in `nparts`
/// parts: METIS's imbalance tolerance ([`UFACTOR`]) over an even share.
fn max_part_weight(n: usize, nparts: usize) -> i64 {
    (n as i64 * (1000 + i64::from(UFACTOR))) / (1000 * nparts.max(1) as i64)
}

/// Refinement sweeps per projected level (METIS' own default `niter`).
const REFINE_PASSES: usize = 10;

/// The METIS options array described in [`partition_mesh`], one cut from `seed`.
fn metis_options(graph_is_connected: bool, seed: Idx) -> [Idx; metis::NOPTIONS] {
    use metis::option::{CType, Contig, NCuts, NIter, ObjType, Opt, PType, Seed, UFactor};
    let mut options = [-1; metis::NOPTIONS];
    options[PType::INDEX] = PType::Kway.value();
    options[ObjType::INDEX] = ObjType::Cut.value();
    options[CType::INDEX] = CType::Shem.value();
    options[UFactor::INDEX] = UFactor(UFACTOR).value();
    options[NCuts::INDEX] = NCuts(1).value();
    options[NIter::INDEX] = NIter(10).value();
    options[Seed::INDEX] = Seed(seed).value();
    options[Contig::INDEX] = Contig(graph_is_connected).value();
    options
}

/// Runs a METIS call so that its result does not depend on other threads: on a
/// generator of this thread's own ([`metis_rng`]), or, where that could not be arranged,
/// one call at a time in the process (libc's generator is process-wide).
fn metis_call<T>(call: impl FnOnce() -> T) -> T {
    static METIS_LOCK: Mutex<()> = Mutex::new(());
    if metis_rng::is_private() {
        let _own = metis_rng::Private::enter();
        call()
    } else {
        let _one_at_a_time = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        call()
    }
}

/// The part of every vertex of `graph` (see [`partition_mesh`]: METIS alone up to
/// `max_metis_vertices`, coarsening first beyond).
fn partition_graph(
    graph: &Graph,
    nparts: usize,
    max_metis_vertices: usize,
) -> Result<Vec<u32>, PartitionError> {
    let n = graph.num_vertices();
    if nparts == 1 {
        return Ok(vec![0; n]);
    }
    let min_vertices = MIN_COARSE_VERTICES_PER_PART.saturating_mul(nparts);
    let mut levels: Vec<(Graph, Vec<Idx>, Vec<[Idx; 2]>)> = Vec::new();
    loop {
        let finer = levels.last().map_or(graph, |l| &l.0);
        let nf = finer.num_vertices();
        // A level about halves the graph.
        if nf <= max_metis_vertices || nf / 2 < min_vertices {
            break;
        }
        let (coarse, cmap, members) = coarsen::coarsen(finer);
        // Few edges left to contract (e.g. many separate triangles): stop, as METIS does.
        if coarse.num_vertices() * 20 > nf * 17 {
            break;
        }
        levels.push((coarse, cmap, members));
    }

    let coarsest = levels.last().map_or(graph, |l| &l.0);
    // Coarse vertices are connected sets of triangles, so the coarse graph is connected
    // exactly when the dual graph is, and contiguous coarse parts project to contiguous
    // parts.
    let connected = pieces_and_cut(coarsest, 1, |_| 0).0[0] == 1;
    let cut = |seed: Idx| metis_kway(coarsest, nparts, &metis_options(connected, seed));
    let mut part = if levels.is_empty() {
        cut(METIS_SEED)?
    } else {
        // Two cuts cost little on the small coarse graph and make up for the quality
        // that coarsening outside METIS loses. From two seeds, at once on the pool's
        // threads (METIS's own two cuts run one after the other), the lower cut kept,
        // the first on a tie: the same parts on any number of threads.
        let (first, second) = rayon::join(|| cut(METIS_SEED), || cut(METIS_SEED + 1));
        let (first, second) = (first?, second?);
        let weight = |p: &[Idx]| pieces_and_cut(coarsest, nparts, |v| p[v] as u32).1;
        if weight(&second) < weight(&first) {
            second
        } else {
            first
        }
    };

    let max_weight = max_part_weight(n, nparts);
    // Projection keeps the part weights.
    let mut weight = vec![0i64; nparts];
    for (v, &p) in part.iter().enumerate() {
        weight[p as usize] += i64::from(coarsest.vertex_weight(v));
    }
    // A fine vertex is on the boundary only if its coarse vertex was, so each level
    // looks at the members of the coarse boundary, not at the whole graph.
    let mut boundary: Vec<Idx> = (0..coarsest.num_vertices())
        .filter(|&v| {
            let p = part[v];
            coarsest
                .neighbours(v)
                .iter()
                .any(|&u| part[u as usize] != p)
        })
        .map(|v| v as Idx)
        .collect();
    while let Some((_, cmap, members)) = levels.pop() {
        let finer = levels.last().map_or(graph, |l| &l.0);
        part = cmap.iter().map(|&c| part[c as usize]).collect();
        let candidates = boundary
            .iter()
            .flat_map(|&c| members[c as usize])
            .filter(|&v| v >= 0);
        boundary = coarsen::refine(
            finer,
            &mut part,
            &mut weight,
            max_weight,
            REFINE_PASSES,
            candidates,
        );
    }
    Ok(part.into_iter().map(|p| p as u32).collect())
}

fn metis_kway(
    graph: &Graph,
    nparts: usize,
    options: &[Idx; metis::NOPTIONS],
) -> Result<Vec<Idx>, PartitionError> {
    let metis_error = |e: &dyn fmt::Display| PartitionError::Metis(e.to_string());
    let mut part = vec![0 as Idx; graph.num_vertices()];
    metis_call(|| {
        let mut g = metis::Graph::new(1, to_idx(nparts)?, &graph.xadj, &graph.adjncy)
            .map_err(|e| metis_error(&e))?;
        if let Some(w) = &graph.vwgt {
            g = g.set_vwgt(w);
        }
        if let Some(w) = &graph.adjwgt {
            g = g.set_adjwgt(w);
        }
        g.set_options(options)
            .part_kway(&mut part)
            .map_err(|e| metis_error(&e))
    })?;
    Ok(part)
}

/// Gives every empty part one triangle: the highest-numbered triangle of the largest
/// part (lowest id on ties). Needs `nparts <= element_part.len()`.
fn fill_empty_parts(element_part: &mut [u32], nparts: usize) {
    let mut sizes = part_sizes(element_part, nparts);
    for empty in 0..nparts {
        if sizes[empty] > 0 {
            continue;
        }
        let largest = (0..nparts).max_by_key(|&q| (sizes[q], std::cmp::Reverse(q)));
        let largest = largest.expect("nparts > 0") as u32;
        let e = element_part
            .iter()
            .rposition(|&p| p == largest)
            .expect("the largest part is not empty");
        element_part[e] = empty as u32;
        sizes[largest as usize] -= 1;
        sizes[empty] += 1;
    }
}

/// Each part's number of triangles, counted by pieces on the pool (these passes over
/// every triangle ran on one thread while the pool's others waited).
fn part_sizes(element_part: &[u32], nparts: usize) -> Vec<usize> {
    const PIECE: usize = 1 << 16;
    let count = |piece: &[u32]| {
        let mut sizes = vec![0usize; nparts];
        for &p in piece {
            sizes[p as usize] += 1;
        }
        sizes
    };
    if element_part.len() <= PIECE {
        return count(element_part);
    }
    (element_part.par_chunks(PIECE).map(count)).reduce(
        || vec![0; nparts],
        |mut a, b| {
            a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
            a
        },
    )
}

/// A range of nodes' share of each part's lists in [`build_partition`].
#[derive(Default)]
struct NodeLists {
    nodes: Vec<usize>,
    owned: Vec<bool>,
    interface: Vec<usize>,
    shared: BTreeMap<u32, Vec<usize>>,
}

/// The nodes in each range of [`build_partition`]'s pass over the nodes: a few ranges
/// a thread, each at least 2^15 nodes, and not so many that their lists (one per part
/// and range) hold more than about 2^20 entries of their own.
fn node_range(num_nodes: usize, nparts: usize) -> usize {
    let ranges = (4 * rayon::current_num_threads())
        .min(num_nodes >> 15)
        .min((1 << 20) / nparts.max(1))
        .max(1);
    num_nodes.div_ceil(ranges).max(1)
}

/// The mesh's connectivity that both the partition and the ownership rules read: the
/// triangles around each node and the dual graph built from them.
struct Connectivity {
    stars: Stars,
    /// `None` for one part (see [`quality`]).
    graph: Option<Graph>,
}

impl Connectivity {
    fn new(num_nodes: usize, triangles: &[[usize; 3]]) -> Result<Self, PartitionError> {
        let stars = Stars::new(num_nodes, triangles)?;
        let graph = Some(dual_from_stars(triangles, &stars)?);
        Ok(Connectivity { stars, graph })
    }

    fn without_graph(num_nodes: usize, triangles: &[[usize; 3]]) -> Result<Self, PartitionError> {
        let stars = Stars::new(num_nodes, triangles)?;
        Ok(Connectivity { stars, graph: None })
    }
}

fn build_partition(
    triangles: &[[usize; 3]],
    contact_nodes: &[usize],
    nparts: usize,
    element_part: Vec<u32>,
    mesh: &Connectivity,
    counted: Counted,
) -> Result<Partition, PartitionError> {
    let stars = &mesh.stars;
    let num_nodes = stars.num_nodes();
    debug_assert_eq!(triangles.len(), element_part.len());
    let mut contact: Vec<usize> = contact_nodes.to_vec();
    contact.sort_unstable();
    contact.dedup();
    if let Some(&node) = contact.iter().find(|&&n| n >= num_nodes) {
        return Err(PartitionError::ContactNodeOutOfRange { node, num_nodes });
    }

    let sizes = part_sizes(&element_part, nparts);
    let mut parts: Vec<Part> = sizes
        .iter()
        .map(|&size| Part {
            elements: Vec::with_capacity(size),
            ..Part::default()
        })
        .collect();
    for (e, &p) in element_part.iter().enumerate() {
        parts[p as usize].elements.push(e);
    }

    // By ranges of nodes on the pool, each range's lists joined in range order: nodes
    // are visited in increasing order, so every per-part list comes out sorted.
    let mut node_owner = vec![NO_PART; num_nodes];
    let range = node_range(num_nodes, nparts);
    let ranges: Vec<(Vec<NodeLists>, usize)> = node_owner
        .par_chunks_mut(range)
        .enumerate()
        .map(|(r, owners)| {
            let mut lists: Vec<NodeLists> = (0..nparts).map(|_| NodeLists::default()).collect();
            let mut interface_nodes = 0;
            let mut touching = Vec::new();
            for (i, owner_of_n) in owners.iter_mut().enumerate() {
                let n = r * range + i;
                let star = stars.of(n);
                let Some(&first) = star.first() else {
                    continue;
                };
                // Most nodes lie inside one part: no list to sort.
                let p0 = element_part[first as usize];
                if star.iter().all(|&t| element_part[t as usize] == p0) {
                    *owner_of_n = p0;
                    let part = &mut lists[p0 as usize];
                    part.nodes.push(n);
                    part.owned.push(true);
                    continue;
                }
                touching.clear();
                touching.extend(star.iter().map(|&t| element_part[t as usize]));
                touching.sort_unstable();
                touching.dedup();
                // Ownership rule: the lowest part id touching the node. Simple,
                // deterministic, and computable by every rank from the shared lists alone.
                let owner = touching[0];
                *owner_of_n = owner;
                for &p in &touching {
                    let part = &mut lists[p as usize];
                    part.nodes.push(n);
                    part.owned.push(p == owner);
                    part.interface.push(n);
                    for &q in touching.iter().filter(|&&q| q != p) {
                        part.shared.entry(q).or_default().push(n);
                    }
                }
                interface_nodes += 1;
            }
            (lists, interface_nodes)
        })
        .collect();
    let interface_nodes = ranges.iter().map(|r| r.1).sum();
    parts.par_iter_mut().enumerate().for_each(|(p, part)| {
        let mut shared: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
        for (lists, _) in &ranges {
            let l = &lists[p];
            part.nodes.extend_from_slice(&l.nodes);
            part.owned.extend_from_slice(&l.owned);
            part.interface.extend_from_slice(&l.interface);
            for (&q, nodes) in &l.shared {
                shared.entry(q).or_default().extend_from_slice(nodes);
            }
        }
        part.neighbours = shared.into_iter().collect();
    });
    drop(ranges);
    for &n in &contact {
        match node_owner[n] {
            NO_PART => return Err(PartitionError::ContactNodeUnused { node: n }),
            p => parts[p as usize].contact_nodes.push(n),
        }
    }

    let quality = quality(
        nparts,
        &element_part,
        &parts,
        interface_nodes,
        match counted {
            Counted::Connected(cut) => Pieces::Connected(cut),
            Counted::No => match &mesh.graph {
                Some(g) => Pieces::Graph(g),
                None => Pieces::Nodes(triangles),
            },
        },
    );
    Ok(Partition {
        nparts,
        element_part,
        node_owner,
        parts,
        quality,
    })
}

/// What the partitioner counted of its parts.
enum Counted {
    /// Nothing.
    No,
    /// The edges cut, and every part in one piece.
    Connected(usize),
}

/// Where the quality's pieces and cut come from.
enum Pieces<'a> {
    /// Every part in one piece, and the edges cut, as counted where they were cut.
    Connected(usize),
    /// The dual graph: each part's edge-connected pieces, the edges cut.
    Graph(&'a Graph),
    /// One part and no graph: the mesh's pieces joined through shared nodes
    /// ([`node_pieces`]), and no cut.
    Nodes(&'a [[usize; 3]]),
}

fn quality(
    nparts: usize,
    element_part: &[u32],
    parts: &[Part],
    interface_nodes: usize,
    from: Pieces,
) -> Quality {
    let (pieces, edge_cut) = match from {
        Pieces::Connected(cut) => (vec![1; nparts], cut),
        Pieces::Graph(graph) => pieces_and_cut(graph, nparts, |e| element_part[e]),
        Pieces::Nodes(triangles) => {
            debug_assert_eq!(nparts, 1);
            return Quality::one_part(element_part.len(), node_pieces(triangles));
        }
    };
    let sizes = parts.iter().map(|p| p.elements.len());
    let max_part_elements = sizes.clone().max().unwrap_or(0);
    let mean = element_part.len() as f64 / nparts as f64;
    Quality {
        nparts,
        num_elements: element_part.len(),
        edge_cut,
        min_part_elements: sizes.min().unwrap_or(0),
        max_part_elements,
        imbalance: if mean > 0.0 {
            max_part_elements as f64 / mean
        } else {
            1.0
        },
        interface_nodes,
        max_part_interface_nodes: parts.iter().map(|p| p.interface.len()).max().unwrap_or(0),
        neighbours: parts.iter().map(|p| p.neighbours.len()).collect(),
        disconnected_parts: pieces.iter().filter(|&&c| c > 1).count(),
    }
}

/// The number of pieces of a mesh whose triangles are joined through shared nodes
/// (union-find over the nodes). It counts two bodies touching at a single vertex as one
/// piece, which the dual graph counts as two: the price of not building the graph for a
/// one-part run, where the figure is only reported.
pub fn node_pieces(triangles: &[[usize; 3]]) -> usize {
    fn root(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    let n = triangles.iter().flatten().max().map_or(0, |&m| m + 1);
    let mut parent: Vec<usize> = (0..n).collect();
    let mut used = vec![false; n];
    for t in triangles {
        for k in 0..3 {
            used[t[k]] = true;
            let (a, b) = (root(&mut parent, t[k]), root(&mut parent, t[(k + 1) % 3]));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    (0..n).filter(|&v| used[v] && parent[v] == v).count()
}

/// Fill-reducing nested-dissection ordering of a symmetric graph (METIS_NodeND).
///
/// `xadj`/`adjncy` is the graph in CSR form without self loops (e.g. the pattern of a
/// sparse matrix minus its diagonal). Returns `perm` with `perm[new] = old`. For the
/// matrices of 2D meshes this orders for roughly half the fill of minimum degree.
pub fn nested_dissection(xadj: &[usize], adjncy: &[usize]) -> Result<Vec<usize>, PartitionError> {
    let n = xadj.len().saturating_sub(1);
    if n == 0 {
        return Ok(Vec::new());
    }
    let too_large = || PartitionError::TooLarge;
    let mut nv: metis_sys::idx_t = n.try_into().map_err(|_| too_large())?;
    let mut xa: Vec<metis_sys::idx_t> = xadj
        .iter()
        .map(|&v| v.try_into().map_err(|_| too_large()))
        .collect::<Result<_, _>>()?;
    let mut adj: Vec<metis_sys::idx_t> = adjncy
        .iter()
        .map(|&v| v.try_into().map_err(|_| too_large()))
        .collect::<Result<_, _>>()?;
    let mut perm = vec![0 as metis_sys::idx_t; n];
    let mut iperm = vec![0 as metis_sys::idx_t; n];
    let mut options = [0 as metis_sys::idx_t; metis_sys::METIS_NOPTIONS as usize];
    let status = metis_call(|| {
        // SAFETY: the arrays have the sizes METIS_NodeND expects (n + 1, xadj[n], n, n,
        // NOPTIONS) and outlive the call; a null vwgt means unit weights.
        unsafe {
            metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr());
            options[metis_sys::moptions_et_METIS_OPTION_SEED as usize] =
                METIS_SEED as metis_sys::idx_t;
            metis_sys::METIS_NodeND(
                &mut nv,
                xa.as_mut_ptr(),
                adj.as_mut_ptr(),
                std::ptr::null_mut(),
                options.as_mut_ptr(),
                perm.as_mut_ptr(),
                iperm.as_mut_ptr(),
            )
        }
    });
    if status != metis_sys::rstatus_et_METIS_OK {
        return Err(PartitionError::Metis(format!(
            "METIS_NodeND returned status {status}"
        )));
    }
    Ok(perm.into_iter().map(|p| p as usize).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_triangles_share_one_edge() {
        let g = dual_graph(4, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        assert_eq!(g.xadj, vec![0, 1, 2]);
        assert_eq!(g.adjncy, vec![1, 0]);
        assert_eq!(g.num_edges(), 1);
    }

    #[test]
    fn stars_list_each_nodes_triangles_in_order_on_any_number_of_threads() {
        // 200 000 nodes, some in no triangle, some triangles repeated.
        let n = 200_000;
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) % (n as u64 - 1)) as usize
        };
        let tris: Vec<[usize; 3]> = std::iter::repeat_with(|| [next(), next(), next()])
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .take(150_000)
            .collect();
        let mut expect: Vec<Vec<Idx>> = vec![Vec::new(); n];
        for (e, t) in tris.iter().enumerate() {
            for &v in t {
                expect[v].push(e as Idx);
            }
        }
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let stars = pool.unwrap().install(|| Stars::new(n, &tris).unwrap());
            assert_eq!(stars.num_nodes(), n);
            for (v, e) in expect.iter().enumerate() {
                assert_eq!(stars.of(v), &e[..], "node {v}, {threads} threads");
            }
        }
    }

    #[test]
    fn stars_report_the_first_bad_triangle_on_any_number_of_threads() {
        let n = 1000;
        let good = |e: usize| [e % n, (e + 1) % n, (e + 2) % n];
        let mut tris: Vec<[usize; 3]> = (0..300_000).map(good).collect();
        tris[250_000] = [3, 3, 4];
        tris[200_001] = [5, n, 6];
        for threads in [1, 3, 4] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let got = pool.unwrap().install(|| Stars::new(n, &tris).err());
            assert_eq!(
                got,
                Some(PartitionError::NodeOutOfRange {
                    element: 200_001,
                    node: n,
                    num_nodes: n
                }),
                "{threads} threads"
            );
        }
        tris[200_001] = good(200_001);
        let got = Stars::new(n, &tris).err();
        assert_eq!(
            got,
            Some(PartitionError::DegenerateTriangle { element: 250_000 })
        );
    }

    #[test]
    fn fan_around_a_node_is_a_cycle() {
        // Six triangles around node 0: each shares an edge with the two next to it.
        let tris: Vec<[usize; 3]> = (0..6).map(|i| [0, 1 + i, 1 + (i + 1) % 6]).collect();
        let g = dual_graph(7, &tris).unwrap();
        for e in 0..6 {
            let mut expect = [(e + 5) % 6, (e + 1) % 6];
            expect.sort();
            assert_eq!(g.neighbours(e), &expect[..]);
        }
        assert_eq!(g.num_edges(), 6);
    }

    #[test]
    fn vertex_contact_is_not_a_dual_edge() {
        let tris = [[0, 1, 2], [2, 3, 4]];
        let g = dual_graph(5, &tris).unwrap();
        assert_eq!(g.num_edges(), 0);
        let g = dual_from_stars(&tris, &Stars::new(5, &tris).unwrap()).unwrap();
        assert_eq!(pieces_and_cut(&g, 1, |_| 0), (vec![2], 0));
    }

    #[test]
    fn duplicate_and_non_manifold_triangles_give_simple_graph() {
        // Triangles 0 and 1 are the same; 2 also hangs on edge (0, 1).
        let g = dual_graph(4, &[[0, 1, 2], [2, 1, 0], [0, 1, 3]]).unwrap();
        assert_eq!(g.neighbours(0), &[1, 2]);
        assert_eq!(g.neighbours(1), &[0, 2]);
        assert_eq!(g.neighbours(2), &[0, 1]);
    }

    #[test]
    fn invalid_triangles_are_rejected() {
        assert_eq!(
            dual_graph(3, &[[0, 1, 3]]),
            Err(PartitionError::NodeOutOfRange {
                element: 0,
                node: 3,
                num_nodes: 3
            })
        );
        assert_eq!(
            dual_graph(3, &[[0, 1, 2], [0, 2, 2]]),
            Err(PartitionError::DegenerateTriangle { element: 1 })
        );
    }

    #[test]
    fn empty_parts_are_filled_from_the_largest() {
        let mut part = vec![0, 0, 0, 2, 2];
        fill_empty_parts(&mut part, 4);
        assert_eq!(part, vec![0, 3, 1, 2, 2]);
    }

    #[test]
    fn metis_options_fix_the_seed() {
        use metis::option::{Contig, Opt, Seed};
        let o = metis_options(false, METIS_SEED);
        assert_eq!(o[Seed::INDEX], METIS_SEED);
        assert_eq!(o[Contig::INDEX], 0);
        assert_eq!(metis_options(true, METIS_SEED)[Contig::INDEX], 1);
    }

    #[test]
    fn nested_dissection_is_a_permutation() {
        // A 30 x 30 grid graph (5-point stencil).
        let n = 30;
        let mut xadj = vec![0];
        let mut adjncy = Vec::new();
        for i in 0..n {
            for j in 0..n {
                for (di, dj) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (a, b) = (i as i64 + di, j as i64 + dj);
                    if a >= 0 && b >= 0 && a < n as i64 && b < n as i64 {
                        adjncy.push(a as usize * n + b as usize);
                    }
                }
                xadj.push(adjncy.len());
            }
        }
        let perm = nested_dissection(&xadj, &adjncy).unwrap();
        let mut seen = perm.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..n * n).collect::<Vec<_>>());
        assert_eq!(
            perm,
            nested_dissection(&xadj, &adjncy).unwrap(),
            "deterministic"
        );
    }

    /// The dual graph of an `nx` x `ny` grid of cells cut into two triangles each, with
    /// pseudo-random diagonals so that no matching follows the grid exactly.
    fn grid_graph(nx: usize, ny: usize) -> Graph {
        let id = |i: usize, j: usize| j * (nx + 1) + i;
        let mut state = 7u32;
        let mut tris = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                if state >> 16 & 1 == 1 {
                    tris.extend([[a, b, c], [a, c, d]]);
                } else {
                    tris.extend([[a, b, d], [b, c, d]]);
                }
            }
        }
        let n = (nx + 1) * (ny + 1);
        dual_from_stars(&tris, &Stars::new(n, &tris).unwrap()).unwrap()
    }

    /// Pieces per colour and edge cut by a breadth-first search, for reference.
    fn pieces_and_cut_by_search(g: &Graph, ncolours: usize, colour: &[u32]) -> (Vec<usize>, usize) {
        let n = g.num_vertices();
        let (mut seen, mut pieces, mut cut) = (vec![false; n], vec![0; ncolours], 0);
        for s in 0..n {
            for k in g.range(s) {
                let u = g.adjncy[k] as usize;
                if u < s && colour[u] != colour[s] {
                    cut += g.edge_weight(k) as usize;
                }
            }
            if seen[s] {
                continue;
            }
            pieces[colour[s] as usize] += 1;
            seen[s] = true;
            let mut queue = vec![s];
            while let Some(v) = queue.pop() {
                for &u in g.neighbours(v) {
                    let u = u as usize;
                    if !seen[u] && colour[u] == colour[s] {
                        seen[u] = true;
                        queue.push(u);
                    }
                }
            }
        }
        (pieces, cut)
    }

    #[test]
    fn pieces_across_blocks_of_vertices_are_counted_once_on_any_number_of_threads() {
        // 120 000 triangles, rows of 600: several blocks of the union-find.
        let g = grid_graph(300, 200);
        let n = g.num_vertices();
        let rows: Vec<u32> = (0..n).map(|e| ((e / 600) % 3) as u32).collect();
        let columns: Vec<u32> = (0..n).map(|e| ((e % 600) / 100 % 2) as u32).collect();
        for (colour, ncolours) in [(&rows, 3), (&columns, 2)] {
            let expected = pieces_and_cut_by_search(&g, ncolours, colour);
            assert!(expected.0.iter().all(|&p| p > 1));
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let got = pool.install(|| pieces_and_cut(&g, ncolours, |v| colour[v]));
                assert_eq!(got, expected, "{threads} threads");
            }
        }
    }

    fn total_edge_weight(g: &Graph) -> i64 {
        (0..g.adjncy.len())
            .map(|k| i64::from(g.edge_weight(k)))
            .sum()
    }

    #[test]
    fn coarsening_keeps_weights_and_symmetry() {
        let g = grid_graph(30, 20);
        let (c1, cmap, members) = coarsen::coarsen(&g);
        assert!(c1.num_vertices() < g.num_vertices() * 3 / 5);
        for (c, pair) in members.iter().enumerate() {
            for &v in pair.iter().filter(|&&v| v >= 0) {
                assert_eq!(cmap[v as usize], c as Idx);
            }
            let w: Idx = pair.iter().filter(|&&v| v >= 0).map(|_| 1).sum();
            assert_eq!(c1.vertex_weight(c), w);
        }
        // Edges inside a coarse vertex disappear; the others keep their weight.
        let (c2, _, _) = coarsen::coarsen(&c1);
        let inside = (0..g.num_vertices())
            .flat_map(|v| g.neighbours(v).iter().map(move |&u| (v, u as usize)))
            .filter(|&(v, u)| cmap[v] == cmap[u])
            .count() as i64;
        assert_eq!(total_edge_weight(&c1), total_edge_weight(&g) - inside);
        let total: Idx = (0..c2.num_vertices()).map(|c| c2.vertex_weight(c)).sum();
        assert_eq!(total as usize, g.num_vertices());
        for g in [&c1, &c2] {
            for v in 0..g.num_vertices() {
                for k in g.range(v) {
                    let u = g.adjncy[k] as usize;
                    assert_ne!(u, v);
                    let back = g.range(u).find(|&j| g.adjncy[j] as usize == v).unwrap();
                    assert_eq!(g.edge_weight(k), g.edge_weight(back));
                }
            }
        }
    }

    #[test]
    fn refinement_lowers_the_cut_and_keeps_parts_whole() {
        // Two parts split along a jagged line: column < 30 + (row pseudo-random shift).
        let (nx, ny) = (60, 40);
        let g = grid_graph(nx, ny);
        let mut state = 3u32;
        let shift: Vec<usize> = (0..ny)
            .map(|_| {
                state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (state >> 16) as usize % 7
            })
            .collect();
        let mut part: Vec<Idx> = (0..g.num_vertices())
            .map(|e| Idx::from((e / 2) % nx >= 27 + shift[e / 2 / nx]))
            .collect();
        let colour = |part: &[Idx]| part.iter().map(|&p| p as u32).collect::<Vec<_>>();
        let before = colour(&part);
        let (pieces, cut_before) = pieces_and_cut(&g, 2, |e| before[e]);
        assert_eq!(pieces, vec![1, 1]);
        let mut weight = vec![0i64; 2];
        for &p in &part {
            weight[p as usize] += 1;
        }
        let max_weight = g.num_vertices() as i64 * 103 / 200;
        let all = 0..g.num_vertices() as Idx;
        let boundary = coarsen::refine(&g, &mut part, &mut weight, max_weight, 10, all);
        let after = colour(&part);
        let (pieces, cut_after) = pieces_and_cut(&g, 2, |e| after[e]);
        assert_eq!(pieces, vec![1, 1]);
        assert!(cut_after < cut_before, "{cut_after} >= {cut_before}");
        assert!(weight.iter().all(|&w| w <= max_weight));
        assert_eq!(weight[1], part.iter().map(|&p| i64::from(p)).sum::<i64>());
        let mut expect: Vec<Idx> = (0..g.num_vertices())
            .filter(|&v| g.neighbours(v).iter().any(|&u| part[u as usize] != part[v]))
            .map(|v| v as Idx)
            .collect();
        let mut got = boundary;
        got.sort_unstable();
        expect.sort_unstable();
        assert_eq!(got, expect);
    }

    #[test]
    fn coarsened_partitions_are_contiguous_balanced_and_deterministic() {
        let g = grid_graph(120, 80);
        let n = g.num_vertices();
        for nparts in [2, 3, 4] {
            let direct = partition_graph(&g, nparts, usize::MAX).unwrap();
            let coarse = partition_graph(&g, nparts, 2000).unwrap();
            assert_eq!(coarse, partition_graph(&g, nparts, 2000).unwrap());
            let (_, direct_cut) = pieces_and_cut(&g, nparts, |e| direct[e]);
            let (pieces, cut) = pieces_and_cut(&g, nparts, |e| coarse[e]);
            assert_eq!(pieces, vec![1; nparts], "{nparts} parts");
            let mut sizes = vec![0usize; nparts];
            for &p in &coarse {
                sizes[p as usize] += 1;
            }
            let imbalance = *sizes.iter().max().unwrap() as f64 * nparts as f64 / n as f64;
            assert!(imbalance <= 1.03, "{nparts} parts: imbalance {imbalance}");
            assert!(
                cut * 10 <= direct_cut * 12,
                "{nparts} parts: cut {cut}, METIS alone {direct_cut}"
            );
        }
    }
}
