//! The study's core: the whole-cell problems of the CTU recordings (`calib_core::whole_cell`),
//! the MAP fits with the common base held fixed, grouped cross-validation of the prior σ (over
//! the [`SigmaGrid`] of `--sigma-grid`) and the parameter set, and the honest tracker score
//! (registration + reflector fitted on one half of a file's poses, scored on the other half,
//! both ways; any seeded split through [`score_recording_split`]).
//!
//! Units: SI inside (m, rad); the prior σ of a spec is one number `s` used as `s` mrad for joint
//! offsets and `s` mm for joint origin positions (as in the Python study).

use anyhow::Context;
use calib_core::stats::{quantile, sorted_finite};
use calib_core::whole_cell::{
    fit_cell_with, initial_estimate, CellEstimate, CellFit, CellParam, CellProblem, Evaluator,
    ObservationKind, ParamLayout, SolveOptions, Tolerance, Tool,
};
use calib_core::{LmOptions, Robot};
use handclasp_cell::{cell_problem, Cell, FitModel, Session, SessionKind, SessionObservation};
use kinematics::{Axis, ErrorParam, KinematicErrors};
use nalgebra::{Isometry3, Vector3};

use crate::data::{Recording, Role};

/// Starting self-contact distance of the no-tracker self-contact files, m (dataset README).
pub const CONTACT_START_M: f64 = 0.116;
/// Starting self-contact distance of the `leica_self_*` files, m (their nominal mean; another
/// set-up, fitted as its own group).
pub const LEICA_SELF_CONTACT_START_M: f64 = 0.1146;
/// Nominal Leica reflector on the right arm, tool0 frame, m (DH EE row a = 45 mm, d = 245 mm,
/// offset −0.38 rad).
pub const REFLECTOR_RIGHT_M: [f64; 3] = [0.041_789_9, -0.016_691_4, 0.245];
/// Nominal Leica reflector on the left arm, tool0 frame, m.
pub const REFLECTOR_LEFT_M: [f64; 3] = [0.05, 0.0, 0.25];
/// Tolerance of every tool tip offset that is fitted (the reflectors, one per tracker file),
/// m: 10 m, i.e. free in effect (the reflector's mounting is not known; on a file with small
/// wrist rotations its offset is weakly determined, and a tighter prior would bias the score).
pub const TIP_TOLERANCE_M: f64 = 10.0;
/// Prior σ of each component of a fitted marker centre (tool 0 tip of either arm), m: a
/// mounting tolerance of the dodecahedron on its 354 mm stem, set before any fit (the lead's
/// Python exploration used the same 2 mm); not chosen by any score.
pub const MARKER_CENTRE_SIGMA_M: f64 = 2e-3;
/// Tracker-frame σ of the honest score's fit, m (any positive value: every row has the same).
const SCORE_SIGMA_M: f64 = 2e-4;
/// Relative cost decrease at which a fit has converged: 1e-8 of a χ² of ~10³ moves no
/// parameter by a visible amount (the library's default 1e-10 only costs iterations in the flat
/// directions of free reflector offsets).
const COST_TOLERANCE: f64 = 1e-8;
/// Seed of the half split of the honest score.
pub const SPLIT_SEED: u64 = 12;
/// The default prior σ values cross-validation chooses from (mrad for offsets and mm for
/// lengths; see [`COMPLIANCE_TORQUE_REF_NM`] for compliance), fixed in stop 9 before any
/// evaluation score was seen; `--sigma-grid` ([`SigmaGrid`]) replaces it for a diagnostic run.
///
/// 10 mrad / 10 mm is left out: with lengths free and no length reference (the contact distance
/// and the planes are fitted), a loose prior lets the whole chain shrink — measured: the
/// self + planes fit at σ = 10 stopped at the iteration cap with a contact distance of 61.5 mm
/// and the arm 5–13 mm off on the tracker.
pub const SIGMA_GRID: [f64; 4] = [0.1, 0.3, 1.0, 3.0];
/// Fewest values a [`SigmaGrid`] holds: two, or there is nothing to choose.
pub const SIGMA_GRID_MIN_LEN: usize = 2;
/// Most values a [`SigmaGrid`] holds: each value adds one candidate per parameter set (6 sets
/// for `self` and `planes`, 4 for `all`), each fitted once per fold, so 8 values double the
/// study's CV cost.
pub const SIGMA_GRID_MAX_LEN: usize = 8;

