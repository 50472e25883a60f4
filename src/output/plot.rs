//! The run's two pictures, drawn by the first subdomain from what it already gathered:
//! `contact.png` (p_n, p_t and u_n along the foundation, one colour per contact pair) from
//! the contact rows, and `convergence.png` (the loop's residuals per sweep on a log scale,
//! retunes of r and refused accelerations marked) from the history.
//!
//! The series are built by pure functions ([`pair_series`], [`convergence_series`]) from
//! the same rows as `contact.csv` and `history.csv`; plotters draws them into memory with
//! the font embedded in the executable (DejaVu Sans, `assets/fonts/`), so that no font need
//! be installed; the png crate encodes the pixels. Each PNG carries a text chunk
//! ([`FRAME_KEY`]) with every panel's [`Frame`]: its axes' ranges, where two corners fall
//! in pixels and the colour of each series, so that a program (the tests) can map values
//! to pixels and read the picture back.

use super::ContactRow;
use crate::contact::Sweep;
use plotters::coord::ranged1d::Ranged;
use plotters::coord::Shift;
use plotters::prelude::*;
use serde::{Deserialize, Serialize};
use std::sync::OnceLock;

/// Width and height of `contact.png`, in pixels.
pub const CONTACT_SIZE: (u32, u32) = (1200, 900);
/// Width and height of `convergence.png`, in pixels.
pub const CONVERGENCE_SIZE: (u32, u32) = (1200, 700);
/// The keyword of the PNG text chunk that holds the frames (JSON, a list of [`Frame`]).
pub const FRAME_KEY: &str = "contact-par frames";

const FONT: &str = "sans-serif";
static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// One colour per contact pair (Tableau 10): the first pair's is blue.
pub const PAIR_COLOURS: [[u8; 3]; 8] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
];

/// The colours of convergence.png, by series.
pub const ERROR_COLOUR: [u8; 3] = [0, 0, 0];
pub const PRESSURE_COLOUR: [u8; 3] = PAIR_COLOURS[0];
pub const TRACTION_COLOUR: [u8; 3] = PAIR_COLOURS[1];
pub const DISPLACEMENT_COLOUR: [u8; 3] = PAIR_COLOURS[2];
pub const TOL_COLOUR: [u8; 3] = [127, 127, 127];
pub const RETUNE_COLOUR: [u8; 3] = PAIR_COLOURS[4];
pub const REFUSED_COLOUR: [u8; 3] = PAIR_COLOURS[3];

/// A straight foundation, where positions are s = (x - point).tangent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Foundation {
    pub point: [f64; 2],
    pub tangent: [f64; 2],
}

impl Foundation {
    /// The abscissa's name: plain x where s is x (a foundation along the x axis through
    /// x = 0, as in every built-in case).
    pub fn axis_label(&self) -> &'static str {
        if self.tangent == [1.0, 0.0] && self.point[0] == 0.0 {
            "x"
        } else {
            "s = (x - obstacle_point).t, along the foundation"
        }
    }
}

/// The abscissa's name where the obstacles are not one straight foundation.
pub const ALONG_OBSTACLES: &str = "s, along each obstacle (arc length)";

/// The abscissa's name where every contact is between two bodies: each slave node's
/// position across its contact's mean normal.
pub const ACROSS_NORMALS: &str = "s, across each contact's mean normal";

/// One contact pair's curves, its nodes in the order of their position s along the
/// foundation.
#[derive(Debug, Clone, PartialEq)]
pub struct PairSeries {
    pub name: String,
    pub s: Vec<f64>,
    pub p_n: Vec<f64>,
    /// `None` without friction (there is no p_t to show).
    pub p_t: Option<Vec<f64>>,
    pub u_n: Vec<f64>,
    /// The initial gap, the bound of u_n.
    pub gap: Vec<f64>,
}

/// The curves of pair `pair` from the contact rows (those of other pairs left out):
/// sorted by their position s along the obstacle, ties by x then y (the order of
/// contact.csv).
pub fn pair_series(name: &str, pair: u32, rows: &[ContactRow], frictional: bool) -> PairSeries {
    let mut sorted: Vec<(f64, &ContactRow)> = rows
        .iter()
        .filter(|r| r.pair == pair)
        .map(|r| (r.s, r))
        .collect();
    sorted.sort_by(|(sa, a), (sb, b)| {
        sa.total_cmp(sb)
            .then(a.x.total_cmp(&b.x))
            .then(a.y.total_cmp(&b.y))
    });
    let column = |f: fn(&ContactRow) -> f64| sorted.iter().map(|(_, r)| f(r)).collect();
    PairSeries {
        name: name.to_string(),
        s: sorted.iter().map(|(s, _)| *s).collect(),
        p_n: column(|r| r.p_n),
        p_t: frictional.then(|| column(|r| r.p_t)),
        u_n: column(|r| r.u_n),
        gap: column(|r| r.gap),
    }
}

