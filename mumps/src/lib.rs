//! A small safe layer over MUMPS (double precision, Debian's `libmumps-dev`): a
//! symmetric positive definite matrix given as entries spread over the ranks of a
//! communicator (each rank its own, repeated entries summed), factored once in parallel,
//! then solved any number of times with the right-hand side and the solution both
//! distributed: no rank ever holds the whole matrix, right-hand side or solution.
//!
//! MPI stays outside: the communicator crosses as its Fortran handle
//! (`MPI_Comm_c2f` of the caller's communicator), which is what MUMPS keeps.
//! Every call that takes a `&mut self` or builds a factor is collective over that
//! communicator.

use std::fmt;

#[allow(
    non_camel_case_types,
    non_snake_case,
    non_upper_case_globals,
    dead_code,
    clippy::all
)]
mod ffi {
    include!(concat!(env!("OUT_DIR"), "/bindings.rs"));
}

/// MUMPS's JOB codes.
const JOB_INIT: i32 = -1;
const JOB_END: i32 = -2;
const JOB_ANALYSE: i32 = 1;
const JOB_FACTOR: i32 = 2;
const JOB_SOLVE: i32 = 3;

/// A failed MUMPS phase, with MUMPS's own error code (INFOG(1) < 0) and its detail
/// (INFOG(2)).
/// INFOG(1) values that say a work array or buffer was estimated too small.
fn is_short_of_room(infog1: i32) -> bool {
    matches!(infog1, -8 | -9 | -14 | -15 | -17 | -20)
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MumpsError {
    pub phase: &'static str,
    pub infog1: i32,
    pub infog2: i32,
}

impl fmt::Display for MumpsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let hint = match self.infog1 {
            -5 | -7 | -13 => "out of memory",
            -8 | -9 | -14 | -15 | -17 | -20 => {
                "a work array was too small, even 320% above MUMPS's estimate"
            }
            -10 => "the matrix is singular",
            -6 => "the matrix is structurally singular",
            -40 => "the matrix is not positive definite",
            -16 => "the order n is out of range",
            -22 => "an array given to MUMPS is wrong",
            _ => "see the MUMPS user guide, error diagnostics",
        };
        write!(
            f,
            "MUMPS {} failed: INFOG(1) = {}, INFOG(2) = {} ({hint})",
            self.phase, self.infog1, self.infog2
        )
    }
}

impl std::error::Error for MumpsError {}

/// The factor of a symmetric positive definite matrix of order n, distributed over the
/// ranks of the communicator it was built on.
pub struct SpdFactor {
    id: Box<ffi::DMUMPS_STRUC_C>,
    /// Whether JOB = -1 succeeded: only then is there an instance to end.
    live: bool,
    n: usize,
    // The arrays MUMPS was handed, kept alive as long as the instance.
    irn: Vec<i32>,
    jcn: Vec<i32>,
    a: Vec<f64>,
    sol: Vec<f64>,
    isol: Vec<i32>,
    rhs: Vec<f64>,
    irhs: Vec<i32>,
}

impl SpdFactor {
    /// Analyses and factors the matrix whose entries this rank holds: `(i, j, v)` with
    /// 0-based global indices, i <= j (the upper triangle; an entry below it is mirrored),
    /// repeated entries (on one rank or several) summed. Collective over `comm`, the
    /// Fortran handle of the communicator.
    pub fn new(comm: i32, n: usize, entries: &[(usize, usize, f64)]) -> Result<Self, MumpsError> {
        let order = i32::try_from(n).map_err(|_| MumpsError {
            phase: "setup",
            infog1: -16,
            infog2: i32::MAX,
        })?;
        let mut irn = Vec::with_capacity(entries.len());
        let mut jcn = Vec::with_capacity(entries.len());
        let mut a = Vec::with_capacity(entries.len());
        for &(i, j, v) in entries {
            let (i, j) = if i <= j { (i, j) } else { (j, i) };
            // MUMPS counts from 1.
            irn.push(i as i32 + 1);
            jcn.push(j as i32 + 1);
            a.push(v);
        }
        // SAFETY: DMUMPS_STRUC_C is plain data (ints, floats, pointers, char arrays);
        // all zeros is a valid value, and JOB = -1 fills in the defaults.
        let id: Box<ffi::DMUMPS_STRUC_C> = Box::new(unsafe { std::mem::zeroed() });
        let mut f = SpdFactor {
            id,
            live: false,
            n,
            irn,
            jcn,
            a,
            sol: Vec::new(),
            isol: Vec::new(),
            rhs: Vec::new(),
            irhs: Vec::new(),
        };
        f.id.comm_fortran = comm;
        // Symmetric positive definite; the first rank works as well as coordinates.
        f.id.sym = 1;
        f.id.par = 1;
        f.call(JOB_INIT, "initialisation")?;
        f.live = true;
        f.quiet();
        // Distributed assembled input (ICNTL(18) = 3), distributed solution (ICNTL(21) = 1).
        f.set_icntl(18, 3);
        f.set_icntl(21, 1);
        f.id.n = order;
        f.id.nz_loc = f.a.len() as i32;
        f.id.nnz_loc = f.a.len() as i64;
        f.id.irn_loc = f.irn.as_mut_ptr();
        f.id.jcn_loc = f.jcn.as_mut_ptr();
        f.id.a_loc = f.a.as_mut_ptr();
        f.call(JOB_ANALYSE, "analysis")?;
        f.factor_with_room()?;
        // INFO(23): the solution entries this rank will hold.
        let local = f.id.info[22].max(0) as usize;
        f.sol = vec![0.0; local.max(1)];
        f.isol = vec![0; local.max(1)];
        Ok(f)
    }

