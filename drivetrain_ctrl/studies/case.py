"""One run as data: a picklable :class:`Case` and the function that runs it.

A case names everything a run needs, by value or by name: the scenario (built-in name, TOML file
or :class:`~drivetrain_ctrl.scenarios.Scenario`), the parameter set (name, TOML file or
:class:`~drivetrain_ctrl.plant.params.DrivetrainParams`) with overrides by dotted parameter name,
the model kind, the controller (built-in name, TOML file or
:class:`~drivetrain_ctrl.control.laws.ControllerSpec`; None for open loop) and the integrator
tolerance. :func:`simulate_case` runs it and returns the result with its context;
:func:`run_case` returns only the flat record of metrics (what a study keeps per sample). The CLI,
the controller report and the studies all run cases through here, so a run means the same thing
everywhere.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..control.blocks import Controller
from ..control.laws import ControllerError, ControllerSpec, builtin_controllers, load_controller
from ..core.serialize import json_ready
from ..core.validate import is_finite_real, reject_unknown
from ..plant.drivetrain import Drivetrain
from ..plant.params import DEFAULT_SET, DrivetrainParams, load_params
from ..scenarios.scenario import Scenario, load_scenario
from ..sim.metrics import engagement_metrics
from ..sim.run import run_scenario
from ..sim.simulator import SimulationOptions, SimulationResult, ZenoError

__all__ = ["Case", "CaseError", "CaseRun", "MODELS", "simulate_case", "run_case"]

#: model kinds a case can run on
MODELS: tuple[str, ...] = ("full", "reduced")


class CaseError(ValueError):
    """A case that cannot run as given (the message names the field and the value)."""


@dataclass(frozen=True, kw_only=True)
class Case:
    """One closed- or open-loop run, as data (picklable; compares by value).

    scenario: built-in name, scenario TOML file or :class:`Scenario`.
    params: parameter set name (``"default"``), TOML file or :class:`DrivetrainParams`.
    overrides: ``{dotted parameter name: value}`` applied to ``params`` (SI units, e.g.
    ``{"clutch.static_ratio": 1.3, "vehicle.M_v": 1400.0}``); validated like a parameter set.
    model: ``"full"`` or ``"reduced"``.
    controller: built-in name, controller TOML file or :class:`ControllerSpec`; None: open loop.
    rtol: the integrator's relative tolerance (None: :class:`SimulationOptions`' default).
    t_end: end of the run [s] (None: the scenario's horizon).
    label: a free name carried into the record (e.g. a sample id).
    """

    scenario: str | Path | Scenario
    params: str | Path | DrivetrainParams = DEFAULT_SET
    overrides: Mapping[str, Any] = field(default_factory=dict)
    model: str = "full"
    controller: str | Path | ControllerSpec | None = None
    rtol: float | None = None
    t_end: float | None = None
    label: str = ""

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise CaseError(f"model = {self.model!r}: must be one of {MODELS}")
        if not isinstance(self.overrides, Mapping) or not all(
            isinstance(k, str) for k in self.overrides
        ):
            raise CaseError(
                f"overrides = {self.overrides!r}: must map dotted parameter names to values"
            )
        object.__setattr__(self, "overrides", dict(self.overrides))
        for name in ("rtol", "t_end"):
            v = getattr(self, name)
            if v is not None and not (is_finite_real(v) and v > 0):
                raise CaseError(f"{name} = {v!r}: must be a finite number > 0 (or None)")
        if not isinstance(self.label, str):
            raise CaseError(f"label = {self.label!r}: must be a string")

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Case:
        """A case from a mapping of its fields (e.g. a TOML table); unknown keys are an error."""
        reject_unknown("case.", d, [f for f in cls.__dataclass_fields__], error=CaseError)
        return cls(**d)


@dataclass(frozen=True)
class CaseRun:
    """A case that ran: its ``result``, the ``drivetrain``, ``scenario``, controller ``spec`` and
    the closed-loop ``controller`` built from it (both None in open loop), integrator ``options``, ``metrics``
    (:func:`~drivetrain_ctrl.sim.metrics.engagement_metrics`), the time spent loading the
    compiled kernels ``kernel_load_s`` [s] (0 unless preloaded) and the case itself."""

    case: Case
    result: SimulationResult
    drivetrain: Drivetrain
    scenario: Scenario
    spec: ControllerSpec | None
    controller: Controller | None
    options: SimulationOptions
    metrics: dict[str, Any]
    kernel_load_s: float

    def record(self) -> dict[str, Any]:
        """The flat record of this run: what ran (scenario, model, parameter set, controller name,
        tolerances, label, each override as ``param:<name>``) and every engagement metric;
        numbers rounded by :func:`~drivetrain_ctrl.core.serialize.json_ready`."""
        c = self.case
        out: dict[str, Any] = {
            "label": c.label,
            "scenario": self.scenario.name,
            "parameter_set": self.drivetrain.params.name,
            "controller": self.spec.name if self.spec is not None else None,
            "rtol": self.options.rtol,
            "atol": self.options.atol,
            **{f"param:{k}": v for k, v in sorted(c.overrides.items())},
            **self.metrics,
        }
        return dict(json_ready(out))


def _params(case: Case) -> DrivetrainParams:
    p = case.params
    if not isinstance(p, DrivetrainParams):
        if isinstance(p, bool) or not isinstance(p, str | Path):
            raise CaseError(f"params = {p!r}: give a parameter set name, TOML file or params")
        p = load_params(p)
    return p.replace(**case.overrides) if case.overrides else p


def _spec(case: Case, scenario: Scenario) -> ControllerSpec | None:
    if case.controller is None:
        if scenario.needs_controller:
            names = "|".join(builtin_controllers())
            raise CaseError(
                f"scenario {scenario.name!r} needs a controller (it gives the engine-speed "
                f"reference, not the pedal): controller = {names}|FILE.toml"
            )
        return None
    if not scenario.needs_controller:
        raise CaseError(
            f"controller = {case.controller!r}: scenario {scenario.name!r} is open loop (it gives "
            "the pedal signal); drop the controller or use a closed-loop scenario (paper-start)"
        )
    try:
        return load_controller(case.controller)
    except ControllerError as exc:
        raise CaseError(f"controller: {exc}") from None


def simulate_case(case: Case, *, preload: bool = False) -> CaseRun:
    """Run ``case`` on the switching plant; returns a :class:`CaseRun`.

    ``preload``: first run 1 ms of the same model, so that the kernels are loaded from numba's
    cache (or compiled) before the timed run; its time is ``kernel_load_s`` and the result's
    ``stats["wall_time_s"]`` is the simulation's own time.

    Raises :class:`CaseError` for input the case cannot run with (unknown scenario, parameter or
    controller, a horizon that ends before the start command, an input outside the model's
    range), and :class:`~drivetrain_ctrl.sim.simulator.ZenoError` or RuntimeError when the
    simulation itself fails.
    """
    if not isinstance(case, Case):
        raise TypeError(f"case: a Case is needed, got {type(case).__name__}")
    if not isinstance(preload, bool):
        raise TypeError(f"preload = {preload!r}: must be True or False")
    try:
        params = _params(case)
        scenario = load_scenario(case.scenario, params=params)
        options = SimulationOptions() if case.rtol is None else SimulationOptions(rtol=case.rtol)
    except FileNotFoundError as exc:
        raise CaseError(f"file not found: {exc.filename or exc}") from None
    except (ValueError, OSError) as exc:
        raise CaseError(str(exc)) from None
    try:
        t_stop = scenario.check_horizon(case.t_end)
        dt = scenario.drivetrain(params, kind=case.model)
        scenario.initial_state(dt)  # validates the initial state for this model
    except ValueError as exc:
        raise CaseError(f"scenario {scenario.name!r}: {exc}") from None
    spec = _spec(case, scenario)
    try:
        ctrl = scenario.make_controller(dt, spec)  # built once: warnings once, one object
        load_s = 0.0
        if preload:
            tic = time.perf_counter()
            with contextlib.suppress(ZenoError, RuntimeError):  # the real run reports them
                run_scenario(
                    scenario, dt, controller=ctrl, options=options, t_end=min(t_stop, 1e-3)
                )
            load_s = time.perf_counter() - tic
        res = run_scenario(scenario, dt, controller=ctrl, options=options, t_end=t_stop)
    except (ZenoError, RuntimeError):
        raise
    except ValueError as exc:  # controller, scenario or input-range errors (all ValueErrors)
        raise CaseError(f"scenario {scenario.name!r}: {exc}") from None
    metrics = engagement_metrics(res, dt, start=scenario.start_time, reference=scenario.reference)
    return CaseRun(case, res, dt, scenario, spec, ctrl, options, metrics, load_s)


def run_case(case: Case) -> dict[str, Any]:
    """The flat record of ``case`` (:meth:`CaseRun.record`): one picklable function from a case
    to a record, for batch work. A run the simulator cannot finish (Zeno, step too small) is a
    record with ``status = "failed"`` and ``error`` (nothing is lost); invalid input raises
    :class:`CaseError`."""
    try:
        return simulate_case(case).record()
    except (ZenoError, RuntimeError) as exc:
        return {
            "label": case.label,
            "scenario": str(getattr(case.scenario, "name", case.scenario)),
            "parameter_set": str(getattr(case.params, "name", case.params)),
            "controller": (
                None
                if case.controller is None
                else str(getattr(case.controller, "name", case.controller))
            ),
            "model": case.model,
            **{f"param:{k}": v for k, v in sorted(case.overrides.items())},
            "status": "failed",
            "error": str(exc),
        }
