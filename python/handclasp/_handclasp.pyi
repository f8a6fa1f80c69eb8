"""Type stubs of the native module (see handclasp/__init__.py for the package's overview)."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_Array = npt.ArrayLike
_F64 = npt.NDArray[np.float64]

__version__: str

class CalibrationError(Exception):
    """A calibration or diagnosis failed; the message names the cause and the fix. A result a
    check refused carries the CLI's --json refusal: status ("refused"), reason, refusal (the
    whole object), result_check (whole-cell) or misfit (points; the other is None). Set on
    refusals only."""
    status: Optional[str]
    reason: Optional[str]
    refusal: Optional[Dict[str, Any]]
    result_check: Optional[Dict[str, Any]]
    misfit: Optional[Dict[str, Any]]

class Robot:
    """A URDF robot model: the chain from the base link to the flange link. Immutable."""
    @staticmethod
    def load(path: _Path, tool_link: str = "tool0") -> Robot:
        """Load a URDF; OSError for an unreadable file, ValueError for an invalid one."""
    @property
    def name(self) -> str: ...
    @property
    def dof(self) -> int:
        """Independent joints (the width of q_deg)."""
    @property
    def joint_names(self) -> List[str]: ...
    @property
    def limits(self) -> List[Tuple[float, float]]:
        """Joint limits, degrees (mm for a prismatic joint)."""

class Cell:
    """A cell TOML: two robots (URDFs, tips, mounts, tolerances), b1_from_b2, noise."""
    @staticmethod
    def load(path: _Path) -> Cell:
        """Read a cell TOML; OSError subclasses for files, ValueError for invalid content."""
    @property
    def b1_from_b2(self) -> _F64:
        """The cell's nominal b1_from_b2, (4, 4), translation in mm."""
    @property
    def path(self) -> Optional[str]: ...
    @property
    def has_robot2(self) -> bool:
        """False for a one-robot cell (no [robot2]: tracker and plane sessions only)."""
    @property
    def dof(self) -> Tuple[int, Optional[int]]:
        """Joint counts of robot 1 and robot 2; robot 2's is None in a one-robot cell."""
    def to_toml(self) -> str: ...

class Session:
    """A session of one cell: coincident handclasps and rows of the other kinds."""
    @staticmethod
    def load(path: _Path, cell: Cell) -> Session:
        """Read a session CSV of `cell`; ValueError names the line and column."""
    @staticmethod
    def from_arrays(
        cell: Cell,
        q1_deg: Optional[_Array] = None,
        q2_deg: Optional[_Array] = None,
        p1_mm: Optional[_Array] = None,
        p2_mm: Optional[_Array] = None,
        point: Optional[Sequence[int]] = None,
        columns: Optional[Dict[str, Any]] = None,
    ) -> Session:
        """A session from arrays: q1_deg (n, dof1), q2_deg (n, dof2) in degrees, tips p1_mm,
        p2_mm (n, 3) in mm in each robot's base (default: nominal FK), other CSV columns by
        name in `columns`. Read exactly as the CSV with these columns."""
    def to_csv(self, path: _Path) -> None: ...
    def to_csv_string(self) -> str: ...
    def columns(self) -> Dict[str, Union[_F64, List[str]]]:
        """The CSV columns by name (numbers float64, NaN for empty; text as lists)."""
    def to_frame(self) -> Any:
        """columns() as a pandas DataFrame when pandas is installed, else the dict."""
    def __len__(self) -> int: ...
    @property
    def rows_by_kind(self) -> Dict[str, int]: ...
    @property
    def q1_deg(self) -> _F64:
        """Coincident rows' robot 1 joints, degrees, (n, dof1)."""
    @property
    def q2_deg(self) -> _F64:
        """Coincident rows' robot 2 joints, degrees, (n, dof2)."""
    @property
    def p1_mm(self) -> _F64:
        """Coincident rows' nominal tips of robot 1 in base 1, mm, (n, 3)."""
    @property
    def p2_mm(self) -> _F64:
        """Coincident rows' nominal tips of robot 2 in base 2, mm, (n, 3)."""

