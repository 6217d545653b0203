"""Loop analysis: stability margins, root loci on a parameter grid, Nyquist data.

Results are frozen dataclasses with ``to_dict()`` (JSON-ready, floats rounded by
:func:`drivetrain_ctrl.core.serialize.json_ready`) and ``plot()`` (drawn by :mod:`drivetrain_ctrl.reporting.figures`).
Undefined figures are None with a reason in ``reasons``.

Margins of a loop ``L`` (negative feedback, ``S = 1/(1+L)``, ``T = L/(1+L)``):

* classical gain / phase margins and crossovers (``control.stability_margins``);
* delay margin ``PM [rad] / omega_gc`` [s];
* symmetric (balanced, skew 0) disk margin (Blight, Dailey, Gangsaas 1994; Seiler, Packard,
  Gahinet, "An introduction to disk margins", IEEE CSM 2020):
  ``alpha = 1 / max_w |S(jw) - T(jw)| / 2``, i.e. ``1/||S - 1/2||_inf``; the loop tolerates
  simultaneous gain and phase variations in the disk with gain range
  ``[(1 - alpha/2)/(1 + alpha/2), (1 + alpha/2)/(1 - alpha/2)]`` and phase ``+-2 atan(alpha/2)``
  (computed from one vectorised frequency response on the grid, checked against
  ``control.disk_margins`` in the tests);
* ``ms = ||S||_inf``, ``mt = ||T||_inf``, bandwidth: first frequency where ``|T|`` falls below
  ``|T(0)|/sqrt(2)``; closed-loop poles with damping and natural frequency (discrete poles mapped
  by ``s = ln(z)/dt``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import control
import numpy as np
from numpy.typing import NDArray

from ..control.blocks import Actuator, Controller, require_controller
from ..core.serialize import json_ready
from ..core.validate import is_finite_real
from ..plant.drivetrain import clutch_friction
from ..plant.params import DrivetrainParams
from .clutch import _slip_mode_poles_of, clutch_loop
from .linearisation import linearise, natural_frequency_damping, trim_tf
from .operating_point import OperatingPoint, rebuild_operating_point, require_op

__all__ = [
    "Pole",
    "LoopMargins",
    "loop_margins",
    "disk_figures",
    "clutch_loop_margins",
    "RootLocusPoint",
    "RootLocus",
    "root_locus",
    "NyquistData",
    "nyquist_data",
    "poles_of",
]

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Pole:
    """A pole [1/s]: real, imag parts, natural frequency ``|p|/2pi`` [Hz] and damping ratio
    ``-Re p/|p|`` (1 for a stable real pole, negative when unstable)."""

    real: float
    imag: float
    frequency_hz: float
    damping: float


def db_phase(h: Any) -> tuple[F64, F64]:
    """Magnitude [dB] (-inf where 0) and unwrapped phase [deg] of a complex frequency response."""
    h = np.asarray(h, dtype=complex).reshape(-1)
    with np.errstate(divide="ignore"):
        db = 20.0 * np.log10(np.abs(h))
    return db, np.degrees(np.unwrap(np.angle(h)))


def poles_of(p: Sequence[complex] | NDArray[Any], dt: float | None = None) -> tuple[Pole, ...]:
    """:class:`Pole` of each value (discrete poles ``z`` mapped by ``s = ln(z)/dt``), sorted by
    frequency then imaginary part. ``dt`` [s]: None (continuous poles) or the finite, positive
    sample period (ValueError otherwise)."""
    if dt is not None:
        if not (is_finite_real(dt) and dt > 0):
            raise ValueError(f"dt = {dt!r}: must be None or a finite sample period > 0 [s]")
    out = []
    for z in np.asarray(p, dtype=complex):
        s = complex(np.log(z) / dt) if dt else complex(z)
        out.append(Pole(s.real, s.imag, *natural_frequency_damping(s)))
    return tuple(sorted(out, key=lambda q: (q.frequency_hz, q.imag)))


def _dt_of(L: Any) -> float | None:
    dt = L.dt
    return None if (dt is None or dt == 0 or dt is True) else float(dt)


def _check_siso(L: Any) -> None:
    if not isinstance(L, control.LTI):
        raise TypeError(f"L: a python-control LTI system is needed, got {type(L).__name__}")
    if L.ninputs != 1 or L.noutputs != 1:
        raise ValueError(f"L: must be SISO, got {L.ninputs} in / {L.noutputs} out")


def _auto_grid(L: Any, *, n: int = 4000, span: float = 1e3, tiny: float = 0.0) -> F64:
    """``n`` log-spaced frequencies [rad/s] from ``1/span`` of the slowest to ``span`` times the
    fastest pole or zero of ``L`` with magnitude above ``tiny`` (discrete: ``ln(z)/dt``, up to
    0.999 of the Nyquist frequency)."""
    dt = _dt_of(L)
    pz = np.concatenate(_poles_zeros(L))
    feats = [abs(complex(x)) for x in pz]
    if dt:
        zs = [complex(x) for x in pz if abs(complex(x)) > 1e-12]
        feats = [abs(complex(np.log(z) / dt)) for z in zs]
    feats = [f for f in feats if f > tiny and np.isfinite(f)] or [1.0]
    lo = min(feats) / span
    hi = math.pi / dt * 0.999 if dt else max(feats) * span
    return np.logspace(math.log10(lo), math.log10(hi), n)


def _siso_tf(L: Any) -> bool:
    return isinstance(L, control.TransferFunction) and L.ninputs == 1 and L.noutputs == 1


def _poles_zeros(L: Any) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Poles and zeros of ``L``; a SISO transfer function's as the roots of its denominator and
    numerator (python-control's ``poles()`` goes through a common denominator: the same roots,
    at several times the cost)."""
    if _siso_tf(L):
        num, den = L.num[0][0], L.den[0][0]
        return np.roots(den).astype(complex), np.roots(num).astype(complex)
    return np.asarray(L.poles(), dtype=complex), np.asarray(L.zeros(), dtype=complex)


