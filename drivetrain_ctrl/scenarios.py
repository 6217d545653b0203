"""Manoeuvres: engaged gear, road slope, initial state and input signals.

A scenario file (TOML) looks like this (rpm, km/h and percent only here, at the edge; SI inside)::

    name = "engage-ramp"
    description = "..."
    gear = 1
    slope_percent = 0.0          # road grade, 100 * tan(slope)
    t_end = 3.0                  # [s]

    [initial]
    engine_speed_rpm = 1900.0    # ignored when clutch_locked = true
    clutch_locked = false        # true: engine at the speed of the primary shaft
    vehicle_speed_kmh = 0.0
    throttle = 0.5               # engine lag state [-]
    twist_torque = 0.0           # driveline preload [N m, primary shaft]; < 0: coasting

    [inputs.throttle]            # theta [-]
    times = [0.0]
    values = [0.5]
    [inputs.pedal]               # x_c [m]
    times = [0.2, 2.2]
    values = [0.11, 0.03]
    [inputs.brake]               # service-brake capacity [N m at the wheels]
    times = [0.0]
    values = [0.0]

Unknown keys are errors naming the key.
"""

from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .drivetrain import INPUTS, Drivetrain
from .params import DrivetrainParams
from .signals import Signal, constant, ramp, step
from .units import kmh_to_m_s, rpm_to_rad_s

__all__ = ["Scenario", "builtin_scenarios", "load_scenario", "ScenarioError", "CONTROLLERS"]

#: closed-loop controllers a scenario can name
CONTROLLERS: tuple[str, ...] = ("law6",)


