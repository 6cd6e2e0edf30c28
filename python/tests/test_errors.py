"""Bad input raises the right exception with the library's message: the
variable named, the shape got and the shape wanted."""

import numpy as np
import pytest

import cassi
from cassi import _cassi


@pytest.fixture
def op():
    return cassi.Operator(np.ones((8, 9), np.float32), bands=4)


def test_exception_hierarchy():
    for cls, builtin in [
        (cassi.InputError, ValueError),
        (cassi.InputTypeError, TypeError),
        (cassi.FileNotFound, FileNotFoundError),
        (cassi.FileError, OSError),
    ]:
        assert issubclass(cls, cassi.CassiError) and issubclass(cls, builtin)
        assert cls.__module__ == "cassi"
    assert issubclass(cassi.CassiError, Exception)


def test_wrong_shape_names_the_variable_and_both_shapes(op):
    with pytest.raises(cassi.InputError, match=r"cube x has shape \(3, 8, 9\), expected \(4, 8, 9\)"):
        op.forward(np.zeros((3, 8, 9), np.float32))
    with pytest.raises(ValueError, match=r"measurement y has shape \(8, 9\), expected \(8, 15\)"):
        op.adjoint(np.zeros((8, 9), np.float32))
    with pytest.raises(ValueError, match=r"mask has shape \(8,\), expected a 2-D array"):
        cassi.Operator(np.ones(8, np.float32))
    with pytest.raises(ValueError, match=r"scene has shape \(8, 9\), expected a 3-D array"):
        cassi.simulate(np.ones((8, 9)), np.ones((8, 9)))
    with pytest.raises(ValueError, match=r"scene \(rows, cols\) has shape 8×9, expected 8×10"):
        cassi.simulate(np.ones((2, 8, 9)), np.ones((8, 10)))


def test_non_finite_values_are_refused_with_their_index(op):
    x = np.zeros(op.cube_shape, np.float32)
    x[2, 5, 7] = np.inf
    with pytest.raises(cassi.InputError, match=r"cube x contains a non-finite value \(inf\) at index \(2, 5, 7\)"):
        op.forward(x)
    x[2, 5, 7] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        op.forward(x)
    mask = np.ones((8, 9))
    mask[0, 1] = np.nan
    with pytest.raises(ValueError, match=r"mask contains a non-finite value \(NaN\) at index \(0, 1\)"):
        cassi.Operator(mask)
    # a float64 beyond the float32 range becomes inf and is refused, saying why
    big = np.zeros(op.cube_shape)
    big[0, 0, 0] = 1e300
    with pytest.raises(ValueError, match="after conversion to float32"), np.errstate(over="ignore"):
        op.forward(big)


def test_unusable_dtypes_are_type_errors(op):
    with pytest.raises(cassi.InputTypeError, match="cube x has dtype complex64"):
        op.forward(np.zeros(op.cube_shape, np.complex64))
    with pytest.raises(TypeError, match="cube x has dtype"):
        op.forward(np.array([["a"]]))
    with pytest.raises(TypeError, match="mismatch must be"):
        cassi.Operator(np.ones((4, 4)), mismatch=3)


def test_parameters_are_checked_by_name():
    mask = np.ones((8, 8), np.float32)
    with pytest.raises(ValueError, match=r"unknown mismatch parameter 'theta' \(known: dx, dy, theta_deg, a1, alpha_deg, blur_sigma_px"):
        cassi.Operator(mask, theta=0.3)
    with pytest.raises(ValueError, match="invalid parameter theta_deg = 46"):
        cassi.Operator(mask, theta_deg=46)
    with pytest.raises(ValueError, match="invalid parameter a1 = 0"):
        cassi.Operator(mask, mismatch={"a1": 0.0})
    with pytest.raises(ValueError, match="unknown dispersion model 'cubic'"):
        cassi.Operator(mask, model="cubic")
    with pytest.raises(ValueError, match=r"\|dx\| must be below the mask width"):
        cassi.Operator(mask, dx=9)
    with pytest.raises(ValueError, match="mask values span"):
        cassi.Operator(mask * 255)
    with pytest.raises(ValueError, match="unknown method 'mst-xl'"):
        cassi.reconstruct(np.ones((8, 10)), mask, bands=2, method="mst-xl")
    # a learned method: its weights (or, without the networks, a rebuild)
    with pytest.raises(ValueError, match="needs weights" if cassi.NETS_BUILT else "built without"):
        cassi.reconstruct(np.ones((8, 10)), mask, bands=2, method="mst-s")
    with pytest.raises(ValueError, match="unknown preset 'fast'"):
        cassi.calibrate(np.ones((8, 10)), mask, bands=2, preset="fast")


def test_meaningless_measurements_are_refused():
    mask = (np.arange(64).reshape(8, 8) % 3 == 0).astype(np.float32)
    with pytest.raises(ValueError, match="no light reached the detector"):
        cassi.reconstruct(np.zeros((8, 10)), mask, bands=2)
    with pytest.raises(ValueError, match="measurement rows has shape 7, expected 8"):
        cassi.reconstruct(np.ones((7, 10)), mask, bands=2)
    with pytest.raises(ValueError, match="no code to calibrate against"):
        cassi.calibrate(np.ones((8, 10)), np.ones((8, 8)), bands=2)


def test_a_panic_is_a_cassi_error_not_a_crash():
    with pytest.raises(cassi.CassiError, match="internal error.*deliberate test panic"):
        _cassi._panic_for_test()
