"""Compiled event-driven hybrid integrator (the hot path): :func:`simulate_kernel`.

Integrates a :class:`~drivetrain_ctrl.kernels.ChainData` model mode by mode with an embedded
Dormand-Prince 5(4) Runge-Kutta method (:mod:`.dopri`):

* within a mode the right-hand side is smooth: the mode's stuck constraints, the affine piece of
  every piecewise-linear law and the current piece of every input signal are held fixed;
* after each accepted step every guard is checked; a guard that turned negative is an event,
  located on the step's continuous extension (Illinois regula falsi) to a bracket of
  ``1e-13 * max(1, |t|)`` s; the state at the event is then re-integrated from the step start
  with one Dormand-Prince step of that length (error-controlled, the energy states with it) and
  the time corrected until the guard has just crossed zero on that trajectory (:mod:`.events`);
* at an event all elements at zero relative speed are decided together
  (:func:`~drivetrain_ctrl.kernels.decide_modes`), then the guards are re-checked until none
  fires; a run of too many events in a short time (Zeno) stops the run with a status naming the
  time and the element;
* every input breakpoint is a forced stop; the step is bounded by ``h_max`` so that short stick
  or break-away episodes are not stepped over, and by the mode's stability bound
  (:mod:`.stability`);
* supplied work and each element's dissipated energy are integrated with the state.

An optional closed loop (:mod:`drivetrain_ctrl.control.blocks`, :mod:`.controller`) computes the
inputs from controller states integrated together with the plant.
"""

from __future__ import annotations

import numpy as np
from numba import types
from numba.typed import Dict

from ._jit import jit, jit_inline, jit_nonrt
from .controller import (
    CF_TS,
    CI_DISC,
    CI_OUT,
    N_CL_EVENT_BLOCKS,
    N_CL_GUARDS,
    cl_command,
    cl_command_cold,
    cl_sample,
    eval_inputs,
    eval_u_cold,
    n_cl_states,
    set_interval,
)
from .decide import DM_TOO_MANY, _dm_work, _mm_alloc, _mm_insert
from .dopri import dense_coeffs, dense_eval, dp5_step, error_norm, full_rhs_call
from .events import (
    MAX_DIP_RETAKES,
    _decide_fast,
    _event_state,
    _fired,
    _guards_last_stage,
    _guards_step_inl,
    _locate,
    _redecide,
    _slip_dip,
    _zeno_push,
)
from .physics import OPEN, guard_element, n_guards
from .stability import _stab_lookup, stable_step_exact

_F2D = types.float64[:, ::1]


# status codes
OK, ZENO, MAX_EVENTS, MAX_STEPS, STEP_TOO_SMALL, TOO_MANY_CANDIDATES = 0, 1, 2, 3, 4, 5


@jit_inline
def _accept(y, y1, Ks, g0, g1):
    """Take an accepted step: y <- y1, k1 <- k7 (FSAL), guards at the start <- at the end."""
    for i in range(y.shape[0]):
        y[i] = y1[i]
        Ks[0, i] = Ks[6, i]
    for i in range(g0.shape[0]):
        g0[i] = g1[i]


@jit_inline
def _record(T, Y, U, FM, RG, n_rec, t, y, u, fm, reg):
    """Store sample ``n_rec`` (the arrays have room for it)."""
    T[n_rec] = t
    for i in range(y.shape[0]):
        Y[n_rec, i] = y[i]
    for i in range(u.shape[0]):
        U[n_rec, i] = u[i]
    for i in range(fm.shape[0]):
        FM[n_rec, i] = fm[i]
    for i in range(reg.shape[0]):
        RG[n_rec, i] = reg[i]


