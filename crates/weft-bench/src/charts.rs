//! Charts of the sweeps (plotters), each written as PNG and SVG: error against wall time with
//! the Pareto front marked, error against step size with the fitted orders, and stability
//! maps. Text is set in the bundled DejaVu Sans (assets/, Bitstream Vera licence), so the
//! charts need no system fonts.

use crate::sweep::{Run, Status, pareto_front_by};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

const FONT: &str = "sans-serif";
const SIZE: (u32, u32) = (760, 520);

fn method_color(m: &str) -> RGBColor {
    match m {
        "explicit" | "staggered" => RGBColor(214, 39, 40),
        "linearized" | "one_way" => RGBColor(31, 119, 180),
        "newton" | "clamped" => RGBColor(44, 160, 44),
        "two_pins" => RGBColor(214, 39, 40),
        // Resolution sweeps name curves by scene.
        "cantilever" => RGBColor(148, 103, 189),
        "catenary" => RGBColor(140, 86, 75),
        "shell_strip" => RGBColor(127, 127, 127),
        "taylor_green" => RGBColor(255, 127, 14),
        "darcy_slab" => RGBColor(23, 190, 207),
        "membrane" => RGBColor(188, 189, 34),
        _ => RGBColor(227, 119, 194),
    }
}

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The bundled font is a valid TTF; if it were not, text would be missing, not wrong.
        let _ = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        );
    });
}

fn err<E: std::fmt::Debug>(e: E) -> String {
    format!("chart: {e:?}")
}

/// Draws with `$draw(&root, args…)` into `stem`.png and `stem`.svg (one generic drawing
/// function, two backends).
macro_rules! both {
    ($stem:expr, $size:expr, $draw:ident ( $($arg:expr),* )) => {{
        register_font();
        let png = $stem.with_extension("png");
        {
            let root = BitMapBackend::new(&png, $size).into_drawing_area();
            $draw(&root, $($arg),*)?;
            root.present().map_err(err)?;
        }
        let svg = $stem.with_extension("svg");
        let root = SVGBackend::new(&svg, $size).into_drawing_area();
        $draw(&root, $($arg),*)?;
        root.present().map_err(err)?;
        Ok(())
    }};
}

/// The chart's legend at `at`, boxed on a light background.
fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    at: SeriesLabelPosition,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(at)
        .label_font((FONT, 12))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)
}

fn log_range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    if lo.is_finite() && hi > 0.0 {
        // Whole decades (at least two), so the log axis labels decades, not crowded
        // in-between values.
        let (a, b) = ((lo / 1.5).log10().floor(), (hi * 1.5).log10().ceil());
        (10f64.powf(a), 10f64.powf(b.max(a + 2.0)))
    } else {
        (1e-6, 1.0)
    }
}

/// Error against wall time, log–log, one curve per method (runs of one stiffness, in step
/// order), the Pareto front ringed.
pub fn error_vs_time(runs: &[Run], title: &str, stem: &Path) -> Result<(), String> {
    error_vs_time_by(runs, |r| r.method.to_string(), title, stem)
}

/// Error against wall time, log–log, one curve per `group` of runs, the Pareto front
/// ringed.
pub fn error_vs_time_by(
    runs: &[Run],
    group: fn(&Run) -> String,
    title: &str,
    stem: &Path,
) -> Result<(), String> {
    let curves = Curves {
        runs,
        title,
        group,
        x: |r| r.seconds,
        x_desc: "wall time [s]",
        orders: None,
        pareto: true,
    };
    both!(stem, SIZE, curves_on(&curves))
}

/// What a convergence chart puts across: the step or the cell size.
#[derive(Clone, Copy, Debug)]
pub enum Across {
    /// The time step h.
    Step,
    /// The segment or cell size.
    Size,
}

/// Error against step or cell size, log–log, one curve per method (or scene) with its
/// fitted order in the legend.
pub fn error_vs(
    across: Across,
    runs: &[Run],
    orders: &[(String, f64)],
    title: &str,
    stem: &Path,
) -> Result<(), String> {
    let (x, x_desc): (fn(&Run) -> f64, &str) = match across {
        Across::Step => (|r| r.h, "step h [s]"),
        Across::Size => (|r| r.dx, "segment or cell size [m]"),
    };
    let curves = Curves {
        runs,
        title,
        group: |r| r.method.to_string(),
        x,
        x_desc,
        orders: Some(orders),
        pareto: false,
    };
    both!(stem, SIZE, curves_on(&curves))
}

