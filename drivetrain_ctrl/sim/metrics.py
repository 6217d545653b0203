"""Clutch-engagement figures of merit of a simulation run (JSON-ready, deterministic).

:func:`engagement_metrics` condenses a :class:`~drivetrain_ctrl.sim.simulator.SimulationResult` into a
flat dict of the standard figures of merit of a dry-clutch engagement (Della Gatta et al., "A survey
on modeling and engagement control for automotive dry clutch", Mechatronics 55 (2018)): engagement
(lock-up) time, friction energy dissipated in the clutch, lurch and jerk, engine stall margin and
flare, tracking, peak driveline torque and backlash activity.

One name, one definition: :data:`METRICS` maps every key :func:`engagement_metrics` returns to its
unit and its definition (a :class:`MetricInfo`), and the command line, the demo's ``summary.md``,
the controller report and the documentation take the definitions from there
(:func:`metric_table`, :func:`metrics_markdown`). A name ends in its unit (``_s``, ``_J``,
``_rpm``, ``_rad_s2``, ``_m_s2``, ``_m_s3``, ``_Nm``, ``_kmh``, ``_m``; ``_rel`` for a relative
number).

Windows. The figures measure the engagement commanded at ``start`` (the controller's start time,
or the start of the pedal release): unless their definition names another interval, over the
*engagement window* ``W = [start, lock-up + 1 s]`` (to the end of the run without lock-up). The
*slip window* of the tracking and torque-match figures is ``[start + 0.3 s, lock-up]`` (to the end
of the run without lock-up). Only the keys describing the run itself (``t_end_s``, ``n_events``,
``work_in_J``, ``energy_residual_rel``, ...) cover the whole run. A figure that is undefined for
a run (no lock-up; the clutch does not slip where the figure measures it; no axle in the reduced
model; ...) is ``None`` (JSON ``null``).

Every float is rounded to :data:`~drivetrain_ctrl.core.serialize.SIGNIFICANT_DIGITS` significant
digits, so that two runs of the same simulation give byte-identical JSON.

Accelerations are evaluated from the model's right-hand side at the samples (not by
differentiating the sampled speed twice): on every sample interval ``[t_k, t_k+1]`` the integrator
holds the mode of sample ``k``, so the acceleration at its start is ``rhs(x_k, u_k, mode_k)`` and
at its end the left limit ``rhs(x_k+1, u_k+1, mode_k)`` (:func:`state_accelerations`). A jump of
an acceleration at a mode change (an event) is reported as such: ``lurch_rad_s2`` at lock-up.
The vehicle itself sits behind the driveline's springs, so its acceleration does not jump; the
lock-up shock reaches it as jerk and shuffle (``jerk_max_m_s3``, ``accel_p2p_after_lock_m_s2``).
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ..core.serialize import json_ready
from ..core.units import m_s_to_kmh, rad_s_to_rpm
from ..core.validate import is_finite_real
from ..kernels.physics import ChainData
from ..plant.model import Model
from .series import RunSeries
from .simulator import SimulationResult

__all__ = [
    "MIN_INTERVAL_S",
    "METRICS",
    "METRIC_KEYS",
    "MetricInfo",
    "engagement_metrics",
    "metric_table",
    "metrics_markdown",
    "state_accelerations",
    "filtered_jerk",
    "jerk",
    "json_ready",
]

F64 = NDArray[np.float64]


class DrivetrainLike(Protocol):
    """What :func:`engagement_metrics` uses of a :class:`~drivetrain_ctrl.plant.drivetrain.Drivetrain`."""

    @property
    def kind(self) -> str: ...

    @property
    def gear(self) -> int: ...


#: sample intervals shorter than this [s] are skipped when differencing accelerations (they only
#: occur at events located to ~1e-13 s, where a difference quotient is round-off)
MIN_INTERVAL_S: float = 1e-12
#: lock-up is the start of the first stuck phase of the clutch lasting at least this [s]
LOCKUP_MIN_DURATION_S: float = 0.2
#: the slip window of the tracking and torque-match figures starts this long [s] after the start
TRACKING_DELAY_S: float = 0.3
#: the engagement window ends this long [s] after lock-up
AFTER_LOCK_S: float = 1.0
#: jerk: vehicle acceleration low-pass filtered at this [Hz] (2nd-order Butterworth, zero phase)
JERK_FILTER_HZ: float = 10.0
#: uniform resampling rate [Hz] of the signals behind the jerk and the RMS figures
RESAMPLE_HZ: float = 1000.0


@dataclass(frozen=True)
class MetricInfo:
    """What one key of :func:`engagement_metrics` means.

    ``unit``: the unit of the value (``"-"`` for a count or a relative number, ``""`` for a text,
    a flag or a list); ``definition``: the one definition of the name, with its interval;
    ``kind``: ``"figure"`` (a figure of merit of the engagement) or ``"run"`` (describes the run
    itself: model, status, sizes, energy check, notes).
    """

    unit: str
    definition: str
    kind: str = "figure"


_W = (
    f"over the engagement window W = [start, lock-up + {AFTER_LOCK_S:g} s] (to the end of the run "
    "without lock-up)"
)
_SLIP = (
    f"over the slip window [start + {TRACKING_DELAY_S:g} s, lock-up] (to the end of the run "
    "without lock-up)"
)

#: The one table of the keys of :func:`engagement_metrics`, in the order they are returned: name
#: -> :class:`MetricInfo` (unit, definition, kind); the documentation's figures-of-merit section
#: shows it as a table.
#:
#: :meta hide-value:
METRICS: dict[str, MetricInfo] = {
    # -- the run ---------------------------------------------------------------------------------
    "model": MetricInfo(
        "", "Model kind of the drivetrain, full or reduced (None without a Drivetrain).", "run"
    ),
    "gear": MetricInfo("-", "Engaged gear (None without a Drivetrain).", "run"),
    "status": MetricInfo(
        "", "Simulation status: ok, or why the run stopped early (zeno, max_steps, ...).", "run"
    ),
    "t_end_s": MetricInfo("s", "Final time of the run.", "run"),
    "n_samples": MetricInfo("-", "Number of recorded samples of the run.", "run"),
    "n_events": MetricInfo(
        "-",
        "Number of events of the whole run: mode changes of the model's elements and, in closed "
        "loop, of the controller's blocks.",
        "run",
    ),
    "inconsistent_decisions": MetricInfo(
        "-",
        "Mode decisions of the whole run in which no stuck/slip combination was consistent (the "
        "least inconsistent was taken); 0 in a sound run.",
        "run",
    ),
    "work_in_J": MetricInfo(
        "J",
        "Work supplied by the sources over the whole run (None if energies were not integrated).",
        "run",
    ),
    "energy_residual_rel": MetricInfo(
        "-",
        "Relative energy-balance residual at the end of the run, |dE_stored - W_in + E_diss| / "
        "max(W_in, E_stored) (None if energies were not integrated).",
        "run",
    ),
    "start_s": MetricInfo(
        "s",
        "Start command: the controller's start time, the start of the pedal release, or the "
        "start of the run; where the engagement window begins.",
        "run",
    ),
    "notes": MetricInfo(
        "",
        "Plain statements about the run: no lock-up, no engagement, engine stall, inconsistent "
        "mode decisions.",
        "run",
    ),
    # -- the engagement --------------------------------------------------------------------------
    "lockup_time_s": MetricInfo(
        "s",
        "Lock-up time: the start of the first stuck phase of the clutch, entered from slip at or "
        f"after the start, that lasts at least {LOCKUP_MIN_DURATION_S:g} s; None if there is none.",
    ),
    "engagement_time_s": MetricInfo(
        "s", "Engagement time, lock-up time minus start; None without lock-up."
    ),
    "n_lock_events": MetricInfo(
        "-",
        "Number of times the clutch entered its stuck mode (1 for a clean engagement, more after "
        f"re-slips, 0 if it never locked), {_W}.",
    ),
    "clutch_energy_J": MetricInfo(
        "J",
        "Energy dissipated by the clutch friction, the integral of clutch torque times slip speed "
        "from the start to lock-up (to the end of the run without lock-up).",
    ),
    "lockup_slip_accel_rad_s2": MetricInfo(
        "rad/s^2",
        "Slip acceleration d(omega_in - r omega_out)/dt of the clutch just before lock-up (the "
        "no-lurch condition asks for 0); None without lock-up.",
    ),
    "lurch_rad_s2": MetricInfo(
        "rad/s^2",
        "Lurch: the jump of the acceleration of the clutch's driven body at lock-up, after minus "
        "before (the clutch disc omega_disc in the full model, the primary shaft omega_primary in "
        "the reduced one); None without lock-up.",
    ),
    "engine_speed_min_rpm": MetricInfo(
        "rpm", f"Lowest engine speed at the samples (the stall margin), {_W}."
    ),
    "engine_speed_max_rpm": MetricInfo(
        "rpm", f"Highest engine speed at the samples (the flare), {_W}."
    ),
    "engine_stalled": MetricInfo(
        "",
        f"True if the engine stops at some sample, {_W}: its speed at or below 0, or its "
        "friction in the standstill mode.",
    ),
    "tracking_rms_rpm": MetricInfo(
        "rpm",
        f"RMS of the engine-speed error omega_r - omega_engine resampled at "
        f"{RESAMPLE_HZ / 1000:g} kHz, {_SLIP}; None without a reference (open loop) or if the "
        "clutch does not slip in that window.",
    ),
    "torque_match_rms_Nm": MetricInfo(
        "N m",
        "RMS of clutch torque minus engine torque, tau_13 - C_1 (the paper's claim: tau_13 ~ C_1 "
        f"while slipping), resampled at {RESAMPLE_HZ / 1000:g} kHz, {_SLIP}; None if the clutch "
        "does not slip in that window.",
    ),
    "vehicle_accel_max_m_s2": MetricInfo(
        "m/s^2",
        f"Largest |vehicle acceleration| at the samples, from the model's right-hand side, {_W}.",
    ),
    "accel_p2p_after_lock_m_s2": MetricInfo(
        "m/s^2",
        "Peak-to-peak vehicle acceleration at the samples (the shuffle after lock-up), over "
        f"[lock-up, lock-up + {AFTER_LOCK_S:g} s]; None without lock-up.",
    ),
    "jerk_max_m_s3": MetricInfo(
        "m/s^3",
        f"Largest |jerk|, {_W}; the jerk is the derivative of the vehicle acceleration resampled "
        f"at {RESAMPLE_HZ / 1000:g} kHz and low-pass filtered at {JERK_FILTER_HZ:g} Hz (2nd-order "
        "Butterworth, zero phase).",
    ),
    "jerk_rms_m_s3": MetricInfo("m/s^3", f"RMS of the filtered jerk of jerk_max_m_s3, {_W}."),
    "shaft_torque_max_Nm": MetricInfo(
        "N m",
        "Largest |driveline torque| in the primary-shaft frame (coupling backlash: the gear mesh "
        f"of the full model, the lumped shaft of the reduced one), {_W}.",
    ),
    "axle_torque_max_Nm": MetricInfo(
        "N m",
        f"Largest |half-shaft torque| in the wheel frame, {_W}; None for the reduced model (no "
        "half-shafts).",
    ),
    "n_backlash_impacts": MetricInfo(
        "-",
        f"Backlash impacts (gap -> contact transitions of every spring with backlash), {_W}.",
    ),
    "n_backlash_crossings": MetricInfo(
        "-", f"Complete traversals of a backlash gap (changes of the contact side), {_W}."
    ),
    "final_vehicle_speed_kmh": MetricInfo("km/h", "Vehicle speed at the end of the run."),
    "rollback_m": MetricInfo(
        "m",
        "Roll-back: the largest backward displacement of the vehicle from its position at the "
        "start of the run, max(0, x(t0) - min x) of the pos_vehicle state at the samples, over "
        "the whole run (a hill start's hill-hold figure); None without a pos_vehicle state in m.",
    ),
}

#: the keys of :func:`engagement_metrics`, always all present (the keys of :data:`METRICS`)
METRIC_KEYS: tuple[str, ...] = tuple(METRICS)


def metric_table(keys: Iterable[str] | None = None) -> list[tuple[str, str, str]]:
    """``(name, unit, definition)`` of every key of :data:`METRICS` (in its order), or of
    ``keys`` in the order given; an unknown name is a :class:`KeyError` naming it."""
    names = METRIC_KEYS if keys is None else tuple(keys)
    unknown = [k for k in names if k not in METRICS]
    if unknown:
        raise KeyError(f"metric_table: not a metric: {', '.join(map(repr, unknown))}")
    return [(k, METRICS[k].unit, METRICS[k].definition) for k in names]


def metrics_markdown(keys: Iterable[str] | None = None) -> str:
    """The Markdown table ``| key | unit | definition |`` of :func:`metric_table` (the one in the
    documentation's figures-of-merit section)."""
    lines = ["| key | unit | definition |", "|---|---|---|"]
    for k, unit, text in metric_table(keys):
        cells = (f"`{k}`", unit or " ", text)
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines) + "\n"


