"""Baselines for ``bench_simulate.py``: scipy integration of the flat full-drivetrain model.

Nothing here uses the compiled chain machinery (``chain``, ``kernels``, ``model``, ``simulate``);
only the parameters, the input signals and the flat reference model
(:mod:`drivetrain_ctrl.reference`).

Two right-hand sides of the same equations (those of ``reference._full_reference``):

* :class:`LiteralFlatSystem` calls ``full_reference_rhs`` / ``full_reference_stuck_torques``
  themselves (about 0.1 ms a call: a readable but slow reference);
* :class:`FastFlatSystem` writes the same equations out with scalars and caches, per stuck pattern,
  the matrices ``P`` (accelerations ``P tau``) and ``Lam`` (stuck torques ``Lam tau``) of the
  constrained system ``M a = tau - G^T lam, G a = 0``. It is what the scipy baselines and the
  reference run on (checked against the literal one by :func:`check_fast_against_reference`).

Both evaluate the piecewise-linear laws with the *region fixed* for a whole integration segment
(the damper spring ``phi_e`` and the backlash dead zone by a guard at each knee, the pedal map by
stopping at the times the pedal crosses a knot), so an integrator never steps across a kink.

:func:`simulate_events` is the event-driven driver (scipy ``solve_ivp`` per mode segment):

* stops at every input breakpoint and at every pedal-map knee time; the input signals are
  evaluated on the piece that starts at the segment start (steps and kinks are never crossed);
* guards (terminal, direction -1): slipping element ``s w``; stuck element ``static_ratio cap -
  |lam|``; table knees ``a - lower bound`` and ``upper bound - a``;
* at an event (and at each stop) every element is decided again: capacity 0 (and not rising) ->
  open; ``|w| > tol_w`` -> slip in the direction of ``w``; the others are candidates, decided
  together: their speeds are projected (momentum-preserving) onto ``w = 0``, then all
  stuck / slip+ / slip- combinations are tried, most stuck first; the first consistent one is taken
  (stuck torques within static capacity, slip directions agreeing with the relative accelerations).
  An element whose stuck guard fired breaks loose in the direction of its stuck torque.

:func:`simulate_tanh` is the smoothed baseline: every Coulomb element ``k sgn(w)`` replaced by
``k tanh(w / eps)``, no stuck modes, the laws evaluated as they are (kinks included), LSODA.
"""

from __future__ import annotations

import bisect
import itertools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import DOP853, RK45, OdeSolution, solve_ivp
from scipy.optimize import brentq

from drivetrain_ctrl.core.signals import Signal
from drivetrain_ctrl.core.units import GRAVITY
from drivetrain_ctrl.plant.params import DrivetrainParams
from drivetrain_ctrl.testing.reference import (
    FRICTION_MODE_NAMES,
    full_reference_rhs,
    full_reference_stuck_torques,
)

F64 = NDArray[np.float64]

#: friction elements, in the order of the full model (codes: 0 stuck, 1 slip+, 2 slip-, 3 open)
ELEMENTS: tuple[str, ...] = ("clutch", "damper_friction", "tyre", "engine", "brake", "vehicle")
STUCK, SLIP_POS, SLIP_NEG, OPEN = 0, 1, 2, 3
_SIGN = (0.0, 1.0, -1.0, 0.0)
INPUT_NAMES = ("throttle", "pedal", "brake")
N_STATES = 13
N_BODIES = 7
#: tables with regions: names as in the compiled model (so events can be matched by name)
TABLE_NAMES = ("damper.spring", "backlash", "clutch.capacity_table")
BACKLASH_REGIONS = ("contact-", "gap", "contact+")
METHODS = {"RK45": RK45, "DOP853": DOP853}


class ZenoError(RuntimeError):
    """Events accumulate at one instant."""


# ------------------------------------------------------------------------------------------------
# piecewise-linear laws with explicit regions
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PwlLaw:
    """A continuous piecewise-linear law: ``bounds`` (knees, increasing) and, per region
    ``r`` (``0..len(bounds)``), ``value = slopes[r] * a + offsets[r]``."""

    bounds: tuple[float, ...]
    slopes: tuple[float, ...]
    offsets: tuple[float, ...]

    def region(self, a: float) -> int:
        """Region containing ``a`` (a bound belongs to the region below it, as in the kernel)."""
        return bisect.bisect_left(self.bounds, a)

    def value(self, a: float) -> float:
        """Value of the law itself (region from ``a``)."""
        r = bisect.bisect_left(self.bounds, a)
        return self.slopes[r] * a + self.offsets[r]

    def inverse(self, v: float) -> float:
        """``a`` with ``value(a) = v`` (strictly increasing laws only)."""
        vals = [self.slopes[r] * b + self.offsets[r] for r, b in enumerate(self.bounds)]
        r = bisect.bisect_left(vals, v)
        return (v - self.offsets[r]) / self.slopes[r]


def _merge(xs: list[float], slopes: list[float], offsets: list[float]) -> PwlLaw:
    """Drop knees where the law does not actually bend."""
    b: list[float] = []
    s = [slopes[0]]
    o = [offsets[0]]
    for i, x in enumerate(xs):
        s1, o1 = slopes[i + 1], offsets[i + 1]
        if math.isclose(s1, s[-1], rel_tol=1e-12, abs_tol=1e-12) and math.isclose(
            o1, o[-1], rel_tol=1e-12, abs_tol=1e-9
        ):
            continue
        b.append(x)
        s.append(s1)
        o.append(o1)
    return PwlLaw(tuple(b), tuple(s), tuple(o))


def law_from_table(
    xs: Sequence[float], ys: Sequence[float], *, extrapolation: str, odd: bool
) -> PwlLaw:
    """Law of a table (``clamp``: end values held; ``linear``: end segments continued;
    ``odd``: the table gives ``a >= 0``, mirrored to ``a < 0``)."""
    x = [float(v) for v in xs]
    y = [float(v) for v in ys]
    if odd:
        if x[0] != 0.0 or y[0] != 0.0:
            raise ValueError("odd table must start at (0, 0)")
        x = [-v for v in reversed(x[1:])] + x
        y = [-v for v in reversed(y[1:])] + y
    if len(x) == 1:
        return PwlLaw((), (0.0,), (y[0],))
    seg_s = [(y[i + 1] - y[i]) / (x[i + 1] - x[i]) for i in range(len(x) - 1)]
    seg_o = [y[i] - seg_s[i] * x[i] for i in range(len(x) - 1)]
    if extrapolation == "clamp":
        slopes = [0.0, *seg_s, 0.0]
        offsets = [y[0], *seg_o, y[-1]]
        knees = x
    elif extrapolation == "linear":
        slopes, offsets, knees = seg_s, seg_o, x[1:-1]
    else:
        raise ValueError(f"extrapolation {extrapolation!r}")
    return _merge(list(knees), slopes, offsets)


