//! The blunder screen ([`fit_screened`]): blunders named, clean sessions kept, too few rows, and
//! the placement-only model's screen and prediction.

use super::*;

/// Issue 11's blunder test: three 5–10 mm blunders in a 40-point floor–wall session whose
/// robot 2 hides a 0.12° joint-3 offset (the only error; every realistic parameter is fitted,
/// with robot 2's offset tolerance widened to 0.2° so the prior admits it). The three rows are
/// named (and only they), each well above the threshold; the screened fit equals the fit of the
/// clean rows; the hidden offset is found (its 95 % interval, ±1.96 posterior σ, excludes 0 and
/// it is within 3 σ of the truth); and the cooperative
/// error stays at the clean level while the unscreened fit's is several times worse.
#[test]
fn three_blunders_are_named_and_the_hidden_offset_is_still_found() {
    let mut sc = sim_cell(Cell::Wall, realistic(), false, 31);
    sc.robot2.tolerance.joint_offset_rad = 0.2f64.to_radians();
    let x = sc.truth.b1_from_b2;
    sc.truth = CellEstimate::nominal(&sc.problem(), x);
    let j3 = ErrorParam::JointOffset { joint: 2 };
    sc.truth.robot2.errors.add(j3, 0.12f64.to_radians());
    let blunders = [(7, 5e-3), (19, 7.5e-3), (33, 10e-3)];
    let mut p = sc.problem();
    p.observations = sc.coincident_with_blunders(40, 3e-4, 0.7, 32, &blunders);
    let solve = SolveOptions::default();
    let s = fit_screened(&p, None, &solve, &ScreenOptions::default()).unwrap();
    let rows: Vec<usize> = s.rejected.iter().map(|r| r.row).collect();
    for r in &s.rejected {
        eprintln!(
            "rejected row {} ({}): {:.1} σ, {:.2} mm (threshold {:.2} σ)",
            r.row,
            r.kind,
            r.size_sigma,
            r.residual_m * 1e3,
            s.threshold_sigma_3
        );
    }
    assert_eq!(rows, vec![7, 19, 33]);
    assert!(s
        .rejected
        .iter()
        .all(|r| r.size_sigma > s.threshold_sigma_3));
    // The screened fit is the fit of the clean rows.
    let clean: Vec<usize> = (0..40).filter(|i| ![6, 18, 32].contains(i)).collect();
    let clean_fit = fit_cell_with(&p, ParamLayout::new(&p, &[]), &clean, None, &solve).unwrap();
    let dx = (clean_fit.estimate.b1_from_b2.translation.vector
        - s.fit.estimate.b1_from_b2.translation.vector)
        .norm();
    assert!(dx < 1e-9, "screened vs clean placement differ by {dx} m");
    let col = s
        .fit
        .layout
        .column(&CellParam::Kinematic {
            robot: Robot::Two,
            param: j3,
        })
        .expect("robot 2 joint 3 offset is fitted");
    let fitted = s.fit.layout.values(&s.fit.estimate)[col];
    let se = s.fit.std_error(col);
    let truth = sc.truth.robot2.errors.get(j3);
    eprintln!(
        "robot 2 joint 3 offset: fitted {:.4}°, true {:.4}° (posterior σ {:.4}°)",
        fitted.to_degrees(),
        truth.to_degrees(),
        se.to_degrees()
    );
    assert!(fitted.abs() > 1.96 * se && (fitted - truth).abs() < 3.0 * se);
    let pairs = sc.eval_pairs(100, 0.7, 33);
    let screened = measure_cooperative_error(&p, &s.fit.estimate, &sc.truth, &pairs).unwrap();
    let plain = fit_cell(&p, &solve).unwrap();
    let unscreened = measure_cooperative_error(&p, &plain.estimate, &sc.truth, &pairs).unwrap();
    eprintln!(
        "cooperative rms: screened {:.3} mm, unscreened {:.3} mm",
        screened.rms_m * 1e3,
        unscreened.rms_m * 1e3
    );
    assert!(unscreened.rms_m > 2.0 * screened.rms_m);
}

