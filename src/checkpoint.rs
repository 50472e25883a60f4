//! The loop-state files: each subdomain saves its Uzawa snapshot every few sweeps, and a
//! restarted run checks that every subdomain resumes the same format, layout, case and
//! sweep.

use crate::contact::Snapshot;
use crate::dd::comm::{decode, encode, Mpi};
use crate::error::{Error, Result};
use crate::output;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Where the loop state is saved and whether to resume from it.
pub struct CheckpointFiles {
    dir: PathBuf,
    /// Save every this many sweeps (0: never).
    pub every: usize,
    restart: bool,
    /// MPI ranks and subdomains per rank: a checkpoint resumes on the same layout.
    ranks: usize,
    per_rank: usize,
}

/// One subdomain's checkpoint (`rank` is the subdomain, as in the file name).
#[derive(Serialize, Deserialize)]
struct CheckpointFile {
    /// [`Snapshot::FORMAT`], first: a file of another format is refused, not misread.
    format: String,
    ranks: usize,
    per_rank: usize,
    rank: usize,
    contact_nodes: usize,
    snapshot: Snapshot,
}

/// What every checkpoint file of a format begins with.
#[derive(Deserialize)]
struct Head {
    format: String,
}

impl CheckpointFiles {
    /// The files under `out/checkpoint/` of a run on `mpi`'s layout.
    pub fn new(out: &Path, every: usize, restart: bool, mpi: &Mpi) -> Self {
        CheckpointFiles {
            dir: out.join("checkpoint"),
            every,
            restart,
            ranks: mpi.mpi_size,
            per_rank: mpi.per_rank(),
        }
    }

    fn path(&self, rank: usize) -> PathBuf {
        self.dir.join(format!("rank_{rank}.bin"))
    }

    /// The snapshot this subdomain resumes from, if the run restarts (collective: every
    /// subdomain checks that all resume from the same sweep).
    pub fn resume(&self, mpi: &Mpi, contact_nodes: usize) -> Result<Option<Snapshot>> {
        if !self.restart {
            return Ok(None);
        }
        let snap = mpi.agree(self.read(mpi.rank, contact_nodes))?;
        let mut sweeps = [snap.sweeps() as f64, -(snap.sweeps() as f64)];
        mpi.max_in_place(&mut sweeps);
        if sweeps[0] != -sweeps[1] {
            return mpi.agree(Err(Error::Input(format!(
                "{}: the ranks' checkpoints are from different sweeps (a crash while saving); run without --restart",
                self.dir.display()
            ))));
        }
        Ok(Some(snap))
    }

    /// Subdomain `rank`'s snapshot, if its file is of this layout and case.
    fn read(&self, rank: usize, contact_nodes: usize) -> Result<Snapshot> {
        let path = self.path(rank);
        let bytes = std::fs::read(&path)
            .map_err(|e| Error::Input(format!("{}: cannot read the checkpoint: {e}; run without --restart, or with the --out of the interrupted run", path.display())))?;
        let refuse =
            |what: &str| Error::Input(format!("{}: {what}; run without --restart", path.display()));
        if !decode::<Head>(&bytes).is_ok_and(|h| h.format == Snapshot::FORMAT) {
            return Err(refuse(
                "not a checkpoint of this version of contact-par (another format)",
            ));
        }
        let c = decode::<CheckpointFile>(&bytes).map_err(|_| refuse("a damaged checkpoint"))?;
        if c.ranks != self.ranks
            || c.per_rank != self.per_rank
            || c.rank != rank
            || c.contact_nodes != contact_nodes
        {
            return Err(Error::Input(format!(
                "{}: written by a run on {} rank(s) x {} subdomain(s) per rank, or of another case or mesh; restart the same case with mpirun -n {} and --subdomains-per-rank {}",
                path.display(),
                c.ranks,
                c.per_rank,
                c.ranks,
                c.per_rank
            )));
        }
        Ok(c.snapshot)
    }

    /// Saves subdomain `rank`'s snapshot, atomically.
    pub fn save(&self, rank: usize, contact_nodes: usize, snap: &Snapshot) -> Result<()> {
        std::fs::create_dir_all(&self.dir)
            .map_err(|e| Error::Output(format!("cannot create {}: {e}", self.dir.display())))?;
        let file = CheckpointFile {
            format: Snapshot::FORMAT.to_string(),
            ranks: self.ranks,
            per_rank: self.per_rank,
            rank,
            contact_nodes,
            snapshot: snap.clone(),
        };
        output::write_atomic(&self.path(rank), &encode(&file)?)
    }
}
