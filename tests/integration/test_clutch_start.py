"""Clutch start control (issue 4): law (6), PI with anti-windup, latch, paper-start, metrics."""

from __future__ import annotations

import dataclasses
import math
import warnings

import control
import numpy as np
import pytest

from drivetrain_ctrl.control.blocks import Controller, LatchRamp
from drivetrain_ctrl.control.laws import (
    ControllerError,
    ControllerSpec,
    UnstableLoopWarning,
    builtin_controllers,
    law6_defaults,
    load_controller,
    slip_loop,
)
from drivetrain_ctrl.core.signals import ramp, sine
from drivetrain_ctrl.core.units import kmh_to_m_s, rpm_to_rad_s
from drivetrain_ctrl.plant.chain import two_body_clutch
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.scenarios.scenario import ScenarioError, idle_throttle, load_scenario
from drivetrain_ctrl.sim.metrics import engagement_metrics
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.sim.simulator import simulate

P = default_params()
K_R, X_R0 = law6_defaults()  # law (6)'s gains: the built-in paper controller's
SC = load_scenario("paper-start", params=P)


def _run(kind: str, ctl: object, sc=SC, **kw):  # type: ignore[no-untyped-def]
    dt = sc.drivetrain(P, kind=kind)
    res = run_scenario(sc, dt, controller=ctl, **kw)
    return res, engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)


# -- the scenario -----------------------------------------------------------------------------


def test_paper_start_numbers() -> None:
    th0 = idle_throttle(P, float(rpm_to_rad_s(900.0)))
    e = P.engine
    assert th0 == pytest.approx((e.b1 * rpm_to_rad_s(900.0) + e.c1) / e.K)
    thr = dict(SC.inputs)["throttle"]
    assert float(thr(0.49)) == pytest.approx(th0)
    assert float(thr(0.5)) == pytest.approx(0.9)
    assert float(thr(1.55)) == pytest.approx(0.75)
    assert float(thr(1.6)) == pytest.approx(0.6)
    assert float(SC.reference(0.49)) == pytest.approx(rpm_to_rad_s(900.0))
    assert float(SC.reference(0.5)) == pytest.approx(rpm_to_rad_s(1600.0))
    assert SC.t_end == 4.0 and SC.gear == 1 and SC.slope == 0.0 and SC.control_start == 0.5


def test_engine_idles_with_the_clutch_open_until_the_start() -> None:
    res, _ = _run("reduced", "paper")
    before = res.t < 0.5
    w = res.state("omega_engine")[before]
    assert np.allclose(w, rpm_to_rad_s(900.0), atol=1e-6)
    assert np.all(res.u[before, 1] == pytest.approx(0.11))  # pedal held open
    assert all(m == "open" for m, b in zip(res.mode_series("clutch"), before, strict=True) if b)


def test_a_scenario_that_needs_a_controller_says_so() -> None:
    dt = SC.drivetrain(P, kind="reduced")
    with pytest.raises(ScenarioError, match="needs a controller"):
        run_scenario(SC, dt)
    with pytest.raises(ScenarioError, match="open loop"):
        open_sc = load_scenario("engage-ramp")
        open_sc.make_controller(open_sc.drivetrain(P), "paper")


# -- law (6) by hand --------------------------------------------------------------------------


@pytest.mark.parametrize("v0_kmh", [0.0, 25.0])
def test_law6_command_matches_the_hand_formula_on_both_sign_branches(v0_kmh: float) -> None:
    """x_r = x_r0 + k_r (w_r - w_1) sgn(w_1 - w_3) at the samples between start and lock-up where
    the formula lies inside the actuator stroke; at 25 km/h the primary shaft turns faster than the
    engine (sgn = -1)."""
    sc = dataclasses.replace(SC, v_vehicle0=float(kmh_to_m_s(v0_kmh)))
    res, m = _run("reduced", "paper", sc=sc, t_end=1.5)
    w1, w3 = res.state("omega_engine"), res.state("omega_primary")
    xr = X_R0 + K_R * (sc.reference(res.t) - w1) * np.sign(w1 - w3)
    cmd = res.extras["controller_command"]
    lock = res.stuck_phases("clutch")
    t_stop = lock[0][0] if lock else 1.5
    sel = (res.t > 0.5) & (res.t < t_stop) & (xr > P.actuator.x_min) & (xr < P.actuator.x_max)
    sel &= np.abs(w1 - w3) > 1e-3
    assert sel.sum() > 50
    assert np.max(np.abs(cmd[sel] - xr[sel])) < 1e-12
    signs = np.sign(w1 - w3)[sel]
    if v0_kmh == 0.0:
        assert np.all(signs == 1.0)
    else:  # the engine first turns slower than the primary shaft, then overtakes it
        assert np.sum(signs == -1.0) > 20 and np.sum(signs == 1.0) > 5


