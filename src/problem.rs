//! From a validated case and a mesh to the discrete problem: oriented mesh, prescribed
//! dofs, load vector, contact nodes with their lumped weights and gaps. Everything that
//! needs the whole mesh happens here, once, on the reading rank.

use crate::case::Case;
use crate::contact::mortar::{mortar_rows, MortarRow, Segment};
use crate::contact::obstacle::{NodeGeometry, Obstacle};
use crate::contact::{tangent_of, ContactNodes, Friction};
use crate::error::{input, Error, Result};
use crate::fem::assembly::{add_body_force, add_edge_traction, edge_length};
use crate::fem::{Hypothesis, Material};
use crate::mesh::validate::{self, ContactHold, Free, Holds};
use crate::mesh::{renumber, Mesh};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::{HashMap, HashSet};

/// What tells, at the answer, whether each separate part of the mesh is held (see
/// [`free_at_answer`]): its Dirichlet conditions as lines of action, and a node of it to
/// name it by.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Holding {
    pub dirichlet: Vec<Holds>,
    pub first: Vec<[f64; 2]>,
}

/// The part of the master nodes of a node against an obstacle (`ContactNodes::part`).
pub const NO_PART: u32 = u32::MAX;

/// A contact node at the answer, as [`free_at_answer`] reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeAtAnswer {
    /// Its part and its master nodes' ([`NO_PART`] against an obstacle).
    pub part: [u32; 2],
    pub at: [f64; 2],
    pub normal: [f64; 2],
    pub pressed: bool,
    pub sticks: bool,
}

/// The parts of the mesh that the answer leaves free to move rigidly without work, one
/// message each. Before the run every contact node counts as holding ([`check_held`]);
/// at the answer only a pressed node holds along its normal and a sticking one along its
/// tangent (an open node is free, a slipping one carries its threshold whatever the
/// slip). A rigid motion that the Dirichlet conditions and those lines leave free moves
/// the body at no cost until an open node touches, so the answer is one of many along
/// it: an iterative method drifts along such a motion, and two runs may differ along it
/// by far more than `tol`.
pub fn free_at_answer(holding: &Holding, nodes: &[NodeAtAnswer]) -> Vec<String> {
    let count = holding.dirichlet.len();
    let known = |p: u32| (p as usize) < count;
    if count == 0
        || !nodes
            .iter()
            .all(|n| known(n.part[0]) && (n.part[1] == NO_PART || known(n.part[1])))
    {
        return Vec::new();
    }
    let rows: Vec<ContactHold> = (nodes.iter().filter(|n| n.pressed))
        .map(|n| ContactHold {
            part: n.part[0] as usize,
            master: (n.part[1] != NO_PART).then_some(n.part[1] as usize),
            at: n.at,
            normal: n.normal,
            tangent: n.sticks,
        })
        .collect();
    let mut holds = holding.dirichlet.clone();
    validate::hold_parts(&mut holds, &rows);
    let with_friction = nodes.iter().any(|n| n.sticks);
    let by = match with_friction {
        true => "its Dirichlet conditions, its pressed contact nodes' normals and its sticking nodes' tangents",
        false => "its Dirichlet conditions and its pressed contact nodes' normals",
    };
    (holds.iter().enumerate())
        .filter_map(|(p, h)| Some((p, h.free()?)))
        .map(|(p, free)| {
            let body = match count {
                1 => "the body".to_string(),
                _ => format!("the part of the mesh with the node at ({}, {})", holding.first[p][0], holding.first[p][1]),
            };
            let (motion, fix) = match free {
                Free::Turn { centre } => (
                    format!("turn about ({}, {})", centre[0], centre[1]),
                    format!("fix ux or uy at a node away from ({}, {})", centre[0], centre[1]),
                ),
                Free::Slide { along } => (
                    format!("slide along ({}, {})", along[0], along[1]),
                    format!("fix {} at a node", component(along)),
                ),
                Free::SlideAndTurn { .. } | Free::Everything => {
                    ("move rigidly".to_string(), "fix ux and uy at a node".to_string())
                }
            };
            format!(
                "at the answer {body} is held only by {by}, and these leave it free to {motion} without work until an open contact node touches: the answer is one of many along that motion (runs may differ along it by far more than tol); {fix} with a [[dirichlet]] condition, or give the contact friction"
            )
        })
        .collect()
}

/// The discrete problem on the whole mesh.
#[derive(Debug, Clone)]
pub struct Problem {
    pub mesh: Mesh,
    /// Prescribed value of each dof, `None` when free.
    pub fixed: Vec<Option<f64>>,
    /// Load vector (tractions + body force), one entry per dof.
    pub load: Vec<f64>,
    /// Global node ids of the contact nodes, increasing.
    pub contact_nodes: Vec<usize>,
    /// Weights, normals and gaps of `contact_nodes`, same order.
    pub contact: ContactNodes,
    /// The master nodes and coefficients of each contact node's mortar row
    /// (`contact::mortar`), same order; empty for a node against an obstacle.
    pub contact_masters: Vec<Vec<(usize, f64)>>,
    /// Mean length of the contact edges.
    pub contact_h: f64,
    /// The mesh file's index of each node (the row of `nodes.csv`): the nodes are
    /// numbered along a Hilbert curve once the problem is built ([`renumber`]).
    pub file_node: Vec<usize>,
    /// Each triangle's body: the index of its entry in `Case::materials`.
    pub body: Vec<u32>,
    /// The bodies of the triangles that touch a contact node, increasing: the scales of
    /// r are theirs ([`contact_modulus`]).
    pub contact_bodies: Vec<u32>,
    /// The separate parts' Dirichlet conditions, for the check of the answer.
    pub holding: Holding,
}

