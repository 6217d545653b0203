"""Compiled (numba) kernels of a chain model: forces, modes, guards, energy, Jacobian.

Everything here works on :class:`ChainData` (arrays made by :mod:`drivetrain_ctrl.model`), so
the same code serves the Python API (``Model.rhs`` etc.), the linearisation and the simulator's
hot loop. Conventions (see :mod:`drivetrain_ctrl.chain`):

* state ``x = [omega (n), q (springs), position (tracked bodies), lag states]``;
* friction element mode ``fm[f]``: ``STUCK = 0``, ``SLIP_POS = 1``, ``SLIP_NEG = 2``,
  ``OPEN = 3``; table region ``reg[k]``: index of the affine piece in use;
* stuck elements are constraints ``G omega = 0``; with ``M a = tau - G^T lam`` the accelerations
  are ``a = P tau`` and the stuck torques ``lam = Lam tau`` with ``P``, ``Lam`` from
  :func:`mode_matrices` (the generalisation of the paper's transformation T, eq. (3)-(4));
* guards ``g >= 0`` in the current mode; a sign change to negative is an event.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, types
from numba.typed import Dict
from numpy.typing import NDArray

#: compiled, cached; numpy error model (no Python exceptions on division: ~2x faster)
jit = njit(cache=True, error_model="numpy")
#: small helpers inlined into their callers (avoids copying ChainData on every call)
jit_inline = njit(cache=True, error_model="numpy", inline="always")
#: the per-step path, compiled without numba's reference counting (NRT): such a function must not
#: allocate; it only reads and writes the arrays it is given. Reference counting of the ~60 array
#: arguments cost two thirds of the step time (perf: atomic inc/dec in NRT_incref/NRT_decref).
jit_nonrt = njit(cache=True, error_model="numpy", _nrt=False)  # type: ignore[call-overload]

STUCK, SLIP_POS, SLIP_NEG, OPEN = 0, 1, 2, 3
ARG_TWIST, ARG_SLIP, ARG_SPEED, ARG_INPUT = 0, 1, 2, 3

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


class ChainData(NamedTuple):
    """Array form of a :class:`~drivetrain_ctrl.chain.Chain` (SI units, upstream frames)."""

    M: F64  # (n,) inertia [kg m^2] / mass [kg]
    visc: F64  # (n,)
    quad: F64  # (n,)
    load: F64  # (n,)
    b_uidx: I64  # (n,) input index of the torque input, -1 none
    b_ugain: F64  # (n,)
    b_pos: I64  # (n,) state index of the position, -1 none
    ratio: F64  # (m,)
    damp: F64  # (m,)
    c_table: I64  # (m,) spring table index, -1 none
    c_q: I64  # (m,) twist state index, -1 none
    f_kind: I64  # (nf,) 0 coupling, 1 ground
    f_idx: I64  # (nf,) coupling or body index
    f_scale: F64
    f_uidx: I64
    f_table: I64
    f_static: F64
    f_mu: I64
    f_eps: F64  # (nf,) 0: exact Coulomb law; > 0: tanh(w / eps) smoothing (comparison only)
    t_nb: I64  # (nt,) number of bounds
    t_b: F64  # (nt, maxb) bounds
    t_s: F64  # (nt, maxb+1) slopes
    t_o: F64  # (nt, maxb+1) offsets
    t_e: F64  # (nt, maxb+1) energy constants (springs)
    t_kind: I64
    t_idx: I64
    l_body: I64  # (nl,)
    l_uidx: I64
    l_tau: F64
    l_gain: F64
    l_table: I64
    l_x: I64  # state index of the lag state
    nx: int


# Helpers take the arrays they need, not ChainData: passing the 33-array tuple into a helper costs
# about 0.6 us per call in reference counting (measured during development with perf and
# micro-benchmarks; the end-to-end effect is in benchmarks/bench_simulate.py).
@jit_inline
def _rel(f_kind, f_idx, ratio, f, x):  # type: ignore[no-untyped-def]
    i = f_idx[f]
    r = x[i]
    if f_kind[f] == 0:
        r = x[i] - ratio[i] * x[i + 1]
    return r


@jit_inline
def _cap(f_scale, f_uidx, f_table, t_s, t_o, f, u, reg):  # type: ignore[no-untyped-def]
    ui = f_uidx[f]
    base = 1.0
    if ui >= 0:
        kt = f_table[f]
        if kt < 0:
            base = u[ui]
        else:
            r = reg[kt]
            base = t_s[kt, r] * u[ui] + t_o[kt, r]
    return f_scale[f] * base


@jit_inline
def _mu(f_mu, t_s, t_o, f, aw, reg):  # type: ignore[no-untyped-def]
    k = f_mu[f]
    r = 1.0
    if k >= 0:
        rr = reg[k]
        r = t_s[k, rr] * aw + t_o[k, rr]
    return r


@jit_inline
def rel_speed(D: ChainData, f: int, x: F64) -> float:
    """Relative speed of friction element ``f`` [rad/s or m/s] (upstream frame)."""
    return _rel(D.f_kind, D.f_idx, D.ratio, f, x)


@jit_inline
def table_arg(D: ChainData, k: int, x: F64, u: F64) -> float:
    """Argument of table ``k`` at state ``x`` and inputs ``u``."""
    kind = D.t_kind[k]
    idx = D.t_idx[k]
    if kind == ARG_TWIST:
        return x[D.c_q[idx]]
    if kind == ARG_SLIP:
        return abs(rel_speed(D, idx, x))
    if kind == ARG_SPEED:
        return x[idx]
    return u[idx]


@jit_inline
def table_region(D: ChainData, k: int, a: float) -> int:
    """Index of the affine piece of table ``k`` that contains ``a``."""
    r = 0
    nb = D.t_nb[k]
    while r < nb and a > D.t_b[k, r]:
        r += 1
    return r


@jit_inline
def table_value(D: ChainData, k: int, r: int, a: float) -> float:
    return D.t_s[k, r] * a + D.t_o[k, r]


@jit_inline
def update_regions(D: ChainData, x: F64, u: F64, reg: I64) -> None:
    """Set every table's region from the current arguments (used at events)."""
    for k in range(D.t_nb.shape[0]):
        reg[k] = table_region(D, k, table_arg(D, k, x, u))


@jit_inline
def capacity(D: ChainData, f: int, u: F64, reg: I64) -> float:
    """Kinetic capacity of friction element ``f`` at zero slip [N m or N]."""
    return _cap(D.f_scale, D.f_uidx, D.f_table, D.t_s, D.t_o, f, u, reg)


@jit_inline
def mu_ratio(D: ChainData, f: int, x: F64, reg: I64) -> float:
    """mu(|w|)/mu(0) of friction element ``f``."""
    return _mu(D.f_mu, D.t_s, D.t_o, f, abs(_rel(D.f_kind, D.f_idx, D.ratio, f, x)), reg)


