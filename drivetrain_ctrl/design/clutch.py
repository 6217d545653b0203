"""The clutch start's slip-mode loop plants, over a trajectory and a parameter box: the plant set
a clutch controller is designed on.

Each plant is the linear analysis's loop plant (:attr:`~drivetrain_ctrl.linear.clutch.ClutchLoop.plant`
of :func:`~drivetrain_ctrl.linear.clutch.clutch_loop`): controller output ``x_r`` [m] -> the
measured, signed engine-speed error [rad/s] through law (6)'s sign switch, the actuator
(``actuator.omega_a``, ``delta_a``), the pedal map's slope, the clutch (capacity and friction
slope) and the engine, with negative feedback ``L = C P``. So a PI ``C`` designed on these plants
is the LTI block of a controller file (``law = "pi"`` or ``"lti"``).

Operating points come from a trajectory: the scenario (default ``paper-start``) run with a
controller (default ``paper``); ``times`` picks instants of the slip phase. Each instant is re-made
as a slip point (:func:`~drivetrain_ctrl.linear.operating_point.slip_operating_point`) with the
trajectory's engine speed, driven speed, clutch position and throttle, so that it can be rebuilt
for every parameter vertex (the driveline twist is the quasi-static one of that point).

The parameter box maps names to ranges:

* a dotted parameter path of :class:`~drivetrain_ctrl.plant.params.DrivetrainParams`
  (``"clutch.k12_max"``: the friction coefficient, as the capacity scale; ``"engine.J1"``,
  ``"actuator.omega_a"``, ``"actuator.delta_a"``, ...): a pair ``(lo, hi)`` of absolute values
  [SI] or ``{"factor": (lo, hi)}`` relative to the parameter set's value;
* ``"pedal_slope"``: factor on the pedal map's slope around the point's ``x_c`` (the capacity at
  ``x_c`` kept; as :func:`~drivetrain_ctrl.linear.margins.root_locus` does it);
* ``"mu_slope"`` [s/rad]: the slope of ``mu(slip)/mu(0)`` in the linearisation (None, the
  default, is the parameter set's own table); a falling characteristic is negative, down to the
  judder threshold (:func:`~drivetrain_ctrl.linear.clutch.judder_crossing`);
* ``"delay_samples"``: a pair of whole numbers of samples (every integer between them is used),
  for a sampled design.

Any entry may instead be ``{"values": [...]}``, an explicit list. ``sampling="vertices"`` takes
every corner of the box (``2^d`` points), an integer ``n`` that many Latin-hypercube samples
(scipy.stats.qmc, ``seed``); the nominal point is added unless ``include_nominal=False``.
A sampled design (``sample_period`` [s], by default the controller's own, e.g. 0.01 s for
``pi-10ms``) gets the zero-order-hold plant (``control.sample_system``, as the linear analysis
samples a loop) and the transport delay ``delay_samples * sample_period`` as the plant's exact
input delay (:class:`~drivetrain_ctrl.design.plants.Plant`).
"""

from __future__ import annotations

import dataclasses
import itertools
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import control
import numpy as np

from drivetrain_ctrl.control.laws import ControllerSpec, load_controller
from drivetrain_ctrl.core.signals import constant
from drivetrain_ctrl.core.validate import did_you_mean, is_finite_real, real_number
from drivetrain_ctrl.design.plants import Plant, PlantSet
from drivetrain_ctrl.linear.clutch import clutch_loop
from drivetrain_ctrl.linear.margins import _scaled_pedal_map
from drivetrain_ctrl.linear.operating_point import (
    OperatingPoint,
    operating_point_from_result,
    slip_operating_point,
)
from drivetrain_ctrl.plant.drivetrain import Drivetrain
from drivetrain_ctrl.plant.params import DrivetrainParams, default_params, field_paths, load_params
from drivetrain_ctrl.scenarios.scenario import Scenario, load_scenario

__all__ = ["ClutchPlantSet", "clutch_plant_set", "SPECIAL_KEYS"]