impl Problem {
    /// Default augmentation parameter r = E_eff / sqrt(h L), h the mean contact edge
    /// length and L the smaller side of the body's bounding box.
    ///
    /// Why: seen from the contact boundary, an elastic body is stiff like E/L for smooth
    /// modes and like E/h for mesh-scale ones; the Uzawa/ADMM iteration converges fastest
    /// when r w_i sits between the two, and the geometric mean balances the primal and
    /// dual contraction, so that the sweep count grows like sqrt(L/h) instead of L/h
    /// (r = E/h) or worse. Measured on the built-in cases at four levels: within 1.3x of
    /// the best r of a sweep over two decades (see the note of the core issue).
    pub fn default_r(&self, case: &Case) -> f64 {
        (self.lengths()).default_r(contact_modulus(case, &self.contact_bodies))
    }

    /// The mesh's two lengths behind r: h, and L the smaller side of the bounding box.
    pub fn lengths(&self) -> Lengths {
        Lengths::of(validate::bounding_box(&self.mesh.nodes), self.contact_h)
    }

    pub fn is_frictional(case: &Case) -> bool {
        !matches!(case.friction(), Friction::None)
    }
}

/// `nodes` with each node's friction value (Coulomb coefficient or Tresca threshold) from
/// its contact's law, where the contacts give different values; otherwise as they are,
/// the one value of `Case::friction` serving every node. Where Tresca and Coulomb
/// contacts are mixed, `friction` holds the coefficients and `fixed_threshold` the
/// thresholds (each 0 at the other law's nodes).
pub fn with_friction_values(case: &Case, nodes: &ContactNodes) -> ContactNodes {
    if case.mixed_friction() {
        let mut out = nodes.clone();
        let law = |p: &u32| case.contacts[*p as usize].friction;
        out.friction = (nodes.pair.iter())
            .map(|p| match law(p) {
                Friction::Coulomb { coefficient } => coefficient,
                _ => 0.0,
            })
            .collect();
        out.fixed_threshold = (nodes.pair.iter())
            .map(|p| match law(p) {
                Friction::Tresca { threshold } => threshold,
                _ => 0.0,
            })
            .collect();
        return out;
    }
    let value = |f: Friction| match f {
        Friction::None => 0.0,
        Friction::Tresca { threshold } => threshold,
        Friction::Coulomb { coefficient } => coefficient,
    };
    let first = value(case.friction());
    let mut out = nodes.clone();
    if case.contacts.iter().any(|c| value(c.friction) != first) {
        out.friction = (nodes.pair.iter())
            .map(|&p| value(case.contacts[p as usize].friction))
            .collect();
    }
    out
}

/// The two lengths of the mesh that set the default r (kept in a split directory, so that
/// a run from it needs no mesh and may change the material).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Lengths {
    /// Mean length of the contact edges, h.
    pub contact_h: f64,
    /// The smaller side of the body's bounding box, L (at least h).
    pub compact: f64,
}

impl Lengths {
    /// The lengths of a mesh in the box `(lo, hi)` with contact edges `contact_h` long
    /// on average.
    pub fn of((lo, hi): ([f64; 2], [f64; 2]), contact_h: f64) -> Lengths {
        Lengths {
            contact_h,
            compact: (hi[0] - lo[0]).min(hi[1] - lo[1]).max(contact_h),
        }
    }

    /// See [`Problem::default_r`]; `e_eff` from [`contact_modulus`].
    pub fn default_r(&self, e_eff: f64) -> f64 {
        (self.mesh_stiffness(e_eff) * self.compact_stiffness(e_eff)).sqrt()
    }

    /// E_eff / h: how stiff the body is, seen from the contact boundary, for modes at the
    /// scale of the mesh (the stiffest).
    pub fn mesh_stiffness(&self, e_eff: f64) -> f64 {
        e_eff / self.contact_h
    }

    /// E_eff / L: how stiff a compact body is for smooth modes (the softest). A slender
    /// body is far softer (it bends): the loop measures that and lowers r (see
    /// `contact::probe`).
    pub fn compact_stiffness(&self, e_eff: f64) -> f64 {
        e_eff / self.compact
    }
}

/// The modulus of a plane problem: E / (1 - nu^2) in plane strain, E in plane stress.
pub fn effective_modulus(m: &Material) -> f64 {
    match m.hypothesis {
        Hypothesis::PlaneStrain => m.young / (1.0 - m.poisson * m.poisson),
        Hypothesis::PlaneStress => m.young,
    }
}

