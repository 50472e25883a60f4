//! Reader for Gmsh meshes (MSH 4.1 and 2.2, ASCII and binary) into a [`Mesh`].
//!
//! Why not the `mshio` crate: on malformed input mshio 0.4.2 panics (a `$Nodes` header
//! `0 0 1 1` underflows `num_nodes - 1`; a huge or odd data size in `$MeshFormat` hits an
//! `unwrap` or `unimplemented!`) and it mis-reads glued tokens (the node line `0.5-1 0` is
//! accepted as x = 0.5, y = -1, z = 0); as it reads neither MSH 2.2 nor `$PhysicalNames`
//! anyway, one small parser here covers both versions.
//!
//! Every error is an [`Error::Input`] of one line naming the file, the place (line number in
//! ASCII files, byte offset in binary ones), what is wrong and how to fix it.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::str::FromStr;

use crate::error::{input, Error, Result};
use crate::mesh::validate::NodeRows;
use crate::mesh::Mesh;
use rayon::prelude::*;

const REEXPORT: &str = "export the mesh again from Gmsh";
const CONVERT: &str =
    "convert it with `gmsh old.msh -save -format msh41 -o new.msh` (or `-format msh22`)";
const FIRST_ORDER: &str = "re-mesh with first-order elements: Mesh.ElementOrder = 1";

/// Reads a Gmsh mesh file (MSH 4.1 or 2.2, ASCII or binary).
pub fn read_msh(path: &Path) -> Result<Mesh> {
    let bytes = read_file(path).map_err(|e| {
        Error::Input(format!(
            "{}: cannot read the mesh file ({e}); check the path",
            path.display()
        ))
    })?;
    parse_msh(&bytes, &path.display().to_string())
}

/// The whole file, read in pieces on the threads of the pool where it is large: the
/// copy from the page cache into fresh pages (a page fault each) took a tenth of a
/// large mesh's read on one thread while the others waited.
fn read_file(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::os::unix::fs::FileExt;
    const PIECE: usize = 8 << 20;
    let file = std::fs::File::open(path)?;
    let len = usize::try_from(file.metadata()?.len()).unwrap_or(usize::MAX);
    let threads = rayon::current_num_threads();
    if threads < 2 || len < 2 * PIECE || !file.metadata()?.is_file() {
        return std::fs::read(path);
    }
    let mut bytes = vec![0u8; len];
    let piece = len.div_ceil(threads).max(PIECE);
    (bytes.par_chunks_mut(piece).enumerate())
        .try_for_each(|(k, chunk)| file.read_exact_at(chunk, (k * piece) as u64))?;
    // A file that grew meanwhile is read as it was when measured; one that shrank fails
    // above (an early end of file).
    Ok(bytes)
}

/// The tolerance of the planarity check: relative to the mesh's size (`extent`, the
/// larger side of its bounding box), so that CAD round-off in z does not count.
pub fn plane_tolerance(extent: f64) -> f64 {
    1e-9 * extent
}

/// The message of a mesh whose node `tag` lies at `z`, off the plane of its first node
/// (`first_tag` at `first_z`).
pub fn off_plane_message(name: &str, tag: u64, z: f64, first_tag: u64, first_z: f64) -> String {
    format!(
        "{name}: the mesh is not planar: node {tag} has z = {z} but node {first_tag} has z = \
         {first_z}; contact-par is 2D: build the geometry in a plane z = constant"
    )
}

/// Parses the content of a Gmsh mesh file; `name` is the file name used in messages.
///
/// Nodes are renumbered 0.. in file order and z is dropped (the mesh must lie in a plane
/// z = constant). Every 3-node triangle is kept once (MSH 2.2 repeats a triangle that is in
/// two physical surfaces), in file order and orientation. 2-node lines and points go to the
/// groups named after their 1D and 0D physical groups (the tag when a group has no name),
/// once per group they belong to; without any physical group, triangles are still kept.
pub fn parse_msh(bytes: &[u8], name: &str) -> Result<Mesh> {
    parse_msh_with(bytes, name, PARALLEL_RECORDS)
}

/// [`parse_msh`], ASCII blocks of at least `parallel_from` records on all threads.
fn parse_msh_with(bytes: &[u8], name: &str, parallel_from: usize) -> Result<Mesh> {
    let mut reader = Reader::new(bytes, name);
    reader.parallel_from = parallel_from;
    let version = read_mesh_format(&mut reader)?;
    let mut builder = Builder::default();
    while reader.next_section()? {
        read_section(&mut reader, &mut builder, version)?;
    }
    builder.finish(name)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Version {
    V22,
    V41,
}

/// How numbers are stored in a binary file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
struct Binary {
    big_endian: bool,
    /// Bytes of a `size_t` (MSH 4.1 only; MSH 2.2 binary uses 4-byte ints).
    size_t: usize,
}

/// A cursor over the file that knows where it is, for messages.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    name: &'a str,
    /// `None` while reading ASCII, and for the whole of an ASCII file.
    binary: Option<Binary>,
    section: String,
    section_at: usize,
    /// ASCII blocks of at least this many records are parsed on all threads.
    parallel_from: usize,
}

fn is_space(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\r' | b'\n')
}

fn line_number(bytes: &[u8], at: usize) -> usize {
    let before = bytes.get(..at).unwrap_or(bytes);
    1 + before.iter().filter(|&&c| c == b'\n').count()
}

/// A token as it can be shown inside a one-line message.
fn quote(bytes: &[u8]) -> String {
    const MAX: usize = 40;
    let text = String::from_utf8_lossy(bytes);
    let mut shown: String = text
        .chars()
        .take(MAX)
        .map(|c| if c.is_control() { '?' } else { c })
        .collect();
    if text.chars().count() > MAX {
        shown.push_str("...");
    }
    format!("'{shown}'")
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    if needle.is_empty() {
        return Some(0);
    }
    haystack.windows(needle.len()).position(|w| w == needle)
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], name: &'a str) -> Self {
        Reader {
            bytes,
            pos: 0,
            name,
            binary: None,
            section: String::new(),
            section_at: 0,
            parallel_from: PARALLEL_RECORDS,
        }
    }

    fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.pos)
    }

    fn rest(&self) -> &'a [u8] {
        self.bytes.get(self.pos..).unwrap_or_default()
    }

    fn place(&self, at: usize) -> String {
        match self.binary {
            None => format!("{}:{}", self.name, line_number(self.bytes, at)),
            Some(_) => format!("{}: byte {at}", self.name),
        }
    }

    fn fail<T>(&self, at: usize, msg: impl std::fmt::Display) -> Result<T> {
        let section = if self.section.is_empty() {
            String::new()
        } else {
            format!("in {}, ", self.section)
        };
        input(format!("{}: {section}{msg}", self.place(at)))
    }

    fn truncated<T>(&self, what: &str) -> Result<T> {
        let at = self.bytes.len().saturating_sub(1);
        self.fail(
            at,
            format!("the file ends where {what} was expected: it is truncated; {REEXPORT}"),
        )
    }

    /// Upper bound for pre-allocating `count` items: a bogus count in a small file must not
    /// reserve gigabytes, so no more items than the remaining bytes could hold.
    fn capacity(&self, count: usize, ascii_bytes: usize, binary_bytes: usize) -> usize {
        let each = if self.binary.is_some() {
            binary_bytes
        } else {
            ascii_bytes
        };
        count.min(self.remaining() / each.max(1))
    }

    fn skip_space(&mut self) {
        while self.bytes.get(self.pos).is_some_and(|&c| is_space(c)) {
            self.pos += 1;
        }
    }

    /// Where the next value starts (in ASCII, past the blanks), for messages about it.
    fn mark(&mut self) -> usize {
        if self.binary.is_none() {
            self.skip_space();
        }
        self.pos
    }

    fn token(&mut self, what: &str) -> Result<(usize, &'a [u8])> {
        self.skip_space();
        let start = self.pos;
        while self.bytes.get(self.pos).is_some_and(|&c| !is_space(c)) {
            self.pos += 1;
        }
        match self.bytes.get(start..self.pos) {
            Some(token) if !token.is_empty() => Ok((start, token)),
            _ => self.truncated(what),
        }
    }

    /// An ASCII number, whole token: `0.5-1` is an error, not 0.5 followed by -1.
    fn text<T: FromStr>(&mut self, what: &str) -> Result<T> {
        let (at, token) = self.token(what)?;
        let value = std::str::from_utf8(token).ok().and_then(|s| s.parse().ok());
        if let Some(value) = value {
            return Ok(value);
        }
        if token.starts_with(b"$") {
            return self.fail(
                at,
                format!(
                    "found {} where {what} was expected: the section holds less data than its \
                     header announces; {REEXPORT}",
                    quote(token)
                ),
            );
        }
        self.fail(
            at,
            format!(
                "bad number {} where {what} was expected; correct the file or {REEXPORT}",
                quote(token)
            ),
        )
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let end = self.pos.saturating_add(N);
        match self.bytes.get(self.pos..end) {
            Some(slice) => {
                let mut out = [0; N];
                out.copy_from_slice(slice);
                self.pos = end;
                Ok(out)
            }
            None => self.truncated(what),
        }
    }

    fn int(&mut self, what: &str) -> Result<i32> {
        match self.binary {
            None => self.text(what),
            Some(b) => {
                let raw = self.take::<4>(what)?;
                Ok(if b.big_endian {
                    i32::from_be_bytes(raw)
                } else {
                    i32::from_le_bytes(raw)
                })
            }
        }
    }

    fn size_t(&mut self, what: &str) -> Result<u64> {
        match self.binary {
            None => self.text(what),
            Some(b) if b.size_t == 4 => {
                let raw = self.take::<4>(what)?;
                Ok(u64::from(if b.big_endian {
                    u32::from_be_bytes(raw)
                } else {
                    u32::from_le_bytes(raw)
                }))
            }
            Some(b) => {
                let raw = self.take::<8>(what)?;
                Ok(if b.big_endian {
                    u64::from_be_bytes(raw)
                } else {
                    u64::from_le_bytes(raw)
                })
            }
        }
    }

    fn double(&mut self, what: &str) -> Result<f64> {
        match self.binary {
            None => self.text(what),
            Some(b) => {
                let raw = self.take::<8>(what)?;
                Ok(if b.big_endian {
                    f64::from_be_bytes(raw)
                } else {
                    f64::from_le_bytes(raw)
                })
            }
        }
    }

    fn count(&mut self, what: &str) -> Result<usize> {
        let at = self.mark();
        let n = self.size_t(what)?;
        usize::try_from(n).or_else(|_| self.fail(at, format!("{what} ({n}) is too large")))
    }

    /// An `int` that counts something, so may not be negative.
    fn int_count(&mut self, what: &str) -> Result<usize> {
        let at = self.mark();
        let n = self.int(what)?;
        usize::try_from(n)
            .or_else(|_| self.fail(at, format!("{what} is negative ({n}); {REEXPORT}")))
    }

    /// A tag stored as an `int` (MSH 2.2), which Gmsh never makes negative.
    fn int_tag(&mut self, what: &str) -> Result<u64> {
        let at = self.mark();
        let tag = self.int(what)?;
        u64::try_from(tag)
            .or_else(|_| self.fail(at, format!("{what} is negative ({tag}); {REEXPORT}")))
    }

    /// Consumes the rest of a line that must hold nothing more: in binary files the binary
    /// data starts right after its newline, so blanks beyond it are data, not padding.
    fn end_of_line(&mut self, after: &str) -> Result<()> {
        while let Some(&c) = self.bytes.get(self.pos) {
            self.pos += 1;
            match c {
                b'\n' => return Ok(()),
                b' ' | b'\t' | b'\r' => {}
                _ => {
                    return self.fail(
                        self.pos - 1,
                        format!("unexpected {} after {after}; {REEXPORT}", quote(&[c])),
                    )
                }
            }
        }
        self.truncated(&format!("a new line after {after}"))
    }

    /// The rest of the current line (without its newline) and where it starts.
    fn rest_of_line(&mut self) -> (usize, &'a [u8]) {
        let start = self.pos;
        let rest = self.rest();
        let len = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
        self.pos = (start + len + 1).min(self.bytes.len());
        (start, rest.get(..len).unwrap_or_default())
    }

    /// Moves to the next section header; false at the end of the file.
    fn next_section(&mut self) -> Result<bool> {
        self.section.clear();
        self.skip_space();
        if self.remaining() == 0 {
            return Ok(false);
        }
        let (at, tag) = self.token("a section header")?;
        if !tag.starts_with(b"$") || tag.starts_with(b"$End") {
            return self.fail(
                at,
                format!(
                    "expected a section header such as $Nodes, found {}; {REEXPORT}",
                    quote(tag)
                ),
            );
        }
        self.section = String::from_utf8_lossy(tag).into_owned();
        self.section_at = at;
        let section = self.section.clone();
        self.end_of_line(&section)?;
        Ok(true)
    }

    fn end_tag(&self) -> String {
        let bare = self.section.strip_prefix('$').unwrap_or(&self.section);
        format!("$End{bare}")
    }

    fn missing_end<T>(&self, end: &str) -> Result<T> {
        self.fail(
            self.section_at,
            format!("the section has no {end}: the file is truncated; {REEXPORT}"),
        )
    }

    fn expect_end(&mut self) -> Result<()> {
        let end = self.end_tag();
        self.skip_space();
        if self.remaining() == 0 {
            return self.missing_end(&end);
        }
        let (at, token) = self.token(&end)?;
        if token == end.as_bytes() {
            return Ok(());
        }
        if self.remaining() == 0 && end.as_bytes().starts_with(token) {
            return self.missing_end(&end);
        }
        self.fail(
            at,
            format!(
                "expected {end}, found {}: the section holds more data than its header \
                 announces; {REEXPORT}",
                quote(token)
            ),
        )
    }

    /// Skips a section this reader does not use, binary content included, by looking for
    /// its end tag at the start of a line.
    fn skip_section(&mut self) -> Result<()> {
        let end = self.end_tag();
        let needle = end.as_bytes();
        let mut from = self.pos;
        while let Some(found) = self.bytes.get(from..).and_then(|h| find(h, needle)) {
            let at = from + found;
            let after = at + needle.len();
            let starts_line = at == 0 || self.bytes.get(at - 1) == Some(&b'\n');
            let ends_line = self.bytes.get(after).is_none_or(|&c| is_space(c));
            if starts_line && ends_line {
                self.pos = after;
                return Ok(());
            }
            from = at + 1;
        }
        self.missing_end(&end)
    }
}

