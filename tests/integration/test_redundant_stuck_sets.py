"""Statically indeterminate stuck sets (issue 19, finding b).

A body held by two stuck paths (its own ground friction and, through a stuck clutch, another
body's ground friction) has stuck torques that are not unique. The kernels take the
distribution with the largest smallest capacity margin (``physics.stuck_torque``); the
decision, the guards, ``Model.stuck_torques`` and ``sim.series`` all use it. Checked here:
against ``scipy.optimize.linprog`` on the same LP, the break-away time of a ramped torque
against its closed form, the energy balance, and the series against the single-point kernels.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linprog

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction, Spring
from drivetrain_ctrl.plant.model import Mode, Model
from drivetrain_ctrl.sim import series
from drivetrain_ctrl.sim.simulator import simulate
from drivetrain_ctrl.testing.reference import max_min_stuck_torques

#: ramp slope of the driving torque [N m/s]
SLOPE = 1.0


def _held_twice(c0: float, cf: float, c1: float, ratio: float) -> Model:
    """b0 (torque input T) held by its ground friction g0 (capacity c0) and, through clutch f
    (capacity cf, ratio ``ratio``), by b1's ground friction g1 (capacity c1)."""
    bodies = (
        Body("b0", 1.0, torque_input="T", ground_friction=Friction(scale=c0, name="g0")),
        Body("b1", 2.0, ground_friction=Friction(scale=c1, name="g1")),
    )
    couplings = (Coupling("c", ratio=ratio, friction=Friction(scale=cf, name="f")),)
    return Model(Chain(bodies, couplings, inputs=("T",)))


def _linprog_stuck_torques(m: Model, x: np.ndarray, u: np.ndarray, mode: Mode) -> tuple:
    """Max-min capacity margin distribution by scipy's LP on the equilibrium equations
    ``S lam = G M^-1 tau`` (all the stuck torques that give the mode's accelerations), from
    scratch: ``(lam of the stuck elements, optimal margin, least-norm lam)``."""
    D = m.data
    fm, reg = mode.arrays()
    stuck = np.flatnonzero(fm == K.STUCK)
    G = K.constraint_rows(D, fm, (fm == K.STUCK).astype(np.int64))
    tau = K.forces(D, x, u, fm, reg)
    Minv = np.diag(1.0 / D.M)
    S = G @ Minv @ G.T
    rhs = G @ Minv @ tau
    assert np.all(D.f_uidx[stuck] < 0)  # constant capacities here: static ratio times scale
    lim = D.f_static[stuck] * D.f_scale[stuck]
    k = stuck.shape[0]
    # variables [lam (k), t]: maximise t with t <= lim_f - |lam_f|
    c = np.zeros(k + 1)
    c[-1] = -1.0
    A_ub = np.zeros((2 * k, k + 1))
    for i in range(k):
        A_ub[2 * i, i], A_ub[2 * i, -1] = 1.0, 1.0
        A_ub[2 * i + 1, i], A_ub[2 * i + 1, -1] = -1.0, 1.0
    b_ub = np.repeat(lim, 2)
    A_eq = np.hstack([S, np.zeros((k, 1))])
    sol = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=rhs, bounds=[(None, None)] * (k + 1))
    assert sol.status == 0, sol.message
    return sol.x[:k], sol.x[-1], np.linalg.pinv(S) @ rhs


@pytest.mark.parametrize("T", [0.3, 1.2, 1.7])
def test_decide_and_stuck_torques_match_linprog(T: float) -> None:
    """Model.decide keeps the set stuck while some distribution holds it; Model.stuck_torques and
    the guards are scipy's max-min LP solution. At T = 1.7 N m the least-norm distribution
    loads g0 beyond its 1 N m (the old decision broke away there)."""
    m = _held_twice(c0=1.0, cf=0.8, c1=2.0, ratio=2.0)
    u = np.array([T])
    mode, x = m.decide(np.zeros(m.nx), u)
    names = m.mode_names(mode)
    assert [names[f] for f in ("g0", "f", "g1")] == ["stuck"] * 3
    got = m.stuck_torques(x, u, mode)
    lam, margin, lam_ln = _linprog_stuck_torques(m, x, u, mode)
    stuck = [fi.name for f, fi in enumerate(m.frictions) if mode.fm[f] == K.STUCK]
    np.testing.assert_allclose([got[nm] for nm in stuck], lam, rtol=1e-9, atol=1e-12)
    # every element of the redundancy guards with the set's optimal margin
    g = m.guards(x, u, mode)
    np.testing.assert_allclose(g[: len(m.frictions)], margin, rtol=1e-9, atol=1e-12)
    if T == 1.7:
        ln = dict(zip(stuck, lam_ln, strict=True))
        assert abs(ln["g0"]) > 1.0 + 1e-3  # least-norm: beyond g0's capacity
        assert margin > 0.0


