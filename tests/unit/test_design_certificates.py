"""Stability certificates (design.certificates): common Lyapunov functions (feasible, and
infeasible for a switched pair shown to diverge by simulation), sector certificates against the
circle criterion's frequency condition and the judder threshold's closed form, and the exact
sampled loop with a fractional delay."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
import scipy.integrate as si
import scipy.linalg as sla
import scipy.signal as ss

from drivetrain_ctrl import default_params, load_controller, reduced_model
from drivetrain_ctrl.core.signals import constant
from drivetrain_ctrl.core.units import rpm_to_rad_s
from drivetrain_ctrl.design.certificates import (
    clutch_sector_certificate,
    common_lyapunov,
    largest_sector,
    sampled_loop,
    sector_certificate,
    zoh_with_delay,
)
from drivetrain_ctrl.linear import judder_crossing, judder_threshold, slip_operating_point

# Liberzon, "Switching in Systems and Control" (2003), Sec. 2.1: two stable modes whose
# switching can diverge
A1 = np.array([[-0.1, 1.0], [-2.0, -0.1]])
A2 = np.array([[-0.1, 2.0], [-1.0, -0.1]])


def test_common_lyapunov_feasible_with_the_known_decay_rate():
    """A_i = -a I + S_i (S_i skew): P = I gives A'P + PA = -2a I, and no P can do better than
    the modes' own decay a."""
    S = np.array([[0.0, 3.0, 1.0], [-3.0, 0.0, 2.0], [-1.0, -2.0, 0.0]])
    a = 0.7
    modes = [-a * np.eye(3) + S, -a * np.eye(3) - 2.0 * S, -a * np.eye(3) + 0.1 * S]
    cert = common_lyapunov(modes, rtol=1e-4)
    assert cert.feasible and cert.all_modes_stable
    assert cert.decay_rate == pytest.approx(a, rel=2e-4)
    P = cert.P
    assert np.min(np.linalg.eigvalsh(P)) > 0
    for A in modes:  # the certificate, checked here
        assert np.max(np.linalg.eigvalsh(A.T @ P + P @ A + 2 * 0.99 * a * P)) < 0
    assert "common quadratic Lyapunov function V = x'Px exists" in cert.summary()


def test_stable_modes_whose_switching_diverges_have_no_common_lyapunov_function():
    for A in (A1, A2):
        assert np.max(np.linalg.eigvals(A).real) < 0  # each mode is stable
    cert = common_lyapunov([A1, A2], names=["A1", "A2"])
    assert not cert.feasible and cert.P is None
    assert cert.all_modes_stable
    assert "Every one of the 2 modes is stable on its own" in cert.message
    assert "NO common quadratic Lyapunov function" in cert.message

    # the divergence: A1 in the 2nd and 4th quadrants, A2 in the 1st and 3rd
    def f(t, x):
        return (A1 if x[0] * x[1] < 0 else A2) @ x

    sol = si.solve_ivp(f, (0.0, 30.0), [1.0, 0.0], max_step=0.01, rtol=1e-9, atol=1e-12)
    assert np.linalg.norm(sol.y[:, -1]) > 100.0
    # each mode alone decays from the same start
    for A in (A1, A2):
        assert np.linalg.norm(sla.expm(A * 30.0) @ [1.0, 0.0]) < 0.2


def test_discrete_common_lyapunov():
    """Samples of the same pair (period 0.5 s): stable each, no common function; rotations scaled
    by r < 1 share P = I, with the contraction r exactly."""
    h = 0.5
    cert = common_lyapunov([sla.expm(A1 * h), sla.expm(A2 * h)], dt=h)
    assert not cert.feasible and cert.all_modes_stable
    r = 0.8

    def rot(t):
        return r * np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])

    cert = common_lyapunov(
        [
            control.ss(rot(0.3), np.zeros((2, 1)), np.zeros((1, 2)), 0, h),
            control.ss(rot(-1.1), np.zeros((2, 1)), np.zeros((1, 2)), 0, h),
        ],
        rtol=1e-4,
    )
    assert cert.feasible and cert.dt == h
    assert cert.contraction == pytest.approx(r, rel=2e-4)
    assert cert.decay_rate == pytest.approx(-math.log(r) / h, rel=2e-3)


