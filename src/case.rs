//! The case file: a TOML description of one contact problem, parsed, typed and validated
//! here so that every later stage can trust it. Also the built-in cases.

use crate::contact::obstacle::{Obstacle, Side};
use crate::contact::{Acceleration, CoulombMode, Friction, DEFAULT_ANDERSON_MEMORY};
use crate::error::{input, Error, Result};
use crate::fem::{Hypothesis, Material};
use serde::{Deserialize, Deserializer, Serialize};
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dirichlet {
    pub group: String,
    pub ux: Option<f64>,
    pub uy: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Traction {
    pub group: String,
    pub t: [f64; 2],
}

/// One contact: a boundary group of a body against a rigid obstacle or against a line
/// group of another body (its master), and its friction law.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    /// The slave body's candidate contact boundary (a line group).
    pub group: String,
    /// The rigid obstacle; `None` for a contact with a master line.
    pub obstacle: Option<Obstacle>,
    /// The master line group of another body (mortar coupling, `contact::mortar`).
    pub master: Option<String>,
    pub friction: Friction,
}

impl Contact {
    /// What the slave group presses on, as the case file names it.
    pub fn kind(&self) -> &'static str {
        self.obstacle.as_ref().map_or("master", Obstacle::kind)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Solver {
    /// Augmentation parameter; `None` lets the solver choose from E and h.
    pub r: Option<f64>,
    pub tol: f64,
    pub max_iter: usize,
    pub coulomb: CoulombMode,
    pub acceleration: Acceleration,
}

impl Default for Solver {
    fn default() -> Self {
        Solver {
            r: None,
            tol: 1e-8,
            max_iter: 10000,
            coulomb: CoulombMode::Inner,
            acceleration: Acceleration::Anderson {
                memory: DEFAULT_ANDERSON_MEMORY,
            },
        }
    }
}

/// Where the mesh comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum MeshSource {
    File(PathBuf),
    Builtin { name: BuiltinMesh, level: u32 },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BuiltinMesh {
    /// Quarter disc of radius `HERTZ_RADIUS` touching y = 0 at the origin.
    QuarterDisc,
    /// Rectangle `BLOCK_WIDTH` x `BLOCK_HEIGHT` on y = 0.
    Block,
    /// Two quarter cylinders meshed on their own, of radii `HERTZ_RADIUS` (above) and
    /// `LOWER_CYLINDER_RADIUS` (below, one level finer), touching at the origin.
    Cylinders,
}

/// Radius of the lower cylinder of the built-in `cylinders` case (mm).
pub const LOWER_CYLINDER_RADIUS: f64 = 90.0;

/// A validated case. Group names are checked against the mesh later, once it is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Case {
    pub title: String,
    /// Where the case came from, for messages (a file path or "built-in case NAME").
    pub origin: String,
    pub mesh: MeshSource,
    /// At least one: a lone `[material]` (no group: the whole mesh), or one per body
    /// (`[[material]]`, each on its surface group, the same plane hypothesis in all). A
    /// triangle's body is the index of its entry.
    pub materials: Vec<BodyMaterial>,
    pub dirichlet: Vec<Dirichlet>,
    pub traction: Vec<Traction>,
    pub body_force: [f64; 2],
    /// At least one; the frictional ones with the same kind of law (checked), each with
    /// its own coefficient or threshold.
    pub contacts: Vec<Contact>,
    pub solver: Solver,
}

/// The material of one body: the triangles of a physical surface group, or the whole mesh
/// (`group` None, the lone `[material]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BodyMaterial {
    pub group: Option<String>,
    pub material: Material,
}

impl Case {
    /// Each body's material, by body index.
    pub fn material_table(&self) -> Vec<Material> {
        self.materials.iter().map(|b| b.material).collect()
    }

    /// The plane hypothesis, one for the whole case (checked).
    pub fn hypothesis(&self) -> Hypothesis {
        self.materials[0].material.hypothesis
    }

    /// The friction law, the same kind on every frictional contact (the first one's
    /// value; `problem::with_friction_values` gives each node its own, zero on a
    /// frictionless contact among frictional ones).
    pub fn friction(&self) -> Friction {
        (self.contacts.iter().map(|c| c.friction))
            .find(|f| *f != Friction::None)
            .unwrap_or(Friction::None)
    }

    /// Whether some contacts have Tresca friction and others Coulomb friction.
    pub fn mixed_friction(&self) -> bool {
        let has = |tresca: bool| {
            (self.contacts.iter()).any(|c| match c.friction {
                Friction::Tresca { .. } => tresca,
                Friction::Coulomb { .. } => !tresca,
                Friction::None => false,
            })
        };
        has(true) && has(false)
    }

    /// The friction law as messages and summary.json name it: "none", "tresca",
    /// "coulomb", or "tresca+coulomb" where contacts mix them.
    pub fn friction_name(&self) -> &'static str {
        if self.mixed_friction() {
            return "tresca+coulomb";
        }
        match self.friction() {
            Friction::None => "none",
            Friction::Tresca { .. } => "tresca",
            Friction::Coulomb { .. } => "coulomb",
        }
    }
}

