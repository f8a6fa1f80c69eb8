//! Geometry-mode trials: the teach points and noise of a trial ([`GeometrySpec`],
//! [`draw_geometry`]), fitted by calib-core's allocation-free [`fit_fast`] and measured by its
//! [`TrialErrors`] against the precomputed truth ([`ErotTruth`]).

use calib_core::{fit_fast, zyz_from_rotation, ErotTruth, Method, MountPair, TrialErrors};
use nalgebra::{Isometry3, Point3, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

use super::MAX_GEOMETRY_POINTS;
use crate::error::SimError;
use crate::layout::{teach_points_into, Layout};
use crate::placement::paper_placement;

/// One geometry-mode trial's setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeometrySpec {
    /// The mounts (used by the `paper` and `constrained` methods).
    pub mounts: MountPair,
    /// The true `b1_from_b2` (m, rad).
    pub b1_from_b2: Isometry3<f64>,
    /// Teach-point layout.
    pub layout: Layout,
    /// Number of teach points (1..=[`MAX_GEOMETRY_POINTS`]).
    pub n: usize,
    /// Layout size, m (see [`crate::layout`]).
    pub spread_m: f64,
    /// Centre of the teach points, m, b1 frame.
    pub centre_b1: Point3<f64>,
    /// σ of the operator's alignment error per b1 axis, m (≥ 0).
    pub sigma_m: Vector3<f64>,
}

impl GeometrySpec {
    /// The spec for one of the paper's cells (true placement and centre from
    /// [`crate::placement`]), isotropic noise `sigma_m`. `None` for mounts the paper did not use.
    pub fn paper(
        mounts: &MountPair,
        layout: Layout,
        n: usize,
        spread_m: f64,
        sigma_m: f64,
    ) -> Option<Self> {
        let p = paper_placement(mounts)?;
        Some(GeometrySpec {
            mounts: *mounts,
            b1_from_b2: p.b1_from_b2(),
            layout,
            n,
            spread_m,
            centre_b1: p.centre_b1(),
            sigma_m: Vector3::repeat(sigma_m),
        })
    }

    /// The true rotation's ZYZ angles (eq 32, rad), as e_rot compares against.
    pub fn zyz_true(&self) -> [f64; 3] {
        zyz_from_rotation(&self.b1_from_b2.rotation.to_rotation_matrix())
    }

    /// The truth's eq 33 reading ([`ErotTruth::new`] of [`GeometrySpec::zyz_true`]).
    pub fn erot_truth(&self) -> ErotTruth {
        ErotTruth::new(self.zyz_true())
    }

    /// Checks the spec: point count, finite non-negative spread and σ.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.n == 0 || self.n > MAX_GEOMETRY_POINTS {
            return Err(SimError::InvalidInput(format!(
                "number of points {} is out of range: use 1..={MAX_GEOMETRY_POINTS} (4 or more for every method)",
                self.n
            )));
        }
        if !(self.spread_m.is_finite() && self.spread_m > 0.0) {
            return Err(SimError::InvalidInput(format!(
                "spread {} m must be a positive length (e.g. 1.0 m)",
                self.spread_m
            )));
        }
        if !self.sigma_m.iter().all(|s| s.is_finite() && *s >= 0.0) {
            return Err(SimError::InvalidInput(format!(
                "alignment σ {:?} m must be finite and ≥ 0",
                self.sigma_m.as_slice()
            )));
        }
        if !self.centre_b1.iter().all(|c| c.is_finite()) {
            return Err(SimError::InvalidInput("centre must be finite".into()));
        }
        Ok(())
    }
}

/// Draws one trial's points: `p_b1` the teach points (the true position of robot 1's tip) and
/// `p_b2 = b2_from_b1·(p_b1 + ε)` with `ε ~ N(0, diag(σ²))` the alignment error (b1 axes).
/// The slices' length is the point count (must be equal). Allocation-free.
pub fn draw_geometry(
    spec: &GeometrySpec,
    rng: &mut impl Rng,
    p_b1: &mut [Point3<f64>],
    p_b2: &mut [Point3<f64>],
) {
    teach_points_into(spec.layout, spec.spread_m, &spec.centre_b1, rng, p_b1);
    let b2_from_b1 = spec.b1_from_b2.inverse();
    for (a, b) in p_b1.iter().zip(p_b2.iter_mut()) {
        let eps = Vector3::new(
            spec.sigma_m.x * rng.sample::<f64, _>(StandardNormal),
            spec.sigma_m.y * rng.sample::<f64, _>(StandardNormal),
            spec.sigma_m.z * rng.sample::<f64, _>(StandardNormal),
        );
        *b = b2_from_b1 * (a + eps);
    }
}

/// One geometry-mode trial of one method: draws the points ([`draw_geometry`]) and fits them.
/// `Ok(None)` when the fit fails (degenerate points for the method); errors for an invalid spec.
///
/// # Examples
/// ```
/// use sim_cell::{layout::Layout, sweep::{geometry_trial, GeometrySpec}, trial_rng};
/// use calib_core::{Method, MountPair};
/// let spec = GeometrySpec::paper(&MountPair::floor_floor(), Layout::Tetrahedron, 4, 1.0, 0.5e-3).unwrap();
/// let e = geometry_trial(&spec, Method::Paper, &mut trial_rng(7, 0)).unwrap().unwrap();
/// assert!(e.e_tran < 5e-3); // m
/// ```
pub fn geometry_trial(
    spec: &GeometrySpec,
    method: Method,
    rng: &mut impl Rng,
) -> Result<Option<TrialErrors>, SimError> {
    spec.validate()?;
    const SMALL: usize = 16;
    if spec.n <= SMALL {
        let mut buf1 = [Point3::origin(); SMALL];
        let mut buf2 = [Point3::origin(); SMALL];
        Ok(geometry_trial_into(
            spec,
            &spec.erot_truth(),
            method,
            rng,
            &mut buf1[..spec.n],
            &mut buf2[..spec.n],
        ))
    } else {
        let mut buf1 = vec![Point3::origin(); spec.n];
        let mut buf2 = vec![Point3::origin(); spec.n];
        Ok(geometry_trial_into(
            spec,
            &spec.erot_truth(),
            method,
            rng,
            &mut buf1,
            &mut buf2,
        ))
    }
}

/// [`geometry_trial`] without validation, drawing into caller buffers (their length is the
/// point count; the spec's `n` is not used), with the truth's eq 33 reading precomputed
/// ([`GeometrySpec::erot_truth`]): allocation-free, for hot loops of a validated spec.
/// `None` when the fit fails.
pub fn geometry_trial_into(
    spec: &GeometrySpec,
    erot_truth: &ErotTruth,
    method: Method,
    rng: &mut impl Rng,
    p_b1: &mut [Point3<f64>],
    p_b2: &mut [Point3<f64>],
) -> Option<TrialErrors> {
    draw_geometry(spec, rng, p_b1, p_b2);
    fit_fast(method, &spec.mounts, p_b1, p_b2)
        .map(|est| TrialErrors::between_fast(&spec.b1_from_b2, erot_truth, &est))
}
