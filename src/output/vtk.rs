//! ParaView output: VTK XML unstructured grids (`.vtu`), one or more per rank (see
//! [`file_ranges`]), and a parallel index (`.pvtu`) that lists the pieces and declares
//! their arrays.
//!
//! Encoding: a short XML head declares each array with an offset into one
//! `<AppendedData encoding="raw">` block at the end of the file, which holds every array
//! as an 8-byte length (`header_type="UInt64"`) and its values as raw little-endian bytes.
//! So every f64 reaches ParaView bit for bit, and writing a file is one copy of its values
//! into one buffer of the file's exact size: no base64 text (a third larger, and the
//! slowest step of the earlier encoder) and no XML escaping of the data. The XML is
//! formatted here, from the array table below: vtkio, the established Rust VTK crate,
//! cannot write raw appended data (0.6 and 0.7 encode every array inline as base64; the
//! raw path of 0.7 is compiled out) nor label components. VTK's own readers open these
//! files in `tests/vtk_reader.rs`.
//!
//! Arrays written (Float64 or Int32):
//!
//! | data  | name                  | type    | comps | meaning                                  |
//! |-------|-----------------------|---------|-------|------------------------------------------|
//! | point | `displacement`        | Float64 | 3     | ux, uy, 0 (3D so Warp By Vector works)   |
//! | point | `contact_pressure`    | Float64 | 1     | 0 off the contact boundary               |
//! | point | `tangential_traction` | Float64 | 1     | 0 off the contact boundary               |
//! | point | `contact_status`      | Int32   | 1     | -1 not a contact node, 0 free, 1 stick, 2 slip, 3 in contact without friction |
//! | cell  | `stress`              | Float64 | 4     | components named xx, yy, xy, zz          |
//! | cell  | `von_mises`           | Float64 | 1     |                                          |
//! | cell  | `rank`                | Int32   | 1     | MPI rank that owns the triangle          |
//! | cell  | `body`                | Int32   | 1     | the triangle's body: its material's index (0 with one `[material]`) |

use crate::error::{Error, Result};

/// The data of one rank's piece: its own triangles and the nodes they use, numbered locally.
///
/// Node arrays have one entry per node, cell arrays one per triangle.
#[derive(Debug, Clone, Copy)]
pub struct Piece<'a> {
    pub nodes: &'a [[f64; 2]],
    /// Local node indices, counter-clockwise.
    pub triangles: &'a [[usize; 3]],
    pub displacement: &'a [[f64; 2]],
    /// Per cell: sxx, syy, sxy, szz.
    pub stress: &'a [[f64; 4]],
    /// Per cell.
    pub von_mises: &'a [f64],
    /// Per cell: the owning rank.
    pub rank: &'a [i32],
    /// Per cell: the body (index of its material in the case).
    pub body: &'a [i32],
    /// Per node, 0 off the contact boundary.
    pub contact_pressure: &'a [f64],
    /// Per node, 0 off the contact boundary.
    pub tangential_traction: &'a [f64],
    /// Per node: -1 not a contact node, 0 free, 1 stick, 2 slip.
    pub contact_status: &'a [i32],
}

/// Triangles per `.vtu` file at most: a rank's piece larger than this is written as
/// several files of equal size ([`file_ranges`], [`SubPiece`]).
///
/// Why: a rank with several threads encodes and writes its files at once, and each
/// file's buffer (about 14 MB at this size) is freed and reused by the next instead of
/// one buffer of the whole piece being page-faulted in and zeroed by the kernel (the
/// output phase keeps freed blocks in the heap).
pub const MAX_TRIANGLES_PER_FILE: usize = 131_072;

/// The triangle ranges of the files of `piece`: as few as [`MAX_TRIANGLES_PER_FILE`]
/// allows, of equal size to one triangle; one empty range for an empty piece, which
/// still gets its file. Errors as [`vtu_bytes`] on an inconsistent piece.
pub fn file_ranges(piece: &Piece) -> Result<Vec<std::ops::Range<usize>>> {
    check_piece(piece)?;
    Ok(even_ranges(piece.triangles.len(), MAX_TRIANGLES_PER_FILE))
}

/// 0..n cut into as few ranges of at most `max` as possible, of equal size to one; one
/// empty range for n = 0.
fn even_ranges(n: usize, max: usize) -> Vec<std::ops::Range<usize>> {
    let files = n.div_ceil(max).max(1);
    (0..files)
        .map(|k| (k * n / files)..((k + 1) * n / files))
        .collect()
}

/// The part of a piece made of some of its triangles and the nodes they use, renumbered
/// in order of first use; cell arrays are borrowed, node arrays copied.
pub struct SubPiece<'a> {
    whole: Piece<'a>,
    range: std::ops::Range<usize>,
    nodes: Vec<[f64; 2]>,
    triangles: Vec<[usize; 3]>,
    displacement: Vec<[f64; 2]>,
    contact_pressure: Vec<f64>,
    tangential_traction: Vec<f64>,
    contact_status: Vec<i32>,
}

impl<'a> SubPiece<'a> {
    /// The triangles `range` of `whole`, one of the [`file_ranges`] of `whole` (which
    /// checks that the triangles name only its nodes).
    pub fn new(whole: &Piece<'a>, range: std::ops::Range<usize>) -> Self {
        let mut new_of = vec![usize::MAX; whole.nodes.len()];
        let mut used = Vec::new();
        let triangles = whole.triangles[range.clone()]
            .iter()
            .map(|t| {
                t.map(|v| {
                    if new_of[v] == usize::MAX {
                        new_of[v] = used.len();
                        used.push(v);
                    }
                    new_of[v]
                })
            })
            .collect();
        SubPiece {
            whole: *whole,
            nodes: pick(whole.nodes, &used),
            triangles,
            displacement: pick(whole.displacement, &used),
            contact_pressure: pick(whole.contact_pressure, &used),
            tangential_traction: pick(whole.tangential_traction, &used),
            contact_status: pick(whole.contact_status, &used),
            range,
        }
    }

