"""Shared helpers of the cassi Python tests.

Tests that run the `cassi` command-line program find it at $CASSI_BIN, else
target/release/cassi in the repository. When it is missing they skip with a
note, unless CASSI_REQUIRE_CLI=1 (set by .ci/run), which makes them fail
naming the path they looked at.
"""

import os
import pathlib

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def cli_path():
    env = os.environ.get("CASSI_BIN")
    return pathlib.Path(env) if env else REPO / "target" / "release" / "cassi"


@pytest.fixture(scope="session")
def cli():
    path = cli_path()
    if not path.is_file():
        msg = f"the cassi program is not at {path} (cargo build --release, or set CASSI_BIN)"
        if os.environ.get("CASSI_REQUIRE_CLI") == "1":
            pytest.fail(msg)
        pytest.skip(msg)
    return str(path)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def inner(a, b):
    """<a, b> in float64."""
    return float(np.dot(a.astype(np.float64).ravel(), b.astype(np.float64).ravel()))