@jit_inline
def forces_into(
    D: ChainData, x: F64, u: F64, fm: I64, reg: I64, tau: F64, ff: F64, ff_off: int
) -> float:
    """Generalised torques on the bodies [N m or N] into ``tau``, without stuck torques.

    If ``ff_off >= 0`` also the dissipated powers into ``ff[ff_off:]`` (layout of
    :func:`powers`: bodies, couplings' dampers, friction elements: the kinetic torque times
    ``s w``, 0 unless slipping) and returns the supplied power; else returns 0.
    (Computed here, where the relative speeds are at hand: see :func:`rhs_into`.)

    Hot path: written without helper calls (each call costs reference counting of its array
    arguments, which made this function 10x slower when it was measured in development).
    """
    n = D.M.shape[0]
    t_s = D.t_s
    t_o = D.t_o
    ratio = D.ratio
    pw = ff_off >= 0
    p_in = 0.0
    for i in range(n):
        w = x[i]
        t = -D.visc[i] * w - D.quad[i] * w * abs(w) + D.load[i]
        if D.b_uidx[i] >= 0:
            t += D.b_ugain[i] * u[D.b_uidx[i]]
            if pw:
                p_in += D.b_ugain[i] * u[D.b_uidx[i]] * w
        tau[i] = t
        if pw:
            ff[ff_off + i] = D.visc[i] * w * w + D.quad[i] * w * w * abs(w)
    for j in range(D.l_body.shape[0]):
        b = D.l_body[j]
        kt = D.l_table[j]
        g = D.l_gain[j]
        if kt >= 0:
            r = reg[kt]
            g *= t_s[kt, r] * x[b] + t_o[kt, r]
        tau[b] += g * x[D.l_x[j]]
        if pw:
            p_in += g * x[D.l_x[j]] * x[b]
    for c in range(ratio.shape[0]):
        w = x[c] - ratio[c] * x[c + 1]
        T = D.damp[c] * w
        if pw:
            ff[ff_off + n + c] = D.damp[c] * w * w
        kt = D.c_table[c]
        if kt >= 0:
            r = reg[kt]
            T += t_s[kt, r] * x[D.c_q[c]] + t_o[kt, r]
        tau[c] -= T
        tau[c + 1] += ratio[c] * T
    for f in range(D.f_kind.shape[0]):
        m = fm[f]
        if pw:
            ff[ff_off + n + ratio.shape[0] + f] = 0.0
        if m == SLIP_POS or m == SLIP_NEG:
            i = D.f_idx[f]
            coupled = D.f_kind[f] == 0
            w = x[i] - ratio[i] * x[i + 1] if coupled else x[i]
            ui = D.f_uidx[f]
            F = D.f_scale[f]
            if ui >= 0:
                kt = D.f_table[f]
                if kt < 0:
                    F *= u[ui]
                else:
                    r = reg[kt]
                    F *= t_s[kt, r] * u[ui] + t_o[kt, r]
            kmu = D.f_mu[f]
            if kmu >= 0:
                r = reg[kmu]
                F *= t_s[kmu, r] * abs(w) + t_o[kmu, r]
            if D.f_eps[f] > 0.0:
                F *= np.tanh(w / D.f_eps[f])
            elif m == SLIP_NEG:
                F = -F
            if pw:
                # kinetic torque times s w, not |w|: the smooth extension of the mode that a
                # stage may sample just past w = 0
                ff[ff_off + n + ratio.shape[0] + f] = F * w
            tau[i] -= F
            if coupled:
                tau[i + 1] += ratio[i] * F
    return p_in


@jit
def forces(D: ChainData, x: F64, u: F64, fm: I64, reg: I64) -> F64:
    """Generalised torques on the bodies [N m or N], without the stuck (constraint) torques."""
    tau = np.empty(D.M.shape[0])
    forces_into(D, x, u, fm, reg, tau, tau, -1)
    return tau


@jit_inline
def rhs_into(
    D: ChainData,
    x: F64,
    u: F64,
    fm: I64,
    reg: I64,
    PT: F64,
    xdot: F64,
    tau: F64,
    pd: F64,
    pd_off: int,
    energy: bool,
) -> float:
    """Allocation-free state derivative (the simulator's hot path).

    ``PT``: the transpose of ``P`` (:func:`mode_matrices`), C-contiguous: the accelerations
    ``P tau`` are summed column by column (independent, vectorisable updates instead of one
    latency-bound dot product per row; each sum in the same order as a row-wise dot product).
    Writes ``xdot``; with ``energy`` also the dissipated powers into ``pd[pd_off:]`` (layout of
    :func:`powers`, stuck elements 0 since their relative speed is held at zero) and returns the
    supplied power.
    """
    n = D.M.shape[0]
    m = D.ratio.shape[0]
    p_in = forces_into(D, x, u, fm, reg, tau, pd, pd_off if energy else -1)
    for i in range(n):
        xdot[i] = 0.0
    for k in range(n):
        tk = tau[k]
        for i in range(n):
            xdot[i] += PT[k, i] * tk
    for i in range(n):
        if D.b_pos[i] >= 0:
            xdot[D.b_pos[i]] = x[i]
    for c in range(m):
        if D.c_q[c] >= 0:
            xdot[D.c_q[c]] = x[c] - D.ratio[c] * x[c + 1]
    for j in range(D.l_body.shape[0]):
        xdot[D.l_x[j]] = (u[D.l_uidx[j]] - x[D.l_x[j]]) / D.l_tau[j]
    return p_in


@jit
def constraint_rows(D: ChainData, fm: I64, which: I64) -> F64:
    """Rows ``G`` (one per element with ``which[f]`` true) with ``G omega`` = relative speeds."""
    n = D.M.shape[0]
    k = 0
    for f in range(fm.shape[0]):
        if which[f]:
            k += 1
    G = np.zeros((k, n))
    r = 0
    for f in range(fm.shape[0]):
        if which[f]:
            i = D.f_idx[f]
            if D.f_kind[f] == 0:
                G[r, i] = 1.0
                G[r, i + 1] = -D.ratio[i]
            else:
                G[r, i] = 1.0
            r += 1
    return G


@jit
def _solve_small(S: F64, R: F64) -> F64:
    """Solve ``S X = R`` for a small symmetric positive semi-definite ``S``.

    Gaussian elimination with partial pivoting; if ``S`` is singular (redundant constraints, e.g.
    two ground frictions on rigidly joined bodies) the least-norm pseudo-inverse solution.
    """
    k = S.shape[0]
    A = S.copy()
    X = R.copy()
    scale = 0.0
    for i in range(k):
        scale = max(scale, abs(A[i, i]))
    for c in range(k):
        p = c
        for r in range(c + 1, k):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if abs(A[p, c]) <= 1e-12 * scale:
            return np.linalg.pinv(S) @ R
        if p != c:
            for j in range(k):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            for j in range(X.shape[1]):
                X[c, j], X[p, j] = X[p, j], X[c, j]
        for r in range(c + 1, k):
            fct = A[r, c] / A[c, c]
            if fct != 0.0:
                for j in range(c, k):
                    A[r, j] -= fct * A[c, j]
                for j in range(X.shape[1]):
                    X[r, j] -= fct * X[c, j]
    for c in range(k - 1, -1, -1):
        for j in range(X.shape[1]):
            acc = X[c, j]
            for q in range(c + 1, k):
                acc -= A[c, q] * X[q, j]
            X[c, j] = acc / A[c, c]
    return X


