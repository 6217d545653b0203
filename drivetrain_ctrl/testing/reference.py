"""Flat reference model of the full drivetrain: the ODE of each mode written out by hand.

This module is an independent check of the chain machinery (:mod:`drivetrain_ctrl.plant.chain`,
:mod:`drivetrain_ctrl.kernels`, :mod:`drivetrain_ctrl.plant.model`): it uses none of it, only the
parameters. Every body equation, coupling torque and constraint row of the full model (see
:mod:`drivetrain_ctrl.plant.drivetrain`) is written plainly in :func:`_full_reference`; it is slow and
meant for tests, not for simulation.

Bodies (index, frame): 0 engine (engine), 1 disc (primary), 2 primary (primary), 3 secondary
(secondary), 4 hub (wheel), 5 tread (wheel), 6 vehicle (translation). State layout (as
``full_model(...).model.state_names``)::

    omega_engine, omega_disc, omega_primary, omega_secondary, omega_hub, omega_tread, v_vehicle,
    q_damper, q_backlash, q_axle, q_tyre_hub, pos_vehicle, lag_engine

``q_axle`` is the half-shaft twist in the *secondary* frame, ``theta_sec - D_c theta_hub`` (the
wheel-frame twist is ``q_axle / D_c``). Inputs ``u = (throttle, pedal x_c [m], brake [N m])``.

Friction elements and their mode names (in the order stuck, slip+, slip-, open):

=================== ================================================ ===========================
element             modes                                            stuck torque reported in
=================== ================================================ ===========================
``clutch``          stuck / slip+ / slip- / open                     N m (engine = primary frame)
``damper_friction`` stuck / slip+ / slip- / open                     N m (primary frame)
``tyre``            grip / slip+ / slip- / lifted                    N m at the tread (F R_p)
``engine``          standstill / turning+ / turning- / free          N m (engine frame)
``brake``           holding / slip+ / slip- / released               N m (wheel frame)
``vehicle``         standstill / moving+ / moving- / free            N (rolling resistance)
=================== ================================================ ===========================

A friction element acts as a torque ``T`` between its two bodies (``-T`` on the upstream body,
``+ratio T`` on the downstream one; ground elements: ``-T`` on the body). Slipping: ``T = capacity
* sign`` (``+1`` for slip+, ``-1`` for slip-), whatever the actual relative speed; open: ``T = 0``;
stuck: ``T`` is the Lagrange multiplier of the constraint "relative speed = 0". Elements whose
coefficient is zero (``c1``, ``k23``, ``k_v``) do not exist in the model and are ignored here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from ..core.units import GRAVITY
from ..plant.params import DrivetrainParams

__all__ = [
    "FRICTION_MODE_NAMES",
    "full_reference_rhs",
    "full_reference_stuck_torques",
    "max_min_stuck_torques",
]

F64 = NDArray[np.float64]

#: mode names of each friction element, in the order stuck (0), slip+ (1), slip- (2), open (3)
FRICTION_MODE_NAMES: dict[str, tuple[str, str, str, str]] = {
    "clutch": ("stuck", "slip+", "slip-", "open"),
    "damper_friction": ("stuck", "slip+", "slip-", "open"),
    "tyre": ("grip", "slip+", "slip-", "lifted"),
    "engine": ("standstill", "turning+", "turning-", "free"),
    "brake": ("holding", "slip+", "slip-", "released"),
    "vehicle": ("standstill", "moving+", "moving-", "free"),
}

_N_STATES = 13
_N_BODIES = 7


def _mode(modes: Mapping[str, str], name: str) -> str:
    """``"stuck"``, ``"slip+"``, ``"slip-"`` or ``"open"`` for element ``name``."""
    if name not in modes:
        raise KeyError(f"no mode given for friction element {name!r}")
    names = FRICTION_MODE_NAMES[name]
    m = modes[name]
    if m not in names:
        raise ValueError(f"{name}: mode {m!r} not in {names}")
    return ("stuck", "slip+", "slip-", "open")[names.index(m)]


def _kinetic(mode: str, capacity: float) -> float:
    """Kinetic friction torque of a slipping element (0 when stuck or open)."""
    if mode == "slip+":
        return capacity
    if mode == "slip-":
        return -capacity
    return 0.0


def _interp_clamped(xs: tuple[float, ...], ys: tuple[float, ...], v: float) -> float:
    """Piecewise-linear table, end values held outside the knots."""
    if len(xs) == 1 or v <= xs[0]:
        return float(ys[0])
    if v >= xs[-1]:
        return float(ys[-1])
    return float(np.interp(v, xs, ys))


def _damper_spring(xs: tuple[float, ...], ys: tuple[float, ...], q: float) -> float:
    """phi_e(q): odd, piecewise linear, last segment continued beyond the last knot."""
    a = abs(q)
    if a >= xs[-1]:
        slope = (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
        val = ys[-1] + slope * (a - xs[-1])
    else:
        val = float(np.interp(a, xs, ys))
    return (val if q > 0 else -val) if q != 0.0 else 0.0


def _deadzone(q: float, g: float) -> float:
    """Spring deflection with a half gap ``g``: ``q - g`` above, ``q + g`` below, 0 inside."""
    if q > g:
        return q - g
    if q < -g:
        return q + g
    return 0.0


def _full_reference(
    params: DrivetrainParams,
    gear: int,
    slope: float,
    x: F64,
    u: F64,
    modes: Mapping[str, str],
) -> tuple[F64, dict[str, float]]:
    """State derivative and stuck torques of the full drivetrain in the given friction modes."""
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    if x.shape != (_N_STATES,):
        raise ValueError(f"x must have shape ({_N_STATES},), got {x.shape}")
    if u.shape != (3,):
        raise ValueError(f"u must have shape (3,), got {u.shape}")

    eng = params.engine
    clu = params.clutch
    dmp = params.damper
    gbx = params.gearbox
    drl = params.driveline
    veh = params.vehicle

    tau_r = gbx.tau_r(gear)
    D_c = gbx.D_c
    R_p = drl.R_p
    g34 = gbx.g34_wheel * tau_r * D_c  # half backlash, primary frame

    # ---- state --------------------------------------------------------------------------------
    w1, w2, w3, w_sec, w_hub, w_tread, v = (float(s) for s in x[:7])
    q_damper, q_backlash, q_axle, q_tyre_hub = (float(s) for s in x[7:11])
    lag = float(x[12])
    throttle, pedal, brake_cap = (float(s) for s in u)

    # ---- inertias -----------------------------------------------------------------------------
    J1 = eng.J1
    J2 = clu.J2
    J3 = dmp.J3
    J4 = gbx.J4
    J_hub = (1.0 - drl.tread_fraction) * drl.J5
    J_tread = drl.tread_fraction * drl.J5
    M_v = veh.M_v

    # ---- which friction elements exist, and their modes ----------------------------------------
    k_v = float(veh.f_r * M_v * GRAVITY * math.cos(slope))  # rolling resistance [N]
    k_w = float(veh.mu_tyre * veh.drive_axle_load_fraction * M_v * GRAVITY * math.cos(slope))
    m_clutch = _mode(modes, "clutch")
    m_damper = _mode(modes, "damper_friction") if dmp.k23 > 0.0 else "open"
    m_tyre = _mode(modes, "tyre")
    m_engine = _mode(modes, "engine") if eng.c1 > 0.0 else "open"
    m_brake = _mode(modes, "brake")
    m_vehicle = _mode(modes, "vehicle") if k_v > 0.0 else "open"

    # ---- engine -------------------------------------------------------------------------------
    if eng.torque_model == "map":
        curve = eng.full_load_curve
        assert curve is not None
        C_G = _interp_clamped(curve.x, curve.y, w1) * lag
    else:
        C_G = eng.K * lag
    lag_dot = (throttle - lag) / eng.tau_p

    # ---- coupling torques (upstream frame unless said otherwise) -------------------------------
    # clutch, engine -> disc: k12(x_c) mu(|w1 - w2|) sgn, k12 = k12_max * shape(x_c) [N m]
    k12_knots = tuple(clu.k12_max * s for s in clu.pedal_map.y)
    k12 = _interp_clamped(clu.pedal_map.x, k12_knots, pedal)
    slip12 = w1 - w2
    mu = _interp_clamped(clu.mu_table.x, clu.mu_table.y, abs(slip12))
    T_clutch = _kinetic(m_clutch, k12 * mu)

    # damper, disc -> primary: spring phi_e(q_damper) + hysteresis friction k23 sgn
    T_damper = _damper_spring(dmp.spring.x, dmp.spring.y, q_damper) + _kinetic(m_damper, dmp.k23)

    # gear mesh, primary frame: h34 deadzone(q, g34) + b34 (w3 - tau_r w_sec); with
    # backlash_damping "contact" b34 acts only while the teeth touch (|q| > g34)
    contact = g34 == 0.0 or abs(q_backlash) > g34
    b34 = gbx.b34 if gbx.backlash_damping == "always" or contact else 0.0
    T_gear = gbx.h34 * _deadzone(q_backlash, g34) + b34 * (w3 - tau_r * w_sec)

    # half-shafts, WHEEL frame: h45 q_axle / D_c + b45 (w_sec / D_c - w_hub)
    T_axle_w = drl.h45 * (q_axle / D_c) + drl.b45 * (w_sec / D_c - w_hub)

    # tyre / hub compliance, wheel frame
    T_tyre_hub = drl.h56 * q_tyre_hub + drl.b56 * (w_hub - w_tread)

    # tyre / road force [N] (slipping: Coulomb limit k_w)
    F_tyre = _kinetic(m_tyre, k_w)

    # ground friction
    T_engine_fr = _kinetic(m_engine, eng.c1)
    T_brake = _kinetic(m_brake, brake_cap)
    F_rolling = _kinetic(m_vehicle, k_v)

    # ---- generalised forces on each body (without stuck torques) ------------------------------
    tau = np.zeros(_N_BODIES)
    # engine: C_1 = C_G - b1 w1 - c1 sgn(w1); clutch reaction
    tau[0] = C_G - eng.b1 * w1 - T_engine_fr - T_clutch
    # disc
    tau[1] = -clu.b2 * w2 + T_clutch - T_damper
    # primary shaft
    tau[2] = -dmp.b3 * w3 + T_damper - T_gear
    # secondary shaft (+ differential)
    tau[3] = -gbx.b4 * w_sec + tau_r * T_gear - T_axle_w / D_c
    # hub (wheels)
    tau[4] = -drl.b5 * w_hub + T_axle_w - T_tyre_hub - T_brake
    # tyre tread ring
    tau[5] = T_tyre_hub - F_tyre * R_p
    # vehicle
    tau[6] = (
        -veh.b_v * v
        - 0.5 * veh.rho_a * veh.C_x * veh.S * v * abs(v)
        - M_v * GRAVITY * math.sin(slope)
        + F_tyre
        - F_rolling
    )

    # ---- constraints of the stuck elements: G a = 0, M a = tau - G^T lam -----------------------
    # each row is the element's relative speed in its upstream frame, so lam is the element's
    # torque (force for the vehicle) with the sign convention of the kinetic torques above
    rows: list[tuple[str, list[float]]] = []
    if m_clutch == "stuck":  # w1 - w2 = 0
        rows.append(("clutch", [1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
    if m_damper == "stuck":  # w2 - w3 = 0
        rows.append(("damper_friction", [0.0, 1.0, -1.0, 0.0, 0.0, 0.0, 0.0]))
    if m_tyre == "stuck":  # w_tread - v / R_p = 0
        rows.append(("tyre", [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, -1.0 / R_p]))
    if m_engine == "stuck":  # w1 = 0
        rows.append(("engine", [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
    if m_brake == "stuck":  # w_hub = 0
        rows.append(("brake", [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]))
    if m_vehicle == "stuck":  # v = 0
        rows.append(("vehicle", [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]))

    # static capacities of the stuck elements (static ratio times the capacity), same units
    static = {
        "clutch": clu.static_ratio * k12,
        "damper_friction": dmp.static_ratio * dmp.k23,
        "tyre": veh.tyre_static_ratio * k_w * R_p,
        "engine": eng.static_ratio * eng.c1,
        "brake": params.brake.static_ratio * brake_cap,
        "vehicle": veh.rolling_static_ratio * k_v,
    }

    M = np.diag([J1, J2, J3, J4, J_hub, J_tread, M_v])
    k = len(rows)
    if k == 0:
        acc = tau / np.diag(M)
        lam = np.zeros(0)
    else:
        G = np.array([r for _, r in rows])
        kkt = np.zeros((_N_BODIES + k, _N_BODIES + k))
        kkt[:_N_BODIES, :_N_BODIES] = M
        kkt[:_N_BODIES, _N_BODIES:] = G.T
        kkt[_N_BODIES:, :_N_BODIES] = G
        b = np.concatenate([tau, np.zeros(k)])
        if np.linalg.matrix_rank(G) < k:
            # redundant constraints (not reachable with the full model's topology, where every
            # rigidly stuck group holds at most one ground element): the accelerations are
            # unique, the stuck torques the max-min distribution within the static capacities
            acc = np.linalg.lstsq(kkt, b, rcond=None)[0][:_N_BODIES]
            limits = np.array([static[name] for name, _ in rows])
            lam = max_min_stuck_torques(np.diag(1.0 / np.diag(M)), G, tau, limits)[0]
        else:
            sol = np.linalg.solve(kkt, b)
            acc = sol[:_N_BODIES]
            lam = sol[_N_BODIES:]

    # ---- state derivative ---------------------------------------------------------------------
    xdot = np.zeros(_N_STATES)
    xdot[:7] = acc
    xdot[7] = w2 - w3  # q_damper
    xdot[8] = w3 - tau_r * w_sec  # q_backlash (primary frame)
    xdot[9] = w_sec - D_c * w_hub  # q_axle (secondary frame)
    xdot[10] = w_hub - w_tread  # q_tyre_hub
    xdot[11] = v  # pos_vehicle
    xdot[12] = lag_dot  # lag_engine
    stuck = {name: float(lam[i]) for i, (name, _) in enumerate(rows)}
    return xdot, stuck


def max_min_stuck_torques(
    minv: F64, G: F64, tau: F64, limits: F64, *, tol: float = 1e-9
) -> tuple[F64, float]:
    """Stuck torques of a (possibly statically indeterminate) stuck set, by ``scipy``'s LP.

    All multipliers ``lam`` with ``S lam = G M^-1 tau`` (``S = G M^-1 G^T``: every ``lam`` that
    gives the constrained accelerations) are candidates; the one taken maximises the smallest
    capacity margin ``limits_i - |lam_i|`` (the optimal margin is returned too), ties broken
    lexicographically: the next smallest margin is maximised with the smallest ones held, and so
    on (leximin), which makes ``lam`` unique. Each stage is one ``scipy.optimize.linprog``; which
    margins a stage holds is decided by one more LP per margin (can it exceed the stage's
    optimum?), so nothing here is shared with the kernels' simplex. ``minv`` (n, n) the inverse
    mass matrix, ``G`` (k, n) the constraint rows, ``tau`` (n,) the forces, ``limits`` (k,) the
    static capacities; returns ``(lam (k,), optimal smallest margin)``. Slow; for tests.
    """
    from scipy.optimize import linprog

    G = np.atleast_2d(np.asarray(G, dtype=float))
    k, n = G.shape
    minv = np.asarray(minv, dtype=float)
    tau = np.asarray(tau, dtype=float)
    lim = np.asarray(limits, dtype=float)
    for name, arr, shape in (("minv", minv, (n, n)), ("tau", tau, (n,)), ("limits", lim, (k,))):
        if arr.shape != shape or not np.all(np.isfinite(arr)):
            raise ValueError(
                f"max_min_stuck_torques: {name} = {arr!r} must be finite with shape {shape} "
                f"(G has shape {G.shape})"
            )
    S = G @ minv @ G.T
    rhs = G @ minv @ tau
    A_eq = np.hstack([S, np.zeros((k, 1))])
    free = np.ones(k, dtype=bool)
    level = np.zeros(k)
    first: float | None = None
    lam = np.zeros(k)

    def solve(obj: int | None, t_min: float | None) -> tuple[F64, float]:
        # variables (lam, t): maximise t (obj None) or the margin of element obj; the free
        # margins >= t (or >= t_min), the held ones >= their level
        rows, b = [], []
        for i in range(k):
            for s in (1.0, -1.0):
                row = np.zeros(k + 1)
                row[i] = s
                if free[i] and (obj is None or i == obj):
                    row[-1] = 1.0
                    b.append(lim[i])
                elif free[i]:
                    assert t_min is not None
                    b.append(lim[i] - t_min)
                else:
                    b.append(lim[i] - level[i])
                rows.append(row)
        c = np.zeros(k + 1)
        c[-1] = -1.0
        sol = linprog(
            c,
            A_ub=np.array(rows),
            b_ub=np.array(b),
            A_eq=A_eq,
            b_eq=rhs,
            bounds=[(None, None)] * (k + 1),
            method="highs",
        )
        if sol.status != 0:
            raise RuntimeError(f"linprog: {sol.message}")
        return sol.x[:k], float(sol.x[-1])

    while np.any(free):
        lam, t = solve(None, None)
        if first is None:
            first = t
        held = []
        for i in np.flatnonzero(free):
            _lam_i, best = solve(int(i), t)
            if best <= t + tol * (1.0 + abs(t)):
                held.append(i)
        if not held:  # round-off: hold them all
            held = list(np.flatnonzero(free))
        for i in held:
            free[i] = False
            level[i] = t
    # the last stage's optimal set is a single point once every margin is held: its lam
    assert first is not None
    return lam, first


def full_reference_rhs(
    params: DrivetrainParams,
    gear: int,
    slope: float,
    x: F64,
    u: F64,
    modes: Mapping[str, str],
) -> F64:
    """State derivative of the full drivetrain (gear 1-based, slope [rad], positive uphill).

    ``modes`` maps every friction element (``clutch``, ``damper_friction``, ``tyre``,
    ``engine``, ``brake``, ``vehicle``) to one of its mode names (:data:`FRICTION_MODE_NAMES`).
    """
    return _full_reference(params, gear, slope, x, u, modes)[0]


def full_reference_stuck_torques(
    params: DrivetrainParams,
    gear: int,
    slope: float,
    x: F64,
    u: F64,
    modes: Mapping[str, str],
) -> dict[str, float]:
    """Torque [N m] (vehicle: force [N]) each stuck element carries; units in the module doc."""
    return _full_reference(params, gear, slope, x, u, modes)[1]
