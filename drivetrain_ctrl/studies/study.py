"""A robustness study as data: uncertain parameters, sampling, controllers, scenarios, criteria.

A study runs every sample of the uncertain parameters under every controller on every scenario
and judges each run by pass criteria on its figures of merit
(:data:`~drivetrain_ctrl.sim.metrics.METRICS`). It is written as a TOML file
(:func:`load_study`) or built in Python (:meth:`Study.from_dict`); :func:`sample_table` draws the
samples (reproducible: the same seed gives the same samples) and :meth:`Study.cases` turns them
into :class:`~drivetrain_ctrl.studies.case.Case` objects, run by
:func:`~drivetrain_ctrl.studies.runner.run_study`.

Every check happens when the study is loaded, before any simulation: an unknown key, parameter,
controller, scenario or metric, an impossible distribution (a lower bound above the upper, a
standard deviation <= 0, ...), a sample count of zero, a criterion that does not parse; the error
(:class:`StudyError`) names the key and the value.

The file (units SI, as in the parameter sets)::

    [study]
    name = "paper-start-quick"
    model = "reduced"                   # full | reduced
    params = "passenger-car"            # parameter set name or file (relative to this file)
    controllers = ["paper", "pi"]       # built-in names or controller files
    scenarios = ["paper-start"]         # built-in names or scenario files
    metrics = ["lockup_time_s", "jerk_max_m_s3"]   # kept per run (default: every figure)
    criteria = ["lockup_time_s <= 3.0", "engine_speed_min_rpm >= 700"]
    t_end = 3.0                         # optional: end of each run [s]
    linear = true                       # the paired linear figures per run (default true)

    [sampling]
    method = "lhs"                      # mc | lhs | sobol | grid
    samples = 200                       # not for grid (the product of the value counts)
    seed = 1

    [parameters."vehicle.M_v"]
    dist = "uniform"                    # uniform | normal | truncnormal | loguniform | values
    low = 1100.0
    high = 1500.0

Distributions: ``uniform`` (``low``, ``high``), ``normal`` (``mean``, ``std``), ``truncnormal``
(``mean``, ``std``, ``low``, ``high``), ``loguniform`` (``low`` > 0, ``high``), ``values`` (a
list ``values``, drawn with equal probability; the grid method needs every parameter given so).
A parameter is a dotted name of the parameter set (``clutch.static_ratio``, ``vehicle.M_v``,
``actuator.omega_a``, ...), ``controller.<gain>`` (``controller.k_r``, ``controller.kp``, ...:
applied to every controller of the study, each of which must have the gain) or
``scenario.<field>`` (``scenario.slope`` [rad], ``scenario.v_vehicle0`` [m/s], ...: one of
:data:`~drivetrain_ctrl.studies.case.SCENARIO_FIELDS`, applied to every scenario of the study).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ..control.laws import ControllerError, ControllerSpec, load_controller
from ..core.registry import read_toml
from ..core.validate import did_you_mean, is_finite_real, reject_unknown
from ..plant.params import DEFAULT_SET, DrivetrainParams, ParameterError, load_params
from ..scenarios.scenario import load_scenario
from ..sim.metrics import METRICS
from .case import MODELS, SCENARIO_FIELDS, Case

__all__ = [
    "DISTRIBUTIONS",
    "METHODS",
    "Criterion",
    "Parameter",
    "Study",
    "StudyError",
    "load_study",
    "sample_table",
]

F64 = NDArray[np.float64]

#: sampling methods: Monte Carlo, Latin hypercube, scrambled Sobol sequence, full grid
METHODS: tuple[str, ...] = ("mc", "lhs", "sobol", "grid")
#: distributions of an uncertain parameter and their keys
DISTRIBUTIONS: dict[str, tuple[str, ...]] = {
    "uniform": ("low", "high"),
    "normal": ("mean", "std"),
    "truncnormal": ("mean", "std", "low", "high"),
    "loguniform": ("low", "high"),
    "values": ("values",),
}
#: the comparison operators a criterion may use
OPERATORS: tuple[str, ...] = ("<=", ">=", "<", ">", "==", "!=")
#: metrics that are texts (kept as strings); every other metric is a number (a flag as 0/1)
TEXT_METRICS: frozenset[str] = frozenset({"model", "status", "notes"})
#: prefix of a controller gain among the uncertain parameters
CONTROLLER_PREFIX = "controller."
#: prefix of a scenario field among the uncertain parameters (one of ``case.SCENARIO_FIELDS``)
SCENARIO_PREFIX = "scenario."

_CRITERION = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|==|!=|<|>)\s*(\S+)\s*$")


class StudyError(ValueError):
    """A study that cannot run as given; the message names the key and the value."""


@dataclass(frozen=True)
class Parameter:
    """One uncertain parameter: dotted ``name``, distribution ``dist`` (a key of
    :data:`DISTRIBUTIONS`) and its arguments ``args`` (SI units; ``values`` a tuple)."""

    name: str
    dist: str
    args: Mapping[str, Any]

    def ppf(self, u: F64) -> F64:
        """The values at quantiles ``u`` in [0, 1) (the inverse distribution function)."""
        from scipy import stats

        a = self.args
        if self.dist == "uniform":
            return np.asarray(a["low"] + u * (a["high"] - a["low"]), dtype=float)
        if self.dist == "loguniform":
            lo, hi = math.log(a["low"]), math.log(a["high"])
            return np.asarray(np.exp(lo + u * (hi - lo)), dtype=float)
        if self.dist == "normal":
            return np.asarray(stats.norm.ppf(u, loc=a["mean"], scale=a["std"]), dtype=float)
        if self.dist == "truncnormal":
            lo = (a["low"] - a["mean"]) / a["std"]
            hi = (a["high"] - a["mean"]) / a["std"]
            v = stats.truncnorm.ppf(u, lo, hi, loc=a["mean"], scale=a["std"])
            return np.asarray(np.clip(v, a["low"], a["high"]), dtype=float)
        vals = np.asarray(a["values"], dtype=float)
        idx = np.minimum((u * vals.shape[0]).astype(np.int64), vals.shape[0] - 1)
        return np.asarray(vals[idx], dtype=float)

    def support(self) -> tuple[float, ...]:
        """Values that bound what can be drawn (checked against the parameter set at load)."""
        a = self.args
        if self.dist == "values":
            return tuple(a["values"])
        if self.dist == "normal":
            return (float(a["mean"]),)
        return (float(a["low"]), float(a["high"]))


@dataclass(frozen=True)
class Criterion:
    """A pass criterion ``metric op threshold`` (e.g. ``lockup_time_s <= 3.0``); a run whose
    metric is undefined (None/NaN) or that failed does not pass it."""

    metric: str
    op: str
    threshold: float

    @property
    def text(self) -> str:
        """The criterion as written canonically (the name of its pass/fail column)."""
        return f"{self.metric} {self.op} {self.threshold:g}"

    def check(self, values: Any) -> NDArray[np.bool_]:
        """Pass/fail of each of ``values`` (NaN fails)."""
        v = np.asarray(values, dtype=float)
        ops = {
            "<=": np.less_equal,
            ">=": np.greater_equal,
            "<": np.less,
            ">": np.greater,
            "==": np.equal,
            "!=": np.not_equal,
        }
        with np.errstate(invalid="ignore"):
            out = ops[self.op](v, self.threshold) & np.isfinite(v)
        return np.asarray(out, dtype=bool)


def _parse_criterion(text: Any, where: str) -> Criterion:
    if not isinstance(text, str):
        raise StudyError(f"{where} = {text!r}: must be a string like 'lockup_time_s <= 3.0'")
    m = _CRITERION.match(text)
    if m is None:
        raise StudyError(
            f"{where} = {text!r}: must read '<metric> <op> <number>' with op one of {OPERATORS}"
        )
    metric, op, num = m.groups()
    if metric not in METRICS:
        raise StudyError(
            f"{where} = {text!r}: unknown metric {metric!r}{did_you_mean(metric, METRICS)}"
        )
    if metric in TEXT_METRICS:
        raise StudyError(f"{where} = {text!r}: metric {metric!r} is a text, not a number")
    try:
        value = float(num)
    except ValueError:
        raise StudyError(f"{where} = {text!r}: threshold {num!r} is not a number") from None
    if not math.isfinite(value):
        raise StudyError(f"{where} = {text!r}: threshold {num!r} must be finite")
    return Criterion(metric, op, value)


def _number(where: str, v: Any) -> float:
    if not is_finite_real(v):
        raise StudyError(f"{where} = {v!r}: must be a finite number")
    return float(v)


def _parameter(name: Any, d: Any) -> Parameter:
    where = f"parameters.{name!r}"
    if not isinstance(d, Mapping):
        raise StudyError(f"{where} = {d!r}: must be a table with dist = ... and its arguments")
    dist = d.get("dist", "values" if "values" in d else None)
    if dist not in DISTRIBUTIONS:
        raise StudyError(
            f"{where}.dist = {dist!r}: must be one of {tuple(DISTRIBUTIONS)}"
            f"{did_you_mean(str(dist), DISTRIBUTIONS)}"
        )
    keys = DISTRIBUTIONS[dist]
    reject_unknown(f"{where}.", [k for k in d if k != "dist"], keys, error=StudyError)
    for k in keys:
        if k not in d:
            raise StudyError(f"{where}: dist = {dist!r} needs {k!r} (it needs {list(keys)})")
    args: dict[str, Any] = {}
    if dist == "values":
        vals = d["values"]
        if not isinstance(vals, list) or not vals:
            raise StudyError(f"{where}.values = {vals!r}: must be a non-empty list of numbers")
        args["values"] = tuple(_number(f"{where}.values[{i}]", v) for i, v in enumerate(vals))
        if len(set(args["values"])) != len(args["values"]):
            raise StudyError(f"{where}.values = {vals!r}: values repeat")
    else:
        for k in keys:
            args[k] = _number(f"{where}.{k}", d[k])
        if "std" in args and args["std"] <= 0:
            raise StudyError(f"{where}.std = {args['std']!r}: must be > 0")
        if "low" in args and not args["low"] < args["high"]:
            raise StudyError(
                f"{where}.low = {args['low']!r}: must be below high = {args['high']!r}"
            )
        if dist == "loguniform" and args["low"] <= 0:
            raise StudyError(f"{where}.low = {args['low']!r}: must be > 0 for dist = 'loguniform'")
        if dist == "truncnormal" and not args["low"] <= args["mean"] <= args["high"]:
            raise StudyError(
                f"{where}.mean = {args['mean']!r}: must lie within [low, high] = "
                f"[{args['low']!r}, {args['high']!r}]"
            )
    return Parameter(str(name), str(dist), args)


def _resolve(source: Any, base: Path | None, where: str) -> str | Path:
    """A built-in name as is, a file path relative to the study file."""
    if not isinstance(source, str) or not source:
        raise StudyError(f"{where} = {source!r}: must be a built-in name or a .toml file")
    if source.endswith(".toml"):
        p = Path(source)
        return p if p.is_absolute() or base is None else base / p
    return source


def _names(v: Any, where: str) -> list[Any]:
    if isinstance(v, str):
        v = [v]
    if not isinstance(v, list) or not v:
        raise StudyError(f"{where} = {v!r}: must be a non-empty list of names or files")
    return v


@dataclass(frozen=True, kw_only=True)
class Study:
    """A robustness study (see the module docstring for the keys; SI units).

    ``parameters``: the uncertain parameters; ``method``, ``samples``, ``seed``: the sampling;
    ``controllers``, ``scenarios``: built-in names or files (each sample runs under every
    controller on every scenario); ``model``, ``params``: model kind and parameter set;
    ``metrics``: the figures of merit kept per run; ``criteria``: the pass criteria;
    ``t_end``/``rtol``: the runs' horizon [s] and tolerance (None: the scenario's / default);
    ``linear``: the paired linear figures of every run (``lin:`` columns,
    :func:`~drivetrain_ctrl.studies.case.linear_figures`).
    """

    name: str
    parameters: tuple[Parameter, ...]
    method: str
    samples: int
    seed: int
    controllers: tuple[str | Path, ...]
    scenarios: tuple[str | Path, ...]
    model: str = "reduced"
    params: str | Path = DEFAULT_SET
    metrics: tuple[str, ...] = ()
    criteria: tuple[Criterion, ...] = ()
    t_end: float | None = None
    rtol: float | None = None
    description: str = ""
    linear: bool = True
    _specs: dict[str, ControllerSpec] = field(
        default_factory=dict, repr=False, compare=False, hash=False
    )
    _scenario_names: tuple[str, ...] = field(default=(), repr=False, compare=False, hash=False)
    _params: DrivetrainParams | None = field(default=None, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        self._check()

    # -- construction --------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, base: Path | None = None) -> Study:
        """A study from the table of a study file (``base``: the folder that relative file
        names are taken from). Everything is checked here; :class:`StudyError` names the key."""
        if not isinstance(d, Mapping):
            raise StudyError(f"study: a table is needed, got {d!r}")
        reject_unknown("", d, ["study", "sampling", "parameters"], error=StudyError)
        s = d.get("study")
        if not isinstance(s, Mapping):
            raise StudyError("study: the [study] table is missing")
        reject_unknown(
            "study.",
            s,
            [
                "name",
                "description",
                "model",
                "params",
                "controllers",
                "scenarios",
                "metrics",
                "criteria",
                "t_end",
                "rtol",
                "linear",
            ],
            error=StudyError,
        )
        name = s.get("name")
        if not isinstance(name, str) or not name.strip():
            raise StudyError(f"study.name = {name!r}: must be a non-empty string")
        description = s.get("description", "")
        if not isinstance(description, str):
            raise StudyError(f"study.description = {description!r}: must be a string")
        model = s.get("model", "reduced")
        if model not in MODELS:
            raise StudyError(f"study.model = {model!r}: must be one of {MODELS}")
        params = _resolve(s.get("params", DEFAULT_SET), base, "study.params")
        controllers = tuple(
            _resolve(c, base, f"study.controllers[{i}]")
            for i, c in enumerate(_names(s.get("controllers"), "study.controllers"))
        )
        scenarios = tuple(
            _resolve(c, base, f"study.scenarios[{i}]")
            for i, c in enumerate(_names(s.get("scenarios"), "study.scenarios"))
        )
        crit_in = s.get("criteria", [])
        if not isinstance(crit_in, list):
            raise StudyError(f"study.criteria = {crit_in!r}: must be a list of strings")
        criteria = tuple(_parse_criterion(c, f"study.criteria[{i}]") for i, c in enumerate(crit_in))
        metrics_in = s.get("metrics")
        if metrics_in is None:
            metrics = tuple(k for k, v in METRICS.items() if v.kind == "figure")
        else:
            if not isinstance(metrics_in, list) or not metrics_in:
                raise StudyError(f"study.metrics = {metrics_in!r}: must be a non-empty list")
            for i, k in enumerate(metrics_in):
                if k not in METRICS:
                    raise StudyError(
                        f"study.metrics[{i}] = {k!r}: unknown metric{did_you_mean(str(k), METRICS)}"
                    )
            metrics = tuple(dict.fromkeys(metrics_in))
        metrics = tuple(dict.fromkeys([*metrics, *(c.metric for c in criteria)]))
        linear = s.get("linear", True)
        if not isinstance(linear, bool):
            raise StudyError(f"study.linear = {linear!r}: must be true or false")
        t_end = s.get("t_end")
        rtol = s.get("rtol")
        for k, v in (("t_end", t_end), ("rtol", rtol)):
            if v is not None and not (is_finite_real(v) and v > 0):
                raise StudyError(f"study.{k} = {v!r}: must be a finite number > 0")

        sm = d.get("sampling")
        if not isinstance(sm, Mapping):
            raise StudyError("sampling: the [sampling] table is missing")
        reject_unknown("sampling.", sm, ["method", "samples", "seed"], error=StudyError)
        method = sm.get("method")
        if method not in METHODS:
            raise StudyError(
                f"sampling.method = {method!r}: must be one of {METHODS}"
                f"{did_you_mean(str(method), METHODS)}"
            )
        seed = sm.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise StudyError(f"sampling.seed = {seed!r}: must be an integer >= 0")

        pin = d.get("parameters", {})
        if not isinstance(pin, Mapping):
            raise StudyError(f"parameters = {pin!r}: must be a table of parameter tables")
        parameters = tuple(_parameter(k, v) for k, v in pin.items())
        if method == "grid":
            for p in parameters:
                if p.dist != "values":
                    raise StudyError(
                        f"parameters.{p.name!r}.dist = {p.dist!r}: sampling.method = 'grid' "
                        "needs a list of values for every parameter"
                    )
            n_grid = math.prod(len(p.args["values"]) for p in parameters)
            if "samples" in sm and sm["samples"] != n_grid:
                raise StudyError(
                    f"sampling.samples = {sm['samples']!r}: a grid has as many samples as the "
                    f"product of the value counts ({n_grid}); leave samples out"
                )
            samples = n_grid
        else:
            samples_in: Any = sm.get("samples")
            if isinstance(samples_in, bool) or not isinstance(samples_in, int) or samples_in < 1:
                raise StudyError(f"sampling.samples = {samples_in!r}: must be an integer >= 1")
            samples = samples_in
        study = cls(
            name=name,
            description=description,
            parameters=parameters,
            method=str(method),
            samples=int(samples),
            seed=int(seed),
            controllers=controllers,
            scenarios=scenarios,
            model=str(model),
            params=params,
            metrics=metrics,
            criteria=criteria,
            t_end=None if t_end is None else float(t_end),
            rtol=None if rtol is None else float(rtol),
            linear=linear,
        )
        return study

    def _check(self) -> None:
        """Load every named thing once and try the parameters' bounds (no simulation)."""
        try:
            p = (
                self.params
                if isinstance(self.params, DrivetrainParams)
                else load_params(self.params)
            )
        except FileNotFoundError:
            raise StudyError(f"study.params = {str(self.params)!r}: file not found") from None
        except ValueError as exc:
            raise StudyError(f"study.params = {str(self.params)!r}: {exc}") from None
        scenario_names: list[str] = []
        loaded = []
        for i, sc in enumerate(self.scenarios):
            try:
                s = load_scenario(sc, params=p)
            except FileNotFoundError:
                raise StudyError(f"study.scenarios[{i}] = {str(sc)!r}: file not found") from None
            except ValueError as exc:
                raise StudyError(f"study.scenarios[{i}] = {str(sc)!r}: {exc}") from None
            if not s.needs_controller:
                raise StudyError(
                    f"study.scenarios[{i}] = {str(sc)!r}: an open-loop scenario (it gives the "
                    "pedal); a study compares controllers on closed-loop scenarios (paper-start)"
                )
            if s.name in scenario_names:
                raise StudyError(f"study.scenarios[{i}] = {str(sc)!r}: {s.name!r} given twice")
            scenario_names.append(s.name)
            loaded.append(s)
        object.__setattr__(self, "_scenario_names", tuple(scenario_names))
        specs: dict[str, ControllerSpec] = {}
        for i, c in enumerate(self.controllers):
            try:
                spec = load_controller(c)
            except (ControllerError, ValueError) as exc:  # a missing file is a ValueError
                raise StudyError(f"study.controllers[{i}] = {str(c)!r}: {exc}") from None
            if spec.name in specs:
                raise StudyError(
                    f"study.controllers[{i}] = {str(c)!r}: a second controller named {spec.name!r}"
                )
            specs[spec.name] = spec
        object.__setattr__(self, "_specs", specs)
        object.__setattr__(self, "_params", p)
        for prm in self.parameters:
            where = f"parameters.{prm.name!r}"
            if prm.name.startswith(CONTROLLER_PREFIX):
                gain = prm.name.removeprefix(CONTROLLER_PREFIX)
                fixed = ("name", "law", "design")  # what a controller is, not a number to vary
                if gain in fixed:
                    raise StudyError(
                        f"{where}: the controller's {gain} cannot be a study parameter"
                    )
                names = [f.name for f in dataclasses.fields(ControllerSpec) if f.name not in fixed]
                if gain not in names:
                    raise StudyError(
                        f"{where}: unknown controller setting {gain!r}{did_you_mean(gain, names)}"
                    )
                for spec in specs.values():
                    if getattr(spec, gain) is None:
                        raise StudyError(
                            f"{where}: controller {spec.name!r} (law {spec.law!r}) has no {gain}"
                        )
                    for v in prm.support():
                        try:
                            change: dict[str, Any] = {gain: v}
                            dataclasses.replace(spec, **change)
                        except (ControllerError, ValueError) as exc:
                            raise StudyError(f"{where} = {v!r}: {exc}") from None
                continue
            if prm.name.startswith(SCENARIO_PREFIX):
                fld = prm.name.removeprefix(SCENARIO_PREFIX)
                if fld not in SCENARIO_FIELDS:
                    raise StudyError(
                        f"{where}: unknown scenario field {fld!r}"
                        f"{did_you_mean(fld, SCENARIO_FIELDS)}; the fields a study may vary: "
                        f"{', '.join(SCENARIO_FIELDS)}"
                    )
                for s in loaded:
                    for v in prm.support():
                        try:
                            new: dict[str, Any] = {fld: float(v)}
                            dataclasses.replace(s, **new)
                        except ValueError as exc:
                            raise StudyError(f"{where} = {v!r}: {exc}") from None
                continue
            try:
                p.get(prm.name)
            except ParameterError as exc:
                raise StudyError(f"{where}: {exc}") from None
            for v in prm.support():
                try:
                    p.replace(**{prm.name: v})
                except (ParameterError, ValueError, TypeError) as exc:
                    raise StudyError(f"{where} = {v!r}: {exc}") from None
        for i, m in enumerate(self.metrics):
            if m not in METRICS:
                raise StudyError(f"study.metrics[{i}] = {m!r}: unknown metric")

    # -- what a study runs ---------------------------------------------------------------------
    @property
    def controller_names(self) -> tuple[str, ...]:
        """The controllers' names (their ``name`` field), in the study's order."""
        return tuple(self._specs)

    @property
    def scenario_names(self) -> tuple[str, ...]:
        """The scenarios' names (their ``name`` field), in the study's order."""
        return self._scenario_names

    def keys(self) -> list[str]:
        """Every row key ``s<sample>|<controller>|<scenario>``, in the order of the table."""
        return [
            row_key(i, c, s)
            for i in range(self.samples)
            for c in self.controller_names
            for s in self.scenario_names
        ]

    def case(
        self, sample: int, values: Mapping[str, float], controller: str, scenario: int
    ) -> Case:
        """The :class:`Case` of one sample (``values``: parameter name -> value) under
        ``controller`` (a name of :attr:`controller_names`) on the ``scenario``-th scenario."""
        spec = self._specs[controller]
        gains: dict[str, Any] = {
            k.removeprefix(CONTROLLER_PREFIX): v
            for k, v in values.items()
            if k.startswith(CONTROLLER_PREFIX)
        }
        if gains:
            spec = dataclasses.replace(spec, **gains)
        return Case(
            scenario=self.scenarios[scenario],
            # the set loaded once (not re-read from its file for every case)
            params=self._params if self._params is not None else self.params,
            overrides={
                k: v
                for k, v in values.items()
                if not k.startswith((CONTROLLER_PREFIX, SCENARIO_PREFIX))
            },
            scenario_overrides={
                k.removeprefix(SCENARIO_PREFIX): v
                for k, v in values.items()
                if k.startswith(SCENARIO_PREFIX)
            },
            model=self.model,
            controller=spec,
            rtol=self.rtol,
            t_end=self.t_end,
            label=row_key(sample, controller, self.scenario_names[scenario]),
            linear=self.linear,
        )

    def to_dict(self) -> dict[str, Any]:
        """The study as a JSON-ready dict (what :attr:`digest` hashes)."""
        return {
            "name": self.name,
            "model": self.model,
            "params": str(self.params),
            "controllers": [str(c) for c in self.controllers],
            "controller_specs": {
                k: dataclasses.asdict(v) | {"design": None} for k, v in self._specs.items()
            },
            "scenarios": [str(s) for s in self.scenarios],
            "metrics": list(self.metrics),
            "criteria": [c.text for c in self.criteria],
            "t_end": self.t_end,
            "rtol": self.rtol,
            "linear": self.linear,
            "method": self.method,
            "samples": self.samples,
            "seed": self.seed,
            "parameters": {p.name: {"dist": p.dist, **p.args} for p in self.parameters},
        }

    @property
    def digest(self) -> str:
        """SHA-256 of :meth:`to_dict` and the parameters' order (the j-th parameter takes the j-th
        column of the unit sample, so the order changes the samples): results in a folder
        belong to the study with this digest."""
        d = {**self.to_dict(), "parameter_order": [p.name for p in self.parameters]}
        text = json.dumps(d, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()

    def summary(self) -> str:
        """One sentence: what the study runs."""
        prm = ", ".join(p.name for p in self.parameters) or "no parameters"
        return (
            f"study {self.name!r}: {self.samples} samples ({self.method}, seed {self.seed}) of "
            f"{prm} x {len(self._specs)} controller(s) x {len(self.scenarios)} scenario(s) on "
            f"the {self.model} model = {self.samples * len(self._specs) * len(self.scenarios)} "
            f"runs, {len(self.criteria)} criteria"
        )


def row_key(sample: int, controller: str, scenario: str) -> str:
    """The key of one row: ``s<sample, 6 digits>|<controller>|<scenario>``."""
    return f"s{sample:06d}|{controller}|{scenario}"


def load_study(path: str | Path) -> Study:
    """The study of TOML file ``path`` (relative file names inside taken from its folder);
    :class:`StudyError` naming the key (and the file) for anything it cannot run."""
    p = Path(path)
    if not p.is_file():
        raise StudyError(f"study file {str(path)!r}: not found")
    d = read_toml(p, error=StudyError)
    try:
        return Study.from_dict(d, base=p.parent)
    except StudyError as exc:
        raise StudyError(f"{exc} (in {p})") from None


def _unit_sample(study: Study) -> F64:
    """(samples, d) points in [0, 1)^d of the study's method and seed."""
    from scipy.stats import qmc

    d = len(study.parameters)
    n = study.samples
    if d == 0:
        return np.zeros((n, 0))
    if study.method == "mc":
        return np.random.default_rng(study.seed).random((n, d))
    if study.method == "lhs":
        return np.asarray(qmc.LatinHypercube(d=d, seed=study.seed).random(n), dtype=float)
    with warnings.catch_warnings():  # a count that is not a power of 2 only loses balance
        warnings.simplefilter("ignore", UserWarning)
        return np.asarray(qmc.Sobol(d=d, scramble=True, seed=study.seed).random(n), dtype=float)


def sample_table(study: Study) -> pd.DataFrame:
    """The samples: one row per sample (index ``sample`` 0..n-1), one column per parameter (SI
    units). Deterministic: the same study (seed included) gives the same table."""
    if study.method == "grid":
        grids = [np.asarray(p.args["values"], dtype=float) for p in study.parameters]
        mesh = np.meshgrid(*grids, indexing="ij") if grids else []
        cols = {p.name: m.reshape(-1) for p, m in zip(study.parameters, mesh, strict=True)}
    else:
        u = _unit_sample(study)
        cols = {p.name: p.ppf(u[:, j]) for j, p in enumerate(study.parameters)}
    df = pd.DataFrame(cols, index=pd.RangeIndex(study.samples, name="sample"))
    return df
