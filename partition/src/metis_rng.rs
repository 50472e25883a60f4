//! A random number generator of its own for every thread inside METIS.
//!
//! Debian's METIS draws its random numbers from libc's `rand()`, seeded by `srand()` at
//! the start of every call: one generator for the whole process. Two threads ordering
//! their subdomains at once would take numbers from each other's sequence, and the
//! orderings (so the factors, so the round-off of the answer) would depend on timing;
//! hence a lock around every METIS call, which made the orderings of the subdomains of
//! one rank run one after the other.
//!
//! This module defines `rand` and `srand` in the executable. The linker exports them
//! because libmetis, a shared library on the link line, refers to them, and the
//! dynamic linker then binds libmetis's calls to these definitions before libc's. On a
//! thread inside a METIS call ([`Private`]) they run glibc's own generator (the additive
//! feedback generator of `random()`, TYPE_3: the same numbers as glibc for the same
//! seed, so the parts and orderings are those of a plain METIS run) on a state of that
//! thread; on any other thread, or outside METIS, they are glibc's `rand` and `srand`
//! (which are `random()` and `srandom()`), so no other code sees a change.
//!
//! [`is_private`] says whether the binding took effect (a linker that did not export
//! the symbols, a static libc); when it did not, callers keep the process-wide lock.

use std::cell::{Cell, RefCell};
use std::os::raw::{c_int, c_uint};

/// Degree and separation of glibc's TYPE_3 generator (the state of `random()` when
/// nothing chose another): x[i] = x[i - 31] + x[i - 3] mod 2^32, output x[i] >> 1.
const DEGREE: usize = 31;
const SEPARATION: usize = 3;

/// glibc's generator, state for state: `srandom_r` and `random_r` of `stdlib/random_r.c`.
pub(crate) struct Glibc {
    state: [i32; DEGREE],
    front: usize,
    rear: usize,
}

impl Glibc {
    pub(crate) fn new(seed: u32) -> Self {
        // Zero would give a state of zeros; glibc takes 1 instead.
        let seed = if seed == 0 { 1 } else { seed };
        let mut state = [0i32; DEGREE];
        state[0] = seed as i32;
        let mut word = seed as i32 as i64;
        for s in state.iter_mut().skip(1) {
            // 16807 * word mod (2^31 - 1) without overflow (Schrage), as glibc does it.
            let (hi, lo) = (word / 127_773, word % 127_773);
            word = 16_807 * lo - 2_836 * hi;
            if word < 0 {
                word += 2_147_483_647;
            }
            *s = word as i32;
        }
        let mut g = Glibc {
            state,
            front: SEPARATION,
            rear: 0,
        };
        // glibc discards the first 10 * 31 outputs: the linear seeding shows in them.
        for _ in 0..10 * DEGREE {
            g.next();
        }
        g
    }

    pub(crate) fn next(&mut self) -> i32 {
        let sum = self.state[self.front].wrapping_add(self.state[self.rear]);
        self.state[self.front] = sum;
        self.front += 1;
        self.rear += 1;
        if self.front == DEGREE {
            self.front = 0;
        } else if self.rear == DEGREE {
            self.rear = 0;
        }
        ((sum as u32) >> 1) as i32
    }
}

extern "C" {
    // glibc's own generator behind its rand() and srand(); the libc crate does not bind it.
    fn random() -> std::os::raw::c_long;
    fn srandom(seed: c_uint);
}

thread_local! {
    /// Set while this thread is inside a METIS call.
    static INSIDE: Cell<bool> = const { Cell::new(false) };
    static GENERATOR: RefCell<Glibc> = RefCell::new(Glibc::new(1));
}

/// libc's `rand`, as libmetis sees it (see the module's documentation).
#[no_mangle]
pub extern "C" fn rand() -> c_int {
    if INSIDE.with(Cell::get) {
        GENERATOR.with(|g| g.borrow_mut().next())
    } else {
        // glibc's rand() is (int) random().
        // SAFETY: random() has no preconditions.
        unsafe { random() as c_int }
    }
}

/// libc's `srand`, as libmetis sees it (see the module's documentation).
#[no_mangle]
pub extern "C" fn srand(seed: c_uint) {
    if INSIDE.with(Cell::get) {
        GENERATOR.with(|g| *g.borrow_mut() = Glibc::new(seed));
    } else {
        // SAFETY: srandom() has no preconditions.
        unsafe { srandom(seed) }
    }
}

