//! Why an iterative solver stopped.

use serde::{Deserialize, Serialize};

/// Why an iterative solver of this crate stopped (serialised in snake_case, e.g. `"iteration_cap"`).
///
/// Non-convergence is a result state, not an error: the solvers return their last iterate with the
/// reason. Every reason except [`StopReason::IterationCap`] and [`StopReason::Singular`] leaves a
/// (numerical) minimum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum StopReason {
    /// The relative cost decrease of an accepted step fell below the solver's tolerance.
    Converged,
    /// The update fell below the solver's step tolerance.
    StepTooSmall,
    /// No (damped) step lowered the cost: the iterate is a numerical minimum.
    NoDescent,
    /// The normal equations could not be solved (a direction is not determined by the data);
    /// the last iterate is returned.
    Singular,
    /// The iteration cap was reached before any stopping test passed.
    IterationCap,
}

impl StopReason {
    /// Whether the solver stopped at a (numerical) minimum: every reason but
    /// [`StopReason::IterationCap`] and [`StopReason::Singular`].
    pub fn converged(self) -> bool {
        !matches!(self, StopReason::IterationCap | StopReason::Singular)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stop_reason_serialises_snake_case() {
        assert_eq!(
            serde_json::to_string(&StopReason::IterationCap).unwrap(),
            "\"iteration_cap\""
        );
        assert_eq!(
            serde_json::to_string(&StopReason::StepTooSmall).unwrap(),
            "\"step_too_small\""
        );
        assert!(StopReason::NoDescent.converged());
        assert!(!StopReason::IterationCap.converged());
    }
}
