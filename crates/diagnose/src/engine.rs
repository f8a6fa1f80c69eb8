//! The diagnosis of one session ([`diagnose_session`]), in named steps: the blunder screen
//! (`screen_blunders`, the whole-cell fit's screen), the selection on the whitened
//! identification problem, the baseline against the cell's noise (`baseline`), the
//! identifiability of each (robot, kind) family (`families`), and the gain (`gain`);
//! [`crate::report`] turns the SI findings into the report.

use std::path::Path;

use calib_core::identify::{self, IdentFit, IdentStatus, Selection, SelectionOptions, TipModel};
use calib_core::stats::chi2_sf;
use calib_core::whole_cell::{calibrate_cell, CellFitError, ScreenOptions, SolveOptions};
use calib_core::Robot;
use handclasp_cell::problem::{cell_problem, FitModel};
use handclasp_cell::Cell;
use handclasp_cell::Session;
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::catalogue::{catalogue, Candidate, EffectKind};
use crate::input::check_session;
use crate::mount_tilt::{self, Placement};
use crate::noise::{simulate_rms, NoiseModel};
use crate::report::{self, CorrelationReport, DiagnoseReport, FamilyReport, RejectedPointReport};
use crate::residuals::correlations;
use crate::session_model::SessionModel;
use crate::DiagnoseError;

/// Options of the diagnosis.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Seed of the Monte Carlo simulations (default 1).
    pub seed: u64,
    /// Monte Carlo trials for the predicted residual distributions (default 400).
    pub trials: usize,
    /// Selection settings (α = 0.04 family-wise per step, 10 folds).
    pub selection: SelectionOptions,
    /// Truth of `b1_from_b2` (e.g. from a CMM), for e_tran/e_rot before and after.
    pub truth: Option<Isometry3<f64>>,
    /// Uncertainty of the cell's stated `b1_from_b2` angles, degrees, in the placement check
    /// (default 0.001°: the rounding of a cell file written with 3 decimals, conservatively).
    pub placement_sd_deg: f64,
    /// Screen the session for blunders before the diagnosis (default true): see
    /// [`diagnose_session`].
    pub screen_blunders: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            trials: 400,
            selection: SelectionOptions::default(),
            truth: None,
            placement_sd_deg: 0.001,
            screen_blunders: true,
        }
    }
}

/// Runs the full diagnosis of a session on its cell (the cell's stated `[robotN.errors]`, if
/// any, are NOT used: the nominal models are the URDFs).
///
/// First (unless `options.screen_blunders` is off) the rows are screened for gross errors by the
/// whole-cell calibration's screen ([`calib_core::whole_cell::calibrate_cell`] on
/// [`handclasp_cell::problem::cell_problem`] with the kinematic model: `b1_from_b2` and every
/// kinematic parameter the cell's `[robotN.tolerance]` admits, so that kinematic errors are not
/// mistaken for blunders; a robust Huber start, then studentised residuals against a Bonferroni
/// limit at α = 1 %). The rejected rows are named in the report with their size in σ, and the
/// diagnosis runs on the others.
///
/// Errors: a session that does not fit the cell ([`check_session`]), too few rows left after the
/// screen (naming the rows to re-record), or a model failure.
///
/// # Examples
/// ```no_run
/// let cell = handclasp_cell::Cell::default_floor_wall();
/// let session = diagnose::load_session(std::path::Path::new("session.csv"), &cell)?;
/// let report = diagnose::diagnose_session(&cell, &session, &diagnose::DiagnoseOptions::default())?;
/// print!("{}", diagnose::render_text(&report));
/// # Ok::<(), diagnose::DiagnoseError>(())
/// ```
pub fn diagnose_session(
    cell: &Cell,
    session: &Session,
    options: &DiagnoseOptions,
) -> Result<DiagnoseReport, DiagnoseError> {
    diagnose_session_with_progress(cell, session, options, &mut |_| {})
}

