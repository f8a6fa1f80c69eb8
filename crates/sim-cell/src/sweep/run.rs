//! Running a sweep: every trial of every grid cell in parallel, each from its own generator.

use nalgebra::{Point3, Vector3};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::config::{GridCell, Mode, SweepConfig, SweepLayout, SweepMethod};
use super::geometry::{draw_geometry, GeometrySpec};
use super::robot::{robot_setup, robot_trial, setup_rng, RobotSetup};
use super::{CHUNK, MAX_GEOMETRY_POINTS};
use crate::error::SimError;
use crate::layout::Layout;
use crate::placement::{mounts_label, paper_placement};
use crate::trial_rng;
use calib_core::{fit_fast, ErotTruth, TrialErrors};
use handclasp_cell::cell::Cell;

/// [`trial_rng`] for many trials of one seed: the seed is expanded into the ChaCha key once, and
/// each trial's generator is a copy of the fresh keyed generator with its stream set, the same
/// state as `trial_rng(seed, index)` (tested).
#[derive(Debug, Clone)]
pub struct TrialRngs {
    base: ChaCha8Rng,
}

impl TrialRngs {
    /// The generators of master `seed`.
    pub fn new(seed: u64) -> Self {
        TrialRngs {
            base: trial_rng(seed, 0),
        }
    }

    /// The generator of trial `index`, equal to `trial_rng(seed, index)`.
    #[inline]
    pub fn get(&self, index: u64) -> ChaCha8Rng {
        let mut rng = self.base.clone();
        rng.set_stream(index);
        rng
    }
}

/// Why a trial gave no estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Failure {
    /// The method could not fit these points (degenerate geometry, too few points).
    FitFailed,
    /// Robot mode: no layout draw was reachable by both robots.
    Unreachable,
}

impl Failure {
    /// Name in the CSV `status` column.
    pub fn name(self) -> &'static str {
        match self {
            Failure::FitFailed => "fit-failed",
            Failure::Unreachable => "unreachable",
        }
    }
}

/// Cooperative accuracy of one robot-mode fit over the grid cell's held-out pairs (see
/// [`super::robot`]), m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cooperative {
    /// Measured rms of the error of the cooperative vector `v` over the pairs, m.
    pub rms_m: f64,
    /// Measured 95th percentile of that error over the pairs, m.
    pub p95_m: f64,
    /// The fit's own prediction of the rms (whole-cell methods only), m.
    pub predicted_rms_m: Option<f64>,
}

/// A trial's estimate of one method, scored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialOutcome {
    /// `e_tran`, `e_rot` and the geodesic angle of the fitted `b1_from_b2` against the truth.
    pub errors: TrialErrors,
    /// Robot mode: the cooperative accuracy (`None` in geometry mode).
    pub cooperative: Option<Cooperative>,
}

/// A trial's result for one method.
pub type Outcome = Result<TrialOutcome, Failure>;

/// A finished sweep: outcome `[trial · methods.len() + method]` for every global trial index.
#[derive(Debug, Clone)]
pub struct SweepResult {
    /// The configuration it ran.
    pub config: SweepConfig,
    /// The grid cells (index = cell number).
    pub grid: Vec<GridCell>,
    /// Outcomes, trial-major, methods in `config.methods` order.
    pub outcomes: Vec<Outcome>,
}

impl SweepResult {
    /// Outcome of global trial `trial` for method index `m`.
    pub fn outcome(&self, trial: usize, m: usize) -> &Outcome {
        &self.outcomes[trial * self.config.methods.len() + m]
    }
}