def state_accelerations(res: SimulationResult) -> tuple[F64, F64]:
    """Time derivatives of all states at every sample, from the model's right-hand side.

    Returns ``(right, left)``, both (N, nx) in state units per second (rad/s^2 for a rotational
    speed, m/s^2 for a translational one): ``right[i] = rhs(x_i, u_i, mode_i)`` (the derivative
    just after ``t_i``) and ``left[i] = rhs(x_i, u_i, mode_{i-1})`` (just before ``t_i``, the mode
    the integrator held on ``[t_{i-1}, t_i]``; ``left[0] = right[0]``). They differ only at
    samples where the mode changed (events). Evaluated on the whole run at once
    (:func:`~drivetrain_ctrl.sim.series.state_derivatives`), equal to
    :meth:`Model.rhs <drivetrain_ctrl.plant.model.Model.rhs>` row by row to round-off.
    """
    return _state_accelerations(_run_series(res, res.model.data))


def _run_series(res: SimulationResult, D: ChainData) -> RunSeries:
    """A :class:`~drivetrain_ctrl.sim.series.RunSeries` of ``res``'s arrays with model data ``D``."""
    return RunSeries(
        D,
        np.asarray(res.x, dtype=float),
        np.asarray(res.u, dtype=float),
        np.asarray(res.fm, dtype=np.int64),
        np.asarray(res.reg, dtype=np.int64),
    )