def deadzone_law(g: float, k: float) -> PwlLaw:
    """``k (a - g)`` above ``g``, 0 inside, ``k (a + g)`` below ``-g``."""
    return PwlLaw((-g, g), (k, 0.0, k), (k * g, 0.0, -k * g))


# ------------------------------------------------------------------------------------------------
# inputs: pieces between breakpoints
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Piece:
    """Inputs on the piece that starts at ``t_ref``: ``u(t) = a + b (t - t_ref)`` (+ sines)."""

    t_ref: float
    a: tuple[float, float, float]
    b: tuple[float, float, float]
    sines: tuple[tuple[int, float, float, float, float], ...]  # (input, A, omega, phase, t0)

    def u(self, t: float) -> tuple[float, float, float]:
        d = t - self.t_ref
        u = [self.a[i] + self.b[i] * d for i in range(3)]
        for i, amp, om, ph, t0 in self.sines:
            u[i] += amp * math.sin(om * (t - t0) + ph)
        return (u[0], u[1], u[2])


class InputPieces:
    """The three input signals (throttle, pedal, brake) split at their breakpoints."""

    def __init__(self, inputs: Mapping[str, Signal]):
        missing = set(INPUT_NAMES) - set(inputs)
        if missing:
            raise KeyError(f"missing inputs {sorted(missing)}")
        self.signals = tuple(inputs[n] for n in INPUT_NAMES)

    def breakpoints(self, t0: float, t1: float) -> list[float]:
        return sorted({b for s in self.signals for b in s.breakpoints if t0 < b < t1})

    def piece(self, t_ref: float) -> Piece:
        a: list[float] = []
        b: list[float] = []
        sines = []
        for i, s in enumerate(self.signals):
            ts, vs = s.times, s.values
            k = bisect.bisect_right(ts, t_ref) - 1
            if k < 0:
                aa, bb = vs[0], 0.0
            elif k >= len(ts) - 1:
                aa, bb = vs[-1], 0.0
            elif ts[k + 1] <= ts[k]:
                aa, bb = vs[k + 1], 0.0
            else:
                bb = (vs[k + 1] - vs[k]) / (ts[k + 1] - ts[k])
                aa = vs[k] + bb * (t_ref - ts[k])
            a.append(float(aa))
            b.append(float(bb))
            for sw in s.sines:
                if t_ref >= sw.t_start:
                    sines.append((i, sw.amplitude, sw.omega, sw.phase, sw.t_start))
        return Piece(float(t_ref), (a[0], a[1], a[2]), (b[0], b[1], b[2]), tuple(sines))

    def stops(self, t0: float, t1: float, pedal_knots: Sequence[float]) -> list[float]:
        """Input breakpoints and the times the pedal crosses a knot of the pedal map."""
        if self.signals[1].sines:
            raise NotImplementedError("pedal signals with sines (knee times not linear)")
        bps = self.breakpoints(t0, t1)
        out = set(bps)
        starts = [t0, *bps]
        ends = [*bps, t1]
        for ta, tb in zip(starts, ends, strict=True):
            p = self.piece(ta)
            if p.b[1] == 0.0:
                continue
            for xk in pedal_knots:
                tk = ta + (xk - p.a[1]) / p.b[1]
                if ta < tk < tb:
                    out.add(tk)
        return sorted(out)


# ------------------------------------------------------------------------------------------------
# the flat model: geometry shared by both right-hand sides
# ------------------------------------------------------------------------------------------------


