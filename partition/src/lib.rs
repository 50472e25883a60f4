//! Mesh partitioning for contact-par.
//!
//! Rank 0 calls [`partition_mesh`] to split a P1 triangle mesh over `nparts` MPI ranks:
//!
//! 1. [`dual_graph`]: triangles are vertices, two triangles are adjacent when they
//!    share an edge;
//! 2. METIS k-way partitioning of that graph with fixed options (listed in
//!    [`partition_mesh`]), so the same mesh always gives the same parts;
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
/// Runs in O(number of triangles): the mesh edges are bucketed by their lower node id
/// (a counting sort), and each bucket holds only the few edges leaving one node.
/// An edge shared by more than two triangles (a non-manifold mesh) links all of them.
///
/// # Errors
/// [`PartitionError::NodeOutOfRange`] or [`PartitionError::DegenerateTriangle`] for an
/// invalid triangle.
pub fn dual_graph(num_nodes: usize, triangles: &[[usize; 3]]) -> Result<DualGraph, PartitionError> {
    validate_triangles(num_nodes, triangles)?;
    let ne = triangles.len();

    // Bucket the 3 edges of every triangle by their lower node: (higher node, triangle).
    let mut start = vec![0usize; num_nodes + 1];
    for t in triangles {
        for (a, b) in triangle_edges(t) {
            start[a.min(b) + 1] += 1;
        }
    }
    prefix_sum(&mut start);
    let mut fill = start.clone();
    let mut edges = vec![(0usize, 0usize); 3 * ne];
    for (e, t) in triangles.iter().enumerate() {
        for (a, b) in triangle_edges(t) {
            let lo = a.min(b);
            edges[fill[lo]] = (a.max(b), e);
            fill[lo] += 1;
        }
    }
    drop(fill);

    // Triangles sharing an edge are now neighbours in a sorted bucket. Count the
    // adjacencies first, then fill them, so the CSR arrays are allocated once.
    let mut xadj = vec![0usize; ne + 1];
    for_each_shared_edge(&start, &mut edges, |e, f| {
        xadj[e + 1] += 1;
        xadj[f + 1] += 1;
    });
    prefix_sum(&mut xadj);
    let mut fill = xadj.clone();
    let mut adjncy = vec![0usize; xadj[ne]];
    for_each_shared_edge(&start, &mut edges, |e, f| {
        adjncy[fill[e]] = f;
        fill[e] += 1;
        adjncy[fill[f]] = e;
        fill[f] += 1;
    });
    drop(edges);

    // Sort each row, and drop repeats: two triangles with the same three nodes would
    // otherwise be linked once per common edge, and METIS rejects multi-edges.
    let mut write = 0;
    let mut row_start = 0;
    for e in 0..ne {
        let row_end = xadj[e + 1];
        adjncy[row_start..row_end].sort_unstable();
        let mut last = usize::MAX;
        for k in row_start..row_end {
            let f = adjncy[k];
            if f != last {
                adjncy[write] = f;
                write += 1;
                last = f;
            }
        }
        row_start = row_end;
        xadj[e + 1] = write;
    }
    adjncy.truncate(write);
    Ok(DualGraph { xadj, adjncy })
}

fn triangle_edges(t: &[usize; 3]) -> [(usize, usize); 3] {
    [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]
}

fn prefix_sum(v: &mut [usize]) {
    for i in 1..v.len() {
        v[i] += v[i - 1];
    }
}

/// Calls `link(e, f)` (with `e < f`) for every pair of triangles sharing a mesh edge.
/// `edges` is bucketed by lower node as in [`dual_graph`]; each bucket gets sorted.
fn for_each_shared_edge(
    start: &[usize],
    edges: &mut [(usize, usize)],
    mut link: impl FnMut(usize, usize),
) {
    for w in start.windows(2) {
        let bucket = &mut edges[w[0]..w[1]];
        if bucket.len() < 2 {
            continue;
        }
        bucket.sort_unstable();
        let mut i = 0;
        while i < bucket.len() {
            let mut j = i + 1;
            while j < bucket.len() && bucket[j].0 == bucket[i].0 {
                j += 1;
            }
            for a in i..j {
                for b in a + 1..j {
                    if bucket[a].1 != bucket[b].1 {
                        link(bucket[a].1, bucket[b].1);
                    }
                }
            }
            i = j;
        }
    }
}

