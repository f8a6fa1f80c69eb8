"""validate against `handclasp validate`: the same JSON, text and warnings on the same files,
each nuisance mode; sessions as objects or paths; the error mapping."""

import warnings

import pytest

import handclasp as hc


@pytest.fixture(scope="module")
def calibrated(data, cell, cell_path, cli, tmp_path_factory):
    """The cell calibrated by the CLI on mixed.csv and exported (cell.toml's path), and a new
    mixed session of the same cell at other poses (same group names: held.csv)."""
    d = tmp_path_factory.mktemp("validate")
    rc, _, err = cli(
        "calibrate", "--cell", cell_path, "--session", data / "mixed.csv", "--export", d / "cal"
    )
    assert rc == 0, err
    hc.simulate_session(cell, n=36, seed=6, layout="random", kind="mixed").to_csv(d / "held.csv")
    return d / "cal" / "cell.toml", d / "held.csv"


def _warnings_of(stderr):
    return [l[len("warning: "):] for l in stderr.splitlines() if l.startswith("warning: ")]


@pytest.mark.parametrize(
    "nominal, nuisance",
    [(True, "split"), (False, "split"), (True, "fixed")],
)
def test_validate_same_report_as_the_cli(calibrated, cell_path, data, cli, cli_json, nominal, nuisance):
    cal_path, held = calibrated
    flags = ["--cell", cal_path, "--session", held]
    kwargs = {}
    nom = None
    if nominal:
        flags += ["--nominal", cell_path]
        nom = hc.Cell.load(cell_path)
    if nuisance == "fixed":
        flags += ["--nuisance", "fixed", "--calibration-session", data / "mixed.csv"]
        kwargs = {"nuisance": "fixed", "calibration_session": data / "mixed.csv"}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = hc.validate(hc.Cell.load(cal_path), held, nominal=nom, **kwargs)
    expected = cli_json("validate", *flags)
    assert r.to_dict() == expected
    assert r.all == expected["all"]
    assert r.to_dict()["nuisance"] == nuisance
    rc, text, err = cli("validate", *flags)
    assert rc == 0, err
    assert r.text() == text
    assert r.warnings == _warnings_of(err)
    assert [str(w.message) for w in caught if issubclass(w.category, UserWarning)] == r.warnings
    assert (r.to_dict()["all"]["nominal"] is None) == (not nominal)


def test_validate_takes_a_session_object_read_with_either_cell(calibrated, cell, cell_path):
    cal_path, held = calibrated
    cal = hc.Cell.load(cal_path)
    by_path = hc.validate(cal, held, nominal=cell).to_dict()
    # The same rows read with the nominal cell (as the path is), named by their file.
    assert hc.validate(cal, hc.Session.load(held, cell), nominal=cell).to_dict() == by_path
    # Read with the calibrated cell: the same rows (this simulated session's tips are the
    # nominal models'; the calibrated cell reads them as well, or says why not).
    try:
        s = hc.Session.load(held, cal)
    except ValueError as e:
        assert "tip" in str(e)
    else:
        assert hc.validate(cal, s, nominal=cell).to_dict()["all"]["rows"] == by_path["all"]["rows"]


def test_validate_errors(calibrated, cell, cell_path, data, cli):
    cal_path, held = calibrated
    cal = hc.Cell.load(cal_path)
    with pytest.raises(ValueError, match="nuisance"):
        hc.validate(cal, held, nuisance="refit")
    with pytest.raises(ValueError, match="needs calibration_session"):
        hc.validate(cal, held, nuisance="fixed")
    with pytest.raises(ValueError, match="nuisance=\"fixed\" only"):
        hc.validate(cal, held, calibration_session=data / "mixed.csv")
    with pytest.raises(ValueError, match="another Cell"):
        hc.validate(cal, hc.Session.load(held, hc.Cell.load(cell_path)), nominal=cell)
    with pytest.raises(ValueError, match="Session or a session CSV path"):
        hc.validate(cal, 42)
    with pytest.raises(FileNotFoundError, match="missing.csv"):
        hc.validate(cal, data / "missing.csv", nominal=cell)
    # The nuisances carried from a calibration session without the new session's groups: the
    # CLI's message, as a CalibrationError.
    rc, _, err = cli(
        "validate", "--cell", cal_path, "--session", held, "--nuisance", "fixed",
        "--calibration-session", data / "coincident.csv",
    )
    assert rc != 0
    with pytest.raises(hc.CalibrationError) as caught:
        hc.validate(cal, held, nuisance="fixed", calibration_session=data / "coincident.csv")
    assert err.strip() == f"error: {caught.value}"
