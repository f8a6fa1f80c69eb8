//! The MAP fit ([`fit_cell`], [`fit_cell_with`]): noise-free recovery, the stop reasons, the
//! whole-cell fit against the placement-only fit and its predicted accuracy, the iteration bound.

use super::*;

/// Noise-free data from a truth the model can represent: the fit reproduces the data exactly
/// and predicts the cooperative vectors far better than the placement-only fit.
#[test]
fn noise_free_fit_reproduces_the_data_and_stops_converged() {
    let sc = sim_cell(Cell::Floor, realistic(), false, 11);
    let p = coincident_problem(&sc, 30, 1e-6, 12);
    let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
    assert_eq!(fit.stopped, StopReason::Converged, "{:?}", fit.stopped);
    assert!(fit.iterations < 30, "{} iterations", fit.iterations);
    // σ = 1 µm: the data χ² of 90 rows stays of order 90 (the prior pulls a little).
    assert!(fit.data_chi2 < 300.0, "data χ² {}", fit.data_chi2);
}

#[test]
fn iteration_cap_is_a_stop_reason_not_an_error() {
    let sc = sim_cell(Cell::Wall, realistic(), false, 5);
    let p = coincident_problem(&sc, 20, 3e-4, 6);
    let opts = SolveOptions {
        lm: LmOptions::whole_cell().with_max_iterations(1).unwrap(),
        ..SolveOptions::default()
    };
    let fit = fit_cell(&p, &opts).unwrap();
    assert_eq!(fit.iterations, 1);
    assert_eq!(fit.stopped, StopReason::IterationCap);
    // A cap of 0 is refused when it is set, naming the option.
    let e = LmOptions::whole_cell().with_max_iterations(0).unwrap_err();
    assert!(e.to_string().contains("max_iterations"), "{e}");
}

/// Issue 11's realistic-errors test on a floor–wall cell: offsets U(±0.05°), origins and tips
/// U(±0.5 mm) on both robots, σ = 0.3 mm, 40 points. Over a small seeded Monte Carlo the
/// whole-cell fit's cooperative rms beats the placement-only fit's in every trial and on
/// average, and the predicted rms (root-mean-square over trials) is within ±25 % of the measured.
#[test]
fn whole_cell_beats_placement_and_predicts_its_accuracy() {
    let trials: Vec<Trial> = (0..10)
        .map(|s| trial(Cell::Wall, 100 + s, 40, 3e-4, 200))
        .collect();
    let rms = |f: &dyn Fn(&Trial) -> f64| {
        (trials.iter().map(|t| f(t).powi(2)).sum::<f64>() / trials.len() as f64).sqrt()
    };
    let place = rms(&|t| t.placement_rms);
    let whole = rms(&|t| t.whole_rms);
    let pred = rms(&|t| t.predicted_rms);
    for t in &trials {
        assert!(
            t.whole_rms < t.placement_rms,
            "{} vs {}",
            t.whole_rms,
            t.placement_rms
        );
    }
    eprintln!(
        "floor–wall, 40 pts, σ 0.3 mm, 10 trials: placement-only {:.3} mm, whole-cell {:.3} mm, \
         predicted {:.3} mm (ratio {:.2}); fit {:.1} ms mean",
        place * 1e3,
        whole * 1e3,
        pred * 1e3,
        pred / whole,
        1e3 * trials.iter().map(|t| t.seconds).sum::<f64>() / trials.len() as f64
    );
    assert!(whole < 0.7 * place, "whole {whole} vs placement {place}");
    assert!(
        (pred / whole - 1.0).abs() <= 0.25,
        "predicted {pred} vs measured {whole}"
    );
}

/// Issue 11's time bound, by iteration count (not wall clock), on the kind of session that made
/// `diagnose` run for minutes: 20 points on the floor–ceiling cell at σ = 0.3 mm with errors on
/// every joint of both robots (every default tolerance fitted: ~100 unknowns).
#[test]
fn every_joint_session_converges_within_the_iteration_bound() {
    for seed in [91u64, 92, 93, 94, 920] {
        let sc = sim_cell(Cell::Ceiling, Tolerance::default(), false, seed);
        let p = coincident_problem(&sc, 20, 3e-4, 901);
        let active: Vec<usize> = (0..p.observations.len()).collect();
        let init = initial_estimate(&p, None, &active).unwrap();
        let red = reduce(&p, &init, &active).unwrap();
        let opts = SolveOptions::default();
        let fit = fit_cell_with(&p, red.layout, &active, Some(&init), &opts).unwrap();
        let full = fit_cell(&p, &opts).unwrap();
        eprintln!(
            "seed {seed}: reduced {} iterations {:?}, full {} iterations {:?}",
            fit.iterations, fit.stopped, full.iterations, full.stopped
        );
        for f in [&fit, &full] {
            assert_eq!(f.stopped, StopReason::Converged);
            assert!(f.iterations <= 10, "{} iterations", f.iterations);
        }
    }
}
