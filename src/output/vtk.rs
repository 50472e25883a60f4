//! ParaView output: VTK XML unstructured grids (`.vtu`), one or more per rank (see
//! [`file_ranges`]), and a parallel index (`.pvtu`) that lists the pieces and declares
//! their arrays.
//!
//! Arrays written (all values are stored as Float64 or Int32, inline base64 binary, so every
//! f64 reaches ParaView bit for bit):
//!
//! | data  | name                  | type    | comps | meaning                                  |
//! |-------|-----------------------|---------|-------|------------------------------------------|
//! | point | `displacement`        | Float64 | 3     | ux, uy, 0 (3D so Warp By Vector works)   |
//! | point | `contact_pressure`    | Float64 | 1     | 0 off the contact boundary               |
//! | point | `tangential_traction` | Float64 | 1     | 0 off the contact boundary               |
//! | point | `contact_status`      | Int32   | 1     | -1 not a contact node, 0 free, 1 stick, 2 slip |
//! | cell  | `stress`              | Float64 | 4     | components named xx, yy, xy, zz          |
//! | cell  | `von_mises`           | Float64 | 1     |                                          |
//! | cell  | `rank`                | Int32   | 1     | MPI rank that owns the triangle          |

use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataArray, DataSet, ElementType, IOBuffer,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

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
/// Why: the VTU encoder copies each array through several buffers. For one large piece
/// they are all fresh memory, page-faulted in and zeroed by the kernel; the buffers of a
/// smaller file are freed and reused by the next (the output phase keeps freed blocks in
/// the heap). Measured on this machine, 600k nodes and 1.2M triangles: 1.2-2.1 s encoded
/// as one file, 0.68 s as 6 files, 0.62 s as 20.
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
            rank: &self.whole.rank[r],
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

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    F64,
    I32,
}

impl Kind {
    fn vtk_name(self) -> &'static str {
        match self {
            Kind::F64 => "Float64",
            Kind::I32 => "Int32",
        }
    }

    /// Bytes per value.
    fn size(self) -> usize {
        match self {
            Kind::F64 => 8,
            Kind::I32 => 4,
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

struct ArraySpec {
    name: &'static str,
    kind: Kind,
    components: u32,
    role: Role,
    component_names: &'static [&'static str],
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
    },
    ArraySpec {
        name: "contact_pressure",
        kind: Kind::F64,
        components: 1,
        role: Role::Scalars,
        component_names: &[],
    },
    ArraySpec {
        name: "tangential_traction",
        kind: Kind::F64,
        components: 1,
        role: Role::Other,
        component_names: &[],
    },
    ArraySpec {
        name: "contact_status",
        kind: Kind::I32,
        components: 1,
        role: Role::Other,
        component_names: &[],
    },
];

const CELL_ARRAYS: [ArraySpec; 3] = [
    ArraySpec {
        name: "stress",
        kind: Kind::F64,
        components: 4,
        role: Role::Other,
        component_names: &["xx", "yy", "xy", "zz"],
    },
    ArraySpec {
        name: "von_mises",
        kind: Kind::F64,
        components: 1,
        role: Role::Scalars,
        component_names: &[],
    },
    ArraySpec {
        name: "rank",
        kind: Kind::I32,
        components: 1,
        role: Role::Other,
        component_names: &[],
    },
];

/// vtu_bytes hands vtkio the points as f64, which it writes as Float64; the index must say so.
const POINTS_KIND: Kind = Kind::F64;

/// VTK XML format version; 1.0 is the first that reads the 64-bit `header_type` vtkio writes.
const FILE_VERSION: (u8, u8) = (1, 0);

