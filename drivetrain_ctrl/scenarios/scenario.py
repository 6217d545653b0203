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

A value that depends on the parameter set: ``{ idle_rpm = 900.0 }`` in place of ``initial.throttle``
or of a value of ``inputs.throttle`` is the throttle that holds the free engine (clutch open) at
900 rpm (:func:`idle_throttle`), resolved when the file is loaded for a parameter set (the default
set if none is given). ``{throttle0}`` in ``description`` is replaced by the initial throttle (4
decimals).

A scenario may change the parameter set it runs on: a ``[params]`` table laid out like a parameter
file (``[params.clutch]``, ``[params.vehicle]``, ...; SI units, keys the fields of
:mod:`drivetrain_ctrl.plant.params`), each value a number (or a table ``{ x = [...], y = [...] }``
for a table field) that replaces the set's, or ``{ scale = f }``: the set's value times ``f`` (a
worn clutch: ``k12_max = { scale = 0.7 }``). The overrides are applied by
:meth:`Scenario.params_for` (and so by :meth:`Scenario.drivetrain`) to whatever set the scenario
runs on, and validated like a parameter set when the file is loaded (an unknown field or a bad
value is a ScenarioError naming ``params.<section>.<field>`` and the value).

A closed-loop scenario has a ``[controller]`` table: the engine-speed reference
``reference_rpm`` (a signal table, rpm), the controller's output before it starts ``pedal0`` [m]
and its start time ``start_s`` [s]. An open-loop scenario has ``[inputs.pedal]`` instead: the
pedal (actuator position x_c) a driver would give. A scenario may have both: then it runs either
way, one run at a time (the *loop*, :data:`LOOPS`): ``"closed"``, the controller drives the pedal
and ``[inputs.pedal]`` is not used; ``"open"``, the pedal signal drives it and the ``[controller]``
table is not used. A scenario's own loop, when none is chosen, is ``"closed"`` if it has a
``[controller]`` table, else ``"open"`` (:attr:`Scenario.loop`); :meth:`Scenario.for_loop` gives
the scenario as one loop runs it.

