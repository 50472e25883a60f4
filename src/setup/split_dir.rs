//! Split directories: a case read, partitioned and split once (`contact-par split`, by
//! its first process) into one file per part, so that a run (`--mesh-split DIR`) has
//! each subdomain read its own part and no rank reads the whole mesh.
//!
//! `DIR/split.json`, the manifest, is written last (a split cut short has none): how many
//! parts, what they were made from, and the figures of the whole problem that a run prints
//! and starts from. `DIR/part-NNNNN.bin` holds one [`SubProblem`] behind a header that
//! names its split and its index, so that a part of another split is refused.
//!
//! A run reads the case file again. Only what the parts are made of must be unchanged:
//! the mesh, the Dirichlet conditions, the tractions, the body force, the contact groups,
//! their obstacles (the nodes' normals and gaps), whether there is friction (which
//! decides the boundary dofs and the nodes turned into their frames) and the bodies'
//! groups (`[[material]] group`, each triangle's body is in its part). The materials'
//! values, the friction coefficient or threshold and the solver settings may change
//! between runs of one split: the split keeps the mesh's lengths, not the default r.

use super::from_file::{facts, load_mesh, Cut};
use super::{check_linear, Layout, Setup};
use crate::case::{Case, MeshSource};
use crate::contact::Friction;
use crate::dd::comm::Mpi;
use crate::dd::split::SubProblem;
use crate::error::{Error, Result};
use crate::host;
use crate::options::{LinearMode, Options, SplitOptions};
use crate::output::write_atomic;
use crate::problem::{self, Holding, Lengths};
use crate::run::Printer;
use crate::timer::{self, Phase, Timer};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The manifest's file name in a split directory.
pub const MANIFEST: &str = "split.json";
/// Bumped whenever the part files or the manifest change layout.
const FORMAT: u32 = 5;
const MAGIC: &[u8; 8] = b"CPSPLIT\x01";

/// What partitioning and splitting a case fixes, whoever did it (the first rank of a run,
/// or `contact-par split` before): the figures of the whole problem that every rank needs
/// and no rank can compute from its own part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Facts {
    pub lengths: Lengths,
    /// The bodies touching the contact nodes (`Problem::contact_bodies`): their materials
    /// set r's scale, whatever the materials of the run.
    pub contact_bodies: Vec<u32>,
    pub n_boundary: usize,
    pub n_interface: usize,
    pub nodes: usize,
    pub elements: usize,
    pub free_dofs: usize,
    pub contact_nodes: usize,
    /// The partition's quality report.
    pub partition: String,
    /// The separate parts' Dirichlet conditions, for the check of the answer.
    pub holding: Holding,
}

/// A split directory checked against the case of the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Split {
    pub dir: PathBuf,
    pub parts: usize,
    /// Every part file of this split carries it.
    pub id: String,
    pub facts: Facts,
}

#[derive(Serialize, Deserialize)]
struct Manifest {
    format: u32,
    program: String,
    parts: usize,
    id: String,
    /// Where the case came from, for messages.
    case: String,
    mesh_file: Option<MeshFile>,
    /// A hash of each part of the case that the part files depend on.
    fingerprint: BTreeMap<String, String>,
    facts: Facts,
}

#[derive(Serialize, Deserialize)]
struct MeshFile {
    name: String,
    bytes: u64,
    sha256: String,
}

#[derive(Serialize, Deserialize)]
struct PartHeader {
    format: u32,
    id: String,
    part: usize,
    parts: usize,
}

/// The file of part `part` in `dir`.
pub fn part_path(dir: &Path, part: usize) -> PathBuf {
    dir.join(format!("part-{part:05}.bin"))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn sha256(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// The hashes of what the parts are made of, section by section (so that a mismatch can
/// be named). The mesh file by its name only: its bytes are checked apart.
fn fingerprint(case: &Case) -> BTreeMap<String, String> {
    let mesh = match &case.mesh {
        MeshSource::File(p) => format!(
            "file {}",
            p.file_name()
                .map_or_else(String::new, |f| f.to_string_lossy().into_owned())
        ),
        MeshSource::Builtin { name, level } => format!("builtin {name:?} {level}"),
    };
    // Each contact's group, obstacle or master (the nodes' frames, gaps and mortar rows
    // are in the parts), and whether there is friction (which decides the boundary dofs).
    let contact = format!(
        "{} {}",
        json(
            &(case.contacts.iter())
                .map(|c| (&c.group, &c.obstacle, &c.master))
                .collect::<Vec<_>>()
        ),
        !matches!(case.friction(), Friction::None)
    );
    [
        ("mesh", mesh),
        ("dirichlet", json(&case.dirichlet)),
        ("traction", json(&case.traction)),
        ("body_force", json(&case.body_force)),
        // Which group each body is (each part's triangles carry their body), not what
        // it is made of: the values may change between runs.
        (
            "material",
            json(
                &(case.materials.iter())
                    .map(|b| &b.group)
                    .collect::<Vec<_>>(),
            ),
        ),
        ("contact", contact),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), sha256(v.as_bytes())[..16].to_string()))
    .collect()
}