/// The prior σ values cross-validation chooses from (`--sigma-grid`): between
/// [`SIGMA_GRID_MIN_LEN`] and [`SIGMA_GRID_MAX_LEN`] positive, finite, strictly increasing
/// values, one number `s` each (`s` mrad for joint offsets, `s` mm for joint origin positions,
/// `s` mrad of deflection at [`COMPLIANCE_TORQUE_REF_NM`] for compliance). The default is
/// [`SIGMA_GRID`]. Parsed from and displayed as a comma-separated list (`0.1,0.3,1,3`).
#[derive(Debug, Clone, PartialEq)]
pub struct SigmaGrid(Vec<f64>);

impl SigmaGrid {
    /// The values, strictly increasing.
    pub fn values(&self) -> &[f64] {
        &self.0
    }

    /// Whether this is the default grid [`SIGMA_GRID`].
    pub fn is_default(&self) -> bool {
        self.0 == SIGMA_GRID
    }
}

impl Default for SigmaGrid {
    fn default() -> Self {
        SigmaGrid(SIGMA_GRID.to_vec())
    }
}

impl std::fmt::Display for SigmaGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text: Vec<String> = self.0.iter().map(|s| s.to_string()).collect();
        write!(f, "{}", text.join(","))
    }
}

impl std::str::FromStr for SigmaGrid {
    type Err = String;

    /// Parses a comma-separated list (spaces around values allowed). Fails, with a message
    /// naming `--sigma-grid` and the fix, on an empty entry, a non-number, a value that is not
    /// positive and finite, a value not larger than the one before, or a count outside
    /// [`SIGMA_GRID_MIN_LEN`]`..=`[`SIGMA_GRID_MAX_LEN`].
    fn from_str(list: &str) -> Result<Self, Self::Err> {
        let fix = format!(
            "give {SIGMA_GRID_MIN_LEN} to {SIGMA_GRID_MAX_LEN} positive, finite, strictly \
             increasing prior σ values (mrad / mm) separated by commas, e.g. --sigma-grid \
             0.1,0.3,1,3,10 (default {})",
            SigmaGrid::default()
        );
        let mut values: Vec<f64> = Vec::new();
        for (i, item) in list.split(',').enumerate() {
            let item = item.trim();
            let v: f64 = item.parse().map_err(|_| {
                format!(
                    "--sigma-grid {list:?}: value {} {item:?} is not a number; {fix}",
                    i + 1
                )
            })?;
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "--sigma-grid {list:?}: value {} ({item}) is not positive and finite; {fix}",
                    i + 1
                ));
            }
            if let Some(&prev) = values.last() {
                if v <= prev {
                    return Err(format!(
                        "--sigma-grid {list:?}: value {} ({item}) is not larger than the one \
                         before ({prev}); {fix}",
                        i + 1
                    ));
                }
            }
            values.push(v);
        }
        if !(SIGMA_GRID_MIN_LEN..=SIGMA_GRID_MAX_LEN).contains(&values.len()) {
            return Err(format!(
                "--sigma-grid {list:?}: {} value(s); {fix}",
                values.len()
            ));
        }
        Ok(SigmaGrid(values))
    }
}
/// Torque that scales the compliance prior, N·m: a spec's σ `s` is `s` mrad of deflection at
/// this torque, i.e. a compliance prior σ of `s·1e-3 / 50` rad/(N·m). 50 N·m is about the
/// largest gravity torque about U of the URDFs' point masses (10 kg at the wrist centre, 0.64 m
/// from U): the prior on the deflection is as wide as the prior on the offsets. The masses'
/// overall scale only rescales the fitted compliance, but through this prior it also sets how
/// tight the prior is; CV over `s` chooses the width.
pub const COMPLIANCE_TORQUE_REF_NM: f64 = 50.0;
/// Joints (chain index) whose compliance is fitted: L and U (the Python study's compliance
/// group). R, B and T carry no mass off their axes in the URDFs (the wrist mass sits on the R and
/// B axes), so their torque is zero; S (tilted 15° from the base z by DH row TT) does carry a
/// torque, but its compliance is held at 0 like R, B and T.
pub const COMPLIANT_JOINTS: [usize; 2] = [1, 2];

