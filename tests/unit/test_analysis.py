"""Loop margins, root loci and Nyquist data (analysis.py)."""

from __future__ import annotations

import json
import math

import control
import numpy as np
import pytest
import scipy.optimize

from drivetrain_ctrl import linear as L
from drivetrain_ctrl.control.blocks import Actuator
from drivetrain_ctrl.control.laws import law6_controller, law6_defaults, pi_controller
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.linear import margins as A
from drivetrain_ctrl.plant.drivetrain import reduced_model
from drivetrain_ctrl.plant.params import default_params

P = default_params()
K_R = law6_defaults()[0]  # law (6)'s gain: the built-in paper controller's


def _textbook(k: float) -> control.TransferFunction:
    return control.tf([k], np.polymul([1, 0], np.polymul([1, 1], [1, 1])))


def test_margins_of_textbook_loop_by_hand():
    # L = k / (s (s + 1)^2): phase -180 deg at w = 1 where |L| = k/2 -> GM = 2/k
    k = 1.0
    m = A.loop_margins(_textbook(k))
    assert m.phase_crossover_rad_s == pytest.approx(1.0, rel=1e-6)
    assert m.gain_margin_db == pytest.approx(20 * math.log10(2.0 / k), rel=1e-6)
    wc = scipy.optimize.brentq(lambda w: w * (1 + w * w) - k, 0.1, 2.0)
    pm = 180.0 - 90.0 - 2 * math.degrees(math.atan(wc))
    assert m.crossover_rad_s == pytest.approx(wc, rel=1e-6)
    assert m.phase_margin_deg == pytest.approx(pm, rel=1e-6)
    assert m.delay_margin_s == pytest.approx(math.radians(pm) / wc, rel=1e-6)
    # symmetric disk margin: alpha = 1 / max |S - T| / 2, gain (1 + a/2)/(1 - a/2)
    w = np.logspace(-3, 3, 20001)
    Lw = k / (1j * w * (1j * w + 1) ** 2)
    alpha = 1.0 / np.max(np.abs((1 - Lw) / (1 + Lw)) / 2)
    assert m.disk_margin == pytest.approx(alpha, rel=1e-3)
    assert m.disk_margin_db == pytest.approx(
        20 * math.log10((1 + alpha / 2) / (1 - alpha / 2)), rel=1e-3
    )
    assert m.disk_margin_deg == pytest.approx(math.degrees(2 * math.atan(alpha / 2)), rel=1e-3)
    assert m.ms == pytest.approx(np.max(np.abs(1 / (1 + Lw))), rel=1e-3)
    assert m.mt == pytest.approx(np.max(np.abs(Lw / (1 + Lw))), rel=1e-3)
    assert m.stable and m.bandwidth_rad_s is not None and m.bandwidth_rad_s > wc
    # closed loop s^3 + 2 s^2 + s + 1: poles and their natural frequencies
    cl = np.roots([1, 2, 1, k])
    assert sorted(p.real for p in m.closed_loop_poles) == pytest.approx(sorted(cl.real))
    assert len(m.natural_frequencies_hz) == 1
    json.dumps(m.to_dict())
    # k = 4: GM = 0.5 (unstable), margins flagged
    m4 = A.loop_margins(_textbook(4.0))
    assert not m4.stable and m4.gain_margin_db == pytest.approx(20 * math.log10(0.5), rel=1e-6)
    assert m4.disk_margin is None and dict(m4.reasons)["disk_margin"] == "closed loop unstable"


def test_undefined_margins_have_reasons():
    m = A.loop_margins(control.tf([0.5], [1, 1]))  # |L| < 1, phase > -90
    r = dict(m.reasons)
    assert m.gain_margin_db is None and "phase crossover" in r["gain_margin_db"]
    assert m.phase_margin_deg is None and "gain crossover" in r["phase_margin_deg"]
    with pytest.raises(TypeError, match="LTI"):
        A.loop_margins([1, 2])  # type: ignore[arg-type]


