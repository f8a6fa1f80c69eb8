//! The report of the whole-cell diagnosis ([`crate::diagnose_cell_session`]) in mm, mrad and
//! degrees (field names carry the unit), and its text rendering ([`render_cell_text`]).

use std::fmt::Write as _;

use calib_core::whole_cell::{CellEstimate, CellFit, CellParam, CellProblem, Noise3};
use calib_core::Robot;
use kinematics::ErrorParam;
use serde::ser::SerializeMap;
use serde::{Serialize, Serializer};

use crate::cell_diagnosis::{
    residuals_at, CellDiagnoseOptions, CellDiagnosis, Family, FamilyKind, HeldOut, NotSelected,
    ScoredRow, KINDS, Z95,
};

/// Number of bins of the residual-against-joint table (quartiles of the joint's values).
pub const JOINT_BINS: usize = 4;

/// The text lists the parameters of a rejected family that the data determine: those whose
/// 95 % interval excludes 0, those without a prior (tracker scales and drifts), and those whose
/// σ is below this fraction of the prior σ; the others' intervals are their prior's, and are in
/// the JSON only.
pub const REJECTED_TEXT_PRIOR_FRACTION: f64 = 0.5;

/// The whole-cell diagnosis of a session.
#[derive(Debug, Clone, Serialize)]
pub struct CellDiagnoseReport {
    /// `"whole_cell"` (the coincident-only report has no such field).
    pub mode: &'static str,
    /// Rows of each kind in the session: contact, tracker, plane, coincident.
    pub rows_by_kind: Vec<KindCount>,
    /// Rows used after the blunder screen.
    pub rows_used: usize,
    /// Rows rejected by the blunder screen.
    pub rejected_points: Vec<CellRejectedReport>,
    /// Every tolerance of the cell times this is the diagnosis prior.
    pub prior_widening: f64,
    /// Held-out units (groups and coincident blocks) and folds.
    pub held_out_units: usize,
    /// Folds of the held-out criterion.
    pub held_out_folds: usize,
    /// The candidate families.
    pub candidates: Vec<Family>,
    /// The nominal model (nuisances fitted): residual per kind against its stated σ, fitted
    /// and held out.
    pub baseline: Vec<KindResidual>,
    /// The selected families in order, with values, intervals and held-out gains.
    pub effects: Vec<CellEffectReport>,
    /// The best candidate that was not accepted (why the selection stopped), if any.
    pub stopped_at: Option<StepSummary>,
    /// Held-out χ² of every candidate tried at the step that stopped the selection (empty when
    /// it stopped for want of candidates or steps); compare with `stopped_at`'s
    /// `held_out_chi2_before`.
    pub stopped_candidates_held_out_chi2: Vec<(String, f64)>,
    /// Each candidate tried at the step that stopped the selection, in candidate order: its
    /// held-out change and its value had it been added to the final model (empty when the
    /// selection stopped for want of candidates or steps).
    pub rejected_families: Vec<RejectedFamilyReport>,
    /// Whether the rows used determine `b1_from_b2` (a coincident or contact row, or a tracker
    /// or plane group with rows of both robots). Without them the fit holds the placement where
    /// it started and `--export` writes the input cell's.
    pub placement_fitted: bool,
    /// The final model: residual per kind against its stated σ.
    pub final_residuals: Vec<KindResidual>,
    /// `max(1, sqrt(χ²/(rows − unknowns)))` of the final fit; it multiplies every posterior σ.
    pub variance_factor: f64,
    /// Solver iterations and stop reason of the final fit.
    pub final_fit_stopped: String,
    /// The final fit's estimate, SI (not serialised: `effects` reports its named parameters).
    /// Its robot corrections (the named families; zero elsewhere) and placement are cell
    /// properties, which [`crate::export_cell_diagnosis`] writes; its nuisance groups are
    /// numbered over the rows used (the blunder screen may drop a whole group), not the
    /// session's.
    #[serde(skip)]
    pub final_estimate: CellEstimate,
    /// The session's coverage: per joint, the range it spans against the limits; per robot,
    /// its tool points' region against the sampled reach (`calib_core::whole_cell::session_coverage`).
    /// Set by the caller that holds the session as `handclasp_cell::Session` (the `handclasp`
    /// CLI); `None`, and left out of the JSON, otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<calib_core::whole_cell::CoverageReport>,
    /// The selection's step cap (`--max-steps`).
    pub max_steps: usize,
    /// True when the selection stopped at [`Self::max_steps`] while still accepting families
    /// (more may be missing).
    pub step_cap_hit: bool,
    /// The blunder screen's rejections classified as a model misfit (every row then kept);
    /// `null` when the screen found blunders only, or none.
    pub screen_misfit: Option<calib_core::whole_cell::RejectionPattern>,
    /// What the caller prints after `warning:`: the step cap hit, a tracker scale beyond any
    /// device of its class, a screen misfit.
    pub warnings: Vec<String>,
    /// What the caller prints after `note:`: the recording-only terms selected (tracker scale,
    /// drift) and what the export does with them.
    pub notes: Vec<String>,
    /// How the held-out folds were made (joint-space regions or the session's groups), and
    /// each fold.
    pub folds: crate::do_no_harm::FoldsReport,
    /// The do-no-harm export rule: each accepted step's model against nominal per fold, and
    /// the families the export keeps and withholds.
    pub do_no_harm: crate::do_no_harm::DoNoHarmReport,
    /// The estimate `--export` writes: the fit of the families the rule keeps (the placement
    /// only when it keeps none), SI; `final_estimate` when nothing is withheld (not
    /// serialised).
    #[serde(skip)]
    pub export_estimate: CellEstimate,
    /// The fit `export_estimate` comes from, with its problem (the diagnosis's: tolerances ×
    /// [`Self::prior_widening`], each kind's σ scaled by its noise level, the rows used): what
    /// the verdict at the work site of the exported model is predicted from (not serialised).
    #[serde(skip)]
    pub export_model: FittedModel,
    /// The same for the full model (`final_estimate`: every named family, what
    /// `diagnose --export --force` writes; not serialised).
    #[serde(skip)]
    pub full_model: FittedModel,
}

