//! Contact geometry of the self-contacts: the two marker dodecahedra touch FACE TO FACE. The
//! direction between the marker centres, seen in each arm's tool0 frame, points through one of
//! the 5 ring faces of the marker (polar angle arctan 2 ≈ 63.43° from tool z, the angle between
//! a regular dodecahedron's top face normal and its ring face normals; azimuths φ₀ + k·72°). Each
//! contact is therefore ring face k of the right marker against ring face j of the left one: the
//! face pair (k, j). Along the contact normal the centre distance is the sum of the two faces'
//! distances from their centres, so a marker centre that is off the nominal tip [0, 0, 354] mm
//! shows as a different mean distance per face pair.
//!
//! SI inside (m, rad); the table's CSV is in mm / deg.

use std::f64::consts::PI;
use std::io::Write;
use std::path::Path;

use anyhow::Context;
use handclasp_cell::Cell;
use kinematics::{true_base_from_tip, KinematicErrors};
use nalgebra::{Isometry3, Unit, Vector3};

use crate::data::{FaceNormals, Recording, Role};

/// Polar angle of a ring face normal from the top face normal (tool z) of a regular
/// dodecahedron: arctan 2, rad.
pub fn ring_polar_angle() -> f64 {
    2f64.atan()
}

/// Unit normal of ring face `k` (0..5) in the tool0 frame, for the ring's azimuth `phi0_rad`.
pub fn ring_normal(phi0_rad: f64, k: usize) -> Vector3<f64> {
    let (st, ct) = ring_polar_angle().sin_cos();
    let phi = phi0_rad + k as f64 * 2.0 * PI / 5.0;
    Vector3::new(st * phi.cos(), st * phi.sin(), ct)
}

/// Both markers of one self-contact pose: (base_from_tip of the right marker, of the left), at
/// `corr` (right, left; the `tip` fields are the marker centres' offsets).
fn markers(
    cell: &Cell,
    q_right: &[f64],
    q_left: &[f64],
    corr: (&KinematicErrors, &KinematicErrors),
) -> anyhow::Result<(Isometry3<f64>, Isometry3<f64>)> {
    let r = &cell.robot1;
    let l = &cell.robot2;
    let right = true_base_from_tip(&r.model, corr.0, q_right, &r.flange_from_tip, &r.g_base)?;
    let left = true_base_from_tip(&l.model, corr.1, q_left, &l.flange_from_tip, &l.g_base)?;
    Ok((right, cell.b1_from_b2 * left))
}

/// Contact directions in the two tool0 frames at nominal kinematics: (right marker → left
/// marker in the right tool0 frame, left → right in the left tool0 frame), unit vectors.
fn directions(
    cell: &Cell,
    rec: &Recording,
    corr: (&KinematicErrors, &KinematicErrors),
) -> anyhow::Result<Vec<(Vector3<f64>, Vector3<f64>)>> {
    rec.poses
        .iter()
        .map(|p| {
            let (r, l) = markers(cell, &p.q_right, &p.q_left, corr)?;
            let u = (l.translation.vector - r.translation.vector).normalize();
            Ok((r.rotation.inverse() * u, l.rotation.inverse() * -u))
        })
        .collect()
}

/// The measured ring geometry of the self-contacts at nominal kinematics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingFit {
    /// Mean polar angle of the contact directions from tool z (both arms), rad.
    pub polar_mean_rad: f64,
    /// Their standard deviation, rad.
    pub polar_sd_rad: f64,
    /// Ring azimuth φ₀ (the circular mean of 5·φ over both arms, divided by 5), rad, in
    /// [0, 72°).
    pub phi0_rad: f64,
    /// Largest distance of a direction's azimuth from its nearest ideal face, rad.
    pub azimuth_max_dev_rad: f64,
    /// Number of directions (2 per pose).
    pub n: usize,
}

