//! The one call ([`calibrate_cell`]): its report, the evidence-chosen prior scale, and the
//! larger Monte Carlo runs behind BENCHMARKS.md (ignored; run in release).

use super::*;

/// The larger Monte Carlo behind the reported figures (run in release:
/// `cargo test --release -p calib-core --lib whole_cell::tests::calibrate::monte_carlo -- --ignored --nocapture`).
/// Per shipped cell, 40 seeded trials of 40 points at σ = 0.3 mm, truths drawn from the
/// realistic tolerances, 200 held-out pairs each: placement-only vs whole-cell cooperative rms,
/// predicted vs measured, time per fit (reduction + MAP); then the time of a fit with every
/// default tolerance (origin rpy too: ~100 parameters) at 20, 40 and 80 points.
#[test]
#[ignore = "a Monte Carlo for the report: run in release with --ignored --nocapture"]
fn monte_carlo_three_cells() {
    for cell in [Cell::Floor, Cell::Wall, Cell::Ceiling] {
        let trials: Vec<Trial> = (0..40)
            .map(|s| trial(cell, 500 + s, 40, 3e-4, 200))
            .collect();
        let rms = |f: &dyn Fn(&Trial) -> f64| {
            (trials.iter().map(|t| f(t).powi(2)).sum::<f64>() / trials.len() as f64).sqrt()
        };
        let mut whole: Vec<f64> = trials.iter().map(|t| t.whole_rms).collect();
        whole.sort_by(f64::total_cmp);
        let mut place: Vec<f64> = trials.iter().map(|t| t.placement_rms).collect();
        place.sort_by(f64::total_cmp);
        eprintln!(
            "{cell:?}: cooperative rms over 40 trials (rms of trials / median): placement-only \
             {:.3}/{:.3} mm, whole-cell {:.3}/{:.3} mm, predicted {:.3} mm (predicted/measured \
             {:.2}); fit {:.1} ms mean, {:.1} ms max",
            rms(&|t| t.placement_rms) * 1e3,
            crate::stats::quantile(&place, 0.5) * 1e3,
            rms(&|t| t.whole_rms) * 1e3,
            crate::stats::quantile(&whole, 0.5) * 1e3,
            rms(&|t| t.predicted_rms) * 1e3,
            rms(&|t| t.predicted_rms) / rms(&|t| t.whole_rms),
            1e3 * trials.iter().map(|t| t.seconds).sum::<f64>() / trials.len() as f64,
            1e3 * trials.iter().map(|t| t.seconds).fold(0.0, f64::max),
        );
    }
    // Where the whole-cell fit stops paying: the floor–wall cell at σ = 1 mm and 4.4 mm.
    for sigma in [3e-4, 1e-3, 4.4e-3] {
        let trials: Vec<Trial> = (0..40)
            .map(|s| trial(Cell::Wall, 700 + s, 40, sigma, 200))
            .collect();
        let mean = |f: &dyn Fn(&Trial) -> f64| trials.iter().map(f).sum::<f64>() / 40.0;
        let worse = trials
            .iter()
            .filter(|t| t.whole_rms > t.placement_rms)
            .count();
        eprintln!(
            "Wall σ {:.1} mm: mean cooperative rms placement-only {:.3} mm, whole-cell {:.3} mm \
             (worse in {worse}/40 trials), predicted {:.3} mm; mean p95 measured {:.3} mm, \
             predicted {:.3} mm",
            sigma * 1e3,
            mean(&|t| t.placement_rms) * 1e3,
            mean(&|t| t.whole_rms) * 1e3,
            mean(&|t| t.predicted_rms) * 1e3,
            mean(&|t| t.whole_p95) * 1e3,
            mean(&|t| t.predicted_p95) * 1e3,
        );
    }
    for n in [20usize, 40, 80] {
        let sc = sim_cell(Cell::Ceiling, Tolerance::default(), false, 900 + n as u64);
        let p = coincident_problem(&sc, n, 3e-4, 901);
        let n_params = ParamLayout::new(&p, &[]).len();
        let start = Instant::now();
        let active: Vec<usize> = (0..n).collect();
        let init = initial_estimate(&p, None, &active).unwrap();
        let red = reduce(&p, &init, &active).unwrap();
        let fit = fit_cell_with(
            &p,
            red.layout,
            &active,
            Some(&init),
            &SolveOptions::default(),
        )
        .unwrap();
        let reduced = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let plain = fit_cell(&p, &SolveOptions::default()).unwrap();
        let unreduced = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let screened = fit_screened(
            &p,
            None,
            &SolveOptions::default(),
            &ScreenOptions::default(),
        )
        .unwrap();
        let screen_s = start.elapsed().as_secs_f64();
        eprintln!(
            "floor–ceiling, {n} points, {n_params} unknowns (all default tolerances): reduce+fit \
             {:.1} ms ({} it, {:?}), full fit {:.1} ms ({} it, {:?}), screened fit {:.1} ms \
             ({} rejected)",
            reduced * 1e3,
            fit.iterations,
            fit.stopped,
            unreduced * 1e3,
            plain.iterations,
            plain.stopped,
            screen_s * 1e3,
            screened.rejected.len()
        );
    }
}

