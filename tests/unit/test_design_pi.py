"""PI from specifications (design/pi.py): closed forms computed by hand here, achieved margins
re-checked with python-control, the infeasible path, exact delays and discrete plants."""

from __future__ import annotations

import math
import pickle

import control
import numpy as np
import pytest

from drivetrain_ctrl.design.pi import PIDesign, design_pi, pi_controller_tf, pi_gains_at
from drivetrain_ctrl.design.plants import Plant

s = control.tf("s")


def _hand_pi(P_wc: complex, F_wc: complex, pm_deg: float) -> tuple[float, float]:
    """kp + ki F(wc) = -exp(j pm) / P(wc), solved for the two real gains."""
    c = -np.exp(1j * math.radians(pm_deg)) / P_wc
    ki = c.imag / F_wc.imag
    return c.real - ki * F_wc.real, ki


def _margins(L):
    gm, pm, _sm, _wpc, wgc, _wms = control.stability_margins(L)
    return pm, wgc


def test_first_order_closed_form():
    """P = K/(tau s + 1): |C| = sqrt(1 + (tau wc)^2)/K, arg C = PM - 180 + atan(tau wc)."""
    K, tau, wc, pm = 2.0, 1.0, 2.0, 60.0
    d = design_pi(K / (tau * s + 1), wc=wc, phase_margin=pm)
    mag = math.hypot(1.0, tau * wc) / K
    ph = math.radians(pm - 180.0) + math.atan(tau * wc)
    assert d.kp == pytest.approx(mag * math.cos(ph), rel=1e-10)
    assert d.ki == pytest.approx(-wc * mag * math.sin(ph), rel=1e-10)  # C = kp - j ki / wc
    assert d.feasible and d.stable and d.message == ""
    pm_pc, wgc = _margins(d.controller * K / (tau * s + 1))  # python-control, rational loop
    assert pm_pc == pytest.approx(pm, abs=1e-6) and wgc == pytest.approx(wc, rel=1e-6)
    assert d.phase_margin == pytest.approx(pm, abs=1e-3) and d.crossover == pytest.approx(
        wc, rel=1e-4
    )
    assert isinstance(d, PIDesign) and "kp = " in d.summary()
    assert pickle.loads(pickle.dumps(d)).kp == d.kp


def test_second_order_closed_form():
    wc, pm = 3.0, 45.0
    P = 5.0 / ((s + 1) * (0.2 * s + 1))
    d = design_pi(P, wc=wc, phase_margin=pm)
    Pw = 5.0 / ((1j * wc + 1) * (0.2j * wc + 1))
    kp, ki = _hand_pi(Pw, 1 / (1j * wc), pm)
    assert kp > 0 and ki > 0
    assert d.kp == pytest.approx(kp, rel=1e-10) and d.ki == pytest.approx(ki, rel=1e-10)
    pm_pc, wgc = _margins(control.tf([kp, ki], [1, 0]) * P)
    assert pm_pc == pytest.approx(pm, abs=1e-6) and wgc == pytest.approx(wc, rel=1e-6)
    assert d.margins.phase_margin_deg == pytest.approx(pm, abs=1e-4)
    assert d.stable and d.feasible
    assert pi_gains_at(P, wc, pm) == pytest.approx((kp, ki), rel=1e-12)


def test_infeasible_needs_phase_lead():
    """1/(s+1)^3 at wc = 1 has phase -135 deg: PM 60 needs +15 deg of lead, so ki < 0. The closest
    PI is a P controller, |C P| = 1 at wc, with PM 45; 60 deg is reachable up to wc = tan 40 deg."""
    P = 1 / (s + 1) ** 3
    d = design_pi(P, wc=1.0, phase_margin=60.0)
    assert not d.feasible
    assert d.ki == 0.0 and d.kp == pytest.approx(2 * math.sqrt(2), rel=1e-10)
    pm_pc, wgc = _margins(d.controller * P)
    assert pm_pc == pytest.approx(45.0, abs=1e-6) and wgc == pytest.approx(1.0, rel=1e-6)
    assert d.phase_margin == pytest.approx(45.0, abs=1e-3)
    assert "needs phase lead" in d.message and "45 deg" in d.message
    edge = math.tan(math.radians(40.0))  # 3 atan(w) = 120 deg
    assert f"up to {edge:.4g} rad/s" in d.message
    assert "NOT FEASIBLE" in d.summary()
    # just inside the edge the spec is feasible
    assert design_pi(P, wc=0.99 * edge, phase_margin=60.0).feasible