/// Which kinematic parameters of both arms are fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamSet {
    /// Joint offsets S..T.
    Offsets,
    /// Joint offsets and the gravity compliance of L and U (rad/(N·m), torques from the URDFs'
    /// point-mass inertials).
    OffsetsCompliance,
    /// Joint offsets and the marker centres (tool 0 tip of both arms, x and y in tool0, prior σ
    /// [`MARKER_CENTRE_SIGMA_M`]; z held, see [`fit`]): the end-effector geometry of the flush
    /// face contacts.
    OffsetsMarker,
    /// Joint offsets and joint origin positions (the link lengths) S..T.
    OffsetsLengths,
    /// Offsets, lengths and the gravity compliance of L and U.
    OffsetsLengthsCompliance,
    /// Offsets, lengths and the marker centres.
    OffsetsLengthsMarker,
}

impl ParamSet {
    /// The sets cross-validated for every model, fewest parameters first (the
    /// one-standard-error rule's order of simplicity: 12, 16, 48, 52 parameters over both arms).
    pub const ALL: [ParamSet; 4] = [
        ParamSet::Offsets,
        ParamSet::OffsetsCompliance,
        ParamSet::OffsetsLengths,
        ParamSet::OffsetsLengthsCompliance,
    ];

    /// The sets cross-validated for the problems with self-contact and no tracker value (`self`,
    /// `planes`): [`Self::ALL`] and the two marker-centre sets, fewest parameters first (12, 16,
    /// 16, 48, 52, 52; a marker set after the compliance set of the same size).
    pub const WITH_MARKER: [ParamSet; 6] = [
        ParamSet::Offsets,
        ParamSet::OffsetsCompliance,
        ParamSet::OffsetsMarker,
        ParamSet::OffsetsLengths,
        ParamSet::OffsetsLengthsCompliance,
        ParamSet::OffsetsLengthsMarker,
    ];

    /// A short name for tables.
    pub fn name(self) -> &'static str {
        match self {
            ParamSet::Offsets => "offsets",
            ParamSet::OffsetsCompliance => "offsets+compl",
            ParamSet::OffsetsMarker => "offsets+marker",
            ParamSet::OffsetsLengths => "offsets+lengths",
            ParamSet::OffsetsLengthsCompliance => "offs+len+compl",
            ParamSet::OffsetsLengthsMarker => "offs+len+marker",
        }
    }

    /// Whether the set fits joint origin positions.
    pub fn lengths(self) -> bool {
        matches!(
            self,
            ParamSet::OffsetsLengths
                | ParamSet::OffsetsLengthsCompliance
                | ParamSet::OffsetsLengthsMarker
        )
    }

    /// Whether the set fits the gravity compliance of L and U.
    pub fn compliance(self) -> bool {
        matches!(
            self,
            ParamSet::OffsetsCompliance | ParamSet::OffsetsLengthsCompliance
        )
    }

    /// Whether the set fits the marker centres (tool 0 tips).
    pub fn marker(self) -> bool {
        matches!(
            self,
            ParamSet::OffsetsMarker | ParamSet::OffsetsLengthsMarker
        )
    }
}

/// A model to fit: parameter set and prior σ (mrad / mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelSpec {
    /// Fitted parameters.
    pub set: ParamSet,
    /// Prior σ: mrad for offsets, mm for origin positions.
    pub sigma: f64,
}

/// Noise σ of each observation class, m (from the nominal fit's residuals, see
/// [`noise_from_nominal`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseLevels {
    /// No-tracker self-contact distance.
    pub contact_m: f64,
    /// No-tracker self-contact distance in the fits of the marker-centre sets
    /// ([`ParamSet::marker`]); `None`: [`Self::contact_m`]. Held-out rows are always whitened
    /// with `contact_m`, so CV errors stay comparable between candidates.
    pub marker_contact_m: Option<f64>,
    /// `leica_self` self-contact distance.
    pub leica_contact_m: f64,
    /// Plane contact.
    pub plane_m: f64,
    /// Tracker position, per axis.
    pub tracker_m: f64,
}

/// Where an observation of a built problem came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Origin {
    /// Index into the recordings given to [`build_problem`].
    pub recording: usize,
    /// Index of the pose in that recording.
    pub pose: usize,
}

/// A problem with the source of each observation.
pub struct Built {
    /// The problem.
    pub problem: CellProblem,
    /// Source of each observation.
    pub origin: Vec<Origin>,
    /// Prior σ of the marker centres (tool 0 tips of both arms), m; `None`: held at the cell's.
    pub marker_sigma_m: Option<f64>,
}

