"""The one table type and the one finite-number check (core.tables, core.validate)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivetrain_ctrl.core.tables import PwlTable, TableError, TableTypeError, _pwl_clamped
from drivetrain_ctrl.core.validate import ParameterError, check_finite, real_number
from drivetrain_ctrl.plant import params


def test_one_table_class_and_one_error_family() -> None:
    assert params.Table is PwlTable
    assert params.ParameterError is ParameterError
    assert issubclass(TableError, ParameterError) and issubclass(TableError, ValueError)
    assert issubclass(TableTypeError, TableError) and issubclass(TableTypeError, TypeError)
    with pytest.raises(TableTypeError, match=r"pm\.x\[1\] = 'a': must be a finite number"):
        PwlTable((0.0, "a"), (1.0, 2.0), "pm")  # type: ignore[arg-type]
    with pytest.raises(TableError, match=r"pm\.symmetry = 'od': must be one of"):
        PwlTable((0.0,), (1.0,), "pm", symmetry="od")
    with pytest.raises(TableTypeError, match=r"pm\.x_unit = 3: must be a str"):
        PwlTable((0.0,), (1.0,), "pm", x_unit=3)  # type: ignore[arg-type]


def test_options_evaluate_and_the_kernel_form_is_for_clamped_tables_only() -> None:
    plain = PwlTable((0.0, 1.0, 2.0), (0.0, 10.0, 30.0), "k")
    odd = PwlTable((0.0, 1.0, 2.0), (0.0, 10.0, 30.0), "k", extrapolation="linear", symmetry="odd")
    even = PwlTable((0.0, 1.0, 2.0), (0.0, 10.0, 30.0), "k", symmetry="even")
    assert plain(3.0) == 30.0 and plain(-1.0) == 0.0
    assert odd(3.0) == 50.0 and odd(-3.0) == -50.0 and odd(-0.5) == -5.0
    assert even(-1.5) == even(1.5) == 20.0
    np.testing.assert_array_equal(plain(np.array([[0.5, 9.0]])), [[5.0, 30.0]])
    b, s, o = _pwl_clamped(plain)
    assert (
        (b, s, o)
        == plain.segments()
        == ([0.0, 1.0, 2.0], [0.0, 10.0, 20.0, 0.0], [0.0, 0.0, -10.0, 30.0])
    )
    with pytest.raises(TableError, match=r"k: the kernels evaluate clamped tables"):
        odd.segments()


@pytest.mark.parametrize(
    ("kw", "value", "exc", "match"),
    [
        ({}, "1", ValueError, r"^v = '1': must be a finite number$"),
        ({"type_error": TypeError}, True, TypeError, r"^v = True: must be a finite number$"),
        ({"type_error": TypeError}, math.nan, ValueError, r"^v = nan: must be a finite number$"),
        ({"lo": 0, "lo_open": True, "unit": "s"}, 0.0, ValueError, r"^v = 0.0: must be > 0 \[s\]$"),
        ({"lo": 1.0, "hi": 3.0, "hi_open": True}, 3.0, ValueError, r"must be >= 1.0 and < 3.0$"),
        ({"phrasing": "got", "type_error": TypeError}, "a", TypeError, "^v must be a real number"),
        ({"phrasing": "got"}, math.inf, ValueError, r"^v must be finite, got inf$"),
    ],
)
def test_real_number_names_the_field_and_value(
    kw: dict, value: object, exc: type, match: str
) -> None:
    with pytest.raises(exc, match=match):
        real_number("v", value, **kw)


def test_real_number_accepts_numpy_scalars_and_0d_arrays() -> None:
    assert real_number("v", np.float32(0.5)) == 0.5
    assert real_number("v", np.array(2)) == 2.0 and isinstance(real_number("v", 3), float)
    assert check_finite("el", "scale", 2.0, lo=0.0, strict=True) == 2.0
