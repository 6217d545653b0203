"""Robust fixed-structure tuning (design/robust.py): known answers computed here by brute force,
every figure re-checked with python-control on dense grids, independently of the tuner."""

from __future__ import annotations

import json
import math

import control
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from drivetrain_ctrl.design.controllers import pid_controller
from drivetrain_ctrl.design.plants import Plant
from drivetrain_ctrl.design.robust import (
    InfeasibleSpecError,
    RobustSpec,
    UnboundedSpecError,
    robust_pi,
    robust_pid,
)

s = control.tf("s")
MS = 1.4
# a textbook set: first- and second-order lags with dead time (Astrom & Hagglund's kind)
SET = (
    (1 / (s + 1), 0.5, "lag1"),
    (1 / ((s + 1) * (0.5 * s + 1)), 0.3, "lag2"),
    (2 / (2 * s + 1), 0.2, "lag1-slow"),
)
W_DENSE = np.logspace(-3, 3, 6000)


def _plants(dt: float = 0.0) -> list[Plant]:
    if not dt:
        return [Plant(sys, d, n) for sys, d, n in SET]
    return [Plant(control.c2d(sys, dt, "zoh"), round(d / dt) * dt, n) for sys, d, n in SET]


def _resp(sys, w: np.ndarray, delay: float = 0.0) -> np.ndarray:
    """Exact frequency response by python-control, the delay as exp(-j w delay)."""
    mag, ph, _ = control.frequency_response(sys, w)
    return np.asarray(mag * np.exp(1j * ph)).reshape(-1) * np.exp(-1j * w * delay)


def _loops(C, plants: list[Plant], w: np.ndarray) -> np.ndarray:
    """L = C P on w for every plant (python-control responses), shape (m, w)."""
    Cw = _resp(C, w)
    return np.stack([Cw * _resp(p.sys, w, p.delay) for p in plants])


def _brute_force(P: np.ndarray, F: np.ndarray, *, ms: float, mt: float | None = None) -> tuple:
    """Max ki over (kp, ki), L = P (kp + ki F), s.t. max |S| <= ms (and |T| <= mt) on the grid.

    For each kp, ki_max(kp) by bisection from a tiny ki upwards (the feasible ki form an interval
    from 0); the best kp from a 61-point scan refined by bounded Brent."""

    def ok(kp: float, ki: float) -> bool:
        L = P * (kp + ki * F)
        if np.max(np.abs(1 / (1 + L))) > ms:
            return False
        return mt is None or np.max(np.abs(L / (1 + L))) <= mt

    def ki_max(kp: float) -> float:
        lo = 1e-6
        if not ok(kp, lo):
            return 0.0
        hi = lo
        while ok(kp, hi):
            lo, hi = hi, hi * 2
        for _ in range(45):
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if ok(kp, mid) else (lo, mid)
        return lo

    kps = np.linspace(0.0, 3.0, 61)
    vals = [ki_max(k) for k in kps]
    i = int(np.argmax(vals))
    r = minimize_scalar(
        lambda k: -ki_max(k),
        bounds=(kps[max(i - 1, 0)], kps[min(i + 1, kps.size - 1)]),
        method="bounded",
        options={"xatol": 1e-7},
    )
    return float(r.x), float(-r.fun)


@pytest.fixture(scope="module")
def pi_design():
    return robust_pi(_plants(), ms=MS)


# -- known answers ------------------------------------------------------------------------------


def test_robust_pi_within_one_percent_of_brute_force(pi_design):
    r = pi_design
    P = np.stack([_resp(sys, W_DENSE, d) for sys, d, _ in SET])
    kp_b, ki_b = _brute_force(P, 1 / (1j * W_DENSE), ms=MS)
    assert ki_b > 0.3  # a real optimum, not a degenerate one
    assert abs(r.ki - ki_b) <= 0.01 * ki_b
    # the tuner holds the bound between grid points too: it cannot beat the brute force by more
    # than the brute force's own grid error
    assert r.ki <= ki_b * (1 + 1e-3)
    assert r.kp == pytest.approx(kp_b, rel=0.05)
    assert r.converged, r.message
    assert r.limiting  # at least one plant limits ki


