#!/usr/bin/env bash
# Builds the whole-CTU diagnose benchmark session and times `handclasp diagnose` on it
# (BENCHMARKS.md, `handclasp diagnose` table): four imports of the CTU dual-arm Motoman data
# (read in place) into one session, points renumbered 1..N in import order:
#   - both laser trackers: tracker_right.toml on leica_right_hand_6x6x6 (212 rows),
#     tracker_left.toml on leica_left_hand_6x6x6 (208 rows);
#   - the planes: plane_right.toml on the six no_leica_*_table* files (552 rows);
#   - self-contact: self_contact.toml on the four no_leica_self_* files (502 rows);
# 1,474 rows in all. Then `/usr/bin/time` of `diagnose --json` on it (load printed beside it).
#
# Usage (from the repository root, after `cargo build --release -p handclasp`):
#   tools/bench/ctu_diagnose.sh [OUT_DIR] [-- extra diagnose flags]
# Environment: HANDCLASP (default target/release/handclasp), CTU_DATA (default
# ../shared/data/ctu-motoman). OUT_DIR (default /tmp/ctu-diagnose) receives ctu-all.csv and
# diagnose.json.
set -euo pipefail
BIN=${HANDCLASP:-target/release/handclasp}
D=${CTU_DATA:-../shared/data/ctu-motoman}
OUT=${1:-/tmp/ctu-diagnose}
shift || true
[ "${1:-}" = "--" ] && shift
CELL=cells/ctu-motoman.toml
M=tools/ctu-motoman/maps
if [ ! -d "$D" ]; then
  echo "skipped: no CTU data at $D (set CTU_DATA)" >&2
  exit 0
fi
mkdir -p "$OUT"
imp() { "$BIN" import --cell "$CELL" --map "$M/$1" --out "$OUT/$2" "${@:3}" > /dev/null; }
imp tracker_right.toml part1.csv --input "$D/leica_right_hand_6x6x6_dataset.csv"
imp tracker_left.toml part2.csv --input "$D/leica_left_hand_6x6x6_dataset.csv"
planes=()
for f in "$D"/no_leica_*_table*_dataset.csv; do planes+=(--input "$f"); done
imp plane_right.toml part3.csv "${planes[@]}"
selfs=()
for f in "$D"/no_leica_self_*_dataset.csv; do selfs+=(--input "$f"); done
imp self_contact.toml part4.csv "${selfs[@]}"
python3 - "$OUT" <<'PY'
import csv, sys
out = sys.argv[1]
rows, header = [], []
for k in range(1, 5):
    with open(f"{out}/part{k}.csv", newline="") as f:
        lines = [l for l in f if not l.startswith("#")]
    r = list(csv.DictReader(lines))
    for h in (r[0].keys() if r else []):
        if h not in header:
            header.append(h)
    rows += r
for i, r in enumerate(rows, 1):
    r["point"] = str(i)
with open(f"{out}/ctu-all.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=header, restval="")
    w.writeheader()
    w.writerows(rows)
print(f"{len(rows)} rows -> {out}/ctu-all.csv", file=sys.stderr)
PY
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
/usr/bin/time -f "%e s wall %U s user %M KB" "$BIN" diagnose --cell "$CELL" \
  --session "$OUT/ctu-all.csv" --json "$@" > "$OUT/diagnose.json"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
