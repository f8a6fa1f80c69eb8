//! Property test (issue 10, "Fuzzing and properties"): a seeded sweep writes byte-identical CSV
//! with one and two worker threads (rayon pools built explicitly). The fixed-input version is a
//! unit test in `sweep/tests.rs`; this one draws the sweep. (The cell TOML round-trip property is
//! handclasp-cell's `tests/properties.rs`.)

use calib_core::{Method, MountPair};
use proptest::prelude::*;
use sim_cell::sweep::{
    run_sweep, summarize_cells, write_summary_csv, write_trials_csv, Mode, SweepConfig,
};
use sim_cell::Layout;

fn sweep_csv(config: &SweepConfig, threads: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let result = pool
        .install(|| run_sweep(config, &[], &|_| {}))
        .expect("valid sweep");
    let mut out = Vec::new();
    write_trials_csv(&result, &mut out).unwrap();
    write_summary_csv(&summarize_cells(&result), &mut out).unwrap();
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4))]

    /// A drawn geometry-mode sweep (seed, mounts, layout, noise, spread, point count, methods)
    /// with more trials than two work chunks (2048 trials each), so that two threads split it:
    /// the trials and summary CSV are byte-identical with one and with two threads.
    #[test]
    fn seeded_sweep_is_byte_identical_at_one_and_two_threads(
        seed in any::<u64>(),
        mounts in 0..3usize,
        layout in prop_oneof![Just(Layout::Tetrahedron), Just(Layout::Random),
            Just(Layout::Planar), Just(Layout::Clustered)],
        noise_mm in 0.01..5.0f64,
        spread_m in 0.1..2.0f64,
        n in 4..9usize,
        methods in proptest::sample::subsequence(Method::ALL.to_vec(), 1..=5),
        extra in 1..200usize,
    ) {
        let config = SweepConfig {
            mode: Mode::Geometry,
            mounts: vec![[MountPair::floor_floor(), MountPair::floor_wall(),
                MountPair::floor_ceiling()][mounts]],
            noise_mm: vec![noise_mm],
            spread_m: vec![spread_m],
            n_points: vec![n],
            methods: methods.into_iter().map(Into::into).collect(),
            layout: layout.into(),
            kinematic_errors: sim_cell::sweep::KinematicErrorDraw::None,
            trials: 2 * 2048 + extra,
            seed,
        };
        prop_assert_eq!(sweep_csv(&config, 1), sweep_csv(&config, 2));
    }
}
