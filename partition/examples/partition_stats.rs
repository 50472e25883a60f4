//! Partitions a structured rectangle mesh and prints timings and quality.
//!
//! ```text
//! cargo run --release --example partition_stats -- NX NY NPARTS...
//! cargo run --release --example partition_stats -- 1000 1000 2 8
//! ```

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("arguments are integers: NX NY NPARTS..."))
        .collect();
    let (nx, ny, nparts) = match args.as_slice() {
        [nx, ny, nparts @ ..] if !nparts.is_empty() => (*nx, *ny, nparts.to_vec()),
        _ => (200, 50, vec![2, 4, 8]),
    };
    let (num_nodes, tris, contact) = common::rectangle(nx, ny);
    println!(
        "{nx} x {ny} rectangle: {num_nodes} nodes, {} triangles",
        tris.len()
    );
    let t = Instant::now();
    let g = partition::dual_graph(num_nodes, &tris).expect("valid mesh");
    println!(
        "dual graph: {} edges in {:.3} s",
        g.num_edges(),
        t.elapsed().as_secs_f64()
    );
    for n in nparts {
        let t = Instant::now();
        let p = partition::partition_mesh(num_nodes, &tris, &contact, n).expect("partition");
        let total = t.elapsed().as_secs_f64();
        // The same bookkeeping without METIS, to show where the time goes.
        let t = Instant::now();
        let again = partition::partition_from_element_parts(
            num_nodes,
            &tris,
            &contact,
            n,
            p.element_part.clone(),
        )
        .expect("same partition");
        let rest = t.elapsed().as_secs_f64();
        assert_eq!(again, p);
        println!(
            "{n} parts in {total:.3} s (METIS {:.3} s, graph and bookkeeping {rest:.3} s): {}",
            total - rest,
            p.quality
        );
    }
}
