//! Splitting the global problem into one subproblem per rank (pure: no MPI).
//!
//! The boundary dofs B of a rank are the free dofs of its own contact nodes that no other
//! part touches (its "contact" dofs, eliminated locally) followed by the free dofs of its
//! interface nodes (touched by several parts; a contact node on the interface is one of
//! them). Only the interface dofs have a global number, in increasing (node, component)
//! order; every rank orders its boundary dofs last: contact, then interface.
//!
//! A contact dof is in B only if the contact acts on it ([`contact_components`]): without
//! friction, at a node whose normal is along an axis, the other component stays in the
//! interior; a node with an oblique normal has its dofs turned into its frame
//! ([`in_frame`]), so that it too keeps only its normal dof in B. The dense work of a rank grows like |B|^3 and its
//! sweep like |B|^2, so this halves the contact part of B where it applies (frictionless
//! Hertz at 1.2M nodes: the last dense supernode of the one-rank factor shrinks from
//! 5047 to 3293 columns).

use crate::contact::ContactNodes;
use crate::error::{Error, Result};
use crate::problem::Problem;
use partition::Partition;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Everything one rank needs, and nothing of the others' parts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct SubProblem {
    pub rank: usize,
    /// The mesh file's index of each local node: its row in `nodes.csv`.
    pub global_nodes: Vec<usize>,
    pub nodes: Vec<[f64; 2]>,
    /// Triangles in local node numbering.
    pub triangles: Vec<[usize; 3]>,
    /// Each triangle's body (its index in `Case::materials`).
    pub body: Vec<u32>,
    /// Whether this rank owns each local node (writes it in nodes.csv).
    pub owned: Vec<bool>,
    /// Prescribed values per local dof.
    pub fixed: Vec<Option<f64>>,
    /// Load per local dof; a node's load is given to its owner only, so that the sum
    /// over subdomains is the global load.
    pub load: Vec<f64>,
    /// Own contact nodes (local ids), in the global sweep order.
    pub contact_nodes: Vec<usize>,
    pub contact: ContactNodes,
    /// Local dofs (2 * local node + c) in B: the `n_contact_dofs` contact dofs first, then
    /// the interface dofs by increasing global interface index.
    pub boundary_dofs: Vec<usize>,
    /// Number of contact (not interface) dofs at the head of `boundary_dofs`.
    pub n_contact_dofs: usize,
    /// Global interface index of each interface dof (the tail of `boundary_dofs`).
    pub interface_global: Vec<usize>,
    /// Local nodes shared with another part.
    pub interface_nodes: usize,
    /// Local nodes whose dofs are in their contact frame ([`in_frame`]), with their
    /// normal m, increasing; every subdomain holding such a node turns it alike.
    pub frames: Vec<(usize, [f64; 2])>,
    /// The master nodes (local ids) and coefficients of each own contact node's mortar
    /// row, same order as `contact_nodes`; empty against an obstacle.
    #[serde(default)]
    pub contact_masters: Vec<Vec<(usize, f64)>>,
    /// The last `ghosts` local nodes are master nodes of this subdomain's mortar rows
    /// that none of its triangles touch: interface nodes with no stiffness here, so that
    /// the rows' augmentation and forces are assembled where the rows are.
    #[serde(default)]
    pub ghosts: usize,
}

/// The large arrays of a [`SubProblem`], which [`Mpi::scatter_parts`] sends as they lie
/// in memory, the rest encoded.
///
/// [`Mpi::scatter_parts`]: crate::dd::comm::Mpi::scatter_parts
#[derive(Debug, Default, PartialEq)]
pub struct PartArrays {
    pub global_nodes: Vec<usize>,
    pub nodes: Vec<[f64; 2]>,
    pub triangles: Vec<[usize; 3]>,
    pub body: Vec<u32>,
    pub owned: Vec<bool>,
    pub load: Vec<f64>,
}

impl PartArrays {
    /// The arrays' lengths, in the order of the fields.
    pub fn lengths(&self) -> [u64; 6] {
        [
            self.global_nodes.len(),
            self.nodes.len(),
            self.triangles.len(),
            self.body.len(),
            self.owned.len(),
            self.load.len(),
        ]
        .map(|n| n as u64)
    }

