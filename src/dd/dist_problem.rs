//! The problem's conditions built by the first rank without the whole mesh, where the
//! ranks cut a Gmsh file from their shares and hold their parts' lists
//! (`dd::share_cut`): the mesh checked on the ranks (`dd::dist_check`), and on the first
//! rank only what is sized like the boundary: the groups' elements (lines and points)
//! with their nodes' places and points from the directory, the boundary edges among
//! those nodes, each node's separate part and the bodies of the triangles around it.
//! From these, the same conditions ([`Conditions`]) and figures ([`Facts`]) as the
//! whole problem gives (`problem::build`, `Conditions::of`).
//!
//! Why: the whole mesh on the first rank was the last thing on it sized like the mesh
//! where the ranks build their own parts (docs/cost-model.md, "The start from one Gmsh
//! file"): 20 GiB and 20 s of a 10^8-dof start by the model.
//!
//! A fault of the mesh found by the ranks' checks, or of the groups and conditions, is
//! named as the whole problem names it (the same functions, the same messages: tested).
//! So are a mesh off the plane (`dist_check::off_plane`) and a fault of the materials
//! (`problem::materials_fault` from the triangle blocks, after the conditions as the
//! whole problem names them; the centroid it names from the part that holds the
//! triangle). What the serial reading treats otherwise (a triangle listed twice, which
//! it drops) and anything these steps do not expect send every rank back to the first
//! rank's reading of the whole file, which names the fault as it always has; the ranks
//! keep their cut and their lists.

use crate::case::Case;
use crate::dd::comm::Mpi;
use crate::dd::dist_check;
use crate::dd::dist_split::{run_value, Conditions};
use crate::dd::locality::{tag_rank, Directory};
use crate::dd::ownership::{NodeParts, PartLists};
use crate::error::{Error, Result};
use crate::mesh::gmsh::off_plane_message;
use crate::mesh::gmsh::shares::{GroupMesh, Scan};
use crate::mesh::validate;
use crate::problem::{self, EdgeThirds, Lengths, Parts};
use crate::split_dir::Facts;
use std::collections::{HashMap, HashSet};

/// What the first rank brings: the case, the file's scan, and the groups' elements'
/// values of every share, in file order (`gmsh::shares::Share::group_values`).
pub struct First<'a> {
    /// The mesh file's name, for messages.
    pub name: &'a str,
    pub case: &'a Case,
    pub scan: &'a Scan,
    pub group_values: &'a [u64],
}

/// The conditions and figures, on the first rank.
#[derive(Debug, Clone, PartialEq)]
pub struct OnGroups {
    pub conditions: Conditions,
    /// Without the partition's figures, which the ranks find.
    pub facts: Facts,
}

/// What [`build`] ends with, the same on every rank.
#[derive(Debug)]
pub enum Outcome {
    /// The conditions, on the first rank.
    Built(Option<OnGroups>),
    /// A fault of the input, its message on the first rank: the one the first rank's
    /// reading of the whole file gives.
    Fault(Option<String>),
    /// Back to the first rank's reading (see the module's notes).
    FallBack,
}

