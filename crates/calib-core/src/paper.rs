//! The paper's Table 1 (Gan et al. 2014), embedded, and its errors recomputed from the published
//! transforms.
//!
//! The table is `data/gan2014_table1.csv` (mm, degrees, ZYZ). For every experiment the recomputation
//! gives e_tran (eq 34, ∞-norm of the xyz difference) and e_rot (eq 33: the estimate's ZYZ angles read
//! on the branch nearest the published true angles, differences wrapped at ±180°, ∞-norm), and the
//! geodesic angle between the true and estimated rotations.

use crate::error::CalibError;
use crate::metrics::{e_rot_raw, e_rot_zyz, geodesic_angle};
use crate::pose::PoseMmDeg;
use kinematics::euler::rotation_from_zyz;

/// The published table, as shipped (CSV text).
pub const TABLE1_CSV: &str = include_str!("../data/gan2014_table1.csv");

/// Tolerance of a recomputed e_tran against the published one, mm (the table's rounding).
pub const E_TRAN_TOL_MM: f64 = 0.2;
/// Tolerance of a recomputed e_rot against the published one, degrees (the table's rounding).
pub const E_ROT_TOL_DEG: f64 = 0.01;
/// Strict rounding bound for e_tran, mm: the printed xyz carry 0.1 mm (±0.05 each, so ±0.1 on a
/// difference) and the printed e_tran ±0.05.
pub const E_TRAN_ROUNDING_MM: f64 = 0.15;
/// Strict rounding bound for e_rot, degrees: printed angles carry 0.001° (±0.001 on a difference)
/// and the printed e_rot ±0.0005.
pub const E_ROT_ROUNDING_DEG: f64 = 0.0015;

/// A transform as the paper prints it: x, y, z in mm and ZYZ φ, θ, ψ in degrees.
pub type PublishedPose = PoseMmDeg;

/// One experiment of Table 1 as published.
#[derive(Debug, Clone, PartialEq)]
pub struct Table1Row {
    /// Experiment number, 1..=15.
    pub experiment: u32,
    /// `floor-floor`, `floor-ceiling` or `floor-wall`.
    pub mounts: String,
    /// CMM ground truth of `b1_from_b2`.
    pub truth: PublishedPose,
    /// The generic method's estimate (calib1).
    pub calib1: PublishedPose,
    /// Published e_tran1, mm.
    pub e_tran1_mm: f64,
    /// Published e_rot1, degrees.
    pub e_rot1_deg: f64,
    /// The constrained method's estimate (calib2).
    pub calib2: PublishedPose,
    /// Published e_tran2, mm.
    pub e_tran2_mm: f64,
    /// Published e_rot2, degrees.
    pub e_rot2_deg: f64,
}

/// The errors of one estimate recomputed from the published transforms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Recomputed {
    /// eq (34), mm.
    pub e_tran_mm: f64,
    /// eq (33) with branch-nearest reading and wrap, degrees.
    pub e_rot_deg: f64,
    /// eq (33) on the printed angles as they stand (no branch reading, wrap only), degrees.
    pub e_rot_raw_deg: f64,
    /// Geodesic angle between the true and estimated rotation, degrees.
    pub geodesic_deg: f64,
    /// Recomputed e_tran within [`E_TRAN_TOL_MM`] of the published one.
    pub e_tran_agrees: bool,
    /// Recomputed e_rot within [`E_ROT_TOL_DEG`] of the published one.
    pub e_rot_agrees: bool,
    /// Published e_tran explained by rounding alone (within [`E_TRAN_ROUNDING_MM`]).
    pub e_tran_consistent: bool,
    /// Published e_rot explained by rounding alone (within [`E_ROT_ROUNDING_DEG`]).
    pub e_rot_consistent: bool,
}

/// A Table 1 row with both estimates' errors recomputed, and a note where the published figure is
/// inconsistent with the published transforms.
#[derive(Debug, Clone, PartialEq)]
pub struct Table1Check {
    /// The published row.
    pub row: Table1Row,
    /// calib1 (generic method) recomputed.
    pub calib1: Recomputed,
    /// calib2 (constrained method) recomputed.
    pub calib2: Recomputed,
    /// Human-readable notes on disagreements (empty when everything agrees).
    pub notes: Vec<String>,
}

/// Parses the embedded table.
pub fn table1() -> Result<Vec<Table1Row>, CalibError> {
    parse_table1(TABLE1_CSV)
}

