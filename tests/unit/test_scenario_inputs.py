"""Input checks of scenarios (:mod:`drivetrain_ctrl.scenarios`) that need no simulation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivetrain_ctrl.core.signals import constant, step
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import (
    ScenarioError,
    idle_throttle,
    load_scenario,
    scenario_from_dict,
)
from drivetrain_ctrl.sim.run import run_scenario

P = default_params()
SC = load_scenario("paper-start", params=P)


def test_pedal0_outside_the_actuator_stroke_is_rejected() -> None:
    act = P.actuator
    assert act.x_max < 0.5  # the scenario's own range [0, 0.5] is wider than the stroke
    sc = dataclasses.replace(SC, pedal0=act.x_max + 0.01)
    dt = sc.drivetrain(P, kind="reduced")
    with pytest.raises(ScenarioError, match=r"pedal0 = .*actuator stroke"):
        sc.check_pedal0(P)
    # checked where it is used: in the run, not when the controller is built
    assert sc.make_controller(dt, "paper").name == "paper"
    with pytest.raises(ScenarioError, match=r"pedal0 = .*actuator stroke"):
        run_scenario(sc, dt, controller="paper")
    SC.check_pedal0(P)  # the built-in value is fine
    dataclasses.replace(SC, pedal0=act.x_max).check_pedal0(P)


def test_numpy_scalars_are_numbers() -> None:
    assert idle_throttle(P, np.float32(94.0)) == pytest.approx(idle_throttle(P, 94.0), rel=1e-6)
    sc = dataclasses.replace(SC, t_end=np.float32(2.0))
    assert sc.t_end == 2.0
    d = SC.to_dict()
    d["t_end"] = np.float64(3.0)
    d["controller"]["pedal0"] = np.float32(0.1)
    assert scenario_from_dict(d).pedal0 == pytest.approx(0.1)


@pytest.mark.parametrize("v", [True, "90", float("nan"), None])
def test_idle_throttle_rejects_non_numbers(v: object) -> None:
    with pytest.raises(ScenarioError, match="omega"):
        idle_throttle(P, v)  # type: ignore[arg-type]


def test_scenario_t_end_rejects_non_numbers() -> None:
    for v in (True, "3", float("inf")):
        with pytest.raises(ScenarioError, match="t_end"):
            dataclasses.replace(SC, t_end=v)


def test_unknown_key_message_unchanged() -> None:
    d = SC.to_dict()
    d["initial"]["throtle"] = 0.5
    with pytest.raises(ScenarioError, match=r"^initial\.throtle: unknown key; did you mean"):
        scenario_from_dict(d)


@pytest.mark.parametrize("v", ["abc", True, float("nan")])
def test_twist_torque_must_be_a_number_and_is_named(v: object) -> None:
    d = load_scenario("tip-in", params=P).to_dict()
    assert "twist_torque" in d["initial"]
    d["initial"]["twist_torque"] = v
    with pytest.raises(ScenarioError, match=r"^initial\.twist_torque = .*finite number"):
        scenario_from_dict(d)
    d["initial"]["twist_torque"] = -12.5
    assert scenario_from_dict(d).twist_torque0 == -12.5


ENGAGE = load_scenario("engage-ramp")


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("name", "", "name = '': must be a non-empty string"),
        ("name", 5, "name = 5"),
        ("description", [1, 2], r"description = \[1, 2\]: must be a string"),
        ("gear", 1.0, "gear = 1.0: must be an integer"),
        ("slope", "0", "slope = '0': must be a finite number"),
        ("omega_engine0", None, "omega_engine0 = None"),
        ("pedal0", "0.1", "pedal0 = '0.1'"),
        ("clutch_locked0", "no", "clutch_locked0 = 'no': must be True or False"),
        ("throttle0", 5.0, r"throttle0 = 5.0: .*\[0, 1\]"),
        ("throttle0", -0.5, "throttle0 = -0.5"),
        ("omega_engine0", -199.0, "omega_engine0 = -199.0 .*must be >= 0"),
        ("inputs", {"throttle": 0.5}, "inputs = .*must be a tuple of .name, Signal. pairs"),
        ("control_start", "0.5", "control_start = '0.5'"),
    ],
)
def test_scenario_fields_are_checked_and_named(field: str, value: object, match: str) -> None:
    with pytest.raises(ScenarioError, match=match):
        dataclasses.replace(ENGAGE, **{field: value})


def test_duplicate_inputs_are_rejected() -> None:
    dup = (*ENGAGE.inputs, ("pedal", constant(0.05)))
    with pytest.raises(ScenarioError, match=r"input\(s\) \['pedal'\] given more than once"):
        dataclasses.replace(ENGAGE, inputs=dup)


def test_negative_reference_is_rejected() -> None:
    with pytest.raises(ScenarioError, match=r"reference_rpm = -1600 rpm at t = 0.5 s"):
        dataclasses.replace(SC, reference=constant(0.0) + step(0.5, -1600.0 * np.pi / 30.0))


def test_a_file_with_a_controller_and_a_pedal_has_both_loops() -> None:
    d = SC.to_dict()
    d["inputs"]["pedal"] = {"times": [0.7, 2.0], "values": [0.1, 0.03]}
    sc = scenario_from_dict(d)
    assert sc.loops == ("closed", "open") and sc.loop == "closed" and sc.needs_controller
    # its own loop is closed: the pedal signal is not an input the simulator sees
    assert set(sc.input_signals()) == {"throttle", "brake"}
    assert sc.start_time == 0.5  # controller.start_s
    op = sc.for_loop("open")
    assert op.loops == ("open",) and op.loop == "open" and not op.needs_controller
    assert op.reference is None and op.control_start is None
    assert set(op.input_signals()) == {"throttle", "pedal", "brake"}
    assert op.input_signals()["pedal"](1.35) == pytest.approx(0.065, rel=1e-12)
    assert op.start_time == 0.7  # the first pedal knot
    cl = sc.for_loop("closed")
    assert cl.loops == ("closed",) and "pedal" not in dict(cl.inputs)
    assert cl.reference == sc.reference and cl.control_start == 0.5
    assert sc.for_loop(None) == cl
    # round trip through the TOML form keeps both parts
    again = scenario_from_dict(sc.to_dict())
    assert again == sc


def test_loop_choice_errors_name_the_field_and_value() -> None:
    with pytest.raises(ScenarioError, match=r"loop = 'half': must be one of \('closed', 'open'\)"):
        SC.for_loop("half")
    with pytest.raises(ScenarioError, match=r"loop = 1"):
        SC.for_loop(1)  # type: ignore[arg-type]
    engage = load_scenario("engage-ramp", params=P)
    assert engage.loops == ("open",) and engage.for_loop("open") is engage
    with pytest.raises(
        ScenarioError, match=r"loop = 'closed': scenario 'engage-ramp' has no \[controller\] table"
    ):
        engage.for_loop("closed")
    closed_only = dataclasses.replace(
        SC, inputs=tuple((n, s) for n, s in SC.inputs if n != "pedal")
    )
    assert closed_only.loops == ("closed",)
    with pytest.raises(
        ScenarioError, match=r"loop = 'open': scenario 'paper-start' has no \[inputs.pedal\]"
    ):
        closed_only.for_loop("open")
    # an open-loop-only scenario still needs its pedal
    d = engage.to_dict()
    del d["inputs"]["pedal"]
    with pytest.raises(ScenarioError, match=r"inputs.pedal: missing"):
        scenario_from_dict(d)


def test_run_scenario_loop_choice() -> None:
    dt = SC.drivetrain(P, kind="reduced")
    with pytest.raises(ScenarioError, match=r"needs a controller.*loop='open'"):
        run_scenario(SC, dt)
    with pytest.raises(ScenarioError, match=r"loop = 'open'.*takes no controller.*'paper'"):
        run_scenario(SC, dt, controller="paper", loop="open", t_end=0.01)
    with pytest.raises(ScenarioError, match=r"loop = 'sideways'"):
        run_scenario(SC, dt, loop="sideways", t_end=0.01)
    engage = load_scenario("engage-ramp", params=P)
    with pytest.raises(ScenarioError, match=r"loop = 'closed'.*no \[controller\]"):
        run_scenario(
            engage, engage.drivetrain(P, kind="reduced"), controller="paper", loop="closed"
        )


def test_start_time_is_not_before_the_run() -> None:
    """Pedal knots before t = 0 (a release that began before the run) start the metrics at 0."""
    d = ENGAGE.to_dict()
    d["inputs"]["pedal"] = {"times": [-5.0, 1.0], "values": [0.11, 0.03]}
    assert scenario_from_dict(d).start_time == 0.0
    d["inputs"]["pedal"] = {"times": [-5.0, -1.0], "values": [0.11, 0.03]}
    assert scenario_from_dict(d).start_time == 0.0
    assert ENGAGE.start_time == 0.2


def test_load_scenario_takes_a_parameter_set_name_and_checks_types() -> None:
    assert load_scenario("paper-start", params="passenger-car") == SC
    with pytest.raises(ScenarioError, match="params = 5: give a DrivetrainParams"):
        load_scenario("paper-start", params=5)  # type: ignore[arg-type]
    with pytest.raises(ScenarioError, match="source = None: give a scenario name or a path"):
        load_scenario(None)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("path", "value", "match"),
    [
        (
            ("initial", "engine_speed_rpm"),
            -100.0,
            r"initial.engine_speed_rpm = -100.0: must be >= 0",
        ),
        (("initial", "throttle"), 5.0, r"initial.throttle = 5.0: must lie in \[0, 1\]"),
        (("slope_percent",), 1e300, r"slope_percent = 1e\+300: out of range"),
        (("name",), 5, "name = 5: must be a string"),
        (("description",), 5, "description = 5: must be a string"),
    ],
)
def test_scenario_file_errors_name_the_file_key(
    path: tuple[str, ...], value: object, match: str
) -> None:
    d = ENGAGE.to_dict()
    target = d
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    with pytest.raises(ScenarioError, match=match):
        scenario_from_dict(d)


# -- built-ins as TOML files; values resolved with the parameter set ----------------------------


def test_builtin_scenarios_are_the_files_in_scenarios_builtin() -> None:
    from drivetrain_ctrl.core.registry import builtin_files
    from drivetrain_ctrl.scenarios.scenario import BUILTIN_ORDER, builtin_scenarios

    files = builtin_files("drivetrain_ctrl.scenarios", order=BUILTIN_ORDER)
    sc = builtin_scenarios(P)
    assert list(sc) == list(files) and list(sc)[: len(BUILTIN_ORDER)] == list(BUILTIN_ORDER)
    for name, f in files.items():
        assert sc[name] == load_scenario(str(f), params=P)  # the same file through the loader


def test_paper_start_idle_throttle_follows_the_parameter_set() -> None:
    from drivetrain_ctrl.core.units import rpm_to_rad_s

    w_idle = float(rpm_to_rad_s(900.0))
    p2 = P.replace(**{"engine.c1": 15.0})
    for p in (P, p2):
        sc = load_scenario("paper-start", params=p)
        th0 = idle_throttle(p, w_idle)
        thr = dict(sc.inputs)["throttle"]
        assert sc.throttle0 == th0 and thr.values[:2] == (th0, th0)
        assert thr.values[2:] == (0.9, 0.9, 0.6) and thr.times == (0.0, 0.5, 0.5, 1.5, 1.6)
        assert f"(throttle {th0:.4f})" in sc.description
        assert sc.omega_engine0 == w_idle and sc.reference is not None
        assert sc.reference.values == (w_idle, w_idle, float(rpm_to_rad_s(1600.0)))
    assert load_scenario("paper-start", params=p2).throttle0 > SC.throttle0


@pytest.mark.parametrize(
    ("where", "value", "msg"),
    [
        ("initial", {"idle_rpm": -5.0}, r"initial\.throttle\.idle_rpm = -5\.0: must be a finite"),
        ("initial", {"idle_rpm": "900"}, r"initial\.throttle\.idle_rpm = '900'"),
        ("initial", {"idle_rmp": 900.0}, r"initial\.throttle = .*idle_rpm = <engine speed"),
        ("input", {"idle_rpm": float("nan")}, r"inputs\.throttle\.values\[0\]\.idle_rpm = nan"),
        ("initial", {"idle_rpm": 1.0e5}, r"initial\.throttle\.idle_rpm = 100000\.0: .*outside"),
    ],
)
def test_a_bad_idle_throttle_is_named(where: str, value: object, msg: str) -> None:
    d = SC.to_dict()
    if where == "initial":
        d["initial"]["throttle"] = value
    else:
        d["inputs"]["throttle"]["values"][0] = value
    with pytest.raises(ScenarioError, match=msg):
        scenario_from_dict(d, params=P)