// ---- raw TOML schema (serde), kept private: only validated `Case`s leave this module ----

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCase {
    title: Option<String>,
    mesh: RawMesh,
    material: OneOrMany<RawMaterial>,
    #[serde(default)]
    dirichlet: Vec<RawDirichlet>,
    #[serde(default)]
    traction: Vec<RawTraction>,
    body_force: Option<RawBodyForce>,
    contact: OneOrMany<RawContact>,
    #[serde(default)]
    solver: RawSolver,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMesh {
    file: Option<String>,
    builtin: Option<String>,
    level: Option<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    group: Option<String>,
    young: f64,
    poisson: f64,
    hypothesis: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDirichlet {
    group: String,
    ux: Option<f64>,
    uy: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTraction {
    group: String,
    #[serde(deserialize_with = "pair")]
    t: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBodyForce {
    #[serde(deserialize_with = "pair")]
    f: [f64; 2],
}

/// A contact entry, either form: the single `[contact]` table of a straight foundation
/// (group, obstacle_point, obstacle_normal) or a `[[contact]]` entry (slave, obstacle).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawContact {
    group: Option<String>,
    slave: Option<String>,
    #[serde(default, deserialize_with = "opt_pair")]
    obstacle_point: Option<[f64; 2]>,
    #[serde(default, deserialize_with = "opt_pair")]
    obstacle_normal: Option<[f64; 2]>,
    obstacle: Option<RawObstacle>,
    master: Option<String>,
    friction: Option<String>,
    threshold: Option<f64>,
    coefficient: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawObstacle {
    #[serde(rename = "type")]
    kind: String,
    #[serde(default, deserialize_with = "opt_pair")]
    point: Option<[f64; 2]>,
    #[serde(default, deserialize_with = "opt_pair")]
    normal: Option<[f64; 2]>,
    #[serde(default, deserialize_with = "opt_pair")]
    centre: Option<[f64; 2]>,
    radius: Option<f64>,
    body: Option<String>,
    #[serde(default, deserialize_with = "opt_points")]
    points: Option<Vec<[f64; 2]>>,
}

/// A section written as one table (`[material]`, `[contact]`: the form of the first
/// versions, for the whole mesh or the single foundation) or as an array of tables
/// (`[[material]]` per body, `[[contact]]` per contact); the deserializer is handed on,
/// so that errors keep their place in the file.
enum OneOrMany<T> {
    One(Box<T>),
    Many(Vec<T>),
}

/// The name of a section that may come as one table or as several.
trait Section {
    const NAME: &'static str;
}

impl Section for RawMaterial {
    const NAME: &'static str = "material";
}

impl Section for RawContact {
    const NAME: &'static str = "contact";
}

impl<'de, T: Deserialize<'de> + Section> Deserialize<'de> for OneOrMany<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de> + Section> serde::de::Visitor<'de> for Visitor<T> {
            type Value = OneOrMany<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "a [{0}] table or [[{0}]] entries", T::NAME)
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                T::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    .map(|one| OneOrMany::One(Box::new(one)))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                seq: A,
            ) -> std::result::Result<Self::Value, A::Error> {
                Vec::<T>::deserialize(serde::de::value::SeqAccessDeserializer::new(seq))
                    .map(OneOrMany::Many)
            }
        }
        d.deserialize_any(Visitor(std::marker::PhantomData))
    }
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawSolver {
    r: Option<f64>,
    tol: Option<f64>,
    max_iter: Option<usize>,
    coulomb: Option<String>,
    acceleration: Option<String>,
    anderson_memory: Option<usize>,
}

/// A 2D vector `[x, y]`: exactly two numbers. Why not `[f64; 2]` directly: the TOML
/// deserializer would take the first two numbers of a longer array and drop the rest, so
/// `[0.0, 1.0, 0.0]` (a 3D habit) would pass unnoticed.
fn pair<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<[f64; 2], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    <[f64; 2]>::try_from(v.as_slice()).map_err(|_| {
        serde::de::Error::custom(format!(
            "expected [x, y], two numbers, found {} number{}",
            v.len(),
            if v.len() == 1 { "" } else { "s" }
        ))
    })
}

fn opt_pair<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Option<[f64; 2]>, D::Error> {
    pair(d).map(Some)
}

/// A list of points `[[x, y], ...]`, each exactly two numbers.
fn opt_points<'de, D: Deserializer<'de>>(
    d: D,
) -> std::result::Result<Option<Vec<[f64; 2]>>, D::Error> {
    let v = Vec::<Vec<f64>>::deserialize(d)?;
    v.iter()
        .enumerate()
        .map(|(k, p)| {
            <[f64; 2]>::try_from(p.as_slice()).map_err(|_| {
                serde::de::Error::custom(format!(
                    "point {} of the polyline: expected [x, y], two numbers, found {} number{}",
                    k + 1,
                    p.len(),
                    if p.len() == 1 { "" } else { "s" }
                ))
            })
        })
        .collect::<std::result::Result<Vec<_>, _>>()
        .map(Some)
}

/// What a required key holds, for the message when it is missing.
fn required(key: &str) -> Option<&'static str> {
    Some(match key {
        "mesh" => "[mesh] with file = \"mesh.msh\" (or builtin = \"block\")",
        "material" => "[material] with young and poisson",
        "contact" => "[[contact]] with slave and obstacle (or [contact] with group, obstacle_point and obstacle_normal)",
        "young" => "young = <Young's modulus>, e.g. young = 210000.0",
        "poisson" => "poisson = <Poisson's ratio in (-1, 0.5)>, e.g. poisson = 0.3",
        "group" => "group = \"<name of a physical group of the mesh>\"",
        "obstacle_point" => "obstacle_point = [x, y], a point of the rigid foundation",
        "obstacle_normal" => {
            "obstacle_normal = [mx, my], the unit normal from the foundation into the body"
        }
        "type" => "type = \"line\" | \"circle\" | \"polyline\" to the obstacle",
        "t" => "t = [tx, ty], the traction (force per unit length)",
        "f" => "f = [fx, fy], the body force (per unit area)",
        _ => return None,
    })
}

/// The TOML parser's message made into a fix where it is terse: a missing key says what
/// to add, a table written where an array of tables is expected says to double the
/// brackets. `header` is the table header on the line the error points at, if any.
fn explain(msg: &str, header: Option<&str>) -> String {
    const SEE: &str = "see the case-file reference in README.md";
    if let Some(key) = msg
        .strip_prefix("missing field `")
        .and_then(|m| m.strip_suffix('`'))
    {
        if let Some(what) = required(key) {
            return match (key, header) {
                ("mesh" | "material" | "contact", _) => {
                    format!("the required table [{key}] is missing; add {what} ({SEE})")
                }
                (_, Some(h)) => format!("{h} lacks the required key {key}; add {what} ({SEE})"),
                _ => format!("the required key {key} is missing; add {what} ({SEE})"),
            };
        }
    }
    if let Some(rest) = msg.strip_prefix("unknown field `") {
        // "unknown field `poison`, expected one of `group`, `young`, `poisson`, `hypothesis`"
        let mut quoted = rest.split('`').step_by(2);
        let unknown = quoted.next().unwrap_or_default();
        let best = quoted
            .filter(|k| !k.is_empty())
            .map(|k| (strsim::levenshtein(unknown, k), k))
            .min();
        if let Some((_, k)) = best.filter(|&(d, _)| d <= unknown.len().max(3) / 2 + 1) {
            return format!("{msg}; did you mean `{k}`? ({SEE})");
        }
    }
    if msg.contains("duplicate key") {
        let name = header.and_then(|h| h.strip_prefix("[[")?.strip_suffix("]]"));
        if let Some(name) = name {
            let fix = if name == "material" {
                "keep a lone [material] for the whole mesh, or [[material]] entries, one per body with its group".to_string()
            } else {
                format!("keep a lone [{name}] or [[{name}]] entries")
            };
            return format!("[{name}] and [[{name}]] are both given; {fix} ({SEE})");
        }
    }
    if msg.contains("expected a sequence") {
        if let Some(h) = header.filter(|h| !h.starts_with("[[")) {
            return format!(
                "{msg}: a block that can repeat is an array of tables, written [{h}] ({SEE})"
            );
        }
    }
    format!("{msg} ({SEE})")
}