/// The prior of `spec` as tolerances of both robots: joint offsets (and, as the set selects,
/// origin positions and L/U compliance) at √3·σ, every tool tip free in effect
/// ([`TIP_TOLERANCE_M`]), the rest held; `None`: only the tips.
pub fn tolerance(spec: Option<ModelSpec>) -> Tolerance {
    let mut t = Tolerance::none();
    t.tip_m = TIP_TOLERANCE_M;
    if let Some(s) = spec {
        // tolerance = √3·σ (the prior of a tolerance is N(0, (tol/√3)²)).
        t.joint_offset_rad = 3f64.sqrt() * s.sigma * 1e-3;
        if s.set.lengths() {
            t.origin_xyz_m = 3f64.sqrt() * s.sigma * 1e-3;
        }
        if s.set.compliance() {
            t.compliance_rad_per_nm = Some(3f64.sqrt() * s.sigma * 1e-3 / COMPLIANCE_TORQUE_REF_NM);
        }
    }
    t
}

/// The cell the study fits: `cell` with the prior of `spec` ([`tolerance`]) on both robots and,
/// as their extra tools (`[robotN.tools]` replaced), one Leica reflector per tracker file in
/// `recordings` (named `reflector FILE`, at its arm's nominal reflector), in recording order.
pub fn study_cell(cell: &Cell, recordings: &[&Recording], spec: Option<ModelSpec>) -> Cell {
    let mut cell = cell.clone();
    for robot in [&mut cell.robot1, &mut cell.robot2] {
        robot.tolerance = tolerance(spec);
        robot.tools.clear();
    }
    for rec in recordings {
        if matches!(rec.role, Role::Tracker | Role::TrackerSelfContact) {
            let (robot, nominal) = if rec.right_arm {
                (&mut cell.robot1, REFLECTOR_RIGHT_M)
            } else {
                (&mut cell.robot2, REFLECTOR_LEFT_M)
            };
            robot.tools.push(Tool {
                name: format!("reflector {}", rec.name),
                flange_from_tip: Vector3::from(nominal),
            });
        }
    }
    cell
}

/// The recordings as one handclasp session (every row an observation, numbered from 1 in
/// recording and pose order) and the source of each row, with the σ of `noise` (the marker
/// model's contact σ for a `spec` that fits the marker centres). Its tools are those of
/// [`study_cell`]'s cell: 0 the marker, then each arm's reflectors in recording order. Rows: see
/// [`build_problem`].
pub fn recordings_session(
    recordings: &[&Recording],
    spec: Option<ModelSpec>,
    noise: &NoiseLevels,
) -> (Session, Vec<Origin>) {
    let mut observations = Vec::new();
    let mut origin = Vec::new();
    let mut reflectors = [0usize; 2];
    for (ri, rec) in recordings.iter().enumerate() {
        let arm = if rec.right_arm {
            Robot::One
        } else {
            Robot::Two
        };
        // Tool 0 is the marker (the cell's tip); the reflectors follow, one per tracker file.
        let reflector = if matches!(rec.role, Role::Tracker | Role::TrackerSelfContact) {
            reflectors[usize::from(arm == Robot::Two)] += 1;
            reflectors[usize::from(arm == Robot::Two)]
        } else {
            0
        };
        for (pi, pose) in rec.poses.iter().enumerate() {
            let q_arm = if rec.right_arm {
                &pose.q_right
            } else {
                &pose.q_left
            };
            let mut kinds = Vec::new();
            match rec.role {
                Role::SelfContact | Role::TrackerSelfContact => {
                    let leica = rec.role == Role::TrackerSelfContact;
                    let group = if leica { "leica_self" } else { "no_leica_self" }.to_string();
                    let sigma_m = if leica {
                        noise.leica_contact_m
                    } else if spec.is_some_and(|s| s.set.marker()) {
                        noise.marker_contact_m.unwrap_or(noise.contact_m)
                    } else {
                        noise.contact_m
                    };
                    let (q1, q2) = (pose.q_right.clone(), pose.q_left.clone());
                    kinds.push(match pose.faces {
                        None => SessionKind::Contact {
                            q1,
                            q2,
                            tool1: 0,
                            tool2: 0,
                            group,
                            distance_m: None,
                            sigma_m,
                        },
                        Some(f) => SessionKind::FaceContact {
                            q1,
                            q2,
                            tool1: 0,
                            tool2: 0,
                            n1_tip: f.right.1,
                            n2_tip: f.left.1,
                            group,
                            distance_m: None,
                            sigma_m,
                        },
                    });
                }
                Role::Plane => kinds.push(SessionKind::Plane {
                    robot: Robot::One,
                    q: pose.q_right.clone(),
                    tool: 0,
                    group: rec.name.clone(),
                    sigma_m: noise.plane_m,
                }),
                Role::Tracker => {}
            }
            if matches!(rec.role, Role::Tracker | Role::TrackerSelfContact) {
                if let Some(p_tracker) = pose.p_tracker {
                    kinds.push(SessionKind::Tracker {
                        robot: arm,
                        q: q_arm.clone(),
                        tool: reflector,
                        group: rec.name.clone(),
                        p_tracker,
                        sigma_m: noise.tracker_m,
                    });
                }
            }
            for kind in kinds {
                observations.push(SessionObservation {
                    point: observations.len() + 1,
                    kind,
                });
                origin.push(Origin {
                    recording: ri,
                    pose: pi,
                });
            }
        }
    }
    let session = Session {
        points: Vec::new(),
        observations,
        ..Session::default()
    };
    (session, origin)
}

