//! The only place that calls MPI: collectives used by the set-up, the sweep and the
//! outputs, and the agreement on errors so that no subdomain waits for one that failed.
//!
//! A rank may run several subdomains, one per thread (`--subdomains-per-rank`): the
//! threads of a rank form a [`Team`], and every collective here is one over subdomains.
//! The team's members meet in shared memory and their leader (the rank's main thread,
//! which alone calls MPI: MPI_THREAD_FUNNELED) stands for them in the MPI collective.
//! Subdomain s lives on rank s / k, k the subdomains per rank, so that gathers in rank
//! order are gathers in subdomain order.

use crate::contact::Reduce;
use crate::dd::split::{PartArrays, SubProblem};
use crate::error::{Error, Result};
use crate::host;
use mpi::collective::SystemOperation;
use mpi::datatype::{Partition, PartitionMut};
use mpi::point_to_point::{Destination, Source};
use mpi::raw::AsRaw;
use mpi::topology::{Communicator, Process, SimpleCommunicator};
use mpi::traits::{CommunicatorCollectives, Root};
use std::any::Any;
use std::sync::atomic::{AtomicU64, Ordering as AtomicOrdering};
use std::sync::{Arc, Barrier, Mutex, PoisonError};

/// The threads of one rank, each running a subdomain, and where they meet.
pub struct Team {
    size: usize,
    barrier: Barrier,
    slots: Mutex<Vec<Option<Box<dyn Any + Send>>>>,
}

impl Team {
    pub fn new(size: usize) -> Arc<Self> {
        Arc::new(Team {
            size,
            barrier: Barrier::new(size),
            slots: Mutex::new((0..size).map(|_| None).collect()),
        })
    }

    pub fn size(&self) -> usize {
        self.size
    }

    fn slots(&self) -> std::sync::MutexGuard<'_, Vec<Option<Box<dyn Any + Send>>>> {
        self.slots.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Every member hands in a value; the leader (member 0) gets them all in member
    /// order, the others `None`. Waiting members sleep (a futex), they do not spin.
    pub fn gather<T: Send + 'static>(&self, me: usize, value: T) -> Option<Vec<T>> {
        if self.size == 1 {
            return Some(vec![value]);
        }
        self.slots()[me] = Some(Box::new(value));
        self.barrier.wait();
        let all = (me == 0).then(|| {
            self.slots()
                .iter_mut()
                .map(|slot| take_as::<T>(slot))
                .collect()
        });
        // The slots are free again before any member hands in its next value.
        self.barrier.wait();
        all
    }

    /// The leader hands each member its value (`values`, one per member, on the leader).
    pub fn scatter<T: Send + 'static>(&self, me: usize, values: Option<Vec<T>>) -> T {
        if self.size == 1 {
            return values
                .and_then(|v| v.into_iter().next())
                .expect("the leader's value");
        }
        if let Some(values) = values {
            let mut slots = self.slots();
            for (slot, v) in slots.iter_mut().zip(values) {
                *slot = Some(Box::new(v));
            }
        }
        self.barrier.wait();
        let mine = take_as::<T>(&mut self.slots()[me]);
        self.barrier.wait();
        mine
    }

    /// The leader's value to every member.
    pub fn broadcast<T: Clone + Send + 'static>(&self, me: usize, value: Option<T>) -> T {
        let copies = value.map(|v| vec![v; self.size]);
        self.scatter(me, copies)
    }
}

fn take_as<T: 'static>(slot: &mut Option<Box<dyn Any + Send>>) -> T {
    // The members call the same collective in the same order, so a slot holds the type
    // its collective put there; anything else is a bug in this module.
    *slot
        .take()
        .expect("a team slot filled by its member")
        .downcast::<T>()
        .expect("a team slot of the collective's type")
}

/// A subdomain's view of the job: its index among all subdomains, and the collectives
/// over them.
pub struct Mpi {
    /// The rank's communicator, on the team's leader only (the thread that calls MPI).
    world: Option<SimpleCommunicator>,
    /// This subdomain, of `size`.
    pub rank: usize,
    pub size: usize,
    /// Subdomains on this rank's node (those that share its memory), itself included.
    pub node_ranks: usize,
    /// The MPI rank and the number of ranks.
    pub mpi_rank: usize,
    pub mpi_size: usize,
    /// Whether MPI granted MPI_THREAD_FUNNELED (or more): what subdomain threads need.
    pub funneled: bool,
    team: Arc<Team>,
    member: usize,
}

