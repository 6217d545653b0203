"""Operating points, linearisation and the clutch control loop (small-signal analysis).

The plant is a switching system; a linear model only exists *inside one mode*. Everything here
therefore works on an :class:`OperatingPoint` = (state, inputs, mode) and uses the model's
analytic Jacobian of that mode (:meth:`~drivetrain_ctrl.plant.model.Model.jacobian`); nothing is
finite-differenced across a switch.

Operating points
----------------
* :func:`operating_point_from_result`: an instant of a simulated trajectory (the mode held there);
* :func:`slip_operating_point`: clutch slipping at given engine / driven speeds. A slip mode is not
  an equilibrium: its certificate reports the drift ``dx/dt`` and the time to lock
  ``|slip| / |d slip/dt|`` (None when the slip grows);
* :func:`locked_trim`: clutch locked, steady state at a vehicle speed and road slope, the throttle
  being the trim unknown (``scipy.optimize.root``); the certificate reports the torque margin to
  breakaway of every stuck element (static capacity - ``|stuck torque|``).

Linearisation (:func:`linearise`)
---------------------------------
``x' = A x + B u`` with ``A``, ``B`` the analytic Jacobian of the mode. In a mode with stuck
elements the speeds obey ``G omega = 0``: the full-coordinate Jacobian then has one spurious zero
eigenvalue per constraint (a direction the mode never visits), and the twist of a spring whose
coupling is held by a stuck friction is frozen (another zero eigenvalue). :func:`linearise`
therefore reduces to the mode's independent coordinates: ``x = T z``, ``z = S x`` with the speed
block of ``T`` a basis of the speeds the mode allows (``Model.speed_basis``) re-expressed in a
subset of the physical speeds (the engine and the vehicle are kept preferentially, so a locked
clutch keeps ``omega_engine`` and drops the driven side), frozen twists dropped, and the position
states (energy bookkeeping of the slope load; nothing depends on them) dropped unless
``keep_positions``. Because ``A`` maps the admissible subspace into itself, ``A_z = S A T`` and
``B_z = S B`` are exact. Remaining zero eigenvalues are physical (e.g. a free rigid-body mode).

Inputs are ``throttle`` [-] and ``x_c`` [m] (the model input ``pedal``); outputs the body speeds
(model names, rad/s or m/s), ``tau_13`` (clutch torque [N m], kinetic in slip, the constraint
torque when stuck), ``C_1`` (engine output torque ``C_G - b1(omega_1)`` [N m]) and ``a_vehicle``
(vehicle acceleration [m/s^2]).

The clutch loop in slip (paper, Sec. IV)
----------------------------------------
In slip ``tau_13 = k13(x_c) mu(|w|) sgn(w)``, ``w = omega_1 - omega_2``. Linearised,
``d tau_13 = k13'(x_c) mu s dx_c + c dw`` with ``s = sgn(w)`` and the mu slope
``c = k13(x_c) mu'(|w|)`` [N m s/rad] (the same on both branches since ``d|w|/dw = s``). The engine
side is ``J_1 omega_1' = C_1(omega_1, theta_f) - tau_13`` with ``C_1 = C_G - b_1 omega_1 -
c_1 sgn(omega_1)``; its linearisation is ``J_1 d omega_1' = -b_1' d omega_1 + dC_G/dtheta_f
d theta_f - d tau_13`` with the engine-side effective damping::

    b_1' = -dC_1/domega_1 = b_1 - theta_f dC_max/domega_1

(``b_1`` viscous; the Coulomb part is constant in a turning mode; the second term only with the
full-load map ``C_G = theta_f C_max(omega_1)``, zero for the paper's ``C_G = K theta_f``). With
constant mu (``c = 0``) the engine decouples from the driveline and law (6),
``x_r = x_r0 + k_r (omega_r - omega_1) s``, closes the loop (negative-feedback convention)::

    L(s) = k_r |k13'(x_c)| mu(|w|) A(s) / (J_1 s + b_1'),   A(s) = w_a^2/(s^2 + 2 d_a w_a s + w_a^2)

the same on both branches because ``s^2 = 1`` (k13' < 0: the pedal map falls with x_c).

With ``c != 0`` the driveline couples in. Let ``Y_2(s)`` be the driven side's admittance
(``d omega_2 / d tau_13``) and ``L`` the loop above. Eliminating ``omega_1`` and ``x_c`` the
characteristic equation of the closed loop is ``1 + c H(s) = 0`` with
``H = (1/(J_1 s + b_1') + Y_2(s)) / (1 + L(s))`` (slip-speed admittance seen by the friction
slope). See :func:`judder_threshold` for the closed form of the critical slope.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from .. import kernels as K
from ..core.serialize import json_ready
from ..core.units import GRAVITY, kmh_to_m_s
from ..core.validate import finite_float
from ..plant.drivetrain import Drivetrain
from ..plant.model import Mode, Model
from ..plant.params import DrivetrainParams

__all__ = [
    "Certificate",
    "StuckMargin",
    "OperatingPoint",
    "operating_point_from_result",
    "slip_point_after_start",
    "SLIP_DELAY_S",
    "slip_operating_point",
    "locked_trim",
    "rebuild_operating_point",
]

F64 = NDArray[np.float64]

#: model input names -> names of the linear model's inputs
INPUT_ALIASES: dict[str, str] = {"throttle": "throttle", "pedal": "x_c", "brake": "brake"}


def _frozen(a: F64) -> F64:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


# ---------------------------------------------------------------------------------------------
# operating points
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class StuckMargin:
    """A stuck friction element: static capacity [N m or N], carried torque [N m or N] and the
    margin to breakaway ``capacity - |torque|`` (negative: the mode cannot hold)."""

    element: str
    capacity: float
    torque: float
    margin: float


@dataclass(frozen=True, slots=True)
class Certificate:
    """Why (and how far) an operating point is valid.

    ``kind``: ``"equilibrium"`` (a trim: the drift is round-off), ``"slip"`` (a slip instant: not
    an equilibrium) or ``"trajectory"`` (an instant of a simulation).
    ``drift``: ``(state name, dx/dt)`` pairs (units of the state per second);
    ``drift_norm``: max ``|dx/dt|`` over the speeds [rad/s^2 or m/s^2];
    ``slip_speed`` [rad/s] and ``slip_accel`` [rad/s^2] of the clutch when it slips;
    ``time_to_lock_s``: ``|slip| / |d slip/dt|`` when the slip closes, None if it grows;
    ``stuck_margins``: torque margin to breakaway of every stuck element;
    ``min_guard``: smallest guard value (>= 0 while the mode holds);
    ``valid``: every guard >= 0 (and, for a trim, the residual small); ``notes``: reasons.
    """

    kind: str
    drift: tuple[tuple[str, float], ...]
    drift_norm: float
    slip_speed: float | None
    slip_accel: float | None
    time_to_lock_s: float | None
    stuck_margins: tuple[StuckMargin, ...]
    min_guard: float
    valid: bool
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (floats rounded by :func:`drivetrain_ctrl.core.serialize.json_ready`)."""
        return json_ready(
            {
                "kind": self.kind,
                "drift": dict(self.drift),
                "drift_norm": self.drift_norm,
                "slip_speed_rad_s": self.slip_speed,
                "slip_accel_rad_s2": self.slip_accel,
                "time_to_lock_s": self.time_to_lock_s,
                "stuck_margins": [
                    {
                        "element": s.element,
                        "capacity": s.capacity,
                        "torque": s.torque,
                        "margin": s.margin,
                    }
                    for s in self.stuck_margins
                ],
                "min_guard": self.min_guard,
                "valid": self.valid,
                "notes": list(self.notes),
            }
        )


