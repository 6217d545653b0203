"""Events of the hybrid integrator: guards along a step, event location and mode decisions.

* after each accepted step every guard is checked (:func:`_fired`); a guard that turned negative
  is an event, located on the step's continuous extension (Illinois regula falsi, :func:`_locate`)
  to a bracket of ``1e-13 * max(1, |t|)`` s. The state there is not the extension's (4th order,
  its error not under the tolerance) but a real integration step's (:func:`_event_state`): one
  DP5 step from the step start to the located time, error-controlled, the energy states with it;
  then the time is corrected (Newton on the guard, short Heun steps) until the guard has just
  crossed zero on the integrated trajectory;
* a slip speed that dips through zero and back within one step (:func:`_slip_dip`) is caught by
  retaking the step up to the dip;
* at an event all elements at zero relative speed are decided together with the controller's
  block states (:func:`_decide_fast`, :func:`_redecide`: the decision of
  :func:`~drivetrain_ctrl.kernels.decide.decide_modes`), then the guards are re-checked until
  none fires; the mode changes are appended to the event list; :func:`_zeno_push` keeps the
  recent event times for the Zeno check.
"""

from __future__ import annotations

import numpy as np

from ._jit import jit_inline, jit_nonrt
from .controller import (
    CI_OUT,
    N_CL_EVENT_BLOCKS,
    cl_guards,
    cl_guards_cold,
    cl_update,
    eval_u_cold,
    n_cl_states,
)
from .decide import (
    DM_MAX_CANDIDATES,
    DM_TOO_MANY,
    _dm_classify_core,
    _dm_combos_all,
    _mm_find,
    _mm_insert,
    _project_cached,
)
from .dopri import (
    _dense_row,
    _dense_value,
    dense_coeffs,
    dense_eval,
    dp5_step,
    error_norm,
    full_rhs_call,
)
from .physics import SLIP_NEG, SLIP_POS, guards_given_forces, guards_into, n_guards, rel_speed


@jit_inline
def _rel_row(D, f, A, k):
    """:func:`rel_speed` of friction element ``f`` from row ``k`` of ``A`` (a stage derivative:
    the relative acceleration), without making a view (the caller runs without NRT)."""
    i = D.f_idx[f]
    return A[k, i] - D.ratio[i] * A[k, i + 1] if D.f_kind[f] == 0 else A[k, i]


#: sample points of the continuous extension in :func:`_slip_dip` (then golden-section refinement)
DIP_SAMPLES = 32


@jit_inline
def _slip_dip(D, fm, y, y1, Ks, hh):
    """Fraction ``th`` in (0, 1) of an accepted step at which a slipping element's relative speed,
    on the slip side at both ends of the step, reaches a minimum on the other side (a stick or
    reversal episode shorter than the step, which the guards at the step ends cannot see); the
    earliest such minimum over the elements, or 0.0 if there is none.

    Per element the continuous extension of ``s w`` (``s`` the slip direction) is a quartic in
    ``th`` (:func:`dense_coeffs`); a bound from its coefficients rules a dip out in almost every
    step, else it is sampled at ``DIP_SAMPLES`` points and the smallest sample refined by golden
    section."""
    th_best = 0.0
    for f in range(fm.shape[0]):
        m = fm[f]
        if (m != SLIP_POS and m != SLIP_NEG) or D.f_eps[f] > 0.0:
            continue
        sg = 1.0 if m == SLIP_POS else -1.0
        g0 = sg * rel_speed(D, f, y)
        g1 = sg * rel_speed(D, f, y1)
        if not (g0 > 0.0 and g1 > 0.0):
            continue
        c1, c2, c3, c4 = _dense_row(
            g0,
            g1,
            sg * _rel_row(D, f, Ks, 0),
            sg * _rel_row(D, f, Ks, 2),
            sg * _rel_row(D, f, Ks, 3),
            sg * _rel_row(D, f, Ks, 4),
            sg * _rel_row(D, f, Ks, 5),
            sg * _rel_row(D, f, Ks, 6),
            hh,
        )
        # g(th) = g0 + th c1 + th(1-th) c2 + th^2(1-th) c3 + th^2(1-th)^2 c4 >= min(g0, g1)
        # - |c2|/4 - 4|c3|/27 - |c4|/16 on [0, 1]
        if min(g0, g1) > 0.25 * abs(c2) + (4.0 / 27.0) * abs(c3) + 0.0625 * abs(c4):
            continue
        k_min = 0
        g_min = np.inf
        for k in range(1, DIP_SAMPLES):
            g = _dense_value(g0, c1, c2, c3, c4, k / DIP_SAMPLES)
            if g < g_min:
                g_min = g
                k_min = k
        # golden section on the two sample intervals around the smallest sample
        a = (k_min - 1) / DIP_SAMPLES
        b = (k_min + 1) / DIP_SAMPLES
        for _it in range(30):
            p = b - 0.6180339887498949 * (b - a)
            q = a + 0.6180339887498949 * (b - a)
            if _dense_value(g0, c1, c2, c3, c4, p) < _dense_value(g0, c1, c2, c3, c4, q):
                b = q
            else:
                a = p
        th = 0.5 * (a + b)
        g = _dense_value(g0, c1, c2, c3, c4, th)
        if g_min < g:
            th = k_min / DIP_SAMPLES
            g = g_min
        if g < 0.0 and (th_best == 0.0 or th < th_best):
            th_best = th
    return th_best