def _slip():
    return L.slip_operating_point(
        reduced_model(P), omega_engine=170.0, omega_driven=80.0, x_c=0.0725, throttle=0.5
    )


def _law6():
    return law6_controller(P, reference=sg.constant(170.0), driven_state="omega_primary")


def test_clutch_loop_margins_law6_and_sampled():
    op = _slip()
    m = A.clutch_loop_margins(op, _law6())
    assert m.stable and m.gain_margin_db is not None and m.gain_margin_db > 20
    # first order-like loop: the gain crossover is about K_L / J1
    es = L.engine_side(op)
    assert m.crossover_rad_s == pytest.approx(K_R * abs(es.dk13_dxc) / es.J1, rel=0.05)
    cd = pi_controller(
        P,
        reference=sg.constant(170.0),
        kp=3e-4,
        ki=1e-3,
        dt=0.02,
        delay_samples=2,
        driven_state="omega_primary",
    )
    cc = pi_controller(
        P, reference=sg.constant(170.0), kp=3e-4, ki=1e-3, driven_state="omega_primary"
    )
    md = A.clutch_loop_margins(op, cd)
    mc = A.clutch_loop_margins(op, cc)
    assert md.dt == 0.02 and mc.dt is None
    assert md.phase_margin_deg < mc.phase_margin_deg  # sample-and-hold and delay cost phase


def test_locked_clutch_loop_margins_are_none():
    op = L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0)
    m = A.clutch_loop_margins(op, _law6())
    d = m.to_dict()
    assert m.gain_margin_db is None and m.phase_margin_deg is None and m.disk_margin is None
    assert "open" in d["reasons"]["all"]


def test_root_locus_over_mu_slope_crosses_at_judder_threshold():
    op = _slip()
    jt = L.judder_threshold(op, _law6())
    vals = np.linspace(0.5, 1.5, 11) * jt.mu_slope_crit
    rl = A.root_locus(op, _law6(), parameter="mu_slope", values=vals)
    assert rl.crossing() == pytest.approx(jt.mu_slope_crit, rel=0.02)
    assert all(dict(p.modes)["clutch"] == "slip+" for p in rl.points)
    d = rl.to_dict()
    assert json.dumps(d) == json.dumps(rl.to_dict())  # deterministic


@pytest.mark.parametrize(
    ("parameter", "values"),
    [
        ("k_r", [1e-4, 3e-4, 1e-3]),
        ("omega_a", [50.0, 200.0]),
        ("J1", [0.15, 0.25]),
        ("pedal_slope", [0.5, 1.0, 2.0]),
    ],
)
def test_root_locus_parameters(parameter, values):
    rl = A.root_locus(_slip(), _law6(), parameter=parameter, values=values)
    assert [p.value for p in rl.points] == values
    assert all(p.stable for p in rl.points)
    json.dumps(rl.to_dict())


def test_root_locus_k_r_moves_the_engine_pole():
    # with constant mu the engine pole sits near -(b1 + k_r |k13'|)/J1 for a fast actuator
    op = _slip()
    es = L.engine_side(op)
    rl = A.root_locus(op, _law6(), parameter="k_r", values=[1e-4])
    target = -(es.b1_eff + 1e-4 * abs(es.dk13_dxc)) / es.J1
    reals = [p.real for p in rl.points[0].poles if abs(p.imag) < 1e-9]
    assert min(abs(r - target) for r in reals) < 0.02 * abs(target)


def test_root_locus_bad_parameter():
    with pytest.raises(ValueError, match="parameter = 'mass'"):
        A.root_locus(_slip(), _law6(), parameter="mass", values=[1.0])


def test_nyquist_counts():
    n1 = A.nyquist_data(_textbook(1.0))
    assert n1.closed_loop_unstable_poles == 0 and n1.open_loop_unstable_poles == 0
    n4 = A.nyquist_data(_textbook(4.0))
    assert n4.closed_loop_unstable_poles == 2
    json.dumps(n1.to_dict())


