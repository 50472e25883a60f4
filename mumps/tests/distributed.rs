//! The distributed factor and solve on 1, 2, 3 and 4 ranks: a matrix assembled from
//! pieces spread over the ranks (each edge of a grid Laplacian on one rank, the diagonal
//! shift split between ranks, so that MUMPS must sum entries across ranks), a
//! right-hand side spread the same way, against the known solution.
//!
//! The test binary runs itself under `mpirun` (`--oversubscribe`; as root, set
//! OMPI_ALLOW_RUN_AS_ROOT=1 and OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1); each rank then runs
//! [`child`] only.

use mpi::collective::SystemOperation;
use mpi::topology::Communicator;
use mpi::traits::*;
use std::process::Command;

const CHILD: &str = "MUMPS_TEST_CHILD";
/// A k x k grid: n = k^2 unknowns.
const K: usize = 30;

fn exact(i: usize) -> f64 {
    (0.37 * i as f64).sin() + 0.1 * (i % 7) as f64
}

/// The pieces of A on rank `rank` of `size`: every grid edge (i, j) adds [1 -1; -1 1],
/// the edges dealt round-robin; every node adds 0.05 to its diagonal, half of it on
/// its edge's rank and half on the next rank.
fn pieces(rank: usize, size: usize) -> Vec<(usize, usize, f64)> {
    let id = |x: usize, y: usize| y * K + x;
    let mut edges = Vec::new();
    for y in 0..K {
        for x in 0..K {
            if x + 1 < K {
                edges.push((id(x, y), id(x + 1, y)));
            }
            if y + 1 < K {
                edges.push((id(x, y), id(x, y + 1)));
            }
        }
    }
    let mut mine = Vec::new();
    for (e, &(i, j)) in edges.iter().enumerate() {
        if e % size == rank {
            mine.extend([(i, i, 1.0), (j, j, 1.0), (i, j, -1.0)]);
        }
    }
    for i in 0..K * K {
        if i % size == rank {
            mine.push((i, i, 0.025));
        }
        if (i + 1) % size == rank {
            mine.push((i, i, 0.025));
        }
    }
    mine
}

/// A x over all pieces (every rank can form it: the test matrix is small).
fn apply(x: &[f64], size: usize) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    for r in 0..size {
        for (i, j, v) in pieces(r, size) {
            y[i] += v * x[j];
            if i != j {
                y[j] += v * x[i];
            }
        }
    }
    y
}

fn child() {
    let universe = mpi::initialize().expect("MPI");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    // SAFETY: the world communicator is valid while `universe` lives.
    let comm = unsafe { mpi::ffi::MPI_Comm_c2f(world.as_raw()) };
    let n = K * K;
    let mut factor = mumps::SpdFactor::new(comm, n, &pieces(rank, size)).expect("factor");
    assert_eq!(factor.order(), n);
    assert!(factor.total_flops() > 0.0 && factor.local_flops() >= 0.0);
    let x: Vec<f64> = (0..n).map(exact).collect();
    let b = apply(&x, size);
    // The right-hand side in two halves on different ranks, summed by MUMPS.
    let mut rows = Vec::new();
    for i in 0..n {
        for owner in [i % size, (i + 1) % size] {
            if owner == rank {
                rows.push(i);
            }
        }
    }
    let values: Vec<f64> = rows.iter().map(|&i| 0.5 * b[i]).collect();
    for _ in 0..2 {
        let (sol_rows, sol) = factor.solve(&rows, &values).expect("solve");
        for (&i, &v) in sol_rows.iter().zip(sol) {
            assert!((v - x[i]).abs() <= 1e-9, "row {i}: {v} against {}", x[i]);
        }
        let mut count = 0u64;
        world.all_reduce_into(&(sol_rows.len() as u64), &mut count, SystemOperation::sum());
        assert_eq!(count as usize, n, "every row once over the ranks");
    }
    // A wrong matrix is an error, not an abort: singular.
    let singular: Vec<(usize, usize, f64)> = if rank == 0 {
        vec![
            (0, 0, 1.0),
            (1, 1, 1.0),
            (0, 1, 1.0),
            (2, 2, 0.0),
            (3, 3, 2.0),
        ]
    } else {
        Vec::new()
    };
    let err = mumps::SpdFactor::new(comm, 4, &singular)
        .err()
        .expect("an error");
    assert!(err.infog1 < 0, "{err}");
    assert!(err.to_string().starts_with("MUMPS factorization failed"));
}

#[test]
fn distributed_spd_factor_and_solve_on_1_to_4_ranks() {
    if std::env::var(CHILD).is_ok() {
        child();
        return;
    }
    let me = std::env::current_exe().unwrap();
    // A session directory of its own: Open MPI's shared one races with other mpiruns.
    let tmp = std::env::temp_dir().join(format!("mumps-test-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    for np in 1..=4 {
        let out = Command::new("mpirun")
            .env("TMPDIR", &tmp)
            .args(["-n", &np.to_string(), "--oversubscribe"])
            .arg(&me)
            .args([
                "--exact",
                "distributed_spd_factor_and_solve_on_1_to_4_ranks",
                "--nocapture",
                "--test-threads",
                "1",
            ])
            .env(CHILD, "1")
            .output()
            .expect("mpirun");
        assert!(
            out.status.success(),
            "{np} ranks: {}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let _ = std::fs::remove_dir_all(&tmp);
}
