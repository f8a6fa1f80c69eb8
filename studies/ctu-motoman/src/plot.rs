//! The study's two SVG figures (plotters, SVG backend): held-out rms per tracker file for each
//! model, and the held-out error of the right arm against each joint angle, nominal vs `self`.

use std::path::Path;

use anyhow::anyhow;
use plotters::prelude::*;

use crate::contact::PairRow;
use crate::data::Recording;
use crate::study::ScoredPose;

const COLOURS: [RGBColor; 8] = [
    RGBColor(127, 127, 127),
    RGBColor(31, 119, 180),
    RGBColor(23, 190, 207),
    RGBColor(44, 160, 44),
    RGBColor(188, 189, 34),
    RGBColor(214, 39, 40),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
];

/// Held-out rms (mm) per tracker file (x = file, in the order of the table), one marker series
/// per model.
pub fn per_file_svg(path: &Path, series: &[(String, Vec<f64>)]) -> anyhow::Result<()> {
    let n = series.first().map_or(0, |s| s.1.len());
    let ymax = series
        .iter()
        .flat_map(|s| s.1.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
        * 1.15;
    let root = SVGBackend::new(path, (1000, 480)).into_drawing_area();
    let e = |e: &dyn std::fmt::Display| anyhow!("{}: {e}", path.display());
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "CTU Motoman: held-out tracker rms per file (registration + reflector on half, scored on the other half)",
            ("sans-serif", 15),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.5..(n as f64 + 0.5), 0.0..ymax.max(0.1))
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc("tracker file (1 right grid, 2 left grid, 3-4 higher, 5-6 lower, 7-8 wall, 9-12 leica_self)")
        .y_desc("held-out rms, mm")
        .x_labels(n)
        .x_label_formatter(&|x| format!("{:.0}", x))
        .draw()
        .map_err(|x| e(&x))?;
    for (i, (name, v)) in series.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        let dx = (i as f64 - 2.0) * 0.08;
        let pts: Vec<(f64, f64)> = v
            .iter()
            .enumerate()
            .filter(|(_, y)| y.is_finite())
            .map(|(k, &y)| (k as f64 + 1.0 + dx, y))
            .collect();
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 5, c.filled())))
            .map_err(|x| e(&x))?
            .label(name.clone())
            .legend(move |(x, y)| Circle::new((x + 8, y), 5, c.filled()));
    }
    legend_and_present(&mut chart, &root, path)
}

