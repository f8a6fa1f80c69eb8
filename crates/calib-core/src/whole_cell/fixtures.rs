//! Test and bench fixtures, not part of the API (hidden from the docs, compiled only for the
//! crate's tests and with the `fixtures` feature): the shipped robots in the shipped cells'
//! placements, truths drawn from tolerances, and simulated observations (built from
//! `kinematics` directly: calib-core cannot depend on sim-cell). Used by the module tests and by
//! `benches/whole_cell.rs` (which gets the feature from calib-core's dev-dependency on itself).

use crate::Robot;
use kinematics::{
    ik_tip_position, rotation_from_zyz, tip_joint_jacobian_true, true_base_from_tip, IkOptions,
    RobotModel,
};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::{
    CellEstimate, CellProblem, CellRobot, ConfigPair, Noise3, Observation, ObservationKind,
    Tolerance, Tool,
};

const VA1400: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../robots/va1400.urdf"
));
const HP20: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../robots/hp20.urdf"
));

/// The shipped cells (cells/*.toml), named by robot 2's mount (robot 1 is on the floor):
/// placement and teach centre.
#[derive(Debug, Clone, Copy)]
pub enum Cell {
    /// Floor–floor: robot 2 on the floor too.
    Floor,
    /// Floor–wall: robot 2 on a wall.
    Wall,
    /// Floor–ceiling: robot 2 hanging from the ceiling.
    Ceiling,
}

impl Cell {
    /// `(b1_from_b2, teach centre in b1)` from cells/*.toml.
    fn placement(self) -> (Isometry3<f64>, Point3<f64>) {
        let (xyz_mm, zyz_deg, centre_mm) = match self {
            Cell::Floor => (
                [37.9, 1476.5, 54.5],
                [-0.001, 0.001, -44.5],
                [150.0, 690.0, 500.0],
            ),
            Cell::Wall => (
                [1303.3, -102.3, 1386.3],
                [180.0, 89.874, -179.997],
                [475.0, -50.0, 995.0],
            ),
            Cell::Ceiling => (
                [1500.1, 500.0, 1499.9],
                [0.0, 180.001, 0.001],
                [750.0, 250.0, 720.0],
            ),
        };
        let r = rotation_from_zyz(zyz_deg.map(f64::to_radians));
        let x = Isometry3::from_parts(
            Translation3::new(xyz_mm[0] * 1e-3, xyz_mm[1] * 1e-3, xyz_mm[2] * 1e-3),
            UnitQuaternion::from_rotation_matrix(&r),
        );
        (x, Point3::from(Vector3::from(centre_mm) * 1e-3))
    }
}

/// A simulated cell: the problem's robots, the true placement and corrections.
pub struct SimCell {
    /// Robot 1 (VA1400, base frame b1) with its nominal model, tools and tolerances.
    pub robot1: CellRobot,
    /// Robot 2 (HP20) with its nominal model, tools and tolerances.
    pub robot2: CellRobot,
    /// The true placement and kinematic corrections.
    pub truth: CellEstimate,
    /// Centre of the teach volume, m, b1 frame.
    pub centre_b1: Point3<f64>,
}

