"""Value tests of design/certificates.py (issue 22 item 4: mutation score of the design
modules): the S-procedure check against matrices written out by hand for scalar loops, the
exact ZOH model of a two-input plant with a fractional delay and a longer input buffer against a
scipy simulation, and a discrete system with an unspecified sample period."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.signal as ss

from drivetrain_ctrl.design.certificates import (
    _Lure,
    _sector_verify,
    common_lyapunov,
    sampled_loop,
    zoh_with_delay,
)


def _scalar_lure(a: float, b: float, dt: float) -> _Lure:
    """y = x, x' = a x - b w (continuous) or x+ = a x - b w (discrete), unscaled."""
    one = np.eye(1)
    return _Lure((a * one,), (b * one,), (one,), (0.0 * one,), np.ones(1), one, 1.0, dt)


def test_sector_check_of_a_continuous_scalar_loop_by_hand() -> None:
    """x' = -x - w, w in sector [0, k] of y = x, V = p x^2. The S-procedure matrix on (x, w) is
    [[-2p, -p], [-p, 0]] + tau [[0, k/2], [k/2, -1]]; with p = 2, tau = 1, k = 4 it is
    diag(-4, -1) (negative definite: certified); with k = 10 it is [[-4, 3], [3, -1]]
    (indefinite: not certified)."""
    L = _scalar_lure(-1.0, 1.0, 0.0)
    P, tau = np.array([[2.0]]), np.array([1.0])
    assert _sector_verify(L, ((0.0, 4.0),), P, tau)
    assert not _sector_verify(L, ((0.0, 10.0),), P, tau)
    # P must be positive definite
    assert not _sector_verify(L, ((0.0, 4.0),), np.array([[-2.0]]), tau)


def test_sector_check_of_a_discrete_scalar_loop_by_hand() -> None:
    """x+ = 0.5 x - w, w in [0, k] of y = x, V = p x^2: the matrix is
    [a -b]' p [a -b] - diag(p, 0) + tau Q = [[-0.75, -0.5], [-0.5, 1]] + tau [[0, k/2], [k/2, -1]]
    for p = 1; with tau = 2, k = 0.5 it is diag(-0.75, -1) (certified); with k = 0.1 it is
    [[-0.75, -0.4], [-0.4, -1]] (still negative definite: det 0.59); with tau = 0.5 the w-w
    entry is 0.5 > 0 (not certified)."""
    L = _scalar_lure(0.5, 1.0, 0.1)
    P = np.array([[1.0]])
    assert _sector_verify(L, ((0.0, 0.5),), P, np.array([2.0]))
    assert _sector_verify(L, ((0.0, 0.1),), P, np.array([2.0]))
    assert not _sector_verify(L, ((0.0, 0.5),), P, np.array([0.5]))


def test_zoh_of_a_two_input_plant_with_fractional_delay_and_long_buffer() -> None:
    """Two inputs, feedthrough D != 0, delay 1.4 samples, buffer of 4 (more than the 2 needed):
    the samples of the discrete model equal scipy's simulation of the continuous plant driven
    by the delayed staircase (input u[k] on [k T + tau, (k + 1) T + tau); the grid holds every
    switching instant, where ZOH interpolation is exact)."""
    A = np.array([[-1.0, 2.0], [-3.0, -4.0]])
    B = np.array([[1.0, 0.5], [0.0, 2.0]])
    C = np.array([[1.0, 0.0], [0.3, 1.0]])
    D = np.array([[0.2, 0.0], [0.0, -0.4]])
    G = control.ss(A, B, C, D)
    T, tau, nk = 0.1, 0.14, 30
    Pd = zoh_with_delay(G, T, delay=tau, buffer=4)
    assert Pd.nstates == 2 + 4 * 2 and Pd.dt == T
    rng = np.random.default_rng(3)
    u = rng.normal(size=(nk, 2))
    # the discrete model, stepped by hand from rest
    x = np.zeros(Pd.nstates)
    yd = []
    for k in range(nk):
        yd.append(Pd.C @ x + Pd.D @ u[k])
        x = Pd.A @ x + Pd.B @ u[k]
    yd_arr = np.array(yd)
    h = 0.002  # kT and kT + tau on the grid
    t = np.arange(round(nk * T / h) + 1) * h
    j = np.floor((t - tau) / T + 1e-9).astype(int)
    uc = np.where((j >= 0)[:, None], u[np.clip(j, 0, nk - 1)], 0.0)
    _, yc, _ = ss.lsim((A, B, C, D), uc, t, interp=False)
    idx = [round(k * T / h) for k in range(nk)]
    assert yd_arr == pytest.approx(yc[idx], abs=1e-9)
    # the same input-output map as the fewest-states model
    P2 = zoh_with_delay(G, T, delay=tau)
    assert P2.nstates == 2 + 2 * 2
    z = np.exp(1j * np.array([0.3, 3.0, 20.0]) * T)
    assert Pd(z) == pytest.approx(P2(z), rel=1e-10)