def test_robust_pi_with_mt_within_one_percent_of_brute_force():
    mt = 1.05
    r = robust_pi(_plants(), ms=MS, mt=mt)
    P = np.stack([_resp(sys, W_DENSE, d) for sys, d, _ in SET])
    _kp, ki_b = _brute_force(P, 1 / (1j * W_DENSE), ms=MS, mt=mt)
    _kp0, ki_ms_only = _brute_force(P, 1 / (1j * W_DENSE), ms=MS)
    assert ki_b < ki_ms_only * 0.999  # the Mt bound binds in this case
    assert abs(r.ki - ki_b) <= 0.01 * ki_b
    assert any(b == "mt" for p in r.plants for b, _w, _s in p.active)
    L = _loops(r.controller, _plants(), W_DENSE)
    assert np.max(np.abs(L / (1 + L))) <= mt * (1 + 1e-6)


def test_discrete_pi_within_one_percent_of_brute_force():
    dt = 0.1
    plants = _plants(dt)
    r = robust_pi(plants, ms=MS)
    assert r.dt == dt and r.controller.dt == dt
    w = np.logspace(-3, math.log10(0.9999 * math.pi / dt), 6000)
    z = np.exp(1j * w * dt)
    P = np.stack([_resp(p.sys, w, p.delay) for p in plants])
    _kp, ki_b = _brute_force(P, dt / (z - 1), ms=MS)  # forward-Euler integrator
    assert abs(r.ki - ki_b) <= 0.01 * ki_b
    # the controller is kp + ki dt / (z - 1)
    zz = np.exp(1j * 0.7 * dt)
    assert complex(r.controller(zz)) == pytest.approx(r.kp + r.ki * dt / (zz - 1), rel=1e-12)


# -- re-checks with python-control ---------------------------------------------------------------


def test_ms_mt_rechecked_for_every_plant(pi_design):
    r = pi_design
    L = _loops(r.controller, _plants(), W_DENSE)
    S, T = 1 / (1 + L), L / (1 + L)
    for i, pc in enumerate(r.plants):
        ms_i, mt_i = np.max(np.abs(S[i])), np.max(np.abs(T[i]))
        assert ms_i <= MS * (1 + 1e-6)
        assert pc.ms == pytest.approx(ms_i, rel=2e-3)
        assert pc.mt == pytest.approx(mt_i, rel=2e-3)
        assert pc.stable is True
    # the limiting plant sits on the bound, the others inside it
    lim = {p.name for p in r.plants if p.limiting}
    for pc in r.plants:
        if pc.name in lim:
            assert pc.ms == pytest.approx(MS, rel=2e-3)


def test_margins_agree_with_python_control_without_delay():
    plants = [
        Plant(1 / (s + 1) ** 3, 0.0, "a"),
        Plant(1.5 / ((s + 1) ** 2 * (0.2 * s + 1)), 0.0, "b"),
    ]
    r = robust_pi(plants, ms=1.6)
    w = np.logspace(-3, 3, 5000)
    for p, pc in zip(plants, r.plants, strict=True):
        L = r.controller * p.sys
        gm, pm, _sm, _wpc, wgc, _wms = control.stability_margins(L)
        assert pc.gain_margin_db == pytest.approx(20 * math.log10(gm), abs=0.02)
        assert pc.phase_margin_deg == pytest.approx(pm, abs=0.05)
        assert pc.crossover_rad_s == pytest.approx(wgc, rel=1e-3)
        dm, dgm, dpm = control.disk_margins(L, w, skew=0.0)
        assert pc.disk_margin == pytest.approx(dm, rel=2e-3)
        assert pc.disk_margin_db == pytest.approx(dgm, rel=5e-3)
        assert pc.disk_margin_deg == pytest.approx(dpm, rel=5e-3)
        assert pc.stable is True
        poles = control.feedback(L, 1).poles()
        assert np.all(poles.real < 0)


