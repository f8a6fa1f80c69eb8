#!/usr/bin/env python3
"""FIGAROH's published protocol on its TIAGo data, with handclasp: calibrate on the training file
as the one-robot cell tools/figaroh-tiago/tiago.toml, then score marker 1 (BL) of every file with
the training registration (`handclasp validate --nuisance fixed`), and of the "new in-range" poses
of each held-out file. Reads the data in place; writes only under a temporary folder.

New in-range: FIGAROH's own definition (`posture_strata` in figaroh-examples'
examples/tiago/heldout_protocol.py): a held-out pose is "repeated" when some training pose is
within REPEAT_TOL on every joint (torso in m, arm in rad; max-abs difference), "out of range"
when some joint lies outside the training file's range widened by IN_RANGE_MARGIN, and "new in
range" otherwise. It gives the published counts (16, 17, 16).

The rows fitted are FIT_MAP's (marker 1 alone, as FIGAROH fits; chosen on the training file by
tools/figaroh-tiago/cv.py, see tiago.toml); marker 1 is scored. With --candidate NAME the fit is
cv.py's candidate of that name instead (its tolerances, `calibrate` arguments and fitted map,
exactly as cross-validated; choice-2026-11-28.md).

Usage: tools/figaroh-tiago/protocol.py [--bin DIR] [--data ../shared/data/figaroh-tiago]
       [--candidate NAME]
"""
import argparse
import atexit
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
TRAIN = "qualisys_2021-11-30_static_postures.csv"
HELD = {
    "validation": "qualisys_2021-11-26_static_postures.csv",
    "confirmation 14:03": "qualisys_2021-11-30-1403_static_postures.csv",
    "confirmation 15:04": "qualisys_2021-11-30-1504_static_postures.csv",
}
JOINTS = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]
REPEAT_TOL = 0.01
IN_RANGE_MARGIN = 0.05
FIT_MAP = "map_bl.toml"


def run(args):
    out = subprocess.run(args, capture_output=True, text=True)
    if out.returncode != 0 and "--force" not in args:
        sys.exit(f"failed: {' '.join(args)}\n{out.stderr}")
    return out.stdout


def rows_of(path):
    return list(csv.DictReader(open(path)))


def q(row):
    return [float(row[j]) for j in JOINTS]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=None,
                    help="folder of the handclasp binary (default: the one on PATH, else target/debug)")
    ap.add_argument("--data", default="../shared/data/figaroh-tiago")
    ap.add_argument("--candidate", default=None,
                    help="fit cv.py's candidate of this name (default: tiago.toml, FIT_MAP)")
    a = ap.parse_args()
    hc = os.path.join(a.bin, "handclasp") if a.bin else (
        shutil.which("handclasp") or os.path.join("target", "debug", "handclasp"))
    data = os.path.abspath(a.data)
    tmp = tempfile.mkdtemp(prefix="tiago-protocol-")
    atexit.register(shutil.rmtree, tmp, True)  # leave nothing behind
    cell = os.path.join(tmp, "tiago.toml")
    fit_map, extra = FIT_MAP, []
    if a.candidate is None:
        text = open(os.path.join(HERE, "tiago.toml")).read().replace(
            "../../../shared/data/figaroh-tiago", data)
    else:
        sys.path.insert(0, HERE)
        sys.dont_write_bytecode = True  # no __pycache__ beside the tools
        import cv  # the candidates as cross-validated
        if a.candidate not in cv.CANDIDATES:
            sys.exit(f"no candidate {a.candidate!r} in cv.py; known: {', '.join(cv.CANDIDATES)}")
        tolerance, extra, fit_map = cv.CANDIDATES[a.candidate]
        text = cv.cell_text(os.path.join(data, "tiago_48_schunk.urdf"), tolerance)
        print(f"candidate: {a.candidate}")
    open(cell, "w").write(text)

    def imp(map_name, src, out):
        run([hc, "import", "--cell", cell, "--map", os.path.join(HERE, map_name), "--input", src,
             "--out", out])

    train = os.path.join(tmp, "train.csv")
    imp(fit_map, os.path.join(data, TRAIN), train)
    cal = os.path.join(tmp, "cal")
    run([hc, "calibrate", "--cell", cell, "--session", train, "--force", "--export", cal] + extra)

    def score(src, name):
        session = os.path.join(tmp, f"{name}.csv")
        imp("map_bl.toml", src, session)
        v = json.loads(run([hc, "validate", "--cell", os.path.join(cal, "cell.toml"), "--session",
                            session, "--nuisance", "fixed", "--calibration-session", train,
                            "--json"]))
        return v["all"]["calibrated"]["rms_mm"], v["all"]["calibrated"]["max_mm"], v["all"]["rows"]

    print(f"{'file':34s} {'poses':>5s} {'BL rms mm':>9s} {'max mm':>7s}")
    r = score(os.path.join(data, TRAIN), "training")
    print(f"{'training':34s} {r[2]:5d} {r[0]:9.3f} {r[1]:7.3f}")
    train_q = [q(x) for x in rows_of(os.path.join(data, TRAIN))]
    lo = [min(c) - IN_RANGE_MARGIN for c in zip(*train_q)]
    hi = [max(c) + IN_RANGE_MARGIN for c in zip(*train_q)]
    for label, f in HELD.items():
        src = os.path.join(data, f)
        r = score(src, label.replace(" ", "_").replace(":", ""))
        print(f"{label:34s} {r[2]:5d} {r[0]:9.3f} {r[1]:7.3f}")
        rows = rows_of(src)
        keep = [x for x in rows
                if min(max(abs(p - t) for p, t in zip(q(x), tq)) for tq in train_q) >= REPEAT_TOL
                and all(l <= v <= h for v, l, h in zip(q(x), lo, hi))]
        sub = os.path.join(tmp, f"new-{len(keep)}.csv")
        with open(sub, "w", newline="") as fh:
            w = csv.DictWriter(fh, list(rows[0].keys()))
            w.writeheader()
            w.writerows(keep)
        r = score(sub, "new_" + label.replace(" ", "_").replace(":", ""))
        print(f"{'  new in-range of ' + label:34s} {r[2]:5d} {r[0]:9.3f} {r[1]:7.3f}")


if __name__ == "__main__":
    main()
