"""Comparing controller variants side by side: the linear loop and the switching plant together.

:func:`compare` runs every controller on every scenario (in closed loop) as a
:class:`~drivetrain_ctrl.studies.case.Case` on Dask (the studies' machinery: a local cluster of
worker processes, or a given client; every worker loads the kernels once) and returns a
:class:`Comparison` whose ``data`` (a JSON-ready dict; the same input gives the same bytes: no
timestamps, no timings, floats rounded by :func:`~drivetrain_ctrl.core.serialize.json_ready`)
holds every number behind every figure of the report
(:mod:`drivetrain_ctrl.reporting.compare_report`, drawn by :meth:`Comparison.plot`).

Per controller and scenario (one worker task each):

* the engagement metrics (:data:`~drivetrain_ctrl.sim.metrics.METRICS`) and pass/fail against
  the stated criteria (:data:`CRITERIA`): lock-up within the scenario's horizon, no engine
  stall, peak jerk ``<=`` :data:`JERK_LIMIT_M_S3`, and on a grade roll-back ``<=``
  :data:`ROLLBACK_LIMIT_M`;
* the time responses on a common grid of :data:`N_SERIES` points over the scenario's horizon
  (the run re-sampled there by :meth:`SimulationResult.sample`): the engine-speed reference,
  engine and primary-shaft speed,
  pedal (actuator position x_c), clutch torque and vehicle acceleration;
* the linear figures of the clutch slip loop at the scenario's slip operating point
  (:func:`~drivetrain_ctrl.linear.operating_point.slip_point_after_start`: the run
  :data:`~drivetrain_ctrl.linear.operating_point.SLIP_DELAY_S` after the controller start),
  from one analysis: the loop (:func:`~drivetrain_ctrl.linear.clutch.clutch_loop`) and its
  :func:`~drivetrain_ctrl.linear.margins.loop_margins` on that function's automatic grid give
  the gain, phase, delay and disk margins, Ms, Mt, crossover, bandwidth, closed-loop poles and
  stability; the judder margin of the same loop as a study row finds it
  (:func:`~drivetrain_ctrl.studies.case.linear_figures_at`). A study row takes Ms and the disk
  margin on a coarser grid (:data:`~drivetrain_ctrl.studies.case.LINEAR_GRID_POINTS`
  frequencies), so they may differ from the comparison's in the last digits. In lock mode the clutch loop is open
  (x_c does not change the transmitted torque of a stuck clutch): no margins, said so; at the
  lock point (the run :data:`LOCK_DELAY_S` after lock-up) the locked driveline's shuffle modes
  and the clutch's torque margin to breakaway
  (:func:`~drivetrain_ctrl.linear.clutch.locked_analysis`).
* **linear against nonlinear**: the linear slip loop *predicts a good engagement* when its
  closed loop is stable at the slip point and at the later slip points where the slip speed has
  fallen to :data:`SLIP_FRACTIONS` of its value there (a falling mu(slip) acts at small slip:
  judder); the switching plant *engages well* when the run ends ``ok``, locks up
  within the horizon and the engine does not stall. The two **disagree** when these differ. The
  cause is named from what the run did after the slip point and the linear model cannot:
  *lock-up* (the clutch sticks: the slip loop ceases to exist), *sign switch* (the slip changes
  sign: law (6)'s sign block switches branch), *saturation* (the pedal reaches a stroke limit)
  and *operating-point drift* (the slip speed moves by more than :data:`DRIFT_THRESHOLD` of its
  value within :data:`DRIFT_WINDOW_S` after the slip point: the slip point is no equilibrium).

Per scenario, the **open-loop baseline** (``open_loop=True``, the default): the scenario run
without a controller, its pedal signal (``[inputs.pedal]``: the pedal a driver would give, each
built-in start has one) driving the clutch; the same metrics, criteria and time responses, shown
beside the controllers and never ranked: what a controller buys over a driver's pedal.

Per controller: the nominal linear figures are those on :data:`NOMINAL_SCENARIO` (run in
addition when it is not among the scenarios) with the Bode data of L and S on
:data:`BODE_GRID_RAD_S`, and the **certified sector** there
(:func:`~drivetrain_ctrl.design.certificates.clutch_sector_certificate`, ``certificate=True``):
the largest interval ``[mu'_cert, 0]`` of friction slopes (of mu/mu0, [s/rad]) for which the
slip loop is certified stable for *every* nonlinear, time-varying friction characteristic with
its slope in it (the sector ``[0, -k13 mu'_cert]`` [N m s/rad] of the friction feedback, by an
LMI), beside the linear limit (a constant slope) and the judder threshold. The **design plant
set** (``design_checks=True``): the controller is checked again here
(:func:`~drivetrain_ctrl.design.checks.check_plant_set`, worst case by
:func:`~drivetrain_ctrl.design.checks.worst_figures`) over the plant set rebuilt
(:func:`~drivetrain_ctrl.design.clutch.clutch_plant_set`) from the ``[design.spec.plants]`` table
of its controller file; a controller without a design spec is checked over
:data:`DEFAULT_PLANT_SET`'s built-in design spec plants (sampled at the controller's period with
its delay when it is sampled), and the report says which. The nominal figures there are the
worst over the set's nominal-parameter plants (one per instant). What the file records
(``[design.achieved]``) is kept beside them, for comparison. Each distinct plant set is built
once, in a worker task that runs in parallel with the runs.

Bad input never stops the others: an unknown controller or scenario, a controller file that
does not load, an open-loop scenario, or a controller whose nominal slip loop is unstable is
listed in ``data["invalid"]`` (with the reason) and left out of the ranking; only a comparison
with no valid controller (or no valid scenario) raises :class:`CompareError`.

The verdict ranks the valid controllers by the number of criteria passed (more first), then by
the weighted score (lower first): for each score key of :data:`WEIGHTS` and each scenario, the
controller's value divided by the best (smallest) value of the valid controllers there, capped
at :data:`RATIO_CAP` (an undefined value counts as the cap); the score is the weighted mean
over keys of the mean over scenarios (1.0: best everywhere).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import control
import numpy as np

from ..control.laws import ControllerError, ControllerSpec, load_controller
from ..core.serialize import json_ready
from ..core.units import RAD_S_TO_RPM
from ..linear.clutch import clutch_loop, locked_analysis
from ..linear.margins import db_phase, loop_margins
from ..linear.operating_point import (
    SLIP_DELAY_S,
    operating_point_from_result,
    slip_point_after_start,
)
from ..plant.params import DEFAULT_SET, DrivetrainParams, load_params
from ..scenarios.scenario import Scenario, builtin_scenarios, load_scenario
from ..sim.metrics import state_accelerations
from ..sim.simulator import ZenoError
from .case import MODELS, NO_LINEAR_FIGURES, Case, CaseError, linear_figures_at, simulate_case

__all__ = [
    "BODE_GRID_RAD_S",
    "CRITERIA",
    "CompareError",
    "Comparison",
    "DEFAULT_CONTROLLERS",
    "DEFAULT_PLANT_SET",
    "DRIFT_THRESHOLD",
    "DRIFT_WINDOW_S",
    "JERK_LIMIT_M_S3",
    "LOCK_DELAY_S",
    "NOMINAL_SCENARIO",
    "N_SERIES",
    "RATIO_CAP",
    "ROLLBACK_LIMIT_M",
    "SERIES",
    "SLIP_FRACTIONS",
    "WEIGHTS",
    "compare",
    "compare_case",
    "design_check",
    "closed_loop_scenarios",
]

#: the built-in design spec whose plant set checks a controller that has no design spec of its own
DEFAULT_PLANT_SET: str = "robust-pi"
#: the controllers compared by default
DEFAULT_CONTROLLERS: tuple[str, ...] = ("paper", "pi", "robust-pi", "hinf")
#: the scenario whose slip point gives each controller's nominal linear figures
NOMINAL_SCENARIO: str = "paper-start"
#: the jerk criterion [m/s^3] (the project's: the shipped studies use the same bound)
JERK_LIMIT_M_S3: float = 25.0
#: the roll-back criterion [m] on a grade (the hill-start's stated limit)
ROLLBACK_LIMIT_M: float = 0.05
#: the criteria, by key: (metric, text)
CRITERIA: dict[str, str] = {
    "lockup": "locks up within the scenario's horizon (lockup_time_s defined)",
    "no_stall": "the engine does not stall (engine_stalled false)",
    "jerk": f"jerk_max_m_s3 <= {JERK_LIMIT_M_S3:g}",
    "rollback": f"rollback_m <= {ROLLBACK_LIMIT_M:g} (on a grade only)",
}
#: points of the common time grid of the time responses
N_SERIES: int = 300
#: the time responses kept per run (name -> unit)
SERIES: dict[str, str] = {
    "omega_ref_rpm": "rpm",
    "omega_engine_rpm": "rpm",
    "omega_primary_rpm": "rpm",
    "pedal_mm": "mm",
    "clutch_torque_Nm": "N m",
    "vehicle_accel_m_s2": "m/s^2",
}
#: the frequency grid [rad/s] of the Bode data (below the Nyquist frequency of a 10-ms controller)
BODE_GRID_RAD_S: tuple[float, ...] = tuple(float(w) for w in np.logspace(-1.0, 2.4, 200))
#: the later slip points: where the slip speed has fallen to these fractions of its value at the
#: slip point (a falling mu(slip) acts at small slip: the judder threshold)
SLIP_FRACTIONS: tuple[float, ...] = (0.5, 0.2, 0.05)
#: the lock operating point: the run this long after lock-up [s] (or its end)
LOCK_DELAY_S: float = 0.5
#: operating-point drift: relative change of the slip speed ...
DRIFT_THRESHOLD: float = 0.25
#: ... within this long after the slip point [s]
DRIFT_WINDOW_S: float = 0.3
#: the default weights of the score keys (each: a metric, or ``ms`` the nominal slip loop's Ms)
WEIGHTS: dict[str, float] = {
    "engagement_time_s": 1.0,
    "clutch_energy_J": 1.0,
    "jerk_max_m_s3": 1.0,
    "tracking_rms_rpm": 1.0,
    "ms": 1.0,
}
#: the largest ratio to the best controller a score key counts with (also for an undefined value)
RATIO_CAP: float = 3.0
#: the linear figures kept per loop (from LoopMargins)
_MARGIN_KEYS = (
    "gain_margin_db",
    "phase_margin_deg",
    "delay_margin_s",
    "disk_margin",
    "disk_margin_db",
    "disk_margin_deg",
    "ms",
    "mt",
    "crossover_rad_s",
    "bandwidth_rad_s",
    "stable",
)
#: the worst-case figures over a plant set (recomputed; and as recorded in [design.achieved])
_DESIGN_KEYS = (
    "n_plants",
    "ms_max",
    "mt_max",
    "gain_margin_db_min",
    "phase_margin_deg_min",
    "disk_margin_db_min",
    "crossover_rad_s_min",
    "crossover_rad_s_max",
    "all_stable",
    "plant_set",
)
_LOCK_REASON = (
    "clutch locked: x_c does not change the transmitted torque of a stuck clutch, so the clutch "
    "loop is open (no margins)"
)


class CompareError(ValueError):
    """A comparison that cannot run: invalid options, or no valid controller or scenario."""


# -- one case, on a worker ------------------------------------------------------------------------
def _series(run: Any, t_end: float, n: int) -> dict[str, Any]:
    """The time responses of :data:`SERIES` on ``n`` points over [0, t_end] (within the run)."""
    res = run.result
    t_last = float(res.t_last)
    grid = np.linspace(float(res.t0), t_end, n)
    grid = grid[grid <= t_last]
    s = res.sample(grid)
    model = s.model
    names = model.state_names
    iv = names.index("v_vehicle")
    right, _ = state_accelerations(s)
    ic = [c.name for c in model.chain.couplings].index("clutch")
    ip = model.input_names.index("pedal")
    ref = run.scenario.reference  # the closed loop has one (Scenario checks it); open: None
    cols = {
        "t_s": s.t,
        **(
            {"omega_ref_rpm": np.asarray(ref(s.t), dtype=float) * RAD_S_TO_RPM}
            if ref is not None
            else {}
        ),
        "omega_engine_rpm": s.state("omega_engine") * RAD_S_TO_RPM,
        "omega_primary_rpm": s.state("omega_primary") * RAD_S_TO_RPM,
        "pedal_mm": np.asarray(s.u)[:, ip] * 1e3,
        "clutch_torque_Nm": s.coupling_torques()[:, ic],
        "vehicle_accel_m_s2": right[:, iv],
    }
    return {k: np.asarray(v, dtype=float).tolist() for k, v in cols.items()}


def _lock(run: Any) -> tuple[dict[str, Any] | None, str]:
    """Lock mode at the run's lock point (:data:`LOCK_DELAY_S` after lock-up): the driveline's
    shuffle modes and the clutch's torque margin to breakaway (the loop itself is open)."""
    lock_t = run.metrics.get("lockup_time_s")
    if lock_t is None:
        return None, f"{_LOCK_REASON}; no lock-up in the run: no lock point"
    t = min(float(lock_t) + LOCK_DELAY_S, float(run.result.t_last))
    try:
        op = operating_point_from_result(run.result, t, drivetrain=run.drivetrain)
        if op.clutch_mode != "stuck":
            return None, f"{_LOCK_REASON}; the clutch slips again at t = {t:.4g} s: no lock point"
        la = locked_analysis(op)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return None, f"{_LOCK_REASON}; no lock analysis: {exc}"
    sm = {m.element: m for m in la.breakaway_margins}
    clutch = sm.get("clutch")
    return {
        "t_s": t,
        "shuffle_modes": [
            {"natural_frequency_hz": m.natural_frequency_hz, "damping": m.damping}
            for m in la.shuffle_modes
        ],
        "clutch_breakaway_margin_Nm": clutch.margin if clutch is not None else None,
        "clutch_capacity_Nm": clutch.capacity if clutch is not None else None,
    }, _LOCK_REASON


