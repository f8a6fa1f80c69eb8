//! Every registration method on arbitrary f64 point sets (NaN, ±∞, huge and tiny values come from
//! the raw coordinates; small-integer millimetre coordinates make well-posed sets likely too) and
//! arbitrary mounts. Every Ok fit (and every `Some` of the allocation-free twins) must be a finite
//! proper rotation with a finite translation.
#![no_main]

use handclasp_fuzz as common;

use arbitrary::Arbitrary;
use calib_core::nalgebra;
use calib_core::{
    constrained_lsq, fit, fit_fast, leave_one_out, rigid_lsq, ConstrainedOptions, Method, Mount,
    MountPair, PointPairs,
};
use libfuzzer_sys::fuzz_target;
use nalgebra::Point3;

#[derive(Debug, Arbitrary)]
enum Coord {
    /// Any f64 bit pattern.
    Raw(f64),
    /// mm, as a controller writes them.
    Mm(i16),
}

impl Coord {
    fn m(&self) -> f64 {
        match *self {
            Coord::Raw(v) => v,
            Coord::Mm(v) => f64::from(v) * 1e-3,
        }
    }
}

#[derive(Debug, Arbitrary)]
enum MountIn {
    Floor,
    Ceiling,
    Wall,
    Tilt(f64, f64),
    TiltDeg(i8, i8),
}

impl MountIn {
    fn mount(&self) -> Mount {
        match *self {
            MountIn::Floor => Mount::Floor,
            MountIn::Ceiling => Mount::Ceiling,
            MountIn::Wall => Mount::Wall,
            MountIn::Tilt(rx, ry) => Mount::Tilt { rx, ry },
            MountIn::TiltDeg(rx, ry) => Mount::Tilt {
                rx: f64::from(rx).to_radians(),
                ry: f64::from(ry).to_radians(),
            },
        }
    }
}

#[derive(Debug, Arbitrary)]
struct Input {
    pairs: Vec<([Coord; 3], [Coord; 3])>,
    /// Optional: p_b1 = Rz(yaw)·p_b2 + t exactly (a consistent set) instead of free p_b1.
    rigid: Option<(i16, [i16; 3])>,
    robot1: MountIn,
    robot2: MountIn,
    weights: Option<Vec<f64>>,
}

fuzz_target!(|input: Input| {
    if input.pairs.len() > 24 {
        return;
    }
    let p_b2: Vec<Point3<f64>> = input
        .pairs
        .iter()
        .map(|(_, b)| Point3::new(b[0].m(), b[1].m(), b[2].m()))
        .collect();
    let p_b1: Vec<Point3<f64>> = match input.rigid {
        None => input
            .pairs
            .iter()
            .map(|(a, _)| Point3::new(a[0].m(), a[1].m(), a[2].m()))
            .collect(),
        Some((yaw, t)) => {
            let r = nalgebra::Rotation3::from_axis_angle(
                &nalgebra::Vector3::z_axis(),
                f64::from(yaw).to_radians() * 0.01,
            );
            let t =
                nalgebra::Vector3::new(f64::from(t[0]), f64::from(t[1]), f64::from(t[2])) * 1e-3;
            p_b2.iter().map(|p| r * p + t).collect()
        }
    };
    let pairs = PointPairs::new(p_b1.clone(), p_b2.clone()).expect("equal lengths");
    let mounts = MountPair {
        robot1: input.robot1.mount(),
        robot2: input.robot2.mount(),
    };
    for method in Method::ALL {
        if let Ok(f) = fit(&pairs, method, &mounts) {
            common::assert_finite_proper(&f.b1_from_b2, method.name());
        }
        if let Some(x) = fit_fast(method, &mounts, &p_b1, &p_b2) {
            common::assert_finite_proper(&x, &format!("{} (fast)", method.name()));
        }
        if pairs.len() <= 8 {
            let _ = leave_one_out(&pairs, method, &mounts);
        }
    }
    if let Some(w) = &input.weights {
        let mut w = w.clone();
        w.resize(pairs.len(), 1.0);
        if let Ok(f) = rigid_lsq(&pairs, Some(&w)) {
            common::assert_finite_proper(&f.b1_from_b2, "lsq weighted");
        }
        let options = ConstrainedOptions { weights: Some(w) };
        if let Ok(f) = constrained_lsq(&pairs, &mounts, &options) {
            common::assert_finite_proper(&f.b1_from_b2, "constrained weighted");
        }
    }
});