def _closed_loop_poles(L: Any) -> NDArray[np.complex128]:
    """Poles of the negative-feedback loop ``feedback(L, 1)``: for a SISO transfer function the
    roots of ``den + num`` (the denominator python-control's ``feedback`` forms)."""
    if _siso_tf(L):
        char = np.trim_zeros(np.polyadd(L.den[0][0], L.num[0][0]), "f")
        return np.roots(char).astype(complex)
    return np.asarray(control.feedback(L, 1).poles(), dtype=complex)


def _grid(L: Any, omega: Sequence[float] | None) -> F64:
    if omega is None:
        return _auto_grid(L)
    try:
        w = np.asarray(omega, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"omega = {omega!r}: a 1-D grid of frequencies [rad/s] is needed") from exc
    if w.ndim != 1 or w.size < 2:
        raise ValueError(f"omega: a 1-D grid of > 1 positive frequencies [rad/s], got {w!r}")
    if not np.all(np.isfinite(w)):
        raise ValueError(f"omega: frequencies must be finite [rad/s], got {w!r}")
    if not np.all(w > 0):
        raise ValueError(f"omega: frequencies must be > 0 [rad/s], got {w!r}")
    if not np.all(np.diff(w) > 0):
        raise ValueError(f"omega: frequencies must be strictly increasing [rad/s], got {w!r}")
    return w


def _freq(L: Any, w: F64) -> NDArray[np.complex128]:
    dt = _dt_of(L)
    s = np.exp(1j * w * dt) if dt else 1j * w
    return np.asarray(L(s), dtype=complex).reshape(-1)


