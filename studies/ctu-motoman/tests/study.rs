//! The study's core on the real CTU data (`../shared/data/ctu-motoman` from the
//! repository root, or `$CTU_MOTOMAN_DATA`): a self-contact calibration, its export (URDFs
//! re-load and reproduce the fitted model to 1e-9 m; the cell loads) and the honest tracker
//! score; and the CV selection rules on made-up tables (no data needed). The data tests skip with a
//! printed reason when the data folder is absent.

use std::path::{Path, PathBuf};

use calib_core::whole_cell::{CellEstimate, Evaluator, ObservationKind, ParamLayout};
use handclasp_cell::Cell;
use handclasp_cell::{export_calibrated_cell, ExportNames, ImportMap, Session, SessionKind};
use kinematics::{true_base_from_tip, KinematicErrors};

use ctu_motoman::{contact, cv, data, proxy, splits, study};

use data::{locate_dataset, read_dataset, Recording, Role};
use study::{
    build_problem, corrections, fit, residuals, score_recording, summarise, ModelSpec, NoiseLevels,
    ParamSet,
};

/// Exported URDF + cell errors against the fitted model: the URDF patch keeps 9 decimals only
/// when their rounding provably stays within half of this (kinematics::PATCH_TOLERANCE_M).
const EXPORT_TOL_M: f64 = 1e-9;

fn dataset() -> Option<PathBuf> {
    let d = locate_dataset(&ctu_motoman::repo_root());
    if d.is_none() {
        eprintln!(
            "skipping: the CTU dataset folder ../shared/data/ctu-motoman (from the repository \
             root) is absent and $CTU_MOTOMAN_DATA is not set"
        );
    }
    d
}

/// The dataset's recordings and the shipped CTU cell; `None` (with the printed reason) when the
/// data folder is absent.
fn dataset_and_cell() -> Option<(Vec<Recording>, Cell)> {
    let recs = read_dataset(&dataset()?).unwrap();
    let cell =
        Cell::from_toml_file(&ctu_motoman::repo_root().join("cells/ctu-motoman.toml")).unwrap();
    Some((recs, cell))
}

/// The no-tracker self-contact recordings.
fn self_contact(recs: &[Recording]) -> Vec<&Recording> {
    recs.iter()
        .filter(|r| r.role == Role::SelfContact)
        .collect()
}

/// Noise levels of the study's nominal fit (the example measures them; fixed here for speed).
fn noise() -> NoiseLevels {
    NoiseLevels {
        contact_m: 1.33e-3,
        marker_contact_m: None,
        leica_contact_m: 0.28e-3,
        plane_m: 0.95e-3,
        tracker_m: 0.28e-3,
    }
}

#[test]
fn self_contact_calibration_exports_a_cell_that_reproduces_the_fit() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let self_recs = self_contact(&recs);
    assert_eq!(self_recs.len(), 4);
    let spec = ModelSpec {
        set: ParamSet::OffsetsLengths,
        sigma: 1.0,
    };
    let b = build_problem(&cell, &self_recs, Some(spec), &noise());
    assert_eq!(b.problem.observations.len(), 502);
    let f = fit(&b, None, None).unwrap();
    assert_eq!(f.stopped.name(), "converged");
    // The contact distance stays near the README's 116 mm (a runaway would move it by tens).
    let d = f.estimate.contact_distance_m[0];
    assert!((d - 0.116).abs() < 2e-3, "contact distance {d} m");
    // The common base is held by the library's placement prior (the cell's `[b1_from_b2]
    // sigma_mm, sigma_deg`): every component stays within one prior σ.
    let prior = b
        .problem
        .placement_prior
        .expect("the CTU cell states its placement σ");
    let t = f.estimate.b1_from_b2.translation.vector;
    let w = f.estimate.b1_from_b2.rotation.scaled_axis();
    assert!(
        t.amax() < prior.sigma_m && w.amax() < prior.sigma_rad,
        "placement moved {t:?} m, {w:?} rad; prior σ {} m, {} rad",
        prior.sigma_m,
        prior.sigma_rad
    );

    let out = tempfile::tempdir().unwrap();
    let names = ExportNames {
        cell: "cell.toml",
        robot1_urdf: "right_arm.urdf",
        robot2_urdf: "left_arm.urdf",
        header: "# test\n",
    };
    let written = export_calibrated_cell(&cell, &f.estimate, out.path(), &names).unwrap();
    assert_eq!(written.len(), 3);
    let exported = Cell::from_toml_file(&out.path().join("cell.toml")).unwrap();
    let joints: Vec<&str> = exported
        .robot1
        .model
        .joints()
        .iter()
        .map(|j| j.name.as_str())
        .collect();
    assert_eq!(joints.len(), 6, "six revolute joints S..T: {joints:?}");
    assert_eq!(exported.robot1.model.tool_link(), "tool0");
    for (setup, fitted, exp) in [
        (&cell.robot1, &f.estimate.robot1.errors, &exported.robot1),
        (&cell.robot2, &f.estimate.robot2.errors, &exported.robot2),
    ] {
        for rec in &self_recs {
            for pose in rec.poses.iter().step_by(10) {
                let q = if std::ptr::eq(setup, &cell.robot1) {
                    &pose.q_right
                } else {
                    &pose.q_left
                };
                let want = true_base_from_tip(
                    &setup.model,
                    fitted,
                    q,
                    &setup.flange_from_tip,
                    &setup.g_base,
                )
                .unwrap();
                let got = true_base_from_tip(
                    &exp.model,
                    &exp.errors,
                    q,
                    &exp.flange_from_tip,
                    &exp.g_base,
                )
                .unwrap();
                let dp = (want.translation.vector - got.translation.vector).norm();
                let dr = want.rotation.angle_to(&got.rotation);
                assert!(dp < EXPORT_TOL_M && dr < EXPORT_TOL_M, "{dp} m, {dr} rad");
            }
        }
    }
}