The built-in scenarios (:func:`builtin_scenarios`) are such files, shipped in
``scenarios/builtin/``: ``engage-ramp`` and ``tip-in`` (open loop), ``paper-start`` and the
harder starts ``hill-start``, ``worn-clutch``, ``judder``, ``heavy-load`` and ``tip-out-reengage``
(both loops: a controller and a driver's pedal). Each file's header says what it tests and why
its pedal has the shape it has.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..control.blocks import Controller
from ..control.laws import load_controller
from ..core.registry import builtin_files, load_builtin_or_toml, load_toml_as
from ..core.signals import Signal
from ..core.units import (
    RAD_S_TO_RPM,
    RPM_TO_RAD_S,
    kmh_to_m_s,
    m_s_to_kmh,
    rad_s_to_rpm,
    rpm_to_rad_s,
)
from ..core.validate import ParameterError, is_finite_real, real_number, reject_unknown
from ..plant.drivetrain import INPUTS, Drivetrain
from ..plant.params import DrivetrainParams, default_params, load_params

__all__ = [
    "LOOPS",
    "Scenario",
    "builtin_scenarios",
    "load_scenario",
    "ScenarioError",
    "idle_throttle",
]

#: the loops a scenario can run in: the controller drives the pedal, or the pedal signal does
LOOPS: tuple[str, ...] = ("closed", "open")


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
    reference: Signal | None = None
    control_start: float | None = None
    pedal0: float = 0.11
    #: parameter overrides ``(dotted path, value)``: a number, a table ``{"x": ..., "y": ...}``
    #: or ``{"scale": f}`` (the base set's value times f); see :meth:`params_for`
    param_overrides: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ScenarioError(f"name = {self.name!r}: must be a non-empty string")
        if not isinstance(self.description, str):
            raise ScenarioError(
                f"{self.name}: description = {self.description!r}: must be a string"
            )
        if isinstance(self.gear, bool) or not isinstance(self.gear, (int, np.integer)):
            raise ScenarioError(f"{self.name}: gear = {self.gear!r}: must be an integer")
        for nm in ("slope", "omega_engine0", "v_vehicle0", "throttle0", "twist_torque0", "pedal0"):
            v = getattr(self, nm)
            if not is_finite_real(v):
                raise ScenarioError(f"{self.name}: {nm} = {v!r}: must be a finite number")
        if not isinstance(self.clutch_locked0, bool):
            raise ScenarioError(
                f"{self.name}: clutch_locked0 = {self.clutch_locked0!r}: must be True or False"
            )
        if not 0.0 <= self.throttle0 <= 1.0:
            raise ScenarioError(
                f"{self.name}: throttle0 = {self.throttle0!r}: the engine's throttle (lag) state "
                "must lie in [0, 1]"
            )
        if self.omega_engine0 < 0.0:
            raise ScenarioError(
                f"{self.name}: omega_engine0 = {self.omega_engine0!r} [rad/s]: must be >= 0 (the "
                "engine does not run backwards)"
            )
        if not isinstance(self.inputs, tuple) or not all(
            isinstance(it, tuple)
            and len(it) == 2
            and isinstance(it[0], str)
            and isinstance(it[1], Signal)
            for it in self.inputs
        ):
            raise ScenarioError(
                f"{self.name}: inputs = {self.inputs!r}: must be a tuple of (name, Signal) pairs"
            )
        if self.reference is not None and not isinstance(self.reference, Signal):
            raise ScenarioError(
                f"{self.name}: reference = {self.reference!r}: must be a Signal [rad/s] or None"
            )
        if self.control_start is not None and not is_finite_real(self.control_start):
            raise ScenarioError(
                f"{self.name}: control_start = {self.control_start!r}: must be a finite number "
                "[s] or None"
            )
        if not (is_finite_real(self.t_end) and self.t_end > 0):
            raise ScenarioError(
                f"{self.name}: t_end = {self.t_end!r}: must be a finite number > 0 [s]"
            )
        if abs(self.slope) >= math.pi / 2:
            raise ScenarioError(f"{self.name}: slope = {self.slope!r} rad out of range")
        names = [n for n, _ in self.inputs]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ScenarioError(f"{self.name}: input(s) {dup} given more than once")
        unknown = set(names) - set(INPUTS)
        if unknown:
            raise ScenarioError(
                f"{self.name}: unknown input(s) {sorted(unknown)}; inputs: {INPUTS}"
            )
        needed = set(INPUTS) - ({"pedal"} if self.needs_controller else set())
        missing = needed - set(names)
        if missing:
            raise ScenarioError(f"{self.name}: missing input(s) {sorted(missing)}")
        if self.control_start is not None:
            cs = self.control_start
            if not (math.isfinite(cs) and 0.0 <= cs < self.t_end):
                raise ScenarioError(
                    f"{self.name}: controller.start_s = {cs!r}: must be in [0, t_end = "
                    f"{self.t_end}) s"
                )
            if self.reference is None:
                raise ScenarioError(f"{self.name}: controller.start_s needs a reference_rpm")
        if self.reference is not None:
            (vmin, tmin), _ = self.reference.extremes(0.0, self.t_end)
            if vmin < 0.0:
                raise ScenarioError(
                    f"{self.name}: controller.reference_rpm = {vmin * RAD_S_TO_RPM:.6g} rpm at "
                    f"t = {tmin:g} s: an engine-speed reference must be >= 0"
                )
        if not (math.isfinite(self.pedal0) and 0.0 <= self.pedal0 <= 0.5):
            raise ScenarioError(f"{self.name}: pedal0 = {self.pedal0!r} [m]: out of range [0, 0.5]")
        if not isinstance(self.param_overrides, tuple) or not all(
            isinstance(it, tuple) and len(it) == 2 and isinstance(it[0], str)
            for it in self.param_overrides
        ):
            raise ScenarioError(
                f"{self.name}: param_overrides = {self.param_overrides!r}: must be a tuple of "
                "(dotted parameter path, value) pairs"
            )

    def params_for(self, params: DrivetrainParams) -> DrivetrainParams:
        """``params`` with this scenario's parameter overrides applied (``params`` itself if it
        has none), validated like a parameter set: ScenarioError naming ``params.<path>`` and the
        value otherwise. A ``{"scale": f}`` value multiplies the value of ``params``."""
        if not self.param_overrides:
            return params
        changes: dict[str, Any] = {}
        for path, value in self.param_overrides:
            where = f"{self.name}: params.{path}"
            try:
                old = params.get(path)
            except ParameterError as exc:
                raise ScenarioError(f"{where}: {exc}") from None
            if isinstance(value, dict) and "scale" in value:
                f = value["scale"]
                if set(value) != {"scale"} or not (is_finite_real(f) and f > 0):
                    raise ScenarioError(
                        f"{where} = {value!r}: a scale must be {{ scale = <number > 0> }}"
                    )
                if isinstance(old, bool) or not is_finite_real(old):
                    raise ScenarioError(
                        f"{where} = {value!r}: only a number can be scaled (the set's value is "
                        f"{old!r})"
                    )
                value = float(old) * float(f)
            changes[path] = value
        changes["name"] = f"{params.name} + scenario {self.name}"
        try:
            return params.with_values(changes)
        except (ParameterError, TypeError, ValueError) as exc:
            raise ScenarioError(f"{self.name}: params: {exc}") from None

    @property
    def start_time(self) -> float:
        """The start command [s]: the controller's start time; for an open-loop scenario the
        first breakpoint of the pedal signal (start of the pedal release), or 0 (the run's start)
        if that lies before; else 0."""
        if self.control_start is not None:
            return float(self.control_start)
        sig = dict(self.inputs).get("pedal")
        if sig is not None and sig.breakpoints:
            return max(0.0, float(sig.breakpoints[0]))
        return 0.0

    def check_horizon(self, t_end: float | None = None, *, arg: str = "t_end") -> float:
        """The run's end [s]: ``t_end``, or this scenario's horizon if None. ScenarioError naming
        ``arg`` (e.g. ``"--t-end"`` on the command line) if it is not a finite number > 0 or ends
        before the start command (the metrics measure from there)."""
        t_stop = self.t_end if t_end is None else t_end
        if not (is_finite_real(t_stop) and t_stop > 0):
            raise ScenarioError(f"{arg} = {t_stop!r}: must be a finite number > 0 [s]")
        if self.start_time > t_stop:
            what = (
                f"{arg} = {t_stop!r}: the run would end"
                if t_end is not None
                else f"scenario {self.name!r}: t_end = {t_stop!r} s ends"
            )
            cmd = "controller.start_s" if self.control_start is not None else "the first pedal knot"
            raise ScenarioError(
                f"{what} before the start command of scenario {self.name!r} at "
                f"{self.start_time:g} s ({cmd}; the metrics measure from there)"
            )
        return float(t_stop)

    @property
    def needs_controller(self) -> bool:
        """True if the scenario's own loop (:attr:`loop`) is closed: a controller drives the pedal
        to follow the engine-speed reference (the scenario may also give an open-loop pedal,
        used with ``loop="open"``)."""
        return self.reference is not None

    @property
    def loops(self) -> tuple[str, ...]:
        """The loops (:data:`LOOPS`) this scenario can run in: ``"closed"`` if it has an
        engine-speed reference (``[controller]``), ``"open"`` if it has a pedal signal
        (``[inputs.pedal]``)."""
        has = {"closed": self.reference is not None, "open": "pedal" in dict(self.inputs)}
        return tuple(k for k in LOOPS if has[k])

    @property
    def loop(self) -> str:
        """The scenario's own loop, run when none is chosen: ``"closed"`` if it has a
        ``[controller]`` table, else ``"open"``."""
        return "closed" if self.reference is not None else "open"

    def for_loop(self, loop: str | None) -> Scenario:
        """This scenario as ``loop`` (``"closed"``, ``"open"``; None: its own, :attr:`loop`)
        runs it: ``"open"`` drops the controller part (reference, start time), ``"closed"`` the
        pedal signal; ``self`` if there is nothing to drop. ScenarioError naming ``loop`` and its
        value if it is not one of :data:`LOOPS`, or if the scenario lacks the part that loop
        needs."""
        if loop is None:
            loop = self.loop
        if not isinstance(loop, str) or loop not in LOOPS:
            raise ScenarioError(
                f"loop = {loop!r}: must be one of {LOOPS} (or None: the scenario's own)"
            )
        if loop not in self.loops:
            part = (
                "no [controller] table (an engine-speed reference for the controller to follow)"
                if loop == "closed"
                else "no [inputs.pedal] signal (the pedal a driver would give)"
            )
            raise ScenarioError(
                f"loop = {loop!r}: scenario {self.name!r} has {part}; it runs in loop "
                f"{' or '.join(repr(k) for k in self.loops)}"
            )
        if loop == "open":
            if self.reference is None:
                return self
            return dataclasses.replace(self, reference=None, control_start=None)
        if "pedal" not in dict(self.inputs):
            return self
        return dataclasses.replace(
            self, inputs=tuple((n, s) for n, s in self.inputs if n != "pedal")
        )

    def input_signals(self) -> dict[str, Signal]:
        """The input signals by name, as the scenario's own loop uses them: a closed-loop
        scenario's pedal signal (its open-loop part) left out (the controller drives the
        pedal)."""
        return {n: s for n, s in self.inputs if not (n == "pedal" and self.needs_controller)}

    def check_pedal0(self, params: DrivetrainParams) -> None:
        """Raise :class:`ScenarioError` unless ``pedal0`` (the controller's initial output [m])
        lies within the actuator stroke ``[actuator.x_min, actuator.x_max]`` of ``params``."""
        msg = params.actuator.outside_stroke("controller.pedal0", self.pedal0)
        if msg:
            raise ScenarioError(f"{self.name}: {msg} of parameter set {params.name!r}")

    def make_controller(self, dt: Drivetrain, controller: Any) -> Any:
        """The closed-loop :class:`~drivetrain_ctrl.control.blocks.Controller` of this scenario on
        drivetrain ``dt`` from ``controller``: a built-in name (``paper``, ``pi``, ...), a
        controller TOML file, a :class:`~drivetrain_ctrl.control.laws.ControllerSpec`, or a ready
        ``Controller`` (returned as is). ``None`` gives None (open loop)."""
        if controller is None:
            return None
        if isinstance(controller, Controller):
            return controller
        if self.reference is None:
            raise ScenarioError(
                f"scenario {self.name!r} is open loop here (it gives the pedal signal, no "
                "engine-speed reference); it takes no controller"
            )
        spec = load_controller(controller)
        return spec.build(dt.params, reference=self.reference, start_time=self.control_start)

    def drivetrain(self, params: DrivetrainParams, *, kind: str = "full") -> Drivetrain:
        """The drivetrain of this scenario (its gear and slope) from ``params`` with the
        scenario's parameter overrides applied (:meth:`params_for`)."""
        return Drivetrain(self.params_for(params), kind=kind, gear=self.gear, slope=self.slope)

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
                "engine_speed_rpm": rad_s_to_rpm(self.omega_engine0),
                "vehicle_speed_kmh": m_s_to_kmh(self.v_vehicle0),
                "throttle": self.throttle0,
                "twist_torque": self.twist_torque0,
                "clutch_locked": self.clutch_locked0,
            },
            "inputs": {n: s.to_dict() for n, s in self.inputs},
            **(
                {
                    "controller": {
                        "reference_rpm": (self.reference * RAD_S_TO_RPM).to_dict(),
                        "pedal0": self.pedal0,
                        **(
                            {"start_s": self.control_start}
                            if self.control_start is not None
                            else {}
                        ),
                    }
                }
                if self.reference is not None
                else {}
            ),
            **({"params": _nest_overrides(self.param_overrides)} if self.param_overrides else {}),
        }


