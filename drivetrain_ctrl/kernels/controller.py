"""Inputs of a run: the input signals' linear pieces and the closed-loop controller.

Input signals are packed by :func:`drivetrain_ctrl.core.signals.pack_signals` into ``S = (st, sv,
snk, ssin, sns)``: knots ``st``/``sv`` per signal and additive sine terms; within an interval
between breakpoints each signal is ``a + b (t - t_ref)`` plus its sines (:func:`set_interval`,
:func:`eval_inputs`). An optional controller (:class:`CtrlData`, built by
:mod:`drivetrain_ctrl.control.blocks`) overrides one input (:func:`eval_u`); its continuous states
are integrated with the plant (:func:`cl_derivs`), its discrete block states ``cs`` change at
its guards (:func:`cl_guards`, :func:`cl_update`) and, if it is discrete, at its samples
(:func:`cl_sample`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._jit import F64, I64, jit, jit_inline, jit_nonrt
from .physics import SLIP_NEG, SLIP_POS, STUCK


@jit_inline
def _piece(st, sv, snk, i, t_ref):
    """(value at t_ref, slope) of the linear piece of signal ``i`` active at ``t_ref``."""
    nk = snk[i]
    k = -1
    for j in range(nk):
        if st[i, j] <= t_ref:
            k = j
        else:
            break
    if k < 0:
        return sv[i, 0], 0.0
    if k >= nk - 1:
        return sv[i, nk - 1], 0.0
    t0 = st[i, k]
    t1 = st[i, k + 1]
    if t1 <= t0:
        return sv[i, k + 1], 0.0
    slope = (sv[i, k + 1] - sv[i, k]) / (t1 - t0)
    return sv[i, k] + slope * (t_ref - t0), slope


@jit_nonrt
def set_interval(S, t_ref, ua, ub):
    """Coefficients of every input on the interval starting at ``t_ref``."""
    st, sv, snk, ssin, sns = S
    for i in range(ua.shape[0]):
        a, b = _piece(st, sv, snk, i, t_ref)
        ua[i] = a
        ub[i] = b


class CtrlData(NamedTuple):
    """Array form of a closed-loop controller (see :mod:`drivetrain_ctrl.control.blocks`).

    Measurement ``e = sum coef_k * (state or signal)``; SISO LTI ``(A, B, C, D)`` (continuous, or
    discrete with period ``Ts`` and a delay of ``n_delay`` samples); then, in order: sign switching
    by ``sign(x[a] - x[b])``, offset, lookup table, saturation, latch-and-ramp (triggered when a
    friction element enters a mode), rate limiter, second-order actuator; the result drives the
    plant input ``out_u``. Integer/float parameters are packed in ``ci``/``cf`` (``CI_*``,
    ``CF_*`` indices).
    """

    m_kind: I64
    m_idx: I64
    m_coef: F64
    A: F64
    B: F64
    C: F64
    Dm: F64
    ci: I64
    cf: F64
    lk_b: F64
    lk_s: F64
    lk_o: F64


CI_OUT, CI_NC, CI_DISC, CI_NDELAY, CI_SA, CI_SB, CI_LF, CI_LM = 0, 1, 2, 3, 4, 5, 6, 7
CI_ACT, CI_RL, CI_LKNB, CI_SAT, CI_ND = 8, 9, 10, 11, 12
N_CI = 13
CF_TS, CF_OFF, CF_LO, CF_HI, CF_RLR, CF_RLG, CF_LR, CF_LT, CF_AW, CF_AZ = range(10)
CF_TON, CF_HOLD, CF_AWK = 10, 11, 12
N_CF = 13
CS_SIGN, CS_SAT, CS_LK, CS_RL, CS_LATCH, CS_TL, CS_VL, CS_HELD, CS_TR, CS_D0, CS_XD = range(11)


#: latch states (``cs[CS_LATCH]``): armed, ramping to the target, holding the target, re-armed
#: after a re-slip with the offset ``cs[CS_D0]`` (taken at ``cs[CS_TR]``) ramping out
LATCH_ARMED, LATCH_RAMP, LATCH_HELD, LATCH_REARMED = 0.0, 1.0, 2.0, 3.0


#: controller blocks whose discrete state changes are listed as events, element index
#: ``nf + nt + k`` for block k = the state ``cs[k]``: sign, saturation, lookup segment, rate
#: limiter, latch (CS_SIGN .. CS_LATCH are 0 .. 4); ``nf + nt + N_CL_EVENT_BLOCKS`` names the
#: controller as a whole (a Zeno stop on its guards)
N_CL_EVENT_BLOCKS = 5
N_CL_GUARDS = 8


def empty_controller() -> CtrlData:
    """An open loop: no controller states, no guards, no input overridden."""
    ci = np.zeros(N_CI, dtype=np.int64)
    ci[CI_OUT] = -1
    ci[CI_SA] = -1
    ci[CI_SB] = -1
    ci[CI_LF] = -1
    ci[CI_LKNB] = -1
    cf = np.zeros(N_CF)
    cf[CF_TON] = -np.inf
    return CtrlData(
        np.zeros(0, np.int64),
        np.zeros(0, np.int64),
        np.zeros(0),
        np.zeros((0, 0)),
        np.zeros(0),
        np.zeros(0),
        np.zeros(1),
        ci,
        cf,
        np.zeros(1),
        np.zeros(1),
        np.zeros(1),
    )


@jit_inline
def n_cl_states(Cd):
    """Continuous controller states: LTI (if continuous), rate limiter, actuator (2)."""
    return Cd.ci[CI_NC] + Cd.ci[CI_RL] + 2 * Cd.ci[CI_ACT]


@jit_inline
def cl_error(Cd, y, sv):
    e = 0.0
    for k in range(Cd.m_kind.shape[0]):
        if Cd.m_kind[k] == 0:
            e += Cd.m_coef[k] * y[Cd.m_idx[k]]
        else:
            e += Cd.m_coef[k] * sv[Cd.m_idx[k]]
    return e


@jit_inline
def cl_chain(Cd, cs, y, nx, t, e):
    """(lookup argument, value before saturation, output before rate limiter/actuator).

    Inlined (called in every closed-loop derivative: a call flattens CtrlData's arrays).

    Before the start time ``cf[CF_TON]`` all three are the hold value ``cf[CF_HOLD]``."""
    ci = Cd.ci
    cf = Cd.cf
    if t < cf[CF_TON]:
        hold = cf[CF_HOLD]
        return hold, hold, hold
    if ci[CI_DISC] != 0:
        v = cs[CS_HELD]
    else:
        v = Cd.Dm[0] * e
        for i in range(ci[CI_NC]):
            v += Cd.C[i] * y[nx + i]
    if ci[CI_SA] >= 0:
        v *= cs[CS_SIGN]
    v += cf[CF_OFF]
    varg = v
    if ci[CI_LKNB] >= 0:
        r = int(cs[CS_LK])
        v = Cd.lk_s[r] * v + Cd.lk_o[r]
    lat = cs[CS_LATCH]
    if lat == LATCH_REARMED:
        d0 = cs[CS_D0]
        v += d0 - (1.0 if d0 > 0.0 else -1.0) * cf[CF_LR] * (t - cs[CS_TR])
    vpre = v
    if ci[CI_SAT] != 0:
        sr = int(cs[CS_SAT])
        if sr == 0:
            v = cf[CF_LO]
        elif sr == 2:
            v = cf[CF_HI]
    if lat == LATCH_RAMP:
        d = 1.0 if cf[CF_LT] >= cs[CS_VL] else -1.0
        v = cs[CS_VL] + d * cf[CF_LR] * (t - cs[CS_TL])
    elif lat == LATCH_HELD:
        v = cf[CF_LT]
    return varg, vpre, v


@jit_inline
def cl_frozen(Cd, cs, t):
    """True while the LTI states must not move: before the start and while latched."""
    if t < Cd.cf[CF_TON]:
        return True
    lat = cs[CS_LATCH]
    return lat == LATCH_RAMP or lat == LATCH_HELD


@jit_inline
def cl_backcalc(Cd, cs, vpre):
    """Back-calculation anti-windup: the factor ``k`` such that adding ``k C^T`` to the LTI state
    derivative moves the value before saturation towards the saturated one with time constant
    ``1 / cf[CF_AWK]`` (0 when off or not saturated)."""
    cf = Cd.cf
    if cf[CF_AWK] <= 0.0 or Cd.ci[CI_SAT] == 0:
        return 0.0
    vs = min(max(vpre, cf[CF_LO]), cf[CF_HI])
    if vs == vpre:
        return 0.0
    cc = 0.0
    for i in range(Cd.C.shape[0]):
        cc += Cd.C[i] * Cd.C[i]
    if cc == 0.0:
        return 0.0
    sg = cs[CS_SIGN] if Cd.ci[CI_SA] >= 0 else 1.0
    return sg * (vs - vpre) * cf[CF_AWK] / cc


@jit_inline
def cl_output(Cd, cs, y, nx, t, sv):
    """The value applied to the plant input ``out_u``."""
    ci = Cd.ci
    i_rl = nx + ci[CI_NC]
    i_act = i_rl + ci[CI_RL]
    if ci[CI_ACT] != 0:
        return y[i_act]
    if ci[CI_RL] != 0:
        return y[i_rl]
    e = cl_error(Cd, y, sv)
    varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
    return v


@jit_inline
def cl_derivs(Cd, cs, y, nx, t, sv, dy):
    ci = Cd.ci
    cf = Cd.cf
    nc = ci[CI_NC]
    if ci[CI_OUT] < 0:
        return
    e = cl_error(Cd, y, sv)
    varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
    if cl_frozen(Cd, cs, t):
        for i in range(nc):
            dy[nx + i] = 0.0
    else:
        kb = cl_backcalc(Cd, cs, vpre)
        for i in range(nc):
            acc = Cd.B[i] * e + kb * Cd.C[i]
            for j in range(nc):
                acc += Cd.A[i, j] * y[nx + j]
            dy[nx + i] = acc
    i_rl = nx + nc
    i_act = i_rl + ci[CI_RL]
    xin = v
    if ci[CI_RL] != 0:
        rr = int(cs[CS_RL])
        if rr == 1:
            dy[i_rl] = cf[CF_RLG] * (v - y[i_rl])
        elif rr == 2:
            dy[i_rl] = cf[CF_RLR]
        else:
            dy[i_rl] = -cf[CF_RLR]
        xin = y[i_rl]
    if ci[CI_ACT] != 0:
        w = cf[CF_AW]
        dy[i_act] = y[i_act + 1]
        dy[i_act + 1] = w * w * (xin - y[i_act]) - 2.0 * cf[CF_AZ] * w * y[i_act + 1]


@jit_inline
def cl_guards(Cd, cs, y, nx, t, sv, g, off):
    """The controller's guards (>= 0 while its discrete state holds) into ``g[off:off+8]``."""
    ci = Cd.ci
    cf = Cd.cf
    for k in range(N_CL_GUARDS):
        g[off + k] = np.inf
    if ci[CI_OUT] < 0:
        return
    lat = cs[CS_LATCH]
    if ci[CI_SA] >= 0 and t >= cf[CF_TON] and lat != LATCH_RAMP and lat != LATCH_HELD:
        # the sign matters only while the law acts (not before the start, not while latched:
        # there the measured speeds may be equal by a stuck constraint, up to round-off)
        g[off] = cs[CS_SIGN] * (y[ci[CI_SA]] - y[ci[CI_SB]])
    e = cl_error(Cd, y, sv)
    varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
    if ci[CI_SAT] != 0:
        sr = int(cs[CS_SAT])
        if sr == 1:
            g[off + 1] = vpre - cf[CF_LO]
            g[off + 2] = cf[CF_HI] - vpre
        elif sr == 0:
            g[off + 1] = cf[CF_LO] - vpre
        else:
            g[off + 2] = vpre - cf[CF_HI]
    nb = ci[CI_LKNB]
    if nb > 0:
        r = int(cs[CS_LK])
        if r > 0:
            g[off + 3] = varg - Cd.lk_b[r - 1]
        if r < nb:
            g[off + 4] = Cd.lk_b[r] - varg
    if ci[CI_RL] != 0:
        z = cf[CF_RLG] * (v - y[nx + ci[CI_NC]])
        R = cf[CF_RLR]
        rr = int(cs[CS_RL])
        if rr == 1:
            g[off + 5] = R - z
            g[off + 6] = z + R
        elif rr == 2:
            g[off + 5] = z - R
        else:
            g[off + 6] = -R - z
    if cs[CS_LATCH] == LATCH_RAMP:
        d = 1.0 if cf[CF_LT] >= cs[CS_VL] else -1.0
        g[off + 7] = (cf[CF_LT] - v) * d
    elif cs[CS_LATCH] == LATCH_REARMED:
        g[off + 7] = abs(cs[CS_D0]) - cf[CF_LR] * (t - cs[CS_TR])


@jit_nonrt
def cl_update(Cd, cs, y, nx, t, sv, fm):
    """Set the controller's discrete state from the current values (start and events)."""
    ci = Cd.ci
    cf = Cd.cf
    if ci[CI_OUT] < 0:
        return
    if ci[CI_SA] >= 0:
        ya = y[ci[CI_SA]]
        yb = y[ci[CI_SB]]
        d = ya - yb
        tol = 1e-8 * (1.0 + abs(ya) + abs(yb))
        if d > tol:
            cs[CS_SIGN] = 1.0
        elif d < -tol:
            cs[CS_SIGN] = -1.0
        elif cs[CS_SIGN] == 0.0:
            cs[CS_SIGN] = 1.0 if d >= 0.0 else -1.0
        elif (
            ci[CI_LF] >= 0
            and (cs[CS_LATCH] == LATCH_RAMP or cs[CS_LATCH] == LATCH_HELD)
            and (fm[ci[CI_LF]] == SLIP_POS or fm[ci[CI_LF]] == SLIP_NEG)
        ):
            # a re-slip of the latched element: the speeds part in its slip direction
            cs[CS_SIGN] = 1.0 if fm[ci[CI_LF]] == SLIP_POS else -1.0
        elif cs[CS_SIGN] * d <= 0.0 and not (ci[CI_LF] >= 0 and fm[ci[CI_LF]] == STUCK):
            # at the switching instant (equal speeds up to the event location) and on or past
            # the switching surface: the difference is crossing zero, the sign flips (a stuck
            # latch element keeps it: the speeds stay equal)
            cs[CS_SIGN] = -cs[CS_SIGN]
    e = cl_error(Cd, y, sv)
    lf = ci[CI_LF]
    if lf >= 0 and t >= cf[CF_TON]:
        lat = cs[CS_LATCH]
        locked = fm[lf] == ci[CI_LM]
        if (lat == LATCH_ARMED or lat == LATCH_REARMED) and locked:
            # latch: ramp from the current value (bumpless)
            varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
            cs[CS_LATCH] = LATCH_RAMP
            cs[CS_TL] = t
            cs[CS_VL] = v
        elif (lat == LATCH_RAMP or lat == LATCH_HELD) and not locked:
            # re-slip: re-arm, continuing from the current value; the offset to the law's value
            # ramps out at the latch rate
            varg, vpre, v_now = cl_chain(Cd, cs, y, nx, t, e)
            cs[CS_LATCH] = LATCH_ARMED
            varg, vpre, v_law = cl_chain(Cd, cs, y, nx, t, e)
            cs[CS_LATCH] = LATCH_REARMED
            cs[CS_TR] = t
            cs[CS_D0] = v_now - vpre
            if cs[CS_D0] == 0.0:
                cs[CS_LATCH] = LATCH_ARMED
    if cs[CS_LATCH] == LATCH_RAMP:
        varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
        d = 1.0 if cf[CF_LT] >= cs[CS_VL] else -1.0
        if (cf[CF_LT] - v) * d <= 0.0:
            cs[CS_LATCH] = LATCH_HELD
    elif cs[CS_LATCH] == LATCH_REARMED:
        if abs(cs[CS_D0]) - cf[CF_LR] * (t - cs[CS_TR]) <= 0.0:
            cs[CS_LATCH] = LATCH_ARMED
    nb = ci[CI_LKNB]
    if nb >= 0:
        varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
        r = 0
        while r < nb and varg > Cd.lk_b[r]:
            r += 1
        cs[CS_LK] = r
    if ci[CI_SAT] != 0:
        varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
        if vpre < cf[CF_LO]:
            cs[CS_SAT] = 0.0
        elif vpre > cf[CF_HI]:
            cs[CS_SAT] = 2.0
        else:
            cs[CS_SAT] = 1.0
    if ci[CI_RL] != 0:
        varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
        z = cf[CF_RLG] * (v - y[nx + ci[CI_NC]])
        if z > cf[CF_RLR]:
            cs[CS_RL] = 2.0
        elif z < -cf[CF_RLR]:
            cs[CS_RL] = 0.0
        else:
            cs[CS_RL] = 1.0


@jit_nonrt
def _cl_output_call(Cd, cs, y, nx, t, sv):
    """:func:`cl_output` as a compiled call (off the per-stage path: each inlined copy of the
    controller costs seconds of compile time)."""
    return cl_output(Cd, cs, y, nx, t, sv)


@jit_nonrt
def _cl_guards_call(Cd, cs, y, nx, t, sv, g, off):
    """:func:`cl_guards` as a compiled call (see :func:`cl_guards_cold`)."""
    cl_guards(Cd, cs, y, nx, t, sv, g, off)


@jit_inline
def cl_guards_cold(Cd, cs, y, nx, t, sv, g, off):
    """:func:`cl_guards` off the per-step path: in closed loop a compiled call, not inlined."""
    for k in range(N_CL_GUARDS):
        g[off + k] = np.inf
    if Cd.ci[CI_OUT] >= 0:
        _cl_guards_call(Cd, cs, y, nx, t, sv, g, off)


@jit_inline
def cl_command(Cd, cs, y, nx, t, sv):
    """The controller's command before the rate limiter and the actuator (x_r of law (6));
    NaN in open loop. ``sv`` must hold the current signal values."""
    if Cd.ci[CI_OUT] < 0:
        return np.nan
    e = cl_error(Cd, y, sv)
    varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
    return v


@jit_nonrt
def _cl_command_call(Cd, cs, y, nx, t, sv):
    """:func:`cl_command` as a compiled call (see :func:`cl_command_cold`)."""
    return cl_command(Cd, cs, y, nx, t, sv)


@jit_inline
def cl_command_cold(Cd, cs, y, nx, t, sv):
    """:func:`cl_command` off the per-step path: in closed loop a compiled call, not inlined."""
    if Cd.ci[CI_OUT] < 0:
        return np.nan
    return _cl_command_call(Cd, cs, y, nx, t, sv)


@jit
def cl_sample(Cd, cs, y, sv, t):
    """Discrete controller: one sample at ``t`` (output with delay, then state update; the state
    holds while :func:`cl_frozen`, and the error is 0 before the start)."""
    nd = Cd.ci[CI_ND]
    e = cl_error(Cd, y, sv) if t >= Cd.cf[CF_TON] else 0.0
    frozen = cl_frozen(Cd, cs, t)
    varg, vpre, v = cl_chain(Cd, cs, y, 0, t, e)
    kb = cl_backcalc(Cd, cs, vpre) * Cd.cf[CF_TS]
    w = Cd.Dm[0] * e
    for i in range(nd):
        w += Cd.C[i] * cs[CS_XD + i]
    xn = np.empty(nd)
    for i in range(nd):
        acc = Cd.B[i] * e + kb * Cd.C[i]
        for j in range(nd):
            acc += Cd.A[i, j] * cs[CS_XD + j]
        xn[i] = acc
    if not frozen:
        for i in range(nd):
            cs[CS_XD + i] = xn[i]
    nde = Cd.ci[CI_NDELAY]
    base = CS_XD + nd
    # shift the delay line: buf[0] oldest ... buf[nde] newest
    for k in range(nde):
        cs[base + k] = cs[base + k + 1]
    cs[base + nde] = w
    cs[CS_HELD] = cs[base]


@jit_inline
def _signal_inputs(S, ua, ub, t, t_ref, sv, u):
    """The input signals at ``t`` into ``sv`` and ``u`` (before the controller's output)."""
    eval_inputs(S, ua, ub, t, t_ref, sv)
    for i in range(u.shape[0]):
        u[i] = sv[i]


@jit_inline
def eval_u(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u):
    """Plant inputs at ``t``: signals, with the controlled input from the controller."""
    _signal_inputs(S, ua, ub, t, t_ref, sv, u)
    if Cd.ci[CI_OUT] >= 0:
        u[Cd.ci[CI_OUT]] = cl_output(Cd, cs, y, nx, t, sv)


@jit_inline
def eval_u_cold(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u):
    """:func:`eval_u` off the per-stage path: the controller by a compiled call."""
    _signal_inputs(S, ua, ub, t, t_ref, sv, u)
    if Cd.ci[CI_OUT] >= 0:
        u[Cd.ci[CI_OUT]] = _cl_output_call(Cd, cs, y, nx, t, sv)


@jit_inline
def eval_inputs(S, ua, ub, t, t_ref, u):
    ssin = S[3]
    sns = S[4]
    dt = t - t_ref
    for i in range(u.shape[0]):
        v = ua[i] + ub[i] * dt
        for j in range(sns[i]):
            if t_ref >= ssin[i, j, 3]:
                v += ssin[i, j, 0] * np.sin(ssin[i, j, 1] * (t - ssin[i, j, 3]) + ssin[i, j, 2])
        u[i] = v