class FlatGeometry:
    """Bodies, constraint rows, capacities and tables of the full drivetrain (from parameters).

    Relative speeds (rows of ``G``): clutch ``w_engine - w_disc``; damper friction ``w_disc -
    w_primary``; tyre ``w_tread - v / R_p``; engine ``w_engine``; brake ``w_hub``; vehicle ``v``.
    Stuck torques / capacities are in the units of :mod:`drivetrain_ctrl.reference` (tyre: N m at
    the tread; vehicle: N).
    """

    def __init__(self, params: DrivetrainParams, gear: int, slope: float):
        p = params
        self.params, self.gear, self.slope = p, gear, float(slope)
        if p.engine.torque_model != "linear":
            raise NotImplementedError("baselines support engine.torque_model = 'linear' only")
        if len(p.clutch.mu_table.x) != 1:
            raise NotImplementedError("baselines support a flat clutch mu table only")
        eng, clu, dmp, gbx, drl, veh = (
            p.engine,
            p.clutch,
            p.damper,
            p.gearbox,
            p.driveline,
            p.vehicle,
        )
        self.tau_r = gbx.tau_r(gear)
        self.D_c = gbx.D_c
        self.R_p = drl.R_p
        self.g34 = gbx.g34_wheel * self.tau_r * self.D_c
        self.M = np.array(
            [
                eng.J1,
                clu.J2,
                dmp.J3,
                gbx.J4,
                (1.0 - drl.tread_fraction) * drl.J5,
                drl.tread_fraction * drl.J5,
                veh.M_v,
            ]
        )
        self.Minv = 1.0 / self.M
        G = np.zeros((6, N_BODIES))
        G[0, 0], G[0, 1] = 1.0, -1.0
        G[1, 1], G[1, 2] = 1.0, -1.0
        G[2, 5], G[2, 6] = 1.0, -1.0 / self.R_p
        G[3, 0] = 1.0
        G[4, 4] = 1.0
        G[5, 6] = 1.0
        self.G = G
        self.ground = (False, False, False, True, True, True)
        self.ground_body = (-1, -1, -1, 0, 4, 6)
        self.mu0 = float(clu.mu_table.y[0])
        self.k_v = float(veh.f_r * veh.M_v * GRAVITY * math.cos(self.slope))
        self.k_w = float(
            veh.mu_tyre * veh.drive_axle_load_fraction * veh.M_v * GRAVITY * math.cos(self.slope)
        )
        self.exists = (True, dmp.k23 > 0.0, True, eng.c1 > 0.0, True, self.k_v > 0.0)
        self.static = np.array(
            [
                clu.static_ratio,
                dmp.static_ratio,
                veh.tyre_static_ratio,
                eng.static_ratio,
                p.brake.static_ratio,
                veh.rolling_static_ratio,
            ]
        )
        sp = dmp.spring
        self.laws = (
            law_from_table(sp.x, sp.y, extrapolation="linear", odd=True),
            deadzone_law(self.g34, 1.0),
            law_from_table(  # clutch capacity k12 [N m] = k12_max * shape(x_c)
                clu.pedal_map.x,
                tuple(clu.k12_max * s for s in clu.pedal_map.y),
                extrapolation="clamp",
                odd=False,
            ),
        )
        self.pedal_knots = self.laws[2].bounds
        self._pl: dict[tuple[bool, ...], tuple[F64 | None, F64]] = {}

    # -- tables ---------------------------------------------------------------------------------
    def table_args(self, x: F64, u: Sequence[float]) -> tuple[float, float, float]:
        return (float(x[7]), float(x[8]), float(u[1]))

    def table_rates(self, x: F64, ub: Sequence[float]) -> tuple[float, float, float]:
        return (
            float(x[1] - x[2]),
            float(x[2] - self.tau_r * x[3]),
            float(ub[1]),
        )

    def table_region_names(self, k: int) -> tuple[str, ...]:
        n = len(self.laws[k].bounds) + 1
        return BACKLASH_REGIONS if k == 1 else tuple(f"segment {r}" for r in range(n))

    # -- elements -------------------------------------------------------------------------------
    def rel_speeds(self, x: F64) -> F64:
        return self.G @ x[:N_BODIES]

    def capacities(self, u: Sequence[float], reg: Sequence[int]) -> F64:
        """Kinetic capacity at zero slip of every element (0 if it does not exist)."""
        p = self.params
        law = self.laws[2]
        r = reg[2]
        k12 = self.mu0 * max(law.slopes[r] * u[1] + law.offsets[r], 0.0)
        caps = np.array(
            [
                k12,
                p.damper.k23,
                self.k_w * self.R_p,
                p.engine.c1,
                max(float(u[2]), 0.0),
                self.k_v,
            ]
        )
        return np.where(self.exists, caps, 0.0)

    def capacity_rates(self, ub: Sequence[float], reg: Sequence[int]) -> F64:
        law = self.laws[2]
        return np.array(
            [self.mu0 * law.slopes[reg[2]] * ub[1], 0.0, 0.0, 0.0, float(ub[2]), 0.0]
        ) * np.array(self.exists, dtype=float)

    def mode_matrices(self, modes: Sequence[int]) -> tuple[F64 | None, F64]:
        """``P`` (None when nothing is stuck: ``a = tau / M``) and ``Lam`` (6, 7)."""
        key = tuple(m == STUCK for m in modes)
        hit = self._pl.get(key)
        if hit is not None:
            return hit
        idx = [f for f in range(6) if key[f]]
        Lam = np.zeros((6, N_BODIES))
        if not idx:
            out: tuple[F64 | None, F64] = (None, Lam)
        else:
            G = self.G[idx]
            GM = G * self.Minv
            S = GM @ G.T
            L = np.linalg.lstsq(S, GM, rcond=None)[0]
            P = np.diag(self.Minv) - GM.T @ L
            Lam[idx] = L
            out = (P, Lam)
        self._pl[key] = out
        return out

    def project(self, x: F64, which: Sequence[int]) -> None:
        """Momentum-preserving projection of the speeds onto ``w_f = 0`` for ``f in which``:
        ``x += -M^-1 G^T (G M^-1 G^T)^+ G x`` (bodies joined by a stuck element are merged at
        their inertia-weighted mean speed)."""
        if not which:
            return
        G = self.G[list(which)]
        GM = G * self.Minv
        lam = np.linalg.lstsq(GM @ G.T, G @ x[:N_BODIES], rcond=None)[0]
        x[:N_BODIES] -= GM.T @ lam
        for f in which:
            if self.ground[f]:
                x[self.ground_body[f]] = 0.0

    def mode_dict(self, modes: Sequence[int]) -> dict[str, str]:
        return {n: FRICTION_MODE_NAMES[n][m] for n, m in zip(ELEMENTS, modes, strict=True)}

    # -- to be provided -------------------------------------------------------------------------
    def accel_lam(
        self, x: F64, u: Sequence[float], modes: Sequence[int], reg: Sequence[int]
    ) -> tuple[F64, F64]:
        """Body accelerations (7,) and stuck torques (6,) in ``modes`` with regions ``reg``."""
        raise NotImplementedError

    def make_rhs(
        self, modes: Sequence[int], reg: Sequence[int], piece: Piece
    ) -> Callable[[float, F64], F64]:
        raise NotImplementedError


