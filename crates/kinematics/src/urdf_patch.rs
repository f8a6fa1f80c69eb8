//! Writing a corrected URDF: the kinematic errors that a URDF can express (joint origin xyz and
//! rpy errors, joint zero offsets) applied to the URDF text, everything else kept byte for byte.
//!
//! The kinematic `<joint>` elements (direct children of `<robot>`, found by their `name`
//! attribute; never a `<joint>` inside `<transmission>` or a comment) and their `<origin>` are
//! located with an XML parser (roxmltree: byte ranges of elements and attribute values), and only
//! the changed numbers are spliced into the text, so formatting, comments, quoting and unknown tags
//! survive:
//! - `origin_xyz` error `Δxyz`: `<origin xyz>` becomes `xyz + Δxyz` (m, parent link frame);
//! - `origin_rpy` error `Δrpy`: `<origin rpy>` becomes `rpy + Δrpy` (rad);
//! - joint offset `δ` of a rotary joint: folded into the origin rotation,
//!   `R(rpy') = R(rpy + Δrpy)·Rot(axis, δ)`, exact for any URDF consumer, and recorded as
//!   `<calibration rising="δ"/>` (rad; informational, as in ROS, where calibration does not move
//!   the kinematics) after a comment;
//! - joint offset `δ` (m) of a prismatic joint: folded into the origin translation,
//!   `xyz' = xyz + Δxyz + R(rpy + Δrpy)·axis·δ` (the joint at `q + δ` is the joint at `q` with its
//!   origin moved `δ` along the axis), recorded the same way (`rising` in m).
//!
//! The errors are per chain joint, coupled joints included: a coupled joint's offset is folded
//! into its own origin like any joint's (its `<mimic>`, if any, is left as it is).
//!
//! An `<origin>` (or its `xyz`/`rpy` attribute) that is missing is inserted. Numbers are written
//! with 9 decimals (1 nm, 1 nrad) when a bound on what that rounding moves the flange, at any
//! joint vector, is at most half of [`PATCH_TOLERANCE_M`]: `Σ_k |δxyz_k| + (|δroll_k| +
//! |δpitch_k| + |δyaw_k|)·max(L_k, 1 m)`, with `δ` the rounding of joint k's numbers and `L_k`
//! the sum of the (fixed and actuated) origin lengths from joint k to the flange; otherwise with
//! all the digits of the `f64`. Every result is re-loaded and checked against the error model
//! ([`verify_patched_urdf`]) before it is returned.
//!
//! Joint scale, compliance, periodic, tip and mount errors have no URDF element: they are refused
//! ([`UrdfPatchError::NotExpressible`]); [`split_for_urdf`] separates them.

use nalgebra::{Rotation3, Vector3};

use crate::error::UrdfPatchError;
use crate::error_model::KinematicErrors;
use crate::fk::base_from_flange_unchecked;
use crate::ik::halton_seed;
use crate::model::{rotation_from_rpy, RobotModel};
use crate::true_fk::true_base_from_flange_unchecked;

/// The largest flange deviation, m, that [`verify_patched_urdf`] accepts between the patched URDF
/// and the error model, over its configurations (rotation deviations count as their angle, rad,
/// times 1 m).
pub const PATCH_TOLERANCE_M: f64 = 1e-9;

/// Number of joint configurations [`verify_patched_urdf`] compares.
pub const VERIFY_CONFIGURATIONS: usize = 64;

/// Splits `errors` into the part a URDF can express (joint offsets, origin xyz and rpy errors) and
/// the rest (joint scale, compliance, periodic terms, tip, mount), each a full [`KinematicErrors`] of the same
/// shape, so that `urdf + rest` is `errors`.
pub fn split_for_urdf(errors: &KinematicErrors) -> (KinematicErrors, KinematicErrors) {
    let n = errors.dof();
    let mut urdf = KinematicErrors::zero(n);
    urdf.joint_offset.clone_from(&errors.joint_offset);
    urdf.origin_xyz.clone_from(&errors.origin_xyz);
    urdf.origin_rpy.clone_from(&errors.origin_rpy);
    let mut rest = errors.clone();
    rest.joint_offset = vec![0.0; n];
    rest.origin_xyz = vec![Vector3::zeros(); n];
    rest.origin_rpy = vec![Vector3::zeros(); n];
    (urdf, rest)
}