impl CellDiagnoseReport {
    /// The do-no-harm warning the CLI prints after `warning:` when the rule withholds families
    /// ([`crate::do_no_harm::DoNoHarmReport::warning`], the folds named as this report's
    /// design names them), `keep` the way to export the full model (`--force` in the CLI);
    /// `None` when nothing is withheld.
    pub fn do_no_harm_warning(&self, keep: &str) -> Option<String> {
        let fold_word = if self.folds.design == crate::cell_diagnosis::FoldDesign::JointRegions {
            "region"
        } else {
            "fold"
        };
        self.do_no_harm.warning(fold_word, keep)
    }
}

/// One model of the diagnosis fitted on the rows used: its problem (the diagnosis's,
/// restricted to the rows used, with the model's families free) and its fit, SI.
#[derive(Debug, Clone)]
pub struct FittedModel {
    /// The problem the fit is of (its observations are the rows used, renumbered).
    pub problem: CellProblem,
    /// The fit, with its posterior covariance.
    pub fit: CellFit,
}

/// A laser tracker's largest credible scale error, ppm. Leica's AT960 states a maximum
/// permissible error of ±(15 µm + 6 µm/m) (ISO 10360-10): 6 ppm of length, so ±50 ppm is
/// several times what a working laser tracker shows.
pub const LASER_TRACKER_SCALE_PPM: f64 = 50.0;
/// A motion-capture system's largest credible scale error, ppm (±0.2 %): a wand calibration
/// (OptiTrack, Vicon) leaves a mean 3-D error of a few tenths of a mm over a volume of metres,
/// ~0.01–0.1 % of length.
pub const MOTION_CAPTURE_SCALE_PPM: f64 = 2000.0;
/// Tracker rows with a stated σ at most this (m) are taken as a laser tracker's; above, as
/// motion capture's (0.1 mm).
pub const LASER_TRACKER_MAX_SIGMA_M: f64 = 1e-4;

/// The warnings and notes of a diagnosis (see [`CellDiagnoseReport::warnings`] and
/// [`CellDiagnoseReport::notes`]).
fn findings(
    d: &CellDiagnosis,
    effects: &[CellEffectReport],
    options: &CellDiagnoseOptions,
    step_cap_hit: bool,
) -> (Vec<String>, Vec<String>) {
    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    if step_cap_hit {
        warnings.push(format!(
            "the selection stopped at its step cap ({} steps, --max-steps) while still              accepting families: more effects may be missing; re-run with a higher --max-steps",
            options.max_steps
        ));
    }
    let mut sigmas: Vec<f64> = d
        .problem
        .observations
        .iter()
        .filter_map(|o| match &o.kind {
            calib_core::whole_cell::ObservationKind::Tracker { noise, .. } => Some(match noise {
                Noise3::Isotropic { sigma_m } => *sigma_m,
                Noise3::Covariance { cov_m2 } => (cov_m2.trace() / 3.0).sqrt(),
                _ => f64::INFINITY,
            }),
            _ => None,
        })
        .collect();
    sigmas.sort_by(f64::total_cmp);
    let laser = sigmas
        .get(sigmas.len() / 2)
        .is_some_and(|s| *s <= LASER_TRACKER_MAX_SIGMA_M);
    let (bound, device) = if laser {
        (
            LASER_TRACKER_SCALE_PPM,
            "a laser tracker (its rows' σ ≤ 0.1 mm)",
        )
    } else {
        (
            MOTION_CAPTURE_SCALE_PPM,
            "motion capture (its rows' σ > 0.1 mm)",
        )
    };
    let mut recording = Vec::new();
    for e in effects {
        match e.family.kind {
            FamilyKind::TrackerScale => {
                recording.push(e.family.name.clone());
                for p in &e.parameters {
                    if p.value.abs() > bound {
                        warnings.push(format!(
                            "{}: {:+.0} ppm is beyond what {device} can have (±{bound:.0} ppm;                              laser trackers ±{LASER_TRACKER_SCALE_PPM:.0} ppm from Leica AT960's                              MPE ±(15 µm + 6 µm/m), motion capture ±0.2 % from OptiTrack/Vicon                              wand-calibration accuracy): a likely stand-in for an unmodelled                              effect (e.g. gravity sag); look at the other families before                              trusting it",
                            p.name, p.value
                        ));
                    }
                }
            }
            FamilyKind::TrackerDrift => recording.push(e.family.name.clone()),
            _ => {}
        }
    }
    if !recording.is_empty() {
        notes.push(format!(
            "recording-only terms selected ({}): they describe this recording, not the cell.              They are kept in the fit the export comes from (the exported robots were fitted              with them in the model); the exported cell does not carry them, so a session              scored without them sees larger residuals than this report's",
            recording.join(", ")
        ));
    }
    notes.extend(compliance_notes(&d.problem, &d.candidates));
    if let Some(p) = &d.screen_misfit {
        warnings.push(format!(
            "model misfit, not blunders: {}; every row kept (--screen auto; --screen strict              rejects them)",
            p.describe()
        ));
    }
    (warnings, notes)
}