def test_ki_non_decreasing_and_every_iterate_meets_ms(pi_design):
    r = pi_design
    ki = np.array(r.ki_history)
    assert ki.size >= 3
    assert np.all(np.diff(ki) >= 0)
    assert ki[-1] > ki[0]
    plants = _plants()
    for h in r.history:
        C = pid_controller(h[0], h[1])
        L = _loops(C, plants, W_DENSE)
        assert np.max(np.abs(1 / (1 + L))) <= MS * (1 + 1e-6)
        for p in plants:  # the closed loops stay stable along the way (Pade for the delay)
            cl = control.feedback(C * p.with_pade(5), 1)
            assert np.all(cl.poles().real < 0)


def test_coarse_grid_the_curve_does_not_slip_between_samples():
    # 25 points over six decades: a design checked only at the samples would exceed Ms between
    # them; the cell conditions keep the continuous curve out of the disk
    w = np.logspace(-3, 3, 25)
    r = robust_pi(_plants(), ms=MS, omega=w, refine=0)
    L = _loops(r.controller, _plants(), W_DENSE)
    assert np.max(np.abs(1 / (1 + L))) <= MS * (1 + 1e-9)
    Ls = _loops(r.controller, _plants(), w)
    assert np.max(np.abs(1 / (1 + Ls))) < MS * 0.99  # the samples alone are far from the bound


# -- PID, effort, integrating plants ------------------------------------------------------------


def test_pid_at_least_the_pi_and_meets_ms(pi_design):
    r = robust_pid(_plants(), ms=MS, tf=0.1)
    assert r.structure == "pid" and r.tf == 0.1 and r.start_source == "robust PI"
    assert r.ki >= pi_design.ki * (1 - 1e-9)
    assert r.ki > 1.2 * pi_design.ki  # the derivative buys phase: a clearly larger ki
    assert np.all(np.diff(r.ki_history) >= 0)
    C = r.kp + r.ki / s + r.kd * s / (0.1 * s + 1)
    L = _loops(C, _plants(), W_DENSE)
    assert np.max(np.abs(1 / (1 + L))) <= MS * (1 + 1e-6)
    assert complex(r.controller(2j)) == pytest.approx(complex(C(2j)), rel=1e-10)


def test_pid_default_filter_rule_and_discrete():
    dt = 0.05
    r = robust_pid(_plants(dt), ms=MS)
    assert r.dt == dt and r.tf >= dt
    w = np.logspace(-3, math.log10(0.9999 * math.pi / dt), 4000)
    L = _loops(r.controller, _plants(dt), w)
    assert np.max(np.abs(1 / (1 + L))) <= MS * (1 + 1e-6)
    assert all(p.stable for p in r.plants)


def test_effort_bound_met_and_binding(pi_design):
    ks_max = 1.1
    r = robust_pi(_plants(), ms=MS, ks_max=ks_max)
    Cw = _resp(r.controller, W_DENSE)
    L = _loops(r.controller, _plants(), W_DENSE)
    assert np.max(np.abs(Cw / (1 + L))) <= ks_max * (1 + 1e-6)
    unbounded = np.max(
        np.abs(
            _resp(pi_design.controller, W_DENSE)
            / (1 + _loops(pi_design.controller, _plants(), W_DENSE))
        )
    )
    assert unbounded > ks_max  # the bound binds ...
    assert r.ki < pi_design.ki  # ... and costs integral gain
    assert any(b == "ks" for p in r.plants for b, _w, _s in p.active)
    assert r.ks == pytest.approx(np.max(np.abs(Cw / (1 + L))), rel=2e-3)


