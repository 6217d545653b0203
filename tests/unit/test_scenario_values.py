"""Value tests of drivetrain_ctrl.scenarios.scenario (issue 22 item 4): the unit conversions of a
scenario file, its range checks at their exact boundaries, the parameter overrides, the start
time and horizon, and the idle throttle against the closed form, each computed by hand here
(``./dev mutate drivetrain_ctrl/scenarios/scenario.py``)."""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from drivetrain_ctrl.core.signals import constant, ramp
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import (
    Scenario,
    ScenarioError,
    idle_throttle,
    scenario_from_dict,
)

P = default_params()

BASE: dict[str, Any] = {
    "name": "t",
    "description": "throttle {throttle0}",
    "gear": 2,
    "slope_percent": 12.0,
    "t_end": 3.0,
    "initial": {
        "engine_speed_rpm": 1500.0,
        "clutch_locked": False,
        "vehicle_speed_kmh": 18.0,
        "throttle": 0.25,
        "twist_torque": -4.0,
    },
    "inputs": {
        "throttle": {"times": [0.0], "values": [0.25]},
        "pedal": {"times": [0.4, 2.4], "values": [0.11, 0.03]},
        "brake": {"times": [0.0], "values": [0.0]},
    },
}


def _d(**changes: Any) -> dict[str, Any]:
    d = copy.deepcopy(BASE)
    for k, v in changes.items():
        if "." in k:
            sec, _, key = k.partition(".")
            d[sec][key] = v
        else:
            d[k] = v
    return d


def _sc(**kw: Any) -> Scenario:
    base: dict[str, Any] = {
        "name": "s",
        "description": "",
        "gear": 1,
        "slope": 0.0,
        "t_end": 2.0,
        "omega_engine0": 150.0,
        "v_vehicle0": 0.0,
        "throttle0": 0.5,
        "twist_torque0": 0.0,
        "inputs": (
            ("throttle", constant(0.5)),
            ("pedal", ramp(0.5, 1.5, 0.11, 0.03)),
            ("brake", constant(0.0)),
        ),
    }
    base.update(kw)
    return Scenario(**base)


def test_file_units_are_converted_to_si() -> None:
    sc = scenario_from_dict(_d())
    assert sc.gear == 2
    assert sc.slope == pytest.approx(math.atan(0.12), rel=1e-15)
    assert sc.omega_engine0 == pytest.approx(1500.0 * 2.0 * math.pi / 60.0, rel=1e-15)
    assert sc.v_vehicle0 == pytest.approx(5.0, rel=1e-15)  # 18 km/h
    assert sc.throttle0 == 0.25
    assert sc.twist_torque0 == -4.0
    assert sc.t_end == 3.0
    assert sc.description == "throttle 0.2500"
    assert sc.pedal0 == 0.11 and sc.reference is None and sc.control_start is None
    assert dict(sc.inputs)["pedal"](1.4) == pytest.approx(0.07)
    # the round trip back to the file's units
    out = sc.to_dict()
    assert out["slope_percent"] == pytest.approx(12.0, rel=1e-14)
    assert out["initial"]["engine_speed_rpm"] == pytest.approx(1500.0, rel=1e-14)
    assert out["initial"]["vehicle_speed_kmh"] == pytest.approx(18.0, rel=1e-14)
    assert out["initial"]["twist_torque"] == -4.0
    assert out["gear"] == 2 and out["t_end"] == 3.0
    assert "controller" not in out and "params" not in out


def test_defaults_of_a_minimal_file() -> None:
    d = _d()
    del d["slope_percent"], d["gear"], d["initial"]["twist_torque"], d["name"], d["description"]
    del d["initial"]["clutch_locked"]
    sc = scenario_from_dict(d)
    assert (sc.slope, sc.gear, sc.twist_torque0) == (0.0, 1, 0.0)
    assert sc.name == "scenario" and sc.description == ""
    assert sc.clutch_locked0 is False


def test_a_locked_start_ignores_the_engine_speed() -> None:
    d = _d(**{"initial.clutch_locked": True, "initial.engine_speed_rpm": -5.0})
    sc = scenario_from_dict(d)
    assert sc.clutch_locked0 is True and sc.omega_engine0 == 0.0
    dt = sc.drivetrain(P, kind="reduced")
    x = sc.initial_state(dt)
    ie = dt.model.state_index("omega_engine")
    # locked: the engine turns at the primary shaft's speed for 5 m/s (rigid chain, no slip)
    assert x[ie] == pytest.approx(dt.vehicle_speed_to_primary(5.0), rel=1e-12)
    assert dt.vehicle_speed_to_primary(5.0) > 0.0
    # unlocked: the given speed
    sc2 = scenario_from_dict(_d())
    dt2 = sc2.drivetrain(P, kind="reduced")
    x2 = sc2.initial_state(dt2)
    ie = dt2.model.state_index("omega_engine")
    assert x2[ie] == pytest.approx(1500.0 * math.pi / 30.0, rel=1e-12)