/// What the report says about each robot's gravity compliance when its URDF has no masses:
/// tested as lumped coefficients, or not tested and why ("compliance not tested: …").
fn compliance_notes(
    problem: &calib_core::whole_cell::CellProblem,
    candidates: &[crate::cell_diagnosis::Family],
) -> Vec<String> {
    let mut notes = Vec::new();
    for r in [calib_core::Robot::One, calib_core::Robot::Two] {
        let rb = problem.robot(r);
        let used = problem
            .observations
            .iter()
            .any(|o| o.kind.tools().iter().any(|(rr, _)| *rr == r));
        let has = |k: FamilyKind| {
            candidates
                .iter()
                .any(|f| (f.robot == Some(r.number()) || f.trunk) && f.kind == k)
        };
        if !used || has(FamilyKind::Compliance) {
            continue;
        }
        if has(FamilyKind::LumpedCompliance) {
            notes.push(format!(
                "{r}: its URDF has no inertials (masses), so joint compliance was tested as \
                 lumped coefficients (compliance × mass moment, which need no masses; \
                 calibrate --cell --model kinematic+compliance fits them)"
            ));
            continue;
        }
        let why = if rb.tolerance.joint_offset_rad == 0.0 {
            "its joint offsets are held (tolerance 0), and the compliance prior is scaled from \
             them"
                .to_string()
        } else if kinematics::lumped_params(&rb.model).is_empty() {
            "its URDF has no inertials and no rotary joint carries only rotary joints (the \
             lumped coefficients' scope)"
                .to_string()
        } else {
            "its URDF's masses give no gravity torque at the session's postures".to_string()
        };
        notes.push(format!("{r} compliance not tested: {why}"));
    }
    notes
}

/// Rows of one kind.
#[derive(Debug, Clone, Serialize)]
pub struct KindCount {
    /// Observation kind.
    pub kind: &'static str,
    /// Rows.
    pub rows: usize,
}

/// A rejected row.
#[derive(Debug, Clone, Serialize)]
pub struct CellRejectedReport {
    /// The row's point number (the CSV's `point` column).
    pub point: usize,
    /// Its kind.
    pub kind: &'static str,
    /// Its studentised size, σ.
    pub size_sigma: f64,
    /// Its residual norm, mm.
    pub residual_mm: f64,
}

/// Residual of one kind against its stated σ.
#[derive(Debug, Clone, Serialize)]
pub struct KindResidual {
    /// Observation kind.
    pub kind: &'static str,
    /// Scalar residual rows.
    pub residual_rows: usize,
    /// RMS of the fitted residuals per scalar residual row, mm: for the 3-D kinds (tracker,
    /// coincident) the rms per axis (of x, y and z together), `rms_3d_mm / √3`.
    pub rms_mm: f64,
    /// For the 3-D kinds (tracker, coincident), the rms of the 3-D residual's length ‖r‖ over
    /// the rows, mm (the figure a tracker's or a handclasp's distance error is compared with);
    /// `None` (JSON `null`) for the 1-D kinds (contact, plane), whose `rms_mm` is already that.
    pub rms_3d_mm: Option<f64>,
    /// RMS of the stated σ, mm.
    pub stated_sigma_mm: f64,
    /// `rms_mm / stated_sigma_mm` (1 = as stated).
    pub rms_over_sigma: f64,
    /// The kind's noise scale: its σ is multiplied by this in the diagnosis (see
    /// [`crate::cell_diagnosis`], step 2).
    pub noise_scale: f64,
    /// RMS of the held-out residuals of this model, mm; `None` (JSON `null`) when no row of
    /// this kind was held out (its groups are too small to refit their nuisance on half the
    /// rows, see [`crate::cell_diagnosis::MIN_SCORED_GROUP_ROWS`]).
    pub held_out_rms_mm: Option<f64>,
    /// `held_out_rms_mm` as the rms of the 3-D residual's length, for the 3-D kinds; `None`
    /// otherwise or when no row of the kind was held out.
    pub held_out_rms_3d_mm: Option<f64>,
}

/// A candidate at a selection step.
#[derive(Debug, Clone, Serialize)]
pub struct StepSummary {
    /// The family.
    pub family: String,
    /// Held-out χ² before and after adding it.
    pub held_out_chi2_before: f64,
    /// Held-out χ² with it.
    pub held_out_chi2_after: f64,
    /// Relative decrease of the held-out χ².
    pub relative_gain: f64,
    /// t statistic of the per-unit relative held-out gains.
    pub gain_t: f64,
}