    pub fn piece(&self) -> Piece<'_> {
        let r = self.range.clone();
        Piece {
            nodes: &self.nodes,
            triangles: &self.triangles,
            displacement: &self.displacement,
            stress: &self.whole.stress[r.clone()],
            von_mises: &self.whole.von_mises[r.clone()],
            rank: &self.whole.rank[r.clone()],
            body: &self.whole.body[r],
            contact_pressure: &self.contact_pressure,
            tangential_traction: &self.tangential_traction,
            contact_status: &self.contact_status,
        }
    }
}

/// The values of `a` at `at`, in that order.
fn pick<T: Copy>(a: &[T], at: &[usize]) -> Vec<T> {
    at.iter().map(|&v| a[v]).collect()
}

/// How one value is stored.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    F64,
    I32,
    I64,
    U8,
}

impl Kind {
    fn vtk_name(self) -> &'static str {
        match self {
            Kind::F64 => "Float64",
            Kind::I32 => "Int32",
            Kind::I64 => "Int64",
            Kind::U8 => "UInt8",
        }
    }

    /// Bytes per value.
    fn size(self) -> usize {
        match self {
            Kind::F64 => 8,
            Kind::I64 => 8,
            Kind::I32 => 4,
            Kind::U8 => 1,
        }
    }
}

/// What ParaView colours by or warps by when a file is first opened.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Role {
    /// The active scalars (`Scalars="..."` on PointData/CellData).
    Scalars,
    /// The active vectors (`Vectors="..."`).
    Vectors,
    Other,
}

/// Whether an array has its values per node or per triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
enum On {
    Nodes,
    Triangles,
}

/// One array of a piece: how the XML declares it and how its bytes are made.
struct ArraySpec {
    name: &'static str,
    kind: Kind,
    components: u32,
    role: Role,
    component_names: &'static [&'static str],
    on: On,
    /// Values per node or per triangle: the components, except for the connectivity,
    /// which VTK declares as one long list.
    per_item: usize,
    /// Writes the array's values, little-endian, into a slice of exactly their size
    /// (the piece has passed [`check_piece`]).
    fill: fn(&Piece, &mut [u8]),
}

impl ArraySpec {
    /// Bytes of the values of this array in `piece` (without the length header).
    fn value_bytes(&self, piece: &Piece) -> usize {
        let items = match self.on {
            On::Nodes => piece.nodes.len(),
            On::Triangles => piece.triangles.len(),
        };
        items * self.per_item * self.kind.size()
    }
}

/// Writes `values` one after the other into `out`, which holds exactly as many.
fn fill<const N: usize>(out: &mut [u8], values: impl Iterator<Item = [u8; N]>) {
    for (slot, v) in out.chunks_exact_mut(N).zip(values) {
        slot.copy_from_slice(&v);
    }
}

/// The single description of the arrays, read by both the pieces and the index, so that the
/// index cannot drift from what the pieces contain (ParaView refuses a mismatch).
const POINT_ARRAYS: [ArraySpec; 4] = [
    ArraySpec {
        name: "displacement",
        kind: Kind::F64,
        components: 3,
        role: Role::Vectors,
        component_names: &[],
        on: On::Nodes,
        per_item: 3,
        fill: |p, out| {
            let xyz = p.displacement.iter().flat_map(|d| [d[0], d[1], 0.0]);
            fill(out, xyz.map(f64::to_le_bytes))
        },
    },
    ArraySpec {
        name: "contact_pressure",
        kind: Kind::F64,
        components: 1,
        role: Role::Scalars,
        component_names: &[],
        on: On::Nodes,
        per_item: 1,
        fill: |p, out| fill(out, p.contact_pressure.iter().map(|v| v.to_le_bytes())),
    },
    ArraySpec {
        name: "tangential_traction",
        kind: Kind::F64,
        components: 1,
        role: Role::Other,
        component_names: &[],
        on: On::Nodes,
        per_item: 1,
        fill: |p, out| fill(out, p.tangential_traction.iter().map(|v| v.to_le_bytes())),
    },
    ArraySpec {
        name: "contact_status",
        kind: Kind::I32,
        components: 1,
        role: Role::Other,
        component_names: &[],
        on: On::Nodes,
        per_item: 1,
        fill: |p, out| fill(out, p.contact_status.iter().map(|v| v.to_le_bytes())),
    },
];

const CELL_ARRAYS: [ArraySpec; 4] = [
    ArraySpec {
        name: "stress",
        kind: Kind::F64,
        components: 4,
        role: Role::Other,
        component_names: &["xx", "yy", "xy", "zz"],
        on: On::Triangles,
        per_item: 4,
        fill: |p, out| fill(out, p.stress.iter().flatten().map(|v| v.to_le_bytes())),
    },
    ArraySpec {
        name: "von_mises",
        kind: Kind::F64,
        components: 1,
        role: Role::Scalars,
        component_names: &[],
        on: On::Triangles,
        per_item: 1,
        fill: |p, out| fill(out, p.von_mises.iter().map(|v| v.to_le_bytes())),
    },
    ArraySpec {
        name: "rank",
        kind: Kind::I32,
        components: 1,
        role: Role::Other,
        component_names: &[],
        on: On::Triangles,
        per_item: 1,
        fill: |p, out| fill(out, p.rank.iter().map(|v| v.to_le_bytes())),
    },
    ArraySpec {
        name: "body",
        kind: Kind::I32,
        components: 1,
        role: Role::Other,
        component_names: &[],
        on: On::Triangles,
        per_item: 1,
        fill: |p, out| fill(out, p.body.iter().map(|v| v.to_le_bytes())),
    },
];

