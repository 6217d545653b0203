"""Stability certificates by linear matrix inequalities (cvxpy; Clarabel by default).

Each function returns a certificate object: ``feasible`` (a certificate was found **and**
verified numerically on the returned matrices, independently of the solver), the matrices, a
margin (a decay rate, a sector) and ``message``/``summary()`` in words.

**Common quadratic Lyapunov function** (:func:`common_lyapunov`). For a set of modes ``A_i``
(closed loops over operating points, parameter vertices, controller branches), one ``P > 0``
with ``A_i' P + P A_i <= -2 alpha P`` (continuous) or ``A_i' P A_i <= rho^2 P`` (discrete) for
every ``i``: then every switching among the modes, however fast, is stable, and ``V = x' P x``
falls at least as ``exp(-2 alpha t)`` (``rho^(2k)``). The LMI is posed as ``min t`` subject to
``A_i' P + P A_i + 2 alpha P <= t I``, ``P >= 0``, ``trace P = 1`` (a compact set, so the optimum
is attained and ``t* < 0`` exactly when a strict certificate exists); the largest ``alpha`` (the
smallest ``rho``) is found by bisection. When every mode is stable but ``t* >= 0`` at ``alpha =
0``, the certificate says so explicitly: each mode alone is stable, yet no common quadratic
function exists, and switching among the modes may diverge.

**Sector (absolute-stability) certificate** (:func:`sector_certificate`, :func:`largest_sector`).
A Lur'e system ``y = G u``, ``u = -phi(y)``, ``G = (A, B, C, D)`` with ``m`` channels, each
``phi_i`` any (time-varying) nonlinearity in the sector ``[a_i, b_i]``
(``(phi_i - a_i y_i)(phi_i - b_i y_i) <= 0``): with ``xi = (x, w)``, ``w = phi(y)``, the S-procedure
LMI ``dV(xi) + sum_i tau_i sigma_i(xi) <= t |xi|^2`` with ``sigma_i = -(w_i - a_i y_i)(w_i - b_i
y_i) >= 0``, ``tau_i >= 0``, ``V = x' P x`` (continuous: ``dV = 2 x' P xdot``, the KYP form of the
multivariable circle criterion; discrete: ``V(x+) - V(x)``), ``min t`` with ``trace P + sum tau =
1``. A list of systems with one state space gets one common ``P`` (a set of operating points, or
a parameter's values). :func:`largest_sector` grows one end of one channel's sector by bisection
up to the linear (Hurwitz) limit, which bounds every certificate (a linear gain is in the sector).

**The clutch slip loop** (:func:`clutch_sector_certificate`). The falling friction
characteristic ``mu(slip)`` adds the torque ``c dslip`` (``c = k13 mu'``) to the clutch: a rank-one
feedback ``u_f = -k y_f`` from the slip ``y_f`` with gain ``k = -k13 mu'`` (found exactly as the
difference of the loop linearised at two values of ``mu'``), so "stable for every friction
characteristic whose slope lies in ``[mu'_min, 0]``" is the sector ``[0, -k13 mu'_min]``. The
actuator saturation (on the controller's output, before the rate limiter and the actuator) is a
second channel in the sector ``[a_s, 1]`` (``a_s = 0``: any saturation, global; ``a_s > 0``: valid
while the unsaturated command stays within ``1/a_s`` of the headroom). The largest certified
``mu'`` is compared with the judder threshold (the closed form
:func:`~drivetrain_ctrl.linear.clutch.judder_threshold` on the reduced model, and
:func:`~drivetrain_ctrl.linear.clutch.judder_crossing` on any model): the certificate holds for
every nonlinear, time-varying characteristic in the sector, so it can only be smaller.

**Sampled controllers with delay** (:func:`zoh_with_delay`, :func:`sampled_loop`). A discrete
controller on a continuous plant with a zero-order hold and a constant input delay ``tau = (d +
f) dt`` is, at the sampling instants, exactly the discrete (lifted) system ``x+ = Phi x + Gamma0
u[k-d] + Gamma1 u[k-d-1]`` with ``Gamma0 = int_0^{(1-f)dt} e^{As} ds B``, ``Gamma1 = e^{A(1-f)dt}
int_0^{f dt} e^{As} ds B`` and a buffer of past inputs. The certificates above, in discrete time,
apply to it with no approximation for a constant sample period (a clutch loop with a sampled
controller: the friction slope is certified by a common Lyapunov function over a grid of
``mu'`` values, since the slope acts in continuous time between the samples).

Complex Hermitian matrix inequalities do not arise here (every LMI is real symmetric); one that
did would be posed through its real embedding ``[[Re, -Im], [Im, Re]]``.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import control
import cvxpy as cp
import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from ..control.blocks import Controller, require_controller
from ..core.serialize import json_ready
from ..core.validate import did_you_mean, real_number
from ..linear.clutch import clutch_loop, engine_side, judder_crossing, judder_threshold
from ..linear.linearisation import linearise
from ..linear.operating_point import OperatingPoint, require_op

__all__ = [
    "LyapunovCertificate",
    "common_lyapunov",
    "SectorCertificate",
    "sector_certificate",
    "largest_sector",
    "ClutchSectorCertificate",
    "clutch_sector_certificate",
    "zoh_with_delay",
    "sampled_loop",
]

F64 = NDArray[np.float64]

SOLVERS = ("CLARABEL", "SCS")
#: a returned certificate counts only if, in the LMI's (normalised) coordinates, ``P``'s smallest
#: eigenvalue exceeds ``P_TOL`` times its largest and every LMI matrix's largest eigenvalue is
#: below ``-LMI_TOL`` times its norm (numpy, independently of the solver)
P_TOL = 1e-10
LMI_TOL = 1e-12


def _solver(solver: str) -> str:
    if not isinstance(solver, str) or solver.upper() not in SOLVERS:
        raise ValueError(
            f"solver = {solver!r}: must be one of {SOLVERS}" + did_you_mean(str(solver), SOLVERS)
        )
    return solver.upper()


def _solve(prob: cp.Problem, solver: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            prob.solve(solver=solver)
        except cp.error.SolverError:
            prob.solve(solver="SCS", eps=1e-9, max_iters=200_000)


def _sym(M: Any) -> Any:
    return 0.5 * (M + M.T)


# ---------------------------------------------------------------------------------------------
# common quadratic Lyapunov function
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LyapunovCertificate:
    """A common quadratic Lyapunov function for a set of modes (:func:`common_lyapunov`).

    ``feasible``: ``P`` found and verified (every ``A_i' P + P A_i + 2 alpha P`` negative
    definite, resp. ``A_i' P A_i - rho^2 P``, and ``P`` positive definite, by numpy eigenvalues).
    ``P`` (original coordinates, ``trace P = 1``; None if infeasible); ``decay_rate`` alpha [1/s]
    certified for every switching (continuous; for a discrete set ``-ln(rho)/dt``);
    ``contraction`` rho per sample (discrete; None if continuous); ``margin`` the LMI optimum
    ``t*`` at ``alpha = 0`` (``rho = 1``), normalised (< 0: a certificate exists);
    ``mode_abscissae`` the spectral abscissa (continuous, [1/s]) or radius (discrete) of each mode;
    ``modes_stable``; ``names``; ``dt`` [s] (0: continuous); ``message`` the verdict in words.
    """

    feasible: bool
    P: F64 | None
    decay_rate: float | None
    contraction: float | None
    margin: float
    mode_abscissae: tuple[float, ...]
    modes_stable: tuple[bool, ...]
    names: tuple[str, ...]
    dt: float
    message: str

    @property
    def all_modes_stable(self) -> bool:
        return all(self.modes_stable)

    def summary(self) -> str:
        return self.message

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["P"] = None if self.P is None else self.P.tolist()
        return json_ready(d)


def _modes(
    modes: Any, dt: float | None, names: Sequence[str] | None
) -> tuple[list[F64], float, list[str]]:
    if isinstance(modes, np.ndarray) and modes.ndim == 2:
        modes = [modes]
    if isinstance(modes, control.LTI):
        modes = [modes]
    try:
        items = list(modes)
    except TypeError:
        raise TypeError(
            f"modes = {modes!r}: a sequence of square matrices or StateSpace systems"
        ) from None
    if not items:
        raise ValueError("modes = []: needs at least one mode")
    As: list[F64] = []
    dts: set[float] = set()
    for i, M in enumerate(items):
        if isinstance(M, control.LTI):
            S = control.ss(M)
            if S.dt is True:  # discrete, period unknown: not to be judged as continuous
                raise ValueError(f"modes[{i}].dt = True: give the sample period in seconds")
            A = np.asarray(S.A, dtype=float)
            dts.add(0.0 if not S.dt else float(S.dt))
        else:
            try:
                A = np.asarray(M, dtype=float)
            except (TypeError, ValueError):
                raise TypeError(f"modes[{i}] = {M!r}: a square matrix or a StateSpace") from None
        if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
            raise ValueError(
                f"modes[{i}]: a non-empty square matrix is needed, got shape {A.shape}"
            )
        if not np.all(np.isfinite(A)):
            raise ValueError(f"modes[{i}]: has non-finite entries")
        As.append(A)
    n = As[0].shape[0]
    for i, A in enumerate(As):
        if A.shape[0] != n:
            raise ValueError(
                f"modes[{i}] has {A.shape[0]} states, modes[0] {n}: a common Lyapunov function "
                "needs one state space (the same coordinates in every mode)"
            )
    if dt is not None:
        dtv = real_number("dt", dt, lo=0.0, unit="s")
        if dts and dts != {dtv}:
            raise ValueError(f"dt = {dt!r}: the systems given have dt = {sorted(dts)}")
    else:
        if len(dts) > 1:
            raise ValueError(f"modes: mixed sample periods {sorted(dts)}")
        dtv = dts.pop() if dts else 0.0
    if names is None:
        nm = [f"mode {i}" for i in range(len(As))]
    else:
        nm = [str(s) for s in names]
        if len(nm) != len(As):
            raise ValueError(f"names: {len(nm)} names for {len(As)} modes")
    return As, dtv, nm


def _balance(As: list[F64]) -> F64:
    """A diagonal similarity ``T`` (powers of 2) balancing ``sum |A_i|``."""
    Ssum = sum(np.abs(A) for A in As)
    _, (scale, _perm) = sla.matrix_balance(Ssum, permute=False, separate=True)
    return np.diag(scale)


def _coordinates(As: list[F64], discrete: bool, ref: F64 | None = None) -> F64:
    """Coordinates ``x = T x'`` for well-conditioned LMIs: ``T = Tb P0^(-1/2)`` with ``Tb`` a
    balancing similarity and ``P0`` the Lyapunov solution (``A'P0 + P0 A = -I``, discrete
    ``A'P0 A - P0 = -I``) of a stable reference mode (``ref``, else the mean mode, else the
    first stable one), so that ``P' = I`` certifies the reference; balancing alone if none is
    stable. A certificate ``P'`` is ``T^-T P' T^-1`` in the original coordinates."""
    Tb = _balance(As)
    Tbi = np.linalg.inv(Tb)
    cands = ([] if ref is None else [ref]) + [sum(As) / len(As)] + list(As)
    n = As[0].shape[0]
    for A in cands:
        Ab = Tbi @ A @ Tb
        ev = np.linalg.eigvals(Ab)
        if (np.max(np.abs(ev)) >= 1.0) if discrete else (np.max(ev.real) >= 0.0):
            continue
        try:
            if discrete:
                P0 = sla.solve_discrete_lyapunov(Ab.T, np.eye(n))
            else:
                P0 = sla.solve_continuous_lyapunov(Ab.T, -np.eye(n))
        except (np.linalg.LinAlgError, ValueError):
            continue
        w, V = np.linalg.eigh(_sym(P0))
        if not np.all(np.isfinite(w)) or w[0] <= 0:
            continue
        return np.asarray(Tb @ (V * w**-0.5) @ V.T, dtype=float)
    return Tb


def _lyap_lmi(As: list[F64], discrete: bool, rate: float, solver: str) -> tuple[float, F64 | None]:
    """``min t`` s.t. the Lyapunov LMIs ``<= t I``, ``P >= 0``, ``trace P = 1``; returns (t*, P)."""
    n = As[0].shape[0]
    P = cp.Variable((n, n), symmetric=True)
    t = cp.Variable()
    Id = np.eye(n)
    cons = [P >> 0, cp.trace(P) == 1.0]
    for A in As:
        if discrete:
            M = A.T @ P @ A - rate**2 * P
        else:
            M = A.T @ P + P @ A + 2.0 * rate * P
        cons.append(_sym(M) << t * Id)
    prob = cp.Problem(cp.Minimize(t), cons)
    _solve(prob, solver)
    if P.value is None or t.value is None:
        return math.inf, None
    return float(t.value), np.asarray(_sym(P.value), dtype=float)


def _lyap_verify(As: list[F64], P: F64, discrete: bool, rate: float) -> bool:
    """``P`` positive definite and every Lyapunov matrix negative definite (numpy eigenvalues,
    relative tolerances :data:`P_TOL`, :data:`LMI_TOL`)."""
    ev = np.linalg.eigvalsh(_sym(P))
    if ev[0] <= P_TOL * ev[-1]:
        return False
    for A in As:
        M = A.T @ P @ A - rate**2 * P if discrete else A.T @ P + P @ A + 2.0 * rate * P
        M = _sym(M)
        if np.max(np.linalg.eigvalsh(M)) >= -LMI_TOL * max(float(np.linalg.norm(M, 2)), 1e-300):
            return False
    return True


def common_lyapunov(
    modes: Any,
    *,
    dt: float | None = None,
    names: Sequence[str] | None = None,
    decay: bool = True,
    rtol: float = 1e-3,
    solver: str = "CLARABEL",
) -> LyapunovCertificate:
    """A common quadratic Lyapunov function for ``modes`` (module docstring).

    ``modes``: square matrices (one state space) or python-control StateSpace systems (their
    ``A`` and ``dt``). ``dt`` [s]: 0 or None continuous (``A' P + P A < 0``), > 0 discrete
    (``A' P A - P < 0``; taken from the systems if they are discrete). ``decay``: also find the
    largest certified decay rate by bisection to ``rtol``. Returns :class:`LyapunovCertificate`.
    """
    solver = _solver(solver)
    As, dtv, nm = _modes(modes, dt, names)
    rtol = real_number("rtol", rtol, lo=0.0, hi=0.5, lo_open=True)
    discrete = dtv > 0
    if discrete:
        absc = [float(np.max(np.abs(np.linalg.eigvals(A)))) for A in As]
        stable = [a < 1.0 for a in absc]
    else:
        absc = [float(np.max(np.linalg.eigvals(A).real)) for A in As]
        stable = [a < 0.0 for a in absc]
    T = _coordinates(As, discrete)
    Ti = np.linalg.inv(T)
    Ab = [Ti @ A @ T for A in As]
    scale = 1.0 if discrete else max(float(np.linalg.norm(A, 2)) for A in Ab)
    An = [A / scale for A in Ab]

    def back(Pb: F64) -> F64:
        Pn = Ti.T @ Pb @ Ti
        return np.asarray(_sym(Pn / np.trace(Pn)), dtype=float)

    def found(tm: float, Pm: F64 | None, rate: float) -> bool:
        return Pm is not None and tm < 0.0 and _lyap_verify(An, Pm, discrete, rate)

    r0 = 1.0 if discrete else 0.0
    t0, Pb = _lyap_lmi(An, discrete, r0, solver)
    ok = found(t0, Pb, r0)
    if not ok:
        if not all(stable):
            bad = [n for n, s in zip(nm, stable, strict=True) if not s]
            msg = (
                f"No common Lyapunov function: {', '.join(bad)} "
                f"{'is' if len(bad) == 1 else 'are'} not stable on {'its' if len(bad) == 1 else 'their'} own "
                f"({'spectral radius' if discrete else 'spectral abscissa'} "
                f"{max(absc):.4g}{'' if discrete else ' 1/s'})."
            )
        else:
            msg = (
                f"Every one of the {len(As)} modes is stable on its own (largest "
                f"{'spectral radius' if discrete else 'spectral abscissa'} {max(absc):.4g}"
                f"{'' if discrete else ' 1/s'}), but NO common quadratic Lyapunov function exists "
                f"(LMI optimum t* = {t0:.3g} >= 0): switching among the modes is not certified "
                "and may diverge; certify fewer modes together, or slower switching."
            )
        return LyapunovCertificate(
            False, None, None, None, t0, tuple(absc), tuple(stable), tuple(nm), dtv, msg
        )
    assert Pb is not None
    P = back(Pb)
    rate_best = 1.0 if discrete else 0.0
    if decay:
        if discrete:
            lo, hi = max(absc), 1.0  # certified rho in (lo, hi]; hi certified
            while hi - lo > rtol * hi:
                mid = 0.5 * (lo + hi)
                tm, Pm = _lyap_lmi(An, True, mid, solver)
                if found(tm, Pm, mid):
                    assert Pm is not None
                    hi, P = mid, back(Pm)
                else:
                    lo = mid
            rate_best = hi
        else:
            lo, hi = 0.0, -max(absc) / scale
            while hi - lo > rtol * hi:
                mid = 0.5 * (lo + hi)
                tm, Pm = _lyap_lmi(An, False, mid, solver)
                if found(tm, Pm, mid):
                    assert Pm is not None
                    lo, P = mid, back(Pm)
                else:
                    hi = mid
            rate_best = lo * scale
    if discrete:
        rho = rate_best
        alpha = -math.log(rho) / dtv if rho > 0 else math.inf
        msg = (
            f"A common quadratic Lyapunov function V = x'Px exists for the {len(As)} modes "
            f"(discrete, dt = {dtv:g} s): every switching among them is stable, V shrinking at "
            f"least by rho^2 = {rho**2:.4g} per sample (rho = {rho:.4g}, decay rate "
            f"{alpha:.4g} 1/s; the slowest mode alone: {max(absc):.4g})."
        )
        return LyapunovCertificate(
            True, P, alpha, rho, t0, tuple(absc), tuple(stable), tuple(nm), dtv, msg
        )
    msg = (
        f"A common quadratic Lyapunov function V = x'Px exists for the {len(As)} modes: every "
        f"switching among them is stable, with decay rate alpha = {rate_best:.4g} 1/s (V falls at "
        f"least as exp(-2 alpha t); the slowest mode alone decays at {-max(absc):.4g} 1/s)."
    )
    return LyapunovCertificate(
        True, P, rate_best, None, t0, tuple(absc), tuple(stable), tuple(nm), 0.0, msg
    )


# ---------------------------------------------------------------------------------------------
# sector (absolute stability) certificates
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SectorCertificate:
    """Absolute stability of a Lur'e system for nonlinearities in sectors
    (:func:`sector_certificate`, :func:`largest_sector`).

    ``feasible`` (found and verified: the LMI matrix negative definite and ``P`` positive definite
    by numpy eigenvalues); ``sectors`` ``((a_i, b_i), ...)`` certified (or tried);
    ``P`` and ``multipliers`` (tau_i) in the original coordinates; ``margin`` the normalised LMI
    optimum ``t*`` (< 0: certified); ``dt`` [s] (0: continuous). From :func:`largest_sector`:
    ``channel`` and ``end`` grown, ``linear_limit`` the value of that end at which a linear gain
    first destabilises the loop (the Hurwitz limit, an upper bound for any certificate; inf if
    none up to ``search_limit``), ``bisections``. ``message`` in words.
    """

    feasible: bool
    sectors: tuple[tuple[float, float], ...]
    P: F64 | None
    multipliers: tuple[float, ...]
    margin: float
    dt: float
    message: str
    channel: int | None = None
    end: str | None = None
    linear_limit: float | None = None
    bisections: int = 0

    @property
    def certified_end(self) -> float | None:
        """The grown end of the certified sector (:func:`largest_sector`), None otherwise."""
        if self.channel is None or self.end is None:
            return None
        a, b = self.sectors[self.channel]
        return b if self.end == "upper" else a

    def summary(self) -> str:
        return self.message

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["P"] = None if self.P is None else self.P.tolist()
        d["sectors"] = [list(s) for s in self.sectors]
        return json_ready(d)


@dataclass(frozen=True)
class _Lure:
    """Scaled Lur'e data (one or several systems on one state space) and the channel scales
    ``c_i`` (a slope ``k`` of channel ``i`` is ``c_i k`` in the scaled coordinates)."""

    A: tuple[F64, ...]
    B: tuple[F64, ...]
    C: tuple[F64, ...]
    D: tuple[F64, ...]
    c: F64
    T: F64  # state scaling x = T x'
    tscale: float
    dt: float


def _systems(systems: Any) -> tuple[list[control.StateSpace], float]:
    if isinstance(systems, control.LTI):
        systems = [systems]
    try:
        items = [control.ss(s) for s in systems]
    except Exception:
        raise TypeError(
            f"system = {systems!r}: a python-control LTI system or a list of them"
        ) from None
    if not items:
        raise ValueError("system: needs at least one system")
    s0 = items[0]
    dts = set()
    for i, s in enumerate(items):
        if s.ninputs != s.noutputs:
            raise ValueError(
                f"system[{i}]: {s.ninputs} inputs and {s.noutputs} outputs; a Lur'e loop u = -phi(y) "
                "needs one input per output (channel)"
            )
        if (s.nstates, s.ninputs) != (s0.nstates, s0.ninputs):
            raise ValueError(
                f"system[{i}] has {s.nstates} states and {s.ninputs} channels, system[0] "
                f"{s0.nstates} and {s0.ninputs}: a common certificate needs one state space"
            )
        if s.nstates == 0:
            raise ValueError(f"system[{i}]: has no states")
        if s.dt is True:
            raise ValueError(f"system[{i}].dt = True: give the sample period in seconds")
        dts.add(float(s.dt) if s.dt else 0.0)
    if len(dts) > 1:
        raise ValueError(f"system: mixed sample periods {sorted(dts)}")
    return items, dts.pop()


def _check_sectors(sectors: Any, m: int) -> tuple[tuple[float, float], ...]:
    if (
        m == 1
        and isinstance(sectors, tuple | list)
        and len(sectors) == 2
        and not isinstance(sectors[0], tuple | list)
    ):
        sectors = [sectors]
    try:
        out = tuple((float(a), float(b)) for a, b in sectors)
    except (TypeError, ValueError):
        raise ValueError(f"sectors = {sectors!r}: one (a, b) pair per channel") from None
    if len(out) != m:
        raise ValueError(f"sectors = {sectors!r}: {len(out)} pairs for {m} channels")
    for i, (a, b) in enumerate(out):
        real_number(f"sectors[{i}][0]", a)
        real_number(f"sectors[{i}][1]", b)
        if a > b:
            raise ValueError(f"sectors[{i}] = {(a, b)}: needs a <= b")
    return out


def _scaled(
    items: list[control.StateSpace], dt: float, mid: Sequence[float] | None = None
) -> _Lure:
    """The Lur'e data in well-conditioned coordinates (:func:`_coordinates`, the reference the
    loop closed at the sector middles ``mid``), time normalised (continuous) and channels scaled
    to unit input and output norms."""
    As = [np.asarray(s.A, dtype=float) for s in items]
    ref = None
    if mid is not None:
        ref = _closed_with_gains(items[0], mid)
    T = _coordinates(As, bool(dt), ref)
    Ti = np.linalg.inv(T)
    A = [Ti @ s.A @ T for s in items]
    B = [Ti @ s.B for s in items]
    C = [s.C @ T for s in items]
    D = [np.asarray(s.D, dtype=float) for s in items]
    ts = 1.0
    if not dt:
        ts = max(float(np.linalg.norm(a, 2)) for a in A) or 1.0
        A = [a / ts for a in A]
        B = [b / math.sqrt(ts) for b in B]
        C = [c / math.sqrt(ts) for c in C]
    m = B[0].shape[1]
    bn = np.array([max(float(np.linalg.norm(b[:, i])) for b in B) for i in range(m)])
    cn = np.array([max(float(np.linalg.norm(c[i, :])) for c in C) for i in range(m)])
    bn[bn == 0] = 1.0
    cn[cn == 0] = 1.0
    su, sy = 1.0 / bn, cn  # u = Su u', y = Sy y'
    B = [b * su[None, :] for b in B]
    C = [c / sy[:, None] for c in C]
    D = [d * su[None, :] / sy[:, None] for d in D]
    return _Lure(tuple(A), tuple(B), tuple(C), tuple(D), sy / su, T, ts, dt)


def _sector_lmi(
    L: _Lure, sectors: tuple[tuple[float, float], ...], solver: str
) -> tuple[float, F64 | None, F64 | None]:
    n = L.A[0].shape[0]
    m = L.B[0].shape[1]
    P = cp.Variable((n, n), symmetric=True)
    tau = cp.Variable(m, nonneg=True)
    t = cp.Variable()
    cons = [P >> 0, cp.trace(P) + cp.sum(tau) == 1.0]
    Id = np.eye(n + m)
    for A, B, C, D in zip(L.A, L.B, L.C, L.D, strict=True):
        if L.dt:
            AB = np.hstack([A, -B])  # x+ = A x - B w
            M = AB.T @ P @ AB - cp.bmat(
                [[P, np.zeros((n, m))], [np.zeros((m, n)), np.zeros((m, m))]]
            )
        else:
            PA = P @ A
            M = cp.bmat([[PA + PA.T, -P @ B], [-(P @ B).T, np.zeros((m, m))]])
        for i in range(m):
            a, b = sectors[i]
            a, b = a * L.c[i], b * L.c[i]
            ei = np.zeros(m)
            ei[i] = 1.0
            ry = np.concatenate([C[i], -D[i]])  # y_i = ry xi
            rw = np.concatenate([np.zeros(n), ei])  # w_i = rw xi
            ra, rb = rw - a * ry, rw - b * ry
            Q = -0.5 * (np.outer(ra, rb) + np.outer(rb, ra))  # sigma_i = xi' Q xi >= 0
            M = M + tau[i] * Q
        cons.append(_sym(M) << t * Id)
    prob = cp.Problem(cp.Minimize(t), cons)
    _solve(prob, solver)
    if P.value is None or t.value is None or tau.value is None:
        return math.inf, None, None
    return (
        float(t.value),
        np.asarray(_sym(P.value)),
        np.maximum(np.asarray(tau.value, dtype=float), 0.0),
    )


def _sector_verify(L: _Lure, sectors: tuple[tuple[float, float], ...], P: F64, tau: F64) -> bool:
    """``P`` positive definite and every S-procedure matrix negative definite (numpy, relative
    tolerances :data:`P_TOL`, :data:`LMI_TOL`)."""
    n = L.A[0].shape[0]
    m = L.B[0].shape[1]
    ev = np.linalg.eigvalsh(_sym(P))
    if ev[0] <= P_TOL * ev[-1]:
        return False
    for A, B, C, D in zip(L.A, L.B, L.C, L.D, strict=True):
        if L.dt:
            AB = np.hstack([A, -B])
            M = AB.T @ P @ AB
            M[:n, :n] -= P
        else:
            M = np.block([[A.T @ P + P @ A, -P @ B], [-(P @ B).T, np.zeros((m, m))]])
        for i in range(m):
            a, b = sectors[i]
            a, b = a * L.c[i], b * L.c[i]
            ei = np.zeros(m)
            ei[i] = 1.0
            ry = np.concatenate([C[i], -D[i]])
            rw = np.concatenate([np.zeros(n), ei])
            ra, rb = rw - a * ry, rw - b * ry
            M = M - tau[i] * 0.5 * (np.outer(ra, rb) + np.outer(rb, ra))
        M = _sym(M)
        if np.max(np.linalg.eigvalsh(M)) >= -LMI_TOL * max(float(np.linalg.norm(M, 2)), 1e-300):
            return False
    return True


def _sector_try(
    items: list[control.StateSpace],
    dt: float,
    sectors: tuple[tuple[float, float], ...],
    solver: str,
) -> tuple[bool, float, F64 | None, F64 | None]:
    """Solve and verify the sector LMI (coordinates from the loop closed at the sector
    middles); returns (certified, t*, P, tau) with ``P`` (trace 1) and ``tau`` in the original
    coordinates and channel units."""
    L = _scaled(items, dt, [0.5 * (a + b) for a, b in sectors])
    t, P, tau = _sector_lmi(L, sectors, solver)
    if P is None or tau is None or not (t < 0.0 and _sector_verify(L, sectors, P, tau)):
        return False, t, None, None
    Ti = np.linalg.inv(L.T)
    Pn = Ti.T @ P @ Ti
    scale = float(np.trace(Pn))
    # sigma_i in scaled units is sigma_i / c_i in the channel's own units (w' = w/su, y' = y/sy)
    return True, t, np.asarray(_sym(Pn / scale), dtype=float), np.asarray(tau / L.c / scale)


def _describe(sectors: tuple[tuple[float, float], ...]) -> str:
    return ", ".join(f"[{a:.6g}, {b:.6g}]" for a, b in sectors)


def sector_certificate(system: Any, sectors: Any, *, solver: str = "CLARABEL") -> SectorCertificate:
    """Absolute stability of ``y = G u``, ``u = -phi(y)`` for every ``phi_i`` in ``sectors[i] =
    (a_i, b_i)`` (module docstring). ``system``: a python-control LTI (``m`` inputs = ``m``
    outputs, continuous or discrete) or a list of them on one state space (one common ``P``).
    A single channel may give ``sectors`` as one pair. Returns :class:`SectorCertificate`."""
    solver = _solver(solver)
    items, dt = _systems(system)
    secs = _check_sectors(sectors, items[0].ninputs)
    ok, t, P, tau = _sector_try(items, dt, secs, solver)
    if ok:
        assert P is not None and tau is not None
        msg = (
            f"Certified: the loop is stable for every nonlinearity in the sector{'s' if len(secs) > 1 else ''} "
            f"{_describe(secs)} (quadratic Lyapunov function, S-procedure; LMI optimum t* = {t:.3g})."
        )
        return SectorCertificate(True, secs, P, tuple(float(x) for x in tau), t, dt, msg)
    msg = (
        f"Not certified for the sector{'s' if len(secs) > 1 else ''} {_describe(secs)}: no quadratic "
        f"Lyapunov function with the S-procedure (LMI optimum t* = {t:.3g} >= 0); this does not "
        "prove instability."
    )
    return SectorCertificate(False, secs, None, (), t, dt, msg)


def _closed_with_gains(item: control.StateSpace, gains: Sequence[float]) -> F64 | None:
    """State matrix of ``y = G u``, ``u = -diag(k) y`` (None if not well posed)."""
    k = np.diag(np.asarray(gains, dtype=float))
    m = k.shape[0]
    E = np.eye(m) + k @ item.D
    if abs(np.linalg.det(E)) < 1e-12:
        return None
    # u = -k (C x + D u) -> u = -E^-1 k C x
    return np.asarray(item.A - item.B @ np.linalg.solve(E, k @ item.C), dtype=float)


def _linear_stable(items: list[control.StateSpace], gains: Sequence[float], dt: float) -> bool:
    for it in items:
        A = _closed_with_gains(it, gains)
        if A is None:
            return False
        ev = np.linalg.eigvals(A)
        if (np.max(np.abs(ev)) >= 1.0) if dt else (np.max(ev.real) >= 0.0):
            return False
    return True


def _linear_limit(
    items: list[control.StateSpace],
    secs: tuple[tuple[float, float], ...],
    channel: int,
    end: str,
    start: float,
    limit: float,
    dt: float,
) -> float:
    """The first value of the grown end (from ``start`` towards ``limit``) at which some linear
    gain combination (the other channels at their sector ends) destabilises the loop."""
    m = len(secs)
    others = [i for i in range(m) if i != channel]
    combos = (
        [[]]
        if not others
        else [
            list(c)
            for c in np.array(np.meshgrid(*[secs[i] for i in others])).T.reshape(-1, len(others))
        ]
    )

    def stable_at(v: float) -> bool:
        for c in combos:
            g = [0.0] * m
            for i, x in zip(others, c, strict=True):
                g[i] = float(x)
            g[channel] = v
            if not _linear_stable(items, g, dt):
                return False
        return True

    sgn = 1.0 if end == "upper" else -1.0
    span = max(abs(limit - start), 1e-300)
    lo = start
    # geometric search outward, then bisection
    step = span * 1e-6
    hi = None
    while True:
        v = start + sgn * step
        if sgn * (v - limit) > 0:
            v = limit
        if not stable_at(v):
            hi = v
            break
        lo = v
        if v == limit:
            return math.inf
        step *= 2.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if stable_at(mid):
            lo = mid
        else:
            hi = mid
        if abs(hi - lo) <= 1e-9 * max(abs(hi), 1e-300):
            break
    return 0.5 * (lo + hi)


def largest_sector(
    system: Any,
    sectors: Any,
    *,
    channel: int = 0,
    end: str = "upper",
    limit: float | None = None,
    rtol: float = 1e-3,
    solver: str = "CLARABEL",
) -> SectorCertificate:
    """The largest certified sector: ``sectors`` (certified as given, e.g. ``(0, 0)``) with the
    ``end`` (``"upper"`` b or ``"lower"`` a) of channel ``channel`` moved outward by bisection
    (relative tolerance ``rtol``) up to the linear (Hurwitz) limit, or to ``limit`` if that comes
    first (``limit`` None: the linear limit, which must then be finite). Returns the certificate of
    the largest sector found, with ``linear_limit`` for comparison."""
    solver = _solver(solver)
    items, dt = _systems(system)
    m = items[0].ninputs
    secs = _check_sectors(sectors, m)
    if (
        isinstance(channel, bool)
        or not isinstance(channel, int | np.integer)
        or not 0 <= channel < m
    ):
        raise ValueError(f"channel = {channel!r}: must be an integer in [0, {m})")
    if end not in ("upper", "lower"):
        raise ValueError(
            f"end = {end!r}: must be 'upper' or 'lower'"
            + did_you_mean(str(end), ["upper", "lower"])
        )
    rtol = real_number("rtol", rtol, lo=0.0, hi=0.5, lo_open=True)
    a0, b0 = secs[channel]
    start = b0 if end == "upper" else a0
    sgn = 1.0 if end == "upper" else -1.0
    if limit is not None:
        limit = real_number("limit", limit)
        if sgn * (limit - start) <= 0:
            raise ValueError(
                f"limit = {limit!r}: must lie {'above' if sgn > 0 else 'below'} the start {start!r}"
            )

    def with_end(v: float) -> tuple[tuple[float, float], ...]:
        s = list(secs)
        s[channel] = (a0, v) if end == "upper" else (v, b0)
        return tuple(s)

    ok0, t0, P0, tau0 = _sector_try(items, dt, secs, solver)
    if not ok0:
        base = sector_certificate(items, secs, solver=solver)
        return dataclasses.replace(
            base,
            channel=int(channel),
            end=end,
            message="The starting sectors are not certified, so nothing to grow: " + base.message,
        )
    search = limit if limit is not None else start + sgn * 1e9 * max(1.0, abs(start))
    lin = _linear_limit(items, secs, channel, end, start, search, dt)
    if limit is None and not math.isfinite(lin):
        raise ValueError(
            "largest_sector: the loop stays stable for every linear gain on that end up to "
            f"{search:.3g}; give limit (the largest value of interest)"
        )
    target = (
        lin
        if limit is None
        else (limit if sgn * (limit - lin) < 0 or not math.isfinite(lin) else lin)
    )
    lo, hi = start, target
    best = (secs, t0, P0, tau0)
    n_bis = 0
    # the target itself (a limit below the linear limit may be certified)
    okt, tt, Pt, taut = _sector_try(items, dt, with_end(target), solver)
    n_bis += 1
    if okt:
        lo, best = target, (with_end(target), tt, Pt, taut)
    else:
        while abs(hi - lo) > rtol * max(abs(hi), abs(lo), 1e-300):
            mid = 0.5 * (lo + hi)
            okm, tm, Pm, taum = _sector_try(items, dt, with_end(mid), solver)
            n_bis += 1
            if okm:
                lo, best = mid, (with_end(mid), tm, Pm, taum)
            else:
                hi = mid
    s_best, t_best, P_best, tau_best = best
    assert P_best is not None and tau_best is not None
    got = s_best[channel][1] if end == "upper" else s_best[channel][0]
    lin_txt = f"{lin:.6g}" if math.isfinite(lin) else f"none up to {search:.3g}"
    ratio = f" ({got / lin:.1%} of it)" if math.isfinite(lin) and lin != 0 else ""
    msg = (
        f"Largest certified sector: {_describe(s_best)} (channel {channel}, {end} end {got:.6g}, "
        f"to {rtol:g} relative); linear (Hurwitz) limit of that end: {lin_txt}{ratio}."
    )
    return SectorCertificate(
        True,
        s_best,
        P_best,
        tuple(float(x) for x in tau_best),
        t_best,
        dt,
        msg,
        channel=int(channel),
        end=end,
        linear_limit=lin,
        bisections=n_bis,
    )


# ---------------------------------------------------------------------------------------------
# sampled loops with delay
# ---------------------------------------------------------------------------------------------


def zoh_with_delay(
    sys: Any, dt: float, *, delay: float = 0.0, buffer: int | None = None
) -> control.StateSpace:
    """The exact discrete model of a continuous ``sys`` (SISO or MIMO) driven through a
    zero-order hold of period ``dt`` [s] with an input delay ``delay`` [s] (any value >= 0, a
    fraction of a sample included): states ``(x, u[k-1], ..., u[k-N])``, ``N = buffer`` (None:
    the fewest needed; more gives a common state space for several delays). Exact at the samples
    for a constant sample period (module docstring)."""
    dt = real_number("dt", dt, lo=0, lo_open=True, unit="s")
    delay = real_number("delay", delay, lo=0.0, unit="s")
    S = control.ss(sys)
    if S.dt:
        raise ValueError(f"sys.dt = {S.dt!r}: a continuous system is needed")
    n, m, p = S.nstates, S.ninputs, S.noutputs
    q = delay / dt
    d = int(math.floor(q + 1e-9))
    f = q - d
    if f < 1e-9:
        f = 0.0
    need = d + (1 if f > 0 else 0)
    if buffer is None:
        N = need
    else:
        if isinstance(buffer, bool) or not isinstance(buffer, int | np.integer) or buffer < need:
            raise ValueError(
                f"buffer = {buffer!r}: must be an integer >= {need} (the delay's samples)"
            )
        N = int(buffer)
    A = np.asarray(S.A, dtype=float)
    B = np.asarray(S.B, dtype=float)

    def phi_gamma(tau: float) -> tuple[F64, F64]:
        M = np.zeros((n + m, n + m))
        M[:n, :n] = A * tau
        M[:n, n:] = B * tau
        E = sla.expm(M)
        return E[:n, :n], E[:n, n:]

    Phi, _ = phi_gamma(dt)
    if f > 0:
        Ph1, G0 = phi_gamma((1.0 - f) * dt)
        _, Gf = phi_gamma(f * dt)
        G1 = Ph1 @ Gf
    else:
        G0 = phi_gamma(dt)[1]
        G1 = np.zeros((n, m))
    nn = n + N * m
    Ad = np.zeros((nn, nn))
    Bd = np.zeros((nn, m))
    Cd = np.zeros((p, nn))
    Dd = np.zeros((p, m))
    Ad[:n, :n] = Phi

    def put_u(lag: int, Mx: F64, rows: slice, target_A: F64, target_B: F64) -> None:
        """Add ``Mx u[k - lag]`` to the rows ``rows``."""
        if lag == 0:
            target_B[rows, :] += Mx
        else:
            c0 = n + (lag - 1) * m
            target_A[rows, c0 : c0 + m] += Mx

    put_u(d, G0, slice(0, n), Ad, Bd)
    if f > 0:
        put_u(d + 1, G1, slice(0, n), Ad, Bd)
    # buffer shift: slot 0 <- u[k], slot i <- slot i-1
    if N:
        Bd[n : n + m, :] = np.eye(m)
        for i in range(1, N):
            Ad[n + i * m : n + (i + 1) * m, n + (i - 1) * m : n + i * m] = np.eye(m)
    Cd[:, :n] = S.C
    lag_y = d + (1 if f > 0 else 0)
    Dx = np.asarray(S.D, dtype=float)
    if np.any(Dx):
        put_u(lag_y, Dx, slice(0, p), Cd, Dd)
    return control.ss(Ad, Bd, Cd, Dd, dt)


def sampled_loop(
    plant: Any, controller: Any, *, delay: float = 0.0, buffer: int | None = None
) -> control.StateSpace:
    """The closed loop, at the samples, of a discrete SISO ``controller`` (its ``dt``) on a
    continuous ``plant`` through a zero-order hold with input delay ``delay`` [s]
    (:func:`zoh_with_delay`; ``L = K P_d``, negative feedback, input the reference, output the
    plant output). States: plant, input buffer, controller; exact for a constant sample period."""
    K = control.ss(controller)
    if not K.dt or K.dt is True:
        raise ValueError(f"controller.dt = {K.dt!r}: a discrete controller (dt > 0) is needed")
    Pd = zoh_with_delay(plant, float(K.dt), delay=delay, buffer=buffer)
    return control.ss(control.feedback(Pd * K, 1))


# ---------------------------------------------------------------------------------------------
# the clutch slip loop
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ClutchSectorCertificate:
    """Absolute stability of the clutch slip loop against the friction slope (and the actuator
    saturation), compared with the judder threshold (:func:`clutch_sector_certificate`).

    ``mu_slope_certified`` [s/rad]: every friction characteristic whose slope ``mu'`` (of
    ``mu/mu0``) stays in ``[mu_slope_certified, 0]`` keeps the slip loop stable (None: not even
    ``mu' = 0``); ``mu_slope_linear`` [s/rad] the linear limit of the same loop (a constant slope);
    ``judder_closed_form`` [s/rad] ``judder_threshold(op, controller).mu_slope_crit`` (reduced
    model, continuous or no controller; else None) and ``judder_numeric`` ``judder_crossing``'s
    (None when unavailable); ``ratio`` certified / closed form (else / numeric); ``k13`` [N m];
    ``saturation`` the sector of the saturation channel (None: not included); ``certificate``
    the underlying :class:`SectorCertificate` (continuous loops) or :class:`LyapunovCertificate`
    (sampled controllers: common Lyapunov function over ``mu_grid``); ``dt`` [s] (0:
    continuous); ``message``."""

    mu_slope_certified: float | None
    mu_slope_linear: float | None
    judder_closed_form: float | None
    judder_numeric: float | None
    ratio: float | None
    k13: float
    saturation: tuple[float, float] | None
    certificate: Any
    dt: float
    message: str

    def summary(self) -> str:
        return self.message

    def to_dict(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["certificate"] = self.certificate.to_dict()
        return json_ready(d)


def _rank_one(dA: F64, what: str) -> tuple[F64, F64]:
    U, s, Vt = np.linalg.svd(dA)
    if s[0] == 0.0:
        raise ValueError(f"{what}: the friction slope does not enter the loop (no slip coupling)")
    if s.size > 1 and s[1] > 1e-8 * s[0]:
        raise ValueError(f"{what}: the friction slope's effect is not rank one ({s[1] / s[0]:.3g})")
    return U[:, :1] * s[0], Vt[:1, :]


def _friction_lure(
    op: OperatingPoint, controller: Controller | None
) -> tuple[control.StateSpace, float]:
    """The Lur'e system of the continuous slip loop: channel 0 the friction slope (output the
    slip, gain ``k = -k13 mu'``); with a controller, channel 1 the saturation (output the
    controller's output, input the saturated command), so that the identity in channel 1 is the
    closed loop. Returns (system, k13)."""
    k13 = engine_side(op).k13
    m1 = -1e-3
    if controller is None:
        s0 = linearise(op, inputs=("x_c",), mu_slope=0.0)
        s1 = linearise(op, inputs=("x_c",), mu_slope=m1)
        A0 = np.asarray(s0.A, dtype=float)
        Bw, Cs = _rank_one((np.asarray(s1.A) - A0) / (k13 * m1), "clutch_sector_certificate")
        # A(k) = A0 - Bw k Cs with k = -k13 mu'
        return control.ss(A0, Bw, Cs, np.zeros((1, 1))), k13
    l0 = clutch_loop(op, controller, mu_slope=0.0)
    l1 = clutch_loop(op, controller, mu_slope=m1)
    P0, P1 = control.ss(l0.plant), control.ss(l1.plant)
    Ap = np.asarray(P0.A, dtype=float)
    Bw, Cs = _rank_one((np.asarray(P1.A) - Ap) / (k13 * m1), "clutch_sector_certificate")
    C = control.ss(l0.controller)
    npn, nc = Ap.shape[0], C.nstates
    Bp, Cp, Dp = np.asarray(P0.B), np.asarray(P0.C), np.asarray(P0.D)
    Ac, Bc, Cc, Dc = (np.asarray(M, dtype=float) for M in (C.A, C.B, C.C, C.D))
    # states (x_P, x_C); inputs (u_f, u); outputs (slip, controller output)
    A = np.block([[Ap, np.zeros((npn, nc))], [Bc @ Cp, Ac]])
    B = np.block([[Bw, Bp], [np.zeros((nc, 1)), Bc @ Dp]])
    Cm = np.block([[Cs, np.zeros((1, nc))], [Dc @ Cp, Cc]])
    D = np.array([[0.0, 0.0], [0.0, float((Dc @ Dp)[0, 0])]])
    return control.ss(A, B, Cm, D), k13


def _close_channel(sys: control.StateSpace, ch: int, k: float) -> control.StateSpace:
    """``sys`` with channel ``ch`` closed by ``u_ch = -k y_ch`` (the others kept, in order)."""
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    keep = [i for i in range(B.shape[1]) if i != ch]
    e = 1.0 + k * D[ch, ch]
    # u_ch = -k (C_ch x + D_ch,keep u_keep) / e
    Fx = -k * C[ch] / e
    Fu = -k * D[ch, keep] / e
    A2 = A + np.outer(B[:, ch], Fx)
    B2 = B[:, keep] + np.outer(B[:, ch], Fu)
    C2 = C[keep] + np.outer(D[keep, ch], Fx)
    D2 = D[np.ix_(keep, keep)] + np.outer(D[keep, ch], Fu)
    return control.ss(A2, B2, C2, D2, sys.dt)


def clutch_sector_certificate(
    op: OperatingPoint,
    controller: Controller | None = None,
    *,
    saturation: tuple[float, float] | None = None,
    mu_slope_limit: float | None = None,
    mu_grid: int = 9,
    rtol: float = 1e-3,
    solver: str = "CLARABEL",
) -> ClutchSectorCertificate:
    """The largest friction-slope interval ``[mu', 0]`` [s/rad] for which the slip loop at
    ``op`` is certified stable for every friction characteristic with its slope in it (module
    docstring), compared with the judder threshold.

    ``controller``: None (pedal held), a continuous controller (a sector certificate of the
    Lur'e loop; ``saturation = (a_s, 1)`` adds the saturation channel) or a sampled one (the
    lifted loop: a common discrete Lyapunov function for ``mu_grid`` slopes evenly spread over
    ``[mu', 0]``, bisection on ``mu'``; certified at those slopes and any switching among them;
    ``saturation`` then a common discrete sector certificate over them). ``mu_slope_limit``
    [s/rad] (< 0): the most negative slope of interest (None: the linear limit).
    """
    require_op(op, "clutch_sector_certificate")
    require_controller(controller, "clutch_sector_certificate", optional=True)
    solver = _solver(solver)
    if saturation is not None:
        saturation = _check_sectors(saturation, 1)[0]
        if controller is None:
            raise ValueError(
                "saturation: the pedal is held (controller None), there is no saturation"
            )
    if mu_slope_limit is not None:
        mu_slope_limit = real_number(
            "mu_slope_limit", mu_slope_limit, hi=0.0, hi_open=True, unit="s/rad"
        )
    if isinstance(mu_grid, bool) or not isinstance(mu_grid, int | np.integer) or mu_grid < 2:
        raise ValueError(f"mu_grid = {mu_grid!r}: must be an integer >= 2")
    rtol = real_number("rtol", rtol, lo=0.0, hi=0.5, lo_open=True)
    try:
        jn: float | None = judder_crossing(op, controller).mu_slope_crit
    except ValueError:
        jn = None
    jc: float | None = None
    if op.kind == "reduced" and (controller is None or not controller.is_discrete):
        try:
            jc = judder_threshold(op, controller).mu_slope_crit
        except ValueError:
            jc = None
    if controller is not None and controller.is_discrete:
        return _sampled_clutch(
            op, controller, saturation, mu_slope_limit, mu_grid, rtol, solver, jc, jn
        )
    G, k13 = _friction_lure(op, controller)
    if controller is not None and saturation is None:
        G = _close_channel(G, 1, 1.0)
    secs: list[tuple[float, float]] = [(0.0, 0.0)]
    if saturation is not None:
        secs.append(saturation)
    lim_k = None if mu_slope_limit is None else -k13 * mu_slope_limit
    try:
        cert = largest_sector(
            G, secs, channel=0, end="upper", limit=lim_k, rtol=rtol, solver=solver
        )
    except ValueError as exc:
        raise ValueError(f"clutch_sector_certificate: {exc}; give mu_slope_limit") from None
    mu_c = -cert.sectors[0][1] / k13 if cert.feasible else None
    lin = cert.linear_limit
    mu_l = -lin / k13 if (lin is not None and math.isfinite(lin)) else None
    ref = jc if jc is not None else jn
    ratio = (mu_c / ref) if (mu_c is not None and ref) else None
    return ClutchSectorCertificate(
        mu_slope_certified=mu_c,
        mu_slope_linear=mu_l,
        judder_closed_form=jc,
        judder_numeric=jn,
        ratio=ratio,
        k13=k13,
        saturation=saturation,
        certificate=cert,
        dt=0.0,
        message=_clutch_message(mu_c, mu_l, jc, jn, saturation, "continuous"),
    )


def _clutch_message(
    mu_c: float | None,
    mu_l: float | None,
    jc: float | None,
    jn: float | None,
    sat: tuple[float, float] | None,
    how: str,
) -> str:
    if mu_c is None:
        return "Not certified even for a constant friction coefficient (mu' = 0)."
    sat_txt = (
        f" and the actuator saturation in the sector [{sat[0]:g}, {sat[1]:g}]"
        if sat is not None
        else ""
    )
    if how == "continuous":
        s = (
            "Slip loop certified stable for every friction characteristic with slope mu' in "
            f"[{mu_c:.6g}, 0] s/rad{sat_txt} (any nonlinear, time-varying characteristic in that "
            "sector; a quadratic Lyapunov function and the S-procedure)."
        )
    else:
        s = (
            f"Sampled slip loop ({how}) certified stable for the friction slopes spread evenly over "
            f"[{mu_c:.6g}, 0] s/rad{sat_txt} and any switching among them (one common Lyapunov "
            "function of the lifted loop, exact at the samples; slopes between the grid points are "
            "not covered by the proof)."
        )
    if mu_l is not None:
        s += f" Linear limit of the same loop: {mu_l:.6g} s/rad."
    if jc is not None:
        s += f" Judder threshold (closed form): {jc:.6g} s/rad, certified {mu_c / jc:.1%} of it."
    if jn is not None:
        s += f" Judder threshold (numeric): {jn:.6g} s/rad."
    return s


def _sampled_clutch(
    op: OperatingPoint,
    controller: Controller,
    saturation: tuple[float, float] | None,
    mu_slope_limit: float | None,
    mu_grid: int,
    rtol: float,
    solver: str,
    jc: float | None,
    jn: float | None,
) -> ClutchSectorCertificate:
    k13 = engine_side(op).k13
    dt = float(controller.lti.dt)

    def loops(mu_min: float) -> tuple[list[control.StateSpace], list[float]]:
        mus = [float(v) for v in np.linspace(mu_min, 0.0, mu_grid)]
        return [clutch_loop(op, controller, mu_slope=m) for m in mus], mus  # type: ignore[misc]

    def cert_at(mu_min: float) -> Any:
        ls, mus = loops(mu_min)
        if saturation is None:
            return common_lyapunov(
                [lp.closed_loop for lp in ls],
                names=[f"mu'={m:.4g}" for m in mus],
                decay=False,
                solver=solver,
            )
        Gs = [control.ss(lp.controller) * control.ss(lp.plant) for lp in ls]
        return sector_certificate(Gs, [saturation], solver=solver)

    c0 = cert_at(-1e-12)
    if not c0.feasible:
        return ClutchSectorCertificate(
            None,
            None,
            jc,
            jn,
            None,
            k13,
            saturation,
            c0,
            dt,
            _clutch_message(None, None, jc, jn, saturation, ""),
        )
    lin = jn if jn is not None else mu_slope_limit
    if lin is None:
        raise ValueError(
            "clutch_sector_certificate: no judder threshold found numerically for the sampled loop; "
            "give mu_slope_limit"
        )
    target = lin if mu_slope_limit is None else max(lin, mu_slope_limit)
    lo, hi = 0.0, target  # lo certified (towards 0), hi the most negative tried
    best = c0
    ct = cert_at(target)
    if ct.feasible:
        lo, best = target, ct
    else:
        while abs(hi - lo) > rtol * abs(hi):
            mid = 0.5 * (lo + hi)
            cm = cert_at(mid)
            if cm.feasible:
                lo, best = mid, cm
            else:
                hi = mid
    mu_c = lo if lo < 0 else None
    ratio = (mu_c / jn) if (mu_c is not None and jn) else None
    how = f"dt = {dt:g} s, {mu_grid} slopes, lifted loop"
    return ClutchSectorCertificate(
        mu_c,
        jn,
        jc,
        jn,
        ratio,
        k13,
        saturation,
        best,
        dt,
        _clutch_message(mu_c, None, None, jn, saturation, how),
    )