def test_common_lyapunov_unstable_mode_and_bad_input():
    cert = common_lyapunov([A1, np.array([[0.1, 0.0], [0.0, -1.0]])])
    assert not cert.feasible and "mode 1 is not stable" in cert.message
    with pytest.raises(ValueError, match=r"modes\[1\] has 3 states"):
        common_lyapunov([A1, np.eye(3)])
    with pytest.raises(ValueError, match="solver = 'MOSEKK'"):
        common_lyapunov([A1], solver="MOSEKK")


G3 = control.tf([1.0], np.polymul(np.polymul([1.0, 1.0], [1.0, 2.0]), [1.0, 3.0]))


def test_largest_sector_equals_the_circle_criterion():
    """Sector [0, b] around a stable SISO G: the circle criterion (lossless for one channel, KYP)
    holds iff 1 + b Re G(jw) > 0 for all w, i.e. b < -1/min Re G; the linear (Nyquist) limit of
    1/((s+1)(s+2)(s+3)) is 60 (phase -180 deg at w^2 = 11)."""
    w = np.logspace(-3, 3, 200001)
    b_circle = -1.0 / np.min(np.real(G3(1j * w)))
    cert = largest_sector(control.ss(G3), (0.0, 0.0), rtol=1e-4)
    assert cert.feasible
    assert cert.certified_end == pytest.approx(b_circle, rel=2e-4)
    assert cert.linear_limit == pytest.approx(60.0, rel=1e-6)
    # just above the circle bound: not certified
    assert not sector_certificate(G3, (0.0, 1.01 * b_circle)).feasible
    assert sector_certificate(G3, (0.0, 0.99 * b_circle)).feasible


def test_discrete_sector_against_the_frequency_condition():
    Gd = control.sample_system(G3, 0.2, method="zoh")
    w = np.linspace(1e-6, math.pi / 0.2, 200001)
    b_circle = -1.0 / np.min(np.real(Gd(np.exp(1j * w * 0.2))))
    cert = largest_sector(Gd, (0.0, 0.0), rtol=1e-4)
    assert cert.certified_end == pytest.approx(b_circle, rel=2e-4)
    assert cert.dt == pytest.approx(0.2)


def test_sector_lower_end_and_bad_input():
    # the lower end of [a, 0] for -G3 (a negative gain on -G is a positive gain on G)
    cert = largest_sector(control.ss(-G3), (0.0, 0.0), end="lower", rtol=1e-3)
    assert cert.linear_limit == pytest.approx(-60.0, rel=1e-6)
    assert -cert.certified_end <= 60.0
    with pytest.raises(ValueError, match=r"sectors\[0\] = \(1.0, 0.0\): needs a <= b"):
        sector_certificate(G3, (1.0, 0.0))
    with pytest.raises(ValueError, match="end = 'top'"):
        largest_sector(G3, (0.0, 0.0), end="top")


@pytest.fixture(scope="module")
def clutch():
    p = default_params()
    dt = reduced_model(p)
    op = slip_operating_point(
        dt, omega_engine=rpm_to_rad_s(1600), omega_driven=50.0, x_c=0.07, throttle=0.6
    )
    ref = constant(rpm_to_rad_s(1600))
    return op, {n: load_controller(n).build(p, reference=ref) for n in ("paper", "pi-10ms")}


def test_clutch_pedal_held_against_the_judder_closed_form(clutch):
    op, _ = clutch
    jt = judder_threshold(op, None)
    cert = clutch_sector_certificate(op, None, rtol=1e-4)
    # the linear limit of the Lur'e loop is the judder threshold (exact for the pedal held)
    assert cert.mu_slope_linear == pytest.approx(jt.mu_slope_crit, rel=1e-5)
    assert cert.judder_closed_form == pytest.approx(jt.mu_slope_crit, rel=1e-12)
    # certified: inside the linear range, and (one channel: the circle criterion) close to it
    assert jt.mu_slope_crit < cert.mu_slope_certified < 0
    assert cert.ratio > 0.9


