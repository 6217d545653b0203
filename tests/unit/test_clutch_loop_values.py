"""Value tests of drivetrain_ctrl.linear.clutch (issue 22 item 4): the engine-side figures from
the parameter set by hand; the engine-side transfer functions from their formulas; the loop gain
of a continuous and of a sampled, delayed controller against the physical interconnection
(plant, actuator, sign block, controller) assembled here in state space and ZOH-sampled with
scipy; the slip-mode poles and the judder crossings' brackets against the eigenvalues of that
interconnection; the locked analysis' modes from its poles; the result objects' dicts and
summaries; and each bad input named (``./dev mutate drivetrain_ctrl/linear/clutch.py``).

The plant ``x_c -> states`` comes from :func:`~drivetrain_ctrl.linear.linearise` (another
module, with its own value tests); what is checked is how the clutch loop is put together."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from scipy import signal

from drivetrain_ctrl import linear as L
from drivetrain_ctrl.control.laws import law6_controller, pi_controller
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.linear import clutch as LC
from drivetrain_ctrl.plant.drivetrain import full_model, reduced_model
from drivetrain_ctrl.plant.params import default_params

P = default_params()
XC = 0.0725  # the middle of the pedal-map piece [0.07, 0.075]
#: a friction characteristic falling linearly: mu/mu0 = 1 - 0.001 |slip| (1/(rad/s))
P_MU = P.replace(**{"clutch.mu_table": {"x": [0.0, 200.0], "y": [1.0, 0.8]}})
W = np.array([0.3, 2.0, 11.0, 40.0, 150.0, 600.0])


def _slip(params=P, omega_driven: float = 80.0, kind: str = "reduced"):
    mk = reduced_model if kind == "reduced" else full_model
    return L.slip_operating_point(
        mk(params), omega_engine=170.0, omega_driven=omega_driven, x_c=XC, throttle=0.5
    )


def _pi(params=P, dt: float | None = None, delay: int = 0):
    return pi_controller(
        params, kp=1e-3, ki=5e-3, reference=sg.constant(170.0), driven_state="omega_primary",
        dt=dt, delay_samples=delay,
    )  # fmt: skip


def _law6(params=P):
    return law6_controller(params, reference=sg.constant(170.0), driven_state="omega_primary")


# -- the interconnection, written out ---------------------------------------------------------


def _plant(op, ctrl, mu_slope=None):
    """(A, B, Cm) of x_r -> the measured part of the error: the linearised plant behind the
    actuator w^2/(s^2 + 2 d w s + w^2), the sign block's sign folded into B."""
    sys = L.linearise(op, inputs=("x_c",), mu_slope=mu_slope)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    labels = list(sys.output_labels)
    Cm = sum(c * C[labels.index(s)] for c, s in ctrl.measurement if s != "ref")
    # body speeds do not jump with the pedal: no feedthrough to the measurement
    assert all(D[labels.index(s), 0] == 0.0 for _, s in ctrl.measurement if s != "ref")
    a, b = ctrl.sign_of
    sgn = 1.0 if op.state(a) > op.state(b) else -1.0
    w, d = ctrl.actuator.omega, ctrl.actuator.delta
    n = A.shape[0]
    Ap = np.zeros((n + 2, n + 2))
    Ap[:n, :n] = A
    Ap[:n, n] = B[:, 0]  # x_c = first actuator state
    Ap[n, n + 1] = 1.0
    Ap[n + 1, n] = -w * w
    Ap[n + 1, n + 1] = -2.0 * d * w
    Bp = np.zeros((n + 2, 1))
    Bp[n + 1, 0] = w * w * sgn
    Cp = np.concatenate([Cm, [0.0, 0.0]]).reshape(1, -1)
    return Ap, Bp, Cp


def _closed_continuous(op, ctrl, mu_slope=None):
    """State matrix of e = Cm x, u = C(e), x_r = sgn u (the physical loop, no sign tricks)."""
    Ap, Bp, Cp = _plant(op, ctrl, mu_slope)
    k = ctrl.lti
    Ak, Bk, Ck, Dk = (np.asarray(m, dtype=float) for m in (k.A, k.B, k.C, k.D))
    nk = Ak.shape[0]
    top = np.hstack([Ap + Bp @ (Dk @ Cp), Bp @ Ck])
    bot = np.hstack([Bk @ Cp, Ak])
    return np.vstack([top, bot]) if nk else Ap + Bp @ (Dk @ Cp)


