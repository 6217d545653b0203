"""Dormand-Prince 5(4) step of the augmented state and its continuous extension.

The augmented state is ``y = [x, controller states, W_in, E_diss...]`` (:func:`full_rhs`);
:func:`dp5_step` takes one embedded Runge-Kutta step with its error estimate and
:func:`dense_coeffs` / :func:`dense_eval` give the state within the step (Hairer's DOPRI5
continuous extension), which event location, the slip-dip check and the output grid sample
(the state at an event is then re-integrated with :func:`dp5_step`, see ``events._event_state``).
"""

from __future__ import annotations

import numpy as np

from ._jit import jit_inline, jit_nonrt
from .controller import cl_derivs, eval_u, n_cl_states
from .physics import rhs_into

# Dormand-Prince 5(4) tableau
C2, C3, C4, C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
A21 = 1 / 5
A31, A32 = 3 / 40, 9 / 40
A41, A42, A43 = 44 / 45, -56 / 15, 32 / 9
A51, A52, A53, A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
A61, A62, A63, A64, A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
B1, B3, B4, B5, B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
E1, E3, E4, E5, E6, E7 = (
    71 / 57600,
    -71 / 16695,
    71 / 1920,
    -17253 / 339200,
    22 / 525,
    -1 / 40,
)


@jit_inline
def error_norm(err, y, y1, nxs, rtol, atol):
    """Scaled RMS norm of a Dormand-Prince step's error estimate ``err`` over the first ``nxs``
    components: ``sqrt(mean((err_i / (atol + rtol max(|y_i|, |y1_i|)))^2))`` (Hairer, Norsett and
    Wanner, Solving ODEs I, Sect. II.4, eq. (4.11)); the step is accepted if it is <= 1 (a NaN
    is not). ``y``, ``y1`` the step's start and end."""
    en = 0.0
    for i in range(nxs):
        a = abs(y[i])
        b = abs(y1[i])
        r = err[i] / (atol + rtol * (a if a > b else b))
        en += r * r
    return np.sqrt(en / nxs)


@jit_inline
def full_rhs(D, S, ua, ub, t, t_ref, y, fm, reg, PT, nx, energy, u, tau, dy, Cd, cs, sv):
    """Derivative of the augmented state ``y = [x, controller states, W_in, E_diss...]``.

    ``PT``: transposed mode matrix (see :func:`rhs_into`). Hot path: no array views are made here
    (each view costs reference counting, which made a step 5x slower); ``u``, ``tau``, ``sv`` are
    work buffers (the dissipated powers go straight into ``dy``).
    """
    ne = nx + n_cl_states(Cd)
    eval_u(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u)
    p_in = rhs_into(D, y, u, fm, reg, PT, dy, tau, dy, ne + 1, energy)
    cl_derivs(Cd, cs, y, nx, t, sv, dy)
    if energy:
        dy[ne] = p_in


_C_TAB = np.array([0.0, C2, C3, C4, C5, 1.0, 1.0])


