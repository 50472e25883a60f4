//! The mesh checks of `mesh::validate::check` made by the ranks on their parts, no rank
//! holding more than its parts, its share of the nodes' directory and its share of the
//! edges: the same faults, named by the same messages, as the check of the whole mesh
//! on one rank; and what that check leaves for the problem: the boundary edges (each
//! on one rank), the separate parts of the mesh (each node's, and each part's lowest
//! node) and the bounding box.
//!
//! Why: it is the step after the part lists in a start in which the first rank no
//! longer holds the whole mesh (docs/cost-model.md, "The start from one Gmsh file"):
//! the first rank then builds only the problem's conditions, from the groups and these
//! boundary edges and parts, which are sized like the boundary.
//!
//! How each check is split (node and triangle numbers are the file's, from 0):
//! - the bounding box: one reduction over the directory, which holds every node of the
//!   file once, used or not;
//! - degenerate triangles and the orientation: each part's own, the first fault the
//!   lowest triangle number over all ranks;
//! - the edges: an edge with an end inside a part has all its triangles in that part
//!   and is matched there; the others (both ends on the part's interface) travel to the
//!   rank that a hash of their ends names ([`dist_graph::edge_rank`]) with every
//!   triangle that runs them, and are matched there: boundary edges, and folds, the
//!   first the lowest (low end, high end) pair, as the serial scan meets it;
//! - the separate parts: joined within each rank, then through the interface nodes on
//!   their directory ranks, the few joins left to the first rank; numbered by their
//!   lowest node as the serial check numbers them;
//! - unused nodes: the directory's nodes that no part touches;
//! - duplicate nodes: the serial sweep over columns of the mesh's tolerance, each
//!   column on the rank a hash of it names, with a copy of the next column; the parts
//!   of two used nodes at one place are sent to the directory only when such a pair
//!   exists.

use crate::dd::comm::{decode, encode, Mpi};
use crate::dd::dist_graph::edge_rank;
use crate::dd::locality::{tag_rank, Directory};
use crate::dd::ownership::{NodeParts, PartLists};
use crate::error::Result;
use crate::mesh::validate::{self, SAME_POINT};
use rayon::prelude::*;
use serde::{de::DeserializeOwned, Deserialize, Serialize};

/// What the checks leave on a rank.
#[derive(Debug, Clone, PartialEq)]
pub struct Checked {
    /// The boundary edges matched on this rank: their ends' file indices in the order
    /// a counter-clockwise triangle runs them (the body on their left).
    pub boundary: Vec<[u64; 2]>,
    /// Per part of this rank (in the lists' order), whether each triangle is listed
    /// clockwise in the file.
    pub listed_cw: Vec<Vec<bool>>,
    /// Per part of this rank, the separate part of the mesh of each of its nodes.
    pub node_part: Vec<Vec<u32>>,
    /// Each separate part's lowest node (file index), increasing: parts are numbered so.
    pub part_first: Vec<u64>,
    /// The lower and upper corners of the box around every node of the file.
    pub bbox: ([f64; 2], [f64; 2]),
}

/// A fault of the mesh, with what its message names (the serial check's messages,
/// [`Fault::message`]). Node and triangle numbers are the file's, from 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Fault {
    Duplicate {
        first: Node,
        second: Node,
        pairs: usize,
    },
    Unused {
        count: usize,
        first: Node,
    },
    Degenerate {
        triangle: u64,
        nodes: [u64; 3],
        at: [f64; 2],
    },
    Fold {
        bad: u64,
        nodes: [u64; 3],
        centroid: [f64; 2],
        edge: [[f64; 2]; 2],
        other: u64,
    },
    /// A triangle listed twice (its first fold): the serial reading drops the repeat
    /// before any check, so its faults (if any) are not these; no message of its own.
    Repeat,
}

