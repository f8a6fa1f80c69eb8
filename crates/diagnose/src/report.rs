//! The diagnosis report: its serialised structs (`handclasp diagnose --json` prints
//! [`DiagnoseReport`]; field names carry the unit, mm and degrees) and [`render_text`].

use calib_core::stats::{fraction_below, quantile};
use calib_core::PoseMmDeg;
use calib_core::Robot;
use serde::Serialize;

use crate::catalogue::EffectKind;
use crate::engine::Findings;
use crate::mount_tilt::{MountTiltFit, Placement, ALPHA_TILT};

/// Millimetres per metre: the report's lengths.
const MM_PER_M: f64 = 1000.0;

/// `b1_from_b2` in file units: the workspace's one pose type at the file edge
/// ([`calib_core::PoseMmDeg`], JSON `{"xyz_mm": [..], "zyz_deg": [..]}`); built with
/// [`PoseMmDeg::from_isometry`] on the ZYZ branch nearest the cell's angles.
pub type PoseReport = PoseMmDeg;

/// The calibrated `b1_from_b2` against the cell's stated one. Handclasp residuals cannot see a
/// mount tilt (it only turns the fit), but if the cell states the TRUE placement of the nominal
/// bases (as a simulation's cell does), the fitted rotation shows it: `R_fit = R_cell·exp([a]ₓ)`,
/// `a` in base-2 axes, which is a tilt of robot 2's base by `a` (or of robot 1's by
/// `−R_cell·a`, which also moves the translation: [`crate::mount_tilt_test`] uses both to tell the
/// robots apart; the `tilt_*` fields here are the rotation-only check).
#[derive(Debug, Clone, Serialize)]
pub struct PlacementReport {
    /// `a` about base 2's x and y axes (a mount tilt of robot 2), degrees.
    pub tilt_b2_deg: [f64; 2],
    /// 95% intervals of the two tilt components, degrees.
    pub tilt_b2_ci95_deg: [[f64; 2]; 2],
    /// Two-sided p-values of the two tilt components.
    pub tilt_b2_p_value: [f64; 2],
    /// Whether a tilt component is significant at 5% (Bonferroni over the two).
    pub tilt_significant: bool,
    /// The same rotation as a tilt of robot 1's base about its x, y, z axes, degrees.
    pub robot1_equivalent_deg: [f64; 3],
    /// `a` about base 2's z axis (a yaw of robot 2's base), degrees, and its 95% interval.
    pub yaw_b2_deg: f64,
    /// 95% interval of the yaw, degrees.
    pub yaw_b2_ci95_deg: [f64; 2],
    /// Fitted minus stated translation, b1 axes, mm.
    pub dxyz_mm: [f64; 3],
    /// Standard errors of `dxyz_mm`, mm.
    pub dxyz_se_mm: [f64; 3],
    /// The mount-tilt test (rotation AND translation against the cell's placement): which
    /// robot's base is tilted; its significant components are named in `effects`.
    pub mount_tilt: MountTiltTest,
}

impl PlacementReport {
    /// The placement check in report units.
    pub fn from_placement(p: &Placement) -> Self {
        let pr = &p.rotation;
        let t = p.t95;
        let ci = |i: usize| {
            [
                (pr.a_b2[i] - t * pr.std_error[i]).to_degrees(),
                (pr.a_b2[i] + t * pr.std_error[i]).to_degrees(),
            ]
        };
        Self {
            tilt_b2_deg: [pr.a_b2.x.to_degrees(), pr.a_b2.y.to_degrees()],
            tilt_b2_ci95_deg: [ci(0), ci(1)],
            tilt_b2_p_value: [pr.p_value.x, pr.p_value.y],
            tilt_significant: p.tilt_significant,
            robot1_equivalent_deg: [
                pr.a1_b1.x.to_degrees(),
                pr.a1_b1.y.to_degrees(),
                pr.a1_b1.z.to_degrees(),
            ],
            yaw_b2_deg: pr.a_b2.z.to_degrees(),
            yaw_b2_ci95_deg: ci(2),
            dxyz_mm: [
                pr.dt_b1.x * MM_PER_M,
                pr.dt_b1.y * MM_PER_M,
                pr.dt_b1.z * MM_PER_M,
            ],
            dxyz_se_mm: [
                pr.dt_std_error.x * MM_PER_M,
                pr.dt_std_error.y * MM_PER_M,
                pr.dt_std_error.z * MM_PER_M,
            ],
            mount_tilt: MountTiltTest::from_fit(&p.mount_tilt),
        }
    }
}

