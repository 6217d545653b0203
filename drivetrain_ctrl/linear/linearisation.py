"""Linearisation of one mode at an operating point (see :mod:`drivetrain_ctrl.linear`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import control
import numpy as np
import scipy.signal
from numpy.typing import NDArray

from .. import kernels as K
from ..core.validate import finite_float
from ..plant.drivetrain import Drivetrain
from .operating_point import (
    INPUT_ALIASES,
    OperatingPoint,
    _friction,
    _frozen,
    _mu_ratio,
    _reduction,
    _with_codes,
    operating_point_from_result,
    require_op,
)

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class LinearisationParts:
    """Full-coordinate pieces of the linearisation at an operating point (SI).

    ``A``, ``B``: ``d x'/dx``, ``d x'/du`` in the mode (mu-slope override applied);
    ``dtau_dx``, ``dtau_du``: generalised body torques without constraint torques;
    ``clutch_dx``, ``clutch_du``: the clutch torque tau_13 [N m];
    ``engine_dx``, ``engine_du``: engine output torque C_1 [N m];
    ``mu_slope_torque``: ``c = k13 mu'`` [N m s/rad] used; ``clutch_gain``: d tau_13/d x_c
    [N m/m] (``k13' mu s`` in slip, 0 otherwise); ``capacity``: k13(x_c) [N m];
    ``mu``: ``mu(|w|)/mu(0)`` [-]; ``sign``: sgn of the clutch slip (0 when not slipping).
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
    level ``mu(|w|)`` is kept): the clutch torque gets the slope ``c = k13(x_c) mu_slope``. Only
    meaningful while the clutch slips (ignored otherwise). The Jacobians at ``op`` are computed
    once and kept for the last few operating points (an operating point is immutable); a slope
    override is a rank-one change of them (the slope enters only through the clutch torque's
    derivative by the slip speed).
    """
    base = _base_parts(op)
    if mu_slope is None or base.P is None:
        return base.parts
    p = base.parts
    n = base.P.shape[0]
    i, ratio, g = base.i, base.ratio, base.g
    c_new = p.capacity * finite_float("mu_slope", mu_slope)
    dc = c_new - p.mu_slope_torque
    clutch_dx = p.clutch_dx + dc * g
    # torque -dc g^T on body i, +ratio dc g^T on body i+1
    dtau = np.zeros((n, g.shape[0]))
    dtau[i] -= dc * g
    dtau[i + 1] += ratio * dc * g
    A = np.array(p.A)
    A[:n] += base.P @ dtau
    return dataclasses.replace(
        p,
        A=_frozen(A),
        dtau_dx=_frozen(p.dtau_dx + dtau),
        clutch_dx=_frozen(clutch_dx),
        mu_slope_torque=float(c_new),
    )


@dataclass(frozen=True)
class _BaseParts:
    """:func:`linearisation_parts` at an operating point without a slope override, and what an
    override needs: the mode's matrix ``P`` (None unless the clutch slips), the clutch's coupling
    ``i``, its ``ratio`` and the slip-speed row ``g``."""

    parts: LinearisationParts
    P: F64 | None
    i: int
    ratio: float
    g: F64


#: operating points whose Jacobians are kept (least recently used dropped first)
_PARTS_CACHE_SIZE = 8
_PARTS: dict[int, tuple[OperatingPoint, _BaseParts]] = {}


def _base_parts(op: OperatingPoint) -> _BaseParts:
    hit = _PARTS.pop(id(op), None)
    if hit is not None and hit[0] is op:
        _PARTS[id(op)] = hit
        return hit[1]
    base = _compute_base_parts(op)
    _PARTS[id(op)] = (op, base)  # op is held: its id is not reused while kept
    while len(_PARTS) > _PARTS_CACHE_SIZE:
        del _PARTS[next(iter(_PARTS))]
    return base


def _compute_base_parts(op: OperatingPoint) -> _BaseParts:
    m, x, u, mode = op.model, np.asarray(op.x), np.asarray(op.u), op.mode
    n = m.n_bodies
    D = m.data
    fc = _friction(m, "clutch")
    M = np.asarray(D.M)
    A, B = m.jacobian(x, u, mode)
    A = np.array(A)
    B = np.array(B)
    no_stuck = _with_codes(mode, {f: K.OPEN for f in range(len(mode.fm)) if mode.fm[f] == K.STUCK})
    # without a stuck element the mode is its own stuck-free version: the same Jacobian
    J1_, B1_ = (A, B) if no_stuck == mode else m.jacobian(x, u, no_stuck)
    dtau_dx = M[:, None] * np.asarray(J1_)[:n]
    dtau_du = M[:, None] * np.asarray(B1_)[:n]
    no_clutch = _with_codes(no_stuck, {fc: K.OPEN})
    J2_, B2_ = m.jacobian(x, u, no_clutch)
    dtau2_dx = M[:, None] * np.asarray(J2_)[:n]
    dtau2_du = M[:, None] * np.asarray(B2_)[:n]
    i = int(D.f_idx[fc])
    ratio = float(D.ratio[i])
    code = mode.fm[fc]
    cap = m.capacity(fc, u, mode)
    mu, dmu = _mu_ratio(m, fc, x, mode)
    c = 0.0
    gain = 0.0
    sign = 0
    g = np.zeros(m.nx)
    g[i] = 1.0
    g[i + 1] = -ratio
    P = None
    if code in (K.SLIP_POS, K.SLIP_NEG):
        sign = 1 if code == K.SLIP_POS else -1
        clutch_dx = -(dtau_dx[i] - dtau2_dx[i])
        clutch_du = -(dtau_du[i] - dtau2_du[i])
        c = float(clutch_dx[i])
        gain = float(clutch_du[m.input_names.index("pedal")])
        P, _ = K.mode_matrices(D, np.array(mode.fm, dtype=np.int64))
        P = _frozen(P)
    elif code == K.STUCK:
        _, Lam = K.mode_matrices(D, np.array(mode.fm, dtype=np.int64))
        # the least-norm part of the stuck-torque matrix (its last nf columns span the
        # self-balancing torques of a statically indeterminate stuck set)
        clutch_dx = Lam[fc, :n] @ dtau_dx
        clutch_du = Lam[fc, :n] @ dtau_du
    else:
        clutch_dx = np.zeros(m.nx)
        clutch_du = np.zeros(len(m.input_names))
    ie = m.chain.body_index("engine")
    parts = LinearisationParts(
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
    return _BaseParts(parts=parts, P=P, i=i, ratio=ratio, g=_frozen(g))


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
    n = m.n_bodies
    avail = list(m.state_names[:n]) + ["tau_13", "C_1", "a_vehicle"]
    for o in avail if outputs is None else outputs:
        if o not in avail:
            raise ValueError(f"outputs: {o!r} unknown; choose from {avail}")
    A, B, C, Df, names, outs = _linear_arrays(
        op,
        inputs=inputs,
        outputs=outputs,
        mu_slope=mu_slope,
        keep_positions=keep_positions,
        reduce=reduce,
    )
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


def _linear_arrays(
    op: OperatingPoint,
    *,
    inputs: Sequence[str],
    outputs: Sequence[str] | None,
    mu_slope: float | None = None,
    keep_positions: bool = False,
    reduce: bool = True,
) -> tuple[F64, F64, F64, F64, list[str], list[str]]:
    """``(A, B, C, D, state names, output names)`` of :func:`linearise` (its arguments already
    checked), as numpy arrays: for callers that need the matrices, not a python-control system."""
    m = op.model
    alias_inv = {v: k for k, v in INPUT_ALIASES.items() if k in m.input_names}
    parts = linearisation_parts(op, mu_slope=mu_slope)
    n = m.n_bodies
    uidx = [m.input_names.index(alias_inv[nm]) for nm in inputs]
    body_names = list(m.state_names[:n])
    outs = list(body_names + ["tau_13", "C_1", "a_vehicle"] if outputs is None else outputs)
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
    return A, B, C, Df, names, outs


def ss_to_tf(sys: control.StateSpace) -> control.TransferFunction:
    """``control.tf(sys)`` computed by scipy (``scipy.signal.ss2tf``, one input column at a time),
    names and sample time kept. With slycot installed python-control converts through slycot's
    ``tb04ad``, which on the 11-state clutch loop loses digits (a denominator coefficient 6000
    came out as 5999.998); scipy's characteristic-polynomial route keeps them."""
    nums, dens = _ss_to_tf_lists(*_ss_arrays(sys))
    return control.tf(
        nums, dens, sys.dt, inputs=sys.input_labels, outputs=sys.output_labels, name=sys.name
    )


