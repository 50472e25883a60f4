//! One MSH 4.1 file read by several processes: one of them finds where the records of
//! `$Nodes` and `$Elements` lie ([`scan`]) and cuts them into one share per process
//! ([`Scan::plan`]); each process parses its share ([`read_share`]); the first puts the
//! gathered values together into the same [`Mesh`] as [`super::parse_msh`] makes
//! ([`Scan::assemble`]). Nothing here moves data between processes.
//!
//! Why: the numbers' text is most of a large mesh file and its parse most of the read,
//! and a process has only its own node's cores to parse on.
//!
//! The scan and the plan can read the records' bytes from the file a window at a time
//! ([`Text`]): then the scanning process never holds the records, which are nearly all
//! of the file (6 GB at 10^8 unknowns in ASCII), only the other sections and the blocks'
//! heads.
//!
//! Any fault (a layout this reading does not expect, a bad number, a duplicate or
//! unknown tag) makes these functions return `None`: the caller then parses the whole
//! file the careful way, which finds the fault and names its place exactly as it always
//! has, so nothing here needs messages of its own. MSH 2.2 is not shared (`scan` returns
//! `None`).

use super::{
    ascii_number, ascii_u64, is_space, read_mesh_format, read_section, Binary, Builder, Kind,
    Reader, Version,
};
use crate::mesh::Mesh;
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::path::{Path, PathBuf};

/// Bytes read at a time where the records are read from the file.
const WINDOW: usize = 1 << 20;
/// Bytes between the line counts kept of an ASCII stretch ([`Scan::plan`] recounts at
/// most this many at a cut).
const MARK: usize = 1 << 16;

/// A file's content for [`scan`] and [`Scan::plan`]: `bytes` are the whole file, whose
/// other sections and block heads the scan parses; the records' lines are counted in
/// windows read from `file` where given (so those pages of `bytes`, a mapping of the
/// file, are never touched), else in `bytes`.
#[derive(Clone, Copy)]
pub struct Text<'a> {
    pub bytes: &'a [u8],
    pub file: Option<&'a File>,
}

impl<'a> Text<'a> {
    /// Bytes in memory.
    pub fn of(bytes: &'a [u8]) -> Self {
        Text { bytes, file: None }
    }

    /// At most `len` bytes from `at` (fewer at the end of the file); `None` past it or
    /// where the file cannot be read.
    fn window<'b>(&'b self, at: usize, len: usize, buf: &'b mut Vec<u8>) -> Option<&'b [u8]> {
        let end = at.checked_add(len)?.min(self.bytes.len());
        let range = self.bytes.get(at..end).filter(|r| !r.is_empty())?;
        match self.file {
            None => Some(range),
            Some(f) => {
                use std::os::unix::fs::FileExt;
                buf.resize(end - at, 0);
                f.read_exact_at(buf, at as u64).ok()?;
                Some(&buf[..])
            }
        }
    }
}

/// What a stretch of a section holds, one record after another.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Record {
    /// A node tag.
    Tag,
    /// A node's x, y, z and `extra` parametric coordinates.
    Point { extra: u8 },
    /// An element's tag and its `nodes` node tags.
    Element { nodes: u8 },
}

impl Record {
    fn tokens(self) -> usize {
        match self {
            Record::Tag => 1,
            Record::Point { extra } => 3 + extra as usize,
            Record::Element { nodes } => 1 + nodes as usize,
        }
    }

    fn bytes(self, size_t: usize) -> usize {
        match self {
            Record::Tag => size_t,
            Record::Point { extra } => 8 * (3 + extra as usize),
            Record::Element { nodes } => size_t * (1 + nodes as usize),
        }
    }

    /// The array of a [`Share`] it goes to (tags, coordinates, element nodes) and how
    /// many values it adds there.
    fn array(self) -> (usize, usize) {
        match self {
            Record::Tag => (0, 1),
            Record::Point { .. } => (1, 3),
            Record::Element { nodes } => (2, nodes as usize),
        }
    }
}

/// Records of one kind at bytes `start..end` of the file (in ASCII, whole lines, the
/// last one's newline included).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Stretch {
    pub start: u64,
    pub end: u64,
    pub records: u64,
    pub record: Record,
}

/// Who parses which bytes of the file: small, sent to every process.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SharePlan {
    pub path: PathBuf,
    binary: Option<Binary>,
    /// Each process's stretches; process after process, they are the file's records in
    /// file order.
    shares: Vec<Vec<Stretch>>,
}