@jit
def mode_matrices(D: ChainData, fm: I64) -> tuple[F64, F64]:
    """``P`` (n, n) and ``Lam`` (nf, n): accelerations ``P tau``, stuck torques ``Lam tau``."""
    n = D.M.shape[0]
    nf = fm.shape[0]
    which = np.zeros(nf, dtype=np.int64)
    for f in range(nf):
        if fm[f] == STUCK:
            which[f] = 1
    Minv = np.diag(1.0 / D.M)
    Lam = np.zeros((nf, n))
    G = constraint_rows(D, fm, which)
    if G.shape[0] == 0:
        return Minv, Lam
    GM = G @ Minv
    L = _solve_small(GM @ G.T, GM)
    P = Minv - GM.T @ L
    r = 0
    for f in range(nf):
        if which[f]:
            Lam[f, :] = L[r, :]
            r += 1
    return P, Lam


@jit_nonrt
def _project_lam(D, x, which, Lam, lamw):  # type: ignore[no-untyped-def]
    """Momentum-preserving projection of the speeds onto ``w_f = 0`` for ``which[f]``, from the
    stuck-torque matrix ``Lam`` of the mode in which exactly those elements are stuck
    (:func:`mode_matrices`): with ``G`` the constraint rows and ``S = G M^-1 G^T``,
    ``x -= M^-1 G^T S^-1 G x`` and ``S^-1 G x = Lam M x`` (``Lam = S^-1 G M^-1``). No
    allocation; ``lamw`` (nf,) is a work array."""
    n = D.M.shape[0]
    nf = which.shape[0]
    for f in range(nf):
        if which[f]:
            acc = 0.0
            for k in range(n):
                acc += Lam[f, k] * (D.M[k] * x[k])
            lamw[f] = acc
    for f in range(nf):
        if which[f]:
            i = D.f_idx[f]
            x[i] -= lamw[f] / D.M[i]
            if D.f_kind[f] == 0:
                x[i + 1] += D.ratio[i] * lamw[f] / D.M[i + 1]
    # exact zeros on the constrained relative speeds (the correction leaves ~1e-16 relative):
    # couplings from downstream up, so that a chain of stuck couplings is exact too; then each
    # grounded body and the bodies stuck to it through couplings are set to 0
    m = D.ratio.shape[0]
    for c in range(m - 1, -1, -1):
        if _coupling_stuck(D, which, c):
            x[c] = D.ratio[c] * x[c + 1]
    for f in range(nf):
        if which[f] and D.f_kind[f] == 1:
            i = D.f_idx[f]
            x[i] = 0.0
            c = i - 1
            while c >= 0 and _coupling_stuck(D, which, c):
                x[c] = 0.0
                c -= 1
            c = i
            while c < m and _coupling_stuck(D, which, c):
                x[c + 1] = 0.0
                c += 1


@jit_inline
def _coupling_stuck(D, which, c):  # type: ignore[no-untyped-def]
    """True if a friction element marked in ``which`` sits on coupling ``c``."""
    for f in range(which.shape[0]):
        if which[f] and D.f_kind[f] == 0 and D.f_idx[f] == c:
            return True
    return False


@jit
def project(D: ChainData, x: F64, which: I64) -> None:
    """Momentum-preserving projection of the speeds onto ``w_f = 0`` for ``which[f]``
    (:func:`_project_lam` with the mode matrices of that stuck set)."""
    nf = which.shape[0]
    trial = np.empty(nf, dtype=np.int64)
    for f in range(nf):
        trial[f] = STUCK if which[f] else SLIP_POS
    _P, Lam = mode_matrices(D, trial)
    _project_lam(D, x, which, Lam, np.empty(nf))


@jit
def rhs(D: ChainData, x: F64, u: F64, fm: I64, reg: I64, P: F64, xdot: F64) -> None:
    """Time derivative of the state in the current mode (``P`` from :func:`mode_matrices`)."""
    tau = np.empty(D.M.shape[0])
    pd = np.empty(0)
    rhs_into(D, x, u, fm, reg, np.ascontiguousarray(P.T), xdot, tau, pd, 0, False)


@jit
def stuck_torques(D: ChainData, x: F64, u: F64, fm: I64, reg: I64, Lam: F64) -> F64:
    """Friction torque [N m or N] each stuck element must carry (0 for the others)."""
    return Lam @ forces(D, x, u, fm, reg)


@jit_inline
def n_guards(D: ChainData) -> int:
    return D.f_kind.shape[0] + 2 * D.t_nb.shape[0]


@jit_inline
def guard_element(D: ChainData, j: int) -> int:
    """The element whose guard ``j`` is (layout of :func:`guards`): friction element ``j``, or
    table ``nf + k`` for its two guards; the event-list numbering (``ev_el``)."""
    nf = D.f_kind.shape[0]
    return j if j < nf else nf + (j - nf) // 2


@jit
def guards(D: ChainData, x: F64, u: F64, fm: I64, reg: I64, Lam: F64, g: F64) -> None:
    """Guard values (>= 0 while the mode holds) into ``g``.

    Layout: one per friction element (slip: ``s w``; stuck: static capacity - ``|lam|``;
    open: ``-capacity``), then two per table (distance to the lower and upper bound of the
    current region; ``+inf`` where there is none).
    """
    tau = np.empty(D.M.shape[0])
    guards_into(D, x, u, fm, reg, Lam, g, tau)


@jit_inline
def guards_into(
    D: ChainData, x: F64, u: F64, fm: I64, reg: I64, Lam: F64, g: F64, tau: F64
) -> None:
    """:func:`guards` with a work buffer ``tau`` (n,) instead of an allocation."""
    nf = D.f_kind.shape[0]
    any_stuck = False
    for f in range(nf):
        if fm[f] == STUCK:
            any_stuck = True
    if any_stuck:
        forces_into(D, x, u, fm, reg, tau, tau, -1)
    guards_given_forces(D, x, u, fm, reg, Lam, g, tau)