#: retakes of one step at a dip (:func:`_slip_dip`) before the step is accepted as it is
MAX_DIP_RETAKES = 4


@jit_nonrt
def _guards_step_inl(D, S, ua, ub, t, t_ref, y, fm, reg, Lam, nx, u, g, Cd, cs, sv, tau):
    """Plant and controller guards at (t, y) on the per-step path (no allocation, no NRT).

    A compiled call (not inlined: compiled once for the event location, the event state and a
    step cut at a stop time; none of them is in the step loop)."""
    eval_u_cold(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u)
    guards_into(D, y, u, fm, reg, Lam, g, tau)
    cl_guards_cold(Cd, cs, y, nx, t, sv, g, n_guards(D))


@jit_inline
def _guards_last_stage(D, y1, fm, reg, Lam, nx, uw, g, Cd, cs, svw, tau, t1, u, sv):
    """Guards at the step end (t1, y1) from the step's last stage, which evaluated the inputs
    ``uw``, signals ``svw`` and forces ``tau`` at exactly (t1, y1) (first same as last): the same
    values as :func:`_guards_step_inl` without evaluating them again. Also copies ``uw``, ``svw``
    into ``u``, ``sv`` (the inputs at t1, as :func:`_guards_step_inl` leaves them)."""
    guards_given_forces(D, y1, uw, fm, reg, Lam, g, tau)
    cl_guards(Cd, cs, y1, nx, t1, svw, g, n_guards(D))
    for i in range(u.shape[0]):
        u[i] = uw[i]
    for i in range(sv.shape[0]):
        sv[i] = svw[i]


@jit_inline
def _fired(g0, g1):
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


@jit_nonrt
def _record_changes(fm, fm_old, reg, reg_old, t, ev_t, ev_el, ev_from, ev_to, n_ev):
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


@jit_nonrt
def _dm_classify(D, S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u, fm, reg, tol, cand, caps):
    """The inputs at t into ``u``, then :func:`_dm_classify_core`."""
    eval_u_cold(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u)
    return _dm_classify_core(D, y, u, fm, reg, tol, cand, caps)


@jit_nonrt
def _dm_controller(Cd, cs, S, ua, ub, t, t_ref, y, nx, sv, u, fm):
    """Controller update after the plant's decision, then the inputs at t again."""
    cl_update(Cd, cs, y, nx, t, sv, fm)
    eval_u_cold(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u)


@jit_nonrt
def _dm_guards(D, y, u, fm, reg, Lam, g0, tau, Cd, cs, nx, t, sv):
    """Guards after a decision into ``g0``; True if none is violated."""
    guards_into(D, y, u, fm, reg, Lam, g0, tau)
    cl_guards_cold(Cd, cs, y, nx, t, sv, g0, n_guards(D))
    ok = True
    for q in range(g0.shape[0]):
        if g0[q] < -1e-9 * (1.0 + abs(g0[q])):
            ok = False
    return ok