impl SharePlan {
    /// The values of each array of a [`Share`] (tags, coordinates, element nodes), per
    /// process: what each sends to the first.
    pub fn counts(&self) -> [Vec<usize>; 3] {
        let mut counts = [(); 3].map(|_| vec![0; self.shares.len()]);
        for (p, share) in self.shares.iter().enumerate() {
            for s in share {
                let (array, values) = s.record.array();
                counts[array][p] += values * s.records as usize;
            }
        }
        counts
    }

    /// The stretches of process `p`.
    pub fn share(&self, p: usize) -> &[Stretch] {
        self.shares.get(p).map_or(&[], |s| &s[..])
    }
}

/// What a process parsed: its records' values in file order.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct Share {
    pub tags: Vec<u64>,
    /// x, y, z of each node.
    pub coords: Vec<f64>,
    /// The node tags of each element, as many as its kind has.
    pub elements: Vec<u64>,
}

impl Share {
    /// The node tags of this share's triangles (its records of 3-node elements), in file
    /// order; `stretches` are the share's ([`SharePlan::share`]).
    pub fn triangles(&self, stretches: &[Stretch]) -> Vec<[u64; 3]> {
        let mut out = Vec::new();
        self.each_element_block(stretches, |nodes, values| {
            if nodes == 3 {
                out.extend(values.chunks_exact(3).map(|t| [t[0], t[1], t[2]]));
            }
        });
        out
    }

    /// The node tags of this share's records of points and lines (the groups'
    /// elements), in file order: all but its triangles' values.
    pub fn group_values(&self, stretches: &[Stretch]) -> Vec<u64> {
        let mut out = Vec::new();
        self.each_element_block(stretches, |nodes, values| {
            if nodes != 3 {
                out.extend_from_slice(values);
            }
        });
        out
    }

    /// Each of the share's stretches of elements, in order: their node count and their
    /// node tags.
    fn each_element_block(&self, stretches: &[Stretch], mut f: impl FnMut(u8, &[u64])) {
        let mut at = 0;
        for s in stretches {
            let Record::Element { nodes } = s.record else {
                continue;
            };
            let values = nodes as usize * s.records as usize;
            f(nodes, &self.elements[at..at + values]);
            at += values;
        }
    }
}

/// The mesh of the groups' elements alone, which the first rank builds the problem's
/// conditions on where the ranks hold the triangles (`dd::dist_problem`).
#[derive(Debug, Clone, PartialEq)]
pub struct GroupMesh {
    /// The groups' nodes, by increasing index among the file's nodes, and their line and
    /// point groups; no triangles; every physical surface by name, without its
    /// triangles.
    pub mesh: Mesh,
    /// Each node's index among the file's nodes.
    pub file: Vec<u64>,
    /// Each node's tag.
    pub tags: Vec<u64>,
    /// The file's triangle blocks in order: each one's count and the names of its
    /// physical surfaces.
    pub triangle_blocks: Vec<(usize, Vec<String>)>,
}

/// A block of `$Nodes` or `$Elements`, in file order.
#[derive(Debug)]
enum Block {
    Nodes(usize),
    Elements {
        kind: Kind,
        count: usize,
        physicals: Vec<i32>,
    },
}

/// The first process's knowledge of a file apart from its records: the other sections
/// read, where the records lie.
pub struct Scan {
    builder: Builder,
    blocks: Vec<Block>,
    stretches: Vec<Stretch>,
    /// For each ASCII stretch, every [`MARK`] bytes from its start: the byte and the
    /// lines before it in the stretch.
    marks: Vec<Vec<(u64, u64)>>,
    binary: Option<Binary>,
    name: String,
}

/// Reads every section of an MSH 4.1 file but the records of `$Nodes` and `$Elements`,
/// whose place it finds: in ASCII by counting lines (a record is a line, as Gmsh writes
/// them), in binary from the block headers. `None` for MSH 2.2 and on any fault.
pub fn scan(text: Text, name: &str) -> Option<Scan> {
    let mut r = Reader::new(text.bytes, name);
    if read_mesh_format(&mut r).ok()? != Version::V41 {
        return None;
    }
    let mut scan = Scan {
        builder: Builder::default(),
        blocks: Vec::new(),
        stretches: Vec::new(),
        marks: Vec::new(),
        binary: r.binary,
        name: name.to_string(),
    };
    while r.next_section().ok()? {
        match r.section.as_str() {
            "$Nodes" => scan.nodes(&mut r, text)?,
            "$Elements" => scan.elements(&mut r, text)?,
            _ => read_section(&mut r, &mut scan.builder, Version::V41).ok()?,
        }
    }
    Some(scan)
}