/// [`diagnose_session`], calling `progress` with a one-line description of each phase as it
/// starts (the noise model, the selection, the Monte Carlo baseline, the gain) and of each
/// model-selection step as soon as it is decided (the long part of a diagnosis: at most
/// `options.selection.max_steps` steps). Errors: as [`diagnose_session`].
pub fn diagnose_session_with_progress(
    cell: &Cell,
    session: &Session,
    options: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<DiagnoseReport, DiagnoseError> {
    let screened = screen_session(cell, session, options)?;
    diagnose_screened_session_with_progress(cell, screened, options, progress)
}

/// A session checked against its cell and screened for blunders: what
/// [`diagnose_session`] runs its first phase to get ([`screen_session`]), and
/// [`diagnose_screened_session_with_progress`] diagnoses.
#[derive(Debug, Clone)]
pub struct ScreenedSession {
    /// The session's points less the rejected blunders.
    kept: Session,
    /// The rows rejected as blunders (point number, size in σ, residual in mm).
    rejected: Vec<RejectedPointReport>,
}

impl ScreenedSession {
    /// The points kept for the diagnosis.
    pub fn kept(&self) -> &Session {
        &self.kept
    }

    /// The rows rejected as blunders.
    pub fn rejected(&self) -> &[RejectedPointReport] {
        &self.rejected
    }
}

/// The first phase of [`diagnose_session`]: the session checked against its cell
/// ([`check_session`]) and, unless `options.screen_blunders` is off, screened for blunders by
/// the whole-cell calibration's screen. A caller with other work before the diagnosis (the CLI's
/// result check) can run it alongside, then hand the result to
/// [`diagnose_screened_session_with_progress`]: the report is the one [`diagnose_session`]
/// gives, bit for bit. Errors: as [`diagnose_session`]'s check and screen.
pub fn screen_session(
    cell: &Cell,
    session: &Session,
    options: &DiagnoseOptions,
) -> Result<ScreenedSession, DiagnoseError> {
    check_session(cell, session, Path::new("<session>"))?;
    let (kept, rejected) = if options.screen_blunders {
        screen_blunders(cell, session)?
    } else {
        (session.clone(), Vec::new())
    };
    Ok(ScreenedSession { kept, rejected })
}

/// [`diagnose_session_with_progress`] after its first phase: the diagnosis of a session
/// [`screen_session`] checked and screened with the same `options`. Errors: as
/// [`diagnose_session`] after the screen.
pub fn diagnose_screened_session_with_progress(
    cell: &Cell,
    screened: ScreenedSession,
    options: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str),
) -> Result<DiagnoseReport, DiagnoseError> {
    let ScreenedSession { kept, rejected } = screened;
    let session = &kept;
    let cands = catalogue(
        cell.robot1.model.chain_joints().len(),
        cell.robot2.model.chain_joints().len(),
    );
    let (q1, q2) = joints(session);
    progress(&format!(
        "{} points: noise model and {} candidate effects",
        session.points.len(),
        cands.len()
    ));
    // The cell's noise at these configurations: residuals are whitened by it, so the F tests
    // hold their size under anisotropic alignment noise.
    let r_cell = cell.b1_from_b2.rotation.to_rotation_matrix().into_inner();
    let noise = NoiseModel::new(cell, &q1, &q2, &r_cell)?;
    let model = SessionModel::new(cell, &q1, &q2, &cands).with_weights(noise.whitening());
    let all: Vec<usize> = (0..cands.len()).collect();
    progress("model selection: identifiability, then one screened step at a time");
    let mut step_no = 0;
    let sel = identify::forward_select_with_progress(&model, &all, &options.selection, &mut |s| {
        step_no += 1;
        let verdict = if s.accepted { "accepted" } else { "rejected" };
        progress(&format!(
            "selection step {step_no}: {} {verdict} (p = {:.2e} vs {:.2e})",
            cands[s.param].label(),
            s.p_value,
            s.threshold
        ));
    })?;
    progress(&format!(
        "baseline and gain: {} Monte Carlo trials",
        options.trials
    ));
    let baseline = baseline(&model, &sel, &noise, session, options)?;
    let partial = identify::partial_f_tests_of_selection(&model, &sel)?;
    // Mount tilts: not from the residuals (they only turn the fit) but from the placement.
    let placement = mount_tilt::placement(&sel.fit, cell, options.placement_sd_deg.to_radians());
    let families = families(&model, &sel, &cands);
    let gain = gain(&sel, &baseline, &noise, options);
    let sigma_m = noise.sigma2_eff.sqrt();
    Ok(report::assemble(&Findings {
        cands: &cands,
        sel: &sel,
        reference_zyz: kinematics::zyz_from_rotation(
            &cell.b1_from_b2.rotation.to_rotation_matrix(),
        ),
        n_points: session.points.len(),
        rejected,
        sigma_m,
        baseline,
        partial_p: partial.iter().map(|p| p.1).collect(),
        placement,
        families,
        min_detectable: identify::min_detectable(
            &sel.identifiability,
            options.selection.alpha,
            sigma_m,
        ),
        gain,
    }))
}