/// A session row rejected as a blunder (see [`crate::diagnose_session`]).
#[derive(Debug, Clone, Serialize)]
pub struct RejectedPointReport {
    /// The row's point number (the CSV's `point` column).
    pub point: usize,
    /// Its deletion-studentised residual against the fit without it, in σ of the cell's noise.
    pub size_sigma: f64,
    /// Its residual against that fit, mm (3-D norm).
    pub residual_mm: f64,
}

/// The mount-tilt test in report units: which robot's base is tilted, if any, when the cell
/// states the TRUE placement of the nominal bases (see [`crate::mount_tilt_test`]).
#[derive(Debug, Clone, Serialize)]
pub struct MountTiltTest {
    /// χ² of the hypotheses no tilt (both base yaws free) / robot 1's base turned (tilt and
    /// yaw) / robot 2's, GLS on the placement difference.
    pub chi2: [f64; 3],
    /// Their degrees of freedom (6 − rank).
    pub dof: [usize; 3],
    /// Upper-tail p of the no-tilt hypothesis.
    pub p_no_tilt: f64,
    /// The robot whose tilt explains the difference best (smaller χ²), when no tilt is rejected
    /// at [`ALPHA_TILT`]; serialised as 1 or 2.
    pub robot: Option<Robot>,
    /// Upper-tail p of the chosen hypothesis (a goodness-of-fit check: below [`ALPHA_TILT`],
    /// no mount tilt explains the difference and none is named).
    pub p_fit: f64,
    /// The chosen robot's tilt about its base x and y axes, degrees (`mount_rpy` x, y).
    pub tilt_deg: [f64; 2],
    /// Their 95% intervals, degrees.
    pub tilt_ci95_deg: [[f64; 2]; 2],
    /// Their two-sided p-values.
    pub tilt_p_value: [f64; 2],
    /// The other robot, when its tilt explains the difference as well (both hypotheses pass
    /// their χ² test): a tilt about the line joining the two bases turns both alike, so the data
    /// cannot tell which base it is; the choice then goes to the fewer tilt components.
    pub alternative: Option<Robot>,
    /// The alternative robot's significant tilt axes ("x", "y").
    pub alternative_axes: Vec<&'static str>,
}

impl MountTiltTest {
    /// The test in report units.
    pub fn from_fit(f: &MountTiltFit) -> Self {
        let deg2 = |v: [f64; 2]| v.map(f64::to_degrees);
        Self {
            chi2: f.chi2,
            dof: f.dof,
            p_no_tilt: f.p_no_tilt,
            robot: f.robot,
            p_fit: f.p_fit,
            tilt_deg: deg2(f.tilt_rad),
            tilt_ci95_deg: f.tilt_ci95_rad.map(deg2),
            tilt_p_value: f.tilt_p_value,
            alternative: f.alternative,
            alternative_axes: f.alternative_axes.iter().map(|a| a.name()).collect(),
        }
    }
}

