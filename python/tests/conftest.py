"""Fixtures: the repository, the CLI binaries (built by `cargo test`/`cargo build`), a cell and
simulated sessions written as CSV files, so that each test runs the Python API and the CLI on the
same inputs."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

import handclasp as hc

REPO = Path(__file__).resolve().parents[2]


def _binary(name):
    """The CLI binary: $HANDCLASP_BIN_DIR/name, else target/debug or target/release."""
    dirs = [os.environ.get("HANDCLASP_BIN_DIR")] if os.environ.get("HANDCLASP_BIN_DIR") else []
    dirs += [REPO / "target" / "debug", REPO / "target" / "release"]
    for d in dirs:
        p = Path(d) / name
        if p.is_file() and os.access(p, os.X_OK):
            return p
    return None


@pytest.fixture(scope="session")
def cli():
    """Runs `handclasp ARGS…`, returns (returncode, stdout, stderr); skips without the binary."""
    exe = _binary("handclasp")
    if exe is None:
        pytest.skip("the handclasp binary is not built (cargo build -p handclasp)")

    def run(*args):
        p = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)
        return p.returncode, p.stdout, p.stderr

    return run


@pytest.fixture(scope="session")
def cli_json(cli):
    """`handclasp ARGS… --json` parsed; fails with the CLI's stderr when it fails."""

    def run(*args):
        rc, out, err = cli(*args, "--json")
        assert rc == 0, err
        return json.loads(out)

    return run


@pytest.fixture(scope="session")
def cell_path():
    return REPO / "cells" / "floor-wall.toml"


@pytest.fixture(scope="session")
def cell(cell_path):
    return hc.Cell.load(cell_path)


@pytest.fixture(scope="session")
def data(tmp_path_factory, cell):
    """A folder with simulated sessions of the floor-wall cell (seeded): coincident.csv (12
    rows) and mixed.csv (coincident, contact, tracker, plane rows)."""
    d = tmp_path_factory.mktemp("data")
    hc.simulate_session(cell, n=12, seed=3, layout="random").to_csv(d / "coincident.csv")
    hc.simulate_session(cell, n=16, seed=5, layout="random", kind="mixed").to_csv(d / "mixed.csv")
    return d