@dataclass(frozen=True)
class OperatingPoint:
    """A point of the switching plant: state ``x``, inputs ``u`` (model order), ``mode``.

    ``kind`` ``"full"`` / ``"reduced"``; ``mode_names`` ``(element, mode name)`` pairs;
    ``certificate`` its validity; ``t`` [s] the time when taken from a trajectory; ``recipe`` the
    constructor and its keyword arguments (so it can be rebuilt for other parameters,
    :func:`rebuild_operating_point`), None when taken from a trajectory. ``x`` and ``u`` are
    read-only arrays.
    """

    kind: str
    x: F64
    u: F64
    mode: Mode
    mode_names: tuple[tuple[str, str], ...]
    certificate: Certificate
    model: Model = field(repr=False, compare=False)
    drivetrain: Drivetrain | None = field(default=None, repr=False, compare=False)
    t: float | None = None
    recipe: tuple[str, tuple[tuple[str, Any], ...]] | None = field(default=None, compare=False)

    def mode_dict(self) -> dict[str, str]:
        """``{element: mode name}``."""
        return dict(self.mode_names)

    @property
    def clutch_mode(self) -> str:
        """Mode name of the clutch (``stuck``, ``slip+``, ``slip-``, ``open``)."""
        return self.mode_dict()["clutch"]

    def state(self, name: str) -> float:
        """Value of state ``name`` (SI)."""
        return float(self.x[self.model.state_index(name)])

    def input(self, name: str) -> float:
        """Value of model input ``name`` (``throttle``, ``pedal``, ``brake``; SI)."""
        return float(self.u[self.model.input_names.index(name)])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (states, inputs, modes, certificate)."""
        m = self.model
        return json_ready(
            {
                "kind": self.kind,
                "t_s": self.t,
                "state": dict(zip(m.state_names, self.x.tolist(), strict=True)),
                "inputs": dict(zip(m.input_names, self.u.tolist(), strict=True)),
                "modes": dict(self.mode_names),
                "certificate": self.certificate.to_dict(),
            }
        )


def _kind_of(model: Model, drivetrain: Drivetrain | None) -> str:
    if drivetrain is not None:
        return drivetrain.kind
    name = model.chain.name
    if name.startswith("full"):
        return "full"
    if name.startswith("reduced"):
        return "reduced"
    return "chain"


def _friction(model: Model, name: str) -> int:
    return model.friction_index(name)


def _mu_ratio(model: Model, f: int, x: F64, mode: Mode) -> tuple[float, float]:
    """(mu(|w|)/mu(0), its slope d mu/d|w| [s/rad]) of friction ``f`` in ``mode``."""
    D = model.data
    k = int(D.f_mu[f])
    if k < 0:
        return 1.0, 0.0
    w = abs(_rel_speed(model, f, x))
    r = mode.reg[k]
    return float(D.t_s[k, r] * w + D.t_o[k, r]), float(D.t_s[k, r])


def _rel_speed(model: Model, f: int, x: F64) -> float:
    D = model.data
    i = int(D.f_idx[f])
    if int(D.f_kind[f]) == 0:
        return float(x[i] - D.ratio[i] * x[i + 1])
    return float(x[i])


def _certificate(
    model: Model, x: F64, u: F64, mode: Mode, kind: str, notes: Sequence[str] = ()
) -> Certificate:
    xdot = model.rhs(x, u, mode)
    n = model.n_bodies
    g = model.guards(x, u, mode)
    stuck = model.stuck_torques(x, u, mode)
    margins = []
    for f, fi in enumerate(model.frictions):
        if mode.fm[f] == K.STUCK:
            cap = float(model.data.f_static[f]) * model.capacity(f, u, mode)
            lam = stuck[fi.name]
            margins.append(StuckMargin(fi.name, cap, lam, cap - abs(lam)))
    slip = slip_acc = ttl = None
    notes_l = list(notes)
    try:
        fc = _friction(model, "clutch")
    except KeyError:
        fc = -1
    if fc >= 0 and mode.fm[fc] in (K.SLIP_POS, K.SLIP_NEG):
        slip = _rel_speed(model, fc, x)
        slip_acc = _rel_speed(model, fc, xdot)
        if slip * slip_acc < 0:
            ttl = abs(slip / slip_acc)
        else:
            notes_l.append("clutch slip is not closing (time to lock: None)")
    min_guard = float(np.min(g)) if g.size else math.inf
    valid = bool(min_guard >= 0.0)
    if not valid:
        bad = [nm for nm, v in zip(model.guard_names(), g, strict=True) if v < 0]
        notes_l.append(f"guards violated: {bad}")
    return Certificate(
        kind=kind,
        drift=tuple((nm, float(v)) for nm, v in zip(model.state_names, xdot, strict=True)),
        drift_norm=float(np.max(np.abs(xdot[:n]))),
        slip_speed=slip,
        slip_accel=slip_acc,
        time_to_lock_s=ttl,
        stuck_margins=tuple(margins),
        min_guard=min_guard,
        valid=valid,
        notes=tuple(notes_l),
    )


def _make_op(
    model: Model,
    x: F64,
    u: F64,
    mode: Mode,
    kind: str,
    *,
    drivetrain: Drivetrain | None,
    t: float | None = None,
    recipe: tuple[str, tuple[tuple[str, Any], ...]] | None = None,
    notes: Sequence[str] = (),
) -> OperatingPoint:
    cert = _certificate(model, x, u, mode, kind, notes)
    return OperatingPoint(
        kind=_kind_of(model, drivetrain),
        x=_frozen(x),
        u=_frozen(u),
        mode=mode,
        mode_names=tuple(model.mode_names(mode).items()),
        certificate=cert,
        model=model,
        drivetrain=drivetrain,
        t=t,
        recipe=recipe,
    )


def operating_point_from_result(
    result: Any, t: float, *, drivetrain: Drivetrain | None = None
) -> OperatingPoint:
    """The instant ``t`` [s] of a simulated trajectory (a ``SimulationResult``).

    On a sample interval ``[t_k, t_k+1)`` the simulator holds the mode of sample ``k``; the state
    and inputs are interpolated linearly inside the interval (exact at the samples). At an event
    (two samples at the same time) the mode after the event is taken. ``drivetrain`` (optional)
    is recorded in the result. Raises ValueError if ``t`` is outside the trajectory.
    """
    t = finite_float("t", t)
    if drivetrain is not None and (
        not isinstance(drivetrain, Drivetrain) or drivetrain.model.chain != result.model.chain
    ):
        got = (
            f"{drivetrain.kind}, gear {drivetrain.gear}"
            if isinstance(drivetrain, Drivetrain)
            else repr(drivetrain)
        )
        raise ValueError(
            f"drivetrain = ({got}): not the drivetrain of the result, whose model is "
            f"{result.model.chain.name!r}"
        )
    T = np.asarray(result.t)
    if not T[0] <= t <= T[-1]:
        raise ValueError(
            f"t = {t!r} s: outside the trajectory [{float(T[0])!r}, {float(T[-1])!r}] s"
        )
    k = int(np.searchsorted(T, t, side="right") - 1)
    k = min(k, T.shape[0] - 1)
    x = np.array(result.x[k], dtype=float)
    u = np.array(result.u[k], dtype=float)
    if t > T[k] and k + 1 < T.shape[0] and T[k + 1] > T[k]:
        a = (t - T[k]) / (T[k + 1] - T[k])
        x = (1 - a) * x + a * np.asarray(result.x[k + 1])
        u = (1 - a) * u + a * np.asarray(result.u[k + 1])
    mode = Mode(tuple(int(v) for v in result.fm[k]), tuple(int(v) for v in result.reg[k]))
    return _make_op(result.model, x, u, mode, "trajectory", drivetrain=drivetrain, t=t)


#: the slip operating point of a closed-loop run is taken this long after the controller start [s]
SLIP_DELAY_S: float = 0.3


def slip_point_after_start(
    result: Any, drivetrain: Drivetrain, start: float, *, delay: float = SLIP_DELAY_S
) -> OperatingPoint:
    """The slip operating point of a run: the trajectory at ``start + delay`` [s] (``start``: the
    controller start; the end of the run if that is later), or, if the clutch does not slip
    there, the first sample after ``start`` at which it does. The point the controller report
    and the studies' linear figures analyse the clutch loop at. ValueError if the clutch never
    slips after ``start``."""
    T = np.asarray(result.t)
    t = min(start + delay, float(T[-1]))
    op = operating_point_from_result(result, t, drivetrain=drivetrain)
    if op.clutch_mode in ("slip+", "slip-"):
        return op
    # the first sample after the start at which the clutch slips (the mode held from a sample on
    # is that of the last sample at its time, as operating_point_from_result takes it)
    fc = _friction(result.model, "clutch")
    fm = np.asarray(result.fm)[:, fc]
    last = np.searchsorted(T, T, side="right") - 1
    slips = np.isin(fm[last], (K.SLIP_POS, K.SLIP_NEG))
    for k in np.flatnonzero((T > start) & slips):
        op = operating_point_from_result(result, float(T[k]), drivetrain=drivetrain)
        if op.clutch_mode in ("slip+", "slip-"):
            return op
    raise ValueError("scenario: the clutch never slips after the controller start; no slip point")


def _driven_state(dt: Drivetrain) -> str:
    return "omega_disc" if dt.kind == "full" else "omega_primary"


def _check_fraction(name: str, v: float) -> float:
    v = finite_float(name, v)
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"{name} = {v!r}: must lie in [0, 1]")
    return v


def _check_brake(v: object, dt: Drivetrain) -> float:
    br = finite_float("brake", v)
    hi = dt.params.brake.capacity_max
    if not 0.0 <= br <= hi:
        raise ValueError(f"brake = {v!r} [N m]: must lie in [0, brake.capacity_max = {hi!r}]")
    return br


def _pedal_knots(dt: Drivetrain) -> tuple[float, float]:
    """First (fully engaged) and last knot x_c [m] of the model's clutch capacity table."""
    table = dt.model.friction("clutch").capacity_table
    assert table is not None
    return float(table.x[0]), float(table.x[-1])


