//! The cell file's `[robotN.errors] lumped_compliance_deg`: the lumped gravity compliance
//! (`kinematics::KinematicErrors::lumped_compliance`, joint compliance × mass moment) in degrees,
//! one list per chain joint holding one `[x, y, z]` per link the joint carries (link frame), an
//! empty list for a joint without coefficients.

use kinematics::nalgebra::Vector3;
use kinematics::RobotModel;

use crate::FormatError;

/// Parses `[{key}.errors] lumped_compliance_deg` (deg) into rad, checked against `model`
/// (shape, finite values, joints that can have coefficients); `err` makes an error naming the
/// cell file from a message.
pub(crate) fn parse_lumped(
    err: impl Fn(String) -> FormatError,
    key: &str,
    model: &RobotModel,
    v: &[Vec<[f64; 3]>],
) -> Result<Vec<Vec<Vector3<f64>>>, FormatError> {
    let field = format!("{key}.errors.lumped_compliance_deg");
    let n = model.chain_joints().len();
    if v.len() != n {
        return Err(err(format!(
            "`{field}` has {} lists but {} has {n} joints: give one list per joint (joint j's \
             holds one [x, y, z] per link it carries, n − j + 1 of them; [] for none)",
            v.len(),
            model.name()
        )));
    }
    let d2r = 1f64.to_radians();
    let mut out = Vec::with_capacity(n);
    for (j, row) in v.iter().enumerate() {
        if row.is_empty() {
            out.push(vec![Vector3::zeros(); n - j]);
            continue;
        }
        if row.len() != n - j {
            return Err(err(format!(
                "`{field}` list {} (joint {}) has {} entries, but the joint carries {} links \
                 ({} to {n}): give one [x, y, z] per link, or [] for none",
                j + 1,
                model.chain_joints()[j].name,
                row.len(),
                n - j,
                j + 1
            )));
        }
        let mut r = Vec::with_capacity(row.len());
        for (k, c) in row.iter().enumerate() {
            if c.iter().any(|x| !x.is_finite()) {
                return Err(err(format!(
                    "`{field}` joint {} link {} is {c:?}: give finite numbers (deg)",
                    j + 1,
                    j + k + 1
                )));
            }
            r.push(Vector3::from(*c) * d2r);
        }
        out.push(r);
    }
    let mut probe = kinematics::KinematicErrors::zero_for(model);
    probe.lumped_compliance = out;
    probe
        .check(model)
        .map_err(|e| err(format!("`{field}`: {e}")))?;
    Ok(probe.lumped_compliance)
}

/// The `lumped_compliance_deg` value of `lumped` (rad), `None` when it is empty or all zero;
/// a joint whose coefficients are all zero is written `[]`.
pub(crate) fn write_lumped(lumped: &[Vec<Vector3<f64>>]) -> Option<Vec<Vec<[f64; 3]>>> {
    let zero = |row: &Vec<Vector3<f64>>| row.iter().all(|c| c.iter().all(|&x| x == 0.0));
    if lumped.iter().all(zero) {
        return None;
    }
    let r2d = 1f64.to_degrees();
    Some(
        lumped
            .iter()
            .map(|row| {
                if zero(row) {
                    Vec::new()
                } else {
                    row.iter()
                        .map(|c| [c.x * r2d, c.y * r2d, c.z * r2d])
                        .collect()
                }
            })
            .collect(),
    )
}
