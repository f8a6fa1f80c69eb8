//! The calibrated `b1_from_b2` against the cell's stated placement: the rotation-only check
//! ([`Placement`], reported as [`crate::PlacementReport`]) and the mount-tilt test ([`mount_tilt_test`]), a generalised
//! least-squares fit of both robots' base tilts and yaws to the rotation AND translation
//! differences, which tells a tilted robot 1 from a tilted robot 2. Mount tilts cannot be
//! selected from handclasp residuals (a turned base only turns the fit), so this is where the
//! diagnosis names them.

use calib_core::identify;
use calib_core::stats::{chi2_sf, t_quantile, t_two_sided_p};
use calib_core::Robot;
use handclasp_cell::Cell;
use kinematics::Axis;
use nalgebra::{Isometry3, Matrix3, Vector3};

/// The calibrated `b1_from_b2` against the cell's stated one, SI units (the report converts:
/// [`crate::PlacementReport`]).
#[derive(Debug, Clone)]
pub struct Placement {
    /// The rotation (and translation) difference with its standard errors
    /// (`calib_core::identify::placement_rotation`).
    pub rotation: identify::PlacementRotation,
    /// The two-sided 95% t quantile at the fit's residual dof (interval half-width per s.e.).
    pub t95: f64,
    /// Whether a tilt component about base 2's x or y is significant at 5% (Bonferroni over
    /// the two).
    pub tilt_significant: bool,
    /// The mount-tilt test (rotation AND translation).
    pub mount_tilt: MountTiltFit,
}

/// The placement check of a fit against the cell, `sd_rad` being the uncertainty of the cell's
/// stated angles (rad), with the mount-tilt test.
pub fn placement(fit: &identify::IdentFit, cell: &Cell, sd_rad: f64) -> Placement {
    let rotation = identify::placement_rotation(fit, &cell.b1_from_b2, sd_rad);
    Placement {
        t95: t_quantile(0.975, fit.dof),
        tilt_significant: rotation.p_value.x.min(rotation.p_value.y) < 0.05 / 2.0,
        rotation,
        mount_tilt: mount_tilt_test(fit, cell, sd_rad),
    }
}

/// Level of the mount-tilt test against the cell's placement ([`mount_tilt_test`]): the
/// no-tilt hypothesis is rejected when its χ² upper-tail p is below this, and a tilt component
/// is named when its two-sided p is below `ALPHA_TILT / 2` (Bonferroni over x and y). 1% so that it
/// adds at most ~1% to the residual selection's false alarms on noise-only sessions (5%
/// family-wise, in practice 2.5–5%; BENCHMARKS.md, "diagnose").
pub const ALPHA_TILT: f64 = 0.01;

/// Standard deviation (m, per axis) of the cell's stated `b1_from_b2` translation in the
/// mount-tilt test: the paper's Table 1 prints xyz to 0.1 mm (rounding sd 0.029 mm), taken
/// conservatively as 0.05 mm.
pub const PLACEMENT_SD_XYZ_M: f64 = 5e-5;

/// The mount-tilt test's result, SI units: which robot's base is tilted, if any, when the cell
/// states the TRUE placement of the nominal bases (see [`mount_tilt_test`]; the report's form
/// is [`crate::MountTiltTest`]).
#[derive(Debug, Clone)]
pub struct MountTiltFit {
    /// χ² of the hypotheses no tilt (both base yaws free) / robot 1's base turned (tilt and
    /// yaw) / robot 2's, GLS on the placement difference.
    pub chi2: [f64; 3],
    /// Their degrees of freedom (6 − rank).
    pub dof: [usize; 3],
    /// Upper-tail p of the no-tilt hypothesis.
    pub p_no_tilt: f64,
    /// The robot whose tilt explains the difference best (smaller χ²), when no tilt is rejected
    /// at [`ALPHA_TILT`].
    pub robot: Option<Robot>,
    /// Upper-tail p of the chosen hypothesis (a goodness-of-fit check: below [`ALPHA_TILT`],
    /// no mount tilt explains the difference and none is named).
    pub p_fit: f64,
    /// The chosen robot's tilt about its base x and y axes, rad (`mount_rpy` x, y).
    pub tilt_rad: [f64; 2],
    /// Their 95% intervals (t quantile at the fit's dof), rad.
    pub tilt_ci95_rad: [[f64; 2]; 2],
    /// Their two-sided p-values.
    pub tilt_p_value: [f64; 2],
    /// The other robot, when its tilt explains the difference as well (both hypotheses pass
    /// their χ² test): a tilt about the line joining the two bases turns both alike, so the data
    /// cannot tell which base it is; the choice then goes to the fewer tilt components.
    pub alternative: Option<Robot>,
    /// The alternative robot's significant tilt axes.
    pub alternative_axes: Vec<Axis>,
    /// Why the Gauss–Newton fit of each hypothesis (no tilt, robot 1, robot 2) stopped (not
    /// part of the report).
    pub stop: [TiltStop; 3],
}

