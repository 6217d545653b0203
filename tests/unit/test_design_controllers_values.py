"""Values of the design tools' shared PI/PID structure (:mod:`drivetrain_ctrl.design.controllers`)
and option handling (:mod:`drivetrain_ctrl.design.options`), against the formulas of their
docstrings written out here (issue 22 item 4: mutation testing)."""

from __future__ import annotations

import dataclasses

import control
import numpy as np
import pytest

from drivetrain_ctrl.design.controllers import (
    INTEGRATORS,
    check_integrator,
    integrator_response,
    pid_basis,
    pid_controller,
)
from drivetrain_ctrl.design.options import frequency_vector, spec_with_options

W = np.array([0.3, 1.0, 7.0, 40.0])  # rad/s


def _integrator(z: np.ndarray, dt: float, integrator: str) -> np.ndarray:
    """I(z) of the module docstring, written out."""
    if integrator == "forward":
        return dt / (z - 1.0)
    if integrator == "backward":
        return dt * z / (z - 1.0)
    return (dt / 2.0) * (z + 1.0) / (z - 1.0)


def _response(sys: control.TransferFunction, w: np.ndarray) -> np.ndarray:
    """The frequency response of a SISO transfer function at ``w`` [rad/s], from its
    coefficients (continuous: s = jw; discrete: z = exp(jw dt))."""
    num = np.asarray(sys.num[0][0], dtype=float)
    den = np.asarray(sys.den[0][0], dtype=float)
    x = 1j * w if sys.dt in (0, None) else np.exp(1j * w * sys.dt)
    return np.polyval(num, x) / np.polyval(den, x)


# --- controllers.py -----------------------------------------------------------------------------


def test_integrators_are_the_three_named() -> None:
    assert INTEGRATORS == ("forward", "backward", "tustin")
    for name in INTEGRATORS:
        assert check_integrator(name) == name
    with pytest.raises(ValueError, match=r"pid\.integrator = 'euler'"):
        check_integrator("euler", "pid.integrator")
    with pytest.raises(ValueError, match=r"^integrator = None"):
        check_integrator(None)


def test_integrator_response_continuous_is_one_over_jw() -> None:
    got = integrator_response(W, 0.0)
    np.testing.assert_allclose(got, 1.0 / (1j * W), rtol=1e-15)
    # a list is accepted as well
    np.testing.assert_allclose(integrator_response([2.0], 0.0), [-0.5j], rtol=1e-15)


@pytest.mark.parametrize("integrator", ["forward", "backward", "tustin"])
def test_integrator_response_discrete(integrator: str) -> None:
    dt = 0.01
    z = np.exp(1j * W * dt)
    got = integrator_response(W, dt, integrator)
    np.testing.assert_allclose(got, _integrator(z, dt, integrator), rtol=1e-13)


def test_integrator_response_default_is_forward() -> None:
    dt = 0.05
    z = np.exp(1j * W * dt)
    np.testing.assert_allclose(integrator_response(W, dt), dt / (z - 1.0), rtol=1e-13)


def test_pid_basis_continuous() -> None:
    nums, d = pid_basis("pi", 0.0, 0.0, "forward")
    np.testing.assert_array_equal(d, [1.0, 0.0])
    np.testing.assert_array_equal(nums[0], [1.0, 0.0])
    np.testing.assert_array_equal(nums[1], [0.0, 1.0])
    assert len(nums) == 2
    tf = 0.02
    nums, d = pid_basis("pid", 0.0, tf, "forward")
    # C = (kp s (tf s + 1) + ki (tf s + 1) + kd s^2) / (s (tf s + 1))
    np.testing.assert_allclose(d, [tf, 1.0, 0.0], rtol=0, atol=0)
    np.testing.assert_allclose(nums[0], [tf, 1.0, 0.0], rtol=0, atol=0)
    np.testing.assert_allclose(nums[1], [0.0, tf, 1.0], rtol=0, atol=0)
    np.testing.assert_allclose(nums[2], [1.0, 0.0, 0.0], rtol=0, atol=0)
    assert len(nums) == 3
    assert all(n.dtype == np.float64 for n in nums)