def test_integrating_plants_start_found_and_stable():
    plants = [Plant(1 / (s * (s + 1)), 0.1, "int1"), Plant(2 / (s * (0.5 * s + 1)), 0.1, "int2")]
    r = robust_pi(plants, ms=MS)
    assert r.start_source == "auto" and r.history[0][0] > 0  # a P part is needed to start
    L = _loops(r.controller, plants, W_DENSE)
    assert np.max(np.abs(1 / (1 + L))) <= MS * (1 + 1e-6)
    assert r.stable is True


# -- bad specifications --------------------------------------------------------------------------


def test_mixed_sign_set_is_infeasible_with_a_clear_message():
    with pytest.raises(InfeasibleSpecError, match="both signs") as e:
        robust_pi([Plant(1 / (s + 1), 0.1, "up"), Plant(-1 / (s + 1), 0.1, "down")])
    assert "'down'" in str(e.value) or "'up'" in str(e.value)


def test_effort_below_the_dc_limit_is_infeasible():
    with pytest.raises(InfeasibleSpecError, match=r"1/\|P\(0\)\| = 1 .*'lag1'"):
        robust_pi(_plants(), ks_max=0.8)


def test_given_start_that_violates_the_spec_is_named():
    with pytest.raises(InfeasibleSpecError, match=r"start = \(5.0, 5.0\).*plant '.*' violates"):
        robust_pi(_plants(), start=(5.0, 5.0))


def test_unbounded_problem_is_an_error():
    # a first-order lag without delay: Ms alone never limits the gains
    with pytest.raises(UnboundedSpecError, match="without bound"):
        robust_pi(1 / (s + 1), ms=MS)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"ms": 0.9}, r"ms = 0\.9"),
        ({"mt": 1.0}, r"mt = 1\.0"),
        ({"ks_max": -1}, r"ks_max = -1"),
        ({"mss": 1.2}, r"unknown option mss = 1\.2; did you mean 'ms'"),
        ({"integrator": "euler"}, r"integrator = 'euler'"),
        ({"solver": "MOSEKK"}, r"solver = 'MOSEKK'"),
        ({"start": (1.0,)}, r"start = \(1\.0,\)"),
        ({"omega": [3.0, 2.0, 1.0]}, r"omega = .*increasing"),
        ({"n_omega": 2}, r"n_omega = 2"),
    ],
)
def test_bad_options_name_the_field_and_value(options, match):
    with pytest.raises(ValueError, match=match):
        robust_pi(_plants(), **options)


def test_spec_as_base_with_overrides():
    spec = RobustSpec(ms=1.6, n_omega=120)
    r = robust_pi(_plants(), spec=spec, ms=1.5)
    assert r.spec.ms == 1.5 and r.spec.n_omega == 120
    assert r.ms <= 1.5 * (1 + 1e-6)


# -- result object --------------------------------------------------------------------------------


def test_summary_table_and_json(pi_design):
    r = pi_design
    text = r.summary()
    assert "robust PI" in text and "limited by" in text and r.limiting[0] in text
    rows = r.table()
    assert [row["plant"] for row in rows] == ["lag1", "lag2", "lag1-slow"]
    d = json.loads(json.dumps(r.to_dict()))
    assert d["ki"] == pytest.approx(r.ki, rel=1e-8)
    assert len(d["history"]) == len(r.history)
    assert set(d["timings_s"]) >= {"grid", "start", "iterations", "solver", "check"}


def test_pid_controller_forms():
    z = np.exp(1j * 0.3 * 0.02)
    C = pid_controller(1.0, 2.0, 0.5, tf=0.1, dt=0.02, integrator="tustin")
    want = 1.0 + 2.0 * 0.01 * (z + 1) / (z - 1) + 0.5 * (z - 1) / (0.12 * z - 0.1)
    assert complex(C(z)) == pytest.approx(want, rel=1e-12)
    C = pid_controller(1.0, 2.0, 0.5, tf=0.1)
    assert complex(C(3j)) == pytest.approx(1 + 2 / 3j + 0.5 * 3j / (0.3j + 1), rel=1e-12)
    with pytest.raises(ValueError, match="tf = 0.0"):
        pid_controller(1.0, 2.0, 0.5)