/// The whole-cell problem of `recordings` in `cell` (robot 1 = right arm, robot 2 = left arm,
/// tool 0 = the marker dodecahedron of the cell), built by handclasp-cell's adapter
/// ([`cell_problem`]) from the recordings as a session ([`recordings_session`]) in the cell of the study
/// ([`study_cell`]): self-contact rows as `contact` (one fitted distance for the no-tracker
/// files, group `no_leica_self`, one for `leica_self`), or as `face_contact` in the same groups
/// and σ for a pose whose touching faces are set (`Pose::faces`); plane rows as `plane` of the
/// right arm's marker (one plane per file), tracker rows as `tracker` of the measured arm (one
/// frame and one reflector tool per file). Two things the adapter does otherwise are set here:
/// tool 0 is named `marker`, and a contact distance starts at [`CONTACT_START_M`] /
/// [`LEICA_SELF_CONTACT_START_M`] (the adapter starts it at the rows' mean nominal distance).
/// `spec = None`: nominal kinematics (only the nuisances and the reflectors are fitted).
pub fn build_problem(
    cell: &Cell,
    recordings: &[&Recording],
    spec: Option<ModelSpec>,
    noise: &NoiseLevels,
) -> Built {
    let (session, origin) = recordings_session(recordings, spec, noise);
    let mut problem = cell_problem(
        &study_cell(cell, recordings, spec),
        &session,
        FitModel::Kinematic,
    );
    for robot in [&mut problem.robot1, &mut problem.robot2] {
        robot.tools[0].name = "marker".into();
    }
    for group in &mut problem.contacts {
        group.distance_m = if group.name == "leica_self" {
            LEICA_SELF_CONTACT_START_M
        } else {
            CONTACT_START_M
        };
    }
    Built {
        problem,
        origin,
        marker_sigma_m: spec
            .filter(|s| s.set.marker())
            .map(|_| MARKER_CENTRE_SIGMA_M),
    }
}

/// MAP fit of `built` over `active` (all rows when `None`), starting from `start` corrections
/// (`None`: nominal; the `tip` field of each carries the marker centre's offset, see
/// [`corrections`]), with `b1_from_b2` held by the cell's placement prior
/// (`CellProblem::placement_prior`), the marker tips (tool 0) fitted with prior σ
/// `built.marker_sigma_m` (x, y; z held) or else held at the start, and compliance (when the tolerances select
/// it) only on [`COMPLIANT_JOINTS`].
pub fn fit(
    built: &Built,
    active: Option<&[usize]>,
    start: Option<(&KinematicErrors, &KinematicErrors)>,
) -> anyhow::Result<CellFit> {
    let problem = &built.problem;
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let active = active.unwrap_or(&all);
    let mut fixed = Vec::new();
    for robot in [Robot::One, Robot::Two] {
        // Marker centres: only x, y are fitted. Along tool z a shift of either centre changes
        // the distance along every ring-face normal by the same cos(arctan 2)·z, which the
        // fitted contact distance already is (measured: with z free and the contact σ of the
        // marker model, the two z drift to ∓11 mm in opposite senses, fitting the sliding of
        // the faces, which the centre-distance contact row cannot tell from the normal).
        let marker_fixed: &[Axis] = if built.marker_sigma_m.is_some() {
            &[Axis::Z]
        } else {
            &Axis::ALL
        };
        for &axis in marker_fixed {
            fixed.push(CellParam::ToolTip {
                robot,
                tool: 0,
                axis,
            });
        }
        for joint in (0..6).filter(|j| !COMPLIANT_JOINTS.contains(j)) {
            fixed.push(CellParam::Kinematic {
                robot,
                param: ErrorParam::Compliance { joint },
            });
        }
    }
    let mut layout = ParamLayout::new(problem, &fixed);
    if let Some(sigma) = built.marker_sigma_m {
        // The tolerance's tip σ is the reflectors' (free in effect); the marker gets its own.
        for robot in [Robot::One, Robot::Two] {
            for axis in [Axis::X, Axis::Y] {
                let p = CellParam::ToolTip {
                    robot,
                    tool: 0,
                    axis,
                };
                let col = layout
                    .column(&p)
                    .context("the marker centre is not a column of the layout")?;
                for row in 0..layout.prior_sqrt_info.nrows() {
                    if layout.prior_sqrt_info[(row, col)] != 0.0 {
                        layout.prior_sqrt_info[(row, col)] = 1.0 / sigma;
                    }
                }
            }
        }
    }
    let mut est = initial_estimate(problem, Some(Isometry3::identity()), active)
        .context("starting values (tracker frames, planes)")?;
    if let Some((right, left)) = start {
        est.robot1.errors = right.clone();
        est.robot2.errors = left.clone();
        est.robot1.tool_tip_m[0] = right.tip;
        est.robot2.tool_tip_m[0] = left.tip;
    }
    let options = SolveOptions {
        lm: LmOptions::whole_cell().with_cost_tolerance(COST_TOLERANCE)?,
        ..SolveOptions::default()
    };
    let fit = fit_cell_with(problem, layout, active, Some(&est), &options).context("MAP fit")?;
    Ok(fit)
}

