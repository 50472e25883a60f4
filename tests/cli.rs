//! The command line: bad input is rejected with one clear line and exit code 2 before
//! anything is written; an exhausted budget exits 3 with outputs marked so; printed cases
//! run as the built-in ones; the CSV outputs are complete, consistent, exact and sorted.

mod common;
use common::*;

/// A valid case (the built-in block at level 0) as printed by the binary.
fn good_case() -> String {
    print_case("block", 0)
}

/// Runs `case.toml` = `text` and checks the input-error contract: exit code 2, exactly
/// one line on stderr containing every string of `must_name`, nothing on stdout, and no
/// output directory. Returns the message.
fn expect_input_error(text: &str, must_name: &[&str]) -> String {
    let run = run_case(text, &[]);
    assert_eq!(
        run.code, 2,
        "exit code {} for bad input; stderr: {}",
        run.code, run.stderr
    );
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "stderr is not one line: {:?}", run.stderr);
    for s in must_name {
        assert!(
            lines[0].contains(s),
            "the message does not name {s:?}: {}",
            lines[0]
        );
    }
    assert!(run.stdout.trim().is_empty(), "stdout: {}", run.stdout);
    assert!(
        !run.out.exists(),
        "the output directory was created for bad input"
    );
    // Nothing else was written either: the run directory holds only the case file.
    let entries: Vec<String> = std::fs::read_dir(run.dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(entries, ["case.toml"], "files left by a bad-input run");
    println!("{}", lines[0]);
    lines[0].to_string()
}

#[test]
fn misspelled_key_is_named_with_the_file() {
    let text = good_case().replace("poisson = 0.33", "poison = 0.33");
    assert!(text.contains("poison"), "the printed case changed: {text}");
    let msg = expect_input_error(&text, &["case.toml", "poison"]);
    // The line of the offending key.
    let line = text.lines().position(|l| l.starts_with("poison")).unwrap() + 1;
    assert!(msg.contains(&format!("line {line}")), "{msg}");
}

#[test]
fn missing_group_suggests_the_closest_name() {
    let text = good_case().replace("group = \"top\"", "group = \"topp\"");
    assert!(text.contains("\"topp\""));
    expect_input_error(&text, &["case.toml", "\"topp\"", "did you mean \"top\""]);
}

#[test]
fn non_unit_normal_is_rejected() {
    let text = good_case().replace(
        "obstacle_normal = [0.0, 1.0]",
        "obstacle_normal = [0.0, 2.0]",
    );
    assert!(text.contains("[0.0, 2.0]"));
    expect_input_error(&text, &["case.toml", "obstacle_normal"]);
}

#[test]
fn missing_mesh_file_is_named() {
    let text = good_case().replace("builtin = \"block\"", "file = \"no_such_mesh.msh\"");
    let text: String = text
        .lines()
        .filter(|l| !l.starts_with("level"))
        .map(|l| format!("{l}\n"))
        .collect();
    expect_input_error(&text, &["no_such_mesh.msh"]);
}

#[test]
fn exhausted_budget_exits_3_with_outputs_marked() {
    let run = run_builtin("block", 0, &["--max-iter", "3"]);
    run.expect_code(3);
    let s = run.summary();
    assert_eq!(s["converged"], false, "{s}");
    assert_eq!(s["iterations"], 3, "{s}");
    // The last iterate is written in full.
    let rows = run.contact();
    assert_eq!(rows.len() as f64, num(&s, "contact_nodes"));
    let history = std::fs::read_to_string(run.out.join("history.csv")).unwrap();
    assert_eq!(history.lines().count(), 1 + 3, "{history}");
}