/// Measures the ring geometry of `recs`' self-contacts at nominal kinematics: the polar angle
/// of the contact directions and the ring's azimuth φ₀. Fails when `recs` holds no pose.
pub fn fit_ring(cell: &Cell, recs: &[&Recording]) -> anyhow::Result<RingFit> {
    let zero = KinematicErrors::zero(6);
    let mut dirs = Vec::new();
    for rec in recs {
        for (r, l) in directions(cell, rec, (&zero, &zero))? {
            dirs.push(r);
            dirs.push(l);
        }
    }
    anyhow::ensure!(!dirs.is_empty(), "no self-contact pose to fit the ring to");
    let n = dirs.len() as f64;
    let polar: Vec<f64> = dirs.iter().map(|d| d.z.clamp(-1.0, 1.0).acos()).collect();
    let polar_mean_rad = polar.iter().sum::<f64>() / n;
    let polar_sd_rad = (polar
        .iter()
        .map(|p| (p - polar_mean_rad).powi(2))
        .sum::<f64>()
        / (n - 1.0).max(1.0))
    .sqrt();
    let (s, c) = dirs.iter().fold((0.0, 0.0), |(s, c), d| {
        let a = 5.0 * d.y.atan2(d.x);
        (s + a.sin(), c + a.cos())
    });
    let phi0_rad = (s.atan2(c) / 5.0).rem_euclid(2.0 * PI / 5.0);
    let azimuth_max_dev_rad = dirs
        .iter()
        .map(|d| {
            let a = d.y.atan2(d.x) - phi0_rad;
            let step = 2.0 * PI / 5.0;
            (a - (a / step).round() * step).abs()
        })
        .fold(0.0, f64::max);
    Ok(RingFit {
        polar_mean_rad,
        polar_sd_rad,
        phi0_rad,
        azimuth_max_dev_rad,
        n: dirs.len(),
    })
}

/// One self-contact pose seen as a face contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceContact {
    /// Ring face of the right marker (0..5).
    pub face_right: usize,
    /// Ring face of the left marker (0..5).
    pub face_left: usize,
    /// Centre distance along the right face's normal, m.
    pub along_m: f64,
    /// Centre distance, m.
    pub centre_m: f64,
    /// Centre distance along the faces' mean normal `n̄ = unit(n_r − n_l)` (`n_l` the left
    /// face's outward normal): what a `FaceContact` row compares with the contact distance, m.
    pub along_mean_m: f64,
    /// The centres' offset across `n̄` (how far the faces slide from centred), m. The centre
    /// distance is `√(along_mean² + slide²)`, so it exceeds `along_mean_m` by
    /// ≈ `slide²/(2·along_mean)`.
    pub slide_m: f64,
    /// Angle between the right face normal and the reversed left face normal, rad (0 for a
    /// perfectly flush contact).
    pub misalign_rad: f64,
}

/// The face contact of every pose of `rec` at `corr` (right, left; the `tip` fields are the
/// marker centres' offsets), faces assigned by the nearest ideal ring normal of `ring`
/// AT NOMINAL kinematics (so the assignment does not depend on the model scored).
pub fn face_contacts(
    cell: &Cell,
    rec: &Recording,
    ring: &RingFit,
    corr: (&KinematicErrors, &KinematicErrors),
) -> anyhow::Result<Vec<FaceContact>> {
    let zero = KinematicErrors::zero(6);
    let nearest = |d: &Vector3<f64>| {
        (0..5)
            .max_by(|&a, &b| {
                ring_normal(ring.phi0_rad, a)
                    .dot(d)
                    .total_cmp(&ring_normal(ring.phi0_rad, b).dot(d))
            })
            .unwrap_or(0)
    };
    let nominal = directions(cell, rec, (&zero, &zero))?;
    rec.poses
        .iter()
        .zip(nominal)
        .map(|(p, (dr, dl))| {
            let (face_right, face_left) = (nearest(&dr), nearest(&dl));
            let (r, l) = markers(cell, &p.q_right, &p.q_left, corr)?;
            let n_r = r.rotation * ring_normal(ring.phi0_rad, face_right);
            let n_l = l.rotation * ring_normal(ring.phi0_rad, face_left);
            let v = l.translation.vector - r.translation.vector;
            let n_bar = (n_r - n_l).normalize();
            let along_mean_m = n_bar.dot(&v);
            Ok(FaceContact {
                face_right,
                face_left,
                along_m: v.dot(&n_r),
                centre_m: v.norm(),
                along_mean_m,
                slide_m: (v - n_bar * along_mean_m).norm(),
                misalign_rad: n_r.angle(&-n_l),
            })
        })
        .collect()
}