def test_infeasible_needs_more_lag_than_an_integrator():
    """1/(s+1) at wc = tan 10 deg has phase -10 deg: PM 30 needs -140 deg from the controller,
    more lag than an integrator (kp < 0). The closest is an I controller, PM 80 deg."""
    wc = math.tan(math.radians(10.0))
    d = design_pi(1 / (s + 1), wc=wc, phase_margin=30.0)
    assert not d.feasible and d.kp == 0.0
    assert d.ki == pytest.approx(wc * math.hypot(1.0, wc), rel=1e-10)  # |ki/(j wc) P| = 1
    assert d.phase_margin == pytest.approx(80.0, abs=1e-2)
    assert "more phase lag than an integrator" in d.message and "80 deg" in d.message


def test_delay_plant_exact():
    """exp(-0.5 s)/(s+1): the closed form uses the exact delay phase -0.5 wc; the achieved margin
    (python-control on the exact frequency response) equals the spec, the Pade loop nearly."""
    tau, wc, pm = 0.5, 1.0, 50.0
    p = Plant(1 / (s + 1), delay=tau)
    d = design_pi(p, wc=wc, phase_margin=pm)
    Pw = np.exp(-1j * wc * tau) / (1j * wc + 1)
    kp, ki = _hand_pi(Pw, 1 / (1j * wc), pm)
    assert d.kp == pytest.approx(kp, rel=1e-10) and d.ki == pytest.approx(ki, rel=1e-10)
    assert d.phase_margin == pytest.approx(pm, abs=0.02)
    assert d.crossover == pytest.approx(wc, rel=1e-3)
    # ignoring the delay would have given different gains
    kp0, ki0 = _hand_pi(1 / (1j * wc + 1), 1 / (1j * wc), pm)
    assert abs(ki0 - ki) > 0.1
    pade = d.controller * control.tf(*control.pade(tau, 5)) / (s + 1)
    assert _margins(pade)[0] == pytest.approx(pm, abs=0.1)
    assert "Pade" in d.delay_model and d.stable


@pytest.mark.parametrize("integrator", ["forward", "backward", "tustin"])
def test_discrete_plant_with_sample_delay(integrator):
    """ZOH samples of 1/(s+1) at Ts = 0.05 s with one sample of delay; F of each integrator."""
    Ts, wc, pm = 0.05, 5.0, 60.0
    a = math.exp(-Ts)
    Pd = control.tf([1 - a], [1, -a], Ts)
    d = design_pi(Plant(Pd, delay=Ts), wc=wc, phase_margin=pm, integrator=integrator)
    z = np.exp(1j * wc * Ts)
    F = {
        "forward": Ts / (z - 1),
        "backward": Ts * z / (z - 1),
        "tustin": Ts / 2 * (z + 1) / (z - 1),
    }
    kp, ki = _hand_pi((1 - a) / (z - a) / z, F[integrator], pm)
    assert d.kp == pytest.approx(kp, rel=1e-9) and d.ki == pytest.approx(ki, rel=1e-9)
    assert d.controller.dt == Ts and d.integrator == integrator
    C = d.controller
    assert complex(C(z)) == pytest.approx(kp + ki * F[integrator], rel=1e-9)
    pm_pc, wgc = _margins(C * Pd * control.tf([1], [1, 0], Ts))  # rational, exact z^-1
    assert pm_pc == pytest.approx(pm, abs=1e-6) and wgc == pytest.approx(wc, rel=1e-6)
    assert d.stable and d.feasible and "z^-1" in d.delay_model


def test_forward_euler_matches_shipped_controller():
    """The forward-Euler PI is the integrator of ControllerSpec.lti (x+ = x + Ts e, y = ki x + kp e)."""
    from drivetrain_ctrl.control.laws import ControllerSpec

    spec = ControllerSpec(name="t", law="pi", kp=1e-3, ki=5e-3, sample_period_s=0.01)
    mine = pi_controller_tf(1e-3, 5e-3, dt=0.01, integrator="forward")
    z = np.exp(1j * np.array([0.3, 3.0, 30.0]) * 0.01)
    assert np.allclose(control.tf(spec.lti())(z), mine(z), rtol=1e-12)