@pytest.mark.parametrize("integrator", ["forward", "backward", "tustin"])
def test_pid_basis_discrete(integrator: str) -> None:
    dt = 0.01
    inum = {"forward": [0.0, dt], "backward": [dt, 0.0], "tustin": [dt / 2, dt / 2]}[integrator]
    nums, d = pid_basis("pi", dt, 0.0, integrator)
    np.testing.assert_array_equal(d, [1.0, -1.0])
    np.testing.assert_array_equal(nums[0], [1.0, -1.0])
    np.testing.assert_allclose(nums[1], inum, rtol=1e-15, atol=0)
    tf = 0.03
    nums, d = pid_basis("pid", dt, tf, integrator)
    # (z - 1)((tf + dt) z - tf) = (tf + dt) z^2 - (2 tf + dt) z + tf
    np.testing.assert_allclose(d, [tf + dt, -(2 * tf + dt), tf], rtol=1e-15)
    np.testing.assert_allclose(nums[0], d, rtol=1e-15)
    a, b = inum
    np.testing.assert_allclose(
        nums[1], [a * (tf + dt), b * (tf + dt) - a * tf, -b * tf], rtol=1e-14, atol=1e-20
    )
    np.testing.assert_allclose(nums[2], [1.0, -2.0, 1.0], rtol=0, atol=0)
    assert [n.size for n in nums] == [3, 3, 3]


def test_pid_controller_continuous_pi_and_pid() -> None:
    kp, ki, kd, tf = 0.7, 2.5, 0.04, 0.01
    c = pid_controller(kp, ki)
    assert c.dt == 0
    np.testing.assert_allclose(_response(c, W), kp + ki / (1j * W), rtol=1e-13)
    np.testing.assert_allclose(c.num[0][0], [kp, ki], rtol=1e-15)
    np.testing.assert_allclose(c.den[0][0], [1.0, 0.0], rtol=0)
    c = pid_controller(kp, ki, kd, tf=tf)
    s = 1j * W
    np.testing.assert_allclose(_response(c, W), kp + ki / s + kd * s / (tf * s + 1.0), rtol=1e-12)
    # a PI ignores the filter time constant; tf = 0 is no error for it
    np.testing.assert_allclose(_response(pid_controller(kp, ki, tf=0.0), W), kp + ki / s)


@pytest.mark.parametrize("integrator", ["forward", "backward", "tustin"])
def test_pid_controller_discrete(integrator: str) -> None:
    kp, ki, kd, tf, dt = 0.7, 2.5, 0.04, 0.03, 0.01
    z = np.exp(1j * W * dt)
    c = pid_controller(kp, ki, dt=dt, integrator=integrator)
    assert c.dt == dt
    np.testing.assert_allclose(
        _response(c, W), kp + ki * _integrator(z, dt, integrator), rtol=1e-12
    )
    c = pid_controller(kp, ki, kd, tf=tf, dt=dt, integrator=integrator)
    want = kp + ki * _integrator(z, dt, integrator) + kd * (z - 1.0) / ((tf + dt) * z - tf)
    np.testing.assert_allclose(_response(c, W), want, rtol=1e-12)
    # a sampled PID without a filter (tf = 0) is a plain backward difference kd (z - 1)/(dt z)
    c = pid_controller(kp, ki, kd, dt=dt, integrator=integrator)
    want = kp + ki * _integrator(z, dt, integrator) + kd * (z - 1.0) / (dt * z)
    np.testing.assert_allclose(_response(c, W), want, rtol=1e-12)


def test_pid_controller_default_integrator_is_forward() -> None:
    dt = 0.02
    z = np.exp(1j * W * dt)
    c = pid_controller(1.0, 3.0, dt=dt)
    np.testing.assert_allclose(_response(c, W), 1.0 + 3.0 * dt / (z - 1.0), rtol=1e-12)


def test_pid_controller_static_gain_and_pure_integrator() -> None:
    c = pid_controller(1.5, 0.0)
    np.testing.assert_array_equal(c.num[0][0], [1.5])
    np.testing.assert_array_equal(c.den[0][0], [1.0])
    assert c.dt == 0
    c = pid_controller(1.5, 0.0, 0.0, dt=0.1)
    np.testing.assert_array_equal(c.num[0][0], [1.5])
    assert c.dt == 0.1
    # kp = 0: the leading zero of the numerator is trimmed, ki/s stays first order over s
    c = pid_controller(0.0, 2.0)
    np.testing.assert_array_equal(c.num[0][0], [2.0])
    np.testing.assert_array_equal(c.den[0][0], [1.0, 0.0])
    # a pure derivative (kp = ki = 0, kd != 0) is a PID
    c = pid_controller(0.0, 0.0, 0.5, tf=0.1)
    np.testing.assert_allclose(_response(c, W), 0.5 * 1j * W / (0.1j * W + 1.0), rtol=1e-12)