def _closed_sampled(op, ctrl, mu_slope=None):
    """State matrix of the sampled loop: the plant ZOH-sampled (scipy), ``delay_samples`` unit
    delays between the controller and the plant, the controller's difference equation."""
    Ap, Bp, Cp = _plant(op, ctrl, mu_slope)
    dt = float(ctrl.lti.dt)
    Ad, Bd, Cd, _, _ = signal.cont2discrete((Ap, Bp, Cp, np.zeros((1, 1))), dt, method="zoh")
    k = ctrl.lti
    Ak, Bk, Ck, Dk = (np.asarray(m, dtype=float) for m in (k.A, k.B, k.C, k.D))
    n, nk, nd = Ad.shape[0], Ak.shape[0], ctrl.delay_samples
    N = n + nd + nk
    M = np.zeros((N, N))
    # plant: x+ = Ad x + Bd (oldest delayed value, or u itself without delay)
    M[:n, :n] = Ad
    # the controller's output u = Ck xk + Dk Cd x
    u_row = np.zeros(N)
    u_row[:n] = (Dk @ Cd)[0]
    u_row[n + nd :] = Ck[0]
    if nd:
        M[:n, n + nd - 1] = Bd[:, 0]
        M[n, :] = u_row  # the newest delayed value
        for j in range(1, nd):
            M[n + j, n + j - 1] = 1.0
    else:
        M[:n, :] += np.outer(Bd[:, 0], u_row)
    M[n + nd :, :n] = Bk @ Cd
    M[n + nd :, n + nd :] = Ak
    return M


def _loop_response(op, ctrl, w):
    """L(jw) or L(e^{jw dt}) of the physical loop, with the sign of negative feedback."""
    Ap, Bp, Cp = _plant(op, ctrl)
    if ctrl.is_discrete:
        dt = float(ctrl.lti.dt)
        Ad, Bd, Cd, _, _ = signal.cont2discrete((Ap, Bp, Cp, np.zeros((1, 1))), dt, method="zoh")
        z = np.exp(1j * w * dt)
        p = np.array([(Cd @ np.linalg.solve(zz * np.eye(len(Ad)) - Ad, Bd))[0, 0] for zz in z])
        p = p * z ** (-ctrl.delay_samples)
        c = np.array([complex(ctrl.lti(zz)) for zz in z])
    else:
        s = 1j * w
        p = np.array([(Cp @ np.linalg.solve(ss * np.eye(len(Ap)) - Ap, Bp))[0, 0] for ss in s])
        c = np.array([complex(ctrl.lti(ss)) for ss in s])
    return -c * p  # L = C P with P = -(the physical path): 1 + L = 0 is the loop's equation


def _resp(sys, w):
    if sys.dt:
        return np.array([complex(sys(np.exp(1j * x * sys.dt))) for x in w])
    return np.array([complex(sys(1j * x)) for x in w])


# -- the engine side ---------------------------------------------------------------------------


@pytest.mark.parametrize(("omega_driven", "sign", "mu"), [(80.0, 1, 0.91), (250.0, -1, 0.92)])
def test_engine_side_figures_from_the_parameter_set(omega_driven: float, sign: int, mu: float):
    es = L.engine_side(_slip(P_MU, omega_driven))
    # the pedal map's piece [0.07, 0.075] -> [0.25, 0.19140625] of k12_max = 250 N m
    slope = 250.0 * (0.19140625 - 0.25) / 0.005
    k13 = 250.0 * (0.25 + 0.5 * (0.19140625 - 0.25))
    assert es.J1 == P.engine.J1 == 0.2
    assert es.tau_p == pytest.approx(P.engine.tau_p, rel=1e-12)
    assert es.torque_per_throttle == pytest.approx(P.engine.K, rel=1e-12)
    assert es.b1_eff == pytest.approx(P.engine.b1, rel=1e-12)  # a linear torque map
    assert es.k13 == pytest.approx(k13, rel=1e-12)
    assert es.dk13_dxc == pytest.approx(slope, rel=1e-12)
    # mu/mu0 at the slip |170 - omega_driven|: 1 - 0.001 |slip|
    assert es.mu == pytest.approx(mu, rel=1e-12) and es.sign == sign
    assert es.clutch_gain == pytest.approx(slope * mu * sign, rel=1e-12)
    assert es.mu_slope_torque == pytest.approx(k13 * -0.001, rel=1e-12)


def test_engine_side_transfer_functions_are_their_formulas() -> None:
    op = _slip(P_MU)
    es = L.engine_side(op)
    s = 1j * W
    J1, b1, tau, K = 0.2, 0.03, 0.1, 150.0
    assert _resp(L.pedal_to_clutch_torque(op), W) == pytest.approx(
        np.full(W.size, es.clutch_gain), rel=1e-12
    )
    assert _resp(L.clutch_torque_to_engine_speed(op), W) == pytest.approx(
        -1.0 / (J1 * s + b1), rel=1e-12
    )
    assert _resp(L.throttle_to_engine_speed(op), W) == pytest.approx(
        K / ((tau * s + 1.0) * (J1 * s + b1)), rel=1e-12
    )


# -- the loop gain -----------------------------------------------------------------------------