/// Parses Table 1 CSV text (header as in `data/gan2014_table1.csv`).
pub fn parse_table1(text: &str) -> Result<Vec<Table1Row>, CalibError> {
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| CalibError::PaperTable {
            line: 1,
            message: e.to_string(),
        })?
        .clone();
    let col = |name: &str| -> Result<usize, CalibError> {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| CalibError::PaperTable {
                line: 1,
                message: format!("missing column {name}"),
            })
    };
    let mut rows = Vec::new();
    for rec in reader.records() {
        let rec = rec.map_err(|e| CalibError::PaperTable {
            line: e.position().map(|p| p.line() as usize).unwrap_or(0),
            message: e.to_string(),
        })?;
        let line = rec.position().map(|p| p.line() as usize).unwrap_or(0);
        let num = |name: &str| -> Result<f64, CalibError> {
            let i = col(name)?;
            let cell = rec.get(i).unwrap_or("");
            cell.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| CalibError::PaperTable {
                    line,
                    message: format!("column {name}: `{cell}` is not a finite number"),
                })
        };
        let pose = |p: &str| -> Result<PublishedPose, CalibError> {
            Ok(PublishedPose {
                xyz_mm: [
                    num(&format!("{p}_x_mm"))?,
                    num(&format!("{p}_y_mm"))?,
                    num(&format!("{p}_z_mm"))?,
                ],
                zyz_deg: [
                    num(&format!("{p}_phi_deg"))?,
                    num(&format!("{p}_theta_deg"))?,
                    num(&format!("{p}_psi_deg"))?,
                ],
            })
        };
        rows.push(Table1Row {
            experiment: num("experiment")? as u32,
            mounts: rec.get(col("mounts")?).unwrap_or("").to_string(),
            truth: pose("true")?,
            calib1: pose("calib1")?,
            e_tran1_mm: num("e_tran1_mm")?,
            e_rot1_deg: num("e_rot1_deg")?,
            calib2: pose("calib2")?,
            e_tran2_mm: num("e_tran2_mm")?,
            e_rot2_deg: num("e_rot2_deg")?,
        });
    }
    Ok(rows)
}

/// Recomputes the errors of `est` against `truth`, comparing with the published figures.
pub fn recompute(
    truth: &PublishedPose,
    est: &PublishedPose,
    published_e_tran_mm: f64,
    published_e_rot_deg: f64,
) -> Recomputed {
    let e_tran_mm = (0..3)
        .map(|i| (truth.xyz_mm[i] - est.xyz_mm[i]).abs())
        .fold(0.0, f64::max);
    let r_est = rotation_from_zyz(est.zyz_rad());
    let e_rot_deg = e_rot_zyz(truth.zyz_rad(), &r_est).to_degrees();
    let e_rot_raw_deg = e_rot_raw(truth.zyz_rad(), est.zyz_rad()).to_degrees();
    let geodesic_deg = geodesic_angle(&truth.to_isometry(), &est.to_isometry()).to_degrees();
    // The 1e-9 absorbs binary round-off of decimal figures that sit exactly on the tolerance.
    Recomputed {
        e_tran_mm,
        e_rot_deg,
        e_rot_raw_deg,
        geodesic_deg,
        e_tran_agrees: (e_tran_mm - published_e_tran_mm).abs() <= E_TRAN_TOL_MM + 1e-9,
        e_rot_agrees: (e_rot_deg - published_e_rot_deg).abs() <= E_ROT_TOL_DEG + 1e-9,
        e_tran_consistent: (e_tran_mm - published_e_tran_mm).abs() <= E_TRAN_ROUNDING_MM + 1e-9,
        e_rot_consistent: (e_rot_deg - published_e_rot_deg).abs() <= E_ROT_ROUNDING_DEG + 1e-9,
    }
}

/// Recomputes every row of the embedded Table 1.
pub fn check_table1() -> Result<Vec<Table1Check>, CalibError> {
    Ok(table1()?.into_iter().map(check_row).collect())
}

