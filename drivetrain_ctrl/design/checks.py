"""The loop check every design tool reports with: one plant closed by one controller, checked on
a dense frequency grid with the exact delay, independently of how the controller was designed.

:func:`check_loop` (one plant) and :func:`check_plant_set` (every plant of a set) return
:class:`LoopCheck`: with ``L = C P`` in negative feedback, ``S = 1/(1 + L)``, ``T = L S``,

* ``ms``, ``mt``: peak ``|S|``, ``|T|`` on the grid and where [rad/s]; ``ks``: peak ``|C S|``;
* ``gain_margin_db``, ``phase_margin_deg``, ``crossover_rad_s`` (the gain crossover of the
  smallest phase margin): python-control ``stability_margins``, of the rational loop when the
  plant has no delay, else of the exact frequency response ``P(jw) exp(-jw delay) C(jw)`` (a ``FrequencyResponseData``, spline-interpolated) on
  the grid points with :data:`GM_FLOOR` ``<= |L| <=`` ``1/GM_FLOOR`` (at most
  :data:`MARGIN_POINTS` of them). A gain margin beyond ``+-20 log10(1/GM_FLOOR)`` dB (60 dB) is
  not reported; None, with the reason in ``reasons``, when there is no such crossover;
* ``disk_margin``: the symmetric (skew 0) disk margin ``alpha = 1/max|S - 1/2|``, and its gain
  and phase figures ``disk_margin_db``, ``disk_margin_deg`` (python-control's ``disk_margins``
  formulas, :func:`~drivetrain_ctrl.linear.margins.disk_figures`);
* ``stable``: from the closed-loop poles of the rational loop (a continuous delay by its Pade
  approximation of ``pade_order``, a discrete one ``z^-k``); None if that model cannot be formed
  (a discrete delay of a fraction of a sample), with the reason;
* ``active``: the design's binding bounds on this plant, ``(bound, frequency [rad/s], relative
  slack)``, when the design tool knows them (:func:`~drivetrain_ctrl.design.robust.robust_pi`).

The default grid is :func:`check_grid` around :func:`~drivetrain_ctrl.design.plants.frequency_grid`
of the plant(s) (4000 points). Units: frequencies [rad/s], ``ks`` in controller output per unit of
measured error.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import control
import numpy as np
from numpy.typing import NDArray

from ..core.serialize import json_ready
from ..linear.margins import disk_figures
from .plants import Plant, PlantSet, as_plant_set, frequency_grid

__all__ = [
    "LoopCheck",
    "check_loop",
    "check_plant_set",
    "check_grid",
    "worst_figures",
    "closed_loop_stable",
    "disk_figures",
    "GM_FLOOR",
    "MARGIN_POINTS",
]

F64 = NDArray[np.float64]

#: ``|L|`` range [GM_FLOOR, 1/GM_FLOOR] in which crossovers are searched (gain margins within 60 dB)
GM_FLOOR = 1e-3
#: at most this many grid points go into python-control's margin search of a loop with a delay
#: (its cost grows with the points; it interpolates between them)
MARGIN_POINTS = 300
#: points of the default check grid
CHECK_POINTS = 4000


@dataclass(frozen=True)
class LoopCheck:
    """One plant's loop with one controller, checked on a dense grid (module docstring).

    ``name`` of the plant; ``ms``, ``mt``: peak ``|S|``, ``|T|`` and where (``ms_frequency_rad_s``,
    ``mt_frequency_rad_s``) [rad/s]; ``ks``: peak ``|K S|`` [u/y]; ``gain_margin_db`` (None: no
    phase crossover), ``phase_margin_deg`` (None: no gain crossover), ``crossover_rad_s``;
    ``disk_margin`` (alpha, skew 0), ``disk_margin_db``, ``disk_margin_deg``; ``stable``
    (closed-loop poles; None if they cannot be formed); ``active``: the design's binding bounds
    on this plant, ``(bound, frequency [rad/s], relative slack)`` (empty: the plant does not
    limit, or the design does not say); ``reasons``: ``(figure, why)`` for a missing figure or
    how it was computed.
    """

    name: str
    ms: float
    ms_frequency_rad_s: float
    mt: float
    mt_frequency_rad_s: float
    ks: float
    gain_margin_db: float | None
    phase_margin_deg: float | None
    crossover_rad_s: float | None
    disk_margin: float
    disk_margin_db: float
    disk_margin_deg: float
    stable: bool | None
    active: tuple[tuple[str, float, float], ...] = ()
    reasons: tuple[tuple[str, str], ...] = ()

    @property
    def limiting(self) -> bool:
        """True if a bound of the design is active on this plant."""
        return bool(self.active)

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["active"] = [{"bound": b, "frequency_rad_s": w, "slack": s} for b, w, s in self.active]
        d["reasons"] = dict(self.reasons)
        return json_ready(d)


def check_grid(w: Any, dt: float = 0.0, n: int = CHECK_POINTS) -> F64:
    """A dense check grid around the frequencies ``w`` [rad/s] (e.g. a design grid): a decade
    beyond each side (up to the Nyquist frequency ``pi/dt`` for sampled plants), ``n``
    log-spaced points, ``w`` included."""
    w = np.asarray(w, dtype=float)
    lo = w[0] / 10.0
    hi = math.pi / dt if dt else w[-1] * 10.0
    return np.unique(np.concatenate([np.logspace(math.log10(lo), math.log10(hi), n), w]))


def _rational_loop(plant: Plant, C: Any, pade_order: int) -> tuple[Any, str]:
    """``C`` times the plant's rational model (:meth:`Plant.with_pade`), or None and why."""
    try:
        Pr = plant.with_pade(pade_order)
    except ValueError as exc:
        return None, str(exc)
    if isinstance(Pr, control.TransferFunction) and isinstance(C, control.TransferFunction):
        return C * Pr, ""
    return control.ss(C) * control.ss(Pr), ""