/// One selected family.
#[derive(Debug, Clone, Serialize)]
pub struct CellEffectReport {
    /// 1-based selection step.
    pub step: usize,
    /// The family.
    pub family: Family,
    /// The held-out gain that selected it.
    pub gain: StepSummary,
    /// Held-out rms per kind before and after this step, mm.
    pub held_out_by_kind: Vec<KindGain>,
    /// Its parameters in the final model, with 95 % intervals.
    pub parameters: Vec<ParamValue>,
    /// Whitened residual rms against each joint before and after this step.
    pub residual_vs_joint: Vec<JointTrend>,
    /// Held-out χ² of every candidate cross-validated at this step (every candidate with
    /// [`CellDiagnoseOptions::refit_every_candidate`]; else those the linearised prediction did
    /// not rule out).
    pub candidates_held_out_chi2: Vec<(String, f64)>,
    /// Each candidate the linearised prediction ruled out at this step (not cross-validated),
    /// with the lower end of its predicted held-out χ² (the prediction less
    /// [`crate::cell_diagnosis::held_out_prediction_slack`]), above this family's held-out χ².
    /// Empty with [`CellDiagnoseOptions::refit_every_candidate`].
    pub candidates_ruled_out: Vec<(String, f64)>,
}

/// A candidate family that was not named: tried at the step that stopped the selection, it
/// failed the criterion (see [`crate::cell_diagnosis`], step 5). What it would be had it been
/// named.
#[derive(Debug, Clone, Serialize)]
pub struct RejectedFamilyReport {
    /// The family.
    pub family: Family,
    /// Its held-out change against the final model (`held_out_chi2_before` is the final
    /// model's; a negative `relative_gain` is a held-out χ² that rose).
    pub gain: StepSummary,
    /// Why it was rejected, e.g. `held-out χ² +1.9 %, a decrease of ≥ 1 % is needed`.
    pub reason: String,
    /// Held-out rms per kind, final model and with the family added, mm.
    pub held_out_by_kind: Vec<KindGain>,
    /// Its parameters fitted with the family added to the final model on all screened rows,
    /// with 95 % intervals (posterior σ times that fit's `variance_factor`).
    pub parameters: Vec<ParamValue>,
    /// `max(1, sqrt(χ²/(rows − unknowns)))` of that fit.
    pub variance_factor: f64,
}

/// Held-out rms of one kind before and after a step.
#[derive(Debug, Clone, Serialize)]
pub struct KindGain {
    /// Observation kind.
    pub kind: &'static str,
    /// Before, mm.
    pub rms_mm_before: f64,
    /// After, mm.
    pub rms_mm_after: f64,
}

/// Unit of a reported parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ParamUnit {
    /// Millimetres (positions, tip offsets, contact distances, a tracker's drift over its
    /// whole recording).
    Mm,
    /// Milliradians (joint offsets, origin angles, joint-periodic amplitudes).
    Mrad,
    /// Microradians per newton-metre (compliance).
    UradPerNm,
    /// Parts per million (joint scale, tracker scale).
    Ppm,
}

impl ParamUnit {
    /// The suffix of the JSON field names.
    pub fn suffix(self) -> &'static str {
        match self {
            ParamUnit::Mm => "mm",
            ParamUnit::Mrad => "mrad",
            ParamUnit::UradPerNm => "urad_per_nm",
            ParamUnit::Ppm => "ppm",
        }
    }

    /// Report units per SI unit.
    pub fn per_si(self) -> f64 {
        match self {
            ParamUnit::Mm | ParamUnit::Mrad => 1e3,
            ParamUnit::UradPerNm | ParamUnit::Ppm => 1e6,
        }
    }

    /// The unit of a cell unknown.
    pub fn of(p: &CellParam) -> ParamUnit {
        match p {
            CellParam::Kinematic { param, .. } => match param {
                ErrorParam::JointOffset { .. }
                | ErrorParam::OriginRpy { .. }
                | ErrorParam::PeriodicSin { .. }
                | ErrorParam::PeriodicCos { .. }
                | ErrorParam::LumpedCompliance { .. } => ParamUnit::Mrad,
                ErrorParam::Compliance { .. } => ParamUnit::UradPerNm,
                ErrorParam::JointScale { .. } => ParamUnit::Ppm,
                _ => ParamUnit::Mm,
            },
            CellParam::PlacementRotation { .. }
            | CellParam::TrackerRotation { .. }
            | CellParam::PlaneNormal { .. } => ParamUnit::Mrad,
            CellParam::TrackerScale { .. } => ParamUnit::Ppm,
            _ => ParamUnit::Mm,
        }
    }
}

/// One fitted parameter in report units. JSON: `name`, `value_<unit>`, `sigma_<unit>`,
/// `ci95_<unit>` `[low, high]`, `prior_sigma_<unit>`, `unit <unit>`.
#[derive(Debug, Clone)]
pub struct ParamValue {
    /// Readable name.
    pub name: String,
    /// Unit.
    pub unit: ParamUnit,
    /// Value.
    pub value: f64,
    /// Posterior σ times the variance factor.
    pub sigma: f64,
    /// Prior σ (the widened tolerance / √3).
    pub prior_sigma: f64,
}

