//! Lumped gravity compliance: joint compliance × mass moment, identifiable without any mass.
//!
//! The gravity torque about rotary chain joint `j` (axis `z_j` through `o_j`, base frame, at the
//! reported posture `q`) is `τ_j = z_j · Σ_{i≥j} m_i (c_i − o_j) × g = (g × z_j) · W_j`, with
//! `W_j = Σ_{i≥j} m_i (c_i − o_j)` the first moment of everything joint `j` carries (the links, the
//! tool and the payload). With link `i`'s frame `(R_i, t_i)`, its first moment `μ_i = m_i·r_i`
//! (`r_i` its centre of mass in its own frame) and, while the chain after `j` is rotary,
//! `t_{i+1} = t_i + R_i·d_{i+1}` (`d_{i+1}` joint `i+1`'s origin in link `i`'s frame), each mass
//! folds into the first moment of the link before it, so `W_j = Σ_{i≥j} R_i·μ̃_i` with the
//! reduced moments `μ̃_i = μ_i + M_{i+1}·d_{i+1}` (`M_{i+1}` the mass beyond link `i`). The
//! deflection `Δq_j = k_j·τ_j` of a joint of compliance `k_j` is then **linear** in the lumped
//! coefficients `c_{j,i} = k_j·g₀·μ̃_i` (rad, a vector in link `i`'s frame, `g₀` =
//! [`LUMPED_G_REF`]):
//!
//! `Δq_j = Σ_{i≥j} c_{j,i} · R_iᵀ·(g/g₀ × z_j)`,
//!
//! whose regressor is pure geometry (the nominal chain at the reported posture): neither the
//! masses nor the compliances are needed, only their products, which a calibration identifies.
//! In the elastostatic-calibration literature joint compliances and the gravity loads of the
//! links enter the observation equations as products, and the identifiable set is found by
//! physical and algebraic model reduction: A. Klimchik, S. Caro, B. Furet, A. Pashkevich,
//! "Complete stiffness model for a serial robot", ICINCO 2014 (the complete and irreducible
//! stiffness model for identification); A. Klimchik, Y. Wu, C. Dumas, S. Caro, B. Furet, A.
//! Pashkevich, "Identification of geometrical and elastostatic parameters of heavy industrial
//! robots", ICRA 2013, arXiv:1311.6810. The reduction below (masses folded into reduced first
//! moments, as in the base-parameter reduction of a gravity model, then the axial components
//! folded) is derived here for joint compliance under gravity.
//!
//! **Minimal set** ([`lumped_params`]). The component of `c_{j,i}` along joint `i`'s own axis
//! `a_i` does not turn with joint `i` (`R_i·a_i` is fixed in link `i − 1`'s frame): it folds into
//! `c_{j,i−1}`, and for `i = j` it has no effect (`(g × z_j)·z_j = 0`). So each (joint, link)
//! pair keeps the two components along the link-frame axes other than the one closest to `a_i`
//! (for the usual `a_i = ±z`: x and y), `n(n+1)` coefficients for `n` rotary joints; what
//! the data still cannot tell apart (a joint axis along gravity, a wrist's tiny lever arms) is
//! left to the fit's base-parameter reduction. [`lumped_canonical`] maps any coefficients to
//! this set without changing a deflection; [`lumped_compliance_from_masses`] gives the exact
//! coefficients of a robot whose masses and compliances are known (the simulator's truth).
//!
//! Scope: a rotary joint `j` whose carried chain is rotary (a prismatic joint after `j` would
//! add mass terms linear in its travel); prismatic joints before it (a track, a torso lift) are
//! fine. A prismatic joint's own compliance stays [`crate::KinematicErrors::compliance`].

use nalgebra::{Matrix3, Vector3};

use crate::axis::Axis;
use crate::error::KinematicsError;
use crate::error_model::ErrorParam;
use crate::fk::apply_step;
use crate::model::RobotModel;

/// The gravity magnitude folded into the lumped coefficients, m/s² (the cell's `9.81`): a
/// coefficient is `compliance × 9.81 × reduced first moment`, rad, and a robot under a gravity
/// of another magnitude deflects in proportion.
pub const LUMPED_G_REF: f64 = 9.81;

/// All-zero lumped coefficients for a chain of `n` joints (`n − j` entries for joint `j`).
pub(crate) fn lumped_zero(n: usize) -> Vec<Vec<Vector3<f64>>> {
    (0..n).map(|j| vec![Vector3::zeros(); n - j]).collect()
}