def closed_loop_stable(plant: Plant, C: Any, pade_order: int = 5) -> tuple[bool | None, str]:
    """Closed-loop stability of ``C`` on ``plant`` (negative feedback) from the poles of the
    rational loop (delay: Pade / ``z^-k``); None and the reason if that cannot be formed."""
    L, why = _rational_loop(plant, C, pade_order)
    return _stable_from(plant, L, why)


def _stable_from(plant: Plant, L: Any, why: str) -> tuple[bool | None, str]:
    if L is None:
        return None, why
    poles = np.asarray(control.feedback(L, 1).poles(), dtype=complex)
    if plant.is_discrete:
        return bool(np.all(np.abs(poles) < 1.0)), ""
    return bool(np.all(poles.real < 0.0)), ""


def _margins(L_w: Any, w: F64, L_rat: Any) -> tuple[float, float, float]:
    """``(gm, pm, wgc)`` by python-control: of the rational loop ``L_rat`` if given, else of the
    response ``L_w`` in the band GM_FLOOR <= |L| <= 1/GM_FLOOR (inf where none)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if L_rat is not None:
            gm, pm, _sm, _wpc, wgc, _wms = control.stability_margins(L_rat)
            return float(gm), float(pm), float(wgc)
        # with a delay there are thousands of phase crossovers at high frequency: only the band
        big = np.flatnonzero((np.abs(L_w) >= GM_FLOOR) & (np.abs(L_w) <= 1.0 / GM_FLOOR))
        if not big.size:
            return math.inf, math.inf, math.inf
        lo, hi = max(int(big[0]) - 1, 0), min(int(big[-1]) + 2, w.size)
        step = max(1, math.ceil((hi - lo) / MARGIN_POINTS))
        idx = np.unique(np.r_[np.arange(lo, hi, step), hi - 1])
        if idx.size < 2:
            return math.inf, math.inf, math.inf
        gm, pm, _sm, _wpc, wgc, _wms = control.stability_margins(control.frd(L_w[idx], w[idx]))
        return float(gm), float(pm), float(wgc)


def check_loop(
    plant: Any,
    controller: Any,
    *,
    grid: Any = None,
    pade_order: int = 5,
    active: Sequence[tuple[str, float, float]] = (),
) -> LoopCheck:
    """The check of ``controller`` on ``plant`` (module docstring).

    ``plant``: an LTI system or a :class:`~drivetrain_ctrl.design.plants.Plant` (exact input
    delay); ``controller``: a python-control LTI system of the plant's time base (``u = C e``,
    ``e = r - y``); ``grid``: the frequencies [rad/s] (default :func:`check_grid`);
    ``pade_order``: of a continuous delay in the rational loop; ``active``: the design's binding
    bounds on this plant, carried into the result."""
    if isinstance(plant, Plant):
        p = plant
    else:
        pset = as_plant_set(plant)
        if len(pset) != 1:
            raise ValueError(
                f"plant: check_loop takes one plant, got {len(pset)}; use check_plant_set"
            )
        p = pset[0]
    if grid is None:
        w = check_grid(frequency_grid(p), p.dt)
    else:
        w = np.unique(np.asarray(grid, dtype=float))
    Cw = Plant(controller).freqresp(w)
    L = p.freqresp(w) * Cw
    ok = np.isfinite(L)
    w, L, Cw = w[ok], L[ok], Cw[ok]
    S = 1.0 / (1.0 + L)
    T = L * S
    iS, iT = int(np.argmax(np.abs(S))), int(np.argmax(np.abs(T)))
    reasons: list[tuple[str, str]] = []
    L_rat, why = _rational_loop(p, controller, pade_order)
    gm, pm, wgc = _margins(L, w, L_rat if not p.delay else None)
    gm_db = pm_v = wgc_v = None
    if np.isfinite(gm) and GM_FLOOR <= gm <= 1.0 / GM_FLOOR:
        gm_db = 20 * math.log10(gm)
    else:
        reasons.append(
            (
                "gain_margin_db",
                f"no phase crossover with {GM_FLOOR:g} <= |L| <= {1 / GM_FLOOR:g}",
            )
        )
    if np.isfinite(pm) and np.isfinite(wgc) and wgc > 0:
        pm_v, wgc_v = pm, wgc
    else:
        reasons.append(("phase_margin_deg", "no gain crossover"))
    alpha = 1.0 / float(np.max(np.abs(S - 0.5)))
    dgm, dpm = disk_figures(alpha)
    stable, why = _stable_from(p, L_rat, why)
    if stable is None:
        reasons.append(("stable", why))
    elif p.delay and not p.is_discrete:
        reasons.append(("stable", f"poles with a Pade approximation of order {pade_order}"))
    return LoopCheck(
        name=p.name,
        ms=float(np.abs(S[iS])),
        ms_frequency_rad_s=float(w[iS]),
        mt=float(np.abs(T[iT])),
        mt_frequency_rad_s=float(w[iT]),
        ks=float(np.max(np.abs(Cw * S))),
        gain_margin_db=gm_db,
        phase_margin_deg=pm_v,
        crossover_rad_s=wgc_v,
        disk_margin=alpha,
        disk_margin_db=dgm,
        disk_margin_deg=dpm,
        stable=stable,
        active=tuple(active),
        reasons=tuple(reasons),
    )


def check_plant_set(
    plants: Any,
    controller: Any,
    *,
    grid: Any = None,
    pade_order: int = 5,
    active: Sequence[Sequence[tuple[str, float, float]]] | None = None,
) -> tuple[LoopCheck, ...]:
    """:func:`check_loop` of ``controller`` on every plant of ``plants`` (anything
    :func:`~drivetrain_ctrl.design.plants.as_plant_set` takes), on one grid (default
    :func:`check_grid` around the set's :func:`~drivetrain_ctrl.design.plants.frequency_grid`);
    ``active``: per plant, the design's binding bounds."""
    pset: PlantSet = as_plant_set(plants)
    w = check_grid(frequency_grid(pset), pset.dt) if grid is None else grid
    acts = [()] * len(pset) if active is None else list(active)
    if len(acts) != len(pset):
        raise ValueError(f"active: {len(acts)} entries for {len(pset)} plants")
    return tuple(
        check_loop(p, controller, grid=w, pade_order=pade_order, active=tuple(a))
        for p, a in zip(pset, acts, strict=True)
    )


def worst_figures(checks: Sequence[Any]) -> dict[str, Any]:
    """The worst figures over a set of loop checks (:class:`LoopCheck`, or rows with the same
    attributes): ``n_plants``; ``ms_max``, ``mt_max``, ``ks_max``; ``gain_margin_db_min``,
    ``phase_margin_deg_min`` (None: no plant has one), ``disk_margin_db_min``; the crossover
    range ``crossover_rad_s_min``, ``crossover_rad_s_max``; ``all_stable`` (False if a loop is
    unstable, None if one could not be checked)."""
    if not checks:
        raise ValueError("checks: empty; the worst figures need at least one loop")
    gms = [c.gain_margin_db for c in checks if c.gain_margin_db is not None]
    pms = [c.phase_margin_deg for c in checks if c.phase_margin_deg is not None]
    wcs = [c.crossover_rad_s for c in checks if c.crossover_rad_s is not None]
    flags = [c.stable for c in checks]
    stable = False if False in flags else (None if None in flags else True)
    return {
        "n_plants": len(checks),
        "ms_max": max(c.ms for c in checks),
        "mt_max": max(c.mt for c in checks),
        "ks_max": max(c.ks for c in checks),
        "gain_margin_db_min": min(gms) if gms else None,
        "phase_margin_deg_min": min(pms) if pms else None,
        "disk_margin_db_min": min(c.disk_margin_db for c in checks),
        "crossover_rad_s_min": min(wcs) if wcs else None,
        "crossover_rad_s_max": max(wcs) if wcs else None,
        "all_stable": stable,
    }
