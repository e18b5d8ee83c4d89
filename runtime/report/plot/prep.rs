//! Input validation, filtering of bad points, decimation and axis ranges.

use std::ops::Range;

use super::{LinePlot, PlotReport, Series, Style};
use crate::report::error::InputError;

/// Largest number of points drawn per series before decimation kicks in.
pub const MAX_POINTS: usize = 4000;

/// Above this many gaps (runs of skipped points) a line is drawn without gaps,
/// so that the decimation bound still holds.
const MAX_GAPS: usize = 500;

/// Relative margin added on each side of the data range.
const MARGIN: f64 = 0.05;

/// Values with a magnitude above this (or, on a log axis, below its inverse)
/// are skipped like non-finite ones: plotters' tick computation is not
/// reliable for such extreme ranges.
pub const LIMIT: f64 = 1e100;

/// Smallest axis span relative to the magnitude of its ends.
const MIN_REL_SPAN: f64 = 1e-9;

/// A series reduced to drawable points, split into gap-free segments.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PreparedSeries {
    pub segments: Vec<Vec<(f64, f64)>>,
    pub skipped: usize,
    pub decimated: bool,
}

/// A validated plot: prepared series plus padded axis ranges.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PreparedPlot {
    pub series: Vec<PreparedSeries>,
    pub x_range: Range<f64>,
    pub y_range: Range<f64>,
    names: Vec<String>,
}

impl PreparedPlot {
    pub fn report(&self) -> PlotReport {
        let decimated = self.series.iter().zip(&self.names);
        PlotReport {
            points_drawn: self.series.iter().map(PreparedSeries::len).sum(),
            points_skipped: self.series.iter().map(|s| s.skipped).sum(),
            decimated_series: decimated
                .filter(|(s, _)| s.decimated)
                .map(|(_, n)| n.clone())
                .collect(),
        }
    }
}

impl PreparedSeries {
    pub fn len(&self) -> usize {
        self.segments.iter().map(Vec::len).sum()
    }

    fn points(&self) -> impl Iterator<Item = &(f64, f64)> {
        self.segments.iter().flatten()
    }
}

/// Validates `plot` and prepares every series for drawing.
pub(crate) fn prepare_plot(plot: &LinePlot) -> Result<PreparedPlot, InputError> {
    if plot.series.is_empty() {
        return Err(InputError::NoSeries);
    }
    let series = plot
        .series
        .iter()
        .map(|s| prepare_series(s, plot.log_y))
        .collect::<Result<Vec<_>, _>>()?;
    let (xs, ys) = extent(&series).ok_or(InputError::NothingToDraw)?;
    let y_range = if plot.log_y {
        pad_log(ys)
    } else {
        pad_linear(ys)
    };
    Ok(PreparedPlot {
        x_range: pad_linear(xs),
        y_range,
        names: plot.series.iter().map(|s| s.name.clone()).collect(),
        series,
    })
}

fn prepare_series(s: &Series, log_y: bool) -> Result<PreparedSeries, InputError> {
    if s.x.len() != s.y.len() {
        return Err(InputError::LengthMismatch {
            series: s.name.clone(),
            x_len: s.x.len(),
            y_len: s.y.len(),
        });
    }
    let (mut segments, skipped) = split_valid(&s.x, &s.y, log_y);
    if segments.len() > MAX_GAPS {
        segments = vec![segments.concat()];
    }
    let total: usize = segments.iter().map(Vec::len).sum();
    let decimated = total > MAX_POINTS;
    if decimated && s.style == Style::Points {
        // A scatter keeps every k-th point: its density is what it shows
        // (min/max per bucket would keep only the extremes, two bands
        // with an empty gap where Gaussian data are densest).
        let stride = total.div_ceil(MAX_POINTS);
        segments = segments
            .iter()
            .map(|seg| seg.iter().copied().step_by(stride).collect())
            .collect();
    } else if decimated {
        let bucket = total.div_ceil(MAX_POINTS / 2);
        segments = segments.iter().map(|seg| decimate(seg, bucket)).collect();
    }
    Ok(PreparedSeries {
        segments,
        skipped,
        decimated,
    })
}