/// The head of an MSH 4.1 `$Nodes` or `$Elements` section: its block count and record
/// count (the tag range after them is not needed).
fn section_header(r: &mut Reader) -> Option<(usize, usize)> {
    let blocks = r.count("").ok()?;
    let total = r.count("").ok()?;
    r.size_t("").ok()?;
    r.size_t("").ok()?;
    Some((blocks, total))
}

impl Scan {
    fn nodes(&mut self, r: &mut Reader, text: Text) -> Option<()> {
        self.builder.start_nodes(r).ok()?;
        let (blocks, total) = section_header(r)?;
        let mut read = 0usize;
        for _ in 0..blocks {
            let dim = r.int("").ok()?;
            r.int("").ok()?;
            let parametric = r.int("").ok()?;
            let count = r.count("").ok()?;
            let extra = match (parametric, dim) {
                (0, _) | (1, 0) => 0,
                (1, 1..=3) => dim as u8,
                _ => return None,
            };
            self.stretch(r, text, count, Record::Tag)?;
            self.stretch(r, text, count, Record::Point { extra })?;
            self.blocks.push(Block::Nodes(count));
            read = read.checked_add(count)?;
        }
        (read == total).then_some(())?;
        r.expect_end().ok()
    }

    fn elements(&mut self, r: &mut Reader, text: Text) -> Option<()> {
        self.builder.start_elements(r).ok()?;
        let (blocks, total) = section_header(r)?;
        let mut read = 0usize;
        for _ in 0..blocks {
            let at = r.mark();
            let dim = r.int("").ok()?;
            let entity = r.int("").ok()?;
            let kind = super::element_kind(r.int("").ok()?).ok()?;
            let count = r.count("").ok()?;
            let physicals = self.builder.entity_physicals(r, at, dim, entity).ok()?;
            let nodes = kind.nodes() as u8;
            self.stretch(r, text, count, Record::Element { nodes })?;
            self.blocks.push(Block::Elements {
                kind,
                count,
                physicals,
            });
            read = read.checked_add(count)?;
        }
        (read == total).then_some(())?;
        r.expect_end().ok()
    }

    /// Notes `count` records from the reader's position and moves past them.
    fn stretch(&mut self, r: &mut Reader, text: Text, count: usize, record: Record) -> Option<()> {
        if count == 0 {
            return Some(());
        }
        let start = match r.binary {
            Some(_) => r.pos,
            None => {
                r.skip_space();
                r.pos
            }
        };
        let mut marks = Vec::new();
        let end = match r.binary {
            Some(b) => start
                .checked_add(count.checked_mul(record.bytes(b.size_t))?)
                .filter(|&end| end <= r.bytes.len())?,
            None => after_lines(text, start, count, &mut marks)?,
        };
        r.pos = end;
        self.marks.push(marks);
        self.stretches.push(Stretch {
            start: start as u64,
            end: end as u64,
            records: count as u64,
            record,
        });
        Some(())
    }

    /// The number of triangle records (3-node elements) in the file.
    pub fn triangles(&self) -> usize {
        (self.blocks.iter())
            .map(|b| match b {
                Block::Elements {
                    kind: Kind::Triangle,
                    count,
                    ..
                } => *count,
                _ => 0,
            })
            .sum()
    }

    /// Cuts the records into `parts` shares of about as many bytes, at record
    /// boundaries, reading at most a few windows of `text` per cut. `None` where the
    /// counts of a share would not fit the i32 of an MPI gather, or the file cannot be
    /// read.
    pub fn plan(&self, text: Text, path: &Path, parts: usize) -> Option<SharePlan> {
        let parts = parts.max(1);
        let total: u64 = self.stretches.iter().map(|s| s.end - s.start).sum();
        // Where each share but the first starts: (stretch, byte), in file order.
        let mut cuts = Vec::with_capacity(parts);
        let (mut i, mut before) = (0, 0u64);
        for k in 1..parts {
            let at = total * k as u64 / parts as u64;
            while i < self.stretches.len() && before + self.len(i) <= at {
                before += self.len(i);
                i += 1;
            }
            let Some(s) = self.stretches.get(i) else {
                break;
            };
            cuts.push((i, self.record_start(text, s, s.start + (at - before))?));
        }
        let mut shares = vec![Vec::new(); parts];
        let mut p = 0;
        for (i, s) in self.stretches.iter().enumerate() {
            // Each cut's records before it counted once, for the pieces on both sides.
            let (mut from, mut before) = (s.start, 0);
            while p < cuts.len() && cuts[p].0 == i {
                let to = cuts[p].1;
                if to > from {
                    let at = self.records_before(text, i, to)?;
                    shares[p].push(piece(s, from, to, at - before));
                    (from, before) = (to, at);
                }
                p += 1;
            }
            if from < s.end {
                shares[p].push(piece(s, from, s.end, s.records - before));
            }
        }
        let plan = SharePlan {
            path: path.to_path_buf(),
            binary: self.binary,
            shares,
        };
        let fits = |c: &Vec<usize>| c.iter().sum::<usize>() <= i32::MAX as usize;
        plan.counts().iter().all(fits).then_some(plan)
    }

