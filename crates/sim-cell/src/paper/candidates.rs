//! The candidate extensions of the isotropic-noise model and the signed observations with each
//! candidate's mean columns.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix6, Vector3, Vector6};
use serde::Serialize;

use super::experiments::{Experiment, PaperCell};
use super::simulate::CellSim;
use super::MRAD_PER_RAD;

/// A candidate extension of the isotropic-noise model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum Candidate {
    /// A tip length error (sum of both tips, mm) along the approach axis: a handclasp cannot see it
    /// in either robot, it shifts every estimate by `−d·a` (a: unit vector from base 1 to base 2).
    /// One parameter for all cells (the same pins were used).
    TipOffset,
    /// A constant contact bias per cell (3 translations per cell, mm): any systematic contact error
    /// whose direction is unknown.
    ContactBiasPerCell,
    /// Robot 1's joint-1 zero offset (deg; true = reported + value): the estimate turns by −value
    /// about b1's z axis, its translation by `−value·ẑ×T`.
    R1Joint1Offset,
    /// Robot 2's joint-1 zero offset (deg): the estimate turns by +value about base 2's z axis, no
    /// translation change. One parameter for all cells.
    R2Joint1Offset,
    /// Robot 2's joint-1 offset per cell (deg): e.g. a gravity deflection of its S axis that depends
    /// on how it hangs (wall: the S axis carries the arm's weight).
    R2Joint1PerCell,
    /// Anisotropic alignment noise: σ along the approach axis = k·σ across it (parameter k).
    AnisotropicNoise,
    /// One noise σ per cell (2 extra parameters).
    SigmaPerCell,
    /// The teach points spread wider (or narrower) than the assumed 1 m tetrahedron: the edge is
    /// fitted on [`super::SPREAD_GRID_M`]. A wider layout shrinks the rotation errors, not the translation
    /// errors, like anisotropic noise does, so the two compete for the same signature.
    LayoutSpread,
    /// A contact (TCP) offset constant over an experiment's 4 points and random between experiments,
    /// N(0, τ²·I) mm: it moves the translation, not the rotation (e.g. a pin re-seated or the TCP
    /// re-taught between experiments). One parameter τ.
    ContactOffsetPerExperiment,
}

impl Candidate {
    /// All candidates, in report order.
    pub const ALL: [Candidate; 9] = [
        Candidate::TipOffset,
        Candidate::ContactBiasPerCell,
        Candidate::R1Joint1Offset,
        Candidate::R2Joint1Offset,
        Candidate::R2Joint1PerCell,
        Candidate::AnisotropicNoise,
        Candidate::SigmaPerCell,
        Candidate::LayoutSpread,
        Candidate::ContactOffsetPerExperiment,
    ];

    /// The name used in reports and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Candidate::TipOffset => "tip_offset",
            Candidate::ContactBiasPerCell => "contact_bias_per_cell",
            Candidate::R1Joint1Offset => "r1_joint1_offset",
            Candidate::R2Joint1Offset => "r2_joint1_offset",
            Candidate::R2Joint1PerCell => "r2_joint1_offset_per_cell",
            Candidate::AnisotropicNoise => "anisotropic_noise",
            Candidate::SigmaPerCell => "sigma_per_cell",
            Candidate::LayoutSpread => "layout_spread",
            Candidate::ContactOffsetPerExperiment => "contact_offset_per_experiment",
        }
    }

    /// One line on what it models.
    pub fn description(self) -> &'static str {
        match self {
            Candidate::TipOffset => {
                "tip length error along the approach axis (both tips summed), one for all cells"
            }
            Candidate::ContactBiasPerCell => {
                "constant contact/translation bias per cell, direction free"
            }
            Candidate::R1Joint1Offset => "robot 1 joint-1 zero offset (rotation about b1 z)",
            Candidate::R2Joint1Offset => {
                "robot 2 joint-1 zero offset (rotation about b2 z), one for all cells"
            }
            Candidate::R2Joint1PerCell => {
                "robot 2 joint-1 offset/deflection per cell (mount-dependent gravity load)"
            }
            Candidate::AnisotropicNoise => {
                "alignment noise larger (or smaller) along the approach axis"
            }
            Candidate::SigmaPerCell => "a different noise level per cell",
            Candidate::LayoutSpread => {
                "teach points spread wider or narrower than a 1 m tetrahedron"
            }
            Candidate::ContactOffsetPerExperiment => {
                "contact/TCP offset constant within an experiment, random between experiments"
            }
        }
    }

    pub(super) fn index(self) -> usize {
        Candidate::ALL.iter().position(|c| *c == self).unwrap_or(0)
    }

    /// Candidates that cannot be combined with this one (nested or collinear).
    pub(super) fn family(self) -> u8 {
        match self {
            Candidate::TipOffset | Candidate::ContactBiasPerCell => 0,
            Candidate::R1Joint1Offset => 1,
            Candidate::R2Joint1Offset | Candidate::R2Joint1PerCell => 2,
            Candidate::AnisotropicNoise => 3,
            Candidate::SigmaPerCell => 4,
            Candidate::LayoutSpread => 5,
            Candidate::ContactOffsetPerExperiment => 6,
        }
    }
}