def _check_pedal(dt: Drivetrain, v: object) -> float:
    """``x_c`` [m] inside the pedal map's knots (the map is clamped outside them)."""
    xc = finite_float("x_c", v)
    lo, hi = _pedal_knots(dt)
    if not lo <= xc <= hi:
        raise ValueError(f"x_c = {v!r} m: outside the pedal map's range [{lo!r}, {hi!r}] m")
    return xc


def slip_operating_point(
    drivetrain: Drivetrain,
    *,
    omega_engine: float,
    omega_driven: float,
    x_c: float,
    throttle: float,
    brake: float = 0.0,
    twist_torque: float | None = None,
) -> OperatingPoint:
    """The clutch slipping: engine at ``omega_engine`` [rad/s], the clutch's driven side (disc in
    the full model, primary shaft in the reduced one) at ``omega_driven`` [rad/s], the driveline
    turning with it (vehicle at ``omega_driven R_p / tau_t`` [m/s]), pedal ``x_c`` [m], throttle
    ``throttle`` [-] (engine lag settled at it), brake capacity ``brake`` [N m].

    ``twist_torque`` [N m, primary frame] preloads the driveline springs; None (default): the
    quasi-static torque for which the driven shaft and the vehicle accelerate together (no shuffle
    at the start). A slip mode is not an equilibrium: the certificate reports the drift and the
    time to lock. Raises ValueError if the slip speed is zero or the clutch carries no torque, if
    ``x_c`` is outside the pedal map's knots or ``brake`` < 0.
    """
    if not isinstance(drivetrain, Drivetrain):
        raise TypeError(f"slip_operating_point: drivetrain = {drivetrain!r}: must be a Drivetrain")
    we = finite_float("omega_engine", omega_engine)
    if we < 0.0:
        raise ValueError(f"omega_engine = {omega_engine!r} rad/s: must be >= 0")
    wd = finite_float("omega_driven", omega_driven)
    xc = _check_pedal(drivetrain, x_c)
    th = _check_fraction("throttle", throttle)
    br = _check_brake(brake, drivetrain)
    if we == wd:
        raise ValueError(
            f"omega_engine = omega_driven = {we!r} rad/s: no slip (use locked_trim for a locked "
            "clutch)"
        )
    m = drivetrain.model
    u = m.inputs(throttle=th, pedal=xc, brake=br)
    R = drivetrain.params.driveline.R_p
    v = wd * R / drivetrain.tau_t

    def state(T: float) -> F64:
        return drivetrain.rigid_state(omega_engine=we, v_vehicle=v, throttle=th, twist_torque=T)

    def mode_of(x: F64) -> Mode:
        mode, _ = m.decide(x, u)
        return mode

    if twist_torque is None:
        iv = m.state_index("v_vehicle")
        ip = m.state_index(_driven_state(drivetrain))
        ratio = drivetrain.tau_t / R

        def mismatch(T: float) -> float:
            x = state(T)
            xd = m.rhs(x, u, mode_of(x))
            return float(xd[ip] - ratio * xd[iv])

        cap = abs(m.capacity("clutch", u, mode_of(state(0.0))))
        hi = 2.0 * cap + 1000.0
        try:
            T0 = float(scipy.optimize.brentq(mismatch, -hi, hi, xtol=1e-10))
        except ValueError:
            T0 = 0.0
    else:
        T0 = finite_float("twist_torque", twist_torque)
    x = state(T0)
    mode, x = m.decide(x, u)
    fc = _friction(m, "clutch")
    if mode.fm[fc] not in (K.SLIP_POS, K.SLIP_NEG):
        raise ValueError(
            f"x_c = {xc!r} m: the clutch is {m.mode_names(mode)['clutch']!r} (capacity "
            f"{m.capacity(fc, u, mode):.6g} N m), not slipping"
        )
    recipe = (
        "slip",
        (
            ("kind", drivetrain.kind),
            ("gear", drivetrain.gear),
            ("slope", drivetrain.slope),
            ("omega_engine", we),
            ("omega_driven", wd),
            ("x_c", xc),
            ("throttle", th),
            ("brake", br),
            ("twist_torque", twist_torque),
        ),
    )
    return _make_op(m, x, u, mode, "slip", drivetrain=drivetrain, recipe=recipe)


