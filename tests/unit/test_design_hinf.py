"""H-infinity mixed sensitivity (design.hinf): gamma against norms computed here from the
controller's frequency response, a closed-form optimum, the synthesis traps (D12 rank,
integrators, time limit), reduction and discretisation checked against margins computed here."""

from __future__ import annotations

import math
import time

import control
import numpy as np
import pytest
from scipy.optimize import brentq

from drivetrain_ctrl.design.hinf import (
    HinfSpec,
    HinfTimeoutError,
    hinf_mixsyn,
    mixsyn_weights,
    shift_axis_poles,
    tustin_to_continuous,
)
from drivetrain_ctrl.design.plants import Plant, as_plant_set

W = np.logspace(-5, 5, 40001)


def resp(sys: object, x: np.ndarray) -> np.ndarray:
    return np.asarray(sys(x, warn_infinite=False), dtype=complex).reshape(-1)  # type: ignore[operator]


def weighted_norm_on_grid(d: object, G: object, K: object, x: np.ndarray, weights: tuple) -> float:
    """max over the grid of |[W1 S; W2 K S; W3 T]| from the frequency responses of G and K."""
    Gw, Kw = resp(G, x), resp(K, x)
    S = 1.0 / (1.0 + Gw * Kw)
    cols = [S, Kw * S, Gw * Kw * S]
    tot = np.zeros(x.shape)
    for Wt, c in zip(weights, cols, strict=True):
        if Wt is not None:
            tot = tot + np.abs(resp(Wt, x) * c) ** 2
    return float(np.sqrt(np.max(tot)))


def phase_margin_exact(L) -> float:  # noqa: ANN001
    """Phase margin [deg] of a loop given as a function of w (exact), by root finding."""
    w = np.logspace(-3, 3, 6001)
    m = np.abs(L(w)) - 1.0
    k = int(np.flatnonzero(np.sign(m[:-1]) != np.sign(m[1:]))[0])
    wc = brentq(lambda v: abs(L(np.array([v]))[0]) - 1.0, w[k], w[k + 1], xtol=1e-14)
    ph = math.degrees(np.angle(L(np.array([wc]))[0]))
    return (ph + 180.0) % 360.0


@pytest.fixture(scope="module")
def first_order():
    return hinf_mixsyn(control.tf([1.0], [1.0, 1.0]), bandwidth=5.0)


@pytest.fixture(scope="module")
def integrator():
    return hinf_mixsyn(control.tf([1.0], [1.0, 1.0, 0.0]), bandwidth=2.0, mt=1.5)


@pytest.fixture(scope="module")
def delayed():
    return hinf_mixsyn(
        Plant(control.tf([1.0], [1.0, 1.0]), delay=0.1), bandwidth=2.0, order=4, dt=0.05
    )


@pytest.mark.parametrize("which", ["first_order", "integrator", "delayed"])
def test_gamma_equals_the_closed_loop_norm_computed_here(which, request):
    d = request.getfixturevalue(which)
    w = d.weights
    norm = weighted_norm_on_grid(d, d.synthesis_plant, d.controller, 1j * W, (w.W1, w.W2, w.W3))
    assert abs(norm - d.gamma) <= 0.01 * d.gamma
    assert abs(d.norm_check - d.gamma) <= 0.01 * d.gamma
    assert d.norm_check_grid <= d.norm_check * (1 + 1e-6)
    assert d.gamma_optimal <= d.gamma <= 1.0101 * d.gamma_optimal
    cl = control.feedback(control.ss(d.synthesis_plant) * d.controller, 1)
    assert np.all(cl.poles().real < 0)


@pytest.mark.filterwarnings("ignore::FutureWarning")  # augw uses the deprecated connect
def test_optimum_equals_python_control_hinfsyn(first_order):
    """The gamma iteration started near the optimum finds python-control's hinfsyn optimum."""
    d = first_order
    w = d.weights
    P = control.augw(d.synthesis_plant, w.W1, w.W2, w.W3)
    _K, _CL, gam, _rc = control.hinfsyn(P, 1, 1)
    assert d.gamma_optimal == pytest.approx(gam, rel=1e-5)


def test_known_optimum_constant_weights():
    """G = 1/(s+1), W1 = W2 = 1/2: |W1 S| -> 1/2 as w -> inf for any proper K (S -> 1), and K = 0
    achieves 1/2, so the optimal gamma is exactly 1/2."""
    d = hinf_mixsyn(
        control.tf([1.0], [1.0, 1.0]), W1=control.tf([0.5], [1]), W2=control.tf([0.5], [1])
    )
    assert d.gamma_optimal == pytest.approx(0.5, rel=1e-3)


