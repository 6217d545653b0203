"""Mode decision at an event: which friction elements at zero relative speed stick or slip.

:func:`decide_modes` (the Python API's ``Model.decide``) and the simulator (through
:func:`_dm_classify_core`, :func:`_project_cached` and :func:`_dm_combos_all`, with caches kept
over a run) make the same decision with the same functions: classify the elements, project the
speeds onto the candidates' constraints, then try the stuck / slip+ / slip- combinations, most
elements stuck first, for consistency.

A combination is consistent if its stuck torques are within the static capacities and its slip
directions agree with the accelerations. The stuck torques are those of the guards
(:func:`~drivetrain_ctrl.kernels.physics.stuck_torque`): in a statically indeterminate stuck set
(a body held by two stuck paths) they are not unique, and the distribution with the largest
smallest capacity margin is taken, so the decision keeps such a set stuck exactly when some
distribution within the capacities exists, and its guards fire when none does.
"""

from __future__ import annotations

import numpy as np

from ._jit import F64, I64, jit, jit_inline, jit_nonrt
from .physics import (
    OPEN,
    SLIP_NEG,
    SLIP_POS,
    STUCK,
    ChainData,
    _project_lam,
    capacity,
    forces_into,
    lam_shape,
    mode_matrices,
    rel_speed,
    stuck_torque,
    update_regions,
)


@jit
def decide_modes(D: ChainData, x: F64, u: F64, fm: I64, reg: I64, tol: float) -> int:
    """Choose the consistent mode at an event; updates ``fm``, ``reg`` and projects ``x``.

    Elements with ``|w| <= tol`` and positive capacity are decided together: of all
    stuck / slip+ / slip- combinations the consistent one with the most elements stuck is taken
    (stuck torques within static capacity, slip directions agreeing with the accelerations).
    Returns the number of candidates (or ``-1`` if no combination was consistent and the least
    inconsistent one was taken; a round-off tie, total violation at most ``DM_TIE_VIOLATION``,
    counts as consistent; ``DM_TOO_MANY`` if more than ``DM_MAX_CANDIDATES`` elements are
    candidates, ``fm`` then unchanged). The simulator makes the same decision through the same functions
    (:func:`_dm_classify_core`, :func:`_project_cached`, :func:`_dm_combos`) with caches kept over
    the run.
    """
    mmask, mP, mPT, mL, mst = _mm_alloc(D)
    cand, caps, idx, trial, tau, lamw, prog = _dm_work(D)
    fm0 = fm.copy()
    nc = _dm_classify_core(D, x, u, fm, reg, tol, cand, caps)
    if nc == 0:
        return 0
    if nc > DM_MAX_CANDIDATES:
        fm[:] = fm0
        return DM_TOO_MANY
    _project_cached(D, x, cand, trial, lamw, mmask, mP, mPT, mL, mst)
    return _dm_combos_all(
        D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mPT, mL, mst
    )


# --- event decisions without reference counting -------------------------------------------------
# The mode matrices P, P^T, Lam depend only on which friction elements are stuck: they are cached
# in plain arrays (slot s: stuck set ``mmask[s]``; ``mst`` = [slots used, next slot to replace])
# that functions compiled without NRT can read. Only a miss (a stuck set seen for the first time)
# and the projection go through the ordinary (reference-counted, allocating) functions.

#: return code of :func:`_dm_combos`: the mode matrices of ``trial`` are not in the cache
DM_MISS = -2


#: largest total violation of the least inconsistent combination that :func:`_dm_combos` still
#: reports as consistent (round-off ties; the combination taken is the same either way)
DM_TIE_VIOLATION = 1e-9


#: :func:`decide_modes` / :func:`_decide_fast`: more candidates than ``DM_MAX_CANDIDATES``
DM_TOO_MANY = -3


#: most elements decided together at one event: the decision tries up to 3^n combinations
#: (3^12 = 531441, some 0.1-1 s); beyond it a run stops with ``TOO_MANY_CANDIDATES``, not a hang
DM_MAX_CANDIDATES = 12


@jit_nonrt
def _mm_find(fm, mmask, mst):
    """Cache slot of the mode matrices of friction modes ``fm``, or -1."""
    nf = fm.shape[0]
    for s in range(mst[0]):
        same = True
        for f in range(nf):
            if (fm[f] == STUCK) != (mmask[s, f] != 0):
                same = False
                break
        if same:
            return s
    return -1