/// The last component of `path` (empty if none), for the fingerprint and the manifest.
fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |f| f.to_string_lossy().into_owned())
}

fn json<T: Serialize + ?Sized>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

/// The mesh file's name, size and hash, read in pieces (it may be large).
fn mesh_file(case: &Case) -> Result<Option<MeshFile>> {
    let MeshSource::File(path) = &case.mesh else {
        return Ok(None);
    };
    let fail = |e: std::io::Error| Error::Input(format!("{}: cannot read: {e}", path.display()));
    let mut file = std::fs::File::open(path).map_err(fail)?;
    let (mut hasher, mut buf, mut bytes) = (Sha256::new(), vec![0u8; 1 << 20], 0u64);
    loop {
        let n = file.read(&mut buf).map_err(fail)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        bytes += n as u64;
    }
    Ok(Some(MeshFile {
        name: file_name(path),
        bytes,
        sha256: hex(&hasher.finalize()),
    }))
}

/// Writes `subs` (part k at index k) and then the manifest into `dir`, each file
/// atomically. An old manifest and part files of an earlier split with more parts are
/// removed first, so that the directory holds one split only.
pub fn write(dir: &Path, case: &Case, facts: &Facts, subs: &[SubProblem]) -> Result<Split> {
    let parts = subs.len();
    clear(dir, parts)?;
    // The id every part file carries: the program, the layout, the case and the mesh.
    let (mesh_file, fingerprint) = (mesh_file(case)?, fingerprint(case));
    let mut h = Sha256::new();
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(format!("{FORMAT} {parts} {fingerprint:?}").as_bytes());
    if let Some(m) = &mesh_file {
        h.update(m.sha256.as_bytes());
    }
    let id = hex(&h.finalize())[..16].to_string();
    for (part, sub) in subs.iter().enumerate() {
        let header = PartHeader {
            format: FORMAT,
            id: id.clone(),
            part,
            parts,
        };
        let mut bytes = MAGIC.to_vec();
        bytes = postcard::to_extend(&header, bytes).map_err(|e| encode_failed(dir, e))?;
        bytes = postcard::to_extend(sub, bytes).map_err(|e| encode_failed(dir, e))?;
        write_atomic(&part_path(dir, part), &bytes)?;
    }
    // The manifest, once every part is written: what makes the split whole.
    let manifest = Manifest {
        format: FORMAT,
        program: format!("contact-par {}", env!("CARGO_PKG_VERSION")),
        parts,
        id: id.clone(),
        case: case.origin.clone(),
        mesh_file,
        fingerprint,
        facts: facts.clone(),
    };
    let text = serde_json::to_string_pretty(&manifest).map_err(|e| encode_failed(dir, e))?;
    write_atomic(&dir.join(MANIFEST), format!("{text}\n").as_bytes())?;
    Ok(Split {
        dir: dir.to_path_buf(),
        parts,
        id,
        facts: facts.clone(),
    })
}

/// `dir` made, an old manifest and part files beyond `parts` removed.
fn clear(dir: &Path, parts: usize) -> Result<()> {
    let out = |e: std::io::Error| {
        Error::Output(format!(
            "{}: cannot write the split: {e}; check that the directory is writable",
            dir.display()
        ))
    };
    std::fs::create_dir_all(dir).map_err(out)?;
    // An old manifest must not vouch for a half-written new split.
    match std::fs::remove_file(dir.join(MANIFEST)) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(out(e)),
        _ => {}
    }
    for entry in std::fs::read_dir(dir).map_err(out)? {
        let name = entry.map_err(out)?.file_name();
        let name = name.to_string_lossy();
        let index = name
            .strip_prefix("part-")
            .and_then(|s| s.strip_suffix(".bin"))
            .and_then(|s| s.parse::<usize>().ok());
        if index.is_some_and(|k| k >= parts) {
            std::fs::remove_file(dir.join(&*name)).map_err(out)?;
        }
    }
    Ok(())
}

