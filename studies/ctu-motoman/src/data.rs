//! The CTU dual-arm Motoman dataset (`../shared/data/ctu-motoman/`, read in place): one CSV per
//! recording, one row per pose, joints in rad, tracker positions in m (see the dataset's README).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use nalgebra::{Point3, Unit, Vector3};

/// Joint columns of the right arm (S, L, U, R, B, T), in chain order.
const RIGHT: [&str; 6] = [
    "r_s_rad", "r_l_rad", "r_u_rad", "r_r_rad", "r_b_rad", "r_t_rad",
];
/// Joint columns of the left arm.
const LEFT: [&str; 6] = [
    "l_s_rad", "l_l_rad", "l_u_rad", "l_r_rad", "l_b_rad", "l_t_rad",
];
/// Tracker position columns.
const LEICA: [&str; 3] = ["leica_x_m", "leica_y_m", "leica_z_m"];

/// One pose of a recording.
#[derive(Debug, Clone)]
pub struct Pose {
    /// Right arm joints S..T, rad.
    pub q_right: Vec<f64>,
    /// Left arm joints S..T, rad.
    pub q_left: Vec<f64>,
    /// Tracker reflector position, m, tracker frame (`None`: the tracker logged nothing).
    pub p_tracker: Option<Point3<f64>>,
    /// The touching faces of a self-contact pose (`--contact-model face`, set by
    /// `contact::assign_face_normals`): `Some` builds the pose's contact row as a
    /// `FaceContact` (distance along the faces' mean normal); `None` (as read) as a `Contact`
    /// (centre distance). Ignored by the other roles.
    pub faces: Option<FaceNormals>,
}

/// The touching ring faces of one self-contact pose: each marker's outward unit face normal in
/// its own tip frame. The marker's tip frame is tool0 translated to the marker centre (a tool's
/// `flange_from_tip` is a translation), so these are tool0 axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceNormals {
    /// Ring face of the right marker (0..5) and its outward normal, right tip frame.
    pub right: (usize, Unit<Vector3<f64>>),
    /// Ring face of the left marker (0..5) and its outward normal, left tip frame.
    pub left: (usize, Unit<Vector3<f64>>),
}

/// What a recording is, and how the study uses it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// The two end effectors touch (no tracker); `pattern` = `upper` or `lower`.
    SelfContact,
    /// An end effector touches a plane (no tracker).
    Plane,
    /// The tracker measures one arm's reflector (grids and plane-contact files with the tracker).
    Tracker,
    /// Self-contact with the tracker on the right arm's reflector (`leica_self_*`).
    TrackerSelfContact,
}

/// One recording.
#[derive(Debug, Clone)]
pub struct Recording {
    /// Base name (the CSV's name without `_dataset.csv`).
    pub name: String,
    /// How it is used.
    pub role: Role,
    /// Which pattern it repeats (recordings `…1` and `…2` are two runs of one pattern): `upper`,
    /// `self_upper`, `self_lower`, `wall`, `higher`, `lower`, `right_grid`, `left_grid`,
    /// `leica_table` (the six tracker plane-contact files), `leica_self`
    pub pattern: &'static str,
    /// The arm that is measured or touches: `true` = right (robot 1).
    pub right_arm: bool,
    /// The poses.
    pub poses: Vec<Pose>,
}

/// Patterns of the tracker files on which the `--select tracker` choice scores the candidates of
/// `self` and `planes`: the grids and the tracker self-contact sets (the issue's "cross-validation
/// on the self-contact sets, the grids and the tracker self-contact sets"). The six table/wall
/// files (`leica_table`) are never used in such a choice: they are its evaluation.
pub const SELF_SELECTION_PATTERNS: [&str; 3] = ["right_grid", "left_grid", "leica_self"];

/// Copies of the recordings whose pattern is in [`SELF_SELECTION_PATTERNS`], with the pattern
/// `"selection"`: one CV fold that holds them all out, so that `cv::cross_validate` over the
/// self-contacts plus these trains on the self-contacts only and scores these.
pub fn self_selection_recordings(recordings: &[Recording]) -> Vec<Recording> {
    recordings
        .iter()
        .filter(|r| SELF_SELECTION_PATTERNS.contains(&r.pattern))
        .map(|r| Recording {
            pattern: "selection",
            ..r.clone()
        })
        .collect()
}

/// (base name, role, pattern, right arm?) of every recording the study reads. The
/// repeatability files (one pose repeated) carry no geometry and are not used.
pub const RECORDINGS: [(&str, Role, &str, bool); 22] = [
    (
        "no_leica_self_upper1_4x4",
        Role::SelfContact,
        "self_upper",
        true,
    ),
    (
        "no_leica_self_upper2_4x4",
        Role::SelfContact,
        "self_upper",
        true,
    ),
    (
        "no_leica_self_lower1_4x4",
        Role::SelfContact,
        "self_lower",
        true,
    ),
    (
        "no_leica_self_lower2_4x4",
        Role::SelfContact,
        "self_lower",
        true,
    ),
    ("no_leica_wall_table1_5x5", Role::Plane, "wall", true),
    ("no_leica_wall_table2_5x5", Role::Plane, "wall", true),
    ("no_leica_higher_table1_5x5", Role::Plane, "higher", true),
    ("no_leica_higher_table2_5x5", Role::Plane, "higher", true),
    ("no_leica_lower_table1_5x5", Role::Plane, "lower", true),
    ("no_leica_lower_table2_5x5", Role::Plane, "lower", true),
    ("leica_right_hand_6x6x6", Role::Tracker, "right_grid", true),
    ("leica_left_hand_6x6x6", Role::Tracker, "left_grid", false),
    (
        "leica_higher_table1_5x5",
        Role::Tracker,
        "leica_table",
        true,
    ),
    (
        "leica_higher_table2_5x5",
        Role::Tracker,
        "leica_table",
        true,
    ),
    ("leica_lower_table1_5x5", Role::Tracker, "leica_table", true),
    ("leica_lower_table2_5x5", Role::Tracker, "leica_table", true),
    ("leica_wall_table1_5x5", Role::Tracker, "leica_table", true),
    ("leica_wall_table2_5x5", Role::Tracker, "leica_table", true),
    (
        "leica_self_upper1_4x4",
        Role::TrackerSelfContact,
        "leica_self",
        true,
    ),
    (
        "leica_self_upper2_4x4",
        Role::TrackerSelfContact,
        "leica_self",
        true,
    ),
    (
        "leica_self_lower1_4x4",
        Role::TrackerSelfContact,
        "leica_self",
        true,
    ),
    (
        "leica_self_lower2_4x4",
        Role::TrackerSelfContact,
        "leica_self",
        true,
    ),
];