@jit
def _mm_insert(D, fm, mmask, mP, mPT, mL, mst):
    """Compute the mode matrices of ``fm`` (:func:`mode_matrices`) into a cache slot (the next
    free one, else round robin); returns the slot."""
    K = mmask.shape[0]
    if mst[0] < K:
        s = mst[0]
        mst[0] += 1
    else:
        s = mst[1]
        mst[1] = (s + 1) % K
    P, Lam = mode_matrices(D, fm)
    for f in range(fm.shape[0]):
        mmask[s, f] = 1 if fm[f] == STUCK else 0
    n = P.shape[0]
    for i in range(n):
        for k in range(n):
            mP[s, i, k] = P[i, k]
            mPT[s, k, i] = P[i, k]
    for f in range(Lam.shape[0]):
        for k in range(Lam.shape[1]):
            mL[s, f, k] = Lam[f, k]
    return s


@jit
def _mm_alloc(D):
    """Empty mode-matrix cache ``(mmask, mP, mPT, mL, mst)`` (see :func:`_mm_find`): every stuck
    set fits for up to 10 friction elements. ``mL[s]`` is the extended stuck-torque matrix
    (:func:`~drivetrain_ctrl.kernels.physics.lam_shape`) of
    :func:`~drivetrain_ctrl.kernels.physics.mode_matrices`: the least-norm map, the basis of the
    self-balancing stuck torques of a statically indeterminate stuck set, its redundancy groups
    and the work space of their LP (so the guards allocate nothing)."""
    n = D.M.shape[0]
    nf = D.f_kind.shape[0]
    n_slots = 1 << min(nf, 10)
    nr, nc = lam_shape(n, nf)
    return (
        np.zeros((n_slots, nf), dtype=np.int64),
        np.empty((n_slots, n, n)),
        np.empty((n_slots, n, n)),
        np.empty((n_slots, nr, nc)),
        np.zeros(2, dtype=np.int64),
    )


@jit
def _dm_work(D):
    """Work arrays ``(cand, caps, idx, trial, tau, lamw, prog)`` of a mode decision (``prog``:
    where :func:`_dm_combos` resumes, see there)."""
    nf = D.f_kind.shape[0]
    return (
        np.zeros(nf, dtype=np.int64),
        np.zeros(nf),
        np.zeros(nf, dtype=np.int64),
        np.zeros(nf, dtype=np.int64),
        np.zeros(D.M.shape[0]),
        np.zeros(nf),
        np.zeros(4),
    )


@jit_inline
def _project_cached(D, x, cand, trial, lamw, mmask, mP, mPT, mL, mst):
    """:func:`project` onto ``w_f = 0`` for the candidates ``cand``, with the stuck-torque matrix
    of the stuck set ``cand`` from the mode-matrix cache (computed into it on a miss); ``trial``
    and ``lamw`` are work arrays."""
    for f in range(cand.shape[0]):
        trial[f] = STUCK if cand[f] else SLIP_POS
    s = _mm_find(trial, mmask, mst)
    if s < 0:
        s = _mm_insert(D, trial, mmask, mP, mPT, mL, mst)
    _project_lam(D, x, cand, mL[s], lamw)


@jit_nonrt
def _dm_classify_core(D, y, u, fm, reg, tol, cand, caps):
    """First part of a mode decision: regions, capacities, the modes of the elements that are
    not candidates (``|w| > tol``, no capacity, smoothed); returns the number of candidates
    (``cand``), without projecting."""
    update_regions(D, y, u, reg)
    nc = 0
    for f in range(fm.shape[0]):
        cand[f] = 0
        cap = capacity(D, f, u, reg)
        caps[f] = cap
        w = rel_speed(D, f, y)
        if D.f_eps[f] > 0.0:
            fm[f] = SLIP_POS  # smoothed: one smooth mode, never stuck
        elif cap <= 0.0:
            fm[f] = OPEN
        elif abs(w) > tol:
            fm[f] = SLIP_POS if w > 0 else SLIP_NEG
        else:
            cand[f] = 1
            nc += 1
    return nc