/// The E_eff behind r and its floors: the largest among `bodies`, those touching the
/// contact nodes (every body's when none is given).
///
/// Why the largest: r sits between the stiffnesses the contact boundary shows (see
/// [`Problem::default_r`]), and the retune floors (E_eff / h) keep a held node's r above
/// its local stiffness. A node on the interface of a soft and a stiff body is held by
/// the stiff one's elements, and an r below that stiffness lets the iteration crawl,
/// while one a material ratio too high only costs sweeps in proportion. Only the bodies
/// at the contact count: a stiff body away from it does not change what the contact
/// sees. One material gives the one-material value, bit for bit.
pub fn contact_modulus(case: &Case, bodies: &[u32]) -> f64 {
    let all: Vec<u32> = (0..case.materials.len() as u32).collect();
    let bodies = if bodies.is_empty() { &all[..] } else { bodies };
    (bodies.iter())
        .map(|&b| effective_modulus(&case.materials[b as usize].material))
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Each triangle's body (its `[[material]]` entry), every triangle in exactly one; a lone
/// `[material]` is body 0 everywhere.
fn bodies(case: &Case, mesh: &Mesh) -> Result<Vec<u32>> {
    const NONE: u32 = u32::MAX;
    let nt = mesh.triangles.len();
    if case.materials.iter().all(|b| b.group.is_none()) {
        return Ok(vec![0; nt]);
    }
    let origin = &case.origin;
    let centroid = |t: usize| {
        let p = mesh.triangles[t].map(|v| mesh.nodes[v]);
        [0, 1].map(|c| (p[0][c] + p[1][c] + p[2][c]) / 3.0)
    };
    let mut body = vec![NONE; nt];
    for (i, b) in case.materials.iter().enumerate() {
        let g = b.group.as_deref().unwrap_or_default();
        let Some(tris) = mesh.surface_groups.get(g) else {
            return input(not_a_surface_message(origin, g, mesh));
        };
        for &t in tris {
            if body[t] != NONE {
                let other = case.materials[body[t] as usize]
                    .group
                    .as_deref()
                    .unwrap_or_default();
                return input(two_materials_message(origin, centroid(t), other, g));
            }
            body[t] = i as u32;
        }
    }
    if let Some(t) = body.iter().position(|&b| b == NONE) {
        let missing = body.iter().filter(|&&b| b == NONE).count();
        let theirs = (mesh.surface_groups.iter())
            .find(|(_, tris)| tris.binary_search(&t).is_ok())
            .map(|(k, _)| k.as_str());
        return input(no_material_message(origin, missing, centroid(t), theirs));
    }
    Ok(body)
}

/// A `[[material]]` group `g` that is no surface group of `mesh` (whose groups alone
/// matter).
fn not_a_surface_message(origin: &str, g: &str, mesh: &Mesh) -> String {
    let what = if mesh.line_groups.contains_key(g) || mesh.point_groups.contains_key(g) {
        "is a line or point group; a material needs a surface group"
    } else {
        "is not a surface group of the mesh"
    };
    let names: Vec<&str> = mesh.surface_groups.keys().map(String::as_str).collect();
    let surfaces = if names.is_empty() {
        "the mesh has no physical surface groups; put each body's surface in a physical group in Gmsh".into()
    } else {
        format!("surface groups in the mesh: {}", names.join(", "))
    };
    format!("{origin}: [[material]] group \"{g}\" {what}; {surfaces}")
}

/// A triangle, centroid `x`, in the groups of two materials.
fn two_materials_message(origin: &str, x: [f64; 2], other: &str, g: &str) -> String {
    format!(
        "{origin}: the triangle at ({}, {}) is in both [[material]] groups \"{other}\" and \"{g}\"; each triangle takes one material: give the bodies disjoint physical surfaces",
        x[0], x[1]
    )
}

/// `missing` triangles in no material's group, the first at `x`, in the surface group
/// `theirs` (its first by name) if any.
fn no_material_message(origin: &str, missing: usize, x: [f64; 2], theirs: Option<&str>) -> String {
    let fix = match theirs {
        Some(g) => format!("add a [[material]] with group = \"{g}\""),
        None => "put it in a physical surface group of the mesh and give that group a [[material]]"
            .to_string(),
    };
    format!(
        "{origin}: {missing} triangle(s), one at ({}, {}), are in no [[material]] group; every triangle needs a material: {fix}",
        x[0], x[1]
    )
}

/// The bodies of the triangles that touch `nodes`, increasing and without repeats.
fn touching(mesh: &Mesh, body: &[u32], nodes: &[usize]) -> Vec<u32> {
    // A scan of every triangle: on the pool, where it ran on one core of the first
    // rank's start (15-20 ms at 1M nodes) while the other waited.
    let is_node = crate::mesh::bit_set(mesh.num_nodes(), nodes);
    let mut out: Vec<u32> = (mesh.triangles.par_iter().zip(body))
        .filter(|(t, _)| t.iter().any(|&v| crate::mesh::in_set(&is_node, v)))
        .map(|(_, &b)| b)
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// The closest existing group name, for "did you mean" hints.
fn suggest(name: &str, mesh: &Mesh) -> String {
    let best = mesh
        .group_names()
        .into_iter()
        .map(|g| {
            (
                strsim::levenshtein(&name.to_lowercase(), &g.to_lowercase()),
                g,
            )
        })
        .min();
    let all = mesh.group_names().join(", ");
    match best {
        Some((d, g)) if d <= name.len().max(3) / 2 + 1 => {
            format!("did you mean \"{g}\"? (groups in the mesh: {all})")
        }
        _ if all.is_empty() => "the mesh has no named groups; add physical groups in Gmsh".into(),
        _ => format!("groups in the mesh: {all}"),
    }
}

fn group_nodes(case: &Case, mesh: &Mesh, what: &str, name: &str) -> Result<Vec<usize>> {
    mesh.group_nodes(name).ok_or_else(|| {
        Error::Input(format!(
            "{}: {what} group \"{name}\" is not in the mesh; {}",
            case.origin,
            suggest(name, mesh)
        ))
    })
}

fn line_group<'a>(case: &Case, mesh: &'a Mesh, what: &str, name: &str) -> Result<&'a [[usize; 2]]> {
    match mesh.line_groups.get(name) {
        Some(lines) if !lines.is_empty() => Ok(lines),
        Some(_) => input(format!(
            "{}: {what} group \"{name}\" has no line elements; put its curves in the physical group and mesh again",
            case.origin
        )),
        None if mesh.point_groups.contains_key(name) => input(format!(
            "{}: {what} group \"{name}\" is a point group; it needs a group of boundary lines",
            case.origin
        )),
        None => input(format!(
            "{}: {what} group \"{name}\" is not in the mesh; {}",
            case.origin,
            suggest(name, mesh)
        )),
    }
}

/// Builds the discrete problem; `mesh_name` names the mesh in messages.
///
/// Everything that can be wrong with the input is reported here, before any assembly:
/// the mesh checks of [`validate::check_with`], the groups, the contact boundary and gaps, and
/// last whether the conditions hold every part of the body ([`check_held`]).
pub fn build(case: &Case, mut mesh: Mesh, mesh_name: &str) -> Result<Problem> {
    let (boundary, parts) = validate::check_with(&mut mesh, mesh_name, Parts::of)?;
    let conditioned = conditioned(case, &mesh, &boundary, &parts)?;
    // Checked here so that every fault of the input is reported before any work; the
    // bodies are found again in the new numbering below.
    bodies(case, &mesh)?;
    let mut prob = in_locality_order(conditioned.on(mesh));
    prob.body = bodies(case, &prob.mesh)?;
    let mut at_contact = prob.contact_nodes.clone();
    at_contact.extend(prob.contact_masters.iter().flatten().map(|m| m.0));
    prob.contact_bodies = touching(&prob.mesh, &prob.body, &at_contact);
    // Summed in the new numbering's triangle order: a node's share of the body force
    // comes from several triangles, and summed in the file's order the load (and the
    // answer, by a rounding) would depend on the order the mesher wrote them in.
    let mut load = traction_load(case, &prob.mesh)?;
    add_body_force(
        &prob.mesh.nodes,
        &prob.mesh.triangles,
        case.body_force,
        &mut load,
    );
    prob.load = load;
    Ok(prob)
}

