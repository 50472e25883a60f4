//! The distributed partition on 1, 2, 3 and 4 ranks: a k x k grid graph spread over the
//! ranks in consecutive ranges, cut into parts that must be balanced, cheap (close to
//! the straight cuts a grid allows) and the same run after run.
//!
//! The test binary runs itself under `mpirun` (`--oversubscribe`; as root, set
//! OMPI_ALLOW_RUN_AS_ROOT=1 and OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1); each rank then runs
//! [`child`] only.

use mpi::topology::Communicator;
use mpi::traits::*;
use ptscotch::{LocalGraph, Num};
use std::process::Command;

const CHILD: &str = "PTSCOTCH_TEST_CHILD";
const K: usize = 60;

/// Rank `rank`'s consecutive range of the K x K grid's vertices (row by row).
fn range(rank: usize, size: usize) -> std::ops::Range<usize> {
    let n = K * K;
    rank * n / size..(rank + 1) * n / size
}

/// The CSR rows of the vertices in `r`, with edge weight 2 along x and 1 along y.
fn rows(r: std::ops::Range<usize>) -> (Vec<Num>, Vec<Num>, Vec<Num>) {
    let (mut xadj, mut adj, mut w) = (vec![0], Vec::new(), Vec::new());
    for v in r {
        let (x, y) = (v % K, v / K);
        if x > 0 {
            adj.push(v as Num - 1);
            w.push(2);
        }
        if x + 1 < K {
            adj.push(v as Num + 1);
            w.push(2);
        }
        if y > 0 {
            adj.push((v - K) as Num);
            w.push(1);
        }
        if y + 1 < K {
            adj.push((v + K) as Num);
            w.push(1);
        }
        xadj.push(adj.len() as Num);
    }
    (xadj, adj, w)
}

fn child() {
    let universe = mpi::initialize().expect("MPI");
    let world = universe.world();
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let mine = range(rank, size);
    let (xadj, adjncy, adjwgt) = rows(mine.clone());
    let graph = LocalGraph {
        xadj: &xadj,
        adjncy: &adjncy,
        adjwgt: Some(&adjwgt),
        vwgt: None,
    };
    for nparts in [1usize, 2, 7] {
        let parts = ptscotch::part(world.as_raw(), size, graph, nparts, 0.03).expect("part");
        assert_eq!(parts.len(), mine.len());
        let again = ptscotch::part(world.as_raw(), size, graph, nparts, 0.03).expect("part");
        assert_eq!(
            parts, again,
            "{nparts} parts: the same graph, the same parts"
        );
        // Every rank checks the whole: gathered on all (the grid is small).
        let mut all = vec![0 as Num; K * K];
        let counts: Vec<Num> = (0..size).map(|r| range(r, size).len() as Num).collect();
        let displs: Vec<Num> = (0..size).map(|r| range(r, size).start as Num).collect();
        {
            let mut buf = mpi::datatype::PartitionMut::new(&mut all[..], counts, displs);
            world.all_gather_varcount_into(&parts[..], &mut buf);
        }
        let mut sizes = vec![0usize; nparts];
        for &p in &all {
            assert!((0..nparts as Num).contains(&p), "part {p} of {nparts}");
            sizes[p as usize] += 1;
        }
        let most = (1.03 * (K * K) as f64 / nparts as f64).ceil() as usize + 1;
        assert!(
            sizes.iter().all(|&s| s > 0 && s <= most),
            "{nparts} parts: {sizes:?}"
        );
        let (x2, a2, w2) = rows(0..K * K);
        let mut cut = 0;
        for v in 0..K * K {
            for k in x2[v] as usize..x2[v + 1] as usize {
                if all[v] != all[a2[k] as usize] {
                    cut += w2[k];
                }
            }
        }
        cut /= 2;
        // A straight cut across the grid's y edges costs K per cut; the parts of a
        // good partitioner stay within twice that.
        let straight = K as Num * (nparts as Num - 1);
        assert!(
            cut <= 2 * straight,
            "{nparts} parts: cut {cut} against {straight}"
        );
        if nparts == 1 {
            assert_eq!(cut, 0);
        }
    }
}

#[test]
fn distributed_partition_on_1_to_4_ranks() {
    if std::env::var(CHILD).is_ok() {
        child();
        return;
    }
    let me = std::env::current_exe().unwrap();
    let tmp = std::env::temp_dir().join(format!("ptscotch-test-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    for np in 1..=4 {
        let out = Command::new("mpirun")
            .env("TMPDIR", &tmp)
            .args(["-n", &np.to_string(), "--oversubscribe"])
            .arg(&me)
            .args([
                "--exact",
                "distributed_partition_on_1_to_4_ranks",
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
