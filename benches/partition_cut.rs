//! The first rank's cut of a mesh file, piece by piece, in one process: the mesh read
//! and its problem built as a run builds them, then, for each part count, the graph
//! (`MeshGraph::new`), the centroids and the straight cuts (`cut_straight`) with their
//! `finish_straight`, and METIS's cut (`MeshGraph::cut`) with its `finish`: the
//! seconds of each repetition and both edge cuts. A plain program rather than a
//! criterion bench: at a million nodes one repetition takes a second, and the pieces
//! are what is read.
//!
//! ```text
//! cargo bench --bench partition_cut -- CASE.toml MESH.msh [--reps 3] [--threads 2] PARTS...
//! ```
//!
//! cargo runs a bench in the package's directory: give the files' absolute paths.

use contact_par::{case, mesh, problem};
use std::path::Path;
use std::time::Instant;

fn main() {
    let mut args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let mut take = |flag: &str, default: usize| -> usize {
        match args.iter().position(|a| a == flag) {
            Some(i) if i + 1 < args.len() => {
                let v = args.remove(i + 1);
                args.remove(i);
                v.parse()
                    .unwrap_or_else(|_| panic!("{flag} takes a whole number"))
            }
            _ => default,
        }
    };
    let reps = take("--reps", 3);
    let threads = take("--threads", 2);
    let [case_file, mesh_file, parts @ ..] = args.as_slice() else {
        eprintln!("usage: partition_cut CASE.toml MESH.msh [--reps N] [--threads N] PARTS...");
        std::process::exit(2);
    };
    let parts: Vec<usize> = match parts {
        [] => vec![2],
        p => p
            .iter()
            .map(|k| k.parse().expect("part counts are whole numbers"))
            .collect(),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool");
    pool.install(|| {
        let case = case::read_case(Path::new(case_file)).expect("a readable case");
        let t = Instant::now();
        let read = mesh::gmsh::read_msh(Path::new(mesh_file)).expect("a readable mesh");
        let prob = problem::build(&case, read, mesh_file).expect("a valid problem");
        let (tris, contact) = (&prob.mesh.triangles, &prob.contact_nodes);
        println!(
            "{mesh_file}: {} nodes, {} triangles, read and built in {:.3} s on {threads} threads",
            prob.mesh.num_nodes(),
            tris.len(),
            t.elapsed().as_secs_f64()
        );
        println!("parts graph_s straight_s finish_straight_s metis_s finish_s straight_cut metis_cut");
        let graph = || {
            let t = Instant::now();
            let g = partition::MeshGraph::new(prob.mesh.num_nodes(), tris, &[], true)
                .expect("a valid mesh");
            (g, t.elapsed().as_secs_f64())
        };
        for &k in &parts {
            for _ in 0..reps {
                let (g, graph_s) = graph();
                let t = Instant::now();
                let straight = g.cut_straight(&prob.mesh.centroids(), k);
                let straight_s = t.elapsed().as_secs_f64();
                let (finish_straight_s, straight_cut) = match straight {
                    Some(parts) => {
                        let t = Instant::now();
                        let p = g.finish_straight(tris, contact, parts).expect("finished");
                        (format!("{:.4}", t.elapsed().as_secs_f64()), p.quality.edge_cut.to_string())
                    }
                    None => ("-".into(), "pieces".into()),
                };
                let (g, _) = graph();
                let t = Instant::now();
                let metis = g.cut(k).expect("METIS's cut");
                let metis_s = t.elapsed().as_secs_f64();
                let t = Instant::now();
                let p = g.finish(tris, contact, k, metis).expect("finished");
                let finish_s = t.elapsed().as_secs_f64();
                println!(
                    "{k} {graph_s:.4} {straight_s:.4} {finish_straight_s} {metis_s:.4} {finish_s:.4} {straight_cut} {}",
                    p.quality.edge_cut
                );
            }
        }
    });
}