/// Reads `$MeshFormat`; sets the reader to binary when the file is.
fn read_mesh_format(r: &mut Reader) -> Result<Version> {
    if r.rest().starts_with(b"\xEF\xBB\xBF") {
        r.pos += 3;
    }
    r.skip_space();
    if r.rest().starts_with(b"$NOD") {
        return input(format!(
            "{}: MSH 1.0 files are not supported (contact-par reads 4.1 and 2.2); {CONVERT}",
            r.name
        ));
    }
    let starts_right = r.rest().starts_with(b"$MeshFormat");
    if !starts_right || !r.next_section()? || r.section != "$MeshFormat" {
        return input(format!(
            "{}: not a Gmsh mesh file: it does not start with $MeshFormat; export the mesh \
             from Gmsh as .msh (format 4.1 or 2.2)",
            r.name
        ));
    }
    let (at, token) = r.token("the MSH version")?;
    let version = match token {
        b"4.1" => Version::V41,
        b"2.2" => Version::V22,
        _ => {
            return r.fail(
                at,
                format!(
                    "MSH version {} is not supported (contact-par reads 4.1 and 2.2); {CONVERT}",
                    quote(token)
                ),
            )
        }
    };
    let at = r.mark();
    let file_type: u32 = r.text("the file type (0 for ASCII, 1 for binary)")?;
    let size_at = r.mark();
    let data_size: usize = r.text("the data size")?;
    match file_type {
        0 => {}
        1 => read_binary_marker(r, version, size_at, data_size)?,
        _ => {
            return r.fail(
                at,
                format!("file type {file_type} is neither 0 (ASCII) nor 1 (binary); {REEXPORT}"),
            )
        }
    }
    r.expect_end()?;
    Ok(version)
}

/// Checks the data size and reads the endianness marker (the int 1) of a binary file.
fn read_binary_marker(r: &mut Reader, version: Version, at: usize, data_size: usize) -> Result<()> {
    let supported = match version {
        Version::V41 => data_size == 4 || data_size == 8,
        Version::V22 => data_size == 8,
    };
    if !supported {
        return r.fail(
            at,
            format!(
                "data size {data_size} is not supported (Gmsh writes 8); {REEXPORT} on a \
                 64-bit machine"
            ),
        );
    }
    r.end_of_line("the data size")?;
    // From here on places are byte offsets; the byte order is known just below.
    r.binary = Some(Binary {
        big_endian: false,
        size_t: data_size,
    });
    let at = r.pos;
    let marker = r.take::<4>("the binary endianness marker")?;
    let big_endian = if i32::from_le_bytes(marker) == 1 {
        false
    } else if i32::from_be_bytes(marker) == 1 {
        true
    } else {
        return r.fail(
            at,
            format!(
                "the binary endianness marker is not the int 1 in either byte order: the \
                 header is damaged; {REEXPORT}"
            ),
        );
    };
    r.binary = Some(Binary {
        big_endian,
        size_t: data_size,
    });
    Ok(())
}

fn read_section(r: &mut Reader, b: &mut Builder, version: Version) -> Result<()> {
    match (r.section.as_str(), version) {
        ("$PhysicalNames", _) => read_physical_names(r, b),
        ("$Entities", Version::V41) => read_entities_v41(r, b),
        ("$Nodes", Version::V41) => read_nodes_v41(r, b),
        ("$Nodes", Version::V22) => read_nodes_v22(r, b),
        ("$Elements", Version::V41) => read_elements_v41(r, b),
        ("$Elements", Version::V22) => read_elements_v22(r, b),
        ("$PartitionedEntities", _) => r.fail(
            r.section_at,
            "the mesh is partitioned by Gmsh, which contact-par does itself: save it \
             unpartitioned (no `-part`, Mesh.NbPartitions = 0)",
        ),
        ("$MeshFormat", _) => r.fail(
            r.section_at,
            format!("a second $MeshFormat: the file holds two meshes; {REEXPORT}"),
        ),
        _ => r.skip_section(),
    }
}

/// `$PhysicalNames` is text even in binary files: `dim tag "name"` per line.
fn read_physical_names(r: &mut Reader, b: &mut Builder) -> Result<()> {
    let count: usize = r.text("the number of physical names")?;
    for _ in 0..count {
        let dim: i32 = r.text("a physical group dimension")?;
        let tag: i32 = r.text("a physical group tag")?;
        let (at, line) = r.rest_of_line();
        let name = unquote(line);
        if name.is_empty() {
            return r.fail(
                at,
                format!("physical group {tag} has an empty name; name it in quotes or remove it"),
            );
        }
        b.names.insert((dim, tag), name);
    }
    r.expect_end()
}

fn unquote(line: &[u8]) -> String {
    let start = line
        .iter()
        .position(|&c| !is_space(c))
        .unwrap_or(line.len());
    let end = line
        .iter()
        .rposition(|&c| !is_space(c))
        .map_or(start, |i| i + 1);
    let mut name = line.get(start..end).unwrap_or_default();
    if name.len() >= 2 && name.starts_with(b"\"") && name.ends_with(b"\"") {
        name = name.get(1..name.len() - 1).unwrap_or_default();
    }
    String::from_utf8_lossy(name).into_owned()
}

/// `$Entities` (MSH 4.1): only the physical tags of each entity are kept.
fn read_entities_v41(r: &mut Reader, b: &mut Builder) -> Result<()> {
    if b.entities.is_some() || b.elements_read {
        return r.fail(
            r.section_at,
            format!("a second $Entities section, or one after $Elements; {REEXPORT}"),
        );
    }
    let mut counts = [0; 4];
    for (count, what) in counts.iter_mut().zip([
        "the number of points",
        "the number of curves",
        "the number of surfaces",
        "the number of volumes",
    ]) {
        *count = r.count(what)?;
    }
    let mut entities = HashMap::new();
    for (dim, &count) in (0..).zip(counts.iter()) {
        for _ in 0..count {
            let (tag, physicals) = read_entity_v41(r, dim)?;
            entities.insert((dim, tag), physicals);
        }
    }
    b.entities = Some(entities);
    r.expect_end()
}

fn read_entity_v41(r: &mut Reader, dim: i32) -> Result<(i32, Vec<i32>)> {
    let tag = r.int("an entity tag")?;
    // A point has its coordinates, other entities their bounding box.
    let coordinates = if dim == 0 { 3 } else { 6 };
    for _ in 0..coordinates {
        r.double("an entity coordinate")?;
    }
    let count = r.count("the number of physical tags of an entity")?;
    let mut physicals = Vec::new();
    for _ in 0..count {
        physicals.push(r.int("a physical tag")?);
    }
    if dim > 0 {
        let bounding = r.count("the number of bounding entities")?;
        for _ in 0..bounding {
            r.int("a bounding entity tag")?;
        }
    }
    Ok((tag, physicals))
}

/// `$Nodes` (MSH 4.1): blocks of tags then coordinates.
fn read_nodes_v41(r: &mut Reader, b: &mut Builder) -> Result<()> {
    b.start_nodes(r)?;
    let blocks = r.count("the number of node blocks")?;
    let total = r.count("the number of nodes")?;
    r.size_t("the smallest node tag")?;
    r.size_t("the largest node tag")?;
    let size_t = r.binary.map_or(8, |b| b.size_t);
    b.reserve_nodes(r.capacity(total, 8, size_t + 24));
    let mut read = 0usize;
    for _ in 0..blocks {
        read = read.saturating_add(read_node_block_v41(r, b)?);
    }
    if read != total {
        return r.fail(
            r.section_at,
            format!("the header announces {total} nodes but the blocks hold {read}; {REEXPORT}"),
        );
    }
    r.expect_end()
}

fn read_node_block_v41(r: &mut Reader, b: &mut Builder) -> Result<usize> {
    let dim = r.int("an entity dimension")?;
    r.int("an entity tag")?;
    let at = r.mark();
    let parametric = r.int("the parametric flag")?;
    let count = r.count("the number of nodes in a block")?;
    // Parametric nodes carry one extra coordinate per dimension of their entity.
    let extra = match (parametric, dim) {
        (0, _) | (1, 0) => 0,
        (1, 1) => 1,
        (1, 2) => 2,
        (1, 3) => 3,
        _ => {
            return r.fail(
                at,
                format!(
                    "bad parametric flag {parametric} for an entity of dimension {dim}; {REEXPORT}"
                ),
            )
        }
    };
    if r.binary.is_none() && count >= r.parallel_from {
        let start = r.pos;
        if let Some((tags, points)) = ascii_nodes(r, count, extra) {
            let first = b.nodes.len();
            if let Err(i) = b.node_index.insert_all(&tags, first) {
                let (at, tag) = (token_start(r.bytes, start, i), tags[i]);
                return r.fail(at, format!("node {tag} is defined twice; {REEXPORT}"));
            }
            append(&mut b.nodes, points);
            append(&mut b.node_tags, tags);
            return Ok(count);
        }
        // Something is off: the record-by-record reading below finds it and says where.
        r.pos = start;
    }
    let size_t = r.binary.map_or(8, |b| b.size_t);
    let mut tags = Vec::with_capacity(r.capacity(count, 2, size_t));
    for _ in 0..count {
        let at = r.mark();
        tags.push((at, r.size_t("a node tag")?));
    }
    for (at, tag) in tags {
        let xyz = read_point(r, tag)?;
        for _ in 0..extra {
            r.double("a parametric coordinate")?;
        }
        b.add_node(r, at, tag, xyz)?;
    }
    Ok(count)
}

/// `block` after the records of `to`: moved where `to` is empty (a mesh's one large
/// block), else copied on the pool (a million records and their fresh pages were the
/// serial tail of a block).
fn append<T: Copy + Send + Sync>(to: &mut Vec<T>, block: Vec<T>) {
    if to.is_empty() {
        *to = block;
    } else {
        to.par_extend(block.par_iter().copied());
    }
}

/// Blocks of at least this many records (ASCII) are parsed on all the threads of the
/// pool ([`ascii_records`]); smaller ones are not worth the hand-over.
const PARALLEL_RECORDS: usize = 1 << 14;