class FastFlatSystem(FlatGeometry):
    """The flat model's equations written with scalars (region-fixed laws, cached P / Lam)."""

    def _forces(self, modes: Sequence[int], reg: Sequence[int]) -> Callable[..., list[float]]:
        """``tau(x_list, throttle, pedal, brake)``: generalised forces on the 7 bodies, kinetic
        frictions included, stuck torques excluded."""
        p = self.params
        eng, clu, dmp, gbx, drl, veh = (
            p.engine,
            p.clutch,
            p.damper,
            p.gearbox,
            p.driveline,
            p.vehicle,
        )
        s_cl, s_d, s_t, s_e, s_b, s_v = (
            _SIGN[m] if ok else 0.0 for m, ok in zip(modes, self.exists, strict=True)
        )
        ld, lb, lp = self.laws
        sd, od = ld.slopes[reg[0]], ld.offsets[reg[0]]
        h34 = gbx.h34
        sb, ob = h34 * lb.slopes[reg[1]], h34 * lb.offsets[reg[1]]
        sp, op = self.mu0 * lp.slopes[reg[2]], self.mu0 * lp.offsets[reg[2]]
        K, b1, c1 = eng.K, eng.b1, eng.c1
        b2, b3, b4, b5 = clu.b2, dmp.b3, gbx.b4, drl.b5
        fr_d = s_d * dmp.k23
        b34, taur, invDc = gbx.b34, self.tau_r, 1.0 / self.D_c
        if gbx.backlash_damping == "contact" and self.g34 > 0.0 and reg[1] == 1:
            b34 = 0.0  # the mesh damping acts only in contact: none in the gap (region 1)
        h45w, b45, h56, b56 = drl.h45 / self.D_c, drl.b45, drl.h56, drl.b56
        T_t = s_t * self.k_w * self.R_p
        invR = 1.0 / self.R_p
        bv = veh.b_v
        cq = 0.5 * veh.rho_a * veh.C_x * veh.S
        ld6 = -veh.M_v * GRAVITY * math.sin(self.slope) - s_v * self.k_v
        fr_e = s_e * c1

        def forces(xl: list[float], thr: float, ped: float, brk: float) -> list[float]:
            w1, w2, w3, ws, wh, wt, v, qd, qb, qa, qth = xl[:11]
            lag = xl[12]
            T_cl = s_cl * (sp * ped + op)
            T_d = sd * qd + od + fr_d
            T_g = sb * qb + ob + b34 * (w3 - taur * ws)
            T_aw = h45w * qa + b45 * (ws * invDc - wh)
            T_th = h56 * qth + b56 * (wh - wt)
            return [
                K * lag - b1 * w1 - fr_e - T_cl,
                -b2 * w2 + T_cl - T_d,
                -b3 * w3 + T_d - T_g,
                -b4 * ws + taur * T_g - T_aw * invDc,
                -b5 * wh + T_aw - T_th - s_b * brk,
                T_th - T_t,
                -bv * v - cq * v * abs(v) + T_t * invR + ld6,
            ]

        return forces

    def accel_lam(
        self, x: F64, u: Sequence[float], modes: Sequence[int], reg: Sequence[int]
    ) -> tuple[F64, F64]:
        tau = np.array(self._forces(modes, reg)(x.tolist(), u[0], u[1], u[2]))
        P, Lam = self.mode_matrices(modes)
        acc = tau * self.Minv if P is None else P @ tau
        return acc, Lam @ tau

    def make_lam(
        self, modes: Sequence[int], reg: Sequence[int], piece: Piece
    ) -> Callable[[float, F64], F64]:
        forces = self._forces(modes, reg)
        _, Lam = self.mode_matrices(modes)

        def lam(t: float, x: F64) -> F64:
            u = piece.u(t)
            return Lam @ np.array(forces(x.tolist(), u[0], u[1], u[2]))

        return lam

    def make_rhs(
        self, modes: Sequence[int], reg: Sequence[int], piece: Piece
    ) -> Callable[[float, F64], F64]:
        forces = self._forces(modes, reg)
        P, _ = self.mode_matrices(modes)
        m0, m1, m2, m3, m4, m5, m6 = self.Minv.tolist()
        taur, Dc = self.tau_r, self.D_c
        inv_taup = 1.0 / self.params.engine.tau_p
        tref = piece.t_ref
        a0, a1, a2 = piece.a
        c0, c1, c2 = piece.b
        has_sines = bool(piece.sines)
        empty = np.empty

        def rhs(t: float, x: F64) -> F64:
            xl = x.tolist()
            if has_sines:
                thr, ped, brk = piece.u(t)
            else:
                d = t - tref
                thr, ped, brk = a0 + c0 * d, a1 + c1 * d, a2 + c2 * d
            tau = forces(xl, thr, ped, brk)
            out = empty(N_STATES)
            if P is None:
                out[:7] = (
                    tau[0] * m0,
                    tau[1] * m1,
                    tau[2] * m2,
                    tau[3] * m3,
                    tau[4] * m4,
                    tau[5] * m5,
                    tau[6] * m6,
                )
            else:
                out[:7] = P @ tau
            out[7:] = (
                xl[1] - xl[2],
                xl[2] - taur * xl[3],
                xl[3] - Dc * xl[4],
                xl[4] - xl[5],
                xl[6],
                (thr - xl[12]) * inv_taup,
            )
            return out

        return rhs

    # -- smoothed friction ------------------------------------------------------------------------
    def make_tanh_rhs(self, piece: Piece, eps: float) -> Callable[[float, F64], F64]:
        """Every Coulomb element ``k sgn(w)`` replaced by ``k tanh(w / eps)``; no stuck modes; the
        laws evaluated as they are (their kinks included)."""
        p = self.params
        eng, clu, dmp, gbx, drl, veh = (
            p.engine,
            p.clutch,
            p.damper,
            p.gearbox,
            p.driveline,
            p.vehicle,
        )
        ld, lb, lp = self.laws
        K, b1 = eng.K, eng.b1
        c1 = eng.c1 if self.exists[3] else 0.0
        k23 = dmp.k23 if self.exists[1] else 0.0
        kv = self.k_v if self.exists[5] else 0.0
        ktR = self.k_w * self.R_p
        b2, b3, b4, b5 = clu.b2, dmp.b3, gbx.b4, drl.b5
        h34, b34, taur, Dc, invDc = gbx.h34, gbx.b34, self.tau_r, self.D_c, 1.0 / self.D_c
        h45w, b45, h56, b56 = drl.h45 / self.D_c, drl.b45, drl.h56, drl.b56
        invR = 1.0 / self.R_p
        bv = veh.b_v
        cq = 0.5 * veh.rho_a * veh.C_x * veh.S
        load = -veh.M_v * GRAVITY * math.sin(self.slope)
        mu0 = self.mu0
        m0, m1, m2, m3, m4, m5, m6 = self.Minv.tolist()
        inv_taup = 1.0 / eng.tau_p
        inv_eps = 1.0 / eps
        tanh = math.tanh
        phi, dz, kmap = ld.value, lb.value, lp.value
        u_of = piece.u
        empty = np.empty

        def rhs(t: float, x: F64) -> F64:
            w1, w2, w3, ws, wh, wt, v, qd, qb, qa, qth, _pos, lag = x.tolist()
            thr, ped, brk = u_of(t)
            T_cl = mu0 * kmap(ped) * tanh((w1 - w2) * inv_eps)
            T_d = phi(qd) + k23 * tanh((w2 - w3) * inv_eps)
            T_g = h34 * dz(qb) + b34 * (w3 - taur * ws)
            T_aw = h45w * qa + b45 * (ws * invDc - wh)
            T_th = h56 * qth + b56 * (wh - wt)
            T_t = ktR * tanh((wt - v * invR) * inv_eps)
            out = empty(N_STATES)
            out[:] = (
                (K * lag - b1 * w1 - c1 * tanh(w1 * inv_eps) - T_cl) * m0,
                (-b2 * w2 + T_cl - T_d) * m1,
                (-b3 * w3 + T_d - T_g) * m2,
                (-b4 * ws + taur * T_g - T_aw * invDc) * m3,
                (-b5 * wh + T_aw - T_th - max(brk, 0.0) * tanh(wh * inv_eps)) * m4,
                (T_th - T_t) * m5,
                (-bv * v - cq * v * abs(v) + load + T_t * invR - kv * tanh(v * inv_eps)) * m6,
                w2 - w3,
                w3 - taur * ws,
                ws - Dc * wh,
                wh - wt,
                v,
                (thr - lag) * inv_taup,
            )
            return out

        return rhs


