//! The result check's parts on simulated floor–wall sessions: the robust noise scale reads the
//! stated noise, each likely mistake undone by [`Mistake::apply`] is what the data would have
//! been, the placement-only trial of the undone mistake recovers the placement, and the
//! blunder-vs-misfit rule.

use super::*;

/// Tolerance of the noise scale on 40 clean handclasps: the median of 40 χ²₃ draws scatters
/// by about ±20 % (its standard error is ~1.25/√40 of the median's scale).
const NOISE_SCALE_TOL: f64 = 0.35;

/// On clean data at the stated σ the robust noise scale is 1 (within its scatter); with the
/// rows' noise 10 times the stated σ it reads ~10.
#[test]
fn robust_noise_scale_reads_the_stated_noise() {
    let sc = sim_cell(Cell::Wall, Tolerance::none(), false, 61);
    let mut p = sc.problem();
    p.observations = sc.coincident(40, 3e-4, 0.7, 62);
    let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
    let s = robust_noise_scale(&p, &fit, 1.0).unwrap();
    assert!((s - 1.0).abs() < NOISE_SCALE_TOL, "noise scale {s}");
    let mut noisy = sc.problem();
    noisy.observations = sc.coincident(40, 3e-3, 0.7, 62);
    for o in &mut noisy.observations {
        o.kind.scale_noise(0.1);
    }
    let fit = fit_cell(&noisy, &SolveOptions::default()).unwrap();
    let s = robust_noise_scale(&noisy, &fit, 1.0).unwrap();
    assert!((s / 10.0 - 1.0).abs() < NOISE_SCALE_TOL, "noise scale {s}");
}

/// Makes a mistake on a copy of clean data.
type MakeMistake = Box<dyn Fn(&mut CellProblem)>;

/// Each mistake made on clean data and undone by its `apply` gives back the placement: the
/// swapped joints 4 and 6 of robot 2, a flipped joint 5 (symmetric limits), radians read as degrees, robot 2's rows
/// shifted by one; the trial of the mistake as given is far off.
#[test]
fn undoing_a_mistake_recovers_the_placement() {
    let sc = sim_cell(Cell::Wall, Tolerance::none(), false, 63);
    let mut clean = sc.problem();
    clean.observations = sc.coincident(30, 3e-4, 0.7, 64);
    let x = sc.truth.b1_from_b2;
    let cases: Vec<(Mistake, MakeMistake)> = vec![
        (
            Mistake::SwappedJoints {
                robot: Robot::Two,
                a: 3,
                b: 5,
            },
            Box::new(|p: &mut CellProblem| {
                for o in &mut p.observations {
                    if let ObservationKind::Coincident { q2, .. } = &mut o.kind {
                        q2.swap(3, 5);
                    }
                }
            }),
        ),
        (
            Mistake::FlippedJoint {
                robot: Robot::Two,
                joint: 4,
            },
            Box::new(|p: &mut CellProblem| {
                for o in &mut p.observations {
                    if let ObservationKind::Coincident { q2, .. } = &mut o.kind {
                        q2[4] = -q2[4];
                    }
                }
            }),
        ),
        (
            Mistake::RadiansAsDegrees { robot: Robot::One },
            Box::new(|p: &mut CellProblem| {
                for o in &mut p.observations {
                    if let ObservationKind::Coincident { q1, .. } = &mut o.kind {
                        for v in q1.iter_mut() {
                            *v = v.to_radians();
                        }
                    }
                }
            }),
        ),
        (
            Mistake::ShiftedRows { by: 1 },
            Box::new(|p: &mut CellProblem| {
                let q2s: Vec<Vec<f64>> = p
                    .observations
                    .iter()
                    .map(|o| match &o.kind {
                        ObservationKind::Coincident { q2, .. } => q2.clone(),
                        _ => unreachable!("coincident rows only"),
                    })
                    .collect();
                let n = q2s.len();
                for (i, o) in p.observations.iter_mut().enumerate() {
                    if let ObservationKind::Coincident { q2, .. } = &mut o.kind {
                        *q2 = q2s[(i + 1) % n].clone();
                    }
                }
            }),
        ),
    ];
    for (mistake, make) in cases {
        let mut wrong = clean.clone();
        make(&mut wrong);
        let as_given = try_problem(&wrong, &x).unwrap();
        let undone = try_problem(&mistake.apply(&wrong).unwrap(), &x).unwrap();
        let d = undone.distance(&x);
        eprintln!(
            "{}: as given noise {:.1}, undone noise {:.2}, {:.2} mm / {:.3}°",
            mistake.describe(),
            as_given.noise_scale,
            undone.noise_scale,
            d.translation_mm,
            d.rotation_deg
        );
        // Undone: the stated noise (within its scatter) and the placement within 2 mm / 0.1°
        // (30 handclasps at 0.3 mm); as given: at least 10 times the stated noise.
        assert!(
            undone.noise_scale < 1.0 + NOISE_SCALE_TOL,
            "{}",
            mistake.describe()
        );
        assert!(
            d.translation_mm < 2.0 && d.rotation_deg < 0.1,
            "{}",
            mistake.describe()
        );
        assert!(as_given.noise_scale > 10.0, "{}", mistake.describe());
    }
}

/// Robots of different joint counts cannot have swapped columns; a zero tip has no sign.
#[test]
fn mistakes_that_cannot_apply_are_skipped() {
    let sc = sim_cell(Cell::Wall, Tolerance::none(), false, 65);
    let mut p = sc.problem();
    p.observations = sc.coincident(8, 3e-4, 0.7, 66);
    p.robot1.tools[0].flange_from_tip = Vector3::zeros();
    if p.robot1.model.dof() != p.robot2.model.dof() {
        assert!(Mistake::SwappedRobots.apply(&p).is_none());
    }
    assert!(Mistake::TipSign { robot: Robot::One }.apply(&p).is_none());
    assert!(Mistake::TipLeftOut { robot: Robot::One }
        .apply(&p)
        .is_none());
}

/// Blunders or misfit: three rows of forty (7.5 %) with the rest at the stated noise are
/// blunders; the same share with the rest noisy is a misfit; a quarter of the rows is a misfit
/// whatever the rest; four rows in a row of forty cluster in time.
#[test]
fn blunders_or_misfit() {
    let sc = sim_cell(Cell::Wall, Tolerance::none(), false, 67);
    let mut p = sc.problem();
    p.observations = sc.coincident(40, 3e-4, 0.7, 68);
    let fit = fit_cell(&p, &SolveOptions::default()).unwrap();
    let spread = [3, 17, 31];
    let c = classify_rejections(&p, &fit, &spread, 1.0, 3.0).unwrap();
    assert!(!c.misfit, "{c:?}");
    assert!(
        classify_rejections(&p, &fit, &spread, 5.0, 3.0)
            .unwrap()
            .misfit
    );
    let quarter: Vec<usize> = (0..40).step_by(4).collect();
    assert!(
        classify_rejections(&p, &fit, &quarter, 1.0, 3.0)
            .unwrap()
            .misfit
    );
    let run = [20, 21, 22, 23];
    let c = classify_rejections(&p, &fit, &run, 1.0, 3.0).unwrap();
    assert!(c.misfit && c.time_cluster.is_some(), "{c:?}");
}