def test_two_independent_redundancies_each_exact() -> None:
    """Two held-twice pairs joined by a spring (two null-space columns, disjoint supports): each
    pair is its own one-dimensional LP, solved exactly (scipy on that pair's margins); each
    element guards with its own pair's optimal margin."""
    fr = lambda nm, s: Friction(scale=s, name=nm)  # noqa: E731
    bodies = (
        Body("b0", 1.0, torque_input="T", ground_friction=fr("g0", 1.0)),
        Body("b1", 1.5, ground_friction=fr("g1", 0.7)),
        Body("b2", 0.5, ground_friction=fr("g2", 0.4)),
        Body("b3", 1.0, torque_input="T3", ground_friction=fr("g3", 3.0)),
    )
    couplings = (
        Coupling("c0", ratio=0.5, friction=fr("f0", 0.3)),
        Coupling("c1", spring=Spring.linear(10.0, name="k1")),
        Coupling("c2", ratio=3.0, friction=fr("f2", 2.0)),
    )
    m = Model(Chain(bodies, couplings, inputs=("T", "T3")))
    u = np.array([1.1, -1.9])
    x = np.zeros(m.nx)
    x[4] = 0.01  # the spring's twist: a torque on b1 and b2
    mode, x = m.decide(x, u)
    assert set(m.mode_names(mode).values()) == {"stuck"}
    got = m.stuck_torques(x, u, mode)
    g = m.guards(x, u, mode)
    order = [fi.name for fi in m.frictions]
    stuck = [nm for f, nm in enumerate(order) if mode.fm[f] == K.STUCK]
    margins = []
    for names in (("g0", "f0", "g1"), ("f2", "g2", "g3")):
        lam, margin = _pair_lp(m, x, u, mode, [stuck.index(nm) for nm in names])
        np.testing.assert_allclose([got[nm] for nm in names], lam, rtol=1e-9, atol=1e-12)
        for nm in names:
            assert g[order.index(nm)] == pytest.approx(margin, rel=1e-9, abs=1e-12)
        margins.append(margin)
    assert abs(margins[0] - margins[1]) > 0.1  # two groups, two different margins


def _pair_lp(m: Model, x: np.ndarray, u: np.ndarray, mode: Mode, sel: list) -> tuple:
    """scipy's max-min LP over the margins of the stuck rows ``sel`` only (the other stuck
    torques free within the equilibrium): ``(lam of rows sel, optimal margin)``."""
    D = m.data
    fm, reg = mode.arrays()
    stuck = np.flatnonzero(fm == K.STUCK)
    G = K.constraint_rows(D, fm, (fm == K.STUCK).astype(np.int64))
    tau = K.forces(D, x, u, fm, reg)
    Minv = np.diag(1.0 / D.M)
    S = G @ Minv @ G.T
    rhs = G @ Minv @ tau
    assert np.all(D.f_uidx[stuck] < 0)  # constant capacities here: static ratio times scale
    lim = D.f_static[stuck] * D.f_scale[stuck]
    k = stuck.shape[0]
    c = np.zeros(k + 1)
    c[-1] = -1.0
    A_ub = np.zeros((2 * len(sel), k + 1))
    for r, i in enumerate(sel):
        A_ub[2 * r, i], A_ub[2 * r, -1] = 1.0, 1.0
        A_ub[2 * r + 1, i], A_ub[2 * r + 1, -1] = -1.0, 1.0
    b_ub = np.repeat(lim[sel], 2)
    A_eq = np.hstack([S, np.zeros((k, 1))])
    sol = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=rhs, bounds=[(None, None)] * (k + 1))
    assert sol.status == 0, sol.message
    return sol.x[sel], sol.x[-1]