/// 1-based line and column of a byte offset, for messages that point into the file.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, col)
}

/// Reads and validates a case file. Relative mesh paths are taken from the file's folder.
pub fn read_case(path: &Path) -> Result<Case> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        let why = if e.kind() == std::io::ErrorKind::InvalidData {
            "it is not UTF-8 text; save it as UTF-8".to_string()
        } else {
            format!("{e}; check the path")
        };
        Error::Input(format!(
            "{}: cannot read the case file: {why}",
            path.display()
        ))
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    parse_case(&text, &path.display().to_string(), dir)
}

/// Parses and validates case-file text; `origin` names it in messages, `dir` resolves the
/// relative mesh path.
pub fn parse_case(text: &str, origin: &str, dir: &Path) -> Result<Case> {
    let raw: RawCase = toml::from_str(text).map_err(|e| {
        let msg = e.message().trim().replace('\n', " ");
        match e.span() {
            Some(span) => {
                let (line, col) = line_col(text, span.start);
                let source = text.lines().nth(line - 1).unwrap_or_default();
                let source = source.split('#').next().unwrap_or_default();
                let header = Some(source.trim()).filter(|l| l.starts_with('['));
                // A bad value: name its key, which the parser's message often does not.
                let key = source
                    .find('=')
                    .filter(|&eq| col > eq + 1)
                    .map(|eq| source[..eq].trim())
                    .filter(|k| !k.is_empty() && !k.starts_with('[') && !msg.contains(*k))
                    .map_or(String::new(), |k| format!("{k}: "));
                Error::Input(format!(
                    "{origin}: line {line}, column {col}: {key}{}",
                    explain(&msg, header)
                ))
            }
            None => Error::Input(format!("{origin}: {}", explain(&msg, None))),
        }
    })?;
    // Values are quoted in messages; a multi-line string must not make them two lines.
    validate(raw, origin, dir).map_err(|e| match e {
        Error::Input(m) => Error::Input(m.replace('\n', "\\n").replace('\r', "\\r")),
        e => e,
    })
}

fn finite(origin: &str, key: &str, v: f64) -> Result<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        input(format!(
            "{origin}: {key} = {v} is not a finite number; give a real value"
        ))
    }
}

fn validate(raw: RawCase, origin: &str, dir: &Path) -> Result<Case> {
    let mesh = match (raw.mesh.file, raw.mesh.builtin) {
        (Some(file), None) => {
            if raw.mesh.level.is_some() {
                return input(format!(
                    "{origin}: [mesh] level applies to built-in meshes only; remove it or use builtin = \"block\" | \"quarter_disc\" | \"cylinders\""
                ));
            }
            MeshSource::File(dir.join(file))
        }
        (None, Some(name)) => MeshSource::Builtin {
            level: match raw.mesh.level.unwrap_or(0) {
                level if level <= MAX_LEVEL => level,
                level => {
                    return input(format!(
                        "{origin}: [mesh] level = {level} is too fine: use 0 to {MAX_LEVEL} (each level multiplies the node count by 4; quarter_disc has 4.8 M nodes at level 6)"
                    ))
                }
            },
            name: match name.as_str() {
                "block" => BuiltinMesh::Block,
                "quarter_disc" => BuiltinMesh::QuarterDisc,
                "cylinders" => BuiltinMesh::Cylinders,
                other => {
                    return input(format!(
                        "{origin}: [mesh] builtin = \"{other}\" is unknown; use \"block\", \"quarter_disc\" or \"cylinders\""
                    ))
                }
            },
        },
        (Some(_), Some(_)) => {
            return input(format!(
                "{origin}: [mesh] has both file and builtin; keep one of them"
            ))
        }
        (None, None) => {
            return input(format!(
                "{origin}: [mesh] needs file = \"mesh.msh\" (or builtin = \"block\" | \"quarter_disc\" | \"cylinders\")"
            ))
        }
    };

    let materials = validate_materials(raw.material, origin)?;

    let mut dirichlet = Vec::new();
    for d in raw.dirichlet {
        if d.ux.is_none() && d.uy.is_none() {
            return input(format!(
                "{origin}: [[dirichlet]] on group \"{}\" sets neither ux nor uy; give at least one",
                d.group
            ));
        }
        let ux =
            d.ux.map(|v| {
                finite(
                    origin,
                    &format!("[[dirichlet]] group \"{}\": ux", d.group),
                    v,
                )
            })
            .transpose()?;
        let uy =
            d.uy.map(|v| {
                finite(
                    origin,
                    &format!("[[dirichlet]] group \"{}\": uy", d.group),
                    v,
                )
            })
            .transpose()?;
        dirichlet.push(Dirichlet {
            group: d.group,
            ux,
            uy,
        });
    }
    let mut traction = Vec::new();
    for t in raw.traction {
        for v in t.t {
            finite(origin, &format!("[[traction]] group \"{}\": t", t.group), v)?;
        }
        traction.push(Traction {
            group: t.group,
            t: t.t,
        });
    }
    let body_force = raw.body_force.map_or([0.0; 2], |b| b.f);
    for v in body_force {
        finite(origin, "body_force.f", v)?;
    }

    let contacts = validate_contacts(raw.contact, origin)?;

    let mut solver = Solver::default();
    let s = raw.solver;
    let key = |k: &str| format!("{origin}: solver.{k}");
    if let Some(r) = s.r {
        solver.r = Some(check_r(&key("r"), r)?);
    }
    if let Some(tol) = s.tol {
        solver.tol = check_tol(&key("tol"), tol)?;
    }
    if let Some(max_iter) = s.max_iter {
        solver.max_iter = check_max_iter(&key("max_iter"), max_iter)?;
    }
    if let Some(mode) = s.coulomb {
        solver.coulomb = parse_coulomb_mode(&mode).ok_or_else(|| {
            Error::Input(format!(
                "{origin}: solver.coulomb = \"{mode}\" is unknown; use \"inner\" or \"outer\""
            ))
        })?;
    }
    if let Some(acc) = s.acceleration.as_deref() {
        solver.acceleration = parse_acceleration(acc, s.anderson_memory.unwrap_or(DEFAULT_ANDERSON_MEMORY)).ok_or_else(|| {
            Error::Input(format!("{origin}: solver.acceleration = \"{acc}\" is unknown; use \"anderson\" or \"none\""))
        })?;
    }
    if let Some(m) = s.anderson_memory {
        if !(1..=50).contains(&m) {
            return input(format!(
                "{origin}: solver.anderson_memory = {m} must lie in 1..=50 (20 is a good value)"
            ));
        }
        if let Acceleration::Anderson { memory } = &mut solver.acceleration {
            *memory = m;
        }
    }

    Ok(Case {
        title: raw.title.unwrap_or_default(),
        origin: origin.to_string(),
        mesh,
        materials,
        dirichlet,
        traction,
        body_force,
        contacts,
        solver,
    })
}