/// Serialises one rank's piece as a VTK XML UnstructuredGrid (`.vtu`).
///
/// Points get z = 0 and cells are VTK_TRIANGLE. Errors (as [`Error::Output`]) if an array
/// length does not match the node or triangle count or a triangle names a missing node:
/// writing such a file would only make ParaView fail later with a less helpful message.
pub fn vtu_bytes(piece: &Piece) -> Result<Vec<u8>> {
    check_piece(piece)?;

    let points: Vec<f64> = piece.nodes.iter().flat_map(|p| [p[0], p[1], 0.0]).collect();
    let connectivity: Vec<u64> = piece
        .triangles
        .iter()
        .flat_map(|t| t.iter().map(|&i| i as u64))
        .collect();
    let offsets: Vec<u64> = (1..=piece.triangles.len() as u64).map(|c| 3 * c).collect();

    let point_data: [IOBuffer; 4] = [
        piece
            .displacement
            .iter()
            .flat_map(|d| [d[0], d[1], 0.0])
            .collect::<Vec<f64>>()
            .into(),
        piece.contact_pressure.to_vec().into(),
        piece.tangential_traction.to_vec().into(),
        piece.contact_status.to_vec().into(),
    ];
    let cell_data: [IOBuffer; 3] = [
        piece
            .stress
            .iter()
            .flatten()
            .copied()
            .collect::<Vec<f64>>()
            .into(),
        piece.von_mises.to_vec().into(),
        piece.rank.to_vec().into(),
    ];

    let vtk = Vtk {
        version: Version::new(FILE_VERSION),
        title: String::new(),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(UnstructuredGridPiece {
            points: points.into(),
            cells: Cells {
                cell_verts: VertexNumbers::XML {
                    connectivity,
                    offsets,
                },
                types: vec![CellType::Triangle; piece.triangles.len()],
            },
            data: Attributes {
                point: attributes(&POINT_ARRAYS, point_data),
                cell: attributes(&CELL_ARRAYS, cell_data),
            },
        }),
    };

    let mut bytes = Vec::with_capacity(encoded_len_bound(piece));
    vtk.write_xml(&mut bytes)
        .map_err(|e| Error::Output(format!("cannot encode the VTU piece: {e}")))?;
    add_component_names(&mut bytes, POINT_ARRAYS.iter().chain(&CELL_ARRAYS))?;
    Ok(bytes)
}

/// XML around the arrays of a piece (declaration, tags, attributes, component names):
/// about 2 kB, with room to spare.
const VTU_MARKUP_BOUND: usize = 16 * 1024;

/// An upper bound of the length of [`vtu_bytes`]'s output, so that its buffer is taken
/// once instead of growing by doubling through a 19 MB piece, each step a copy into fresh
/// pages. (vtkio still copies the text through its own nested buffers, which we cannot
/// size.) Every array is written as base64 of an 8-byte length header and its values.
fn encoded_len_bound(piece: &Piece) -> usize {
    let nodes = piece.nodes.len();
    let triangles = piece.triangles.len();
    let base64 = |bytes: usize| 4 * (8 + bytes).div_ceil(3);
    let point_bytes = POINT_ARRAYS
        .iter()
        .map(|s| base64(nodes * s.components as usize * s.kind.size()))
        .sum::<usize>();
    let cell_bytes = CELL_ARRAYS
        .iter()
        .map(|s| base64(triangles * s.components as usize * s.kind.size()))
        .sum::<usize>();
    // Points (3 x f64), connectivity (3 x u64), offsets (u64), types (u8).
    let mesh_bytes = base64(nodes * 24) + base64(triangles * 24) + base64(triangles * 8);
    point_bytes + cell_bytes + mesh_bytes + base64(triangles) + VTU_MARKUP_BOUND
}

/// Serialises the parallel index (`solution.pvtu`) that lists the per-rank pieces, e.g.
/// `solution_0.vtu`, as paths relative to the index file.
///
/// Written by hand: vtkio 0.6.3 can read a `.pvtu` but not write one (converting its model to
/// XML loads every referenced piece and inlines it, and the fields of its `PUnstructured`
/// XML type are private), so the few lines of the index are formatted here from the same array
/// table that [`vtu_bytes`] uses.
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
        "    <PPoints>\n      <PDataArray type=\"{}\" NumberOfComponents=\"3\"/>\n    </PPoints>\n",
        POINTS_KIND.vtk_name()
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

fn element_type(spec: &ArraySpec) -> ElementType {
    match spec.role {
        Role::Scalars => ElementType::Scalars {
            num_comp: spec.components,
            lookup_table: None,
        },
        Role::Vectors => ElementType::Vectors,
        Role::Other => ElementType::Generic(spec.components),
    }
}

fn attributes<const N: usize>(specs: &[ArraySpec; N], data: [IOBuffer; N]) -> Vec<Attribute> {
    specs
        .iter()
        .zip(data)
        .map(|(spec, data)| {
            Attribute::DataArray(DataArray {
                name: spec.name.to_string(),
                elem: element_type(spec),
                data,
            })
        })
        .collect()
}

/// `ComponentName{i}="..."` attributes, which VTK readers use to label components.
fn component_name_attributes(spec: &ArraySpec) -> String {
    spec.component_names
        .iter()
        .enumerate()
        .map(|(i, n)| format!(" ComponentName{i}=\"{n}\""))
        .collect()
}

