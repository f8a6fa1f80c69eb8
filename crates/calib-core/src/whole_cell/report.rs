//! The reports of the whole-cell results in file units (mm, degrees; each parameter names its
//! unit): a calibration ([`CellCalibration::report`]; `handclasp calibrate --cell` prints it,
//! with the session's framing) and a design's prediction ([`DesignPredictionReport`];
//! `handclasp plan` prints two). Typed structs that serialise to JSON and that a text renderer
//! reads.
//!
//! The fields of every struct stand in alphabetical order (the two hand-written serialisers
//! write them so): serde writes them in declaration order, and this is the key order of the JSON
//! `calibrate --cell` printed before it had types.

use kinematics::ErrorParam;
use serde::ser::{SerializeMap, Serializer};
use serde::Serialize;

use super::calibrate::CellCalibration;
use super::design::DesignPrediction;
use super::layout::CellParam;
use super::observations::CellProblem;
use super::prediction::{ModelError, PairSet, PredictedError};
use super::reduce::{ReductionEntry, ReductionReason};

use crate::{PoseForms, Robot, StopReason};

/// The unit a report gives a parameter in; serialised as its [`ReportUnit::name`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub enum ReportUnit {
    /// Millimetres (lengths; also, as before the report had types, the periodic joint terms'
    /// amplitudes and a tracker's scale, which are values × 1000).
    #[serde(rename = "mm")]
    Mm,
    /// Degrees (joint offsets, origin and mount angles, placement, tracker and plane-normal
    /// rotations).
    #[serde(rename = "deg")]
    Deg,
    /// A ratio (joint scale).
    #[serde(rename = "ratio")]
    Ratio,
    /// Degrees per kilonewton-metre (compliance).
    #[serde(rename = "deg/kNm")]
    DegPerKnm,
}

impl ReportUnit {
    /// The unit of a cell unknown.
    pub fn of(p: &CellParam) -> ReportUnit {
        match p {
            CellParam::ToolTip { .. } => ReportUnit::Mm,
            CellParam::Kinematic { param, .. } => match param {
                ErrorParam::JointOffset { .. }
                | ErrorParam::OriginRpy { .. }
                | ErrorParam::MountRpy { .. }
                | ErrorParam::LumpedCompliance { .. } => ReportUnit::Deg,
                ErrorParam::JointScale { .. } => ReportUnit::Ratio,
                ErrorParam::Compliance { .. } => ReportUnit::DegPerKnm,
                _ => ReportUnit::Mm,
            },
            CellParam::PlacementRotation { .. }
            | CellParam::TrackerRotation { .. }
            | CellParam::PlaneNormal { .. } => ReportUnit::Deg,
            _ => ReportUnit::Mm,
        }
    }

    /// `"mm"`, `"deg"`, `"ratio"` or `"deg/kNm"`.
    pub fn name(self) -> &'static str {
        match self {
            ReportUnit::Mm => "mm",
            ReportUnit::Deg => "deg",
            ReportUnit::Ratio => "ratio",
            ReportUnit::DegPerKnm => "deg/kNm",
        }
    }

    /// Report units per SI unit (m, rad, ratio, rad/(N·m)).
    pub fn per_si(self) -> f64 {
        let deg = 1f64.to_degrees();
        match self {
            ReportUnit::Mm => 1e3,
            ReportUnit::Deg => deg,
            ReportUnit::Ratio => 1.0,
            ReportUnit::DegPerKnm => deg * 1e3,
        }
    }
}

/// Which robot's kinematic parameter (or tool tip) a report entry is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamIdentity {
    /// The axis (`x`, `y`, `z`) of a vector parameter, `None` for a scalar one.
    pub axis: Option<String>,
    /// The joint, 1-based, `None` for a parameter of no joint (tip, mount).
    pub joint: Option<usize>,
    /// The carried link of a lumped-compliance coefficient, 1-based (JSON `link`, present only
    /// then); `None` otherwise.
    pub link: Option<usize>,
    /// The parameter's kind (`joint_offset`, `origin_xyz`, …, `tip` for a tool tip).
    pub kind: &'static str,
    /// The robot.
    pub robot: Robot,
}

