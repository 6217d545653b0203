"""Compiled event-driven hybrid integrator (the hot path).

Integrates a :class:`~drivetrain_ctrl.kernels.ChainData` model mode by mode with an embedded
Dormand-Prince 5(4) Runge-Kutta method:

* within a mode the right-hand side is smooth: the mode's stuck constraints, the affine piece of
  every piecewise-linear law and the current piece of every input signal are held fixed;
* after each accepted step every guard is checked; a guard that turned negative is an event,
  located by re-integrating from the step start with a shorter step (Illinois regula falsi) to
  a bracket of ``1e-13 * max(1, |t|)`` s; the state just past the event is taken;
* at an event all elements at zero relative speed are decided together
  (:func:`~drivetrain_ctrl.kernels.decide_modes`), then the guards are re-checked until none
  fires; a run of too many events in a short time (Zeno) stops the run with a status naming the
  time and the element;
* every input breakpoint is a forced stop; the step is bounded by ``h_max`` so that short stick
  or break-away episodes are not stepped over;
* supplied work and each element's dissipated energy are integrated with the state.

An optional closed loop (:mod:`drivetrain_ctrl.closedloop`) computes the inputs from controller
states integrated together with the plant.
"""

from __future__ import annotations

import numpy as np
from numba import njit

jit = njit(cache=True, error_model="numpy")
jit_inline = njit(cache=True, error_model="numpy", inline="always")

from . import kernels as K

# status codes
OK, ZENO, MAX_EVENTS, MAX_STEPS, STEP_TOO_SMALL = 0, 1, 2, 3, 4

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


@jit
def signal_value(st, sv, snk, ssin, sns, i, t, t_ref):  # type: ignore[no-untyped-def]
    """Value of signal ``i`` at ``t`` on the linear piece active at ``t_ref``."""
    a, b = _piece(st, sv, snk, i, t_ref)
    v = a + b * (t - t_ref)
    for j in range(sns[i]):
        if t_ref >= ssin[i, j, 3]:
            v += ssin[i, j, 0] * np.sin(ssin[i, j, 1] * (t - ssin[i, j, 3]) + ssin[i, j, 2])
    return v


@jit_inline
def _piece(st, sv, snk, i, t_ref):  # type: ignore[no-untyped-def]
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


@jit
def set_interval(S, t_ref, ua, ub):  # type: ignore[no-untyped-def]
    """Coefficients of every input on the interval starting at ``t_ref``."""
    st, sv, snk, ssin, sns = S
    for i in range(ua.shape[0]):
        a, b = _piece(st, sv, snk, i, t_ref)
        ua[i] = a
        ub[i] = b


@jit_inline
def eval_inputs(S, ua, ub, t, t_ref, u):  # type: ignore[no-untyped-def]
    ssin = S[3]
    sns = S[4]
    dt = t - t_ref
    for i in range(u.shape[0]):
        v = ua[i] + ub[i] * dt
        for j in range(sns[i]):
            if t_ref >= ssin[i, j, 3]:
                v += ssin[i, j, 0] * np.sin(ssin[i, j, 1] * (t - ssin[i, j, 3]) + ssin[i, j, 2])
        u[i] = v


@jit_inline
def full_rhs(D, S, ua, ub, t, t_ref, y, fm, reg, P, nx, energy, W, dy):  # type: ignore[no-untyped-def]
    """Derivative of the augmented state ``y = [x, W_in, E_diss...]`` (W: work buffers)."""
    u = W[0]
    tau = W[1]
    pd = W[2]
    eval_inputs(S, ua, ub, t, t_ref, u)
    p_in = K.rhs_into(D, y[:nx], u, fm, reg, P, dy[:nx], tau, pd, energy)
    if energy:
        dy[nx] = p_in
        for k in range(pd.shape[0]):
            dy[nx + 1 + k] = pd[k]