impl MountTiltFit {
    /// The tilt components the test names (indices 0 = x, 1 = y): none unless a robot was
    /// chosen and its hypothesis passes its χ² test at [`ALPHA_TILT`]; then those with
    /// two-sided p below `ALPHA_TILT / 2`.
    pub fn named_components(&self) -> Vec<usize> {
        if self.robot.is_none() || self.p_fit.is_nan() || self.p_fit < ALPHA_TILT {
            return Vec::new();
        }
        (0..2)
            .filter(|&k| self.tilt_p_value[k] < ALPHA_TILT / 2.0)
            .collect()
    }
}

/// Largest Gauss–Newton step (rad, ∞-norm over the fitted tilts and yaws) taken as converged:
/// 1e-12 rad moves a point 1 m away by 1 pm.
pub const TILT_STEP_TOL_RAD: f64 = 1e-12;

/// Gauss–Newton iterations per hypothesis: the prediction is nearly linear in tilts of a few
/// tenths of a degree, so 4 steps reach [`TILT_STEP_TOL_RAD`] in practice.
pub const TILT_ITERATIONS: usize = 4;

/// Why the mount-tilt test's Gauss–Newton fit of one hypothesis stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum TiltStop {
    /// All iterations ran and the last step was below [`TILT_STEP_TOL_RAD`].
    Converged,
    /// All iterations ran and the last step was still this large (rad, ∞-norm): the χ² is the
    /// smaller of the last two evaluated.
    IterationLimit {
        /// The last step, rad.
        last_step_rad: f64,
    },
    /// Not fitted: the covariance of the placement difference is not positive definite.
    SingularCovariance,
}

/// The placement difference `d = (φ, δt)` predicted by tilts/yaws `θ = [a1x, a1y, ψ1, a2x, a2y,
/// ψ2]` (rad): the true base `i` is the nominal one turned by `Rot(rpy = (aix, aiy, 0))·Rz(ψi)`
/// (ψ: the base yaw, equivalent to a joint-1 offset), so the fit sees
/// `X̂ = M1⁻¹·X·M2`; `φ = log(R̂·Rᵀ)` (b1 axes), `δt = t̂ − t`.
fn tilt_prediction(x: &Isometry3<f64>, th: &[f64; 6]) -> [f64; 6] {
    let m = |a: f64, b: f64, psi: f64| {
        let r = kinematics::rotation_from_rpy(&Vector3::new(a, b, 0.0))
            * nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), psi);
        Isometry3::from_parts(nalgebra::Translation3::identity(), r.into())
    };
    let xh = m(th[0], th[1], th[2]).inverse() * x * m(th[3], th[4], th[5]);
    let phi = (xh.rotation * x.rotation.inverse()).scaled_axis();
    let dt = xh.translation.vector - x.translation.vector;
    [phi.x, phi.y, phi.z, dt.x, dt.y, dt.z]
}

/// The Jacobian of [`tilt_prediction`] at θ = 0 (rad → d; columns `[a1x, a1y, ψ1, a2x, a2y,
/// ψ2]`): robot 1's base turned by `e` turns the fit by `−e` and moves its translation by
/// `−e × t`; robot 2's turns it by `R·e`.
fn tilt_columns(x: &Isometry3<f64>) -> nalgebra::DMatrix<f64> {
    let r = x.rotation.to_rotation_matrix().into_inner();
    let t = x.translation.vector;
    let mut a_full = nalgebra::DMatrix::<f64>::zeros(6, 6);
    for (k, e) in [Vector3::x(), Vector3::y(), Vector3::z()]
        .iter()
        .enumerate()
    {
        let rot1 = -e;
        let tr1 = -e.cross(&t);
        let rot2 = r * e;
        for i in 0..3 {
            a_full[(i, k)] = rot1[i];
            a_full[(3 + i, k)] = tr1[i];
            a_full[(i, 3 + k)] = rot2[i];
        }
    }
    a_full
}