impl Fault {
    /// The message of the mesh `name`; `group` names the groups a node is in (for an
    /// unused node, which the serial check places in its first group).
    pub fn message(&self, name: &str, group: impl Fn(u64) -> Option<String>) -> String {
        let us = |i: u64| i as usize;
        match self {
            Fault::Duplicate {
                first,
                second,
                pairs,
            } => validate::duplicate_message(
                name,
                (us(first.0), first.1),
                (us(second.0), second.1),
                *pairs,
            ),
            Fault::Unused { count, first } => {
                let g = group(first.0);
                validate::unused_message(name, *count, (us(first.0), first.1), g.as_deref())
            }
            Fault::Degenerate {
                triangle,
                nodes,
                at,
            } => validate::degenerate_message(name, us(*triangle), nodes.map(us), *at),
            Fault::Fold {
                bad,
                nodes,
                centroid,
                edge,
                other,
            } => validate::fold_message(
                name,
                (us(*bad), nodes.map(us), *centroid),
                *edge,
                us(*other),
            ),
            Fault::Repeat => format!("{name}: a triangle is listed twice"),
        }
    }
}

/// The checks of the mesh whose nodes' directory is spread as `directory` (every node
/// of the file) and `around` (the nodes of the triangles, with their parts), whose
/// parts this rank holds are `lists`, and whose box is `bbox` ([`bounding_box`] of the
/// directory). The same result on every rank. Collective; one subdomain per rank.
pub fn check(
    mpi: &Mpi,
    (directory, around): (&Directory, &NodeParts),
    lists: &[PartLists],
    bbox: ([f64; 2], [f64; 2]),
) -> Result<std::result::Result<Checked, Fault>> {
    let size = (bbox.1[0] - bbox.0[0]).max(bbox.1[1] - bbox.0[1]).max(0.0);
    let local: Vec<Local> = lists.par_iter().map(|l| Local::of(l, size)).collect();

    let degenerate = (local.iter().zip(lists))
        .filter_map(|(loc, l)| loc.degenerate.map(|t| (loc, l, t)))
        .map(|(loc, l, t)| {
            let c = loc.triangles[t];
            let fault = Fault::Degenerate {
                triangle: l.elements[t],
                nodes: c.map(|v| l.file_nodes[v]),
                at: l.xy[c[0]],
            };
            (l.elements[t], fault)
        })
        .min_by_key(|f| f.0);
    let degenerate = first_of(mpi, degenerate)?;

    let (boundary, fold) = edges(mpi, &local, lists);
    let fold = first_of(mpi, fold)?;
    let fold = match fold {
        Some(f) => Some(fold_fault(mpi, &local, lists, f)?),
        None => None,
    };

    let (node_part, part_first) = parts(mpi, &local, lists)?;
    let (idle, first_idle) = unused(directory, around);
    let count: usize = mpi.all_gather_counts(idle).iter().sum();
    let unused =
        first_of(mpi, first_idle.map(|u| (u.0, u)))?.map(|first| Fault::Unused { count, first });
    let duplicate = duplicates(mpi, directory, around, lists, &node_part, bbox)?;

    // A repeat changes the serial reading's triangles, whatever else is wrong.
    let fault = match fold {
        Some(Fault::Repeat) => Some(Fault::Repeat),
        _ => [duplicate, unused, degenerate, fold]
            .into_iter()
            .flatten()
            .next(),
    };
    Ok(match fault {
        Some(f) => Err(f),
        None => Ok(Checked {
            boundary,
            listed_cw: local.into_iter().map(|l| l.listed_cw).collect(),
            node_part,
            part_first,
            bbox,
        }),
    })
}

/// The box around every rank's `xy`. Collective.
pub fn bounding_box(mpi: &Mpi, xy: &[[f64; 2]]) -> ([f64; 2], [f64; 2]) {
    let (lo, hi) = validate::bounding_box(xy);
    let mut v = [-lo[0], -lo[1], hi[0], hi[1]];
    mpi.max_in_place(&mut v);
    ([-v[0], -v[1]], [v[2], v[3]])
}

/// A node off the plane of the file's first node, as the reading finds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffPlane {
    pub tag: u64,
    pub z: f64,
    pub first_tag: u64,
    pub first_z: f64,
}