fn validate_triangles(num_nodes: usize, triangles: &[[usize; 3]]) -> Result<(), PartitionError> {
    for (element, t) in triangles.iter().enumerate() {
        if let Some(&node) = t.iter().find(|&&n| n >= num_nodes) {
            return Err(PartitionError::NodeOutOfRange {
                element,
                node,
                num_nodes,
            });
        }
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            return Err(PartitionError::DegenerateTriangle { element });
        }
    }
    Ok(())
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
/// # METIS options
/// `METIS_PartGraphKway` on the unweighted dual graph with METIS' defaults (edge-cut
/// objective, sorted heavy-edge matching, load imbalance tolerance 1.03 (`ufactor`
/// 30), one cut, 10 refinement iterations), set explicitly, plus two choices:
/// `seed` = [`METIS_SEED`], and `contig` = 1 (contiguous parts) when the dual graph is
/// connected. METIS refuses `contig` on a disconnected graph (e.g. two separate
/// bodies in contact), so it is off there. Calls are serialised by a lock because
/// METIS keeps its random state in process-wide statics.
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
    check_nparts(nparts, triangles.len())?;
    let graph = dual_graph(num_nodes, triangles)?;
    let mut element_part = metis_kway(&graph, nparts)?;
    fill_empty_parts(&mut element_part, nparts);
    build_partition(
        num_nodes,
        triangles,
        contact_nodes,
        nparts,
        element_part,
        &graph,
    )
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
    if let Some(element) = element_part.iter().position(|&p| p as usize >= nparts) {
        return Err(PartitionError::PartOutOfRange {
            element,
            part: element_part[element],
            nparts,
        });
    }
    let graph = dual_graph(num_nodes, triangles)?;
    build_partition(
        num_nodes,
        triangles,
        contact_nodes,
        nparts,
        element_part,
        &graph,
    )
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

/// The METIS options array described in [`partition_mesh`].
fn metis_options(graph_is_connected: bool) -> [metis::Idx; metis::NOPTIONS] {
    use metis::option::{CType, Contig, NCuts, NIter, ObjType, Opt, PType, Seed, UFactor};
    let mut options = [-1; metis::NOPTIONS];
    options[PType::INDEX] = PType::Kway.value();
    options[ObjType::INDEX] = ObjType::Cut.value();
    options[CType::INDEX] = CType::Shem.value();
    options[UFactor::INDEX] = UFactor(30).value();
    options[NCuts::INDEX] = NCuts(1).value();
    options[NIter::INDEX] = NIter(10).value();
    options[Seed::INDEX] = Seed(METIS_SEED).value();
    options[Contig::INDEX] = Contig(graph_is_connected).value();
    options
}

/// METIS keeps its random number generator in process-wide statics, so two threads
/// partitioning at once would disturb each other's sequence (and results).
static METIS_LOCK: Mutex<()> = Mutex::new(());

fn metis_kway(graph: &DualGraph, nparts: usize) -> Result<Vec<u32>, PartitionError> {
    let ne = graph.num_vertices();
    if nparts == 1 {
        return Ok(vec![0; ne]);
    }
    let to_idx = |v: usize| metis::Idx::try_from(v).map_err(|_| PartitionError::TooLarge);
    let xadj = graph
        .xadj
        .iter()
        .map(|&v| to_idx(v))
        .collect::<Result<Vec<_>, _>>()?;
    // Entries of adjncy are < ne, so they fit once ne does.
    to_idx(ne)?;
    let adjncy: Vec<metis::Idx> = graph.adjncy.iter().map(|&v| v as metis::Idx).collect();
    let options = metis_options(pieces_per_colour(graph, 1, |_| 0)[0] == 1);
    let mut part = vec![0 as metis::Idx; ne];
    {
        let _guard = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        metis::Graph::new(1, to_idx(nparts)?, &xadj, &adjncy)
            .map_err(|e| PartitionError::Metis(e.to_string()))?
            .set_options(&options)
            .part_kway(&mut part)
            .map_err(|e| PartitionError::Metis(e.to_string()))?;
    }
    Ok(part.into_iter().map(|p| p as u32).collect())
}

