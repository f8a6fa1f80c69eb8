"""simulate_session, plan and sweep against the CLIs; the GIL released during long calls."""

import json
import threading
import time

import numpy as np
import pytest

import handclasp as hc
from conftest import _binary


def test_simulate_session_matches_sim_cell(cell, cell_path, tmp_path):
    exe = _binary("sim-cell")
    if exe is None:
        pytest.skip("the sim-cell binary is not built")
    import subprocess

    out = subprocess.run(
        [str(exe), "session", "--cell", str(cell_path), "--n", "8", "--seed", "4", "--layout", "random"],
        capture_output=True, text=True, check=True,
    ).stdout
    s = hc.simulate_session(cell, n=8, seed=4, layout="random")
    assert s.to_csv_string() == out


def test_plan_matches_the_cli(cell, cell_path, cli, tmp_path):
    args = ["plan", "--cell", cell_path, "--n", "6", "--candidates", "30", "--out", tmp_path / "plan.csv"]
    rc, text, err = cli(*args)
    assert rc == 0, err
    rc, out, err = cli(*args, "--json")
    assert rc == 0, err
    p = hc.plan(cell, n=6, candidates=30, out=tmp_path / "plan.csv")
    # The report `plan --json` prints, and its text.
    assert p.to_dict() == json.loads(out)
    assert p.text() == text
    assert p.to_csv_string() == (tmp_path / "plan.csv").read_text()
    assert isinstance(p.session, hc.Session) and len(p) == len(p.session) == 6
    cols = p.columns()
    assert cols["point"].tolist() == [1, 2, 3, 4, 5, 6]
    # Without out: the same prediction, nothing written.
    q = hc.plan(cell, n=6, candidates=30)
    assert q.to_dict()["out"] == "(not written)"
    assert q.to_dict()["predicted"] == p.to_dict()["predicted"]


def test_sweep_columns(tmp_path):
    exe = _binary("sim-cell")
    kw = dict(mounts=["floor-wall"], noise_mm=[1.0], spread_mm=[1000.0], n_points=[6], methods=["lsq", "generic"], trials=20, seed=2)
    cols = hc._handclasp.sweep(**kw)
    assert cols["method"] == ["generic", "lsq"] or sorted(cols["method"]) == ["generic", "lsq"]
    assert cols["e_tran_mm_median"].dtype == np.float64 and cols["e_tran_mm_median"].shape == (2,)
    again = hc._handclasp.sweep(**kw)
    assert all(np.array_equal(cols[k], again[k]) if isinstance(cols[k], np.ndarray) else cols[k] == again[k] for k in cols)
    if exe is not None:
        import csv
        import subprocess

        subprocess.run(
            [str(exe), "sweep", "--mounts", "floor-wall", "--noise-mm", "1", "--spread-mm", "1000", "--points", "6",
             "--methods", "lsq,generic", "--trials", "20", "--seed", "2", "--out", str(tmp_path / "sw")],
            capture_output=True, text=True, check=True,
        )
        with open(tmp_path / "sw" / "summary.csv") as f:
            rows = list(csv.DictReader(f))
        for i, row in enumerate(rows):
            for k, v in row.items():
                got = cols[k][i]
                assert (str(got) == v) if isinstance(got, str) else (float(v) == got or (np.isnan(got) and v == "")), k



def _summary_equals_sim_cell(cols, args, out):
    """The summary columns equal `sim-cell sweep ARGS --out OUT`'s summary.csv, cell for cell."""
    import csv
    import subprocess

    exe = _binary("sim-cell")
    if exe is None:
        pytest.skip("the sim-cell binary is not built")
    subprocess.run([str(exe), "sweep", *args, "--out", str(out)], capture_output=True, text=True, check=True)
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert rows and len(rows) == len(cols["method"])
    for i, row in enumerate(rows):
        for k, v in row.items():
            got = cols[k][i]
            assert (str(got) == v) if isinstance(got, str) else (float(v or "nan") == got or (np.isnan(got) and v in ("", "NaN"))), k


def test_sweep_robot_mode_matches_sim_cell(cell_path, tmp_path):
    """mode="robot" (full simulated sessions on the robots) with a cell, a planned layout and drawn
    kinematic errors: sim-cell sweep --mode robot's summary, value for value."""
    kw = dict(noise_mm=[0.5], spread_mm=[800.0], n_points=[6], methods=["lsq", "placement"], trials=2,
              seed=3, mode="robot", layout="random", kinematic_errors="tolerance", cells=[hc.Cell.load(cell_path)])
    cols = hc._handclasp.sweep(**kw)
    assert sorted(set(cols["method"])) == ["lsq", "placement"]
    _summary_equals_sim_cell(
        cols,
        ["--mode", "robot", "--cell", str(cell_path), "--noise-mm", "0.5", "--spread-mm", "800", "--points", "6",
         "--methods", "lsq,placement", "--trials", "2", "--seed", "3", "--layout", "random",
         "--kinematic-errors", "tolerance"],
        tmp_path / "sw",
    )


def test_sweep_mode_arguments_are_checked(cell):
    with pytest.raises(ValueError, match="mode="):
        hc.sweep(mode="fast")
    with pytest.raises(ValueError, match="for mode=\"robot\""):
        hc.sweep(cells=[cell], trials=1)
    with pytest.raises(ValueError, match="for mode=\"robot\""):
        hc.sweep(kinematic_errors="tolerance", trials=1)
    with pytest.raises(ValueError, match="layout="):
        hc.sweep(mode="robot", layout="spiral", trials=1)

def test_the_gil_is_released(cell):
    """A second Python thread keeps running while plan works in Rust (about a second of CPU)."""
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    time.sleep(0.01)
    start = time.perf_counter()
    hc.plan(cell, n=20, candidates=200)
    end = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    # With the GIL held the counter could not tick at all during the call (0 or 1 at its edge);
    # released, it ticks about every millisecond (at least 10 on a loaded machine).
    assert len(during) >= 10, (end - start, len(during))