@jit_nonrt
def _decide_fast(
    D, S, ua, ub, t, t_ref, y, nx, fm, reg, u, tol_w, Cd, cs, sv, g0, W, mmask, mP, mPT, mL, mst
):
    """Decide plant modes (as :func:`decide_modes`) and controller states together until no guard
    fires, with the array cache of mode matrices and work arrays ``W = (cand, caps, idx, trial,
    tau, lamw, prog)``. A compiled call without reference counting (it allocates nothing itself;
    a new mode's matrices come from :func:`_mm_insert`): with it, every call counted its some 70
    array arguments up and down. Returns ``(slot, n_bad)``: the mode matrices of the decided mode
    are in cache slot ``slot``; ``n_bad`` is 1 if no combination was consistent (the least inconsistent was
    taken) or guards still fired after 20 rounds, ``DM_TOO_MANY`` if more than
    ``DM_MAX_CANDIDATES`` elements were candidates (then no decision was made: stop the run)."""
    cand, caps, idx, trial, tauw, lamw, prog = W
    slot = -1
    ok = False
    n_bad = 0
    for _rep in range(20):
        nc = _dm_classify(D, S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u, fm, reg, tol_w, cand, caps)
        r = 0
        if nc > DM_MAX_CANDIDATES:
            return -1, DM_TOO_MANY
        if nc > 0:
            _project_cached(D, y, cand, trial, lamw, mmask, mP, mPT, mL, mst)
            r = _dm_combos_all(
                D, y, u, fm, reg, nc, cand, caps, idx, trial, tauw, prog, mmask, mP, mPT, mL, mst
            )
        # only the last round counts: a first round may be inconsistent before the projection
        n_bad = 1 if r < 0 else 0
        _dm_controller(Cd, cs, S, ua, ub, t, t_ref, y, nx, sv, u, fm)
        slot = _mm_find(fm, mmask, mst)
        if slot < 0:
            slot = _mm_insert(D, fm, mmask, mP, mPT, mL, mst)
        ok = _dm_guards(D, y, u, fm, reg, mL[slot], g0, tauw, Cd, cs, nx, t, sv)
        if ok:
            break
    if not ok:
        n_bad = 1
    return slot, n_bad


@jit_nonrt
def _locate(
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
    Lam,
    nx,
    u,
    gtry,
    Cd,
    cs,
    sv,
    taug,
    ys,
    yhi,
):
    """Locate the event of a step from ``(t, y)`` of length ``hh`` in which guard ``j`` fired:
    Illinois on the guard in theta on the continuous extension (no allocation, no NRT).

    Returns ``(hi, j)``: the fraction of the step at which the first guard has fired (``yhi`` the
    state there on the extension; :func:`_event_state` then integrates it) and that guard (the
    earliest one found)."""
    dense_coeffs(y, y1, Ks, hh, rc)
    lo = 0.0
    hi = 1.0
    glo = g0[j] if g0[j] > 0.0 else 0.0
    ghi = g1[j]
    for i in range(y1.shape[0]):
        yhi[i] = y1[i]
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
        _guards_step_inl(
            D, S, ua, ub, t + s * hh, t_ref, ys, fm, reg, Lam, nx, u, gtry, Cd, cs, sv, taug
        )
        jj = _fired(g0, gtry)
        if jj >= 0:
            if jj != j:
                j = jj
                glo = g0[j] if g0[j] > 0.0 else 0.0
            hi = s
            ghi = gtry[j]
            for i in range(ys.shape[0]):
                yhi[i] = ys[i]
            if side == -1:
                glo *= 0.5
            side = -1
        else:
            lo = s
            glo = gtry[j]
            if side == 1:
                ghi *= 0.5
            side = 1
    return hi, j


#: most DP5 re-integrations for the state at one event (:func:`_event_state`)
MAX_EVENT_STEPS = 8
#: most halvings of a re-integration whose error estimate exceeds the tolerance
MAX_EVENT_SPLITS = 6
#: fraction of the step of the central difference that gives a guard's slope on the extension
SLOPE_DTH = 1e-5