/// The loop's history as curves against the sweep number.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvergenceSeries {
    pub sweeps: Vec<f64>,
    /// The estimated relative error, which the loop stops on.
    pub error: Vec<f64>,
    /// The relative changes of p_n and p_t (the dual residuals) and of u (the primal).
    pub pressure: Vec<f64>,
    /// `None` without friction.
    pub traction: Option<Vec<f64>>,
    pub displacement: Vec<f64>,
    /// Sweeps that ran with a newly retuned r (the retune came just before them).
    pub retunes: Vec<f64>,
    /// Sweeps whose accelerated point the safeguard refused.
    pub refused: Vec<f64>,
    pub tol: f64,
}

/// The curves of `history` (the rows of history.csv).
pub fn convergence_series(history: &[Sweep], frictional: bool, tol: f64) -> ConvergenceSeries {
    let column = |f: fn(&Sweep) -> f64| history.iter().map(f).collect();
    // Both counts are cumulative: a sweep is marked where its count grew.
    let grew = |f: fn(&Sweep) -> usize| {
        let mut before = 0;
        let mut at = Vec::new();
        for s in history {
            if f(s) > before {
                at.push(s.iter as f64);
            }
            before = f(s);
        }
        at
    };
    ConvergenceSeries {
        sweeps: column(|s| s.iter as f64),
        error: column(|s| s.error),
        pressure: column(|s| s.pressure),
        traction: frictional.then(|| column(|s| s.traction)),
        displacement: column(|s| s.displacement),
        retunes: grew(|s| s.retunes),
        refused: grew(|s| s.refused),
        tol,
    }
}

/// One panel of a picture: its axes, where they fall in pixels, and its series.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// What the panel shows: "p_n", "p_t", "u_n" or "convergence".
    pub panel: String,
    /// The y axis is logarithmic.
    pub log_y: bool,
    /// The axes' ranges, [low, high].
    pub x: [f64; 2],
    pub y: [f64; 2],
    /// The pixels (column, row) of the corners (x low, y low) and (x high, y high).
    pub pixel_low: [i32; 2],
    pub pixel_high: [i32; 2],
    /// Each series' name and colour (RGB).
    pub series: Vec<(String, [u8; 3])>,
}

impl Frame {
    /// Where the point (x, y) falls in the picture: (column, row), in pixels.
    pub fn pixel(&self, x: f64, y: f64) -> (f64, f64) {
        let along = |v: f64, range: [f64; 2], log: bool| match log {
            true => (v.ln() - range[0].ln()) / (range[1].ln() - range[0].ln()),
            false => (v - range[0]) / (range[1] - range[0]),
        };
        let (fx, fy) = (along(x, self.x, false), along(y, self.y, self.log_y));
        let between = |a: i32, b: i32, f: f64| a as f64 + f * (b - a) as f64;
        (
            between(self.pixel_low[0], self.pixel_high[0], fx),
            between(self.pixel_low[1], self.pixel_high[1], fy),
        )
    }

    /// The colour of the series called `name`.
    pub fn colour(&self, name: &str) -> Option<[u8; 3]> {
        self.series.iter().find(|(n, _)| n == name).map(|(_, c)| *c)
    }
}

/// The frames a picture of this module carries, from its PNG bytes (`None` if it has
/// none): for programs that read values back off the picture.
pub fn frames_of(png_bytes: &[u8]) -> Option<Vec<Frame>> {
    let reader = png::Decoder::new(std::io::Cursor::new(png_bytes))
        .read_info()
        .ok()?;
    let chunk = reader
        .info()
        .utf8_text
        .iter()
        .find(|t| t.keyword == FRAME_KEY)?;
    serde_json::from_str(&chunk.get_text().ok()?).ok()
}

