//! Gravity compliance on a shared trunk: two arms on one chain of trunk joints (a humanoid's
//! torso, a dual-arm robot's waist), each arm a [`RobotModel`] whose first `k` chain joints are
//! the trunk (the same joints, origins and axes in both models, from the same base).
//!
//! A trunk joint `j < k` carries both arms, so its gravity torque is its own chain's
//! ([`crate::gravity_torques`] of either model: the trunk and that arm) plus the other arm's,
//! `τ_j^other = z_j · Σ_{i≥k} m'_i (c'_i − o_j) × g` over the other model's arm links
//! ([`branch_torques`]), which depends on the other arm's posture. In the lumped form
//! ([`crate::lumped`]) the other arm's links are coefficients `c'_{j,i}` (`j < k ≤ i`: the other
//! model's own lumped coefficients of its arm links on the trunk joints) whose deflection
//! `Σ_{i≥k} c'_{j,i}·R'_iᵀ·(g/g₀ × z_j)` is evaluated on the other model's nominal frames at the
//! other arm's posture ([`branch_deflections`], [`branch_regressor`]); the trunk links'
//! coefficients `c_{j,i}` (`i < k`) are one set, shared by both models, and fold the masses of
//! both arms (each arm's mass `M'` hangs at its first joint's origin `d'_k`, so the trunk's
//! reduced first moments `μ̃_i` of [`crate::lumped`] gain `M'·d_{i+1}`, with `d_k = d'_k`:
//! [`shared_trunk_lumped_from_masses`]).
//!
//! A caller evaluating one arm's tip adds the other arm's deflections to the trunk joints'
//! values (they add to the joint angle as a zero offset does, so
//! [`crate::KinematicErrors::joint_offset`] carries them), and the tip's Jacobian column of
//! the other arm's coefficient `c'_{j,i}[axis]` is the joint-offset column of joint `j` times
//! [`branch_regressor`]; of a physical compliance `k_j` it gains the joint-offset column times
//! [`branch_torques`]. The other arm's posture moves the trunk's deflection by a second-order
//! amount (compliance × torque change) that no Jacobian here carries.

use nalgebra::Vector3;

use crate::error::KinematicsError;
use crate::error_model::ErrorParam;
use crate::gravity::{check_gravity, gravity_entries, GravityEntry};
use crate::lumped::{lumped_compliance_from_masses, NominalFrames, LUMPED_G_REF};
use crate::model::RobotModel;

/// Largest difference, m (origins) or unit-vector components (axes), between the two models'
/// trunk joints for them to count as one trunk (far below any manufacturing tolerance; the
/// same URDF loaded twice agrees exactly).
pub const TRUNK_MATCH_TOL: f64 = 1e-9;

/// Checks that the first `trunk_joints` chain joints of `model` and `other` are one trunk: both
/// have at least `trunk_joints + 1` chain joints (an arm beyond the trunk), and the trunk steps
/// have the same kinds, axes and origins (within [`TRUNK_MATCH_TOL`]).
fn check_trunk(
    model: &RobotModel,
    other: &RobotModel,
    trunk_joints: usize,
) -> Result<(), KinematicsError> {
    for m in [model, other] {
        if m.chain_joints().len() <= trunk_joints {
            return Err(KinematicsError::InvalidInput(format!(
                "shared trunk of {trunk_joints} joints: {} has {} chain joints, so no arm beyond \
                 the trunk; give a trunk shorter than each chain",
                m.name(),
                m.chain_joints().len()
            )));
        }
    }
    for j in 0..trunk_joints {
        let (a, b) = (&model.steps[j], &other.steps[j]);
        let same = a.axis_kind == b.axis_kind
            && (a.axis.into_inner() - b.axis.into_inner()).amax() <= TRUNK_MATCH_TOL
            && (a.origin.t - b.origin.t).amax() <= TRUNK_MATCH_TOL
            && (a.origin.r - b.origin.r).amax() <= TRUNK_MATCH_TOL;
        if !same {
            return Err(KinematicsError::InvalidInput(format!(
                "shared trunk: chain joint {} differs between {} ({}) and {} ({}); the first \
                 {trunk_joints} chain joints must be the same joints in both models",
                j + 1,
                model.name(),
                model.chain_joints()[j].name,
                other.name(),
                other.chain_joints()[j].name
            )));
        }
    }
    Ok(())
}