/// Residuals (m, unwhitened, one norm per observation) and whitened squared norms of every
/// observation of `problem` at `est`.
pub fn residuals(
    problem: &CellProblem,
    fit: &CellFit,
    est: &CellEstimate,
) -> anyhow::Result<Vec<(f64, f64)>> {
    let ev = Evaluator::new(problem, &fit.layout);
    problem
        .observations
        .iter()
        .map(|o| {
            let l = ev.linearise(o, est, false)?;
            let w = &l.whitening * &l.residual;
            Ok((l.residual.norm(), w.norm_squared()))
        })
        .collect()
}

/// Noise σ of each class from the nominal fit of every recording (kinematics nominal; contact
/// distances, planes, tracker frames and reflectors fitted): the rms residual per scalar row.
/// These σ are the model error of the nominal model, which is what a calibration must explain.
pub fn noise_from_nominal(cell: &Cell, recordings: &[Recording]) -> anyhow::Result<NoiseLevels> {
    let start = NoiseLevels {
        contact_m: 1e-3,
        marker_contact_m: None,
        leica_contact_m: 1e-3,
        plane_m: 1e-3,
        tracker_m: 1e-3,
    };
    let recs: Vec<&Recording> = recordings.iter().collect();
    let b = build_problem(cell, &recs, None, &start);
    let f = fit(&b, None, None)?;
    let res = residuals(&b.problem, &f, &f.estimate)?;
    let mut acc = [(0.0, 0usize); 4];
    for (o, (r, _)) in b.problem.observations.iter().zip(&res) {
        let (k, dim) = match &o.kind {
            ObservationKind::Contact { group: 0, .. }
            | ObservationKind::FaceContact { group: 0, .. } => (0, 1),
            ObservationKind::Contact { .. } | ObservationKind::FaceContact { .. } => (1, 1),
            ObservationKind::Plane { .. } => (2, 1),
            _ => (3, 3),
        };
        acc[k].0 += r * r;
        acc[k].1 += dim;
    }
    let rms = |(s, n): (f64, usize)| (s / n.max(1) as f64).sqrt();
    Ok(NoiseLevels {
        contact_m: rms(acc[0]),
        marker_contact_m: None,
        leica_contact_m: rms(acc[1]),
        plane_m: rms(acc[2]),
        tracker_m: rms(acc[3]),
    })
}

/// Both arms' kinematic corrections of a fit (right, left), each with its marker centre's
/// offset (tool 0 tip error, m, tool0 axes) in the `tip` field. Any other tip (a reflector)
/// must use these with `tip` set to zero.
pub fn corrections(fit: &CellFit) -> (KinematicErrors, KinematicErrors) {
    (
        fit.estimate.robot1.errors_for_tool(0),
        fit.estimate.robot2.errors_for_tool(0),
    )
}

/// The observation kind of a held-out row: each kind has its own CV error in the per-kind
/// selection rule (`cv`). Ordered as the CV table's columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum RowKind {
    /// A self-contact distance row (either contact group).
    Contact,
    /// A plane-contact row.
    Plane,
    /// A tracker point (the honest protocol's held-out pose, or a tracker observation).
    Tracker,
}

