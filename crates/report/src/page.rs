//! The HTML pages: one self-contained file each (inline CSS, inline SVG plots, one inline
//! script that marks the plots the browser laid out; nothing fetched), written with maud
//! (every text escaped) from the commands' typed reports.
//!
//! The calibration page: [`calibration_page`]; the diagnosis pages: [`coincident_diagnosis_page`]
//! and [`cell_diagnosis_page`]. Each ends with the command line, the version, and the command's
//! JSON report (the same typed report the page is rendered from) in a `<script
//! type="application/json" id="report-json">` block.

use calib_core::whole_cell::{CalibrationReport, DropReason};
use diagnose::{CellDiagnoseReport, DiagnoseReport};
use maud::{html, Markup, PreEscaped, DOCTYPE};

use crate::fit_data::{JointCoverage, RowResidual};
use crate::plot;
use crate::work_site::{Verdict, VerdictModel, WorkSiteReport, WorkspaceMap};
use calib_core::Robot;

/// How the page was made: the command line and the program's version.
#[derive(Debug, Clone)]
pub struct Invocation {
    /// The command line as typed (arguments joined by spaces, quoted where needed).
    pub command_line: String,
    /// `handclasp X.Y.Z`.
    pub version: String,
}

/// The predicted cooperative accuracy over the session's own meeting pairs (the `calibrate
/// --cell` text's figure), mm.
#[derive(Debug, Clone, Copy)]
pub struct MeetingPairsAccuracy {
    /// Number of meeting pairs.
    pub pairs: usize,
    /// Predicted rms, mm.
    pub rms_mm: f64,
    /// Predicted p95, mm.
    pub p95_mm: f64,
}

/// Everything the calibration page shows.
#[derive(Debug, Clone, Copy)]
pub struct CalibrationPage<'a> {
    /// The cell file, as given.
    pub cell: &'a str,
    /// The session file, as given.
    pub session: &'a str,
    /// `kinematic` or `placement`.
    pub model: &'a str,
    /// The session's rows of all kinds.
    pub rows: usize,
    /// The calibration's report (whose fields the JSON report carries).
    pub report: &'a CalibrationReport,
    /// The verdict at the work site (also in the JSON report).
    pub work_site: &'a WorkSiteReport,
    /// The prediction over the session's meeting pairs, if it has any.
    pub meeting_pairs: Option<MeetingPairsAccuracy>,
    /// Every row's residual ([`crate::row_residuals`]).
    pub residuals: &'a [RowResidual],
    /// Each joint's coverage ([`crate::joint_coverage`]).
    pub coverage: &'a [JointCoverage],
    /// The predicted error over the whole workspace, pose by pose ([`crate::workspace_map`]);
    /// `None` when it could not be predicted (the page says so).
    pub workspace: Option<&'a WorkspaceMap>,
    /// Each robot's number of joints.
    pub dof: [usize; 2],
    /// A shared-trunk cell (`[robot2] shares`): the placement is the trunk's (the identity its
    /// prior holds), so nothing is "absorbed by b1_from_b2".
    pub shared_trunk: bool,
    /// The command's JSON report, embedded as it is.
    pub json: &'a str,
    /// Command line and version.
    pub invocation: &'a Invocation,
}

/// Tables longer than this many rows start folded (`<details>`), so the plots stay near the top.
const FOLDED_ROWS: usize = 12;