def test_gamma_above_the_pointwise_lower_bound():
    """At each w, min over complex k of (|W1|^2 + |W2 k|^2)/|1 + G k|^2 = 1/(1/|W1|^2 +
    |G|^2/|W2|^2) (Cauchy-Schwarz): gamma can never be below its maximum."""
    G = control.tf([1.0], [1.0, 1.0])
    W1 = control.tf([0.5, 5.0], [1.0, 5e-3])
    d = hinf_mixsyn(G, W1=W1, W2=control.tf([0.2], [1]))
    g, w1 = np.abs(resp(G, 1j * W)), np.abs(resp(W1, 1j * W))
    bound = float(np.max(1.0 / np.sqrt(1.0 / w1**2 + g**2 / 0.2**2)))
    assert d.gamma_optimal >= bound * (1 - 1e-6)
    assert d.gamma_optimal < 1.6 * bound  # and not absurdly above it


def test_integrators_shifted_for_synthesis_and_kept_in_the_controller(integrator):
    d = integrator
    assert any("imaginary axis" in n for n in d.notes)
    p = np.asarray(d.synthesis_plant.poles())
    assert np.all(p.real < 0)
    shift = 1e-3 * 2.0
    assert np.sort(p.real)[-1] == pytest.approx(-shift, rel=1e-6)
    # the checks use the true plant (with its integrator): the loop has an infinite DC gain
    assert all(c.stable for c in d.checks_full + d.checks_reduced)
    Kp = np.asarray(d.controller_reduced.poles())
    assert np.min(np.abs(Kp)) < 1e-12  # an exact integrator in the reduced controller
    # the Mt bound asked for (W3 = 1/mt): |T| <= gamma mt
    assert d.checks_full[0].mt <= d.gamma * 1.5 * (1 + 1e-3)


def test_shift_axis_poles_moves_only_the_axis_poles():
    G = control.tf([1.0], np.polymul([1.0, 0.0, 0.0], [1.0, 3.0]))
    Gs, k = shift_axis_poles(G, 0.01)
    assert k == 2
    assert np.sort(np.asarray(Gs.poles()).real) == pytest.approx([-3.0, -0.01, -0.01], abs=1e-6)


def test_missing_w2_gets_a_small_default_and_says_so():
    G = control.tf([1.0], [1.0, 2.0, 1.0])
    d = hinf_mixsyn(G, W1=control.tf([0.5, 2.0], [1.0, 2e-4]))
    assert any("W2 was not given" in n for n in d.notes)
    assert d.weights.W2 is not None
    assert all(c.stable for c in d.checks_full)


def test_strictly_proper_w2_is_an_error_naming_it():
    with pytest.raises(ValueError, match="W2"):
        hinf_mixsyn(
            control.tf([1.0], [1.0, 1.0]),
            W1=control.tf([0.5, 2.0], [1.0, 2e-4]),
            W2=control.tf([1.0], [1.0, 1.0]),
        )


def test_time_limit_ends_with_a_clear_error():
    t0 = time.perf_counter()
    with pytest.raises(HinfTimeoutError, match=r"time_limit = 0\.001 s.*Raise time_limit"):
        hinf_mixsyn(control.tf([1.0], [1.0, 1.0]), bandwidth=5.0, time_limit=1e-3)
    assert time.perf_counter() - t0 < 10.0


def test_without_fork_the_synthesis_runs_as_a_script(monkeypatch, first_order):
    """In a daemonic process (a pool or Dask worker) or without fork: a fresh interpreter runs
    the worker module; same optimum, and the time limit still holds."""
    import drivetrain_ctrl.design.hinf as hinf

    monkeypatch.setattr(hinf, "_can_fork", lambda: False)
    d = hinf_mixsyn(control.tf([1.0], [1.0, 1.0]), bandwidth=5.0)
    assert d.gamma_optimal == pytest.approx(first_order.gamma_optimal, rel=1e-9)
    with pytest.raises(HinfTimeoutError, match="time_limit = 0.001 s"):
        hinf_mixsyn(control.tf([1.0], [1.0, 1.0]), bandwidth=5.0, time_limit=1e-3)


def test_reduction_reports_margins_before_and_after(delayed):
    d = delayed
    assert d.order_full == 5 and d.order_reduced == 4
    P = Plant(control.tf([1.0], [1.0, 1.0]), delay=0.1)
    for K, check in ((d.controller, d.checks_full[0]), (d.controller_reduced, d.checks_reduced[0])):

        def L(w, K=K):
            return P.freqresp(w) * resp(K, 1j * w)

        assert check.phase_margin_deg == pytest.approx(phase_margin_exact(L), abs=0.2)
        assert check.stable
    assert d.checks_full[0].phase_margin_deg != pytest.approx(
        d.checks_reduced[0].phase_margin_deg, abs=1e-3
    )