/// Payload bytes this process has handed MPI to send to other ranks (a reduction's or a
/// broadcast's vector counted once, whatever algorithm MPI runs; MUMPS's own messages
/// not counted). For the figures of summary.json.
static SENT: AtomicU64 = AtomicU64::new(0);

fn count_sent(bytes: usize) {
    SENT.fetch_add(bytes as u64, AtomicOrdering::Relaxed);
}

/// The bytes this process has sent so far (see [`SENT`]).
pub fn bytes_sent() -> u64 {
    SENT.load(AtomicOrdering::Relaxed)
}

/// MPI as a team's leader sees it inside [`Mpi::on_leader`]: one caller per rank.
pub struct Leader<'a> {
    mpi: &'a Mpi,
}

impl Leader<'_> {
    /// The number of ranks.
    pub fn ranks(&self) -> usize {
        self.mpi.mpi_size
    }

    /// This rank (not the subdomain: that is `Mpi::rank`).
    pub fn mpi_rank(&self) -> usize {
        self.mpi.mpi_rank
    }

    /// Every rank's `value`, by rank.
    pub fn all_gather_u64(&self, value: u64) -> Vec<u64> {
        let mut all = vec![0u64; self.mpi.mpi_size];
        count_sent(8);
        self.mpi.world().all_gather_into(&value, &mut all[..]);
        all
    }

    /// The first rank's `value` on every rank.
    pub fn broadcast_u64(&self, value: u64) -> u64 {
        let mut v = value;
        if self.mpi.mpi_rank == 0 {
            count_sent(8);
        }
        self.mpi.world().process_at_rank(0).broadcast_into(&mut v);
        v
    }

    /// Whether `ok` holds on every rank.
    pub fn all_true(&self, ok: bool) -> bool {
        let (mine, mut all) = (ok as i32, 0i32);
        count_sent(4);
        self.mpi
            .world()
            .all_reduce_into(&mine, &mut all, SystemOperation::min());
        all == 1
    }

    /// The ranks' communicator as a Fortran handle (MPI_Comm_c2f), which is what MUMPS
    /// keeps.
    pub fn fortran_comm(&self) -> i32 {
        // SAFETY: the communicator is valid as long as this rank's `Mpi` lives.
        unsafe { mpi::ffi::MPI_Comm_c2f(self.mpi.world().as_raw()) }
    }

    /// All-to-all with lists of any length: `send[q]` goes to rank q; returns what each
    /// rank sent here, by rank. Two collectives: the counts, then the values.
    pub fn exchange<T>(&self, send: Vec<Vec<T>>) -> Vec<Vec<T>>
    where
        T: mpi::datatype::Equivalence + Copy + Default,
    {
        let p = self.mpi.mpi_size;
        assert_eq!(send.len(), p, "exchange: one list per rank");
        if p == 1 {
            return send;
        }
        let world = self.mpi.world();
        let counts: Vec<i32> = send.iter().map(|v| v.len() as i32).collect();
        let mut recv_counts = vec![0i32; p];
        world.all_to_all_into(&counts[..], &mut recv_counts[..]);
        let displs = |c: &[i32]| -> Vec<i32> {
            c.iter()
                .scan(0, |acc, &x| {
                    let d = *acc;
                    *acc += x;
                    Some(d)
                })
                .collect()
        };
        let me = self.mpi.mpi_rank;
        let others: usize = (0..p).filter(|&q| q != me).map(|q| send[q].len()).sum();
        count_sent(4 * p + others * std::mem::size_of::<T>());
        // Never an empty buffer's dangling address: for a type of one byte it is 1, which
        // Open MPI takes for MPI_IN_PLACE (and refuses as a receive buffer).
        let mut flat: Vec<T> = send.concat();
        flat.reserve(1);
        let (sd, rd) = (displs(&counts), displs(&recv_counts));
        let total = recv_counts.iter().sum::<i32>() as usize;
        let mut received = Vec::with_capacity(total + 1);
        received.resize(total, T::default());
        {
            let out = Partition::new(&flat[..], &counts[..], &sd[..]);
            let mut into = PartitionMut::new(&mut received[..], &recv_counts[..], &rd[..]);
            world.all_to_all_varcount_into(&out, &mut into);
        }
        let mut by_rank = Vec::with_capacity(p);
        let mut at = 0;
        for &c in &recv_counts {
            by_rank.push(received[at..at + c as usize].to_vec());
            at += c as usize;
        }
        by_rank
    }
}