/// What [`diagnose_session`] found, SI units; [`report::assemble`] converts it.
pub(crate) struct Findings<'a> {
    /// The catalogue.
    pub cands: &'a [Candidate],
    /// The selection (baseline and final fits, steps, identifiability).
    pub sel: &'a Selection,
    /// The cell's ZYZ angles of `b1_from_b2`, rad (the branch the report's angles follow).
    pub reference_zyz: [f64; 3],
    /// Points diagnosed (the session's, less the rejected blunders).
    pub n_points: usize,
    /// Rows rejected as blunders by the screen, by point number.
    pub rejected: Vec<RejectedPointReport>,
    /// The cell's effective noise σ per axis, m.
    pub sigma_m: f64,
    /// Step 1.
    pub baseline: Baseline,
    /// Partial F-test p-values of the selected parameters (order of `sel.fit.params`).
    pub partial_p: Vec<f64>,
    /// The placement check and the mount-tilt test.
    pub placement: Placement,
    /// Step 2: identifiability per (robot, kind) family.
    pub families: Vec<FamilyReport>,
    /// Smallest detectable |value| per candidate, SI (infinite: not identifiable).
    pub min_detectable: Vec<f64>,
    /// Step 4.
    pub gain: Gain,
}

/// Step 1: the nominal fit against the cell's noise.
pub(crate) struct Baseline {
    /// MC distribution (ascending) of the nominal-fit residual RMS under the cell's noise, m.
    pub mc_rms: Vec<f64>,
    /// χ² upper-tail p of the nominal fit's RSS/σ².
    pub chi2_p: f64,
    /// χ² upper-tail p of the extended fit's RSS/σ².
    pub chi2_p_after: f64,
    /// Significant residual correlations of the nominal fit.
    pub correlations: Vec<CorrelationReport>,
    /// Significant residual correlations left by the extended fit.
    pub correlations_after: Vec<CorrelationReport>,
    /// Robot 2's nominal tips, b2, m (the MC's design).
    p2_nom: Vec<Point3<f64>>,
    /// Per point, the deterministic discrepancy the nominal fit sees if the extended model is
    /// true, b1 axes, m.
    discrepancy: Vec<Vector3<f64>>,
}

/// Step 4: what the extended model gains.
pub(crate) struct Gain {
    /// MC distribution (ascending) of the nominal-fit RMS re-simulated with the extended model, m.
    pub resimulated_rms: Vec<f64>,
    /// Errors of `b1_from_b2` against the truth, before / after, when a truth was given.
    pub truth: Option<TruthErrors>,
}

/// Errors of the nominal and extended `b1_from_b2` against a truth, before / after.
pub(crate) struct TruthErrors {
    /// e_tran (eq 34), m.
    pub e_tran_m: [f64; 2],
    /// e_rot (eq 33), rad.
    pub e_rot_rad: [f64; 2],
    /// Geodesic angle, rad.
    pub geodesic_rad: [f64; 2],
}