class LiteralFlatSystem(FlatGeometry):
    """Right-hand side and stuck torques by ``full_reference_rhs`` / ``full_reference_stuck_torques``
    themselves. The regions are fixed by substituting the twists: the damper twist by the inverse
    of ``phi_e`` of the region's affine value, the backlash twist by one giving the region's dead
    zone value; the pedal stays in its region by the knee stops."""

    def _subst(self, x: F64, reg: Sequence[int]) -> F64:
        ld, lb, _ = self.laws
        q = float(x[7])
        r = reg[0]
        lo = ld.bounds[r - 1] if r > 0 else -math.inf
        hi = ld.bounds[r] if r < len(ld.bounds) else math.inf
        qb = float(x[8])
        g = self.g34
        rb = reg[1]
        need_d = not (lo <= q <= hi)
        need_b = (rb == 2 and qb < g) or (rb == 0 and qb > -g) or (rb == 1 and abs(qb) > g)
        if not (need_d or need_b):
            return x
        x = x.copy()
        if need_d:
            x[7] = ld.inverse(ld.slopes[r] * q + ld.offsets[r])
        if need_b:
            x[8] = qb - 2 * g if rb == 2 else (qb + 2 * g if rb == 0 else 0.0)
        return x

    def accel_lam(
        self, x: F64, u: Sequence[float], modes: Sequence[int], reg: Sequence[int]
    ) -> tuple[F64, F64]:
        xs = self._subst(np.asarray(x, dtype=float), reg)
        md = self.mode_dict(modes)
        uu = np.array(u, dtype=float)
        xd = full_reference_rhs(self.params, self.gear, self.slope, xs, uu, md)
        st = full_reference_stuck_torques(self.params, self.gear, self.slope, xs, uu, md)
        lam = np.array([st.get(n, 0.0) for n in ELEMENTS])
        return xd[:N_BODIES], lam

    def make_lam(
        self, modes: Sequence[int], reg: Sequence[int], piece: Piece
    ) -> Callable[[float, F64], F64]:
        md = self.mode_dict(modes)
        p, gear, slope = self.params, self.gear, self.slope

        def lam(t: float, x: F64) -> F64:
            st = full_reference_stuck_torques(
                p, gear, slope, self._subst(x, reg), np.array(piece.u(t)), md
            )
            return np.array([st.get(n, 0.0) for n in ELEMENTS])

        return lam

    def make_rhs(
        self, modes: Sequence[int], reg: Sequence[int], piece: Piece
    ) -> Callable[[float, F64], F64]:
        md = self.mode_dict(modes)
        p, gear, slope = self.params, self.gear, self.slope

        def rhs(t: float, x: F64) -> F64:
            return full_reference_rhs(p, gear, slope, self._subst(x, reg), np.array(piece.u(t)), md)

        return rhs


# ------------------------------------------------------------------------------------------------
# mode decision
# ------------------------------------------------------------------------------------------------


def _regions(sys: FlatGeometry, x: F64, u: Sequence[float], ub: Sequence[float]) -> tuple[int, ...]:
    """Region of each table; an argument on a knee (within 1e-10) goes to the side it moves to."""
    args = sys.table_args(x, u)
    rates = sys.table_rates(x, ub)
    out = []
    for k, law in enumerate(sys.laws):
        a, da = args[k], rates[k]
        r = law.region(a)
        for i, b in enumerate(law.bounds):
            if abs(a - b) <= 1e-10:
                # not moving: the bound belongs to the region below (as in the kernel)
                r = i + 1 if da > 0.0 else i
                break
        out.append(r)
    return tuple(out)


def _violation(
    sys: FlatGeometry,
    x: F64,
    u: Sequence[float],
    trial: Sequence[int],
    reg: Sequence[int],
    check: Sequence[int],
    caps: F64,
) -> float:
    acc, lam = sys.accel_lam(x, u, trial, reg)
    dw = sys.G @ acc
    viol = 0.0
    for f in check:
        if trial[f] == STUCK:
            lim = sys.static[f] * caps[f]
            ex = abs(lam[f]) - lim * (1.0 + 1e-12) - 1e-12
            if ex > 0.0:
                viol += ex / (lim + 1e-300)
        else:
            s = _SIGN[trial[f]]
            if dw[f] * s <= 0.0:
                viol += 1.0 + abs(dw[f])
    return viol


