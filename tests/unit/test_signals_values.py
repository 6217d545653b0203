"""Value tests of drivetrain_ctrl.core.signals (issue 22 item 4), each against a hand-written
case (``./dev mutate drivetrain_ctrl/core/signals.py``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivetrain_ctrl.core.signals import sine, step


def test_a_sine_signal_has_one_knot_at_zero() -> None:
    s = sine(2.0, 3.0, phase=0.5, t_start=0.25)
    assert s.times == (0.0,) and s.values == (0.0,)
    assert s.breakpoints == (0.0, 0.25)
    assert s.to_dict() == {
        "times": [0.0],
        "values": [0.0],
        "sines": [{"amplitude": 2.0, "omega": 3.0, "phase": 0.5, "t_start": 0.25}],
    }
    assert float(s(1.0)) == pytest.approx(2.0 * math.sin(3.0 * 0.75 + 0.5), rel=1e-15)


def test_extremes_of_a_slow_sine_are_taken_on_the_100_point_grid() -> None:
    # 40 points per period would be 40 * 3 / (2 pi) = 19 points on [0, 3]: at least 100 are used
    s = sine(1.0, 1.0)
    (vmin, tmin), (vmax, tmax) = s.extremes(0.0, 3.0)
    grid = np.linspace(0.0, 3.0, 100)
    k = int(np.argmax(np.sin(grid)))
    assert vmax == pytest.approx(math.sin(grid[k]), rel=1e-15) and tmax == grid[k]
    assert (vmin, tmin) == (0.0, 0.0)


def test_extremes_with_a_step_and_a_sine_count_both_sides_of_the_jump() -> None:
    s = step(1.0, -5.0, initial=2.0) + sine(0.1, 100.0)
    (vmin, tmin), (vmax, tmax) = s.extremes(0.0, 2.0)
    assert tmax <= 1.0 and vmax == pytest.approx(2.1, abs=1e-3)
    assert tmin >= 1.0 and vmin == pytest.approx(-3.1, abs=1e-3)
