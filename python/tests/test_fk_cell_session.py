"""fk, Cell, Session against the CLI and the session files."""

import json

import numpy as np
import pytest

import handclasp as hc
from conftest import REPO


def test_fk_matches_the_cli(cell, cell_path, data, cli_json):
    s = hc.Session.load(data / "coincident.csv", cell)
    q = s.q1_deg[:3]
    poses = hc.fk((cell, 1), q)
    assert poses.shape == (3, 4, 4) and poses.dtype == np.float64
    for i in range(3):
        j = cli_json("fk", "--cell", cell_path, "--robot", "1", "--q-deg", ",".join(repr(float(v)) for v in q[i]))
        assert np.array_equal(poses[i, :3, 3], np.array(j["xyz_mm"]))
        assert np.allclose(poses[i, :3, :3], np.array(j["rotation"]), atol=1e-15)


def test_fk_urdf_robot_and_tip(cell, data, cli_json):
    urdf = REPO / "robots" / "hp20.urdf"
    robot = hc.Robot.load(urdf)
    assert robot.dof == 6 and len(robot.joint_names) == 6
    q = np.array([[0, 10, -20, 0, 30, 0], [5, 0, 0, 0, -30, 90]], dtype=float)
    a = hc.fk(robot, q, tip=[0, 0, 150])
    b = hc.fk(str(urdf), q, tip=np.array([0, 0, 150]))
    assert np.array_equal(a, b)
    j = cli_json("fk", "--robot", urdf, "--q-deg", "0,10,-20,0,30,0", "--tip-mm", "0,0,150")
    assert np.array_equal(a[0, :3, 3], np.array(j["xyz_mm"]))
    one = hc.fk(robot, q[1])
    assert one.shape == (4, 4)
    # The session's tips are the nominal FK with the cell's tip.
    s = hc.Session.load(data / "coincident.csv", cell)
    assert np.allclose(hc.fk((cell, 2), s.q2_deg, tip="cell")[:, :3, 3], s.p2_mm, atol=1e-5)


def test_fk_errors(cell):
    with pytest.raises(ValueError, match=r"shape \[2, 5\], expected \(n, 7\)"):
        hc.fk((cell, 1), np.zeros((2, 5)))
    with pytest.raises(ValueError, match="not finite"):
        hc.fk((cell, 1), np.full(7, np.nan))
    with pytest.raises(ValueError, match="1 or 2"):
        hc.fk((cell, 3), np.zeros(7))
    with pytest.raises(FileNotFoundError):
        hc.fk("no/such.urdf", np.zeros(6))
    with pytest.raises(ValueError, match="limit"):
        hc.fk((cell, 1), np.full(7, 400.0))


def test_session_round_trip_and_arrays(cell, data, tmp_path):
    s = hc.Session.load(data / "coincident.csv", cell)
    assert len(s) == 12 and s.q1_deg.shape == (12, 7) and s.q2_deg.shape == (12, 6)
    s.to_csv(tmp_path / "again.csv")
    assert (tmp_path / "again.csv").read_text() == (data / "coincident.csv").read_text()
    t = hc.Session.from_arrays(cell, s.q1_deg, s.q2_deg, s.p1_mm, s.p2_mm)
    assert t.to_csv_string() == s.to_csv_string()
    # Tips from the nominal FK when not given.
    u = hc.Session.from_arrays(cell, s.q1_deg, s.q2_deg)
    assert np.allclose(u.p1_mm, s.p1_mm, atol=1e-5)
    cols = s.columns()
    assert list(cols)[:2] == ["point", "r1_q1_deg"] and cols["r1_x_mm"].dtype == np.float64
    # A mixed session through its columns reads back the same.
    m = hc.Session.load(data / "mixed.csv", cell)
    again = hc.Session.from_arrays(cell, columns=m.columns())
    assert again.to_csv_string() == m.to_csv_string()
    assert m.rows_by_kind["tracker"] > 0


def test_session_errors(cell, data, tmp_path):
    s = hc.Session.load(data / "coincident.csv", cell)
    with pytest.raises(ValueError, match="q1_deg: shape"):
        hc.Session.from_arrays(cell, s.q1_deg[:, :6], s.q2_deg)
    p1 = s.p1_mm.copy()
    p1[0, 0] += 50.0
    with pytest.raises(ValueError, match="session <arrays>"):
        hc.Session.from_arrays(cell, s.q1_deg, s.q2_deg, p1, s.p2_mm)
    with pytest.raises(FileNotFoundError):
        hc.Session.load(tmp_path / "none.csv", cell)
    with pytest.raises(FileNotFoundError):
        hc.Cell.load(tmp_path / "none.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[robot1]\nurdf = 3\n")
    with pytest.raises(ValueError, match="cell"):
        hc.Cell.load(bad)