#: box entries that are not parameter paths (module docstring)
SPECIAL_KEYS: tuple[str, ...] = ("pedal_slope", "mu_slope", "delay_samples")


@dataclass(frozen=True)
class ClutchPlantSet(PlantSet):
    """A :class:`~drivetrain_ctrl.design.plants.PlantSet` of clutch slip-mode loop plants (usable
    wherever a plant set is), with ``points``: per plant, a dict of where it comes from (``t``
    [s] of the trajectory, ``omega_engine``, ``omega_driven`` [rad/s], ``x_c`` [m],
    ``throttle``, the box values, ``delay_samples``, ``vertex``: the corner's lo/hi labels, or
    ``"nominal"``/``"sample k"``) and ``sample_period`` [s] (0.0 continuous)."""

    points: tuple[Mapping[str, Any], ...] = ()
    sample_period: float = 0.0

    def summary(self) -> str:
        """One sentence: how many plants, over which instants and box."""
        ts = sorted({round(float(p["t"]), 6) for p in self.points if p.get("t") is not None})
        keys = sorted({k for p in self.points for k in p.get("box", {})})
        smp = (
            f", sampled every {self.sample_period:g} s (ZOH) with delays "
            f"{sorted({int(p['delay_samples']) for p in self.points})} samples"
            if self.sample_period
            else ", continuous"
        )
        return (
            f"{len(self)} slip-mode loop plants (x_r -> signed engine-speed error) at "
            f"{len(ts) or len({p['op'] for p in self.points})} operating points"
            + (f" (t = {', '.join(f'{t:g}' for t in ts)} s)" if ts else "")
            + (f" over {', '.join(keys)}" if keys else "")
            + smp
            + "."
        )


@dataclass(frozen=True)
class _Dim:
    key: str
    values: tuple[Any, ...]  # (lo, hi) or explicit values, absolute (None: nominal)
    explicit: bool
    integer: bool = False


def _pair(where: str, v: object, *, integer: bool = False) -> tuple[float, float]:
    if isinstance(v, str | bytes) or not isinstance(v, Sequence) or len(v) != 2:
        raise ValueError(f"{where} = {v!r}: must be a pair (lo, hi)")
    lo, hi = (real_number(f"{where}[{i}]", x) for i, x in enumerate(v))
    if lo > hi:
        raise ValueError(f"{where} = {v!r}: lo must be <= hi")
    if integer and (lo != int(lo) or hi != int(hi) or lo < 0):
        raise ValueError(f"{where} = {v!r}: must be whole numbers of samples >= 0")
    return lo, hi


def _dims(box: Mapping[str, Any], params: DrivetrainParams) -> list[_Dim]:
    if not isinstance(box, Mapping):
        raise TypeError(f"box = {box!r}: must be a mapping {{name: (lo, hi)}}")
    paths = field_paths()
    dims = []
    for key, spec in box.items():
        where = f"box[{key!r}]"
        if key not in SPECIAL_KEYS:
            if key not in paths:
                hint = did_you_mean(str(key), [*paths, *SPECIAL_KEYS])
                raise ValueError(
                    f"box: {key!r} is neither a parameter path nor one of {SPECIAL_KEYS}{hint}"
                )
            if not is_finite_real(params.get(key)):
                raise ValueError(f"box: {key!r} is not a number parameter (a table or a text)")
        integer = key == "delay_samples"
        if isinstance(spec, Mapping):
            if set(spec) == {"values"}:
                vals = spec["values"]
                if isinstance(vals, str | bytes) or not isinstance(vals, Sequence) or not vals:
                    raise ValueError(f"{where}.values = {vals!r}: must be a non-empty list")
                out = tuple(real_number(f"{where}.values[{i}]", x) for i, x in enumerate(vals))
                if integer and any(x != int(x) or x < 0 for x in out):
                    raise ValueError(f"{where}.values = {vals!r}: whole numbers of samples >= 0")
                dims.append(_Dim(key, out, True, integer))
                continue
            if set(spec) != {"factor"}:
                bad = sorted(set(spec) - {"factor", "values"}) or sorted(spec)
                raise ValueError(
                    f"{where}: unknown key {bad[0]!r} = {spec.get(bad[0])!r}; give (lo, hi), "
                    "{'factor': (lo, hi)} or {'values': [...]}"
                )
            if key in ("mu_slope", "delay_samples", "pedal_slope"):
                raise ValueError(
                    f"{where} = {dict(spec)!r}: 'factor' applies to parameter paths only "
                    f"({key} is given absolutely)"
                )
            f_lo, f_hi = _pair(f"{where}.factor", spec["factor"])
            nom = float(params.get(key))
            dims.append(_Dim(key, (f_lo * nom, f_hi * nom), False))
        else:
            dims.append(_Dim(key, _pair(where, spec, integer=integer), False, integer))
    return dims