class PointsResult:
    """A points fit: b1_from_b2 and the CLI's report."""
    @property
    def b1_from_b2(self) -> _F64:
        """(4, 4), translation in mm; p_b1 = b1_from_b2 @ p_b2."""
    @property
    def method(self) -> str: ...
    @property
    def residuals_mm(self) -> _F64:
        """p_b1 - b1_from_b2·p_b2, mm, (n, 3)."""
    @property
    def residual_norms_mm(self) -> _F64: ...
    @property
    def residual_rms_mm(self) -> float: ...
    @property
    def rows(self) -> List[int]: ...
    @property
    def uncertainty(self) -> Optional[Dict[str, Any]]:
        """Predicted 1σ: e_tran_1sigma_mm, e_rot_1sigma_deg, sigma_point_mm, covariance, ..."""
    @property
    def covariance(self) -> Optional[_F64]:
        """(6, 6) posterior covariance of b1_from_b2, or None."""
    @property
    def warnings(self) -> List[str]: ...
    def to_json(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]:
        """Equal to json.loads of `handclasp calibrate POINTS.csv --json`."""

class PointsMethods:
    """calibrate_points(..., method="all"): every method's fit, or why it does not apply."""
    @property
    def results(self) -> Dict[str, PointsResult]:
        """The fitted methods' results by name (each .to_dict() the CLI's --method NAME --json)."""
    @property
    def errors(self) -> Dict[str, str]:
        """Why each method that does not apply does not, by name."""
    def __getitem__(self, name: str) -> Optional[PointsResult]:
        """A method's result; None when it does not apply; KeyError when it was not tried."""
    def to_json(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]:
        """Equal to json.loads of `handclasp calibrate POINTS.csv --method all --json`."""

class PlanResult:
    """plan(...): the planned poses and `handclasp plan`'s report (predicted cooperative error
    of the plan beside the random picks' mean, mm and deg)."""
    @property
    def session(self) -> Session: ...
    def to_csv(self, path: _Path) -> None: ...
    def to_csv_string(self) -> str: ...
    def columns(self) -> Dict[str, Union[_F64, List[str]]]: ...
    def __len__(self) -> int: ...
    def text(self) -> str: ...
    def to_json(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]:
        """Equal to json.loads of `handclasp plan ... --json` (with the same out)."""

class CellResult:
    """A whole-cell calibration: b1_from_b2, parameters with σ, predicted accuracy, report."""
    @property
    def b1_from_b2(self) -> _F64:
        """(4, 4), translation in mm."""
    @property
    def b1_from_b2_sigma(self) -> _F64:
        """Posterior σ: translation x, y, z (mm), rotation x, y, z (deg)."""
    def parameters(self) -> Dict[str, Any]:
        """Columns name, value, sigma, prior_sigma, unit."""
    @property
    def cooperative_accuracy_mm(self) -> Optional[Dict[str, Any]]: ...
    @property
    def work_site(self) -> Optional[Dict[str, Any]]:
        """The verdict at the work site (the CLI's JSON `work_site`: predicted cooperative
        accuracy there in mm, the placement's rotation error in deg, PASS/FAIL and why), or
        None when calibrate_cell was given no work_points, accept_mm or accept_deg."""
    def report(
        self,
        path: _Path,
        work_points: Optional[Union[_Array, _Path]] = None,
        accept_mm: Optional[float] = None,
        accept_deg: Optional[float] = None,
    ) -> str:
        """Write the HTML page of `calibrate --cell ... --report PATH` (the CLI's function);
        the verdict from these arguments when any is given, else calibrate_cell's, else at the
        cell's [teach] centre. work_points: (n, 3) tool positions in base 1, mm, or a CSV path
        (x_mm,y_mm,z_mm). Returns the path written."""
    def export(self, dir: _Path, overwrite: bool = False, force: bool = False) -> List[str]:
        """Write cell.toml, robot1.urdf, robot2.urdf (calibrate --cell --export), under the
        CLI's export lock; a non-empty folder needs overwrite=True.

        Runs the CLI's do-no-harm check first (the same library function; the verdict is
        do_no_harm()): when the model is worse than nominal on a held-out region of joint
        space, the error families that harm are withheld family by family and the export is a
        refit without them (the placement only when all harm), with a UserWarning naming what
        was withheld and why. force=True (--force) exports the full model as fitted, warning
        when it harms. (force=True used to raise ValueError, as the old way to overwrite.)"""
    def do_no_harm(self) -> Optional[Dict[str, Any]]:
        """The do-no-harm verdict export() applies: the CLI's JSON `do_no_harm` object
        (folds, exported: the model's name, "partial" or "placement", kept, withheld with the
        held-out regions that decided each, families, trials); None for a placement-only
        calibration. Runs the check on first use, then keeps it."""
    def text(self) -> str: ...
    def to_json(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]:
        """Equal to json.loads of `handclasp calibrate --cell ... --json`."""

