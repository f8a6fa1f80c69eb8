//! Simulated face-contact sessions (`kind = face_contact`): their normals tilt as specified and
//! they read back through the CSV unchanged, and they satisfy the face-contact model at the truth
//! (and not the sphere-contact model, because the faces slide). (The normal columns' own tests
//! are handclasp-cell's.)

use std::path::Path;

use calib_core::whole_cell::{
    calibrate_cell, Evaluator, ObservationKind, ParamLayout, ScreenOptions, SolveOptions,
};
use calib_core::StopReason;
use handclasp_cell::problem::{cell_problem, session_meeting_pairs, truth_estimate, FitModel};
use handclasp_cell::Cell;
use handclasp_cell::{Session, SessionKind};
use nalgebra::Vector3;
use sim_cell::{
    generate_kind_session, trial_rng, KindSpec, Layout, NuisanceTruth, SessionSpec, SimKind,
};

/// The floor–floor cell with seeded joint offsets (±0.05°) on both robots, and no
/// repeatability or encoder quantisation (so a row's only noise is its stated σ).
fn cell_with_offsets() -> Cell {
    let mut cell = Cell::default_floor_floor();
    cell.noise.repeatability_m = 0.0;
    cell.noise.encoder_resolution_rad = 0.0;
    let offsets1 = [0.03, -0.04, 0.02, 0.05, -0.01, 0.03, 0.0];
    let offsets2 = [-0.02, 0.04, -0.05, 0.01, 0.03, -0.03];
    for (e, o) in cell.robot1.errors.joint_offset.iter_mut().zip(offsets1) {
        *e = f64::to_radians(o);
    }
    for (e, o) in cell.robot2.errors.joint_offset.iter_mut().zip(offsets2) {
        *e = f64::to_radians(o);
    }
    cell
}