def _certificate(op: Any, controller: Any) -> tuple[dict[str, Any], float]:
    """The certified friction-slope sector of the slip loop at ``op``
    (:func:`~drivetrain_ctrl.design.certificates.clutch_sector_certificate`; module docstring),
    or the reason there is none; and its cost [s] (not part of ``data``)."""
    from ..design.certificates import clutch_sector_certificate

    tic = time.perf_counter()
    try:
        cert = clutch_sector_certificate(op, controller)
    except Exception as exc:  # noqa: BLE001 - the reason is reported; the comparison goes on
        out: dict[str, Any] = {
            "mu_slope_certified": None,
            "reason": f"no certificate: {type(exc).__name__}: {exc}",
        }
        return out, time.perf_counter() - tic
    mu = cert.mu_slope_certified
    out = {
        "mu_slope_certified": mu,
        "sector_N_m_s_rad": None if mu is None else [0.0, -cert.k13 * mu],
        "mu_slope_linear": cert.mu_slope_linear,
        "judder_closed_form": cert.judder_closed_form,
        "judder_numeric": cert.judder_numeric,
        "ratio": cert.ratio,
        "k13": cert.k13,
        "dt": cert.dt,
        "message": cert.message,
        "reason": None if mu is not None else cert.message,
    }
    return out, time.perf_counter() - tic