@jit_inline
def guards_given_forces(
    D: ChainData, x: F64, u: F64, fm: I64, reg: I64, Lam: F64, g: F64, tau: F64
) -> None:
    """:func:`guards_into` with the forces at ``(x, u)`` already in ``tau`` (read only if an
    element is stuck)."""
    nf = D.f_kind.shape[0]
    n = D.M.shape[0]
    for f in range(nf):
        m = fm[f]
        i = D.f_idx[f]
        w = x[i] - D.ratio[i] * x[i + 1] if D.f_kind[f] == 0 else x[i]
        ui = D.f_uidx[f]
        cap = D.f_scale[f]
        if ui >= 0:
            kt = D.f_table[f]
            if kt < 0:
                cap *= u[ui]
            else:
                rr = reg[kt]
                cap *= D.t_s[kt, rr] * u[ui] + D.t_o[kt, rr]
        if m == OPEN:
            g[f] = -cap
        elif m == STUCK:
            lam = 0.0
            for k in range(n):
                lam += Lam[f, k] * tau[k]
            g[f] = D.f_static[f] * cap - abs(lam)
        elif D.f_eps[f] > 0.0:
            g[f] = np.inf
        elif m == SLIP_POS:
            g[f] = w
        else:
            g[f] = -w
    for k in range(D.t_nb.shape[0]):
        lo = nf + 2 * k
        kind = D.t_kind[k]
        idx = D.t_idx[k]
        if kind == ARG_SLIP:
            m = fm[idx]
            if m != SLIP_POS and m != SLIP_NEG:
                g[lo] = np.inf
                g[lo + 1] = np.inf
                continue
        if kind == ARG_TWIST:
            a = x[D.c_q[idx]]
        elif kind == ARG_SLIP:
            i = D.f_idx[idx]
            a = abs(x[i] - D.ratio[i] * x[i + 1] if D.f_kind[idx] == 0 else x[i])
        elif kind == ARG_SPEED:
            a = x[idx]
        else:
            a = u[idx]
        r = reg[k]
        g[lo] = a - D.t_b[k, r - 1] if r > 0 else np.inf
        g[lo + 1] = D.t_b[k, r] - a if r < D.t_nb[k] else np.inf


_F2D = types.float64[:, ::1]


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


@jit
def kinetic_torque(D: ChainData, f: int, x: F64, u: F64, fm: I64, reg: I64) -> float:
    """Signed friction torque of a slipping element (tanh law if smoothed) [N m or N]."""
    w = rel_speed(D, f, x)
    F = capacity(D, f, u, reg) * mu_ratio(D, f, x, reg)
    if D.f_eps[f] > 0.0:
        return F * np.tanh(w / D.f_eps[f])
    return F if fm[f] == SLIP_POS else -F


@jit
def stored_energy(D: ChainData, x: F64) -> float:
    """Stored energy [J]: kinetic, elastic (integral of each spring law) and potential."""
    n = D.M.shape[0]
    E = 0.0
    for i in range(n):
        E += 0.5 * D.M[i] * x[i] * x[i]
        if D.b_pos[i] >= 0:
            E -= D.load[i] * x[D.b_pos[i]]
    for c in range(D.ratio.shape[0]):
        k = D.c_table[c]
        if k >= 0:
            q = x[D.c_q[c]]
            r = table_region(D, k, q)
            E += 0.5 * D.t_s[k, r] * q * q + D.t_o[k, r] * q + D.t_e[k, r]
    return E


@jit
def powers(D: ChainData, x: F64, u: F64, fm: I64, reg: I64, Lam: F64) -> tuple[float, F64]:
    """Power supplied [W] and power dissipated per element [W].

    Dissipation layout: ``n`` bodies (viscous + quadratic to ground), ``m`` coupling dampers,
    ``nf`` friction elements (kinetic torque times slip speed; stuck/open: 0).
    """
    n = D.M.shape[0]
    m = D.ratio.shape[0]
    nf = D.f_kind.shape[0]
    pd = np.zeros(n + m + nf)
    p_in = 0.0
    for i in range(n):
        w = x[i]
        pd[i] = D.visc[i] * w * w + D.quad[i] * w * w * abs(w)
        if D.b_uidx[i] >= 0:
            p_in += D.b_ugain[i] * u[D.b_uidx[i]] * w
    for j in range(D.l_body.shape[0]):
        b = D.l_body[j]
        kt = D.l_table[j]
        g = D.l_gain[j] if kt < 0 else D.l_gain[j] * table_value(D, kt, reg[kt], x[b])
        p_in += g * x[D.l_x[j]] * x[b]
    for c in range(m):
        w = x[c] - D.ratio[c] * x[c + 1]
        pd[n + c] = D.damp[c] * w * w
    lam = Lam @ forces(D, x, u, fm, reg)
    for f in range(nf):
        w = rel_speed(D, f, x)
        if fm[f] == SLIP_POS or fm[f] == SLIP_NEG:
            pd[n + m + f] = kinetic_torque(D, f, x, u, fm, reg) * w
        elif fm[f] == STUCK:
            pd[n + m + f] = lam[f] * w
    return p_in, pd


@jit
def jacobians(
    D: ChainData, x: F64, u: F64, fm: I64, reg: I64, P: F64, linear_only: bool
) -> tuple[F64, F64]:
    """Analytic ``d xdot / d x`` (nx, nx) and ``d xdot / d u`` (nx, nu) within the mode.

    With ``linear_only`` the smooth nonlinear terms (quadratic drag, the slopes of the
    friction-vs-slip and engine full-load tables, capacity-vs-input) are left out: what remains
    is the ``A``, ``B`` of the POG form ``L x' = A x + B u + g(x, u)``.
    """
    n = D.M.shape[0]
    nx = D.nx
    nu = u.shape[0]
    dt = np.zeros((n, nx))
    du = np.zeros((n, nu))
    for i in range(n):
        dt[i, i] -= D.visc[i]
        if not linear_only:
            dt[i, i] -= 2.0 * D.quad[i] * abs(x[i])
        if D.b_uidx[i] >= 0:
            du[i, D.b_uidx[i]] += D.b_ugain[i]
    for j in range(D.l_body.shape[0]):
        b = D.l_body[j]
        kt = D.l_table[j]
        if kt < 0:
            dt[b, D.l_x[j]] += D.l_gain[j]
        else:
            r = reg[kt]
            if linear_only:
                continue
            dt[b, D.l_x[j]] += D.l_gain[j] * table_value(D, kt, r, x[b])
            dt[b, b] += D.l_gain[j] * D.t_s[kt, r] * x[D.l_x[j]]
    for c in range(D.ratio.shape[0]):
        r_c = D.ratio[c]
        row = np.zeros(nx)
        row[c] += D.damp[c]
        row[c + 1] -= D.damp[c] * r_c
        kt = D.c_table[c]
        if kt >= 0:
            row[D.c_q[c]] += D.t_s[kt, reg[kt]]
        for k in range(nx):
            dt[c, k] -= row[k]
            dt[c + 1, k] += r_c * row[k]
    if not linear_only:
        for f in range(D.f_kind.shape[0]):
            m = fm[f]
            if m != SLIP_POS and m != SLIP_NEG:
                continue
            s = 1.0 if m == SLIP_POS else -1.0
            cap = capacity(D, f, u, reg)
            i = D.f_idx[f]
            kind = D.f_kind[f]
            # d F / d w from the mu(|w|) table: F = cap * (a |w| + b) * s
            kmu = D.f_mu[f]
            dFdw = cap * D.t_s[kmu, reg[kmu]] if kmu >= 0 else 0.0
            if dFdw != 0.0:
                if kind == 0:
                    dt[i, i] -= dFdw
                    dt[i, i + 1] += dFdw * D.ratio[i]
                    dt[i + 1, i] += D.ratio[i] * dFdw
                    dt[i + 1, i + 1] -= D.ratio[i] * dFdw * D.ratio[i]
                else:
                    dt[i, i] -= dFdw
            ui = D.f_uidx[f]
            if ui >= 0:
                kt = D.f_table[f]
                dcap = D.f_scale[f] * (1.0 if kt < 0 else D.t_s[kt, reg[kt]])
                dF = dcap * mu_ratio(D, f, x, reg) * s
                if kind == 0:
                    du[i, ui] -= dF
                    du[i + 1, ui] += D.ratio[i] * dF
                else:
                    du[i, ui] -= dF
    J = np.zeros((nx, nx))
    B = np.zeros((nx, nu))
    J[:n, :] = P @ dt
    B[:n, :] = P @ du
    for i in range(n):
        if D.b_pos[i] >= 0:
            J[D.b_pos[i], i] = 1.0
    for c in range(D.ratio.shape[0]):
        if D.c_q[c] >= 0:
            J[D.c_q[c], c] = 1.0
            J[D.c_q[c], c + 1] = -D.ratio[c]
    for j in range(D.l_body.shape[0]):
        J[D.l_x[j], D.l_x[j]] = -1.0 / D.l_tau[j]
        B[D.l_x[j], D.l_uidx[j]] += 1.0 / D.l_tau[j]
    return J, B