@pytest.mark.parametrize("which", ["law6", "pi"])
def test_continuous_loop_gain_is_the_physical_interconnection(which: str) -> None:
    op = _slip(P_MU)
    ctrl = _law6(P_MU) if which == "law6" else _pi(P_MU)
    loop = L.clutch_loop(op, ctrl)
    want = _loop_response(op, ctrl, W)
    assert _resp(loop.L, W) == pytest.approx(want, rel=1e-8)
    assert not loop.discrete and loop.dt is None and loop.controller_name == ctrl.name
    # the gang of four from L, P and C at each frequency
    c = np.array([complex(ctrl.lti(1j * x)) for x in W])
    p = want / c
    assert _resp(loop.S, W) == pytest.approx(1.0 / (1.0 + want), rel=1e-7)
    assert _resp(loop.T, W) == pytest.approx(want / (1.0 + want), rel=1e-7)
    assert _resp(loop.PS, W) == pytest.approx(p / (1.0 + want), rel=1e-7)
    assert _resp(loop.CS, W) == pytest.approx(c / (1.0 + want), rel=1e-7)
    assert _resp(loop.plant, W) == pytest.approx(p, rel=1e-8)
    # the actuator's own transfer function
    wa, da = P.actuator.omega_a, P.actuator.delta_a
    s = 1j * W
    assert _resp(loop.actuator, W) == pytest.approx(wa**2 / (s**2 + 2 * da * wa * s + wa**2))
    # the closed loop (reference -> omega_1) has the poles of the interconnection
    cl = np.sort_complex(np.linalg.eigvals(np.asarray(loop.closed_loop.A)))
    ref = np.sort_complex(np.linalg.eigvals(_closed_continuous(op, ctrl)))
    assert cl == pytest.approx(ref, rel=1e-7, abs=1e-9)
    # clutch_loop_gain: the same engine side and L
    es, Lt = LC.clutch_loop_gain(op, ctrl)
    assert es == loop.engine
    assert _resp(Lt, W) == pytest.approx(want, rel=1e-8)


@pytest.mark.parametrize("delay", [0, 1, 2])
def test_sampled_loop_gain_is_the_zoh_plant_delayed(delay: int) -> None:
    op = _slip(P_MU)
    ctrl = _pi(P_MU, dt=0.01, delay=delay)
    loop = L.clutch_loop(op, ctrl)
    w = np.array([0.3, 2.0, 11.0, 40.0, 150.0])  # below the Nyquist frequency 314 rad/s
    want = _loop_response(op, ctrl, w)
    assert loop.discrete and loop.dt == 0.01 and loop.L.dt == 0.01
    # (the transfer function's coefficients carry round-off near the integrator at z = 1)
    assert _resp(loop.L, w) == pytest.approx(want, rel=1e-4)
    assert _resp(loop.S, w) == pytest.approx(1.0 / (1.0 + want), rel=1e-4)
    z = np.linalg.eigvals(np.asarray(loop.closed_loop.A))
    ref = np.linalg.eigvals(_closed_sampled(op, ctrl))
    # the same nonzero poles (a delay's poles at z = 0 may be realised differently)
    nz = np.sort_complex(z[np.abs(z) > 1e-9])
    assert nz == pytest.approx(np.sort_complex(ref[np.abs(ref) > 1e-9]), rel=1e-6, abs=1e-9)
    assert np.max(np.abs(z)) == pytest.approx(np.max(np.abs(ref)), rel=1e-9)


def test_a_rate_limiter_adds_its_first_order_lag_and_a_static_sign_none_is_plus() -> None:
    op = _slip(P_MU)
    ctrl = _law6(P_MU)
    g = 40.0
    rl = dataclasses.replace(ctrl, rate_limit=(0.5, g))
    s = 1j * W
    base = _resp(L.clutch_loop(op, ctrl).L, W)
    assert _resp(L.clutch_loop(op, rl).L, W) == pytest.approx(base * g / (s + g), rel=1e-8)
    # without a sign block the sign is +1 (the same as the sign block on slip+)
    plus = dataclasses.replace(ctrl, sign_of=None)
    assert _resp(L.clutch_loop(op, plus).L, W) == pytest.approx(base, rel=1e-10)
    # on slip- the sign block flips: without it the loop's sign is reversed there
    down = _slip(P_MU, 250.0)
    a = _resp(L.clutch_loop(down, ctrl).L, W)
    b = _resp(L.clutch_loop(down, plus).L, W)
    assert b == pytest.approx(-a, rel=1e-10)
    # without an actuator: the actuator's response divided out
    wa, da = P.actuator.omega_a, P.actuator.delta_a
    bare = dataclasses.replace(ctrl, actuator=None)
    act = wa**2 / (s**2 + 2 * da * wa * s + wa**2)
    assert _resp(L.clutch_loop(op, bare).L, W) == pytest.approx(base / act, rel=1e-8)
    assert _resp(L.clutch_loop(op, bare).actuator, W) == pytest.approx(np.ones(W.size))


# -- slip-mode poles and judder crossings -------------------------------------------------------