/// vtkio's DataArray has no field for component names, so they are spliced into its output
/// right after each array's `Name` attribute. The names are ours and base64 never contains
/// a quote, so each `Name="..."` text occurs exactly once; anything else means vtkio
/// changed its output and is reported rather than guessed around. One pass over the text:
/// the buffer grows once and each stretch between two insertions moves once.
fn add_component_names<'a>(
    xml: &mut Vec<u8>,
    specs: impl Iterator<Item = &'a ArraySpec>,
) -> Result<()> {
    let mut inserts = Vec::new();
    for spec in specs.filter(|s| !s.component_names.is_empty()) {
        let needle = format!("Name=\"{}\"", spec.name);
        let mut hits = memchr::memmem::find_iter(xml, needle.as_bytes());
        match (hits.next(), hits.next()) {
            (Some(at), None) => {
                inserts.push((at + needle.len(), component_name_attributes(spec)));
            }
            _ => {
                return Err(Error::Output(format!(
                    "cannot label the components of array {}: unexpected VTU text from vtkio",
                    spec.name
                )))
            }
        }
    }
    inserts.sort_unstable_by_key(|(at, _)| *at);
    let old_len = xml.len();
    let mut shift: usize = inserts.iter().map(|(_, text)| text.len()).sum();
    xml.resize(old_len + shift, 0);
    let mut end = old_len;
    for (at, text) in inserts.iter().rev() {
        // Everything from `at` on moves past the insertions at or before `at`.
        xml.copy_within(*at..end, at + shift);
        shift -= text.len();
        xml[at + shift..at + shift + text.len()].copy_from_slice(text.as_bytes());
        end = *at;
    }
    Ok(())
}

