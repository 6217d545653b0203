"""The Zeno guard: ``zeno_count`` events within ``zeno_window`` seconds stop the run, with
:class:`ZenoError` naming the time and the element, or a partial result with status 'zeno'."""

from __future__ import annotations

import functools
import re

import numpy as np
import pytest

from drivetrain_ctrl.chain import Body, Chain, Coupling, Friction
from drivetrain_ctrl.model import Model
from drivetrain_ctrl.params import default_params
from drivetrain_ctrl.scenarios import builtin_scenarios
from drivetrain_ctrl.simulate import SimulationOptions, ZenoError, simulate

ZENO_MSG = re.compile(r"at t = ([0-9.eE+-]+) s on element '([^']+)'")


@functools.cache
def four_body() -> Model:
    """Four unit inertias, clutches (4, 5, 3) N m: from speeds (16, 13, 4, 0) they lock up at
    t = 1, 7/3 and 2.75 s (derivation in test_simulate_analytic.py)."""
    bodies = tuple(Body(f"b{i}", 1.0) for i in range(4))
    k = (4.0, 5.0, 3.0)
    cps = tuple(Coupling(f"c{i}", friction=Friction(scale=k[i], name=f"c{i}")) for i in range(3))
    return Model(Chain(bodies, cps))


X0 = (16.0, 13.0, 4.0, 0.0)


def test_zeno_error_names_time_and_element() -> None:
    """Three events within 2 s (1, 2.33, 2.75): the third one trips the guard."""
    opts = SimulationOptions(zeno_count=3, zeno_window=2.0)
    with pytest.raises(ZenoError) as exc:
        simulate(four_body(), X0, {}, t_end=4.0, options=opts)
    msg = str(exc.value)
    m = ZENO_MSG.search(msg)
    assert m is not None, msg
    assert float(m.group(1)) == pytest.approx(2.75, abs=1e-8)
    assert m.group(2) == "c2"
    assert "3 events" in msg


def test_zeno_partial_result() -> None:
    opts = SimulationOptions(zeno_count=3, zeno_window=2.0)
    res = simulate(four_body(), X0, {}, t_end=4.0, options=opts, raise_on_zeno=False)
    assert res.status == "zeno"
    assert [e.element for e in res.events] == ["c0", "c1", "c2"]
    assert res.events[-1].t == pytest.approx(2.75, abs=1e-9)
    # the run stopped at the event: nothing recorded past it
    assert res.t[-1] <= res.events[-1].t + 1e-12
    assert res.t[-1] < 4.0
    assert res.x.shape == (res.t.shape[0], 4)
    assert res.fm.shape[0] == res.t.shape[0]
    assert np.all(np.isfinite(res.x))


def test_window_just_too_short_lets_the_run_finish() -> None:
    """The first and third events are 1.75 s apart: a 1.5 s window is not tripped."""
    opts = SimulationOptions(zeno_count=3, zeno_window=1.5)
    res = simulate(four_body(), X0, {}, t_end=4.0, options=opts)
    assert res.status == "ok"
    assert len(res.events) == 3


def test_zeno_guard_on_backlash_rattle_of_tip_in() -> None:
    """The tip-in's backlash rattle is a burst of real events; a guard of 5 events within 20 ms
    must trip at the first fifth event that closes such a window, naming its element."""
    sc = builtin_scenarios()["tip-in"]
    dt = sc.drivetrain(default_params())
    x0 = sc.initial_state(dt)
    ref = simulate(dt.model, x0, sc.input_signals(), t_end=1.0)
    t_ev = np.array([e.t for e in ref.events])
    count, window = 5, 0.02
    hits = [i for i in range(count - 1, len(t_ev)) if t_ev[i] - t_ev[i - count + 1] < window]
    assert hits, "the rattle should contain a burst of 5 events within 20 ms"
    first = hits[0]
    opts = SimulationOptions(zeno_count=count, zeno_window=window)
    with pytest.raises(ZenoError) as exc:
        simulate(dt.model, x0, sc.input_signals(), t_end=1.0, options=opts)
    m = ZENO_MSG.search(str(exc.value))
    assert m is not None, str(exc.value)
    assert float(m.group(1)) == pytest.approx(t_ev[first], abs=1e-8)
    assert m.group(2) == ref.events[first].element
    part = simulate(
        dt.model, x0, sc.input_signals(), t_end=1.0, options=opts, raise_on_zeno=False
    )
    assert part.status == "zeno"
    assert len(part.events) == first + 1
    assert part.t[-1] < 1.0