impl RowKind {
    /// The kind's name in tables and CSV columns.
    pub fn name(self) -> &'static str {
        match self {
            RowKind::Contact => "contact",
            RowKind::Plane => "plane",
            RowKind::Tracker => "tracker",
        }
    }
}

/// Held-out error of held-out recordings that are not scored by the tracker protocol: the
/// problem of `recordings` with nominal tolerances (only contact distances and planes fitted) at
/// the given corrections; returns the whitened square of each scalar row (σ units).
pub fn held_out_nuisance_cost(
    cell: &Cell,
    recordings: &[&Recording],
    corr: (&KinematicErrors, &KinematicErrors),
    noise: &NoiseLevels,
) -> anyhow::Result<Vec<f64>> {
    Ok(held_out_nuisance_rows(cell, recordings, corr, noise)?
        .into_iter()
        .map(|(_, e2)| e2)
        .collect())
}

/// [`held_out_nuisance_cost`] with the kind of each row: (kind, whitened square). Fails on an
/// observation kind the study does not build (it would have no CV column).
pub fn held_out_nuisance_rows(
    cell: &Cell,
    recordings: &[&Recording],
    corr: (&KinematicErrors, &KinematicErrors),
    noise: &NoiseLevels,
) -> anyhow::Result<Vec<(RowKind, f64)>> {
    let b = build_problem(cell, recordings, None, noise);
    let f = fit(&b, None, Some(corr))?;
    let res = residuals(&b.problem, &f, &f.estimate)?;
    // Contact and plane rows are scalar: the whitened square is the row's.
    b.problem
        .observations
        .iter()
        .zip(&res)
        .map(|(o, r)| {
            let kind = match o.kind {
                ObservationKind::Contact { .. } | ObservationKind::FaceContact { .. } => {
                    RowKind::Contact
                }
                ObservationKind::Plane { .. } => RowKind::Plane,
                ObservationKind::Tracker { .. } => RowKind::Tracker,
                _ => anyhow::bail!(
                    "held-out row of an observation kind the CTU study does not build: {:?}",
                    o.kind
                ),
            };
            Ok((kind, r.1))
        })
        .collect()
}

/// One held-out tracker point of the honest score.
#[derive(Debug, Clone)]
pub struct ScoredPose {
    /// The measured arm's joints, rad.
    pub q: Vec<f64>,
    /// Held-out 3-D error, m.
    pub error_m: f64,
}

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seeded half split of `n` rows: indices of half A (⌊n/2⌋ rows) and half B, each ascending.
pub fn halves(n: usize, seed: u64) -> (Vec<usize>, Vec<usize>) {
    let mut idx: Vec<usize> = (0..n).collect();
    idx.sort_by_key(|&i| splitmix64(seed ^ splitmix64(i as u64)));
    let (a, b) = idx.split_at(n / 2);
    let (mut a, mut b) = (a.to_vec(), b.to_vec());
    a.sort_unstable();
    b.sort_unstable();
    (a, b)
}

/// The honest tracker score of one arm model on one tracker recording: one rigid registration
/// (`tracker_from_base`) and the reflector offset (tool0) fitted on half A of the poses (seeded
/// split, [`SPLIT_SEED`]), the other half's 3-D errors predicted; then the halves swapped. The
/// arm's kinematics are `corr` (held). With `local_sigma = Some(s)`, offsets and lengths are
/// also fitted on the fitting half with the weak prior `s` (mrad / mm): the error left by a
/// rigid-geometry calibration of this file alone.
pub fn score_recording(
    cell: &Cell,
    rec: &Recording,
    corr: (&KinematicErrors, &KinematicErrors),
    local_sigma: Option<f64>,
) -> anyhow::Result<Vec<ScoredPose>> {
    score_recording_split(cell, rec, corr, local_sigma, SPLIT_SEED)
}