#[test]
fn honest_score_reproduces_the_independent_nominal_figure_on_the_right_grid() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let grid = recs
        .iter()
        .find(|r| r.name == "leica_right_hand_6x6x6")
        .unwrap();
    let zero = KinematicErrors::zero(6);
    let s = score_recording(&cell, grid, (&zero, &zero), None).unwrap();
    // Every pose with a tracker value is scored once (212 of 216).
    assert_eq!(s.len(), 212);
    let sum = summarise(&s.iter().map(|p| p.error_m).collect::<Vec<_>>());
    // The Python study (another split) measured 0.252 mm; the Rust split gives 0.250 mm. A
    // protocol error (no reflector fit, a biased reflector prior) gives ≥ 0.3 mm.
    assert!(
        (0.2..0.28).contains(&sum.rms_mm),
        "nominal right-grid held-out rms {} mm",
        sum.rms_mm
    );
    assert!(sum.median_mm <= sum.p95_mm && sum.p95_mm <= sum.max_mm);
}

#[test]
fn a_wrong_data_folder_is_a_clear_error() {
    let e = read_dataset(Path::new("/nonexistent/ctu-motoman"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("not the ctu-motoman dataset folder"), "{e}");
}

/// The `--select tracker` choice scores exactly the grids and the four `leica_self` files,
/// trains on the self-contacts only, and never sees a table/wall file (the evaluation files).
/// The study's reader (`data::read_dataset`) and `handclasp import` with the shipped maps
/// (`tools/ctu-motoman/maps/`) read the same numbers from every recording: the contact map the
/// self-contact files' joints of both arms, the plane map the plane files' right-arm joints, the
/// tracker maps each tracker file's measured arm and its tracker positions (rows without one are
/// skipped by the map, kept by the reader as poses without a position). Tracker positions are
/// equal exactly (both parse the same decimal text, unit m); joints to [`IMPORT_JOINT_ROUNDING_RAD`],
/// because the import converts every joint through degrees (`(x·deg_per_unit).to_radians()`), a
/// few ulps (measured: 0.23881 reads as 0.23881000000000002). So a session imported with the maps
/// holds the data the study fits; the reader stays the study's own because the study keeps both
/// arms' joints of every pose (the proxy, the figures and the per-pose splits need them), chooses
/// the rows' σ after reading (from the nominal fit), which a map fixes when it reads, and because
/// the degree round trip would move the study's outputs in their last digits.
/// How far an imported joint may sit from the study's reading of the same text, rad: the degree
/// round trip of the import errs by a few ulps of values up to π (ulp 4.4e-16 at 2..4).
const IMPORT_JOINT_ROUNDING_RAD: f64 = 4e-15;

/// Whether two joint vectors agree to [`IMPORT_JOINT_ROUNDING_RAD`].
fn same_joints(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= IMPORT_JOINT_ROUNDING_RAD)
}