/// The conditions of the mesh whose parts this rank holds (`lists`, with its shares of
/// the directory), the first rank's `first`; `z`: this rank's share of the nodes' z
/// (the largest, minus the smallest, and the first node's of the file where this rank
/// holds it, else minus infinity). Collective; one subdomain per rank.
pub fn build(
    mpi: &Mpi,
    first: Option<First>,
    lists: &[PartLists],
    (directory, around): (&Directory, &NodeParts),
    triangles: usize,
    z: &[f64],
) -> Result<Outcome> {
    // The reading checks the plane before the mesh, whatever else is wrong.
    let bbox = dist_check::bounding_box(mpi, &directory.xy);
    if let Some(off) = dist_check::off_plane(mpi, z, directory, bbox)? {
        let message = (first.as_ref().zip(off))
            .map(|(f, o)| off_plane_message(f.name, o.tag, o.z, o.first_tag, o.first_z));
        let named = mpi.broadcast(mpi.is_root().then_some(message.is_some()))?;
        return Ok(match named {
            true => Outcome::Fault(message),
            false => Outcome::FallBack,
        });
    }
    let checked = dist_check::check(mpi, (directory, around), lists, bbox)?;
    let groups = groups_mesh(mpi, first.as_ref(), directory);
    let checked = match checked {
        Ok(c) => c,
        Err(dist_check::Fault::Repeat) => return Ok(Outcome::FallBack),
        Err(fault) => {
            let message = (first.as_ref().zip(groups.as_ref()))
                .map(|(f, groups)| fault.message(f.name, |node| group_of(groups, node)));
            // Without the groups' mesh the first rank's reading names it.
            let named = mpi.broadcast(mpi.is_root().then_some(message.is_some()))?;
            return Ok(match named {
                true => Outcome::Fault(message),
                false => Outcome::FallBack,
            });
        }
    };
    let nodes: usize = mpi.all_gather_counts(directory.tags.len()).iter().sum();
    let edges: Vec<u64> = checked.boundary.iter().flatten().copied().collect();
    let edges = mpi.gather_varcount(&edges, &mpi.all_gather_counts(edges.len()));
    // A fault of the materials is named after those of the conditions, as the whole
    // problem names them: the conditions are built first, on any bodies.
    let mut materials = None;
    let groups = first.as_ref().zip(groups).and_then(|(f, mesh)| {
        let runs = problem::body_runs(f.case, &mesh.triangle_blocks).or_else(|| {
            materials = problem::materials_fault(f.case, &mesh.triangle_blocks, &mesh.mesh);
            materials.is_some().then(|| vec![(0, 0)])
        })?;
        Some((mesh, runs))
    });
    let ask = groups.as_ref().map(|(mesh, runs)| Ask {
        tags: mesh.tags.clone(),
        firsts: checked.part_first.clone(),
        runs: runs.clone(),
    });
    let ask: Option<Ask> = mpi.broadcast(mpi.is_root().then_some(ask))?;
    let Some(ask) = ask else {
        return Ok(Outcome::FallBack);
    };
    let told = tell(mpi, &ask, lists, &checked.node_part);
    let built = first.zip(groups).and_then(|(f, (mesh, runs))| {
        let whole = Whole {
            nodes,
            triangles,
            bbox: checked.bbox,
            boundary: edges.unwrap_or_default(),
            part_first: &checked.part_first,
        };
        on_groups(f.case, mesh, runs, told, whole)
    });
    // A fault of the conditions is named here, then one of the materials; anything else
    // falls back.
    let kind = mpi.is_root().then_some(match (&built, &materials) {
        (Some(Ok(_)), None) => (0u8, None),
        (Some(Err(Error::Input(_))), _) => (1, None),
        (Some(Ok(_)), Some((triangle, _))) => (3, *triangle),
        _ => (2, None),
    });
    Ok(match mpi.broadcast(kind)? {
        (0, _) => Outcome::Built(built.and_then(Result::ok)),
        (1, _) => Outcome::Fault(built.and_then(|b| b.err()).map(|e| e.to_string())),
        (3, triangle) => {
            let x = match triangle {
                Some(t) => centroid(mpi, lists, t, checked.bbox)?,
                None => Some([f64::NAN; 2]),
            };
            let message = materials.zip(x).map(|((_, message), x)| message(x));
            match mpi.broadcast(mpi.is_root().then_some(message.is_some()))? {
                true => Outcome::Fault(message),
                false => Outcome::FallBack,
            }
        }
        _ => Outcome::FallBack,
    })
}

/// The centroid of the file's triangle `t` (its index among the file's triangle
/// records) as the whole problem computes it, on its corners turned counter-clockwise;
/// on the first rank, `None` there where no part holds it. Collective.
fn centroid(
    mpi: &Mpi,
    lists: &[PartLists],
    t: u64,
    (lo, hi): ([f64; 2], [f64; 2]),
) -> Result<Option<[f64; 2]>> {
    let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let mine = lists.iter().find_map(|l| {
        let k = l.elements.binary_search(&t).ok()?;
        let at = |tag: u64| Some(l.xy[l.nodes.binary_search(&tag).ok()?]);
        let [a, b, c] = l.triangles[k];
        let mut p = [at(a)?, at(b)?, at(c)?];
        if validate::clockwise(&p, [0, 1, 2], size)? {
            p.swap(1, 2);
        }
        Some([0, 1].map(|i| (p[0][i] + p[1][i] + p[2][i]) / 3.0))
    });
    let all = mpi.gather_parts(mine)?;
    Ok(all.and_then(|all| all.into_iter().flatten().next()))
}