/// The coordinates, with z = 0.
const POINTS: ArraySpec = ArraySpec {
    name: "Points",
    kind: Kind::F64,
    components: 3,
    role: Role::Other,
    component_names: &[],
    on: On::Nodes,
    per_item: 3,
    fill: |p, out| {
        let xyz = p.nodes.iter().flat_map(|x| [x[0], x[1], 0.0]);
        fill(out, xyz.map(f64::to_le_bytes))
    },
};

/// VTK's cell arrays: Int64 is VTK's own id type, so its reader takes the connectivity
/// and offsets as they are.
const TOPOLOGY: [ArraySpec; 3] = [
    ArraySpec {
        name: "connectivity",
        kind: Kind::I64,
        components: 1,
        role: Role::Other,
        component_names: &[],
        on: On::Triangles,
        per_item: 3,
        fill: |p, out| {
            let ids = p
                .triangles
                .iter()
                .flatten()
                .map(|&v| (v as i64).to_le_bytes());
            fill(out, ids)
        },
    },
    ArraySpec {
        name: "offsets",
        kind: Kind::I64,
        components: 1,
        role: Role::Other,
        component_names: &[],
        on: On::Triangles,
        per_item: 1,
        fill: |p, out| {
            let ends = (1..=p.triangles.len() as i64).map(|c| (3 * c).to_le_bytes());
            fill(out, ends)
        },
    },
    ArraySpec {
        name: "types",
        kind: Kind::U8,
        components: 1,
        role: Role::Other,
        component_names: &[],
        on: On::Triangles,
        per_item: 1,
        fill: |_, out| out.fill(VTK_TRIANGLE),
    },
];

/// VTK's cell type number of a linear triangle.
const VTK_TRIANGLE: u8 = 5;

/// VTK XML format version; 1.0 is the first that reads the 64-bit `header_type`.
const FILE_VERSION: (u8, u8) = (1, 0);

/// Bytes of the length header before each array in the appended block (`UInt64`).
const HEADER_BYTES: usize = 8;

/// What follows the appended block.
const TAIL: &str = "\n  </AppendedData>\n</VTKFile>\n";

/// Serialises one rank's piece as a VTK XML UnstructuredGrid (`.vtu`): a short XML head
/// that declares every array with its offset, then all values as raw little-endian bytes
/// in one `AppendedData` block.
///
/// Points get z = 0 and cells are VTK_TRIANGLE. Errors (as [`Error::Output`]) if an array
/// length does not match the node or triangle count or a triangle names a missing node:
/// writing such a file would only make ParaView fail later with a less helpful message.
pub fn vtu_bytes(piece: &Piece) -> Result<Vec<u8>> {
    check_piece(piece)?;
    let (major, minor) = FILE_VERSION;
    let mut head = String::new();
    head.push_str("<?xml version=\"1.0\"?>\n");
    head.push_str(&format!(
        "<VTKFile type=\"UnstructuredGrid\" version=\"{major}.{minor}\" \
         byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
    ));
    head.push_str("  <UnstructuredGrid>\n");
    head.push_str(&format!(
        "    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
        piece.nodes.len(),
        piece.triangles.len()
    ));
    // Each array's offset counts the bytes of those before it in the appended block,
    // which holds them in the order they are declared here.
    let mut offset = 0;
    let mut declare = |head: &mut String, spec: &ArraySpec| {
        head.push_str(&format!(
            "        <DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\"{} \
             format=\"appended\" offset=\"{offset}\"/>\n",
            spec.kind.vtk_name(),
            spec.name,
            spec.components,
            component_name_attributes(spec),
        ));
        offset += HEADER_BYTES + spec.value_bytes(piece);
    };
    for (tag, specs) in [("PointData", &POINT_ARRAYS[..]), ("CellData", &CELL_ARRAYS)] {
        head.push_str(&format!("      <{tag}{}>\n", active_arrays(specs)));
        specs.iter().for_each(|s| declare(&mut head, s));
        head.push_str(&format!("      </{tag}>\n"));
    }
    head.push_str("      <Points>\n");
    declare(&mut head, &POINTS);
    head.push_str("      </Points>\n      <Cells>\n");
    TOPOLOGY.iter().for_each(|s| declare(&mut head, s));
    head.push_str("      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n");
    // The underscore marks where the block starts: offsets count from the byte after it.
    head.push_str("  <AppendedData encoding=\"raw\">\n   _");

    // One buffer of exactly the file's size: no growth, no copy.
    let mut bytes = Vec::with_capacity(head.len() + offset + TAIL.len());
    bytes.extend_from_slice(head.as_bytes());
    for spec in file_order() {
        let len = spec.value_bytes(piece);
        bytes.extend_from_slice(&(len as u64).to_le_bytes());
        let start = bytes.len();
        bytes.resize(start + len, 0);
        (spec.fill)(piece, &mut bytes[start..]);
    }
    bytes.extend_from_slice(TAIL.as_bytes());
    Ok(bytes)
}

/// The arrays in the order of [`vtu_bytes`]'s declarations, hence of its appended block.
fn file_order() -> impl Iterator<Item = &'static ArraySpec> {
    POINT_ARRAYS
        .iter()
        .chain(&CELL_ARRAYS)
        .chain(std::iter::once(&POINTS))
        .chain(&TOPOLOGY)
}

