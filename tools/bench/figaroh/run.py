#!/usr/bin/env python3
"""handclasp against FIGAROH on the same calibration problem (issue 25, item 4).

One command, from the repository root:

    python3 tools/bench/figaroh/run.py            # sizes 20,40,200,2000; writes out/bench-figaroh/

It (1) makes a virtual environment OUT/venv with FIGAROH and its dependencies
(requirements.txt beside this file, from PyPI) and re-runs itself inside it, (2) builds the
release `handclasp` and `sim-cell`, (3) simulates the sessions with the repository's simulator
on cell.toml (seeded), (4) fits each session with `handclasp calibrate --cell --model kinematic`
and with FIGAROH's geometric calibration (`BaseCalibration`, estimators `structural` and `map`),
timing the fits only, and (5) scores every fit the same way against the cell's truth on held-out
poses. It prints a table and writes OUT/results.json and OUT/table.md. Nothing here runs in
`cargo test` or CI (it downloads packages). README.md beside this file says what is compared and
why the two problems are the same.

The problem. cell.toml's robot 1 is perfect and held at nominal (tolerance 0), so a coincident
handclasp row is an external measurement of robot 2's tip in base 1: p_b1 = FK1(q1) (the
session's r1_*_mm columns) against q2 (r2_q*_deg). That is FIGAROH's problem: one robot (hp20)
measured in a fixed frame, unknowns the frame (b1_from_b2 = FIGAROH's base frame), the joint
placements (full_params: xyz and rpy of every joint origin, which hold the joint offsets and the
link lengths) and the tip. handclasp fits the same data with the same unknowns (placement, robot
2's joint offsets, origin xyz/rpy, tip).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
import tomllib
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
IN_VENV_FLAG = "HANDCLASP_FIGAROH_BENCH_VENV"

# The stopping rule both tools use. handclasp's whole-cell LM (calib_core::LmOptions::whole_cell)
# stops when an accepted step lowers the cost by less than 1e-10 relative (or the Gauss-Newton
# step predicts less) and has no step or gradient test; scipy's least_squares (FIGAROH's solver,
# MINPACK lmdif for method="lm") gets ftol = 1e-10, and xtol = gtol = machine epsilon, the
# smallest scipy accepts for "lm", so that in practice only the cost test stops it.
COST_TOLERANCE = 1e-10
EPS = 2.220446049250313e-16


# ---------------------------------------------------------------- setup (outside the venv)


def ensure_venv(out: Path) -> Path:
    """OUT/venv with requirements.txt installed; returns its python."""
    venv = out / "venv"
    py = venv / "bin" / "python"
    req = HERE / "requirements.txt"
    stamp = venv / ".requirements"
    if py.exists() and stamp.exists() and stamp.read_text() == req.read_text():
        return py
    print(f"setting up {venv} (pip install -r {req.relative_to(REPO)})", file=sys.stderr)
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    subprocess.run([str(py), "-m", "pip", "install", "-q", "--upgrade", "pip"], check=True)
    subprocess.run([str(py), "-m", "pip", "install", "-q", "-r", str(req)], check=True)
    stamp.write_text(req.read_text())
    return py


# ---------------------------------------------------------------- helpers


def loadavg() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def run(cmd, **kw):
    return subprocess.run([str(c) for c in cmd], check=True, **kw)


def rot_zyz(deg):
    import numpy as np

    a, b, c = (math.radians(v) for v in deg)

    def rz(t):
        return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])

    def ry(t):
        return np.array([[math.cos(t), 0, math.sin(t)], [0, 1, 0], [-math.sin(t), 0, math.cos(t)]])

    return rz(a) @ ry(b) @ rz(c)


def read_session(path: Path, n1: int, n2: int):
    """(q1 deg, q2 rad, p_b1 m) of a coincident session CSV (crates/sim-cell/README.md)."""
    import csv

    import numpy as np

    rows = list(csv.DictReader(open(path, newline="")))
    q1 = np.array([[float(r[f"r1_q{i}_deg"]) for i in range(1, n1 + 1)] for r in rows])
    q2 = np.radians([[float(r[f"r2_q{i}_deg"]) for i in range(1, n2 + 1)] for r in rows])
    p1 = np.array([[float(r[f"r1_{a}_mm"]) for a in "xyz"] for r in rows]) / 1e3
    return q1, q2, p1


class Arm:
    """One robot as pinocchio evaluates it: URDF, tip (tool0 frame), base placement, and the
    truth's joint offsets (rad, added to the reported angles). Tip positions in base 1, m."""

    def __init__(self, urdf, tip_m, b1_from_b, offsets=None, origin_xyz=None):
        import numpy as np
        import pinocchio as pin

        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(urdf))
        self.data = self.model.createData()
        self.fid = self.model.getFrameId("tool0")
        self.tip = np.asarray(tip_m, float)
        self.X = b1_from_b
        self.offsets = np.zeros(self.model.nq) if offsets is None else np.asarray(offsets)
        if origin_xyz is not None:  # added to each joint's <origin xyz> (parent frame)
            for j, d in enumerate(origin_xyz, start=1):
                self.model.jointPlacements[j].translation = (
                    self.model.jointPlacements[j].translation + np.asarray(d)
                )

    def tips_b1(self, q):
        import numpy as np

        out = np.empty((len(q), 3))
        for i, qi in enumerate(q):
            self.pin.framesForwardKinematics(self.model, self.data, qi + self.offsets)
            out[i] = self.X.act(self.data.oMf[self.fid].act(self.tip))
        return out


