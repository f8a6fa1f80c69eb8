//! `handclasp validate`'s scores, shared by the CLI and the Python package
//! (`handclasp.validate`): a calibrated cell scored on a session it was not fitted to, beside
//! the nominal cell.
//!
//! 1. The session is read with the nominal cell when given, else or if its models disagree with
//!    the tip columns with the calibrated cell ([`read_session`]: a session's tip columns are
//!    what the controllers reported, the FK of the models they ran).
//! 2. For each cell, the problem of the session ([`cell_problem`], placement model: nothing of
//!    the cell is fitted) and the cell as an estimate: the calibrated cell's placement, URDFs,
//!    tips and `[robotN.errors]` (what a URDF cannot hold, [`truth_estimate`]); the nominal
//!    cell's placement, URDFs and tips, its `[robotN.errors]` ignored (a simulated cell's are
//!    its hidden truth).
//! 3. The session's nuisances (tracker frames, planes, fitted contact distances) per
//!    [`NuisanceSource`]: `split` fits each group's on alternate rows and scores the others
//!    ([`held_out_residuals`]); `fixed` fits them on the calibration session with the same cell
//!    held and carries them over by group name ([`carry_nuisances`]).
//! 4. Per kind, per group (coincident rows: one unit) and over all rows: rows, rms of the
//!    residual (mm: the 3-D norm of a coincident or tracker row, the distance of a contact or
//!    plane row) and the whitened rms (1 when the residuals are as large as the stated noise),
//!    for both cells, and their ratio ([`validate`]).
//!
//! [`warnings`] gives the lines the CLI prints as `warning:` (Python: `UserWarning`s): a
//! calibrated cell whose whitened rms over all rows is above the nominal cell's, and one whose
//! whitened rms over all rows is above [`NOISE_WARNING_WHITENED_RMS`].

use std::fmt::Write as _;
use std::path::Path;

use calib_core::whole_cell::{
    carry_nuisances, fit_nuisances, group_name, held_out_residuals, CellEstimate, CellFitError,
    CellProblem, GroupKind, HeldOutResidual, Kind, NuisanceMode, SolveOptions,
};
use handclasp_cell::problem::{cell_problem, truth_estimate, FitModel};
use handclasp_cell::{Cell, FormatError, Session};
use serde::Serialize;

/// A whitened rms over all rows above this is warned of: the rows are this many times as far
/// off as the cell's and session's stated σ allow. Over the tens of residuals of a session,
/// chance alone keeps the whitened rms within a few tenths of 1 (its sampling spread is about
/// `1/sqrt(2·residuals)`); 3 is far beyond that, and below the factors an understated σ or an
/// unmodelled error produces (tens, on the CTU tracker files).
pub const NOISE_WARNING_WHITENED_RMS: f64 = 3.0;

/// Where the session's nuisances come from; serialised as its name (`split`, `fixed`), the
/// CLI's `--nuisance`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Nuisance {
    /// Refitted on alternate rows of each group, scored on the others.
    Split,
    /// Fitted on the calibration session, carried over by group name.
    Fixed,
}

/// Where the session's nuisances come from, with what that needs.
#[derive(Clone, Copy, Debug)]
pub enum NuisanceSource<'a> {
    /// Each group's fitted on alternate rows and scored on the others, and back.
    Split,
    /// Fitted on `calibration` (the session the cell was calibrated on, its groups named as
    /// the scored session's) with each cell held, carried over by group name.
    Fixed {
        /// The calibration session.
        calibration: &'a Session,
    },
}

impl NuisanceSource<'_> {
    /// The mode's name as the report gives it.
    pub fn mode(&self) -> Nuisance {
        match self {
            NuisanceSource::Split => Nuisance::Split,
            NuisanceSource::Fixed { .. } => Nuisance::Fixed,
        }
    }
}

/// One cell's score of a set of rows.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Score {
    /// Largest residual, mm.
    pub max_mm: f64,
    /// `sqrt(mean ‖r‖²)` over the rows, mm (a coincident or tracker row's 3-D norm, a contact
    /// or plane row's distance).
    pub rms_mm: f64,
    /// `sqrt(χ²/residuals)` of the whitened residuals: 1 when the rows are as far off as the
    /// stated noise says.
    pub whitened_rms: f64,
}

impl Score {
    fn of<'a>(rows: impl Iterator<Item = &'a HeldOutResidual>) -> Option<Score> {
        let (mut n, mut sum2, mut max, mut chi2, mut dof) = (0usize, 0.0, 0f64, 0.0, 0usize);
        for r in rows {
            let norm = r.raw_m.norm();
            n += 1;
            sum2 += norm * norm;
            max = max.max(norm);
            chi2 += r.whitened.norm_squared();
            dof += r.whitened.len();
        }
        (n > 0).then(|| Score {
            max_mm: max * 1e3,
            rms_mm: (sum2 / n as f64).sqrt() * 1e3,
            whitened_rms: (chi2 / dof as f64).sqrt(),
        })
    }
}

