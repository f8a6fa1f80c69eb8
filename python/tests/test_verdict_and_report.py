"""The verdict at the work site and the report page from Python, against `handclasp calibrate
--cell … --work-points F --accept-mm X --accept-deg Y` and `diagnose … --report`: the same
JSON, the same text, the same page (but for the command-line and version line)."""

import re
import warnings

import numpy as np
import pytest

import handclasp as hc

# Tool positions in base 1, mm, around the floor-wall cell's teach centre (475, -50, 995).
WORK_MM = np.array([[475.0, -50.0, 995.0], [525.0, 0.0, 1020.0], [430.0, -110.0, 960.0]])


@pytest.fixture(scope="module")
def work_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("work") / "work.csv"
    rows = "\n".join(",".join(f"{v:.1f}" for v in p) for p in WORK_MM)
    path.write_text(f"x_mm,y_mm,z_mm\n{rows}\n")
    return path


def _without_invocation(html):
    """The page without its command line and version (the one line Python writes differently)."""
    html = re.sub(r'<pre class="cmd" id="command-line">.*?</pre>', "", html, flags=re.S)
    return re.sub(r'<span id="version">.*?</span>', "", html, flags=re.S)


@pytest.mark.parametrize("name", ["coincident", "mixed"])
def test_calibrate_cell_verdict_equals_the_cli(cell, cell_path, data, cli_json, cli, work_csv, name):
    path = data / f"{name}.csv"
    session = hc.Session.load(path, cell)
    flags = ["--work-points", work_csv, "--accept-mm", 1.0, "--accept-deg", 0.05]
    r = hc.calibrate_cell(cell, session, work_points=work_csv, accept_mm=1.0, accept_deg=0.05)
    expected = cli_json("calibrate", "--cell", cell_path, "--session", path, *flags)
    assert "work_site" in expected
    assert r.to_dict() == expected
    assert r.work_site == expected["work_site"]
    rc, text, err = cli("calibrate", "--cell", cell_path, "--session", path, *flags)
    assert rc == 0, err
    assert r.text() == text
    # The same points as an array: the same verdict, but for where they came from.
    a = hc.calibrate_cell(cell, session, work_points=WORK_MM, accept_mm=1.0, accept_deg=0.05)
    site, expected_site = dict(a.work_site), dict(expected["work_site"])
    assert site.pop("source") == "3 points of the work_points array"
    expected_site.pop("source")
    assert site == expected_site


def test_calibrate_cell_without_verdict_arguments_has_none(cell, data):
    r = hc.calibrate_cell(cell, hc.Session.load(data / "coincident.csv", cell), model="placement")
    assert r.work_site is None and "work_site" not in r.to_dict()