/// What a member thread needs to build its [`Mpi`] (which holds no MPI handle).
#[derive(Clone)]
pub struct Membership {
    team: Arc<Team>,
    member: usize,
    mpi_rank: usize,
    mpi_size: usize,
    node_ranks: usize,
    funneled: bool,
}

impl Reduce for Mpi {
    fn sum_in_place(&self, values: &mut [f64]) {
        if self.size == 1 {
            return;
        }
        self.reduce_in_place(values, |a, b| a + b, SystemOperation::sum());
    }

    fn min_in_place(&self, values: &mut [f64]) {
        if self.size == 1 {
            return;
        }
        self.reduce_in_place(values, f64::min, SystemOperation::min());
    }
}

impl Mpi {
    /// One subdomain per rank (the set-up, before any team exists); `funneled`: the
    /// thread level MPI granted.
    pub fn new(world: SimpleCommunicator, funneled: bool) -> Self {
        let rank = world.rank() as usize;
        let size = world.size() as usize;
        let node_ranks = Self::ranks_on_node(&world);
        Mpi {
            world: Some(world),
            rank,
            size,
            node_ranks,
            mpi_rank: rank,
            mpi_size: size,
            funneled,
            team: Team::new(1),
            member: 0,
        }
    }

    /// `k` subdomains on every rank, one per thread: this rank's main thread becomes
    /// subdomain k x rank, its leader; the memberships are for the threads of the other
    /// k - 1 (each builds its own with [`Mpi::member`]). Every rank must use the same k.
    pub fn into_team(self, k: usize) -> (Mpi, Vec<Membership>) {
        let k = k.max(1);
        let team = Team::new(k);
        let node_ranks = self.node_ranks * k;
        let members = (1..k)
            .map(|member| Membership {
                team: team.clone(),
                member,
                mpi_rank: self.mpi_rank,
                mpi_size: self.mpi_size,
                node_ranks,
                funneled: self.funneled,
            })
            .collect();
        let leader = Mpi {
            world: self.world,
            rank: self.mpi_rank * k,
            size: self.mpi_size * k,
            node_ranks,
            mpi_rank: self.mpi_rank,
            mpi_size: self.mpi_size,
            funneled: self.funneled,
            team,
            member: 0,
        };
        (leader, members)
    }

    /// The view of a member thread of a team (no MPI handle: its leader calls MPI).
    pub fn member(m: Membership) -> Self {
        let k = m.team.size();
        Mpi {
            world: None,
            rank: m.mpi_rank * k + m.member,
            size: m.mpi_size * k,
            node_ranks: m.node_ranks,
            mpi_rank: m.mpi_rank,
            mpi_size: m.mpi_size,
            funneled: m.funneled,
            team: m.team,
            member: m.member,
        }
    }

    /// Subdomains per rank.
    pub fn per_rank(&self) -> usize {
        self.team.size()
    }

    /// The number of ranks that share this rank's node (MPI_Comm_split_type, shared
    /// memory), itself included; and the CPUs they may run on together, for
    /// [`host::set_node_cpus`]. Collective.
    fn ranks_on_node(world: &SimpleCommunicator) -> usize {
        let own = host::own_cpus();
        if world.size() == 1 {
            host::set_node_cpus(own);
            return 1;
        }
        let node = world.split_shared(0);
        let mut all = vec![0u64; own.len() * node.size().max(1) as usize];
        node.all_gather_into(&own[..], &mut all[..]);
        let mut union = own;
        for cpus in all.chunks_exact(union.len()) {
            union.iter_mut().zip(cpus).for_each(|(u, c)| *u |= c);
        }
        host::set_node_cpus(union);
        node.size().max(1) as usize
    }

    pub fn is_root(&self) -> bool {
        self.rank == 0
    }

    fn is_leader(&self) -> bool {
        self.member == 0
    }

    fn world(&self) -> &SimpleCommunicator {
        self.world
            .as_ref()
            .expect("MPI is called by a team's leader only")
    }

    /// The subdomains of rank r: r k .. (r + 1) k.
    fn rank_counts(&self, counts: &[usize]) -> Vec<usize> {
        counts
            .chunks(self.per_rank())
            .map(|c| c.iter().sum())
            .collect()
    }