@pytest.mark.parametrize(
    ("cf", "c1", "slipping"),
    [
        (0.8, 2.0, {"g0", "f"}),  # the clutch path gives way: b0 breaks away alone
        (0.8, 1.2, {"g0", "g1"}),  # b1's ground friction gives way: b0 and b1 move together
    ],
)
def test_ramp_breaks_away_at_the_sum_of_the_path_capacities(
    cf: float, c1: float, slipping: set
) -> None:
    """T = SLOPE t on b0: the set holds until T reaches c0 + min(cf, c1 / ratio) (the two paths'
    capacities in b0's frame), not before (the least-norm distribution broke away earlier), with
    no inconsistent decision; the energy balance holds and the series pins the kernels."""
    c0, ratio = 1.0, 2.0
    m = _held_twice(c0, cf, c1, ratio)
    t_star = (c0 + min(cf, c1 / ratio)) / SLOPE
    t_end = t_star + 0.2
    res = simulate(m, np.zeros(m.nx), {"T": sg.ramp(0.0, t_end, 0.0, SLOPE * t_end)}, t_end=t_end)
    assert res.status == "ok"
    assert res.stats["inconsistent_decisions"] == 0
    first = res.events[0].t
    assert first == pytest.approx(t_star, abs=1e-7)
    at_first = {e.element for e in res.events if e.t == first and e.from_mode == "stuck"}
    assert at_first == slipping
    # before the break-away all three stuck, their torques within the capacities
    caps = {"g0": c0, "f": cf, "g1": c1}
    for k in np.flatnonzero(res.t < first):
        mode = Mode(tuple(res.fm[k]), tuple(res.reg[k]))
        lam = m.stuck_torques(res.x[k], res.u[k], mode)
        assert set(lam) == {"g0", "f", "g1"}
        for nm, v in lam.items():
            assert abs(v) <= caps[nm] + 1e-9
    # the energy balance
    E = res.stored_energy()
    resid = abs(E[-1] - E[0] - res.work_in[-1] + res.dissipated[-1].sum())
    assert resid <= 1e-6 * max(abs(res.work_in[-1]), np.abs(E).max(), 1e-3)
    # the series' coupling torque (a stuck clutch's: the LP's) equals the single-point kernels'
    D = m.data
    jf = [fi.name for fi in m.frictions].index("f")
    Tc = series.coupling_torques(D, res.x, res.u, res.fm, res.reg)
    for k in range(res.t.shape[0]):
        _, Lam = K.mode_matrices(D, res.fm[k])
        ref = K.coupling_torques(D, res.x[k], res.u[k], res.fm[k], res.reg[k], Lam)
        assert Tc[k, 0] == pytest.approx(ref[0], rel=1e-12, abs=1e-12)
        mode = Mode(tuple(res.fm[k]), tuple(res.reg[k]))
        if res.fm[k, jf] == K.STUCK and res.t[k] < first:
            assert Tc[k, 0] == pytest.approx(m.stuck_torques(res.x[k], res.u[k], mode)["f"])


def _three_held(c0: float, c01: float, c1: float, c12: float, c2: float) -> Model:
    """b0 (torque input T) held by its ground friction g0 and, through clutch f01, by b1 (ground
    friction g1) and, through clutch f12, by b2 (ground friction g2): five stuck elements on
    three bodies, a coupled redundancy of dimension two."""
    fr = lambda nm, s: Friction(scale=s, name=nm)  # noqa: E731
    bodies = (
        Body("b0", 1.0, torque_input="T", ground_friction=fr("g0", c0)),
        Body("b1", 1.0, ground_friction=fr("g1", c1)),
        Body("b2", 1.0, ground_friction=fr("g2", c2)),
    )
    couplings = (Coupling("c0", friction=fr("f01", c01)), Coupling("c1", friction=fr("f12", c12)))
    return Model(Chain(bodies, couplings, inputs=("T",)))


def _reference(m: Model, x: np.ndarray, u: np.ndarray, mode: Mode) -> tuple:
    """The flat reference's leximin LP (scipy) on hand-made ``M``, ``G`` and forces (the
    models here are at rest with only their torque inputs acting): ``(lam, m*)``."""
    D = m.data
    fm = np.array(mode.fm, dtype=np.int64)
    stuck = np.flatnonzero(fm == K.STUCK)
    assert np.all(x[: m.n_bodies] == 0.0)
    n = m.n_bodies
    G = np.zeros((stuck.shape[0], n))
    for r, f in enumerate(stuck):
        i = D.f_idx[f]
        G[r, i] = 1.0
        if D.f_kind[f] == 0:
            G[r, i + 1] = -D.ratio[i]
    tau = np.zeros(n)
    for i in range(n):
        if D.b_uidx[i] >= 0:
            tau[i] = D.b_ugain[i] * u[D.b_uidx[i]]
    limits = D.f_static[stuck] * D.f_scale[stuck]
    return max_min_stuck_torques(np.diag(1.0 / D.M), G, tau, limits)


