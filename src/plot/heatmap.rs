//! The residual figure: measured matrix, fitted matrix and residual as heat maps over
//! excitation (x) and emission (y), with colour bars.
//!
//! Cells are drawn as pixel rectangles computed by [`HeatmapPanel`], the same mapping the
//! figure reports, so a pixel probe at [`HeatmapPanel::cell_centre_px`] shows exactly
//! [`HeatmapPanel::scale`]`.colour(value)` for a Stokes or anti-Stokes cell.
//! Diagonal cells are black, guard-band cells faded towards white, cells the fit's scatter
//! masking removed hatched on light grey ([`CellClass::Masked`], also hatched over the
//! fitted panel, where the model still has a value), cells the file does not hold plain
//! grey; the legend lists each kind present.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::colormap::{self, ColourScale};
use super::common::{
    Draw, DrawResult, anchored, draw_text, draw_title, font, format_significant, format_tick,
    tick_step, ticks,
};
use super::{Comparison, Layout};
use crate::material::Material;
use crate::measurement::{CellKind, Measurement, Units};

/// Size of the residual figure in pixels.
pub const SIZE: (u32, u32) = (1300, 540);

/// How much a guard-band cell's colour is mixed with white.
pub const GUARD_FADE: f64 = 0.6;

const TITLE_HEIGHT: i32 = 44;
const LEGEND_HEIGHT: i32 = 40;
const PANEL_WIDTH: i32 = 350;
const BAR_WIDTH: i32 = 125;

/// Where one heat map sits in the image and how it maps cells to pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatmapPanel {
    /// Panel title ("measured", "fitted", "residual").
    pub title: String,
    /// Plotting area in pixels: left, top, right, bottom (right and bottom exclusive).
    pub plot_area_px: [i32; 4],
    /// Excitation cell edges (nm), one more than cells; cell i spans edges i..i+1.
    pub excitation_edges_nm: Vec<f64>,
    /// Emission cell edges (nm), one more than cells.
    pub emission_edges_nm: Vec<f64>,
    /// The colour scale of this panel's values.
    pub scale: ColourScale,
}

impl HeatmapPanel {
    /// Horizontal pixel position of excitation wavelength `nm` (fractional).
    pub fn x_px(&self, nm: f64) -> f64 {
        let [left, _, right, _] = self.plot_area_px;
        let e = &self.excitation_edges_nm;
        let (lo, hi) = (e[0], e[e.len() - 1]);
        left as f64 + (nm - lo) / (hi - lo) * (right - left) as f64
    }

    /// Vertical pixel position of emission wavelength `nm` (fractional; up is longer).
    pub fn y_px(&self, nm: f64) -> f64 {
        let [_, top, _, bottom] = self.plot_area_px;
        let e = &self.emission_edges_nm;
        let (lo, hi) = (e[0], e[e.len() - 1]);
        bottom as f64 - (nm - lo) / (hi - lo) * (bottom - top) as f64
    }

    /// Pixel rectangle of cell (excitation `i`, emission `j`): left, top, right, bottom
    /// (right and bottom exclusive).
    pub fn cell_rect_px(&self, i: usize, j: usize) -> [i32; 4] {
        let left = self.x_px(self.excitation_edges_nm[i]).round() as i32;
        let right = self.x_px(self.excitation_edges_nm[i + 1]).round() as i32;
        let top = self.y_px(self.emission_edges_nm[j + 1]).round() as i32;
        let bottom = self.y_px(self.emission_edges_nm[j]).round() as i32;
        [left, top, right.max(left + 1), bottom.max(top + 1)]
    }

    /// The pixel at the centre of cell (`i`, `j`).
    pub fn cell_centre_px(&self, i: usize, j: usize) -> (i32, i32) {
        let [left, top, right, bottom] = self.cell_rect_px(i, j);
        ((left + right - 1) / 2, (top + bottom - 1) / 2)
    }
}

