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

/// A fitted kinematic parameter (or tool tip) in its [`ReportUnit`]. JSON: `axis`, `joint`,
/// `kind`, `name`, `prior_sigma`, `robot`, `sigma`, `unit`, `value`.
#[derive(Debug, Clone)]
pub struct ParameterReport {
    /// Robot, kind, joint and axis.
    pub identity: ParamIdentity,
    /// Readable name, e.g. `robot 2 origin_xyz joint 3 x`.
    pub name: String,
    /// Prior σ (the chosen prior scale is not applied).
    pub prior_sigma: f64,
    /// Posterior σ.
    pub sigma: f64,
    /// The unit of `value`, `sigma` and `prior_sigma`.
    pub unit: ReportUnit,
    /// The fitted correction.
    pub value: f64,
}

impl Serialize for ParameterReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let id = &self.identity;
        let mut m = s.serialize_map(Some(9 + usize::from(id.link.is_some())))?;
        m.serialize_entry("axis", &id.axis)?;
        m.serialize_entry("joint", &id.joint)?;
        m.serialize_entry("kind", id.kind)?;
        if let Some(link) = id.link {
            m.serialize_entry("link", &link)?;
        }
        m.serialize_entry("name", &self.name)?;
        m.serialize_entry("prior_sigma", &self.prior_sigma)?;
        m.serialize_entry("robot", &id.robot)?;
        m.serialize_entry("sigma", &self.sigma)?;
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

/// The prior scale chosen by the evidence ([`super::PriorScaleChoice`]).
#[derive(Debug, Clone, Serialize)]
pub struct PriorScaleReport {
    /// The chosen scale.
    pub chosen: f64,
    /// Every scale that fitted, with its log evidence.
    pub log_evidence: Vec<LogEvidenceReport>,
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
                Some(identity) => parameters.push(ParameterReport {
                    identity,
                    name: p.name.clone(),
                    prior_sigma: p.prior_sigma * k,
                    sigma: p.posterior_sigma * k,
                    unit,
                    value: p.value * k,
                }),
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
            prior_sigma: 0.5,
            sigma: 0.25,
            unit,
            value: 1e-3 * unit.per_si(),
        };
        let json = serde_json::to_string(&p).unwrap();
        assert_eq!(
            json,
            r#"{"axis":"z","joint":null,"kind":"tip","name":"robot 1 tool `tip` tip z","prior_sigma":0.5,"robot":1,"sigma":0.25,"unit":"mm","value":1.0}"#
        );
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