def locked_trim(
    drivetrain: Drivetrain,
    *,
    vehicle_speed_kmh: float,
    slope: float | None = None,
    x_c: float | None = None,
    brake: float = 0.0,
) -> OperatingPoint:
    """Locked-clutch steady state at ``vehicle_speed_kmh`` [km/h] on a road of ``slope`` [rad]
    (None: the drivetrain's slope), pedal ``x_c`` [m] (None: fully engaged, the first knot of the
    pedal map), brake capacity ``brake`` [N m].

    Unknowns: the throttle theta (the trim unknown; the engine lag is settled at it) and the twist
    of every spring; equations: zero acceleration of every independent speed of the locked mode and
    zero friction torque in a stuck friction parallel to a spring (the spring then carries the
    torque: the largest margin). Solved with ``scipy.optimize.root`` (the table regions follow the
    iterate). Raises ValueError naming the speed and slope if the throttle needed is outside
    [0, 1], if the clutch cannot hold (its stuck torque exceeds its static capacity) or another
    friction element changes mode at the solution (e.g. the tyre slips); also if ``x_c`` is
    outside the pedal map's knots or ``brake`` < 0.
    """
    vk = finite_float("vehicle_speed_kmh", vehicle_speed_kmh)
    if vk <= 0:
        raise ValueError(
            f"vehicle_speed_kmh = {vehicle_speed_kmh!r}: must be > 0 (at rest the engine stalls "
            "with the clutch locked)"
        )
    dt = drivetrain
    if slope is not None:
        s = finite_float("slope", slope)
        if s != dt.slope:
            dt = Drivetrain(dt.params, kind=dt.kind, gear=dt.gear, slope=s)
    m = dt.model
    v = kmh_to_m_s(vk)
    xc = _pedal_knots(dt)[0] if x_c is None else _check_pedal(dt, x_c)
    br = _check_brake(brake, dt)
    w = dt.vehicle_speed_to_primary(v)
    x0 = dt.rigid_state(omega_engine=w, v_vehicle=v, throttle=0.3)
    u0 = m.inputs(throttle=0.3, pedal=xc, brake=br)
    mode0, x0 = m.decide(x0, u0)
    fm = np.array(mode0.fm, dtype=np.int64)
    names = m.mode_names(mode0)
    if names["clutch"] != "stuck":
        raise ValueError(f"x_c = {xc!r} m: the clutch is {names['clutch']!r}, not locked")
    D = m.data
    q_idx = [int(D.c_q[c]) for c in range(D.ratio.shape[0]) if D.c_q[c] >= 0]
    # stuck frictions in couplings that have a spring: their torque is set to zero
    par = [
        f
        for f in range(len(m.frictions))
        if fm[f] == K.STUCK and D.f_kind[f] == 0 and D.c_q[D.f_idx[f]] >= 0
    ]
    red = _reduction(m, mode0, keep_positions=False)
    rows = red.speed_rows
    il = m.state_index("lag_engine")
    iu = m.input_names.index("throttle")

    def build(p: F64, reg: tuple[int, ...] | None = None) -> tuple[F64, F64, Mode]:
        x = x0.copy()
        x[il] = p[0]
        for j, qi in enumerate(q_idx):
            x[qi] = p[1 + j]
        u = u0.copy()
        u[iu] = p[0]
        if reg is None:
            r = np.zeros(len(m.tables), dtype=np.int64)
            K.update_regions(D, x, u, r)
            reg = tuple(int(v) for v in r)
        return x, u, Mode(tuple(int(c) for c in fm), reg)

    def resid(p: F64, reg: tuple[int, ...] | None = None) -> F64:
        x, u, mode = build(p, reg)
        xd = m.rhs(x, u, mode)
        out = [xd[i] for i in rows]
        if par:
            st = m.stuck_torques(x, u, mode)
            out += [st[m.frictions[f].name] for f in par]
        return np.array(out)

    # initial guess: every spring at the torque of the road load (so a backlash is in contact)
    vp = dt.params.vehicle
    F_road = (
        float(vp.k_v(dt.slope))
        + vp.b_v * v
        + 0.5 * vp.rho_a * vp.C_x * vp.S * v * v
        + vp.M_v * GRAVITY * math.sin(dt.slope)
    )
    T_road = F_road * dt.params.driveline.R_p / dt.tau_t
    if not math.isfinite(T_road):
        raise ValueError(
            f"locked_trim: vehicle_speed_kmh = {vk!r}: no locked steady state there (the road "
            "load is not finite)"
        )
    p = np.zeros(1 + len(q_idx))
    p[0] = 0.3
    x_guess = dt.rigid_state(
        omega_engine=w, v_vehicle=v, throttle=0.3, twist_torque=T_road if T_road else 1e-3
    )
    for j, qi in enumerate(q_idx):
        p[1 + j] = x_guess[qi]
    r0 = resid(p)
    n_eq = len(r0)
    finite = bool(np.isfinite(r0).all())
    if names.get("tyre", "grip") != "grip" or not finite:
        raise ValueError(
            f"locked_trim: vehicle_speed_kmh = {vk!r}: no locked steady state there (the initial "
            f"decision gives {names}; residual finite: {finite})"
        )
    if n_eq != p.shape[0]:
        raise RuntimeError(  # pragma: no cover - structural
            f"locked_trim: {n_eq} equations for {p.shape[0]} unknowns in mode {names}"
        )
    where = f"vehicle_speed_kmh = {vk!r}, slope = {dt.slope!r} rad, gear = {dt.gear}"
    # active set: with the table regions held, the residual is affine in (theta, twists) and
    # root finding converges at once; then the regions are updated from the solution until they
    # no longer change
    seen: set[tuple[int, ...]] = set()
    for _ in range(50):
        reg = build(p)[2].reg
        if reg in seen:
            break
        seen.add(reg)
        sol = scipy.optimize.root(lambda q, reg=reg: resid(q, reg), p, method="hybr")
        p = sol.x
    res = float(np.max(np.abs(resid(p))))
    if not res <= 1e-8 * max(1.0, float(np.max(np.abs(x0[: m.n_bodies])))):  # NaN too
        raise RuntimeError(f"locked_trim did not converge ({where}): residual {res:.3g}")
    theta = float(p[0])
    if not 0.0 <= theta <= 1.0:
        raise ValueError(
            f"locked_trim: the throttle needed is {theta:.6g}, outside [0, 1] ({where})"
        )
    x, u, mode = build(p)
    mode, x = m.decide(x, u)
    notes = [f"trim residual {res:.3g}"]
    op = _make_op(
        m,
        x,
        u,
        mode,
        "equilibrium",
        drivetrain=dt,
        recipe=(
            "locked",
            (
                ("kind", dt.kind),
                ("gear", dt.gear),
                ("slope", dt.slope),
                ("vehicle_speed_kmh", vk),
                ("x_c", x_c),
                ("brake", br),
            ),
        ),
        notes=notes,
    )
    if op.clutch_mode != "stuck":
        raise ValueError(
            f"locked_trim: the clutch cannot hold ({where}): its mode is {op.clutch_mode!r}"
        )
    # the trim solved the friction modes of the initial decision; an element that changes mode
    # at the solution is fine if the point is still at rest (a friction parallel to a spring
    # found stuck), not if it moves it (e.g. the tyre spinning on a steep, slippery road)
    tol = 1e-8 * max(1.0, float(np.max(np.abs(x0[: m.n_bodies]))))
    if not op.certificate.drift_norm <= tol:
        changed = {
            fi.name: f"{names[fi.name]} -> {op.mode_dict()[fi.name]}"
            for f, fi in enumerate(m.frictions)
            if op.mode.fm[f] != mode0.fm[f]
        }
        raise ValueError(
            f"locked_trim: no locked steady state there ({where}): at the trim the speeds "
            f"accelerate (drift {op.certificate.drift_norm:.3g}); modes changed: {changed}"
        )
    return op


