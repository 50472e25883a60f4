//! Each rank's subproblem built on its own rank, from the lists of its part that the
//! ranks found from their shares of the mesh file (`dd::ownership::part_lists`) and the
//! conditions of the part's nodes: the same subproblem as [`super::split::split`]
//! makes from the whole problem, but for its local numbering, the global numbering of
//! the interface dofs, and the rounding of the loads.
//!
//! Why: the split and the hand-out of the subproblems are otherwise the first rank's,
//! serial, and sized like the whole mesh (docs/cost-model.md, "The start from one Gmsh
//! file"); here the first rank sends only the conditions of the boundary nodes, and
//! each rank builds, numbers and loads its own part.
//!
//! Who holds what: the conditions ([`Conditions`]) come from the first rank's problem;
//! everything sized like a part stays on the part's rank. A contact between two bodies
//! adds to the conditions each slave node's mortar row (its master nodes and their
//! coefficients) and each master node's point: a part that owns a slave node but does
//! not hold one of its masters takes it as a ghost, and the ranks tell each other which
//! masters are ghosts somewhere (interface nodes in every part that holds them) and
//! their interface numbers, boundary-sized lists sent to every rank.

use crate::case::Case;
use crate::contact::ContactNodes;
use crate::dd::comm::Mpi;
use crate::dd::ownership::{InterfaceFigures, PartLists};
use crate::dd::split::{contact_components, in_frame, GlobalMap, SubProblem};
use crate::error::{Error, Result};
use crate::fem::assembly::add_body_force;
use crate::mesh::renumber;
use crate::problem::{traction_load, Problem};
use partition::{node_pieces, Quality};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// A node of a part that carries a condition: what the part's rank cannot know from its
/// triangles.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NodeRecord {
    /// The node's index among the file's nodes.
    pub file: u64,
    pub fixed: [Option<f64>; 2],
    /// The nodal force of the tractions, which the node's owner alone applies.
    pub traction: [f64; 2],
    pub contact: Option<ContactRecord>,
    /// Where the node is a master node of mortar rows.
    pub master: Option<MasterRecord>,
}

/// A master node of mortar rows: what a part needs of it, also where it holds the node
/// only as a ghost (a part that owns a slave node but not the triangles of its master).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MasterRecord {
    /// The components its rows read (`split::contact_components` of each row's normal).
    pub read: [bool; 2],
    pub xy: [f64; 2],
}

/// A contact node's geometry against its obstacle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContactRecord {
    /// Its place among the problem's contact nodes: each rank keeps its own in this
    /// order.
    pub k: u64,
    pub w: f64,
    pub g: f64,
    pub s: f64,
    pub normal: [f64; 2],
    pub pair: u32,
    /// Its separate part of the mesh and its master's (see `ContactNodes::part`).
    pub part: [u32; 2],
    /// Its mortar row's master nodes (indices among the file's nodes) and coefficients;
    /// empty against an obstacle.
    pub masters: Vec<(u64, f64)>,
}

/// What the first rank tells the ranks about the problem beyond the parts' triangles:
/// sized like the boundary, not the mesh, and sent whole to every rank.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Conditions {
    /// The nodes that carry a condition, by increasing file index.
    pub nodes: Vec<NodeRecord>,
    /// Each triangle's body, in runs over the file's triangle records: (first record of
    /// the run, body), increasing.
    pub bodies: Vec<(u64, u32)>,
}

impl Conditions {
    /// The conditions of `prob`.
    pub fn of(case: &Case, prob: &Problem) -> Result<Conditions> {
        let nodes = Self::records(case, prob)?;
        let mut by_file = vec![0u32; prob.file_triangle.len()];
        for (&f, &b) in prob.file_triangle.iter().zip(&prob.body) {
            by_file[f] = b;
        }
        Ok(Conditions {
            nodes,
            bodies: runs(&by_file),
        })
    }