/// The first group that holds node `file` (an index among the file's nodes), lines
/// before points, as the whole mesh's check names it.
fn group_of(groups: &GroupMesh, file: u64) -> Option<String> {
    let at = groups.file.binary_search(&file).ok()?;
    let mesh = &groups.mesh;
    let line = (mesh.line_groups.iter()).find(|(_, v)| v.iter().flatten().any(|&i| i == at));
    let point = || (mesh.point_groups.iter()).find(|(_, v)| v.contains(&at));
    line.map(|(g, _)| g.clone())
        .or_else(|| point().map(|(g, _)| g.clone()))
}

/// What the first rank asks every rank about the groups' nodes.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Ask {
    /// The groups' nodes' tags, in the group mesh's order.
    tags: Vec<u64>,
    /// The separate parts' lowest nodes (file indices).
    firsts: Vec<u64>,
    /// The bodies' runs over the file's triangle records.
    runs: Vec<(u64, u32)>,
}

/// What the ranks tell the first: per group node, its separate part and the bodies of
/// the triangles around it; per separate part, its lowest node's point; per edge between
/// two group nodes (lower first), the third corner of its triangle (`problem::Thirds`).
struct Told {
    part: Vec<u32>,
    bodies: Vec<Vec<u32>>,
    first_at: Vec<[f64; 2]>,
    thirds: EdgeThirds,
}

/// A node as the directory holds it: tag, index among the file's nodes, point.
type Found = (u64, u64, [f64; 2]);

/// The groups' mesh on the first rank, its nodes' points from the directory; `None`
/// elsewhere, and where a group's node is not in the directory. Collective.
fn groups_mesh(mpi: &Mpi, first: Option<&First>, directory: &Directory) -> Option<GroupMesh> {
    let tags = first.and_then(|f| f.scan.group_tags(f.group_values));
    let found = look_up(mpi, tags.as_deref().unwrap_or_default(), directory);
    let found = found.flatten();
    first
        .zip(found)
        .and_then(|(f, found)| f.scan.group_mesh(f.group_values, &found))
}

/// The nodes of `tags` (increasing) as the directory holds them: tag, index among the
/// file's nodes, point; `None` where one is missing. On the first rank (`None`
/// elsewhere). Collective.
fn look_up(mpi: &Mpi, tags: &[u64], directory: &Directory) -> Option<Option<Vec<Found>>> {
    let nodes = find(mpi, tags, directory);
    if !mpi.is_root() {
        return None;
    }
    Some(nodes.into_iter().collect())
}

/// Each of this rank's `tags` (any order) as the directory holds it, `None` where it
/// does not: every rank asks for its own. Collective.
fn find(mpi: &Mpi, tags: &[u64], directory: &Directory) -> Vec<Option<Found>> {
    let p = mpi.size;
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for &t in tags {
        send[tag_rank(t, p)].push(t);
    }
    let asked = mpi.exchange(send);
    let answers: Vec<Vec<u64>> = (asked.iter())
        .map(|from| {
            (from.iter())
                .flat_map(|&t| match directory.tags.binary_search(&t) {
                    Ok(k) => [
                        t,
                        directory.file[k],
                        directory.xy[k][0].to_bits(),
                        directory.xy[k][1].to_bits(),
                    ],
                    Err(_) => [t, u64::MAX, 0, 0],
                })
                .collect()
        })
        .collect();
    let answered = mpi.exchange(answers);
    let mut nodes: Vec<Found> = (answered.iter())
        .flat_map(|v| v.chunks_exact(4))
        .filter(|c| c[1] != u64::MAX)
        .map(|c| (c[0], c[1], [f64::from_bits(c[2]), f64::from_bits(c[3])]))
        .collect();
    nodes.sort_unstable_by_key(|n| n.0);
    (tags.iter())
        .map(|&t| {
            let i = nodes.binary_search_by_key(&t, |n| n.0).ok()?;
            Some(nodes[i])
        })
        .collect()
}

