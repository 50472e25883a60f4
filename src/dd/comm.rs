//! The only place that calls MPI: collectives used by the set-up, the sweep and the
//! outputs, and the agreement on errors so that no rank waits for one that failed.

use crate::contact::Reduce;
use crate::error::{Error, Result};
use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::point_to_point::{Destination, Source};
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::{CommunicatorCollectives, Root};

pub struct Mpi {
    pub world: SimpleCommunicator,
    pub rank: usize,
    pub size: usize,
    /// Ranks on this rank's node (those that share its memory), itself included.
    pub node_ranks: usize,
}

impl Reduce for Mpi {
    fn sum_in_place(&self, values: &mut [f64]) {
        if self.size == 1 {
            return;
        }
        let local = values.to_vec();
        self.world
            .all_reduce_into(&local[..], values, SystemOperation::sum());
    }
}

impl Mpi {
    pub fn new(world: SimpleCommunicator) -> Self {
        let rank = world.rank() as usize;
        let size = world.size() as usize;
        let node_ranks = Self::ranks_on_node(&world);
        Mpi {
            world,
            rank,
            size,
            node_ranks,
        }
    }

    /// The number of ranks that share this rank's node (MPI_Comm_split_type, shared
    /// memory), itself included. Collective.
    fn ranks_on_node(world: &SimpleCommunicator) -> usize {
        if world.size() == 1 {
            return 1;
        }
        world.split_shared(0).size().max(1) as usize
    }

    pub fn is_root(&self) -> bool {
        self.rank == 0
    }

    /// Returns once every rank has called it, having slept, not spun, while waiting.
    ///
    /// MPI's blocking calls poll a core at full speed. Where the first rank works alone
    /// (it factors the interface system), the others wait here instead, so that the
    /// cores they would burn are the first rank's to use (on a node shared by several
    /// ranks, or with more ranks than cores). Polling every 100 us costs nothing next to
    /// that work.
    pub fn barrier_sleeping(&self) {
        if self.size == 1 {
            return;
        }
        let mut request = self.world.immediate_barrier();
        loop {
            match request.test() {
                Ok(_) => return,
                Err(pending) => {
                    request = pending;
                    std::thread::sleep(std::time::Duration::from_micros(100));
                }
            }
        }
    }

    /// Concatenation over ranks of `local` (rank r contributes `counts[r]` values).
    pub fn all_gather(&self, local: &[f64], counts: &[usize], out: &mut Vec<f64>) {
        let total: usize = counts.iter().sum();
        out.resize(total, 0.0);
        if self.size == 1 {
            out.copy_from_slice(local);
            return;
        }
        let c: Vec<i32> = counts.iter().map(|&c| c as i32).collect();
        let d: Vec<i32> = counts
            .iter()
            .scan(0i32, |acc, &c| {
                let d = *acc;
                *acc += c as i32;
                Some(d)
            })
            .collect();
        let mut part = PartitionMut::new(&mut out[..], &c[..], &d[..]);
        self.world.all_gather_varcount_into(local, &mut part);
    }

    fn counts_displs(counts: &[usize]) -> (Vec<i32>, Vec<i32>) {
        let c: Vec<i32> = counts.iter().map(|&c| c as i32).collect();
        let mut d = Vec::with_capacity(c.len());
        let mut acc = 0;
        for &x in &c {
            d.push(acc);
            acc += x;
        }
        (c, d)
    }

    /// Concatenation over ranks of `local`, on the first rank only.
    pub fn gather_to_root(&self, local: &[f64], counts: &[usize], out: &mut Vec<f64>) {
        if self.size == 1 {
            out.clear();
            out.extend_from_slice(local);
            return;
        }
        let root = self.world.process_at_rank(0);
        if self.is_root() {
            out.resize(counts.iter().sum(), 0.0);
            let (c, d) = Self::counts_displs(counts);
            let mut part = PartitionMut::new(&mut out[..], &c[..], &d[..]);
            root.gather_varcount_into_root(local, &mut part);
        } else {
            root.gather_varcount_into(local);
        }
    }

    /// The first rank's `all` cut by `counts`: each rank receives its part in `mine`.
    pub fn scatter_from_root(&self, all: &[f64], counts: &[usize], mine: &mut [f64]) {
        if self.size == 1 {
            mine.copy_from_slice(all);
            return;
        }
        let root = self.world.process_at_rank(0);
        if self.is_root() {
            let (c, d) = Self::counts_displs(counts);
            let part = mpi::datatype::Partition::new(all, &c[..], &d[..]);
            root.scatter_varcount_into_root(&part, mine);
        } else {
            root.scatter_varcount_into(mine);
        }
    }

    pub fn send_bytes(&self, dest: usize, bytes: &[u8]) {
        self.world.process_at_rank(dest as i32).send(bytes);
    }

    pub fn recv_bytes(&self, src: usize) -> Vec<u8> {
        self.world.process_at_rank(src as i32).receive_vec::<u8>().0
    }

    /// Sends a value from the root to every other rank.
    pub fn broadcast<T: serde::Serialize + serde::de::DeserializeOwned>(
        &self,
        value: Option<T>,
    ) -> Result<T> {
        let root = self.world.process_at_rank(0);
        let mut bytes = match &value {
            Some(v) if self.is_root() => encode(v)?,
            _ => Vec::new(),
        };
        if self.size > 1 {
            let mut len = bytes.len() as u64;
            root.broadcast_into(&mut len);
            bytes.resize(len as usize, 0);
            root.broadcast_into(&mut bytes[..]);
        }
        match value {
            Some(v) if self.is_root() => Ok(v),
            _ => decode(&bytes),
        }
    }

    /// Collective error agreement: every rank learns whether any rank failed. The first
    /// failing rank prints its message (the caller prints nothing more), all return Err.
    pub fn agree<T>(&self, local: Result<T>) -> Result<T> {
        if self.size == 1 {
            return local;
        }
        let code = local.as_ref().err().map_or(0, |e| e.exit_code());
        let mut worst = 0i32;
        self.world
            .all_reduce_into(&code, &mut worst, SystemOperation::max());
        if worst == 0 {
            return local;
        }
        let me = if local.is_err() {
            self.rank as i32
        } else {
            i32::MAX
        };
        let mut first = 0i32;
        self.world
            .all_reduce_into(&me, &mut first, SystemOperation::min());
        match local {
            Err(e) if first as usize == self.rank => Err(e),
            _ => Err(Error::Silent(worst)),
        }
    }
}

pub fn encode<T: serde::Serialize>(v: &T) -> Result<Vec<u8>> {
    postcard::to_allocvec(v)
        .map_err(|e| Error::Numerical(format!("internal: cannot encode a message: {e}")))
}

pub fn decode<T: serde::de::DeserializeOwned>(b: &[u8]) -> Result<T> {
    postcard::from_bytes(b)
        .map_err(|e| Error::Numerical(format!("internal: cannot decode a message: {e}")))
}
