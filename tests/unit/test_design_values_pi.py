"""Value tests of design/pi.py (issue 22 item 4: mutation score of the design modules): the Ms
bound's acceptance tolerance (0.1 %) against a peak of |S| computed here, and the stability
screen at a pole exactly on the stability boundary."""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from drivetrain_ctrl.design.pi import _stable_mask, design_pi
from drivetrain_ctrl.design.plants import Plant

s = control.tf("s")


def _peak_sensitivity(kp: float, ki: float) -> float:
    """max |1/(1 + L)| of L = (kp + ki/(j w)) / (j w + 1)^3: a dense scan refined by Brent."""

    def S(w: float) -> float:
        return float(abs(1.0 / (1.0 + (kp + ki / (1j * w)) / (1j * w + 1.0) ** 3)))

    w = np.logspace(-3, 2, 20001)
    k = int(np.argmax([S(x) for x in w]))
    r = minimize_scalar(
        lambda x: -S(x), bounds=(w[max(k - 2, 0)], w[k + 2]), method="bounded",
        options={"xatol": 1e-12},
    )  # fmt: skip
    return float(-r.fun)


@pytest.mark.parametrize(("excess", "feasible"), [(1.0015, False), (1.0005, True)])
def test_an_ms_bound_is_met_to_one_per_mille(excess: float, feasible: bool) -> None:
    """1/(s + 1)^3 at wc = 0.5 rad/s, PM 50 deg: the closed-form PI's peak |S| is Ms (computed
    here). With the bound ms = Ms / 1.0015 the design is reported infeasible (Ms exceeds it by
    more than the 0.1 % tolerance); with Ms / 1.0005 it is accepted."""
    P = 1 / (s + 1) ** 3
    ref = design_pi(P, wc=0.5, phase_margin=50.0)
    Ms = _peak_sensitivity(ref.kp, ref.ki)
    assert ref.ms == pytest.approx(Ms, rel=1e-5)
    d = design_pi(P, wc=0.5, phase_margin=50.0, ms=Ms / excess)
    assert (d.kp, d.ki) == (ref.kp, ref.ki)
    assert d.feasible is feasible
    assert ("exceeds the bound" in d.message) is not feasible


def test_the_stability_screen_rejects_a_pole_on_the_boundary() -> None:
    """kp = ki = 0: the integrator's pole stays at z = 1 (discrete) or s = 0 (continuous), on
    the stability boundary: not stable, whatever the (stable) plant. A small PI is stable."""
    Pd = Plant(control.c2d(1 / (s + 1), 0.1))
    zero = np.array([0.0])
    assert _stable_mask(Pd, zero, zero, "forward", 5).tolist() == [False]
    assert _stable_mask(Plant(1 / (s + 1)), zero, zero, "continuous", 5).tolist() == [False]
    small = np.array([0.1])
    assert _stable_mask(Pd, small, small, "forward", 5).tolist() == [True]
    assert _stable_mask(Plant(1 / (s + 1)), small, small, "continuous", 5).tolist() == [True]


@pytest.mark.parametrize(("offset", "hint"), [(0.5e-10, True), (3e-10, False)])
def test_a_pole_near_z_1_is_an_integrator_only_within_the_tolerance(
    offset: float, hint: bool
) -> None:
    """-0.01 / (z - 1 - e), Ts = 0.01 s: a PI with positive gains fails on it (negative gain
    above the lowest frequencies). The low-frequency sign divides out roots at z = 1 up to
    |c(1)| <= 1e-10 sum|c| (here 2e-10): for e = 0.5e-10 the pole counts as an integrator, the
    gain with it divided out is -0.01 < 0 and the message hints at the sign; for e = 3e-10 it
    does not, the gain at z = 1 is -0.01 / (-3e-10) > 0 and there is no such hint."""
    d = design_pi(control.tf([-0.01], [1.0, -(1.0 + offset)], 0.01), wc=1.0, phase_margin=60.0)
    assert not d.feasible
    assert ("low-frequency gain is negative" in d.message) is hint