/// contact.png: a panel each for p_n, p_t (when a pair has friction) and u_n with the
/// initial gap (dashed where it is within u_n's range: where the body may touch), against
/// the position along the foundation; one colour per pair, named in the legend. `titles`
/// head the picture (what it shows, the case), `abscissa` names the x axis.
pub fn contact_png(
    titles: [&str; 2],
    abscissa: &str,
    pairs: &[PairSeries],
) -> Result<Vec<u8>, String> {
    render(CONTACT_SIZE, |root| {
        let body = heading(root, titles[0], titles[1])?;
        let (plots, legend) = body.split_horizontally(CONTACT_SIZE.0 - LEGEND_WIDTH);
        let frictional = pairs.iter().any(|p| p.p_t.is_some());
        let mut panels: Vec<(&str, &str)> = vec![("p_n", "contact pressure p_n")];
        if frictional {
            panels.push(("p_t", "tangential traction p_t"));
        }
        panels.push(("u_n", "normal displacement u_n (gap dashed)"));
        let areas = plots.split_evenly((panels.len(), 1));
        let x = span(pairs.iter().flat_map(|p| p.s.iter().copied()), false, 0.0);
        // Round-off (a u_n of 1e-16 where the body lies on the foundation, a p_t of
        // 1e-12 p_n) is drawn flat, not blown up to the panel's height.
        let abs_max = |v: &[f64]| {
            v.iter()
                .map(|x| x.abs())
                .filter(|x| x.is_finite())
                .fold(0.0, f64::max)
        };
        let force = pairs.iter().map(|p| abs_max(&p.p_n)).fold(0.0, f64::max);
        let floor = |name: &str| match name {
            "u_n" => 1e-9 * (x.1 - x.0),
            _ => 1e-9 * force,
        };
        let mut frames = Vec::new();
        for ((name, desc), area) in panels.into_iter().zip(&areas) {
            let mut curves = Vec::new();
            for (k, pair) in pairs.iter().enumerate() {
                let colour = PAIR_COLOURS[k % PAIR_COLOURS.len()];
                let label = |q: &str| format!("{q}: {}", pair.name);
                match name {
                    "p_n" => curves.push(Curve::solid(label("p_n"), &pair.s, &pair.p_n, colour)),
                    "p_t" => {
                        if let Some(p_t) = &pair.p_t {
                            curves.push(Curve::solid(label("p_t"), &pair.s, p_t, colour));
                        }
                    }
                    _ => {
                        // Under u_n, which must be seen where it meets the gap.
                        curves.push(Curve::dashed(label("gap"), &pair.s, &pair.gap, colour));
                        curves.push(Curve::solid(label("u_n"), &pair.s, &pair.u_n, colour));
                    }
                }
            }
            // The gap only bounds u_n: it does not set the range.
            let values = curves.iter().filter(|c| !c.dashed);
            let y = span(values.flat_map(|c| c.y.iter().copied()), true, floor(name));
            let axes = Axes {
                panel: name,
                x_desc: abscissa,
                y_desc: desc,
                x,
                y,
            };
            frames.push(linear_panel(area, &axes, &curves)?);
        }
        let mut entries: Vec<Entry> = pairs
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let name = format!("group {}", p.name);
                Entry::line(&name, PAIR_COLOURS[k % PAIR_COLOURS.len()])
            })
            .collect();
        entries.push(Entry::dashed("initial gap", TOL_COLOUR));
        draw_legend(&legend, "contact pair", &entries)?;
        Ok(frames)
    })
}

/// convergence.png: the estimated error (what the loop stops on) and the relative changes
/// of p_n, p_t and u per sweep on a log scale, tol dashed, a dashed vertical line before
/// each sweep with a retuned r and a cross on each refused accelerated point.
pub fn convergence_png(titles: [&str; 2], c: &ConvergenceSeries) -> Result<Vec<u8>, String> {
    render(CONVERGENCE_SIZE, |root| {
        let body = heading(root, titles[0], titles[1])?;
        let (plot, legend) = body.split_horizontally(CONVERGENCE_SIZE.0 - LEGEND_WIDTH);
        let mut curves = vec![
            Curve::solid("error estimate", &c.sweeps, &c.error, ERROR_COLOUR),
            Curve::solid("p_n change", &c.sweeps, &c.pressure, PRESSURE_COLOUR),
        ];
        if let Some(t) = &c.traction {
            curves.push(Curve::solid("p_t change", &c.sweeps, t, TRACTION_COLOUR));
        }
        curves.push(Curve::solid(
            "u change",
            &c.sweeps,
            &c.displacement,
            DISPLACEMENT_COLOUR,
        ));
        let frame = log_panel(&plot, c, &curves)?;
        let mut entries: Vec<Entry> = curves
            .iter()
            .map(|c| Entry::line(&c.label, c.colour))
            .collect();
        entries.push(Entry::dashed("tol", TOL_COLOUR));
        entries.push(Entry::dashed("r retuned", RETUNE_COLOUR));
        entries.push(Entry::cross("acceleration refused", REFUSED_COLOUR));
        draw_legend(&legend, "per sweep", &entries)?;
        Ok(vec![frame])
    })
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

const LEGEND_WIDTH: u32 = 240;
const TITLE_HEIGHT: u32 = 64;
/// Characters of the case's title that fit across the picture at its font size.
const MAX_TITLE_CHARS: usize = 140;

/// A curve of a panel.
struct Curve<'a> {
    label: String,
    x: &'a [f64],
    y: &'a [f64],
    colour: [u8; 3],
    dashed: bool,
}

impl<'a> Curve<'a> {
    fn solid(label: impl Into<String>, x: &'a [f64], y: &'a [f64], colour: [u8; 3]) -> Self {
        Curve {
            label: label.into(),
            x,
            y,
            colour,
            dashed: false,
        }
    }

    fn dashed(label: impl Into<String>, x: &'a [f64], y: &'a [f64], colour: [u8; 3]) -> Self {
        Curve {
            dashed: true,
            ..Curve::solid(label, x, y, colour)
        }
    }

    /// Its points in runs that `keep` keeps whole: a line is not drawn across a value
    /// left out (NaN, or on a log axis a value that is not positive).
    fn runs(&self, keep: impl Fn(f64) -> bool) -> Vec<Vec<(f64, f64)>> {
        let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
        let mut run = Vec::new();
        for (&x, &y) in self.x.iter().zip(self.y) {
            if x.is_finite() && y.is_finite() && keep(y) {
                run.push((x, y));
            } else if !run.is_empty() {
                runs.push(std::mem::take(&mut run));
            }
        }
        if !run.is_empty() {
            runs.push(run);
        }
        runs
    }
}

/// A legend line: a sample of the mark and its text.
struct Entry {
    text: String,
    colour: [u8; 3],
    mark: Mark,
}