impl ParamIdentity {
    /// The identity of a robot's kinematic parameter or tool tip; `None` for the other unknowns
    /// (placement, trackers, planes, contact distances).
    pub fn of(p: &CellParam) -> Option<Self> {
        match p {
            CellParam::Kinematic { robot, param } => Some(ParamIdentity {
                axis: param.axis().map(|a| a.to_string()),
                joint: param.joint().map(|j| j + 1),
                link: match param {
                    ErrorParam::LumpedCompliance { link, .. } => Some(link + 1),
                    _ => None,
                },
                kind: param.kind_name(),
                robot: *robot,
            }),
            CellParam::ToolTip { robot, axis, .. } => Some(ParamIdentity {
                axis: Some(axis.to_string()),
                joint: None,
                link: None,
                kind: "tip",
                robot: *robot,
            }),
            _ => None,
        }
    }
}

/// A fitted kinematic parameter (or tool tip) in its [`ReportUnit`]. JSON: `axis`,
/// `exceeds_tolerance`, `exceeds_tolerance_beyond_noise`, `joint`, `kind`, `name`, `prior_scale`, `prior_sigma`, `robot`, `sigma`,
/// `tolerance`, `unit`, `value`.
#[derive(Debug, Clone)]
pub struct ParameterReport {
    /// Robot, kind, joint and axis.
    pub identity: ParamIdentity,
    /// Readable name, e.g. `robot 2 origin_xyz joint 3 x`.
    pub name: String,
    /// The prior scale applied to its family ([`super::PriorScaleChoice`]): the fit's prior σ
    /// is `prior_scale × prior_sigma`.
    pub prior_scale: f64,
    /// Prior σ from the stated tolerance (the chosen prior scale is not applied; a merged
    /// parameter's includes its partners' prior).
    pub prior_sigma: f64,
    /// Posterior σ.
    pub sigma: f64,
    /// The stated tolerance, `√3 × prior_sigma` (the half-width of the uniform band the prior
    /// stands for).
    pub tolerance: f64,
    /// The unit of `value`, `sigma`, `prior_sigma` and `tolerance`.
    pub unit: ReportUnit,
    /// The fitted correction.
    pub value: f64,
}

/// Posterior σ a fitted correction must exceed its stated tolerance by before
/// [`ParameterReport::tolerance_warning`] warns: a correction within `tolerance + 2σ` is
/// consistent with a true error inside the tolerance plus the fit's own noise (a correct
/// session's corrections land just beyond the band about one time in twenty per parameter
/// without it).
pub const TOLERANCE_WARNING_SIGMAS: f64 = 2.0;

impl ParameterReport {
    /// Whether the fitted correction is larger than the stated tolerance (`|value| > tolerance`).
    pub fn exceeds_tolerance(&self) -> bool {
        self.value.abs() > self.tolerance
    }

    /// Whether the fitted correction is beyond the stated tolerance by more than the fit's noise
    /// (`|value| > tolerance + TOLERANCE_WARNING_SIGMAS × sigma`): the data say the robot is
    /// further off than stated.
    pub fn exceeds_tolerance_beyond_noise(&self) -> bool {
        self.value.abs() > self.tolerance + TOLERANCE_WARNING_SIGMAS * self.sigma
    }

    /// The warning for a correction beyond its stated tolerance by more than
    /// [`TOLERANCE_WARNING_SIGMAS`] posterior σ (`None` otherwise): names the parameter, its
    /// value and σ, its tolerance and the prior scale applied.
    pub fn tolerance_warning(&self) -> Option<String> {
        let unit = self.unit.name();
        self.exceeds_tolerance_beyond_noise().then(|| {
            format!(
                "{}: fitted correction {:+.4} ± {:.4} {unit} (1σ) exceeds its stated tolerance \
                 ±{:.4} {unit} by more than {TOLERANCE_WARNING_SIGMAS}σ ({:.1}× it; prior scale \
                 applied ×{}): the robot is further off than the cell's [robotN.tolerance] says; \
                 check the tolerance or the session",
                self.name,
                self.value,
                self.sigma,
                self.tolerance,
                self.value.abs() / self.tolerance,
                super::format_scale(self.prior_scale)
            )
        })
    }
}

impl Serialize for ParameterReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let id = &self.identity;
        let mut m = s.serialize_map(Some(13 + usize::from(id.link.is_some())))?;
        m.serialize_entry("axis", &id.axis)?;
        m.serialize_entry("exceeds_tolerance", &self.exceeds_tolerance())?;
        m.serialize_entry(
            "exceeds_tolerance_beyond_noise",
            &self.exceeds_tolerance_beyond_noise(),
        )?;
        m.serialize_entry("joint", &id.joint)?;
        m.serialize_entry("kind", id.kind)?;
        if let Some(link) = id.link {
            m.serialize_entry("link", &link)?;
        }
        m.serialize_entry("name", &self.name)?;
        m.serialize_entry("prior_scale", &self.prior_scale)?;
        m.serialize_entry("prior_sigma", &self.prior_sigma)?;
        m.serialize_entry("robot", &id.robot)?;
        m.serialize_entry("sigma", &self.sigma)?;
        m.serialize_entry("tolerance", &self.tolerance)?;
        m.serialize_entry("unit", &self.unit)?;
        m.serialize_entry("value", &self.value)?;
        m.end()
    }
}