/// Parses `n` records of `per` blank-separated ASCII tokens from the reader's position on
/// all the threads of the pool, each record by `parse`; moves the reader past them.
/// Reads a record as one line, as Gmsh writes them. `None` if the lines run out, a line
/// does not hold `per` tokens or a record does not parse: the caller then reads the same
/// bytes one token at a time, which accepts any layout, finds the fault and names its
/// line exactly as it always has, so this path needs no messages of its own.
///
/// Why: the numbers' text is most of a large mesh file, and its parse most of the read.
/// A search for the newlines (memchr, many bytes per step) finds where every thread's
/// share of whole records starts; a scan over the blanks, byte by byte, cost more than
/// a second thread saved.
fn ascii_records<T: Send + Default + Clone>(
    r: &mut Reader,
    n: usize,
    per: usize,
    parse: impl Fn(&[&[u8]]) -> Option<T> + Sync,
) -> Option<Vec<T>> {
    if n == 0 {
        return Some(Vec::new());
    }
    let bytes = r.bytes;
    r.skip_space();
    let pieces = line_pieces(bytes, r.pos, n)?;
    // Each piece parses its lines into its own slice of the records: no piece's vector
    // to allocate, fill and copy again (page faults, not the parse, were most of the
    // time left on one thread).
    let mut all = vec![T::default(); n];
    let mut outs: Vec<&mut [T]> = Vec::with_capacity(pieces.len());
    let mut rest = &mut all[..];
    for piece in &pieces {
        let (head, tail) = rest.split_at_mut(piece.lines);
        outs.push(head);
        rest = tail;
    }
    // Each piece a job of its own (`with_max_len(1)`), so that a thread that starts late
    // or parses faster takes the pieces of another.
    let jobs = outs.into_par_iter().zip(pieces.par_iter());
    let parsed = jobs.with_max_len(1).all(|(out, piece)| {
        let mut record: Vec<&[u8]> = Vec::with_capacity(per + 1);
        // Every piece ends with its last line's newline.
        let text = &bytes[piece.start..piece.end];
        let text = text.strip_suffix(b"\n").unwrap_or(text);
        let mut slots = out.iter_mut();
        for line in text.split(|&c| c == b'\n') {
            record.clear();
            record.extend(
                line.split(|&c| is_space(c))
                    .filter(|t| !t.is_empty())
                    .take(per + 1),
            );
            if record.len() != per {
                return false;
            }
            match (slots.next(), parse(&record)) {
                (Some(slot), Some(value)) => *slot = value,
                _ => return false,
            }
        }
        slots.next().is_none()
    });
    parsed.then_some(())?;
    // At the last line's newline, as the token reader leaves it.
    r.pos = pieces.last().map_or(r.pos, |p| p.end - 1);
    Some(all)
}

/// Lines of a record block, from a line's start to just past a newline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct LinePiece {
    start: usize,
    end: usize,
    lines: usize,
}

/// The `n` lines from `first` in pieces of about `LINE_PIECE` bytes, each starting at a
/// line's start, the last ending with the `n`-th line's newline; `None` where fewer than
/// `n` newlines follow. The pieces are found on the pool, a few per thread at a time:
/// each moves its nominal start to the next line's and counts its newlines (a vectorised
/// count), until the count reaches `n`; only the last piece is walked newline by newline.
///
/// Why: one thread walking every newline to cut equal pieces was the longest stretch of
/// the read on one core (about 50 ms of a 97 MB file), the other threads idle.
fn line_pieces(bytes: &[u8], first: usize, n: usize) -> Option<Vec<LinePiece>> {
    let at_line = |i: usize| -> usize {
        let s = first + i * LINE_PIECE;
        if i == 0 || s >= bytes.len() {
            return s.min(bytes.len());
        }
        if bytes[s - 1] == b'\n' {
            return s;
        }
        memchr::memchr(b'\n', &bytes[s..]).map_or(bytes.len(), |p| s + p + 1)
    };
    let batch = 4 * rayon::current_num_threads();
    let mut pieces = Vec::new();
    let mut lines = 0;
    for from in (0..).step_by(batch) {
        let counted: Vec<LinePiece> = (from..from + batch)
            .into_par_iter()
            .map(|i| {
                let (start, end) = (at_line(i), at_line(i + 1));
                let lines = memchr::memchr_iter(b'\n', &bytes[start..end]).count();
                LinePiece { start, end, lines }
            })
            .collect();
        for piece in counted {
            if piece.start >= bytes.len() {
                return None;
            }
            if lines + piece.lines >= n {
                let last = n - lines;
                let text = &bytes[piece.start..piece.end];
                let nl = memchr::memchr_iter(b'\n', text).nth(last - 1)?;
                pieces.push(LinePiece {
                    end: piece.start + nl + 1,
                    lines: last,
                    ..piece
                });
                return Some(pieces);
            }
            if piece.lines > 0 {
                pieces.push(piece);
                lines += piece.lines;
            }
        }
    }
    None
}

/// The bytes of a piece of [`line_pieces`]: enough lines for a job worth handing over,
/// and many pieces a thread, so that the threads end together.
const LINE_PIECE: usize = 1 << 18;

/// A whole ASCII token as a number, as [`Reader::text`] reads it.
fn ascii_number<T: FromStr>(token: &[u8]) -> Option<T> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// A whole ASCII token as a `u64`, as `ascii_number::<u64>` reads it: plain digits
/// directly (tags are most of a mesh file's tokens, and UTF-8 validation plus the
/// generic parse were a tenth of its read), anything else the generic way.
fn ascii_u64(token: &[u8]) -> Option<u64> {
    if token.is_empty() || token.len() > 19 || !token.iter().all(u8::is_ascii_digit) {
        return ascii_number(token);
    }
    Some(
        token
            .iter()
            .fold(0u64, |v, &d| v * 10 + u64::from(d - b'0')),
    )
}

/// Where the `i`-th blank-separated token from `from` starts (for messages).
fn token_start(bytes: &[u8], from: usize, i: usize) -> usize {
    let mut tokens = 0;
    let mut in_token = false;
    for (k, &c) in bytes.iter().enumerate().skip(from) {
        match (is_space(c), in_token) {
            (false, false) if tokens == i => return k,
            (false, false) => (tokens, in_token) = (tokens + 1, true),
            (true, true) => in_token = false,
            _ => {}
        }
    }
    from
}

/// An ASCII MSH 4.1 node block's tags, then coordinates (plus `extra` parametric ones),
/// on all threads ([`ascii_records`]); `None` for the record-by-record reading to judge.
fn ascii_nodes(r: &mut Reader, count: usize, extra: usize) -> Option<(Vec<u64>, Vec<[f64; 3]>)> {
    let tags = ascii_records(r, count, 1, |t| ascii_u64(t[0]))?;
    let points = ascii_records(r, count, 3 + extra, |t| {
        let xyz = [0, 1, 2].map(|c| ascii_number::<f64>(t[c]));
        let xyz = [xyz[0]?, xyz[1]?, xyz[2]?];
        // A non-finite coordinate gets its message from the careful reading.
        for v in &t[3..] {
            ascii_number::<f64>(v)?;
        }
        xyz.iter().all(|v| v.is_finite()).then_some(xyz)
    })?;
    Some((tags, points))
}

/// An ASCII MSH 4.1 block of triangles (tag and three node tags per record), as node
/// indices, on all threads ([`ascii_records`]).
fn ascii_triangles(r: &mut Reader, b: &Builder, count: usize) -> Option<Vec<[usize; 3]>> {
    ascii_records(r, count, 4, |t| {
        ascii_u64(t[0])?;
        let node = |k: usize| b.node_index.get(ascii_u64(t[k])?);
        Some([node(1)?, node(2)?, node(3)?])
    })
}

/// `$Nodes` (MSH 2.2): a text count, then `tag x y z` records.
fn read_nodes_v22(r: &mut Reader, b: &mut Builder) -> Result<()> {
    b.start_nodes(r)?;
    let count: usize = r.text("the number of nodes")?;
    if r.binary.is_some() {
        r.end_of_line("the number of nodes")?;
    }
    b.reserve_nodes(r.capacity(count, 8, 28));
    for _ in 0..count {
        let at = r.mark();
        let tag = r.int_tag("a node tag")?;
        let xyz = read_point(r, tag)?;
        b.add_node(r, at, tag, xyz)?;
    }
    r.expect_end()
}

fn read_point(r: &mut Reader, tag: u64) -> Result<[f64; 3]> {
    let mut xyz = [0.0; 3];
    for (value, axis) in xyz.iter_mut().zip(["x", "y", "z"]) {
        let at = r.mark();
        *value = r.double("a node coordinate")?;
        if !value.is_finite() {
            return r.fail(
                at,
                format!(
                    "node {tag} has {axis} = {value}, not a finite number; fix the geometry \
                     or the file"
                ),
            );
        }
    }
    Ok(xyz)
}

/// `$Elements` (MSH 4.1): blocks of one element type on one entity.
fn read_elements_v41(r: &mut Reader, b: &mut Builder) -> Result<()> {
    b.start_elements(r)?;
    let blocks = r.count("the number of element blocks")?;
    let total = r.count("the number of elements")?;
    r.size_t("the smallest element tag")?;
    r.size_t("the largest element tag")?;
    let triangles = r.capacity(total, 6, 16);
    b.triangles.reserve(triangles);
    let mut read = 0usize;
    for _ in 0..blocks {
        read = read.saturating_add(read_element_block_v41(r, b)?);
    }
    if read != total {
        return r.fail(
            r.section_at,
            format!("the header announces {total} elements but the blocks hold {read}; {REEXPORT}"),
        );
    }
    r.expect_end()
}

fn read_element_block_v41(r: &mut Reader, b: &mut Builder) -> Result<usize> {
    let at = r.mark();
    let dim = r.int("an entity dimension")?;
    let entity = r.int("an entity tag")?;
    let type_at = r.mark();
    let element_type = r.int("an element type")?;
    let count = r.count("the number of elements in a block")?;
    let kind = element_kind(element_type).or_else(|msg| r.fail(type_at, msg))?;
    let physicals = b.entity_physicals(r, at, dim, entity)?;
    if r.binary.is_none() && kind == Kind::Triangle && count >= r.parallel_from {
        let start = r.pos;
        if let Some(triangles) = ascii_triangles(r, b, count) {
            let first = b.triangles.len();
            append(&mut b.triangles, triangles);
            for &p in &physicals {
                (b.surfaces.entry(p).or_default()).extend(first..b.triangles.len());
            }
            return Ok(count);
        }
        r.pos = start;
    }
    for _ in 0..count {
        let element = r.size_t("an element tag")?;
        let mut nodes = [0; 3];
        for node in nodes.iter_mut().take(kind.nodes()) {
            let at = r.mark();
            let tag = r.size_t("a node tag")?;
            *node = b.node(r, at, element, tag)?;
        }
        b.add_element(kind, nodes, &physicals);
    }
    Ok(count)
}

/// `$Elements` (MSH 2.2): a text count, then one record per element (ASCII) or blocks of
/// records of one type (binary).
fn read_elements_v22(r: &mut Reader, b: &mut Builder) -> Result<()> {
    b.start_elements(r)?;
    let count: usize = r.text("the number of elements")?;
    b.triangles.reserve(r.capacity(count, 8, 24));
    if r.binary.is_some() {
        r.end_of_line("the number of elements")?;
        read_element_blocks_v22(r, b, count)?;
    } else {
        for _ in 0..count {
            let element = r.int_tag("an element tag")?;
            let type_at = r.mark();
            let element_type = r.int("an element type")?;
            let kind = element_kind(element_type).or_else(|msg| r.fail(type_at, msg))?;
            let num_tags = r.int_count("the number of element tags")?;
            read_element_v22(r, b, element, kind, num_tags)?;
        }
    }
    r.expect_end()
}

fn read_element_blocks_v22(r: &mut Reader, b: &mut Builder, count: usize) -> Result<()> {
    let mut read = 0;
    while read < count {
        let type_at = r.mark();
        let element_type = r.int("an element type")?;
        let follow_at = r.mark();
        let follow = r.int_count("the number of elements in a block")?;
        let num_tags = r.int_count("the number of element tags")?;
        let kind = element_kind(element_type).or_else(|msg| r.fail(type_at, msg))?;
        if follow == 0 || follow > count - read {
            return r.fail(
                follow_at,
                format!(
                    "a block of {follow} elements does not fit the {count} elements the \
                     section announces; {REEXPORT}"
                ),
            );
        }
        for _ in 0..follow {
            let element = r.int_tag("an element tag")?;
            read_element_v22(r, b, element, kind, num_tags)?;
        }
        read += follow;
    }
    Ok(())
}

/// The tags and nodes of one MSH 2.2 element; its first tag is its physical group (0: none).
fn read_element_v22(
    r: &mut Reader,
    b: &mut Builder,
    element: u64,
    kind: Kind,
    num_tags: usize,
) -> Result<()> {
    let mut physical = 0;
    for i in 0..num_tags {
        let tag = r.int("an element tag (physical, elementary, ...)")?;
        if i == 0 {
            physical = tag;
        }
    }
    let mut nodes = [0; 3];
    for node in nodes.iter_mut().take(kind.nodes()) {
        let at = r.mark();
        let tag = r.int_tag("a node tag")?;
        *node = b.node(r, at, element, tag)?;
    }
    let physicals: &[i32] = if physical == 0 {
        &[]
    } else {
        std::slice::from_ref(&physical)
    };
    b.add_element(kind, nodes, physicals);
    Ok(())
}

/// The element types this reader accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Point,
    Line,
    Triangle,
}

