//! A sweep's grid and settings, and their validation.

use calib_core::{Method, MountPair};

use super::MAX_GEOMETRY_POINTS;
use crate::error::SimError;
use crate::layout::Layout;
use crate::placement::{mounts_label, paper_placement};

/// Simulation mode of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Points and noise only (fast).
    Geometry,
    /// Full sessions on robot cells (IK, reach, joint-level noise).
    Robot,
}

impl Mode {
    /// `geometry` or `robot`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Geometry => "geometry",
            Mode::Robot => "robot",
        }
    }
}

/// A method fitted on every trial of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SweepMethod {
    /// A point-registration method of calib-core ([`Method`]) on all the session's nominal tips.
    Registration(Method),
    /// Robot mode: the paper's 4-point method on the 4 most spread tips of the session (the
    /// four whose tetrahedron has the largest volume, robot 1's nominal tips).
    PaperSpread4,
    /// Robot mode: the whole-cell placement-only fit ([`handclasp_cell::problem::FitModel::Placement`],
    /// both robots nominal, blunder-screened).
    Placement,
    /// Robot mode: the whole-cell MAP fit of `b1_from_b2` and both robots' kinematic parameters
    /// ([`handclasp_cell::problem::FitModel::Kinematic`], [`calib_core::whole_cell::calibrate_cell`]).
    Kinematic,
}

impl From<Method> for SweepMethod {
    fn from(m: Method) -> Self {
        SweepMethod::Registration(m)
    }
}

impl SweepMethod {
    /// The methods beyond calib-core's registration methods (robot mode only), in display order.
    pub const ROBOT_EXTRAS: [SweepMethod; 3] = [
        SweepMethod::PaperSpread4,
        SweepMethod::Placement,
        SweepMethod::Kinematic,
    ];

    /// The name in files and on the command line (a registration method's own name,
    /// `paper-spread4`, `placement`, `kinematic`).
    pub fn name(self) -> &'static str {
        match self {
            SweepMethod::Registration(m) => m.name(),
            SweepMethod::PaperSpread4 => "paper-spread4",
            SweepMethod::Placement => "placement",
            SweepMethod::Kinematic => "kinematic",
        }
    }

    /// Parses a name given by [`SweepMethod::name`]; `None` otherwise.
    pub fn from_name(text: &str) -> Option<SweepMethod> {
        if let Some(m) = Method::from_name(text) {
            return Some(m.into());
        }
        let t = text.trim().to_ascii_lowercase();
        Self::ROBOT_EXTRAS.into_iter().find(|m| m.name() == t)
    }

    /// Whether the method needs robot mode (a session, not bare points).
    pub fn robot_only(self) -> bool {
        !matches!(self, SweepMethod::Registration(_))
    }
}

/// Where a sweep's teach points come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SweepLayout {
    /// A drawn [`Layout`] (a fresh draw per trial; random layouts redrawn until reachable).
    Points(Layout),
    /// Robot mode: the greedy A-optimal plan of the grid cell's point count from
    /// [`super::PLAN_CANDIDATES`] seeded reachable candidates in the spread cube around the
    /// cell's centre, made once per grid cell on the NOMINAL cell
    /// ([`calib_core::whole_cell::greedy_design`], cooperative criterion over the held-out pairs);
    /// every trial teaches the same planned points on its own true robots.
    Planned,
}

impl From<Layout> for SweepLayout {
    fn from(l: Layout) -> Self {
        SweepLayout::Points(l)
    }
}

impl SweepLayout {
    /// The name in files and on the command line (`planned` or the layout's name).
    pub fn name(self) -> &'static str {
        match self {
            SweepLayout::Points(l) => l.name(),
            SweepLayout::Planned => "planned",
        }
    }
}

impl std::fmt::Display for SweepLayout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The true kinematic errors of a robot-mode trial's robots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum KinematicErrorDraw {
    /// The cell's `[robotN.errors]` as written (zero when absent), the same in every trial.
    None,
    /// Per trial, every parameter the robot's `[robotN.tolerance]` selects (joint offsets,
    /// origin xyz/rpy, scale and compliance when given, the tip) drawn from `U(±tolerance)`,
    /// both robots, from the trial's own generator (replacing the cell's value of that
    /// parameter; mount errors stay as written).
    Tolerance,
}

impl KinematicErrorDraw {
    /// `none` or `tolerance`.
    pub fn name(self) -> &'static str {
        match self {
            KinematicErrorDraw::None => "none",
            KinematicErrorDraw::Tolerance => "tolerance",
        }
    }
}

/// A sweep's grid and settings. Noise is the operator's isotropic alignment σ per axis.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    /// Simulation mode.
    pub mode: Mode,
    /// Mount pairs (geometry mode: the paper's cells only, see [`crate::placement`]).
    pub mounts: Vec<MountPair>,
    /// Alignment σ per axis, mm.
    pub noise_mm: Vec<f64>,
    /// Layout spreads, m.
    pub spread_m: Vec<f64>,
    /// Point counts.
    pub n_points: Vec<usize>,
    /// Methods fitted on every trial.
    pub methods: Vec<SweepMethod>,
    /// Teach-point layout.
    pub layout: SweepLayout,
    /// Robot mode: the robots' true kinematic errors per trial.
    pub kinematic_errors: KinematicErrorDraw,
    /// Trials per grid cell.
    pub trials: usize,
    /// Master seed.
    pub seed: u64,
}