enum Mark {
    Line,
    Dashed,
    Cross,
}

impl Entry {
    fn line(text: &str, colour: [u8; 3]) -> Self {
        Entry {
            text: text.to_string(),
            colour,
            mark: Mark::Line,
        }
    }

    fn dashed(text: &str, colour: [u8; 3]) -> Self {
        Entry {
            mark: Mark::Dashed,
            ..Entry::line(text, colour)
        }
    }

    fn cross(text: &str, colour: [u8; 3]) -> Self {
        Entry {
            mark: Mark::Cross,
            ..Entry::line(text, colour)
        }
    }
}

/// The axes of a linear panel.
struct Axes<'a> {
    panel: &'a str,
    x_desc: &'a str,
    y_desc: &'a str,
    x: (f64, f64),
    y: (f64, f64),
}

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

fn failed(e: impl std::fmt::Display) -> String {
    format!("drawing failed: {e}")
}

/// Draws with `draw` on a white picture of `size` and encodes it as PNG with the frames
/// `draw` returns.
fn render(
    size: (u32, u32),
    draw: impl FnOnce(&Area) -> Result<Vec<Frame>, String>,
) -> Result<Vec<u8>, String> {
    register_font()?;
    let mut pixels = vec![255u8; 3 * size.0 as usize * size.1 as usize];
    let frames = {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        let frames = draw(&root)?;
        root.present().map_err(failed)?;
        frames
    };
    encode(&pixels, size, &frames).map_err(|e| format!("PNG encoding failed: {e}"))
}

/// The embedded font, registered once for the process.
fn register_font() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    match ok {
        true => Ok(()),
        false => Err("the embedded font cannot be read".into()),
    }
}

fn encode(pixels: &[u8], size: (u32, u32), frames: &[Frame]) -> Result<Vec<u8>, String> {
    let json = serde_json::to_string(frames).map_err(|e| e.to_string())?;
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, size.0, size.1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    // Balanced makes files of two thirds the size in ten times the time (18 ms a picture).
    encoder.set_compression(png::Compression::Fast);
    // iTXt: UTF-8, as group names may be.
    encoder
        .add_itxt_chunk(FRAME_KEY.to_string(), json)
        .map_err(|e| e.to_string())?;
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    writer.write_image_data(pixels).map_err(|e| e.to_string())?;
    writer.finish().map_err(|e| e.to_string())?;
    Ok(bytes)
}

/// Writes `what` (what the picture shows) and under it `case` (the case's title,
/// shortened to fit) across the top of `root`; returns the area below.
fn heading<'a>(root: &Area<'a>, what: &str, case: &str) -> Result<Area<'a>, String> {
    let (top, body) = root.split_vertically(TITLE_HEIGHT);
    let case: String = match case.chars().count() > MAX_TITLE_CHARS {
        true => case
            .chars()
            .take(MAX_TITLE_CHARS - 3)
            .chain("...".chars())
            .collect(),
        false => case.to_string(),
    };
    top.draw(&Text::new(
        what.to_string(),
        (16, 8),
        (FONT, 20).into_font(),
    ))
    .and_then(|_| top.draw(&Text::new(case, (16, 36), (FONT, 15).into_font())))
    .map_err(failed)?;
    Ok(body)
}

/// Draws the legend `entries` under `heading` in `area`.
fn draw_legend(area: &Area, heading: &str, entries: &[Entry]) -> Result<(), String> {
    let text = |s: &str, at| Text::new(s.to_string(), at, (FONT, 15).into_font());
    area.draw(&text(heading, (10, 16))).map_err(failed)?;
    for (k, e) in entries.iter().enumerate() {
        let y = 48 + 26 * k as i32;
        let style = rgb(e.colour).stroke_width(2);
        match e.mark {
            Mark::Line => area.draw(&PathElement::new(vec![(10, y), (44, y)], style)),
            Mark::Dashed => area
                .draw(&PathElement::new(vec![(10, y), (18, y)], style))
                .and_then(|_| area.draw(&PathElement::new(vec![(26, y), (34, y)], style))),
            Mark::Cross => area.draw(&Cross::new((27, y), 5, style)),
        }
        .map_err(failed)?;
        // Text is placed by its top; centre it on the mark.
        area.draw(&text(&e.text, (52, y - 8))).map_err(failed)?;
    }
    Ok(())
}

/// Draws a panel with linear axes and its curves, each with a dot on every point, and
/// returns its frame.
fn linear_panel(area: &Area, axes: &Axes, curves: &[Curve]) -> Result<Frame, String> {
    let mut chart = ChartBuilder::on(area)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(90)
        .build_cartesian_2d(axes.x.0..axes.x.1, axes.y.0..axes.y.1)
        .map_err(failed)?;
    chart
        .configure_mesh()
        .x_desc(axes.x_desc)
        .y_desc(axes.y_desc)
        .x_label_formatter(&|v| tick(*v, axes.x))
        .y_label_formatter(&|v| tick(*v, axes.y))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .light_line_style(WHITE)
        .draw()
        .map_err(failed)?;
    let (lo, hi) = axes.y;
    for c in curves {
        for run in c.runs(|v| (lo..=hi).contains(&v)) {
            draw_run(&mut chart, run, c.colour, c.dashed)?;
        }
    }
    Ok(frame_of(&chart, axes.panel, false, axes.x, axes.y, curves))
}

