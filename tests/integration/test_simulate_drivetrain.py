"""Simulation of the drivetrain: built-in scenarios, locked clutch vs merged inertia, and the
compiled kernel against the flat reference model (:mod:`drivetrain_ctrl.reference`) integrated
independently with scipy between our event times."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from drivetrain_ctrl.plant.chain import Body, Chain
from drivetrain_ctrl.plant.drivetrain import Drivetrain
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import Scenario, builtin_scenarios
from drivetrain_ctrl.sim.simulator import SimulationOptions, SimulationResult, simulate
from drivetrain_ctrl.testing.reference import full_reference_rhs

SCENARIOS = ("engage-ramp", "tip-in")
TIGHT = SimulationOptions(rtol=1e-11, atol=1e-12)


@functools.cache
def scenario(name: str) -> Scenario:
    return builtin_scenarios()[name]


@functools.cache
def drivetrain(name: str, kind: str = "full") -> Drivetrain:
    return scenario(name).drivetrain(default_params(), kind=kind)


@functools.cache
def run(
    name: str, kind: str = "full", options: SimulationOptions | None = None
) -> SimulationResult:
    sc = scenario(name)
    dt = drivetrain(name, kind)
    return simulate(
        dt.model, sc.initial_state(dt), sc.input_signals(), t_end=sc.t_end, options=options
    )


# ------------------------------------------------------------------------------------------------
# built-in scenarios: status, energy balance, lock-up
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["full", "reduced"])
@pytest.mark.parametrize("name", SCENARIOS)
def test_builtin_scenario_ok_and_energy_balanced(name: str, kind: str) -> None:
    res = run(name, kind)
    assert res.status == "ok"
    # every mode decision found a consistent combination (no guard re-fired after a decision)
    assert res.stats["inconsistent_decisions"] == 0
    assert res.t[-1] == scenario(name).t_end
    assert np.all(np.diff(res.t) >= 0.0)
    assert np.all(np.isfinite(res.x))
    assert res.energy_residual_rel <= 1e-6
    # the work supplied is not negligible (the residual is relative to a real scale)
    assert abs(res.work_in[-1]) > 100.0


@pytest.mark.parametrize("kind", ["full", "reduced"])
def test_engage_ramp_locks_up(kind: str) -> None:
    res = run("engage-ramp", kind)
    t_lock = res.lockup_time()
    assert t_lock is not None
    assert 1.0 < t_lock < 3.0
    series = res.mode_series("clutch")
    assert series[0] == "open" and series[-1] == "stuck"
    # engine and disc turn together after lock-up; before it the engine is faster
    after = res.t > t_lock
    we, wd = (
        res.state("omega_engine"),
        res.state("omega_disc" if kind == "full" else "omega_primary"),
    )
    np.testing.assert_allclose(we[after], wd[after], rtol=1e-12, atol=1e-9)
    slip = (res.t > 0.25) & (res.t < t_lock - 1e-3)
    assert np.all(we[slip] > wd[slip])
    # the clutch engages at 0.2 s (pedal ramp start: capacity leaves 0)
    first = next(e for e in res.events if e.element == "clutch")
    assert (first.from_mode, first.to_mode) == ("open", "slip+")
    assert first.t == pytest.approx(0.2, abs=1e-12)


def test_tip_in_keeps_clutch_locked_and_crosses_the_backlash() -> None:
    res = run("tip-in")
    assert set(res.mode_series("clutch")) == {"stuck"}
    assert res.lockup_time() is None  # stuck from the start: no lock-up event
    bl = res.mode_series("backlash")
    assert bl[0] == "contact-" and bl[-1] == "contact+"
    ev = [e for e in res.events if e.element == "backlash"]
    assert ev[0].from_mode == "contact-" and ev[0].t > 0.5


def test_self_convergence_of_the_event_times() -> None:
    """Default tolerances vs rtol 1e-11: same event sequence, event times and end state close."""
    a, b = run("tip-in"), run("tip-in", "full", TIGHT)
    seq = [(e.element, e.from_mode, e.to_mode) for e in a.events]
    assert seq == [(e.element, e.from_mode, e.to_mode) for e in b.events]
    ta = np.array([e.t for e in a.events])
    tb = np.array([e.t for e in b.events])
    assert np.max(np.abs(ta - tb)) < 1e-5
    scale = np.maximum(1.0, np.abs(b.x[-1]))
    assert np.max(np.abs(a.x[-1] - b.x[-1]) / scale) < 1e-5


# ------------------------------------------------------------------------------------------------
# locked clutch == engine and disc merged into one body
# ------------------------------------------------------------------------------------------------


def merged_engine_disc(model: Model) -> Model:
    """The full chain with engine and disc merged into one body (clutch coupling removed)."""
    ch = model.chain
    eng, disc = ch.bodies[0], ch.bodies[1]
    assert (eng.name, disc.name, ch.couplings[0].name) == ("engine", "disc", "clutch")
    merged = Body(
        "engine",
        eng.inertia + disc.inertia,
        viscous=eng.viscous + disc.viscous,
        ground_friction=eng.ground_friction,
    )
    return Model(Chain((merged, *ch.bodies[2:]), ch.couplings[1:], ch.sources, ch.inputs))


def test_locked_clutch_equals_merged_engine_and_disc() -> None:
    sc = scenario("tip-in")
    dt = drivetrain("tip-in")
    mm = merged_engine_disc(dt.model)
    idx = [dt.model.state_index(n) for n in mm.state_names]
    x0 = sc.initial_state(dt)
    r1 = simulate(dt.model, x0, sc.input_signals(), t_end=1.5, options=TIGHT)
    r2 = simulate(mm, x0[idx], sc.input_signals(), t_end=1.5, options=TIGHT)
    assert set(r1.mode_series("clutch")) == {"stuck"}
    np.testing.assert_allclose(r1.state("omega_engine"), r1.state("omega_disc"), rtol=1e-13)
    # same events (the merged model has no clutch element)
    ev1 = [(e.element, e.from_mode, e.to_mode) for e in r1.events]
    ev2 = [(e.element, e.from_mode, e.to_mode) for e in r2.events]
    assert ev1 == ev2 and len(ev1) > 5
    t1 = np.array([e.t for e in r1.events])
    t2 = np.array([e.t for e in r2.events])
    np.testing.assert_allclose(t1, t2, rtol=0.0, atol=1e-7)
    # the states just after each event and at the end agree
    scale = np.maximum(1.0, np.abs(r2.x).max(axis=0))
    for ta, tb in [*zip(t1, t2, strict=True), (1.5, 1.5)]:
        i1 = np.flatnonzero(r1.t == ta)[-1]
        i2 = np.flatnonzero(r2.t == tb)[-1]
        err = np.abs(r1.x[i1, idx] - r2.x[i2]) / scale
        assert np.max(err) < 1e-6, (ta, dict(zip(mm.state_names, err, strict=True)))


# ------------------------------------------------------------------------------------------------
# compiled kernel vs flat reference model, integrated independently between our events
# ------------------------------------------------------------------------------------------------


def reference_check(name: str, t_a: float, t_b: float) -> tuple[int, float]:
    """Restart a DOP853 integration of :func:`full_reference_rhs` at our state after every event
    (and input breakpoint) in ``[t_a, t_b]``, in the mode our simulator chose there, and compare
    at all our samples up to the next event. Returns (intervals, worst scaled error)."""
    sc = scenario(name)
    dt = drivetrain(name)
    m = dt.model
    p = default_params()
    sigs = sc.input_signals()
    res = simulate(m, sc.initial_state(dt), sigs, t_end=t_b, options=TIGHT)
    sig_list = [sigs[n] for n in m.input_names]
    bps = {b for s in sig_list for b in s.breakpoints}
    cuts = sorted(t for t in {e.t for e in res.events} | bps if t_a < t < t_b)
    bounds = [t_a, *cuts, t_b]
    worst = 0.0
    n_int = 0
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        ia = int(np.searchsorted(res.t, a, side="right")) - 1  # last sample at a (post event)
        ib = int(np.searchsorted(res.t, b, side="left"))  # first sample at b
        assert ia < ib
        assert np.all(res.fm[ia:ib] == res.fm[ia]), "mode changed without an event"
        modes = {fi.name: fi.mode_names[c] for fi, c in zip(m.frictions, res.fm[ia], strict=True)}

        def f(t: float, x: np.ndarray, modes: dict[str, str] = modes) -> np.ndarray:
            u = np.array([float(s(t)) for s in sig_list])
            return full_reference_rhs(p, sc.gear, sc.slope, x, u, modes)

        teval = res.t[ia : ib + 1]
        sol = solve_ivp(
            f,
            (teval[0], teval[-1]),
            res.x[ia],
            method="DOP853",
            rtol=1e-12,
            atol=1e-12,
            t_eval=teval,
        )
        assert sol.success
        ours = res.x[ia : ib + 1]
        err = np.abs(sol.y.T - ours) / np.maximum(1.0, np.abs(ours))
        worst = max(worst, float(err.max()))
        n_int += 1
    return n_int, worst


def test_kernel_matches_reference_tip_in() -> None:
    n_int, worst = reference_check("tip-in", 0.5, 1.0)
    assert n_int > 10  # backlash crossing, damper friction stick/slip
    assert worst < 1e-7


def test_kernel_matches_reference_engage_ramp_rattle() -> None:
    n_int, worst = reference_check("engage-ramp", 0.2, 0.6)
    assert n_int > 10
    assert worst < 1e-7


def test_kernel_matches_reference_engage_ramp_lockup() -> None:
    n_int, worst = reference_check("engage-ramp", 1.7, 2.3)
    assert n_int > 3
    assert worst < 1e-7


@pytest.mark.parametrize("name", ["engage-ramp", "tip-in"])
def test_events_and_speeds_match_an_independent_event_driven_reference(name: str) -> None:
    """The compiled kernel at default options against the benchmark's reference, computed
    independently of it (scipy DOP853 event-driven on the flat model, its own mode decisions,
    guards also sampled every 10 us; rtol 1e-10 here, 1e-12 in the benchmark): every event
    matched (same element, same new mode) within 1e-5 s, speeds within 1e-4 rad/s away from events."""
    import importlib
    import sys
    from pathlib import Path

    bench = str(Path(__file__).resolve().parents[2] / "benchmarks")
    if bench not in sys.path:
        sys.path.insert(0, bench)
    BS = importlib.import_module("bench_simulate")
    s = BS.scenario_setup(name)
    ref = BS.reference_run(s, 1e-10)
    res = simulate(s.dt.model, s.x0, s.inputs, t_end=s.sc.t_end)
    ev = BS.match_events(ref.events, BS.ours_events(res))
    assert ev["n_ref"] > 50
    assert ev["unmatched_ref"] == 0 and ev["unmatched_method"] == 0, ev
    assert ev["max_abs_err_s"] < 1e-5, ev
    assert BS.speed_error(ref, res.t, res.x)["max_abs"] < 1e-4
