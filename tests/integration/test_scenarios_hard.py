"""The harder built-in starts of issue 21 (item 1): hill-start, worn-clutch, judder, heavy-load
and tip-out-reengage. Their parameter overrides, and each one's physical claim, from runs, in
closed loop (a controller) and in open loop (the driver's pedal of the file); every built-in
scenario in every loop it has on both models."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from drivetrain_ctrl import default_params, engagement_metrics, load_scenario, run_scenario
from drivetrain_ctrl.control.laws import load_controller
from drivetrain_ctrl.core.signals import constant
from drivetrain_ctrl.core.units import rpm_to_rad_s
from drivetrain_ctrl.linear import judder_threshold
from drivetrain_ctrl.linear.operating_point import operating_point_from_result
from drivetrain_ctrl.scenarios import ScenarioError, builtin_scenarios
from drivetrain_ctrl.scenarios.scenario import scenario_from_dict
from drivetrain_ctrl.studies.case import Case, simulate_case

HARD = ("hill-start", "worn-clutch", "judder", "heavy-load", "tip-out-reengage")
#: the starts: a controller part and a driver's pedal each
STARTS = ("paper-start", *HARD)


def _run(name: str, controller: str | None = "paper", kind: str = "reduced", **replace):  # type: ignore[no-untyped-def]
    """``controller`` None: the open loop (the file's pedal signal)."""
    p = default_params()
    sc = load_scenario(name, params=p)
    if replace:
        sc = dataclasses.replace(sc, **replace)
    sc = sc.for_loop("closed" if controller is not None else "open")
    dt = sc.drivetrain(p, kind=kind)
    res = run_scenario(sc, dt, controller=controller)
    m = engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
    return sc, dt, res, m


def _col(res, name: str) -> np.ndarray:  # type: ignore[no-untyped-def]
    return res.x[:, res.model.state_names.index(name)]


def _slip(res) -> np.ndarray:  # type: ignore[no-untyped-def]
    return _col(res, "omega_engine") - _col(res, "omega_primary")


# -- the files and their parameter overrides --------------------------------------------------------


def test_builtins_listed_with_their_claims() -> None:
    b = builtin_scenarios()
    for name in HARD:
        sc = b[name]
        assert sc.needs_controller and sc.description and "{throttle0}" not in sc.description
    for name in STARTS:  # closed loop by default, and a driver's pedal for the open loop
        assert b[name].loops == ("closed", "open") and b[name].loop == "closed", name
    assert b["engage-ramp"].loops == b["tip-in"].loops == ("open",)  # pedal manoeuvres only
    assert b["hill-start"].slope == pytest.approx(math.atan(0.12), rel=1e-12)
    assert b["heavy-load"].gear == 2


def test_overrides_applied_to_the_set_the_scenario_runs_on() -> None:
    p = default_params()
    worn = load_scenario("worn-clutch")
    q = worn.params_for(p)
    assert q.clutch.k12_max == pytest.approx(0.7 * p.clutch.k12_max, rel=1e-15)
    assert q.clutch.mu_table.y == (1.0, 0.85)
    # the scale is relative to whatever set the scenario runs on
    strong = p.replace(**{"clutch.k12_max": 300.0})
    assert worn.params_for(strong).clutch.k12_max == pytest.approx(210.0, rel=1e-15)
    assert worn.drivetrain(strong).params.clutch.k12_max == pytest.approx(210.0, rel=1e-15)
    heavy = load_scenario("heavy-load").drivetrain(p, kind="reduced").params.vehicle
    assert (heavy.M_v, heavy.drive_axle_load_fraction) == (2500.0, 0.42)
    # a scenario without overrides runs on the set itself
    assert load_scenario("tip-out-reengage").params_for(p) is p
    # round trip through the TOML form
    again = scenario_from_dict(worn.to_dict())
    assert again.param_overrides == worn.param_overrides


@pytest.mark.parametrize(
    ("params", "needle"),
    [
        ({"clutch": {"k12_maxx": 1.0}}, "params.clutch.k12_maxx"),
        ({"clutch": {"k12_max": -5.0}}, "-5"),
        ({"clutch": {"k12_max": {"scale": 0.0}}}, "params.clutch.k12_max"),
        ({"clutch": {"k12_max": {"scale": 0.7, "x": 1}}}, "params.clutch.k12_max"),
        ({"vehicle": 3}, "params.vehicle = 3"),
        ({"clutch": {"mu_table": {"scale": 0.5}}}, "params.clutch.mu_table"),
        ({"clutch": {"mu_table": {"x": [0.0, 10.0], "y": [1.0, -0.5]}}}, "mu_table"),
    ],
)
def test_bad_overrides_named(params: dict, needle: str) -> None:  # type: ignore[type-arg]
    d = load_scenario("worn-clutch").to_dict()
    d["params"] = params
    with pytest.raises(ScenarioError, match=None) as exc:
        scenario_from_dict(d)
    assert needle in str(exc.value), str(exc.value)


# -- every scenario under law (6), reduced model ----------------------------------------------------


@pytest.mark.parametrize("name", HARD)
def test_paper_locks_up_within_the_horizon_reduced(name: str) -> None:
    sc, _dt, _res, m = _run(name)
    assert m["status"] == "ok"
    assert m["lockup_time_s"] is not None and sc.start_time < m["lockup_time_s"] < sc.t_end - 0.5
    assert not m["engine_stalled"]
    assert m["inconsistent_decisions"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["reduced", "full"])
@pytest.mark.parametrize("controller", ["paper", "pi"])
@pytest.mark.parametrize("name", HARD)
def test_matrix(name: str, controller: str, kind: str) -> None:
    sc, _dt, res, m = _run(name, controller, kind)
    assert m["status"] == "ok"
    assert m["lockup_time_s"] is not None and m["lockup_time_s"] < sc.t_end - 0.5
    assert not m["engine_stalled"]
    assert res.energy_residual_rel is None or res.energy_residual_rel < 1e-6


# -- every built-in scenario, in every loop it has, on both models -------------------------------------

_MATRIX = [
    (name, loop, kind)
    for name, sc in builtin_scenarios().items()
    for loop in sc.loops
    for kind in ("full", "reduced")
]


@pytest.mark.parametrize(("name", "loop", "kind"), _MATRIX)
def test_every_scenario_in_every_loop_runs_to_its_horizon(name: str, loop: str, kind: str) -> None:
    """Through :class:`Case` (the path of the CLI, the studies and the comparison); about 4 s for
    all of them."""
    run = simulate_case(
        Case(
            scenario=name,
            loop=loop,
            model=kind,
            controller="paper" if loop == "closed" else None,
        )
    )
    sc, m = run.scenario, run.metrics
    assert sc.loop == loop and run.record()["loop"] == loop
    assert (run.controller is not None) == (loop == "closed")
    assert m["status"] == "ok"
    assert run.result.t_last == pytest.approx(sc.t_end, abs=1e-12)
    r = run.result.energy_residual_rel
    assert r is not None and math.isfinite(r) and r < 1e-6
    assert m["inconsistent_decisions"] == 0


# -- the physical claims ------------------------------------------------------------------------------


ROLLBACK_LIMIT_M = 0.05  # the hill-start's stated limit (its file header)


def test_hill_start_brake_holds_then_the_clutch_does() -> None:
    sc, dt, res, m = _run("hill-start")
    t = res.t
    df = res.to_dataframe()
    held = t < 1.0  # the brake is at 1500 N m until its ramp starts
    assert set(df["mode_brake"].to_numpy()[held]) == {"holding"}
    # the braked side stands still: the car moves only through the driveline's compliance
    x = _col(res, "pos_vehicle")
    assert np.all(_col(res, "omega_primary")[held] == 0.0)
    assert np.min(x) > -ROLLBACK_LIMIT_M
    # the clutch carries more than the grade torque (referred to the primary shaft) when the
    # brake lets go
    p = dt.params
    grade = p.vehicle.M_v * 9.80665 * math.sin(sc.slope) * p.driveline.R_p / p.gearbox.tau_t(1)
    i_rel = int(np.searchsorted(t, 1.0))
    assert df["T_clutch [N m]"].to_numpy()[i_rel] > grade
    assert m["lockup_time_s"] is not None
    # the brake is what holds it: without it the car rolls back beyond the limit
    _, _, res0, _ = _run(
        "hill-start",
        inputs=tuple((n, constant(0.0) if n == "brake" else s) for n, s in sc.inputs),
    )
    assert np.min(_col(res0, "pos_vehicle")) < -ROLLBACK_LIMIT_M


def _slip_points(res, lo: float, hi: float, n: int = 3) -> list[float]:  # type: ignore[no-untyped-def]
    """``n`` sample times of the run in slip with slip speed in (lo, hi) rad/s."""
    slip = _slip(res)
    mode = res.to_dataframe()["mode_clutch"].to_numpy()
    idx = np.flatnonzero((mode == "slip+") & (slip > lo) & (slip < hi) & (res.t > 0.6))
    assert idx.size >= n
    return [float(res.t[i]) for i in idx[np.linspace(0, idx.size - 1, n).astype(int)]]


def _paper_at(p) -> object:  # type: ignore[no-untyped-def]
    return load_controller("paper").build(p, reference=constant(rpm_to_rad_s(1600.0)))


def _falling_crit(jt) -> float:  # type: ignore[no-untyped-def]
    """The judder threshold mu' [s/rad] of a FALLING characteristic: the crossing with c < 0 of
    smallest |c| (judder_threshold's c_crit may be a c_dc > 0, a rising one, at some points)."""
    neg = [c for c in (jt.c_shuffle, jt.c_dc) if c is not None and c < 0.0]
    assert neg, jt
    return max(neg) / jt.k13


def test_judder_slope_beyond_the_threshold_and_law6_oscillates() -> None:
    sc, dt, res, m = _run("judder")
    mu = dt.params.clutch.mu_table
    slope = (mu.y[1] - mu.y[0]) / (mu.x[1] - mu.x[0])
    ctl = _paper_at(dt.params)
    for t in _slip_points(res, 1.0, 40.0):
        jt = judder_threshold(operating_point_from_result(res, t, drivetrain=dt), ctl)
        assert slope < _falling_crit(jt) < 0.0, (t, jt)  # beyond it

    # the run: in the steep part (slip < 40 rad/s) the clutch torque swings; on the flat
    # characteristic (paper-start) the same phase is smooth
    def swing(r) -> float:  # type: ignore[no-untyped-def]
        T = r.to_dataframe()["T_clutch [N m]"].to_numpy()
        s = _slip(r)
        w = (s > 0.0) & (s < 40.0) & (r.t > 0.6) & (r.to_dataframe()["mode_clutch"] == "slip+")
        return float(np.ptp(T[w.to_numpy()]))

    _, _, flat, m_flat = _run("paper-start")
    assert swing(res) > 5.0 * swing(flat)
    assert m["accel_p2p_after_lock_m_s2"] > 2.0 * m_flat["accel_p2p_after_lock_m_s2"]


def test_worn_clutch_slope_within_the_judder_stable_range() -> None:
    sc, dt, res, m = _run("worn-clutch")
    mu = dt.params.clutch.mu_table
    slope = (mu.y[1] - mu.y[0]) / (mu.x[1] - mu.x[0])
    assert slope == pytest.approx(-0.001, rel=1e-12)
    ctl = _paper_at(dt.params)
    for t in _slip_points(res, 1.0, 150.0, n=4):
        jt = judder_threshold(operating_point_from_result(res, t, drivetrain=dt), ctl)
        assert _falling_crit(jt) < 2.0 * slope, (t, jt)  # margin >= 2
    # the worn capacity: the transmitted torque never exceeds 0.7 x the new clutch's capacity
    T = res.to_dataframe()["T_clutch [N m]"].to_numpy()
    assert np.max(np.abs(T)) <= 0.7 * default_params().clutch.k12_max * (1 + 1e-9)
    _, _, _, m_new = _run("paper-start")
    assert m["lockup_time_s"] > m_new["lockup_time_s"]  # the worn clutch takes longer


def test_heavy_load_slips_longer_and_dissipates_more() -> None:
    _, dt, _, m = _run("heavy-load")
    assert dt.gear == 2
    _, _, _, m0 = _run("paper-start")
    assert m["engagement_time_s"] > 2.0 * m0["engagement_time_s"]
    assert m["clutch_energy_J"] > 2.0 * m0["clutch_energy_J"]


def test_tip_out_during_slip_then_one_lock_up() -> None:
    sc, dt, res, m = _run("tip-out-reengage")
    thr = res.to_dataframe()["input_throttle [-]"].to_numpy()
    t = res.t
    lifted = (t > 1.15) & (t < 1.55)
    assert np.all(thr[lifted] < 0.2)  # the driver's foot is off
    slip = _slip(res)
    assert np.all(slip[lifted] > 0.0)  # ... during slip
    assert m["lockup_time_s"] > 1.6 and m["n_lock_events"] == 1 and not m["engine_stalled"]
    # the engine falls during the tip-out, and the controller keeps it above idle - 100 rpm
    w = _col(res, "omega_engine")
    assert np.min(w[lifted]) < np.max(w[(t > 0.5) & (t < 1.0)])
    assert np.min(w[t > 0.5]) > rpm_to_rad_s(800.0)


# -- the open loop: the driver's pedal of each file -------------------------------------------------


def test_paper_start_open_loop_is_the_rougher_baseline() -> None:
    """The driver's pedal locks up sooner than law (6) but jerks beyond the comparison's limit
    (25 m/s^3), which law (6) stays within."""
    _, _, _, m_open = _run("paper-start", None)
    _, _, _, m_closed = _run("paper-start")
    assert m_open["lockup_time_s"] < m_closed["lockup_time_s"]
    assert m_open["jerk_max_m_s3"] > 25.0 > m_closed["jerk_max_m_s3"]


def test_hill_start_open_loop_holds_the_car() -> None:
    """The driver's pedal carries more than the grade torque when the brake ramp starts, so the
    car rolls back less than the stated limit."""
    sc, dt, res, m = _run("hill-start", None)
    df = res.to_dataframe()
    held = res.t < 1.0
    assert set(df["mode_brake"].to_numpy()[held]) == {"holding"}
    p = dt.params
    grade = p.vehicle.M_v * 9.80665 * math.sin(sc.slope) * p.driveline.R_p / p.gearbox.tau_t(1)
    i_rel = int(np.searchsorted(res.t, 1.0))
    assert df["T_clutch [N m]"].to_numpy()[i_rel] > grade
    assert np.min(_col(res, "pos_vehicle")) > -ROLLBACK_LIMIT_M
    assert m["lockup_time_s"] is not None and not m["engine_stalled"]


def test_worn_clutch_open_loop_slips_longer_than_the_new_clutch() -> None:
    """The same pedal on the worn clutch: 0.7 times the torque, a later lock-up, more heat."""
    _, _, res, m = _run("worn-clutch", None)
    _, _, _, m_new = _run("paper-start", None)
    T = res.to_dataframe()["T_clutch [N m]"].to_numpy()
    assert np.max(np.abs(T)) <= 0.7 * default_params().clutch.k12_max * (1 + 1e-9)
    assert m["lockup_time_s"] > m_new["lockup_time_s"] + 0.3
    assert m["clutch_energy_J"] > 1.5 * m_new["clutch_energy_J"]


def _swing(r) -> float:  # type: ignore[no-untyped-def]
    """Peak-to-peak clutch torque [N m] in forward slip below 40 rad/s after 0.6 s."""
    df = r.to_dataframe()
    s = _slip(r)
    w = (s > 0.0) & (s < 40.0) & (r.t > 0.6) & (df["mode_clutch"].to_numpy() == "slip+")
    return float(np.ptp(df["T_clutch [N m]"].to_numpy()[w]))


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_judder_open_loop_the_clutch_torque_swings(kind: str) -> None:
    """Nothing damps the slip mode on the falling mu(slip): with the same pedal the clutch
    torque swings many times more than on the flat characteristic."""
    _, _, res, m = _run("judder", None, kind)
    _, _, flat, _ = _run("paper-start", None, kind)
    assert _swing(res) > 5.0 * _swing(flat)
    assert m["lockup_time_s"] is not None  # the pedal still closes the clutch


def test_heavy_load_open_loop_pulls_the_engine_below_idle_without_stalling() -> None:
    _, _, res, m = _run("heavy-load", None)
    _, _, _, m_closed = _run("heavy-load")
    assert not m["engine_stalled"] and np.min(_col(res, "omega_engine")) > 0.0
    assert m["engine_speed_min_rpm"] < 700.0
    assert m_closed["engine_speed_min_rpm"] > 899.0  # law (6) holds it at idle and above
    assert m["lockup_time_s"] is not None


def test_tip_out_open_loop_drags_the_engine_down() -> None:
    """The driver keeps releasing the clutch pedal during the tip-out: the clutch pulls the
    engine far below idle, where law (6) keeps it above 800 rpm."""
    _, _, res, _ = _run("tip-out-reengage", None)
    _, _, res_c, _ = _run("tip-out-reengage")
    lifted = (res.t > 1.0) & (res.t < 1.6)
    assert np.min(_col(res, "omega_engine")[lifted]) < rpm_to_rad_s(600.0)
    lifted_c = (res_c.t > 1.0) & (res_c.t < 1.6)
    assert np.min(_col(res_c, "omega_engine")[lifted_c]) > rpm_to_rad_s(800.0)
