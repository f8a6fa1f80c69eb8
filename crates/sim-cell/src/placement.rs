//! The paper's three cells (Gan et al. 2014, Table 1): true `b1_from_b2` and the centre of the
//! common workspace where the teach points go. Needs no robot model (geometry mode uses it directly;
//! the shipped cells, [`handclasp_cell::Cell::shipped`], hold the same placements: tested here).
//!
//! Table 1's placements are used as published; the centres were checked against the URDFs in
//! `robots/` (both robots reach a 1 m tetrahedron around them head-on; see the sim-cell README).

use calib_core::{Mount, MountPair, PoseMmDeg};
use nalgebra::{Isometry3, Point3};

/// One of the paper's cells: mounts, true placement and teach-point centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// The robots' mounts.
    pub mounts: MountPair,
    /// Position of base 2 in base 1, mm (Table 1).
    pub xyz_mm: [f64; 3],
    /// Orientation of base 2 in base 1, ZYZ degrees, `R = Rz(φ)·Ry(θ)·Rz(ψ)` (Table 1).
    pub zyz_deg: [f64; 3],
    /// Centre of the teach points, mm, base 1 frame (about the midpoint of the two shoulders;
    /// the shipped cells' `[teach] centre_mm`).
    pub centre_mm: [f64; 3],
}

impl Placement {
    /// `b1_from_b2` (m, rad).
    pub fn b1_from_b2(&self) -> Isometry3<f64> {
        PoseMmDeg {
            xyz_mm: self.xyz_mm,
            zyz_deg: self.zyz_deg,
        }
        .to_isometry()
    }

    /// The teach-point centre, m, base 1 frame.
    pub fn centre_b1(&self) -> Point3<f64> {
        Point3::new(
            self.centre_mm[0] / 1000.0,
            self.centre_mm[1] / 1000.0,
            self.centre_mm[2] / 1000.0,
        )
    }

    /// The file-name-safe label of the mount pair: `floor-floor`, `floor-wall`, `floor-ceiling`,
    /// or `MOUNT1-MOUNT2` for other pairs.
    pub fn label(&self) -> String {
        mounts_label(&self.mounts)
    }
}

/// Label of a mount pair for files and tables (`floor-wall`; tilts as `tilt(rx,ry)` in degrees).
pub fn mounts_label(m: &MountPair) -> String {
    let one = |m: &Mount| match m {
        Mount::Tilt { rx, ry } => format!("tilt({},{})", rx.to_degrees(), ry.to_degrees()),
        other => other.to_string(),
    };
    format!("{}-{}", one(&m.robot1), one(&m.robot2))
}

/// Floor–floor (Table 1): base 2 1.48 m along y, turned −44.5° about z.
pub const FLOOR_FLOOR: Placement = Placement {
    mounts: MountPair {
        robot1: Mount::Floor,
        robot2: Mount::Floor,
    },
    xyz_mm: [37.9, 1476.5, 54.5],
    zyz_deg: [-0.001, 0.001, -44.5],
    centre_mm: [150.0, 690.0, 500.0],
};

/// Floor–wall (Table 1): base 2 on a wall 1.39 m up, its z axis horizontal.
pub const FLOOR_WALL: Placement = Placement {
    mounts: MountPair {
        robot1: Mount::Floor,
        robot2: Mount::Wall,
    },
    xyz_mm: [1303.3, -102.3, 1386.3],
    zyz_deg: [180.0, 89.874, -179.997],
    centre_mm: [475.0, -50.0, 995.0],
};

/// Floor–ceiling (Table 1): base 2 hanging 1.5 m up, 1.58 m away horizontally.
pub const FLOOR_CEILING: Placement = Placement {
    mounts: MountPair {
        robot1: Mount::Floor,
        robot2: Mount::Ceiling,
    },
    xyz_mm: [1500.1, 500.0, 1499.9],
    zyz_deg: [0.0, 180.001, 0.001],
    centre_mm: [750.0, 250.0, 720.0],
};

/// The three paper cells, in the order floor-floor, floor-wall, floor-ceiling.
pub const PAPER: [Placement; 3] = [FLOOR_FLOOR, FLOOR_WALL, FLOOR_CEILING];

/// The paper cell with these mounts, if any.
pub fn paper_placement(mounts: &MountPair) -> Option<Placement> {
    PAPER.into_iter().find(|p| &p.mounts == mounts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn paper_placements_match_their_mounts() {
        // Robot 2's z axis in b1: up for floor, down for ceiling, horizontal for wall (within 0.2°).
        let z = |p: &Placement| p.b1_from_b2().rotation * Vector3::z();
        assert!(z(&FLOOR_FLOOR).z > (0.2f64).to_radians().cos());
        assert!(z(&FLOOR_CEILING).z < -(0.2f64).to_radians().cos());
        assert!(z(&FLOOR_WALL).z.abs() < (0.2f64).to_radians().sin());
        assert_eq!(FLOOR_WALL.label(), "floor-wall");
        assert_eq!(
            paper_placement(&MountPair::floor_ceiling()),
            Some(FLOOR_CEILING)
        );
    }
}

#[cfg(test)]
mod shipped_cells {
    use super::*;
    use handclasp_cell::Cell;

    /// The geometry-mode placements are the shipped cells' (same truth, same teach centre), to 0.1 mm.
    const SAME_CELL_TOL_M: f64 = 1e-4;

    #[test]
    fn placements_match_the_shipped_cells() {
        for p in PAPER {
            let cell = Cell::shipped(p.mounts).unwrap();
            assert!(
                (cell.b1_from_b2.translation.vector - p.b1_from_b2().translation.vector).amax()
                    < SAME_CELL_TOL_M
            );
            assert!(cell.b1_from_b2.rotation.angle_to(&p.b1_from_b2().rotation) < 1e-9);
            assert!(
                (cell.centre_b1 - p.centre_b1()).amax() < SAME_CELL_TOL_M,
                "{}",
                p.label()
            );
            assert_eq!(cell.mounts(), p.mounts);
        }
    }
}
