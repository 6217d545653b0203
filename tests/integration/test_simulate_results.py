"""The results API of :func:`simulate` (DataFrames with units, modes, lock-up time, coupling
torques) and the errors of bad arguments."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.plant.chain import two_body_clutch
from drivetrain_ctrl.plant.drivetrain import Drivetrain, input_ranges
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import builtin_scenarios
from drivetrain_ctrl.sim.simulator import (
    Event,
    InputRangeError,
    SimulationOptions,
    SimulationResult,
    simulate,
)


@functools.cache
def engage() -> tuple[Drivetrain, SimulationResult]:
    sc = builtin_scenarios()["engage-ramp"]
    dt = sc.drivetrain(default_params())
    return dt, simulate(dt.model, sc.initial_state(dt), sc.input_signals(), t_end=sc.t_end)


@functools.cache
def tip_in() -> SimulationResult:
    sc = builtin_scenarios()["tip-in"]
    dt = sc.drivetrain(default_params())
    return simulate(dt.model, sc.initial_state(dt), sc.input_signals(), t_end=1.0)


def small() -> tuple[Model, dict[str, object], np.ndarray]:
    m = Model(two_body_clutch(0.2, 1.0, capacity=50.0))
    return m, {"torque1": 20.0}, np.array([100.0, 0.0])


# ------------------------------------------------------------------------------------------------
# DataFrames
# ------------------------------------------------------------------------------------------------


def test_to_dataframe_columns_carry_units_and_values() -> None:
    dt, res = engage()
    df = res.to_dataframe()
    cols = set(df.columns)
    for c in (
        "t [s]",
        "omega_engine [rad/s]",
        "omega_disc [rad/s]",
        "v_vehicle [m/s]",
        "q_backlash [rad]",
        "pos_vehicle [m]",
        "lag_engine [-]",
        "T_clutch [N m]",
        "T_backlash [N m]",
        "work_in [J]",
        "stored_energy [J]",
        "dissipated_clutch [J]",
        "mode_clutch",
        "mode_backlash",
    ):
        assert c in cols, c
    # every state has a column named "<state> [<unit>]"
    for nm, un in zip(dt.model.state_names, dt.model.state_units, strict=True):
        np.testing.assert_array_equal(df[f"{nm} [{un}]"].to_numpy(), res.state(nm))
    assert len(df) == res.t.shape[0]
    np.testing.assert_array_equal(df["t [s]"].to_numpy(), res.t)
    assert list(df["mode_clutch"]) == res.mode_series("clutch")
    np.testing.assert_array_equal(df["T_clutch [N m]"].to_numpy(), res.coupling_torques()[:, 0])
    np.testing.assert_allclose(df["stored_energy [J]"].to_numpy(), res.stored_energy())
    # the inputs are there too (throttle [-], pedal [m], brake [N m])
    np.testing.assert_array_equal(df["input_pedal [m]"].to_numpy(), res.u[:, 1])
    assert {"input_throttle [-]", "input_brake [N m]"} <= cols
    # the axle torque also at the wheels: ratio D_c times the secondary-frame torque; its peak
    # over the engagement window [start, lock-up + 1 s] (start: the run's) is the metrics'
    # axle_torque_max_Nm
    from drivetrain_ctrl.sim.metrics import engagement_metrics

    ratio = float(dt.model.data.ratio[[c.name for c in dt.model.chain.couplings].index("axle")])
    assert ratio > 1.0
    np.testing.assert_allclose(df["T_axle_out [N m]"], ratio * df["T_axle [N m]"], rtol=1e-15)
    m = engagement_metrics(res, dt)
    in_w = df["t [s]"] <= m["lockup_time_s"] + 1.0
    peak = float(np.max(np.abs(df["T_axle_out [N m]"][in_w])))
    assert peak == pytest.approx(m["axle_torque_max_Nm"], rel=1e-8)


def test_to_dataframe_without_energy_and_residual_needs_energy() -> None:
    m, inputs, x0 = small()
    res = simulate(m, x0, inputs, t_end=1.0, options=SimulationOptions(energy=False))
    assert res.work_in is None and res.dissipated is None
    df = res.to_dataframe()
    assert "work_in [J]" not in df.columns
    assert "omega_b1 [rad/s]" in df.columns
    with pytest.raises(ValueError, match="energy"):
        _ = res.energy_residual_rel


def test_events_dataframe_matches_events() -> None:
    _, res = engage()
    ev = res.events_dataframe()
    assert list(ev.columns) == ["t [s]", "element", "from_mode", "to_mode"]
    assert len(ev) == len(res.events) > 0
    for row, e in zip(ev.itertuples(index=False), res.events, strict=True):
        assert (row[0], row[1], row[2], row[3]) == (e.t, e.element, e.from_mode, e.to_mode)
    assert np.all(np.diff(ev["t [s]"].to_numpy()) >= 0.0)
    # every friction event names real modes of its element
    modes = {fi.name: set(fi.mode_names) for fi in res.model.frictions}
    for e in res.events:
        if e.element in modes:
            assert {e.from_mode, e.to_mode} <= modes[e.element]
            assert e.from_mode != e.to_mode


def test_events_are_immutable_and_name_table_regions() -> None:
    res = tip_in()
    assert all(isinstance(e, Event) for e in res.events)
    with pytest.raises(AttributeError):
        res.events[0].t = 0.0  # type: ignore[misc]
    backlash = [e for e in res.events if e.element == "backlash"]
    assert backlash, "tip-in crosses the backlash gap"
    for e in backlash:
        assert {e.from_mode, e.to_mode} <= {"contact-", "gap", "contact+"}
        assert e.from_mode != e.to_mode


def test_events_are_consistent_with_mode_series() -> None:
    """Each friction event changes the recorded mode at its sample, from from_mode to to_mode."""
    _, res = engage()
    for e in res.events:
        if e.element not in {fi.name for fi in res.model.frictions}:
            continue
        series = res.mode_series(e.element)
        i = int(np.flatnonzero(res.t == e.t)[-1])
        assert series[i] == e.to_mode
        j = int(np.flatnonzero(res.t < e.t)[-1])
        assert series[j] == e.from_mode


def test_mode_series_elements() -> None:
    _, res = engage()
    assert res.mode_series("clutch")[0] == "open"
    assert set(res.mode_series("tyre")) <= {"grip", "slip+", "slip-", "lifted"}
    assert set(res.mode_series("backlash")) <= {"contact-", "gap", "contact+"}
    assert len(res.mode_series("vehicle")) == res.t.shape[0]
    with pytest.raises(KeyError, match="nope"):
        res.mode_series("nope")
    with pytest.raises(KeyError):
        res.mode_series("clutch.capacity_table")  # a table without mode names


def test_lockup_time() -> None:
    _, res = engage()
    t_lock = res.lockup_time()
    assert t_lock is not None and 1.0 < t_lock < 3.0
    last = [e for e in res.events if e.element == "clutch" and e.to_mode == "stuck"][-1]
    assert t_lock == last.t
    assert res.lockup_time(after=t_lock + 0.1) is None
    assert tip_in().lockup_time() is None  # stuck from the start
    with pytest.raises(KeyError, match="nope"):
        res.lockup_time("nope")
    for bad in (float("nan"), "0.2", True):
        with pytest.raises(ValueError, match="min_duration"):
            res.lockup_time(min_duration=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="min_duration = -1"):
        res.lockup_time(min_duration=-1.0)
    with pytest.raises(ValueError, match="after"):
        res.lockup_time(after=float("inf"))
    with pytest.raises(ValueError, match=r"after = 99.0 \[s\] is past the end of the run"):
        res.lockup_time(after=99.0)
    # stuck phases: entered from slip, each ending at the first sample after it
    ph = res.stuck_phases("clutch")
    stuck_events = [e.t for e in res.events if e.element == "clutch" and e.to_mode == "stuck"]
    assert [p0 for p0, _ in ph] == stuck_events
    assert all(p1 > p0 for p0, p1 in ph) and ph[-1][1] == res.t[-1]
    # a two-body clutch that locks at 0.5 s
    m, inputs, x0 = small()
    r = simulate(m, x0, inputs, t_end=1.0)
    assert r.lockup_time() == pytest.approx(0.5, abs=1e-12)


# ------------------------------------------------------------------------------------------------
# coupling torques
# ------------------------------------------------------------------------------------------------


def test_clutch_torque_is_the_capacity_while_slipping() -> None:
    dt, res = engage()
    pm = dt.params.clutch.pedal_map
    cap = dt.params.clutch.k12_max * np.interp(res.u[:, 1], pm.x, pm.y)  # flat mu: k12(x_c)
    Tc = res.coupling_torques()[:, 0]
    series = np.array(res.mode_series("clutch"))
    slip = series == "slip+"
    assert slip.sum() > 100
    np.testing.assert_allclose(Tc[slip], cap[slip], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(Tc[series == "open"], 0.0)
    # stuck: the constraint torque, within the (static = kinetic) capacity
    stuck = series == "stuck"
    assert stuck.sum() > 10
    assert np.all(np.abs(Tc[stuck]) <= cap[stuck] * (1.0 + 1e-9))
    # and it equals the model's stuck torque at those samples
    m = dt.model
    for i in np.flatnonzero(stuck)[::50]:
        mode, _ = m.decide(res.x[i], res.u[i])
        assert m.mode_names(mode)["clutch"] == "stuck"
        assert Tc[i] == pytest.approx(m.stuck_torques(res.x[i], res.u[i], mode)["clutch"])


def test_spring_coupling_torque_is_the_spring_law() -> None:
    """T_backlash = h34 * deadzone(q, g) + b34 * (w3 - tau_r w4) at every sample."""
    res = tip_in()
    p = default_params()
    g = p.gearbox.g34_primary(1)
    q = res.state("q_backlash")
    dz = np.where(q > g, q - g, np.where(q < -g, q + g, 0.0))
    w = res.state("omega_primary") - p.gearbox.tau_r(1) * res.state("omega_secondary")
    Tb = res.coupling_torques()[:, 2]
    np.testing.assert_allclose(Tb, p.gearbox.h34 * dz + p.gearbox.b34 * w, rtol=1e-9, atol=1e-9)


# ------------------------------------------------------------------------------------------------
# bad arguments
# ------------------------------------------------------------------------------------------------


def test_bad_x0_shape() -> None:
    m, inputs, _ = small()
    with pytest.raises(ValueError, match=r"x0 must have shape \(2,\).*omega_b1"):
        simulate(m, np.zeros(3), inputs, t_end=1.0)
    with pytest.raises(ValueError, match="x0 must have shape"):
        simulate(m, np.zeros((1, 2)), inputs, t_end=1.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_x0_names_the_state(bad: float) -> None:
    dt, _ = engage()
    x0 = np.zeros(dt.model.nx)
    x0[dt.model.state_index("q_backlash")] = bad
    with pytest.raises(ValueError, match="q_backlash") as exc:
        simulate(dt.model, x0, {"throttle": 0.0, "pedal": 0.1, "brake": 0.0}, t_end=0.1)
    assert "omega_engine" not in str(exc.value)


def test_missing_and_unknown_inputs_are_named() -> None:
    dt, _ = engage()
    x0 = np.zeros(dt.model.nx)
    with pytest.raises(KeyError, match="brake"):
        simulate(dt.model, x0, {"throttle": 0.0, "pedal": 0.1}, t_end=0.1)
    with pytest.raises(KeyError, match="clutch_pedal"):
        simulate(
            dt.model,
            x0,
            {"throttle": 0.0, "pedal": 0.1, "brake": 0.0, "clutch_pedal": 0.1},
            t_end=0.1,
        )


@pytest.mark.parametrize(
    ("t0", "t_end"), [(0.0, 0.0), (1.0, 0.5), (0.0, math.nan), (0.0, math.inf)]
)
def test_bad_time_span(t0: float, t_end: float) -> None:
    m, inputs, x0 = small()
    with pytest.raises(ValueError, match="t_end"):
        simulate(m, x0, inputs, t0=t0, t_end=t_end)


def test_nonzero_t0() -> None:
    """Starting at t0 = 2 with a torque step at 2.5: lock-up 0.5 s after the start as from 0."""
    m, _, x0 = small()
    res = simulate(m, x0, {"torque1": sg.step(2.5, 5.0, initial=20.0)}, t0=2.0, t_end=3.0)
    assert res.t[0] == 2.0 and res.t[-1] == 3.0
    assert res.lockup_time() == pytest.approx(2.5, abs=1e-12)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("rtol", 0.0),
        ("rtol", "1e-6"),
        ("atol", -1.0),
        ("h_max", math.nan),
        ("h_init", math.inf),
        ("tol_w", True),
        ("zeno_window", 0.0),
        ("zeno_count", 1),
        ("zeno_count", 3.0),
        ("max_events", 2.5),
        ("max_steps", True),
    ],
)
def test_bad_options_name_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=rf"SimulationOptions\.{field}"):
        SimulationOptions(**{field: value})  # type: ignore[arg-type]


def test_options_are_keyword_only_and_frozen() -> None:
    with pytest.raises(TypeError):
        SimulationOptions(1e-6)  # type: ignore[misc]
    opts = SimulationOptions()
    with pytest.raises(AttributeError):
        opts.rtol = 1e-3  # type: ignore[misc]


def test_non_finite_constant_input_names_the_input() -> None:
    m, _, x0 = small()
    with pytest.raises(ValueError, match="torque1"):
        simulate(m, x0, {"torque1": math.nan}, t_end=1.0)


def test_energy_option_must_be_bool() -> None:
    with pytest.raises((TypeError, ValueError), match="energy"):
        SimulationOptions(energy="yes")  # type: ignore[arg-type]


def test_smoothed_run_reports_the_smoothed_torques_and_no_stick_slip_modes() -> None:
    """With ``smoothing`` eps the clutch transmits ``50 tanh(w / eps)`` N m: the result's coupling
    torque is that (not the exact law's 50 N m), and its mode is 'smoothed' throughout."""
    m, u, x0 = small()
    eps = 30.0  # wide: the smoothing matters over most of the run
    res = simulate(m, x0, u, t_end=0.5, options=SimulationOptions(smoothing=eps))
    assert res.smoothing == eps
    w = res.x[:, 0] - res.x[:, 1]
    T = res.coupling_torques()[:, 0]
    np.testing.assert_allclose(T, 50.0 * np.tanh(w / eps), rtol=1e-12, atol=1e-12)
    assert np.ptp(T) > 10.0  # really varies with w
    assert set(res.mode_series("clutch")) == {"smoothed"}
    df = res.to_dataframe()
    assert set(df["mode_clutch"]) == {"smoothed"}
    np.testing.assert_allclose(df["T_clutch [N m]"], T)
    import matplotlib.pyplot as plt

    fig = res.plot()
    try:
        assert "friction smoothed (tanh, 30)" in fig._suptitle.get_text()
        assert "clutch" not in [t.get_text() for t in fig.axes[3].get_yticklabels()]
        # a general chain's speeds: every body, by name
        assert [ln.get_label() for ln in fig.axes[0].get_lines()][:2] == ["b1", "b2"]
    finally:
        plt.close(fig)
    # the exact run still reports the stick/slip modes and the exact law's torque while slipping
    exact = simulate(m, x0, u, t_end=0.5)
    assert exact.smoothing is None
    assert exact.mode_series("clutch")[0] == "slip+"
    assert exact.coupling_torques()[0, 0] == pytest.approx(50.0)


def test_plot_overview_saves_a_png_with_four_panels(tmp_path: object) -> None:
    """``res.plot(path)`` (matplotlib only in the plotting layer): speeds, torques, inputs and a
    mode strip with one row per friction element and backlash; the title counts the events."""
    from pathlib import Path

    import matplotlib.pyplot as plt

    res = tip_in()
    path = Path(str(tmp_path)) / "overview.png"
    fig = res.plot(str(path))
    try:
        assert path.stat().st_size > 10_000
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert len(fig.axes) >= 4
        assert f"{len(res.events)} events" in fig._suptitle.get_text()
        strip = fig.axes[3]
        labels = [t.get_text() for t in strip.get_yticklabels()]
        moded = [f.name for f in res.model.frictions] + [
            t.name for t in res.model.tables if t.region_names is not None
        ]
        assert set(moded) <= set(labels), labels
    finally:
        plt.close(fig)


# ------------------------------------------------------------------------------------------------
# bad arguments and inputs outside the physical range
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kw", "exc", "match"),
    [
        ({"options": {}}, TypeError, r"options = \{\}: must be a SimulationOptions"),
        ({"options": 0}, TypeError, "options = 0"),
        ({"t_end": "3"}, ValueError, "t_end = '3': must be a finite number"),
        ({"t_end": True}, ValueError, "t_end = True"),
        ({"t0": None}, ValueError, "t0 = None"),
        ({"raise_on_zeno": "no"}, TypeError, "raise_on_zeno = 'no'"),
        ({"controller": "paper"}, TypeError, "controller = 'paper': must be a closedloop"),
        ({"controller_initial": 0.07}, ValueError, "controller_initial = 0.07: only a closed"),
    ],
)
def test_bad_simulate_arguments_name_the_argument(
    kw: dict[str, object], exc: type[Exception], match: str
) -> None:
    m, inputs, x0 = small()
    args: dict[str, object] = {"t_end": 1.0, **kw}
    with pytest.raises(exc, match=match):
        simulate(m, x0, inputs, **args)  # type: ignore[arg-type]