/// The blunder screen of [`diagnose_session`]: the session without the rows the whole-cell
/// calibration's screen rejects, and those rows (point number, size in σ, residual in mm).
///
/// Errors: the screen's ([`CellFitError::TooFewRows`] names the rows to re-record), or fewer
/// points left than the diagnosis needs (naming the rejected rows to re-record).
fn screen_blunders(
    cell: &Cell,
    session: &Session,
) -> Result<(Session, Vec<RejectedPointReport>), DiagnoseError> {
    let problem = cell_problem(cell, session, FitModel::Kinematic);
    let cal = calibrate_cell(
        &problem,
        &SolveOptions::default(),
        &ScreenOptions::default(),
    )
    .map_err(|e| match e {
        CellFitError::TooFewRows { .. } => DiagnoseError::Session {
            path: "<session>".into(),
            message: format!("blunder screen: {e}"),
        },
        other => DiagnoseError::Session {
            path: "<session>".into(),
            message: format!("blunder screen (whole-cell fit with the cell's tolerances): {other}"),
        },
    })?;
    let rejected: Vec<RejectedPointReport> = cal
        .rejected
        .iter()
        .map(|r| RejectedPointReport {
            point: r.row,
            size_sigma: r.size_sigma,
            residual_mm: r.residual_m * 1e3,
        })
        .collect();
    let kept = Session::from_points(
        session
            .points
            .iter()
            .filter(|p| !rejected.iter().any(|r| r.point == p.point))
            .cloned()
            .collect(),
    );
    if !rejected.is_empty() {
        if let Err(e) = check_session(cell, &kept, Path::new("<session>")) {
            let rows: Vec<usize> = rejected.iter().map(|r| r.point).collect();
            return Err(DiagnoseError::Session {
                path: "<session>".into(),
                message: format!(
                    "after rejecting the blunders at points {rows:?}, {} points are left, too few to diagnose ({e}); \
                     re-record points {rows:?}",
                    kept.points.len()
                ),
            });
        }
    }
    Ok((kept, rejected))
}

/// Joint vectors of a session (rad): `(q1s, q2s)`.
fn joints(session: &Session) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    (
        session.points.iter().map(|p| p.q1.clone()).collect(),
        session.points.iter().map(|p| p.q2.clone()).collect(),
    )
}

/// Step 1: the residual RMS the cell's noise predicts at these configurations (seeded MC), the
/// χ² tests of both fits, and the residual correlations.
fn baseline(
    model: &SessionModel<'_>,
    sel: &Selection,
    noise: &NoiseModel,
    session: &Session,
    options: &DiagnoseOptions,
) -> Result<Baseline, DiagnoseError> {
    let (base, fit) = (&sel.baseline, &sel.fit);
    let n = session.points.len();
    let mut p2_nom = Vec::with_capacity(n);
    let mut discrepancy = Vec::with_capacity(n);
    for i in 0..n {
        let nom = model.eval(i, &[], &[], &[])?;
        let ext = model.eval(i, &fit.params, &fit.values, &[])?;
        p2_nom.push(nom.p2_b2);
        discrepancy
            .push((nom.p1_b1 - ext.p1_b1) - fit.b1_from_b2.rotation * (nom.p2_b2 - ext.p2_b2));
    }
    let zeros = vec![Vector3::zeros(); n];
    let mc_rms = simulate_rms(
        &p2_nom,
        &base.b1_from_b2,
        &zeros,
        noise,
        options.seed,
        options.trials,
    );
    let chi2 = |f: &IdentFit| {
        if noise.sigma2_eff > 0.0 {
            chi2_sf(f.rss / noise.sigma2_eff, f.dof)
        } else if f.rss > 0.0 {
            0.0
        } else {
            1.0
        }
    };
    Ok(Baseline {
        mc_rms,
        chi2_p: chi2(base),
        chi2_p_after: chi2(fit),
        correlations: correlations(session, &base.residuals),
        correlations_after: correlations(session, &fit.residuals),
        p2_nom,
        discrepancy,
    })
}