/// True if chain joint `j` may have lumped coefficients: it is rotary and every chain joint
/// after it is rotary.
pub fn lumped_allowed(model: &RobotModel, j: usize) -> bool {
    let chain = model.chain_joints();
    j < chain.len() && chain[j..].iter().all(|joint| !joint.kind.is_prismatic())
}

/// The two link-frame axes that carry link `i`'s coefficients: the coordinate axes other than
/// the one closest to joint `i`'s axis, in cyclic order (axis z: x, y; axis x: y, z; axis y: z, x).
pub fn lumped_axes(model: &RobotModel, i: usize) -> [Axis; 2] {
    let a = model.steps[i].axis.into_inner();
    let k = dominant(&a);
    [Axis::ALL[(k + 1) % 3], Axis::ALL[(k + 2) % 3]]
}

/// Index of the largest |component|.
fn dominant(a: &Vector3<f64>) -> usize {
    let mut k = 0;
    for c in 1..3 {
        if a[c].abs() > a[k].abs() {
            k = c;
        }
    }
    k
}

/// The minimal lumped-compliance parameters of `model` ([`ErrorParam::LumpedCompliance`]): for
/// each rotary chain joint `j` whose carried chain is rotary ([`lumped_allowed`]) and each link
/// `i ≥ j`, the two components of [`lumped_axes`]; joint-major, then link, then axis.
pub fn lumped_params(model: &RobotModel) -> Vec<ErrorParam> {
    let n = model.chain_joints().len();
    let mut out = Vec::new();
    for joint in (0..n).filter(|&j| lumped_allowed(model, j)) {
        for link in joint..n {
            out.extend(
                lumped_axes(model, link).map(|axis| ErrorParam::LumpedCompliance {
                    joint,
                    link,
                    axis,
                }),
            );
        }
    }
    out
}

/// Checks one lumped parameter against `model`: the joint may have lumped coefficients.
pub(crate) fn check_lumped_param(
    model: &RobotModel,
    joint: usize,
    link: usize,
    axis: Axis,
) -> Result<(), KinematicsError> {
    if !lumped_allowed(model, joint) {
        return Err(not_allowed(model, joint));
    }
    if !lumped_axes(model, link).contains(&axis) {
        return Err(KinematicsError::InvalidInput(format!(
            "lumped compliance joint {} link {} {axis}: the {axis} component lies along joint \
             {}'s axis and folds into the link before it; use the {} and {} components",
            joint + 1,
            link + 1,
            link + 1,
            lumped_axes(model, link)[0],
            lumped_axes(model, link)[1]
        )));
    }
    Ok(())
}

/// The error for lumped coefficients on a joint that cannot have them.
fn not_allowed(model: &RobotModel, joint: usize) -> KinematicsError {
    let j = &model.chain_joints()[joint];
    KinematicsError::InvalidInput(format!(
        "lumped compliance of joint {} ({}): {}; give it no lumped coefficients (a prismatic \
         joint's compliance is `compliance`, m/N)",
        joint + 1,
        j.name,
        if j.kind.is_prismatic() {
            "the joint is prismatic, and lumped coefficients are for rotary joints"
        } else {
            "a prismatic joint follows it, whose travel the lumped model does not carry"
        }
    ))
}

/// Checks the shape and values of [`crate::KinematicErrors::lumped_compliance`] against
/// `model`: empty, or one entry per chain joint with `n − j` finite vectors, non-zero only
/// where [`lumped_allowed`].
pub(crate) fn check_lumped(
    model: &RobotModel,
    lumped: &[Vec<Vector3<f64>>],
) -> Result<(), KinematicsError> {
    if lumped.is_empty() {
        return Ok(());
    }
    let n = model.chain_joints().len();
    if lumped.len() != n {
        return Err(KinematicsError::InvalidInput(format!(
            "kinematic errors: `lumped_compliance` has {} joints but {} has {n} chain joints; \
             give one list per joint (or none)",
            lumped.len(),
            model.name()
        )));
    }
    for (j, row) in lumped.iter().enumerate() {
        if row.len() != n - j {
            return Err(KinematicsError::InvalidInput(format!(
                "kinematic errors: `lumped_compliance` of joint {} has {} links but the joint \
                 carries {} (links {} to {n}); give one vector per carried link",
                j + 1,
                row.len(),
                n - j,
                j + 1
            )));
        }
        if let Some(x) = row.iter().flatten().find(|x| !x.is_finite()) {
            return Err(KinematicsError::InvalidInput(format!(
                "kinematic errors: `lumped_compliance` of joint {} holds {x}, not a finite \
                 number; give finite values",
                j + 1
            )));
        }
        let nonzero = row.iter().flatten().any(|&x| x != 0.0);
        if nonzero && !lumped_allowed(model, j) {
            return Err(not_allowed(model, j));
        }
    }
    Ok(())
}