# -- the targets of the paper start ----------------------------------------------------------


@pytest.mark.parametrize("ctl,max_rms", [("paper", 400.0), ("pi", 120.0)])
def test_paper_start_figures_on_both_models(ctl: str, max_rms: float) -> None:
    locks = []
    for kind in ("reduced", "full"):
        res, m = _run(kind, ctl)
        assert m["lockup_time_s"] == pytest.approx(2.5, abs=0.3), (kind, m["lockup_time_s"])
        assert m["engine_speed_min_rpm"] >= 800.0
        assert min(res.state("omega_engine")[res.t >= 0.5]) >= rpm_to_rad_s(800.0)
        assert m["tracking_rms_rpm"] <= max_rms
        assert m["energy_residual_rel"] <= 1e-6
        assert m["engagement_time_s"] == pytest.approx(m["lockup_time_s"] - 0.5)
        assert m["n_lock_events"] >= 1 and m["notes"] == []
        locks.append(m["lockup_time_s"])
    assert abs(locks[0] - locks[1]) <= 0.15


def test_closed_loop_energy_balance_for_every_builtin_controller() -> None:
    """Energy balanced, and every mode decision consistent: the 10-ms law (6) meets a break-away
    tie (vehicle rolling resistance, static = kinetic capacity, near 0.5438 s: stuck beyond its
    capacity by round-off, slipping with zero acceleration) that counts as consistent, not as a
    failed decision."""
    for name in builtin_controllers():
        res, m = _run("full", name)
        assert m["energy_residual_rel"] <= 1e-6, name
        assert res.stats["inconsistent_decisions"] == 0, name


def test_no_lockup_within_the_horizon_is_null_and_said() -> None:
    res, m = _run("reduced", "paper", t_end=1.0)
    assert m["lockup_time_s"] is None and m["engagement_time_s"] is None
    assert any("did not lock" in n for n in m["notes"])


# -- PI anti-windup, latch ------------------------------------------------------------------


def test_pi_integrator_does_not_wind_up_while_the_actuator_saturates() -> None:
    """At the start the PI asks for more than the stroke (x_r0 + kp * 73 rad/s > x_max): with
    back-calculation the value before the saturation stays near the limit; without it the
    integrator keeps integrating the large error."""
    spec = ControllerSpec(name="pi-big", law="pi", kp=1e-3, ki=0.05)
    nowind = dataclasses.replace(spec, anti_windup=False)
    out = {}
    for s in (spec, nowind):
        res, _ = _run("reduced", s, t_end=0.8)
        out[s.anti_windup] = (res, res.extras["controller_states"][:, 0])
    res, xi = out[True]
    res_free, xi_free = out[False]
    e = SC.reference(res_free.t) - res_free.state("omega_engine")
    sat = res_free.extras["controller_command"] >= P.actuator.x_max - 1e-15
    assert sat[-1] and np.sum(sat & (res_free.t > 0.5)) > 10
    # without anti-windup the integrator integrates the whole error (winds up) ...
    int_e = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * np.diff(res_free.t))])
    k = res_free.t >= 0.5
    assert xi_free[-1] == pytest.approx(int_e[-1] - int_e[k][0], rel=1e-3)
    # ... with back-calculation it is pulled back while saturated: far less than that, and the
    # unsaturated value comes back to the limit within T_t = kp/ki = 0.02 s after saturation ends
    assert xi[-1] < 0.2 * xi_free[-1]
    # recovery: once the cause of the saturation ends (the error changes sign) the output leaves
    # the limit within T_t; without anti-windup it stays saturated for the rest of the run
    T_t = spec.anti_windup_time_s()
    assert T_t == pytest.approx(0.02)

    def error_sign_change(r) -> float:  # type: ignore[no-untyped-def]
        err = SC.reference(r.t) - r.state("omega_engine")
        after = r.t > 0.5
        return float(r.t[after][np.flatnonzero(err[after] <= 0.0)[0]])

    t_e0 = error_sign_change(res)
    sat_aw = res.extras["controller_command"] >= P.actuator.x_max - 1e-15
    assert sat_aw[np.searchsorted(res.t, 0.5, side="right")]  # saturated at the start
    t_leave = float(res.t[(res.t > 0.5) & ~sat_aw][0])
    assert abs(t_leave - t_e0) <= T_t, (t_leave, t_e0)
    assert not np.any(sat_aw[res.t >= t_leave])  # and does not saturate again
    t_e0_free = error_sign_change(res_free)
    assert res_free.t[-1] - t_e0_free > 4.0 * T_t
    assert np.all(sat[res_free.t >= t_e0_free])


