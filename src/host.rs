//! Host and runtime policy: how many subdomains and threads a rank runs, whose cores the
//! first rank borrows, how the allocator keeps freed memory, and what the process reads
//! of its own memory. Nothing here changes a result, only where and how fast it is made.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::OnceLock;

/// Triangles per subdomain from which [`subdomains_per_rank`] gives a thread a
/// subdomain of its own (see there).
pub const MIN_TRIANGLES_PER_SUBDOMAIN: usize = 5_000;

/// Subdomains of the whole job beyond which [`subdomains_per_rank`] splits no rank
/// further (see there).
pub const MAX_DEFAULT_SUBDOMAINS: usize = 8;

/// Stack of a subdomain thread: the main thread's usual 8 MiB.
const SUBDOMAIN_STACK_BYTES: usize = 8 << 20;

/// Subdomains per rank by default: one per thread of the rank, as long as each keeps
/// [`MIN_TRIANGLES_PER_SUBDOMAIN`] triangles and the job [`MAX_DEFAULT_SUBDOMAINS`]
/// subdomains; at least one.
///
/// Why split: a sparse Cholesky factorization spreads over threads only inside its
/// fronts, whereas k subdomains factor on k threads at once, each a piece whose factor
/// costs less than 1/k of the whole (O(n^1.5) flops in 2D); below the threshold the
/// partition and the interface cost what the threads save (docs/performance.md).
///
/// Why stop at a few subdomains: the interface system is dense and solved by the first
/// rank (`dd`). In 2D its size grows as sqrt(nodes x subdomains), so its n_G^3 / 3 flops
/// grow as P^1.5 times those of the whole mesh while each subdomain's factor shrinks as
/// P^-1.5: their ratio grows as P^3. With many ranks each rank keeps one subdomain; more
/// can still be asked for with `--subdomains-per-rank`.
pub fn subdomains_per_rank(threads: usize, ranks: usize, triangles: usize) -> usize {
    let ranks = ranks.max(1);
    let by_size = triangles / (ranks * MIN_TRIANGLES_PER_SUBDOMAIN);
    let by_interface = MAX_DEFAULT_SUBDOMAINS / ranks;
    threads.min(by_size).min(by_interface).max(1)
}

/// Runs `work` with the threads of every rank of this node, `node_ranks` of them each
/// with this rank's thread count, while the others wait asleep: as many as the node's
/// ranks may run on together ([`node_cores`]). Only where that is more than its own
/// threads; otherwise, or should the pool not start, on its own threads.
pub fn on_idle_cores<T: Send>(node_ranks: usize, work: impl FnOnce() -> T + Send) -> T {
    let own = rayon::current_num_threads();
    let threads = match borrowing() {
        true => idle_core_threads(own, node_ranks, node_cores()),
        false => own,
    };
    BORROWED_THREADS.fetch_max(threads, Ordering::Relaxed);
    if threads <= own {
        return work();
    }
    match node_pool(threads) {
        Some(pool) => pool.install(work),
        None => work(),
    }
}

/// The most threads [`on_idle_cores`] asked for in this process.
static BORROWED_THREADS: AtomicUsize = AtomicUsize::new(0);

/// The most threads this process's work on its node's idle cores ran on (its own where
/// it borrowed none; 0 before any such work): summary.json's `idle_core_threads`.
pub fn idle_core_threads_used() -> usize {
    BORROWED_THREADS.load(Ordering::Relaxed)
}

/// Threads for the first rank's work alone: its own `own` times the `node_ranks` ranks
/// of its node, within the `cores` they may run on, and never fewer than its own.
fn idle_core_threads(own: usize, node_ranks: usize, cores: usize) -> usize {
    own.saturating_mul(node_ranks).min(cores).max(own)
}