impl ParamValue {
    /// The 95 % interval `value ± 1.96·σ`.
    pub fn ci95(&self) -> [f64; 2] {
        [self.value - Z95 * self.sigma, self.value + Z95 * self.sigma]
    }
}

impl Serialize for ParamValue {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let u = self.unit.suffix();
        let mut m = s.serialize_map(Some(6))?;
        m.serialize_entry("name", &self.name)?;
        m.serialize_entry("unit", u)?;
        m.serialize_entry(&format!("value_{u}"), &self.value)?;
        m.serialize_entry(&format!("sigma_{u}"), &self.sigma)?;
        m.serialize_entry(&format!("ci95_{u}"), &self.ci95())?;
        m.serialize_entry(&format!("prior_sigma_{u}"), &self.prior_sigma)?;
        m.end()
    }
}

/// Whitened residual rms of the rows of one robot in quartile bins of one joint.
#[derive(Debug, Clone, Serialize)]
pub struct JointTrend {
    /// Robot, 1 or 2.
    pub robot: u8,
    /// Joint, 1-based.
    pub joint: usize,
    /// Mean joint angle of each bin, degrees.
    pub q_deg: Vec<f64>,
    /// Whitened rms per bin before the step.
    pub rms_over_sigma_before: Vec<f64>,
    /// Whitened rms per bin after the step.
    pub rms_over_sigma_after: Vec<f64>,
}

impl JointTrend {
    /// Largest minus smallest bin rms, before and after.
    pub fn spread(&self) -> (f64, f64) {
        let s = |v: &[f64]| {
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - v.iter().copied().fold(f64::INFINITY, f64::min)
        };
        (
            s(&self.rms_over_sigma_before),
            s(&self.rms_over_sigma_after),
        )
    }
}

/// The rms of the 3-D residual's length over the rows of `kind`, mm; `None` when the kind has
/// no row or its rows are not 3-D.
fn kind_rms_3d(rows: &[ScoredRow], kind: &str) -> Option<f64> {
    let (mut n, mut raw) = (0usize, 0.0);
    for r in rows.iter().filter(|r| r.kind == kind) {
        if r.raw_m.len() != 3 {
            return None;
        }
        n += 1;
        raw += r.raw_m.norm_squared();
    }
    (n > 0).then(|| (raw / n as f64).sqrt() * 1e3)
}

fn kind_rms(rows: &[ScoredRow], kind: &str) -> Option<(usize, f64, f64, f64)> {
    let (mut n, mut raw, mut sig, mut wh) = (0usize, 0.0, 0.0, 0.0);
    for r in rows.iter().filter(|r| r.kind == kind) {
        n += r.raw_m.len();
        raw += r.raw_m.norm_squared();
        sig += r.sigma_m.norm_squared();
        wh += r.whitened.norm_squared();
    }
    (n > 0).then(|| {
        let m = n as f64;
        (
            n,
            (raw / m).sqrt() * 1e3,
            (sig / m).sqrt() * 1e3,
            (wh / m).sqrt(),
        )
    })
}

fn fit_rows(fit: &(CellProblem, CellFit)) -> Vec<ScoredRow> {
    let (p, f) = fit;
    residuals_at(p, &f.layout, &f.estimate, &f.active).unwrap_or_default()
}

fn kind_residuals(
    fitted: &[ScoredRow],
    held: &HeldOut,
    scale: &[f64; KINDS.len()],
) -> Vec<KindResidual> {
    KINDS
        .iter()
        .zip(scale)
        .filter_map(|(&k, &s)| {
            let (n, rms_mm, scaled_sigma_mm, _) = kind_rms(fitted, k.name())?;
            let stated_sigma_mm = scaled_sigma_mm / s;
            Some(KindResidual {
                kind: k.name(),
                residual_rows: n,
                rms_mm,
                rms_3d_mm: kind_rms_3d(fitted, k.name()),
                stated_sigma_mm,
                rms_over_sigma: rms_mm / stated_sigma_mm,
                noise_scale: s,
                held_out_rms_mm: kind_rms(&held.rows, k.name()).map(|v| v.1),
                held_out_rms_3d_mm: kind_rms_3d(&held.rows, k.name()),
            })
        })
        .collect()
}

fn summary(name: &str, before: &HeldOut, after: &HeldOut, t: f64) -> StepSummary {
    let (b, a) = (before.total(), after.total());
    StepSummary {
        family: name.to_string(),
        held_out_chi2_before: b,
        held_out_chi2_after: a,
        relative_gain: if b > 0.0 { (b - a) / b } else { 0.0 },
        gain_t: t,
    }
}