def test_non_numeric_x0_is_named() -> None:
    m, inputs, _ = small()
    with pytest.raises(ValueError, match=r"x0 = \['a', 'b'\]: must be 2 numbers .*omega_b1"):
        simulate(m, ["a", "b"], inputs, t_end=1.0)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("name", "signal", "match"),
    [
        (
            "throttle",
            sg.constant(10.0),
            r"input 'throttle' = 10 at t = 0 s: outside its range \[0, 1\]",
        ),
        ("throttle", sg.step(0.5, -1.5, initial=0.5), r"'throttle' = -1 at t = 0.5 s"),
        ("pedal", sg.ramp(0.2, 1.0, 0.11, -0.1), r"'pedal' = -0.1 m at t = 1 s: .*\[0, 0.12\] m"),
        ("brake", sg.constant(-3000.0), r"'brake' = -3000 N m .*\[0, 3000\] N m"),
        (
            "brake",
            sg.constant(2000.0) + sg.sine(1500.0, 20.0),
            r"'brake' = 3[45][0-9.]+ N m at t = 0.07",
        ),
    ],
)
def test_inputs_outside_their_physical_range_are_rejected(
    name: str, signal: sg.Signal, match: str
) -> None:
    """The drivetrain's inputs have ranges (throttle [0, 1], pedal within the actuator stroke,
    brake within [0, brake.capacity_max]); a signal that leaves one is rejected before the run,
    naming the input, the value and the time."""
    dt, _ = engage()
    sc = builtin_scenarios()["engage-ramp"]
    inputs = {**sc.input_signals(), name: signal}
    with pytest.raises(InputRangeError, match=match):
        simulate(dt.model, sc.initial_state(dt), inputs, t_end=3.0)


