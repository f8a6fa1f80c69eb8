//! The report crate's tests: the verdict's rule, the work-points reader, and a whole page from
//! a simulated calibration (self-contained, plots present, the same numbers as the JSON).

use std::io::Write as _;

use calib_core::whole_cell::{calibrate_cell, PairSet, ScreenOptions, SolveOptions};
use handclasp_cell::problem::{cell_problem, FitModel};
use handclasp_cell::Cell;
use kinematics::ErrorParam;
use nalgebra::Point3;
use sim_cell::{generate_session, trial_rng, Layout, SessionSpec};

use crate::work_site::{RotationFigures, RotationPredictionReport, UnreachableReport};

/// Fewest workspace poses the map needs on a shipped cell (of `WORKSPACE_POSES`, 100): the
/// whole-workspace draw keeps those robot 2 reaches head-on.
const WORKSPACE_MIN_POSES: usize = 20;
use crate::*;

/// A work-site report with the given p95 and interval (mm) and rotation p95 interval (deg).
fn work_site(p95: f64, ci: [f64; 2], rot_ci: [f64; 2]) -> WorkSiteReport {
    WorkSiteReport {
        acceptance: Acceptance::default(),
        one_robot: false,
        parts_mm: calib_core::whole_cell::PredictedErrorReport {
            data_part_rms: p95 / 4.0,
            held_out_ratio: None,
            held_out_p_value: None,
            held_out_regions: None,
            model_error_rms: 0.0,
            model_error_source: "assumed_none",
            pair_set: PairSet::WorkPoints.describe(),
            pair_set_kind: PairSet::WorkPoints,
            pairs: 1,
            predicted_p95: p95,
            predicted_rms: p95 / 2.0,
            prior_part_rms: p95 / 3.0,
            rms_bound95: p95,
        },
        placement_rotation: Some(RotationPredictionReport {
            basis: "test basis".into(),
            conditional_on: vec![],
            marginal: RotationFigures {
                p95_ci_deg: rot_ci,
                p95_deg: (rot_ci[0] + rot_ci[1]) / 2.0,
                rms_deg: rot_ci[0] / 2.0,
            },
            p95_ci_deg: rot_ci,
            p95_deg: (rot_ci[0] + rot_ci[1]) / 2.0,
            rms_deg: rot_ci[0] / 2.0,
        }),
        points: vec![],
        predicted_p95_ci_mm: ci,
        predicted_p95_mm: p95,
        predicted_rms_mm: p95 / 2.0,
        seed: 1,
        source: "test".into(),
        unreachable: vec![],
        verdict: Verdict::NoAcceptance,
        why: String::new(),
    }
}

/// PASS needs the upper end of each stated p95's interval within the threshold; a p95 below
/// the threshold whose interval reaches above it is FAIL ("not shown to be within"); an
/// unreachable work point fails a stated acceptance; nothing stated is no verdict.
#[test]
fn verdict_rule() {
    let w = work_site(1.0, [0.9, 1.2], [0.01, 0.02]);
    let v = |mm: Option<f64>, deg: Option<f64>, w: &WorkSiteReport| {
        Acceptance::new(mm, deg).unwrap().verdict(w)
    };
    assert_eq!(v(Some(1.5), None, &w).0, Verdict::Pass);
    assert_eq!(v(Some(1.5), Some(0.05), &w).0, Verdict::Pass);
    let (verdict, why) = v(Some(1.1), None, &w);
    assert_eq!(verdict, Verdict::Fail);
    assert!(why.contains("not shown to be within"), "{why}");
    let (verdict, why) = v(Some(0.5), None, &w);
    assert_eq!(verdict, Verdict::Fail);
    assert!(why.contains("exceeds the accepted 0.500 mm"), "{why}");
    assert_eq!(v(Some(1.5), Some(0.015), &w).0, Verdict::Fail);
    let (verdict, why) = v(None, None, &w);
    assert_eq!(verdict, Verdict::NoAcceptance);
    assert!(why.starts_with("no acceptance stated"), "{why}");
    let mut far = w.clone();
    far.unreachable.push(UnreachableReport {
        p_b1_mm: [5000.0, 0.0, 0.0],
        row: 3,
        why: "out of reach".into(),
    });
    let (verdict, why) = v(Some(1.5), None, &far);
    assert_eq!(verdict, Verdict::Fail);
    assert!(why.contains("(rows 3)"), "{why}");
    let mut no_rotation = w;
    no_rotation.placement_rotation = None;
    assert_eq!(v(None, Some(1.0), &no_rotation).0, Verdict::Fail);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(Acceptance::new(Some(bad), None).is_err());
        assert!(Acceptance::new(None, Some(bad)).is_err());
    }
}

