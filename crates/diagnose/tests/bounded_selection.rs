//! Bounded work of the selection (issue 11, item 3): a 20-point floor–ceiling session at
//! σ = 0.3 mm with small errors on every joint (the reproducer of `handclasp diagnose` running
//! for minutes, embedded as `fixtures/slow_diagnose`) once cycled forever: a candidate accepted
//! by the forward criteria was dropped again by the backward F test, and the next step accepted
//! it again. The bound is on deterministic work (tip-model evaluations), not wall-clock time.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use calib_core::identify::{
    forward_select, IdentifyError, SelectionOptions, SelectionStop, TipEval, TipModel,
};
use calib_core::Robot;
use diagnose::noise::NoiseModel;
use diagnose::{catalogue, load_session, DiagnoseOptions, SessionModel};
use handclasp_cell::Cell;
use nalgebra::Matrix3;

/// Tip-model evaluations (one point, any parameters) the whole forward selection on the fixture
/// may use. Measured: 39 580 (4 steps, the 4th accepted and dropped again, then the cycle
/// stop). A selection running to the 20-step cap would need about 5× that; the old endless loop
/// used ~1 400 per step forever.
const MAX_EVALS: usize = 50_000;

/// Counts the evaluations of the wrapped model.
struct Counting<'a> {
    inner: &'a SessionModel<'a>,
    evals: AtomicUsize,
}

impl TipModel for Counting<'_> {
    fn n_points(&self) -> usize {
        self.inner.n_points()
    }
    fn n_params(&self) -> usize {
        self.inner.n_params()
    }
    fn param_robot(&self, j: usize) -> Robot {
        self.inner.param_robot(j)
    }
    fn param_scale(&self, j: usize) -> f64 {
        self.inner.param_scale(j)
    }
    fn weight(&self, point: usize) -> Matrix3<f64> {
        self.inner.weight(point)
    }
    fn param_prior(&self, j: usize) -> f64 {
        self.inner.param_prior(j)
    }
    fn eval(
        &self,
        point: usize,
        params: &[usize],
        values: &[f64],
        jacobian_params: &[usize],
    ) -> Result<TipEval, IdentifyError> {
        self.evals.fetch_add(1, Ordering::Relaxed);
        self.inner.eval(point, params, values, jacobian_params)
    }
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/slow_diagnose")
        .join(name)
}

/// The reproducer's cell. Its URDF paths are `../robots/…`, relative to the folder the cell
/// file sat in beside the repository's `robots/`: resolve them from `crates/`.
fn cell() -> Cell {
    let text = std::fs::read_to_string(fixture("cell.toml")).unwrap();
    Cell::from_toml_str(&text, &Path::new(env!("CARGO_MANIFEST_DIR")).join("..")).unwrap()
}

#[test]
fn selection_on_the_slow_session_stops_within_its_work_bound() {
    let cell = cell();
    let session = load_session(&fixture("session.csv"), &cell).unwrap();
    assert_eq!(session.points.len(), 20);
    let cands = catalogue(
        cell.robot1.model.chain_joints().len(),
        cell.robot2.model.chain_joints().len(),
    );
    let q1: Vec<Vec<f64>> = session.points.iter().map(|p| p.q1.clone()).collect();
    let q2: Vec<Vec<f64>> = session.points.iter().map(|p| p.q2.clone()).collect();
    let r_cell = cell.b1_from_b2.rotation.to_rotation_matrix().into_inner();
    let noise = NoiseModel::new(&cell, &q1, &q2, &r_cell).unwrap();
    let inner = SessionModel::new(&cell, &q1, &q2, &cands).with_weights(noise.whitening());
    let model = Counting {
        inner: &inner,
        evals: AtomicUsize::new(0),
    };
    let all: Vec<usize> = (0..cands.len()).collect();
    let options = SelectionOptions::default();
    let sel = forward_select(&model, &all, &options).unwrap();
    let evals = model.evals.load(Ordering::Relaxed);
    eprintln!(
        "steps {}, stop {:?}, selected {:?}, evaluations {evals}",
        sel.steps.len(),
        sel.stop,
        sel.fit.params
    );
    assert_eq!(sel.stop, SelectionStop::Cycle);
    assert!(sel.steps.len() <= options.max_steps);
    assert!(sel.fit.converged(), "{:?}", sel.fit.stopped);
    assert!(
        evals <= MAX_EVALS,
        "{evals} tip evaluations > bound {MAX_EVALS}"
    );
}

#[test]
fn diagnose_of_the_slow_session_reports_each_selection_step_as_progress() {
    let cell = cell();
    let session = load_session(&fixture("session.csv"), &cell).unwrap();
    let options = DiagnoseOptions {
        trials: 50,
        ..DiagnoseOptions::default()
    };
    let mut lines = Vec::new();
    let report = diagnose::diagnose_session_with_progress(&cell, &session, &options, &mut |l| {
        lines.push(l.to_string())
    })
    .unwrap();
    // Two phase lines, one progress line per selection step in the report's order, then the
    // Monte Carlo phase; the 4th step is accepted, then dropped again by the backward F test
    // (the cycle stop).
    assert_eq!(lines.len(), report.steps.len() + 3, "{lines:?}");
    assert!(lines[0].starts_with("20 points: "), "{lines:?}");
    assert!(lines[1].starts_with("model selection"), "{lines:?}");
    assert!(lines[6].starts_with("baseline and gain: 50 "), "{lines:?}");
    let steps: Vec<&String> = lines[2..lines.len() - 1].iter().collect();
    assert_eq!(steps.len(), 4, "{lines:?}");
    assert!(
        steps.iter().all(|l| l.starts_with("selection step ")),
        "{lines:?}"
    );
    assert!(steps[0].starts_with("selection step 1: "), "{lines:?}");
    assert!(steps[3].contains(" accepted "), "{lines:?}");
    assert_eq!(report.effects.len(), 3);
}