@dataclass(frozen=True)
class LoopMargins:
    """Stability margins of a loop (module docstring). Units: dB, deg, s, rad/s, Hz.

    ``gain_margin_db`` (None: no phase crossover), ``phase_margin_deg`` (None: no gain crossover),
    ``delay_margin_s``, ``disk_margin`` (alpha), ``disk_margin_db``, ``disk_margin_deg``, ``ms``,
    ``mt``, ``crossover_rad_s`` (gain crossover), ``phase_crossover_rad_s``, ``bandwidth_rad_s``,
    ``closed_loop_poles``, ``natural_frequencies_hz`` (of the oscillatory closed-loop poles),
    ``stable`` (closed loop), ``dt`` (sample period of a discrete loop, None if continuous),
    ``reasons`` (``(figure, why None)`` pairs)."""

    gain_margin_db: float | None
    phase_margin_deg: float | None
    delay_margin_s: float | None
    disk_margin: float | None
    disk_margin_db: float | None
    disk_margin_deg: float | None
    ms: float | None
    mt: float | None
    crossover_rad_s: float | None
    phase_crossover_rad_s: float | None
    bandwidth_rad_s: float | None
    closed_loop_poles: tuple[Pole, ...]
    natural_frequencies_hz: tuple[float, ...]
    stable: bool | None
    dt: float | None = None
    reasons: tuple[tuple[str, str], ...] = ()

    @classmethod
    def undefined(cls, reason: str) -> LoopMargins:
        """Every figure None with ``reason`` (e.g. the clutch loop is open when locked)."""
        names = [f.name for f in dataclasses.fields(cls)]
        kw: dict[str, Any] = dict.fromkeys(names)
        kw["closed_loop_poles"] = ()
        kw["natural_frequencies_hz"] = ()
        kw["reasons"] = (("all", reason),)
        return cls(**kw)

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["closed_loop_poles"] = [dataclasses.asdict(p) for p in self.closed_loop_poles]
        d["reasons"] = dict(self.reasons)
        return json_ready(d)

    def plot(self, L: Any = None, path: str | None = None) -> Any:
        """Bode diagram of ``L``, ``S`` and ``T`` (if ``L`` is given) beside the closed-loop poles;
        a matplotlib Figure (:func:`drivetrain_ctrl.reporting.figures.plot_loop`), saved to ``path``."""
        from ..reporting.figures import plot_loop

        poles = [(p.real, p.imag) for p in self.closed_loop_poles]

        def fmt(v: float | None) -> str:
            return "-" if v is None else f"{v:.3g}"

        title = (
            f"GM {fmt(self.gain_margin_db)} dB, PM {fmt(self.phase_margin_deg)} deg, "
            f"DM {fmt(self.disk_margin_db)} dB"
        )
        if L is None:
            return plot_loop([], {}, title=title, poles=poles, path=path)
        w = _grid(L, None)
        Lw = _freq(L, w)
        bode = {k: db_phase(h) for k, h in (("L", Lw), ("S", 1 / (1 + Lw)), ("T", Lw / (1 + Lw)))}
        return plot_loop(w, bode, title=title, poles=poles, path=path)


def disk_figures(alpha: float) -> tuple[float, float]:
    """Disk-based gain [dB] and phase [deg] margins of a symmetric (skew 0) disk margin
    ``alpha``, as python-control's ``disk_margins`` gives them: with ``t = alpha/2`` the gain
    margin ``20 log10((1 + t)/(1 - t))`` (inf for ``alpha >= 2``) and the phase margin
    ``arccos((1 - t^2)/(1 + t^2)) = 2 atan(t)`` (90 at ``alpha = 2``, above 90 beyond)."""
    if not alpha >= 0.0:
        raise ValueError(f"alpha = {alpha!r}: a disk margin is a number >= 0 (or inf)")
    t = 0.5 * alpha
    gain_db = 20.0 * math.log10((1.0 + t) / (1.0 - t)) if alpha < 2.0 else math.inf
    c = (1.0 - t * t) / (1.0 + t * t) if math.isfinite(t) else -1.0
    phase = math.degrees(math.acos(c)) if abs(c) < 1.0 else math.inf
    return gain_db, phase


def _disk_margin(S: NDArray[np.complex128]) -> tuple[float, float, float]:
    """Symmetric (skew 0) disk margin of a SISO loop from its sensitivity ``S`` on a frequency
    grid: ``alpha = 1/max_w |S(jw) - 1/2|`` and its :func:`disk_figures`. One vectorised
    frequency response instead of ``disk_margins``' per-frequency loop; equal to it within
    rounding (tests/unit/test_linear_fast_paths.py)."""
    peak = float(np.max(np.abs(np.asarray(S, dtype=complex) - 0.5)))
    alpha = 1.0 / peak if peak > 0 else math.inf
    return (alpha, *disk_figures(alpha))


