"""Exact switching simulation against hand-derived solutions of small chains.

Every case here has piecewise-constant (or piecewise-linear in time) accelerations, so the speeds
are polynomials in time inside each mode and the event times solve linear or quadratic equations.
The integrator (Dormand-Prince 5(4)) is exact on such pieces up to round-off, and the event
location bisects the guard to about ``1e-13`` s, so event times are compared within ``1e-9`` s
and speeds within ``1e-9`` (relative).

Sign conventions (:mod:`drivetrain_ctrl.chain`): coupling ``c`` with relative speed
``w = omega_c - r omega_{c+1}`` and torque ``T`` acts with ``-T`` on body ``c`` and ``+r T`` on
body ``c + 1``; a slipping friction element carries ``T = +k`` (slip+, ``w > 0``) or ``-k``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction, Spring, two_body_clutch
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.sim.simulator import SimulationOptions, SimulationResult, simulate

T_EV = 1e-9  # event-time tolerance [s]


def events_of(res: SimulationResult, element: str | None = None) -> list[tuple[float, str, str]]:
    return [(e.t, e.from_mode, e.to_mode) for e in res.events if element in (None, e.element)]


def sample_at(res: SimulationResult, t: float) -> int:
    """Index of the recorded sample at time ``t`` (the state just after an event there)."""
    i = int(np.argmin(np.abs(res.t - t)))
    assert abs(res.t[i] - t) < 1e-12 * max(1.0, abs(t)) + 1e-12, (res.t[i], t)
    # several samples may share the time (event + breakpoint): take the last one
    while i + 1 < res.t.shape[0] and res.t[i + 1] == res.t[i]:
        i += 1
    return i


def assert_events(
    res: SimulationResult, expected: list[tuple[float, str, str]], element: str | None = None
) -> None:
    got = events_of(res, element)
    assert [(a, b) for _, a, b in got] == [(a, b) for _, a, b in expected], got
    for (tg, *_), (te, *_) in zip(got, expected, strict=True):
        assert abs(tg - te) <= T_EV, (tg, te, tg - te)


# ------------------------------------------------------------------------------------------------
# 1. locked mode == merged inertia
# ------------------------------------------------------------------------------------------------


def test_locked_two_body_clutch_is_the_merged_inertia() -> None:
    """Huge capacity: (J1 + J2) w' = T(t) with T = 25 + 8 sin(13 t); no event, clutch stuck."""
    j1, j2, w0 = 0.3, 0.7, 40.0
    m = Model(two_body_clutch(j1, j2, capacity=1e6))
    torque = sg.constant(25.0) + sg.sine(8.0, 13.0)
    res = simulate(m, [w0, w0], {"torque1": torque}, t_end=2.0)
    assert res.status == "ok"
    assert res.events == ()
    assert set(res.mode_series("clutch")) == {"stuck"}
    t = res.t
    exact = w0 + (25.0 * t + 8.0 * (1.0 - np.cos(13.0 * t)) / 13.0) / (j1 + j2)
    np.testing.assert_allclose(res.x[:, 0], exact, rtol=1e-9, atol=0.0)
    np.testing.assert_allclose(res.x[:, 1], exact, rtol=1e-9, atol=0.0)
    # the clutch carries exactly the torque that accelerates body 2: J2 T / (J1 + J2)
    Tc = res.coupling_torques()[:, 0]
    np.testing.assert_allclose(Tc, j2 / (j1 + j2) * torque(t), rtol=1e-9, atol=1e-9)


def test_locked_four_body_chain_with_viscous_load_is_first_order_lag() -> None:
    """Four bodies locked by strong clutches, torque T on the first, viscous b on the last:
    ``sum(J) w' = T - b w``, so ``w = T/b + (w0 - T/b) exp(-b t / sum(J))``."""
    J = (0.2, 0.5, 0.1, 1.2)
    T, b, w0 = 30.0, 2.0, 3.0
    bodies = tuple(
        Body(f"b{i}", J[i], torque_input="T" if i == 0 else None, viscous=b if i == 3 else 0.0)
        for i in range(4)
    )
    cps = tuple(Coupling(f"c{i}", friction=Friction(scale=1e5, name=f"c{i}")) for i in range(3))
    m = Model(Chain(bodies, cps, inputs=("T",)))
    res = simulate(m, [w0] * 4, {"T": T}, t_end=3.0)
    assert res.events == ()
    Jt = sum(J)
    exact = T / b + (w0 - T / b) * np.exp(-b * res.t / Jt)
    for i in range(4):
        np.testing.assert_allclose(res.x[:, i], exact, rtol=1e-8, atol=0.0)
    # stuck torque of coupling c carries what accelerates everything downstream of it
    a = (T - b * res.x[:, 3]) / Jt
    Tc = res.coupling_torques()
    for c in range(3):
        down = sum(J[c + 1 :])
        np.testing.assert_allclose(Tc[:, c], down * a + b * res.x[:, 3], rtol=1e-7, atol=1e-9)