/// The conditions of a problem on its mesh.
struct Conditioned {
    fixed: Vec<Option<f64>>,
    contact_nodes: Vec<usize>,
    contact: ContactNodes,
    contact_h: f64,
    contact_masters: Vec<Vec<(usize, f64)>>,
    holding: Holding,
}

impl Conditioned {
    /// The problem on `mesh` with these conditions, in the file's numbering; without
    /// loads and bodies.
    fn on(self, mesh: Mesh) -> Problem {
        Problem {
            file_node: (0..mesh.num_nodes()).collect(),
            mesh,
            fixed: self.fixed,
            load: Vec::new(),
            contact_nodes: self.contact_nodes,
            contact: self.contact,
            contact_masters: self.contact_masters,
            contact_h: self.contact_h,
            body: Vec::new(),
            contact_bodies: Vec::new(),
            holding: self.holding,
        }
    }
}

/// The prescribed dofs, the traction groups' check, the contact nodes and their
/// geometry, and the check that the conditions hold every part (`boundary`: the mesh's
/// boundary edges; `parts`: its separate parts).
fn conditioned(
    case: &Case,
    mesh: &Mesh,
    boundary: &HashSet<(usize, usize)>,
    parts: &Parts,
) -> Result<Conditioned> {
    let mut fixed: Vec<Option<f64>> = vec![None; 2 * mesh.num_nodes()];
    for d in &case.dirichlet {
        for node in group_nodes(case, mesh, "dirichlet", &d.group)? {
            for (c, v) in [d.ux, d.uy].into_iter().enumerate() {
                if let Some(v) = v {
                    fixed[2 * node + c] = Some(v);
                }
            }
        }
    }
    for t in &case.traction {
        line_group(case, mesh, "traction", &t.group)?;
    }
    let ContactGeometry {
        nodes: contact_nodes,
        mut contact,
        h: contact_h,
        masters: contact_masters,
    } = contact_geometry(case, mesh, boundary)?;
    let (holding, held) = check_held(
        case,
        (mesh, parts),
        &fixed,
        &contact_nodes,
        &contact,
        &contact_masters,
    )?;
    contact.part = held;
    Ok(Conditioned {
        fixed,
        contact_nodes,
        contact,
        contact_h,
        contact_masters,
        holding,
    })
}

/// The nodal forces of the case's tractions alone, one entry per dof of `mesh`.
pub fn traction_load(case: &Case, mesh: &Mesh) -> Result<Vec<f64>> {
    let mut load = vec![0.0; 2 * mesh.num_nodes()];
    for t in &case.traction {
        let lines = line_group(case, mesh, "traction", &t.group)?;
        add_edge_traction(&mesh.nodes, lines, t.t, &mut load);
    }
    Ok(load)
}

/// The contact nodes of every contact (global ids, increasing), their weights and
/// geometry against their obstacles or master lines, the master nodes and coefficients of
/// each node's mortar row (empty against an obstacle), and the mean contact edge length.
/// Refuses a group off the boundary and a node already through its obstacle or master.
fn contact_geometry(
    case: &Case,
    mesh: &Mesh,
    boundary: &HashSet<(usize, usize)>,
) -> Result<ContactGeometry> {
    let (weight, mut lengths) = contact_lines(case, mesh, boundary)?;
    let obstacle = |i: usize| {
        case.contacts[i]
            .obstacle
            .as_ref()
            .expect("weights are kept for obstacle contacts only")
    };
    // A node in several groups (the corner between two sides) is one node of the contact
    // whose obstacle is nearest (the first on a tie), with its weight in that group: one
    // normal per node, the other obstacle's pressure there left to its neighbours.
    let owner: HashMap<usize, (usize, f64)> = (weight.iter())
        .map(|(&v, per)| {
            let gap = |i: usize| obstacle(i).geometry(mesh.nodes[v]).gap;
            let best = (per.iter().copied())
                .min_by(|a, b| gap(a.0).total_cmp(&gap(b.0)).then(a.0.cmp(&b.0)))
                .expect("a contact node has a contact");
            (v, best)
        })
        .collect();
    let rows = mortar_contacts(case, mesh, &owner)?;
    // Summed in a fixed order, so that r does not depend on the order of the file's
    // edges by a rounding (the loop's retunes can turn that into a sweep more or less).
    lengths.sort_unstable_by(f64::total_cmp);
    let total_len: f64 = lengths.iter().sum();
    let contact_h = total_len / lengths.len() as f64;
    let mut contact_nodes: Vec<usize> = owner.keys().chain(rows.keys()).copied().collect();
    contact_nodes.sort_unstable();
    let geometry: Vec<NodeGeometry> = (contact_nodes.iter())
        .map(|v| match (owner.get(v), rows.get(v)) {
            (Some(&(i, _)), _) => obstacle(i).geometry(mesh.nodes[*v]),
            (None, Some((_, row, s))) => NodeGeometry {
                normal: row.normal,
                gap: row.gap,
                s: *s,
            },
            (None, None) => unreachable!("a contact node is in a contact"),
        })
        .collect();
    let contact_of = |v: &usize| owner.get(v).map_or_else(|| rows[v].0, |o| o.0);
    let pair: Vec<u32> = contact_nodes.iter().map(|v| contact_of(v) as u32).collect();
    let mut s: Vec<f64> = geometry.iter().map(|g| g.s).collect();
    arc_positions(case, mesh, (&contact_nodes, &pair), &mut s);
    let contact = ContactNodes {
        w: (contact_nodes.iter())
            .map(|v| owner.get(v).map_or_else(|| rows[v].1.w, |o| o.1))
            .collect(),
        g: geometry.iter().map(|g| g.gap).collect(),
        s,
        normal: geometry.iter().map(|g| g.normal).collect(),
        pair,
        friction: Vec::new(),
        fixed_threshold: Vec::new(),
        part: Vec::new(),
    };
    let masters: Vec<Vec<(usize, f64)>> = (contact_nodes.iter())
        .map(|v| rows.get(v).map_or_else(Vec::new, |r| r.1.masters.clone()))
        .collect();
    let found = ContactGeometry {
        nodes: contact_nodes,
        contact,
        h: contact_h,
        masters,
    };
    check_overlap(case, mesh, &found)?;
    Ok(found)
}