/// Runs the sweep in parallel on the current rayon pool. Robot mode needs one [`Cell`] per mount
/// pair of the config (same order; their alignment σ is replaced by the noise axis);
/// geometry mode ignores `cells`. `progress` is called with the number of trials finished since its
/// last call (from any worker thread, in steps of up to `CHUNK` trials).
pub fn run_sweep(
    config: &SweepConfig,
    cells: &[Cell],
    progress: &(dyn Fn(u64) + Sync),
) -> Result<SweepResult, SimError> {
    config.validate()?;
    if config.mode == Mode::Robot && cells.len() != config.mounts.len() {
        return Err(SimError::InvalidInput(format!(
            "robot mode needs one cell per mount pair: {} cells for {} mount pairs",
            cells.len(),
            config.mounts.len()
        )));
    }
    if config.mode == Mode::Robot {
        if let Some((c, m)) = cells
            .iter()
            .zip(&config.mounts)
            .find(|(c, m)| c.mounts() != **m)
        {
            return Err(SimError::InvalidSetting {
                field: "mounts",
                message: format!(
                    "has {} where its robot-mode cell has {}; give the cells in the order of the mounts",
                    mounts_label(m),
                    mounts_label(&c.mounts())
                ),
            });
        }
    }
    let grid = config.grid();
    let total = config.total_trials();
    let n_methods = config.methods.len();
    let specs: Vec<(GeometrySpec, ErotTruth)> = grid
        .iter()
        .map(|g| {
            let spec = geometry_spec(config, g);
            (spec, spec.erot_truth())
        })
        .collect();
    let setups: Vec<RobotSetup> = if config.mode == Mode::Robot {
        grid.par_iter()
            .enumerate()
            .map(|(i, g)| robot_setup(config, g, &cells[g.mounts], &mut setup_rng(config.seed, i)))
            .collect::<Result<_, _>>()?
    } else {
        Vec::new()
    };
    let rngs = TrialRngs::new(config.seed);
    // One item per trial × method, written in place into `outcomes` by rayon (no serial
    // pre-fill of the output); a worker runs a trial's methods when it meets the trial's first
    // item it is given (a trial split between two workers is run by both, identically).
    let mut outcomes: Vec<Outcome> = Vec::new();
    // Robot trials take milliseconds each: one trial per work item and per progress step.
    let chunk = match config.mode {
        Mode::Geometry => CHUNK,
        Mode::Robot => 1,
    };
    (0..total * n_methods)
        .into_par_iter()
        .with_min_len(chunk * n_methods)
        .map_init(
            || Worker::new(progress, chunk as u64),
            |w, item| {
                let trial = item / n_methods;
                if w.trial != Some(trial) {
                    w.trial = Some(trial);
                    w.outcomes.clear();
                    let cell_index = trial / config.trials;
                    let mut rng = rngs.get(trial as u64);
                    match config.mode {
                        Mode::Geometry => {
                            let (spec, erot_truth) = &specs[cell_index];
                            let (p1, p2) = (&mut w.buf1[..spec.n], &mut w.buf2[..spec.n]);
                            draw_geometry(spec, &mut rng, p1, p2);
                            w.outcomes.extend(config.methods.iter().map(|&method| {
                                let SweepMethod::Registration(method) = method else {
                                    return Err(Failure::FitFailed); // refused by validate()
                                };
                                fit_fast(method, &spec.mounts, p1, p2)
                                    .map(|est| TrialOutcome {
                                        errors: TrialErrors::between_fast(
                                            &spec.b1_from_b2,
                                            erot_truth,
                                            &est,
                                        ),
                                        cooperative: None,
                                    })
                                    .ok_or(Failure::FitFailed)
                            }));
                        }
                        Mode::Robot => {
                            let cell = &grid[cell_index];
                            robot_trial(
                                config,
                                cell,
                                &cells[cell.mounts],
                                &setups[cell_index],
                                &mut rng,
                                &mut w.outcomes,
                            );
                        }
                    }
                }
                let m = item % n_methods;
                if m == 0 {
                    w.count_trial();
                }
                w.outcomes[m]
            },
        )
        .collect_into_vec(&mut outcomes);
    Ok(SweepResult {
        config: config.clone(),
        grid,
        outcomes,
    })
}

/// Per-worker state of [`run_sweep`]: point buffers, the trial in hand and its outcomes (one per
/// method), and progress not yet reported (reported every `report_every` trials — [`CHUNK`] in
/// geometry mode, 1 in robot mode — and when dropped).
pub(super) struct Worker<'a> {
    buf1: Vec<Point3<f64>>,
    buf2: Vec<Point3<f64>>,
    trial: Option<usize>,
    outcomes: Vec<Outcome>,
    progress: &'a (dyn Fn(u64) + Sync),
    pending: u64,
    report_every: u64,
}

impl<'a> Worker<'a> {
    fn new(progress: &'a (dyn Fn(u64) + Sync), report_every: u64) -> Self {
        Worker {
            buf1: vec![Point3::origin(); MAX_GEOMETRY_POINTS],
            buf2: vec![Point3::origin(); MAX_GEOMETRY_POINTS],
            trial: None,
            outcomes: Vec::new(),
            progress,
            pending: 0,
            report_every,
        }
    }

    fn count_trial(&mut self) {
        self.pending += 1;
        if self.pending == self.report_every {
            (self.progress)(self.pending);
            self.pending = 0;
        }
    }
}

impl Drop for Worker<'_> {
    fn drop(&mut self) {
        if self.pending > 0 {
            (self.progress)(self.pending);
        }
    }
}

/// The geometry spec of a grid cell.
pub(super) fn geometry_spec(config: &SweepConfig, cell: &GridCell) -> GeometrySpec {
    let mounts = &config.mounts[cell.mounts];
    let p = paper_placement(mounts).unwrap_or(crate::placement::FLOOR_FLOOR);
    GeometrySpec {
        mounts: *mounts,
        b1_from_b2: p.b1_from_b2(),
        layout: match config.layout {
            SweepLayout::Points(l) => l,
            SweepLayout::Planned => Layout::Random, // refused in geometry mode by validate()
        },
        n: config.n_points[cell.n],
        spread_m: config.spread_m[cell.spread],
        centre_b1: p.centre_b1(),
        sigma_m: Vector3::repeat(config.noise_mm[cell.noise] / 1000.0),
    }
}
