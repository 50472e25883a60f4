//! The `.vtu` pieces and the `.pvtu` index of real runs, opened by VTK's own readers
//! (`vtkXMLPUnstructuredGridReader`, `vtkXMLUnstructuredGridReader`, through Python's
//! `vtk` package: Debian's `python3-vtk9`, which `run-scripts/setup.sh` installs), hold
//! what the run's CSV files say, value for value.
//!
//! Without the package these tests print a note and pass on a developer's machine, but
//! fail in CI (`CI=true`), where a silent skip would leave the files untested.

mod common;

use common::{
    mpirun, python_with, read_contact, read_nodes, read_summary, run_builtin, session_dir,
};
use serde_json::Value;
use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::process::Command;

/// tests/vtk/read_solution.py: prints what VTK reads from a run's files as JSON.
const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/vtk/read_solution.py");

/// What VTK reads from `out`'s solution.pvtu and its pieces, or `None` (after a note) on a
/// developer's machine without the `vtk` package.
fn read_with_vtk(out: &Path) -> Option<Value> {
    let Some(python) = python_with("import vtkmodules.vtkIOXML") else {
        let note = "no Python with the vtk package (Debian: apt-get install python3-vtk9)";
        if std::env::var("CI").is_ok_and(|v| v == "true") {
            panic!("{note}: CI must read the VTU files with VTK's own readers");
        }
        println!("SKIPPED: {note}; the VTU files were not read by VTK");
        return None;
    };
    let o = Command::new(python)
        .arg(SCRIPT)
        .arg(out)
        .output()
        .expect("cannot start python");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "read_solution.py failed: {stderr}");
    // VTK reports a file it cannot read on its error output and goes on with an empty grid.
    assert!(
        !stderr.contains("ERROR") && !stderr.contains("Warning"),
        "VTK complained: {stderr}"
    );
    Some(serde_json::from_slice(&o.stdout).expect("read_solution.py prints JSON"))
}

/// The bytes of an array that read_solution.py printed as hex, checked to be of `ty`.
fn bytes_of(array: &Value, ty: &str) -> Vec<u8> {
    assert_eq!(array["type"], ty, "{}", array["name"]);
    hex_bytes(array)
}

fn hex_bytes(array: &Value) -> Vec<u8> {
    let hex = array["hex"].as_str().expect("an array");
    let byte = |k: usize| u8::from_str_radix(&hex[2 * k..2 * k + 2], 16).unwrap();
    (0..hex.len() / 2).map(byte).collect()
}

/// A Float64 array's values, exactly.
fn f64s(array: &Value) -> Vec<f64> {
    let b = bytes_of(array, "double");
    b.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// An Int32 array's values.
fn i32s(array: &Value) -> Vec<i32> {
    let b = bytes_of(array, "int");
    b.chunks_exact(4)
        .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// A VTK id array (connectivity, offsets): 64-bit integers, whose C type name differs
/// between platforms ("long long", "long").
fn ids(array: &Value) -> Vec<usize> {
    assert_eq!(array["size"], 8);
    let b = hex_bytes(array);
    b.chunks_exact(8)
        .map(|c| i64::from_le_bytes(c.try_into().unwrap()) as usize)
        .collect()
}

/// The array `name` of a point_data or cell_data list.
fn named<'a>(arrays: &'a Value, name: &str) -> &'a Value {
    let list = arrays.as_array().unwrap();
    let found = list.iter().find(|a| a["name"] == name);
    found.unwrap_or_else(|| panic!("no array {name}"))
}

fn names(arrays: &Value) -> Vec<&str> {
    let list = arrays.as_array().unwrap();
    list.iter().map(|a| a["name"].as_str().unwrap()).collect()
}

fn points(grid: &Value) -> Vec<[f64; 3]> {
    let xyz = f64s(&grid["xyz"]);
    xyz.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect()
}

/// The triangles of a grid, as node ids; checks that every cell is a VTK_TRIANGLE.
fn triangles(grid: &Value) -> Vec<[usize; 3]> {
    assert!(bytes_of(&grid["types"], "unsigned char")
        .iter()
        .all(|&t| t == 5));
    let (c, o) = (ids(&grid["connectivity"]), ids(&grid["offsets"]));
    assert_eq!(o, (0..=c.len() / 3).map(|k| 3 * k).collect::<Vec<_>>());
    c.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
}

fn count(grid: &Value, key: &str) -> usize {
    grid[key].as_u64().unwrap() as usize
}

/// A point by the bits of its coordinates: pieces share the nodes of their interfaces.
fn key(x: f64, y: f64) -> (u64, u64) {
    (x.to_bits(), y.to_bits())
}

