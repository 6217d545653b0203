"""Value tests of drivetrain_ctrl.sim.series: the whole-run arrays against the single-point
model (``Model.rhs`` row by row, the compiled kernels' coupling torques and stored energy), the
mode grouping against the rows themselves (every branch: no friction, up to 30 elements, more),
and a sub-series in other modes (``RunSeries.at``)."""

from __future__ import annotations

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.core.tables import PwlTable
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction, LaggedSource
from drivetrain_ctrl.plant.drivetrain import Drivetrain
from drivetrain_ctrl.plant.model import Mode, Model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim import series as S
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.sim.simulator import simulate


@pytest.fixture(scope="module", params=["reduced", "full"])
def run(request):
    dt = Drivetrain(default_params(), kind=request.param)
    res = run_scenario(load_scenario("engage-ramp"), dt, t_end=1.0)
    idx = np.arange(0, len(res.t), 25)  # a subsample keeps the row loops short
    D = res._data()
    X = np.asarray(res.x)[idx]
    U = np.asarray(res.u)[idx]
    FM = np.asarray(res.fm, dtype=np.int64)[idx]
    REG = np.asarray(res.reg, dtype=np.int64)[idx]
    # the second half of the samples held in the stuck-clutch mode as well (both mode kinds)
    FM2 = FM.copy()
    FM2[FM2.shape[0] // 2 :, 0] = K.STUCK
    return res.model, D, X, U, FM2, REG


def _mode(FM, REG, i):
    return Mode(tuple(int(v) for v in FM[i]), tuple(int(v) for v in REG[i]))


def test_state_derivatives_equal_the_model_rhs_row_by_row(run) -> None:
    model, D, X, U, FM, REG = run
    got = S.state_derivatives(D, X, U, FM, REG)
    want = np.array([model.rhs(X[i], U[i], _mode(FM, REG, i)) for i in range(X.shape[0])])
    scale = np.max(np.abs(want), axis=0) + 1e-12
    assert np.max(np.abs(got - want) / scale) < 1e-12
    assert len({tuple(r) for r in FM}) >= 2


def test_body_forces_give_the_accelerations_of_a_slip_mode(run) -> None:
    # the accelerations are the forces through the mode's matrix P (the kernel's): a = P tau
    model, D, X, U, FM, REG = run
    tau = S.body_forces(D, X, U, FM, REG)
    n = D.M.shape[0]
    for i in range(0, X.shape[0], 7):
        P, _ = K.mode_matrices(D, np.ascontiguousarray(FM[i]))
        xdot = model.rhs(X[i], U[i], _mode(FM, REG, i))
        np.testing.assert_allclose(P @ tau[i], xdot[:n], rtol=1e-12, atol=1e-9)


def test_coupling_torques_and_energy_equal_the_kernels_row_by_row(run) -> None:
    model, D, X, U, FM, REG = run
    got = S.coupling_torques(D, X, U, FM, REG)
    want = np.empty_like(got)
    for i in range(X.shape[0]):
        _, Lam = K.mode_matrices(D, np.ascontiguousarray(FM[i]))
        want[i] = K.coupling_torques(D, X[i], U[i], FM[i], REG[i], Lam)
    scale = np.max(np.abs(want), axis=0) + 1e-12
    assert np.max(np.abs(got - want) / scale) < 1e-12
    E = S.stored_energy(D, X)
    E0 = np.array([K.stored_energy(D, x) for x in X])
    np.testing.assert_allclose(E, E0, rtol=1e-12, atol=1e-9)


def test_a_sub_series_in_other_modes(run) -> None:
    model, D, X, U, FM, REG = run
    s = S.RunSeries(D, X, U, FM, REG)
    s.state_derivatives()
    rows = np.arange(1, X.shape[0], dtype=np.int64)
    mode_rows = rows - 1  # each sample in the mode of the one before it
    sub = s.at(rows, mode_rows)
    got = sub.state_derivatives()
    want = np.array([model.rhs(X[i], U[i], _mode(FM, REG, i - 1)) for i in rows])
    scale = np.max(np.abs(want), axis=0) + 1e-12
    assert np.max(np.abs(got - want) / scale) < 1e-12
    # cached: the same array twice
    assert sub.state_derivatives() is got and s.coupling_torques() is s.coupling_torques()


@pytest.mark.parametrize("nf", [0, 1, 3, 30, 31, 40])
def test_mode_groups_reproduce_the_rows(nf: int) -> None:
    rng = np.random.default_rng(nf)
    FM = rng.integers(0, 4, size=(200, nf)).astype(np.int64)
    FM[100:] = FM[:100]  # repeated rows
    modes, inv = S._mode_groups(FM)
    assert inv.shape == (200,) and inv.dtype == np.int64
    np.testing.assert_array_equal(modes[inv], FM)
    assert len({tuple(r) for r in modes}) == modes.shape[0]  # distinct
    assert modes.shape[0] == len({tuple(r) for r in FM}) or nf == 0
    if nf == 0:
        assert modes.shape == (1, 0) and np.all(inv == 0)


def test_a_capacity_input_without_a_table_by_hand() -> None:
    # two bodies (1 and 2 kg m^2) and one friction of capacity `cap` [N m] read from an input
    # without a table, mu(|w|)/mu(0) = 1 - 0.5 |w| / 20, a torque T = 1 N m on a:
    # a' = T - cap mu, b' = cap mu / 2
    bodies = (Body("a", 1.0, torque_input="T"), Body("b", 2.0))
    fr = Friction(capacity_input="cap", name="f", mu_table=PwlTable((0.0, 20.0), (1.0, 0.5)))
    m = Model(Chain(bodies, (Coupling("c", friction=fr),), inputs=("T", "cap")))
    res = simulate(m, np.array([10.0, 0.0]), {"T": 1.0, "cap": 5.0}, t_end=0.1)
    X = np.asarray(res.x)
    args = (res._data(), X, np.asarray(res.u), np.asarray(res.fm), np.asarray(res.reg))
    mu = 1.0 - 0.5 * (X[:, 0] - X[:, 1]) / 20.0
    slipping = np.asarray(res.fm)[:, 0] == K.SLIP_POS
    assert slipping.all()
    np.testing.assert_allclose(S.RunSeries(*args).slip_torques()[:, 0], 5.0 * mu, rtol=1e-12)
    xdot = S.state_derivatives(*args)
    np.testing.assert_allclose(xdot[:, 0], 1.0 - 5.0 * mu, rtol=1e-12)
    np.testing.assert_allclose(xdot[:, 1], 2.5 * mu, rtol=1e-12)
    np.testing.assert_allclose(S.coupling_torques(*args)[:, 0], 5.0 * mu, rtol=1e-12)
    # the kinetic energy: 0.5 (1 a^2 + 2 b^2)
    E = 0.5 * (X[:, 0] ** 2 + 2.0 * X[:, 1] ** 2)
    np.testing.assert_allclose(S.stored_energy(res._data(), X), E, rtol=1e-14)


def _by_hand_chain(with_source: bool) -> tuple[Model, dict[str, float]]:
    # two bodies (1 and 2 kg m^2) and one friction between them; either a lagged source on a
    # (state s, tau s' = th - s, torque g(w_a) s with g = 2 - w_a / 100: the model's only
    # table) and a capacity read from `cap` directly, or a torque input T on a and a capacity
    # 10 x [N m] from a table of the input x (the model's only table)
    if with_source:
        bodies = (Body("a", 1.0), Body("b", 2.0))
        fr = Friction(capacity_input="cap", name="f")
        src = LaggedSource(
            "s", body="a", input="th", tau=0.1, gain_table=PwlTable((0.0, 100.0), (2.0, 1.0))
        )
        chain = Chain(bodies, (Coupling("c", friction=fr),), inputs=("th", "cap"), sources=(src,))
        return Model(chain), {"th": 0.5, "cap": 3.0}
    bodies = (Body("a", 1.0, torque_input="T"), Body("b", 2.0))
    fr = Friction(capacity_input="x", capacity_table=PwlTable((0.0, 1.0), (0.0, 10.0)), name="f")
    chain = Chain(bodies, (Coupling("c", friction=fr),), inputs=("T", "x"))
    return Model(chain), {"T": 2.0, "x": 0.4}


@pytest.mark.parametrize("with_source", [True, False])
def test_tables_at_index_zero_by_hand(with_source: bool) -> None:
    m, inputs = _by_hand_chain(with_source)
    x0 = np.array([20.0, 0.0, 0.2]) if with_source else np.array([20.0, 0.0])
    res = simulate(m, x0, inputs, t_end=0.05)
    X, U = np.asarray(res.x), np.asarray(res.u)
    assert (np.asarray(res.fm)[:, 0] == K.SLIP_POS).all()
    xdot = S.state_derivatives(res._data(), X, U, np.asarray(res.fm), np.asarray(res.reg))
    if with_source:
        F = 3.0
        g = 2.0 - X[:, 0] / 100.0
        np.testing.assert_allclose(xdot[:, 0], g * X[:, 2] - F, rtol=1e-12)
        np.testing.assert_allclose(xdot[:, 2], (0.5 - X[:, 2]) / 0.1, rtol=1e-12)
    else:
        F = 10.0 * 0.4
        np.testing.assert_allclose(xdot[:, 0], 2.0 - F, rtol=1e-12)
    np.testing.assert_allclose(xdot[:, 1], F / 2.0, rtol=1e-12)