def decide(
    sys: FlatGeometry,
    t: float,
    x: F64,
    piece: Piece,
    prev_modes: Sequence[int] | None,
    prev_reg: Sequence[int] | None,
    forced: Mapping[int, int] | None = None,
    tol_w: float = 1e-9,
) -> tuple[tuple[int, ...], tuple[int, ...], bool]:
    """Modes and regions at ``(t, x)`` (``x`` is projected in place). ``forced`` maps elements
    that must break loose to their slip mode. Returns (modes, regions, consistent).

    The decision depends on the state only; ``prev_modes`` / ``prev_reg`` are not used (kept for
    the call sites' readability)."""
    u = piece.u(t)
    ub = piece.b
    forced = dict(forced or {})
    consistent = True
    for _rep in range(10):
        reg = _regions(sys, x, u, ub)
        caps = sys.capacities(u, reg)
        rates = sys.capacity_rates(ub, reg)
        w = sys.rel_speeds(x)
        modes = [OPEN] * 6
        cand: list[int] = []
        near: list[int] = []
        for f in range(6):
            if not sys.exists[f]:
                continue
            if caps[f] <= 1e-12 and not rates[f] > 0.0:
                modes[f] = OPEN
            elif abs(w[f]) > tol_w:
                modes[f] = SLIP_POS if w[f] > 0 else SLIP_NEG
            else:
                near.append(f)
                if f in forced:
                    modes[f] = forced[f]
                else:
                    cand.append(f)
        sys.project(x, near)
        reg = _regions(sys, x, u, ub)
        caps = sys.capacities(u, reg)
        best, best_v = None, math.inf
        if cand:
            combos = sorted(
                itertools.product((STUCK, SLIP_POS, SLIP_NEG), repeat=len(cand)),
                key=lambda c: -sum(1 for m in c if m == STUCK),
            )
            for c in combos:
                trial = list(modes)
                for f, m in zip(cand, c, strict=True):
                    trial[f] = m
                v = _violation(sys, x, u, trial, reg, cand, caps)
                if v == 0.0:
                    best, best_v = trial, 0.0
                    break
                if v < best_v:
                    best, best_v = trial, v
            assert best is not None
            modes = best
            consistent = best_v == 0.0
        # every stuck element must hold (a break-away forced elsewhere can overload it)
        _, lam = sys.accel_lam(x, u, modes, reg)
        over = [
            f
            for f in range(6)
            if modes[f] == STUCK and abs(lam[f]) > sys.static[f] * caps[f] * (1 + 1e-9) + 1e-9
        ]
        if not over:
            return tuple(modes), reg, consistent
        for f in over:
            forced[f] = SLIP_POS if lam[f] > 0 else SLIP_NEG
    return tuple(modes), reg, False


# ------------------------------------------------------------------------------------------------
# guards
# ------------------------------------------------------------------------------------------------


class Guards:
    """Guard functions of one segment (starting at ``t0``) for ``solve_ivp`` (terminal, direction
    -1); all values are computed together, once per ``(t, y)``."""

    def __init__(
        self,
        sys: FlatGeometry,
        modes: Sequence[int],
        reg: Sequence[int],
        piece: Piece,
        t0: float | None = None,
    ):
        self.kinds: list[tuple[str, int]] = []
        for f, m in enumerate(modes):
            if m in (SLIP_POS, SLIP_NEG):
                self.kinds.append(("slip", f))
            elif m == STUCK:
                self.kinds.append(("stuck", f))
        for k in (0, 1):  # state-dependent tables (the pedal map is handled by time stops)
            law = sys.laws[k]
            if reg[k] > 0:
                self.kinds.append(("lo", k))
            if reg[k] < len(law.bounds):
                self.kinds.append(("hi", k))
        self.sys, self.modes, self.reg, self.piece = sys, tuple(modes), tuple(reg), piece
        self.t0 = piece.t_ref if t0 is None else t0
        self.lam_fn = sys.make_lam(modes, reg, piece) if STUCK in modes else None
        self._t: float | None = None
        self._y: F64 | None = None
        self._g: F64 = np.zeros(len(self.kinds))
        self.events = [self._make(i) for i in range(len(self.kinds))]

    def values(self, t: float, y: F64) -> F64:
        if self._t == t and self._y is not None and np.array_equal(self._y, y):
            return self._g
        g = self.compute(t, y)
        self._t, self._y, self._g = t, y.copy(), g
        return g

    def compute(self, t: float, y: F64) -> F64:
        """Guard values at ``(t, y)`` (no cache)."""
        sys = self.sys
        w = sys.G @ y[:N_BODIES]
        lam = self.lam_fn(t, y) if self.lam_fn is not None else None
        caps = None
        if lam is not None:
            caps = sys.capacities(self.piece.u(t), self.reg)
        g = np.empty(len(self.kinds))
        for i, (kind, j) in enumerate(self.kinds):
            if kind == "slip":
                g[i] = w[j] if self.modes[j] == SLIP_POS else -w[j]
            elif kind == "stuck":
                assert lam is not None and caps is not None
                g[i] = sys.static[j] * caps[j] - abs(lam[j])
            else:
                law = sys.laws[j]
                a = float(y[7 + j])
                r = self.reg[j]
                g[i] = a - law.bounds[r - 1] if kind == "lo" else law.bounds[r] - a
        if t == self.t0:
            # A guard of a mode just entered starts at 0 (up to round-off): count it as positive at
            # the segment start, so that solve_ivp brackets its first real crossing (its root
            # finder would return the segment start itself if the value there were exactly 0).
            np.maximum(g, 1e-300, out=g)
        return g

    def _make(self, i: int) -> Callable[[float, F64], float]:
        def ev(t: float, y: F64) -> float:
            return float(self.values(t, y)[i])

        ev.terminal = True  # type: ignore[attr-defined]
        ev.direction = -1.0  # type: ignore[attr-defined]
        return ev


# ------------------------------------------------------------------------------------------------
# one segment with the guards also sampled inside each step
# ------------------------------------------------------------------------------------------------

_EPS = float(np.finfo(float).eps)


@dataclass
class _Segment:
    t: F64  # accepted step ends, from the segment start to its end (event or stop)
    y: F64  # (13, n)
    sol: object | None
    status: int  # 0 reached the stop, 1 a guard fired
    fired: list[int]
    nfev: int