/// The nominal chain at a reported posture: each chain link's rotation `R_i` (base from link)
/// and each chain joint's axis `z_i` (base frame).
#[derive(Debug, Clone)]
pub(crate) struct NominalFrames {
    /// `base_from_link_i` rotation per chain joint.
    pub(crate) r: Vec<Matrix3<f64>>,
    /// Joint axis per chain joint, unit, base frame.
    pub(crate) z: Vec<Vector3<f64>>,
}

impl NominalFrames {
    /// The nominal frames of `model` at the independent joint values `q_rep`. No checks.
    pub(crate) fn at(model: &RobotModel, q_rep: &[f64]) -> NominalFrames {
        let mut buf = Vec::new();
        let q = model.chain_q(q_rep, &mut buf);
        let n = q.len();
        let mut out = NominalFrames {
            r: Vec::with_capacity(n),
            z: Vec::with_capacity(n),
        };
        let mut r = Matrix3::identity();
        let mut t = Vector3::zeros();
        for (step, &qi) in model.steps.iter().zip(q) {
            apply_step::<true>(&mut r, &mut t, step, qi);
            out.r.push(r);
            out.z.push(r * step.axis.into_inner());
        }
        out
    }

    /// The regressor of one coefficient: `(R_linkᵀ·(g/g₀ × z_joint))[axis]`, the deflection of
    /// `joint` (rad) per rad of `c_{joint,link}[axis]`.
    pub(crate) fn factor(
        &self,
        g_base: &Vector3<f64>,
        joint: usize,
        link: usize,
        axis: Axis,
    ) -> f64 {
        let w = (g_base / LUMPED_G_REF).cross(&self.z[joint]);
        (self.r[link].transpose() * w)[axis.index()]
    }

    /// The deflections `Δq_j`, rad, one per chain joint.
    pub(crate) fn deflections(
        &self,
        lumped: &[Vec<Vector3<f64>>],
        g_base: &Vector3<f64>,
    ) -> Vec<f64> {
        let g = g_base / LUMPED_G_REF;
        lumped
            .iter()
            .enumerate()
            .map(|(j, row)| {
                let w = g.cross(&self.z[j]);
                row.iter()
                    .enumerate()
                    .map(|(k, c)| c.dot(&(self.r[j + k].transpose() * w)))
                    .sum()
            })
            .collect()
    }

    /// `∂Δq/∂q_chain`, chain × chain: with `v_i = R_i·c_{j,i}`, `V_m = Σ_{i≥m} v_i` (joint `j`'s
    /// coefficients) and `ĝ = g/g₀`, `Δq_j = ĝ·(z_j × V_j)`; a rotary chain joint `k` turns
    /// `z_j` (if `k < j`) by `z_k × z_j` and every `v_i` with `i ≥ k` by `z_k × v_i`, so
    /// `∂Δq_j/∂q_k = [k < j]·ĝ·((z_k × z_j) × V_j) + ĝ·(z_j × (z_k × V_max(j,k)))`; a
    /// prismatic `k` (only before `j`) turns nothing: 0.
    pub(crate) fn deflection_jacobian(
        &self,
        model: &RobotModel,
        lumped: &[Vec<Vector3<f64>>],
        g_base: &Vector3<f64>,
    ) -> nalgebra::DMatrix<f64> {
        let g = g_base / LUMPED_G_REF;
        let n = self.z.len();
        let mut d = nalgebra::DMatrix::zeros(n, n);
        for (j, row) in lumped.iter().enumerate() {
            // tail[m − j] = V_m for m ≥ j.
            let mut tail = vec![Vector3::zeros(); row.len() + 1];
            for k in (0..row.len()).rev() {
                tail[k] = tail[k + 1] + self.r[j + k] * row[k];
            }
            let zj = self.z[j];
            for k in 0..n {
                if model.chain_joints()[k].kind.is_prismatic() {
                    continue;
                }
                let zk = self.z[k];
                let v = tail[k.saturating_sub(j)];
                let mut val = g.dot(&zj.cross(&zk.cross(&v)));
                if k < j {
                    val += g.dot(&zk.cross(&zj).cross(&tail[0]));
                }
                d[(j, k)] = val;
            }
        }
        d
    }
}

