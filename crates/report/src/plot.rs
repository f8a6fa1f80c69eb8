//! The page's plots: SVG text from plotters' SVG backend (no file, no font file: the text is
//! SVG `<text>` that the browser sets). Each function returns the `<svg>` element, or why it
//! could not be drawn (the page prints that in the plot's place).

use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;

use crate::fit_data::{JointCoverage, RowResidual};
use calib_core::Robot;

/// Used rows.
const USED: RGBColor = RGBColor(31, 119, 180);
/// Rejected rows and "before" values.
const REJECTED: RGBColor = RGBColor(214, 39, 40);
/// "After" values and the session's range.
const AFTER: RGBColor = RGBColor(44, 160, 44);
/// Light grid lines and the joints' full travel.
const LIGHT: RGBColor = RGBColor(225, 225, 225);

/// Caption and axis-label font size, px.
const FONT: u32 = 14;

/// Plot width, px.
const WIDTH: u32 = 860;

type PlotResult = Result<(), String>;

/// Draws into an SVG string of `size` with `draw`.
fn svg(
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> PlotResult,
) -> Result<String, String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        draw(&root)?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(out)
}

/// The chart's legend, upper right on a light box.
fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())
}

/// `[lo, hi]` of `values` padded by 5 % (a unit range around a single value; `[0, 1]` for none).
fn padded(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo <= 0.0 {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

/// Residual (mm) per session row: used rows as filled circles, rejected rows as red crosses.
pub fn residual_per_row(rows: &[RowResidual]) -> Result<String, String> {
    svg((WIDTH, 320), |root| {
        let (x0, x1) = padded(rows.iter().map(|r| r.row as f64));
        let (_, y1) = padded(rows.iter().map(|r| r.residual_mm).chain([0.0]));
        let mut chart = ChartBuilder::on(root)
            .caption("residual per session row", ("sans-serif", FONT + 2))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, 0.0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("session row (point)")
            .y_desc("residual, mm")
            .light_line_style(LIGHT)
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(
                rows.iter()
                    .filter(|r| !r.rejected)
                    .map(|r| Circle::new((r.row as f64, r.residual_mm), 3, USED.filled())),
            )
            .map_err(|e| e.to_string())?
            .label("used by the fit")
            .legend(|(x, y)| Circle::new((x + 8, y), 3, USED.filled()));
        chart
            .draw_series(
                rows.iter().filter(|r| r.rejected).map(|r| {
                    Cross::new((r.row as f64, r.residual_mm), 6, REJECTED.stroke_width(2))
                }),
            )
            .map_err(|e| e.to_string())?
            .label("rejected as a blunder")
            .legend(|(x, y)| Cross::new((x + 8, y), 5, REJECTED.stroke_width(2)));
        legend(&mut chart)
    })
}

/// Residual (mm) against each joint of `robot` (`dof` joints), one small panel a joint, three
/// a line; rejected rows as red crosses.
pub fn residual_against_joints(
    rows: &[RowResidual],
    robot: Robot,
    dof: usize,
) -> Result<String, String> {
    let cols = 3usize;
    let lines = dof.div_ceil(cols).max(1);
    let q = |r: &RowResidual| match robot {
        Robot::One => r.q1_deg.clone(),
        Robot::Two => r.q2_deg.clone(),
    };
    let (_, y1) = padded(rows.iter().map(|r| r.residual_mm).chain([0.0]));
    svg((WIDTH, 230 * lines as u32 + 30), |root| {
        let root = root
            .titled(
                &format!("residual against robot {}'s joints", robot.number()),
                ("sans-serif", FONT + 2),
            )
            .map_err(|e| e.to_string())?;
        let areas = root.split_evenly((lines, cols));
        for (j, area) in areas.iter().enumerate().take(dof) {
            let pts: Vec<(f64, f64, bool)> = rows
                .iter()
                .filter_map(|r| {
                    q(r).and_then(|v| v.get(j).copied())
                        .map(|x| (x, r.residual_mm, r.rejected))
                })
                .collect();
            let (x0, x1) = padded(pts.iter().map(|p| p.0));
            let mut chart = ChartBuilder::on(area)
                .margin(8)
                .x_label_area_size(34)
                .y_label_area_size(48)
                .build_cartesian_2d(x0..x1, 0.0..y1)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc(format!("q{}, deg", j + 1))
                .y_desc("residual, mm")
                .x_labels(5)
                .y_labels(5)
                .light_line_style(LIGHT)
                .draw()
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(
                    pts.iter()
                        .filter(|p| !p.2)
                        .map(|p| Circle::new((p.0, p.1), 2, USED.filled())),
                )
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(
                    pts.iter()
                        .filter(|p| p.2)
                        .map(|p| Cross::new((p.0, p.1), 5, REJECTED.stroke_width(2))),
                )
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    })
}

/// Each joint's travel (grey) and the range the session covers (green), one bar a joint,
/// robot 1's joints first; the fraction of the travel at the bar's end.
pub fn coverage(joints: &[JointCoverage]) -> Result<String, String> {
    let n = joints.len().max(1);
    let (x0, x1) = padded(joints.iter().flat_map(|j| [j.lower, j.upper]));
    svg((WIDTH, 40 + 26 * n as u32 + 50), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(
                "coverage of each joint's range (grey: limits, green: this session)",
                ("sans-serif", FONT + 2),
            )
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(110)
            .build_cartesian_2d(x0..x1, 0.0..n as f64)
            .map_err(|e| e.to_string())?;
        let label = |y: f64| {
            let i = n.saturating_sub(1 + y.floor() as usize);
            joints
                .get(i)
                .map(|j| format!("robot {} q{}", j.robot.number(), j.joint))
                .unwrap_or_default()
        };
        chart
            .configure_mesh()
            .x_desc("joint value, deg (mm for a linear axis)")
            .y_labels(n * 2 + 1)
            .y_label_formatter(&|y| {
                if (y.fract() - 0.5).abs() < 1e-6 {
                    label(*y)
                } else {
                    String::new()
                }
            })
            .disable_y_mesh()
            .light_line_style(LIGHT)
            .draw()
            .map_err(|e| e.to_string())?;
        // Row i from the top: y in [n − 1 − i, n − i].
        let band = |i: usize| (n - 1 - i) as f64;
        chart
            .draw_series(joints.iter().enumerate().map(|(i, j)| {
                Rectangle::new(
                    [(j.lower, band(i) + 0.2), (j.upper, band(i) + 0.8)],
                    LIGHT.filled(),
                )
            }))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(joints.iter().enumerate().filter_map(|(i, j)| {
                j.session.map(|[a, b]| {
                    Rectangle::new(
                        [(a, band(i) + 0.25), (b.max(a + 1e-9), band(i) + 0.75)],
                        AFTER.filled(),
                    )
                })
            }))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(joints.iter().enumerate().map(|(i, j)| {
                Text::new(
                    format!("{:.0} %", j.fraction * 100.0),
                    (j.upper, band(i) + 0.75),
                    ("sans-serif", 12),
                )
            }))
            .map_err(|e| e.to_string())?;
        Ok(())
    })
}

/// A bar per label of `values` (one colour a series; at most 2 series: red then green), for
/// "before/after" and per-point charts; `y_desc` names the unit.
pub fn bars(
    title: &str,
    labels: &[String],
    series: &[(&str, Vec<f64>)],
    y_desc: &str,
) -> Result<String, String> {
    let n = labels.len().max(1);
    let k = series.len().max(1);
    // Headroom above the tallest bar for the legend.
    let (_, y1) = padded(series.iter().flat_map(|s| s.1.iter().copied()).chain([0.0]));
    let y1 = y1 * 1.3;
    let height = 320;
    svg((WIDTH, height), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", FONT + 2))
            .margin(10)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..n as f64, 0.0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .y_desc(y_desc)
            .x_labels(n * 2 + 1)
            .x_label_formatter(&|x| {
                let i = x.floor() as usize;
                if (x.fract() - 0.5).abs() < 1e-6 {
                    labels.get(i).cloned().unwrap_or_default()
                } else {
                    String::new()
                }
            })
            .disable_x_mesh()
            .light_line_style(LIGHT)
            .draw()
            .map_err(|e| e.to_string())?;
        let width = 0.8 / k as f64;
        for (s, (name, values)) in series.iter().enumerate() {
            let colour = if series.len() == 1 {
                USED
            } else if s == 0 {
                REJECTED
            } else {
                AFTER
            };
            let left = |i: usize| i as f64 + 0.1 + s as f64 * width;
            chart
                .draw_series(
                    values
                        .iter()
                        .enumerate()
                        .filter(|(_, v)| v.is_finite())
                        .map(|(i, v)| {
                            Rectangle::new(
                                [(left(i), 0.0), (left(i) + width * 0.95, *v)],
                                colour.filled(),
                            )
                        }),
                )
                .map_err(|e| e.to_string())?
                .label(*name)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 10, y + 5)], colour.filled())
                });
        }
        legend(&mut chart)
    })
}

