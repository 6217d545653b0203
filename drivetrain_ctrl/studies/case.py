"""One run as data: a picklable :class:`Case` and the function that runs it.

A case names everything a run needs, by value or by name: the scenario (built-in name, TOML file
or :class:`~drivetrain_ctrl.scenarios.Scenario`), the parameter set (name, TOML file or
:class:`~drivetrain_ctrl.plant.params.DrivetrainParams`) with overrides by dotted parameter name,
the model kind, the loop (closed: a controller drives the pedal; open: the scenario's pedal
signal does), the controller (built-in name, TOML file or
:class:`~drivetrain_ctrl.control.laws.ControllerSpec`; None for open loop) and the integrator
tolerance. :func:`simulate_case` runs it and returns the result with its context;
:func:`run_case` returns only the flat record of metrics (what a study keeps per sample). The CLI,
the controller report and the studies all run cases through here, so a run means the same thing
everywhere.

With ``linear=True`` the record also holds the paired linear figures of the run
(:func:`linear_figures`): the slip-mode clutch loop (actuator, clutch, engine and controller;
:func:`~drivetrain_ctrl.linear.clutch.clutch_loop`) linearised at the run's slip operating point
(:func:`~drivetrain_ctrl.linear.operating_point.slip_point_after_start`: the trajectory 0.3 s
after the controller start) with the case's parameters, as :data:`LINEAR_FIGURES`.

What does not depend on the sample is not redone per case within one process: a scenario file
is parsed once per (file, engine parameters) -- the only parameters a scenario's values depend
on (an ``idle_rpm`` throttle) -- and the parameter set with a case's overrides and its drivetrain
are kept for the next case with the same values (the controllers and scenarios of one sample).
The values are the same as without these caches (tested; :func:`clear_caches`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time
from collections import OrderedDict
from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..control.blocks import Controller
from ..control.laws import ControllerError, ControllerSpec, builtin_controllers, load_controller
from ..core.serialize import json_ready
from ..core.validate import did_you_mean, is_finite_real, reject_unknown
from ..linear.clutch import EngineSide, _judder_threshold, clutch_loop_gain, judder_crossing
from ..linear.margins import LoopMargins, _auto_grid, loop_margins
from ..linear.operating_point import OperatingPoint, slip_point_after_start
from ..plant.drivetrain import Drivetrain
from ..plant.params import DEFAULT_SET, DrivetrainParams, load_params
from ..scenarios.scenario import LOOPS, Scenario, load_scenario
from ..sim.metrics import engagement_metrics
from ..sim.run import run_scenario
from ..sim.simulator import SimulationOptions, SimulationResult, ZenoError

__all__ = [
    "Case",
    "CaseError",
    "CaseRun",
    "LINEAR_FIGURES",
    "MODELS",
    "SCENARIO_FIELDS",
    "clear_caches",
    "linear_figures",
    "linear_figures_at",
    "simulate_case",
    "run_case",
]

#: model kinds a case can run on
MODELS: tuple[str, ...] = ("full", "reduced")

#: scenario fields a case (and a study, as ``scenario.<field>``) may replace, SI units: road
#: slope [rad], initial engine speed [rad/s], vehicle speed [m/s], throttle (lag) state [-],
#: driveline twist torque [N m, primary shaft] and the controller's initial output [m]
SCENARIO_FIELDS: tuple[str, ...] = (
    "slope",
    "omega_engine0",
    "v_vehicle0",
    "throttle0",
    "twist_torque0",
    "pedal0",
)


class CaseError(ValueError):
    """A case that cannot run as given (the message names the field and the value)."""


@dataclass(frozen=True, kw_only=True)
class Case:
    """One closed- or open-loop run, as data (picklable; compares by value).

    scenario: built-in name, scenario TOML file or :class:`Scenario`.
    params: parameter set name (``"default"``), TOML file or :class:`DrivetrainParams`.
    overrides: ``{dotted parameter name: value}`` applied to ``params`` (SI units, e.g.
    ``{"clutch.static_ratio": 1.3, "vehicle.M_v": 1400.0}``); validated like a parameter set.
    scenario_overrides: ``{field: value}`` replacing fields of the scenario, one of
    :data:`SCENARIO_FIELDS` (SI units: ``{"slope": 0.05}`` is a 5 % road grade in rad).
    model: ``"full"`` or ``"reduced"``.
    loop: ``"closed"`` (the controller drives the pedal to follow the scenario's engine-speed
    reference), ``"open"`` (the scenario's pedal signal drives it; no controller) or None: the
    scenario's own (closed if it has a ``[controller]`` table; :meth:`Scenario.for_loop`).
    controller: built-in name, controller TOML file or :class:`ControllerSpec`; None: open loop.
    rtol: the integrator's relative tolerance (None: :class:`SimulationOptions`' default).
    t_end: end of the run [s] (None: the scenario's horizon).
    label: a free name carried into the record (e.g. a sample id).
    linear: also the paired linear figures of the run (:func:`linear_figures`) in its record.
    """

    scenario: str | Path | Scenario
    params: str | Path | DrivetrainParams = DEFAULT_SET
    overrides: Mapping[str, Any] = field(default_factory=dict)
    scenario_overrides: Mapping[str, float] = field(default_factory=dict)
    model: str = "full"
    loop: str | None = None
    controller: str | Path | ControllerSpec | None = None
    rtol: float | None = None
    t_end: float | None = None
    label: str = ""
    linear: bool = False

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise CaseError(f"model = {self.model!r}: must be one of {MODELS}")
        if self.loop is not None and (not isinstance(self.loop, str) or self.loop not in LOOPS):
            raise CaseError(
                f"loop = {self.loop!r}: must be one of {LOOPS} or None (the scenario's own)"
            )
        if not isinstance(self.overrides, Mapping) or not all(
            isinstance(k, str) for k in self.overrides
        ):
            raise CaseError(
                f"overrides = {self.overrides!r}: must map dotted parameter names to values"
            )
        object.__setattr__(self, "overrides", dict(self.overrides))
        so = self.scenario_overrides
        if not isinstance(so, Mapping):
            raise CaseError(f"scenario_overrides = {so!r}: must map scenario fields to numbers")
        for k, v in so.items():
            if k not in SCENARIO_FIELDS:
                raise CaseError(
                    f"scenario_overrides: unknown scenario field {k!r}"
                    f"{did_you_mean(str(k), SCENARIO_FIELDS)}; fields: {SCENARIO_FIELDS}"
                )
            if not is_finite_real(v):
                raise CaseError(f"scenario_overrides.{k} = {v!r}: must be a finite number")
        object.__setattr__(self, "scenario_overrides", {k: float(v) for k, v in so.items()})
        for name in ("rtol", "t_end"):
            v = getattr(self, name)
            if v is not None and not (is_finite_real(v) and v > 0):
                raise CaseError(f"{name} = {v!r}: must be a finite number > 0 (or None)")
        if not isinstance(self.label, str):
            raise CaseError(f"label = {self.label!r}: must be a string")
        if not isinstance(self.linear, bool):
            raise CaseError(f"linear = {self.linear!r}: must be True or False")

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
    compiled kernels ``kernel_load_s`` [s] (0 unless preloaded), the case itself and, if the case
    asks for them, its ``linear`` figures (:func:`linear_figures`; else None)."""

    case: Case
    result: SimulationResult
    drivetrain: Drivetrain
    scenario: Scenario
    spec: ControllerSpec | None
    controller: Controller | None
    options: SimulationOptions
    metrics: dict[str, Any]
    kernel_load_s: float
    linear: dict[str, Any] | None = None

    def record(self) -> dict[str, Any]:
        """The flat record of this run: what ran (scenario, loop, model, parameter set, controller
        name, tolerances, label, each override as ``param:<name>``), every engagement metric and the
        linear figures if computed; numbers rounded by
        :func:`~drivetrain_ctrl.core.serialize.json_ready`."""
        c = self.case
        out: dict[str, Any] = {
            "label": c.label,
            "scenario": self.scenario.name,
            "loop": self.scenario.loop,
            "parameter_set": self.drivetrain.params.name,
            "controller": self.spec.name if self.spec is not None else None,
            "rtol": self.options.rtol,
            "atol": self.options.atol,
            **{f"param:{k}": v for k, v in sorted(c.overrides.items())},
            **{f"param:scenario.{k}": v for k, v in sorted(c.scenario_overrides.items())},
            **self.metrics,
            **(self.linear or {}),
        }
        return dict(json_ready(out))


# -- what does not depend on the sample: kept between the cases of one process ---------------
#: entries each cache keeps (least recently used dropped first)
CACHE_SIZE = 32


class _Cache:
    """A small least-recently-used map (per process; a worker runs its chunk's cases in turn)."""

    def __init__(self, size: int = CACHE_SIZE) -> None:
        self.size = size
        self.data: OrderedDict[Hashable, Any] = OrderedDict()

    def get(self, key: Hashable) -> Any:
        v = self.data.get(key)
        if v is not None:
            self.data.move_to_end(key)
        return v

    def put(self, key: Hashable, value: Any) -> None:
        self.data[key] = value
        self.data.move_to_end(key)
        while len(self.data) > self.size:
            self.data.popitem(last=False)


_CACHES: dict[str, _Cache] = {"params": _Cache(), "scenario": _Cache(), "drivetrain": _Cache()}
_CACHING = [True]


def clear_caches() -> None:
    """Forget the parameter sets, scenarios and drivetrains kept between cases."""
    for c in _CACHES.values():
        c.data.clear()


@contextlib.contextmanager
def caching(enabled: bool) -> Any:
    """Within the block, keep (``True``) or rebuild for every case (``False``) what does not
    depend on the sample; the values are the same either way (a test checks it)."""
    old = _CACHING[0]
    _CACHING[0] = bool(enabled)
    try:
        yield
    finally:
        _CACHING[0] = old


def _params(case: Case) -> DrivetrainParams:
    p = case.params
    if not isinstance(p, DrivetrainParams):
        if isinstance(p, bool) or not isinstance(p, str | Path):
            raise CaseError(f"params = {p!r}: give a parameter set name, TOML file or params")
        p = load_params(p)
    if not case.overrides:
        return p
    if not _CACHING[0]:
        return p.replace(**case.overrides)
    try:
        key: Hashable = (p, tuple(sorted(case.overrides.items())))
        hash(key)
    except TypeError:  # an unhashable override value: not kept
        return p.replace(**case.overrides)
    out = _CACHES["params"].get(key)
    if out is None:
        out = p.replace(**case.overrides)
        _CACHES["params"].put(key, out)
    return out


def _scenario_key(source: str | Path, params: DrivetrainParams) -> Hashable | None:
    """What a loaded scenario depends on: the built-in name or the file (path, time of the last
    change, size) and the engine parameters (an ``idle_rpm`` throttle); None: not kept."""
    try:
        st = os.stat(source)
    except (OSError, ValueError):
        return ("name", str(source), params.engine)
    return ("file", str(Path(source).resolve()), st.st_mtime_ns, st.st_size, params.engine)


def _load_scenario(source: str | Path | Scenario, params: DrivetrainParams) -> Scenario:
    """:func:`load_scenario` of ``source`` for ``params``; a file parsed once per key of
    :func:`_scenario_key`. A kept scenario's parameter overrides are checked on ``params`` as
    loading checks them; should they fail, the scenario is loaded afresh (the same error)."""
    if isinstance(source, Scenario) or not _CACHING[0]:
        return load_scenario(source, params=params)
    key = _scenario_key(source, params)
    try:
        hash(key)
    except TypeError:
        return load_scenario(source, params=params)
    sc: Scenario | None = _CACHES["scenario"].get(key)
    if sc is None:
        sc = load_scenario(source, params=params)
        _CACHES["scenario"].put(key, sc)
    elif sc.param_overrides:
        try:
            sc.params_for(params)
        except ValueError:
            return load_scenario(source, params=params)  # raises as loading does
    return sc


def _drivetrain(scenario: Scenario, params: DrivetrainParams, kind: str) -> Drivetrain:
    """:meth:`Scenario.drivetrain`; one per (scenario gear, slope and overrides, parameters,
    model kind), kept for the next case (e.g. the sample's next controller)."""
    if not _CACHING[0]:
        return scenario.drivetrain(params, kind=kind)
    key = (
        scenario.gear,
        scenario.slope,
        repr(scenario.param_overrides),
        params,
        kind,
    )
    dt: Drivetrain | None = _CACHES["drivetrain"].get(key)
    if dt is None:
        dt = scenario.drivetrain(params, kind=kind)
        _CACHES["drivetrain"].put(key, dt)
    return dt


def _spec(case: Case, scenario: Scenario, loops: tuple[str, ...]) -> ControllerSpec | None:
    """The controller spec of ``case`` on ``scenario`` (as its loop runs it; ``loops``: the
    loops the scenario file has)."""
    if case.controller is None:
        if scenario.needs_controller:
            names = "|".join(builtin_controllers())
            alt = "; or loop = 'open' for its open-loop pedal" if "open" in loops else ""
            raise CaseError(
                f"scenario {scenario.name!r} needs a controller (it gives the engine-speed "
                f"reference, not the pedal): controller = {names}|FILE.toml{alt}"
            )
        return None
    if not scenario.needs_controller:
        if case.loop == "open":
            raise CaseError(
                f"controller = {case.controller!r}: loop = 'open' runs the pedal signal of "
                f"scenario {scenario.name!r}; drop the controller or use loop = 'closed'"
            )
        raise CaseError(
            f"controller = {case.controller!r}: scenario {scenario.name!r} is open loop (it gives "
            "the pedal signal); drop the controller or use a closed-loop scenario (paper-start)"
        )
    try:
        return load_controller(case.controller)
    except ControllerError as exc:
        raise CaseError(f"controller: {exc}") from None


# -- the paired linear figures ----------------------------------------------------------------
#: the linear figures of a record (NaN in a study's table where undefined; why in ``linear_note``)
LINEAR_FIGURES: dict[str, str] = {
    "lin:gain_margin": "gain margin, a factor (not dB) [-]",
    "lin:phase_margin_deg": "phase margin [deg]",
    "lin:disk_margin": "symmetric disk margin alpha (skew 0) [-]",
    "lin:Ms": "peak sensitivity max |S| [-]",
    "lin:judder_margin": "1 - mu'/mu'_crit: the share of the judder threshold unused [-]",
    "lin:mu_slope": "friction slope mu' of mu/mu0 at the slip point [s/rad]",
    "lin:mu_slope_crit": "judder threshold mu'_crit [s/rad]",
    "lin:crossover_rad_s": "gain crossover frequency [rad/s]",
    "lin:stable": "the linearised closed loop is stable (1/0) [-]",
    "lin:t_s": "time of the slip operating point [s]",
}
#: frequencies of the grid that ``lin:disk_margin`` and ``lin:Ms`` are taken on (log-spaced
#: over the loop's poles and zeros, three decades beyond each side)
LINEAR_GRID_POINTS = 300
#: relative tolerance of the numeric judder threshold (:func:`judder_crossing`) in a record
LINEAR_JUDDER_RTOL = 1e-4


def _judder(
    op: OperatingPoint, ctrl: Controller, es: EngineSide, L: Any
) -> tuple[float | None, str]:
    """(mu'_crit [s/rad] or None, how it was found). The closed form (reduced model, continuous
    controller) where it gives a falling-friction threshold; else the numeric first crossing
    going from mu' = 0 towards falling friction (:func:`judder_crossing`). The closed form can
    pick a crossing at a rising slope (its real, s = 0, crossing ``c_dc`` > 0 when the engine
    side's damping is negative at the point): not a judder threshold, so the numeric one is used
    and the note says so."""
    note = ""
    if op.kind == "reduced" and not ctrl.is_discrete:
        try:
            jt = _judder_threshold(op, es, L)
        except (ValueError, ArithmeticError) as exc:
            note = f"closed form failed ({exc}); "
        else:
            if jt.mu_slope_crit < 0.0:
                return float(jt.mu_slope_crit), f"judder: closed form ({jt.which} crossing)"
            note = (
                f"the closed form's critical slope mu' = {jt.mu_slope_crit:.4g} s/rad is a "
                f"rising-friction ({jt.which}) crossing, not a judder threshold; "
            )
    jc = judder_crossing(op, ctrl, rtol=LINEAR_JUDDER_RTOL)
    if jc.mu_slope_crit is None:
        return None, f"judder: {note}no numeric threshold: {jc.reason}"
    how = f"judder: {note}numeric (judder_crossing, rtol {LINEAR_JUDDER_RTOL:g})"
    return float(jc.mu_slope_crit), how


def linear_figures(
    result: SimulationResult, drivetrain: Drivetrain, controller: Controller | None, *, start: float
) -> dict[str, Any]:
    """The paired linear figures of a closed-loop run (:data:`LINEAR_FIGURES`; None where
    undefined) and ``linear_note`` (how the judder threshold was found, or why figures are None).
    A linear analysis that fails leaves its figures None with the reason in the note; it never
    fails the run, whose metrics stand.

    The slip-mode clutch loop of ``controller`` (:func:`~drivetrain_ctrl.linear.clutch.clutch_loop_gain`,
    the loop gain of :func:`~drivetrain_ctrl.linear.clutch.clutch_loop`:
    actuator, clutch and engine with the driveline coupled in, ``L = C P``, negative feedback) at
    the run's slip operating point (:func:`slip_point_after_start` of ``start``, the controller
    start) on ``drivetrain`` (the case's parameters and model). Gain and phase margins and the
    crossover: :func:`~drivetrain_ctrl.linear.margins.loop_margins` (python-control's
    ``stability_margins``); the disk margin and Ms on :data:`LINEAR_GRID_POINTS` frequencies.
    The figures from these: :func:`linear_figures_at`.
    """
    out: dict[str, Any] = dict.fromkeys(LINEAR_FIGURES)
    if controller is None:
        out["linear_note"] = "open loop: no clutch loop"
        return out
    op: OperatingPoint | None = None
    try:
        op = slip_point_after_start(result, drivetrain, start)
        es, L = clutch_loop_gain(op, controller)
        m = loop_margins(L, omega=_auto_grid(L, n=LINEAR_GRID_POINTS).tolist())
    except Exception as exc:  # noqa: BLE001 - the run's own figures stand; the reason is kept
        out["lin:t_s"] = None if op is None else op.t
        out["linear_note"] = f"{NO_LINEAR_FIGURES}: {type(exc).__name__}: {exc}"
        return out
    return linear_figures_at(op, controller, es, L, m)


#: the start of ``linear_note`` when the slip loop could not be analysed
NO_LINEAR_FIGURES = "no linear figures"


def linear_figures_at(
    op: OperatingPoint, controller: Controller, engine: EngineSide, L: Any, margins: LoopMargins
) -> dict[str, Any]:
    """:data:`LINEAR_FIGURES` and ``linear_note`` of a slip loop already analysed: ``op`` its
    operating point, ``engine`` and ``L`` its engine side and loop gain
    (:func:`~drivetrain_ctrl.linear.clutch.clutch_loop_gain`, or a
    :func:`~drivetrain_ctrl.linear.clutch.clutch_loop`'s ``engine`` and ``L``), ``margins`` its
    :func:`~drivetrain_ctrl.linear.margins.loop_margins` (on whatever grid the caller chose:
    the disk margin and Ms are taken on it). Only the judder threshold is computed here.
    Judder margin ``1 - mu'/mu'_crit`` with ``mu'`` the slope of the friction ratio mu/mu0 at the
    slip point and ``mu'_crit`` < 0 the judder threshold (:func:`_judder`): 1 for a constant
    friction coefficient, 0 at the threshold, negative beyond it, above 1 for rising friction.
    """
    out: dict[str, Any] = dict.fromkeys(LINEAR_FIGURES)
    m, es = margins, engine
    out["lin:t_s"] = op.t
    out["lin:gain_margin"] = None if m.gain_margin_db is None else 10.0 ** (m.gain_margin_db / 20)
    out["lin:phase_margin_deg"] = m.phase_margin_deg
    out["lin:disk_margin"] = m.disk_margin
    out["lin:Ms"] = m.ms
    out["lin:crossover_rad_s"] = m.crossover_rad_s
    out["lin:stable"] = None if m.stable is None else float(m.stable)
    notes = [
        f"{k}: {v}"
        for k, v in m.reasons
        if k in ("gain_margin_db", "phase_margin_deg", "disk_margin")
    ]
    mu = es.mu_slope_torque / es.k13 if es.k13 > 0 else None
    out["lin:mu_slope"] = mu
    try:
        crit, how = _judder(op, controller, es, L)
    except Exception as exc:  # noqa: BLE001 - the run's own figures stand; the reason is kept
        crit, how = None, f"judder: failed ({type(exc).__name__}: {exc})"
    notes.append(how)
    out["lin:mu_slope_crit"] = crit
    if crit is not None and mu is not None and math.isfinite(mu):
        out["lin:judder_margin"] = 1.0 - mu / crit
    out["linear_note"] = "; ".join(notes)
    return out


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
        scenario = _load_scenario(case.scenario, params)
        if case.scenario_overrides:
            changes: dict[str, Any] = dict(case.scenario_overrides)
            scenario = dataclasses.replace(scenario, **changes)
        loops = scenario.loops
        scenario = scenario.for_loop(case.loop)
        options = SimulationOptions() if case.rtol is None else SimulationOptions(rtol=case.rtol)
    except FileNotFoundError as exc:
        raise CaseError(f"file not found: {exc.filename or exc}") from None
    except (ValueError, OSError) as exc:
        raise CaseError(str(exc)) from None
    try:
        t_stop = scenario.check_horizon(case.t_end)
        dt = _drivetrain(scenario, params, case.model)
        scenario.initial_state(dt)  # validates the initial state for this model
    except ValueError as exc:
        raise CaseError(f"scenario {scenario.name!r}: {exc}") from None
    spec = _spec(case, scenario, loops)
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
    lin = linear_figures(res, dt, ctrl, start=scenario.start_time) if case.linear else None
    return CaseRun(case, res, dt, scenario, spec, ctrl, options, metrics, load_s, lin)


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
            "loop": case.loop,
            "model": case.model,
            **{f"param:{k}": v for k, v in sorted(case.overrides.items())},
            **{f"param:scenario.{k}": v for k, v in sorted(case.scenario_overrides.items())},
            "status": "failed",
            "error": str(exc),
        }
