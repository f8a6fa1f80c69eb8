//! The setup the end-to-end tests share: paths into the workspace, running the built `handclasp`
//! binary and reading what it printed, simulated sessions written as session CSVs, and the CTU
//! dataset folder (or a printed reason to skip). No tests live here; each test keeps its own
//! assertions and tolerances.

use std::ffi::OsStr;
use std::fmt::Debug;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use handclasp_cell::Cell;
use handclasp_cell::Session;
use serde_json::Value;
use sim_cell::{generate_session, trial_rng, Layout, SessionSpec};

/// `rel` inside the workspace root (the folder holding `cells/`, `robots/` and `tools/`).
pub fn workspace(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// The shipped cell file `cells/{name}.toml` (e.g. `"floor-floor"`, `"ctu-motoman"`).
pub fn shipped_cell(name: &str) -> PathBuf {
    workspace(&format!("cells/{name}.toml"))
}

/// A `Command` for the `handclasp` binary cargo built for these tests, for callers that pipe its
/// output or pass `OsStr` arguments; [`handclasp`] runs it to completion.
pub fn handclasp_command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_handclasp"))
}

/// Runs `handclasp` with `args` to completion and returns its status, stdout and stderr. The
/// status is not checked: see [`stdout_json`] and [`stderr_of_failure`]. Panics only when the
/// binary cannot be started.
pub fn handclasp<S: AsRef<OsStr>>(args: &[S]) -> Output {
    handclasp_command()
        .args(args)
        .output()
        .expect("runs handclasp")
}

/// The arguments `{command} --cell {cell} --session {session}` followed by `extra`, for the
/// commands that read a cell file and a session CSV (`calibrate`, `diagnose`).
pub fn cell_session_args(
    command: &str,
    cell: &Path,
    session: &Path,
    extra: &[&str],
) -> Vec<String> {
    let mut args = vec![
        command.to_string(),
        "--cell".into(),
        cell.display().to_string(),
        "--session".into(),
        session.display().to_string(),
    ];
    args.extend(extra.iter().map(|a| a.to_string()));
    args
}

