//! The triangles of a mesh file spread over the ranks in the file's order (each rank
//! its share of the node records and of the triangle records, as the shared reading
//! parses them) put into one locality order by every rank at once: each triangle's key
//! is the Hilbert index of its first node on a grid over the whole mesh's bounding
//! box, and a sample sort hands each rank a consecutive range of the sorted triangles,
//! a compact piece of the mesh. No rank holds more than its share and its range.
//!
//! How: the triangles are first spread evenly in the file's order (the shares put the
//! nodes first and the elements after, so the first ranks hold few triangles); each
//! node's key lives on the rank that a hash of its tag names (the directory,
//! [`tag_rank`]); each rank asks the directory for its triangles' first nodes (one
//! all-to-all out, one back), sorts its triangles by key, and sends a few samples to
//! the first rank, which picks the splitters ([`splitters`]) and broadcasts them; one
//! all-to-all then moves every triangle to the rank whose range holds its key.
//!
//! The first node rather than the centroid: one node to ask for per triangle instead
//! of three, and the triangles around a node stay together.
//!
//! Why: the graph a partitioner cuts on the ranks (`dd::dist_graph`, PT-Scotch) is
//! cheap to build and to cut when each rank's triangles are neighbours of each other;
//! in the file's order they need not be (PT-Scotch took 1.78 s on a 2M-triangle graph
//! in file order against 0.34 s in a locality order, docs/performance-history.md).

use crate::dd::comm::Mpi;
use crate::mesh::renumber::hilbert_keys;
use rayon::prelude::*;

/// This rank's range of the triangles in the locality order.
#[derive(Debug, Clone, PartialEq)]
pub struct Sorted {
    /// The position of this rank's first triangle in the order.
    pub first: u64,
    /// Every rank's number of triangles, in rank order.
    pub counts: Vec<usize>,
    /// The triangles, as the tags of their nodes (each keeps its file's node order).
    pub triangles: Vec<[u64; 3]>,
    /// Each triangle's index among the file's triangle records (0 for the first).
    pub file: Vec<u64>,
    /// This rank's share of the nodes' directory, which the order was found with.
    pub nodes: Directory,
}

/// This rank's share of the nodes' directory: the nodes whose tags [`tag_rank`] names
/// this rank, by increasing tag, each with its index among the file's nodes and its
/// x, y.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Directory {
    pub tags: Vec<u64>,
    pub file: Vec<u64>,
    pub xy: Vec<[f64; 2]>,
}

impl Directory {
    /// From entries (tag, file index, x bits, y bits, ...) sorted by tag; `None` where
    /// a tag comes twice.
    fn of<const W: usize>(entries: &[[u64; W]], file: usize) -> Option<Self> {
        if entries.windows(2).any(|w| w[0][0] == w[1][0]) {
            return None;
        }
        Some(Directory {
            tags: entries.iter().map(|e| e[0]).collect(),
            file: entries.iter().map(|e| e[file]).collect(),
            xy: (entries.iter())
                .map(|e| [f64::from_bits(e[file + 1]), f64::from_bits(e[file + 2])])
                .collect(),
        })
    }
}

/// The directory of the ranks' shares of the nodes ([`share_nodes`]); `None` on every
/// rank where a tag is held twice. One all-to-all. Collective; one subdomain per rank.
pub fn directory(mpi: &Mpi, nodes: &ShareNodes) -> Option<Directory> {
    let p = mpi.size;
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for (k, (&tag, xy)) in nodes.tags.iter().zip(&nodes.xy).enumerate() {
        let at = nodes.first + k as u64;
        send[tag_rank(tag, p)].extend_from_slice(&[tag, at, xy[0].to_bits(), xy[1].to_bits()]);
    }
    let mut known: Vec<[u64; 4]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]))
        .collect();
    known.par_sort_unstable_by_key(|e| e[0]);
    let directory = Directory::of(&known, 1);
    mpi.all_ok(directory.is_some())
        .then_some(directory)
        .flatten()
}

/// The rank of `procs` that holds node `tag` in the directory: a mix of the tag
/// (splitmix64), so that the nodes spread evenly whatever the tags.
pub fn tag_rank(tag: u64, procs: usize) -> usize {
    let mut z = tag.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z % procs as u64) as usize
}