    /// The records of `prob`'s nodes that carry a condition, by increasing file index
    /// (`prob` may hold only those nodes, `Problem::file_node` placing them).
    pub fn records(case: &Case, prob: &Problem) -> Result<Vec<NodeRecord>> {
        let traction = traction_load(case, &prob.mesh)?;
        let mut contact_k = vec![usize::MAX; prob.mesh.num_nodes()];
        for (k, &v) in prob.contact_nodes.iter().enumerate() {
            contact_k[v] = k;
        }
        let c = &prob.contact;
        let masters = |k: usize| prob.contact_masters.get(k).map_or(&[][..], |m| &m[..]);
        // A master node is read along the normals of its rows (as `split::split` reads it).
        let frictional = Problem::is_frictional(case);
        let mut master_read: std::collections::HashMap<usize, [bool; 2]> = Default::default();
        for (k, &m) in c.normal.iter().enumerate() {
            let comps = contact_components(frictional, m);
            for &(v, _) in masters(k) {
                let read = master_read.entry(v).or_default();
                *read = [read[0] || comps[0], read[1] || comps[1]];
            }
        }
        let record = |v: usize| -> Option<NodeRecord> {
            let fixed = [prob.fixed[2 * v], prob.fixed[2 * v + 1]];
            let traction = [traction[2 * v], traction[2 * v + 1]];
            let contact = (contact_k[v] != usize::MAX).then(|| {
                let k = contact_k[v];
                ContactRecord {
                    k: k as u64,
                    w: c.w[k],
                    g: c.g[k],
                    s: c.s[k],
                    normal: c.normal[k],
                    pair: c.pair[k],
                    part: c.part.get(k).copied().unwrap_or([u32::MAX; 2]),
                    masters: (masters(k).iter())
                        .map(|&(m, coef)| (prob.file_node[m] as u64, coef))
                        .collect(),
                }
            });
            let master = master_read.get(&v).map(|&read| MasterRecord {
                read,
                xy: prob.mesh.nodes[v],
            });
            let carries = fixed.iter().any(Option::is_some)
                || traction != [0.0, 0.0]
                || contact.is_some()
                || master.is_some();
            carries.then(|| NodeRecord {
                file: prob.file_node[v] as u64,
                fixed,
                traction,
                contact,
                master,
            })
        };
        let mut nodes: Vec<NodeRecord> = (0..prob.mesh.num_nodes()).filter_map(record).collect();
        nodes.sort_unstable_by_key(|r| r.file);
        Ok(nodes)
    }
}

/// `values` as runs of equal values: (first index, value).
fn runs(values: &[u32]) -> Vec<(u64, u32)> {
    let mut out: Vec<(u64, u32)> = Vec::new();
    for (i, &v) in values.iter().enumerate() {
        if out.last().is_none_or(|&(_, b)| b != v) {
            out.push((i as u64, v));
        }
    }
    out
}

/// The value of the run holding index `i` of [`runs`].
pub fn run_value(runs: &[(u64, u32)], i: u64) -> u32 {
    let at = runs.partition_point(|&(first, _)| first <= i);
    runs[at.saturating_sub(1)].1
}

/// The case's data a part's rank reads to build its subproblem.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PartCase {
    pub body_force: [f64; 2],
    pub frictional: bool,
}

/// One part's subproblem before the global numbering of its interface dofs, with what
/// that numbering needs.
#[derive(Debug, Clone)]
pub struct LocalPart {
    /// Complete but for the interface dofs, which `boundary_dofs` lacks (it holds the
    /// contact dofs), and `interface_global`.
    pub sub: SubProblem,
    /// Each node of the lists' (by tag): its local id.
    of_list: Vec<usize>,
    /// Each local node's index among the file's nodes, increasing, with its local id.
    by_file: Vec<(u64, usize)>,
    /// Whether each local node is on the interface.
    on_interface: Vec<bool>,
}

