//! The noise level per observation kind ([`KINDS`]): the robust scale of the whitened residuals
//! of the fit with every family free, and the problem with every row's σ scaled by it.

use calib_core::whole_cell::{CellFitError, CellProblem, Kind};

use super::held_out::{fit_model, residuals_at};
use super::{CellDiagnoseOptions, Family};

/// Every observation kind ([`Kind::ALL`]) in the report's order (each its own noise scale):
/// the kinds with a nuisance group first, as the report has always listed them. A new kind is
/// added here (a test checks that every kind is here once).
pub const KINDS: [Kind; Kind::ALL.len()] = [
    Kind::Contact,
    Kind::Tracker,
    Kind::Plane,
    Kind::Coincident,
    Kind::FaceContact,
];

/// Per kind ([`KINDS`] order), `max(1, 1.4826·median|w|)` of the whitened residuals of the fit
/// with every family free on `rows`.
pub(super) fn noise_scales(
    problem: &CellProblem,
    families: &[Family],
    rows: &[usize],
    options: &CellDiagnoseOptions,
    x0: nalgebra::Isometry3<f64>,
) -> Result<[f64; KINDS.len()], CellFitError> {
    let (sub, fit) = fit_model(problem, families, rows, None, options, x0)?;
    let scored = residuals_at(&sub, &fit.layout, &fit.estimate, &fit.active)?;
    let mut out = [1.0; KINDS.len()];
    for (k, kind) in KINDS.iter().enumerate() {
        let mut w: Vec<f64> = scored
            .iter()
            .filter(|r| r.kind == kind.name())
            .flat_map(|r| r.whitened.iter().map(|v| v.abs()).collect::<Vec<_>>())
            .collect();
        if w.is_empty() {
            continue;
        }
        w.sort_by(f64::total_cmp);
        let median = if w.len() % 2 == 1 {
            w[w.len() / 2]
        } else {
            0.5 * (w[w.len() / 2 - 1] + w[w.len() / 2])
        };
        out[k] = (1.4826 * median).max(1.0);
    }
    Ok(out)
}

/// `problem` with every row's σ multiplied by its kind's scale ([`KINDS`] order).
pub(super) fn scaled_noise(problem: &CellProblem, scale: &[f64; KINDS.len()]) -> CellProblem {
    let mut p = problem.clone();
    for o in &mut p.observations {
        // Every kind is in KINDS (the test below).
        let k = KINDS.iter().position(|k| *k == o.kind.kind()).unwrap_or(0);
        o.kind.scale_noise(scale[k]);
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_order_holds_every_kind_once() {
        for kind in Kind::ALL {
            let n = KINDS.iter().filter(|k| **k == kind).count();
            assert_eq!(n, 1, "{} is in KINDS {n} times", kind.name());
        }
    }
}