/// The contact entries, each mapped onto a [`Contact`]; `[contact]` (one straight
/// foundation) is the line obstacle of one entry.
fn validate_contacts(raw: OneOrMany<RawContact>, origin: &str) -> Result<Vec<Contact>> {
    let (entries, single_table) = match raw {
        OneOrMany::One(c) => (vec![*c], true),
        OneOrMany::Many(v) => (v, false),
    };
    if entries.is_empty() {
        return input(format!(
            "{origin}: contact is an empty list; add a [[contact]] with slave and obstacle (see the case-file reference in README.md)"
        ));
    }
    let several = entries.len() > 1;
    let mut contacts = Vec::with_capacity(entries.len());
    for (i, c) in entries.into_iter().enumerate() {
        // How messages name the entry and its keys.
        let key = if several {
            format!("contact #{}", i + 1)
        } else {
            "contact".to_string()
        };
        let table = if single_table {
            "[contact]"
        } else {
            "[[contact]]"
        };
        let lacks = |k: &str| -> Error {
            let what = required(k).unwrap_or_default();
            Error::Input(format!(
                "{origin}: {table}{} lacks the required key {k}; add {what} (see the case-file reference in README.md)",
                if several { format!(" #{}", i + 1) } else { String::new() }
            ))
        };
        let (group, obstacle) = if c.obstacle.is_some() || c.slave.is_some() || c.master.is_some() {
            for (k, given) in [
                ("group", c.group.is_some()),
                ("obstacle_point", c.obstacle_point.is_some()),
                ("obstacle_normal", c.obstacle_normal.is_some()),
            ] {
                if given {
                    return input(format!(
                        "{origin}: {key}.{k} belongs to the single-foundation form (group, obstacle_point, obstacle_normal); with slave and obstacle, remove it (a straight foundation is obstacle = {{ type = \"line\", point = [x, y], normal = [mx, my] }})"
                    ));
                }
            }
            let slave = c.slave.ok_or_else(|| lacks("slave"))?;
            match (c.obstacle, &c.master) {
                (Some(_), Some(_)) => {
                    return input(format!(
                        "{origin}: {key} has both obstacle and master; a contact presses its slave on one of them: keep obstacle for a rigid one, master = \"<line group of the other body>\" for an elastic one"
                    ))
                }
                (None, None) => return Err(lacks("obstacle")),
                (None, Some(m)) if *m == slave => {
                    return input(format!(
                        "{origin}: {key} has master = slave = \"{slave}\"; the master must be a line group of the other body"
                    ))
                }
                (None, Some(_)) => (slave, None),
                (Some(o), None) => (slave, Some(validate_obstacle(o, origin, &key)?)),
            }
        } else {
            let group = c.group.ok_or_else(|| lacks("group"))?;
            let point = c.obstacle_point.ok_or_else(|| lacks("obstacle_point"))?;
            let normal = c.obstacle_normal.ok_or_else(|| lacks("obstacle_normal"))?;
            let point = finite_pair(origin, &format!("{key}.obstacle_point"), point)?;
            let normal = unit_normal(origin, &format!("{key}.obstacle_normal"), normal)?;
            (group, Some(Obstacle::Line { point, normal }))
        };
        let friction = validate_friction(&c.friction, c.threshold, c.coefficient, origin, &key)?;
        contacts.push(Contact {
            group,
            obstacle,
            master: c.master,
            friction,
        });
    }
    if let Some((i, c)) = (contacts.iter().enumerate())
        .find(|(i, c)| contacts[..*i].iter().any(|d| d.group == c.group))
    {
        return input(format!(
            "{origin}: contact #{} names slave = \"{}\" again; each boundary group can be in one contact only: merge the obstacles into one polyline or give the nodes different groups",
            i + 1,
            c.group
        ));
    }
    Ok(contacts)
}

fn finite_pair(origin: &str, key: &str, v: [f64; 2]) -> Result<[f64; 2]> {
    for x in v {
        finite(origin, key, x)?;
    }
    Ok(v)
}

fn unit_normal(origin: &str, key: &str, v: [f64; 2]) -> Result<[f64; 2]> {
    let [mx, my] = finite_pair(origin, key, v)?;
    let norm = mx.hypot(my);
    if norm == 0.0 {
        return input(format!(
            "{origin}: {key} is zero; give the unit normal pointing from the foundation into the body, e.g. [0.0, 1.0]"
        ));
    }
    if (norm - 1.0).abs() > 1e-6 {
        return input(format!(
            "{origin}: {key} has length {norm}, not 1; use [{}, {}]",
            mx / norm,
            my / norm
        ));
    }
    Ok([mx, my])
}