# ------------------------------------------------------------------------------------------------
# 2. the lock projection preserves momentum
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ratio", [1.0, 2.5])
def test_kernel_project_preserves_momentum(ratio: float) -> None:
    """Projection onto w1 - r w2 = 0 keeps r J1 w1 + J2 w2 (the momentum along the constraint
    manifold) and zeroes the relative speed."""
    j1, j2 = 2.0, 0.5
    ch = Chain(
        (Body("b1", j1), Body("b2", j2)),
        (Coupling("clutch", ratio=ratio, friction=Friction(scale=10.0, name="clutch")),),
    )
    m = Model(ch)
    x = np.array([10.0, 4.0])
    p_before = ratio * j1 * x[0] + j2 * x[1]
    K.project(m.data, x, np.array([1], dtype=np.int64))
    assert x[0] - ratio * x[1] == pytest.approx(0.0, abs=1e-13)
    assert ratio * j1 * x[0] + j2 * x[1] == pytest.approx(p_before, rel=1e-14)
    # hand solution: w2 = p / (r^2 J1 + J2), w1 = r w2
    w2 = p_before / (ratio**2 * j1 + j2)
    np.testing.assert_allclose(x, [ratio * w2, w2], rtol=1e-14)


def test_decide_projection_at_start_keeps_weighted_mean_speed() -> None:
    """A run started with a small slip (below tol_w) is projected to the weighted mean speed
    z = (J1 w1 + J2 w2) / (J1 + J2) and sticks."""
    j1, j2 = 0.2, 0.6
    m = Model(two_body_clutch(j1, j2, capacity=100.0))
    x0 = np.array([10.0, 9.9])
    res = simulate(m, x0, {"torque1": 0.0}, t_end=0.01, options=SimulationOptions(tol_w=0.5))
    z = (j1 * x0[0] + j2 * x0[1]) / (j1 + j2)
    np.testing.assert_allclose(res.x[0], [z, z], rtol=1e-14)
    np.testing.assert_allclose(res.x[-1], [z, z], rtol=1e-14)
    assert res.mode_series("clutch")[0] == "stuck"


def test_weighted_mean_speed_is_continuous_across_lockup() -> None:
    """z = (J1 w1 + J2 w2)/(J1 + J2) only sees the external torque: z(t) = z0 + T1 t/(J1 + J2) at
    every sample, in particular just before and just after the slip -> stuck event."""
    j1, j2, T1 = 0.2, 1.0, 20.0
    m = Model(two_body_clutch(j1, j2, capacity=50.0))
    res = simulate(m, [100.0, 0.0], {"torque1": T1}, t_end=1.0)
    z = (j1 * res.x[:, 0] + j2 * res.x[:, 1]) / (j1 + j2)
    z_exact = (j1 * 100.0) / (j1 + j2) + T1 * res.t / (j1 + j2)
    np.testing.assert_allclose(z, z_exact, rtol=1e-12)
    (t_ev, _, to), *_ = events_of(res, "clutch")
    assert to == "stuck"
    i = sample_at(res, t_ev)
    before, after = z[i - 1], z[i]
    assert after - before == pytest.approx(T1 * (res.t[i] - res.t[i - 1]) / (j1 + j2), abs=1e-11)
    assert res.x[i, 0] == res.x[i, 1]  # relative speed exactly zero after the projection


# ------------------------------------------------------------------------------------------------
# 3. hand-derived event times
# ------------------------------------------------------------------------------------------------


