//! The pictures of a run: contact.png and convergence.png are PNGs of the stated size
//! whose curves are contact.csv's and history.csv's values, drawn where the picture's own
//! frames put them (checked pixel by pixel, with a control that the check can fail);
//! --no-plots writes none; a picture that cannot be written is a warning, not a failure.

mod common;
use common::*;
use contact_par::output::plot::{
    frames_of, Frame, CONTACT_SIZE, CONVERGENCE_SIZE, ERROR_COLOUR, PAIR_COLOURS, REFUSED_COLOUR,
    RETUNE_COLOUR,
};
use std::path::Path;

/// A decoded picture: width, height, RGB pixels, and its frames.
struct Picture {
    width: u32,
    height: u32,
    pixels: Vec<u8>,
    frames: Vec<Frame>,
}

fn picture(path: &Path) -> Picture {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::Cursor::new(&bytes[..]))
        .read_info()
        .unwrap_or_else(|e| panic!("{} is not a PNG: {e}", path.display()));
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb, "{}", path.display());
    let frames = frames_of(&bytes).expect("the picture's frames");
    Picture {
        width: info.width,
        height: info.height,
        pixels,
        frames,
    }
}

impl Picture {
    fn frame(&self, panel: &str) -> &Frame {
        let found = self.frames.iter().find(|f| f.panel == panel);
        found.unwrap_or_else(|| panic!("no panel {panel} in {:?}", self.frames))
    }

    /// Whether a pixel of `colour` lies within `radius` of `at` (column, row).
    fn colour_near(&self, at: (f64, f64), colour: [u8; 3], radius: i32) -> bool {
        let (cx, cy) = (at.0.round() as i32, at.1.round() as i32);
        (-radius..=radius).any(|dy| {
            (-radius..=radius).any(|dx| {
                let (x, y) = (cx + dx, cy + dy);
                let inside = x >= 0 && y >= 0 && x < self.width as i32 && y < self.height as i32;
                let k = 3 * (y as usize * self.width as usize + x as usize);
                inside && self.pixels[k..k + 3] == colour
            })
        })
    }

    /// How many of the points (x, y) of `panel` show `colour` where the frame puts them.
    fn shown(&self, panel: &str, points: &[(f64, f64)], colour: [u8; 3]) -> usize {
        let f = self.frame(panel);
        let at = |&(x, y): &(f64, f64)| f.pixel(x, y);
        points
            .iter()
            .filter(|p| self.colour_near(at(p), colour, 1))
            .count()
    }

    /// Asserts that every point is drawn, and that the same points a quarter of the
    /// panel higher mostly are not (the check tells drawn values from others).
    fn assert_drawn(&self, panel: &str, points: &[(f64, f64)], colour: [u8; 3]) {
        assert!(!points.is_empty(), "{panel}: no points");
        let shown = self.shown(panel, points, colour);
        assert_eq!(
            shown,
            points.len(),
            "{panel}: {shown} of {} points drawn",
            points.len()
        );
        let f = self.frame(panel);
        let lift = |&(x, y): &(f64, f64)| match f.log_y {
            true => (x, y * (f.y[1] / f.y[0]).powf(0.25)),
            false => (x, y + 0.25 * (f.y[1] - f.y[0])),
        };
        let lifted: Vec<(f64, f64)> = points.iter().map(lift).collect();
        let found = self.shown(panel, &lifted, colour);
        assert!(
            found * 4 < points.len(),
            "{panel}: {found} of {} lifted points found as well",
            points.len()
        );
    }
}

/// The sweeps at which a cumulative count of history.csv grew.
fn grew(counts: &[f64], sweeps: &[f64]) -> Vec<f64> {
    let mut before = 0.0;
    let mut at = Vec::new();
    for (&c, &k) in counts.iter().zip(sweeps) {
        if c > before {
            at.push(k);
        }
        before = c;
    }
    at
}

/// Checks convergence.png against history.csv: the error estimate of every sweep, a
/// dashed line before each sweep with a retuned r, a cross on each refused point; returns
/// the number of retunes and refusals seen.
fn check_convergence(out: &Path, frictional: bool) -> (usize, usize) {
    let pic = picture(&out.join("convergence.png"));
    assert_eq!((pic.width, pic.height), CONVERGENCE_SIZE);
    let f = pic.frame("convergence");
    assert!(f.log_y);
    assert_eq!(
        f.colour("p_t change").is_some(),
        frictional,
        "{:?}",
        f.series
    );
    let (header, rows) = read_history(out);
    let sweeps = history_column(&header, &rows, "iteration");
    let error = history_column(&header, &rows, "error_estimate");
    let points: Vec<(f64, f64)> = sweeps
        .iter()
        .zip(&error)
        .map(|(&k, &e)| (k, e))
        .filter(|&(_, e)| e > 0.0 && e.is_finite())
        .collect();
    assert_eq!(f.colour("error estimate"), Some(ERROR_COLOUR));
    pic.assert_drawn("convergence", &points, ERROR_COLOUR);
    let retunes = grew(&history_column(&header, &rows, "retunes"), &sweeps);
    for &k in &retunes {
        // Dashed: 6 pixels on, 5 off, down the panel.
        let hits = (0..50)
            .filter(|i| {
                let y = f.y[0] * (f.y[1] / f.y[0]).powf((*i as f64 + 0.5) / 50.0);
                pic.colour_near(f.pixel(k - 0.5, y), RETUNE_COLOUR, 0)
            })
            .count();
        assert!(hits >= 15, "retune before sweep {k}: {hits} of 50 pixels");
    }
    let refused = grew(
        &history_column(&header, &rows, "refused_accelerations"),
        &sweeps,
    );
    for &k in &refused {
        let at = f.pixel(k, error[k as usize - 1]);
        // A cross of arms 6 pixels long, under the error's dot.
        assert!(
            pic.colour_near(at, REFUSED_COLOUR, 6),
            "refusal at sweep {k}"
        );
    }
    (retunes.len(), refused.len())
}