#[test]
fn printed_case_runs_like_the_builtin() {
    for (name, level) in [("block", 0), ("block_flat", 0), ("hertz", 0), ("punch", 0)] {
        let text = print_case(name, level);
        let from_file = run_case(&text, &[]);
        let builtin = run_builtin(name, level, &[]);
        from_file.expect_code(0);
        builtin.expect_code(0);
        // Same case, same mesh, same arithmetic: byte-identical results.
        let a = std::fs::read_to_string(from_file.out.join("contact.csv")).unwrap();
        let b = std::fs::read_to_string(builtin.out.join("contact.csv")).unwrap();
        assert!(
            a == b,
            "{name}: contact.csv differs between --print-case file and built-in"
        );
        let (sa, sb) = (from_file.summary(), builtin.summary());
        for key in [
            "iterations",
            "nodes",
            "total_normal_force",
            "total_tangential_force",
        ] {
            assert_eq!(sa[key], sb[key], "{name}: {key}");
        }
    }
}

#[test]
fn nodes_csv_has_every_node_and_agrees_with_contact_csv() {
    // m = (0, 1), t = (1, 0): at a contact node u_n = -uy and u_t = ux, whatever the law.
    for (law, extra) in [
        ("none", "friction = \"none\""),
        ("tresca", "friction = \"tresca\"\nthreshold = 20.0"),
        ("coulomb", "friction = \"coulomb\"\ncoefficient = 0.3"),
    ] {
        let run = run_case(
            &block_case(0, "ux = 0.01\nuy = -0.02", extra, [0.0, 1.0], ""),
            &["--nodes-csv"],
        );
        run.expect_code(0);
        let s = run.summary();
        let nodes = read_nodes(&run.out.join("nodes.csv"));
        assert_eq!(
            nodes.len() as f64,
            num(&s, "nodes"),
            "{law}: nodes.csv rows"
        );
        // The built-in block at level 0: 40 x 10 cells of size 1, so 41 x 11 nodes.
        assert_eq!(nodes.len(), 41 * 11, "{law}");
        let rows = run.contact();
        let umax = nodes
            .iter()
            .map(|n| n[2].abs().max(n[3].abs()))
            .fold(0.0, f64::max);
        let (mut en, mut et) = (0.0f64, 0.0f64);
        for r in &rows {
            let n = nodes
                .iter()
                .find(|n| n[0] == r.x && n[1] == r.y)
                .unwrap_or_else(|| {
                    panic!("{law}: contact node ({}, {}) not in nodes.csv", r.x, r.y)
                });
            en = en.max((r.u_n + n[3]).abs() / umax);
            et = et.max((r.u_t - n[2]).abs() / umax);
        }
        println!("{law}: contact.csv vs nodes.csv: max |u_n + uy| / max|u| = {en:e}, max |u_t - ux| / max|u| = {et:e}");
        // Same displacement, two projections: round-off only.
        assert!(
            en <= 1e-9,
            "{law}: u_n in contact.csv differs from -uy in nodes.csv by {en:e}"
        );
        assert!(
            et <= 1e-9,
            "{law}: u_t in contact.csv differs from ux in nodes.csv by {et:e}"
        );
    }
}

#[test]
fn contact_csv_numbers_round_trip_and_rows_are_sorted() {
    // The quarter disc: irrational coordinates and values of every magnitude.
    let run = run_builtin("hertz", 0, &[]);
    run.expect_code(0);
    let text = std::fs::read_to_string(run.out.join("contact.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,u_n,u_t,p_n,p_t,gap,contact"));
    let mut keys = Vec::new();
    let mut count = 0;
    for l in lines {
        let fields: Vec<&str> = l.split(',').collect();
        assert_eq!(fields.len(), 8, "{l}");
        for f in &fields {
            let v: f64 = f
                .parse()
                .unwrap_or_else(|_| panic!("{f:?} is not a number"));
            assert!(v.is_finite(), "{f}");
            // Shortest round-trip text: printing the parsed value gives the same text, so
            // no digit was lost or invented.
            assert_eq!(v.to_string(), *f, "{f} does not round-trip");
            count += 1;
        }
        keys.push((
            fields[0].parse::<f64>().unwrap(),
            fields[1].parse::<f64>().unwrap(),
        ));
    }
    let s = run.summary();
    assert_eq!(keys.len() as f64, num(&s, "contact_nodes"));
    assert!(
        keys.windows(2)
            .all(|w| w[0].0 < w[1].0 || (w[0].0 == w[1].0 && w[0].1 < w[1].1)),
        "rows are not sorted by x then y"
    );
    println!("{count} numbers round-trip, {} rows sorted", keys.len());
}

