#!/usr/bin/env python3
"""Model choice for FIGAROH's TIAGo data on the training file alone: k-fold cross-validation by pose.

For each candidate (tolerances of the cell's [robot1.tolerance], the blunder screen) and each fold,
calibrate on the training poses outside the fold (all four markers), then score marker 1 (BL) of
the fold's poses with `handclasp validate --nuisance fixed` (the registration fitted on the fold's
training poses, carried over: the published protocol in miniature). Prints the pooled BL rms per
candidate. Reads the data in place; writes only under a temporary folder.

Usage: tools/figaroh-tiago/cv.py [--bin target/debug] [--data ../shared/data/figaroh-tiago] [--folds 5]
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
TRAIN = "qualisys_2021-11-30_static_postures.csv"
# Candidates: name -> ([robot1.tolerance] keys, --screen). The defaults are the cell's
# (`calib_core::whole_cell::Tolerance::default`); the others scale all three by 0.3, 3, 10 and
# 100 (a service robot's arm may be built to looser tolerances than an industrial one), and the
# last holds the kinematics at nominal (FIGAROH's "registration only": the mocap frame and the
# marker positions).
CANDIDATES = {
    "default tolerances, screen auto": ({}, "auto"),
    "default tolerances, screen off": ({}, "off"),
    "0.3x tolerances, screen auto": ({"joint_offset_deg": 0.015, "origin_mm": 0.15, "origin_deg": 0.015}, "auto"),
    "3x tolerances, screen auto": ({"joint_offset_deg": 0.15, "origin_mm": 1.5, "origin_deg": 0.15}, "auto"),
    "10x tolerances, screen auto": ({"joint_offset_deg": 0.5, "origin_mm": 5.0, "origin_deg": 0.5}, "auto"),
    "10x tolerances, screen off": ({"joint_offset_deg": 0.5, "origin_mm": 5.0, "origin_deg": 0.5}, "off"),
    "100x tolerances, screen off": ({"joint_offset_deg": 5.0, "origin_mm": 50.0, "origin_deg": 5.0}, "off"),
    "registration and tools only (kinematics nominal)": (
        {"joint_offset_deg": 0.0, "origin_mm": 0.0, "origin_deg": 0.0}, "auto"),
}


def cell_text(urdf, tolerance):
    lines = [
        "[robot1]",
        f'urdf = "{urdf}"',
        'tool_link = "arm_tool_link"',
        'mount = "floor"',
        "tip_mm = [0.0, 0.0, 0.0]",
        "[robot1.tools]",
    ]
    lines += [f"{t} = [100.0, 0.0, 0.0]" for t in ("bl", "br", "tr", "tl")]
    lines += ["[robot1.tolerance]", "tip_mm = 300.0"]
    lines += [f"{k} = {v}" for k, v in tolerance.items()]
    return "\n".join(lines) + "\n"


def run(args):
    out = subprocess.run(args, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"failed: {' '.join(args)}\n{out.stderr}")
    return out.stdout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="target/debug")
    ap.add_argument("--data", default="../shared/data/figaroh-tiago")
    ap.add_argument("--folds", type=int, default=5)
    a = ap.parse_args()
    hc = os.path.join(a.bin, "handclasp")
    data = os.path.abspath(a.data)
    rows = list(csv.DictReader(open(os.path.join(data, TRAIN))))
    header = list(rows[0].keys())
    tmp = tempfile.mkdtemp(prefix="tiago-cv-")
    for name, (tolerance, screen) in CANDIDATES.items():
        cell = os.path.join(tmp, "cell.toml")
        open(cell, "w").write(cell_text(os.path.join(data, "tiago_48_schunk.urdf"), tolerance))
        sq, n = 0.0, 0
        for k in range(a.folds):
            part = {"fit": [r for i, r in enumerate(rows) if i % a.folds != k],
                    "test": [r for i, r in enumerate(rows) if i % a.folds == k]}
            files = {}
            for key, rs in part.items():
                src = os.path.join(tmp, f"{key}.csv")
                with open(src, "w", newline="") as f:
                    w = csv.DictWriter(f, header)
                    w.writeheader()
                    w.writerows(rs)
                files[key] = os.path.join(tmp, f"{key}-session.csv")
                m = "map.toml" if key == "fit" else "map_bl.toml"
                run([hc, "import", "--cell", cell, "--map", os.path.join(HERE, m), "--input", src,
                     "--out", files[key]])
            cal = os.path.join(tmp, f"cal{k}")
            model = ["--screen", screen]
            run([hc, "calibrate", "--cell", cell, "--session", files["fit"], "--force", "--overwrite",
                 "--export", cal] + model)
            v = run([hc, "validate", "--cell", os.path.join(cal, "cell.toml"), "--session", files["test"],
                     "--nuisance", "fixed", "--calibration-session", files["fit"], "--json"])
            score = json.loads(v)["all"]["calibrated"]["rms_mm"]
            sq += score ** 2 * len(part["test"])
            n += len(part["test"])
        print(f"{name:45s} CV BL rms {math.sqrt(sq / n):7.3f} mm over {n} poses ({a.folds} folds)")


if __name__ == "__main__":
    main()