/// Lines of `(x, before)` and `(x, after)` (the diagnosis's residual trend along one joint).
pub fn before_after_lines(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    x: &[f64],
    before: &[f64],
    after: &[f64],
) -> Result<String, String> {
    let (x0, x1) = padded(x.iter().copied());
    let (_, y1) = padded(before.iter().chain(after).copied().chain([0.0]));
    svg((WIDTH / 2, 280), |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", FONT))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(50)
            .build_cartesian_2d(x0..x1, 0.0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_labels(5)
            .light_line_style(LIGHT)
            .draw()
            .map_err(|e| e.to_string())?;
        for (name, values, colour) in [("before", before, REJECTED), ("after", after, AFTER)] {
            let pts: Vec<(f64, f64)> = x
                .iter()
                .copied()
                .zip(values.iter().copied())
                .filter(|p| p.1.is_finite())
                .collect();
            chart
                .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| e.to_string())?;
        }
        legend(&mut chart)
    })
}

/// Colour of a predicted rms in `[lo, hi]`: blue (small) through amber to red (large).
fn heat(v: f64, lo: f64, hi: f64) -> RGBColor {
    let t = if hi > lo {
        ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mix =
        |a: u8, b: u8, f: f64| (f64::from(a) + (f64::from(b) - f64::from(a)) * f).round() as u8;
    let (c0, c1, f) = if t < 0.5 {
        (USED, RGBColor(255, 170, 0), 2.0 * t)
    } else {
        (RGBColor(255, 170, 0), REJECTED, 2.0 * t - 1.0)
    };
    RGBColor(mix(c0.0, c1.0, f), mix(c0.1, c1.1, f), mix(c0.2, c1.2, f))
}

/// The predicted error over the workspace: each workspace pose's meeting point (robot 1's tip in
/// base 1, mm) seen from above (x, y) and from the side (x, z), coloured by its predicted
/// cooperative rms (mm; blue small, red large; the legend gives the colour of the smallest,
/// middle and largest value); the session's meeting points (`session_mm`) as black crosses.
pub fn workspace_map(
    points_mm: &[[f64; 3]],
    rms_mm: &[f64],
    session_mm: &[[f64; 3]],
) -> Result<String, String> {
    if points_mm.is_empty() || points_mm.len() != rms_mm.len() {
        return Err("no workspace pose was predicted".into());
    }
    let (lo, hi) = rms_mm
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    svg((WIDTH, 440), |root| {
        let root = root
            .titled(
                "predicted cooperative rms over the workspace (meeting points in base 1)",
                ("sans-serif", FONT + 2),
            )
            .map_err(|e| e.to_string())?;
        let panels = root.split_evenly((1, 2));
        for (k, (axis, name)) in [(1usize, "y, mm"), (2usize, "z, mm")]
            .into_iter()
            .enumerate()
        {
            let all = points_mm.iter().chain(session_mm);
            let (x0, x1) = padded(all.clone().map(|p| p[0]));
            let (y0, y1) = padded(all.map(|p| p[axis]));
            let mut chart = ChartBuilder::on(&panels[k])
                .caption(
                    if k == 0 {
                        "from above (x, y)"
                    } else {
                        "from the side (x, z)"
                    },
                    ("sans-serif", FONT),
                )
                .margin(8)
                .x_label_area_size(34)
                .y_label_area_size(54)
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc("x, mm")
                .y_desc(name)
                .x_labels(5)
                .y_labels(5)
                .light_line_style(LIGHT)
                .draw()
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(
                    points_mm
                        .iter()
                        .zip(rms_mm)
                        .map(|(p, v)| Circle::new((p[0], p[axis]), 4, heat(*v, lo, hi).filled())),
                )
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(
                    session_mm
                        .iter()
                        .map(|p| Cross::new((p[0], p[axis]), 4, BLACK.stroke_width(1))),
                )
                .map_err(|e| e.to_string())?;
            if k == 0 {
                for v in [lo, 0.5 * (lo + hi), hi] {
                    let c = heat(v, lo, hi);
                    chart
                        .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                        .map_err(|e| e.to_string())?
                        .label(format!("{v:.3} mm"))
                        .legend(move |(x, y)| Circle::new((x + 8, y), 4, c.filled()));
                }
                chart
                    .draw_series(std::iter::empty::<Cross<(f64, f64), i32>>())
                    .map_err(|e| e.to_string())?
                    .label("session's meeting points")
                    .legend(|(x, y)| Cross::new((x + 8, y), 4, BLACK.stroke_width(1)));
                legend(&mut chart)?;
            }
        }
        Ok(())
    })
}
