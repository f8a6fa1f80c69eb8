//! `handclasp calibrate --cell CELL --session SESSION --model kinematic|placement [--export DIR]
//! [--json]`: the whole-cell calibration (`calib_core::whole_cell`) of a measured session.
//!
//! `kinematic` fits `b1_from_b2` jointly with every identifiable kinematic parameter of both
//! robots (joint offsets, joint origin xyz/rpy, tip offsets), a maximum a posteriori fit with the
//! prior from the cell's `[robotN.tolerance]`; what the session cannot separate is dropped or
//! merged and reported. `placement` fits `b1_from_b2` alone (both robots nominal) from the same
//! session. Both screen the rows for blunders and refit without them.
//!
//! Predicted cooperative accuracy: the posterior error of the predicted vector from tip 2 to tip
//! 1 (b1), over **the session's meeting pairs `(q1_i, q2_i)`** of its coincident and contact rows
//! (rejected rows included: their joint vectors are still the session's workspace), rms exact,
//! p95 from a seeded draw (seed [`P95_SEED`]).
//!
//! The placement's uncertainty: JSON `b1_from_b2.sigma`, one entry per translation axis (mm) and
//! rotation-vector axis (deg, of the left perturbation `b1_from_b2 ← R(φ)·b1_from_b2`), each with
//! its `sigma` (posterior) and `prior_sigma` (the cell's `[b1_from_b2] sigma_mm`/`sigma_deg`;
//! `null` when that half is fitted freely); the text report prints the same on one line.
//!
//! Output units: mm and degrees (ZYZ, `R = Rz(φ)·Ry(θ)·Rz(ψ)`); parameters in their unit (`deg`,
//! `mm`, `ratio`, `deg/kNm`).

use anyhow::{bail, Context};
use calib_core::whole_cell::{
    calibrate_cell, predict_cooperative_accuracy, CellCalibration, CellParam, CellProblem, Kind,
    ReductionReason, ScreenOptions, SolveOptions,
};
use calib_core::zyz_canonical;
use handclasp_cell::problem::{cell_problem, session_meeting_pairs, FitModel};
use handclasp_cell::Cell;
use handclasp_cell::{export_calibrated_cell, Session, CALIBRATE_EXPORT_NAMES};
use kinematics::ErrorParam;
use serde_json::{json, Value};

use crate::calibrate::Args;

/// Seed of the predicted p95's Monte Carlo draw.
pub const P95_SEED: u64 = 1;

/// How many of the largest kinematic corrections the text report lists.
const TEXT_LARGEST: usize = 10;

/// How many partners of a merged parameter the text report names (largest coefficients first).
const MERGE_PARTNERS_SHOWN: usize = 3;

/// `--model`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelArg {
    /// b1_from_b2 and every identifiable kinematic parameter of both robots (MAP).
    Kinematic,
    /// b1_from_b2 only, both robots nominal.
    Placement,
}

impl ModelArg {
    fn fit_model(self) -> FitModel {
        match self {
            ModelArg::Kinematic => FitModel::Kinematic,
            ModelArg::Placement => FitModel::Placement,
        }
    }

    fn name(self) -> &'static str {
        match self {
            ModelArg::Kinematic => "kinematic",
            ModelArg::Placement => "placement",
        }
    }
}

/// The kinds of the non-zero `[robotN.errors]` terms of each robot of `cell` (catalogue order,
/// e.g. `["joint_offset", "compliance"]`), for robots that have any: the whole-cell fit starts
/// from the URDFs and tips and does not use them.
fn unused_error_terms(cell: &Cell) -> Vec<(calib_core::Robot, Vec<&'static str>)> {
    [calib_core::Robot::One, calib_core::Robot::Two]
        .into_iter()
        .filter_map(|robot| {
            let errors = &cell.robot(robot).errors;
            let mut kinds: Vec<&'static str> = Vec::new();
            for p in kinematics::all_params(errors.dof()) {
                if errors.get(p) != 0.0 && !kinds.contains(&p.kind_name()) {
                    kinds.push(p.kind_name());
                }
            }
            (!kinds.is_empty()).then_some((robot, kinds))
        })
        .collect()
}