/// nodes.csv is written by every rank, each its block of node ids at its offset: the file
/// keeps the one-rank run's layout (header, one row per node in global order, the same
/// coordinates byte for byte) whatever the ranks and subdomains per rank, and no
/// temporary is left behind.
#[test]
fn nodes_csv_written_in_blocks_by_the_ranks_keeps_the_one_rank_layout() {
    let dir = tempfile::tempdir().unwrap();
    let run = |np: usize, k: &str, out: &str| {
        let o = mpirun(np, dir.path())
            .args(["--builtin", "block", "--level", "2", "--tol", "1e-11"])
            .args(["--subdomains-per-rank", k, "--threads", "1", "--nodes-csv"])
            .args(["--quiet", "--out", out])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read_to_string(dir.path().join(out).join("nodes.csv")).unwrap()
    };
    let one = run(1, "1", "one");
    let nodes = read_summary(&dir.path().join("one/summary.json"))["nodes"]
        .as_u64()
        .unwrap() as usize;
    assert_eq!(one.lines().count(), nodes + 1);
    let scale = read_nodes(&dir.path().join("one/nodes.csv"))
        .iter()
        .flat_map(|n| [n[2].abs(), n[3].abs()])
        .fold(0.0, f64::max);
    for (np, k) in [(5, "1"), (3, "2")] {
        let out = format!("np{np}x{k}");
        let many = run(np, k, &out);
        assert_eq!(many.lines().count(), one.lines().count(), "{out}");
        assert!(
            many.starts_with("x,y,ux,uy\n") && many.ends_with('\n'),
            "{out}"
        );
        for (a, b) in one.lines().zip(many.lines()).skip(1) {
            let (fa, fb): (Vec<&str>, Vec<&str>) = (a.split(',').collect(), b.split(',').collect());
            assert_eq!(fb.len(), 4, "{out}: {b}");
            assert_eq!(fa[..2], fb[..2], "{out}: rows out of order");
            for c in 2..4 {
                let d = (fa[c].parse::<f64>().unwrap() - fb[c].parse::<f64>().unwrap()).abs();
                assert!(d <= 1e-8 * scale, "{out}: {a} against {b}");
            }
        }
        let left: Vec<String> = std::fs::read_dir(dir.path().join(&out))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect();
        assert!(left.is_empty(), "{out}: {left:?}");
    }
}