@pytest.mark.parametrize(
    ("key", "value", "ok"),
    [
        ("initial.engine_speed_rpm", 0.0, True),
        ("initial.engine_speed_rpm", -1e-9, False),
        ("initial.throttle", 0.0, True),
        ("initial.throttle", 1.0, True),
        ("initial.throttle", -1e-12, False),
        ("initial.throttle", 1.0 + 1e-12, False),
        ("slope_percent", 1400.0, True),  # atan(14) = 1.4995 rad < 1.5
        ("slope_percent", -1400.0, True),
        ("slope_percent", 1420.0, False),  # atan(14.2) = 1.5005 rad
        ("slope_percent", -1420.0, False),
    ],
)
def test_file_range_boundaries(key: str, value: float, ok: bool) -> None:
    d = _d(**{key: value})
    if key == "initial.throttle":
        d["inputs"]["throttle"]["values"] = [min(max(value, 0.0), 1.0)]
    if ok:
        scenario_from_dict(d)
    else:
        with pytest.raises(ScenarioError, match=key.rpartition(".")[2]):
            scenario_from_dict(d)


@pytest.mark.parametrize(
    ("field", "value", "ok"),
    [
        ("throttle0", 0.0, True),
        ("throttle0", 1.0, True),
        ("throttle0", -0.01, False),
        ("throttle0", 1.01, False),
        ("omega_engine0", 0.0, True),
        ("omega_engine0", -0.01, False),
        ("t_end", 1e-9, True),
        ("t_end", 0.0, False),
        ("slope", math.pi / 2 - 1e-9, True),
        ("slope", -(math.pi / 2 - 1e-9), True),
        ("slope", math.pi / 2, False),
        ("slope", -math.pi / 2, False),
        ("pedal0", 0.0, True),
        ("pedal0", 0.5, True),
        ("pedal0", -1e-9, False),
        ("pedal0", 0.5 + 1e-9, False),
    ],
)
def test_scenario_range_boundaries(field: str, value: float, ok: bool) -> None:
    if ok:
        assert getattr(_sc(**{field: value}), field) == value
    else:
        with pytest.raises(ScenarioError, match=field):
            _sc(**{field: value})


@pytest.mark.parametrize(
    ("start", "ok"), [(0.0, True), (1.999, True), (-1e-9, False), (2.0, False), (2.5, False)]
)
def test_control_start_lies_in_the_run(start: float, ok: bool) -> None:
    kw: dict[str, Any] = {
        "inputs": (("throttle", constant(0.5)), ("brake", constant(0.0))),
        "reference": constant(100.0),
        "control_start": start,
    }
    if ok:
        sc = _sc(**kw)
        assert sc.needs_controller and sc.start_time == start
    else:
        with pytest.raises(ScenarioError, match="start_s"):
            _sc(**kw)


def test_a_closed_loop_scenario_file_converts_its_reference() -> None:
    d = _d()
    del d["inputs"]["pedal"]
    d["controller"] = {
        "reference_rpm": {"times": [0.0, 1.0], "values": [1200.0, 900.0]},
        "pedal0": 0.1,
        "start_s": 0.3,
    }
    sc = scenario_from_dict(d)
    assert sc.reference is not None and sc.control_start == 0.3 and sc.pedal0 == 0.1
    assert sc.reference(0.5) == pytest.approx(1050.0 * math.pi / 30.0, rel=1e-14)
    assert sc.start_time == 0.3
    out = sc.to_dict()
    assert out["controller"]["start_s"] == 0.3 and out["controller"]["pedal0"] == 0.1
    assert out["controller"]["reference_rpm"]["values"] == pytest.approx([1200.0, 900.0])
    assert "pedal" not in out["inputs"]
    # without a start: the controller starts at 0
    del d["controller"]["start_s"]
    sc2 = scenario_from_dict(d)
    assert sc2.control_start is None and sc2.start_time == 0.0
    assert "start_s" not in sc2.to_dict()["controller"]


def test_start_time_is_the_first_pedal_knot_not_before_zero() -> None:
    assert _sc().start_time == 0.5
    early = (("throttle", constant(0.5)), ("pedal", ramp(-1.0, 1.0, 0.11, 0.03)))
    assert _sc(inputs=(*early, ("brake", constant(0.0)))).start_time == 0.0