def se3(R, t):
    import numpy as np
    import pinocchio as pin

    return pin.SE3(np.asarray(R, float), np.asarray(t, float))


def truth_arm(cell: dict, cell_dir: Path) -> Arm:
    """Robot 2 as cell.toml's truth: nominal URDF + [robot2.errors] at the true placement."""
    import numpy as np

    r2 = cell["robot2"]
    errors = r2.get("errors", {})
    unknown = set(errors) - {"joint_offset_deg", "origin_xyz_mm"}
    if unknown:
        sys.exit(
            f"error: {cell_dir}/cell.toml: [robot2.errors] keys {sorted(unknown)} are not modelled "
            "by run.py's truth (joint_offset_deg and origin_xyz_mm only); remove them or extend "
            "truth_arm()"
        )
    placement = cell["b1_from_b2"]
    X = se3(rot_zyz(placement["zyz_deg"]), np.array(placement["xyz_mm"]) / 1e3)
    offsets = np.radians(errors.get("joint_offset_deg", [0.0] * 6))
    origin_xyz = np.array(errors.get("origin_xyz_mm", [[0.0] * 3] * 6)) / 1e3
    arm = Arm((cell_dir / r2["urdf"]).resolve(), np.array(r2["tip_mm"]) / 1e3, X, offsets, origin_xyz)
    # The placement a fit can find: joint 1's offset and origin error move the whole arm like a
    # move of its base, so both tools hold them at 0 and the placement absorbs them (handclasp:
    # "confounded_with_placement"; FIGAROH: no joint-1 base parameter). For joint 1 about z with
    # its origin on the z axis that is X·Trans(δxyz)·Rz(offset).
    model = arm.model
    j1 = model.joints[1]
    if j1.shortname() != "JointModelRZ" or np.any(np.abs(model.jointPlacements[1].translation[:2]) > 0):
        sys.exit("error: run.py's identifiable placement assumes joint 1 about z with its origin on z")
    rz = np.array([[math.cos(offsets[0]), -math.sin(offsets[0]), 0], [math.sin(offsets[0]), math.cos(offsets[0]), 0],
                   [0, 0, 1]])
    arm.X_identifiable = X * se3(np.eye(3), origin_xyz[0]) * se3(rz, np.zeros(3))
    return arm