/// The master nodes (indices among the file's nodes, increasing) of the mortar rows of
/// the contact nodes that `lists` owns which it does not hold: its ghosts. Empty where
/// no record has a mortar row.
fn ghosts_of(lists: &PartLists, records: &[NodeRecord]) -> Vec<u64> {
    // The slave nodes with a row, and the rows' master nodes.
    let tied: Vec<(u64, &[(u64, f64)])> = (records.iter())
        .filter_map(|r| {
            let masters = &r.contact.as_ref()?.masters;
            (!masters.is_empty()).then_some((r.file, &masters[..]))
        })
        .collect();
    if tied.is_empty() {
        return Vec::new();
    }
    let mut wanted: Vec<u64> = (tied.iter())
        .flat_map(|&(f, masters)| std::iter::once(f).chain(masters.iter().map(|m| m.0)))
        .collect();
    wanted.sort_unstable();
    wanted.dedup();
    // Which of them the part holds, and whether it owns them: one walk of its nodes.
    let mut held: Vec<(u64, bool)> = (lists.file_nodes.iter().zip(&lists.owned))
        .filter(|(f, _)| wanted.binary_search(f).is_ok())
        .map(|(&f, &o)| (f, o))
        .collect();
    held.sort_unstable();
    let holds = |f: u64| {
        let i = held.binary_search_by_key(&f, |h| h.0).ok()?;
        Some(held[i].1)
    };
    let mut ghosts: Vec<u64> = (tied.iter())
        .filter(|&&(f, _)| holds(f) == Some(true))
        .flat_map(|&(_, masters)| masters.iter().map(|m| m.0))
        .filter(|&m| holds(m).is_none())
        .collect();
    ghosts.sort_unstable();
    ghosts.dedup();
    ghosts
}

