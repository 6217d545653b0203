"""Numerical helpers of the simulator kernel: the spectral-radius bound that sets the largest
stable step, and the momentum-preserving projection onto stuck constraints."""

from __future__ import annotations

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.plant.drivetrain import full_model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim.run import run_scenario


def _rho(J: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(J))))


def test_spectral_radius_bound_is_an_upper_bound_within_5_percent_on_random_matrices() -> None:
    rng = np.random.default_rng(7)
    for n in (1, 2, 5, 12, 15):
        for _ in range(20):
            # eigenvalues over four decades, eigenvectors moderately ill-conditioned
            lam = rng.uniform(-1, 1, n) * 10 ** rng.uniform(0, 4, n)
            V = np.eye(n) + 0.5 * rng.standard_normal((n, n))
            J = V @ np.diag(lam) @ np.linalg.inv(V)
            rho = _rho(J)
            b = K._spectral_radius_bound(J)
            assert b >= rho * (1 - 1e-12)
            assert b <= 1.05 * rho
            assert K._inf_norm(K._balance(J)) >= b * (1 - 1e-12)


def test_spectral_radius_bound_of_an_oscillator_and_special_cases() -> None:
    w, z = 3600.0, 0.003  # the gear-mesh mode: lightly damped, complex pair
    J = np.array([[0.0, 1.0], [-w * w, -2 * z * w]])
    assert K._spectral_radius_bound(J) == pytest.approx(w, rel=0.02)
    assert K._spectral_radius_bound(J) >= w * (1 - 1e-12)
    assert K._spectral_radius_bound(np.zeros((3, 3))) == 0.0
    nil = np.array([[0.0, 5.0, 1.0], [0.0, 0.0, 2.0], [0.0, 0.0, 0.0]])  # nilpotent
    assert K._spectral_radius_bound(nil) == 0.0
    assert K._rho_step(nil) == np.inf
    assert K._rho_step(J) == pytest.approx(K.STABILITY_FACTOR / w, rel=0.02)
    assert K._rho_step(J) <= K.STABILITY_FACTOR / w


def test_spectral_radius_bound_is_tight_on_the_drivetrain_mode_jacobians() -> None:
    """Within 3 % above the spectral radius for every mode engage-ramp visits (the step bound
    in stiff modes is then at most 3 % shorter than the exact one)."""
    p = default_params()
    sc = load_scenario("engage-ramp")
    dt = full_model(p, gear=sc.gear, slope=sc.slope)
    res = run_scenario(sc, dt)
    m = dt.model
    seen = set()
    checked = 0
    for k in range(0, res.t.shape[0], 7):
        fm = np.asarray(res.fm[k], dtype=np.int64)
        reg = np.asarray(res.reg[k], dtype=np.int64)
        key = (tuple(fm), tuple(reg))
        if key in seen:
            continue
        seen.add(key)
        P, _lam = K.mode_matrices(m.data, fm)
        J, _B = K.jacobians(m.data, np.asarray(res.x[k]), np.asarray(res.u[k]), fm, reg, P, False)
        rho = _rho(J)
        b = K._spectral_radius_bound(J)
        assert rho * (1 - 1e-12) <= b <= 1.03 * rho, key
        checked += 1
    assert checked >= 10


def _projection_reference(m, x, which):  # type: ignore[no-untyped-def]
    """x - M^-1 G^T (G M^-1 G^T)^-1 G x, written out with numpy."""
    d = m.data
    n = d.M.shape[0]
    rows = []
    for f in range(len(which)):
        if which[f]:
            g = np.zeros(n)
            i = d.f_idx[f]
            g[i] = 1.0
            if d.f_kind[f] == 0:
                g[i + 1] = -d.ratio[i]
            rows.append(g)
    G = np.array(rows)
    Minv = np.diag(1.0 / d.M)
    xs = x[:n]
    corr = Minv @ G.T @ np.linalg.solve(G @ Minv @ G.T, G @ xs)
    out = x.copy()
    out[:n] = xs - corr
    return out


@pytest.mark.parametrize(
    "stuck",
    [
        # clutch, damper_friction, tyre (couplings); engine, brake, vehicle (to ground)
        (1, 0, 0, 0, 0, 0),
        (1, 1, 0, 0, 0, 0),
        (0, 1, 1, 0, 0, 0),
        (1, 1, 1, 0, 0, 0),
        (1, 1, 0, 1, 0, 0),  # a chain of stuck couplings held to ground at its upstream end
        (0, 0, 1, 0, 0, 1),  # the tyre stuck to a vehicle held to ground
        (0, 1, 0, 0, 1, 0),
    ],
)
def test_projection_matches_the_textbook_formula_and_zeroes_the_relative_speeds(stuck) -> None:  # type: ignore[no-untyped-def]
    p = default_params()
    m = full_model(p).model
    nf = len(m.frictions)
    assert [f.name for f in m.frictions] == [
        "clutch", "damper_friction", "tyre", "engine", "brake", "vehicle"
    ]  # fmt: skip
    which = np.array(stuck, dtype=np.int64)
    rng = np.random.default_rng(3)
    for _ in range(10):
        x = np.zeros(m.nx)
        x[: m.n_bodies] = rng.uniform(50, 200, m.n_bodies) * np.sign(
            rng.uniform(-0.2, 1, m.n_bodies)
        )
        ref = _projection_reference(m, x, which)
        y = x.copy()
        K.project(m.data, y, which)
        scale = np.max(np.abs(x))
        assert np.max(np.abs(y - ref)) <= 1e-12 * scale
        for f in range(nf):
            if which[f]:
                assert K.rel_speed(m.data, f, y) == 0.0  # exactly, not only to round-off
        # momentum (sum of M x over the bodies, in upstream frames) of a free body set kept:
        # the kinetic energy can only drop
        e0 = float(np.sum(m.data.M * x[: m.n_bodies] ** 2))
        e1 = float(np.sum(m.data.M * y[: m.n_bodies] ** 2))
        assert e1 <= e0 * (1 + 1e-12)