def _optimal_set_is_a_point(m: Model, x: np.ndarray, u: np.ndarray, mode: Mode) -> bool:
    """True if the max-min LP has one optimal distribution (no ties): every stuck torque's
    smallest and largest value over the optimal set (scipy) agree."""
    D = m.data
    fm, reg = mode.arrays()
    stuck = np.flatnonzero(fm == K.STUCK)
    _lam, margin, _ = _linprog_stuck_torques(m, x, u, mode)
    G = K.constraint_rows(D, fm, (fm == K.STUCK).astype(np.int64))
    tau = K.forces(D, x, u, fm, reg)
    Minv = np.diag(1.0 / D.M)
    k = stuck.shape[0]
    lim = D.f_static[stuck] * D.f_scale[stuck] - margin + 1e-12
    A_ub = np.vstack([np.eye(k), -np.eye(k)])
    b_ub = np.concatenate([lim, lim])
    spans = []
    for i in range(k):
        c = np.zeros(k)
        c[i] = 1.0
        lo = linprog(
            c,
            A_ub=A_ub,
            b_ub=b_ub,
            A_eq=G @ Minv @ G.T,
            b_eq=G @ Minv @ tau,
            bounds=[(None, None)] * k,
        )
        hi = linprog(
            -c,
            A_ub=A_ub,
            b_ub=b_ub,
            A_eq=G @ Minv @ G.T,
            b_eq=G @ Minv @ tau,
            bounds=[(None, None)] * k,
        )
        spans.append(hi.x[i] - lo.x[i])
    return max(spans) < 1e-6


#: (c0, c01, c1, c12, c2): three capacity sets of the two-dimensional case; the third has ties
THREE_HELD = [(1.0, 2.0, 1.0, 1.0, 1.0), (1.0, 1.5, 1.0, 1.0, 1.0), (1.0, 2.0, 1.0, 10.0, 10.0)]


@pytest.mark.parametrize("caps", THREE_HELD)
@pytest.mark.parametrize("T", [0.4, 1.7, 2.4, -2.2])
def test_two_dimensional_redundancy_matches_linprog(caps: tuple, T: float) -> None:
    """A coupled redundancy of dimension two: the guards of all five elements are scipy's
    max-min LP optimum m*, and the stuck torques are the flat reference's leximin solution
    (scipy, on hand-made matrices): scipy's LP solution itself where the optimum is unique."""
    m = _three_held(*caps)
    u = np.array([T])
    mode, x = m.decide(np.zeros(m.nx), u)
    assert set(m.mode_names(mode).values()) == {"stuck"}
    _D, Lam = K.mode_matrices(m.data, np.array(mode.fm, dtype=np.int64))
    n, nf = m.n_bodies, len(m.frictions)
    assert np.count_nonzero(np.any(Lam[:nf, n : n + nf] != 0.0, axis=0)) == 2  # k = 2
    got = m.stuck_torques(x, u, mode)
    lam, margin, _ = _linprog_stuck_torques(m, x, u, mode)
    g = m.guards(x, u, mode)
    np.testing.assert_allclose(g[:nf], margin, rtol=1e-9, atol=1e-12)
    names = [fi.name for fi in m.frictions]
    ref, ref_margin = _reference(m, x, u, mode)
    assert ref_margin == pytest.approx(margin, rel=1e-7, abs=1e-9)
    np.testing.assert_allclose([got[nm] for nm in names], ref, rtol=1e-7, atol=1e-9)
    if _optimal_set_is_a_point(m, x, u, mode):
        np.testing.assert_allclose([got[nm] for nm in names], lam, rtol=1e-7, atol=1e-9)
    # whichever: an equilibrium within the capacities less the optimal margin
    c0, c01, c1, c12, c2 = caps
    caps_of = {"g0": c0, "f01": c01, "g1": c1, "f12": c12, "g2": c2}
    for nm, v in got.items():
        assert abs(v) <= caps_of[nm] - margin + 1e-9


