"""The clutch control loop in slip and the locked driveline (paper, Sec. IV): car-specific theory on top of
:mod:`drivetrain_ctrl.linear.linearisation`."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np
from numpy.typing import NDArray

from .. import kernels as K
from ..control.blocks import Controller, actuator_tf, require_controller
from ..core.serialize import json_ready
from ..core.validate import finite_float, is_finite_real, positive_float
from .linearisation import (
    ShuffleMode,
    _linear_arrays,
    _oscillatory,
    _siso,
    _tf_min,
    _trim_tf_arrays,
    linearisation_parts,
    linearise,
)
from .operating_point import OperatingPoint, StuckMargin, require_op


@dataclass(frozen=True, slots=True)
class EngineSide:
    """Engine-side figures at a slip operating point (from the analytic Jacobian).

    ``J1`` [kg m^2]; ``b1_eff`` b_1' = -dC_1/domega_1 [N m s/rad]; ``clutch_gain``
    d tau_13/d x_c = k13'(x_c) mu s [N m/m]; ``dk13_dxc`` k13'(x_c) [N m/m]; ``k13`` [N m];
    ``mu`` ``mu(|w|)/mu(0)``; ``mu_slope_torque`` c = k13 mu' [N m s/rad]; ``sign`` of the slip;
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
    es, P_use, L_ss, Lt = _loop_parts(op, controller, mu_slope=mu_slope, what="clutch_loop")
    C = controller.lti
    disc = controller.is_discrete
    Ts = float(C.dt) if disc else None
    one = control.tf([1.0], [1.0], Ts) if disc else control.tf([1.0], [1.0])
    S = control.minreal(one / (one + Lt), verbose=False)
    T = control.minreal(Lt / (one + Lt), verbose=False)
    P_sys = _as_ss(P_use, Ts)
    Pt = _tf_min(P_sys)
    Ct = control.tf(C)
    PS = control.minreal(Pt * S, verbose=False)
    CS = control.minreal(Ct * S, verbose=False)
    cl = control.feedback(_as_ss(L_ss, Ts), 1)
    return ClutchLoop(
        op=op,
        controller_name=controller.name,
        engine=es,
        actuator=actuator_tf(controller.actuator) if controller.actuator else control.tf(1, 1),
        x_c_to_tau13=_pedal_to_clutch_torque(es),
        tau13_to_omega1=_clutch_torque_to_engine_speed(es),
        theta_to_omega1=_throttle_to_engine_speed(es),
        x_c_to_accel=pedal_to_vehicle_accel(op, mu_slope=mu_slope),
        plant=P_sys,
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


def clutch_loop_gain(
    op: OperatingPoint, controller: Controller, *, mu_slope: float | None = None
) -> tuple[EngineSide, control.TransferFunction]:
    """The engine side at ``op`` and the loop gain ``L`` of :func:`clutch_loop` (the same
    transfer function), without the loop's other transfer functions (S, T, PS, CS, the
    pedal-to-acceleration path): for callers that need only ``L``, such as a study's paired
    linear figures."""
    es, _P, _L_ss, Lt = _loop_parts(op, controller, mu_slope=mu_slope, what="clutch_loop_gain")
    return es, Lt


#: a state-space system as numpy arrays ``(A, B, C, D)``
Arrays = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


def _arrays(sys: control.StateSpace) -> Arrays:
    """``(A, B, C, D)`` of a python-control state space, as float arrays."""
    return (
        np.asarray(sys.A, dtype=float),
        np.asarray(sys.B, dtype=float),
        np.asarray(sys.C, dtype=float),
        np.asarray(sys.D, dtype=float),
    )


def _as_ss(sys: Arrays | control.StateSpace, dt: float | None) -> control.StateSpace:
    if isinstance(sys, control.StateSpace):
        return sys
    return control.ss(*sys, dt) if dt else control.ss(*sys)


def _series(first: Arrays, second: Arrays) -> Arrays:
    """``second`` after ``first`` (python-control's ``second * first``, the same state order:
    ``first``'s states, then ``second``'s)."""
    A1, B1, C1, D1 = first
    A2, B2, C2, D2 = second
    n1, n2 = A1.shape[0], A2.shape[0]
    A = np.block([[A1, np.zeros((n1, n2))], [B2 @ C1, A2]])
    return A, np.vstack([B1, B2 @ D1]), np.hstack([D2 @ C1, C2]), D2 @ D1


def _loop_parts(
    op: OperatingPoint, controller: Controller, *, mu_slope: float | None, what: str
) -> tuple[EngineSide, Arrays | control.StateSpace, Arrays | control.StateSpace, Any]:
    """(engine side, plant seen by the controller, ``L`` as state space, ``L`` minimal transfer
    function) of :func:`clutch_loop`. A continuous loop's plant and ``L`` are numpy arrays
    ``(A, B, C, D)`` (built without python-control's interconnections; :func:`_as_ss` makes
    systems of them), a sampled loop's python-control systems."""
    _require_slip(op, what)
    require_controller(controller, what)
    if controller.output != "pedal":
        raise ValueError(f"controller.output = {controller.output!r}: must drive 'pedal'")
    es = engine_side(op, mu_slope=mu_slope)
    A, B, C, D, _names, outs = _linear_arrays(op, inputs=("x_c",), outputs=None, mu_slope=mu_slope)
    Cm, Dm = _measurement_rows_of(C, D, outs, controller)
    if all(src == "ref" for _coef, src in controller.measurement):
        raise ValueError("controller.measurement: has no plant state (only 'ref')")
    P: Arrays = _series(_error_chain_arrays(controller, op), (A, B, Cm, Dm))
    Cl = controller.lti
    if not controller.is_discrete:
        L_ss = _series(P, _arrays(Cl))
        return es, P, L_ss, _tf_min_arrays(*L_ss, None)
    # a sampled loop: python-control's realisation of the plant (the ZOH and the conversion to
    # a transfer function are ill-conditioned for it: another realisation moves its figures
    # beyond round-off)
    # one realisation: the measured speeds' output rows summed (:func:`_measured_plant`); a sum
    # of one system per speed would hold a copy of the plant per speed, whose unstable modes
    # (uncontrollable from the loop) would stay in the closed loop
    meas = _measured_plant(linearise(op, inputs=("x_c",), mu_slope=mu_slope), controller)
    Ts = float(Cl.dt)
    Pd = control.sample_system(control.ss(meas * _error_chain(controller, op)), Ts, method="zoh")
    if controller.delay_samples:
        zd = control.tf([1.0], [1.0] + [0.0] * controller.delay_samples, Ts)
        Pd = control.ss(Pd * control.ss(zd))
    L_sys = control.ss(Cl * Pd)
    return es, Pd, L_sys, _tf_min(L_sys)


def _tf_min_arrays(
    A: NDArray[np.float64],
    B: NDArray[np.float64],
    C: NDArray[np.float64],
    D: NDArray[np.float64],
    dt: float | None,
) -> control.TransferFunction:
    """:func:`_tf_min` of the SISO system ``(A, B, C, D)`` (no python-control system built)."""
    return control.minreal(_trim_tf_arrays(A, B, C, D, dt), verbose=False)


def _error_chain_arrays(controller: Controller, op: OperatingPoint) -> Arrays:
    """Controller output -> x_c as numpy arrays: ``-sgn`` (the sign block; the minus sign turns
    the loop into negative feedback), rate limiter (linear range, ``g/(s+g)``) and actuator
    (``w_a^2/(s^2 + 2 d_a w_a s + w_a^2)`` as ``x1' = -2 d_a w_a x1 - w_a x2 + w_a u``,
    ``x2' = w_a x1``, ``x_c = x2``: every entry of the order of ``w_a``, a well-scaled matrix)."""
    sgn = _controller_sign(controller, op)
    e = np.zeros((0, 0))
    chain: Arrays = (e, np.zeros((0, 1)), np.zeros((1, 0)), np.array([[-sgn]]))
    if controller.rate_limit is not None:
        g = float(controller.rate_limit[1])
        rate = (np.array([[-g]]), np.array([[g]]), np.array([[1.0]]), np.zeros((1, 1)))
        chain = _series(chain, rate)
    if controller.actuator is not None:
        w, d = float(controller.actuator.omega), float(controller.actuator.delta)
        act = (
            np.array([[-2.0 * d * w, -w], [w, 0.0]]),
            np.array([[w], [0.0]]),
            np.array([[0.0, 1.0]]),
            np.zeros((1, 1)),
        )
        chain = _series(chain, act)
    return chain


def _error_chain(controller: Controller, op: OperatingPoint) -> control.StateSpace:
    """The transfer function of :func:`_error_chain_arrays` in python-control's realisation
    (its conversions of the rate limiter's and the actuator's transfer functions), for the
    sampled loop (:func:`_loop_parts`)."""
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


def _measurement_rows(
    sys: control.StateSpace, controller: Controller
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(Cm, Dm)``: the output row and feedthrough of x_c -> the measured part of the
    controller's error, from the plant ``sys`` (input ``x_c``)."""
    return _measurement_rows_of(
        np.asarray(sys.C), np.asarray(sys.D), list(sys.output_labels), controller
    )


def _measurement_rows_of(
    C: NDArray[np.float64], D: NDArray[np.float64], outputs: list[str], controller: Controller
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_measurement_rows` from the plant's output matrices ``C``, ``D`` (input ``x_c``)
    and its output names."""
    Cm = np.zeros((1, C.shape[1]))
    Dm = np.zeros((1, 1))
    for coef, src in controller.measurement:
        if src == "ref":
            continue
        if src not in outputs:
            raise ValueError(f"controller.measurement: {src!r} is not a body speed of the model")
        o = outputs.index(src)
        Cm += coef * C[[o], :]
        Dm += coef * D[[o], :]
    return Cm, Dm


def _measured_plant(sys: control.StateSpace, controller: Controller) -> control.StateSpace:
    """x_c -> the measured part of the controller's error (every state of ``sys`` kept)."""
    Cm, Dm = _measurement_rows(sys, controller)
    return control.ss(sys.A, sys.B, Cm, Dm)


def _negative_feedback_matrix(
    A: NDArray[np.float64],
    B: NDArray[np.float64],
    Cm: NDArray[np.float64],
    Dm: NDArray[np.float64],
    K: control.StateSpace | Arrays,
) -> NDArray[np.float64]:
    """State matrix of the SISO plant ``(A, B, Cm, Dm)`` (x_c -> measured error) closed by the
    SISO controller-and-error-chain ``K`` in negative feedback, ``x_c = -K y`` (as
    :func:`_slip_mode_matrix`; states: the plant's, then ``K``'s). With ``y = Cm x + Dm x_c`` and
    ``x_c = -(Ck xk + Dk y)``: ``x_c = -(Dk Cm x + Ck xk)/(1 + Dk Dm)``."""
    Ak, Bk, Ck, Dk_ = _arrays(K) if isinstance(K, control.StateSpace) else K
    Dk = float(Dk_[0, 0])
    dm = float(Dm[0, 0])
    den = 1.0 + Dk * dm
    if den == 0.0:
        raise ValueError("the slip-mode loop is algebraic (1 + D_K D_P = 0): no state matrix")
    n, nk = A.shape[0], Ak.shape[0]
    Fu = -np.hstack([Dk * Cm, Ck.reshape(1, nk)]) / den  # x_c = Fu [x; xk]
    top = np.hstack([A, np.zeros((n, nk))]) + B.reshape(n, 1) @ Fu
    bot = np.hstack([Bk.reshape(nk, 1) @ Cm, Ak]) + Bk.reshape(nk, 1) * dm @ Fu
    return np.vstack([top, bot])


def _slip_mode_matrix(
    sys: control.StateSpace, op: OperatingPoint, controller: Controller | None
) -> NDArray[np.float64]:
    """The state matrix whose eigenvalues are :func:`slip_mode_poles`, from the plant already
    linearised at ``op`` (input ``x_c``): the plant's ``A`` (``controller`` None) or the closed
    loop's."""
    if controller is None:
        return np.asarray(sys.A, dtype=float)
    if controller.is_discrete:
        raise ValueError("slip_mode_poles: a discrete controller; use clutch_loop(...).closed_loop")
    plant_e = _measured_plant(sys, controller)  # x_c -> measured part of the error
    open_ss = control.ss(controller.lti) * _error_chain(controller, op) * plant_e
    # open_ss maps the error back to the controller input with the sign of the loop: close it
    cl = control.feedback(open_ss, 1, sign=-1)
    return np.asarray(cl.A, dtype=float)


def _slip_mode_poles_of(
    sys: control.StateSpace, op: OperatingPoint, controller: Controller | None
) -> NDArray[np.complex128]:
    """:func:`slip_mode_poles` from the plant already linearised at ``op`` (input ``x_c``)."""
    return np.asarray(np.linalg.eigvals(_slip_mode_matrix(sys, op, controller)), dtype=complex)


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
    ``h_t`` [N m/rad] and ``b_t`` [N m s/rad] in the op's backlash mode (in the gap 0, and
    ``b_t`` too if it acts only in contact), ``b_p`` (driven shaft to ground) and ``b_e``
    (vehicle road-load slope referred) [N m s/rad], ``b1_eff`` b_1', ``engine_factor`` Re of
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
    J, m, h = (positive_float(nm, v) for nm, v in (("J", J), ("m", m), ("h", h)))
    b, e = (finite_float(nm, v) for nm, v in (("b", b), ("e", e)))
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
    # the shaft's damping in the op's mode (0 in the gap if it acts only in contact)
    b = float(K.damper_coefficient(D, c, op.mode.arrays()[1]))
    return J, me, h, b, float(D.visc[ip]), b_e


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


# ---------------------------------------------------------------------------------------------
# the judder threshold on any model: the first crossing of the re-linearised loop's poles
# ---------------------------------------------------------------------------------------------

#: relative tolerance of :func:`judder_crossing`: the crossing is located to within
#: ``JUDDER_RTOL * |mu'_crit|`` [s/rad]
JUDDER_RTOL: float = 1e-6

#: the search of :func:`judder_crossing`: from ``-JUDDER_FIRST_STEP`` [s/rad] outward by the factor
#: ``JUDDER_GRID_RATIO`` down to ``-JUDDER_SEARCH_LIMIT`` [s/rad]
JUDDER_FIRST_STEP: float = 1e-7
JUDDER_GRID_RATIO: float = 1.5
JUDDER_SEARCH_LIMIT: float = 1.0

#: slopes of the search's grid whose poles :func:`judder_crossing` computes in one call on the
#: affine matrix (``evaluations`` counts only those examined before the first unstable one)
JUDDER_BATCH: int = 8

#: a pole with ``|Re p| <= JUDDER_BOUNDARY_TOL * max(1, |p|)`` [1/s] counts as on the stability
#: boundary (not asymptotically stable)
JUDDER_BOUNDARY_TOL: float = 1e-9


@dataclass(frozen=True)
class JudderCrossing:
    """The judder threshold of a slip point on any model (:func:`judder_crossing`): the first
    friction slope mu' [s/rad] (of the ratio mu/mu0), going from 0 towards a falling friction
    characteristic, at which a pole of the re-linearised slip mode (the plant with the pedal held,
    or the closed loop of the controller) leaves the open left half plane (a sampled loop: the open
    unit disc).

    ``mu_slope_crit`` [s/rad]: the middle of the final bracket ``(stable_side, unstable_side)``
    (the poles at ``stable_side`` are stable, at ``unstable_side`` one is not), so the crossing lies
    within ``tolerance`` [s/rad] of it; ``c_crit = k13 mu_slope_crit`` [N m s/rad] the torque slope;
    ``crossing_pole`` [1/s] the rightmost pole at ``unstable_side`` (a sampled loop's ``z`` mapped
    by ``ln(z)/dt``) and ``frequency_hz`` its frequency ``|Im p|/2pi`` (0: a real pole crosses);
    ``frequency_note`` says where a sampled loop's frequency comes from. ``spectral_abscissa_at_zero``
    [1/s] the largest real part at mu' = 0. ``searched`` the interval of mu' [s/rad] searched,
    ``evaluations`` the number of pole computations (eigenvalue problems). When there is no threshold,
    ``mu_slope_crit``, ``c_crit``, the bracket and the pole are None and ``reason`` says why.
    ``controller`` names the controller (None: pedal held); ``dt`` [s] the sample period of a
    sampled loop (None: continuous)."""

    mu_slope_crit: float | None
    c_crit: float | None
    tolerance: float | None
    stable_side: float | None
    unstable_side: float | None
    crossing_pole: complex | None
    frequency_hz: float | None
    frequency_note: str
    k13: float
    spectral_abscissa_at_zero: float
    searched: tuple[float, float]
    evaluations: int
    controller: str | None
    dt: float | None
    reason: str | None

    @property
    def available(self) -> bool:
        """Whether a threshold was found (else see ``reason``)."""
        return self.mu_slope_crit is not None

    def summary(self) -> str:
        """One line: the threshold with its tolerance and mode, or ``not available: <reason>``."""
        if self.mu_slope_crit is None:
            return f"not available: {self.reason}"
        assert self.c_crit is not None and self.tolerance is not None
        mode = (
            f"a {self.frequency_hz:.4g} Hz mode"
            if self.frequency_hz
            else "a real pole (no oscillation)"
        )
        return (
            f"mu' = {self.mu_slope_crit:.6g} s/rad (+-{self.tolerance:.2g}; c = k13 mu' = "
            f"{self.c_crit:.6g} N m s/rad): {mode} crosses"
        )

    def to_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        p = self.crossing_pole
        d["crossing_pole"] = None if p is None else [p.real, p.imag]
        d["searched"] = list(self.searched)
        return json_ready(d)


def _sampled_loop_poles(
    sys: control.StateSpace, op: OperatingPoint, controller: Controller
) -> NDArray[np.complex128]:
    """Closed-loop poles ``z`` of a sampled ``controller`` around the plant ``sys`` linearised at
    ``op`` (input ``x_c``): the plant with the error chain ZOH-sampled, ``z^-d`` for the delay, as
    :func:`clutch_loop` builds it; every plant state kept."""
    P = _measured_plant(sys, controller) * _error_chain(controller, op)
    Ts = float(controller.lti.dt)
    Pd = control.sample_system(P, Ts, method="zoh")
    if controller.delay_samples:
        zd = control.tf([1.0], [1.0] + [0.0] * controller.delay_samples, Ts)
        Pd = Pd * control.ss(zd)
    cl = control.feedback(control.ss(controller.lti) * Pd, 1)
    return np.asarray(np.linalg.eigvals(cl.A), dtype=complex)


def _slip_plant_arrays(
    op: OperatingPoint, mu: float
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    list[str],
    list[str],
]:
    """The plant at ``op`` with input ``x_c`` and the friction slope ``mu`` [s/rad], as the
    arrays of :func:`linearise` (``A, B, C, D``, state and output names)."""
    return _linear_arrays(op, inputs=("x_c",), outputs=None, mu_slope=mu)


#: relative tolerance of the check that the slip mode's state matrix is affine in mu'
#: (:func:`_affine_slip_matrix`)
JUDDER_AFFINE_RTOL: float = 1e-9


def _affine_slip_matrix(
    op: OperatingPoint, controller: Controller | None, limit: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """``(A0, dA)`` with the slip mode's state matrix (:func:`_slip_mode_matrix`, continuous)
    ``A(mu') = A0 + mu' dA`` over ``[-limit, 0]``, from the plant at three slopes (mu' = 0,
    ``-limit`` and their geometric middle as the check; one Jacobian evaluation, which
    :func:`linearisation_parts` keeps, and a rank-one change per slope); None when the check fails (the matrix is not
    affine in mu' to :data:`JUDDER_AFFINE_RTOL`, or its shape changes), and the caller
    re-linearises at every mu'. The friction slope enters the Jacobian only through the clutch
    torque's derivative by the slip speed, ``k13 mu'`` times the slip direction, so the matrix
    is affine in it and one eigenvalue problem per mu' replaces a linearisation."""

    K = None
    if controller is not None:
        # the controller after the error chain, independent of mu'
        K = _series(_error_chain_arrays(controller, op), _arrays(controller.lti))
        if K[1].shape[1] != 1 or K[2].shape[0] != 1:
            return None

    def mat(mu: float) -> NDArray[np.float64]:
        A, B, C, D, _names, outs = _slip_plant_arrays(op, mu)
        if K is None:
            return A
        assert controller is not None
        Cm, Dm = _measurement_rows_of(C, D, outs, controller)
        return _negative_feedback_matrix(A, B, Cm, Dm, K)

    A0, A1 = mat(0.0), mat(-limit)
    mid = -math.sqrt(JUDDER_FIRST_STEP * limit)
    Am = mat(mid)
    if A0.shape != A1.shape or A0.shape != Am.shape:
        return None
    dA = (A1 - A0) / -limit
    scale = float(np.max(np.abs(A0))) + abs(mid) * float(np.max(np.abs(dA)))
    if not np.all(np.abs(A0 + mid * dA - Am) <= JUDDER_AFFINE_RTOL * max(scale, 1e-300)):
        return None
    return A0, dA


def judder_crossing(
    op: OperatingPoint,
    controller: Controller | None = None,
    *,
    rtol: float = JUDDER_RTOL,
    search_limit: float = JUDDER_SEARCH_LIMIT,
) -> JudderCrossing:
    """The judder threshold of the slip point ``op`` on any model, located numerically.

    The slip mode is re-linearised with the clutch friction slope mu' [s/rad] overridden
    (:func:`linearise`'s ``mu_slope``), and its poles computed: the plant alone (``controller``
    None, pedal held), or closed by a continuous controller (every driveline mode included,
    :func:`slip_mode_poles`) or a sampled one (ZOH plant, delay; the poles ``z``, unstable outside
    the unit circle). Starting from mu' = 0 the search steps towards a falling friction
    characteristic on the geometric grid ``-JUDDER_FIRST_STEP * JUDDER_GRID_RATIO^k`` down to
    ``-search_limit``; the first grid value with an unstable pole and the stable value before it
    bracket the crossing, which bisection narrows to ``rtol * |mu'|`` (:class:`JudderCrossing`:
    the bracket, its middle and half-width, the crossing pole and its frequency). A pole within
    ``JUDDER_BOUNDARY_TOL`` of the boundary counts as unstable. An unstable window narrower than
    one grid step before the first unstable grid value would be missed. For a continuous loop
    (or the plant alone) the state matrix is affine in mu' (:func:`_affine_slip_matrix`, checked
    at a third slope): the plant at three slopes, then one eigenvalue problem per evaluation; a sampled
    loop, or a matrix that fails the check, is re-linearised at every evaluation.

    No threshold (``mu_slope_crit`` None, with ``reason``): the slip mode is not stable at mu' = 0,
    or it stays stable down to ``-search_limit``. On the reduced model the result agrees with the
    closed form :func:`judder_threshold` (which approximates the shuffle crossing).
    """
    _require_slip(op, "judder_crossing")
    require_controller(controller, "judder_crossing", optional=True)
    if not (is_finite_real(rtol) and 0 < rtol < 0.1):
        raise ValueError(f"rtol = {rtol!r}: must be a number in (0, 0.1)")
    if not (is_finite_real(search_limit) and search_limit > JUDDER_FIRST_STEP):
        raise ValueError(f"search_limit = {search_limit!r}: must be > {JUDDER_FIRST_STEP} [s/rad]")
    disc = controller is not None and controller.is_discrete
    dt = float(controller.lti.dt) if (controller is not None and disc) else None
    k13 = engine_side(op).k13
    count = 0
    affine = None if disc else _affine_slip_matrix(op, controller, float(search_limit))

    def poles(mu: float) -> NDArray[np.complex128]:
        """Closed-loop poles at mu' = ``mu`` in the s-plane (a sampled loop's mapped by ln z/dt)."""
        nonlocal count
        count += 1
        if affine is not None:
            A0, dA = affine
            return np.asarray(np.linalg.eigvals(A0 + mu * dA), dtype=complex)
        sys = linearise(op, inputs=("x_c",), mu_slope=mu)
        if controller is not None and disc:
            z = _sampled_loop_poles(sys, op, controller)
            z = z[np.abs(z) > 0.0]  # z = 0 (a delay, a deadbeat pole) is deep inside
            assert dt is not None
            return np.asarray(np.log(z) / dt, dtype=complex)
        return _slip_mode_poles_of(sys, op, controller)

    def unstable(p: NDArray[np.complex128]) -> bool:
        return bool(np.any(p.real >= -JUDDER_BOUNDARY_TOL * np.maximum(1.0, np.abs(p))))

    def rightmost(p: NDArray[np.complex128]) -> complex:
        return complex(p[int(np.argmax(p.real))])

    name = None if controller is None else controller.name
    p0 = poles(0.0)
    a0 = float(np.max(p0.real)) if p0.size else -math.inf
    none: dict[str, Any] = dict(
        mu_slope_crit=None,
        c_crit=None,
        tolerance=None,
        stable_side=None,
        unstable_side=None,
        crossing_pole=None,
        frequency_hz=None,
        frequency_note="",
        k13=k13,
        spectral_abscissa_at_zero=a0,
        searched=(-float(search_limit), 0.0),
        controller=name,
        dt=dt,
    )
    if unstable(p0):
        q = rightmost(p0)
        return JudderCrossing(
            **none,
            evaluations=count,
            reason=(
                "the slip mode is not stable with constant friction (mu' = 0): pole "
                f"{q.real:.4g}{q.imag:+.4g}j 1/s ({abs(q.imag) / (2 * math.pi):.4g} Hz), so there "
                "is no threshold to cross"
            ),
        )
    grid = []
    v = -JUDDER_FIRST_STEP
    while v >= -search_limit * (1 + 1e-12):
        grid.append(v)
        v *= JUDDER_GRID_RATIO

    def grid_poles() -> Iterator[NDArray[np.complex128]]:
        """The poles at the grid's slopes in turn; on the affine matrix
        :data:`JUDDER_BATCH` eigenvalue problems at a time (the same problems, one call)."""
        nonlocal count
        if affine is None:
            for v in grid:
                yield poles(v)
            return
        A0, dA = affine
        for k in range(0, len(grid), JUDDER_BATCH):
            vs = np.asarray(grid[k : k + JUDDER_BATCH])
            for p in np.linalg.eigvals(A0 + vs[:, None, None] * dA):
                count += 1  # counted as they are examined, as one at a time
                yield np.asarray(p, dtype=complex)

    a, b = 0.0, None
    for v, p in zip(grid, grid_poles(), strict=False):
        if unstable(p):
            b = v
            break
        a = v
    if b is None:
        return JudderCrossing(
            **none,
            evaluations=count,
            reason=(
                f"the slip mode stays stable for every mu' in [{-search_limit:g}, 0] s/rad "
                "(searched to that friction slope)"
            ),
        )
    # bisection: a stable, b unstable
    while abs(b - a) > 2 * rtol * abs(b):
        m = 0.5 * (a + b)
        if unstable(poles(m)):
            b = m
        else:
            a = m
    pb = poles(b)
    q = rightmost(pb)
    freq = abs(q.imag) / (2 * math.pi)
    note = "the crossing closed-loop pole" if controller is not None else "the crossing plant pole"
    if dt is not None:
        freq, note = _unaliased_frequency(op, controller, b, q, dt)
    mid = 0.5 * (a + b)
    return JudderCrossing(
        mu_slope_crit=mid,
        c_crit=k13 * mid,
        tolerance=0.5 * abs(b - a),
        stable_side=a,
        unstable_side=b,
        crossing_pole=q,
        frequency_hz=freq,
        frequency_note=note,
        k13=k13,
        spectral_abscissa_at_zero=a0,
        searched=(-float(search_limit), 0.0),
        evaluations=count,
        controller=name,
        dt=dt,
        reason=None,
    )


def _unaliased_frequency(
    op: OperatingPoint, controller: Any, mu: float, q: complex, dt: float
) -> tuple[float, str]:
    """Frequency [Hz] of a sampled loop's crossing pole ``q = ln(z)/dt``: ``|Im q|/2pi`` is only
    known up to multiples of the sample rate; when a pole ``lambda`` of the continuous plant at
    mu' = ``mu`` maps onto it (``exp(lambda dt)`` nearest to ``z``, within 1 %), that mode's
    frequency is reported."""
    z = complex(np.exp(q * dt))
    lam = np.linalg.eigvals(np.asarray(linearise(op, inputs=("x_c",), mu_slope=mu).A))
    if lam.size:
        zl = np.exp(lam * dt)
        k = int(np.argmin(np.abs(zl - z)))
        if abs(zl[k] - z) <= 0.01 * max(abs(z), 1.0):
            f = abs(lam[k].imag) / (2 * math.pi)
            return f, (
                "the plant mode exp(lambda dt) nearest to the crossing closed-loop pole z"
                + (" (above the sampled loop's Nyquist frequency)" if f > 0.5 / dt else "")
            )
    return abs(q.imag) / (2 * math.pi), (
        f"|Im ln(z)|/(2 pi dt) of the crossing closed-loop pole (a sampled loop knows frequencies "
        f"up to multiples of its sample rate {1 / dt:g} Hz)"
    )
