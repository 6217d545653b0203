"""The Zeno guard: ``zeno_count`` events within ``zeno_window`` seconds stop the run, with
:class:`ZenoError` naming the time and the element, or a partial result with status 'zeno'."""

from __future__ import annotations

import functools
import re

import numpy as np
import pytest

from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import builtin_scenarios
from drivetrain_ctrl.sim.simulator import SimulationOptions, ZenoError, simulate

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
    # events located by the guards (those at input breakpoints are forced, not counted)
    bps = {b for s in sc.input_signals().values() for b in s.breakpoints}
    located = [i for i, e in enumerate(ref.events) if e.t not in bps]
    t_ev = np.array([ref.events[i].t for i in located])
    count, window = 5, 0.02
    hits = [k for k in range(count - 1, len(t_ev)) if t_ev[k] - t_ev[k - count + 1] < window]
    assert hits, "the rattle should contain a burst of 5 events within 20 ms"
    first = located[hits[0]]
    t_zeno = ref.events[first].t
    batch = [e for e in ref.events[first:] if e.t == t_zeno]  # decided together at t_zeno
    opts = SimulationOptions(zeno_count=count, zeno_window=window)
    with pytest.raises(ZenoError) as exc:
        simulate(dt.model, x0, sc.input_signals(), t_end=1.0, options=opts)
    m = ZENO_MSG.search(str(exc.value))
    assert m is not None, str(exc.value)
    assert float(m.group(1)) == pytest.approx(t_zeno, abs=1e-8)
    assert m.group(2) in {e.element for e in batch}
    part = simulate(dt.model, x0, sc.input_signals(), t_end=1.0, options=opts, raise_on_zeno=False)
    assert part.status == "zeno"
    assert part.events == ref.events[: first + len(batch)]
    assert part.t[-1] < 1.0


def _toggled_capacity_run(**opts: object):  # type: ignore[no-untyped-def]
    """Two-body clutch whose capacity input toggles 50 -> 0 -> 50 ... every 0.1 s (10 switches,
    each one an event at an input breakpoint: stuck -> open -> stuck ...)."""
    from drivetrain_ctrl.core import signals as sg
    from drivetrain_ctrl.plant.chain import two_body_clutch

    m = Model(two_body_clutch(0.2, 1.0, capacity="cap"))
    ts, vs = [0.0], [50.0]
    for k in range(1, 11):
        ts += [0.1 * k, 0.1 * k]
        vs += [vs[-1], 0.0 if k % 2 else 50.0]
    return simulate(
        m,
        [10.0, 10.0],
        {"torque1": 0.0, "cap": sg.table(ts, vs)},
        t_end=1.2,
        options=SimulationOptions(**opts),  # type: ignore[arg-type]
    )


def test_breakpoint_events_are_all_recorded() -> None:
    res = _toggled_capacity_run()
    assert res.status == "ok"
    assert [e.to_mode for e in res.events] == ["open", "stuck"] * 5
    np.testing.assert_allclose([e.t for e in res.events], 0.1 * np.arange(1, 11), atol=1e-12)


def test_max_events_is_enforced_for_breakpoint_events() -> None:
    """With max_events = 3 the run must either stop with status max_events (RuntimeError from
    simulate) or keep every event; it must not report 'ok' with events silently dropped."""
    try:
        res = _toggled_capacity_run(max_events=3)
    except RuntimeError as exc:
        assert "max_events" in str(exc)
        return
    series = res.mode_series("clutch")
    changes = sum(a != b for a, b in zip(series[:-1], series[1:], strict=True))
    assert len(res.events) == changes == 10


def test_relay_sliding_mode_is_a_real_zeno_case_at_default_settings() -> None:
    """A relay (torque -10 sgn(w) N m on body 1, w = omega1 - omega2) on two unit bodies joined by
    a unit spring, from w = 5 rad/s, q = 0: w' = -10 - 2 q, so w = 5 cos(r t) - (10 / r) sin(r t)
    with r = sqrt(2), zero at t* = atan(r / 2) / r = 0.4352 s. There the spring torque (2 q < 10)
    cannot hold the relay off: it switches ever faster (no stuck mode holds a controller's sign).
    With the default zeno_count / zeno_window the run ends there with a ZenoError naming the
    controller, within the milliseconds the switching takes to accumulate."""
    import control

    from drivetrain_ctrl.control.blocks import Controller
    from drivetrain_ctrl.core.signals import constant
    from drivetrain_ctrl.plant.chain import Spring

    ch = Chain(
        (Body("b1", 1.0, torque_input="torque"), Body("b2", 1.0)),
        (Coupling("s", spring=Spring.linear(1.0, name="s")),),
        inputs=("torque",),
    )
    c = Controller(
        lti=control.ss([], [], [], [[-10.0]]),
        measurement=((1.0, "ref"),),
        reference=constant(1.0),
        output="torque",
        sign_of=("omega_b1", "omega_b2"),
    )
    r = np.sqrt(2.0)
    t_star = float(np.arctan(r / 2.0) / r)
    with pytest.raises(ZenoError) as exc:
        simulate(Model(ch), np.array([5.0, 0.0, 0.0]), {}, t_end=2.0, controller=c)
    m = ZENO_MSG.search(str(exc.value))
    assert m is not None, str(exc.value)
    assert m.group(2) == "controller"
    assert t_star <= float(m.group(1)) < t_star + 1e-3


def test_guard_crossings_that_repeat_at_one_instant_stop_the_run(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A stall in ever shorter steps, with guard crossings that change no mode, is stopped by the
    Zeno guard at once, naming the element, not by ``max_steps`` much later. Reproduced with the
    bug fixed in 10044e2: a mu(slip) table with a bound at zero slip (each return to zero slip
    entered a region below 0 and left it at once)."""
    import drivetrain_ctrl.plant.model as model_mod
    from drivetrain_ctrl.core.tables import PwlTable
    from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction
    from drivetrain_ctrl.plant.model import Model

    orig = model_mod._pwl_clamped

    def with_a_bound_at_zero_slip(t: PwlTable) -> tuple[list[float], list[float], list[float]]:
        b, s, o = orig(t)  # the model drops the first bound: this restores it
        return [-1.0, *b], [0.0, *s], [o[0], *o]

    monkeypatch.setattr(model_mod, "_pwl_clamped", with_a_bound_at_zero_slip)
    mu = PwlTable((0.0, 1.0), (1.0, 0.5))
    ch = Chain(
        (Body("a", 1.0, torque_input="t"), Body("b", 2.0)),
        (Coupling("s", friction=Friction(scale=5.0, mu_table=mu, name="f")),),
        inputs=("t",),
    )
    model = Model(ch)
    monkeypatch.undo()
    opts = SimulationOptions(max_steps=200_000)  # without the guard: stops at max_steps
    with pytest.raises(ZenoError) as exc:
        simulate(model, np.zeros(2), {"t": 20.0}, t_end=0.5, options=opts)
    m = ZENO_MSG.search(str(exc.value))
    assert m is not None, str(exc.value)
    assert float(m.group(1)) < 1e-9  # at the break-away, t = 0
    assert m.group(2) == "f.mu_table"
    assert "guard crossings" in str(exc.value)
    part = simulate(model, np.zeros(2), {"t": 20.0}, t_end=0.5, options=opts, raise_on_zeno=False)
    assert part.status == "zeno" and part.stats["steps"] < 1000
