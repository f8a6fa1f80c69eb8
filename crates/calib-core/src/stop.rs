//! Why an iterative solver stopped.

use serde::{Deserialize, Serialize};

/// Why an iterative solver of this crate stopped: the Levenberg–Marquardt solver of
/// [`crate::identify`] and [`crate::whole_cell`] (see [`crate::LmOptions`]) and the Gauss–Newton
/// fit of [`crate::constrained_soft`]. Serialised in snake_case ([`StopReason::name`], e.g.
/// `"iteration_cap"`).
///
/// Each reason means one thing whichever solver gives it. Non-convergence is a result state,
/// not an error: the solvers return their last (accepted) iterate with the reason. Every reason
/// except [`StopReason::IterationCap`], [`StopReason::Singular`] and [`StopReason::NonFinite`]
/// leaves a (numerical) minimum ([`StopReason::converged`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum StopReason {
    /// The cost stopped decreasing: an accepted step lowered it by less than the solver's
    /// relative cost tolerance, or (when the solver tests it) the undamped Gauss–Newton step
    /// predicts a decrease below that tolerance.
    Converged,
    /// The last update's norm fell below the solver's step tolerance (the iterate no longer
    /// moves, although the cost test has not passed).
    StepTooSmall,
    /// No damped step, up to the solver's largest damping, lowered the cost: the iterate is a
    /// numerical minimum.
    NoDescent,
    /// The normal equations could not be solved (a direction is not determined by the data);
    /// the last iterate is returned.
    Singular,
    /// The iteration cap was reached before any stopping test passed.
    IterationCap,
    /// A trial step left the model's domain (a residual, a Jacobian or the cost was not
    /// finite: the step diverged); the last finite iterate is returned.
    NonFinite,
}

impl StopReason {
    /// Whether the solver stopped at a (numerical) minimum: every reason but
    /// [`StopReason::IterationCap`], [`StopReason::Singular`] and [`StopReason::NonFinite`].
    pub fn converged(self) -> bool {
        !matches!(
            self,
            StopReason::IterationCap | StopReason::Singular | StopReason::NonFinite
        )
    }

    /// The serialised name: `"converged"`, `"step_too_small"`, `"no_descent"`, `"singular"`,
    /// `"iteration_cap"` or `"non_finite"`.
    pub fn name(self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::StepTooSmall => "step_too_small",
            StopReason::NoDescent => "no_descent",
            StopReason::Singular => "singular",
            StopReason::IterationCap => "iteration_cap",
            StopReason::NonFinite => "non_finite",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [StopReason; 6] = [
        StopReason::Converged,
        StopReason::StepTooSmall,
        StopReason::NoDescent,
        StopReason::Singular,
        StopReason::IterationCap,
        StopReason::NonFinite,
    ];

    /// The names the CLI's JSON and text print: serde's and [`StopReason::name`] agree, and the
    /// three reasons the CLI printed before the two enums became one keep their strings.
    #[test]
    fn stop_reason_serialises_snake_case_as_its_name() {
        for r in ALL {
            assert_eq!(
                serde_json::to_string(&r).unwrap(),
                format!("\"{}\"", r.name())
            );
            let back: StopReason = serde_json::from_str(&format!("\"{}\"", r.name())).unwrap();
            assert_eq!(back, r);
        }
        assert_eq!(StopReason::Converged.name(), "converged");
        assert_eq!(StopReason::IterationCap.name(), "iteration_cap");
        assert_eq!(StopReason::NonFinite.name(), "non_finite");
        assert_eq!(StopReason::StepTooSmall.name(), "step_too_small");
        assert_eq!(StopReason::NoDescent.name(), "no_descent");
    }

    #[test]
    fn only_the_minima_count_as_converged() {
        let minima: Vec<StopReason> = ALL.into_iter().filter(|r| r.converged()).collect();
        assert_eq!(
            minima,
            [
                StopReason::Converged,
                StopReason::StepTooSmall,
                StopReason::NoDescent
            ]
        );
    }
}
