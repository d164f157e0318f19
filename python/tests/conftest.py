import os
from pathlib import Path

import numpy as np
import pytest

import funcorr

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "data" / "faust"
X_PATH = DATA / "tr_reg_000.off"
Y_PATH = DATA / "tr_reg_001.off"


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def mesh_x():
    return funcorr.read_mesh(X_PATH)


@pytest.fixture(scope="session")
def mesh_y():
    return funcorr.read_mesh(Y_PATH)


@pytest.fixture(scope="session")
def prepared_pair(mesh_x, mesh_y):
    return funcorr.prepare(mesh_x, k=60), funcorr.prepare(mesh_y, k=60)


@pytest.fixture(scope="session")
def ground_truth():
    return (
        funcorr.read_vts(DATA / "tr_reg_000.vts"),
        funcorr.read_vts(DATA / "tr_reg_001.vts"),
        funcorr.read_vts(DATA / "tr_reg_001.sym.vts"),
    )


@pytest.fixture(scope="session")
def cli():
    """The release binary of funcorr-cli (built by .ci/run before pytest; FUNCORR_CLI overrides)."""
    path = Path(os.environ.get("FUNCORR_CLI", ROOT / "target" / "release" / "funcorr"))
    if not path.exists():
        pytest.fail(f"{path} not found: build it with `cargo build --release -p funcorr-cli` (or set FUNCORR_CLI)")
    return path


@pytest.fixture(scope="session")
def default_match():
    """funcorr.match on the bundled pair with the defaults (shared by several tests)."""
    return funcorr.match(X_PATH, Y_PATH)