@jit
def coupling_torques(D: ChainData, x: F64, u: F64, fm: I64, reg: I64, Lam: F64) -> F64:
    """Total torque of each coupling [N m] (upstream frame): spring + damper + friction."""
    m = D.ratio.shape[0]
    out = np.zeros(m)
    for c in range(m):
        w = x[c] - D.ratio[c] * x[c + 1]
        T = D.damp[c] * w
        kt = D.c_table[c]
        if kt >= 0:
            T += table_value(D, kt, reg[kt], x[D.c_q[c]])
        out[c] = T
    lam = Lam @ forces(D, x, u, fm, reg)
    for f in range(D.f_kind.shape[0]):
        if D.f_kind[f] != 0:
            continue
        c = D.f_idx[f]
        if fm[f] == STUCK:
            out[c] += lam[f]
        elif fm[f] == SLIP_POS or fm[f] == SLIP_NEG:
            out[c] += kinetic_torque(D, f, x, u, fm, reg)
    return out


# ======================================================================================
# Event-driven hybrid integrator (kept in this file so that numba's per-file cache is
# invalidated whenever any kernel it inlines changes)
# ======================================================================================
# Compiled event-driven hybrid integrator (the hot path).
#
# Integrates a :class:`~drivetrain_ctrl.kernels.ChainData` model mode by mode with an embedded
# Dormand-Prince 5(4) Runge-Kutta method:
#
# * within a mode the right-hand side is smooth: the mode's stuck constraints, the affine piece of
#   every piecewise-linear law and the current piece of every input signal are held fixed;
# * after each accepted step every guard is checked; a guard that turned negative is an event,
#   located by re-integrating from the step start with a shorter step (Illinois regula falsi) to
#   a bracket of ``1e-13 * max(1, |t|)`` s; the state just past the event is taken;
# * at an event all elements at zero relative speed are decided together
#   (:func:`~drivetrain_ctrl.kernels.decide_modes`), then the guards are re-checked until none
#   fires; a run of too many events in a short time (Zeno) stops the run with a status naming the
#   time and the element;
# * every input breakpoint is a forced stop; the step is bounded by ``h_max`` so that short stick
#   or break-away episodes are not stepped over;
# * supplied work and each element's dissipated energy are integrated with the state.
#
# An optional closed loop (:mod:`drivetrain_ctrl.closedloop`) computes the inputs from controller
# states integrated together with the plant.
#

# status codes
OK, ZENO, MAX_EVENTS, MAX_STEPS, STEP_TOO_SMALL, TOO_MANY_CANDIDATES = 0, 1, 2, 3, 4, 5

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


@jit_nonrt
def set_interval(S, t_ref, ua, ub):  # type: ignore[no-untyped-def]
    """Coefficients of every input on the interval starting at ``t_ref``."""
    st, sv, snk, ssin, sns = S
    for i in range(ua.shape[0]):
        a, b = _piece(st, sv, snk, i, t_ref)
        ua[i] = a
        ub[i] = b


