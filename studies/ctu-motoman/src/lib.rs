#![doc = include_str!("../README.md")]
//!
//! # Modules
//!
//! One job each. Reading the dataset is [`data`]; the whole-cell problems, the fits and the
//! honest scoring protocol are [`study`]; the cross-validated choice is [`cv`]; fitting and
//! exporting a calibrated model is [`calibrated`]; the face-contact geometry is [`contact`] and
//! its report [`contact_report`]; the tracker score table is [`scores`], its spread over random
//! half splits [`splits`]; the hidden-set proxy is [`proxy`] and its report [`proxy_report`];
//! the figures are [`plot`]; the region-held-out protocol (issue 20) is [`region`]. The binary (`src/main.rs`) is the study's outline: its flags, which
//! model is fitted on which recordings and in what order, which models are scored and compared.

use std::path::{Path, PathBuf};

pub mod calibrated;
pub mod contact;
pub mod contact_report;
pub mod cv;
pub mod data;
pub mod plot;
pub mod proxy;
pub mod proxy_report;
pub mod region;
pub mod scores;
pub mod splits;
pub mod study;

/// The repository root: the nominal cell `cells/ctu-motoman.toml` and its URDFs live there.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs `run` on every job over `threads` threads (at least one; job k on thread k % threads)
/// and returns the results in job order, so that they never depend on the thread count. A
/// panic in a job is resumed in the caller.
pub fn in_job_order<J: Sync, R: Send>(
    jobs: &[J],
    threads: usize,
    run: &(dyn Fn(&J) -> R + Sync),
) -> Vec<R> {
    let threads = threads.max(1);
    let mut done: Vec<(usize, R)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                scope.spawn(move || {
                    (t..jobs.len())
                        .step_by(threads)
                        .map(|k| (k, run(&jobs[k])))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    done.sort_by_key(|(k, _)| *k);
    done.into_iter().map(|(_, r)| r).collect()
}