    /// The team hands its values to its leader, which runs `f` (MPI included) and hands
    /// every member the result.
    fn leader_then_all<T: Send + 'static, R: Clone + Send + 'static>(
        &self,
        local: T,
        f: impl FnOnce(&Self, Vec<T>) -> R,
    ) -> R {
        let all = self.team.gather(self.member, local);
        let result = all.map(|all| f(self, all));
        self.team.broadcast(self.member, result)
    }

    /// Returns once every subdomain has called it, having slept, not spun, while
    /// waiting.
    ///
    /// MPI's blocking calls poll a core at full speed. Where the first subdomain works
    /// alone (it factors the interface system), the others wait here instead, so that
    /// the cores they would burn are the first one's to use (on a node shared by several
    /// ranks, or with more ranks than cores). Polling every 100 us to 1 ms costs nothing
    /// next to that work; the members of a team wait on a futex.
    pub fn barrier_sleeping(&self) {
        if self.size == 1 {
            return;
        }
        self.leader_then_all((), |s, _| {
            if s.mpi_size == 1 {
                return;
            }
            let mut request = s.world().immediate_barrier();
            // The poll backs off from 100 us to 1 ms: a long wait (the first rank's
            // start, a second or more) then wakes this rank a thousand times a second
            // on the core the first rank's threads borrow, not ten thousand, and ends
            // at most a millisecond late.
            let mut pause = std::time::Duration::from_micros(100);
            loop {
                match request.test() {
                    Ok(_) => return,
                    Err(pending) => {
                        request = pending;
                        std::thread::sleep(pause);
                        pause = (pause * 2).min(std::time::Duration::from_millis(1));
                    }
                }
            }
        })
    }

    /// The team hands its values to its leader, which runs `f` (MPI included, through
    /// the [`Leader`] it is given) and hands every member the result. For work that only
    /// one thread per rank may do, such as calling MUMPS.
    pub fn on_leader<T: Send + 'static, R: Clone + Send + 'static>(
        &self,
        local: T,
        f: impl FnOnce(&Leader, Vec<T>) -> R,
    ) -> R {
        self.leader_then_all(local, |s, parts| f(&Leader { mpi: s }, parts))
    }

    /// Concatenation over subdomains of `local` (subdomain s contributes `counts[s]`
    /// values).
    pub fn all_gather(&self, local: &[f64], counts: &[usize], out: &mut Vec<f64>) {
        let all = self.leader_then_all(local.to_vec(), |s, parts| {
            let mine = parts.concat();
            if s.mpi_size == 1 {
                return mine;
            }
            let rank_counts = s.rank_counts(counts);
            let mut all = vec![0.0; rank_counts.iter().sum()];
            let (c, d) = counts_displs(&rank_counts);
            let mut part = PartitionMut::new(&mut all[..], &c[..], &d[..]);
            count_sent(8 * mine.len());
            s.world().all_gather_varcount_into(&mine[..], &mut part);
            all
        });
        *out = all;
    }

    /// Concatenation over subdomains of `local`, on the first subdomain only.
    pub fn gather_to_root(&self, local: &[f64], counts: &[usize], out: &mut Vec<f64>) {
        // One subdomain per rank (every sweep of a cluster job): no team, no copy.
        let team_values;
        let mine = if self.per_rank() == 1 {
            local
        } else {
            let Some(parts) = self.team.gather(self.member, local.to_vec()) else {
                return;
            };
            team_values = parts.concat();
            &team_values[..]
        };
        if self.mpi_size == 1 {
            out.clear();
            out.extend_from_slice(mine);
            return;
        }
        let root = self.world().process_at_rank(0);
        if self.is_root() {
            let rank_counts = self.rank_counts(counts);
            out.resize(rank_counts.iter().sum(), 0.0);
            let (c, d) = counts_displs(&rank_counts);
            let mut part = PartitionMut::new(&mut out[..], &c[..], &d[..]);
            root.gather_varcount_into_root(mine, &mut part);
        } else {
            count_sent(8 * mine.len());
            root.gather_varcount_into(mine);
        }
    }

    /// The first subdomain's `all` cut by `counts`: each subdomain receives its part in
    /// `mine`.
    pub fn scatter_from_root(&self, all: &[f64], counts: &[usize], mine: &mut [f64]) {
        let k = self.per_rank();
        if k == 1 {
            self.scatter_to_ranks(all, counts, mine);
            return;
        }
        let segment = self.is_leader().then(|| {
            let mut segment = vec![0.0; self.rank_counts(counts)[self.mpi_rank]];
            self.scatter_to_ranks(all, counts, &mut segment);
            segment
        });
        let segment = self.team.broadcast(self.member, segment);
        let offset: usize = counts[self.mpi_rank * k..self.rank].iter().sum();
        mine.copy_from_slice(&segment[offset..offset + counts[self.rank]]);
    }