def test_verdict_arguments_are_checked(cell, data, tmp_path):
    s = hc.Session.load(data / "coincident.csv", cell)
    with pytest.raises(ValueError, match="positive"):
        hc.calibrate_cell(cell, s, accept_mm=-1.0)
    with pytest.raises(ValueError, match=r"work_points: shape \[3, 2\]"):
        hc.calibrate_cell(cell, s, work_points=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="not finite"):
        hc.calibrate_cell(cell, s, work_points=np.array([[np.nan, 0.0, 0.0]]))
    with pytest.raises(FileNotFoundError):
        hc.calibrate_cell(cell, s, work_points=tmp_path / "missing.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("x_mm,y_mm\n1,2\n")
    with pytest.raises(ValueError, match="data row 1"):
        hc.calibrate_cell(cell, s, work_points=bad)
    # A coincident-only session has no whole-cell diagnosis to give a verdict for (as the CLI).
    with pytest.raises(ValueError, match="contact, tracker or plane rows"):
        hc.diagnose(cell, s, trials=40, accept_mm=1.0)


def test_diagnose_verdict_equals_the_cli(cell, cell_path, data, cli_json, cli, work_csv):
    path = data / "mixed.csv"
    flags = ["--work-points", work_csv, "--accept-mm", 1.0, "--accept-deg", 0.5]
    d = hc.diagnose(cell, hc.Session.load(path, cell), work_points=work_csv, accept_mm=1.0, accept_deg=0.5)
    expected = cli_json("diagnose", "--cell", cell_path, "--session", path, *flags)
    assert "work_site" in expected and "work_site_model" in expected
    assert d.to_dict() == expected
    assert d.work_site == expected["work_site"]
    rc, text, err = cli("diagnose", "--cell", cell_path, "--session", path, *flags)
    assert rc == 0, err
    assert d.text() == text


def test_calibration_report_page_equals_the_cli(cell, cell_path, data, cli, work_csv, tmp_path):
    path = data / "mixed.csv"
    flags = ["--work-points", work_csv, "--accept-mm", 1.0]
    rc, _, err = cli("calibrate", "--cell", cell_path, "--session", path, *flags, "--report", tmp_path / "cli.html")
    assert rc == 0, err
    r = hc.calibrate_cell(cell, hc.Session.load(path, cell))
    # The verdict's arguments given to report() …
    assert r.report(tmp_path / "py.html", work_points=work_csv, accept_mm=1.0) == str(tmp_path / "py.html")
    cli_page = (tmp_path / "cli.html").read_text()
    py_page = (tmp_path / "py.html").read_text()
    assert 'id="command-line">python: handclasp.CellResult.report</pre>' in py_page
    assert _without_invocation(py_page) == _without_invocation(cli_page)
    # … or to calibrate_cell: the same page.
    r2 = hc.calibrate_cell(cell, hc.Session.load(path, cell), work_points=work_csv, accept_mm=1.0)
    r2.report(tmp_path / "py2.html")
    assert (tmp_path / "py2.html").read_text() == py_page
    # Without any: the verdict at the teach centre, as `--report` alone.
    rc, _, err = cli("calibrate", "--cell", cell_path, "--session", path, "--report", tmp_path / "cli0.html")
    assert rc == 0, err
    r.report(tmp_path / "py0.html")
    assert _without_invocation((tmp_path / "py0.html").read_text()) == _without_invocation(
        (tmp_path / "cli0.html").read_text()
    )
    with pytest.raises(OSError):
        r.report(tmp_path / "no-such-folder" / "page.html")


@pytest.mark.parametrize("name", ["coincident", "mixed"])
def test_diagnosis_report_page_equals_the_cli(cell, cell_path, data, cli, work_csv, tmp_path, name):
    path = data / f"{name}.csv"
    extra = ["--trials", 40] if name == "coincident" else ["--work-points", work_csv, "--accept-mm", 2.0]
    rc, _, err = cli("diagnose", "--cell", cell_path, "--session", path, *extra, "--report", tmp_path / "cli.html")
    assert rc == 0, err
    kwargs = {"trials": 40} if name == "coincident" else {}
    d = hc.diagnose(cell, hc.Session.load(path, cell), **kwargs)
    if name == "coincident":
        d.report(tmp_path / "py.html")
        with pytest.raises(ValueError, match="contact, tracker or plane rows"):
            d.report(tmp_path / "py.html", accept_mm=1.0)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            d.report(tmp_path / "py.html", work_points=work_csv, accept_mm=2.0)
    cli_page = (tmp_path / "cli.html").read_text()
    py_page = (tmp_path / "py.html").read_text()
    assert 'id="command-line">python: handclasp.DiagnoseResult.report</pre>' in py_page
    assert _without_invocation(py_page) == _without_invocation(cli_page)


def test_diagnose_force_is_the_cli_force(cell, cell_path, data, cli_json, cli, work_csv, tmp_path):
    """diagnose(force=True) gives `diagnose --force`'s verdict (the full model, the families the
    do-no-harm rule withholds included), JSON and text; force=False the do-no-harm model's; and
    export() then writes what `--force --export` writes."""
    path = data / "mixed.csv"
    flags = ["--work-points", work_csv, "--accept-mm", 1.0, "--accept-deg", 0.5]
    s = hc.Session.load(path, cell)
    kw = dict(work_points=work_csv, accept_mm=1.0, accept_deg=0.5)
    forced = hc.diagnose(cell, s, force=True, **kw)
    expected = cli_json("diagnose", "--cell", cell_path, "--session", path, *flags, "--force")
    assert forced.to_dict() == expected
    assert expected["work_site_model"]["model"] == "full"
    every = [e["family"]["name"] for e in expected["effects"]]
    assert expected["work_site_model"]["families"] == every
    rc, text, err = cli("diagnose", "--cell", cell_path, "--session", path, *flags, "--force")
    assert rc == 0, err
    assert forced.text() == text
    safe = hc.diagnose(cell, s, **kw).to_dict()
    withheld = [w["family"] for w in safe["do_no_harm"]["withheld"]]
    assert safe["work_site_model"]["model"] == ("do_no_harm" if withheld else "full")
    assert safe["work_site_model"]["withheld"] == withheld
    # export() defaults to diagnose's force: the full model, file for file with --force --export.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        files = forced.export(tmp_path / "py")
    kept = [str(w.message) for w in caught if "kept by diagnose(force=True)" in str(w.message)]
    assert len(kept) == (1 if withheld else 0)
    rc, _, err = cli("diagnose", "--cell", cell_path, "--session", path, "--force", "--export", tmp_path / "cli")
    assert rc == 0, err
    for f in files:
        if not f.endswith(".toml"):  # cell.toml names its own folder's URDFs
            with open(f, encoding="utf-8") as a, open(tmp_path / "cli" / f.split("/")[-1], encoding="utf-8") as b:
                assert a.read() == b.read(), f