/// A one-robot cell's verdict names what it predicts (robot 1's absolute accuracy in its base
/// frame, not a cooperative one), has no placement rotation (an `--accept-deg` is not met and
/// the why says to drop it), its work points are robot 1's, and its JSON says `one_robot`
/// (absent from a two-robot report).
#[test]
fn one_robot_verdict_is_worded_for_one_robot() {
    let two = work_site(1.0, [0.9, 1.2], [0.01, 0.02]);
    let mut one = two.clone();
    one.one_robot = true;
    one.placement_rotation = None;
    let text = work_site_text(&one);
    assert!(
        text.starts_with("predicted absolute accuracy of robot 1's tool (its position in robot 1's base frame) at the work site"),
        "{text}"
    );
    assert!(
        !text.contains("cooperative") && !text.contains("placement"),
        "{text}"
    );
    assert!(work_site_text(&two).starts_with("predicted cooperative accuracy"));
    let (verdict, why) = Acceptance::new(Some(1.5), Some(0.1)).unwrap().verdict(&one);
    assert_eq!(verdict, Verdict::Fail);
    assert!(
        why.contains("one-robot cell has no placement") && why.contains("drop --accept-deg"),
        "{why}"
    );
    assert_eq!(
        Acceptance::new(Some(1.5), None).unwrap().verdict(&one).0,
        Verdict::Pass
    );
    one.unreachable.push(UnreachableReport {
        p_b1_mm: [5000.0, 0.0, 0.0],
        row: 2,
        why: "out of reach".into(),
    });
    let (_, why) = Acceptance::new(Some(1.5), None).unwrap().verdict(&one);
    assert!(
        why.contains("robot 1 does not reach them head-on (rows 2)"),
        "{why}"
    );
    let json = |w: &WorkSiteReport| serde_json::to_value(w).unwrap();
    assert_eq!(json(&one)["one_robot"], serde_json::json!(true));
    assert!(json(&two).get("one_robot").is_none());
}

fn csv_file(text: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(text.as_bytes()).unwrap();
    f
}

/// The work-points file: mm in, m out; a bad row, a missing column or no row is an error that
/// names the row or says what the header is.
#[test]
fn work_points_file() {
    let f = csv_file("x_mm,y_mm,z_mm\n# a comment\n1000, -50, 900\n1100,0,1000.5\n");
    let p = read_work_points(f.path()).unwrap();
    assert_eq!(
        p,
        vec![Point3::new(1.0, -0.05, 0.9), Point3::new(1.1, 0.0, 1.0005)]
    );
    let bad = csv_file("x_mm,y_mm,z_mm\n1,2,3\n1,two,3\n");
    let e = read_work_points(bad.path()).unwrap_err().to_string();
    assert!(e.contains("data row 2"), "{e}");
    let missing = csv_file("x_mm,y_mm\n1,2\n");
    let e = read_work_points(missing.path()).unwrap_err().to_string();
    assert!(e.contains("x_mm,y_mm,z_mm"), "{e}");
    let empty = csv_file("x_mm,y_mm,z_mm\n");
    let e = read_work_points(empty.path()).unwrap_err().to_string();
    assert!(e.contains("no work point"), "{e}");
    let nan = csv_file("x_mm,y_mm,z_mm\n1,NaN,3\n");
    assert!(read_work_points(nan.path()).is_err());
}

/// What a page must not do to be self-contained: load anything (a `src`/`href` to the
/// network, a style sheet link, a CSS import or `url(...)`).
fn fetches(html: &str) -> Vec<&'static str> {
    let lower = html.to_ascii_lowercase();
    [
        "src=\"http",
        "src='http",
        "href=\"http",
        "href='http",
        "src=\"//",
        "href=\"//",
        "<link",
        "@import",
        "url(",
    ]
    .into_iter()
    .filter(|p| lower.contains(p))
    .collect()
}

