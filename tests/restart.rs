//! Nothing lost: a run stopped by its sweep budget resumes from its checkpoint and ends
//! exactly where an uninterrupted run ends; a rank killed mid-run takes the job down
//! promptly instead of leaving the others waiting.

mod common;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn run(np: usize, args: &[&str], dir: &Path) -> Output {
    common::mpirun(np, dir).args(args).output().unwrap()
}

fn iterations(dir: &Path) -> i64 {
    common::read_summary(&dir.join("summary.json"))["iterations"]
        .as_i64()
        .unwrap()
}

/// Interrupt at sweep 17 (checkpoints every 5: the last at 15), restart, compare with an
/// uninterrupted run: the same iteration count and the same files, byte for byte.
fn check_restart(np: usize, extra: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    check_restart_in(
        tmp.path(),
        np,
        &["--builtin", "block", "--level", "1"],
        extra,
        (17, 5),
    );
}

/// [`check_restart`] for a run given by `source` (a built-in or a case file), stopped
/// after `stop.0` sweeps with checkpoints every `stop.1`.
fn check_restart_in(tmp: &Path, np: usize, source: &[&str], extra: &[&str], stop: (usize, usize)) {
    let base: Vec<&str> = source
        .iter()
        .copied()
        .chain(["--quiet", "--nodes-csv"])
        .collect();
    let args = |out: &str, more: &[&str]| -> Vec<String> {
        base.iter()
            .chain(["--out", out].iter())
            .chain(more)
            .chain(extra)
            .map(|s| s.to_string())
            .collect()
    };
    let (max_iter, every) = (stop.0.to_string(), stop.1.to_string());
    let a = args(
        "stopped",
        &["--max-iter", &max_iter, "--checkpoint-every", &every],
    );
    let o = run(np, &a.iter().map(String::as_str).collect::<Vec<_>>(), tmp);
    assert_eq!(
        o.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // One file per subdomain (several per rank with --subdomains-per-rank).
    let parts = common::read_summary(&tmp.join("stopped/summary.json"))["subdomains"]
        .as_u64()
        .unwrap() as usize;
    assert!(parts >= np);
    for r in 0..parts {
        assert!(tmp
            .join(format!("stopped/checkpoint/rank_{r}.bin"))
            .exists());
    }
    let a = args("stopped", &["--restart"]);
    let o = run(np, &a.iter().map(String::as_str).collect::<Vec<_>>(), tmp);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a = args("straight", &[]);
    let o = run(np, &a.iter().map(String::as_str).collect::<Vec<_>>(), tmp);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    assert_eq!(
        iterations(&tmp.join("stopped")),
        iterations(&tmp.join("straight"))
    );
    for file in ["contact.csv", "nodes.csv", "history.csv"] {
        let x = std::fs::read(tmp.join("stopped").join(file)).unwrap();
        let y = std::fs::read(tmp.join("straight").join(file)).unwrap();
        assert!(x == y, "{file} differs");
    }
}

#[test]
fn restart_equals_uninterrupted_run_one_rank() {
    check_restart(1, &[]);
}

#[test]
fn restart_equals_uninterrupted_run_two_ranks_coulomb_outer() {
    check_restart(2, &["--coulomb", "outer"]);
}

#[test]
fn restart_equals_uninterrupted_run_two_ranks_of_two_subdomains() {
    check_restart(2, &["--subdomains-per-rank", "2"]);
}

/// Frictionless, every node at zero gap: r is retuned after sweep 1, before the
/// checkpoint of sweep 2, so the restart must refactor with the retuned r to continue
/// exactly (the run converges at sweep 5).
#[test]
fn restart_after_a_retune_of_r_continues_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let case = common::builtin_with_friction("block", 1, "friction = \"none\"");
    let path = tmp.path().join("case.toml");
    std::fs::write(&path, case).unwrap();
    check_restart_in(tmp.path(), 2, &[path.to_str().unwrap()], &[], (4, 2));
    let s = common::read_summary(&tmp.path().join("stopped/summary.json"));
    assert!(s["r_retunes"].as_u64().unwrap() >= 1, "{s}");
}

/// A slender beam: the loop lowers r before its first sweep (the body is far softer
/// than a compact one); the restart must continue with that r, not the automatic one.
#[test]
fn restart_after_r_was_lowered_for_a_slender_body_continues_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let case: std::path::PathBuf = [
        env!("CARGO_MANIFEST_DIR"),
        "tests/data/tolerance/cantilever.toml",
    ]
    .iter()
    .collect();
    // 73 sweeps in all, 10 retunes (several before the checkpoint of sweep 40).
    check_restart_in(tmp.path(), 2, &[case.to_str().unwrap()], &[], (50, 20));
    let s = common::read_summary(&tmp.path().join("straight/summary.json"));
    let (r, r_loop) = (common::num(&s, "r"), common::num(&s, "r_loop"));
    assert!(r_loop < 0.5 * r, "r {r}, r_loop {r_loop}");
}