/// A log–log chart of error against some measure of each run, a curve per method.
struct Curves<'a> {
    runs: &'a [Run],
    title: &'a str,
    /// The curve a run belongs to (its method, unless said otherwise).
    group: fn(&Run) -> String,
    x: fn(&Run) -> f64,
    x_desc: &'a str,
    /// Fitted orders to name in the legend.
    orders: Option<&'a [(String, f64)]>,
    /// Ring the Pareto front of (x, error).
    pareto: bool,
}

fn curves_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    c: &Curves<'_>,
) -> Result<(), String> {
    let x = c.x;
    let (x0, x1) = log_range(c.runs.iter().map(x));
    let (y0, y1) = log_range(c.runs.iter().map(|r| r.error));
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(root)
        .caption(c.title, (FONT, 18))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(64)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    let y_desc = match c.runs.first().map_or("m", |r| r.error_unit) {
        "relative" => "relative error".to_string(),
        unit => format!("error [{unit}]"),
    };
    chart
        .configure_mesh()
        .x_desc(c.x_desc)
        .y_desc(y_desc)
        .label_style((FONT, 12))
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(err)?;
    let mut groups: Vec<String> = Vec::new();
    for r in c.runs {
        let g = (c.group)(r);
        if !groups.contains(&g) {
            groups.push(g);
        }
    }
    for (gi, m) in groups.iter().enumerate() {
        let m = m.as_str();
        let color = if groups.len() > 1 && methods(c.runs).len() == 1 {
            // One method in several groups: tell the groups apart.
            let (r, g, b) = Palette99::pick(gi).to_rgba().rgb();
            RGBColor(r, g, b)
        } else {
            method_color(m)
        };
        let mut pts: Vec<(f64, f64)> = c
            .runs
            .iter()
            .filter(|r| (c.group)(r) == m && r.error.is_finite() && x(r) > 0.0)
            .map(|r| (x(r), r.error))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let label = match c.orders.and_then(|o| o.iter().find(|(n, _)| n == m)) {
            Some((_, order)) => format!("{m} (order {order:.2})"),
            None => m.to_string(),
        };
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        chart
            .draw_series(pts.iter().map(|p| Circle::new(*p, 3, color.filled())))
            .map_err(err)?;
    }
    if c.pareto {
        // The chart's runs are comparable by choice.
        let front = pareto_front_by(c.runs, |_, _| true);
        chart
            .draw_series(
                c.runs
                    .iter()
                    .zip(&front)
                    .filter(|(r, f)| **f && x(r) > 0.0)
                    .map(|(r, _)| Circle::new((x(r), r.error), 7, BLACK.stroke_width(1))),
            )
            .map_err(err)?
            .label("Pareto front")
            .legend(|(x, y)| Circle::new((x + 9, y), 6, BLACK.stroke_width(1)));
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight)
}

/// Stability maps: one panel per method, step size across and `param` (named `label`) up,
/// each cell green (stable), orange (inaccurate) or red (blown up).
pub fn stability_map(
    runs: &[Run],
    param: fn(&Run) -> f64,
    label: &str,
    title: &str,
    stem: &Path,
) -> Result<(), String> {
    let size = (300 * methods(runs).len().max(1) as u32 + 40, 420);
    both!(stem, size, stability_map_on(runs, param, label, title))
}

