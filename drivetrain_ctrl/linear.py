"""Operating points, linearisation and the clutch control loop (small-signal analysis).

The plant is a switching system; a linear model only exists *inside one mode*. Everything here
therefore works on an :class:`OperatingPoint` = (state, inputs, mode) and uses the model's
analytic Jacobian of that mode (:meth:`~drivetrain_ctrl.model.Model.jacobian`); nothing is
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
d theta_f - d tau_13`` with the engine-side effective damping

    b_1' = -dC_1/domega_1 = b_1 - theta_f dC_max/domega_1

(``b_1`` viscous; the Coulomb part is constant in a turning mode; the second term only with the
full-load map ``C_G = theta_f C_max(omega_1)``, zero for the paper's ``C_G = K theta_f``). With
constant mu (``c = 0``) the engine decouples from the driveline and law (6),
``x_r = x_r0 + k_r (omega_r - omega_1) s``, closes the loop (negative-feedback convention)

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

import control
import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from . import kernels as K
from .closedloop import Actuator, Controller, require_controller
from .drivetrain import Drivetrain
from .metrics import json_ready
from .model import Mode, Model
from .params import DrivetrainParams
from .units import GRAVITY, kmh_to_m_s

__all__ = [
    "Certificate",
    "StuckMargin",
    "OperatingPoint",
    "operating_point_from_result",
    "slip_operating_point",
    "locked_trim",
    "rebuild_operating_point",
    "LinearisationParts",
    "linearisation_parts",
    "linearise",
    "EngineSide",
    "engine_side",
    "actuator_tf",
    "pedal_to_clutch_torque",
    "clutch_torque_to_engine_speed",
    "throttle_to_engine_speed",
    "pedal_to_vehicle_accel",
    "throttle_to_vehicle_accel",
    "law6_loop_closed_form",
    "ClutchLoop",
    "clutch_loop",
    "ShuffleMode",
    "LockedAnalysis",
    "locked_analysis",
    "JudderThreshold",
    "judder_threshold",
    "slip_mode_poles",
    "shuffle_speed_source_threshold",
    "VisitedMode",
    "linearise_visited_modes",
]

F64 = NDArray[np.float64]

#: model input names -> names of the linear model's inputs
INPUT_ALIASES: dict[str, str] = {"throttle": "throttle", "pedal": "x_c", "brake": "brake"}


def _finite(name: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} = {v!r}: must be a finite number")
    f = float(v)
    if not math.isfinite(f):
        raise ValueError(f"{name} = {v!r}: must be a finite number")
    return f


def _positive(name: str, v: object) -> float:
    f = _finite(name, v)
    if not f > 0:
        raise ValueError(f"{name} = {v!r}: must be > 0")
    return f


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
        """JSON-ready form (floats rounded by :func:`drivetrain_ctrl.metrics.json_ready`)."""
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


def _capacity(model: Model, f: int, u: F64, mode: Mode) -> float:
    """Kinetic capacity at zero slip of friction ``f`` [N m or N] (same law as the kernels)."""
    D = model.data
    base = 1.0
    ui = int(D.f_uidx[f])
    if ui >= 0:
        kt = int(D.f_table[f])
        if kt < 0:
            base = float(u[ui])
        else:
            r = mode.reg[kt]
            base = float(D.t_s[kt, r] * u[ui] + D.t_o[kt, r])
    return float(D.f_scale[f]) * base


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
            cap = float(model.data.f_static[f]) * _capacity(model, f, u, mode)
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
    t = _finite("t", t)
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


def _driven_state(dt: Drivetrain) -> str:
    return "omega_disc" if dt.kind == "full" else "omega_primary"


def _check_fraction(name: str, v: float) -> float:
    v = _finite(name, v)
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"{name} = {v!r}: must lie in [0, 1]")
    return v


def _check_brake(v: object, dt: Drivetrain) -> float:
    br = _finite("brake", v)
    hi = dt.params.brake.capacity_max
    if not 0.0 <= br <= hi:
        raise ValueError(f"brake = {v!r} [N m]: must lie in [0, brake.capacity_max = {hi!r}]")
    return br


def _check_pedal(dt: Drivetrain, v: object) -> float:
    """``x_c`` [m] inside the pedal map's knots (the map is clamped outside them)."""
    xc = _finite("x_c", v)
    pm = dt.params.clutch.pedal_map
    lo, hi = float(pm.x[0]), float(pm.x[-1])
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
    we = _finite("omega_engine", omega_engine)
    if we < 0.0:
        raise ValueError(f"omega_engine = {omega_engine!r} rad/s: must be >= 0")
    wd = _finite("omega_driven", omega_driven)
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

        cap = abs(_capacity(m, _friction(m, "clutch"), u, mode_of(state(0.0))))
        hi = 2.0 * cap + 1000.0
        try:
            T0 = float(scipy.optimize.brentq(mismatch, -hi, hi, xtol=1e-10))
        except ValueError:
            T0 = 0.0
    else:
        T0 = _finite("twist_torque", twist_torque)
    x = state(T0)
    mode, x = m.decide(x, u)
    fc = _friction(m, "clutch")
    if mode.fm[fc] not in (K.SLIP_POS, K.SLIP_NEG):
        raise ValueError(
            f"x_c = {xc!r} m: the clutch is {m.mode_names(mode)['clutch']!r} (capacity "
            f"{_capacity(m, fc, u, mode):.6g} N m), not slipping"
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
    [0, 1], or if the clutch cannot hold (its stuck torque exceeds its static capacity); also if
    ``x_c`` is outside the pedal map's knots or ``brake`` < 0.
    """
    vk = _finite("vehicle_speed_kmh", vehicle_speed_kmh)
    if vk <= 0:
        raise ValueError(
            f"vehicle_speed_kmh = {vehicle_speed_kmh!r}: must be > 0 (at rest the engine stalls "
            "with the clutch locked)"
        )
    dt = drivetrain
    if slope is not None:
        s = _finite("slope", slope)
        if s != dt.slope:
            dt = Drivetrain(dt.params, kind=dt.kind, gear=dt.gear, slope=s)
    m = dt.model
    v = kmh_to_m_s(vk)
    xc = float(dt.params.clutch.pedal_map.x[0]) if x_c is None else _check_pedal(dt, x_c)
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
    return op


def rebuild_operating_point(op: OperatingPoint, params: Any) -> OperatingPoint:
    """The same operating point (same recipe: speeds, pedal, throttle or trim conditions) for
    another parameter set ``params`` (a :class:`~drivetrain_ctrl.params.DrivetrainParams`, else
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


@dataclass(frozen=True)
class _Reduction:
    T: F64  # (nx, nz)
    S: F64  # (nz, nx)
    names: tuple[str, ...]
    units: tuple[str, ...]
    speed_rows: tuple[int, ...]
    Nsel: F64  # (n, r) omega = Nsel omega[speed_rows]


def _reduction(model: Model, mode: Mode, *, keep_positions: bool) -> _Reduction:
    n = model.n_bodies
    N = model.speed_basis(mode)
    r = N.shape[1]
    bodies = model.chain.bodies
    pref = [0] + [i for i in range(n - 1, 0, -1) if bodies[i].kind == "translational"]
    pref += [i for i in range(n) if i not in pref]
    rows: list[int] = []
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
        T,
        S,
        tuple(model.state_names[i] for i in idx),
        tuple(model.state_units[i] for i in idx),
        tuple(rows),
        Nsel,
    )


def _with_codes(mode: Mode, changes: Mapping[int, int]) -> Mode:
    fm = list(mode.fm)
    for f, c in changes.items():
        fm[f] = c
    return Mode(tuple(fm), mode.reg)


@dataclass(frozen=True)
class LinearisationParts:
    """Full-coordinate pieces of the linearisation at an operating point (SI).

    ``A``, ``B``: ``d x'/dx``, ``d x'/du`` in the mode (mu-slope override applied);
    ``dtau_dx``, ``dtau_du``: generalised body torques without constraint torques;
    ``clutch_dx``, ``clutch_du``: the clutch torque tau_13 [N m];
    ``engine_dx``, ``engine_du``: engine output torque C_1 [N m];
    ``mu_slope_torque``: ``c = k13 mu'`` [N m s/rad] used; ``clutch_gain``: d tau_13/d x_c
    [N m/m] (``k13' mu s`` in slip, 0 otherwise); ``capacity``: k13(x_c) [N m];
    ``mu``: mu(|w|)/mu(0) [-]; ``sign``: sgn of the clutch slip (0 when not slipping).
    """

    A: F64
    B: F64
    dtau_dx: F64
    dtau_du: F64
    clutch_dx: F64
    clutch_du: F64
    engine_dx: F64
    engine_du: F64
    mu_slope_torque: float
    clutch_gain: float
    capacity: float
    mu: float
    sign: int


def linearisation_parts(op: OperatingPoint, *, mu_slope: float | None = None) -> LinearisationParts:
    """Analytic full-coordinate Jacobians at ``op`` (see :class:`LinearisationParts`).

    ``mu_slope`` [s/rad] overrides ``d(mu/mu0)/d|w|`` of the clutch at the operating point (the
    level mu(|w|) is kept): the clutch torque gets the slope ``c = k13(x_c) mu_slope``. Only
    meaningful while the clutch slips (ignored otherwise).
    """
    m, x, u, mode = op.model, np.asarray(op.x), np.asarray(op.u), op.mode
    n = m.n_bodies
    D = m.data
    fc = _friction(m, "clutch")
    M = np.asarray(D.M)
    A, B = m.jacobian(x, u, mode)
    A = np.array(A)
    B = np.array(B)
    no_stuck = _with_codes(mode, {f: K.OPEN for f in range(len(mode.fm)) if mode.fm[f] == K.STUCK})
    J1_, B1_ = m.jacobian(x, u, no_stuck)
    dtau_dx = M[:, None] * np.asarray(J1_)[:n]
    dtau_du = M[:, None] * np.asarray(B1_)[:n]
    no_clutch = _with_codes(no_stuck, {fc: K.OPEN})
    J2_, B2_ = m.jacobian(x, u, no_clutch)
    dtau2_dx = M[:, None] * np.asarray(J2_)[:n]
    dtau2_du = M[:, None] * np.asarray(B2_)[:n]
    i = int(D.f_idx[fc])
    ratio = float(D.ratio[i])
    code = mode.fm[fc]
    cap = _capacity(m, fc, u, mode)
    mu, dmu = _mu_ratio(m, fc, x, mode)
    c = 0.0
    gain = 0.0
    sign = 0
    g = np.zeros(m.nx)
    g[i] = 1.0
    g[i + 1] = -ratio
    if code in (K.SLIP_POS, K.SLIP_NEG):
        sign = 1 if code == K.SLIP_POS else -1
        clutch_dx = -(dtau_dx[i] - dtau2_dx[i])
        clutch_du = -(dtau_du[i] - dtau2_du[i])
        c = float(clutch_dx[i])
        if mu_slope is not None:
            c_new = cap * _finite("mu_slope", mu_slope)
            dc = c_new - c
            clutch_dx = clutch_dx + dc * g
            # torque -dc g^T on body i, +ratio dc g^T on body i+1
            dtau = np.zeros((n, m.nx))
            dtau[i] -= dc * g
            dtau[i + 1] += ratio * dc * g
            dtau_dx = dtau_dx + dtau
            P, _ = K.mode_matrices(D, np.array(mode.fm, dtype=np.int64))
            A[:n] += P @ dtau
            c = c_new
        gain = float(clutch_du[m.input_names.index("pedal")])
    elif code == K.STUCK:
        _, Lam = K.mode_matrices(D, np.array(mode.fm, dtype=np.int64))
        clutch_dx = Lam[fc] @ dtau_dx
        clutch_du = Lam[fc] @ dtau_du
    else:
        clutch_dx = np.zeros(m.nx)
        clutch_du = np.zeros(len(m.input_names))
    ie = m.chain.body_index("engine")
    return LinearisationParts(
        A=_frozen(A),
        B=_frozen(B),
        dtau_dx=_frozen(dtau_dx),
        dtau_du=_frozen(dtau_du),
        clutch_dx=_frozen(clutch_dx),
        clutch_du=_frozen(clutch_du),
        engine_dx=_frozen(dtau2_dx[ie]),
        engine_du=_frozen(dtau2_du[ie]),
        mu_slope_torque=float(c),
        clutch_gain=gain,
        capacity=cap,
        mu=mu,
        sign=sign,
    )


def linearise(
    op: OperatingPoint,
    *,
    inputs: Sequence[str] = ("throttle", "x_c"),
    outputs: Sequence[str] | None = None,
    mu_slope: float | None = None,
    keep_positions: bool = False,
    reduce: bool = True,
) -> control.StateSpace:
    """The linear model of the plant in the mode of ``op``: a python-control ``StateSpace`` with
    named states, inputs and outputs (deviations from ``op``, SI units).

    ``inputs``: any of ``throttle`` [-], ``x_c`` [m] (model input ``pedal``), ``brake`` [N m].
    ``outputs`` (None: all): body speeds by state name, ``tau_13`` [N m], ``C_1`` [N m],
    ``a_vehicle`` [m/s^2]. ``mu_slope`` [s/rad]: see :func:`linearisation_parts`. With ``reduce``
    (default) the state is the mode's independent coordinates (module docstring); otherwise the
    full state with the constrained Jacobian. The state units are in ``sys.state_units``-like
    order of ``sys.state_labels``.
    """
    require_op(op, "linearise")
    for nm, flag in (("keep_positions", keep_positions), ("reduce", reduce)):
        if not isinstance(flag, bool):
            raise TypeError(f"linearise: {nm} = {flag!r}: must be True or False")
    m = op.model
    for arg, val in (("inputs", inputs), ("outputs", outputs)):
        if val is None and arg == "outputs":
            continue
        if isinstance(val, str | bytes):
            raise ValueError(
                f"{arg} = {val!r}: a sequence of names is needed, e.g. ({val!r},), not a bare "
                "string"
            )
        if not isinstance(val, Sequence) or not val:
            raise TypeError(f"linearise: {arg} = {val!r}: must be a non-empty sequence of names")
        if len(set(val)) != len(val):
            raise ValueError(f"linearise: {arg} = {val!r}: names must not repeat")
    alias_inv = {v: k for k, v in INPUT_ALIASES.items() if k in m.input_names}
    for nm in inputs:
        if nm not in alias_inv:
            raise ValueError(f"inputs: {nm!r} unknown; choose from {sorted(alias_inv)}")
    parts = linearisation_parts(op, mu_slope=mu_slope)
    n = m.n_bodies
    uidx = [m.input_names.index(alias_inv[nm]) for nm in inputs]
    body_names = list(m.state_names[:n])
    avail = body_names + ["tau_13", "C_1", "a_vehicle"]
    outs = list(avail if outputs is None else outputs)
    for o in outs:
        if o not in avail:
            raise ValueError(f"outputs: {o!r} unknown; choose from {avail}")
    iv = m.state_index("v_vehicle") if "v_vehicle" in m.state_names else -1
    rows_x = []
    rows_u = []
    for o in outs:
        if o in body_names:
            e = np.zeros(m.nx)
            e[m.state_index(o)] = 1.0
            rows_x.append(e)
            rows_u.append(np.zeros(len(m.input_names)))
        elif o == "tau_13":
            rows_x.append(np.asarray(parts.clutch_dx))
            rows_u.append(np.asarray(parts.clutch_du))
        elif o == "C_1":
            rows_x.append(np.asarray(parts.engine_dx))
            rows_u.append(np.asarray(parts.engine_du))
        else:
            if iv < 0:
                raise ValueError("outputs: 'a_vehicle' needs a body 'vehicle'")
            rows_x.append(np.asarray(parts.A)[iv])
            rows_u.append(np.asarray(parts.B)[iv])
    Cf = np.array(rows_x).reshape(len(outs), m.nx)
    Df = np.array(rows_u).reshape(len(outs), len(m.input_names))[:, uidx]
    Af = np.asarray(parts.A)
    Bf = np.asarray(parts.B)[:, uidx]
    if reduce:
        red = _reduction(m, op.mode, keep_positions=keep_positions)
        A = red.S @ Af @ red.T
        B = red.S @ Bf
        C = Cf @ red.T
        names = list(red.names)
    else:
        A, B, C = Af, Bf, Cf
        names = list(m.state_names)
    return control.ss(
        A,
        B,
        C,
        Df,
        states=names,
        inputs=list(inputs),
        outputs=outs,
        name=f"{op.kind} {op.clutch_mode}",
    )


# ---------------------------------------------------------------------------------------------
# the clutch loop in slip
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class EngineSide:
    """Engine-side figures at a slip operating point (from the analytic Jacobian).

    ``J1`` [kg m^2]; ``b1_eff`` b_1' = -dC_1/domega_1 [N m s/rad]; ``clutch_gain``
    d tau_13/d x_c = k13'(x_c) mu s [N m/m]; ``dk13_dxc`` k13'(x_c) [N m/m]; ``k13`` [N m];
    ``mu`` mu(|w|)/mu(0); ``mu_slope_torque`` c = k13 mu' [N m s/rad]; ``sign`` of the slip;
    ``torque_per_throttle`` dC_G/dtheta_f [N m]; ``tau_p`` [s] engine lag.
    """

    J1: float
    b1_eff: float
    clutch_gain: float
    dk13_dxc: float
    k13: float
    mu: float
    mu_slope_torque: float
    sign: int
    torque_per_throttle: float
    tau_p: float


def require_op(op: object, what: str) -> None:
    """Raise ``TypeError`` unless ``op`` is an :class:`OperatingPoint` (``what``: the caller)."""
    if not isinstance(op, OperatingPoint):
        raise TypeError(
            f"{what}: op = {op!r}: must be an OperatingPoint (slip_operating_point, locked_trim "
            "or operating_point_from_result)"
        )


def _require_slip(op: OperatingPoint, what: str) -> None:
    require_op(op, what)
    if op.clutch_mode not in ("slip+", "slip-"):
        raise ValueError(
            f"{what}: op has the clutch {op.clutch_mode!r}; the clutch loop exists only in slip "
            "(use locked_analysis for a locked clutch)"
        )


def engine_side(op: OperatingPoint, *, mu_slope: float | None = None) -> EngineSide:
    """:class:`EngineSide` at the slip point ``op`` (ValueError if the clutch does not slip)."""
    _require_slip(op, "engine_side")
    m = op.model
    parts = linearisation_parts(op, mu_slope=mu_slope)
    ie = m.chain.body_index("engine")
    il = m.state_index("lag_engine")
    J1 = float(m.data.M[ie])
    b1 = -float(parts.engine_dx[ie])
    Kth = float(parts.engine_dx[il])
    tau_p = -1.0 / float(parts.A[il, il])
    mu = parts.mu
    return EngineSide(
        J1=J1,
        b1_eff=b1,
        clutch_gain=parts.clutch_gain,
        dk13_dxc=parts.clutch_gain / (mu * parts.sign),
        k13=parts.capacity,
        mu=mu,
        mu_slope_torque=parts.mu_slope_torque,
        sign=parts.sign,
        torque_per_throttle=Kth,
        tau_p=tau_p,
    )


def actuator_tf(actuator: Actuator) -> control.TransferFunction:
    """x_r -> x_c [m/m]: ``w_a^2 / (s^2 + 2 d_a w_a s + w_a^2)`` (paper, Sec. IV). TypeError
    if ``actuator`` is not an :class:`~drivetrain_ctrl.closedloop.Actuator`."""
    if not isinstance(actuator, Actuator):
        raise TypeError(f"actuator: an Actuator is needed, got {type(actuator).__name__}")
    w, d = actuator.omega, actuator.delta
    return control.tf([w * w], [1.0, 2 * d * w, w * w], inputs="x_r", outputs="x_c")


def pedal_to_clutch_torque(op: OperatingPoint) -> control.TransferFunction:
    """x_c -> tau_13 [N m/m] in slip: the static gain ``k13'(x_c) mu s`` (driveline-independent:
    the kinetic torque depends on the pedal and the slip only)."""
    return _pedal_to_clutch_torque(engine_side(op))


def clutch_torque_to_engine_speed(op: OperatingPoint) -> control.TransferFunction:
    """tau_13 -> omega_1 [rad/s / N m] in slip: ``-1 / (J_1 s + b_1')``."""
    return _clutch_torque_to_engine_speed(engine_side(op))


def throttle_to_engine_speed(op: OperatingPoint) -> control.TransferFunction:
    """theta -> omega_1 [rad/s] in slip with constant mu (clutch torque held by the pedal):
    ``(dC_G/dtheta_f) / ((tau_p s + 1)(J_1 s + b_1'))``."""
    return _throttle_to_engine_speed(engine_side(op))


# the three above from an engine side already computed (clutch_loop)
def _pedal_to_clutch_torque(es: EngineSide) -> control.TransferFunction:
    return control.tf([es.clutch_gain], [1.0], inputs="x_c", outputs="tau_13")


def _clutch_torque_to_engine_speed(es: EngineSide) -> control.TransferFunction:
    return control.tf([-1.0], [es.J1, es.b1_eff], inputs="tau_13", outputs="omega_engine")


def _throttle_to_engine_speed(es: EngineSide) -> control.TransferFunction:
    den = np.polymul([es.tau_p, 1.0], [es.J1, es.b1_eff])
    return control.tf([es.torque_per_throttle], den, inputs="throttle", outputs="omega_engine")


def trim_tf(sys: Any) -> control.TransferFunction:
    """``control.tf(sys)`` with the exact leading zeros of each numerator restored.

    A state-space system ``(A, B, C, D)`` has ``num(z) = D den(z) + (C B) z^(n-1) + ...``: the
    leading numerator coefficients are its Markov parameters ``D, C B, C A B, ...`` up to terms
    in the earlier ones. When these are zero (a strictly proper plant, a sample of delay), the
    conversion leaves them at round-off (e.g. 9e-16 against 0.06) instead of zero: a spurious zero
    near infinity, and scipy's ``BadCoefficients`` warning in every later conversion. Here each
    leading coefficient is dropped while the Markov parameter behind it is zero (``D`` exactly;
    ``C A^(k-1) B`` within ``1e-12 |C| |A|^(k-1) |B|``, with element-wise absolute values: its
    round-off scale) and the coefficient itself is below ``1e-6`` of the numerator's largest.
    Transfer functions and systems without state pass through ``control.tf`` unchanged; names and
    the sample time are kept."""
    tf = control.tf(sys)
    if not isinstance(sys, control.StateSpace) or sys.nstates == 0:
        return tf
    A = np.asarray(sys.A, dtype=float)
    B = np.asarray(sys.B, dtype=float)
    C = np.asarray(sys.C, dtype=float)
    D = np.asarray(sys.D, dtype=float)
    nums = []
    for i in range(tf.noutputs):
        row = []
        for j in range(tf.ninputs):
            num = np.atleast_1d(np.asarray(tf.num[i][j], dtype=float))
            big = float(np.max(np.abs(num))) if num.size else 0.0
            # num[k] is the coefficient behind Markov parameter k + off (0: D, 1: C B, ...)
            off = len(tf.den[i][j]) - num.size
            v, va = B[:, j].copy(), np.abs(B[:, j])
            for _ in range(max(off - 1, 0)):
                v, va = A @ v, np.abs(A) @ va
            k = 0
            while k < num.size - 1 and abs(num[k]) <= 1e-6 * big:
                mk = k + off
                if mk == 0:
                    markov_zero = D[i, j] == 0.0
                else:
                    # |C A^(mk-1) B| against its round-off scale |C| |A|^(mk-1) |B|
                    markov_zero = abs(float(C[i, :] @ v)) <= 1e-12 * float(np.abs(C[i, :]) @ va)
                    v, va = A @ v, np.abs(A) @ va
                if not markov_zero:
                    break
                k += 1
            row.append(num[k:])
        nums.append(row)
    dens = [[np.asarray(tf.den[i][j], dtype=float) for j in range(tf.ninputs)]
            for i in range(tf.noutputs)]  # fmt: skip
    return control.tf(
        nums, dens, tf.dt, inputs=tf.input_labels, outputs=tf.output_labels, name=tf.name
    )


def _tf_min(sys: Any) -> control.TransferFunction:
    """Minimal transfer function (pole-zero cancellation; no slycot needed), with round-off
    leading numerator coefficients dropped (:func:`trim_tf`)."""
    return control.minreal(trim_tf(sys), verbose=False)


def _siso(sys: control.StateSpace, inp: str, out: str) -> control.StateSpace:
    i = list(sys.input_labels).index(inp)
    o = list(sys.output_labels).index(out)
    s = control.ss(sys.A, sys.B[:, [i]], sys.C[[o], :], sys.D[[o]][:, [i]])
    return s


def pedal_to_vehicle_accel(
    op: OperatingPoint, *, mu_slope: float | None = None
) -> control.TransferFunction:
    """x_c -> a_vehicle [m/s^2 / m] from the linearised plant (minimal realisation)."""
    sys = linearise(op, outputs=["a_vehicle"], mu_slope=mu_slope)
    return _tf_min(_siso(sys, "x_c", "a_vehicle"))


def throttle_to_vehicle_accel(
    op: OperatingPoint, *, mu_slope: float | None = None
) -> control.TransferFunction:
    """theta -> a_vehicle [m/s^2] from the linearised plant (minimal realisation)."""
    sys = linearise(op, outputs=["a_vehicle"], mu_slope=mu_slope)
    return _tf_min(_siso(sys, "throttle", "a_vehicle"))


def law6_loop_closed_form(
    *, k_r: float, dk13_dxc: float, mu: float, J1: float, b1_eff: float, actuator: Actuator
) -> control.TransferFunction:
    """Closed form of law (6)'s loop with constant mu:
    ``L(s) = k_r |k13'(x_c)| mu A(s) / (J_1 s + b_1')`` (units: k_r [m s/rad], k13' [N m/m],
    J_1 [kg m^2], b_1' [N m s/rad]; L dimensionless). TypeError if ``actuator`` is not an
    :class:`~drivetrain_ctrl.closedloop.Actuator`."""
    if not isinstance(actuator, Actuator):
        raise TypeError(f"actuator: an Actuator is needed, got {type(actuator).__name__}")
    kr, j1 = _positive("k_r", k_r), _positive("J1", J1)
    g = kr * abs(_finite("dk13_dxc", dk13_dxc)) * _finite("mu", mu)
    return control.tf([g], [j1, _finite("b1_eff", b1_eff)]) * actuator_tf(actuator)


@dataclass(frozen=True)
class ClutchLoop:
    """The linearised clutch loop at a slip point, for one controller.

    TFs (python-control): ``actuator`` x_r -> x_c, ``x_c_to_tau13``, ``tau13_to_omega1``,
    ``theta_to_omega1``, ``x_c_to_accel``; ``plant`` P: controller output -> measured error
    channel with the sign, actuator and (possibly coupled) engine dynamics, so that ``L = C P``
    (negative feedback); ``controller`` C; ``L``, ``S``, ``T``, ``PS``, ``CS`` (gang of four);
    ``closed_loop`` the state-space closed loop (reference -> omega_1) whose poles include the
    driveline modes. ``discrete``: sampled controller analysed in discrete time (``dt`` [s]):
    ``L(z) = C(z) z^-d ZOH{P}(z)``, exact at the samples. ``engine``: :class:`EngineSide`.
    """

    op: OperatingPoint = field(repr=False)
    controller_name: str
    engine: EngineSide
    actuator: control.TransferFunction
    x_c_to_tau13: control.TransferFunction
    tau13_to_omega1: control.TransferFunction
    theta_to_omega1: control.TransferFunction
    x_c_to_accel: control.TransferFunction
    plant: control.StateSpace
    controller: control.StateSpace
    L: Any
    S: Any
    T: Any
    PS: Any
    CS: Any
    closed_loop: control.StateSpace
    discrete: bool
    dt: float | None


def _controller_sign(controller: Controller, op: OperatingPoint) -> float:
    if controller.sign_of is None:
        return 1.0
    a, b = controller.sign_of
    d = op.state(a) - op.state(b)
    if d == 0:
        raise ValueError(f"controller.sign_of = {controller.sign_of}: zero at the operating point")
    return 1.0 if d > 0 else -1.0


def clutch_loop(
    op: OperatingPoint, controller: Controller, *, mu_slope: float | None = None
) -> ClutchLoop:
    """The loop of ``controller`` around the slipping clutch at ``op``.

    The plant seen by the controller's LTI block is built from the linearised model
    (:func:`linearise`, input ``x_c``): ``P = -sgn * R(s) * A(s) * sum_k coef_k P_k(s)`` with
    ``P_k`` = x_c -> measured state k, ``sgn`` = the sign block at ``op``, ``R`` the rate limiter
    (first order ``g/(s+g)`` in its linear range), ``A`` the actuator; the reference term of the
    measurement is not part of the loop. Saturation is assumed inactive at ``op``. With constant
    mu ``L`` equals :func:`law6_loop_closed_form` (the driveline modes are uncontrollable from
    x_c to omega_1 and cancel); with ``mu_slope`` they couple in. A discrete controller is
    analysed in discrete time (ZOH-discretised plant, ``z^-d`` for the delay).
    """
    _require_slip(op, "clutch_loop")
    require_controller(controller, "clutch_loop")
    if controller.output != "pedal":
        raise ValueError(f"controller.output = {controller.output!r}: must drive 'pedal'")
    es = engine_side(op, mu_slope=mu_slope)
    sys = linearise(op, inputs=("throttle", "x_c"), mu_slope=mu_slope)
    meas = None
    for coef, src in controller.measurement:
        if src == "ref":
            continue
        if src not in sys.output_labels:
            raise ValueError(f"controller.measurement: {src!r} is not a body speed of the model")
        Pk = _siso(sys, "x_c", src) * float(coef)
        meas = Pk if meas is None else meas + Pk
    if meas is None:
        raise ValueError("controller.measurement: has no plant state (only 'ref')")
    P = control.ss(meas * _error_chain(controller, op))
    C = controller.lti
    disc = controller.is_discrete
    if disc:
        Ts = float(C.dt)
        Pd = control.sample_system(P, Ts, method="zoh")
        if controller.delay_samples:
            zd = control.tf([1.0], [1.0] + [0.0] * controller.delay_samples, Ts)
            Pd = control.ss(Pd * control.ss(zd))
        P_use = Pd
    else:
        Ts = None
        P_use = P
    L_ss = control.ss(C * P_use)
    Lt = _tf_min(L_ss)
    one = control.tf([1.0], [1.0], Ts) if disc else control.tf([1.0], [1.0])
    S = control.minreal(one / (one + Lt), verbose=False)
    T = control.minreal(Lt / (one + Lt), verbose=False)
    Pt = _tf_min(P_use)
    Ct = control.tf(C)
    PS = control.minreal(Pt * S, verbose=False)
    CS = control.minreal(Ct * S, verbose=False)
    cl = control.feedback(L_ss, 1)
    return ClutchLoop(
        op=op,
        controller_name=controller.name,
        engine=es,
        actuator=actuator_tf(controller.actuator) if controller.actuator else control.tf(1, 1),
        x_c_to_tau13=_pedal_to_clutch_torque(es),
        tau13_to_omega1=_clutch_torque_to_engine_speed(es),
        theta_to_omega1=_throttle_to_engine_speed(es),
        x_c_to_accel=pedal_to_vehicle_accel(op, mu_slope=mu_slope),
        plant=P_use,
        controller=C,
        L=Lt,
        S=S,
        T=T,
        PS=PS,
        CS=CS,
        closed_loop=cl,
        discrete=disc,
        dt=Ts,
    )


def _error_chain(controller: Controller, op: OperatingPoint) -> control.StateSpace:
    """Controller output -> x_c: ``-sgn`` (the sign block; the minus sign turns the loop into
    negative feedback), rate limiter (linear range) and actuator."""
    sgn = _controller_sign(controller, op)
    chain = control.ss([], [], [], [[-sgn]])
    if controller.rate_limit is not None:
        g = controller.rate_limit[1]
        chain = control.ss(control.tf([g], [1.0, g])) * chain
    if controller.actuator is not None:
        chain = control.ss(actuator_tf(controller.actuator)) * chain
    return chain


def slip_mode_poles(
    op: OperatingPoint, controller: Controller | None = None, *, mu_slope: float | None = None
) -> NDArray[np.complex128]:
    """Poles [1/s] of the linearised slip mode: the plant alone (pedal held) or closed by a
    continuous ``controller`` (the full state-space interconnection, so every driveline mode is
    included, controllable or not)."""
    require_op(op, "slip_mode_poles")
    require_controller(controller, "slip_mode_poles", optional=True)
    return _slip_mode_poles_of(linearise(op, inputs=("x_c",), mu_slope=mu_slope), op, controller)


def _slip_mode_poles_of(
    sys: control.StateSpace, op: OperatingPoint, controller: Controller | None
) -> NDArray[np.complex128]:
    """:func:`slip_mode_poles` from the plant already linearised at ``op`` (input ``x_c``)."""
    if controller is None:
        return np.asarray(np.linalg.eigvals(sys.A), dtype=complex)
    if controller.is_discrete:
        raise ValueError("slip_mode_poles: a discrete controller; use clutch_loop(...).closed_loop")
    Cm = np.zeros((1, sys.nstates))
    Dm = np.zeros((1, 1))
    for coef, src in controller.measurement:
        if src == "ref":
            continue
        o = list(sys.output_labels).index(src)
        Cm += coef * sys.C[[o], :]
        Dm += coef * sys.D[[o], :]
    plant_e = control.ss(sys.A, sys.B, Cm, Dm)  # x_c -> measured part of the error
    open_ss = control.ss(controller.lti) * _error_chain(controller, op) * plant_e
    # open_ss maps the error back to the controller input with the sign of the loop: close it
    cl = control.feedback(open_ss, 1, sign=-1)
    return np.asarray(np.linalg.eigvals(cl.A), dtype=complex)


# ---------------------------------------------------------------------------------------------
# locked clutch
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class ShuffleMode:
    """An oscillatory mode: eigenvalue, natural frequency [Hz] ``|lambda|/2pi``, damped
    frequency [Hz] ``Im lambda / 2pi`` and damping ratio ``-Re lambda / |lambda|``."""

    real: float
    imag: float
    natural_frequency_hz: float
    damped_frequency_hz: float
    damping: float


def natural_frequency_damping(p: complex) -> tuple[float, float]:
    """Natural frequency ``|p| / 2 pi`` [Hz] and damping ratio ``-Re p / |p|`` [-] of a
    continuous-time pole ``p`` [1/s] (damping 1 for ``p = 0``; negative when unstable)."""
    a = abs(p)
    return a / (2 * math.pi), (float(-p.real / a) if a > 0 else 1.0)


def oscillatory_poles(poles: Any) -> list[complex]:
    """The poles [1/s] with ``Im p > 0`` (beyond round-off: ``1e-9 max(1, |p|)``), one of each
    conjugate pair, sorted by ``|p|``."""
    ps = (complex(q) for q in np.asarray(poles, dtype=complex).ravel())
    return sorted((p for p in ps if p.imag > 1e-9 * max(1.0, abs(p))), key=abs)


def _oscillatory(poles: NDArray[np.complex128]) -> tuple[ShuffleMode, ...]:
    out = []
    for p in oscillatory_poles(poles):
        fn, zeta = natural_frequency_damping(p)
        out.append(ShuffleMode(p.real, p.imag, fn, p.imag / (2 * math.pi), zeta))
    return tuple(out)


@dataclass(frozen=True)
class LockedAnalysis:
    """Locked clutch: the clutch loop is open (x_c does not act), so loop margins are undefined.

    ``margins_reason``; ``shuffle_modes`` (oscillatory modes of the locked driveline, lowest
    first); ``poles``; ``theta_to_accel`` TF theta -> a_vehicle [m/s^2];
    ``breakaway_margins`` (certificate of ``op``)."""

    op: OperatingPoint = field(repr=False)
    margins_reason: str
    shuffle_modes: tuple[ShuffleMode, ...]
    poles: tuple[complex, ...]
    theta_to_accel: control.TransferFunction
    breakaway_margins: tuple[StuckMargin, ...]

    def to_dict(self) -> dict[str, Any]:
        return json_ready(
            {
                "margins": None,
                "margins_reason": self.margins_reason,
                "shuffle_modes": [
                    {
                        "natural_frequency_hz": s.natural_frequency_hz,
                        "damped_frequency_hz": s.damped_frequency_hz,
                        "damping": s.damping,
                    }
                    for s in self.shuffle_modes
                ],
                "poles": [[p.real, p.imag] for p in self.poles],
                "breakaway_margins": {
                    s.element: {"capacity": s.capacity, "torque": s.torque, "margin": s.margin}
                    for s in self.breakaway_margins
                },
            }
        )


def locked_analysis(op: OperatingPoint) -> LockedAnalysis:
    """Shuffle modes, theta -> vehicle acceleration and breakaway margins at a locked point."""
    if op.clutch_mode != "stuck":
        raise ValueError(f"locked_analysis: op has the clutch {op.clutch_mode!r}, not 'stuck'")
    sys = linearise(op, inputs=("throttle",))
    poles = np.linalg.eigvals(sys.A)
    return LockedAnalysis(
        op=op,
        margins_reason=(
            "clutch locked: x_c does not change the transmitted torque while the clutch is stuck, "
            "so the clutch loop is open (gain, phase, delay and disk margins undefined)"
        ),
        shuffle_modes=_oscillatory(poles),
        poles=tuple(complex(p) for p in sorted(poles, key=lambda z: (z.real, z.imag))),
        theta_to_accel=throttle_to_vehicle_accel(op),
        breakaway_margins=op.certificate.stuck_margins,
    )


# ---------------------------------------------------------------------------------------------
# judder
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class JudderThreshold:
    """Critical clutch friction slope of a slip point of the reduced model
    (:func:`judder_threshold`). Torque slopes ``c = k13 mu'`` in [N m s/rad], mu slopes in
    [s/rad] (of the ratio mu/mu0).

    ``c_shuffle_speed_source``: the shuffle-mode crossing with the engine side a speed source
    (Routh-Hurwitz of the driveline cubic); ``c_shuffle``: the same corrected for the engine side's
    impedance at the shuffle frequency; ``c_dc``: the real (s = 0) crossing, None when the
    controller has integral action; ``c_crit`` the first of them (smallest ``|c|``) and ``which``
    (``"shuffle"`` or ``"dc"``); ``mu_slope_crit = c_crit / k13``; ``shuffle_frequency_hz`` at the
    crossing; figures (primary frame): ``J25`` [kg m^2], ``m_e`` vehicle mass referred [kg m^2],
    ``h_t`` [N m/rad], ``b_t`` [N m s/rad], ``b_p`` (driven shaft to ground) and ``b_e`` (vehicle
    road-load slope referred) [N m s/rad], ``b1_eff`` b_1', ``engine_factor`` Re of
    ``(J_1 jw + b_1')/(Z_e(jw) + c)`` at the crossing, ``k13`` [N m]."""

    c_shuffle_speed_source: float
    c_shuffle: float
    c_dc: float | None
    c_crit: float
    which: str
    mu_slope_crit: float
    shuffle_frequency_hz: float
    J25: float
    m_e: float
    h_t: float
    b_t: float
    b_p: float
    b_e: float
    b1_eff: float
    engine_factor: float
    k13: float

    def to_dict(self) -> dict[str, Any]:
        return json_ready({k: getattr(self, k) for k in self.__dataclass_fields__})


def shuffle_speed_source_threshold(
    *, J: float, m: float, h: float, b: float, e: float
) -> tuple[float, float]:
    """Routh-Hurwitz boundary of the driveline seen from a speed source at the clutch.

    Driven inertia ``J`` with damping ``d`` to ground (the unknown), shaft ``h``, ``b`` to the
    (referred) vehicle inertia ``m`` with damping ``e`` to ground. Characteristic polynomial
    ``s^3 + a2 s^2 + a1 s + a0`` with ``a2 = (d + b)/J + (e + b)/m``,
    ``a1 = (d e + b (d + e) + h (J + m))/(J m)``, ``a0 = h (d + e)/(J m)``. The oscillatory
    pair crosses at ``a2 a1 = a0`` (then ``s = +-j sqrt(a1)``): a quadratic in ``d``,

        d^2 (e + b)/(J^2 m) + d [g/J + k (e + b)/(J m) - h/(J m)] + k g - h e/(J m) = 0,

    ``k = b/J + (e + b)/m``, ``g = (b e + h (J + m))/(J m)``; its larger root is ``d*``. Returns
    ``(d*, omega*)`` [N m s/rad, rad/s]. To first order in the damping ``d* = -b (1 + J/m)^2 -
    e (J/m)^2`` (the trace of the system matrix minus the rigid-body pole).

    ``J``, ``m``, ``h`` must be finite and > 0, ``b``, ``e`` finite and >= 0 with ``b + e > 0``
    (ValueError naming the field otherwise).
    """
    J, m, h = (_positive(nm, v) for nm, v in (("J", J), ("m", m), ("h", h)))
    b, e = (_finite(nm, v) for nm, v in (("b", b), ("e", e)))
    for nm, v in (("b", b), ("e", e)):
        if v < 0:
            raise ValueError(f"{nm} = {v!r}: a damping [N m s/rad] must be >= 0")
    if b + e <= 0:
        raise ValueError(f"b = {b!r}, e = {e!r}: b + e must be > 0 (an undamped driveline)")
    kk = b / J + (e + b) / m
    gg = (b * e + h * (J + m)) / (J * m)
    qa = (e + b) / (J * J * m)
    qb = gg / J + kk * (e + b) / (J * m) - h / (J * m)
    qc = kk * gg - h * e / (J * m)
    disc = qb * qb - 4 * qa * qc
    d = (-qb + math.sqrt(max(disc, 0.0))) / (2 * qa)
    a1 = (d * e + b * (d + e) + h * (J + m)) / (J * m)
    return d, math.sqrt(max(a1, 0.0))


def _reduced_figures(op: OperatingPoint) -> tuple[float, float, float, float, float, float]:
    m = op.model
    if op.kind != "reduced":
        raise ValueError(
            f"judder_threshold: op is on the {op.kind!r} model; the closed form is derived on the "
            "reduced model (engine, J25, shaft h_t/b_t, vehicle)"
        )
    D = m.data
    ip = m.chain.body_index("primary")
    iv = m.chain.body_index("vehicle")
    c = ip  # coupling primary -> vehicle
    ratio = float(D.ratio[c])
    kt = int(D.c_table[c])
    h = float(D.t_s[kt, op.mode.reg[kt]])
    v = op.state("v_vehicle")
    J = float(D.M[ip])
    me = float(D.M[iv]) / ratio**2
    b_e = float(D.visc[iv] + 2 * D.quad[iv] * abs(v)) / ratio**2
    return J, me, h, float(D.damp[c]), float(D.visc[ip]), b_e


def judder_threshold(op: OperatingPoint, controller: Controller | None = None) -> JudderThreshold:
    """Critical friction slope at which a falling mu(slip) destabilises the slip mode (reduced
    model; ``controller`` None = pedal held, else a continuous clutch controller, e.g. law (6)).

    Derivation. In slip the clutch torque perturbation is ``c (dw_1 - dw_2) + k13' mu s dx_c``
    with ``c = k13 mu'``. Eliminating the engine (and the controller) the driven side sees the
    clutch as an impedance ``-d tau_13/d omega_2 = Z(s) = c (J_1 s + b_1')/(Z_e(s) + c)`` with
    the engine-side impedance ``Z_e = (J_1 s + b_1')(1 + L(s))`` (``L`` the constant-mu loop, 0
    with the pedal held). The characteristic equation is ``1 + Y_2(s) Z(s) = 0`` (``Y_2``: driven
    side admittance).

    * Shuffle (judder) crossing: at the shuffle frequency ``|Z_e| >> |c|`` (the engine inertia,
      and law (6) holding omega_1, make the engine a speed source), so ``Z ~ c``: the driven
      inertia J25 gets the damping ``d = b_p + c`` to ground, and the driveline (J25, h_t, b_t,
      m_e, b_e) crosses at ``d*`` of :func:`shuffle_speed_source_threshold`:
      ``c* = d* - b_p ~ -b_p - b_t (1 + J25/m_e)^2 - b_e (J25/m_e)^2``: the driveline side's
      effective damping at the shuffle mode, ``b_p + c + b_t (1 + J25/m_e)^2 + ...``, turns
      negative. ``c_shuffle`` corrects for the engine side: ``c = c*/kappa`` with
      ``kappa = Re[(J_1 jw + b_1')/(Z_e(jw) + c)]`` at ``w*`` (fixed point).
    * DC crossing: at ``s = 0`` the driveline is rigid, ``Y_2(0) = 1/b_d`` with
      ``b_d = b_p + b_e``, and a real pole crosses at ``c_dc = -Z_e(0) b_d/(b_1' + b_d)``: pedal
      held ``-b_1' b_d/(b_1' + b_d)`` (the two sides' dampings in series); law (6)
      ``-b_d (b_1' + K_L)/(b_1' + b_d)``, ``K_L = k_r |k13'| mu``; integral action: none.

    ``c_crit`` is the crossing with the smaller ``|c|``.
    """
    _require_slip(op, "judder_threshold")
    require_controller(controller, "judder_threshold", optional=True)
    if controller is None:
        return _judder_threshold(op, engine_side(op), None)
    if controller.is_discrete:
        raise ValueError("judder_threshold: a continuous controller is needed")
    loop = clutch_loop(op, controller)
    return _judder_threshold(op, loop.engine, loop.L)


def _judder_threshold(op: OperatingPoint, es: EngineSide, Lf: Any) -> JudderThreshold:
    """:func:`judder_threshold` at slip point ``op`` with its engine side ``es`` and the
    constant-mu loop ``Lf`` of a continuous controller (None: pedal held), e.g. a built
    :class:`ClutchLoop`'s ``engine`` and ``L``."""
    J, me, h, b, bp, be = _reduced_figures(op)
    b1 = es.b1_eff
    d_star, w_star = shuffle_speed_source_threshold(J=J, m=me, h=h, b=b, e=be)
    c_ss = d_star - bp
    if Lf is None:

        def Ze(s: complex) -> complex:
            return es.J1 * s + b1

        Ze0: float | None = b1
    else:

        def Ze(s: complex) -> complex:
            return (es.J1 * s + b1) * (1.0 + complex(Lf(s)))

        L0 = complex(Lf(1e-9)) if np.isfinite(abs(complex(Lf(1e-9)))) else math.inf
        Ze0 = None if abs(L0) > 1e8 else b1 * (1.0 + L0.real)
    c = c_ss
    kappa = 1.0
    for _ in range(50):
        s = 1j * w_star
        kappa = float(((es.J1 * s + b1) / (Ze(s) + c)).real)
        c_new = c_ss / kappa
        if abs(c_new - c) < 1e-13 * max(1.0, abs(c)):
            c = c_new
            break
        c = c_new
    c_dc = None if Ze0 is None else -Ze0 * (bp + be) / (b1 + bp + be)
    if c_dc is not None and abs(c_dc) < abs(c):
        crit, which = c_dc, "dc"
    else:
        crit, which = c, "shuffle"
    return JudderThreshold(
        c_shuffle_speed_source=c_ss,
        c_shuffle=c,
        c_dc=c_dc,
        c_crit=crit,
        which=which,
        mu_slope_crit=crit / es.k13,
        shuffle_frequency_hz=w_star / (2 * math.pi),
        J25=J,
        m_e=me,
        h_t=h,
        b_t=b,
        b_p=bp,
        b_e=be,
        b1_eff=b1,
        engine_factor=kappa,
        k13=es.k13,
    )


@dataclass(frozen=True)
class VisitedMode:
    """A mode held by a simulated trajectory, linearised at the middle of its longest interval.

    ``label``: ``element=mode`` pairs; ``duration_s``: total time [s] the trajectory holds it;
    ``op``: the operating point; ``sys``: :func:`linearise` of it; ``natural_frequencies_hz``:
    ``|p| / 2 pi`` of its oscillatory poles (Im p > 0) [Hz]; ``damping``: their damping ratios.
    """

    label: str
    duration_s: float
    op: OperatingPoint
    sys: control.StateSpace
    natural_frequencies_hz: tuple[float, ...]
    damping: tuple[float, ...]


def linearise_visited_modes(
    result: Any, *, drivetrain: Drivetrain | None = None, min_duration: float = 1e-3
) -> tuple[VisitedMode, ...]:
    """Linearise every mode the trajectory ``result`` holds for at least ``min_duration`` [s]
    in total (the reachable modes of that manoeuvre), each at the middle of its longest interval,
    never across a switch. A mode is the friction modes, backlash regions and table segments
    (pedal map, spring pieces) together. Sorted by decreasing duration."""
    T = np.asarray(result.t)
    if not _finite("min_duration", min_duration) >= 0:
        raise ValueError(f"min_duration = {min_duration!r} [s]: must be >= 0")
    keys = [tuple(int(v) for v in f) + (-1,) + tuple(int(v) for v in r)
            for f, r in zip(result.fm, result.reg, strict=True)]  # fmt: skip
    total: dict[tuple[int, ...], float] = {}
    longest: dict[tuple[int, ...], tuple[float, float]] = {}
    i = 0
    n = T.shape[0]
    while i < n - 1:
        j = i
        while j + 1 < n - 1 and keys[j + 1] == keys[i]:
            j += 1
        t0, t1 = float(T[i]), float(T[j + 1])
        k = keys[i]
        total[k] = total.get(k, 0.0) + (t1 - t0)
        if t1 - t0 > longest.get(k, (0.0, 0.0))[1] - longest.get(k, (0.0, 0.0))[0]:
            longest[k] = (t0, t1)
        i = j + 1
    out = []
    for k, dur in sorted(total.items(), key=lambda kv: -kv[1]):
        if dur < min_duration or k not in longest:
            continue
        t0, t1 = longest[k]
        op = operating_point_from_result(result, 0.5 * (t0 + t1), drivetrain=drivetrain)
        sys = linearise(op)
        poles: list[complex] = (
            [complex(q) for q in np.linalg.eigvals(np.asarray(sys.A, dtype=float))]
            if sys.nstates
            else []
        )
        fz = [natural_frequency_damping(p) for p in oscillatory_poles(poles)]
        segs = [
            f"{ti.name}=segment {r}"
            for ti, r in zip(op.model.tables, op.mode.reg, strict=True)
            if ti.region_names is None
        ]
        label = ", ".join([f"{e}={m}" for e, m in op.mode_names] + segs)
        out.append(
            VisitedMode(
                label=label,
                duration_s=dur,
                op=op,
                sys=sys,
                natural_frequencies_hz=tuple(f for f, _ in fz),
                damping=tuple(z for _, z in fz),
            )
        )
    return tuple(out)