def _linear(run: Any, bode: bool, certificate: bool = False) -> dict[str, Any]:
    """The slip loop at the run's slip point: margins (and the Bode data of L and S, and with
    ``certificate`` the certified sector, :func:`_certificate`); lock mode at the lock point
    (:func:`_lock`).

    One analysis of the slip loop: the slip point
    (:func:`~drivetrain_ctrl.linear.operating_point.slip_point_after_start`), the loop
    (:func:`~drivetrain_ctrl.linear.clutch.clutch_loop`) and its margins
    (:func:`~drivetrain_ctrl.linear.margins.loop_margins`, on its automatic grid: every
    frequency-domain figure, Ms, Mt, the disk margin and the bandwidth, on that one grid), once
    each; the judder figures from the same loop (:func:`~drivetrain_ctrl.studies.case.linear_figures_at`,
    the function a study row's figures come from)."""
    lock, lock_reason = _lock(run)
    out: dict[str, Any] = {
        "slip": None,
        "slip_reason": None,
        "lock": lock,
        "lock_reason": lock_reason,
    }
    if run.controller is None:
        out["slip_reason"] = "open loop: no clutch loop"
        return out
    try:
        op = slip_point_after_start(run.result, run.drivetrain, run.scenario.start_time)
        cl = clutch_loop(op, run.controller)
        m = loop_margins(cl.L)
    except Exception as exc:  # noqa: BLE001 - the run's own figures stand; the reason is kept
        out["slip_reason"] = f"{NO_LINEAR_FIGURES}: {type(exc).__name__}: {exc}"
        return out
    fig = linear_figures_at(op, run.controller, cl.engine, cl.L, m)
    lm = m.to_dict()
    slip = {k: lm.get(k) for k in _MARGIN_KEYS}
    slip["judder"] = {
        k.removeprefix("lin:"): fig.get(k)
        for k in ("lin:mu_slope", "lin:mu_slope_crit", "lin:judder_margin")
    }
    slip["linear_note"] = fig.get("linear_note")
    slip["reasons"] = lm.get("reasons") or {}
    slip["operating_point"] = {
        "t_s": float(op.t or 0.0),
        "clutch_mode": op.clutch_mode,
        "slip_speed_rad_s": op.state("omega_engine") - op.state(_driven(run)),
        "omega_engine_rpm": op.state("omega_engine") * RAD_S_TO_RPM,
        "pedal_m": op.input("pedal"),
    }
    poles = [complex(p["real"], p["imag"]) for p in lm.get("closed_loop_poles", [])]
    slip["closed_loop_poles"] = [[p.real, p.imag] for p in poles]
    slip0 = op.state("omega_engine") - op.state(_driven(run))
    slip["later_points"] = _later_points(run, op, slip0)
    if bode:
        w = np.asarray(BODE_GRID_RAD_S)
        hL = control.frequency_response(cl.L, w).complex
        hS = control.frequency_response(cl.S, w).complex
        dbL, phL = db_phase(hL)
        dbS, phS = db_phase(hS)
        bd = {"omega_rad_s": w, "L_db": dbL, "L_deg": phL, "S_db": dbS, "S_deg": phS}
        slip["bode"] = {k: np.asarray(v, dtype=float).tolist() for k, v in bd.items()}
    if certificate:
        slip["certificate"], out["certificate_s"] = _certificate(op, run.controller)
    out["slip"] = slip
    return out