def test_two_body_lockup_time_and_speeds() -> None:
    """Slip+ with constant accelerations a1 = (T1 - k)/J1, a2 = k/J2; lock-up at
    t* = (w10 - w20)/(a2 - a1); then both at a = T1/(J1 + J2) (stuck torque J2 T1/(J1+J2) < k)."""
    j1, j2, k, T1, w10, w20 = 0.2, 1.0, 50.0, 20.0, 100.0, 0.0
    m = Model(two_body_clutch(j1, j2, capacity=k))
    res = simulate(m, [w10, w20], {"torque1": T1}, t_end=1.0)
    a1, a2 = (T1 - k) / j1, k / j2
    t_star = (w10 - w20) / (a2 - a1)
    assert t_star == pytest.approx(0.5)
    assert_events(res, [(t_star, "slip+", "stuck")], "clutch")
    w_star = w20 + a2 * t_star
    i = sample_at(res, res.events[0].t)
    np.testing.assert_allclose(res.x[i], [w_star, w_star], rtol=1e-12)
    a = T1 / (j1 + j2)
    np.testing.assert_allclose(res.x[-1], [w_star + a * (1.0 - t_star)] * 2, rtol=1e-12)
    # before the event: the slip phase polynomials
    pre = res.t < t_star
    np.testing.assert_allclose(res.x[pre, 0], w10 + a1 * res.t[pre], rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(res.x[pre, 1], w20 + a2 * res.t[pre], rtol=1e-12, atol=1e-10)


def test_two_body_lockup_with_ratio() -> None:
    """Coupling with ratio r: slip+ gives w' = -k/J1 - r^2 k/J2 for w = w1 - r w2, so lock-up at
    t* = w0 / (k (1/J1 + r^2/J2)); with no external torque the speeds stay constant after."""
    j1, j2, k, r = 0.5, 2.0, 10.0, 3.0
    ch = Chain(
        (Body("b1", j1), Body("b2", j2)),
        (Coupling("clutch", ratio=r, friction=Friction(scale=k, name="clutch")),),
    )
    m = Model(ch)
    x0 = np.array([60.0, 5.0])
    res = simulate(m, x0, {}, t_end=2.0)
    w0 = x0[0] - r * x0[1]
    t_star = w0 / (k * (1.0 / j1 + r**2 / j2))
    assert_events(res, [(t_star, "slip+", "stuck")])
    w1 = x0[0] - k / j1 * t_star
    w2 = x0[1] + r * k / j2 * t_star
    assert w1 == pytest.approx(r * w2)
    np.testing.assert_allclose(res.x[-1], [w1, w2], rtol=1e-12)


def _static_case(static_ratio: float, torque: sg.Signal | float, t_end: float) -> SimulationResult:
    m = Model(two_body_clutch(0.2, 1.0, capacity=50.0, static_ratio=static_ratio))
    return simulate(m, [0.0, 100.0], {"torque1": torque}, t_end=t_end)


# J1 = 0.2, J2 = 1, k = 50, T1 = 72, body 1 from rest, body 2 at 100 rad/s: slip- with
# a1 = (T1 + k)/J1 = 610, a2 = -k/J2 = -50, so w1 - w2 = -100 + 660 t: lock-up at t* = 100/660.
# Stuck, the clutch must carry J2 T1/(J1 + J2) = 60 N m: above kinetic (50), below static (75).
T_LOCK = 100.0 / 660.0
W_LOCK = 610.0 * T_LOCK


def test_static_capacity_keeps_it_stuck_between_kinetic_and_static() -> None:
    res = _static_case(1.5, 72.0, 1.0)
    assert_events(res, [(T_LOCK, "slip-", "stuck")])
    assert res.mode_series("clutch")[-1] == "stuck"
    a = 72.0 / 1.2
    np.testing.assert_allclose(res.x[-1], [W_LOCK + a * (1.0 - T_LOCK)] * 2, rtol=1e-12)
    lam = res.coupling_torques()[-1, 0]
    assert lam == pytest.approx(60.0, rel=1e-12)
    assert 50.0 < lam < 75.0


def test_kinetic_equals_static_breaks_through_at_lockup() -> None:
    """Same case with static_ratio 1: 60 N m > 50 N m, so at w = 0 it goes straight to slip+."""
    res = _static_case(1.0, 72.0, 0.5)
    assert_events(res, [(T_LOCK, "slip-", "slip+")])
    a1, a2 = (72.0 - 50.0) / 0.2, 50.0 / 1.0
    t = 0.5 - T_LOCK
    np.testing.assert_allclose(res.x[-1], [W_LOCK + a1 * t, W_LOCK + a2 * t], rtol=1e-12)


def test_ramped_torque_breaks_away_at_static_capacity() -> None:
    """Torque 72 until t = 1 s, then ramps by 30 N m/s to 102 at t = 2 s: the stuck torque
    T1/1.2 reaches the static capacity 75 N m when T1 = 90, at t = 1.6 s; then slip+."""
    torque = sg.constant(72.0) + sg.ramp(1.0, 2.0, 0.0, 30.0)
    res = _static_case(1.5, torque, 2.0)
    assert_events(res, [(T_LOCK, "slip-", "stuck"), (1.6, "stuck", "slip+")])
    # speeds: stuck until 1.6 (a = T1/1.2), then a1 = (T1 - 50)/0.2, a2 = 50
    w_1 = W_LOCK + 60.0 * (1.0 - T_LOCK)
    w_b = w_1 + (0.6 * 72.0 + 0.5 * 30.0 * 0.6**2) / 1.2
    i = sample_at(res, res.events[1].t)
    np.testing.assert_allclose(res.x[i], [w_b, w_b], rtol=1e-11)
    # from 1.6 to 2.0 T1 goes 90 -> 102 (mean 96)
    w1_end = w_b + (96.0 - 50.0) * 0.4 / 0.2
    w2_end = w_b + 50.0 * 0.4
    np.testing.assert_allclose(res.x[-1], [w1_end, w2_end], rtol=1e-10)


def test_capacity_steps_to_zero_opens_and_closes() -> None:
    """Locked at 10 rad/s, T1 = 10; capacity 50 -> 0 at t = 1 (open), back to 50 at t = 2
    (slip+, since body 1 ran ahead at T1/J1 = 50 rad/s^2), lock-up at 2 + 50/250 = 2.2 s."""
    m = Model(two_body_clutch(0.2, 1.0, capacity="cap"))
    cap = sg.table([0.0, 1.0, 1.0, 2.0, 2.0], [50.0, 50.0, 0.0, 0.0, 50.0])
    res = simulate(m, [10.0, 10.0], {"torque1": 10.0, "cap": cap}, t_end=3.0)
    assert_events(res, [(1.0, "stuck", "open"), (2.0, "open", "slip+"), (2.2, "slip+", "stuck")])
    assert res.events[0].t == 1.0 and res.events[1].t == 2.0  # input breakpoints: exact
    # speeds: 10 + t/1.2*10 until 1; open: w1 += 50 s, w2 const; slip+: a1 = -200, a2 = 50
    w1_1 = 10.0 + 10.0 / 1.2
    i = sample_at(res, 2.0)
    np.testing.assert_allclose(res.x[i], [w1_1 + 50.0, w1_1], rtol=1e-12)
    w_lock = w1_1 + 50.0 * 0.2
    np.testing.assert_allclose(res.x[-1], [w_lock + 10.0 / 1.2 * 0.8] * 2, rtol=1e-12)
    assert res.mode_series("clutch")[sample_at(res, 1.5)] == "open"


def test_capacity_ramps_to_zero_opens_and_closes() -> None:
    """Capacity c(t): 50, ramp to 0 over [1, 1.5], 0 until 2, ramp back to 50 over [2, 2.5].

    J1 = 0.2, J2 = 1, T1 = 10; stuck torque J2 T1/(J1+J2) = 25/3 N m.
    * break-away when c = 25/3: t_b = 1 + (50 - 25/3)/100;
    * slip+ to 1.5: w' = T1/J1 - c (1/J1 + 1/J2) = 50 - 6 c(t);
    * open at t = 1.5 (capacity 0, an input breakpoint), w' = 50 until t = 2;
    * closes at t = 2 (slip+), w' = 50 - 600 (t - 2): lock-up at the root of
      w(2) + 50 s - 300 s^2 = 0.
    """
    m = Model(two_body_clutch(0.2, 1.0, capacity="cap"))
    cap = sg.table([0.0, 1.0, 1.5, 2.0, 2.5], [50.0, 50.0, 0.0, 0.0, 50.0])
    res = simulate(m, [10.0, 10.0], {"torque1": 10.0, "cap": cap}, t_end=3.0)
    lam = 10.0 / 1.2
    tb = 1.0 + (50.0 - lam) / 100.0
    # w over [tb, 1.5] with tau = t - 1: integral of -250 + 600 tau
    tau_b = tb - 1.0
    w15 = (-250.0 * 0.5 + 300.0 * 0.25) - (-250.0 * tau_b + 300.0 * tau_b**2)
    w2 = w15 + 50.0 * 0.5
    s = (50.0 + math.sqrt(50.0**2 + 4.0 * 300.0 * w2)) / 600.0
    assert_events(
        res,
        [
            (tb, "stuck", "slip+"),
            (1.5, "slip+", "open"),
            (2.0, "open", "slip+"),
            (2.0 + s, "slip+", "stuck"),
        ],
    )
    i = int(np.flatnonzero(res.t == 2.0)[-1])  # the breakpoint sample (still open)
    assert res.x[i, 0] - res.x[i, 1] == pytest.approx(w2, rel=1e-10)
    assert res.mode_series("clutch")[-1] == "stuck"


def _four_body(k: tuple[float, float, float]) -> Model:
    bodies = tuple(Body(f"b{i}", 1.0) for i in range(4))
    cps = tuple(Coupling(f"c{i}", friction=Friction(scale=k[i], name=f"c{i}")) for i in range(3))
    return Model(Chain(bodies, cps, name="four clutches"))


#: Four unit inertias, clutch capacities (4, 5, 3), speeds (16, 13, 4, 0), all slip+:
#: accelerations (-4, -1, 2, 3), relative speeds (3, 9, 4) falling at (3, 3, 1) rad/s^2.
#: c0 locks at t = 1 (speeds 12, 12, 6, 3). Bodies 0+1 (J = 2) then feel -5: a = -2.5 (c0 carries
#: 2.5 < 4), body 2: 2, body 3: 3; r12 = 6 falls at 4.5 -> c1 locks at 1 + 4/3; r23 = 3 falls at 1
#: -> 1.6667 at 7/3. Bodies 0..2 (J = 3) feel -3: a = -1 (c0 carries 1, c1 carries 2), body 3: 3;
#: r23 falls at 4 -> c2 locks at 7/3 + 5/12 = 2.75 with every speed at the mean 33/4 = 8.25.
FOUR_X0 = (16.0, 13.0, 4.0, 0.0)
FOUR_EVENTS = [(1.0, "slip+", "stuck"), (7.0 / 3.0, "slip+", "stuck"), (2.75, "slip+", "stuck")]


def test_four_body_chain_event_times() -> None:
    m = _four_body((4.0, 5.0, 3.0))
    res = simulate(m, FOUR_X0, {}, t_end=4.0)
    assert_events(res, FOUR_EVENTS)
    assert [e.element for e in res.events] == ["c0", "c1", "c2"]
    np.testing.assert_allclose(res.x[sample_at(res, res.events[0].t)], [12, 12, 6, 3], rtol=1e-12)
    t2 = res.events[1].t
    w01 = 12.0 - 2.5 * (7.0 / 3.0 - 1.0)
    w3 = 3.0 + 3.0 * (7.0 / 3.0 - 1.0)
    np.testing.assert_allclose(res.x[sample_at(res, t2)], [w01, w01, w01, w3], rtol=1e-12)
    np.testing.assert_allclose(res.x[-1], [8.25] * 4, rtol=1e-12)
    # stuck torques between the second and third lock-up: c0 1 N m, c1 2 N m; c2 slips at 3
    i = sample_at(res, t2)
    np.testing.assert_allclose(res.coupling_torques()[i], [1.0, 2.0, 3.0], rtol=1e-9)


def test_four_body_chain_with_ground_friction_comes_to_rest() -> None:
    """Four unit bodies locked together (strong clutches), spinning at 10 rad/s, ground friction
    8 N m on body 3 and an opposing torque input of 4 N m on body 0: a = -12/4 = -3 until rest at
    t = 10/3, then the friction holds (the 4 N m input is below its static capacity 8 N m)."""
    bodies = (
        Body("b0", 1.0, torque_input="T"),
        Body("b1", 1.0),
        Body("b2", 1.0),
        Body("b3", 1.0, ground_friction=Friction(scale=8.0, name="ground")),
    )
    cps = tuple(Coupling(f"c{i}", friction=Friction(scale=100.0, name=f"c{i}")) for i in range(3))
    m = Model(Chain(bodies, cps, inputs=("T",)))
    res = simulate(m, [10.0] * 4, {"T": -4.0}, t_end=5.0)
    assert_events(res, [(10.0 / 3.0, "slip+", "stuck")], "ground")
    assert [e.element for e in res.events] == ["ground"]
    np.testing.assert_allclose(res.x[-1], [0.0] * 4, atol=1e-12)
    pre = res.t < 10.0 / 3.0
    np.testing.assert_allclose(res.x[pre, 2], 10.0 - 3.0 * res.t[pre], rtol=1e-12, atol=1e-11)


def _dip_case(c: float, t_end: float, opts: SimulationOptions) -> SimulationResult:
    """One unit body with ground friction F = 5 N m (static = kinetic), torque input
    T = F + a cos(om t), a / om = 10 rad/s, om = 2 pi 50 rad/s, starting in slip+ at
    w0 = c a / om: in slip+ w(t) = w0 + (a / om) sin(om t), which touches down near
    om t = 3 pi / 2 and dips below zero by (1 - c) a / om for c < 1."""
    om = 2.0 * math.pi * 50.0
    a, F = 10.0 * om, 5.0
    body = Body("b", 1.0, torque_input="T", ground_friction=Friction(scale=F, name="ground"))
    m = Model(Chain((body,), (), inputs=("T",)))
    torque = sg.constant(F) + sg.sine(a, om, phase=math.pi / 2.0)
    return simulate(m, [c * a / om], {"T": torque}, t_end=t_end, options=opts)


def test_stick_episode_shorter_than_a_step_is_not_stepped_over() -> None:
    """c = 0.999999: the slip speed of :func:`_dip_case` reaches zero at om t1 = pi + asin(c),
    where the friction holds (T = F - a s, s = sqrt(1 - c^2), a s = 4.4 N m <= 2 F: T within the
    capacity, both slip directions inconsistent), and breaks away at om t2 = 3 pi / 2, where T
    rises through F: a stick episode of (pi / 2 - asin(c)) / om = 4.5 us inside one step of up to
    h_max = 1 ms, with the guards at both step ends positive. The slip speed's continuous
    extension shows the dip; the simulator retakes the step up to it."""
    c = 0.999999
    om = 2.0 * math.pi * 50.0
    t1 = (math.pi + math.asin(c)) / om
    t2 = 1.5 * math.pi / om
    res = _dip_case(c, 2.5 * math.pi / om, SimulationOptions())
    got = events_of(res, "ground")
    assert [(a, b) for _, a, b in got] == [("slip+", "stuck"), ("stuck", "slip+")], got
    # the touch-down is nearly tangent (slope a s): its time is as good as the slip speed (some
    # 1e-7 rad/s at rtol 1e-8) over that slope; the break-away is at T = F exactly
    slope = 10.0 * om * math.sqrt(1.0 - c * c)
    assert abs(got[0][0] - t1) <= 1e-6 / slope, (got[0][0], t1)
    assert abs(got[1][0] - t2) <= T_EV, (got[1][0], t2)
    assert float(np.min(res.x[:, 0])) >= -1e-9  # never negative slip in slip+
    assert res.stats["steps"] < 200  # found without shortening every step


def test_slip_reversal_shorter_than_a_step_is_not_stepped_over() -> None:
    """c = 0.9999: at t1 (as above) a s = 44 N m > 2 F, so the friction cannot hold: slip-, with
    w(t) = 2 F (t - t1) + (a / om)(sin(om t) - sin(om t1)) (unit inertia), until that is zero
    again at t3 (root found numerically), 70 us later: slip+ again."""
    from scipy.optimize import brentq

    c = 0.9999
    om = 2.0 * math.pi * 50.0
    a, F = 10.0 * om, 5.0
    t1 = (math.pi + math.asin(c)) / om

    def w_neg(t: float) -> float:
        return 2.0 * F * (t - t1) + (a / om) * (math.sin(om * t) - math.sin(om * t1))

    t3 = brentq(w_neg, t1 + 1e-9, 2.0 * math.pi / om, xtol=1e-15)
    res = _dip_case(c, 2.5 * math.pi / om, SimulationOptions())
    got = events_of(res, "ground")
    assert [(a, b) for _, a, b in got] == [("slip+", "slip-"), ("slip-", "slip+")], got
    s1 = a * math.sqrt(1.0 - c * c)  # |w'| at t1 in slip+ is a s - 0; in slip- it is a s - 2 F
    s3 = abs(2.0 * F + a * math.cos(om * t3))
    assert abs(got[0][0] - t1) <= 1e-6 / s1, (got[0][0], t1)
    assert abs(got[1][0] - t3) <= 1e-6 / s3, (got[1][0], t3)
    assert 60e-6 < t3 - t1 < 80e-6


def test_spring_knee_event_times() -> None:
    """Two unit bodies, spring torque 0 for |q| < 0.1 rad, slope 100 N m/rad to 0.2 rad, 300
    beyond; from w = omega1 - omega2 = 2 rad/s, q = 0 (w' = -2 T(q)):
    t1 = 0.05 s (free flight to the first knee); then q - 0.1 = (2 / W1) sin(W1 tau), W1 =
    sqrt(200), reaching 0.2 at W1 tau = pi / 4 (t2), with w = sqrt(2); beyond, p = q - 0.2 obeys
    p'' = -2 (10 + 300 p): p = (cos(W2 tau) - 1) / 30 + (sqrt(2) / W2) sin(W2 tau), W2 = sqrt(600),
    back to 0 at W2 tau = 2 atan(30 sqrt(2) / W2) = 2 pi / 3 (t3); then by symmetry back at 0.1
    after another pi / (4 W1) (t4)."""
    sp = Spring((0.0, 0.1, 0.2, 0.3), (0.0, 0.0, 10.0, 40.0), name="s")
    m = Model(Chain((Body("b1", 1.0), Body("b2", 1.0)), (Coupling("s", spring=sp),)))
    res = simulate(m, np.array([2.0, 0.0, 0.0]), {}, t_end=0.3)
    w1, w2 = math.sqrt(200.0), math.sqrt(600.0)
    t1 = 0.05
    t2 = t1 + math.pi / 4.0 / w1
    t3 = t2 + 2.0 * math.atan(30.0 * math.sqrt(2.0) / w2) / w2
    t4 = t3 + math.pi / 4.0 / w1
    got = events_of(res, "s.spring")
    # segments of the odd table counted from the most negative one (0: q < -0.2, 1, 2: |q| < 0.1)
    assert [(a, b) for _, a, b in got] == [
        ("segment 2", "segment 3"),
        ("segment 3", "segment 4"),
        ("segment 4", "segment 3"),
        ("segment 3", "segment 2"),
    ], got
    for (tg, *_), te in zip(got, (t1, t2, t3, t4), strict=True):
        assert abs(tg - te) <= T_EV, (tg, te, tg - te)
    assert res.stats["knee_crossings"] == 4


# ------------------------------------------------------------------------------------------------
# 4. an input step breaks a stuck element away exactly at the step
# ------------------------------------------------------------------------------------------------


def test_torque_step_breaks_clutch_away_at_the_step() -> None:
    """Stuck clutch (capacity 50, static 1.2 -> 60 N m); torque steps 10 -> 200 N m at t = 1:
    needed 200/1.2 = 166.7 N m > 60, so the clutch breaks away at t = 1 exactly."""
    m = Model(two_body_clutch(0.2, 1.0, capacity=50.0, static_ratio=1.2))
    res = simulate(m, [5.0, 5.0], {"torque1": sg.step(1.0, 190.0, initial=10.0)}, t_end=1.5)
    (ev,) = res.events
    assert (ev.element, ev.from_mode, ev.to_mode) == ("clutch", "stuck", "slip+")
    assert abs(ev.t - 1.0) <= 1e-12
    i = sample_at(res, 1.0)
    np.testing.assert_allclose(res.x[i], [5.0 + 10.0 / 1.2] * 2, rtol=1e-13)
    # slip with kinetic capacity 50: a1 = (200 - 50)/0.2 = 750, a2 = 50
    np.testing.assert_allclose(
        res.x[-1], [res.x[i, 0] + 750.0 * 0.5, res.x[i, 1] + 50.0 * 0.5], rtol=1e-12
    )


def test_torque_step_breaks_ground_friction_away_at_the_step() -> None:
    """Block at rest on a ground friction (kinetic 5, static 7.5); torque 3 -> 8 at t = 1."""
    ch = Chain(
        (
            Body(
                "block",
                2.0,
                torque_input="T",
                ground_friction=Friction(scale=5.0, static_ratio=1.5, name="ground"),
            ),
        ),
        (),
        inputs=("T",),
    )
    m = Model(ch)
    res = simulate(m, [0.0], {"T": sg.step(1.0, 5.0, initial=3.0)}, t_end=2.0)
    (ev,) = res.events
    assert (ev.element, ev.from_mode, ev.to_mode) == ("ground", "stuck", "slip+")
    assert abs(ev.t - 1.0) <= 1e-12
    assert np.all(res.x[res.t < 1.0, 0] == 0.0)
    assert res.x[-1, 0] == pytest.approx((8.0 - 5.0) / 2.0 * 1.0, rel=1e-12)


# ------------------------------------------------------------------------------------------------
# backlash: free flight across the gap, half a period of contact (an elastic collision)
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("opts", "tol"),
    [(SimulationOptions(), 1e-9), (SimulationOptions(rtol=1e-12, atol=1e-13), 1e-12)],
)
def test_backlash_gap_and_contact_times(opts: SimulationOptions, tol: float) -> None:
    """Two bodies joined by a spring k with half gap g; body 1 at v, body 2 at rest, twist 0.

    Gap: no torque, the twist grows at v: contact+ at t1 = g/v. Contact: the relative motion is
    harmonic with omega = sqrt(k/mu), mu = J1 J2/(J1 + J2): back to the gap after pi/omega at
    relative speed -v (speeds of an elastic collision); across the gap 2g/v to contact-; again
    pi/omega to the gap with the initial speeds restored."""
    j1, j2, k, g, v = 0.5, 1.5, 2000.0, 0.1, 4.0
    sp = Spring.linear(k, backlash=g, name="bl")
    m = Model(Chain((Body("b1", j1), Body("b2", j2)), (Coupling("bl", spring=sp),)))
    assert m.state_names == ("omega_b1", "omega_b2", "q_bl")
    half = math.pi / math.sqrt(k * (j1 + j2) / (j1 * j2))
    t1 = g / v
    t2 = t1 + half
    t3 = t2 + 2.0 * g / v
    t4 = t3 + half
    res = simulate(m, [v, 0.0, 0.0], {}, t_end=t4 + 0.01, options=opts)
    expected = [
        (t1, "gap", "contact+"),
        (t2, "contact+", "gap"),
        (t3, "gap", "contact-"),
        (t4, "contact-", "gap"),
    ]
    got = events_of(res, "bl")
    assert [(a, b) for _, a, b in got] == [(a, b) for _, a, b in expected]
    np.testing.assert_allclose([e[0] for e in got], [e[0] for e in expected], rtol=0, atol=tol)
    # elastic collision: w1 = (J1 - J2)/(J1 + J2) v, w2 = 2 J1/(J1 + J2) v
    i = sample_at(res, got[1][0])
    w_after = [(j1 - j2) / (j1 + j2) * v, 2.0 * j1 / (j1 + j2) * v]
    np.testing.assert_allclose(res.x[i, :2], w_after, rtol=0, atol=1e3 * tol)
    assert res.x[i, 2] == pytest.approx(g, abs=1e3 * tol)
    np.testing.assert_allclose(res.x[-1], [v, 0.0, -g + v * 0.01], rtol=0, atol=1e4 * tol)
    assert res.energy_residual_rel <= (1e-8 if tol > 1e-10 else 1e-11)


