//! The bad-input corpus: every case in `tests/bad-inputs/` must be refused the way a user
//! should see it, and no input, however mangled, may panic a parser or the checks.
//!
//! A case is `NAME.toml` (a case file, usually on a built-in mesh) or a folder `NAME/`
//! holding `case.toml` and the files it uses, with a sibling `NAME.expected` whose first
//! line must appear in the error message, optionally `NAME.ranks` (a number) to run it
//! under `mpirun -n N` and `NAME.args` (one line) for extra command-line arguments, e.g. a
//! bad `--max-iter 0`. Names starting with `_` are not cases (`_good/` is the sound
//! baseline that the mesh cases each spoil in one way). Cases are found by listing the
//! folder: a new file is a new case, with no code to write.
//!
//! The contract checked for every case: exit code 2; on stderr exactly one line starting
//! with `contact-par: error:` (the only line at all on one rank), which contains the
//! expected text and starts with the name of the faulty file (the case file or the mesh
//! it names); nothing on stdout; no file written; no `panicked` anywhere.

use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use contact_par::error::Error;

const BIN: &str = env!("CARGO_BIN_EXE_contact-par");
const PREFIX: &str = "contact-par: error: ";

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad-inputs")
}

/// One case of the corpus.
struct Case {
    name: String,
    /// `NAME.toml`, or the folder `NAME/`.
    source: PathBuf,
    expected: String,
    ranks: Option<usize>,
    /// Extra command-line arguments.
    args: Vec<String>,
}

impl Case {
    fn is_folder(&self) -> bool {
        self.source.is_dir()
    }

    /// The case file's name as the binary is given it.
    fn case_file(&self) -> String {
        if self.is_folder() {
            "case.toml".into()
        } else {
            format!("{}.toml", self.name)
        }
    }
}

/// Every case, sorted by name; panics on a case without its `.expected` or the reverse.
fn cases() -> Vec<Case> {
    let dir = corpus();
    let mut names = BTreeSet::new();
    let mut expected = BTreeSet::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let entry = entry.unwrap();
        let file = entry.file_name().to_string_lossy().into_owned();
        if file.starts_with('_') || file.starts_with('.') {
            continue;
        }
        let path = entry.path();
        if path.is_dir() {
            assert!(path.join("case.toml").is_file(), "{file}/ has no case.toml");
            names.insert(file);
        } else if let Some(stem) = file.strip_suffix(".toml") {
            names.insert(stem.to_string());
        } else if let Some(stem) = file.strip_suffix(".expected") {
            expected.insert(stem.to_string());
        } else {
            assert!(
                file.ends_with(".ranks") || file.ends_with(".args") || file.ends_with(".md"),
                "{file}: not a case, an .expected, .ranks or .args file"
            );
        }
    }
    let orphans: Vec<_> = expected.difference(&names).collect();
    assert!(orphans.is_empty(), ".expected without a case: {orphans:?}");
    names
        .into_iter()
        .map(|name| {
            let text = std::fs::read_to_string(dir.join(format!("{name}.expected")))
                .unwrap_or_else(|_| panic!("case {name} has no {name}.expected"));
            let expected = text.lines().next().unwrap_or_default().to_string();
            assert!(!expected.trim().is_empty(), "{name}.expected is empty");
            let ranks = std::fs::read_to_string(dir.join(format!("{name}.ranks")))
                .ok()
                .map(|r| r.trim().parse().expect("a .ranks file holds a number"));
            let args = std::fs::read_to_string(dir.join(format!("{name}.args")))
                .map(|a| a.split_whitespace().map(String::from).collect())
                .unwrap_or_default();
            let folder = dir.join(&name);
            let source = if folder.is_dir() {
                folder
            } else {
                dir.join(format!("{name}.toml"))
            };
            Case {
                name,
                source,
                expected,
                ranks,
                args,
            }
        })
        .collect()
}

/// The files of a directory, recursively, relative to it.
fn files(dir: &Path) -> BTreeSet<PathBuf> {
    let mut out = BTreeSet::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path.clone());
            }
            out.insert(path.strip_prefix(dir).unwrap().to_path_buf());
        }
    }
    out
}

/// Copies the case into `dir` (a folder's files side by side, as the case expects).
fn stage(case: &Case, dir: &Path) {
    if case.is_folder() {
        for entry in std::fs::read_dir(&case.source).unwrap() {
            let path = entry.unwrap().path();
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
        }
    } else {
        std::fs::copy(&case.source, dir.join(case.case_file())).unwrap();
    }
}

