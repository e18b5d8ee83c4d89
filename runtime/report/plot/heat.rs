//! Category maps: panels of labelled grid cells, each cell filled with its
//! category's colour and carrying a short text (a ratio, a value).

use plotters::prelude::*;

use super::{Area, DrawResult, colour};

/// One panel: row and column labels, and per cell (row-major) its category
/// (an index into the legend) and text.
pub struct HeatPanel {
    pub title: String,
    pub row_title: String,
    pub column_title: String,
    pub rows: Vec<String>,
    pub columns: Vec<String>,
    pub cells: Vec<Vec<(usize, String)>>,
}

/// Panels side by side under `title`, a legend of `categories` below.
pub(super) fn draw(
    root: &Area<'_>,
    title: &str,
    panels: &[HeatPanel],
    categories: &[&str],
) -> DrawResult {
    let body = root.titled(title, ("sans-serif", 24))?;
    let (grid, legend) = body.split_vertically(body.dim_in_pixel().1.saturating_sub(50));
    for (area, panel) in grid
        .split_evenly((1, panels.len().max(1)))
        .iter()
        .zip(panels)
    {
        draw_panel(area, panel)?;
    }
    for (k, name) in categories.iter().enumerate() {
        let x = 20 + 170 * k as i32;
        legend.draw(&Rectangle::new(
            [(x, 15), (x + 18, 33)],
            colour(k).mix(0.6).filled(),
        ))?;
        legend.draw(&Text::new(
            name.to_string(),
            (x + 24, 17),
            ("sans-serif", 15),
        ))?;
    }
    Ok(())
}

fn draw_panel(area: &Area<'_>, panel: &HeatPanel) -> DrawResult {
    let area = area.titled(&panel.title, ("sans-serif", 18))?;
    let (width, height) = area.dim_in_pixel();
    let (left, top, bottom) = (70_i32, 30_i32, 40_i32);
    let columns = panel.columns.len().max(1) as i32;
    let rows = panel.rows.len().max(1) as i32;
    let cell_w = (width as i32 - left - 10) / columns;
    let cell_h = (height as i32 - top - bottom) / rows;
    let font = ("sans-serif", 14);
    for (r, row) in panel.cells.iter().enumerate() {
        for (c, (category, text)) in row.iter().enumerate() {
            let (x, y) = (left + c as i32 * cell_w, top + r as i32 * cell_h);
            let fill = colour(*category).mix(0.6).filled();
            area.draw(&Rectangle::new(
                [(x, y), (x + cell_w - 2, y + cell_h - 2)],
                fill,
            ))?;
            area.draw(&Text::new(text.clone(), (x + 6, y + cell_h / 2 - 7), font))?;
        }
    }
    for (r, label) in panel.rows.iter().enumerate() {
        let y = top + r as i32 * cell_h + cell_h / 2 - 7;
        area.draw(&Text::new(label.clone(), (8, y), font))?;
    }
    for (c, label) in panel.columns.iter().enumerate() {
        let x = left + c as i32 * cell_w + cell_w / 2 - 8;
        area.draw(&Text::new(label.clone(), (x, top - 20), font))?;
    }
    let bottom_y = height as i32 - bottom + 12;
    area.draw(&Text::new(panel.column_title.clone(), (left, 4), font))?;
    area.draw(&Text::new(panel.row_title.clone(), (8, bottom_y), font))?;
    Ok(())
}