def loop_margins(L: Any, *, omega: Sequence[float] | None = None) -> LoopMargins:
    """Margins of the SISO loop ``L`` (python-control LTI, continuous or discrete; negative
    feedback). ``omega`` [rad/s]: frequency grid for the disk margin, ``ms``, ``mt`` and the
    bandwidth (None: automatic, up to Nyquist for a discrete loop)."""
    _check_siso(L)
    dt = _dt_of(L)
    reasons: list[tuple[str, str]] = []
    Lt = L if _siso_tf(L) else trim_tf(L)
    cpoles = _closed_loop_poles(Lt)
    stable = bool(np.all(np.abs(cpoles) < 1.0)) if dt else bool(np.all(cpoles.real < 0))
    gm, pm, _sm, wpc, wgc, _wms = control.stability_margins(Lt)
    gm_db = None
    if not np.isfinite(gm) or gm <= 0:
        reasons.append(("gain_margin_db", "no phase crossover (phase never reaches -180 deg)"))
        wpc_v = None
    else:
        gm_db = 20 * math.log10(gm)
        wpc_v = float(wpc)
    pm_v = wgc_v = dm_s = None
    if not np.isfinite(pm) or not np.isfinite(wgc) or wgc <= 0:
        reasons.append(("phase_margin_deg", "no gain crossover (|L| never equals 1)"))
        reasons.append(("delay_margin_s", "no gain crossover"))
    else:
        pm_v, wgc_v = float(pm), float(wgc)
        if pm_v <= 0 or not stable:
            reasons.append(("delay_margin_s", "closed loop unstable"))
        else:
            dm_s = math.radians(pm_v) / wgc_v
    w = _grid(Lt, omega)
    Lw = _freq(Lt, w)
    S = 1.0 / (1.0 + Lw)
    T = Lw / (1.0 + Lw)
    ms = float(np.max(np.abs(S)))
    mt = float(np.max(np.abs(T)))
    dm = ddb = ddeg = None
    if stable:
        dm, ddb, ddeg = _disk_margin(S)
    else:
        reasons.append(("disk_margin", "closed loop unstable"))
    T0 = abs(T[0])
    bw = None
    below = np.flatnonzero(np.abs(T) < T0 / math.sqrt(2))
    if T0 > 0 and below.size:
        k = int(below[0])
        if k > 0:
            # log-linear interpolation between the bracketing grid points
            a, b = abs(T[k - 1]), abs(T[k])
            thr = T0 / math.sqrt(2)
            f = (a - thr) / (a - b) if a != b else 0.0
            bw = float(10 ** (math.log10(w[k - 1]) + f * (math.log10(w[k]) - math.log10(w[k - 1]))))
        else:
            bw = float(w[0])
    else:
        reasons.append(("bandwidth_rad_s", "|T| does not fall 3 dB below |T(0)| on the grid"))
    pl = poles_of(cpoles, dt)
    nat = tuple(sorted({round(p.frequency_hz, 12) for p in pl if p.imag > 1e-9}))
    return LoopMargins(
        gain_margin_db=gm_db,
        phase_margin_deg=pm_v,
        delay_margin_s=dm_s,
        disk_margin=dm,
        disk_margin_db=ddb,
        disk_margin_deg=ddeg,
        ms=ms,
        mt=mt,
        crossover_rad_s=wgc_v,
        phase_crossover_rad_s=wpc_v,
        bandwidth_rad_s=bw,
        closed_loop_poles=pl,
        natural_frequencies_hz=nat,
        stable=stable,
        dt=dt,
        reasons=tuple(reasons),
    )


