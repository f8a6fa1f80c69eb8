//! Teach-point layouts: where the operator puts the handclasp points (b1 frame, metres).
//!
//! Every layout is centred on a given point and scaled by one `spread_m` (m):
//!
//! | layout | points | `spread_m` is |
//! |---|---|---|
//! | `tetrahedron` | the paper's advice: P1–P3 a horizontal equilateral triangle, P4 above its centroid (regular tetrahedron, random yaw); points 5.. uniform inside it | the edge length (the paper asks ≥ 1 m) |
//! | `random` | uniform in an axis-aligned cube | the cube's side |
//! | `planar` | uniform in a horizontal square, ±1 % of the side in height (near-planar: ill-conditioned for the 4-point methods) | the square's side |
//! | `clustered` | two small clusters (cubes of side 10 % of the spread) at ±spread/2 along a random horizontal direction, points alternating between them | the distance between the clusters |

use nalgebra::{Point3, Vector3};
use rand::Rng;
use std::fmt;

/// Height of the `planar` layout's slab as a fraction of its side.
pub const PLANAR_THICKNESS_REL: f64 = 0.02;
/// Side of a `clustered` layout's cluster cube as a fraction of the spread.
pub const CLUSTER_SIZE_REL: f64 = 0.1;

/// A teach-point layout (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Layout {
    /// The paper's advice: a regular tetrahedron with a horizontal base triangle.
    Tetrahedron,
    /// Uniform in a cube.
    Random,
    /// Near-planar: uniform in a thin horizontal slab.
    Planar,
    /// Two small clusters (nearly collinear point set).
    Clustered,
}

impl Layout {
    /// All layouts, in display order.
    pub const ALL: [Layout; 4] = [
        Layout::Tetrahedron,
        Layout::Random,
        Layout::Planar,
        Layout::Clustered,
    ];

    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Tetrahedron => "tetrahedron",
            Layout::Random => "random",
            Layout::Planar => "planar",
            Layout::Clustered => "clustered",
        }
    }

    /// Parses a name given by [`Layout::name`]; `None` otherwise.
    pub fn from_name(text: &str) -> Option<Layout> {
        let t = text.trim().to_ascii_lowercase();
        Layout::ALL.into_iter().find(|l| l.name() == t)
    }
}

impl fmt::Display for Layout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `n` teach points (m, b1 frame) of `layout` with size `spread_m` around `centre`, drawn from `rng`.
///
/// For `n = 0` the result is empty. Non-finite or negative `spread_m` gives non-finite points;
/// callers validate their specs (see [`crate::simulate::SessionSpec`]).
///
/// # Examples
/// ```
/// use sim_cell::layout::{teach_points, Layout};
/// let centre = nalgebra::Point3::new(0.5, 0.7, 0.6);
/// let pts = teach_points(Layout::Tetrahedron, 4, 1.0, &centre, &mut sim_cell::trial_rng(1, 0));
/// assert!((nalgebra::distance(&pts[0], &pts[3]) - 1.0).abs() < 1e-12); // edge = spread
/// ```
pub fn teach_points(
    layout: Layout,
    n: usize,
    spread_m: f64,
    centre: &Point3<f64>,
    rng: &mut impl Rng,
) -> Vec<Point3<f64>> {
    let mut out = vec![Point3::origin(); n];
    teach_points_into(layout, spread_m, centre, rng, &mut out);
    out
}

/// As [`teach_points`], filling `out` (its length is the point count); allocation-free.
pub fn teach_points_into(
    layout: Layout,
    spread_m: f64,
    centre: &Point3<f64>,
    rng: &mut impl Rng,
    out: &mut [Point3<f64>],
) {
    let s = spread_m;
    match layout {
        Layout::Tetrahedron => {
            let yaw: f64 = rng.random::<f64>() * std::f64::consts::TAU;
            let (sy, cy) = yaw.sin_cos();
            let r_circ = s / 3f64.sqrt();
            let h = s * (2.0f64 / 3.0).sqrt();
            let mut verts = [Vector3::zeros(); 4];
            // cos, sin of 0°, 120°, 240°.
            const TRIANGLE: [(f64, f64); 3] = [
                (1.0, 0.0),
                (-0.5, 0.866_025_403_784_438_6),
                (-0.5, -0.866_025_403_784_438_6),
            ];
            for (v, (ca, sa)) in verts.iter_mut().zip(TRIANGLE) {
                let (x, y) = (r_circ * ca, r_circ * sa);
                *v = Vector3::new(cy * x - sy * y, sy * x + cy * y, -h / 4.0);
            }
            verts[3] = Vector3::new(0.0, 0.0, 0.75 * h);
            for (i, p) in out.iter_mut().enumerate() {
                let v = if i < 4 {
                    verts[i]
                } else {
                    // Uniform in the tetrahedron: Dirichlet(1,1,1,1) barycentric weights.
                    let mut w = [0.0; 4];
                    let mut sum = 0.0;
                    for wk in &mut w {
                        *wk = -(1.0 - rng.random::<f64>()).ln();
                        sum += *wk;
                    }
                    verts
                        .iter()
                        .zip(&w)
                        .fold(Vector3::zeros(), |acc, (v, wk)| acc + v * (wk / sum))
                };
                *p = centre + v;
            }
        }
        Layout::Random => {
            for p in out.iter_mut() {
                *p = centre + cube(rng, s);
            }
        }
        Layout::Planar => {
            for p in out.iter_mut() {
                let x = (rng.random::<f64>() - 0.5) * s;
                let y = (rng.random::<f64>() - 0.5) * s;
                let z = (rng.random::<f64>() - 0.5) * s * PLANAR_THICKNESS_REL;
                *p = centre + Vector3::new(x, y, z);
            }
        }
        Layout::Clustered => {
            let yaw: f64 = rng.random::<f64>() * std::f64::consts::TAU;
            let dir = Vector3::new(yaw.cos(), yaw.sin(), 0.0) * (0.5 * s);
            for (i, p) in out.iter_mut().enumerate() {
                let c = if i % 2 == 0 { dir } else { -dir };
                *p = centre + c + cube(rng, s * CLUSTER_SIZE_REL);
            }
        }
    }
}