def test_phase_margin_rule_maximises_ki():
    """No wc: the crossover with the largest ki at PM 60, against a brute-force scan of the
    closed form ki(wc) = -wc Im(-exp(j PM)/P(j wc))."""
    P = 1 / (s + 1) ** 3
    d = design_pi(P)
    assert d.rule == "max ki at phase margin" and d.pm_target == 60.0
    w = np.linspace(0.05, 1.5, 20001)
    Pw = 1 / (1j * w + 1) ** 3
    c = -np.exp(1j * math.radians(60)) / Pw
    ki = -w * c.imag
    kp = c.real
    ki[(kp < 0) | (ki < 0)] = -np.inf
    k = int(np.argmax(ki))
    assert d.ki == pytest.approx(ki[k], rel=2e-3)
    assert d.crossover == pytest.approx(w[k], rel=0.02)
    assert d.phase_margin == pytest.approx(60.0, abs=0.1) and d.feasible and d.stable


def test_ms_rule_against_brute_force():
    """Largest ki with max|S| <= 1.4 on 1/(s+1)^3, against a brute-force (kp, ki) grid."""
    P = 1 / (s + 1) ** 3
    d = design_pi(P, ms=1.4)
    assert d.rule == "max ki under Ms" and d.feasible and d.stable
    assert d.ms <= 1.4 * 1.001
    w = np.logspace(-2, 1.5, 500)
    Pw = 1 / (1j * w + 1) ** 3
    kps = np.linspace(0.0, 1.5, 151)
    kis = np.linspace(0.0, 0.6, 601)
    best = 0.0
    for kp in kps:
        L = (kp + kis[:, None] / (1j * w[None, :])) * Pw[None, :]
        peak = np.max(1 / np.abs(1 + L), axis=1)
        ok = kis[peak <= 1.4]
        if ok.size:  # |S| bounded and kp, ki >= 0: stable for this stable plant at these gains
            best = max(best, float(ok.max()))
    assert d.ki == pytest.approx(best, rel=0.01)
    cl = control.feedback(d.controller * P, 1)
    assert np.all(control.poles(cl).real < 0)


def test_integrator_plant_no_limit_says_so():
    d = design_pi(1 / s)
    assert d.feasible and "upper end" in d.message
    d2 = design_pi(1 / s, wc=4.0, phase_margin=70.0)  # c = -exp(j pm) j wc
    assert d2.kp == pytest.approx(4.0 * math.sin(math.radians(70)), rel=1e-10)
    assert d2.ki == pytest.approx(16.0 * math.cos(math.radians(70)), rel=1e-10)


def test_unreachable_everywhere():
    d = design_pi(1 / s**2)
    assert not d.feasible and not d.stable
    assert "not reachable" in d.message


def test_negative_plant_hint():
    d = design_pi(-1 / (s + 1), wc=1.0, phase_margin=60.0)
    assert not d.feasible and "negative" in d.message


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"wc": -1.0}, r"wc = -1.0: must be > 0"),
        ({"wc": float("inf")}, r"wc = inf"),
        ({"phase_margin": 190.0}, r"phase_margin = 190.0: must be > 0.* and < 180"),
        ({"ms": 0.9}, r"ms = 0.9: must be > 1"),
        ({"integrator": "tustin"}, r"integrator = 'tustin': the plant is continuous"),
        ({"grid": [1.0]}, r"grid = \[1.0\]"),
        ({"pade_order": 0}, r"pade_order = 0"),
    ],
)
def test_bad_input(kw, match):
    with pytest.raises(ValueError, match=match):
        design_pi(1 / (s + 1), **kw)


def test_bad_input_discrete_and_sets():
    Pd = control.tf([1], [1, -0.5], 0.1)
    with pytest.raises(ValueError, match=r"integrator = 'euler': must be one of"):
        design_pi(Pd, integrator="euler")
    with pytest.raises(ValueError, match=r"method = 'tustin'.*now called integrator"):
        design_pi(Pd, method="tustin")
    with pytest.raises(ValueError, match=r"wc = 40.0 rad/s: must be below the Nyquist"):
        design_pi(Pd, wc=40.0, phase_margin=60)
    with pytest.raises(ValueError, match=r"takes one plant, got a set of 2"):
        design_pi([1 / (s + 1), 1 / (s + 2)])
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'pm'"):
        design_pi(1 / (s + 1), pm=60)  # type: ignore[call-arg]