fn stability_map_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    runs: &[Run],
    param: fn(&Run) -> f64,
    label: &str,
    title: &str,
) -> Result<(), String> {
    let methods = methods(runs);
    let mut hs: Vec<f64> = runs.iter().map(|r| r.h).collect();
    hs.sort_by(|a, b| b.total_cmp(a));
    hs.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * b.abs());
    let mut ps: Vec<f64> = runs.iter().map(param).collect();
    ps.sort_by(f64::total_cmp);
    ps.dedup();
    let index = |v: f64, of: &[f64]| of.iter().position(|x| (x - v).abs() <= 1e-12 * x.abs());
    {
        root.fill(&WHITE).map_err(err)?;
        let root = root.titled(title, (FONT, 18)).map_err(err)?;
        let panels = root.split_evenly((1, methods.len().max(1)));
        for (panel, m) in panels.iter().zip(&methods) {
            let mut chart = ChartBuilder::on(panel)
                .caption(*m, (FONT, 15))
                .margin(8)
                .x_label_area_size(48)
                .y_label_area_size(56)
                .build_cartesian_2d(
                    // `a..b` segmented has a segment per value in a..=b.
                    (0..hs.len().saturating_sub(1)).into_segmented(),
                    (0..ps.len().saturating_sub(1)).into_segmented(),
                )
                .map_err(err)?;
            // Segmented axes: each cell is a segment, labelled at its centre.
            let centre = |v: &SegmentValue<usize>| match v {
                SegmentValue::CenterOf(i) => Some(*i),
                _ => None,
            };
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc("step h [s]")
                .y_desc(label)
                .label_style((FONT, 10))
                .x_labels(hs.len())
                .y_labels(ps.len())
                .x_label_formatter(&|v| {
                    centre(v)
                        .filter(|i| *i < hs.len())
                        .map_or(String::new(), |i| format!("1/{:.0}", 1.0 / hs[i]))
                })
                .y_label_formatter(&|v| {
                    centre(v)
                        .filter(|i| *i < ps.len())
                        .map_or(String::new(), |i| format!("{:.0e}", ps[i]))
                })
                .draw()
                .map_err(err)?;
            chart
                .draw_series(runs.iter().filter(|r| r.method == *m).filter_map(|r| {
                    let (i, j) = (index(r.h, &hs)?, index(param(r), &ps)?);
                    let c = match r.status {
                        Status::Stable => RGBColor(44, 160, 44),
                        Status::Inaccurate => RGBColor(255, 160, 40),
                        Status::BlownUp => RGBColor(214, 39, 40),
                        Status::Failed => RGBColor(120, 20, 20),
                        Status::Unjudged => RGBColor(190, 190, 190),
                    };
                    Some(Rectangle::new(
                        [
                            (SegmentValue::Exact(i), SegmentValue::Exact(j)),
                            (SegmentValue::Exact(i + 1), SegmentValue::Exact(j + 1)),
                        ],
                        c.filled(),
                    ))
                }))
                .map_err(err)?;
        }
        Ok(())
    }
}

/// The methods present, in the order they first appear.
fn methods(runs: &[Run]) -> Vec<&'static str> {
    let mut m: Vec<&'static str> = Vec::new();
    for r in runs {
        if !m.contains(&r.method) {
            m.push(r.method);
        }
    }
    m
}

/// The incline sweep: measured acceleration along the slope against the angle (points), on
/// Coulomb's a = g max(0, sin θ − μ cos θ) (`curve`), with atan μ marked.
pub fn incline(
    measured: &[(f64, f64)],
    curve: &[(f64, f64)],
    mu: f64,
    stem: &Path,
) -> Result<(), String> {
    both!(stem, SIZE, incline_on(measured, curve, mu))
}

fn incline_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    measured: &[(f64, f64)],
    curve: &[(f64, f64)],
    mu: f64,
) -> Result<(), String> {
    let x1 = curve.iter().map(|p| p.0).fold(0.0f64, f64::max);
    let x0 = curve.iter().map(|p| p.0).fold(x1, f64::min);
    let y1 = curve
        .iter()
        .chain(measured)
        .map(|p| p.1)
        .fold(0.0f64, f64::max)
        * 1.1;
    root.fill(&WHITE).map_err(err)?;
    let title = format!("cloth patch on an incline, μ = {mu}: stick, then Coulomb sliding");
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT, 18))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, 0.0..y1.max(1e-3))
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("incline θ [°]")
        .y_desc("acceleration along the slope [m/s²]")
        .label_style((FONT, 12))
        .draw()
        .map_err(err)?;
    let line = RGBColor(31, 119, 180);
    chart
        .draw_series(LineSeries::new(curve.to_vec(), line.stroke_width(2)))
        .map_err(err)?
        .label("Coulomb: g max(0, sin θ − μ cos θ)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], line.stroke_width(2)));
    let atan = mu.atan().to_degrees();
    let grey = RGBColor(127, 127, 127);
    chart
        .draw_series(LineSeries::new(
            vec![(atan, 0.0), (atan, y1)],
            grey.stroke_width(1),
        ))
        .map_err(err)?
        .label(format!("atan μ = {atan:.2}°"))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], grey.stroke_width(1)));
    let dot = RGBColor(214, 39, 40);
    chart
        .draw_series(measured.iter().map(|p| Circle::new(*p, 4, dot.filled())))
        .map_err(err)?
        .label("Weft (velocity after 1 s)")
        .legend(move |(x, y)| Circle::new((x + 9, y), 4, dot.filled()));
    legend(&mut chart, SeriesLabelPosition::UpperLeft)
}