def clutch_loop_margins(
    op: OperatingPoint, controller: Controller, *, mu_slope: float | None = None
) -> LoopMargins:
    """Margins of ``controller``'s clutch loop at ``op``; with the clutch not slipping the loop
    is open and every margin is None with the reason."""
    require_op(op, "clutch_loop_margins")
    require_controller(controller, "clutch_loop_margins")
    if op.clutch_mode not in ("slip+", "slip-"):
        return LoopMargins.undefined(
            f"clutch {op.clutch_mode}: x_c does not act on the engine speed, the clutch loop is "
            "open (see linear.locked_analysis for the shuffle modes and the breakaway margin)"
        )
    return loop_margins(clutch_loop(op, controller, mu_slope=mu_slope).L)


# ---------------------------------------------------------------------------------------------
# root loci
# ---------------------------------------------------------------------------------------------

PARAMETERS: dict[str, str] = {
    "k_r": "m s/rad",
    "pedal_slope": "-",
    "J1": "kg m^2",
    "omega_a": "rad/s",
    "mu_slope": "s/rad",
}


@dataclass(frozen=True, slots=True)
class RootLocusPoint:
    """Poles [1/s] at one parameter value, the mode of the operating point and stability."""

    value: float
    poles: tuple[Pole, ...]
    modes: tuple[tuple[str, str], ...]
    max_real: float
    stable: bool


@dataclass(frozen=True)
class RootLocus:
    """Closed-loop poles over a parameter grid (``parameter`` [``unit``]); each point re-linearised
    and tagged with its mode."""

    parameter: str
    unit: str
    points: tuple[RootLocusPoint, ...]

    def crossing(self) -> float | None:
        """First parameter value (linear interpolation of the largest real part) at which the
        stability changes along the grid, None if it does not."""
        pts = self.points
        for a, b in zip(pts, pts[1:], strict=False):
            if a.stable != b.stable:
                f = a.max_real / (a.max_real - b.max_real) if a.max_real != b.max_real else 0.0
                return a.value + f * (b.value - a.value)
        return None

    def to_dict(self) -> dict[str, Any]:
        return json_ready(
            {
                "parameter": self.parameter,
                "unit": self.unit,
                "crossing": self.crossing(),
                "points": [
                    {
                        "value": p.value,
                        "poles": [[q.real, q.imag] for q in p.poles],
                        "modes": dict(p.modes),
                        "max_real": p.max_real,
                        "stable": p.stable,
                    }
                    for p in self.points
                ],
            }
        )

    def plot(self, path: str | None = None) -> Any:
        """Poles in the complex plane, coloured by the parameter value, one marker per mode of the
        operating point (legend: the clutch's mode and the elements that differ); a matplotlib
        Figure (:func:`drivetrain_ctrl.reporting.figures.plot_root_locus`), saved to ``path`` if given."""
        from ..reporting.figures import plot_root_locus

        pts = [
            (
                p.value,
                [(q.real, q.imag) for q in p.poles],
                ", ".join(f"{e}={m}" for e, m in p.modes) or "-",
            )
            for p in self.points
        ]
        return plot_root_locus(pts, parameter=self.parameter, unit=self.unit, path=path)


def _scaled_pedal_map(params: DrivetrainParams, x_c: float, factor: float) -> Any:
    """``params`` with the clutch capacity k12 [N m] at the knots moved about its value at
    ``x_c`` [m] by ``factor`` in slope, clipped to [0, k12_max]; its value at full engagement is
    the new capacity scale ``k12_max``, the rest the new shape."""
    fr = clutch_friction(params)
    table = fr.capacity_table
    assert table is not None
    k0 = fr.capacity(float(x_c))
    y = np.clip(k0 + factor * (np.asarray(table.y) - k0), 0.0, params.clutch.k12_max)
    top = float(np.max(y))
    return params.replace(
        **{
            "clutch.k12_max": top,
            "clutch.pedal_map": {"x": list(table.x), "y": [float(v) / top for v in y]},
        }
    )


def _values(values: Any) -> list[float]:
    """``values`` of :func:`root_locus` as floats: a non-empty 1-D sequence of finite numbers."""
    msg = f"values = {values!r}: a non-empty 1-D sequence of finite numbers is needed"
    if isinstance(values, np.ndarray):
        if values.dtype.kind not in "iuf":
            raise ValueError(msg)
        items: list[Any] = list(values.reshape(-1)) if values.ndim == 1 else []
    elif isinstance(values, str | bytes) or not hasattr(values, "__iter__"):
        raise ValueError(msg)
    else:
        items = list(values)
        if not all(is_finite_real(v) for v in items):
            raise ValueError(msg)
    vals = [float(v) for v in items]
    if not vals or not all(math.isfinite(v) for v in vals):
        raise ValueError(msg)
    return vals