    /// The leader's part of [`Mpi::scatter_from_root`]: this rank's segment of `all` (its
    /// subdomains' parts, in order) into `segment`.
    fn scatter_to_ranks(&self, all: &[f64], counts: &[usize], segment: &mut [f64]) {
        if self.mpi_size == 1 {
            segment.copy_from_slice(all);
            return;
        }
        let root = self.world().process_at_rank(0);
        if self.is_root() {
            let (c, d) = counts_displs(&self.rank_counts(counts));
            count_sent(8 * (all.len() - segment.len()));
            let part = mpi::datatype::Partition::new(all, &c[..], &d[..]);
            root.scatter_varcount_into_root(&part, segment);
        } else {
            root.scatter_varcount_into(segment);
        }
    }

    /// Every subdomain's `value`, in subdomain order, on the first subdomain (`None`
    /// elsewhere). Within a rank the values move; between ranks they travel encoded, one
    /// message per rank.
    pub fn gather_parts<T>(&self, value: T) -> Result<Option<Vec<T>>>
    where
        T: serde::Serialize + serde::de::DeserializeOwned + Send + 'static,
    {
        let Some(mut all) = self.team.gather(self.member, value) else {
            return Ok(None);
        };
        if self.mpi_size == 1 {
            return Ok(Some(all));
        }
        if !self.is_root() {
            // A failed encoding is this rank's error to report; the first rank, which
            // must not wait for a message that never comes, gets an empty one.
            let (bytes, result) = match encode(&all) {
                Ok(b) => (b, Ok(None)),
                Err(e) => (Vec::new(), Err(e)),
            };
            self.world().process_at_rank(0).send(&bytes[..]);
            return result;
        }
        let mut failure: Option<Error> = None;
        for r in 1..self.mpi_size {
            let (bytes, _) = self.world().process_at_rank(r as i32).receive_vec::<u8>();
            match decode_part::<Vec<T>>(&bytes) {
                Ok(v) => all.extend(v),
                // A message that could not be read is this rank's to report, before a
                // sender's failure, which the sender reports itself.
                Err(e) => {
                    if failure
                        .as_ref()
                        .is_none_or(|f| matches!(f, Error::Silent(_)))
                    {
                        failure = Some(e);
                    }
                }
            }
        }
        match failure {
            Some(e) => Err(e),
            None => Ok(Some(all)),
        }
    }

    /// The first subdomain's `all` (one part per subdomain, in order) handed out: each
    /// subdomain returns its own. The counterpart of [`Mpi::gather_parts`].
    ///
    /// A rank's parts travel as one encoded message without their large arrays, then
    /// each array as it lies in memory ([`PartArrays`]), received straight into the
    /// part's own: the encoding and decoding of those arrays, element by element, and
    /// the buffers they went through were a tenth of a second on each side for a
    /// subdomain of a million-node mesh, while the other rank waited.
    pub fn scatter_parts(&self, all: Option<Vec<SubProblem>>) -> Result<SubProblem> {
        let k = self.per_rank();
        let team_values: Option<Vec<Result<SubProblem>>> = self.is_leader().then(|| {
            if self.is_root() {
                let mut all = all.unwrap_or_default().into_iter();
                let own: Vec<SubProblem> = all.by_ref().take(k).collect();
                let mut failure = None;
                for r in 1..self.mpi_size {
                    let mut chunk: Vec<SubProblem> = all.by_ref().take(k).collect();
                    let arrays: Vec<PartArrays> =
                        chunk.iter_mut().map(|p| p.take_arrays()).collect();
                    // A failed encoding is reported here, where it happened; the rank
                    // that waits for the message gets an empty one and stays quiet.
                    let bytes = encode(&chunk).unwrap_or_else(|e| {
                        failure = failure.take().or(Some(e));
                        Vec::new()
                    });
                    let to = self.world().process_at_rank(r as i32);
                    to.send(&bytes[..]);
                    if !bytes.is_empty() {
                        arrays.iter().for_each(|a| send_arrays(&to, a));
                    }
                }
                match failure {
                    Some(e) => (0..k).map(|_| Err(e.clone())).collect(),
                    None => pad(own.into_iter().map(Ok).collect(), k),
                }
            } else {
                let from = self.world().process_at_rank(0);
                let (bytes, _) = from.receive_vec::<u8>();
                match decode_part::<Vec<SubProblem>>(&bytes) {
                    Ok(mut parts) => {
                        parts
                            .iter_mut()
                            .for_each(|p| p.put_arrays(receive_arrays(&from)));
                        pad(parts.into_iter().map(Ok).collect(), k)
                    }
                    // An empty message: no arrays follow. A message that does not
                    // decode cannot be from this program's sender.
                    Err(e) => (0..k).map(|_| Err(e.clone())).collect(),
                }
            }
        });
        self.team.scatter(self.member, team_values)
    }