/// One named effect.
#[derive(Debug, Clone, Serialize)]
pub struct EffectReport {
    /// Kind.
    pub kind: EffectKind,
    /// Robot, serialised as 1 or 2.
    pub robot: Robot,
    /// 1-based joint, or null.
    pub joint: Option<usize>,
    /// "x" | "y" | "z", or null.
    pub axis: Option<&'static str>,
    /// Estimate, true minus nominal, in `unit`.
    pub value: f64,
    /// Unit.
    pub unit: &'static str,
    /// 95% interval (t quantile), in `unit`.
    pub ci95: [f64; 2],
    /// Candidates the data cannot tell apart from this one (labels), including itself.
    pub confounded_with: Vec<String>,
    /// Partial F-test p-value in the final model (refit without it), unadjusted; it was
    /// selected at the Bonferroni level `α/m`. For a `mount_tilt` (named from the placement,
    /// [`crate::mount_tilt_test`]): the component's two-sided p, named below `ALPHA_TILT / 2`.
    pub p_value: f64,
}

/// A significant correlation of the residuals.
#[derive(Debug, Clone, Serialize)]
pub struct CorrelationReport {
    /// Residual component: "x", "y", "z" (b1 axes) or "norm".
    pub residual: String,
    /// Against what: "r1_q3", "r2_q1", "x", "y", "z" (robot 1 tip in b1), "reach1", "reach2".
    pub against: String,
    /// Pearson r.
    pub r: f64,
    /// Bonferroni-adjusted p-value.
    pub p_adjusted: f64,
}

/// The smallest effect of one candidate this session can detect (80% power, first step).
#[derive(Debug, Clone, Serialize)]
pub struct DetectableReport {
    /// Candidate label, e.g. `robot 2 joint_offset joint 3`.
    pub label: String,
    /// Smallest detectable |value|, in `unit` (cell σ).
    pub value: f64,
    /// Unit.
    pub unit: &'static str,
}

/// Identifiability of one family.
#[derive(Debug, Clone, Serialize)]
pub struct FamilyReport {
    /// Robot, serialised as 1 or 2.
    pub robot: Robot,
    /// Kind.
    pub kind: EffectKind,
    /// Candidates in the family.
    pub size: usize,
    /// Rank after projecting out the base frames.
    pub rank: usize,
    /// Condition number of the unit-scaled projected columns (null when rank-deficient).
    pub condition: Option<f64>,
    /// Singular values (dimensionless, unit-scaled columns).
    pub singular_values: Vec<f64>,
    /// Members confounded with a base frame (absorbed by `b1_from_b2`).
    pub confounded_with_base: Vec<String>,
    /// For each member of `confounded_with_base` (same order), the base-frame motion it is
    /// equivalent to, e.g. `rotation of robot 1's base about its (0.000, 0.000, 1.000) axis
    /// (base yaw)`.
    pub confounded_as: Vec<String>,
    /// Members that do not move the tip at these configurations.
    pub no_effect: Vec<String>,
}