@jit_nonrt
def _reintegrate(
    D, S, ua, ub, t, t_ref, y, h, fm, reg, PT, nx, energy, rtol, atol, uw, tau, Ks, K2, dy, yt,
    ya, yr, err, Cd, cs, svw,
):  # fmt: skip
    """The state at ``t + h`` from ``(t, y)`` into ``yr`` by DP5 steps (:func:`dp5_step`, the
    energy states too; ``Ks[0] = f(t, y)``): one step of length ``h``, or ``2^k`` equal steps if a
    step's error estimate exceeds the tolerance (the norm of the step control of ``_advance``).
    Returns ``(nfev, ok)``; ``ok`` is False if ``2^MAX_EVENT_SPLITS`` steps still miss it.
    A compiled call, not inlined: one copy of the inlined :func:`dp5_step` for both call sites."""
    n = y.shape[0]
    nxs = nx + n_cl_states(Cd)
    nfev = 0
    n_sub = 1
    ok = False
    for _split in range(MAX_EVENT_SPLITS + 1):
        for i in range(n):
            ya[i] = y[i]
            K2[0, i] = Ks[0, i]
        hs = h / n_sub
        ok = True
        for k in range(n_sub):
            dp5_step(
                D, S, ua, ub, t + k * hs, t_ref, ya, hs, fm, reg, PT, nx, energy, uw, tau, K2,
                dy, yt, yr, err, Cd, cs, svw,
            )  # fmt: skip
            nfev += 6
            if not (error_norm(err, ya, yr, nxs, rtol, atol) <= 1.0):
                ok = False
                break
            for i in range(n):
                ya[i] = yr[i]
                K2[0, i] = K2[6, i]  # first same as last: same mode, same input pieces
        if ok:
            break
        n_sub *= 2
    return nfev, ok


@jit_inline
def _guard_slope(D, S, ua, ub, t, t_ref, hh, th, j, rc, ys, fm, reg, Lam, nx, u, gtry, Cd, cs,
                 sv, taug):  # fmt: skip
    """d(guard ``j``)/d(theta) at fraction ``th`` of the step, by a central difference on the
    step's continuous extension ``rc`` (``SLOPE_DTH``); overwrites ``gtry``."""
    dense_eval(rc, th + SLOPE_DTH, ys)
    _guards_step_inl(
        D, S, ua, ub, t + (th + SLOPE_DTH) * hh, t_ref, ys, fm, reg, Lam, nx, u, gtry, Cd, cs, sv,
        taug,
    )  # fmt: skip
    gp = gtry[j]
    dense_eval(rc, th - SLOPE_DTH, ys)
    _guards_step_inl(
        D, S, ua, ub, t + (th - SLOPE_DTH) * hh, t_ref, ys, fm, reg, Lam, nx, u, gtry, Cd, cs, sv,
        taug,
    )  # fmt: skip
    return (gp - gtry[j]) / (2.0 * SLOPE_DTH)


@jit_inline
def _slip_sign(fm, j):
    """``s`` of guard ``j`` if it is the slip guard ``min(s w, capacity)`` of a slipping friction
    element (``s`` = +1 slip+, -1 slip-), else 0."""
    if j >= fm.shape[0]:
        return 0.0
    if fm[j] == SLIP_POS:
        return 1.0
    if fm[j] == SLIP_NEG:
        return -1.0
    return 0.0


@jit_inline
def _slip_overshoot(D, fm, j, y, g, tol_w):
    """True if guard ``j`` is the slip-speed guard of a slipping friction element whose relative
    speed at ``y`` is past zero by more than ``tol_w / 2``: the decision, which takes elements
    with ``|w| <= tol_w`` as candidates for sticking, would not see it at zero."""
    if j >= fm.shape[0] or (fm[j] != SLIP_POS and fm[j] != SLIP_NEG):
        return False
    w = rel_speed(D, j, y)
    sw = w if fm[j] == SLIP_POS else -w
    return sw == g[j] and sw < -0.5 * tol_w


@jit_inline
def _short_step(
    D, S, ua, ub, t0, t_ref, yr, dt, fm, reg, PT, nx, energy, rtol, atol, uw, tau, K2, dy, ya,
    Cd, cs, svw,
):  # fmt: skip
    """Move ``yr`` (the state at ``t0``, ``K2[6] = f(t0, yr)``) by ``dt`` (either sign) with
    Heun's method, if the error estimate (its difference from Euler's step, in the norm of the
    step control) is within the tolerance; then ``K2[6] = f(t0 + dt, yr)`` again. For the tiny
    corrections of an event's fraction (about 1e-10 of a step) this costs 2 evaluations instead
    of a DP5 step's 6. Returns ``(nfev, ok)``; ``yr`` is unchanged if not ``ok``."""
    n = yr.shape[0]
    nxs = nx + n_cl_states(Cd)
    for i in range(nxs):
        ya[i] = yr[i] + dt * K2[6, i]
    full_rhs_call(
        D, S, ua, ub, t0 + dt, t_ref, ya, fm, reg, PT, nx, energy, uw, tau, dy, Cd, cs, svw
    )
    en = 0.0
    for i in range(n):
        v = yr[i] + 0.5 * dt * (K2[6, i] + dy[i])
        if i < nxs:
            a = abs(yr[i])
            b = abs(v)
            r = 0.5 * dt * (dy[i] - K2[6, i]) / (atol + rtol * (a if a > b else b))
            en += r * r
        ya[i] = v
    if not (np.sqrt(en / nxs) <= 1.0):
        return 1, False
    for i in range(n):
        yr[i] = ya[i]
    full_rhs_call(
        D, S, ua, ub, t0 + dt, t_ref, yr, fm, reg, PT, nx, energy, uw, tau, dy, Cd, cs, svw
    )
    for i in range(n):
        K2[6, i] = dy[i]
    return 2, True