#[test]
fn the_reader_reads_what_the_shipped_import_maps_read() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let dir = dataset().unwrap();
    let maps = ctu_motoman::repo_root().join("tools/ctu-motoman/maps");
    let map = |name: &str| {
        let path = maps.join(name);
        ImportMap::from_toml_str(&std::fs::read_to_string(&path).unwrap(), &path, &cell).unwrap()
    };
    let (contact, plane) = (map("self_contact.toml"), map("plane_right.toml"));
    let (tracker_right, tracker_left) = (map("tracker_right.toml"), map("tracker_left.toml"));
    let mut rows_compared = 0;
    for rec in &recs {
        let input = dir.join(format!("{}_dataset.csv", rec.name));
        let text = std::fs::read_to_string(&input).unwrap();
        let import = |m: &ImportMap| {
            let mut session = Session::default();
            m.read_rows(&text, &input, &cell, &mut session).unwrap();
            assert!(session.points.is_empty(), "{}", rec.name);
            session.observations
        };
        if matches!(rec.role, Role::SelfContact | Role::TrackerSelfContact) {
            let rows = import(&contact);
            assert_eq!(rows.len(), rec.poses.len(), "{}", rec.name);
            for (row, pose) in rows.iter().zip(&rec.poses) {
                let SessionKind::Contact { q1, q2, .. } = &row.kind else {
                    panic!("{}: not a contact row", rec.name);
                };
                assert!(
                    same_joints(q1, &pose.q_right) && same_joints(q2, &pose.q_left),
                    "{}: {q1:?} {q2:?} vs {:?} {:?}",
                    rec.name,
                    pose.q_right,
                    pose.q_left
                );
                rows_compared += 1;
            }
        }
        if rec.role == Role::Plane {
            let rows = import(&plane);
            assert_eq!(rows.len(), rec.poses.len(), "{}", rec.name);
            for (row, pose) in rows.iter().zip(&rec.poses) {
                let SessionKind::Plane { q, .. } = &row.kind else {
                    panic!("{}: not a plane row", rec.name);
                };
                assert!(same_joints(q, &pose.q_right), "{}: {q:?}", rec.name);
                rows_compared += 1;
            }
        }
        if matches!(rec.role, Role::Tracker | Role::TrackerSelfContact) {
            let rows = import(if rec.right_arm {
                &tracker_right
            } else {
                &tracker_left
            });
            let measured: Vec<_> = rec.poses.iter().filter(|p| p.p_tracker.is_some()).collect();
            assert_eq!(rows.len(), measured.len(), "{}", rec.name);
            for (row, pose) in rows.iter().zip(measured) {
                let SessionKind::Tracker { q, p_tracker, .. } = &row.kind else {
                    panic!("{}: not a tracker row", rec.name);
                };
                let q_arm = if rec.right_arm {
                    &pose.q_right
                } else {
                    &pose.q_left
                };
                assert!(same_joints(q, q_arm), "{}: {q:?} vs {q_arm:?}", rec.name);
                assert_eq!(Some(*p_tracker), pose.p_tracker, "{}", rec.name);
                rows_compared += 1;
            }
        }
    }
    // Every recording (22 files) and every row of every role compared: 1746 rows, counted in the
    // files with Python's csv module (self-contact and plane rows, plus tracker rows with all
    // three leica_*_m columns set).
    assert_eq!(recs.len(), 22);
    assert_eq!(rows_compared, 1746);
}