/// Recomputes one row and explains any disagreement.
pub fn check_row(row: Table1Row) -> Table1Check {
    let c1 = recompute(&row.truth, &row.calib1, row.e_tran1_mm, row.e_rot1_deg);
    let c2 = recompute(&row.truth, &row.calib2, row.e_tran2_mm, row.e_rot2_deg);
    let mut notes = Vec::new();
    for (k, c, pt, pr) in [
        (1, &c1, row.e_tran1_mm, row.e_rot1_deg),
        (2, &c2, row.e_tran2_mm, row.e_rot2_deg),
    ] {
        if !c.e_tran_consistent {
            notes.push(format!(
                "e_tran{k}: published {pt} mm, the published transforms give {:.2} mm: more than rounding ({E_TRAN_ROUNDING_MM} mm) explains{}",
                c.e_tran_mm,
                if c.e_tran_agrees { "" } else { ", beyond the ±0.2 mm tolerance" }
            ));
        }
        if !c.e_rot_consistent {
            notes.push(format!(
                "e_rot{k}: published {pr}°, the published transforms give {:.4}° (geodesic {:.3}°): more than rounding ({E_ROT_ROUNDING_DEG}°) explains{}",
                c.e_rot_deg,
                c.geodesic_deg,
                if c.e_rot_agrees { "" } else { ", beyond the ±0.01° tolerance" }
            ));
        }
    }
    Table1Check {
        row,
        calib1: c1,
        calib2: c2,
        notes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_has_15_rows_of_the_three_cells() {
        let rows = table1().unwrap();
        assert_eq!(rows.len(), 15);
        for (i, r) in rows.iter().enumerate() {
            assert_eq!(r.experiment as usize, i + 1);
            let expected = ["floor-floor", "floor-ceiling", "floor-wall"][i / 5];
            assert_eq!(r.mounts, expected);
        }
    }

    /// Table 1 reproduced: every published e_tran / e_rot is recomputed from the published
    /// transforms within the table's rounding tolerance (±0.2 mm, ±0.01°).
    #[test]
    fn table1_reproduced_within_tolerance() {
        for c in check_table1().unwrap() {
            for (k, r, pt, pr) in [
                (1, &c.calib1, c.row.e_tran1_mm, c.row.e_rot1_deg),
                (2, &c.calib2, c.row.e_tran2_mm, c.row.e_rot2_deg),
            ] {
                assert!(
                    r.e_tran_agrees,
                    "experiment {} e_tran{k}: {} vs {pt}",
                    c.row.experiment, r.e_tran_mm
                );
                assert!(
                    r.e_rot_agrees,
                    "experiment {} e_rot{k}: {} vs {pr}",
                    c.row.experiment, r.e_rot_deg
                );
                // The geodesic angle never exceeds the ZYZ ∞-norm by more than the sum of the three.
                assert!(r.geodesic_deg <= 3.0 * r.e_rot_deg + 1e-9);
            }
        }
    }

    /// The published figures that rounding alone does not explain (the CLI prints them as notes):
    /// experiment 4's e_tran1 (7.2 published, 7.0 from the transforms), experiment 5's e_rot1
    /// (0.147 vs 0.143), and the floor–wall e_rot of experiments 11, 13, 14 and 15 (published
    /// 0.005–0.007° below what the printed transforms give, in both calib1 and calib2, which
    /// suggests the paper computed them from unrounded or differently-read angles).
    #[test]
    fn inconsistent_published_figures_are_found() {
        let mut found = Vec::new();
        for c in check_table1().unwrap() {
            let e = c.row.experiment;
            for (k, r) in [(1, &c.calib1), (2, &c.calib2)] {
                if !r.e_tran_consistent {
                    found.push(format!("{e}:e_tran{k}"));
                }
                if !r.e_rot_consistent {
                    found.push(format!("{e}:e_rot{k}"));
                }
            }
            assert_eq!(
                c.notes.is_empty(),
                !found.iter().any(|f| f.starts_with(&format!("{e}:")))
            );
        }
        let expected = [
            "4:e_tran1",
            "5:e_rot1",
            "11:e_rot1",
            "11:e_rot2",
            "13:e_rot1",
            "13:e_rot2",
            "14:e_rot1",
            "14:e_rot2",
            "15:e_rot1",
            "15:e_rot2",
        ];
        assert_eq!(found, expected);
    }

    #[test]
    fn malformed_table_is_an_error_not_a_panic() {
        let bad = TABLE1_CSV.replacen("37.9", "abc", 1);
        let e = parse_table1(&bad).unwrap_err();
        assert!(e.to_string().contains("true_x_mm"), "{e}");
    }
}