/// Clean data: nothing is rejected (α = 1 % family-wise, so a false alarm in these seeds would
/// be a 1-in-100 event each).
#[test]
fn clean_sessions_lose_no_rows() {
    for seed in [41u64, 42, 43] {
        let sc = sim_cell(Cell::Floor, realistic(), false, seed);
        let p = coincident_problem(&sc, 30, 3e-4, seed + 7);
        let s = fit_screened(
            &p,
            None,
            &SolveOptions::default(),
            &ScreenOptions::default(),
        )
        .unwrap();
        assert!(s.rejected.is_empty(), "seed {seed}: {:?}", s.rejected);
    }
}

/// When the rows left after rejection are too few, the error names the rows to re-record.
#[test]
fn too_few_rows_after_rejection_names_the_rows_to_re_record() {
    let sc = sim_cell(Cell::Wall, realistic(), false, 51);
    let mut p = sc.problem();
    p.observations = sc.coincident_with_blunders(12, 3e-4, 0.7, 52, &[(3, 8e-3), (9, 6e-3)]);
    let screen = ScreenOptions {
        min_redundancy: 30,
        ..ScreenOptions::default()
    };
    let Err(e) = fit_screened(&p, None, &SolveOptions::default(), &screen) else {
        panic!("expected TooFewRows, got a fit");
    };
    assert!(e.to_string().contains("re-record rows [3, 9]"), "{e}");
    match e {
        CellFitError::TooFewRows { rejected_rows, .. } => assert_eq!(rejected_rows, vec![3, 9]),
        other => panic!("expected TooFewRows, got {other:?}"),
    }
}

/// With no row rejected, the error says the session is too small, not "re-record rows []"
/// (regression: `calibrate --cell` on a 6-row face-contact session printed exactly that).
#[test]
fn too_few_rows_without_rejection_asks_for_more_rows() {
    let e = CellFitError::TooFewRows {
        remaining: 6,
        needed: 13,
        rejected_rows: vec![],
    };
    let text = e.to_string();
    assert!(
        text.contains("only 6 residual rows") && text.contains("record more rows"),
        "{text}"
    );
    assert!(!text.contains("[]"), "{text}");
}

/// Issue 11's accuracy target for a prediction: within ±25 % of the measured value.
const PREDICTION_TOL_REL: f64 = 0.25;

/// Issue 11 item 4: the placement-only model on sessions whose robots carry errors on every
/// joint (offsets ±0.05°, origins and tips ±0.5 mm, σ = 0.3 mm, 30 points). Its residuals hold
/// the unmodelled kinematic error, so the screen works at the residuals' robust scale: no clean
/// row is rejected, a 10 mm blunder still is, and the prediction carries the model-error term.
#[test]
fn placement_only_screen_and_prediction_allow_for_model_error() {
    for seed in [61u64, 62, 63] {
        let sc = sim_cell(Cell::Floor, realistic(), false, seed);
        let mut p = sc.problem();
        p.robot1.tolerance = Tolerance::none();
        p.robot2.tolerance = Tolerance::none();
        p.observations = sc.coincident(30, 3e-4, 0.7, seed + 7);
        let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        assert!(cal.rejected.is_empty(), "seed {seed}: {:?}", cal.rejected);
        assert!(cal.noise_scale > 1.0, "seed {seed}: {}", cal.noise_scale);
        let pairs = sc.eval_pairs(200, 0.7, seed + 2000);
        let pred = predict_cooperative_accuracy(&p, &cal.fit, &pairs, seed).unwrap();
        let meas = measure_cooperative_error(&p, &cal.fit.estimate, &sc.truth, &pairs).unwrap();
        eprintln!(
            "seed {seed}: noise scale {:.2}, predicted {:.3} mm, measured {:.3} mm",
            cal.noise_scale,
            pred.predicted_rms_m * 1e3,
            meas.rms_m * 1e3
        );
        // The issue's ±25 % between predicted and measured cooperative rms (before the
        // model-error term the prediction was ~0.15 mm against ~1 mm measured).
        assert!(
            (pred.predicted_rms_m / meas.rms_m - 1.0).abs() <= PREDICTION_TOL_REL,
            "seed {seed}: predicted {} vs measured {}",
            pred.predicted_rms_m,
            meas.rms_m
        );
        let mut q = p.clone();
        q.observations = sc.coincident_with_blunders(30, 3e-4, 0.7, seed + 7, &[(12, 10e-3)]);
        let cal = calibrate_cell(&q, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        let rows: Vec<usize> = cal.rejected.iter().map(|r| r.row).collect();
        assert_eq!(rows, vec![12], "seed {seed}");
    }
}