@jit_nonrt
def _event_state(
    D, S, ua, ub, t, t_ref, y, y1, hh, hi, j, fm, reg, PT, Lam, nx, energy, rtol, atol, tol_w,
    g0, g1, gtry, u, uw, tau, taug, Ks, K2, dy, yt, ya, yr, err, Cd, cs, sv, svw, rc, ys, yhi,
):  # fmt: skip
    """The state at the event of a step from ``(t, y)`` of length ``hh`` (end ``y1``, guards
    ``g1``) into ``yhi``, from real integration steps instead of the continuous extension.

    :func:`_locate` found the event at fraction ``hi`` on the extension (``yhi`` its state there,
    ``rc`` the extension). The extension is 4th order and has no error estimate: its error, not
    the tolerance, set the energy residual's floor (issue 19). Here the state at ``hi`` is
    re-integrated from the step start (:func:`_reintegrate`: DP5, error-controlled, energy states
    included). The guards there differ from the extension's by the extension's error, so the
    fraction is then corrected by Newton steps on the fired guard (slope on the extension,
    :func:`_guard_slope`; aiming a tenth of the miss past zero, at least the location's bracket)
    with short Heun steps from the re-integrated state (:func:`_short_step`; a full re-integration
    if its error is too large), until a guard has fired at the integrated state (``_fired``)
    and, if it is the slip-speed guard of a slipping element, the relative speed is within
    ``tol_w / 2`` of zero (:func:`_slip_overshoot`), so that the decision sees the element at
    zero as before. For a slip guard near zero speed the Newton steps aim at the slip speed itself
    (a capacity near zero would hide it in ``min(s w, capacity)``). A Newton step that leaves the
    bracket (last fraction not fired, last fired) ends the tries.

    Returns ``(th, j, nfev)``: the event's fraction of the step, the guard that fired there and
    the right-hand-side evaluations spent. If no fraction qualifies within ``MAX_EVENT_STEPS``
    tries, or a re-integration misses the tolerance even in ``2^MAX_EVENT_SPLITS`` pieces (a step
    that met it as a whole), the extension's state is kept (``yhi``, ``hi``, ``j`` unchanged): it
    is at the located crossing, which a state further on would not be."""
    n = y.shape[0]
    nfev, ok = _reintegrate(
        D, S, ua, ub, t, t_ref, y, hi * hh, fm, reg, PT, nx, energy, rtol, atol, uw, tau, Ks, K2,
        dy, yt, ya, yr, err, Cd, cs, svw,
    )  # fmt: skip
    if not ok:
        return hi, j, nfev
    tol_th = 1e-13 * max(1.0, abs(t)) / hh  # the bracket of _locate
    th_lo = 0.0
    th_hi = 1.0
    th = hi
    jg = j  # the guard the Newton steps aim at
    for it in range(MAX_EVENT_STEPS):
        _guards_step_inl(
            D, S, ua, ub, t + th * hh, t_ref, yr, fm, reg, Lam, nx, u, gtry, Cd, cs, sv, taug
        )
        jj = _fired(g0, gtry)
        if jj >= 0:
            if not _slip_overshoot(D, fm, jj, yr, gtry, tol_w):
                for i in range(n):
                    yhi[i] = yr[i]
                return th, jj, nfev
            th_hi = th
            jg = jj
        else:
            th_lo = th
        if it == MAX_EVENT_STEPS - 1:
            break
        gv = gtry[jg]
        sg = _slip_sign(fm, jg)
        if sg != 0.0 and abs(rel_speed(D, jg, yr)) <= tol_w:
            # a slip speed at zero: Newton on it, not on the guard min(s w, capacity), which a
            # capacity near zero hides it behind
            gv = sg * rel_speed(D, jg, yr)
            dense_eval(rc, th + SLOPE_DTH, ys)
            slope = sg * rel_speed(D, jg, ys)
            dense_eval(rc, th - SLOPE_DTH, ys)
            slope = (slope - sg * rel_speed(D, jg, ys)) / (2.0 * SLOPE_DTH)
        else:
            slope = _guard_slope(
                D, S, ua, ub, t, t_ref, hh, th, jg, rc, ys, fm, reg, Lam, nx, u, gtry, Cd, cs, sv,
                taug,
            )  # fmt: skip
        # Newton towards g = -|gv| / 10, just past zero on the integrated trajectory; at least
        # the location's bracket, doubled on every further try (a miss at round-off level)
        dmin = tol_th * (1 << it)
        th_new = np.nan
        if slope < 0.0:
            dth = (-0.1 * abs(gv) - gv) / slope
            if th_lo == th:  # not fired yet: forward
                dth = dth if dth > dmin else dmin
            else:  # fired, past zero by too much: back
                dth = dth if dth < -dmin else -dmin
            th_new = th + dth
        if not (th_lo < th_new < th_hi):
            break  # no usable Newton step: the extension's state
        nf_, ok = _short_step(
            D, S, ua, ub, t + th * hh, t_ref, yr, (th_new - th) * hh, fm, reg, PT, nx, energy,
            rtol, atol, uw, tau, K2, dy, ya, Cd, cs, svw,
        )  # fmt: skip
        nfev += nf_
        if not ok:
            nf_, ok = _reintegrate(
                D, S, ua, ub, t, t_ref, y, th_new * hh, fm, reg, PT, nx, energy, rtol, atol, uw,
                tau, Ks, K2, dy, yt, ya, yr, err, Cd, cs, svw,
            )  # fmt: skip
            nfev += nf_
            if not ok:
                break
        th = th_new
    return hi, j, nfev  # no integrated state qualified: the extension's (yhi), as located