/// Checks the other arm's inputs of the `branch_*` functions: its joints, the gravity, and a
/// trunk shorter than its chain.
fn check_other_arm(
    other: &RobotModel,
    q_other: &[f64],
    g_base: &Vector3<f64>,
    trunk_joints: usize,
) -> Result<(), KinematicsError> {
    other.check_q(q_other)?;
    check_gravity(g_base)?;
    check_trunk(other, other, trunk_joints)
}

/// The gravity torques (N·m) about the first `trunk_joints` chain joints from the other arm of a
/// shared trunk: `τ_j^other = z_j · (S' − M'·o_j) × g_base` with `S' = Σ_{i≥k} m'_i·c'_i` and
/// `M' = Σ_{i≥k} m'_i` over `other`'s chain links after the trunk (its URDF inertials,
/// [`RobotModel::inertials`]) at the other arm's posture `q_other` (independent joints, rad or
/// m), `z_j`, `o_j` the trunk joint's axis and axis point (base frame). A trunk joint's whole
/// torque is this plus [`crate::gravity_torques`] of the arm being evaluated. A prismatic trunk
/// joint gets the other arm's weight along its axis, `M'·z_j·g_base` (N).
///
/// Errors: a bad `q_other` ([`RobotModel::check_q`]), a non-finite `g_base`, or
/// `trunk_joints` not shorter than `other`'s chain.
pub fn branch_torques(
    other: &RobotModel,
    q_other: &[f64],
    g_base: &Vector3<f64>,
    trunk_joints: usize,
) -> Result<Vec<f64>, KinematicsError> {
    check_other_arm(other, q_other, g_base, trunk_joints)?;
    let mut entries = vec![GravityEntry::default(); other.chain_joints().len()];
    gravity_entries(other, q_other, &mut entries);
    let (s, m) = entries[trunk_joints..]
        .iter()
        .fold((Vector3::zeros(), 0.0), |(s, m), e| (s + e.mc, m + e.m));
    Ok(entries[..trunk_joints]
        .iter()
        .map(|e| {
            if e.prismatic {
                m * e.z.dot(g_base)
            } else {
                e.z.dot(&(s - m * e.o).cross(g_base))
            }
        })
        .collect())
}

/// True if `p` is a lumped coefficient of one of `other`'s arm links on a trunk joint (`joint <
/// trunk_joints ≤ link`): the coefficients [`branch_deflections`] reads.
pub fn is_branch_param(p: &ErrorParam, trunk_joints: usize) -> bool {
    matches!(*p, ErrorParam::LumpedCompliance { joint, link, .. }
        if joint < trunk_joints && link >= trunk_joints)
}

