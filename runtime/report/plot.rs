//! SVG plots: line plots, stacked per-joint grids and grouped bar charts.
//!
//! # Bad input policy
//! * Structural problems are errors ([`ReportError::Input`]): a plot without
//!   series, a series whose `x` and `y` lengths differ, a grid without panels,
//!   a bar chart without groups or bars, or value/error vectors whose length
//!   differs from the number of groups.
//! * Bad values are skipped, not fatal: points with a non-finite `x` or `y`,
//!   or one beyond ±[`LIMIT`] (1e100), and with `log_y` points with `y` outside
//!   `[1e-100, 1e100]` (so every `y <= 0`), are left out; bars whose value is
//!   non-finite or beyond ±`LIMIT` are not drawn, and a non-finite, negative or
//!   huge error bar is dropped. Lines are broken at skipped points. The number of skipped values
//!   is returned in [`PlotReport::points_skipped`]. If nothing at all is left
//!   to draw, the result is [`InputError::NothingToDraw`]. An empty series is
//!   allowed (it still gets a legend entry) as long as another series has data.
//!
//! # Decimation
//! A series with more than [`MAX_POINTS`] drawable points is decimated for
//! drawing with a min/max-per-bucket scheme: the points are cut into
//! consecutive buckets of `k = ceil(n / (MAX_POINTS / 2))` points and from each
//! bucket the points with the smallest and the largest `y` are kept, in their
//! original order. This keeps spikes and the noise envelope visible (e.g. raw
//! joint velocity) while bounding the file size. Decimated series are listed
//! in [`PlotReport::decimated_series`].
//!
//! # Text
//! Titles, axis labels, tick labels and legends become SVG `<text>` elements
//! (plotters' SVG backend, built without its `ttf`/`ab_glyph` features), so no
//! font file or fontconfig is needed to produce the files.

mod bar;
mod draw;
mod heat;
mod prep;

pub use heat::HeatPanel;

use std::path::Path;

use plotters::prelude::*;
use serde::{Deserialize, Serialize};

use crate::report::atomic::write_atomic;
use crate::report::error::{InputError, ReportError};

pub use prep::{LIMIT, MAX_POINTS};

/// Width in pixels of every generated SVG.
const WIDTH: u32 = 1000;
/// Height in pixels of a single line plot or bar chart.
const HEIGHT: u32 = 600;
/// Height in pixels of one panel of a grid plot.
const PANEL_HEIGHT: u32 = 320;
/// Height in pixels reserved for the title of a grid plot.
const GRID_TITLE_HEIGHT: u32 = 50;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Style {
    /// A polyline through the points (broken at skipped points).
    #[default]
    Line,
    /// A small filled circle per point.
    Points,
}

/// One named data series of a [`LinePlot`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// X values; must have the same length as `y`.
    pub x: Vec<f64>,
    /// Y values.
    pub y: Vec<f64>,
    /// Line or points.
    pub style: Style,
}

/// A 2-D plot of one or more series with a legend and automatic ranges.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LinePlot {
    /// Plot title (also the panel caption inside a grid).
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// The series, drawn in order with distinct colours.
    pub series: Vec<Series>,
    /// Logarithmic y axis (e.g. training curves); non-positive y are skipped.
    pub log_y: bool,
}

/// Grouped bar chart, e.g. the per-joint MSE of several models.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct BarChart {
    /// Chart title.
    pub title: String,
    /// Y axis label.
    pub y_label: String,
    /// Group names along the x axis, e.g. `["J1", "J2", "J3", "mean"]`.
    pub groups: Vec<String>,
    /// Per model: name, one value per group, optional error (e.g. std) per group.
    pub bars: Vec<(String, Vec<f64>, Option<Vec<f64>>)>,
}

/// What was drawn; returned by every plotting function.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct PlotReport {
    /// Points (or bars) actually drawn, after skipping and decimation.
    pub points_drawn: usize,
    /// Values skipped: non-finite, non-positive on a log axis, or bars with a
    /// non-finite value / invalid error bar.
    pub points_skipped: usize,
    /// Names of the series that were decimated (see the module docs).
    pub decimated_series: Vec<String>,
}