def _nest_overrides(overrides: tuple[tuple[str, Any], ...]) -> dict[str, Any]:
    """``{"clutch.k12_max": v}`` pairs -> ``{"clutch": {"k12_max": v}}`` (the TOML layout)."""
    out: dict[str, Any] = {}
    for path, value in overrides:
        section, _, name = path.partition(".")
        out.setdefault(section, {})[name] = value
    return out


def _param_overrides(d: Any) -> tuple[tuple[str, Any], ...]:
    """The ``[params]`` table -> ``(dotted path, value)`` pairs (sections and fields in the file's
    order); its shape checked here, its values by :meth:`Scenario.params_for`."""
    if not isinstance(d, dict):
        raise ScenarioError(f"params = {d!r}: must be a table of parameter sections")
    out = []
    for section, fields_ in d.items():
        if not isinstance(fields_, dict):
            raise ScenarioError(
                f"params.{section} = {fields_!r}: must be a table (a parameter section, e.g. "
                "[params.clutch])"
            )
        for name, value in fields_.items():
            out.append((f"{section}.{name}", value))
    return tuple(out)


_TOP = {
    "name",
    "description",
    "gear",
    "slope_percent",
    "t_end",
    "initial",
    "inputs",
    "controller",
    "params",
}
_CONTROLLER = {"reference_rpm", "pedal0", "start_s"}
_INITIAL = {"engine_speed_rpm", "vehicle_speed_kmh", "throttle", "twist_torque", "clutch_locked"}