/// Part `lists`'s subproblem but for its interface numbering ([`LocalPart`]), from the
/// records of the conditioned nodes (`records`, any order; those of nodes the part does
/// not hold are passed over) and the bodies' runs; `ghosts`: the part's own ghosts
/// ([`ghosts_of`]), which come last among its nodes, as `split::split` puts them, and
/// the master nodes (increasing file indices) that some part holds as a ghost, which are
/// interface nodes in every part that holds them.
/// Nodes in the Hilbert order of their coordinates and triangles in the order of their
/// nodes, as the first rank numbers the whole problem (`problem::build`), so that the
/// assembly walks memory in order whatever the file's order; triangles turned
/// counter-clockwise. Pure.
pub fn local_part(
    lists: &PartLists,
    records: &[NodeRecord],
    bodies: &[(u64, u32)],
    case: PartCase,
    (ghosts, ghosted): (&[u64], &[u64]),
) -> Result<LocalPart> {
    let n = lists.nodes.len();
    let box_ = renumber::bounding_box(&lists.xy);
    let list_of = renumber::sorted_order(&renumber::hilbert_keys(&lists.xy, box_));
    let of_list = renumber::inverse(&list_of);
    let mut by_file: Vec<(u64, usize)> = (lists.file_nodes.iter().copied())
        .zip(of_list.iter().copied())
        .collect();
    by_file.extend(ghosts.iter().enumerate().map(|(g, &f)| (f, n + g)));
    by_file.sort_unstable();
    let local_of_file = |f: u64| {
        (by_file.binary_search_by_key(&f, |x| x.0))
            .ok()
            .map(|i| by_file[i].1)
    };
    let not_held = |t: u64| {
        Error::Numerical(format!(
            "internal: part {} has a triangle on node tag {t}, which it does not hold",
            lists.part
        ))
    };
    let local_of_tag = |t: u64| -> Result<usize> {
        (lists.nodes.binary_search(&t))
            .map(|i| of_list[i])
            .map_err(|_| not_held(t))
    };
    let mut nodes: Vec<[f64; 2]> = list_of.iter().map(|&i| lists.xy[i]).collect();
    let mut owned: Vec<bool> = list_of.iter().map(|&i| lists.owned[i]).collect();
    if !ghosts.is_empty() {
        let mut masters: Vec<(u64, [f64; 2])> = (records.iter())
            .filter_map(|r| Some((r.file, r.master?.xy)))
            .collect();
        masters.sort_unstable_by_key(|m| m.0);
        for &f in ghosts {
            let i = (masters.binary_search_by_key(&f, |m| m.0)).map_err(|_| {
                Error::Numerical(format!("internal: master node {f} has no record"))
            })?;
            nodes.push(masters[i].1);
            owned.push(false);
        }
    }
    let all = nodes.len();
    // The corners' local ids by one sort of the corners and a walk along the sorted
    // tags: a search per corner took most of this function on a million triangles.
    let mut corners: Vec<(u64, usize)> = (lists.triangles.par_iter().enumerate())
        .flat_map_iter(|(i, t)| (0..3).map(move |c| (t[c], 3 * i + c)))
        .collect();
    corners.par_sort_unstable();
    let mut corner = vec![0usize; corners.len()];
    let mut at = 0;
    for (tag, slot) in corners {
        while at < n && lists.nodes[at] < tag {
            at += 1;
        }
        if at == n || lists.nodes[at] != tag {
            return Err(not_held(tag));
        }
        corner[slot] = of_list[at];
    }
    let mut listed = Vec::with_capacity(lists.triangles.len());
    for c in corner.chunks_exact(3) {
        let mut l = [c[0], c[1], c[2]];
        let [a, b, c] = l.map(|v| nodes[v]);
        if (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]) < 0.0 {
            l.swap(1, 2);
        }
        listed.push(l);
    }
    let order = renumber::order_by_nodes(&listed, n);
    let triangles: Vec<[usize; 3]> = order.iter().map(|&t| listed[t]).collect();
    let body: Vec<u32> = (order.iter())
        .map(|&t| run_value(bodies, lists.elements[t]))
        .collect();
    drop(listed);
    let mut fixed = vec![None; 2 * all];
    let mut load = vec![0.0; 2 * all];
    let mut contact: Vec<(u64, usize, &ContactRecord)> = Vec::new();
    let mut is_master = vec![false; all];
    let mut read = vec![[false; 2]; all];
    for r in records {
        let Some(v) = local_of_file(r.file) else {
            continue;
        };
        fixed[2 * v] = r.fixed[0];
        fixed[2 * v + 1] = r.fixed[1];
        if owned[v] {
            load[2 * v] += r.traction[0];
            load[2 * v + 1] += r.traction[1];
        }
        if let Some(c) = &r.contact {
            contact.push((c.k, v, c));
        }
        if let Some(m) = &r.master {
            is_master[v] = true;
            read[v] = m.read;
        }
    }
    // Every part adds its own triangles' share: the parts' loads sum to the whole's.
    add_body_force(&nodes, &triangles, case.body_force, &mut load);
    contact.sort_unstable_by_key(|c| c.0);
    let mut on_interface = vec![false; all];
    for &t in &lists.interface {
        on_interface[local_of_tag(t)?] = true;
    }
    // A master node held by a part that owns none of its rows' slave nodes is a ghost
    // there, and an interface node in every part.
    for &f in ghosted {
        if let Some(v) = local_of_file(f) {
            on_interface[v] = true;
        }
    }
    let mut frames = Vec::new();
    for &(_, v, c) in &contact {
        let held = [fixed[2 * v].is_some(), fixed[2 * v + 1].is_some()];
        // A master node does not turn: its rows read it in x, y.
        if !is_master[v] && in_frame(case.frictional, c.normal, held) {
            frames.push((v, c.normal));
            read[v] = [true, false];
        } else {
            let comps = contact_components(case.frictional, c.normal);
            read[v] = [read[v][0] || comps[0], read[v][1] || comps[1]];
        }
    }
    frames.sort_unstable_by_key(|f| f.0);
    // The own contact nodes' free dofs that no other part touches; the interface's come
    // with their global numbers.
    let mut boundary_dofs = Vec::new();
    for v in 0..all {
        for c in 0..2 {
            if read[v][c] && !on_interface[v] && fixed[2 * v + c].is_none() {
                boundary_dofs.push(2 * v + c);
            }
        }
    }
    let owned_contact: Vec<&(u64, usize, &ContactRecord)> =
        contact.iter().filter(|c| owned[c.1]).collect();
    let contact_nodes = ContactNodes {
        w: owned_contact.iter().map(|c| c.2.w).collect(),
        g: owned_contact.iter().map(|c| c.2.g).collect(),
        s: owned_contact.iter().map(|c| c.2.s).collect(),
        normal: owned_contact.iter().map(|c| c.2.normal).collect(),
        pair: owned_contact.iter().map(|c| c.2.pair).collect(),
        friction: Vec::new(),
        fixed_threshold: Vec::new(),
        part: owned_contact.iter().map(|c| c.2.part).collect(),
    };
    let contact_masters = (owned_contact.iter())
        .map(|c| {
            (c.2.masters.iter())
                .map(|&(f, coef)| {
                    let v = local_of_file(f).ok_or_else(|| {
                        Error::Numerical(format!(
                            "internal: part {} lacks master node {f}",
                            lists.part
                        ))
                    })?;
                    Ok((v, coef))
                })
                .collect::<Result<Vec<(usize, f64)>>>()
        })
        .collect::<Result<Vec<_>>>()?;
    let sub = SubProblem {
        rank: lists.part as usize,
        global_nodes: (list_of.iter().map(|&i| lists.file_nodes[i]))
            .chain(ghosts.iter().copied())
            .map(|f| f as usize)
            .collect(),
        nodes,
        body,
        triangles,
        owned,
        fixed,
        load,
        contact_nodes: owned_contact.iter().map(|c| c.1).collect(),
        contact: contact_nodes,
        n_contact_dofs: boundary_dofs.len(),
        boundary_dofs,
        interface_global: Vec::new(),
        interface_nodes: lists.interface.len(),
        frames,
        contact_masters,
        ghosts: ghosts.len(),
    };
    Ok(LocalPart {
        sub,
        of_list,
        by_file,
        on_interface,
    })
}