/// Hertz on 2 ranks: the index and each piece, as VTK reads them, against contact.csv,
/// nodes.csv and summary.json.
#[test]
fn vtk_reads_what_the_csv_files_say() {
    let dir = tempfile::tempdir().unwrap();
    let session = session_dir();
    let o = mpirun(2, dir.path())
        .args(["--builtin", "hertz", "--level", "1", "--nodes-csv"])
        .args(["--out", "out", "--quiet"])
        .env("TMPDIR", session.path())
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .expect("mpirun must be installed (openmpi-bin)");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("out");
    let Some(vtk) = read_with_vtk(&out) else {
        return;
    };
    let summary = read_summary(&out.join("summary.json"));
    let in_summary = |k: &str| summary[k].as_u64().unwrap() as usize;

    // The index: both pieces, appended into one grid with every array.
    let index = &vtk["index"];
    let pieces = vtk["pieces"].as_array().unwrap();
    assert_eq!(pieces.len(), 2);
    assert_eq!(count(index, "cells"), in_summary("elements"));
    let piece_points: usize = pieces.iter().map(|p| count(p, "points")).sum();
    assert_eq!(count(index, "points"), piece_points);
    for grid in std::iter::once(index).chain(pieces) {
        assert_eq!(
            names(&grid["point_data"]),
            [
                "displacement",
                "contact_pressure",
                "tangential_traction",
                "contact_status"
            ]
        );
        assert_eq!(
            names(&grid["cell_data"]),
            ["stress", "von_mises", "rank", "body"]
        );
        let stress = named(&grid["cell_data"], "stress");
        assert_eq!(stress["components"], 4);
        let labels = serde_json::json!(["xx", "yy", "xy", "zz"]);
        assert_eq!(stress["component_names"], labels);
        assert_eq!(named(&grid["point_data"], "displacement")["components"], 3);
    }

    let nodes: HashMap<(u64, u64), [f64; 2]> = read_nodes(&out.join("nodes.csv"))
        .into_iter()
        .map(|n| (key(n[0], n[1]), [n[2], n[3]]))
        .collect();
    let contact: HashMap<(u64, u64), [f64; 2]> = read_contact(&out.join("contact.csv"))
        .into_iter()
        .map(|r| (key(r.x, r.y), [r.p_n, r.p_t]))
        .collect();
    assert_eq!(nodes.len(), in_summary("nodes"));
    assert_eq!(contact.len(), in_summary("contact_nodes"));

    let mut seen = HashMap::new();
    for (r, piece) in pieces.iter().enumerate() {
        let xyz = points(piece);
        assert_eq!(xyz.len(), count(piece, "points"));
        let (pd, cd) = (&piece["point_data"], &piece["cell_data"]);
        let u = f64s(named(pd, "displacement"));
        let p_n = f64s(named(pd, "contact_pressure"));
        let p_t = f64s(named(pd, "tangential_traction"));
        let status = i32s(named(pd, "contact_status"));
        assert_eq!(u.len(), 3 * xyz.len());
        assert!([p_n.len(), p_t.len(), status.len()] == [xyz.len(); 3]);
        for (i, p) in xyz.iter().enumerate() {
            assert_eq!(p[2], 0.0);
            let copy = (
                [u[3 * i], u[3 * i + 1], u[3 * i + 2]],
                p_n[i],
                p_t[i],
                status[i],
            );
            seen.entry(key(p[0], p[1]))
                .or_insert_with(Vec::new)
                .push(copy);
        }
        let tris = triangles(piece);
        assert_eq!(tris.len(), count(piece, "cells"));
        assert!(tris.iter().flatten().all(|&v| v < xyz.len()));
        let rank = i32s(named(cd, "rank"));
        assert_eq!(rank, vec![r as i32; tris.len()]);
        // One [material]: one body.
        assert_eq!(i32s(named(cd, "body")), vec![0; tris.len()]);
        let (s, vm) = (f64s(named(cd, "stress")), f64s(named(cd, "von_mises")));
        assert_eq!((s.len(), vm.len()), (4 * tris.len(), tris.len()));
        for (s, vm) in s.chunks(4).zip(&vm) {
            let [xx, yy, xy, zz] = [s[0], s[1], s[2], s[3]];
            let squares = (xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2);
            let mises = (0.5 * squares + 3.0 * xy * xy).sqrt();
            assert!(
                (vm - mises).abs() <= 1e-9 * mises.max(1.0),
                "{vm} vs {mises}"
            );
        }
    }
    assert_eq!(seen.len(), in_summary("nodes"));
    for (k, copies) in &seen {
        // nodes.csv has the displacement of the subdomain that owns the node; a node on an
        // interface is also in the neighbour's piece, with that subdomain's own
        // recovered value, equal to rounding.
        let want = nodes.get(k).expect("every point is a node of nodes.csv");
        let want = [want[0], want[1], 0.0];
        assert!(copies
            .iter()
            .any(|c| c.0.map(f64::to_bits) == want.map(f64::to_bits)));
        // A contact node belongs to one subdomain: the copy in a neighbour's piece is off
        // its contact boundary.
        let on_contact: Vec<_> = copies.iter().filter(|c| c.3 >= 0).collect();
        for (u, p_n, p_t, status) in copies {
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1e-9);
            assert!((0..3).all(|d| close(u[d], want[d])), "{u:?} vs {want:?}");
            if *status < 0 {
                assert_eq!((*p_n, *p_t), (0.0, 0.0));
            }
        }
        match contact.get(k) {
            Some(pt) => {
                let [(_, p_n, p_t, status)] = on_contact[..] else {
                    panic!("a contact node is on the contact boundary of one piece");
                };
                assert_eq!([*p_n, *p_t].map(f64::to_bits), pt.map(f64::to_bits));
                assert!([0, 1, 2, 3].contains(status), "status {status}");
            }
            None => assert!(on_contact.is_empty()),
        }
    }
    let status: Vec<i32> = seen
        .values()
        .map(|c| c.iter().map(|c| c.3).max().unwrap())
        .collect();
    let with = |s: i32| status.iter().filter(|&&v| v == s).count();
    assert_eq!(
        with(0) + with(1) + with(2) + with(3),
        in_summary("contact_nodes")
    );
    assert_eq!(with(1) + with(2) + with(3), in_summary("active_nodes"));
    // Status 3 is contact without friction, where stick and slip are not counted.
    if with(3) > 0 {
        assert_eq!(with(1) + with(2), 0);
        assert!(summary["stick_nodes"].is_null() && summary["slip_nodes"].is_null());
    } else {
        assert_eq!(with(1), in_summary("stick_nodes"));
        assert_eq!(with(2), in_summary("slip_nodes"));
    }
}