def _box_points(
    dims: list[_Dim], sampling: str | int, seed: int, include_nominal: bool
) -> list[tuple[str, dict[str, Any]]]:
    """``(label, {key: value})`` for every point of the box (delay dimension apart)."""
    cont = [d for d in dims if not d.integer]
    pts: list[tuple[str, dict[str, Any]]] = []
    if include_nominal or not cont:
        pts.append(("nominal", {}))
    if not cont:
        return pts
    if sampling == "vertices":
        axes = [d.values if d.explicit else tuple(dict.fromkeys(d.values)) for d in cont]
        for combo in itertools.product(*[range(len(a)) for a in axes]):
            vals = {d.key: a[i] for d, a, i in zip(cont, axes, combo, strict=True)}
            labels = []
            for d, i in zip(cont, combo, strict=True):
                labels.append(f"{d.key} {'lo' if i == 0 else 'hi'}" if not d.explicit else "")
            pts.append(("vertex " + ", ".join(x for x in labels if x) if labels else "", vals))
        return pts
    import scipy.stats.qmc as qmc

    n = int(sampling)
    u = qmc.LatinHypercube(d=len(cont), seed=seed).random(n)
    for k in range(n):
        vals = {}
        for j, d in enumerate(cont):
            if d.explicit:
                vals[d.key] = d.values[min(int(u[k, j] * len(d.values)), len(d.values) - 1)]
            else:
                lo, hi = d.values
                vals[d.key] = lo + u[k, j] * (hi - lo)
        pts.append((f"sample {k}", vals))
    return pts


def _fmt(v: Any) -> str:
    return "own" if v is None else f"{v:.4g}"


def _slip_instants(res: Any, start: float, n: int) -> list[float]:
    """``n`` instants [s] at the middles of ``n`` equal parts of the longest slip phase after
    the controller's start (the engagement; a brief slip before the clutch opens again is
    passed over)."""
    t = np.asarray(res.t)
    modes = np.asarray(res.mode_series("clutch"))
    slip = np.isin(modes, ("slip+", "slip-")) & (t >= start)
    if not slip.any():
        raise ValueError("the trajectory has no slip phase after the controller's start")
    phases: list[tuple[float, float]] = []
    k = 0
    while k < t.size:
        if slip[k]:
            k1 = k
            while k1 + 1 < t.size and slip[k1 + 1]:
                k1 += 1
            phases.append((float(t[k]), float(t[k1])))
            k = k1 + 1
        else:
            k += 1
    a, b = max(phases, key=lambda ab: ab[1] - ab[0])
    return [a + (j + 0.5) / n * (b - a) for j in range(n)]


