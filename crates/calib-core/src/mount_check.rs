//! Does the installation constraint agree with the points? An F-test of the installation-constrained
//! least-squares fit against the free rigid fit.
//!
//! A constrained fit always returns a transform, even when the mounts it was given are wrong (a
//! wall robot declared on the floor, a tilt with the wrong sign): its residuals then grow by orders
//! of magnitude, and its transform is nonsense. A mount that is right in name but off by a small
//! real tilt (the paper's floor–wall cell is 0.126° out of its wall family) shows the same way, only
//! smaller. Both are caught by comparing the residual sums of squares of the two nested fits:
//!
//! `F = ((RSS_c − RSS_f) / c) / (RSS_f / (3n − 6))`, with `c = 6 − k` the number of rotation
//! degrees of freedom the mounts remove (`k` the constrained fit's parameters), distributed as
//! `F(c, 3n − 6)` when the constraint holds and the point noise is isotropic and Gaussian.

use crate::error::CalibError;
use crate::points::PointPairs;
use crate::registration::{constrained_lsq, rigid_lsq, ConstrainedOptions, MountPair};

/// Below this p-value the mounts are reported as disagreeing with the points. Small on purpose: a
/// warning that fires on one calibration in a thousand of a correctly mounted cell.
pub const MOUNT_CHECK_ALPHA: f64 = 1e-3;

/// Smallest residual sum of squares per coordinate taken as noise, m² ((1 nm)²): with exact data
/// both fits are at round-off and their ratio means nothing.
const RSS_FLOOR_PER_COORD_M2: f64 = 1e-18;

/// The F-test of the mounts against the points (see the module doc). Serialises (serde) with
/// the fields' SI units.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MountCheck {
    /// Residual sum of squares of the installation-constrained fit, m².
    pub rss_constrained_m2: f64,
    /// Residual sum of squares of the free rigid fit, m².
    pub rss_free_m2: f64,
    /// Rotation degrees of freedom that the mounts remove (1 for the paper's wall family, 2 when
    /// both gravity directions are known).
    pub constraints: usize,
    /// Residual degrees of freedom of the free fit, `3n − 6`.
    pub dof_free: usize,
    /// The F statistic.
    pub f_statistic: f64,
    /// Its upper tail probability under `F(constraints, dof_free)`.
    pub p_value: f64,
    /// Angle between the constrained and the free fit's rotations, rad: how far the points pull
    /// the rotation out of the mounts' family.
    pub rotation_gap_rad: f64,
}

impl MountCheck {
    /// `true` when the points do not contradict the mounts at level [`MOUNT_CHECK_ALPHA`].
    pub fn consistent(&self) -> bool {
        self.p_value >= MOUNT_CHECK_ALPHA
    }
}