def _reject_unknown(where: str, got: set[str], allowed: set[str]) -> None:
    reject_unknown(where, got, allowed, error=ScenarioError)


def _num(where: str, d: dict[str, Any], key: str) -> float:
    if key not in d:
        raise ScenarioError(f"{where}{key}: missing")
    return real_number(f"{where}{key}", d[key], error=ScenarioError)


def _resolve_idle(d: dict[str, Any], params: DrivetrainParams | None) -> dict[str, Any]:
    """``d`` with each ``{idle_rpm = n}`` (in ``initial.throttle`` and in the values of
    ``inputs.throttle``) replaced by the throttle that holds the free engine of ``params`` (the
    default set if None) at ``n`` rpm; ``d`` itself is left as it is."""
    cache: dict[float, float] = {}

    def resolve(where: str, v: Any) -> Any:
        if not isinstance(v, dict):
            return v
        if set(v) != {"idle_rpm"}:
            raise ScenarioError(
                f"{where} = {v!r}: a table here must be {{ idle_rpm = <engine speed [rpm]> }} "
                "(the throttle that holds the free engine at that speed)"
            )
        rpm = v["idle_rpm"]
        if not is_finite_real(rpm) or rpm <= 0:
            raise ScenarioError(f"{where}.idle_rpm = {rpm!r}: must be a finite number > 0 [rpm]")
        if rpm not in cache:
            p = default_params() if params is None else params
            try:
                cache[rpm] = idle_throttle(p, float(rpm_to_rad_s(float(rpm))))
            except ScenarioError as exc:
                raise ScenarioError(
                    f"{where}.idle_rpm = {rpm!r}: {exc} (parameter set {p.name!r})"
                ) from None
        return cache[rpm]

    out = dict(d)
    ini = d.get("initial")
    if isinstance(ini, dict) and "throttle" in ini:
        out["initial"] = {**ini, "throttle": resolve("initial.throttle", ini["throttle"])}
    inputs = d.get("inputs")
    thr = inputs.get("throttle") if isinstance(inputs, dict) else None
    if isinstance(inputs, dict) and isinstance(thr, dict) and isinstance(thr.get("values"), list):
        vals = [resolve(f"inputs.throttle.values[{i}]", v) for i, v in enumerate(thr["values"])]
        out["inputs"] = {**inputs, "throttle": {**thr, "values": vals}}
    return out