def _later_points(run: Any, op: Any, slip0: float) -> list[dict[str, Any]]:
    """The slip loop where the slip speed has fallen to :data:`SLIP_FRACTIONS` of ``slip0``
    (the first sample after the slip point at which the clutch still slips); stability, Ms and
    the rightmost closed-loop pole at each."""
    res = run.result
    t = np.asarray(res.t)
    slip = np.abs(res.state("omega_engine") - res.state(_driven(run)))
    modes = np.asarray(res.mode_series("clutch"))
    slipping = (modes == "slip+") | (modes == "slip-")
    t_op = float(op.t or 0.0)
    out: list[dict[str, Any]] = []
    for f in SLIP_FRACTIONS:
        idx = np.flatnonzero((t > t_op) & slipping & (slip <= f * abs(slip0)))
        point: dict[str, Any] = {"fraction": f, "t_s": None}
        if idx.size:
            tk = float(t[idx[0]])
            try:
                opk = operating_point_from_result(res, tk, drivetrain=run.drivetrain)
                lm = loop_margins(clutch_loop(opk, run.controller).L)
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
                point.update(t_s=tk, reason=f"no slip loop: {exc}")
            else:
                point.update(
                    t_s=tk,
                    slip_speed_rad_s=opk.state("omega_engine") - opk.state(_driven(run)),
                    stable=lm.stable,
                    ms=lm.ms,
                    max_real_pole=max((p.real for p in lm.closed_loop_poles), default=None),
                )
        else:
            point["reason"] = "the slip speed does not fall that far while the clutch slips"
        out.append(point)
    return out


def _driven(run: Any) -> str:
    names = run.result.model.state_names
    return "omega_disc" if "omega_disc" in names else "omega_primary"


def _observed(run: Any, t_op: float | None) -> dict[str, Any]:
    """What the run did after the slip point that the linear slip loop cannot describe."""
    res = run.result
    t = np.asarray(res.t)
    after = t >= (t_op if t_op is not None else run.scenario.start_time)
    modes = np.asarray(res.mode_series("clutch"))
    m_after = modes[after]
    first = str(m_after[0]) if m_after.size else ""
    other = {"slip+": "slip-", "slip-": "slip+"}.get(first)
    lock_t = run.metrics.get("lockup_time_s")
    act = run.drivetrain.params.actuator
    ip = res.model.input_names.index("pedal")
    pedal = np.asarray(res.u)[after, ip]
    tol = 1e-9
    sat = bool(pedal.size) and bool(
        np.any(pedal <= act.x_min + tol) or np.any(pedal >= act.x_max - tol)
    )
    drift: float | None = None
    if t_op is not None:
        slip = res.state("omega_engine") - res.state(_driven(run))
        t1 = min(t_op + DRIFT_WINDOW_S, float(t[-1]))
        s0, s1 = np.interp([t_op, t1], t, slip)
        drift = abs(float(s1) - float(s0)) / max(abs(float(s0)), 1e-9)
    return {
        "lock_up_s": lock_t,
        "sign_switch": bool(other is not None and other in set(m_after.tolist())),
        "saturation": sat,
        "drift_rel": drift,
        "drift": bool(drift is not None and drift > DRIFT_THRESHOLD),
    }


def compare_case(
    controller: ControllerSpec | None,
    scenario: Scenario,
    params: DrivetrainParams,
    model: str,
    *,
    t_end: float | None = None,
    n_series: int = N_SERIES,
    bode: bool = False,
    certificate: bool = False,
) -> dict[str, Any]:
    """One controller on one scenario (runs on a worker; picklable arguments): the case's
    metrics, time responses, slip-loop figures (with ``bode`` its Bode data, with
    ``certificate`` its certified sector) and what the run did after the slip point; ``status``
    ``failed`` with ``error`` when the case cannot run (nothing raised). ``controller`` None:
    the scenario's open loop (its pedal signal, the baseline): metrics and time responses only
    (there is no clutch loop)."""
    loop = "closed" if controller is not None else "open"
    out: dict[str, Any] = {
        "controller": controller.name if controller is not None else None,
        "scenario": scenario.name,
        "loop": loop,
    }
    case = Case(
        scenario=scenario,
        params=params,
        model=model,
        loop=loop,
        controller=controller,
        t_end=t_end,
    )
    try:
        run = simulate_case(case)
    except (CaseError, ZenoError, RuntimeError) as exc:
        out.update(status="failed", error=f"{type(exc).__name__}: {exc}")
        return out
    horizon = float(t_end if t_end is not None else scenario.t_end)
    out.update(
        status=str(run.metrics.get("status")),
        error=None,
        horizon_s=horizon,
        metrics=run.metrics,
        series=_series(run, horizon, n_series),
    )
    if controller is None:  # the open loop has no clutch loop to analyse
        return out
    lin = _linear(run, bode, certificate)
    t_op = lin["slip"]["operating_point"]["t_s"] if lin["slip"] is not None else None
    out.update(linear=lin, observed=_observed(run, t_op))
    return out


def _plants_of(spec: ControllerSpec) -> tuple[dict[str, Any], str]:
    """The plant-set keywords a controller is checked over (module docstring) and where they
    come from: its file's ``[design.spec.plants]``, else :data:`DEFAULT_PLANT_SET`'s."""
    from ..design.from_spec import load_design_spec

    own = ((spec.to_dict().get("design") or {}).get("spec") or {}).get("plants")
    if own:
        return dict(own), "the controller file's design spec ([design.spec.plants])"
    kw = dict(load_design_spec(DEFAULT_PLANT_SET).plants)
    where = (
        "no design spec in the controller file: the default plant set (the plants of the "
        f"built-in design spec {DEFAULT_PLANT_SET!r})"
    )
    if spec.sample_period_s is not None:
        kw.update(sample_period=spec.sample_period_s, delay_samples=spec.delay_samples)
        where += (
            f", sampled every {spec.sample_period_s:g} s with {spec.delay_samples} sample(s) "
            "of delay as the controller"
        )
    return kw, where