/// The scores of one unit (a kind, a group, or all rows).
#[derive(Debug, Clone, Serialize)]
pub struct UnitScore {
    /// The calibrated cell's score.
    pub calibrated: Score,
    /// The group's name (`null` for a kind, or all rows).
    pub group: Option<String>,
    /// The kind name, `"coincident"` for the coincident rows' unit, `"all"` for every row.
    pub kind: String,
    /// The nominal cell's score (`null` without a nominal cell).
    pub nominal: Option<Score>,
    /// Calibrated rms / nominal rms (`null` without a nominal cell): below 1, the calibration
    /// helps.
    pub rms_ratio: Option<f64>,
    /// Rows in the unit.
    pub rows: usize,
}

/// What `handclasp validate` prints (`--json` serialises it).
#[derive(Debug, Clone, Serialize)]
pub struct ValidateReport {
    /// Over every row of the session (the rms mixes 3-D and 1-D rows; the whitened rms is the
    /// one to compare).
    pub all: UnitScore,
    /// Per observation kind, in the session CSV's kind order.
    pub by_kind: Vec<UnitScore>,
    /// Per nuisance group (in order of first appearance), then the coincident rows as one unit.
    pub by_group: Vec<UnitScore>,
    /// The calibrated cell file.
    pub calibrated_cell: String,
    /// Groups where the calibrated cell's rms is below the nominal's, of those compared.
    pub groups_improved: Option<[usize; 2]>,
    /// The nominal cell file (`null` without a nominal cell).
    pub nominal_cell: Option<String>,
    /// `split` or `fixed`.
    pub nuisance: Nuisance,
    /// The scored session file.
    pub session: String,
}

/// A cell to score, with the name the report and the errors give it (its file).
#[derive(Clone, Copy, Debug)]
pub struct NamedCell<'a> {
    /// The cell.
    pub cell: &'a Cell,
    /// Its file as the report names it.
    pub name: &'a str,
}

/// Why a cell could not be scored on the session.
#[derive(Debug, thiserror::Error)]
pub enum ScoreError {
    /// The session's problem or the nuisances' fit failed.
    #[error(transparent)]
    Fit(#[from] CellFitError),
    /// The nuisances could not be fitted on the calibration session (`fixed`).
    #[error("fitting the nuisances on the calibration session")]
    CalibrationNuisances(#[source] CellFitError),
}

/// Why [`validate`] failed: one of the cells could not be scored on the session.
#[derive(Debug, thiserror::Error)]
#[error("scoring {cell} on {session}")]
pub struct ValidateError {
    /// The cell's name.
    pub cell: String,
    /// The session's name.
    pub session: String,
    /// What failed.
    #[source]
    pub source: ScoreError,
}

/// Why [`read_session`] failed: no cell read the session.
#[derive(Debug, thiserror::Error)]
#[error(
    "reading {path} with {tried} (a session's tip columns are what the controllers reported: \
     read it with the cell whose models recorded it, {nominal_hint} for a session recorded \
     before the calibration)"
)]
pub struct ReadSessionError {
    /// The session file.
    pub path: String,
    /// The cells tried, as `"--nominal N.toml, then --cell C.toml"`.
    pub tried: String,
    /// How the caller names the nominal cell (`--nominal NOMINAL.toml` for the CLI).
    pub nominal_hint: String,
    /// The first cell's error.
    #[source]
    pub source: Box<FormatError>,
}