def _relsip_controller() -> Controller:
    """Law (6) whose latch drives the pedal back open: the clutch locks, then re-slips."""
    c = load_controller("paper").build(
        P, reference=SC.reference, start_time=0.5, driven_state="omega_primary"
    )
    return dataclasses.replace(c, latch=LatchRamp("clutch", "stuck", 0.05, 0.11))


def test_latch_is_bumpless_and_rearms_on_reslip() -> None:
    ctl = _relsip_controller()
    res, m = _run("reduced", ctl)
    phases = res.stuck_phases("clutch")
    assert len(phases) >= 2
    # the lock events of the engagement window [start, lock-up + 1 s] (to the end of the run
    # without lock-up: here each stuck phase is shorter than the 0.2 s of a lock-up)
    lock = m["lockup_time_s"]
    t_w = m["t_end_s"] if lock is None else lock + 1.0
    assert m["n_lock_events"] == sum(1 for t0, _ in phases if 0.5 <= t0 <= t_w)
    cmd = res.extras["controller_command"]
    t_lock, t_slip = phases[0]
    i0 = int(np.searchsorted(res.t, t_lock))
    # bumpless at the lock: same command just before and just after, then the ramp at 0.05 m/s
    assert abs(cmd[i0] - cmd[i0 - 1]) < 1e-5
    k = (res.t > t_lock + 1e-3) & (res.t < t_slip - 1e-6)
    assert np.allclose(cmd[k], cmd[i0] + 0.05 * (res.t[k] - t_lock), atol=1e-9)
    # re-slip: re-armed, continuing from the current value (no jump), offset ramping out
    j = int(np.searchsorted(res.t, t_slip, side="right"))
    assert abs(cmd[j] - (cmd[i0] + 0.05 * (t_slip - t_lock))) < 1e-4
    w1, w3 = res.state("omega_engine"), res.state("omega_primary")
    law = X_R0 + K_R * (SC.reference(res.t) - w1) * np.sign(w1 - w3)
    d_j = cmd[j] - law[j]  # the offset at the first sample after the re-slip
    d0 = d_j + np.sign(d_j) * 0.05 * (res.t[j] - t_slip)
    later = (res.t > t_slip) & (res.t < t_slip + abs(d0) / 0.05) & (res.t < phases[1][0])
    offset = d0 - np.sign(d0) * 0.05 * (res.t[later] - t_slip)
    assert later.sum() >= 3  # enough samples in the ramp-out window to check it
    assert np.allclose(cmd[later], np.clip(law[later] + offset, 0.0, 0.12), atol=1e-6)


# -- sampled vs continuous --------------------------------------------------------------------


def test_sampled_law_converges_to_the_continuous_one() -> None:
    res_c, m_c = _run("reduced", "paper", t_end=2.0)
    errs = []
    for ts in (1e-2, 1e-3):
        spec = ControllerSpec(name=f"paper-{ts}", law="paper", sample_period_s=ts)
        res_s, _ = _run("reduced", spec, t_end=2.0)
        w = np.interp(res_c.t, res_s.t, res_s.state("omega_engine"))
        errs.append(float(np.max(np.abs(w - res_c.state("omega_engine")))))
    assert errs[1] < errs[0] / 4.0, errs
    assert errs[1] < 2.0  # rad/s


# -- the LTI realisation is what runs ---------------------------------------------------------


@pytest.mark.parametrize("ts", [None, 0.01])
def test_controller_lti_and_simulated_output_agree(ts: float | None) -> None:
    """Small-signal test: the PI's LTI block, driven by a known error (the reference only), gives
    the same command in the simulation as python-control's forced_response."""
    spec = ControllerSpec(name="pi", law="pi", kp=2e-4, ki=1e-3, sample_period_s=ts)
    lti = spec.lti()
    ref = ramp(0.1, 0.6, 0.0, 2.0) + sine(0.5, 3.0)
    ctl = Controller(
        name="probe", lti=lti, measurement=((1.0, "ref"),), output="pedal", reference=ref,
        offset=0.07,
    )  # fmt: skip
    model = Model(two_body_clutch(1.0, 1.0, capacity="pedal"))
    x0 = np.zeros(model.nx)
    res = simulate(model, x0, {"torque1": 0.0}, t_end=1.0, controller=ctl, controller_initial=0.07)
    cmd = res.extras["controller_command"]
    if ts is None:
        T = np.linspace(0.0, 1.0, 2001)
        _, y = control.forced_response(lti, T, np.asarray(ref(T)))
        got = np.interp(T, res.t, cmd)
        assert np.max(np.abs(got - (0.07 + y))) < 1e-6
    else:
        T = np.arange(0.0, 1.0, ts)
        _, y = control.forced_response(lti, T, np.asarray(ref(T)))
        # held between samples: the command just after sample k is y[k]
        got = np.array([cmd[np.searchsorted(res.t, tk + 1e-9)] for tk in T[1:-1]])
        assert np.max(np.abs(got - (0.07 + y[1:-1]))) < 1e-9