impl Kind {
    fn nodes(self) -> usize {
        match self {
            Kind::Point => 1,
            Kind::Line => 2,
            Kind::Triangle => 3,
        }
    }
}

/// The kind of a Gmsh element type, or what is wrong with it and the fix.
fn element_kind(element_type: i32) -> std::result::Result<Kind, String> {
    let t = element_type;
    match t {
        15 => Ok(Kind::Point),
        1 => Ok(Kind::Line),
        2 => Ok(Kind::Triangle),
        3 => Err(
            "element type 3 (4-node quadrangle) is not supported; use triangles: remove \
             Recombine (Recombine Surface, Mesh.RecombineAll = 0)"
                .into(),
        ),
        8 => Err(format!(
            "element type 8 (3-node second-order line) is not supported; {FIRST_ORDER}"
        )),
        9 => Err(format!(
            "element type 9 (6-node second-order triangle) is not supported; {FIRST_ORDER}"
        )),
        10 | 16 => Err(format!(
            "element type {t} (second-order quadrangle) is not supported; {FIRST_ORDER}, \
             and use triangles: remove Recombine"
        )),
        20..=28 => Err(format!(
            "element type {t} (high-order line or triangle) is not supported; {FIRST_ORDER}"
        )),
        4..=7 | 11..=14 | 17..=19 | 29..=31 => Err(format!(
            "element type {t} is a volume element, and contact-par is 2D; mesh the surface \
             only (`gmsh -2`) and put no volume in a physical group"
        )),
        _ => Err(format!(
            "element type {t} is not supported; contact-par reads points (15), 2-node lines \
             (1) and 3-node triangles (2)"
        )),
    }
}

/// What has been read so far, turned into a [`Mesh`] at the end.
#[derive(Default)]
struct Builder {
    names: HashMap<(i32, i32), String>,
    /// Physical tags of each (dim, tag) entity; `None` without `$Entities` (or in MSH 2.2).
    entities: Option<HashMap<(i32, i32), Vec<i32>>>,
    nodes_read: bool,
    elements_read: bool,
    node_index: TagIndex,
    node_tags: Vec<u64>,
    nodes: Vec<[f64; 3]>,
    /// Every triangle as read; [`Builder::finish`] drops the repeats.
    triangles: Vec<[usize; 3]>,
    lines: BTreeMap<i32, Vec<[usize; 2]>>,
    points: BTreeMap<i32, Vec<usize>>,
    /// Indices into `triangles` (as read, repeats included) of each physical surface.
    surfaces: BTreeMap<i32, Vec<usize>>,
}

impl Builder {
    fn start_nodes(&mut self, r: &Reader) -> Result<()> {
        if self.nodes_read {
            return r.fail(
                r.section_at,
                format!("a second $Nodes section; contact-par reads one mesh: {REEXPORT}"),
            );
        }
        self.nodes_read = true;
        Ok(())
    }

    fn start_elements(&mut self, r: &Reader) -> Result<()> {
        if self.elements_read {
            return r.fail(
                r.section_at,
                format!("a second $Elements section; contact-par reads one mesh: {REEXPORT}"),
            );
        }
        if !self.nodes_read {
            return r.fail(
                r.section_at,
                format!("$Elements comes before $Nodes; {REEXPORT}"),
            );
        }
        self.elements_read = true;
        Ok(())
    }

    fn reserve_nodes(&mut self, n: usize) {
        self.nodes.reserve(n);
        self.node_tags.reserve(n);
        self.node_index.expect(n);
    }

    fn add_node(&mut self, r: &Reader, at: usize, tag: u64, xyz: [f64; 3]) -> Result<()> {
        if !self.node_index.insert(tag, self.nodes.len()) {
            return r.fail(at, format!("node {tag} is defined twice; {REEXPORT}"));
        }
        self.nodes.push(xyz);
        self.node_tags.push(tag);
        Ok(())
    }

    fn node(&self, r: &Reader, at: usize, element: u64, tag: u64) -> Result<usize> {
        match self.node_index.get(tag) {
            Some(index) => Ok(index),
            None => r.fail(
                at,
                format!(
                    "element {element} uses node {tag}, which is not defined in $Nodes; \
                     {REEXPORT}"
                ),
            ),
        }
    }

    fn entity_physicals(&self, r: &Reader, at: usize, dim: i32, tag: i32) -> Result<Vec<i32>> {
        let Some(entities) = &self.entities else {
            return Ok(Vec::new());
        };
        match entities.get(&(dim, tag)) {
            Some(physicals) => Ok(physicals.clone()),
            None => r.fail(
                at,
                format!(
                    "an element block lies on entity {tag} of dimension {dim}, which is not \
                     listed in $Entities; {REEXPORT}"
                ),
            ),
        }
    }

    fn add_element(&mut self, kind: Kind, nodes: [usize; 3], physicals: &[i32]) {
        let [a, b, _] = nodes;
        match kind {
            Kind::Triangle => {
                for &p in physicals {
                    (self.surfaces.entry(p).or_default()).push(self.triangles.len());
                }
                self.triangles.push(nodes);
            }
            Kind::Line => {
                for &p in physicals {
                    self.lines.entry(p).or_default().push([a, b]);
                }
            }
            Kind::Point => {
                for &p in physicals {
                    self.points.entry(p).or_default().push(a);
                }
            }
        }
    }

    fn check_planar(&self, name: &str) -> Result<()> {
        let Some(first) = self.nodes.first() else {
            return Ok(());
        };
        let extent = |axis: usize| {
            let values = self.nodes.par_iter().map(|p| p[axis]);
            let max = values.clone().reduce(|| f64::NEG_INFINITY, f64::max);
            let min = values.reduce(|| f64::INFINITY, f64::min);
            max - min
        };
        let tolerance = plane_tolerance(extent(0).max(extent(1)));
        let first_tag = self.node_tags.first().copied().unwrap_or_default();
        let off_plane = (self.nodes.par_iter().zip(&self.node_tags))
            .find_first(|(p, _)| (p[2] - first[2]).abs() > tolerance);
        match off_plane {
            Some((p, tag)) => input(off_plane_message(name, *tag, p[2], first_tag, first[2])),
            None => Ok(()),
        }
    }

    fn finish(mut self, name: &str) -> Result<Mesh> {
        let kept = drop_repeated_triangles(self.nodes.len(), &mut self.triangles);
        // A repeat's groups go to the triangle kept in its place (MSH 2.2 writes a
        // triangle of two physical surfaces twice, once with each tag).
        let surfaces = (std::mem::take(&mut self.surfaces).into_iter())
            .map(|(tag, tris)| {
                let mut t: Vec<usize> = match &kept {
                    Some(kept) => tris.iter().map(|&t| kept[t]).collect(),
                    None => tris,
                };
                t.sort_unstable();
                t.dedup();
                (tag, t)
            })
            .collect();
        if self.triangles.is_empty() {
            return input(format!(
                "{name}: the mesh has no triangles (3-node, element type 2); mesh the surface \
                 in 2D (`gmsh -2`) and, if the file has physical groups, put the surface in a \
                 physical surface"
            ));
        }
        self.check_planar(name)?;
        Ok(Mesh {
            nodes: (self.nodes.par_iter()).map(|p| [p[0], p[1]]).collect(),
            triangles: self.triangles,
            line_groups: named(self.lines, 1, &self.names),
            point_groups: named(self.points, 0, &self.names),
            surface_groups: named(surfaces, 2, &self.names),
        })
    }
}

/// Node tag -> node index. Gmsh numbers nodes 1..N, or nearly, so a table indexed by the
/// tag serves nearly every file; a tag far beyond the node count (a file renumbered by
/// hand, or merged) goes to a hash map instead. Hashing every tag took 70% of the parse of
/// a 2.2M-node mesh.
///
/// Where every tag so far is one run, the first tag at index 0 and each next tag at the
/// next index (a mesh fresh from Gmsh), a tag's index is its offset in the run: the
/// elements' millions of lookups then read no table, whose scattered reads were a tenth
/// of the read of a 1M-node mesh.
#[derive(Debug, Default)]
struct TagIndex {
    table: Vec<usize>,
    others: HashMap<u64, usize>,
    /// Tags below it use the table: a few times the announced node count, so the table
    /// stays a few bytes per node whatever the tags.
    table_limit: u64,
    /// The tags recorded so far as a run, while they are one.
    run: Run,
}

/// The tags a [`TagIndex`] holds, while they are one run.
#[derive(Debug, Default, Clone, Copy, PartialEq)]
enum Run {
    /// None yet.
    #[default]
    Empty,
    /// Tags `first..first + len`, tag `first + k` at index `k`.
    Tags { first: u64, len: u64 },
    /// Not one run.
    Broken,
}

impl TagIndex {
    const NONE: usize = usize::MAX;

    /// Sizes the table for `n` nodes; call it before the first insert.
    fn expect(&mut self, n: usize) {
        self.table_limit = (n as u64).saturating_mul(4).max(1 << 16);
    }

    /// The run of tags (see [`TagIndex`]) after recording `count` consecutive tags from
    /// `tag` at indices from `index`.
    fn extend_run(&mut self, tag: u64, index: usize, count: u64) {
        self.run = match self.run {
            Run::Empty if index == 0 => Run::Tags {
                first: tag,
                len: count,
            },
            Run::Tags { first, len }
                if first.checked_add(len) == Some(tag) && len == index as u64 =>
            {
                Run::Tags {
                    first,
                    len: len + count,
                }
            }
            _ => Run::Broken,
        };
    }

    /// Records `tag` at `index`; false if the tag was already there.
    fn insert(&mut self, tag: u64, index: usize) -> bool {
        let new = if tag >= self.table_limit {
            match self.others.entry(tag) {
                std::collections::hash_map::Entry::Occupied(_) => false,
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(index);
                    true
                }
            }
        } else {
            let t = tag as usize;
            if t >= self.table.len() {
                self.table.resize(t + 1, Self::NONE);
            }
            let slot = &mut self.table[t];
            let new = *slot == Self::NONE;
            if new {
                *slot = index;
            }
            new
        };
        if new {
            self.extend_run(tag, index, 1);
        }
        new
    }

    /// Records `tags[i]` at `first + i` for every i; `Err(i)` for the first tag that was
    /// already there (in the table or earlier in `tags`), the tags before it recorded.
    ///
    /// Why: Gmsh numbers a block's nodes consecutively, so a block of a large mesh fills
    /// one stretch of the table: checked and filled on all the threads, where one thread
    /// recording a million tags one by one was a serial step of the read.
    fn insert_all(&mut self, tags: &[u64], first: usize) -> std::result::Result<(), usize> {
        let consecutive = |t0: u64| {
            let end = t0.checked_add(tags.len() as u64)?;
            let runs = tags
                .par_iter()
                .enumerate()
                .all(|(i, &t)| t == t0 + i as u64);
            (end <= self.table_limit && runs).then_some((t0 as usize, end as usize))
        };
        if let Some((lo, hi)) = tags.first().and_then(|&t0| consecutive(t0)) {
            if self.table.len() < hi {
                self.table.resize(hi, Self::NONE);
            }
            let stretch = &mut self.table[lo..hi];
            if stretch.par_iter().all(|&slot| slot == Self::NONE) {
                let fill = |(i, slot): (usize, &mut usize)| *slot = first + i;
                stretch.par_iter_mut().enumerate().for_each(fill);
                self.extend_run(lo as u64, first, tags.len() as u64);
                return Ok(());
            }
        }
        for (i, &tag) in tags.iter().enumerate() {
            if !self.insert(tag, first + i) {
                return Err(i);
            }
        }
        Ok(())
    }

    fn get(&self, tag: u64) -> Option<usize> {
        if let Run::Tags { first, len } = self.run {
            let k = tag.wrapping_sub(first);
            if k < len {
                return Some(k as usize);
            }
        }
        if tag >= self.table_limit {
            return self.others.get(&tag).copied();
        }
        match self.table.get(tag as usize) {
            Some(&i) if i != Self::NONE => Some(i),
            _ => None,
        }
    }
}

/// Keeps the first of triangles with the same three nodes (in any order), in file order.
/// MSH 2.2 repeats an element once per physical group, so a triangle in two physical
/// surfaces appears twice; a mesh never holds the same triangle twice on purpose.
///
/// Repeats share their smallest node, so triangles are put in rows by it
/// ([`NodeRows`]: a couple of triangles per node) and each row is sorted on its own.
///
/// Returns, when any was dropped, the new index of each triangle as read (a repeat's is
/// that of the triangle kept in its place).
fn drop_repeated_triangles(
    num_nodes: usize,
    triangles: &mut Vec<[usize; 3]>,
) -> Option<Vec<usize>> {
    let repeats = repeats_of(num_nodes, triangles);
    if repeats.is_empty() {
        return None;
    }
    // The triangle as read that each one repeats (itself when it is kept).
    let mut first_of: Vec<usize> = (0..triangles.len()).collect();
    for (t, kept) in repeats {
        first_of[t] = kept;
    }
    let mut new_index = vec![usize::MAX; triangles.len()];
    let mut next = 0;
    for i in 0..triangles.len() {
        if first_of[i] == i {
            new_index[i] = next;
            next += 1;
        } else {
            new_index[i] = new_index[first_of[i]];
        }
    }
    let mut k = 0;
    triangles.retain(|_| {
        k += 1;
        first_of[k - 1] == k - 1
    });
    Some(new_index)
}

