"""Value tests of drivetrain_ctrl.sim.series: the whole-run arrays against the single-point
model (``Model.rhs`` row by row, the compiled kernels' coupling torques and stored energy), the
mode grouping against the rows themselves (every branch: no friction, up to 30 elements, more),
and a sub-series in other modes (``RunSeries.at``)."""

from __future__ import annotations

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.plant.drivetrain import Drivetrain
from drivetrain_ctrl.plant.model import Mode
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim import series as S
from drivetrain_ctrl.sim.run import run_scenario


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