@jit
def dp5_step(D, S, ua, ub, t, t_ref, y, h, fm, reg, P, nx, energy, W, ks, yt, y1, err):  # type: ignore[no-untyped-def]
    """One Dormand-Prince step from ``y`` with ``ks[0] = f(y)``; writes ``y1``, ``err``,
    ``ks[6] = f(y1)``."""
    n = y.shape[0]
    k1 = ks[0]
    k2 = ks[1]
    k3 = ks[2]
    k4 = ks[3]
    k5 = ks[4]
    k6 = ks[5]
    k7 = ks[6]
    for i in range(n):
        yt[i] = y[i] + h * (A21 * k1[i])
    full_rhs(D, S, ua, ub, t + C2 * h, t_ref, yt, fm, reg, P, nx, energy, W, k2)
    for i in range(n):
        yt[i] = y[i] + h * (A31 * k1[i] + A32 * k2[i])
    full_rhs(D, S, ua, ub, t + C3 * h, t_ref, yt, fm, reg, P, nx, energy, W, k3)
    for i in range(n):
        yt[i] = y[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i])
    full_rhs(D, S, ua, ub, t + C4 * h, t_ref, yt, fm, reg, P, nx, energy, W, k4)
    for i in range(n):
        yt[i] = y[i] + h * (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i])
    full_rhs(D, S, ua, ub, t + C5 * h, t_ref, yt, fm, reg, P, nx, energy, W, k5)
    for i in range(n):
        yt[i] = y[i] + h * (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i])
    full_rhs(D, S, ua, ub, t + h, t_ref, yt, fm, reg, P, nx, energy, W, k6)
    for i in range(n):
        y1[i] = y[i] + h * (B1 * k1[i] + B3 * k3[i] + B4 * k4[i] + B5 * k5[i] + B6 * k6[i])
    full_rhs(D, S, ua, ub, t + h, t_ref, y1, fm, reg, P, nx, energy, W, k7)
    for i in range(n):
        err[i] = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i])


D1, D3, D4, D5, D6, D7 = (
    -12715105075 / 11282082432,
    87487479700 / 32700410799,
    -10690763975 / 1880347072,
    701980252875 / 199316789632,
    -1453857185 / 822651844,
    69997945 / 29380423,
)


@jit_inline
def dense_coeffs(y, y1, ks, h, rc):  # type: ignore[no-untyped-def]
    """Coefficients of the Dormand-Prince continuous extension (Hairer's DOPRI5) into ``rc``."""
    for i in range(y.shape[0]):
        r2 = y1[i] - y[i]
        r3 = h * ks[0, i] - r2
        rc[0, i] = y[i]
        rc[1, i] = r2
        rc[2, i] = r3
        rc[3, i] = r2 - h * ks[6, i] - r3
        rc[4, i] = h * (
            D1 * ks[0, i] + D3 * ks[2, i] + D4 * ks[3, i] + D5 * ks[4, i] + D6 * ks[5, i] + D7 * ks[6, i]
        )


@jit_inline
def dense_eval(rc, th, out):  # type: ignore[no-untyped-def]
    """State at fraction ``th`` of the step from the continuous extension."""
    th1 = 1.0 - th
    for i in range(out.shape[0]):
        out[i] = rc[0, i] + th * (rc[1, i] + th1 * (rc[2, i] + th * (rc[3, i] + th1 * rc[4, i])))


@jit
def _guards_at(D, S, ua, ub, t, t_ref, y, fm, reg, Lam, nx, u, g):  # type: ignore[no-untyped-def]
    eval_inputs(S, ua, ub, t, t_ref, u)
    K.guards(D, y[:nx], u, fm, reg, Lam, g)


@jit
def _fired(g0, g1):  # type: ignore[no-untyped-def]
    """Index of the guard that fired in a step (most negative normalised), or -1."""
    best = -1
    best_frac = 2.0
    for j in range(g1.shape[0]):
        if g1[j] < 0.0 and (g0[j] >= 0.0 or g1[j] < g0[j]):
            a = g0[j] if g0[j] > 0.0 else 0.0
            frac = a / (a - g1[j])  # linear estimate of the crossing within the step
            if frac < best_frac:
                best_frac = frac
                best = j
    return best


@jit
def _record_changes(fm, fm_old, reg, reg_old, t, ev_t, ev_el, ev_from, ev_to, n_ev):  # type: ignore[no-untyped-def]
    """Append every changed friction mode / table region to the event arrays."""
    nf = fm.shape[0]
    for f in range(nf + reg.shape[0]):
        if f < nf:
            a_from = fm_old[f]
            a_to = fm[f]
        else:
            a_from = reg_old[f - nf]
            a_to = reg[f - nf]
        if a_from == a_to or n_ev >= ev_t.shape[0]:
            continue
        ev_t[n_ev] = t
        ev_el[n_ev] = f
        ev_from[n_ev] = a_from
        ev_to[n_ev] = a_to
        n_ev += 1
    return n_ev