/// The one-call calibration on a session with a blunder: the report names the row, lists what
/// was dropped, and serialises in file units with its keys in alphabetical order (the order of
/// the `serde_json::Value` the CLI built before the report had types).
#[test]
fn calibrate_cell_reports_rows_reduction_and_serialises() {
    let sc = sim_cell(Cell::Ceiling, realistic(), false, 81);
    let mut p = sc.problem();
    p.observations = sc.coincident_with_blunders(30, 3e-4, 0.7, 82, &[(11, 6e-3)]);
    let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
    let report = cal.report(&p);
    assert_eq!(report.rejected_points.len(), 1);
    assert_eq!(report.rejected_points[0].row, 11);
    // The 6 mm blunder, in mm.
    assert!(report.rejected_points[0].residual_mm > 1.0);
    assert_eq!(report.stopped, StopReason::Converged);
    assert!(!report.unidentifiable.is_empty());
    assert!(!report.parameters.is_empty());
    assert_eq!(report.b1_from_b2.sigma.len(), 6);
    let json = serde_json::to_string(&report).unwrap();
    for key in [
        "\"size_sigma\"",
        "\"prior_sigma\"",
        "\"residual_mm\"",
        "\"stopped\":\"converged\"",
    ] {
        assert!(json.contains(key), "{key} missing in {json}");
    }
    let sorted = serde_json::to_string(&serde_json::to_value(&report).unwrap()).unwrap();
    assert_eq!(json, sorted, "report keys out of alphabetical order");
}

/// Cooperative rms (m) of the one-call calibration, of the scale-1 MAP fit on its rows (the
/// fit before the prior scale was chosen) and of the placement-only fit, and the chosen scale.
struct ScaleTrial {
    chosen_rms: f64,
    scale1_rms: f64,
    placement_rms: f64,
    scale: f64,
    /// Wall-clock time of the one-call calibration, s.
    seconds: f64,
}

/// `truth_fraction`: the truth is drawn from `U(±truth_fraction·tolerance)` while the prior
/// keeps the full tolerances (1: the prior is right; < 1: the robots are better than their
/// tolerances, the prior too wide).
fn scale_trial(cell: Cell, seed: u64, n: usize, sigma: f64, truth_fraction: f64) -> ScaleTrial {
    let tol = realistic();
    let truth_tol = Tolerance {
        joint_offset_rad: tol.joint_offset_rad * truth_fraction,
        origin_xyz_m: tol.origin_xyz_m * truth_fraction,
        tip_m: tol.tip_m * truth_fraction,
        ..tol
    };
    let sc = sim_cell(cell, truth_tol, false, seed);
    let mut p = coincident_problem(&sc, n, sigma, seed + 1000);
    p.robot1.tolerance = tol;
    p.robot2.tolerance = tol;
    let pairs = sc.eval_pairs(200, 0.7, seed + 2000);
    let start = Instant::now();
    let cal = evidence_calibration(&p);
    let seconds = start.elapsed().as_secs_f64();
    let chosen = measure_cooperative_error(&p, &cal.fit.estimate, &sc.truth, &pairs).unwrap();
    let all: Vec<usize> = (0..n).collect();
    let init = initial_estimate(&p, None, &all).unwrap();
    let scale1 = fit_cell_with(
        &p,
        cal.reduction.layout.clone(),
        &cal.fit.active,
        Some(&init),
        &SolveOptions::default(),
    )
    .unwrap();
    let scale1 = measure_cooperative_error(&p, &scale1.estimate, &sc.truth, &pairs).unwrap();
    ScaleTrial {
        chosen_rms: chosen.rms_m,
        scale1_rms: scale1.rms_m,
        placement_rms: placement_error(&p, &sc, &pairs).rms_m,
        scale: cal.prior_scale.scale,
        seconds,
    }
}