/// Whitened rms per quartile bin of each joint of each robot.
fn joint_bins(problem: &CellProblem, rows: &[ScoredRow]) -> Vec<(u8, usize, Vec<f64>, Vec<f64>)> {
    let mut out = Vec::new();
    for r in [Robot::One, Robot::Two] {
        for j in 0..problem.robot(r).model.dof() {
            let mut v: Vec<(f64, f64, usize)> = rows
                .iter()
                .filter_map(|s| {
                    problem.observations[s.index]
                        .kind
                        .joints()
                        .into_iter()
                        .find(|(rr, _)| *rr == r)
                        .map(|(_, q)| (q[j], s.whitened.norm_squared(), s.whitened.len()))
                })
                .collect();
            if v.len() < JOINT_BINS {
                continue;
            }
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            let size = v.len().div_ceil(JOINT_BINS);
            let (q, rms): (Vec<f64>, Vec<f64>) = v
                .chunks(size)
                .map(|c| {
                    let q = c.iter().map(|x| x.0).sum::<f64>() / c.len() as f64;
                    let ss: f64 = c.iter().map(|x| x.1).sum();
                    let n: usize = c.iter().map(|x| x.2).sum();
                    (q.to_degrees(), (ss / n as f64).sqrt())
                })
                .unzip();
            out.push((r.number(), j + 1, q, rms));
        }
    }
    out
}

fn trends(before: &(CellProblem, CellFit), after: &(CellProblem, CellFit)) -> Vec<JointTrend> {
    let b = joint_bins(&before.0, &fit_rows(before));
    let a = joint_bins(&after.0, &fit_rows(after));
    b.into_iter()
        .zip(a)
        .map(|((robot, joint, q_deg, rb), (_, _, _, ra))| JointTrend {
            robot,
            joint,
            q_deg,
            rms_over_sigma_before: rb,
            rms_over_sigma_after: ra,
        })
        .collect()
}

fn variance_factor(fit: &CellFit) -> f64 {
    let dof = fit.residual_rows.saturating_sub(fit.layout.len()).max(1) as f64;
    (fit.data_chi2 / dof).sqrt().max(1.0)
}

/// The parameters of `family` in the fit `fit`, in report units, σ times the variance factor
/// `vf`.
fn family_parameters(fit: &(CellProblem, CellFit), family: &Family, vf: f64) -> Vec<ParamValue> {
    let (p, f) = fit;
    f.parameters(p)
        .iter()
        .filter(|fp| family.contains(&fp.param))
        .map(|fp| {
            let unit = ParamUnit::of(&fp.param);
            let k = unit.per_si();
            ParamValue {
                name: family.param_name(p, &fp.param),
                unit,
                value: fp.value * k,
                sigma: fp.posterior_sigma * vf * k,
                prior_sigma: fp.prior_sigma * k,
            }
        })
        .collect()
}

/// Held-out rms per kind before and after, of the kinds scored in both.
fn kind_gains(before: &HeldOut, after: &HeldOut) -> Vec<KindGain> {
    KINDS
        .iter()
        .filter_map(|&k| {
            Some(KindGain {
                kind: k.name(),
                rms_mm_before: kind_rms(&before.rows, k.name())?.1,
                rms_mm_after: kind_rms(&after.rows, k.name())?.1,
            })
        })
        .collect()
}

/// The report of a family tried at the stopping step against the final model `final_held`.
fn rejected_family(
    n: &NotSelected,
    final_held: &HeldOut,
    options: &CellDiagnoseOptions,
) -> RejectedFamilyReport {
    let gain = summary(&n.family.name, final_held, &n.held, n.t);
    let change = -100.0 * gain.relative_gain;
    let reason = if gain.relative_gain < options.min_relative_gain {
        format!(
            "held-out χ² {change:+.1} %, a decrease of ≥ {:.1} % is needed",
            100.0 * options.min_relative_gain
        )
    } else if n.t < options.min_gain_t {
        format!(
            "held-out χ² {change:+.1} %, but not consistently over the held-out groups: t = {:.1} < {:.1}",
            n.t, options.min_gain_t
        )
    } else {
        format!(
            "held-out χ² {change:+.1} % (t = {:.1}), but its in-sample χ² drop is within the noise at \
             a {:.0} % false-alarm level over the step's candidates: F = {:.2} on ({}, {}) \
             degrees of freedom, p = {:.1e} > {:.1e}",
            n.t,
            100.0 * options.false_alarm,
            n.nested.f,
            n.nested.k,
            n.nested.dof,
            n.nested.p,
            n.nested.p_needed
        )
    };
    let vf = variance_factor(&n.fit.1);
    RejectedFamilyReport {
        family: n.family.clone(),
        held_out_by_kind: kind_gains(final_held, &n.held),
        parameters: family_parameters(&n.fit, &n.family, vf),
        variance_factor: vf,
        gain,
        reason,
    }
}