/// `build_problem` (the recordings as a session through `handclasp_cell::cell_problem`) on
/// made-up recordings of every role, no data needed: rows in recording and pose order with their
/// origins and σ, contact groups `no_leica_self` then `leica_self` starting at the study's
/// distances and fitted, one plane per plane file at robot 1, one tracker frame and one
/// reflector tool per tracker file on its arm (a pose without a tracker value gives no row),
/// tool 0 named `marker`, and the prior of the spec.
#[test]
fn build_problem_turns_recordings_into_the_adapters_problem() {
    let cell =
        Cell::from_toml_file(&ctu_motoman::repo_root().join("cells/ctu-motoman.toml")).unwrap();
    let pose = |k: f64, tracker: bool| data::Pose {
        q_right: vec![0.1 * k, 0.2, -0.1, 0.3, 0.4, -0.2],
        q_left: vec![-0.1 * k, 0.1, 0.2, -0.3, 0.2, 0.1],
        p_tracker: tracker.then(|| nalgebra::Point3::new(1.0, 2.0 * k, 0.5)),
        faces: None,
    };
    let rec = |name: &str, role: Role, right_arm: bool, poses: Vec<data::Pose>| Recording {
        name: name.into(),
        role,
        pattern: "made_up",
        right_arm,
        poses,
    };
    let recs = [
        rec(
            "self_a",
            Role::SelfContact,
            true,
            vec![pose(1.0, false), pose(2.0, false)],
        ),
        rec("plane_a", Role::Plane, true, vec![pose(3.0, false)]),
        rec(
            "grid_left",
            Role::Tracker,
            false,
            vec![pose(4.0, true), pose(5.0, false)],
        ),
        rec(
            "leica_self_a",
            Role::TrackerSelfContact,
            true,
            vec![pose(6.0, true)],
        ),
    ];
    let refs: Vec<&Recording> = recs.iter().collect();
    let spec = ModelSpec {
        set: study::ParamSet::OffsetsCompliance,
        sigma: 3.0,
    };
    let b = build_problem(&cell, &refs, Some(spec), &noise());
    let p = &b.problem;
    let kinds: Vec<&str> = p
        .observations
        .iter()
        .map(|o| match o.kind {
            ObservationKind::Contact { .. } => "contact",
            ObservationKind::Plane { .. } => "plane",
            ObservationKind::Tracker { .. } => "tracker",
            _ => "other",
        })
        .collect();
    assert_eq!(
        kinds,
        ["contact", "contact", "plane", "tracker", "contact", "tracker"]
    );
    let rows: Vec<usize> = p.observations.iter().map(|o| o.row).collect();
    assert_eq!(rows, [1, 2, 3, 4, 5, 6]);
    let origin: Vec<(usize, usize)> = b.origin.iter().map(|o| (o.recording, o.pose)).collect();
    assert_eq!(origin, [(0, 0), (0, 1), (1, 0), (2, 0), (3, 0), (3, 0)]);
    let contacts: Vec<(&str, f64, bool)> = p
        .contacts
        .iter()
        .map(|c| (c.name.as_str(), c.distance_m, c.fit_distance))
        .collect();
    assert_eq!(
        contacts,
        [
            ("no_leica_self", study::CONTACT_START_M, true),
            ("leica_self", study::LEICA_SELF_CONTACT_START_M, true)
        ]
    );
    assert_eq!(p.planes.len(), 1);
    assert_eq!(p.planes[0].anchor, calib_core::Robot::One);
    let trackers: Vec<(&str, calib_core::Robot)> = p
        .trackers
        .iter()
        .map(|t| (t.name.as_str(), t.anchor))
        .collect();
    assert_eq!(
        trackers,
        [
            ("grid_left", calib_core::Robot::Two),
            ("leica_self_a", calib_core::Robot::One)
        ]
    );
    let tools = |r: &calib_core::whole_cell::CellRobot| -> Vec<String> {
        r.tools.iter().map(|t| t.name.clone()).collect()
    };
    assert_eq!(tools(&p.robot1), ["marker", "reflector leica_self_a"]);
    assert_eq!(tools(&p.robot2), ["marker", "reflector grid_left"]);
    match (&p.observations[3].kind, &p.observations[5].kind) {
        (
            ObservationKind::Tracker {
                tool: 1, group: 0, ..
            },
            ObservationKind::Tracker {
                tool: 1, group: 1, ..
            },
        ) => {}
        other => panic!("tracker rows' tools and groups: {other:?}"),
    }
    match (&p.observations[0].kind, &p.observations[4].kind) {
        (
            ObservationKind::Contact {
                group: 0,
                sigma_m: s0,
                ..
            },
            ObservationKind::Contact {
                group: 1,
                sigma_m: s1,
                ..
            },
        ) => assert_eq!((*s0, *s1), (noise().contact_m, noise().leica_contact_m)),
        other => panic!("contact rows' groups: {other:?}"),
    }
    // The prior of the spec: offsets and compliance at σ 3 (tolerance √3·σ), tips free (10 m).
    let t = p.robot1.tolerance;
    assert_eq!(t.joint_offset_rad, 3f64.sqrt() * 3e-3);
    assert_eq!(t.tip_m, study::TIP_TOLERANCE_M);
    assert!(t.compliance_rad_per_nm.is_some());
    assert_eq!(p.robot2.tolerance, t);
    assert!(b.marker_sigma_m.is_none());
}

#[test]
fn self_selection_scores_the_grids_and_leica_self_and_trains_on_self_contact_only() {
    let Some((recs, _)) = dataset_and_cell() else {
        return;
    };
    let selection = data::self_selection_recordings(&recs);
    let mut names: Vec<&str> = selection.iter().map(|r| r.name.as_str()).collect();
    names.sort_unstable();
    assert_eq!(
        names,
        [
            "leica_left_hand_6x6x6",
            "leica_right_hand_6x6x6",
            "leica_self_lower1_4x4",
            "leica_self_lower2_4x4",
            "leica_self_upper1_4x4",
            "leica_self_upper2_4x4",
        ]
    );
    assert!(selection.iter().all(|r| r.pattern == "selection"));
    // The CV over self-contacts + selection, fold "selection": its training set.
    let pool: Vec<&Recording> = self_contact(&recs).into_iter().chain(&selection).collect();
    let train: Vec<&Recording> = pool
        .iter()
        .copied()
        .filter(|r| r.pattern != "selection")
        .collect();
    assert_eq!(train.len(), 4);
    assert!(train.iter().all(|r| r.role == Role::SelfContact));
    // No table/wall tracker file is scored.
    assert!(selection.iter().all(|r| r.pattern != "leica_table"
        && !r.name.contains("table")
        && !r.name.contains("wall")));
}

#[test]
fn halves_are_disjoint_and_cover_every_row() {
    let (a, b) = study::halves(25, study::SPLIT_SEED);
    assert_eq!((a.len(), b.len()), (12, 13));
    let mut all: Vec<usize> = a.iter().chain(&b).copied().collect();
    all.sort_unstable();
    assert_eq!(all, (0..25).collect::<Vec<_>>());
    assert_eq!(study::halves(25, study::SPLIT_SEED), (a, b), "seeded");
}

