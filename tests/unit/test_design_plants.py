"""Plants, plant sets and frequency grids of the design layer (design/plants.py)."""

from __future__ import annotations

import math
import pickle

import control
import numpy as np
import pytest

from drivetrain_ctrl.design.plants import Plant, PlantSet, as_plant_set, frequency_grid

s = control.tf("s")
W = np.logspace(-2, 3, 41)


def test_delay_phase_is_exact():
    """The delay adds exactly -w*delay to the phase (not a Pade approximation's phase), and
    leaves the magnitude unchanged, at every frequency including far beyond w*delay ~ 1."""
    P0 = 2 / (s + 1)
    tau = 0.3
    p = Plant(P0, delay=tau)
    ref = np.array([complex(P0(1j * w)) for w in W])
    got = p.freqresp(W)
    assert np.allclose(np.abs(got), np.abs(ref), rtol=1e-12)
    dphase = np.angle(got / ref)
    wrapped = np.angle(np.exp(-1j * W * tau))  # -w tau, wrapped into (-pi, pi]
    assert np.allclose(dphase, wrapped, atol=1e-10)
    # A Pade model is only right at low frequency: its phase is wrong above w tau ~ 3.
    pade = p.with_pade(3)
    pr = np.array([complex(pade(1j * w)) for w in W])
    low = W * tau < 0.5
    assert np.allclose(pr[low], got[low], rtol=1e-3)
    assert np.max(np.abs(pr / got - 1)) > 0.5


def test_scalar_and_statespace():
    p = Plant(control.ss(1 / (s + 2)), delay=0.1)
    v = p.freqresp(2.0)
    assert np.ndim(v) == 0
    assert v == pytest.approx(1 / (2j + 2) * np.exp(-0.2j))
    assert isinstance(p.with_pade(2), control.StateSpace)


def test_discrete_frequency_response():
    """A discrete plant is evaluated on the unit circle, z = exp(j w dt), not at s = j w."""
    dt = 0.01
    a = math.exp(-dt)
    Pd = control.tf([1 - a], [1, -a], dt)  # ZOH equivalent of 1/(s+1)
    p = Plant(Pd, delay=2 * dt)
    w = np.array([0.0, 1.0, 10.0, 100.0, math.pi / dt])
    z = np.exp(1j * w * dt)
    expected = (1 - a) / (z - a) * z**-2
    assert np.allclose(p.freqresp(w), expected, rtol=1e-12)
    # with_pade: the delay as z^-2 exactly
    r = p.with_pade()
    assert r.dt == dt
    assert np.allclose([complex(r(zz)) for zz in z], expected, rtol=1e-10)
    assert p.is_discrete and p.dt == dt


def test_discrete_fractional_delay_needs_a_multiple_for_rational_model():
    p = Plant(control.tf([1], [1, -0.5], 0.01), delay=0.015)
    assert np.isfinite(p.freqresp(W[W < 300])).all()  # exact in the frequency response
    with pytest.raises(ValueError, match=r"delay = 0.015.*not a multiple.*dt = 0.01"):
        p.with_pade()


def test_integrator_gives_inf_not_error():
    p = Plant(1 / s)
    r = p.freqresp(np.array([0.0, 1.0]))
    assert np.isinf(r[0]) and r[1] == pytest.approx(-1j)