/// The convergence panel: sweeps against a log axis of the curves, tol, the retunes and
/// the refused points.
fn log_panel(area: &Area, c: &ConvergenceSeries, curves: &[Curve]) -> Result<Frame, String> {
    let last = c.sweeps.last().copied().unwrap_or(1.0).max(1.0);
    let x = (0.5, last + 0.5);
    let positive = |v: f64| v > 0.0 && v.is_finite();
    let values = curves.iter().flat_map(|c| c.y.iter().copied());
    let y = decades(values.chain([c.tol]).filter(|&v| positive(v)));
    let mut chart = ChartBuilder::on(area)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(90)
        .build_cartesian_2d(x.0..x.1, (y.0..y.1).log_scale())
        .map_err(failed)?;
    chart
        .configure_mesh()
        .x_desc("sweep")
        .y_desc("relative change, estimated error")
        .x_label_formatter(&|v| tick(*v, x))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .light_line_style(WHITE)
        .draw()
        .map_err(failed)?;
    let dashed = |colour, points: Vec<(f64, f64)>| {
        DashedLineSeries::new(points, 6, 5, rgb(colour).stroke_width(2))
    };
    let drawn = chart
        .draw_series(dashed(TOL_COLOUR, vec![(x.0, c.tol), (x.1, c.tol)]))
        .map(drop);
    drawn.map_err(failed)?;
    for &k in &c.retunes {
        let line = dashed(RETUNE_COLOUR, vec![(k - 0.5, y.0), (k - 0.5, y.1)]);
        chart.draw_series(line).map_err(failed)?;
    }
    // Under the curves, whose points stay visible; the arms stand out.
    let refused = c.refused.iter().filter_map(|&k| {
        let error = c.error[c.sweeps.iter().position(|&s| s == k)?];
        positive(error).then(|| Cross::new((k, error), 6, rgb(REFUSED_COLOUR).stroke_width(2)))
    });
    chart.draw_series(refused).map_err(failed)?;
    // The error last, over the changes it is made of.
    for curve in curves.iter().rev() {
        for run in curve.runs(positive) {
            draw_run(&mut chart, run, curve.colour, false)?;
        }
    }
    let mut frame = frame_of(&chart, "convergence", true, x, y, curves);
    frame.series.extend([
        ("tol".to_string(), TOL_COLOUR),
        ("r retuned".to_string(), RETUNE_COLOUR),
        ("acceleration refused".to_string(), REFUSED_COLOUR),
    ]);
    Ok(frame)
}

/// Draws one run of a curve: dashed, or solid with a dot on every point.
fn draw_run<X, Y>(
    chart: &mut ChartContext<BitMapBackend, Cartesian2d<X, Y>>,
    run: Vec<(f64, f64)>,
    colour: [u8; 3],
    dashed: bool,
) -> Result<(), String>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let style = rgb(colour).stroke_width(2);
    if dashed {
        chart
            .draw_series(DashedLineSeries::new(run, 6, 5, style))
            .map_err(failed)?;
        return Ok(());
    }
    let dots: Vec<_> = run
        .iter()
        .map(|&p| Circle::new(p, 2, rgb(colour).filled()))
        .collect();
    chart
        .draw_series(LineSeries::new(run, style))
        .map_err(failed)?;
    chart.draw_series(dots).map_err(failed)?;
    Ok(())
}

/// The frame of a drawn chart.
fn frame_of<X, Y>(
    chart: &ChartContext<BitMapBackend, Cartesian2d<X, Y>>,
    panel: &str,
    log_y: bool,
    x: (f64, f64),
    y: (f64, f64),
    curves: &[Curve],
) -> Frame
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let (low, high) = (
        chart.backend_coord(&(x.0, y.0)),
        chart.backend_coord(&(x.1, y.1)),
    );
    Frame {
        panel: panel.to_string(),
        log_y,
        x: [x.0, x.1],
        y: [y.0, y.1],
        pixel_low: [low.0, low.1],
        pixel_high: [high.0, high.1],
        series: curves.iter().map(|c| (c.label.clone(), c.colour)).collect(),
    }
}

/// A range holding the finite `values` (and 0 if `with_zero`), at least `min_width`
/// wide, with a margin of 5% each side; never empty, so that an axis can be drawn
/// whatever the values.
fn span(values: impl Iterator<Item = f64>, with_zero: bool, min_width: f64) -> (f64, f64) {
    let start = if with_zero {
        (0.0, 0.0)
    } else {
        (f64::INFINITY, f64::NEG_INFINITY)
    };
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold(start, |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return (0.0, 1.0);
    }
    let (lo, hi) = match hi - lo < min_width {
        true => {
            let mid = 0.5 * (lo + hi);
            (mid - 0.5 * min_width, mid + 0.5 * min_width)
        }
        false => (lo, hi),
    };
    let width = hi - lo;
    let pad = if width > 0.0 {
        0.05 * width
    } else if lo != 0.0 {
        0.1 * lo.abs()
    } else {
        1.0
    };
    (lo - pad, hi + pad)
}

