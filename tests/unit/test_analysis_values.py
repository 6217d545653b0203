"""Every analysis result of :mod:`drivetrain_ctrl.linear.margins` checked by value (issue 22 item 2).

Hand-derived loops:

* continuous ``L = k / (s (s + 1)^2)``: closed loop ``s^3 + 2 s^2 + s + k``; the bandwidth is the
  root of ``|T(jw)| = |T(0)|/sqrt(2)`` found here by a dense grid and ``brentq``;
* sampled ``L = K / (z - 1)`` (a discrete integrator, period ``h``): with ``z = e^{j theta}``,
  ``|z - 1| = 2 sin(theta/2)`` and ``arg(z - 1) = (pi + theta)/2``, so the gain crossover is at
  ``theta_c = 2 asin(K/2)``, the phase margin ``pi/2 - theta_c/2``, the phase crossover at the
  Nyquist frequency ``pi/h`` where ``L = -K/2`` (gain margin ``2/K``); the closed-loop pole is
  ``z = 1 - K``; ``|S| = |z - 1|/|z - 1 + K|`` is largest at ``z = -1`` (``2/(2 - K)``);
  ``|T| = K/|z - (1 - K)|`` is largest at ``z = 1`` (1, for ``0 < K < 1``) and equals
  ``1/sqrt(2)`` where ``cos theta = (1 + a^2 - 2 K^2)/(2 a)``, ``a = 1 - K``.

Root loci: each parameter's point equals the poles of a re-linearisation done here at that
value (parameters replaced by hand, the operating point made anew), on the slipping and on the
locked clutch.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
import scipy.optimize

from drivetrain_ctrl import linear as L
from drivetrain_ctrl.control.laws import law6_controller
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.linear import margins as A
from drivetrain_ctrl.plant.drivetrain import clutch_friction, reduced_model
from drivetrain_ctrl.plant.params import default_params

P = default_params()
SLIP = {"omega_engine": 170.0, "omega_driven": 80.0, "x_c": 0.0725, "throttle": 0.5}


def _slip(params=P):  # type: ignore[no-untyped-def]
    return L.slip_operating_point(reduced_model(params), **SLIP)


def _law6(params=P):  # type: ignore[no-untyped-def]
    return law6_controller(params, reference=sg.constant(170.0), driven_state="omega_primary")


def _textbook(k: float) -> control.TransferFunction:
    return control.tf([k], np.polymul([1, 0], np.polymul([1, 1], [1, 1])))


# -- bandwidth -----------------------------------------------------------------------------------


@pytest.mark.parametrize("k", [0.3, 1.0, 1.6])
def test_bandwidth_of_a_continuous_loop_is_the_3db_root(k: float) -> None:
    def mag_t(w: float) -> float:
        s = 1j * w
        return abs(k / (s**3 + 2 * s**2 + s + k))

    w = np.logspace(-3, 3, 200001)
    t = np.array([mag_t(x) for x in w[::100]])
    target = mag_t(1e-9) / math.sqrt(2)
    i = int(np.flatnonzero(t < target)[0]) * 100
    bw = scipy.optimize.brentq(lambda x: mag_t(x) - target, w[i - 100], w[i], xtol=1e-14)
    m = A.loop_margins(_textbook(k))
    assert m.bandwidth_rad_s == pytest.approx(bw, rel=2e-4)
    # a different loop gain gives a different bandwidth (no constant answer)
    assert A.loop_margins(_textbook(k * 1.1)).bandwidth_rad_s != pytest.approx(bw, rel=1e-2)


def test_bandwidth_on_a_user_grid_interpolates_between_grid_points() -> None:
    """On a coarse grid the 3-dB crossing is the log-linear interpolation of |T| between the two
    grid points that bracket it (written out here)."""
    k = 1.0
    w = np.logspace(-2, 1, 31)
    s = 1j * w
    t = np.abs(k / (s**3 + 2 * s**2 + s + k))
    thr = t[0] / math.sqrt(2)
    j = int(np.flatnonzero(t < thr)[0])
    f = (t[j - 1] - thr) / (t[j - 1] - t[j])
    expected = 10 ** (np.log10(w[j - 1]) + f * (np.log10(w[j]) - np.log10(w[j - 1])))
    m = A.loop_margins(_textbook(k), omega=w)
    assert m.bandwidth_rad_s == pytest.approx(expected, rel=1e-12)
    assert w[j - 1] < m.bandwidth_rad_s < w[j]
    # two grid points bracketing the crossing: the interpolation between them
    w2 = np.array([0.01, 10.0])
    t2 = np.abs(k / ((1j * w2) ** 3 + 2 * (1j * w2) ** 2 + 1j * w2 + k))
    f2 = (t2[0] - t2[0] / math.sqrt(2)) / (t2[0] - t2[1])
    m2 = A.loop_margins(_textbook(k), omega=w2)
    assert m2.bandwidth_rad_s == pytest.approx(10 ** (-2 + f2 * 3), rel=1e-12)
    # a grid ending before |T| falls: no bandwidth, with the reason
    m3 = A.loop_margins(_textbook(k), omega=np.logspace(-3, -2, 5))
    assert m3.bandwidth_rad_s is None and "3 dB" in dict(m3.reasons)["bandwidth_rad_s"]


# -- the sampled integrator loop ------------------------------------------------------------------


@pytest.mark.filterwarnings("ignore:divide by zero:RuntimeWarning")  # python-control at z = 1
@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")
@pytest.mark.parametrize(("K", "h"), [(0.5, 0.1), (0.8, 0.02)])
def test_margins_of_a_sampled_integrator_by_hand(K: float, h: float) -> None:
    Lz = control.tf([K], [1.0, -1.0], h)
    m = A.loop_margins(Lz)
    theta_c = 2 * math.asin(K / 2)
    pm = 90.0 - math.degrees(theta_c) / 2
    assert m.dt == h and m.stable is True
    assert m.crossover_rad_s == pytest.approx(theta_c / h, rel=1e-6)
    assert m.phase_margin_deg == pytest.approx(pm, rel=1e-6)
    assert m.delay_margin_s == pytest.approx(math.radians(pm) / (theta_c / h), rel=1e-6)
    # closed-loop pole z = 1 - K, mapped by s = ln(z)/h
    (p,) = m.closed_loop_poles
    assert p.real == pytest.approx(math.log(1 - K) / h, rel=1e-9) and p.imag == 0.0
    assert p.damping == pytest.approx(1.0) and m.natural_frequencies_hz == ()
    assert p.frequency_hz == pytest.approx(abs(math.log(1 - K) / h) / (2 * math.pi), rel=1e-9)
    # sensitivities: the automatic grid ends at 0.999 of the Nyquist frequency
    th_end = 0.999 * math.pi
    z_end = complex(math.cos(th_end), math.sin(th_end))
    assert m.ms == pytest.approx(abs((z_end - 1) / (z_end - 1 + K)), rel=1e-6)
    assert m.ms == pytest.approx(2 / (2 - K), rel=1e-4)
    assert m.mt == pytest.approx(1.0, rel=1e-5)
    # bandwidth: |T| = 1/sqrt(2) at cos(theta) = (1 + a^2 - 2 K^2) / (2 a)
    a = 1 - K
    assert m.bandwidth_rad_s == pytest.approx(
        math.acos((1 + a * a - 2 * K * K) / (2 * a)) / h, rel=1e-4
    )
    # symmetric disk margin: alpha = 1 / max |S - T| / 2 = 1 / max |(z - 1 - K)/(z - 1 + K)| / 2
    th = np.linspace(1e-6, 0.999 * math.pi, 200001)
    z = np.exp(1j * th)
    alpha = 1.0 / np.max(np.abs((z - 1 - K) / (z - 1 + K)) / 2)
    assert m.disk_margin == pytest.approx(alpha, rel=1e-4)
    assert m.disk_margin_db == pytest.approx(
        20 * math.log10((1 + alpha / 2) / (1 - alpha / 2)), rel=1e-4
    )
    assert m.disk_margin_deg == pytest.approx(math.degrees(2 * math.atan(alpha / 2)), rel=1e-4)
    # (its phase reaches -180 deg only at the Nyquist frequency itself: see the delayed loop)
    assert "disk_margin" not in dict(m.reasons)


@pytest.mark.parametrize(("K", "h"), [(0.5, 0.1), (0.3, 0.01)])
def test_margins_of_a_sampled_integrator_with_a_one_sample_delay_by_hand(
    K: float, h: float
) -> None:
    """L = K/(z (z - 1)): arg(z (z - 1)) = (pi + 3 theta)/2, so the phase crossover is at
    theta = pi/3 where |z (z - 1)| = 2 sin(pi/6) = 1 (gain margin 1/K); the gain crossover at
    theta_c = 2 asin(K/2) with phase margin 90 - 1.5 theta_c [deg]; closed loop z^2 - z + K."""
    m = A.loop_margins(control.tf([K], [1.0, -1.0, 0.0], h))
    theta_c = 2 * math.asin(K / 2)
    pm = 90.0 - 1.5 * math.degrees(theta_c)
    assert m.stable is True and m.dt == h
    assert m.phase_crossover_rad_s == pytest.approx(math.pi / 3 / h, rel=1e-6)
    assert m.gain_margin_db == pytest.approx(-20 * math.log10(K), rel=1e-6)
    assert m.crossover_rad_s == pytest.approx(theta_c / h, rel=1e-6)
    assert m.phase_margin_deg == pytest.approx(pm, rel=1e-6)
    assert m.delay_margin_s == pytest.approx(math.radians(pm) / (theta_c / h), rel=1e-6)
    zc = np.roots([1.0, -1.0, K])
    sc = np.log(zc.astype(complex)) / h
    assert sorted(q.real for q in m.closed_loop_poles) == pytest.approx(sorted(sc.real))
    if K > 0.25:  # complex pair: one natural frequency
        assert m.natural_frequencies_hz == pytest.approx((abs(sc[0]) / (2 * math.pi),))
    th = np.linspace(1e-7, 0.999 * math.pi, 400001)
    z = np.exp(1j * th)
    Lz = K / (z * (z - 1))
    assert m.ms == pytest.approx(np.max(np.abs(1 / (1 + Lz))), rel=1e-4)
    assert m.mt == pytest.approx(np.max(np.abs(Lz / (1 + Lz))), rel=1e-4)

    def mag_t(t: float) -> float:
        zz = complex(math.cos(t), math.sin(t))
        return abs(K / (zz * zz - zz + K))

    i = int(np.flatnonzero(np.abs(Lz / (1 + Lz)) < 1 / math.sqrt(2))[0])
    bw = scipy.optimize.brentq(lambda t: mag_t(t) - 1 / math.sqrt(2), th[i - 1], th[i]) / h
    assert m.bandwidth_rad_s == pytest.approx(bw, rel=1e-4)


def test_an_unstable_sampled_loop() -> None:
    """L = K/(z (z - 1)) with K = 1.5 > 1: closed-loop poles |z| = sqrt(K) outside the unit circle;
    the gain margin 1/K < 1 is negative in dB; no delay or disk margin, each with its reason."""
    K, h = 1.5, 0.1
    m = A.loop_margins(control.tf([K], [1.0, -1.0, 0.0], h))
    assert m.stable is False
    assert m.gain_margin_db == pytest.approx(-20 * math.log10(K), rel=1e-6)
    for p in m.closed_loop_poles:
        assert p.real == pytest.approx(math.log(math.sqrt(K)) / h, rel=1e-9)
        assert p.damping < 0
    r = dict(m.reasons)
    assert m.delay_margin_s is None and r["delay_margin_s"] == "closed loop unstable"
    assert m.disk_margin is None and r["disk_margin"] == "closed loop unstable"


def test_a_loop_without_crossovers_gives_its_reasons_and_the_sensitivity_peaks() -> None:
    """L = 0.5/(s + 1): |L| < 1 (no gain crossover) and phase > -90 deg (no phase crossover);
    Ms = max |(s + 1)/(s + 1.5)| -> 1 at high frequency, Mt = |T(0)| = 1/3."""
    m = A.loop_margins(control.tf([0.5], [1.0, 1.0]))
    r = dict(m.reasons)
    assert set(r) == {"gain_margin_db", "phase_margin_deg", "delay_margin_s"}
    assert m.crossover_rad_s is None and m.phase_crossover_rad_s is None
    assert m.delay_margin_s is None
    assert m.mt == pytest.approx(1.0 / 3.0, rel=1e-6)
    w_top = 1e3  # the automatic grid ends 1000 times above the pole
    assert m.ms == pytest.approx(abs((1j * w_top + 1) / (1j * w_top + 1.5)), rel=1e-9)
    assert m.stable is True and m.disk_margin is not None
    (p,) = m.closed_loop_poles
    assert p.real == pytest.approx(-1.5) and p.damping == pytest.approx(1.0)


def test_natural_frequencies_of_the_oscillatory_closed_loop_poles() -> None:
    k = 1.0
    m = A.loop_margins(_textbook(k))
    cl = np.roots([1, 2, 1, k])
    osc = cl[np.abs(cl.imag) > 1e-9]
    (f,) = m.natural_frequencies_hz
    assert f == pytest.approx(abs(osc[0]) / (2 * math.pi), rel=1e-9)
    for q in m.closed_loop_poles:
        assert q.damping == pytest.approx(-q.real / math.hypot(q.real, q.imag), rel=1e-9)


def test_clutch_loop_margins_pass_the_friction_slope_on() -> None:
    op, c = _slip(), _law6()
    ms = 0.3 * L.judder_threshold(op, c).mu_slope_crit
    got = A.clutch_loop_margins(op, c, mu_slope=ms)
    want = A.loop_margins(L.clutch_loop(op, c, mu_slope=ms).L)
    assert got.to_dict() == want.to_dict()
    assert got.to_dict() != A.clutch_loop_margins(op, c).to_dict()


# -- root loci: each parameter against a re-linearisation here ------------------------------------


def _poles(p) -> list[complex]:  # type: ignore[no-untyped-def]
    return sorted((complex(q) for q in np.asarray(p)), key=lambda z: (z.real, z.imag))


def _locus(pt) -> list[complex]:  # type: ignore[no-untyped-def]
    return sorted((complex(q.real, q.imag) for q in pt.poles), key=lambda z: (z.real, z.imag))


def _close(a: list[complex], b: list[complex], rel: float = 1e-6) -> bool:
    return len(a) == len(b) and all(
        abs(x - y) <= rel * max(1.0, abs(y)) for x, y in zip(a, b, strict=True)
    )


def test_root_locus_over_J1_is_the_relinearisation_with_that_inertia() -> None:
    op, c = _slip(), _law6()
    j1 = [0.5 * P.engine.J1, 2.0 * P.engine.J1]
    rl = A.root_locus(op, c, parameter="J1", values=j1)
    assert rl.unit == "kg m^2"
    for v, pt in zip(j1, rl.points, strict=True):
        pv = P.replace(**{"engine.J1": v})
        want = _poles(L.slip_mode_poles(_slip(pv), c))
        assert _close(_locus(pt), want), v
        assert pt.max_real == pytest.approx(max(z.real for z in want), rel=1e-6)
        assert pt.stable is (pt.max_real < 0)
    # the engine pole ~ -(b1 + k_r |k13'|)/J1 moves with 1/J1: the two points differ
    assert not _close(_locus(rl.points[0]), _locus(rl.points[1]), rel=1e-3)


def test_root_locus_over_the_pedal_slope_scales_the_capacity_slope() -> None:
    """factor f on the pedal map's slope about x_c, the capacity at x_c kept: the map rebuilt by
    hand here (knots moved, clipped to [0, k12_max], renormalised) and the point re-made."""
    op, c = _slip(), _law6()
    x_c = SLIP["x_c"]
    fr = clutch_friction(P)
    tab = fr.capacity_table
    assert tab is not None
    k0 = fr.capacity(x_c)
    slope0 = L.engine_side(op).dk13_dxc
    for f in (0.5, 1.5):
        y = np.clip(k0 + f * (np.asarray(tab.y) - k0), 0.0, P.clutch.k12_max)
        top = float(np.max(y))
        pf = P.replace(
            **{
                "clutch.k12_max": top,
                "clutch.pedal_map": {"x": list(tab.x), "y": [float(v) / top for v in y]},
            }
        )
        assert clutch_friction(pf).capacity(x_c) == pytest.approx(k0, rel=1e-9)
        op_f = _slip(pf)
        assert L.engine_side(op_f).dk13_dxc == pytest.approx(f * slope0, rel=1e-6)
        (pt,) = A.root_locus(op, c, parameter="pedal_slope", values=[f]).points
        assert _close(_locus(pt), _poles(L.slip_mode_poles(op_f, c))), f
    # the slope moves the engine pole: factor 1 is the unchanged point
    (p1,) = A.root_locus(op, c, parameter="pedal_slope", values=[1.0]).points
    assert _close(_locus(p1), _poles(L.slip_mode_poles(op, c)))


def test_root_locus_over_mu_slope_and_omega_a_by_value() -> None:
    op, c = _slip(), _law6()
    ms = 0.4 * L.judder_threshold(op, c).mu_slope_crit
    (pt,) = A.root_locus(op, c, parameter="mu_slope", values=[ms]).points
    assert _close(_locus(pt), _poles(L.slip_mode_poles(op, c, mu_slope=ms)))
    assert not _close(_locus(pt), _poles(L.slip_mode_poles(op, c)), rel=1e-4)
    assert A.root_locus(op, c, parameter="omega_a", values=[80.0]).unit == "rad/s"


def test_root_locus_of_a_locked_clutch_gives_the_plant_poles() -> None:
    """The stuck-clutch branch: the clutch loop is open, the locus gives the eigenvalues of the
    locked plant; for J1 each re-made with that inertia, for k_r (controller only) the same
    poles at every value."""
    from drivetrain_ctrl.plant.drivetrain import Drivetrain

    op = L.locked_trim(Drivetrain(P, kind="reduced"), vehicle_speed_kmh=25.0)
    c = _law6()
    assert op.clutch_mode == "stuck"
    want = _poles(np.linalg.eigvals(L.linearise(op).A))
    rl = A.root_locus(op, c, parameter="k_r", values=[1e-4, 1e-3])
    for pt in rl.points:
        assert dict(pt.modes)["clutch"] == "stuck"
        assert _close(_locus(pt), want)
        assert pt.max_real == pytest.approx(max(z.real for z in want), abs=1e-12)
    j1 = 2.0 * P.engine.J1
    (pj,) = A.root_locus(op, c, parameter="J1", values=[j1]).points
    op_j = L.locked_trim(
        Drivetrain(P.replace(**{"engine.J1": j1}), kind="reduced"), vehicle_speed_kmh=25.0
    )
    want_j = _poles(np.linalg.eigvals(L.linearise(op_j).A))
    assert _close(_locus(pj), want_j)
    assert not _close(want_j, want, rel=1e-4)


def test_root_locus_crossing_interpolates_the_largest_real_part() -> None:
    pts = (
        A.RootLocusPoint(1.0, (), (), -2.0, False),
        A.RootLocusPoint(2.0, (), (), -1.0, True),
        A.RootLocusPoint(3.0, (), (), 1.0, False),
    )
    # first change of stability between 1 and 2 (flags given), at f = -2 / (-2 - -1) = 2
    assert A.RootLocus("k_r", "m s/rad", pts).crossing() == pytest.approx(1.0 + 2.0 * 1.0)
    pts2 = (
        A.RootLocusPoint(1.0, (), (), -0.5, True),
        A.RootLocusPoint(3.0, (), (), 1.5, False),
    )
    assert A.RootLocus("k_r", "m s/rad", pts2).crossing() == pytest.approx(1.5)
    assert A.RootLocus("k_r", "m s/rad", pts2[:1]).crossing() is None


# -- Nyquist counts ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("den", "K", "P_", "boundary", "Z"),
    [
        ([1.0, -1.0], 0.5, 0, 1, 0),  # integrator z = 1 on the boundary: stable
        ([1.0, -1.0], 2.5, 0, 1, 1),  # ... closed loop z = 1 - K = -1.5
        ([1.0, 1.0], 0.5, 0, 1, 1),  # pole z = -1 on the boundary; closed loop z = -1.5
        ([1.0, -1.001], 0.5, 1, 0, 0),  # |z| = 1.001 beyond the tolerance: unstable, stabilised
        ([1.0, -1.001], 0.0005, 1, 0, 1),  # ... not stabilised: z = 1.0005
    ],
)
def test_nyquist_counts_of_first_order_sampled_loops(den, K, P_, boundary, Z) -> None:  # type: ignore[no-untyped-def]
    h = 0.05
    n = A.nyquist_data(control.tf([K], den, h))
    assert n.dt == h
    assert n.open_loop_unstable_poles == P_
    assert n.boundary_poles == boundary
    assert n.closed_loop_unstable_poles == Z == n.closed_loop_unstable_eig
    assert n.encirclements == Z - P_
    # the contour runs outside the boundary's tolerance and inside every other pole
    assert A.NYQUIST_BOUNDARY_TOL / h < n.contour_shift or boundary == 0
    others = [abs(math.log(abs(float(np.roots(den)[0])))) / h] if boundary == 0 else []
    cl = abs(math.log(abs(-den[1] - K))) / h
    assert n.contour_shift < min([cl, *others])


def test_nyquist_of_a_continuous_loop_with_an_integrator_and_an_unstable_pole() -> None:
    """L = k (s + 1)/(s (s - 1)): P = 1 (s = 1), one boundary pole (s = 0); the closed loop
    s^2 + (k - 1) s + k is stable for k > 1 (N = -1) and unstable for k < 1 (two poles, N = 1)."""
    for k, Z in ((3.0, 0), (0.5, 2)):
        n = A.nyquist_data(control.tf([k, k], [1.0, -1.0, 0.0]))
        assert (n.open_loop_unstable_poles, n.boundary_poles) == (1, 1)
        assert n.closed_loop_unstable_poles == Z and n.encirclements == Z - 1
        assert 0 < n.contour_shift < min(1.0, *np.abs(np.roots([1.0, k - 1.0, k]).real))
        # the curve starts at omega = 0 on the shifted contour: L(shift), real
        s0 = n.contour_shift
        assert n.omega[0] == 0.0
        assert complex(n.real[0], n.imag[0]) == pytest.approx(k * (s0 + 1) / (s0 * (s0 - 1)))


# -- the figures ---------------------------------------------------------------------------------


def test_loop_plot_draws_L_S_and_T() -> None:
    import matplotlib

    matplotlib.use("Agg")
    Lc = _textbook(1.0)
    m = A.loop_margins(Lc)
    fig = m.plot(Lc)
    am = fig.axes[0]
    lines = {ln.get_label(): ln for ln in am.get_lines()}
    assert {"L", "S", "T"} <= set(lines)
    w = np.asarray(lines["L"].get_xdata(), dtype=float)
    s = 1j * w
    Lw = 1.0 / (s * (s + 1) ** 2)
    for name, h in (("L", Lw), ("S", 1 / (1 + Lw)), ("T", Lw / (1 + Lw))):
        np.testing.assert_allclose(lines[name].get_ydata(), 20 * np.log10(np.abs(h)), atol=1e-9)
    # the peaks on the figure are Ms and Mt
    assert 10 ** (np.max(lines["S"].get_ydata()) / 20) == pytest.approx(m.ms, rel=1e-9)
    assert 10 ** (np.max(lines["T"].get_ydata()) / 20) == pytest.approx(m.mt, rel=1e-9)
    assert "PM" in fig.get_suptitle() or any("PM" in ax.get_title() for ax in fig.axes)
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_nyquist_plot_returns_the_figure_of_the_curve() -> None:
    import matplotlib
    import matplotlib.pyplot as plt

    matplotlib.use("Agg")
    n = A.nyquist_data(_textbook(4.0))
    fig = n.plot(title="textbook k = 4")
    assert isinstance(fig, matplotlib.figure.Figure)
    curve = next(ln for ln in fig.axes[0].get_lines() if ln.get_label() == "L, omega > 0")
    assert len(curve.get_xdata()) == len(n.real)
    title = fig.get_suptitle()
    assert "textbook k = 4" in title and "N = 2" in title and "Z = N + P = 2" in title
    plt.close(fig)


def test_root_locus_says_which_controller_a_parameter_needs() -> None:
    from drivetrain_ctrl.control.laws import pi_controller

    op = _slip()
    pi = pi_controller(
        P, reference=sg.constant(170.0), kp=3e-4, ki=1e-3, driven_state="omega_primary"
    )
    pi_d = pi_controller(
        P, reference=sg.constant(170.0), kp=3e-4, ki=1e-3, dt=0.01, driven_state="omega_primary"
    )
    for c in (None, pi, pi_d):
        with pytest.raises(ValueError, match="parameter 'k_r': needs a static continuous"):
            A.root_locus(op, c, parameter="k_r", values=[1e-4])
    with pytest.raises(ValueError, match="parameter 'omega_a': needs a controller with an"):
        A.root_locus(op, None, parameter="omega_a", values=[50.0])


def test_the_loop_figure_title_gives_the_margins() -> None:
    import matplotlib.pyplot as plt

    Lc = _textbook(1.0)
    m = A.loop_margins(Lc)
    fig = m.plot(Lc)
    title = fig.get_suptitle() or fig.axes[0].get_title()
    want = f"GM {m.gain_margin_db:.3g} dB, PM {m.phase_margin_deg:.3g} deg, DM "
    assert want in title and f"DM {m.disk_margin_db:.3g} dB" in title
    plt.close(fig)
    m0 = A.loop_margins(control.tf([0.5], [1.0, 1.0]))  # no crossovers: dashes
    fig0 = m0.plot()
    assert "GM - dB, PM - deg" in (fig0.get_suptitle() or fig0.axes[0].get_title())
    plt.close(fig0)
