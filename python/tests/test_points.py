"""calibrate_points against `handclasp calibrate POINTS.csv --json`."""

import numpy as np
import pytest

import handclasp as hc


@pytest.mark.parametrize(
    "options, flags",
    [
        ({}, []),
        ({"method": "generic"}, ["--method", "generic"]),
        ({"mounts": "floor-wall"}, ["--mounts", "floor-wall"]),
        ({"mounts": "floor-wall", "tilt_sigma_deg": 0.5}, ["--mounts", "floor-wall", "--tilt-sigma-deg", "0.5"]),
    ],
)
def test_same_report_as_the_cli(data, cli_json, options, flags):
    path = data / "coincident.csv"
    r = hc.calibrate_points(path, **options)
    assert r.to_dict() == cli_json("calibrate", path, *flags)


def test_arrays_give_the_files_fit(data, cli_json):
    """The CSV's numbers as arrays: the same fit; rows are then 1..n instead of line numbers."""
    path = data / "coincident.csv"
    table = np.genfromtxt(path, delimiter=",", names=True)
    p1 = np.column_stack([table[f"r1_{a}_mm"] for a in "xyz"])
    p2 = np.column_stack([table[f"r2_{a}_mm"] for a in "xyz"])
    r = hc.calibrate_points(p1, p2)
    expected = cli_json("calibrate", path)
    got = r.to_dict()
    assert got["rows"] == list(range(1, len(p1) + 1))
    for key in ["b1_from_b2", "residuals_mm", "residual_rms_mm", "uncertainty", "condition"]:
        assert got[key] == expected[key], key
    assert np.allclose(r.b1_from_b2[:3, 3], expected["b1_from_b2"]["xyz_mm"], atol=1e-6)
    assert np.allclose(r.b1_from_b2[:3, :3], expected["b1_from_b2"]["rotation"], atol=1e-12)


def test_shapes_and_dtypes(data):
    r = hc.calibrate_points(data / "coincident.csv")
    assert r.b1_from_b2.shape == (4, 4) and r.b1_from_b2.dtype == np.float64
    assert r.residuals_mm.shape == (12, 3) and r.residuals_mm.dtype == np.float64
    assert r.residual_norms_mm.shape == (12,)
    assert r.covariance.shape == (6, 6)
    assert set(r.uncertainty) >= {"e_tran_1sigma_mm", "e_rot_1sigma_deg", "sigma_point_mm"}
    assert np.allclose(r.b1_from_b2[3], [0, 0, 0, 1])


def test_errors(data, cli):
    p = np.random.default_rng(1).normal(size=(6, 3)) * 500
    with pytest.raises(ValueError, match="shape"):
        hc.calibrate_points(p[:, :2], p)
    q = p.copy()
    q[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"p2_mm\[2, 1\].*not finite"):
        hc.calibrate_points(p, q)
    with pytest.raises(ValueError, match="unknown method"):
        hc.calibrate_points(p, p, method="nope")
    with pytest.raises(FileNotFoundError):
        hc.calibrate_points(data / "missing.csv")
    # Too few points: the fit fails, with the CLI's message.
    with pytest.raises(hc.CalibrationError) as e:
        hc.calibrate_points(p[:2], p[:2] + 1.0)
    assert "method lsq" in str(e.value)


def test_misfit_is_a_calibration_error_with_the_clis_message(data, cli, tmp_path):
    """Robot 2's rows shifted by one: the CLI and the package both refuse, naming the cause."""
    lines = (data / "coincident.csv").read_text().splitlines()
    header, rows = lines[0], [l.split(",") for l in lines[1:]]
    cols = header.split(",")
    k = cols.index("r2_x_mm")
    shifted = [r[:k] + rows[(i + 1) % len(rows)][k:] for i, r in enumerate(rows)]
    bad = tmp_path / "shifted.csv"
    bad.write_text("\n".join([header] + [",".join(r) for r in shifted]) + "\n")
    rc, _, err = cli("calibrate", bad)
    assert rc != 0
    with pytest.raises(hc.CalibrationError) as e:
        hc.calibrate_points(bad)
    cli_msg = err.strip().removeprefix("error: ")
    py_msg = str(e.value)
    # Same message but for the names of the two ways out.
    assert py_msg == cli_msg.replace("--expected-noise-mm", "expected_noise_mm=").replace("--force", "force=True")
    with pytest.warns(UserWarning, match="kept by force=True"):
        hc.calibrate_points(bad, force=True)


@pytest.mark.parametrize("options, flags", [({}, []), ({"mounts": "floor-wall"}, ["--mounts", "floor-wall"])])
def test_all_methods_same_report_as_the_cli(data, cli_json, options, flags, tmp_path):
    """method="all" is `--method all`: every method's report by name, a method that does not
    apply (3 points: generic-affine needs 4) as its error."""
    path = data / "coincident.csv"
    r = hc.calibrate_points(path, method="all", **options)
    expected = cli_json("calibrate", path, "--method", "all", *flags)
    assert r.to_dict() == expected
    names = ["constrained", "generic", "generic-affine", "lsq", "paper"] if options else ["generic", "generic-affine", "lsq"]
    assert sorted(r.results) == names and r.errors == {}
    assert r.results["lsq"].to_dict() == expected["methods"]["lsq"]
    assert r["lsq"].b1_from_b2.shape == (4, 4)
    with pytest.raises(KeyError):
        r["nope"]
    lines = path.read_text().splitlines()
    three = tmp_path / "three.csv"
    three.write_text("\n".join(lines[:4]) + "\n")
    r3 = hc.calibrate_points(three, method="all", **options)
    expected3 = cli_json("calibrate", three, "--method", "all", *flags)
    assert r3.to_dict() == expected3
    assert "generic-affine" in r3.errors and r3["generic-affine"] is None
    assert r3.errors["generic-affine"] == expected3["methods"]["generic-affine"]["error"]
