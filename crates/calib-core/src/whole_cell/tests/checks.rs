//! Bad input is a named error, not a panic: the problem's checks, the evaluator's and the fit's.

use super::*;

#[test]
fn bad_input_is_a_named_error() {
    let (mut p, _) = every_kind(4);
    if let ObservationKind::Tracker { tool, .. } = &mut p.observations[3].kind {
        *tool = 7;
    }
    let e = p.check().unwrap_err().to_string();
    assert!(e.contains("row 4") && e.contains("tool"), "{e}");
    let (mut p, _) = every_kind(4);
    if let ObservationKind::Coincident { q1, .. } = &mut p.observations[0].kind {
        q1.pop();
    }
    let e = p.check().unwrap_err().to_string();
    assert!(e.contains("row 1"), "{e}");
    // A zero or NaN face normal names the row, the field and the fix.
    for bad in [Vector3::zeros(), Vector3::new(f64::NAN, 0.0, 1.0)] {
        let (mut p, _) = every_kind(4);
        let o = p
            .observations
            .iter_mut()
            .find(|o| matches!(o.kind, ObservationKind::FaceContact { .. }))
            .unwrap();
        let row = o.row;
        if let ObservationKind::FaceContact { n2_tip, .. } = &mut o.kind {
            *n2_tip = Unit::new_unchecked(bad);
        }
        let e = p.check().unwrap_err().to_string();
        assert!(
            e.contains(&format!("row {row}")) && e.contains("n2_tip") && e.contains("outward"),
            "{e}"
        );
    }
    // Two outward normals that point the same way in b1 (faces not facing each other) are an
    // error at evaluation, naming the row and the fix.
    let (mut p, est) = every_kind(4);
    let i = p
        .observations
        .iter()
        .position(|o| matches!(o.kind, ObservationKind::FaceContact { .. }))
        .unwrap();
    let rotation = |r: Robot, tool: usize, q: &[f64]| {
        let rb = p.robot(r);
        kinematics::true_base_from_tip(
            &rb.model,
            &est.robot(r).errors_for_tool(tool),
            q,
            &rb.tools[tool].flange_from_tip,
            &rb.g_base,
        )
        .unwrap()
        .rotation
    };
    let row = p.observations[i].row;
    if let ObservationKind::FaceContact {
        q1,
        q2,
        tool1,
        tool2,
        n1_tip,
        ..
    } = &p.observations[i].kind
    {
        let n1_b1 = rotation(Robot::One, *tool1, q1) * n1_tip.into_inner();
        let n2_b2 = est.b1_from_b2.rotation.inverse() * n1_b1;
        let same = Unit::new_normalize(rotation(Robot::Two, *tool2, q2).inverse() * n2_b2);
        if let ObservationKind::FaceContact { n2_tip, .. } = &mut p.observations[i].kind {
            *n2_tip = same;
        }
    }
    p.check().expect("unit normals pass the problem check");
    let layout = ParamLayout::new(&p, &[]);
    let e = Evaluator::new(&p, &layout)
        .linearise(&p.observations[i], &est, true)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!("row {row}")) && e.contains("same way") && e.contains("OUTWARD"),
        "{e}"
    );
    let (mut p, _) = every_kind(4);
    p.robot2.tolerance.tip_m = f64::NAN;
    let e = p.check().unwrap_err().to_string();
    assert!(e.contains("robot 2") && e.contains("tip_m"), "{e}");
    // A starting estimate of the wrong shape is an error, not a panic.
    let (p, mut est) = every_kind(4);
    est.planes.pop();
    let active: Vec<usize> = (0..p.observations.len()).collect();
    let e = fit_cell_with(
        &p,
        ParamLayout::new(&p, &[]),
        &active,
        Some(&est),
        &SolveOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("plane"), "{e}");
}