def _state_accelerations(s: RunSeries) -> tuple[F64, F64]:
    """``(right, left)`` of :func:`state_accelerations` from ``s`` (its state derivatives are
    ``right``; ``left`` is a copy with the event rows re-evaluated in the previous mode)."""
    X, FM, REG = s.X, s.FM, s.REG
    right = s.state_derivatives()
    left = right.copy()
    changed = np.zeros(X.shape[0], dtype=bool)
    if X.shape[0] > 1:
        changed[1:] = np.any(FM[1:] != FM[:-1], axis=1) | np.any(REG[1:] != REG[:-1], axis=1)
    idx = np.flatnonzero(changed)
    if idx.size:
        left[idx] = s.at(idx, idx - 1).state_derivatives()
    return right, left


def jerk(t: F64, right: F64, left: F64, *, min_interval: float = MIN_INTERVAL_S) -> F64:
    """Difference quotient of an acceleration over each sample interval.

    ``t`` (N,) [s]; ``right``/``left`` (N,) accelerations just after / just before each sample (see
    :func:`state_accelerations`). Returns ``(left[k+1] - right[k]) / (t[k+1] - t[k])`` for every
    interval longer than ``min_interval`` [s] (shorter ones, in particular zero-length ones, are
    skipped), in acceleration units per second (m/s^3 for a vehicle speed).
    """
    t = np.asarray(t, dtype=float)
    dt = np.diff(t)
    keep = dt > min_interval
    da = np.asarray(left, dtype=float)[1:] - np.asarray(right, dtype=float)[:-1]
    return np.asarray(da[keep] / dt[keep], dtype=float)