def test_plant_set_and_as_plant_set():
    P1, P2 = 1 / (s + 1), 3 / (s + 2)
    ps = as_plant_set([P1, Plant(P2, delay=0.1, name="fast")], delay=None)
    assert len(ps) == 2 and ps.names == ("plant 0", "fast")
    R = ps.freqresp(W)
    assert R.shape == (2, W.size)
    assert np.allclose(R[1], ps[1].freqresp(W))
    assert isinstance(ps[0:1], PlantSet) and len(ps[0:1]) == 1
    assert [p.name for p in ps] == ["plant 0", "fast"]
    assert as_plant_set(ps) is not None and as_plant_set(ps).plants == ps.plants
    one = as_plant_set(P1, delay=0.2)
    assert one[0].delay == 0.2 and one.dt == 0.0
    nested = as_plant_set([ps, P1])
    assert len(nested) == 3
    assert pickle.loads(pickle.dumps(ps)).names == ps.names


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: Plant("x"), r"Plant.sys = 'x': must be a python-control LTI"),
        (lambda: Plant(1 / (s + 1), delay=-0.1), r"Plant.delay = -0.1: must be >= 0"),
        (lambda: Plant(1 / (s + 1), delay=float("nan")), r"Plant.delay = nan"),
        (
            lambda: Plant(control.tf([[[1]], [[1]]], [[[1, 1]], [[1, 2]]])),
            r"must be SISO.*2 outputs",
        ),
        (lambda: Plant(control.tf([1], [1, 1], True)), r"dt = True"),
        (lambda: as_plant_set(3.0), r"plants = 3.0: must be a python-control"),
        (lambda: as_plant_set([1 / s, "b"]), r"plants\[1\] = 'b'"),
        (lambda: as_plant_set([]), r"at least one plant"),
        (lambda: PlantSet(()), r"at least one plant"),
        (lambda: as_plant_set(Plant(1 / s, delay=0.1), delay=0.2), r"delay = 0.1 s.*0.2"),
        (lambda: as_plant_set(1 / s, delay=-1), r"delay = -1: must be >= 0"),
        (lambda: frequency_grid(1 / (s + 1), n=1), r"n = 1: must be an integer >= 2"),
        (lambda: frequency_grid(1 / (s + 1), w_min=-1.0), r"w_min = -1.0: must be > 0"),
        (lambda: frequency_grid(1 / (s + 1), w_min=10.0, w_max=1.0), r"w_min = 10.0.*< w_max"),
        (lambda: frequency_grid(1 / (s + 1), crossover=0.0), r"crossover = 0.0: must be > 0"),
        (
            lambda: frequency_grid(control.tf([1], [1, -0.5], 0.01), w_max=1000.0),
            r"w_max = 1000.0 rad/s: must be <= the Nyquist frequency",
        ),
        (lambda: Plant(1 / s).freqresp([np.nan]), r"finite"),
        (lambda: Plant(1 / s).with_pade(0), r"order = 0"),
    ],
)
def test_bad_input_names_field_and_value(call, match):
    with pytest.raises((ValueError, TypeError), match=match):
        call()


def test_mixed_sample_periods_have_no_common_dt():
    ps = as_plant_set([1 / (s + 1), control.tf([1], [1, -0.5], 0.01)])
    with pytest.raises(ValueError, match=r"mixes sample periods"):
        _ = ps.dt


def test_grid_covers_poles_zeros():
    """The automatic grid spans two decades beyond the slowest and fastest pole/zero."""
    P = (s + 0.5) / ((s + 0.02) * (s + 300))
    w = frequency_grid(P, n=100)
    assert np.all(np.diff(w) > 0) and w.size >= 100
    assert w[0] == pytest.approx(0.02 / 100) and w[-1] == pytest.approx(300 * 100)
    # log-spaced: constant ratio between the base points
    assert w.size == 100 and np.allclose(np.diff(np.log(w)), np.log(w[1] / w[0]))


def test_grid_dense_around_crossover_and_resonance():
    wn, zeta = 40.0, 0.02
    P = wn**2 / (s**2 + 2 * zeta * wn * s + wn**2) / (s + 1)
    w = frequency_grid(P, n=60, crossover=5.0)
    assert w.size > 60
    near_wc = np.sum((w >= 5 / 3) & (w <= 15))
    base = frequency_grid(P, n=60)
    assert near_wc >= np.sum((base >= 5 / 3) & (base <= 15)) + 60 // 4 - 2
    # the resonance peak (half-power width 2 zeta wn) holds several points
    assert np.sum(np.abs(w - wn) <= zeta * wn) >= 3


def test_grid_discrete_ends_at_nyquist():
    dt = 0.01
    Pd = control.c2d(1 / ((s + 1) * (s + 5)), dt)
    w = frequency_grid(Pd, n=50)
    assert w[-1] == pytest.approx(math.pi / dt, rel=1e-12)
    for n in (50, 3000):  # strictly increasing up to the Nyquist frequency itself
        wn = frequency_grid(Plant(Pd, delay=dt), n=n, crossover=3.0)
        assert np.all(np.diff(wn) > 0) and wn[-1] == math.pi / dt
    assert w[0] == pytest.approx(1.0 / 100, rel=1e-6)  # the z-plane pole exp(-dt) maps to 1 rad/s
    # a set mixing 10-ms and 20-ms plants ends at the smaller Nyquist frequency
    w2 = frequency_grid([Pd, control.c2d(1 / (s + 1), 0.02)], n=50)
    assert w2[-1] == pytest.approx(math.pi / 0.02)


def test_grid_delay_and_pure_gain():
    w = frequency_grid(Plant(control.tf([2.0], [1.0]), delay=0.5), n=20)
    assert w[0] == pytest.approx(2.0 / 100) and w[-1] == pytest.approx(2.0 * 100)
    w1 = frequency_grid(control.tf([2.0], [1.0]), n=20)
    assert w1[0] == pytest.approx(0.01) and w1[-1] == pytest.approx(100.0)
