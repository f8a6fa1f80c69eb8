//! A pose as files and robot controllers write it: x, y, z in mm and ZYZ angles in degrees,
//! `R = Rz(φ)·Ry(θ)·Rz(ψ)`. Code works in m and rad ([`Isometry3`]); this is the file edge.

use kinematics::euler::{rotation_from_zyz, zyz_canonical, zyz_canonical_within, zyz_nearest};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// A pose `a_from_b` in file units: translation x, y, z (mm) and ZYZ φ, θ, ψ (degrees,
/// `R = Rz(φ)·Ry(θ)·Rz(ψ)`). Which frames it relates is named by the field that holds it.
/// Serialised as `{"xyz_mm": [x, y, z], "zyz_deg": [φ, θ, ψ]}` (unknown keys are refused).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseMmDeg {
    /// x, y, z, mm.
    pub xyz_mm: [f64; 3],
    /// φ, θ, ψ (ZYZ, `R = Rz(φ)·Ry(θ)·Rz(ψ)`), degrees.
    pub zyz_deg: [f64; 3],
}

impl PoseMmDeg {
    /// The pose as an isometry (m, rad): millimetres divided by 1000 (correctly rounded).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(
                self.xyz_mm[0] / 1000.0,
                self.xyz_mm[1] / 1000.0,
                self.xyz_mm[2] / 1000.0,
            ),
            UnitQuaternion::from_rotation_matrix(&rotation_from_zyz(self.zyz_rad())),
        )
    }

    /// The pose of an isometry (m, rad) in mm and degrees, its ZYZ angles read on the branch nearest
    /// `reference_zyz_rad` (rad, e.g. a cell's stated angles; see
    /// [`kinematics::euler::zyz_nearest`], which also fixes the angles at the θ = 0° and 180°
    /// singularities). Each angle is wrapped to (−180°, 180°].
    pub fn from_isometry(pose: &Isometry3<f64>, reference_zyz_rad: [f64; 3]) -> Self {
        let t = pose.translation.vector * 1e3;
        let zyz_rad = zyz_nearest(&pose.rotation.to_rotation_matrix(), reference_zyz_rad);
        PoseMmDeg {
            xyz_mm: [t.x, t.y, t.z],
            zyz_deg: zyz_rad.map(f64::to_degrees),
        }
    }

    /// The ZYZ angles in radians.
    pub fn zyz_rad(&self) -> [f64; 3] {
        self.zyz_deg.map(f64::to_radians)
    }
}

/// A pose `a_from_b` in every form the reports print: translation x, y, z (mm), ZYZ φ, θ, ψ
/// (degrees, `R = Rz(φ)·Ry(θ)·Rz(ψ)`, canonical branch: [`zyz_canonical`]), the rotation matrix
/// (row-major, `rotation[i][j] = R[(i, j)]`: column j is b's axis j in a's axes) and the unit
/// quaternion `[w, x, y, z]`. Which frames it relates is named by the field that holds it.
///
/// Fields in alphabetical order, which is the JSON key order of every report that prints one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PoseForms {
    /// Unit quaternion `[w, x, y, z]`, sign chosen so that `w ≥ 0` (q and −q are one rotation;
    /// one sign keeps reports comparable).
    pub quaternion_wxyz: [f64; 4],
    /// Rotation matrix, row-major.
    pub rotation: [[f64; 3]; 3],
    /// x, y, z, mm.
    pub xyz_mm: [f64; 3],
    /// φ, θ, ψ (ZYZ, canonical branch), degrees.
    pub zyz_deg: [f64; 3],
}

impl PoseForms {
    /// The forms of an isometry (m, rad): millimetres are metres × 1000, the ZYZ angles are
    /// [`zyz_canonical`]'s in degrees.
    pub fn from_isometry(a_from_b: &Isometry3<f64>) -> Self {
        let t = a_from_b.translation.vector * 1e3;
        let r = a_from_b.rotation.to_rotation_matrix();
        let q = a_from_b.rotation;
        // The stored quaternion's own digits, with the sign of `kinematics::quaternion_wxyz`:
        // w > 0, or at w = 0 the first non-zero of x, y, z positive.
        let mut wxyz = [q.w, q.i, q.j, q.k];
        if wxyz.iter().copied().find(|c| *c != 0.0).unwrap_or(1.0) < 0.0 {
            wxyz = wxyz.map(|c| -c);
        }
        PoseForms {
            quaternion_wxyz: wxyz,
            rotation: [0, 1, 2].map(|i| [0, 1, 2].map(|j| r[(i, j)])),
            xyz_mm: [t.x, t.y, t.z],
            zyz_deg: zyz_canonical(&r).map(f64::to_degrees),
        }
    }