/// The page's style sheet.
const CSS: &str = r#"
body { font-family: system-ui, "DejaVu Sans", sans-serif; margin: 2em auto; max-width: 980px; color: #222; line-height: 1.4; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 1.8em; }
.sub { color: #555; margin-top: 0; }
.verdict { border: 3px solid; border-radius: 8px; padding: 0.8em 1.2em; margin: 1em 0; }
.verdict .headline { font-size: 2em; font-weight: bold; letter-spacing: 0.05em; }
.verdict.pass { border-color: #2ca02c; background: #eef8ee; }
.verdict.pass .headline { color: #1e7b1e; }
.verdict.fail { border-color: #d62728; background: #fcefef; }
.verdict.fail .headline { color: #b01e1e; }
.verdict.none { border-color: #888; background: #f4f4f4; }
.verdict .why { margin-top: 0.4em; }
.verdict .rotation-basis { margin-top: 0.3em; font-size: 0.9em; }
.figures { font-size: 1.1em; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.92em; }
th, td { border-bottom: 1px solid #e3e3e3; padding: 0.25em 0.7em; text-align: left; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; }
figure svg { max-width: 100%; height: auto; }
td.detail { font-size: 0.85em; color: #555; max-width: 40em; }
details summary { cursor: pointer; color: #1f4f8f; margin: 0.3em 0; }
figcaption { color: #555; font-size: 0.9em; }
.note { color: #555; font-style: italic; }
pre.cmd { background: #f4f4f4; padding: 0.6em; white-space: pre-wrap; word-break: break-all; }
footer { margin-top: 2em; color: #555; font-size: 0.9em; }
"#;

/// Marks, once the page is laid out, how many plots the browser drew with a non-zero size
/// (`data-plots-rendered` on `<body>`, beside `data-plots` the number of plots): what the
/// headless-browser test reads back from the DOM.
const SCRIPT: &str = r#"
window.addEventListener('load', function () {
  var svgs = document.querySelectorAll('figure.plot svg');
  var drawn = 0;
  svgs.forEach(function (s) {
    var box = s.getBoundingClientRect();
    if (box.width > 0 && box.height > 0 && s.querySelector('circle, rect, path, polyline, line, text')) { drawn += 1; }
  });
  document.body.setAttribute('data-plots', String(svgs.length));
  document.body.setAttribute('data-plots-rendered', String(drawn));
});
"#;

/// A plot in a `<figure class="plot">` with its caption, or the reason it is missing.
fn figure(svg: Result<String, String>, caption: &str) -> Markup {
    match svg {
        Ok(s) => html! {
            figure class="plot" { (PreEscaped(s)) figcaption { (caption) } }
        },
        Err(e) => html! { p class="note" { "plot not drawn (" (e) "): " (caption) } },
    }
}

/// The JSON report, safe inside `<script>` (`</` written as `<\/`, which JSON reads the same).
fn json_block(json: &str) -> Markup {
    html! {
        script type="application/json" id="report-json" { (PreEscaped(json.replace("</", "<\\/"))) }
    }
}

/// The page around `body`.
fn page(title: &str, body: Markup, json: &str, invocation: &Invocation) -> String {
    html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                meta name="viewport" content="width=device-width, initial-scale=1";
                title { (title) }
                style { (PreEscaped(CSS)) }
            }
            body {
                (body)
                footer {
                    h2 { "How this page was made" }
                    p { "Command line:" }
                    pre class="cmd" id="command-line" { (invocation.command_line) }
                    p { "Version: " span id="version" { (invocation.version) } ". The numbers on this page are those of the command's JSON report (printed with --json), embedded below in a script block of type application/json." }
                }
                (json_block(json))
                script { (PreEscaped(SCRIPT)) }
            }
        }
    }
    .into_string()
}

/// `value ± sigma unit`.
fn pm(value: f64, sigma: f64, unit: &str, decimals: usize) -> String {
    format!("{value:.decimals$} ± {sigma:.decimals$} {unit}")
}

/// The verdict box of a work-site report.
fn verdict_box(w: &WorkSiteReport) -> Markup {
    let class = match w.verdict {
        Verdict::Pass => "verdict pass",
        Verdict::Fail => "verdict fail",
        Verdict::NoAcceptance => "verdict none",
    };
    let [lo, hi] = w.predicted_p95_ci_mm;
    html! {
        section class=(class) id="verdict" data-verdict=(w.verdict.headline()) {
            div class="headline" { (w.verdict.headline()) }
            div class="figures" {
                "Predicted " (w.accuracy_name()) " at the work site (" (w.source) "): "
                strong { "rms " (format!("{:.3}", w.predicted_rms_mm)) " mm" } ", "
                strong { "p95 " (format!("{:.3}", w.predicted_p95_mm)) " mm" }
                " (95 % interval " (format!("{lo:.3}–{hi:.3}")) " mm)"
                @if let Some(r) = &w.placement_rotation {
                    "; placement rotation error rms " (format!("{:.4}", r.rms_deg)) "°, p95 " (format!("{:.4}", r.p95_deg)) "° (95 % interval " (format!("{:.4}–{:.4}", r.p95_ci_deg[0], r.p95_ci_deg[1])) "°)"
                }
                "."
            }
            @if let Some(r) = &w.placement_rotation {
                div class="rotation-basis" id="rotation-basis" {
                    "Placement rotation: " (r.basis)
                    @if !r.conditional_on.is_empty() {
                        ". Marginal (their prior included: the physical base frame, which the session cannot tell): rms "
                        (format!("{:.4}", r.marginal.rms_deg)) "°, p95 " (format!("{:.4}", r.marginal.p95_deg)) "°"
                    }
                    "."
                }
            }
            div class="acceptance" {
                "Accepted: "
                @match (w.acceptance.accept_mm, w.acceptance.accept_deg) {
                    (None, None) => { "no acceptance stated" }
                    (mm, deg) => {
                        @if let Some(a) = mm { "p95 position error ≤ " (format!("{a}")) " mm" }
                        @if mm.is_some() && deg.is_some() { "; " }
                        @if let Some(a) = deg { "p95 placement rotation error ≤ " (format!("{a}")) "°" }
                    }
                }
            }
            div class="why" { "Why: " (w.why) "." }
        }
    }
}

/// The bars of the predicted rms at each work point, when there are at least two.
fn work_point_plot(w: &WorkSiteReport) -> Option<Result<String, String>> {
    (w.points.len() >= 2).then(|| {
        let labels: Vec<String> = w.points.iter().map(|q| format!("row {}", q.row)).collect();
        plot::bars(
            "predicted cooperative rms at each work point",
            &labels,
            &[(
                "predicted rms",
                w.points.iter().map(|q| q.predicted_rms_mm).collect(),
            )],
            "predicted rms, mm",
        )
    })
}

/// Under the verdict box: the work points not predicted, and what the prediction is (from
/// `posterior`, in words).
fn work_site_details(w: &WorkSiteReport, posterior: &str) -> Markup {
    html! {
        @if !w.unreachable.is_empty() {
            p { "Work points not predicted (" (if w.one_robot { "robot 1 does not reach them head-on" } else { "both robots do not reach them head-on" }) "):" }
            ul { @for u in &w.unreachable { li { "row " (u.row) " (" (format!("{:.1}, {:.1}, {:.1}", u.p_b1_mm[0], u.p_b1_mm[1], u.p_b1_mm[2])) " mm): " (u.why) } } }
        }
        p class="note" {
            @if w.one_robot {
                "The prediction is the posterior error of robot 1's tool position in its base frame (its absolute accuracy: where the measuring device's registration puts the tool) with the tool head-on at each work point, "
            } @else {
                "The prediction is the posterior error of the vector from tip 2 to tip 1 (base 1) where both tips meet head-on at each work point, "
            }
            "from " (posterior) "; the p95 and its interval come from a seeded draw (seed " (w.seed) "). "
            @if !w.one_robot {
                "The rotation figure is the placement's (b1_from_b2), not the tools' orientation at the work site. "
            }
            "At the work points, " (w.parts_mm.parts_line()) "."
        }
    }
}

/// The readable reason a parameter was not identified (the words of `calibrate --cell`'s text):
/// `one_robot` for a cell without a robot 2, where what absorbs a base-like parameter is the
/// robot's base frame (the tracker/plane unknowns), not a placement `b1_from_b2`;
/// `shared_trunk` for a cell whose arms share a trunk, where the placement is the trunk's and
/// held, so such a parameter moves robot 2's tips as a placement would and is not seen.
fn drop_reason(reason: DropReason, one_robot: bool, shared_trunk: bool) -> &'static str {
    match reason {
        DropReason::Merged => "merged into others",
        DropReason::ConfoundedWithPlacement if one_robot => {
            "absorbed by the robot's base frame (the tracker/plane unknowns)"
        }
        DropReason::ConfoundedWithPlacement if shared_trunk => {
            "moves robot 2's tips as b1_from_b2 would, which the shared trunk holds"
        }
        DropReason::ConfoundedWithPlacement => "absorbed by b1_from_b2",
        DropReason::NoEffect => "moves no observed tip",
        DropReason::MovesBothHandsAlike => "the shared trunk's: moves both hands alike",
        DropReason::PriorDecided => "barely seen: the prior decides it",
        _ => "confounded",
    }
}

/// The calibration page (`calibrate --cell … --report FILE.html`): the verdict at the work site
/// first, then the placement, the parameters, what was not identifiable, the plots and the
/// solver's state.
pub fn calibration_page(p: &CalibrationPage) -> String {
    let r = p.report;
    let w = p.work_site;
    let b = &r.b1_from_b2;
    let work_point_plot = work_point_plot(w);
    let body = html! {
        h1 { "handclasp calibration report" }
        p class="sub" { "Cell " code { (p.cell) } ", session " code { (p.session) } " (" (p.rows) " rows), model " (p.model) "." }
        (verdict_box(w))
        (work_site_details(w, "every unknown's posterior (the prior-regularised ones and those not identifiable included)"))
        h2 { "Placement b1_from_b2 (robot 2's base in robot 1's base)" }
        table id="placement" {
            tr { th { "x" } th { "y" } th { "z" } th { "φ" } th { "θ" } th { "ψ" } }
            tr {
                @for v in b.xyz_mm { td class="num" { (format!("{v:.3} mm")) } }
                @for v in b.zyz_deg { td class="num" { (format!("{v:.4}°")) } }
            }
        }
        p class="note" { "ZYZ angles, R = Rz(φ)·Ry(θ)·Rz(ψ)." }
        table id="placement-sigma" {
            tr { th { "axis" } th class="num" { "posterior σ" } th class="num" { "prior σ" } }
            @for s in &b.sigma {
                tr {
                    td { (s.name.trim_start_matches("b1_from_b2 ")) }
                    td class="num" { (format!("{:.4} {}", s.sigma, s.unit.name())) }
                    td class="num" { @match s.prior_sigma { Some(v) => (format!("{v:.4} {}", s.unit.name())), None => "free" } }
                }
            }
        }
        h2 { "Identified parameters (" (r.parameters.len()) ")" }
        @if r.parameters.is_empty() {
            p { "None fitted: both robots held at their nominal models." }
        } @else {
            details open[r.parameters.len() <= FOLDED_ROWS] {
            summary { (r.parameters.len()) " parameters: value ± posterior σ, prior σ" }
            table id="parameters" {
                tr { th { "parameter" } th class="num" { "value ± posterior σ" } th class="num" { "prior σ" } th class="num" { "size, prior σ" } }
                @for q in &r.parameters {
                    tr {
                        td { (q.name) }
                        td class="num" { (pm(q.value, q.sigma, q.unit.name(), 4)) }
                        td class="num" { (format!("{:.4} {}", q.prior_sigma, q.unit.name())) }
                        td class="num" { (format!("{:.1}", (q.value / q.prior_sigma).abs())) }
                    }
                }
            }
            }
            p class="note" { (r.data_determined_directions) " directions determined by the data, " (r.prior_dominated_directions) " dominated by the prior; prior scale chosen by the evidence: " (r.prior_scale.chosen) "." }
        }
        h2 { "Not identifiable from this session (" (r.unidentifiable.len()) ")" }
        @if r.unidentifiable.is_empty() {
            p { "Every fitted parameter is identifiable." }
        } @else {
            p class="note" { "Held at nominal; their prior is kept in the prediction." }
            details open[r.unidentifiable.len() <= FOLDED_ROWS] {
                summary { (r.unidentifiable.len()) " parameters and why" }
                table id="unidentifiable" {
                    tr { th { "parameter" } th { "reason" } th { "detail" } }
                    @for d in &r.unidentifiable { tr { td { (d.name) } td { (drop_reason(d.reason, w.one_robot, p.shared_trunk)) } td class="detail" { (d.why) } } }
                }
            }
        }
        h2 { "Rows rejected as blunders (" (r.rejected_points.len()) ")" }
        @if r.rejected_points.is_empty() {
            p { "None: no row's studentised residual is above the Bonferroni limit." }
        } @else {
            table id="rejected" {
                tr { th class="num" { "row" } th class="num" { "size, σ" } th class="num" { "residual" } }
                @for x in &r.rejected_points { tr { td class="num" { (x.row) } td class="num" { (format!("{:.1}", x.size_sigma)) } td class="num" { (format!("{:.3} mm", x.residual_mm)) } } }
            }
            p class="note" { "Re-record these rows." }
        }
        h2 { "Plots" }
        (figure(plot::residual_per_row(p.residuals), "Residual of each session row against the final fit (norm, mm); red crosses: rows rejected as blunders."))
        @for (robot, dof) in [(Robot::One, p.dof[0]), (Robot::Two, p.dof[1])] {
            (figure(plot::residual_against_joints(p.residuals, robot, dof), &format!("Residual (mm) against each of robot {}'s joints (deg): a trend along a joint is an error the model does not carry.", robot.number())))
        }
        (figure(plot::coverage(p.coverage), "Each joint's travel between its limits (grey) and the range this session covered (green), with the covered fraction: away from the green the calibration extrapolates."))
        @if let Some(svg) = work_point_plot {
            (figure(svg, "Predicted cooperative rms at each work point, mm."))
        }
        @match p.workspace {
            Some(m) => {
                div id="workspace-map" {
                    (figure(plot::workspace_map(&m.points_mm, &m.rms_mm, &m.session_mm), &format!(
                        "Predicted cooperative rms over the whole workspace: {} seeded reachable handclasps (robot 1 within its joint limits, robot 2 meeting it head-on), each at its meeting point in base 1, coloured by its predicted rms; black crosses: this session's meeting points. Over all of them: rms {:.3} mm, p95 {:.3} mm; {}.",
                        m.report.pairs, m.report.predicted_rms, m.report.predicted_p95, m.report.parts_line())))
                }
            }
            None => p class="note" id="workspace-map" { "Predicted error over the workspace: not shown (no workspace pose both robots reach head-on was found)." },
        }
        h2 { "Solver" }
        ul {
            li { "Stopped: " (r.stopped.name()) " after " (r.iterations) " iterations; data χ² " (format!("{:.1}", r.data_chi2)) " over " (r.residual_rows) " residual rows; " (r.rows_used) " of " (p.rows) " rows used." }
            li { "Blunder-screen noise scale " (format!("{:.3}", r.noise_scale)) "." }
            @if let Some(m) = p.meeting_pairs {
                li { "Predicted cooperative accuracy over the session's own " (m.pairs) " meeting pairs: rms " (format!("{:.3}", m.rms_mm)) " mm, p95 " (format!("{:.3}", m.p95_mm)) " mm." }
            }
        }
    };
    page("handclasp calibration report", body, p.json, p.invocation)
}

/// The summary box of a diagnosis. Without a verdict at the work site (`with_verdict` false:
/// the coincident diagnosis) it is the page's headline box (`id="verdict"`) and says where a
/// verdict comes from; with one, it follows the verdict (`id="diagnosis"`).
fn diagnosis_box(named: usize, before: f64, after: f64, what: &str, with_verdict: bool) -> Markup {
    let (class, headline) = if named == 0 {
        ("verdict none", "NO CAUSE NAMED".to_string())
    } else {
        (
            "verdict pass",
            format!("{named} CAUSE{} NAMED", if named == 1 { "" } else { "S" }),
        )
    };
    let figures = html! {
        div class="headline" { (headline) }
        div class="figures" { (what) ": " strong { (format!("{before:.3} mm before → {after:.3} mm after")) } "." }
    };
    if with_verdict {
        html! {
            section class=(class) id="diagnosis" data-diagnosis=(headline) {
                (figures)
                div class="why" { "What the nominal models get wrong, named by the held-out fit; the verdict above is for the model the export writes." }
            }
        }
    } else {
        html! {
            section class=(class) id="verdict" data-verdict=(headline) {
                (figures)
                div class="why" { "A diagnosis of coincident handclasps names what the nominal models get wrong; for PASS or FAIL at a work site, run calibrate --cell … --report with --accept-mm (or diagnose a session with contact, tracker or plane rows)." }
            }
        }
    }
}

/// The page of `diagnose` on a session of coincident handclasps.
pub fn coincident_diagnosis_page(
    r: &DiagnoseReport,
    cell: &str,
    session: &str,
    json: &str,
    invocation: &Invocation,
) -> String {
    let body = html! {
        h1 { "handclasp diagnosis report" }
        p class="sub" { "Cell " code { (cell) } ", session " code { (session) } " (" (r.n_points) " points)." }
        (diagnosis_box(r.effects.len(), r.heldout_rms_before_mm, r.heldout_rms_after_mm, "held-out rms (cross-validated)", false))
        h2 { "Named causes (" (r.effects.len()) ")" }
        @if r.effects.is_empty() {
            p { "None: the residuals are explained by the stated noise." }
        } @else {
            table id="causes" {
                tr { th { "cause" } th { "robot" } th { "joint / axis" } th class="num" { "value" } th class="num" { "95 % interval" } th class="num" { "p" } }
                @for e in &r.effects {
                    tr {
                        td { (e.kind.name()) }
                        td { (e.robot.number()) }
                        td { (e.joint.map(|j| j.to_string()).unwrap_or_default()) " " (e.axis.unwrap_or("")) }
                        td class="num" { (format!("{:.4} {}", e.value, e.unit)) }
                        td class="num" { (format!("{:.4} – {:.4}", e.ci95[0], e.ci95[1])) }
                        td class="num" { (format!("{:.2e}", e.p_value)) }
                    }
                }
            }
        }
        h2 { "Before and after" }
        (figure(plot::bars("rms before and after the named causes", &["fit".to_string(), "held-out".to_string()],
            &[("before", vec![r.rms_before_mm, r.heldout_rms_before_mm]), ("after", vec![r.rms_after_mm, r.heldout_rms_after_mm])], "rms, mm"),
            "Residual rms over the session (fit) and cross-validated (held-out), before and after the named causes, mm."))
        table id="placement" {
            tr { th { "b1_from_b2" } th class="num" { "x, y, z (mm)" } th class="num" { "φ, θ, ψ (ZYZ, deg)" } }
            @for (name, pose) in [("before (placement only)", &r.b1_from_b2_before), ("after (with the causes)", &r.b1_from_b2)] {
                tr { td { (name) } td class="num" { (format!("{:.3}, {:.3}, {:.3}", pose.xyz_mm[0], pose.xyz_mm[1], pose.xyz_mm[2])) } td class="num" { (format!("{:.4}, {:.4}, {:.4}", pose.zyz_deg[0], pose.zyz_deg[1], pose.zyz_deg[2])) } }
            }
        }
        h2 { "Families examined" }
        table id="families" {
            tr { th { "robot" } th { "family" } th class="num" { "size" } th class="num" { "rank" } th { "confounded with the base frames" } th { "no effect" } }
            @for f in &r.families { tr { td { (f.robot.number()) } td { (f.kind.name()) } td class="num" { (f.size) } td class="num" { (f.rank) } td { (f.confounded_with_base.join(", ")) } td { (f.no_effect.join(", ")) } } }
        }
        h2 { "Rows rejected as blunders (" (r.rejected_points.len()) ")" }
        @if !r.rejected_points.is_empty() {
            table id="rejected" {
                tr { th class="num" { "point" } th class="num" { "size, σ" } th class="num" { "residual" } }
                @for x in &r.rejected_points { tr { td class="num" { (x.point) } td class="num" { (format!("{:.1}", x.size_sigma)) } td class="num" { (format!("{:.3} mm", x.residual_mm)) } } }
            }
        }
    };
    page("handclasp diagnosis report", body, json, invocation)
}

/// The page of `diagnose` on a session with contact, tracker or plane rows (the whole-cell
/// diagnosis): the verdict at the work site first (`work_site`, with the model it is for:
/// [`crate::diagnosis_work_site`]), then the causes with their held-out gain, before/after by
/// kind, the rejected families.
pub fn cell_diagnosis_page(
    r: &CellDiagnoseReport,
    work_site: Option<(&WorkSiteReport, &VerdictModel)>,
    cell: &str,
    session: &str,
    json: &str,
    invocation: &Invocation,
) -> String {
    let held = |v: &[diagnose::cell_report::KindResidual]| -> Vec<(String, f64)> {
        v.iter()
            .filter_map(|k| k.held_out_rms_mm.map(|h| (k.kind.to_string(), h)))
            .collect()
    };
    let before = held(&r.baseline);
    let after = held(&r.final_residuals);
    let rms = |v: &[(String, f64)]| {
        if v.is_empty() {
            f64::NAN
        } else {
            (v.iter().map(|x| x.1 * x.1).sum::<f64>() / v.len() as f64).sqrt()
        }
    };
    let labels: Vec<String> = before.iter().map(|b| b.0.clone()).collect();
    let after_by_label: Vec<f64> = labels
        .iter()
        .map(|l| after.iter().find(|a| &a.0 == l).map_or(f64::NAN, |a| a.1))
        .collect();
    let body = html! {
        h1 { "handclasp diagnosis report (whole cell)" }
        p class="sub" { "Cell " code { (cell) } ", session " code { (session) } " (" (r.rows_used) " rows used)." }
        @if let Some((w, model)) = work_site {
            (verdict_box(w))
            p class="note" id="verdict-model" data-model=(model.model) { "The verdict is for " (model.description) "." }
            (work_site_details(w, "that model's posterior"))
            @if let Some(svg) = work_point_plot(w) {
                (figure(svg, "Predicted cooperative rms of the exported model at each work point, mm."))
            }
        }
        (diagnosis_box(r.effects.len(), rms(&before), rms(&after), "held-out rms over the kinds (mean square of each kind's)", work_site.is_some()))
        h2 { "Named causes (" (r.effects.len()) ")" }
        @if r.effects.is_empty() {
            p { "None: no family of errors improved the held-out fit enough." }
        } @else {
            table id="causes" {
                tr { th class="num" { "step" } th { "cause" } th class="num" { "held-out χ² before → after" } th class="num" { "gain" } th class="num" { "gain, t" } }
                @for e in &r.effects {
                    tr {
                        td class="num" { (e.step) }
                        td { (e.family.name) }
                        td class="num" { (format!("{:.1} → {:.1}", e.gain.held_out_chi2_before, e.gain.held_out_chi2_after)) }
                        td class="num" { (format!("{:.1} %", e.gain.relative_gain * 100.0)) }
                        td class="num" { (format!("{:.1}", e.gain.gain_t)) }
                    }
                }
            }
            @for e in &r.effects {
                h3 { "Step " (e.step) ": " (e.family.name) }
                table {
                    tr { th { "parameter" } th class="num" { "value ± σ" } th class="num" { "prior σ" } }
                    @for q in &e.parameters { tr { td { (q.name) } td class="num" { (pm(q.value, q.sigma, q.unit.suffix(), 4)) } td class="num" { (format!("{:.4} {}", q.prior_sigma, q.unit.suffix())) } } }
                }
                @for t in e.residual_vs_joint.iter().take(2) {
                    (figure(plot::before_after_lines(&format!("robot {} joint {}", t.robot, t.joint), &format!("q{}, deg", t.joint), "rms / σ", &t.q_deg, &t.rms_over_sigma_before, &t.rms_over_sigma_after),
                        &format!("Whitened residual rms in quartile bins of robot {}'s joint {}, before and after step {}.", t.robot, t.joint, e.step)))
                }
            }
        }
        h2 { "Before and after, held out" }
        @if labels.is_empty() {
            p class="note" { "No held-out figure by kind in this report." }
        } @else {
            (figure(plot::bars("held-out rms by observation kind", &labels, &[("before", before.iter().map(|b| b.1).collect()), ("after", after_by_label)], "held-out rms, mm"),
                "Cross-validated residual rms of each observation kind, before the diagnosis and after its named causes, mm."))
        }
        h2 { "Rejected families (" (r.rejected_families.len()) ")" }
        @if r.rejected_families.is_empty() {
            p { "None." }
        } @else {
            table id="rejected-families" {
                tr { th { "family" } th class="num" { "gain" } th { "why rejected" } }
                @for f in &r.rejected_families { tr { td { (f.family.name) } td class="num" { (format!("{:.1} %", f.gain.relative_gain * 100.0)) } td { (f.reason) } } }
            }
        }
        h2 { "Rows rejected as blunders (" (r.rejected_points.len()) ")" }
        @if !r.rejected_points.is_empty() {
            table id="rejected" {
                tr { th class="num" { "row" } th { "kind" } th class="num" { "size, σ" } th class="num" { "residual" } }
                @for x in &r.rejected_points { tr { td class="num" { (x.point) } td { (x.kind) } td class="num" { (format!("{:.1}", x.size_sigma)) } td class="num" { (format!("{:.3} mm", x.residual_mm)) } } }
            }
        }
    };
    page("handclasp diagnosis report", body, json, invocation)
}

#[cfg(test)]
mod drop_reason_tests {
    use super::*;

    /// A one-robot cell has no `b1_from_b2`: a base-like parameter is absorbed by the robot's
    /// base frame (the words of `calibrate --cell`'s text); a two-robot cell keeps the placement.
    #[test]
    fn a_one_robot_page_does_not_name_b1_from_b2() {
        let one = drop_reason(DropReason::ConfoundedWithPlacement, true, false);
        assert!(
            one.contains("robot's base frame") && !one.contains("b1_from_b2"),
            "{one}"
        );
        assert_eq!(
            drop_reason(DropReason::ConfoundedWithPlacement, false, false),
            "absorbed by b1_from_b2"
        );
    }

    /// A shared trunk holds the placement (stop 35: the page's short reason still said
    /// "absorbed by b1_from_b2" there while `calibrate --cell`'s text had been corrected).
    #[test]
    fn a_shared_trunk_page_does_not_say_absorbed_by_b1_from_b2() {
        let r = drop_reason(DropReason::ConfoundedWithPlacement, false, true);
        assert!(
            r.contains("shared trunk holds") && !r.contains("absorbed"),
            "{r}"
        );
    }
}