/// The obstacle of a `[[contact]]` entry; `key` names the entry in messages.
fn validate_obstacle(o: RawObstacle, origin: &str, key: &str) -> Result<Obstacle> {
    let key = format!("{key}.obstacle");
    let takes: &[&str] = match o.kind.as_str() {
        "line" => &["point", "normal"],
        "circle" => &["centre", "radius", "body"],
        "polyline" => &["points", "body"],
        other => {
            return input(format!(
                "{origin}: {key}.type = \"{other}\" is unknown; use \"line\", \"circle\" or \"polyline\""
            ))
        }
    };
    let given = [
        ("point", o.point.is_some()),
        ("normal", o.normal.is_some()),
        ("centre", o.centre.is_some()),
        ("radius", o.radius.is_some()),
        ("body", o.body.is_some()),
        ("points", o.points.is_some()),
    ];
    if let Some((k, _)) = given.iter().find(|(k, g)| *g && !takes.contains(k)) {
        return input(format!(
            "{origin}: {key}.{k} does not apply to type = \"{}\", which takes {}; remove {k}",
            o.kind,
            takes.join(", ")
        ));
    }
    let need = |k: &str, what: &str| {
        Error::Input(format!(
            "{origin}: {key} of type = \"{}\" needs {k} = {what}",
            o.kind
        ))
    };
    Ok(match o.kind.as_str() {
        "line" => {
            let point = o
                .point
                .ok_or_else(|| need("point", "[x, y], a point of the line"))?;
            let normal = o.normal.ok_or_else(|| {
                need(
                    "normal",
                    "[mx, my], the unit normal from the line into the body",
                )
            })?;
            Obstacle::Line {
                point: finite_pair(origin, &format!("{key}.point"), point)?,
                normal: unit_normal(origin, &format!("{key}.normal"), normal)?,
            }
        }
        "circle" => {
            let centre = o.centre.ok_or_else(|| need("centre", "[x, y]"))?;
            let centre = finite_pair(origin, &format!("{key}.centre"), centre)?;
            let radius = o
                .radius
                .ok_or_else(|| need("radius", "<the circle's radius>"))?;
            let radius = finite(origin, &format!("{key}.radius"), radius)?;
            if radius <= 0.0 {
                return input(format!(
                    "{origin}: {key}.radius = {radius} must be positive; give the circle's radius"
                ));
            }
            let body = match o.body.as_deref().unwrap_or("outside") {
                "outside" => Side::Outside,
                "inside" => Side::Inside,
                other => {
                    return input(format!(
                        "{origin}: {key}.body = \"{other}\" is unknown for a circle; use \"outside\" (the body outside the rigid disc) or \"inside\" (the body in the rigid hole)"
                    ))
                }
            };
            Obstacle::Circle {
                centre,
                radius,
                body,
            }
        }
        _ => {
            let mut points = o
                .points
                .ok_or_else(|| need("points", "[[x0, y0], [x1, y1], ...]"))?;
            for p in &points {
                finite_pair(origin, &format!("{key}.points"), *p)?;
            }
            if points.len() < 2 {
                return input(format!(
                    "{origin}: {key}.points has {} point(s); a polyline needs at least 2 distinct points",
                    points.len()
                ));
            }
            for (k, p) in points.iter().enumerate() {
                if let Some(j) = points[..k].iter().position(|q| q == p) {
                    return input(format!(
                        "{origin}: {key}.points repeats the point [{}, {}] (points {} and {}); remove the repetition: every point of a polyline must be distinct",
                        p[0],
                        p[1],
                        j + 1,
                        k + 1
                    ));
                }
            }
            if let Some(k) = (1..points.len()).find(|&k| {
                let len = (points[k][0] - points[k - 1][0]).hypot(points[k][1] - points[k - 1][1]);
                !(len.is_finite() && len > 0.0)
            }) {
                return input(format!(
                    "{origin}: {key}.points: the segment from point {k} to point {} has no finite length; give points of the scale of the mesh",
                    k + 1
                ));
            }
            match o.body.as_deref().unwrap_or("left") {
                "left" => {}
                // The kernel keeps the body on the left: walk the other way.
                "right" => points.reverse(),
                other => {
                    return input(format!(
                        "{origin}: {key}.body = \"{other}\" is unknown for a polyline; use \"left\" or \"right\" (the body's side, walking from the first point to the last)"
                    ))
                }
            }
            Obstacle::Polyline { points }
        }
    })
}

/// The friction law of one contact entry; `key` names the entry in messages.
fn validate_friction(
    law: &Option<String>,
    threshold: Option<f64>,
    coefficient: Option<f64>,
    origin: &str,
    key: &str,
) -> Result<Friction> {
    // A threshold or coefficient under another law would be ignored: most likely the
    // friction line was forgotten, and the run would silently be frictionless.
    let law = law.as_deref().unwrap_or("none");
    for (k, given, needs) in [
        ("threshold", threshold.is_some(), "tresca"),
        ("coefficient", coefficient.is_some(), "coulomb"),
    ] {
        if given && law != needs && matches!(law, "none" | "tresca" | "coulomb") {
            return input(format!(
                "{origin}: {key}.{k} applies to friction = \"{needs}\" only, but friction = \"{law}\"; set friction = \"{needs}\" or remove {k}"
            ));
        }
    }
    Ok(match law {
        "none" => Friction::None,
        "tresca" => {
            let threshold = threshold.ok_or_else(|| {
                Error::Input(format!(
                    "{origin}: {key}.friction = \"tresca\" needs {key}.threshold (slip threshold, force per unit length)"
                ))
            })?;
            let threshold = finite(origin, &format!("{key}.threshold"), threshold)?;
            if threshold < 0.0 {
                return input(format!(
                    "{origin}: {key}.threshold = {threshold} must be >= 0"
                ));
            }
            Friction::Tresca { threshold }
        }
        "coulomb" => {
            let coefficient = coefficient.ok_or_else(|| {
                Error::Input(format!(
                    "{origin}: {key}.friction = \"coulomb\" needs {key}.coefficient (friction coefficient)"
                ))
            })?;
            let coefficient = finite(origin, &format!("{key}.coefficient"), coefficient)?;
            if coefficient < 0.0 {
                return input(format!(
                    "{origin}: {key}.coefficient = {coefficient} must be >= 0"
                ));
            }
            Friction::Coulomb { coefficient }
        }
        other => {
            return input(format!(
                "{origin}: {key}.friction = \"{other}\" is unknown; use \"none\", \"tresca\" or \"coulomb\""
            ))
        }
    })
}