def test_slip_mode_poles_are_the_interconnections() -> None:
    op = _slip(P_MU)
    for ctrl in (_law6(P_MU), _pi(P_MU)):
        for mu in (None, -2e-3):
            got = np.sort_complex(L.slip_mode_poles(op, ctrl, mu_slope=mu))
            ref = np.sort_complex(np.linalg.eigvals(_closed_continuous(op, ctrl, mu)))
            assert got == pytest.approx(ref, rel=1e-7, abs=1e-9)
    plant = np.sort_complex(L.slip_mode_poles(op, None, mu_slope=-2e-3))
    A = L.linearise(op, inputs=("x_c",), mu_slope=-2e-3).A
    assert plant == pytest.approx(np.sort_complex(np.linalg.eigvals(A)), rel=1e-12, abs=1e-12)


def _rightmost(M: np.ndarray) -> float:
    return float(np.max(np.linalg.eigvals(M).real))


@pytest.mark.parametrize("which", ["none", "law6", "pi"])
def test_a_continuous_judder_crossing_is_bracketed_by_the_interconnection(which: str) -> None:
    op = _slip(P)
    ctrl = {"none": None, "law6": _law6(), "pi": _pi()}[which]
    jc = L.judder_crossing(op, ctrl)
    assert jc.available and jc.reason is None and jc.dt is None
    assert jc.controller == (None if ctrl is None else ctrl.name)

    def closed(mu: float) -> np.ndarray:
        if ctrl is None:
            return np.asarray(L.linearise(op, inputs=("x_c",), mu_slope=mu).A, dtype=float)
        return _closed_continuous(op, ctrl, mu)

    assert _rightmost(closed(jc.stable_side)) < 0.0
    assert _rightmost(closed(jc.unstable_side)) >= -1e-9 * np.max(np.abs(closed(0.0)))
    assert _rightmost(closed(0.0)) == pytest.approx(jc.spectral_abscissa_at_zero, rel=1e-9)
    # the bracket, its middle, its half-width and the torque slope
    a, b = jc.stable_side, jc.unstable_side
    assert b < a < 0.0 and jc.mu_slope_crit == pytest.approx(0.5 * (a + b), rel=1e-15)
    assert jc.tolerance == pytest.approx(0.5 * (a - b), rel=1e-12)
    assert jc.tolerance <= LC.JUDDER_RTOL * abs(b)
    assert jc.c_crit == pytest.approx(jc.k13 * jc.mu_slope_crit, rel=1e-15)
    assert jc.k13 == pytest.approx(L.engine_side(op).k13, rel=1e-15)
    # the crossing pole: the rightmost at the unstable side, its frequency |Im|/2pi
    p = np.linalg.eigvals(closed(b))
    q = p[np.argmax(p.real)]
    assert jc.crossing_pole == pytest.approx(q, rel=1e-6, abs=1e-6)
    assert jc.frequency_hz == pytest.approx(abs(q.imag) / (2 * math.pi), rel=1e-6, abs=1e-9)
    assert jc.searched == (-1.0, 0.0)
    assert jc.frequency_note == (
        "the crossing plant pole" if ctrl is None else "the crossing closed-loop pole"
    )
    # the grid's first unstable value and the bisection: a handful of steps each
    k = math.ceil(math.log(abs(b) / LC.JUDDER_FIRST_STEP) / math.log(LC.JUDDER_GRID_RATIO))
    assert k + 1 <= jc.evaluations <= k + 1 + 40 + 1


@pytest.mark.parametrize("delay", [0, 1])
def test_a_sampled_judder_crossing_is_bracketed_by_the_zoh_interconnection(delay: int) -> None:
    op = _slip(P)
    ctrl = _pi(P, dt=0.01, delay=delay)
    jc = L.judder_crossing(op, ctrl)
    assert jc.available and jc.dt == 0.01

    def radius(mu: float) -> float:
        return float(np.max(np.abs(np.linalg.eigvals(_closed_sampled(op, ctrl, mu)))))

    assert radius(jc.stable_side) < 1.0
    assert radius(jc.unstable_side) >= 1.0 - 1e-9
    # the largest real part of ln(z)/dt at mu' = 0 (z = 0 left out: it is deep inside)
    z0 = np.linalg.eigvals(_closed_sampled(op, ctrl, 0.0))
    z0 = z0[np.abs(z0) > 0.0]
    assert jc.spectral_abscissa_at_zero == pytest.approx(
        float(np.max(np.log(np.abs(z0)))) / 0.01, rel=1e-6
    )
    # the crossing pole ln(z)/dt of the outermost z at the unstable side
    z = np.linalg.eigvals(_closed_sampled(op, ctrl, jc.unstable_side))
    z = z[np.abs(z) > 0.0]
    q = np.log(z) / 0.01
    assert jc.crossing_pole.real == pytest.approx(float(np.max(q.real)), rel=1e-5, abs=1e-6)


