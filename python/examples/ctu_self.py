"""The CTU dual-arm Motoman cell calibrated from its self-contact files, then scored on laser-tracker
poses it never saw, as the CLI does with `handclasp import --map tools/ctu-motoman/maps/self_contact.toml`,
`handclasp calibrate --cell cells/ctu-motoman.toml --model kinematic --export DIR` and
`handclasp validate --cell DIR/cell.toml --session TRACKER.csv --nominal cells/ctu-motoman.toml`.
Run from anywhere (the cell and the maps are found beside this file):

    python python/examples/ctu_self.py [DATA_DIR]

DATA_DIR defaults to shared/data/ctu-motoman beside the clone (as CI has it), then
/work/shared/data/ctu-motoman; the example exits with a message when the folder is absent. The
data are read in place, never copied.

The held-out poses are the six table and wall tracker files (`leica_*_table*_5x5`, the right arm
carrying the reflector), the files the study (studies/ctu-motoman) uses for no choice and scores its
`self` model on. `validate` fits each file's tracker frame on alternate poses and scores the others,
and back; the study also fits the reflector's position per file, so its figures differ (see
docs/guide/python.md).
"""

import sys
import tempfile
from pathlib import Path

import handclasp as hc

repo = Path(__file__).resolve().parents[2]                                # cells/ and tools/ are the repository's
candidates = [Path(a) for a in sys.argv[1:2]] or [repo.parent / "shared/data/ctu-motoman", Path("/work/shared/data/ctu-motoman")]
data = next((d for d in candidates if (d / "README.md").is_file()), None)
if data is None:
    sys.exit(f"skipped: the CTU data folder is absent (looked in {', '.join(map(str, candidates))})")

cell = hc.Cell.load(repo / "cells/ctu-motoman.toml")
files = sorted(data.glob("no_leica_self_*_4x4_dataset.csv"))           # the four self-contact files
session = hc.import_session(cell, repo / "tools/ctu-motoman/maps/self_contact.toml", files)
result = hc.calibrate_cell(cell, session, model="kinematic")
print(f"{len(session)} self-contact rows from {len(files)} files; {result!r}")
p = result.parameters()                                                   # value ± posterior sigma per parameter
print("\n".join(f"  {n:<32} {v:+.4f} ± {s:.4f} {u}" for n, v, s, u in zip(p["name"], p["value"], p["sigma"], p["unit"])))
trackers = sorted(data.glob("leica_*_table*_5x5_dataset.csv"))            # held out: six tracker files
held_out = hc.import_session(cell, repo / "tools/ctu-motoman/maps/tracker_right.toml", trackers)
with tempfile.TemporaryDirectory() as out:
    result.export(out)                                                    # cell.toml + the two URDFs
    score = hc.validate(hc.Cell.load(Path(out) / "cell.toml"), held_out, nominal=cell)
print(score.text(), end="")
a = score.all
print(f"held-out tracker rms: calibrated {a['calibrated']['rms_mm']:.3f} mm, nominal {a['nominal']['rms_mm']:.3f} mm "
      f"(ratio {a['rms_ratio']:.3f}) over {a['rows']} poses of {len(trackers)} files")