/// Uniform in a centred cube of side `side`.
fn cube(rng: &mut impl Rng, side: f64) -> Vector3<f64> {
    Vector3::new(
        (rng.random::<f64>() - 0.5) * side,
        (rng.random::<f64>() - 0.5) * side,
        (rng.random::<f64>() - 0.5) * side,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trial_rng;
    use calib_core::spread_singular_values;

    /// Round-off on metre-sized distances.
    const GEOM_TOL: f64 = 1e-12;

    #[test]
    fn tetrahedron_is_regular_with_horizontal_base_and_off_plane_apex() {
        let c = Point3::new(0.3, 0.8, 0.5);
        for seed in 0..20 {
            let p = teach_points(Layout::Tetrahedron, 4, 1.2, &c, &mut trial_rng(seed, 3));
            for i in 0..4 {
                for j in i + 1..4 {
                    assert!((nalgebra::distance(&p[i], &p[j]) - 1.2).abs() < GEOM_TOL);
                }
            }
            assert!((p[0].z - p[1].z).abs() < GEOM_TOL && (p[1].z - p[2].z).abs() < GEOM_TOL);
            assert!(p[3].z > p[0].z + 0.9);
            let centroid = p.iter().fold(Vector3::zeros(), |a, q| a + q.coords) / 4.0;
            assert!((centroid - c.coords).norm() < GEOM_TOL);
        }
    }

    #[test]
    fn extra_tetrahedron_points_lie_inside() {
        let c = Point3::origin();
        let p = teach_points(Layout::Tetrahedron, 12, 1.0, &c, &mut trial_rng(2, 0));
        let r_circ = (3.0f64 / 8.0).sqrt(); // circumradius of a unit regular tetrahedron
        for q in &p[4..] {
            assert!(q.coords.norm() < r_circ);
        }
    }

    #[test]
    fn layouts_have_the_documented_shape() {
        let c = Point3::new(1.0, 0.0, 0.5);
        let mut rng = trial_rng(11, 0);
        let planar = teach_points(Layout::Planar, 50, 1.0, &c, &mut rng);
        let sv = spread_singular_values(&planar);
        // Uniform slab: σ_z/σ_xy = PLANAR_THICKNESS_REL in expectation; 2× covers 50-point sampling.
        assert!(
            sv[2] / sv[1] < 2.0 * PLANAR_THICKNESS_REL,
            "planar sv {sv:?}"
        );
        let clustered = teach_points(Layout::Clustered, 50, 1.0, &c, &mut rng);
        let sv = spread_singular_values(&clustered);
        assert!(
            sv[1] / sv[0] < 2.0 * CLUSTER_SIZE_REL,
            "clustered sv {sv:?}"
        );
        let random = teach_points(Layout::Random, 50, 1.0, &c, &mut rng);
        for q in &random {
            assert!((q - c).amax() <= 0.5);
        }
        let sv = spread_singular_values(&random);
        assert!(sv[2] / sv[0] > 0.3, "random sv {sv:?}");
    }

    #[test]
    fn names_round_trip() {
        for l in Layout::ALL {
            assert_eq!(Layout::from_name(l.name()), Some(l));
        }
        assert_eq!(Layout::from_name("cube"), None);
    }

    #[test]
    fn same_rng_same_points() {
        let c = Point3::origin();
        for l in Layout::ALL {
            let a = teach_points(l, 7, 0.8, &c, &mut trial_rng(5, 9));
            let b = teach_points(l, 7, 0.8, &c, &mut trial_rng(5, 9));
            assert_eq!(a, b);
        }
    }

    proptest::proptest! {
        /// Every layout stays within its documented bounds of the centre, for any seed, spread
        /// and point count (tolerance: round-off on metre-sized coordinates).
        #[test]
        fn layouts_stay_within_their_bounds(
            seed in 0u64..1000, n in 1usize..20, spread in 0.01f64..3.0,
            cx in -2.0f64..2.0, cy in -2.0f64..2.0, cz in -1.0f64..2.0,
        ) {
            let c = Point3::new(cx, cy, cz);
            for l in Layout::ALL {
                let pts = teach_points(l, n, spread, &c, &mut trial_rng(seed, 0));
                proptest::prop_assert_eq!(pts.len(), n);
                let bound = match l {
                    // circumradius of a regular tetrahedron of edge s: s·√(3/8)
                    Layout::Tetrahedron => spread * (3.0f64 / 8.0).sqrt(),
                    Layout::Random => spread * 3f64.sqrt() / 2.0,
                    Layout::Planar => spread * (0.5f64 + PLANAR_THICKNESS_REL * PLANAR_THICKNESS_REL / 4.0).sqrt(),
                    Layout::Clustered => spread * (0.5 + CLUSTER_SIZE_REL * 3f64.sqrt() / 2.0),
                };
                for p in &pts {
                    proptest::prop_assert!((p - c).norm() <= bound + GEOM_TOL, "{l}: {p:?}");
                }
            }
        }
    }
}