def test_a_sampled_loop_has_no_delay_by_default() -> None:
    """sampled_loop(G, K) without a delay: the closed loop of K and the ZOH samples of G,
    feedback(K Pd, 1) with Pd from python-control's sample_system (one state per plant state,
    no input buffer)."""
    T = 0.05
    G = control.tf([2.0], [1.0, 3.0])
    K = control.tf([1.5, -1.2], [1.0, -1.0], T)
    cl = sampled_loop(G, K)
    ref = control.feedback(K * control.sample_system(G, T, method="zoh"), 1)
    assert cl.nstates == 2
    got = np.sort_complex(np.asarray(cl.poles()))
    want = np.sort_complex(np.asarray(ref.poles()))
    assert got == pytest.approx(want, abs=1e-10)


def test_a_discrete_system_with_unspecified_period_is_not_judged_continuous() -> None:
    """x+ = 0.5 x is a stable discrete mode. common_lyapunov must either refuse dt = True (as
    sector_certificate does, naming it) or test it as discrete: P = 1 gives 0.25 - 1 < 0."""
    S = control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], True)
    try:
        cert = common_lyapunov([S], decay=False)
    except ValueError as exc:
        assert "dt" in str(exc)
        return
    assert cert.feasible and cert.dt != 0.0


def test_the_clutch_certificate_bisects_to_one_per_mille_by_default() -> None:
    """The default tolerance of the bisections (the signatures, shown in the API reference):
    rtol = 1e-3 (relative) for the clutch's certificate as for common_lyapunov."""
    import inspect

    from drivetrain_ctrl.design.certificates import clutch_sector_certificate

    for f in (clutch_sector_certificate, common_lyapunov):
        assert inspect.signature(f).parameters["rtol"].default == 1e-3


G3 = control.tf([1.0], np.polymul(np.polymul([1.0, 1.0], [1.0, 2.0]), [1.0, 3.0]))


def test_certified_end_of_a_grown_sector() -> None:
    """largest_sector grows the upper end of [0, 0] for 1/((s+1)(s+2)(s+3)) up to limit = 2,
    inside the circle criterion's bound -1/min Re G (computed here on a dense grid): the sector
    [0, 2] is certified and certified_end is 2; a plain sector certificate has no grown end."""
    from drivetrain_ctrl.design.certificates import largest_sector, sector_certificate

    w = np.logspace(-3, 3, 200001)
    circle = -1.0 / float(np.min(np.real(G3(1j * w))))
    assert circle > 2.0
    cert = largest_sector(G3, (0.0, 0.0), limit=2.0)
    assert cert.feasible and cert.sectors == ((0.0, 2.0),) and cert.certified_end == 2.0
    plain = sector_certificate(G3, (0.0, 2.0))
    assert plain.feasible and plain.certified_end is None


def test_no_linear_limit_below_a_billion_is_an_error() -> None:
    """G3 scaled by 60/1.5e9: its linear (Hurwitz) limit, 60 for G3, becomes 1.5e9, beyond the
    search range of 1e9 (times max(1, |start|)) used when no limit is given: an error asking
    for a limit."""
    from drivetrain_ctrl.design.certificates import largest_sector

    with pytest.raises(ValueError, match=r"up to 1e\+09; give limit"):
        largest_sector(G3 * (60.0 / 1.5e9), (0.0, 0.0))


