//! SVG plots of sweep results (plotters): median error against spread and against noise, one line
//! per method, one file per mount pair and axis, e_tran (mm) and e_rot (deg) side by side, log y.

use crate::error::SimError;
use crate::placement::mounts_label;
use crate::sweep::SweepResult;
use calib_core::stats::{quantile, sorted_finite};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// A named polyline `(x, y)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Points, ascending x; non-positive or non-finite y are skipped (log axis).
    pub points: Vec<(f64, f64)>,
}

const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Methods often coincide (lsq with generic at 4 points, paper with constrained): every other
/// series is dashed and each has its own marker, so a line lying on another stays visible.
fn dashed(i: usize) -> bool {
    i % 2 == 1
}

/// A panel: title, x label, y label, series.
pub struct Panel<'a> {
    /// Panel caption.
    pub title: &'a str,
    /// x axis label (with unit).
    pub x_label: &'a str,
    /// y axis label (with unit).
    pub y_label: &'a str,
    /// The lines.
    pub series: &'a [Series],
    /// Where the legend goes: away from the data (errors fall with spread, rise with noise).
    pub legend: SeriesLabelPosition,
}

/// A tick label with two significant digits and no trailing zeros: 0.05, 0.3, 2, 15, 120.
fn tick_label(v: f64) -> String {
    if !(v.is_finite() && v > 0.0) {
        return format!("{v}");
    }
    let decimals = (1 - v.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The 1-2-5 values inside `[lo, hi]` (log-axis ticks; `lo > 0`).
fn ticks_125(lo: f64, hi: f64) -> Vec<f64> {
    let mut ticks = Vec::new();
    let mut decade = 10f64.powf(lo.log10().floor());
    while decade <= hi {
        for m in [1.0, 2.0, 5.0] {
            let v = m * decade;
            if v >= lo && v <= hi {
                ticks.push(v);
            }
        }
        decade *= 10.0;
    }
    ticks
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    p: &Panel,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let pts: Vec<(f64, f64)> = p
        .series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(|(x, y)| x.is_finite() && y.is_finite() && *y > 0.0)
        .collect();
    let (mut x0, mut x1) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), (x, _)| {
        (a.min(*x), b.max(*x))
    });
    let (mut y0, mut y1) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), (_, y)| {
        (a.min(*y), b.max(*y))
    });
    if pts.is_empty() {
        (x0, x1, y0, y1) = (0.0, 1.0, 1e-3, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if y1 <= y0 {
        y1 = y0 * 10.0;
    }
    let pad = (x1 - x0) * 0.05;
    let mut chart = ChartBuilder::on(area)
        .caption(p.title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (x0 - pad)..(x1 + pad),
            (y0 / 1.5..y1 * 1.5)
                .log_scale()
                .with_key_points(ticks_125(y0 / 1.5, y1 * 1.5)),
        )
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(p.x_label)
        .y_desc(p.y_label)
        .x_labels(8)
        .x_label_formatter(&|x| tick_label(*x))
        .y_label_formatter(&|y| tick_label(*y))
        .light_line_style(RGBColor(242, 242, 242))
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, s) in p.series.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        let data: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite() && *y > 0.0)
            .collect();
        let dash = dashed(i);
        if dash {
            chart.draw_series(DashedLineSeries::new(data.clone(), 8, 5, c.stroke_width(2)))
        } else {
            chart.draw_series(LineSeries::new(data.clone(), c.stroke_width(2)))
        }
        .map_err(|e| e.to_string())?
        .label(s.name.clone())
        .legend(move |(x, y)| {
            let end = if dash { x + 8 } else { x + 20 };
            PathElement::new(vec![(x, y), (end, y)], c.stroke_width(2))
        });
        draw_markers(&mut chart, i, c, data)?;
    }
    chart
        .configure_series_labels()
        .position(p.legend.clone())
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())?;
    Ok(())
}