/// Torque below which a joint counts as carrying no gravity torque, N·m (round-off of sums of
/// ~10² N·m terms).
const ZERO_TORQUE_NM: f64 = 1e-9;

#[test]
fn point_mass_inertials_load_only_l_and_u_gravity_torques() {
    // Needs no data: the URDFs' point masses (30 kg on the U axis, 10 kg at the wrist centre)
    // give no torque about R, B, T (the wrist mass sits on the R and B axes, T carries no mass).
    // S is tilted 15° from the base z by DH row TT, so it does carry a torque (not fitted).
    let cell =
        Cell::from_toml_file(&ctu_motoman::repo_root().join("cells/ctu-motoman.toml")).unwrap();
    let g = nalgebra::Vector3::new(0.0, 0.0, -9.81);
    for robot in [&cell.robot1, &cell.robot2] {
        for q in [
            [0.0, 0.0, 0.0, 0.0, std::f64::consts::FRAC_PI_2, 0.0],
            [0.3, 0.5, -0.6, 1.0, 0.8, -2.0],
            [-1.0, 1.1, 0.4, -2.2, 2.5, 3.0],
        ] {
            let tau = kinematics::gravity_torques(&robot.model, &q, &g).unwrap();
            for j in [3, 4, 5] {
                assert!(tau[j].abs() < ZERO_TORQUE_NM, "joint {j}: {} N·m", tau[j]);
            }
            // The U torque is the wrist weight times its horizontal lever (≤ 0.67 m: 0.64 m
            // forearm, 0.2 m offset), and L's adds the elbow's (≤ 0.614 m).
            let w = 10.0 * 9.81;
            assert!(tau[2].abs() <= w * 0.67, "U {} N·m", tau[2]);
            assert!(tau[1].abs() <= w * (0.614 + 0.67) + 30.0 * 9.81 * 0.614);
        }
        let tau = kinematics::gravity_torques(&robot.model, &[0.0, 0.5, -0.6, 0.0, 1.0, 0.0], &g)
            .unwrap();
        assert!(tau[1].abs() > 1.0 && tau[2].abs() > 1.0, "{tau:?}");
    }
}

/// The contact residual (centre distance minus the fitted distance, rms over the no-tracker
/// self-contacts) that fitting only the two marker centres (x, y; nominal joints) must reach, m.
/// Nominal: 1.33 mm; measured with the marker centres: 0.33 mm (the Python study's
/// along-normal fit: 0.31 mm). A fit that did not move the centres stays above 1 mm.
const MARKER_CONTACT_RMS_TOL_M: f64 = 0.4e-3;

/// Lowest polar angle of the contact directions from tool z, rad (5° under arctan 2 = 63.43°);
/// a contact through the marker's top face would be near 0.
const RING_POLAR_MIN_RAD: f64 = 58.0 * std::f64::consts::PI / 180.0;

#[test]
fn face_pairs_are_eight_in_the_self_files_and_one_in_leica_self() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let self_recs = self_contact(&recs);
    let leica: Vec<_> = recs
        .iter()
        .filter(|r| r.role == Role::TrackerSelfContact)
        .collect();
    let ring = contact::fit_ring(&cell, &self_recs).unwrap();
    assert!(
        (ring.polar_mean_rad - contact::ring_polar_angle()).abs() < 1f64.to_radians(),
        "contact directions at {}° from tool z",
        ring.polar_mean_rad.to_degrees()
    );
    // Every direction is within a few degrees of a ring face (the faces are 72° apart).
    assert!(ring.azimuth_max_dev_rad < 5f64.to_radians());
    let zero = KinematicErrors::zero(6);
    let rows = contact::pair_table(&cell, &self_recs, &ring, &[(&zero, &zero)]).unwrap();
    assert_eq!(
        rows.len(),
        8,
        "{:?}",
        rows.iter().map(|r| r.pair).collect::<Vec<_>>()
    );
    assert_eq!(rows.iter().map(|r| r.n).sum::<usize>(), 502);
    for r in &rows {
        // Flush faces: the two normals anti-parallel to a fraction of a degree.
        assert!(r.misalign.0 < 0.5f64.to_radians(), "{:?}", r);
    }
    let leica_rows = contact::pair_table(&cell, &leica, &ring, &[(&zero, &zero)]).unwrap();
    assert_eq!(leica_rows.len(), 1);
    assert_eq!(leica_rows[0].n, 64);
    for rec in self_recs.iter().chain(&leica) {
        for c in contact::face_contacts(&cell, rec, &ring, (&zero, &zero)).unwrap() {
            assert!(c.face_right < 5 && c.face_left < 5);
        }
    }
    assert!(ring.polar_mean_rad - 3.0 * ring.polar_sd_rad > RING_POLAR_MIN_RAD);
    // The leave-one-face-pair-out folds: 8 folds, every pose once.
    let (split, folds) = contact::split_by_face_pair(&cell, &self_recs, &ring).unwrap();
    assert_eq!(folds.len(), 8, "{folds:?}");
    assert_eq!(split.iter().map(|r| r.poses.len()).sum::<usize>(), 502);
}