def integrate_segment_dense_guards(
    method: str,
    rhs: Callable[[float, F64], F64],
    t0: float,
    t1: float,
    x0: F64,
    guards: Guards,
    *,
    rtol: float,
    atol: float,
    first_step: float | None = None,
    guard_spacing: float = 1e-5,
    max_samples: int = 200,
) -> _Segment:
    """scipy's ``method`` stepper (the one ``solve_ivp`` uses), with every guard checked at the
    step end *and* on the step's dense output every ``guard_spacing`` seconds (at most
    ``max_samples`` points a step): a guard that goes negative and comes back within one step is
    not missed, as it is with ``solve_ivp``'s events (checked at step ends only). The first
    crossing is located by ``brentq`` on the dense output (xtol 4 eps, as ``solve_ivp``)."""
    cls = METHODS[method]
    solver = cls(rhs, t0, x0, t1, rtol=rtol, atol=atol, first_step=first_step)
    ts = [t0]
    ys = [np.array(x0, dtype=float)]
    interps = []
    g_prev = guards.values(t0, ys[0]).copy()
    status, fired = 0, []
    while solver.status == "running":
        solver.step()
        if solver.status == "failed":
            raise RuntimeError(f"{method} failed at t = {solver.t}")
        ta0, tb0 = solver.t_old, solver.t
        dense = solver.dense_output()
        interps.append(dense)
        if guards.kinds:
            n = min(max_samples, int(math.ceil((tb0 - ta0) / guard_spacing)) - 1)
            inner = ta0 + (tb0 - ta0) * np.arange(1, n + 1) / (n + 1) if n > 0 else np.empty(0)
            pts_t = [*inner.tolist(), tb0]
            pts_y = [*(dense(inner).T if n > 0 else []), solver.y]
            ta, ga = ta0, g_prev
            hit = None
            for tb, yb in zip(pts_t, pts_y, strict=True):
                gb = guards.compute(tb, yb)
                idx = np.nonzero((ga >= 0.0) & (gb < 0.0))[0]
                if idx.size:
                    roots = []
                    for i in idx:
                        r = brentq(
                            lambda tt, i=i, d=dense: float(guards.compute(tt, d(tt))[i]),
                            ta,
                            tb,
                            xtol=4 * _EPS,
                            rtol=4 * _EPS,
                        )
                        roots.append((r, int(i)))
                    t_hit = min(r for r, _ in roots)
                    hit = (t_hit, [i for r, i in roots if r == t_hit])
                    break
                ta, ga = tb, gb
            if hit is not None:
                t_hit, fired = hit
                ts.append(t_hit)
                ys.append(dense(t_hit))
                status = 1
                break
            g_prev = ga
        ts.append(tb0)
        ys.append(solver.y.copy())
    sol = OdeSolution(np.array(ts), interps) if interps else None
    return _Segment(np.array(ts), np.array(ys).T, sol, status, fired, solver.nfev)


# ------------------------------------------------------------------------------------------------
# runs
# ------------------------------------------------------------------------------------------------


@dataclass
class Run:
    """Output of a scipy run: samples (the integrator's accepted steps), events, dense output."""

    t: F64
    x: F64
    events: list[tuple[float, str, str, str]]
    segments: list[tuple[float, float, object]] = field(default_factory=list)
    nfev: int = 0
    nsteps: int = 0
    wall_s: float = 0.0
    inconsistent: int = 0

    def dense(self, times: F64) -> F64:
        """State at ``times`` from the dense output (right-continuous at segment boundaries)."""
        if not self.segments:
            raise ValueError("run made without dense output")
        starts = np.array([s[0] for s in self.segments])
        idx = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(starts) - 1)
        out = np.empty((len(times), N_STATES))
        for k in np.unique(idx):
            sel = idx == k
            t0, t1, sol = self.segments[k]
            tt = np.clip(times[sel], t0, t1)
            out[sel] = sol(tt).T  # type: ignore[operator]
        return out


def _record(
    sys: FlatGeometry,
    t: float,
    m0: Sequence[int],
    r0: Sequence[int],
    m1: Sequence[int],
    r1: Sequence[int],
    events: list[tuple[float, str, str, str]],
) -> None:
    for f in range(6):
        if m0[f] != m1[f]:
            names = FRICTION_MODE_NAMES[ELEMENTS[f]]
            events.append((t, ELEMENTS[f], names[m0[f]], names[m1[f]]))
    for k in range(3):
        if r0[k] != r1[k]:
            names = sys.table_region_names(k)
            events.append((t, TABLE_NAMES[k], names[r0[k]], names[r1[k]]))


def simulate_events(
    sys: FlatGeometry,
    x0: F64,
    inputs: Mapping[str, Signal],
    t_end: float,
    *,
    method: str = "RK45",
    rtol: float = 1e-6,
    atol: float = 1e-9,
    t0: float = 0.0,
    dense: bool = True,
    tol_w: float = 1e-9,
    max_events: int = 200_000,
    guard_spacing: float | None = None,
) -> Run:
    """Event-driven scipy simulation of the flat model (see the module docstring).

    ``guard_spacing`` None: ``solve_ivp`` with the guards as terminal events (checked at step
    ends); a number [s]: :func:`integrate_segment_dense_guards` (guards also sampled inside each
    step at that spacing), used for the reference.
    """
    tic = time.perf_counter()
    pieces = InputPieces(inputs)
    stops = pieces.stops(t0, t_end, sys.pedal_knots)
    t = float(t0)
    x = np.array(x0, dtype=float)
    piece = pieces.piece(t)
    modes, reg, ok = decide(sys, t, x, piece, None, None, tol_w=tol_w)
    n_bad = 0 if ok else 1
    events: list[tuple[float, str, str, str]] = []
    Ts: list[F64] = []
    Xs: list[F64] = []
    segs: list[tuple[float, float, object]] = []
    nfev = nsteps = 0
    i_stop = 0
    same_t = 0
    first_step: float | None = None
    while t < t_end:
        while i_stop < len(stops) and stops[i_stop] <= t:
            i_stop += 1
        t_stop = stops[i_stop] if i_stop < len(stops) else t_end
        rhs = sys.make_rhs(modes, reg, piece)
        guards = Guards(sys, modes, reg, piece, t)
        fs = None if first_step is None else min(first_step, t_stop - t)
        if guard_spacing is None:
            sol = solve_ivp(
                rhs,
                (t, t_stop),
                x,
                method=method,
                rtol=rtol,
                atol=atol,
                events=guards.events or None,
                dense_output=dense,
                first_step=fs,
            )
            if sol.status < 0:
                raise RuntimeError(f"solve_ivp failed at t = {t}: {sol.message}")
            seg_t, seg_y, seg_sol, status = sol.t, sol.y, sol.sol, sol.status
            fired = [i for i, te in enumerate(sol.t_events or []) if te.size]
            nfev += sol.nfev
        else:
            seg = integrate_segment_dense_guards(
                method,
                rhs,
                t,
                t_stop,
                x,
                guards,
                rtol=rtol,
                atol=atol,
                first_step=fs,
                guard_spacing=guard_spacing,
            )
            seg_t, seg_y, seg_sol, status, fired = seg.t, seg.y, seg.sol, seg.status, seg.fired
            nfev += seg.nfev
        nsteps += len(seg_t) - 1
        Ts.append(seg_t[:-1])
        Xs.append(seg_y[:, :-1].T)
        if dense:
            segs.append((t, float(seg_t[-1]), seg_sol))
        t_new = float(seg_t[-1])
        x = seg_y[:, -1].copy()
        forced: dict[int, int] = {}
        if status == 1:
            for i in fired:
                kind, f = guards.kinds[i]
                if kind == "stuck":
                    _, lam = sys.accel_lam(x, piece.u(t_new), modes, reg)
                    forced[f] = SLIP_POS if lam[f] > 0 else SLIP_NEG
        else:
            t_new = t_stop
            if t_new >= t_end:
                t = t_new
                break
            piece = pieces.piece(t_new)
        tiny = t_new - t <= 1e-12 * max(1.0, abs(t))
        same_t = same_t + 1 if tiny else 0
        if same_t > 100:
            raise ZenoError(f"events accumulate at t = {t_new}")
        t = t_new
        m_new, r_new, ok = decide(sys, t, x, piece, modes, reg, forced, tol_w=tol_w)
        n_bad += 0 if ok else 1
        if tiny and status == 1 and m_new == modes and r_new == reg:
            # a spurious root right at the segment start: the first step jumped over a short
            # episode (the dense output then misplaces the crossing); restart with small steps
            first_step = 1e-7 if first_step is None else first_step * 1e-2
            if first_step < 1e-14:
                raise ZenoError(f"events accumulate at t = {t}")
        else:
            first_step = None
        _record(sys, t, modes, reg, m_new, r_new, events)
        modes, reg = m_new, r_new
        if len(events) > max_events:
            raise RuntimeError(f"more than {max_events} events")
    Ts.append(np.array([t]))
    Xs.append(x[None, :])
    wall = time.perf_counter() - tic
    return Run(
        np.concatenate(Ts),
        np.concatenate(Xs),
        events,
        segs,
        nfev,
        nsteps,
        wall,
        n_bad,
    )