/// Step 2: rank, conditioning and confounding of every (robot, kind) family at the baseline.
fn families(model: &SessionModel<'_>, sel: &Selection, cands: &[Candidate]) -> Vec<FamilyReport> {
    let id = &sel.identifiability;
    let mut families = Vec::new();
    for robot in [Robot::One, Robot::Two] {
        for kind in EffectKind::ALL {
            let members: Vec<usize> = (0..cands.len())
                .filter(|&m| cands[m].robot() == robot && cands[m].kind() == kind)
                .collect();
            let fam = id.family(&members);
            let with = |st: IdentStatus| {
                members
                    .iter()
                    .filter(|&&m| id.params[m].status == st)
                    .map(|&m| cands[m].label())
                    .collect()
            };
            families.push(FamilyReport {
                robot,
                kind,
                size: fam.size,
                rank: fam.rank,
                condition: fam.condition.is_finite().then_some(fam.condition),
                singular_values: fam.singular_values,
                confounded_as: members
                    .iter()
                    .filter(|&&m| id.params[m].status == IdentStatus::ConfoundedWithBase)
                    .map(|&m| describe_confounding(model, &sel.baseline, m, cands[m].robot()))
                    .collect(),
                confounded_with_base: with(IdentStatus::ConfoundedWithBase),
                no_effect: with(IdentStatus::NoEffect),
            });
        }
    }
    families
}

/// Step 4: the nominal-fit RMS re-simulated with the extended model, and the errors against the
/// truth when one is given.
fn gain(
    sel: &Selection,
    baseline: &Baseline,
    noise: &NoiseModel,
    options: &DiagnoseOptions,
) -> Gain {
    let (base, fit) = (&sel.baseline, &sel.fit);
    let resimulated_rms = simulate_rms(
        &baseline.p2_nom,
        &fit.b1_from_b2,
        &baseline.discrepancy,
        noise,
        options.seed.wrapping_add(0x5eed),
        options.trials,
    );
    let truth = options.truth.map(|t| {
        let both = |f: &dyn Fn(&Isometry3<f64>) -> f64| [f(&base.b1_from_b2), f(&fit.b1_from_b2)];
        TruthErrors {
            e_tran_m: both(&|x| calib_core::e_tran(&t, x)),
            e_rot_rad: both(&|x| calib_core::e_rot(&t, x)),
            geodesic_rad: both(&|x| calib_core::geodesic_angle(&t, x)),
        }
    });
    Gain {
        resimulated_rms,
        truth,
    }
}