/// Largest slide of the touching faces across their mean normal over the no-tracker
/// self-contacts at nominal kinematics, m: measured 3.22 mm (`--contact-model face` prints it;
/// the Python check, tools/ctu-motoman/face_contact.py, found at most 3.2 mm), rounded up.
const SLIDE_MAX_M: f64 = 3.5e-3;
/// Margin on the slide term `SLIDE_MAX²/(2·d)` (0.053 mm at d = 116 mm), m. The exact excess of
/// the centre distance over the along-normal distance `a` is `√(a² + s²) − a ≤ s²/(2·a)`; `a` is
/// the contact distance d within the nominal contact residual (1.33 mm rms, a few mm at most),
/// so `s²/(2·a)` exceeds `s²/(2·d)` by a few per cent of 0.053 mm: 5 µm covers 9 %.
const FACE_ROW_MARGIN_M: f64 = 5e-6;

/// `--contact-model face` (issue 12): at nominal kinematics and the same contact distance, each
/// no-tracker self-contact row built as `FaceContact` (the ring faces assigned at nominal, the
/// normals in the marker tip frames) differs from its `Contact` row by the faces' slide term
/// only, `s²/(2·d)`, bounded by [`SLIDE_MAX_M`] and [`FACE_ROW_MARGIN_M`]. A normal in the
/// wrong frame or a wrong face tilts the mean normal away from the centre line: a 5° tilt alone
/// slides the centres by 10 mm, 0.4 mm of difference.
#[test]
fn face_contact_rows_differ_from_distance_rows_by_the_slide_term_only() {
    let Some((mut recs, cell)) = dataset_and_cell() else {
        return;
    };
    let nominal_residuals = |recs: &[Recording]| -> Vec<(bool, f64)> {
        let b = build_problem(&cell, &self_contact(recs), None, &noise());
        let est = CellEstimate::nominal(&b.problem, cell.b1_from_b2);
        assert_eq!(est.contact_distance_m, vec![study::CONTACT_START_M]);
        let layout = ParamLayout::new(&b.problem, &[]);
        let ev = Evaluator::new(&b.problem, &layout);
        b.problem
            .observations
            .iter()
            .map(|o| {
                let face = matches!(o.kind, ObservationKind::FaceContact { .. });
                (face, ev.linearise(o, &est, false).unwrap().residual[0])
            })
            .collect()
    };
    let distance = nominal_residuals(&recs);
    let ring = contact::fit_ring(&cell, &self_contact(&recs)).unwrap();
    // The no-tracker (502) and leica_self (64) self-contact poses.
    assert_eq!(
        contact::assign_face_normals(&cell, &mut recs, &ring).unwrap(),
        566
    );
    let face = nominal_residuals(&recs);
    assert_eq!(distance.len(), 502);
    assert_eq!(face.len(), 502);
    assert!(distance.iter().all(|r| !r.0) && face.iter().all(|r| r.0));

    let zero = KinematicErrors::zero(6);
    let mut slide_max: f64 = 0.0;
    for rec in self_contact(&recs) {
        for c in contact::face_contacts(&cell, rec, &ring, (&zero, &zero)).unwrap() {
            slide_max = slide_max.max(c.slide_m);
        }
    }
    assert!(
        slide_max < SLIDE_MAX_M,
        "faces slide up to {:.2} mm",
        slide_max * 1e3
    );
    let tol = SLIDE_MAX_M.powi(2) / (2.0 * study::CONTACT_START_M) + FACE_ROW_MARGIN_M;
    let diffs: Vec<f64> = distance.iter().zip(&face).map(|(d, f)| d.1 - f.1).collect();
    let worst = diffs.iter().map(|d| d.abs()).fold(0.0, f64::max);
    assert!(
        worst < tol,
        "a face row differs from its distance row by {:.4} mm (tolerance {:.4} mm)",
        worst * 1e3,
        tol * 1e3
    );
    // The centre distance is never shorter than its projection on the mean normal (1e-12 m:
    // round-off of two 0.116 m norms).
    assert!(diffs.iter().all(|&d| d > -1e-12), "{diffs:?}");
}

/// A model scored against its own predictions by the proxy protocol (registration + reflector
/// fitted on one half) must leave only solver round-off, m.
const PROXY_SELF_TOL_M: f64 = 1e-9;