/// The ties of the contacts between two bodies (`problem::mortar_ties`) as pairs of
/// node tags (slave, master), on every rank, for the cut from the ranks' shares (which
/// then keeps a contact's two sides together, as the first rank's graph does): the
/// first rank finds the rows on the groups' elements (`first`), with their nodes'
/// points from the directory and, for each contact line's edge, the third corner of its
/// triangle from the rank that holds it (`triangles`, node tags). Empty where no
/// contact ties two bodies, or the rows cannot be found (the conditions then name the
/// fault). Collective; before the cut.
pub fn ties(
    mpi: &Mpi,
    first: Option<First>,
    triangles: &[[u64; 3]],
    directory: &Directory,
) -> Vec<[u64; 2]> {
    let tied = (first.as_ref()).is_some_and(|f| f.case.contacts.iter().any(|c| c.master.is_some()));
    if !mpi
        .broadcast(mpi.is_root().then_some(tied))
        .unwrap_or(false)
    {
        return Vec::new();
    }
    let groups = groups_mesh(mpi, first.as_ref(), directory);
    // The contact lines' edges, by their nodes' tags.
    let lines: Option<Vec<[u64; 2]>> = first.as_ref().zip(groups.as_ref()).map(|(f, g)| {
        let tag = |v: usize| g.tags[v];
        let mut lines: Vec<[u64; 2]> = (problem::tied_lines(f.case, &g.mesh).iter())
            .map(|&(a, b)| [tag(a).min(tag(b)), tag(a).max(tag(b))])
            .collect();
        lines.sort_unstable();
        lines
    });
    let lines: Vec<[u64; 2]> = mpi
        .broadcast(mpi.is_root().then_some(lines))
        .ok()
        .flatten()
        .unwrap_or_default();
    let got = line_thirds(mpi, &lines, triangles, directory);
    let ties = first.zip(groups).and_then(|(f, g)| {
        let index: HashMap<u64, usize> = g.tags.iter().enumerate().map(|(v, &t)| (t, v)).collect();
        let thirds: EdgeThirds = (got.chunks_exact(4))
            .filter_map(|c| {
                let (a, b) = (*index.get(&c[0])?, *index.get(&c[1])?);
                Some((
                    (a.min(b), a.max(b)),
                    [f64::from_bits(c[2]), f64::from_bits(c[3])],
                ))
            })
            .collect();
        let ties = problem::mortar_ties(f.case, &g.mesh, &thirds)?;
        Some(
            ties.iter()
                .map(|t| t.map(|v| g.tags[v]))
                .collect::<Vec<[u64; 2]>>(),
        )
    });
    mpi.broadcast(mpi.is_root().then_some(ties))
        .ok()
        .flatten()
        .unwrap_or_default()
}

/// Each of `lines`' edges (node tags, lower first, sorted) with the point of the third
/// corner of its triangle, from the rank that holds the triangle (its `triangles`, node
/// tags; the point from the directory): on the first rank, four values an edge (the two
/// tags, x and y bits); empty elsewhere. Collective.
fn line_thirds(
    mpi: &Mpi,
    lines: &[[u64; 2]],
    triangles: &[[u64; 3]],
    directory: &Directory,
) -> Vec<u64> {
    let mut sides: Vec<([u64; 2], u64)> = Vec::new();
    for t in triangles {
        for c in 0..3 {
            let (a, b) = (t[c], t[(c + 1) % 3]);
            let edge = [a.min(b), a.max(b)];
            if lines.binary_search(&edge).is_ok() {
                sides.push((edge, t[(c + 2) % 3]));
            }
        }
    }
    let thirds: Vec<u64> = sides.iter().map(|s| s.1).collect();
    let at = find(mpi, &thirds, directory);
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); mpi.size];
    for ((edge, _), x) in sides.iter().zip(&at) {
        if let Some((_, _, x)) = x {
            send[0].extend_from_slice(&[edge[0], edge[1], x[0].to_bits(), x[1].to_bits()]);
        }
    }
    mpi.exchange(send).concat()
}

