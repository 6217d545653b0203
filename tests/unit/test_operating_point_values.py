"""Value tests of drivetrain_ctrl.linear.operating_point: the state, inputs and mode of an
instant of a trajectory (linear interpolation written out here), the certificate's figures
(the drift against the model's rhs, the slip speed and acceleration against the body speeds,
the time to lock, the stuck margins) and the locked trim (every independent speed at rest,
the throttle equal to the settled engine lag, the vehicle speed from km/h by hand)."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl import linear as L
from drivetrain_ctrl.core.tables import PwlTable
from drivetrain_ctrl.linear.operating_point import _certificate, _kind_of, _mu_ratio
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction
from drivetrain_ctrl.plant.drivetrain import Drivetrain
from drivetrain_ctrl.plant.model import Mode, Model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.sim.simulator import simulate

P = default_params()
XC = 0.0725  # inside a pedal-map piece


@pytest.fixture(scope="module")
def ramp():
    dt = Drivetrain(P, kind="reduced")
    return dt, run_scenario(load_scenario("engage-ramp"), dt, t_end=1.2)


def test_kind_without_a_drivetrain_comes_from_the_chain_name(ramp) -> None:
    dt, res = ramp
    op = L.operating_point_from_result(res, 1.0)
    assert op.kind == "reduced" and op.drivetrain is None
    assert _kind_of(dt.model, None) == "reduced"
    full = Drivetrain(P, kind="full")
    assert _kind_of(full.model, None) == "full"
    assert _kind_of(full.model, full) == "full"


def test_instant_between_samples_is_interpolated(ramp) -> None:
    dt, res = ramp
    T = np.asarray(res.t)
    # a sample interval of positive length inside the run
    k = next(i for i in range(T.size // 2, T.size - 1) if T[i + 1] > T[i])
    for a in (0.25, 0.7):
        t = float(T[k] + a * (T[k + 1] - T[k]))
        op = L.operating_point_from_result(res, t, drivetrain=dt)
        a_exact = (t - T[k]) / (T[k + 1] - T[k])
        x = (1.0 - a_exact) * np.asarray(res.x[k]) + a_exact * np.asarray(res.x[k + 1])
        u = (1.0 - a_exact) * np.asarray(res.u[k]) + a_exact * np.asarray(res.u[k + 1])
        np.testing.assert_allclose(op.x, x, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(op.u, u, rtol=1e-13, atol=1e-13)
        assert op.mode.fm == tuple(int(v) for v in res.fm[k])
        assert op.mode.reg == tuple(int(v) for v in res.reg[k])
        assert op.t == t
    # exactly at a sample: that sample's state; at the last sample: the last state
    op = L.operating_point_from_result(res, float(T[k]), drivetrain=dt)
    last = int(np.searchsorted(T, T[k], side="right") - 1)
    np.testing.assert_array_equal(op.x, np.asarray(res.x[last]))
    op = L.operating_point_from_result(res, float(T[-1]), drivetrain=dt)
    np.testing.assert_array_equal(op.x, np.asarray(res.x[-1]))
    np.testing.assert_array_equal(op.u, np.asarray(res.u[-1]))
    op = L.operating_point_from_result(res, float(T[0]), drivetrain=dt)
    np.testing.assert_array_equal(op.x, np.asarray(res.x[0]))


def test_at_an_event_the_mode_after_it_is_taken(ramp) -> None:
    # an event is recorded as two samples at one time: a copy of the ramp with one such pair
    # (the second sample in another friction mode) built here
    dt, res = ramp
    k = 600
    idx = np.r_[np.arange(k + 1), k, np.arange(k + 1, len(res.t))]
    fm = np.asarray(res.fm)[idx].copy()
    fm[k + 1 :, dt.model.friction_index("clutch")] = K.STUCK
    ev = SimpleNamespace(
        t=np.asarray(res.t)[idx],
        x=np.asarray(res.x)[idx],
        u=np.asarray(res.u)[idx],
        fm=fm,
        reg=np.asarray(res.reg)[idx],
        model=res.model,
    )
    op = L.operating_point_from_result(ev, float(res.t[k]), drivetrain=dt)
    assert op.mode.fm == tuple(int(v) for v in fm[k + 1])
    assert op.clutch_mode == "stuck"
    np.testing.assert_array_equal(op.x, np.asarray(res.x[k]))
    # just before the event: the mode before it
    t = float(0.5 * (res.t[k - 1] + res.t[k]))
    assert L.operating_point_from_result(ev, t, drivetrain=dt).clutch_mode == "slip+"


def test_certificate_figures_against_the_model(ramp) -> None:
    dt, res = ramp
    op = L.operating_point_from_result(res, 1.0, drivetrain=dt)
    m = dt.model
    c = op.certificate
    xdot = m.rhs(np.array(op.x), np.array(op.u), op.mode)
    assert c.kind == "trajectory"
    assert dict(c.drift) == pytest.approx(dict(zip(m.state_names, xdot.tolist(), strict=True)))
    assert c.drift_norm == pytest.approx(float(np.max(np.abs(xdot[: m.n_bodies]))), rel=1e-15)
    g = m.guards(np.array(op.x), np.array(op.u), op.mode)
    assert c.min_guard == pytest.approx(float(np.min(g)), rel=1e-15)
    assert c.valid is True and c.min_guard >= 0.0
    assert not any("guards violated" in n for n in c.notes)
    # reduced model: clutch slip = omega_engine - omega_primary (the clutch has no ratio)
    ie, ip = m.state_index("omega_engine"), m.state_index("omega_primary")
    assert c.slip_speed == pytest.approx(op.x[ie] - op.x[ip], rel=1e-14)
    assert c.slip_accel == pytest.approx(xdot[ie] - xdot[ip], rel=1e-12)
    # at 1.0 s the slip still grows: no time to lock, and a note says so
    assert c.slip_speed is not None and c.slip_accel is not None
    assert c.slip_speed > 0 and c.slip_accel > 0
    assert c.time_to_lock_s is None
    assert c.notes == ("clutch slip is not closing (time to lock: None)",)


def test_a_violated_guard_is_reported(ramp) -> None:
    dt, res = ramp
    op = L.operating_point_from_result(res, 1.0, drivetrain=dt)
    m = dt.model
    # the same state held in the stuck mode while it slips at 90 rad/s: a violated guard
    fc = m.friction_index("clutch")
    fm = list(op.mode.fm)
    fm[fc] = K.STUCK
    bad = Mode(tuple(fm), op.mode.reg)
    c = _certificate(m, np.array(op.x), np.array(op.u), bad, "trajectory")
    g = m.guards(np.array(op.x), np.array(op.u), bad)
    assert c.min_guard == pytest.approx(float(np.min(g)))
    assert c.min_guard < 0 and not c.valid
    names = [nm for nm, v in zip(m.guard_names(), g, strict=True) if v < 0]
    assert names
    assert any(n.startswith("guards violated") and all(x in n for x in names) for n in c.notes)


def test_slip_point_time_to_lock_and_drift_by_hand() -> None:
    dt = Drivetrain(P, kind="full")
    op = L.slip_operating_point(dt, omega_engine=170.0, omega_driven=80.0, x_c=XC, throttle=0.5)
    m = dt.model
    c = op.certificate
    xdot = m.rhs(np.array(op.x), np.array(op.u), op.mode)
    ie, idisc = m.state_index("omega_engine"), m.state_index("omega_disc")
    assert op.x[ie] == 170.0 and op.x[idisc] == pytest.approx(80.0, rel=1e-14)
    # vehicle speed: the driven speed through the total ratio and the wheel radius
    assert op.state("v_vehicle") == pytest.approx(80.0 * P.driveline.R_p / dt.tau_t, rel=1e-14)
    assert c.slip_speed == pytest.approx(90.0, rel=1e-14)
    assert c.slip_accel == pytest.approx(xdot[ie] - xdot[idisc], rel=1e-12)
    assert c.slip_accel is not None and c.slip_accel < 0
    assert c.time_to_lock_s == pytest.approx(90.0 / -c.slip_accel, rel=1e-12)
    assert op.input("throttle") == 0.5 and op.input("pedal") == XC
    assert op.state("lag_engine") == pytest.approx(0.5)
    # the quasi-static twist: the driven shaft and the vehicle accelerate together
    iv = m.state_index("v_vehicle")
    assert xdot[idisc] == pytest.approx(dt.tau_t / P.driveline.R_p * xdot[iv], rel=1e-7, abs=1e-7)
    assert c.drift_norm == pytest.approx(float(np.max(np.abs(xdot[: m.n_bodies]))), rel=1e-15)
    assert op.clutch_mode == "slip+" and c.valid
    # the stuck elements (the damper's friction, the tyre): capacity - |torque|, the torque the
    # model's stuck torques
    st = m.stuck_torques(np.array(op.x), np.array(op.u), op.mode)
    assert {s.element for s in c.stuck_margins} == {"damper_friction", "tyre"}
    for s in c.stuck_margins:
        assert s.torque == st[s.element]
        assert s.margin == pytest.approx(s.capacity - abs(s.torque), rel=1e-14)
        assert s.margin > 0
    # rebuilt from its recipe: the same point
    op2 = L.rebuild_operating_point(op, P)
    assert op2.certificate.kind == "slip"
    np.testing.assert_allclose(op2.x, op.x, rtol=1e-13, atol=1e-13)


def test_slip_point_with_the_engine_slower_slips_negative() -> None:
    dt = Drivetrain(P, kind="reduced")
    op = L.slip_operating_point(dt, omega_engine=60.0, omega_driven=100.0, x_c=XC, throttle=0.2)
    assert op.clutch_mode == "slip-"
    assert op.certificate.slip_speed == pytest.approx(-40.0, rel=1e-14)


@pytest.mark.parametrize("slope", [0.0, 0.02])
@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_locked_trim_by_hand(kind: str, slope: float) -> None:
    dt = Drivetrain(P, kind=kind)
    op = L.locked_trim(dt, vehicle_speed_kmh=45.0, slope=slope)
    m = op.model
    c = op.certificate
    v = 45.0 / 3.6
    assert op.state("v_vehicle") == pytest.approx(v, rel=1e-12)
    assert op.state("omega_engine") == pytest.approx(v * dt.tau_t / P.driveline.R_p, rel=1e-12)
    theta = op.input("throttle")
    assert 0.0 < theta < 1.0 and op.state("lag_engine") == pytest.approx(theta, rel=1e-12)
    # every speed at rest (the drift is round-off) in the locked mode
    xdot = m.rhs(np.array(op.x), np.array(op.u), op.mode)
    assert np.max(np.abs(xdot[: m.n_bodies])) < 1e-8
    assert op.clutch_mode == "stuck" and c.kind == "equilibrium" and c.valid
    e = P.engine
    w1 = op.state("omega_engine")
    C1 = e.K * theta - e.b1 * w1 - e.c1
    margins = {s.element: s for s in c.stuck_margins}
    assert margins["clutch"].torque == pytest.approx(C1, rel=1e-8)
    assert margins["clutch"].capacity == pytest.approx(P.clutch.k12_max, rel=1e-14)
    for s in c.stuck_margins:
        assert s.margin == pytest.approx(s.capacity - abs(s.torque), rel=1e-14, abs=1e-12)
    # the residual converges to round-off, far below the threshold 1e-8 max(1, |speeds|)
    (note,) = [n for n in c.notes if n.startswith("trim residual")]
    assert float(note.split()[-1]) < 1e-9 < 1e-8 * op.state("omega_engine") / 1000.0
    # the recipe rebuilds the same point
    op2 = L.rebuild_operating_point(op, P)
    np.testing.assert_allclose(op2.x, op.x, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_mu_ratio_of_a_falling_table_by_hand(kind: str) -> None:
    # mu(|w|)/mu(0) falls linearly from 1 at 0 to 0.8 at 200 rad/s: 0.91 at 90 rad/s, slope
    # -0.2/200 s/rad; a flat table (the default) gives (1, 0)
    pmu = P.replace(**{"clutch.mu_table": {"x": [0.0, 200.0], "y": [1.0, 0.8]}})
    for params, want in ((pmu, (0.91, -0.001)), (P, (1.0, 0.0))):
        dt = Drivetrain(params, kind=kind)
        op = L.slip_operating_point(dt, omega_engine=170.0, omega_driven=80.0, x_c=XC, throttle=0.5)
        fc = op.model.friction_index("clutch")
        mu, dmu = _mu_ratio(op.model, fc, np.array(op.x), op.mode)
        assert mu == pytest.approx(want[0], rel=1e-12)
        assert dmu == pytest.approx(want[1], rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_locked_trim_slope_load_by_hand(kind: str) -> None:
    # at one speed the losses are the same: the engine's extra output torque on a slope is the
    # slope's extra road force M g (sin s - sin 0) plus the rolling term's change, referred to
    # the primary shaft (R_p / tau_t)
    dt = Drivetrain(P, kind=kind)
    e, vp = P.engine, P.vehicle
    C1 = {}
    for slope in (0.0, 0.05):
        op = L.locked_trim(dt, vehicle_speed_kmh=45.0, slope=slope)
        C1[slope] = e.K * op.state("lag_engine") - e.b1 * op.state("omega_engine") - e.c1
    dF = vp.k_v(0.05) - vp.k_v(0.0) + vp.M_v * 9.81 * math.sin(0.05)
    assert C1[0.05] - C1[0.0] == pytest.approx(dF * P.driveline.R_p / dt.tau_t, rel=1e-8)


def _two_body_chain(friction_name: str) -> Model:
    # body a (1 kg m^2) driven by torque T, body b (2 kg m^2), one friction between them of
    # capacity `cap` times mu(|w|)/mu(0) = 1 - 0.5 |w| / 20 (the model's only table: index 0)
    bodies = (Body("a", 1.0, torque_input="T"), Body("b", 2.0))
    mu = PwlTable((0.0, 20.0), (1.0, 0.5))
    fr = Friction(capacity_input="cap", name=friction_name, mu_table=mu)
    return Model(Chain(bodies, (Coupling("c", friction=fr),), inputs=("T", "cap")))


@pytest.mark.parametrize("name", ["f", "clutch"])
def test_a_chain_of_two_bodies_by_hand(name: str) -> None:
    m = _two_body_chain(name)
    res = simulate(m, np.array([10.0, 0.0]), {"T": 0.0, "cap": 5.0}, t_end=0.1)
    op = L.operating_point_from_result(res, 0.05)
    assert op.kind == "chain" and op.mode_dict()[name] == "slip+"
    w = float(op.x[0] - op.x[1])
    mu = 1.0 - 0.5 * w / 20.0
    assert _mu_ratio(m, 0, np.array(op.x), op.mode) == pytest.approx((mu, -0.025), rel=1e-12)
    c = op.certificate
    # a' = -cap mu / 1, b' = +cap mu / 2
    assert dict(c.drift) == pytest.approx({"omega_a": -5.0 * mu, "omega_b": 2.5 * mu}, rel=1e-12)
    assert c.drift_norm == pytest.approx(5.0 * mu, rel=1e-12)
    assert c.valid and c.min_guard == pytest.approx(5.0)
    if name == "clutch":  # the slip figures are the clutch's
        assert c.slip_speed == pytest.approx(w, rel=1e-14)
        assert c.slip_accel == pytest.approx(-7.5 * mu, rel=1e-12)
        assert c.time_to_lock_s == pytest.approx(w / (7.5 * mu), rel=1e-12)
    else:  # no clutch: no slip figures
        assert c.slip_speed is None and c.slip_accel is None and c.time_to_lock_s is None
        assert c.notes == ()


def test_the_model_is_neither_shown_nor_compared(ramp) -> None:
    dt, res = ramp
    op = L.operating_point_from_result(res, 1.0, drivetrain=dt)
    assert "model=" not in repr(op) and "drivetrain=" not in repr(op)
    other = Drivetrain(P, kind="reduced")
    assert other.model is not op.model
    assert dataclasses.replace(op, model=other.model, drivetrain=other) == op


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_quasi_static_twist_of_a_strong_clutch(kind: str) -> None:
    # a clutch of 5000 N m fully engaged: the quasi-static twist torque is far above 1000 N m,
    # and still the driven shaft and the vehicle accelerate together
    params = P.replace(**{"clutch.k12_max": 5000.0})
    dt = Drivetrain(params, kind=kind)
    op = L.slip_operating_point(dt, omega_engine=170.0, omega_driven=80.0, x_c=0.03, throttle=0.5)
    m = op.model
    xdot = m.rhs(np.array(op.x), np.array(op.u), op.mode)
    driven = "omega_primary" if kind == "reduced" else "omega_disc"
    a_driven = xdot[m.state_index(driven)]
    a_vehicle = xdot[m.state_index("v_vehicle")]
    assert a_driven == pytest.approx(dt.tau_t / params.driveline.R_p * a_vehicle, rel=1e-9)
    assert abs(a_driven) > 100.0


def test_locked_trim_near_the_clutch_capacity() -> None:
    # 20 km/h on the flat: the trim throttle (about 0.2) does not depend on the pedal while the
    # clutch holds; at x_c = 0.088 m (about 23 N m of capacity) it still holds, though at a
    # throttle of 0.6 it would slip
    dt = Drivetrain(P, kind="reduced")
    engaged = L.locked_trim(dt, vehicle_speed_kmh=20.0, x_c=0.03)
    near = L.locked_trim(dt, vehicle_speed_kmh=20.0, x_c=0.088)
    assert near.input("throttle") == pytest.approx(engaged.input("throttle"), rel=1e-10)
    assert 0.15 < near.input("throttle") < 0.3
    assert near.clutch_mode == "stuck"
    cl = {s.element: s for s in near.certificate.stuck_margins}["clutch"]
    # the capacity by hand: the pedal map between its knots 0.085 and 0.09 m
    pm = P.clutch.pedal_map
    k = pm.x.index(0.085)
    shape = pm.y[k] + (pm.y[k + 1] - pm.y[k]) * (0.088 - 0.085) / (0.09 - 0.085)
    assert cl.capacity == pytest.approx(P.clutch.k12_max * shape, rel=1e-12)
    assert 0.0 < cl.margin < cl.capacity


def test_locked_trim_rejects_a_spinning_tyre() -> None:
    # a slippery road (mu_tyre = 0.02) on a 0.2 rad slope: at the trim's throttle the tyre
    # spins: no locked steady state (it was returned as a valid "equilibrium" with the tyre
    # slipping and the speeds accelerating)
    params = P.replace(**{"vehicle.mu_tyre": 0.02})
    with pytest.raises(
        ValueError,
        match=r"no locked steady state there .*modes changed: .*'tyre': 'grip -> slip\+'",
    ):
        L.locked_trim(Drivetrain(params, kind="full"), vehicle_speed_kmh=20.0, slope=0.2)
    # the same road with the default grip (mu_tyre = 0.8) holds
    op = L.locked_trim(Drivetrain(P, kind="full"), vehicle_speed_kmh=20.0, slope=0.2)
    assert op.mode_dict()["tyre"] == "grip" and op.certificate.drift_norm < 1e-8


def test_locked_trim_rejects_a_tyre_slipping_from_the_start() -> None:
    # an icy road (mu_tyre = 0.001) on a 0.3 rad slope: the tyre slips already at the initial
    # guess (throttle 0.3, the springs at the road load), before any solve
    params = P.replace(**{"vehicle.mu_tyre": 0.001})
    with pytest.raises(ValueError, match=r"the initial decision gives .*'tyre': 'slip\+'"):
        L.locked_trim(Drivetrain(params, kind="full"), vehicle_speed_kmh=20.0, slope=0.3)