def _ss_arrays(sys: control.StateSpace) -> tuple[F64, F64, F64, F64]:
    return (
        np.asarray(sys.A, dtype=float),
        np.asarray(sys.B, dtype=float),
        np.asarray(sys.C, dtype=float),
        np.asarray(sys.D, dtype=float),
    )


def _ss_to_tf_lists(A: F64, B: F64, C: F64, D: F64) -> tuple[list[list[Any]], list[list[Any]]]:
    """Numerators and denominators (lists by output, then input) of :func:`ss_to_tf`."""
    nu, ny = B.shape[1], C.shape[0]
    nums: list[list[Any]] = [[None] * nu for _ in range(ny)]
    dens: list[list[Any]] = [[None] * nu for _ in range(ny)]
    for j in range(nu):
        num, den = scipy.signal.ss2tf(A, B, C, D, input=j)
        for i in range(ny):
            nums[i][j] = np.trim_zeros(np.atleast_1d(num[i]), "f") if np.any(num[i]) else [0.0]
            dens[i][j] = den
    return nums, dens


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
    the sample time are kept. The conversion is scipy's (:func:`ss_to_tf`), whether slycot is
    installed or not."""
    if not isinstance(sys, control.StateSpace) or sys.nstates == 0:
        return control.tf(sys)
    return _trim_tf_arrays(
        *_ss_arrays(sys),
        sys.dt,
        inputs=sys.input_labels,
        outputs=sys.output_labels,
        name=sys.name,
    )


def _trim_tf_arrays(
    A: F64, B: F64, C: F64, D: F64, dt: Any, **names: Any
) -> control.TransferFunction:
    """:func:`trim_tf` of the system ``(A, B, C, D)`` (at least one state) with sample time
    ``dt`` (None or 0: continuous) and python-control's naming keywords ``names``."""
    tnums, tdens = _ss_to_tf_lists(A, B, C, D)
    nums = []
    for i in range(len(tnums)):
        row = []
        for j in range(len(tnums[i])):
            num = np.atleast_1d(np.asarray(tnums[i][j], dtype=float))
            big = float(np.max(np.abs(num))) if num.size else 0.0
            # num[k] is the coefficient behind Markov parameter k + off (0: D, 1: C B, ...)
            off = len(tdens[i][j]) - num.size
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
    dens = [[np.asarray(tdens[i][j], dtype=float) for j in range(len(tdens[i]))]
            for i in range(len(tdens))]  # fmt: skip
    return control.tf(nums, dens, dt if dt else 0, **names)


def _tf_min(sys: Any) -> control.TransferFunction:
    """Minimal transfer function (pole-zero cancellation; no slycot needed), with round-off
    leading numerator coefficients dropped (:func:`trim_tf`)."""
    return control.minreal(trim_tf(sys), verbose=False)


def _siso(sys: control.StateSpace, inp: str, out: str) -> control.StateSpace:
    i = list(sys.input_labels).index(inp)
    o = list(sys.output_labels).index(out)
    s = control.ss(sys.A, sys.B[:, [i]], sys.C[[o], :], sys.D[[o]][:, [i]])
    return s


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
    if not finite_float("min_duration", min_duration) >= 0:
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