/// The first node in file order farther in z from the file's first node than the
/// reading's tolerance (`mesh::gmsh::plane_tolerance` of the box `bbox`): `Some` on
/// every rank where there is one, its figures on the first rank (`None` there should
/// the directory lack a tag). `z` is this rank's share of the file's nodes' z, in file
/// order after the ranks before it; `directory` gives their tags. Collective: two
/// gathers and a broadcast of a few numbers.
pub fn off_plane(
    mpi: &Mpi,
    z: &[f64],
    directory: &Directory,
    (lo, hi): ([f64; 2], [f64; 2]),
) -> Result<Option<Option<OffPlane>>> {
    let before: usize = mpi.all_gather_counts(z.len())[..mpi.rank].iter().sum();
    let mut first_z = [match (before, z.first()) {
        (0, Some(&z)) => z,
        _ => f64::NEG_INFINITY,
    }];
    mpi.max_in_place(&mut first_z);
    let first_z = first_z[0];
    let tolerance = crate::mesh::gmsh::plane_tolerance((hi[0] - lo[0]).max(hi[1] - lo[1]));
    let mine = (z.iter().position(|&v| (v - first_z).abs() > tolerance))
        .map(|k| ((before + k) as u64, z[k]));
    let off = mpi.gather_parts(mine)?.map(|all| {
        let mut all = all.into_iter().flatten();
        all.next()
    });
    let Some((at, z_at)) = mpi.broadcast(off)? else {
        return Ok(None);
    };
    let tags: Vec<(u64, u64)> = (directory.file.iter().zip(&directory.tags))
        .filter(|(&f, _)| f == at || f == 0)
        .map(|(&f, &t)| (f, t))
        .collect();
    let found = mpi.gather_parts(tags)?.map(|all| {
        let all: Vec<(u64, u64)> = all.into_iter().flatten().collect();
        let tag_of = |f: u64| all.iter().find(|x| x.0 == f).map(|x| x.1);
        Some(OffPlane {
            tag: tag_of(at)?,
            z: z_at,
            first_tag: tag_of(0)?,
            first_z,
        })
    });
    Ok(Some(found.flatten()))
}

/// A part's triangles on its own nodes.
struct Local {
    /// The triangles' corners (indices into the part's nodes), turned counter-clockwise
    /// where they were listed clockwise (degenerate ones as listed).
    triangles: Vec<[usize; 3]>,
    listed_cw: Vec<bool>,
    /// The first degenerate triangle, if any (by place, so by file index).
    degenerate: Option<usize>,
    /// Whether each node lies on the part's interface.
    on_interface: Vec<bool>,
}

impl Local {
    fn of(l: &PartLists, size: f64) -> Self {
        let mut triangles = corners(&l.nodes, &l.triangles);
        let mut listed_cw = vec![false; triangles.len()];
        let mut degenerate = None;
        for (t, (tri, cw)) in triangles.iter_mut().zip(&mut listed_cw).enumerate() {
            match validate::clockwise(&l.xy, *tri, size) {
                Some(true) => {
                    tri.swap(1, 2);
                    *cw = true;
                }
                Some(false) => {}
                None => {
                    degenerate.get_or_insert(t);
                }
            }
        }
        let mut on_interface = vec![false; l.nodes.len()];
        let mut at = 0;
        for tag in &l.interface {
            while l.nodes[at] < *tag {
                at += 1;
            }
            on_interface[at] = true;
        }
        Local {
            triangles,
            listed_cw,
            degenerate,
            on_interface,
        }
    }
}

/// The corners of `triangles` (node tags) as indices into `nodes` (tags, increasing,
/// every corner among them): one sort of the corners and a walk along the tags.
fn corners(nodes: &[u64], triangles: &[[u64; 3]]) -> Vec<[usize; 3]> {
    let mut all: Vec<(u64, usize)> = (triangles.par_iter().enumerate())
        .flat_map_iter(|(i, t)| (0..3).map(move |c| (t[c], 3 * i + c)))
        .collect();
    all.par_sort_unstable();
    let mut out = vec![[0usize; 3]; triangles.len()];
    let mut at = 0;
    for (tag, slot) in all {
        while nodes[at] < tag {
            at += 1;
        }
        out[slot / 3][slot % 3] = at;
    }
    out
}

/// The key of a fold: its edge's ends (low, high), then its two triangles.
type FoldKey = ([u64; 2], [u64; 2]);

