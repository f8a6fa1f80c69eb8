//! sim-cell's integration tests as one test binary (`cargo test -p sim-cell --test sim_cell`):
//! the `sim-cell` binary as a user runs it (`cli`), the paper study through the library (`paper`)
//! and simulated sessions and robot-mode sweeps (`session`). The diagnose engine's hidden-parameter
//! tests stay in `tests/diagnose_hidden.rs`.

mod cli;
mod kinds;
mod paper;
mod session;
