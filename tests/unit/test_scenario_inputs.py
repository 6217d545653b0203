"""Input checks of scenarios (:mod:`drivetrain_ctrl.scenarios`) that need no simulation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drivetrain_ctrl.params import default_params
from drivetrain_ctrl.scenarios import (
    ScenarioError,
    idle_throttle,
    load_scenario,
    scenario_from_dict,
)

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
        sc.run(dt, controller="paper")
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