def rebuild_operating_point(op: OperatingPoint, params: DrivetrainParams) -> OperatingPoint:
    """The same operating point (same recipe: speeds, pedal, throttle or trim conditions) for
    another parameter set ``params`` (a :class:`~drivetrain_ctrl.plant.params.DrivetrainParams`, else
    TypeError). Raises ValueError for a point taken from a trajectory."""
    if not isinstance(params, DrivetrainParams):
        raise TypeError(f"params: a DrivetrainParams is needed, got {type(params).__name__}")
    if op.recipe is None:
        raise ValueError("op: taken from a trajectory (no recipe); it cannot be rebuilt")
    what, kw = op.recipe
    d = dict(kw)
    dt = Drivetrain(params, kind=d.pop("kind"), gear=d.pop("gear"), slope=d.pop("slope"))
    if what == "slip":
        return slip_operating_point(dt, **d)
    return locked_trim(dt, **d)


# ---------------------------------------------------------------------------------------------
# linearisation
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# the clutch loop in slip
# ---------------------------------------------------------------------------------------------


def require_op(op: object, what: str) -> None:
    """Raise ``TypeError`` unless ``op`` is an :class:`OperatingPoint` (``what``: the caller)."""
    if not isinstance(op, OperatingPoint):
        raise TypeError(
            f"{what}: op = {op!r}: must be an OperatingPoint (slip_operating_point, locked_trim "
            "or operating_point_from_result)"
        )