/// A piece above the per-file size is split, and with several threads its files are
/// encoded and written at once: every file is complete, listed once in the index, and
/// together they hold every triangle once; no temporary file is left.
#[test]
fn split_piece_written_by_several_threads_is_complete() {
    // Block level 4: 204800 triangles, two files on one rank.
    let run = run_builtin(
        "block",
        4,
        &["--threads", "2", "--subdomains-per-rank", "1"],
    );
    run.expect_code(0);
    let mut names: Vec<String> = std::fs::read_dir(&run.out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "contact.csv",
            "contact.png",
            "convergence.png",
            "history.csv",
            "solution.pvtu",
            "solution_0_0.vtu",
            "solution_0_1.vtu",
            "summary.json"
        ]
    );
    let Some(vtk) = read_with_vtk(&run.out) else {
        return;
    };
    let pieces = vtk["pieces"].as_array().unwrap();
    assert_eq!(pieces.len(), 2);
    let mut all = BTreeSet::new();
    for piece in pieces {
        let xyz = points(piece);
        for t in triangles(piece) {
            // Triangles by their corners' coordinates: local numbering differs per file.
            let mut corners = t.map(|v| key(xyz[v][0], xyz[v][1]));
            corners.sort();
            assert!(all.insert(corners), "a triangle is in two files");
        }
    }
    assert_eq!(all.len(), 204_800);
    assert_eq!(count(&vtk["index"], "cells"), 204_800);
}

/// Two bodies on 2 ranks: each cell's `body`, in the pieces and through the index, is
/// the index of its [[material]] entry, listed here in the reverse of the mesh's order
/// of groups ("upper" first, body 0: the triangles above y = 1).
#[test]
fn body_of_each_cell_is_its_material() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = "bimaterial_v41_ascii.msh";
    std::fs::copy(common::gmsh_dir().join(mesh), dir.path().join(mesh)).unwrap();
    let case = format!(
        "[mesh]\nfile = \"{mesh}\"\n[[material]]\ngroup = \"upper\"\nyoung = 200.0\npoisson = 0.3\n[[material]]\ngroup = \"lower\"\nyoung = 1000.0\npoisson = 0.3\n[[dirichlet]]\ngroup = \"top\"\nux = 0.0\nuy = -0.01\n[contact]\ngroup = \"bottom\"\nobstacle_point = [0.0, 0.0]\nobstacle_normal = [0.0, 1.0]\n"
    );
    std::fs::write(dir.path().join("case.toml"), case).unwrap();
    let session = session_dir();
    let o = mpirun(2, dir.path())
        .args(["case.toml", "--out", "out", "--quiet", "--no-plots"])
        .env("TMPDIR", session.path())
        .env("RAYON_NUM_THREADS", "1")
        .output()
        .expect("mpirun must be installed (openmpi-bin)");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let Some(vtk) = read_with_vtk(&dir.path().join("out")) else {
        return;
    };
    let mut counts = [0usize; 2];
    let grids = vtk["pieces"].as_array().unwrap().iter();
    for (k, grid) in std::iter::once(&vtk["index"]).chain(grids).enumerate() {
        let xyz = points(grid);
        let body = i32s(named(&grid["cell_data"], "body"));
        let tris = triangles(grid);
        assert_eq!(body.len(), tris.len());
        for (t, b) in tris.iter().zip(&body) {
            let y = t.iter().map(|&v| xyz[v][1]).sum::<f64>() / 3.0;
            assert_eq!(*b, if y > 1.0 { 0 } else { 1 }, "a cell at y = {y}");
            if k == 0 {
                counts[*b as usize] += 1;
            }
        }
    }
    assert!(counts[0] > 0 && counts[1] > 0, "{counts:?}");
}
