#!/usr/bin/env python3
"""Score calibrated CTU cells the way the hidden set will be scored: through `handclasp fk`.

For each cell and each tracker file that the example scores (the (file, arm) rows of its
`scores.csv`), this writes the moving arm's joint angles as a `--q-csv` (q1_deg … q6_deg), runs
`handclasp fk --cell CELL --robot 1|2 --q-csv … --out …` (tool0 poses, mm and quaternions, in that
robot's base), and applies the issue's protocol with its own code: one rigid registration plus the
reflector's offset on the flange, fitted on one seeded half of the file's poses and scored on the
other half, both ways. It prints rms per file and pooled, beside the example's own figure from
`scores.csv` (which uses its own FK and its own split, so the two agree to the split's scatter, not
digit for digit).

This checks the path the issue's owner will use for the hidden set (`handclasp fk` on the exported
`cell.toml`, compliance included) against the example's internal scoring. Python 3 + numpy + scipy;
shares no code with the Rust crates (the protocol helpers come from study.py in this folder).

Run (after `cargo run --release -p ctu-motoman -- --data D --out OUT` and
`cargo build --release --bin handclasp`):
  python3 tools/ctu-motoman/score_fk.py --data ../shared/data/ctu-motoman --study OUT \
      [--handclasp target/release/handclasp] [--models nominal,self,planes,all]
`nominal` is `cells/ctu-motoman.toml`; any other name is `OUT/NAME/cell.toml`.
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from dh import EE_REFLECTOR, ee_tip  # noqa: E402
from study import JOINTS, halves, kabsch, load, stats_mm, tracker_rows  # noqa: E402

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
ROBOT = {"right": 1, "left": 2}


def fk_poses(handclasp, cell, robot, q_rad, tmp):
    """tool0 rotations (N,3,3) and positions (N,3), m, from `handclasp fk --q-csv`."""
    q_path = os.path.join(tmp, "q.csv")
    out_path = os.path.join(tmp, "fk.csv")
    with open(q_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"q{i + 1}_deg" for i in range(len(JOINTS))])
        for q in q_rad:
            w.writerow([repr(float(np.degrees(v))) for v in q])
    subprocess.run([handclasp, "fk", "--cell", cell, "--robot", str(robot), "--q-csv", q_path,
                    "--out", out_path], check=True, capture_output=True)
    with open(out_path) as fh:
        rows = list(csv.DictReader(fh))
    t = np.array([[float(r[k]) * 1e-3 for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    quat_wxyz = np.array([[float(r[k]) for k in ("qw", "qx", "qy", "qz")] for r in rows])
    rot = Rotation.from_quat(quat_wxyz[:, [1, 2, 3, 0]]).as_matrix()
    return rot, t


def score(rot, t, p_tr, arm, seed):
    """The issue's protocol on fixed tool0 poses: per half, registration + reflector by least
    squares (start: Kabsch with the nominal reflector), scored on the other half; error norms, m."""
    def points(idx, tip):
        return t[idx] + np.einsum("nij,j->ni", rot[idx], tip)

    a, b = halves(len(t), seed)
    errs = []
    for fit_i, test_i in ((a, b), (b, a)):
        tip0 = ee_tip(EE_REFLECTOR[arm])
        r0, t0 = kabsch(points(fit_i, tip0), p_tr[fit_i])
        x0 = np.concatenate([Rotation.from_matrix(r0).as_rotvec(), t0, tip0])

        def res(x):
            return (Rotation.from_rotvec(x[:3]).apply(points(fit_i, x[6:9])) + x[3:6]
                    - p_tr[fit_i]).ravel()

        x = least_squares(res, x0, method="lm", xtol=1e-14, ftol=1e-14).x
        pred = Rotation.from_rotvec(x[:3]).apply(points(test_i, x[6:9])) + x[3:6]
        errs.append(np.linalg.norm(pred - p_tr[test_i], axis=1))
    return np.concatenate(errs)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="the CTU dataset folder (read in place)")
    ap.add_argument("--study", required=True, help="the example's --out folder")
    ap.add_argument("--handclasp", default=os.path.join(REPO, "target", "release", "handclasp"))
    ap.add_argument("--models", default="nominal,self,planes,all")
    ap.add_argument("--seed", type=int, default=12, help="seed of the halves (numpy) for the table")
    ap.add_argument("--seeds", type=int, default=1,
                    help="also score with seeds 0 … N-1 and count, per file, the wins over nominal")
    args = ap.parse_args()

    with open(os.path.join(args.study, "scores.csv")) as fh:
        rust = list(csv.DictReader(fh))
    files = []
    for r in rust:
        if (r["file"], r["arm"]) not in files:
            files.append((r["file"], r["arm"]))
    rust_rms = {(r["file"], r["arm"], r["model"]): float(r["rms_mm"]) for r in rust}
    models = args.models.split(",")
    cells = {m: (os.path.join(REPO, "cells", "ctu-motoman.toml") if m == "nominal"
                 else os.path.join(args.study, m, "cell.toml")) for m in models}
    for m, c in cells.items():
        if not os.path.isfile(c):
            sys.exit(f"{m}: no cell at {c} (run the example with --out {args.study} first)")

    # The example's row of each exported model: its `exported` column names the folder (older
    # outputs without it: the row of the same name).
    example_row = {m: m for m in models}
    for r in rust:
        if r.get("exported"):
            example_row[r["exported"]] = r["model"]
    poses = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, arm in files:
            d = load(os.path.join(args.data, f"{name}_dataset.csv"))
            idx = tracker_rows(d)
            for m in models:
                poses[name, arm, m] = fk_poses(args.handclasp, cells[m], ROBOT[arm], d["q"][arm][idx],
                                               tmp) + (d["p"][idx],)

    def per_file(seed):
        return {(name, arm, m): score(*poses[name, arm, m], arm, seed)
                for name, arm in files for m in models}

    errs = per_file(args.seed)
    print(f"held-out tracker rms, mm, seed {args.seed}: through `handclasp fk` (this script) | the "
          f"example's scores.csv (its own FK and split)")
    print(f"  {'file':<28} {'arm':<5} {'n':>4} " + " ".join(f"{m:>17}" for m in models))
    for name, arm in files:
        cols = []
        for m in models:
            theirs = rust_rms.get((name, arm, example_row[m]))
            cols.append(f"{stats_mm(errs[name, arm, m])['rms']:7.3f} | "
                        + (f"{theirs:7.3f}" if theirs is not None else "      -"))
        n = len(poses[name, arm, models[0]][1])
        print(f"  {name:<28} {arm:<5} {n:>4} " + " ".join(f"{c:>17}" for c in cols))
    n_all = sum(len(e) for (f, a, m), e in errs.items() if m == models[0])
    print(f"  {'pooled':<28} {'':<5} {n_all:>4} " + " ".join(
        f"{stats_mm(np.concatenate([e for k, e in errs.items() if k[2] == m]))['rms']:7.3f}          "
        for m in models))

    if args.seeds > 1 and "nominal" in models:
        print(f"\nover {args.seeds} seeds of the halves (0 … {args.seeds - 1}): per file, how often "
              f"each model's rms is below nominal's, and its mean rms (mm)")
        wins = {(f, a, m): 0 for f, a in files for m in models}
        total = {(f, a, m): 0.0 for f, a in files for m in models}
        everywhere = {m: 0 for m in models}
        for seed in range(args.seeds):
            e = per_file(seed)
            rms = {k: stats_mm(v)["rms"] for k, v in e.items()}
            for m in models:
                beats = [rms[f, a, m] < rms[f, a, "nominal"] for f, a in files]
                everywhere[m] += all(beats)
                for (f, a), b in zip(files, beats):
                    wins[f, a, m] += b
                    total[f, a, m] += rms[f, a, m]
        print(f"  {'file':<28} {'arm':<5} " + " ".join(f"{m:>14}" for m in models))
        for f, a in files:
            print(f"  {f:<28} {a:<5} " + " ".join(
                f"{wins[f, a, m]:>3}/{args.seeds:<3} {total[f, a, m] / args.seeds:6.3f}" for m in models))
        print(f"  {'beats nominal on every file':<34} " + " ".join(
            f"{everywhere[m]:>3}/{args.seeds:<10}" for m in models))


if __name__ == "__main__":
    main()