/// The deflections (rad) of the first `trunk_joints` chain joints caused by the other arm of a
/// shared trunk, from its lumped coefficients `other_lumped` (as
/// [`crate::KinematicErrors::lumped_compliance`] of `other`; only the entries of its arm links
/// on trunk joints are read, [`is_branch_param`]) at its posture `q_other`:
/// `Δq_j = Σ_{i≥k} c'_{j,i}·R'_iᵀ·(g/g₀ × z_j)` (module docs). Empty coefficients give zeros.
///
/// Errors: a bad `q_other`, a non-finite `g_base`, coefficients of the wrong shape or on a
/// joint that cannot have them ([`crate::lumped_deflections`]), or `trunk_joints` not shorter
/// than `other`'s chain.
pub fn branch_deflections(
    other: &RobotModel,
    other_lumped: &[Vec<Vector3<f64>>],
    q_other: &[f64],
    g_base: &Vector3<f64>,
    trunk_joints: usize,
) -> Result<Vec<f64>, KinematicsError> {
    check_other_arm(other, q_other, g_base, trunk_joints)?;
    crate::lumped::check_lumped(other, other_lumped)?;
    if other_lumped.is_empty() {
        return Ok(vec![0.0; trunk_joints]);
    }
    let frames = NominalFrames::at(other, q_other);
    let g = g_base / LUMPED_G_REF;
    Ok((0..trunk_joints)
        .map(|j| {
            let w = g.cross(&frames.z[j]);
            // other_lumped[j][i − j] is c'_{j,i}.
            (trunk_joints..other.chain_joints().len())
                .map(|i| other_lumped[j][i - j].dot(&(frames.r[i].transpose() * w)))
                .sum()
        })
        .collect())
}

/// `∂Δq_j/∂p` of [`branch_deflections`] for each of `params` (`other`'s error parameters) at
/// the other arm's posture `q_other`: for a branch coefficient `c'_{j,i}[axis]`
/// ([`is_branch_param`]) `(R'_iᵀ·(g/g₀ × z_j))[axis]`, the deflection of trunk joint `j` per rad
/// of it; 0 for every other parameter. Each entry pairs the trunk joint it moves (0 when the
/// factor is 0) with the factor, so the tip's column of `p` is the joint-offset column of that
/// joint times the factor.
///
/// Errors: a bad `q_other`, a non-finite `g_base`, `trunk_joints` not shorter than `other`'s
/// chain, or a parameter that is not `other`'s ([`ErrorParam::check_model`]).
pub fn branch_regressor(
    other: &RobotModel,
    q_other: &[f64],
    g_base: &Vector3<f64>,
    trunk_joints: usize,
    params: &[ErrorParam],
) -> Result<Vec<(usize, f64)>, KinematicsError> {
    check_other_arm(other, q_other, g_base, trunk_joints)?;
    for p in params {
        p.check_model(other)?;
    }
    let mut frames = None;
    Ok(params
        .iter()
        .map(|p| match *p {
            ErrorParam::LumpedCompliance { joint, link, axis }
                if is_branch_param(p, trunk_joints) =>
            {
                let frames = frames.get_or_insert_with(|| NominalFrames::at(other, q_other));
                (joint, frames.factor(g_base, joint, link, axis))
            }
            _ => (0, 0.0),
        })
        .collect())
}