/// Threads the interface system's factorization may use: every core of this node's
/// ranks once it is worth a thread pool (n^3 / 3 flops: 0.36 Gflop, tens of
/// milliseconds, at n = 1024), else one. The other subdomains sleep meanwhile
/// (`dd::step`).
pub fn interface_threads(n_interface: usize) -> usize {
    match (n_interface >= 1024, borrowing()) {
        (true, true) => node_cores(),
        (true, false) => rayon::current_num_threads(),
        (false, _) => 1,
    }
}

/// Set by `--borrow-idle-cores false`: every rank keeps to its own threads and CPUs.
static OWN_CORES_ONLY: AtomicBool = AtomicBool::new(false);

/// From here on, the first rank's work alone runs on its own threads only, not on the
/// cores of its node's sleeping ranks: for studies of that work on one core (e.g.
/// `run-scripts/start_study.py`).
pub fn keep_to_own_cores() {
    OWN_CORES_ONLY.store(true, Ordering::Relaxed);
}

fn borrowing() -> bool {
    !OWN_CORES_ONLY.load(Ordering::Relaxed)
}

/// A set of CPUs: CPU k is bit k % 64 of word k / 64.
pub type CpuWords = Vec<u64>;

/// The CPUs of all the ranks of this node together, gathered once at start-up
/// ([`set_node_cpus`]).
static NODE_CPUS: OnceLock<CpuWords> = OnceLock::new();

/// Words of a [`CpuWords`] set: as many CPUs as the kernel's fixed-size CPU mask.
#[cfg(target_os = "linux")]
pub const CPU_WORDS: usize = libc::CPU_SETSIZE as usize / 64;
#[cfg(not(target_os = "linux"))]
pub const CPU_WORDS: usize = 16;

/// The CPUs this thread may run on ([`CPU_WORDS`] words); none where the system does
/// not tell.
pub fn own_cpus() -> CpuWords {
    let mut words = vec![0; CPU_WORDS];
    #[cfg(target_os = "linux")]
    {
        // SAFETY: cpu_set_t is a plain bit array, zeroed is the empty set; the call
        // writes at most the size it is given.
        let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
        let size = std::mem::size_of::<libc::cpu_set_t>();
        if unsafe { libc::sched_getaffinity(0, size, &mut set) } == 0 {
            for cpu in 0..CPU_WORDS * 64 {
                // SAFETY: cpu is below CPU_SETSIZE.
                if unsafe { libc::CPU_ISSET(cpu, &set) } {
                    words[cpu / 64] |= 1 << (cpu % 64);
                }
            }
        }
    }
    words
}

/// Binds the calling thread to `cpus`; false where the system refuses (e.g. a CPU
/// outside the process's cgroup) or cannot.
fn bind_to(cpus: &[u64]) -> bool {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: as in own_cpus; every cpu set is below CPU_SETSIZE.
        let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
        for cpu in
            (0..cpus.len().min(CPU_WORDS) * 64).filter(|&c| cpus[c / 64] >> (c % 64) & 1 == 1)
        {
            unsafe { libc::CPU_SET(cpu, &mut set) };
        }
        let size = std::mem::size_of::<libc::cpu_set_t>();
        unsafe { libc::sched_setaffinity(0, size, &set) == 0 }
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = cpus;
        false
    }
}

/// The union of the node's ranks' CPU sets, each gathered with [`own_cpus`]: where one
/// rank's threads may run while the node's other ranks sleep. Set once; later calls
/// are ignored.
pub fn set_node_cpus(union: CpuWords) {
    let _ = NODE_CPUS.set(union);
}

fn count(cpus: &[u64]) -> usize {
    cpus.iter().map(|w| w.count_ones() as usize).sum()
}

/// Cores the ranks of this node may run on together: all of the node's under
/// `--bind-to none`, one a rank under `--bind-to core` (Open MPI's default for two
/// ranks); this process's own where the node's are not known.
pub fn node_cores() -> usize {
    match NODE_CPUS.get().map(|c| count(c)) {
        Some(n) if n > 0 => n,
        _ => std::thread::available_parallelism().map_or(1, |n| n.get()),
    }
}