/// One axis of the placement's posterior σ, with its prior.
#[derive(Debug, Clone, Serialize)]
pub struct PlacementSigmaReport {
    /// `b1_from_b2 translation x` … `b1_from_b2 rotation z` (left perturbation, b1 axes).
    pub name: String,
    /// The cell's prior σ, `None` when that half of the placement is fitted freely.
    pub prior_sigma: Option<f64>,
    /// Posterior σ.
    pub sigma: f64,
    /// mm (translation) or deg (rotation).
    pub unit: ReportUnit,
}

/// The fitted `b1_from_b2` (mm, degrees, canonical ZYZ; see [`PoseForms`]) and its posterior σ
/// per axis.
#[derive(Debug, Clone, Serialize)]
pub struct FittedPlacementReport {
    /// Unit quaternion `[w, x, y, z]`.
    pub quaternion_wxyz: [f64; 4],
    /// Rotation matrix, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Posterior σ of the three translation and three rotation axes, in that order.
    pub sigma: Vec<PlacementSigmaReport>,
    /// x, y, z, mm.
    pub xyz_mm: [f64; 3],
    /// φ, θ, ψ (ZYZ), degrees.
    pub zyz_deg: [f64; 3],
}

/// A fitted nuisance unknown (tracker frame, plane, contact distance) in its [`ReportUnit`];
/// the perturbation columns (tracker rotation, plane normal) report 0 as value.
#[derive(Debug, Clone, Serialize)]
pub struct NuisanceReport {
    /// Readable name, e.g. ``tracker `t` translation x``.
    pub name: String,
    /// Posterior σ.
    pub sigma: f64,
    /// The unit of `value` and `sigma`.
    pub unit: ReportUnit,
    /// The fitted value.
    pub value: f64,
}

/// Why a parameter was dropped ([`ReductionReason`] without its data); serialised snake_case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum DropReason {
    /// It moves no observed tip.
    NoEffect,
    /// A shared trunk's parameter that moves both hands alike, which the rows do not see.
    MovesBothHandsAlike,
    /// The data barely see it: the prior decides it.
    PriorDecided,
    /// The placement absorbs it.
    ConfoundedWithPlacement,
    /// The placement and the nuisance unknowns absorb it.
    ConfoundedWithNuisance,
    /// Merged into kept parameters ([`UnidentifiableReport::merged_into`]).
    Merged,
}

/// A kept parameter a dropped one was merged into.
#[derive(Debug, Clone, Serialize)]
pub struct MergePartner {
    /// Its coefficient, in prior-σ units.
    pub coefficient: f64,
    /// The kept parameter's readable name.
    pub parameter: String,
}

/// A parameter the session cannot determine, held at nominal. JSON: `axis`,
/// `independent_fraction`, `joint`, `kind`, `merged_into`, `name`, `reason`, `robot`, `why`
/// (`axis`, `joint`, `kind` and `robot` only for a robot's kinematic parameter or tool tip).
#[derive(Debug, Clone)]
pub struct UnidentifiableReport {
    /// Robot, kind, joint and axis; `None` for another unknown (a placement half with a prior).
    pub identity: Option<ParamIdentity>,
    /// Fraction of its effect left after projecting out the unknowns that absorb it.
    pub independent_fraction: f64,
    /// For [`DropReason::Merged`], the kept parameters it was merged into; `None` otherwise.
    pub merged_into: Option<Vec<MergePartner>>,
    /// Readable name.
    pub name: String,
    /// Why it was dropped.
    pub reason: DropReason,
    /// A sentence for people ([`ReductionEntry::message`]).
    pub why: String,
}