    /// Arrays of the given [`PartArrays::lengths`], to receive into.
    pub fn of_lengths(n: [u64; 6]) -> Self {
        let n = n.map(|n| n as usize);
        PartArrays {
            global_nodes: vec![0; n[0]],
            nodes: vec![[0.0; 2]; n[1]],
            triangles: vec![[0; 3]; n[2]],
            body: vec![0; n[3]],
            owned: vec![false; n[4]],
            load: vec![0.0; n[5]],
        }
    }
}

impl SubProblem {
    /// Moves its large arrays out, leaving them empty.
    pub fn take_arrays(&mut self) -> PartArrays {
        use std::mem::take;
        PartArrays {
            global_nodes: take(&mut self.global_nodes),
            nodes: take(&mut self.nodes),
            triangles: take(&mut self.triangles),
            body: take(&mut self.body),
            owned: take(&mut self.owned),
            load: take(&mut self.load),
        }
    }

    /// Puts back the arrays [`SubProblem::take_arrays`] took.
    pub fn put_arrays(&mut self, a: PartArrays) {
        self.global_nodes = a.global_nodes;
        self.nodes = a.nodes;
        self.triangles = a.triangles;
        self.body = a.body;
        self.owned = a.owned;
        self.load = a.load;
    }

    /// Each local node's frame, `None` for x, y (see `fem::assemble_in_frames`).
    pub fn node_frames(&self) -> Vec<Option<[f64; 2]>> {
        let mut f = vec![None; self.nodes.len()];
        for &(v, m) in &self.frames {
            f[v] = Some(m);
        }
        f
    }

    /// The normal of each own contact node as the linear step sees it: (1, 0) for a node
    /// in its frame (u'_0 = m . u, and the tangent (0, -1) reads t . u), else m.
    pub fn step_normals(&self) -> Vec<[f64; 2]> {
        let frames = self.node_frames();
        (self.contact_nodes.iter().zip(&self.contact.normal))
            .map(|(&v, &m)| frames[v].map_or(m, |_| [1.0, 0.0]))
            .collect()
    }
}

/// Whether a contact node's dofs are turned into its frame (m, (-m_y, m_x)): without
/// friction, where the normal is oblique (otherwise the contact reads one component
/// already, [`contact_components`]) and both dofs are free (a prescribed component is a
/// condition in x, y). Then only m . u is read, and the other dof leaves the condensed
/// system.
pub fn in_frame(frictional: bool, m: [f64; 2], fixed: [bool; 2]) -> bool {
    !frictional && m[0] != 0.0 && m[1] != 0.0 && !fixed[0] && !fixed[1]
}

/// The global numbering shared by all ranks, known in full on the first rank only.
#[derive(Debug, Clone, PartialEq)]
pub struct GlobalMap {
    /// Number of interface dofs (the size of the dense interface system).
    pub n_interface: usize,
    /// Number of boundary dofs, contact and interface, over all ranks.
    pub n_boundary: usize,
    /// Own contact nodes per rank (the counts of the per-sweep all-gather).
    pub contact_counts: Vec<usize>,
}

/// The components (x, y) of a contact node that the contact conditions read and load:
/// with friction both; without, those along which the normal `m` has a component (u_n =
/// -m.u and the force -m f_n leave a component with m_c = 0 untouched, and the
/// augmentation w r m m' is then exactly zero on it). A component that is not read need
/// not be in the condensed system: it is eliminated with the interior.
pub fn contact_components(frictional: bool, m: [f64; 2]) -> [bool; 2] {
    if frictional {
        [true, true]
    } else {
        [m[0] != 0.0, m[1] != 0.0]
    }
}

/// What the contact reads of each node of a problem (see [`split`]).
struct ContactReads {
    /// Contact nodes and the master nodes of their rows.
    is_contact: Vec<bool>,
    /// The components each node's contact reads (none off the contact boundary), in the
    /// node's frame where it has one.
    read: Vec<[bool; 2]>,
    /// Only contact nodes turn: a map, not a vector sized like the mesh, which one thread
    /// filled while the others waited.
    frame: std::collections::HashMap<usize, [f64; 2]>,
    is_master: Vec<bool>,
}