def test_input_ranges_follow_the_parameter_set() -> None:
    p = default_params()
    dt = Drivetrain(p.replace(**{"actuator.x_max": 0.2, "brake.capacity_max": 5000.0}))
    ranges = dict(zip(dt.model.input_names, dt.model.input_ranges, strict=True))
    with pytest.raises(TypeError, match="input_ranges: p = None: must be a DrivetrainParams"):
        input_ranges(None)  # type: ignore[arg-type]
    assert ranges == {"throttle": (0.0, 1.0), "pedal": (0.0, 0.2), "brake": (0.0, 5000.0)}
    # a chain without ranges leaves its inputs unbounded
    m, _, x0 = small()
    assert m.input_ranges == ((-math.inf, math.inf),)
    simulate(m, x0, {"torque1": 1e6}, t_end=0.01)


def test_a_run_that_goes_non_finite_is_an_error_naming_time_and_column() -> None:
    dt, _ = engage()
    sc = builtin_scenarios()["engage-ramp"]
    x0 = sc.initial_state(dt)
    x0[dt.model.state_index("omega_engine")] = 1e300
    with pytest.raises(RuntimeError, match=r"went non-finite: .* at t = [0-9.e-]+ s"):
        simulate(dt.model, x0, sc.input_signals(), t_end=0.1)


