"""export_controllers against `handclasp export --json`: the same report, the same files."""

import os

import pytest

import handclasp as hc


def _same_but_folder(d, folder):
    """The report with the output folder written as DIR (the CLI and Python write to two)."""
    text = repr(d).replace(str(folder), "DIR")
    return text


@pytest.mark.parametrize("formats, flag", [(None, "all"), (["abb", "ros2"], "abb,ros2")])
def test_export_controllers_same_report_and_files_as_the_cli(cell, cell_path, cli_json, tmp_path, formats, flag):
    py_dir, cli_dir = tmp_path / "py", tmp_path / "cli"
    d = hc.export_controllers(cell, py_dir, formats=formats)
    want = cli_json("export", "--cell", cell_path, "--to", cli_dir, "--format", flag)
    assert _same_but_folder(d, py_dir) == _same_but_folder(want, cli_dir)
    names = sorted(os.path.basename(f["path"]) for f in d["files"])
    assert names == sorted(os.listdir(cli_dir)) == sorted(os.listdir(py_dir))
    assert {f["format"] for f in d["files"]} == ({"abb", "ros2"} if formats else {"abb", "kuka", "fanuc", "yaskawa", "ros2"})
    for n in names:
        py_text = (py_dir / n).read_text().replace(str(py_dir), "DIR")
        cli_text = (cli_dir / n).read_text().replace(str(cli_dir), "DIR")
        assert py_text == cli_text, n
    for f in d["files"]:
        assert f["read_back_um"] <= 1.0 and f["read_back_urad"] <= 1.0


def test_export_controllers_errors(cell, tmp_path):
    with pytest.raises(ValueError, match='unknown target "staubli"'):
        hc.export_controllers(cell, tmp_path / "a", formats=["staubli"])
    assert not (tmp_path / "a").exists()
    hc.export_controllers(cell, tmp_path / "b", formats=["kuka"])
    with pytest.raises(FileExistsError, match="not empty"):
        hc.export_controllers(cell, tmp_path / "b", formats=["kuka"])
    hc.export_controllers(cell, tmp_path / "b", formats=["kuka"], force=True)
    # A folder another export holds (its lock file present) is refused, naming the lock.
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / ".handclasp-export.lock").write_text("1")
    with pytest.raises(FileExistsError, match="another export"):
        hc.export_controllers(cell, tmp_path / "c", force=True)