def test_check_horizon() -> None:
    sc = _sc()  # start 0.5 s, t_end 2 s
    assert sc.check_horizon() == 2.0
    assert sc.check_horizon(0.5) == 0.5  # ends at the start command: allowed
    assert type(sc.check_horizon(1)) is float
    with pytest.raises(ScenarioError, match=r"--t-end = 0.49: the run would end before"):
        sc.check_horizon(0.49, arg="--t-end")
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ScenarioError, match="must be a finite number > 0"):
            sc.check_horizon(bad)


def test_scale_override_multiplies_the_sets_value() -> None:
    sc = _sc(param_overrides=(("clutch.k12_max", {"scale": 0.7}), ("vehicle.M_v", 1500.0)))
    p2 = sc.params_for(P)
    assert p2.clutch.k12_max == pytest.approx(0.7 * P.clutch.k12_max, rel=1e-15)
    assert p2.vehicle.M_v == 1500.0
    assert p2.name == f"{P.name} + scenario s"
    assert _sc().params_for(P) is P
    out = sc.to_dict()["params"]
    assert out == {"clutch": {"k12_max": {"scale": 0.7}}, "vehicle": {"M_v": 1500.0}}


@pytest.mark.parametrize("f", [0.0, -0.5, float("inf"), "2"])
def test_a_bad_scale_is_named(f: object) -> None:
    sc = _sc(param_overrides=(("clutch.k12_max", {"scale": f}),))
    with pytest.raises(ScenarioError, match=r"params.clutch.k12_max = .*a scale must be"):
        sc.params_for(P)


def test_a_scale_with_another_key_is_rejected() -> None:
    sc = _sc(param_overrides=(("clutch.k12_max", {"scale": 0.5, "x": 1}),))
    with pytest.raises(ScenarioError, match="a scale must be"):
        sc.params_for(P)


def test_idle_throttle_is_the_closed_form() -> None:
    e = P.engine
    for w in (80.0, 100.0):
        if e.torque_model == "map" and e.full_load_curve is not None:
            gain = float(np.interp(w, e.full_load_curve.x, e.full_load_curve.y))
        else:
            gain = e.K
        assert idle_throttle(P, w) == pytest.approx((e.b1 * w + e.c1) / gain, rel=1e-14)


def test_idle_throttle_on_the_linear_torque_model() -> None:
    p = P.with_values({"engine.torque_model": "linear"}) if P.engine.torque_model != "linear" else P
    e = p.engine
    w = 90.0
    assert idle_throttle(p, w) == pytest.approx((e.b1 * w + e.c1) / e.K, rel=1e-14)
    # the throttle limit: 1 is allowed, just above is not
    w1 = (e.K - e.c1) / e.b1
    assert idle_throttle(p, w1) == pytest.approx(1.0, rel=1e-12)
    with pytest.raises(ScenarioError, match="outside"):
        idle_throttle(p, w1 * 1.001)
    with pytest.raises(ScenarioError, match="must be > 0"):
        idle_throttle(p, 0.0)


def test_idle_rpm_in_a_file_is_the_idle_throttle() -> None:
    d = _d()
    d["initial"]["throttle"] = {"idle_rpm": 900.0}
    d["inputs"]["throttle"]["values"] = [{"idle_rpm": 900.0}]
    sc = scenario_from_dict(d, params=P)
    th = idle_throttle(P, 900.0 * math.pi / 30.0)
    assert sc.throttle0 == pytest.approx(th, rel=1e-14)
    assert dict(sc.inputs)["throttle"](0.0) == pytest.approx(th, rel=1e-14)
    for bad in (0.0, -900.0):
        d["initial"]["throttle"] = {"idle_rpm": bad}
        with pytest.raises(ScenarioError, match=r"initial.throttle.idle_rpm = .*> 0"):
            scenario_from_dict(d, params=P)
    d["initial"]["throttle"] = {"idle_rpm": 0.5}  # any positive speed, even below 1 rpm
    sc = scenario_from_dict(d, params=P)
    assert sc.throttle0 == pytest.approx(idle_throttle(P, 0.5 * math.pi / 30.0), rel=1e-14)


@pytest.mark.parametrize("ctl", [3.0, "paper", [1, 2]])
def test_a_controller_that_is_not_a_table_is_named(ctl: object) -> None:
    d = _d()
    d["controller"] = ctl
    with pytest.raises(ScenarioError, match=r"^controller: must be a table$"):
        scenario_from_dict(d)


def test_replace_keeps_the_checks() -> None:
    sc = _sc()
    with pytest.raises(ScenarioError, match="throttle0"):
        dataclasses.replace(sc, throttle0=2.0)


@pytest.mark.parametrize("name", ["throttle", "pedal", "brake"])
def test_a_missing_input_is_named(name: str) -> None:
    d = _d()
    del d["inputs"][name]
    with pytest.raises(ScenarioError, match=rf"^inputs\.{name}: missing$"):
        scenario_from_dict(d)