    fn len(&self, i: usize) -> u64 {
        self.stretches[i].end - self.stretches[i].start
    }

    /// The first record boundary of `s` at or after `at`.
    fn record_start(&self, text: Text, s: &Stretch, at: u64) -> Option<u64> {
        if let Some(b) = self.binary {
            let size = s.record.bytes(b.size_t) as u64;
            return Some((s.start + (at - s.start).div_ceil(size) * size).min(s.end));
        }
        if at == s.start {
            return Some(at);
        }
        // The first newline from the byte before `at`: a record starts after it.
        let (mut from, mut buf) = (usize::try_from(at - 1).ok()?, Vec::new());
        let end = usize::try_from(s.end).ok()?;
        while from < end {
            // A record is a line of a few tens of bytes: a short read finds its end.
            let window = text.window(from, (end - from).min(MARK), &mut buf)?;
            if let Some(nl) = memchr::memchr(b'\n', window) {
                return Some((from + nl + 1) as u64);
            }
            from += window.len();
        }
        Some(s.end)
    }

    /// The records of stretch `i` before byte `at`, a record boundary: in ASCII its
    /// lines, from its last mark at or before `at`, counting at most [`MARK`] bytes.
    fn records_before(&self, text: Text, i: usize, at: u64) -> Option<u64> {
        let s = &self.stretches[i];
        if let Some(b) = self.binary {
            return Some((at - s.start) / s.record.bytes(b.size_t) as u64);
        }
        let marks = &self.marks[i];
        let k = marks.partition_point(|m| m.0 <= at).checked_sub(1)?;
        let (mark, before) = marks[k];
        let len = usize::try_from(at - mark).ok()?;
        if len == 0 {
            return Some(before);
        }
        let mut buf = Vec::new();
        let window = text.window(usize::try_from(mark).ok()?, len, &mut buf)?;
        (window.len() == len).then_some(())?;
        Some(before + memchr::memchr_iter(b'\n', window).count() as u64)
    }

    /// The node tags of the groups' elements (points and lines), increasing, from their
    /// values in file order ([`Share::group_values`] of every share, concatenated in
    /// process order); `None` where they do not match the blocks.
    pub fn group_tags(&self, values: &[u64]) -> Option<Vec<u64>> {
        self.group_records(values)?;
        let mut tags = values.to_vec();
        tags.sort_unstable();
        tags.dedup();
        Some(tags)
    }