/// Runs the whole-cell calibration (`args.cell` is `Some`).
pub fn run(args: Args) -> anyhow::Result<()> {
    let (Some(cell_path), Some(session_path)) = (&args.cell, &args.session) else {
        bail!("--cell CELL needs --session SESSION (the session CSV of that cell)");
    };
    if let Some(dir) = &args.export {
        crate::export_dir::check_export_folder(dir, args.force)?;
    }
    let cell = Cell::from_toml_file(cell_path)?;
    if args.verbose {
        crate::fk::print_cell_branches(&cell);
    }
    for (robot, kinds) in unused_error_terms(&cell) {
        eprintln!(
            "note: {}: [robot{}.errors] holds {} terms, which calibrate --cell does not use: it \
             fits from the URDFs and tips, within [robot{}.tolerance] (a simulated cell's errors \
             are its hidden truth; an exported cell's are an earlier calibration's, which fk --cell \
             applies). --export writes this fit's terms in their place.",
            cell_path.display(),
            robot.number(),
            kinds.join(", "),
            robot.number(),
        );
    }
    let session = Session::read_csv(session_path, &cell)?;
    let problem = cell_problem(&cell, &session, args.model.fit_model());
    let mut solve = SolveOptions::default();
    if session.points.len() < MIN_COINCIDENT_FOR_START {
        // Contact, tracker and plane rows alone give no rigid starting placement: start from
        // the cell's own b1_from_b2.
        solve.initial_b1_from_b2 = Some(cell.b1_from_b2);
    }
    let cal = calibrate_cell(&problem, &solve, &ScreenOptions::default()).with_context(|| {
        format!(
            "calibrating {} with cell {}",
            session_path.display(),
            cell_path.display()
        )
    })?;
    let pairs = session_meeting_pairs(&session);
    let mut out = report(&problem, &cal, args.model, session.len());
    if pairs.is_empty() {
        out["cooperative_accuracy_mm"] = Value::Null;
    } else {
        let prediction = predict_cooperative_accuracy(&problem, &cal.fit, &pairs, P95_SEED)
            .context("predicting the cooperative accuracy over the session's meeting pairs")?;
        out["cooperative_accuracy_mm"] = json!({
            "predicted_rms": prediction.predicted_rms_m * 1e3,
            "predicted_p95": prediction.predicted_p95_m * 1e3,
            "pairs": pairs.len(),
            "pair_set": "meeting pairs (q1_i, q2_i) of the session's coincident and contact rows",
        });
    }
    if !session.is_handclasp_only() {
        let counts = Kind::ALL.iter().zip(session.kind_counts());
        out["rows_by_kind"] = Value::Object(
            counts
                .map(|(kind, n)| (kind.name().to_string(), json!(n)))
                .collect(),
        );
        out["groups"] = groups_json(&problem, &cal);
    }
    let written = match &args.export {
        Some(dir) => export_calibrated_cell(&cell, &cal.fit.estimate, dir, &CALIBRATE_EXPORT_NAMES)
            .with_context(|| format!("--export {}", dir.display()))?,
        None => Vec::new(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print_text(&out);
        for f in &written {
            println!("wrote {}", f.display());
        }
    }
    Ok(())
}

/// Fewer coincident rows than this: the fit starts from the cell's `b1_from_b2` (a rigid start
/// needs 3 points not on a line).
const MIN_COINCIDENT_FOR_START: usize = 3;

/// The fitted nuisance groups of a mixed session (mm, degrees): contact distances, planes
/// (unit normal and offset in the anchor robot's base), tracker frames (`anchor_from_tracker`:
/// the tracker's origin and ZYZ angles in the anchor robot's base).
fn groups_json(problem: &CellProblem, cal: &CellCalibration) -> Value {
    let est = &cal.fit.estimate;
    let contacts: Vec<Value> = problem
        .contacts
        .iter()
        .zip(&est.contact_distance_m)
        .map(|(g, d)| json!({"group": g.name, "distance_mm": d * 1e3, "fitted": g.fit_distance}))
        .collect();
    let planes: Vec<Value> = problem
        .planes
        .iter()
        .zip(&est.planes)
        .map(|(g, p)| {
            let n = p.normal_anchor;
            json!({"group": g.name, "anchor_robot": g.anchor, "normal": [n.x, n.y, n.z], "offset_mm": p.offset_m * 1e3})
        })
        .collect();
    let trackers: Vec<Value> = problem
        .trackers
        .iter()
        .zip(&est.tracker_from_anchor)
        .map(|(g, t)| {
            let a = t.inverse();
            let zyz = zyz_canonical(&a.rotation.to_rotation_matrix());
            let v = a.translation.vector * 1e3;
            json!({
                "group": g.name,
                "anchor_robot": g.anchor,
                "anchor_from_tracker": {"xyz_mm": [v.x, v.y, v.z], "zyz_deg": zyz.map(f64::to_degrees)},
            })
        })
        .collect();
    json!({"contact": contacts, "plane": planes, "tracker": trackers})
}

/// Unit and SI → unit factor of a kinematic parameter.
fn unit_of(p: &CellParam) -> (&'static str, f64) {
    let deg = 1f64.to_degrees();
    match p {
        CellParam::ToolTip { .. } => ("mm", 1e3),
        CellParam::Kinematic { param, .. } => match param {
            ErrorParam::JointOffset { .. } | ErrorParam::OriginRpy { .. } => ("deg", deg),
            ErrorParam::MountRpy { .. } => ("deg", deg),
            ErrorParam::JointScale { .. } => ("ratio", 1.0),
            ErrorParam::Compliance { .. } => ("deg/kNm", deg * 1e3),
            _ => ("mm", 1e3),
        },
        CellParam::PlacementRotation { .. } | CellParam::TrackerRotation { .. } => ("deg", deg),
        CellParam::PlaneNormal { .. } => ("deg", deg),
        _ => ("mm", 1e3),
    }
}

/// Robot, kind, 1-based joint and axis of a kinematic parameter (JSON fields).
fn describe(p: &CellParam) -> Option<Value> {
    match p {
        CellParam::Kinematic { robot, param } => Some(json!({
            "robot": robot,
            "kind": param.kind_name(),
            "joint": param.joint().map(|j| j + 1),
            "axis": param.axis().map(|a| a.to_string()),
        })),
        CellParam::ToolTip { robot, axis, .. } => Some(json!({
            "robot": robot,
            "kind": "tip",
            "joint": Value::Null,
            "axis": axis.to_string(),
        })),
        _ => None,
    }
}

fn reason_text(r: &ReductionReason) -> (&'static str, Value) {
    match r {
        ReductionReason::NoEffect => ("no_effect", Value::Null),
        ReductionReason::PriorDecided => ("prior_decided", Value::Null),
        ReductionReason::ConfoundedWithPlacement => ("confounded_with_placement", Value::Null),
        ReductionReason::ConfoundedWithNuisance => ("confounded_with_nuisance", Value::Null),
        ReductionReason::MergedInto { into } => (
            "merged",
            into.iter()
                .map(|(name, c)| json!({"parameter": name, "coefficient": c}))
                .collect(),
        ),
        _ => ("other", Value::Null),
    }
}

/// The JSON report (mm, degrees).
fn report(problem: &CellProblem, cal: &CellCalibration, model: ModelArg, rows: usize) -> Value {
    let x = &cal.fit.estimate.b1_from_b2;
    let r = x.rotation.to_rotation_matrix();
    let zyz = zyz_canonical(&r);
    let q = x.rotation;
    let params = cal.fit.parameters(problem);
    let mut parameters = Vec::new();
    let mut placement_sigma = Vec::new();
    let mut nuisance = Vec::new();
    for p in &params {
        let (unit, k) = unit_of(&p.param);
        match describe(&p.param) {
            Some(mut v) => {
                v["name"] = json!(p.name);
                v["value"] = json!(p.value * k);
                v["unit"] = json!(unit);
                v["sigma"] = json!(p.posterior_sigma * k);
                v["prior_sigma"] = json!(p.prior_sigma * k);
                parameters.push(v);
            }
            None => {
                let entry = json!({"name": p.name, "unit": unit, "value": p.value * k, "sigma": p.posterior_sigma * k});
                if matches!(
                    p.param,
                    CellParam::PlacementTranslation { .. } | CellParam::PlacementRotation { .. }
                ) {
                    // A prior σ of 0 is no prior: that half of the placement is fitted freely.
                    let prior = (p.prior_sigma > 0.0).then_some(p.prior_sigma * k);
                    placement_sigma.push(json!({
                        "name": p.name,
                        "unit": unit,
                        "sigma": p.posterior_sigma * k,
                        "prior_sigma": prior,
                    }));
                } else {
                    // Tracker frames, planes, contact distances (mixed sessions only).
                    nuisance.push(entry);
                }
            }
        }
    }
    let unidentifiable: Vec<Value> = cal
        .reduction
        .dropped
        .iter()
        .map(|d| {
            let (reason, into) = reason_text(&d.reason);
            let mut v = describe(&d.param).unwrap_or_else(|| json!({}));
            v["name"] = json!(d.name);
            v["reason"] = json!(reason);
            v["merged_into"] = into;
            v["independent_fraction"] = json!(d.independent_fraction);
            v["why"] = json!(d.message);
            v
        })
        .collect();
    let rejected: Vec<Value> = cal
        .rejected
        .iter()
        .map(|b| {
            json!({
                "row": b.row,
                "size_sigma": b.size_sigma,
                "residual_mm": b.residual_m * 1e3,
            })
        })
        .collect();
    let mut out = json!({
        "model": model.name(),
        "rows": rows,
        "rows_used": cal.fit.active.len(),
        "b1_from_b2": {
            "xyz_mm": [x.translation.x * 1e3, x.translation.y * 1e3, x.translation.z * 1e3],
            "zyz_deg": [zyz[0].to_degrees(), zyz[1].to_degrees(), zyz[2].to_degrees()],
            "rotation": (0..3).map(|i| (0..3).map(|j| r[(i, j)]).collect::<Vec<_>>()).collect::<Vec<_>>(),
            "quaternion_wxyz": [q.w, q.i, q.j, q.k],
            "sigma": placement_sigma,
        },
        "parameters": parameters,
        "unidentifiable": unidentifiable,
        "rejected_points": rejected,
        "stopped": cal.fit.stopped.name(),
        "iterations": cal.fit.iterations,
        "data_chi2": cal.fit.data_chi2,
        "residual_rows": cal.fit.residual_rows,
        "data_determined_directions": cal.reduction.data_determined,
        "prior_dominated_directions": cal.reduction.prior_dominated,
        "prior_scale": {
            "chosen": cal.prior_scale.scale,
            "log_evidence": cal.prior_scale.log_evidence.iter()
                .map(|(s, z)| json!({"scale": s, "log_evidence": z}))
                .collect::<Vec<_>>(),
        },
        "noise_scale": cal.noise_scale,
    });
    if !nuisance.is_empty() {
        out["nuisance_parameters"] = json!(nuisance);
    }
    out
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn print_text(v: &Value) {
    println!(
        "== whole-cell calibration, model {} ({} of {} rows used)",
        v["model"].as_str().unwrap_or("?"),
        v["rows_used"],
        v["rows"]
    );
    let b = &v["b1_from_b2"];
    let xyz: Vec<f64> = (0..3).map(|i| num(&b["xyz_mm"][i])).collect();
    let zyz: Vec<f64> = (0..3).map(|i| num(&b["zyz_deg"][i])).collect();
    println!(
        "b1_from_b2:  x {:.3} mm  y {:.3} mm  z {:.3} mm   φ {:.4}°  θ {:.4}°  ψ {:.4}°  (ZYZ, R = Rz(φ)·Ry(θ)·Rz(ψ))",
        xyz[0], xyz[1], xyz[2], zyz[0], zyz[1], zyz[2]
    );
    println!("{}", placement_sigma_line(&b["sigma"]));
    let params = v["parameters"].as_array().cloned().unwrap_or_default();
    if params.is_empty() {
        println!("kinematic parameters: none fitted (both robots nominal)");
    } else {
        let mut ranked: Vec<&Value> = params.iter().collect();
        let size = |p: &Value| (num(&p["value"]) / num(&p["prior_sigma"])).abs();
        ranked.sort_by(|a, b| size(b).total_cmp(&size(a)));
        println!(
            "kinematic parameters: {} fitted; the {} largest corrections (in prior σ):",
            params.len(),
            TEXT_LARGEST.min(params.len())
        );
        for p in ranked.iter().take(TEXT_LARGEST) {
            let unit = p["unit"].as_str().unwrap_or("");
            println!(
                "  {:<40} {:>+10.4} {unit:<4} ± {:.4} {unit:<4} (prior σ {:.4}; {:.1} σ)",
                p["name"].as_str().unwrap_or("?"),
                num(&p["value"]),
                num(&p["sigma"]),
                num(&p["prior_sigma"]),
                size(p)
            );
        }
    }
    let dropped = v["unidentifiable"].as_array().cloned().unwrap_or_default();
    if !dropped.is_empty() {
        println!(
            "not identifiable from this session ({}; held at nominal, their prior kept in the prediction):",
            dropped.len()
        );
        for d in &dropped {
            println!("  {}", dropped_line(d));
        }
    }
    let rejected = v["rejected_points"].as_array().cloned().unwrap_or_default();
    if rejected.is_empty() {
        println!("blunders: none (no row's studentised residual above the Bonferroni limit)");
    } else {
        println!("blunders: rejected and refitted without them; re-record these rows:");
        for r in &rejected {
            println!(
                "  row {:>4}: {:.1} σ (residual {:.3} mm)",
                r["row"].as_u64().unwrap_or(0),
                num(&r["size_sigma"]),
                num(&r["residual_mm"])
            );
        }
    }
    if v["model"].as_str() == Some("placement") {
        println!(
            "note: the placement model takes both robots' nominal kinematics as exact; its blunder screen and \
             predicted accuracy allow for their errors only as extra noise, from the residuals' variance \
             factor (use --model kinematic to fit them)"
        );
    }
    let g = &v["groups"];
    if !g.is_null() {
        let k = &v["rows_by_kind"];
        println!(
            "rows by kind: {} coincident, {} contact, {} tracker, {} plane",
            k["coincident"], k["contact"], k["tracker"], k["plane"]
        );
        for c in g["contact"].as_array().into_iter().flatten() {
            println!(
                "  contact group {}: distance {:.3} mm ({})",
                c["group"],
                num(&c["distance_mm"]),
                if c["fitted"].as_bool() == Some(true) {
                    "fitted"
                } else {
                    "given"
                }
            );
        }
        for p in g["plane"].as_array().into_iter().flatten() {
            println!(
                "  plane group {}: normal ({:.5}, {:.5}, {:.5}), offset {:.3} mm (base of robot {})",
                p["group"],
                num(&p["normal"][0]),
                num(&p["normal"][1]),
                num(&p["normal"][2]),
                num(&p["offset_mm"]),
                p["anchor_robot"]
            );
        }
        for t in g["tracker"].as_array().into_iter().flatten() {
            let f = &t["anchor_from_tracker"];
            println!(
                "  tracker group {}: origin ({:.3}, {:.3}, {:.3}) mm in the base of robot {}",
                t["group"],
                num(&f["xyz_mm"][0]),
                num(&f["xyz_mm"][1]),
                num(&f["xyz_mm"][2]),
                t["anchor_robot"]
            );
        }
    }
    let c = &v["cooperative_accuracy_mm"];
    if c.is_null() {
        println!(
            "predicted cooperative accuracy: none (no coincident or contact row: no meeting pair)"
        );
    } else {
        println!(
            "predicted cooperative accuracy (tip 2 → tip 1 in b1, over the {} meeting pairs (q1_i, q2_i) of this session's coincident and contact rows): rms {:.3} mm, p95 {:.3} mm",
            c["pairs"],
            num(&c["predicted_rms"]),
            num(&c["predicted_p95"])
        );
    }
    if params.is_empty() {
        println!(
            "prior scale: none (no kinematic parameter fitted); blunder-screen noise scale {:.3}",
            num(&v["noise_scale"])
        );
    } else {
        println!(
            "prior scale chosen by the evidence: {} (prior σ = scale × tolerance/√3; 1e-3 = placement-only limit); blunder-screen noise scale {:.3}",
            num(&v["prior_scale"]["chosen"]),
            num(&v["noise_scale"])
        );
    }
    println!(
        "solver: {} after {} iterations (data χ² {:.1} over {} residual rows)",
        v["stopped"].as_str().unwrap_or("?"),
        v["iterations"],
        num(&v["data_chi2"]),
        v["residual_rows"]
    );
}

/// The placement's posterior σ per axis, each with its prior σ (`free` without a prior), from
/// the JSON `b1_from_b2.sigma` entries.
fn placement_sigma_line(sigma: &Value) -> String {
    let parts: Vec<String> = sigma
        .as_array()
        .into_iter()
        .flatten()
        .map(|p| {
            let unit = p["unit"].as_str().unwrap_or("");
            let prior = match p["prior_sigma"].as_f64() {
                Some(s) => format!("prior {s:.4} {unit}"),
                None => "prior: free".to_string(),
            };
            format!(
                "{} ± {:.4} {unit} ({prior})",
                p["name"]
                    .as_str()
                    .unwrap_or("?")
                    .trim_start_matches("b1_from_b2 "),
                num(&p["sigma"]),
            )
        })
        .collect();
    format!("b1_from_b2 posterior σ: {}", parts.join(", "))
}

/// One readable line per dropped parameter: why, and for a merge its largest partners.
fn dropped_line(d: &Value) -> String {
    let name = d["name"].as_str().unwrap_or("?");
    match d["reason"].as_str() {
        Some("merged") => {
            let mut into: Vec<(String, f64)> = d["merged_into"]
                .as_array()
                .map(|a| {
                    a.iter()
                        .map(|m| {
                            (
                                m["parameter"].as_str().unwrap_or("?").to_string(),
                                num(&m["coefficient"]),
                            )
                        })
                        .collect()
                })
                .unwrap_or_default();
            into.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            let shown: Vec<String> = into
                .iter()
                .take(MERGE_PARTNERS_SHOWN)
                .map(|(n, c)| format!("{c:+.3}·{n}"))
                .collect();
            let more = into.len().saturating_sub(MERGE_PARTNERS_SHOWN);
            let more = if more > 0 {
                format!(" and {more} smaller")
            } else {
                String::new()
            };
            format!(
                "{name}: merged into {}{more} (coefficients in prior σ)",
                shown.join(", ")
            )
        }
        Some("confounded_with_placement") => format!("{name}: absorbed by b1_from_b2"),
        Some("no_effect") => format!("{name}: moves no observed tip"),
        Some("prior_decided") => format!("{name}: barely seen by the data, the prior decides it"),
        _ => d["why"].as_str().unwrap_or(name).to_string(),
    }
}