/// Series `i`'s markers: filled circle, triangle, cross, hollow circle, in turn.
fn draw_markers<DB: DrawingBackend>(
    chart: &mut ChartContext<
        DB,
        Cartesian2d<
            plotters::coord::types::RangedCoordf64,
            plotters::coord::combinators::WithKeyPoints<LogCoord<f64>>,
        >,
    >,
    i: usize,
    c: RGBColor,
    data: Vec<(f64, f64)>,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let points = data.into_iter();
    let r = match i % 4 {
        0 => chart.draw_series(points.map(|p| Circle::new(p, 4, c.filled()))),
        1 => chart.draw_series(points.map(|p| TriangleMarker::new(p, 6, c.filled()))),
        2 => chart.draw_series(points.map(|p| Cross::new(p, 5, c.stroke_width(2)))),
        _ => chart.draw_series(points.map(|p| Circle::new(p, 6, c.stroke_width(2)))),
    };
    r.map(|_| ()).map_err(|e| e.to_string())
}

/// Writes an SVG with the panels side by side.
pub fn write_panels_svg(path: &Path, title: &str, panels: &[Panel]) -> Result<(), SimError> {
    let w = 520 * panels.len().max(1) as u32;
    let root = SVGBackend::new(path, (w, 420)).into_drawing_area();
    let run = || -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(title, ("sans-serif", 18))
            .map_err(|e| e.to_string())?;
        let areas = root.split_evenly((1, panels.len().max(1)));
        for (a, p) in areas.iter().zip(panels) {
            draw_panel(a, p)?;
        }
        root.present().map_err(|e| e.to_string())
    };
    run().map_err(|e| SimError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Index of the value nearest `target`.
fn nearest(values: &[f64], target: f64) -> usize {
    values
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 - target).abs().total_cmp(&(b.1 - target).abs()))
        .map_or(0, |(i, _)| i)
}

/// Median e_tran (mm) and e_rot (deg) per method along one axis, the others fixed.
fn medians(
    result: &SweepResult,
    mounts: usize,
    pick: impl Fn(&crate::sweep::GridCell) -> Option<f64>,
) -> (Vec<Series>, Vec<Series>) {
    let c = &result.config;
    let mut tran = Vec::new();
    let mut rot = Vec::new();
    for (m, method) in c.methods.iter().enumerate() {
        let mut pt = Vec::new();
        let mut pr = Vec::new();
        for (ci, g) in result.grid.iter().enumerate() {
            if g.mounts != mounts {
                continue;
            }
            let Some(x) = pick(g) else { continue };
            let trials = ci * c.trials..(ci + 1) * c.trials;
            let et = sorted_finite(trials.clone().filter_map(|t| {
                result
                    .outcome(t, m)
                    .as_ref()
                    .ok()
                    .map(|e| e.errors.e_tran * 1e3)
            }));
            let er = sorted_finite(trials.filter_map(|t| {
                result
                    .outcome(t, m)
                    .as_ref()
                    .ok()
                    .map(|e| e.errors.e_rot.to_degrees())
            }));
            pt.push((x, quantile(&et, 0.5)));
            pr.push((x, quantile(&er, 0.5)));
        }
        pt.sort_by(|a, b| a.0.total_cmp(&b.0));
        pr.sort_by(|a, b| a.0.total_cmp(&b.0));
        tran.push(Series {
            name: method.name().into(),
            points: pt,
        });
        rot.push(Series {
            name: method.name().into(),
            points: pr,
        });
    }
    (tran, rot)
}

/// A mount label as a file-name part: `(` and `,` become `_`, `)` is dropped
/// (`floor-tilt(0.5,0)` → `floor-tilt_0.5_0`); the paper's labels are unchanged.
fn file_stem(label: &str) -> String {
    label
        .chars()
        .filter(|c| *c != ')')
        .map(|c| if c == '(' || c == ',' { '_' } else { c })
        .collect()
}

