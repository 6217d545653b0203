"""Value tests of drivetrain_ctrl.design.plants (issue 22 item 4): the design grid of plants
with known poles, zeros, delays and sample periods, written out point by point with numpy here;
the exact delay and the Pade / z^-k models (``./dev mutate drivetrain_ctrl/design/plants.py``)."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from drivetrain_ctrl.design.plants import Plant, as_plant_set, frequency_grid

# poles 1 and 10 rad/s, no zeros
P2 = control.tf([10.0], [1.0, 11.0, 10.0])


def _dedup(g: np.ndarray, lo: float, hi: float) -> np.ndarray:
    g = np.unique(np.clip(g, lo, hi))
    keep = np.concatenate([[True], np.diff(g) > 1e-12 * g[1:]])
    g = g[keep]
    g[0], g[-1] = lo, hi
    return g


def test_grid_spans_two_decades_beyond_the_poles() -> None:
    g = frequency_grid(P2, n=50)
    expected = _dedup(np.concatenate([np.logspace(-2.0, 3.0, 50), [0.01, 1000.0]]), 0.01, 1000.0)
    assert g.size == expected.size
    assert np.allclose(g, expected, rtol=1e-13, atol=0.0)
    assert g[0] == 0.01 and g[-1] == 1000.0


def test_grid_with_a_crossover_adds_a_quarter_of_the_points() -> None:
    g = frequency_grid(P2, n=40, crossover=5.0)
    base = np.logspace(-2.0, 3.0, 40)
    extra = np.logspace(math.log10(5.0 / 3.0), math.log10(15.0), 10)
    expected = _dedup(np.concatenate([base, extra, [0.01, 1000.0]]), 0.01, 1000.0)
    assert np.allclose(g, expected, rtol=1e-13, atol=0.0)
    # a crossover beyond the poles widens the range: two decades above it
    g2 = frequency_grid(P2, n=40, crossover=100.0)
    assert g2[-1] == pytest.approx(1e4, rel=1e-14)


def test_grid_around_a_lightly_damped_pair() -> None:
    # wn = 10 rad/s, zeta = 0.1: 8 points on [10 - 3, 10 + 3]; zeta = 0.5 gets none
    light = control.tf([100.0], [1.0, 2.0, 100.0])
    g = frequency_grid(light, n=30)
    lo, hi = 0.1, 1000.0
    expected = _dedup(
        np.concatenate([np.logspace(-1.0, 3.0, 30), np.linspace(7.0, 13.0, 8), [lo, hi]]), lo, hi
    )
    assert np.allclose(g, expected, rtol=1e-13, atol=0.0)
    damped = control.tf([100.0], [1.0, 10.0, 100.0])
    assert frequency_grid(damped, n=30).size == 30


def test_grid_of_a_delay_and_of_a_pure_gain() -> None:
    # 1/delay = 20 rad/s is the only feature of a delayed gain
    g = frequency_grid(Plant(control.tf([2.0], [1.0]), delay=0.05), n=20)
    assert (g[0], g[-1]) == (pytest.approx(0.2), pytest.approx(2000.0))
    assert g.size == 20
    g1 = frequency_grid(control.tf([2.0], [1.0]), n=20)  # nothing: 1 rad/s
    assert (g1[0], g1[-1]) == (pytest.approx(0.01), pytest.approx(100.0))


def test_grid_of_a_sampled_plant_ends_at_nyquist() -> None:
    # pole z = exp(-2 * 0.01): 2 rad/s; the grid starts at 0.02 and ends at pi / 0.01
    Pd = control.tf([1.0], [1.0, -math.exp(-0.02)], 0.01)
    g = frequency_grid(Pd, n=25)
    assert g[0] == pytest.approx(0.02, rel=1e-12)
    assert g[-1] == math.pi / 0.01
    expected = _dedup(
        np.concatenate([np.logspace(math.log10(0.02), math.log10(math.pi / 0.01), 25)]),
        g[0],
        math.pi / 0.01,
    )
    assert np.allclose(g, expected, rtol=1e-12, atol=0.0)
    # a pole at z = 0 (a pure delay) has no frequency
    assert np.allclose(frequency_grid(control.tf([1.0], [1.0, 0.0], 0.01), n=10)[-1], 100 * math.pi)


def test_grid_explicit_ends_and_a_degenerate_range() -> None:
    g = frequency_grid(P2, n=11, w_min=1.0, w_max=100.0)
    assert np.allclose(g, np.logspace(0.0, 2.0, 11), rtol=1e-13)
    # w_max below the automatic start: the automatic start is one decade below it
    g2 = frequency_grid(P2, n=5, w_max=0.001)
    assert g2[0] == pytest.approx(1e-4, rel=1e-12) and g2[-1] == 0.001
    with pytest.raises(ValueError, match="w_min = 10.0 rad/s must be < w_max = 1.0 rad/s"):
        frequency_grid(P2, w_min=10.0, w_max=1.0)
    with pytest.raises(ValueError, match="Nyquist"):
        frequency_grid(control.tf([1.0], [1.0, -0.5], 0.1), w_max=32.0)
    frequency_grid(control.tf([1.0], [1.0, -0.5], 0.1), w_max=math.pi / 0.1)  # exactly: allowed
    with pytest.raises(ValueError, match="n = 1"):
        frequency_grid(P2, n=1)
    assert frequency_grid(P2, n=2).size == 2


def test_exact_delay_in_the_frequency_response() -> None:
    p = Plant(P2, delay=0.1)
    w = np.array([0.0, 0.5, 3.0, 40.0])
    s = 1j * w
    expected = 10.0 / ((s + 1.0) * (s + 10.0)) * np.exp(-0.1 * s)
    assert np.allclose(p.freqresp(w), expected, rtol=1e-13)
    assert p.freqresp(3.0) == pytest.approx(expected[2], rel=1e-13)
    pd = Plant(control.tf([1.0], [1.0, -0.5], 0.1), delay=0.2)
    z = np.exp(1j * w * 0.1)
    assert np.allclose(pd.freqresp(w), 1.0 / (z - 0.5) * np.exp(-0.2j * w), rtol=1e-13)
    assert pd.dt == 0.1 and pd.is_discrete and not p.is_discrete and p.dt == 0.0


def test_rational_models_of_the_delay() -> None:
    # continuous: sys times control.pade(delay, order)
    p = Plant(P2, delay=0.1)
    num, den = control.pade(0.1, 4)
    r = p.with_pade(4)
    expected = P2 * control.tf(num, den)
    w = np.array([0.3, 3.0, 30.0])
    assert np.allclose(r(1j * w), expected(1j * w), rtol=1e-12)
    assert p.with_pade(1) is not None and Plant(P2).with_pade(2) is P2
    # discrete: z^-2 for a delay of two samples, state space kept
    sd = control.ss(control.tf([1.0], [1.0, -0.5], 0.1))
    rd = Plant(sd, delay=0.2).with_pade()
    assert isinstance(rd, control.StateSpace) and rd.nstates == 3
    z = np.exp(1j * w * 0.1)
    assert np.allclose(rd(z), 1.0 / ((z - 0.5) * z**2), rtol=1e-12)
    for bad in (0, True, 1.5):
        with pytest.raises(ValueError, match="order"):
            p.with_pade(bad)  # type: ignore[arg-type]


def test_as_plant_set_names_and_delays() -> None:
    s = as_plant_set([P2, Plant(P2, name="x"), P2], delay=0.0)
    assert s.names == ("plant 0", "x", "plant 2")
    s2 = as_plant_set([P2, P2], delay=0.3)
    assert all(p.delay == 0.3 for p in s2) and len(s2) == 2
    assert s2[1:].names == ("plant 1",) and s2.dt == 0.0
    fr = s2.freqresp([1.0, 2.0])
    assert fr.shape == (2, 2)
    assert fr[1, 1] == pytest.approx(complex(P2(2j)) * np.exp(-0.6j), rel=1e-13)


def test_a_pole_at_round_off_distance_from_zero_is_an_integrator() -> None:
    # poles -10 and -5e-10 rad/s: the second is below 1e-9 of the largest, no feature
    p = control.tf([1.0], np.polymul([1.0, 5e-10], [1.0, 10.0]))
    g = frequency_grid(p, n=10)
    assert g[0] == pytest.approx(0.1, rel=1e-12) and g[-1] == pytest.approx(1000.0, rel=1e-12)
    # 5e-8 rad/s is above that: the grid reaches two decades below it
    p2 = control.tf([1.0], np.polymul([1.0, 5e-8], [1.0, 10.0]))
    assert frequency_grid(p2, n=10)[0] == pytest.approx(5e-10, rel=1e-6)


def test_equal_grid_ends_are_rejected() -> None:
    with pytest.raises(ValueError, match="w_min = 10.0 rad/s must be < w_max = 10.0 rad/s"):
        frequency_grid(P2, w_min=10.0, w_max=10.0)


def test_the_round_off_floor_is_relative_to_at_least_1_rad_s() -> None:
    # largest feature 0.5 rad/s: the floor is 1e-9 * max(1, 0.5) = 1e-9; a pole at 1.5e-9 is kept
    p = control.tf([1.0], np.polymul([1.0, 1.5e-9], [1.0, 0.5]))
    assert frequency_grid(p, n=10)[0] == pytest.approx(1.5e-11, rel=1e-6)
    p2 = control.tf([1.0], np.polymul([1.0, 0.5e-9], [1.0, 0.5]))
    assert frequency_grid(p2, n=10)[0] == pytest.approx(0.005, rel=1e-9)


def test_a_nearly_undamped_pair_gets_a_band_of_at_least_1_percent() -> None:
    # wn = 10 rad/s, zeta = 0.001: 3 zeta = 0.3 % is below the floor, 8 points on 10 +- 0.1
    light = control.tf([100.0], [1.0, 0.02, 100.0])
    g = frequency_grid(light, n=30)
    lo, hi = 0.1, 1000.0
    expected = _dedup(
        np.concatenate([np.logspace(-1.0, 3.0, 30), np.linspace(9.9, 10.1, 8), [lo, hi]]), lo, hi
    )
    assert np.allclose(g, expected, rtol=1e-12, atol=0.0)


def test_a_sampled_delay_must_be_a_whole_number_of_samples_to_1e_9() -> None:
    sys = control.tf([1.0], [1.0, -0.5], 0.1)
    # k = 1 + 5e-10 samples: a whole sample within 1e-9 (of max(1, k)); z^-1
    r = Plant(sys, delay=0.1 * (1.0 + 5e-10)).with_pade()
    z = np.exp(1j * 2.0 * 0.1)
    assert complex(r(z)) == pytest.approx(1.0 / ((z - 0.5) * z), rel=1e-12)
    with pytest.raises(ValueError, match="not a multiple of the sample period"):
        Plant(sys, delay=0.1 * (1.0 + 1.5e-9)).with_pade()
    # for 20 samples the tolerance is 20e-9 samples
    Plant(sys, delay=0.1 * 20.0 * (1.0 + 5e-10)).with_pade()
    with pytest.raises(ValueError, match="not a multiple of the sample period"):
        Plant(sys, delay=0.1 * 20.0 * (1.0 + 2e-9)).with_pade()