/// Whether `v` can be drawn on an axis (see [`LIMIT`]).
pub(crate) fn in_limits(v: f64, log: bool) -> bool {
    if log {
        (1.0 / LIMIT..=LIMIT).contains(&v)
    } else {
        v.abs() <= LIMIT
    }
}

fn usable(x: f64, y: f64, log_y: bool) -> bool {
    in_limits(x, false) && in_limits(y, log_y)
}

/// Splits the points into runs of usable points; returns the runs and the
/// number of skipped points.
fn split_valid(x: &[f64], y: &[f64], log_y: bool) -> (Vec<Vec<(f64, f64)>>, usize) {
    let mut segments = Vec::new();
    let mut current = Vec::new();
    let mut skipped = 0;
    for (&a, &b) in x.iter().zip(y) {
        if usable(a, b, log_y) {
            current.push((a, b));
        } else {
            skipped += 1;
            if !current.is_empty() {
                segments.push(std::mem::take(&mut current));
            }
        }
    }
    if !current.is_empty() {
        segments.push(current);
    }
    (segments, skipped)
}

/// Keeps the min-y and max-y point of each bucket of `bucket` consecutive
/// points, in their original order.
pub(crate) fn decimate(points: &[(f64, f64)], bucket: usize) -> Vec<(f64, f64)> {
    points
        .chunks(bucket.max(1))
        .flat_map(min_max_in_order)
        .collect()
}

fn min_max_in_order(chunk: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let (mut lo, mut hi) = (0, 0);
    for (i, p) in chunk.iter().enumerate() {
        if p.1 < chunk[lo].1 {
            lo = i;
        }
        if p.1 > chunk[hi].1 {
            hi = i;
        }
    }
    match lo.cmp(&hi) {
        std::cmp::Ordering::Equal => vec![chunk[lo]],
        std::cmp::Ordering::Less => vec![chunk[lo], chunk[hi]],
        std::cmp::Ordering::Greater => vec![chunk[hi], chunk[lo]],
    }
}

/// Min/max of x and y over all drawable points, or `None` if there are none.
fn extent(series: &[PreparedSeries]) -> Option<((f64, f64), (f64, f64))> {
    let mut points = series.iter().flat_map(PreparedSeries::points);
    let &(x0, y0) = points.next()?;
    let init = ((x0, x0), (y0, y0));
    Some(points.fold(init, |((xl, xh), (yl, yh)), &(x, y)| {
        ((xl.min(x), xh.max(x)), (yl.min(y), yh.max(y)))
    }))
}

/// Adds a relative margin on both sides and widens degenerate or extremely
/// narrow ranges, so that plotters' tick computation stays well-behaved. The
/// input must lie within ±[`LIMIT`]; the result is finite and non-empty.
pub(crate) fn pad_linear((lo, hi): (f64, f64)) -> Range<f64> {
    let span = hi - lo;
    let m = lo.abs().max(hi.abs());
    let pad = if span >= (m * MIN_REL_SPAN).max(1.0 / LIMIT) {
        span * MARGIN
    } else if m > 0.0 {
        (m * MARGIN).max(1.0 / LIMIT)
    } else {
        1.0
    };
    (lo - pad)..(hi + pad)
}