def test_a_delay_moves_the_sampled_judder_crossing() -> None:
    op = _slip(P)
    a = L.judder_crossing(op, _pi(P, dt=0.01, delay=0))
    b = L.judder_crossing(op, _pi(P, dt=0.01, delay=1))
    assert abs(a.mu_slope_crit - b.mu_slope_crit) > 10 * (a.tolerance + b.tolerance)


def test_judder_crossing_results_as_dict_and_summary() -> None:
    op = _slip(P)
    jc = L.judder_crossing(op, _law6())
    d = jc.to_dict()
    json.dumps(d)
    assert d["mu_slope_crit"] == pytest.approx(jc.mu_slope_crit)
    assert d["crossing_pole"] == pytest.approx([jc.crossing_pole.real, jc.crossing_pole.imag])
    assert d["searched"] == [-1.0, 0.0] and d["controller"] == "law6"
    assert set(d) == {f.name for f in dataclasses.fields(jc)}
    assert jc.available
    assert jc.summary() == (
        f"mu' = {jc.mu_slope_crit:.6g} s/rad (+-{jc.tolerance:.2g}; c = k13 mu' = "
        f"{jc.c_crit:.6g} N m s/rad): a {jc.frequency_hz:.4g} Hz mode crosses"
    )
    real = L.judder_crossing(op, None)  # pedal held: a real pole crosses
    assert real.frequency_hz == 0.0
    assert real.summary().endswith("a real pole (no oscillation) crosses")
    none = L.judder_crossing(op, _law6(), search_limit=1e-5)
    assert not none.available
    assert none.summary() == f"not available: {none.reason}"
    assert none.to_dict()["crossing_pole"] is None and none.to_dict()["searched"] == [-1e-5, 0.0]


def test_judder_crossing_searches_down_to_the_limit_inclusive() -> None:
    op = _slip(P)
    full = L.judder_crossing(op, _law6())
    b = full.unstable_side
    # a limit on the grid value just beyond the crossing: found; a little before it: not
    k = round(math.log(abs(full.stable_side) / LC.JUDDER_FIRST_STEP, LC.JUDDER_GRID_RATIO))
    grid = [LC.JUDDER_FIRST_STEP * LC.JUDDER_GRID_RATIO**i for i in range(k + 3)]
    first_unstable = min(g for g in grid if g >= abs(b) * (1 - 1e-9))
    at = L.judder_crossing(op, _law6(), search_limit=first_unstable)
    assert at.available and at.mu_slope_crit == pytest.approx(full.mu_slope_crit, rel=1e-12)
    before = L.judder_crossing(op, _law6(), search_limit=first_unstable / 1.2)
    assert not before.available
    assert before.reason == (
        f"the slip mode stays stable for every mu' in [{-first_unstable / 1.2:g}, 0] s/rad "
        "(searched to that friction slope)"
    )


def test_judder_crossing_checks_its_options() -> None:
    op = _slip(P)
    for rtol in (0.0, 0.1, 0.15, -1e-3, math.nan, True):
        with pytest.raises(ValueError, match=r"rtol = .*must be a number in \(0, 0.1\)"):
            L.judder_crossing(op, None, rtol=rtol)
    assert L.judder_crossing(op, None, rtol=0.09).available
    for lim in (LC.JUDDER_FIRST_STEP, 0.0, math.inf):
        with pytest.raises(ValueError, match="search_limit = "):
            L.judder_crossing(op, None, search_limit=lim)
    with pytest.raises(ValueError, match="clutch loop exists only in slip"):
        L.judder_crossing(L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0))


# -- the closed form (reduced model) -------------------------------------------------------------