/// Six panels (joints S..T): held-out error (mm) of every right-arm tracker pose against the
/// joint angle (deg), nominal and `self_model` (the exported `self` model's score label).
pub fn residual_vs_joint_svg(
    path: &Path,
    per_pose: &[(String, String, Vec<ScoredPose>)],
    trackers: &[&Recording],
    self_model: &str,
) -> anyhow::Result<()> {
    let right: Vec<&str> = trackers
        .iter()
        .filter(|t| t.right_arm)
        .map(|t| t.name.as_str())
        .collect();
    let pick = |model: &str| -> Vec<&ScoredPose> {
        per_pose
            .iter()
            .filter(|(f, m, _)| m == model && right.contains(&f.as_str()))
            .flat_map(|(_, _, s)| s.iter())
            .collect()
    };
    let sets = [("nominal", pick("nominal")), (self_model, pick(self_model))];
    let ymax = sets
        .iter()
        .flat_map(|(_, s)| s.iter().map(|p| p.error_m * 1e3))
        .fold(0.0, f64::max)
        * 1.1;
    let root = SVGBackend::new(path, (1500, 820)).into_drawing_area();
    let e = |e: &dyn std::fmt::Display| anyhow!("{}: {e}", path.display());
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let root = root
        .titled(
            &format!("CTU Motoman, right arm, every tracker file: held-out error vs joint angle (grey nominal, blue {self_model}: the exported self)"),
            ("sans-serif", 17),
        )
        .map_err(|x| e(&x))?;
    let names = ["S", "L", "U", "R", "B", "T"];
    for (j, area) in root.split_evenly((2, 3)).iter().enumerate() {
        let xs = sets
            .iter()
            .flat_map(|(_, s)| s.iter().map(|p| p.q[j].to_degrees()));
        let (x0, x1) = xs.fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
        let pad = ((x1 - x0) * 0.05).max(1.0);
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .caption(format!("joint {}", names[j]), ("sans-serif", 14))
            .build_cartesian_2d((x0 - pad)..(x1 + pad), 0.0..ymax.max(0.1))
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc(format!("q_{} deg", names[j]))
            .y_desc("held-out error, mm")
            .draw()
            .map_err(|x| e(&x))?;
        for (i, (_, s)) in sets.iter().enumerate() {
            let c = COLOURS[i];
            chart
                .draw_series(
                    s.iter().map(|p| {
                        Circle::new((p.q[j].to_degrees(), p.error_m * 1e3), 2, c.filled())
                    }),
                )
                .map_err(|x| e(&x))?;
        }
    }
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// Along-normal centre distance (mm) per face pair of the self-contacts (x = pair, in the
/// table's order), mean ± sd, one series per model (nominal first).
pub fn contact_pairs_svg(path: &Path, rows: &[PairRow], models: &[&str]) -> anyhow::Result<()> {
    let vals = rows.iter().flat_map(|r| {
        r.along
            .iter()
            .flat_map(|(m, s)| [(m - s) * 1e3, (m + s) * 1e3])
    });
    let (y0, y1) = vals.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    let pad = ((y1 - y0) * 0.08).max(0.1);
    let root = SVGBackend::new(path, (900, 460)).into_drawing_area();
    let e = |e: &dyn std::fmt::Display| anyhow!("{}: {e}", path.display());
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "CTU Motoman self-contacts: centre distance along the contact face normal per face pair (mean ± sd)",
            ("sans-serif", 15),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.5..(rows.len() as f64 + 0.5), (y0 - pad)..(y1 + pad))
        .map_err(|x| e(&x))?;
    let labels: Vec<String> = rows
        .iter()
        .map(|r| format!("({},{})", r.pair.0, r.pair.1))
        .collect();
    chart
        .configure_mesh()
        .x_desc("face pair (right ring face, left ring face)")
        .y_desc("along-normal distance, mm")
        .x_labels(rows.len())
        .x_label_formatter(&|x| {
            let k = x.round() as usize;
            labels.get(k.wrapping_sub(1)).cloned().unwrap_or_default()
        })
        .draw()
        .map_err(|x| e(&x))?;
    for (i, name) in models.iter().enumerate() {
        let c = COLOURS[i % COLOURS.len()];
        let dx = (i as f64 - (models.len() as f64 - 1.0) / 2.0) * 0.1;
        let pts: Vec<(f64, f64, f64)> = rows
            .iter()
            .enumerate()
            .filter_map(|(k, r)| {
                r.along
                    .get(i)
                    .map(|(m, s)| (k as f64 + 1.0 + dx, m * 1e3, s * 1e3))
            })
            .collect();
        chart
            .draw_series(pts.iter().map(|&(x, m, s)| {
                PathElement::new(vec![(x, m - s), (x, m + s)], c.stroke_width(2))
            }))
            .map_err(|x| e(&x))?;
        chart
            .draw_series(
                pts.iter()
                    .map(|&(x, m, _)| Circle::new((x, m), 5, c.filled())),
            )
            .map_err(|x| e(&x))?
            .label(name.to_string())
            .legend(move |(x, y)| Circle::new((x + 8, y), 5, c.filled()));
    }
    legend_and_present(&mut chart, &root, path)
}

/// Draws the series legend (upper right) and writes the SVG file at `path` (named in errors).
fn legend_and_present<'a, X, Y>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, Cartesian2d<X, Y>>,
    root: &DrawingArea<SVGBackend<'a>, plotters::coord::Shift>,
    path: &Path,
) -> anyhow::Result<()>
where
    X: Ranged,
    Y: Ranged,
{
    let e = |e: &dyn std::fmt::Display| anyhow!("{}: {e}", path.display());
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}