/// The boundary edges matched on this rank (see [`Checked::boundary`]), and its first
/// fold. Collective.
fn edges(
    mpi: &Mpi,
    local: &[Local],
    lists: &[PartLists],
) -> (Vec<[u64; 2]>, Option<(FoldKey, FoldKey)>) {
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); mpi.size];
    let mut boundary = Vec::new();
    let mut fold: Option<FoldKey> = None;
    for (loc, l) in local.iter().zip(lists) {
        match_inside(loc, l, &mut boundary, &mut fold, &mut send);
    }
    let mut there: Vec<[u64; 3]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]))
        .collect();
    match_runs(&mut there, &mut boundary, &mut fold);
    (boundary, fold.map(|f| (f, f)))
}

/// Matches the edges of a part with an end inside it, in rows of their lower end in the
/// part's own numbering (as the serial check does: no sort of all the edges), and puts
/// the others' records in `send`, by the rank that matches them.
fn match_inside(
    loc: &Local,
    l: &PartLists,
    boundary: &mut Vec<[u64; 2]>,
    fold: &mut Option<FoldKey>,
    send: &mut [Vec<u64>],
) {
    let n = l.nodes.len();
    let sides = |t: &[usize; 3]| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])];
    let inside = |a: usize, b: usize| !(loc.on_interface[a] && loc.on_interface[b]);
    let mut start = vec![0usize; n + 1];
    for t in &loc.triangles {
        for (a, b) in sides(t).into_iter().filter(|&(a, b)| inside(a, b)) {
            start[a.min(b) + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    // (higher end, triangle << 1 | 1 when the triangle runs the edge from the lower end)
    let mut entries = vec![(0usize, 0u64); start[n]];
    for (t, &e) in loc.triangles.iter().zip(&l.elements) {
        for (a, b) in sides(t) {
            let (fa, fb) = (l.file_nodes[a], l.file_nodes[b]);
            if !inside(a, b) {
                let record = [fa.min(fb), fa.max(fb), e << 1 | u64::from(fa < fb)];
                send[edge_rank(record[0], record[1], send.len())].extend_from_slice(&record);
                continue;
            }
            let low = a.min(b);
            entries[fill[low]] = (a.max(b), e << 1 | u64::from(a == low));
            fill[low] += 1;
        }
    }
    for low in 0..n {
        let row = &mut entries[start[low]..start[low + 1]];
        row.sort_unstable();
        for run in row.chunk_by(|x, y| x.0 == y.0) {
            let (fl, fh) = (l.file_nodes[low], l.file_nodes[run[0].0]);
            match run {
                [one] if one.1 & 1 == 1 => boundary.push([fl, fh]),
                [_] => boundary.push([fh, fl]),
                [x, y] if (x.1 ^ y.1) & 1 == 1 => {}
                _ => {
                    let (x, y) = validate::same_way(run.iter().map(|r| r.1));
                    let key = ([fl.min(fh), fl.max(fh)], [x, y]);
                    if fold.is_none_or(|f| key < f) {
                        *fold = Some(key);
                    }
                }
            }
        }
    }
}

/// The runs of edge `records` (low, high, triangle << 1 | 1 when it runs low to high):
/// an edge run once is a boundary edge, run once each way an inner one, anything else a
/// fold, of which the lowest is kept in `fold`.
fn match_runs(records: &mut [[u64; 3]], boundary: &mut Vec<[u64; 2]>, fold: &mut Option<FoldKey>) {
    records.par_sort_unstable();
    for run in records.chunk_by(|x, y| x[0] == y[0] && x[1] == y[1]) {
        let [low, high, code] = run[0];
        match run {
            [_] if code & 1 == 1 => boundary.push([low, high]),
            [_] => boundary.push([high, low]),
            [x, y] if (x[2] ^ y[2]) & 1 == 1 => {}
            _ => {
                let (x, y) = validate::same_way(run.iter().map(|r| r[2]));
                let key = ([low, high], [x, y]);
                if fold.is_none_or(|f| key < f) {
                    *fold = Some(key);
                }
            }
        }
    }
}

/// What the rank that holds a triangle of a fold knows of it.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct FoldSide {
    triangle: u64,
    listed_cw: bool,
    nodes: [u64; 3],
    centroid: [f64; 2],
    /// The edge's ends' points.
    edge: [[f64; 2]; 2],
}

/// The fault of the first fold (`([low, high], [x, y])`): which of its triangles is the
/// inverted one needs their listing and the file's. Collective.
fn fold_fault(mpi: &Mpi, local: &[Local], lists: &[PartLists], key: FoldKey) -> Result<Fault> {
    let ([low, high], [x, y]) = key;
    let mut sides = Vec::new();
    let mut cw = 0;
    for (loc, l) in local.iter().zip(lists) {
        cw += loc.listed_cw.iter().filter(|&&c| c).count();
        for t in [x, y] {
            let Ok(i) = l.elements.binary_search(&t) else {
                continue;
            };
            let c = loc.triangles[i];
            let point = |f: u64| c.iter().find(|&&v| l.file_nodes[v] == f).map(|&v| l.xy[v]);
            let (Some(p), Some(q)) = (point(low), point(high)) else {
                continue;
            };
            let [a, b, d] = c.map(|v| l.xy[v]);
            sides.push(FoldSide {
                triangle: t,
                listed_cw: loc.listed_cw[i],
                nodes: c.map(|v| l.file_nodes[v]),
                centroid: [(a[0] + b[0] + d[0]) / 3.0, (a[1] + b[1] + d[1]) / 3.0],
                edge: [p, q],
            });
        }
    }
    let triangles: usize = lists.iter().map(|l| l.elements.len()).sum();
    let cw: usize = mpi.all_gather_counts(cw).iter().sum();
    let triangles: usize = mpi.all_gather_counts(triangles).iter().sum();
    let cw_majority = 2 * cw > triangles;
    let sides = to_first(mpi, &sides)?.map(|all| all.concat());
    let fault = sides.map(|sides| {
        let side = |t: u64| sides.iter().find(|s| s.triangle == t);
        let (sx, sy) = (side(x)?, side(y)?);
        let set = |s: &FoldSide| {
            let mut n = s.nodes;
            n.sort_unstable();
            n
        };
        if set(sx) == set(sy) {
            return Some(Fault::Repeat);
        }
        let bad = validate::inverted([x, y], |t| {
            let s = if t == x { sx } else { sy };
            s.listed_cw != cw_majority
        });
        let s = if bad == x { sx } else { sy };
        Some(Fault::Fold {
            bad,
            nodes: s.nodes,
            centroid: s.centroid,
            edge: s.edge,
            other: x + y - bad,
        })
    });
    mpi.broadcast(fault)?.ok_or_else(|| {
        crate::error::Error::Numerical("internal: a fold's triangles were not found".into())
    })
}

/// Each node's separate part of the mesh, per part of this rank, and each separate
/// part's lowest node. Collective.
fn parts(mpi: &Mpi, local: &[Local], lists: &[PartLists]) -> Result<(Vec<Vec<u32>>, Vec<u64>)> {
    // This rank's nodes (every part's, once) joined through its triangles.
    let mut tags: Vec<u64> = lists.iter().flat_map(|l| l.nodes.iter().copied()).collect();
    tags.par_sort_unstable();
    tags.dedup();
    let index = |l: &PartLists| -> Vec<usize> {
        let mut at = 0;
        (l.nodes.iter())
            .map(|t| {
                while tags[at] < *t {
                    at += 1;
                }
                at
            })
            .collect()
    };
    let of_list: Vec<Vec<usize>> = lists.iter().map(index).collect();
    let mut joins = Joins::new(tags.len());
    for (loc, here) in local.iter().zip(&of_list) {
        for t in &loc.triangles {
            joins.join(here[t[0]], here[t[1]]);
            joins.join(here[t[0]], here[t[2]]);
        }
    }
    let (label, count) = joins.labels();
    // Each of this rank's pieces by a number among every rank's, and its lowest node.
    let offset: usize = mpi.all_gather_counts(count)[..mpi.rank].iter().sum();
    let mut lowest = vec![u64::MAX; count];
    for (l, here) in lists.iter().zip(&of_list) {
        for (&v, &f) in here.iter().zip(&l.file_nodes) {
            lowest[label[v]] = lowest[label[v]].min(f);
        }
    }
    // The pieces that meet at an interface node, found on its directory rank.
    let p = mpi.size;
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for (l, here) in lists.iter().zip(&of_list) {
        let mut at = 0;
        for tag in &l.interface {
            while l.nodes[at] < *tag {
                at += 1;
            }
            let piece = (offset + label[here[at]]) as u64;
            send[tag_rank(*tag, p)].extend_from_slice(&[*tag, piece]);
        }
    }
    let mut met: Vec<[u64; 2]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(2).map(|c| [c[0], c[1]]))
        .collect();
    met.par_sort_unstable();
    met.dedup();
    let mut pairs: Vec<[u64; 2]> = Vec::new();
    for run in met.chunk_by(|a, b| a[0] == b[0]) {
        pairs.extend(run[1..].iter().map(|m| [run[0][1], m[1]]));
    }
    let pairs = forest(pairs);
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    send[0] = pairs.into_iter().flatten().collect();
    let joined = mpi.exchange(send).concat();
    let lowest_all = mpi.gather_varcount(&lowest, &mpi.all_gather_counts(count));
    // On the first rank: every piece's separate part, numbered by its lowest node.
    let numbered = lowest_all.map(|lowest| {
        let mut joins = Joins::new(lowest.len());
        for c in joined.chunks_exact(2) {
            joins.join(c[0] as usize, c[1] as usize);
        }
        let (root, roots) = joins.labels();
        let mut first = vec![u64::MAX; roots];
        for (piece, &low) in lowest.iter().enumerate() {
            first[root[piece]] = first[root[piece]].min(low);
        }
        let mut order: Vec<usize> = (0..roots).collect();
        order.sort_by_key(|&r| first[r]);
        let mut number = vec![0u32; roots];
        for (k, &r) in order.iter().enumerate() {
            number[r] = k as u32;
        }
        let of_piece: Vec<u32> = root.iter().map(|&r| number[r]).collect();
        let part_first: Vec<u64> = order.iter().map(|&r| first[r]).collect();
        (of_piece, part_first)
    });
    let (of_piece, part_first) = mpi.broadcast(numbered)?;
    let node_part = (of_list.iter())
        .map(|here| here.iter().map(|&v| of_piece[offset + label[v]]).collect())
        .collect();
    Ok((node_part, part_first))
}

