"""calibrate_cell and diagnose against `handclasp calibrate --cell` and `handclasp diagnose`."""

import os

import numpy as np
import pytest

import handclasp as hc


@pytest.mark.parametrize("name", ["coincident", "mixed"])
@pytest.mark.parametrize("model", ["kinematic", "placement"])
def test_calibrate_cell_same_report_as_the_cli(cell, cell_path, data, cli_json, name, model):
    path = data / f"{name}.csv"
    r = hc.calibrate_cell(cell, hc.Session.load(path, cell), model=model)
    assert r.to_dict() == cli_json("calibrate", "--cell", cell_path, "--session", path, "--model", model)


def test_calibrate_cell_result(cell, cell_path, data, cli, tmp_path):
    path = data / "coincident.csv"
    r = hc.calibrate_cell(cell, hc.Session.load(path, cell))
    d = r.to_dict()
    assert r.b1_from_b2.shape == (4, 4)
    assert np.allclose(r.b1_from_b2[:3, 3], d["b1_from_b2"]["xyz_mm"], atol=1e-3)
    assert r.b1_from_b2_sigma.shape == (6,)
    p = r.parameters()
    assert set(p) == {"name", "value", "sigma", "prior_sigma", "unit"}
    assert len(p["name"]) == len(d["parameters"]) and p["sigma"].dtype == np.float64
    assert r.cooperative_accuracy_mm["pairs"] == 12
    rc, text, err = cli("calibrate", "--cell", cell_path, "--session", path)
    assert rc == 0, err
    assert r.text() == text
    # The export writes the CLI's files, byte for byte.
    written = r.export(tmp_path / "py")
    rc, _, err = cli("calibrate", "--cell", cell_path, "--session", path, "--export", tmp_path / "cli")
    assert rc == 0, err
    names = sorted(os.path.basename(f) for f in written)
    assert names == ["cell.toml", "robot1.urdf", "robot2.urdf"]
    for n in names:
        py_text = (tmp_path / "py" / n).read_text().replace(str(tmp_path / "py"), "DIR")
        cli_text = (tmp_path / "cli" / n).read_text().replace(str(tmp_path / "cli"), "DIR")
        assert py_text == cli_text, n
    with pytest.raises(FileExistsError, match="not empty"):
        r.export(tmp_path / "py")
    r.export(tmp_path / "py", overwrite=True)


def test_calibrate_cell_errors(cell, data, cell_path):
    s = hc.Session.load(data / "coincident.csv", cell)
    with pytest.raises(ValueError, match="model"):
        hc.calibrate_cell(cell, s, model="nope")
    other = hc.Cell.load(cell_path)
    with pytest.raises(ValueError, match="another Cell"):
        hc.calibrate_cell(other, s)


@pytest.mark.parametrize("name, extra", [("coincident", ["--trials", "40"]), ("mixed", [])])
def test_diagnose_same_report_as_the_cli(cell, cell_path, data, cli_json, cli, name, extra, tmp_path):
    path = data / f"{name}.csv"
    kwargs = {"trials": 40} if extra else {}
    d = hc.diagnose(cell, hc.Session.load(path, cell), **kwargs)
    assert d.mode == ("coincident" if name == "coincident" else "whole_cell")
    assert d.to_dict() == cli_json("diagnose", "--cell", cell_path, "--session", path, *extra)
    rc, text, _ = cli("diagnose", "--cell", cell_path, "--session", path, *extra)
    assert rc == 0 and d.text() == text
    files = d.export(tmp_path / "diag")
    assert files and all(os.path.exists(f) for f in files)
    assert d.b1_from_b2.shape == (4, 4)


def test_diagnosis_export_says_what_it_withholds_and_keeps_it_on_request(
    cell, cell_path, data, cli_json, cli, tmp_path
):
    """Diagnosis.export writes the do-no-harm model as `diagnose --export` does and warns of
    every withheld family in the CLI's words; keep_withheld=True writes what `--export --force`
    writes (the full model), file for file."""
    import warnings

    path = data / "mixed.csv"
    d = hc.diagnose(cell, hc.Session.load(path, cell))
    withheld = [w["family"] for w in d.to_dict()["do_no_harm"]["withheld"]]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        safe = d.export(tmp_path / "safe")
    said = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    no_harm = [m for m in said if m.startswith("do no harm: --export withholds")]
    if withheld:
        assert len(no_harm) == 1, said
        assert all(f in no_harm[0] for f in withheld), no_harm
        assert "keep_withheld=True exports the full model" in no_harm[0]
    else:
        assert no_harm == [], said
    rc, _, err = cli(
        "diagnose", "--cell", cell_path, "--session", path, "--export", tmp_path / "cli-safe"
    )
    assert rc == 0, err
    if withheld:
        assert "warning: do no harm: --export withholds" in err
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        full = d.export(tmp_path / "full", keep_withheld=True)
    kept = [str(w.message) for w in caught if "kept by keep_withheld=True" in str(w.message)]
    assert len(kept) == (1 if withheld else 0), [str(w.message) for w in caught]
    rc, _, err = cli(
        "diagnose", "--cell", cell_path, "--session", path, "--export", tmp_path / "cli-full",
        "--force",
    )
    assert rc == 0, err
    for ours, cli_dir in [(safe, "cli-safe"), (full, "cli-full")]:
        names = sorted(os.path.basename(f) for f in ours)
        assert names == sorted(os.listdir(tmp_path / cli_dir))
        for f in ours:
            if f.endswith(".toml"):
                continue  # names its own folder's URDFs
            with open(f, encoding="utf-8") as a, open(
                tmp_path / cli_dir / os.path.basename(f), encoding="utf-8"
            ) as b:
                assert a.read() == b.read(), f