/// The [`ErrorParam::LumpedCompliance`] columns of [`crate::tip_error_jacobian`] (the others are
/// left as they are): joint `j`'s column of the true chain at the tip `p` times the regressor
/// [`NominalFrames::factor`] at the reported posture `q_rep`. No checks.
pub(crate) fn fill_lumped_columns(
    model: &RobotModel,
    q_rep: &[f64],
    g_base: &Vector3<f64>,
    frames: &[crate::true_fk::TrueJointFrame],
    p: &Vector3<f64>,
    params: &[ErrorParam],
    jac: &mut nalgebra::Matrix3xX<f64>,
) {
    let mut nominal = None;
    for (c, param) in params.iter().enumerate() {
        if let ErrorParam::LumpedCompliance { joint, link, axis } = *param {
            let nominal = nominal.get_or_insert_with(|| NominalFrames::at(model, q_rep));
            let col = frames[joint].joint_column(p) * nominal.factor(g_base, joint, link, axis);
            jac.set_column(c, &col);
        }
    }
}

/// Adds the lumped deflections of `lumped` (non-empty) at the reported independent values
/// `q_rep` to the chain's true values `q_true`. No checks.
pub(crate) fn add_lumped_deflections(
    model: &RobotModel,
    lumped: &[Vec<Vector3<f64>>],
    q_rep: &[f64],
    g_base: &Vector3<f64>,
    q_true: &mut [f64],
) {
    let frames = NominalFrames::at(model, q_rep);
    for (q, d) in q_true.iter_mut().zip(frames.deflections(lumped, g_base)) {
        *q += d;
    }
}

/// The lumped deflections `Δq_j = Σ_{i≥j} c_{j,i}·R_iᵀ·(g/g₀ × z_j)`, rad, one per chain joint,
/// of the coefficients `lumped` (as [`crate::KinematicErrors::lumped_compliance`]; empty gives
/// zeros) at the reported independent joint values `q_rep`, gravity `g_base` in the nominal base
/// frame (m/s²).
///
/// Errors: a bad `q_rep` ([`RobotModel::check_q`]), a non-finite `g_base`, coefficients of the
/// wrong shape, non-finite, or on a joint that cannot have them.
pub fn lumped_deflections(
    model: &RobotModel,
    lumped: &[Vec<Vector3<f64>>],
    q_rep: &[f64],
    g_base: &Vector3<f64>,
) -> Result<Vec<f64>, KinematicsError> {
    model.check_q(q_rep)?;
    crate::gravity::check_gravity(g_base)?;
    check_lumped(model, lumped)?;
    if lumped.is_empty() {
        return Ok(vec![0.0; model.chain_joints().len()]);
    }
    Ok(NominalFrames::at(model, q_rep).deflections(lumped, g_base))
}

/// The exact lumped coefficients of a robot whose masses (the URDF inertials,
/// [`RobotModel::inertials`], plus whatever the caller added to them) and joint compliances
/// `compliance` (rad/(N·m), one per chain joint) are known: `c_{j,i} = k_j·g₀·μ̃_i` with the
/// reduced first moments `μ̃_i = m_i·r_i + M_{i+1}·d_{i+1}` (module documentation). Joints that
/// cannot have lumped coefficients ([`lumped_allowed`]) get zeros. Their deflections equal
/// `compliance_j·τ_j` ([`crate::gravity_torques`]) at every posture and gravity of magnitude
/// `g₀`, in proportion otherwise.
///
/// Errors: `compliance` not one finite value per chain joint, or non-zero on a joint that
/// cannot have lumped coefficients.
pub fn lumped_compliance_from_masses(
    model: &RobotModel,
    compliance: &[f64],
) -> Result<Vec<Vec<Vector3<f64>>>, KinematicsError> {
    let n = model.chain_joints().len();
    if compliance.len() != n || compliance.iter().any(|k| !k.is_finite()) {
        return Err(KinematicsError::InvalidInput(format!(
            "lumped compliance from masses: give {n} finite compliances (one per chain joint of \
             {}), not {compliance:?}",
            model.name()
        )));
    }
    let inertials = model.inertials();
    // Reduced first moments, kg·m, link frames: μ̃_i = μ_i + M_{i+1}·d_{i+1}.
    let mut reduced = vec![Vector3::zeros(); n];
    let mut beyond = 0.0;
    for i in (0..n).rev() {
        let d_next = if i + 1 < n {
            model.steps[i + 1].origin.t
        } else {
            Vector3::zeros()
        };
        reduced[i] = inertials[i].mass * inertials[i].com + beyond * d_next;
        beyond += inertials[i].mass;
    }
    let mut out = lumped_zero(n);
    for (j, row) in out.iter_mut().enumerate() {
        if compliance[j] == 0.0 {
            continue;
        }
        if !lumped_allowed(model, j) {
            return Err(not_allowed(model, j));
        }
        for (k, c) in row.iter_mut().enumerate() {
            *c = compliance[j] * LUMPED_G_REF * reduced[j + k];
        }
    }
    Ok(out)
}