/// Whole decades around the positive `values`: [10^floor(log min), 10^ceil(log max)],
/// at least one decade wide.
fn decades(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if lo > hi {
        return (1e-1, 1e1);
    }
    let (a, b) = (lo.log10().floor(), hi.log10().ceil());
    let b = if b > a { b } else { a + 1.0 };
    (10f64.powf(a), 10f64.powf(b))
}

/// The label of tick `v` on an axis over `range`: one format for the whole axis, plain
/// with the decimals a tenth of the range needs where its values are of moderate size,
/// in exponent form otherwise; a value within round-off of 0 is 0.
fn tick(v: f64, range: (f64, f64)) -> String {
    let width = (range.1 - range.0).abs();
    let size = range.0.abs().max(range.1.abs());
    if v.abs() <= 1e-9 * width {
        return "0".into();
    }
    if (1e-3..1e6).contains(&size) && width > 0.0 {
        // The decimals a tenth of the range needs, more if the tick needs them.
        let mut decimals = (-(width / 10.0).log10()).ceil().clamp(0.0, 8.0) as usize;
        while decimals < 8
            && (format!("{v:.decimals$}").parse::<f64>().unwrap_or(v) - v).abs() > 1e-6 * width
        {
            decimals += 1;
        }
        let text = format!("{v:.decimals$}");
        match text.contains('.') {
            true => text.trim_end_matches('0').trim_end_matches('.').to_string(),
            false => text,
        }
    } else {
        format!("{v:.1e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::Status;

    fn row(x: f64, y: f64, v: f64) -> ContactRow {
        ContactRow {
            x,
            y,
            u_n: 2.0 * v,
            u_t: 3.0 * v,
            p_n: 4.0 * v,
            p_t: 5.0 * v,
            gap: 6.0 * v,
            status: Status::Free,
            w: 1.0,
            pair: 0,
            s: x,
            normal: [0.0, 1.0],
            to_master: 0.0,
            part: [0, crate::problem::NO_PART],
        }
    }

    #[test]
    fn pair_series_are_the_rows_sorted_along_the_foundation() {
        let mut rows = vec![row(2.0, 0.0, 1.0), row(-1.0, 0.5, 2.0), row(0.5, 0.0, 3.0)];
        let along_x = Foundation {
            point: [0.0, -1.0],
            tangent: [1.0, 0.0],
        };
        // Another pair's row is left out.
        rows.push(ContactRow {
            pair: 1,
            ..row(0.0, 0.0, 9.0)
        });
        let p = pair_series("bottom", 0, &rows, true);
        assert_eq!(p.name, "bottom");
        assert_eq!(p.s, [-1.0, 0.5, 2.0]);
        assert_eq!(p.p_n, [8.0, 12.0, 4.0]);
        assert_eq!(p.p_t, Some(vec![10.0, 15.0, 5.0]));
        assert_eq!(p.u_n, [4.0, 6.0, 2.0]);
        assert_eq!(p.gap, [12.0, 18.0, 6.0]);
        assert_eq!(along_x.axis_label(), "x");
        // Positions along another obstacle: the rows in their order.
        for (r, s) in rows.iter_mut().zip([-0.6, 1.6, 0.3]) {
            r.s = s;
        }
        let q = pair_series("bottom", 0, &rows, false);
        assert_eq!(q.s, [-0.6, 0.3, 1.6]);
        assert_eq!(q.p_n, [4.0, 12.0, 8.0]);
        assert_eq!(q.p_t, None);
        let tilted = Foundation {
            point: [1.0, 0.0],
            tangent: [-0.6, 0.8],
        };
        assert_ne!(tilted.axis_label(), "x");
    }

    fn sweep(iter: usize, error: f64, retunes: usize, refused: usize) -> Sweep {
        Sweep {
            iter,
            pressure: error / 2.0,
            traction: error / 3.0,
            displacement: error / 4.0,
            contraction: 0.5,
            error,
            active: 1,
            slip: 0,
            changed: 0,
            stiff: 0,
            soft: 0,
            mistuned: 0,
            mistuned_n: 0,
            unsettled: 0,
            uncertain: 0,
            pattern: 0,
            retunes,
            refused,
            roundoff: 0.0,
        }
    }

    #[test]
    fn convergence_series_mark_where_the_counts_grow() {
        let h = [
            sweep(1, 1.0, 0, 0),
            sweep(2, 0.5, 0, 1),
            sweep(3, 0.25, 1, 1),
            sweep(4, 0.125, 1, 2),
            sweep(5, 0.0625, 2, 2),
        ];
        let c = convergence_series(&h, false, 1e-8);
        assert_eq!(c.sweeps, [1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(c.error, [1.0, 0.5, 0.25, 0.125, 0.0625]);
        assert_eq!(c.pressure, [0.5, 0.25, 0.125, 0.0625, 0.03125]);
        assert_eq!(c.displacement[0], 0.25);
        assert_eq!(c.traction, None);
        assert_eq!(c.retunes, [3.0, 5.0]);
        assert_eq!(c.refused, [2.0, 4.0]);
        assert_eq!(c.tol, 1e-8);
        let f = convergence_series(&h, true, 1e-8);
        assert_eq!(f.traction.unwrap()[0], 1.0 / 3.0);
    }

    #[test]
    fn ranges_hold_the_values_and_are_never_empty() {
        assert_eq!(span([1.0, 3.0].into_iter(), false, 0.0), (0.9, 3.1));
        let (lo, hi) = span([1.0, 3.0].into_iter(), true, 0.0);
        assert!(lo < 0.0 && hi > 3.0);
        assert_eq!(span(std::iter::empty(), true, 0.0), (-1.0, 1.0));
        assert_eq!(span([f64::NAN].into_iter(), false, 0.0), (0.0, 1.0));
        let (lo, hi) = span([2.0, 2.0].into_iter(), false, 0.0);
        assert!(lo < 2.0 && hi > 2.0);
        // Round-off about 0 is drawn in a range of the given least width.
        let (lo, hi) = span([-1e-16, 2e-16].into_iter(), true, 1e-6);
        assert!(
            (hi - lo - 1.1e-6).abs() < 1e-12 && lo < -4e-7 && hi > 4e-7,
            "{lo} {hi}"
        );
        assert_eq!(decades([3e-9, 0.7].into_iter()), (1e-9, 1.0));
        assert_eq!(decades([1.0].into_iter()), (1.0, 10.0));
        assert_eq!(decades(std::iter::empty()), (0.1, 10.0));
    }

    #[test]
    fn curves_break_where_a_value_is_left_out() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        let y = [1.0, 0.0, 2.0, f64::NAN, 3.0];
        let c = Curve::solid("c", &x, &y, [0, 0, 0]);
        assert_eq!(
            c.runs(|v| v > 0.0),
            [vec![(1.0, 1.0)], vec![(3.0, 2.0)], vec![(5.0, 3.0)]]
        );
        assert_eq!(c.runs(|_| true).len(), 2);
    }

    /// The picture's size and RGB pixels.
    fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut pixels).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        (info.width, info.height, pixels)
    }

    /// Whether a pixel of `colour` lies within `radius` of `at`.
    fn colour_near(
        img: &(u32, u32, Vec<u8>),
        at: (f64, f64),
        colour: [u8; 3],
        radius: i32,
    ) -> bool {
        let (w, h, pixels) = img;
        let (cx, cy) = (at.0.round() as i32, at.1.round() as i32);
        (-radius..=radius).any(|dy| {
            (-radius..=radius).any(|dx| {
                let (x, y) = (cx + dx, cy + dy);
                let inside = x >= 0 && y >= 0 && x < *w as i32 && y < *h as i32;
                let k = 3 * (y as usize * *w as usize + x as usize);
                inside && pixels[k..k + 3] == colour
            })
        })
    }

    fn pair(frictional: bool) -> PairSeries {
        let s: Vec<f64> = (0..40).map(|i| i as f64 * 0.25).collect();
        let p_n: Vec<f64> = s
            .iter()
            .map(|x| (100.0 * (1.0 - x / 5.0)).max(0.0))
            .collect();
        PairSeries {
            name: "bottom".into(),
            p_t: frictional.then(|| p_n.iter().map(|p| -0.3 * p).collect()),
            u_n: s.iter().map(|x| 1e-3 * x * x).collect(),
            gap: s.iter().map(|x| 2e-3 * x * x).collect(),
            p_n,
            s,
        }
    }

    #[test]
    fn contact_picture_shows_each_value_where_its_frame_maps_it() {
        for frictional in [true, false] {
            let p = pair(frictional);
            let bytes = contact_png(["what", "case"], "x", std::slice::from_ref(&p)).unwrap();
            let img = decode(&bytes);
            assert_eq!((img.0, img.1), CONTACT_SIZE);
            let frames = frames_of(&bytes).unwrap();
            let names: Vec<&str> = frames.iter().map(|f| f.panel.as_str()).collect();
            let want = if frictional {
                vec!["p_n", "p_t", "u_n"]
            } else {
                vec!["p_n", "u_n"]
            };
            assert_eq!(names, want);
            for f in &frames {
                let (label, values) = match f.panel.as_str() {
                    "p_n" => ("p_n: bottom", &p.p_n),
                    "p_t" => ("p_t: bottom", p.p_t.as_ref().unwrap()),
                    _ => ("u_n: bottom", &p.u_n),
                };
                let colour = f.colour(label).unwrap();
                assert_eq!(colour, PAIR_COLOURS[0]);
                for (&s, &v) in p.s.iter().zip(values) {
                    let at = f.pixel(s, v);
                    assert!(
                        colour_near(&img, at, colour, 1),
                        "{label} at s = {s}: {at:?}"
                    );
                }
                // The check can fail: the values a quarter of the panel higher are not drawn.
                let shift = 0.25 * (f.y[1] - f.y[0]);
                let found =
                    p.s.iter()
                        .zip(values)
                        .filter(|(&s, &v)| colour_near(&img, f.pixel(s, v + shift), colour, 1))
                        .count();
                assert!(
                    found * 4 < p.s.len(),
                    "{label}: {found} shifted points found"
                );
            }
        }
    }

    #[test]
    fn convergence_picture_shows_the_history_and_its_marks() {
        let h: Vec<Sweep> = (1..=30)
            .map(|k| {
                sweep(
                    k,
                    0.5f64.powi(k as i32),
                    usize::from(k >= 12),
                    usize::from(k >= 7),
                )
            })
            .collect();
        let c = convergence_series(&h, true, 1e-8);
        let bytes = convergence_png(["what", "case"], &c).unwrap();
        let img = decode(&bytes);
        assert_eq!((img.0, img.1), CONVERGENCE_SIZE);
        let frames = frames_of(&bytes).unwrap();
        let [f] = &frames[..] else {
            panic!("{frames:?}")
        };
        assert!(f.log_y);
        assert_eq!(f.colour("error estimate"), Some(ERROR_COLOUR));
        assert_eq!(f.colour("p_t change"), Some(TRACTION_COLOUR));
        for (&k, &e) in c.sweeps.iter().zip(&c.error) {
            assert!(
                colour_near(&img, f.pixel(k, e), ERROR_COLOUR, 1),
                "sweep {k}"
            );
        }
        // The refusal at sweep 7: a cross on its error (under its dot, the arms out).
        let cross_near =
            |k: usize| colour_near(&img, f.pixel(k as f64, c.error[k - 1]), REFUSED_COLOUR, 6);
        assert!(cross_near(7) && !cross_near(8) && !cross_near(6));
        // The retune before sweep 12: a dashed line down the panel, before it only.
        let column = |x: f64| {
            (0..40)
                .filter(|i| {
                    let y = f.y[0] * (f.y[1] / f.y[0]).powf((*i as f64 + 0.5) / 40.0);
                    colour_near(&img, f.pixel(x, y), RETUNE_COLOUR, 0)
                })
                .count()
        };
        assert!(column(11.5) >= 15, "{}", column(11.5));
        assert_eq!(column(10.5), 0);
        // Without friction, no p_t.
        let f = convergence_series(&h, false, 1e-8);
        let frames = frames_of(&convergence_png(["", ""], &f).unwrap()).unwrap();
        assert_eq!(frames[0].colour("p_t change"), None);
    }

    #[test]
    fn odd_data_is_drawn_without_failing() {
        let empty = PairSeries {
            name: String::new(),
            s: vec![],
            p_n: vec![],
            p_t: None,
            u_n: vec![],
            gap: vec![],
        };
        let mut odd = pair(true);
        odd.p_n[3] = f64::NAN;
        odd.u_n[4] = f64::INFINITY;
        odd.gap = vec![1e300; odd.s.len()];
        odd.name = "Kontaktfläche 接触".into();
        for pairs in [
            vec![empty],
            vec![odd.clone()],
            vec![odd.clone(), pair(false)],
        ] {
            let bytes = contact_png(["", ""], "x", &pairs).unwrap();
            assert!(frames_of(&bytes).is_some());
        }
        let mut h = vec![sweep(1, f64::INFINITY, 0, 0), sweep(2, 0.0, 0, 0)];
        h[1].displacement = f64::NAN;
        for history in [vec![], h] {
            let c = convergence_series(&history, true, 1e-8);
            assert!(frames_of(&convergence_png(["", ""], &c).unwrap()).is_some());
        }
    }

    #[test]
    fn a_frame_maps_its_corners_to_its_pixels() {
        let f = Frame {
            panel: "p".into(),
            log_y: true,
            x: [0.0, 10.0],
            y: [1e-8, 1.0],
            pixel_low: [100, 500],
            pixel_high: [900, 100],
            series: vec![],
        };
        assert_eq!(f.pixel(0.0, 1e-8), (100.0, 500.0));
        assert_eq!(f.pixel(10.0, 1.0), (900.0, 100.0));
        let (x, y) = f.pixel(5.0, 1e-4);
        assert!(
            (x - 500.0).abs() < 1e-9 && (y - 300.0).abs() < 1e-9,
            "{x} {y}"
        );
        assert_eq!(frames_of(b"not a png"), None);
    }

    #[test]
    fn tick_labels_are_short() {
        let pressure = (-400.0, 8100.0);
        assert_eq!(tick(0.0, pressure), "0");
        assert_eq!(tick(7700.0, pressure), "7700");
        let small = (-0.0005, 0.0105);
        assert_eq!(tick(0.009, small), "0.009");
        assert_eq!(tick(0.01, small), "0.01");
        assert_eq!(tick(-0.04, (-0.05, 0.05)), "-0.04");
        assert_eq!(tick(2.5, (0.0, 50.0)), "2.5");
        assert_eq!(tick(0.0004, (0.0, 0.0005)), "4.0e-4");
        assert_eq!(tick(2.0e6, (0.0, 2.1e6)), "2.0e6");
        // Round-off about 0 on an axis of round-off.
        assert_eq!(tick(-2.1e-25, (-1.1e-9, 1.1e-9)), "0");
        assert_eq!(tick(5e-10, (-1.1e-9, 1.1e-9)), "5.0e-10");
    }
}