/// The bodies' materials: a lone `[material]` (no group) or `[[material]]` entries, each
/// on its own group, all with the same plane hypothesis. Whether the groups exist and
/// cover every triangle once is checked with the mesh (`problem::build`).
fn validate_materials(raw: OneOrMany<RawMaterial>, origin: &str) -> Result<Vec<BodyMaterial>> {
    let (entries, many) = match raw {
        OneOrMany::One(m) => {
            if let Some(g) = &m.group {
                return input(format!(
                    "{origin}: [material] has group = \"{g}\" but a lone [material] covers the whole mesh; write one [[material]] per body (double brackets), each with its group"
                ));
            }
            (vec![*m], false)
        }
        OneOrMany::Many(v) => (v, true),
    };
    let mut out: Vec<BodyMaterial> = Vec::with_capacity(entries.len());
    for (i, m) in entries.into_iter().enumerate() {
        let key = if many {
            format!("material[{}]", i + 1)
        } else {
            "material".to_string()
        };
        if many && m.group.is_none() {
            return input(format!(
                "{origin}: [[material]] entry {} lacks group; give each body's surface group, group = \"<name>\" (or write a lone [material] for the whole mesh)",
                i + 1
            ));
        }
        if let Some(g) = &m.group {
            if out.iter().any(|b| b.group.as_ref() == Some(g)) {
                return input(format!(
                    "{origin}: [[material]] group \"{g}\" is listed twice; give each body one entry"
                ));
            }
        }
        let young = finite(origin, &format!("{key}.young"), m.young)?;
        let poisson = finite(origin, &format!("{key}.poisson"), m.poisson)?;
        if young <= 0.0 {
            return input(format!(
                "{origin}: {key}.young = {young} must be positive (Young's modulus)"
            ));
        }
        if !(poisson > -1.0 && poisson < 0.5) {
            return input(format!(
                "{origin}: {key}.poisson = {poisson} must lie in (-1, 0.5) (0.5 is incompressible, which P1 elements cannot represent)"
            ));
        }
        let hypothesis = match m.hypothesis.as_deref().unwrap_or("plane_strain") {
            "plane_strain" => Hypothesis::PlaneStrain,
            "plane_stress" => Hypothesis::PlaneStress,
            other => {
                return input(format!(
                    "{origin}: {key}.hypothesis = \"{other}\" is unknown; use \"plane_strain\" or \"plane_stress\""
                ))
            }
        };
        if let Some(first) = out.first() {
            if first.material.hypothesis != hypothesis {
                return input(format!(
                    "{origin}: {key}.hypothesis differs from material[1]'s; the plane hypothesis is one for the whole model: give every [[material]] the same hypothesis"
                ));
            }
        }
        out.push(BodyMaterial {
            group: m.group,
            material: Material {
                young,
                poisson,
                hypothesis,
            },
        });
    }
    Ok(out)
}

pub fn parse_acceleration(s: &str, memory: usize) -> Option<Acceleration> {
    match s {
        "none" => Some(Acceleration::None),
        "anderson" => Some(Acceleration::Anderson { memory }),
        _ => None,
    }
}

// The [solver] values, checked alike in the case file and on the command line; `key` names
// the value and where it was given ("case.toml: solver.r" or "command line: --r").

fn check_r(key: &str, r: f64) -> Result<f64> {
    if r.is_finite() && r > 0.0 {
        Ok(r)
    } else {
        input(format!(
            "{key} = {r} must be a positive number (or leave it out for the automatic choice)"
        ))
    }
}

fn check_tol(key: &str, tol: f64) -> Result<f64> {
    if tol.is_finite() && tol > 0.0 && tol < 1.0 {
        Ok(tol)
    } else {
        input(format!("{key} = {tol} must lie in (0, 1), e.g. 1e-8"))
    }
}

fn check_max_iter(key: &str, max_iter: usize) -> Result<usize> {
    if max_iter >= 1 {
        Ok(max_iter)
    } else {
        input(format!("{key} = 0: it must be at least 1"))
    }
}

/// Applies the command-line overrides of `[solver]` (`--r`, `--tol`, `--max-iter`,
/// `--coulomb`) to a validated case, with the checks of the case file: an override must
/// not let in what the file would refuse (a negative or NaN r, a zero budget).
pub fn override_solver(
    case: &mut Case,
    r: Option<f64>,
    tol: Option<f64>,
    max_iter: Option<usize>,
    coulomb: Option<CoulombMode>,
) -> Result<()> {
    if let Some(r) = r {
        case.solver.r = Some(check_r("command line: --r", r)?);
    }
    if let Some(tol) = tol {
        case.solver.tol = check_tol("command line: --tol", tol)?;
    }
    if let Some(max_iter) = max_iter {
        case.solver.max_iter = check_max_iter("command line: --max-iter", max_iter)?;
    }
    if let Some(mode) = coulomb {
        case.solver.coulomb = mode;
    }
    Ok(())
}

pub fn parse_coulomb_mode(s: &str) -> Option<CoulombMode> {
    match s {
        "inner" => Some(CoulombMode::Inner),
        "outer" => Some(CoulombMode::Outer),
        _ => None,
    }
}

// ---- built-in cases ----

/// Finest refinement level of the built-in meshes: level 8 is about 80 M nodes, far past
/// the machine; the cap keeps a typo such as `level = 40` from overflowing the cell counts.
pub const MAX_LEVEL: u32 = 8;

/// Radius of the built-in quarter disc (mm).
pub const HERTZ_RADIUS: f64 = 50.0;
/// Built-in block size (mm).
pub const BLOCK_WIDTH: f64 = 40.0;
pub const BLOCK_HEIGHT: f64 = 10.0;

/// Names of the built-in cases, the first being the default.
pub const BUILTIN_CASES: [&str; 5] = ["hertz", "block", "block_flat", "punch", "cylinders"];

/// Radius of the built-in punch (mm).
pub const PUNCH_RADIUS: f64 = 100.0;