impl UnidentifiableReport {
    /// The report of one dropped parameter.
    pub fn new(d: &ReductionEntry) -> Self {
        let (reason, merged_into) = match &d.reason {
            ReductionReason::NoEffect => (DropReason::NoEffect, None),
            ReductionReason::MovesBothHandsAlike => (DropReason::MovesBothHandsAlike, None),
            ReductionReason::PriorDecided => (DropReason::PriorDecided, None),
            ReductionReason::ConfoundedWithPlacement => (DropReason::ConfoundedWithPlacement, None),
            ReductionReason::ConfoundedWithNuisance => (DropReason::ConfoundedWithNuisance, None),
            ReductionReason::MergedInto { into } => (
                DropReason::Merged,
                Some(
                    into.iter()
                        .map(|(name, c)| MergePartner {
                            coefficient: *c,
                            parameter: name.clone(),
                        })
                        .collect(),
                ),
            ),
        };
        UnidentifiableReport {
            identity: ParamIdentity::of(&d.param),
            independent_fraction: d.independent_fraction,
            merged_into,
            name: d.name.clone(),
            reason,
            why: d.message.clone(),
        }
    }
}

impl Serialize for UnidentifiableReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let id = self.identity.as_ref();
        let link = id.and_then(|id| id.link);
        let keys = if id.is_some() { 9 } else { 5 } + usize::from(link.is_some());
        let mut m = s.serialize_map(Some(keys))?;
        if let Some(id) = id {
            m.serialize_entry("axis", &id.axis)?;
        }
        m.serialize_entry("independent_fraction", &self.independent_fraction)?;
        if let Some(id) = id {
            m.serialize_entry("joint", &id.joint)?;
            m.serialize_entry("kind", id.kind)?;
        }
        if let Some(link) = link {
            m.serialize_entry("link", &link)?;
        }
        m.serialize_entry("merged_into", &self.merged_into)?;
        m.serialize_entry("name", &self.name)?;
        m.serialize_entry("reason", &self.reason)?;
        if let Some(id) = id {
            m.serialize_entry("robot", &id.robot)?;
        }
        m.serialize_entry("why", &self.why)?;
        m.end()
    }
}

/// A row rejected as a blunder.
#[derive(Debug, Clone, Serialize)]
pub struct RejectedRowReport {
    /// Its residual against the final fit, mm (norm for 3-row kinds).
    pub residual_mm: f64,
    /// The 1-based source row.
    pub row: usize,
    /// Its deletion-studentised size, σ.
    pub size_sigma: f64,
}

/// The log evidence of one prior scale.
#[derive(Debug, Clone, Serialize)]
pub struct LogEvidenceReport {
    /// Natural log of the evidence, up to a constant common to all scales.
    pub log_evidence: f64,
    /// The prior scale `s`.
    pub scale: f64,
}

/// The scale applied to one family of parameters ([`super::FamilyScale`]).
#[derive(Debug, Clone, Serialize)]
pub struct FamilyScaleReport {
    /// The family (the parameters' kind: `joint_offset`, `origin_xyz`, `origin_rpy`, `tip`, …).
    pub family: String,
    /// Its fitted parameters.
    pub parameters: usize,
    /// The scale applied (prior σ = scale × tolerance/√3).
    pub scale: f64,
}

/// The prior scales applied and why ([`super::PriorScaleChoice`]).
#[derive(Debug, Clone, Serialize)]
pub struct PriorScaleReport {
    /// The common scale of largest evidence (or the fixed scale): every family's scale unless
    /// `method` is `evidence_per_family`.
    pub chosen: f64,
    /// The scale applied to each family.
    pub families: Vec<FamilyScaleReport>,
    /// Log evidence of the best per-family scales (`null` when no family gained by its own).
    pub family_log_evidence: Option<f64>,
    /// Every common scale, with its log evidence.
    pub log_evidence: Vec<LogEvidenceReport>,
    /// How the scales were set: `evidence_common`, `evidence_per_family`, `fixed` (the
    /// `--tolerance-scale` flag) or `no_prior`.
    pub method: super::ScaleMethod,
    /// Which scales and why, with the evidence values.
    pub why: String,
}

/// A contact group's distance.
#[derive(Debug, Clone, Serialize)]
pub struct ContactGroupReport {
    /// The distance between the two tools, mm.
    pub distance_mm: f64,
    /// Whether it was fitted (else given).
    pub fitted: bool,
    /// The group's name.
    pub group: String,
}

/// A plane group's plane, in its anchor robot's base.
#[derive(Debug, Clone, Serialize)]
pub struct PlaneGroupReport {
    /// The robot whose base the plane is expressed in.
    pub anchor_robot: Robot,
    /// The group's name.
    pub group: String,
    /// Unit normal, anchor base axes.
    pub normal: [f64; 3],
    /// Offset, mm.
    pub offset_mm: f64,
}

