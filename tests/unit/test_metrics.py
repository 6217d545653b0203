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
    engagement_metrics,
    filtered_jerk,
    jerk,
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
    m = metrics(run(k))
    assert m["lurch_m_s2"] == pytest.approx(T / (J1 + J2) - k / J2, rel=1e-8)
    assert m["lockup_slip_accel_rad_s2"] == pytest.approx((T - k) / J1 - k / J2, rel=1e-8)
    assert m["max_vehicle_accel_m_s2"] == pytest.approx(k / J2, rel=1e-8)
    # piecewise-constant accelerations: zero jerk inside modes, the jump is not a jerk
    assert m["max_vehicle_jerk_m_s3"] == pytest.approx(0.0, abs=1e-6)
    # engine figures on body b1: it only decelerates while slipping, then accelerates
    w_lock = W0 + (T - k) / J1 * m["lockup_time_s"]
    assert m["min_engine_speed_rpm"] == pytest.approx(w_lock * 30.0 / math.pi, rel=1e-8)


def test_no_lockup_gives_none() -> None:
    k = 10.0  # too weak: the slip grows
    res = run(k, t_end=0.5)
    m = metrics(res)
    assert m["lockup_time_s"] is None
    assert m["lurch_m_s2"] is None
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
        "max_vehicle_jerk_m_s3",
        "lurch_m_s2",
        "min_engine_speed_rpm",
        "peak_axle_torque_Nm",
        "peak_shaft_torque_Nm",
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
        return (*out[:-1], 3)  # the last output: the count of inconsistent decisions

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
