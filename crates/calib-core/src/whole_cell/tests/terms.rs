//! The nuisance groups and the optional model terms: a mixed session's trackers, plane and
//! contacts, joint-periodic errors, a tracker's scale and drift, compliance, and their
//! serialised form.

use super::*;

/// A mixed session on a floor–wall cell with two tools on robot 1: 30 coincident handclasps,
/// 20 tracker readings of robot 1's reflector (tracker frame unknown, anchored to b1), 15
/// touches of robot 2's tip on an unknown plane (anchored to b2) and 10 sphere contacts at an
/// unknown distance. All noise σ = 0.05 mm. The MAP fit converges, its data χ² is that of the
/// noise, the contact distance and the plane come back within 4 posterior σ, and the cooperative
/// error beats the placement-only fit's.
#[test]
fn mixed_session_recovers_groups_and_beats_placement_only() {
    let sigma = 5e-5;
    let sc = sim_cell(Cell::Wall, realistic(), true, 71);
    let mut p = sc.problem();
    let mut obs: Vec<ObservationKind> = sc
        .coincident(30, sigma, 0.7, 72)
        .into_iter()
        .map(|o| o.kind)
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(73);
    let normal = |rng: &mut ChaCha8Rng| {
        Vector3::from_fn(|_, _| {
            let z: f64 = rand_distr::Distribution::sample(&rand_distr::StandardNormal, rng);
            z * sigma
        })
    };
    // Tracker.
    let tracker_from_b1 =
        Isometry3::new(Vector3::new(2.0, -1.0, 0.3), Vector3::new(0.1, -0.2, 2.5));
    p.trackers = vec![TrackerGroup {
        name: "leica".into(),
        anchor: Robot::One,
        initial_tracker_from_anchor: None,
        fit_scale: false,
        fit_drift: false,
    }];
    for _ in 0..20 {
        let q = random_q(&p.robot1.model, &mut rng);
        let t = sc.true_tip(Robot::One, 1, &q);
        obs.push(ObservationKind::Tracker {
            robot: Robot::One,
            q,
            tool: 1,
            group: 0,
            p_tracker: tracker_from_b1 * Point3::from(t) + normal(&mut rng),
            noise: Noise3::Isotropic { sigma_m: sigma },
        });
    }
    // Plane z = 0.3 m in b2, touched by robot 2's tip pointing into it.
    let (n_true, d_true) = (Vector3::z_axis(), 0.3);
    p.planes = vec![PlaneGroup {
        name: "table".into(),
        anchor: Robot::Two,
        initial: None,
    }];
    let mut touched = 0;
    while touched < 15 {
        let target = Point3::new(
            rng.random_range(0.6..1.1),
            rng.random_range(-0.5..0.5),
            d_true + normal(&mut rng).z,
        );
        if let Some(q) = sc.solve_true(Robot::Two, 0, &target, -Vector3::z_axis()) {
            obs.push(ObservationKind::Plane {
                robot: Robot::Two,
                q,
                tool: 0,
                group: 0,
                sigma_m: sigma,
            });
            touched += 1;
        }
    }
    // Sphere contacts 50 mm apart.
    let d_contact = 0.05;
    p.contacts = vec![ContactGroup {
        name: "spheres".into(),
        distance_m: 0.045,
        fit_distance: true,
    }];
    let mut contacts = 0;
    while contacts < 10 {
        let dir = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize();
        let along = d_contact + normal(&mut rng).x;
        if let Some(pair) = sc.draw_pair(&mut rng, 0.6, 1, dir * along) {
            obs.push(ObservationKind::Contact {
                q1: pair.q1,
                q2: pair.q2,
                tool1: 1,
                tool2: 0,
                group: 0,
                sigma_m: sigma,
            });
            contacts += 1;
        }
    }
    p.observations = obs
        .into_iter()
        .enumerate()
        .map(|(i, kind)| Observation { row: i + 1, kind })
        .collect();
    let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
    assert_eq!(fit.stopped, StopReason::Converged);
    let chi2_per_row = fit.data_chi2 / fit.residual_rows as f64;
    let col_d = fit
        .layout
        .column(&CellParam::ContactDistance { group: 0 })
        .unwrap();
    let col_off = fit
        .layout
        .column(&CellParam::PlaneOffset { group: 0 })
        .unwrap();
    let d_fit = fit.estimate.contact_distance_m[0];
    let plane = fit.estimate.planes[0];
    // The fitted normal may point either way.
    let sign = plane.normal_anchor.dot(&n_true).signum();
    eprintln!(
        "mixed: {} iterations, χ²/row {chi2_per_row:.2}, contact {:.4} mm (σ {:.4}), plane \
         offset {:.4} mm (σ {:.4}), normal error {:.2e} rad",
        fit.iterations,
        d_fit * 1e3,
        fit.std_error(col_d) * 1e3,
        sign * plane.offset_m * 1e3,
        fit.std_error(col_off) * 1e3,
        (plane.normal_anchor.into_inner() * sign - n_true.into_inner()).norm()
    );
    assert!((0.5..1.5).contains(&chi2_per_row));
    assert!((d_fit - d_contact).abs() < 4.0 * fit.std_error(col_d));
    assert!((sign * plane.offset_m - d_true).abs() < 4.0 * fit.std_error(col_off));
    let pairs = sc.eval_pairs(100, 0.7, 74);
    let whole = measure_cooperative_error(&p, &fit.estimate, &sc.truth, &pairs).unwrap();
    let mut q = p.clone();
    q.observations.truncate(30);
    q.trackers.clear();
    q.planes.clear();
    q.contacts.clear();
    let place = placement_error(&q, &sc, &pairs);
    eprintln!(
        "mixed: cooperative rms {:.3} mm vs placement-only {:.3} mm",
        whole.rms_m * 1e3,
        place.rms_m * 1e3
    );
    assert!(whole.rms_m < 0.5 * place.rms_m);
}