/// Applies the URDF-expressible `errors` (SI units, see the module documentation) to the URDF
/// text `xml` from which `model` was loaded, keeping every other byte; returns the corrected text,
/// verified with [`verify_patched_urdf`].
///
/// Errors: `errors` of the wrong shape or non-finite; a non-zero joint scale, compliance, periodic term, tip or
/// mount error (these belong beside the URDF, see [`split_for_urdf`]); text that is not
/// well-formed XML or whose root is not `<robot>`; a model joint with no (or more than one)
/// `<joint>` of that name under `<robot>`; an `<origin>` whose `xyz`/`rpy` is not 3 finite
/// numbers; a patched text that does not load or does not reproduce the error model.
///
/// # Examples
/// ```
/// use kinematics::{patch_urdf_text, KinematicErrors, RobotModel};
/// let urdf = r#"<robot name="arm">
///   <link name="base"/><link name="tool0"/>
///   <joint name="j1" type="revolute"><parent link="base"/><child link="tool0"/>
///     <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
/// </robot>"#;
/// let model = RobotModel::from_urdf_str(urdf, "tool0").unwrap();
/// let mut errors = KinematicErrors::zero(1);
/// errors.origin_xyz[0].z = 0.001; // the joint sits 1 mm higher
/// let corrected = patch_urdf_text(urdf, &model, &errors).unwrap();
/// assert!(corrected.contains(r#"<origin xyz="0.000000000 0.000000000 0.501000000"/>"#));
/// ```
pub fn patch_urdf_text(
    xml: &str,
    model: &RobotModel,
    errors: &KinematicErrors,
) -> Result<String, UrdfPatchError> {
    check_expressible(model, errors)?;
    let (short, rounding_bound_m) = patch_with(xml, model, errors, Digits::Nine)?;
    // 9 decimals when their rounding provably keeps the flange within half the tolerance at
    // every joint vector; otherwise every digit.
    let text = if rounding_bound_m <= 0.5 * PATCH_TOLERANCE_M {
        short
    } else {
        patch_with(xml, model, errors, Digits::RoundTrip)?.0
    };
    verify_patched_urdf(&text, model, errors)?;
    Ok(text)
}

/// Loads `patched_xml` with the model's tool link and compares its flange pose with
/// [`true_base_from_flange`](crate::true_base_from_flange) of (`model`, `errors`) at
/// [`VERIFY_CONFIGURATIONS`] deterministic joint vectors spread over the joint limits (the IK's
/// Halton seeds 1, 2, …: 90 % of each range around its middle, at most 2π wide; ±π for continuous
/// joints). Returns the largest deviation,
/// m (translation, or rotation angle × 1 m).
///
/// Errors: `errors` of the wrong shape, non-finite or not URDF-expressible; the text does not
/// load ([`UrdfPatchError::Reload`]); a different joint count or names; a deviation above
/// [`PATCH_TOLERANCE_M`] ([`UrdfPatchError::Verification`], with the joint vector).
pub fn verify_patched_urdf(
    patched_xml: &str,
    model: &RobotModel,
    errors: &KinematicErrors,
) -> Result<f64, UrdfPatchError> {
    check_expressible(model, errors)?;
    // The couplings declared beside the URDF hold for the patched text too.
    let patched = RobotModel::from_urdf_str(patched_xml, model.tool_link())
        .and_then(|m| m.with_couplings(model.added_couplings()))
        .map_err(|e| UrdfPatchError::Reload(Box::new(e)))?;
    let names = |m: &RobotModel| {
        m.chain_joints()
            .iter()
            .map(|j| j.name.clone())
            .collect::<Vec<_>>()
    };
    if names(&patched) != names(model) {
        return Err(UrdfPatchError::Verification {
            message: format!(
                "the patched URDF's chain to `{}` has joints [{}], the model [{}]",
                model.tool_link(),
                names(&patched).join(", "),
                names(model).join(", ")
            ),
        });
    }
    let g_unused = Vector3::zeros(); // no compliance: gravity does not enter
    let mut q = vec![0.0; model.dof()];
    let mut worst = 0.0f64;
    for s in 0..VERIFY_CONFIGURATIONS {
        halton_seed(model, s + 1, &mut q);
        let want = true_base_from_flange_unchecked(model, errors, &q, &g_unused);
        let got = base_from_flange_unchecked(&patched, &q);
        let dev = (want.translation.vector - got.translation.vector)
            .norm()
            .max(want.rotation.angle_to(&got.rotation));
        worst = worst.max(dev);
        if dev > PATCH_TOLERANCE_M || dev.is_nan() {
            return Err(UrdfPatchError::Verification {
                message: format!(
                    "at q = {:?} rad the patched URDF's flange is {dev:.3e} m (or rad × 1 m) from \
                     the error model's, above the tolerance {PATCH_TOLERANCE_M:e} m",
                    q
                ),
            });
        }
    }
    Ok(worst)
}