/// The TOML text of a built-in case, so users can print it and start from it.
pub fn builtin_case_text(name: &str, level: u32) -> Option<String> {
    let text = match name {
        // Steel quarter cylinder (mm, N, MPa) pressed on a rigid plane by a rigid
        // frictionless platen: a/R is about 0.1, where the Hertz formula holds.
        "hertz" => format!(
            r#"title = "Hertz line contact: quarter cylinder on a rigid plane (symmetry at x = 0)"
[mesh]
builtin = "quarter_disc"   # radius {HERTZ_RADIUS} mm, centre (0, {HERTZ_RADIUS})
level = {level}
[material]
young = 210000.0           # MPa
poisson = 0.3
hypothesis = "plane_strain"
[[dirichlet]]              # symmetry
group = "axis"
ux = 0.0
[[dirichlet]]              # rigid frictionless platen pushed down
group = "top"
uy = -0.4
[contact]
group = "contact"
obstacle_point = [0.0, 0.0]
obstacle_normal = [0.0, 1.0]
friction = "none"
"#
        ),
        // Aluminium block squeezed and sheared by its clamped top: partial slip.
        "block" => format!(
            r#"title = "Block on a rigid plane, compressed and sheared by its top, Coulomb friction"
[mesh]
builtin = "block"          # {BLOCK_WIDTH} x {BLOCK_HEIGHT} mm
level = {level}
[material]
young = 70000.0            # MPa
poisson = 0.33
hypothesis = "plane_strain"
[[dirichlet]]
group = "top"
ux = 0.01
uy = -0.02
[contact]
group = "bottom"
obstacle_point = [0.0, 0.0]
obstacle_normal = [0.0, 1.0]
friction = "coulomb"
coefficient = 0.3
"#
        ),
        // nu = 0 and a uniform pressure on top: the exact solution is a uniform
        // contact pressure equal to the applied one (a patch test for contact).
        "block_flat" => format!(
            r#"title = "Block pressed flat, nu = 0: uniform contact pressure equal to the applied pressure"
[mesh]
builtin = "block"
level = {level}
[material]
young = 70000.0
poisson = 0.0
hypothesis = "plane_strain"
[[traction]]
group = "top"
t = [0.0, -50.0]           # MPa
[[dirichlet]]              # only to remove the horizontal rigid motion
group = "bottom_left"
ux = 0.0
[contact]
group = "bottom"
obstacle_point = [0.0, -0.001]
obstacle_normal = [0.0, 1.0]
friction = "none"
"#
        ),
        // A rigid cylindrical punch over the middle of the block's top, pressed in and
        // dragged along it: the block's base is moved instead (down-right of the punch
        // is up-left of the block), so the obstacle stays where it is. Coulomb friction:
        // a sticking centre and slipping edges.
        "punch" => format!(
            r#"title = "Rigid circular punch pressed into a block and dragged along it, Coulomb friction"
[mesh]
builtin = "block"          # {BLOCK_WIDTH} x {BLOCK_HEIGHT} mm
level = {level}
[material]
young = 70000.0            # MPa
poisson = 0.33
hypothesis = "plane_strain"
[[dirichlet]]              # the base moved: the punch pressed in by 0.05 mm, dragged by 0.01 mm along +x
group = "bottom"
ux = -0.01
uy = 0.05
[[contact]]
slave = "top"
obstacle = {{ type = "circle", centre = [{cx:?}, {cy:?}], radius = {PUNCH_RADIUS:?}, body = "outside" }}
friction = "coulomb"
coefficient = 0.3
"#,
            cx = BLOCK_WIDTH / 2.0,
            cy = BLOCK_HEIGHT + PUNCH_RADIUS,
        ),
        // Two elastic cylinders in line contact (Hertz), steel on aluminium, each
        // meshed on its own: the upper one pressed down by a rigid frictionless platen,
        // the lower one on a rigid base; symmetry at x = 0.
        "cylinders" => format!(
            r#"title = "Hertz line contact of two elastic cylinders, steel on aluminium (symmetry at x = 0)"
[mesh]
builtin = "cylinders"      # radii {HERTZ_RADIUS} (upper, centre (0, {HERTZ_RADIUS})) and {LOWER_CYLINDER_RADIUS} mm (lower, centre (0, -{LOWER_CYLINDER_RADIUS}), one level finer)
level = {level}
[[material]]
group = "upper"
young = 210000.0           # MPa, steel
poisson = 0.3
[[material]]
group = "lower"
young = 70000.0            # MPa, aluminium
poisson = 0.33
[[dirichlet]]              # symmetry
group = "upper_axis"
ux = 0.0
[[dirichlet]]
group = "lower_axis"
ux = 0.0
[[dirichlet]]              # rigid frictionless platen pushed down
group = "upper_top"
uy = -0.4
[[dirichlet]]              # rigid base
group = "lower_bottom"
uy = 0.0
[[contact]]
slave = "upper_contact"    # the finer side
master = "lower_contact"
friction = "none"
"#
        ),
        _ => return None,
    };
    Some(text)
}