def root_locus(
    op: OperatingPoint,
    controller: Controller | None,
    *,
    parameter: str,
    values: Sequence[float],
    mu_slope: float | None = None,
) -> RootLocus:
    """Closed-loop poles of the slip mode (or the plant's poles if the clutch does not slip)
    over ``values`` of ``parameter``:

    * ``k_r`` [m s/rad]: the gain of a static (law 6) controller;
    * ``pedal_slope`` [-]: factor on the pedal-map slope around ``x_c`` (k13(x_c) kept; the map is
      rebuilt and the point re-made, :func:`~drivetrain_ctrl.linear.operating_point.rebuild_operating_point`);
    * ``J1`` [kg m^2]: engine inertia (parameters replaced, point re-made);
    * ``omega_a`` [rad/s]: actuator natural frequency;
    * ``mu_slope`` [s/rad]: clutch friction slope (the linearisation override).
    """
    require_op(op, "root_locus")
    require_controller(controller, "root_locus", optional=True)
    if parameter not in PARAMETERS:
        raise ValueError(f"parameter = {parameter!r}: choose from {sorted(PARAMETERS)}")
    vals = _values(values)
    # k_r and omega_a change the controller only: the plant is linearised once
    plant_fixed = parameter in ("k_r", "omega_a")
    sys_slip: control.StateSpace | None = None
    open_poles: NDArray[Any] | None = None
    pts = []
    for v in vals:
        o, c, ms = op, controller, mu_slope
        if parameter == "k_r":
            if c is None or c.lti.nstates != 0 or c.is_discrete:
                raise ValueError("parameter 'k_r': needs a static continuous controller (law 6)")
            c = dataclasses.replace(c, lti=control.ss([], [], [], [[v]]))
        elif parameter == "omega_a":
            if c is None or c.actuator is None:
                raise ValueError("parameter 'omega_a': needs a controller with an actuator")
            c = dataclasses.replace(c, actuator=Actuator(v, c.actuator.delta))
        elif parameter == "mu_slope":
            ms = v
        else:
            if op.drivetrain is None or op.recipe is None:
                raise ValueError(f"parameter {parameter!r}: op must come from a constructor")
            p = op.drivetrain.params
            if parameter == "J1":
                p2 = p.replace(**{"engine.J1": v})
            else:
                xc = op.input("pedal")
                p2 = _scaled_pedal_map(p, xc, v)
            o = rebuild_operating_point(op, p2)
        if o.clutch_mode in ("slip+", "slip-"):
            sys = sys_slip if sys_slip is not None else linearise(o, inputs=("x_c",), mu_slope=ms)
            if plant_fixed:
                sys_slip = sys
            poles = _slip_mode_poles_of(sys, o, c)
        else:
            poles = open_poles if open_poles is not None else np.linalg.eigvals(linearise(o).A)
            if plant_fixed:
                open_poles = poles
        mr = float(np.max(np.asarray(poles).real)) if len(poles) else -math.inf
        pts.append(RootLocusPoint(v, poles_of(poles), o.mode_names, mr, bool(mr < 0)))
    return RootLocus(parameter, PARAMETERS[parameter], tuple(pts))


# ---------------------------------------------------------------------------------------------
# Nyquist
# ---------------------------------------------------------------------------------------------


#: an open- or closed-loop pole lies on the stability boundary (an integrator, an undamped mode) when
#: ``|Re p| <= NYQUIST_BOUNDARY_TOL * max(1, |p|)`` [1/s], a sampled loop's when
#: ``||z| - 1| <= NYQUIST_BOUNDARY_TOL``: wide enough for the round-off of a transfer function's
#: poles (a sampled PI's integrator at ``z = 1`` among plant poles near 1 comes out ~1e-6 off)
NYQUIST_BOUNDARY_TOL: float = 1e-5