#[test]
fn proxy_set_is_seeded_within_limits_and_scores_a_model_against_itself_to_zero() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let (joints, draws) = proxy::proxy_joints(&cell, &recs).unwrap();
    assert_eq!(joints.len(), proxy::PROXY_POSES);
    assert!(draws >= joints.len());
    for q in &joints {
        for (v, j) in q.iter().zip(cell.robot1.model.joints()) {
            assert!(*v >= j.lower && *v <= j.upper);
        }
    }
    assert_eq!(
        proxy::proxy_joints(&cell, &recs).unwrap().0,
        joints,
        "seeded"
    );
    let mut offset = KinematicErrors::zero(6);
    offset.set(kinematics::ErrorParam::JointOffset { joint: 2 }, 2e-3);
    let reference = proxy::reference_recording(&cell, &joints, &offset).unwrap();
    let same = proxy::model_difference(&cell, &reference, &offset).unwrap();
    assert!(same.rms_mm * 1e-3 < PROXY_SELF_TOL_M, "{} mm", same.rms_mm);
    // A 2 mrad U offset is not a rigid motion: the nominal model differs by millimetres.
    let nominal = proxy::model_difference(&cell, &reference, &KinematicErrors::zero(6)).unwrap();
    assert!(nominal.rms_mm > 0.5, "{} mm", nominal.rms_mm);
}

#[test]
fn marker_centre_fit_lowers_the_contact_residual() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let self_recs = self_contact(&recs);
    let contact_rms = |spec: Option<ModelSpec>| {
        let b = build_problem(&cell, &self_recs, spec, &noise());
        let f = fit(&b, None, None).unwrap();
        assert_eq!(f.stopped.name(), "converged");
        let r = residuals(&b.problem, &f, &f.estimate).unwrap();
        let rms = (r.iter().map(|x| x.0 * x.0).sum::<f64>() / r.len() as f64).sqrt();
        (rms, f)
    };
    let (before, _) = contact_rms(None);
    let (after, f) = contact_rms(Some(ModelSpec {
        set: ParamSet::OffsetsMarker,
        sigma: 0.0,
    }));
    assert!(before > 1e-3, "nominal contact rms {before} m");
    assert!(
        after < MARKER_CONTACT_RMS_TOL_M,
        "contact rms with the marker centres {after} m (nominal {before} m)"
    );
    // Only the marker centres moved (x, y), the joints stayed nominal.
    let (right, left) = corrections(&f);
    assert_eq!(right.tip.z, 0.0);
    assert!(right.tip.xy().norm() > 0.5e-3 && left.tip.xy().norm() > 0.5e-3);
    let mut joints_only = right.clone();
    joints_only.tip = nalgebra::Vector3::zeros();
    assert_eq!(joints_only, KinematicErrors::zero(6));
}

/// `--sigma-grid`: the CV candidates are every set at every σ of the given grid (not the
/// default's), in the table's order (set, then σ), and the choice carries that grid.
#[test]
fn cv_candidates_are_the_sets_times_the_given_sigma_grid() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let self_recs = self_contact(&recs);
    let grid: study::SigmaGrid = "0.2,5".parse().unwrap();
    let noise = noise();
    let score = |test: &[&Recording], corr: (&KinematicErrors, &KinematicErrors)| {
        study::held_out_nuisance_rows(&cell, test, corr, &noise)
    };
    let sets = [ParamSet::Offsets, ParamSet::OffsetsCompliance];
    let c = cv::cross_validate(
        &cell,
        &self_recs,
        &sets,
        &grid,
        &["self_upper", "self_lower"],
        &noise,
        cv::CvRule::OneSe,
        &score,
    )
    .unwrap();
    let specs: Vec<(ParamSet, f64)> = c.table.iter().map(|r| (r.spec.set, r.spec.sigma)).collect();
    assert_eq!(
        specs,
        [
            (ParamSet::Offsets, 0.2),
            (ParamSet::Offsets, 5.0),
            (ParamSet::OffsetsCompliance, 0.2),
            (ParamSet::OffsetsCompliance, 5.0),
        ]
    );
    assert_eq!(c.grid, grid);
    assert!(grid.values().contains(&c.spec.sigma));
    // One training fit per fold per candidate, each recorded with its contact distance.
    for row in &c.table {
        let folds: Vec<&str> = row.fold_fits.iter().map(|f| f.fold.as_str()).collect();
        assert_eq!(folds, ["self_upper", "self_lower"]);
        assert!(row
            .fold_fits
            .iter()
            .all(|f| f.contact_distance_m.len() == 1));
    }
}

// --- How much one split decides (`splits.rs`): the exported models over K half splits.

/// The tracker files of the split tests: the smallest (16 rows, 6435 partitions) and an odd one
/// (23 rows).
const SPLIT_TEST_FILES: [&str; 2] = ["leica_self_upper1_4x4", "leica_lower_table1_5x5"];

/// A made-up right-arm correction (+1 mrad on L, −0.5 mrad on U): a model other than nominal,
/// no fit needed.
fn made_up_correction() -> KinematicErrors {
    let mut e = KinematicErrors::zero(6);
    e.set(kinematics::ErrorParam::JointOffset { joint: 1 }, 1e-3);
    e.set(kinematics::ErrorParam::JointOffset { joint: 2 }, -0.5e-3);
    e
}

