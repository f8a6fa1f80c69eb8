//! The report of a plan ([`super::plan_session`]), as `handclasp plan` prints it (text and
//! `--json`) and Python's `plan(...)` returns it: [`PlanReport::new`], [`render_text`].

use std::fmt::Write as _;

use calib_core::whole_cell::{DesignCriterion, DesignPredictionReport, PredictedErrorReport};
use handclasp_cell::cell::SHARED_TRUNK_PLACEMENT_SIGMA;
use handclasp_cell::Cell;
use serde::Serialize;

use super::{Plan, EVAL_POSES};

/// The design criterion as the report names it; serialised as `"a"` or `"d"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// A-optimal: smallest predicted cooperative error.
    A,
    /// D-optimal: largest information volume.
    D,
}

impl Criterion {
    /// The design's criterion.
    pub fn design(self) -> DesignCriterion {
        match self {
            Criterion::A => DesignCriterion::CooperativeA,
            Criterion::D => DesignCriterion::D,
        }
    }

    /// `a` or `d`; `None` for another name.
    pub fn from_name(name: &str) -> Option<Criterion> {
        match name {
            "a" => Some(Criterion::A),
            "d" => Some(Criterion::D),
            _ => None,
        }
    }
}

/// What the report says of how the plan was asked for (the command's options).
#[derive(Debug, Clone, Copy)]
pub struct PlanInputs<'a> {
    /// The cell file, as given.
    pub cell: &'a str,
    /// Where the plan is written (the CSV), as given.
    pub out: &'a str,
    /// Poses planned.
    pub n: usize,
    /// Candidates asked for.
    pub candidates: usize,
    /// The criterion.
    pub criterion: Criterion,
    /// The seed.
    pub seed: u64,
    /// The candidates' cube side, mm.
    pub spread_mm: f64,
    /// The candidates' cube centre in base 1, mm (`None`: the cell's `[teach]` centre).
    pub centre_mm: Option<[f64; 3]>,
}

/// What `handclasp plan` prints and Python's `plan(...).report` holds: the inputs (cell, output
/// file, options), the plan's poses and its prediction beside the random picks'. `--json`
/// serialises it; [`render_text`] reads it.
///
/// Fields in alphabetical order: the JSON key order (that of the `serde_json::Value` this
/// report was before it had types).
#[derive(Debug, Clone, Serialize)]
pub struct PlanReport {
    /// The candidates asked for, found reachable, and the points drawn to find them.
    pub candidates: CandidateCounts,
    /// `--cell`: the cell file as given.
    pub cell: String,
    /// The candidates' cube centre in b1, mm (`--centre-mm` or the cell's `[teach]` centre).
    pub centre_mm: [f64; 3],
    /// How much lower the plan's predicted cooperative rms is than the random picks' mean, %.
    pub cooperative_gain_over_random_percent: f64,
    /// `--criterion`: `a` or `d`.
    pub criterion: Criterion,
    /// What the evaluation pairs are.
    pub evaluation_pair_set: String,
    /// Number of held-out evaluation pairs.
    pub evaluation_pairs: usize,
    /// `--n`: poses planned.
    pub n: usize,
    /// `--out`: where the plan is written.
    pub out: String,
    /// The chosen poses, in the order chosen.
    pub poses: Vec<PlannedPose>,
    /// The plan's prediction and the random picks' mean.
    pub predicted: Predicted,
    /// The plan's predicted error in parts, over its held-out pairs and the whole workspace.
    pub predicted_error_mm: PlanPredictedError,
    /// Random picks compared with.
    pub random_draws: usize,
    /// `--seed`.
    pub seed: u64,
    /// A shared-trunk cell's trunk joints ([`Cell::shared_joints`]; 0 for two robots on their
    /// own bases): there `b1_from_b2` is the identity held by its prior (the arms' one base), so
    /// the predicted `e_tran`/`e_rot` are that prior's, and the text says so instead of printing
    /// them.
    pub shared_trunk_joints: usize,
    /// `--spread-mm`: the candidates' cube side, mm.
    pub spread_mm: f64,
    /// Always false: the tip is not checked for collision with its own robot's links.
    pub tip_collision_checked: bool,
}

/// Candidate counts of a plan.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateCounts {
    /// Candidates asked for.
    pub asked: usize,
    /// Points drawn to find them.
    pub drawn: usize,
    /// Candidates found reachable.
    pub reachable: usize,
}

/// The plan's prediction and the mean of the random picks'.
#[derive(Debug, Clone, Serialize)]
pub struct Predicted {
    /// The plan's.
    pub plan: DesignPredictionReport,
    /// The mean of the random picks'.
    pub random: DesignPredictionReport,
}