def _friction_coupling(model: Model, name: str) -> tuple[int, int] | None:
    """(friction index, coupling index) of coupling friction element ``name``, or None."""
    for f, fi in enumerate(model.frictions):
        if fi.name == name and fi.kind == "coupling":
            return f, fi.index
    return None


def _coupling_index(model: Model, name: str) -> int | None:
    for c, cp in enumerate(model.chain.couplings):
        if cp.name == name:
            return c
    return None


def _backlash_counts(res: SimulationResult, t0: float, t1: float) -> tuple[int, int]:
    """(impacts, crossings) in ``[t0, t1]`` [s], summed over every spring with backlash.

    An impact is a ``gap -> contact`` transition; a crossing a traversal of the whole gap, i.e. a
    change of the contact side (``contact-`` ... ``contact+`` or back), counted at the sample
    where the new side is reached.
    """
    impacts = 0
    crossings = 0
    for k, ti in enumerate(res.model.tables):
        if ti.region_names is None:
            continue
        for ev in res.events:
            if (
                ev.element == ti.name
                and ev.from_mode == "gap"
                and ev.to_mode != "gap"
                and t0 <= ev.t <= t1
            ):
                impacts += 1
        # the contact side at every sample (+1, -1, 0 in the gap); a crossing is a change of
        # side between consecutive samples in contact, counted where the new side is reached
        sides = np.array(
            [1 if n.endswith("+") else -1 if n.endswith("-") else 0 for n in ti.region_names]
        )
        s = sides[res.reg[:, k]]
        touch = np.flatnonzero(s != 0)
        if touch.size > 1:
            change = touch[1:][s[touch[1:]] != s[touch[:-1]]]
            tc = res.t[change]
            crossings += int(np.count_nonzero((tc >= t0) & (tc <= t1)))
    return impacts, crossings