impl Default for SweepConfig {
    /// The default study: the paper's three cells, noise 0.5/1/2/3 mm, spread 0.25/0.5/1/1.5 m,
    /// 4/6/8/12 points, every method, tetrahedron layout, 200 trials per cell, seed 1, geometry mode.
    fn default() -> Self {
        SweepConfig {
            mode: Mode::Geometry,
            mounts: vec![
                MountPair::floor_floor(),
                MountPair::floor_wall(),
                MountPair::floor_ceiling(),
            ],
            noise_mm: vec![0.5, 1.0, 2.0, 3.0],
            spread_m: vec![0.25, 0.5, 1.0, 1.5],
            n_points: vec![4, 6, 8, 12],
            methods: Method::ALL.map(SweepMethod::from).to_vec(),
            layout: Layout::Tetrahedron.into(),
            kinematic_errors: KinematicErrorDraw::None,
            trials: 200,
            seed: 1,
        }
    }
}

/// One grid cell: indices into the config's axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridCell {
    /// Index into `mounts`.
    pub mounts: usize,
    /// Index into `noise_mm`.
    pub noise: usize,
    /// Index into `spread_m`.
    pub spread: usize,
    /// Index into `n_points`.
    pub n: usize,
}

impl SweepConfig {
    /// Checks every axis: non-empty, finite, in range; names the axis and what would work.
    pub fn validate(&self) -> Result<(), SimError> {
        let empty = |name: &str| {
            SimError::InvalidInput(format!("the {name} axis is empty: give at least one value"))
        };
        if self.mounts.is_empty() {
            return Err(empty("mounts"));
        }
        if self.noise_mm.is_empty() {
            return Err(empty("noise"));
        }
        if self.spread_m.is_empty() {
            return Err(empty("spread"));
        }
        if self.n_points.is_empty() {
            return Err(empty("points"));
        }
        if self.methods.is_empty() {
            return Err(empty("methods"));
        }
        if self.trials == 0 {
            return Err(SimError::InvalidSetting {
                field: "trials",
                message: "must be at least 1".into(),
            });
        }
        if let Some(v) = self
            .noise_mm
            .iter()
            .find(|v| !(v.is_finite() && **v >= 0.0))
        {
            return Err(SimError::InvalidInput(format!(
                "noise {v} mm must be finite and ≥ 0 (e.g. 0.5,1,2,3)"
            )));
        }
        if let Some(v) = self.spread_m.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(SimError::InvalidInput(format!(
                "spread {} mm must be a positive length (e.g. 250,500,1000,1500)",
                v * 1000.0
            )));
        }
        if let Some(n) = self
            .n_points
            .iter()
            .find(|n| **n < 3 || **n > MAX_GEOMETRY_POINTS)
        {
            return Err(SimError::InvalidInput(format!(
                "{n} points is out of range: use 3..={MAX_GEOMETRY_POINTS} (the 4-point methods need ≥ 4)"
            )));
        }
        if self.mode == Mode::Geometry {
            if let Some(m) = self.methods.iter().find(|m| m.robot_only()) {
                return Err(SimError::InvalidInput(format!(
                    "method {} needs robot sessions: use --mode robot",
                    m.name()
                )));
            }
            if self.layout == SweepLayout::Planned {
                return Err(SimError::InvalidInput(
                    "the planned layout needs robots: use --mode robot".into(),
                ));
            }
            if self.kinematic_errors != KinematicErrorDraw::None {
                return Err(SimError::InvalidInput(
                    "kinematic errors need robots: use --mode robot".into(),
                ));
            }
            if let Some(m) = self.mounts.iter().find(|m| paper_placement(m).is_none()) {
                return Err(SimError::InvalidInput(format!(
                    "geometry mode knows the paper's cells only (floor-floor, floor-wall, floor-ceiling), not {}",
                    mounts_label(m)
                )));
            }
        }
        Ok(())
    }

    /// The grid cells in sweep order (mounts, noise, spread, n; n fastest).
    pub fn grid(&self) -> Vec<GridCell> {
        let mut out = Vec::new();
        for mounts in 0..self.mounts.len() {
            for noise in 0..self.noise_mm.len() {
                for spread in 0..self.spread_m.len() {
                    for n in 0..self.n_points.len() {
                        out.push(GridCell {
                            mounts,
                            noise,
                            spread,
                            n,
                        });
                    }
                }
            }
        }
        out
    }

    /// Total number of trials (grid cells × trials per cell).
    pub fn total_trials(&self) -> usize {
        self.mounts.len()
            * self.noise_mm.len()
            * self.spread_m.len()
            * self.n_points.len()
            * self.trials
    }
}