def scenario_from_dict(d: dict[str, Any], *, params: DrivetrainParams | None = None) -> Scenario:
    """Build a :class:`Scenario` from its TOML form (see the module docstring); ``params`` is the
    parameter set that ``{ idle_rpm = ... }`` values are resolved with (the default set if
    None)."""
    _reject_unknown("", set(d), _TOP)
    d = _resolve_idle(d, params)
    for key in ("name", "description"):
        if key in d and not isinstance(d[key], str):
            raise ScenarioError(f"{key} = {d[key]!r}: must be a string")
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
    reference: Signal | None = None
    start: float | None = None
    pedal0 = 0.11
    if ctl is not None:
        if not isinstance(ctl, dict):
            raise ScenarioError("controller: must be a table")
        _reject_unknown("controller.", set(ctl), _CONTROLLER)
        if "reference_rpm" not in ctl:
            raise ScenarioError("controller.reference_rpm: missing")
        try:
            rpm = Signal.from_dict(ctl["reference_rpm"], name="controller.reference_rpm")
        except (TypeError, ValueError) as exc:
            raise ScenarioError(str(exc)) from exc
        # knots converted as initial.engine_speed_rpm is (rpm_to_rad_s): a reference equal to the
        # initial engine speed in rpm is exactly that speed in rad/s
        reference = Signal(
            rpm.times,
            tuple(float(rpm_to_rad_s(v)) for v in rpm.values),
            (rpm * RPM_TO_RAD_S).sines,
        )
        if "pedal0" in ctl:
            pedal0 = _num("controller.", ctl, "pedal0")
        if "start_s" in ctl:
            start = _num("controller.", ctl, "start_s")
    sigs = []
    for n in INPUTS:
        if n == "pedal" and reference is not None and "pedal" not in inputs:
            continue  # closed loop only
        if n not in inputs:
            raise ScenarioError(f"inputs.{n}: missing")
        try:
            sigs.append((n, Signal.from_dict(inputs[n], name=f"inputs.{n}")))
        except (TypeError, ValueError) as exc:
            raise ScenarioError(str(exc)) from exc
    if not locked and _num("initial.", ini, "engine_speed_rpm") < 0.0:
        raise ScenarioError(
            f"initial.engine_speed_rpm = {ini['engine_speed_rpm']!r}: must be >= 0 (the engine "
            "does not run backwards)"
        )
    if not 0.0 <= _num("initial.", ini, "throttle") <= 1.0:
        raise ScenarioError(f"initial.throttle = {ini['throttle']!r}: must lie in [0, 1]")
    if "slope_percent" in d and abs(math.atan(_num("", d, "slope_percent") / 100.0)) >= 1.5:
        raise ScenarioError(
            f"slope_percent = {d['slope_percent']!r}: out of range (|slope| < 1410 %, 86 deg)"
        )
    throttle0 = _num("initial.", ini, "throttle")
    sc = Scenario(
        name=name,
        description=str(d.get("description", "")).replace("{throttle0}", f"{throttle0:.4f}"),
        gear=gear,
        slope=math.atan(_num("", d, "slope_percent") / 100.0) if "slope_percent" in d else 0.0,
        t_end=_num("", d, "t_end"),
        omega_engine0=float(rpm_to_rad_s(_num("initial.", ini, "engine_speed_rpm")))
        if not locked
        else 0.0,
        clutch_locked0=locked,
        v_vehicle0=float(kmh_to_m_s(_num("initial.", ini, "vehicle_speed_kmh"))),
        throttle0=throttle0,
        twist_torque0=_num("initial.", ini, "twist_torque") if "twist_torque" in ini else 0.0,
        inputs=tuple(sigs),
        reference=reference,
        control_start=start,
        pedal0=pedal0,
        param_overrides=_param_overrides(d["params"]) if "params" in d else (),
    )
    if sc.param_overrides:  # validated like a parameter set, on the set the file is loaded for
        sc.params_for(default_params() if params is None else params)
    return sc