class CtrlData(NamedTuple):
    """Array form of a closed-loop controller (see :mod:`drivetrain_ctrl.closedloop`).

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
def n_cl_states(Cd):  # type: ignore[no-untyped-def]
    """Continuous controller states: LTI (if continuous), rate limiter, actuator (2)."""
    return Cd.ci[CI_NC] + Cd.ci[CI_RL] + 2 * Cd.ci[CI_ACT]


@jit_inline
def cl_error(Cd, y, sv):  # type: ignore[no-untyped-def]
    e = 0.0
    for k in range(Cd.m_kind.shape[0]):
        if Cd.m_kind[k] == 0:
            e += Cd.m_coef[k] * y[Cd.m_idx[k]]
        else:
            e += Cd.m_coef[k] * sv[Cd.m_idx[k]]
    return e


@jit_inline
def cl_chain(Cd, cs, y, nx, t, e):  # type: ignore[no-untyped-def]
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
def cl_frozen(Cd, cs, t):  # type: ignore[no-untyped-def]
    """True while the LTI states must not move: before the start and while latched."""
    if t < Cd.cf[CF_TON]:
        return True
    lat = cs[CS_LATCH]
    return lat == LATCH_RAMP or lat == LATCH_HELD


@jit_inline
def cl_backcalc(Cd, cs, vpre):  # type: ignore[no-untyped-def]
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
def cl_output(Cd, cs, y, nx, t, sv):  # type: ignore[no-untyped-def]
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
def cl_derivs(Cd, cs, y, nx, t, sv, dy):  # type: ignore[no-untyped-def]
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
def cl_guards(Cd, cs, y, nx, t, sv, g, off):  # type: ignore[no-untyped-def]
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
def cl_update(Cd, cs, y, nx, t, sv, fm):  # type: ignore[no-untyped-def]
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


@jit_inline
def cl_command(Cd, cs, y, nx, t, sv):  # type: ignore[no-untyped-def]
    """The controller's command before the rate limiter and the actuator (x_r of law (6));
    NaN in open loop. ``sv`` must hold the current signal values."""
    if Cd.ci[CI_OUT] < 0:
        return np.nan
    e = cl_error(Cd, y, sv)
    varg, vpre, v = cl_chain(Cd, cs, y, nx, t, e)
    return v


@jit
def cl_sample(Cd, cs, y, sv, t):  # type: ignore[no-untyped-def]
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
def eval_u(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u):  # type: ignore[no-untyped-def]
    """Plant inputs at ``t``: signals, with the controlled input from the controller."""
    eval_inputs(S, ua, ub, t, t_ref, sv)
    for i in range(u.shape[0]):
        u[i] = sv[i]
    if Cd.ci[CI_OUT] >= 0:
        u[Cd.ci[CI_OUT]] = cl_output(Cd, cs, y, nx, t, sv)


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
def full_rhs(D, S, ua, ub, t, t_ref, y, fm, reg, PT, nx, energy, u, tau, dy, Cd, cs, sv):  # type: ignore[no-untyped-def]
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
def dp5_step(  # type: ignore[no-untyped-def]
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
def full_rhs_call(D, S, ua, ub, t, t_ref, y, fm, reg, PT, nx, energy, u, tau, dy, Cd, cs, sv):  # type: ignore[no-untyped-def]
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
def _dense_row(y0, y1, k0, k2, k3, k4, k5, k6, h):  # type: ignore[no-untyped-def]
    """Coefficients ``(r1, r2, r3, r4)`` of the Dormand-Prince continuous extension (Hairer's
    DOPRI5) of one component (or of any fixed linear combination of components) from its values
    ``y0``, ``y1`` at the step's ends and its stage derivatives ``k0``, ``k2`` .. ``k6``; the
    value at fraction ``th`` is :func:`_dense_value`."""
    r2 = y1 - y0
    r3 = h * k0 - r2
    return r2, r3, r2 - h * k6 - r3, h * (D1 * k0 + D3 * k2 + D4 * k3 + D5 * k4 + D6 * k5 + D7 * k6)


@jit_inline
def _dense_value(r0, r1, r2, r3, r4, th):  # type: ignore[no-untyped-def]
    """Continuous extension at fraction ``th`` of the step (``r0`` the value at its start)."""
    th1 = 1.0 - th
    return r0 + th * (r1 + th1 * (r2 + th * (r3 + th1 * r4)))


@jit_inline
def dense_coeffs(y, y1, Ks, h, rc):  # type: ignore[no-untyped-def]
    """Coefficients of the continuous extension of every component into ``rc``."""
    for i in range(y.shape[0]):
        rc[0, i] = y[i]
        rc[1, i], rc[2, i], rc[3, i], rc[4, i] = _dense_row(
            y[i], y1[i], Ks[0, i], Ks[2, i], Ks[3, i], Ks[4, i], Ks[5, i], Ks[6, i], h
        )


@jit_inline
def dense_eval(rc, th, out):  # type: ignore[no-untyped-def]
    """State at fraction ``th`` of the step from the continuous extension."""
    for i in range(out.shape[0]):
        out[i] = _dense_value(rc[0, i], rc[1, i], rc[2, i], rc[3, i], rc[4, i], th)


@jit_inline
def _rel_row(D, f, A, k):  # type: ignore[no-untyped-def]
    """:func:`rel_speed` of friction element ``f`` from row ``k`` of ``A`` (a stage derivative:
    the relative acceleration), without making a view (the caller runs without NRT)."""
    i = D.f_idx[f]
    return A[k, i] - D.ratio[i] * A[k, i + 1] if D.f_kind[f] == 0 else A[k, i]


#: sample points of the continuous extension in :func:`_slip_dip` (then golden-section refinement)
DIP_SAMPLES = 32


@jit_inline
def _slip_dip(D, fm, y, y1, Ks, hh):  # type: ignore[no-untyped-def]
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


@jit_inline
def _guards_step_inl(D, S, ua, ub, t, t_ref, y, fm, reg, Lam, nx, u, g, Cd, cs, sv, tau):  # type: ignore[no-untyped-def]
    """Plant and controller guards at (t, y) on the per-step path (no allocation, no NRT).

    Inlined into the step loop and the event location: a call passes ChainData and CtrlData as
    some 350 flattened arguments."""
    eval_u(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u)
    guards_into(D, y, u, fm, reg, Lam, g, tau)
    cl_guards(Cd, cs, y, nx, t, sv, g, n_guards(D))


@jit_inline
def _guards_last_stage(D, y1, fm, reg, Lam, nx, uw, g, Cd, cs, svw, tau, t1, u, sv):  # type: ignore[no-untyped-def]
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


@jit_nonrt
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


@jit_inline
def _accept(y, y1, Ks, g0, g1):  # type: ignore[no-untyped-def]
    """Take an accepted step: y <- y1, k1 <- k7 (FSAL), guards at the start <- at the end."""
    for i in range(y.shape[0]):
        y[i] = y1[i]
        Ks[0, i] = Ks[6, i]
    for i in range(g0.shape[0]):
        g0[i] = g1[i]


@jit_inline
def _record(T, Y, U, FM, RG, n_rec, t, y, u, fm, reg):  # type: ignore[no-untyped-def]
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


#: |lambda| h allowed per step for the mode's fastest eigenvalue (with |lambda| from
#: :func:`_spectral_radius_bound`), so that a loose tolerance cannot let a stiff mode grow
#: numerically and trigger spurious stick/slip events. Dormand-Prince 5(4)'s stability region
#: reaches about 3.3 on the negative real axis, so for well-damped modes this is inside it with a
#: margin. Near the imaginary axis the region is narrower: along the ray of the lightly damped
#: gear-mesh eigenvalue (damping ratio about 0.03) it ends near 2.2, on the axis itself near 1.0
#: (``python benchmarks/step_limits.py`` prints both). For such a mode this bound is only a
#: ceiling; the error control keeps the steps inside the region (the local error estimate grows
#: with the numerically amplified mode), and the steps there sit below the bound (the script
#: prints the distribution of h / bound).
STABILITY_FACTOR = 2.5
#: log of the smallest error norm the PI step control remembers (1e-4)
LOG_ERR_FLOOR = float(np.log(1e-4))


@jit_nonrt
def _mode_key(fm, reg):  # type: ignore[no-untyped-def]
    key = np.int64(7)
    for f in range(fm.shape[0]):
        key = key * np.int64(1000003) + np.int64(fm[f] + 1)
    for k in range(reg.shape[0]):
        key = key * np.int64(1000003) + np.int64(reg[k] + 1)
    return key


@jit
def _balance(J):  # type: ignore[no-untyped-def]
    """``S^-1 J S`` for a diagonal ``S`` of powers of 2 that balances row and column norms
    (EISPACK ``balanc`` without permutations): similar to ``J``, exactly so in floating point."""
    n = J.shape[0]
    A = J.copy()
    for _sweep in range(50):
        done = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(A[j, i])
                    r += abs(A[i, j])
            if c == 0.0 or r == 0.0:
                continue
            g = r / 2.0
            f = 1.0
            sm = c + r
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c >= g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * sm:
                done = False
                for j in range(n):
                    A[i, j] /= f
                    A[j, i] *= f
        if done:
            break
    return A


@jit
def _inf_norm(A):  # type: ignore[no-untyped-def]
    """Max row sum of ``|A|`` (the operator norm induced by the max norm)."""
    nrm = 0.0
    for i in range(A.shape[0]):
        r = 0.0
        for j in range(A.shape[1]):
            r += abs(A[i, j])
        if r > nrm:
            nrm = r
    return nrm


#: squarings in :func:`_spectral_radius_bound`: ``||A^1024||^(1/1024)``, within 3 % of the
#: spectral radius on the drivetrain's mode Jacobians (``tests/unit/test_kernel_numerics.py``)
GELFAND_SQUARINGS = 10


@jit
def _spectral_radius_bound(J):  # type: ignore[no-untyped-def]
    """An upper bound of the spectral radius of ``J``, tight to a few per cent: Gelfand's
    ``rho(A) <= ||A^m||^(1/m)`` for every induced norm, with ``A`` the balanced ``J`` and
    ``m = 2^GELFAND_SQUARINGS`` (repeated squaring, normalised after each product so that nothing
    overflows; the logarithms of the norms are accumulated). Ten small matrix products in place
    of LAPACK's eigenvalue routine, which it replaces: the bound only sets the largest stable
    step, where a bound from above is what is needed (``tests/unit/test_kernel_numerics.py``
    checks both sides)."""
    A = _balance(J)
    nrm = _inf_norm(A)
    if nrm == 0.0:
        return 0.0
    B = A / nrm
    lg = np.log(nrm)
    for _k in range(GELFAND_SQUARINGS):
        B = B @ B
        nb = _inf_norm(B)
        if nb == 0.0:  # nilpotent: spectral radius 0
            return 0.0
        lg = 2.0 * lg + np.log(nb)
        B /= nb
    return np.exp(lg / 2.0**GELFAND_SQUARINGS)


@jit
def _rho_step(J):  # type: ignore[no-untyped-def]
    """``STABILITY_FACTOR / rho`` with ``rho`` :func:`_spectral_radius_bound` (``inf`` for 0),
    with a margin for round-off in the products."""
    rho = _spectral_radius_bound(J)
    return STABILITY_FACTOR / (rho * (1.0 + 1e-9)) if rho > 0.0 else np.inf


@jit
def stable_step_lazy(D, y, u, fm, reg, P, nx, key, jcache, lcache):  # type: ignore[no-untyped-def]
    """Largest step [s] that keeps the mode's fastest eigenvalue in the stability region,
    ``STABILITY_FACTOR / max |lambda(J)|`` (J at the first entry of the mode; cached per mode and
    table region), without the tight bound of the spectral radius until it can matter.

    Returns ``(h, exact)``: the tight step bound (``STABILITY_FACTOR / rho`` with ``rho`` from
    :func:`_spectral_radius_bound`, at most ~1 % above the spectral radius) if it is known for the
    mode (``exact``), else a cruder lower bound of it, ``STABILITY_FACTOR / ||S^-1 J S||``
    (balanced norm; J kept in ``jcache``). A step not longer than the crude bound is not limited
    by the tight one either, so :func:`stable_step_exact` is only called for longer steps, and
    modes that only see short steps (chatter after events) never need it. The caller
    (:func:`_stab_lookup`) has looked ``key`` up in both caches: this is the miss path. ``jcache``
    keeps the balanced J (similar to J: the same spectral radius)."""
    J, _B = jacobians(D, y[:nx], u, fm, reg, P, False)
    A = _balance(J)
    nrm = _inf_norm(A)
    # margin for round-off in the norm's sums (~1e-15)
    h_lo = STABILITY_FACTOR / (nrm * (1.0 + 1e-9)) if nrm > 0.0 else np.inf
    jcache[key] = A
    lcache[key] = h_lo
    return h_lo, False


@jit
def stable_step_exact(fm, reg, hcache, jcache):  # type: ignore[no-untyped-def]
    """The tight bound of :func:`stable_step_lazy` for a mode it has seen (:func:`_rho_step`)."""
    key = _mode_key(fm, reg)
    if key in hcache:
        return hcache[key]
    h = _rho_step(jcache[key])
    hcache[key] = h
    return h


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
def _mm_find(fm, mmask, mst):  # type: ignore[no-untyped-def]
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
def _mm_insert(D, fm, mmask, mP, mPT, mL, mst):  # type: ignore[no-untyped-def]
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
        for k in range(n):
            mL[s, f, k] = Lam[f, k]
    return s


@jit
def _mm_alloc(D):  # type: ignore[no-untyped-def]
    """Empty mode-matrix cache ``(mmask, mP, mPT, mL, mst)`` (see :func:`_mm_find`): every stuck
    set fits for up to 10 friction elements."""
    n = D.M.shape[0]
    nf = D.f_kind.shape[0]
    n_slots = 1 << min(nf, 10)
    return (
        np.zeros((n_slots, nf), dtype=np.int64),
        np.empty((n_slots, n, n)),
        np.empty((n_slots, n, n)),
        np.empty((n_slots, nf, n)),
        np.zeros(2, dtype=np.int64),
    )


@jit
def _dm_work(D):  # type: ignore[no-untyped-def]
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
def _project_cached(D, x, cand, trial, lamw, mmask, mP, mPT, mL, mst):  # type: ignore[no-untyped-def]
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
def _dm_classify(D, S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u, fm, reg, tol, cand, caps):  # type: ignore[no-untyped-def]
    """The inputs at t into ``u``, then :func:`_dm_classify_core`."""
    eval_u(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u)
    return _dm_classify_core(D, y, u, fm, reg, tol, cand, caps)


@jit_nonrt
def _dm_classify_core(D, y, u, fm, reg, tol, cand, caps):  # type: ignore[no-untyped-def]
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
def _consistency_nr(D, fm, cand, caps, P, Lam, tau):  # type: ignore[no-untyped-def]
    """Total violation (0 = consistent) of trial mode ``fm`` for the candidate elements: stuck
    torques beyond static capacity, slip directions against the accelerations; from the forces
    of the trial mode in ``tau`` (no allocation)."""
    n = tau.shape[0]
    viol = 0.0
    for f in range(fm.shape[0]):
        if not cand[f]:
            continue
        if fm[f] == STUCK:
            lim = D.f_static[f] * caps[f]
            lam = 0.0
            for k in range(n):
                lam += Lam[f, k] * tau[k]
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
def _dm_combos(D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mL, mst):  # type: ignore[no-untyped-def]
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
            v = _consistency_nr(D, trial, cand, caps, mP[s], mL[s], tau)
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
):  # type: ignore[no-untyped-def]
    """:func:`_dm_combos` from the start, filling the mode-matrix cache on a miss and resuming."""
    prog[0] = -1.0
    r = _dm_combos(D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mL, mst)
    while r == DM_MISS:
        _mm_insert(D, trial, mmask, mP, mPT, mL, mst)
        r = _dm_combos(D, x, u, fm, reg, nc, cand, caps, idx, trial, tau, prog, mmask, mP, mL, mst)
    return r


@jit_nonrt
def _dm_controller(Cd, cs, S, ua, ub, t, t_ref, y, nx, sv, u, fm):  # type: ignore[no-untyped-def]
    """Controller update after the plant's decision, then the inputs at t again."""
    cl_update(Cd, cs, y, nx, t, sv, fm)
    eval_u(S, ua, ub, t, t_ref, y, nx, Cd, cs, sv, u)