/// Item 3's measurement (`cargo test --release -p calib-core --lib whole_cell::tests::calibrate::prior_scale_monte_carlo -- --ignored --nocapture`):
/// floor–wall, 40 points, 40 trials per σ: cooperative rms of the scale-1 MAP fit (before) and
/// of the evidence-chosen scale (after) against the placement-only fit.
#[test]
#[ignore = "a Monte Carlo for the report: run in release with --ignored --nocapture"]
fn prior_scale_monte_carlo() {
    for (sigma, fraction) in [
        (3e-4, 1.0),
        (1e-3, 1.0),
        (4.4e-3, 1.0),
        (1e-3, 0.25),
        (4.4e-3, 0.25),
    ] {
        let t: Vec<ScaleTrial> = (0..40)
            .map(|s| scale_trial(Cell::Wall, 700 + s, 40, sigma, fraction))
            .collect();
        let mean = |f: &dyn Fn(&ScaleTrial) -> f64| t.iter().map(f).sum::<f64>() / 40.0 * 1e3;
        let worse =
            |f: &dyn Fn(&ScaleTrial) -> f64| t.iter().filter(|x| f(x) > x.placement_rms).count();
        let worst = |f: &dyn Fn(&ScaleTrial) -> f64| {
            t.iter().map(|x| f(x) / x.placement_rms).fold(0.0, f64::max)
        };
        eprintln!(
            "Wall σ {:.1} mm, truth U(±{fraction}·tol): mean coop rms placement {:.3} mm; scale-1 MAP {:.3} mm (worse in \
             {}/40, worst ratio {:.2}); evidence-chosen {:.3} mm (worse in {}/40, worst ratio \
             {:.2}); calibrate_cell {:.1} ms mean, {:.1} ms max; scales chosen: {}",
            sigma * 1e3,
            mean(&|x| x.placement_rms),
            mean(&|x| x.scale1_rms),
            worse(&|x| x.scale1_rms),
            worst(&|x| x.scale1_rms),
            mean(&|x| x.chosen_rms),
            worse(&|x| x.chosen_rms),
            worst(&|x| x.chosen_rms),
            mean(&|x| x.seconds),
            t.iter().map(|x| x.seconds).fold(0.0, f64::max) * 1e3,
            t.iter()
                .map(|x| format!("{}", x.scale))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
}

/// What `calibrate --cell` does on a session that passes its result check: the calibration at
/// the stated tolerances, then its widening when the evidence asks for one.
fn evidence_calibration(p: &CellProblem) -> CellCalibration {
    let (solve, screen) = (SolveOptions::default(), ScreenOptions::default());
    let stated = calibrate_cell(p, &solve, &screen).unwrap();
    widen_prior(p, &stated, &solve, &screen)
        .unwrap()
        .unwrap_or(stated)
}

/// The evidence-chosen scale 1e-3 shrinks the kinematic corrections to ~1e-6 of their
/// tolerances: its fit is the placement-only fit far inside 0.1 %.
const PLACEMENT_LIMIT_REL: f64 = 1e-3;

/// Regression of issue 11's "never worse than lsq" at σ = 4.4 mm (floor–wall, 40 points, the
/// seed-709 session of `prior_scale_monte_carlo`): the MAP fit at the tolerances' prior lost to
/// the placement-only fit (1.637 vs 1.583 mm); the session's evidence now chooses the
/// placement-only limit and the calibration is at the placement-only fit's level.
#[test]
fn high_noise_session_is_not_worse_than_placement_only() {
    let t = scale_trial(Cell::Wall, 709, 40, 4.4e-3, 1.0);
    assert!(
        t.scale1_rms > t.placement_rms,
        "the session no longer shows the defect"
    );
    assert_eq!(t.scale, PRIOR_SCALES[PRIOR_SCALES.len() - 1]);
    assert!(
        t.chosen_rms <= t.placement_rms * (1.0 + PLACEMENT_LIMIT_REL),
        "chosen {} vs placement-only {}",
        t.chosen_rms,
        t.placement_rms
    );
}

/// Robots four times better than their tolerances (truth U(±tol/4), prior from tol), σ = 1 mm,
/// 7 sessions: the MAP fit at the tolerances' prior fits noise into the kinematic parameters and
/// loses to the placement-only fit by > 20 % on average; the evidence-chosen scale keeps the
/// calibration within 5 % of it (measured: +0.9 %; scale-1 +27 %).
#[test]
fn too_wide_a_prior_is_shrunk_to_placement_level_by_the_evidence() {
    let t: Vec<ScaleTrial> = (700..707)
        .map(|s| scale_trial(Cell::Wall, s, 40, 1e-3, 0.25))
        .collect();
    let mean = |f: &dyn Fn(&ScaleTrial) -> f64| t.iter().map(f).sum::<f64>() / t.len() as f64;
    let place = mean(&|x| x.placement_rms);
    assert!(mean(&|x| x.scale1_rms) > 1.2 * place);
    assert!(mean(&|x| x.chosen_rms) < 1.05 * place);
}

/// Cooperative rms (m) over 200 held-out pairs of the evidence-chosen fit, of the fit that
/// knows the true prior (the oracle: the tolerances × `truth_fraction`, the factor the truth was
/// drawn with) and of the fit with the stated tolerances held (scale 1), and the evidence's
/// largest family scale.
struct OracleTrial {
    evidence_rms: f64,
    oracle_rms: f64,
    held_rms: f64,
    largest_scale: f64,
    choice: PriorScaleChoice,
}

fn oracle_trial(cell: Cell, seed: u64, truth_fraction: f64) -> OracleTrial {
    let tol = realistic();
    let truth_tol = Tolerance {
        joint_offset_rad: tol.joint_offset_rad * truth_fraction,
        origin_xyz_m: tol.origin_xyz_m * truth_fraction,
        tip_m: tol.tip_m * truth_fraction,
        ..tol
    };
    let sc = sim_cell(cell, truth_tol, false, seed);
    let mut p = coincident_problem(&sc, 40, 3e-4, seed + 1000);
    p.robot1.tolerance = tol;
    p.robot2.tolerance = tol;
    let pairs = sc.eval_pairs(200, 0.7, seed + 2000);
    let rms = |scale: Option<f64>| {
        let cal = calibrate_cell_with(
            &p,
            &SolveOptions::default(),
            &ScreenOptions::default(),
            scale,
        )
        .unwrap();
        let e = measure_cooperative_error(&p, &cal.fit.estimate, &sc.truth, &pairs).unwrap();
        (e.rms_m, cal)
    };
    let cal = evidence_calibration(&p);
    let evidence_rms = measure_cooperative_error(&p, &cal.fit.estimate, &sc.truth, &pairs)
        .unwrap()
        .rms_m;
    OracleTrial {
        evidence_rms,
        oracle_rms: rms(Some(truth_fraction)).0,
        held_rms: rms(Some(1.0)).0,
        largest_scale: cal
            .prior_scale
            .families
            .iter()
            .map(|f| f.scale)
            .fold(0.0, f64::max),
        choice: cal.prior_scale,
    }
}

/// The evidence-chosen fit's cooperative rms is at most this many times the oracle's on the
/// sessions whose truth is 10× the stated tolerances.
const NEAR_ORACLE: f64 = 1.15;
/// On those sessions the evidence widens some family by at least this factor.
const WIDENED_AT_LEAST: f64 = 4.0;
/// With the tolerances right, no family is widened beyond this factor.
const NO_WIDENING_BEYOND: f64 = 2.0;

/// Robots 10× further off than their stated tolerances (truth U(±10·tol), floor–wall, 40
/// points, σ 0.3 mm, 3 seeds): the fit with the stated prior held is far off (the prior pulls
/// the corrections to a tenth of what they need); the evidence widens the prior and the
/// held-out cooperative error is near the oracle's.
#[test]
fn evidence_widens_a_prior_ten_times_too_narrow() {
    for seed in [731, 732, 733] {
        let t = oracle_trial(Cell::Wall, seed, 10.0);
        assert!(
            t.largest_scale >= WIDENED_AT_LEAST,
            "seed {seed}: {:?}",
            t.choice
        );
        assert!(
            t.evidence_rms <= NEAR_ORACLE * t.oracle_rms,
            "seed {seed}: evidence {} m vs oracle {} m ({:?})",
            t.evidence_rms,
            t.oracle_rms,
            t.choice
        );
        assert!(
            t.held_rms > 3.0 * t.oracle_rms,
            "seed {seed}: the session no longer shows the defect (held {} m, oracle {} m)",
            t.held_rms,
            t.oracle_rms
        );
    }
}

/// Tolerances right (truth U(±tol)), the three shipped cells, 2 seeds each: no family is
/// widened beyond [`NO_WIDENING_BEYOND`].
#[test]
fn evidence_does_not_widen_right_tolerances() {
    for cell in [Cell::Floor, Cell::Wall, Cell::Ceiling] {
        for seed in [741, 742] {
            let t = oracle_trial(cell, seed, 1.0);
            assert!(
                t.largest_scale <= NO_WIDENING_BEYOND,
                "{cell:?} seed {seed}: {:?}",
                t.choice
            );
        }
    }
}

/// Tolerances stated 1000× too narrow (truth drawn from the realistic tolerances, the problem's
/// tolerances a thousandth of them): the evidence would widen beyond ×100, but the product of
/// every widening of a family stays within [`MAX_PRIOR_SCALE`] (the passes multiply: before the
/// cap a family reached ×400), and `calibrate_cell` alone never widens.
#[test]
fn widening_is_capped_at_max_prior_scale_in_all() {
    let sc = sim_cell(Cell::Wall, realistic(), false, 761);
    let mut p = coincident_problem(&sc, 40, 3e-4, 762);
    let narrow = |t: Tolerance| Tolerance {
        joint_offset_rad: t.joint_offset_rad * 1e-3,
        origin_xyz_m: t.origin_xyz_m * 1e-3,
        tip_m: t.tip_m * 1e-3,
        ..t
    };
    p.robot1.tolerance = narrow(realistic());
    p.robot2.tolerance = narrow(realistic());
    let (solve, screen) = (SolveOptions::default(), ScreenOptions::default());
    let stated = calibrate_cell(&p, &solve, &screen).unwrap();
    assert!(stated.prior_scale.families.iter().all(|f| f.scale <= 1.0));
    let wide = widen_prior(&p, &stated, &solve, &screen)
        .unwrap()
        .expect("the evidence widens tolerances 1000× too narrow");
    let widest = wide
        .prior_scale
        .families
        .iter()
        .map(|f| f.scale)
        .fold(0.0, f64::max);
    assert!(
        widest > 8.0 && widest <= MAX_PRIOR_SCALE * (1.0 + 1e-12),
        "{:?}",
        wide.prior_scale
    );
    for q in &wide.report(&p).parameters {
        assert!(
            q.prior_scale <= MAX_PRIOR_SCALE * (1.0 + 1e-12),
            "{}",
            q.name
        );
    }
}

/// `calibrate_cell_with` a fixed scale applies it to every family, says so, and refuses a scale
/// outside 1e-3 … 100 naming the range.
#[test]
fn fixed_tolerance_scale_is_applied_and_checked() {
    let sc = sim_cell(Cell::Floor, realistic(), false, 751);
    let p = coincident_problem(&sc, 30, 3e-4, 752);
    let cal = calibrate_cell_with(
        &p,
        &SolveOptions::default(),
        &ScreenOptions::default(),
        Some(10.0),
    )
    .unwrap();
    assert_eq!(cal.prior_scale.method, ScaleMethod::Fixed);
    assert!(cal.prior_scale.families.iter().all(|f| f.scale == 10.0));
    assert!(cal.prior_scale.why.contains("--tolerance-scale"));
    let report = cal.report(&p);
    for q in &report.parameters {
        assert_eq!(q.prior_scale, 10.0);
        assert!((q.tolerance - q.prior_sigma * 3f64.sqrt()).abs() < 1e-12);
    }
    for bad in [0.0, 1e-4, 101.0, f64::NAN] {
        let err = calibrate_cell_with(
            &p,
            &SolveOptions::default(),
            &ScreenOptions::default(),
            Some(bad),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("0.001") && err.contains("100"), "{err}");
    }
}