    /// Each non-triangle block's kind, physicals and records, in file order; `None`
    /// where `values` do not match the blocks.
    #[allow(clippy::type_complexity)]
    fn group_records<'a>(&'a self, values: &'a [u64]) -> Option<Vec<(Kind, &'a [i32], &'a [u64])>> {
        let mut out = Vec::new();
        let mut e = 0usize;
        for block in &self.blocks {
            let Block::Elements {
                kind,
                count,
                physicals,
            } = block
            else {
                continue;
            };
            if *kind == Kind::Triangle {
                continue;
            }
            let n = count.checked_mul(kind.nodes())?;
            let mine = values.get(e..e.checked_add(n)?)?;
            e += n;
            out.push((*kind, &physicals[..], mine));
        }
        (e == values.len()).then_some(out)
    }

    /// The [`GroupMesh`] of the groups' elements (`values`, as for [`Scan::group_tags`])
    /// on their nodes (`nodes`: tag, index among the file's nodes, x, y, by increasing
    /// tag, every tag of the elements among them). `None` where they do not match.
    pub fn group_mesh(&self, values: &[u64], nodes: &[(u64, u64, [f64; 2])]) -> Option<GroupMesh> {
        let records = self.group_records(values)?;
        let mut by_file: Vec<&(u64, u64, [f64; 2])> = nodes.iter().collect();
        by_file.sort_unstable_by_key(|n| n.1);
        let mut index = vec![0usize; nodes.len()];
        for (i, n) in by_file.iter().enumerate() {
            index[nodes.binary_search_by_key(&n.0, |m| m.0).ok()?] = i;
        }
        let at = |tag: u64| -> Option<usize> {
            Some(index[nodes.binary_search_by_key(&tag, |m| m.0).ok()?])
        };
        let mut lines: std::collections::BTreeMap<i32, Vec<[usize; 2]>> = Default::default();
        let mut points: std::collections::BTreeMap<i32, Vec<usize>> = Default::default();
        for (kind, physicals, mine) in records {
            for record in mine.chunks_exact(kind.nodes()) {
                let a = at(record[0])?;
                match kind {
                    Kind::Line => {
                        let b = at(record[1])?;
                        for &p in physicals {
                            lines.entry(p).or_default().push([a, b]);
                        }
                    }
                    _ => {
                        for &p in physicals {
                            points.entry(p).or_default().push(a);
                        }
                    }
                }
            }
        }
        let names = &self.builder.names;
        let mut surfaces: std::collections::BTreeMap<i32, Vec<usize>> = Default::default();
        let mut triangle_blocks = Vec::new();
        for block in &self.blocks {
            if let Block::Elements {
                kind: Kind::Triangle,
                count,
                physicals,
            } = block
            {
                for &p in physicals {
                    surfaces.entry(p).or_default();
                }
                let named =
                    super::named(physicals.iter().map(|&p| (p, vec![()])).collect(), 2, names);
                triangle_blocks.push((*count, named.into_keys().collect()));
            }
        }
        Some(GroupMesh {
            mesh: Mesh {
                nodes: by_file.iter().map(|n| n.2).collect(),
                triangles: Vec::new(),
                line_groups: super::named(lines, 1, names),
                point_groups: super::named(points, 0, names),
                surface_groups: super::named(surfaces, 2, names),
            },
            file: by_file.iter().map(|n| n.1).collect(),
            tags: by_file.iter().map(|n| n.0).collect(),
            triangle_blocks,
        })
    }

    /// The mesh from every share's values, concatenated in process order: the same
    /// [`Mesh`] as [`super::parse_msh`] reads from the file. `None` on a fault (a node
    /// defined twice, an element on an unknown node, a count that does not match, or
    /// anything [`super::parse_msh`] would refuse at the end).
    pub fn assemble(self, tags: &[u64], coords: &[f64], elements: &[u64]) -> Option<Mesh> {
        let Scan {
            mut builder,
            blocks,
            name,
            ..
        } = self;
        let nodes: usize = (blocks.iter())
            .map(|b| match b {
                Block::Nodes(n) => *n,
                Block::Elements { .. } => 0,
            })
            .sum();
        (tags.len() == nodes && coords.len() == 3 * nodes).then_some(())?;
        builder.reserve_nodes(nodes);
        let (mut t, mut e) = (0usize, 0usize);
        for block in blocks {
            match block {
                Block::Nodes(count) => {
                    for _ in 0..count {
                        let tag = tags[t];
                        if !builder.node_index.insert(tag, builder.nodes.len()) {
                            return None;
                        }
                        builder
                            .nodes
                            .push([coords[3 * t], coords[3 * t + 1], coords[3 * t + 2]]);
                        builder.node_tags.push(tag);
                        t += 1;
                    }
                }
                Block::Elements {
                    kind,
                    count,
                    physicals,
                } => {
                    let k = kind.nodes();
                    let mine = elements.get(e..e.checked_add(count.checked_mul(k)?)?)?;
                    e += mine.len();
                    if kind == Kind::Triangle {
                        // Most of the records: looked up on the pool's threads.
                        use rayon::prelude::*;
                        let index = &builder.node_index;
                        let triangles: Option<Vec<[usize; 3]>> = (mine.par_chunks_exact(3))
                            .map(|t| Some([index.get(t[0])?, index.get(t[1])?, index.get(t[2])?]))
                            .collect();
                        let first = builder.triangles.len();
                        builder.triangles.extend(triangles?);
                        for &p in &physicals {
                            let surface = builder.surfaces.entry(p).or_default();
                            surface.extend(first..builder.triangles.len());
                        }
                        continue;
                    }
                    for record in mine.chunks_exact(k) {
                        let mut nodes = [0; 3];
                        for (node, &tag) in nodes.iter_mut().zip(record) {
                            *node = builder.node_index.get(tag)?;
                        }
                        builder.add_element(kind, nodes, &physicals);
                    }
                }
            }
        }
        (e == elements.len()).then_some(())?;
        builder.finish(&name).ok()
    }
}