def idle_throttle(params: DrivetrainParams, omega: float) -> float:
    """Throttle [-] that holds the free engine (clutch open) at ``omega`` [rad/s].

    Engine torque = engine friction: ``K theta = b1 omega + c1`` (linear torque model, eq. (1)) or
    ``theta C_max(omega) = b1 omega + c1`` (map model)."""
    if not is_finite_real(omega):
        raise ScenarioError(f"idle_throttle: omega = {omega!r} [rad/s]: must be a finite number")
    if omega <= 0:
        raise ScenarioError(f"idle_throttle: omega = {omega!r} [rad/s]: must be > 0")
    e = params.engine
    loss = e.b1 * omega + e.c1
    if e.torque_model == "map" and e.full_load_curve is not None:
        gain = float(np.interp(omega, e.full_load_curve.x, e.full_load_curve.y))
    else:
        gain = e.K
    th = loss / gain
    if not 0.0 <= th <= 1.0:
        raise ScenarioError(f"idle speed {omega!r} rad/s needs throttle {th:.3g}, outside [0, 1]")
    return float(th)


#: the order the built-in scenarios are listed (and the demo runs them) in; a file in
#: ``scenarios/builtin/`` not named here follows, alphabetically
BUILTIN_ORDER: tuple[str, ...] = (
    "engage-ramp",
    "tip-in",
    "paper-start",
    "hill-start",
    "worn-clutch",
    "judder",
    "heavy-load",
    "tip-out-reengage",
)