/// Refuses errors of the wrong shape and those a URDF cannot express, naming where they go.
fn check_expressible(model: &RobotModel, errors: &KinematicErrors) -> Result<(), UrdfPatchError> {
    errors.check(model).map_err(UrdfPatchError::Errors)?;
    let joints = |v: &[f64]| -> Vec<String> {
        v.iter()
            .enumerate()
            .filter(|(_, x)| **x != 0.0)
            .map(|(j, _)| format!("{} ({})", j + 1, model.chain_joints()[j].name))
            .collect()
    };
    let mut found = Vec::new();
    let scale = joints(&errors.joint_scale);
    if !scale.is_empty() {
        found.push(format!(
            "joint_scale of joint {}: a URDF has no gear-ratio element; keep it as a kinematic \
             error beside the URDF",
            scale.join(", ")
        ));
    }
    let compliance = joints(&errors.compliance);
    if !compliance.is_empty() {
        found.push(format!(
            "compliance of joint {}: a URDF has no joint stiffness; keep it as a kinematic error \
             beside the URDF",
            compliance.join(", ")
        ));
    }
    let periodic: Vec<String> = joints(&errors.periodic_sin)
        .into_iter()
        .chain(joints(&errors.periodic_cos))
        .collect();
    if !periodic.is_empty() {
        found.push(format!(
            "periodic_sin/periodic_cos of joint {}: a URDF has no angle-dependent joint error; \
             keep them as kinematic errors beside the URDF",
            periodic.join(", ")
        ));
    }
    if errors.tip != Vector3::zeros() {
        found.push(
            "tip: the tip is not part of the URDF; add it to the tip offset flange_from_tip".into(),
        );
    }
    if errors.mount_xyz != Vector3::zeros() || errors.mount_rpy != Vector3::zeros() {
        found.push(
            "mount_xyz/mount_rpy: they move the whole robot; put them into the robot's placement \
             (its base pose in the cell), not into its URDF"
                .into(),
        );
    }
    if found.is_empty() {
        Ok(())
    } else {
        Err(UrdfPatchError::NotExpressible {
            robot: model.name().to_string(),
            what: found.join("; "),
        })
    }
}

/// How numbers are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Digits {
    /// `{:.9}`: 9 decimals (the format of the writer this one replaced).
    Nine,
    /// Shortest text that reads back as the same `f64`.
    RoundTrip,
}

fn format3(v: &Vector3<f64>, digits: Digits) -> String {
    match digits {
        Digits::Nine => format!("{:.9} {:.9} {:.9}", v.x, v.y, v.z),
        Digits::RoundTrip => format!("{} {} {}", v.x, v.y, v.z),
    }
}

fn format1(x: f64, digits: Digits) -> String {
    match digits {
        Digits::Nine => format!("{x:.9}"),
        Digits::RoundTrip => format!("{x}"),
    }
}

/// One text edit: replace `range` of the original text by `text`.
struct Edit {
    range: std::ops::Range<usize>,
    text: String,
}

