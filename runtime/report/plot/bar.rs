//! Grouped bar charts with error bars.

use std::ops::Range;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::draw::{AXIS_DESC_FONT, LABEL_FONT, TITLE_FONT, axis_tick, legend};
use super::prep::{in_limits, pad_linear};
use super::{Area, BarChart, DrawResult, PlotReport, colour};
use crate::report::error::InputError;

/// Fraction of a group's width taken by its bars.
const GROUP_WIDTH: f64 = 0.8;
/// Fraction of a bar slot filled by the bar (the rest is a gap).
const BAR_FILL: f64 = 0.9;
/// Extra headroom above the tallest bar, per model, as a fraction of the
/// data span, to keep the legend (upper right) clear of the bars.
const LEGEND_HEADROOM: f64 = 0.07;

/// A validated bar chart: the y range and the drawn/skipped counts.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PreparedBars {
    pub y_range: Range<f64>,
    drawn: usize,
    skipped: usize,
}

impl PreparedBars {
    pub fn report(&self) -> PlotReport {
        PlotReport {
            points_drawn: self.drawn,
            points_skipped: self.skipped,
            decimated_series: Vec::new(),
        }
    }
}

/// One bar: model index, group index, value, error bar (if valid).
struct Bar {
    model: usize,
    group: usize,
    value: f64,
    error: Option<f64>,
}

fn check_len(
    model: &str,
    what: &'static str,
    got: usize,
    expected: usize,
) -> Result<(), InputError> {
    if got == expected {
        return Ok(());
    }
    Err(InputError::BarLength {
        model: model.to_string(),
        what,
        expected,
        got,
    })
}

fn validate(chart: &BarChart) -> Result<(), InputError> {
    if chart.groups.is_empty() {
        return Err(InputError::NoGroups);
    }
    if chart.bars.is_empty() {
        return Err(InputError::NoSeries);
    }
    let n = chart.groups.len();
    for (model, values, errors) in &chart.bars {
        check_len(model, "values", values.len(), n)?;
        if let Some(errors) = errors {
            check_len(model, "error bars", errors.len(), n)?;
        }
    }
    Ok(())
}

/// All bars of all models; `None` entries are bars with a non-finite value.
/// The second element is the number of invalid error bars.
fn bars(chart: &BarChart) -> (Vec<Option<Bar>>, usize) {
    let mut bad_errors = 0;
    let mut out = Vec::new();
    for (model, (_, values, errors)) in chart.bars.iter().enumerate() {
        for (group, &value) in values.iter().enumerate() {
            let raw = errors.as_ref().map(|e| e[group]);
            let error = raw.filter(|e| *e >= 0.0 && in_limits(*e, false));
            bad_errors += usize::from(raw.is_some() && error.is_none());
            let bar = Bar {
                model,
                group,
                value,
                error,
            };
            out.push(in_limits(value, false).then_some(bar));
        }
    }
    (out, bad_errors)
}

/// Y range covering 0, every bar and every error bar, with a top/bottom margin
/// only on the side(s) away from 0.
fn y_range<'a>(bars: impl Iterator<Item = &'a Bar>, models: usize) -> Range<f64> {
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for bar in bars {
        let e = bar.error.unwrap_or(0.0);
        lo = lo.min(bar.value - e);
        hi = hi.max(bar.value + e);
    }
    if lo == 0.0 && hi == 0.0 {
        return 0.0..1.0;
    }
    let padded = pad_linear((lo, hi));
    let start = if lo < 0.0 { padded.start } else { 0.0 };
    let end = if hi > 0.0 { padded.end } else { 0.0 };
    let headroom = (end - start) * LEGEND_HEADROOM * models as f64;
    start..end + headroom
}

/// Validates `chart` and computes the y range; see the `plot` module docs.
pub(crate) fn prepare(chart: &BarChart) -> Result<PreparedBars, InputError> {
    validate(chart)?;
    let (all, bad_errors) = bars(chart);
    let valid: Vec<&Bar> = all.iter().flatten().collect();
    if valid.is_empty() {
        return Err(InputError::NothingToDraw);
    }
    Ok(PreparedBars {
        y_range: y_range(valid.iter().copied(), chart.bars.len()),
        drawn: valid.len(),
        skipped: all.len() - valid.len() + bad_errors,
    })
}