class ScenarioError(ValueError):
    """A scenario file or argument is invalid (the message names the field)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Scenario:
    """A manoeuvre. Units: slope [rad], t_end [s], engine speed [rad/s], vehicle speed [m/s],
    twist torque [N m, primary shaft]; inputs: throttle [-], pedal [m], brake [N m]."""

    name: str
    description: str
    gear: int
    slope: float
    t_end: float
    omega_engine0: float
    v_vehicle0: float
    throttle0: float
    twist_torque0: float
    inputs: tuple[tuple[str, Signal], ...]
    clutch_locked0: bool = False
    controller: str | None = None
    reference: Signal | None = None
    pedal0: float = 0.11

    def __post_init__(self) -> None:
        if not (
            isinstance(self.t_end, (int, float)) and math.isfinite(self.t_end) and self.t_end > 0
        ):
            raise ScenarioError(
                f"{self.name}: t_end = {self.t_end!r}: must be a finite number > 0 [s]"
            )
        if not math.isfinite(self.slope) or abs(self.slope) >= math.pi / 2:
            raise ScenarioError(f"{self.name}: slope = {self.slope!r} rad out of range")
        for nm in ("omega_engine0", "v_vehicle0", "throttle0", "twist_torque0"):
            v = getattr(self, nm)
            if not math.isfinite(v):
                raise ScenarioError(f"{self.name}: {nm} = {v!r}: must be finite")
        names = [n for n, _ in self.inputs]
        unknown = set(names) - set(INPUTS)
        if unknown:
            raise ScenarioError(
                f"{self.name}: unknown input(s) {sorted(unknown)}; inputs: {INPUTS}"
            )
        needed = set(INPUTS) - ({"pedal"} if self.controller else set())
        missing = needed - set(names)
        if missing:
            raise ScenarioError(f"{self.name}: missing input(s) {sorted(missing)}")
        if self.controller is not None:
            if self.controller not in CONTROLLERS:
                raise ScenarioError(
                    f"{self.name}: controller = {self.controller!r}: known controllers {CONTROLLERS}"
                )
            if "pedal" in names:
                raise ScenarioError(
                    f"{self.name}: inputs.pedal is driven by the controller; remove it"
                )
            if self.reference is None:
                raise ScenarioError(
                    f"{self.name}: controller {self.controller!r} needs a reference"
                )

    def input_signals(self) -> dict[str, Signal]:
        return dict(self.inputs)

    def make_controller(self, dt: Drivetrain) -> Any:
        """The closed-loop controller of this scenario for drivetrain ``dt`` (None: open loop)."""
        if self.controller is None:
            return None
        from .closedloop import law6_controller

        assert self.reference is not None
        driven = "omega_disc" if dt.kind == "full" else "omega_primary"
        return law6_controller(dt.params, reference=self.reference, driven_state=driven)

    def run(self, dt: Drivetrain, *, options: Any = None, t_end: float | None = None) -> Any:
        """Simulate this scenario on ``dt`` (open or closed loop); returns a SimulationResult."""
        from .simulate import simulate

        return simulate(
            dt.model,
            self.initial_state(dt),
            self.input_signals(),
            t_end=self.t_end if t_end is None else t_end,
            options=options,
            controller=self.make_controller(dt),
            controller_initial=self.pedal0,
        )

    def drivetrain(self, params: DrivetrainParams, *, kind: str = "full") -> Drivetrain:
        """The drivetrain of this scenario (its gear and slope) from ``params``."""
        return Drivetrain(params, kind=kind, gear=self.gear, slope=self.slope)

    def initial_state(self, dt: Drivetrain) -> NDArray[np.float64]:
        """Initial state of this scenario for drivetrain ``dt``."""
        w_eng = self.omega_engine0
        if self.clutch_locked0:
            w_eng = dt.vehicle_speed_to_primary(self.v_vehicle0)
        return dt.rigid_state(
            omega_engine=w_eng,
            v_vehicle=self.v_vehicle0,
            throttle=self.throttle0,
            twist_torque=self.twist_torque0,
        )

    def to_dict(self) -> dict[str, Any]:
        """TOML-ready form (rpm, km/h, percent)."""
        return {
            "name": self.name,
            "description": self.description,
            "gear": self.gear,
            "slope_percent": 100.0 * math.tan(self.slope),
            "t_end": self.t_end,
            "initial": {
                "engine_speed_rpm": self.omega_engine0 * 60.0 / (2 * math.pi),
                "vehicle_speed_kmh": self.v_vehicle0 * 3.6,
                "throttle": self.throttle0,
                "twist_torque": self.twist_torque0,
                "clutch_locked": self.clutch_locked0,
            },
            "inputs": {n: s.to_dict() for n, s in self.inputs},
            **(
                {
                    "controller": {
                        "law": self.controller,
                        "reference_rpm": (self.reference * (30.0 / math.pi)).to_dict(),
                        "pedal0": self.pedal0,
                    }
                }
                if self.controller is not None and self.reference is not None
                else {}
            ),
        }


_TOP = {"name", "description", "gear", "slope_percent", "t_end", "initial", "inputs", "controller"}
_CONTROLLER = {"law", "reference_rpm", "pedal0"}
_INITIAL = {"engine_speed_rpm", "vehicle_speed_kmh", "throttle", "twist_torque", "clutch_locked"}


def _reject_unknown(where: str, got: set[str], allowed: set[str]) -> None:
    for k in sorted(got - allowed):
        close = difflib.get_close_matches(k, sorted(allowed), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else f"; allowed: {sorted(allowed)}"
        raise ScenarioError(f"{where}{k}: unknown key{hint}")


def _num(where: str, d: dict[str, Any], key: str) -> float:
    if key not in d:
        raise ScenarioError(f"{where}{key}: missing")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScenarioError(f"{where}{key} = {v!r}: must be a finite number")
    return float(v)


def scenario_from_dict(d: dict[str, Any]) -> Scenario:
    """Build a :class:`Scenario` from its TOML form (see the module docstring)."""
    _reject_unknown("", set(d), _TOP)
    name = str(d.get("name", "scenario"))
    ini = d.get("initial", {})
    if not isinstance(ini, dict):
        raise ScenarioError("initial: must be a table")
    _reject_unknown("initial.", set(ini), _INITIAL)
    gear = d.get("gear", 1)
    if isinstance(gear, bool) or not isinstance(gear, int):
        raise ScenarioError(f"gear = {gear!r}: must be an integer")
    inputs = d.get("inputs", {})
    if not isinstance(inputs, dict):
        raise ScenarioError("inputs: must be a table of signals")
    _reject_unknown("inputs.", set(inputs), set(INPUTS))
    locked = ini.get("clutch_locked", False)
    if not isinstance(locked, bool):
        raise ScenarioError(f"initial.clutch_locked = {locked!r}: must be true or false")
    ctl = d.get("controller")
    law: str | None = None
    reference: Signal | None = None
    pedal0 = 0.11
    if ctl is not None:
        if not isinstance(ctl, dict):
            raise ScenarioError("controller: must be a table")
        _reject_unknown("controller.", set(ctl), _CONTROLLER)
        law = str(ctl.get("law", ""))
        if "reference_rpm" not in ctl:
            raise ScenarioError("controller.reference_rpm: missing")
        try:
            reference = Signal.from_dict(ctl["reference_rpm"], name="controller.reference_rpm") * (
                math.pi / 30.0
            )
        except (TypeError, ValueError) as exc:
            raise ScenarioError(str(exc)) from exc
        if "pedal0" in ctl:
            pedal0 = _num("controller.", ctl, "pedal0")
    sigs = []
    for n in INPUTS:
        if n == "pedal" and law is not None:
            continue
        if n not in inputs:
            raise ScenarioError(f"inputs.{n}: missing")
        try:
            sigs.append((n, Signal.from_dict(inputs[n], name=f"inputs.{n}")))
        except (TypeError, ValueError) as exc:
            raise ScenarioError(str(exc)) from exc
    return Scenario(
        name=name,
        description=str(d.get("description", "")),
        gear=gear,
        slope=math.atan(_num("", d, "slope_percent") / 100.0) if "slope_percent" in d else 0.0,
        t_end=_num("", d, "t_end"),
        omega_engine0=float(rpm_to_rad_s(_num("initial.", ini, "engine_speed_rpm")))
        if not locked
        else 0.0,
        clutch_locked0=locked,
        v_vehicle0=float(kmh_to_m_s(_num("initial.", ini, "vehicle_speed_kmh"))),
        throttle0=_num("initial.", ini, "throttle"),
        twist_torque0=float(ini.get("twist_torque", 0.0)),
        inputs=tuple(sigs),
        controller=law,
        reference=reference,
        pedal0=pedal0,
    )


def builtin_scenarios() -> dict[str, Scenario]:
    """The built-in scenarios: ``engage-ramp`` and ``tip-in``."""
    engage = Scenario(
        name="engage-ramp",
        description=(
            "Vehicle at rest, first gear, engine at constant throttle 0.5 and 1900 rpm; the clutch "
            "pedal is released on a ramp from fully open (0.11 m) to fully engaged (0.03 m) "
            "between 0.2 s and 2.2 s, until lock-up."
        ),
        gear=1,
        slope=0.0,
        t_end=3.0,
        omega_engine0=float(rpm_to_rad_s(1900.0)),
        v_vehicle0=0.0,
        throttle0=0.5,
        twist_torque0=0.0,
        inputs=(
            ("throttle", constant(0.5)),
            ("pedal", ramp(0.2, 2.2, 0.11, 0.03)),
            ("brake", constant(0.0)),
        ),
    )
    tip = Scenario(
        name="tip-in",
        description=(
            "Clutch locked, first gear, coasting at 15 km/h with the throttle closed (engine "
            "braking: backlash in negative contact); throttle step to 0.6 at 0.5 s: the gap is "
            "crossed and the driveline shuffles."
        ),
        gear=1,
        slope=0.0,
        t_end=3.0,
        omega_engine0=0.0,
        clutch_locked0=True,
        v_vehicle0=float(kmh_to_m_s(15.0)),
        throttle0=0.0,
        twist_torque0=-13.0,
        inputs=(
            ("throttle", step(0.5, 0.6)),
            ("pedal", constant(0.03)),
            ("brake", constant(0.0)),
        ),
    )
    paper = Scenario(
        name="paper-start",
        description=(
            "The paper's start (Section IV, Fig. 14) under control law (6): vehicle at rest, "
            "engine idling at 1000 rpm, clutch open; at 0.5 s the engine-speed reference rises to "
            "1600 rpm and the throttle opens; at 1.5 s the driver reduces the engine torque; the "
            "law keeps the engine on the reference until lock-up, then the clutch is closed."
        ),
        gear=1,
        slope=0.0,
        t_end=3.5,
        omega_engine0=float(rpm_to_rad_s(1000.0)),
        v_vehicle0=0.0,
        throttle0=0.2,
        twist_torque0=0.0,
        inputs=(
            ("throttle", constant(0.2) + step(0.5, 0.5) + step(1.5, -0.2)),
            ("brake", constant(0.0)),
        ),
        controller="law6",
        reference=constant(float(rpm_to_rad_s(1000.0))) + step(0.5, float(rpm_to_rad_s(600.0))),
        pedal0=0.11,
    )
    return {engage.name: engage, tip.name: tip, paper.name: paper}


def load_scenario(source: str | Path) -> Scenario:
    """A built-in scenario by name, or a scenario TOML file."""
    b = builtin_scenarios()
    if isinstance(source, str) and source in b:
        return b[source]
    p = Path(source)
    if not p.suffix == ".toml" or not p.exists():
        close = difflib.get_close_matches(str(source), sorted(b), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ScenarioError(
            f"scenario {str(source)!r}: not a built-in scenario ({sorted(b)}) "
            f"nor an existing .toml file{hint}"
        )
    with p.open("rb") as fh:
        try:
            d = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise ScenarioError(f"{p}: invalid TOML: {exc}") from exc
    try:
        return scenario_from_dict(d)
    except ScenarioError as exc:
        raise ScenarioError(f"{exc} (in {p})") from None