/// Cell edges of a grid: midway between samples, and half a step beyond the ends.
pub fn cell_edges(grid: &[f64]) -> Vec<f64> {
    match grid.len() {
        0 => vec![0.0, 1.0],
        1 => vec![grid[0] - 5.0, grid[0] + 5.0],
        n => {
            let mut edges = Vec::with_capacity(n + 1);
            edges.push(grid[0] - 0.5 * (grid[1] - grid[0]));
            edges.extend(grid.windows(2).map(|w| 0.5 * (w[0] + w[1])));
            edges.push(grid[n - 1] + 0.5 * (grid[n - 1] - grid[n - 2]));
            edges
        }
    }
}

/// The value scale shared by the measured and fitted panels: from 0 to the largest value
/// of either matrix outside the diagonal and guard band (reflectance would swamp the
/// fluorescence).
pub fn value_scale(c: &Comparison) -> ColourScale {
    let mut max = f64::NEG_INFINITY;
    for i in 0..c.measured.n_excitation() {
        for j in 0..c.measured.n_emission() {
            if matches!(c.kind(i, j), CellKind::Stokes | CellKind::AntiStokes) {
                max = max.max(c.measured.get(i, j)).max(c.fitted.get(i, j));
            } else if c.kind(i, j) == CellKind::Missing {
                let fitted_kind = c.fitted.cell_kind(i, j, c.guard_nm);
                if matches!(fitted_kind, CellKind::Stokes | CellKind::AntiStokes) {
                    max = max.max(c.fitted.get(i, j));
                }
            }
        }
    }
    ColourScale::sequential(0.0, if max > 0.0 { max } else { 1.0 })
}

/// The residual scale: symmetric about zero, reaching the largest |measured − fitted|
/// outside the diagonal and guard band.
pub fn residual_scale(c: &Comparison) -> ColourScale {
    let mut limit = 0.0f64;
    for i in 0..c.measured.n_excitation() {
        for j in 0..c.measured.n_emission() {
            if matches!(c.kind(i, j), CellKind::Stokes | CellKind::AntiStokes) {
                limit = limit.max(c.residual(i, j).abs());
            }
        }
    }
    ColourScale::diverging(limit)
}

/// How the residual figure draws a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellClass {
    /// A fitted off-diagonal cell (Stokes or anti-Stokes): its value's colour.
    Fitted,
    /// The diagonal λo = λi: black.
    Diagonal,
    /// In the guard band: its value's colour faded towards white.
    Guard,
    /// Removed by scatter masking (Rayleigh, Raman): hatched on light grey.
    Masked,
    /// Not recorded in the file: plain grey.
    Missing,
}

impl CellClass {
    /// The class of a cell of `kind`; `masked` says a missing cell was masked as scatter.
    pub fn of(kind: CellKind, masked: bool) -> Self {
        match kind {
            CellKind::Missing if masked => CellClass::Masked,
            CellKind::Missing => CellClass::Missing,
            CellKind::Diagonal => CellClass::Diagonal,
            CellKind::Guard => CellClass::Guard,
            CellKind::Stokes | CellKind::AntiStokes => CellClass::Fitted,
        }
    }
}

/// The class of every cell of the measured and residual panels, row-major (excitation
/// × emission): what the drawing uses.
pub fn cell_classes(c: &Comparison) -> Vec<CellClass> {
    let (n_ex, n_em) = (c.measured.n_excitation(), c.measured.n_emission());
    (0..n_ex * n_em)
        .map(|k| {
            let (i, j) = (k / n_em, k % n_em);
            CellClass::of(c.kind(i, j), c.is_masked(i, j))
        })
        .collect()
}

/// The colour a panel gives a cell of `kind` with `value`.
pub fn cell_colour(kind: CellKind, value: f64, scale: &ColourScale) -> RGBColor {
    class_colour(CellClass::of(kind, false), value, scale)
}

