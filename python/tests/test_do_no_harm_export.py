"""CellResult.export runs the do-no-harm check of `calibrate --cell --export` (the same library
function): it withholds the families that harm a held-out region and warns, force=True keeps the
full model, and do_no_harm() is the CLI's JSON `do_no_harm` object."""

import warnings

import pytest

import handclasp as hc

from conftest import REPO

# The truth's gravity compliance at the shoulder and elbow of both robots, deg/(kN·m): far beyond
# what the kinematic model represents (as tests/e2e/do_no_harm.rs builds it).
SAG_DEG_PER_KNM = 1.0


def _sag_cell(tmp_path):
    """The shipped floor-wall cell with the sag as its hidden truth (URDF paths absolute)."""
    c = SAG_DEG_PER_KNM
    text = (REPO / "cells" / "floor-wall.toml").read_text().replace("../robots/", f"{REPO / 'robots'}/")
    text += (
        f"\n[robot1.errors]\ncompliance_deg_per_knm = [0.0, {c}, {c}, 0.0, 0.0, 0.0, 0.0]\n"
        f"\n[robot2.errors]\ncompliance_deg_per_knm = [0.0, {c}, {c}, 0.0, 0.0, 0.0]\n"
    )
    path = tmp_path / "sag.toml"
    path.write_text(text)
    return path


def test_export_withholds_what_harms_and_warns_and_force_keeps_the_full_model(tmp_path, cli_json):
    path = _sag_cell(tmp_path)
    cell = hc.Cell.load(path)
    # 40 handclasps in two small clusters of the workspace: the corrections that absorb the sag
    # there extrapolate worse than nominal to the region held out.
    hc.simulate_session(cell, n=40, seed=1, layout="clustered", spread_mm=600.0).to_csv(tmp_path / "s.csv")
    r = hc.calibrate_cell(cell, hc.Session.load(tmp_path / "s.csv", cell))
    with pytest.warns(UserWarning, match="do no harm: the kinematic model is worse") as caught:
        r.export(tmp_path / "py")
    v = r.do_no_harm()
    assert v["withheld"], v
    assert v["exported"] in ("partial", "placement"), v
    assert v["forced"] is False
    warned = [str(w.message) for w in caught if "WITHHELD" in str(w.message)]
    assert len(warned) == 1, [str(w.message) for w in caught]
    assert "force=True exports the full model" in warned[0]
    assert all(w["family"] in warned[0] for w in v["withheld"]), (warned, v["withheld"])
    # The CLI's verdict and export on the same session, file for file.
    cli = cli_json("calibrate", "--cell", path, "--session", tmp_path / "s.csv", "--export", tmp_path / "cli")
    assert cli["do_no_harm"] == v
    for n in ["robot1.urdf", "robot2.urdf"]:
        assert (tmp_path / "py" / n).read_text() == (tmp_path / "cli" / n).read_text(), n
    # force=True writes the full model, and says that it harms.
    with pytest.warns(UserWarning, match="kept by force=True: do no harm"):
        r.export(tmp_path / "full", force=True)
    full = cli_json("calibrate", "--cell", path, "--session", tmp_path / "s.csv", "--export", tmp_path / "cli-full", "--force")
    assert full["do_no_harm"]["forced"] is True
    for n in ["robot1.urdf", "robot2.urdf"]:
        assert (tmp_path / "full" / n).read_text() == (tmp_path / "cli-full" / n).read_text(), n
    assert (tmp_path / "full" / "robot2.urdf").read_text() != (tmp_path / "py" / "robot2.urdf").read_text()


def test_a_healthy_export_keeps_the_full_model(cell, data, tmp_path):
    r = hc.calibrate_cell(cell, hc.Session.load(data / "mixed.csv", cell))
    # Nothing withheld and the check ran: no do-no-harm warning (its notes, e.g. folds in row
    # order, are in do_no_harm() only; stop 36 warned them on every export).
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r.export(tmp_path / "out")
    v = r.do_no_harm()
    if v["design"] != "not_checked":
        assert not [str(w.message) for w in caught if "do no harm" in str(w.message)], v
    assert v["exported"] == "kinematic" and v["withheld"] == [], v
    assert all(f["kept"] for f in v["families"]), v
    assert hc.calibrate_cell(cell, hc.Session.load(data / "mixed.csv", cell), model="placement").do_no_harm() is None
