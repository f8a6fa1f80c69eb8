"""A one-robot cell (cells/rail-tracker.toml: an arm on a linear track, measured by a laser
tracker; no [robot2]) from Python, against the CLI on the same files."""

import pytest

import handclasp as hc

from conftest import REPO


@pytest.fixture(scope="module")
def rail():
    path = REPO / "cells" / "rail-tracker.toml"
    return path, hc.Cell.load(path)


@pytest.fixture(scope="module")
def tracker_csv(rail, tmp_path_factory):
    _, cell = rail
    path = tmp_path_factory.mktemp("rail") / "tracker.csv"
    hc.simulate_session(cell, n=20, seed=2, layout="random", kind="tracker").to_csv(path)
    return path


def test_one_robot_cell_loads(rail):
    _, cell = rail
    assert not cell.has_robot2
    # The track's prismatic joint and the arm's six; no robot 2 (not its stand-in's count).
    assert cell.dof == (7, None)
    assert "robot2=None" in repr(cell)
    two = hc.Cell.load(REPO / "cells" / "floor-wall.toml")
    assert two.has_robot2
    assert all(isinstance(d, int) and d > 0 for d in two.dof)
    # The kinds that need two robots are refused, naming the ones that do not.
    with pytest.raises(ValueError, match="only \\[robot1\\].*tracker"):
        hc.simulate_session(cell, n=6, kind="coincident")
    with pytest.raises(ValueError, match="only \\[robot1\\]"):
        hc.plan(cell, n=10, candidates=50)


def test_one_robot_calibration_and_diagnosis_equal_the_cli(rail, tracker_csv, cli_json, cli):
    cell_path, cell = rail
    session = hc.Session.load(tracker_csv, cell)
    args = ["--cell", cell_path, "--session", tracker_csv]
    r = hc.calibrate_cell(cell, session, accept_mm=1.0)
    assert r.to_dict() == cli_json("calibrate", *args, "--accept-mm", 1.0)
    rc, text, err = cli("calibrate", *args, "--accept-mm", 1.0)
    assert rc == 0, err
    assert r.text() == text
    d = hc.diagnose(cell, session)
    assert d.mode == "whole_cell"
    assert d.to_dict() == cli_json("diagnose", *args)