/// The base-frame motion a confounded candidate is equivalent to: its residual column regressed
/// on the 6 columns of `b1_from_b2` at the fit, expressed as a twist of the candidate's robot's
/// base (robot 2: the right perturbation of `b1_from_b2`, in b2 axes).
fn describe_confounding(
    model: &SessionModel<'_>,
    fit: &identify::IdentFit,
    cand: usize,
    robot: Robot,
) -> String {
    let number = robot.number();
    let n = fit.points.len();
    let x = fit.b1_from_b2;
    let r_x = x.rotation.to_rotation_matrix().into_inner();
    let mut a = nalgebra::DMatrix::zeros(3 * n, 6);
    let mut b = nalgebra::DVector::zeros(3 * n);
    for (row, &i) in fit.points.iter().enumerate() {
        let Ok(e) = model.eval(i, &[], &[], &[cand]) else {
            return "a base-frame motion".into();
        };
        let y = x * e.p2_b2;
        a.fixed_view_mut::<3, 3>(3 * row, 0)
            .copy_from(&(-Matrix3::identity()));
        a.fixed_view_mut::<3, 3>(3 * row, 3)
            .copy_from(&y.coords.cross_matrix());
        let col: Vector3<f64> = e.jacobian.column(0).into_owned();
        let col = if robot == Robot::One {
            col
        } else {
            -(r_x * col)
        };
        b.fixed_rows_mut::<3>(3 * row).copy_from(&col);
    }
    let Ok(c) = a.svd(true, true).solve(&b, 1e-12) else {
        return "a base-frame motion".into();
    };
    let rho = Vector3::new(c[0], c[1], c[2]);
    let phi = Vector3::new(c[3], c[4], c[5]);
    // Twist in the robot's own base axes (robot 2: right perturbation X·exp(ξ2)).
    // Robot 1: a motion ξ1 of its base changes r by +ξ1 while the fit's left perturbation c
    // changes r by −c, so ξ1 = −c.
    let (rho_r, phi_r) = if robot == Robot::One {
        (-rho, -phi)
    } else {
        (
            r_x.transpose() * (rho + phi.cross(&x.translation.vector)),
            r_x.transpose() * phi,
        )
    };
    // A rotation moves points 1 m away by |φ|·1 m: compare with the translation.
    if phi_r.norm() * 1.0 > 0.1 * rho_r.norm() && phi_r.norm() > 0.0 {
        let u = phi_r.normalize();
        let name = if u.z.abs() > 0.99 {
            "base yaw"
        } else if u.z.abs() < 0.1 {
            "base tilt"
        } else {
            "base rotation"
        };
        let mut text = format!(
            "rotation of robot {number}'s base about its ({:.3}, {:.3}, {:.3}) axis ({name})",
            u.x, u.y, u.z
        );
        if rho_r.norm() > 1e-3 * phi_r.norm() {
            let v = rho_r.normalize();
            text += &format!(
                " with a translation along ({:.3}, {:.3}, {:.3})",
                v.x, v.y, v.z
            );
        }
        text
    } else if rho_r.norm() > 0.0 {
        let v = rho_r.normalize();
        format!(
            "translation of robot {number}'s base along its ({:.3}, {:.3}, {:.3}) axis",
            v.x, v.y, v.z
        )
    } else {
        "a base-frame motion".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::ErrorParam;
    use sim_cell::{generate_session, trial_rng, Layout, SessionSpec};

    /// Regression guard for the parallel fits of the selection (points, folds, refits) and the
    /// parallel Monte Carlo: a session with two hidden effects (so that steps are accepted and
    /// the re-screen, the backward elimination and the partial F tests all run) gives the
    /// byte-identical JSON report in a 1-thread and a 2-thread pool, and the same progress lines.
    #[test]
    fn the_report_is_identical_whatever_the_thread_count() {
        let cell = Cell::default_floor_wall();
        let mut truth = cell.clone();
        truth
            .robot2
            .errors
            .set(ErrorParam::JointOffset { joint: 2 }, 0.2f64.to_radians());
        truth
            .robot1
            .errors
            .set(ErrorParam::JointOffset { joint: 1 }, 0.1f64.to_radians());
        let spec = SessionSpec::new(40, Layout::Random, 0.8);
        let session = generate_session(&truth, &spec, &mut trial_rng(11, 0)).expect("session");
        let options = DiagnoseOptions {
            trials: 60,
            ..DiagnoseOptions::default()
        };
        let run_with = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let mut lines = Vec::new();
            let report = pool.install(|| {
                diagnose_session_with_progress(&cell, &session, &options, &mut |l| {
                    lines.push(l.to_owned())
                })
                .expect("diagnosis")
            });
            (serde_json::to_string(&report).expect("json"), report, lines)
        };
        let (json1, report1, lines1) = run_with(1);
        let (json2, _, lines2) = run_with(2);
        assert!(
            report1.effects.len() >= 2,
            "the session must name both hidden effects: {}",
            report::render_text(&report1)
        );
        assert_eq!(json1, json2);
        assert_eq!(lines1, lines2);
    }

    /// Largest relative difference of a held-out RMS of the report between the one-step folds
    /// (`SelectionOptions::refit_every_fold = false`) and the refitted folds: calib-core's bound
    /// (`one_step_held_out_rms_agrees_with_refitted_folds`: at most 1.4e-4 measured on toy
    /// sessions of 25–120 points; 2.8e-7 on the 2,000-row slow-diagnose session).
    const HELD_OUT_ONE_STEP_REL_TOL: f64 = 1e-3;

    /// Asserts that two report JSONs are equal but for numbers under a key naming a held-out
    /// figure (`heldout…`), which must agree within [`HELD_OUT_ONE_STEP_REL_TOL`], and the
    /// held-out RMS printed in a step's text (within that bound plus its last printed digit).
    fn same_but_held_out(a: &serde_json::Value, b: &serde_json::Value, path: &str) {
        use serde_json::Value;
        match (a, b) {
            (Value::Object(x), Value::Object(y)) => {
                assert_eq!(
                    x.keys().collect::<Vec<_>>(),
                    y.keys().collect::<Vec<_>>(),
                    "{path}"
                );
                for (key, va) in x {
                    let inner = format!("{path}.{key}");
                    match (va, &y[key]) {
                        (Value::Number(p), Value::Number(q)) if key.contains("heldout") => {
                            let (p, q) = (
                                p.as_f64().unwrap_or(f64::NAN),
                                q.as_f64().unwrap_or(f64::NAN),
                            );
                            let rel = (p - q).abs() / p.abs().max(q.abs()).max(f64::MIN_POSITIVE);
                            assert!(rel <= HELD_OUT_ONE_STEP_REL_TOL, "{inner}: {p} vs {q}");
                        }
                        (va, vb) => same_but_held_out(va, vb, &inner),
                    }
                }
            }
            (Value::Array(x), Value::Array(y)) => {
                assert_eq!(x.len(), y.len(), "{path}");
                for (i, (va, vb)) in x.iter().zip(y).enumerate() {
                    same_but_held_out(va, vb, &format!("{path}[{i}]"));
                }
            }
            (Value::String(x), Value::String(y)) if x != y => {
                // A step's text prints the held-out RMS (`held-out RMS A → B mm`) to 4 decimals:
                // those two numbers may differ in the last digit, nothing else.
                let split = |t: &str| -> Option<(String, Vec<f64>, String)> {
                    let start = t.find("held-out RMS ")? + "held-out RMS ".len();
                    let end = start + t[start..].find(" mm")?;
                    let numbers = t[start..end]
                        .split(" → ")
                        .map(|v| v.parse::<f64>().ok())
                        .collect::<Option<Vec<f64>>>()?;
                    Some((t[..start].to_string(), numbers, t[end..].to_string()))
                };
                let (Some((pa, na, sa)), Some((pb, nb, sb))) = (split(x), split(y)) else {
                    panic!("{path}: {x} vs {y}");
                };
                assert_eq!((pa, sa, na.len()), (pb, sb, nb.len()), "{path}");
                for (p, q) in na.iter().zip(&nb) {
                    // The printed precision (1e-4 mm) plus the relative bound.
                    let bound = 1e-4 + HELD_OUT_ONE_STEP_REL_TOL * p.abs().max(q.abs());
                    assert!((p - q).abs() <= bound, "{path}: {x} vs {y}");
                }
            }
            _ => assert_eq!(a, b, "{path}"),
        }
    }

    /// A shipped cell (`cells/NAME.toml`).
    fn shipped(name: &str) -> Cell {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../cells")
            .join(format!("{name}.toml"));
        Cell::from_toml_file(&path).expect("shipped cell")
    }

    /// The selection's score-test pruning (`SelectionOptions::refit_every_ranked = false`: only
    /// the candidates the score cannot rule out are refitted, the backward elimination is
    /// skipped when the Wald predictions keep every parameter, the held-out RMS of an unchanged
    /// model is reused) gives the byte-identical report of refitting every ranked candidate, on
    /// the hidden-effect sessions of `tests/e2e/diagnose.rs` (floor–floor cell, random layout,
    /// 0.8 m: robot 2's joint-3 offset 0.2° with seeds 11 and 12, robot 1's mount tilted −0.12°
    /// about y with seed 21, noise only with seed 14; 40 points each), the two-effect session of
    /// the thread-count test above, and a floor–ceiling session with an error on every joint of
    /// both robots (joint offsets and origin positions, as the slow-diagnose benchmark cell).
    /// Also: the held-out RMS by one Gauss–Newton step per fold (the default) gives the report
    /// of refitting every fold (`SelectionOptions::refit_every_fold`) but for the held-out
    /// figures, within [`HELD_OUT_ONE_STEP_REL_TOL`].
    #[test]
    fn pruned_refits_choose_what_refitting_every_candidate_chooses() {
        let floor_floor = shipped("floor-floor");
        let hidden = |robot: u8, param: ErrorParam, value: f64, seed: u64| {
            let mut truth = floor_floor.clone();
            let errors = if robot == 1 {
                &mut truth.robot1.errors
            } else {
                &mut truth.robot2.errors
            };
            errors.set(param, value);
            let spec = SessionSpec::new(40, Layout::Random, 0.8);
            let s = generate_session(&truth, &spec, &mut trial_rng(seed, 0)).expect("session");
            (floor_floor.clone(), s)
        };
        let offset = ErrorParam::JointOffset { joint: 2 };
        let tilt = ErrorParam::MountRpy {
            axis: kinematics::Axis::Y,
        };
        let mut sessions = vec![
            hidden(2, offset, 0.2f64.to_radians(), 11),
            hidden(2, offset, 0.2f64.to_radians(), 12),
            hidden(1, tilt, (-0.12f64).to_radians(), 21),
            hidden(2, offset, 0.0, 14),
        ];
        let floor_wall = Cell::default_floor_wall();
        let mut truth = floor_wall.clone();
        truth
            .robot2
            .errors
            .set(ErrorParam::JointOffset { joint: 2 }, 0.2f64.to_radians());
        truth
            .robot1
            .errors
            .set(ErrorParam::JointOffset { joint: 1 }, 0.1f64.to_radians());
        let spec = SessionSpec::new(40, Layout::Random, 0.8);
        sessions.push((
            floor_wall,
            generate_session(&truth, &spec, &mut trial_rng(11, 0)).expect("session"),
        ));
        // Every joint of both robots: offsets up to ±0.04°, origin positions up to ±0.5 mm
        // (seeded, as in the slow-diagnose cell).
        let floor_ceiling = shipped("floor-ceiling");
        let mut truth = floor_ceiling.clone();
        let mut rng = trial_rng(7, 0);
        for errors in [&mut truth.robot1.errors, &mut truth.robot2.errors] {
            for joint in 0..errors.joint_offset.len() {
                let v: f64 = rand::Rng::random_range(&mut rng, -0.04..0.04);
                errors.set(ErrorParam::JointOffset { joint }, v.to_radians());
                for axis in kinematics::Axis::ALL {
                    let v: f64 = rand::Rng::random_range(&mut rng, -0.5e-3..0.5e-3);
                    errors.set(ErrorParam::OriginXyz { joint, axis }, v);
                }
            }
        }
        let spec = SessionSpec::new(150, Layout::Tetrahedron, 1.0);
        sessions.push((
            floor_ceiling,
            generate_session(&truth, &spec, &mut trial_rng(11, 0)).expect("session"),
        ));
        let mut named = 0;
        for (k, (cell, session)) in sessions.iter().enumerate() {
            let run = |every: bool, every_fold: bool| {
                let mut options = DiagnoseOptions {
                    trials: 40,
                    ..DiagnoseOptions::default()
                };
                options.selection.refit_every_ranked = every;
                options.selection.refit_every_fold = every_fold;
                let report = diagnose_session(cell, session, &options).expect("diagnosis");
                (serde_json::to_string(&report).expect("json"), report)
            };
            let (pruned, report) = run(false, false);
            let (every, _) = run(true, false);
            assert_eq!(
                pruned,
                every,
                "session {k}: {}",
                report::render_text(&report)
            );
            // The held-out RMS by one Gauss–Newton step per fold against refitted folds: the
            // same report but for the held-out figures, which agree closely.
            let (refitted_folds, _) = run(false, true);
            let a: serde_json::Value = serde_json::from_str(&pruned).expect("json");
            let b: serde_json::Value = serde_json::from_str(&refitted_folds).expect("json");
            same_but_held_out(&a, &b, &format!("session {k}"));
            named += report.effects.len();
        }
        // The sessions exercise accepted steps (re-screens, backward eliminations), not only
        // the first rejected one.
        assert!(named >= 5, "{named} effects named in all");
    }
}