/// Per node, its weight in each obstacle contact whose group holds it; and the length of
/// every contact edge. Refuses a contact group (slave or master) off the boundary.
#[allow(clippy::type_complexity)]
fn contact_lines(
    case: &Case,
    mesh: &Mesh,
    boundary: &HashSet<(usize, usize)>,
) -> Result<(HashMap<usize, Vec<(usize, f64)>>, Vec<f64>)> {
    let mut weight: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
    let mut lengths = Vec::new();
    for (i, c) in case.contacts.iter().enumerate() {
        let lines = line_group(case, mesh, "contact", &c.group)?;
        let mut groups = vec![("slave", &c.group, lines)];
        if let Some(m) = &c.master {
            groups.push(("master", m, line_group(case, mesh, "contact master", m)?));
        }
        for (what, name, lines) in groups {
            if let Some(&[a, b]) = lines
                .iter()
                .find(|&&[a, b]| !boundary.contains(&(a.min(b), a.max(b))))
            {
                return input(format!(
                    "{}: contact {what} group \"{name}\" has the edge ({}, {}) - ({}, {}) that is not on the boundary of a body; the contact groups must be boundary lines",
                    case.origin, mesh.nodes[a][0], mesh.nodes[a][1], mesh.nodes[b][0], mesh.nodes[b][1]
                ));
            }
        }
        for &[a, b] in lines {
            let len = edge_length(&mesh.nodes, a, b);
            lengths.push(len);
            if c.obstacle.is_none() {
                continue;
            }
            for v in [a, b] {
                let per = weight.entry(v).or_default();
                match per.iter_mut().find(|(j, _)| *j == i) {
                    Some((_, w)) => *w += 0.5 * len,
                    None => per.push((i, 0.5 * len)),
                }
            }
        }
    }
    Ok((weight, lengths))
}

/// The positions `s` along their obstacles of each obstacle contact's nodes (`nodes`,
/// with their contacts `pair`), where the obstacle measures them along itself.
fn arc_positions(case: &Case, mesh: &Mesh, (nodes, pair): (&[usize], &[u32]), s: &mut [f64]) {
    for (i, c) in case.contacts.iter().enumerate() {
        let Some(obstacle) = &c.obstacle else {
            continue;
        };
        let mine: Vec<usize> = (0..nodes.len())
            .filter(|&k| pair[k] as usize == i)
            .collect();
        let xs: Vec<[f64; 2]> = mine.iter().map(|&k| mesh.nodes[nodes[k]]).collect();
        if let Some(arc) = obstacle.arc_positions(&xs) {
            for (&k, a) in mine.iter().zip(arc) {
                s[k] = a;
            }
        }
    }
}

/// Refuses a contact node already through its obstacle or master line. Round-off in mesh
/// coordinates can put a touching node a hair below the line. (A gap that is not a
/// number, from an obstacle far beyond the mesh's scale, is refused alike.) A mortar
/// row's gap is a weighted mean over the slave segments (`contact::mortar`) between two
/// polygons: where curved bodies touch, the chords' sag makes it slightly negative
/// (about h^2 / R), which is the discrete geometry, not an overlap; one of a twentieth
/// of the contact edges is refused.
fn check_overlap(case: &Case, mesh: &Mesh, found: &ContactGeometry) -> Result<()> {
    let (contact, masters, contact_h) = (&found.contact, &found.masters, found.h);
    let allowed = |k: usize| {
        let mortar = !masters[k].is_empty();
        if mortar {
            MORTAR_OVERLAP * contact_h
        } else {
            1e-9 * contact_h
        }
    };
    let Some(k) =
        (0..found.nodes.len()).find(|&k| contact.g[k].is_nan() || contact.g[k] < -allowed(k))
    else {
        return Ok(());
    };
    let x = mesh.nodes[found.nodes[k]];
    let c = &case.contacts[contact.pair[k] as usize];
    let fix = match (&c.obstacle, &c.master) {
        (Some(Obstacle::Line { .. }), _) => "move obstacle_point or check that obstacle_normal points from the foundation into the body (obstacle.point and obstacle.normal in a [[contact]] entry)".to_string(),
        (Some(Obstacle::Circle { .. }), _) => "check the centre and the radius, and body = \"outside\" (the body outside the disc) or \"inside\" (in the hole)".to_string(),
        (Some(Obstacle::Polyline { .. }), _) => "check the points, and body = \"left\" or \"right\" (the body's side walking from the first point to the last)".to_string(),
        (None, m) => format!("the two bodies overlap there: mesh them apart or touching (master \"{}\")", m.as_deref().unwrap_or_default()),
    };
    input(format!(
        "{}: contact node at ({}, {}) already penetrates the {} by {} (contact \"{}\", {} {}); {fix}",
        case.origin,
        x[0],
        x[1],
        if c.obstacle.is_some() { "foundation" } else { "master body" },
        -contact.g[k],
        c.group,
        if c.obstacle.is_some() { "obstacle type" } else { "against" },
        c.obstacle.as_ref().map_or("a master line", Obstacle::kind)
    ))
}

/// The weighted overlap of a mortar row accepted at the start, as a share of the mean
/// contact edge (see [`contact_geometry`]).
const MORTAR_OVERLAP: f64 = 0.05;

/// What [`contact_geometry`] finds.
struct ContactGeometry {
    nodes: Vec<usize>,
    contact: ContactNodes,
    h: f64,
    masters: Vec<Vec<(usize, f64)>>,
}