def test_sampled_variant_checked_on_the_zoh_plant(delayed):
    d = delayed
    Kd = d.controller_sampled
    assert Kd is not None and Kd.dt == pytest.approx(0.05)
    Pd = control.sample_system(control.ss(control.tf([1.0], [1.0, 1.0])), 0.05, method="zoh")
    Pd = Pd * control.ss(control.tf([1.0], [1.0, 0.0, 0.0], 0.05))  # the 0.1 s delay: z^-2
    L = control.ss(Kd) * Pd
    _gm, pm, *_ = control.stability_margins(L)
    assert d.checks_sampled[0].phase_margin_deg == pytest.approx(pm, abs=0.3)
    assert np.all(np.abs(control.feedback(L, 1).poles()) < 1.0) == d.checks_sampled[0].stable


def test_tustin_to_continuous_is_the_w_plane_map():
    Gd = control.sample_system(control.tf([1.0, 2.0], [1.0, 0.5, 4.0]), 0.1, method="zoh")
    Gc = tustin_to_continuous(Gd)
    w = np.linspace(0.1, 30.0, 50)
    nu = 2.0 / 0.1 * np.tan(w * 0.1 / 2.0)
    assert resp(Gc, 1j * nu) == pytest.approx(resp(Gd, np.exp(1j * w * 0.1)), rel=1e-9)
    back = control.sample_system(Gc, 0.1, method="tustin")
    assert resp(back, np.exp(1j * w * 0.1)) == pytest.approx(
        resp(Gd, np.exp(1j * w * 0.1)), rel=1e-9
    )


def test_sampled_plant_designed_in_the_w_plane():
    dt = 0.05
    Gd = control.sample_system(control.tf([1.0], [1.0, 1.0]), dt, method="zoh")
    d = hinf_mixsyn(Gd, bandwidth=5.0)
    assert d.controller.dt == pytest.approx(dt) and d.controller_reduced.dt == pytest.approx(dt)
    z = np.exp(1j * np.linspace(1e-6, math.pi / dt, 40001) * dt)
    wts = tuple(
        None if Wc is None else control.sample_system(Wc, dt, method="tustin")
        for Wc in (d.weights.W1, d.weights.W2, d.weights.W3)
    )
    norm = weighted_norm_on_grid(d, Gd, d.controller, z, wts)
    assert abs(norm - d.gamma) <= 0.01 * d.gamma
    assert all(c.stable for c in d.checks_reduced)


def test_plant_set_checked_plant_by_plant():
    plants = as_plant_set([control.tf([g], [1.0, 1.0]) for g in (0.7, 1.0, 1.3)])
    d = hinf_mixsyn(plants, bandwidth=3.0, nominal=1)
    assert [c.name for c in d.checks_reduced] == ["plant 0", "plant 1", "plant 2"]
    # a larger plant gain gives a larger crossover
    wc = [c.crossover_rad_s for c in d.checks_reduced]
    assert wc[0] < wc[1] < wc[2]
    assert "gamma" in d.summary()


def test_mixsyn_weights_rule():
    G = control.tf([1.0], [1.0, 1.0])
    mw = mixsyn_weights(G, bandwidth=4.0, ms=2.0, mt=1.3)
    assert abs(complex(mw.W1(0.0))) == pytest.approx(1.0 / 1e-4, rel=1e-9)
    assert abs(complex(mw.W1(1e9j))) == pytest.approx(1.0 / 2.0, rel=1e-6)
    assert abs(complex(mw.W1(4j))) == pytest.approx(1.0, rel=0.3)
    assert float(mw.W2.D[0, 0]) == pytest.approx(abs(complex(G(4j))) / 10.0, rel=1e-12)
    assert float(mw.W3.D[0, 0]) == pytest.approx(1 / 1.3)


def test_bad_input_names_the_field():
    G = control.tf([1.0], [1.0, 1.0])
    with pytest.raises(
        ValueError, match=r"unknown option bandwith = 3\.0; did you mean 'bandwidth'"
    ):
        hinf_mixsyn(G, bandwith=3.0)
    with pytest.raises(ValueError, match="either the weights or the specifications"):
        hinf_mixsyn(G, bandwidth=3.0, W1=control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(ValueError, match="W1 has the pole"):
        hinf_mixsyn(G, W1=control.tf([1.0], [1.0, 0.0]))
    with pytest.raises(ValueError, match="nominal = 3"):
        hinf_mixsyn(G, bandwidth=3.0, nominal=3)
    with pytest.raises(ValueError, match="ms = 0.5"):
        HinfSpec(ms=0.5)
    with pytest.raises(ValueError, match="give the weights"):
        hinf_mixsyn(G)
    with pytest.raises(ValueError, match="already sampled"):
        hinf_mixsyn(control.sample_system(G, 0.1), bandwidth=1.0, dt=0.1)