    /// Sends a value from the first subdomain to every other one.
    pub fn broadcast<T>(&self, value: Option<T>) -> Result<T>
    where
        T: serde::Serialize + serde::de::DeserializeOwned,
    {
        // A failed encoding is reported on the first subdomain, where it happened; the
        // others still take part in the broadcast (nobody waits for them) and get its
        // length as FAILED, which tells them to stay quiet.
        let (mut bytes, failure) = match &value {
            Some(v) if self.is_root() => match encode(v) {
                Ok(b) => (b, None),
                Err(e) => (Vec::new(), Some(e)),
            },
            _ => (Vec::new(), None),
        };
        let mut len = if failure.is_some() {
            FAILED
        } else {
            bytes.len() as u64
        };
        if self.is_leader() && self.mpi_size > 1 {
            let root = self.world().process_at_rank(0);
            root.broadcast_into(&mut len);
            if len != FAILED {
                bytes.resize(len as usize, 0);
                root.broadcast_into(&mut bytes[..]);
            }
        }
        let message = self
            .team
            .broadcast(self.member, self.is_leader().then_some((len, bytes)));
        match (value, failure) {
            (_, Some(e)) => Err(e),
            (Some(v), None) if self.is_root() => Ok(v),
            _ if message.0 == FAILED => Err(encode_failed_elsewhere()),
            _ => decode(&message.1),
        }
    }

    /// The largest of each entry over all subdomains.
    pub fn max_in_place(&self, values: &mut [f64]) {
        if self.size == 1 {
            return;
        }
        self.reduce_in_place(values, f64::max, SystemOperation::max());
    }

    /// Every entry of `values` combined over all subdomains: within the team by `op`
    /// in member order, then between ranks by `mpi_op` (the same operation).
    fn reduce_in_place(
        &self,
        values: &mut [f64],
        op: fn(f64, f64) -> f64,
        mpi_op: SystemOperation,
    ) {
        // One subdomain per rank (every sweep of a cluster job): MPI alone.
        if self.per_rank() == 1 {
            let local = values.to_vec();
            count_sent(8 * local.len());
            self.world().all_reduce_into(&local[..], values, mpi_op);
            return;
        }
        let reduced = self.leader_then_all(values.to_vec(), |s, parts| {
            let mut acc = parts[0].clone();
            for p in &parts[1..] {
                for (a, v) in acc.iter_mut().zip(p) {
                    *a = op(*a, *v);
                }
            }
            if s.mpi_size > 1 {
                let local = acc.clone();
                count_sent(8 * local.len());
                s.world().all_reduce_into(&local[..], &mut acc[..], mpi_op);
            }
            acc
        });
        values.copy_from_slice(&reduced);
    }