fn encode_failed(dir: &Path, e: impl std::fmt::Display) -> Error {
    Error::Output(format!("{}: cannot encode the split: {e}", dir.display()))
}

/// The way out of a bad or mismatched split directory.
fn split_again(case: &Case, dir: &Path) -> String {
    let case_arg = match &case.mesh {
        MeshSource::Builtin { .. } => format!("--builtin ... --level ... (as for {})", case.origin),
        MeshSource::File(_) => case.origin.clone(),
    };
    format!(
        "make it again: contact-par split {case_arg} --parts N --out {}",
        dir.display()
    )
}

/// `contact-par split`: reads the case and its mesh, cuts and splits them into
/// `--parts` subdomains as a run on that many would, and writes one file per part. The
/// first process does it all; under mpirun the others sleep, lending it their cores.
pub fn split(opts: &SplitOptions, mpi: &Mpi, print: &Printer) -> Result<()> {
    let done = mpi.is_root().then(|| {
        host::on_idle_cores(mpi.node_ranks, || -> Result<()> {
            let case = opts.case.case()?;
            let (mesh, mesh_name) = load_mesh(&case)?;
            let prob = problem::build(&case, mesh, &mesh_name)?;
            let triangles = prob.mesh.triangles.len();
            if opts.parts > triangles {
                return Err(Error::Input(format!(
                    "{mesh_name}: --parts {} for {triangles} triangles; use at most as many parts as triangles (better: thousands of triangles each)",
                    opts.parts
                )));
            }
            let mut facts = facts(&prob);
            let cut = Cut {
                nparts: opts.parts,
                partitioner: opts.partitioner,
                mesh_name: &mesh_name,
            };
            let (subs, method) = cut.split(&case, &mut facts, prob, &Timer::start())?;
            let split = write(&opts.out, &case, &facts, &subs)?;
            print_split(print, opts, &facts, split.parts, method);
            Ok(())
        })
    });
    mpi.barrier_sleeping();
    mpi.agree(done.unwrap_or(Ok(())))
}

/// The split's two lines: what was split, how it was cut, and how to run it.
fn print_split(print: &Printer, opts: &SplitOptions, facts: &Facts, parts: usize, how: &str) {
    let out = opts.out.display();
    print.line(format!(
        "split: {} nodes, {} triangles, {} contact nodes into {parts} parts ({how}: {}) in {out}",
        facts.nodes, facts.elements, facts.contact_nodes, facts.partition,
    ));
    print.line(format!(
        "run it with: mpirun -n N contact-par {} --mesh-split {out}   (N dividing {parts})",
        opts.case.command_line(),
    ));
}

/// Phase 1 of a run from the split `dir`, on the first rank: the case and the split's
/// manifest (each subdomain reads its own part in phase 3). Prints the run's first line
/// and the read's.
pub(super) fn setup(
    opts: &Options,
    dir: &Path,
    layout: Layout,
    timer: &Timer,
    print: &Printer,
) -> Result<Setup> {
    let (case, split) = timer.time(Phase::Read, || -> Result<_> {
        let case = opts.load_case()?;
        check_linear(opts, &case)?;
        let split = open(dir, &case)?;
        Ok((case, split))
    })?;
    let per_rank = split.per_rank(opts, layout.ranks)?;
    let (facts, parts) = (split.facts.clone(), split.parts);
    let setup = Setup::new(opts, (case, facts), Some(split), layout, per_rank)?;
    print.line(&setup.header);
    let f = &setup.facts;
    let figure = format!(
        "the split {} of {parts} parts ({} nodes, {} triangles, {} contact nodes): {}",
        dir.display(),
        f.nodes,
        f.elements,
        f.contact_nodes,
        f.partition
    );
    let read = timer.seconds(Phase::Read);
    print.line(timer::phase_line(Phase::Read, read, &figure));
    Ok(setup)
}