/// The patch without verification.
fn patch_with(
    xml: &str,
    model: &RobotModel,
    errors: &KinematicErrors,
    digits: Digits,
) -> Result<(String, f64), UrdfPatchError> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..roxmltree::ParsingOptions::default()
    };
    let doc = roxmltree::Document::parse_with_options(xml, options)
        .map_err(|e| UrdfPatchError::Xml(e.to_string()))?;
    let robot = doc.root_element();
    if !robot.has_tag_name("robot") {
        return Err(UrdfPatchError::Xml(format!(
            "the root element is <{}>, not <robot>",
            robot.tag_name().name()
        )));
    }
    let line = |pos: usize| doc.text_pos_at(pos).row;
    let mut edits: Vec<Edit> = Vec::new();
    // reach[k]: the origin lengths from joint k's frame to the flange, m, plus the largest travel
    // of every prismatic joint after k (a bound on the lever of a rotation error at joint k).
    let chain = model.chain_joints();
    let n = chain.len();
    let mut reach = vec![model.last_from_flange().translation.vector.norm(); n];
    for k in (0..n.saturating_sub(1)).rev() {
        let next = &chain[k + 1];
        let travel = if next.kind.is_prismatic() {
            next.lower.abs().max(next.upper.abs())
        } else {
            0.0
        };
        reach[k] = reach[k + 1]
            + next.fixed_prefix.translation.vector.norm()
            + (next.origin_xyz + errors.origin_xyz[k + 1]).norm()
            + travel;
    }
    let mut rounding_bound_m = 0.0;
    // What writing `v` as `text` changes, summed over the components.
    let rounded_by =
        |v: &Vector3<f64>, text: &str| parse3(text).map_or(f64::INFINITY, |w| (w - v).abs().sum());
    for (k, joint) in chain.iter().enumerate() {
        let dxyz = errors.origin_xyz[k];
        let drpy = errors.origin_rpy[k];
        let offset = errors.joint_offset[k];
        if dxyz == Vector3::zeros() && drpy == Vector3::zeros() && offset == 0.0 {
            continue;
        }
        let name = &joint.name;
        let mut found = robot
            .children()
            .filter(|n| n.has_tag_name("joint") && n.attribute("name") == Some(name.as_str()));
        let element = found.next().ok_or_else(|| UrdfPatchError::JointNotFound {
            joint: name.clone(),
        })?;
        if let Some(second) = found.next() {
            return Err(UrdfPatchError::DuplicateJoint {
                joint: name.clone(),
                lines: (line(element.range().start), line(second.range().start)),
            });
        }
        let mut origins = element.children().filter(|n| n.has_tag_name("origin"));
        let origin = origins.next();
        if let Some(second) = origins.next() {
            return Err(UrdfPatchError::BadOrigin {
                joint: name.clone(),
                line: line(second.range().start),
                message: "a joint has one <origin>; remove the extra one".into(),
            });
        }
        let attr = |a: &str| origin.and_then(|o| o.attributes().find(|x| x.name() == a));
        let read = |a: &str| -> Result<Vector3<f64>, UrdfPatchError> {
            match attr(a) {
                None => Ok(Vector3::zeros()),
                Some(at) => parse3(at.value()).ok_or_else(|| UrdfPatchError::BadOrigin {
                    joint: name.clone(),
                    line: line(at.range().start),
                    message: format!(
                        "<origin {a}=\"{}\"> is not 3 finite numbers; write e.g. {a}=\"0 0 0.5\"",
                        at.value()
                    ),
                }),
            }
        };
        let xyz = read("xyz")?;
        let rpy = read("rpy")?;
        let prismatic = joint.kind.is_prismatic();
        // New attribute values, in the order written when the element is created.
        let mut new_attrs: Vec<(&str, String)> = Vec::new();
        if dxyz != Vector3::zeros() || (prismatic && offset != 0.0) {
            let mut xyz_new = xyz + dxyz;
            if prismatic {
                xyz_new += rotation_from_rpy(&(rpy + drpy)) * joint.axis.into_inner() * offset;
            }
            let text = format3(&xyz_new, digits);
            rounding_bound_m += rounded_by(&xyz_new, &text);
            new_attrs.push(("xyz", text));
        }
        if drpy != Vector3::zeros() || (!prismatic && offset != 0.0) {
            let mut rpy_new = rpy + drpy;
            if offset != 0.0 && !prismatic {
                let r =
                    rotation_from_rpy(&rpy_new) * Rotation3::from_axis_angle(&joint.axis, offset);
                let (roll, pitch, yaw) = r.euler_angles();
                rpy_new = Vector3::new(roll, pitch, yaw);
            }
            let text = format3(&rpy_new, digits);
            rounding_bound_m += rounded_by(&rpy_new, &text) * reach[k].max(1.0);
            new_attrs.push(("rpy", text));
        }
        match origin {
            Some(o) => {
                for (a, text) in &new_attrs {
                    match attr(a) {
                        Some(at) => edits.push(Edit {
                            range: at.range_value(),
                            text: text.clone(),
                        }),
                        None => {
                            let at = o.range().start + 1 + o.tag_name().name().len();
                            edits.push(Edit {
                                range: at..at,
                                text: format!(" {a}=\"{text}\""),
                            });
                        }
                    }
                }
            }
            None => {
                let at = start_tag_end(xml, &element).ok_or_else(|| {
                    UrdfPatchError::Xml(format!(
                        "joint `{name}` (line {}) has no end of its start tag",
                        line(element.range().start)
                    ))
                })?;
                let indent = child_indent(xml, &element, at);
                let attrs: String = new_attrs
                    .iter()
                    .map(|(a, t)| format!(" {a}=\"{t}\""))
                    .collect();
                edits.push(Edit {
                    range: at..at,
                    text: format!("{indent}<origin{attrs}/>"),
                });
            }
        }
        if offset != 0.0 {
            let end = element.range().end;
            let close = xml[element.range()]
                .rfind("</")
                .map(|i| element.range().start + i)
                .filter(|_| !xml[..end].ends_with("/>"))
                .ok_or_else(|| UrdfPatchError::Xml(format!(
                    "joint `{name}` (line {}) is an empty element; a joint needs <parent> and <child>",
                    line(element.range().start)
                )))?;
            let rising = format1(offset, digits);
            let comment = if prismatic {
                format!(
                    "  <!-- handclasp diagnose: joint offset {rising} m folded into origin xyz -->\n"
                )
            } else {
                format!(
                    "  <!-- handclasp diagnose: joint offset {rising} rad folded into origin rpy -->\n"
                )
            };
            let calibration = element.children().find(|n| n.has_tag_name("calibration"));
            match calibration {
                None => edits.push(Edit {
                    range: close..close,
                    text: format!("{comment}    <calibration rising=\"{rising}\"/>\n  "),
                }),
                Some(c) => {
                    match c.attributes().find(|x| x.name() == "rising") {
                        // A joint calibrated before: the rising reference accumulates.
                        Some(r) => {
                            let old = r.value().trim().parse::<f64>().map_err(|_| {
                                UrdfPatchError::BadOrigin {
                                    joint: name.clone(),
                                    line: line(r.range().start),
                                    message: format!(
                                        "<calibration rising=\"{}\"> is not a number",
                                        r.value()
                                    ),
                                }
                            })?;
                            edits.push(Edit {
                                range: r.range_value(),
                                text: format1(old + offset, digits),
                            });
                        }
                        None => {
                            let at = c.range().start + 1 + c.tag_name().name().len();
                            edits.push(Edit {
                                range: at..at,
                                text: format!(" rising=\"{rising}\""),
                            });
                        }
                    }
                    edits.push(Edit {
                        range: close..close,
                        text: format!("{comment}  "),
                    });
                }
            }
        }
    }
    // Apply from the end so earlier ranges stay valid; edits never overlap (distinct attributes
    // and insertion points of distinct elements).
    edits.sort_by_key(|e| std::cmp::Reverse((e.range.start, e.range.end)));
    let mut out = xml.to_string();
    for e in edits {
        out.replace_range(e.range, &e.text);
    }
    Ok((out, rounding_bound_m))
}

/// 3 finite numbers separated by whitespace.
fn parse3(text: &str) -> Option<Vector3<f64>> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect::<Option<_>>()?;
    (v.len() == 3).then(|| Vector3::new(v[0], v[1], v[2]))
}

/// Byte index just after the `>` that ends `element`'s start tag.
fn start_tag_end(xml: &str, element: &roxmltree::Node<'_, '_>) -> Option<usize> {
    let after_attrs = element
        .attributes()
        .map(|a| a.range().end)
        .max()
        .unwrap_or(element.range().start + 1 + element.tag_name().name().len());
    xml[after_attrs..element.range().end]
        .find('>')
        .map(|i| after_attrs + i + 1)
}

/// The whitespace (newline and indentation) before `element`'s first child element, if the text
/// between the start tag end `at` and that child is only whitespace; else a newline and 4 spaces.
fn child_indent(xml: &str, element: &roxmltree::Node<'_, '_>, at: usize) -> String {
    element
        .children()
        .find(|n| n.is_element())
        .map(|c| &xml[at..c.range().start])
        .filter(|s| s.contains('\n') && s.chars().all(char::is_whitespace))
        .unwrap_or("\n    ")
        .to_string()
}