/// `procs - 1` splitters from every rank's samples (each a sort key, (Hilbert key,
/// file index)), at even steps through them sorted: rank r then takes the keys from
/// splitter r - 1 (inclusive) to splitter r (exclusive).
pub fn splitters(mut samples: Vec<[u64; 2]>, procs: usize) -> Vec<[u64; 2]> {
    samples.sort_unstable();
    if samples.is_empty() {
        return vec![[u64::MAX; 2]; procs.saturating_sub(1)];
    }
    (1..procs)
        .map(|r| samples[(r * samples.len() / procs).min(samples.len() - 1)])
        .collect()
}

/// Samples per rank: with `procs - 1` regular samples per rank no range exceeds twice
/// the mean (the bound of sorting by regular sampling); four times as many bring it
/// near 1.25, and the partitioner works on the ranges that come out.
fn samples_per_rank(procs: usize) -> usize {
    4 * procs
}

/// The triangles `triangles` of this rank's share (node tags; this rank's share comes
/// after the shares of the ranks before it in the file) in the locality order, given
/// the share's nodes: `tags` and their `coords` (x, y, z each; a share's tags and
/// coordinates may end at different nodes). `None` on every rank when a triangle's
/// first node is held by no rank or a node by two: the first rank's reading of the
/// whole file then finds and names the fault (it checks the other nodes too, which the
/// order does not read). Collective; one subdomain per rank.
pub fn sort_triangles(
    mpi: &Mpi,
    tags: &[u64],
    coords: &[f64],
    triangles: &[[u64; 3]],
) -> Option<Sorted> {
    let p = mpi.size;
    // The grid over the whole mesh.
    let mut bbox = [f64::NEG_INFINITY; 4];
    for xyz in coords.chunks_exact(3) {
        let (x, y) = (xyz[0], xyz[1]);
        bbox = [
            bbox[0].max(-x),
            bbox[1].max(-y),
            bbox[2].max(x),
            bbox[3].max(y),
        ];
    }
    mpi.max_in_place(&mut bbox);
    let bbox = [[-bbox[0], -bbox[1]], [bbox[2], bbox[3]]];
    let (file_first, triangles) = balanced(mpi, triangles);
    let share = share_nodes(mpi, tags, coords);

    // The directory: each node's key, file index and x, y on the rank its tag names.
    let keys = hilbert_keys(&share.xy, bbox);
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    for (i, ((&t, &k), xy)) in share.tags.iter().zip(&keys).zip(&share.xy).enumerate() {
        let at = share.first + i as u64;
        send[tag_rank(t, p)].extend_from_slice(&[t, k, at, xy[0].to_bits(), xy[1].to_bits()]);
    }
    drop((keys, share));
    let mut directory: Vec<[u64; 5]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(5).map(|c| [c[0], c[1], c[2], c[3], c[4]]))
        .collect();
    directory.par_sort_unstable_by_key(|e| e[0]);
    let nodes = Directory::of(&directory, 2);
    let mut ok = nodes.is_some();

    // A triangle's key is its first node's: the triangles around a node go together,
    // and one node per triangle is asked for (once per node). The first nodes sorted
    // by tag give the nodes to ask for and each triangle's.
    let mut firsts: Vec<(u64, u32)> = (triangles.par_iter().enumerate())
        .map(|(i, t)| (t[0], i as u32))
        .collect();
    firsts.par_sort_unstable();
    let mut node_of = vec![0u32; firsts.len()];
    let mut ask: Vec<Vec<u64>> = vec![Vec::new(); p];
    let mut place: Vec<(u32, u32)> = Vec::new();
    for (k, &(t, i)) in firsts.iter().enumerate() {
        if k == 0 || firsts[k - 1].0 != t {
            let q = tag_rank(t, p);
            place.push((q as u32, ask[q].len() as u32));
            ask[q].push(t);
        }
        node_of[i as usize] = (place.len() - 1) as u32;
    }
    drop(firsts);
    let answers: Vec<Vec<u64>> = (mpi.exchange(ask).iter())
        .map(|asked| {
            let (found, all) = look_up(&directory, asked);
            ok &= all;
            found
        })
        .collect();
    drop(directory);
    let got = mpi.exchange(answers);
    if !mpi.all_ok(ok) {
        return None;
    }
    // Key and file index: the file index breaks ties, so the order is one order of
    // the whole mesh whatever the ranks.
    let mut order: Vec<[u64; 2]> = (node_of.par_iter().enumerate())
        .map(|(i, &n)| {
            let (q, k) = place[n as usize];
            [got[q as usize][k as usize], file_first + i as u64]
        })
        .collect();
    drop((node_of, got));
    order.par_sort_unstable();

    // Splitters from regular samples, picked on the first rank.
    let s = samples_per_rank(p).min(order.len());
    let samples: Vec<u64> = (0..s).flat_map(|j| order[j * order.len() / s]).collect();
    let counts = mpi.all_gather_counts(samples.len());
    let all = mpi.gather_varcount(&samples, &counts);
    let cuts = all.map(|a| splitters(a.chunks_exact(2).map(|c| [c[0], c[1]]).collect(), p));
    let cuts = match p {
        1 => Vec::new(),
        _ => mpi.broadcast(cuts).ok()?,
    };

    // Every triangle to the rank whose range holds its key: key, file index, nodes.
    let mut send: Vec<Vec<u64>> = Vec::with_capacity(p);
    let mut from = 0;
    for r in 0..p {
        let to = match cuts.get(r) {
            Some(c) => from + order[from..].partition_point(|x| x < c),
            None => order.len(),
        };
        let mut list = Vec::with_capacity(5 * (to - from));
        for &[k, f] in &order[from..to] {
            list.extend_from_slice(&[k, f]);
            list.extend_from_slice(&triangles[(f - file_first) as usize]);
        }
        send.push(list);
        from = to;
    }
    drop((order, triangles));
    let mut mine: Vec<[u64; 5]> = (mpi.exchange(send).iter())
        .flat_map(|v| v.chunks_exact(5))
        .map(|c| [c[0], c[1], c[2], c[3], c[4]])
        .collect();
    // The ranks' runs came sorted: a stable sort merges them.
    mine.par_sort_by_key(|r| [r[0], r[1]]);
    let counts = mpi.all_gather_counts(mine.len());
    let first = counts[..mpi.rank].iter().map(|&c| c as u64).sum();
    Some(Sorted {
        first,
        counts,
        triangles: mine.iter().map(|r| [r[2], r[3], r[4]]).collect(),
        file: mine.iter().map(|r| r[1]).collect(),
        nodes: nodes.unwrap_or_default(),
    })
}