def design_check(
    controllers: Sequence[ControllerSpec], plants: Mapping[str, Any]
) -> dict[str, dict[str, Any]]:
    """Every controller of ``controllers`` checked over the plant set ``plants`` (keywords of
    :func:`~drivetrain_ctrl.design.clutch.clutch_plant_set`; built once; runs on a worker):
    per controller name ``plant_set`` (its summary), ``worst`` (over every plant) and
    ``nominal`` (over the nominal-parameter plants) by
    :func:`~drivetrain_ctrl.design.checks.worst_figures`, the ``limiting`` plant (largest Ms),
    ``reason`` (None, or why there are no figures) and ``seconds`` (the cost: not for ``data``).
    """
    import warnings

    from ..control.laws import UnstableLoopWarning
    from ..design.checks import check_plant_set, worst_figures
    from ..design.clutch import clutch_plant_set

    tic = time.perf_counter()
    kw = dict(plants)
    box = kw.pop("box", None)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnstableLoopWarning)
            pset = clutch_plant_set(**kw, box=box)
    except Exception as exc:  # noqa: BLE001 - the reason is reported; the comparison goes on
        why = f"plant set not built: {type(exc).__name__}: {exc}"
        share = (time.perf_counter() - tic) / max(1, len(controllers))
        return {c.name: {"reason": why, "seconds": share} for c in controllers}
    build_s = (time.perf_counter() - tic) / max(1, len(controllers))
    nominal = [i for i, pt in enumerate(pset.points) if pt.get("vertex") == "nominal"]
    keys = [k for k in _DESIGN_KEYS if k != "plant_set"]
    out: dict[str, dict[str, Any]] = {}
    for spec in controllers:
        t0 = time.perf_counter()
        rec: dict[str, Any] = {"plant_set": pset.summary(), "reason": None}
        try:
            checks = check_plant_set(pset, spec.lti())
        except Exception as exc:  # noqa: BLE001 - as above
            rec["reason"] = f"check failed: {type(exc).__name__}: {exc}"
        else:
            worst = worst_figures(checks)
            rec["worst"] = {k: worst[k] for k in keys}
            rec["nominal"] = (
                {k: v for k, v in worst_figures([checks[i] for i in nominal]).items() if k in keys}
                if nominal
                else None
            )
            rec["limiting"] = max(checks, key=lambda c: c.ms).name
        rec["seconds"] = build_s + time.perf_counter() - t0
        out[spec.name] = rec
    return out


# -- judging ---------------------------------------------------------------------------------------
def _criteria(rec: Mapping[str, Any], scenario: Scenario) -> dict[str, bool | None]:
    """Pass/fail of :data:`CRITERIA` for one run (None: the criterion does not apply)."""
    m = rec.get("metrics") or {}
    ok = rec.get("status") == "ok"
    lock = m.get("lockup_time_s")
    jerk = m.get("jerk_max_m_s3")
    out: dict[str, bool | None] = {
        "lockup": ok and lock is not None and lock <= rec.get("horizon_s", math.inf),
        "no_stall": ok and m.get("engine_stalled") is False,
        "jerk": ok and jerk is not None and jerk <= JERK_LIMIT_M_S3,
        "rollback": None,
    }
    if scenario.slope != 0.0:
        rb = m.get("rollback_m")
        out["rollback"] = ok and rb is not None and rb <= ROLLBACK_LIMIT_M
    return out


def _agreement(rec: Mapping[str, Any], crit: Mapping[str, bool | None]) -> dict[str, Any]:
    """Linear prediction against the switching plant (module docstring)."""
    lin = (rec.get("linear") or {}).get("slip")
    if lin is None or lin.get("stable") is None:
        why = (rec.get("linear") or {}).get("slip_reason") or "no stability verdict"
        return {"disagree": None, "causes": [], "statement": f"no linear prediction: {why}."}
    later = [p for p in lin.get("later_points", []) if p.get("stable") is not None]
    unstable_at = [p for p in later if p["stable"] is False]
    predicts = bool(lin["stable"]) and not unstable_at
    engages = bool(crit["lockup"]) and bool(crit["no_stall"])
    obs = rec.get("observed") or {}
    causes = []
    if obs.get("lock_up_s") is not None:
        causes.append(f"lock-up at {obs['lock_up_s']:.4g} s")
    if obs.get("sign_switch"):
        causes.append("sign switch of the slip")
    if obs.get("saturation"):
        causes.append("saturation at a stroke limit")
    if obs.get("drift"):
        causes.append(
            f"operating-point drift ({100 * obs['drift_rel']:.0f} % of the slip speed in "
            f"{DRIFT_WINDOW_S:g} s)"
        )
    if predicts:
        pred = f"stable at the slip point and at {len(later)} later one(s) (a good engagement)"
    elif not lin["stable"]:
        pred = "unstable at the slip point"
    else:
        where = ", ".join(
            f"t = {p['t_s']:.3g} s (slip {p['slip_speed_rad_s']:.3g} rad/s)" for p in unstable_at
        )
        pred = f"unstable later in the slip phase, at {where}"
    did = "engages (locks up, no stall)" if engages else "does not engage well"
    disagree = predicts != engages
    stmt = f"linear slip loop {pred}; the switching plant {did}"
    if disagree:
        stmt += ": they disagree; seen in the run: " + ("; ".join(causes) or "no mode change")
    else:
        stmt += ": they agree"
    return {
        "disagree": disagree,
        "linear_stable": predicts,
        "nonlinear_engages": engages,
        "causes": causes if disagree else [],
        "statement": stmt + ".",
    }


def _score(
    valid: Sequence[str],
    scenarios: Sequence[str],
    runs: Mapping[tuple[str, str], Mapping[str, Any]],
    nominal: Mapping[str, Any],
    weights: Mapping[str, float],
) -> dict[str, dict[str, Any]]:
    """Per controller: the mean capped ratio to the best of each score key, and the score.

    The best is the smallest positive value: a value of 0 counts as the best (ratio 1) instead
    of making every positive value's ratio infinite."""

    def value(c: str, s: str | None, key: str) -> float | None:
        if key == "ms":
            slip = (nominal.get(c) or {}).get("slip") or {}
            v = slip.get("ms")
        else:
            v = ((runs.get((c, s or "")) or {}).get("metrics") or {}).get(key)
        return float(v) if v is not None and math.isfinite(float(v)) else None

    out: dict[str, dict[str, Any]] = {c: {"ratios": {}} for c in valid}
    for key in weights:
        places: Sequence[str | None] = [None] if key == "ms" else list(scenarios)
        for c in valid:
            out[c]["ratios"][key] = []
        for s in places:
            vals = {c: value(c, s, key) for c in valid}
            best = min((v for v in vals.values() if v is not None and v > 0), default=None)
            for c in valid:
                v = vals[c]
                if v is None or best is None:
                    r = RATIO_CAP if v is None else 1.0
                else:
                    r = min(RATIO_CAP, max(v, best) / best)
                out[c]["ratios"][key].append(r)
    total = sum(weights.values())
    for c in valid:
        means = {k: float(np.mean(v)) for k, v in out[c]["ratios"].items()}
        out[c]["mean_ratio"] = means
        out[c]["score"] = sum(weights[k] * means[k] for k in weights) / total
        del out[c]["ratios"]
    return out


