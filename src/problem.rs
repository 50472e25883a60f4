//! From a validated case and a mesh to the discrete problem: oriented mesh, prescribed
//! dofs, load vector, contact nodes with their lumped weights and gaps. Everything that
//! needs the whole mesh happens here, once, on the reading rank.

use crate::case::{Case, Friction, Hypothesis};
use crate::contact::ContactNodes;
use crate::error::{input, Error, Result};
use crate::fem::assembly::{add_body_force, add_edge_traction, edge_length};
use crate::mesh::Mesh;
use std::collections::{HashMap, HashSet};

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
    /// Weights and gaps of `contact_nodes`, same order.
    pub contact: ContactNodes,
    /// Unit normal m (foundation -> body) and tangent t = (m_y, -m_x).
    pub normal: [f64; 2],
    pub tangent: [f64; 2],
    /// Mean length of the contact edges.
    pub contact_h: f64,
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
        let m = &case.material;
        let e_eff = match m.hypothesis {
            Hypothesis::PlaneStrain => m.young / (1.0 - m.poisson * m.poisson),
            Hypothesis::PlaneStress => m.young,
        };
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &self.mesh.nodes {
            for c in 0..2 {
                lo[c] = lo[c].min(p[c]);
                hi[c] = hi[c].max(p[c]);
            }
        }
        let size = (hi[0] - lo[0]).min(hi[1] - lo[1]).max(self.contact_h);
        e_eff / (self.contact_h * size).sqrt()
    }

    pub fn is_frictional(case: &Case) -> bool {
        !matches!(case.contact.friction, Friction::None)
    }
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
            "{}: {what} group \"{name}\" has no line elements",
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

/// Orients every triangle counter-clockwise; rejects degenerate ones. A mesh whose
/// triangles are all clockwise (a surface with normal -z in Gmsh) is simply flipped.
pub fn orient(mesh: &mut Mesh, origin: &str) -> Result<()> {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &mesh.nodes {
        for c in 0..2 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    for t in 0..mesh.triangles.len() {
        let a2 = mesh.signed_area2(t);
        let [i, j, k] = mesh.triangles[t];
        let longest = [(i, j), (j, k), (k, i)]
            .iter()
            .map(|&(a, b)| edge_length(&mesh.nodes, a, b))
            .fold(0.0, f64::max);
        // Relative to the element's own size (and the mesh's, for zero-length edges).
        if a2.abs() <= 1e-12 * longest * longest || longest <= 1e-14 * size {
            let p = mesh.nodes[i];
            return input(format!(
                "{origin}: triangle {} (nodes {}, {}, {}, near ({}, {})) is degenerate (zero area); fix the mesh",
                t + 1,
                i + 1,
                j + 1,
                k + 1,
                p[0],
                p[1]
            ));
        }
        if a2 < 0.0 {
            mesh.triangles[t].swap(1, 2);
        }
    }
    Ok(())
}

/// Edges that belong to exactly one triangle.
pub fn boundary_edges(mesh: &Mesh) -> HashSet<(usize, usize)> {
    let mut count: HashMap<(usize, usize), u8> = HashMap::with_capacity(3 * mesh.triangles.len());
    for t in &mesh.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    count
        .into_iter()
        .filter(|&(_, c)| c == 1)
        .map(|(e, _)| e)
        .collect()
}

/// Builds the discrete problem; `mesh_name` names the mesh in messages.
pub fn build(case: &Case, mut mesh: Mesh, mesh_name: &str) -> Result<Problem> {
    orient(&mut mesh, mesh_name)?;
    let n = mesh.num_nodes();

    let mut fixed: Vec<Option<f64>> = vec![None; 2 * n];
    for d in &case.dirichlet {
        for node in group_nodes(case, &mesh, "dirichlet", &d.group)? {
            for (c, v) in [d.ux, d.uy].into_iter().enumerate() {
                if let Some(v) = v {
                    fixed[2 * node + c] = Some(v);
                }
            }
        }
    }

    let mut load = vec![0.0; 2 * n];
    for t in &case.traction {
        let lines = line_group(case, &mesh, "traction", &t.group)?;
        add_edge_traction(&mesh.nodes, lines, t.t, &mut load);
    }
    add_body_force(&mesh.nodes, &mesh.triangles, case.body_force, &mut load);

    let c = &case.contact;
    let lines = line_group(case, &mesh, "contact", &c.group)?;
    let boundary = boundary_edges(&mesh);
    if let Some(&[a, b]) = lines
        .iter()
        .find(|&&[a, b]| !boundary.contains(&(a.min(b), a.max(b))))
    {
        return input(format!(
            "{}: contact group \"{}\" has the edge ({}, {}) - ({}, {}) that is not on the boundary of the body; the contact group must be a boundary line",
            case.origin, c.group, mesh.nodes[a][0], mesh.nodes[a][1], mesh.nodes[b][0], mesh.nodes[b][1]
        ));
    }
    let mut weight: HashMap<usize, f64> = HashMap::new();
    let mut total_len = 0.0;
    for &[a, b] in lines {
        let len = edge_length(&mesh.nodes, a, b);
        total_len += len;
        *weight.entry(a).or_insert(0.0) += 0.5 * len;
        *weight.entry(b).or_insert(0.0) += 0.5 * len;
    }
    let mut contact_nodes: Vec<usize> = weight.keys().copied().collect();
    contact_nodes.sort_unstable();
    let m = c.obstacle_normal;
    let p0 = c.obstacle_point;
    let gap = |x: [f64; 2]| (x[0] - p0[0]) * m[0] + (x[1] - p0[1]) * m[1];
    let contact = ContactNodes {
        w: contact_nodes.iter().map(|i| weight[i]).collect(),
        g: contact_nodes.iter().map(|&i| gap(mesh.nodes[i])).collect(),
    };
    let contact_h = total_len / lines.len() as f64;
    // Round-off in mesh coordinates can put a touching node a hair below the line.
    if let Some(k) = (0..contact_nodes.len()).find(|&k| contact.g[k] < -1e-9 * contact_h) {
        let x = mesh.nodes[contact_nodes[k]];
        return input(format!(
            "{}: contact node at ({}, {}) already penetrates the foundation by {} (gap (x - obstacle_point) . obstacle_normal < 0); move obstacle_point or check that obstacle_normal points from the foundation into the body",
            case.origin, x[0], x[1], -contact.g[k]
        ));
    }

    Ok(Problem {
        mesh,
        fixed,
        load,
        contact_nodes,
        contact,
        normal: m,
        tangent: [m[1], -m[0]],
        contact_h,
    })
}