struct Outcome {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

/// Runs the binary in `dir` (under mpirun when `ranks` is given), killed after a minute:
/// bad input must never hang a rank.
fn run(dir: &Path, ranks: Option<usize>, args: &[&str]) -> Outcome {
    // A TMPDIR of its own for a run without mpirun (see `session_dir` in tests/common).
    let session = tempfile::TempDir::new().expect("cannot make a session directory");
    let mut cmd = match ranks {
        Some(n) => {
            let mut c = Command::new("mpirun");
            c.args(["-n", &n.to_string(), "--oversubscribe", BIN]);
            c.env("OMPI_MCA_rmaps_base_oversubscribe", "1");
            // A session directory of its own: parallel mpiruns race on a shared one (see
            // `mpirun` in tests/common).
            c.env("TMPDIR", dir);
            c
        }
        None => {
            let mut c = Command::new(BIN);
            c.env("TMPDIR", session.path());
            c
        }
    };
    let mut child = cmd
        .args(args)
        .current_dir(dir)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("RAYON_NUM_THREADS", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cannot start contact-par (or mpirun)");
    // Read both pipes while waiting, so that a chatty failure cannot block on a full pipe.
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut s = Vec::new();
        out.read_to_end(&mut s).ok();
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = Vec::new();
        err.read_to_end(&mut s).ok();
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > Duration::from_secs(60) {
            child.kill().ok();
            child.wait().ok();
            break None;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    Outcome {
        code: status.and_then(|s| s.code()),
        stdout: String::from_utf8_lossy(&out.join().unwrap()).into_owned(),
        stderr: String::from_utf8_lossy(&err.join().unwrap()).into_owned(),
    }
}

/// The files a message may name first: the case file and the mesh file it points to.
fn input_files(case: &Case, dir: &Path) -> Vec<String> {
    let case_file = case.case_file();
    let mut names = vec![case_file.clone()];
    let mesh = std::fs::read_to_string(dir.join(&case_file))
        .ok()
        .and_then(|t| t.parse::<toml::Table>().ok())
        .and_then(|t| t.get("mesh")?.get("file")?.as_str().map(String::from));
    names.extend(mesh);
    names
}

/// Runs one case and returns what is wrong with the outcome, if anything.
fn check(case: &Case) -> Result<String, String> {
    let tmp = tempfile::tempdir().unwrap();
    stage(case, tmp.path());
    let before = files(tmp.path());
    let case_file = case.case_file();
    let mut args = vec![case_file.as_str(), "--out", "out"];
    args.extend(case.args.iter().map(String::as_str));
    let o = run(tmp.path(), case.ranks, &args);
    let context = || {
        format!(
            "exit code {:?}\n--- stdout\n{}--- stderr\n{}",
            o.code, o.stdout, o.stderr
        )
    };
    if o.code != Some(2) {
        return Err(format!("expected exit code 2; {}", context()));
    }
    if (o.stdout.clone() + &o.stderr).contains("panicked") {
        return Err(format!("a panic; {}", context()));
    }
    if !o.stdout.trim().is_empty() {
        return Err(format!("something on stdout; {}", context()));
    }
    let errors: Vec<&str> = o
        .stderr
        .lines()
        .filter(|l| l.starts_with("contact-par"))
        .collect();
    let [line] = errors[..] else {
        return Err(format!(
            "expected one contact-par line on stderr; {}",
            context()
        ));
    };
    // On one rank nothing else may appear; mpirun may add notes of its own.
    if case.ranks.is_none() && o.stderr.lines().count() != 1 {
        return Err(format!("stderr is not one line; {}", context()));
    }
    let Some(msg) = line.strip_prefix(PREFIX) else {
        return Err(format!("the line does not start with {PREFIX:?}: {line}"));
    };
    if !msg.contains(&case.expected) {
        return Err(format!("the message lacks {:?}: {line}", case.expected));
    }
    let mut names = input_files(case, tmp.path());
    // A bad option is named as such.
    names.push("command line".into());
    if !names.iter().any(|n| msg.starts_with(&format!("{n}:"))) {
        return Err(format!(
            "the message does not start with one of {names:?}: {line}"
        ));
    }
    let after = files(tmp.path());
    if after != before {
        let new: Vec<_> = after.difference(&before).collect();
        return Err(format!("files were written: {new:?}"));
    }
    Ok(line.to_string())
}

/// Checks `cases`, printing the message of each; returns the failures.
fn check_all(part: &str, cases: &[Case]) -> Vec<String> {
    cases
        .iter()
        .filter_map(|case| match check(case) {
            Ok(line) => {
                println!("{part} ok   {:<36} {line}", case.name);
                None
            }
            Err(why) => Some(format!("{}: {why}", case.name)),
        })
        .collect()
}

#[test]
fn every_bad_input_is_refused_with_one_clear_line() {
    let cases = cases();
    assert!(cases.len() >= 50, "only {} cases found", cases.len());
    // Two at a time: the machines have two cores, and mpirun cases take a second.
    let (a, b) = cases.split_at(cases.len() / 2);
    let failures: Vec<String> = std::thread::scope(|s| {
        let first = s.spawn(|| check_all("a", a));
        let mut failures = check_all("b", b);
        failures.extend(first.join().unwrap());
        failures
    });
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n\n")
    );
}

/// The sound baseline runs: the mesh cases fail for what each one spoils, not for
/// something they share.
#[test]
fn the_baseline_of_the_mesh_cases_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let good = Case {
        name: "_good".into(),
        source: corpus().join("_good"),
        expected: String::new(),
        ranks: None,
        args: Vec::new(),
    };
    stage(&good, tmp.path());
    let o = run(tmp.path(), None, &["case.toml", "--out", "out", "--quiet"]);
    assert_eq!(o.code, Some(0), "{}{}", o.stdout, o.stderr);
    assert!(tmp.path().join("out/contact.csv").is_file());
}

// ---- mutations: no input may panic (a stable stand-in for `cargo fuzz`, see fuzz/) ----

/// xorshift64: the same mutations on every run, so a failure reproduces.
struct Rng(u64);

impl Rng {
    fn below(&mut self, bound: usize) -> usize {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 % bound.max(1) as u64) as usize
    }
}