/// Union-find over `0..n`, each set known by its lowest member.
struct Joins {
    parent: Vec<usize>,
}

impl Joins {
    fn new(n: usize) -> Self {
        Joins {
            parent: (0..n).collect(),
        }
    }

    fn root(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn join(&mut self, a: usize, b: usize) {
        let (a, b) = (self.root(a), self.root(b));
        self.parent[a.max(b)] = a.min(b);
    }

    /// Each member's set, numbered from 0 in the order of their lowest members, and
    /// the number of sets.
    fn labels(mut self) -> (Vec<usize>, usize) {
        let n = self.parent.len();
        let mut label = vec![usize::MAX; n];
        let mut count = 0;
        let mut out = vec![0; n];
        for i in 0..n {
            let r = self.root(i);
            if label[r] == usize::MAX {
                label[r] = count;
                count += 1;
            }
            out[i] = label[r];
        }
        (out, count)
    }
}

/// The same sets as `pairs` join, by at most one pair per member but one: each member
/// paired with its set's lowest.
fn forest(mut pairs: Vec<[u64; 2]>) -> Vec<[u64; 2]> {
    let mut ids: Vec<u64> = pairs.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let at = |v: u64| ids.binary_search(&v).unwrap_or_default();
    let mut joins = Joins::new(ids.len());
    for [a, b] in pairs.drain(..) {
        joins.join(at(a), at(b));
    }
    (0..ids.len())
        .filter_map(|i| {
            let r = joins.root(i);
            (r != i).then(|| [ids[r], ids[i]])
        })
        .collect()
}

/// This rank's directory nodes that no triangle uses: their count and the first (file
/// index, point).
fn unused(directory: &Directory, around: &NodeParts) -> (usize, Option<Node>) {
    let used = used(directory, around);
    let mut count = 0;
    let mut first: Option<Node> = None;
    for (k, &u) in used.iter().enumerate() {
        if !u {
            count += 1;
            let f = directory.file[k];
            if first.is_none_or(|x| f < x.0) {
                first = Some((f, directory.xy[k]));
            }
        }
    }
    (count, first)
}

/// Whether each node of this rank's directory is used by a triangle (is in `around`,
/// the same rank's share of the used nodes).
fn used(directory: &Directory, around: &NodeParts) -> Vec<bool> {
    let mut at = 0;
    (directory.tags.iter())
        .map(|t| {
            while at < around.tags.len() && around.tags[at] < *t {
                at += 1;
            }
            around.tags.get(at) == Some(t)
        })
        .collect()
}

/// No part known for a node yet, and no part at all (an unused node).
const UNKNOWN: u64 = u64::MAX - 1;
const UNUSED: u64 = u64::MAX;

/// The fault of duplicate nodes, the serial check's (see the module's notes).
/// Collective.
fn duplicates(
    mpi: &Mpi,
    directory: &Directory,
    around: &NodeParts,
    lists: &[PartLists],
    node_part: &[Vec<u32>],
    (lo, hi): ([f64; 2], [f64; 2]),
) -> Result<Option<Fault>> {
    let tol = SAME_POINT * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(0.0);
    let used = used(directory, around);
    let mut part: Vec<u64> = used
        .iter()
        .map(|&u| if u { UNKNOWN } else { UNUSED })
        .collect();
    let mut found = close_pairs(mpi, directory, &part, lo[0], tol);
    if mpi.all_ok(!found.unsure) {
        return first_duplicate(mpi, found);
    }
    // Two used nodes at one place count only within one separate part: the parts of
    // the used nodes to the directory, and the sweep again.
    let p = mpi.size;
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for (l, parts) in lists.iter().zip(node_part) {
        for ((tag, &owned), &q) in l.nodes.iter().zip(&l.owned).zip(parts) {
            if owned {
                send[tag_rank(*tag, p)].extend_from_slice(&[*tag, u64::from(q)]);
            }
        }
    }
    let mut known: Vec<[u64; 2]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(2).map(|c| [c[0], c[1]]))
        .collect();
    known.par_sort_unstable();
    let mut at = 0;
    for (k, tag) in directory.tags.iter().enumerate() {
        while at < known.len() && known[at][0] < *tag {
            at += 1;
        }
        if known.get(at).is_some_and(|e| e[0] == *tag) {
            part[k] = known[at][1];
        }
    }
    found = close_pairs(mpi, directory, &part, lo[0], tol);
    first_duplicate(mpi, found)
}