/// Serialises the parallel index (`solution.pvtu`) that lists the per-rank pieces, e.g.
/// `solution_0.vtu`, as paths relative to the index file.
///
/// Formatted here from the same array table that [`vtu_bytes`] uses, so the two always
/// agree.
pub fn pvtu_bytes(piece_sources: &[String]) -> Result<Vec<u8>> {
    if piece_sources.is_empty() {
        return Err(Error::Output(
            "cannot write the .pvtu index: it lists no pieces".to_string(),
        ));
    }
    if piece_sources.iter().any(|s| s.is_empty()) {
        return Err(Error::Output(
            "cannot write the .pvtu index: a piece has an empty file name".to_string(),
        ));
    }
    let (major, minor) = FILE_VERSION;
    let mut x = String::new();
    x.push_str("<?xml version=\"1.0\"?>\n");
    x.push_str(&format!(
        "<VTKFile type=\"PUnstructuredGrid\" version=\"{major}.{minor}\" \
         byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
    ));
    x.push_str("  <PUnstructuredGrid GhostLevel=\"0\">\n");
    p_attribute_data(&mut x, "PPointData", &POINT_ARRAYS);
    p_attribute_data(&mut x, "PCellData", &CELL_ARRAYS);
    x.push_str(&format!(
        "    <PPoints>\n      <PDataArray type=\"{}\" NumberOfComponents=\"{}\"/>\n    </PPoints>\n",
        POINTS.kind.vtk_name(),
        POINTS.components
    ));
    for source in piece_sources {
        x.push_str(&format!(
            "    <Piece Source=\"{}\"/>\n",
            escape_attribute(source)
        ));
    }
    x.push_str("  </PUnstructuredGrid>\n</VTKFile>\n");
    Ok(x.into_bytes())
}

fn check_piece(p: &Piece) -> Result<()> {
    let n_nodes = p.nodes.len();
    let n_cells = p.triangles.len();
    let lengths = [
        ("displacement", p.displacement.len(), n_nodes, "nodes"),
        (
            "contact_pressure",
            p.contact_pressure.len(),
            n_nodes,
            "nodes",
        ),
        (
            "tangential_traction",
            p.tangential_traction.len(),
            n_nodes,
            "nodes",
        ),
        ("contact_status", p.contact_status.len(), n_nodes, "nodes"),
        ("stress", p.stress.len(), n_cells, "triangles"),
        ("von_mises", p.von_mises.len(), n_cells, "triangles"),
        ("rank", p.rank.len(), n_cells, "triangles"),
        ("body", p.body.len(), n_cells, "triangles"),
    ];
    for (name, len, want, what) in lengths {
        if len != want {
            return Err(Error::Output(format!(
                "cannot write the VTU piece: array {name} has {len} values for {want} {what}"
            )));
        }
    }
    if let Some((c, t)) = p
        .triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i >= n_nodes))
    {
        return Err(Error::Output(format!(
            "cannot write the VTU piece: triangle {c} uses nodes {t:?} but the piece has {n_nodes} nodes"
        )));
    }
    Ok(())
}

/// `ComponentName{i}="..."` attributes, which VTK readers use to label components.
fn component_name_attributes(spec: &ArraySpec) -> String {
    spec.component_names
        .iter()
        .enumerate()
        .map(|(i, n)| format!(" ComponentName{i}=\"{n}\""))
        .collect()
}

/// ` Scalars="..." Vectors="..."`: the first array of each role is the active one.
fn active_arrays(specs: &[ArraySpec]) -> String {
    [(Role::Scalars, "Scalars"), (Role::Vectors, "Vectors")]
        .iter()
        .filter_map(|&(role, attr)| {
            let s = specs.iter().find(|s| s.role == role)?;
            Some(format!(" {attr}=\"{}\"", s.name))
        })
        .collect()
}

fn p_attribute_data(x: &mut String, tag: &str, specs: &[ArraySpec]) {
    x.push_str(&format!("    <{tag}{}>\n", active_arrays(specs)));
    for s in specs {
        x.push_str(&format!(
            "      <PDataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\"{}/>\n",
            s.kind.vtk_name(),
            s.name,
            s.components,
            component_name_attributes(s)
        ));
    }
    x.push_str(&format!("    </{tag}>\n"));
}