def test_judder_threshold_figures_from_the_parameter_set() -> None:
    op = _slip(P_MU)
    jt = L.judder_threshold(op, None)
    v = op.state("v_vehicle")
    m = op.model
    Dd = m.data
    ip, iv = m.chain.body_index("primary"), m.chain.body_index("vehicle")
    ratio = float(Dd.ratio[ip])
    assert jt.J25 == pytest.approx(float(Dd.M[ip]), rel=1e-15)
    assert jt.m_e == pytest.approx(float(Dd.M[iv]) / ratio**2, rel=1e-12)
    assert jt.b_e == pytest.approx(
        (float(Dd.visc[iv]) + 2 * float(Dd.quad[iv]) * abs(v)) / ratio**2, rel=1e-12
    )
    assert jt.b_p == pytest.approx(float(Dd.visc[ip]), rel=1e-15)
    assert jt.b1_eff == pytest.approx(P.engine.b1, rel=1e-12)
    assert jt.k13 == pytest.approx(L.engine_side(op).k13, rel=1e-15)
    assert jt.h_t > 0 and jt.b_t >= 0
    # the speed-source threshold of the driveline with these figures, and its frequency
    ds, ws = L.shuffle_speed_source_threshold(J=jt.J25, m=jt.m_e, h=jt.h_t, b=jt.b_t, e=jt.b_e)
    assert jt.c_shuffle_speed_source == pytest.approx(ds - jt.b_p, rel=1e-12)
    assert jt.shuffle_frequency_hz == pytest.approx(ws / (2 * math.pi), rel=1e-12)
    # pedal held: Z_e = J1 s + b1, the dc crossing the two sides' dampings in series
    b1, bd = jt.b1_eff, jt.b_p + jt.b_e
    assert jt.c_dc == pytest.approx(-b1 * bd / (b1 + bd), rel=1e-12)
    # the engine correction: c = c*/kappa, kappa = Re[(J1 jw + b1)/(J1 jw + b1 + c)] at w*
    s = 1j * ws
    kappa = ((0.2 * s + b1) / (0.2 * s + b1 + jt.c_shuffle)).real
    assert jt.engine_factor == pytest.approx(kappa, rel=1e-9)
    assert jt.c_shuffle == pytest.approx(jt.c_shuffle_speed_source / kappa, rel=1e-9)
    first = min((jt.c_dc, "dc"), (jt.c_shuffle, "shuffle"), key=lambda t: abs(t[0]))
    assert (jt.c_crit, jt.which) == first
    assert jt.mu_slope_crit == pytest.approx(jt.c_crit / jt.k13, rel=1e-15)
    d = jt.to_dict()
    json.dumps(d)
    assert d == pytest.approx({k: getattr(jt, k) for k in d if k != "which"} | {"which": jt.which})  # type: ignore[operator]


def test_judder_threshold_of_an_integrating_controller_has_no_dc_crossing() -> None:
    op = _slip(P)
    jt = L.judder_threshold(op, _pi())
    assert jt.c_dc is None and jt.which == "shuffle" and jt.c_crit == jt.c_shuffle
    # law (6): Z_e(0) = b1 (1 + L(0)), the dc crossing -Z_e(0) b_d/(b1 + b_d)
    ctrl = _law6()
    jt = L.judder_threshold(op, ctrl)
    L0 = complex(L.clutch_loop(op, ctrl).L(1e-9)).real
    bd = jt.b_p + jt.b_e
    assert jt.c_dc == pytest.approx(-jt.b1_eff * (1 + L0) * bd / (jt.b1_eff + bd), rel=1e-6)
    with pytest.raises(ValueError, match="a continuous controller is needed"):
        L.judder_threshold(op, _pi(dt=0.01))


# -- locked ----------------------------------------------------------------------------------------


def test_locked_analysis_modes_from_its_poles() -> None:
    op = L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0)
    la = L.locked_analysis(op)
    A = np.asarray(L.linearise(op, inputs=("throttle",)).A)
    lam = np.linalg.eigvals(A)
    assert list(la.poles) == pytest.approx(sorted(lam, key=lambda z: (z.real, z.imag)), abs=1e-9)
    osc = sorted((p for p in lam if p.imag > 1e-9), key=abs)
    assert len(la.shuffle_modes) == len(osc) >= 1
    for mode, p in zip(la.shuffle_modes, osc, strict=True):
        assert mode.natural_frequency_hz == pytest.approx(abs(p) / (2 * math.pi), rel=1e-9)
        assert mode.damped_frequency_hz == pytest.approx(p.imag / (2 * math.pi), rel=1e-9)
        assert mode.damping == pytest.approx(-p.real / abs(p), rel=1e-9)
    d = la.to_dict()
    json.dumps(d)
    assert d["margins"] is None and d["margins_reason"] == la.margins_reason
    assert np.ravel(d["poles"]) == pytest.approx(
        np.ravel([[p.real, p.imag] for p in la.poles]), rel=1e-8, abs=1e-12
    )
    assert d["shuffle_modes"][0]["natural_frequency_hz"] == pytest.approx(
        la.shuffle_modes[0].natural_frequency_hz
    )
    sm = la.breakaway_margins[0]
    assert d["breakaway_margins"][sm.element] == pytest.approx(
        {"capacity": sm.capacity, "torque": sm.torque, "margin": sm.margin}
    )
    with pytest.raises(ValueError, match="not 'stuck'"):
        L.locked_analysis(_slip())


# -- bad inputs ------------------------------------------------------------------------------------


