//! Drawing of line plots and grids with plotters' SVG backend.

use std::ops::Range;

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use super::prep::{PreparedPlot, PreparedSeries};
use super::{Area, DrawResult, LinePlot, Series, Style, colour};
use crate::report::table::format_sig;

/// Legend box size as a fraction of the plotting area: width, height per
/// entry, fixed extra height.
const LEGEND_BOX: (f64, f64, f64) = (0.3, 0.06, 0.06);

/// Font of plot titles.
pub(crate) const TITLE_FONT: (&str, u32) = ("sans-serif", 22);
/// Font of tick labels and legend entries.
pub(crate) const LABEL_FONT: (&str, u32) = ("sans-serif", 15);
/// Font of axis descriptions.
pub(crate) const AXIS_DESC_FONT: (&str, u32) = ("sans-serif", 17);
/// Most y tick labels on a linear and on a log axis.
const LINEAR_LABELS: usize = 10;
const LOG_LABELS: usize = 5;
/// Radius in pixels of the markers of [`Style::Points`].
const POINT_RADIUS: u32 = 2;

/// Draws one line plot (axes, series, legend) filling `area`.
pub(crate) fn line_panel(area: &Area<'_>, plot: &LinePlot, prep: &PreparedPlot) -> DrawResult {
    let x = prep.x_range.clone();
    let y = prep.y_range.clone();
    if plot.log_y {
        panel_with(area, plot, prep, x, y.log_scale())
    } else {
        panel_with(area, plot, prep, x, y)
    }
}

/// Draws the grid title and one panel per plot, stacked vertically.
pub(crate) fn grid(
    root: &Area<'_>,
    title: &str,
    plots: &[LinePlot],
    prep: &[PreparedPlot],
) -> DrawResult {
    let body = root.titled(title, ("sans-serif", 28))?;
    let areas = body.split_evenly((plots.len(), 1));
    for ((area, plot), p) in areas.iter().zip(plots).zip(prep) {
        line_panel(area, plot, p)?;
    }
    Ok(())
}

fn panel_with<Y>(
    area: &Area<'_>,
    plot: &LinePlot,
    prep: &PreparedPlot,
    x: Range<f64>,
    y: Y,
) -> DrawResult
where
    Y: AsRangedCoord<Value = f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let mut chart = ChartBuilder::on(area)
        .caption(&plot.title, TITLE_FONT)
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(75)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .label_style(LABEL_FONT)
        .axis_desc_style(AXIS_DESC_FONT)
        .x_label_formatter(&|v| axis_tick(*v, &prep.x_range))
        .y_label_formatter(&|v| axis_tick(*v, &prep.y_range))
        // A log axis asks for fewer labels: its key points include the
        // 2..9 multiples of each decade, which overlap in a grid's panel.
        .y_labels(if plot.log_y {
            LOG_LABELS
        } else {
            LINEAR_LABELS
        })
        .draw()?;
    for (i, (s, p)) in plot.series.iter().zip(&prep.series).enumerate() {
        draw_series(&mut chart, s, p, colour(i))?;
    }
    let corner = legend_corner(prep, plot.log_y);
    legend(&mut chart, corner)
}

/// A tick label on an axis spanning `range`: a tick within 1e-9 of the span
/// from zero is zero (the tick arithmetic leaves `-2.22e-16` there).
pub(crate) fn axis_tick(v: f64, range: &Range<f64>) -> String {
    let span = (range.end - range.start).abs();
    if v.abs() <= 1e-9 * span {
        "0".to_string()
    } else {
        tick_label(v)
    }
}

/// A tick label: [`format_sig`] without trailing zeros (`0.5`, `1e-4`).
pub(crate) fn tick_label(v: f64) -> String {
    fn trim(s: &str) -> &str {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.')
        } else {
            s
        }
    }
    let s = format_sig(v);
    match s.split_once('e') {
        Some((mantissa, exp)) => format!("{}e{exp}", trim(mantissa)),
        None => trim(&s).to_string(),
    }
}

/// The plot corner whose legend-sized box covers the fewest data points.
fn legend_corner(prep: &PreparedPlot, log_y: bool) -> SeriesLabelPosition {
    let scale = |v: f64, r: &Range<f64>| {
        if log_y {
            (v.log10() - r.start.log10()) / (r.end.log10() - r.start.log10())
        } else {
            (v - r.start) / (r.end - r.start)
        }
    };
    let (w, per_entry, extra) = LEGEND_BOX;
    let h = extra + per_entry * prep.series.len() as f64;
    let mut counts = [0usize; 4]; // upper right, upper left, lower right, lower left
    for &(x, y) in prep.series.iter().flat_map(|s| s.segments.iter().flatten()) {
        let fx = (x - prep.x_range.start) / (prep.x_range.end - prep.x_range.start);
        let fy = scale(y, &prep.y_range);
        let (right, left) = (fx >= 1.0 - w, fx <= w);
        let (upper, lower) = (fy >= 1.0 - h, fy <= h);
        for (i, hit) in [upper && right, upper && left, lower && right, lower && left]
            .iter()
            .enumerate()
        {
            counts[i] += usize::from(*hit);
        }
    }
    let best = (0..4).min_by_key(|&i| counts[i]).unwrap_or(0);
    [
        SeriesLabelPosition::UpperRight,
        SeriesLabelPosition::UpperLeft,
        SeriesLabelPosition::LowerRight,
        SeriesLabelPosition::LowerLeft,
    ][best]
        .clone()
}

/// Draws the legend box of the series labelled so far.
pub(crate) fn legend<'a, 'b: 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, SVGBackend<'b>, CT>,
    position: SeriesLabelPosition,
) -> DrawResult {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(LABEL_FONT)
        .draw()
}

fn draw_series<'a, 'b: 'a, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'a, SVGBackend<'b>, CT>,
    series: &Series,
    prep: &PreparedSeries,
    colour: RGBColor,
) -> DrawResult {
    // A labelled, empty element carries the legend entry, even for an empty series.
    let style = series.style;
    let anno = chart
        .draw_series(std::iter::empty::<PathElement<(f64, f64)>>())?
        .label(series.name.as_str());
    match style {
        Style::Line => anno.legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
        }),
        Style::Points => anno.legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled())),
    };
    match style {
        Style::Line => {
            let line = colour.stroke_width(2);
            for segment in &prep.segments {
                chart.draw_series(LineSeries::new(segment.iter().copied(), line))?;
            }
        }
        Style::Points => {
            let points = prep.segments.iter().flatten();
            let marker = |&(x, y): &(f64, f64)| Circle::new((x, y), POINT_RADIUS, colour.filled());
            chart.draw_series(points.map(marker))?;
        }
    }
    Ok(())
}