/// A pool of `threads` threads that may run on every CPU of this node's ranks, for
/// work during which the node's other ranks sleep (their cores are idle): a rank bound
/// to its own core (`--bind-to core`) would otherwise crowd them all onto it. The pool's
/// threads take the CPU set of the thread that starts them, so this thread takes the
/// node's for the start and its own back after. None should the pool not start.
pub fn node_pool(threads: usize) -> Option<rayon::ThreadPool> {
    let own = own_cpus();
    let wider = (NODE_CPUS.get().filter(|_| borrowing()))
        .filter(|node| count(&own) > 0 && count(node) > count(&own) && bind_to(node));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
    if wider.is_some() {
        bind_to(&own);
    }
    pool.ok()
}

/// Starts the rank's threads: `threads`, or by default the cores this process may run
/// on over the `node_ranks` ranks of its node (per node, not per job: on a cluster the
/// ranks of other nodes use other cores), for the global pool and faer; with
/// `borrow_idle_cores` false the first rank's work alone keeps to them too
/// ([`keep_to_own_cores`]).
pub fn start_threads(threads: Option<usize>, borrow_idle_cores: bool, node_ranks: usize) {
    if !borrow_idle_cores {
        keep_to_own_cores();
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let threads = threads.unwrap_or((cores / node_ranks).max(1)).max(1);
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
    faer::set_global_parallelism(if threads == 1 {
        faer::Par::Seq
    } else {
        faer::Par::rayon(threads)
    });
}

/// Shares the rank's `threads` among its `per_rank` subdomains: each factorization
/// (faer) gets its share, sequential below two threads.
pub fn share_threads(threads: usize, per_rank: usize) {
    faer::set_global_parallelism(match threads / per_rank {
        0 | 1 => faer::Par::Seq,
        t => faer::Par::rayon(t),
    });
}

/// Runs `member(m, k)` for every `members[k]` on a thread of its own, named `subdomain
/// {first + k + 1}`, and `leader` on this thread; returns when all have ended.
///
/// A rank that cannot start its threads cannot run: the panic ends the job (main's
/// hook) rather than leaving the other subdomains waiting.
pub fn on_subdomain_threads<M: Send, R>(
    members: Vec<M>,
    first: usize,
    member: impl Fn(M) + Sync,
    leader: impl FnOnce() -> R,
) -> R {
    let member = &member;
    std::thread::scope(|scope| {
        for (k, m) in members.into_iter().enumerate() {
            std::thread::Builder::new()
                .name(format!("subdomain {}", first + k + 1))
                .stack_size(SUBDOMAIN_STACK_BYTES)
                .spawn_scoped(scope, move || member(m))
                .expect("cannot start a subdomain thread");
        }
        leader()
    })
}

/// From here on, blocks freed by this process stay in its heap for the next allocations.
///
/// Why: glibc serves each block above its mmap threshold with a fresh mapping and unmaps
/// it on free, so the next large buffer is page-faulted in and zeroed by the kernel again.
/// The VTU encoder copies each array through several nested buffers, which made the
/// output phase mostly page faults. Only the output phase gets this: its buffers are far
/// smaller than the factorization's, so the peak memory per rank does not move, whereas
/// the same setting for the whole run (`GLIBC_TUNABLES=glibc.malloc.mmap_max=0`,
/// docs/performance.md "Memory") raises it.
pub fn keep_freed_blocks_for_reuse() {
    // SAFETY: mallopt only changes glibc's allocation policy; it may be called at any
    // time, and blocks already mapped are still unmapped correctly when freed. A failed
    // call leaves the default policy, which is merely slower.
    #[cfg(target_env = "gnu")]
    unsafe {
        libc::mallopt(libc::M_MMAP_MAX, 0);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}

/// Peak resident memory of this process (VmHWM), 0 where /proc is not available.
pub fn peak_memory_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// Drops `value` on a thread of its own, so that the caller goes on at once: a large
/// factor takes a while to hand back to the system, on the way from the recovery to the
/// output. Should the thread not start, `value` is dropped here.
pub fn drop_in_background<T: Send + 'static>(value: T) {
    let _ = std::thread::Builder::new()
        .name("free".into())
        .spawn(move || drop(value));
}

#[cfg(test)]
mod tests {
    use super::{
        bind_to, idle_core_threads, node_pool, own_cpus, set_node_cpus, subdomains_per_rank,
        CPU_WORDS, MAX_DEFAULT_SUBDOMAINS, MIN_TRIANGLES_PER_SUBDOMAIN,
    };

    /// A rank bound to one CPU starts a pool whose threads run on every CPU of its node
    /// (here: all of this test's), and keeps its own binding.
    #[test]
    fn a_node_pool_runs_on_the_nodes_cpus_and_its_starter_stays_on_its_own() {
        let all = own_cpus();
        let first = (0..CPU_WORDS * 64)
            .find(|&c| all[c / 64] >> (c % 64) & 1 == 1)
            .expect("a CPU to run on");
        set_node_cpus(all.clone());
        let mut one = vec![0; CPU_WORDS];
        one[first / 64] |= 1 << (first % 64);
        assert!(bind_to(&one));
        let pool = node_pool(2).expect("a pool of two threads");
        let inside = pool.install(own_cpus);
        let after = own_cpus();
        bind_to(&all);
        assert_eq!(inside, all);
        assert_eq!(after, one);
    }

    #[test]
    fn a_rank_splits_into_one_subdomain_per_thread_while_they_stay_large_and_few() {
        let m = MIN_TRIANGLES_PER_SUBDOMAIN;
        // A laptop: one rank, its threads, a large mesh.
        assert_eq!(subdomains_per_rank(2, 1, 2_400_000), 2);
        assert_eq!(subdomains_per_rank(4, 1, 2_400_000), 4);
        // Never more than the threads, never fewer than one.
        assert_eq!(subdomains_per_rank(1, 1, 2_400_000), 1);
        assert_eq!(subdomains_per_rank(0, 1, 2_400_000), 1);
        // Small meshes: as many subdomains as keep the threshold each.
        assert_eq!(subdomains_per_rank(8, 1, 3 * m + 1), 3);
        assert_eq!(subdomains_per_rank(8, 2, 3 * m), 1);
        assert_eq!(subdomains_per_rank(8, 1, m - 1), 1);
        // Few subdomains in the whole job: many ranks keep one each.
        assert_eq!(
            subdomains_per_rank(16, 1, 100_000_000),
            MAX_DEFAULT_SUBDOMAINS
        );
        assert_eq!(
            subdomains_per_rank(16, 2, 100_000_000),
            MAX_DEFAULT_SUBDOMAINS / 2
        );
        assert_eq!(subdomains_per_rank(16, 64, 100_000_000), 1);
        assert_eq!(subdomains_per_rank(4, 0, 100_000_000), 4);
    }

    #[test]
    fn the_first_rank_borrows_only_the_cores_of_its_node_it_may_run_on() {
        // Two ranks of one thread on two cores, bound to one each or not: both cores.
        assert_eq!(idle_core_threads(1, 2, 2), 2);
        // One rank told to use one thread: no other rank's cores to borrow.
        assert_eq!(idle_core_threads(1, 1, 2), 1);
        // Two ranks on one core: that core.
        assert_eq!(idle_core_threads(1, 2, 1), 1);
        // More threads than cores asked for: never fewer than its own.
        assert_eq!(idle_core_threads(4, 2, 2), 4);
        // A cluster node of 64 cores with 16 ranks of 4 threads.
        assert_eq!(idle_core_threads(4, 16, 64), 64);
        assert_eq!(idle_core_threads(1, 32, 64), 32);
    }
}