/// Every (repeat, the first triangle of the same three nodes in the file) pair, in
/// file order within each smallest node.
fn repeats_of(num_nodes: usize, triangles: &[[usize; 3]]) -> Vec<(usize, usize)> {
    let key = |t: &[usize; 3]| {
        let mut k = *t;
        k.sort_unstable();
        k
    };
    let Some(rows) = NodeRows::new(num_nodes, triangles, 1, |i, t, put| {
        put(t[0].min(t[1]).min(t[2]), (key(t), i))
    }) else {
        // Beyond 2^32 triangles: one thread, one sort.
        let mut all: Vec<([usize; 3], usize)> = triangles
            .iter()
            .enumerate()
            .map(|(i, t)| (key(t), i))
            .collect();
        all.sort_unstable();
        return runs_of_repeats(&all);
    };
    let found = rows.scan(Vec::new, |repeats, _, row| {
        if row.len() > 1 {
            // By key, then by position in the file: the first of equal keys is kept.
            row.sort_unstable();
            repeats.extend(runs_of_repeats(row));
        }
        Ok::<(), ()>(())
    });
    found.map(|f| f.concat()).unwrap_or_default()
}

/// In `sorted` (key, position) pairs, each repeat of a key with the first position of
/// its key.
fn runs_of_repeats(sorted: &[([usize; 3], usize)]) -> Vec<(usize, usize)> {
    let mut repeats = Vec::new();
    let Some(&first) = sorted.first() else {
        return repeats;
    };
    let mut kept = first;
    for &t in &sorted[1..] {
        if t.0 == kept.0 {
            repeats.push((t.1, kept.1));
        } else {
            kept = t;
        }
    }
    repeats
}

