"""Tests of drivetrain_ctrl.units (SI constants and edge conversions)."""

import math

import numpy as np
import pytest

from drivetrain_ctrl.core import units


def test_gravity_is_the_rounded_value() -> None:
    assert units.GRAVITY == 9.81


@pytest.mark.parametrize(
    ("func", "value", "expected"),
    [
        (units.rpm_to_rad_s, 60.0, 2.0 * math.pi),
        (units.rpm_to_rad_s, 1600.0, 1600.0 * math.pi / 30.0),
        (units.rad_s_to_rpm, math.pi, 30.0),
        (units.kmh_to_m_s, 36.0, 10.0),
        (units.m_s_to_kmh, 10.0, 36.0),
    ],
)
def test_scalar_conversions(func, value, expected) -> None:
    out = func(value)
    assert isinstance(out, float)
    assert out == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize(
    ("forward", "backward"),
    [(units.rpm_to_rad_s, units.rad_s_to_rpm), (units.kmh_to_m_s, units.m_s_to_kmh)],
)
def test_array_round_trip(forward, backward) -> None:
    x = np.array([[-1000.0, 0.0], [800.0, 6500.0]])
    y = forward(x)
    assert isinstance(y, np.ndarray) and y.shape == x.shape
    np.testing.assert_allclose(backward(y), x, rtol=1e-14)
    assert y is not x  # a new array, the input is not modified
    np.testing.assert_array_equal(x, [[-1000.0, 0.0], [800.0, 6500.0]])


def test_list_and_numpy_scalar_inputs() -> None:
    out = units.kmh_to_m_s([0.0, 3.6, 72.0])
    assert isinstance(out, np.ndarray)
    np.testing.assert_allclose(out, [0.0, 1.0, 20.0])
    assert isinstance(units.rpm_to_rad_s(np.float64(30.0)), float)
    assert units.rpm_to_rad_s(np.float64(30.0)) == pytest.approx(math.pi)
    assert units.rad_s_to_rpm(np.array(math.pi)) == pytest.approx(30.0)


def test_conversion_constants() -> None:
    assert units.RPM_TO_RAD_S == pytest.approx(2.0 * math.pi / 60.0)
    assert units.KMH_TO_M_S * 3.6 == pytest.approx(1.0)