impl LocalPart {
    /// The local id of the node at index `f` among the file's nodes, if the part holds
    /// it (a ghost too).
    fn local_of_file(&self, f: u64) -> Option<usize> {
        let i = self.by_file.binary_search_by_key(&f, |x| x.0).ok()?;
        Some(self.by_file[i].1)
    }
}

/// The free dofs of the interface nodes that `part` owns, by increasing file index then
/// component: (local node, component).
fn owned_interface_dofs(part: &LocalPart) -> Vec<(usize, usize)> {
    let sub = &part.sub;
    (part.by_file.iter())
        .map(|&(_, v)| v)
        .filter(|&v| sub.owned[v] && part.on_interface[v])
        .flat_map(|v| [(v, 0), (v, 1)])
        .filter(|&(v, c)| sub.fixed[2 * v + c].is_none())
        .collect()
}

/// Each rank's subproblems (`lists`: its parts, the same number k on every rank, part
/// `rank * k + j` at j, as the run's subdomains) from their lists and the first rank's
/// `conditions` (sent to every rank), with the global map. The interface dofs are
/// numbered part after part, each part's by file index and component; each part tells
/// its neighbours the numbers of the shared nodes it owns (through the exchange where
/// they are on another rank). Collective; before any team of subdomains exists.
pub fn build(
    mpi: &Mpi,
    lists: &[PartLists],
    conditions: Option<Conditions>,
    case: PartCase,
) -> Result<(Vec<SubProblem>, GlobalMap)> {
    let (p, k) = (mpi.size, lists.len());
    let conditions = match p {
        1 => conditions.unwrap_or_default(),
        _ => mpi.broadcast(conditions)?,
    };
    // The ghosts of every part, known to every part: boundary-sized.
    let ghosts: Vec<Vec<u64>> = (lists.iter())
        .map(|l| ghosts_of(l, &conditions.nodes))
        .collect();
    let mut ghosted = mpi.exchange(vec![ghosts.concat(); p]).concat();
    ghosted.sort_unstable();
    ghosted.dedup();
    let parts = mpi.agree(
        (lists.iter().zip(&ghosts))
            .map(|(l, own)| {
                let nodes = &conditions.nodes;
                local_part(l, nodes, &conditions.bodies, case, (own, &ghosted))
            })
            .collect::<Result<Vec<LocalPart>>>(),
    )?;
    drop(conditions);

    let own: Vec<Vec<(usize, usize)>> = parts.iter().map(owned_interface_dofs).collect();
    let counts = per_part(mpi, own.iter().map(Vec::len), k);
    let before = mpi.rank * k;
    let n_interface: usize = counts.iter().sum();
    let mut number: Vec<Vec<[u64; 2]>> = (parts.iter())
        .map(|part| vec![[u64::MAX; 2]; part.sub.nodes.len()])
        .collect();
    for (j, own) in own.iter().enumerate() {
        let first: usize = counts[..before + j].iter().sum();
        for (i, &(v, c)) in own.iter().enumerate() {
            number[j][v][c] = (first + i) as u64;
        }
    }
    let local_of_tag =
        |j: usize, t: u64| (lists[j].nodes.binary_search(&t).ok()).map(|i| parts[j].of_list[i]);
    // To each neighbour's rank, the numbers of the shared nodes a part owns: the tag,
    // then the global numbers of its x and y dofs (u64::MAX where prescribed); those for
    // a part on this rank kept here.
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    let mut here: Vec<u64> = Vec::new();
    for (j, list) in lists.iter().enumerate() {
        for (q, tags) in &list.neighbours {
            let rank = (*q as usize / k).min(p - 1);
            for &t in tags {
                let v = local_of_tag(j, t).ok_or_else(|| {
                    Error::Numerical(format!(
                        "internal: a shared node tag {t} is not in its part"
                    ))
                })?;
                if parts[j].sub.owned[v] {
                    let to = if rank == mpi.rank {
                        &mut here
                    } else {
                        &mut send[rank]
                    };
                    to.extend_from_slice(&[t, number[j][v][0], number[j][v][1]]);
                }
            }
        }
    }
    let mut got = mpi.exchange(send);
    got.push(here);
    for r in got.iter().flat_map(|g| g.chunks_exact(3)) {
        for (j, number) in number.iter_mut().enumerate() {
            if let Some(v) = local_of_tag(j, r[0]) {
                if !parts[j].sub.owned[v] {
                    number[v] = [r[1], r[2]];
                }
            }
        }
    }
    // A ghost's part need not touch its owner's: the owners tell every rank the numbers
    // of the master nodes that are ghosts somewhere (by file index).
    if !ghosted.is_empty() {
        let mut told: Vec<u64> = Vec::new();
        for (part, number) in parts.iter().zip(&number) {
            for &f in &ghosted {
                if let Some(v) = part.local_of_file(f).filter(|&v| part.sub.owned[v]) {
                    told.extend_from_slice(&[f, number[v][0], number[v][1]]);
                }
            }
        }
        let told = mpi.exchange(vec![told; p]).concat();
        for (part, number) in parts.iter().zip(&mut number) {
            for r in told.chunks_exact(3) {
                if let Some(v) = part.local_of_file(r[0]).filter(|&v| !part.sub.owned[v]) {
                    number[v] = [r[1], r[2]];
                }
            }
        }
    }
    let mut missing = false;
    let mut subs = Vec::with_capacity(k);
    for (part, number) in parts.into_iter().zip(&number) {
        let mut interface: Vec<(usize, usize)> = Vec::new();
        for v in (0..part.sub.nodes.len()).filter(|&v| part.on_interface[v]) {
            for c in 0..2 {
                if part.sub.fixed[2 * v + c].is_none() {
                    match number[v][c] {
                        u64::MAX => missing = true,
                        b => interface.push((b as usize, 2 * v + c)),
                    }
                }
            }
        }
        let mut sub = part.sub;
        interface.sort_unstable();
        let (global, dofs): (Vec<usize>, Vec<usize>) = interface.into_iter().unzip();
        sub.interface_global = global;
        sub.boundary_dofs.extend(dofs);
        subs.push(sub);
    }
    if !mpi.all_ok(!missing) {
        return Err(Error::Numerical(
            "internal: an interface dof has no global number".into(),
        ));
    }
    let contact_counts = per_part(mpi, subs.iter().map(|s| s.contact_nodes.len()), k);
    let contact_dofs: usize = per_part(mpi, subs.iter().map(|s| s.n_contact_dofs), k)
        .iter()
        .sum();
    Ok((
        subs,
        GlobalMap {
            n_interface,
            n_boundary: n_interface + contact_dofs,
            contact_counts,
        },
    ))
}