/// A tracker group's frame in its anchor robot's base.
#[derive(Debug, Clone, Serialize)]
pub struct TrackerGroupReport {
    /// `anchor_from_tracker`: the tracker's origin (mm) and rotation in the anchor robot's base,
    /// in every form of [`PoseForms`] (canonical ZYZ degrees, rotation matrix, quaternion).
    pub anchor_from_tracker: PoseForms,
    /// The robot whose base the tracker frame is expressed against.
    pub anchor_robot: Robot,
    /// The group's name.
    pub group: String,
}

/// The fitted nuisance groups of a session with contact, plane or tracker rows.
#[derive(Debug, Clone, Serialize)]
pub struct GroupsReport {
    /// Contact groups.
    pub contact: Vec<ContactGroupReport>,
    /// Plane groups.
    pub plane: Vec<PlaneGroupReport>,
    /// Tracker groups.
    pub tracker: Vec<TrackerGroupReport>,
}

/// A whole-cell calibration in file units: the fitted placement, the kinematic corrections, what
/// the session cannot determine, the rejected rows, the nuisance groups and the solver's state.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    /// The fitted `b1_from_b2` and its posterior σ.
    pub b1_from_b2: FittedPlacementReport,
    /// Data χ² of the final fit.
    pub data_chi2: f64,
    /// Kept kinematic directions the data determine better than the prior.
    pub data_determined_directions: usize,
    /// The fitted nuisance groups (empty lists for a session of handclasps alone).
    pub groups: GroupsReport,
    /// Solver iterations of the final fit.
    pub iterations: usize,
    /// The blunder screen's noise scale ([`CellCalibration::noise_scale`]).
    pub noise_scale: f64,
    /// The nuisance unknowns (absent from the JSON when there are none).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub nuisance_parameters: Vec<NuisanceReport>,
    /// The fitted kinematic parameters and tool tips.
    pub parameters: Vec<ParameterReport>,
    /// Kept kinematic directions the prior dominates.
    pub prior_dominated_directions: usize,
    /// The prior scale chosen by the evidence.
    pub prior_scale: PriorScaleReport,
    /// The rows rejected as blunders.
    pub rejected_points: Vec<RejectedRowReport>,
    /// Residual rows of the final fit.
    pub residual_rows: usize,
    /// Rows (observations) the final fit used.
    pub rows_used: usize,
    /// Why the solver stopped.
    pub stopped: StopReason,
    /// The parameters dropped or merged, and why.
    pub unidentifiable: Vec<UnidentifiableReport>,
}

impl CellCalibration {
    /// The report of this calibration of `problem`, in file units.
    pub fn report(&self, problem: &CellProblem) -> CalibrationReport {
        let mut parameters = Vec::new();
        let mut placement_sigma = Vec::new();
        let mut nuisance_parameters = Vec::new();
        for p in &self.fit.parameters(problem) {
            let unit = ReportUnit::of(&p.param);
            let k = unit.per_si();
            match ParamIdentity::of(&p.param) {
                Some(identity) => {
                    let prior_scale = super::prior_family(&p.param)
                        .map_or(1.0, |f| self.prior_scale.family_scale(f));
                    let prior_sigma = p.prior_sigma / prior_scale * k;
                    parameters.push(ParameterReport {
                        identity,
                        name: p.name.clone(),
                        prior_scale,
                        prior_sigma,
                        sigma: p.posterior_sigma * k,
                        tolerance: prior_sigma * 3f64.sqrt(),
                        unit,
                        value: p.value * k,
                    })
                }
                None if matches!(
                    p.param,
                    CellParam::PlacementTranslation { .. } | CellParam::PlacementRotation { .. }
                ) =>
                {
                    placement_sigma.push(PlacementSigmaReport {
                        name: p.name.clone(),
                        // A prior σ of 0 is no prior: that half of the placement is fitted freely.
                        prior_sigma: (p.prior_sigma > 0.0).then_some(p.prior_sigma * k),
                        sigma: p.posterior_sigma * k,
                        unit,
                    })
                }
                // Tracker frames, planes, contact distances (mixed sessions only).
                None => nuisance_parameters.push(NuisanceReport {
                    name: p.name.clone(),
                    sigma: p.posterior_sigma * k,
                    unit,
                    value: p.value * k,
                }),
            }
        }
        let PoseForms {
            quaternion_wxyz,
            rotation,
            xyz_mm,
            zyz_deg,
        } = PoseForms::from_isometry(&self.fit.estimate.b1_from_b2);
        CalibrationReport {
            b1_from_b2: FittedPlacementReport {
                quaternion_wxyz,
                rotation,
                sigma: placement_sigma,
                xyz_mm,
                zyz_deg,
            },
            data_chi2: self.fit.data_chi2,
            data_determined_directions: self.reduction.data_determined,
            groups: self.groups_report(problem),
            iterations: self.fit.iterations,
            noise_scale: self.noise_scale,
            nuisance_parameters,
            parameters,
            prior_dominated_directions: self.reduction.prior_dominated,
            prior_scale: PriorScaleReport {
                chosen: self.prior_scale.scale,
                families: self
                    .prior_scale
                    .families
                    .iter()
                    .map(|f| FamilyScaleReport {
                        family: f.family.to_string(),
                        parameters: f.parameters,
                        scale: f.scale,
                    })
                    .collect(),
                family_log_evidence: self.prior_scale.family_log_evidence,
                method: self.prior_scale.method,
                why: self.prior_scale.why.clone(),
                log_evidence: self
                    .prior_scale
                    .log_evidence
                    .iter()
                    .map(|&(scale, log_evidence)| LogEvidenceReport {
                        log_evidence,
                        scale,
                    })
                    .collect(),
            },
            rejected_points: self
                .rejected
                .iter()
                .map(|b| RejectedRowReport {
                    residual_mm: b.residual_m * 1e3,
                    row: b.row,
                    size_sigma: b.size_sigma,
                })
                .collect(),
            residual_rows: self.fit.residual_rows,
            rows_used: self.fit.active.len(),
            stopped: self.fit.stopped,
            unidentifiable: self
                .reduction
                .dropped
                .iter()
                .map(UnidentifiableReport::new)
                .collect(),
        }
    }