/// The diagnosis report (`--json` prints it).
#[derive(Debug, Clone, Serialize)]
pub struct DiagnoseReport {
    /// Named effects.
    pub effects: Vec<EffectReport>,
    /// Residual RMS (3-D per point) of the nominal fit, mm.
    pub rms_before_mm: f64,
    /// Residual RMS of the extended model, mm.
    pub rms_after_mm: f64,
    /// K-fold held-out residual RMS, nominal model, mm.
    pub heldout_rms_before_mm: f64,
    /// K-fold held-out residual RMS, extended model, mm.
    pub heldout_rms_after_mm: f64,
    /// Calibrated `b1_from_b2` (extended model).
    pub b1_from_b2: PoseReport,
    /// `b1_from_b2` of the nominal fit.
    pub b1_from_b2_before: PoseReport,
    /// Points diagnosed: the session's, less the rejected blunders.
    pub n_points: usize,
    /// Rows the blunder screen rejected (left out of everything else in this report), by
    /// point number, with their size in σ; empty when none (or when the screen is off).
    pub rejected_points: Vec<RejectedPointReport>,
    /// The cell's noise as an effective σ per axis at these configurations (alignment,
    /// repeatability of both robots and encoder resolution, RMS over points), mm.
    pub sigma_cell_mm: f64,
    /// σ estimated from the nominal fit, mm.
    pub sigma_hat_before_mm: f64,
    /// σ estimated from the extended fit, mm.
    pub sigma_hat_after_mm: f64,
    /// Predicted RMS under the cell's noise (MC median), mm.
    pub predicted_rms_mm: f64,
    /// MC 5–95% band of the predicted RMS, mm.
    pub predicted_rms_band_mm: [f64; 2],
    /// Fraction of MC trials whose RMS is below the measured one.
    pub measured_rms_percentile: f64,
    /// χ² test of RSS/σ² with 3n−6 dof: upper-tail p-value.
    pub chi2_p_value: f64,
    /// Significant residual correlations of the nominal fit (Bonferroni 5%).
    pub correlations: Vec<CorrelationReport>,
    /// Significant residual correlations left by the extended model (Bonferroni 5%).
    pub correlations_after: Vec<CorrelationReport>,
    /// χ² test of the extended model's (whitened) RSS/σ² with its residual dof: upper-tail p.
    pub chi2_p_value_after: f64,
    /// Identifiability per family.
    pub families: Vec<FamilyReport>,
    /// Smallest detectable |value| per identifiable candidate under this session's design and
    /// the cell's σ.
    pub min_detectable: Vec<DetectableReport>,
    /// Groups of mutually confounded candidates (labels).
    pub confounded_groups: Vec<Vec<String>>,
    /// Predicted 1-σ translation error of `b1_from_b2`, before / after, mm.
    pub predicted_e_tran_mm: [f64; 2],
    /// Predicted 1-σ rotation error, before / after, degrees.
    pub predicted_e_rot_deg: [f64; 2],
    /// e_tran against the truth, before / after, mm (when truth given).
    pub truth_e_tran_mm: Option<[f64; 2]>,
    /// e_rot (eq 33: ZYZ angles, branch nearest the truth, wrapped, ∞-norm) against the truth,
    /// before / after, degrees (when truth given).
    pub truth_e_rot_deg: Option<[f64; 2]>,
    /// Geodesic rotation error against the truth, before / after, degrees (when truth given).
    pub truth_geodesic_deg: Option<[f64; 2]>,
    /// Re-simulation with the extended model: MC median of the nominal-fit RMS it predicts, mm
    /// (to compare with `rms_before_mm`), and the measured RMS's percentile in it.
    pub resimulated_rms_before_mm: f64,
    /// Percentile of the measured nominal RMS in the re-simulated distribution.
    pub resimulated_percentile: f64,
    /// 5–95% band of the re-simulated nominal-fit RMS, mm.
    pub resimulated_rms_band_mm: [f64; 2],
    /// Percentile of the extended model's residual RMS among noise-only simulations of a
    /// correct model (near 50% when the extended model explains the data).
    pub rms_after_percentile: f64,
    /// The calibrated `b1_from_b2` against the cell's stated one (mount tilts).
    pub placement: PlacementReport,
    /// Selection steps in words.
    pub steps: Vec<String>,
    /// Whether the final LM fit converged.
    pub converged: bool,
    /// The session's coverage: per joint, the range it spans against the limits; per robot,
    /// its tool points' region against the sampled reach (`calib_core::whole_cell::session_coverage`).
    /// Set by the caller that holds the session as `handclasp_cell::Session` (the `handclasp`
    /// CLI); `None`, and left out of the JSON, otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<calib_core::whole_cell::CoverageReport>,
}