    /// The order of the matrix.
    pub fn order(&self) -> usize {
        self.n
    }

    /// Solves A x = b, b given by the entries this rank holds (`rows` 0-based, values
    /// summed where a row appears more than once, also across ranks). Returns the
    /// solution entries MUMPS leaves on this rank: its rows (0-based) and values; over
    /// all ranks, every row once. Collective.
    pub fn solve(
        &mut self,
        rows: &[usize],
        values: &[f64],
    ) -> Result<(Vec<usize>, &[f64]), MumpsError> {
        assert_eq!(
            rows.len(),
            values.len(),
            "solve: rows and values differ in length"
        );
        self.irhs.clear();
        self.irhs.extend(rows.iter().map(|&r| r as i32 + 1));
        self.rhs.clear();
        self.rhs.extend_from_slice(values);
        // Non-null pointers even when this rank holds no entry.
        if self.rhs.is_empty() {
            self.rhs.push(0.0);
            self.irhs.push(1);
        }
        // Distributed dense right-hand side (ICNTL(20) = 10).
        self.set_icntl(20, 10);
        self.id.nrhs = 1;
        self.id.nloc_rhs = rows.len() as i32;
        self.id.lrhs_loc = rows.len().max(1) as i32;
        self.id.rhs_loc = self.rhs.as_mut_ptr();
        self.id.irhs_loc = self.irhs.as_mut_ptr();
        self.id.sol_loc = self.sol.as_mut_ptr();
        self.id.isol_loc = self.isol.as_mut_ptr();
        self.id.lsol_loc = self.sol.len() as i32;
        self.call(JOB_SOLVE, "solve")?;
        let local = self.id.info[22].max(0) as usize;
        let rows = self.isol[..local].iter().map(|&r| r as usize - 1).collect();
        Ok((rows, &self.sol[..local]))
    }

    /// This rank's floating-point operations in the factorization (RINFO(3)).
    pub fn local_flops(&self) -> f64 {
        self.id.rinfo[2]
    }

    /// All ranks' floating-point operations in the factorization (RINFOG(3)).
    pub fn total_flops(&self) -> f64 {
        self.id.rinfog[2]
    }

    /// Entries in the factor over all ranks (INFOG(29)).
    pub fn factor_entries(&self) -> f64 {
        self.id.infog[28] as f64
    }

    /// Every rank prints nothing: errors come back as [`MumpsError`].
    fn quiet(&mut self) {
        for (k, v) in [(1, -1), (2, -1), (3, -1), (4, 0)] {
            self.set_icntl(k, v);
        }
    }

    /// The factorization, retried with more room where MUMPS's estimate of its work
    /// arrays fell short (it can, in parallel: INFOG(1) -8, -9, -14, -15, -17 or -20),
    /// doubling ICNTL(14), the percentage added to the estimate, from 20 up to 320.
    /// Every rank sees the same INFOG(1), so all retry together. Seen: -9 on the
    /// interface system of hertz level 5 on 64 ranks ordered by QAMD, factored on the
    /// first retry.
    fn factor_with_room(&mut self) -> Result<(), MumpsError> {
        let mut extra = self.id.icntl[13].max(20);
        loop {
            self.set_icntl(14, extra);
            match self.call(JOB_FACTOR, "factorization") {
                Err(e) if is_short_of_room(e.infog1) && extra < 16 * 20 => extra *= 2,
                done => return done,
            }
        }
    }

    /// ICNTL(k), counted from 1 as in the MUMPS user guide.
    fn set_icntl(&mut self, k: usize, v: i32) {
        self.id.icntl[k - 1] = v;
    }

    fn call(&mut self, job: i32, phase: &'static str) -> Result<(), MumpsError> {
        self.id.job = job;
        // SAFETY: `id` was initialised by JOB = -1 (or is being), and every pointer in
        // it points into a buffer this struct owns, sized as the struct says.
        unsafe { ffi::dmumps_c(&mut *self.id) };
        match self.id.infog[0] {
            e if e < 0 => Err(MumpsError {
                phase,
                infog1: e,
                infog2: self.id.infog[1],
            }),
            _ => Ok(()),
        }
    }
}

/// Collective, like every MUMPS call: every rank drops its factor at the same point.
impl Drop for SpdFactor {
    fn drop(&mut self) {
        if !self.live {
            return;
        }
        self.id.job = JOB_END;
        // SAFETY: as in `call`; JOB = -2 frees MUMPS's own storage of this instance.
        unsafe { ffi::dmumps_c(&mut *self.id) };
    }
}