/// Panics with `out`'s stderr unless the run succeeded.
pub fn assert_success(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `out`'s stdout parsed as one JSON object, after [`assert_success`].
pub fn stdout_json(out: &Output) -> Value {
    assert_success(out);
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

/// `handclasp validate --cell {cell} --session {session} --nominal {nominal} --json`: the
/// calibrated and the nominal cell's rms over every row, mm.
pub fn validate_rms_mm(cell: &Path, session: &Path, nominal: &Path) -> (f64, f64) {
    let path = |p: &Path| p.display().to_string();
    let v = stdout_json(&handclasp(&[
        "validate",
        "--cell",
        &path(cell),
        "--session",
        &path(session),
        "--nominal",
        &path(nominal),
        "--json",
    ]));
    let rms = |which: &str| v["all"][which]["rms_mm"].as_f64().unwrap();
    (rms("calibrated"), rms("nominal"))
}

/// Runs `handclasp` with `args` (which should include `--json`), requires success (else panics
/// with the arguments and stderr) and returns stdout parsed as one JSON object.
pub fn json_ok<S: AsRef<OsStr> + Debug>(args: &[S]) -> Value {
    let out = handclasp(args);
    assert!(
        out.status.success(),
        "handclasp {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

/// The JSON array `v` as numbers (e.g. `b1_from_b2.xyz_mm`); panics when `v` is not an array of
/// numbers.
pub fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// Runs `handclasp` with `args`, requires it to fail (else panics naming the arguments) and
/// returns its stderr (lossy UTF-8).
pub fn stderr_of_failure<S: AsRef<OsStr> + Debug>(args: &[S]) -> String {
    let out = handclasp(args);
    assert!(!out.status.success(), "handclasp {args:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Side of the cube (m) around the teach centre in which the random-layout sessions draw points.
pub const RANDOM_SPREAD_M: f64 = 0.8;

/// A session simulated on `truth` (robot mode: both robots' IK, nominal-model tips): `n` points
/// of `layout` within `spread_m` (m) of the teach centre, drawn from trial 0 of `seed`.
pub fn simulate(truth: &Cell, n: usize, layout: Layout, spread_m: f64, seed: u64) -> Session {
    let spec = SessionSpec::new(n, layout, spread_m);
    generate_session(truth, &spec, &mut trial_rng(seed, 0)).expect("session")
}

/// A session of `n` random-layout points ([`RANDOM_SPREAD_M`]) simulated on `truth` with `seed`.
pub fn random_session(truth: &Cell, n: usize, seed: u64) -> Session {
    simulate(truth, n, Layout::Random, RANDOM_SPREAD_M, seed)
}

/// Writes `session` to `dir/name` as a session CSV whose tips are what `reported`'s models
/// predict (what the controllers report: mm and degrees) and returns the file's path.
pub fn write_session_csv(dir: &Path, name: &str, session: &Session, reported: &Cell) -> PathBuf {
    let path = dir.join(name);
    session.write_csv(&path, reported).expect("write session");
    path
}

/// The CTU dual-arm Motoman dataset folder, the first of `$CTU_MOTOMAN_DATA`,
/// `../shared/data/ctu-motoman` beside the repository (CI's clone) and
/// `../../shared/data/ctu-motoman` (a worktree one level further down) that holds the dataset's
/// `README.md`: the same places as the `ctu-motoman` study's tests (`studies/ctu-motoman`,
/// `data::locate_dataset`). When none does, prints why the calling test is skipped (the dataset
/// is not in the repository) and returns `None`: the caller returns.
pub fn ctu_data_or_skip() -> Option<PathBuf> {
    shared_data_or_skip(
        "CTU_MOTOMAN_DATA",
        "ctu-motoman",
        "README.md",
        "the CTU dataset",
    )
}

/// A data set's folder under the shared data, the first of `$env_var`,
/// `../shared/data/{folder}` beside the repository (CI's clone) and `../../shared/data/{folder}`
/// (a worktree one level further down) that holds `marker`. When none does, prints why the
/// calling test is skipped (`what` is not in the repository) and returns `None`: the caller
/// returns.
pub fn shared_data_or_skip(
    env_var: &str,
    folder: &str,
    marker: &str,
    what: &str,
) -> Option<PathBuf> {
    let candidates: Vec<PathBuf> = std::env::var_os(env_var)
        .map(PathBuf::from)
        .into_iter()
        .chain([
            workspace(&format!("../shared/data/{folder}")),
            workspace(&format!("../../shared/data/{folder}")),
        ])
        .collect();
    let found = candidates
        .iter()
        .find(|d| d.join(marker).is_file())
        .cloned();
    if found.is_none() {
        eprintln!(
            "skipped: {what} is not in the repository and none of {candidates:?} holds it \
             (set ${env_var} to its folder)"
        );
    }
    found
}

/// `handclasp import --cell cells/ctu-motoman.toml --map tools/ctu-motoman/maps/{map} --out out`
/// with one `--input` per name of `files` inside the CTU dataset folder `data`; requires success
/// (else panics with stdout and stderr) and returns stdout.
pub fn ctu_import(data: &Path, map: &str, files: &[&str], out: &Path) -> String {
    let mut args = vec![
        "import".to_string(),
        "--cell".into(),
        shipped_cell("ctu-motoman").display().to_string(),
        "--map".into(),
        workspace("tools/ctu-motoman/maps")
            .join(map)
            .display()
            .to_string(),
        "--out".into(),
        out.display().to_string(),
    ];
    for f in files {
        args.push("--input".into());
        args.push(data.join(f).display().to_string());
    }
    let o = handclasp(&args);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    stdout
}

/// `urdf` (a URDF's text) with every `<inertial>…</inertial>` block removed: the same robot
/// with no mass, for fits that must not know the masses the simulator's truth sags under.
pub fn strip_inertials(urdf: &str) -> String {
    let mut text = urdf.to_string();
    while let Some(a) = text.find("<inertial>") {
        let b = a
            + text[a..]
                .find("</inertial>")
                .expect("an <inertial> block is closed")
            + "</inertial>".len();
        text.replace_range(a..b, "");
    }
    assert!(!text.contains("<mass"), "a <mass> outside <inertial>");
    text
}
