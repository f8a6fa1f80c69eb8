"""handclasp: base-frame calibration of two cooperating robots and whole robot cells.

The engine of the ``handclasp`` command with numpy arrays in and out. Units are the files' and
the CLI's: millimetres and degrees (ZYZ, ``R = Rz(phi)·Ry(theta)·Rz(psi)``). Frames are named
``a_from_b`` (``p_a = a_from_b @ p_b``): ``b1_from_b2`` is robot 2's base in robot 1's base,
the calibration result; 4×4 matrices carry their translation in mm.

Entry points (each mirrors a CLI command; ``.to_dict()`` equals its ``--json`` output):

- ``calibrate_points(p1_mm, p2_mm, method=...)``: ``handclasp calibrate POINTS.csv`` (``method="all"``:
  ``--method all``)
- ``fk(robot, q_deg, tip=None)``: ``handclasp fk`` for many joint vectors at once
- ``Cell.load(path)``, ``Session.load(path, cell)``, ``Session.from_arrays(cell, q1_deg, q2_deg)``
- ``import_session(cell, map, inputs)``: ``handclasp import`` (a dataset's CSVs → a session)
- ``calibrate_cell(cell, session, model="kinematic")``: ``handclasp calibrate --cell`` (with
  ``work_points``, ``accept_mm``, ``accept_deg``: the verdict at the work site; ``.report(path)``:
  ``--report``)
- ``diagnose(cell, session)``: ``handclasp diagnose`` (the same verdict arguments, ``.report(path)``)
- ``export_controllers(cell, to, formats=None)``: ``handclasp export`` (ABB, KUKA, Fanuc, Yaskawa,
  ROS 2 files of the cell's ``b1_from_b2``)
- ``simulate_session(cell, n, seed)``, ``plan(cell, n)``: ``sim-cell session``, ``handclasp plan`` (a ``PlanResult``:
  ``.session``, ``.to_dict()``)
- ``validate(calibrated_cell, session, nominal=None, nuisance="split")``: ``handclasp validate`` (a
  calibrated cell scored on data it was not fitted to, beside the nominal cell)
- ``sweep(...)``: ``sim-cell sweep``, a seeded Monte Carlo of the points fit over the paper's cells
  (``mode="robot"``: full simulated sessions on the robots, the whole-cell methods too)

Errors: ``ValueError`` for bad shapes, NaN and invalid input; ``OSError`` subclasses for file
problems; ``CalibrationError`` when a fit fails. Long calls release the GIL.
"""

from __future__ import annotations

import warnings as _warnings
from typing import Any, Dict

from . import _handclasp
from ._handclasp import (
    CalibrationError,
    Cell,
    CellResult,
    DiagnoseResult,
    PlanResult,
    PointsMethods,
    PointsResult,
    Robot,
    Session,
    ValidateResult,
    calibrate_cell,
    diagnose,
    export_controllers,
    fk,
    import_session,
    plan,
    simulate_session,
    validate,
)

__version__ = _handclasp.__version__

__all__ = [
    "CalibrationError",
    "Cell",
    "CellResult",
    "DiagnoseResult",
    "PlanResult",
    "PointsMethods",
    "PointsResult",
    "Robot",
    "Session",
    "ValidateResult",
    "calibrate_cell",
    "calibrate_points",
    "diagnose",
    "export_controllers",
    "fk",
    "frame",
    "import_session",
    "plan",
    "simulate_session",
    "sweep",
    "validate",
]


def frame(columns: Dict[str, Any]) -> Any:
    """A dict of columns as a pandas DataFrame when pandas is installed, else the dict itself."""
    try:
        import pandas
    except ImportError:
        return columns
    return pandas.DataFrame(columns)


def calibrate_points(p1_mm: Any, p2_mm: Any = None, **options: Any) -> Any:
    """Fit ``b1_from_b2`` from handclasp points, as ``handclasp calibrate POINTS.csv`` does.

    ``p1_mm``, ``p2_mm``: (n, 3) arrays of the same physical points in base 1 and base 2, mm;
    or ``p1_mm`` a points CSV path and ``p2_mm`` None. Options (as the CLI's flags):
    ``method`` (generic, generic-affine, paper, lsq, constrained; default constrained with
    mounts, else lsq), ``mounts`` (floor-floor, floor-wall, floor-ceiling) or ``mount1`` and
    ``mount2`` (floor, ceiling, wall, tilt:RX,RY in degrees), ``tilt_sigma_deg`` and
    ``point_sigma_mm`` (soft mount), ``expected_noise_mm`` (default 5), ``force``.

    Returns a ``PointsResult``: ``.b1_from_b2`` (4×4, mm), ``.residuals_mm`` (n, 3),
    ``.uncertainty``, ``.covariance``, ``.to_dict()`` (the CLI's JSON). A misfit kept by
    ``force=True`` is issued as a ``UserWarning``.

    ``method="all"`` (``--method all``): every method (paper and constrained only with mounts),
    as a ``PointsMethods``: ``.results`` (method name → ``PointsResult``), ``.errors`` (method
    name → why it does not apply), ``result["lsq"]``, ``.to_dict()`` (the CLI's ``--method all
    --json``).
    """
    result = _handclasp.calibrate_points(p1_mm, p2_mm, **options)
    for w in getattr(result, "warnings", []):
        _warnings.warn(w, UserWarning, stacklevel=2)
    return result


def sweep(**options: Any) -> Any:
    """A seeded Monte Carlo sweep over the paper's cells (``sim-cell sweep``): one row per grid
    cell (mounts × noise × spread × points) and method, errors in mm and degrees. Options:
    ``mounts`` (list of floor-floor, floor-wall, floor-ceiling), ``noise_mm``, ``spread_mm``,
    ``n_points``, ``methods``, ``trials`` (per grid cell, default 200 in geometry mode, 5 in
    robot mode), ``seed`` (default 1), ``trials_table`` (the per-trial table instead of the
    summary), ``mode`` (``"geometry"``: points and noise only, the default; ``"robot"``: full
    sessions on the robots, ``--mode robot``, with methods ``paper-spread4``, ``placement``,
    ``kinematic`` too), and in robot mode ``layout`` (tetrahedron, random, planar, clustered,
    planned), ``kinematic_errors`` (``"none"`` or ``"tolerance"``) and ``cells`` (a list of
    ``Cell`` instead of the paper's; their mounts replace ``mounts``).

    Returns a pandas DataFrame when pandas is installed, else a dict of columns (numpy arrays,
    lists of str for text columns).
    """
    return frame(_handclasp.sweep(**options))
