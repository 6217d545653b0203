"""Value tests of design/hinf.py (issue 22 item 4: mutation score of the design modules): the
reference frequency w_ref of the module docstring (bandwidth, prewarped for a sampled set; else
where |W1| falls to 1; else the log-middle of the nominal plant's grid), and the axis-pole shift
of a static system."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from drivetrain_ctrl.design.hinf import (
    HinfSpec,
    _reference_frequency,
    _unity_crossing,
    shift_axis_poles,
)
from drivetrain_ctrl.design.plants import Plant, frequency_grid

s = control.tf("s")


def test_unity_crossing_of_a_first_order_weight() -> None:
    """|10/(j w + 1)| = 1 at w = sqrt(99); on the 2000-point log grid from 0.01 to 1000 rad/s
    the crossing is reported at the grid point at or just below it (one step is a factor
    10^(5/1999)). A weight below 1 everywhere has no crossing."""
    w = _unity_crossing(control.ss(10 / (s + 1)), 0.01, 1000.0)
    step = 10 ** (5 / 1999)
    assert w is not None and math.sqrt(99) / step < w <= math.sqrt(99)
    assert _unity_crossing(control.ss(0.5 / (s + 1)), 0.01, 1000.0) is None
    # |0.1 (s + 1)| rises through 1 at sqrt(99) too
    up = _unity_crossing(control.ss(control.tf([0.1, 0.1], [1e-6, 1.0])), 0.01, 1000.0)
    assert up is not None and math.sqrt(99) / step < up <= math.sqrt(99) * step


def test_reference_frequency_rules() -> None:
    nom = Plant(1 / ((s + 1) * (0.1 * s + 1)))
    # 1. the bandwidth
    assert _reference_frequency(HinfSpec(bandwidth=3.0), nom, 0.0) == 3.0
    # ... prewarped for a sampled set: 2/dt tan(w dt/2)
    dt = 0.05
    got = _reference_frequency(HinfSpec(bandwidth=3.0), nom, dt)
    assert got == pytest.approx(2 / dt * math.tan(3.0 * dt / 2), rel=1e-14)
    with pytest.raises(ValueError, match="must be below the Nyquist frequency"):
        _reference_frequency(HinfSpec(bandwidth=math.pi / dt), nom, dt)
    # 2. where |W1| falls to 1 (W1 = (s/2 + 5)/(s + 0.05): |W1| = 1 at w^2 = (25 - 0.0025)/0.75)
    W1 = (s / 2 + 5) / (s + 0.05)
    w1 = math.sqrt((25 - 0.0025) / 0.75)
    got = _reference_frequency(HinfSpec(W1=W1), nom, 0.0)
    g0 = frequency_grid(nom, n=50)
    step = (g0[-1] * 100 / (g0[0] / 100)) ** (1 / 1999)
    assert w1 / step < got <= w1
    # 3. no bandwidth, W1 never reaching 1 (or no W1): the log-middle of the plant's grid
    mid = math.sqrt(g0[0] * g0[-1])
    assert _reference_frequency(HinfSpec(W2=control.tf([0.1], [1.0])), nom, 0.0) == pytest.approx(
        mid, rel=1e-14
    )
    assert _reference_frequency(
        HinfSpec(W1=control.tf([0.5], [1.0, 1.0])), nom, 0.0
    ) == pytest.approx(mid, rel=1e-14)
    # ... warped for a sampled set, 2/dt tan(min(mid dt/2, 1.4))
    nd = Plant(control.c2d(1 / ((s + 1) * (0.1 * s + 1)), dt))
    gd = frequency_grid(nd, n=50)
    midd = math.sqrt(gd[0] * gd[-1])
    want = 2 / dt * math.tan(min(midd * dt / 2, 1.4))
    assert _reference_frequency(HinfSpec(W2=control.tf([0.1], [1.0])), nd, dt) == pytest.approx(
        want, rel=1e-14
    )


def test_shift_axis_poles_of_a_static_system() -> None:
    """No states: nothing to shift, the system itself and 0 poles moved."""
    G, k = shift_axis_poles(control.ss([], [], [], [[2.5]]), 0.1)
    assert k == 0 and G.nstates == 0 and float(np.asarray(G.D)[0, 0]) == 2.5