    /// The ZYZ angles (degrees) of this pose's `rotation` with a tilt within `band_deg` of
    /// θ = 0° or 180° written as a pure yaw ([`zyz_canonical_within`]): what a text report
    /// prints when the tilt is below its resolution or its σ.
    pub fn zyz_deg_within(&self, band_deg: f64) -> [f64; 3] {
        let m = nalgebra::Matrix3::from_fn(|i, j| self.rotation[i][j]);
        let r = nalgebra::Rotation3::from_matrix_unchecked(m);
        zyz_canonical_within(&r, band_deg.to_radians()).map(f64::to_degrees)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Round trip mm/deg → isometry → mm/deg: round-off of degree↔radian and ZYZ extraction on
    /// O(1000) mm and O(180)° values.
    const ROUND_TRIP_TOL: f64 = 1e-9;

    #[test]
    fn round_trip_on_the_reference_branch_including_singular_theta() {
        for zyz_deg in [
            [30.0, 45.0, -60.0],
            [179.5, 90.0, -179.5],
            [-150.0, -120.0, 10.0],
            [180.0, 180.0, 0.0],
            [40.0, 0.0, 0.0],
            [1e-7, 1e-7, 1e-7],
        ] {
            let pose = PoseMmDeg {
                xyz_mm: [1500.0, -20.5, 300.25],
                zyz_deg,
            };
            let back = PoseMmDeg::from_isometry(&pose.to_isometry(), pose.zyz_rad());
            for i in 0..3 {
                assert!((back.xyz_mm[i] - pose.xyz_mm[i]).abs() < ROUND_TRIP_TOL);
            }
            // Same rotation, and on the reference's branch: angles agree modulo 360°.
            let r = back
                .to_isometry()
                .rotation
                .angle_to(&pose.to_isometry().rotation);
            assert!(r < ROUND_TRIP_TOL, "{zyz_deg:?} → {:?}", back.zyz_deg);
            if zyz_deg[1].abs() > 1e-3 && (zyz_deg[1].abs() - 180.0).abs() > 1e-3 {
                for i in 0..3 {
                    let d = (back.zyz_deg[i] - zyz_deg[i]).rem_euclid(360.0);
                    assert!(d.min(360.0 - d) < 1e-7, "{zyz_deg:?} → {:?}", back.zyz_deg);
                }
            }
        }
    }

    #[test]
    fn serialises_with_named_unit_fields() {
        let pose = PoseMmDeg {
            xyz_mm: [1.0, 2.0, 3.0],
            zyz_deg: [4.0, 5.0, 6.0],
        };
        let json = serde_json::to_string(&pose).unwrap();
        assert_eq!(json, r#"{"xyz_mm":[1.0,2.0,3.0],"zyz_deg":[4.0,5.0,6.0]}"#);
        assert_eq!(serde_json::from_str::<PoseMmDeg>(&json).unwrap(), pose);
        // A misspelt key is refused, naming it (a cell file's [b1_from_b2] relies on this).
        let e = serde_json::from_str::<PoseMmDeg>(r#"{"xyz_mm":[0,0,0],"zyz_degs":[0,0,0]}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("zyz_degs"), "{e}");
    }

    /// A quaternion stored with w < 0 is reported with w > 0, same rotation, same digits up to
    /// the sign (stop 28: a tracker frame in the calibrate-cell guide printed w = −0.828226).
    #[test]
    fn pose_forms_quaternion_has_w_positive() {
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            -0.828226, -0.016141, -0.000309, -0.560161,
        ));
        let a_from_b = Isometry3::from_parts(Translation3::new(0.1, 0.2, 0.3), q);
        let f = PoseForms::from_isometry(&a_from_b);
        assert_eq!(f.quaternion_wxyz, [-q.w, -q.i, -q.j, -q.k]);
        assert!(f.quaternion_wxyz[0] > 0.0);
        // At w = 0 (a half turn) the first non-zero component is positive.
        let half = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.0, 0.0, -1.0, 0.0));
        let f = PoseForms::from_isometry(&Isometry3::from_parts(Translation3::identity(), half));
        assert_eq!(f.quaternion_wxyz, [0.0, 0.0, 1.0, 0.0]);
    }

    /// The four forms of one pose: a 90° turn about z (columns of the matrix are b's axes in a)
    /// and 1.5 m along x; a pure yaw, which the canonical ZYZ writes as ψ alone (θ = φ = 0).
    #[test]
    fn pose_forms_of_a_turn_about_z() {
        let a_from_b = Isometry3::new(
            nalgebra::Vector3::new(1.5, 0.0, -0.25),
            nalgebra::Vector3::z() * std::f64::consts::FRAC_PI_2,
        );
        let f = PoseForms::from_isometry(&a_from_b);
        assert_eq!(f.xyz_mm, [1500.0, 0.0, -250.0]);
        let want = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        for (row, want_row) in f.rotation.iter().zip(want) {
            for (v, w) in row.iter().zip(want_row) {
                assert!((v - w).abs() < 1e-15, "{:?}", f.rotation);
            }
        }
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for (q, w) in f.quaternion_wxyz.iter().zip([h, 0.0, 0.0, h]) {
            assert!((q - w).abs() < 1e-15, "{:?}", f.quaternion_wxyz);
        }
        assert!(f.zyz_deg[0] == 0.0 && f.zyz_deg[1] == 0.0 && (f.zyz_deg[2] - 90.0).abs() < 1e-12);
        let json = serde_json::to_string(&f).unwrap();
        assert!(
            json.starts_with(r#"{"quaternion_wxyz":["#) && json.contains(r#""zyz_deg":[0.0,0.0,"#)
        );
    }

    /// Millimetres become metres by a correctly rounded division: 0.3 mm is exactly the f64
    /// nearest 0.0003 m.
    #[test]
    fn to_isometry_divides_millimetres_exactly_rounded() {
        let pose = PoseMmDeg {
            xyz_mm: [0.3, 1303.3, -102.3],
            zyz_deg: [0.0; 3],
        };
        let t = pose.to_isometry().translation.vector;
        assert_eq!([t.x, t.y, t.z], [0.0003, 1.3033, -0.1023]);
    }
}