/// This rank's even share of the triangles in the file's order (rank r the `r`-th of
/// `p` consecutive ranges of about as many), and the file index of its first: the
/// shares of the file put the nodes before the elements, so that the first ranks hold
/// few triangles or none. One all-to-all.
fn balanced(mpi: &Mpi, triangles: &[[u64; 3]]) -> (u64, Vec<[u64; 3]>) {
    let p = mpi.size;
    let now = mpi.all_gather_counts(triangles.len());
    let total: usize = now.iter().sum();
    let even: Vec<usize> = (0..p)
        .map(|r| total * (r + 1) / p - total * r / p)
        .collect();
    let flat: Vec<u64> = triangles.iter().flatten().copied().collect();
    let mine = redistribute(mpi, &flat, 3, &now, &even);
    let first = total * mpi.rank / p;
    (
        first as u64,
        mine.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    )
}

/// This rank's share of the file's nodes, each with its tag, its index among the
/// file's nodes and its x, y (see [`tags_of_coordinates`]). Collective.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShareNodes {
    /// The file index of the first.
    pub first: u64,
    pub tags: Vec<u64>,
    pub xy: Vec<[f64; 2]>,
}

/// The nodes of this rank's share of the file (`tags`, `coords`: x, y, z each, as the
/// shares parse them), each tag with its coordinates. Collective; one subdomain per
/// rank.
pub fn share_nodes(mpi: &Mpi, tags: &[u64], coords: &[f64]) -> ShareNodes {
    let n = coords.len() / 3;
    let before = mpi.all_gather_counts(n)[..mpi.rank].iter().sum::<usize>();
    ShareNodes {
        first: before as u64,
        tags: tags_of_coordinates(mpi, tags, n),
        xy: coords.chunks_exact(3).map(|c| [c[0], c[1]]).collect(),
    }
}