@jit_nonrt
def _record_grid(T, Y, U, FM, RG, n_rec, t_out, io, t, hh, t_lim, rc, ys, fm, reg, W):
    """Record the output-grid times ``t_out[io:]`` up to ``t_lim`` from the continuous extension
    ``rc`` of the step from ``t`` of length ``hh`` (the mode and regions of the step: at an event
    time, the left limit). ``W = (S, ua, ub, t_ref, nx, Cd, cs, uw, svw)``: the inputs there are
    evaluated into the work arrays ``uw``, ``svw``. Returns ``(n_rec, io)``."""
    S, ua, ub, t_ref, nx, Cd, cs, uw, svw = W
    while io < t_out.shape[0] and t_out[io] <= t_lim:
        tg = t_out[io]
        dense_eval(rc, (tg - t) / hh, ys)
        eval_u_cold(S, ua, ub, tg, t_ref, ys, nx, Cd, cs, svw, uw)
        _record(T, Y, U, FM, RG, n_rec, tg, ys, uw, fm, reg)
        U[n_rec, U.shape[1] - 1] = (
            np.nan if Cd.ci[CI_OUT] < 0 else cl_command_cold(Cd, cs, ys, nx, tg, svw)
        )
        n_rec += 1
        io += 1
    return n_rec, io


@jit_inline
def _scan_dissipation(Ks, k, off, t, fs, ist):
    """Second-law scan: the dissipated powers [W] in row ``k`` of ``Ks`` (a stage derivative at
    time ``t``: the energy columns from ``off`` on are the elements' powers); keeps the most
    negative in ``fs[8]`` (its time ``fs[9]``, its element ``ist[9]``) and the largest total
    ``sum |p|`` in ``fs[10]`` (the scale of round-off)."""
    tot = 0.0
    for j in range(off, Ks.shape[1]):
        p = Ks[k, j]
        tot += abs(p)
        if p < fs[8]:
            fs[8] = p
            fs[9] = t
            ist[9] = j - off
    if tot > fs[10]:
        fs[10] = tot


@jit_inline
def _step_end(
    T, Y, U, FM, RG, n_rec, t_out, io, t, hh, t1, y, y1, Ks, rc, ys, fm, reg, energy, nxs, fs,
    ist, W,
):  # fmt: skip
    """Before an accepted step from ``t`` to ``t1`` is taken: the output-grid times within it
    (:func:`_record_grid`, with an output grid) and the second-law scan of its end
    (:func:`_scan_dissipation`, with ``energy``). Returns ``(n_rec, io)``."""
    if t_out.shape[0] > 0 and io < t_out.shape[0] and t_out[io] <= t1:
        dense_coeffs(y, y1, Ks, hh, rc)
        n_rec, io = _record_grid(T, Y, U, FM, RG, n_rec, t_out, io, t, hh, t1, rc, ys, fm, reg, W)
    if energy:
        _scan_dissipation(Ks, 6, nxs + 1, t1, fs, ist)
    return n_rec, io


#: log of the smallest error norm the PI step control remembers (1e-4)
LOG_ERR_FLOOR = float(np.log(1e-4))


#: return codes of :func:`_advance`
ADV_DONE, ADV_MAX_STEPS, ADV_TOO_SMALL, ADV_FULL, ADV_STAB, ADV_STEP = 0, 1, 2, 3, 4, 5
#: the fired guard of an ``ADV_STEP`` cut to a stop time: its end's guards are not evaluated yet
GUARDS_PENDING = -2