def test_ties_are_exercised_and_the_leximin_torques_are_continuous() -> None:
    """The third capacity set has ties (g1's torque is free within the optimal margin at
    T = 1.7 N m): the leximin rule picks one, and along a fine sweep of T the torques change
    by no more than the load does (no jump between optimal vertices)."""
    m = _three_held(*THREE_HELD[2])
    mode, x = m.decide(np.zeros(m.nx), np.array([1.7]))
    assert not _optimal_set_is_a_point(m, x, np.array([1.7]), mode)
    names = [fi.name for fi in m.frictions]
    Ts = np.linspace(-2.9, 2.9, 1161)
    lam = np.array([[m.stuck_torques(x, np.array([T]), mode)[nm] for nm in names] for T in Ts])
    steps = np.abs(np.diff(lam, axis=0)).max(axis=1) / np.diff(Ts)
    assert steps.max() <= 1.0 + 1e-6


def test_coupled_two_dimensional_redundancy_holds_within_capacities() -> None:
    """b0 (2.5 N m) held by g0, g1, g2 (1 N m each) through f01 (2 N m) and f12 (1 N m): g0 1,
    f01 1.5, g1 0.75, f12 = g2 0.75 holds, but the least-norm distribution puts 5/8 of the
    torque (1.56 N m) on g0. The max-min one: 5/6 on each ground friction."""
    m = _three_held(*THREE_HELD[0])
    u = np.array([2.5])
    mode, x = m.decide(np.zeros(m.nx), u)
    assert set(m.mode_names(mode).values()) == {"stuck"}
    lam, margin, lam_ln = _linprog_stuck_torques(m, x, u, mode)
    assert margin >= 0.0
    got = m.stuck_torques(x, u, mode)
    stuck = [fi.name for f, fi in enumerate(m.frictions) if mode.fm[f] == K.STUCK]
    np.testing.assert_allclose([got[nm] for nm in stuck], lam, rtol=1e-9, atol=1e-12)
    assert abs(dict(zip(stuck, lam_ln, strict=True))["g0"]) > 1.5
    for nm in ("g0", "g1", "g2"):
        assert abs(got[nm]) == pytest.approx(2.5 / 3.0, rel=1e-12)


@pytest.mark.parametrize(
    ("caps", "slipping"),
    [
        ((1.0, 1.5, 1.0, 1.0, 1.0), {"g0", "f01"}),  # f01 gives way: b0 breaks away alone
        ((1.0, 3.0, 1.0, 0.5, 1.0), {"g0", "g1", "f12"}),  # f12 gives way: b0, b1 together
    ],
)
def test_ramp_breaks_away_from_a_two_dimensional_set(caps: tuple, slipping: set) -> None:
    """T = SLOPE t on b0 of the three-body set: it holds until T reaches
    c0 + min(c01, c1 + min(c12, c2)) (the paths' capacities in series and parallel), with no
    inconsistent decision, every torque within its capacity before; the energy balance holds
    and the series pins the kernels."""
    c0, c01, c1, c12, c2 = caps
    m = _three_held(*caps)
    t_star = (c0 + min(c01, c1 + min(c12, c2))) / SLOPE
    t_end = t_star + 0.2
    res = simulate(m, np.zeros(m.nx), {"T": sg.ramp(0.0, t_end, 0.0, SLOPE * t_end)}, t_end=t_end)
    assert res.status == "ok"
    assert res.stats["inconsistent_decisions"] == 0
    first = res.events[0].t
    assert first == pytest.approx(t_star, abs=1e-7)
    at_first = {e.element for e in res.events if e.t == first and e.from_mode == "stuck"}
    assert at_first == slipping
    cap_of = {"g0": c0, "f01": c01, "g1": c1, "f12": c12, "g2": c2}
    for k in np.flatnonzero(res.t < first):
        mode = Mode(tuple(res.fm[k]), tuple(res.reg[k]))
        lam = m.stuck_torques(res.x[k], res.u[k], mode)
        assert set(lam) == set(cap_of)
        for nm, v in lam.items():
            assert abs(v) <= cap_of[nm] + 1e-9
    E = res.stored_energy()
    resid = abs(E[-1] - E[0] - res.work_in[-1] + res.dissipated[-1].sum())
    assert resid <= 1e-6 * max(abs(res.work_in[-1]), np.abs(E).max(), 1e-3)
    assert abs(res.energy_residual_rel) <= 1e-9
    D = m.data
    Tc = series.coupling_torques(D, res.x, res.u, res.fm, res.reg)
    for k in range(res.t.shape[0]):
        _, Lam = K.mode_matrices(D, res.fm[k])
        ref = K.coupling_torques(D, res.x[k], res.u[k], res.fm[k], res.reg[k], Lam)
        np.testing.assert_allclose(Tc[k], ref, rtol=1e-12, atol=1e-12)