def clutch_plant_set(
    params: DrivetrainParams | str | None = None,
    *,
    scenario: str | Scenario = "paper-start",
    controller: str | ControllerSpec = "paper",
    kind: str = "reduced",
    times: int | Sequence[float] = 5,
    trajectory: Any = None,
    operating_points: Sequence[OperatingPoint] | None = None,
    box: Mapping[str, Any] | None = None,
    sampling: str | int = "vertices",
    seed: int = 0,
    include_nominal: bool = True,
    sample_period: float | None = None,
    delay_samples: int | None = None,
    minimal: bool = False,
) -> ClutchPlantSet:
    """The clutch's slip-mode loop plants over operating points and a parameter box (module
    docstring).

    ``params``: the parameter set (a ``DrivetrainParams``, a set name or TOML file; None: the
    default set). ``scenario``, ``controller``, ``kind`` (``"reduced"`` or ``"full"``): the run
    giving the trajectory (or pass it as ``trajectory``, a ``SimulationResult`` of that scenario
    and kind). ``times``: instants [s] of the trajectory, or a number of instants spread evenly over
    its longest slip phase after the controller starts. ``operating_points``: slip points made by
    :func:`~drivetrain_ctrl.linear.operating_point.slip_operating_point` instead of a trajectory.
    ``box``, ``sampling``, ``seed``, ``include_nominal``: the parameter box. ``sample_period``
    [s]: ZOH-sampled plants (None: the controller's own period, continuous if it has none);
    ``delay_samples``: the transport delay [samples] when the box has no ``delay_samples`` entry
    (None: the controller's own). ``minimal``: drop the modes the loop does not see
    (``control.minreal``; with constant mu the driveline modes are uncontrollable from ``x_r``,
    and their near-cancellation in a sampled plant costs digits at low frequency); by default
    the plant is the linear analysis's as it is. Plants are named by instant and vertex.
    Returns a :class:`ClutchPlantSet`.
    """
    if params is None:
        p0 = default_params()
    elif isinstance(params, DrivetrainParams):
        p0 = params
    elif isinstance(params, str):
        p0 = load_params(params)
    else:
        raise TypeError(f"params = {params!r}: a DrivetrainParams, a set name or file, or None")
    if kind not in ("reduced", "full"):
        raise ValueError(f"kind = {kind!r}: must be 'reduced' or 'full'")
    spec = load_controller(controller)
    if sampling != "vertices" and (
        isinstance(sampling, bool) or not isinstance(sampling, int) or sampling < 1
    ):
        raise ValueError(f"sampling = {sampling!r}: must be 'vertices' or a number of samples >= 1")
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise ValueError(f"seed = {seed!r}: must be an integer")
    if not isinstance(minimal, bool):
        raise ValueError(f"minimal = {minimal!r}: must be True or False")
    ts = spec.sample_period_s if sample_period is None else sample_period
    ts = 0.0 if ts is None else real_number("sample_period", ts, lo=0.0, lo_open=True, unit="s")
    dims = _dims(box or {}, p0)
    delay_dim = next((d for d in dims if d.integer), None)
    if delay_dim is not None:
        if delay_samples is not None:
            raise ValueError(
                f"delay_samples = {delay_samples!r} and box['delay_samples']: give one of them"
            )
        lo, hi = delay_dim.values[0], delay_dim.values[-1]
        delays = (
            [int(v) for v in delay_dim.values]
            if delay_dim.explicit
            else list(range(int(lo), int(hi) + 1))
        )
    else:
        d0 = spec.delay_samples if delay_samples is None else delay_samples
        if isinstance(d0, bool) or not isinstance(d0, int | np.integer) or d0 < 0:
            raise ValueError(f"delay_samples = {d0!r}: must be a whole number of samples >= 0")
        delays = [int(d0)]
    if ts == 0.0 and any(delays):
        raise ValueError(
            f"delay_samples = {max(delays)}: a transport delay in samples needs a sampled design "
            "(sample_period, or a sampled controller such as 'pi-10ms')"
        )

    # the operating points: slip recipes (kind, gear, slope, speeds, pedal, throttle)
    recipes: list[tuple[float | None, dict[str, Any]]] = []
    if operating_points is not None:
        if trajectory is not None:
            raise ValueError("give operating_points or a trajectory, not both")
        for i, op in enumerate(operating_points):
            if not isinstance(op, OperatingPoint) or op.recipe is None or op.recipe[0] != "slip":
                raise ValueError(
                    f"operating_points[{i}] = {op!r}: must be a slip point made by "
                    "slip_operating_point (it is rebuilt for every parameter vertex)"
                )
            recipes.append((None, dict(op.recipe[1])))
    else:
        sc = load_scenario(scenario, params=p0)
        drive = sc.drivetrain(p0, kind=kind)
        # the parameter box varies the scenario's car (its overrides applied once, here)
        p0 = sc.params_for(p0)
        if trajectory is None:
            from drivetrain_ctrl.sim.run import run_scenario

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                trajectory = run_scenario(sc, drive, controller=spec)
        if isinstance(times, bool):
            raise ValueError(f"times = {times!r}: a number of instants or a list of times [s]")
        if isinstance(times, int | np.integer):
            if times < 1:
                raise ValueError(f"times = {times!r}: must be >= 1")
            start = 0.0 if sc.control_start is None else float(sc.control_start)
            inst = _slip_instants(trajectory, start, int(times))
        else:
            inst = [real_number(f"times[{i}]", t, unit="s") for i, t in enumerate(times)]
            if not inst:
                raise ValueError("times = []: needs at least one instant")
        driven = "omega_disc" if kind == "full" else "omega_primary"
        for t in inst:
            op = operating_point_from_result(trajectory, t, drivetrain=drive)
            if op.clutch_mode not in ("slip+", "slip-"):
                raise ValueError(
                    f"times: at t = {t:g} s the clutch is {op.clutch_mode!r}, not slipping; "
                    "pick instants of the slip phase"
                )
            recipes.append(
                (
                    t,
                    dict(
                        kind=kind,
                        gear=drive.gear,
                        slope=drive.slope,
                        omega_engine=op.state("omega_engine"),
                        omega_driven=op.state(driven),
                        x_c=op.input("pedal"),
                        throttle=op.input("throttle"),
                        brake=op.input("brake"),
                    ),
                )
            )
    pts = _box_points(dims, sampling, seed, include_nominal)
    cont_spec = dataclasses.replace(spec, sample_period_s=None, delay_samples=0)

    plants: list[Plant] = []
    info: list[dict[str, Any]] = []
    for k_op, (t_op, rec) in enumerate(recipes):
        rec = dict(rec)
        for label, vals in pts:
            param_vals = {k: v for k, v in vals.items() if k not in SPECIAL_KEYS}
            where = f"operating point {k_op}" + (f" (t = {t_op:g} s)" if t_op is not None else "")
            p = p0.replace(**param_vals) if param_vals else p0
            if "pedal_slope" in vals:
                p = _scaled_pedal_map(p, rec["x_c"], vals["pedal_slope"])
            drive = Drivetrain(p, kind=rec["kind"], gear=rec["gear"], slope=rec["slope"])
            op_kw = {k: v for k, v in rec.items() if k not in ("kind", "gear", "slope")}
            try:
                op = slip_operating_point(drive, **op_kw)
            except ValueError as exc:
                raise ValueError(f"{where}, {label}: {exc}") from None
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ctrl = cont_spec.build(p, reference=constant(rec["omega_engine"]))
            loop = clutch_loop(op, ctrl, mu_slope=vals.get("mu_slope"))
            P = loop.plant
            if minimal:
                P = control.minreal(P, verbose=False)
            if ts:
                P = control.sample_system(P, ts, method="zoh")
            base = ("t = " + f"{t_op:.3g} s" if t_op is not None else f"op {k_op}") + (
                f", {label}" if label else ""
            )
            vals_txt = ", ".join(f"{k} = {_fmt(v)}" for k, v in vals.items())
            for d in delays:
                name = base + (f" [{vals_txt}]" if vals_txt else "")
                if ts:
                    name += f", delay {d} sample{'s' if d != 1 else ''}"
                plants.append(Plant(P, delay=d * ts, name=name))
                info.append(
                    dict(
                        op=k_op,
                        t=t_op,
                        omega_engine=float(rec["omega_engine"]),
                        omega_driven=float(rec["omega_driven"]),
                        x_c=float(rec["x_c"]),
                        throttle=float(rec["throttle"]),
                        box=dict(vals),
                        vertex=label,
                        delay_samples=d,
                    )
                )
    if not plants:
        raise ValueError("no plants: give operating points or times")
    return ClutchPlantSet(tuple(plants), points=tuple(info), sample_period=float(ts))