@jit_nonrt
def _advance(
    D,
    S,
    ua,
    ub,
    t_ref,
    bps,
    t_end,
    h_max,
    rtol,
    atol,
    max_steps,
    y,
    fm,
    reg,
    PT,
    Lam,
    nx,
    energy,
    uw,
    u,
    tau,
    taug,
    Ks,
    dy,
    yt,
    y1,
    err,
    Cd,
    cs,
    svw,
    sv,
    g0,
    g1,
    T,
    Y,
    U,
    FM,
    RG,
    fs,
    ist,
    t_out,
    rec_every,
    rc,
    ys,
):
    """The step loop of :func:`simulate_kernel` within one mode, without reference counting.

    Takes steps (Dormand-Prince, error control, guards at the step end) and records the accepted
    ones until it returns a code: ``ADV_DONE`` (``t >= t_end``), ``ADV_MAX_STEPS``,
    ``ADV_TOO_SMALL``, ``ADV_FULL`` (no room to record a step), ``ADV_STAB`` (the tight stability
    bound is needed before the next step) or ``ADV_STEP``: an accepted step in which a guard
    fired or that ends at a stop time, not yet taken (the caller locates the event or handles the
    stop; for a step cut to a stop time ``j`` is ``GUARDS_PENDING`` and the caller evaluates the
    guards at its end). Scalars in ``fs`` = [t, h, log(err_old), h_stab, t_sample, hh, t1, h_next,
    p_min, t_pmin, p_scale] and ``ist`` = [ib, n_steps, n_rej, nfev, n_rec, stab_exact, j,
    hit_stop, io, el_pmin] (in and out; the last three of ``fs`` and the last of ``ist``: the
    second-law scan of :func:`_scan_dissipation` over the accepted steps' ends, with ``energy``).

    Recording: with an output grid ``t_out`` (non-empty) its times within each step, from the
    step's continuous extension (``rc``, ``ys`` work arrays; ``io`` the next grid index); else every
    ``rec_every``-th accepted step.
    """
    t = fs[0]
    h = fs[1]
    lerr_old = fs[2]
    h_stab = fs[3]
    t_sample = fs[4]
    ib = ist[0]
    n_steps = ist[1]
    n_rej = ist[2]
    nfev = ist[3]
    n_rec = ist[4]
    stab_exact = ist[5] != 0
    io = ist[8]
    grid = t_out.shape[0] > 0
    nxs = nx + n_cl_states(Cd)
    n_dip = 0
    code = ADV_DONE
    while True:
        if not (t < t_end):
            code = ADV_DONE
            break
        if n_steps >= max_steps:
            code = ADV_MAX_STEPS
            break
        if n_rec >= T.shape[0] and not grid:
            code = ADV_FULL
            break
        t_stop = t_end
        if ib < bps.shape[0] and bps[ib] < t_stop:
            t_stop = bps[ib]
        if t_sample < t_stop:
            t_stop = t_sample
        hh = min(h, h_max)
        if hh > h_stab and not stab_exact:
            # longer than the lower bound: the tight stability bound is needed now
            code = ADV_STAB
            break
        hh = min(hh, h_stab)
        hit_stop = hh >= t_stop - t
        if hit_stop:
            hh = t_stop - t
        dp5_step(
            D,
            S,
            ua,
            ub,
            t,
            t_ref,
            y,
            hh,
            fm,
            reg,
            PT,
            nx,
            energy,
            uw,
            tau,
            Ks,
            dy,
            yt,
            y1,
            err,
            Cd,
            cs,
            svw,
        )
        nfev += 6
        en = error_norm(err, y, y1, nxs, rtol, atol)
        if not (en <= 1.0):
            n_rej += 1
            fac = 0.9 * en ** (-0.2) if en == en else 0.2
            h = hh * max(0.2, fac)
            if h < 1e-14 * max(1.0, abs(t)):
                code = ADV_TOO_SMALL
                break
            continue
        if n_dip < MAX_DIP_RETAKES:
            th = _slip_dip(D, fm, y, y1, Ks, hh)
            if th > 0.0 and th * hh >= 1e-14 * max(1.0, abs(t)):
                # a slip speed dips through zero and back inside the step: retake the step up to
                # the dip's minimum, where its guard then fires (counted as a rejected step)
                n_dip += 1
                n_rej += 1
                h = th * hh
                continue
        n_dip = 0
        n_steps += 1
        # PI step-size control (Gustafsson): 0.9 en^-0.14 err_old^0.08, with log(err_old) kept
        # (one log and one exp a step instead of two pow calls)
        if en > 0.0:
            len_ = np.log(en)
            fac = 0.9 * np.exp(-0.14 * len_ + 0.08 * lerr_old)
        else:
            len_ = LOG_ERR_FLOOR
            fac = 5.0
        lerr_old = len_ if len_ > LOG_ERR_FLOOR else LOG_ERR_FLOOR
        h_next = hh * min(5.0, max(0.2, fac))
        t1 = t + hh if not hit_stop else t_stop
        # the last stage was evaluated at t + 1.0 * hh, y1: when that is t1 bitwise (always
        # unless the step was cut to a stop time), its inputs and forces give the guards; a step
        # cut to a stop time is returned with its guards still to evaluate (GUARDS_PENDING: the
        # caller does it, so that this loop holds no call of the guards)
        if t + hh == t1:
            _guards_last_stage(D, y1, fm, reg, Lam, nx, uw, g1, Cd, cs, svw, tau, t1, u, sv)
            j = _fired(g0, g1)
        else:
            j = GUARDS_PENDING
        if j >= 0 or hit_stop:
            fs[5] = hh
            fs[6] = t1
            fs[7] = h_next
            ist[6] = j
            ist[7] = 1 if hit_stop else 0
            code = ADV_STEP
            break
        n_rec, io = _step_end(
            T, Y, U, FM, RG, n_rec, t_out, io, t, hh, t1, y, y1, Ks, rc, ys, fm, reg, energy, nxs,
            fs, ist, (S, ua, ub, t_ref, nx, Cd, cs, uw, svw),
        )  # fmt: skip
        t = t1
        _accept(y, y1, Ks, g0, g1)
        h = h_next
        if not grid and (rec_every == 1 or n_steps % rec_every == 0):
            # u, sv hold the inputs and signals at t (from the step's last stage)
            _record(T, Y, U, FM, RG, n_rec, t, y, u, fm, reg)
            U[n_rec, U.shape[1] - 1] = (
                np.nan if Cd.ci[CI_OUT] < 0 else cl_command(Cd, cs, y, nx, t, sv)
            )
            n_rec += 1
    fs[0] = t
    fs[1] = h
    fs[2] = lerr_old
    ist[1] = n_steps
    ist[2] = n_rej
    ist[3] = nfev
    ist[4] = n_rec
    ist[8] = io
    return code


