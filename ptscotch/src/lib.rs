//! A small safe layer over PT-Scotch (Debian's `libptscotch-dev`): a graph whose
//! vertices are spread over the ranks of a communicator in consecutive ranges (rank 0
//! the first range, rank 1 the next, ...), partitioned by all of them at once
//! ([`part`]). No rank holds more of the graph than its own range.
//!
//! Why PT-Scotch: the mesh's partition is the largest piece of the start a run from one
//! mesh file does on one rank, and it grows with the part count (see the project's
//! `docs/cost-model.md`); ParMETIS, the other distributed partitioner, is not packaged
//! by Debian.
//!
//! Every function here is collective over the communicator it is given.

use mpi::ffi::MPI_Comm;
use std::ffi::{c_double, c_int, c_void};
use std::fmt;

/// PT-Scotch's `SCOTCH_Num` in the default Debian library: a C `int`.
pub type Num = i32;

// Opaque: PT-Scotch allocates them itself (`SCOTCH_*Alloc`), so their sizes stay its own.
#[repr(C)]
struct Dgraph {
    _private: [u8; 0],
}
#[repr(C)]
struct Strat {
    _private: [u8; 0],
}
#[repr(C)]
struct Context {
    _private: [u8; 0],
}

#[link(name = "ptscotch")]
extern "C" {
    fn SCOTCH_numSizeof() -> c_int;
    fn SCOTCH_memFree(p: *mut c_void);
    fn SCOTCH_dgraphAlloc() -> *mut Dgraph;
    fn SCOTCH_dgraphInit(g: *mut Dgraph, comm: MPI_Comm) -> c_int;
    fn SCOTCH_dgraphExit(g: *mut Dgraph);
    #[allow(clippy::too_many_arguments)]
    fn SCOTCH_dgraphBuild(
        g: *mut Dgraph,
        baseval: Num,
        vertlocnbr: Num,
        vertlocmax: Num,
        vertloctab: *mut Num,
        vendloctab: *mut Num,
        veloloctab: *mut Num,
        vlblloctab: *mut Num,
        edgelocnbr: Num,
        edgelocsiz: Num,
        edgeloctab: *mut Num,
        edgegsttab: *mut Num,
        edloloctab: *mut Num,
    ) -> c_int;
    fn SCOTCH_dgraphCheck(g: *const Dgraph) -> c_int;
    fn SCOTCH_dgraphPart(g: *mut Dgraph, partnbr: Num, strat: *mut Strat, parts: *mut Num)
        -> c_int;
    fn SCOTCH_contextAlloc() -> *mut Context;
    fn SCOTCH_contextInit(c: *mut Context) -> c_int;
    fn SCOTCH_contextExit(c: *mut Context);
    fn SCOTCH_contextOptionSetNum(c: *mut Context, option: c_int, value: Num) -> c_int;
    fn SCOTCH_contextRandomReset(c: *mut Context);
    fn SCOTCH_contextThreadSpawn(c: *mut Context, threads: c_int, cores: *const c_int) -> c_int;
    fn SCOTCH_contextBindDgraph(c: *mut Context, org: *const Dgraph, bound: *mut Dgraph) -> c_int;
    fn SCOTCH_stratAlloc() -> *mut Strat;
    fn SCOTCH_stratInit(s: *mut Strat) -> c_int;
    fn SCOTCH_stratExit(s: *mut Strat);
    fn SCOTCH_stratDgraphMapBuild(
        s: *mut Strat,
        flags: Num,
        procnbr: Num,
        partnbr: Num,
        balrat: c_double,
    ) -> c_int;
}

/// `SCOTCH_OPTIONNUMDETERMINISTIC` and `SCOTCH_OPTIONNUMRANDOMFIXEDSEED`.
const OPTION_DETERMINISTIC: c_int = 0;
const OPTION_FIXED_SEED: c_int = 1;

/// `SCOTCH_STRATQUALITY`: PT-Scotch's better-cut strategy. Against `SCOTCH_STRATSPEED`
/// on a 2M-triangle dual graph on 2 ranks, into 64 and 512 parts: 1% and 0.6% fewer
/// interface nodes for 0.6 s and 1.0 s more; the interface is the critical path of a
/// run on many ranks and its factor grows faster than its size.
const STRAT_QUALITY: Num = 0x1;