def placement_error(X_fit, X):
    """(e_tran mm, e_rot deg) of a fitted placement against X."""
    import numpy as np
    import pinocchio as pin

    e_tran = np.linalg.norm(X_fit.translation - X.translation) * 1e3
    e_rot = np.degrees(np.linalg.norm(pin.log3(X_fit.rotation.T @ X.rotation)))
    return float(e_tran), float(e_rot)


def score(P_fit, truth, heldout_q2, X_fit):
    """Held-out tip error (rms, max, mm) and placement error (e_tran mm, e_rot deg) against the
    true placement and against the identifiable one (Arm.X_identifiable)."""
    import numpy as np

    e = np.linalg.norm(P_fit - truth.tips_b1(heldout_q2), axis=1) * 1e3
    e_tran, e_rot = placement_error(X_fit, truth.X)
    e_tran_id, e_rot_id = placement_error(X_fit, truth.X_identifiable)
    return {
        "heldout_rms_mm": float(np.sqrt(np.mean(e**2))),
        "heldout_max_mm": float(e.max()),
        "e_tran_mm": e_tran,
        "e_rot_deg": e_rot,
        "e_tran_identifiable_mm": e_tran_id,
        "e_rot_identifiable_deg": e_rot_id,
    }


def summary(times):
    return {
        "median": statistics.median(times),
        "min": min(times),
        "max": max(times),
        "runs": len(times),
    }


# ---------------------------------------------------------------- handclasp


def handclasp_side(bins, cell_path, session, out_dir, reps, truth, heldout_q2):
    """Times `handclasp calibrate --cell --model kinematic --json` (wall and CPU of the
    process), then exports the same fit and scores it with pinocchio."""
    import numpy as np

    cmd = [bins / "handclasp", "calibrate", "--cell", cell_path, "--session", session,
           "--model", "kinematic", "--json"]
    walls, cpus, outputs = [], [], []
    load_before = loadavg()
    for _ in range(reps):
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        p = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if p.returncode != 0:
            sys.exit(f"error: {' '.join(map(str, cmd))} failed:\n{p.stderr}")
        walls.append(wall)
        cpus.append((r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime))
        outputs.append(p.stdout)
    load_after = loadavg()
    if len(set(outputs)) != 1:
        sys.exit("error: handclasp calibrate gave different JSON on identical runs")
    fit = json.loads(outputs[0])

    export = out_dir / "export"
    shutil.rmtree(export, ignore_errors=True)
    run(cmd + ["--export", export], capture_output=True)
    exported = tomllib.loads((export / "cell.toml").read_text())
    if "errors" in exported["robot2"]:
        sys.exit(f"error: {export}/cell.toml has [robot2.errors]; run.py scores URDF + tip only")
    pl = exported["b1_from_b2"]
    X_fit = se3(rot_zyz(pl["zyz_deg"]), np.array(pl["xyz_mm"]) / 1e3)
    # the JSON's placement and the exported one are the same fit
    X_json = se3(fit["b1_from_b2"]["rotation"], np.array(fit["b1_from_b2"]["xyz_mm"]) / 1e3)
    drift = np.linalg.norm(X_json.translation - X_fit.translation) * 1e3
    if drift > 1e-6:
        sys.exit(f"error: exported placement differs from the JSON's by {drift:.2e} mm")
    arm = Arm(export / exported["robot2"]["urdf"], np.array(exported["robot2"]["tip_mm"]) / 1e3, X_fit)
    res = score(arm.tips_b1(heldout_q2), truth, heldout_q2, X_fit)
    res.update(
        wall_s=summary(walls), cpu_s=summary(cpus), load_before=load_before, load_after=load_after,
        parameters=len(fit["parameters"]) + 6, stop=f"{fit['stopped']}, {fit['iterations']} it",
    )
    return res