/// Every rank's answer to `ask` from its parts, on the first rank (`None` elsewhere, and
/// where a group node is in no part). Collective.
fn tell(mpi: &Mpi, ask: &Ask, lists: &[PartLists], node_part: &[Vec<u32>]) -> Option<Told> {
    let mut sorted: Vec<(u64, usize)> = ask.tags.iter().copied().zip(0..).collect();
    sorted.sort_unstable();
    let asked = |tag: u64| -> Option<usize> {
        let i = sorted.binary_search_by_key(&tag, |s| s.0).ok()?;
        Some(sorted[i].1)
    };
    let wanted: HashSet<u64> = ask.firsts.iter().copied().collect();
    let (mut parts, mut touch, mut firsts) = (Vec::new(), Vec::new(), Vec::new());
    let mut sides = Vec::new();
    for (l, labels) in lists.iter().zip(node_part) {
        let ks: Vec<Option<usize>> = l.nodes.iter().map(|&t| asked(t)).collect();
        for (k, &q) in ks.iter().zip(labels) {
            if let Some(k) = k {
                parts.extend_from_slice(&[*k as u64, u64::from(q)]);
            }
        }
        for (v, (&f, xy)) in l.file_nodes.iter().zip(&l.xy).enumerate() {
            if wanted.contains(&f) && l.owned[v] {
                let j = ask.firsts.iter().position(|&g| g == f).unwrap_or_default();
                firsts.extend_from_slice(&[j as u64, xy[0].to_bits(), xy[1].to_bits()]);
            }
        }
        // The part's asked nodes, few: a search among them per corner.
        let here: Vec<(u64, usize)> = (l.nodes.iter().zip(&ks))
            .filter_map(|(&t, k)| Some((t, (*k)?)))
            .collect();
        if here.is_empty() {
            continue;
        }
        for (t, &e) in l.triangles.iter().zip(&l.elements) {
            let ks = t.map(|tag| here.binary_search_by_key(&tag, |h| h.0).ok());
            for i in ks.iter().flatten() {
                let body = u64::from(run_value(&ask.runs, e));
                touch.extend_from_slice(&[here[*i].1 as u64, body]);
            }
            // An edge between two asked nodes, with the point of its third corner (a
            // contact line's edge turns its normal away from it).
            for c in 0..3 {
                let (Some(a), Some(b)) = (ks[c], ks[(c + 1) % 3]) else {
                    continue;
                };
                let (a, b) = (here[a].1 as u64, here[b].1 as u64);
                let Ok(i) = l.nodes.binary_search(&t[(c + 2) % 3]) else {
                    continue;
                };
                let x = l.xy[i];
                sides.extend_from_slice(&[a.min(b), a.max(b), x[0].to_bits(), x[1].to_bits()]);
            }
        }
    }
    let to_first = |values: Vec<u64>| {
        let mut send: Vec<Vec<u64>> = vec![Vec::new(); mpi.size];
        send[0] = values;
        mpi.exchange(send).concat()
    };
    let (parts, touch, firsts) = (to_first(parts), to_first(touch), to_first(firsts));
    let sides = to_first(sides);
    if !mpi.is_root() {
        return None;
    }
    let n = ask.tags.len();
    let mut part = vec![u32::MAX; n];
    for c in parts.chunks_exact(2) {
        part[c[0] as usize] = c[1] as u32;
    }
    let mut bodies = vec![Vec::new(); n];
    for c in touch.chunks_exact(2) {
        bodies[c[0] as usize].push(c[1] as u32);
    }
    for b in &mut bodies {
        b.sort_unstable();
        b.dedup();
    }
    let mut first_at = vec![[f64::NAN; 2]; ask.firsts.len()];
    for c in firsts.chunks_exact(3) {
        first_at[c[0] as usize] = [f64::from_bits(c[1]), f64::from_bits(c[2])];
    }
    let thirds = (sides.chunks_exact(4))
        .map(|c| {
            let x = [f64::from_bits(c[2]), f64::from_bits(c[3])];
            ((c[0] as usize, c[1] as usize), x)
        })
        .collect();
    let complete = part.iter().all(|&q| q != u32::MAX) && first_at.iter().all(|p| !p[0].is_nan());
    complete.then_some(Told {
        part,
        bodies,
        first_at,
        thirds,
    })
}

