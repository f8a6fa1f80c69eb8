//! The contact-geometry report: the measured ring of face normals, the face pairs of the
//! self-contacts with their along-normal distances at nominal and at the `self` models, the
//! `leica_self` contact scatter (an independent check that uses no tracker value), and whether
//! the self-contacts agree with the tracker-derived joint offsets of `all`. Prints, and writes
//! `contact_pairs.csv` and `contact_pairs.svg`.

use std::path::Path;

use handclasp_cell::Cell;
use kinematics::{ErrorParam, KinematicErrors};

use crate::calibrated::{calibrate, contact_rms, Calibrated, Calibrations};
use crate::contact;
use crate::data::{self, Recording, Role};
use crate::plot;
use crate::study::{
    build_problem, corrections, fit, held_out_nuisance_cost, ModelSpec, NoiseLevels, ParamSet,
};

/// Contact geometry (`contact` module): the measured ring of face normals, the face pairs of the
/// no-tracker self-contacts and of `leica_self`, the along-normal distance per pair at nominal,
/// with only the marker centres fitted (nominal joints) and at the `self` models; the contact
/// residual before and after; the `leica_self` contact scatter (no tracker value: an
/// independent check of the `self` models). Writes `out/contact_pairs.csv` and
/// `out/contact_pairs.svg`.
pub fn contact_report(
    cell: &Cell,
    self_recs: &[&Recording],
    leica_self: &[&Recording],
    cal_self: &Calibrations,
    noise: &NoiseLevels,
    out: &Path,
) -> anyhow::Result<()> {
    let ring = contact::fit_ring(cell, self_recs)?;
    println!(
        "contact geometry (nominal kinematics): {} contact directions in the tool0 frames at polar angle {:.2} ± {:.2}° \
         (ideal ring face: arctan 2 = {:.2}°), ring azimuth φ0 = {:.2}° + k·72°, largest azimuth departure {:.2}°",
        ring.n,
        ring.polar_mean_rad.to_degrees(),
        ring.polar_sd_rad.to_degrees(),
        contact::ring_polar_angle().to_degrees(),
        ring.phi0_rad.to_degrees(),
        ring.azimuth_max_dev_rad.to_degrees()
    );
    let marker_only = calibrate(
        cell,
        "marker only".into(),
        self_recs,
        ModelSpec {
            set: ParamSet::OffsetsMarker,
            sigma: 0.0,
        },
        noise,
    )?;
    let zero = KinematicErrors::zero(6);
    let mut models: Vec<(String, KinematicErrors, KinematicErrors, Option<f64>)> =
        vec![("nominal".into(), zero.clone(), zero.clone(), None)];
    for c in std::iter::once(&marker_only)
        .chain(std::iter::once(&cal_self.chosen))
        .chain(
            cal_self
                .marker
                .iter()
                .filter(|m| m.name != cal_self.chosen.name),
        )
    {
        let (r, l) = corrections(&c.fit);
        models.push((c.name.clone(), r, l, Some(contact_rms(c)?)));
    }
    let corr: Vec<(&KinematicErrors, &KinematicErrors)> =
        models.iter().map(|m| (&m.1, &m.2)).collect();
    let rows = contact::pair_table(cell, self_recs, &ring, &corr)?;
    println!(
        "face pairs of the no-tracker self-contacts ({} pairs; along-normal centre distance mean ± sd, mm; misalignment of the \
         two face normals at nominal, deg):",
        rows.len()
    );
    print!("  {:<8} {:>4}", "(R, L)", "n");
    for m in &models {
        print!(" {:>18}", m.0);
    }
    println!(" {:>14}", "misalign");
    for r in &rows {
        print!(
            "  {:<8} {:>4}",
            format!("({}, {})", r.pair.0, r.pair.1),
            r.n
        );
        for (mu, sd) in &r.along {
            print!(" {:>10.2} ± {:>5.2}", mu * 1e3, sd * 1e3);
        }
        println!(
            " {:>6.3} ± {:.3}",
            r.misalign.0.to_degrees(),
            r.misalign.1.to_degrees()
        );
    }
    print!("  {:<13}", "rms about one distance, mm:");
    for m in 0..models.len() {
        print!(" {:>18.3}", contact::along_rms_about_common(&rows, m) * 1e3);
    }
    println!();
    print!("  {:<13}", "contact residual (fit), mm:");
    for m in &models {
        let v = m.3.unwrap_or(noise.contact_m);
        print!(" {:>18.3}", v * 1e3);
    }
    println!("  (centre distance minus the fitted distance; nominal = the noise σ above)");
    if self_recs
        .iter()
        .all(|r| r.poses.iter().all(|p| p.faces.is_some()))
    {
        println!(
            "  --contact-model face: the contact residual above is the along-normal distance minus the fitted distance; the faces' slide per model:"
        );
        for m in &models {
            let mut c = Vec::new();
            for rec in self_recs {
                c.extend(contact::face_contacts(cell, rec, &ring, (&m.1, &m.2))?);
            }
            println!("  {}: {}", m.0, contact::slide_summary(&c));
        }
    }
    let names: Vec<String> = models
        .iter()
        .map(|m| m.0.replace([' ', '+'], "_"))
        .collect();
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    contact::write_pair_table(&out.join("contact_pairs.csv"), &rows, &name_refs)?;
    plot::contact_pairs_svg(
        &out.join("contact_pairs.svg"),
        &rows,
        &models.iter().map(|m| m.0.as_str()).collect::<Vec<_>>(),
    )?;
    let leica_rows = contact::pair_table(cell, leica_self, &ring, &corr[..1])?;
    println!(
        "leica_self face pairs: {}",
        leica_rows
            .iter()
            .map(|r| format!(
                "({}, {}) n {} along {:.2} ± {:.2} mm",
                r.pair.0,
                r.pair.1,
                r.n,
                r.along[0].0 * 1e3,
                r.along[0].1 * 1e3
            ))
            .collect::<Vec<_>>()
            .join("; ")
    );
    // Independent check without tracker values: the leica_self contact rows alone (their tracker
    // values dropped), contact distance refitted, at each model's corrections.
    let contact_only = leica_contact_only(leica_self);
    let refs: Vec<&Recording> = contact_only.iter().collect();
    print!("leica_self contact scatter (no tracker value; distance refitted), rms mm:");
    for m in &models {
        let e2 = held_out_nuisance_cost(cell, &refs, (&m.1, &m.2), noise)?;
        let rms = (e2.iter().sum::<f64>() / e2.len().max(1) as f64).sqrt() * noise.contact_m;
        print!(" {} {:.3};", m.0, rms * 1e3);
    }
    println!();
    Ok(())
}