def _max_abs(a: F64) -> float | None:
    return float(np.max(np.abs(a))) if a.size else None


def filtered_jerk(
    t: F64,
    accel: F64,
    *,
    cutoff_hz: float = JERK_FILTER_HZ,
    fs_hz: float = RESAMPLE_HZ,
) -> tuple[F64, F64, F64]:
    """Jerk from an acceleration sampled at (non-uniform) times ``t`` [s].

    The acceleration [m/s^2] is resampled uniformly at ``fs_hz`` [Hz] (linear interpolation),
    low-pass filtered by a second-order Butterworth filter at ``cutoff_hz`` [Hz] run forwards and
    backwards (zero phase, ``scipy.signal.sosfiltfilt``) and differentiated (central differences).
    Returns ``(grid [s], filtered acceleration [m/s^2], jerk [m/s^3])``.

    ``t`` and ``accel`` must be 1-D arrays of the same length >= 2 with finite values, ``t``
    non-decreasing with ``t[-1] > t[0]`` (else :class:`ValueError` naming the argument). Repeated
    times are allowed: a simulation records several samples at the time of an event.
    """
    from scipy import signal

    t = np.asarray(t, dtype=float)
    accel = np.asarray(accel, dtype=float)
    if t.ndim != 1 or accel.ndim != 1:
        raise ValueError(
            f"filtered_jerk: t and accel must be 1-D arrays, got shapes {t.shape} and {accel.shape}"
        )
    if t.shape != accel.shape:
        raise ValueError(
            f"filtered_jerk: t and accel must have the same length, got {t.shape[0]} and "
            f"{accel.shape[0]}"
        )
    if t.shape[0] < 2:
        raise ValueError(f"filtered_jerk: t has {t.shape[0]} sample(s); needs at least 2")
    if not np.all(np.isfinite(t)):
        raise ValueError("filtered_jerk: t must be finite")
    if not np.all(np.isfinite(accel)):
        raise ValueError("filtered_jerk: accel must be finite")
    steps = np.diff(t)
    if not np.all(steps >= 0):
        i = int(np.argmax(steps < 0)) + 1
        raise ValueError(
            f"filtered_jerk: t must be non-decreasing, but t[{i}] = {t[i]!r} < "
            f"t[{i - 1}] = {t[i - 1]!r}"
        )
    if not t[-1] > t[0]:
        raise ValueError(f"filtered_jerk: t spans no time (t[0] = t[-1] = {t[0]!r})")
    for nm, v in (("cutoff_hz", cutoff_hz), ("fs_hz", fs_hz)):
        if not is_finite_real(v) or v <= 0:
            raise ValueError(f"filtered_jerk: {nm} = {v!r} [Hz]: must be a finite number > 0")
    if not cutoff_hz < fs_hz / 2:
        raise ValueError(
            f"filtered_jerk: cutoff_hz = {cutoff_hz!r} must be below half of fs_hz = {fs_hz!r}"
        )
    grid = np.arange(float(t[0]), float(t[-1]), 1.0 / fs_hz)
    a = np.interp(grid, t, accel)
    sos = _butter_sos(float(cutoff_hz), float(fs_hz)).copy()  # scipy's filters want it writable
    pad = min(3 * (2 * sos.shape[0] + 1), a.shape[0] - 1)
    af = signal.sosfiltfilt(sos, a, padlen=max(pad, 0)) if a.shape[0] > 7 else a
    jk = np.gradient(af, 1.0 / fs_hz) if a.shape[0] > 1 else np.zeros_like(a)
    return grid, np.asarray(af, dtype=float), np.asarray(jk, dtype=float)