/// A line with every number replaced by N and runs of spaces by one: what stays the same
/// from run to run.
fn shape(line: &str) -> String {
    line.split_whitespace()
        .map(|w| {
            let bare = w.trim_matches(|c: char| "(),:|".contains(c));
            match bare.parse::<f64>() {
                Ok(_) => w.replace(bare, "N"),
                Err(_) => w.to_string(),
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Runs `args` (not quiet) in `dir` and returns stdout, checking the exit code.
fn printed(dir: &std::path::Path, args: &[&str]) -> String {
    let (code, stdout, stderr) = run_in(dir, args);
    assert_eq!(code, 0, "{stdout}{stderr}");
    stdout
}

#[test]
fn help_shows_a_true_example_of_each_output() {
    let dir = tempfile::TempDir::new().unwrap();
    let help = printed(dir.path(), &["--help"]);
    let hertz = printed(
        dir.path(),
        &["--builtin", "hertz", "--level", "1", "--out", "ex1"],
    );
    let block = printed(
        dir.path(),
        &["--builtin", "block", "--level", "1", "--out", "ex2"],
    );
    let ex1 = dir.path().join("ex1");
    let lines: Vec<&str> = help.lines().collect();
    // The sample lines under a heading, indented by four spaces.
    let under = |heading: &str| -> Vec<&str> {
        let start = lines.iter().position(|l| l.starts_with(heading));
        let start = start.unwrap_or_else(|| panic!("no {heading:?} in --help"));
        lines[start + 1..]
            .iter()
            .take_while(|l| l.starts_with("    "))
            .map(|l| l.trim())
            .collect()
    };
    for (file, heading) in [
        ("contact.csv", "contact.csv:"),
        ("history.csv", "history.csv:"),
    ] {
        let real = std::fs::read_to_string(ex1.join(file)).unwrap();
        let sample = under(heading);
        assert_eq!(sample[0], real.lines().next().unwrap(), "{file}'s header");
        let width = sample[0].split(',').count();
        for row in &sample[1..] {
            let fields: Vec<&str> = row.split(',').collect();
            assert_eq!(fields.len(), width, "{file}: {row}");
            assert!(fields.iter().all(|f| f.parse::<f64>().is_ok()), "{row}");
        }
        assert!(sample.len() >= 2, "{file}: no sample row");
    }
    let summary = read_summary(&ex1.join("summary.json"));
    let sample = under("summary.json:").join(" ");
    let keys: Vec<&str> = sample
        .split('"')
        .enumerate()
        .filter(|(k, _)| k % 2 == 1)
        .map(|(_, key)| key)
        .collect();
    assert!(keys.len() >= 8, "{keys:?}");
    for key in keys {
        let found = summary.get(key).is_some() || summary["timings_s"].get(key).is_some();
        assert!(found, "--help names {key:?}, summary.json has no such key");
    }
    use contact_par::output::plot::{CONTACT_SIZE, CONVERGENCE_SIZE};
    for (name, (w, h)) in [
        ("contact.png", CONTACT_SIZE),
        ("convergence.png", CONVERGENCE_SIZE),
    ] {
        assert!(
            help.contains(&format!("{name}: {w} x {h} pixels")),
            "{name}"
        );
        assert!(ex1.join(name).exists(), "{name}");
    }
    // Every printed sample has the shape of a line the runs printed.
    let real: std::collections::HashSet<String> =
        hertz.lines().chain(block.lines()).map(shape).collect();
    let mut samples = under("monitor line every");
    samples.extend(under("With friction"));
    assert!(samples.len() >= 8, "{samples:?}");
    for s in samples {
        assert!(
            real.contains(&shape(s)),
            "--help shows {s:?}, the run printed no such line:\n{hertz}"
        );
    }
}

/// The phase lines of `stdout`, each phase once and in order, and the closing table's
/// rows: the seconds of each phase line must be the table's.
fn check_phase_lines(stdout: &str, phases: &[&str]) {
    let done: Vec<(&str, &str)> = stdout
        .lines()
        .filter_map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            (w.len() >= 5 && w[1] == "done" && w[2] == "in" && w[4].starts_with('s'))
                .then(|| (w[0], w[3]))
        })
        .collect();
    let names: Vec<&str> = done.iter().map(|d| d.0).collect();
    assert_eq!(names, phases, "{stdout}");
    let table = stdout
        .lines()
        .skip_while(|l| !l.starts_with("phase         seconds"))
        .collect::<Vec<_>>();
    for (name, seconds) in done {
        let row = table
            .iter()
            .find(|l| l.split_whitespace().next() == Some(name));
        let row = row.unwrap_or_else(|| panic!("no row {name} in the table:\n{stdout}"));
        assert_eq!(
            row.split_whitespace().nth(1),
            Some(seconds),
            "{name}: {row}"
        );
    }
}

#[test]
fn each_phase_prints_one_line_as_it_ends_with_the_tables_seconds() {
    let dir = tempfile::TempDir::new().unwrap();
    let all = [
        "read",
        "partition",
        "scatter",
        "assemble",
        "factor",
        "condense",
        "loop",
        "recover",
        "output",
    ];
    let two = [
        "--builtin",
        "hertz",
        "--level",
        "1",
        "--subdomains-per-rank",
        "2",
    ];
    let stdout = printed(dir.path(), &[&two[..], &["--out", "a"]].concat());
    check_phase_lines(&stdout, &all);
    // The first line comes first; the partition's line names the parts.
    assert!(stdout.starts_with("contact-par: "), "{stdout}");
    assert!(stdout.contains("2 parts"), "{stdout}");
    // --linear full has no condensation and no recovery.
    let full = [
        "--builtin",
        "block",
        "--level",
        "0",
        "--linear",
        "full",
        "--out",
        "b",
    ];
    let full_phases = [
        "read",
        "partition",
        "scatter",
        "assemble",
        "factor",
        "loop",
        "output",
    ];
    check_phase_lines(&printed(dir.path(), &full), &full_phases);
    // --quiet: nothing.
    let quiet = printed(dir.path(), &[&two[..], &["--out", "c", "--quiet"]].concat());
    assert!(quiet.is_empty(), "{quiet}");
    // Two ranks: the first prints, once.
    let o = mpirun(2, dir.path())
        .args(two)
        .args(["--out", "d"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    check_phase_lines(&stdout, &all);
    assert!(
        stdout.contains("4 parts") && stdout.contains("2 rank(s)"),
        "{stdout}"
    );
}

#[test]
fn monitor_lines_show_what_the_friction_law_has() {
    let dir = tempfile::TempDir::new().unwrap();
    for (law, case, frictional) in [
        ("none", print_case("hertz", 0), false),
        ("coulomb", print_case("block", 0), true),
        (
            "tresca",
            builtin_with_friction("block", 0, "friction = \"tresca\"\nthreshold = 20.0"),
            true,
        ),
    ] {
        let file = format!("{law}.toml");
        std::fs::write(dir.path().join(&file), case).unwrap();
        let out = format!("out-{law}");
        let args = [file.as_str(), "--out", &out, "--monitor-every", "1"];
        let stdout = printed(dir.path(), &args);
        let monitor: Vec<&str> = stdout.lines().filter(|l| l.contains("  error ")).collect();
        let summary = read_summary(&dir.path().join(&out).join("summary.json"));
        assert_eq!(
            monitor.len() as f64,
            num(&summary, "iterations"),
            "{law}: {stdout}"
        );
        for line in monitor {
            let words: Vec<&str> = line.split_whitespace().collect();
            let count = |name: &str| {
                let k = words.iter().position(|w| *w == name)?;
                words[k + 1].parse::<usize>().ok()
            };
            assert!(count("active").is_some(), "{law}: {line}");
            assert_eq!(line.contains("p_t "), frictional, "{law}: {line}");
            if frictional {
                let (stick, slip) = (count("stick").unwrap(), count("slip").unwrap());
                assert_eq!(stick + slip, count("active").unwrap(), "{law}: {line}");
            } else {
                assert!(!line.contains("stick") && !line.contains("slip"), "{line}");
            }
        }
    }
}

/// A run into the directory of an earlier one on more subdomains, with `--nodes-csv`,
/// leaves none of that run's files that do not match it: the earlier pieces its index
/// does not list and its nodes.csv are gone; the index lists exactly the pieces left.
#[test]
fn a_new_run_leaves_no_earlier_piece_or_table_in_its_directory() {
    let dir = tempfile::TempDir::new().unwrap();
    let p = dir.path();
    let base = [
        "--builtin",
        "block",
        "--out",
        "out",
        "--quiet",
        "--no-plots",
    ];
    let (code, _, err) = run_on_ranks(p, 3, &[&base[..], &["--nodes-csv"]].concat());
    assert_eq!(code, 0, "{err}");
    let pieces = |p: &std::path::Path| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(p.join("out"))
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .filter(|n| n.ends_with(".vtu"))
            .collect();
        v.sort();
        v
    };
    assert_eq!(pieces(p).len(), 3, "{:?}", pieces(p));
    let (code, _, err) = run_in(p, &[&base[..], &["--subdomains-per-rank", "1"]].concat());
    assert_eq!(code, 0, "{err}");
    let left = pieces(p);
    assert_eq!(left, ["solution_0_0.vtu"], "{left:?}");
    assert!(
        !p.join("out/nodes.csv").exists(),
        "an earlier nodes.csv is left"
    );
    let index = std::fs::read_to_string(p.join("out/solution.pvtu")).unwrap();
    assert_eq!(index.matches("<Piece ").count(), left.len(), "{index}");
}