/// Writes `spread_<mounts>.svg` and `noise_<mounts>.svg` (the label through `file_stem`) into `dir` for every mount pair of the
/// sweep (medians per method; other axes at reference values: noise nearest 1 mm, the smallest
/// point count (the paper's 4 where present), spread nearest 1 m (the paper's advice)). Returns the
/// files written.
pub fn write_sweep_plots(result: &SweepResult, dir: &Path) -> Result<Vec<PathBuf>, SimError> {
    let c = &result.config;
    let noise_ref = nearest(&c.noise_mm, 1.0);
    let n_ref = c
        .n_points
        .iter()
        .enumerate()
        .min_by_key(|(_, n)| **n)
        .map_or(0, |(i, _)| i);
    let spread_ref = nearest(&c.spread_m, 1.0);
    let mut files = Vec::new();
    for (mi, mounts) in c.mounts.iter().enumerate() {
        let label = mounts_label(mounts);
        let (t, r) = medians(result, mi, |g| {
            (g.noise == noise_ref && g.n == n_ref).then(|| c.spread_m[g.spread] * 1e3)
        });
        let path = dir.join(format!("spread_{}.svg", file_stem(&label)));
        let title = format!(
            "{label} ({} mode, {} layout): median error vs spread; σ = {} mm, n = {}, {} trials",
            c.mode.name(),
            c.layout,
            c.noise_mm[noise_ref],
            c.n_points[n_ref],
            c.trials
        );
        write_panels_svg(
            &path,
            &title,
            &[
                Panel {
                    title: "e_tran (eq 34)",
                    x_label: "spread, mm",
                    y_label: "median e_tran, mm",
                    series: &t,
                    legend: SeriesLabelPosition::UpperRight,
                },
                Panel {
                    title: "e_rot (eq 33)",
                    x_label: "spread, mm",
                    y_label: "median e_rot, deg",
                    series: &r,
                    legend: SeriesLabelPosition::UpperRight,
                },
            ],
        )?;
        files.push(path);
        let (t, r) = medians(result, mi, |g| {
            (g.spread == spread_ref && g.n == n_ref).then(|| c.noise_mm[g.noise])
        });
        let path = dir.join(format!("noise_{}.svg", file_stem(&label)));
        let title = format!(
            "{label} ({} mode, {} layout): median error vs noise; spread = {} mm, n = {}, {} trials",
            c.mode.name(),
            c.layout,
            c.spread_m[spread_ref] * 1e3,
            c.n_points[n_ref],
            c.trials
        );
        write_panels_svg(
            &path,
            &title,
            &[
                Panel {
                    title: "e_tran (eq 34)",
                    x_label: "alignment σ, mm",
                    y_label: "median e_tran, mm",
                    series: &t,
                    legend: SeriesLabelPosition::UpperLeft,
                },
                Panel {
                    title: "e_rot (eq 33)",
                    x_label: "alignment σ, mm",
                    y_label: "median e_rot, deg",
                    series: &r,
                    legend: SeriesLabelPosition::UpperLeft,
                },
            ],
        )?;
        files.push(path);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: a tilted mount's label put `(`, `)` and `,` into the SVG file names.
    #[test]
    fn file_stems_have_no_parentheses_or_commas() {
        assert_eq!(file_stem("floor-tilt(0.5,0)"), "floor-tilt_0.5_0");
        assert_eq!(file_stem("floor-wall"), "floor-wall");
    }

    #[test]
    fn tick_labels_are_short() {
        // Regression: the log axis printed `0.30000000000000004`.
        assert_eq!(tick_label(0.30000000000000004), "0.3");
        assert_eq!(tick_label(0.05), "0.05");
        assert_eq!(tick_label(2.0), "2");
        assert_eq!(tick_label(2.5), "2.5");
        assert_eq!(tick_label(15.0), "15");
        assert_eq!(tick_label(1000.0), "1000");
    }

    #[test]
    fn log_ticks_are_1_2_5() {
        let t = ticks_125(0.04, 12.0);
        let want = [0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0];
        assert_eq!(t.len(), want.len(), "{t:?}");
        for (a, b) in t.iter().zip(want) {
            assert!((a - b).abs() < 1e-12 * b, "{t:?}");
        }
    }

    #[test]
    fn reference_values_are_the_nearest_grid_entries() {
        // Regression: the reference spread was `nearest(spreads, f64::MAX)`, which is the first
        // entry (|a − MAX| rounds to MAX for every a), so the noise plots showed 250 mm.
        let spreads = [0.25, 0.5, 1.0, 1.5];
        assert_eq!(nearest(&spreads, 1.0), 2);
        assert_eq!(nearest(&[0.5, 1.0, 2.0, 3.0], 1.0), 1);
        assert_eq!(nearest(&[0.25], 1.0), 0);
    }
}