/// The report of what [`crate::diagnose_session`] found: every unit conversion to mm and
/// degrees happens here.
pub(crate) fn assemble(f: &Findings<'_>) -> DiagnoseReport {
    let (sel, cands) = (f.sel, f.cands);
    let (base, fit) = (&sel.baseline, &sel.fit);
    let mm = |v: f64| v * MM_PER_M;
    let label = |m: usize| cands[m].label();
    let mut effects: Vec<EffectReport> = fit
        .params
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            let c = &cands[p];
            let to = c.kind().to_output();
            let (lo, hi) = fit.interval(k, 0.95);
            EffectReport {
                kind: c.kind(),
                robot: c.robot(),
                joint: c.joint().map(|j| j + 1),
                axis: c.axis().map(kinematics::Axis::name),
                value: fit.values[k] * to,
                unit: c.kind().unit(),
                ci95: [lo * to, hi * to],
                confounded_with: sel
                    .groups
                    .get(k)
                    .map(|g| g.iter().map(|&m| label(m)).collect())
                    .unwrap_or_default(),
                p_value: f.partial_p[k],
            }
        })
        .collect();
    effects.extend(mount_tilt_effects(&f.placement.mount_tilt));
    let steps = sel
        .steps
        .iter()
        .map(|s| {
            format!(
                "{}: {} (F = {:.2}, p = {:.2e} vs α/m = {:.2e} over {} screened; held-out RMS {:.4} → {:.4} mm; BIC {:.1} → {:.1})",
                label(s.param),
                if s.accepted { "accepted" } else { "rejected" },
                s.f_stat, s.p_value, s.threshold, s.screened,
                mm(s.heldout_rms_before), mm(s.heldout_rms_after), s.bic_before, s.bic_after
            )
        })
        .collect();
    let (mc, remc) = (&f.baseline.mc_rms, &f.gain.resimulated_rms);
    let truth = f.gain.truth.as_ref();
    let deg = |v: [f64; 2]| v.map(f64::to_degrees);
    DiagnoseReport {
        effects,
        rms_before_mm: mm(base.rms()),
        rms_after_mm: mm(fit.rms()),
        heldout_rms_before_mm: mm(sel.heldout_rms_before),
        heldout_rms_after_mm: mm(sel.heldout_rms_after),
        b1_from_b2: PoseReport::from_isometry(&fit.b1_from_b2, f.reference_zyz),
        b1_from_b2_before: PoseReport::from_isometry(&base.b1_from_b2, f.reference_zyz),
        n_points: f.n_points,
        rejected_points: f.rejected.clone(),
        sigma_cell_mm: mm(f.sigma_m),
        sigma_hat_before_mm: mm(base.sigma_hat),
        sigma_hat_after_mm: mm(fit.sigma_hat),
        predicted_rms_mm: mm(quantile(mc, 0.5)),
        predicted_rms_band_mm: [mm(quantile(mc, 0.05)), mm(quantile(mc, 0.95))],
        measured_rms_percentile: fraction_below(mc, base.rms()),
        chi2_p_value: f.baseline.chi2_p,
        correlations: f.baseline.correlations.clone(),
        correlations_after: f.baseline.correlations_after.clone(),
        chi2_p_value_after: f.baseline.chi2_p_after,
        families: f.families.clone(),
        min_detectable: f
            .min_detectable
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(m, v)| DetectableReport {
                label: label(m),
                value: v * cands[m].kind().to_output(),
                unit: cands[m].kind().unit(),
            })
            .collect(),
        confounded_groups: sel
            .identifiability
            .groups
            .iter()
            .map(|g| g.iter().map(|&m| label(m)).collect())
            .collect(),
        predicted_e_tran_mm: [
            mm(base.predicted_translation_error()),
            mm(fit.predicted_translation_error()),
        ],
        predicted_e_rot_deg: [
            base.predicted_rotation_error().to_degrees(),
            fit.predicted_rotation_error().to_degrees(),
        ],
        truth_e_tran_mm: truth.map(|t| t.e_tran_m.map(mm)),
        truth_e_rot_deg: truth.map(|t| deg(t.e_rot_rad)),
        truth_geodesic_deg: truth.map(|t| deg(t.geodesic_rad)),
        resimulated_rms_before_mm: mm(quantile(remc, 0.5)),
        resimulated_percentile: fraction_below(remc, base.rms()),
        resimulated_rms_band_mm: [mm(quantile(remc, 0.05)), mm(quantile(remc, 0.95))],
        rms_after_percentile: fraction_below(mc, fit.rms()),
        placement: PlacementReport::from_placement(&f.placement),
        steps,
        converged: fit.converged(),
        coverage: None,
    }
}