/// The node tags that go with this rank's coordinates: a share of the file may end
/// inside a block's list of tags, its coordinates then lying in the next share, so
/// the tags move to the rank that holds their nodes' coordinates (node `i` of the file
/// has the `i`-th tag and the `i`-th coordinates). One all-to-all.
fn tags_of_coordinates(mpi: &Mpi, tags: &[u64], nodes: usize) -> Vec<u64> {
    let now = mpi.all_gather_counts(tags.len());
    let want = mpi.all_gather_counts(nodes);
    redistribute(mpi, tags, 1, &now, &want)
}

/// An array spread over the ranks in consecutive ranges (rank r holds `now[r]` items
/// of `width` values each, `values` here) spread again, rank r to hold `want[r]`
/// items (the same total): this rank's new range. One all-to-all.
fn redistribute(
    mpi: &Mpi,
    values: &[u64],
    width: usize,
    now: &[usize],
    want: &[usize],
) -> Vec<u64> {
    let p = mpi.size;
    let from: usize = now[..mpi.rank].iter().sum();
    let mut send: Vec<Vec<u64>> = vec![Vec::new(); p];
    let mut start = 0;
    for (q, list) in send.iter_mut().enumerate() {
        let (lo, hi) = (start.max(from), (start + want[q]).min(from + now[mpi.rank]));
        if lo < hi {
            list.extend_from_slice(&values[width * (lo - from)..width * (hi - from)]);
        }
        start += want[q];
    }
    mpi.exchange(send).concat()
}

/// The key of each of the `asked` tags (increasing) from the `directory` (tag, key;
/// increasing tags), in one walk through both; and whether every tag was found (a
/// missing one gets key 0).
fn look_up(directory: &[[u64; 5]], asked: &[u64]) -> (Vec<u64>, bool) {
    let mut found = Vec::with_capacity(asked.len());
    let mut all = true;
    let mut i = 0;
    for &t in asked {
        while i < directory.len() && directory[i][0] < t {
            i += 1;
        }
        match directory.get(i) {
            Some(e) if e[0] == t => found.push(e[1]),
            _ => {
                all = false;
                found.push(0);
            }
        }
    }
    (found, all)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitters_cut_the_sorted_samples_evenly() {
        let samples: Vec<[u64; 2]> = (0..12u64).rev().map(|k| [k / 2, k]).collect();
        assert_eq!(splitters(samples, 3), vec![[2, 4], [4, 8]]);
        assert_eq!(splitters(Vec::new(), 3), vec![[u64::MAX; 2]; 2]);
        assert!(splitters(vec![[1, 1]], 1).is_empty());
    }

    #[test]
    fn the_directory_answers_in_the_order_asked_and_flags_a_missing_tag() {
        let dir = [[2, 20, 0, 0, 0], [5, 50, 1, 0, 0], [9, 90, 2, 0, 0]];
        assert_eq!(look_up(&dir, &[2, 9]), (vec![20, 90], true));
        assert_eq!(look_up(&dir, &[5, 7]), (vec![50, 0], false));
        assert_eq!(look_up(&dir, &[]), (vec![], true));
    }

    #[test]
    fn a_directory_refuses_a_tag_held_twice() {
        let x = 1.5f64.to_bits();
        let d = Directory::of(&[[2, 7, x, x], [5, 3, x, x]], 1).expect("a directory");
        assert_eq!(
            (d.tags, d.file, d.xy),
            (vec![2, 5], vec![7, 3], vec![[1.5, 1.5]; 2])
        );
        assert!(Directory::of(&[[2, 7, x, x], [2, 3, x, x]], 1).is_none());
    }

    #[test]
    fn tags_spread_over_the_ranks() {
        let mut hits = [0usize; 5];
        for t in 1..=1000u64 {
            hits[tag_rank(t, 5)] += 1;
        }
        assert!(hits.iter().all(|&h| (150..250).contains(&h)), "{hits:?}");
        assert_eq!(tag_rank(42, 1), 0);
    }
}