@jit_nonrt
def _redecide(
    D, S, ua, ub, t, t_ref, y, nx, fm, reg, fm_old, reg_old, u, tol_w, Cd, cs, sv, g0, W, mmask,
    mP, mPT, mL, mst, ev_t, ev_el, ev_from, ev_to, cs_old, n_ev,
):  # fmt: skip
    """At an event or a stop: decide the modes (:func:`_decide_fast`; ``mmask, mP, mPT, mL, mst``
    the mode-matrix cache) and append the mode changes to the event list ``ev_t, ev_el, ev_from,
    ev_to`` (``cs_old`` a work array). The controller's block states that the decision changes
    are listed too (element ``nf + nt + k``, see ``N_CL_EVENT_BLOCKS``). Returns ``(slot, n_bad,
    n_ev)``. A compiled call without reference counting: inlined into the reference-counted
    :func:`~drivetrain_ctrl.kernels.integrator.simulate_kernel`, its some 70 array arguments
    were counted up and down at every event."""
    for f in range(fm.shape[0]):
        fm_old[f] = fm[f]
    for k in range(reg.shape[0]):
        reg_old[k] = reg[k]
    for k in range(N_CL_EVENT_BLOCKS):
        cs_old[k] = cs[k]
    slot, nb = _decide_fast(
        D, S, ua, ub, t, t_ref, y, nx, fm, reg, u, tol_w, Cd, cs, sv, g0, W, mmask, mP, mPT, mL, mst
    )
    if nb == DM_TOO_MANY:
        return slot, nb, n_ev
    n_ev = _record_changes(fm, fm_old, reg, reg_old, t, ev_t, ev_el, ev_from, ev_to, n_ev)
    if Cd.ci[CI_OUT] >= 0:
        base = fm.shape[0] + reg.shape[0]
        for k in range(N_CL_EVENT_BLOCKS):
            if cs[k] != cs_old[k] and n_ev < ev_t.shape[0]:
                ev_t[n_ev] = t
                ev_el[n_ev] = base + k
                ev_from[n_ev] = int(cs_old[k])
                ev_to[n_ev] = int(cs[k])
                n_ev += 1
    return slot, nb, n_ev


@jit_inline
def _zeno_push(ring, pos, t, window):
    """Record an event at ``t`` in the ring of the last ``len(ring)`` event times (next slot
    ``pos``); returns ``(next pos, True if all of them lie within window [s] of t)``."""
    ring[pos] = t
    pos = (pos + 1) % ring.shape[0]
    return pos, t - ring[pos] < window