/// Reads one recording `DIR/<name>_dataset.csv`. Errors name the file, row and column.
pub fn read_recording(
    dir: &Path,
    name: &str,
    role: Role,
    pattern: &'static str,
    right_arm: bool,
) -> anyhow::Result<Recording> {
    let path = dir.join(format!("{name}_dataset.csv"));
    let mut rdr = csv::Reader::from_path(&path).with_context(|| {
        format!(
            "cannot open {}: is --data the folder ctu-motoman of the dataset (its README.md \
             lists {name}_dataset.csv)?",
            path.display()
        )
    })?;
    let headers = rdr.headers()?.clone();
    let col = |c: &str| {
        headers
            .iter()
            .position(|h| h == c)
            .with_context(|| format!("{}: no column `{c}`", path.display()))
    };
    col("pose")?; // present in every file of the dataset: a check that this is one
    let right: Vec<usize> = RIGHT.iter().map(|c| col(c)).collect::<Result<_, _>>()?;
    let left: Vec<usize> = LEFT.iter().map(|c| col(c)).collect::<Result<_, _>>()?;
    let leica: Vec<usize> = LEICA.iter().map(|c| col(c)).collect::<Result<_, _>>()?;
    let mut poses = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let row = i + 2;
        let rec = rec.with_context(|| format!("{} row {row}", path.display()))?;
        let num = |c: usize| -> anyhow::Result<Option<f64>> {
            let s = rec.get(c).unwrap_or("").trim();
            if s.is_empty() {
                return Ok(None);
            }
            let v: f64 = s.parse().with_context(|| {
                format!(
                    "{} row {row} column `{}`: `{s}` is not a number",
                    path.display(),
                    &headers[c]
                )
            })?;
            Ok(Some(v))
        };
        let req = |c: usize| -> anyhow::Result<f64> {
            num(c)?.with_context(|| {
                format!(
                    "{} row {row} column `{}` is empty",
                    path.display(),
                    &headers[c]
                )
            })
        };
        let q_right = right.iter().map(|&c| req(c)).collect::<Result<_, _>>()?;
        let q_left = left.iter().map(|&c| req(c)).collect::<Result<_, _>>()?;
        let xyz: Vec<Option<f64>> = leica.iter().map(|&c| num(c)).collect::<Result<_, _>>()?;
        let p_tracker = match (xyz[0], xyz[1], xyz[2]) {
            (Some(x), Some(y), Some(z)) => Some(Point3::new(x, y, z)),
            _ => None,
        };
        poses.push(Pose {
            q_right,
            q_left,
            p_tracker,
            faces: None,
        });
    }
    if poses.is_empty() {
        bail!("{} has no poses", path.display());
    }
    Ok(Recording {
        name: name.to_string(),
        role,
        pattern,
        right_arm,
        poses,
    })
}

/// Reads every recording of [`RECORDINGS`] from `dir`.
pub fn read_dataset(dir: &Path) -> anyhow::Result<Vec<Recording>> {
    if !dir.join("README.md").is_file() {
        bail!(
            "--data {}: not the ctu-motoman dataset folder (no README.md there); give the folder \
             that holds leica_right_hand_6x6x6_dataset.csv, e.g. ../shared/data/ctu-motoman",
            dir.display()
        );
    }
    RECORDINGS
        .iter()
        .map(|&(name, role, pattern, right)| read_recording(dir, name, role, pattern, right))
        .collect()
}

/// The dataset folder: the first of `$CTU_MOTOMAN_DATA`, `../shared/data/ctu-motoman` and
/// `../../shared/data/ctu-motoman` from the repository root (`repo`) that holds the dataset's
/// `README.md` (the same rule as the end-to-end tests' `ctu_data_or_skip`); `None` if none does.
/// A `$CTU_MOTOMAN_DATA` that points elsewhere is named on stderr and passed over, so the data
/// tests skip (or find the shared copy) instead of failing on a missing file.
pub fn locate_dataset(repo: &Path) -> Option<PathBuf> {
    let from_env = std::env::var_os("CTU_MOTOMAN_DATA").map(PathBuf::from);
    if let Some(p) = &from_env {
        if !p.join("README.md").is_file() {
            eprintln!(
                "CTU_MOTOMAN_DATA={}: no README.md there, not the ctu-motoman dataset; ignored",
                p.display()
            );
        }
    }
    from_env
        .into_iter()
        .chain(
            [
                "../shared/data/ctu-motoman",
                "../../shared/data/ctu-motoman",
            ]
            .iter()
            .map(|rel| repo.join(rel)),
        )
        .find(|p| p.join("README.md").is_file())
}
