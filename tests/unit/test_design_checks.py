"""The design tools' shared pieces: the loop check (design/checks.py), the PI/PID structure
(design/controllers.py) and the spec options (design/options.py), against python-control and
closed forms computed here."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from drivetrain_ctrl.design import (
    HinfSpec,
    LoopCheck,
    Plant,
    RobustSpec,
    check_loop,
    check_plant_set,
    pid_controller,
)
from drivetrain_ctrl.design.checks import check_grid, disk_figures, worst_figures
from drivetrain_ctrl.design.controllers import INTEGRATORS, integrator_response
from drivetrain_ctrl.design.options import frequency_vector, spec_with_options

s = control.tf("s")


def test_check_loop_without_delay_is_python_controls_margins():
    P = 2 / ((s + 1) * (0.2 * s + 1) * (0.05 * s + 1))
    C = pid_controller(1.0, 0.8)
    c = check_loop(P, C)
    L = C * P
    gm, pm, _sm, _wpc, wgc, _wms = control.stability_margins(L)
    assert isinstance(c, LoopCheck) and c.stable is True and c.active == () and not c.limiting
    assert c.gain_margin_db == pytest.approx(20 * math.log10(gm), rel=1e-9)
    assert c.phase_margin_deg == pytest.approx(pm, rel=1e-9)
    assert c.crossover_rad_s == pytest.approx(wgc, rel=1e-9)
    w = check_grid(np.logspace(-2, 3, 50))
    c2 = check_loop(P, C, grid=w)
    S = 1 / (1 + L(1j * w))
    assert c2.ms == pytest.approx(np.max(np.abs(S)), rel=1e-12)
    assert c2.ms_frequency_rad_s == w[np.argmax(np.abs(S))]
    assert c2.mt == pytest.approx(np.max(np.abs(L(1j * w) * S)), rel=1e-12)
    assert c2.ks == pytest.approx(np.max(np.abs(C(1j * w) * S)), rel=1e-12)
    alpha = 1 / np.max(np.abs(S - 0.5))
    assert c2.disk_margin == pytest.approx(alpha, rel=1e-12)
    assert (c2.disk_margin_db, c2.disk_margin_deg) == disk_figures(alpha)
    dm, dgm, dpm = control.disk_margins(L, w, skew=0.0)
    assert (c2.disk_margin_db, c2.disk_margin_deg) == pytest.approx((dgm, dpm), rel=1e-6)


def test_check_loop_with_delay_uses_the_exact_response():
    """exp(-0.5 s)/(s+1) with an integral controller ki/s: |L| = 1 at w with
    ki = w sqrt(1 + w^2); PM = 180 - 90 - atan(w) - 0.5 w (degrees)."""
    wc = 0.8
    ki = wc * math.sqrt(1 + wc**2)
    c = check_loop(Plant(1 / (s + 1), delay=0.5, name="lag"), pid_controller(0.0, ki))
    pm = 90 - math.degrees(math.atan(wc) + 0.5 * wc)
    assert c.name == "lag" and c.stable is True
    assert c.phase_margin_deg == pytest.approx(pm, abs=0.02)
    assert c.crossover_rad_s == pytest.approx(wc, rel=1e-3)
    assert dict(c.reasons)["stable"].startswith("poles with a Pade approximation")


def test_check_stability_unknown_for_a_fractional_sample_delay():
    Pd = control.sample_system(1 / (s + 1), 0.1, method="zoh")
    c = check_loop(Plant(Pd, delay=0.15), pid_controller(0.5, 0.5, dt=0.1))
    assert c.stable is None and "not a multiple" in dict(c.reasons)["stable"]
    assert c.phase_margin_deg is not None


def test_check_plant_set_and_worst_figures():
    plants = [Plant(k / (s + 1) ** 3, name=f"k{k}") for k in (0.5, 1.0, 2.0)]
    C = pid_controller(0.3, 0.3)
    checks = check_plant_set(plants, C, active=[(), (("ms", 1.0, 0.0),), ()])
    assert [c.name for c in checks] == ["k0.5", "k1.0", "k2.0"]
    assert [c.limiting for c in checks] == [False, True, False]
    w = worst_figures(checks)
    assert w["ms_max"] == max(c.ms for c in checks) == checks[2].ms
    assert w["gain_margin_db_min"] == min(c.gain_margin_db for c in checks)  # type: ignore[type-var]
    assert w["all_stable"] is True and w["n_plants"] == 3
    unstable = check_loop(plants[2], pid_controller(20.0, 20.0))
    assert unstable.stable is False
    assert worst_figures([*checks, unstable])["all_stable"] is False
    with pytest.raises(ValueError, match="active: 1 entries for 3 plants"):
        check_plant_set(plants, C, active=[()])
    with pytest.raises(ValueError, match="check_loop takes one plant, got 3"):
        check_loop(plants, C)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_pid_controller_and_integrator_response_agree(integrator):
    dt, w = 0.02, np.array([0.3, 3.0, 30.0])
    z = np.exp(1j * w * dt)
    C = pid_controller(1.5, 2.0, dt=dt, integrator=integrator)
    F = integrator_response(w, dt, integrator)
    assert np.asarray(C(z)).ravel() == pytest.approx(1.5 + 2.0 * F, rel=1e-12)
    assert integrator_response(w, 0.0) == pytest.approx(1 / (1j * w))
    P = pid_controller(2.5, 0.0, dt=dt)  # a P controller is a static gain
    assert list(P.den[0][0]) == [1.0] and list(P.num[0][0]) == [2.5] and P.dt == dt
    with pytest.raises(ValueError, match=r"integrator = 'euler': must be one of"):
        pid_controller(1.0, 1.0, dt=dt, integrator="euler")


def test_spec_options():
    assert spec_with_options(RobustSpec, "robust_pi", None, {"ms": 1.3}).ms == 1.3
    base = HinfSpec(bandwidth=2.0)
    assert spec_with_options(HinfSpec, "hinf_mixsyn", base, {"ms": 1.5}).bandwidth == 2.0
    with pytest.raises(ValueError, match=r"robust_pi: unknown option mss = 1\.2; did you mean"):
        spec_with_options(RobustSpec, "robust_pi", None, {"mss": 1.2})
    with pytest.raises(TypeError, match="must be a RobustSpec or None"):
        spec_with_options(RobustSpec, "robust_pi", base, {})
    assert frequency_vector("omega", [1, 2, 3], 3) == (1.0, 2.0, 3.0)
    with pytest.raises(ValueError, match=r"omega = \[1, 2\]: a 1-D grid of >= 3"):
        frequency_vector("omega", [1, 2], 3)
    with pytest.raises(ValueError, match="strictly increasing"):
        frequency_vector("omega", [1, 3, 2], 3)