#: the package whose ``builtin/`` folder holds the built-in scenario files
_PACKAGE = __name__.rpartition(".")[0]


def builtin_scenarios(params: DrivetrainParams | None = None) -> dict[str, Scenario]:
    """The built-in scenarios by name: the TOML files in ``scenarios/builtin/`` (package data),
    loaded for ``params`` (the default parameter set if None; ``paper-start``'s idle throttle
    depends on it)."""
    out = {}
    for stem, f in builtin_files(_PACKAGE, order=BUILTIN_ORDER).items():
        sc = load_toml_as(
            f, functools.partial(scenario_from_dict, params=params), error=ScenarioError
        )
        if sc.name != stem:
            raise ScenarioError(f"{f}: name = {sc.name!r}: must be the file's stem {stem!r}")
        out[stem] = sc
    return out


def load_scenario(
    source: str | Path | Scenario, *, params: DrivetrainParams | str | Path | None = None
) -> Scenario:
    """A built-in scenario by name or a scenario TOML file, loaded for ``params`` (a parameter set,
    or its name or TOML file; the default parameter set if None), or a :class:`Scenario`
    (returned as it is)."""
    if isinstance(source, Scenario):
        return source
    if isinstance(source, bool) or not isinstance(source, (str, Path)):
        raise ScenarioError(f"load_scenario: source = {source!r}: give a scenario name or a path")
    if isinstance(params, (str, Path)):
        params = load_params(params)
    elif params is not None and not isinstance(params, DrivetrainParams):
        raise ScenarioError(
            f"load_scenario: params = {params!r}: give a DrivetrainParams, a parameter set name "
            "or file, or None"
        )
    files = builtin_files(_PACKAGE, order=BUILTIN_ORDER)
    if isinstance(source, str) and source in files:  # one built-in: read only its file
        sc = load_toml_as(
            files[source], functools.partial(scenario_from_dict, params=params), error=ScenarioError
        )
        if sc.name != source:
            raise ScenarioError(f"{files[source]}: name = {sc.name!r}: must be the file's stem")
        return sc
    b = builtin_scenarios(params)
    return load_builtin_or_toml(
        source,
        b,
        functools.partial(scenario_from_dict, params=params),
        what="scenario",
        error=ScenarioError,
    )
