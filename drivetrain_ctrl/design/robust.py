"""Robust fixed-structure tuning: one PI, or PID with a derivative filter, for a whole plant set.

:func:`robust_pi` and :func:`robust_pid` maximise the integral gain ``ki`` (the load-disturbance
rejection of a PI: the integrated error of a step load is ``1/ki``) subject to, for every plant
``m`` of the set and every frequency of the design grid,

* ``|1 + L_m(jw)| >= 1/Ms`` (the Nyquist curve stays outside the disk of radius ``1/Ms`` about
  ``-1``: ``|S_m| <= Ms``),
* optionally ``|T_m(jw)| <= Mt`` (the curve stays outside the Mt circle, centre
  ``-Mt^2/(Mt^2 - 1)``, radius ``Mt/(Mt^2 - 1)``),
* optionally ``|K S_m(jw)| <= ks_max`` (control effort: the controller output per unit of
  measurement noise or reference step),

with ``L_m = C P_m`` in negative feedback (the exact delay of each plant included). The method is
the convex-concave iteration of Hast, Astrom, Bernhardsson and Boyd ("PID design by
convex-concave optimization", ECC 2013): ``L`` is linear in the gains ``theta = (kp, ki[, kd])``
(the filter time constant ``tf`` is fixed), and each keep-out disk ``|L - c| >= r`` is replaced
by the half-plane ``Re{conj(u) (L - c)} >= r`` with ``u`` the unit direction from ``c`` to the
previous iterate's curve (Cauchy-Schwarz: an inner approximation). Each step is a linear program
(a second-order cone program with the effort bound) solved by cvxpy; the previous iterate is
feasible for it, so **every iterate meets the specification and ki never decreases**.

Between grid points: the constraint is posed per grid *cell* ``[w_k, w_k+1]``. Within a cell
``L(w)`` is the chord between the two samples plus a sag that is linear in the gains,
``|L(w) - chord| <= sum_i |theta_i| e_i``; ``e_i`` (per plant, cell and gain) is measured on
``subsamples`` log-spaced points of the cell and multiplied by 1.5. Keeping the whole chord in
the half-plane (two linear rows per cell, one per end) with ``r`` raised by the sag bound keeps
the continuous curve, not only its samples, out of the disk. So the curve cannot slip between
samples, and it never crosses ``-1`` along the path of the iterates: the closed loops stay
stable from a stabilising start.

The start: ``start`` if given (checked), else the largest-``ki`` member of a coarse family of
small PI controllers (``kp`` from 0 up, ``ki`` over many decades) that meets every cell
condition and stabilises every plant (closed-loop poles, delays by a Pade approximation of
``pade_order``); a set with no such member (an unstable plant, DC gains of both signs) raises
:class:`InfeasibleSpecError` saying which plant fails and how.

Sampled plants (``dt > 0``, one ``dt`` for the set) get a discrete controller: integral
``ki dt/(z - 1)`` (``integrator="forward"``, MATLAB's default; ``"backward"``: ``ki dt z/(z -
1)``, ``"tustin"``: ``ki dt/2 (z + 1)/(z - 1)``), derivative with a backward-Euler filter
``kd (z - 1)/((tf + dt) z - tf)``; continuous: ``kp + ki/s + kd s/(tf s + 1)``. Units: ``kp``
[u/y], ``ki`` [u/(y s)], ``kd`` [u s/y], ``tf`` [s], frequencies [rad/s].

The result (:class:`RobustTuning`) re-checks every plant on a dense grid, independently of the
optimisation, with the design tools' loop check (:func:`~drivetrain_ctrl.design.checks.check_loop`:
``Ms``, ``Mt``, ``max |KS|``, classical gain and phase margins, the symmetric disk margin and
closed-loop stability); it says which plants and frequencies are active (limit the design) and
keeps the iteration history. The controller structure
(:func:`~drivetrain_ctrl.design.controllers.pid_controller`, the discrete integrators) is
:mod:`~drivetrain_ctrl.design.controllers`, shared with :func:`~drivetrain_ctrl.design.pi.design_pi`.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import control
import cvxpy as cp
import numpy as np
import scipy.sparse as sps
from numpy.typing import NDArray

from ..core.serialize import json_ready
from ..core.validate import did_you_mean, real_number
from .checks import LoopCheck, check_grid, check_plant_set, closed_loop_stable, worst_figures
from .controllers import INTEGRATORS, pid_basis
from .options import frequency_vector, spec_with_options
from .plants import PlantSet, as_plant_set, frequency_grid

__all__ = [
    "RobustSpec",
    "RobustTuning",
    "InfeasibleSpecError",
    "UnboundedSpecError",
    "robust_pi",
    "robust_pid",
]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]

STRUCTURES = ("pi", "pid")
SOLVERS = ("CLARABEL", "SCS", "HIGHS", "OSQP", "ECOS")
#: factor on the sag measured on the sub-samples of a cell (the sub-sampled maximum can miss the
#: true one by a little)
SAG_SAFETY = 1.5
#: relative slack below which a cell constraint is reported active
ACTIVE_TOL = 2e-3
#: relative tolerance of the feasibility check of an iterate (solver accuracy)
FEAS_TOL = 1e-7


class UnboundedSpecError(ValueError):
    """The bounds do not limit ``ki``: the gains grow without end (e.g. a plant set without delay
    or roll-off beyond first order, with only an Ms bound). Add a bound that high gain violates
    (``ks_max``, a plant's delay or actuator lag)."""


class InfeasibleSpecError(ValueError):
    """The tuner found no start: the given ``start`` fails, or none of the start family's
    candidates that meet every bound (tried largest ``ki`` first, at most 25 of them) stabilises
    every plant; a stabilising member beyond those 25 is not searched for (give ``start``). The
    message names the plant, the bound and the frequency that fail."""


@dataclass(frozen=True)
class RobustSpec:
    """What :func:`robust_pi` / :func:`robust_pid` design for (all keyword options).

    Bounds: ``ms`` (> 1) on ``max |S|`` (1.4: Astrom and Hagglund's robust default, at least
    about 45 deg phase margin and 2.3 (7.4 dB) gain margin); ``mt`` (> 1, None: no bound) on
    ``max |T|``; ``ks_max`` (> 0 [u/y], None: no bound) on ``max |K S|``, the control effort.
    Structure: ``tf`` [s] the derivative filter time constant of a PID (None: one tenth of the
    period of the robust PI's largest crossover, at least ``dt`` for a sampled set); ``integrator``
    the discrete integral formula (``"forward"``, ``"backward"``, ``"tustin"``; sampled sets only).
    Grid: ``omega`` [rad/s] the design grid (None: :func:`~drivetrain_ctrl.design.plants.frequency_grid`
    with ``n_omega`` points); ``subsamples`` per grid cell for the sag bound between grid points;
    ``check_points`` of the dense re-check grid. Start: ``start`` ``(kp, ki)`` or ``(kp, ki, kd)``
    (None: automatic). Iteration: ``solver`` (a cvxpy solver name), ``max_iter``, ``tol``
    (relative ``ki`` increase below which, twice in a row, the iteration has converged),
    ``trust`` (each gain moves at most ``trust`` times its own size, plus a floor, per step),
    ``pade_order`` of the delay approximation used for closed-loop poles only; ``refine``: rounds
    of grid refinement around the active cells after convergence (each splits the cells within
    1 % of a bound in four and continues the iteration); ``working_set``: solve each convex step on
    the rows near their bound, adding violated ones until none is (True, the fastest measured),
    or the full problem built once with cvxpy Parameters (False; the same optimum).
    """

    ms: float = 1.4
    mt: float | None = None
    ks_max: float | None = None
    tf: float | None = None
    integrator: str = "forward"
    omega: tuple[float, ...] | None = None
    n_omega: int = 200
    subsamples: int = 8
    check_points: int = 2000
    start: tuple[float, ...] | None = None
    solver: str = "CLARABEL"
    max_iter: int = 100
    tol: float = 1e-6
    trust: float = 1.0
    pade_order: int = 5
    refine: int = 1
    working_set: bool = True

    def __post_init__(self) -> None:
        s = object.__setattr__
        s(self, "ms", real_number("ms", self.ms, lo=1.0, lo_open=True))
        if self.mt is not None:
            s(self, "mt", real_number("mt", self.mt, lo=1.0, lo_open=True))
        if self.ks_max is not None:
            s(self, "ks_max", real_number("ks_max", self.ks_max, lo=0.0, lo_open=True))
        if self.tf is not None:
            s(self, "tf", real_number("tf", self.tf, lo=0.0, lo_open=True, unit="s"))
        if self.integrator not in INTEGRATORS:
            raise ValueError(
                f"integrator = {self.integrator!r}: must be one of {INTEGRATORS}"
                + did_you_mean(str(self.integrator), INTEGRATORS)
            )
        if self.omega is not None:
            s(self, "omega", frequency_vector("omega", self.omega, 3))
        for name, lo in (
            ("n_omega", 3),
            ("subsamples", 1),
            ("check_points", 10),
            ("max_iter", 1),
            ("pade_order", 1),
            ("refine", 0),
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
                raise ValueError(f"{name} = {v!r}: must be an integer >= {lo}")
            s(self, name, int(v))
        s(self, "tol", real_number("tol", self.tol, lo=0.0, lo_open=True))
        s(self, "trust", real_number("trust", self.trust, lo=0.0, lo_open=True))
        if not isinstance(self.solver, str) or self.solver.upper() not in SOLVERS:
            raise ValueError(
                f"solver = {self.solver!r}: must be one of {SOLVERS}"
                + did_you_mean(str(self.solver), SOLVERS)
            )
        s(self, "solver", self.solver.upper())
        if not isinstance(self.working_set, bool):
            raise ValueError(f"working_set = {self.working_set!r}: must be True or False")
        if self.start is not None:
            st = self.start
            if (
                isinstance(st, str)
                or not isinstance(st, Sequence | np.ndarray)
                or len(st)
                not in (
                    2,
                    3,
                )
            ):
                raise ValueError(f"start = {st!r}: must be (kp, ki) or (kp, ki, kd)")
            vals = tuple(real_number(f"start[{i}]", v) for i, v in enumerate(st))
            if vals[1] <= 0:
                raise ValueError(f"start[1] = {st[1]!r}: the start's ki must be > 0 [u/(y s)]")
            s(self, "start", vals)

    def to_dict(self) -> dict[str, Any]:
        """The options as a JSON-ready dict."""
        return json_ready(dataclasses.asdict(self))


# ---------------------------------------------------------------------------------------------
# controller structure
# ---------------------------------------------------------------------------------------------


def _eval_poly_ratio(nums: list[F64], d: F64, x: C128) -> C128:
    """``n_i(x) / d(x)`` for each numerator: shape ``(len(nums), x.size)``, by python-control."""
    out = np.empty((len(nums), x.size), dtype=complex)
    for i, n in enumerate(nums):
        sys = control.tf(n if np.any(n) else [0.0], d)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[i] = np.asarray(sys(x, warn_infinite=False), dtype=complex).reshape(-1)
    return out


# ---------------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RobustTuning:
    """A robust PI/PID for a plant set (:func:`robust_pi`, :func:`robust_pid`).

    ``kp`` [u/y], ``ki`` [u/(y s)], ``kd`` [u s/y], ``tf`` [s] (0 for a PI), ``dt`` [s] (0:
    continuous), ``controller`` (python-control transfer function,
    :func:`~drivetrain_ctrl.design.controllers.pid_controller`);
    ``spec``; ``plants``: one :class:`~drivetrain_ctrl.design.checks.LoopCheck` per plant; ``history``: the gains
    ``(kp, ki[, kd])`` of the start and of each accepted iterate (``ki`` non-decreasing);
    ``converged`` and ``message``; ``omega`` the final design grid [rad/s] (refined around the
    active cells); ``start_source`` (``"auto"``, ``"given"``, ``"robust PI"``); ``timings`` [s]
    per phase (grid, start, iterations, of which solver, check; a PID's robust PI start);
    ``wall_time_s`` of the whole design.
    """

    structure: str
    kp: float
    ki: float
    kd: float
    tf: float
    dt: float
    controller: control.TransferFunction
    spec: RobustSpec
    plants: tuple[LoopCheck, ...]
    history: tuple[tuple[float, ...], ...]
    converged: bool
    message: str
    omega: F64 = field(repr=False, compare=False)
    start_source: str = "auto"
    timings: tuple[tuple[str, float], ...] = ()
    wall_time_s: float = 0.0

    @property
    def solve_time_s(self) -> float:
        """Time in the convex solver (cvxpy included) [s], of the robust PI start too."""
        t = dict(self.timings)
        return t.get("solver", 0.0)

    @property
    def ki_history(self) -> tuple[float, ...]:
        """``ki`` of the start and of each iterate [u/(y s)]."""
        return tuple(h[1] for h in self.history)

    @property
    def iterations(self) -> int:
        """Number of convex steps taken."""
        return len(self.history) - 1

    @property
    def limiting(self) -> tuple[str, ...]:
        """Names of the plants with an active bound (the ones that limit ``ki``)."""
        return tuple(p.name for p in self.plants if p.limiting)

    @property
    def ms(self) -> float:
        """Largest re-checked ``|S|`` over the set."""
        return float(worst_figures(self.plants)["ms_max"])

    @property
    def mt(self) -> float:
        """Largest re-checked ``|T|`` over the set."""
        return float(worst_figures(self.plants)["mt_max"])

    @property
    def ks(self) -> float:
        """Largest re-checked ``|K S|`` over the set [u/y]."""
        return float(worst_figures(self.plants)["ks_max"])

    @property
    def stable(self) -> bool | None:
        """True if every closed loop is stable (None if one could not be checked)."""
        flag: bool | None = worst_figures(self.plants)["all_stable"]
        return flag

    def table(self) -> list[dict[str, Any]]:
        """One row per plant: name, Ms, Mt, ``|KS|``, GM [dB], PM [deg], disk margin [dB, deg],
        crossover [rad/s], stable, limiting (for a printed table or a DataFrame)."""
        return [
            {
                "plant": p.name,
                "ms": p.ms,
                "mt": p.mt,
                "ks": p.ks,
                "gm_db": p.gain_margin_db,
                "pm_deg": p.phase_margin_deg,
                "dm_db": p.disk_margin_db,
                "dm_deg": p.disk_margin_deg,
                "crossover_rad_s": p.crossover_rad_s,
                "stable": p.stable,
                "limiting": p.limiting,
            }
            for p in self.plants
        ]

    def summary(self) -> str:
        """One sentence: the gains, the achieved figures and what limits the design."""
        kind = "robust PID" if self.structure == "pid" else "robust PI"
        gains = f"kp = {self.kp:.4g}, ki = {self.ki:.4g}"
        if self.structure == "pid":
            gains += f", kd = {self.kd:.4g}, tf = {self.tf:.4g} s"
        if self.dt:
            gains += f" (sampled, dt = {self.dt:g} s)"
        bounds = f"Ms <= {self.spec.ms:g}"
        if self.spec.mt is not None:
            bounds += f", Mt <= {self.spec.mt:g}"
        if self.spec.ks_max is not None:
            bounds += f", |KS| <= {self.spec.ks_max:g}"
        w = worst_figures(self.plants)
        fig = f"achieved Ms {w['ms_max']:.3f}, Mt {w['mt_max']:.3f}"
        if w["gain_margin_db_min"] is not None:
            fig += f", GM >= {w['gain_margin_db_min']:.1f} dB"
        if w["phase_margin_deg_min"] is not None:
            fig += f", PM >= {w['phase_margin_deg_min']:.1f} deg"
        fig += f", disk margin >= {w['disk_margin_db_min']:.1f} dB"
        lim = ", ".join(self.limiting) or "none"
        stab = {True: "all loops stable", False: "UNSTABLE loop(s)", None: "stability unchecked"}
        return (
            f"{kind} for {len(self.plants)} plant(s), {bounds}: {gains}; {fig}; "
            f"limited by {lim}; {stab[self.stable]}; "
            f"{'converged' if self.converged else 'NOT converged'} in {self.iterations} "
            f"iterations ({self.wall_time_s:.2f} s)."
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: gains, spec, per-plant checks, history, status (no controller object)."""
        return json_ready(
            {
                "structure": self.structure,
                "kp": self.kp,
                "ki": self.ki,
                "kd": self.kd,
                "tf": self.tf,
                "dt": self.dt,
                "integrator": self.spec.integrator if self.dt else None,
                "spec": self.spec.to_dict(),
                "plants": [p.to_dict() for p in self.plants],
                "history": [list(h) for h in self.history],
                "converged": self.converged,
                "message": self.message,
                "start_source": self.start_source,
                "limiting": list(self.limiting),
                "timings_s": dict(self.timings),
                "wall_time_s": self.wall_time_s,
            }
        )


# ---------------------------------------------------------------------------------------------
# the problem on the grid
# ---------------------------------------------------------------------------------------------


def _seg_nearest(za: C128, zb: C128) -> tuple[C128, F64]:
    """Nearest point to 0 of each segment ``[za, zb]`` and its parameter ``t`` in [0, 1]."""
    d = zb - za
    dd = np.abs(d) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(dd > 0, -np.real(np.conj(za) * d) / dd, 0.0)
    t = np.clip(t, 0.0, 1.0)
    return za + t * d, t


class _Grid:
    """Frequency data of one design: responses of the gains' basis times each plant at the grid
    points, and the sag bounds per cell."""

    def __init__(
        self,
        pset: PlantSet,
        w: F64,
        nums: list[F64],
        den: F64,
        dt: float,
        subsamples: int,
    ) -> None:
        self.w = w
        self.dt = dt
        self.nums, self.den = nums, den
        x = np.exp(1j * w * dt) if dt else 1j * w
        P = pset.freqresp(w)  # (m, w)
        bad = ~np.isfinite(P)
        if bad.any():
            m, k = np.argwhere(bad)[0]
            raise ValueError(
                f"plant {pset[int(m)].name!r}: infinite response at w = {w[k]:.6g} rad/s on the "
                "design grid (a pole on the stability boundary there); move the grid (omega)"
            )
        B = _eval_poly_ratio(nums, den, np.asarray(x, dtype=complex))  # (i, w)
        self.B = B
        self.Phi = P[:, None, :] * B[None, :, :]  # (m, i, w)
        # sub-samples of every cell (log-spaced), their chord parameter t
        n_sub = subsamples
        t = np.arange(1, n_sub + 1) / (n_sub + 1)
        lw = np.log(w)
        wsub = np.exp(lw[:-1, None] * (1 - t) + lw[1:, None] * t)  # (k, s)
        xs = np.exp(1j * wsub.ravel() * dt) if dt else 1j * wsub.ravel()
        Ps = pset.freqresp(wsub.ravel()).reshape(len(pset), *wsub.shape)  # (m, k, s)
        Bs = _eval_poly_ratio(nums, den, xs).reshape(len(nums), *wsub.shape)  # (i, k, s)
        if not np.all(np.isfinite(Ps)):
            raise ValueError(
                "a plant has an infinite response between design grid points (a pole on the "
                "stability boundary); move the grid (omega)"
            )
        chordB = B[:, :-1, None] * (1 - t) + B[:, 1:, None] * t  # (i, k, s)
        self.sagC = SAG_SAFETY * np.max(np.abs(Bs - chordB), axis=-1).T  # (k, i)
        Phis = Ps[:, None] * Bs[None]  # (m, i, k, s)
        chord = self.Phi[:, :, :-1, None] * (1 - t) + self.Phi[:, :, 1:, None] * t
        self.sagL = SAG_SAFETY * np.max(np.abs(Phis - chord), axis=-1).transpose(0, 2, 1)  # m,k,i
        self.wsub = wsub

    def L(self, theta: F64) -> C128:
        """``L_m(w)`` for gains ``theta``: shape (m, w)."""
        return np.einsum("i,miw->mw", theta, self.Phi)

    def C(self, theta: F64) -> C128:
        return np.asarray(theta @ self.B)


class _Disks:
    """Keep-out disks in the L plane: (name, centre, radius)."""

    def __init__(self, spec: RobustSpec) -> None:
        self.items: list[tuple[str, float, float]] = [("ms", -1.0, 1.0 / spec.ms)]
        if spec.mt is not None:
            mt2 = spec.mt**2
            self.items.append(("mt", -mt2 / (mt2 - 1.0), spec.mt / (mt2 - 1.0)))
        self.ks_max = spec.ks_max


def _cell_slack(g: _Grid, disks: _Disks, theta: F64) -> dict[str, tuple[F64, F64]]:
    """Relative slack of the continuous cell conditions at ``theta`` per bound: ``(slack (m, k),
    t of the nearest chord point (m, k))``; >= 0 means met on the whole cell."""
    L = g.L(theta)
    ath = np.abs(theta)
    sag = g.sagL @ ath  # (m, k)
    out: dict[str, tuple[F64, F64]] = {}
    dist_ms: F64 | None = None
    t_ms: F64 | None = None
    for name, c, r in disks.items:
        p, t = _seg_nearest(L[:, :-1] - c, L[:, 1:] - c)
        dist = np.abs(p)
        out[name] = ((dist - sag - r) / r, t)
        if name == "ms":
            dist_ms, t_ms = dist, t
    if disks.ks_max is not None:
        assert dist_ms is not None and t_ms is not None
        cm = np.abs(g.C(theta))
        cmax = np.maximum(cm[:-1], cm[1:]) + g.sagC @ ath  # (k,)
        room = disks.ks_max * (dist_ms - sag)
        with np.errstate(divide="ignore", invalid="ignore"):
            sl = np.where(room > 0, 1.0 - cmax[None, :] / room, -np.inf)
        out["ks"] = (sl, t_ms)
    return out


def _min_slack(sl: dict[str, tuple[F64, F64]]) -> float:
    return float(min(np.min(v[0]) for v in sl.values()))


class _LP:
    """The convex step at the current iterate: rows ``G x - E |x| >= h`` (two per plant, cell and
    bound; with the effort bound the second-order cone rows of the module docstring), the trust
    box, maximise ``x_ki``.

    ``working_set=True`` (the default, fastest measured): the problem is solved on the rows near
    their bound at the current iterate, every other row is checked at the solution and the
    violated ones are added until none is (the same optimum as the full problem, a fraction of
    its rows). ``False``: the full problem, built once with cvxpy Parameters (DPP) and re-solved.
    """

    def __init__(self, g: _Grid, disks: _Disks, solver: str, working_set: bool) -> None:
        self.g, self.disks, self.solver, self.working_set = g, disks, solver, working_set
        n_m, n_i, n_w = g.Phi.shape
        self.n_i = n_i
        n_k = n_w - 1
        self.n_rows_disk = n_m * n_k * 2
        self.cell = np.tile(np.repeat(np.arange(n_k), 2), n_m)  # row (m, k, j) -> cell k
        self.ws_prev: NDArray[np.intp] = np.zeros(0, dtype=np.intp)
        self.ws_prev_e: NDArray[np.intp] = np.zeros(0, dtype=np.intp)
        self.last_rows = 0
        if not working_set:
            self._build_dpp()

    def _build_dpp(self) -> None:
        g, disks = self.g, self.disks
        n_i = self.n_i
        n_w = g.w.size
        R = len(disks.items) * self.n_rows_disk
        self.x = cp.Variable(n_i)
        self.a = cp.Variable(n_i)
        self.pG = cp.Parameter((R, n_i))
        self.pE = cp.Parameter((R, n_i), nonneg=True)
        self.ph = cp.Parameter(R)
        self.plo = cp.Parameter(n_i)
        self.phi = cp.Parameter(n_i)
        x, a = self.x, self.a
        cons = [
            self.pG @ x - self.pE @ a >= self.ph,
            a >= x,
            a >= -x,
            x >= self.plo,
            x <= self.phi,
            x[1] >= 0,
        ]
        if disks.ks_max is not None:
            Rm = self.n_rows_disk
            self.pBre = cp.Parameter((n_w, n_i))
            self.pBim = cp.Parameter((n_w, n_i))
            self.pEe = cp.Parameter((Rm, n_i), nonneg=True)
            self.pinv = cp.Parameter(Rm, nonneg=True)
            self.phe = cp.Parameter(Rm)
            cmag = cp.norm(cp.vstack([self.pBre @ x, self.pBim @ x]), 2, axis=0)
            cmax = cp.maximum(cmag[:-1], cmag[1:])
            sel = sps.csr_matrix((np.ones(Rm), (np.arange(Rm), self.cell)), shape=(Rm, n_w - 1))
            cons.append(
                self.pG[:Rm] @ x
                - self.pE[:Rm] @ a
                - self.pEe @ a
                - cp.multiply(self.pinv, sel @ cmax)
                >= self.phe
            )
        self.prob = cp.Problem(cp.Maximize(x[1]), cons)

    def set(self, theta0: F64, scale: F64, trust: float) -> None:
        """Linearise at ``theta0``; variables ``x = theta / scale``; box ``|x - x0| <= trust``."""
        g = self.g
        L0 = g.L(theta0)
        n_m, n_i, n_w = g.Phi.shape
        Gs, Es, hs = [], [], []
        sagE = np.repeat(g.sagL[:, :, None, :], 2, axis=2).reshape(-1, n_i) * scale  # (m k j, i)
        # Phi at the two ends of every cell: (m, k, j, i)
        ends = np.stack([g.Phi[:, :, :-1], g.Phi[:, :, 1:]], axis=-1).transpose(0, 2, 3, 1)
        sigma_ms = g_ms = None
        for name, c, r in self.disks.items:
            za, zb = L0[:, :-1] - c, L0[:, 1:] - c
            p, _t = _seg_nearest(za, zb)
            u = p / np.abs(p)  # (m, k)
            zend = np.stack([za, zb], axis=-1)  # (m, k, j)
            sigma = np.maximum(np.abs(zend), r).reshape(-1)  # row scale
            G = np.real(np.conj(u)[:, :, None, None] * ends).reshape(-1, n_i) * scale
            g0 = np.real(np.conj(u)[:, :, None] * (-c) * np.ones(2)).reshape(-1)
            Gs.append(G / sigma[:, None])
            Es.append(sagE / sigma[:, None])
            hs.append((r - g0) / sigma)
            if name == "ms":
                sigma_ms, g_ms = sigma, g0
        self.G = np.vstack(Gs)
        self.E = np.vstack(Es)
        self.h = np.concatenate(hs)
        self.x0 = theta0 / scale
        self.lo = self.x0 - trust
        self.hi = self.x0 + trust
        if self.disks.ks_max is not None:
            assert sigma_ms is not None and g_ms is not None
            K = self.disks.ks_max
            sagC = np.repeat(np.tile(g.sagC[None], (n_m, 1, 1))[:, :, None, :], 2, axis=2)
            self.Bre = np.real(g.B.T) * scale
            self.Bim = np.imag(g.B.T) * scale
            self.Ee = sagC.reshape(-1, n_i) * scale / (K * sigma_ms[:, None])
            self.inv = 1.0 / (K * sigma_ms)
            self.he = -g_ms / sigma_ms
        if not self.working_set:
            self.pG.value, self.pE.value, self.ph.value = self.G, self.E, self.h
            self.plo.value, self.phi.value = self.lo, self.hi
            if self.disks.ks_max is not None:
                self.pBre.value, self.pBim.value = self.Bre, self.Bim
                self.pEe.value, self.pinv.value, self.phe.value = self.Ee, self.inv, self.he

    def _residuals(self, x: F64) -> tuple[F64, F64 | None]:
        """Row residuals ``lhs - h`` at ``x`` (>= 0: met): disk rows and effort rows."""
        a = np.abs(x)
        rd = self.G @ x - self.E @ a - self.h
        if self.disks.ks_max is None:
            return rd, None
        Rm = self.n_rows_disk
        cmag = np.hypot(self.Bre @ x, self.Bim @ x)
        cmax = np.maximum(cmag[:-1], cmag[1:])
        re = self.G[:Rm] @ x - self.E[:Rm] @ a - self.Ee @ a - self.inv * cmax[self.cell] - self.he
        return rd, re

    def solve(self) -> tuple[F64 | None, str, float]:
        tic = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = self._solve_ws() if self.working_set else self._solve_full()
        except cp.error.SolverError as exc:
            return None, f"solver error: {exc}", time.perf_counter() - tic
        return out[0], out[1], time.perf_counter() - tic

    def _solve_full(self) -> tuple[F64 | None, str]:
        self.prob.solve(solver=self.solver)
        self.last_rows = self.G.shape[0]
        if self.prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or self.x.value is None:
            return None, str(self.prob.status)
        return np.asarray(self.x.value, dtype=float), str(self.prob.status)

    def _solve_ws(self) -> tuple[F64 | None, str]:
        r0, e0 = self._residuals(self.x0)
        W = np.union1d(np.flatnonzero(r0 <= WS_SLACK), self.ws_prev)
        We = np.zeros(0, dtype=np.intp)
        if e0 is not None:
            We = np.union1d(np.flatnonzero(e0 <= WS_SLACK), self.ws_prev_e)
        status = "no solve"
        for _round in range(50):
            x, status = self._solve_rows(W, We)
            if x is None:
                return None, status
            rd, re = self._residuals(x)
            add = np.setdiff1d(np.flatnonzero(rd < -WS_TOL), W)
            add_e = np.zeros(0, dtype=np.intp)
            if re is not None:
                add_e = np.setdiff1d(np.flatnonzero(re < -WS_TOL), We)
            if add.size == 0 and add_e.size == 0:
                self.ws_prev = np.flatnonzero(rd <= 1e-6)
                self.ws_prev_e = np.flatnonzero(re <= 1e-6) if re is not None else We[:0]
                self.last_rows = W.size + We.size
                return x, status
            W = np.union1d(W, add)
            We = np.union1d(We, add_e)
        return None, "working set did not settle in 50 rounds"

    def _solve_rows(self, W: NDArray[np.intp], We: NDArray[np.intp]) -> tuple[F64 | None, str]:
        x = cp.Variable(self.n_i)
        a = cp.Variable(self.n_i)
        cons = [a >= x, a >= -x, x >= self.lo, x <= self.hi, x[1] >= 0]
        if W.size:
            cons.append(self.G[W] @ x - self.E[W] @ a >= self.h[W])
        if We.size:
            cells = self.cell[We]
            pts = np.unique(np.concatenate([cells, cells + 1]))
            cm = cp.norm(cp.vstack([self.Bre[pts] @ x, self.Bim[pts] @ x]), 2, axis=0)
            pos = {int(p): i for i, p in enumerate(pts)}
            ia = np.array([pos[int(c)] for c in cells])
            ib = np.array([pos[int(c) + 1] for c in cells])
            cmax = cp.maximum(cm[ia], cm[ib])
            cons.append(
                self.G[We] @ x - (self.E[We] + self.Ee[We]) @ a - cp.multiply(self.inv[We], cmax)
                >= self.he[We]
            )
        prob = cp.Problem(cp.Maximize(x[1]), cons)
        prob.solve(solver=self.solver)
        if prob.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or x.value is None:
            return None, str(prob.status)
        return np.asarray(x.value, dtype=float), str(prob.status)


# ---------------------------------------------------------------------------------------------
# start, stability, re-check
# ---------------------------------------------------------------------------------------------


def _describe_violation(
    pset: PlantSet, g: _Grid, disks: _Disks, sl: dict[str, tuple[F64, F64]]
) -> str:
    name, (s, t) = min(sl.items(), key=lambda kv: float(np.min(kv[1][0])))
    m, k = np.unravel_index(int(np.argmin(s)), s.shape)
    w = float(np.exp(np.log(g.w[k]) * (1 - t[m, k]) + np.log(g.w[k + 1]) * t[m, k]))
    what = {"ms": "|S| <= Ms", "mt": "|T| <= Mt", "ks": "|KS| <= ks_max"}[name]
    return f"plant {pset[int(m)].name!r} violates {what} near w = {w:.4g} rad/s"


def _find_start(
    pset: PlantSet, g: _Grid, disks: _Disks, spec: RobustSpec, n_i: int
) -> tuple[F64, str]:
    """A gain vector that meets every cell condition and stabilises every plant (module
    docstring); InfeasibleSpecError otherwise."""
    if spec.start is not None:
        th = np.zeros(n_i)
        th[: min(n_i, len(spec.start))] = spec.start[:n_i]
        sl = _cell_slack(g, disks, th)
        if _min_slack(sl) < -FEAS_TOL:
            raise InfeasibleSpecError(
                f"start = {spec.start!r} does not meet the specification: "
                + _describe_violation(pset, g, disks, sl)
            )
        C = _controller_of(th, g)
        for p in pset:
            st, why = closed_loop_stable(p, C, spec.pade_order)
            if st is False:
                raise InfeasibleSpecError(
                    f"start = {spec.start!r} does not stabilise plant {p.name!r}"
                )
        return th, "given"
    Pmag = np.abs(g.Phi[:, 0, :])  # |P| (the kp basis is 1)
    sp = 1.0 / max(float(np.max(Pmag)), 1e-300)
    lw0, lw1 = math.log10(g.w[0]), math.log10(g.w[-1])
    kis = sp * np.logspace(lw0 - 4, lw1, 80)
    kps = np.concatenate([[0.0], sp * np.logspace(-3, 1, 13)])
    KP, KI = np.meshgrid(kps, kis, indexing="ij")
    cands = np.stack([KP.ravel(), KI.ravel()], axis=1)
    worst = np.empty(len(cands))
    for j, c in enumerate(cands):
        th = np.zeros(n_i)
        th[:2] = c
        worst[j] = _min_slack(_cell_slack(g, disks, th))
    ok = worst >= 0.0
    # per kp, only the run of feasible ki that starts at the smallest ki (the component that
    # reaches the stable small-gain limit; a huge gain also clears every disk, encircling -1)
    okg = ok.reshape(KP.shape)
    run = np.cumprod(okg, axis=1).astype(bool)
    ok = run.ravel()
    order = np.argsort(-cands[:, 1] - 1e-12 * cands[:, 0])  # largest ki first, then small kp
    tried = 0
    unstable: dict[str, int] = {}
    for idx in order:
        if not ok[idx]:
            continue
        th = np.zeros(n_i)
        th[:2] = cands[idx]
        C = _controller_of(th, g)
        bad = None
        for p in pset:
            st, _why = closed_loop_stable(p, C, spec.pade_order)
            if st is False:
                bad = p.name
                break
        if bad is None:
            return th, "auto"
        unstable[bad] = unstable.get(bad, 0) + 1
        tried += 1
        if tried >= 25:  # the documented cap (InfeasibleSpecError)
            break
    if not ok.any():
        i = int(np.argmax(worst))
        th = np.zeros(n_i)
        th[:2] = cands[i]
        detail = _describe_violation(pset, g, disks, _cell_slack(g, disks, th))
        raise InfeasibleSpecError(
            "no small PI meets the specification on every plant (tried kp in [0, "
            f"{kps[-1]:.3g}], ki in [{kis[0]:.3g}, {kis[-1]:.3g}]); the best one: {detail}. "
            "Relax the bounds (ms, mt, ks_max), check the plants' signs, or give start=(kp, ki)"
        )
    worst_plant = max(unstable, key=lambda k: unstable[k]) if unstable else "?"
    dc = _dc_signs(pset)
    hint = ""
    if len(dc) > 1:
        hint = (
            f" The set has DC gains of both signs ({', '.join(f'{n}: {s}' for n, s in dc.items())}):"
            " integral action of one sign cannot stabilise both."
        )
    raise InfeasibleSpecError(
        f"no small PI that meets the bounds stabilises every plant: plant {worst_plant!r} stays "
        f"unstable in closed loop.{hint} An open-loop unstable plant needs start=(kp, ki) from a "
        "stabilising design."
    )


def _dc_signs(pset: PlantSet) -> dict[str, str]:
    """Plant name -> sign of its DC gain, grouped: {sign: names} flattened for a message."""
    groups: dict[str, list[str]] = {}
    for p in pset:
        with np.errstate(all="ignore"):
            g0 = complex(p.sys(1.0 if p.is_discrete else 0.0, warn_infinite=False))
        if not np.isfinite(g0) or g0.real == 0:
            continue
        groups.setdefault("+" if g0.real > 0 else "-", []).append(p.name)
    return {f"DC {s}": ", ".join(v) for s, v in groups.items()}


def _controller_of(theta: F64, g: _Grid) -> control.TransferFunction:
    num = sum(t * n for t, n in zip(theta, g.nums, strict=True))
    num = np.asarray(num, dtype=float)
    return control.tf(num if np.any(num) else [0.0], g.den, g.dt)


def _active(
    pset: PlantSet, g: _Grid, disks: _Disks, theta: F64
) -> list[tuple[tuple[str, float, float], ...]]:
    """Per plant: the active cell constraints (one per run of adjacent active cells, at its
    tightest cell), ``(bound, frequency [rad/s], slack)``."""
    sl = _cell_slack(g, disks, theta)
    lw = np.log(g.w)
    out: list[list[tuple[str, float, float]]] = [[] for _ in pset]
    for name, (s, t) in sl.items():
        for m in range(s.shape[0]):
            act = s[m] <= ACTIVE_TOL
            k = 0
            n_k = act.size
            while k < n_k:
                if not act[k]:
                    k += 1
                    continue
                j = k
                while j + 1 < n_k and act[j + 1]:
                    j += 1
                b = k + int(np.argmin(s[m, k : j + 1]))
                w = float(np.exp(lw[b] * (1 - t[m, b]) + lw[b + 1] * t[m, b]))
                out[m].append((name, w, float(s[m, b])))
                k = j + 1
    return [tuple(sorted(o, key=lambda e: e[1])) for o in out]


# ---------------------------------------------------------------------------------------------
# the tuner
# ---------------------------------------------------------------------------------------------


def _check_effort_at_dc(pset: PlantSet, ks_max: float) -> None:
    """With integral action ``K S -> 1/P(0)`` as ``w -> 0``: a bound below ``1/|P(0)|`` on some
    plant cannot be met by any PI/PID (InfeasibleSpecError naming the plant)."""
    for p in pset:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            g0 = abs(complex(p.sys(1.0 if p.is_discrete else 0.0, warn_infinite=False)))
        need = math.inf if g0 == 0 else (0.0 if not math.isfinite(g0) else 1.0 / g0)
        if need > ks_max:
            raise InfeasibleSpecError(
                f"ks_max = {ks_max!r}: with integral action |K S| tends to 1/|P(0)| = {need:.4g} "
                f"at low frequency on plant {p.name!r} (DC gain {g0:.4g}); raise ks_max above it"
            )


def _iterate(
    g: _Grid, disks: _Disks, theta: F64, spec: RobustSpec, history: list[tuple[float, ...]]
) -> tuple[F64, bool, str, float]:
    """Convex-concave steps on grid ``g`` from the feasible ``theta`` (history appended);
    returns the last iterate, converged, a message and the solver time [s]."""
    lp = _LP(g, disks, spec.solver, spec.working_set)
    n_i = theta.size
    w = g.w
    solve_time = 0.0
    small = 0
    at_bound = 0
    ki_start = history[0][1]
    for _it in range(spec.max_iter):
        s_ms = _cell_slack(g, disks, theta)["ms"][0]
        _m, k = np.unravel_index(int(np.argmin(s_ms)), s_ms.shape)
        w_ref = float(math.sqrt(w[k] * w[k + 1]))
        # variable scales: each gain's own size plus a floor (kp ~ ki / w_ref, kd ~ ki / w_ref^2
        # at the tightest frequency), so that a gain at 0 can move
        floors = np.array([theta[1] / w_ref, 1e-3 * theta[1], theta[1] / w_ref**2][:n_i])
        scale = np.abs(theta) + floors
        lp.set(theta, scale, spec.trust)
        xs, status, el = lp.solve()
        solve_time += el
        if xs is None:
            msg = f"stopped: the convex step failed ({status}); the last iterate is kept"
            return theta, False, msg, solve_time
        new = xs * scale
        at_bound = at_bound + 1 if xs[1] >= theta[1] / scale[1] + 0.999 * spec.trust else 0
        if at_bound >= 5 and new[1] > UNBOUNDED_GROWTH * ki_start:
            raise UnboundedSpecError(
                f"ki grows without bound (from {ki_start:.3g} to {new[1]:.3g}, every step at its "
                "trust limit): the bounds do not limit the gains on this plant set; add ks_max "
                "(control effort) or model the delay / actuator lag that limits the loop"
            )
        # accept only a verified, not worse iterate (solver tolerance): backtrack towards theta,
        # whose segment to the LP solution is feasible in exact arithmetic
        beta = 1.0
        while beta > 1e-6:
            cand = theta + beta * (new - theta)
            if cand[1] >= theta[1] and _min_slack(_cell_slack(g, disks, cand)) >= -FEAS_TOL:
                break
            beta *= 0.5
        else:
            msg = "converged: no verified improvement left (solver accuracy)"
            return theta, True, msg, solve_time
        gain = (cand[1] - theta[1]) / max(theta[1], 1e-300)
        theta = cand
        history.append(tuple(float(v) for v in theta))
        small = small + 1 if gain < spec.tol else 0
        if small >= 2:
            msg = f"converged: ki grew by < {spec.tol:g} (relative) twice in a row"
            return theta, True, msg, solve_time
    msg = f"not converged in max_iter = {spec.max_iter} iterations; the last iterate is kept"
    return theta, False, msg, solve_time


#: rows whose normalised residual at the current iterate is below this start the working set
WS_SLACK = 0.05
#: a row violated by more than this (normalised) at a working-set solution is added
WS_TOL = 1e-9
#: growth of ki over its start beyond which steps at the trust limit mean "unbounded"
UNBOUNDED_GROWTH = 1e6
#: relative slack below which a cell is refined, and the number of sub-cells it is split into
REFINE_SLACK = 0.01
REFINE_FACTOR = 4


def _refined_grid(g: _Grid, disks: _Disks, theta: F64) -> F64 | None:
    """The grid with every cell near an active one (relative slack <= REFINE_SLACK on a plant,
    and its neighbours) split into REFINE_FACTOR log-equal cells; None if no cell is near."""
    sl = _cell_slack(g, disks, theta)
    near = np.zeros(g.w.size - 1, dtype=bool)
    for s, _t in sl.values():
        near |= np.any(s <= REFINE_SLACK, axis=0)
    if not near.any():
        return None
    near = near | np.r_[near[1:], False] | np.r_[False, near[:-1]]
    lw = np.log(g.w)
    ks = np.flatnonzero(near)
    f = np.arange(1, REFINE_FACTOR) / REFINE_FACTOR
    add = np.exp(lw[ks, None] + (lw[ks + 1] - lw[ks])[:, None] * f).ravel()
    return np.union1d(g.w, add)


def _tune(plants: Any, structure: str, spec: RobustSpec) -> RobustTuning:
    tic = time.perf_counter()
    timings: dict[str, float] = {}
    pset = as_plant_set(plants)
    dt = pset.dt
    if spec.omega is not None:
        w = np.asarray(spec.omega, dtype=float)
        if dt and w[-1] > math.pi / dt * (1 + 1e-12):
            raise ValueError(
                f"omega: {w[-1]:.6g} rad/s beyond the Nyquist frequency pi/dt = "
                f"{math.pi / dt:.6g} rad/s of the sampled plants"
            )
    else:
        w = frequency_grid(pset, n=spec.n_omega)
    if spec.ks_max is not None:
        _check_effort_at_dc(pset, spec.ks_max)
    tf = 0.0
    pi_result: RobustTuning | None = None
    if structure == "pid":
        if spec.tf is None or spec.start is None:
            pi_result = _tune(pset, "pi", spec)
            timings["robust PI"] = pi_result.wall_time_s
        if spec.tf is None:
            # the documented rule: one tenth of the period of the robust PI's fastest crossover
            assert pi_result is not None
            wc = [p.crossover_rad_s for p in pi_result.plants if p.crossover_rad_s]
            wc_max = max(wc) if wc else max(p.ms_frequency_rad_s for p in pi_result.plants)
            tf = 1.0 / (10.0 * wc_max)
            if dt:
                tf = max(tf, dt)
        else:
            tf = float(spec.tf)
    nums, den = pid_basis(structure, dt, tf, spec.integrator)
    n_i = len(nums)
    from_pi = pi_result is not None and spec.start is None
    if from_pi:
        assert pi_result is not None
        w = pi_result.omega  # the PI's (refined) grid: its optimum is feasible there
    t0 = time.perf_counter()
    g = _Grid(pset, w, nums, den, dt, spec.subsamples)
    disks = _Disks(spec)
    timings["grid"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if from_pi:
        assert pi_result is not None
        theta = np.array([pi_result.kp, pi_result.ki, 0.0])
        source = "robust PI"
        if _min_slack(_cell_slack(g, disks, theta)) < -FEAS_TOL:  # same L, same grid: not met
            theta, source = _find_start(pset, g, disks, spec, n_i)
    else:
        theta, source = _find_start(pset, g, disks, spec, n_i)
    timings["start"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    history = [tuple(float(v) for v in theta)]
    solve_time = 0.0
    notes: list[str] = []
    for rnd in range(spec.refine + 1):
        theta, converged, message, el = _iterate(g, disks, theta, spec, history)
        solve_time += el
        if rnd == spec.refine or not converged:
            break
        w2 = _refined_grid(g, disks, theta)
        if w2 is None:
            break
        g2 = _Grid(pset, w2, nums, den, dt, spec.subsamples)
        if _min_slack(_cell_slack(g2, disks, theta)) < -FEAS_TOL:
            notes.append("grid refinement skipped (the iterate misses a refined cell by its sag)")
            break
        g = g2
        notes.append(f"grid refined around the active cells to {g.w.size} points")
    if notes:
        message = "; ".join([message, *notes])
    timings["iterations"] = time.perf_counter() - t0
    timings["solver"] = solve_time
    t0 = time.perf_counter()
    C = _controller_of(theta, g)
    w_check = check_grid(g.w, dt, spec.check_points)
    actives = _active(pset, g, disks, theta)
    checks = check_plant_set(pset, C, grid=w_check, pade_order=spec.pade_order, active=actives)
    timings["check"] = time.perf_counter() - t0
    return RobustTuning(
        structure=structure,
        kp=float(theta[0]),
        ki=float(theta[1]),
        kd=float(theta[2]) if n_i == 3 else 0.0,
        tf=tf,
        dt=dt,
        controller=C,
        spec=spec,
        plants=checks,
        history=tuple(history),
        converged=converged,
        message=message,
        omega=g.w,
        start_source=source,
        timings=tuple(timings.items()),
        wall_time_s=time.perf_counter() - tic,
    )


def robust_pi(plants: Any, *, spec: RobustSpec | None = None, **options: Any) -> RobustTuning:
    """The PI ``kp + ki/s`` (sampled set: ``kp + ki I(z)``) with the largest integral gain that
    keeps ``|S| <= ms`` (and ``|T| <= mt``, ``|K S| <= ks_max`` if given) on every plant.

    ``plants``: an LTI system, a :class:`~drivetrain_ctrl.design.plants.Plant`, a list of them or
    a :class:`~drivetrain_ctrl.design.plants.PlantSet` (exact input delays). Options: the fields
    of :class:`RobustSpec` (``spec`` as a base, keywords override; an unknown keyword is a
    ValueError naming it and its value). Raises :class:`InfeasibleSpecError` when no start is
    found. See the module docstring for the method."""
    return _tune(plants, "pi", spec_with_options(RobustSpec, "robust_pi", spec, options))


def robust_pid(plants: Any, *, spec: RobustSpec | None = None, **options: Any) -> RobustTuning:
    """The PID ``kp + ki/s + kd s/(tf s + 1)`` (sampled: backward-Euler filter) with the largest
    integral gain under the same bounds as :func:`robust_pi`, ``tf`` fixed (``spec.tf`` or the
    rule in :class:`RobustSpec`). Starts from the robust PI (``kd = 0``), so its ``ki`` is at
    least the PI's."""
    return _tune(plants, "pid", spec_with_options(RobustSpec, "robust_pid", spec, options))