impl ContactReads {
    fn of(prob: &Problem, frictional: bool) -> Self {
        let n = prob.mesh.num_nodes();
        let mut is_contact = vec![false; n];
        let mut read = vec![[false; 2]; n];
        let mut frame: std::collections::HashMap<usize, [f64; 2]> = Default::default();
        let mut is_master = vec![false; n];
        for k in 0..prob.contact_nodes.len() {
            for &(v, _) in masters_of(prob, k) {
                is_master[v] = true;
            }
        }
        for (k, &c) in prob.contact_nodes.iter().enumerate() {
            is_contact[c] = true;
            let m = prob.contact.normal[k];
            let fixed = [0, 1].map(|i| prob.fixed[2 * c + i].is_some());
            // A mortar row reads its master nodes in x, y along its normal (the rows of
            // several slave nodes along theirs): a master node does not turn; the slave
            // node does, like a node against an obstacle.
            if !is_master[c] && in_frame(frictional, m, fixed) {
                frame.insert(c, m);
                read[c] = [true, false];
            } else {
                read[c] = contact_components(frictional, m);
            }
        }
        // A master node is read like the slave node of its row.
        for k in 0..prob.contact_nodes.len() {
            let comps = contact_components(frictional, prob.contact.normal[k]);
            for &(v, _) in masters_of(prob, k) {
                is_contact[v] = true;
                read[v] = [read[v][0] || comps[0], read[v][1] || comps[1]];
            }
        }
        ContactReads {
            is_contact,
            read,
            frame,
            is_master,
        }
    }

    /// A contact dof in B: read by the contact and free.
    fn in_b(&self, prob: &Problem, v: usize, c: usize) -> bool {
        self.is_contact[v] && self.read[v][c] && prob.fixed[2 * v + c].is_none()
    }
}

/// The master nodes and coefficients of contact node `k`'s row (none against an obstacle).
fn masters_of(prob: &Problem, k: usize) -> &[(usize, f64)] {
    prob.contact_masters.get(k).map_or(&[][..], |m| &m[..])
}

/// [`split`] into one part, `prob`'s arrays moved rather than copied: the one subdomain
/// of a one-rank run is the whole problem in its own numbering (every node is on a
/// triangle, which the problem's checks make sure of), with its contact dofs for B and
/// no interface, without the copy, the node stars and the ownership pass of the general
/// split.
pub fn split_whole(prob: Problem, frictional: bool) -> (SubProblem, GlobalMap) {
    let reads = ContactReads::of(&prob, frictional);
    let nc = prob.contact_nodes.len();
    let mut at_contact: Vec<usize> = (prob.contact_nodes.iter().copied())
        .chain(prob.contact_masters.iter().flatten().map(|&(v, _)| v))
        .collect();
    at_contact.sort_unstable();
    at_contact.dedup();
    let boundary_dofs: Vec<usize> = (at_contact.iter())
        .flat_map(|&v| [2 * v, 2 * v + 1])
        .filter(|&d| reads.in_b(&prob, d / 2, d % 2))
        .collect();
    let mut frames: Vec<(usize, [f64; 2])> = reads.frame.into_iter().collect();
    frames.sort_unstable_by_key(|f| f.0);
    let all: Vec<usize> = (0..nc).collect();
    let sub = SubProblem {
        rank: 0,
        owned: vec![true; prob.mesh.num_nodes()],
        contact: prob.contact.select(&all),
        contact_masters: (0..nc).map(|k| masters_of(&prob, k).to_vec()).collect(),
        n_contact_dofs: boundary_dofs.len(),
        boundary_dofs,
        interface_global: Vec::new(),
        interface_nodes: 0,
        frames,
        ghosts: 0,
        global_nodes: prob.file_node,
        nodes: prob.mesh.nodes,
        triangles: prob.mesh.triangles,
        body: prob.body,
        fixed: prob.fixed,
        load: prob.load,
        contact_nodes: prob.contact_nodes,
    };
    let map = GlobalMap {
        n_interface: 0,
        n_boundary: sub.n_contact_dofs,
        contact_counts: vec![nc],
    };
    (sub, map)
}

