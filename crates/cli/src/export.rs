//! `handclasp export --cell CELL --to DIR [--format abb,kuka,fanuc,yaskawa,ros2|all] [--json]
//! [--force]`: the cell's placement `b1_from_b2` (robot 2's base frame in robot 1's base frame)
//! in each controller's and ROS 2's own convention and file, each file read back and checked
//! before the command succeeds (`handclasp_cell::export_formats`). The JSON and the text table come
//! from one typed report, [`ExportReport`].

use std::path::PathBuf;

use anyhow::Context;
use handclasp_cell::export_formats::{
    export_placement, ControllerFormat, PlacementFormats, READ_BACK_TOL_M, READ_BACK_TOL_RAD,
};
use handclasp_cell::Cell;
use serde::Serialize;

/// `--format` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatArg {
    /// ABB MultiMove: ROB_2 base frame of MOC.cfg (m, quaternion q1..q4 = w x y z).
    Abb,
    /// KUKA: $ROBROOT / BASE_DATA frame (mm, A B C deg, R = Rz(A)·Ry(B)·Rx(C)).
    Kuka,
    /// Fanuc: user frame of robot 1 (mm, W P R deg about fixed x y z).
    Fanuc,
    /// Yaskawa: user frame of robot 1 (mm, Rx Ry Rz deg about fixed x y z).
    Yaskawa,
    /// ROS 2: cell URDF, xacro properties, static_transform_publisher launch file.
    Ros2,
    /// All of the above.
    All,
}

impl FormatArg {
    fn formats(self) -> Vec<ControllerFormat> {
        match self {
            FormatArg::Abb => vec![ControllerFormat::Abb],
            FormatArg::Kuka => vec![ControllerFormat::Kuka],
            FormatArg::Fanuc => vec![ControllerFormat::Fanuc],
            FormatArg::Yaskawa => vec![ControllerFormat::Yaskawa],
            FormatArg::Ros2 => vec![ControllerFormat::Ros2],
            FormatArg::All => ControllerFormat::ALL.to_vec(),
        }
    }
}

/// Write the calibrated placement b1_from_b2 for the robot controllers and ROS 2.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The cell TOML: a shipped cell (cells/*.toml) or one written by `calibrate --cell
    /// --export` or `diagnose --export` (whose URDFs are the corrected ones).
    #[arg(long)]
    pub cell: PathBuf,
    /// Output folder (created if missing). It must be new or empty, unless --force.
    #[arg(long)]
    pub to: PathBuf,
    /// Targets, comma-separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "all")]
    pub format: Vec<FormatArg>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write into a non-empty --to folder, replacing files of the same names.
    #[arg(long)]
    pub force: bool,
}

/// One written file in the report.
#[derive(Debug, Serialize)]
pub struct FileReport {
    /// The file.
    pub path: String,
    /// Its target (`abb`, …).
    pub format: &'static str,
    /// Translation difference when read back, µm.
    pub read_back_um: f64,
    /// Rotation difference when read back, µrad.
    pub read_back_urad: f64,
}

/// What `handclasp export` did: one struct, printed as JSON (`--json`) or as a table.
#[derive(Debug, Serialize)]
pub struct ExportReport {
    /// The cell file.
    pub cell: String,
    /// The output folder.
    pub to: String,
    /// b1_from_b2 in each target's convention.
    pub formats: PlacementFormats,
    /// The files written, each read back within 1 µm and 1 µrad.
    pub files: Vec<FileReport>,
    /// What the files cannot carry (also printed on stderr as `warning:` lines).
    pub warnings: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    crate::export_dir::check_output_folder(&args.to, args.force, "--to")?;
    let mut formats: Vec<ControllerFormat> = args.format.iter().flat_map(|f| f.formats()).collect();
    formats.sort();
    formats.dedup();
    let cell = Cell::from_toml_file(&args.cell)?;
    let source = args.cell.display().to_string();
    let out = crate::export_dir::locked(&args.to, args.force, "--to", || {
        Ok(export_placement(&cell, &source, &args.to, &formats)?)
    })
    .with_context(|| format!("exporting {} to {}", source, args.to.display()))?;
    let report = ExportReport {
        cell: source,
        to: args.to.display().to_string(),
        formats: out.formats,
        files: out
            .files
            .iter()
            .map(|f| FileReport {
                path: f.path.display().to_string(),
                format: f.format.name(),
                read_back_um: f.translation_error_m * 1e6,
                read_back_urad: f.rotation_error_rad * 1e6,
            })
            .collect(),
        warnings: out.warnings,
    };
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(())
}

/// The readable table of `report`.
fn render_text(report: &ExportReport) -> String {
    let mut s = format!(
        "b1_from_b2 (robot 2's base in robot 1's base) of {}, written to {}:\n",
        report.cell, report.to
    );
    let f = &report.formats;
    let row = |name: &str, a: String, b: String| format!("  {name:<8} {a}   {b}\n");
    if let Some(v) = f.abb {
        s += &row(
            "ABB",
            format!("x y z (m)  {:.9} {:.9} {:.9}", v.x_m, v.y_m, v.z_m),
            format!(
                "q1 q2 q3 q4  {:.12} {:.12} {:.12} {:.12}",
                v.q1, v.q2, v.q3, v.q4
            ),
        );
    }
    if let Some(v) = f.kuka {
        s += &row(
            "KUKA",
            format!("X Y Z (mm)  {:.6} {:.6} {:.6}", v.x_mm, v.y_mm, v.z_mm),
            format!("A B C (deg)  {:.9} {:.9} {:.9}", v.a_deg, v.b_deg, v.c_deg),
        );
    }
    if let Some(v) = f.fanuc {
        s += &row(
            "Fanuc",
            format!("X Y Z (mm)  {:.6} {:.6} {:.6}", v.x_mm, v.y_mm, v.z_mm),
            format!("W P R (deg)  {:.9} {:.9} {:.9}", v.w_deg, v.p_deg, v.r_deg),
        );
    }
    if let Some(v) = f.yaskawa {
        s += &row(
            "Yaskawa",
            format!("X Y Z (mm)  {:.6} {:.6} {:.6}", v.x_mm, v.y_mm, v.z_mm),
            format!(
                "Rx Ry Rz (deg)  {:.9} {:.9} {:.9}",
                v.rx_deg, v.ry_deg, v.rz_deg
            ),
        );
    }
    if let Some(v) = f.ros2 {
        s += &row(
            "ROS 2",
            format!("x y z (m)  {:.9} {:.9} {:.9}", v.x_m, v.y_m, v.z_m),
            format!(
                "qx qy qz qw  {:.12} {:.12} {:.12} {:.12}",
                v.qx, v.qy, v.qz, v.qw
            ),
        );
    }
    s += &format!(
        "files (each parsed back and within {} µm / {} µrad of the placement before it was kept):\n",
        READ_BACK_TOL_M * 1e6,
        READ_BACK_TOL_RAD * 1e6
    );
    for file in &report.files {
        s += &format!(
            "  {:<8} {}   read back {:.2e} µm {:.2e} µrad\n",
            file.format, file.path, file.read_back_um, file.read_back_urad
        );
    }
    s += "what to type where: docs/guide/export.md\n";
    s
}