# -- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kw,field",
    [
        ({"k_r": float("nan")}, "k_r"),
        ({"k_r": -1e-3}, "k_r"),
        ({"k_r": 5.0}, "k_r"),
        ({"sample_period_s": 0.0}, "sample_period_s"),
        ({"sample_period_s": float("inf")}, "sample_period_s"),
        ({"delay_samples": 2}, "delay_samples"),
        ({"engage_rate_m_s": -1.0}, "engage_rate_m_s"),
        ({"law": "pid"}, "law"),
    ],
)
def test_bad_controller_values_name_the_field(kw: dict[str, object], field: str) -> None:
    with pytest.raises(ControllerError, match=field):
        ControllerSpec(name="bad", **kw)  # type: ignore[arg-type]


def test_bad_pi_gain_and_actuator_bandwidth_name_the_field() -> None:
    with pytest.raises(ControllerError, match="ki"):
        ControllerSpec(name="bad", law="pi", kp=1e-3, ki=math.inf)
    with pytest.raises(ValueError, match="actuator.omega_a"):
        P.replace(**{"actuator.omega_a": -5.0})


def test_controller_file_round_trip_and_typos(tmp_path) -> None:  # type: ignore[no-untyped-def]
    f = tmp_path / "c.toml"
    f.write_text('name = "mine"\nlaw = "pi"\nkp = 1e-3\nki = 5e-3\nsample_period_s = 0.01\n')
    spec = load_controller(str(f))
    assert spec.kp == 1e-3 and spec.sample_period_s == 0.01
    f.write_text('law = "pi"\nkp = 1e-3\nkii = 5e-3\n')
    with pytest.raises(ControllerError, match="kii.*did you mean 'ki'"):
        load_controller(str(f))
    with pytest.raises(ControllerError, match="did you mean 'paper'"):
        load_controller("papr")


def test_bad_scenario_control_values_name_the_field() -> None:
    with pytest.raises(ScenarioError, match="start_s"):
        dataclasses.replace(SC, control_start=9.0)
    with pytest.raises(ScenarioError, match="pedal0"):
        dataclasses.replace(SC, pedal0=float("nan"))


def test_an_unstable_gain_gives_a_result_and_a_warning() -> None:
    spec = ControllerSpec(name="hot", law="paper", k_r=0.02, sample_period_s=0.01, delay_samples=1)
    with pytest.warns(UnstableLoopWarning, match="unstable"):
        stable, _ = spec.check_stability(P)
    assert not stable
    with pytest.warns(UnstableLoopWarning, match="unstable"):
        res, m = _run("reduced", spec, t_end=1.5)
    assert res.status == "ok" and res.t[-1] == pytest.approx(1.5)


def test_builtin_controllers_are_stable_in_slip() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for spec in builtin_controllers().values():
            stable, _ = spec.check_stability(P)
            assert stable, spec.name
    # closed form at s = 0: k_r |k13'| / b1, k13' the pedal-map chord at x_r0 = 0.07 m
    pm = P.clutch.pedal_map
    k12 = [P.clutch.k12_max * y for y in pm.y]  # capacity [N m] at the knots
    k = list(pm.x).index(0.07)
    k13p = abs((k12[k + 1] - k12[k]) / (pm.x[k + 1] - pm.x[k]))
    L = slip_loop(builtin_controllers()["paper"], P)
    dc = float(np.real(control.evalfr(L, 0.0)))
    assert dc == pytest.approx(K_R * k13p / P.engine.b1, rel=1e-9)