/// One signed observation (generic estimate).
pub(super) struct Obs {
    pub(super) cell: PaperCell,
    /// `(Δ mm, ω mrad)` on the cell's observed dims.
    pub(super) y: DVector<f64>,
    /// True `b1_from_b2` of the experiment.
    pub(super) truth: Isometry3<f64>,
    pub(super) approach: Vector3<f64>,
    pub(super) cov_perp: DMatrix<f64>,
    pub(super) cov_along: DMatrix<f64>,
    /// `(cov_perp, cov_along)` per tetrahedron edge of [`super::SPREAD_GRID_M`].
    pub(super) covs: Vec<(DMatrix<f64>, DMatrix<f64>)>,
    /// Per candidate (in [`Candidate::ALL`] order): parameter names (qualified, unit, report scale)
    /// and mean columns per unit parameter (6 rows: Δ mm, ω mrad).
    pub(super) columns: Vec<ParamColumns>,
}

/// A fitted mean parameter's name and how it is reported: reported value = β·`scale`, in `unit`.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ParamName {
    /// Qualified name (`candidate.parameter[cell]`).
    pub(super) name: String,
    /// Unit of the reported value (`mm`, `deg`).
    pub(super) unit: &'static str,
    /// Reported value per unit β.
    pub(super) scale: f64,
}

/// A candidate's parameters for one observation: names and mean columns per unit parameter
/// (6 rows: Δ mm, ω mrad), in the same order.
#[derive(Debug, Clone)]
pub(super) struct ParamColumns {
    /// The parameters.
    pub(super) names: Vec<ParamName>,
    /// Their mean columns.
    pub(super) cols: Vec<Vector6<f64>>,
}

pub(super) fn restrict(m: &Matrix6<f64>, dims: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(dims.len(), dims.len(), |i, j| m[(dims[i], dims[j])])
}

pub(super) fn observations(exps: &[Experiment], sims: &[CellSim]) -> Vec<Obs> {
    exps.iter()
        .map(|e| {
            let dims = e.cell.observed_dims();
            let y6 = e.signed_generic();
            let sim = &sims[e.cell.index()];
            let mut o = Obs {
                cell: e.cell,
                y: DVector::from_iterator(dims.len(), dims.iter().map(|&d| y6[d])),
                truth: e.b1_from_b2_true,
                approach: sim.ctx.approach,
                cov_perp: restrict(&sim.cov_perp, dims),
                cov_along: restrict(&sim.cov_along, dims),
                covs: sim
                    .spread_covs
                    .iter()
                    .map(|(p, a)| (restrict(p, dims), restrict(a, dims)))
                    .collect(),
                columns: Vec::new(),
            };
            o.columns = Candidate::ALL
                .iter()
                .map(|&c| {
                    let mut names = Vec::new();
                    let mut cols = Vec::new();
                    for (n, u, sc, col) in columns(c, &o) {
                        names.push(ParamName {
                            name: format!("{}.{}", c.name(), n),
                            unit: u,
                            scale: sc,
                        });
                        cols.push(col);
                    }
                    ParamColumns { names, cols }
                })
                .collect();
            o
        })
        .collect()
}

/// Parameter columns of a candidate for one observation (6 rows: Δ mm, ω mrad), with names/units.
pub(super) fn columns(c: Candidate, o: &Obs) -> Vec<(String, &'static str, f64, Vector6<f64>)> {
    // (name, unit, report scale: reported value = β·scale, column per unit β)
    let z = Vector3::z();
    let t_m = o.truth.translation.vector;
    let z2 = o.truth.rotation * z;
    let mrad_to_deg = 180.0 / std::f64::consts::PI / MRAD_PER_RAD;
    let cell_cols =
        |k: usize, col: Vector6<f64>| -> Vec<(String, &'static str, f64, Vector6<f64>)> {
            PaperCell::ALL
                .iter()
                .map(|&c| {
                    (
                        format!(
                            "{}[{}]",
                            ["x", "y", "z"].get(k).copied().unwrap_or("value"),
                            c.label()
                        ),
                        "",
                        1.0,
                        if c == o.cell { col } else { Vector6::zeros() },
                    )
                })
                .collect()
        };
    match c {
        Candidate::TipOffset => {
            let a = -o.approach;
            vec![(
                "tip".into(),
                "mm",
                1.0,
                Vector6::new(a.x, a.y, a.z, 0.0, 0.0, 0.0),
            )]
        }
        Candidate::ContactBiasPerCell => {
            let mut v = Vec::new();
            for k in 0..3 {
                let mut col = Vector6::zeros();
                col[k] = 1.0;
                for (n, _, s, c) in cell_cols(k, col) {
                    v.push((n, "mm", s, c));
                }
            }
            v
        }
        Candidate::R1Joint1Offset => {
            // value δ (mrad internally): ω = −δ·ẑ, ΔT = −δ·ẑ×T (T in m, δ in mrad → mm).
            let dt = -z.cross(&t_m);
            vec![(
                "offset".into(),
                "deg",
                mrad_to_deg,
                Vector6::new(dt.x, dt.y, dt.z, 0.0, 0.0, -1.0),
            )]
        }
        Candidate::R2Joint1Offset => vec![(
            "offset".into(),
            "deg",
            mrad_to_deg,
            Vector6::new(0.0, 0.0, 0.0, z2.x, z2.y, z2.z),
        )],
        Candidate::R2Joint1PerCell => PaperCell::ALL
            .iter()
            .map(|&c| {
                (
                    format!("offset[{}]", c.label()),
                    "deg",
                    mrad_to_deg,
                    if c == o.cell {
                        Vector6::new(0.0, 0.0, 0.0, z2.x, z2.y, z2.z)
                    } else {
                        Vector6::zeros()
                    },
                )
            })
            .collect(),
        Candidate::AnisotropicNoise
        | Candidate::SigmaPerCell
        | Candidate::LayoutSpread
        | Candidate::ContactOffsetPerExperiment => Vec::new(),
    }
}