/// Splits `prob` by `part`; `frictional` tells which components of a contact node belong
/// to B ([`contact_components`]).
pub fn split(
    prob: &Problem,
    part: &Partition,
    frictional: bool,
) -> Result<(Vec<SubProblem>, GlobalMap)> {
    let reads = ContactReads::of(prob, frictional);
    let (ghosts, on_interface) = ghosts(prob, part, &reads.is_master);
    let (interface_index, n_interface, n_boundary) = number_boundary(prob, &reads, &on_interface);
    let mut contact_by_rank: Vec<Vec<usize>> = vec![Vec::new(); part.nparts];
    for (k, &c) in prob.contact_nodes.iter().enumerate() {
        contact_by_rank[part.node_owner[c] as usize].push(k);
    }
    let split = Splitter {
        prob,
        part,
        reads,
        ghosts,
        interface_index,
        contact_by_rank,
    };
    // Each part on a thread of the pool, with a scratch map from global to local node
    // numbers per thread: a part of a large mesh takes tens of milliseconds, and the
    // other ranks wait for the first rank's split.
    let n = prob.mesh.num_nodes();
    let subs = (part.parts.par_iter().enumerate())
        .map_init(
            || vec![usize::MAX; n],
            |local_of, (r, p)| split.sub(local_of, r, p),
        )
        .collect::<Result<Vec<SubProblem>>>()?;
    let contact_counts = split.contact_by_rank.iter().map(Vec::len).collect();
    let map = GlobalMap {
        n_interface,
        n_boundary,
        contact_counts,
    };
    Ok((subs, map))
}

/// Each part's ghosts (the master nodes of its own contact rows that it does not hold:
/// `SubProblem::ghosts`, sorted), and which nodes are on the interface: the parts'
/// interface nodes and every ghost.
fn ghosts(prob: &Problem, part: &Partition, is_master: &[bool]) -> (Vec<Vec<usize>>, Vec<bool>) {
    let mut on_interface = vec![false; prob.mesh.num_nodes()];
    for p in &part.parts {
        for &v in &p.interface {
            on_interface[v] = true;
        }
    }
    let mut holders: std::collections::HashMap<usize, Vec<usize>> = Default::default();
    for (r, p) in part.parts.iter().enumerate() {
        for &v in p.nodes.iter().filter(|&&v| is_master[v]) {
            holders.entry(v).or_default().push(r);
        }
    }
    let mut ghosts: Vec<Vec<usize>> = vec![Vec::new(); part.nparts];
    for (k, &c) in prob.contact_nodes.iter().enumerate() {
        let r = part.node_owner[c] as usize;
        for &(v, _) in masters_of(prob, k) {
            if !holders[&v].contains(&r) {
                ghosts[r].push(v);
                on_interface[v] = true;
            }
        }
    }
    for g in &mut ghosts {
        g.sort_unstable();
        g.dedup();
    }
    (ghosts, on_interface)
}

/// Each interface dof's number plus one (0: none), numbered by node then component, and
/// the counts of interface and boundary dofs. Zeroed memory, so the vector costs nothing
/// where it is not written; the loop runs over the interface and contact nodes alone.
fn number_boundary(
    prob: &Problem,
    reads: &ContactReads,
    on_interface: &[bool],
) -> (Vec<[u32; 2]>, usize, usize) {
    let n = prob.mesh.num_nodes();
    let mut interface_index = vec![[0u32; 2]; n];
    let (mut n_interface, mut n_boundary) = (0, 0);
    let boundary_nodes: Vec<usize> = (0..n)
        .into_par_iter()
        .filter(|&v| on_interface[v] || reads.is_contact[v])
        .collect();
    for v in boundary_nodes {
        for c in 0..2 {
            if prob.fixed[2 * v + c].is_some() {
                continue;
            }
            if on_interface[v] {
                n_interface += 1;
                interface_index[v][c] = n_interface as u32;
                n_boundary += 1;
            } else if reads.in_b(prob, v, c) {
                n_boundary += 1;
            }
        }
    }
    (interface_index, n_interface, n_boundary)
}

/// What every part's subproblem is cut from ([`split`]).
struct Splitter<'a> {
    prob: &'a Problem,
    part: &'a Partition,
    reads: ContactReads,
    ghosts: Vec<Vec<usize>>,
    /// [`number_boundary`]'s.
    interface_index: Vec<[u32; 2]>,
    /// Each part's own contact nodes (indices into the problem's).
    contact_by_rank: Vec<Vec<usize>>,
}

/// A part's dofs: each one's prescribed value and load, its contact dofs for B and its
/// interface dofs with their global numbers.
struct PartDofs {
    fixed: Vec<Option<f64>>,
    load: Vec<f64>,
    boundary_dofs: Vec<usize>,
    interface: Vec<(usize, usize)>,
}