# ---------------------------------------------------------------- FIGAROH


LSQ_CALLS = []  # (parameters, residuals, nfev, seconds) of each least_squares call FIGAROH makes


def figaroh_setup(common_tolerance=True):
    """Imports FIGAROH and wraps its least_squares calls: the common stopping rule (unless
    `common_tolerance` is off: scipy's defaults, as FIGAROH ships) and a record in LSQ_CALLS."""
    warnings.filterwarnings("ignore", message="to-Python converter")
    import numpy as np
    import pinocchio as pin
    from scipy.optimize import least_squares

    import figaroh.calibration.base_calibration as base_calibration
    import figaroh.calibration.estimation as estimation
    from figaroh.calibration import BaseCalibration
    from figaroh.calibration.calibration_tools import calc_updated_fkm

    def least_squares_recorded(fun, x0, **kw):
        if common_tolerance:
            kw.update(ftol=COST_TOLERANCE, xtol=EPS, gtol=EPS)
        t0 = time.perf_counter()
        result = least_squares(fun, x0, **kw)
        LSQ_CALLS.append((len(x0), len(result.fun), int(result.nfev), time.perf_counter() - t0))
        return result

    # FIGAROH calls scipy's least_squares with its defaults (ftol = xtol = gtol = 1e-8) in
    # BaseCalibration._optimize_with_outlier_removal and estimation._fit (the `map` estimator's
    # preliminary free fit of every parameter its Jacobian does not show to be dependent).
    base_calibration.least_squares = least_squares_recorded
    estimation.least_squares = least_squares_recorded

    class CellCalibration(BaseCalibration):
        """FIGAROH's calibration of robot 2 with the cost its examples use: the measured
        position minus the model's, in metres (world frame = base 1)."""

        def cost_function(self, var):
            pee = calc_updated_fkm(self.model, self.data, var, self.q_measured, self.calib_config)
            return pee - self.PEE_measured

    return np, pin, CellCalibration, calc_updated_fkm


def figaroh_config(path: Path, data_csv: Path, n: int, method: str, sigma_m: float, priors: dict):
    import yaml

    config = {
        "robot": {"name": "hp20"},
        "tasks": {
            "calibration": {
                "type": "kinematic_calibration",
                "parameters": {
                    "calibration_level": "full_params",
                    "include_non_geometric": False,
                    "outlier_threshold": 0.05,  # FIGAROH's default (m); nothing is that far off
                    "random_seed": 0,
                    "estimation": {"method": method, "noise_std": sigma_m, "priors": priors},
                },
                "kinematics": {"base_frame": "universe", "tool_frame": "tool0"},
                "measurements": {
                    "markers": [
                        {
                            "name": "tip",
                            "reference_joint": "joint_6_t",
                            "measurable_dof": [True, True, True, False, False, False],
                        }
                    ]
                },
                "data": {"source_file": str(data_csv), "number_of_samples": n},
            }
        },
    }
    path.write_text(yaml.safe_dump(config, sort_keys=False))


