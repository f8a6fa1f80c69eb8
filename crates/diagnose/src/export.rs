//! Export of the extended model: corrected URDFs (joint origins and offsets patched into the
//! URDF text, everything else kept byte for byte), a cell TOML with the calibrated
//! `b1_from_b2`, and the effects as JSON.
//!
//! The URDF patcher works on the text (it finds the joint's element and its `<origin>` by
//! string search); a parser-based replacement in `kinematics` is planned.

use std::path::{Path, PathBuf};

use calib_core::Robot;
use kinematics::KinematicErrors;
use nalgebra::{Isometry3, Vector3};
use sim_cell::Cell;

use crate::catalogue::effects_to_errors;
use crate::report::DiagnoseReport;
use crate::DiagnoseError;

/// Finds joint `name`'s element in URDF text: `(start of "<joint", index of "</joint>")`.
fn joint_span(xml: &str, name: &str) -> Result<(usize, usize), String> {
    let mut from = 0;
    while let Some(i) = xml[from..].find("<joint") {
        let open = from + i;
        let end_tag = xml[open..]
            .find('>')
            .map(|e| open + e)
            .ok_or_else(|| format!("unterminated <joint> near byte {open}"))?;
        let tag = &xml[open..end_tag];
        if tag.contains(&format!("name=\"{name}\"")) || tag.contains(&format!("name='{name}'")) {
            let close = xml[open..]
                .find("</joint>")
                .map(|c| open + c)
                .ok_or_else(|| format!("joint `{name}` has no </joint>"))?;
            return Ok((open, close));
        }
        from = end_tag;
    }
    Err(format!("joint `{name}` not found in the URDF text"))
}

/// Byte range of an `<origin>` attribute's value (if present) and byte index of the `<origin`
/// tag (if present).
type OriginAttr = (Option<(usize, usize)>, Option<usize>);

/// Reads (and returns the byte range of) attribute `attr` of the `<origin>` element of the
/// joint at `span`; `None` when the joint has no `<origin>` or the origin lacks the attribute.
fn origin_attr(xml: &str, span: (usize, usize), attr: &str) -> Result<OriginAttr, String> {
    let block = &xml[span.0..span.1];
    let Some(o) = block.find("<origin") else {
        return Ok((None, None));
    };
    let o_abs = span.0 + o;
    let o_end = xml[o_abs..]
        .find('>')
        .map(|e| o_abs + e)
        .ok_or("unterminated <origin>")?;
    let pat = format!("{attr}=\"");
    match xml[o_abs..o_end].find(&pat) {
        Some(a) => {
            let start = o_abs + a + pat.len();
            let end = start + xml[start..].find('"').ok_or("unterminated attribute")?;
            Ok((Some((start, end)), Some(o_abs)))
        }
        None => Ok((None, Some(o_abs))),
    }
}