def test_four_bodies_three_dimensional_redundancy_matches_the_reference() -> None:
    """Four grounded bodies joined by stuck clutches with ratios (k = 3): kernel torques and
    guards against the flat reference's leximin LP."""
    fr = lambda nm, s: Friction(scale=s, name=nm)  # noqa: E731
    bodies = (
        Body("b0", 1.0, torque_input="T", ground_friction=fr("g0", 0.8)),
        Body("b1", 2.0, ground_friction=fr("g1", 1.3)),
        Body("b2", 0.5, ground_friction=fr("g2", 0.4)),
        Body("b3", 1.0, torque_input="T3", ground_friction=fr("g3", 2.0)),
    )
    couplings = (
        Coupling("c0", ratio=2.0, friction=fr("f01", 1.1)),
        Coupling("c1", ratio=0.5, friction=fr("f12", 3.0)),
        Coupling("c2", friction=fr("f23", 0.9)),
    )
    m = Model(Chain(bodies, couplings, inputs=("T", "T3")))
    n, nf = m.n_bodies, len(m.frictions)
    for u in (np.array([1.9, -0.4]), np.array([-0.3, 2.6]), np.array([0.0, 0.0])):
        mode, x = m.decide(np.zeros(m.nx), u)
        assert set(m.mode_names(mode).values()) == {"stuck"}
        _P, Lam = K.mode_matrices(m.data, np.array(mode.fm, dtype=np.int64))
        assert np.count_nonzero(np.any(Lam[:nf, n : n + nf] != 0.0, axis=0)) == 3
        got = m.stuck_torques(x, u, mode)
        ref, margin = _reference(m, x, u, mode)
        names = [fi.name for fi in m.frictions]
        np.testing.assert_allclose([got[nm] for nm in names], ref, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(m.guards(x, u, mode)[:nf], margin, rtol=1e-7, atol=1e-9)


def test_stuck_torques_rows_is_the_single_point_kernel_exactly() -> None:
    """``stuck_torques_rows`` (the series' no-NRT row loop) gives bit for bit what
    ``stuck_torques`` gives sample by sample, in the modes of a run through a two-dimensional
    redundancy, its break-away and the modes after it (unique stuck torques)."""
    m = _three_held(1.0, 1.5, 1.0, 1.0, 1.0)
    res = simulate(m, np.zeros(m.nx), {"T": sg.ramp(0.0, 3.0, 0.0, 3.0)}, t_end=3.0)
    assert res.status == "ok"
    D = m.data
    seen = set()
    for fm in {tuple(r) for r in res.fm}:
        fm_a = np.array(fm, dtype=np.int64)
        sel = np.flatnonzero(np.all(res.fm == fm_a, axis=1))
        _P, Lam = K.mode_matrices(D, fm_a)
        TAU = np.array([K.forces(D, res.x[k], res.u[k], fm_a, res.reg[k]) for k in sel])
        rows = K.stuck_torques_rows(
            D, np.ascontiguousarray(res.u[sel]), fm_a, np.ascontiguousarray(res.reg[sel]), Lam, TAU
        )
        for r, k in enumerate(sel):
            _P, Lam1 = K.mode_matrices(D, fm_a)
            one = K.stuck_torques(D, res.x[k], res.u[k], fm_a, res.reg[k], Lam1)
            np.testing.assert_array_equal(rows[r], one)
        seen.add(int(np.sum(fm_a == K.STUCK)))
    assert 5 in seen and len(seen) > 1  # the redundant set and at least one other stuck set


def test_reference_lp_rejects_bad_shapes_naming_the_field() -> None:
    G = np.array([[1.0, 0.0], [1.0, -1.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="limits"):
        max_min_stuck_torques(np.eye(2), G, np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="tau"):
        max_min_stuck_torques(np.eye(2), G, np.array([np.nan, 0.0]), np.ones(3))
    lam, margin = max_min_stuck_torques(np.eye(2), G, np.array([1.5, 0.0]), np.ones(3))
    # b0 loaded with 1.5: g0 and the path f01 -> g1 share it, 0.75 each (margin 0.25)
    np.testing.assert_allclose(lam, [0.75, 0.75, 0.75], atol=1e-9)
    assert margin == pytest.approx(0.25, abs=1e-9)
