//! Reporting helpers for the sdnn robotics tool.
//!
//! * [`table`]: model-comparison tables (Markdown and CSV), in the style of
//!   Table 3.1 of the SDNN thesis (mean ± std of the MSE, overall and per joint).
//! * [`plot`]: SVG line plots, stacked per-joint grids and grouped bar charts.
//!
//! All file outputs are written atomically: the content is rendered in
//! memory, written to a temporary file in the destination directory, flushed
//! and then renamed over the destination. Every error names the output path.
//!
//! Text in SVG output is emitted as SVG `<text>` elements, so rendering needs
//! no font file, fontconfig or system fonts; the viewer picks a `sans-serif`
//! face when the SVG is displayed.

pub(crate) mod atomic;
pub mod error;
pub mod plot;
pub mod table;

pub use error::{InputError, ReportError};
