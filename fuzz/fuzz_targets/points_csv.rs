//! The points CSV reader of `handclasp calibrate` (`calib_core::parse_points_csv`), then what
//! calibrate does next: the duplicate and unit-consistency checks and an `lsq` fit, whose Ok
//! result must be a finite proper rotation.
#![no_main]

use handclasp_fuzz as common;

use std::path::Path;

use calib_core::{fit, parse_points_csv, Method, MountPair};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(pairs) = parse_points_csv(text, Path::new("fuzz.csv")) else {
        return;
    };
    if pairs.check_duplicates().is_err() || pairs.check_consistency("fuzz.csv").is_err() {
        return;
    }
    if let Ok(f) = fit(&pairs, Method::Lsq, &MountPair::floor_floor()) {
        common::assert_finite_proper(&f.b1_from_b2, "lsq on a parsed points CSV");
    }
});