/// Columns of the periodic parameters of both robots.
fn periodic_columns(layout: &ParamLayout) -> Vec<usize> {
    (0..layout.len())
        .filter(|&c| {
            matches!(
                layout.params[c],
                CellParam::Kinematic {
                    param: ErrorParam::PeriodicSin { .. } | ErrorParam::PeriodicCos { .. },
                    ..
                }
            )
        })
        .collect()
}

/// Joint-angle-periodic errors (first harmonic, ±0.02° per amplitude) hidden in simulated
/// 60-point handclasp sessions are recovered within 4 posterior σ when fitted; with the truth
/// free of them, fitting them returns values within 4σ of 0; over six sessions (three each) the
/// rms of the standardised errors is ~1. Some amplitudes must be determined by the data
/// (posterior σ below half the prior's), so the check is not the prior's.
#[test]
fn periodic_errors_are_recovered_within_their_intervals() {
    let periodic = Tolerance {
        periodic_rad: Some(0.02f64.to_radians()),
        ..realistic()
    };
    let mut zs = Vec::new();
    for (hidden, seed) in (0..6u64).map(|k| (k % 2 == 0, 81 + 2 * k)) {
        let truth_tol = if hidden { periodic } else { realistic() };
        let sc = sim_cell(Cell::Floor, truth_tol, false, seed);
        let mut p = coincident_problem(&sc, 60, 5e-5, seed + 1);
        p.robot1.tolerance = periodic;
        p.robot2.tolerance = periodic;
        let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
        assert_eq!(fit.stopped, StopReason::Converged, "{:?}", fit.stopped);
        let cols = periodic_columns(&fit.layout);
        let dofs = p.robot1.model.dof() + p.robot2.model.dof();
        assert_eq!(cols.len(), 2 * dofs, "sin and cos per joint of both robots");
        let truth_of = |c: usize| match &fit.layout.params[c] {
            CellParam::Kinematic { robot, param } => sc.truth.robot(*robot).errors.get(*param),
            _ => unreachable!("periodic columns only"),
        };
        if hidden {
            assert!(cols.iter().any(|&c| truth_of(c) != 0.0));
        } else {
            assert!(cols.iter().all(|&c| truth_of(c) == 0.0));
        }
        let determined = cols
            .iter()
            .filter(|&&c| fit.std_error(c) < 0.5 * fit.layout.prior_sigma(c))
            .count();
        assert!(
            determined >= 4,
            "only {determined} periodic amplitudes determined"
        );
        assert_within_interval(&fit, &p, &cols, truth_of, "periodic", &mut zs);
        eprintln!(
            "periodic (seed {seed}, hidden: {hidden}): {} iterations, {determined}/{} determined",
            fit.iterations,
            cols.len()
        );
    }
    let (rms, worst) = assert_calibrated(&zs, "periodic");
    eprintln!(
        "periodic: rms z {rms:.2}, worst |z| {worst:.2} over {} values",
        zs.len()
    );
}