/// A failed PT-Scotch call (PT-Scotch prints its own detail on stderr).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ScotchError {
    /// The library's `SCOTCH_Num` is not the 32-bit `int` this layer declares.
    NumSize(usize),
    /// A graph larger than `SCOTCH_Num` can count.
    TooLarge,
    /// `function` returned a non-zero status.
    Call(&'static str),
}

impl fmt::Display for ScotchError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScotchError::NumSize(b) => write!(
                f,
                "the PT-Scotch library counts with {b}-byte integers, this build expects 4 (Debian's default libptscotch)"
            ),
            ScotchError::TooLarge => write!(f, "the graph is too large for 32-bit PT-Scotch"),
            ScotchError::Call(name) => write!(f, "PT-Scotch's {name} failed"),
        }
    }
}

impl std::error::Error for ScotchError {}

/// One rank's range of a distributed graph in CSR form: the neighbours of its `i`-th
/// vertex are `adjncy[xadj[i]..xadj[i + 1]]`, in the graph's global numbering (rank
/// `r`'s vertices follow those of ranks `0..r`), with optional edge weights (same
/// positions) and vertex weights. `xadj[0] == 0`.
#[derive(Debug, Clone, Copy)]
pub struct LocalGraph<'a> {
    pub xadj: &'a [Num],
    pub adjncy: &'a [Num],
    pub adjwgt: Option<&'a [Num]>,
    pub vwgt: Option<&'a [Num]>,
}

/// Frees what PT-Scotch allocated, on every path out of [`part`].
struct Owned {
    graph: *mut Dgraph,
    graph_ready: bool,
    strat: *mut Strat,
    strat_ready: bool,
    context: *mut Context,
    context_ready: bool,
    bound: *mut Dgraph,
    bound_ready: bool,
}

impl Drop for Owned {
    fn drop(&mut self) {
        // SAFETY: each pointer came from its `SCOTCH_*Alloc` and is exited only if its
        // init succeeded, then freed once.
        unsafe {
            if self.bound_ready {
                SCOTCH_dgraphExit(self.bound);
            }
            if !self.bound.is_null() {
                SCOTCH_memFree(self.bound.cast());
            }
            if self.context_ready {
                SCOTCH_contextExit(self.context);
            }
            if !self.context.is_null() {
                SCOTCH_memFree(self.context.cast());
            }
            if self.strat_ready {
                SCOTCH_stratExit(self.strat);
            }
            if !self.strat.is_null() {
                SCOTCH_memFree(self.strat.cast());
            }
            if self.graph_ready {
                SCOTCH_dgraphExit(self.graph);
            }
            if !self.graph.is_null() {
                SCOTCH_memFree(self.graph.cast());
            }
        }
    }
}