    /// Collective error agreement: every subdomain learns whether any failed. The first
    /// failing one that holds a message keeps its error, to print (the caller prints
    /// nothing more); all others return [`Error::Silent`].
    pub fn agree<T>(&self, local: Result<T>) -> Result<T> {
        if self.size == 1 {
            return local;
        }
        let (code, me) = agreement_vote(&local, self.rank);
        let (worst, first) = self.leader_then_all((code, me), |s, parts| {
            let mut worst = parts.iter().map(|p| p.0).max().unwrap_or(0);
            let mut first = parts.iter().map(|p| p.1).min().unwrap_or(i32::MAX);
            if s.mpi_size > 1 {
                let (w, f) = (worst, first);
                count_sent(4);
                s.world()
                    .all_reduce_into(&w, &mut worst, SystemOperation::max());
                if worst != 0 {
                    s.world()
                        .all_reduce_into(&f, &mut first, SystemOperation::min());
                }
            }
            (worst, first)
        });
        if worst == 0 {
            return local;
        }
        match local {
            Err(e) if first as usize == self.rank => Err(e),
            _ => Err(Error::Silent(worst)),
        }
    }
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

/// `v` made `k` long: missing entries are an internal error for their member.
fn pad<T>(mut v: Vec<Result<T>>, k: usize) -> Vec<Result<T>> {
    v.truncate(k);
    while v.len() < k {
        v.push(Err(Error::Numerical(
            "internal: a subdomain was not sent".into(),
        )));
    }
    v
}

/// What a subdomain brings to [`Mpi::agree`]: its exit code (0: no failure) and its
/// claim to print the message (its index; `i32::MAX` for none). A [`Error::Silent`]
/// failure has no message to print (another subdomain holds it), so it does not claim:
/// were it the first, nobody would print anything.
fn agreement_vote<T>(local: &Result<T>, rank: usize) -> (i32, i32) {
    match local {
        Ok(_) => (0, i32::MAX),
        Err(e @ Error::Silent(_)) => (e.exit_code(), i32::MAX),
        Err(e) => (e.exit_code(), rank as i32),
    }
}

/// The length [`Mpi::broadcast`] sends for a value the first subdomain could not encode.
const FAILED: u64 = u64::MAX;

/// The error of a subdomain whose message could not be encoded by its sender: the
/// sender reports the reason (an encoding failure is [`Error::Numerical`]), so this one
/// stays quiet with the same exit code.
fn encode_failed_elsewhere() -> Error {
    Error::Silent(Error::Numerical(String::new()).exit_code())
}

/// Sends a part's arrays to `to`: their lengths, then each as it lies in memory.
fn send_arrays(to: &Process<'_>, a: &PartArrays) {
    to.send(&a.lengths()[..]);
    to.send(&a.global_nodes[..]);
    to.send(a.nodes.as_flattened());
    to.send(a.triangles.as_flattened());
    to.send(&a.body[..]);
    to.send(&a.owned[..]);
    to.send(&a.load[..]);
}

/// Receives the arrays [`send_arrays`] sent, straight into their places.
fn receive_arrays(from: &Process<'_>) -> PartArrays {
    let mut n = [0u64; 6];
    from.receive_into(&mut n[..]);
    let mut a = PartArrays::of_lengths(n);
    from.receive_into(&mut a.global_nodes[..]);
    from.receive_into(a.nodes.as_flattened_mut());
    from.receive_into(a.triangles.as_flattened_mut());
    from.receive_into(&mut a.body[..]);
    from.receive_into(&mut a.owned[..]);
    from.receive_into(&mut a.load[..]);
    a
}

/// Decodes a message of [`Mpi::gather_parts`] or [`Mpi::scatter_parts`]. Those carry a
/// `Vec`, whose encoding starts with its length and is never empty: an empty message is
/// a sender's failure to encode, which the sender reports.
fn decode_part<T: serde::de::DeserializeOwned>(b: &[u8]) -> Result<T> {
    if b.is_empty() {
        return Err(encode_failed_elsewhere());
    }
    decode(b)
}

pub fn encode<T: serde::Serialize>(v: &T) -> Result<Vec<u8>> {
    postcard::to_allocvec(v)
        .map_err(|e| Error::Numerical(format!("internal: cannot encode a message: {e}")))
}

pub fn decode<T: serde::de::DeserializeOwned>(b: &[u8]) -> Result<T> {
    postcard::from_bytes(b)
        .map_err(|e| Error::Numerical(format!("internal: cannot decode a message: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `f(member)` on every member of a team of `k`, each on its own thread.
    fn on_team<R: Send>(k: usize, f: impl Fn(&Team, usize) -> R + Sync) -> Vec<R> {
        let team = Team::new(k);
        std::thread::scope(|s| {
            let handles: Vec<_> = (0..k)
                .map(|m| {
                    let (team, f) = (&team, &f);
                    s.spawn(move || f(team, m))
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        })
    }

    #[test]
    fn the_leader_gathers_in_member_order_and_hands_out_in_turn() {
        for k in [1, 2, 5] {
            let results = on_team(k, |team, me| {
                let mut seen = Vec::new();
                // Many rounds in a row: a fast member must not overwrite a slot that a
                // slow leader has yet to read.
                for round in 0..200 {
                    let all = team.gather(me, (me, round));
                    if me == 0 {
                        let all = all.unwrap();
                        assert_eq!(all, (0..k).map(|m| (m, round)).collect::<Vec<_>>());
                    } else {
                        assert!(all.is_none());
                    }
                    let values = (me == 0).then(|| (0..k).map(|m| 10 * m + round).collect());
                    seen.push(team.scatter(me, values));
                    let b = team.broadcast(me, (me == 0).then(|| vec![round; 3]));
                    assert_eq!(b, vec![round; 3]);
                }
                seen
            });
            for (m, seen) in results.iter().enumerate() {
                assert_eq!(*seen, (0..200).map(|r| 10 * m + r).collect::<Vec<_>>());
            }
        }
    }

    /// A value whose encoding fails, as an oversized or malformed one would.
    #[derive(Debug, Clone, serde::Deserialize)]
    struct Unencodable;

    impl serde::Serialize for Unencodable {
        fn serialize<S: serde::Serializer>(&self, _: S) -> std::result::Result<S::Ok, S::Error> {
            Err(serde::ser::Error::custom("cannot be encoded"))
        }
    }

    /// Runs `f` on every subdomain of a single rank with `k` of them, each on its own
    /// thread (no MPI call is made).
    fn on_one_rank<T: Send, R: Send>(local: Vec<T>, f: impl Fn(&Mpi, T) -> R + Sync) -> Vec<R> {
        let k = local.len();
        let team = Team::new(k);
        std::thread::scope(|s| {
            let handles: Vec<_> = local
                .into_iter()
                .enumerate()
                .map(|(member, value)| {
                    let (team, f) = (team.clone(), &f);
                    s.spawn(move || {
                        let mpi = Mpi::member(Membership {
                            team,
                            member,
                            mpi_rank: 0,
                            mpi_size: 1,
                            node_ranks: k,
                            funneled: true,
                        });
                        f(&mpi, value)
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        })
    }

    #[test]
    fn an_encoding_failure_is_reported_where_it_happens() {
        assert!(matches!(encode(&Unencodable), Err(Error::Numerical(_))));
        // The first subdomain cannot encode what it broadcasts: it reports why, the
        // others take part (nobody hangs) and stay quiet with the same exit code.
        let results = on_one_rank(vec![(); 3], |mpi, ()| {
            mpi.broadcast(mpi.is_root().then_some(Unencodable))
        });
        let message = results[0].as_ref().unwrap_err().to_string();
        assert!(message.contains("cannot encode"), "{message}");
        for r in &results[1..] {
            assert_eq!(r.as_ref().unwrap_err(), &Error::Silent(4));
        }
    }

    #[test]
    fn an_empty_part_is_the_senders_failure_and_garbage_the_readers() {
        let silent = decode_part::<Vec<u32>>(&[]).unwrap_err();
        assert_eq!(silent, Error::Silent(4));
        let bytes = encode(&vec![7u32, 8]).unwrap();
        assert_eq!(decode_part::<Vec<u32>>(&bytes).unwrap(), vec![7, 8]);
        // Even an empty Vec encodes to its length: never to an empty message.
        assert!(!encode(&Vec::<u32>::new()).unwrap().is_empty());
        let garbage = decode_part::<Vec<u32>>(&[0xff]).unwrap_err();
        assert!(garbage.to_string().contains("cannot decode"), "{garbage}");
    }

    #[test]
    fn the_agreement_keeps_the_message_of_the_first_subdomain_that_holds_one() {
        assert_eq!(agreement_vote(&Ok(()), 3), (0, i32::MAX));
        assert_eq!(
            agreement_vote::<()>(&Err(Error::Silent(4)), 0),
            (4, i32::MAX)
        );
        assert_eq!(
            agreement_vote::<()>(&Err(Error::Input("x".into())), 2),
            (2, 2)
        );
        // Subdomain 0 failed quietly (its sender reports), subdomain 1 holds a message:
        // subdomain 1 keeps it, and the job exits with the worse code.
        let local = vec![
            Err(Error::Silent(4)),
            Err(Error::Input("the message".into())),
            Ok(()),
        ];
        let results = on_one_rank(local, |mpi, l| mpi.agree(l));
        assert_eq!(
            results,
            vec![
                Err(Error::Silent(4)),
                Err(Error::Input("the message".into())),
                Err(Error::Silent(4)),
            ]
        );
    }

    #[test]
    fn counts_and_displacements_follow_each_other() {
        assert_eq!(counts_displs(&[3, 0, 2]), (vec![3, 0, 2], vec![0, 3, 3]));
        let padded = pad(vec![Ok(1)], 3);
        assert_eq!(padded.len(), 3);
        assert!(padded[0].is_ok() && padded[1].is_err() && padded[2].is_err());
    }
}