fn p_attribute_data(x: &mut String, tag: &str, specs: &[ArraySpec]) {
    x.push_str(&format!("    <{tag}"));
    for (role, attr) in [(Role::Scalars, "Scalars"), (Role::Vectors, "Vectors")] {
        // The first array of a role is the active one, as vtkio does for the pieces.
        if let Some(s) = specs.iter().find(|s| s.role == role) {
            x.push_str(&format!(" {attr}=\"{}\"", s.name));
        }
    }
    x.push_str(">\n");
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
    use vtkio::model::{ArrayMetaData, MetaData, Piece as VtkPiece, ScalarType};

    /// Two triangles on four nodes; node 3 is off the contact boundary.
    struct Owned {
        nodes: Vec<[f64; 2]>,
        triangles: Vec<[usize; 3]>,
        displacement: Vec<[f64; 2]>,
        stress: Vec<[f64; 4]>,
        von_mises: Vec<f64>,
        rank: Vec<i32>,
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
                contact_pressure: &self.contact_pressure,
                tangential_traction: &self.tangential_traction,
                contact_status: &self.contact_status,
            }
        }
    }

    fn parse_piece(bytes: &[u8]) -> UnstructuredGridPiece {
        let vtk = Vtk::parse_xml(bytes).expect("vtkio reads the piece back");
        let DataSet::UnstructuredGrid { meta, mut pieces } = vtk.data else {
            panic!("not an unstructured grid: {:?}", vtk.data);
        };
        assert!(meta.is_none());
        assert_eq!(pieces.len(), 1);
        match pieces.remove(0) {
            VtkPiece::Inline(p) => *p,
            other => panic!("piece is not inline: {other:?}"),
        }
    }

    fn array<'a>(attrs: &'a [Attribute], name: &str) -> &'a DataArray {
        attrs
            .iter()
            .find_map(|a| match a {
                Attribute::DataArray(d) if d.name == name => Some(d),
                _ => None,
            })
            .unwrap_or_else(|| panic!("array {name} missing"))
    }

    fn f64_bits(buf: &IOBuffer) -> Vec<u64> {
        buf.iter::<f64>()
            .expect("Float64 data")
            .map(|v| v.to_bits())
            .collect()
    }

    fn bits(values: impl IntoIterator<Item = f64>) -> Vec<u64> {
        values.into_iter().map(f64::to_bits).collect()
    }

    fn i32s(buf: &IOBuffer) -> Vec<i32> {
        buf.iter::<i32>().expect("Int32 data").copied().collect()
    }

    #[test]
    fn vtu_round_trips_through_vtkio_exactly() {
        let o = Owned::sample(3);
        let p = parse_piece(&vtu_bytes(&o.piece()).unwrap());

        assert_eq!(p.num_points(), 4);
        assert_eq!(
            f64_bits(&p.points),
            bits(o.nodes.iter().flat_map(|n| [n[0], n[1], 0.0]))
        );
        assert_eq!(p.cells.num_cells(), 2);
        assert_eq!(p.cells.types, vec![CellType::Triangle; 2]);
        let (connectivity, offsets) = p.cells.cell_verts.clone().into_xml();
        assert_eq!(connectivity, vec![0, 1, 2, 0, 2, 3]);
        assert_eq!(offsets, vec![3, 6]);

        let names = |attrs: &[Attribute]| -> Vec<String> {
            attrs.iter().map(|a| a.name().to_string()).collect()
        };
        assert_eq!(
            names(&p.data.point),
            [
                "displacement",
                "contact_pressure",
                "tangential_traction",
                "contact_status"
            ]
        );
        assert_eq!(names(&p.data.cell), ["stress", "von_mises", "rank"]);

        let pt = &p.data.point;
        let d = array(pt, "displacement");
        assert_eq!(d.elem, ElementType::Vectors);
        assert_eq!(d.num_comp(), 3);
        assert_eq!(
            f64_bits(&d.data),
            bits(o.displacement.iter().flat_map(|u| [u[0], u[1], 0.0]))
        );
        let cp = array(pt, "contact_pressure");
        assert_eq!(cp.num_comp(), 1);
        assert_eq!(f64_bits(&cp.data), bits(o.contact_pressure.clone()));
        let tt = array(pt, "tangential_traction");
        assert_eq!(tt.num_comp(), 1);
        assert_eq!(f64_bits(&tt.data), bits(o.tangential_traction.clone()));
        let cs = array(pt, "contact_status");
        assert_eq!(cs.num_comp(), 1);
        assert_eq!(i32s(&cs.data), o.contact_status);

        let cl = &p.data.cell;
        let s = array(cl, "stress");
        assert_eq!(s.num_comp(), 4);
        assert_eq!(f64_bits(&s.data), bits(o.stress.iter().flatten().copied()));
        let vm = array(cl, "von_mises");
        assert_eq!(vm.num_comp(), 1);
        assert_eq!(f64_bits(&vm.data), bits(o.von_mises.clone()));
        let r = array(cl, "rank");
        assert_eq!(r.num_comp(), 1);
        assert_eq!(i32s(&r.data), vec![3, 3]);
    }

    #[test]
    fn vtu_labels_stress_components_and_active_arrays() {
        let o = Owned::sample(0);
        let xml = String::from_utf8(vtu_bytes(&o.piece()).unwrap()).unwrap();
        let labelled = "Name=\"stress\" ComponentName0=\"xx\" ComponentName1=\"yy\" \
                        ComponentName2=\"xy\" ComponentName3=\"zz\"";
        assert_eq!(xml.matches(labelled).count(), 1, "{xml}");
        assert!(xml.contains("type=\"UnstructuredGrid\""));
        assert!(xml.contains("Vectors=\"displacement\""));
        assert!(xml.contains("Scalars=\"contact_pressure\""));
        assert!(xml.contains("Scalars=\"von_mises\""));
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
            nodes,
            triangles,
        }
    }

    #[test]
    fn the_buffer_is_taken_once_and_not_much_too_large() {
        for n in [0, 1, 2, 3, 1000, 30_001] {
            let o = strip(n);
            let bound = encoded_len_bound(&o.piece());
            let len = vtu_bytes(&o.piece()).unwrap().len();
            assert!(len <= bound, "{n} triangles: {len} bytes > bound {bound}");
            assert!(
                bound <= len + VTU_MARKUP_BOUND,
                "{n} triangles: bound {bound} for {len} bytes"
            );
        }
        let o = Owned::sample(1);
        assert!(vtu_bytes(&o.piece()).unwrap().len() <= encoded_len_bound(&o.piece()));
    }

    #[test]
    fn component_names_go_after_each_name_in_one_pass() {
        let spec = |name: &'static str, component_names: &'static [&'static str]| ArraySpec {
            name,
            kind: Kind::F64,
            components: component_names.len().max(1) as u32,
            role: Role::Other,
            component_names,
        };
        let specs = [spec("c", &["r"]), spec("b", &[]), spec("a", &["p", "q"])];
        let mut xml = b"<A Name=\"a\" x=\"1\"/><B Name=\"b\"/><C Name=\"c\">QUJD</C>".to_vec();
        add_component_names(&mut xml, specs.iter()).unwrap();
        assert_eq!(
            String::from_utf8(xml).unwrap(),
            "<A Name=\"a\" ComponentName0=\"p\" ComponentName1=\"q\" x=\"1\"/>\
             <B Name=\"b\"/><C Name=\"c\" ComponentName0=\"r\">QUJD</C>"
        );

        for text in ["<A Name=\"x\"/>", "<A Name=\"a\"/><B Name=\"a\"/>"] {
            let mut xml = text.as_bytes().to_vec();
            let err = add_component_names(&mut xml, specs[2..].iter()).unwrap_err();
            assert!(err.to_string().contains("array a"), "{err}");
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
            contact_pressure: &[],
            tangential_traction: &[],
            contact_status: &[],
        };
        let p = parse_piece(&vtu_bytes(&piece).unwrap());
        assert_eq!(p.num_points(), 0);
        assert_eq!(p.cells.num_cells(), 0);
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

    fn parse_index(bytes: &[u8]) -> (MetaData, Vec<VtkPiece<UnstructuredGridPiece>>) {
        let vtk = Vtk::parse_xml(bytes).expect("vtkio reads the index back");
        let DataSet::UnstructuredGrid { meta, pieces } = vtk.data else {
            panic!("not an unstructured grid: {:?}", vtk.data);
        };
        (*meta.expect("a parallel file has metadata"), pieces)
    }

    fn declared(attrs: &[Attribute]) -> Vec<ArrayMetaData> {
        attrs
            .iter()
            .map(|a| match a {
                Attribute::DataArray(d) => ArrayMetaData {
                    name: d.name.clone(),
                    elem: d.elem.clone(),
                    scalar_type: d.data.scalar_type(),
                },
                other => panic!("unexpected field attribute {other:?}"),
            })
            .collect()
    }

    #[test]
    fn pvtu_declares_what_the_pieces_contain() {
        let sources: Vec<String> = (0..3).map(|r| format!("solution_{r}.vtu")).collect();
        let (meta, pieces) = parse_index(&pvtu_bytes(&sources).unwrap());
        assert_eq!(
            pieces,
            sources
                .iter()
                .map(|s| VtkPiece::Source(s.clone(), None))
                .collect::<Vec<_>>()
        );

        let MetaData::UnstructuredGrid {
            ghost_level,
            points_type,
            attributes,
        } = meta
        else {
            panic!("not unstructured metadata: {meta:?}");
        };
        assert_eq!(ghost_level, 0);

        let o = Owned::sample(1);
        let piece = parse_piece(&vtu_bytes(&o.piece()).unwrap());
        assert_eq!(points_type, piece.points.scalar_type());
        assert_eq!(points_type, ScalarType::F64);
        // Name, element type (hence component count and active role) and scalar type, in order.
        assert_eq!(attributes.point_data, declared(&piece.data.point));
        assert_eq!(attributes.cell_data, declared(&piece.data.cell));
        assert_eq!(attributes.point_data.len(), 4);
        assert_eq!(attributes.cell_data.len(), 3);
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
        let (_, pieces) = parse_index(&pvtu_bytes(std::slice::from_ref(&odd)).unwrap());
        assert_eq!(pieces, vec![VtkPiece::Source(odd, None)]);
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

        let mut vtk = Vtk::import(&index).expect("vtkio opens the index");
        vtk.load_all_pieces().expect("vtkio loads the pieces");
        let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
            panic!("not an unstructured grid");
        };
        assert_eq!(pieces.len(), 5);
        let mut big_cells = Vec::new();
        for (r, piece) in pieces.into_iter().enumerate() {
            let VtkPiece::Inline(p) = piece else {
                panic!("piece {r} not loaded: {piece:?}");
            };
            if r >= 2 {
                big_cells.extend(f64_bits(&array(&p.data.cell, "von_mises").data));
                continue;
            }
            assert_eq!(p.cells.num_cells(), 2);
            assert_eq!(i32s(&array(&p.data.cell, "rank").data), vec![r as i32; 2]);
            assert_eq!(
                f64_bits(&array(&p.data.point, "contact_pressure").data),
                bits(owned[r].contact_pressure.clone())
            );
        }
        assert_eq!(big_cells, bits(big.von_mises.clone()));
    }
}