/// A node: its file index and its point.
type Node = (u64, [f64; 2]);

/// The pairs of nodes at one place that this rank's columns hold.
struct Close {
    pairs: usize,
    first: Option<(Node, Node)>,
    /// Whether a pair of used nodes was met whose parts are not known.
    unsure: bool,
}

/// The serial sweep (`validate::column_pairs`) over columns of width `tol` from `lo`,
/// each column on the rank that [`column_rank`] names, with a copy of the next one;
/// `part` is each directory node's separate part ([`UNKNOWN`], [`UNUSED`]).
/// Collective.
fn close_pairs(mpi: &Mpi, directory: &Directory, part: &[u64], lo: f64, tol: f64) -> Close {
    let p = mpi.size;
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for ((&f, xy), &q) in directory.file.iter().zip(&directory.xy).zip(part) {
        let c = validate::column(xy[0], lo, tol);
        let record = [f, xy[0].to_bits(), xy[1].to_bits(), q];
        let (home, before) = (column_rank(c, p), column_rank(c - 1, p));
        send[home].extend_from_slice(&record);
        if before != home {
            send[before].extend_from_slice(&record);
        }
    }
    let nodes: Vec<(u64, [f64; 2], u64)> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(4))
        .map(|c| (c[0], [f64::from_bits(c[1]), f64::from_bits(c[2])], c[3]))
        .collect();
    let mut order: Vec<(i64, f64, usize)> = (nodes.iter().enumerate())
        .map(|(i, n)| (validate::column(n.1[0], lo, tol), n.1[1], i))
        .collect();
    order.par_sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut out = Close {
        pairs: 0,
        first: None,
        unsure: false,
    };
    let me = mpi.rank;
    validate::column_pairs(
        &order,
        tol,
        |c| column_rank(c, p) == me,
        |i, j| {
            let (a, b) = (&nodes[i], &nodes[j]);
            let close = (a.1[0] - b.1[0]).abs() <= tol && (a.1[1] - b.1[1]).abs() <= tol;
            if !close || (a.2 == UNUSED && b.2 == UNUSED) {
                return;
            }
            if a.2 != UNUSED && b.2 != UNUSED {
                if a.2 == UNKNOWN || b.2 == UNKNOWN {
                    out.unsure = true;
                    return;
                }
                if a.2 != b.2 {
                    return;
                }
            }
            out.pairs += 1;
            let pair = if a.0 < b.0 {
                ((a.0, a.1), (b.0, b.1))
            } else {
                ((b.0, b.1), (a.0, a.1))
            };
            if out
                .first
                .is_none_or(|f| (pair.0 .0, pair.1 .0) < (f.0 .0, f.1 .0))
            {
                out.first = Some(pair);
            }
        },
    );
    out
}

