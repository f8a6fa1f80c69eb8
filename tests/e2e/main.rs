//! End-to-end tests: the `handclasp` and `sim-cell` binaries run as a new user would run them.
//! One test binary (owned by the `handclasp` package), one module per command.

mod calibrate;
mod calibrate_cell;
mod coupled;
mod diagnose;
mod do_no_harm;
mod docs;
mod export;
mod fk_ik;
mod import;
mod import_rows;
mod input_guard;
mod inputs;
mod lumped;
mod one_robot;
mod paper;
mod paper_diagnose;
mod plan;
mod prior_scale;
mod report;
mod result_check;
mod silent_cases;
mod sim;
mod support;
mod validate;