/// The plan's predicted error in parts ([`super::PlanParts`]), mm.
#[derive(Debug, Clone, Serialize)]
pub struct PlanPredictedError {
    /// Over the held-out pairs at the tolerances (prior scale 1, as the design assumes).
    pub held_out: PredictedErrorReport,
    /// Over the same pairs at the placement-only limit (prior scale 0.001).
    pub placement_only_limit: PredictedErrorReport,
    /// Over the whole workspace (the poses `calibrate --cell` predicts over), prior scale 1.
    pub workspace: Option<PredictedErrorReport>,
}

/// One chosen pose: joints (deg) and nominal tips (mm, each in its robot's base).
#[derive(Debug, Clone, Serialize)]
pub struct PlannedPose {
    /// Its candidate number (1-based).
    pub candidate: usize,
    /// Its point number in the plan.
    pub point: usize,
    /// Robot 1's joints, deg (mm for a prismatic joint).
    pub r1_q_deg: Vec<f64>,
    /// Robot 1's nominal tip in base 1, mm.
    pub r1_tip_mm: [f64; 3],
    /// Robot 2's joints, deg (mm for a prismatic joint).
    pub r2_q_deg: Vec<f64>,
    /// Robot 2's nominal tip in base 2, mm.
    pub r2_tip_mm: [f64; 3],
}

impl PlanReport {
    /// The report of `plan`, planned on `cell` as `inputs` asked.
    pub fn new(inputs: &PlanInputs<'_>, cell: &Cell, plan: &Plan) -> Self {
        let deg = |q: &[f64]| q.iter().map(|v| v.to_degrees()).collect::<Vec<_>>();
        let poses = plan
            .session
            .points
            .iter()
            .zip(&plan.chosen)
            .map(|(p, &c)| PlannedPose {
                candidate: c + 1,
                point: p.point,
                r1_q_deg: deg(&p.q1),
                r1_tip_mm: [p.p_b1.x * 1e3, p.p_b1.y * 1e3, p.p_b1.z * 1e3],
                r2_q_deg: deg(&p.q2),
                r2_tip_mm: [p.p_b2.x * 1e3, p.p_b2.y * 1e3, p.p_b2.z * 1e3],
            })
            .collect();
        let gain = 1.0 - plan.predicted.cooperative_rms_m / plan.random_mean.cooperative_rms_m;
        PlanReport {
            candidates: CandidateCounts {
                asked: inputs.candidates,
                drawn: plan.attempts,
                reachable: plan.candidates.len(),
            },
            cell: inputs.cell.to_string(),
            centre_mm: match inputs.centre_mm {
                Some(c) => c,
                None => {
                    let c = cell.centre_b1 * 1e3;
                    [c.x, c.y, c.z]
                }
            },
            cooperative_gain_over_random_percent: gain * 100.0,
            criterion: inputs.criterion,
            evaluation_pair_set: format!(
                "{EVAL_POSES} held-out reachable handclasp poses (q1_i, q2_i) in the same cube"
            ),
            evaluation_pairs: plan.eval_pairs.len(),
            n: inputs.n,
            out: inputs.out.to_string(),
            poses,
            predicted: Predicted {
                plan: DesignPredictionReport::from(&plan.predicted),
                random: DesignPredictionReport::from(&plan.random_mean),
            },
            predicted_error_mm: PlanPredictedError {
                held_out: PredictedErrorReport::from(&plan.parts.held_out),
                placement_only_limit: PredictedErrorReport::from(&plan.parts.placement_only_limit),
                workspace: plan
                    .parts
                    .workspace
                    .as_ref()
                    .map(PredictedErrorReport::from),
            },
            random_draws: plan.random.len(),
            seed: inputs.seed,
            shared_trunk_joints: cell.shared_joints,
            spread_mm: inputs.spread_mm,
            tip_collision_checked: false,
        }
    }
}