/// The colour a panel fills a cell of `class` with `value` (masked cells also get hatch
/// lines of [`colormap::HATCH`], see [`hatch_segments`]).
pub fn class_colour(class: CellClass, value: f64, scale: &ColourScale) -> RGBColor {
    match class {
        CellClass::Missing => colormap::MISSING,
        CellClass::Masked => colormap::MASKED,
        CellClass::Diagonal => colormap::DIAGONAL,
        CellClass::Guard => colormap::mix(scale.colour(value), WHITE, GUARD_FADE),
        CellClass::Fitted => scale.colour(value),
    }
}

/// Spacing (pixels) of the hatch lines on masked cells.
pub const HATCH_SPACING: i32 = 5;

/// The hatch lines of a pixel rectangle (left, top, right, bottom; right and bottom
/// exclusive): the diagonals x + y = a multiple of [`HATCH_SPACING`], clipped to it, so
/// neighbouring masked cells continue each other's lines.
pub fn hatch_segments([left, top, right, bottom]: [i32; 4]) -> Vec<[(i32, i32); 2]> {
    let (first, last) = (left + top, right - 1 + bottom - 1);
    let mut sum = first.div_euclid(HATCH_SPACING) * HATCH_SPACING;
    if sum < first {
        sum += HATCH_SPACING;
    }
    let mut segments = Vec::new();
    while sum <= last {
        let (x0, x1) = (left.max(sum - (bottom - 1)), (right - 1).min(sum - top));
        if x0 <= x1 {
            segments.push([(x0, sum - x0), (x1, sum - x1)]);
        }
        sum += HATCH_SPACING;
    }
    segments
}

fn units_label(m: &Measurement) -> &'static str {
    match (m.arbitrary_scale, m.units) {
        (true, _) => "arbitrary units",
        (false, Units::PerBin) => "radiance factor per emission bin",
        (false, Units::PerNm) => "radiance factor per nm",
    }
}

fn fitted_title(material: &Material, c: &Comparison) -> String {
    let n = material.fluorophores.len();
    let plural = if n == 1 { "" } else { "s" };
    if c.fitted_scale == 1.0 {
        format!("fitted ({n} fluorophore{plural})")
    } else {
        format!(
            "fitted ({n} fluorophore{plural}) × {}",
            format_significant(c.fitted_scale, 3)
        )
    }
}

/// The residual figure: measured, fitted and their difference.
pub(crate) struct ResidualFigure<'a> {
    pub(crate) material: &'a Material,
    pub(crate) comparison: &'a Comparison,
}

struct PanelSpec<'a> {
    title: String,
    x: i32,
    scale: ColourScale,
    class: &'a dyn Fn(usize, usize) -> CellClass,
    value: &'a dyn Fn(usize, usize) -> f64,
}