/// Tests for a mount tilt by comparing the fitted `b1_from_b2` (`X̂`) with the cell's (`X`),
/// assuming the cell states the TRUE placement of the nominal bases (as a simulation's cell
/// does). A tilt of robot 2's base by `a2` (b2 axes) gives `X̂ = X·exp([a2]ₓ)`: the rotation
/// turns by `R·a2`, the translation does not move. A tilt of robot 1's base by `a1` (b1 axes)
/// gives `X̂ = exp(−[a1]ₓ)·X` (the points measured in the nominal b1 are the true ones turned
/// back): the rotation turns by `−a1` AND the translation moves by `−a1 × t` (≈ 1.5 mm for
/// 0.05° at |t| ≈ 1.7 m, against an s.e. of ~0.1–0.2 mm), which is what tells the robots apart.
///
/// `d = (φ, δt)` with covariance from the fit (left perturbation: `φ`, `δt = ρ − [t̂]ₓφ`) plus
/// the cell's stated-angle sd `sd_rad` and [`PLACEMENT_SD_XYZ_M`]. Hypotheses (a base yaw is
/// confounded with that robot's joint-1 offset: a nuisance, never a mount tilt): H0 no tilt
/// (both yaws free), H1 robot 1's base turned (tilt about x, y and its yaw), H2 robot 2's;
/// generalised least squares (Gauss–Newton on the exact `tilt_prediction`). H0 rejected at
/// [`ALPHA_TILT`] → the hypothesis that passes its own χ² test at [`ALPHA_TILT`]; if both pass (a
/// turn about the line joining the two bases looks the same for both robots), the one with fewer
/// significant tilt components, then the smaller χ² (the other is recorded as `alternative`).
/// If neither passes, the difference is no mount tilt (e.g. a base-frame translation) and
/// nothing is named. Components are named at `ALPHA_TILT / 2` each (Bonferroni over x and y), not
/// both on the joint test: a zero component named would be a false cause.
pub fn mount_tilt_test(fit: &identify::IdentFit, cell: &Cell, sd_rad: f64) -> MountTiltFit {
    use nalgebra::{DMatrix, DVector, Matrix6};
    let x = cell.b1_from_b2;
    let t = x.translation.vector;
    let xh = fit.b1_from_b2;
    let phi = (xh.rotation * x.rotation.inverse()).scaled_axis();
    let dt = xh.translation.vector - t;
    let d = DVector::from_row_slice(&[phi.x, phi.y, phi.z, dt.x, dt.y, dt.z]);
    // Covariance of d from the fit's (ρ, φ) covariance.
    let mut j = Matrix6::<f64>::zeros();
    j.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&Matrix3::identity());
    j.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&Matrix3::identity());
    j.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(-xh.translation.vector.cross_matrix()));
    let sx: Matrix6<f64> = fit.covariance.fixed_view::<6, 6>(0, 0).into_owned();
    let mut c = j * sx * j.transpose();
    for i in 0..3 {
        c[(i, i)] += sd_rad * sd_rad;
        c[(3 + i, 3 + i)] += PLACEMENT_SD_XYZ_M * PLACEMENT_SD_XYZ_M;
    }
    let empty = MountTiltFit {
        chi2: [f64::NAN; 3],
        dof: [0; 3],
        p_no_tilt: 1.0,
        robot: None,
        p_fit: 1.0,
        tilt_rad: [0.0; 2],
        tilt_ci95_rad: [[0.0; 2]; 2],
        tilt_p_value: [1.0; 2],
        alternative: None,
        alternative_axes: Vec::new(),
        stop: [TiltStop::SingularCovariance; 3],
    };
    let Some(chol) = nalgebra::Cholesky::new(DMatrix::from_iterator(6, 6, c.iter().copied()))
    else {
        return empty;
    };
    let l = chol.l();
    let whiten = |v: &DVector<f64>| {
        l.solve_lower_triangular(v)
            .unwrap_or_else(|| DVector::zeros(6))
    };
    let a_full = tilt_columns(&x);
    // GLS fit of a hypothesis (columns `cols` of θ): (θ, χ², dof, cov θ).
    let gls = |cols: &[usize]| {
        let a = a_full.select_columns(cols);
        let aw = DMatrix::from_columns(
            &(0..cols.len())
                .map(|k| whiten(&a.column(k).into_owned()))
                .collect::<Vec<_>>(),
        );
        let svd = aw.clone().svd(true, true);
        let smax = svd.singular_values.max();
        let tol = smax * 1e-9;
        let rank = svd.singular_values.iter().filter(|&&s| s > tol).count();
        let pinv = svd
            .clone()
            .pseudo_inverse(tol)
            .unwrap_or_else(|_| DMatrix::zeros(cols.len(), 6));
        let mut th = [0.0; 6];
        let mut chi2 = f64::NAN;
        let mut last_step = f64::INFINITY;
        for _ in 0..TILT_ITERATIONS {
            let pred = DVector::from_row_slice(&tilt_prediction(&x, &th));
            let rw = whiten(&(&d - pred));
            chi2 = rw.norm_squared();
            let step = &pinv * rw;
            last_step = step.amax();
            for (k, &col) in cols.iter().enumerate() {
                th[col] += step[k];
            }
        }
        let pred = DVector::from_row_slice(&tilt_prediction(&x, &th));
        chi2 = whiten(&(&d - pred)).norm_squared().min(chi2);
        let cov = &pinv * pinv.transpose();
        let stop = if last_step <= TILT_STEP_TOL_RAD {
            TiltStop::Converged
        } else {
            TiltStop::IterationLimit {
                last_step_rad: last_step,
            }
        };
        (th, chi2, 6 - rank, cov, stop)
    };
    let h0 = gls(&[2, 5]);
    let hyp = [gls(&[0, 1, 2]), gls(&[3, 4, 5])];
    let p0 = chi2_sf(h0.1, h0.2);
    let mut out = MountTiltFit {
        chi2: [h0.1, hyp[0].1, hyp[1].1],
        dof: [h0.2, hyp[0].2, hyp[1].2],
        p_no_tilt: p0,
        stop: [h0.4, hyp[0].4, hyp[1].4],
        ..empty
    };
    if p0.is_nan() || p0 >= ALPHA_TILT {
        return out;
    }
    // Per hypothesis: p of its χ², the tilt components (rad), their s.e., their p-values.
    let tq = t_quantile(0.975, fit.dof);
    let stats = |h: &(_, f64, usize, DMatrix<f64>, TiltStop), off: usize| {
        let th: &[f64; 6] = &h.0;
        let comp = [0, 1].map(|k| {
            let v = th[off + k];
            let se = h.3[(k, k)].max(0.0).sqrt();
            let p = if se > 0.0 {
                t_two_sided_p(v / se, fit.dof)
            } else {
                1.0
            };
            (v, se, p)
        });
        let n_sig = comp.iter().filter(|c| c.2 < ALPHA_TILT / 2.0).count();
        (chi2_sf(h.1, h.2), comp, n_sig)
    };
    let st = [stats(&hyp[0], 0), stats(&hyp[1], 3)];
    let acceptable = |i: usize| st[i].0 >= ALPHA_TILT && st[i].2 > 0;
    // Among the hypotheses that explain the difference, the one needing fewer tilt components
    // (a tilt about the line joining the bases is the same for both robots), then the smaller χ².
    let i = match (acceptable(0), acceptable(1)) {
        (true, true) => {
            if st[0].2 != st[1].2 {
                usize::from(st[1].2 < st[0].2)
            } else {
                usize::from(hyp[1].1 < hyp[0].1)
            }
        }
        (true, false) => 0,
        (false, true) => 1,
        (false, false) => usize::from(hyp[1].1 < hyp[0].1),
    };
    let robots = [Robot::One, Robot::Two];
    out.robot = Some(robots[i]);
    out.alternative = (acceptable(0) && acceptable(1)).then_some(robots[1 - i]);
    out.p_fit = st[i].0;
    for (k, &(v, se, p)) in st[i].1.iter().enumerate() {
        out.tilt_rad[k] = v;
        out.tilt_ci95_rad[k] = [v - tq * se, v + tq * se];
        out.tilt_p_value[k] = p;
    }
    if let Some(j) = out.alternative {
        let (_, comp, _) = &st[usize::from(j.number()) - 1];
        out.alternative_axes = (0..2)
            .filter(|&k| comp[k].2 < ALPHA_TILT / 2.0)
            .map(|k| if k == 0 { Axis::X } else { Axis::Y })
            .collect();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::LmOptions;
    use kinematics::ErrorParam;
    use sim_cell::{generate_session, trial_rng, Layout, SessionSpec};

    use crate::catalogue::catalogue;
    use crate::session_model::SessionModel;

    /// [`tilt_columns`] against central differences of [`tilt_prediction`] at θ = 0. Step 1e-6
    /// rad: the truncation error is O(h²·|t|) ≈ 1e-12 and the round-off O(ε·|t|/h) ≈ 1e-9 for
    /// |t| ≈ 2 m, so 1e-8 (m or rad per rad) separates a wrong column from the FD noise.
    #[test]
    fn tilt_columns_match_central_differences() {
        const H: f64 = 1e-6;
        const FD_TOL: f64 = 1e-8;
        for cell in [Cell::default_floor_wall(), Cell::default_floor_ceiling()] {
            let x = cell.b1_from_b2;
            let a = tilt_columns(&x);
            for k in 0..6 {
                let (mut plus, mut minus) = ([0.0; 6], [0.0; 6]);
                plus[k] = H;
                minus[k] = -H;
                let (dp, dm) = (tilt_prediction(&x, &plus), tilt_prediction(&x, &minus));
                for i in 0..6 {
                    let fd = (dp[i] - dm[i]) / (2.0 * H);
                    assert!(
                        (fd - a[(i, k)]).abs() < FD_TOL,
                        "row {i}, column {k}: analytic {} vs FD {fd}",
                        a[(i, k)]
                    );
                }
            }
        }
    }

    /// The nominal fit of a 40-point session simulated on `cell` with `robot2_tilt_x` rad of
    /// robot 2's mount tilt about its x axis, and the test on it.
    fn test_on(cell: &Cell, robot2_tilt_x: f64, seed: u64) -> MountTiltFit {
        let mut truth = cell.clone();
        truth
            .robot2
            .errors
            .set(ErrorParam::MountRpy { axis: Axis::X }, robot2_tilt_x);
        let spec = SessionSpec::new(40, Layout::Random, 0.8);
        let session = generate_session(&truth, &spec, &mut trial_rng(seed, 0)).expect("session");
        let q1: Vec<Vec<f64>> = session.points.iter().map(|p| p.q1.clone()).collect();
        let q2: Vec<Vec<f64>> = session.points.iter().map(|p| p.q2.clone()).collect();
        let cands = catalogue(
            cell.robot1.model.chain_joints().len(),
            cell.robot2.model.chain_joints().len(),
        );
        let model = SessionModel::new(cell, &q1, &q2, &cands);
        let fit = identify::fit(&model, &[], None, None, &LmOptions::identify()).expect("fit");
        mount_tilt_test(&fit, cell, 1e-3f64.to_radians())
    }

    /// A 0.2° tilt of robot 2's mount about x is named for robot 2, axis x, with an interval
    /// covering it, and the Gauss–Newton fits say why they stopped.
    #[test]
    fn a_robot2_tilt_is_named_and_the_fits_say_why_they_stopped() {
        let cell = Cell::default_floor_wall();
        let v = 0.2f64.to_radians();
        let t = test_on(&cell, v, 21);
        eprintln!("stop reasons (no tilt, robot 1, robot 2): {:?}", t.stop);
        assert_eq!(t.robot, Some(Robot::Two), "{t:?}");
        assert!(t.named_components().contains(&0), "{t:?}");
        let [lo, hi] = t.tilt_ci95_rad[0];
        assert!(lo <= v && v <= hi, "{v} outside [{lo}, {hi}]");
        for stop in t.stop {
            assert!(
                matches!(stop, TiltStop::Converged | TiltStop::IterationLimit { .. }),
                "{stop:?}"
            );
        }
        // The chosen hypothesis fits a tilt of a few tenths of a degree: it converges.
        assert_eq!(t.stop[2], TiltStop::Converged, "{:?}", t.stop);
    }

    /// Without a tilt, nothing is named.
    #[test]
    fn no_tilt_names_nothing() {
        let t = test_on(&Cell::default_floor_wall(), 0.0, 22);
        assert!(t.named_components().is_empty(), "{t:?}");
    }
}