fn parse3(text: &str, what: &str) -> Result<Vector3<f64>, String> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| format!("{what}: bad number `{t}`"))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != 3 {
        return Err(format!("{what}: needs 3 numbers, found {}", v.len()));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

/// Sets the `<origin>` attribute `attr` (`xyz` or `rpy`) of the joint at `span` to `v`
/// (inserting the attribute, or an `<origin>` element, when missing).
fn set_origin_attr(
    xml: &mut String,
    span: (usize, usize),
    attr: &str,
    v: &Vector3<f64>,
) -> Result<(), String> {
    let text = format!("{:.9} {:.9} {:.9}", v.x, v.y, v.z);
    match origin_attr(xml, span, attr)? {
        (Some((s, e)), _) => xml.replace_range(s..e, &text),
        (None, Some(o)) => xml.insert_str(o + "<origin".len(), &format!(" {attr}=\"{text}\"")),
        (None, None) => {
            let at = span.0 + xml[span.0..].find('>').ok_or("unterminated <joint>")? + 1;
            xml.insert_str(at, &format!("\n    <origin {attr}=\"{text}\"/>"));
        }
    }
    Ok(())
}

/// Applies the identified errors of one robot to its URDF text, keeping everything else byte for
/// byte: a `link_length` error is added to the joint's `<origin xyz>`; a `joint_offset` δ is
/// folded into the joint's `<origin rpy>` (`R(rpy') = R(rpy)·Rot(axis, δ)`, exact for any URDF
/// consumer) and recorded as `<calibration rising="δ"/>` (rad; informational, as in ROS, where
/// calibration does not move the kinematics). `errors` are in SI units.
pub fn correct_urdf_text(
    xml: &str,
    model: &kinematics::RobotModel,
    errors: &KinematicErrors,
) -> Result<String, String> {
    let mut out = xml.to_string();
    for (k, joint) in model.joints().iter().enumerate() {
        let dxyz = errors
            .origin_xyz
            .get(k)
            .copied()
            .unwrap_or_else(Vector3::zeros);
        let offset = errors.joint_offset.get(k).copied().unwrap_or(0.0);
        if dxyz == Vector3::zeros() && offset == 0.0 {
            continue;
        }
        let name = &joint.name;
        if dxyz != Vector3::zeros() {
            let span = joint_span(&out, name)?;
            let xyz = match origin_attr(&out, span, "xyz")?.0 {
                Some((s, e)) => parse3(&out[s..e], &format!("joint `{name}` origin xyz"))?,
                None => Vector3::zeros(),
            };
            set_origin_attr(&mut out, span, "xyz", &(xyz + dxyz))?;
        }
        if offset != 0.0 {
            let span = joint_span(&out, name)?;
            let rpy = match origin_attr(&out, span, "rpy")?.0 {
                Some((s, e)) => parse3(&out[s..e], &format!("joint `{name}` origin rpy"))?,
                None => Vector3::zeros(),
            };
            let r = kinematics::rotation_from_rpy(&rpy)
                * nalgebra::Rotation3::from_axis_angle(&joint.axis, offset);
            let (roll, pitch, yaw) = r.euler_angles();
            set_origin_attr(&mut out, span, "rpy", &Vector3::new(roll, pitch, yaw))?;
            let span = joint_span(&out, name)?;
            out.insert_str(
                span.1,
                &format!(
                    "  <!-- handclasp diagnose: joint offset {offset:.9} rad folded into origin rpy -->\n    <calibration rising=\"{offset:.9}\"/>\n  "
                ),
            );
        }
    }
    Ok(out)
}

/// Writes the extended model to `dir`: `robot1_corrected.urdf`, `robot2_corrected.urdf` (joint
/// origins and offsets, see [`correct_urdf_text`]), `cell_corrected.toml` (the calibrated
/// `b1_from_b2`, corrected tip offsets, URDF paths to the corrected files, and the joint-scale and
/// compliance errors, which URDF cannot express, as `[robotN.errors]`) and `effects.json`.
/// Returns the files written.
pub fn export_corrected(
    cell: &Cell,
    report: &DiagnoseReport,
    b1_from_b2: &Isometry3<f64>,
    dir: &Path,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir).map_err(|source| DiagnoseError::ExportFolder {
        path: dir.to_path_buf(),
        source,
    })?;
    let (e1, e2) = effects_to_errors(cell, &report.effects);
    let mut written = Vec::new();
    let mut out = cell.clone();
    out.base_dir = dir.to_path_buf();
    out.b1_from_b2 = *b1_from_b2;
    for (robot, errors) in [(Robot::One, &e1), (Robot::Two, &e2)] {
        let setup = cell.robot(robot);
        let xml = std::fs::read_to_string(&setup.urdf_path)
            .map_err(|e| DiagnoseError::io(&setup.urdf_path, e))?;
        let corrected = correct_urdf_text(&xml, &setup.model, errors).map_err(|message| {
            DiagnoseError::Export {
                path: setup.urdf_path.clone(),
                message,
            }
        })?;
        let file = format!("robot{}_corrected.urdf", robot.number());
        let path = dir.join(&file);
        std::fs::write(&path, &corrected).map_err(|e| DiagnoseError::io(&path, e))?;
        let model =
            kinematics::RobotModel::from_urdf_str(&corrected, &setup.tool_link).map_err(|e| {
                DiagnoseError::Export {
                    path: path.clone(),
                    message: format!("the corrected URDF does not load: {e}"),
                }
            })?;
        written.push(path.clone());
        let r = match robot {
            Robot::One => &mut out.robot1,
            Robot::Two => &mut out.robot2,
        };
        r.model = model;
        r.urdf = file;
        r.urdf_path = path;
        r.flange_from_tip = setup.flange_from_tip + errors.tip;
        let mut rest = KinematicErrors::zero(setup.model.dof());
        rest.joint_scale = errors.joint_scale.clone();
        rest.compliance = errors.compliance.clone();
        r.errors = rest;
    }
    // Robot 2's gravity follows the calibrated placement.
    out.robot2.g_base = out.b1_from_b2.rotation.inverse() * out.robot1.g_base;
    let cell_path = dir.join("cell_corrected.toml");
    let text = format!(
        "# Written by `handclasp diagnose --export`: the extended model (corrected URDFs, tip offsets,\n# calibrated b1_from_b2; joint scale and compliance as [robotN.errors]).\n{}",
        out.to_toml_string()
    );
    std::fs::write(&cell_path, text).map_err(|e| DiagnoseError::io(&cell_path, e))?;
    written.push(cell_path);
    let eff_path = dir.join("effects.json");
    let eff =
        serde_json::to_string_pretty(&report.effects).map_err(|source| DiagnoseError::Json {
            path: eff_path.clone(),
            source,
        })?;
    std::fs::write(&eff_path, eff).map_err(|e| DiagnoseError::io(&eff_path, e))?;
    written.push(eff_path);
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::{Axis, ErrorParam};
    use rand::Rng;

    /// The corrected URDF (offsets folded into origin rpy, lengths added to origin xyz) gives the
    /// same tips as the nominal URDF with the error model, at random postures.
    #[test]
    fn corrected_urdf_matches_the_error_model() {
        let cell = Cell::default_floor_floor();
        for robot in [&cell.robot1, &cell.robot2] {
            let dof = robot.model.dof();
            let mut e = KinematicErrors::zero(dof);
            for k in 0..dof {
                e.set(
                    ErrorParam::JointOffset { joint: k },
                    1e-3 * (k as f64 + 1.0),
                );
                e.set(
                    ErrorParam::OriginXyz {
                        joint: k,
                        axis: Axis::X,
                    },
                    -2e-4 * k as f64,
                );
                e.set(
                    ErrorParam::OriginXyz {
                        joint: k,
                        axis: Axis::Z,
                    },
                    3e-4,
                );
            }
            let xml = std::fs::read_to_string(&robot.urdf_path).expect("URDF");
            let fixed = correct_urdf_text(&xml, &robot.model, &e).expect("corrected");
            assert!(fixed.contains("<calibration rising="));
            let corrected =
                kinematics::RobotModel::from_urdf_str(&fixed, &robot.tool_link).expect("loads");
            let mut rng = sim_cell::trial_rng(3, 0);
            for _ in 0..20 {
                let q: Vec<f64> = robot
                    .model
                    .joints()
                    .iter()
                    .map(|j| rng.random_range(j.lower.max(-2.0)..j.upper.min(2.0)))
                    .collect();
                let want = kinematics::true_base_from_tip(
                    &robot.model,
                    &e,
                    &q,
                    &robot.flange_from_tip,
                    &robot.g_base,
                )
                .expect("fk");
                let got =
                    kinematics::base_from_tip(&corrected, &q, &robot.flange_from_tip).expect("fk");
                // The text carries 9 decimals (1 nm, 1 nrad): agreement to 1e-8 m.
                let d = (want.translation.vector - got.translation.vector).norm();
                assert!(d < 1e-8, "{}: {d} m", robot.model.name());
            }
        }
    }
}
