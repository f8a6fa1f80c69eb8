"""Issue 21 in the package: a refused result raises `CalibrationError` carrying the CLI's
check values (its `--json` refusal object), `.export(dir)` takes the CLI's export lock and
overwrite rule, and `import_session` runs the input checks every command shares."""

import json
import os

import pytest

import handclasp as hc


def _refusal(cli, *args):
    """The CLI's `--json` refusal object of a refused run (exit non-zero, JSON on stdout)."""
    rc, out, err = cli(*args, "--json")
    assert rc != 0, "the CLI did not refuse"
    refusal = json.loads(out)
    assert refusal["status"] == "refused", out
    assert err.strip().splitlines()[-1] == "error: " + refusal["reason"], err
    return refusal


def test_points_misfit_carries_the_clis_check_values(data, cli, tmp_path):
    """Robot 2's rows shifted by one: the exception carries the CLI's `misfit` values."""
    lines = (data / "coincident.csv").read_text().splitlines()
    header, rows = lines[0], [l.split(",") for l in lines[1:]]
    k = header.split(",").index("r2_x_mm")
    shifted = [r[:k] + rows[(i + 1) % len(rows)][k:] for i, r in enumerate(rows)]
    bad = tmp_path / "shifted.csv"
    bad.write_text("\n".join([header] + [",".join(r) for r in shifted]) + "\n")
    refusal = _refusal(cli, "calibrate", bad)
    with pytest.raises(hc.CalibrationError) as e:
        hc.calibrate_points(bad)
    assert e.value.status == "refused" and e.value.result_check is None
    py, cli_misfit = dict(e.value.misfit), dict(refusal["misfit"])
    # The message names the two ways out as each front end spells them; the values agree.
    for m in (py, cli_misfit):
        m.pop("message")
    assert py == cli_misfit
    assert cli_misfit["median_residual_mm"] > cli_misfit["limit_mm"]


@pytest.fixture
def ceiling_session(tmp_path):
    """A session recorded in the floor–ceiling cell, written as CSV."""
    from conftest import REPO

    ceiling = hc.Cell.load(REPO / "cells" / "floor-ceiling.toml")
    path = tmp_path / "ceiling.csv"
    hc.simulate_session(ceiling, n=20, seed=3, layout="random").to_csv(path)
    return path


def test_refused_cell_fit_carries_the_result_check(cell, cell_path, cli, ceiling_session):
    """A session of another cell: refused by both, with the same check values; force=True keeps
    it, the findings as `UserWarning`s."""
    refusal = _refusal(
        cli, "calibrate", "--cell", cell_path, "--session", ceiling_session, "--model", "placement"
    )
    s = hc.Session.load(ceiling_session, cell)
    with pytest.raises(hc.CalibrationError) as e:
        hc.calibrate_cell(cell, s, model="placement")
    err = e.value
    assert err.status == "refused" and err.misfit is None
    assert "floor-ceiling.toml" in str(err) and "force=True" in str(err)
    assert err.result_check == refusal["result_check"]
    assert err.refusal["result_check"] == refusal["result_check"]
    assert err.refusal["reason"] == str(err)
    with pytest.warns(UserWarning, match="kept by force=True: likely mistake"):
        kept = hc.calibrate_cell(cell, s, model="placement", force=True)
    assert kept.to_dict()["result_check"]["status"] == "refused"


def test_export_takes_the_lock_and_the_overwrite_rule(cell, data, tmp_path):
    r = hc.calibrate_cell(cell, hc.Session.load(data / "coincident.csv", cell))
    out = tmp_path / "out"
    r.export(out)
    with pytest.raises(FileExistsError, match="overwrite=True"):
        r.export(out)
    # force=True keeps the full model (the do-no-harm rule's --force); it does not overwrite.
    with pytest.raises(FileExistsError, match="overwrite=True"):
        r.export(out, force=True)
    assert sorted(os.listdir(out)) == ["cell.toml", "robot1.urdf", "robot2.urdf"]
    r.export(out, overwrite=True)
    # Another export holding the folder's lock: refused, nothing written, the lock left alone.
    locked = tmp_path / "locked"
    locked.mkdir()
    (locked / ".handclasp-export.lock").write_text("")
    with pytest.raises(FileExistsError, match="handclasp-export.lock"):
        r.export(locked, overwrite=True)
    assert os.listdir(locked) == [".handclasp-export.lock"]
    d = hc.diagnose(cell, hc.Session.load(data / "coincident.csv", cell), trials=40)
    d.export(tmp_path / "diag")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        d.export(tmp_path / "diag")
    d.export(tmp_path / "diag", overwrite=True)


def test_import_session_runs_the_shared_input_checks(cell, cell_path, cli, tmp_path):
    """Every row twice: `import` and `import_session` refuse with the same message."""
    from conftest import REPO

    examples = REPO / "docs" / "examples"
    lines = (examples / "controller_log.csv").read_text().splitlines()
    twice = tmp_path / "twice.csv"
    twice.write_text("\n".join([lines[0]] + lines[1:] + lines[1:]) + "\n")
    out = tmp_path / "session.csv"
    rc, _, err = cli(
        "import", "--cell", cell_path, "--map", examples / "controller_map.toml",
        "--input", twice, "--out", out,
    )
    assert rc != 0 and not out.exists()
    with pytest.raises(ValueError) as e:
        hc.import_session(cell, examples / "controller_map.toml", [twice])
    cli_msg = err.strip().splitlines()[-1].removeprefix("error: ")
    assert str(e.value) == cli_msg.replace(str(out), "<session>")