@jit_nonrt
def _dm_guards(D, y, u, fm, reg, Lam, g0, tau, Cd, cs, nx, t, sv):  # type: ignore[no-untyped-def]
    """Guards after a decision into ``g0``; True if none is violated."""
    guards_into(D, y, u, fm, reg, Lam, g0, tau)
    cl_guards(Cd, cs, y, nx, t, sv, g0, n_guards(D))
    ok = True
    for q in range(g0.shape[0]):
        if g0[q] < -1e-9 * (1.0 + abs(g0[q])):
            ok = False
    return ok


@jit_inline
def _decide_fast(  # type: ignore[no-untyped-def]
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


@jit_inline
def _stab_lookup(D, y, u, fm, reg, P, nx, hcache, jcache, lcache):  # type: ignore[no-untyped-def]
    """The mode's step bound ``(h, exact)`` from the caches (see :func:`stable_step_lazy`, called
    only for a new mode)."""
    key = _mode_key(fm, reg)
    if key in hcache:
        return hcache[key], True
    if key in lcache:
        return lcache[key], False
    return stable_step_lazy(D, y, u, fm, reg, P, nx, key, jcache, lcache)


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
):  # type: ignore[no-untyped-def]
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


#: return codes of :func:`_advance`
ADV_DONE, ADV_MAX_STEPS, ADV_TOO_SMALL, ADV_FULL, ADV_STAB, ADV_STEP = 0, 1, 2, 3, 4, 5