fn faces(cell: &Cell, n: usize, slide_m: f64, seed: u64) -> (Session, NuisanceTruth) {
    let spec = SessionSpec::new(n, Layout::Random, 0.7);
    let kinds = KindSpec {
        kind: SimKind::FaceContact,
        contact_distance_m: 0.116,
        contact_sigma_m: 0.05e-3,
        face_slide_m: slide_m,
        ..KindSpec::default()
    };
    generate_kind_session(cell, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .unwrap_or_else(|e| panic!("{e}"))
}

/// A simulated face-contact session written and read back gives the same rows (normals to the
/// file's 9 decimals), and writing it again gives the same text; the normal columns follow the
/// other extra columns; the simulated face normals tilt from the flange z as specified.
#[test]
fn face_contact_session_round_trips_through_the_csv() {
    let cell = cell_with_offsets();
    let (s, _) = faces(&cell, 10, 5e-3, 21);
    assert_eq!(s.kind_counts(), [0, 0, 0, 0, 10]);
    let text = s.csv_text(&cell);
    assert!(
        text.lines()
            .next()
            .unwrap()
            .ends_with(",tracker_z_mm,n1_x,n1_y,n1_z,n2_x,n2_y,n2_z"),
        "{}",
        text.lines().next().unwrap()
    );
    // The touching face varies: its normal within the default 20° (+ the kinematic errors'
    // ≲ 0.5°) of the flange z, and some far from it.
    let tilts: Vec<f64> = s
        .observations
        .iter()
        .filter_map(|o| match &o.kind {
            SessionKind::FaceContact { n1_tip, .. } => Some(n1_tip.angle(&Vector3::z())),
            _ => None,
        })
        .collect();
    assert_eq!(tilts.len(), 10);
    assert!(
        tilts.iter().all(|t| *t <= 20.5f64.to_radians()),
        "{tilts:?}"
    );
    assert!(tilts.iter().any(|t| *t > 5f64.to_radians()), "{tilts:?}");
    let back = Session::parse_csv(&text, Path::new("faces.csv"), &cell).unwrap();
    assert_eq!(back.csv_text(&cell), text);
    for (a, b) in s.observations.iter().zip(&back.observations) {
        let (
            SessionKind::FaceContact {
                n1_tip: a1,
                n2_tip: a2,
                group: ga,
                distance_m: da,
                ..
            },
            SessionKind::FaceContact {
                n1_tip: b1,
                n2_tip: b2,
                group: gb,
                distance_m: db,
                ..
            },
        ) = (&a.kind, &b.kind)
        else {
            panic!("face contacts expected: {:?}", b.kind);
        };
        assert!((a1.into_inner() - b1.into_inner()).amax() < 1e-8);
        assert!((a2.into_inner() - b2.into_inner()).amax() < 1e-8);
        assert_eq!((ga, da), (gb, db));
    }
}

/// Residual rms (whitened) at the truth within which the simulation must satisfy the
/// face-contact model: ~1 for honest noise (60 rows: a band of ±0.5 is > 5 standard errors).
const TRUTH_CHI_BAND: std::ops::RangeInclusive<f64> = 0.5..=1.5;

/// The simulated rows (faces sliding ±10 mm, σ 0.05 mm) fit the face-contact model at the true
/// kinematics and distance with whitened rms ~1, while the same rows read as sphere contacts
/// are off by the slide's `s²/2d` (rms > 3); the session calibrates (`--model kinematic`, from
/// the cell's placement) to the true distance within 4 posterior σ, and its meeting pairs are
/// its rows.
#[test]
fn simulated_face_contacts_satisfy_the_model_at_the_truth() {
    let cell = cell_with_offsets();
    let (s, truth) = faces(&cell, 60, 10e-3, 23);
    assert_eq!(session_meeting_pairs(&s).len(), 60);
    let problem = cell_problem(&cell, &s, FitModel::Kinematic);
    problem.check().unwrap();
    assert_eq!(problem.contacts.len(), 1);
    assert!(problem.contacts[0].fit_distance);
    let mut est = truth_estimate(&cell, &problem);
    est.contact_distance_m = vec![truth.contact_distance_m];
    let layout = ParamLayout::new(&problem, &[]);
    let rms = |p: &calib_core::whole_cell::CellProblem| {
        let ev = Evaluator::new(p, &layout);
        let sum: f64 = p
            .observations
            .iter()
            .map(|o| {
                let l = ev.linearise(o, &est, false).unwrap();
                (&l.whitening * &l.residual).norm_squared()
            })
            .sum();
        (sum / p.observations.len() as f64).sqrt()
    };
    let face_rms = rms(&problem);
    let mut spheres = problem.clone();
    for o in &mut spheres.observations {
        if let ObservationKind::FaceContact {
            q1,
            q2,
            tool1,
            tool2,
            group,
            sigma_m,
            ..
        } = &o.kind
        {
            o.kind = ObservationKind::Contact {
                q1: q1.clone(),
                q2: q2.clone(),
                tool1: *tool1,
                tool2: *tool2,
                group: *group,
                sigma_m: *sigma_m,
            };
        }
    }
    let sphere_rms = rms(&spheres);
    eprintln!("at the truth: face-contact rms {face_rms:.2} σ, as spheres {sphere_rms:.2} σ");
    assert!(TRUTH_CHI_BAND.contains(&face_rms), "{face_rms}");
    assert!(sphere_rms > 3.0, "{sphere_rms}");
    let solve = SolveOptions {
        initial_b1_from_b2: Some(cell.b1_from_b2),
        ..SolveOptions::default()
    };
    let cal = calibrate_cell(&problem, &solve, &ScreenOptions::default()).unwrap();
    assert_eq!(cal.fit.stopped, StopReason::Converged);
    let col = cal
        .fit
        .layout
        .column(&calib_core::whole_cell::CellParam::ContactDistance { group: 0 })
        .unwrap();
    let d = cal.fit.estimate.contact_distance_m[0];
    eprintln!(
        "calibrated: distance {:.4} mm (σ {:.4}), {} rows rejected",
        d * 1e3,
        cal.fit.std_error(col) * 1e3,
        cal.rejected.len()
    );
    assert!((d - truth.contact_distance_m).abs() < 4.0 * cal.fit.std_error(col));
}