/// The `records` records of stretch `s` at bytes `start..end`.
fn piece(s: &Stretch, start: u64, end: u64, records: u64) -> Stretch {
    Stretch {
        start,
        end,
        records,
        record: s.record,
    }
}

/// Where the `n`-th line from `from` ends (past its newline): counted a window at a
/// time, which a vector search does at many bytes per step. Notes in `marks`, every
/// [`MARK`] bytes from `from`, the byte and the lines before it.
fn after_lines(text: Text, from: usize, n: usize, marks: &mut Vec<(u64, u64)>) -> Option<usize> {
    let (mut at, mut left, mut counted) = (from, n, 0u64);
    let mut buf = Vec::new();
    while left > 0 {
        let window = text.window(at, WINDOW, &mut buf)?;
        for (k, block) in window.chunks(MARK).enumerate() {
            let start = at + k * MARK;
            marks.push((start as u64, counted));
            let lines = memchr::memchr_iter(b'\n', block).count();
            if lines >= left {
                let nl = memchr::memchr_iter(b'\n', block).nth(left - 1)?;
                return Some(start + nl + 1);
            }
            left -= lines;
            counted += lines as u64;
        }
        at += window.len();
    }
    Some(at)
}

/// Parses process `p`'s share of `plan`, from `bytes` (the whole file) when given, else
/// from the file itself (its share's bytes only), on the threads of the pool. `None` on
/// any fault, a file that cannot be read included.
pub fn read_share(plan: &SharePlan, p: usize, bytes: Option<&[u8]>) -> Option<Share> {
    use std::os::unix::fs::FileExt;
    let counts = plan.counts();
    let mut share = Share {
        tags: Vec::with_capacity(*counts[0].get(p)?),
        coords: Vec::with_capacity(counts[1][p]),
        elements: Vec::with_capacity(counts[2][p]),
    };
    let stretches = plan.share(p);
    let file = match (bytes, stretches.is_empty()) {
        (None, false) => Some(std::fs::File::open(&plan.path).ok()?),
        _ => None,
    };
    let mut buffer = Vec::new();
    for s in stretches {
        let range = usize::try_from(s.start).ok()?..usize::try_from(s.end).ok()?;
        let data = match (bytes, &file) {
            (Some(b), _) => b.get(range)?,
            (None, Some(f)) => {
                buffer.resize(range.len(), 0);
                f.read_exact_at(&mut buffer, s.start).ok()?;
                &buffer[..]
            }
            (None, None) => return None,
        };
        let before = [share.tags.len(), share.coords.len(), share.elements.len()];
        match plan.binary {
            Some(b) => binary_stretch(data, s.record, b, &mut share)?,
            None => ascii_stretch(data, s.record, &mut share)?,
        }
        let after = [share.tags.len(), share.coords.len(), share.elements.len()];
        let (array, values) = s.record.array();
        (after[array] - before[array] == values * s.records as usize).then_some(())?;
    }
    Some(share)
}

/// ASCII records, a line each, parsed on the pool's threads in pieces of whole lines.
fn ascii_stretch(data: &[u8], record: Record, share: &mut Share) -> Option<()> {
    use rayon::prelude::*;
    let per = record.tokens();
    let pieces = (4 * rayon::current_num_threads()).max(1);
    let mut starts = vec![0];
    for k in 1..pieces {
        let at = (data.len() * k / pieces).max(*starts.last()?);
        let next = memchr::memchr(b'\n', data.get(at..)?).map_or(data.len(), |nl| at + nl + 1);
        if next > *starts.last()? && next < data.len() {
            starts.push(next);
        }
    }
    starts.push(data.len());
    let parsed: Vec<Option<Share>> = starts
        .par_windows(2)
        .map(|w| {
            let mut out = Share::default();
            let piece = &data[w[0]..w[1]];
            let piece = piece.strip_suffix(b"\n").unwrap_or(piece);
            let mut tokens: Vec<&[u8]> = Vec::with_capacity(per + 1);
            for line in piece.split(|&c| c == b'\n') {
                tokens.clear();
                tokens.extend(
                    (line.split(|&c| is_space(c)))
                        .filter(|t| !t.is_empty())
                        .take(per + 1),
                );
                if tokens.len() != per {
                    return None;
                }
                ascii_record(&tokens, record, &mut out)?;
            }
            Some(out)
        })
        .collect();
    for piece in parsed {
        let piece = piece?;
        share.tags.extend(piece.tags);
        share.coords.extend(piece.coords);
        share.elements.extend(piece.elements);
    }
    Some(())
}

