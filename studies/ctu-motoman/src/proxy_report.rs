//! The hidden-set proxy's report: each model's difference from the reference (`all`) over the
//! seeded whole-workspace poses of `proxy`, printed and written as `proxy.csv`. MODEL vs MODEL,
//! not a measurement.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use handclasp_cell::Cell;
use kinematics::KinematicErrors;

use crate::data::Recording;
use crate::proxy;

/// The hidden-set proxy (`proxy` module): the difference between each model of `compared` and
/// the reference (the `all` model's file-CV choice, labelled `reference_label` in the table and
/// the CSV's `reference` column, e.g. `all (file-cv/all/)`) over a seeded whole-workspace set of
/// right-arm poses, with the protocol. MODEL vs MODEL, not model vs measurement. Writes
/// `out/proxy.csv`.
pub fn proxy_report(
    cell: &Cell,
    recordings: &[Recording],
    reference: &KinematicErrors,
    reference_label: &str,
    compared: &[(String, KinematicErrors)],
    out: &Path,
) -> anyhow::Result<()> {
    let (joints, draws) = proxy::proxy_joints(cell, recordings)?;
    let mut r = reference.clone();
    r.tip = nalgebra::Vector3::zeros();
    let rec = proxy::reference_recording(cell, &joints, &r)?;
    println!(
        "hidden-set PROXY (model vs model, no measurement): {} right-arm poses (seed {}, {draws} draws in the URDF limits, tool0 above \
         the dataset's lowest and ≥ 0.3 m from the S axis), each model vs {reference_label}, registration + reflector on one half, scored on the other:",
        joints.len(),
        proxy::PROXY_SEED
    );
    let path = out.join("proxy.csv");
    let mut w = std::fs::File::create(&path).with_context(|| format!("{}", path.display()))?;
    writeln!(w, "model,reference,n,rms_mm,median_mm,p95_mm,max_mm")?;
    for (name, m) in compared {
        let s = proxy::model_difference(cell, &rec, m)?;
        println!(
            "  {name:<22} vs {reference_label}: rms {:.3} mm, median {:.3}, p95 {:.3}, max {:.3}",
            s.rms_mm, s.median_mm, s.p95_mm, s.max_mm
        );
        writeln!(
            w,
            "{name},{reference_label},{},{:.4},{:.4},{:.4},{:.4}",
            s.n, s.rms_mm, s.median_mm, s.p95_mm, s.max_mm
        )?;
    }
    println!("wrote {}", path.display());
    Ok(())
}