/// Range for a log axis over strictly positive data within
/// `[1/LIMIT, LIMIT]`: data spanning less than a decade is widened to the
/// enclosing powers of ten (so at least two ticks are labelled), otherwise a
/// margin of 5 % of the decades is added.
pub(crate) fn pad_log((lo, hi): (f64, f64)) -> Range<f64> {
    let (l, h) = (lo.log10(), hi.log10());
    if h - l < 1.0 {
        let (a, b) = (l.floor(), h.ceil());
        let b = if b > a { b } else { a + 1.0 };
        return 10f64.powf(a)..10f64.powf(b);
    }
    let pad = (h - l) * MARGIN;
    10f64.powf(l - pad)..10f64.powf(h + pad)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::plot::Style;

    fn series(x: Vec<f64>, y: Vec<f64>) -> Series {
        Series {
            name: "s".into(),
            x,
            y,
            style: Style::Line,
        }
    }

    #[test]
    fn splits_at_non_finite_points() {
        let (segs, skipped) = split_valid(
            &[0., 1., 2., 3., 4.],
            &[1., f64::NAN, 2., 3., f64::INFINITY],
            false,
        );
        assert_eq!(skipped, 2);
        assert_eq!(segs, vec![vec![(0., 1.)], vec![(2., 2.), (3., 3.)]]);
    }

    #[test]
    fn log_axis_skips_non_positive() {
        let (segs, skipped) = split_valid(&[0., 1., 2.], &[1., 0., -2.], true);
        assert_eq!((segs.len(), skipped), (1, 2));
    }

    #[test]
    fn decimation_keeps_extremes_in_order() {
        let pts: Vec<(f64, f64)> = (0..10)
            .map(|i| (i as f64, [0., 5., -3., 1., 2.][i % 5]))
            .collect();
        let d = decimate(&pts, 5);
        assert_eq!(d, vec![(1., 5.), (2., -3.), (6., 5.), (7., -3.)]);
    }

    #[test]
    fn large_series_is_bounded() {
        let n = 100_000;
        let x: Vec<f64> = (0..n).map(f64::from).collect();
        let y: Vec<f64> = x.iter().map(|v| (v * 0.37).sin()).collect();
        let p = prepare_series(&series(x, y), false).unwrap();
        assert!(p.decimated);
        assert!(
            p.len() <= MAX_POINTS && p.len() > MAX_POINTS / 2,
            "{}",
            p.len()
        );
    }

    #[test]
    fn many_gaps_are_merged_and_bounded() {
        let n = 50_000;
        let x: Vec<f64> = (0..n).map(f64::from).collect();
        let y: Vec<f64> = (0..n)
            .map(|i| if i % 2 == 0 { f64::NAN } else { 1.0 })
            .collect();
        let p = prepare_series(&series(x, y), false).unwrap();
        assert_eq!(p.skipped, 25_000);
        assert!(p.len() <= MAX_POINTS);
    }

    #[test]
    fn ranges_are_padded_and_never_empty() {
        let r = pad_linear((0.0, 10.0));
        assert_eq!((r.start, r.end), (-0.5, 10.5));
        assert_eq!(pad_linear((0.0, 0.0)), -1.0..1.0);
        for v in [LIMIT, -LIMIT, 1.0 / LIMIT, 5e-324, 1.0] {
            let r = pad_linear((v, v));
            assert!(r.start < r.end && r.end.is_finite(), "{v}");
            let r = pad_linear((v, v + v.abs() * 1e-15));
            assert!(r.end - r.start >= v.abs() * 0.05, "{v}");
        }
        let r = pad_linear((-LIMIT, LIMIT));
        assert!((r.end - r.start).is_finite());
        let r = pad_log((1e-3, 1e1));
        assert!(r.start < 1e-3 && r.end > 10.0 && r.start > 0.0);
        assert_eq!(pad_log((2.0, 3.0)), 1.0..10.0);
        assert_eq!(pad_log((10.0, 10.0)), 10.0..100.0);
        let r = pad_log((1.0 / LIMIT, LIMIT));
        assert!(r.start > 0.0 && r.end.is_finite());
    }

    #[test]
    fn extreme_values_are_skipped() {
        let (segs, skipped) = split_valid(&[0., 1e101, 2.], &[1., 1., 1e-101], true);
        assert_eq!((segs.len(), skipped), (1, 2));
    }

    #[test]
    fn mismatch_and_empty_are_errors() {
        let mut plot = LinePlot::default();
        assert_eq!(prepare_plot(&plot), Err(InputError::NoSeries));
        plot.series.push(series(vec![1.0], vec![]));
        assert!(matches!(
            prepare_plot(&plot),
            Err(InputError::LengthMismatch {
                x_len: 1,
                y_len: 0,
                ..
            })
        ));
        plot.series[0] = series(vec![f64::NAN], vec![1.0]);
        assert_eq!(prepare_plot(&plot), Err(InputError::NothingToDraw));
    }
}