def _verdict(
    valid: Sequence[str],
    scenarios: Sequence[str],
    runs: Mapping[tuple[str, str], Mapping[str, Any]],
    nominal: Mapping[str, Any],
    weights: Mapping[str, float],
) -> dict[str, Any]:
    scores = _score(valid, scenarios, runs, nominal, weights)
    rows = []
    for c in valid:
        passed = applicable = 0
        failed: list[str] = []
        for s in scenarios:
            for k, v in (runs[(c, s)].get("criteria") or {}).items():
                if v is None:
                    continue
                applicable += 1
                passed += bool(v)
                if not v:
                    failed.append(f"{k} on {s}")
        rows.append(
            {
                "controller": c,
                "criteria_passed": passed,
                "criteria_applicable": applicable,
                "failed": failed,
                "score": scores[c]["score"],
                "mean_ratio": scores[c]["mean_ratio"],
            }
        )
    rows.sort(key=lambda r: (-r["criteria_passed"], r["score"], r["controller"]))
    reasoning = []
    for i, r in enumerate(rows):
        r["rank"] = i + 1
        terms = " + ".join(f"{weights[k]:g} x {r['mean_ratio'][k]:.3f} ({k})" for k in weights)
        line = (
            f"#{i + 1} {r['controller']}: {r['criteria_passed']}/{r['criteria_applicable']} "
            f"criteria passed"
            + (f" (failed: {', '.join(r['failed'])})" if r["failed"] else "")
            + f"; score {r['score']:.3f} = ({terms}) / {sum(weights.values()):g}"
        )
        if i > 0:
            p = rows[i - 1]
            if p["criteria_passed"] > r["criteria_passed"]:
                line += f"; below {p['controller']}: fewer criteria passed"
            elif p["score"] < r["score"]:
                line += f"; below {p['controller']}: same criteria passed, higher score"
            else:
                line += f"; below {p['controller']}: tie, by name"
        reasoning.append(line)
    return {"ranking": rows, "reasoning": reasoning}


# -- the comparison --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Comparison:
    """What :func:`compare` found: ``data`` (JSON-ready, deterministic; module docstring),
    ``wall_s`` [s], ``workers`` and ``timing`` (``startup_s``: kernels, cluster and its warm-up;
    ``runs_s``; ``shutdown_s``; how it ran: not part of ``data``)."""

    data: dict[str, Any]
    wall_s: float
    workers: int
    timing: dict[str, float]

    @property
    def ranking(self) -> list[str]:
        """The valid controllers, best first."""
        return [r["controller"] for r in self.data["verdict"]["ranking"]]

    @property
    def problems(self) -> list[str]:
        """One line per controller or scenario left out, with the reason."""
        return [f"{p['kind']} {p['name']!r}: {p['reason']}" for p in self.data["invalid"]]

    def plot(self, out: str | Path | None = None, *, pdf: bool = True) -> Any:
        """The figures (:func:`~drivetrain_ctrl.reporting.compare_report.compare_figures`), or,
        with ``out``, the report written there (compare.html, compare.pdf unless ``pdf`` is
        False, data.json)."""
        from ..reporting.compare_report import compare_figures, write_compare_report

        if out is None:
            return compare_figures(self.data)
        return write_compare_report(self.data, out, pdf=pdf)


def closed_loop_scenarios(params: DrivetrainParams | None = None) -> list[str]:
    """The built-in scenarios that need a controller (``--scenarios all``), in their order."""
    return [n for n, s in builtin_scenarios(params).items() if s.needs_controller]


def _split(v: str | Sequence[str | Path] | None, what: str) -> list[str | Path]:
    if v is None:
        return []
    if isinstance(v, str):
        items: list[str | Path] = [x.strip() for x in v.split(",") if x.strip()]
    elif isinstance(v, Sequence) and all(isinstance(x, str | Path) for x in v):
        items = list(v)
    else:
        raise CompareError(f"{what} = {v!r}: give names or files, a list or comma-separated")
    if not items:
        raise CompareError(f"{what} = {v!r}: empty")
    return items


def _check_weights(weights: Mapping[str, float] | None) -> dict[str, float]:
    w = dict(WEIGHTS)
    if weights is None:
        return w
    if not isinstance(weights, Mapping):
        raise CompareError(f"weights = {weights!r}: must map score keys to numbers")
    for k, v in weights.items():
        if k not in WEIGHTS:
            raise CompareError(f"weights: unknown key {k!r}; known: {', '.join(WEIGHTS)}")
        if isinstance(v, bool) or not isinstance(v, int | float) or not (v >= 0 and v < math.inf):
            raise CompareError(f"weights[{k!r}] = {v!r}: must be a finite number >= 0")
        w[k] = float(v)
    if not sum(w.values()) > 0:
        raise CompareError(f"weights = {w!r}: at least one must be > 0")
    return w


def _run_all(
    tasks: Sequence[tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]],
    *,
    client: Any,
    workers: int | None,
    progress: bool,
) -> tuple[list[Any], int, dict[str, float]]:
    """Every task ``(function, args, kwargs)`` on Dask
    (:func:`~drivetrain_ctrl.studies.runner.dask_client`: a local cluster of single-threaded
    worker processes with the kernel warm-up plugin, or ``client``), with a progress bar;
    results in task order, the number of workers and the time [s] of the set-up (kernels,
    cluster, warm-up), the runs and the cluster's shut-down."""
    from dask.distributed import as_completed
    from tqdm import tqdm

    from .runner import dask_client

    tic = time.perf_counter()
    timing: dict[str, float] = {}
    with dask_client(client, workers=workers, timing=timing) as client:
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        futures = [
            client.submit(fn, *args, **kw, pure=False, key=f"compare-{i}-{fn.__name__}")
            for i, (fn, args, kw) in enumerate(tasks)
        ]
        index = {f.key: i for i, f in enumerate(futures)}
        out: list[Any] = [{} for _ in futures]
        with tqdm(total=len(futures), unit="task", disable=not progress, dynamic_ncols=True) as bar:
            for fut in as_completed(futures):
                out[index[fut.key]] = fut.result()
                bar.update(1)
                fut.release()
        timing["runs_s"] = time.perf_counter() - tic - timing["startup_s"]
    return out, n_workers, timing