@dataclass(frozen=True)
class NyquistData:
    """Nyquist curve of a loop ``L`` and its count, one convention for continuous and sampled
    loops (:func:`nyquist_data`).

    ``omega`` [rad/s] (0 first), ``real``, ``imag``: ``L`` along the counting contour for
    ``omega >= 0`` (the mirror image is the other half); ``encirclements`` N: clockwise
    encirclements of -1; ``open_loop_unstable_poles`` P and ``closed_loop_unstable_poles``
    ``Z = N + P``; ``boundary_poles``: open-loop poles on the stability boundary (integrators,
    undamped modes), which the contour passes on the unstable side, so that they count as stable
    (python-control's ``indent_direction="right"``); ``contour_shift`` [1/s]: the contour's
    distance from the boundary (``s = shift + j omega``; sampled: ``z = exp((shift + j omega) dt)``),
    smaller than the distance of any other open- or closed-loop pole; ``closed_loop_unstable_eig``:
    Z counted from the closed-loop poles with the same convention (equal to Z unless the curve was
    resolved too coarsely); ``dt`` [s] of a sampled loop (None: continuous)."""

    omega: tuple[float, ...]
    real: tuple[float, ...]
    imag: tuple[float, ...]
    encirclements: int
    open_loop_unstable_poles: int
    closed_loop_unstable_poles: int
    boundary_poles: int = 0
    contour_shift: float = 0.0
    closed_loop_unstable_eig: int | None = None
    dt: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return json_ready(dataclasses.asdict(self))

    def plot(self, path: str | None = None, *, title: str | None = None) -> Any:
        """The curve (and its mirror image) with the critical point -1: the whole curve with a
        compressed radius beside a linear window around -1; a matplotlib Figure
        (:func:`drivetrain_ctrl.reporting.figures.plot_nyquist`), saved to ``path`` if given."""
        from ..reporting.figures import plot_nyquist

        return plot_nyquist(
            self.real,
            self.imag,
            omega=self.omega,
            encirclements=self.encirclements,
            open_loop_unstable_poles=self.open_loop_unstable_poles,
            closed_loop_unstable_poles=self.closed_loop_unstable_poles,
            boundary_poles=self.boundary_poles,
            dt=self.dt,
            title=title,
            path=path,
        )