def test_closed_loop_scenario_round_trips_through_toml(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import tomli_w

    f = tmp_path / "start.toml"
    f.write_text(tomli_w.dumps(SC.to_dict()))
    sc2 = load_scenario(str(f))
    assert sc2.control_start == 0.5 and sc2.needs_controller and sc2.pedal0 == SC.pedal0
    _, m1 = _run("reduced", "paper")
    _, m2 = _run("reduced", "paper", sc=sc2)
    assert m2["lockup_time_s"] == pytest.approx(m1["lockup_time_s"], abs=1e-9)
    f.write_text(
        tomli_w.dumps({**SC.to_dict(), "controller": {"reference_rpm": 1.0, "strat_s": 1}})
    )
    with pytest.raises(ScenarioError, match="strat_s.*did you mean 'start_s'"):
        load_scenario(str(f))


def test_new_entry_points_name_the_bad_argument() -> None:
    from drivetrain_ctrl.reporting.figures import plot_engagement
    from drivetrain_ctrl.sim.metrics import filtered_jerk

    res, _ = _run("reduced", "paper", t_end=0.6)
    dt = SC.drivetrain(P, kind="reduced")
    with pytest.raises(ValueError, match="start = nan"):
        engagement_metrics(res, dt, start=float("nan"))
    with pytest.raises(TypeError, match="reference"):
        engagement_metrics(res, dt, reference=3.0)
    t = np.linspace(0.0, 1.0, 101)
    with pytest.raises(ValueError, match="cutoff_hz"):
        filtered_jerk(t, t, cutoff_hz=600.0)
    with pytest.raises(ValueError, match="fs_hz"):
        filtered_jerk(t, t, fs_hz=-1.0)
    with pytest.raises(ScenarioError, match="omega"):
        idle_throttle(P, float("inf"))
    with pytest.raises(ScenarioError, match="omega"):
        idle_throttle(P, -10.0)
    with pytest.raises(ControllerError, match="controller = 3"):
        load_controller(3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="runs is empty"):
        plot_engagement([])
    with pytest.raises(ValueError, match="lockups"):
        plot_engagement([("a", res)], lockups=[1.0, 2.0])


def test_short_damper_stick_episode_matches_a_run_with_tiny_steps() -> None:
    """At default options the closed-loop full model (law (6)) finds the same events as with
    h_max = 10 us up to 1 s, including a damper stick episode of 39 us near 0.7933 s inside one
    ordinary step: found through the slip speed's dip on the continuous extension, not by the
    guards at the step ends (the simulator before the dip check stepped over it)."""
    from drivetrain_ctrl.sim.simulator import SimulationOptions

    dt = SC.drivetrain(P, kind="full")
    res = run_scenario(SC, dt, controller="paper", t_end=1.0)
    fine = run_scenario(
        SC, dt, controller="paper", t_end=1.0, options=SimulationOptions(h_max=1e-5)
    )
    ev = [(e.element, e.from_mode, e.to_mode) for e in res.events]
    assert ev == [(e.element, e.from_mode, e.to_mode) for e in fine.events]
    dt_ev = [abs(a.t - b.t) for a, b in zip(res.events, fine.events, strict=True)]
    assert max(dt_ev) < 1e-5
    ep = [e for e in res.events if e.element == "damper_friction" and abs(e.t - 0.7933) < 1e-4]
    assert [(e.from_mode, e.to_mode) for e in ep] == [("slip+", "stuck"), ("stuck", "slip+")]
    assert 30e-6 < ep[1].t - ep[0].t < 50e-6
    assert res.stats["steps"] < 0.1 * fine.stats["steps"]


def test_controller_block_changes_are_in_the_event_list() -> None:
    """Closed loop (law (6) and PI, reduced model): the latch arms -> ramps at the clutch's lock
    event, at the same time, and is held once the ramp reaches full engagement; the PI saturates
    at the stroke at its start (0.5 s) and leaves it. Plant events are the same as without these
    entries (the controller's are extra rows)."""
    dt = SC.drivetrain(P, kind="reduced")
    for ctl in ("paper", "pi"):
        res = run_scenario(SC, dt, controller=ctl)
        ev = res.events
        lock = [e for e in ev if e.element == "clutch" and e.to_mode == "stuck"]
        latch = [e for e in ev if e.element == "controller.latch"]
        assert [(e.from_mode, e.to_mode) for e in latch] == [("armed", "ramp"), ("ramp", "held")]
        assert latch[0].t == lock[0].t
        assert latch[1].t > latch[0].t
        # the plant's events are those of the model's elements, the controller's extra rows
        plant = {f.name for f in dt.model.frictions} | {t.name for t in dt.model.tables}
        assert {e.element for e in ev} - plant <= {
            f"controller.{b}" for b in ("latch", "sign", "saturation")
        }
        df = res.events_dataframe()
        assert (df["element"] == "controller.latch").sum() == 2
    sat = [(e.t, e.from_mode, e.to_mode) for e in ev if e.element == "controller.saturation"]
    assert sat[0] == (SC.start_time, "linear", "high")
    assert sat[1][1:] == ("high", "linear")