def test_bad_controllers_are_named() -> None:
    op = _slip(P)
    ctrl = _law6()
    with pytest.raises(ValueError, match="controller.output = 'throttle': must drive 'pedal'"):
        L.clutch_loop(op, dataclasses.replace(ctrl, output="throttle"))
    only_ref = dataclasses.replace(ctrl, measurement=((1.0, "ref"),))
    with pytest.raises(ValueError, match="has no plant state"):
        L.clutch_loop(op, only_ref)
    nope = dataclasses.replace(ctrl, measurement=((1.0, "ref"), (-1.0, "omega_nope")))
    for fn in (L.clutch_loop, L.slip_mode_poles, L.judder_crossing):
        with pytest.raises(ValueError, match="'omega_nope' is not a body speed of the model"):
            fn(op, nope)
    # a sign block read at a point where its two speeds are equal
    same = dataclasses.replace(ctrl, sign_of=("omega_engine", "omega_engine"))
    with pytest.raises(ValueError, match=r"controller.sign_of = .*zero at the operating point"):
        L.clutch_loop(op, same)
    with pytest.raises(ValueError, match="a discrete controller"):
        L.slip_mode_poles(op, _pi(dt=0.01))
    locked = L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0)
    for fn in (L.engine_side, L.pedal_to_clutch_torque, L.clutch_torque_to_engine_speed):
        with pytest.raises(ValueError, match="op has the clutch 'stuck'"):
            fn(locked)
    with pytest.raises(ValueError, match="clutch_loop_gain: op has the clutch 'stuck'"):
        LC.clutch_loop_gain(locked, ctrl)
    with pytest.raises(ValueError, match="judder_threshold: op is on the 'full' model"):
        L.judder_threshold(_slip(P, kind="full"), None)


def test_vehicle_paths_are_siso_minimal_realisations() -> None:
    op = _slip(P_MU)
    sys = L.linearise(op, outputs=["a_vehicle"])
    i_x, i_t = list(sys.input_labels).index("x_c"), list(sys.input_labels).index("throttle")
    o = list(sys.output_labels).index("a_vehicle")
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    s = 1j * W
    for tf, i in ((L.pedal_to_vehicle_accel(op), i_x), (L.throttle_to_vehicle_accel(op), i_t)):
        want = [C[o] @ np.linalg.solve(x * np.eye(len(A)) - A, B[:, i]) + D[o, i] for x in s]
        assert _resp(tf, W) == pytest.approx(np.array(want), rel=1e-7)
    mu = -1e-3
    sys = L.linearise(op, outputs=["a_vehicle"], mu_slope=mu)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    want = [C[o] @ np.linalg.solve(x * np.eye(len(A)) - A, B[:, i_x]) + D[o, i_x] for x in s]
    assert _resp(L.pedal_to_vehicle_accel(op, mu_slope=mu), W) == pytest.approx(
        np.array(want), rel=1e-7
    )


def test_a_measurement_with_feedthrough_closes_an_algebraic_loop() -> None:
    """A controller that measures the clutch torque (feedthrough from x_c) with no actuator and
    a proportional part: ``x_c = sgn (Ck xk + Dk (Cm x + Dm x_c))`` is solved for x_c, i.e.
    ``x_c = sgn (Ck xk + Dk Cm x) / (1 - sgn Dk Dm)``, written out here."""
    op = _slip(P_MU)
    ctrl = dataclasses.replace(
        _pi(P_MU), actuator=None,
        measurement=((1.0, "ref"), (-1.0, "omega_engine"), (1e-3, "tau_13")),
    )  # fmt: skip

    def closed(mu: float | None) -> np.ndarray:
        sys = L.linearise(op, inputs=("x_c",), mu_slope=mu)
        A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
        lab = list(sys.output_labels)
        Cm = -C[lab.index("omega_engine")] + 1e-3 * C[lab.index("tau_13")]
        Dm = 1e-3 * D[lab.index("tau_13"), 0]
        k = ctrl.lti
        Ak, Bk, Ck, Dk = (float(np.asarray(m)[0, 0]) for m in (k.A, k.B, k.C, k.D))
        sgn = 1.0  # slip+
        den = 1.0 - sgn * Dk * Dm
        assert abs(Dk * Dm) > 1e-3  # the feedthrough matters
        # x_c = gx . x + gk xk
        gx, gk = sgn * Dk * Cm / den, sgn * Ck / den
        n = A.shape[0]
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = A + np.outer(B[:, 0], gx)
        M[:n, n] = B[:, 0] * gk
        M[n, :n] = Bk * (Cm + Dm * gx)
        M[n, n] = Ak + Bk * Dm * gk
        return M

    for mu in (None, -1e-3):
        got = np.sort_complex(L.slip_mode_poles(op, ctrl, mu_slope=mu))
        ref = np.sort_complex(np.linalg.eigvals(closed(mu)))
        assert got == pytest.approx(ref, rel=1e-7, abs=1e-9)
    jc = L.judder_crossing(op, ctrl)
    assert jc.spectral_abscissa_at_zero == pytest.approx(_rightmost(closed(0.0)), rel=1e-7)
    if jc.available:
        assert (
            _rightmost(closed(jc.stable_side)) < 0.0 <= _rightmost(closed(jc.unstable_side)) + 1e-9
        )


