"""load/save through cassi-io: every format, the layout rules, errors that
name the file and the variable."""

import numpy as np
import pytest

import cassi
from conftest import REPO

FIXTURES = REPO / "crates" / "cassi-io" / "tests" / "data"


@pytest.mark.parametrize("ext", [".npy", ".npz", ".mat"])
def test_cube_and_frame_round_trip(tmp_path, rng, ext):
    cube = rng.random((5, 12, 13), dtype=np.float32)
    path = tmp_path / f"cube{ext}"
    cassi.save(path, cube)
    np.testing.assert_array_equal(cassi.load(path, kind="cube"), cube)
    stored = cassi.load(path, "cube" if ext != ".npy" else None)
    if ext == ".mat":
        # MATLAB benchmark convention: (rows, cols, bands) on disk
        assert stored.shape == (12, 13, 5)
        np.testing.assert_array_equal(stored, cube.transpose(1, 2, 0))
    else:
        np.testing.assert_array_equal(stored, cube)
    frame = rng.random((7, 9))  # float64, stored as float32
    fpath = tmp_path / f"mask{ext}"
    cassi.save(fpath, frame, var="mask")
    back = cassi.load(fpath, "mask" if ext != ".npy" else None, kind="frame")
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, frame.astype(np.float32))


def test_mat_v73_reads_like_v5():
    v73 = cassi.load(FIXTURES / "v73.mat", "cube")
    v5 = cassi.load(FIXTURES / "v5_types.mat", "cube")
    assert v73.shape == (4, 5, 3)
    np.testing.assert_array_equal(v73, v5)
    assert cassi.load(FIXTURES / "v73.mat", "cube", kind="cube").shape == (3, 4, 5)
    assert cassi.load(FIXTURES / "v73.mat", "mask", kind="frame").shape == (4, 6)


def test_stored_dtypes_and_orders_read_as_c_order_float32():
    c = cassi.load(FIXTURES / "cube_f32_c.npy")
    for other in ["cube_f32_f.npy", "cube_f64_c.npy", "cube_f64_f.npy", "cube_f32_be.npy"]:
        a = cassi.load(FIXTURES / other)
        assert a.dtype == np.float32 and a.flags.c_contiguous
        np.testing.assert_array_equal(a, c)


def test_errors_name_the_file_and_variable(tmp_path):
    missing = tmp_path / "nope.npy"
    with pytest.raises(cassi.FileNotFound, match="nope.npy: no such file"):
        cassi.load(missing)
    with pytest.raises(FileNotFoundError):
        cassi.save(tmp_path / "no" / "dir.npy", np.ones(3))
    with pytest.raises(cassi.InputError, match=r"no variable named 'mesa'; the file holds: .*cube"):
        cassi.load(FIXTURES / "v73.mat", "mesa")
    with pytest.raises(ValueError, match=r"frame_nan.npy: variable .* contains a non-finite value"):
        cassi.load(FIXTURES / "frame_nan.npy")
    with pytest.raises(ValueError, match="unknown file format"):
        cassi.save(tmp_path / "x.txt", np.ones(3))
    with pytest.raises(ValueError, match=r"v73.mat: variable .cube. has shape 4×5×3, expected a 2-D frame"):
        cassi.load(FIXTURES / "v73.mat", "cube", kind="frame")
    with pytest.raises(ValueError, match="truncated"):
        cassi.load(FIXTURES / "truncated.npy")
    with pytest.raises(ValueError, match="kind 'table'"):
        cassi.load(FIXTURES / "cube_f32_c.npy", kind="table")
    with pytest.raises(ValueError, match=r"array contains a non-finite value \(NaN\) at index \(1,\)"):
        cassi.save(tmp_path / "n.npy", np.array([0.0, np.nan]))
