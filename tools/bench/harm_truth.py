#!/usr/bin/env python3
"""The do-no-harm judge against the workspace truth (issue 20): for simulated sessions of a known
truth, does `calibrate --cell --export` withhold the model exactly when the model is worse than
the placement-only calibration over the whole workspace?

Per session (seed): the session is simulated (`sim-cell session`), the judge runs
(`calibrate --cell --model kinematic --export`: withheld when `do_no_harm.exported` is
`placement`), then the full kinematic model (`--force`) and the placement-only model are both
exported and scored by `handclasp validate` on 100 fresh coincident handclasps of the same truth
over the workspace (random layout, 800 mm cube, seed 90000 + seed). The model is *truly harmful*
when its validate rms is above the placement's. Prints one line per session and, per case, how
many sessions were truly harmful, withheld among them, and withheld among the harmless ones.
"Withheld" is the whole model (`exported` is `placement`), as stop 35's table counted it; the
summary adds `any`: some family withheld (`exported` is `partial` or `placement`), and the
export actually written (`--export` without `--force`) scored the same way: `export harmful`
counts sessions whose export is worse than the placement over the workspace (the harm that
reaches the user).

Cases (the benchmark's kinds, tests/e2e/do_no_harm.rs): `sag-coincident` and `sag-tracker` (the
floor-wall cell with 1 deg/kN.m compliance at joints 2 and 3 of both robots, clustered, 40 rows,
600 mm apart), `healthy-plane` and `healthy-tracker` (docs/examples/truth.toml reported as the
floor-wall cell, random, 40 rows, 800 mm). Seeds default to 600..629, disjoint from the e2e
benchmark's (100..119 healthy, 1..10 sag): do not score a rule on the seeds that judge it.

Usage (from the workspace root, after `cargo build -p handclasp -p sim-cell`):
    python3 tools/bench/harm_truth.py [--seeds 600:630] [--case sag-tracker ...] [--bin target/debug]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

SAG = """
[robot1.errors]
compliance_deg_per_knm = [0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0]

[robot2.errors]
compliance_deg_per_knm = [0.0, 1.0, 1.0, 0.0, 0.0, 0.0]
"""

# case: (truth is sag?, kind, layout, rows, spread mm)
CASES = {
    "sag-coincident": (True, "coincident", "clustered", 40, 600),
    "sag-tracker": (True, "tracker", "clustered", 40, 600),
    "healthy-plane": (False, "plane", "random", 40, 800),
    "healthy-tracker": (False, "tracker", "random", 40, 800),
}


def run(args):
    return subprocess.run(args, capture_output=True, text=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="600:630")
    ap.add_argument("--case", action="append", choices=sorted(CASES))
    ap.add_argument("--bin", default="target/debug")
    a = ap.parse_args()
    lo, hi = (int(v) for v in a.seeds.split(":"))
    root = os.getcwd()
    hc, sim = os.path.join(a.bin, "handclasp"), os.path.join(a.bin, "sim-cell")
    tmp = tempfile.mkdtemp(prefix="harm_truth-")
    floor_wall = open(os.path.join(root, "cells/floor-wall.toml")).read()
    floor_wall = floor_wall.replace('"../robots/', f'"{root}/robots/')
    nominal = os.path.join(tmp, "nominal.toml")
    open(nominal, "w").write(floor_wall)
    sag = os.path.join(tmp, "sag.toml")
    open(sag, "w").write(floor_wall + SAG)
    example = os.path.join(root, "docs/examples/truth.toml")
    for case in a.case or list(CASES):
        is_sag, kind, layout, n, spread = CASES[case]
        truth = sag if is_sag else example
        counts = {"harmful": 0, "harmless": 0, "withheld_harmful": 0, "withheld_harmless": 0}
        for seed in range(lo, hi):
            d = os.path.join(tmp, f"{case}-{seed}")
            os.makedirs(d)
            train, held = os.path.join(d, "train.csv"), os.path.join(d, "held.csv")
            r = run([sim, "session", "--cell", truth, "--kind", kind, "--layout", layout,
                     "--n", str(n), "--spread-mm", str(spread), "--seed", str(seed), "--out", train])
            r2 = run([sim, "session", "--cell", truth, "--layout", "random", "--n", "100",
                      "--spread-mm", "800", "--seed", str(90000 + seed), "--out", held])
            if r.returncode or r2.returncode:
                print(f"{case} {seed}: simulation failed: {r.stderr.strip()} {r2.stderr.strip()}")
                continue
            base = [hc, "calibrate", "--cell", nominal, "--session", train, "--json"]
            judged = run(base + ["--model", "kinematic", "--export", os.path.join(d, "j")])
            if judged.returncode:
                print(f"{case} {seed}: refused, not judged")
                continue
            exported = json.loads(judged.stdout)["do_no_harm"]["exported"]
            withheld = exported == "placement"
            some = exported != "kinematic"

            def score(out):
                v = run([hc, "validate", "--cell", os.path.join(out, "cell.toml"), "--session",
                         held, "--nominal", nominal, "--json"])
                return (json.loads(v.stdout)["all"]["calibrated"]["rms_mm"] if not v.returncode
                        else float("nan"))

            rms = []
            for model in ["kinematic", "placement"]:
                out = os.path.join(d, model)
                run(base + ["--model", model, "--force", "--export", out])
                rms.append(score(out))
            ratio = rms[0] / rms[1]
            export_ratio = score(os.path.join(d, "j")) / rms[1]
            harmful = ratio > 1.0
            key = "harmful" if harmful else "harmless"
            counts[key] += 1
            counts["withheld_" + key] += withheld
            counts["any_" + key] = counts.get("any_" + key, 0) + some
            counts["export_harmful"] = counts.get("export_harmful", 0) + (export_ratio > 1.0)
            print(f"{case} {seed}: workspace rms kinematic {rms[0]:.3f} mm, placement "
                  f"{rms[1]:.3f} mm (x{ratio:.2f}, {key}); judge: {exported} "
                  f"(export x{export_ratio:.2f})")
        print(f"== {case}: truly harmful {counts['harmful']}, withheld {counts['withheld_harmful']}"
              f" (any {counts.get('any_harmful', 0)}); harmless {counts['harmless']}, withheld "
              f"{counts['withheld_harmless']} (any {counts.get('any_harmless', 0)}); export "
              f"harmful {counts.get('export_harmful', 0)}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