/// The exact lumped coefficients of two arms on one trunk whose masses (URDF inertials) and
/// joint compliances (rad/(N·m), one per chain joint of each model) are known: for each model,
/// its own [`lumped_compliance_from_masses`] with the trunk links' coefficients `c_{j,i}` (`j ≤ i
/// < k`) gaining the other arm's mass folding `k_j·g₀·M'·d_{i+1}` (`d_k` the other model's first
/// arm joint origin in the trunk's last link frame): so the two results agree on the trunk links
/// (one set), and `lumped_deflections(model, own) + branch_deflections(other, other's)` is
/// `k_j·(τ_j + τ_j^other)` at every posture pair that agrees on the trunk (gravity of magnitude
/// g₀; in proportion otherwise). The simulator's truth for gravity compliance on a shared trunk.
///
/// Errors: the trunk not the same in both models, a compliance list not one finite value per
/// chain joint, the two lists differing on a trunk joint (one joint has one compliance), or a
/// compliance on a joint that cannot have lumped coefficients ([`crate::lumped`]).
pub fn shared_trunk_lumped_from_masses(
    models: [&RobotModel; 2],
    compliance: [&[f64]; 2],
    trunk_joints: usize,
) -> Result<[Vec<Vec<Vector3<f64>>>; 2], KinematicsError> {
    check_trunk(models[0], models[1], trunk_joints)?;
    for j in 0..trunk_joints {
        let (a, b) = (compliance[0].get(j), compliance[1].get(j));
        if a != b {
            return Err(KinematicsError::InvalidInput(format!(
                "shared trunk: trunk joint {} has compliance {a:?} in {} but {b:?} in {}; one \
                 joint has one compliance, give the same value in both",
                j + 1,
                models[0].name(),
                models[1].name()
            )));
        }
    }
    let mut out = [
        lumped_compliance_from_masses(models[0], compliance[0])?,
        lumped_compliance_from_masses(models[1], compliance[1])?,
    ];
    for (r, lumped) in out.iter_mut().enumerate() {
        let (own, other) = (models[r], models[1 - r]);
        let m_other: f64 = other.inertials()[trunk_joints..]
            .iter()
            .map(|i| i.mass)
            .sum();
        for (j, row) in lumped.iter_mut().enumerate().take(trunk_joints) {
            let k = compliance[r][j];
            if k == 0.0 {
                continue;
            }
            for i in j..trunk_joints {
                let d_next = if i + 1 < trunk_joints {
                    own.steps[i + 1].origin.t
                } else {
                    other.steps[trunk_joints].origin.t
                };
                row[i - j] += k * LUMPED_G_REF * m_other * d_next;
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gravity_torques;
    use crate::test_fixtures::{random_q, random_vec, G_FLOOR};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// robots/humanoid.urdf: a 4-joint torso (`chest` its last link) and two 7-joint arms.
    const HUMANOID: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../robots/humanoid.urdf"
    ));
    /// The torso's chain joints.
    const TRUNK: usize = 4;

    /// Right arm (chain 1), left arm (chain 2), the torso alone (to `chest`).
    fn humanoid() -> [RobotModel; 3] {
        ["right_tool0", "left_tool0", "chest"]
            .map(|tool| RobotModel::from_urdf_str(HUMANOID, tool).expect("humanoid loads"))
    }

    /// Both arms' postures, agreeing on the torso.
    fn posture_pair(m: &[RobotModel; 3], rng: &mut ChaCha8Rng) -> (Vec<f64>, Vec<f64>) {
        let q1 = random_q(&m[0], rng);
        let mut q2 = random_q(&m[1], rng);
        q2[..TRUNK].copy_from_slice(&q1[..TRUNK]);
        (q1, q2)
    }

    /// Torques and deflections agree to 1e-9 relative (sums of ~20 terms of ~10² N·m).
    const REL_TOL: f64 = 1e-9;

    /// The other arm's torque is the whole tree's minus this chain's: τ_total = τ_1 + τ_2 −
    /// τ_torso (the torso counted once), from three independent gravity sums; and the lumped
    /// coefficients of the two arms from the masses deflect each trunk joint by exactly
    /// `k_j·τ_total` (own chain + the other arm's branch term), agree on the trunk links, and
    /// deflect each arm joint by `k_j·τ_j` of its own chain.
    #[test]
    fn shared_trunk_load_carries_both_arms() {
        let m = humanoid();
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        let n = m[0].chain_joints().len();
        let k1: Vec<f64> = (0..n).map(|_| rng.random_range(5e-5..2e-4)).collect();
        let mut k2: Vec<f64> = (0..n).map(|_| rng.random_range(5e-5..2e-4)).collect();
        k2[..TRUNK].copy_from_slice(&k1[..TRUNK]);
        let lumped = shared_trunk_lumped_from_masses([&m[0], &m[1]], [&k1, &k2], TRUNK).unwrap();
        for j in 0..TRUNK {
            for i in j..TRUNK {
                let (a, b) = (lumped[0][j][i - j], lumped[1][j][i - j]);
                assert!(
                    (a - b).norm() <= 1e-15,
                    "trunk joint {j} link {i}: {a} vs {b}"
                );
            }
        }
        for _ in 0..20 {
            let (q1, q2) = posture_pair(&m, &mut rng);
            let v = random_vec(&mut rng, 1.0);
            let g = LUMPED_G_REF * v / v.norm();
            let tau1 = gravity_torques(&m[0], &q1, &g).unwrap();
            let tau2 = gravity_torques(&m[1], &q2, &g).unwrap();
            let tau_torso = gravity_torques(&m[2], &q1[..TRUNK], &g).unwrap();
            let other_of_1 = branch_torques(&m[1], &q2, &g, TRUNK).unwrap();
            let other_of_2 = branch_torques(&m[0], &q1, &g, TRUNK).unwrap();
            for j in 0..TRUNK {
                let total = tau1[j] + tau2[j] - tau_torso[j];
                let scale = total.abs().max(1.0);
                assert!(
                    (tau1[j] + other_of_1[j] - total).abs() <= REL_TOL * scale,
                    "{j}"
                );
                assert!(
                    (tau2[j] + other_of_2[j] - total).abs() <= REL_TOL * scale,
                    "{j}"
                );
            }
            for (r, (q, q_other, k, tau)) in [(&q1, &q2, &k1, &tau1), (&q2, &q1, &k2, &tau2)]
                .into_iter()
                .enumerate()
            {
                let own = crate::lumped_deflections(&m[r], &lumped[r], q, &g).unwrap();
                let branch =
                    branch_deflections(&m[1 - r], &lumped[1 - r], q_other, &g, TRUNK).unwrap();
                for j in 0..n {
                    let expected = if j < TRUNK {
                        k[j] * (tau1[j] + tau2[j] - tau_torso[j])
                    } else {
                        k[j] * tau[j]
                    };
                    let got = own[j] + branch.get(j).copied().unwrap_or(0.0);
                    assert!(
                        (got - expected).abs() <= REL_TOL * expected.abs().max(1e-6),
                        "arm {} joint {}: {got:e} vs {expected:e}",
                        r + 1,
                        j + 1
                    );
                }
            }
        }
    }

    /// Central differences (the step and tolerance of `lumped.rs`'s Jacobian test): robot 1's
    /// tip with the other arm's branch deflections added to its trunk joints' offsets, against
    /// the joint-offset column × [`branch_regressor`] for every branch coefficient of robot 2,
    /// and × [`branch_torques`] for each trunk joint's physical compliance (the part of its
    /// column the other arm adds).
    #[test]
    fn branch_columns_match_central_differences() {
        const H: f64 = 1e-6;
        const FD_TOL_M: f64 = 1e-14;
        const FD_TOL_REL: f64 = 1e-7;
        let m = humanoid();
        let n = m[0].chain_joints().len();
        let tip = Vector3::new(0.0, 0.0, 0.05);
        for seed in 0..4u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(300 + seed);
            let (q1, q2) = posture_pair(&m, &mut rng);
            let mut e1 = crate::test_fixtures::random_errors(&m[0], &mut rng);
            e1.compliance = (0..n).map(|_| rng.random_range(0.0..2e-4)).collect();
            let mut c2 = crate::lumped::lumped_zero(n);
            for row in c2.iter_mut() {
                for c in row.iter_mut() {
                    *c = random_vec(&mut rng, 0.02);
                }
            }
            let tip_of = |c2: &[Vec<Vector3<f64>>], compliance: &[f64]| {
                let mut e = e1.clone();
                e.compliance = compliance.to_vec();
                let branch = branch_deflections(&m[1], c2, &q2, &G_FLOOR, TRUNK).unwrap();
                let tau = branch_torques(&m[1], &q2, &G_FLOOR, TRUNK).unwrap();
                for j in 0..TRUNK {
                    e.joint_offset[j] += branch[j] + compliance[j] * tau[j];
                }
                crate::true_base_from_tip(&m[0], &e, &q1, &tip, &G_FLOOR)
                    .unwrap()
                    .translation
                    .vector
            };
            // The joint-offset columns at the loaded errors.
            let mut loaded = e1.clone();
            let branch = branch_deflections(&m[1], &c2, &q2, &G_FLOOR, TRUNK).unwrap();
            let tau_other = branch_torques(&m[1], &q2, &G_FLOOR, TRUNK).unwrap();
            for j in 0..TRUNK {
                loaded.joint_offset[j] += branch[j] + e1.compliance[j] * tau_other[j];
            }
            let offsets: Vec<ErrorParam> = (0..TRUNK)
                .map(|joint| ErrorParam::JointOffset { joint })
                .collect();
            let jac =
                crate::tip_error_jacobian(&m[0], &loaded, &q1, &tip, &G_FLOOR, &offsets).unwrap();
            let params: Vec<ErrorParam> = crate::lumped_params(&m[1])
                .into_iter()
                .filter(|p| is_branch_param(p, TRUNK))
                .collect();
            assert_eq!(params.len(), TRUNK * (n - TRUNK) * 2);
            let reg = branch_regressor(&m[1], &q2, &G_FLOOR, TRUNK, &params).unwrap();
            let check = |an: Vector3<f64>, fd: Vector3<f64>, what: String| {
                let diff = (fd - an * H).norm();
                assert!(
                    diff <= FD_TOL_M + FD_TOL_REL * (an * H).norm().max(1e-9),
                    "seed {seed} {what}: |Δ|·h = {diff:e} m"
                );
            };
            for (p, &(joint, factor)) in params.iter().zip(&reg) {
                let ErrorParam::LumpedCompliance {
                    joint: pj,
                    link,
                    axis,
                } = *p
                else {
                    unreachable!("branch params are lumped")
                };
                assert_eq!(joint, pj);
                let (mut cp, mut cm) = (c2.clone(), c2.clone());
                cp[pj][link - pj][axis.index()] += H;
                cm[pj][link - pj][axis.index()] -= H;
                let fd = (tip_of(&cp, &e1.compliance) - tip_of(&cm, &e1.compliance)) / 2.0;
                check(jac.column(joint) * factor, fd, format!("{p}"));
            }
            for j in 0..TRUNK {
                let (mut kp, mut km) = (e1.compliance.clone(), e1.compliance.clone());
                kp[j] += H;
                km[j] -= H;
                let fd = (tip_of(&c2, &kp) - tip_of(&c2, &km)) / 2.0;
                // The own chain's part of the compliance column, plus the other arm's.
                let own = crate::tip_error_jacobian(
                    &m[0],
                    &loaded,
                    &q1,
                    &tip,
                    &G_FLOOR,
                    &[ErrorParam::Compliance { joint: j }],
                )
                .unwrap();
                let an = own.column(0) + jac.column(j) * tau_other[j];
                check(an, fd, format!("compliance of trunk joint {}", j + 1));
            }
        }
    }

    /// Trunks that differ, a trunk as long as a chain, and trunk compliances that differ
    /// between the two lists are refused by name.
    #[test]
    fn mismatched_trunks_are_refused() {
        let m = humanoid();
        let n = m[0].chain_joints().len();
        let k = vec![1e-4; n];
        let va = crate::test_fixtures::model(crate::test_fixtures::VA1400);
        let kv = vec![1e-4; va.chain_joints().len()];
        let err = shared_trunk_lumped_from_masses([&m[0], &va], [&k, &kv], 2)
            .unwrap_err()
            .to_string();
        assert!(err.contains("chain joint 1 differs"), "{err}");
        let err = branch_torques(&m[2], &[0.0; TRUNK], &G_FLOOR, TRUNK)
            .unwrap_err()
            .to_string();
        assert!(err.contains("no arm beyond the trunk"), "{err}");
        let mut k2 = k.clone();
        k2[1] *= 2.0;
        let err = shared_trunk_lumped_from_masses([&m[0], &m[1]], [&k, &k2], TRUNK)
            .unwrap_err()
            .to_string();
        assert!(err.contains("trunk joint 2 has compliance"), "{err}");
    }
}