/// Sets the touching faces ([`FaceNormals`]) of every pose of the self-contact recordings of
/// `recordings` (roles `SelfContact` and `TrackerSelfContact`): the ring faces of `ring`
/// assigned at nominal kinematics as in [`face_contacts`], each outward normal in its marker's
/// tip frame. That frame is the rotation of `true_base_from_tip`, i.e. tool0's (a tool's
/// `flange_from_tip` is a translation), which is also the frame `ring_normal` is measured in,
/// so the normal needs no rotation. `study::build_problem` then builds these poses' contact
/// rows as `FaceContact`. Returns the number of poses set.
pub fn assign_face_normals(
    cell: &Cell,
    recordings: &mut [Recording],
    ring: &RingFit,
) -> anyhow::Result<usize> {
    let zero = KinematicErrors::zero(6);
    let normal = |k: usize| (k, Unit::new_normalize(ring_normal(ring.phi0_rad, k)));
    let mut n = 0;
    for rec in recordings
        .iter_mut()
        .filter(|r| matches!(r.role, Role::SelfContact | Role::TrackerSelfContact))
    {
        let contacts = face_contacts(cell, rec, ring, (&zero, &zero))?;
        for (pose, c) in rec.poses.iter_mut().zip(contacts) {
            pose.faces = Some(FaceNormals {
                right: normal(c.face_right),
                left: normal(c.face_left),
            });
            n += 1;
        }
    }
    Ok(n)
}

/// One line on how far the faces of `contacts` slide: the mean and largest slide, and the mean
/// and largest excess of the centre distance over the along-normal distance, mm.
pub fn slide_summary(contacts: &[FaceContact]) -> String {
    let n = contacts.len().max(1) as f64;
    let max = |f: fn(&FaceContact) -> f64| contacts.iter().map(f).fold(0.0, f64::max);
    let mean = |f: fn(&FaceContact) -> f64| contacts.iter().map(f).sum::<f64>() / n;
    let excess = |c: &FaceContact| c.centre_m - c.along_mean_m;
    format!(
        "faces slide {:.2} mm mean, {:.2} mm max; centre distance − along-normal distance {:.4} mm mean, {:.4} mm max",
        mean(|c| c.slide_m) * 1e3,
        max(|c| c.slide_m) * 1e3,
        mean(excess) * 1e3,
        max(excess) * 1e3
    )
}

/// One row of the per-pair table.
#[derive(Debug, Clone, PartialEq)]
pub struct PairRow {
    /// (right face, left face).
    pub pair: (usize, usize),
    /// Poses.
    pub n: usize,
    /// (mean, sd) of the along-normal centre distance of each model of the table, m.
    pub along: Vec<(f64, f64)>,
    /// (mean, sd) of the misalignment at the first model, rad.
    pub misalign: (f64, f64),
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    (m, sd)
}

/// The per-face-pair table of `recs` for each model of `models` (right, left corrections), the
/// first being the reference of the misalignment column; pairs in ascending order.
pub fn pair_table(
    cell: &Cell,
    recs: &[&Recording],
    ring: &RingFit,
    models: &[(&KinematicErrors, &KinematicErrors)],
) -> anyhow::Result<Vec<PairRow>> {
    let per_model: Vec<Vec<FaceContact>> = models
        .iter()
        .map(|&corr| -> anyhow::Result<Vec<FaceContact>> {
            let mut all = Vec::new();
            for rec in recs {
                all.extend(face_contacts(cell, rec, ring, corr)?);
            }
            Ok(all)
        })
        .collect::<anyhow::Result<_>>()?;
    let first = per_model.first().context("no model for the pair table")?;
    let mut pairs: Vec<(usize, usize)> =
        first.iter().map(|c| (c.face_right, c.face_left)).collect();
    pairs.sort_unstable();
    pairs.dedup();
    Ok(pairs
        .into_iter()
        .map(|pair| {
            let idx: Vec<usize> = (0..first.len())
                .filter(|&i| (first[i].face_right, first[i].face_left) == pair)
                .collect();
            let along = per_model
                .iter()
                .map(|m| mean_sd(&idx.iter().map(|&i| m[i].along_m).collect::<Vec<_>>()))
                .collect();
            let misalign = mean_sd(
                &idx.iter()
                    .map(|&i| first[i].misalign_rad)
                    .collect::<Vec<_>>(),
            );
            PairRow {
                pair,
                n: idx.len(),
                along,
                misalign,
            }
        })
        .collect())
}