def simulate_tanh(
    sys: FastFlatSystem,
    x0: F64,
    inputs: Mapping[str, Signal],
    t_end: float,
    *,
    eps: float = 1e-3,
    method: str = "LSODA",
    rtol: float = 1e-6,
    atol: float = 1e-9,
    t0: float = 0.0,
    dense: bool = False,
) -> Run:
    """The tanh-smoothed model integrated piece by piece between the input breakpoints."""
    tic = time.perf_counter()
    pieces = InputPieces(inputs)
    bps = [*pieces.breakpoints(t0, t_end), t_end]
    t = float(t0)
    x = np.array(x0, dtype=float)
    Ts: list[F64] = []
    Xs: list[F64] = []
    segs: list[tuple[float, float, object]] = []
    nfev = nsteps = 0
    for tb in bps:
        sol = solve_ivp(
            sys.make_tanh_rhs(pieces.piece(t), eps),
            (t, tb),
            x,
            method=method,
            rtol=rtol,
            atol=atol,
            dense_output=dense,
        )
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed at t = {t}: {sol.message}")
        nfev += sol.nfev
        nsteps += len(sol.t) - 1
        Ts.append(sol.t[:-1])
        Xs.append(sol.y[:, :-1].T)
        if dense:
            segs.append((t, tb, sol.sol))
        t = tb
        x = sol.y[:, -1].copy()
    Ts.append(np.array([t]))
    Xs.append(x[None, :])
    return Run(
        np.concatenate(Ts), np.concatenate(Xs), [], segs, nfev, nsteps, time.perf_counter() - tic
    )


# ------------------------------------------------------------------------------------------------
# checks of the fast right-hand side against the flat reference model
# ------------------------------------------------------------------------------------------------


def check_fast_against_reference(
    params: DrivetrainParams, gear: int, slope: float, *, n: int = 300, seed: int = 1
) -> dict[str, float]:
    """Largest relative differences between :class:`FastFlatSystem` and ``full_reference_rhs`` /
    ``full_reference_stuck_torques`` over random states, inputs and mode combinations (regions
    taken from the state, so the region-fixed laws are the laws), and the tanh right-hand side
    against ``full_reference_rhs`` with every element open plus ``k tanh(w / eps)`` torques."""
    rng = np.random.default_rng(seed)
    fast = FastFlatSystem(params, gear, slope)
    eps = 1e-3
    worst = {"rhs": 0.0, "stuck_torques": 0.0, "tanh_rhs": 0.0}  # relative to max |reference|
    for _ in range(n):
        x = np.concatenate(
            [
                rng.normal(0.0, 50.0, 7),
                rng.uniform(-0.25, 0.25, 1),
                rng.uniform(-0.6, 0.6, 1),
                rng.normal(0.0, 0.02, 2),
                rng.uniform(0, 10, 1),
                rng.uniform(0, 1, 1),
            ]
        )
        # some relative speeds near zero, as at a mode change
        if rng.random() < 0.5:
            x[1] = x[0] + rng.normal(0.0, 1e-3)
            x[6] = x[5] * fast.R_p + rng.normal(0.0, 1e-3)
        u = (float(rng.uniform(0, 1)), float(rng.uniform(0.02, 0.12)), float(rng.uniform(0, 500)))
        modes = tuple(int(v) for v in rng.integers(0, 4, 6))
        reg = _regions(fast, x, u, (0.0, 0.0, 0.0))
        piece = Piece(0.0, u, (0.0, 0.0, 0.0), ())
        md = fast.mode_dict(modes)
        ref = full_reference_rhs(params, gear, slope, x, np.array(u), md)
        got = fast.make_rhs(modes, reg, piece)(0.0, x)
        scale = max(float(np.max(np.abs(ref))), 1.0)
        worst["rhs"] = max(worst["rhs"], float(np.max(np.abs(got - ref))) / scale)
        st = full_reference_stuck_torques(params, gear, slope, x, np.array(u), md)
        lam = fast.make_lam(modes, reg, piece)(0.0, x)
        for f, name in enumerate(ELEMENTS):
            if name in st:
                d = abs(lam[f] - st[name]) / max(abs(st[name]), 1.0)
                worst["stuck_torques"] = max(worst["stuck_torques"], float(d))
        # tanh: reference with every element open, plus the smoothed torques through G^T
        md_open = fast.mode_dict((OPEN,) * 6)
        base = full_reference_rhs(params, gear, slope, x, np.array(u), md_open)
        caps = fast.capacities(u, reg)
        w = fast.rel_speeds(x)
        T = caps * np.tanh(w / eps)
        base[:7] -= (fast.G.T @ T) * fast.Minv
        got_t = fast.make_tanh_rhs(piece, eps)(0.0, x)
        worst["tanh_rhs"] = max(
            worst["tanh_rhs"],
            float(np.max(np.abs(got_t - base))) / max(float(np.max(np.abs(base))), 1.0),
        )
    return worst