class DiagnoseResult:
    """A diagnosis: what the nominal models get wrong, and the CLI's report."""
    @property
    def mode(self) -> str:
        """"coincident" or "whole_cell"."""
    @property
    def b1_from_b2(self) -> _F64: ...
    @property
    def work_site(self) -> Optional[Dict[str, Any]]:
        """The verdict at the work site for the model export() writes (the CLI's JSON
        `work_site`; `to_dict()["work_site_model"]` names the model), or None when diagnose was
        given no work_points, accept_mm or accept_deg."""
    def report(
        self,
        path: _Path,
        work_points: Optional[Union[_Array, _Path]] = None,
        accept_mm: Optional[float] = None,
        accept_deg: Optional[float] = None,
    ) -> str:
        """Write the HTML page of `diagnose ... --report PATH` (the CLI's function). Whole-cell
        diagnoses: the verdict first, from these arguments when any is given, else diagnose's,
        else at the cell's [teach] centre; coincident ones take no verdict (ValueError).
        Returns the path written."""
    def export(
        self,
        dir: _Path,
        overwrite: bool = False,
        force: bool = False,
        keep_withheld: Optional[bool] = None,
    ) -> List[str]:
        """Write the corrected model (diagnose --export), under the CLI's export lock; a
        non-empty folder needs overwrite=True (force=True is refused).

        Whole-cell diagnoses write the do-no-harm rule's model and, when the rule withholds
        families, issue a UserWarning naming each and why (the CLI's `warning: do no harm: ...`);
        keep_withheld=True writes the full model (the CLI's --export --force) and warns that it
        did; its default (None) is diagnose's force. Coincident diagnoses have no such rule
        (keep_withheld changes nothing)."""
    def text(self) -> str: ...
    def to_json(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]:
        """Equal to json.loads of `handclasp diagnose ... --json`."""

def calibrate_points(
    p1_mm: Union[_Array, _Path],
    p2_mm: Optional[_Array] = None,
    method: Optional[str] = None,
    mounts: Optional[str] = None,
    mount1: Optional[str] = None,
    mount2: Optional[str] = None,
    tilt_sigma_deg: Optional[float] = None,
    point_sigma_mm: float = 0.5,
    expected_noise_mm: float = 5.0,
    force: bool = False,
) -> Union[PointsResult, PointsMethods]:
    """method="all" (--method all) returns a PointsMethods; any other method a PointsResult."""
def fk(
    robot: Union[_Path, Robot, Tuple[Cell, int]],
    q_deg: _Array,
    tip: Union[None, _Array, str] = None,
) -> _F64:
    """base_from_tip, (n, 4, 4) (or (4, 4) for one joint vector), translation in mm."""
def calibrate_cell(
    cell: Cell,
    session: Session,
    model: str = "kinematic",
    force: bool = False,
    work_points: Optional[Union[_Array, _Path]] = None,
    accept_mm: Optional[float] = None,
    accept_deg: Optional[float] = None,
) -> CellResult:
    """A refused result raises CalibrationError (its .result_check, .refusal) unless force=True.

    work_points ((n, 3) tool positions in base 1, mm, or a CSV path x_mm,y_mm,z_mm; default the
    cell's [teach] centre), accept_mm (mm), accept_deg (deg): the verdict at the work site, as
    `calibrate --cell --work-points F --accept-mm X --accept-deg Y` (result.work_site)."""