/// `--contact-model face`: each spec of `specs` (a label and a set with its prior σ) fitted on
/// the no-tracker self-contacts `self_recs` (their faces set) with both contact models, the
/// `Contact` rows (faces dropped) and the `FaceContact` rows, same σ and start. Prints, per spec,
/// the contact residual of each (mm), the largest change of a joint offset (mrad), of a marker
/// centre component (mm) and of the contact distance (mm).
pub fn contact_model_comparison(
    cell: &Cell,
    self_recs: &[&Recording],
    specs: &[(&str, ModelSpec)],
    noise: &NoiseLevels,
) -> anyhow::Result<()> {
    let distance_recs: Vec<Recording> = self_recs
        .iter()
        .map(|r| Recording {
            poses: r
                .poses
                .iter()
                .map(|p| data::Pose {
                    faces: None,
                    ..p.clone()
                })
                .collect(),
            ..(*r).clone()
        })
        .collect();
    let distance_refs: Vec<&Recording> = distance_recs.iter().collect();
    println!(
        "contact models compared (each spec fitted on the no-tracker self-contacts as distance rows, then as face rows; same σ):"
    );
    for &(label, spec) in specs {
        let [d, f] = [&distance_refs[..], self_recs].map(|recs| -> anyhow::Result<Calibrated> {
            let b = build_problem(cell, recs, Some(spec), noise);
            let fit = fit(&b, None, None)?;
            Ok(Calibrated {
                name: label.to_string(),
                problem: b.problem,
                fit,
                spec,
            })
        });
        let (d, f) = (d?, f?);
        let (dr, dl) = corrections(&d.fit);
        let (fr, fl) = corrections(&f.fit);
        let (mut offset_rad, mut marker_m): (f64, f64) = (0.0, 0.0);
        for (a, b) in [(&dr, &fr), (&dl, &fl)] {
            for joint in 0..6 {
                let p = ErrorParam::JointOffset { joint };
                offset_rad = offset_rad.max((a.get(p) - b.get(p)).abs());
            }
            marker_m = marker_m.max((a.tip - b.tip).amax());
        }
        println!(
            "  {label:<28} ({} σ {}): contact residual {:.3} → {:.3} mm; joint offsets change ≤ {:.3} mrad, marker centres ≤ {:.3} mm, contact distance {:.3} → {:.3} mm",
            spec.set.name(),
            spec.sigma,
            contact_rms(&d)? * 1e3,
            contact_rms(&f)? * 1e3,
            offset_rad * 1e3,
            marker_m * 1e3,
            d.fit.estimate.contact_distance_m[0] * 1e3,
            f.fit.estimate.contact_distance_m[0] * 1e3,
        );
    }
    Ok(())
}

/// The `leica_self` recordings among `recs` as no-tracker self-contacts (their tracker values
/// dropped): contact rows only, scored in the no-tracker contact σ.
pub fn leica_contact_only(recs: &[&Recording]) -> Vec<Recording> {
    recs.iter()
        .filter(|r| r.role == Role::TrackerSelfContact)
        .map(|r| Recording {
            role: Role::SelfContact,
            poses: r
                .poses
                .iter()
                .map(|p| data::Pose {
                    p_tracker: None,
                    ..p.clone()
                })
                .collect(),
            ..(*r).clone()
        })
        .collect()
}

/// Prints the self-contact residual with only the marker centres fitted on `self_recs` and the
/// joints held at `all`'s corrections (tracker-derived): do the self-contacts agree with them?
pub fn marker_at_report(
    cell: &Cell,
    self_recs: &[&Recording],
    all: &Calibrated,
    noise: &NoiseLevels,
) -> anyhow::Result<()> {
    let b = build_problem(
        cell,
        self_recs,
        Some(ModelSpec {
            set: ParamSet::OffsetsMarker,
            sigma: 0.0,
        }),
        noise,
    );
    let (r, l) = corrections(&all.fit);
    let f = fit(&b, None, Some((&r, &l)))?;
    let c = Calibrated {
        name: "marker at all".into(),
        problem: b.problem,
        fit: f,
        spec: all.spec,
    };
    println!(
        "self-contact residual with the marker centres fitted and the joints held at `all` (tracker-derived): {:.3} mm",
        contact_rms(&c)? * 1e3
    );
    Ok(())
}
