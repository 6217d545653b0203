"""Value tests of drivetrain_ctrl.core.units: every constant and conversion against numbers
derived by hand (1 rev = 2 pi rad, 1 min = 60 s, 1 km/h = 1000 m / 3600 s), and the scalar /
array dispatch (a scalar of any kind gives a Python float, an array of any shape an array)."""

import math

import numpy as np
import pytest

from drivetrain_ctrl.core import units


def test_constants_by_hand() -> None:
    assert units.GRAVITY == 9.81
    assert units.RPM_TO_RAD_S == pytest.approx(2.0 * math.pi / 60.0, rel=1e-15)
    assert units.RAD_S_TO_RPM == pytest.approx(60.0 / (2.0 * math.pi), rel=1e-15)
    assert units.KMH_TO_M_S == pytest.approx(1000.0 / 3600.0, rel=1e-15)
    assert units.M_S_TO_KMH == pytest.approx(3600.0 / 1000.0, rel=1e-15)
    # 3000 rpm = 50 rev/s = 100 pi rad/s; 90 km/h = 25 m/s
    assert 3000.0 * units.RPM_TO_RAD_S == pytest.approx(100.0 * math.pi, rel=1e-15)
    assert 100.0 * math.pi * units.RAD_S_TO_RPM == pytest.approx(3000.0, rel=1e-15)
    assert 90.0 * units.KMH_TO_M_S == pytest.approx(25.0, rel=1e-15)
    assert 25.0 * units.M_S_TO_KMH == pytest.approx(90.0, rel=1e-15)


SCALARS = [
    (units.rpm_to_rad_s, 3000.0, 100.0 * math.pi),
    (units.rad_s_to_rpm, 100.0 * math.pi, 3000.0),
    (units.kmh_to_m_s, 90.0, 25.0),
    (units.m_s_to_kmh, 25.0, 90.0),
]


@pytest.mark.parametrize(("func", "value", "expected"), SCALARS)
def test_every_scalar_kind_gives_a_float(func, value, expected) -> None:
    for x in (value, np.float64(value), np.float32(value), np.array(value)):
        out = func(x)
        assert type(out) is float, (func.__name__, type(x))
        assert out == pytest.approx(expected, rel=1e-6 if isinstance(x, np.float32) else 1e-15)
    # an int (a Python int and a NumPy integer)
    assert type(func(3)) is float
    assert type(func(np.int64(3))) is float
    assert func(np.int64(3)) == pytest.approx(expected * 3.0 / value, rel=1e-15)


@pytest.mark.parametrize(("func", "value", "expected"), SCALARS)
def test_arrays_of_every_shape_give_arrays(func, value, expected) -> None:
    for shape in ((1,), (3,), (2, 2)):
        x = np.full(shape, value)
        out = func(x)
        assert isinstance(out, np.ndarray) and out.dtype == np.float64 and out.shape == shape
        np.testing.assert_allclose(out, expected, rtol=1e-15)
    out = func([value, -value, 0.0])
    np.testing.assert_allclose(out, [expected, -expected, 0.0], rtol=1e-15)
    # an integer array is converted to float64 (no integer division or truncation)
    out = func(np.array([3, 7], dtype=np.int64))
    assert out.dtype == np.float64
    np.testing.assert_allclose(out, np.array([3.0, 7.0]) * expected / value, rtol=1e-15)


def test_negative_and_zero_values() -> None:
    assert units.rpm_to_rad_s(-60.0) == pytest.approx(-2.0 * math.pi, rel=1e-15)
    assert units.kmh_to_m_s(-3.6) == pytest.approx(-1.0, rel=1e-15)
    assert units.rad_s_to_rpm(0.0) == 0.0
    assert units.m_s_to_kmh(0.0) == 0.0