/// Each segment of a line group with the unit normal out of the triangle it bounds.
fn outward_segments(mesh: &Mesh, lines: &[[usize; 2]]) -> Result<Vec<Segment>> {
    let key = |a: usize, b: usize| (a.min(b), a.max(b));
    let wanted: HashSet<(usize, usize)> = lines.iter().map(|&[a, b]| key(a, b)).collect();
    // The third corner of the triangle on each edge, which turns its normal outward.
    let mut thirds = HashMap::with_capacity(lines.len());
    for t in &mesh.triangles {
        for e in 0..3 {
            let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
            if wanted.contains(&key(a, b)) {
                thirds.insert(key(a, b), mesh.nodes[c]);
            }
        }
    }
    (lines.iter())
        .map(|&[a, b]| {
            let (xa, xb) = (mesh.nodes[a], mesh.nodes[b]);
            let xc = *thirds.get(&key(a, b)).ok_or_else(|| {
                Error::Numerical("internal: a contact line's edge has no triangle".into())
            })?;
            let len = edge_length(&mesh.nodes, a, b);
            let mut n = [(xb[1] - xa[1]) / len, -(xb[0] - xa[0]) / len];
            if n[0] * (xc[0] - xa[0]) + n[1] * (xc[1] - xa[1]) > 0.0 {
                n = [-n[0], -n[1]];
            }
            Ok(Segment {
                nodes: [a, b],
                outward: n,
            })
        })
        .collect()
}

/// The mortar row of every slave node of every contact with a master line, by node: its
/// contact, the row and its position along the contact (for pictures). Refuses a slave
/// node that is also a node of an obstacle contact or of another master contact, a slave
/// line that shares nodes with its master, and a slave line that faces no master.
#[allow(clippy::type_complexity)]
fn mortar_contacts(
    case: &Case,
    mesh: &Mesh,
    obstacle_nodes: &HashMap<usize, (usize, f64)>,
) -> Result<HashMap<usize, (usize, MortarRow, f64)>> {
    let origin = &case.origin;
    let mut rows: HashMap<usize, (usize, MortarRow, f64)> = HashMap::new();
    for (i, c) in case.contacts.iter().enumerate() {
        let Some(master) = &c.master else {
            continue;
        };
        let slave_lines = line_group(case, mesh, "contact", &c.group)?;
        let master_lines = line_group(case, mesh, "contact master", master)?;
        let on_master: std::collections::HashSet<usize> =
            master_lines.iter().flatten().copied().collect();
        if let Some(&v) = slave_lines.iter().flatten().find(|v| on_master.contains(v)) {
            let x = mesh.nodes[v];
            return input(format!(
                "{origin}: contact \"{}\" and its master \"{master}\" share the node at ({}, {}); the master must be a line of another body, meshed on its own",
                c.group, x[0], x[1]
            ));
        }
        let found = mortar_rows(
            &mesh.nodes,
            &outward_segments(mesh, slave_lines)?,
            &outward_segments(mesh, master_lines)?,
        );
        if found.is_empty() {
            return input(format!(
                "{origin}: contact \"{}\" faces no segment of its master \"{master}\"; the master must lie across from the slave line, its outward normal against the slave's",
                c.group
            ));
        }
        // Positions along the contact: across the mean normal.
        let mut mean = [0.0; 2];
        for r in &found {
            mean[0] += r.w * r.normal[0];
            mean[1] += r.w * r.normal[1];
        }
        let t = tangent_of(mean);
        for row in found {
            let v = row.node;
            let x = mesh.nodes[v];
            let other = obstacle_nodes
                .get(&v)
                .map(|o| o.0)
                .or_else(|| rows.get(&v).map(|r| r.0));
            if let Some(j) = other {
                return input(format!(
                    "{origin}: the node at ({}, {}) is a slave node of both contact \"{}\" and contact \"{}\"; a node presses on one obstacle or master: give the groups no common node",
                    x[0], x[1], case.contacts[j].group, c.group
                ));
            }
            let s = (x[0] * t[0] + x[1] * t[1]) / t[0].hypot(t[1]);
            rows.insert(v, (i, row, s));
        }
    }
    Ok(rows)
}

/// `v` (two values per node) in the node order `old_of` (new -> old).
fn per_dof<T: Copy + Send + Sync>(old_of: &[usize], v: &[T]) -> Vec<T> {
    (old_of.par_iter())
        .map(|&o| [v[2 * o], v[2 * o + 1]])
        .collect::<Vec<[T; 2]>>()
        .into_flattened()
}

/// `prob` with its nodes and triangles numbered along a Hilbert curve
/// ([`renumber::by_hilbert_curve`]), whatever the order of the mesh file: the same
/// problem, its set-up walking memory in order. Done after every check, so that
/// messages name nodes and triangles in the file's numbering.
fn in_locality_order(prob: Problem) -> Problem {
    let (mesh, numbering) = renumber::by_hilbert_curve(prob.mesh);
    let renumber::Renumbering { old_of, new_of, .. } = numbering;
    let fixed = per_dof(&old_of, &prob.fixed);
    // Contact nodes stay in increasing order, now the new one.
    let mut by_new: Vec<(usize, usize)> = (prob.contact_nodes.iter())
        .enumerate()
        .map(|(k, &c)| (new_of[c], k))
        .collect();
    by_new.sort_unstable();
    let keep: Vec<usize> = by_new.iter().map(|&(_, k)| k).collect();
    let contact_masters = (keep.iter())
        .map(|&k| {
            let mut m: Vec<(usize, f64)> = (prob.contact_masters[k].iter())
                .map(|&(v, c)| (new_of[v], c))
                .collect();
            m.sort_unstable_by_key(|e| e.0);
            m
        })
        .collect();
    Problem {
        contact: prob.contact.select(&keep),
        contact_masters,
        contact_nodes: by_new.iter().map(|&(v, _)| v).collect(),
        file_node: old_of.par_iter().map(|&o| prob.file_node[o]).collect(),
        mesh,
        fixed,
        ..prob
    }
}