/// The two robots (VA1400 tip 150 mm, HP20 tip 120 mm; optionally a second tool on robot 1, a
/// reflector at (40, 0, 60) mm) with tolerances `tol`, and a truth whose every fitted
/// parameter is drawn from `U(±tolerance)` (seeded). Panics only if a shipped URDF fails to
/// parse (a build defect, not an input).
pub fn sim_cell(cell: Cell, tol: Tolerance, second_tool: bool, seed: u64) -> SimCell {
    let (x, centre_b1) = cell.placement();
    let g1 = Vector3::new(0.0, 0.0, -9.81);
    let mut tools1 = vec![Tool {
        name: "tip".into(),
        flange_from_tip: Vector3::new(0.0, 0.0, 0.15),
    }];
    if second_tool {
        tools1.push(Tool {
            name: "reflector".into(),
            flange_from_tip: Vector3::new(0.04, 0.0, 0.06),
        });
    }
    let robot1 = CellRobot {
        model: RobotModel::from_urdf_str(VA1400, "tool0").expect("shipped URDF"),
        tools: tools1,
        g_base: g1,
        tolerance: tol,
        shared_joints: 0,
    };
    let robot2 = CellRobot {
        model: RobotModel::from_urdf_str(HP20, "tool0").expect("shipped URDF"),
        tools: vec![Tool {
            name: "tip".into(),
            flange_from_tip: Vector3::new(0.0, 0.0, 0.12),
        }],
        g_base: x.rotation.inverse() * g1,
        tolerance: tol,
        shared_joints: 0,
    };
    let problem = CellProblem {
        robot1: robot1.clone(),
        robot2: robot2.clone(),
        observations: vec![],
        trackers: vec![],
        planes: vec![],
        contacts: vec![],
        placement_prior: None,
        other_arm_q: Default::default(),
    };
    let mut truth = CellEstimate::nominal(&problem, x);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for r in [Robot::One, Robot::Two] {
        let rb = problem.robot(r);
        let params = rb.fitted_params();
        let corr = if r == Robot::One {
            &mut truth.robot1
        } else {
            &mut truth.robot2
        };
        for p in params {
            let tol = rb.prior_sigma(p) * 3f64.sqrt();
            corr.errors.set(p, rng.random_range(-tol..=tol));
        }
        for t in &mut corr.tool_tip_m {
            let tol = rb.tolerance.tip_m;
            *t = Vector3::from_fn(|_, _| rng.random_range(-tol..=tol));
        }
    }
    SimCell {
        robot1,
        robot2,
        truth,
        centre_b1,
    }
}

impl SimCell {
    /// An empty problem with these robots.
    pub fn problem(&self) -> CellProblem {
        CellProblem {
            robot1: self.robot1.clone(),
            robot2: self.robot2.clone(),
            observations: vec![],
            trackers: vec![],
            planes: vec![],
            contacts: vec![],
            placement_prior: None,
            other_arm_q: Default::default(),
        }
    }

    /// True pose of `robot`'s tool at `q` (`base_from_tip`), its own base frame.
    pub fn true_pose(&self, robot: Robot, tool: usize, q: &[f64]) -> Isometry3<f64> {
        let rb = if robot == Robot::One {
            &self.robot1
        } else {
            &self.robot2
        };
        let e = self.truth.robot(robot).errors_for_tool(tool);
        true_base_from_tip(
            &rb.model,
            &e,
            q,
            &rb.tools[tool].flange_from_tip,
            &rb.g_base,
        )
        .expect("valid")
    }

    /// True tip of `robot`'s tool at `q`, its own base frame.
    pub fn true_tip(&self, robot: Robot, tool: usize, q: &[f64]) -> Vector3<f64> {
        self.true_pose(robot, tool, q).translation.vector
    }

    /// Joints putting robot `robot`'s TRUE tool `tool` at `target` (its base frame) with the
    /// flange z along `axis`: nominal IK, then Newton on the true model. `None` if unreachable.
    pub fn solve_true(
        &self,
        robot: Robot,
        tool: usize,
        target: &Point3<f64>,
        axis: Unit<Vector3<f64>>,
    ) -> Option<Vec<f64>> {
        let rb = if robot == Robot::One {
            &self.robot1
        } else {
            &self.robot2
        };
        let fft = rb.tools[tool].flange_from_tip;
        let opts = IkOptions {
            tool_axis_base: Some(axis),
            tolerance_m: 1e-9,
            axis_tolerance_rad: 1e-7,
            restarts: 6,
            ..IkOptions::default()
        };
        let sol = ik_tip_position(&rb.model, target, &fft, &opts).ok()?;
        if !sol.reachable() {
            return None;
        }
        let mut q = sol.q;
        let e = self.truth.robot(robot).errors_for_tool(tool);
        for _ in 0..20 {
            let tip = true_base_from_tip(&rb.model, &e, &q, &fft, &rb.g_base).ok()?;
            let err = target.coords - tip.translation.vector;
            if err.norm() < 1e-11 {
                return rb.model.check_q(&q).ok().map(|_| q);
            }
            let j = tip_joint_jacobian_true(&rb.model, &e, &q, &fft, &rb.g_base).ok()?;
            let jjt: Matrix3<f64> = &j * j.transpose();
            let dq = j.transpose() * (jjt.try_inverse()? * err);
            for (qi, d) in q.iter_mut().zip(dq.iter()) {
                *qi += d;
            }
        }
        None
    }