@functools.lru_cache(maxsize=16)
def _butter_sos(cutoff_hz: float, fs_hz: float) -> F64:
    """The jerk filter's second-order sections (designed once per cutoff and rate: a
    ``scipy.signal.butter`` design costs about as much as the filtering itself)."""
    from scipy import signal

    sos = np.asarray(signal.butter(2, cutoff_hz, btype="low", fs=fs_hz, output="sos"), dtype=float)
    sos.setflags(write=False)  # shared: callers take a copy
    return sos


def _window(t: F64, t0: float, t1: float) -> NDArray[np.bool_]:
    return np.asarray((t >= t0) & (t <= t1))


def _rms(a: F64) -> float | None:
    return float(np.sqrt(np.mean(a * a))) if a.size else None


def engagement_metrics(
    res: SimulationResult,
    dt: DrivetrainLike | None = None,
    *,
    vehicle: str = "v_vehicle",
    vehicle_pos: str = "pos_vehicle",
    engine: str = "omega_engine",
    clutch: str = "clutch",
    start: float | None = None,
    reference: Any = None,
) -> dict[str, Any]:
    """Figures of merit of run ``res`` of drivetrain ``dt``; a flat, JSON-ready dict.

    The keys are those of :data:`METRICS`, always all present and in its order, each with the
    definition given there (None where undefined); see the module docstring for the windows.

    ``start``: the start command [s] (the controller's start time, or the start of the pedal
    release; default the start of the run), where the engagement window begins. ``reference``:
    the controller's engine-speed reference omega_r (a signal of t [s] in rad/s), for
    ``tracking_rms_rpm``. ``dt`` may be None for a model not built by
    :class:`~drivetrain_ctrl.plant.drivetrain.Drivetrain` (e.g. a
    :func:`~drivetrain_ctrl.plant.chain.two_body_clutch` test chain). ``vehicle`` and ``engine``
    name the speed states used for the vehicle and engine figures, ``clutch`` the clutch friction
    element; figures whose state or element does not exist are None, and so are the vehicle
    figures for a ``vehicle`` state that is not a translational speed in m/s (their names carry
    m/s units); ``vehicle_pos`` names the vehicle's position state [m] of ``rollback_m``.
    """
    if start is not None and not is_finite_real(start):
        raise ValueError(f"engagement_metrics: start = {start!r} [s]: must be a finite number")
    if start is not None and not float(res.t[0]) <= start <= float(res.t[-1]):
        raise ValueError(
            f"engagement_metrics: start = {start!r} [s]: must lie within the run "
            f"[{float(res.t[0])!r}, {float(res.t[-1])!r}] s"
        )
    if reference is not None and not callable(reference):
        raise TypeError(
            f"engagement_metrics: reference = {reference!r}: must be a Signal (callable of t [s])"
        )
    model = res.model
    names = model.state_names
    if dt is not None and not (hasattr(dt, "kind") and hasattr(dt, "gear")):
        raise TypeError(f"engagement_metrics: dt = {dt!r}: must be a Drivetrain or None")
    frictions = [fi.name for fi in model.frictions]
    for arg, val, default, known in (
        ("vehicle", vehicle, "v_vehicle", names),
        ("vehicle_pos", vehicle_pos, "pos_vehicle", names),
        ("engine", engine, "omega_engine", names),
        ("clutch", clutch, "clutch", frictions),
    ):
        # a name other than the default must exist (the defaults may be absent from a general
        # chain: their metrics are then None)
        if val != default and val not in known:
            raise ValueError(
                f"engagement_metrics: {arg} = {val!r}: not in the model (choose from {known})"
            )
    out: dict[str, Any] = dict.fromkeys(METRIC_KEYS)
    out["model"] = dt.kind if dt is not None else None
    out["gear"] = int(dt.gear) if dt is not None else None
    out["status"] = res.status
    t = res.t
    t_final = float(t[-1])
    out["t_end_s"] = t_final
    out["n_samples"] = int(t.shape[0])
    out["n_events"] = len(res.events)
    out["inconsistent_decisions"] = int(res.stats.get("inconsistent_decisions", 0))
    if res.work_in is not None and res.dissipated is not None:
        out["work_in_J"] = float(res.work_in[-1])
        out["energy_residual_rel"] = res.energy_residual_rel
    t_start = float(t[0]) if start is None else float(start)
    out["start_s"] = t_start
    notes: list[str] = []

    # the clutch: lock-up, the windows, the energy
    fc = _friction_coupling(model, clutch)
    t_lock: float | None = None
    i_lock: int | None = None  # the sample recorded just after the lock-up event
    if fc is not None:
        t_lock = res.lockup_time(clutch, min_duration=LOCKUP_MIN_DURATION_S, after=t_start)
        out["lockup_time_s"] = t_lock
        if t_lock is not None:
            out["engagement_time_s"] = t_lock - t_start
            col = res.fm[:, fc[0]]  # 0: stuck
            for i in range(int(np.searchsorted(t, t_lock, side="left")), t.shape[0]):
                if t[i] != t_lock:
                    break
                if i > 0 and col[i] == 0 and col[i - 1] != 0:
                    i_lock = i
                    break
    t_win_end = min(t_final, t_lock + AFTER_LOCK_S) if t_lock is not None else t_final
    t_slip_end = t_lock if t_lock is not None else t_final
    in_w = _window(t, t_start, t_win_end)
    slips_in_slip_window = True  # without a clutch there is nothing to judge
    if fc is not None:
        f = fc[0]
        out["n_lock_events"] = sum(
            1 for t0, _ in res.stuck_phases(clutch) if t_start <= t0 <= t_win_end
        )
        slipping = res.fm[:-1, f] != 0  # the mode held on [t_k, t_k+1]
        slips_in_slip_window = bool(
            np.any(slipping & (t[:-1] < t_slip_end) & (t[1:] > t_start + TRACKING_DELAY_S))
        )
        if not np.any(slipping & (t[1:] > t_start)):
            notes.append(
                "the clutch stayed locked from the start to the end of the run (no engagement "
                "to measure)"
            )
        elif t_lock is None:
            notes.append(
                f"the clutch did not lock up (no stuck phase of at least {LOCKUP_MIN_DURATION_S} "
                f"s) within the horizon of {t_final:g} s: lockup_time_s is null"
            )
        if res.dissipated is not None:
            e = res.dissipated[:, model.power_names().index(clutch)]
            k_end = int(np.searchsorted(t, t_slip_end, side="right")) - 1
            out["clutch_energy_J"] = float(e[k_end]) - float(np.interp(t_start, t, e))

    # accelerations (only if something needs them)
    is_vehicle = vehicle in names and model.state_units[names.index(vehicle)] == "m/s"
    # the run's per-sample arrays, each computed once and shared by the accelerations and the
    # coupling torques (body forces, slip torques, mode matrices); the coupling torques use the
    # data the run used (smoothed, if it was), the accelerations the model's own
    # (as res.coupling_torques() and state_accelerations(res))
    rs = _run_series(res, model.data)
    rs_T = rs if res._data() is model.data else _run_series(res, res._data())
    right: F64 | None = None
    left: F64 | None = None
    if is_vehicle or i_lock is not None:
        right, left = _state_accelerations(rs)
    if fc is not None and i_lock is not None and right is not None and left is not None:
        c = fc[1]
        r = float(model.data.ratio[c])
        out["lockup_slip_accel_rad_s2"] = float(left[i_lock, c] - r * left[i_lock, c + 1])
        jb = c + 1  # the clutch coupling's driven body
        out["lurch_rad_s2"] = float(right[i_lock, jb] - left[i_lock, jb])

    if is_vehicle and right is not None and left is not None:
        iv = names.index(vehicle)
        out["final_vehicle_speed_kmh"] = float(m_s_to_kmh(float(res.x[-1, iv])))
        acc_r, acc_l = right[:, iv], left[:, iv]
        # both one-sided limits at the samples in W (the left one only inside W)
        out["vehicle_accel_max_m_s2"] = _max_abs(
            np.concatenate([acc_r[in_w], acc_l[in_w & (t > t_start)]])
        )
        if t_lock is not None:
            first = i_lock if i_lock is not None else int(np.searchsorted(t, t_lock, "right"))
            after = in_w & (np.arange(t.shape[0]) >= first)
            a = np.concatenate([acc_r[after], acc_l[after & (np.arange(t.shape[0]) > first)]])
            if a.size:
                out["accel_p2p_after_lock_m_s2"] = float(np.max(a) - np.min(a))
        if t.shape[0] > 1:
            g, _, jk = filtered_jerk(t, acc_r)
            win = _window(g, t_start, t_win_end)
            if np.any(win):
                out["jerk_max_m_s3"] = float(np.max(np.abs(jk[win])))
                out["jerk_rms_m_s3"] = _rms(jk[win])

    grid = np.arange(t_start, t_final, 1.0 / RESAMPLE_HZ)
    trk = _window(grid, t_start + TRACKING_DELAY_S, t_slip_end)
    T: F64 | None = None
    if engine in names:
        w = res.state(engine)
        ends = np.interp([t_start, t_win_end], t, w)
        w_win = np.concatenate([w[in_w], ends])
        out["engine_speed_min_rpm"] = float(rad_s_to_rpm(float(np.min(w_win))))
        out["engine_speed_max_rpm"] = float(rad_s_to_rpm(float(np.max(w_win))))
        # stopped: at or below zero speed (dragged backwards by the clutch it is no longer an
        # engine), or its friction in the standstill mode
        stalled = bool(np.min(w_win) <= 0.0)
        body = engine.removeprefix("omega_")
        for k, fi in enumerate(model.frictions):
            if fi.kind == "ground" and model.chain.bodies[fi.index].name == body:
                stalled = stalled or bool(np.any(res.fm[in_w, k] == 0))
        out["engine_stalled"] = stalled
        if reference is not None and slips_in_slip_window and np.any(trk):
            err = np.asarray(reference(grid[trk]), dtype=float) - np.interp(grid[trk], t, w)
            out["tracking_rms_rpm"] = _rms(np.asarray(rad_s_to_rpm(err), dtype=float))
    if fc is not None and model.chain.sources and slips_in_slip_window and np.any(trk):
        T = rs_T.coupling_torques()
        c1 = res.source_torques()[model.chain.sources[0].name]
        d = np.interp(grid[trk], t, T[:, fc[1]]) - np.interp(grid[trk], t, c1)
        out["torque_match_rms_Nm"] = _rms(d)

    # roll-back: the vehicle's position state against its value at the start of the run
    if vehicle_pos in names and model.state_units[names.index(vehicle_pos)] == "m":
        xp = res.state(vehicle_pos)
        out["rollback_m"] = max(0.0, float(xp[0]) - float(np.min(xp)))

    # driveline torques
    c_axle = _coupling_index(model, "axle")
    c_shaft = _coupling_index(model, "backlash")
    if (c_axle is not None or c_shaft is not None) and np.any(in_w):
        if T is None:
            T = rs_T.coupling_torques()
        if c_axle is not None:
            ratio = float(model.data.ratio[c_axle])
            out["axle_torque_max_Nm"] = float(np.max(np.abs(T[in_w, c_axle]))) * ratio
        if c_shaft is not None:
            out["shaft_torque_max_Nm"] = float(np.max(np.abs(T[in_w, c_shaft])))
    impacts, crossings = _backlash_counts(res, t_start, t_win_end)
    out["n_backlash_impacts"] = impacts
    out["n_backlash_crossings"] = crossings

    if out.get("engine_stalled"):
        notes.append("the engine stalled (it stopped or turned backwards)")
    if out["inconsistent_decisions"]:
        notes.append(
            f"{out['inconsistent_decisions']} mode decision(s) found no consistent stuck/slip "
            "combination; the least inconsistent was taken (see simulate's warning)"
        )
    out["notes"] = notes
    result: dict[str, Any] = json_ready(out)
    return result
