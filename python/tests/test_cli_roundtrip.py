"""Python against the `cassi` program: the same inputs through `cassi
simulate` / `cassi calibrate` and through the bindings give the same
measurement and a calibration the bindings read and use."""

import json
import subprocess

import numpy as np
import pytest

import cassi


def run(cli, *args, cwd):
    done = subprocess.run([cli, *map(str, args)], cwd=cwd, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done


@pytest.fixture
def inputs(tmp_path):
    scene = cassi.synthetic_scene(48, 48, 8, seed=3)
    mask = cassi.random_mask(48, 48, seed=4)
    cassi.save(tmp_path / "scene.npy", scene)
    cassi.save(tmp_path / "mask.npy", mask, var="mask")
    return scene, mask


@pytest.mark.parametrize("model", ["rounded", "subpixel"])
def test_discrete_simulation_matches_the_cli(cli, tmp_path, inputs, model):
    scene, mask = inputs
    run(cli, "simulate", "--scene", "scene.npy", "--mask", "mask.npy", "--dx", 0.7, "--dy", -0.4,
        "--theta", 0.2, "--a1", 2.03, "--alpha", 0.4, "--model", model,
        "--photon-peak", 5000, "--read-noise", 2, "--noise-seed", 9, "-o", "meas.npy", "-q",
        cwd=tmp_path)
    theirs = cassi.load(tmp_path / "meas.npy")
    ours = cassi.simulate(scene, mask, dict(dx=0.7, dy=-0.4, theta_deg=0.2, a1=2.03, alpha_deg=0.4),
                          model=model, photon_peak=5000, read_noise=2, seed=9)
    assert ours.shape == theirs.shape
    np.testing.assert_array_equal(ours, theirs)
    # the sidecar's true parameters are the registry's keys (a straight
    # dispersion's curvature is not written)
    sidecar = json.loads((tmp_path / "meas.json").read_text())
    text = json.dumps(sidecar)
    for key in cassi.PARAMETERS:
        assert (f'"{key}"' in text) == (key != "a2"), key


def test_physical_simulation_matches_the_cli(cli, tmp_path, inputs):
    scene, mask = inputs
    run(cli, "simulate", "--scene", "scene.npy", "--mask", "mask.npy", "--paper-mismatch",
        "--oversample", 2, "--blur", 0.5, "--blur-slope", 0.002, "--adc-bits", 12,
        "--no-noise", "-o", "meas.mat", "-q", cwd=tmp_path)
    theirs = cassi.load(tmp_path / "meas.mat", kind="frame")
    ours = cassi.simulate_physical(scene, mask, "paper", oversample=2, blur_sigma_px=0.5,
                                   blur_slope_px_per_nm=0.002, adc_bits=12, noise=False)
    np.testing.assert_array_equal(ours, theirs)
    # with a halo under the blur: the same on both sides, and not the blur alone
    run(cli, "simulate", "--scene", "scene.npy", "--mask", "mask.npy", "--paper-mismatch",
        "--oversample", 2, "--blur", 0.5, "--halo", "0.3,2", "--no-noise", "-o", "halo.npy", "-q",
        cwd=tmp_path)
    theirs = cassi.load(tmp_path / "halo.npy", kind="frame")
    ours = cassi.simulate_physical(scene, mask, "paper", oversample=2, blur_sigma_px=0.5,
                                   halo=(0.3, 2.0), noise=False)
    np.testing.assert_array_equal(ours, theirs)
    plain = cassi.simulate_physical(scene, mask, "paper", oversample=2, blur_sigma_px=0.5,
                                    noise=False)
    assert not np.array_equal(ours, plain)
    with pytest.raises(ValueError, match="halo.share"):
        cassi.simulate_physical(scene, mask, "paper", oversample=2, halo=(1.5, 2.0))
    # a curved dispersion: the same on both sides
    run(cli, "simulate", "--scene", "scene.npy", "--mask", "mask.npy", "--paper-mismatch",
        "--oversample", 2, "--blur", 0.5, "--dispersion-a2", 0.004, "--no-noise", "-o", "bent.npy",
        "-q", cwd=tmp_path)
    theirs = cassi.load(tmp_path / "bent.npy", kind="frame")
    ours = cassi.simulate_physical(scene, mask, "paper", oversample=2, blur_sigma_px=0.5,
                                   dispersion_a2=0.004, noise=False)
    np.testing.assert_array_equal(ours, theirs)
    # a stepped dispersion likewise
    run(cli, "simulate", "--scene", "scene.npy", "--mask", "mask.npy", "--paper-mismatch",
        "--oversample", 2, "--blur", 0.5, "--dispersion-step", "3:0.5", "--no-noise", "-o",
        "stepped.npy", "-q", cwd=tmp_path)
    stepped = cassi.load(tmp_path / "stepped.npy", kind="frame")
    assert not np.array_equal(stepped, plain)
    np.testing.assert_array_equal(
        stepped, cassi.simulate_physical(scene, mask, "paper", oversample=2, blur_sigma_px=0.5,
                                         dispersion_step=(3, 0.5), noise=False))
    with pytest.raises(ValueError, match="dispersion_step"):
        cassi.simulate_physical(scene, mask, "paper", oversample=2, dispersion_step=(3, 2.5))
    # each band's light spread between its neighbours likewise
    run(cli, "simulate", "--scene", "scene.npy", "--mask", "mask.npy", "--paper-mismatch",
        "--oversample", 2, "--blur", 0.5, "--band-spread", "linear", "--no-noise", "-o",
        "spread.npy", "-q", cwd=tmp_path)
    spread = cassi.load(tmp_path / "spread.npy", kind="frame")
    assert not np.array_equal(spread, plain)
    np.testing.assert_array_equal(
        spread, cassi.simulate_physical(scene, mask, "paper", oversample=2, blur_sigma_px=0.5,
                                        band_spread="linear", noise=False))
    with pytest.raises(ValueError, match="band_spread.*'box'"):
        cassi.simulate_physical(scene, mask, "paper", oversample=2, band_spread="box")
    # and it is not the discrete operator's measurement
    discrete = cassi.simulate(scene, mask, "paper", model="subpixel", noise=False)
    assert discrete.shape == ours.shape and not np.allclose(discrete, ours, atol=1e-3)


def test_cli_calibration_file_drives_the_python_reconstruction(cli, tmp_path, inputs):
    scene, mask = inputs
    run(cli, "simulate", "--scene", "scene.npy", "--mask", "mask.npy", "--paper-mismatch",
        "--model", "subpixel", "--no-noise", "-o", "meas.npy", "-q", cwd=tmp_path)
    run(cli, "calibrate", "meas.npy", "--mask", "mask.npy", "--bands", 8, "-o", "calib.json", "-q",
        cwd=tmp_path)
    theirs = cassi.Calibration.from_json((tmp_path / "calib.json").read_text())
    y = cassi.load(tmp_path / "meas.npy")
    # the CLI fits the point bands the measurement's sidecar records (the
    # subpixel operator made it); the library is told
    ours = cassi.calibrate(y, mask, bands=8, band_spread="point")
    # the same library call on the same data: the same estimate
    for key in cassi.PARAMETERS:
        assert ours.parameters[key] == pytest.approx(theirs.parameters[key], abs=1e-9), key
    assert ours.model == theirs.model == "dispersed-mask"  # the default
    run(cli, "reconstruct", "meas.npy", "--mask", "mask.npy", "--bands", 8, "--calibration",
        "calib.json", "--method", "gap-tv", "-o", "cube.npy", "-q", cwd=tmp_path)
    cube_cli = cassi.load(tmp_path / "cube.npy")
    cube_py = cassi.reconstruct(y, mask, bands=8, calibration=theirs)
    assert cube_py.shape == (8, 48, 48)
    # the same solve (the CLI writes the cube unclipped)
    np.testing.assert_allclose(cube_cli, cube_py, atol=1e-5)