/// `path` read with the first of `cells` (label, cell) whose models agree with its tip
/// columns: the caller lists the nominal cell's, then the calibrated cell's.
///
/// Errors: [`ReadSessionError`] with the first cell's error when none reads it (or `cells` is
/// empty: then the error of reading it with no cell is an empty-list error naming the file).
pub fn read_session(
    path: &Path,
    cells: &[(String, &Cell)],
    nominal_hint: &str,
) -> Result<Session, ReadSessionError> {
    let mut first_error = None;
    for (_, cell) in cells {
        match Session::read_csv(path, cell) {
            Ok(s) => return Ok(s),
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    let tried: Vec<&str> = cells.iter().map(|(f, _)| f.as_str()).collect();
    Err(ReadSessionError {
        path: path.display().to_string(),
        tried: tried.join(", then "),
        nominal_hint: nominal_hint.to_string(),
        source: Box::new(first_error.unwrap_or_else(|| FormatError::Session {
            path: path.to_path_buf(),
            message: "no cell was given to read it with".to_string(),
        })),
    })
}

/// One cell's held-out residuals of the session.
fn residuals(
    cell: &Cell,
    session: &Session,
    calibrated: bool,
    nuisance: NuisanceSource<'_>,
) -> Result<(CellProblem, Vec<HeldOutResidual>), ScoreError> {
    let problem = cell_problem(cell, session, FitModel::Placement);
    problem.check()?;
    let estimate = |p: &CellProblem| {
        if calibrated {
            truth_estimate(cell, p)
        } else {
            CellEstimate::nominal(p, cell.b1_from_b2)
        }
    };
    let options = SolveOptions::default();
    let scored = match nuisance {
        NuisanceSource::Split => {
            held_out_residuals(&problem, &estimate(&problem), NuisanceMode::Split, &options)?
        }
        NuisanceSource::Fixed { calibration } => {
            let old_problem = cell_problem(cell, calibration, FitModel::Placement);
            old_problem.check()?;
            let all: Vec<usize> = (0..old_problem.observations.len()).collect();
            let fitted = fit_nuisances(&old_problem, &estimate(&old_problem), &all, &options)
                .map_err(ScoreError::CalibrationNuisances)?;
            let carried = carry_nuisances(&old_problem, &fitted, &problem, &estimate(&problem))?;
            held_out_residuals(&problem, &carried, NuisanceMode::Fixed, &options)?
        }
    };
    Ok((problem, scored))
}

/// A unit's key: a nuisance group, or the rows without one.
type UnitKey = Option<(GroupKind, usize)>;

fn unit_score(
    kind: &str,
    group: Option<String>,
    cal: &[&HeldOutResidual],
    nom: Option<&[&HeldOutResidual]>,
) -> Option<UnitScore> {
    let calibrated = Score::of(cal.iter().copied())?;
    let nominal = nom.and_then(|n| Score::of(n.iter().copied()));
    Some(UnitScore {
        calibrated,
        group,
        kind: kind.to_string(),
        rms_ratio: nominal.map(|n| calibrated.rms_mm / n.rms_mm),
        nominal,
        rows: cal.len(),
    })
}

/// Scores `calibrated` (and `nominal`, when given) on `session` (named `session_name`) with the
/// nuisances from `nuisance`: the report `handclasp validate` prints.
///
/// Errors: [`ValidateError`] naming the cell that could not be scored (the session's problem
/// is invalid for it, or a nuisance fit failed).
pub fn validate(
    calibrated: NamedCell<'_>,
    nominal: Option<NamedCell<'_>>,
    session: &Session,
    session_name: &str,
    nuisance: NuisanceSource<'_>,
) -> Result<ValidateReport, ValidateError> {
    let scoring = |name: &str, source| ValidateError {
        cell: name.to_string(),
        session: session_name.to_string(),
        source,
    };
    let (problem, cal) = residuals(calibrated.cell, session, true, nuisance)
        .map_err(|e| scoring(calibrated.name, e))?;
    let nom = match nominal {
        Some(n) => Some(
            residuals(n.cell, session, false, nuisance)
                .map_err(|e| scoring(n.name, e))?
                .1,
        ),
        None => None,
    };
    let mut r = report(&problem, &cal, nom.as_deref());
    r.calibrated_cell = calibrated.name.to_string();
    r.nominal_cell = nominal.map(|n| n.name.to_string());
    r.nuisance = nuisance.mode();
    r.session = session_name.to_string();
    Ok(r)
}

/// The report of the two cells' residuals (same rows, same order), names left empty.
fn report(
    problem: &CellProblem,
    cal: &[HeldOutResidual],
    nom: Option<&[HeldOutResidual]>,
) -> ValidateReport {
    let pick = |rs: &[HeldOutResidual], f: &dyn Fn(&HeldOutResidual) -> bool| -> Vec<usize> {
        rs.iter()
            .enumerate()
            .filter(|(_, r)| f(r))
            .map(|(i, _)| i)
            .collect()
    };
    let unit = |kind: &str, group: Option<String>, idx: &[usize]| {
        let c: Vec<&HeldOutResidual> = idx.iter().map(|&i| &cal[i]).collect();
        let n: Option<Vec<&HeldOutResidual>> = nom.map(|n| idx.iter().map(|&i| &n[i]).collect());
        unit_score(kind, group, &c, n.as_deref())
    };
    let all_idx: Vec<usize> = (0..cal.len()).collect();
    let all = unit("all", None, &all_idx).unwrap_or(UnitScore {
        calibrated: Score {
            max_mm: 0.0,
            rms_mm: 0.0,
            whitened_rms: 0.0,
        },
        group: None,
        kind: "all".into(),
        nominal: None,
        rms_ratio: None,
        rows: 0,
    });
    let by_kind = Kind::ALL
        .iter()
        .filter_map(|k| unit(k.name(), None, &pick(cal, &|r| r.kind == *k)))
        .collect();
    let mut keys: Vec<UnitKey> = Vec::new();
    for r in cal {
        if !keys.contains(&r.group) {
            keys.push(r.group);
        }
    }
    // Coincident rows (no group) last.
    keys.sort_by_key(Option::is_none);
    let by_group: Vec<UnitScore> = keys
        .iter()
        .filter_map(|key| {
            let idx = pick(cal, &|r| r.group == *key);
            match key {
                Some(k) => unit(
                    cal[idx[0]].kind.name(),
                    Some(group_name(problem, *k).to_string()),
                    &idx,
                ),
                None => unit(Kind::Coincident.name(), None, &idx),
            }
        })
        .collect();
    let groups_improved = nom.map(|_| {
        [
            by_group
                .iter()
                .filter(|u| u.rms_ratio.is_some_and(|r| r < 1.0))
                .count(),
            by_group.len(),
        ]
    });
    ValidateReport {
        all,
        by_kind,
        by_group,
        calibrated_cell: String::new(),
        groups_improved,
        nominal_cell: None,
        nuisance: Nuisance::Split,
        session: String::new(),
    }
}

/// The report's warnings, without the CLI's `warning: ` prefix: the calibrated cell fits the
/// session worse than the nominal cell (whitened rms over all rows), and its whitened rms over
/// all rows is above [`NOISE_WARNING_WHITENED_RMS`].
pub fn warnings(r: &ValidateReport) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(n) = &r.all.nominal {
        if r.all.calibrated.whitened_rms > n.whitened_rms {
            out.push(format!(
                "the calibrated cell fits this session worse than the nominal cell \
                 (whitened rms {:.3} against {:.3}): it does harm on these poses; do not use it here \
                 without recalibrating with data from this region",
                r.all.calibrated.whitened_rms, n.whitened_rms
            ));
        }
    }
    let w = r.all.calibrated.whitened_rms;
    if w > NOISE_WARNING_WHITENED_RMS {
        out.push(format!(
            "the calibrated cell's residuals on this session are {w:.1} times the stated \
             noise (whitened rms; 1 = as stated): the session's σ columns or the cell's [noise] \
             understate it, or the cell misses an error on these poses{}",
            r.all.nominal.map_or(String::new(), |n| format!(
                " (the nominal cell: {:.1} times)",
                n.whitened_rms
            ))
        ));
    }
    out
}

/// One text line of a unit.
fn unit_line(s: &mut String, label: &str, u: &UnitScore) -> std::fmt::Result {
    let c = &u.calibrated;
    write!(
        s,
        "  {label:<32} {:>5} rows  calibrated rms {:>8.3} mm (max {:>8.3}, whitened {:>6.2})",
        u.rows, c.rms_mm, c.max_mm, c.whitened_rms
    )?;
    match (&u.nominal, u.rms_ratio) {
        (Some(n), Some(ratio)) => writeln!(
            s,
            "  nominal rms {:>8.3} mm (max {:>8.3}, whitened {:>6.2})  ratio {ratio:.3}",
            n.rms_mm, n.max_mm, n.whitened_rms
        ),
        _ => writeln!(s),
    }
}

/// The text report `handclasp validate` prints without `--json`.
pub fn render_text(r: &ValidateReport) -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = write_text(&mut s, r);
    s
}