@jit_inline
def dp5_step(
    D,
    S,
    ua,
    ub,
    t,
    t_ref,
    y,
    h,
    fm,
    reg,
    PT,
    nx,
    energy,
    u,
    tau,
    Ks,
    dy,
    yt,
    y1,
    err,
    Cd,
    cs,
    sv,
):
    """One Dormand-Prince step from ``y`` with ``Ks[0] = f(y)``; writes ``y1``, ``err`` and
    ``Ks[6] = f(y1)`` (first same as last). One call site of ``full_rhs`` (inlined), stages in a
    loop: compiling seven inlined copies took minutes. Inlined into :func:`_advance` (a call passes
    ChainData, CtrlData and the signals as some 400 flattened arguments).

    The energy integrals (``y[nxs:]``) do not enter any derivative, so the intermediate stage
    states are formed for the first ``nxs`` components only and ``y1`` for all; ``err`` is written
    for the first ``nxs`` components (the ones the error norm uses). Stage sums are written out
    with the tableau's coefficients in the order of the generic loop. The second stage has weight
    0 in the solution, the error estimate and the continuous extension: its energy components
    (``Ks[1, nxs:]``) are neither computed nor read."""
    n = y.shape[0]
    nxs = nx + n_cl_states(Cd)
    for st in range(1, 7):
        if st == 1:
            for i in range(nxs):
                yt[i] = y[i] + h * (A21 * Ks[0, i])
        elif st == 2:
            for i in range(nxs):
                yt[i] = y[i] + h * (A31 * Ks[0, i] + A32 * Ks[1, i])
        elif st == 3:
            for i in range(nxs):
                yt[i] = y[i] + h * (A41 * Ks[0, i] + A42 * Ks[1, i] + A43 * Ks[2, i])
        elif st == 4:
            for i in range(nxs):
                yt[i] = y[i] + h * (
                    A51 * Ks[0, i] + A52 * Ks[1, i] + A53 * Ks[2, i] + A54 * Ks[3, i]
                )
        elif st == 5:
            for i in range(nxs):
                yt[i] = y[i] + h * (
                    A61 * Ks[0, i]
                    + A62 * Ks[1, i]
                    + A63 * Ks[2, i]
                    + A64 * Ks[3, i]
                    + A65 * Ks[4, i]
                )
        else:
            for i in range(n):
                v = y[i] + h * (
                    B1 * Ks[0, i] + B3 * Ks[2, i] + B4 * Ks[3, i] + B5 * Ks[4, i] + B6 * Ks[5, i]
                )
                yt[i] = v
                y1[i] = v
        full_rhs(
            D,
            S,
            ua,
            ub,
            t + _C_TAB[st] * h,
            t_ref,
            yt,
            fm,
            reg,
            PT,
            nx,
            energy and st != 1,
            u,
            tau,
            dy,
            Cd,
            cs,
            sv,
        )
        for i in range(n):
            Ks[st, i] = dy[i]
    for i in range(nxs):
        err[i] = h * (
            E1 * Ks[0, i]
            + E3 * Ks[2, i]
            + E4 * Ks[3, i]
            + E5 * Ks[4, i]
            + E6 * Ks[5, i]
            + E7 * Ks[6, i]
        )


@jit_nonrt
def full_rhs_call(D, S, ua, ub, t, t_ref, y, fm, reg, PT, nx, energy, u, tau, dy, Cd, cs, sv):
    """:func:`full_rhs` as an ordinary call (outside the hot loop)."""
    full_rhs(D, S, ua, ub, t, t_ref, y, fm, reg, PT, nx, energy, u, tau, dy, Cd, cs, sv)


D1, D3, D4, D5, D6, D7 = (
    -12715105075 / 11282082432,
    87487479700 / 32700410799,
    -10690763975 / 1880347072,
    701980252875 / 199316789632,
    -1453857185 / 822651844,
    69997945 / 29380423,
)


@jit_inline
def _dense_row(y0, y1, k0, k2, k3, k4, k5, k6, h):
    """Coefficients ``(r1, r2, r3, r4)`` of the Dormand-Prince continuous extension (Hairer's
    DOPRI5) of one component (or of any fixed linear combination of components) from its values
    ``y0``, ``y1`` at the step's ends and its stage derivatives ``k0``, ``k2`` .. ``k6``; the
    value at fraction ``th`` is :func:`_dense_value`."""
    r2 = y1 - y0
    r3 = h * k0 - r2
    return r2, r3, r2 - h * k6 - r3, h * (D1 * k0 + D3 * k2 + D4 * k3 + D5 * k4 + D6 * k5 + D7 * k6)


@jit_inline
def _dense_value(r0, r1, r2, r3, r4, th):
    """Continuous extension at fraction ``th`` of the step (``r0`` the value at its start)."""
    th1 = 1.0 - th
    return r0 + th * (r1 + th1 * (r2 + th * (r3 + th1 * r4)))


@jit_inline
def dense_coeffs(y, y1, Ks, h, rc):
    """Coefficients of the continuous extension of every component into ``rc``."""
    for i in range(y.shape[0]):
        rc[0, i] = y[i]
        rc[1, i], rc[2, i], rc[3, i], rc[4, i] = _dense_row(
            y[i], y1[i], Ks[0, i], Ks[2, i], Ks[3, i], Ks[4, i], Ks[5, i], Ks[6, i], h
        )


@jit_inline
def dense_eval(rc, th, out):
    """State at fraction ``th`` of the step from the continuous extension."""
    for i in range(out.shape[0]):
        out[i] = _dense_value(rc[0, i], rc[1, i], rc[2, i], rc[3, i], rc[4, i], th)
