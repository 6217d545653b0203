"""Value tests of drivetrain_ctrl.design.checks (issue 22 item 4): the loop check of a textbook
loop against hand-derived margins and a plain numpy evaluation of S and T on the same grid, the
disk-margin figures against their closed forms, the check grid and the worst figures
(``./dev mutate drivetrain_ctrl/design/checks.py``)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import control
import numpy as np
import pytest
from scipy.optimize import brentq

from drivetrain_ctrl.design.checks import (
    check_grid,
    check_loop,
    check_plant_set,
    closed_loop_stable,
    disk_figures,
    worst_figures,
)
from drivetrain_ctrl.design.plants import Plant, as_plant_set, frequency_grid

# L = k / (s (s + 1)^2): phase -180 deg at w = 1, where |L| = k / 2 -> gain margin 2 / k
P3 = control.tf([1.0], [1.0, 2.0, 1.0, 0.0])
W = np.logspace(-2, 2, 2001)


def _L(k: float, w: np.ndarray) -> np.ndarray:
    s = 1j * w
    return k / (s * (s + 1.0) ** 2)


@pytest.mark.parametrize(
    ("alpha", "db", "deg"),
    [
        # alpha = 1: gmin = 1/3, gmax = 3 -> 20 log10 3; c = 2 / (10/3) = 0.6
        (1.0, 20 * math.log10(3.0), math.degrees(math.acos(0.6))),
        # alpha = 0.5: gmin = 0.6, gmax = 5/3; c = 2 / (0.6 + 5/3)
        (0.5, 20 * math.log10(5.0 / 3.0), math.degrees(math.acos(2.0 / (0.6 + 5.0 / 3.0)))),
        (2.0, math.inf, 90.0),
        # alpha = 3: gmin = -0.2, gmax = -5 (both negative: no gain margin, as python-control's
        # nan -> inf); c = (1 + 1) / (-5.2) -> 112.6 deg, not 90 (python-control's per-frequency
        # formula; 90 only where gmax is exactly infinite, alpha = 2)
        (3.0, math.inf, math.degrees(math.acos(2.0 / -5.2))),
    ],
)
def test_disk_figures_closed_form(alpha: float, db: float, deg: float) -> None:
    got_db, got_deg = disk_figures(alpha)
    assert got_db == pytest.approx(db, rel=1e-12)
    assert got_deg == pytest.approx(deg, rel=1e-12)


def test_disk_figures_equal_python_control_beyond_alpha_2() -> None:
    """L = 0.2/(s + 1): |S - 1/2| <= 1/3, alpha = 3 at w = 0; python-control's disk_margins
    gives the same phase figure (above 90 deg) as design.checks reports."""
    L = control.tf([0.2], [1.0, 1.0])
    w = np.logspace(-3, 3, 400)
    dm, dgm, dpm = control.disk_margins(L, w)
    got_db, got_deg = disk_figures(float(dm))
    assert float(dm) > 2.0
    assert got_deg == pytest.approx(float(dpm), rel=1e-9)
    assert got_db == dgm == math.inf


def test_check_grid_spans_a_decade_beyond_the_design_grid() -> None:
    w = np.array([1.0, 3.3, 10.0])
    g = check_grid(w, 0.0, n=41)
    expected = np.unique(np.concatenate([np.logspace(-1.0, 2.0, 41), w]))
    assert np.array_equal(g, expected)
    # sampled: up to the Nyquist frequency pi / dt
    g2 = check_grid(w, 0.05, n=11)
    assert g2[0] == pytest.approx(0.1, rel=1e-14)
    assert g2[-1] == pytest.approx(math.pi / 0.05, rel=1e-14)
    assert g2.size == 11 + 3  # 3.3 and 1.0, 10.0 are not on the 11-point grid
    assert np.all(np.diff(g2) > 0)


@pytest.mark.parametrize("k", [0.5, 1.0])
def test_check_loop_of_the_textbook_loop(k: float) -> None:
    c = check_loop(P3, control.tf([k], [1.0]), grid=W)
    L = _L(k, W)
    S = 1.0 / (1.0 + L)
    T = L * S
    iS, iT = int(np.argmax(np.abs(S))), int(np.argmax(np.abs(T)))
    assert c.ms == pytest.approx(abs(S[iS]), rel=1e-12)
    assert c.ms_frequency_rad_s == W[iS]
    assert c.mt == pytest.approx(abs(T[iT]), rel=1e-12)
    assert c.mt_frequency_rad_s == W[iT]
    assert c.ks == pytest.approx(k * np.max(np.abs(S)), rel=1e-12)
    assert c.gain_margin_db == pytest.approx(20 * math.log10(2.0 / k), rel=1e-6)
    wc = brentq(lambda x: abs(_L(k, np.array([x]))[0]) - 1.0, 1e-3, 10.0, xtol=1e-14)
    pm = 180.0 + math.degrees(np.angle(_L(k, np.array([wc]))[0]))
    assert c.crossover_rad_s == pytest.approx(wc, rel=1e-6)
    assert c.phase_margin_deg == pytest.approx(pm, rel=1e-6)
    alpha = 1.0 / np.max(np.abs(S - 0.5))
    assert c.disk_margin == pytest.approx(alpha, rel=1e-12)
    assert (c.disk_margin_db, c.disk_margin_deg) == pytest.approx(disk_figures(alpha))
    assert c.stable is True and c.reasons == () and c.active == ()
    assert closed_loop_stable(Plant(P3), control.tf([k], [1.0])) == (True, "")


def test_check_loop_of_an_unstable_loop() -> None:
    # k = 3: |L(j1)| = 1.5, gain margin 2/3 (-3.5 dB), the closed loop unstable
    c = check_loop(P3, control.tf([3.0], [1.0]), grid=W)
    assert c.gain_margin_db == pytest.approx(20 * math.log10(2.0 / 3.0), rel=1e-6)
    assert c.stable is False
    poles = control.feedback(3.0 * P3, 1).poles()
    assert np.any(poles.real > 0)  # the answer checked independently


def test_check_loop_without_crossovers_names_the_missing_figures() -> None:
    # L = 0.5 / (s + 1): |L| < 1 everywhere, phase never -180 deg
    c = check_loop(control.tf([1.0], [1.0, 1.0]), control.tf([0.5], [1.0]), grid=W)
    assert c.gain_margin_db is None and c.phase_margin_deg is None and c.crossover_rad_s is None
    assert dict(c.reasons).keys() == {"gain_margin_db", "phase_margin_deg"}
    assert c.stable is True
    S = 1.0 / (1.0 + 0.5 / (1j * W + 1.0))
    assert c.ms == pytest.approx(np.max(np.abs(S)), rel=1e-12)


def test_check_loop_of_a_delayed_plant() -> None:
    # L = e^{-s tau} / s: |L| = 1 at w = 1, phase -90 - tau [rad] -> pm = 90 - 57.3 tau deg;
    # phase crossover at w = pi / (2 tau) with |L| = 2 tau / pi
    tau = 0.5
    p = Plant(control.tf([1.0], [1.0, 0.0]), delay=tau)
    c = check_loop(p, control.tf([1.0], [1.0]), grid=W)
    assert c.crossover_rad_s == pytest.approx(1.0, rel=1e-3)
    assert c.phase_margin_deg == pytest.approx(90.0 - math.degrees(tau), rel=1e-3)
    assert c.gain_margin_db == pytest.approx(20 * math.log10(math.pi / (2 * tau)), rel=1e-3)
    assert c.stable is True
    assert dict(c.reasons)["stable"] == "poles with a Pade approximation of order 5"
    L = np.exp(-1j * W * tau) / (1j * W)
    assert c.ms == pytest.approx(np.max(np.abs(1.0 / (1.0 + L))), rel=1e-12)


def test_check_loop_of_a_sampled_loop() -> None:
    # L = K / (z - 1), dt = 0.1: closed-loop pole 1 - K, stable for 0 < K < 2
    dt = 0.1
    w = np.linspace(0.05, math.pi / dt, 3001)
    for K, stable in ((0.5, True), (1.9, True), (2.1, False)):
        c = check_loop(control.tf([1.0], [1.0, -1.0], dt), control.tf([K], [1.0], dt), grid=w)
        assert c.stable is stable
        z = np.exp(1j * w * dt)
        S = 1.0 / (1.0 + K / (z - 1.0))
        assert c.ms == pytest.approx(np.max(np.abs(S)), rel=1e-12)


def test_a_delay_of_a_fraction_of_a_sample_has_no_stability_verdict() -> None:
    p = Plant(control.tf([1.0], [1.0, -0.5], 0.1), delay=0.05)
    c = check_loop(p, control.tf([0.2], [1.0], 0.1), grid=np.linspace(0.1, 31.0, 500))
    assert c.stable is None
    assert "not a multiple of the sample period" in dict(c.reasons)["stable"]


def test_check_plant_set_carries_the_active_bounds() -> None:
    act = [[("ms", 2.0, 0.0)], []]
    cs = check_plant_set([P3, 2.0 * P3], control.tf([0.5], [1.0]), grid=W, active=act)
    assert cs[0].active == (("ms", 2.0, 0.0),) and cs[0].limiting is True
    assert cs[1].active == () and cs[1].limiting is False
    assert cs[1].gain_margin_db == pytest.approx(20 * math.log10(2.0), rel=1e-6)
    with pytest.raises(ValueError, match="active: 1 entries for 2 plants"):
        check_plant_set([P3, 2.0 * P3], control.tf([0.5], [1.0]), grid=W, active=[[]])


def _row(**kw: object) -> SimpleNamespace:
    base: dict[str, object] = {
        "ms": 1.5,
        "mt": 1.2,
        "ks": 3.0,
        "gain_margin_db": 6.0,
        "phase_margin_deg": 45.0,
        "disk_margin_db": 4.0,
        "crossover_rad_s": 2.0,
        "stable": True,
    }
    base.update(kw)
    return SimpleNamespace(**base)


def test_worst_figures() -> None:
    rows = [
        _row(),
        _row(ms=2.5, mt=1.1, ks=1.0, gain_margin_db=None, phase_margin_deg=30.0, crossover_rad_s=5.0),
        _row(mt=1.7, ks=4.0, gain_margin_db=3.0, phase_margin_deg=None, disk_margin_db=2.0,
             crossover_rad_s=None),
    ]  # fmt: skip
    f = worst_figures(rows)
    assert f == {
        "n_plants": 3,
        "ms_max": 2.5,
        "mt_max": 1.7,
        "ks_max": 4.0,
        "gain_margin_db_min": 3.0,
        "phase_margin_deg_min": 30.0,
        "disk_margin_db_min": 2.0,
        "crossover_rad_s_min": 2.0,
        "crossover_rad_s_max": 5.0,
        "all_stable": True,
    }
    none = worst_figures([_row(gain_margin_db=None, phase_margin_deg=None, crossover_rad_s=None)])
    assert none["gain_margin_db_min"] is None and none["phase_margin_deg_min"] is None
    assert none["crossover_rad_s_min"] is None and none["crossover_rad_s_max"] is None
    assert worst_figures([_row(), _row(stable=None)])["all_stable"] is None
    assert worst_figures([_row(stable=None), _row(stable=False)])["all_stable"] is False
    with pytest.raises(ValueError, match="checks: empty"):
        worst_figures([])


def test_to_dict_lays_out_the_bounds_and_reasons() -> None:
    c = check_loop(control.tf([1.0], [1.0, 1.0]), control.tf([0.5], [1.0]), grid=W,
                   active=[("mt", 0.7, 0.01)])  # fmt: skip
    d = c.to_dict()
    assert d["active"] == [{"bound": "mt", "frequency_rad_s": 0.7, "slack": 0.01}]
    assert d["reasons"]["phase_margin_deg"] == "no gain crossover"
    assert d["ms"] == pytest.approx(c.ms, rel=1e-8)


def test_gain_margins_up_to_60_db_are_reported() -> None:
    # L = k / (s (s + 1)^2): gain margin 2 / k; 2 / k = 800 (58 dB) is reported, 2000 (66 dB) not
    w = np.logspace(-5, 2, 3001)
    c = check_loop(P3, control.tf([2.0 / 800.0], [1.0]), grid=w)
    assert c.gain_margin_db == pytest.approx(20 * math.log10(800.0), rel=1e-6)
    c2 = check_loop(P3, control.tf([2.0 / 2000.0], [1.0]), grid=w)
    assert c2.gain_margin_db is None
    assert dict(c2.reasons)["gain_margin_db"] == "no phase crossover with 0.001 <= |L| <= 1000"
    assert c2.phase_margin_deg is not None and c2.stable is True


def test_a_state_space_plant_or_controller_gives_the_same_check() -> None:
    ref = check_loop(P3, control.tf([0.5], [1.0]), grid=W)
    for plant, ctrl in (
        (control.ss(P3), control.tf([0.5], [1.0])),
        (P3, control.ss(control.tf([0.5], [1.0]))),
    ):
        c = check_loop(plant, ctrl, grid=W)
        assert c.stable is True
        assert c.gain_margin_db == pytest.approx(20 * math.log10(4.0), rel=1e-6)
        assert c.phase_margin_deg == pytest.approx(ref.phase_margin_deg, rel=1e-6)
        assert c.ms == pytest.approx(ref.ms, rel=1e-12)
    unstable = check_loop(control.ss(P3), control.tf([3.0], [1.0]), grid=W)
    assert unstable.stable is False


def test_check_plant_set_uses_the_given_grid_or_one_for_the_whole_set() -> None:
    C = control.tf([0.5], [1.0])
    cs = check_plant_set([P3, 2.0 * P3], C, grid=W)
    for k, c in zip((0.5, 1.0), cs, strict=True):
        S = 1.0 / (1.0 + _L(k, W))
        assert c.ms == pytest.approx(np.max(np.abs(S)), rel=1e-12)
        assert c.ms_frequency_rad_s == W[int(np.argmax(np.abs(S)))]
    # default: one check grid around the set's design grid, the same for every plant
    fast = control.tf([100.0], [1.0, 100.0, 0.0])  # poles 0 and 100 rad/s: a wider set grid
    pset = as_plant_set([P3, fast])
    w_set = check_grid(frequency_grid(pset), 0.0)
    d = check_plant_set(pset, C)
    ref = check_loop(pset[0], C, grid=w_set)
    assert d[0].ms == ref.ms and d[0].ms_frequency_rad_s == ref.ms_frequency_rad_s
    assert d[0].mt_frequency_rad_s == ref.mt_frequency_rad_s


def test_the_margins_of_a_delayed_loop_use_every_band_point_of_a_coarse_grid() -> None:
    # L = e^{-s/2} / s: |L(j1)| = 1 exactly, phase margin 90 - 28.6 deg there; on a grid of
    # fewer than MARGIN_POINTS band points every point is used, so the crossover is the knot
    p = Plant(control.tf([1.0], [1.0, 0.0]), delay=0.5)
    c = check_loop(p, control.tf([1.0], [1.0]), grid=[0.5, 1.0, 2.0])
    assert c.crossover_rad_s == pytest.approx(1.0, rel=1e-9)
    assert c.phase_margin_deg == pytest.approx(90.0 - math.degrees(0.5), rel=1e-9)
    # two band points are enough for an (interpolated) crossover between them
    c2 = check_loop(p, control.tf([1.0], [1.0]), grid=[0.5, 2.0])
    assert c2.crossover_rad_s is not None and 0.5 < c2.crossover_rad_s < 2.0
    assert c2.phase_margin_deg is not None


@pytest.mark.parametrize("alpha", [-1.0, float("nan")])
def test_disk_figures_reject_a_negative_or_nan_margin(alpha: float) -> None:
    with pytest.raises(ValueError, match="alpha = "):
        disk_figures(alpha)


def test_a_delayed_loop_on_a_one_point_grid_has_no_crossovers() -> None:
    # one band point: no crossover can be located, so no margin and no crossover (not an error)
    p = Plant(control.tf([1.0], [1.0, 0.0]), delay=0.5)
    c = check_loop(p, control.tf([1.0], [1.0]), grid=[1.0])
    assert (c.gain_margin_db, c.phase_margin_deg, c.crossover_rad_s) == (None, None, None)
    assert dict(c.reasons)["phase_margin_deg"] == "no gain crossover"
    # |S(j1)| = 1 / |1 + e^{-j/2} / j| computed plainly
    L1 = np.exp(-0.5j) / 1j
    assert c.ms == pytest.approx(1.0 / abs(1.0 + L1), rel=1e-12)