def test_a_measurement_of_several_speeds_sums_their_paths() -> None:
    op = _slip(P_MU)
    two = dataclasses.replace(
        _pi(P_MU), measurement=((1.0, "ref"), (-1.0, "omega_engine"), (0.5, "omega_primary"))
    )
    loop = L.clutch_loop(op, two)
    assert _resp(loop.L, W) == pytest.approx(_loop_response(op, two, W), rel=1e-8)
    cl = np.sort_complex(np.linalg.eigvals(np.asarray(loop.closed_loop.A)))
    ref = np.sort_complex(np.linalg.eigvals(_closed_continuous(op, two)))
    assert cl == pytest.approx(ref, rel=1e-7, abs=1e-9)
    one = L.clutch_loop(op, _pi(P_MU))
    assert not np.allclose(_resp(loop.L, W), _resp(one.L, W), rtol=1e-3)
    # the same in a sampled loop (built on another path)
    two_d = dataclasses.replace(
        _pi(P_MU, dt=0.01, delay=1),
        measurement=((1.0, "ref"), (-1.0, "omega_engine"), (0.5, "omega_primary")),
    )
    # every pole of the interconnection is a pole of the closed loop
    z = np.linalg.eigvals(np.asarray(L.clutch_loop(op, two_d).closed_loop.A))
    ref = np.linalg.eigvals(_closed_sampled(op, two_d))
    for p in ref[np.abs(ref) > 0.5]:
        assert np.min(np.abs(z - p)) < 1e-6 * abs(p)


def test_a_sampled_loop_measuring_two_speeds_has_the_interconnections_gain() -> None:
    op = _slip(P_MU)
    two_d = dataclasses.replace(
        _pi(P_MU, dt=0.01, delay=1),
        measurement=((1.0, "ref"), (-1.0, "omega_engine"), (0.5, "omega_primary")),
    )
    loop = L.clutch_loop(op, two_d)
    # the closed loop's spectral radius is the interconnection's (0.99947): no spurious
    # unstable pole (1.0021, the open plant's, in a second copy of the plant)
    z = np.linalg.eigvals(np.asarray(loop.closed_loop.A))
    ref = np.linalg.eigvals(_closed_sampled(op, two_d))
    assert np.max(np.abs(z)) == pytest.approx(np.max(np.abs(ref)), rel=1e-9)
    w = np.array([0.3, 2.0, 11.0, 40.0, 150.0])
    assert _resp(loop.L, w) == pytest.approx(_loop_response(op, two_d, w), rel=1e-4)


def test_the_analysis_results_are_frozen() -> None:
    op = _slip(P)
    locked = L.locked_analysis(L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0))
    for obj, name in (
        (L.clutch_loop(op, _law6()), "L"),
        (L.judder_crossing(op, None), "mu_slope_crit"),
        (L.judder_threshold(op, None), "c_crit"),
        (L.engine_side(op), "k13"),
        (locked, "poles"),
        (L.clutch_loop_margins(op, _law6()), "gain_margin_db"),
    ):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, name, None)


def test_the_results_repr_leaves_out_the_operating_point() -> None:
    op = _slip(P)
    assert repr(L.clutch_loop(op, _law6())).startswith("ClutchLoop(controller_name='law6', ")
    locked = L.locked_analysis(L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0))
    assert repr(locked).startswith("LockedAnalysis(margins_reason='clutch locked: ")


def test_a_sampled_crossing_reports_the_plant_modes_frequency() -> None:
    """ln(z)/dt knows a frequency only up to multiples of the sample rate: the crossing's
    frequency is that of the continuous plant mode lambda whose exp(lambda dt) is the crossing
    pole z (within 1 %), found here from the plant's eigenvalues at the unstable side; else
    |Im ln z|/(2 pi dt)."""
    op = _slip(P)
    branches = set()
    for dt, delay in ((0.01, 0), (0.01, 1), (0.002, 0), (0.02, 0)):
        jc = L.judder_crossing(op, _pi(P, dt=dt, delay=delay))
        z = complex(np.exp(jc.crossing_pole * dt))
        A = L.linearise(op, inputs=("x_c",), mu_slope=jc.unstable_side).A
        lam = np.linalg.eigvals(np.asarray(A))
        k = int(np.argmin(np.abs(np.exp(lam * dt) - z)))
        if abs(np.exp(lam[k] * dt) - z) <= 0.01 * max(abs(z), 1.0):  # a plant mode
            branches.add("plant")
            f = abs(lam[k].imag) / (2 * math.pi)
            assert jc.frequency_hz == pytest.approx(f, rel=1e-12)
            assert jc.frequency_note == (
                "the plant mode exp(lambda dt) nearest to the crossing closed-loop pole z"
                + (" (above the sampled loop's Nyquist frequency)" if f > 0.5 / dt else "")
            )
        else:
            branches.add("z")
            f = abs(jc.crossing_pole.imag) / (2 * math.pi)
            assert jc.frequency_hz == pytest.approx(f, rel=1e-12)
            assert jc.frequency_note.startswith("|Im ln(z)|/(2 pi dt) of the crossing")
            assert f"sample rate {1 / dt:g} Hz" in jc.frequency_note
    assert branches == {"plant", "z"}
