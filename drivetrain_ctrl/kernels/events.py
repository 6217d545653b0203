"""Events of the hybrid integrator: guards along a step, event location and mode decisions.

* after each accepted step every guard is checked (:func:`_fired`); a guard that turned negative
  is an event, located on the step's continuous extension (Illinois regula falsi, :func:`_locate`)
  to a bracket of ``1e-13 * max(1, |t|)`` s; the state just past the event is taken;
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

from ._jit import jit, jit_inline, jit_nonrt
from .controller import CI_OUT, N_CL_EVENT_BLOCKS, cl_guards, cl_guards_cold, cl_update, eval_u_cold
from .decide import (
    DM_MAX_CANDIDATES,
    DM_TOO_MANY,
    _dm_classify_core,
    _dm_combos_all,
    _mm_find,
    _mm_insert,
    _project_cached,
)
from .dopri import _dense_row, _dense_value, dense_coeffs, dense_eval
from .physics import SLIP_NEG, SLIP_POS, guards_given_forces, guards_into, n_guards, rel_speed
from .stability import _stab_lookup


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

    A compiled call (not inlined: compiled once for the event location and the step loop, where
    it is needed only for a step cut at a stop time)."""
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


@jit
def _decide_fast(
    D, S, ua, ub, t, t_ref, y, nx, fm, reg, u, tol_w, Cd, cs, sv, g0, W, mmask, mP, mPT, mL, mst
):
    """Decide plant modes (as :func:`decide_modes`) and controller states together until no guard
    fires, with the array cache of mode matrices and work arrays ``W = (cand, caps, idx, trial,
    tau, lamw, prog)``. Returns ``(slot, n_bad)``: the mode matrices of the decided mode are in
    cache slot ``slot``; ``n_bad`` is 1 if no combination was consistent (the least inconsistent was
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
    state there) and that guard (the earliest one found)."""
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


@jit_inline
def _redecide(
    D, S, ua, ub, t, t_ref, y, nx, fm, reg, fm_old, reg_old, u, tol_w, Cd, cs, sv, g0, W, MM,
    SC, EV, n_ev,
):  # fmt: skip
    """At an event or a stop: decide the modes (:func:`_decide_fast`), look up the mode's
    stability bound and append the mode changes to the event list. ``MM = (mmask, mP, mPT, mL,
    mst)`` mode-matrix cache, ``SC = (hcache, jcache, lcache)`` stability-bound caches, ``EV =
    (ev_t, ev_el, ev_from, ev_to, cs_old)`` event list and work array (tuples: CPython passes a
    call of more than 30 arguments as ``*args``, which numba cannot inline). The controller's
    block states that the decision changes are listed too (element ``nf + nt + k``, see
    ``N_CL_EVENT_BLOCKS``). Returns ``(slot, n_bad, h_stab, stab_exact, n_ev)``."""
    mmask, mP, mPT, mL, mst = MM
    hcache, jcache, lcache = SC
    ev_t, ev_el, ev_from, ev_to, cs_old = EV
    fm_old[:] = fm
    reg_old[:] = reg
    for k in range(N_CL_EVENT_BLOCKS):
        cs_old[k] = cs[k]
    slot, nb = _decide_fast(
        D, S, ua, ub, t, t_ref, y, nx, fm, reg, u, tol_w, Cd, cs, sv, g0, W, mmask, mP, mPT, mL, mst
    )
    if nb == DM_TOO_MANY:
        return slot, nb, 0.0, True, n_ev
    h_stab, stab_exact = _stab_lookup(D, y, u, fm, reg, mP[slot], nx, hcache, jcache, lcache)
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
    return slot, nb, h_stab, stab_exact, n_ev


@jit_inline
def _zeno_push(ring, pos, t, window):
    """Record an event at ``t`` in the ring of the last ``len(ring)`` event times (next slot
    ``pos``); returns ``(next pos, True if all of them lie within window [s] of t)``."""
    ring[pos] = t
    pos = (pos + 1) % ring.shape[0]
    return pos, t - ring[pos] < window