def test_plots_run(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    m = A.loop_margins(_textbook(1.0))
    m.plot(_textbook(1.0), path=str(tmp_path / "m.png"))
    A.nyquist_data(_textbook(1.0)).plot(str(tmp_path / "n.png"))
    A.root_locus(_slip(), _law6(), parameter="k_r", values=[1e-4, 3e-4]).plot(
        str(tmp_path / "r.png")
    )
    assert (tmp_path / "m.png").exists() and (tmp_path / "r.png").exists()


def test_trim_tf_drops_round_off_leading_numerator_terms_in_discrete_time() -> None:
    """A sampled loop with one sample of delay: scipy's conversion of its state-space form
    (:func:`linear.ss_to_tf`, what ``control.tf`` does without slycot) leaves the
    leading numerator coefficient at round-off; :func:`linear.trim_tf` drops it (same frequency
    response) and the margins come without scipy's BadCoefficients warning."""
    import warnings

    from scipy.signal import BadCoefficients

    ts = 0.01
    plant = control.c2d(control.tf([50.0], [0.2, 1.0, 0.0]) * control.tf([1.0], [0.01, 1.0]), ts)
    delay = control.tf([1.0], [1.0, 0.0], ts)
    pi = control.tf([0.02, -0.019], [1.0, -1.0], ts)
    L_ss = control.ss(pi * plant * delay)
    raw = L.ss_to_tf(L_ss)
    trimmed = L.trim_tf(L_ss)
    assert len(trimmed.num[0][0]) < len(raw.num[0][0])
    assert abs(trimmed.num[0][0][0]) > 1e-6 * np.max(np.abs(trimmed.num[0][0]))
    w = np.logspace(-1, math.log10(math.pi / ts * 0.99), 50)
    r1 = np.asarray(control.frequency_response(raw, w).complex).ravel()
    r2 = np.asarray(control.frequency_response(trimmed, w).complex).ravel()
    assert np.allclose(r1, r2, rtol=1e-9, atol=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BadCoefficients)
        # python-control's own note on this loop (it switches to its frequency-response method)
        warnings.filterwarnings("ignore", "stability_margins: Falling back", UserWarning)
        m = A.loop_margins(trimmed)
    assert m.phase_margin_deg is not None
    # continuous time: the same for a strictly proper system; a transfer function passes as is
    cont = control.tf2ss(control.tf([1.0, 2.0], [1.0, 3.0, 2.0, 1.0]), method="scipy")
    assert np.allclose(L.trim_tf(cont).num[0][0], [1.0, 2.0], rtol=1e-12)
    assert np.allclose(L.trim_tf(cont).den[0][0], [1.0, 3.0, 2.0, 1.0], rtol=1e-12)
    g = control.tf([1e-9, 1.0], [1.0, 1.0])
    assert np.array_equal(L.trim_tf(g).num[0][0], g.num[0][0])
    # a genuine (non-zero Markov parameter) small leading coefficient is kept
    biproper = control.tf2ss(control.tf([1e-8, 1.0, 1.0], [1.0, 2.0, 1.0]), method="scipy")
    assert len(L.trim_tf(biproper).num[0][0]) == 3


def test_freq_is_the_pointwise_evaluation() -> None:
    """The vectorised frequency response equals L evaluated point by point (continuous and
    discrete, transfer function and state space)."""
    w = np.logspace(-2, 2, 37)
    for sys in (
        _textbook(1.0),
        control.ss(_textbook(1.0)),
        control.tf([1.0, 2.0], [1.0, 3.0, 2.0, 1.0], 0.01),
    ):
        dt = A._dt_of(sys)
        s = np.exp(1j * w * dt) if dt else 1j * w
        assert np.array_equal(A._freq(sys, w), np.array([complex(sys(x)) for x in s]))


@pytest.mark.parametrize(
    ("omega", "match"),
    [
        ([1.0, float("nan"), 3.0], "finite"),
        ([1.0, float("inf")], "finite"),
        ([0.0, 1.0], "> 0"),
        ([-1.0, 1.0], "> 0"),
        ([1.0, 3.0, 2.0], "strictly increasing"),
        ([1.0, 1.0, 2.0], "strictly increasing"),
        ([1.0], "1-D grid"),
        ([[1.0, 2.0]], "1-D grid"),
        (["a", "b"], "omega"),
    ],
)
def test_bad_omega_grid_is_rejected(omega, match):
    for f in (A.loop_margins, A.nyquist_data):
        with pytest.raises(ValueError, match=match) as exc:
            f(_textbook(1.0), omega=omega)
        assert "omega" in str(exc.value)


def test_nyquist_data_checks_its_loop():
    with pytest.raises(TypeError, match="L: a python-control LTI"):
        A.nyquist_data([1, 2])  # type: ignore[arg-type]
    mimo = control.ss(np.eye(2) * -1.0, np.eye(2), np.eye(2), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="L: must be SISO"):
        A.nyquist_data(mimo)
    with pytest.raises(ValueError, match="L: must be SISO"):
        A.loop_margins(mimo)


@pytest.mark.parametrize("dt", [0.0, -0.01, float("nan"), float("inf"), True, "0.01"])
def test_poles_of_rejects_a_bad_sample_period(dt):
    with pytest.raises(ValueError, match="dt = "):
        A.poles_of([0.5 + 0.1j], dt)  # type: ignore[arg-type]


def test_poles_of_maps_discrete_poles():
    (p,) = A.poles_of([math.exp(-2.0 * 0.01)], 0.01)
    assert p.real == pytest.approx(-2.0) and p.damping == pytest.approx(1.0)
    assert A.poles_of([-2.0]) == A.poles_of([-2.0], None)


@pytest.mark.parametrize(
    "values",
    [
        [],
        [1e-4, float("nan")],
        [1e-4, float("inf")],
        [[1e-4, 2e-4]],
        1e-4,
        "1e-4",
        ["1e-4"],
        np.array([[1e-4]]),
        np.array(1e-4),
        None,
        [True, False],
        np.array([True, False]),
    ],  # fmt: skip
)
def test_root_locus_rejects_bad_values(values):
    with pytest.raises(ValueError, match="values = "):
        A.root_locus(_slip(), _law6(), parameter="k_r", values=values)


def test_root_locus_accepts_arrays_and_iterables():
    a = A.root_locus(_slip(), _law6(), parameter="k_r", values=np.array([1e-4, 3e-4]))
    b = A.root_locus(_slip(), _law6(), parameter="k_r", values=(v for v in (1e-4, 3e-4)))
    assert a.to_dict() == b.to_dict()


@pytest.mark.parametrize(("parameter", "values"), [("k_r", [1e-4, 3e-4]), ("omega_a", [50.0])])
def test_root_locus_with_the_plant_linearised_once_equals_slip_mode_poles(parameter, values):
    """k_r and omega_a only change the controller: the locus reuses one linearisation and gives
    the poles of :func:`linear.slip_mode_poles` with each controller."""
    import dataclasses

    op, c = _slip(), _law6()
    rl = A.root_locus(op, c, parameter=parameter, values=values)
    for v, pt in zip(values, rl.points, strict=True):
        if parameter == "k_r":
            cv = dataclasses.replace(c, lti=control.ss([], [], [], [[v]]))
        else:
            cv = dataclasses.replace(c, actuator=Actuator(v, c.actuator.delta))
        assert pt.poles == A.poles_of(L.slip_mode_poles(op, cv))


def test_db_phase_of_an_integrator_and_a_zero() -> None:
    w = np.array([0.1, 1.0, 10.0])
    db, ph = A.db_phase(1.0 / (1j * w))
    np.testing.assert_allclose(db, [20.0, 0.0, -20.0], atol=1e-12)
    np.testing.assert_allclose(ph, -90.0, atol=1e-12)
    db0, _ = A.db_phase([0.0, 1.0])
    assert db0[0] == -np.inf and db0[1] == 0.0
    # unwrapped: a delay's phase keeps falling past -180 deg
    _, ph_d = A.db_phase(np.exp(-1j * np.linspace(0.0, 3 * np.pi, 50)))
    assert ph_d[-1] == pytest.approx(-540.0)


# -- one Nyquist convention for continuous and sampled loops (issue 19, item 8) ----------------


def _true_unstable(loop) -> int:  # type: ignore[no-untyped-def]
    p = control.feedback(loop, 1).poles()
    return int(np.sum(np.abs(p) > 1.0)) if loop.dt else int(np.sum(p.real > 0))


@pytest.mark.parametrize("k", [0.5, 2.0, 10.0, 30.0])
def test_nyquist_integrator_loop_counts_alike_continuous_and_sampled(k):
    """L = k/(s(s+1)): its closed loop is stable for every k > 0; its ZOH samples are stable up to a
    gain that falls with the sample period. The integrator (s = 0, z = 1) lies on the boundary
    in both forms and counts as stable (P = 0) in both; N, and Z = N + P, follow the closed loop.
    (python-control's own count of the sampled loop depends on the round-off of the pole at z = 1:
    -1 for dt = 0.1.)"""
    Lc = control.tf([k], [1.0, 1.0, 0.0])
    nc = A.nyquist_data(Lc)
    assert (nc.encirclements, nc.open_loop_unstable_poles, nc.closed_loop_unstable_poles) == (
        0, 0, 0
    )  # fmt: skip
    assert nc.boundary_poles == 1 and nc.dt is None
    # the same as python-control's continuous count (indentation to the right)
    assert nc.encirclements == control.nyquist_response(Lc, warn_encirclements=False).count
    for dt in (0.1, 0.5):
        Ld = control.sample_system(Lc, dt, method="zoh")
        nd = A.nyquist_data(Ld)
        assert nd.boundary_poles == 1 and nd.open_loop_unstable_poles == 0 and nd.dt == dt
        assert nd.closed_loop_unstable_poles == _true_unstable(Ld) == nd.closed_loop_unstable_eig
        if _true_unstable(Ld) == 0:
            assert nd.encirclements == nc.encirclements == 0


def test_nyquist_counts_with_unstable_and_boundary_open_loop_poles():
    cases = [
        control.tf([2.0], [1.0, -1.0]),  # P = 1, stabilised: N = -1
        control.tf([0.5], [1.0, -1.0]),  # P = 1, not stabilised
        control.tf([1.0, 0.5], [1.0, 0.0, 0.0]),  # double integrator with a lead
        control.tf([4.0], np.polymul([1, 0], np.polymul([1, 1], [1, 1]))),  # Z = 2
    ]
    for Lc in cases:
        for loop in (Lc, control.sample_system(Lc, 0.1, method="zoh")):
            n = A.nyquist_data(loop)
            assert n.closed_loop_unstable_poles == _true_unstable(loop), (Lc, loop.dt)
            assert n.closed_loop_unstable_eig == n.closed_loop_unstable_poles


def test_nyquist_curve_keeps_the_low_frequencies_and_the_plot_shows_them():
    import matplotlib

    matplotlib.use("Agg")
    L = control.tf([2.0], [1.0, 1.0, 0.0])
    n = A.nyquist_data(L)
    assert n.omega[0] == 0.0 and n.omega[1] < n.contour_shift  # from the indentation on
    big = max(abs(complex(x, y)) for x, y in zip(n.real, n.imag, strict=True))
    assert big == pytest.approx(2.0 / n.contour_shift, rel=0.01)  # the integrator at low w
    fig = n.plot()
    ax_all, ax_zoom = fig.axes[:2]
    line = ax_all.get_lines()
    curve = next(ln for ln in line if ln.get_label() == "L, omega > 0")
    x, y = curve.get_xdata(), curve.get_ydata()
    (x0, x1), (y0, y1) = ax_all.get_xlim(), ax_all.get_ylim()
    assert x0 <= x.min() and x.max() <= x1 and y0 <= y.min() and y.max() <= y1  # nothing clipped
    assert ax_zoom.get_xlim()[0] < -1.0 < ax_zoom.get_xlim()[1]
    title = fig.get_suptitle()
    assert "N = 0" in title and "Z = N + P = 0" in title and "counted stable" in title