/// One record's tokens as the careful reading reads them (a whole token a number).
fn ascii_record(t: &[&[u8]], record: Record, out: &mut Share) -> Option<()> {
    match record {
        Record::Tag => out.tags.push(ascii_u64(t[0])?),
        Record::Point { .. } => {
            for v in &t[..3] {
                let v = ascii_number::<f64>(v)?;
                // A non-finite coordinate gets its message from the careful reading.
                v.is_finite().then_some(())?;
                out.coords.push(v);
            }
            for v in &t[3..] {
                ascii_number::<f64>(v)?;
            }
        }
        Record::Element { .. } => {
            ascii_u64(t[0])?;
            for v in &t[1..] {
                out.elements.push(ascii_u64(v)?);
            }
        }
    }
    Some(())
}

fn binary_stretch(data: &[u8], record: Record, b: Binary, share: &mut Share) -> Option<()> {
    let size = record.bytes(b.size_t);
    (data.len() % size == 0).then_some(())?;
    let uint = |raw: &[u8]| -> u64 {
        match (raw.len(), b.big_endian) {
            (4, false) => u64::from(u32::from_le_bytes(raw.try_into().unwrap_or_default())),
            (4, true) => u64::from(u32::from_be_bytes(raw.try_into().unwrap_or_default())),
            (_, false) => u64::from_le_bytes(raw.try_into().unwrap_or_default()),
            (_, true) => u64::from_be_bytes(raw.try_into().unwrap_or_default()),
        }
    };
    let double = |raw: &[u8]| -> f64 {
        let raw = raw.try_into().unwrap_or_default();
        if b.big_endian {
            f64::from_be_bytes(raw)
        } else {
            f64::from_le_bytes(raw)
        }
    };
    for rec in data.chunks_exact(size) {
        match record {
            Record::Tag => share.tags.push(uint(rec)),
            Record::Point { .. } => {
                for raw in rec[..24].chunks_exact(8) {
                    let v = double(raw);
                    v.is_finite().then_some(())?;
                    share.coords.push(v);
                }
            }
            Record::Element { .. } => {
                let tags = rec.chunks_exact(b.size_t).skip(1);
                share.elements.extend(tags.map(uint));
            }
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plan's shares, each parsed from the bytes, then put together.
    fn shared(bytes: &[u8], parts: usize) -> Option<Mesh> {
        let scan = scan(Text::of(bytes), "m.msh")?;
        let plan = scan.plan(Text::of(bytes), Path::new("m.msh"), parts)?;
        let mut all = Share::default();
        for p in 0..parts {
            let s = read_share(&plan, p, Some(bytes))?;
            all.tags.extend(s.tags);
            all.coords.extend(s.coords);
            all.elements.extend(s.elements);
        }
        scan.assemble(&all.tags, &all.coords, &all.elements)
    }

    #[test]
    fn lines_are_counted_across_blocks() {
        let mut text = Vec::new();
        for i in 0..400_000 {
            text.extend_from_slice(format!("{i}\n").as_bytes());
        }
        let line_end = |n: usize| {
            let mut k = 0;
            text.iter().position(|&c| {
                k += usize::from(c == b'\n');
                k == n
            })
        };
        assert!(text.len() > 2 * WINDOW);
        for n in [1, 2, 9999, 70_000, 100_000, 300_000, 400_000] {
            let got = after_lines(Text::of(&text), 0, n, &mut Vec::new());
            assert_eq!(got, line_end(n).map(|p| p + 1), "{n}");
        }
        assert_eq!(
            after_lines(Text::of(&text), 0, 400_001, &mut Vec::new()),
            None
        );
        assert_eq!(after_lines(Text::of(&text), 3, 0, &mut Vec::new()), Some(3));
    }

    #[test]
    fn shares_are_whole_records_and_cover_every_record_once() {
        let bytes = super::super::tests::big_ascii(60).into_bytes();
        let scan = scan(Text::of(&bytes), "m.msh").expect("an MSH 4.1 file");
        for parts in [1, 2, 3, 4, 7, 64] {
            let plan = scan
                .plan(Text::of(&bytes), Path::new("m.msh"), parts)
                .unwrap();
            let mut covered = Vec::new();
            for p in 0..parts {
                for s in plan.share(p) {
                    let data = &bytes[s.start as usize..s.end as usize];
                    assert!(
                        data.ends_with(b"\n"),
                        "{parts} parts: a piece ends mid-line"
                    );
                    let at = s.start as usize;
                    assert!(
                        bytes[at - 1] == b'\n',
                        "{parts} parts: a piece starts mid-line"
                    );
                    covered.push((s.start, s.end, s.records));
                }
            }
            // Pieces follow each other within a stretch and count their lines.
            for w in covered.windows(2) {
                assert!(w[0].1 <= w[1].0);
            }
            let total: u64 = covered.iter().map(|c| c.2).sum();
            let nodes = 61 * 61;
            assert_eq!(total, 2 * nodes + 2 * 60 * 60 + 60, "{parts} parts");
        }
    }

    #[test]
    fn with_the_file_the_plan_reads_no_record_from_the_bytes() {
        use std::io::Write;
        let bytes = super::super::tests::big_ascii(300).into_bytes();
        let mut file = tempfile::NamedTempFile::new().unwrap();
        file.write_all(&bytes).unwrap();
        let found = scan(Text::of(&bytes), "m.msh").unwrap();
        assert!(found
            .stretches
            .iter()
            .any(|s| s.end - s.start > 4 * MARK as u64));
        // The bytes the scan may parse keep everything but the records, which are
        // overwritten (lines kept, so that any count from them would be wrong too).
        let mut heads = bytes.clone();
        for s in &found.stretches {
            for c in &mut heads[s.start as usize..s.end as usize] {
                *c = if *c == b'\n' { b'\n' } else { b'x' };
            }
            heads[s.start as usize + 1] = b'\n';
        }
        let text = Text {
            bytes: &heads,
            file: Some(file.as_file()),
        };
        let mapped = scan(text, "m.msh").unwrap();
        assert_eq!(mapped.stretches, found.stretches);
        for parts in [1, 2, 3, 7, 64] {
            let path = Path::new("m.msh");
            let plan = mapped.plan(text, path, parts).unwrap();
            assert_eq!(plan, found.plan(Text::of(&bytes), path, parts).unwrap());
        }
        // Without the file, the same overwritten bytes give another count.
        assert!(scan(Text::of(&heads), "m.msh").map(|s| s.stretches) != Some(found.stretches));
    }

    #[test]
    fn shared_reading_is_the_careful_one_in_every_encoding() {
        let mut files = vec![(
            "big ascii".to_string(),
            super::super::tests::big_ascii(40).into_bytes(),
        )];
        files.extend(
            super::super::tests::all_variants(&super::super::tests::square())
                .into_iter()
                .filter(|(name, _)| name.contains("4.1")),
        );
        assert!(
            files.len() >= 4,
            "{:?}",
            files.iter().map(|f| &f.0).collect::<Vec<_>>()
        );
        for (name, bytes) in &files {
            let careful = super::super::parse_msh(bytes, "m.msh").unwrap();
            for parts in [1, 2, 3, 5] {
                let mesh = shared(bytes, parts).unwrap_or_else(|| panic!("{name}, {parts}"));
                assert_eq!(mesh, careful, "{name} in {parts} parts");
            }
        }
    }

    #[test]
    fn msh22_is_not_shared_and_faults_give_none() {
        let v22 = super::super::tests::all_variants(&super::super::tests::square());
        for (name, bytes) in v22.iter().filter(|(n, _)| n.contains("2.2")) {
            assert!(scan(Text::of(bytes), "m.msh").is_none(), "{name}");
        }
        let good = super::super::tests::big_ascii(30);
        assert!(shared(good.as_bytes(), 3).is_some());
        for (from, to) in [
            ("\n5\n", "\n5 6\n"),       // two tokens on a tag line
            ("\n7\n", "\n7x\n"),        // a bad number
            ("\n9\n", "\n8\n"),         // a node defined twice
            ("2 1 0 961", "2 1 0 962"), // a block longer than it is
        ] {
            let bad = good.replacen(from, to, 1);
            assert_ne!(bad, good, "{from}");
            assert!(shared(bad.as_bytes(), 3).is_none(), "{from} -> {to}");
            assert!(
                super::super::parse_msh(bad.as_bytes(), "m.msh").is_err(),
                "{from}"
            );
        }
    }
}
