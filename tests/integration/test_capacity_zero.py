"""A friction capacity through zero is an event from every mode, and the second-law check.

Issue 19, item 1 and 2: a slipping element whose capacity input goes negative inside a smooth
stretch of its signal must open at the crossing (no torque), a stuck one likewise, and both close
again when the capacity is positive; an element that supplies energy trips the second-law check.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from drivetrain_ctrl import signals as sg
from drivetrain_ctrl.core.tables import PwlTable
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.sim.simulator import (
    SecondLawError,
    SimulationOptions,
    simulate,
)


def _pair(friction: Friction, *, torque: bool = False) -> Model:
    a = Body("a", 1.0, torque_input="T") if torque else Body("a", 1.0)
    inputs = ("fn", "T") if torque else ("fn",)
    return Model(
        Chain(
            bodies=(a, Body("b", 1.0)), couplings=(Coupling("c", friction=friction),), inputs=inputs
        )
    )


def _events(res, element="c"):
    return [(e.t, e.from_mode, e.to_mode) for e in res.events if e.element == element]


def _run(model, x0, inputs, t_end, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no second-law warning, nothing else either
        return simulate(model, np.array(x0, dtype=float), inputs, t_end=t_end, **kw)


def test_issue_reproducer_slipping_clutch_opens_at_the_crossing():
    """The issue's reproducer: capacity sin(t) while slipping; it opens at t = pi, exactly, and
    from then on transmits nothing (speeds and the dissipated energy stay constant)."""
    m = _pair(Friction(capacity_input="fn", name="c"))
    res = _run(m, [10.0, 0.0], {"fn": sg.sine(1.0, 1.0)}, 4.0)
    ev = _events(res)
    assert [(a, b) for _, a, b in ev] == [("open", "slip+"), ("slip+", "open")]
    assert abs(ev[1][0] - math.pi) < 1e-9
    # slip phase: each body gets +-sin(t); the slip speed falls by 2 (1 - cos t) = 4 at t = pi
    assert np.allclose(res.x[-1], [8.0, 2.0], atol=1e-7)
    after = res.t > math.pi + 1e-6
    assert np.ptp(res.x[after, 0]) < 1e-12 and np.ptp(res.dissipated[after, -1]) < 1e-12
    # dissipated energy = integral of sin(t) * w(t), w = 10 - 2 (1 - cos t): 20 - 4 = 16 J
    assert res.dissipated[-1, -1] == pytest.approx(16.0, rel=1e-8)
    assert res.energy_residual_rel < 1e-10
    assert res.stats["dissipation_min_W"] >= -1e-9
    assert set(res.mode_series("c")[int(np.argmax(after)) :]) == {"open"}


def test_slipping_backwards_opens_and_closes_again_in_the_direction_of_slip():
    m = _pair(Friction(capacity_input="fn", name="c"))
    res = _run(m, [0.0, 10.0], {"fn": sg.sine(1.0, 1.0)}, 7.0)
    ev = _events(res)
    assert [(a, b) for _, a, b in ev] == [("open", "slip-"), ("slip-", "open"), ("open", "slip-")]
    assert abs(ev[1][0] - math.pi) < 1e-9 and abs(ev[2][0] - 2 * math.pi) < 1e-9
    # open over [pi, 2 pi]: no torque, the speeds hold
    k = (res.t > math.pi + 1e-6) & (res.t < 2 * math.pi - 1e-6)
    assert np.ptp(res.x[k, 0]) < 1e-12
    assert res.stats["dissipation_min_W"] >= -1e-9


def test_stuck_clutch_opens_at_the_crossing_and_sticks_again():
    """Stuck with a torque across it: static guard; at the capacity's zero it opens, and when
    the capacity is positive again with the slip still small it slips, then sticks."""
    m = _pair(Friction(capacity_input="fn", name="c"), torque=True)
    # capacity 1 + 2 sin(t): negative on (7 pi/6, 11 pi/6); torque 0.2 N m on body a
    res = _run(
        m, [5.0, 5.0], {"fn": sg.constant(1.0) + sg.sine(2.0, 1.0), "T": sg.constant(0.2)}, 8.0
    )
    assert res.mode_series("c")[0] == "stuck"
    ev = _events(res)
    modes = [(a, b) for _, a, b in ev]
    # stuck while the capacity holds 0.1 N m (half the torque, shared by equal inertias):
    # 1 + 2 sin t >= 0.1 until sin t = -0.45
    t_break = math.pi + math.asin(0.45)
    assert modes[0] == ("stuck", "slip+") and abs(ev[0][0] - t_break) < 1e-8
    assert modes[1] == ("slip+", "open") and modes[2] == ("open", "slip+")
    assert modes[3] == ("slip+", "stuck")
    t_open = next(t for t, a, b in ev if (a, b) == ("slip+", "open"))
    assert abs(t_open - (math.pi + math.asin(0.5))) < 1e-8
    t_close = next(t for t, a, b in ev if a == "open")
    assert abs(t_close - (2 * math.pi - math.asin(0.5))) < 1e-8
    # while open, a accelerates at 0.2 and b holds its speed
    k = (res.t > t_open + 1e-6) & (res.t < t_close - 1e-6)
    assert np.allclose(np.diff(res.x[k, 1]), 0.0, atol=1e-12)
    assert res.stats["dissipation_min_W"] >= -1e-9
    assert res.energy_residual_rel < 1e-9


def test_capacity_table_of_an_input_through_zero():
    """A capacity table that maps the input to a negative value (not clamped at 0 by the
    user): the element opens where the table crosses 0 and closes where it comes back."""
    tab = PwlTable(x=(0.0, 1.0), y=(-1.0, 1.0))  # capacity 2 v - 1 on [0, 1]
    m = _pair(Friction(capacity_input="fn", capacity_table=tab, name="c"))
    # input 1 -> 0 over [0, 2] s, then back to 1 over [2, 4] s: capacity 0 at t = 1 and t = 3
    res = _run(m, [20.0, 0.0], {"fn": sg.table([0.0, 2.0, 4.0], [1.0, 0.0, 1.0])}, 4.0)
    ev = _events(res)
    assert res.mode_series("c")[0] == "slip+"
    assert [(a, b) for _, a, b in ev] == [("slip+", "open"), ("open", "slip+")]
    assert abs(ev[0][0] - 1.0) < 1e-9 and abs(ev[1][0] - 3.0) < 1e-9
    assert res.stats["dissipation_min_W"] >= -1e-9


def test_second_law_check_names_element_and_time():
    """A body with negative viscous friction (impossible through the validated API: patched
    into the model's arrays) supplies energy; the check warns, raises or stays silent."""
    m = Model(Chain(bodies=(Body("a", 1.0, viscous=0.1),), couplings=()))
    object.__setattr__(m, "data", m.data._replace(visc=-m.data.visc))  # Model is immutable
    with pytest.warns(
        RuntimeWarning, match=r"second law violated: element 'a.ground' .* at t = 1 s"
    ):
        res = simulate(m, np.array([1.0]), {}, t_end=1.0)
    # p = c w^2 with w = e^{0.1 t}: most negative at the end, -0.1 e^{0.2} W
    assert res.stats["dissipation_min_W"] == pytest.approx(-0.1 * math.exp(0.2), rel=1e-6)
    with pytest.raises(SecondLawError, match="'a.ground'"):
        simulate(m, np.array([1.0]), {}, t_end=1.0, options=SimulationOptions(second_law="raise"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulate(m, np.array([1.0]), {}, t_end=1.0, options=SimulationOptions(second_law="ignore"))


def test_second_law_option_is_checked():
    with pytest.raises(ValueError, match="second_law = 'loud'"):
        SimulationOptions(second_law="loud")
