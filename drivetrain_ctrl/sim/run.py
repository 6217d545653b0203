"""Running a manoeuvre: a :class:`~drivetrain_ctrl.scenarios.Scenario` on a drivetrain, open or
closed loop (scenarios are data; the simulator runs them)."""

from __future__ import annotations

from typing import Any

from ..control.laws import builtin_controllers
from ..plant.drivetrain import Drivetrain
from ..scenarios.scenario import Scenario, ScenarioError
from .simulator import SimulationResult, simulate

__all__ = ["run_scenario"]


def run_scenario(
    scenario: Scenario,
    dt: Drivetrain,
    *,
    controller: Any = None,
    options: Any = None,
    t_end: float | None = None,
) -> SimulationResult:
    """Simulate ``scenario`` on drivetrain ``dt``; returns a :class:`SimulationResult`.

    ``controller``: see :meth:`Scenario.make_controller`; a scenario that gives an engine-speed
    reference instead of the pedal (``paper-start``) needs one."""
    if scenario.needs_controller and controller is None:
        names = ", ".join(repr(n) for n in builtin_controllers())
        raise ScenarioError(
            f"scenario {scenario.name!r} needs a controller (it gives the engine-speed reference, "
            f"not the pedal): pass controller={names} or a controller TOML file "
            "(CLI: --controller)"
        )
    if controller is not None:
        scenario.check_pedal0(dt.params)
    ctrl = scenario.make_controller(dt, controller)
    return simulate(
        dt.model,
        scenario.initial_state(dt),
        scenario.input_signals(),
        t_end=scenario.t_end if t_end is None else t_end,
        options=options,
        controller=ctrl,
        controller_initial=scenario.pedal0 if ctrl is not None else 0.0,
    )