/// How a direction reads in a fix: the displacement component that holds it.
fn component(v: [f64; 2]) -> &'static str {
    if v[1].abs() <= 1e-9 {
        "ux"
    } else if v[0].abs() <= 1e-9 {
        "uy"
    } else {
        "ux or uy"
    }
}

/// The separate parts of a mesh (triangles joined through nodes) as [`check_held`] reads
/// them.
#[derive(Debug, Clone, PartialEq)]
pub struct Parts {
    /// The part of each node of the mesh given.
    pub of_node: Vec<usize>,
    /// Each part's lowest node (its index among the file's nodes, its point), the parts
    /// numbered in their order.
    pub first: Vec<(usize, [f64; 2])>,
    /// The mesh's size (the larger side of its bounding box), for the tolerances.
    pub size: f64,
}

impl Parts {
    /// The parts of a whole mesh, its nodes in the file's order.
    pub fn of(mesh: &Mesh) -> Parts {
        let (of_node, count) = validate::parts(mesh);
        let mut first = vec![usize::MAX; count];
        for (node, &p) in of_node.iter().enumerate().rev() {
            first[p] = node;
        }
        Parts {
            of_node,
            first: first.into_iter().map(|n| (n, mesh.nodes[n])).collect(),
            size: validate::size(mesh),
        }
    }
}

/// Rejects a problem whose stiffness matrix would be singular because a rigid motion of
/// some part of the mesh is held by nothing, before anything is assembled or factored.
///
/// The rule is structural (see [`Holds`] for why it is exact): each separate part of the
/// mesh (triangles joined through nodes) must be held by lines of action that are neither
/// all parallel nor all through one point. Each fixed dof holds its node along x or y;
/// each contact node holds along its normal, and with friction (Tresca or
/// Coulomb) also along the tangent. So frictionless contact alone always leaves the
/// sliding along the foundation free, which some Dirichlet condition must stop. Pieces
/// joined at a single node (a hinge) count as one part here; a mechanism through such a
/// hinge is left to the factorization, which reports a numerical failure.
pub fn check_held(
    case: &Case,
    (mesh, parts): (&Mesh, &Parts),
    fixed: &[Option<f64>],
    contact_nodes: &[usize],
    contact: &ContactNodes,
    masters: &[Vec<(usize, f64)>],
) -> Result<(Holding, Vec<[u32; 2]>)> {
    let (part, count) = (&parts.of_node, parts.first.len());
    let tol = validate::SAME_LINE * parts.size;
    let mut holds = vec![Holds::new(tol); count];
    // Per part: ux fixed, uy fixed, contact along the normal, friction along the tangent.
    let mut kinds = vec![[false; 4]; count];
    for (dof, _) in fixed.iter().enumerate().filter(|(_, f)| f.is_some()) {
        let (node, c) = (dof / 2, dof % 2);
        let dir = if c == 0 { [1.0, 0.0] } else { [0.0, 1.0] };
        holds[part[node]].add(mesh.nodes[node], dir);
        kinds[part[node]][c] = true;
    }
    let holding = Holding {
        dirichlet: holds.clone(),
        first: parts.first.iter().map(|f| f.1).collect(),
    };
    let rows: Vec<ContactHold> = (contact_nodes.iter().enumerate())
        .map(|(k, &node)| ContactHold {
            part: part[node],
            master: masters
                .get(k)
                .and_then(|m| m.first())
                .map(|&(m, _)| part[m]),
            at: mesh.nodes[node],
            normal: contact.normal[k],
            // A frictionless contact among frictional ones holds along its normals only.
            tangent: case.contacts[contact.pair[k] as usize].friction != Friction::None,
        })
        .collect();
    let parts_of = (rows.iter())
        .map(|r| [r.part as u32, r.master.map_or(NO_PART, |m| m as u32)])
        .collect();
    let touched = validate::hold_parts(&mut holds, &rows);
    for (k, t) in kinds.iter_mut().zip(&touched) {
        k[2] |= t[0];
        k[3] |= t[1];
    }
    let Some((p, free)) = holds
        .iter()
        .enumerate()
        .find_map(|(p, h)| h.free().map(|f| (p, f)))
    else {
        return Ok((holding, parts_of));
    };
    let held = Held {
        by: kinds[p],
        on_body: touched[p][2],
    };
    Err(Error::Input(not_held(case, (mesh, parts), p, free, held)))
}

/// What holds a part that is not held: its kinds of conditions (ux fixed, uy fixed,
/// contact along the normal, friction along the tangent), and whether a contact
/// between bodies holds it.
struct Held {
    by: [bool; 4],
    on_body: bool,
}