# ---------------------------------------------------------------------------------------------
# locked clutch
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# judder
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Reduction:
    T: F64  # (nx, nz)
    S: F64  # (nz, nx)
    names: tuple[str, ...]
    units: tuple[str, ...]
    speed_rows: tuple[int, ...]
    Nsel: F64  # (n, r) omega = Nsel omega[speed_rows]


#: reductions kept (least recently used dropped first): a study row linearises one mode of one
#: model several times (the loop gain, the judder search)
_REDUCTION_CACHE_SIZE = 16
_REDUCTIONS: dict[tuple[int, tuple[int, ...], bool], tuple[Model, _Reduction]] = {}


def _reduction(model: Model, mode: Mode, *, keep_positions: bool) -> _Reduction:
    """The mode's independent coordinates (module docstring; read-only arrays). It depends only
    on the (immutable) model and the friction modes, so it is kept for the last few of them."""
    key = (id(model), mode.fm, bool(keep_positions))
    hit = _REDUCTIONS.pop(key, None)
    if hit is not None and hit[0] is model:
        _REDUCTIONS[key] = hit
        return hit[1]
    red = _reduction_of(model, mode, keep_positions=keep_positions)
    _REDUCTIONS[key] = (model, red)  # the model is held: its id is not reused while kept
    while len(_REDUCTIONS) > _REDUCTION_CACHE_SIZE:
        del _REDUCTIONS[next(iter(_REDUCTIONS))]
    return red


