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


def test_from_arrays_names_a_prismatic_joint_in_mm(tmp_path):
    """Session.from_arrays writes a prismatic joint's column as rN_qK_mm (its values are mm, as
    the CSV's header says); it wrote rN_qK_deg and the reader refused the arrays (found at stop 34)."""
    rail_urdf = REPO / "crates" / "kinematics" / "tests" / "fixtures" / "rail_6r.urdf"
    hp20 = REPO / "robots" / "hp20.urdf"
    path = tmp_path / "rail-pair.toml"
    path.write_text(
        f'[robot1]\nurdf = "{rail_urdf}"\nmount = "floor"\ntip_mm = [0.0, 0.0, 120.0]\n\n'
        f'[robot2]\nurdf = "{hp20}"\nmount = "floor"\ntip_mm = [0.0, 0.0, 150.0]\n\n'
        "[b1_from_b2]\nxyz_mm = [1500.0, 1200.0, 0.0]\nzyz_deg = [180.0, 0.0, 0.0]\n"
    )
    cell = hc.Cell.load(path)
    q1 = [[1500.0, 0.0, 10.0, -20.0, 0.0, 30.0, 0.0], [900.0, 5.0, 0.0, 10.0, 0.0, 20.0, 0.0]]
    q2 = [[0.0, 10.0, -10.0, 0.0, 20.0, 0.0], [5.0, 0.0, 10.0, 0.0, -20.0, 0.0]]
    s = hc.Session.from_arrays(cell, q1, q2)
    cols = s.columns()
    assert "r1_q1_mm" in cols and "r1_q1_deg" not in cols and "r1_q2_deg" in cols
    assert list(cols["r1_q1_mm"]) == [1500.0, 900.0]