/// Builds the report from the diagnosis.
pub(crate) fn build(d: &CellDiagnosis, options: &CellDiagnoseOptions) -> CellDiagnoseReport {
    let (_, ff) = &d.final_fit;
    let vf = variance_factor(ff);
    let mut counts = [0usize; KINDS.len()];
    for o in &d.problem.observations {
        if let Some(k) = KINDS.iter().position(|k| *k == o.kind.kind()) {
            counts[k] += 1;
        }
    }
    let final_held = d
        .steps
        .iter()
        .rev()
        .find(|s| s.accepted)
        .map_or(&d.baseline_held_out, |s| &s.after);
    let effects: Vec<CellEffectReport> = d
        .steps
        .iter()
        .enumerate()
        .filter(|(_, s)| s.accepted)
        .map(|(i, s)| {
            let after = s.fit_after.as_ref().expect("accepted steps have a fit");
            CellEffectReport {
                step: i + 1,
                family: s.family.clone(),
                gain: summary(&s.family.name, &s.before, &s.after, s.t),
                held_out_by_kind: kind_gains(&s.before, &s.after),
                parameters: family_parameters(&d.final_fit, &s.family, vf),
                residual_vs_joint: trends(&s.fit_before, after),
                candidates_held_out_chi2: s.tried.clone(),
                candidates_ruled_out: s.ruled_out.clone(),
            }
        })
        .collect();
    let accepted = d.steps.iter().filter(|s| s.accepted).count();
    let step_cap_hit = d.steps.len() >= options.max_steps
        && d.steps.last().is_some_and(|s| s.accepted)
        && accepted < d.candidates.len();
    let (mut warnings, notes) = findings(d, &effects, options, step_cap_hit);
    let folds = crate::do_no_harm::folds_report(d);
    let do_no_harm = crate::do_no_harm::do_no_harm_report(d, &folds);
    let fold_word = if d.fold_design.0 == crate::cell_diagnosis::FoldDesign::JointRegions {
        "region"
    } else {
        "fold"
    };
    warnings.extend(do_no_harm.warning(fold_word, "--force"));
    CellDiagnoseReport {
        folds,
        do_no_harm,
        export_estimate: d.safe_fit.1.estimate.clone(),
        export_model: FittedModel {
            problem: d.safe_fit.0.clone(),
            fit: d.safe_fit.1.clone(),
        },
        full_model: FittedModel {
            problem: d.final_fit.0.clone(),
            fit: d.final_fit.1.clone(),
        },
        mode: "whole_cell",
        rows_by_kind: KINDS
            .iter()
            .zip(counts)
            .filter(|(_, n)| *n > 0)
            .map(|(kind, rows)| KindCount {
                kind: kind.name(),
                rows,
            })
            .collect(),
        rows_used: d.used.len(),
        rejected_points: d
            .rejected
            .iter()
            .map(|r| CellRejectedReport {
                point: r.row,
                kind: r.kind,
                size_sigma: r.size_sigma,
                residual_mm: r.residual_m * 1e3,
            })
            .collect(),
        prior_widening: options.prior_widening,
        held_out_units: d.n_units,
        held_out_folds: d.n_folds,
        candidates: d.candidates.clone(),
        baseline: kind_residuals(&fit_rows(&d.baseline), &d.baseline_held_out, &d.noise_scale),
        effects,
        stopped_at: d
            .steps
            .last()
            .filter(|s| !s.accepted)
            .map(|s| summary(&s.family.name, &s.before, &s.after, s.t)),
        stopped_candidates_held_out_chi2: d
            .steps
            .last()
            .filter(|s| !s.accepted)
            .map_or_else(Vec::new, |s| s.tried.clone()),
        rejected_families: d
            .not_selected
            .iter()
            .map(|n| rejected_family(n, final_held, options))
            .collect(),
        placement_fitted: d.placement_fitted,
        final_residuals: kind_residuals(&fit_rows(&d.final_fit), final_held, &d.noise_scale),
        variance_factor: vf,
        final_fit_stopped: format!("{} after {} iterations", ff.stopped.name(), ff.iterations),
        final_estimate: ff.estimate.clone(),
        coverage: None,
        max_steps: options.max_steps,
        step_cap_hit,
        screen_misfit: d.screen_misfit.clone(),
        warnings,
        notes,
    }
}

/// One parameter line of the text: name, value, unit and 95 % interval.
fn param_line(s: &mut String, p: &ParamValue) {
    let [lo, hi] = p.ci95();
    let _ = writeln!(
        s,
        "     {:<40} {:>9.3} {:<11} 95 % [{:.3}, {:.3}]",
        p.name,
        p.value,
        p.unit.suffix(),
        lo,
        hi
    );
}

/// The parameters of `params` whose 95 % interval excludes 0.
fn excluding_zero(params: &[ParamValue]) -> Vec<&ParamValue> {
    params
        .iter()
        .filter(|p| p.value.abs() > Z95 * p.sigma)
        .collect()
}

