"""The learned methods from Python: in a package built with the networks
(`MATURIN_PEP517_ARGS="--features nets" pip install ./python`), MST-S on the
PyTorch reference measurement gives the reference PSNR and the same cube as
`cassi reconstruct`; without them, a clear error.

The reference files are ../shared/data (or $CASSI_SHARED_DATA); without
them the networks' tests skip, unless CASSI_REQUIRE_SHARED_DATA=1 (as
in .ci/run). CASSI_REQUIRE_NETS=1 fails the run when the package lacks the
networks.
"""

import os
import pathlib
import subprocess

import numpy as np
import pytest

import cassi
from conftest import REPO


def shared_data():
    env = os.environ.get("CASSI_SHARED_DATA")
    path = pathlib.Path(env) if env else REPO.parent / "shared" / "data"
    if not (path / "nets" / "common" / "y.npy").is_file():
        msg = f"no reference data at {path} (set CASSI_SHARED_DATA)"
        if os.environ.get("CASSI_REQUIRE_SHARED_DATA") == "1":
            pytest.fail(msg)
        pytest.skip(msg)
    return path


@pytest.fixture
def nets():
    if not cassi.NETS_BUILT:
        msg = "this package was built without the networks"
        if os.environ.get("CASSI_REQUIRE_NETS") == "1":
            pytest.fail(msg)
        pytest.skip(msg)


def test_without_the_networks_a_learned_method_is_a_clear_error():
    if cassi.NETS_BUILT:
        pytest.skip("this package has the networks")
    y = np.zeros((64, 118), np.float32)
    with pytest.raises(ValueError, match="built without the deep networks"):
        cassi.reconstruct(y, np.ones((64, 64), np.float32), method="mst-s", weights="w.pth")


def test_weights_are_required_and_checked(nets, tmp_path):
    y, mask = np.ones((256, 310), np.float32), np.ones((256, 256), np.float32)
    with pytest.raises(ValueError, match="needs weights"):
        cassi.reconstruct(y, mask, method="hdnet")
    with pytest.raises(FileNotFoundError, match="no such file"):
        cassi.reconstruct(y, mask, method="hdnet", weights=tmp_path / "missing.pth")
    with pytest.raises(ValueError, match="weights= is for the learned methods"):
        cassi.reconstruct(y, mask, method="gap-tv", weights=tmp_path / "w.pth")


def test_mst_s_gives_the_reference_psnr_and_the_cli_cube(nets, cli, tmp_path):
    data = shared_data()
    common = data / "nets" / "common"
    y = np.load(common / "y.npy")[0]
    mask = np.load(common / "mask.npy")
    truth = np.load(common / "cube.npy")[0]
    weights = data / "weights" / "mst_s.pth"
    cube, info = cassi.reconstruct(y, mask, method="mst-s", weights=weights, return_info=True)
    assert cube.shape == (28, 256, 256) and info["method"] == "mst-s"
    psnr = cassi.metrics(truth, cube)["psnr"]
    assert abs(psnr - 26.79) < 0.01, psnr
    out = tmp_path / "cube.npy"
    subprocess.run([cli, "reconstruct", str(common / "y.npy"), "--mask", str(common / "mask.npy"),
                    "--method", "mst-s", "--weights", str(weights), "-o", str(out), "--quiet"],
                   check=True)
    assert np.array_equal(cassi.load(out, kind="cube"), cube)


def test_a_study_runs_a_network_beside_a_solver(nets, tmp_path):
    data = shared_data()
    summary = cassi.evaluate(tmp_path, synthetic=1, size=64, iterations=15,
                             methods=["gap-tv", "hdnet"],
                             weights={"hdnet": data / "nets" / "hdnet" / "hdnet_seed0.safetensors"})
    assert [m["method"] for m in summary["methods"]] == ["gap-tv", "hdnet"]
    rows = (tmp_path / "outcomes.csv").read_text().splitlines()
    assert sum(",hdnet," in r for r in rows) == 5  # one per scenario


def test_without_the_networks_a_study_refuses_a_learned_method(tmp_path):
    if cassi.NETS_BUILT:
        pytest.skip("this package has the networks")
    with pytest.raises(ValueError, match="built without the deep networks"):
        cassi.evaluate(tmp_path, synthetic=1, size=64, methods=["hdnet"])
