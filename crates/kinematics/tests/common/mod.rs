//! Helpers shared by the kinematics integration tests (`mod common;` in each test file).

use kinematics::RobotModel;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// A random independent joint vector: each joint uniform in its range (capped at ±3, rad or m)
/// shrunk by `margin` × the span at both ends.
pub fn random_q(model: &RobotModel, rng: &mut ChaCha8Rng, margin: f64) -> Vec<f64> {
    model
        .joints()
        .iter()
        .map(|j| {
            let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
            let span = hi - lo;
            rng.random_range(lo + margin * span..hi - margin * span)
        })
        .collect()
}