/// A whole calibration page from a simulated session with one robot-2 joint offset hidden and
/// one blunder: self-contained, every plot an inline SVG, the verdict first, the rejected row
/// marked, and the embedded JSON the one given.
#[test]
fn calibration_page_is_self_contained_and_shows_the_verdict_first() {
    let cell = Cell::default_floor_wall();
    let mut truth = cell.clone();
    truth
        .robot2
        .errors
        .set(ErrorParam::JointOffset { joint: 2 }, 0.05f64.to_radians());
    let spec = SessionSpec::new(16, Layout::Random, 0.8);
    let mut session = generate_session(&truth, &spec, &mut trial_rng(21, 0)).unwrap();
    // A blunder: robot 1's reported joint 1 of row 5 off by 0.02 rad (~20 mm at the tip).
    session.points[4].q1[0] += 0.02;
    let problem = cell_problem(&cell, &session, FitModel::Kinematic);
    let cal = calibrate_cell(
        &problem,
        &SolveOptions::default(),
        &ScreenOptions::default(),
    )
    .unwrap();
    assert!(!cal.rejected.is_empty(), "the blunder was not rejected");
    let acceptance = Acceptance::new(Some(5.0), None).unwrap();
    let far = Point3::new(20.0, 0.0, 0.0);
    let w = predict_work_site(
        &cell,
        &problem,
        &cal,
        &[cell.centre_b1, far],
        "test points",
        acceptance,
        1,
    )
    .unwrap();
    assert_eq!(w.points.len(), 1);
    assert_eq!(w.unreachable.len(), 1, "20 m away is out of reach");
    assert_eq!(w.unreachable[0].row, 2);
    assert!(
        w.unreachable[0].why.starts_with("the work point at"),
        "{}",
        w.unreachable[0].why
    );
    assert_eq!(w.verdict, Verdict::Fail, "{}", w.why);
    let [lo, hi] = w.predicted_p95_ci_mm;
    assert!(
        lo <= w.predicted_p95_mm && w.predicted_p95_mm <= hi,
        "{lo} {} {hi}",
        w.predicted_p95_mm
    );
    let residuals = row_residuals(&problem, &cal).unwrap();
    assert_eq!(residuals.len(), session.len());
    let rejected: Vec<usize> = residuals
        .iter()
        .filter(|r| r.rejected)
        .map(|r| r.row)
        .collect();
    assert_eq!(
        rejected,
        cal.rejected.iter().map(|r| r.row).collect::<Vec<_>>()
    );
    let coverage = joint_coverage(&cell, &residuals);
    assert_eq!(
        coverage.len(),
        cell.robot1.model.dof() + cell.robot2.model.dof()
    );
    assert!(coverage
        .iter()
        .all(|c| (0.0..=1.0).contains(&c.fraction) && c.session.is_some()));
    // The JSON's keys stand in alphabetical order at every level (every report's key order).
    // (`to_value` sorts the keys without parsing the floats back.)
    assert_eq!(
        serde_json::to_string(&w).unwrap(),
        serde_json::to_string(&serde_json::to_value(&w).unwrap()).unwrap(),
        "keys out of order"
    );
    let map = workspace_map(&problem, &cal, 1).unwrap();
    assert_eq!(map.points_mm.len(), map.rms_mm.len());
    assert!(
        map.points_mm.len() >= WORKSPACE_MIN_POSES,
        "{}",
        map.points_mm.len()
    );
    assert_eq!(map.session_mm.len(), session.len());
    // The work site's parts and total agree: rms² = data² + prior² + model² (round-off only).
    let parts = &w.parts_mm;
    let sum = (parts.data_part_rms.powi(2)
        + parts.prior_part_rms.powi(2)
        + parts.model_error_rms.powi(2))
    .sqrt();
    assert!((sum - w.predicted_rms_mm).abs() <= 1e-9 * w.predicted_rms_mm);
    let report = cal.report(&problem);
    let json = serde_json::json!({"work_site": &w, "probe": "</script><script>alert(1)</script>"})
        .to_string();
    let invocation = Invocation {
        command_line: "handclasp calibrate --cell 'a b.toml' --report <x>.html".into(),
        version: "handclasp 0.0.0".into(),
    };
    let html = calibration_page(&CalibrationPage {
        cell: "cell.toml",
        session: "session.csv",
        model: "kinematic",
        rows: session.len(),
        report: &report,
        work_site: &w,
        meeting_pairs: None,
        residuals: &residuals,
        coverage: &coverage,
        workspace: Some(&map),
        dof: [cell.robot1.model.dof(), cell.robot2.model.dof()],
        shared_trunk: false,
        json: &json,
        invocation: &invocation,
    });
    assert_eq!(fetches(&html), Vec::<&str>::new());
    // Five plots: residual per row, against each robot's joints, coverage, the workspace map
    // (one work point: no per-point chart).
    assert_eq!(html.matches("<figure class=\"plot\"><svg").count(), 5);
    let at = html.find("id=\"workspace-map\"").unwrap();
    assert!(html[at..].contains("<svg"), "the workspace map is drawn");
    // The verdict comes before the placement, and says FAIL with its reason.
    let verdict = html.find("id=\"verdict\"").unwrap();
    assert!(verdict < html.find("id=\"placement\"").unwrap());
    assert!(html.contains("data-verdict=\"FAIL\""));
    assert!(html.contains("not predicted"));
    // Text is escaped; the JSON block cannot close its script early, and reads back the same.
    assert!(html.contains("&lt;x&gt;.html"));
    let start = html.find("id=\"report-json\">").unwrap() + "id=\"report-json\">".len();
    let end = start + html[start..].find("</script>").unwrap();
    let back: serde_json::Value = serde_json::from_str(&html[start..end]).unwrap();
    assert_eq!(
        back,
        serde_json::from_str::<serde_json::Value>(&json).unwrap()
    );
}
