"""Figures of merit (:mod:`drivetrain_ctrl.metrics`) on runs with hand-derived answers.

Two-body clutch (bodies b1, b2; constant drive torque T on b1, constant capacity k, b2 at rest):
while slipping (slip+) the accelerations are constant, ``a1 = (T - k)/J1`` and ``a2 = k/J2``, so
the slip speed ``s = w1 - w2`` falls linearly from ``w0`` and the clutch locks at
``t_l = w0 / (k/J2 - (T - k)/J1)``; it stays locked if the stuck torque ``T J2/(J1 + J2) <= k``.
The clutch dissipates ``integral k s dt = k w0 t_l / 2``. At lock-up the acceleration of b2
jumps from ``k/J2`` to ``T/(J1 + J2)`` (the "lurch" of b2) and the slip acceleration just before
is ``(T - k)/J1 - k/J2``. Accelerations are piecewise constant, so the jerk is zero.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.core.serialize import json_ready, round_sig
from drivetrain_ctrl.plant.chain import two_body_clutch
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.sim.metrics import (
    METRIC_KEYS,
    METRICS,
    engagement_metrics,
    filtered_jerk,
    jerk,
    metric_table,
    metrics_markdown,
    state_accelerations,
)
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.sim.simulator import SimulationResult, simulate

J1, J2, T, W0 = 0.2, 0.3, 30.0, 100.0


def run(k: float, t_end: float = 1.0) -> SimulationResult:
    model = Model(two_body_clutch(J1, J2, capacity=k))
    x0 = np.array([W0, 0.0])
    return simulate(model, x0, {"torque1": sg.constant(T)}, t_end=t_end)


def metrics(res: SimulationResult) -> dict:
    return engagement_metrics(res, vehicle="omega_b2", engine="omega_b1")


def test_lockup_time_and_clutch_energy_are_analytic() -> None:
    k = 40.0
    t_l = W0 / (k / J2 - (T - k) / J1)
    assert T * J2 / (J1 + J2) <= k  # stays locked
    m = metrics(run(k))
    assert m["lockup_time_s"] == pytest.approx(t_l, abs=1e-8)
    assert m["clutch_energy_J"] == pytest.approx(k * W0 * t_l / 2.0, rel=1e-7)
    assert m["n_events"] == 1
    assert m["status"] == "ok"
    assert m["energy_residual_rel"] < 1e-9
    # all supplied work ends up stored or dissipated in the clutch (no other losses)
    w_end = W0 + (T - k) / J1 * t_l + T / (J1 + J2) * (1.0 - t_l)
    e_end = 0.5 * (J1 + J2) * w_end**2
    assert m["work_in_J"] == pytest.approx(
        e_end - 0.5 * J1 * W0**2 + m["clutch_energy_J"], rel=1e-7
    )


def test_lurch_slip_acceleration_and_jerk() -> None:
    k = 40.0
    res = run(k)
    m = metrics(res)
    assert m["lurch_rad_s2"] == pytest.approx(T / (J1 + J2) - k / J2, rel=1e-8)
    assert m["lockup_slip_accel_rad_s2"] == pytest.approx((T - k) / J1 - k / J2, rel=1e-8)
    # the vehicle figures are in m/s units: None for a rotational "vehicle" state
    for key in ("vehicle_accel_max_m_s2", "jerk_max_m_s3", "final_vehicle_speed_kmh"):
        assert m[key] is None, key
    # piecewise-constant accelerations: zero jerk inside modes, the jump is not a jerk
    right, left = state_accelerations(res)
    assert np.max(np.abs(jerk(res.t, right[:, 1], left[:, 1]))) == pytest.approx(0.0, abs=1e-6)
    # engine figures on body b1: it only decelerates while slipping, then accelerates
    w_lock = W0 + (T - k) / J1 * m["lockup_time_s"]
    assert m["engine_speed_min_rpm"] == pytest.approx(w_lock * 30.0 / math.pi, rel=1e-8)


def test_no_lockup_gives_none() -> None:
    k = 10.0  # too weak: the slip grows
    res = run(k, t_end=0.5)
    m = metrics(res)
    assert m["lockup_time_s"] is None
    assert m["lurch_rad_s2"] is None
    assert m["lockup_slip_accel_rad_s2"] is None
    assert m["clutch_energy_J"] == pytest.approx(
        k * (W0 * 0.5 + 0.5 * ((T - k) / J1 - k / J2) * 0.5**2), rel=1e-7
    )


def test_keys_json_and_none_for_missing_elements() -> None:
    m = engagement_metrics(run(40.0))  # default names: no engine, vehicle, axle or backlash
    assert tuple(m) == METRIC_KEYS
    json.dumps(m, allow_nan=False)
    for key in (
        "model",
        "gear",
        "final_vehicle_speed_kmh",
        "vehicle_accel_max_m_s2",
        "jerk_max_m_s3",
        "engine_speed_min_rpm",
        "axle_torque_max_Nm",
        "shaft_torque_max_Nm",
    ):
        assert m[key] is None, key
    assert m["lockup_time_s"] is not None
    assert m["lockup_slip_accel_rad_s2"] is not None
    assert m["n_backlash_crossings"] == 0


def test_deterministic_across_runs() -> None:
    a = json.dumps(metrics(run(40.0)), sort_keys=True)
    b = json.dumps(metrics(run(40.0)), sort_keys=True)
    assert a == b


def test_accelerations_left_and_right_limits() -> None:
    k = 40.0
    res = run(k)
    right, left = state_accelerations(res)
    i = int(np.flatnonzero(res.fm[:, 0] == 0)[0])  # first stuck sample = lock-up
    assert left[i, 1] == pytest.approx(k / J2)
    assert right[i, 1] == pytest.approx(T / (J1 + J2))
    assert np.all(right[:i, 1] == pytest.approx(k / J2))


def test_jerk_skips_zero_length_intervals() -> None:
    t = np.array([0.0, 1.0, 1.0, 2.0])
    a = np.array([0.0, 1.0, 5.0, 7.0])
    assert jerk(t, a, a).tolist() == [1.0, 2.0]


def test_rounding() -> None:
    assert round_sig(1.0 / 3.0) == 0.333333333
    assert round_sig(-0.0) == 0.0 and math.copysign(1.0, round_sig(-0.0) or 0.0) == 1.0
    assert round_sig(float("nan")) is None
    assert round_sig(float("inf")) is None
    assert round_sig(None) is None
    got = json_ready({"a": (np.float64(2.0) / 3.0, np.int64(3)), "b": np.bool_(True)})
    assert got == {"a": [0.666666667, 3], "b": True}
    assert type(got["a"][1]) is int and type(got["b"]) is bool


def test_start_must_lie_within_the_run() -> None:
    res = run(40.0)
    for bad in (-0.1, 1.0 + 1e-9, 5.0):
        with pytest.raises(ValueError, match=r"start = .*must lie within the run"):
            engagement_metrics(res, start=bad)
    for bad_type in (True, "0.1", float("nan")):
        with pytest.raises(ValueError, match="start"):
            engagement_metrics(res, start=bad_type)  # type: ignore[arg-type]
    # the ends and NumPy scalars are accepted
    assert engagement_metrics(res, start=0.0)["start_s"] == 0.0
    assert engagement_metrics(res, start=np.float32(0.25))["start_s"] == 0.25
    assert engagement_metrics(res, start=float(res.t[-1]))["start_s"] == float(res.t[-1])


def test_engagement_window_figures_unchanged_by_reusing_accelerations() -> None:
    # the window figures use the accelerations computed once; the lurch of the driven body b2
    # at lock-up is the hand-derived jump (see the module docstring)
    k = 40.0
    m = metrics(run(k))
    assert m["lurch_rad_s2"] == pytest.approx(T / (J1 + J2) - k / J2, rel=1e-8)


def test_filtered_jerk_checks_its_arrays() -> None:
    t = np.linspace(0.0, 1.0, 101)
    a = np.sin(t)
    with pytest.raises(ValueError, match="1-D"):
        filtered_jerk(t.reshape(1, -1), a)
    with pytest.raises(ValueError, match="same length"):
        filtered_jerk(t, a[:-1])
    with pytest.raises(ValueError, match="at least 2"):
        filtered_jerk(t[:1], a[:1])
    with pytest.raises(ValueError, match="t must be finite"):
        filtered_jerk(np.where(t == 0.5, np.nan, t), a)
    with pytest.raises(ValueError, match="accel must be finite"):
        filtered_jerk(t, np.where(t == 0.5, np.inf, a))
    with pytest.raises(ValueError, match=r"t must be non-decreasing, but t\[3\]"):
        filtered_jerk(np.array([0.0, 0.1, 0.2, 0.15, 0.3]), np.zeros(5))
    with pytest.raises(ValueError, match="t spans no time"):
        filtered_jerk(np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="cutoff_hz"):
        filtered_jerk(t, a, cutoff_hz=True)  # type: ignore[arg-type]
    # NumPy scalars are numbers; repeated times (events) are allowed
    g, af, jk = filtered_jerk(t, a, cutoff_hz=np.float32(10.0), fs_hz=np.int64(1000))
    assert g.shape == af.shape == jk.shape and g[0] == 0.0
    tr = np.array([0.0, 0.5, 0.5, 1.0])
    g, af, jk = filtered_jerk(tr, np.array([0.0, 1.0, 1.0, 2.0]))
    assert np.allclose(jk[200:-200], 2.0, rtol=1e-3)


def test_inconsistent_decisions_are_reported_not_silent(monkeypatch: pytest.MonkeyPatch) -> None:
    """A kernel that reports inconsistent mode decisions (the least inconsistent combination
    taken): ``simulate`` warns, and the metrics carry the count and a note."""
    import dataclasses

    from drivetrain_ctrl.sim import simulator as S

    res = run(40.0)
    m = metrics(res)
    assert m["inconsistent_decisions"] == 0
    assert not any("consistent" in n for n in m["notes"])
    bad = dataclasses.replace(res, stats={**res.stats, "inconsistent_decisions": 2})
    m = metrics(bad)
    assert m["inconsistent_decisions"] == 2
    assert any(n.startswith("2 mode decision(s) found no consistent") for n in m["notes"])

    real = S.K.simulate_kernel

    def kernel_with_bad_decisions(*args: object) -> tuple:
        out = real(*args)
        return (*out[:16], 3, *out[17:])  # output 16: the count of inconsistent decisions

    monkeypatch.setattr(S.K, "simulate_kernel", kernel_with_bad_decisions)
    with pytest.warns(RuntimeWarning, match=r"^3 mode decision\(s\) found no consistent"):
        res3 = run(40.0)
    assert res3.stats["inconsistent_decisions"] == 3


def test_misspelt_names_are_errors_while_absent_defaults_give_none() -> None:
    from drivetrain_ctrl.plant.drivetrain import Drivetrain
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    dt = Drivetrain(default_params(), kind="reduced")
    res = run_scenario(load_scenario("engage-ramp"), dt, t_end=0.3)
    for kw in ({"vehicle": "v_vehicel"}, {"engine": "omega_engin"}, {"clutch": "clutc"}):
        ((arg, val),) = kw.items()
        with pytest.raises(ValueError, match=rf"engagement_metrics: {arg} = '{val}': not in the"):
            engagement_metrics(res, dt, **kw)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="dt = 'reduced': must be a Drivetrain or None"):
        engagement_metrics(res, "reduced")  # type: ignore[arg-type]
    # a general chain has none of the default names: those metrics are None, no error
    m = Model(two_body_clutch(0.2, 1.0, capacity=50.0))
    r = simulate(m, np.array([100.0, 0.0]), {"torque1": 20.0}, t_end=0.5)
    out = engagement_metrics(r)
    assert out["final_vehicle_speed_kmh"] is None and out["n_events"] == len(r.events)


# ------------------------------------------------------------------------------------------------
# one name, one definition (issue 19, item 7)
# ------------------------------------------------------------------------------------------------

#: the names of engagement_metrics, spelt out: renaming or adding one is a decision, and the
#: changelog says so (users' scripts read these keys)
NAMES = (
    "model",
    "gear",
    "status",
    "t_end_s",
    "n_samples",
    "n_events",
    "inconsistent_decisions",
    "work_in_J",
    "energy_residual_rel",
    "start_s",
    "notes",
    "lockup_time_s",
    "engagement_time_s",
    "n_lock_events",
    "clutch_energy_J",
    "lockup_slip_accel_rad_s2",
    "lurch_rad_s2",
    "engine_speed_min_rpm",
    "engine_speed_max_rpm",
    "engine_stalled",
    "tracking_rms_rpm",
    "torque_match_rms_Nm",
    "vehicle_accel_max_m_s2",
    "accel_p2p_after_lock_m_s2",
    "jerk_max_m_s3",
    "jerk_rms_m_s3",
    "shaft_torque_max_Nm",
    "axle_torque_max_Nm",
    "n_backlash_impacts",
    "n_backlash_crossings",
    "final_vehicle_speed_kmh",
    "rollback_m",
)

#: the unit a name's suffix stands for
SUFFIX_UNIT = {
    "_s": "s",
    "_J": "J",
    "_rpm": "rpm",
    "_rad_s2": "rad/s^2",
    "_m_s2": "m/s^2",
    "_m_s3": "m/s^3",
    "_Nm": "N m",
    "_kmh": "km/h",
    "_rel": "-",
    "_m": "m",
}


@pytest.fixture(scope="module")
def car_runs() -> dict[str, tuple]:
    """engage-ramp and tip-in on both models: (result, drivetrain, metrics)."""
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    out = {}
    for name in ("engage-ramp", "tip-in"):
        sc = load_scenario(name)
        for kind in ("full", "reduced"):
            dt = sc.drivetrain(default_params(), kind=kind)
            res = run_scenario(sc, dt)
            m = engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
            out[f"{name}/{kind}"] = (res, dt, m)
    return out


def test_the_names_are_the_table(car_runs: dict[str, tuple]) -> None:
    assert tuple(METRICS) == METRIC_KEYS == NAMES
    # every key engagement_metrics returns is in the table, and every entry of the table is
    # returned, in its order (a two-body chain and the car, with and without lock-up)
    for m in [metrics(run(40.0)), metrics(run(10.0, t_end=0.5))] + [
        r[2] for r in car_runs.values()
    ]:
        assert set(m) == set(METRICS)
        assert tuple(m) == tuple(METRICS)
    # the names that meant two things are gone
    for old in (
        "lurch_m_s2",
        "max_vehicle_jerk_m_s3",
        "max_engine_speed_rpm",
        "min_engine_speed_rpm",
        "max_vehicle_accel_m_s2",
        "peak_axle_torque_Nm",
        "peak_shaft_torque_Nm",
    ):
        assert old not in METRICS, old


def test_one_definition_per_name_and_the_unit_in_the_name() -> None:
    definitions = [info.definition for info in METRICS.values()]
    assert len(set(definitions)) == len(definitions), "two names share a definition"
    for name, info in METRICS.items():
        assert info.kind in ("figure", "run"), name
        assert info.definition.strip() and info.definition.endswith("."), name
        suffix = [s for s in SUFFIX_UNIT if name.endswith(s)]
        if info.unit in ("", "-"):
            # a text, a flag, a list, a count: no unit suffix to contradict
            assert info.unit == "-" or not suffix, name
        else:
            assert suffix and SUFFIX_UNIT[max(suffix, key=len)] == info.unit, (name, info.unit)
    assert metric_table(["lurch_rad_s2"]) == [
        ("lurch_rad_s2", "rad/s^2", METRICS["lurch_rad_s2"].definition)
    ]
    with pytest.raises(KeyError, match="lurch_m_s2"):
        metric_table(["lurch_m_s2"])


def test_the_documentation_shows_the_table() -> None:
    from pathlib import Path

    page = Path(__file__).resolve().parents[2] / "docs" / "simulation.md"
    assert metrics_markdown() in page.read_text(encoding="utf-8"), (
        "docs/simulation.md: paste the output of "
        "drivetrain_ctrl.sim.metrics.metrics_markdown() into the figures-of-merit section"
    )


def test_nothing_engages_on_tip_in(car_runs: dict[str, tuple]) -> None:
    """tip-in starts and stays locked: the figures of an engagement are None, not numbers."""
    for kind in ("full", "reduced"):
        res, _, m = car_runs[f"tip-in/{kind}"]
        assert np.all(res.fm[:, res.model.friction_index("clutch")] == 0)  # stuck throughout
        for key in (
            "torque_match_rms_Nm",
            "tracking_rms_rpm",
            "lockup_time_s",
            "engagement_time_s",
            "lurch_rad_s2",
            "lockup_slip_accel_rad_s2",
            "accel_p2p_after_lock_m_s2",
        ):
            assert m[key] is None, (kind, key)
        assert m["clutch_energy_J"] == 0.0 and m["n_lock_events"] == 0
        assert any("no engagement" in n for n in m["notes"])
        # the figures of the window (here the whole run) are numbers
        assert m["jerk_max_m_s3"] > 0 and m["engine_speed_max_rpm"] > m["engine_speed_min_rpm"]
        # ... and the extremes are those of the samples: the window is the whole run here
        w = res.state("omega_engine") * 30.0 / math.pi
        assert m["engine_speed_max_rpm"] == pytest.approx(np.max(w), rel=1e-8)
        assert m["engine_speed_min_rpm"] == pytest.approx(np.min(w), rel=1e-8)


def test_torque_match_is_a_number_when_the_clutch_slips(car_runs: dict[str, tuple]) -> None:
    for kind in ("full", "reduced"):
        m = car_runs[f"engage-ramp/{kind}"][2]
        assert m["torque_match_rms_Nm"] > 0
        assert m["tracking_rms_rpm"] is None  # open loop: no reference


def test_lurch_is_the_jump_of_the_driven_acceleration_on_the_trajectory(
    car_runs: dict[str, tuple],
) -> None:
    """lurch_rad_s2 against a plain computation on the recorded speeds: the one-sided slopes of
    the driven body's speed at lock-up (a cubic through the lock-up sample and the three samples
    before it, and one through it and the three after), after minus before."""
    for kind, body in (("full", "omega_disc"), ("reduced", "omega_primary")):
        res, _, m = car_runs[f"engage-ramp/{kind}"]
        t = res.t
        w = res.state(body)
        stuck = np.asarray(res.mode_series("clutch")) == "stuck"
        i0 = int(np.flatnonzero(stuck[1:] & ~stuck[:-1])[0]) + 1  # first stuck sample
        t_lock = t[i0]
        assert m["lockup_time_s"] == pytest.approx(t_lock, rel=1e-8)
        before = np.flatnonzero(t < t_lock)[-3:]
        after = np.flatnonzero(t > t_lock)[:3]
        slope_before = np.polyfit(t[[*before, i0]] - t_lock, w[[*before, i0]], 3)[-2]
        slope_after = np.polyfit(t[[i0, *after]] - t_lock, w[[i0, *after]], 3)[-2]
        lurch = slope_after - slope_before
        assert abs(lurch) > 100.0, (kind, lurch)  # a real jump, not round-off
        assert m["lurch_rad_s2"] == pytest.approx(lurch, rel=1e-2), kind
        # the vehicle sits behind the driveline's springs: its acceleration does not jump (the
        # reason the vehicle-acceleration "lurch" was always 0 and is no figure)
        right, left = state_accelerations(res)
        iv = res.model.state_names.index("v_vehicle")
        assert abs(right[i0, iv] - left[i0, iv]) < 1e-9 * max(1.0, abs(right[i0, iv]))


def test_the_readme_docs_and_analyses_quote_only_names_of_the_table() -> None:
    """``m["..."]`` (a metrics dict) in the README, the documentation and the analyses: every
    name with a unit suffix is a key of the table (an old name would not be)."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    files = [root / "README.md", *(root / "docs").glob("*.md"), *(root / "analyses").glob("*.py")]
    pattern = re.compile(r"\b[mr]\[[\"'](\w+_(?:s|J|rpm|rad_s2|m_s2|m_s3|Nm|kmh|rel))[\"']\]")
    quoted = {(f.name, k) for f in files for k in pattern.findall(f.read_text(encoding="utf-8"))}
    assert {k for _, k in quoted} >= {"lockup_time_s", "jerk_max_m_s3", "tracking_rms_rpm"}
    assert {(f, k) for f, k in quoted if k not in METRICS} == set()


def test_an_engine_turned_backwards_counts_as_stalled(car_runs: dict[str, tuple]) -> None:
    """A wrong-sign controller can drag the engine through zero while its friction slips
    backwards (never in the standstill mode): that is a stall too. The engage-ramp run with the
    engine speed made negative at one sample inside the window W = [start, lock-up + 1 s], and
    at one after it."""
    import dataclasses

    from drivetrain_ctrl.scenarios.scenario import load_scenario

    start = load_scenario("engage-ramp").start_time
    res, dt, m = car_runs["engage-ramp/full"]
    assert m["engine_stalled"] is False
    w_end = m["lockup_time_s"] + 1.0
    assert res.t[-1] > w_end + 0.005
    j = res.model.state_index("omega_engine")
    for t_at, expected in ((0.5 * (start + w_end), True), (0.5 * (w_end + res.t[-1]), False)):
        x = res.x.copy()
        x[int(np.searchsorted(res.t, t_at)), j] = -5.0
        got = engagement_metrics(dataclasses.replace(res, x=x), dt, start=start)["engine_stalled"]
        assert got is expected, (t_at, got)