def test_clutch_law6_sector_and_saturation(clutch):
    op, ctl = clutch
    jt = judder_threshold(op, ctl["paper"])
    cert = clutch_sector_certificate(op, ctl["paper"], rtol=1e-3)
    assert cert.mu_slope_linear == pytest.approx(
        judder_crossing(op, ctl["paper"]).mu_slope_crit, rel=1e-4
    )
    assert cert.mu_slope_linear == pytest.approx(
        jt.mu_slope_crit, rel=5e-3
    )  # the closed form: 0.2 %
    assert cert.mu_slope_linear < cert.mu_slope_certified < 0
    # with the saturation in [0, 1] the pedal may as well be held: the pedal-held limit binds
    sat = clutch_sector_certificate(op, ctl["paper"], saturation=(0.0, 1.0), rtol=1e-3)
    held = judder_threshold(op, None).mu_slope_crit
    assert held <= sat.mu_slope_certified < 0
    assert sat.mu_slope_linear == pytest.approx(held, rel=1e-4)


def test_clutch_sampled_controller_lifted_loop(clutch):
    op, ctl = clutch
    jn = judder_crossing(op, ctl["pi-10ms"]).mu_slope_crit
    cert = clutch_sector_certificate(op, ctl["pi-10ms"], mu_grid=3, rtol=0.05)
    assert cert.dt == pytest.approx(0.01)
    assert jn <= cert.mu_slope_certified < 0
    assert "lifted loop" in cert.message


def test_zoh_with_delay_matches_sample_system_and_integer_delays():
    G = control.ss(control.tf([2.0, 1.0], [1.0, 3.0, 2.0]))
    Pd0 = zoh_with_delay(G, 0.1)
    ref = control.sample_system(G, 0.1, method="zoh")
    z = np.exp(1j * np.linspace(0.01, 31.0, 40) * 0.1)
    assert Pd0(z).ravel() == pytest.approx(ref(z).ravel(), rel=1e-10)
    Pd2 = zoh_with_delay(G, 0.1, delay=0.2)
    assert Pd2(z).ravel() == pytest.approx((ref(z) * z**-2).ravel(), rel=1e-10)


def test_zoh_with_fractional_delay_is_exact_at_the_samples():
    """A first-order plant driven by a delayed staircase, simulated by scipy on a grid that holds
    every switching instant (ZOH interpolation is then exact)."""
    a, T, tau = 3.0, 0.1, 0.23
    G = control.ss(control.tf([a], [1.0, a]))
    Pd = zoh_with_delay(G, T, delay=tau)
    rng = np.random.default_rng(1)
    u = rng.normal(size=40)
    _, yd = control.forced_response(Pd, T=np.arange(40) * T, U=u)
    # continuous: input u[k] acts on [k T + tau, (k+1) T + tau)
    t = np.arange(391) * 0.01  # uniform, every kT and kT + tau on it
    k = np.floor((t - tau) / T + 1e-9).astype(int)
    uc = np.where(k >= 0, u[np.clip(k, 0, 39)], 0.0)
    _, yc, _ = ss.lsim((G.A, G.B, G.C, G.D), uc, t, interp=False)
    idx = [int(np.argmin(np.abs(t - kk * T))) for kk in range(40)]
    assert yd == pytest.approx(yc[idx], abs=1e-9)


def test_sampled_loop_poles():
    """A discrete PI on 1/(s+1) with one sample of delay: the poles of feedback(K P_zoh z^-1)."""
    T = 0.05
    G = control.tf([1.0], [1.0, 1.0])
    K = control.tf([2.0, -1.8], [1.0, -1.0], T)
    cl = sampled_loop(G, K, delay=T)
    ref = control.feedback(
        K * control.sample_system(G, T, method="zoh") * control.tf([1.0], [1.0, 0.0], T), 1
    )
    assert np.sort_complex(cl.poles()) == pytest.approx(np.sort_complex(ref.poles()), abs=1e-9)
    # a common Lyapunov function over delays 0, 1 and 2 samples (one buffer of 2): the delay may
    # change from sample to sample; no certificate can beat the slowest mode
    modes = [sampled_loop(G, K, delay=d * T, buffer=2) for d in (0, 1, 2)]
    cert = common_lyapunov(modes)
    assert cert.feasible and cert.dt == pytest.approx(T)
    slowest = max(float(np.max(np.abs(m.poles()))) for m in modes)
    assert slowest <= cert.contraction < 1.0
