"""Per-sample physics over a whole recorded run at once (numpy, no Python loop over samples).

A study keeps one record of figures of merit per run, and the figures need quantities the
integrator does not record: the state derivatives at every sample (accelerations, jerk, lurch)
and the torque of every coupling (driveline torques, torque match). Evaluating them row by row
through the compiled single-point kernels costs a Python call, a mode object and a ``P`` matrix
per sample (about 50-80 us each: 0.3-0.6 s for a 3-s run of the full model, 20-40 times the
simulation itself). Here the same formulas as
:func:`~drivetrain_ctrl.kernels.physics.forces_into`, :func:`~drivetrain_ctrl.kernels.physics.rhs`
and :func:`~drivetrain_ctrl.kernels.physics.coupling_torques` are written on columns of all
samples, and the mode matrices ``P``, ``Lam`` are computed once per distinct stick/slip
combination. :class:`RunSeries` holds one run's arrays and computes each of these quantities
at most once (the forces, the slip torques, the mode grouping and matrices are shared by the state
derivatives and the coupling torques of :func:`~drivetrain_ctrl.sim.metrics.engagement_metrics`);
the module functions are one-shot uses of it. The stuck torques are not re-implemented: the compiled
:func:`~drivetrain_ctrl.kernels.physics.stuck_torques_rows` (the kernel's
:func:`~drivetrain_ctrl.kernels.physics.stuck_torque` on every row of a mode) gives them from the
forces computed here, the most feasible distribution in a statically indeterminate stuck set
included. The values equal the single-point kernels' to round-off (the sums run in another
order); the tests compare them on the built-in scenarios.

All arrays are in SI units: ``X`` (N, nx) states, ``U`` (N, nu) inputs, ``FM`` (N, nf) friction
mode codes, ``REG`` (N, nt) table regions (the layout of a
:class:`~drivetrain_ctrl.sim.simulator.SimulationResult`), ``D`` the model's
:class:`~drivetrain_ctrl.kernels.physics.ChainData`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import kernels as K
from ..kernels.physics import ChainData

__all__ = ["RunSeries", "body_forces", "coupling_torques", "state_derivatives", "stored_energy"]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


def _slip_torques(D: ChainData, X: F64, U: F64, FM: I64, REG: I64) -> F64:
    """(N, nf) signed kinetic torque of every friction element where it slips, 0 elsewhere
    (:func:`~drivetrain_ctrl.kernels.physics.kinetic_torque`, tanh law if smoothed)."""
    N = X.shape[0]
    nf = D.f_kind.shape[0]
    out = np.zeros((N, nf))
    for f in range(nf):
        m = FM[:, f]
        slip = (m == K.SLIP_POS) | (m == K.SLIP_NEG)
        if not np.any(slip):
            continue
        i = int(D.f_idx[f])
        w = X[:, i] - D.ratio[i] * X[:, i + 1] if D.f_kind[f] == 0 else X[:, i]
        F = np.full(N, float(D.f_scale[f]))
        ui = int(D.f_uidx[f])
        if ui >= 0:
            kt = int(D.f_table[f])
            if kt < 0:
                F = F * U[:, ui]
            else:
                r = REG[:, kt]
                F = F * (D.t_s[kt, r] * U[:, ui] + D.t_o[kt, r])
        kmu = int(D.f_mu[f])
        if kmu >= 0:
            r = REG[:, kmu]
            F = F * (D.t_s[kmu, r] * np.abs(w) + D.t_o[kmu, r])
        if D.f_eps[f] > 0.0:
            F = np.where(F > 0.0, F * np.tanh(w / D.f_eps[f]), 0.0)
        else:
            F = np.where(m == K.SLIP_NEG, -F, F)
        out[:, f] = np.where(slip, F, 0.0)
    return out


def _body_forces(s: RunSeries) -> F64:
    """(N, n) generalised torques on the bodies of :func:`body_forces`, from ``s``'s shared
    spring-damper and slip torques."""
    D, X, U, REG = s.D, s.X, s.U, s.REG
    n = D.M.shape[0]
    w = X[:, :n]
    tau = -D.visc * w - D.quad * w * np.abs(w) + D.load
    for i in range(n):
        if D.b_uidx[i] >= 0:
            tau[:, i] += D.b_ugain[i] * U[:, D.b_uidx[i]]
    for j in range(D.l_body.shape[0]):
        b = int(D.l_body[j])
        kt = int(D.l_table[j])
        g: F64 | float = float(D.l_gain[j])
        if kt >= 0:
            r = REG[:, kt]
            g = g * (D.t_s[kt, r] * X[:, b] + D.t_o[kt, r])
        tau[:, b] += g * X[:, D.l_x[j]]
    for c in range(D.ratio.shape[0]):
        T = s.spring_damper(c)
        tau[:, c] -= T
        tau[:, c + 1] += D.ratio[c] * T
    F = s.slip_torques()
    for f in range(D.f_kind.shape[0]):
        i = int(D.f_idx[f])
        tau[:, i] -= F[:, f]
        if D.f_kind[f] == 0:
            tau[:, i + 1] += D.ratio[i] * F[:, f]
    return np.asarray(tau, dtype=float)


def _spring_damper(D: ChainData, X: F64, REG: I64, c: int) -> F64:
    """(N,) torque of coupling ``c``'s spring and damper [N m] (upstream frame). The damper is
    off where the spring is in region ``c_gap[c]``: the gap of a damper that acts only in
    contact (:func:`~drivetrain_ctrl.kernels.physics.damper_coefficient`)."""
    T = D.damp[c] * (X[:, c] - D.ratio[c] * X[:, c + 1])
    kt = int(D.c_table[c])
    if D.c_gap[c] >= 0:
        T = np.where(REG[:, kt] == D.c_gap[c], 0.0, T)
    if kt >= 0:
        r = REG[:, kt]
        T = T + (D.t_s[kt, r] * X[:, D.c_q[c]] + D.t_o[kt, r])
    return np.asarray(T, dtype=float)


def _mode_groups(FM: I64) -> tuple[I64, I64]:
    """(distinct friction-mode rows, index of each sample's row among them).

    The rows are encoded as integers in base 4 (a mode code is 0..3), so the grouping is a 1-D
    :func:`numpy.unique` (``unique(axis=0)`` sorts rows lexicographically, several times slower).
    """
    nf = FM.shape[1]
    if nf == 0:
        return np.zeros((1, 0), dtype=np.int64), np.zeros(FM.shape[0], dtype=np.int64)
    if nf > 30:  # beyond int64 in base 4: group the rows themselves
        modes, inverse = np.unique(FM, axis=0, return_inverse=True)
        return modes, np.asarray(inverse, dtype=np.int64).reshape(-1)
    key = FM.astype(np.int64) @ (np.int64(4) ** np.arange(nf, dtype=np.int64))
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return np.asarray(FM[first], dtype=np.int64), np.asarray(inverse, dtype=np.int64).reshape(-1)


def _state_derivatives(s: RunSeries) -> F64:
    """(N, nx) state derivatives of :func:`state_derivatives`, from ``s``'s shared forces and
    mode matrices."""
    D, X, U = s.D, s.X, s.U
    N = X.shape[0]
    n = D.M.shape[0]
    out = np.zeros((N, X.shape[1]))
    tau = s.body_forces()
    modes, _inv = s.mode_groups()
    order, starts = s.group_order()
    tau_s = tau[order]  # the samples grouped by mode: one gather, then slices
    acc_s = np.empty((N, n))
    for g in range(modes.shape[0]):
        P, _ = s.mode_matrices(g)
        rows = slice(int(starts[g]), int(starts[g + 1]))
        acc_s[rows] = tau_s[rows] @ P.T
    out[order, :n] = acc_s
    for i in range(n):
        if D.b_pos[i] >= 0:
            out[:, D.b_pos[i]] = X[:, i]
    for c in range(D.ratio.shape[0]):
        if D.c_q[c] >= 0:
            out[:, D.c_q[c]] = X[:, c] - D.ratio[c] * X[:, c + 1]
    for j in range(D.l_body.shape[0]):
        out[:, D.l_x[j]] = (U[:, D.l_uidx[j]] - X[:, D.l_x[j]]) / D.l_tau[j]
    return out


def _coupling_torques(s: RunSeries) -> F64:
    """(N, m) coupling torques of :func:`coupling_torques`, from ``s``'s shared spring-damper
    and slip torques, forces and mode matrices."""
    D, X, U, FM, REG = s.D, s.X, s.U, s.FM, s.REG
    N = X.shape[0]
    m = D.ratio.shape[0]
    out = np.empty((N, m))
    for c in range(m):
        out[:, c] = s.spring_damper(c)
    coupled = [f for f in range(D.f_kind.shape[0]) if D.f_kind[f] == 0]
    if not coupled:
        return out
    stuck = FM == K.STUCK
    lam = np.zeros(FM.shape, dtype=float)
    if np.any(stuck[:, coupled]):
        tau = s.body_forces()
        modes, _inv = s.mode_groups()
        order, starts = s.group_order()
        # the samples grouped by mode (one gather each, then contiguous slices)
        U_s = np.ascontiguousarray(U[order], dtype=float)
        REG_s = np.ascontiguousarray(REG[order], dtype=np.int64)
        tau_s = np.ascontiguousarray(tau[order], dtype=float)
        lam_s = np.zeros(FM.shape, dtype=float)
        for g in range(modes.shape[0]):
            if not np.any(modes[g] == K.STUCK):
                continue
            fm = np.ascontiguousarray(modes[g], dtype=np.int64)
            _, Lam = s.mode_matrices(g)
            rows = slice(int(starts[g]), int(starts[g + 1]))
            # the kernel's one definition of the stuck torques (not a numpy re-implementation):
            # in a statically indeterminate stuck set the distribution is an LP's solution
            lam_s[rows] = K.stuck_torques_rows(D, U_s[rows], fm, REG_s[rows], Lam, tau_s[rows])
        lam[order] = lam_s
    F = s.slip_torques()
    for f in coupled:
        c = int(D.f_idx[f])
        out[:, c] += np.where(stuck[:, f], lam[:, f], F[:, f])
    return out


class RunSeries:
    """One run's arrays ``D``, ``X``, ``U``, ``FM``, ``REG`` and the per-sample quantities of
    this module over them, each computed at most once (on first use) and then shared: the body
    forces, slip and spring-damper torques, the mode grouping and each group's ``P``, ``Lam``,
    the state derivatives and the coupling torques. The values are those of the module
    functions (which are one-shot uses of it). The returned arrays are the cached ones: do not
    modify them. Build one per result (and per ``D``: a smoothed run's coupling torques use its
    smoothed data); it is not keyed on anything global.
    """

    def __init__(self, D: ChainData, X: F64, U: F64, FM: I64, REG: I64) -> None:
        self.D = D
        self.X = X
        self.U = U
        self.FM = FM
        self.REG = REG
        self._slip: F64 | None = None
        self._springs: dict[int, F64] = {}
        self._forces: F64 | None = None
        self._groups: tuple[I64, I64] | None = None
        self._order: tuple[I64, I64] | None = None
        self._matrices: dict[int, tuple[F64, F64]] = {}
        self._derivatives: F64 | None = None
        self._couplings: F64 | None = None

    def slip_torques(self) -> F64:
        """(N, nf) signed kinetic torque of every slipping friction element [N m], 0 elsewhere."""
        if self._slip is None:
            self._slip = _slip_torques(self.D, self.X, self.U, self.FM, self.REG)
        return self._slip

    def spring_damper(self, c: int) -> F64:
        """(N,) torque of coupling ``c``'s spring and damper [N m] (upstream frame)."""
        T = self._springs.get(c)
        if T is None:
            T = self._springs[c] = _spring_damper(self.D, self.X, self.REG, c)
        return T

    def body_forces(self) -> F64:
        """(N, n) generalised torques on the bodies (:func:`body_forces`)."""
        if self._forces is None:
            self._forces = _body_forces(self)
        return self._forces

    def mode_groups(self) -> tuple[I64, I64]:
        """(distinct friction-mode rows, index of each sample's row among them)."""
        if self._groups is None:
            self._groups = _mode_groups(self.FM)
        return self._groups

    def at(self, rows: I64, mode_rows: I64) -> RunSeries:
        """The series of the states and inputs of ``rows`` in the modes (friction modes and
        table regions) of ``mode_rows``, e.g. the samples after events in the modes before them;
        it shares this series' mode groups and their matrices (``mode_rows`` are samples of
        this run)."""
        sub = RunSeries(self.D, self.X[rows], self.U[rows], self.FM[mode_rows], self.REG[mode_rows])
        modes, inv = self.mode_groups()
        sub._groups = (modes, inv[mode_rows])
        sub._matrices = self._matrices  # group g is the same mode in both
        return sub

    def group_order(self) -> tuple[I64, I64]:
        """``(order, starts)``: the samples sorted by mode group (stable: in time within a
        group) and where each group starts in that order (``starts[g]:starts[g + 1]``)."""
        if self._order is None:
            modes, inv = self.mode_groups()
            order = np.argsort(inv, kind="stable")
            starts = np.zeros(modes.shape[0] + 1, dtype=np.int64)
            np.cumsum(np.bincount(inv, minlength=modes.shape[0]), out=starts[1:])
            self._order = (np.asarray(order, dtype=np.int64), starts)
        return self._order

    def mode_matrices(self, g: int) -> tuple[F64, F64]:
        """``(P, Lam)`` of mode group ``g`` of :meth:`mode_groups`
        (:func:`~drivetrain_ctrl.kernels.physics.mode_matrices`)."""
        PL = self._matrices.get(g)
        if PL is None:
            fm = np.ascontiguousarray(self.mode_groups()[0][g], dtype=np.int64)
            P, Lam = K.mode_matrices(self.D, fm)
            PL = self._matrices[g] = (P, Lam)
        return PL

    def state_derivatives(self) -> F64:
        """(N, nx) state derivative at every sample (:func:`state_derivatives`)."""
        if self._derivatives is None:
            self._derivatives = _state_derivatives(self)
        return self._derivatives

    def coupling_torques(self) -> F64:
        """(N, m) total torque of every coupling [N m] (:func:`coupling_torques`)."""
        if self._couplings is None:
            self._couplings = _coupling_torques(self)
        return self._couplings


def body_forces(D: ChainData, X: F64, U: F64, FM: I64, REG: I64) -> F64:
    """(N, n) generalised torques on the bodies [N m or N] at every sample, without the stuck
    (constraint) torques: :func:`~drivetrain_ctrl.kernels.physics.forces` on every row."""
    return RunSeries(D, X, U, FM, REG).body_forces()


def state_derivatives(D: ChainData, X: F64, U: F64, FM: I64, REG: I64) -> F64:
    """(N, nx) state derivative at every sample in the mode given for it (row ``k`` is
    :meth:`Model.rhs(X[k], U[k], Mode(FM[k], REG[k])) <drivetrain_ctrl.plant.model.Model.rhs>`),
    in state units per second."""
    return RunSeries(D, X, U, FM, REG).state_derivatives()


def coupling_torques(D: ChainData, X: F64, U: F64, FM: I64, REG: I64) -> F64:
    """(N, m) total torque of every coupling [N m] (upstream frame) at every sample: spring,
    damper and friction, a stuck friction's constraint torque included
    (:func:`~drivetrain_ctrl.kernels.physics.coupling_torques` on every row)."""
    return RunSeries(D, X, U, FM, REG).coupling_torques()


def stored_energy(D: ChainData, X: F64) -> F64:
    """(N,) stored energy [J] at every sample: kinetic, elastic (the integral of each spring
    law, its region taken from the twist) and potential
    (:func:`~drivetrain_ctrl.kernels.physics.stored_energy` on every row)."""
    n = D.M.shape[0]
    w = X[:, :n]
    E = np.sum(0.5 * D.M * w * w, axis=1)
    for i in range(n):
        if D.b_pos[i] >= 0:
            E -= D.load[i] * X[:, D.b_pos[i]]
    for c in range(D.ratio.shape[0]):
        k = int(D.c_table[c])
        if k >= 0:
            q = X[:, D.c_q[c]]
            r = np.searchsorted(D.t_b[k, : int(D.t_nb[k])], q, side="left")
            E += 0.5 * D.t_s[k, r] * q * q + D.t_o[k, r] * q + D.t_e[k, r]
    return np.asarray(E, dtype=float)
