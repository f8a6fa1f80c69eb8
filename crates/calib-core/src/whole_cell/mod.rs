//! Whole-cell calibration: a maximum-a-posteriori fit of a two-robot cell — the placement
//! `b1_from_b2`, the kinematic parameters of both robots and nuisance unknowns — from mixed
//! observations, with a prior from tolerances, base-parameter reduction, blunder screening,
//! the cooperative-accuracy prediction and greedy experiment design. No I/O; SI units.
//!
//! # Unknowns
//! - `X = b1_from_b2 ∈ SE(3)`, perturbed on the left: `X ← Translation(ρ)·Rotation(φ)·X`
//!   (`ρ` m, `φ` rad, b1 axes), as in [`crate::identify`]. Unpenalised.
//! - Each robot's kinematic parameters `θ_r` ([`kinematics::ErrorParam`]: joint offsets, origin
//!   xyz/rpy, optional scale, compliance and first-harmonic periodic errors) and a tip offset
//!   error per tool (m, flange axes).
//!   The tip of tool `t` of robot `r` at reported joints `q` is
//!   `f_r,t(q) = kinematics::true_base_from_tip(model_r, θ_r ⊕ tip_t, q, flange_from_tip_t, g_r)`,
//!   in robot r's nominal base frame, and its derivatives `∂f/∂θ` are
//!   [`kinematics::tip_error_jacobian`] (exact, at the current values). Mount parameters are
//!   never fitted: they are the placement's (or a tracker frame's) job.
//! - Nuisances per named group, all unpenalised: a tracker frame `T = tracker_from_b{a}`
//!   (left-perturbed like `X`) with, when switched on, a scale error `s` and a translation drift
//!   `δ` over the normalised recording order `u ∈ [−½, ½]` ([`TrackerGroup`]), a plane `{p_a : n·p_a = d}` (normal perturbed as
//!   `n ← normalise(n + α·u + β·v)` with `(u, v)` = [`tangent_basis`]`(n)`, `d` additive), a
//!   contact distance `d` (known, or fitted).
//!
//! # Observations and residuals (`g_a` = a tip in anchor base `a`)
//! `g_a = f` when the tip's robot is `a`; `X·f2` for robot 2 in b1; `X⁻¹·f1` for robot 1 in b2.
//! With `∂(X·f2)/∂ρ = I`, `∂(X·f2)/∂φ_i = e_i × X·f2`, and `∂(X⁻¹·f1)/∂ρ = −R_Xᵀ`,
//! `∂(X⁻¹·f1)/∂φ_i = −R_Xᵀ(e_i × f1)`:
//! - `Coincident`: `r = f1(q1) − X·f2(q2)` (3 rows);
//! - `Contact`: `r = ‖f1 − X·f2‖ − d` (1 row; `∂r = ûᵀ·∂(f1 − X·f2) − ∂d`, `û` the unit vector);
//! - `FaceContact` (two flat faces touching flush): `r = n̄·(X·f2 − f1) − d` (1 row), the
//!   tip-to-tip distance along the faces' mean normal `n̄ = m/‖m‖`, `m = n1 − n2`, with the
//!   outward face normals fixed in each tip frame and rotated into b1:
//!   `n1 = R1(θ1)·n1_tip`, `n2 = R_X·R2(θ2)·n2_tip` (`R_r` the rotation of the true
//!   `base_from_tip`); the tangential part of `X·f2 − f1` (the faces sliding) is not
//!   observed. With `e = X·f2 − f1`: `∂r = n̄ᵀ·∂e + wᵀ·(∂n1 − ∂n2) − ∂d`,
//!   `w = (I − n̄n̄ᵀ)·e/‖m‖`; `∂n2/∂φ_i = e_i × n2`, `∂n2/∂ρ = 0`, tip offsets do not rotate
//!   the normals, and `∂(R_r·n)/∂θ = ∂f_r(t + n)/∂θ − ∂f_r(t)/∂θ` exactly (the tip is affine
//!   in the tool offset `t`: `f_r(t) = o + R_r·(t + tip)`);
//! - `Tracker`: `r = (1 + s)·(T·g_a + u·δ) − p_tracker` (3 rows; `∂r/∂ρ_T = (1 + s)·I`,
//!   `∂r/∂φ_T,i = (1 + s)·e_i × T·g_a`, `∂r/∂g = (1 + s)·R_T`, `∂r/∂s = T·g_a + u·δ`,
//!   `∂r/∂δ = (1 + s)·u·I`; `s = 0`, `δ = 0` unless the group fits them);
//! - `Plane`: `r = n·g_a − d` (1 row; `∂r/∂α = u·g_a`, `∂r/∂β = v·g_a`, `∂r/∂d = −1`).
//!
//! Each row block is whitened by `W_i = L_i⁻¹`, `Σ_i = L_i·L_iᵀ` its noise covariance (or `1/σ`).
//! Every analytic Jacobian is checked against central differences in the tests.
//!
//! # Prior and MAP cost
//! A tolerance is the half-width of a uniform band; the prior is `θ_k ~ N(0, (tol_k/√3)²)`, so a
//! truth drawn from `U(±tol)` has the prior's variance ([`Tolerance`]; defaults 0.05° for joint
//! offsets and origin rpy, 0.5 mm for origin xyz and tips; scale, compliance and periodic off). The fit
//! minimises `C = Σ_i ‖W_i·r_i‖² + ‖R_p·θ‖²` (`R_p` the square-root prior information, diagonal
//! `1/σ_k`, or a full matrix after merging) by the crate's Levenberg–Marquardt solver
//! ([`fit_cell`], [`crate::LmOptions::whole_cell`]): damped normal equations
//! `(H + λ·diag H)·δ = −g`, `H = JᵀJ`, `g = Jᵀr` over the stacked whitened data and prior rows;
//! a step is accepted when `C` decreases. It stops ([`crate::StopReason`]) when the relative
//! decrease or the predicted Gauss–Newton decrease `gᵀH⁻¹g` falls below `cost_tolerance·C`
//! (converged), at `max_iterations` (iteration cap), when no damping up to `λ = 1e10` lowers `C`
//! (no descent), or on a non-finite residual (non-finite). The posterior covariance is `Σ = H⁻¹` at the optimum
//! (Laplace approximation; the noise is taken as stated, not rescaled).
//!
//! # Base-parameter reduction ([`reduce`])
//! Let `J_n` be the whitened data Jacobian of the unpenalised columns (placement, nuisances) and
//! `J_k` that of the kinematic columns. Project: `A = (I − Q_n·Q_nᵀ)·J_k·D`, `Q_n` an orthonormal
//! basis of `range(J_n)`, `D = diag(σ_prior)`. A placement prior ([`PlacementPrior`]:
//! `[b1_from_b2] sigma_mm/sigma_deg`, a shared trunk's identity, whitened rows `L`) holds the
//! motions of the placement along which its information exceeds the data's (eigenvalues `< 1`
//! of the data information in the prior's metric, nuisances projected out): those are fixed,
//! not in `J_n`, and the rest of the placement stays in `J_n` (a free or loosely held
//! placement absorbs its six motions; a tightly held one absorbs nothing, and a parameter that
//! moves the hands as it would is kept: a shared trunk held still keeps the shoulders). The
//! prior rows never enter `A`; a column only the held motions tell apart is a pivot only if the
//! data carry at least its prior's information ([`HELD_ONLY_MIN_INFO`]). A column-pivoted QR `A·P = Q·R` orders the
//! columns by how much new information each adds; columns whose `|R_jj| ≤ rank_tol·|R_00|` are
//! structurally undetermined. Each such column is dropped (held at 0) and reported: "no effect"
//! if its raw column is zero, "confounded with b1_from_b2 / the nuisance unknowns" if its
//! projected column is zero, "decided by the prior" if its data information `‖J_k,j·σ_j‖²`
//! (prior-σ units: the prior's is 1) is at most [`PRIOR_INFO_TOL`] (such a column is never a
//! pivot: the relative test alone would keep a column the data barely see, and merge others
//! onto it with coefficients ~1/its norm), else "merged into" the kept columns
//! `c = R₁₁⁻¹·R₁₂` it is a combination of. Merging is exact in the linear sense: the kept parameters then stand for
//! `θ_keep + (D_keep·c_j/σ_j)·θ_j`, so their prior covariance becomes
//! `D_keep² + Σ_j (D_keep·c_j)(D_keep·c_j)ᵀ` (and `R_p` its inverse Cholesky factor), so the
//! prediction still carries the dropped parameters' prior uncertainty.
//!
//! # Blunders ([`fit_screened`])
//! A robust start (IRLS with Huber weights `w = min(1, k/s_i)` on each block's whitened norm
//! `s_i = ‖W_i·r_i‖`, `k = sqrt(χ²_dim(0.95))`), then the studentised statistic of each block
//! `t_i² = r̃_iᵀ(I − H_ii)⁻¹·r̃_i`, `H_ii = J̃_i·Σ·J̃_iᵀ` (hat matrix of the linearised MAP problem,
//! `r̃, J̃` whitened), which is `χ²_dim` under the model; a block is rejected when `t_i²` exceeds
//! the `1 − α/B` quantile of `χ²_dim` (Bonferroni over the `B` blocks, `α = 0.01` by default).
//! The refit drops the worst rejected block one at a time and re-admits a rejected block whose
//! deletion statistic `r̃ᵀ(I + H)⁻¹r̃` falls below the threshold. Rejected rows are reported with
//! `sqrt(t²)` ("size in σ").
//!
//! # Cooperative accuracy ([`predict_cooperative_accuracy`])
//! For a configuration pair `(q1, q2)`, `v = f1(q1) − X·f2(q2)` (m, b1 axes); its error has
//! covariance `Σ_v = J_v·Σ·J_vᵀ` (`J_v` as the coincident residual's unwhitened Jacobian). The
//! predicted rms over pairs is `sqrt(mean trace Σ_v)` (exact); the p95 of `‖δv‖` comes from a
//! seeded draw of [`P95_DRAWS_PER_PAIR`] Gaussian errors per pair. [`measure_cooperative_error`]
//! gives the actual `‖v_fit − v_true‖` against a known truth.
//!
//! # The predicted error ([`predict_error`])
//! One definition for `calibrate --cell`, `plan` and the report page (`prediction.rs`): the
//! error covariance split into the part the data determined and the part the prior asserts
//! ([`PredictionSplit`]), a model-error term from held-out residuals ([`ModelError`]), propagated
//! to a named [`PairSet`] (the session's meeting pairs, work points, or the whole workspace:
//! [`workspace_pairs`]), with a 95 % bound of the rms.
//!
//! # Do no harm ([`region_harm_check`])
//! Before `calibrate --cell` exports, the fitted model and the nominal model (placement and
//! nuisances only) are both fitted without each joint-space region of the session's
//! handclasps and scored on it (`do_no_harm.rs`); a model worse than nominal with significance
//! in any region is withheld by the caller ([`HarmCheck::harmful`]).
//!
//! # Design ([`greedy_design`])
//! At nominal, the information is `A₀ = R_pᵀR_p + ε·I` on the unpenalised columns (a weak
//! prior: σ = [`WEAK_PRIOR_SIGMA`] so that `A₀` is invertible) and each candidate `c` adds its
//! whitened block `B_c` (`A ← A + B_cᵀB_c`). With `Σ = A⁻¹`, adding `B` gives, by Woodbury,
//! `Σ' = Σ − Σ·Bᵀ·S⁻¹·B·Σ`, `S = I + B·Σ·Bᵀ`. A-optimal: minimise the mean cooperative variance
//! `trace(M·Σ)`, `M = mean_k J_v,kᵀJ_v,k` over evaluation pairs; its decrease is
//! `trace(S⁻¹·B·Σ·M·Σ·Bᵀ)`. D-optimal: maximise `log det A`; its increase is `log det S`.
//! Greedy: pick the best candidate, update `Σ` by Woodbury, repeat.
//!
//! # One call
//! [`calibrate_cell`] runs the chain a CLI needs (start, reduce, screened MAP fit) and
//! [`CellCalibration::report`] gives its report in file units (mm, degrees: [`CalibrationReport`],
//! the typed structs `calibrate --cell` prints as JSON and text).
//!
//! # Files, in dependency order (each uses only those before it)
//! `cell` (error type, robots, tools, tolerances, noise) ← `observations` (observation kinds,
//! nuisance groups, [`CellProblem`] and its checks) ← `layout` (estimates, columns, prior,
//! manifold updates) ← `residuals` (residuals and analytic Jacobians, [`Evaluator`]) ← `start`
//! (starting values) ← `solve` (Levenberg–Marquardt) ← `reduce` ← `blunders` ← `accuracy` ←
//! `design`, `evidence` (the prior scales from the evidence), `calibrate` (the one call) ←
//! `prediction` (the predicted error), `do_no_harm` (the region-held-out check against nominal) ← `withhold` (the export's
//! family-by-family do-no-harm decision) ←
//! `report` (its file-unit report); beside them, `coverage` (the joint ranges and tool-point
//! region a session covers against the limits and the reach), the result check (`check`: noise
//! scale, placement against the stated one, layout shape; `mistakes`: likely data mistakes
//! tried; `misfit`: blunders or model misfit) and `validate` (a held cell scored on observations
//! it was not fitted to, nuisances given or split-refitted). `fixtures` (simulated cells) and `tests` sit on top.