impl Draw for ResidualFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let c = self.comparison;
        let m = &c.measured;
        let (width, height) = SIZE;
        draw_title(
            root,
            &format!(
                "{}: reradiation matrix, measured vs fitted ({})",
                self.material.name,
                units_label(m)
            ),
            (width as i32 / 2, TITLE_HEIGHT / 2 + 2),
        )?;

        let values = value_scale(c);
        let residuals = residual_scale(c);
        let classes = cell_classes(c);
        let n_em = m.n_emission();
        let measured_class = |i: usize, j: usize| classes[i * n_em + j];
        // The model has a value on masked cells: drawn plain, hatched over below.
        let fitted_class = |i: usize, j: usize| match c.is_masked(i, j) {
            true => CellClass::Fitted,
            false => CellClass::of(c.fitted.cell_kind(i, j, c.guard_nm), false),
        };
        let measured_value = |i: usize, j: usize| m.get(i, j);
        let fitted_value = |i: usize, j: usize| c.fitted.get(i, j);
        let residual_value = |i: usize, j: usize| c.residual(i, j);
        let rel = c.relative_residual_stokes();
        let residual_title = if rel.is_finite() {
            format!(
                "residual = measured − fitted ({} % rel.)",
                format_significant(100.0 * rel, 3)
            )
        } else {
            "residual = measured − fitted".to_string()
        };
        let specs = [
            PanelSpec {
                title: "measured".to_string(),
                x: 0,
                scale: values,
                class: &measured_class,
                value: &measured_value,
            },
            PanelSpec {
                title: fitted_title(self.material, c),
                x: PANEL_WIDTH,
                scale: values,
                class: &fitted_class,
                value: &fitted_value,
            },
            PanelSpec {
                title: residual_title,
                x: 2 * PANEL_WIDTH + BAR_WIDTH,
                scale: residuals,
                class: &measured_class,
                value: &residual_value,
            },
        ];
        let mut panels = Vec::new();
        for spec in &specs {
            panels.push(draw_panel(root, c, spec)?);
        }
        let unit = units_label(m);
        draw_colour_bar(root, 2 * PANEL_WIDTH, &panels[1], &values, unit)?;
        draw_colour_bar(
            root,
            3 * PANEL_WIDTH + BAR_WIDTH,
            &panels[2],
            &residuals,
            &format!("residual, {unit}"),
        )?;
        let present = |class: CellClass| classes.contains(&class);
        draw_legend(
            root,
            c.guard_nm,
            m.has_diagonal,
            [
                present(CellClass::Guard),
                present(CellClass::Masked),
                present(CellClass::Missing),
            ],
            height as i32 - LEGEND_HEIGHT / 2,
        )?;
        Ok(Layout {
            heatmaps: panels,
            ..Layout::default()
        })
    }
}

fn draw_panel<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    c: &Comparison,
    spec: &PanelSpec<'_>,
) -> DrawResult<HeatmapPanel, DB> {
    let m = &c.measured;
    let body_height = SIZE.1 as i32 - TITLE_HEIGHT - LEGEND_HEIGHT;
    let area = root.clone().shrink(
        (spec.x, TITLE_HEIGHT),
        (PANEL_WIDTH as u32, body_height as u32),
    );
    let ex_edges = cell_edges(&m.excitation_nm);
    let em_edges = cell_edges(&m.emission_nm);
    let x_range = ex_edges[0]..ex_edges[ex_edges.len() - 1];
    let y_range = em_edges[0]..em_edges[em_edges.len() - 1];
    let mut chart = ChartBuilder::on(&area)
        .caption(&spec.title, font(16.0))
        .margin_top(4)
        .margin_left(4)
        .margin_right(14)
        .margin_bottom(2)
        .x_label_area_size(48)
        .y_label_area_size(62)
        .build_cartesian_2d(x_range.clone(), y_range.clone())?;
    let (xs, ys) = chart.plotting_area().get_pixel_range();
    let panel = HeatmapPanel {
        title: spec.title.clone(),
        plot_area_px: [xs.start, ys.start, xs.end, ys.end],
        excitation_edges_nm: ex_edges,
        emission_edges_nm: em_edges,
        scale: spec.scale,
    };
    for i in 0..m.n_excitation() {
        for j in 0..m.n_emission() {
            let colour = class_colour((spec.class)(i, j), (spec.value)(i, j), &spec.scale);
            let [l, t, r, b] = panel.cell_rect_px(i, j);
            root.draw(&Rectangle::new([(l, t), (r, b)], colour.filled()))?;
        }
    }
    // Hatch every masked cell, over the model's value on the fitted panel.
    for i in 0..m.n_excitation() {
        for j in 0..m.n_emission() {
            if c.is_masked(i, j) {
                for segment in hatch_segments(panel.cell_rect_px(i, j)) {
                    root.draw(&PathElement::new(segment.to_vec(), colormap::HATCH))?;
                }
            }
        }
    }
    let step_x = tick_step(x_range.start, x_range.end, 5);
    let step_y = tick_step(y_range.start, y_range.end, 5);
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&|v| format_tick(*v, step_x))
        .y_label_formatter(&|v| format_tick(*v, step_y))
        .x_desc("excitation λi (nm)")
        .y_desc("emission λo (nm)")
        .label_style(font(14.0))
        .axis_desc_style(font(15.0))
        .draw()?;
    Ok(panel)
}

