//! `handclasp export --cell CELL --to DIR [--format abb,kuka,fanuc,yaskawa,ros2|all] [--json]
//! [--force]`: the cell's placement `b1_from_b2` (robot 2's base frame in robot 1's base frame)
//! in each controller's and ROS 2's own convention and file, each file read back and checked
//! before the command succeeds (`handclasp_cell::export_formats`). The JSON and the text table come
//! from one typed report, [`cli_support::controllers::ExportReport`] (shared with the Python
//! package's `export_controllers`).

use std::path::PathBuf;

use anyhow::Context;
use cli_support::controllers::{export_controllers, render_text};
use handclasp_cell::export_formats::ControllerFormat;
use handclasp_cell::Cell;

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

pub fn run(args: Args) -> anyhow::Result<()> {
    crate::export_dir::check_output_folder(&args.to, args.force, "--to")?;
    let formats: Vec<ControllerFormat> = args.format.iter().flat_map(|f| f.formats()).collect();
    let cell = Cell::from_toml_file(&args.cell)?;
    let source = args.cell.display().to_string();
    let report = export_controllers(
        &cell,
        &source,
        &args.to,
        &formats,
        args.force,
        ("--to", "--force"),
    )
    .with_context(|| format!("exporting {} to {}", source, args.to.display()))?;
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