/// The rms of the along-normal distance about one common distance (its mean) over every pose of
/// the table, for model `m`, m: what one contact distance leaves along the normals.
pub fn along_rms_about_common(rows: &[PairRow], m: usize) -> f64 {
    let n: usize = rows.iter().map(|r| r.n).sum();
    let mean = rows.iter().map(|r| r.along[m].0 * r.n as f64).sum::<f64>() / n.max(1) as f64;
    let ss: f64 = rows
        .iter()
        .map(|r| {
            let (mu, sd) = r.along[m];
            // Σ (x − mean)² over a pair = (n − 1)·sd² + n·(mu − mean)².
            (r.n as f64 - 1.0).max(0.0) * sd * sd + r.n as f64 * (mu - mean).powi(2)
        })
        .sum();
    (ss / n.max(1) as f64).sqrt()
}

/// Writes the pair table as CSV (mm, deg), one column pair per model named in `names`.
pub fn write_pair_table(path: &Path, rows: &[PairRow], names: &[&str]) -> anyhow::Result<()> {
    let mut w = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    write!(w, "face_right,face_left,n")?;
    for m in names {
        write!(w, ",{m}_along_mean_mm,{m}_along_sd_mm")?;
    }
    writeln!(w, ",misalign_mean_deg,misalign_sd_deg")?;
    for r in rows {
        write!(w, "{},{},{}", r.pair.0, r.pair.1, r.n)?;
        for (mu, sd) in &r.along {
            write!(w, ",{:.4},{:.4}", mu * 1e3, sd * 1e3)?;
        }
        writeln!(
            w,
            ",{:.4},{:.4}",
            r.misalign.0.to_degrees(),
            r.misalign.1.to_degrees()
        )?;
    }
    Ok(())
}

/// Fold names of the face pairs (right face k, left face j) at index `5·k + j`.
const PAIR_FOLDS: [&str; 25] = [
    "pair 0-0", "pair 0-1", "pair 0-2", "pair 0-3", "pair 0-4", "pair 1-0", "pair 1-1", "pair 1-2",
    "pair 1-3", "pair 1-4", "pair 2-0", "pair 2-1", "pair 2-2", "pair 2-3", "pair 2-4", "pair 3-0",
    "pair 3-1", "pair 3-2", "pair 3-3", "pair 3-4", "pair 4-0", "pair 4-1", "pair 4-2", "pair 4-3",
    "pair 4-4",
];

/// `recs` split by face pair (faces assigned at nominal kinematics): one recording per
/// (recording, pair), its `pattern` the pair's fold name, its poses in their original order.
/// Returns the recordings and the distinct fold names (ascending).
pub fn split_by_face_pair(
    cell: &Cell,
    recs: &[&Recording],
    ring: &RingFit,
) -> anyhow::Result<(Vec<Recording>, Vec<&'static str>)> {
    let zero = KinematicErrors::zero(6);
    let mut out = Vec::new();
    let mut folds = Vec::new();
    for rec in recs {
        let contacts = face_contacts(cell, rec, ring, (&zero, &zero))?;
        for (k, fold) in PAIR_FOLDS.iter().enumerate() {
            let poses: Vec<_> = rec
                .poses
                .iter()
                .zip(&contacts)
                .filter(|(_, c)| 5 * c.face_right + c.face_left == k)
                .map(|(p, _)| p.clone())
                .collect();
            if poses.is_empty() {
                continue;
            }
            folds.push(*fold);
            out.push(Recording {
                name: format!("{} {fold}", rec.name),
                pattern: fold,
                poses,
                ..(*rec).clone()
            });
        }
    }
    folds.sort_unstable();
    folds.dedup();
    Ok((out, folds))
}