@jit_nonrt
def _advance(  # type: ignore[no-untyped-def]
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
):
    """The step loop of :func:`simulate_kernel` within one mode, without reference counting.

    Takes steps (Dormand-Prince, error control, guards at the step end) and records the accepted
    ones until it returns a code: ``ADV_DONE`` (``t >= t_end``), ``ADV_MAX_STEPS``,
    ``ADV_TOO_SMALL``, ``ADV_FULL`` (no room to record a step), ``ADV_STAB`` (the tight stability
    bound is needed before the next step) or ``ADV_STEP``: an accepted step in which a guard
    fired or that ends at a stop time, not yet taken (the caller locates the event or handles the
    stop, as before). Scalars in ``fs`` = [t, h, log(err_old), h_stab, t_sample, hh, t1, h_next] and
    ``ist`` = [ib, n_steps, n_rej, nfev, n_rec, stab_exact, j, hit_stop] (in and out).
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
        if n_rec >= T.shape[0]:
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
        en = 0.0
        for i in range(nxs):
            a = abs(y[i])
            b = abs(y1[i])
            r = err[i] / (atol + rtol * (a if a > b else b))
            en += r * r
        en = np.sqrt(en / nxs)
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
        # unless the step was cut to a stop time), its inputs and forces give the guards
        u_fresh = t + hh == t1
        if u_fresh:
            _guards_last_stage(D, y1, fm, reg, Lam, nx, uw, g1, Cd, cs, svw, tau, t1, u, sv)
        else:
            _guards_step_inl(D, S, ua, ub, t1, t_ref, y1, fm, reg, Lam, nx, u, g1, Cd, cs, sv, taug)
        j = _fired(g0, g1)
        if j >= 0 or hit_stop:
            fs[5] = hh
            fs[6] = t1
            fs[7] = h_next
            ist[6] = j
            ist[7] = 1 if hit_stop else 0
            code = ADV_STEP
            break
        t = t1
        _accept(y, y1, Ks, g0, g1)
        h = h_next
        # u, sv hold the inputs and signals at t (from the step's last stage)
        _record(T, Y, U, FM, RG, n_rec, t, y, u, fm, reg)
        U[n_rec, U.shape[1] - 1] = np.nan if Cd.ci[CI_OUT] < 0 else cl_command(Cd, cs, y, nx, t, sv)
        n_rec += 1
    fs[0] = t
    fs[1] = h
    fs[2] = lerr_old
    ist[1] = n_steps
    ist[2] = n_rej
    ist[3] = nfev
    ist[4] = n_rec
    return code


@jit_inline
def _redecide(  # type: ignore[no-untyped-def]
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
def _zeno_push(ring, pos, t, window):  # type: ignore[no-untyped-def]
    """Record an event at ``t`` in the ring of the last ``len(ring)`` event times (next slot
    ``pos``); returns ``(next pos, True if all of them lie within window [s] of t)``."""
    ring[pos] = t
    pos = (pos + 1) % ring.shape[0]
    return pos, t - ring[pos] < window


@jit
def _grow(T, Y, U, FM, RG, n_rec):  # type: ignore[no-untyped-def]
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
    Cd,
    cs,
    y_cl0,
    nu,
):
    """Run the hybrid simulation (open or closed loop). Returns a tuple of outputs.

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
    ng = n_guards(D) + N_CL_GUARDS
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

    # room for about 4 samples per h_max (growing by doubling beyond): no copies in a typical run
    est = 4.0 * (t_end - t0) / h_max + 64.0
    cap = int(min(max(est, 1024.0), 65536.0))
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

    T[0] = t
    Y[0] = y
    U[0, :nu] = u
    U[0, nu] = cl_command(Cd, cs, y, nx, t, sv)
    FM[0] = fm
    RG[0] = reg
    n_rec = 1
    zeno_ring = np.full(zeno_count, -np.inf)
    zeno_pos = 0
    lerr_old = 0.0  # log of the previous step's error norm (PI control)
    fm_old = fm.copy()
    reg_old = reg.copy()

    fs = np.zeros(8)
    ist = np.zeros(8, dtype=np.int64)
    pending = False  # a step taken here still to be recorded
    while True:
        if pending:
            if n_rec >= T.shape[0]:
                T, Y, U, FM, RG = _grow(T, Y, U, FM, RG, n_rec)
            # u, sv hold the inputs at (t, y): set by the mode decision at the event or stop
            _record(T, Y, U, FM, RG, n_rec, t, y, u, fm, reg)
            U[n_rec, U.shape[1] - 1] = (
                np.nan if Cd.ci[CI_OUT] < 0 else cl_command(Cd, cs, y, nx, t, sv)
            )
            n_rec += 1
            pending = False
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
        )
        t = fs[0]
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
        event = j >= 0
        if not event:
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
            slot, nb, h_stab, stab_exact, n_ev = _redecide(
                D, S, ua, ub, t, t_ref, y, nx, fm, reg, fm_old, reg_old, u, tol_w, Cd, cs, sv, g0,
                W, (mmask, mP, mPT, mL, mst), (hcache, jcache, lcache),
                (ev_t, ev_el, ev_from, ev_to, cs_old), n_ev,
            )  # fmt: skip
            if nb == DM_TOO_MANY:
                status = TOO_MANY_CANDIDATES
                break
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
                if j >= n_guards(D):
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
    )