/// Every part's count (`k` parts on every rank, this rank's in `mine`), in part order.
fn per_part(mpi: &Mpi, mine: impl Iterator<Item = usize>, k: usize) -> Vec<usize> {
    let local: Vec<f64> = mine.map(|c| c as f64).collect();
    let mut all = Vec::new();
    mpi.all_gather(&local, &vec![k; mpi.size], &mut all);
    all.into_iter().map(|c| c as usize).collect()
}

/// The partition's figures (`partition::Quality`) from every rank's parts (`subs`), the
/// interface's figures and the edge cut found on the ranks: a part's pieces are its
/// triangles joined through shared nodes, as where the first rank takes the cut from
/// elsewhere. Collective.
pub fn quality(
    mpi: &Mpi,
    subs: &[SubProblem],
    figures: &InterfaceFigures,
    edge_cut: usize,
) -> Quality {
    let k = subs.len();
    let sizes = per_part(mpi, subs.iter().map(|s| s.triangles.len()), k);
    let pieces = subs
        .iter()
        .map(|s| usize::from(node_pieces(&s.triangles) > 1));
    let disconnected = per_part(mpi, pieces, k);
    let num_elements: usize = sizes.iter().sum();
    let max_part_elements = sizes.iter().copied().max().unwrap_or(0);
    let mean = num_elements as f64 / sizes.len().max(1) as f64;
    Quality {
        nparts: sizes.len(),
        num_elements,
        edge_cut,
        min_part_elements: sizes.iter().copied().min().unwrap_or(0),
        max_part_elements,
        imbalance: if mean > 0.0 {
            max_part_elements as f64 / mean
        } else {
            1.0
        },
        interface_nodes: figures.interface_nodes,
        max_part_interface_nodes: figures.per_part.iter().copied().max().unwrap_or(0),
        neighbours: figures.neighbours.clone(),
        disconnected_parts: disconnected.iter().sum(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_find_the_value_of_every_index() {
        let values = [0, 0, 1, 1, 1, 0, 2];
        let r = runs(&values);
        assert_eq!(r, vec![(0, 0), (2, 1), (5, 0), (6, 2)]);
        for (i, &v) in values.iter().enumerate() {
            assert_eq!(run_value(&r, i as u64), v);
        }
    }

    /// Two triangles of the unit square, one listed clockwise; the part holds them both
    /// and owns every node; a contact node and a fixed node.
    #[test]
    fn a_part_turns_its_triangles_and_keeps_its_conditions() {
        let lists = PartLists {
            part: 0,
            elements: vec![0, 1],
            triangles: vec![[10, 20, 30], [10, 40, 30]],
            nodes: vec![10, 20, 30, 40],
            file_nodes: vec![3, 2, 1, 0],
            xy: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            owned: vec![true; 4],
            interface: Vec::new(),
            neighbours: Vec::new(),
        };
        let records = vec![
            NodeRecord {
                file: 2,
                fixed: [None, None],
                traction: [0.0, 1.0],
                contact: Some(ContactRecord {
                    k: 0,
                    w: 0.5,
                    g: 0.0,
                    s: 1.0,
                    normal: [0.0, 1.0],
                    pair: 0,
                    part: [0, u32::MAX],
                    masters: Vec::new(),
                }),
                master: None,
            },
            NodeRecord {
                file: 3,
                fixed: [Some(0.0), Some(0.0)],
                traction: [0.0, 0.0],
                contact: None,
                master: None,
            },
        ];
        let case = PartCase {
            body_force: [0.0, -3.0],
            frictional: false,
        };
        let part =
            local_part(&lists, &records, &[(0, 0), (1, 1)], case, (&[], &[])).expect("a part");
        let sub = &part.sub;
        let local = |f: usize| sub.global_nodes.iter().position(|&g| g == f).unwrap();
        let area2 = |t: &[usize; 3]| {
            let [a, b, c] = t.map(|v| sub.nodes[v]);
            (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        };
        let mut by_file: Vec<([usize; 3], u32)> = (sub.triangles.iter().zip(&sub.body))
            .map(|(t, &b)| {
                assert!(area2(t) > 0.0, "{t:?} counter-clockwise");
                let mut f = t.map(|v| sub.global_nodes[v]);
                f.sort_unstable();
                (f, b)
            })
            .collect();
        by_file.sort_unstable();
        // Tags 10, 20, 30, 40 are file nodes 3, 2, 1, 0.
        assert_eq!(by_file, vec![([0, 1, 3], 1), ([1, 2, 3], 0)]);
        let (c, f) = (local(2), local(3));
        assert_eq!(sub.nodes[c], [1.0, 0.0]);
        assert_eq!(sub.fixed[2 * f..2 * f + 2], [Some(0.0), Some(0.0)]);
        assert_eq!(sub.contact_nodes, vec![c]);
        // Frictionless along y: only uy is read.
        assert_eq!(sub.boundary_dofs, vec![2 * c + 1]);
        assert_eq!(sub.n_contact_dofs, 1);
        // Body force: area 1 shared among 6 corners; the traction at the contact node.
        let total: f64 = sub.load.iter().skip(1).step_by(2).sum();
        assert!((total - (1.0 - 3.0)).abs() < 1e-15, "{total}");
        // A record of a node the part does not hold is passed over.
        let stray = NodeRecord {
            file: 9,
            ..records[1].clone()
        };
        let without = local_part(&lists, &[stray], &[(0, 0)], case, (&[], &[])).expect("a part");
        assert!(without.sub.fixed.iter().all(Option::is_none));
    }
}
