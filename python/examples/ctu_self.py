"""The CTU dual-arm Motoman cell calibrated from its self-contact files, as the CLI does with
`handclasp import --map tools/ctu-motoman/maps/self_contact.toml` then `handclasp calibrate
--cell cells/ctu-motoman.toml --model kinematic`. Run from the repository root:

    python python/examples/ctu_self.py [DATA_DIR]

DATA_DIR defaults to ../shared/data/ctu-motoman (beside the clone, as CI has it), then
/work/shared/data/ctu-motoman. The data are read in place, never copied.
"""

import sys
from pathlib import Path

import handclasp as hc

candidates = [Path(a) for a in sys.argv[1:]] + [Path("../shared/data/ctu-motoman"), Path("/work/shared/data/ctu-motoman")]
data = next((d for d in candidates if d.is_dir()), None)
if data is None:
    sys.exit(f"skipped: the CTU data folder is absent (looked in {', '.join(map(str, candidates))})")

cell = hc.Cell.load("cells/ctu-motoman.toml")
files = sorted(data.glob("no_leica_self_*_4x4_dataset.csv"))           # the four self-contact files
session = hc.import_session(cell, "tools/ctu-motoman/maps/self_contact.toml", files)
result = hc.calibrate_cell(cell, session, model="kinematic")
print(f"{len(session)} self-contact rows from {len(files)} files; {result!r}")
print("b1_from_b2 (mm):\n", result.b1_from_b2.round(3))
print(hc.frame(result.parameters()))                                      # value ± sigma per parameter
report = result.to_dict()
print("rows used:", report["rows_used"], "of", report["rows"], "| rejected:", len(report["rejected_points"]),
      "| fitted contact distances (mm):", [round(g["distance_mm"], 3) for g in report["groups"]["contact"]])