/// The fault of the lowest pair over every rank's, with every rank's count.
fn first_duplicate(mpi: &Mpi, found: Close) -> Result<Option<Fault>> {
    let pairs: usize = mpi.all_gather_counts(found.pairs).iter().sum();
    let first = found.first.map(|(a, b)| ((a.0, b.0), (a, b)));
    Ok(
        first_of(mpi, first)?.map(|(first, second)| Fault::Duplicate {
            first,
            second,
            pairs,
        }),
    )
}

/// The rank that sweeps column `c`: a mix of it (splitmix64), so that the columns
/// spread evenly whatever the mesh.
fn column_rank(c: i64, procs: usize) -> usize {
    tag_rank(c as u64, procs)
}

/// The value with the lowest key over every rank's `mine`, on every rank. Collective.
fn first_of<K, T>(mpi: &Mpi, mine: Option<(K, T)>) -> Result<Option<T>>
where
    K: Ord + Serialize + DeserializeOwned,
    T: Serialize + DeserializeOwned,
{
    let all = to_first(mpi, &mine)?;
    let best = all.map(|all| {
        all.into_iter()
            .flatten()
            .min_by(|a, b| a.0.cmp(&b.0))
            .map(|b| b.1)
    });
    mpi.broadcast(best)
}

/// Every rank's `value` on the first rank, in rank order (`None` elsewhere).
/// Collective.
fn to_first<T: Serialize + DeserializeOwned>(mpi: &Mpi, value: &T) -> Result<Option<Vec<T>>> {
    let mut send: Vec<Vec<u8>> = vec![Vec::new(); mpi.size];
    send[0] = encode(value)?;
    let got = mpi.exchange(send);
    if !mpi.is_root() {
        return Ok(None);
    }
    got.iter()
        .map(|b| decode(b))
        .collect::<Result<_>>()
        .map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_forest_joins_the_same_sets() {
        let pairs = vec![[7, 3], [3, 9], [20, 11], [9, 7], [11, 30]];
        let mut f = forest(pairs);
        f.sort_unstable();
        assert_eq!(f, vec![[3, 7], [3, 9], [11, 20], [11, 30]]);
    }

    #[test]
    fn runs_give_boundary_edges_counter_clockwise_and_the_lowest_fold() {
        // Edge (1, 2) run once from 2 to 1; edge (1, 5) once each way; edge (2, 3) twice
        // from 2 to 3 (triangles 4 and 6); edge (0, 8) by three triangles.
        let mut records = vec![
            [1, 2, 10 << 1],
            [1, 5, 3 << 1 | 1],
            [1, 5, 4 << 1],
            [2, 3, 4 << 1 | 1],
            [2, 3, 6 << 1 | 1],
            [0, 8, 7 << 1],
            [0, 8, 2 << 1 | 1],
            [0, 8, 9 << 1 | 1],
        ];
        let (mut boundary, mut fold) = (Vec::new(), None);
        match_runs(&mut records, &mut boundary, &mut fold);
        assert_eq!(boundary, vec![[2, 1]]);
        assert_eq!(fold, Some(([0, 8], [2, 9])));
    }

    #[test]
    fn corners_are_found_by_their_tags() {
        let nodes = [4, 9, 17, 30];
        let triangles = [[9, 30, 4], [17, 9, 30]];
        assert_eq!(corners(&nodes, &triangles), vec![[1, 3, 0], [2, 1, 3]]);
    }
}
