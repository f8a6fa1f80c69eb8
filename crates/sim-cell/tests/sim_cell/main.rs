//! sim-cell's integration tests as one test binary (`cargo test -p sim-cell --test sim_cell`):
//! the `sim-cell` binary as a user runs it (`cli`), the paper study through the library
//! (`paper`), simulated sessions and robot-mode sweeps (`session`), and drawn-input properties
//! (`properties`: a sweep identical at 1 and 2 threads). The diagnose
//! engine's hidden-parameter tests stay in `tests/diagnose_hidden.rs`.

mod cli;
mod face_contact;
mod kinds;
mod paper;
mod placement_prior;
mod properties;
mod session;
