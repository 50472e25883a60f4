//! The partition of a mesh file's triangles found by every rank from its own share of
//! the file, before any rank holds the whole mesh: the triangles put in a locality
//! order (`dd::locality`), their dual graph built on the ranks (`dd::dist_graph`), cut
//! by PT-Scotch, the edges cut counted; each rank then finds its parts' lists, or,
//! where the parts are not as many on every rank, the first rank receives each
//! triangle's part, by the triangle's index among the file's triangle records.
//!
//! Why: the graph, the largest piece of the partition, then never exists on the first
//! rank, which on a cluster has only its own node's cores (docs/cost-model.md, "The
//! start from one Gmsh file"); and the locality order and the graph are the first steps
//! of a start in which each rank builds its own part of the problem.

use crate::dd::comm::Mpi;
use crate::dd::locality::Directory;
use crate::dd::ownership::{self, InterfaceFigures, NodeParts, PartLists};
use crate::dd::{dist_graph, locality};
use std::time::Instant;

/// The cut made on the ranks.
#[derive(Debug, Clone)]
pub struct ShareCut {
    /// On the first rank, each of the file's triangle records' part, where the ranks
    /// made no part lists (`lists`); `None` elsewhere. Where they made them, each rank
    /// builds its own parts, and the first rank, should its problem not match the cut,
    /// cuts it itself: a part per triangle on it would be its largest array.
    pub parts: Option<Vec<u32>>,
    /// The file's triangle records in all the shares.
    pub triangles: usize,
    /// The number of parts.
    pub nparts: usize,
    /// Edges of the dual graph between two parts.
    pub edge_cut: usize,
    /// Seconds of the locality order, the graph, the cut with its count and gather,
    /// and the part lists.
    pub seconds: [f64; 4],
    /// This rank's parts' lists (`dd::ownership`: the same number of parts on every
    /// rank, parts `rank * k ..`), where every node of the triangles is in one share:
    /// each rank then builds its own subproblems (`dd::dist_split`).
    pub lists: Option<Vec<PartLists>>,
    /// The interface's figures, on every rank, where the lists were made.
    pub figures: Option<InterfaceFigures>,
    /// Where the lists were made, this rank's share of the nodes' directory (every node
    /// of the file) and of the used nodes with their parts: the mesh checks on the ranks
    /// read them (`dd::dist_check`).
    pub directory: Option<(Directory, NodeParts)>,
}

/// The triangles of every rank's share (`triangles`: this rank's, as node tags, its
/// share after those of the ranks before it in the file; `tags` and `coords` (x, y, z
/// each): its share of the nodes) cut into `nparts` parts. `None` on every rank where
/// the shares do not make a mesh (a node no rank holds, a tag held twice), the graph
/// is too large for PT-Scotch's 32-bit numbers, or PT-Scotch fails: the first rank
/// then cuts as it does without the shares. `ties`: pairs of node tags the cut keeps
/// together (`dist_graph::with_ties`), found from the triangles in their order and the
/// nodes' directory (`dist_problem::ties`). Collective; one subdomain per rank.
pub fn cut_shares(
    mpi: &Mpi,
    (tags, coords): (&[u64], &[f64]),
    triangles: &[[u64; 3]],
    (nparts, imbalance): (usize, f64),
    ties: impl FnOnce(&[[u64; 3]], &Directory) -> Vec<[u64; 2]>,
) -> Option<ShareCut> {
    let start = Instant::now();
    let sorted = locality::sort_triangles(mpi, tags, coords, triangles)?;
    let order_s = start.elapsed().as_secs_f64();
    let total: usize = sorted.counts.iter().sum();
    if i32::try_from(total).is_err() {
        return None;
    }
    let start = Instant::now();
    let dual = dist_graph::dual_graph(mpi, &sorted.triangles);
    let ties = ties(&sorted.triangles, &sorted.nodes);
    // The edge cut counts the mesh's edges alone, as the `partition` crate's does.
    let (xadj, adjncy): (Vec<i32>, Vec<i32>) = if ties.is_empty() {
        let xadj = dual.xadj.iter().map(|&x| x as i32).collect();
        (xadj, dual.adjncy.iter().map(|&t| t as i32).collect())
    } else {
        let (x, a) = dist_graph::with_ties(mpi, &dual, &sorted.triangles, &ties);
        let xadj = x.iter().map(|&x| x as i32).collect();
        (xadj, a.iter().map(|&t| t as i32).collect())
    };
    let graph_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let local = ptscotch::LocalGraph {
        xadj: &xadj,
        adjncy: &adjncy,
        adjwgt: None,
        vwgt: None,
    };
    let parts = mpi.part_graph(local, nparts, imbalance);
    if !mpi.all_ok(parts.is_ok()) {
        return None;
    }
    let parts = parts.unwrap_or_default();
    let edge_cut = dist_graph::edge_cut(mpi, &dual, &parts, &sorted.counts);
    drop(dual);
    let cut_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let per_rank = nparts / mpi.size;
    let made = (nparts % mpi.size == 0)
        .then(|| {
            let parts: Vec<u32> = parts.iter().map(|&q| q as u32).collect();
            let around = ownership::node_parts(mpi, &sorted.triangles, &parts, &sorted.nodes)?;
            let figures = ownership::interface_figures(mpi, &around, nparts);
            let lists = ownership::part_lists(
                mpi,
                &sorted.file,
                &sorted.triangles,
                &parts,
                &around,
                per_rank,
            );
            Some((lists, figures, around))
        })
        .flatten();
    let (lists, figures, around) = match made {
        Some((l, f, a)) => (Some(l), Some(f), Some(a)),
        None => (None, None, None),
    };
    let lists_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    // Collective: every rank made the lists or none did.
    let parts = match lists {
        Some(_) => None,
        None => {
            let file = mpi.gather_varcount(&sorted.file, &sorted.counts);
            let gathered = mpi.gather_varcount(&parts, &sorted.counts);
            file.zip(gathered).map(|(file, gathered)| {
                let mut by_file = vec![0u32; total];
                for (&f, &q) in file.iter().zip(&gathered) {
                    by_file[f as usize] = q as u32;
                }
                by_file
            })
        }
    };
    Some(ShareCut {
        parts,
        triangles: total,
        nparts,
        edge_cut,
        seconds: [
            order_s,
            graph_s,
            cut_s + start.elapsed().as_secs_f64(),
            lists_s,
        ],
        lists,
        figures,
        directory: around.map(|a| (sorted.nodes, a)),
    })
}