/// While alive, this thread's METIS calls draw from this thread's own generator.
pub(crate) struct Private {
    was_inside: bool,
}

impl Private {
    pub(crate) fn enter() -> Self {
        Private {
            was_inside: INSIDE.with(|i| i.replace(true)),
        }
    }
}

impl Drop for Private {
    fn drop(&mut self) {
        INSIDE.with(|i| i.set(self.was_inside));
    }
}

/// Whether libmetis's `rand` and `srand` are the ones above: the dynamic linker's
/// global lookup of each name finds this module's function.
pub fn is_private() -> bool {
    use std::sync::OnceLock;
    static BOUND: OnceLock<bool> = OnceLock::new();
    *BOUND.get_or_init(|| {
        let found = |name: &std::ffi::CStr| {
            // SAFETY: dlsym with RTLD_DEFAULT and a NUL-terminated name only looks up.
            unsafe { libc::dlsym(libc::RTLD_DEFAULT, name.as_ptr()) as usize }
        };
        found(c"rand") == rand as *const () as usize
            && found(c"srand") == srand as *const () as usize
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::raw::c_char;

    /// glibc's `struct random_data`, for its reentrant generator: the reference.
    #[repr(C)]
    struct RandomData {
        fptr: *mut i32,
        rptr: *mut i32,
        state: *mut i32,
        rand_type: c_int,
        rand_deg: c_int,
        rand_sep: c_int,
        end_ptr: *mut i32,
    }

    extern "C" {
        fn initstate_r(
            seed: c_uint,
            statebuf: *mut c_char,
            statelen: usize,
            buf: *mut RandomData,
        ) -> c_int;
        fn random_r(buf: *mut RandomData, result: *mut i32) -> c_int;
    }

    fn glibc_sequence(seed: u32, n: usize) -> Vec<i32> {
        // 128 bytes of state select TYPE_3, the type of random()'s default state.
        let mut statebuf = [0 as c_char; 128];
        // SAFETY: glibc requires a zeroed random_data; all fields are plain data.
        let mut data: RandomData = unsafe { std::mem::zeroed() };
        let mut out = Vec::with_capacity(n);
        // SAFETY: statebuf and data outlive every call and are used by this thread only.
        unsafe {
            assert_eq!(initstate_r(seed, statebuf.as_mut_ptr(), 128, &mut data), 0);
            for _ in 0..n {
                let mut r = 0i32;
                assert_eq!(random_r(&mut data, &mut r), 0);
                out.push(r);
            }
        }
        out
    }

    #[test]
    fn same_numbers_as_glibc_for_any_seed() {
        for seed in [0u32, 1, 2, 4321, 123_456_789, i32::MAX as u32, u32::MAX] {
            let mut g = Glibc::new(seed);
            let ours: Vec<i32> = (0..1000).map(|_| g.next()).collect();
            assert_eq!(ours, glibc_sequence(seed, 1000), "seed {seed}");
        }
    }

    #[test]
    fn outside_metis_rand_is_libcs() {
        // The same thread, the same seed: libc's random() and our rand() agree.
        srand(77);
        let ours: Vec<c_int> = (0..5).map(|_| rand()).collect();
        // SAFETY: srandom and random have no preconditions.
        let libcs: Vec<c_int> = unsafe {
            srandom(77);
            (0..5).map(|_| random() as c_int).collect()
        };
        assert_eq!(ours, libcs);
    }

    #[test]
    fn inside_metis_each_thread_has_its_own_sequence() {
        let run = || {
            let _p = Private::enter();
            srand(4321);
            let mut v = Vec::new();
            for _ in 0..2000 {
                v.push(rand());
                std::thread::yield_now();
            }
            v
        };
        let alone = run();
        let together: Vec<Vec<c_int>> = std::thread::scope(|s| {
            let hs: Vec<_> = (0..4).map(|_| s.spawn(run)).collect();
            hs.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for v in together {
            assert_eq!(v, alone);
        }
        let mut g = Glibc::new(4321);
        assert!(alone[..3].iter().all(|&r| r == g.next()));
    }

    #[test]
    fn libmetis_is_bound_to_these_functions() {
        assert!(
            is_private(),
            "the test binary does not export rand/srand: METIS calls stay serialized"
        );
    }
}