    /// The fitted nuisance groups (mm, degrees): contact distances, planes (unit normal and
    /// offset in the anchor robot's base), tracker frames (`anchor_from_tracker`).
    fn groups_report(&self, problem: &CellProblem) -> GroupsReport {
        let est = &self.fit.estimate;
        GroupsReport {
            contact: problem
                .contacts
                .iter()
                .zip(&est.contact_distance_m)
                .map(|(g, d)| ContactGroupReport {
                    distance_mm: d * 1e3,
                    fitted: g.fit_distance,
                    group: g.name.clone(),
                })
                .collect(),
            plane: problem
                .planes
                .iter()
                .zip(&est.planes)
                .map(|(g, p)| PlaneGroupReport {
                    anchor_robot: g.anchor,
                    group: g.name.clone(),
                    normal: [p.normal_anchor.x, p.normal_anchor.y, p.normal_anchor.z],
                    offset_mm: p.offset_m * 1e3,
                })
                .collect(),
            tracker: problem
                .trackers
                .iter()
                .zip(&est.tracker_from_anchor)
                .map(|(g, tracker_from_anchor)| TrackerGroupReport {
                    anchor_from_tracker: PoseForms::from_isometry(&tracker_from_anchor.inverse()),
                    anchor_robot: g.anchor,
                    group: g.name.clone(),
                })
                .collect(),
        }
    }
}

/// A predicted cooperative error ([`PredictedError`]) in mm: the figures `calibrate --cell`,
/// `plan` and the report page print, with the pair set it is over and its parts. Keys without a
/// unit suffix: the parent key names the unit (`…_mm`).
#[derive(Debug, Clone, Serialize)]
pub struct PredictedErrorReport {
    /// The part the data determined (the noise the data leave), mm.
    pub data_part_rms: f64,
    /// For a model-error term from region-held-out residuals: the upper-tail probability of
    /// their statistic under the model (the term is added below 0.05).
    pub held_out_p_value: Option<f64>,
    /// The same: `Σ t² / E[Σ t²]` (1: as the stated noise and the posterior predict).
    pub held_out_ratio: Option<f64>,
    /// How many joint-space regions were held out in turn.
    pub held_out_regions: Option<usize>,
    /// The model-error part, mm.
    pub model_error_rms: f64,
    /// Where the model-error term comes from: `assumed_none`, `placement_residuals` or
    /// `held_out_residuals`.
    pub model_error_source: &'static str,
    /// Which configuration pairs the prediction is over, for people.
    pub pair_set: &'static str,
    /// The same as an identifier ([`PairSet`], snake_case).
    pub pair_set_kind: PairSet,
    /// Their number.
    pub pairs: usize,
    /// Predicted 95th percentile of the cooperative error, mm.
    pub predicted_p95: f64,
    /// Predicted rms of the cooperative error, mm: `sqrt(data² + prior² + model²)` of the parts.
    pub predicted_rms: f64,
    /// The part the prior asserts (the tolerances of what the data do not determine), mm.
    pub prior_part_rms: f64,
    /// 95 % upper bound of the rms over these pairs, mm.
    pub rms_bound95: f64,
}