@pytest.mark.parametrize("falling", [False, True])
def test_break_away_with_a_mu_table(falling: bool) -> None:
    """Two bodies at rest, 20 N m on the first, a clutch of 5 N m with a mu(slip) table that
    starts at zero slip: it slips at once and the run ends (it used to stall at t = 0, entering
    and leaving a table region below zero slip at every step). A flat table equals no table; a
    falling one (mu 1 -> 0.5 over 1 rad/s) matches scipy on the slip ODE."""
    from scipy.integrate import solve_ivp

    from drivetrain_ctrl.core.tables import PwlTable
    from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction
    from drivetrain_ctrl.plant.model import Model

    mu = PwlTable((0.0, 1.0), (1.0, 0.5 if falling else 1.0))
    ch = Chain(
        (Body("a", 1.0, torque_input="t"), Body("b", 2.0)),
        (Coupling("s", friction=Friction(scale=5.0, mu_table=mu, name="f")),),
        inputs=("t",),
    )
    res = simulate(Model(ch), np.zeros(2), {"t": 20.0}, t_end=0.5)
    assert res.status == "ok" and res.stats["steps"] < 2000

    def rhs(_t: float, w: np.ndarray) -> list[float]:
        T = 5.0 * float(np.interp(w[0] - w[1], mu.x, mu.y))
        return [20.0 - T, T / 2.0]

    ref = solve_ivp(rhs, (0.0, 0.5), [0.0, 0.0], rtol=1e-11, atol=1e-11, method="DOP853")
    assert np.allclose(res.x[-1], ref.y[:, -1], atol=1e-6)
    if not falling:
        assert np.allclose(res.x[-1], [7.5, 1.25], atol=1e-9)