/// The mount tilts the test names ([`MountTiltFit::named_components`]), as effects.
fn mount_tilt_effects(test: &MountTiltFit) -> Vec<EffectReport> {
    let Some(robot) = test.robot else {
        return Vec::new();
    };
    let number = robot.number();
    test.named_components()
        .into_iter()
        .map(|k| {
            let axis = if k == 0 { "x" } else { "y" };
            let kind = EffectKind::MountTilt;
            EffectReport {
                kind,
                robot,
                joint: None,
                axis: Some(axis),
                value: test.tilt_rad[k].to_degrees(),
                unit: kind.unit(),
                ci95: test.tilt_ci95_rad[k].map(f64::to_degrees),
                confounded_with: std::iter::once(format!("robot {number} mount_tilt {axis}"))
                    .chain(test.alternative.iter().flat_map(|&r| {
                        test.alternative_axes
                            .iter()
                            .map(move |a| format!("robot {} mount_tilt {}", r.number(), a.name()))
                    }))
                    .collect(),
                p_value: test.tilt_p_value[k],
            }
        })
        .collect()
}

/// Readable text of a report.
pub fn render_text(r: &DiagnoseReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "handclasp diagnose: {} points, cell noise σ = {:.3} mm per axis (alignment, repeatability, encoders; effective)",
        r.n_points, r.sigma_cell_mm
    );
    if !r.rejected_points.is_empty() {
        let _ = writeln!(
            s,
            "\n0. Blunders: {} rows rejected by the whole-cell screen (studentised residual above the Bonferroni limit) \
             and left out of everything below; re-record them:",
            r.rejected_points.len()
        );
        for b in &r.rejected_points {
            let _ = writeln!(
                s,
                "   point {:>4}: {:.1} σ (residual {:.3} mm)",
                b.point, b.size_sigma, b.residual_mm
            );
        }
    }
    let _ = writeln!(s, "\n1. Baseline (nominal models)");
    let _ = writeln!(
        s,
        "   residual RMS {:.3} mm; predicted under the cell's noise {:.3} mm (5–95%: {:.3}–{:.3}); measured at MC percentile {:.1}%",
        r.rms_before_mm, r.predicted_rms_mm, r.predicted_rms_band_mm[0], r.predicted_rms_band_mm[1], 100.0 * r.measured_rms_percentile
    );
    let _ = writeln!(
        s,
        "   χ² test of RSS/σ²: p = {:.3e} ({}); σ̂ = {:.3} mm per axis",
        r.chi2_p_value,
        if r.chi2_p_value < 0.05 {
            "the nominal model does NOT explain the data"
        } else {
            "consistent with noise"
        },
        r.sigma_hat_before_mm
    );
    if r.correlations.is_empty() {
        let _ = writeln!(s, "   no significant residual correlation (Bonferroni 5%)");
    }
    for c in &r.correlations {
        let _ = writeln!(
            s,
            "   residual {} correlates with {}: r = {:+.2} (adjusted p = {:.1e})",
            c.residual, c.against, c.r, c.p_adjusted
        );
    }
    let _ = writeln!(
        s,
        "\n2. Identifiability from these handclasps (rank / size, condition)"
    );
    for f in &r.families {
        let cond = f.condition.map_or("∞".to_string(), |c| format!("{c:.1}"));
        let _ = write!(
            s,
            "   robot {} {:<13} rank {}/{} cond {}",
            f.robot.number(),
            f.kind.name(),
            f.rank,
            f.size,
            cond
        );
        if !f.confounded_with_base.is_empty() {
            let pairs: Vec<String> = f
                .confounded_with_base
                .iter()
                .zip(&f.confounded_as)
                .map(|(c, a)| format!("{c} ≡ {a}"))
                .collect();
            let _ = write!(s, "; confounded with the base frame: {}", pairs.join("; "));
        }
        if !f.no_effect.is_empty() {
            let _ = write!(s, "; no effect here: {}", f.no_effect.join(", "));
        }
        let _ = writeln!(s);
    }
    for g in &r.confounded_groups {
        let _ = writeln!(s, "   indistinguishable: {}", g.join(" ≡ "));
    }
    let _ = writeln!(s, "\n3. Model selection");
    for st in &r.steps {
        let _ = writeln!(s, "   {st}");
    }
    if r.effects.is_empty() {
        let _ = writeln!(s, "   no significant effect: noise alone explains the data");
    }
    for e in &r.effects {
        let _ = writeln!(
            s,
            "   {} robot {}{}{}: {:+.4} {} (95%: {:+.4} … {:+.4}){}",
            e.kind.name(),
            e.robot.number(),
            e.joint.map_or(String::new(), |j| format!(" joint {j}")),
            e.axis.map_or(String::new(), |a| format!(" axis {a}")),
            e.value,
            e.unit,
            e.ci95[0],
            e.ci95[1],
            if e.kind == EffectKind::MountTilt {
                format!(
                    " [from the placement check, section 5{}]",
                    if e.confounded_with.len() > 1 {
                        format!("; or any of: {}", e.confounded_with.join(", "))
                    } else {
                        String::new()
                    }
                )
            } else if e.confounded_with.len() > 1 {
                format!(" [or any of: {}]", e.confounded_with.join(", "))
            } else {
                String::new()
            }
        );
    }
    let _ = writeln!(s, "\n4. Gain");
    let _ = writeln!(
        s,
        "   residual RMS {:.3} → {:.3} mm; held-out (K-fold) {:.3} → {:.3} mm",
        r.rms_before_mm, r.rms_after_mm, r.heldout_rms_before_mm, r.heldout_rms_after_mm
    );
    let _ = writeln!(
        s,
        "   predicted b1_from_b2 accuracy: {:.3} → {:.3} mm, {:.4} → {:.4} deg (1σ)",
        r.predicted_e_tran_mm[0],
        r.predicted_e_tran_mm[1],
        r.predicted_e_rot_deg[0],
        r.predicted_e_rot_deg[1]
    );
    if let (Some(t), Some(a), Some(g)) =
        (r.truth_e_tran_mm, r.truth_e_rot_deg, r.truth_geodesic_deg)
    {
        let _ = writeln!(
            s,
            "   against the truth: e_tran {:.3} → {:.3} mm, e_rot {:.4} → {:.4} deg (geodesic {:.4} → {:.4} deg)",
            t[0], t[1], a[0], a[1], g[0], g[1]
        );
    }
    let _ = writeln!(
        s,
        "   re-simulated with the extended model: nominal-fit RMS {:.3} mm predicted vs {:.3} measured (percentile {:.1}%)",
        r.resimulated_rms_before_mm, r.rms_before_mm, 100.0 * r.resimulated_percentile
    );
    let _ = writeln!(
        s,
        "   extended model's residual RMS at percentile {:.1}% of noise-only simulations of a correct model; χ² p = {:.3}; {} significant residual correlation(s) left",
        100.0 * r.rms_after_percentile,
        r.chi2_p_value_after,
        r.correlations_after.len()
    );
    let _ = writeln!(
        s,
        "   b1_from_b2: xyz {:.3?} mm, zyz {:.4?} deg",
        r.b1_from_b2.xyz_mm, r.b1_from_b2.zyz_deg
    );
    let p = &r.placement;
    let _ = writeln!(
        s,
        "\n5. Placement against the cell's b1_from_b2 (mount tilts: invisible in the residuals)"
    );
    let _ = writeln!(
        s,
        "   turn of base 2 about its x: {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}); about its y: {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}); about its z: {:+.4} deg",
        p.tilt_b2_deg[0],
        p.tilt_b2_ci95_deg[0][0],
        p.tilt_b2_ci95_deg[0][1],
        p.tilt_b2_p_value[0],
        p.tilt_b2_deg[1],
        p.tilt_b2_ci95_deg[1][0],
        p.tilt_b2_ci95_deg[1][1],
        p.tilt_b2_p_value[1],
        p.yaw_b2_deg
    );
    let _ = writeln!(
        s,
        "   translation minus the cell's: {:+.3?} mm (s.e. {:.3?} mm)",
        p.dxyz_mm, p.dxyz_se_mm
    );
    if p.tilt_significant {
        let _ = writeln!(
            s,
            "   significant turn (Bonferroni 5%): as a turn of robot 2's base as above, or of robot 1's by {:+.4?} deg \
             about its x, y, z (which would also move the translation by −a1 × t)",
            p.robot1_equivalent_deg
        );
    } else {
        let _ = writeln!(s, "   no significant turn against the cell's placement");
    }
    let m = &p.mount_tilt;
    let _ = writeln!(
        s,
        "   mount-tilt test (rotation and translation; base yaws are nuisances): χ² no tilt {:.2} ({} dof, p = {:.2e}), \
         robot 1 tilted {:.2} ({} dof), robot 2 tilted {:.2} ({} dof)",
        m.chi2[0], m.dof[0], m.p_no_tilt, m.chi2[1], m.dof[1], m.chi2[2], m.dof[2]
    );
    match m.robot {
        None => {
            let _ = writeln!(
                s,
                "   no mount tilt (level {ALPHA_TILT}): the cell's placement explains the fit up to base yaws"
            );
        }
        Some(r) if m.p_fit < ALPHA_TILT => {
            let r = r.number();
            let _ = writeln!(
                s,
                "   the placement differs from the cell's (p = {:.2e}) but no mount tilt explains it (best: robot {r}, \
                 χ² p = {:.2e}): a wrong cell placement or a base-frame translation; nothing named",
                m.p_no_tilt, m.p_fit
            );
        }
        Some(r) => {
            let r = r.number();
            let _ = writeln!(
                s,
                "   robot {r}'s mount is tilted: x {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}), y {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}); \
                 significant components (p < {}) are named in 3.{}",
                m.tilt_deg[0], m.tilt_ci95_deg[0][0], m.tilt_ci95_deg[0][1], m.tilt_p_value[0],
                m.tilt_deg[1], m.tilt_ci95_deg[1][0], m.tilt_ci95_deg[1][1], m.tilt_p_value[1],
                ALPHA_TILT / 2.0,
                m.alternative.map_or(String::new(), |a| format!(
                    " (robot {}'s tilt about {} explains it as well — a turn about the line joining the bases; \
                     the fewer components chosen)",
                    a.number(),
                    m.alternative_axes.join(", ")
                ))
            );
        }
    }
    if let Some(c) = &r.coverage {
        for line in c.text_lines() {
            let _ = writeln!(s, "{line}");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Robots serialise as 1/2 (or null), as the JSON always did.
    #[test]
    fn robots_serialise_as_numbers() {
        let e = EffectReport {
            kind: EffectKind::JointOffset,
            robot: Robot::Two,
            joint: Some(3),
            axis: None,
            value: 0.1,
            unit: "deg",
            ci95: [0.0, 0.2],
            confounded_with: vec![],
            p_value: 0.5,
        };
        let json = serde_json::to_string(&e).unwrap();
        assert!(
            json.starts_with(r#"{"kind":"joint_offset","robot":2,"joint":3,"axis":null,"#),
            "{json}"
        );
        assert_eq!(serde_json::to_string(&Some(Robot::One)).unwrap(), "1");
        assert_eq!(serde_json::to_string(&None::<Robot>).unwrap(), "null");
    }
}