impl From<&PredictedError> for PredictedErrorReport {
    fn from(p: &PredictedError) -> Self {
        let (source, held) = match p.model_error {
            ModelError::PlacementResiduals { .. } => ("placement_residuals", None),
            ModelError::HeldOut {
                ratio,
                p_value,
                regions,
                ..
            } => ("held_out_residuals", Some((ratio, p_value, regions))),
            _ => ("assumed_none", None),
        };
        PredictedErrorReport {
            data_part_rms: p.data_rms_m * 1e3,
            held_out_ratio: held.map(|h| h.0),
            held_out_p_value: held.map(|h| h.1),
            held_out_regions: held.map(|h| h.2),
            model_error_rms: p.model_error_rms_m * 1e3,
            model_error_source: source,
            pair_set: p.pair_set.describe(),
            pair_set_kind: p.pair_set,
            pairs: p.pairs,
            predicted_p95: p.p95_m * 1e3,
            predicted_rms: p.rms_m * 1e3,
            prior_part_rms: p.prior_rms_m * 1e3,
            rms_bound95: p.rms_bound95_m * 1e3,
        }
    }
}

impl PredictedErrorReport {
    /// One line of its parts and bound, for the text reports: what the data determined, what
    /// the prior asserts, the model error and where it comes from, the 95 % bound.
    pub fn parts_line(&self) -> String {
        let regions = self
            .held_out_regions
            .map_or(String::new(), |k| format!(" of {k} joint-space regions"));
        let p = self
            .held_out_p_value
            .map_or(String::new(), |p| format!(", p {p:.2}"));
        let model = match (self.model_error_source, self.held_out_ratio) {
            ("placement_residuals", _) => format!(
                "model error {:.3} mm (the placement-only fit's residuals above the stated noise)",
                self.model_error_rms
            ),
            ("held_out_residuals", Some(r)) if self.model_error_rms > 0.0 => format!(
                "model error {:.3} mm (held-out residuals{regions} {r:.2}× what the fit predicts{p})",
                self.model_error_rms
            ),
            ("held_out_residuals", Some(r)) => format!(
                "model error none (held-out residuals{regions} {r:.2}× what the fit predicts{p}: \
                 not significantly above)"
            ),
            _ => "model error none assumed".to_string(),
        };
        format!(
            "of which: data-determined {:.3} mm, prior-asserted {:.3} mm (the tolerances of the \
             terms the data do not determine: right only if the robots are that far off), {model}; \
             95 % bound of the rms {:.3} mm",
            self.data_part_rms, self.prior_part_rms, self.rms_bound95
        )
    }
}

/// A design's predicted errors ([`DesignPrediction`]) in mm and degrees.
#[derive(Debug, Clone, Serialize)]
pub struct DesignPredictionReport {
    /// Predicted cooperative rms over the evaluation pairs, mm.
    pub cooperative_rms_mm: f64,
    /// Predicted rms of the paper's `e_rot`, degrees.
    pub e_rot_deg: f64,
    /// Predicted rms of the paper's `e_tran`, mm.
    pub e_tran_mm: f64,
    /// `log det` of the posterior information (dimensionless).
    pub log_det_information: f64,
}