/// Checks contact.png against contact.csv, positions along the foundation through
/// `point` with unit tangent `tangent`.
fn check_contact(out: &Path, frictional: bool, point: [f64; 2], tangent: [f64; 2]) {
    let pic = picture(&out.join("contact.png"));
    assert_eq!((pic.width, pic.height), CONTACT_SIZE);
    let panels: Vec<&str> = pic.frames.iter().map(|f| f.panel.as_str()).collect();
    let want = match frictional {
        true => vec!["p_n", "p_t", "u_n"],
        false => vec!["p_n", "u_n"],
    };
    assert_eq!(panels, want);
    let rows = read_contact(&out.join("contact.csv"));
    let s = |r: &Row| (r.x - point[0]) * tangent[0] + (r.y - point[1]) * tangent[1];
    let colour = PAIR_COLOURS[0];
    for (panel, value) in [
        ("p_n", (|r: &Row| r.p_n) as fn(&Row) -> f64),
        ("p_t", |r: &Row| r.p_t),
        ("u_n", |r: &Row| r.u_n),
    ] {
        if !panels.contains(&panel) {
            continue;
        }
        let points: Vec<(f64, f64)> = rows.iter().map(|r| (s(r), value(r))).collect();
        pic.assert_drawn(panel, &points, colour);
    }
}

#[test]
fn frictionless_pictures_are_contact_csv_and_history_csv() {
    let run = run_builtin("hertz", 1, &[]);
    run.expect_code(0);
    check_contact(&run.out, false, [0.0, 0.0], [1.0, 0.0]);
    let (retunes, _) = check_convergence(&run.out, false);
    assert!(retunes >= 1, "no retune to check");
}

#[test]
fn frictional_pictures_are_contact_csv_and_history_csv() {
    // A tilted foundation: positions along it are not x.
    let t: f64 = 1e-3;
    let (normal, tangent) = ([t.sin(), t.cos()], [t.cos(), -t.sin()]);
    let run = run_case(
        &block_case(
            0,
            "ux = 0.01\nuy = -0.02",
            "friction = \"tresca\"\nthreshold = 20.0",
            normal,
            "",
        ),
        &[],
    );
    run.expect_code(0);
    check_contact(&run.out, true, [0.0, -0.001], tangent);
    check_convergence(&run.out, true);
}

#[test]
fn refused_accelerations_are_marked() {
    // Coulomb at level 2: the safeguard refuses an accelerated point. (Coulomb by
    // outer Tresca solves refused some before the tangents of Tresca solves followed
    // their statuses, none since.)
    let run = run_builtin("block", 2, &["--threads", "1"]);
    run.expect_code(0);
    let (retunes, refused) = check_convergence(&run.out, true);
    assert!(
        retunes >= 1 && refused >= 1,
        "{retunes} retunes, {refused} refusals"
    );
    assert_eq!(
        num(&run.summary(), "refused_accelerations") as usize,
        refused,
        "history.csv and summary.json disagree"
    );
}

fn pictures_in(out: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".png"))
        .collect();
    names.sort();
    names
}

#[test]
fn no_plots_writes_none_and_removes_those_of_an_earlier_run() {
    let dir = tempfile::TempDir::new().unwrap();
    let args = [
        "--builtin",
        "block",
        "--level",
        "0",
        "--out",
        "out",
        "--quiet",
    ];
    let (code, _, err) = run_in(dir.path(), &args);
    assert_eq!(code, 0, "{err}");
    let out = dir.path().join("out");
    assert_eq!(pictures_in(&out), ["contact.png", "convergence.png"]);
    let (code, stdout, err) = run_in(dir.path(), &[&args[..], &["--no-plots"]].concat());
    assert_eq!(code, 0, "{err}");
    assert!(stdout.is_empty() && err.is_empty(), "{stdout}{err}");
    assert!(pictures_in(&out).is_empty(), "{:?}", pictures_in(&out));
    assert!(out.join("contact.csv").exists() && out.join("summary.json").exists());
}

#[test]
fn a_picture_that_cannot_be_written_is_a_warning() {
    let dir = tempfile::TempDir::new().unwrap();
    // A directory with a file in it under the picture's name: the rename fails.
    let blocked = dir.path().join("out/contact.png");
    std::fs::create_dir_all(&blocked).unwrap();
    std::fs::write(blocked.join("keep"), b"").unwrap();
    let (code, stdout, stderr) = run_in(
        dir.path(),
        &[
            "--builtin",
            "hertz",
            "--level",
            "0",
            "--out",
            "out",
            "--quiet",
        ],
    );
    assert_eq!(code, 0, "{stdout}{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    let [line] = lines[..] else {
        panic!("expected one warning line: {stderr}")
    };
    assert!(
        line.starts_with("contact-par: warning:") && line.contains("contact.png"),
        "{line}"
    );
    assert!(!stderr.contains("panicked"));
    let out = dir.path().join("out");
    assert!(blocked.join("keep").exists());
    // The other picture and every table are written.
    check_convergence(&out, false);
    assert!(!read_contact(&out.join("contact.csv")).is_empty());
    assert_eq!(read_summary(&out.join("summary.json"))["converged"], true);
}
