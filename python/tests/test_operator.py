"""The forward operator from Python: conventions, the adjoint identity,
shapes, and the zero-copy path."""

import tracemalloc

import numpy as np
import pytest

import cassi
from cassi import _cassi
from conftest import inner


@pytest.mark.parametrize("model", ["rounded", "subpixel", "dispersed-mask", "crisp-cells"])
@pytest.mark.parametrize(
    "psi",
    [
        {},
        {"dx": 1.5, "dy": -0.7, "theta_deg": 0.3, "a1": 2.04, "alpha_deg": 0.5},
        {"dx": -0.4, "a1": 1.7, "alpha_deg": 2.0, "blur_sigma_px": 0.6},
    ],
)
def test_adjoint_identity(rng, model, psi):
    mask = (rng.random((23, 31)) > 0.4).astype(np.float32)
    op = cassi.Operator(mask, bands=6, mismatch=psi, model=model)
    x = rng.random(op.cube_shape, dtype=np.float32)
    y = rng.random(op.measurement_shape, dtype=np.float32)
    lhs, rhs = inner(op.forward(x), y), inner(x, op.adjoint(y))
    assert abs(lhs - rhs) <= 1e-5 * max(abs(lhs), abs(rhs))
    # and it is not the identity of zeros
    assert abs(lhs) > 1.0


def test_shapes_follow_the_conventions():
    mask = np.ones((16, 20), np.float32)
    op = cassi.Operator(mask)  # 28 bands, stride 2, nominal
    assert op.cube_shape == (28, 16, 20)
    assert op.measurement_shape == (16, 20 + 54)
    assert (op.bands, op.stride, op.model) == (28, 2.0, "rounded")
    assert op.mismatch == dict(zip(cassi.PARAMETERS, [0, 0, 0, 2.0, 0, 0, 0]))
    # the paper's a1 = 2.04 widens the detector by one column
    assert cassi.Operator(mask, mismatch="paper").measurement_shape == (16, 20 + 55)


def test_one_open_pixel_lands_at_its_dispersion_offset():
    mask = np.zeros((8, 10), np.float32)
    mask[3, 4] = 1.0
    op = cassi.Operator(mask, bands=5)
    x = np.zeros(op.cube_shape, np.float32)
    x[:, 3, 4] = 1.0
    y = op.forward(x)
    assert sorted(zip(*np.nonzero(y))) == [(3, 4 + 2 * k) for k in range(5)]
    # +dx moves the pattern right, +dy down
    moved = cassi.Operator(mask, bands=1, dx=1.0, dy=2.0).forward(np.ones((1, 8, 10), np.float32))
    assert list(zip(*np.nonzero(moved))) == [(5, 5)]


def test_mismatch_by_dict_keywords_preset_and_registry_names(rng):
    mask = (rng.random((12, 12)) > 0.5).astype(np.float32)
    paper = cassi.Operator(mask, mismatch="paper")
    as_dict = cassi.Operator(mask, mismatch=paper.mismatch)
    as_kw = cassi.Operator(mask, **paper.mismatch)
    x = rng.random(paper.cube_shape, dtype=np.float32)
    np.testing.assert_array_equal(paper.forward(x), as_dict.forward(x))
    np.testing.assert_array_equal(paper.forward(x), as_kw.forward(x))
    assert paper.mismatch["theta_deg"] == 0.3
    # keywords override the dict
    assert cassi.Operator(mask, mismatch={"dx": 1.0}, dx=2.0).mismatch["dx"] == 2.0
    assert set(cassi.PARAMETER_UNITS) == set(cassi.PARAMETERS)


def test_forward_is_the_noise_free_simulation(rng):
    mask = (rng.random((20, 24)) > 0.5).astype(np.float32)
    scene = rng.random((7, 20, 24), dtype=np.float32)
    for model in ["rounded", "subpixel"]:
        op = cassi.Operator(mask, bands=7, mismatch="paper", model=model)
        y = cassi.simulate(scene, mask, "paper", model=model, noise=False)
        np.testing.assert_array_equal(op.forward(scene), y)


def test_c_contiguous_float32_is_read_in_place():
    x = np.ones((28, 256, 256), np.float32)
    address, copied = _cassi._input_address(x)
    assert (address, copied) == (x.ctypes.data, False)
    # a view at an offset is still read in place
    sub = x[1:]
    assert _cassi._input_address(sub) == (sub.ctypes.data, False)
    # other dtypes and layouts are converted (a copy), not refused
    for other in [x.astype(np.float64), np.asfortranarray(x), x[:, :, ::2], x.astype(">f4")]:
        address, copied = _cassi._input_address(other)
        assert copied and address != other.ctypes.data


def _peak_bytes(f):
    tracemalloc.start()
    tracemalloc.reset_peak()
    try:
        f()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_forward_allocates_only_its_output():
    mask = np.ones((256, 256), np.float32)
    op = cassi.Operator(mask)
    x = np.full(op.cube_shape, 0.5, np.float32)
    out_bytes = 256 * 310 * 4
    in_bytes = x.nbytes  # 7.3 MB
    peak = _peak_bytes(lambda: op.forward(x))
    assert peak < out_bytes + 64 * 1024, (peak, out_bytes)
    # the measurement sees a copy when there is one: float64 input is converted
    x64 = x.astype(np.float64)
    assert _peak_bytes(lambda: op.forward(x64)) >= in_bytes
    # adjoint: the output cube only
    y = np.ones(op.measurement_shape, np.float32)
    assert _peak_bytes(lambda: op.adjoint(y)) < in_bytes + 64 * 1024


def test_converted_inputs_give_the_same_result(rng):
    mask = (rng.random((10, 12)) > 0.5)  # bool mask, converted
    op = cassi.Operator(mask, bands=3)
    x = rng.random((3, 10, 12))  # float64
    np.testing.assert_array_equal(op.forward(x), op.forward(x.astype(np.float32)))
    fortran = np.asfortranarray(x.astype(np.float32))
    np.testing.assert_array_equal(op.forward(fortran), op.forward(x.astype(np.float32)))
    np.testing.assert_array_equal(op.forward(x.tolist()), op.forward(x.astype(np.float32)))
