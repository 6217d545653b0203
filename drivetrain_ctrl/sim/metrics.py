"""Clutch-engagement figures of merit of a simulation run (JSON-ready, deterministic).

:func:`engagement_metrics` condenses a :class:`~drivetrain_ctrl.sim.simulator.SimulationResult` into a
flat dict of the standard figures of merit of a dry-clutch engagement (Della Gatta et al., "A survey
on modeling and engagement control for automotive dry clutch", Mechatronics 55 (2018)): engagement
(lock-up) time, friction energy dissipated in the clutch, lurch and jerk of the vehicle, engine
stall margin and flare, peak driveline torque and backlash activity.

Every float is rounded to :data:`SIGNIFICANT_DIGITS` significant digits, so that two runs of the
same simulation give byte-identical JSON; a figure that is undefined for a run (no lock-up, no
axle in the reduced model, ...) is ``None`` (JSON ``null``). Key suffixes carry the unit
(``_s``, ``_J``, ``_kmh``, ``_rpm``, ``_m_s2``, ``_m_s3``, ``_Nm``, ``_rad_s2``).

Accelerations are evaluated from the model's right-hand side at the samples (not by
differentiating the sampled speed twice): on every sample interval ``[t_k, t_k+1]`` the integrator
holds the mode of sample ``k``, so the acceleration at its start is ``rhs(x_k, u_k, mode_k)`` and
at its end the left limit ``rhs(x_k+1, u_k+1, mode_k)``. Jerk is the difference quotient of these
over the interval, so a jump of the acceleration at a mode change (an event) is not turned into a
spurious huge jerk; such jumps are reported separately (``lurch_m_s2`` at lock-up).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from ..core.serialize import json_ready
from ..core.units import m_s_to_kmh, rad_s_to_rpm
from ..core.validate import is_finite_real
from ..plant.model import Mode, Model
from .simulator import SimulationResult

__all__ = [
    "MIN_INTERVAL_S",
    "METRIC_KEYS",
    "engagement_metrics",
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

#: the keys of :func:`engagement_metrics`, always all present
METRIC_KEYS: tuple[str, ...] = (
    "model",
    "gear",
    "status",
    "t_end_s",
    "n_samples",
    "n_events",
    "inconsistent_decisions",
    "lockup_time_s",
    "clutch_energy_J",
    "work_in_J",
    "energy_residual_rel",
    "final_vehicle_speed_kmh",
    "max_vehicle_accel_m_s2",
    "max_vehicle_jerk_m_s3",
    "lurch_m_s2",
    "lockup_slip_accel_rad_s2",
    "min_engine_speed_rpm",
    "max_engine_speed_rpm",
    "engine_stalled",
    "peak_axle_torque_Nm",
    "peak_shaft_torque_Nm",
    "n_backlash_impacts",
    "n_backlash_crossings",
    "start_s",
    "engagement_time_s",
    "n_lock_events",
    "engine_speed_max_rpm",
    "engine_speed_min_rpm",
    "tracking_rms_rpm",
    "torque_match_rms_Nm",
    "lurch_rad_s2",
    "accel_p2p_after_lock_m_s2",
    "jerk_max_m_s3",
    "jerk_rms_m_s3",
    "notes",
)

#: lock-up is the start of the first stuck phase of the clutch lasting at least this [s]
LOCKUP_MIN_DURATION_S: float = 0.2
#: engagement-window settings: tracking/torque-match from start + this [s] to lock-up
TRACKING_DELAY_S: float = 0.3
#: after lock-up [s]: window of the engine-speed, p2p-acceleration and jerk figures
AFTER_LOCK_S: float = 1.0
#: jerk: vehicle acceleration low-pass filtered at this [Hz] (2nd-order Butterworth, zero phase)
JERK_FILTER_HZ: float = 10.0
#: uniform resampling rate [Hz] of the signals behind the windowed figures
RESAMPLE_HZ: float = 1000.0


def _mode(res: SimulationResult, i: int) -> Mode:
    return Mode(tuple(int(v) for v in res.fm[i]), tuple(int(v) for v in res.reg[i]))


def state_accelerations(res: SimulationResult) -> tuple[F64, F64]:
    """Time derivatives of all states at every sample, from the model's right-hand side.

    Returns ``(right, left)``, both (N, nx) in state units per second (rad/s^2 for a rotational
    speed, m/s^2 for a translational one): ``right[i] = rhs(x_i, u_i, mode_i)`` (the derivative
    just after ``t_i``) and ``left[i] = rhs(x_i, u_i, mode_{i-1})`` (just before ``t_i``, the mode
    the integrator held on ``[t_{i-1}, t_i]``; ``left[0] = right[0]``). They differ only at
    samples where the mode changed (events).
    """
    model = res.model
    n = res.t.shape[0]
    right = np.empty((n, model.nx))
    left = np.empty((n, model.nx))
    prev: Mode | None = None
    for i in range(n):
        mode = _mode(res, i)
        right[i] = model.rhs(res.x[i], res.u[i], mode)
        if prev is None or prev == mode:
            left[i] = right[i]
        else:
            left[i] = model.rhs(res.x[i], res.u[i], prev)
        prev = mode
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


def _backlash_counts(res: SimulationResult) -> tuple[int, int]:
    """(impacts, crossings) summed over every spring with backlash.

    An impact is a ``gap -> contact`` transition; a crossing a traversal of the whole gap, i.e. a
    change of the contact side (``contact-`` ... ``contact+`` or back).
    """
    impacts = 0
    crossings = 0
    for ti in res.model.tables:
        if ti.region_names is None:
            continue
        for ev in res.events:
            if ev.element == ti.name and ev.from_mode == "gap" and ev.to_mode != "gap":
                impacts += 1
        side = 0
        for name in res.mode_series(ti.name):
            s = 1 if name.endswith("+") else -1 if name.endswith("-") else 0
            if s != 0:
                if side != 0 and s != side:
                    crossings += 1
                side = s
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
    sos = signal.butter(2, cutoff_hz, btype="low", fs=fs_hz, output="sos")
    pad = min(3 * (2 * sos.shape[0] + 1), a.shape[0] - 1)
    af = signal.sosfiltfilt(sos, a, padlen=max(pad, 0)) if a.shape[0] > 7 else a
    jk = np.gradient(af, 1.0 / fs_hz) if a.shape[0] > 1 else np.zeros_like(a)
    return grid, np.asarray(af, dtype=float), np.asarray(jk, dtype=float)


def _window(t: F64, t0: float, t1: float) -> NDArray[np.bool_]:
    return np.asarray((t >= t0) & (t <= t1))


def _rms(a: F64) -> float | None:
    return float(np.sqrt(np.mean(a * a))) if a.size else None


def engagement_metrics(
    res: SimulationResult,
    dt: DrivetrainLike | None = None,
    *,
    vehicle: str = "v_vehicle",
    engine: str = "omega_engine",
    clutch: str = "clutch",
    start: float | None = None,
    reference: Any = None,
) -> dict[str, Any]:
    """Figures of merit of run ``res`` of drivetrain ``dt``; a flat, JSON-ready dict.

    Keys (:data:`METRIC_KEYS`, always all present; None where undefined):

    ``model``, ``gear``
        ``dt.kind`` (``"full"`` / ``"reduced"``) and the engaged gear (None without ``dt``).
    ``status``, ``t_end_s``, ``n_samples``, ``n_events``
        Simulation status, final time [s], number of samples and of events (mode changes of
        the model's elements and, in closed loop, of the controller's blocks).
    ``inconsistent_decisions``
        Mode decisions in which no stuck/slip combination was consistent (the least inconsistent
        was taken) or guards still fired after the re-checks; 0 in a sound run (``notes`` says
        so otherwise).
    ``lockup_time_s``
        Lock-up time [s]: the start of the first stuck phase of the clutch that lasts at least
        :data:`LOCKUP_MIN_DURATION_S` = 0.2 s (``res.lockup_time(clutch)``); None if there is none
        (and ``notes`` says so).
    ``start_s``, ``engagement_time_s``
        The start command [s] (argument ``start``: the controller's start time, or the start of the
        pedal release; default the start of the run) and engagement time = lock-up - start [s].
    ``n_lock_events``
        Number of times the clutch entered its stuck mode (re-slips counted: 1 for a clean
        engagement).
    ``clutch_energy_J``
        Energy [J] dissipated by the clutch friction, ``integral of tau_13 * slip dt`` from the
        start of the run to lock-up (to the end of the run without lock-up).
    ``work_in_J``, ``energy_residual_rel``
        Work supplied by the sources [J]; relative energy-balance residual [-]
        (``res.energy_residual_rel``). None if energies were not integrated.
    ``final_vehicle_speed_kmh``
        Vehicle speed at the end [km/h].
    ``max_vehicle_accel_m_s2``
        Largest ``|vehicle acceleration|`` [m/s^2].
    ``max_vehicle_jerk_m_s3``
        Largest ``|jerk|`` [m/s^3]: difference quotient of the acceleration (from the model rhs) over
        the sample intervals, inside modes (see the module docstring; comfort target < 10 m/s^3).
    ``lurch_m_s2``
        Jump of the vehicle acceleration at lock-up [m/s^2], after minus before; None without
        lock-up. With a compliant driveline (both models here) the vehicle is connected to the
        clutch through springs, so its acceleration is continuous and this is ~0; the lock-up
        shock then shows as jerk and shuffle.
    ``lockup_slip_accel_rad_s2``
        Slip acceleration ``d(omega_in - r omega_out)/dt`` [rad/s^2] just before lock-up (the
        "no-lurch" condition asks for 0); None without lock-up.
    ``min_engine_speed_rpm``, ``max_engine_speed_rpm``
        Lowest engine speed (stall margin) and highest (flare) [rpm].
    ``engine_stalled``
        True if the engine's ground friction is ever in its standstill mode.
    ``peak_axle_torque_Nm``
        Largest ``|half-shaft torque|`` [N m] in the wheel frame (``axle`` coupling torque, secondary
        frame, times its ratio D_c); None for the reduced model, which has no axle.
    ``peak_shaft_torque_Nm``
        Largest ``|driveline torque|`` [N m] in the primary-shaft frame, comparable between models:
        the gear-mesh coupling ``backlash`` of the full model, the lumped shaft ``backlash``
        (stiffness h_t) of the reduced model. Wheel-frame equivalent: times ``dt.tau_t``.
    ``n_backlash_impacts``, ``n_backlash_crossings``
        Gap -> contact transitions and complete traversals of the gap (contact side changes).

    Engagement-window figures (the window ``[start, lock-up + 1 s]``; without lock-up, to the end
    of the run). Signals are resampled uniformly at :data:`RESAMPLE_HZ`:

    ``engine_speed_max_rpm``, ``engine_speed_min_rpm``
        Highest (flare) and lowest (stall margin) engine speed [rpm] over the window.
    ``tracking_rms_rpm``
        RMS of ``omega_r - omega_1`` [rpm] over ``[start + 0.3 s, lock-up]``; needs
        ``reference`` (the controller's omega_r signal [rad/s]), else None.
    ``torque_match_rms_Nm``
        RMS of ``tau_13 - C_1`` [N m] (clutch torque minus engine torque: the paper's claim
        tau_13 ~ C_1 while slipping) over ``[start + 0.3 s, lock-up]``.
    ``lurch_rad_s2``
        Jump of the acceleration of the clutch's driven body at lock-up [rad/s^2], after minus
        before: the primary shaft (omega_3) in the reduced model; in the full model the clutch
        disc (omega_2), the body the clutch locks to (the primary shaft sits behind the damper
        spring there and its acceleration has no jump).
    ``accel_p2p_after_lock_m_s2``
        Peak-to-peak vehicle acceleration [m/s^2] over ``[lock-up, lock-up + 1 s]``.
    ``jerk_max_m_s3``, ``jerk_rms_m_s3``
        Largest ``|jerk|`` and RMS jerk [m/s^3] over the window, from the vehicle acceleration
        low-pass filtered at 10 Hz (second-order Butterworth, zero phase; :func:`filtered_jerk`).
    ``notes``
        Plain statements about the run (no lock-up within the horizon, engine stall, ...).

    ``dt`` may be None for a model not built by :class:`~drivetrain_ctrl.plant.drivetrain.Drivetrain`
    (e.g. a :func:`~drivetrain_ctrl.plant.chain.two_body_clutch` test chain). ``vehicle`` and
    ``engine`` name the speed states used for the vehicle and engine figures (for a rotational
    ``vehicle`` state the acceleration figures are in rad/s^2, rad/s^3 and the final speed is
    None); ``clutch`` names the clutch friction element. Figures whose state or element does not
    exist are None.
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
    out["t_end_s"] = float(res.t[-1])
    out["n_samples"] = int(res.t.shape[0])
    out["n_events"] = len(res.events)
    out["inconsistent_decisions"] = int(res.stats.get("inconsistent_decisions", 0))

    # clutch: lock-up, energy, slip acceleration
    fc = _friction_coupling(model, clutch)
    t_lock: float | None = None
    if fc is not None:
        t_lock = res.lockup_time(clutch, min_duration=LOCKUP_MIN_DURATION_S)
        out["lockup_time_s"] = t_lock
        out["n_lock_events"] = len(res.stuck_phases(clutch))
        if res.dissipated is not None:
            j = model.power_names().index(clutch)
            k_end = -1
            if t_lock is not None:
                k_end = int(np.searchsorted(res.t, t_lock, side="right")) - 1
            out["clutch_energy_J"] = float(res.dissipated[k_end, j])
    if res.work_in is not None and res.dissipated is not None:
        out["work_in_J"] = float(res.work_in[-1])
        out["energy_residual_rel"] = res.energy_residual_rel

    # accelerations (only if something needs them)
    need_acc = vehicle in names or (fc is not None and t_lock is not None)
    i_lock: int | None = None
    right: F64 | None = None
    left: F64 | None = None
    if t_lock is not None and fc is not None:
        # the sample recorded just after the lock-up event (several samples may share its time)
        col = res.fm[:, fc[0]]
        for i in range(int(np.searchsorted(res.t, t_lock, side="left")), res.t.shape[0]):
            if res.t[i] != t_lock:
                break
            if i > 0 and col[i] == 0 and col[i - 1] != 0:
                i_lock = i
                break
    if need_acc:
        right, left = state_accelerations(res)
        if vehicle in names:
            iv = names.index(vehicle)
            out["max_vehicle_accel_m_s2"] = _max_abs(right[:, iv])
            out["max_vehicle_jerk_m_s3"] = _max_abs(jerk(res.t, right[:, iv], left[:, iv]))
            if i_lock is not None:
                out["lurch_m_s2"] = float(right[i_lock, iv] - left[i_lock, iv])
        if fc is not None and i_lock is not None:
            c = fc[1]
            r = float(model.data.ratio[c])
            out["lockup_slip_accel_rad_s2"] = float(left[i_lock, c] - r * left[i_lock, c + 1])

    if vehicle in names:
        v_end = float(res.state(vehicle)[-1])
        if model.state_units[names.index(vehicle)] == "m/s":
            out["final_vehicle_speed_kmh"] = float(m_s_to_kmh(v_end))

    if engine in names:
        w = res.state(engine)
        out["min_engine_speed_rpm"] = float(rad_s_to_rpm(float(np.min(w))))
        out["max_engine_speed_rpm"] = float(rad_s_to_rpm(float(np.max(w))))
        stalled = False
        body = engine.removeprefix("omega_")
        for f, fi in enumerate(model.frictions):
            if fi.kind == "ground" and model.chain.bodies[fi.index].name == body:
                stalled = bool(np.any(res.fm[:, f] == 0))
        out["engine_stalled"] = stalled

    # driveline torques
    c_axle = _coupling_index(model, "axle")
    c_shaft = _coupling_index(model, "backlash")
    if c_axle is not None or c_shaft is not None:
        T = res.coupling_torques()
        if c_axle is not None:
            ratio = float(model.data.ratio[c_axle])
            out["peak_axle_torque_Nm"] = float(np.max(np.abs(T[:, c_axle]))) * ratio
        if c_shaft is not None:
            out["peak_shaft_torque_Nm"] = float(np.max(np.abs(T[:, c_shaft])))

    _engagement_window(
        res, out, model, fc, t_lock, i_lock, vehicle, engine, start, reference, right, left
    )
    impacts, crossings = _backlash_counts(res)
    out["n_backlash_impacts"] = impacts
    out["n_backlash_crossings"] = crossings
    result: dict[str, Any] = json_ready(out)
    return result


def _engagement_window(
    res: SimulationResult,
    out: dict[str, Any],
    model: Model,
    fc: tuple[int, int] | None,
    t_lock: float | None,
    i_lock: int | None,
    vehicle: str,
    engine: str,
    start: float | None,
    reference: Any,
    right: F64 | None,
    left: F64 | None,
) -> None:
    """The engagement-window figures of :func:`engagement_metrics` into ``out``; ``right``,
    ``left``: the :func:`state_accelerations` of ``res`` (None if they were not needed)."""
    names = model.state_names
    t = res.t
    t_start = float(t[0]) if start is None else float(start)
    out["start_s"] = t_start
    notes: list[str] = []
    t_final = float(t[-1])
    always_stuck = fc is not None and bool(np.all(res.fm[:, fc[0]] == 0))
    if always_stuck:
        notes.append("the clutch stayed locked throughout the run (no engagement to measure)")
    elif fc is not None and t_lock is None:
        notes.append(
            f"the clutch did not lock up (no stuck phase of at least {LOCKUP_MIN_DURATION_S} s) "
            f"within the horizon of {t_final:g} s: lockup_time_s is null"
        )
    if t_lock is not None:
        out["engagement_time_s"] = t_lock - t_start
    t_win_end = min(t_final, t_lock + AFTER_LOCK_S) if t_lock is not None else t_final
    t_track_end = t_lock if t_lock is not None else t_final
    grid = np.arange(t_start, t_final, 1.0 / RESAMPLE_HZ)
    if grid.size == 0:
        grid = np.array([t_start])
    if engine in names:
        w = np.interp(grid, t, res.state(engine))
        win = _window(grid, t_start, t_win_end)
        if np.any(win):
            out["engine_speed_max_rpm"] = float(rad_s_to_rpm(float(np.max(w[win]))))
            out["engine_speed_min_rpm"] = float(rad_s_to_rpm(float(np.min(w[win]))))
        trk = _window(grid, t_start + TRACKING_DELAY_S, t_track_end)
        if reference is not None and np.any(trk):
            err = np.asarray(reference(grid[trk]), dtype=float) - w[trk]
            out["tracking_rms_rpm"] = _rms(np.asarray(rad_s_to_rpm(err), dtype=float))
        if fc is not None and model.chain.sources and np.any(trk):
            tau = res.coupling_torques()[:, fc[1]]
            c1 = res.source_torques()[model.chain.sources[0].name]
            d = np.interp(grid[trk], t, tau) - np.interp(grid[trk], t, c1)
            out["torque_match_rms_Nm"] = _rms(d)
    if fc is not None and i_lock is not None and right is not None and left is not None:
        jb = fc[1] + 1  # the clutch coupling's driven body
        out["lurch_rad_s2"] = float(right[i_lock, jb] - left[i_lock, jb])
    if right is not None and vehicle in names and model.state_units[names.index(vehicle)] == "m/s":
        acc = right[:, names.index(vehicle)]
        if t.shape[0] > 1:
            g, af, jk = filtered_jerk(t, acc)
            win = _window(g, t_start, t_win_end)
            if np.any(win):
                out["jerk_max_m_s3"] = float(np.max(np.abs(jk[win])))
                out["jerk_rms_m_s3"] = _rms(jk[win])
        if t_lock is not None:
            after = _window(grid, t_lock, t_win_end)
            if np.any(after):
                a = np.interp(grid[after], t, acc)
                out["accel_p2p_after_lock_m_s2"] = float(np.max(a) - np.min(a))
    if out.get("engine_stalled"):
        notes.append("the engine stalled (its friction entered standstill)")
    if out["inconsistent_decisions"]:
        notes.append(
            f"{out['inconsistent_decisions']} mode decision(s) found no consistent stuck/slip "
            "combination; the least inconsistent was taken (see simulate's warning)"
        )
    out["notes"] = notes