/// A tracker session of robot 1's second tool: `n` rows (numbered after `first_row − 1`) of the
/// true tip seen by a tracker at `tracker_from_b1` with scale error `scale` and drift `drift_m`
/// over the normalised order `u = k/(n − 1) − ½`, plus isotropic noise `sigma`.
#[allow(clippy::too_many_arguments)]
fn tracker_rows(
    sc: &SimCell,
    tracker_from_b1: &Isometry3<f64>,
    scale: f64,
    drift_m: &Vector3<f64>,
    n: usize,
    sigma: f64,
    first_row: usize,
    seed: u64,
) -> Vec<Observation> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            let q = random_q(&sc.robot1.model, &mut rng);
            let g = sc.true_tip(Robot::One, 1, &q);
            let u = k as f64 / (n - 1) as f64 - 0.5;
            let noise = Vector3::from_fn(|_, _| {
                let z: f64 =
                    rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng);
                z * sigma
            });
            let p = (tracker_from_b1 * Point3::from(g) + drift_m * u) * (1.0 + scale) + noise;
            Observation {
                row: first_row + k,
                kind: ObservationKind::Tracker {
                    robot: Robot::One,
                    q,
                    tool: 1,
                    group: 0,
                    p_tracker: p,
                    noise: Noise3::Isotropic { sigma_m: sigma },
                },
            }
        })
        .collect()
}