/// [`score_recording`] with the half split of seed `split_seed` ([`halves`] of the recording's
/// tracker rows) instead of [`SPLIT_SEED`]: the same protocol on another random split.
pub fn score_recording_split(
    cell: &Cell,
    rec: &Recording,
    corr: (&KinematicErrors, &KinematicErrors),
    local_sigma: Option<f64>,
    split_seed: u64,
) -> anyhow::Result<Vec<ScoredPose>> {
    let noise = NoiseLevels {
        contact_m: SCORE_SIGMA_M,
        marker_contact_m: None,
        leica_contact_m: SCORE_SIGMA_M,
        plane_m: SCORE_SIGMA_M,
        tracker_m: SCORE_SIGMA_M,
    };
    let tracker_only = Recording {
        role: Role::Tracker,
        ..rec.clone()
    };
    let spec = local_sigma.map(|sigma| ModelSpec {
        set: ParamSet::OffsetsLengths,
        sigma,
    });
    let b = build_problem(cell, &[&tracker_only], spec, &noise);
    let n = b.problem.observations.len();
    let (ha, hb) = halves(n, split_seed);
    let mut out = Vec::new();
    for (train, test) in [(&ha, &hb), (&hb, &ha)] {
        let f =
            fit(&b, Some(train), Some(corr)).with_context(|| format!("scoring {}", rec.name))?;
        let res = residuals(&b.problem, &f, &f.estimate)?;
        for &i in test.iter() {
            let pose = &rec.poses[b.origin[i].pose];
            out.push(ScoredPose {
                q: if rec.right_arm {
                    pose.q_right.clone()
                } else {
                    pose.q_left.clone()
                },
                error_m: res[i].0,
            });
        }
    }
    Ok(out)
}

/// rms, median, p95, max of errors (m in, mm out) and their count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Count.
    pub n: usize,
    /// rms, mm.
    pub rms_mm: f64,
    /// Median, mm.
    pub median_mm: f64,
    /// 95th percentile, mm.
    pub p95_mm: f64,
    /// Maximum, mm.
    pub max_mm: f64,
}

/// Summary of errors in m.
pub fn summarise(errors_m: &[f64]) -> Summary {
    let s = sorted_finite(errors_m.iter().map(|e| e * 1e3));
    let n = s.len();
    Summary {
        n,
        rms_mm: (s.iter().map(|e| e * e).sum::<f64>() / n.max(1) as f64).sqrt(),
        median_mm: quantile(&s, 0.5),
        p95_mm: quantile(&s, 0.95),
        max_mm: s.last().copied().unwrap_or(f64::NAN),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_grid_parses_good_lists_and_round_trips_through_its_display() {
        let g: SigmaGrid = "0.1,0.3,1,3".parse().unwrap();
        assert_eq!(g, SigmaGrid::default());
        assert!(g.is_default());
        assert_eq!(g.to_string(), "0.1,0.3,1,3");
        assert_eq!(g.to_string().parse::<SigmaGrid>().unwrap(), g);
        let g: SigmaGrid = " 0.1, 0.3 ,1,3,1e1".parse().unwrap();
        assert_eq!(g.values(), [0.1, 0.3, 1.0, 3.0, 10.0]);
        assert!(!g.is_default());
        assert_eq!(g.to_string(), "0.1,0.3,1,3,10");
        // The length limits are inclusive.
        assert_eq!("0.5,2".parse::<SigmaGrid>().unwrap().values().len(), 2);
        let eight = "1,2,3,4,5,6,7,8".parse::<SigmaGrid>().unwrap();
        assert_eq!(eight.values().len(), SIGMA_GRID_MAX_LEN);
    }

    #[test]
    fn sigma_grid_refuses_bad_lists_naming_the_flag_and_the_fix() {
        for (list, why) in [
            ("", "not a number"),
            ("3", "1 value(s)"),
            ("0.1,,3", "value 2 \"\" is not a number"),
            ("0.1,x,3", "value 2 \"x\" is not a number"),
            ("0,1,3", "value 1 (0) is not positive"),
            ("-1,1,3", "value 1 (-1) is not positive"),
            ("0.1,inf", "value 2 (inf) is not positive and finite"),
            ("0.1,NaN", "value 2 (NaN) is not positive and finite"),
            (
                "0.1,3,1",
                "value 3 (1) is not larger than the one before (3)",
            ),
            (
                "0.1,1,1",
                "value 3 (1) is not larger than the one before (1)",
            ),
            ("1,2,3,4,5,6,7,8,9", "9 value(s)"),
        ] {
            let e = list.parse::<SigmaGrid>().unwrap_err();
            assert!(e.starts_with("--sigma-grid "), "{list:?}: {e}");
            assert!(e.contains(why), "{list:?}: {e}");
            assert!(
                e.contains("give 2 to 8 positive, finite, strictly increasing"),
                "{list:?}: {e}"
            );
            assert!(e.contains("(default 0.1,0.3,1,3)"), "{list:?}: {e}");
        }
    }
}