@jit_inline
def _consistency_nr(D, u, fm, reg, cand, caps, P, Lam, tau):
    """Total violation (0 = consistent) of trial mode ``fm`` for the candidate elements: stuck
    torques beyond static capacity, slip directions against the accelerations; from the forces
    of the trial mode in ``tau`` (no allocation). The stuck torques are
    :func:`~drivetrain_ctrl.kernels.physics.stuck_torque`'s, as in the guards: in a statically
    indeterminate stuck set the distribution with the largest smallest capacity margin, so a
    set that can hold within the capacities is consistent."""
    n = tau.shape[0]
    viol = 0.0
    for f in range(fm.shape[0]):
        if not cand[f]:
            continue
        if fm[f] == STUCK:
            lim = D.f_static[f] * caps[f]
            lam = stuck_torque(D, u, fm, reg, Lam, tau, f)[0]
            ex = abs(lam) - lim
            if ex > 0.0:
                viol += ex / (lim + 1e-300)
        else:
            i = D.f_idx[f]
            ai = 0.0
            for k in range(n):
                ai += P[i, k] * tau[k]
            if D.f_kind[f] == 0:
                ai1 = 0.0
                for k in range(n):
                    ai1 += P[i + 1, k] * tau[k]
                dw = ai - D.ratio[i] * ai1
            else:
                dw = ai
            s = 1.0 if fm[f] == SLIP_POS else -1.0
            if dw * s <= 0.0:
                viol += 1.0 + abs(dw)
    return viol


@jit_nonrt
def _dm_combos(D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mL, mst):
    """Second part of a mode decision (after the projection): the candidates' modes. Returns as
    :func:`decide_modes` does, or ``DM_MISS`` before changing ``fm`` if a trial's mode matrices are not
    cached (``trial`` holds that mode; call again once they are: the search resumes at that trial).

    ``prog = [n_stuck, code, best_code, best_violation]``: where the search stands; set
    ``prog[0] = -1`` to start a new decision. (Resuming, not restarting, keeps a decision linear
    in the number of combinations, and finite when the combinations' stuck sets outnumber the
    cache slots: a restart then needed a slot the cache had just evicted, forever.)"""
    nf = fm.shape[0]
    update_regions(D, x, u, reg)
    j = 0
    for f in range(nf):
        if cand[f]:
            idx[j] = f
            j += 1
    ncomb = 1
    for _q in range(nc):
        ncomb *= 3
    if prog[0] < 0.0:
        prog[0] = nc
        prog[1] = 0.0
        prog[2] = 0.0
        prog[3] = np.inf
    n0 = int(prog[0])
    code0 = int(prog[1])
    best_code = int(prog[2])
    best_viol = prog[3]
    for f in range(nf):
        trial[f] = fm[f]
    for n_stuck in range(n0, -1, -1):
        for code in range(code0 if n_stuck == n0 else 0, ncomb):
            c = code
            ns = 0
            for jj in range(nc):
                d = c % 3
                c //= 3
                trial[idx[jj]] = STUCK if d == 0 else (SLIP_POS if d == 1 else SLIP_NEG)
                if d == 0:
                    ns += 1
            if ns != n_stuck:
                continue
            s = _mm_find(trial, mmask, mst)
            if s < 0:
                prog[0] = n_stuck
                prog[1] = code
                prog[2] = best_code
                prog[3] = best_viol
                return DM_MISS
            forces_into(D, x, u, trial, reg, tau, tau, -1)
            v = _consistency_nr(D, u, trial, reg, cand, caps, mP[s], mL[s], tau)
            if v == 0.0:
                for jj in range(nc):
                    fm[idx[jj]] = trial[idx[jj]]
                return nc
            if v < best_viol:
                best_viol = v
                best_code = code
    c = best_code
    for jj in range(nc):
        d = c % 3
        c //= 3
        fm[idx[jj]] = STUCK if d == 0 else (SLIP_POS if d == 1 else SLIP_NEG)
    # a violation this small is a stuck torque beyond its static capacity by round-off only (a
    # slip direction against the acceleration counts at least 1): a tie at a break-away with
    # static = kinetic capacity, where stuck is taken and the guard fires right after; not counted
    # as inconsistent
    return nc if best_viol <= DM_TIE_VIOLATION else -1


@jit_inline
def _dm_combos_all(
    D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mPT, mL, mst
):
    """:func:`_dm_combos` from the start, filling the mode-matrix cache on a miss and resuming."""
    prog[0] = -1.0
    r = _dm_combos(D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mL, mst)
    while r == DM_MISS:
        _mm_insert(D, trial, mmask, mP, mPT, mL, mst)
        r = _dm_combos(D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mL, mst)
    return r