#[test]
fn restart_with_another_rank_count_is_refused_clearly() {
    let tmp = tempfile::tempdir().unwrap();
    let base = [
        "--builtin",
        "block",
        "--level",
        "0",
        "--quiet",
        "--out",
        "o",
    ];
    let with = |more: &[&'static str]| -> Vec<&str> { base.iter().chain(more).copied().collect() };
    let o = run(
        2,
        &with(&["--max-iter", "6", "--checkpoint-every", "3"]),
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(3));
    let o = run(1, &with(&["--restart"]), tmp.path());
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("mpirun -n 2"), "{err}");
    // Two subdomains, but on one rank: another layout, refused as clearly.
    let o = run(
        1,
        &with(&["--restart", "--subdomains-per-rank", "2"]),
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("mpirun -n 2 and --subdomains-per-rank 1"),
        "{err}"
    );
}

/// A checkpoint of another format (as written before formats were named: the layout
/// first) is refused in one line naming the file, not misread; so is a checkpoint of the
/// automatic r resumed with a given r.
#[test]
fn a_checkpoint_of_another_format_or_policy_is_refused_clearly() {
    let tmp = tempfile::tempdir().unwrap();
    let base = [
        "--builtin",
        "block",
        "--level",
        "0",
        "--quiet",
        "--out",
        "o",
    ];
    let with = |more: &[&'static str]| -> Vec<&str> { base.iter().chain(more).copied().collect() };
    let refused = |args: &[&str], what: &str| {
        let o = run(1, args, tmp.path());
        assert_eq!(o.status.code(), Some(2));
        let err = String::from_utf8_lossy(&o.stderr);
        // mpirun adds its own lines.
        let lines: Vec<&str> = err.lines().filter(|l| l.contains("contact-par")).collect();
        assert_eq!(lines.len(), 1, "{err}");
        assert!(lines[0].starts_with("contact-par: error:"), "{err}");
        assert!(
            lines[0].contains(what) && lines[0].contains("without --restart"),
            "{err}"
        );
    };
    let o = run(
        1,
        &with(&["--max-iter", "6", "--checkpoint-every", "3"]),
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(3));
    refused(
        &with(&["--restart", "--r", "1e5"]),
        "this run has a given r (--r)",
    );
    let file = tmp.path().join("o/checkpoint/rank_0.bin");
    let bytes = std::fs::read(&file).unwrap();
    // The format's name (after its length, one byte) dropped.
    let format = contact_par::contact::Snapshot::FORMAT;
    assert_eq!(&bytes[1..1 + format.len()], format.as_bytes());
    std::fs::write(&file, &bytes[1 + format.len()..]).unwrap();
    refused(
        &with(&["--restart"]),
        "rank_0.bin: not a checkpoint of this version",
    );
}

/// The process ids of mpirun's children running the solver.
fn ranks_of(mpirun_pid: u32) -> Vec<u32> {
    let mut pids = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        // "pid (comm) state ppid ..."; comm may hold spaces, so split after the ')'.
        let Some(close) = stat.rfind(')') else {
            continue;
        };
        let comm = &stat[stat.find('(').unwrap_or(0) + 1..close];
        let ppid: u32 = stat[close + 2..]
            .split_whitespace()
            .nth(1)
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        if ppid == mpirun_pid && comm.starts_with("contact-par") {
            pids.push(pid);
        }
    }
    pids
}

#[test]
fn killing_one_rank_ends_the_job_within_ten_seconds() {
    let tmp = tempfile::tempdir().unwrap();
    // Plain ALG2 with a far too small r crawls: the loop runs for a minute or more.
    let mut child = common::mpirun(2, tmp.path())
        .args([
            "--builtin",
            "block",
            "--level",
            "2",
            "--acceleration",
            "none",
            "--r",
            "1",
            "--max-iter",
            "2000000",
            "--quiet",
            "--out",
            "o",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait until both ranks exist and have had time to enter the loop.
    let start = Instant::now();
    let mut pids = Vec::new();
    while start.elapsed() < Duration::from_secs(30) {
        pids = ranks_of(child.id());
        if pids.len() == 2 {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(pids.len(), 2, "did not find the two ranks");
    std::thread::sleep(Duration::from_secs(2));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the run ended before the kill; make it longer"
    );
    let victim = pids[1];
    let killed = Instant::now();
    Command::new("kill")
        .args(["-9", &victim.to_string()])
        .status()
        .unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if killed.elapsed() > Duration::from_secs(10) {
            let _ = child.kill();
            panic!("mpirun still running 10 s after a rank was killed");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(!status.success());
    // No half-written outputs under final names.
    assert!(!tmp.path().join("o/summary.json").exists());
}