@pytest.mark.parametrize(
    ("plant", "method"),
    [
        (Plant((s + 0.5) / ((s + 1) * (s + 2)), delay=0.3), "continuous"),
        (Plant((-0.5 * s + 1) / (s + 2)), "continuous"),  # feedthrough D != 0
        (Plant(control.c2d(1 / ((s + 1) * (s + 4)), 0.1), delay=0.1), "forward"),
        (Plant(control.c2d(1 / ((s + 1) * (s + 4)), 0.1)), "backward"),
        (Plant(control.c2d(3 / (s + 1), 0.1)), "tustin"),
    ],
)
def test_stability_screen_agrees_with_python_control(plant, method):
    """The stacked-eigenvalue screen of the scan against python-control's feedback poles."""
    from drivetrain_ctrl.design.pi import _stable_mask

    rng = np.random.default_rng(1)
    kp = 10 ** rng.uniform(-2, 1.7, 60)
    ki = 10 ** rng.uniform(-2, 1.7, 60)
    got = _stable_mask(plant, kp, ki, method, 5)
    G = plant.with_pade(5)
    m = "forward" if method == "continuous" else method
    want = []
    for a, b in zip(kp, ki, strict=True):
        cl = control.feedback(pi_controller_tf(a, b, dt=plant.dt, integrator=m) * G, 1)
        poles = control.poles(cl)
        want.append(bool(np.all(np.abs(poles) < 1) if plant.dt else np.all(poles.real < 0)))
    assert got.tolist() == want
    assert 0 < sum(want) < 60  # both outcomes occur


def test_ms_rule_discrete_with_delay_against_brute_force():
    """ZOH 1/((s+1)(s+4)) at 0.1 s with a sample of delay, Ms <= 1.5: the largest stable ki of
    a (kp, ki) grid (stability by python-control) against the design."""
    Ts = 0.1
    Pd = control.c2d(1 / ((s + 1) * (s + 4)), Ts)
    plant = Plant(Pd, delay=Ts)
    d = design_pi(plant, ms=1.5)
    assert d.feasible and d.stable and d.ms <= 1.5 * 1.001
    w = np.linspace(1e-3, math.pi / Ts, 1000)
    z = np.exp(1j * w * Ts)
    Pw = np.array([complex(Pd(x)) for x in z]) / z
    F = Ts / (z - 1)
    kps = np.linspace(0, 10, 101)
    kis = np.linspace(0, 10, 501)
    cands = []
    for kp in kps:
        L = (kp + kis[:, None] * F[None, :]) * Pw[None, :]
        ok = np.max(1 / np.abs(1 + L), axis=1) <= 1.5
        cands += [(ki, kp) for ki in kis[ok]]
    Gd = Pd * control.tf([1], [1, 0], Ts)
    best = None
    for ki, kp in sorted(cands, reverse=True):
        cl = control.feedback(pi_controller_tf(kp, ki, dt=Ts) * Gd, 1)
        if np.all(np.abs(control.poles(cl)) < 1):
            best = ki
            break
    assert best is not None and d.ki == pytest.approx(best, rel=0.01)


def test_to_spec_is_the_designed_controller(tmp_path):
    """A forward-Euler design becomes law "pi" with the plant's delay in samples; a Tustin one
    law "lti"; both files' LTI blocks have the design's frequency response."""
    from drivetrain_ctrl.control.laws import load_controller, save_controller

    Ts = 0.05
    a = math.exp(-Ts)
    # clutch-like scale: the gains come out in the controller files' range (< 1 m s/rad)
    plant = Plant(control.tf([1e4 * (1 - a)], [1, -a], Ts), delay=2 * Ts)
    z = np.exp(1j * np.array([0.5, 5.0, 30.0]) * Ts)
    for method, law in (("forward", "pi"), ("tustin", "lti")):
        d = design_pi(plant, wc=3.0, phase_margin=60.0, integrator=method)
        spec = d.to_spec(f"my-{method}")
        assert spec.law == law and spec.delay_samples == 2 and spec.sample_period_s == Ts
        assert spec.design["rule"] == "given crossover"
        assert spec.design["phase_margin_deg"] == pytest.approx(60.0, abs=1e-3)
        back = load_controller(save_controller(spec, tmp_path / f"{method}.toml"))
        assert np.allclose(control.tf(back.lti())(z), d.controller(z), rtol=1e-9)
    d = design_pi(Plant(1e4 / (s + 1), delay=0.1), wc=1.0, phase_margin=60.0)
    with pytest.raises(ValueError, match=r"continuous plant has a delay of 0.1 s"):
        d.to_spec("x")
    assert d.to_spec("x", delay_samples=0).law == "pi"
