//! Shared by the fuzz targets (`fuzz_targets/*.rs`, each a binary of this package that imports
//! it as `handclasp_fuzz`): the repository's shipped robots and cells, loaded once per process,
//! and the invariants the targets assert.

use calib_core::nalgebra;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use handclasp_cell::Cell;
use kinematics::RobotModel;
use nalgebra::Isometry3;

/// The repository root (the fuzz crate sits in `<root>/fuzz`).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The shipped URDFs (`robots/*.urdf`), in a fixed order.
pub const ROBOT_FILES: [&str; 4] = [
    "hp20.urdf",
    "va1400.urdf",
    "motoman_right_arm.urdf",
    "motoman_left_arm.urdf",
];

/// The shipped cells (`cells/*.toml`), in a fixed order.
pub const CELL_FILES: [&str; 4] = [
    "floor-wall.toml",
    "floor-floor.toml",
    "floor-ceiling.toml",
    "ctu-motoman.toml",
];

/// `(URDF text, model with tool link tool0)` of every shipped robot.
pub fn robots() -> &'static [(String, RobotModel)] {
    static ROBOTS: OnceLock<Vec<(String, RobotModel)>> = OnceLock::new();
    ROBOTS.get_or_init(|| load_urdfs("robots", &ROBOT_FILES))
}

/// Test fixtures of the kinematics crate (`crates/kinematics/tests/fixtures/`) with what the
/// shipped robots lack: a prismatic track under an arm, prismatic joints on oblique axes and in
/// the middle of a chain, `<mimic>` couplings.
pub const FIXTURE_FILES: [&str; 3] = ["rail_6r.urdf", "mixed_chain.urdf", "mimic_torso.urdf"];

/// `(URDF text, model with tool link tool0)` of every [`FIXTURE_FILES`] entry.
pub fn fixture_robots() -> &'static [(String, RobotModel)] {
    static ROBOTS: OnceLock<Vec<(String, RobotModel)>> = OnceLock::new();
    ROBOTS.get_or_init(|| load_urdfs("crates/kinematics/tests/fixtures", &FIXTURE_FILES))
}

/// `(text, model with tool link tool0)` of each of `files` in the repository folder `dir`.
fn load_urdfs(dir: &str, files: &[&str]) -> Vec<(String, RobotModel)> {
    files
        .iter()
        .map(|f| {
            let path = repo_root().join(dir).join(f);
            let text = std::fs::read_to_string(&path).expect("URDF readable");
            let model = RobotModel::from_urdf_str(&text, "tool0").expect("URDF loads");
            (text, model)
        })
        .collect()
}

/// Every shipped cell.
pub fn cells() -> &'static [Cell] {
    static CELLS: OnceLock<Vec<Cell>> = OnceLock::new();
    CELLS.get_or_init(|| {
        CELL_FILES
            .iter()
            .map(|f| {
                Cell::from_toml_file(&repo_root().join("cells").join(f))
                    .expect("shipped cell loads")
            })
            .collect()
    })
}

/// Panics unless `b1_from_b2` is finite and its rotation proper (orthonormal, det +1) to 1e-9:
/// the promise of every registration method's Ok result.
pub fn assert_finite_proper(b1_from_b2: &Isometry3<f64>, what: &str) {
    let t = b1_from_b2.translation.vector;
    assert!(
        t.iter().all(|v| v.is_finite()),
        "{what}: translation {t:?} not finite"
    );
    let q = b1_from_b2.rotation.quaternion();
    assert!(
        q.coords.iter().all(|v| v.is_finite()),
        "{what}: rotation {q:?} not finite"
    );
    let r = b1_from_b2.rotation.to_rotation_matrix().into_inner();
    let ortho = (r.transpose() * r - nalgebra::Matrix3::identity())
        .abs()
        .max();
    assert!(ortho < 1e-9, "{what}: RᵀR − I = {ortho:e}");
    let det = r.determinant();
    assert!((det - 1.0).abs() < 1e-9, "{what}: det R = {det}");
}