/// The message of [`check_held`] for part `p`, left `free` by what `held` it.
fn not_held(
    case: &Case,
    (mesh, parts): (&Mesh, &Parts),
    p: usize,
    free: Free,
    held: Held,
) -> String {
    let origin = &case.origin;
    let count = parts.first.len();
    let body = if count == 1 {
        "the body".to_string()
    } else {
        let (node, x) = parts.first[p];
        format!(
            "the part of the mesh with node {} at ({}, {}) (one of {count} separate parts)",
            node + 1,
            x[0],
            x[1]
        )
    };
    let names = [
        "ux fixed",
        "uy fixed",
        "contact along obstacle_normal",
        "friction",
    ];
    let held_by: Vec<&str> = (0..4).filter(|&k| held.by[k]).map(|k| names[k]).collect();
    let held_by = held_by.join(", ");
    let groups = format!("groups in the mesh: {}", mesh.group_names().join(", "));
    let frictionless = held.by[2] && !Problem::is_frictional(case);
    match free {
        Free::Everything => format!(
            "{origin}: {body} has no [[dirichlet]] condition and no contact node, so nothing holds it (singular problem); fix ux and uy on one of its groups with [[dirichlet]] ({groups})"
        ),
        Free::Slide { along } if frictionless && held.on_body => {
            let comp = component(along);
            format!(
                "{origin}: nothing stops {body} from sliding on the body it rests on (singular problem): frictionless contact holds it only along the contact normals and no [[dirichlet]] fixes {comp}; add a [[dirichlet]] with {comp} = 0.0 on a symmetry line or on one node (a point group), or use friction = \"tresca\" or \"coulomb\" ({groups})"
            )
        }
        Free::Slide { along } if frictionless => {
            let comp = component(along);
            format!(
                "{origin}: nothing stops {body} from sliding along the foundation (singular problem): frictionless contact holds it only along obstacle_normal and no [[dirichlet]] fixes {comp}; add a [[dirichlet]] with {comp} = 0.0 on a symmetry line or on one node (a point group), or use friction = \"tresca\" or \"coulomb\" ({groups})"
            )
        }
        Free::Slide { along } => format!(
            "{origin}: {body} can translate rigidly along ({}, {}) (singular problem): all its conditions ({held_by}) act across that direction; add a [[dirichlet]] that fixes {} on one of its groups ({groups})",
            along[0],
            along[1],
            component(along)
        ),
        Free::Turn { centre } => format!(
            "{origin}: {body} can rotate rigidly about ({}, {}) (singular problem): all its conditions ({held_by}) act on lines through that point; also fix ux or uy at a node away from it (uy at another x, or ux at another y) ({groups})",
            centre[0], centre[1]
        ),
        Free::SlideAndTurn { point, dir } => format!(
            "{origin}: {body} can translate and rotate rigidly (singular problem): all its conditions ({held_by}) act along one line, through ({}, {}) along ({}, {}); fix both ux and uy, on a line group or at two separate nodes ({groups})",
            point[0], point[1], dir[0], dir[1]
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{builtin_case, BodyMaterial};

    /// Two triangles of the unit square, "lower" (0, 1, 2) and "upper" (0, 2, 3).
    fn square() -> Mesh {
        let mut mesh = Mesh {
            nodes: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        };
        mesh.surface_groups.insert("lower".into(), vec![0]);
        mesh.surface_groups.insert("upper".into(), vec![1]);
        mesh
    }

    fn two_bodies(young: [f64; 2], hypothesis: Hypothesis) -> Case {
        let mut case = builtin_case("block", 0).unwrap();
        case.materials = (["upper", "lower"].into_iter().zip(young))
            .map(|(g, young)| BodyMaterial {
                group: Some(g.into()),
                material: Material {
                    young,
                    poisson: 0.5f64.sqrt(),
                    hypothesis,
                },
            })
            .collect();
        case
    }

    #[test]
    fn each_triangle_gets_the_entry_of_its_group() {
        let case = two_bodies([1.0, 2.0], Hypothesis::PlaneStrain);
        assert_eq!(bodies(&case, &square()).unwrap(), [1, 0]);
        let lone = builtin_case("block", 0).unwrap();
        assert_eq!(bodies(&lone, &square()).unwrap(), [0, 0]);
        let mut unlisted = case.clone();
        unlisted.materials.pop();
        let e = bodies(&unlisted, &square()).unwrap_err().to_string();
        assert!(e.contains("with group = \"lower\""), "{e}");
    }

    #[test]
    fn the_scale_of_r_is_the_stiffest_body_at_the_contact() {
        // Node 1 is in "lower" only, node 3 in "upper" only, node 0 in both.
        let mesh = square();
        let body = [1, 0];
        assert_eq!(touching(&mesh, &body, &[1]), [1]);
        assert_eq!(touching(&mesh, &body, &[3]), [0]);
        assert_eq!(touching(&mesh, &body, &[0, 1]), [0, 1]);
        // E_eff = E / (1 - nu^2) = 2 E in plane strain with nu^2 = 1/2; E in plane stress.
        let case = two_bodies([10.0, 30.0], Hypothesis::PlaneStrain);
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b;
        assert!(close(contact_modulus(&case, &[0]), 20.0));
        assert!(close(contact_modulus(&case, &[1]), 60.0));
        assert!(close(contact_modulus(&case, &[0, 1]), 60.0));
        assert!(close(contact_modulus(&case, &[]), 60.0));
        let stress = two_bodies([10.0, 30.0], Hypothesis::PlaneStress);
        assert_eq!(contact_modulus(&stress, &[0]), 10.0);
        // One material: its own E_eff, bit for bit.
        let lone = builtin_case("block", 0).unwrap();
        let m = lone.materials[0].material;
        assert_eq!(contact_modulus(&lone, &[0]), effective_modulus(&m));
    }

    #[test]
    fn an_answer_held_by_lines_through_one_point_is_not_unique() {
        // ux fixed along the line y = 1 (at two nodes of it): with one pressed node below,
        // every line of action passes through (0, 1).
        let mut ux = Holds::new(1e-9);
        ux.add([-1.0, 1.0], [1.0, 0.0]);
        ux.add([1.0, 1.0], [1.0, 0.0]);
        let holding = Holding {
            dirichlet: vec![ux],
            first: vec![[-1.0, 1.0]],
        };
        let node = |x: f64, pressed, sticks| NodeAtAnswer {
            part: [0, NO_PART],
            at: [x, 0.0],
            normal: [0.0, 1.0],
            pressed,
            sticks,
        };
        let one = free_at_answer(&holding, &[node(0.0, true, false), node(0.5, false, false)]);
        assert_eq!(one.len(), 1);
        assert!(
            one[0].contains("the body") && one[0].contains("free to turn about (0, 1)"),
            "{}",
            one[0]
        );
        // A second pressed node, or a sticking one, holds it.
        assert!(
            free_at_answer(&holding, &[node(0.0, true, false), node(0.5, true, false)]).is_empty()
        );
        assert!(free_at_answer(&holding, &[node(0.0, true, true)]).is_empty());
        // Nothing pressed: free to move rigidly.
        let none = free_at_answer(&holding, &[node(0.0, false, false)]);
        assert!(none[0].contains("free to move rigidly"), "{}", none[0]);
        // Parts not known (an older split, a row without them): no verdict.
        let unknown = NodeAtAnswer {
            part: [NO_PART; 2],
            ..node(0.0, true, false)
        };
        assert!(free_at_answer(&holding, &[unknown]).is_empty());
        assert!(free_at_answer(&Holding::default(), &[node(0.0, true, false)]).is_empty());
    }
}