impl From<&DesignPrediction> for DesignPredictionReport {
    fn from(p: &DesignPrediction) -> Self {
        DesignPredictionReport {
            cooperative_rms_mm: p.cooperative_rms_m * 1e3,
            e_rot_deg: p.e_rot_rad.to_degrees(),
            e_tran_mm: p.e_tran_m * 1e3,
            log_det_information: p.log_det_info,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::Axis;

    fn sorted(json: &str) -> String {
        // serde_json's `Value` keeps its object keys in a BTreeMap (this workspace does not turn
        // on `preserve_order`): the order the untyped report had.
        serde_json::to_string(&serde_json::from_str::<serde_json::Value>(json).unwrap()).unwrap()
    }

    fn dropped(param: CellParam, reason: ReductionReason) -> ReductionEntry {
        ReductionEntry {
            param,
            name: "p".into(),
            reason,
            independent_fraction: 0.25,
            message: "why".into(),
        }
    }

    /// A robot's parameter carries its identity (1-based joint, axis); a placement half has
    /// none, and then the four identity keys are absent, not null.
    #[test]
    fn unidentifiable_entries_with_and_without_identity() {
        let kin = CellParam::Kinematic {
            robot: Robot::Two,
            param: ErrorParam::OriginXyz {
                joint: 2,
                axis: Axis::Y,
            },
        };
        let merged = UnidentifiableReport::new(&dropped(
            kin,
            ReductionReason::MergedInto {
                into: vec![("q".into(), -0.5)],
            },
        ));
        let json = serde_json::to_string(&merged).unwrap();
        assert_eq!(
            json,
            r#"{"axis":"y","independent_fraction":0.25,"joint":3,"kind":"origin_xyz","merged_into":[{"coefficient":-0.5,"parameter":"q"}],"name":"p","reason":"merged","robot":2,"why":"why"}"#
        );
        assert_eq!(json, sorted(&json));
        let placement = UnidentifiableReport::new(&dropped(
            CellParam::PlacementTranslation { axis: Axis::X },
            ReductionReason::ConfoundedWithNuisance,
        ));
        let json = serde_json::to_string(&placement).unwrap();
        assert_eq!(
            json,
            r#"{"independent_fraction":0.25,"merged_into":null,"name":"p","reason":"confounded_with_nuisance","why":"why"}"#
        );
    }

    /// A tool tip is kind `tip` with no joint; units and their factors per SI unit.
    #[test]
    fn parameter_entry_of_a_tool_tip_and_units() {
        let tip = CellParam::ToolTip {
            robot: Robot::One,
            tool: 0,
            axis: Axis::Z,
        };
        let unit = ReportUnit::of(&tip);
        assert_eq!(unit, ReportUnit::Mm);
        let p = ParameterReport {
            identity: ParamIdentity::of(&tip).unwrap(),
            name: "robot 1 tool `tip` tip z".into(),
            prior_scale: 2.0,
            prior_sigma: 0.5,
            sigma: 0.1,
            tolerance: 0.75,
            unit,
            value: 1e-3 * unit.per_si(),
        };
        let json = serde_json::to_string(&p).unwrap();
        assert_eq!(
            json,
            r#"{"axis":"z","exceeds_tolerance":true,"exceeds_tolerance_beyond_noise":true,"joint":null,"kind":"tip","name":"robot 1 tool `tip` tip z","prior_scale":2.0,"prior_sigma":0.5,"robot":1,"sigma":0.1,"tolerance":0.75,"unit":"mm","value":1.0}"#
        );
        // 1.0 mm against ±0.75 mm + 2 × 0.1 mm: beyond the noise margin, a warning.
        let warning = p.tolerance_warning().unwrap();
        assert!(
            warning.starts_with("robot 1 tool `tip` tip z: fitted correction +1.0000 ± 0.1000 mm (1σ) exceeds its stated tolerance ±0.7500 mm by more than 2σ (1.3× it; prior scale applied ×2)"),
            "{warning}"
        );
        // Just beyond the tolerance but within 2σ of it (the 0.5028 mm against ±0.5 mm a
        // correct session gave): beyond the tolerance, no warning.
        let just_beyond = ParameterReport {
            value: 0.75 + 1.9 * 0.1,
            ..p.clone()
        };
        assert!(just_beyond.exceeds_tolerance());
        assert!(!just_beyond.exceeds_tolerance_beyond_noise());
        assert!(just_beyond.tolerance_warning().is_none());
        let past_margin = ParameterReport {
            value: -(0.75 + 2.1 * 0.1),
            ..p.clone()
        };
        assert!(past_margin.tolerance_warning().is_some());
        let within = ParameterReport {
            value: 0.7,
            ..p.clone()
        };
        assert!(!within.exceeds_tolerance());
        assert!(within.tolerance_warning().is_none());
        assert_eq!(json, sorted(&json));
        let compliance = CellParam::Kinematic {
            robot: Robot::One,
            param: ErrorParam::Compliance { joint: 1 },
        };
        assert_eq!(ReportUnit::of(&compliance).name(), "deg/kNm");
        assert_eq!(ReportUnit::DegPerKnm.per_si(), 1f64.to_degrees() * 1e3);
        assert_eq!(
            serde_json::to_string(&ReportUnit::DegPerKnm).unwrap(),
            r#""deg/kNm""#
        );
        assert!(ParamIdentity::of(&CellParam::PlacementRotation { axis: Axis::X }).is_none());
    }
}