/// A tracker's scale error (2e-4) and drift ((0.3, −0.2, 0.25) mm over the recording) hidden in
/// simulated sessions (30 handclasp rows, 40 tracker rows) are recovered within 4 posterior σ
/// and reported with their σ; without them in the data, fitting them returns values within 4σ
/// of 0; over eight sessions (four each) the rms of the standardised errors is ~1 (measured over
/// 30 sessions while writing this test: rms 1.02, largest |z| 3.05 of 120). Normalised order: the tracker rows are 31..70, so `u` runs from −½ to +½. The joint
/// origins are neither drawn nor fitted here: with them fitted (and no length reference) the
/// scale is confounded with the link lengths (measured: posterior σ 2.4e-4, as large as the
/// hidden scale), which is the Python study's "scale redundant with lengths".
#[test]
fn tracker_scale_and_drift_are_recovered_within_their_intervals() {
    let sigma = 5e-5;
    let tol = Tolerance {
        origin_xyz_m: 0.0,
        ..realistic()
    };
    let tracker_from_b1 =
        Isometry3::new(Vector3::new(2.0, -1.0, 0.3), Vector3::new(0.1, -0.2, 2.5));
    let mut zs = Vec::new();
    for (hidden, seed) in (0..8u64).map(|k| (k % 2 == 0, 91 + 2 * k)) {
        let (scale, drift) = if hidden {
            (2e-4, Vector3::new(3e-4, -2e-4, 2.5e-4))
        } else {
            (0.0, Vector3::zeros())
        };
        let sc = sim_cell(Cell::Wall, tol, true, seed);
        let mut p = sc.problem();
        p.observations = sc.coincident(30, sigma, 0.7, seed + 1);
        p.observations.extend(tracker_rows(
            &sc,
            &tracker_from_b1,
            scale,
            &drift,
            40,
            sigma,
            31,
            seed + 2,
        ));
        p.trackers = vec![TrackerGroup {
            name: "leica".into(),
            anchor: Robot::One,
            initial_tracker_from_anchor: None,
            fit_scale: true,
            fit_drift: true,
        }];
        assert_eq!(p.tracker_order(0, 31), -0.5);
        assert_eq!(p.tracker_order(0, 70), 0.5);
        let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
        assert_eq!(fit.stopped, StopReason::Converged, "{:?}", fit.stopped);
        let s_col = fit
            .layout
            .column(&CellParam::TrackerScale { group: 0 })
            .unwrap();
        let d_cols: Vec<usize> = kinematics::Axis::ALL
            .iter()
            .map(|&axis| {
                fit.layout
                    .column(&CellParam::TrackerDrift { group: 0, axis })
                    .unwrap()
            })
            .collect();
        let truth_of = |c: usize| {
            if c == s_col {
                scale
            } else {
                drift[d_cols.iter().position(|&d| d == c).unwrap()]
            }
        };
        let mut cols = vec![s_col];
        cols.extend(&d_cols);
        assert_within_interval(&fit, &p, &cols, truth_of, "tracker nuisance", &mut zs);
        // Reported like the other nuisances: unpenalised, with a posterior σ well below the
        // hidden values (so the hidden case is a detection, not a prior's guess).
        let report = fit.parameters(&p);
        let s_report = report
            .iter()
            .find(|f| f.param == CellParam::TrackerScale { group: 0 })
            .unwrap();
        assert_eq!(s_report.prior_sigma, 0.0);
        assert!(s_report.posterior_sigma < 0.25 * 2e-4, "{s_report:?}");
        assert!(s_report.value.abs() > 4.0 * s_report.posterior_sigma || !hidden);
        for &c in &d_cols {
            assert!(fit.std_error(c) < 0.25 * 2e-4, "{}", report[c].name);
        }
        eprintln!(
            "tracker (seed {seed}, hidden: {hidden}): {} iterations, scale {:.2e} ± {:.1e}, drift \
             {:.3?} mm ± {:.3?} mm",
            fit.iterations,
            fit.estimate.tracker_scale[0],
            fit.std_error(s_col),
            (fit.estimate.tracker_drift_m[0] * 1e3).as_slice(),
            d_cols
                .iter()
                .map(|&c| fit.std_error(c) * 1e3)
                .collect::<Vec<_>>(),
        );
    }
    let (rms, worst) = assert_calibrated(&zs, "tracker nuisance");
    eprintln!(
        "tracker: rms z {rms:.2}, worst |z| {worst:.2} over {} values",
        zs.len()
    );
}

/// The new terms stay out of serialised estimates while they are zero (so reports of fits
/// without them are byte-identical to before), and appear once set.
#[test]
fn new_terms_serialise_only_when_set() {
    let (p, _) = every_kind(5);
    let mut est = CellEstimate::nominal(&p, Isometry3::identity());
    let json = serde_json::to_string(&est).unwrap();
    for key in [
        "periodic_sin",
        "periodic_cos",
        "tracker_scale",
        "tracker_drift_m",
    ] {
        assert!(!json.contains(key), "`{key}` in {json}");
    }
    est.robot2.errors.periodic_cos[1] = 1e-4;
    est.robot1.errors.periodic_sin[6] = -1e-4;
    est.tracker_scale[0] = 1e-5;
    est.tracker_drift_m[1].z = 1e-4;
    let json = serde_json::to_string(&est).unwrap();
    for key in [
        "periodic_sin",
        "periodic_cos",
        "tracker_scale",
        "tracker_drift_m",
    ] {
        assert!(json.contains(key), "`{key}` missing from {json}");
    }
}