fn escape_attribute(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles on four nodes; node 3 is off the contact boundary.
    struct Owned {
        nodes: Vec<[f64; 2]>,
        triangles: Vec<[usize; 3]>,
        displacement: Vec<[f64; 2]>,
        stress: Vec<[f64; 4]>,
        von_mises: Vec<f64>,
        rank: Vec<i32>,
        body: Vec<i32>,
        contact_pressure: Vec<f64>,
        tangential_traction: Vec<f64>,
        contact_status: Vec<i32>,
    }

    impl Owned {
        #[allow(clippy::excessive_precision)]
        fn sample(rank: i32) -> Owned {
            Owned {
                nodes: vec![
                    [0.0, 0.0],
                    [1.0, 0.0],
                    [1.0, 0.1 + 0.2],
                    [-0.0, 123456789.123456789],
                ],
                triangles: vec![[0, 1, 2], [0, 2, 3]],
                displacement: vec![
                    [1e-300, -0.0],
                    [0.1 + 0.2, -2.5],
                    [5e-324, 1.0],
                    [0.0, -1e300],
                ],
                stress: vec![[1.0, -2.0, 0.1 + 0.2, -0.0], [1e-300, 7.25, -1e10, 3.0]],
                von_mises: vec![2.6457513110645907, f64::MIN_POSITIVE],
                rank: vec![rank, rank],
                body: vec![1, 0],
                contact_pressure: vec![0.1 + 0.2, 1e-300, -0.0, 0.0],
                tangential_traction: vec![-0.5, 0.0, 1.0 / 3.0, 0.0],
                contact_status: vec![1, 2, 0, -1],
            }
        }

        fn piece(&self) -> Piece<'_> {
            Piece {
                nodes: &self.nodes,
                triangles: &self.triangles,
                displacement: &self.displacement,
                stress: &self.stress,
                von_mises: &self.von_mises,
                rank: &self.rank,
                body: &self.body,
                contact_pressure: &self.contact_pressure,
                tangential_traction: &self.tangential_traction,
                contact_status: &self.contact_status,
            }
        }
    }

    /// One `<DataArray>` of a file read back: its section, attributes and value bytes.
    struct ReadArray {
        section: String,
        attrs: Vec<(String, String)>,
        bytes: Vec<u8>,
    }

    impl ReadArray {
        fn attr(&self, key: &str) -> &str {
            attr(&self.attrs, key).unwrap_or_else(|| panic!("no {key} on {:?}", self.attrs))
        }

        fn f64_bits(&self) -> Vec<u64> {
            assert_eq!(self.attr("type"), "Float64");
            let v = self.bytes.chunks_exact(8);
            v.map(|b| u64::from_le_bytes(b.try_into().unwrap()))
                .collect()
        }

        fn i32s(&self) -> Vec<i32> {
            assert_eq!(self.attr("type"), "Int32");
            let v = self.bytes.chunks_exact(4);
            v.map(|b| i32::from_le_bytes(b.try_into().unwrap()))
                .collect()
        }

        fn i64s(&self) -> Vec<i64> {
            assert_eq!(self.attr("type"), "Int64");
            let v = self.bytes.chunks_exact(8);
            v.map(|b| i64::from_le_bytes(b.try_into().unwrap()))
                .collect()
        }
    }

    fn attr<'a>(attrs: &'a [(String, String)], key: &str) -> Option<&'a str> {
        attrs
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// A tag: its name and its attributes.
    type Tag = (String, Vec<(String, String)>);

    /// The tags of an XML text (no text content, comments or CDATA in our files), each as
    /// its name (with a leading `/` for a closing tag) and attributes, values unescaped.
    fn tags(xml: &str) -> Vec<Tag> {
        let mut out = Vec::new();
        let mut rest = xml;
        while let Some(open) = rest.find('<') {
            let close = open + rest[open..].find('>').expect("an unclosed tag");
            let body = rest[open + 1..close].trim_end_matches('/').trim();
            rest = &rest[close + 1..];
            if body.starts_with('?') {
                continue;
            }
            let (name, mut a) = body.split_once(' ').unwrap_or((body, ""));
            let mut attrs = Vec::new();
            while let Some(eq) = a.find("=\"") {
                let end = eq + 2 + a[eq + 2..].find('"').expect("an unclosed value");
                let value = a[eq + 2..end]
                    .replace("&lt;", "<")
                    .replace("&gt;", ">")
                    .replace("&quot;", "\"")
                    .replace("&apos;", "'")
                    .replace("&amp;", "&");
                attrs.push((a[..eq].trim().to_string(), value));
                a = &a[end + 1..];
            }
            out.push((name.to_string(), attrs));
        }
        out
    }

    /// A `.vtu` file read as a VTK reader does: the counts of its `Piece`, and each
    /// declared array with the bytes its offset and length header point at. Checks that the
    /// arrays fill the appended block exactly, in order.
    fn read_vtu(file: &[u8]) -> (usize, usize, Vec<ReadArray>) {
        let marker = b"<AppendedData encoding=\"raw\">";
        let at = memmem(file, marker).expect("an appended block");
        let head = std::str::from_utf8(&file[..at]).expect("the XML head is text");
        let after = &file[at + marker.len()..];
        let underscore = after.iter().position(|&b| b == b'_').unwrap();
        assert!(after[..underscore].iter().all(u8::is_ascii_whitespace));
        let block = &after[underscore + 1..];
        assert!(block.ends_with(TAIL.as_bytes()), "the file ends as VTK XML");
        let block = &block[..block.len() - TAIL.len()];

        let (mut points, mut cells) = (None, None);
        let mut section = String::new();
        let mut arrays = Vec::new();
        let mut next = 0;
        for (name, attrs) in tags(head) {
            match name.as_str() {
                "Piece" => {
                    points = attr(&attrs, "NumberOfPoints").map(|v| v.parse().unwrap());
                    cells = attr(&attrs, "NumberOfCells").map(|v| v.parse().unwrap());
                }
                "PointData" | "CellData" | "Points" | "Cells" => section = name,
                "DataArray" => {
                    assert_eq!(attr(&attrs, "format"), Some("appended"));
                    let offset: usize = attr(&attrs, "offset").unwrap().parse().unwrap();
                    assert_eq!(offset, next, "arrays are consecutive");
                    let len = u64::from_le_bytes(block[offset..offset + 8].try_into().unwrap());
                    next = offset + 8 + len as usize;
                    let bytes = block[offset + 8..next].to_vec();
                    let section = section.clone();
                    arrays.push(ReadArray {
                        section,
                        attrs,
                        bytes,
                    });
                }
                _ => {}
            }
        }
        assert_eq!(next, block.len(), "the arrays fill the appended block");
        (points.unwrap(), cells.unwrap(), arrays)
    }

    fn memmem(hay: &[u8], needle: &[u8]) -> Option<usize> {
        hay.windows(needle.len()).position(|w| w == needle)
    }

    fn array<'a>(arrays: &'a [ReadArray], section: &str, name: &str) -> &'a ReadArray {
        arrays
            .iter()
            .find(|a| a.section == section && attr(&a.attrs, "Name") == Some(name))
            .unwrap_or_else(|| panic!("array {name} missing from {section}"))
    }

    fn bits(values: impl IntoIterator<Item = f64>) -> Vec<u64> {
        values.into_iter().map(f64::to_bits).collect()
    }

    /// The head of a `.vtu` file (the text before its appended block).
    fn head_of(file: &[u8]) -> String {
        let at = memmem(file, b"<AppendedData").unwrap();
        String::from_utf8(file[..at].to_vec()).unwrap()
    }

    #[test]
    fn vtu_round_trips_exactly() {
        let o = Owned::sample(3);
        let (points, cells, a) = read_vtu(&vtu_bytes(&o.piece()).unwrap());

        assert_eq!((points, cells), (4, 2));
        let xyz = array(&a, "Points", "Points");
        assert_eq!(xyz.attr("NumberOfComponents"), "3");
        assert_eq!(
            xyz.f64_bits(),
            bits(o.nodes.iter().flat_map(|n| [n[0], n[1], 0.0]))
        );
        assert_eq!(
            array(&a, "Cells", "connectivity").i64s(),
            [0, 1, 2, 0, 2, 3]
        );
        assert_eq!(array(&a, "Cells", "offsets").i64s(), [3, 6]);
        let types = array(&a, "Cells", "types");
        assert_eq!(
            (types.attr("type"), &types.bytes[..]),
            ("UInt8", &[5u8, 5][..])
        );

        let names = |section: &str| -> Vec<&str> {
            let s = a.iter().filter(|x| x.section == section);
            s.map(|x| x.attr("Name")).collect()
        };
        assert_eq!(
            names("PointData"),
            [
                "displacement",
                "contact_pressure",
                "tangential_traction",
                "contact_status"
            ]
        );
        assert_eq!(names("CellData"), ["stress", "von_mises", "rank", "body"]);

        let d = array(&a, "PointData", "displacement");
        assert_eq!(d.attr("NumberOfComponents"), "3");
        assert_eq!(
            d.f64_bits(),
            bits(o.displacement.iter().flat_map(|u| [u[0], u[1], 0.0]))
        );
        let point = |name| array(&a, "PointData", name);
        let cell = |name| array(&a, "CellData", name);
        assert_eq!(
            point("contact_pressure").f64_bits(),
            bits(o.contact_pressure.clone())
        );
        assert_eq!(
            point("tangential_traction").f64_bits(),
            bits(o.tangential_traction.clone())
        );
        assert_eq!(point("contact_status").i32s(), o.contact_status);
        let s = cell("stress");
        assert_eq!(s.attr("NumberOfComponents"), "4");
        assert_eq!(s.f64_bits(), bits(o.stress.iter().flatten().copied()));
        assert_eq!(cell("von_mises").f64_bits(), bits(o.von_mises.clone()));
        assert_eq!(cell("rank").i32s(), vec![3, 3]);
        assert_eq!(cell("body").i32s(), vec![1, 0]);
        for x in a.iter().filter(|x| x.section.ends_with("Data")) {
            assert_eq!(
                x.attr("NumberOfComponents") == "1",
                x.attr("Name") != "stress" && x.attr("Name") != "displacement"
            );
        }
    }

    #[test]
    fn vtu_labels_stress_components_and_active_arrays() {
        let o = Owned::sample(0);
        let xml = head_of(&vtu_bytes(&o.piece()).unwrap());
        let labelled = "Name=\"stress\" NumberOfComponents=\"4\" ComponentName0=\"xx\" \
                        ComponentName1=\"yy\" ComponentName2=\"xy\" ComponentName3=\"zz\"";
        assert_eq!(xml.matches(labelled).count(), 1, "{xml}");
        assert!(xml.contains("type=\"UnstructuredGrid\""));
        assert!(xml.contains("<PointData Scalars=\"contact_pressure\" Vectors=\"displacement\">"));
        assert!(xml.contains("<CellData Scalars=\"von_mises\">"));
    }
    /// A strip of `n` triangles over 2 rows of nodes, with varied values.
    fn strip(n: usize) -> Owned {
        let m = n.div_ceil(2) + 1;
        let nodes: Vec<[f64; 2]> = (0..2 * m)
            .map(|i| [(i / 2) as f64, (i % 2) as f64])
            .collect();
        let triangles: Vec<[usize; 3]> = (0..n)
            .map(|t| {
                let k = 2 * (t / 2);
                if t % 2 == 0 {
                    [k, k + 2, k + 1]
                } else {
                    [k + 1, k + 2, k + 3]
                }
            })
            .collect();
        let value = |i: usize| (i as f64).sin() * 1e3;
        Owned {
            displacement: (0..nodes.len()).map(|i| [value(i), -value(i)]).collect(),
            contact_pressure: (0..nodes.len()).map(value).collect(),
            tangential_traction: (0..nodes.len()).map(|i| value(i + 1)).collect(),
            contact_status: (0..nodes.len()).map(|i| i as i32 % 3 - 1).collect(),
            stress: (0..n).map(|t| [value(t), 1.0, -value(t), 0.5]).collect(),
            von_mises: (0..n).map(value).collect(),
            rank: vec![7; n],
            body: (0..n).map(|t| (t % 3) as i32).collect(),
            nodes,
            triangles,
        }
    }

    #[test]
    fn the_buffer_is_taken_once_at_the_size_of_the_file() {
        for n in [0, 1, 2, 3, 1000, 30_001] {
            let o = strip(n);
            let bytes = vtu_bytes(&o.piece()).unwrap();
            assert_eq!(bytes.capacity(), bytes.len(), "{n} triangles");
            let (points, cells, a) = read_vtu(&bytes);
            assert_eq!((points, cells), (o.nodes.len(), n));
            assert_eq!(
                array(&a, "CellData", "von_mises").f64_bits(),
                bits(o.von_mises.clone())
            );
        }
    }

    #[test]
    fn empty_piece_is_written() {
        let piece = Piece {
            nodes: &[],
            triangles: &[],
            displacement: &[],
            stress: &[],
            von_mises: &[],
            rank: &[],
            body: &[],
            contact_pressure: &[],
            tangential_traction: &[],
            contact_status: &[],
        };
        let (points, cells, a) = read_vtu(&vtu_bytes(&piece).unwrap());
        assert_eq!((points, cells), (0, 0));
        assert_eq!(a.len(), 12);
        assert!(a.iter().all(|x| x.bytes.is_empty()));
    }
    #[test]
    fn even_ranges_cover_everything_in_few_equal_parts() {
        assert_eq!(even_ranges(0, 4), vec![0..0]);
        assert_eq!(even_ranges(3, 4), vec![0..3]);
        assert_eq!(even_ranges(4, 4), vec![0..4]);
        assert_eq!(even_ranges(5, 4), vec![0..2, 2..5]);
        for n in [1, 99, 100, 101, 1000, 12345] {
            let r = even_ranges(n, 100);
            assert_eq!(r.len(), n.div_ceil(100));
            assert_eq!((r[0].start, r[r.len() - 1].end), (0, n));
            for w in r.windows(2) {
                assert_eq!(w[0].end, w[1].start);
            }
            let sizes: Vec<usize> = r.iter().map(|x| x.len()).collect();
            let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
            assert!(*hi <= 100 && hi - lo <= 1, "{n}: {sizes:?}");
        }
    }

    /// A fan of triangles around node 0 plus a strip: shared nodes, so sub-pieces must
    /// renumber and repeat the nodes they share.
    fn fan_and_strip(n: usize) -> Owned {
        let mut o = Owned::sample(5);
        o.nodes = (0..n)
            .map(|i| [(i as f64).sqrt(), (i as f64 / 3.0).sin()])
            .collect();
        let mut tris: Vec<[usize; 3]> = (1..n / 2).map(|i| [0, i, i + 1]).collect();
        tris.extend((n / 2..n - 2).map(|i| [i + 2, i + 1, i]));
        let m = tris.len();
        o.triangles = tris;
        o.displacement = o.nodes.iter().map(|p| [p[1] * 1e-3, -p[0] / 7.0]).collect();
        o.stress = (0..m)
            .map(|i| [i as f64, -(i as f64), 0.1 * i as f64, 1.0 / (i + 1) as f64])
            .collect();
        o.von_mises = (0..m).map(|i| i as f64 / 3.0).collect();
        o.rank = vec![5; m];
        o.body = (0..m).map(|i| (i % 2) as i32).collect();
        o.contact_pressure = (0..n).map(|i| i as f64 / 11.0).collect();
        o.tangential_traction = (0..n).map(|i| -(i as f64) / 13.0).collect();
        o.contact_status = (0..n).map(|i| (i % 4) as i32 - 1).collect();
        o
    }

    #[test]
    fn sub_pieces_carry_each_triangle_with_its_nodes_and_values() {
        let o = fan_and_strip(500);
        let whole = o.piece();
        let mut seen = 0;
        for range in even_ranges(whole.triangles.len(), 150) {
            let sub = SubPiece::new(&whole, range.clone());
            let p = sub.piece();
            check_piece(&p).unwrap();
            // Only the nodes the triangles use, each once.
            let mut used: Vec<usize> = p.triangles.iter().flatten().copied().collect();
            used.sort_unstable();
            used.dedup();
            assert_eq!(used, (0..p.nodes.len()).collect::<Vec<_>>());
            for (t, c) in p.triangles.iter().zip(range.clone()) {
                let orig = whole.triangles[c];
                for (&v, &w) in t.iter().zip(&orig) {
                    assert_eq!(p.nodes[v], whole.nodes[w]);
                    assert_eq!(p.displacement[v], whole.displacement[w]);
                    assert_eq!(p.contact_pressure[v], whole.contact_pressure[w]);
                    assert_eq!(p.tangential_traction[v], whole.tangential_traction[w]);
                    assert_eq!(p.contact_status[v], whole.contact_status[w]);
                }
            }
            assert_eq!(p.stress, &whole.stress[range.clone()]);
            assert_eq!(p.von_mises, &whole.von_mises[range.clone()]);
            assert_eq!(p.rank, &whole.rank[range.clone()]);
            assert_eq!(p.body, &whole.body[range.clone()]);
            seen += p.triangles.len();
        }
        assert_eq!(seen, whole.triangles.len());
    }

    #[test]
    fn inconsistent_piece_is_an_output_error() {
        let mut o = Owned::sample(0);
        o.von_mises.pop();
        let err = vtu_bytes(&o.piece()).unwrap_err();
        assert!(
            matches!(&err, Error::Output(m) if m.contains("von_mises has 1 values for 2 triangles")),
            "{err:?}"
        );

        let mut o = Owned::sample(0);
        o.contact_status.push(0);
        let err = vtu_bytes(&o.piece()).unwrap_err();
        assert!(
            matches!(&err, Error::Output(m) if m.contains("contact_status has 5 values for 4 nodes")),
            "{err:?}"
        );

        let mut o = Owned::sample(0);
        o.triangles[1] = [0, 2, 4];
        let err = vtu_bytes(&o.piece()).unwrap_err();
        assert!(
            matches!(&err, Error::Output(m) if m.contains("triangle 1 uses nodes [0, 2, 4]")),
            "{err:?}"
        );
    }

    /// The index's declarations (section, attributes) and its piece sources.
    fn read_index(bytes: &[u8]) -> (Vec<Tag>, Vec<String>) {
        let xml = std::str::from_utf8(bytes).unwrap();
        let all = tags(xml);
        assert_eq!(all[0].0, "VTKFile");
        assert_eq!(attr(&all[0].1, "type"), Some("PUnstructuredGrid"));
        let mut section = String::new();
        let (mut declared, mut sources) = (Vec::new(), Vec::new());
        for (name, attrs) in all {
            match name.as_str() {
                "PPointData" | "PCellData" | "PPoints" => section = name[1..].to_string(),
                "PDataArray" => declared.push((section.clone(), attrs)),
                "Piece" => sources.push(attr(&attrs, "Source").unwrap().to_string()),
                _ => {}
            }
        }
        (declared, sources)
    }

    #[test]
    fn pvtu_declares_what_the_pieces_contain() {
        let sources: Vec<String> = (0..3).map(|r| format!("solution_{r}.vtu")).collect();
        let index = pvtu_bytes(&sources).unwrap();
        let (declared, listed) = read_index(&index);
        assert_eq!(listed, sources);
        let xml = String::from_utf8(index).unwrap();
        assert!(xml.contains("<PUnstructuredGrid GhostLevel=\"0\">"));

        let o = Owned::sample(1);
        let (_, _, arrays) = read_vtu(&vtu_bytes(&o.piece()).unwrap());
        // Every data array and the points, in order, with the same name, type, component
        // count and labels; the active arrays agree too.
        let in_piece: Vec<Tag> = arrays
            .iter()
            .filter(|a| a.section != "Cells")
            .map(|a| {
                let keep = |(k, _): &&(String, String)| k != "format" && k != "offset";
                let mut attrs: Vec<_> = a.attrs.iter().filter(keep).cloned().collect();
                if a.section == "Points" {
                    attrs.retain(|(k, _)| k != "Name");
                }
                (a.section.clone(), attrs)
            })
            .collect();
        assert_eq!(declared, in_piece);
        assert_eq!(declared.len(), 9);
        let piece_head = head_of(&vtu_bytes(&o.piece()).unwrap());
        for tag in ["PointData", "CellData"] {
            let open = |text: &str, t: &str| {
                let at = text.find(&format!("<{t}")).unwrap();
                text[at + t.len() + 1..at + text[at..].find('>').unwrap()].to_string()
            };
            assert_eq!(open(&xml, &format!("P{tag}")), open(&piece_head, tag));
        }
    }
    #[test]
    fn pvtu_labels_stress_components_like_the_pieces() {
        let xml = String::from_utf8(pvtu_bytes(&["a.vtu".to_string()]).unwrap()).unwrap();
        assert!(xml.contains(
            "Name=\"stress\" NumberOfComponents=\"4\" ComponentName0=\"xx\" \
             ComponentName1=\"yy\" ComponentName2=\"xy\" ComponentName3=\"zz\"/>"
        ));
    }

    #[test]
    fn pvtu_escapes_source_names() {
        let odd = "runs/a&b \"q\" <1>'.vtu".to_string();
        let (_, sources) = read_index(&pvtu_bytes(std::slice::from_ref(&odd)).unwrap());
        assert_eq!(sources, vec![odd]);
    }
    #[test]
    fn pvtu_without_pieces_is_an_output_error() {
        assert!(matches!(pvtu_bytes(&[]), Err(Error::Output(_))));
        assert!(matches!(
            pvtu_bytes(&["a.vtu".to_string(), String::new()]),
            Err(Error::Output(_))
        ));
    }

    #[test]
    fn written_files_load_as_one_parallel_data_set() {
        // The whole path a user takes: pieces and index on disk, opened through the index.
        let dir = tempfile::tempdir().unwrap();
        let mut sources = Vec::new();
        let mut owned = Vec::new();
        for r in 0..2 {
            let o = Owned::sample(r);
            let name = format!("solution_{r}_0.vtu");
            crate::output::write_atomic(&dir.path().join(&name), &vtu_bytes(&o.piece()).unwrap())
                .unwrap();
            sources.push(name);
            owned.push(o);
        }
        // A third rank whose piece is split in three files.
        let big = fan_and_strip(300);
        for (k, range) in even_ranges(big.triangles.len(), 100)
            .into_iter()
            .enumerate()
        {
            let name = format!("solution_2_{k}.vtu");
            let sub = SubPiece::new(&big.piece(), range);
            crate::output::write_atomic(&dir.path().join(&name), &vtu_bytes(&sub.piece()).unwrap())
                .unwrap();
            sources.push(name);
        }
        let index = dir.path().join("solution.pvtu");
        crate::output::write_atomic(&index, &pvtu_bytes(&sources).unwrap()).unwrap();

        let (_, listed) = read_index(&std::fs::read(&index).unwrap());
        assert_eq!(listed.len(), 5);
        let mut big_cells = Vec::new();
        for (r, source) in listed.iter().enumerate() {
            let (_, cells, a) = read_vtu(&std::fs::read(dir.path().join(source)).unwrap());
            if r >= 2 {
                big_cells.extend(array(&a, "CellData", "von_mises").f64_bits());
                continue;
            }
            assert_eq!(cells, 2);
            assert_eq!(array(&a, "CellData", "rank").i32s(), vec![r as i32; 2]);
            assert_eq!(array(&a, "CellData", "body").i32s(), owned[r].body);
            assert_eq!(
                array(&a, "PointData", "contact_pressure").f64_bits(),
                bits(owned[r].contact_pressure.clone())
            );
        }
        assert_eq!(big_cells, bits(big.von_mises.clone()));
    }
}