mod accuracy;
mod blunders;
mod calibrate;
mod cell;
mod check;
mod coverage;
mod design;
mod do_no_harm;
mod evidence;
mod layout;
mod misfit;
mod mistakes;
mod observations;
mod placement_prior;
mod placement_rotation;
mod prediction;
mod reduce;
mod report;
mod residuals;
mod solve;
mod start;
mod validate;
mod withhold;

#[cfg(any(test, feature = "fixtures"))]
#[doc(hidden)]
pub mod fixtures;
#[cfg(test)]
mod tests;

pub use accuracy::{
    cooperative_covariances, measure_cooperative_error, predict_cooperative_accuracy,
    summarise_covariances, ConfigPair, CooperativeError, CooperativePrediction, P95_DRAWS_PER_PAIR,
};
pub use blunders::{fit_screened, RejectedRow, ScreenOptions, ScreenedFit};
pub use calibrate::{calibrate_cell, calibrate_cell_with, widen_prior, CellCalibration};
pub use cell::{
    CellFitError, CellRobot, Noise3, Tolerance, Tool, COINCIDENT_TIP_M,
    LUMPED_COMPLIANCE_TOLERANCE_RAD,
};
pub use check::{
    coincident_pairs, fitted_rows_noise_scale, layout_shape, placement_distance,
    robust_noise_scale, robust_noise_scale_with_tolerances, CheckThresholds, LayoutShape,
    PlacementDistance, LEVERAGE_FLOOR,
};
pub use coverage::{
    session_coverage, CoverageReport, JointCoverage, JointCoverageReport, PointRegion,
    PointRegionReport, RobotCoverage, RobotCoverageReport, SessionCoverage, ENVELOPE_SAMPLES,
    NARROW_JOINT_FRACTION, NARROW_REACH_FRACTION,
};
pub use design::{
    design_criterion, design_prediction, design_split, greedy_design, DesignCriterion,
    DesignPrediction, DesignResult, PLACEMENT_DRAWS, WEAK_PRIOR_SIGMA,
};
pub use do_no_harm::{
    region_harm_check, HarmCheck, HarmDesign, HarmFold, FALLBACK_BLOCKS, MIN_BLOCK_ROWS,
    MIN_HARM_REGION_ROWS,
};
pub use evidence::{
    format_scale, prior_family, FamilyScale, PriorScaleChoice, ScaleMethod, FAMILY_EVIDENCE_MARGIN,
    FAMILY_SWEEPS, MAX_PRIOR_SCALE, PRIOR_SCALES, REFERENCE_EVIDENCE_MARGIN,
};
pub use layout::{
    tangent_basis, CellEstimate, CellParam, ParamLayout, PlaneEstimate, RobotCorrection,
};
pub use misfit::{
    classify_rejections, JointCluster, RejectionPattern, ResidualPattern, CLUSTER_MIN_ROWS,
    JOINT_TAIL, MISFIT_MIN_ROWS, MISFIT_SHARE, MISFIT_SHARE_ALONE, MISFIT_SHARE_MAJORITY,
    REST_FITS_SCALE, TIME_WINDOW,
};
pub use mistakes::{candidate_mistakes, try_problem, Mistake, Trial};
pub use observations::{
    CellProblem, ContactGroup, GroupKind, Kind, Observation, ObservationKind, PlaneGroup,
    TrackerGroup, OTHER_ARM_TRUNK_TOL, UNIT_NORMAL_TOL,
};
pub use placement_prior::PlacementPrior;
pub use placement_rotation::{
    placement_rotation_posterior, PlacementRotationPosterior, CONDITIONING_RCOND,
};
pub use prediction::{
    predict_error, workspace_pairs, ModelError, PairSet, PredictedError, PredictionSplit,
    WorkspacePose, BOUND_DRAWS, MODEL_ERROR_ALPHA, WORKSPACE_ATTEMPTS_PER_POSE, WORKSPACE_POSES,
    WORKSPACE_SEED,
};
pub use reduce::{
    reduce, reduce_layout, Reduction, ReductionEntry, ReductionReason, HELD_ONLY_MIN_INFO,
    PRIOR_INFO_TOL, RANK_TOL,
};
pub use report::{
    CalibrationReport, ContactGroupReport, DesignPredictionReport, DropReason, FamilyScaleReport,
    FittedPlacementReport, GroupsReport, LogEvidenceReport, MergePartner, NuisanceReport,
    ParamIdentity, ParameterReport, PlacementSigmaReport, PlaneGroupReport, PredictedErrorReport,
    PriorScaleReport, RejectedRowReport, ReportUnit, TrackerGroupReport, UnidentifiableReport,
    TOLERANCE_WARNING_SIGMAS,
};
pub use residuals::{AtEstimate, Evaluator, ObservationLinearisation, MIN_FACE_NORMAL_SUM};
pub use solve::{fit_cell, fit_cell_with, CellFit, FittedParam, SolveOptions};
pub use start::initial_estimate;
pub(crate) use start::initial_estimate_at;
pub use validate::{
    carry_nuisances, fit_nuisances, group_name, held_out_pieces, held_out_residuals, hold_cell,
    score_held_out, sub_problem, HeldOutResidual, NuisanceMode, HOLD_SIGMA, MIN_SPLIT_ROWS,
};
pub use withhold::{
    check_margin, decide_families, error_families, judge_full_model, largest_harmless, ErrorFamily,
    FamilyDecision, FamilyKind, FamilyTrial, FamilyVerdict,
};