/// Draws the chart: axes, bars, error bars, group labels and legend.
pub(crate) fn draw(root: &Area<'_>, chart: &BarChart, prep: &PreparedBars) -> DrawResult {
    let n = chart.groups.len() as f64;
    let mut ctx = ChartBuilder::on(root)
        .caption(&chart.title, TITLE_FONT)
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(75)
        .build_cartesian_2d(-0.5..n - 0.5, prep.y_range.clone())?;
    ctx.configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .label_style(LABEL_FONT)
        .axis_desc_style(AXIS_DESC_FONT)
        .y_desc(chart.y_label.as_str())
        .y_label_formatter(&|v| axis_tick(*v, &prep.y_range))
        .draw()?;
    let slot = GROUP_WIDTH / chart.bars.len() as f64;
    for (i, (model, _, _)) in chart.bars.iter().enumerate() {
        let c = colour(i);
        ctx.draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())?
            .label(model.as_str())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], c.filled()));
    }
    for bar in bars(chart).0.iter().flatten() {
        draw_bar(&mut ctx, bar, slot)?;
    }
    group_labels(root, &ctx, &chart.groups, prep.y_range.start)?;
    legend(&mut ctx, SeriesLabelPosition::UpperRight)
}

type BarCtx<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

fn draw_bar(ctx: &mut BarCtx<'_, '_>, bar: &Bar, slot: f64) -> DrawResult {
    let left = bar.group as f64 - GROUP_WIDTH / 2.0 + bar.model as f64 * slot;
    let right = left + slot * BAR_FILL;
    let rect = Rectangle::new(
        [(left, 0.0), (right, bar.value)],
        colour(bar.model).filled(),
    );
    ctx.draw_series(std::iter::once(rect))?;
    let Some(e) = bar.error else {
        return Ok(());
    };
    let (cx, cap) = ((left + right) / 2.0, slot * 0.25);
    let (lo, hi) = (bar.value - e, bar.value + e);
    let lines = [
        vec![(cx, lo), (cx, hi)],
        vec![(cx - cap, lo), (cx + cap, lo)],
        vec![(cx - cap, hi), (cx + cap, hi)],
    ];
    let style = BLACK.stroke_width(1);
    ctx.draw_series(lines.into_iter().map(|l| PathElement::new(l, style)))?;
    Ok(())
}

/// Writes each group name centred below its group, in the x label area.
fn group_labels(root: &Area<'_>, ctx: &BarCtx<'_, '_>, groups: &[String], y0: f64) -> DrawResult {
    let style = TextStyle::from(LABEL_FONT.into_font()).pos(Pos::new(HPos::Center, VPos::Top));
    for (i, name) in groups.iter().enumerate() {
        let (px, py) = ctx.backend_coord(&(i as f64, y0));
        root.draw(&Text::new(name.as_str(), (px, py + 8), style.clone()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart(bars: Vec<(String, Vec<f64>, Option<Vec<f64>>)>) -> BarChart {
        BarChart {
            title: "t".into(),
            y_label: "y".into(),
            groups: vec!["J1".into(), "J2".into()],
            bars,
        }
    }

    #[test]
    fn range_includes_zero_and_error_bars() {
        let p = prepare(&chart(vec![(
            "m".into(),
            vec![2.0, 3.0],
            Some(vec![0.5, 1.0]),
        )]))
        .unwrap();
        assert_eq!(p.y_range.start, 0.0);
        assert!(p.y_range.end > 4.0);
        let p = prepare(&chart(vec![("m".into(), vec![-2.0, -3.0], None)])).unwrap();
        // Headroom for the legend sits above 0 even for negative bars.
        assert!(p.y_range.start < -3.0 && (0.0..1.0).contains(&p.y_range.end));
        let p = prepare(&chart(vec![("m".into(), vec![0.0, 0.0], None)])).unwrap();
        assert_eq!(p.y_range.start, 0.0);
        assert!(p.y_range.end >= 1.0);
    }

    #[test]
    fn non_finite_bars_and_errors_are_counted() {
        let p = prepare(&chart(vec![(
            "m".into(),
            vec![f64::NAN, 1.0],
            Some(vec![0.1, -1.0]),
        )]))
        .unwrap();
        assert_eq!(p.report().points_drawn, 1);
        assert_eq!(p.report().points_skipped, 2);
    }

    #[test]
    fn shape_errors() {
        let mut c = chart(vec![("m".into(), vec![1.0], None)]);
        assert!(matches!(
            prepare(&c),
            Err(InputError::BarLength {
                what: "values",
                got: 1,
                ..
            })
        ));
        c.bars[0] = ("m".into(), vec![1.0, 2.0], Some(vec![1.0]));
        assert!(matches!(
            prepare(&c),
            Err(InputError::BarLength {
                what: "error bars",
                ..
            })
        ));
        c.bars.clear();
        assert_eq!(prepare(&c), Err(InputError::NoSeries));
        c.groups.clear();
        assert_eq!(prepare(&c), Err(InputError::NoGroups));
        let c = chart(vec![("m".into(), vec![f64::NAN, f64::INFINITY], None)]);
        assert_eq!(prepare(&c), Err(InputError::NothingToDraw));
    }
}