def diagnose(
    cell: Cell,
    session: Session,
    seed: int = 1,
    trials: int = 400,
    prior_widening: float = 10.0,
    truth_xyz_mm: Optional[Sequence[float]] = None,
    truth_zyz_deg: Optional[Sequence[float]] = None,
    work_points: Optional[Union[_Array, _Path]] = None,
    accept_mm: Optional[float] = None,
    accept_deg: Optional[float] = None,
    force: bool = False,
) -> DiagnoseResult:
    """work_points, accept_mm, accept_deg: the verdict at the work site of the model export()
    writes (whole-cell diagnoses; ValueError on a coincident-only session), as `diagnose
    --work-points F --accept-mm X --accept-deg Y` (result.work_site). force=True (--force): the
    verdict and export() are for the full model, the families the do-no-harm rule withholds
    included (to_dict()["work_site_model"]["model"] == "full")."""

class ValidateResult:
    """A calibrated cell scored on a session it was not fitted to, beside the nominal cell."""
    @property
    def all(self) -> Dict[str, Any]:
        """Over every row: rows, calibrated/nominal scores (rms_mm, max_mm, whitened_rms),
        rms_ratio (calibrated rms / nominal rms; below 1 the calibration helps)."""
    @property
    def warnings(self) -> List[str]:
        """The CLI's `warning:` lines (also issued as UserWarnings)."""
    def text(self) -> str: ...
    def to_json(self) -> str: ...
    def to_dict(self) -> Dict[str, Any]:
        """Equal to json.loads of `handclasp validate ... --json`."""

def validate(
    calibrated_cell: Cell,
    session: Union[Session, _Path],
    nominal: Optional[Cell] = None,
    nuisance: str = "split",
    calibration_session: Optional[Union[Session, _Path]] = None,
) -> ValidateResult:
    """handclasp validate --cell C --session S [--nominal N] [--nuisance split|fixed
    --calibration-session OLD]: each cell's held-out residuals per kind, per group and over
    all rows. nuisance="split" refits each group's tracker frame/plane/contact distance on
    alternate rows and scores the others; "fixed" fits them on calibration_session. A session
    path is read with the nominal cell first, then the calibrated one."""
def simulate_session(
    cell: Cell,
    n: int = 6,
    seed: int = 1,
    layout: str = "tetrahedron",
    spread_mm: float = 1000.0,
    centre_mm: Optional[Sequence[float]] = None,
    kind: str = "coincident",
) -> Session: ...
def plan(
    cell: Cell,
    n: int = 40,
    candidates: int = 400,
    criterion: str = "a",
    seed: int = 1,
    spread_mm: float = 1000.0,
    centre_mm: Optional[Sequence[float]] = None,
    random_draws: int = 20,
    out: Optional[_Path] = None,
) -> PlanResult:
    """handclasp plan: the poses (.session) and the report (.to_dict() == plan --json; .text())."""
def sweep(
    mounts: Optional[Sequence[str]] = None,
    noise_mm: Optional[Sequence[float]] = None,
    spread_mm: Optional[Sequence[float]] = None,
    n_points: Optional[Sequence[int]] = None,
    methods: Optional[Sequence[str]] = None,
    trials: Optional[int] = None,
    seed: int = 1,
    trials_table: bool = False,
    mode: str = "geometry",
    layout: Optional[str] = None,
    kinematic_errors: str = "none",
    cells: Optional[Sequence[Cell]] = None,
) -> Dict[str, Union[_F64, List[str]]]:
    """sim-cell sweep; mode="robot" (--mode robot) with layout, kinematic_errors, cells."""
def import_session(cell: Cell, map: _Path, inputs: Sequence[_Path]) -> Session:
    """A dataset's CSV files as a session of `cell`, as a mapping file says (handclasp import)."""
def export_controllers(
    cell: Cell,
    to: _Path,
    formats: Optional[Sequence[str]] = None,
    force: bool = False,
) -> Dict[str, Any]:
    """The cell's b1_from_b2 for ABB, KUKA, Fanuc, Yaskawa and ROS 2 written into `to`, each file
    read back and checked (handclasp export); returns its --json report as a dict."""