def test_the_clutch_certificate_refuses_a_slope_limit_of_zero() -> None:
    """mu_slope_limit, the most negative slope of interest, must be < 0 [s/rad]."""
    from drivetrain_ctrl import default_params, reduced_model
    from drivetrain_ctrl.core.units import rpm_to_rad_s
    from drivetrain_ctrl.design.certificates import clutch_sector_certificate
    from drivetrain_ctrl.linear import slip_operating_point

    op = slip_operating_point(
        reduced_model(default_params()),
        omega_engine=rpm_to_rad_s(1600),
        omega_driven=50.0,
        x_c=0.07,
        throttle=0.6,
    )
    with pytest.raises(ValueError, match=r"mu_slope_limit = 0.0: must be < 0"):
        clutch_sector_certificate(op, None, mu_slope_limit=0.0)


def test_the_linear_limit_search_range_scales_with_the_start() -> None:
    """The search for the linear limit reaches 1e9 max(1, |start|): growing [0, 2] (start 2) of
    G3 scaled by 60/7e8, whose linear limit is 7e8 (60 for G3: phase -180 deg at w^2 = 11, where
    |G3| = 1/60), finds it (7e8 < 2e9)."""
    from drivetrain_ctrl.design.certificates import largest_sector

    cert = largest_sector(G3 * (60.0 / 7e8), (0.0, 2.0), rtol=1e-2)
    assert cert.linear_limit == pytest.approx(7e8, rel=1e-6)
    assert cert.feasible and 2.0 < cert.certified_end < 7e8
    # the message gives the certified end as a share of the linear limit
    share = cert.certified_end / cert.linear_limit
    assert f"linear (Hurwitz) limit of that end: 7e+08 ({share:.1%} of it)." in cert.message


def test_rank_one_factors_of_the_friction_slope() -> None:
    """_rank_one splits dA = b c' (the friction slope's effect): for [[2, 0], [0, 0]] (singular
    values 2 and exactly 0) the factors multiply back to it; a zero matrix (no slip coupling)
    and a rank-two one are errors naming the reason."""
    from drivetrain_ctrl.design.certificates import _rank_one

    dA = np.array([[2.0, 0.0], [0.0, 0.0]])
    b, c = _rank_one(dA, "x")
    assert b.shape == (2, 1) and c.shape == (1, 2)
    assert b @ c == pytest.approx(dA, abs=1e-15)
    with pytest.raises(ValueError, match="does not enter the loop"):
        _rank_one(np.zeros((2, 2)), "x")
    with pytest.raises(ValueError, match="not rank one"):
        _rank_one(np.eye(2), "x")


def test_the_lure_system_of_the_slip_loop_has_no_direct_feedthrough_of_friction() -> None:
    """Law (6) on the slip loop as a two-channel Lur'e system (friction slope, saturation): the
    slip is a state, so its output has no direct term from either input, and the friction
    torque reaches the controller's output only through the plant: D = [[0, 0], [0, d]] with d
    the controller-plant feedthrough (0 for this strictly proper plant)."""
    from drivetrain_ctrl import default_params, load_controller, reduced_model
    from drivetrain_ctrl.core.signals import constant
    from drivetrain_ctrl.core.units import rpm_to_rad_s
    from drivetrain_ctrl.design.certificates import _friction_lure
    from drivetrain_ctrl.linear import slip_operating_point

    p = default_params()
    op = slip_operating_point(
        reduced_model(p),
        omega_engine=rpm_to_rad_s(1600),
        omega_driven=50.0,
        x_c=0.07,
        throttle=0.6,
    )
    ctl = load_controller("paper").build(p, reference=constant(rpm_to_rad_s(1600)))
    G, k13 = _friction_lure(op, ctl)
    assert (G.ninputs, G.noutputs) == (2, 2) and k13 > 0
    assert np.array_equal(np.asarray(G.D), np.zeros((2, 2)))
