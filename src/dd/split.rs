//! Splitting the global problem into one subproblem per rank (pure: no MPI).
//!
//! The boundary dofs B are the free dofs of every interface node (touched by several
//! parts) and of every contact node. They are numbered globally in increasing
//! (node, component) order; every rank orders its own boundary dofs last, in that order.

use crate::contact::ContactNodes;
use crate::error::{Error, Result};
use crate::problem::Problem;
use partition::Partition;
use serde::{Deserialize, Serialize};

/// Everything one rank needs, and nothing of the others' parts.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
pub struct SubProblem {
    pub rank: usize,
    /// Global id of each local node (increasing).
    pub global_nodes: Vec<usize>,
    pub nodes: Vec<[f64; 2]>,
    /// Triangles in local node numbering.
    pub triangles: Vec<[usize; 3]>,
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
    /// Local dofs (2 * local node + c) in B, by increasing global B index.
    pub boundary_dofs: Vec<usize>,
    /// Global B index of each of `boundary_dofs`.
    pub boundary_global: Vec<usize>,
    /// Local nodes shared with another part.
    pub interface_nodes: usize,
}

/// How a contact node's normal and tangential displacements read the boundary vector.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct ContactDof {
    /// Global B index of the x and y dofs, `None` when prescribed.
    pub b: [Option<usize>; 2],
    /// Prescribed x and y values (0 when free).
    pub fixed: [f64; 2],
}

/// The global numbering shared by all ranks, known in full on the first rank only.
#[derive(Debug, Clone)]
pub struct GlobalMap {
    /// Number of boundary dofs.
    pub n_boundary: usize,
    /// Contact nodes in sweep order: by owning rank, then by global node id.
    pub contact_order: Vec<usize>,
    /// Index into `Problem::contact_nodes` of each entry of `contact_order`.
    pub contact_index: Vec<usize>,
    pub contact_dofs: Vec<ContactDof>,
    /// Own contact nodes per rank (the counts of the per-sweep all-gather).
    pub contact_counts: Vec<usize>,
}

/// Splits `prob` by `part`.
pub fn split(prob: &Problem, part: &Partition) -> Result<(Vec<SubProblem>, GlobalMap)> {
    let n = prob.mesh.num_nodes();
    let nparts = part.nparts;
    let mut is_contact = vec![false; n];
    for &c in &prob.contact_nodes {
        is_contact[c] = true;
    }
    let mut in_b = is_contact.clone();
    for p in &part.parts {
        for &v in &p.interface {
            in_b[v] = true;
        }
    }
    let mut b_index: Vec<[Option<usize>; 2]> = vec![[None; 2]; n];
    let mut n_boundary = 0;
    for v in 0..n {
        if !in_b[v] {
            continue;
        }
        for c in 0..2 {
            if prob.fixed[2 * v + c].is_none() {
                b_index[v][c] = Some(n_boundary);
                n_boundary += 1;
            }
        }
    }

    let owner = |v: usize| part.node_owner[v] as usize;
    let mut contact_by_rank: Vec<Vec<usize>> = vec![Vec::new(); nparts];
    for (k, &c) in prob.contact_nodes.iter().enumerate() {
        contact_by_rank[owner(c)].push(k);
    }
    let contact_index: Vec<usize> = contact_by_rank.iter().flatten().copied().collect();
    let contact_order: Vec<usize> = contact_index
        .iter()
        .map(|&k| prob.contact_nodes[k])
        .collect();
    let contact_dofs = contact_order
        .iter()
        .map(|&v| ContactDof {
            b: b_index[v],
            fixed: [
                prob.fixed[2 * v].unwrap_or(0.0),
                prob.fixed[2 * v + 1].unwrap_or(0.0),
            ],
        })
        .collect();

    let mut local_of = vec![usize::MAX; n];
    let mut subs = Vec::with_capacity(nparts);
    for (r, p) in part.parts.iter().enumerate() {
        for (l, &g) in p.nodes.iter().enumerate() {
            local_of[g] = l;
        }
        let triangles: Vec<[usize; 3]> = p
            .elements
            .iter()
            .map(|&e| prob.mesh.triangles[e].map(|g| local_of[g]))
            .collect();
        let owned: Vec<bool> = p.nodes.iter().map(|&g| owner(g) == r).collect();
        let mut fixed = Vec::with_capacity(2 * p.nodes.len());
        let mut load = Vec::with_capacity(2 * p.nodes.len());
        let mut boundary_dofs = Vec::new();
        let mut boundary_global = Vec::new();
        for (l, &g) in p.nodes.iter().enumerate() {
            for c in 0..2 {
                fixed.push(prob.fixed[2 * g + c]);
                load.push(if owned[l] { prob.load[2 * g + c] } else { 0.0 });
                if let Some(b) = b_index[g][c] {
                    boundary_dofs.push(2 * l + c);
                    boundary_global.push(b);
                }
            }
        }
        let mine = &contact_by_rank[r];
        let sub = SubProblem {
            rank: r,
            global_nodes: p.nodes.clone(),
            nodes: p.nodes.iter().map(|&g| prob.mesh.nodes[g]).collect(),
            triangles,
            owned,
            fixed,
            load,
            contact_nodes: mine
                .iter()
                .map(|&k| local_of[prob.contact_nodes[k]])
                .collect(),
            contact: ContactNodes {
                w: mine.iter().map(|&k| prob.contact.w[k]).collect(),
                g: mine.iter().map(|&k| prob.contact.g[k]).collect(),
            },
            boundary_dofs,
            boundary_global,
            interface_nodes: p.interface.len(),
        };
        if sub.contact_nodes.contains(&usize::MAX) {
            return Err(Error::Numerical(format!(
                "internal: rank {r} owns a contact node it does not hold"
            )));
        }
        subs.push(sub);
        for &g in &p.nodes {
            local_of[g] = usize::MAX;
        }
    }
    Ok((
        subs,
        GlobalMap {
            n_boundary,
            contact_order,
            contact_index,
            contact_dofs,
            contact_counts: contact_by_rank.iter().map(Vec::len).collect(),
        },
    ))
}