    /// A handclasp pair whose TRUE tips differ by `noise_b1` (m, b1 axes): robot 1 reaches a
    /// point near the centre (±spread/2 per axis), robot 2 meets it head-on. `None` if
    /// unreachable.
    pub fn draw_pair(
        &self,
        rng: &mut ChaCha8Rng,
        spread_m: f64,
        tool1: usize,
        noise_b1: Vector3<f64>,
    ) -> Option<ConfigPair> {
        let x = &self.truth.b1_from_b2;
        let p = self.centre_b1 + Vector3::from_fn(|_, _| rng.random_range(-0.5..0.5)) * spread_m;
        let toward2 = (x.translation.vector - p.coords).normalize();
        let tilt = Vector3::from_fn(|_, _| rng.random_range(-0.5..0.5));
        let a1 = Unit::new_normalize(toward2 + tilt);
        let q1 = self.solve_true(Robot::One, tool1, &p, a1)?;
        let t1 = self.true_tip(Robot::One, tool1, &q1);
        let target2 = x.inverse() * Point3::from(t1 + noise_b1);
        let a2 = Unit::new_normalize(x.rotation.inverse() * (-a1.into_inner()));
        let q2 = self.solve_true(Robot::Two, 0, &target2, a2)?;
        Some(ConfigPair {
            q1,
            q2,
            tool1,
            tool2: 0,
        })
    }

    /// `n` coincident observations (rows 1..n) with isotropic noise σ, seeded.
    pub fn coincident(&self, n: usize, sigma_m: f64, spread_m: f64, seed: u64) -> Vec<Observation> {
        self.coincident_with_blunders(n, sigma_m, spread_m, seed, &[])
    }

    /// As [`SimCell::coincident`], with a gross error of the given size (m, random direction)
    /// added to the alignment of each listed (1-based) row.
    pub fn coincident_with_blunders(
        &self,
        n: usize,
        sigma_m: f64,
        spread_m: f64,
        seed: u64,
        blunders: &[(usize, f64)],
    ) -> Vec<Observation> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let mut noise = Vector3::from_fn(|_, _| {
                let z: f64 = StandardNormal.sample(&mut rng);
                z * sigma_m
            });
            if let Some(&(_, size)) = blunders.iter().find(|b| b.0 == out.len() + 1) {
                let d = Vector3::from_fn(|_, _| StandardNormal.sample(&mut rng));
                noise += d.normalize() * size;
            }
            if let Some(p) = self.draw_pair(&mut rng, spread_m, 0, noise) {
                out.push(Observation {
                    row: out.len() + 1,
                    kind: ObservationKind::Coincident {
                        q1: p.q1,
                        q2: p.q2,
                        tool1: 0,
                        tool2: 0,
                        noise: Noise3::Isotropic { sigma_m },
                    },
                });
            }
        }
        out
    }

    /// `n` noise-free evaluation pairs, seeded.
    pub fn eval_pairs(&self, n: usize, spread_m: f64, seed: u64) -> Vec<ConfigPair> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            if let Some(p) = self.draw_pair(&mut rng, spread_m, 0, Vector3::zeros()) {
                out.push(p);
            }
        }
        out
    }
}