def figaroh_side(fig, urdf, config, reps, truth, heldout_q2):
    """Times FIGAROH's calibration from files to fitted parameters (robot load, config, data,
    parameter selection, least squares with its report), in-process, then scores the fit."""
    np, pin, CellCalibration, calc_updated_fkm = fig
    from figaroh.calibration.calibration_tools import cartesian_to_SE3
    from figaroh.calibration.parameter import BASE_TPL
    from figaroh.tools.load_robot import load_robot

    walls, cpus, xs = [], [], []
    load_before = loadavg()
    for _ in range(reps):
        LSQ_CALLS.clear()
        pin.seed(0)
        np.random.seed(0)
        t0, c0 = time.perf_counter(), time.process_time()
        with contextlib.redirect_stdout(io.StringIO()):
            robot = load_robot(str(urdf), load_by_urdf=True)
            cal = CellCalibration(robot, str(config))
            cal.calib_config["known_baseframe"] = False
            cal.calib_config["known_tipframe"] = False
            cal.initialize()
            result = cal.solve(plotting=False, enable_logging=False)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        xs.append(result.x.copy())
    load_after = loadavg()
    if any(not np.array_equal(x, xs[0]) for x in xs):
        sys.exit("error: FIGAROH gave different parameters on identical runs")

    names = list(cal.calib_config["param_name"])
    x = dict(zip(names, result.x))
    X_fit = cartesian_to_SE3([x[b] for b in BASE_TPL])
    cfg = dict(cal.calib_config, NbSample=len(heldout_q2))
    pee = calc_updated_fkm(cal.model, cal.data, result.x, heldout_q2, cfg)
    P_fit = pee.reshape(3, len(heldout_q2)).T
    res = score(P_fit, truth, heldout_q2, X_fit)
    res.update(
        wall_s=summary(walls), cpu_s=summary(cpus), load_before=load_before, load_after=load_after,
        parameters=len(names),
        stop=(("ftol" if result.status in (2, 3) else f"status {result.status}")
              + (", " if result.success else ", FAILED, ")
              + " + ".join(f"{c[2]} fev" for c in LSQ_CALLS)),
        least_squares_calls=[
            {"parameters": c[0], "residuals": c[1], "nfev": c[2], "seconds": c[3]} for c in LSQ_CALLS
        ],
    )
    return res


def write_figaroh_data(path: Path, joint_names, q2, p1):
    """FIGAROH's CSV (PoseObservations.from_csv): x1,y1,z1 (m) and one column per joint (rad)."""
    with open(path, "w") as f:
        f.write(",".join(["x1", "y1", "z1", *joint_names]) + "\n")
        for p, q in zip(p1, q2):
            f.write(",".join(repr(float(v)) for v in (*p, *q)) + "\n")