#[test]
fn split_zero_of_the_split_scores_is_the_score_tables_figure() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let trackers: Vec<&Recording> = SPLIT_TEST_FILES
        .iter()
        .map(|n| recs.iter().find(|r| r.name == *n).unwrap())
        .collect();
    let (zero, made_up) = (KinematicErrors::zero(6), made_up_correction());
    let models = [("nominal", &zero, &zero), ("made_up", &made_up, &zero)];
    let table = splits::score_splits(&cell, &models, &trackers, 3, 2).unwrap();
    for (file, rec) in table.files.iter().zip(&trackers) {
        assert_eq!(file.seeds[0], study::SPLIT_SEED, "{}", file.file);
        for (m, (name, right, left)) in models.iter().enumerate() {
            // The score table's figure: `score_models` is `summarise(score_recording(…))`.
            let s = score_recording(&cell, rec, (right, left), None).unwrap();
            let rms = summarise(&s.iter().map(|p| p.error_m).collect::<Vec<_>>()).rms_mm;
            assert_eq!(file.rms_mm[m][0], rms, "{} {name}", file.file);
        }
    }
}

#[test]
fn split_scores_are_identical_over_runs_and_thread_counts_and_differ_between_splits() {
    let Some((recs, cell)) = dataset_and_cell() else {
        return;
    };
    let trackers: Vec<&Recording> = SPLIT_TEST_FILES
        .iter()
        .map(|n| recs.iter().find(|r| r.name == *n).unwrap())
        .collect();
    let (zero, made_up) = (KinematicErrors::zero(6), made_up_correction());
    let models = [("nominal", &zero, &zero), ("made_up", &made_up, &zero)];
    let k = 4;
    let one = splits::score_splits(&cell, &models, &trackers, k, 1).unwrap();
    let again = splits::score_splits(&cell, &models, &trackers, k, 1).unwrap();
    let three = splits::score_splits(&cell, &models, &trackers, k, 3).unwrap();
    assert_eq!(one, again, "two runs");
    assert_eq!(one, three, "1 vs 3 threads");
    // Each split is another draw: every file and model has k different figures.
    for file in &one.files {
        for (m, v) in file.rms_mm.iter().enumerate() {
            assert_eq!(v.len(), k);
            let mut bits: Vec<u64> = v.iter().map(|x| x.to_bits()).collect();
            bits.sort_unstable();
            bits.dedup();
            assert_eq!(bits.len(), k, "{} model {m}: {v:?}", file.file);
        }
    }
    let s = one.summary(0, 1).unwrap();
    assert!(s.min_mm <= s.mean_mm && s.mean_mm <= s.max_mm, "{s:?}");
}

#[test]
fn split_seeds_give_distinct_partitions_and_start_at_the_score_tables_split() {
    // 16 rows have C(16, 8)/2 = 6435 partitions: 1000 free draws repeat some (so the skip is
    // needed), the 1000 seeds of `split_seeds` never do.
    let (n, k) = (16, 1000);
    let seeds = splits::split_seeds(n, k).unwrap();
    assert_eq!(seeds.len(), k);
    assert_eq!(seeds[0], study::SPLIT_SEED);
    let keys: std::collections::HashSet<Vec<usize>> =
        seeds.iter().map(|&s| splits::partition_key(n, s)).collect();
    assert_eq!(keys.len(), k, "distinct partitions");
    let free: std::collections::HashSet<Vec<usize>> = (0..k)
        .map(|j| splits::partition_key(n, splits::candidate_seed(j)))
        .collect();
    assert!(free.len() < k, "free draws repeated no partition");
    // The key names the partition whichever half holds row 0.
    let (a, b) = study::halves(n, seeds[1]);
    let key = splits::partition_key(n, seeds[1]);
    assert!(key == a || key == b);
    assert_eq!(key[0], 0);
    // 4 rows have only 3 partitions; 1 row has none.
    let e = splits::split_seeds(4, 4).unwrap_err().to_string();
    assert!(e.contains("only 3 distinct half splits"), "{e}");
    assert!(splits::split_seeds(1, 1).is_err());
}

#[test]
fn regions_hold_the_protocols_tracker_poses() {
    // docs/region-protocol.md, table "Regions": tracker poses per region.
    use ctu_motoman::region::Region;
    let Some((recs, _)) = dataset_and_cell() else {
        return;
    };
    let poses = |r: Region| -> usize {
        recs.iter()
            .filter(|x| matches!(x.role, data::Role::Tracker | data::Role::TrackerSelfContact))
            .filter(|x| Region::of(&x.name) == Some(r))
            .map(|x| x.poses.iter().filter(|p| p.p_tracker.is_some()).count())
            .sum()
    };
    assert_eq!(Region::ALL.map(poses), [212, 208, 64, 48, 46, 50]);
}
