"""H-infinity mixed-sensitivity design (python-control ``augw``/``hinfsyn``, slycot).

:func:`hinf_mixsyn` finds a controller ``K`` for one nominal SISO plant ``G`` (``L = G K``,
negative feedback, ``S = 1/(1 + L)``, ``T = L S``) that minimises

    gamma = || [W1 S; W2 K S; W3 T] ||_inf,

the weights either given as python-control LTI objects or derived from specifications by
:func:`mixsyn_weights`. ``gamma <= 1`` means every weighted bound holds: ``|S| <= 1/|W1|``,
``|K S| <= 1/|W2|``, ``|T| <= 1/|W3|`` at every frequency (the stack is at most sqrt(3) times
stricter than the three bounds taken alone). The plant may be one of a set: the design is made on
``plants[nominal]`` and every plant of the set is checked with the designed controllers.

The traps of the synthesis are guarded, and each guard is said in the result's ``notes``:

* **D12 rank.** With a strictly proper plant and no ``W2``, the control input does not reach the
  performance outputs directly (``D12 = 0``) and the Riccati formulas do not apply. Given weights
  without ``W2`` get a small constant one, ``W2 = 1e-3 |G(j w_ref)|`` (``|KS|`` allowed up to a
  thousand times the gain that puts the crossover at ``w_ref``); a ``W2`` that is itself strictly
  proper is an error naming it.
* **Imaginary-axis poles.** Plant poles on the imaginary axis (integrators, undamped modes) break
  the synthesis assumptions; they are moved into the left half plane by ``axis_shift`` [rad/s]
  (default ``1e-3 w_ref``; a Schur split, the other poles untouched) for the synthesis only, and
  every check uses the true plant. Weights must be stable (an error names the weight and pole).
* **Run time.** The gamma iteration (slycot ``sb10ad``, bisection then scanning, the routine
  python-control's ``hinfsyn`` calls) runs in a separate process under ``time_limit`` [s] (a
  ``multiprocessing`` process that is terminated, never a hang; where ``fork`` is missing or
  the caller is a daemonic pool or Dask worker, a fresh interpreter running
  :mod:`~drivetrain_ctrl.design._hinf_worker`, killed); past it :class:`HinfTimeoutError` says
  what to change. It starts at the first of 1, 10, 100, ... that
  admits a controller rather than at ``hinfsyn``'s 1e100 (the same optimum, fewer iterations).
* **Optimum.** At the optimal gamma the central controller is ill-conditioned (its closed-loop
  norm can exceed gamma by several per cent); as MATLAB's ``hinfsyn`` does, the returned
  controller is the suboptimal one at ``gamma = (1 + gamma_backoff) gamma_opt`` (slycot
  ``sb10ad`` with ``job=4``).

**Independent check.** The weighted closed loop is re-built from ``K`` with python-control
(``feedback``, series) and its norm computed by ``linfnorm`` (slycot ``ab13dd``, a different
algorithm from the synthesis) and, separately, as the largest value on a dense frequency grid;
both are reported beside gamma.

**Reduction.** The controller's slow poles (``|p| < integrator_tol``, default ``1e-2 w_ref``:
the integral action the ``W1`` weight asks for, at ``-1e-4 w_B`` with the derived weights) are
split off exactly (ordered Schur form and a Sylvester equation) and, with ``keep_integrators``,
moved to ``s = 0``: the reduced controller has true integral action. The rest is reduced by
balanced truncation (``control.balred``) to the given ``order``, or (``order=None``) to the
smallest order whose weighted closed-loop norm on the synthesis plant stays within
``reduction_tol`` of gamma. Gain, phase and disk margins, ``Ms``, ``Mt`` and ``max |KS|`` are
reported for every plant with the full and the reduced controller.

**Delay and sampling.** A plant's input delay enters the synthesis as its Pade approximation
(:meth:`~drivetrain_ctrl.design.plants.Plant.with_pade`, ``pade_order``); the margins are
computed on the exact frequency response ``P(jw) exp(-jw delay)``, stability from the poles
with a Pade approximation of ``check_pade_order``. ``dt`` [s] asks for a sampled variant of a
continuous design: the reduced controller discretised by Tustin's rule prewarped at the nominal
crossover (``control.sample_system``), checked on each plant sampled with a zero-order hold and
its delay (exact at the samples, fractional delays included:
:func:`~drivetrain_ctrl.design.certificates.zoh_with_delay`). A set of sampled plants (``dt >
0``) is designed in the w-plane: ``z = (1 + s dt/2)/(1 - s dt/2)`` maps the plant to continuous
time exactly (the H-infinity norm is unchanged by the map), the weights are read in the w-plane
(a specified bandwidth is prewarped, ``(2/dt) tan(w dt/2)``), and the controllers come back by
the same map (Tustin without prewarping): the discrete controller meets exactly the discrete
weighted bound.

Units: frequencies [rad/s], times [s], gains in the plant's units (``K``: plant input per unit
of measured error).
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing as mp
import pickle
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import control
import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from ..core.serialize import json_ready
from ..core.validate import real_number
from . import _hinf_worker
from .checks import LoopCheck, check_plant_set, worst_figures
from .options import frequency_vector, spec_with_options
from .plants import Plant, PlantSet, as_plant_set, frequency_grid

__all__ = [
    "HinfSpec",
    "MixsynWeights",
    "HinfDesign",
    "HinfTimeoutError",
    "HinfSynthesisError",
    "mixsyn_weights",
    "hinf_mixsyn",
    "tustin_to_continuous",
    "shift_axis_poles",
]

F64 = NDArray[np.float64]
C128 = NDArray[np.complex128]


class HinfTimeoutError(TimeoutError):
    """The H-infinity synthesis did not finish within ``time_limit``; the message says what to
    change (the limit, the order of the plant or the weights)."""


class HinfSynthesisError(RuntimeError):
    """slycot found no admissible H-infinity controller, or the augmented plant violates an
    assumption of the synthesis; the message names the cause and what to change."""


# ---------------------------------------------------------------------------------------------
# options
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HinfSpec:
    """What :func:`hinf_mixsyn` designs for (all keyword options; unknown ones are errors).

    Weights (python-control LTI, SISO; continuous, or for a sampled plant set discrete with the
    set's ``dt`` or continuous in the w-plane): ``W1`` on ``S``, ``W2`` on ``K S``, ``W3`` on
    ``T``. Or specifications, turned into weights by :func:`mixsyn_weights`: ``bandwidth``
    [rad/s] (where ``|S|`` reaches 1), ``ms`` (> 1, the high-frequency bound on ``|S|``), ``mt``
    (> 1 or None: no ``W3``), ``effort`` [u/y] (bound on ``|K S|``; None: ten times the gain that
    puts the crossover at the bandwidth), ``low_frequency_gain`` (``|S|`` bound at DC, > 0).
    Give either weights or a bandwidth, not both.

    Design: ``nominal`` index of the plant designed for; ``order`` of the reduced controller
    (None: automatic, ``reduction_tol``); ``keep_integrators`` move the controller's slow poles
    (``|p| < integrator_tol`` [rad/s], None: ``1e-2 w_ref``) to ``s = 0``; ``axis_shift``
    [rad/s] (None: ``1e-3 w_ref``) for plant poles on the imaginary axis; ``dt`` [s] a sampled
    variant of a continuous design (None: none); ``time_limit`` [s] on the synthesis;
    ``gamma_backoff`` the relative distance above the optimal gamma of the returned controller;
    ``pade_order`` of a delay in the synthesis plant, ``check_pade_order`` for closed-loop
    poles; ``check_points`` of the dense check grid (``omega`` [rad/s] to give it instead).
    ``w_ref`` is the bandwidth, else the frequency where ``|W1|`` falls to 1, else the middle
    (log) of the nominal plant's grid.
    """

    W1: Any = None
    W2: Any = None
    W3: Any = None
    bandwidth: float | None = None
    ms: float = 2.0
    mt: float | None = None
    effort: float | None = None
    low_frequency_gain: float = 1e-4
    nominal: int = 0
    order: int | None = None
    reduction_tol: float = 0.05
    keep_integrators: bool = True
    integrator_tol: float | None = None
    axis_shift: float | None = None
    dt: float | None = None
    time_limit: float = 60.0
    gamma_backoff: float = 0.01
    pade_order: int = 3
    check_pade_order: int = 6
    check_points: int = 3000
    omega: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        s = object.__setattr__
        for nm in ("W1", "W2", "W3"):
            W = getattr(self, nm)
            if W is None:
                continue
            if not isinstance(W, control.LTI):
                raise TypeError(f"{nm} = {W!r}: must be a python-control LTI system or None")
            if W.ninputs != 1 or W.noutputs != 1:
                raise ValueError(f"{nm}: must be SISO, got {W.ninputs} in / {W.noutputs} out")
        given_w = any(getattr(self, nm) is not None for nm in ("W1", "W2", "W3"))
        if self.bandwidth is not None:
            s(self, "bandwidth", real_number("bandwidth", self.bandwidth, lo=0, lo_open=True))
            if given_w:
                raise ValueError(
                    f"bandwidth = {self.bandwidth!r} with weights W1/W2/W3: give either the "
                    "weights or the specifications (bandwidth, ms, mt, effort), not both"
                )
        s(self, "ms", real_number("ms", self.ms, lo=1.0, lo_open=True))
        if self.mt is not None:
            s(self, "mt", real_number("mt", self.mt, lo=1.0, lo_open=True))
        if self.effort is not None:
            s(self, "effort", real_number("effort", self.effort, lo=0.0, lo_open=True))
        s(
            self,
            "low_frequency_gain",
            real_number("low_frequency_gain", self.low_frequency_gain, lo=0, hi=1, lo_open=True),
        )
        for nm, lo in (("nominal", 0), ("pade_order", 1), ("check_pade_order", 1)):
            v = getattr(self, nm)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
                raise ValueError(f"{nm} = {v!r}: must be an integer >= {lo}")
            s(self, nm, int(v))
        v = self.check_points
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 50:
            raise ValueError(f"check_points = {v!r}: must be an integer >= 50")
        if self.order is not None:
            o = self.order
            if isinstance(o, bool) or not isinstance(o, int | np.integer) or o < 0:
                raise ValueError(f"order = {o!r}: must be an integer >= 0 or None (automatic)")
            s(self, "order", int(o))
        s(self, "reduction_tol", real_number("reduction_tol", self.reduction_tol, lo=0.0))
        if not isinstance(self.keep_integrators, bool):
            raise TypeError(f"keep_integrators = {self.keep_integrators!r}: must be True or False")
        for nm, unit in (("integrator_tol", "rad/s"), ("axis_shift", "rad/s"), ("dt", "s")):
            if getattr(self, nm) is not None:
                s(self, nm, real_number(nm, getattr(self, nm), lo=0, lo_open=True, unit=unit))
        s(
            self,
            "time_limit",
            real_number("time_limit", self.time_limit, lo=0, lo_open=True, unit="s"),
        )
        s(
            self,
            "gamma_backoff",
            real_number("gamma_backoff", self.gamma_backoff, lo=1e-6, hi=1.0),
        )
        if self.omega is not None:
            s(self, "omega", frequency_vector("omega", self.omega, 10))

    @property
    def weights_given(self) -> bool:
        """True if the user gave at least one weight (no specification-derived weights)."""
        return any(getattr(self, nm) is not None for nm in ("W1", "W2", "W3"))

    def to_dict(self) -> dict[str, Any]:
        """The options as a JSON-ready dict (weights as their transfer-function coefficients)."""
        d: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, control.LTI):
                t = control.tf(v)
                v = {"num": t.num[0][0].tolist(), "den": t.den[0][0].tolist(), "dt": t.dt}
            d[f.name] = v
        return json_ready(d)


# ---------------------------------------------------------------------------------------------
# weights
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MixsynWeights:
    """The three weights of a mixed-sensitivity design (continuous StateSpace or None) and a
    sentence saying where they come from (``rule``)."""

    W1: control.StateSpace | None
    W2: control.StateSpace | None
    W3: control.StateSpace | None
    rule: str

    def summary(self) -> str:
        return self.rule


def mixsyn_weights(
    plant: Any,
    *,
    bandwidth: float,
    ms: float = 2.0,
    mt: float | None = None,
    effort: float | None = None,
    low_frequency_gain: float = 1e-4,
) -> MixsynWeights:
    """Weights from specifications, by the rule of Skogestad and Postlethwaite (Multivariable
    Feedback Control, 2nd ed., eq. 2.72; MATLAB's ``makeweight``):

    * ``W1(s) = (s/ms + w_B)/(s + w_B A)``: the bound ``1/|W1|`` on ``|S|`` is ``A`` at DC
      (``low_frequency_gain``, near-integral action), rises by 20 dB/decade, reaches 1 at about
      ``w_B`` (``bandwidth`` [rad/s]) and ``ms`` at high frequency;
    * ``W2 = 1/effort`` (constant): ``|K S| <= effort`` [u/y]; None: ``effort = 10/|G(j w_B)|``,
      ten times the controller gain that puts the crossover at ``w_B`` (``plant``: a continuous
      SISO LTI or :class:`~drivetrain_ctrl.design.plants.Plant`, its exact response used);
    * ``W3 = 1/mt`` (constant, only when ``mt`` is given): ``|T| <= mt``.

    ``gamma <= 1`` then means the three bounds hold. Returns :class:`MixsynWeights`.
    """
    wb = real_number("bandwidth", bandwidth, lo=0, lo_open=True, unit="rad/s")
    ms = real_number("ms", ms, lo=1.0, lo_open=True)
    A = real_number("low_frequency_gain", low_frequency_gain, lo=0, hi=1, lo_open=True)
    W1 = control.ss(control.tf([1.0 / ms, wb], [1.0, wb * A]))
    parts = [
        f"W1 = (s/{ms:g} + {wb:.4g})/(s + {wb * A:.4g}) (|S| <= {A:g} at DC, 1 at about "
        f"{wb:.4g} rad/s, {ms:g} above)"
    ]
    if effort is None:
        p = plant if isinstance(plant, Plant) else Plant(plant)
        g = abs(complex(p.freqresp(np.array([wb]))[0]))
        if not (math.isfinite(g) and g > 0):
            raise ValueError(
                f"effort: |G(j {wb:g})| = {g!r}; give effort [u/y] explicitly (the default "
                "needs a finite, nonzero plant gain at the bandwidth)"
            )
        eff = 10.0 / g
        parts.append(f"W2 = 1/{eff:.4g} (|KS| <= 10/|G(j w_B)| = {eff:.4g}, the default effort)")
    else:
        eff = real_number("effort", effort, lo=0, lo_open=True)
        parts.append(f"W2 = 1/{eff:.4g} (|KS| <= effort)")
    W2 = control.ss([], [], [], [[1.0 / eff]])
    W3 = None
    if mt is not None:
        mt = real_number("mt", mt, lo=1.0, lo_open=True)
        W3 = control.ss([], [], [], [[1.0 / mt]])
        parts.append(f"W3 = 1/{mt:g} (|T| <= {mt:g})")
    else:
        parts.append("no W3 (no Mt bound)")
    return MixsynWeights(W1, W2, W3, "; ".join(parts))


# ---------------------------------------------------------------------------------------------
# state-space helpers
# ---------------------------------------------------------------------------------------------


def tustin_to_continuous(sys: Any) -> control.StateSpace:
    """The continuous (w-plane) system ``Gc(s) = Gd((1 + s dt/2)/(1 - s dt/2))`` of a discrete
    ``sys`` (the inverse of Tustin's rule without prewarping): ``Gc(j nu) = Gd(exp(j w dt))`` at
    ``nu = (2/dt) tan(w dt/2)``, so the H-infinity norm is the same. Needs no pole at ``z = -1``.
    """
    ss = control.ss(sys)
    dt = ss.dt
    if not (dt and dt is not True and dt > 0):
        raise ValueError(f"tustin_to_continuous: sys.dt = {dt!r}: a discrete system is needed")
    a = 2.0 / float(dt)
    n = ss.nstates
    if n == 0:
        return control.ss([], [], [], ss.D)
    Id = np.eye(n)
    IA = Id + ss.A
    if np.linalg.cond(IA) > 1e12:
        raise ValueError(
            "tustin_to_continuous: the system has a pole at z = -1 (the Nyquist frequency), "
            "which the w-plane map sends to infinity"
        )
    M = np.linalg.inv(IA)
    r = math.sqrt(2.0 * a)
    Ac = a * (ss.A - Id) @ M
    Bc = r * M @ ss.B
    Cc = r * ss.C @ M
    Dc = ss.D - ss.C @ M @ ss.B
    return control.ss(Ac, Bc, Cc, Dc)


def _schur_split(A: F64, select: Any) -> tuple[F64, F64, F64, int]:
    """Real Schur form ``A = Z T Z^T`` with the eigenvalues chosen by ``select(lam) -> bool``
    first, then the coupling block removed: returns ``(T, V, Vinv, k)`` with ``Vinv Z^T A Z V``
    block diagonal ``diag(T11, T22)`` (``k`` the size of ``T11``), ``V = Z [[I, X], [0, I]]``."""
    n = A.shape[0]

    def sel(re: float, im: float) -> bool:
        return bool(select(complex(re, im)))

    T, Z, k = sla.schur(A, output="real", sort=sel)
    k = int(k)
    if 0 < k < n:
        T11, T12, T22 = T[:k, :k], T[:k, k:], T[k:, k:]
        X = sla.solve_sylvester(T11, -T22, -T12)
        W = np.eye(n)
        W[:k, k:] = X
        Wi = np.eye(n)
        Wi[:k, k:] = -X
        T = Wi @ T @ W
        T[:k, k:] = 0.0
        T[k:, :k] = 0.0
        V = Z @ W
        Vi = Wi @ Z.T
    else:
        V, Vi = Z, Z.T
    return T, V, Vi, k


def shift_axis_poles(
    sys: Any, shift: float, *, tol: float | None = None
) -> tuple[control.StateSpace, int]:
    """``sys`` (continuous) with its poles on the imaginary axis (``|Re p| <= tol``, default
    ``1e-9 max(1, |p|)``) moved left by ``shift`` [rad/s], the other poles and the realisation of
    the rest unchanged (ordered real Schur form: the axis block ``T11`` becomes ``T11 - shift
    I``). Returns the shifted StateSpace and the number of poles moved."""
    shift = real_number("shift", shift, lo=0, lo_open=True, unit="rad/s")
    ss = control.ss(sys)
    if ss.nstates == 0:
        return ss, 0

    def on_axis(lam: complex) -> bool:
        t = tol if tol is not None else 1e-9 * max(1.0, abs(lam))
        return abs(lam.real) <= t

    T, Z, k = sla.schur(
        np.asarray(ss.A, dtype=float), output="real", sort=lambda re, im: on_axis(complex(re, im))
    )
    k = int(k)
    if k == 0:
        return ss, 0
    T = T.copy()
    T[:k, :k] -= shift * np.eye(k)
    A2 = Z @ T @ Z.T
    return control.ss(A2, ss.B, ss.C, ss.D, ss.dt), k


def _stable(sys: control.StateSpace) -> bool:
    if sys.nstates == 0:
        return True
    ev = np.linalg.eigvals(sys.A)
    if sys.dt:
        return bool(np.all(np.abs(ev) < 1.0))
    return bool(np.all(ev.real < 0.0))


def _weighted_loop(G: Any, K: Any, W1: Any, W2: Any, W3: Any) -> control.StateSpace:
    """``[W1 S; W2 K S; W3 T]`` (input the reference, up to three outputs) of ``G`` and ``K``
    (``L = G K``, negative feedback) connected by ``control.interconnect``: the error ``e = r -
    y`` weighted by W1, the control ``u = K e`` by W2 and the output ``y = G u`` by W3; every state
    of the plant, the controller and the weights appears once."""
    dt = control.ss(G).dt
    Gs = control.ss(G, inputs="u", outputs="y", name="G")
    Ks = control.ss(K, inputs="e", outputs="u", name="K")
    err = control.summing_junction(inputs=["r", "-y"], output="e", dt=dt, name="sum")
    blocks: list[Any] = [Gs, Ks, err]
    outs = []
    for i, (W, sig) in enumerate(((W1, "e"), (W2, "u"), (W3, "y")), start=1):
        if W is not None:
            blocks.append(control.ss(W, inputs=sig, outputs=f"z{i}", name=f"W{i}"))
            outs.append(f"z{i}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cl = control.interconnect(blocks, inplist=["r"], outlist=outs)
    return control.ss(cl.A, cl.B, cl.C, cl.D, dt)


def _norm(sys: control.StateSpace) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return float(control.linfnorm(sys)[0])


def _grid_norm(sys: control.StateSpace, w: F64) -> float:
    dt = sys.dt
    x = np.exp(1j * w * dt) if dt else 1j * w
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        h = np.asarray(sys(x, warn_infinite=False), dtype=complex).reshape(sys.noutputs, -1)
    return float(np.max(np.sqrt(np.sum(np.abs(h) ** 2, axis=0))))


# ---------------------------------------------------------------------------------------------
# synthesis in a process that can be abandoned
# ---------------------------------------------------------------------------------------------


_SLYCOT_INFO = {
    1: (
        "the matrix [A - jwI, B2; C1, D12] loses column rank at some w: a zero of the plant on "
        "the imaginary axis (e.g. a differentiator), or W2/W3 vanishing there; move it off the "
        "axis"
    ),
    2: (
        "the matrix [A - jwI, B1; C2, D21] loses row rank at some w: a pole of the plant or of "
        "W1 on the imaginary axis that was not shifted; move it into the left half plane"
    ),
    3: "D12 is not of full column rank: give W2 a nonzero direct feedthrough",
    4: "D21 is not of full row rank",
    6: "no admissible controller (gamma too small)",
    7: "the X-Riccati equation has no stabilising solution",
    8: "the Y-Riccati equation has no stabilising solution",
    12: "no stabilising controller exists for these weights",
}


def _synthesis_worker(conn: Any, *args: Any) -> None:
    """In a forked child: :func:`~drivetrain_ctrl.design._hinf_worker.run`, the result sent
    through ``conn``."""
    try:
        conn.send(_hinf_worker.run(args))
    finally:
        conn.close()


def _can_fork() -> bool:
    """Whether the synthesis can run in a forked ``multiprocessing`` child: ``fork`` exists and
    this process is not daemonic (a daemonic process may not have children)."""
    return "fork" in mp.get_all_start_methods() and not mp.current_process().daemon


def _run_forked(args: tuple[Any, ...], time_limit: float) -> tuple[bool, Any, str]:
    """(finished, message, how it ended) of the worker in a forked child, terminated past
    ``time_limit``."""
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_synthesis_worker, args=(send, *args), daemon=True)
    proc.start()
    send.close()
    try:
        ready = recv.poll(time_limit)
        msg = recv.recv() if ready else None
    except EOFError:
        msg, ready = None, True
    finally:
        if proc.is_alive() and not ready:
            proc.terminate()
        proc.join(5.0)
        if proc.is_alive():
            proc.kill()
            proc.join()
        recv.close()
    return ready, msg, f"exit code {proc.exitcode}"


def _run_script(args: tuple[Any, ...], time_limit: float) -> tuple[bool, Any, str]:
    """The same in a fresh interpreter running the worker module as a script (numpy and slycot
    only), killed past ``time_limit`` (its start-up counts)."""
    cmd = [sys.executable, "-I", str(Path(_hinf_worker.__file__).resolve())]
    try:
        done = subprocess.run(
            cmd, input=pickle.dumps(args), capture_output=True, timeout=time_limit, check=False
        )
    except subprocess.TimeoutExpired:
        return False, None, "killed"
    if done.returncode != 0 or not done.stdout:
        err = done.stderr.decode(errors="replace").strip().splitlines()[-1:] or [""]
        return True, None, f"exit code {done.returncode} {err[0]}"
    return True, pickle.loads(done.stdout), "exit code 0"


def _synthesise(P: control.StateSpace, time_limit: float, backoff: float) -> tuple[Any, ...]:
    """The gamma iteration (:mod:`~drivetrain_ctrl.design._hinf_worker`) in a child process under
    ``time_limit`` [s]: forked where possible, else a fresh interpreter; returns ``(gamma_opt,
    gamma, K, rcond, seconds)``."""
    mats = [np.ascontiguousarray(np.asarray(M, dtype=float)) for M in (P.A, P.B, P.C, P.D)]
    args: tuple[Any, ...] = (*mats, float(backoff))
    t0 = time.perf_counter()
    run = _run_forked if _can_fork() else _run_script
    ready, msg, how = run(args, time_limit)
    elapsed = time.perf_counter() - t0
    if not ready:
        raise HinfTimeoutError(
            f"H-infinity synthesis did not finish within time_limit = {time_limit:g} s (slycot's "
            f"gamma iteration on an augmented plant of order {P.nstates}); stopped. Raise "
            "time_limit, or lower the order: reduce the plant (control.balred) or the delay's "
            "pade_order, use first-order weights, or relax the specification (a lower "
            "bandwidth, larger ms/mt/effort)"
        )
    if msg is None:
        raise HinfSynthesisError(f"H-infinity synthesis process ended without a result ({how})")
    if msg[0] == "error":
        _, name, text, info = msg
        why = _SLYCOT_INFO.get(info, "") if isinstance(info, int) else ""
        raise HinfSynthesisError(
            f"H-infinity synthesis failed ({name}: {text.strip()})"
            + (f": {why}" if why else "")
            + ". Relax the weights (a lower bandwidth, larger ms, mt or effort) or check the "
            "plant (stabilisable, detectable, no imaginary-axis zeros)"
        )
    _, gam_opt, gam, (Ak, Bk, Ck, Dk), rcond = msg
    K = control.ss(Ak, Bk, Ck, Dk)
    return gam_opt, gam, K, np.asarray(rcond, dtype=float), elapsed


# ---------------------------------------------------------------------------------------------
# loop checks
# ---------------------------------------------------------------------------------------------


# ---------------------------------------------------------------------------------------------
# result
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class HinfDesign:
    """The result of :func:`hinf_mixsyn`.

    Controllers (python-control StateSpace, ``u = K e``, ``e = r - y``): ``controller`` the full
    order synthesis result, ``controller_reduced`` after balanced truncation (integrators kept),
    both continuous for continuous plants and discrete for a sampled set; ``controller_sampled``
    the reduced controller discretised by Tustin for ``dt`` (None without ``dt``).

    Figures: ``gamma`` the bound of the returned controller (``(1 + gamma_backoff)
    gamma_optimal``), ``gamma_optimal`` slycot's estimate of the optimum; ``norm_check`` the
    weighted closed-loop norm re-computed by ``control.linfnorm``, ``norm_check_grid`` its
    largest value on the dense grid, ``norm_reduced`` the same with the reduced controller (all
    on the synthesis plant; for a sampled set in discrete time); ``specs_met`` is ``gamma <= 1``.
    ``checks_full``, ``checks_reduced``, ``checks_sampled``: :class:`~drivetrain_ctrl.design.checks.LoopCheck` per plant of
    the set. ``weights`` (:class:`MixsynWeights`, continuous / w-plane), ``synthesis_plant`` the
    plant the synthesis saw (Pade, shifted poles; w-plane for a sampled set), ``nominal`` its
    index, ``integrators`` the number of controller poles moved to 0 (or kept as slow poles),
    ``hankel_singular_values`` of the controller's fast part, ``dt`` [s] (0: continuous),
    ``synthesis_time_s``, ``rcond`` (slycot's four reciprocal condition estimates), ``notes``:
    every guard that acted, in words.
    """

    controller: control.StateSpace
    controller_reduced: control.StateSpace
    controller_sampled: control.StateSpace | None
    gamma: float
    gamma_optimal: float
    norm_check: float
    norm_check_grid: float
    norm_reduced: float
    specs_met: bool
    checks_full: tuple[LoopCheck, ...]
    checks_reduced: tuple[LoopCheck, ...]
    checks_sampled: tuple[LoopCheck, ...]
    weights: MixsynWeights
    synthesis_plant: control.StateSpace
    nominal: int
    integrators: int
    hankel_singular_values: tuple[float, ...]
    dt: float
    synthesis_time_s: float
    rcond: tuple[float, ...]
    notes: tuple[str, ...]
    spec: HinfSpec

    @property
    def order_full(self) -> int:
        return int(self.controller.nstates)

    @property
    def order_reduced(self) -> int:
        return int(self.controller_reduced.nstates)

    @property
    def norm_error(self) -> float:
        """``|norm_check - gamma| / gamma``: how far the independent check is from gamma."""
        return abs(self.norm_check - self.gamma) / self.gamma

    def summary(self) -> str:
        """One paragraph: gamma and its check, orders, the worst margins over the set."""

        def worst(checks: tuple[LoopCheck, ...]) -> str:
            if not checks:
                return "-"
            w = worst_figures(checks)
            pm = (
                "-" if w["phase_margin_deg_min"] is None else f"{w['phase_margin_deg_min']:.1f} deg"
            )
            gm = "inf" if w["gain_margin_db_min"] is None else f"{w['gain_margin_db_min']:.1f} dB"
            bad = ", ".join(c.name for c in checks if not c.stable)
            return (
                f"{'UNSTABLE on ' + bad if bad else 'all stable'}"
                f", worst PM {pm}, GM {gm}, Ms {w['ms_max']:.3g}"
            )

        met = (
            "specifications met (gamma <= 1)"
            if self.specs_met
            else (
                f"specifications NOT met: gamma = {self.gamma:.4g} > 1, the weighted bounds are "
                "exceeded by up to that factor"
            )
        )
        s = (
            f"H-infinity mixed sensitivity: gamma = {self.gamma:.4g} (optimum {self.gamma_optimal:.4g}; "
            f"re-checked {self.norm_check:.4g} by linfnorm, {self.norm_check_grid:.4g} on the grid), "
            f"{met}. Controller order {self.order_full} -> {self.order_reduced} "
            f"({self.integrators} integrator{'s' if self.integrators != 1 else ''} kept; weighted "
            f"norm {self.norm_reduced:.4g}). Full: {worst(self.checks_full)}. Reduced: "
            f"{worst(self.checks_reduced)}."
        )
        if self.controller_sampled is not None:
            s += f" Sampled ({self.spec.dt:g} s, Tustin): {worst(self.checks_sampled)}."
        if self.notes:
            s += " Notes: " + " ".join(self.notes)
        return s

    def to_dict(self) -> dict[str, Any]:
        def tfd(K: control.StateSpace | None) -> Any:
            if K is None:
                return None
            t = control.tf(K)
            return {"num": t.num[0][0].tolist(), "den": t.den[0][0].tolist(), "dt": t.dt or 0.0}

        return json_ready(
            {
                "gamma": self.gamma,
                "gamma_optimal": self.gamma_optimal,
                "norm_check": self.norm_check,
                "norm_check_grid": self.norm_check_grid,
                "norm_reduced": self.norm_reduced,
                "specs_met": self.specs_met,
                "order_full": self.order_full,
                "order_reduced": self.order_reduced,
                "integrators": self.integrators,
                "hankel_singular_values": list(self.hankel_singular_values),
                "controller_reduced": tfd(self.controller_reduced),
                "controller_sampled": tfd(self.controller_sampled),
                "checks_full": [c.to_dict() for c in self.checks_full],
                "checks_reduced": [c.to_dict() for c in self.checks_reduced],
                "checks_sampled": [c.to_dict() for c in self.checks_sampled],
                "weights": self.weights.rule,
                "nominal": self.nominal,
                "dt": self.dt,
                "synthesis_time_s": self.synthesis_time_s,
                "rcond": list(self.rcond),
                "notes": list(self.notes),
                "spec": self.spec.to_dict(),
            }
        )


# ---------------------------------------------------------------------------------------------
# the design
# ---------------------------------------------------------------------------------------------


def _to_design_plane(W: Any, name: str, dt: float) -> control.StateSpace:
    """A weight as a continuous StateSpace (a sampled set: discrete weights with the set's dt
    mapped to the w-plane, continuous ones taken as w-plane weights)."""
    Ws = control.ss(W)
    wdt = Ws.dt
    if wdt and wdt is not True and wdt > 0:
        if not dt:
            raise ValueError(f"{name}: a discrete weight (dt = {wdt!r}) for continuous plants")
        if abs(float(wdt) - dt) > 1e-12 * dt:
            raise ValueError(f"{name}.dt = {wdt!r}: must equal the plants' dt = {dt!r} s")
        Ws = tustin_to_continuous(Ws)
    elif wdt is True:
        raise ValueError(f"{name}.dt = True: give the sample period in seconds")
    if Ws.nstates:
        ev = np.linalg.eigvals(Ws.A)
        bad = ev[ev.real >= -1e-12 * np.maximum(1.0, np.abs(ev))]
        if bad.size:
            raise ValueError(
                f"{name} has the pole {complex(bad[0]):.4g} on or right of the imaginary axis: an "
                "H-infinity weight must be stable (its states are not seen by the controller); "
                "move it to a small negative value, e.g. W1 = (s/M + wB)/(s + wB*A) with A = 1e-4"
            )
    return control.ss(Ws.A, Ws.B, Ws.C, Ws.D)


def _unity_crossing(W: control.StateSpace, lo: float, hi: float) -> float | None:
    w = np.logspace(math.log10(lo), math.log10(hi), 2000)
    m = np.abs(np.asarray(W(1j * w), dtype=complex).reshape(-1))
    idx = np.flatnonzero((m[:-1] - 1.0) * (m[1:] - 1.0) <= 0)
    return float(w[idx[0]]) if idx.size else None


def _split_slow(K: control.StateSpace, tol: float) -> tuple[control.StateSpace, control.StateSpace]:
    """``K = K_slow + K_fast`` exactly: the poles with ``|p| < tol`` in ``K_slow`` (no direct
    term), the rest in ``K_fast``."""
    if K.nstates == 0:
        return control.ss([], [], [], [[0.0]]), K
    T, V, Vi, k = _schur_split(np.asarray(K.A, dtype=float), lambda lam: abs(lam) < tol)
    B = Vi @ K.B
    C = K.C @ V
    Ks = (
        control.ss(T[:k, :k], B[:k], C[:, :k], np.zeros((1, 1)))
        if k
        else control.ss([], [], [], [[0.0]])
    )
    Kf = (
        control.ss(T[k:, k:], B[k:], C[:, k:], K.D)
        if k < K.nstates
        else control.ss([], [], [], K.D)
    )
    return Ks, Kf


def _snap(Ks: control.StateSpace) -> tuple[control.StateSpace, bool]:
    """The slow part with its real poles moved to exactly 0 (the upper-triangular Schur block's
    diagonal zeroed); a slow complex pair is left as it is (returns False)."""
    if Ks.nstates == 0:
        return Ks, True
    A = np.asarray(Ks.A, dtype=float)
    if np.any(np.abs(np.tril(A, -1)) > 0):
        return Ks, False
    return control.ss(np.triu(A, 1), Ks.B, Ks.C, Ks.D), True


def _reduce(Kf: control.StateSpace, r: int) -> control.StateSpace:
    if r >= Kf.nstates:
        return Kf
    if r == 0:
        return control.ss([], [], [], Kf.D)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return control.ss(control.balred(Kf, r, method="truncate"))


def _parallel(a: control.StateSpace, b: control.StateSpace) -> control.StateSpace:
    return control.ss(control.parallel(a, b))


def _reference_frequency(sp: HinfSpec, nom: Plant, dt: float) -> float:
    """``w_ref`` [rad/s] in the design plane: the bandwidth (prewarped for a sampled set), else
    where ``|W1|`` falls to 1, else the log-middle of the nominal plant's grid (warped)."""
    if sp.bandwidth is not None:
        w = float(sp.bandwidth)
        if dt:
            if w >= math.pi / dt:
                raise ValueError(
                    f"bandwidth = {w!r} rad/s: must be below the Nyquist frequency "
                    f"{math.pi / dt:.6g} rad/s of the sampled plants"
                )
            w = 2.0 / dt * math.tan(w * dt / 2.0)
        return w
    g0 = frequency_grid(nom, n=50)
    if sp.W1 is not None:
        W1c = _to_design_plane(sp.W1, "W1", dt)
        hit = _unity_crossing(W1c, float(g0[0]) / 100, float(g0[-1]) * 100)
        if hit is not None:
            return hit
    mid = float(math.sqrt(g0[0] * g0[-1]))
    return 2.0 / dt * math.tan(min(mid * dt / 2.0, 1.4)) if dt else mid


def hinf_mixsyn(plants: Any, *, spec: HinfSpec | None = None, **options: Any) -> HinfDesign:
    """H-infinity mixed-sensitivity design for ``plants[nominal]``, checked on every plant.

    ``plants``: anything :func:`~drivetrain_ctrl.design.plants.as_plant_set` accepts (an LTI, a
    :class:`~drivetrain_ctrl.design.plants.Plant` with a delay, a list, a PlantSet); one common
    timebase. ``spec``: :class:`HinfSpec`; ``options`` override its fields (an unknown one is a
    ValueError naming it and its value). Returns :class:`HinfDesign`; raises
    :class:`HinfTimeoutError` past ``time_limit`` and :class:`HinfSynthesisError` when slycot
    finds no controller (both say what to change). See the module docstring for the method.
    """
    sp = spec_with_options(HinfSpec, "hinf_mixsyn", spec, options)
    pset = as_plant_set(plants)
    dt = pset.dt
    if sp.nominal >= len(pset):
        raise ValueError(f"nominal = {sp.nominal}: the set has {len(pset)} plants")
    if dt and sp.dt is not None:
        raise ValueError(
            f"dt = {sp.dt!r}: the plants are already sampled (dt = {dt:g} s); the design is "
            "discrete, leave dt out"
        )
    if not sp.weights_given and sp.bandwidth is None:
        raise ValueError(
            "hinf_mixsyn: give the weights (W1, W2, W3 as LTI) or the specifications "
            "(bandwidth [rad/s], and optionally ms, mt, effort)"
        )
    notes: list[str] = []
    nom = pset[sp.nominal]

    # the synthesis plant, continuous (w-plane for a sampled set)
    G = control.ss(nom.with_pade(sp.pade_order))
    if nom.delay and not nom.is_discrete:
        notes.append(
            f"The delay {nom.delay:g} s entered the synthesis as a Pade approximation of order "
            f"{sp.pade_order}; the checks use the exact delay."
        )
    if dt:
        G = tustin_to_continuous(G)
    G = control.ss(G.A, G.B, G.C, G.D)

    # reference frequency: bandwidth, else |W1| = 1, else the middle of the plant's grid
    w_ref = _reference_frequency(sp, nom, dt)

    # imaginary-axis poles of the plant
    shift = sp.axis_shift if sp.axis_shift is not None else 1e-3 * w_ref
    G, n_shift = shift_axis_poles(G, shift)
    if n_shift:
        notes.append(
            f"{n_shift} plant pole{'s' if n_shift > 1 else ''} on the imaginary axis "
            f"(integrator{'s' if n_shift > 1 else ''} or undamped modes) moved to Re p = "
            f"-{shift:.3g} rad/s for the synthesis (the synthesis assumes none); the checks use "
            "the true plant."
        )

    # weights
    if sp.weights_given:
        W1 = None if sp.W1 is None else _to_design_plane(sp.W1, "W1", dt)
        W2 = None if sp.W2 is None else _to_design_plane(sp.W2, "W2", dt)
        W3 = None if sp.W3 is None else _to_design_plane(sp.W3, "W3", dt)
        rule = "weights given" + (" (discrete ones mapped to the w-plane)" if dt else "")
    else:
        mw = mixsyn_weights(
            Plant(G),
            bandwidth=w_ref,
            ms=sp.ms,
            mt=sp.mt,
            effort=sp.effort,
            low_frequency_gain=sp.low_frequency_gain,
        )
        W1, W2, W3, rule = mw.W1, mw.W2, mw.W3, mw.rule
        if dt:
            rule += f" (in the w-plane; bandwidth prewarped to {w_ref:.4g} rad/s)"
    if W1 is None and W3 is None:
        raise ValueError("hinf_mixsyn: W1 and W3 are both None; at least W1 or W3 is needed")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        P = control.augw(G, W1, W2, W3)
    nz = P.noutputs - 1
    if np.linalg.matrix_rank(np.asarray(P.D)[:nz, -1:], tol=1e-12) < 1:
        if W2 is not None:
            raise ValueError(
                "W2: the plant is strictly proper and W2 has no direct feedthrough, so D12 is "
                "rank deficient and the H-infinity formulas do not apply; give W2 a nonzero "
                "high-frequency gain (e.g. a constant)"
            )
        gref = abs(complex(G(1j * w_ref)))
        eps = 1e-3 * gref if gref > 0 and math.isfinite(gref) else 1e-3
        W2 = control.ss([], [], [], [[eps]])
        notes.append(
            f"W2 was not given and the plant is strictly proper (D12 would be rank deficient): a "
            f"small constant W2 = {eps:.3g} was added (|KS| allowed up to {1 / eps:.3g}, a "
            f"thousand times the gain that puts the crossover at {w_ref:.3g} rad/s); give W2 to "
            "choose the effort bound."
        )
        rule += f"; W2 = {eps:.3g} added (D12 rank)"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            P = control.augw(G, W1, W2, W3)
    weights = MixsynWeights(W1, W2, W3, rule)

    # synthesis under the time limit
    gam_opt, gam, K, rcond, t_syn = _synthesise(P, sp.time_limit, sp.gamma_backoff)

    # independent re-check of the weighted closed-loop norm
    wchk = np.asarray(sp.omega, dtype=float) if sp.omega is not None else None
    if dt:
        Kd = control.ss(control.sample_system(K, dt, method="tustin"))
        Gd = control.sample_system(G, dt, method="tustin")
        Wd = [
            None if W is None else control.sample_system(W, dt, method="tustin")
            for W in (W1, W2, W3)
        ]
        cl = _weighted_loop(Gd, Kd, *Wd)
        wg = (
            wchk
            if wchk is not None
            else frequency_grid(
                Plant(Gd), n=sp.check_points, crossover=2.0 / dt * math.atan(w_ref * dt / 2.0)
            )
        )
    else:
        cl = _weighted_loop(G, K, W1, W2, W3)
        wg = (
            wchk
            if wchk is not None
            else frequency_grid(Plant(G), n=sp.check_points, crossover=w_ref)
        )
    if not _stable(cl):
        raise HinfSynthesisError(
            "the synthesised controller does not stabilise the synthesis plant (a numerical "
            "failure of the synthesis); relax the weights or rescale the plant"
        )
    norm_check = _norm(cl)
    norm_grid = _grid_norm(cl, wg)

    # reduction (in the design plane), integrators kept
    itol = sp.integrator_tol if sp.integrator_tol is not None else 1e-2 * w_ref
    Ks_, Kf = _split_slow(K, itol)
    n_int = int(Ks_.nstates)
    if n_int and sp.keep_integrators:
        Ks_, snapped = _snap(Ks_)
        if snapped:
            notes.append(
                f"{n_int} controller pole{'s' if n_int > 1 else ''} below {itol:.3g} rad/s "
                "(the integral action W1 asks for) moved to s = 0 in the reduced controller."
            )
        else:
            notes.append(
                "A slow complex controller pole pair was kept as it is (not an integrator)."
            )
    hsv: tuple[float, ...] = ()
    if Kf.nstates and _stable(Kf):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            hsv = tuple(float(v) for v in np.atleast_1d(control.hsvd(Kf)))

    def reduced(order: int) -> control.StateSpace:
        return _parallel(Ks_, _reduce(Kf, order - n_int)) if n_int else _reduce(Kf, order)

    def red_norm(Kr: control.StateSpace) -> float:
        if dt:
            Krd = control.ss(control.sample_system(Kr, dt, method="tustin"))
            c = _weighted_loop(Gd, Krd, *Wd)
        else:
            c = _weighted_loop(G, Kr, W1, W2, W3)
        return _norm(c) if _stable(c) else math.inf

    n_full = int(K.nstates)
    if sp.order is not None:
        if sp.order < n_int:
            raise ValueError(
                f"order = {sp.order}: below the {n_int} integrator(s) kept; use order >= {n_int} "
                "or keep_integrators=False"
            )
        try:
            K_red = reduced(min(sp.order, n_full))
        except ValueError as exc:
            raise ValueError(f"order = {sp.order}: balanced truncation failed ({exc})") from exc
        n_red = red_norm(K_red)
    else:
        # the reference: the full order with its integrators kept
        K_red, n_red = reduced(n_full), red_norm(reduced(n_full))
        ref = max(n_red, gam) if math.isfinite(n_red) else gam
        for r in range(n_int, n_full):
            try:
                Kr = reduced(r)
            except ValueError:
                continue  # fewer states than unstable poles
            nr = red_norm(Kr)
            if nr <= (1.0 + sp.reduction_tol) * ref:
                K_red, n_red = Kr, nr
                break
    if not math.isfinite(n_red):
        notes.append("The reduced controller does not stabilise the synthesis plant: raise order.")

    # back to discrete for a sampled set
    if dt:
        K_out = control.ss(control.sample_system(K, dt, method="tustin"))
        K_red_out = control.ss(control.sample_system(K_red, dt, method="tustin"))
    else:
        K_out, K_red_out = K, K_red

    # checks on every plant (true plants, exact delay)
    def grid_for(p: Plant | PlantSet, wc: float | None) -> F64:
        if wchk is not None:
            return wchk
        return frequency_grid(p, n=sp.check_points, crossover=wc)

    wc_nom = None
    w_all = grid_for(pset, None if dt else w_ref)
    checks_full = check_plant_set(pset, K_out, grid=w_all, pade_order=sp.check_pade_order)
    checks_red = check_plant_set(pset, K_red_out, grid=w_all, pade_order=sp.check_pade_order)
    wc_nom = checks_red[sp.nominal].crossover_rad_s

    K_samp = None
    checks_samp: tuple[LoopCheck, ...] = ()
    if sp.dt is not None:
        from .certificates import zoh_with_delay

        Ts = sp.dt
        pw = wc_nom if (wc_nom is not None and wc_nom < math.pi / Ts) else None
        K_samp = control.ss(control.sample_system(K_red, Ts, method="tustin", prewarp_frequency=pw))
        sampled = as_plant_set(
            [Plant(zoh_with_delay(p.sys, Ts, delay=p.delay), name=p.name) for p in pset]
        )
        ws = grid_for(sampled, None)
        checks_samp = check_plant_set(sampled, K_samp, grid=ws, pade_order=sp.check_pade_order)
        notes.append(
            f"Sampled variant: Tustin at dt = {Ts:g} s"
            + (f", prewarped at the crossover {pw:.4g} rad/s" if pw else "")
            + "; checked on the zero-order-hold plants with their delays (exact at the samples)."
        )

    return HinfDesign(
        controller=K_out,
        controller_reduced=K_red_out,
        controller_sampled=K_samp,
        gamma=float(gam),
        gamma_optimal=float(gam_opt),
        norm_check=norm_check,
        norm_check_grid=norm_grid,
        norm_reduced=float(n_red),
        specs_met=bool(gam <= 1.0),
        checks_full=checks_full,
        checks_reduced=checks_red,
        checks_sampled=checks_samp,
        weights=weights,
        synthesis_plant=G,
        nominal=sp.nominal,
        integrators=n_int,
        hankel_singular_values=hsv,
        dt=float(dt),
        synthesis_time_s=float(t_syn),
        rcond=tuple(float(v) for v in rcond),
        notes=tuple(notes),
        spec=sp,
    )