def _boundary_distance(
    p: NDArray[Any], dt: float | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Signed distance of each pole from the stability boundary [1/s] (``Re p``; a sampled loop's
    ``ln|z|/dt``, ``z = 0`` at ``-inf``) and its boundary tolerance [1/s]
    (:data:`NYQUIST_BOUNDARY_TOL`)."""
    p = np.asarray(p, dtype=complex).reshape(-1)
    if not dt:
        return p.real.astype(float), NYQUIST_BOUNDARY_TOL * np.maximum(1.0, np.abs(p))
    r = np.abs(p)
    d = np.full(p.shape, -np.inf)
    nz = r > 0
    d[nz] = np.log(r[nz]) / dt
    return d, np.full(p.shape, NYQUIST_BOUNDARY_TOL / dt)


def _contour_shift(
    ol: tuple[NDArray[np.float64], NDArray[np.float64]],
    cl: tuple[NDArray[np.float64], NDArray[np.float64]],
) -> tuple[float, int]:
    """The counting contour's distance from the boundary [1/s] and the number of open-loop poles
    on the boundary: above the tolerance of every pole on the boundary, below the distance of
    every other pole (the geometric mean of the two)."""
    d = np.concatenate([ol[0], cl[0]])
    tol = np.concatenate([ol[1], cl[1]])
    on = np.abs(d) <= tol
    lo = float(np.max(tol[on])) if np.any(on) else float(np.min(tol, initial=NYQUIST_BOUNDARY_TOL))
    off = np.abs(d[~on & np.isfinite(d)])
    hi = float(np.min(off)) if off.size else 1e3 * lo
    shift = math.sqrt(lo * hi) if hi > lo else 0.5 * (lo + hi)
    return shift, int(np.sum(np.abs(ol[0]) <= ol[1]))


def _nyquist_contour(
    Lt: Any, w0: F64, shift: float, dt: float | None
) -> tuple[F64, NDArray[np.complex128]]:
    """``L`` along ``s = shift + j omega`` (sampled: ``z = exp(s dt)``) for ``omega`` from 0 over
    ``w0`` to infinity (the Nyquist frequency), refined until the angle of ``1 + L`` moves less
    than 30 degrees between neighbours (or the step is below 1e-9 relative)."""
    top = math.pi / dt if dt else None

    def ev(w: F64) -> NDArray[np.complex128]:
        s = shift + 1j * w
        x = np.exp(s * dt) if dt else s
        return np.asarray(Lt(x), dtype=complex).reshape(-1)

    lo = min(float(w0[0]), shift) * 1e-3
    ws = [0.0, *np.geomspace(lo, float(w0[0]), 40)[:-1], *w0]
    if top is not None:
        ws = [w for w in ws if w < top] + [top]
    else:
        ws.append(float(w0[-1]) * 1e3)
    w = np.unique(np.asarray(ws, dtype=float))
    h = ev(w)
    for _ in range(40):
        d = np.abs(np.angle((1 + h[1:]) / (1 + h[:-1])))
        bad = np.flatnonzero((d > math.pi / 6) & (np.diff(w) > 1e-9 * np.maximum(w[1:], 1e-300)))
        if not bad.size:
            break
        mids = 0.5 * (w[bad] + w[bad + 1])
        w = np.concatenate([w, mids])
        h = np.concatenate([h, ev(mids)])
        order = np.argsort(w, kind="stable")
        w, h = w[order], h[order]
    return w, h


def nyquist_data(L: Any, *, omega: Sequence[float] | None = None) -> NyquistData:
    """Nyquist data of the SISO loop ``L`` (python-control LTI, continuous or discrete; the same
    checks as :func:`loop_margins`). ``omega`` [rad/s]: the frequencies the curve is drawn at
    (None: automatic); the count refines them where the curve turns fast.

    One convention for continuous and sampled loops: open-loop poles on the stability boundary
    (``Re p = 0``, for a sampled loop ``|z| = 1``, within :data:`NYQUIST_BOUNDARY_TOL`: an
    integrator at ``s = 0`` or ``z = 1`` is one) are passed on the unstable side and count as
    stable, like python-control's default ``indent_direction="right"`` for continuous loops. The
    contour runs at ``s = shift + j omega`` (sampled: ``z = exp((shift + j omega) dt)``, a circle of
    radius slightly above 1), so the indentation is the image of its piece near ``omega = 0``; N
    counts the clockwise turns of ``1 + L`` about 0 along it (``omega`` from 0 to infinity or
    the Nyquist frequency, and the mirror image), P the open-loop poles beyond the contour and
    ``Z = N + P`` the closed-loop poles beyond it. ``closed_loop_unstable_eig`` counts them from
    the closed-loop poles (a check of the count)."""
    _check_siso(L)
    Lt = trim_tf(L)
    dt = _dt_of(Lt)
    w = _grid(Lt, omega)
    ol = _boundary_distance(Lt.poles(), dt)
    cl = _boundary_distance(control.feedback(Lt, 1).poles(), dt)
    shift, n_on = _contour_shift(ol, cl)
    wc, hc = _nyquist_contour(Lt, w, shift, dt)
    turns = np.sum(np.angle((1 + hc[1:]) / (1 + hc[:-1])))
    N = int(round(-float(turns) / math.pi))
    P = int(np.sum(ol[0] > shift))
    Z_eig = int(np.sum(cl[0] > shift))
    return NyquistData(
        omega=tuple(float(v) for v in wc),
        real=tuple(float(v) for v in hc.real),
        imag=tuple(float(v) for v in hc.imag),
        encirclements=N,
        open_loop_unstable_poles=P,
        closed_loop_unstable_poles=N + P,
        boundary_poles=n_on,
        contour_shift=shift,
        closed_loop_unstable_eig=Z_eig,
        dt=dt,
    )