# ---------------------------------------------------------------- main


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="20,40,200,2000", help="session sizes (points)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the training sessions")
    ap.add_argument("--heldout", type=int, default=500, help="held-out poses (seed + 1000)")
    ap.add_argument("--reps-handclasp", type=int, default=7, help="timed runs per size")
    ap.add_argument("--reps-figaroh", type=int, default=3, help="timed runs per size and estimator")
    ap.add_argument("--map-max-points", type=int, default=200,
                    help="run FIGAROH `map` only up to this many points (its preliminary free fit "
                         "takes ~2 min at 200 points and far longer at 2000)")
    ap.add_argument("--figaroh-tolerance", choices=["common", "default"], default="common",
                    help="common: FIGAROH's least_squares stops as handclasp does (ftol 1e-10); "
                         "default: scipy's defaults, as FIGAROH ships (ftol = xtol = gtol = 1e-8)")
    ap.add_argument("--estimators", default="structural,map", help="FIGAROH estimation methods")
    ap.add_argument("--cell", type=Path, default=HERE / "cell.toml")
    ap.add_argument("--out", type=Path, default=REPO / "out" / "bench-figaroh")
    ap.add_argument("--no-build", action="store_true", help="use target/release as it is")
    args = ap.parse_args()
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)

    if os.environ.get(IN_VENV_FLAG) != "1":
        py = ensure_venv(out)
        os.environ[IN_VENV_FLAG] = "1"
        os.execv(str(py), [str(py), str(Path(__file__).resolve()), *sys.argv[1:]])

    import importlib.metadata as md

    if not args.no_build:
        run(["cargo", "build", "--release", "--locked", "-p", "handclasp", "-p", "sim-cell"], cwd=REPO)
    bins = REPO / "target" / "release"
    cell_path = args.cell.resolve()
    cell = tomllib.loads(cell_path.read_text())
    fig = figaroh_setup(args.figaroh_tolerance == "common")
    np = fig[0]
    truth = truth_arm(cell, cell_path.parent)
    joint_names = [truth.model.names[j] for j in range(1, truth.model.njoints)]
    n1 = fig[1].buildModelFromUrdf(str((cell_path.parent / cell["robot1"]["urdf"]).resolve())).nq

    # the same σ for both: handclasp reads the cell; FIGAROH `map` gets noise and priors from it
    sigma_m = float(cell["noise"]["alignment_mm"]) / 1e3
    tol = {"joint_offset_deg": 0.05, "origin_mm": 0.5, "origin_deg": 0.05, "tip_mm": 0.5}
    tol.update(cell["robot2"].get("tolerance", {}))
    priors = {
        "translation": tol["origin_mm"] / 1e3 / math.sqrt(3),
        "rotation": math.radians(tol["origin_deg"]) / math.sqrt(3),
        "joint_offset": math.radians(tol["joint_offset_deg"]) / math.sqrt(3),
    }

    data = out / "data"
    data.mkdir(exist_ok=True)
    sim = [bins / "sim-cell", "session", "--cell", cell_path, "--layout", "random"]
    heldout_csv = data / "heldout.csv"
    run(sim + ["--n", args.heldout, "--seed", args.seed + 1000, "--noise-mm", 0, "--out", heldout_csv],
        capture_output=True)
    _, heldout_q2, heldout_p1 = read_session(heldout_csv, n1, len(joint_names))
    # The truth model reproduces the simulator: on the noise-free held-out session robot 2's
    # true tip (this script's pinocchio model of cell.toml's errors) meets robot 1's. What is
    # left is the 0.001° encoder rounding of both robots' joints (~10 µm).
    check = np.linalg.norm(truth.tips_b1(heldout_q2) - heldout_p1, axis=1) * 1e3
    nominal = Arm(truth_urdf(cell, cell_path.parent), np.array(cell["robot2"]["tip_mm"]) / 1e3, truth.X)
    nominal_err = np.linalg.norm(nominal.tips_b1(heldout_q2) - heldout_p1, axis=1) * 1e3
    truth_rms = float(np.sqrt(np.mean(check**2)))
    nominal_rms = float(np.sqrt(np.mean(nominal_err**2)))
    if truth_rms > 0.05:
        sys.exit(f"error: the truth model misses the simulator's tips by {truth_rms:.3f} mm rms")

    versions = {p: md.version(p) for p in ("figaroh", "pin", "numpy", "scipy")}
    versions["handclasp"] = subprocess.run([str(bins / "handclasp"), "--version"], capture_output=True,
                                           text=True).stdout.strip()
    versions["python"] = sys.version.split()[0]
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True,
                          text=True).stdout.strip()
    t_import = subprocess.run(
        [sys.executable, "-c", "import time; t = time.perf_counter(); import figaroh.calibration, "
         "pinocchio, scipy.optimize; print(time.perf_counter() - t)"],
        capture_output=True, text=True).stdout.strip()
    print(f"versions: {versions}; head {head}")
    print(f"truth check: simulator vs run.py truth {truth_rms:.4f} mm rms on {len(check)} held-out poses;"
          f" nominal robot 2 at the true placement {nominal_rms:.3f} mm rms")
    print(f"load at start (1, 5, 15 min): {loadavg()}; {os.cpu_count()} cores")

    results = []
    for n in [int(s) for s in args.sizes.split(",")]:
        session = data / f"session_{n}.csv"
        run(sim + ["--n", n, "--seed", args.seed, "--out", session], capture_output=True)
        _, q2, p1 = read_session(session, n1, len(joint_names))
        fig_csv = data / f"figaroh_{n}.csv"
        write_figaroh_data(fig_csv, joint_names, q2, p1)

        r = handclasp_side(bins, cell_path, session, out / f"handclasp_{n}", args.reps_handclasp, truth,
                           heldout_q2)
        results.append({"points": n, "tool": "handclasp kinematic (MAP, tolerance prior)", **r})
        print(row_text(results[-1]), flush=True)
        for method in args.estimators.split(","):
            if method == "map" and n > args.map_max_points:
                print(f"{n:>5} FIGAROH map: not run (--map-max-points {args.map_max_points})", flush=True)
                continue
            cfg = data / f"figaroh_{n}_{method}.yaml"
            figaroh_config(cfg, fig_csv, n, method, sigma_m, priors)
            r = figaroh_side(fig, truth_urdf(cell, cell_path.parent), cfg, args.reps_figaroh, truth, heldout_q2)
            label = {"structural": "FIGAROH structural (free LSQ, QR base params)",
                     "map": "FIGAROH map (Gaussian prior = tolerance/√3)"}.get(method, f"FIGAROH {method}")
            results.append({"points": n, "tool": label, **r})
            print(row_text(results[-1]), flush=True)

    meta = {
        "versions": versions, "head": head, "cell": str(cell_path.relative_to(REPO)),
        "seed": args.seed, "heldout": args.heldout, "heldout_seed": args.seed + 1000,
        "truth_check_rms_mm": truth_rms, "nominal_heldout_rms_mm": nominal_rms,
        "figaroh_import_s": t_import, "figaroh_tolerance": args.figaroh_tolerance,
        "cost_tolerance": COST_TOLERANCE, "load_end": loadavg(),
        "command": "python3 tools/bench/figaroh/run.py " + " ".join(sys.argv[1:]),
    }
    (out / "results.json").write_text(json.dumps({"meta": meta, "rows": results}, indent=1))
    table = markdown_table(results)
    (out / "table.md").write_text(table)
    print()
    print(table)
    print(f"load at end: {loadavg()}; FIGAROH import (not timed above): {float(t_import):.2f} s")
    print(f"wrote {out / 'results.json'} and {out / 'table.md'}")