def test_pid_controller_input_errors() -> None:
    with pytest.raises(ValueError, match=r"tf = 0\.0: a continuous PID needs"):
        pid_controller(1.0, 1.0, 0.1)
    with pytest.raises(ValueError, match=r"tf = 0\.0: a continuous PID needs"):
        pid_controller(1.0, 0.0, 0.1, tf=0.0)
    with pytest.raises(ValueError, match=r"dt"):
        pid_controller(1.0, 1.0, dt=-0.1)
    with pytest.raises(ValueError, match=r"tf"):
        pid_controller(1.0, 1.0, 0.1, tf=-0.1)
    with pytest.raises(ValueError, match=r"integrator = 'trapezoid'"):
        pid_controller(1.0, 1.0, dt=0.1, integrator="trapezoid")
    with pytest.raises(ValueError, match=r"kp"):
        pid_controller(float("nan"), 1.0)
    with pytest.raises(ValueError, match=r"ki"):
        pid_controller(1.0, float("inf"))
    with pytest.raises(ValueError, match=r"kd"):
        pid_controller(1.0, 1.0, float("nan"))


# --- options.py ---------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _Spec:
    alpha: float = 1.0
    beta: str = "x"


@dataclasses.dataclass(frozen=True)
class _Other:
    alpha: float = 1.0


def test_spec_with_options_replaces_fields_of_the_given_spec() -> None:
    assert spec_with_options(_Spec, "tool", None, {}) == _Spec()
    assert spec_with_options(_Spec, "tool", None, {"alpha": 3.0}) == _Spec(alpha=3.0)
    base = _Spec(alpha=2.0, beta="y")
    assert spec_with_options(_Spec, "tool", base, {}) == base
    assert spec_with_options(_Spec, "tool", base, {"alpha": 5.0}) == _Spec(alpha=5.0, beta="y")


def test_spec_with_options_errors() -> None:
    with pytest.raises(TypeError, match=r"tool: spec = _Other\(alpha=1\.0\): must be a _Spec"):
        spec_with_options(_Spec, "tool", _Other(), {})
    with pytest.raises(ValueError, match=r"tool: unknown option alpah = 2; did you mean 'alpha'"):
        spec_with_options(_Spec, "tool", None, {"alpah": 2})
    with pytest.raises(
        ValueError, match=r"tool: unknown option zzz = 1; options: \['alpha', 'beta'\]$"
    ):
        spec_with_options(_Spec, "tool", _Spec(), {"zzz": 1})


def test_frequency_vector_accepts_a_valid_grid() -> None:
    got = frequency_vector("w", [0.5, 1.0, 2.5], 3)
    assert got == (0.5, 1.0, 2.5)
    assert all(type(x) is float for x in got)
    assert frequency_vector("w", np.array([1, 2]), 2) == (1.0, 2.0)
    # small positive frequencies and small steps are fine
    assert frequency_vector("w", [1e-3, 1.1e-3, 0.5], 1) == (1e-3, 1.1e-3, 0.5)


@pytest.mark.parametrize(
    "value, n, match",
    [
        ([[1.0, 2.0], [3.0, 4.0]], 2, "1-D grid of >= 2"),
        (3.0, 1, "1-D grid of >= 1"),
        ([1.0, 2.0], 3, "1-D grid of >= 3"),
        ([1.0, np.inf], 2, "finite, > 0"),
        ([1.0, np.nan, 3.0], 2, "finite, > 0"),
        ([0.0, 1.0], 2, "finite, > 0"),
        ([-1.0, 1.0], 2, "finite, > 0"),
        ([1.0, 1.0, 2.0], 2, "strictly increasing"),
        ([2.0, 1.0], 2, "strictly increasing"),
        ("abc", 1, "a 1-D grid \\[rad/s\\] is needed"),
        ([[1.0], [1.0, 2.0]], 1, "a 1-D grid \\[rad/s\\] is needed"),
        ({"a": 1}, 1, "a 1-D grid \\[rad/s\\] is needed"),
    ],
)
def test_frequency_vector_rejects(value: object, n: int, match: str) -> None:
    with pytest.raises(ValueError, match=r"^w_grid = ") as err:
        frequency_vector("w_grid", value, n)
    assert err.match(match)