/// Numbers with `decimals` decimals, separated by spaces.
fn list(v: &[f64], decimals: usize) -> String {
    v.iter()
        .map(|x| format!("{x:.decimals$}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The text report (mm, degrees) `handclasp plan` prints.
pub fn render_text(r: &PlanReport) -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = write_text(&mut s, r);
    s
}

fn write_text(s: &mut String, r: &PlanReport) -> std::fmt::Result {
    let (criterion, goal) = match r.criterion {
        Criterion::A => ("a", "smallest predicted cooperative error"),
        Criterion::D => ("d", "largest information volume"),
    };
    writeln!(
        s,
        "== session plan: {} poses, criterion {criterion} ({goal}), from {} reachable candidates ({} drawn, seed {})",
        r.n, r.candidates.reachable, r.candidates.drawn, r.seed
    )?;
    writeln!(
        s,
        "{:>5} {:>9}  {:<58} {:<50} meeting point in b1, mm",
        "point", "candidate", "robot 1 joints, deg", "robot 2 joints, deg",
    )?;
    for p in &r.poses {
        writeln!(
            s,
            "{:>5} {:>9}  {:<58} {:<50} {}",
            p.point,
            p.candidate,
            list(&p.r1_q_deg, 2),
            list(&p.r2_q_deg, 2),
            list(&p.r1_tip_mm, 1)
        )?;
    }
    writeln!(
        s,
        "predicted after a whole-cell calibration (prior from the cell's tolerances, the cell's noise), \
         cooperative error over the {} held-out configuration pairs:",
        r.evaluation_pairs
    )?;
    let random = format!(
        "random (mean of {} picks of the same candidates)",
        r.random_draws
    );
    for (name, p) in [
        ("plan", &r.predicted.plan),
        (random.as_str(), &r.predicted.random),
    ] {
        if r.shared_trunk_joints > 0 {
            writeln!(
                s,
                "  {name:<50} cooperative rms {:.3} mm",
                p.cooperative_rms_mm
            )?;
        } else {
            writeln!(
                s,
                "  {name:<50} cooperative rms {:.3} mm   e_tran {:.3} mm   e_rot {:.4}°",
                p.cooperative_rms_mm, p.e_tran_mm, p.e_rot_deg
            )?;
        }
    }
    writeln!(
        s,
        "  the plan's cooperative rms is {:.0} % below the random picks' mean",
        r.cooperative_gain_over_random_percent
    )?;
    let p = &r.predicted_error_mm;
    writeln!(s, "  plan, {}", p.held_out.parts_line())?;
    if let Some(w) = &p.workspace {
        writeln!(
            s,
            "  plan over the whole workspace ({} seeded reachable handclasps: robot 1 within its joint limits, robot 2 meeting it head-on; the poses calibrate --cell predicts over): rms {:.3} mm, p95 {:.3} mm",
            w.pairs, w.predicted_rms, w.predicted_p95
        )?;
        writeln!(s, "    {}", w.parts_line())?;
    }
    let l = &p.placement_only_limit;
    writeln!(
        s,
        "  plan at the placement-only limit (prior scale 0.001: the kinematic corrections held at nominal, as calibrate --cell's evidence chooses when the robots look closer to nominal than their tolerances or the data are few or noisy): rms {:.3} mm over the held-out pairs, of which prior-asserted {:.3} mm",
        l.predicted_rms, l.prior_part_rms
    )?;
    writeln!(
        s,
        "  (calibrate --cell predicts with the same definition over its session's own meeting pairs and the whole workspace, at the prior scale its evidence chooses: near the figures at scale 1 above when it chooses 1, near the placement-only limit when it chooses 0.001)"
    )?;
    if r.shared_trunk_joints > 0 {
        writeln!(
            s,
            "  (a shared trunk of {} joints: the arms stand on one base, so b1_from_b2 is the identity held by its \
             prior ({:.0} µm, {:.0} µrad) and no e_tran/e_rot applies; the trunk's errors move both hands alike, which \
             handclasps do not see, and the cooperative error above is what the arms' relative pose keeps)",
            r.shared_trunk_joints,
            SHARED_TRUNK_PLACEMENT_SIGMA.sigma_m * 1e6,
            SHARED_TRUNK_PLACEMENT_SIGMA.sigma_rad * 1e6,
        )?;
    } else {
        writeln!(
            s,
            "  (e_tran/e_rot of b1_from_b2 carry the kinematic errors no handclasp can tell from the placement, \
             held by the prior; the cooperative error does not)"
        )?;
    }
    writeln!(
        s,
        "note: the tip is not checked for collision with its own robot's links"
    )?;
    writeln!(s, "wrote {}", r.out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prediction(rms_mm: f64) -> DesignPredictionReport {
        DesignPredictionReport {
            cooperative_rms_mm: rms_mm,
            e_rot_deg: 0.01234,
            e_tran_mm: 0.25,
            log_det_information: 12.5,
        }
    }

    fn parts(rms: f64, set: PairSet) -> PredictedErrorReport {
        PredictedErrorReport {
            data_part_rms: 0.3,
            held_out_ratio: None,
            held_out_p_value: None,
            held_out_regions: None,
            model_error_rms: 0.0,
            model_error_source: "assumed_none",
            pair_set: set.describe(),
            pair_set_kind: set,
            pairs: 200,
            predicted_p95: 2.0 * rms,
            predicted_rms: rms,
            prior_part_rms: 0.4,
            rms_bound95: 1.2 * rms,
        }
    }

    fn report() -> PlanReport {
        PlanReport {
            candidates: CandidateCounts {
                asked: 400,
                drawn: 1234,
                reachable: 400,
            },
            cell: "cells/floor-wall.toml".into(),
            centre_mm: [475.0, -50.0, 995.0],
            cooperative_gain_over_random_percent: 41.6,
            criterion: Criterion::A,
            evaluation_pair_set: "200 held-out …".into(),
            evaluation_pairs: 200,
            n: 1,
            out: "plan.csv".into(),
            poses: vec![PlannedPose {
                candidate: 17,
                point: 1,
                r1_q_deg: vec![10.0, -20.555, 0.0],
                r1_tip_mm: [475.04, -50.0, 995.0],
                r2_q_deg: vec![1.0, 2.0],
                r2_tip_mm: [0.0; 3],
            }],
            predicted: Predicted {
                plan: prediction(0.5),
                random: prediction(0.85),
            },
            predicted_error_mm: PlanPredictedError {
                held_out: parts(0.5, PairSet::HeldOutHandclasps),
                placement_only_limit: parts(1.5, PairSet::HeldOutHandclasps),
                workspace: Some(parts(0.75, PairSet::Workspace)),
            },
            random_draws: 20,
            seed: 1,
            shared_trunk_joints: 0,
            spread_mm: 1000.0,
            tip_collision_checked: false,
        }
    }

    use calib_core::whole_cell::PairSet;

    #[test]
    fn text_of_a_plan() {
        let text = render_text(&report());
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "== session plan: 1 poses, criterion a (smallest predicted cooperative error), from 400 reachable candidates (1234 drawn, seed 1)"
        );
        assert_eq!(
            lines[2],
            format!(
                "{:>5} {:>9}  {:<58} {:<50} 475.0 -50.0 995.0",
                1, 17, "10.00 -20.55 0.00", "1.00 2.00"
            )
        );
        for line in [
            "  plan                                               cooperative rms 0.500 mm   e_tran 0.250 mm   e_rot 0.0123°",
            "  random (mean of 20 picks of the same candidates)   cooperative rms 0.850 mm   e_tran 0.250 mm   e_rot 0.0123°",
            "  the plan's cooperative rms is 42 % below the random picks' mean",
            "  plan, of which: data-determined 0.300 mm, prior-asserted 0.400 mm (the tolerances of the terms the data do not determine: right only if the robots are that far off), model error none assumed; 95 % bound of the rms 0.600 mm",
            "  plan at the placement-only limit (prior scale 0.001: the kinematic corrections held at nominal, as calibrate --cell's evidence chooses when the robots look closer to nominal than their tolerances or the data are few or noisy): rms 1.500 mm over the held-out pairs, of which prior-asserted 0.400 mm",
            "wrote plan.csv",
        ] {
            assert!(lines.contains(&line), "{line:?} missing in\n{text}");
        }
        let mut d = report();
        d.criterion = Criterion::D;
        assert!(render_text(&d).contains("criterion d (largest information volume)"));
    }

    /// On a shared trunk the placement is the trunk, held at the identity: the rows print no
    /// e_tran/e_rot (they were a free placement's, 1.1 mm for one held at 1 µm) and a note says
    /// why; the JSON keeps the figures (now the held prior's) and the trunk's joint count.
    #[test]
    fn text_of_a_shared_trunk_plan_prints_no_placement_error() {
        let mut r = report();
        r.shared_trunk_joints = 4;
        let text = render_text(&r);
        assert!(!text.contains("e_tran 0.250"), "{text}");
        assert!(
            text.lines().any(|l| l
                == "  plan                                               cooperative rms 0.500 mm"),
            "{text}"
        );
        assert!(
            text.contains("a shared trunk of 4 joints") && text.contains("no e_tran/e_rot applies"),
            "{text}"
        );
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains(r#""shared_trunk_joints":4"#), "{json}");
    }

    /// The JSON's keys in the order of the `serde_json::Value` it was, the criterion as a letter.
    #[test]
    fn json_keys_in_value_order() {
        let json = serde_json::to_string(&report()).unwrap();
        let value: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(
            json,
            serde_json::to_string(&value).unwrap(),
            "keys out of order"
        );
        assert!(
            json.contains(r#""criterion":"a""#)
                && json.contains(r#""tip_collision_checked":false"#)
        );
    }
}