/// A built-in case, validated like a file.
pub fn builtin_case(name: &str, level: u32) -> Result<Case> {
    let text = builtin_case_text(name, level).ok_or_else(|| {
        Error::Input(format!(
            "unknown built-in case \"{name}\"; choose one of {}",
            BUILTIN_CASES.join(", ")
        ))
    })?;
    parse_case(&text, &format!("built-in case {name}"), Path::new("."))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
title = "t"
[mesh]
file = "m.msh"
[material]
young = 200.0
poisson = 0.3
[[dirichlet]]
group = "top"
uy = -0.01
[[traction]]
group = "right"
t = [-15.0, 0.0]
[contact]
group = "bottom"
obstacle_point = [0.0, -0.001]
obstacle_normal = [0.0, 1.0]
friction = "coulomb"
coefficient = 0.3
[solver]
r = 1.0e4
tol = 1e-9
max_iter = 50
"#;

    fn parse(text: &str) -> Result<Case> {
        parse_case(text, "case.toml", Path::new("dir"))
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    /// GOOD with its [material] replaced by `materials`.
    fn with_materials(materials: &str) -> String {
        GOOD.replace("[material]\nyoung = 200.0\npoisson = 0.3\n", materials)
    }

    #[test]
    fn one_material_per_body_is_typed_in_order() {
        let c = parse(&with_materials(
            "[[material]]\ngroup = \"upper\"\nyoung = 3.0\npoisson = 0.1\nhypothesis = \"plane_stress\"\n[[material]]\ngroup = \"lower\"\nyoung = 5.0\npoisson = 0.2\nhypothesis = \"plane_stress\"\n",
        ))
        .unwrap();
        let groups: Vec<_> = c.materials.iter().map(|b| b.group.as_deref()).collect();
        assert_eq!(groups, [Some("upper"), Some("lower")]);
        let table = c.material_table();
        assert_eq!(
            table.iter().map(|m| m.young).collect::<Vec<_>>(),
            [3.0, 5.0]
        );
        assert_eq!(table[1].poisson, 0.2);
        assert_eq!(c.hypothesis(), Hypothesis::PlaneStress);
        // The lone table is one body on the whole mesh.
        let lone = parse(GOOD).unwrap();
        assert_eq!(lone.materials.len(), 1);
        assert_eq!(lone.materials[0].group, None);
        assert_eq!(lone.materials[0].material.young, 200.0);
    }

    #[test]
    fn materials_are_refused_with_their_fix() {
        let entry = |g: &str, h: &str| {
            format!(
                "[[material]]\ngroup = \"{g}\"\nyoung = 1.0\npoisson = 0.3\nhypothesis = \"{h}\"\n"
            )
        };
        let e = err(&with_materials(
            &(entry("a", "plane_strain") + &entry("a", "plane_strain")),
        ));
        assert!(e.contains("group \"a\" is listed twice"), "{e}");
        let e = err(&with_materials(
            &(entry("a", "plane_strain") + &entry("b", "plane_stress")),
        ));
        assert!(e.contains("material[2].hypothesis differs"), "{e}");
        let e = err(&with_materials(
            "[[material]]\nyoung = 1.0\npoisson = 0.3\n",
        ));
        assert!(e.contains("entry 1 lacks group"), "{e}");
        let e = err(&with_materials(
            "[material]\ngroup = \"a\"\nyoung = 1.0\npoisson = 0.3\n",
        ));
        assert!(e.contains("a lone [material] covers the whole mesh"), "{e}");
        let both =
            "[material]\nyoung = 1.0\npoisson = 0.3\n".to_string() + &entry("a", "plane_strain");
        let e = err(&with_materials(&both));
        assert!(
            e.contains("[material] and [[material]] are both given"),
            "{e}"
        );
        let e = err(&with_materials(
            &(entry("a", "plane_strain") + "young = -1.0\n"),
        ));
        assert!(e.starts_with("case.toml: "), "{e}");
        let bad = entry("a", "plane_strain").replace("young = 1.0", "young = -1.0");
        let e = err(&with_materials(&(entry("b", "plane_strain") + &bad)));
        assert!(e.contains("material[2].young = -1 must be positive"), "{e}");
    }

    #[test]
    fn good_case_is_typed() {
        let c = parse(GOOD).unwrap();
        assert_eq!(c.mesh, MeshSource::File(Path::new("dir").join("m.msh")));
        assert_eq!(c.hypothesis(), Hypothesis::PlaneStrain);
        assert_eq!(c.materials.len(), 1);
        assert_eq!(c.materials[0].group, None);
        assert_eq!(c.dirichlet[0].ux, None);
        assert_eq!(c.dirichlet[0].uy, Some(-0.01));
        assert_eq!(c.friction(), Friction::Coulomb { coefficient: 0.3 });
        assert_eq!(c.solver.r, Some(1.0e4));
        assert_eq!(c.solver.max_iter, 50);
        assert_eq!(c.solver.coulomb, CoulombMode::Inner);
    }

    #[test]
    fn unknown_key_is_named_with_its_line() {
        let e = err(&GOOD.replace("poisson = 0.3", "poison = 0.3"));
        assert!(e.contains("poison"), "{e}");
        assert!(e.contains("line 7"), "{e}");
        assert!(!e.contains('\n'));
    }

    #[test]
    fn missing_key_is_named() {
        let e = err(&GOOD.replace("young = 200.0\n", ""));
        assert!(e.contains("young"), "{e}");
    }

    #[test]
    fn bad_values_are_rejected_with_a_fix() {
        assert!(err(&GOOD.replace("young = 200.0", "young = -1.0")).contains("positive"));
        assert!(err(&GOOD.replace("poisson = 0.3", "poisson = 0.5")).contains("(-1, 0.5)"));
        assert!(err(&GOOD.replace("[0.0, 1.0]", "[1.0, 1.0]")).contains("0.7071067811865475"));
        assert!(err(&GOOD.replace("[0.0, 1.0]", "[0.0, 0.0]")).contains("zero"));
        assert!(err(&GOOD.replace("coefficient = 0.3\n", "")).contains("coefficient"));
        assert!(err(&GOOD.replace("young = 200.0", "young = nan")).contains("finite"));
        assert!(err(&GOOD.replace("\"coulomb\"", "\"colomb\"")).contains("\"none\""));
    }

    #[test]
    fn command_line_overrides_are_checked_like_the_file() {
        let mut c = parse(GOOD).unwrap();
        override_solver(
            &mut c,
            Some(5.0),
            Some(1e-6),
            Some(7),
            Some(CoulombMode::Outer),
        )
        .unwrap();
        assert_eq!(
            (
                c.solver.r,
                c.solver.tol,
                c.solver.max_iter,
                c.solver.coulomb
            ),
            (Some(5.0), 1e-6, 7, CoulombMode::Outer)
        );
        let e = |r, tol, max_iter| {
            let mut c = parse(GOOD).unwrap();
            override_solver(&mut c, r, tol, max_iter, None)
                .unwrap_err()
                .to_string()
        };
        assert!(e(Some(-1.0), None, None).starts_with("command line: --r = -1 must be a positive"));
        assert!(e(Some(f64::NAN), None, None).contains("--r = NaN"));
        assert!(e(None, Some(2.0), None).contains("--tol = 2 must lie in (0, 1)"));
        assert!(e(None, None, Some(0)).contains("--max-iter = 0: it must be at least 1"));
        assert!(err(&GOOD.replace("max_iter = 50", "max_iter = 0"))
            .contains("case.toml: solver.max_iter = 0"));
    }

    #[test]
    fn contact_entries_map_onto_obstacles() {
        let head = GOOD.split("[contact]").next().unwrap();
        let tail = "[solver]\nr = 1.0e4\n";
        let c = parse(&format!(
            r#"{head}[[contact]]
slave = "bottom"
obstacle = {{ type = "circle", centre = [1.0, -2.0], radius = 2.0, body = "inside" }}
friction = "coulomb"
coefficient = 0.3
[[contact]]
slave = "right"
obstacle = {{ type = "polyline", points = [[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]], body = "right" }}
friction = "coulomb"
coefficient = 0.1
{tail}"#
        ))
        .unwrap();
        assert_eq!(c.contacts.len(), 2);
        assert_eq!(
            c.contacts[0].obstacle,
            Some(Obstacle::Circle {
                centre: [1.0, -2.0],
                radius: 2.0,
                body: Side::Inside
            })
        );
        // The body on the right: walked the other way, the kernel keeps it on the left.
        assert_eq!(
            c.contacts[1].obstacle,
            Some(Obstacle::Polyline {
                points: vec![[2.0, 1.0], [1.0, 0.0], [0.0, 0.0]]
            })
        );
        assert_eq!(
            c.contacts[1].friction,
            Friction::Coulomb { coefficient: 0.1 }
        );
        // The old table is a line.
        let old = parse(GOOD).unwrap();
        assert_eq!(
            old.contacts[0].obstacle,
            Some(Obstacle::Line {
                point: [0.0, -0.001],
                normal: [0.0, 1.0]
            })
        );
        assert_eq!(old.contacts[0].group, "bottom");
        // An empty list, and a missing slave.
        let e = err(&format!("contact = []\n{head}{tail}"));
        assert!(e.contains("empty list"), "{e}");
        let e = err(&format!(
            "{head}[[contact]]\nobstacle = {{ type = \"circle\", centre = [0.0, 0.0], radius = 1.0 }}\n{tail}"
        ));
        assert!(e.contains("lacks the required key slave"), "{e}");
    }

    #[test]
    fn builtin_cases_parse() {
        for name in BUILTIN_CASES {
            builtin_case(name, 0).unwrap();
        }
        assert!(builtin_case("nope", 0).is_err());
    }
}