/// What the first rank knows of the whole mesh from the ranks.
struct Whole<'a> {
    nodes: usize,
    triangles: usize,
    bbox: ([f64; 2], [f64; 2]),
    /// The boundary edges' ends (file indices), two values each.
    boundary: Vec<u64>,
    part_first: &'a [u64],
}

/// The conditions and figures on the groups' mesh, or the fault of the input that the
/// whole problem names first; `None` where something else is off.
fn on_groups(
    case: &Case,
    groups: GroupMesh,
    runs: Vec<(u64, u32)>,
    told: Option<Told>,
    whole: Whole,
) -> Option<Result<OnGroups>> {
    let told = told?;
    let file: Vec<usize> = groups.file.iter().map(|&f| f as usize).collect();
    let compact = |f: u64| file.binary_search(&(f as usize)).ok();
    let boundary: HashSet<(usize, usize)> = (whole.boundary.chunks_exact(2))
        .filter_map(|e| {
            let (a, b) = (compact(e[0])?, compact(e[1])?);
            Some((a.min(b), a.max(b)))
        })
        .collect();
    let parts = Parts {
        of_node: told.part.iter().map(|&q| q as usize).collect(),
        first: (whole.part_first.iter().zip(&told.first_at))
            .map(|(&f, &x)| (f as usize, x))
            .collect(),
        size: {
            let (lo, hi) = whole.bbox;
            (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.0)
        },
    };
    let sides = (&boundary, &told.thirds);
    let prob = match problem::build_on_groups(case, groups.mesh, file, sides, &parts) {
        Ok(p) => p,
        Err(e) => return Some(Err(e)),
    };
    let nodes = Conditions::records(case, &prob).ok()?;
    // The bodies at the contact, the masters' too, as the whole problem finds them.
    let masters = prob.contact_masters.iter().flatten().map(|m| m.0);
    let mut contact_bodies: Vec<u32> = (prob.contact_nodes.iter().copied().chain(masters))
        .flat_map(|v| told.bodies[v].iter().copied())
        .collect();
    contact_bodies.sort_unstable();
    contact_bodies.dedup();
    let fixed = prob.fixed.iter().filter(|f| f.is_some()).count();
    let facts = Facts {
        lengths: Lengths::of(whole.bbox, prob.contact_h),
        contact_bodies,
        n_boundary: 0,
        n_interface: 0,
        nodes: whole.nodes,
        elements: whole.triangles,
        free_dofs: 2 * whole.nodes - fixed,
        contact_nodes: prob.contact_nodes.len(),
        partition: String::new(),
        holding: prob.holding,
    };
    Some(Ok(OnGroups {
        conditions: Conditions {
            nodes,
            bodies: runs,
        },
        facts,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;

    #[test]
    fn a_node_is_named_by_its_first_line_group_then_point_group() {
        let mut mesh = Mesh {
            nodes: vec![[0.0, 0.0]; 4],
            ..Mesh::default()
        };
        mesh.line_groups.insert("top".into(), vec![[1, 2]]);
        mesh.line_groups.insert("bottom".into(), vec![[0, 1]]);
        mesh.point_groups.insert("corner".into(), vec![3]);
        let groups = GroupMesh {
            mesh,
            file: vec![4, 9, 12, 30],
            tags: vec![1, 2, 3, 4],
            triangle_blocks: Vec::new(),
        };
        assert_eq!(group_of(&groups, 9).as_deref(), Some("bottom"));
        assert_eq!(group_of(&groups, 12).as_deref(), Some("top"));
        assert_eq!(group_of(&groups, 30).as_deref(), Some("corner"));
        assert_eq!(group_of(&groups, 5), None);
    }
}