/// Gives every empty part one triangle: the highest-numbered triangle of the largest
/// part (lowest id on ties). Needs `nparts <= element_part.len()`.
fn fill_empty_parts(element_part: &mut [u32], nparts: usize) {
    let mut sizes = vec![0usize; nparts];
    for &p in element_part.iter() {
        sizes[p as usize] += 1;
    }
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

/// For each colour `c < ncolours`, the number of edge-connected pieces of the dual
/// graph restricted to the triangles of colour `c`.
fn pieces_per_colour(
    graph: &DualGraph,
    ncolours: usize,
    colour: impl Fn(usize) -> u32,
) -> Vec<usize> {
    let ne = graph.num_vertices();
    let mut seen = vec![false; ne];
    let mut stack = Vec::new();
    let mut count = vec![0usize; ncolours];
    for root in 0..ne {
        if seen[root] {
            continue;
        }
        let c = colour(root);
        count[c as usize] += 1;
        seen[root] = true;
        stack.push(root);
        while let Some(e) = stack.pop() {
            for &f in graph.neighbours(e) {
                if !seen[f] && colour(f) == c {
                    seen[f] = true;
                    stack.push(f);
                }
            }
        }
    }
    count
}

fn build_partition(
    num_nodes: usize,
    triangles: &[[usize; 3]],
    contact_nodes: &[usize],
    nparts: usize,
    element_part: Vec<u32>,
    graph: &DualGraph,
) -> Result<Partition, PartitionError> {
    let mut contact: Vec<usize> = contact_nodes.to_vec();
    contact.sort_unstable();
    contact.dedup();
    if let Some(&node) = contact.iter().find(|&&n| n >= num_nodes) {
        return Err(PartitionError::ContactNodeOutOfRange { node, num_nodes });
    }

    let mut parts = vec![Part::default(); nparts];
    for (e, &p) in element_part.iter().enumerate() {
        parts[p as usize].elements.push(e);
    }

    // Node -> parts of its triangles, as CSR (a counting sort by node), so that each
    // node's parts can be listed without per-node allocation.
    let mut start = vec![0usize; num_nodes + 1];
    for t in triangles {
        for &n in t {
            start[n + 1] += 1;
        }
    }
    prefix_sum(&mut start);
    let mut fill = start.clone();
    let mut node_parts = vec![0u32; start[num_nodes]];
    for (t, &p) in triangles.iter().zip(&element_part) {
        for &n in t {
            node_parts[fill[n]] = p;
            fill[n] += 1;
        }
    }
    drop(fill);

    // Nodes are visited in increasing order, so every per-part list comes out sorted.
    let mut node_owner = vec![NO_PART; num_nodes];
    let mut shared: Vec<BTreeMap<u32, Vec<usize>>> = vec![BTreeMap::new(); nparts];
    let mut interface_nodes = 0;
    for n in 0..num_nodes {
        let touching = &mut node_parts[start[n]..start[n + 1]];
        if touching.is_empty() {
            continue;
        }
        touching.sort_unstable();
        let mut k = 1;
        for i in 1..touching.len() {
            if touching[i] != touching[k - 1] {
                touching[k] = touching[i];
                k += 1;
            }
        }
        let touching = &touching[..k];
        // Ownership rule: the lowest part id touching the node. Simple, deterministic,
        // and computable by every rank from the shared lists alone.
        let owner = touching[0];
        node_owner[n] = owner;
        for &p in touching {
            let part = &mut parts[p as usize];
            part.nodes.push(n);
            part.owned.push(p == owner);
            if touching.len() > 1 {
                part.interface.push(n);
                for &q in touching.iter().filter(|&&q| q != p) {
                    shared[p as usize].entry(q).or_default().push(n);
                }
            }
        }
        if touching.len() > 1 {
            interface_nodes += 1;
        }
    }
    for (part, map) in parts.iter_mut().zip(shared) {
        part.neighbours = map.into_iter().collect();
    }
    for &n in &contact {
        match node_owner[n] {
            NO_PART => return Err(PartitionError::ContactNodeUnused { node: n }),
            p => parts[p as usize].contact_nodes.push(n),
        }
    }

    let quality = quality(nparts, &element_part, &parts, interface_nodes, graph);
    Ok(Partition {
        nparts,
        element_part,
        node_owner,
        parts,
        quality,
    })
}

fn quality(
    nparts: usize,
    element_part: &[u32],
    parts: &[Part],
    interface_nodes: usize,
    graph: &DualGraph,
) -> Quality {
    let edge_cut = (0..graph.num_vertices())
        .map(|e| {
            graph
                .neighbours(e)
                .iter()
                .filter(|&&f| f > e && element_part[f] != element_part[e])
                .count()
        })
        .sum();
    let sizes = parts.iter().map(|p| p.elements.len());
    let max_part_elements = sizes.clone().max().unwrap_or(0);
    let mean = element_part.len() as f64 / nparts as f64;
    let pieces = pieces_per_colour(graph, nparts, |e| element_part[e]);
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
    let status = {
        let _guard = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
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
    };
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
        let g = dual_graph(5, &[[0, 1, 2], [2, 3, 4]]).unwrap();
        assert_eq!(g.num_edges(), 0);
        assert_eq!(pieces_per_colour(&g, 1, |_| 0), vec![2]);
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
        let o = metis_options(false);
        assert_eq!(o[Seed::INDEX], METIS_SEED);
        assert_eq!(o[Contig::INDEX], 0);
        assert_eq!(metis_options(true)[Contig::INDEX], 1);
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
}