/// Tests `mounts` against the points: fits both [`constrained_lsq`] and [`rigid_lsq`] and compares
/// them (module doc). Needs 3 non-collinear points and more coordinates than the free fit has
/// parameters (n ≥ 3 gives 3n − 6 ≥ 3); the errors are those of the two fits.
///
/// # Examples
/// ```
/// use calib_core::{mount_check, MountPair, PointPairs};
/// use nalgebra::{Isometry3, Point3, Vector3};
/// // Robot 2 on the floor, turned 30° about z: a floor–floor cell, exactly.
/// let b1_from_b2 = Isometry3::new(Vector3::new(1.0, 0.5, 0.0), Vector3::z() * 30f64.to_radians());
/// let p_b2: Vec<Point3<f64>> = [[0.0, 0.0, 0.5], [1.0, 0.0, 0.6], [0.0, 1.0, 0.4], [0.5, 0.5, 1.5]]
///     .iter()
///     .map(|p| Point3::new(p[0], p[1], p[2]))
///     .collect();
/// let p_b1 = p_b2.iter().map(|p| b1_from_b2 * p).collect();
/// let pairs = PointPairs::new(p_b1, p_b2).unwrap();
/// assert!(mount_check(&pairs, &MountPair::floor_floor()).unwrap().consistent());
/// // The same points declared floor–ceiling: the constraint cannot hold.
/// let check = mount_check(&pairs, &MountPair::floor_ceiling()).unwrap();
/// assert!(!check.consistent());
/// assert!(check.rotation_gap_rad.to_degrees() > 90.0);
/// ```
pub fn mount_check(pairs: &PointPairs, mounts: &MountPair) -> Result<MountCheck, CalibError> {
    let constrained = constrained_lsq(pairs, mounts, &ConstrainedOptions::default())?;
    let free = rigid_lsq(pairs, None)?;
    let rss = |f: &crate::Fit| f.residuals.iter().map(|r| r.norm_squared()).sum::<f64>();
    let n_coords = 3 * pairs.len();
    let floor = RSS_FLOOR_PER_COORD_M2 * n_coords as f64;
    let (rss_c, rss_f) = (rss(&constrained), rss(&free));
    let dof_free = n_coords.saturating_sub(6);
    // Both gravity directions known: only the yaw is free (2 removed). One robot on the paper's
    // wall family: two free angles (1 removed). Both on it is an error of `constrained_lsq`.
    let known = |m: &crate::Mount| m.level_from_base().is_some();
    let constraints = if known(&mounts.robot1) && known(&mounts.robot2) {
        2
    } else {
        1
    };
    let (f_statistic, p_value) = if dof_free == 0 {
        (0.0, 1.0)
    } else {
        let num = (rss_c - rss_f).max(0.0) / constraints as f64;
        let den = rss_f.max(floor) / dof_free as f64;
        let f = num / den;
        let p = crate::stats::f_sf(f, constraints, dof_free);
        (f, p)
    };
    Ok(MountCheck {
        rss_constrained_m2: rss_c,
        rss_free_m2: rss_f,
        constraints,
        dof_free,
        f_statistic,
        p_value,
        rotation_gap_rad: constrained
            .b1_from_b2
            .rotation
            .angle_to(&free.b1_from_b2.rotation),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registration::Mount;
    use nalgebra::{Isometry3, Point3, Vector3};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A floor–floor cell turned `tilt_deg` about b2's x, with `sigma` m of isotropic point noise.
    fn cell(seed: u64, n: usize, tilt_deg: f64, sigma: f64) -> PointPairs {
        let b1_from_b2 = Isometry3::new(Vector3::new(1.2, -0.3, 0.1), Vector3::z() * 0.7)
            * Isometry3::rotation(Vector3::x() * tilt_deg.to_radians());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let u = rand_distr::Uniform::new(-0.5, 0.5).unwrap();
        let noise = Normal::new(0.0, sigma).unwrap();
        let p_b2: Vec<Point3<f64>> = (0..n)
            .map(|_| Point3::new(u.sample(&mut rng), u.sample(&mut rng), u.sample(&mut rng)))
            .collect();
        let p_b1 = p_b2
            .iter()
            .map(|p| {
                b1_from_b2 * p
                    + Vector3::new(
                        noise.sample(&mut rng),
                        noise.sample(&mut rng),
                        noise.sample(&mut rng),
                    )
            })
            .collect();
        PointPairs::new(p_b1, p_b2).unwrap()
    }

    #[test]
    fn right_mounts_pass_and_false_alarms_are_rare() {
        // 200 correctly mounted cells at 0.5 mm noise: at α = 1e-3 expect 0.2 alarms; allow 2.
        let alarms = (0..200)
            .filter(|&s| {
                !mount_check(&cell(s, 8, 0.0, 5e-4), &MountPair::floor_floor())
                    .unwrap()
                    .consistent()
            })
            .count();
        assert!(alarms <= 2, "{alarms} false alarms in 200");
    }

    #[test]
    fn a_wrong_mount_is_caught_with_its_gap() {
        let pairs = cell(1, 6, 0.0, 5e-4);
        let wall = MountPair {
            robot1: Mount::Floor,
            robot2: Mount::Tilt {
                rx: 0.0,
                ry: -std::f64::consts::FRAC_PI_2,
            },
        };
        let check = mount_check(&pairs, &wall).unwrap();
        assert!(!check.consistent(), "{check:?}");
        assert!(
            (check.rotation_gap_rad.to_degrees() - 90.0).abs() < 1.0,
            "{check:?}"
        );
        assert_eq!((check.constraints, check.dof_free), (2, 12));
    }

    #[test]
    fn a_small_real_tilt_is_seen_with_enough_points() {
        // 0.126° (the paper's floor–wall cell) at 0.3 mm noise over a 1 m cube, 40 points.
        let check = mount_check(&cell(3, 40, 0.126, 3e-4), &MountPair::floor_floor()).unwrap();
        assert!(!check.consistent(), "{check:?}");
        assert!(
            (check.rotation_gap_rad.to_degrees() - 0.126).abs() < 0.03,
            "{check:?}"
        );
    }

    #[test]
    fn exact_data_is_consistent() {
        let check = mount_check(&cell(4, 5, 0.0, 0.0), &MountPair::floor_floor()).unwrap();
        assert!(check.consistent(), "{check:?}");
    }
}