fn draw_colour_bar<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    x: i32,
    beside: &HeatmapPanel,
    scale: &ColourScale,
    label: &str,
) -> DrawResult<(), DB> {
    let [_, top, _, bottom] = beside.plot_area_px;
    let (bar_left, bar_right) = (x + 4, x + 22);
    let rows = (bottom - top).max(2);
    for py in top..bottom {
        let t = (bottom - 1 - py) as f64 / (rows - 1) as f64;
        root.draw(&Rectangle::new(
            [(bar_left, py), (bar_right, py + 1)],
            scale.map.at(t).filled(),
        ))?;
    }
    root.draw(&Rectangle::new(
        [(bar_left, top), (bar_right, bottom)],
        BLACK.stroke_width(1),
    ))?;
    let step = tick_step(scale.min, scale.max, 5);
    for v in ticks(scale.min, scale.max, 5) {
        let py = bottom as f64 - 1.0 - scale.position(v) * (rows - 1) as f64;
        let py = py.round() as i32;
        root.draw(&PathElement::new(
            vec![(bar_right, py), (bar_right + 4, py)],
            BLACK.stroke_width(1),
        ))?;
        draw_text(
            root,
            &format_tick(v, step),
            (bar_right + 6, py),
            &anchored(font(13.0), HPos::Left, VPos::Center),
        )?;
    }
    let label_style =
        anchored(font(14.0), HPos::Center, VPos::Center).transform(FontTransform::Rotate270);
    draw_text(root, label, (x + 92, (top + bottom) / 2), &label_style)
}

/// The legend of cell markings, listing only the kinds the data have.
fn draw_legend<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    guard_nm: f64,
    has_diagonal: bool,
    [any_guard, any_masked, any_missing]: [bool; 3],
    y: i32,
) -> DrawResult<(), DB> {
    let guard_sample = colormap::mix(colormap::viridis(0.5), WHITE, GUARD_FADE);
    let mut items = Vec::new();
    if has_diagonal {
        items.push((
            colormap::DIAGONAL,
            "diagonal λo = λi (reflectance; see spectra)".to_string(),
        ));
    }
    let guard_text = if has_diagonal {
        format!(
            "guard band 0 < |λo − λi| ≤ {} nm (crosstalk, not fitted)",
            format_significant(guard_nm, 3)
        )
    } else {
        format!(
            "guard band |λo − λi| ≤ {} nm (scatter, not fitted)",
            format_significant(guard_nm, 3)
        )
    };
    if any_guard {
        items.push((guard_sample, guard_text));
    }
    if any_masked {
        items.push((colormap::MASKED, "scatter masked (not fitted)".to_string()));
    }
    if any_missing {
        items.push((colormap::MISSING, "not recorded".to_string()));
    }
    let mut x = 70;
    for (colour, text) in items {
        root.draw(&Rectangle::new(
            [(x, y - 8), (x + 16, y + 8)],
            colour.filled(),
        ))?;
        if colour == colormap::MASKED {
            for segment in hatch_segments([x, y - 8, x + 16, y + 8]) {
                root.draw(&PathElement::new(segment.to_vec(), colormap::HATCH))?;
            }
        }
        root.draw(&Rectangle::new(
            [(x, y - 8), (x + 16, y + 8)],
            RGBColor(90, 90, 90).stroke_width(1),
        ))?;
        let style = anchored(font(15.0), HPos::Left, VPos::Center);
        draw_text(root, &text, (x + 24, y), &style)?;
        let (w, _) = root.estimate_text_size(&text, &style)?;
        x += 24 + w as i32 + 40;
    }
    Ok(())
}