/// Partitions the graph spread over `comm` into `nparts` parts of equal vertex weight
/// within `imbalance` (0.03: 3%), minimising the weight of the cut edges. Returns this
/// rank's vertices' parts. Collective over `comm`; `procs` is its size.
///
/// PT-Scotch runs in a context of its own with its deterministic option, a fixed, reset
/// random seed and one thread: the same graph spread the same way gives the same parts
/// run after run (without them, its threads and the order messages arrive in relabel
/// the parts). One thread, because a rank is one core of the job: Debian's library
/// otherwise starts a thread per core of the node on every rank, and on ranks that share
/// a node unbound (`--bind-to none`) the cut took 13 times as long (4.4 s against
/// 0.34 s on 2 ranks, 2M triangles).
///
/// # Errors
/// [`ScotchError`]; every rank sees a failure of a collective call.
///
/// # Panics
/// If the CSR arrays are inconsistent (`xadj` not starting at 0 or not ending at
/// `adjncy.len()`, weights of the wrong length).
pub fn part(
    comm: MPI_Comm,
    procs: usize,
    graph: LocalGraph<'_>,
    nparts: usize,
    imbalance: f64,
) -> Result<Vec<Num>, ScotchError> {
    let n = graph.xadj.len() - 1;
    assert_eq!(graph.xadj[0], 0);
    assert_eq!(graph.xadj[n] as usize, graph.adjncy.len());
    if let Some(w) = graph.adjwgt {
        assert_eq!(w.len(), graph.adjncy.len());
    }
    if let Some(w) = graph.vwgt {
        assert_eq!(w.len(), n);
    }
    // SAFETY: no arguments.
    let num = unsafe { SCOTCH_numSizeof() } as usize;
    if num != std::mem::size_of::<Num>() {
        return Err(ScotchError::NumSize(num));
    }
    let count = |v: usize| Num::try_from(v).map_err(|_| ScotchError::TooLarge);
    let (vert, edges, nparts_n, procs_n) = (
        count(n)?,
        count(graph.adjncy.len())?,
        count(nparts)?,
        count(procs)?,
    );
    // PT-Scotch's build takes mutable pointers but only reads them (it keeps them, so
    // they live until the graph is exited below): copies keep the caller's slices
    // untouched under that contract.
    let mut xadj = graph.xadj.to_vec();
    let mut adjncy = graph.adjncy.to_vec();
    let mut adjwgt = graph.adjwgt.map(<[Num]>::to_vec);
    let mut vwgt = graph.vwgt.map(<[Num]>::to_vec);
    let mut parts = vec![0 as Num; n.max(1)];
    let opt =
        |v: &mut Option<Vec<Num>>| v.as_mut().map_or(std::ptr::null_mut(), |v| v.as_mut_ptr());

    // SAFETY: the allocations are checked before use and released by `Owned`; the
    // arrays outlive the graph (declared before `owned`, so dropped after it).
    unsafe {
        let mut owned = Owned {
            graph: SCOTCH_dgraphAlloc(),
            graph_ready: false,
            strat: SCOTCH_stratAlloc(),
            strat_ready: false,
            context: SCOTCH_contextAlloc(),
            context_ready: false,
            bound: SCOTCH_dgraphAlloc(),
            bound_ready: false,
        };
        if owned.graph.is_null()
            || owned.strat.is_null()
            || owned.context.is_null()
            || owned.bound.is_null()
        {
            return Err(ScotchError::Call("allocation"));
        }
        if SCOTCH_dgraphInit(owned.graph, comm) != 0 {
            return Err(ScotchError::Call("SCOTCH_dgraphInit"));
        }
        owned.graph_ready = true;
        let status = SCOTCH_dgraphBuild(
            owned.graph,
            0,
            vert,
            vert,
            xadj.as_mut_ptr(),
            xadj.as_mut_ptr().add(1),
            opt(&mut vwgt),
            std::ptr::null_mut(),
            edges,
            edges,
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            opt(&mut adjwgt),
        );
        if status != 0 {
            return Err(ScotchError::Call("SCOTCH_dgraphBuild"));
        }
        if cfg!(debug_assertions) && SCOTCH_dgraphCheck(owned.graph) != 0 {
            return Err(ScotchError::Call("SCOTCH_dgraphCheck"));
        }
        if SCOTCH_contextInit(owned.context) != 0 {
            return Err(ScotchError::Call("SCOTCH_contextInit"));
        }
        owned.context_ready = true;
        if SCOTCH_contextOptionSetNum(owned.context, OPTION_DETERMINISTIC, 1) != 0
            || SCOTCH_contextOptionSetNum(owned.context, OPTION_FIXED_SEED, 1) != 0
        {
            return Err(ScotchError::Call("SCOTCH_contextOptionSetNum"));
        }
        if SCOTCH_contextThreadSpawn(owned.context, 1, std::ptr::null()) != 0 {
            return Err(ScotchError::Call("SCOTCH_contextThreadSpawn"));
        }
        SCOTCH_contextRandomReset(owned.context);
        if SCOTCH_contextBindDgraph(owned.context, owned.graph, owned.bound) != 0 {
            return Err(ScotchError::Call("SCOTCH_contextBindDgraph"));
        }
        owned.bound_ready = true;
        if SCOTCH_stratInit(owned.strat) != 0 {
            return Err(ScotchError::Call("SCOTCH_stratInit"));
        }
        owned.strat_ready = true;
        if SCOTCH_stratDgraphMapBuild(owned.strat, STRAT_QUALITY, procs_n, nparts_n, imbalance) != 0
        {
            return Err(ScotchError::Call("SCOTCH_stratDgraphMapBuild"));
        }
        if SCOTCH_dgraphPart(owned.bound, nparts_n, owned.strat, parts.as_mut_ptr()) != 0 {
            return Err(ScotchError::Call("SCOTCH_dgraphPart"));
        }
        drop(owned);
    }
    parts.truncate(n);
    Ok(parts)
}
