//! A known placement: a contact-only session of the CTU cell (two arms on one base) calibrated
//! with and without the cell's `[b1_from_b2]` prior.

use std::path::Path;

use calib_core::whole_cell::{calibrate_cell, CellCalibration, ScreenOptions, SolveOptions};
use calib_core::StopReason;
use handclasp_cell::problem::{cell_problem, FitModel};
use handclasp_cell::Cell;
use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

fn ctu_cell() -> Cell {
    Cell::from_toml_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/ctu-motoman.toml"),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// A seeded contact-only session of `n` rows on `cell`, calibrated with `--model kinematic`
/// from the cell's own `b1_from_b2` (as `handclasp calibrate` starts a session without
/// coincident rows). Returns the calibration, the placement error (m, rad) and the placement
/// columns' reported prior σ (m ×3, rad ×3).
fn contact_only(cell: &Cell, n: usize, seed: u64) -> (CellCalibration, f64, f64, Vec<f64>) {
    let spec = SessionSpec::new(n, Layout::Random, 0.3);
    let kinds = KindSpec {
        kind: SimKind::Contact,
        ..KindSpec::default()
    };
    let (s, _) = generate_kind_session(cell, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .unwrap_or_else(|e| panic!("{e}"));
    let problem = cell_problem(cell, &s, FitModel::Kinematic);
    let solve = SolveOptions {
        initial_b1_from_b2: Some(cell.b1_from_b2),
        ..SolveOptions::default()
    };
    let cal = calibrate_cell(&problem, &solve, &ScreenOptions::default()).unwrap();
    let x = cal.fit.estimate.b1_from_b2;
    let dt = (x.translation.vector - cell.b1_from_b2.translation.vector).norm();
    let dr = x.rotation.angle_to(&cell.b1_from_b2.rotation);
    let prior = cal.fit.parameters(&problem)[..6]
        .iter()
        .map(|p| p.prior_sigma)
        .collect();
    (cal, dt, dr, prior)
}

/// Placement tolerance with the prior: this many prior σ (translation norm, rotation angle).
const PRIOR_FACTOR: f64 = 3.0;
/// Without the prior the contacts leave the placement loose: at least this many prior σ off
/// (measured 31–105 σ on seeds 3–5, 40 rows).
const FREE_FACTOR: f64 = 10.0;
/// The prior shrinks each placement posterior σ by at least this factor (measured on the x
/// columns, seeds 3–5: translation 190–235, rotation 40–98).
const SHRINK: f64 = 10.0;

/// Contact rows alone (40 rows, known-free distance fitted) cannot pin `b1_from_b2` of a cell
/// whose arms share one base; with the cell's prior at the truth the fit converges with the
/// placement within 3 σ (measured < 1e-6 m, < 3e-6 rad against σ 1e-5 m, 1.7e-5 rad) and a
/// posterior σ far below the free fit's; without it the placement moves 0.3–1.1 mm.
#[test]
fn placement_prior_pins_a_contact_only_session() {
    let cell = ctu_cell();
    let sigma = cell
        .b1_from_b2_sigma
        .expect("ctu-motoman states its placement σ");
    let mut free = cell.clone();
    free.b1_from_b2_sigma = None;
    for seed in [3, 4, 5] {
        let (cal, dt, dr, problem_prior) = contact_only(&cell, 40, seed);
        assert_eq!(cal.fit.stopped, StopReason::Converged, "seed {seed}");
        assert_eq!(
            problem_prior,
            [[sigma.sigma_m; 3], [sigma.sigma_rad; 3]].concat(),
            "the report names the placement prior"
        );
        assert!(
            dt < PRIOR_FACTOR * sigma.sigma_m && dr < PRIOR_FACTOR * sigma.sigma_rad,
            "seed {seed}: placement off by {dt} m, {dr} rad"
        );
        let (cal_free, dt_free, _, _) = contact_only(&free, 40, seed);
        // The prior shrinks every placement column's posterior σ (measured 1.0–1.9 prior σ:
        // the chosen prior scale's error covariance also carries the kinematic shrinkage; free:
        // 0.9–3.2 mm or mrad).
        for j in 0..6 {
            assert!(
                cal.fit.std_error(j) * SHRINK < cal_free.fit.std_error(j),
                "seed {seed} col {j}: σ {} with the prior, {} without",
                cal.fit.std_error(j),
                cal_free.fit.std_error(j)
            );
        }
        assert!(
            dt_free > FREE_FACTOR * sigma.sigma_m,
            "seed {seed}: without the prior the placement moved only {dt_free} m"
        );
    }
}