/// Reads the manifest of `dir` and checks it against the run's `case`: same sections of
/// the case, same mesh file size where the mesh file is at hand (a run on a cluster may
/// have the split directory only).
pub fn open(dir: &Path, case: &Case) -> Result<Split> {
    let path = dir.join(MANIFEST);
    let again = || split_again(case, dir);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        Error::Input(format!(
            "{}: cannot read the split's manifest ({e}): --mesh-split wants a directory written by contact-par split; {}",
            path.display(),
            again()
        ))
    })?;
    let m: Manifest = serde_json::from_str(&text).map_err(|e| {
        Error::Input(format!(
            "{}: not a manifest of contact-par split ({e}); {}",
            path.display(),
            again()
        ))
    })?;
    if m.format != FORMAT {
        return Err(Error::Input(format!(
            "{}: split by another version of contact-par ({}, format {}; this one reads format {FORMAT}); {}",
            path.display(),
            m.program,
            m.format,
            again()
        )));
    }
    let ours = fingerprint(case);
    let differ: Vec<&str> = ours
        .iter()
        .filter(|(k, v)| m.fingerprint.get(*k) != Some(v))
        .map(|(k, _)| k.as_str())
        .collect();
    if !differ.is_empty() {
        return Err(Error::Input(format!(
            "{}: split from another case ({}): its {} {} from {}; {}",
            path.display(),
            m.case,
            differ.join(", "),
            if differ.len() == 1 {
                "section differs"
            } else {
                "sections differ"
            },
            case.origin,
            again()
        )));
    }
    if let (MeshSource::File(mesh), Some(recorded)) = (&case.mesh, &m.mesh_file) {
        if let Ok(meta) = std::fs::metadata(mesh) {
            if meta.len() != recorded.bytes {
                return Err(Error::Input(format!(
                    "{}: split from another {} ({} bytes, this one has {}); {}",
                    path.display(),
                    mesh.display(),
                    recorded.bytes,
                    meta.len(),
                    again()
                )));
            }
        }
    }
    if m.parts == 0 {
        return Err(Error::Input(format!(
            "{}: the split has no parts; {}",
            path.display(),
            again()
        )));
    }
    Ok(Split {
        dir: dir.to_path_buf(),
        parts: m.parts,
        id: m.id,
        facts: m.facts,
    })
}

impl Split {
    /// Subdomains per rank of a run from this split on `ranks` ranks: its parts over
    /// the ranks, which must divide them.
    fn per_rank(&self, opts: &Options, ranks: usize) -> Result<usize> {
        let (parts, dir) = (self.parts, self.dir.display());
        if parts % ranks != 0 {
            let divisors: Vec<String> = (1..=parts)
                .filter(|k| parts % k == 0)
                .map(|k| k.to_string())
                .collect();
            return Err(Error::Input(format!(
                "{dir}: the split has {parts} parts for {ranks} ranks; run on a number of ranks that divides {parts} ({}), or split again with --parts {ranks}",
                divisors.join(", ")
            )));
        }
        let per_rank = parts / ranks;
        match opts.subdomains_per_rank {
            Some(k) if k != per_rank => Err(Error::Input(format!(
                "{dir}: --subdomains-per-rank {k} on {ranks} ranks makes {} subdomains, the split has {parts} parts; leave --subdomains-per-rank out (it is {per_rank} here)",
                k * ranks
            ))),
            _ if opts.linear == LinearMode::Full && parts > 1 => Err(Error::Input(format!(
                "{dir}: --linear full runs on one subdomain, the split has {parts} parts; use the default (condensed) or a split with --parts 1"
            ))),
            _ => Ok(per_rank),
        }
    }

    /// Reads part `part` and checks that it belongs to this split.
    pub fn read_part(&self, part: usize) -> Result<SubProblem> {
        let path = part_path(&self.dir, part);
        let bad = |why: String| {
            Error::Input(format!(
                "{}: {why}; the split in {} is damaged: make it again with contact-par split",
                path.display(),
                self.dir.display()
            ))
        };
        let bytes = std::fs::read(&path)
            .map_err(|e| bad(format!("cannot read part {part} of {} ({e})", self.parts)))?;
        let body = bytes
            .strip_prefix(MAGIC.as_slice())
            .ok_or_else(|| bad("not a part file of contact-par split".into()))?;
        let (header, rest): (PartHeader, &[u8]) =
            postcard::take_from_bytes(body).map_err(|e| bad(format!("unreadable header ({e})")))?;
        if header.format != FORMAT || header.id != self.id || header.parts != self.parts {
            return Err(bad(format!(
                "belongs to another split (id {}, {} parts; {MANIFEST} says id {}, {} parts)",
                header.id, header.parts, self.id, self.parts
            )));
        }
        if header.part != part {
            return Err(bad(format!("holds part {}, not {part}", header.part)));
        }
        let sub: SubProblem =
            postcard::from_bytes(rest).map_err(|e| bad(format!("truncated or corrupt ({e})")))?;
        if sub.rank != part {
            return Err(bad(format!("holds subdomain {}, not {part}", sub.rank)));
        }
        Ok(sub)
    }
}
