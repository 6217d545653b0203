"""A clutch controller from a design spec file: the plant set, the method, the controller file, and
the check on the switching plant (what ``drivetrain-ctrl design`` runs).

A design spec is a TOML file (unknown keys are errors naming the key)::

    name = "robust-pi"            # the controller's name (default: the output file's stem)
    description = "..."           # optional, kept in the controller file's provenance
    method = "robust-pi"          # optional: pi | robust-pi | pid | hinf; must match the command

    [plants]                      # the plant set: clutch_plant_set's keywords
    params = "passenger-car"      # parameter set name or .toml file (default: the default set)
    scenario = "paper-start"      # the trajectory giving the operating points ...
    controller = "pi"             # ... run with this controller
    kind = "reduced"              # model of the linearisation: reduced | full
    times = 3                     # instants [s], or a number of them over the slip phase
    sampling = "vertices"         # or a number of Latin-hypercube samples (with seed)
    sample_period = 0.01          # optional: ZOH-sampled plants (default: the controller's own)
    delay_samples = 1             # optional: the transport delay [samples]
    minimal = false

    [plants.box]                  # the parameter box (design.clutch)
    "clutch.k12_max" = {factor = [0.6, 1.4]}
    "actuator.omega_a" = [100.0, 300.0]

    [design]                      # the method's options (see below)
    ms = 1.4

    [controller]                  # the controller file's own settings
    x_r0 = 0.07                   # [m] (default: law (6)'s)
    engage_rate_m_s = 0.05
    form = "ss"                   # an LTI law as num/den ("tf") or A, B, C, D ("ss")

    [check]                       # the run on the switching plant
    scenario = "paper-start"
    models = ["reduced", "full"]
    params = "passenger-car"      # default: [plants] params

The methods (:data:`METHODS`) and the options their ``[design]`` table takes:

``pi``
    :func:`~drivetrain_ctrl.design.pi.design_pi` on one plant of the set, ``nominal`` (index;
    default: the first plant whose delay is the controller file's, i.e. the nominal point of the
    first instant): ``wc`` [rad/s], ``phase_margin`` [deg],
    ``ms``, ``integrator`` (discrete integrator), ``pade_order``; the PI is then checked on every
    plant of the set.
``robust-pi``, ``pid``
    :func:`~drivetrain_ctrl.design.robust.robust_pi` / ``robust_pid`` over the whole set: the
    fields of :class:`~drivetrain_ctrl.design.robust.RobustSpec` (``ms``, ``mt``, ``ks_max``,
    ``tf``, ``integrator``, ...).
``hinf``
    :func:`~drivetrain_ctrl.design.hinf.hinf_mixsyn`: the fields of
    :class:`~drivetrain_ctrl.design.hinf.HinfSpec` (``bandwidth``, ``ms``, ``mt``, ``effort``,
    ``nominal`` (default as for ``pi``), ``order``, ``dt``, ``time_limit``, ...); weights
    ``W1``, ``W2``, ``W3`` as
    tables ``{num = [...], den = [...]}`` (continuous, descending powers of s).

Every method's achieved figures come per plant from the design tools' loop check
(:func:`~drivetrain_ctrl.design.checks.check_loop`, a dense grid with the exact delay) of its
controller (:class:`PlantFigures`); the *limiting* plants are, for the robust tuners,
those whose constraint is active, else the plant with the largest ``|S|``.

The controller file (:class:`~drivetrain_ctrl.control.laws.ControllerSpec`): a PI that is
continuous or has the forward-Euler integrator becomes ``law = "pi"`` (the shipped PI's form),
anything else ``law = "lti"`` (PID: ``num``/``den``; H-infinity: the matrices of its reduced,
balanced realisation). A sampled plant set gives a sampled controller with the set's period and
the delay ``[controller] delay_samples`` (default ``[plants] delay_samples``, else the
``[plants]`` controller's own). Its ``[design]`` table records the method, the spec and the
achieved figures (provenance, shown in the controller report).

:func:`check_on_switching_plant` then runs the controller on the switching plant
(``paper-start`` by default, both models) and says loudly what went wrong: an engine stall (the
engine's friction at standstill, or its speed below :data:`STALL_SPEED_RPM`), no lock-up, the
Zeno guard, a failed simulation.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import control
import numpy as np

from ..control.laws import ControllerSpec, UnstableLoopWarning, load_controller, spec_from_lti
from ..core.registry import builtin_files, load_builtin_or_toml, load_toml_as
from ..core.serialize import round_sig
from ..core.validate import did_you_mean, reject_unknown
from ..plant.params import DEFAULT_SET, load_params
from ..scenarios.scenario import load_scenario
from ..sim.metrics import engagement_metrics
from ..sim.run import run_scenario
from ..sim.simulator import ZenoError
from .checks import LoopCheck, check_plant_set, worst_figures
from .clutch import ClutchPlantSet, clutch_plant_set
from .hinf import HinfDesign, HinfSpec, hinf_mixsyn
from .pi import PIDesign, design_pi
from .robust import RobustSpec, RobustTuning, robust_pi, robust_pid

__all__ = [
    "METHODS",
    "DesignSpec",
    "DesignSpecError",
    "DesignRun",
    "PlantFigures",
    "SwitchingRun",
    "SwitchingCheck",
    "builtin_design_specs",
    "load_design_spec",
    "design_from_spec",
    "check_on_switching_plant",
    "STALL_SPEED_RPM",
]

#: the design methods a spec can name (the command's first argument)
METHODS: tuple[str, ...] = ("pi", "robust-pi", "pid", "hinf")

#: the top-level keys and tables of a design spec
_TOP_KEYS = ("name", "description", "method", "plants", "design", "controller", "check")

#: keys of the ``[controller]`` table
_CONTROLLER_KEYS = (
    "x_r0",
    "engage_rate_m_s",
    "rate_limit_m_s",
    "anti_windup",
    "back_calculation_time_s",
    "delay_samples",
    "form",
)

#: keys of the ``[check]`` table
_CHECK_KEYS = ("scenario", "models", "params")

#: model kinds of the switching-plant check
MODELS: tuple[str, ...] = ("reduced", "full")

#: significant digits of the achieved figures written into a controller file's provenance
PROVENANCE_DIGITS: int = 6

#: the package whose ``specs/`` folder holds the built-in design specs
_PACKAGE = __name__.rpartition(".")[0]


class DesignSpecError(ValueError):
    """A design spec that cannot be used as given (the message names the key and the value)."""


def _plants_keys() -> tuple[str, ...]:
    """The keywords of :func:`~drivetrain_ctrl.design.clutch.clutch_plant_set` a spec may give
    (not the Python-only ``trajectory`` and ``operating_points``)."""
    sig = inspect.signature(clutch_plant_set)
    return tuple(k for k in sig.parameters if k not in ("trajectory", "operating_points"))


def _design_keys(method: str) -> tuple[str, ...]:
    """The ``[design]`` keys ``method`` accepts."""
    if method == "pi":
        sig = inspect.signature(design_pi)
        return (*(k for k in sig.parameters if k not in ("plant", "grid")), "nominal")
    if method in ("robust-pi", "pid"):
        return tuple(f.name for f in dataclasses.fields(RobustSpec))
    return tuple(f.name for f in dataclasses.fields(HinfSpec))


@dataclass(frozen=True)
class DesignSpec:
    """A design spec, as read (module docstring): ``plants``, ``design``, ``controller``,
    ``check`` are its tables (plain dicts, TOML types); ``source`` where it came from (a file
    name, or ``"<dict>"``)."""

    name: str | None
    description: str
    method: str | None
    plants: Mapping[str, Any]
    design: Mapping[str, Any]
    controller: Mapping[str, Any]
    check: Mapping[str, Any]
    source: str = "<dict>"

    def to_dict(self) -> dict[str, Any]:
        """The spec in its TOML form (None entries left out)."""
        out: dict[str, Any] = {}
        for k in ("name", "description", "method"):
            v = getattr(self, k)
            if v:
                out[k] = v
        for k in ("plants", "design", "controller", "check"):
            v = getattr(self, k)
            if v:
                out[k] = _plain(v)
        return out


def _plain(v: Any) -> Any:
    """Nested mappings as dicts (for TOML / JSON)."""
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_plain(x) for x in v]
    return v


def _table(where: str, d: Mapping[str, Any], key: str) -> dict[str, Any]:
    v = d.get(key, {})
    if not isinstance(v, Mapping):
        raise DesignSpecError(f"{where}{key} = {v!r}: must be a table")
    return dict(v)


def design_spec_from_dict(d: Mapping[str, Any], *, source: str = "<dict>") -> DesignSpec:
    """A :class:`DesignSpec` from its TOML form; unknown keys (top level, ``[plants]``,
    ``[controller]``, ``[check]``) are errors naming the key. ``[design]`` is checked against the
    method when it is known (:func:`design_from_spec`)."""
    if not isinstance(d, Mapping):
        raise DesignSpecError(f"design spec = {d!r}: must be a table")
    reject_unknown("", set(d), _TOP_KEYS, error=DesignSpecError)
    name = d.get("name")
    if name is not None and (not isinstance(name, str) or not name.strip()):
        raise DesignSpecError(f"name = {name!r}: must be a non-empty string")
    desc = d.get("description", "")
    if not isinstance(desc, str):
        raise DesignSpecError(f"description = {desc!r}: must be a string")
    method = d.get("method")
    if method is not None and method not in METHODS:
        hint = did_you_mean(str(method), METHODS)
        raise DesignSpecError(f"method = {method!r}: must be one of {METHODS}{hint}")
    plants = _table("", d, "plants")
    reject_unknown("plants.", set(plants), _plants_keys(), error=DesignSpecError)
    design = _table("", d, "design")
    if method is not None:
        reject_unknown("design.", set(design), _design_keys(method), error=DesignSpecError)
    ctrl = _table("", d, "controller")
    reject_unknown("controller.", set(ctrl), _CONTROLLER_KEYS, error=DesignSpecError)
    form = ctrl.get("form")
    if form is not None and form not in ("tf", "ss"):
        raise DesignSpecError(f"controller.form = {form!r}: must be 'tf' or 'ss'")
    check = _table("", d, "check")
    reject_unknown("check.", set(check), _CHECK_KEYS, error=DesignSpecError)
    models = check.get("models", list(MODELS))
    if (
        isinstance(models, str)
        or not isinstance(models, Sequence)
        or not models
        or any(m not in MODELS for m in models)
    ):
        raise DesignSpecError(f"check.models = {models!r}: a non-empty list of {MODELS}")
    return DesignSpec(
        name=name,
        description=desc,
        method=method,
        plants=plants,
        design=design,
        controller=ctrl,
        check=check,
        source=source,
    )


@functools.cache
def _builtin_specs() -> dict[str, DesignSpec]:
    out = {}
    for stem, f in builtin_files(_PACKAGE, "specs").items():
        out[stem] = load_toml_as(
            f,
            functools.partial(design_spec_from_dict, source=f"{stem}.toml"),
            error=DesignSpecError,
        )
    return out


def builtin_design_specs() -> dict[str, DesignSpec]:
    """The built-in design specs by name (``design/specs/*.toml``): the specs that produced the
    built-in designed controllers of the same name (``control/builtin/``)."""
    return dict(_builtin_specs())


def load_design_spec(source: str | Path | Mapping[str, Any] | DesignSpec) -> DesignSpec:
    """A design spec: a built-in name (:func:`builtin_design_specs`), a TOML file, a mapping of
    its TOML form, or a :class:`DesignSpec` (returned as is)."""
    if isinstance(source, DesignSpec):
        return source
    if isinstance(source, Mapping):
        return design_spec_from_dict(source)
    if not isinstance(source, str | Path):
        raise DesignSpecError(
            f"spec = {source!r}: give a built-in design spec name, a .toml path or a mapping"
        )
    name = Path(source).name

    def from_dict(d: dict[str, Any]) -> DesignSpec:
        return design_spec_from_dict(d, source=name)

    return load_builtin_or_toml(
        source, _builtin_specs(), from_dict, what="design spec", error=DesignSpecError
    )


# ---------------------------------------------------------------------------------------------
# per-plant figures
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlantFigures:
    """One plant's loop with the designed controller (a row of its
    :class:`~drivetrain_ctrl.design.checks.LoopCheck`, a dense grid with the exact delay): ``ms``, ``mt`` peak ``|S|``, ``|T|``; ``ks`` peak ``|K S|``
    [m s/rad]; ``gain_margin_db``, ``phase_margin_deg``, ``crossover_rad_s`` (None: no such
    crossover); ``disk_margin_db``, ``disk_margin_deg`` (symmetric disk margin); ``stable``
    (None: not checked); ``limiting``: the plant limits the design."""

    plant: str
    ms: float
    mt: float
    ks: float
    gain_margin_db: float | None
    phase_margin_deg: float | None
    crossover_rad_s: float | None
    disk_margin_db: float
    disk_margin_deg: float
    stable: bool | None
    limiting: bool = False


def _figures(c: LoopCheck, limiting: bool = False) -> PlantFigures:
    """The row of one :class:`~drivetrain_ctrl.design.checks.LoopCheck`."""
    return PlantFigures(
        plant=c.name,
        ms=c.ms,
        mt=c.mt,
        ks=c.ks,
        gain_margin_db=c.gain_margin_db,
        phase_margin_deg=c.phase_margin_deg,
        crossover_rad_s=c.crossover_rad_s,
        disk_margin_db=c.disk_margin_db,
        disk_margin_deg=c.disk_margin_deg,
        stable=c.stable,
        limiting=limiting,
    )


def _mark_worst_ms(rows: list[PlantFigures]) -> list[PlantFigures]:
    """The plant with the largest ``|S|`` is the limiting one (no active-set information)."""
    k = int(np.argmax([r.ms for r in rows]))
    return [dataclasses.replace(r, limiting=(i == k)) for i, r in enumerate(rows)]


# ---------------------------------------------------------------------------------------------
# the design
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DesignRun:
    """A design made from a spec (:func:`design_from_spec`).

    ``method``; ``spec`` (:class:`DesignSpec`); ``plant_set`` (the clutch plants); ``result``
    (the method's own result: :class:`~drivetrain_ctrl.design.pi.PIDesign`,
    :class:`~drivetrain_ctrl.design.robust.RobustTuning` or
    :class:`~drivetrain_ctrl.design.hinf.HinfDesign`); ``controller`` the controller file
    (:class:`~drivetrain_ctrl.control.laws.ControllerSpec`, with its ``[design]`` provenance);
    ``plants``: :class:`PlantFigures` per plant; ``met``: the method says its specification is
    met (PI: feasible; robust: converged; H-infinity: gamma <= 1); ``message``; ``wall_time_s``.
    """

    method: str
    spec: DesignSpec
    plant_set: ClutchPlantSet
    result: Any
    controller: ControllerSpec
    plants: tuple[PlantFigures, ...]
    met: bool
    message: str
    wall_time_s: float

    @property
    def limiting(self) -> tuple[str, ...]:
        """Names of the plants that limit the design."""
        return tuple(p.plant for p in self.plants if p.limiting)

    def worst(self) -> dict[str, Any]:
        """The worst figures over the set: max Ms, Mt, ``|KS|``; min GM, PM, disk margin; the
        crossover range; all stable (None if one was not checked)."""
        # the clutch loop's |KS| unit in the key (controller output [m/s] per slip [rad/s])
        return {
            ("ks_max_m_s_rad" if k == "ks_max" else k): v
            for k, v in worst_figures(self.plants).items()
        }

    def check(self) -> SwitchingCheck:
        """The controller on the switching plant as the spec's ``[check]`` says
        (:func:`check_on_switching_plant`; default: ``paper-start`` on both models, with the
        ``[plants]`` parameter set)."""
        chk = self.spec.check
        return check_on_switching_plant(
            self.controller,
            params=chk.get("params", self.spec.plants.get("params")),
            scenario=chk.get("scenario", "paper-start"),
            models=tuple(chk.get("models", MODELS)),
        )

    def summary(self) -> str:
        """One sentence: method, plants, the worst figures, the limiting plants, the controller."""
        w = self.worst()
        stab = {True: "all loops stable", False: "UNSTABLE loop(s)", None: "stability unchecked"}
        gm = w["gain_margin_db_min"]
        pm = w["phase_margin_deg_min"]
        return (
            f"{self.method} design {self.controller.name!r} on {w['n_plants']} plants: worst Ms "
            f"{w['ms_max']:.3g}, Mt {w['mt_max']:.3g}, GM "
            f"{'inf' if gm is None else f'{gm:.1f}'} dB, PM "
            f"{'-' if pm is None else f'{pm:.1f}'} deg, disk margin "
            f"{w['disk_margin_db_min']:.1f} dB; {stab[w['all_stable']]}; limited by "
            f"{', '.join(self.limiting) or 'none'}; "
            f"{'specification met' if self.met else 'SPECIFICATION NOT MET'}: {self.message}"
        )


def _check_method(method: str) -> str:
    if method not in METHODS:
        hint = did_you_mean(str(method), METHODS)
        raise DesignSpecError(f"method = {method!r}: must be one of {METHODS}{hint}")
    return method


def _weights(where: str, design: dict[str, Any]) -> dict[str, Any]:
    """``W1``/``W2``/``W3`` given as ``{num, den}`` tables -> python-control transfer functions."""
    out = dict(design)
    for nm in ("W1", "W2", "W3"):
        W = out.get(nm)
        if W is None:
            continue
        if not isinstance(W, Mapping) or set(W) != {"num", "den"}:
            raise DesignSpecError(
                f"{where}{nm} = {W!r}: give a weight as {{num = [...], den = [...]}} (continuous, "
                "descending powers of s)"
            )
        try:
            out[nm] = control.tf([float(c) for c in W["num"]], [float(c) for c in W["den"]])
        except (TypeError, ValueError) as exc:
            raise DesignSpecError(f"{where}{nm} = {W!r}: {exc}") from None
    return out


def _controller_options(spec: DesignSpec, ts: float) -> tuple[dict[str, Any], int]:
    """The ControllerSpec fields of ``[controller]`` and the delay [samples] of a controller
    with sample period ``ts`` [s] (0: continuous, no delay)."""
    ctrl = dict(spec.controller)
    ctrl.pop("form", None)
    delay = ctrl.pop("delay_samples", None)
    if not ts:
        if delay:
            raise DesignSpecError(
                f"controller.delay_samples = {delay!r}: the designed controller is continuous "
                "(give plants.sample_period for a sampled design)"
            )
        return ctrl, 0
    if delay is None:
        delay = spec.plants.get("delay_samples")
    if delay is None:
        delay = load_controller(spec.plants.get("controller", "paper")).delay_samples
    return ctrl, delay


def _provenance(run_method: str, spec: DesignSpec, extra: dict[str, Any]) -> dict[str, Any]:
    def rnd(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: rnd(x) for k, x in v.items() if x is not None}
        if isinstance(v, list | tuple):
            return [rnd(x) for x in v]
        if isinstance(v, float):
            return round_sig(v, PROVENANCE_DIGITS) if math.isfinite(v) else v
        return v

    return {
        "method": run_method,
        "spec_file": spec.source,
        "spec": spec.to_dict(),
        "achieved": rnd(extra),
    }


def design_from_spec(
    method: str, spec: str | Path | Mapping[str, Any] | DesignSpec, *, name: str | None = None
) -> DesignRun:
    """Design a clutch controller with ``method`` (:data:`METHODS`) from the design spec ``spec``
    (a built-in name, a TOML file, a mapping or a :class:`DesignSpec`): build the plant set, run
    the method, check every plant, and make the controller file. ``name``: the controller's name
    (default: the spec's ``name``, else the method). Returns a :class:`DesignRun`.

    Raises :class:`DesignSpecError` (or the method's ValueError, e.g.
    :class:`~drivetrain_ctrl.design.robust.InfeasibleSpecError`) for a spec that cannot be
    designed as given; H-infinity's :class:`~drivetrain_ctrl.design.hinf.HinfTimeoutError` and
    :class:`~drivetrain_ctrl.design.hinf.HinfSynthesisError` pass through.
    """
    tic = time.perf_counter()
    method = _check_method(method)
    sp = load_design_spec(spec)
    if sp.method is not None and sp.method != method:
        raise DesignSpecError(
            f"method = {sp.method!r} in the spec ({sp.source}) but the command asks for "
            f"{method!r}: run `design {sp.method}` or change the spec"
        )
    reject_unknown("design.", set(sp.design), _design_keys(method), error=DesignSpecError)
    cname = name or sp.name or method
    kw = dict(sp.plants)
    box = kw.pop("box", None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableLoopWarning)
        try:
            pset = clutch_plant_set(**kw, box=box)
        except (TypeError, ValueError) as exc:
            raise DesignSpecError(f"plants: {exc}") from None
    opts = dict(sp.design)
    form = sp.controller.get("form")
    # the plant a single-plant design is made on: by default the first with the file's delay
    file_delay = _controller_options(sp, pset.sample_period)[1]
    nominal_default = next(
        (i for i, pt in enumerate(pset.points) if pt.get("delay_samples", 0) == file_delay), 0
    )
    result: Any
    rows: list[PlantFigures]
    if method == "pi":
        nominal = opts.pop("nominal", nominal_default)
        if (
            isinstance(nominal, bool)
            or not isinstance(nominal, int)
            or not 0 <= nominal < len(pset)
        ):
            raise DesignSpecError(
                f"design.nominal = {nominal!r}: an index of the {len(pset)} plants"
            )
        result = design_pi(pset[nominal], **opts)
        assert isinstance(result, PIDesign)
        C = result.controller
        rows = _mark_worst_ms([_figures(c) for c in check_plant_set(pset, C)])
        met, message = result.feasible, result.message or "the specification is met"
        ctrl = _pi_controller(cname, result.kp, result.ki, result.dt, result.integrator, C, form)
        extra: dict[str, Any] = {"kp": result.kp, "ki": result.ki, "rule": result.rule}
    elif method in ("robust-pi", "pid"):
        tuner = robust_pi if method == "robust-pi" else robust_pid
        result = tuner(pset, **opts)
        assert isinstance(result, RobustTuning)
        lim = set(result.limiting)
        rows = [_figures(c, c.name in lim) for c in result.plants]
        met, message = result.converged, result.message
        C = result.controller
        if result.structure == "pi":
            integ = result.spec.integrator if result.dt else "continuous"
            ctrl = _pi_controller(cname, result.kp, result.ki, result.dt, integ, C, form)
        else:
            ctrl = spec_from_lti(C, name=cname, form=form or "tf")
        extra = {
            "kp": result.kp,
            "ki": result.ki,
            **({"kd": result.kd, "tf": result.tf} if result.structure == "pid" else {}),
            "ki_history": list(result.ki_history),
            "converged": result.converged,
        }
    else:
        opts.setdefault("nominal", nominal_default)
        result = hinf_mixsyn(pset, **_weights("design.", opts))
        assert isinstance(result, HinfDesign)
        if result.controller_sampled is not None:
            K, checks = result.controller_sampled, result.checks_sampled
        else:
            K, checks = result.controller_reduced, result.checks_reduced
        rows = _mark_worst_ms([_figures(c) for c in checks])
        met = bool(result.specs_met)
        message = (
            f"gamma = {result.gamma:.4g} (re-checked {result.norm_check:.4g}), controller order "
            f"{result.order_full} -> {result.order_reduced}"
            + (f"; {' '.join(result.notes)}" if result.notes else "")
        )
        ctrl = spec_from_lti(K, name=cname, form=form or "ss")
        extra = {
            "gamma": result.gamma,
            "norm_check": result.norm_check,
            "order_full": result.order_full,
            "order_reduced": result.order_reduced,
            "specs_met": met,
        }
    # the controller file: period, delay, the [controller] settings, the provenance
    ts = float(ctrl.sample_period_s or 0.0)
    if method != "hinf" and abs(ts - pset.sample_period) > 1e-12 * max(ts, 1.0):
        raise DesignSpecError(
            f"the designed controller's sample period {ts!r} s differs from the plant set's "
            f"{pset.sample_period!r} s"
        )
    ctrl_opts, delay = _controller_options(sp, ts)
    first = DesignRun(method, sp, pset, result, ctrl, tuple(rows), met, message, 0.0)
    prov = _provenance(
        method,
        sp,
        {
            **extra,
            **first.worst(),
            "limiting": list(first.limiting),
            "met": met,
            "message": message,
            "plant_set": pset.summary(),
        },
    )
    try:
        ctrl = dataclasses.replace(ctrl, delay_samples=delay, design=prov, **ctrl_opts)
    except (TypeError, ValueError) as exc:
        raise DesignSpecError(f"controller: {exc}") from None
    return DesignRun(
        method=method,
        spec=sp,
        plant_set=pset,
        result=result,
        controller=ctrl,
        plants=tuple(rows),
        met=met,
        message=message,
        wall_time_s=time.perf_counter() - tic,
    )


def _pi_controller(
    name: str, kp: float, ki: float, dt: float, integrator: str, C: Any, form: str | None
) -> ControllerSpec:
    """A PI as a controller file: law ``"pi"`` (continuous, or the forward-Euler integrator)
    unless ``form`` asks for an LTI law; otherwise ``"lti"`` with ``C``."""
    if form is None and integrator in ("continuous", "forward"):
        return ControllerSpec(name=name, law="pi", kp=kp, ki=ki, sample_period_s=dt or None)
    return spec_from_lti(C, name=name, form=form or "tf")


# ---------------------------------------------------------------------------------------------
# the check on the switching plant
# ---------------------------------------------------------------------------------------------


#: the engagement figures the check reports (names of :func:`engagement_metrics`)
CHECK_METRICS: tuple[str, ...] = (
    "lockup_time_s",
    "engagement_time_s",
    "engine_speed_min_rpm",
    "engine_speed_max_rpm",
    "tracking_rms_rpm",
    "jerk_max_m_s3",
    "lurch_rad_s2",
    "clutch_energy_J",
    "n_events",
)


@dataclass(frozen=True)
class SwitchingRun:
    """One run of a controller on the switching plant: ``model``; ``metrics`` (None if the run
    failed); ``error`` (the simulator's message if it failed); ``problems``: plain statements of
    what went wrong (engine stall, no lock-up, the Zeno guard, a failed run), empty when the
    engagement is fine; ``warnings``: warnings raised while building or running."""

    model: str
    metrics: Mapping[str, Any] | None
    error: str | None
    problems: tuple[str, ...]
    warnings: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return not self.problems


@dataclass(frozen=True)
class SwitchingCheck:
    """A controller on the switching plant (:func:`check_on_switching_plant`): ``controller``
    name, ``scenario``, ``params`` name, ``runs`` per model."""

    controller: str
    scenario: str
    params: str
    runs: tuple[SwitchingRun, ...]

    @property
    def ok(self) -> bool:
        """True if every run locked up without a stall, a Zeno stop or a failure."""
        return all(r.ok for r in self.runs)

    def summary(self) -> str:
        """One sentence per model: locked up when, or what went wrong (in capitals)."""
        parts = []
        for r in self.runs:
            if r.ok:
                assert r.metrics is not None
                m = r.metrics
                parts.append(
                    f"{r.model} model: locked up at {m['lockup_time_s']:.3g} s, lowest engine "
                    f"speed {m['engine_speed_min_rpm']:.0f} rpm, jerk {m['jerk_max_m_s3']:.3g} m/s^3"
                )
            else:
                parts.append(f"{r.model} model: " + "; ".join(r.problems))
        return (
            f"controller {self.controller!r} on the switching plant ({self.scenario}, "
            f"{self.params}): " + "; ".join(parts) + "."
        )


#: lowest engine speed [rpm] of a run that counts as an engine stall: a real engine stalls well
#: above standstill (about half its idle speed; the model's engine keeps turning at any speed)
STALL_SPEED_RPM: float = 450.0


def _problems(m: Mapping[str, Any]) -> list[str]:
    out = []
    low = m.get("engine_speed_min_rpm")
    if m.get("engine_stalled") or (low is not None and low < STALL_SPEED_RPM):
        out.append(
            f"the engine STALLED (lowest engine speed {low:.0f} rpm"
            + (", its friction at standstill" if m.get("engine_stalled") else "")
            + f"; a stall is below {STALL_SPEED_RPM:g} rpm)"
        )
    if m.get("lockup_time_s") is None:
        out.append("the clutch NEVER LOCKED UP within the scenario")
    return out


def check_on_switching_plant(
    controller: str | Path | ControllerSpec,
    *,
    params: Any = None,
    scenario: Any = "paper-start",
    models: Sequence[str] = MODELS,
) -> SwitchingCheck:
    """Run ``controller`` (a spec, a built-in name or a controller file) on the switching plant:
    ``scenario`` (a closed-loop one) with parameter set ``params`` (None: the default set) on
    each of ``models``. A run that stops (the Zeno guard, a step-size failure) is a
    :class:`SwitchingRun` with ``error`` and the problem said, never an exception; so is an
    engine stall or a run without lock-up."""
    spec = load_controller(controller)
    p = load_params(DEFAULT_SET if params is None else params)
    sc = load_scenario(scenario, params=p)
    bad = [m for m in models if m not in MODELS]
    if bad or not models:
        raise DesignSpecError(f"models = {list(models)!r}: a non-empty list of {MODELS}")
    runs = []
    for kind in models:
        dt = sc.drivetrain(p, kind=kind)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                res = run_scenario(sc, dt, controller=spec)
            except ZenoError as exc:
                runs.append(
                    SwitchingRun(
                        kind,
                        None,
                        str(exc),
                        (f"the simulation TRIPPED THE ZENO GUARD: {exc}",),
                        tuple(str(w.message) for w in caught),
                    )
                )
                continue
            except RuntimeError as exc:
                runs.append(
                    SwitchingRun(
                        kind,
                        None,
                        str(exc),
                        (f"the simulation FAILED: {exc}",),
                        tuple(str(w.message) for w in caught),
                    )
                )
                continue
        m = engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
        runs.append(
            SwitchingRun(kind, m, None, tuple(_problems(m)), tuple(str(w.message) for w in caught))
        )
    return SwitchingCheck(spec.name, sc.name, p.name, tuple(runs))
