"""PI controllers from specifications: crossover frequency, phase margin, Ms bound.

The job of MATLAB's ``pidtune`` for a PI, which python-control lacks, done in closed form on any
SISO python-control plant (continuous or discrete, with an exact input delay through
:meth:`~drivetrain_ctrl.design.plants.Plant.freqresp`).

The controller is ``C = kp + ki F`` with ``F = 1/s`` (continuous) or, for a discrete plant with
sample period ``Ts``, the discrete integrator ``integrator``
(:mod:`~drivetrain_ctrl.design.controllers`, shared with the robust tuners):

* ``"forward"`` (default; the integrator of the shipped ``pi``/``pi-10ms`` controllers,
  :meth:`~drivetrain_ctrl.control.laws.ControllerSpec.lti`): ``F = Ts / (z - 1)``;
* ``"backward"``: ``F = Ts z / (z - 1)``;
* ``"tustin"``: ``F = (Ts / 2) (z + 1) / (z - 1)``.

**Closed form.** A crossover ``wc`` with phase margin ``PM`` means ``L(jwc) = C P = -exp(j PM)``,
i.e. ``C(jwc) = c := -exp(j PM) / P(jwc)``. With ``kp``, ``ki`` real this is two real equations:
``ki = Im c / Im F(wc)``, ``kp = Re c - ki Re F(wc)``. A PI adds a phase between ``arg F`` (-90
deg continuous; ``-90 - wc Ts/2`` deg forward Euler) and 0 deg; the spec is feasible for a PI
when both gains come out ``>= 0``.

**Choice of the crossover** (``wc`` not given). Among the PIs meeting the specification, the one
with the largest integral gain ``ki`` (best rejection of load disturbances: the integrated error
after a load step is ``1/ki`` times the step, Astrom and Hagglund): with a phase margin (default
60 deg) ``wc`` is scanned for the largest ``ki`` at which the margin is reached with ``kp, ki >=
0``; with an ``ms`` bound on ``|S| = |1/(1 + L)|`` (and the phase margin left free unless given)
``wc`` and the margin are scanned for the largest ``ki`` with ``max |S| <= ms``. The scan runs on
a grid (:func:`~drivetrain_ctrl.design.plants.frequency_grid`), is refined twice around the best
point, and every candidate is checked for closed-loop stability (and, with a given margin, that
no other crossover has a smaller one) before it is accepted. When ``ki`` keeps growing up to the
grid's upper end (a plant without phase lag to limit the crossover, e.g. a first-order lag) that
end is taken and the message says so.

**Infeasible specifications** are never met silently with a worse loop: the result is the
closest design a PI can reach, with ``feasible=False`` and a message saying what was reached
(e.g. 60 deg at a crossover where the plant's phase is already -135 deg would need phase lead:
the closest PI there is a P controller, ``ki = 0``, with 45 deg).

**Achieved figures** are computed independently of the closed form, by the design tools' loop
check (:func:`~drivetrain_ctrl.design.checks.check_loop`, on a dense grid): ``phase_margin``,
``gain_margin_db`` and ``crossover`` by python-control's ``stability_margins`` (of the rational
loop when the plant has no delay, else of the frequency response with the delay applied
exactly); ``ms``,
``mt`` on the grid; ``stable`` from the closed-loop poles; :attr:`PIDesign.margins` (disk
margin, closed-loop poles, :func:`~drivetrain_ctrl.linear.margins.loop_margins`) on the rational
loop. There a continuous delay is a Pade approximation of order ``pade_order`` and a discrete one
``z^-k`` (exact; the delay must then be a multiple of the sample period).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import control
import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from drivetrain_ctrl.core.validate import real_number
from drivetrain_ctrl.design.checks import check_loop
from drivetrain_ctrl.design.controllers import (
    check_integrator,
    integrator_response,
    pid_controller,
)
from drivetrain_ctrl.design.plants import Plant, as_plant_set, frequency_grid
from drivetrain_ctrl.linear.margins import LoopMargins, loop_margins

__all__ = ["PIDesign", "design_pi", "pi_controller_tf", "pi_gains_at"]

#: default phase margin [deg] when neither a margin nor an Ms bound is given
DEFAULT_PHASE_MARGIN = 60.0

#: tolerance [deg] on the achieved phase margin of an accepted scanned design
_PM_TOL_DEG = 0.5

C128 = NDArray[np.complex128]
F64 = NDArray[np.float64]


def pi_controller_tf(kp: float, ki: float, *, dt: float = 0.0, integrator: str = "forward") -> Any:
    """The PI ``kp + ki F`` as a python-control ``TransferFunction``: ``(kp s + ki)/s``
    continuous (``dt = 0``), or discrete with sample period ``dt`` [s] and the discrete
    ``integrator`` (module docstring); :func:`~drivetrain_ctrl.design.controllers.pid_controller`
    with ``kd = 0``. ``kp`` [plant input per error unit], ``ki`` [same per s]."""
    return pid_controller(kp, ki, dt=dt, integrator=integrator)


def _gains(c: C128, F: C128) -> tuple[F64, F64]:
    """``(kp, ki)`` with ``kp + ki F = c`` (real gains; element-wise)."""
    ki = np.imag(c) / np.imag(F)
    kp = np.real(c) - ki * np.real(F)
    return kp, ki


def _target(P: C128, pm_deg: Any) -> C128:
    """The controller response ``c`` putting ``L = c P`` at ``-exp(j PM)``."""
    return -np.exp(1j * np.radians(pm_deg)) / P


def pi_gains_at(
    plant: object, wc: float, phase_margin: float, *, integrator: str | None = None
) -> tuple[float, float]:
    """``(kp, ki)`` of the PI whose loop crosses over at ``wc`` [rad/s] with ``phase_margin``
    [deg] (the closed form of the module docstring, no feasibility check: a negative gain says
    the spec needs phase lead, ``ki < 0``, or more lag than an integrator, ``kp < 0``)."""
    p = _single_plant(plant)
    wc = real_number("wc", wc, lo=0.0, lo_open=True, unit="rad/s")
    w = np.array([wc])
    F = integrator_response(w, p.dt, _integrator(p, integrator))
    kp, ki = _gains(_target(p.freqresp(w), phase_margin), F)
    return float(kp[0]), float(ki[0])


@dataclass(frozen=True)
class PIDesign:
    """A PI designed from specifications (:func:`design_pi`) and what it achieves.

    Gains: ``kp`` [plant input per error unit], ``ki`` [the same per s]; ``dt`` [s] (0.0:
    continuous) and ``integrator`` (``"continuous"`` or the discrete integrator); ``controller`` the
    python-control ``TransferFunction`` ``kp + ki F``. Specification: ``rule`` (how the crossover
    was chosen: ``"given crossover"``, ``"max ki at phase margin"``, ``"max ki under Ms"``),
    ``wc_target`` [rad/s], ``pm_target`` [deg], ``ms_target`` [-] (None where not given).
    Achieved, computed independently of the design (module docstring): ``crossover`` [rad/s],
    ``phase_margin`` [deg], ``gain_margin_db`` [dB] (None: no such crossover), ``ms``, ``mt``,
    ``stable``, ``margins`` (:class:`~drivetrain_ctrl.linear.margins.LoopMargins` of the rational
    loop) and ``delay_model`` (how the delay entered the rational loop). ``feasible`` is False
    when the specification could not be met; ``message`` then says what was reached.
    """

    kp: float
    ki: float
    dt: float
    integrator: str
    controller: Any
    plant: Plant
    rule: str
    wc_target: float | None
    pm_target: float | None
    ms_target: float | None
    crossover: float | None
    phase_margin: float | None
    gain_margin_db: float | None
    ms: float
    mt: float
    stable: bool
    margins: LoopMargins
    delay_model: str
    feasible: bool
    message: str

    def loop(self, *, pade_order: int = 5) -> Any:
        """The rational loop ``C P`` (delay as in :meth:`Plant.with_pade`)."""
        return self.controller * self.plant.with_pade(pade_order)

    def to_spec(
        self,
        name: str,
        *,
        x_r0: float | None = None,
        delay_samples: int | None = None,
        **options: Any,
    ) -> Any:
        """This PI as a clutch controller (a :class:`~drivetrain_ctrl.control.laws.ControllerSpec`,
        saved with ``save_controller``): ``law = "pi"`` for a continuous or forward-Euler PI
        (the shipped PI's integrator), else ``law = "lti"`` with the transfer function. The
        gains act on law (6)'s signed error, as on the plants of
        :func:`~drivetrain_ctrl.design.clutch.clutch_plant_set` (``kp`` [m s/rad], ``ki``
        [m/rad]). ``delay_samples``: the controller's transport delay [samples]; None takes the
        plant's delay in samples (a sampled clutch plant carries the controller's delay).
        ``x_r0`` [m] and ``options`` (``engage_rate_m_s``, ``rate_limit_m_s``, ``anti_windup``,
        ...) are the spec's fields. The design spec and achieved figures go into its ``design``
        table."""
        from drivetrain_ctrl.control.laws import ControllerSpec, spec_from_lti

        if delay_samples is None:
            k = self.plant.delay / self.dt if self.dt else 0.0
            if self.dt and abs(k - round(k)) > 1e-9 * max(1.0, k):
                raise ValueError(
                    f"delay_samples: the plant's delay {self.plant.delay!r} s is not a whole "
                    f"number of samples of {self.dt!r} s; give delay_samples"
                )
            if not self.dt and self.plant.delay:
                raise ValueError(
                    f"delay_samples: the continuous plant has a delay of {self.plant.delay!r} s, "
                    "which a continuous controller file cannot carry; give delay_samples=0 if "
                    "the delay is the plant's own"
                )
            delay_samples = round(k)
        prov: dict[str, Any] = {
            "method": "design_pi",
            "rule": self.rule,
            "plant": self.plant.name,
            "feasible": self.feasible,
        }
        for key, v in (
            ("wc_target_rad_s", self.wc_target),
            ("phase_margin_target_deg", self.pm_target),
            ("ms_target", self.ms_target),
            ("crossover_rad_s", self.crossover),
            ("phase_margin_deg", self.phase_margin),
            ("gain_margin_db", self.gain_margin_db),
            ("ms", self.ms),
            ("mt", self.mt),
        ):
            if v is not None:
                prov[key] = float(v)
        if self.integrator in ("continuous", "forward"):
            return ControllerSpec(
                name=name,
                law="pi",
                kp=self.kp,
                ki=self.ki,
                x_r0=x_r0,
                sample_period_s=self.dt or None,
                delay_samples=int(delay_samples),
                design=prov,
                **options,
            )
        return spec_from_lti(
            self.controller,
            name=name,
            x_r0=x_r0,
            delay_samples=int(delay_samples),
            design=prov,
            **options,
        )

    def summary(self) -> str:
        """One sentence: gains, achieved margins, and the message if the spec was not met."""

        def f(v: float | None, unit: str = "") -> str:
            return "none" if v is None else f"{v:.4g}{unit}"

        kind = "continuous" if self.dt == 0 else f"{self.integrator} Euler, Ts = {self.dt:g} s"
        if self.integrator == "tustin":
            kind = f"Tustin, Ts = {self.dt:g} s"
        head = (
            f"PI ({kind}) for {self.plant.name or 'the plant'}: kp = {self.kp:.4g}, "
            f"ki = {self.ki:.4g} 1/s ({self.rule}); crossover {f(self.crossover, ' rad/s')}, "
            f"phase margin {f(self.phase_margin, ' deg')}, gain margin "
            f"{f(self.gain_margin_db, ' dB')}, Ms {self.ms:.3g}, Mt {self.mt:.3g}, "
            f"closed loop {'stable' if self.stable else 'UNSTABLE'}"
        )
        if self.feasible:
            return head + (f". {self.message}" if self.message else ".")
        return head + f". NOT FEASIBLE: {self.message}"


def _single_plant(plant: object) -> Plant:
    ps = as_plant_set(plant)
    if len(ps) != 1:
        raise ValueError(
            f"plant: design_pi takes one plant, got a set of {len(ps)} ({', '.join(ps.names)}); "
            "use the robust tuning over a plant set, or pick one"
        )
    return ps[0]


def _integrator(p: Plant, integrator: str | None) -> str:
    if p.dt == 0.0:
        if integrator not in (None, "continuous"):
            raise ValueError(
                f"integrator = {integrator!r}: the plant is continuous, so is the PI; a discrete "
                "integrator needs a discrete plant (e.g. control.c2d(P, Ts, 'zoh'))"
            )
        return "continuous"
    if integrator is None:
        return "forward"
    return check_integrator(integrator)


def _dense_grid(p: Plant, wc: float | None) -> F64:
    return frequency_grid(p, n=3000, crossover=wc)


def _delay_model(p: Plant, pade_order: int) -> str:
    if not p.delay:
        return "no delay"
    if p.dt:
        return f"z^-{round(p.delay / p.dt)} (exact)"
    return f"Pade approximation of order {pade_order} of the {p.delay:g} s delay"


# ---------------------------------------------------------------------------------------------
# the design
# ---------------------------------------------------------------------------------------------


def _low_frequency_sign(p: Plant) -> float:
    """Sign of the plant's gain at low frequency with its integrators (poles at s = 0 or
    z = 1) and differentiators divided out."""
    tf = control.tf(p.sys)
    num = np.atleast_1d(np.asarray(tf.num[0][0], dtype=float))
    den = np.atleast_1d(np.asarray(tf.den[0][0], dtype=float))

    def low(coef: F64) -> float:
        c = np.asarray(np.trim_zeros(coef, "f"), dtype=float)
        if p.dt:  # divide out the roots at z = 1
            while c.size > 1 and abs(np.polyval(c, 1.0)) <= 1e-10 * np.sum(np.abs(c)):
                c = np.asarray(np.polydiv(c, [1.0, -1.0])[0], dtype=float)
            return float(np.polyval(c, 1.0))
        nz = c[np.abs(c) > 1e-14 * np.max(np.abs(c))] if c.size else c
        return float(nz[-1]) if nz.size else 0.0

    return float(np.sign(low(num) * low(den)))


def _wrap_deg(a: F64 | float) -> Any:
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


def _pm_of(L: C128) -> F64:
    """Phase margin [deg] of a loop value at its crossover: ``180 + arg L`` wrapped."""
    return np.asarray(_wrap_deg(180.0 + np.degrees(np.angle(L))), dtype=float)


def _boundary_designs(P: complex, F: complex) -> list[tuple[float, float]]:
    """The two edge PIs with ``|C P| = 1`` at one frequency: P only (``ki = 0``) and I only
    (``kp = 0``)."""
    return [(float(1.0 / abs(P)), 0.0), (0.0, float(1.0 / abs(F * P)))]


def _phase_range(P: complex, F: complex) -> tuple[float, float]:
    """The phase margins [deg] a PI can reach at a crossover where the plant is ``P``."""
    a = float(_pm_of(np.array([P * F]))[0])
    b = float(_pm_of(np.array([P]))[0])
    return a, b


def _reachable_up_to(p: Plant, F_of: Any, pm: float, grid: F64, wc: float) -> float | None:
    """The upper edge [rad/s] of the band of crossovers below ``wc`` where ``pm`` is reachable
    with ``kp, ki >= 0`` (None: nowhere below ``wc`` on the grid)."""

    def margin_of_gains(x: F64) -> F64:
        kp, ki = _gains(_target(p.freqresp(x), pm), F_of(x))
        return np.where(np.isfinite(kp) & np.isfinite(ki), np.minimum(kp, ki), -np.inf)

    below = grid[grid < wc]
    g = margin_of_gains(below)
    ok = np.flatnonzero(g >= 0)
    if not ok.size:
        return None
    k = int(ok[-1])
    hi = below[k + 1] if k + 1 < below.size else wc
    g_hi = float(margin_of_gains(np.array([hi]))[0])
    if np.isfinite(g_hi) and g_hi < 0:  # the edge between two grid points
        return float(
            scipy.optimize.brentq(lambda x: float(margin_of_gains(np.array([x]))[0]), below[k], hi)
        )
    return float(below[k])


def _stable_mask(p: Plant, kp: F64, ki: F64, meth: str, pade_order: int) -> NDArray[np.bool_]:
    """Closed-loop stability of many PIs at once: the eigenvalues of the loop's state matrix
    (the plant's rational model, :meth:`Plant.with_pade`, and the integrator state), stacked.

    With ``u = ki xi + kpe e``, ``e = -y`` and ``xi' = e`` (discrete: ``xi+ = xi + Ts e``; the
    backward and Tustin integrators are the forward one with ``kpe = kp + ki Ts`` and
    ``kp + ki Ts/2``), the state matrix is affine in the gains up to ``g = 1/(1 + kpe D)``.
    A screen for the scan; the chosen design is re-checked with python-control."""
    G = control.ss(p.with_pade(pade_order))
    A, B, C, D = (np.asarray(M, dtype=float) for M in (G.A, G.B, G.C, G.D))
    n = A.shape[0]
    dt = p.dt
    gamma = {"continuous": 0.0, "forward": 0.0, "backward": 1.0, "tustin": 0.5}[meth]
    kpe = kp + gamma * ki * dt
    d = float(D[0, 0])
    out = np.zeros(kp.shape, dtype=bool)
    for chunk in np.array_split(np.arange(kp.size), max(1, kp.size // 2000)):
        if not chunk.size:
            continue
        g = 1.0 / (1.0 + kpe[chunk] * d)
        M = np.zeros((chunk.size, n + 1, n + 1))
        if n:
            M[:, :n, :n] = A[None] - (g * kpe[chunk])[:, None, None] * (B @ C)[None]
            M[:, :n, n] = (g * ki[chunk])[:, None] * B[:, 0][None]
            M[:, n, :n] = -g[:, None] * C[0][None] * (dt if dt else 1.0)
        corner = -g * ki[chunk] * d
        M[:, n, n] = 1.0 + dt * corner if dt else corner
        ev = np.linalg.eigvals(M)
        if dt:
            out[chunk] = np.all(np.abs(ev) < 1.0 - 1e-12, axis=1)
        else:
            out[chunk] = np.all(ev.real < -1e-12 * np.maximum(1.0, np.abs(ev)), axis=1)
    return out


def design_pi(
    plant: object,
    *,
    wc: float | None = None,
    phase_margin: float | None = None,
    ms: float | None = None,
    integrator: str | None = None,
    grid: Any = None,
    pade_order: int = 5,
    method: str | None = None,
) -> PIDesign:
    """A PI for ``plant`` from specifications (rules, conventions and checks: module docstring).

    ``plant``: one SISO plant (a python-control LTI system, a
    :class:`~drivetrain_ctrl.design.plants.Plant` with an exact input delay, or a one-plant set);
    negative feedback ``L = C P``. ``wc`` [rad/s]: the crossover (None: chosen by the rule of the
    module docstring). ``phase_margin`` [deg] in (0, 180): default 60 unless ``ms`` is given.
    ``ms`` [-] > 1: bound on ``max |1/(1 + L)|``. ``integrator``: discrete integrator for a
    discrete plant (``"forward"``, ``"backward"``, ``"tustin"``; default ``"forward"``; the
    former name ``method`` is an error naming it). ``grid``: the
    frequencies [rad/s] scanned for ``wc`` and used for ``ms`` (default
    :func:`~drivetrain_ctrl.design.plants.frequency_grid` of the plant, 400 points).
    ``pade_order``: order of the Pade approximation of a continuous delay in the stability
    check. Returns a :class:`PIDesign`.
    """
    if method is not None:
        raise ValueError(
            f"design_pi: method = {method!r}: the discrete integrator's option is now called "
            f"integrator (integrator={method!r})"
        )
    p = _single_plant(plant)
    meth = _integrator(p, integrator)
    if wc is not None:
        wc = real_number("wc", wc, lo=0.0, lo_open=True, unit="rad/s")
        if p.dt and wc >= math.pi / p.dt:
            raise ValueError(
                f"wc = {wc!r} rad/s: must be below the Nyquist frequency pi/dt = "
                f"{math.pi / p.dt:.6g} rad/s of the discrete plant"
            )
    if phase_margin is not None:
        phase_margin = real_number(
            "phase_margin", phase_margin, lo=0.0, hi=180.0, lo_open=True, hi_open=True, unit="deg"
        )
    if ms is not None:
        ms = real_number("ms", ms, lo=1.0, lo_open=True)
    if isinstance(pade_order, bool) or not isinstance(pade_order, int) or pade_order < 1:
        raise ValueError(f"pade_order = {pade_order!r}: must be an integer >= 1")
    if grid is None:
        w = frequency_grid(p, n=400, crossover=wc)
    else:
        w = np.asarray(grid, dtype=float)
        if w.ndim != 1 or w.size < 2 or not np.all(np.isfinite(w)) or not np.all(w > 0):
            raise ValueError(f"grid = {grid!r}: must be a 1-D array of > 1 frequencies > 0 rad/s")
        w = np.unique(w)
    if p.dt:
        w = w[w < math.pi / p.dt]  # F is real (no integral action possible) at Nyquist
    pm = phase_margin if (phase_margin is not None or ms is not None) else DEFAULT_PHASE_MARGIN

    def F_of(x: F64) -> C128:
        return integrator_response(np.asarray(x, dtype=float), p.dt, meth)

    if wc is not None and pm is not None:
        kp, ki, feasible, msg, rule = _at_crossover(p, F_of, wc, pm, w)
        wc_found = wc
    else:
        kp, ki, feasible, msg, rule, wc_found = _scan(p, F_of, w, wc, pm, ms, meth, pade_order)
    C = pi_controller_tf(kp, ki, dt=p.dt, integrator=meth if p.dt else "forward")
    chk = check_loop(
        p, C, grid=_dense_grid(p, wc_found if wc_found > 0 else None), pade_order=pade_order
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        margins = loop_margins(C * p.with_pade(pade_order))
    notes = [msg] if msg else []
    if not chk.stable:
        feasible = False
        notes.append("the closed loop is unstable (see margins.closed_loop_poles)")
    if (
        feasible
        and pm is not None
        and (chk.phase_margin_deg is None or chk.phase_margin_deg < pm - _PM_TOL_DEG)
    ):
        feasible = False
        got = "no crossover" if chk.phase_margin_deg is None else f"{chk.phase_margin_deg:.3g} deg"
        where = "" if chk.crossover_rad_s is None else f" at {chk.crossover_rad_s:.4g} rad/s"
        notes.append(
            f"the loop's smallest phase margin is {got}{where} (another gain crossover), "
            f"below the {pm:g} deg asked for"
        )
    if feasible and ms is not None and chk.ms > ms * (1 + 1e-3):
        feasible = False
        notes.append(f"Ms = {chk.ms:.4g} exceeds the bound {ms:g}")
    if not feasible and _low_frequency_sign(p) < 0:
        notes.append(
            "the plant's low-frequency gain is negative: with negative feedback L = C P "
            "a PI with positive gains needs a plant with positive gain (flip its sign)"
        )
    return PIDesign(
        kp=float(kp),
        ki=float(ki),
        dt=p.dt,
        integrator=meth,
        controller=C,
        plant=p,
        rule=rule,
        wc_target=wc,
        pm_target=pm,
        ms_target=ms,
        crossover=chk.crossover_rad_s,
        phase_margin=chk.phase_margin_deg,
        gain_margin_db=chk.gain_margin_db,
        ms=chk.ms,
        mt=chk.mt,
        stable=bool(chk.stable),
        margins=margins,
        delay_model=_delay_model(p, pade_order),
        feasible=feasible,
        message="; ".join(notes),
    )


def _at_crossover(
    p: Plant, F_of: Any, wc: float, pm: float, w: F64
) -> tuple[float, float, bool, str, str]:
    """The closed form at a given crossover, or the closest edge PI if it needs negative gains."""
    x = np.array([wc])
    P = p.freqresp(x)
    F = F_of(x)
    kp, ki = (float(v[0]) for v in _gains(_target(P, pm), F))
    if not (np.isfinite(kp) and np.isfinite(ki)):
        raise ValueError(f"wc = {wc!r} rad/s: the plant's response there is not finite")
    if kp >= 0 and ki >= 0:
        return kp, ki, True, "", "given crossover"
    lo, hi = _phase_range(complex(P[0]), complex(F[0]))
    cands = _boundary_designs(complex(P[0]), complex(F[0]))
    pms = [float(_pm_of(np.array([(kpb + kib * F[0]) * P[0]]))[0]) for kpb, kib in cands]
    k = int(np.argmin([abs(float(_wrap_deg(v - pm))) for v in pms]))
    kp, ki = cands[k]
    arg_p = float(np.degrees(np.angle(P[0])))
    edge = "a P controller (ki = 0)" if k == 0 else "an I controller (kp = 0)"
    need = "phase lead" if k == 0 else "more phase lag than an integrator"
    msg = (
        f"a phase margin of {pm:g} deg at wc = {wc:.4g} rad/s needs {need}: the plant's phase "
        f"there is {arg_p:.4g} deg, so a PI reaches phase margins from {lo:.4g} to {hi:.4g} "
        f"deg at this crossover; the closest design is {edge} with {pms[k]:.4g} deg"
    )
    top = _reachable_up_to(p, F_of, pm, w[w > 0], wc)
    if k == 0:
        msg += (
            f"; {pm:g} deg is reachable with a PI at crossovers up to {top:.4g} rad/s"
            if top is not None
            else f"; {pm:g} deg is not reachable with a PI at any crossover below wc on the grid"
        )
    return kp, ki, False, msg, "given crossover"


def _scan(
    p: Plant,
    F_of: Any,
    w: F64,
    wc: float | None,
    pm: float | None,
    ms: float | None,
    meth: str,
    pade_order: int,
) -> tuple[float, float, bool, str, str, float]:
    """The largest-ki PI over a (crossover, phase margin) scan (module docstring)."""
    Pw = p.freqresp(w)
    okw = np.isfinite(Pw)
    w_ms, P_ms = w[okw], Pw[okw]
    F_ms = F_of(w_ms)
    # the phase margins scanned when free: from the least an Ms bound allows (|1 + L| >= 1/Ms
    # at crossover means PM >= 2 asin(1/(2 Ms))) to 179 deg
    pm_lo = 2 * math.degrees(math.asin(min(1.0, 0.5 / ms))) if ms is not None else 1.0
    wcs = np.array([wc]) if wc is not None else w_ms
    pms = np.array([pm]) if pm is not None else np.linspace(pm_lo, 179.0, 90)
    rule = "max ki under Ms" if ms is not None else "max ki at phase margin"

    def evaluate(wc_v: F64, pm_v: F64) -> tuple[F64, F64, F64, F64, F64]:
        WC2d, PM2d = np.meshgrid(wc_v, pm_v, indexing="ij")
        WC, PM = WC2d.ravel(), PM2d.ravel()
        kp, ki = _gains(_target(p.freqresp(WC), PM), F_of(WC))
        ok = np.isfinite(kp) & np.isfinite(ki) & (kp >= 0) & (ki >= 0)
        peak = np.full(kp.shape, np.inf)
        if ms is not None and ok.any():
            idx = np.flatnonzero(ok)
            for chunk in np.array_split(idx, max(1, idx.size // 2000)):
                L = (kp[chunk, None] + ki[chunk, None] * F_ms[None, :]) * P_ms[None, :]
                peak[chunk] = np.max(1.0 / np.abs(1.0 + L), axis=1)
        return WC, PM, kp, ki, np.where(ok, peak, np.inf)

    def admissible(kp: F64, ki: F64, peak: F64) -> NDArray[np.bool_]:
        ok = np.isfinite(kp) & np.isfinite(ki) & (kp >= 0) & (ki > 0)
        if ms is not None:
            ok &= peak <= ms
        idx = np.flatnonzero(ok)
        ok[idx] = _stable_mask(p, kp[idx], ki[idx], meth, pade_order)
        return ok

    def verified(kp: float, ki: float) -> bool:
        C = pi_controller_tf(kp, ki, dt=p.dt, integrator=meth if p.dt else "forward")
        chk = check_loop(p, C, grid=_dense_grid(p, None), pade_order=pade_order)
        if not chk.stable:
            return False
        if pm is not None and (
            chk.phase_margin_deg is None or chk.phase_margin_deg < pm - _PM_TOL_DEG
        ):
            return False
        return not (ms is not None and chk.ms > ms * (1 + 1e-3))

    WC, PM, kp, ki, peak = evaluate(wcs, pms)
    good = admissible(kp, ki, peak)
    rejected: set[int] = set()
    order = np.flatnonzero(good)[np.argsort(-ki[good], kind="stable")]
    chosen = None
    for n_tried, i in enumerate(order):
        if n_tried >= 40:
            break
        if verified(float(kp[i]), float(ki[i])):
            chosen = int(i)
            break
        rejected.add(int(i))
    if chosen is None:
        return _closest_scan(w_ms, P_ms, F_ms, pm, ms, rule, len(rejected))
    best = (float(kp[chosen]), float(ki[chosen]), float(WC[chosen]), float(PM[chosen]))
    # refine twice around the chosen point (neighbours in wc and, if free, in the margin)
    wc_axis, pm_axis = wcs, pms
    for _ in range(2):
        iw = int(np.argmin(np.abs(np.log(wc_axis) - math.log(best[2]))))
        wc_new = (
            np.geomspace(wc_axis[max(iw - 1, 0)], wc_axis[min(iw + 1, wc_axis.size - 1)], 21)
            if wc_axis.size > 1
            else wc_axis
        )
        ip = int(np.argmin(np.abs(pm_axis - best[3])))
        pm_new = (
            np.linspace(pm_axis[max(ip - 1, 0)], pm_axis[min(ip + 1, pm_axis.size - 1)], 21)
            if pm_axis.size > 1
            else pm_axis
        )
        WC2, PM2, kp2, ki2, peak2 = evaluate(wc_new, pm_new)
        good2 = admissible(kp2, ki2, peak2)
        for i in np.flatnonzero(good2)[np.argsort(-ki2[good2], kind="stable")][:5]:
            if ki2[i] <= best[1]:
                break
            if verified(float(kp2[i]), float(ki2[i])):
                best = (float(kp2[i]), float(ki2[i]), float(WC2[i]), float(PM2[i]))
                break
        wc_axis, pm_axis = wc_new, pm_new
    kp_b, ki_b, wc_b, _pm_b = best
    msg = ""
    if wc is None and wc_b >= w_ms[-2]:
        msg = (
            f"ki still grows at the grid's upper end, {w_ms[-1]:.4g} rad/s: the plant sets no "
            "limit on the crossover there (give wc, or a grid reaching higher)"
        )
    return kp_b, ki_b, True, msg, rule, wc_b


def _closest_scan(
    w: F64, P: C128, F: C128, pm: float | None, ms: float | None, rule: str, n_rejected: int
) -> tuple[float, float, bool, str, str, float]:
    """No PI on the scan meets the spec: the closest design, and what it reaches."""
    if ms is not None:
        # the smallest Ms over the PIs (kp, ki >= 0) crossing over on the grid at any margin
        best: tuple[float, float, float, float] | None = None
        for pm_v in np.linspace(1.0, 179.0, 60):
            kpa, kia = _gains(_target(P, pm_v), F)
            ok = np.isfinite(kpa) & np.isfinite(kia) & (kpa >= 0) & (kia >= 0)
            for i in np.flatnonzero(ok):
                L = (kpa[i] + kia[i] * F) * P
                pk = float(np.max(1.0 / np.abs(1.0 + L)))
                if best is None or pk < best[0]:
                    best = (pk, float(kpa[i]), float(kia[i]), float(w[i]))
        if best is None:
            return 0.0, 0.0, False, "no PI with kp, ki >= 0 crosses over on the grid", rule, 0.0
        return (
            best[1],
            best[2],
            False,
            f"no PI on the scanned designs keeps Ms <= {ms:g} with a stable loop"
            + (f" and a {pm:g} deg phase margin" if pm is not None else "")
            + f"; the smallest Ms reached is {best[0]:.4g} (at wc = {best[3]:.4g} rad/s)",
            rule,
            best[3],
        )
    assert pm is not None
    # the largest phase margin a PI reaches at any grid crossover: the plant's own phase (ki = 0)
    reach = _pm_of(P)
    j = int(np.argmax(reach))
    kp, ki = float(1.0 / abs(P[j])), 0.0
    if n_rejected:
        return (
            kp,
            ki,
            False,
            f"{n_rejected} PIs reach a {pm:g} deg phase margin at a crossover on the grid, but "
            "none of them closes a stable loop with that margin at every crossover; shown: a "
            f"P controller (ki = 0) at wc = {w[j]:.4g} rad/s, where the plant's phase allows "
            f"{reach[j]:.4g} deg",
            rule,
            float(w[j]),
        )
    return (
        kp,
        ki,
        False,
        f"a {pm:g} deg phase margin is not reachable by a stable PI at any crossover on the grid "
        f"({w[0]:.3g} to {w[-1]:.3g} rad/s); the largest a PI reaches is {reach[j]:.4g} deg, "
        f"by a P controller (ki = 0) at wc = {w[j]:.4g} rad/s",
        rule,
        float(w[j]),
    )