def truth_urdf(cell, cell_dir):
    return (cell_dir / cell["robot2"]["urdf"]).resolve()


def row_text(r):
    return (f"{r['points']:>5} {r['tool']:<48} wall {r['wall_s']['median']:8.3f} s  cpu {r['cpu_s']['median']:8.3f} s"
            f"  held-out {r['heldout_rms_mm']:.3f}/{r['heldout_max_mm']:.3f} mm"
            f"  placement {r['e_tran_mm']:.3f} mm {r['e_rot_deg']:.4f}° (identifiable {r['e_tran_identifiable_mm']:.3f} mm"
            f" {r['e_rot_identifiable_deg']:.4f}°)  [{r['stop']}; load {r['load_before']} -> {r['load_after']}]")


def markdown_table(rows):
    lines = [
        "| points | tool | parameters | fit wall, median [min–max], runs | fit CPU, median "
        "| held-out tip rms / max | placement e_tran / e_rot | against the identifiable placement "
        "| stop | load (1 min) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        w, c = r["wall_s"], r["cpu_s"]
        lines.append(
            f"| {r['points']} | {r['tool']} | {r['parameters']} | **{fmt_s(w['median'])}** "
            f"[{fmt_s(w['min'])}–{fmt_s(w['max'])}], {w['runs']} | {fmt_s(c['median'])} | "
            f"**{r['heldout_rms_mm']:.3f}** / {r['heldout_max_mm']:.3f} mm | "
            f"{r['e_tran_mm']:.3f} mm / {r['e_rot_deg']:.4f}° | "
            f"{r['e_tran_identifiable_mm']:.3f} mm / {r['e_rot_identifiable_deg']:.4f}° | {r['stop']} | "
            f"{r['load_before'].split()[0]} → {r['load_after'].split()[0]} |"
        )
    return "\n".join(lines) + "\n"


def fmt_s(s):
    return f"{s * 1e3:.0f} ms" if s < 1 else f"{s:.2f} s"


if __name__ == "__main__":
    main()