/// Keys groups by their physical name, or by their tag when they have none.
fn named<T>(
    groups: BTreeMap<i32, Vec<T>>,
    dim: i32,
    names: &HashMap<(i32, i32), String>,
) -> BTreeMap<String, Vec<T>> {
    let mut out: BTreeMap<String, Vec<T>> = BTreeMap::new();
    for (tag, items) in groups {
        let name = names
            .get(&(dim, tag))
            .cloned()
            .unwrap_or_else(|| tag.to_string());
        // Moved, not copied, where the name is new: a surface's list holds every triangle.
        match out.entry(name) {
            std::collections::btree_map::Entry::Vacant(v) => {
                v.insert(items);
            }
            std::collections::btree_map::Entry::Occupied(mut o) => o.get_mut().extend(items),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pieces of `n` lines cover them in order, each from a line's start to just
    /// past a newline, with its count of lines; also where a line is longer than a
    /// piece, where the lines run to the end of the text, and where they run out.
    #[test]
    fn line_pieces_cover_the_lines_in_order() {
        let mut text = b"head\n".to_vec();
        let first = text.len();
        let mut ends = Vec::new();
        for i in 0..60_000usize {
            let len = match i {
                7 => 3 * LINE_PIECE / 2,
                _ => 5 + (i * 7919) % 40,
            };
            text.extend(std::iter::repeat_n(b'7', len));
            text.push(b'\n');
            ends.push(text.len());
        }
        text.extend_from_slice(b"tail without a newline");
        for n in [1, 2, 8, 9, 1000, 59_999, 60_000] {
            let pieces = line_pieces(&text, first, n).expect("pieces");
            assert_eq!(pieces[0].start, first, "{n}");
            for w in pieces.windows(2) {
                assert_eq!(w[0].end, w[1].start, "{n}");
            }
            for p in &pieces {
                let count = text[p.start..p.end].iter().filter(|&&b| b == b'\n').count();
                assert_eq!((count, text[p.end - 1]), (p.lines, b'\n'), "{n}");
            }
            assert_eq!(pieces.iter().map(|p| p.lines).sum::<usize>(), n);
            assert_eq!(pieces.last().unwrap().end, ends[n - 1], "{n}");
            assert!(
                n < 59_999 || pieces.len() > 4,
                "{n}: {} pieces",
                pieces.len()
            );
        }
        assert_eq!(line_pieces(&text, first, 60_001), None);
        assert_eq!(line_pieces(&text, text.len(), 1), None);
    }

    /// An ASCII MSH 4.1 grid of (n + 1)^2 nodes and 2 n^2 triangles, its node tags
    /// scrambled, with a line group and a surface group: large enough to be read in
    /// parallel.
    pub(super) fn big_ascii(n: usize) -> String {
        let nodes = (n + 1) * (n + 1);
        let tag = |i: usize| (i * 7919) % nodes + 1;
        let mut t = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
        t += "$PhysicalNames\n2\n1 1 \"bottom\"\n2 2 \"body\"\n$EndPhysicalNames\n";
        t += "$Entities\n0 1 1 0\n1 0 0 0 1 0 0 1 1 0\n1 0 0 0 1 1 0 1 2 0\n$EndEntities\n";
        t += &format!("$Nodes\n1 {nodes} 1 {nodes}\n2 1 0 {nodes}\n");
        for i in 0..nodes {
            t += &format!("{}\n", tag(i));
        }
        for i in 0..nodes {
            let (x, y) = (i % (n + 1), i / (n + 1));
            t += &format!("{} {} 0\n", x as f64 / 3.0, y as f64 * 0.25);
        }
        let id = |x: usize, y: usize| tag(y * (n + 1) + x);
        t += &format!(
            "$EndNodes\n$Elements\n2 {} 1 {}\n",
            2 * n * n + n,
            2 * n * n + n
        );
        t += &format!("1 1 1 {n}\n");
        for x in 0..n {
            t += &format!("{} {} {}\n", x + 1, id(x, 0), id(x + 1, 0));
        }
        t += &format!("2 1 2 {}\n", 2 * n * n);
        let mut e = n;
        for y in 0..n {
            for x in 0..n {
                let (a, b, c, d) = (id(x, y), id(x + 1, y), id(x + 1, y + 1), id(x, y + 1));
                t += &format!("{} {a} {b} {c}\n{} {a}   {c} {d}\n", e + 1, e + 2);
                e += 2;
            }
        }
        t + "$EndElements\n"
    }

    /// The parallel path reads records laid out one per line, and leaves any other
    /// layout to the record-by-record reading (`None`).
    #[test]
    fn parallel_records_are_lines() {
        let pair = |t: &[&[u8]]| Some((ascii_u64(t[0])?, ascii_u64(t[1])?));
        let text = b"  1 2\n3  4\r\n5 6\n7 8\n9 10\n$EndX\n";
        let mut r = Reader::new(text, "t");
        let got = ascii_records(&mut r, 5, 2, pair);
        assert_eq!(got, Some(vec![(1, 2), (3, 4), (5, 6), (7, 8), (9, 10)]));
        assert_eq!(&text[r.pos..r.pos + 6], b"\n$EndX");
        for bad in [
            &b"1 2 3\n4\n5 6\n7 8\n9 10\n"[..],
            b"1 2\n\n3 4\n5 6\n7 8\n",
            b"1 2\n3 4\n5 6",
        ] {
            assert_eq!(ascii_records(&mut Reader::new(bad, "t"), 5, 2, pair), None);
        }
    }

    #[test]
    fn plain_digits_read_as_the_generic_parse_reads_them() {
        for t in [
            "0",
            "7",
            "007",
            "+5",
            "-1",
            "",
            "1a",
            "1.0",
            "9999999999999999999",
            "18446744073709551615",
            "18446744073709551616",
            "123456789012345678901",
        ] {
            assert_eq!(ascii_u64(t.as_bytes()), t.parse::<u64>().ok(), "{t:?}");
        }
    }

    #[test]
    fn large_ascii_blocks_read_in_parallel_as_record_by_record() {
        let text = big_ascii(120);
        let parallel = parse_msh_with(text.as_bytes(), "big.msh", 1000).unwrap();
        let serial = parse_msh_with(text.as_bytes(), "big.msh", usize::MAX).unwrap();
        assert_eq!(parallel.triangles.len(), 2 * 120 * 120);
        let every: Vec<usize> = (0..2 * 120 * 120).collect();
        assert_eq!(parallel.surface_groups["body"], every);
        assert_eq!(parallel, serial);
        assert_eq!(parse_msh(text.as_bytes(), "big.msh").unwrap(), serial);
    }

    /// Each fault in a block read in parallel gets the message the careful reading gives.
    #[test]
    fn faults_in_large_ascii_blocks_get_the_usual_message() {
        let text = big_ascii(40);
        let nodes_at = text.find("$Nodes").unwrap();
        let elements_at = text.find("$Elements").unwrap();
        let faults = [
            // A bad coordinate, a non-finite one, a tag defined twice.
            text.replacen("0.3333333333333333 0 0", "0.33x 0 0", 1),
            text.replacen("0.3333333333333333 0 0", "inf 0 0", 1),
            format!(
                "{}{}",
                &text[..nodes_at],
                text[nodes_at..].replacen("\n8\n", "\n1\n", 1)
            ),
            // A triangle on an undefined node, a bad element tag, a truncated block.
            format!(
                "{}{}",
                &text[..elements_at],
                text[elements_at..].replacen(" 5 ", " 999999 ", 1)
            ),
            format!(
                "{}{}",
                &text[..elements_at],
                text[elements_at..].replacen("\n100 ", "\n1-0 ", 1)
            ),
            text[..text.len() - 200].to_string(),
        ];
        let words = [
            "bad number '0.33x'",
            "x = inf",
            "node 1 is defined twice",
            "node 999999",
            "bad number '1-0'",
            "truncated",
        ];
        for (k, bad) in faults.iter().enumerate() {
            assert_ne!(bad, &text, "fault {k} not applied");
            let parallel = parse_msh_with(bad.as_bytes(), "big.msh", 100).unwrap_err();
            let serial = parse_msh_with(bad.as_bytes(), "big.msh", usize::MAX).unwrap_err();
            assert_eq!(parallel.to_string(), serial.to_string(), "fault {k}");
            assert!(serial.to_string().contains(words[k]), "{serial}");
        }
    }

    macro_rules! fixture {
        ($file:literal) => {
            include_bytes!(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/data/gmsh/",
                $file
            ))
        };
    }

    const RECT_41_ASCII: &[u8] = fixture!("rect_v41_ascii.msh");
    const RECT_41_BINARY: &[u8] = fixture!("rect_v41_binary.msh");
    const RECT_22_ASCII: &[u8] = fixture!("rect_v22_ascii.msh");
    const RECT_22_BINARY: &[u8] = fixture!("rect_v22_binary.msh");
    const OVERLAP_41: &[u8] = fixture!("overlap_v41_ascii.msh");
    const OVERLAP_22: &[u8] = fixture!("overlap_v22_ascii.msh");
    const NOGROUPS_41: &[u8] = fixture!("nogroups_v41_ascii.msh");
    const NOGROUPS_22: &[u8] = fixture!("nogroups_v22_ascii.msh");
    const QUARTER_DISC: &[u8] = fixture!("quarter_disc_v41_ascii.msh");

    const ALL_FIXTURES: [&[u8]; 9] = [
        RECT_41_ASCII,
        RECT_41_BINARY,
        RECT_22_ASCII,
        RECT_22_BINARY,
        OVERLAP_41,
        OVERLAP_22,
        NOGROUPS_41,
        NOGROUPS_22,
        QUARTER_DISC,
    ];

    fn parse(bytes: &[u8]) -> Mesh {
        parse_msh(bytes, "test.msh").unwrap_or_else(|e| panic!("{e}"))
    }

    /// The message of the input error that `bytes` must give; checks it is one line that
    /// names the file.
    fn error(bytes: &[u8]) -> String {
        match parse_msh(bytes, "bad.msh") {
            Err(Error::Input(msg)) => {
                assert!(!msg.contains('\n'), "not one line: {msg}");
                assert!(msg.starts_with("bad.msh"), "no file name: {msg}");
                msg
            }
            other => panic!("expected an input error, got {other:?}"),
        }
    }

    fn assert_words(msg: &str, words: &[&str]) {
        for word in words {
            assert!(msg.contains(word), "{msg:?} lacks {word:?}");
        }
    }

    fn text(bytes: &[u8]) -> String {
        String::from_utf8(bytes.to_vec()).unwrap()
    }

    /// Replaces the first `from` of an ASCII file by `to`.
    fn edit(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
        let s = text(bytes);
        assert!(s.contains(from), "{from:?} not in the file");
        s.replacen(from, to, 1).into_bytes()
    }

    fn line_of(bytes: &[u8], needle: &str) -> usize {
        let s = text(bytes);
        let at = s.find(needle).unwrap();
        1 + s[..at].matches('\n').count()
    }

    fn group_sizes<T>(groups: &BTreeMap<String, Vec<T>>) -> Vec<(&str, usize)> {
        groups.iter().map(|(k, v)| (k.as_str(), v.len())).collect()
    }

    // ---- hand-made files in every encoding -------------------------------------------

    #[derive(Clone, Copy, Debug)]
    enum Enc {
        Ascii,
        Little,
        Big,
    }

    /// A small mesh to write in any format: nodes (tag, xyz), elements (type, physical tag
    /// or 0, node tags), physical names (dim, tag, name).
    pub(super) struct Spec<'s> {
        nodes: &'s [(i32, [f64; 3])],
        elements: &'s [(i32, i32, &'s [i32])],
        names: &'s [(i32, i32, &'s str)],
    }

    fn put_int(out: &mut Vec<u8>, enc: Enc, v: i64, size: usize) {
        match (enc, size) {
            (Enc::Ascii, _) => out.extend_from_slice(format!("{v} ").as_bytes()),
            (Enc::Little, 4) => out.extend_from_slice(&(v as i32).to_le_bytes()),
            (Enc::Big, 4) => out.extend_from_slice(&(v as i32).to_be_bytes()),
            (Enc::Little, _) => out.extend_from_slice(&v.to_le_bytes()),
            (Enc::Big, _) => out.extend_from_slice(&v.to_be_bytes()),
        }
    }

    fn put_f64(out: &mut Vec<u8>, enc: Enc, v: f64) {
        match enc {
            // `{:?}` is the shortest text that reads back to the same bits.
            Enc::Ascii => out.extend_from_slice(format!("{v:?} ").as_bytes()),
            Enc::Little => out.extend_from_slice(&v.to_le_bytes()),
            Enc::Big => out.extend_from_slice(&v.to_be_bytes()),
        }
    }

    fn newline(out: &mut Vec<u8>, enc: Enc) {
        if let Enc::Ascii = enc {
            out.push(b'\n');
        }
    }

    fn header(out: &mut Vec<u8>, enc: Enc, version: &str, size: usize, spec: &Spec) {
        let binary = !matches!(enc, Enc::Ascii);
        out.extend_from_slice(
            format!("$MeshFormat\n{version} {} {size}\n", binary as u8).as_bytes(),
        );
        if binary {
            put_int(out, enc, 1, 4);
            out.push(b'\n');
        }
        out.extend_from_slice(b"$EndMeshFormat\n");
        if !spec.names.is_empty() {
            out.extend_from_slice(format!("$PhysicalNames\n{}\n", spec.names.len()).as_bytes());
            for (dim, tag, name) in spec.names {
                out.extend_from_slice(format!("{dim} {tag} \"{name}\"\n").as_bytes());
            }
            out.extend_from_slice(b"$EndPhysicalNames\n");
        }
    }

    fn msh22(enc: Enc, spec: &Spec) -> Vec<u8> {
        let mut out = Vec::new();
        header(&mut out, enc, "2.2", 8, spec);
        out.extend_from_slice(format!("$Nodes\n{}\n", spec.nodes.len()).as_bytes());
        for &(tag, xyz) in spec.nodes {
            put_int(&mut out, enc, tag.into(), 4);
            xyz.iter().for_each(|&v| put_f64(&mut out, enc, v));
            newline(&mut out, enc);
        }
        out.extend_from_slice(b"\n$EndNodes\n");
        out.extend_from_slice(format!("$Elements\n{}\n", spec.elements.len()).as_bytes());
        for (i, &(ty, physical, nodes)) in spec.elements.iter().enumerate() {
            let tag = i as i64 + 1;
            match enc {
                Enc::Ascii => [tag, ty.into(), 2]
                    .iter()
                    .for_each(|&v| put_int(&mut out, enc, v, 4)),
                _ => {
                    [ty.into(), 1, 2]
                        .iter()
                        .for_each(|&v| put_int(&mut out, enc, v, 4));
                    put_int(&mut out, enc, tag, 4);
                }
            }
            put_int(&mut out, enc, physical.into(), 4);
            put_int(&mut out, enc, tag, 4);
            nodes
                .iter()
                .for_each(|&n| put_int(&mut out, enc, n.into(), 4));
            newline(&mut out, enc);
        }
        out.extend_from_slice(b"\n$EndElements\n");
        out
    }

    fn element_dim(ty: i32) -> i64 {
        match ty {
            15 => 0,
            1 | 8 => 1,
            4 => 3,
            _ => 2,
        }
    }

    /// MSH 4.1 with one entity per element (entity tag = element index + 1).
    fn msh41(enc: Enc, size_t: usize, spec: &Spec) -> Vec<u8> {
        let mut out = Vec::new();
        header(&mut out, enc, "4.1", size_t, spec);
        out.extend_from_slice(b"$Entities\n");
        let mut counts = [0i64; 4];
        for &(ty, _, _) in spec.elements {
            counts[element_dim(ty) as usize] += 1;
        }
        counts
            .iter()
            .for_each(|&c| put_int(&mut out, enc, c, size_t));
        newline(&mut out, enc);
        for dim in 0..4 {
            for (i, &(ty, physical, _)) in spec.elements.iter().enumerate() {
                if element_dim(ty) != dim {
                    continue;
                }
                put_int(&mut out, enc, i as i64 + 1, 4);
                let coordinates = if dim == 0 { 3 } else { 6 };
                (0..coordinates).for_each(|_| put_f64(&mut out, enc, 0.0));
                put_int(&mut out, enc, (physical != 0) as i64, size_t);
                if physical != 0 {
                    put_int(&mut out, enc, physical.into(), 4);
                }
                if dim > 0 {
                    put_int(&mut out, enc, 0, size_t);
                }
                newline(&mut out, enc);
            }
        }
        out.extend_from_slice(b"\n$EndEntities\n$Nodes\n");
        let n = spec.nodes.len() as i64;
        let min = spec.nodes.iter().map(|p| p.0).min().unwrap_or(0).into();
        let max = spec.nodes.iter().map(|p| p.0).max().unwrap_or(0).into();
        [1, n, min, max]
            .iter()
            .for_each(|&v| put_int(&mut out, enc, v, size_t));
        newline(&mut out, enc);
        [2, 1, 0].iter().for_each(|&v| put_int(&mut out, enc, v, 4));
        put_int(&mut out, enc, n, size_t);
        newline(&mut out, enc);
        for &(tag, _) in spec.nodes {
            put_int(&mut out, enc, tag.into(), size_t);
            newline(&mut out, enc);
        }
        for &(_, xyz) in spec.nodes {
            xyz.iter().for_each(|&v| put_f64(&mut out, enc, v));
            newline(&mut out, enc);
        }
        out.extend_from_slice(b"\n$EndNodes\n$Elements\n");
        let e = spec.elements.len() as i64;
        [e, e, 1, e.max(1)]
            .iter()
            .for_each(|&v| put_int(&mut out, enc, v, size_t));
        newline(&mut out, enc);
        for (i, &(ty, _, nodes)) in spec.elements.iter().enumerate() {
            let tag = i as i64 + 1;
            [element_dim(ty), tag, ty.into()]
                .iter()
                .for_each(|&v| put_int(&mut out, enc, v, 4));
            put_int(&mut out, enc, 1, size_t);
            newline(&mut out, enc);
            put_int(&mut out, enc, tag, size_t);
            nodes
                .iter()
                .for_each(|&n| put_int(&mut out, enc, n.into(), size_t));
            newline(&mut out, enc);
        }
        out.extend_from_slice(b"\n$EndElements\n");
        out
    }

    /// Every hand-made variant of `spec`: (label, bytes).
    pub(super) fn all_variants(spec: &Spec) -> Vec<(String, Vec<u8>)> {
        let mut out = Vec::new();
        for enc in [Enc::Ascii, Enc::Little, Enc::Big] {
            out.push((format!("2.2 {enc:?}"), msh22(enc, spec)));
            out.push((format!("4.1 {enc:?} size_t 8"), msh41(enc, 8, spec)));
            if !matches!(enc, Enc::Ascii) {
                out.push((format!("4.1 {enc:?} size_t 4"), msh41(enc, 4, spec)));
            }
        }
        out
    }

    /// Awkward doubles: none has a short exact decimal form.
    const AWKWARD: [f64; 6] = [
        0.1,
        1.0 / 3.0,
        std::f64::consts::SQRT_2,
        1e-300,
        -2.5e10,
        5e-324,
    ];

    /// A square of 4 nodes with sparse, unordered tags and awkward coordinates.
    const SQUARE_NODES: [(i32, [f64; 3]); 4] = [
        (40, [AWKWARD[0], AWKWARD[3], 0.0]),
        (7, [AWKWARD[1], AWKWARD[5], 0.0]),
        (1000, [AWKWARD[2], AWKWARD[4], 0.0]),
        (3, [-0.0, 1.0, 0.0]),
    ];
    const SQUARE_ELEMENTS: [(i32, i32, &[i32]); 4] = [
        (15, 2, &[1000]),
        (1, 1, &[40, 7]),
        (2, 3, &[40, 7, 1000]),
        (2, 3, &[40, 1000, 3]),
    ];
    const SQUARE_NAMES: [(i32, i32, &str); 2] = [(1, 1, "bottom side"), (2, 3, "body")];

    pub(super) fn square() -> Spec<'static> {
        Spec {
            nodes: &SQUARE_NODES,
            elements: &SQUARE_ELEMENTS,
            names: &SQUARE_NAMES,
        }
    }

    #[test]
    fn hand_made_files_read_the_same_in_every_encoding() {
        let expected = Mesh {
            nodes: SQUARE_NODES.iter().map(|(_, p)| [p[0], p[1]]).collect(),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            line_groups: BTreeMap::from([("bottom side".to_string(), vec![[0, 1]])]),
            // Group 2 has no name: its tag names it.
            point_groups: BTreeMap::from([("2".to_string(), vec![2])]),
            surface_groups: BTreeMap::from([("body".to_string(), vec![0, 1])]),
        };
        for (label, bytes) in all_variants(&square()) {
            let mesh = parse_msh(&bytes, "square.msh").unwrap_or_else(|e| panic!("{label}: {e}"));
            assert_eq!(mesh, expected, "{label}");
        }
    }

    /// Two bodies, one triangle also in a third group (written twice, once per group, as
    /// MSH 2.2 does): each triangle once, in every group it was given.
    #[test]
    fn surface_groups_keep_their_triangles_through_repeats() {
        const ELEMENTS: [(i32, i32, &[i32]); 5] = [
            (1, 1, &[40, 7]),
            (2, 3, &[40, 7, 1000]),
            (2, 4, &[40, 1000, 3]),
            (2, 5, &[1000, 3, 40]),
            (2, 3, &[7, 1000, 40]),
        ];
        const NAMES: [(i32, i32, &str); 3] = [(2, 3, "lower"), (2, 4, "upper"), (2, 5, "tip")];
        let spec = Spec {
            nodes: &SQUARE_NODES,
            elements: &ELEMENTS,
            names: &NAMES,
        };
        for (label, bytes) in all_variants(&spec) {
            let mesh = parse(&bytes);
            assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]], "{label}");
            let groups: Vec<(&str, &[usize])> = (mesh.surface_groups.iter())
                .map(|(k, v)| (k.as_str(), v.as_slice()))
                .collect();
            assert_eq!(
                groups,
                [("lower", &[0][..]), ("tip", &[1]), ("upper", &[1])],
                "{label}"
            );
        }
    }

    #[test]
    fn coordinates_round_trip_bit_for_bit() {
        for (label, bytes) in all_variants(&square()) {
            let mesh = parse(&bytes);
            for (got, (_, want)) in mesh.nodes.iter().zip(SQUARE_NODES) {
                assert_eq!(got[0].to_bits(), want[0].to_bits(), "{label}");
                assert_eq!(got[1].to_bits(), want[1].to_bits(), "{label}");
            }
        }
    }

    // ---- the Gmsh fixtures ------------------------------------------------------------

    #[test]
    fn rectangle_ascii_formats_are_identical() {
        assert_eq!(parse(RECT_41_ASCII), parse(RECT_22_ASCII));
    }

    #[test]
    fn rectangle_binary_formats_are_identical() {
        assert_eq!(parse(RECT_41_BINARY), parse(RECT_22_BINARY));
    }

    /// Gmsh writes ASCII coordinates with 16 significant digits, one short of what a double
    /// needs, so ASCII and binary agree to the last bit or so, and exactly in everything else.
    #[test]
    fn rectangle_ascii_and_binary_agree() {
        let ascii = parse(RECT_41_ASCII);
        let binary = parse(RECT_41_BINARY);
        assert_eq!(ascii.triangles, binary.triangles);
        assert_eq!(ascii.line_groups, binary.line_groups);
        assert_eq!(ascii.point_groups, binary.point_groups);
        assert_eq!(ascii.nodes.len(), binary.nodes.len());
        for (a, b) in ascii.nodes.iter().zip(&binary.nodes) {
            for k in 0..2 {
                let tolerance = 2.0 * f64::EPSILON * a[k].abs().max(1.0);
                assert!((a[k] - b[k]).abs() <= tolerance, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn rectangle_ascii_coordinates_are_the_file_text() {
        let mesh = parse(RECT_41_ASCII);
        // Node 5 is the first node inside the bottom side.
        assert_eq!(mesh.nodes[4], [0.2499999999995475, 0.0]);
        let binary = parse(RECT_41_BINARY);
        assert_eq!(
            binary.nodes[4][0].to_bits(),
            0.24999999999954753f64.to_bits()
        );
    }

    #[test]
    fn rectangle_groups_have_the_right_names_and_sizes() {
        let mesh = parse(RECT_41_ASCII);
        assert_eq!(mesh.num_nodes(), 56);
        assert_eq!(mesh.triangles.len(), 86);
        assert_eq!(
            group_sizes(&mesh.line_groups),
            [("bottom", 8), ("left", 4), ("right", 4), ("top", 8)]
        );
        assert_eq!(mesh.point_groups["corner"], vec![0]);
        assert_eq!(mesh.nodes[0], [0.0, 0.0]);
        let on = |group: &str, test: &dyn Fn([f64; 2]) -> bool| {
            let nodes = mesh.group_nodes(group).unwrap();
            nodes.iter().all(|&n| test(mesh.nodes[n]))
        };
        assert!(on("bottom", &|p| p[1] == 0.0));
        assert!(on("top", &|p| p[1] == 1.0));
        assert!(on("left", &|p| p[0] == 0.0));
        assert!(on("right", &|p| p[0] == 2.0));
        assert_eq!(mesh.group_nodes("bottom").unwrap().len(), 9);
        let area: f64 = (0..mesh.triangles.len())
            .map(|t| mesh.signed_area2(t).abs())
            .sum();
        assert!((area / 2.0 - 2.0).abs() < 1e-12, "area {}", area / 2.0);
    }

    #[test]
    fn element_in_several_groups_goes_in_each() {
        let v41 = parse(OVERLAP_41);
        let v22 = parse(OVERLAP_22);
        assert_eq!(v41, v22);
        assert_eq!(
            group_sizes(&v41.line_groups),
            [("7", 2), ("bottom", 2), ("contact", 4)]
        );
        let bottom = &v41.line_groups["bottom"];
        assert_eq!(&v41.line_groups["contact"][..2], &bottom[..]);
        assert_eq!(v41.point_groups["pin"].len(), 1);
        assert_eq!(v41.nodes[v41.point_groups["pin"][0]], [1.0, 1.0]);
        // The surface is in two physical groups: MSH 2.2 lists each triangle twice.
        assert_eq!(v41.triangles.len(), 14);
        assert_eq!(text(OVERLAP_22).matches(" 2 2 9 1 ").count(), 14);
    }

    #[test]
    fn a_block_of_tags_is_recorded_whole_or_up_to_its_first_repeat() {
        let mut index = TagIndex::default();
        index.expect(1000);
        // Consecutive tags fill a stretch of the table.
        let block: Vec<u64> = (10..610).collect();
        assert_eq!(index.insert_all(&block, 4), Ok(()));
        assert_eq!(
            (index.get(10), index.get(609), index.get(610)),
            (Some(4), Some(603), None)
        );
        // A second block that repeats a tag: the first repeat is named, those before it kept.
        assert_eq!(index.insert_all(&[700, 701, 609, 702], 604), Err(2));
        assert_eq!(
            (index.get(701), index.get(609), index.get(702)),
            (Some(605), Some(603), None)
        );
        // Consecutive tags over a recorded one, and tags that repeat within the block.
        assert_eq!(index.insert_all(&[2004], 699), Ok(()));
        assert_eq!(
            index.insert_all(&(2000..2010).collect::<Vec<_>>(), 700),
            Err(4)
        );
        assert_eq!((index.get(2003), index.get(2004)), (Some(703), Some(699)));
        assert_eq!(index.insert_all(&[800, 801, 800], 710), Err(2));
        // Beyond the table, in the map; and an empty block.
        assert_eq!(index.insert_all(&[u64::MAX - 1, u64::MAX], 720), Ok(()));
        assert_eq!(index.get(u64::MAX), Some(721));
        assert_eq!(index.insert_all(&[], 730), Ok(()));
    }

    #[test]
    fn tags_in_one_run_are_found_by_their_offset_and_the_run_ends_at_the_first_other() {
        let mut index = TagIndex::default();
        index.expect(1000);
        assert_eq!(index.insert_all(&(1..=600).collect::<Vec<_>>(), 0), Ok(()));
        assert!(index.insert(601, 600));
        assert_eq!(
            index.insert_all(&(602..700).collect::<Vec<_>>(), 601),
            Ok(())
        );
        assert_eq!(index.run, Run::Tags { first: 1, len: 699 });
        assert_eq!(
            (index.get(1), index.get(699), index.get(700)),
            (Some(0), Some(698), None)
        );
        assert_eq!(index.get(0), None);
        // A repeat leaves the run as it was.
        assert!(!index.insert(5, 699));
        assert_eq!(index.run, Run::Tags { first: 1, len: 699 });
        // A tag out of the run's order ends it; the table still answers.
        assert!(index.insert(900, 699));
        assert_eq!(index.run, Run::Broken);
        let found: Vec<Option<usize>> = [1, 699, 900, 700].map(|t| index.get(t)).to_vec();
        assert_eq!(found, [Some(0), Some(698), Some(699), None]);
        // A first block not at index 0 is no run.
        let mut later = TagIndex::default();
        later.expect(10);
        assert_eq!(later.insert_all(&[1, 2, 3], 4), Ok(()));
        assert_eq!(later.run, Run::Broken);
    }

    #[test]
    fn far_node_tags_read_like_near_ones() {
        // Tags from 65536 on are beyond the table of a 4-node file: they go to the map.
        let far: Vec<(i32, [f64; 3])> = SQUARE_NODES
            .iter()
            .zip([70_000, 3, i32::MAX, 65_536])
            .map(|(&(_, p), tag)| (tag, p))
            .collect();
        let retag = |t: i32| far[SQUARE_NODES.iter().position(|n| n.0 == t).unwrap()].0;
        let nodes: Vec<Vec<i32>> = SQUARE_ELEMENTS
            .iter()
            .map(|e| e.2.iter().map(|&t| retag(t)).collect())
            .collect();
        let elements: Vec<(i32, i32, &[i32])> = SQUARE_ELEMENTS
            .iter()
            .zip(&nodes)
            .map(|(e, n)| (e.0, e.1, &n[..]))
            .collect();
        let spec = Spec {
            nodes: &far,
            elements: &elements,
            names: &SQUARE_NAMES,
        };
        let expected = parse_msh(&msh41(Enc::Ascii, 8, &square()), "near.msh").unwrap();
        for (label, bytes) in all_variants(&spec) {
            let mesh = parse_msh(&bytes, "far.msh").unwrap_or_else(|e| panic!("{label}: {e}"));
            assert_eq!(mesh, expected, "{label}");
        }
    }

    #[test]
    fn tag_index_finds_each_tag_once_near_and_far() {
        let mut index = TagIndex::default();
        index.expect(4);
        let tags = [1u64, 9, 1 << 16, u64::MAX, 0, 70_000];
        for (i, &t) in tags.iter().enumerate() {
            assert!(index.insert(t, i), "tag {t}");
        }
        for (i, &t) in tags.iter().enumerate() {
            assert_eq!(index.get(t), Some(i), "tag {t}");
            assert!(!index.insert(t, 99), "tag {t} twice");
            assert_eq!(index.get(t), Some(i), "tag {t} kept");
        }
        for t in [2u64, 8, 10, 65_535, 1 << 40] {
            assert_eq!(index.get(t), None, "tag {t}");
        }
    }

    #[test]
    fn repeated_triangles_keep_the_first_in_file_order() {
        // Few nodes, many triangles: repeats in every orientation, big buckets.
        let mut seed = 12345u64;
        let mut next = |n: u64| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) % n) as usize
        };
        // The last on several threads, each with a range of the nodes: many nodes, and a
        // third of the triangles earlier ones again, turned or reflected.
        for (nodes, count, threads) in
            [(4, 10, 1), (6, 200, 1), (30, 2000, 1), (90_000, 400_000, 3)]
        {
            let mut triangles: Vec<[usize; 3]> = Vec::with_capacity(count);
            for i in 0..count {
                let t = if i > 0 && next(3) == 0 {
                    let [a, b, c] = triangles[next(i as u64)];
                    [[a, b, c], [b, c, a], [c, b, a]][next(3)]
                } else {
                    [next(nodes), next(nodes), next(nodes)]
                };
                triangles.push(t);
            }
            let mut seen = std::collections::HashSet::new();
            let expected: Vec<[usize; 3]> = triangles
                .iter()
                .filter(|t| {
                    let mut k = **t;
                    k.sort_unstable();
                    seen.insert(k)
                })
                .copied()
                .collect();
            let mut kept = triangles.clone();
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
            let new_index = (pool.unwrap())
                .install(|| drop_repeated_triangles(nodes as usize, &mut kept))
                .unwrap_or_else(|| (0..count).collect());
            assert_eq!(kept, expected, "{nodes} nodes, {count} triangles");
            let sorted = |mut t: [usize; 3]| {
                t.sort_unstable();
                t
            };
            for (t, &i) in triangles.iter().zip(&new_index) {
                assert_eq!(
                    sorted(kept[i]),
                    sorted(*t),
                    "{nodes} nodes, {count} triangles"
                );
            }
        }
    }

    #[test]
    fn without_physical_groups_all_triangles_are_kept() {
        let v41 = parse(NOGROUPS_41);
        assert_eq!(v41, parse(NOGROUPS_22));
        assert_eq!(v41.triangles.len(), 14);
        assert!(v41.line_groups.is_empty());
        assert!(v41.point_groups.is_empty());
    }

    #[test]
    fn quarter_disc_groups_lie_where_they_should() {
        let mesh = parse(QUARTER_DISC);
        assert!(mesh.triangles.len() > 300, "{}", mesh.triangles.len());
        assert_eq!(
            mesh.line_groups.keys().collect::<Vec<_>>(),
            ["axis", "contact", "top"]
        );
        let nodes = |group: &str| -> Vec<[f64; 2]> {
            let ids = mesh.group_nodes(group).unwrap();
            ids.into_iter().map(|n| mesh.nodes[n]).collect()
        };
        assert!(nodes("axis").iter().all(|p| p[0] == 0.0));
        assert!(nodes("top").iter().all(|p| p[1] == 1.0));
        for p in nodes("contact") {
            let r = (p[0] * p[0] + (p[1] - 1.0) * (p[1] - 1.0)).sqrt();
            assert!((r - 1.0).abs() < 1e-12, "{p:?}");
        }
        let area: f64 = (0..mesh.triangles.len())
            .map(|t| mesh.signed_area2(t).abs())
            .sum();
        let exact = std::f64::consts::PI / 4.0;
        assert!((area / 2.0 - exact).abs() < 0.01, "area {}", area / 2.0);
    }

    #[test]
    fn read_msh_reads_a_file_and_names_a_missing_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rect.msh");
        std::fs::write(&path, RECT_22_BINARY).unwrap();
        assert_eq!(read_msh(&path).unwrap(), parse(RECT_22_BINARY));
        let missing = dir.path().join("missing.msh");
        let Err(Error::Input(msg)) = read_msh(&missing) else {
            panic!("a missing file must be an input error");
        };
        assert_words(&msg, &["missing.msh", "cannot read"]);
    }

    #[test]
    fn unknown_sections_are_skipped() {
        let extra = "$Comments\nnot a $Nodes section\n$EndNodes is no end here\n$EndComments\n\
                     $NodeData\n1\n\"u\"\n1\n0.0\n3\n0\n1\n1\n1 0.5\n$EndNodeData\n";
        let ascii = edit(RECT_41_ASCII, "$Nodes\n", &format!("{extra}$Nodes\n"));
        assert_eq!(parse(&ascii), parse(RECT_41_ASCII));
        let ascii = [RECT_22_ASCII, extra.as_bytes()].concat();
        assert_eq!(parse(&ascii), parse(RECT_22_ASCII));
        let mut binary = RECT_41_BINARY.to_vec();
        binary.extend_from_slice(b"$NodeData\n1\n\"u\"\n1\n0.0\n3\n0\n1\n1\n");
        binary.extend_from_slice(&[1, 0, 0, 0, b'\n', b'$', 0, 0, 0, 0, 0, 0xe0, 0x3f]);
        binary.extend_from_slice(b"\n$EndNodeData\n");
        assert_eq!(parse(&binary), parse(RECT_41_BINARY));
    }

    #[test]
    fn windows_line_endings_are_read() {
        let crlf = text(RECT_41_ASCII).replace('\n', "\r\n");
        assert_eq!(parse(crlf.as_bytes()), parse(RECT_41_ASCII));
    }

    #[test]
    fn a_mesh_in_a_plane_z_constant_is_accepted() {
        let nodes: Vec<_> = SQUARE_NODES
            .iter()
            .map(|&(t, p)| (t, [p[0].clamp(-3.0, 3.0), p[1], 4.5]))
            .collect();
        let spec = Spec {
            nodes: &nodes,
            ..square()
        };
        assert_eq!(parse(&msh22(Enc::Ascii, &spec)).nodes[3], [-0.0, 1.0]);
    }

    // ---- errors ----------------------------------------------------------------------

    #[test]
    fn not_a_gmsh_file() {
        for bytes in [
            &b""[..],
            b"   \n",
            b"hello world",
            b"$Nodes\n1\n1 0 0 0\n$EndNodes\n",
            b"$MeshFormatX\n4.1 0 8\n$EndMeshFormat\n",
            b"\x00\x01\x02binary junk",
        ] {
            assert_words(&error(bytes), &["not a Gmsh mesh file", "$MeshFormat"]);
        }
    }

    #[test]
    fn unsupported_versions_say_how_to_convert() {
        for version in ["3.0", "4", "4.0", "2.1", "1.0", "abc"] {
            let bytes = edit(RECT_41_ASCII, "4.1 0 8", &format!("{version} 0 8"));
            let msg = error(&bytes);
            assert_words(
                &msg,
                &[version, "not supported", "-save -format msh41", "msh22"],
            );
            assert!(msg.starts_with("bad.msh:2:"), "{msg}");
        }
        let msh1 = b"$NOD\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n$ENDNOD\n$ELM\n0\n$ENDELM\n";
        assert_words(&error(msh1), &["MSH 1.0", "msh41", "msh22"]);
    }

    #[test]
    fn bad_header_fields() {
        let msg = error(&edit(RECT_41_ASCII, "4.1 0 8", "4.1 2 8"));
        assert_words(&msg, &["file type 2"]);
        let mut bad_size = RECT_41_BINARY.to_vec();
        bad_size[18] = b'3';
        assert_words(&error(&bad_size), &["data size 3", "not supported"]);
        let mut bad_marker = RECT_41_BINARY.to_vec();
        bad_marker[20] = 7;
        assert_words(&error(&bad_marker), &["endianness", "byte 20"]);
        let huge = edit(RECT_41_ASCII, "4.1 0 8", "4.1 1 99999999999999999999999");
        assert_words(&error(&huge), &["bad number", "data size"]);
    }

    #[test]
    fn missing_end_tags_are_truncation() {
        let s = text(RECT_41_ASCII);
        let cut = &s[..s.find("$EndNodes").unwrap()];
        let msg = error(cut.as_bytes());
        assert_words(&msg, &["truncated", "$Nodes"]);
        let cut = &s[..s.find("$EndElements").unwrap() + 8];
        assert_words(&error(cut.as_bytes()), &["$EndElements", "truncated"]);
        let open = [RECT_41_ASCII, b"$Comments\nno end\n"].concat();
        assert_words(&error(&open), &["$EndComments", "truncated"]);
        let b = RECT_22_BINARY;
        assert_words(&error(&b[..b.len() / 2]), &["truncated", "byte"]);
    }

    #[test]
    fn malformed_numbers_are_quoted_with_their_line() {
        let token = "0.2499999999995475 0 0";
        let line = line_of(RECT_41_ASCII, token);
        for bad in ["0.24x 0 0", "0.5-1 0", "1,5 0 0"] {
            let msg = error(&edit(RECT_41_ASCII, token, bad));
            let quoted = format!("'{}'", bad.split(' ').next().unwrap());
            assert_words(&msg, &["bad number", &quoted, "node coordinate"]);
            assert!(
                msg.starts_with(&format!("bad.msh:{line}: in $Nodes")),
                "{msg}"
            );
        }
        let msg = error(&edit(RECT_22_ASCII, "\n26 2 2 6 1", "\n26 2 2 6 x1"));
        assert_words(&msg, &["'x1'", "$Elements"]);
    }

    #[test]
    fn non_finite_coordinates_are_rejected() {
        for bad in ["nan", "inf", "-inf", "1e999"] {
            let msg = error(&edit(
                RECT_22_ASCII,
                "\n5 0.2499999999995475 0 0",
                &format!("\n5 {bad} 0 0"),
            ));
            assert_words(&msg, &["node 5", "not a finite number"]);
        }
        let mut nodes = SQUARE_NODES;
        nodes[2].1[1] = f64::NAN;
        let spec = Spec {
            nodes: &nodes,
            ..square()
        };
        let msg = error(&msh41(Enc::Little, 8, &spec));
        assert_words(&msg, &["node 1000", "y = NaN", "byte"]);
    }

    #[test]
    fn undefined_node_tags_are_named() {
        let msg = error(&edit(
            RECT_22_ASCII,
            "\n26 2 2 6 1 37 44 53",
            "\n26 2 2 6 1 37 44 999",
        ));
        assert_words(&msg, &["element 26", "node 999", "not defined"]);
        let msg = error(&edit(RECT_41_ASCII, "\n26 37 44 53", "\n26 37 44 999"));
        assert_words(&msg, &["element 26", "node 999", "not defined"]);
    }

    #[test]
    fn unsupported_element_types_say_what_to_do() {
        let cases: [(i32, &[i32], &[&str]); 6] = [
            (8, &[40, 7, 3], &["type 8", "Mesh.ElementOrder = 1"]),
            (
                9,
                &[40, 7, 1000, 3, 40, 7],
                &["type 9", "Mesh.ElementOrder = 1"],
            ),
            (
                3,
                &[40, 7, 1000, 3],
                &["type 3", "quadrangle", "remove Recombine"],
            ),
            (
                16,
                &[40, 7, 1000, 3, 40, 7, 1000, 3],
                &["Recombine", "ElementOrder = 1"],
            ),
            (4, &[40, 7, 1000, 3], &["volume", "2D"]),
            (99, &[40], &["type 99", "not supported", "(2)"]),
        ];
        for (ty, nodes, words) in cases {
            let mut elements = SQUARE_ELEMENTS.to_vec();
            elements.push((ty, 5, nodes));
            let spec = Spec {
                elements: &elements,
                ..square()
            };
            for (label, bytes) in all_variants(&spec) {
                let msg = error(&bytes);
                assert_words(&msg, words);
                assert!(msg.contains("$Elements"), "{label}: {msg}");
            }
        }
    }

    #[test]
    fn a_mesh_without_triangles_is_rejected() {
        let elements = &SQUARE_ELEMENTS[..2];
        let spec = Spec {
            elements,
            ..square()
        };
        for (_, bytes) in all_variants(&spec) {
            assert_words(&error(&bytes), &["no triangles", "gmsh -2"]);
        }
        let s = text(RECT_41_ASCII);
        let no_elements = &s[..s.find("$Elements").unwrap()];
        assert_words(&error(no_elements.as_bytes()), &["no triangles"]);
    }

    #[test]
    fn a_mesh_that_is_not_planar_is_rejected() {
        let msg = error(&edit(
            RECT_22_ASCII,
            "\n5 0.2499999999995475 0 0",
            "\n5 0.2499999999995475 0 0.01",
        ));
        assert_words(&msg, &["not planar", "node 5", "z = 0.01"]);
    }

    #[test]
    fn structural_errors() {
        let twice = edit(
            RECT_22_ASCII,
            "\n6 0.4999999999988248 0 0",
            "\n5 0.4999999999988248 0 0",
        );
        assert_words(&error(&twice), &["node 5", "defined twice"]);
        let short = edit(RECT_22_ASCII, "$Nodes\n56\n", "$Nodes\n57\n");
        assert_words(&error(&short), &["'$EndNodes'", "less data"]);
        let long = edit(RECT_22_ASCII, "$Nodes\n56\n", "$Nodes\n55\n");
        assert_words(&error(&long), &["expected $EndNodes", "more data"]);
        let count = edit(RECT_41_ASCII, "9 56 1 56", "9 57 1 57");
        assert_words(&error(&count), &["57 nodes", "56"]);
        let junk = edit(RECT_41_ASCII, "$Nodes\n", "junk\n$Nodes\n");
        assert_words(&error(&junk), &["section header", "'junk'"]);
        let partitioned = edit(
            RECT_41_ASCII,
            "$Nodes\n",
            "$PartitionedEntities\n0\n$EndPartitionedEntities\n$Nodes\n",
        );
        assert_words(&error(&partitioned), &["partitioned"]);
        let entity = edit(RECT_41_ASCII, "\n2 1 2 86", "\n2 9 2 86");
        assert_words(&error(&entity), &["entity 9", "$Entities"]);
        let no_name = edit(RECT_41_ASCII, "1 1 \"bottom\"", "1 1 ");
        assert_words(&error(&no_name), &["empty name"]);
        let s = text(RECT_22_ASCII);
        let (head, tail) = s.split_at(s.find("$Nodes").unwrap());
        let nodes_end = tail.find("$Elements").unwrap();
        let swapped = format!("{head}{}{}", &tail[nodes_end..], &tail[..nodes_end]);
        assert_words(&error(swapped.as_bytes()), &["before $Nodes"]);
    }

    #[test]
    fn huge_counts_do_not_allocate() {
        let huge = edit(
            RECT_41_ASCII,
            "9 56 1 56",
            "1 18446744073709551615 1 18446744073709551615",
        );
        error(&huge);
        let huge = edit(
            RECT_22_ASCII,
            "$Nodes\n56\n",
            "$Nodes\n18446744073709551615\n",
        );
        error(&huge);
        let huge = edit(
            RECT_22_ASCII,
            "$Nodes\n56\n",
            "$Nodes\n99999999999999999999999\n",
        );
        error(&huge);
        let huge = edit(RECT_41_ASCII, "\n2 1 2 86", "\n2 1 2 4611686018427387904");
        error(&huge);
        let empty = edit(
            RECT_41_ASCII,
            "$Nodes\n9 56 1 56",
            "$Nodes\n0 0 1 1\n$EndNodes\n$Nodes\n9 56 1 56",
        );
        assert_words(&error(&empty), &["second $Nodes"]);
    }

    // ---- robustness: no input may panic ----------------------------------------------

    fn parses_without_panic(bytes: &[u8]) -> bool {
        match parse_msh(bytes, "fuzz.msh") {
            Ok(_) => true,
            Err(Error::Input(msg)) => {
                assert!(!msg.contains('\n') && msg.starts_with("fuzz.msh"), "{msg}");
                false
            }
            Err(e) => panic!("not an input error: {e:?}"),
        }
    }

    #[test]
    fn every_truncation_is_an_error_unless_only_blanks_are_cut() {
        for file in ALL_FIXTURES.iter().take(8) {
            for n in 0..file.len() {
                let only_blanks_cut = file[n..].iter().all(|&c| is_space(c));
                assert_eq!(
                    parses_without_panic(&file[..n]),
                    only_blanks_cut,
                    "cut at {n}"
                );
            }
        }
    }

    #[test]
    fn corrupted_bytes_never_panic() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move |bound: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % bound as u64) as usize
        };
        const INTERESTING: &[u8] = b"$\n -.09eE\x00\xff\x01\x7f";
        for file in ALL_FIXTURES {
            for _ in 0..600 {
                let mut bytes = file.to_vec();
                for _ in 0..1 + next(3) {
                    let at = next(bytes.len());
                    match next(4) {
                        0 => bytes[at] = INTERESTING[next(INTERESTING.len())],
                        1 => bytes[at] = next(256) as u8,
                        2 => {
                            let end = (at + next(16)).min(bytes.len());
                            bytes.drain(at..end);
                        }
                        _ => bytes.insert(at, INTERESTING[next(INTERESTING.len())]),
                    }
                    if bytes.is_empty() {
                        break;
                    }
                }
                parses_without_panic(&bytes);
            }
        }
    }
}