/// One to three edits: a byte replaced by an interesting one or a random one, a run
/// deleted, a byte inserted, or a run duplicated (which repeats keys, sections, records).
fn mutate(rng: &mut Rng, input: &[u8], interesting: &[u8]) -> Vec<u8> {
    let mut bytes = input.to_vec();
    for _ in 0..1 + rng.below(3) {
        if bytes.is_empty() {
            break;
        }
        let at = rng.below(bytes.len());
        let end = (at + 1 + rng.below(24)).min(bytes.len());
        match rng.below(5) {
            0 => bytes[at] = interesting[rng.below(interesting.len())],
            1 => bytes[at] = rng.below(256) as u8,
            2 => {
                bytes.drain(at..end);
            }
            3 => bytes.insert(at, interesting[rng.below(interesting.len())]),
            _ => {
                let run = bytes[at..end].to_vec();
                bytes.splice(at..at, run);
            }
        }
    }
    bytes
}

/// Runs `f` on `input`; a panic fails the test and leaves the input in the target folder
/// as a regression case to add to the corpus.
fn no_panic(what: &str, input: &[u8], f: impl FnOnce() -> contact_par::error::Result<()>) {
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    match result {
        Ok(Ok(())) => {}
        Ok(Err(Error::Input(msg))) => {
            assert!(
                !msg.contains('\n'),
                "{what}: a message of several lines: {msg}"
            );
            assert!(
                msg.starts_with("fuzz."),
                "{what}: the message does not name the file: {msg}"
            );
        }
        Ok(Err(e)) => panic!("{what}: not an input error: {e:?}"),
        Err(_) => {
            let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("crash-{what}"));
            std::fs::write(&path, input).unwrap();
            panic!("{what} panicked; the input is in {}", path.display());
        }
    }
}

#[test]
fn mutated_case_files_never_panic() {
    let mut texts: Vec<Vec<u8>> = contact_par::case::BUILTIN_CASES
        .iter()
        .map(|n| {
            contact_par::case::builtin_case_text(n, 0)
                .unwrap()
                .into_bytes()
        })
        .collect();
    for entry in std::fs::read_dir(corpus()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            texts.push(std::fs::read(path).unwrap());
        }
    }
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let interesting = b"[]=\"'#\n .-+e0123456789nafitrueinfnan,{}";
    for (k, text) in texts.iter().enumerate() {
        for i in 0..400 {
            let bytes = mutate(&mut rng, text, interesting);
            let text = String::from_utf8_lossy(&bytes);
            no_panic(&format!("case-{k}-{i}"), &bytes, || {
                contact_par::case::parse_case(&text, "fuzz.toml", Path::new(".")).map(|_| ())
            });
        }
    }
}

#[test]
fn mutated_meshes_never_panic_the_reader_or_the_checks() {
    let good = corpus().join("_good");
    let case_text = std::fs::read_to_string(good.join("case.toml")).unwrap();
    let case = contact_par::case::parse_case(&case_text, "fuzz.toml", Path::new(".")).unwrap();
    let mut meshes = vec![std::fs::read(good.join("mesh.msh")).unwrap()];
    for entry in std::fs::read_dir(corpus()).unwrap() {
        let path = entry.unwrap().path().join("mesh.msh");
        if let Ok(bytes) = std::fs::read(&path) {
            meshes.push(bytes);
        }
    }
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gmsh");
    for entry in std::fs::read_dir(fixtures).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "msh") {
            meshes.push(std::fs::read(path).unwrap());
        }
    }
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let interesting = b"$\n -.09eE\x00\xff\x01\x7f\"";
    for (k, mesh) in meshes.iter().enumerate() {
        for i in 0..300 {
            let bytes = mutate(&mut rng, mesh, interesting);
            no_panic(&format!("mesh-{k}-{i}"), &bytes, || {
                let mesh = contact_par::mesh::gmsh::parse_msh(&bytes, "fuzz.msh")?;
                contact_par::problem::build(&case, mesh, "fuzz.msh").map(|_| ())
            });
        }
    }
}
