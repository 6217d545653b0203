"""Controllers declared once: an LTI realisation plus explicit nonlinear blocks.

A :class:`Controller` is used both by the linear analysis (its ``lti`` is a python-control
``StateSpace``) and by the nonlinear simulation (``simulate(..., controller=c)`` runs it inside the
compiled loop). The signal chain, in order:

1. measurement ``e = sum(coef * source)``, a source being a state name of the model (e.g.
   ``"omega_engine"``) or a reference signal (``"ref"``, given as :class:`Signal`);
2. the SISO LTI block ``lti`` (continuous; or discrete with sample period ``lti.dt`` [s], held
   between samples, with a transport delay of ``delay_samples`` samples);
3. sign switching: times ``sign(x[a] - x[b])`` for ``sign_of = (a, b)`` state names;
4. ``offset``;
5. ``lookup`` table;
6. ``saturation = (lo, hi)``;
7. latch-and-ramp: when friction element ``latch.element`` enters mode ``latch.mode``, the output
   is frozen and moved without a jump from its current value to ``latch.target`` at
   ``latch.rate`` [unit/s]; if the element leaves that mode again (a re-slip) the latch re-arms:
   the output continues from its current value, and the offset to the law's value ramps out at
   the same rate (applied before the saturation);
8. rate limiter ``rate_limit = (rate [unit/s], gain [1/s])``: ``r' = clip(gain (v - r), -rate, rate)``;
9. second-order actuator ``omega_a^2 / (s^2 + 2 delta_a omega_a s + omega_a^2)`` (paper Sec. IV);
   the result drives plant input ``output``.

Before ``start_time`` [s] the output is held at the simulation's ``controller_initial`` value
(e.g. the open pedal) and the LTI states do not move. The LTI states are also frozen while the latch
holds the output. Anti-windup (``anti_windup_time`` T_t [s], None: off) is back-calculation
(Astrom & Hagglund): while the saturation is active the LTI state derivative gets the extra term
``sgn C^T (v_sat - v_pre) / (|C|^2 T_t)``, which pulls the unsaturated value back to the limit with
time constant T_t, so the integrator of a PI does not wind up while the actuator saturates. It is
continuous across the saturation limits (unlike freezing the integrator, which makes the
saturation state chatter when the integrator pushes outwards right at the limit).
Every switch of a nonlinear block (sign change, knee,
saturation and rate-limit limits, end of the ramp) is an event of the simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import control
import numpy as np
from numpy.typing import NDArray

from .. import kernels as K
from ..core.signals import Signal, constant
from ..core.tables import PwlTable, _pwl_clamped
from ..core.validate import is_finite_real
from ..plant.model import Model

__all__ = [
    "Actuator",
    "LatchRamp",
    "Controller",
]


@dataclass(frozen=True, slots=True)
class Actuator:
    """Second-order actuator: natural frequency ``omega`` [rad/s], damping ratio ``delta`` [-]."""

    omega: float
    delta: float

    def __post_init__(self) -> None:
        for nm in ("omega", "delta"):
            v = getattr(self, nm)
            if not (is_finite_real(v) and v > 0):
                raise ValueError(f"Actuator.{nm} = {v!r}: must be a finite number > 0")

    def lti(self) -> control.StateSpace:
        """The actuator as a python-control transfer function realisation."""
        w, d = self.omega, self.delta
        return control.ss(control.tf([w * w], [1.0, 2 * d * w, w * w]))


@dataclass(frozen=True, slots=True)
class LatchRamp:
    """When friction ``element`` enters ``mode`` (e.g. the clutch 'stuck'), freeze the output and
    ramp it at ``rate`` [unit/s] to ``target``."""

    element: str
    mode: str
    rate: float
    target: float

    def __post_init__(self) -> None:
        for nm in ("rate", "target"):
            v = getattr(self, nm)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"LatchRamp.{nm} = {v!r}: must be a finite number")
        if not self.rate > 0:
            raise ValueError(f"LatchRamp.rate = {self.rate!r} [unit/s]: must be > 0")


def require_controller(controller: object, what: str, *, optional: bool = False) -> None:
    """Raise ``TypeError`` unless ``controller`` is a :class:`Controller` (or None if
    ``optional``); ``what`` names the caller in the message."""
    if optional and controller is None:
        return
    if not isinstance(controller, Controller):
        raise TypeError(
            f"{what}: controller = {controller!r}: must be a closedloop.Controller"
            f"{' or None' if optional else ''} (build one with controllers.load_controller(NAME)"
            ".build(params, reference=...), or let run_scenario(scenario, dt, controller=NAME) do it)"
        )


#: largest transport delay of a :class:`Controller` [samples]: the loop keeps a buffer of this
#: many values (a ``ControllerSpec`` allows fewer, ``controllers.MAX_DELAY_SAMPLES``)
DELAY_BUFFER_MAX = 100_000


@dataclass(frozen=True, kw_only=True)
class Controller:
    """A controller: LTI block plus listed nonlinear blocks (see the module docstring)."""

    lti: control.StateSpace
    measurement: tuple[tuple[float, str], ...]
    output: str
    reference: Signal | None = None
    delay_samples: int = 0
    sign_of: tuple[str, str] | None = None
    offset: float = 0.0
    lookup: PwlTable | None = None
    saturation: tuple[float, float] | None = None
    latch: LatchRamp | None = None
    rate_limit: tuple[float, float] | None = None
    actuator: Actuator | None = None
    name: str = "controller"
    initial_lti_state: tuple[float, ...] | None = field(default=None)
    start_time: float | None = None
    anti_windup_time: float | None = None

    def __post_init__(self) -> None:
        sys = self.lti
        if not isinstance(sys, control.StateSpace):
            raise TypeError(
                f"{self.name}.lti must be a control.StateSpace, got {type(sys).__name__}"
            )
        if sys.ninputs != 1 or sys.noutputs != 1:
            raise ValueError(
                f"{self.name}.lti must be SISO, got {sys.ninputs} in / {sys.noutputs} out"
            )
        if not self.measurement:
            raise ValueError(f"{self.name}.measurement: needs at least one (coef, source) term")
        ds = self.delay_samples
        if isinstance(ds, bool) or not isinstance(ds, (int, np.integer)):
            raise ValueError(
                f"{self.name}.delay_samples = {ds!r}: must be a whole number of samples"
            )
        if ds < 0 or (ds and not self.is_discrete) or ds > DELAY_BUFFER_MAX:
            raise ValueError(
                f"{self.name}.delay_samples = {ds}: needs a discrete lti and 0 <= delay_samples "
                f"<= {DELAY_BUFFER_MAX}"
            )
        if not is_finite_real(self.offset):
            raise ValueError(f"{self.name}.offset = {self.offset!r}: must be a finite number")
        for nm in ("saturation", "rate_limit"):
            pair = getattr(self, nm)
            if pair is not None and not (
                isinstance(pair, (tuple, list))
                and len(pair) == 2
                and all(is_finite_real(v) for v in pair)
            ):
                raise ValueError(
                    f"{self.name}.{nm} = {pair!r}: must be a pair of finite numbers or None"
                )
        if self.saturation is not None and not self.saturation[0] < self.saturation[1]:
            raise ValueError(f"{self.name}.saturation = {self.saturation}: needs lo < hi")
        if self.rate_limit is not None and not (self.rate_limit[0] > 0 and self.rate_limit[1] > 0):
            raise ValueError(
                f"{self.name}.rate_limit = {self.rate_limit}: rate and gain must be > 0"
            )
        x0 = self.initial_lti_state
        if x0 is not None:
            n_lti = int(sys.nstates)
            if (
                not isinstance(x0, (tuple, list))
                or len(x0) != n_lti
                or not all(is_finite_real(v) for v in x0)
            ):
                raise ValueError(
                    f"{self.name}.initial_lti_state = {x0!r}: must be {n_lti} finite numbers "
                    "(one per state of lti) or None"
                )
        if self.reference is not None and not isinstance(self.reference, Signal):
            raise ValueError(
                f"{self.name}.reference = {self.reference!r}: must be a Signal or None"
            )
        if self.start_time is not None and not is_finite_real(self.start_time):
            raise ValueError(
                f"{self.name}.start_time = {self.start_time!r} [s]: must be a finite number"
            )
        awt = self.anti_windup_time
        if awt is not None and not (is_finite_real(awt) and awt > 0):
            raise ValueError(
                f"{self.name}.anti_windup_time = {awt!r} [s]: must be a finite number > 0 or None"
            )
        if self.is_discrete and not (math.isfinite(self.lti.dt) and self.lti.dt > 0):
            raise ValueError(f"{self.name}.lti.dt = {self.lti.dt!r} [s]: sample period must be > 0")
        for nm, arr in (("A", sys.A), ("B", sys.B), ("C", sys.C), ("D", sys.D)):
            if not np.all(np.isfinite(np.asarray(arr, dtype=float))):
                raise ValueError(f"{self.name}.lti.{nm} has non-finite entries: {arr!r}")
        for c, src in self.measurement:
            if src == "ref" and self.reference is None:
                raise ValueError(f"{self.name}.measurement uses 'ref' but no reference is given")
            if not math.isfinite(c):
                raise ValueError(f"{self.name}.measurement coefficient {c!r} for {src!r}")

    @property
    def is_discrete(self) -> bool:
        return bool(self.lti.dt) and self.lti.dt is not True

    def compile(
        self, model: Model, *, hold: float = 0.0
    ) -> tuple[K.CtrlData, NDArray[np.float64], list[Signal]]:
        """Arrays for the compiled loop: (CtrlData, discrete state, reference signals).

        ``hold`` is the output before :attr:`start_time` (e.g. the open pedal position [m]). The
        continuous controller states start from :meth:`initial_states`."""
        nu = len(model.input_names)
        m_kind, m_idx, m_coef = [], [], []
        for c, src in self.measurement:
            if src == "ref":
                m_kind.append(1)
                m_idx.append(nu)
            else:
                m_kind.append(0)
                m_idx.append(model.state_index(src))
            m_coef.append(float(c))
        A = np.atleast_2d(np.asarray(self.lti.A, dtype=float))
        B = np.asarray(self.lti.B, dtype=float).reshape(-1)
        C = np.asarray(self.lti.C, dtype=float).reshape(-1)
        Dm = np.asarray(self.lti.D, dtype=float).reshape(-1)[:1]
        nstate = B.shape[0]
        if A.shape != (nstate, nstate):
            A = A.reshape(nstate, nstate)
        ci = np.zeros(K.N_CI, dtype=np.int64)
        cf = np.zeros(K.N_CF)
        cf[K.CF_TON] = -np.inf if self.start_time is None else float(self.start_time)
        cf[K.CF_HOLD] = float(hold)
        cf[K.CF_AWK] = 0.0 if self.anti_windup_time is None else 1.0 / self.anti_windup_time
        ci[K.CI_OUT] = model.input_names.index(self.output)
        disc = self.is_discrete
        ci[K.CI_DISC] = int(disc)
        ci[K.CI_NC] = 0 if disc else nstate
        ci[K.CI_ND] = nstate if disc else 0
        ci[K.CI_NDELAY] = self.delay_samples
        ci[K.CI_SA] = model.state_index(self.sign_of[0]) if self.sign_of else -1
        ci[K.CI_SB] = model.state_index(self.sign_of[1]) if self.sign_of else -1
        if self.latch is not None:
            f = model.friction_index(self.latch.element)
            names = model.frictions[f].mode_names
            if self.latch.mode not in names:
                raise ValueError(f"{self.name}.latch.mode = {self.latch.mode!r}: not in {names}")
            ci[K.CI_LF] = f
            ci[K.CI_LM] = names.index(self.latch.mode)
            cf[K.CF_LR] = self.latch.rate
            cf[K.CF_LT] = self.latch.target
        else:
            ci[K.CI_LF] = -1
        ci[K.CI_ACT] = int(self.actuator is not None)
        ci[K.CI_RL] = int(self.rate_limit is not None)
        ci[K.CI_SAT] = int(self.saturation is not None)
        if self.lookup is not None:
            b_, s_, o_ = _pwl_clamped(self.lookup)
            ci[K.CI_LKNB] = len(b_)
            lk_b = np.array(b_ + [np.inf])
            lk_s = np.array(s_)
            lk_o = np.array(o_)
        else:
            ci[K.CI_LKNB] = -1
            lk_b = np.zeros(1)
            lk_s = np.zeros(1)
            lk_o = np.zeros(1)
        cf[K.CF_TS] = float(self.lti.dt) if disc else 0.0
        cf[K.CF_OFF] = self.offset
        if self.saturation is not None:
            cf[K.CF_LO], cf[K.CF_HI] = self.saturation
        if self.rate_limit is not None:
            cf[K.CF_RLR], cf[K.CF_RLG] = self.rate_limit
        if self.actuator is not None:
            cf[K.CF_AW] = self.actuator.omega
            cf[K.CF_AZ] = self.actuator.delta
        Cd = K.CtrlData(
            np.array(m_kind, dtype=np.int64),
            np.array(m_idx, dtype=np.int64),
            np.array(m_coef),
            A,
            B,
            C,
            Dm if Dm.size else np.zeros(1),
            ci,
            cf,
            lk_b,
            lk_s,
            lk_o,
        )
        cs = np.zeros(K.CS_XD + ci[K.CI_ND] + self.delay_samples + 1)
        x_lti = (
            np.zeros(nstate) if self.initial_lti_state is None else np.array(self.initial_lti_state)
        )
        if disc:
            cs[K.CS_XD : K.CS_XD + nstate] = x_lti
        refs = [self.reference if self.reference is not None else constant(0.0)]
        return Cd, cs, refs

    def initial_states(
        self, model: Model, x0: NDArray[np.float64], u0: float
    ) -> NDArray[np.float64]:
        """Initial continuous controller states: LTI state, rate limiter and actuator at ``u0``
        (the value of the driven input at the start, e.g. the pedal position [m])."""
        disc = self.is_discrete
        nstate = np.asarray(self.lti.B).shape[0]
        x_lti = (
            np.zeros(nstate) if self.initial_lti_state is None else np.array(self.initial_lti_state)
        )
        out: list[float] = [] if disc else list(x_lti)
        if self.rate_limit is not None:
            out.append(u0)
        if self.actuator is not None:
            out += [u0, 0.0]
        return np.array(out, dtype=float)


def actuator_tf(actuator: Actuator) -> control.TransferFunction:
    """x_r -> x_c [m/m]: ``w_a^2 / (s^2 + 2 d_a w_a s + w_a^2)`` (paper, Sec. IV). TypeError
    if ``actuator`` is not an :class:`~drivetrain_ctrl.control.blocks.Actuator`."""
    if not isinstance(actuator, Actuator):
        raise TypeError(f"actuator: an Actuator is needed, got {type(actuator).__name__}")
    w, d = actuator.omega, actuator.delta
    return control.tf([w * w], [1.0, 2 * d * w, w * w], inputs="x_r", outputs="x_c")
