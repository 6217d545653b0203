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
    loop: str | None = None,
) -> SimulationResult:
    """Simulate ``scenario`` on drivetrain ``dt``; returns a :class:`SimulationResult`.

    ``loop``: ``"closed"`` (a controller drives the pedal to follow the scenario's engine-speed
    reference), ``"open"`` (the scenario's pedal signal drives it) or None: the scenario's own
    (:attr:`Scenario.loop`: closed if it has a ``[controller]`` table). ``controller``: see
    :meth:`Scenario.make_controller`; the closed loop needs one, the open loop takes none."""
    loops = scenario.loops
    scenario = scenario.for_loop(loop)
    if scenario.needs_controller and controller is None:
        names = ", ".join(repr(n) for n in builtin_controllers())
        alt = (
            "; or run its open-loop pedal: loop='open' (CLI: --loop open)"
            if "open" in loops
            else ""
        )
        raise ScenarioError(
            f"scenario {scenario.name!r} needs a controller (it gives the engine-speed reference, "
            f"not the pedal): pass controller={names} or a controller TOML file "
            f"(CLI: --controller){alt}"
        )
    if loop == "open" and controller is not None:
        raise ScenarioError(
            f"loop = 'open': scenario {scenario.name!r} runs its pedal signal; it takes no "
            f"controller (got controller = {getattr(controller, 'name', controller)!r})"
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