/// The report as text.
pub fn render_cell_text(r: &CellDiagnoseReport) -> String {
    let mut s = String::new();
    let kinds: Vec<String> = r
        .rows_by_kind
        .iter()
        .map(|k| format!("{} {}", k.rows, k.kind))
        .collect();
    let _ = writeln!(
        s,
        "Whole-cell diagnosis: {} rows ({}), {} used; held out by {} units in {} folds; prior = tolerances × {}",
        r.rows_by_kind.iter().map(|k| k.rows).sum::<usize>(),
        kinds.join(", "),
        r.rows_used,
        r.held_out_units,
        r.held_out_folds,
        r.prior_widening
    );
    for p in &r.rejected_points {
        let _ = writeln!(
            s,
            "  rejected row {} ({}): {:.1} σ, residual {:.3} mm",
            p.point, p.kind, p.size_sigma, p.residual_mm
        );
    }
    let table = |s: &mut String, title: &str, rows: &[KindResidual]| {
        let _ = writeln!(s, "{title}");
        let _ = writeln!(
            s,
            "  {:<11} {:>6} {:>9} {:>13} {:>9} {:>12} {:>15} {:>10} {:>18}",
            "kind",
            "rows",
            "rms_mm",
            "stated_σ_mm",
            "rms/σ",
            "noise_scale",
            "held_out_rms_mm",
            "rms_3d_mm",
            "held_out_rms_3d_mm"
        );
        let opt = |v: Option<f64>| v.map_or_else(|| "–".to_string(), |v| format!("{v:.3}"));
        for k in rows {
            let _ = writeln!(
                s,
                "  {:<11} {:>6} {:>9.3} {:>13.3} {:>9.2} {:>12.2} {:>15} {:>10} {:>18}",
                k.kind,
                k.residual_rows,
                k.rms_mm,
                k.stated_sigma_mm,
                k.rms_over_sigma,
                k.noise_scale,
                opt(k.held_out_rms_mm),
                opt(k.rms_3d_mm),
                opt(k.held_out_rms_3d_mm)
            );
        }
        if rows.iter().any(|k| k.rms_3d_mm.is_some()) {
            let _ = writeln!(
                s,
                "  (rms_mm is per residual row: per axis for tracker and coincident rows; rms_3d_mm is their 3-D error ‖r‖, √3 × per axis for isotropic errors)"
            );
        }
    };
    table(
        &mut s,
        "Baseline (nominal kinematics, nuisances fitted):",
        &r.baseline,
    );
    if r.effects.is_empty() {
        let _ = writeln!(s, "Significant effects: none");
    } else {
        let _ = writeln!(s, "Significant effects (in order of selection):");
    }
    for e in &r.effects {
        let g = &e.gain;
        let _ = writeln!(
            s,
            "{}. {}: held-out χ² {:.1} → {:.1} ({:.1} %, t = {:.1})",
            e.step,
            e.family.name,
            g.held_out_chi2_before,
            g.held_out_chi2_after,
            100.0 * g.relative_gain,
            g.gain_t
        );
        for k in &e.held_out_by_kind {
            let _ = writeln!(
                s,
                "     held-out {:<10} rms {:.3} → {:.3} mm",
                k.kind, k.rms_mm_before, k.rms_mm_after
            );
        }
        // Text: the parameters whose 95 % interval excludes 0 (JSON: all of them).
        let shown = excluding_zero(&e.parameters);
        if shown.len() < e.parameters.len() {
            let _ = writeln!(
                s,
                "     ({} of {} parameters have a 95 % interval that excludes 0; the others are in the JSON)",
                shown.len(),
                e.parameters.len()
            );
        }
        for p in shown {
            param_line(&mut s, p);
        }
        if let Some(t) = e.residual_vs_joint.iter().max_by(|a, b| {
            let (ab, aa) = a.spread();
            let (bb, ba) = b.spread();
            (ab - aa).total_cmp(&(bb - ba))
        }) {
            let f = |v: &[f64]| {
                v.iter()
                    .map(|x| format!("{x:.2}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            let _ = writeln!(
                s,
                "     residual vs robot {} q{} (quartiles at {} deg): rms/σ {} → {}",
                t.robot,
                t.joint,
                f(&t.q_deg),
                f(&t.rms_over_sigma_before),
                f(&t.rms_over_sigma_after)
            );
        }
    }
    if let Some(st) = &r.stopped_at {
        let _ = writeln!(
            s,
            "Stopped: best remaining candidate {} changes the held-out χ² by {:+.1} % (t = {:.1}): not significant",
            st.family,
            -100.0 * st.relative_gain,
            st.gain_t
        );
    }
    if !r.rejected_families.is_empty() {
        let _ = writeln!(
            s,
            "Rejected families (each fitted added to the final model on all rows; not named):"
        );
    }
    for f in &r.rejected_families {
        let _ = writeln!(s, "  {}: {}", f.family.name, f.reason);
        let shown: Vec<&ParamValue> = f
            .parameters
            .iter()
            .filter(|p| {
                p.value.abs() > Z95 * p.sigma
                    || p.prior_sigma == 0.0
                    || p.sigma < REJECTED_TEXT_PRIOR_FRACTION * p.prior_sigma
            })
            .collect();
        if shown.len() < f.parameters.len() {
            let _ = writeln!(
                s,
                "     ({} of {} parameters are determined by the data (interval excludes 0, or σ < {} × prior σ); the others are in the JSON)",
                shown.len(),
                f.parameters.len(),
                REJECTED_TEXT_PRIOR_FRACTION
            );
        }
        for p in shown {
            param_line(&mut s, p);
        }
    }
    crate::do_no_harm::write_text(&mut s, &r.folds, &r.do_no_harm);
    table(&mut s, "Final model:", &r.final_residuals);
    let _ = writeln!(
        s,
        "Final fit: {}; posterior σ × variance factor {:.2}",
        r.final_fit_stopped, r.variance_factor
    );
    if let Some(c) = &r.coverage {
        for line in c.text_lines() {
            let _ = writeln!(s, "{line}");
        }
    }
    s
}