def _reduction_of(model: Model, mode: Mode, *, keep_positions: bool) -> _Reduction:
    n = model.n_bodies
    N = model.speed_basis(mode)
    r = N.shape[1]
    bodies = model.chain.bodies
    pref = [0] + [i for i in range(n - 1, 0, -1) if bodies[i].kind == "translational"]
    pref += [i for i in range(n) if i not in pref]
    rows: list[int] = []
    if r == n:  # no constraint (no stuck element): every speed is independent
        pref = []
        rows = list(range(n))
    for i in pref:
        trial = rows + [i]
        if np.linalg.matrix_rank(N[trial], tol=1e-9) == len(trial):
            rows = trial
        if len(rows) == r:
            break
    rows.sort()
    Nsel = N @ np.linalg.inv(N[rows]) if r else np.zeros((n, 0))
    Nsel[np.abs(Nsel) < 1e-12] = 0.0
    D = model.data
    others: list[int] = []
    frozen_q = set()
    for c in range(D.ratio.shape[0]):
        qi = int(D.c_q[c])
        if qi < 0:
            continue
        g = np.zeros(n)
        g[c] = 1.0
        g[c + 1] = -D.ratio[c]
        if np.max(np.abs(g @ Nsel), initial=0.0) < 1e-12:
            frozen_q.add(qi)
    pos = {int(p) for p in D.b_pos if p >= 0}
    for j in range(n, model.nx):
        if j in frozen_q or (j in pos and not keep_positions):
            continue
        others.append(j)
    nz = r + len(others)
    T = np.zeros((model.nx, nz))
    S = np.zeros((nz, model.nx))
    T[:n, :r] = Nsel
    for k, i in enumerate(rows):
        S[k, i] = 1.0
    for k, j in enumerate(others):
        T[j, r + k] = 1.0
        S[r + k, j] = 1.0
    idx = rows + others
    return _Reduction(
        _frozen(T),
        _frozen(S),
        tuple(model.state_names[i] for i in idx),
        tuple(model.state_units[i] for i in idx),
        tuple(rows),
        _frozen(Nsel),
    )


def _with_codes(mode: Mode, changes: Mapping[int, int]) -> Mode:
    fm = list(mode.fm)
    for f, c in changes.items():
        fm[f] = c
    return Mode(tuple(fm), mode.reg)