@jit
def simulate_kernel(  # type: ignore[no-untyped-def]
    D,
    S,
    bps,
    x0,
    t0,
    t_end,
    rtol,
    atol,
    h_max,
    h_init,
    tol_w,
    energy,
    zeno_count,
    zeno_window,
    max_events,
    max_steps,
):
    """Run the hybrid simulation. Returns a tuple of outputs (see ``simulate.py``)."""
    nx = x0.shape[0]
    n = D.M.shape[0]
    nf = D.f_kind.shape[0]
    nt = D.t_nb.shape[0]
    npow = n + D.ratio.shape[0] + nf
    ny = nx + (1 + npow if energy else 0)
    nu = S[2].shape[0]
    ng = K.n_guards(D)
    W = np.zeros((3, max(nu, npow, n)))
    u = np.zeros(nu)
    W0 = W[0, :nu]
    W1 = W[1, :n]
    W2 = W[2, :npow]
    Wt = (W0, W1, W2)
    ua = np.zeros(nu)
    ub = np.zeros(nu)

    cap = 1024
    T = np.empty(cap)
    Y = np.empty((cap, ny))
    FM = np.empty((cap, nf), dtype=np.int64)
    RG = np.empty((cap, nt), dtype=np.int64)
    ev_t = np.empty(max_events + nf + nt)
    ev_el = np.empty(max_events + nf + nt, dtype=np.int64)
    ev_from = np.empty(max_events + nf + nt, dtype=np.int64)
    ev_to = np.empty(max_events + nf + nt, dtype=np.int64)
    n_ev = 0
    n_steps = 0
    n_rej = 0
    nfev = 0
    status = OK
    status_el = -1

    ks = np.empty((7, ny))
    yt = np.empty(ny)
    y1 = np.empty(ny)
    err = np.empty(ny)
    ys = np.empty(ny)
    yhi = np.empty(ny)
    rc = np.empty((5, ny))
    y = np.zeros(ny)
    y[:nx] = x0
    t = t0
    ib = 0
    while ib < bps.shape[0] and bps[ib] <= t:
        ib += 1
    t_ref = t
    set_interval(S, t_ref, ua, ub)
    fm = np.full(nf, K.OPEN, dtype=np.int64)
    reg = np.zeros(nt, dtype=np.int64)
    eval_inputs(S, ua, ub, t, t_ref, u)
    K.decide_modes(D, y[:nx], u, fm, reg, tol_w)
    P, Lam = K.mode_matrices(D, fm)
    g0 = np.empty(ng)
    g1 = np.empty(ng)
    gtry = np.empty(ng)
    h = h_init
    full_rhs(D, S, ua, ub, t, t_ref, y, fm, reg, P, nx, energy, Wt, ks[0])
    nfev += 1
    _guards_at(D, S, ua, ub, t, t_ref, y, fm, reg, Lam, nx, u, g0)

    T[0] = t
    Y[0] = y
    FM[0] = fm
    RG[0] = reg
    n_rec = 1
    zeno_ring = np.full(zeno_count, -np.inf)
    zeno_pos = 0
    err_old = 1.0

    while t < t_end:
        if n_steps >= max_steps:
            status = MAX_STEPS
            break
        t_stop = t_end
        if ib < bps.shape[0] and bps[ib] < t_stop:
            t_stop = bps[ib]
        hh = min(h, h_max)
        hit_stop = hh >= t_stop - t
        if hit_stop:
            hh = t_stop - t
        dp5_step(D, S, ua, ub, t, t_ref, y, hh, fm, reg, P, nx, energy, Wt, ks, yt, y1, err)
        nfev += 6
        en = 0.0
        for i in range(nx):
            a = abs(y[i])
            b = abs(y1[i])
            r = err[i] / (atol + rtol * (a if a > b else b))
            en += r * r
        en = np.sqrt(en / nx)
        if not (en <= 1.0):
            n_rej += 1
            fac = 0.9 * en ** (-0.2) if en == en else 0.2
            h = hh * max(0.2, fac)
            if h < 1e-14 * max(1.0, abs(t)):
                status = STEP_TOO_SMALL
                break
            continue
        n_steps += 1
        # PI step-size control (Gustafsson)
        if en > 0.0:
            fac = 0.9 * en ** (-0.14) * err_old**0.08
        else:
            fac = 5.0
        err_old = max(en, 1e-4)
        h_next = hh * min(5.0, max(0.2, fac))
        t1 = t + hh if not hit_stop else t_stop
        _guards_at(D, S, ua, ub, t1, t_ref, y1, fm, reg, Lam, nx, u, g1)
        j = _fired(g0, g1)
        if j < 0:
            t = t1
            y[:] = y1
            ks[0, :] = ks[6]
            g0[:] = g1
        else:
            # locate the event on the continuous extension: Illinois on guard j in theta
            dense_coeffs(y, y1, ks, hh, rc)
            lo = 0.0
            hi = 1.0
            glo = g0[j] if g0[j] > 0.0 else 0.0
            ghi = g1[j]
            yhi[:] = y1
            side = 0
            tol_th = 1e-13 * max(1.0, abs(t)) / hh
            for _it in range(200):
                if hi - lo <= tol_th:
                    break
                s = hi - ghi * (hi - lo) / (ghi - glo) if ghi != glo else 0.5 * (lo + hi)
                margin = 0.01 * (hi - lo)
                if not (s - lo >= margin):
                    s = lo + margin
                if not (hi - s >= margin):
                    s = hi - margin
                dense_eval(rc, s, ys)
                _guards_at(D, S, ua, ub, t + s * hh, t_ref, ys, fm, reg, Lam, nx, u, gtry)
                jj = _fired(g0, gtry)
                if jj >= 0:
                    if jj != j:
                        j = jj
                        glo = g0[j] if g0[j] > 0.0 else 0.0
                    hi = s
                    ghi = gtry[j]
                    yhi[:] = ys
                    if side == -1:
                        glo *= 0.5
                    side = -1
                else:
                    lo = s
                    glo = gtry[j]
                    if side == 1:
                        ghi *= 0.5
                    side = 1
            hi = hi * hh
            t = t + hi
            y[:] = yhi
            fm_old = fm.copy()
            reg_old = reg.copy()
            eval_inputs(S, ua, ub, t, t_ref, u)
            for _rep in range(20):
                K.decide_modes(D, y[:nx], u, fm, reg, tol_w)
                P, Lam = K.mode_matrices(D, fm)
                K.guards(D, y[:nx], u, fm, reg, Lam, g0)
                bad = False
                for q in range(ng):
                    if g0[q] < -1e-9 * (1.0 + abs(g0[q])):
                        bad = True
                if not bad:
                    break
            n_old = n_ev
            n_ev = _record_changes(fm, fm_old, reg, reg_old, t, ev_t, ev_el, ev_from, ev_to, n_ev)
            for e in range(n_old, n_ev):
                zeno_ring[zeno_pos] = t
                zeno_pos = (zeno_pos + 1) % zeno_count
                if t - zeno_ring[zeno_pos] < zeno_window:
                    status = ZENO
                    status_el = ev_el[e]
            if status != OK:
                break
            if n_ev >= max_events:
                status = MAX_EVENTS
                break
            full_rhs(D, S, ua, ub, t, t_ref, y, fm, reg, P, nx, energy, Wt, ks[0])
            nfev += 1
            h_next = hh
        if j < 0 and hit_stop and t < t_end:
            # input breakpoint: new pieces of the inputs, re-decide the mode
            ib += 1
            while ib < bps.shape[0] and bps[ib] <= t:
                ib += 1
            t_ref = t
            set_interval(S, t_ref, ua, ub)
            fm_old = fm.copy()
            reg_old = reg.copy()
            eval_inputs(S, ua, ub, t, t_ref, u)
            K.decide_modes(D, y[:nx], u, fm, reg, tol_w)
            P, Lam = K.mode_matrices(D, fm)
            n_ev = _record_changes(fm, fm_old, reg, reg_old, t, ev_t, ev_el, ev_from, ev_to, n_ev)
            full_rhs(D, S, ua, ub, t, t_ref, y, fm, reg, P, nx, energy, Wt, ks[0])
            nfev += 1
            K.guards(D, y[:nx], u, fm, reg, Lam, g0)
            if hh < h:
                h_next = h
        h = h_next
        if n_rec >= T.shape[0]:
            c2 = 2 * T.shape[0]
            T2 = np.empty(c2)
            T2[:n_rec] = T[:n_rec]
            T = T2
            Y2 = np.empty((c2, ny))
            Y2[:n_rec] = Y[:n_rec]
            Y = Y2
            F2 = np.empty((c2, nf), dtype=np.int64)
            F2[:n_rec] = FM[:n_rec]
            FM = F2
            R2 = np.empty((c2, nt), dtype=np.int64)
            R2[:n_rec] = RG[:n_rec]
            RG = R2
        T[n_rec] = t
        Y[n_rec] = y
        FM[n_rec] = fm
        RG[n_rec] = reg
        n_rec += 1

    n_knee = 0
    for e in range(n_ev):
        if ev_el[e] >= nf:
            n_knee += 1
    return (
        T[:n_rec],
        Y[:n_rec],
        FM[:n_rec],
        RG[:n_rec],
        ev_t[:n_ev],
        ev_el[:n_ev],
        ev_from[:n_ev],
        ev_to[:n_ev],
        status,
        status_el,
        t,
        n_steps,
        n_rej,
        nfev,
        n_knee,
    )