impl Splitter<'_> {
    /// Part `r`'s subproblem; `local_of` is a scratch map from global to local nodes,
    /// all `usize::MAX`, and left so.
    fn sub(&self, local_of: &mut [usize], r: usize, p: &partition::Part) -> Result<SubProblem> {
        let prob = self.prob;
        let all_nodes: Vec<usize> = p.nodes.iter().chain(&self.ghosts[r]).copied().collect();
        for (l, &g) in all_nodes.iter().enumerate() {
            local_of[g] = l;
        }
        let owned: Vec<bool> = (all_nodes.iter().enumerate())
            .map(|(l, &g)| l < p.nodes.len() && self.part.node_owner[g] as usize == r)
            .collect();
        let PartDofs {
            fixed,
            load,
            mut boundary_dofs,
            mut interface,
        } = self.dofs(&all_nodes, &owned);
        // Ghosts come last among the nodes but take their place among the interface dofs.
        interface.sort_unstable();
        let (interface_global, interface_dofs): (Vec<usize>, Vec<usize>) =
            interface.into_iter().unzip();
        let n_contact_dofs = boundary_dofs.len();
        boundary_dofs.extend(interface_dofs);
        let mine = &self.contact_by_rank[r];
        let local = |v: usize| local_of[v];
        let sub = SubProblem {
            rank: r,
            global_nodes: all_nodes.iter().map(|&g| prob.file_node[g]).collect(),
            nodes: all_nodes.iter().map(|&g| prob.mesh.nodes[g]).collect(),
            triangles: (p.elements.iter())
                .map(|&e| prob.mesh.triangles[e].map(local))
                .collect(),
            body: p.elements.iter().map(|&e| prob.body[e]).collect(),
            owned,
            fixed,
            load,
            contact_nodes: mine.iter().map(|&k| local(prob.contact_nodes[k])).collect(),
            contact: prob.contact.select(mine),
            boundary_dofs,
            n_contact_dofs,
            interface_global,
            interface_nodes: p.interface.len(),
            frames: (all_nodes.iter().enumerate())
                .filter_map(|(l, &g)| self.reads.frame.get(&g).map(|&m| (l, m)))
                .collect(),
            contact_masters: (mine.iter())
                .map(|&k| (masters_of(prob, k).iter()).map(|&(v, c)| (local(v), c)))
                .map(|row| row.collect())
                .collect(),
            ghosts: self.ghosts[r].len(),
        };
        // Reset before any return: the scratch serves the thread's next part.
        let unheld = sub.contact_nodes.contains(&usize::MAX);
        for &g in &all_nodes {
            local_of[g] = usize::MAX;
        }
        if unheld {
            return Err(Error::Numerical(format!(
                "internal: rank {r} owns a contact node it does not hold"
            )));
        }
        Ok(sub)
    }

    /// The dofs of the nodes `all_nodes` (local numbering: their order), the loads on
    /// the `owned` ones only.
    fn dofs(&self, all_nodes: &[usize], owned: &[bool]) -> PartDofs {
        let prob = self.prob;
        let mut dofs = PartDofs {
            fixed: Vec::with_capacity(2 * all_nodes.len()),
            load: Vec::with_capacity(2 * all_nodes.len()),
            boundary_dofs: Vec::new(),
            interface: Vec::new(),
        };
        for (l, &g) in all_nodes.iter().enumerate() {
            for c in 0..2 {
                dofs.fixed.push(prob.fixed[2 * g + c]);
                dofs.load
                    .push(if owned[l] { prob.load[2 * g + c] } else { 0.0 });
                if let Some(b) = self.interface_index[g][c].checked_sub(1) {
                    dofs.interface.push((b as usize, 2 * l + c));
                } else if self.reads.in_b(prob, g, c) {
                    dofs.boundary_dofs.push(2 * l + c);
                }
            }
        }
        dofs
    }
}

#[cfg(test)]
mod tests {
    use super::{contact_components, in_frame};

    #[test]
    fn contact_components_are_those_the_contact_reads() {
        assert_eq!(contact_components(true, [0.0, 1.0]), [true, true]);
        assert_eq!(contact_components(false, [0.0, 1.0]), [false, true]);
        assert_eq!(contact_components(false, [-1.0, 0.0]), [true, false]);
        let t: f64 = 1e-3;
        assert_eq!(contact_components(false, [t.sin(), t.cos()]), [true, true]);
    }

    #[test]
    fn only_frictionless_oblique_free_nodes_turn() {
        let oblique = [0.6, 0.8];
        assert!(in_frame(false, oblique, [false, false]));
        assert!(!in_frame(true, oblique, [false, false]));
        assert!(!in_frame(false, [0.0, 1.0], [false, false]));
        assert!(!in_frame(false, oblique, [true, false]));
    }
}