def compare(
    *,
    controllers: str | Sequence[str | Path] = DEFAULT_CONTROLLERS,
    scenarios: str | Sequence[str | Path] = "all",
    model: str = "full",
    params: str | Path | DrivetrainParams = DEFAULT_SET,
    weights: Mapping[str, float] | None = None,
    t_end: float | None = None,
    n_series: int = N_SERIES,
    workers: int | None = None,
    client: Any = None,
    progress: bool = True,
    warn: Callable[[str], None] | None = None,
    design_checks: bool = True,
    certificate: bool = True,
    open_loop: bool = True,
) -> Comparison:
    """Compare ``controllers`` (built-in names or controller TOML files; a list or
    comma-separated) on ``scenarios`` (``"all"``: every built-in closed-loop scenario; or names /
    scenario files) on ``model`` (``full`` / ``reduced``) with parameter set ``params`` (name,
    TOML file or set; each scenario's own overrides applied). ``weights``: score key -> weight
    (:data:`WEIGHTS`; missing keys keep their default). ``t_end`` [s]: a shorter horizon for every
    scenario (None: each scenario's own). ``n_series``: points of the time responses.
    ``workers``: local worker processes (default: the cores), or ``client``: a
    ``dask.distributed.Client`` to run on (left open). ``progress``: a progress bar on stderr.
    ``warn``: called with one line per controller or scenario left out (e.g. print to stderr).
    ``design_checks``: check every controller over its design plant set (module docstring; a
    few seconds per controller, in parallel with the runs). ``certificate``: the certified
    sector of each nominal slip loop (about a second per controller, on the nominal run's
    worker). ``open_loop``: also run each scenario's open loop (its driver's pedal, no
    controller: one short run per scenario) as the baseline the controllers are measured
    against: its metrics, criteria and time responses in ``data["open_loop"]``, drawn and
    tabled beside the controllers, never ranked (a scenario without a pedal signal says so).
    Returns a :class:`Comparison`; raises :class:`CompareError` for invalid options or when no
    controller (or no scenario) is valid."""
    tic = time.perf_counter()
    if model not in MODELS:
        raise CompareError(f"model = {model!r}: must be one of {MODELS}")
    w = _check_weights(weights)
    if t_end is not None and (
        isinstance(t_end, bool) or not isinstance(t_end, int | float) or not 0 < t_end < math.inf
    ):
        raise CompareError(f"t_end = {t_end!r}: must be a finite number > 0 [s] (or None)")
    if isinstance(n_series, bool) or not isinstance(n_series, int) or n_series < 2:
        raise CompareError(f"n_series = {n_series!r}: must be an integer >= 2")
    from .runner import check_cluster_options  # dask only when a comparison runs

    check_cluster_options(workers=workers, error=CompareError)
    if client is not None and workers is not None:
        raise CompareError("client: give a client or workers, not both")
    for name, flag in (
        ("design_checks", design_checks),
        ("certificate", certificate),
        ("open_loop", open_loop),
    ):
        if not isinstance(flag, bool):
            raise CompareError(f"{name} = {flag!r}: must be True or False")
    if not isinstance(params, str | Path | DrivetrainParams):
        raise CompareError(
            f"params = {params!r}: give a parameter set's name, a TOML file or a DrivetrainParams"
        )
    try:
        p = params if isinstance(params, DrivetrainParams) else load_params(params)
    except FileNotFoundError as exc:
        raise CompareError(f"params = {str(params)!r}: file not found: {exc.filename}") from None
    except (ValueError, OSError, TypeError) as exc:
        raise CompareError(f"params = {params!r}: {exc}") from None
    invalid: list[dict[str, str]] = []

    def bad(kind: str, name: Any, reason: str) -> None:
        invalid.append({"kind": kind, "name": str(name), "reason": reason})
        if warn is not None:
            warn(f"{kind} {str(name)!r} left out: {reason}")

    specs: dict[str, ControllerSpec] = {}
    for c in _split(controllers, "controllers"):
        try:
            spec = load_controller(c)
        except (ControllerError, OSError) as exc:
            bad("controller", c, f"does not load: {exc}")
            continue
        if spec.name in specs:
            bad("controller", c, f"a second controller named {spec.name!r} (names must differ)")
            continue
        specs[spec.name] = spec
    scen_names = closed_loop_scenarios(p) if scenarios == "all" else _split(scenarios, "scenarios")
    scens: dict[str, Scenario] = {}
    for s in scen_names:
        try:
            sc = load_scenario(s, params=p)
        except (ValueError, OSError) as exc:
            bad("scenario", s, f"does not load: {exc}")
            continue
        if not sc.needs_controller:
            bad("scenario", s, "open loop (it gives the pedal, not an engine-speed reference)")
            continue
        if sc.name in scens:
            bad("scenario", s, f"a second scenario named {sc.name!r}")
            continue
        scens[sc.name] = sc
    if not specs:
        raise CompareError(
            "no valid controller to compare" + "".join(f"\n  {c}" for c in _lines(invalid))
        )
    if not scens:
        raise CompareError(
            "no valid scenario to compare on" + "".join(f"\n  {c}" for c in _lines(invalid))
        )
    nominal_sc = scens.get(NOMINAL_SCENARIO) or load_scenario(NOMINAL_SCENARIO, params=p)
    tasks: list[tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]] = []
    # the design plant sets first (the longest tasks): one task per distinct set
    groups: dict[str, tuple[dict[str, Any], list[ControllerSpec]]] = {}
    plant_source: dict[str, str] = {}
    if design_checks:
        for c, spec in specs.items():
            kw, plant_source[c] = _plants_of(spec)
            key = json.dumps(kw, sort_keys=True, default=str)
            groups.setdefault(key, (kw, []))[1].append(spec)
        for kw, group in groups.values():
            tasks.append((design_check, (group, kw), {}))
    n_design = len(tasks)
    keys: list[tuple[str, str, bool]] = []  # (controller, scenario, nominal-only)
    for c, spec in specs.items():
        for s, sc in scens.items():
            nom = s == NOMINAL_SCENARIO
            kw = {
                "t_end": t_end,
                "n_series": n_series,
                "bode": nom,
                "certificate": nom and certificate,
            }
            tasks.append((compare_case, (spec, sc, p, model), kw))
            keys.append((c, s, False))
        if NOMINAL_SCENARIO not in scens:
            kw = {"t_end": t_end, "bode": True, "certificate": certificate}
            tasks.append((compare_case, (spec, nominal_sc, p, model), kw))
            keys.append((c, NOMINAL_SCENARIO, True))
    baseline: dict[str, dict[str, Any]] = {}  # the open loop per scenario
    n_closed = len(tasks)
    open_keys: list[str] = []
    if open_loop:
        for s, sc in scens.items():
            if "open" not in sc.loops:
                baseline[s] = {
                    "controller": None,
                    "scenario": s,
                    "loop": "open",
                    "status": None,
                    "error": "no open-loop part (the scenario gives no [inputs.pedal] signal)",
                }
                continue
            kw = {"t_end": t_end, "n_series": n_series}
            tasks.append((compare_case, (None, sc, p, model), kw))
            open_keys.append(s)
    out_all, n_workers, timing = _run_all(tasks, client=client, workers=workers, progress=progress)
    checked: dict[str, dict[str, Any]] = {}
    for r in out_all[:n_design]:
        checked.update(r)
    results = out_all[n_design:n_closed]
    for s, rec in zip(open_keys, out_all[n_closed:], strict=True):
        if rec.get("status") != "failed":
            rec["criteria"] = _criteria(rec, scens[s])
        baseline[s] = rec
    timing["design_checks_s"] = sum(float(r.pop("seconds", 0.0)) for r in checked.values())
    timing["certificate_s"] = sum(
        float((r.get("linear") or {}).pop("certificate_s", 0.0)) for r in results
    )
    runs: dict[tuple[str, str], dict[str, Any]] = {}
    nominal: dict[str, Any] = {}
    for (c, s, only), rec in zip(keys, results, strict=True):
        if s == NOMINAL_SCENARIO:
            nominal[c] = dict(rec.get("linear") or {"slip": None, "slip_reason": rec.get("error")})
            nominal[c]["status"] = rec.get("status")
        if only:
            continue
        rec["criteria"] = _criteria(rec, scens[s])
        rec["linear_vs_nonlinear"] = _agreement(rec, rec["criteria"])
        runs[(c, s)] = rec
    valid = []
    for c in specs:
        slip = (nominal.get(c) or {}).get("slip")
        if slip is not None and slip.get("stable") is False:
            bad("controller", c, f"unstable on the nominal slip loop ({NOMINAL_SCENARIO})")
        else:
            valid.append(c)
    if not valid:
        raise CompareError(
            "no valid controller to compare" + "".join(f"\n  {c}" for c in _lines(invalid))
        )
    design: dict[str, Any] = {}
    for c, spec in specs.items():
        dd = spec.to_dict().get("design") or {}
        ach = dd.get("achieved") or None
        rec = dict(checked.get(c) or {})
        if not design_checks:
            rec["reason"] = "not checked (design_checks=False)"
        design[c] = {
            "method": dd.get("method"),
            "plant_set_source": plant_source.get(c),
            **rec,
            "recorded": {k: ach.get(k) for k in _DESIGN_KEYS} if ach else None,
        }
    data: dict[str, Any] = {
        "format": "drivetrain_ctrl comparison 1",
        "inputs": {
            "controllers": list(specs),
            "controller_specs": {c: s.to_dict() for c, s in specs.items()},
            "scenarios": list(scens),
            "scenario_descriptions": {s: sc.description for s, sc in scens.items()},
            "model": model,
            "params": p.name,
            "t_end_s": t_end,
            "weights": w,
            "n_series": n_series,
            "design_checks": design_checks,
            "certificate": certificate,
            "open_loop": open_loop,
        },
        "definitions": {
            "criteria": dict(CRITERIA),
            "jerk_limit_m_s3": JERK_LIMIT_M_S3,
            "rollback_limit_m": ROLLBACK_LIMIT_M,
            "nominal_scenario": NOMINAL_SCENARIO,
            "default_plant_set": DEFAULT_PLANT_SET,
            "certificate": (
                "the largest friction-slope interval [mu_slope_certified, 0] (of mu/mu0, s/rad) "
                "for which the nominal slip loop is certified stable for every nonlinear, "
                "time-varying friction characteristic with its slope in it: the sector "
                "[0, -k13 mu_slope_certified] (N m s/rad) of the friction feedback "
                "(design.certificates.clutch_sector_certificate)"
            ),
            "slip_delay_s": SLIP_DELAY_S,
            "lock_delay_s": LOCK_DELAY_S,
            "slip_fractions": list(SLIP_FRACTIONS),
            "drift_threshold": DRIFT_THRESHOLD,
            "drift_window_s": DRIFT_WINDOW_S,
            "ratio_cap": RATIO_CAP,
            "series_units": dict(SERIES),
            "open_loop": (
                "the baseline: each scenario run in open loop, its pedal signal (a driver's "
                "pedal, [inputs.pedal] of the scenario) instead of a controller; the same "
                "metrics and criteria, not ranked"
            ),
            "disagree": (
                "the linear slip loop is closed-loop stable at the run's slip point and at the "
                "later slip points (slip speed fallen to the fractions slip_fractions of its "
                "value there), predicting a good engagement, while the run does not lock up "
                "within the horizon or stalls the engine, or the other way round"
            ),
        },
        "invalid": invalid,
        "valid": valid,
        "nominal_linear": nominal,
        "design": design,
        "runs": {c: {s: runs[(c, s)] for s in scens} for c in specs},
        "open_loop": {s: baseline[s] for s in scens if s in baseline},
        "verdict": _verdict(valid, list(scens), runs, nominal, w),
    }
    return Comparison(json_ready(data), time.perf_counter() - tic, n_workers, timing)


def _lines(invalid: Sequence[Mapping[str, str]]) -> list[str]:
    return [f"{p['kind']} {p['name']!r}: {p['reason']}" for p in invalid]