fn write_text(s: &mut String, r: &ValidateReport) -> std::fmt::Result {
    writeln!(
        s,
        "== validate {} on {} (nuisances: {})",
        r.calibrated_cell,
        r.session,
        match r.nuisance {
            Nuisance::Split => "refitted on alternate rows of each group, scored on the others",
            Nuisance::Fixed => "fitted on the calibration session, carried over by group name",
        }
    )?;
    match &r.nominal_cell {
        Some(n) => writeln!(s, "against the nominal cell {n}; ratio = calibrated rms / nominal rms (below 1: the calibration helps)")?,
        None => writeln!(s, "no nominal cell given (--nominal): the calibrated cell's scores alone")?,
    }
    writeln!(s, "by kind:")?;
    for u in &r.by_kind {
        unit_line(s, &u.kind, u)?;
    }
    writeln!(s, "by group:")?;
    for u in &r.by_group {
        let label = match &u.group {
            Some(g) => format!(
                "{} {}",
                u.kind,
                serde_json::to_string(g).unwrap_or_default()
            ),
            None => format!("{} rows", u.kind),
        };
        unit_line(s, &label, u)?;
    }
    unit_line(s, "all rows", &r.all)?;
    if let Some([better, of]) = r.groups_improved {
        writeln!(
            s,
            "the calibrated cell is better than nominal in {better} of {of} groups"
        )?;
    }
    Ok(())
}
