"""The chain model's physics on :class:`ChainData`: forces, state derivative, stuck constraints
and mode matrices, projection, guards, energy and powers, Jacobians, coupling torques.

:class:`ChainData` is the array form of a :class:`~drivetrain_ctrl.plant.chain.Chain` (made by
:mod:`drivetrain_ctrl.plant.model`), so the same code serves the Python API (``Model.rhs`` etc.), the
linearisation and the simulator's hot loop. Conventions (see :mod:`drivetrain_ctrl.plant.chain`):

* state ``x = [omega (n), q (springs), position (tracked bodies), lag states]``;
* friction element mode ``fm[f]``: ``STUCK = 0``, ``SLIP_POS = 1``, ``SLIP_NEG = 2``,
  ``OPEN = 3``; table region ``reg[k]``: index of the affine piece in use;
* stuck elements are constraints ``G omega = 0``; with ``M a = tau - G^T lam`` the accelerations
  are ``a = P tau`` and the stuck torques ``lam`` follow from ``tau`` and the extended matrix
  ``Lam`` of :func:`mode_matrices` (the generalisation of the paper's transformation T,
  eq. (3)-(4)) through :func:`stuck_torque`: in a statically indeterminate stuck set the
  distribution with the largest smallest capacity margin;
* guards ``g >= 0`` in the current mode; a sign change to negative is an event.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._jit import F64, I64, jit, jit_inline, jit_nonrt

#: friction element modes ``fm[f]``
STUCK, SLIP_POS, SLIP_NEG, OPEN = 0, 1, 2, 3
#: what a table's argument is (``t_kind[k]``; ``t_idx[k]`` the coupling, friction element, body
#: or input): a spring twist, a slip speed ``|w|``, a body speed, an input
ARG_TWIST, ARG_SLIP, ARG_SPEED, ARG_INPUT = 0, 1, 2, 3


class ChainData(NamedTuple):
    """Array form of a :class:`~drivetrain_ctrl.plant.chain.Chain` (SI units, upstream frames)."""

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
    c_gap: I64  # (m,) spring-table region (the gap) where the damper is off, -1: never off
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


# Helpers take the arrays they need, not ChainData: passing the 34-array tuple into a helper costs
# about 0.6 us per call in reference counting (measured during development with perf and
# micro-benchmarks; the end-to-end effect is in benchmarks/bench_simulate.py).
@jit_inline
def _rel(f_kind, f_idx, ratio, f, x):
    i = f_idx[f]
    r = x[i]
    if f_kind[f] == 0:
        r = x[i] - ratio[i] * x[i + 1]
    return r


@jit_inline
def _cap(f_scale, f_uidx, f_table, t_s, t_o, f, u, reg):
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
def _mu(f_mu, t_s, t_o, f, aw, reg):
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
def damper_coefficient(D: ChainData, c: int, reg: I64) -> float:
    """Damping of coupling ``c`` [N m s/rad or N s/m] in table regions ``reg``: ``damp[c]``, or
    0 while its spring is in the region ``c_gap[c]`` (its backlash gap, for a damper that acts
    only in contact). :func:`forces_into` writes the same test out (hot path)."""
    d = D.damp[c]
    if D.c_gap[c] >= 0 and reg[D.c_table[c]] == D.c_gap[c]:
        d = 0.0
    return d


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
        kt = D.c_table[c]
        # the damper, off in its spring's gap if it acts only in contact (damper_coefficient)
        d = D.damp[c]
        if D.c_gap[c] >= 0 and reg[kt] == D.c_gap[c]:
            d = 0.0
        T = d * w
        if pw:
            ff[ff_off + n + c] = d * w * w
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
                # smoothed law (comparison only, no open mode): a negative capacity gives none
                F = F * np.tanh(w / D.f_eps[f]) if F > 0.0 else 0.0
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
def _null_basis(G: F64) -> F64:
    """Basis (k, d) of the null space of ``G^T`` for constraint rows ``G`` (k, n): the
    self-balancing stuck torques (``G^T v = 0``: no acceleration changes) of a statically
    indeterminate stuck set; ``d = 0`` if the rows are independent.

    Reduced row echelon form of ``G^T`` (partial pivoting): one basis vector per free column,
    1 there and minus the pivot rows' entries. Stuck sets that do not share a body give vectors
    with disjoint supports (elimination keeps the block structure); entries below 1e-12 of the
    largest are set to exactly 0 so that the supports are exact.
    """
    k = G.shape[0]
    n = G.shape[1]
    A = G.T.copy()
    scale = 0.0
    for i in range(n):
        for c in range(k):
            scale = max(scale, abs(A[i, c]))
    pivcol = np.full(n, -1, dtype=np.int64)
    isfree = np.zeros(k, dtype=np.int64)
    r = 0
    for c in range(k):
        if r >= n:
            isfree[c] = 1
            continue
        p = r
        for q in range(r + 1, n):
            if abs(A[q, c]) > abs(A[p, c]):
                p = q
        if abs(A[p, c]) <= 1e-12 * scale:
            isfree[c] = 1
            continue
        if p != r:
            for j in range(k):
                A[r, j], A[p, j] = A[p, j], A[r, j]
        piv = A[r, c]
        for j in range(k):
            A[r, j] /= piv
        for q in range(n):
            if q != r and A[q, c] != 0.0:
                fct = A[q, c]
                for j in range(k):
                    A[q, j] -= fct * A[r, j]
        pivcol[r] = c
        r += 1
    d = 0
    for c in range(k):
        d += isfree[c]
    N = np.zeros((k, d))
    j = 0
    for c in range(k):
        if not isfree[c]:
            continue
        N[c, j] = 1.0
        for q in range(r):
            N[pivcol[q], j] = -A[q, c]
        big = 0.0
        for i in range(k):
            big = max(big, abs(N[i, j]))
        for i in range(k):
            if abs(N[i, j]) <= 1e-12 * big:
                N[i, j] = 0.0
        j += 1
    return N


# Rows of the extended stuck-torque matrix after the nf element rows (offsets from nf), see
# mode_matrices: the redundancy groups, then the work space of the max-min LP (_group_optimum).
_R_EGROUP = 0  # [f]: group of stuck element f (its smallest null-space column), -1 none
_R_CGROUP = 1  # [j]: group of null-space column j, -1 unused
_R_MEMO = 2  # [valid, group, m*] of the last LP solved
_R_MA = 3  # [i]: its least-norm torque lam0 of the group's i-th element
_R_MC = 4  # [i]: its static capacity
_R_Z = 5  # [j]: its optimal self-balancing torque along column j
_R_LEVEL = 6  # [i]: margin at which element i is held (leximin stages), NaN while free
_R_BASIS = 7  # [r]: basic variable of tableau row r
_R_ELEM = 8  # [i]: the group's elements
_R_COL = 9  # [r]: the group's columns
_R_TAB = 10  # simplex tableau: up to nf + 1 rows


@jit
def mode_matrices(D: ChainData, fm: I64) -> tuple[F64, F64]:
    """``P`` (n, n) and the extended stuck-torque matrix ``Lam`` of friction modes ``fm``:
    accelerations ``P tau``; ``Lam[:nf, :n] tau`` the least-norm stuck torques;
    ``Lam[:nf, n:n + nf]`` a basis ``N`` of the self-balancing stuck torques (zero columns beyond
    its dimension ``d``; ``d = 0`` unless the stuck set is statically indeterminate).

    With the constraint rows ``G`` of the stuck elements and ``S = G M^-1 G^T``:
    ``Lam0 = S^+ G M^-1`` and ``P = M^-1 - M^-1 G^T Lam0`` (the paper's transformation T,
    eq. (3)-(4), generalised). If ``S`` is singular (redundant constraints: a body held by two
    stuck paths) the stuck torques are ``Lam0 tau + N z`` for any ``z``; which ``z`` the stuck
    elements carry is chosen by :func:`stuck_torque` (the distribution with the largest smallest
    capacity margin). Read the stuck torques through :func:`stuck_torque` /
    :func:`stuck_torques`, never as ``Lam @ tau``.

    The rows after the ``nf`` element rows (shape :func:`lam_shape`) hold the redundancy groups
    (the connected sets of stuck elements coupled through null-space columns; ``Lam[nf, f]`` the
    group of element ``f``, -1 if its stuck torque is unique; ``Lam[nf + 1, j]`` the group of
    column ``j``) and the work space of the LP of :func:`stuck_torque` (rows ``nf + 2`` on,
    written by it). The mode-matrix cache of the simulator thus sizes that work space once per
    mode, and the guard path, which receives ``Lam`` everywhere, allocates nothing. Since the
    stuck torques write into it, one ``Lam`` must not serve two kernel calls at the same time
    (the kernels hold the GIL, so threads of one process never do; a ``nogil`` kernel would
    need a ``Lam`` per thread).
    """
    n = D.M.shape[0]
    nf = fm.shape[0]
    which = np.zeros(nf, dtype=np.int64)
    for f in range(nf):
        if fm[f] == STUCK:
            which[f] = 1
    Minv = np.diag(1.0 / D.M)
    nr, nc = lam_shape(n, nf)
    Lam = np.zeros((nr, nc))
    for f in range(nf):
        Lam[nf + _R_EGROUP, f] = -1.0
        Lam[nf + _R_CGROUP, f] = -1.0
    G = constraint_rows(D, fm, which)
    if G.shape[0] == 0:
        return Minv, Lam
    GM = G @ Minv
    L = _solve_small(GM @ G.T, GM)
    P = Minv - GM.T @ L
    N = _null_basis(G)
    d = N.shape[1]
    # redundancy groups: label propagation over the columns sharing a stuck element (labels
    # only decrease: each connected set of columns ends with its smallest column index)
    cg = np.arange(d)
    changed = d > 1
    while changed:
        changed = False
        for r in range(N.shape[0]):
            lo = d
            for j in range(d):
                if N[r, j] != 0.0 and cg[j] < lo:
                    lo = cg[j]
            for j in range(d):
                if N[r, j] != 0.0 and cg[j] != lo:
                    cg[j] = lo
                    changed = True
    for j in range(d):
        Lam[nf + _R_CGROUP, j] = cg[j]
    r = 0
    for f in range(nf):
        if which[f]:
            Lam[f, :n] = L[r, :]
            for j in range(d):
                Lam[f, n + j] = N[r, j]
                if N[r, j] != 0.0:
                    Lam[nf + _R_EGROUP, f] = cg[j]
            r += 1
    return P, Lam


@jit_inline
def lam_shape(n, nf):
    """Shape of the extended stuck-torque matrix of :func:`mode_matrices` for ``n`` bodies and
    ``nf`` friction elements: the element rows, the group rows, the LP's work space (a tableau
    of at most ``k + 2 <= nf + 1`` rows and ``2 p + k + 2 <= 3 nf + 1`` columns for a group of
    ``p <= nf`` elements and ``k <= nf - 1`` columns)."""
    return 2 * nf + _R_TAB + 1, max(n + nf, 3 * nf + 2)


@jit_inline
def _group_columns(Lam, nf, g):
    """Number of null-space columns in redundancy group ``g``."""
    k = 0
    for j in range(nf):
        if Lam[nf + _R_CGROUP, j] == g:
            k += 1
    return k


@jit_inline
def _lam0(Lam, tau, n, f):
    """Least-norm stuck torque of element ``f``: ``Lam[f, :n] . tau``."""
    lam = 0.0
    for k in range(n):
        lam += Lam[f, k] * tau[k]
    return lam


@jit_inline
def _column_optimum(D, u, fm, reg, Lam, tau, j):
    """``(z*, m*)``: the self-balancing torque ``z`` along null-space column ``j`` that maximises
    the smallest static capacity margin ``m(z) = min_h (static_h cap_h - |lam0_h + N_hj z|)`` of
    the column's stuck elements, and that largest margin (a redundancy group of one column).

    An LP in one variable; exact, no iteration, no allocation. Each element gives an increasing
    and a decreasing line of ``z``; by LP duality ``m*`` is the lowest of the intersection heights
    of an increasing with a decreasing line, and ``z*`` that intersection (unique, since every
    line has a nonzero slope). ``m*`` is continuous in the state and the inputs. The same optimum
    as :func:`_group_optimum` (whose leximin tie-break never acts here: ``z*`` is unique), in
    closed form: kept for the common one-column case, without the tableau.
    """
    n = D.M.shape[0]
    nf = fm.shape[0]
    best = np.inf
    zbest = 0.0
    for f in range(nf):
        bf = Lam[f, n + j] if fm[f] == STUCK else 0.0
        if bf == 0.0:
            continue
        sf = 1.0 if bf > 0.0 else -1.0
        cf = D.f_static[f] * _cap(D.f_scale, D.f_uidx, D.f_table, D.t_s, D.t_o, f, u, reg)
        # increasing line of f: c_f + s_f a_f + |b_f| z
        pf = cf + sf * _lam0(Lam, tau, n, f)
        for h in range(nf):
            bh = Lam[h, n + j] if fm[h] == STUCK else 0.0
            if bh == 0.0:
                continue
            sh = 1.0 if bh > 0.0 else -1.0
            ch = D.f_static[h] * _cap(D.f_scale, D.f_uidx, D.f_table, D.t_s, D.t_o, h, u, reg)
            # decreasing line of h: c_h - s_h a_h - |b_h| z
            ph = ch - sh * _lam0(Lam, tau, n, h)
            z = (ph - pf) / (abs(bf) + abs(bh))
            ht = pf + abs(bf) * z
            if ht < best:
                best = ht
                zbest = z
    return zbest, best


@jit_inline
def _pivot(Lam, T0, B, R, C, pr, pc):
    """Simplex pivot of the tableau (rows ``T0 .. T0 + R``, the last the reduced costs; columns
    ``0 .. C``, the last the right-hand side) on row ``pr``, column ``pc``."""
    piv = Lam[T0 + pr, pc]
    for q in range(C + 1):
        Lam[T0 + pr, q] /= piv
    for r in range(R + 1):
        if r == pr:
            continue
        fct = Lam[T0 + r, pc]
        if fct != 0.0:
            for q in range(C + 1):
                Lam[T0 + r, q] -= fct * Lam[T0 + pr, q]
            Lam[T0 + r, pc] = 0.0
            if r < R and Lam[T0 + r, C] < 0.0:  # round-off below the basic level 0
                Lam[T0 + r, C] = 0.0
    Lam[B, pr] = pc


@jit_inline
def _simplex(Lam, T0, B, R, ny, C, tol):
    """Primal simplex (Bland's rule: no cycling) on the tableau of :func:`_pivot`, entering only
    the first ``ny`` columns, until no reduced cost is below ``-tol``."""
    for _it in range(50 * (R + ny) + 50):
        e = -1
        for q in range(ny):
            if Lam[T0 + R, q] < -tol:
                e = q
                break
        if e < 0:
            return
        pr = -1
        best = 0.0
        for r in range(R):
            a = Lam[T0 + r, e]
            if a > 1e-12:
                ratio = Lam[T0 + r, C] / a
                if pr < 0 or ratio < best or (ratio == best and Lam[B, r] < Lam[B, pr]):
                    pr = r
                    best = ratio
        if pr < 0:  # unbounded: not for these LPs (their primal is feasible)
            return
        _pivot(Lam, T0, B, R, C, pr, e)


@jit_inline
def _lp_cost(Lam, nf, q):
    """Cost of dual variable ``q`` (element ``q // 2``, sign + for even ``q``): the right-hand
    side ``c_i - level_i -+ a_i`` of its primal constraint (level 0 while the element is free)."""
    i = q // 2
    lev = Lam[nf + _R_LEVEL, i]
    c = Lam[nf + _R_MC, i] - (0.0 if np.isnan(lev) else lev)
    return c - Lam[nf + _R_MA, i] if q % 2 == 0 else c + Lam[nf + _R_MA, i]


@jit_inline
def _lp_stage(Lam, n, nf, p, k):
    """One stage of the max-min LP of :func:`_group_optimum`: ``max t`` over ``(z, t)`` with
    ``|a_i + N_i z| <= c_i - t`` for the free elements and ``<= c_i - level_i`` for the held ones,
    solved as its dual (standard form: ``min b^T y``, ``A^T y = e_(k+1)``, ``y >= 0``, one ``y``
    per constraint) by the two-phase simplex; ``(z, t)`` are the dual's simplex multipliers.
    Writes ``z`` into the ``_R_Z`` row, holds the free elements whose dual weight is positive
    (binding at every optimum, by complementary slackness) at level ``t``; returns ``t``."""
    T0 = nf + _R_TAB
    B = nf + _R_BASIS
    R = k + 1
    ny = 2 * p
    C = ny + R
    for r in range(R + 1):
        for q in range(C + 1):
            Lam[T0 + r, q] = 0.0
    for i in range(p):
        f = int(Lam[nf + _R_ELEM, i])
        for r in range(k):
            v = Lam[f, n + int(Lam[nf + _R_COL, r])]
            Lam[T0 + r, 2 * i] = v
            Lam[T0 + r, 2 * i + 1] = -v
        if np.isnan(Lam[nf + _R_LEVEL, i]):
            Lam[T0 + k, 2 * i] = 1.0
            Lam[T0 + k, 2 * i + 1] = 1.0
    for r in range(R):
        Lam[T0 + r, ny + r] = 1.0
        Lam[B, r] = ny + r
    Lam[T0 + k, C] = 1.0
    # phase 1: minimise the sum of the artificial variables (a feasible y exists: any free
    # element's two constraints with weights 1/2)
    for q in range(ny):
        s = 0.0
        for r in range(R):
            s += Lam[T0 + r, q]
        Lam[T0 + R, q] = -s
    Lam[T0 + R, C] = -1.0
    _simplex(Lam, T0, B, R, ny, C, 1e-12)
    for r in range(R):  # artificials left in the basis (at level 0) are pivoted out
        if Lam[B, r] >= ny:
            best = -1
            big = 1e-9
            for q in range(ny):
                if abs(Lam[T0 + r, q]) > big:
                    big = abs(Lam[T0 + r, q])
                    best = q
            if best >= 0:
                _pivot(Lam, T0, B, R, C, r, best)
    # phase 2: the costs b; reduced costs of every column (artificials: cost 0, so that their
    # reduced costs are minus the simplex multipliers)
    bscale = 0.0
    for q in range(ny):
        bscale = max(bscale, abs(_lp_cost(Lam, nf, q)))
    for q in range(C + 1):
        s = 0.0 if q >= ny else _lp_cost(Lam, nf, q)
        if q == C:
            s = 0.0
        for r in range(R):
            bb = int(Lam[B, r])
            if bb < ny:
                s -= _lp_cost(Lam, nf, bb) * Lam[T0 + r, q]
        Lam[T0 + R, q] = s
    _simplex(Lam, T0, B, R, ny, C, 1e-13 * (1.0 + bscale))
    for r in range(k):
        Lam[nf + _R_Z, int(Lam[nf + _R_COL, r])] = -Lam[T0 + R, ny + r]
    t = -Lam[T0 + R, ny + k]
    for r in range(R):
        bb = int(Lam[B, r])
        if bb < ny and Lam[T0 + r, C] > 1e-11:
            i = bb // 2
            if np.isnan(Lam[nf + _R_LEVEL, i]):
                Lam[nf + _R_LEVEL, i] = t
    return t


@jit_nonrt
def _group_optimum(f_static, f_scale, f_uidx, f_table, t_s, t_o, n, u, fm, reg, Lam, tau, g):
    """``m*`` of redundancy group ``g`` (two or more null-space columns ``N``, elements ``i``
    with least-norm torques ``a_i`` and static capacities ``c_i``): the largest smallest margin
    ``max_z min_i (c_i - |a_i + N_i z|)``; the optimal ``z`` into ``Lam``'s ``_R_Z`` row.

    The LP ``max t`` s.t. ``|a_i + N_i z| <= c_i - t``, by the two-phase simplex on its dual
    (:func:`_lp_stage`), exact up to round-off, in ``Lam``'s work space (no allocation). ``m*``
    (the LP's value) is continuous in the state and the inputs. The optimal ``z`` of a
    degenerate LP (ties: some torques free within the optimal margin) is made unique by the
    leximin rule: the elements binding at every optimum are held at ``m*``, the smallest of the
    others' margins is maximised, and so on, until every element is held (at most ``p``
    stages); that point does not depend on the simplex's pivoting. The last group solved is
    remembered with its data ``(a, c)``: the guards ask for every element of the group in turn.
    Compiled once and called (not inlined into every guard), with the arrays of ``ChainData`` it
    needs (``n`` the number of bodies).
    """
    nf = fm.shape[0]
    p = 0
    for f in range(nf):
        if fm[f] == STUCK and Lam[nf + _R_EGROUP, f] == g:
            Lam[nf + _R_ELEM, p] = f
            p += 1
    k = 0
    for j in range(nf):
        if Lam[nf + _R_CGROUP, j] == g:
            Lam[nf + _R_COL, k] = j
            k += 1
    same = Lam[nf + _R_MEMO, 0] == 1.0 and Lam[nf + _R_MEMO, 1] == g
    for i in range(p):
        f = int(Lam[nf + _R_ELEM, i])
        a = _lam0(Lam, tau, n, f)
        c = f_static[f] * _cap(f_scale, f_uidx, f_table, t_s, t_o, f, u, reg)
        if Lam[nf + _R_MA, i] != a or Lam[nf + _R_MC, i] != c:
            same = False
        Lam[nf + _R_MA, i] = a
        Lam[nf + _R_MC, i] = c
    if same:
        return Lam[nf + _R_MEMO, 2]
    for i in range(p):
        Lam[nf + _R_LEVEL, i] = np.nan
    mstar = _lp_stage(Lam, n, nf, p, k)
    for _stage in range(p):
        free = 0
        for i in range(p):
            if np.isnan(Lam[nf + _R_LEVEL, i]):
                free += 1
        if free == 0:
            break
        _lp_stage(Lam, n, nf, p, k)
    Lam[nf + _R_MEMO, 0] = 1.0
    Lam[nf + _R_MEMO, 1] = g
    Lam[nf + _R_MEMO, 2] = mstar
    return mstar


@jit_inline
def stuck_torque(D, u, fm, reg, Lam, tau, f):
    """``(lam, margin)`` of stuck element ``f`` from the forces ``tau`` at ``u`` (regions
    ``reg``) and the extended stuck-torque matrix ``Lam`` of :func:`mode_matrices`: the torque
    [N m or N] it carries and its guard (>= 0 while the stuck set can hold).

    The one definition of the stuck torques (used by the guards, the mode decision's consistency
    test, :func:`stuck_torques`, :func:`powers`, :func:`coupling_torques` and, through
    :func:`stuck_torques_rows`, :mod:`drivetrain_ctrl.sim.series`). A unique stuck torque: the
    least-norm one, margin ``static cap - |lam|``. In a statically indeterminate stuck set, per
    redundancy group (the stuck elements coupled through self-balancing torques; independent
    groups stay independent): the distribution with the largest smallest capacity margin,
    ties broken by the leximin rule, and for every element of the group the group's optimal
    margin ``m*`` as its guard: continuous in the state (an LP's optimal value), so that the
    event locator finds the crossing, and negative exactly when no distribution within the
    capacities exists. A group of one column (a body held by its own ground friction and,
    through a stuck clutch, by another body's) in closed form (:func:`_column_optimum`), a
    coupled group of two or more (three grounded bodies joined by stuck couplings) by the
    simplex (:func:`_group_optimum`).
    """
    n = D.M.shape[0]
    nf = fm.shape[0]
    lam = _lam0(Lam, tau, n, f)
    g = Lam[nf + _R_EGROUP, f]
    if g >= 0.0:
        j = int(g)
        if _group_columns(Lam, nf, g) == 1:
            z, mstar = _column_optimum(D, u, fm, reg, Lam, tau, j)
            return lam + Lam[f, n + j] * z, mstar
        mstar = _group_optimum(
            D.f_static, D.f_scale, D.f_uidx, D.f_table, D.t_s, D.t_o, n, u, fm, reg, Lam, tau, g
        )
        for c in range(nf):
            if Lam[nf + _R_CGROUP, c] == g:
                lam += Lam[f, n + c] * Lam[nf + _R_Z, c]
        return lam, mstar
    cap = _cap(D.f_scale, D.f_uidx, D.f_table, D.t_s, D.t_o, f, u, reg)
    return lam, D.f_static[f] * cap - abs(lam)


@jit_nonrt
def _project_lam(D, x, which, Lam, lamw):
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
def _coupling_stuck(D, which, c):
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
    """Friction torque [N m or N] each stuck element must carry (0 for the others), ``Lam``
    from :func:`mode_matrices` (:func:`stuck_torque`: in a statically indeterminate stuck set
    the distribution with the largest smallest capacity margin)."""
    tau = forces(D, x, u, fm, reg)
    nf = fm.shape[0]
    out = np.zeros(nf)
    for f in range(nf):
        if fm[f] == STUCK:
            out[f] = stuck_torque(D, u, fm, reg, Lam, tau, f)[0]
    return out


@jit
def stuck_torques_rows(D: ChainData, U: F64, fm: I64, REG: I64, Lam: F64, TAU: F64) -> F64:
    """(N, nf) :func:`stuck_torque` of every stuck element at N samples in one friction mode
    ``fm`` (``Lam`` its :func:`mode_matrices`), from the inputs ``U`` (N, nu), regions ``REG``
    (N, nt) and forces ``TAU`` (N, n) of the samples; 0 for the elements not stuck."""
    out = np.empty((TAU.shape[0], fm.shape[0]))
    _stuck_torques_rows_into(D, U, fm, REG, Lam, TAU, out)
    return out


@jit_nonrt
def _stuck_torques_rows_into(D, U, fm, REG, Lam, TAU, out):
    """:func:`stuck_torques_rows` into ``out``, without reference counting (no per-row views'
    bookkeeping): an element outside a redundancy group takes :func:`_lam0` directly (what
    :func:`stuck_torque` does for it, without its margin), the others :func:`stuck_torque`."""
    n = D.M.shape[0]
    nf = fm.shape[0]
    for i in range(TAU.shape[0]):
        for f in range(nf):
            if fm[f] != STUCK:
                out[i, f] = 0.0
            elif Lam[nf + _R_EGROUP, f] < 0.0:
                lam = 0.0
                for k in range(n):
                    lam += Lam[f, k] * TAU[i, k]
                out[i, f] = lam
            else:
                out[i, f] = stuck_torque(D, U[i], fm, REG[i], Lam, TAU[i], f)[0]


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

    Layout: one per friction element (slip: ``min(s w, capacity)``: it stops slipping or opens;
    stuck: static capacity - ``|lam|``, or the optimal margin of its statically indeterminate
    stuck set, :func:`stuck_torque`; open: ``-capacity``), then two per table (distance to the lower and upper bound of the
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
            g[f] = stuck_torque(D, u, fm, reg, Lam, tau, f)[1]
        elif D.f_eps[f] > 0.0:
            g[f] = np.inf
        else:
            # slipping: the slip speed reaching 0, or the capacity reaching 0 (then open)
            sw = w if m == SLIP_POS else -w
            g[f] = sw if sw < cap else cap
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


@jit
def kinetic_torque(D: ChainData, f: int, x: F64, u: F64, fm: I64, reg: I64) -> float:
    """Signed friction torque of a slipping element (tanh law if smoothed) [N m or N]."""
    w = rel_speed(D, f, x)
    F = capacity(D, f, u, reg) * mu_ratio(D, f, x, reg)
    if D.f_eps[f] > 0.0:
        return F * np.tanh(w / D.f_eps[f]) if F > 0.0 else 0.0
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

    Dissipation layout: ``n`` bodies (viscous + quadratic to ground), ``m`` coupling dampers
    (:func:`damper_coefficient` times ``w^2``: 0 in the gap of a damper that acts only in
    contact), ``nf`` friction elements (kinetic torque times slip speed; stuck/open: 0).
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
        pd[n + c] = damper_coefficient(D, c, reg) * w * w
    lam = stuck_torques(D, x, u, fm, reg, Lam)
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
        d = damper_coefficient(D, c, reg)
        row = np.zeros(nx)
        row[c] += d
        row[c + 1] -= d * r_c
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
        T = damper_coefficient(D, c, reg) * w
        kt = D.c_table[c]
        if kt >= 0:
            T += table_value(D, kt, reg[kt], x[D.c_q[c]])
        out[c] = T
    lam = stuck_torques(D, x, u, fm, reg, Lam)
    for f in range(D.f_kind.shape[0]):
        if D.f_kind[f] != 0:
            continue
        c = D.f_idx[f]
        if fm[f] == STUCK:
            out[c] += lam[f]
        elif fm[f] == SLIP_POS or fm[f] == SLIP_NEG:
            out[c] += kinetic_torque(D, f, x, u, fm, reg)
    return out