/// The coefficients `lumped` in the minimal set of [`lumped_params`], deflections unchanged:
/// from the last link back to joint `j`, the part `α·a_i` of `c_{j,i}` along joint `i`'s axis
/// (`α` such that the [`lumped_axes`]-excluded component vanishes) moves into `c_{j,i−1}` as
/// `α·R_o,i·a_i` (`R_o,i` joint `i`'s origin rotation in link `i − 1`'s frame), and at `i = j`
/// is dropped (it has no effect). Empty stays empty.
pub fn lumped_canonical(
    model: &RobotModel,
    lumped: &[Vec<Vector3<f64>>],
) -> Vec<Vec<Vector3<f64>>> {
    let mut out = lumped.to_vec();
    for (j, row) in out.iter_mut().enumerate() {
        for k in (0..row.len()).rev() {
            let i = j + k;
            let step = &model.steps[i];
            let a = step.axis.into_inner();
            let e = dominant(&a);
            let alpha = row[k][e] / a[e];
            let mut rest = row[k] - alpha * a;
            rest[e] = 0.0;
            row[k] = rest;
            if k > 0 {
                row[k - 1] += alpha * (step.origin.r * a);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gravity_torques;
    use crate::test_fixtures::{model, random_q, HP20, VA1400};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Deflections agree to 1e-12 rad (a few ulps of ~1e-2 rad sums of ~10 terms).
    const DEFLECTION_TOL: f64 = 1e-12;

    /// The coefficients from the masses deflect every joint by exactly `k_j·τ_j` at random
    /// postures and gravity directions of magnitude g₀, and their canonical form (the minimal
    /// set) deflects it by the same amount with the excluded components zero.
    #[test]
    fn from_masses_equals_the_physical_compliance_and_canonical_keeps_it() {
        for (xml, seed) in [(VA1400, 1u64), (HP20, 2)] {
            let m = model(xml);
            let n = m.chain_joints().len();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let k: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..1e-5)).collect();
            let lumped = lumped_compliance_from_masses(&m, &k).unwrap();
            let canonical = lumped_canonical(&m, &lumped);
            for (j, row) in canonical.iter().enumerate() {
                for (o, c) in row.iter().enumerate() {
                    let excluded = dominant(&m.steps[j + o].axis.into_inner());
                    assert_eq!(c[excluded], 0.0);
                }
            }
            for _ in 0..20 {
                let q = random_q(&m, &mut rng);
                let v = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let g = LUMPED_G_REF * v / v.norm();
                let tau = gravity_torques(&m, &q, &g).unwrap();
                let d = lumped_deflections(&m, &lumped, &q, &g).unwrap();
                let dc = lumped_deflections(&m, &canonical, &q, &g).unwrap();
                for j in 0..n {
                    assert!((d[j] - k[j] * tau[j]).abs() < DEFLECTION_TOL, "{j}");
                    assert!((dc[j] - d[j]).abs() < DEFLECTION_TOL, "{j}");
                }
            }
            assert_eq!(lumped_params(&m).len(), n * (n + 1));
        }
    }

    /// Lumped coefficients on a prismatic joint, or a rotary one carrying a prismatic joint, are
    /// refused naming the joint.
    #[test]
    fn prismatic_chains_are_refused_by_name() {
        let m = model(crate::test_fixtures::RAIL_6R);
        assert!(!lumped_allowed(&m, 0));
        assert!(lumped_allowed(&m, 1));
        let mut lumped = lumped_zero(m.chain_joints().len());
        lumped[0][1].x = 1e-3;
        let err = check_lumped(&m, &lumped).unwrap_err().to_string();
        assert!(
            err.contains("joint 1") && err.contains("prismatic"),
            "{err}"
        );
        assert!(lumped_params(&m)
            .iter()
            .all(|p| matches!(p, ErrorParam::LumpedCompliance { joint, .. } if *joint >= 1)));
    }

    /// Random errors of every kind plus random lumped coefficients (up to 0.02 rad per
    /// component, full vectors, on the joints that may have them).
    fn errors_with_lumped(m: &RobotModel, rng: &mut ChaCha8Rng) -> crate::KinematicErrors {
        let mut e = crate::test_fixtures::random_errors(m, rng);
        let mut lumped = lumped_zero(m.chain_joints().len());
        for (j, row) in lumped.iter_mut().enumerate() {
            if lumped_allowed(m, j) {
                for c in row.iter_mut() {
                    *c = crate::test_fixtures::random_vec(rng, 0.02);
                }
            }
        }
        e.lumped_compliance = lumped;
        e
    }

    /// Central differences: step 1e-6 rad per coefficient or joint value (tip motions ~1e-6 m),
    /// the tolerance of the true chain's other Jacobian tests (`true_fk/tests.rs`): |analytic −
    /// fd|·h ≤ 1e-14 m + 1e-7 relative.
    const H: f64 = 1e-6;
    const FD_TOL_M: f64 = 1e-14;
    const FD_TOL_REL: f64 = 1e-7;

    fn tip_at(
        m: &RobotModel,
        e: &crate::KinematicErrors,
        q: &[f64],
        tip: &Vector3<f64>,
        g: &Vector3<f64>,
    ) -> Vector3<f64> {
        crate::true_base_from_tip(m, e, q, tip, g)
            .unwrap()
            .translation
            .vector
    }

    /// The lumped columns of `tip_error_jacobian` and the lumped part of
    /// `tip_joint_jacobian_true` match central differences on every test robot (coupled and
    /// prismatic chains included), at random errors of every kind, and the one-walk pose and
    /// Jacobian equal the two separate calls bit for bit.
    #[test]
    fn lumped_jacobians_match_central_differences() {
        for seed in 0..6u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
            for m in crate::test_fixtures::robots() {
                let q = random_q(&m, &mut rng);
                let e = errors_with_lumped(&m, &mut rng);
                let tip = crate::test_fixtures::random_vec(&mut rng, 0.1);
                let g = Vector3::new(1.0, -2.0, -9.5);
                let mut params = lumped_params(&m);
                params.push(ErrorParam::JointOffset { joint: 0 });
                let jac = crate::tip_error_jacobian(&m, &e, &q, &tip, &g, &params).unwrap();
                let (pose, jac1) =
                    crate::true_tip_with_error_jacobian(&m, &e, &q, &tip, &g, &params).unwrap();
                assert_eq!(jac, jac1, "{}", m.name());
                assert_eq!(
                    pose,
                    crate::true_base_from_tip(&m, &e, &q, &tip, &g).unwrap(),
                    "{}",
                    m.name()
                );
                for (c, &p) in params.iter().enumerate() {
                    let (mut ep, mut em) = (e.clone(), e.clone());
                    ep.add(p, H);
                    em.add(p, -H);
                    let fd = (tip_at(&m, &ep, &q, &tip, &g) - tip_at(&m, &em, &q, &tip, &g)) / 2.0;
                    let an = jac.column(c) * H;
                    let diff = (fd - an).norm();
                    assert!(
                        diff <= FD_TOL_M + FD_TOL_REL * an.norm().max(1e-9),
                        "{} seed {seed} {p}: |Δ|·h = {diff:e} m",
                        m.name()
                    );
                }
                let jq = crate::tip_joint_jacobian_true(&m, &e, &q, &tip, &g).unwrap();
                for i in 0..m.dof() {
                    let (mut qp, mut qm) = (q.clone(), q.clone());
                    qp[i] += H;
                    qm[i] -= H;
                    let fd = (tip_at(&m, &e, &qp, &tip, &g) - tip_at(&m, &e, &qm, &tip, &g)) / 2.0;
                    let an = jq.column(i) * H;
                    let diff = (fd - an).norm();
                    assert!(
                        diff <= FD_TOL_M + FD_TOL_REL * an.norm().max(1e-9),
                        "{} seed {seed} joint {}: |Δ|·h = {diff:e} m",
                        m.name(),
                        i + 1
                    );
                }
            }
        }
    }
}