def test_options_accept_numpy_scalars_and_reject_a_meaningless_rtol() -> None:
    o = SimulationOptions(rtol=np.float32(1e-8), max_steps=np.int64(1000))
    assert isinstance(o.rtol, float) and o.rtol == pytest.approx(1e-8)
    assert isinstance(o.max_steps, int) and o.max_steps == 1000
    for bad in (1.0, 1e10):
        with pytest.raises(ValueError, match=rf"SimulationOptions\.rtol = {bad!r}: must be < 1e-2"):
            SimulationOptions(rtol=bad)
    with pytest.raises(ValueError, match=r"SimulationOptions\.rtol = 10{400}"[:-5]):
        SimulationOptions(rtol=10**400)


def test_h_init_above_h_max_starts_at_h_max() -> None:
    m, inputs, x0 = small()
    a = simulate(m, x0, inputs, t_end=0.5, options=SimulationOptions(h_init=1e-3, h_max=1e-4))
    b = simulate(m, x0, inputs, t_end=0.5, options=SimulationOptions(h_init=1e-4, h_max=1e-4))
    assert np.array_equal(a.t, b.t) and np.array_equal(a.x, b.x)
    assert a.t[1] - a.t[0] == pytest.approx(1e-4)


def test_a_run_longer_than_max_steps_can_cover_is_rejected_up_front() -> None:
    m, inputs, x0 = small()
    with pytest.raises(ValueError, match=r"t_end = 1e\+300 s: a run of .* cannot finish"):
        simulate(m, x0, inputs, t_end=1e300)
    opts = SimulationOptions(max_steps=100, h_max=1e-3)
    with pytest.raises(ValueError, match=r"max_steps = 100 steps of at most h_max = 0.001 s"):
        simulate(m, x0, inputs, t_end=0.2, options=opts)


def test_smoothing_accepts_numpy_scalars() -> None:
    assert SimulationOptions(smoothing=np.float32(0.5)).smoothing == pytest.approx(0.5)