/// Issue 12 blamed the CTU `all+c` fit's iteration cap on compliance's units (rad/(N·m) next to
/// rad). In simulation a compliance fit with joint offsets, a tracker whose frame is fitted and
/// a reflector recorded at one tool orientation (a 4×4×3 grid of positions, flange z held
/// vertical, the CTU 6×6×6 file's design) converges in a few iterations, whether the reflector
/// offset's prior is free (10 m, the CTU example's) or physical (0.2 m); the Levenberg–Marquardt
/// damping `λ·diag H` already makes the steps independent of the columns' units. What the grid
/// leaves undetermined is the reflector offset along the held flange axis (confounded with the
/// tracker translation): its posterior σ is ~0.1 m against a 0.05 mm noise. Measured on the CTU
/// data (not reproducible here without it): the capped fit's last steps move exactly such a
/// pair, robot 2's reflector offset and its tracker's translation.
#[test]
fn compliance_fit_with_a_free_reflector_offset_converges() {
    let tol = Tolerance {
        compliance_rad_per_nm: Some(1e-6),
        origin_xyz_m: 0.0,
        origin_rpy_rad: 0.0,
        tip_m: 0.0,
        ..Tolerance::default()
    };
    let sc = sim_cell(Cell::Floor, tol, true, 61);
    let mut base = sc.problem();
    base.observations = sc.coincident(20, 5e-5, 0.7, 62);
    let tracker_from_b1 =
        Isometry3::new(Vector3::new(2.0, -1.0, 0.3), Vector3::new(0.1, -0.2, 2.5));
    let mut rng = ChaCha8Rng::seed_from_u64(63);
    for (i, j, k) in (0..4).flat_map(|i| (0..4).flat_map(move |j| (0..3).map(move |k| (i, j, k)))) {
        let target =
            sc.centre_b1 + Vector3::new(i as f64 - 1.5, j as f64 - 1.5, k as f64 - 1.0) * 0.12;
        if let Some(q) = sc.solve_true(Robot::One, 1, &target, -Vector3::z_axis()) {
            let g = sc.true_tip(Robot::One, 1, &q);
            let noise = Vector3::from_fn(|_, _| {
                let z: f64 =
                    rand_distr::Distribution::sample(&rand_distr::StandardNormal, &mut rng);
                z * 5e-5
            });
            base.observations.push(Observation {
                row: base.observations.len() + 1,
                kind: ObservationKind::Tracker {
                    robot: Robot::One,
                    q,
                    tool: 1,
                    group: 0,
                    p_tracker: tracker_from_b1 * Point3::from(g) + noise,
                    noise: Noise3::Isotropic { sigma_m: 5e-5 },
                },
            });
        }
    }
    base.trackers = vec![TrackerGroup {
        name: "leica".into(),
        anchor: Robot::One,
        initial_tracker_from_anchor: None,
        fit_scale: false,
        fit_drift: false,
    }];
    let active: Vec<usize> = (0..base.observations.len()).collect();
    for tip_tol in [10.0, 0.2] {
        let mut p = base.clone();
        p.robot1.tolerance.tip_m = tip_tol;
        p.robot2.tolerance.tip_m = 0.0;
        let fixed: Vec<CellParam> = kinematics::Axis::ALL
            .iter()
            .map(|&axis| CellParam::ToolTip {
                robot: Robot::One,
                tool: 0,
                axis,
            })
            .collect();
        let layout = ParamLayout::new(&p, &fixed);
        let fit = fit_cell_with(&p, layout, &active, None, &SolveOptions::default()).unwrap();
        let z_col = fit
            .layout
            .column(&CellParam::ToolTip {
                robot: Robot::One,
                tool: 1,
                axis: kinematics::Axis::Z,
            })
            .unwrap();
        eprintln!(
            "tip tolerance {tip_tol} m: {:?} after {} iterations, data χ² {:.1} ({} rows), \
             reflector {:?} mm, σ_z {:.1} mm",
            fit.stopped,
            fit.iterations,
            fit.data_chi2,
            fit.residual_rows,
            (fit.estimate.robot1.tool_tip_m[1] * 1e3).as_slice(),
            fit.std_error(z_col) * 1e3
        );
        assert_eq!(fit.stopped, StopReason::Converged);
        assert!(fit.iterations <= 15, "{} iterations", fit.iterations);
        assert!(fit.data_chi2 < 1.5 * fit.residual_rows as f64);
        // The flat direction: the offset along the held axis is barely determined (σ_z of
        // ~0.1 m against a noise σ of 0.05 mm).
        assert!(fit.std_error(z_col) > 0.02, "σ_z {}", fit.std_error(z_col));
    }
}