impl PlotReport {
    fn merge(mut self, other: PlotReport) -> PlotReport {
        self.points_drawn += other.points_drawn;
        self.points_skipped += other.points_skipped;
        self.decimated_series.extend(other.decimated_series);
        self
    }
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;
type DrawResult = Result<(), DrawingAreaErrorKind<std::io::Error>>;

fn input_error(path: &Path, problem: InputError) -> ReportError {
    ReportError::Input {
        path: path.to_path_buf(),
        problem,
    }
}

/// Renders into an in-memory SVG and writes it to `path` atomically.
fn render_svg(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&Area<'_>) -> DrawResult,
) -> Result<(), ReportError> {
    let render_error = |e: DrawingAreaErrorKind<std::io::Error>| ReportError::Render {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(render_error)?;
        draw(&root).map_err(render_error)?;
        root.present().map_err(render_error)?;
    }
    write_atomic(path, svg.as_bytes())
}

/// Draws `plot` to an SVG file at `path` (written atomically).
///
/// Returns what was drawn and skipped; see the module docs for the bad-input
/// policy and decimation.
pub fn line_plot(path: impl AsRef<Path>, plot: &LinePlot) -> Result<PlotReport, ReportError> {
    let path = path.as_ref();
    let prepared = prep::prepare_plot(plot).map_err(|p| input_error(path, p))?;
    render_svg(path, (WIDTH, HEIGHT), |root| {
        draw::line_panel(root, plot, &prepared)
    })?;
    Ok(prepared.report())
}

/// Draws several line plots stacked vertically in one SVG file (e.g. one panel
/// per joint), under a common `title`. Each panel keeps its own title, axis
/// labels, legend and `log_y` setting. Every panel must be valid on its own.
pub fn grid_plot(
    path: impl AsRef<Path>,
    title: &str,
    panels: &[LinePlot],
) -> Result<PlotReport, ReportError> {
    let path = path.as_ref();
    if panels.is_empty() {
        return Err(input_error(path, InputError::NoPanels));
    }
    let prepared = panels
        .iter()
        .map(prep::prepare_plot)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|p| input_error(path, p))?;
    let height = GRID_TITLE_HEIGHT + PANEL_HEIGHT * panels.len() as u32;
    render_svg(path, (WIDTH, height), |root| {
        draw::grid(root, title, panels, &prepared)
    })?;
    let report = prepared.iter().map(prep::PreparedPlot::report);
    Ok(report.fold(PlotReport::default(), PlotReport::merge))
}

/// Draws a grouped bar chart with optional error bars and a legend to an SVG
/// file at `path` (written atomically). The y axis always includes 0.
pub fn bar_chart(path: impl AsRef<Path>, chart: &BarChart) -> Result<PlotReport, ReportError> {
    let path = path.as_ref();
    let prepared = bar::prepare(chart).map_err(|p| input_error(path, p))?;
    render_svg(path, (WIDTH, HEIGHT), |root| {
        bar::draw(root, chart, &prepared)
    })?;
    Ok(prepared.report())
}

/// Draws category-map panels side by side with a legend of `categories`
/// (cell colours) to an SVG file at `path` (written atomically).
pub fn heat_map(
    path: impl AsRef<Path>,
    title: &str,
    panels: &[HeatPanel],
    categories: &[&str],
) -> Result<(), ReportError> {
    let width = 40 + 420 * panels.len().max(1) as u32;
    render_svg(path.as_ref(), (width, 480), |root| {
        heat::draw(root, title, panels, categories)
    })
}

/// Colour of the `index`-th series or model (Tableau 10 palette; repeats after 10).
fn colour(index: usize) -> RGBColor {
    const PALETTE: [(u8, u8, u8); 10] = [
        (31, 119, 180),
        (255, 127, 14),
        (44, 160, 44),
        (214, 39, 40),
        (148, 103, 189),
        (140, 86, 75),
        (227, 119, 194),
        (127, 127, 127),
        (188, 189, 34),
        (23, 190, 207),
    ];
    let (r, g, b) = PALETTE[index % PALETTE.len()];
    RGBColor(r, g, b)
}

#[cfg(test)]
mod tests;