@jit
def _grow(T, Y, U, FM, RG, n_rec):
    """The output arrays with twice the room, the first ``n_rec`` rows copied."""
    c2 = 2 * T.shape[0]
    T2 = np.empty(c2)
    T2[:n_rec] = T[:n_rec]
    Y2 = np.empty((c2, Y.shape[1]))
    Y2[:n_rec] = Y[:n_rec]
    U2 = np.empty((c2, U.shape[1]))
    U2[:n_rec] = U[:n_rec]
    F2 = np.empty((c2, FM.shape[1]), dtype=np.int64)
    F2[:n_rec] = FM[:n_rec]
    R2 = np.empty((c2, RG.shape[1]), dtype=np.int64)
    R2[:n_rec] = RG[:n_rec]
    return T2, Y2, U2, F2, R2


@jit
def simulate_kernel(
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
    Cd,
    cs,
    y_cl0,
    nu,
    t_out,
    rec_every,
):
    """Run the hybrid simulation (open or closed loop). Returns a tuple of outputs.

    Recorded: with an output grid ``t_out`` (sorted, within [t0, t_end]; non-empty) the state,
    inputs and modes at exactly those times, from the integrator's continuous extension (at an
    event time the left limit); else the start, every ``rec_every``-th accepted step and every
    step that ends at an event or a stop. Events and integrated energies are the same either way.

    ``Cd``/``cs``: controller data and its discrete state (see :class:`CtrlData`);
    ``y_cl0``: initial continuous controller states; ``nu``: number of plant inputs (the
    first ``nu`` signals; the others are controller references).
    """
    nx = x0.shape[0]
    n = D.M.shape[0]
    nf = D.f_kind.shape[0]
    nt = D.t_nb.shape[0]
    ncl = n_cl_states(Cd)
    nxs = nx + ncl
    npow = n + D.ratio.shape[0] + nf
    ny = nxs + (1 + npow if energy else 0)
    nsig = S[2].shape[0]
    n_pg = n_guards(D)  # the plant's guards (then the controller's)
    ng = n_pg + N_CL_GUARDS
    u = np.zeros(nu)
    uw = np.zeros(nu)
    sv = np.zeros(nsig)
    svw = np.zeros(nsig)
    tau = np.zeros(n)
    taug = np.zeros(n)
    ua = np.zeros(nsig)
    ub = np.zeros(nsig)
    Ts = Cd.cf[CF_TS] if Cd.ci[CI_DISC] != 0 else np.inf
    t_sample = t0 if Cd.ci[CI_DISC] != 0 else np.inf

    # room for about 4 samples per h_max (growing by doubling beyond): no copies in a typical run;
    # with an output grid exactly its length
    grid = t_out.shape[0] > 0
    est = 4.0 * (t_end - t0) / h_max / rec_every + 64.0
    cap = t_out.shape[0] if grid else int(min(max(est, 1024.0), 65536.0))
    T = np.empty(cap)
    Y = np.empty((cap, ny))
    U = np.empty((cap, nu + 1))  # last column: the controller command (see cl_command)
    FM = np.empty((cap, nf), dtype=np.int64)
    RG = np.empty((cap, nt), dtype=np.int64)
    n_ev_room = max_events + nf + nt + N_CL_EVENT_BLOCKS
    ev_t = np.empty(n_ev_room)
    ev_el = np.empty(n_ev_room, dtype=np.int64)
    ev_from = np.empty(n_ev_room, dtype=np.int64)
    ev_to = np.empty(n_ev_room, dtype=np.int64)
    cs_old = np.zeros(N_CL_EVENT_BLOCKS)
    n_ev = 0
    n_steps = 0
    n_rej = 0
    nfev = 0
    status = OK
    status_el = -1

    Ks = np.empty((7, ny))
    dy = np.empty(ny)
    yt = np.empty(ny)
    y1 = np.empty(ny)
    err = np.empty(ny)
    ys = np.empty(ny)
    yhi = np.empty(ny)
    K2 = np.empty((7, ny))  # re-integration of an event's state (_event_state): its stages,
    ya = np.empty(ny)  # start and end of a piece
    yr = np.empty(ny)
    rc = np.empty((5, ny))
    y = np.zeros(ny)
    y[:nx] = x0
    y[nx:nxs] = y_cl0
    t = t0
    ib = 0
    while ib < bps.shape[0] and bps[ib] <= t:
        ib += 1
    t_ref = t
    set_interval(S, t_ref, ua, ub)
    fm = np.full(nf, OPEN, dtype=np.int64)
    reg = np.zeros(nt, dtype=np.int64)
    g0 = np.empty(ng)
    g1 = np.empty(ng)
    gtry = np.empty(ng)
    n_incons = 0
    if t_sample <= t:
        eval_inputs(S, ua, ub, t, t_ref, sv)
        cl_sample(Cd, cs, y, sv, t)
        t_sample = t + Ts
    mmask, mP, mPT, mL, mst = _mm_alloc(D)
    W = _dm_work(D)
    slot, nb = _decide_fast(
        D, S, ua, ub, t, t_ref, y, nx, fm, reg, u, tol_w, Cd, cs, sv, g0, W, mmask, mP, mPT, mL, mst
    )
    if nb == DM_TOO_MANY:
        # no decision: stop before the first step (the outputs hold the initial sample)
        status = TOO_MANY_CANDIDATES
        t_end = t
        slot = 0
        nb = 0
        _mm_insert(D, fm, mmask, mP, mPT, mL, mst)
    n_incons += nb
    hcache = Dict.empty(key_type=types.int64, value_type=types.float64)
    jcache = Dict.empty(key_type=types.int64, value_type=_F2D)
    lcache = Dict.empty(key_type=types.int64, value_type=types.float64)
    h_stab, stab_exact = _stab_lookup(D, y, u, fm, reg, mP[slot], nx, hcache, jcache, lcache)
    h = h_init
    full_rhs_call(
        D, S, ua, ub, t, t_ref, y, fm, reg, mPT[slot], nx, energy, uw, tau, dy, Cd, cs, svw
    )
    Ks[0, :] = dy
    nfev += 1
    # g0: the guards at (t, y) in the decided mode, from the decision (_dm_guards)

    n_rec = 0
    io = 0
    if not grid or t_out[0] <= t:
        T[0] = t
        Y[0] = y
        U[0, :nu] = u
        U[0, nu] = cl_command_cold(Cd, cs, y, nx, t, sv)
        FM[0] = fm
        RG[0] = reg
        n_rec = 1
        io = 1
    zeno_ring = np.full(zeno_count, -np.inf)
    zeno_pos = 0
    lerr_old = 0.0  # log of the previous step's error norm (PI control)
    fm_old = fm.copy()
    reg_old = reg.copy()

    fs = np.zeros(11)
    fs[8] = np.inf
    ist = np.zeros(10, dtype=np.int64)
    ist[9] = -1
    if energy:
        _scan_dissipation(Ks, 0, nxs + 1, t, fs, ist)
    pending = False  # a step taken here still to be recorded
    while True:
        if pending and not grid:
            if n_rec >= T.shape[0]:
                T, Y, U, FM, RG = _grow(T, Y, U, FM, RG, n_rec)
            # u, sv hold the inputs at (t, y): set by the mode decision at the event or stop
            _record(T, Y, U, FM, RG, n_rec, t, y, u, fm, reg)
            U[n_rec, U.shape[1] - 1] = (
                np.nan if Cd.ci[CI_OUT] < 0 else cl_command_cold(Cd, cs, y, nx, t, sv)
            )
            n_rec += 1
            pending = False
        ist[8] = io
        fs[0] = t
        fs[1] = h
        fs[2] = lerr_old
        fs[3] = h_stab
        fs[4] = t_sample
        ist[0] = ib
        ist[1] = n_steps
        ist[2] = n_rej
        ist[3] = nfev
        ist[4] = n_rec
        ist[5] = 1 if stab_exact else 0
        code = _advance(
            D,
            S,
            ua,
            ub,
            t_ref,
            bps,
            t_end,
            h_max,
            rtol,
            atol,
            max_steps,
            y,
            fm,
            reg,
            mPT[slot],
            mL[slot],
            nx,
            energy,
            uw,
            u,
            tau,
            taug,
            Ks,
            dy,
            yt,
            y1,
            err,
            Cd,
            cs,
            svw,
            sv,
            g0,
            g1,
            T,
            Y,
            U,
            FM,
            RG,
            fs,
            ist,
            t_out,
            rec_every,
            rc,
            ys,
        )
        t = fs[0]
        io = ist[8]
        h = fs[1]
        lerr_old = fs[2]
        n_steps = ist[1]
        n_rej = ist[2]
        nfev = ist[3]
        n_rec = ist[4]
        if code == ADV_DONE:
            break
        if code == ADV_MAX_STEPS:
            status = MAX_STEPS
            break
        if code == ADV_TOO_SMALL:
            status = STEP_TOO_SMALL
            break
        if code == ADV_FULL:
            T, Y, U, FM, RG = _grow(T, Y, U, FM, RG, n_rec)
            continue
        if code == ADV_STAB:
            h_stab = stable_step_exact(fm, reg, hcache, jcache)
            stab_exact = True
            continue
        # ADV_STEP: an accepted step with an event or ending at a stop time
        hh = fs[5]
        t1 = fs[6]
        h_next = fs[7]
        j = ist[6]
        hit_stop = ist[7] != 0
        if j == GUARDS_PENDING:
            # a step cut to a stop time: the guards at its end (t1, y1), and the inputs there
            _guards_step_inl(
                D, S, ua, ub, t1, t_ref, y1, fm, reg, mL[slot], nx, u, g1, Cd, cs, sv, taug
            )
            j = _fired(g0, g1)
        event = j >= 0
        if not event:
            n_rec, io = _step_end(
                T, Y, U, FM, RG, n_rec, t_out, io, t, hh, t1, y, y1, Ks, rc, ys, fm, reg, energy,
                nxs, fs, ist, (S, ua, ub, t_ref, nx, Cd, cs, uw, svw),
            )  # fmt: skip
            t = t1
            _accept(y, y1, Ks, g0, g1)
        else:
            # locate the event on the continuous extension: Illinois on guard j in theta
            hi, j = _locate(
                D,
                S,
                ua,
                ub,
                t,
                t_ref,
                y,
                y1,
                Ks,
                hh,
                rc,
                g0,
                g1,
                j,
                fm,
                reg,
                mL[slot],
                nx,
                u,
                gtry,
                Cd,
                cs,
                sv,
                taug,
                ys,
                yhi,
            )
            # the state there from a real (error-controlled) integration step, not the extension
            hi, j, nfe = _event_state(
                D, S, ua, ub, t, t_ref, y, y1, hh, hi, j, fm, reg, mPT[slot], mL[slot], nx, energy,
                rtol, atol, tol_w, g0, g1, gtry, u, uw, tau, taug, Ks, K2, dy, yt, ya, yr, err, Cd,
                cs, sv, svw, rc, ys, yhi,
            )  # fmt: skip
            nfev += nfe
            if grid and io < t_out.shape[0] and t_out[io] <= t + hi * hh:
                # the grid up to the event on the step's continuous extension (rc from _locate)
                n_rec, io = _record_grid(
                    T, Y, U, FM, RG, n_rec, t_out, io, t, hh, t + hi * hh, rc, ys, fm, reg,
                    (S, ua, ub, t_ref, nx, Cd, cs, uw, svw),
                )  # fmt: skip
            t = t + hi * hh
            y[:] = yhi
        stop = not event and hit_stop and t < t_end
        if stop:
            # input breakpoint or controller sample: new input pieces
            while ib < bps.shape[0] and bps[ib] <= t:
                ib += 1
            t_ref = t
            set_interval(S, t_ref, ua, ub)
            if t_sample <= t:
                eval_inputs(S, ua, ub, t, t_ref, sv)
                cl_sample(Cd, cs, y, sv, t)
                t_sample = t0 + Ts * (np.floor((t - t0) / Ts + 0.5) + 1.0)
        if event or stop:
            # re-decide the modes at t; g0 (guards at t in the new mode) and u, sv are the
            # decision's (_dm_guards)
            n_old = n_ev
            slot, nb, n_ev = _redecide(
                D, S, ua, ub, t, t_ref, y, nx, fm, reg, fm_old, reg_old, u, tol_w, Cd, cs, sv, g0,
                W, mmask, mP, mPT, mL, mst, ev_t, ev_el, ev_from, ev_to, cs_old, n_ev,
            )  # fmt: skip
            if nb == DM_TOO_MANY:
                status = TOO_MANY_CANDIDATES
                break
            h_stab, stab_exact = _stab_lookup(
                D, y, u, fm, reg, mP[slot], nx, hcache, jcache, lcache
            )
            n_incons += nb
            if event:
                # the Zeno check counts the events located on the trajectory (a controller guard
                # once, below, however many of its blocks changed), not the decisions at stops
                for e in range(n_old, n_ev):
                    if ev_el[e] >= nf + nt:
                        continue
                    zeno_pos, hit = _zeno_push(zeno_ring, zeno_pos, t, zeno_window)
                    if hit:
                        status = ZENO
                        status_el = ev_el[e]
                if j >= n_pg:
                    zeno_pos, hit = _zeno_push(zeno_ring, zeno_pos, t, zeno_window)
                    if hit:
                        status = ZENO
                        status_el = nf + nt + N_CL_EVENT_BLOCKS  # the controller as a whole
                elif n_ev == n_old:
                    # a guard crossing that changed no mode: counted too, so that crossings that
                    # repeat at one instant (a stall in ever shorter steps, which no mode change
                    # would end) stop the run here instead of at max_steps
                    zeno_pos, hit = _zeno_push(zeno_ring, zeno_pos, t, zeno_window)
                    if hit:
                        status = ZENO
                        status_el = guard_element(D, j)
                if status != OK:
                    break
            if n_ev >= max_events:
                status = MAX_EVENTS
                break
            if event:
                h_next = hh
            elif hh < h:
                h_next = h
            # a new mode or new input pieces from t on: the first stage of the next step afresh
            full_rhs_call(
                D,
                S,
                ua,
                ub,
                t,
                t_ref,
                y,
                fm,
                reg,
                mPT[slot],
                nx,
                energy,
                uw,
                tau,
                dy,
                Cd,
                cs,
                svw,
            )
            Ks[0, :] = dy
            nfev += 1
            if energy:
                _scan_dissipation(Ks, 0, nxs + 1, t, fs, ist)
        h = h_next
        pending = True

    n_knee = 0
    for e in range(n_ev):
        if nf <= ev_el[e] < nf + nt:
            n_knee += 1
    return (
        T[:n_rec],
        Y[:n_rec],
        U[:n_rec],
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
        n_incons,
        fs[8],
        fs[9],
        ist[9],
        fs[10],
    )
