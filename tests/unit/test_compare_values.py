"""Value tests of :mod:`drivetrain_ctrl.studies.compare` (issue 22 item 4: mutation score): the
criteria against the documented limits, the verdict's ratios, score and reasoning text, the
linear-against-nonlinear statement, what a run did after its slip point (hand-built runs), the
option checks, the plant-set sources and their cost, the assembly of ``data`` by
:func:`compare` (its Dask step replaced by canned records, in process), the Dask step itself on
an in-process client, :meth:`Comparison.plot`'s dispatch and, on one real run of the reduced
model (pi on paper-start), the time responses, lock point, slip-loop figures, Bode data, later
slip points and certified sector, each checked against a computation written out here."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from drivetrain_ctrl.studies import compare as cm
from drivetrain_ctrl.studies.compare import CompareError

RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)
OK = {"lockup": True, "no_stall": True, "jerk": True, "rollback": None}


# -- criteria (docs/compare.md's table) ------------------------------------------------------------
def _crit_rec(**metrics: Any) -> dict[str, Any]:
    m = {"lockup_time_s": 2.0, "engine_stalled": False, "jerk_max_m_s3": 10.0, "rollback_m": 0.0}
    m.update(metrics)
    return {"status": "ok", "horizon_s": 4.0, "metrics": m}


GRADE: Any = SimpleNamespace(slope=0.12)
FLAT: Any = SimpleNamespace(slope=0.0)


def test_criteria_follow_the_documented_limits() -> None:
    """jerk <= 25 m/s^3, roll-back <= 0.05 m on a grade only, lock-up within the horizon, no
    stall; a run that does not end ok passes none."""
    assert cm._criteria(_crit_rec(), GRADE) == {
        "lockup": True,
        "no_stall": True,
        "jerk": True,
        "rollback": True,
    }
    assert cm._criteria(_crit_rec(rollback_m=0.049), GRADE)["rollback"] is True
    assert cm._criteria(_crit_rec(rollback_m=0.05), GRADE)["rollback"] is True
    assert cm._criteria(_crit_rec(rollback_m=0.051), GRADE)["rollback"] is False
    assert cm._criteria(_crit_rec(rollback_m=0.07), GRADE)["rollback"] is False
    assert cm._criteria(_crit_rec(rollback_m=None), GRADE)["rollback"] is False
    assert cm._criteria(_crit_rec(rollback_m=1.0), FLAT)["rollback"] is None  # flat: n/a
    assert cm._criteria(_crit_rec(jerk_max_m_s3=25.0), FLAT)["jerk"] is True
    assert cm._criteria(_crit_rec(jerk_max_m_s3=25.01), FLAT)["jerk"] is False
    assert cm._criteria(_crit_rec(jerk_max_m_s3=30.0), FLAT)["jerk"] is False
    assert cm._criteria(_crit_rec(jerk_max_m_s3=None), FLAT)["jerk"] is False
    assert cm._criteria(_crit_rec(lockup_time_s=4.0), FLAT)["lockup"] is True  # at the horizon
    assert cm._criteria(_crit_rec(lockup_time_s=4.001), FLAT)["lockup"] is False
    assert cm._criteria(_crit_rec(lockup_time_s=None), FLAT)["lockup"] is False
    assert cm._criteria(_crit_rec(engine_stalled=True), FLAT)["no_stall"] is False
    assert cm._criteria(_crit_rec(engine_stalled=None), FLAT)["no_stall"] is False
    failed = {**_crit_rec(), "status": "failed"}
    assert cm._criteria(failed, GRADE) == dict.fromkeys(
        ("lockup", "no_stall", "jerk", "rollback"), False
    )
    assert cm.JERK_LIMIT_M_S3 == 25.0 and cm.ROLLBACK_LIMIT_M == 0.05


# -- the verdict ------------------------------------------------------------------------------------
def _run(eng: float | None, jerk: float | None, crit: dict[str, bool | None]) -> dict[str, Any]:
    return {
        "metrics": {"engagement_time_s": eng, "jerk_max_m_s3": jerk, "tracking_rms_rpm": None},
        "criteria": crit,
    }


def test_verdict_ratios_score_and_reasoning_text() -> None:
    """Ratios to the best valid value per scenario (capped at 3, undefined or non-finite: 3),
    averaged over scenarios; score = weighted mean; the reasoning line of each rank in full."""
    runs = {
        ("a", "s1"): _run(1.0, 10.0, OK),
        ("a", "s2"): _run(2.0, 10.0, OK),
        ("b", "s1"): _run(2.0, 10.0, OK),
        ("b", "s2"): _run(4.0, 10.0, OK),
        ("c", "s1"): _run(2.0, 10.0, OK),
        ("c", "s2"): _run(4.0, 10.0, OK),
        ("d", "s1"): _run(1.0, float("nan"), {**OK, "jerk": False}),
        ("d", "s2"): _run(10.0, 10.0, OK),
    }
    nominal = {c: {"slip": {"ms": 1.5}} for c in "abcd"}
    nominal["b"] = {"slip": {"ms": 3.0}}
    nominal["c"] = {"slip": {"ms": 1.5}}
    w = {"engagement_time_s": 1.0, "jerk_max_m_s3": 2.0, "ms": 1.0}
    v = cm._verdict(["a", "b", "c", "d"], ["s1", "s2"], runs, nominal, w)
    rows = {r["controller"]: r for r in v["ranking"]}
    # by hand: best engagement 1.0 on s1, 2.0 on s2; jerk best 10 (d's nan counts as 3); ms 1.5
    assert rows["a"]["mean_ratio"] == {"engagement_time_s": 1.0, "jerk_max_m_s3": 1.0, "ms": 1.0}
    assert rows["b"]["mean_ratio"] == {"engagement_time_s": 2.0, "jerk_max_m_s3": 1.0, "ms": 2.0}
    assert rows["d"]["mean_ratio"] == {"engagement_time_s": 2.0, "jerk_max_m_s3": 2.0, "ms": 1.0}
    assert rows["a"]["score"] == pytest.approx(1.0)
    assert rows["b"]["score"] == pytest.approx((2.0 + 2 * 1.0 + 2.0) / 4)
    assert rows["c"]["score"] == pytest.approx((2.0 + 2 * 1.0 + 1.0) / 4)
    assert rows["d"]["score"] == pytest.approx((2.0 + 2 * 2.0 + 1.0) / 4)
    assert [r["controller"] for r in v["ranking"]] == ["a", "c", "b", "d"]
    assert [r["rank"] for r in v["ranking"]] == [1, 2, 3, 4]
    assert (rows["d"]["criteria_passed"], rows["d"]["criteria_applicable"]) == (5, 6)
    assert rows["d"]["failed"] == ["jerk on s1"]
    assert v["reasoning"] == [
        "#1 a: 6/6 criteria passed; score 1.000 = (1 x 1.000 (engagement_time_s) + "
        "2 x 1.000 (jerk_max_m_s3) + 1 x 1.000 (ms)) / 4",
        "#2 c: 6/6 criteria passed; score 1.250 = (1 x 2.000 (engagement_time_s) + "
        "2 x 1.000 (jerk_max_m_s3) + 1 x 1.000 (ms)) / 4; below a: same criteria passed, "
        "higher score",
        "#3 b: 6/6 criteria passed; score 1.500 = (1 x 2.000 (engagement_time_s) + "
        "2 x 1.000 (jerk_max_m_s3) + 1 x 2.000 (ms)) / 4; below c: same criteria passed, "
        "higher score",
        "#4 d: 5/6 criteria passed (failed: jerk on s1); score 1.750 = (1 x 2.000 "
        "(engagement_time_s) + 2 x 2.000 (jerk_max_m_s3) + 1 x 1.000 (ms)) / 4; below b: fewer "
        "criteria passed",
    ]


def test_verdict_ties_by_name_and_undefined_best() -> None:
    """Equal criteria and score: by name, said so; a key no valid controller has a positive
    value of counts 1 for a defined value and the cap for an undefined one."""
    runs = {(c, "s"): _run(None, 0.0, OK) for c in ("y", "x")}
    runs[("z", "s")] = _run(None, None, OK)
    nominal: dict[str, Any] = {"x": {"slip": {"ms": 2.0}}, "y": {"slip": {"ms": 2.0}}, "z": {}}
    w = {"engagement_time_s": 1.0, "jerk_max_m_s3": 1.0, "ms": 0.0}
    v = cm._verdict(["y", "x", "z"], ["s"], runs, nominal, w)
    rows = {r["controller"]: r for r in v["ranking"]}
    assert rows["x"]["mean_ratio"] == {"engagement_time_s": 3.0, "jerk_max_m_s3": 1.0, "ms": 1.0}
    assert rows["z"]["mean_ratio"] == {"engagement_time_s": 3.0, "jerk_max_m_s3": 3.0, "ms": 3.0}
    assert rows["x"]["score"] == pytest.approx(2.0) and rows["z"]["score"] == pytest.approx(3.0)
    assert [r["controller"] for r in v["ranking"]] == ["x", "y", "z"]
    assert v["reasoning"][1].endswith("; below x: tie, by name")
    assert v["reasoning"][2].endswith("; below y: same criteria passed, higher score")
    assert v["reasoning"][0].startswith("#1 x: 3/3 criteria passed; score 2.000 = (")


def test_score_ratio_is_capped_at_three() -> None:
    runs = {("a", "s"): _run(1.0, 1.0, OK), ("b", "s"): _run(2.9, 7.0, OK)}
    nominal = {"a": {"slip": {"ms": 1.0}}, "b": {"slip": {"ms": math.inf}}}
    s = cm._score(["a", "b"], ["s"], runs, nominal, dict(cm.WEIGHTS))
    assert s["b"]["mean_ratio"]["engagement_time_s"] == pytest.approx(2.9)
    assert s["b"]["mean_ratio"]["jerk_max_m_s3"] == 3.0  # 7 x the best
    assert s["b"]["mean_ratio"]["ms"] == 3.0  # an infinite Ms counts as undefined
    assert s["b"]["mean_ratio"]["tracking_rms_rpm"] == 3.0  # undefined for both: the cap
    assert s["b"]["score"] == pytest.approx((2.9 + 4 * 3.0) / 5)
    assert cm.RATIO_CAP == 3.0


def test_default_weights_are_the_documented_keys_with_one_each() -> None:
    assert cm.WEIGHTS == {
        "engagement_time_s": 1.0,
        "clutch_energy_J": 1.0,
        "jerk_max_m_s3": 1.0,
        "tracking_rms_rpm": 1.0,
        "ms": 1.0,
    }


# -- linear against nonlinear -----------------------------------------------------------------------
def _agree(stable: bool, later: list[dict[str, Any]], crit: dict[str, Any], **obs: Any) -> Any:
    observed = {"lock_up_s": None, "sign_switch": False, "saturation": False, "drift": False}
    observed.update(obs)
    rec = {"linear": {"slip": {"stable": stable, "later_points": later}}, "observed": observed}
    return cm._agreement(rec, crit)


def test_agreement_statements() -> None:
    p_ok = {"stable": True, "t_s": 1.2, "slip_speed_rad_s": 80.0}
    p_none = {"stable": None, "t_s": None}
    p_bad = {"stable": False, "t_s": 1.9005, "slip_speed_rad_s": 32.83}
    a = _agree(True, [p_ok, p_ok, p_none], OK, lock_up_s=2.44684)
    assert a == {
        "disagree": False,
        "linear_stable": True,
        "nonlinear_engages": True,
        "causes": [],
        "statement": "linear slip loop stable at the slip point and at 2 later one(s) (a good "
        "engagement); the switching plant engages (locks up, no stall): they agree.",
    }
    a = _agree(False, [p_ok], OK, lock_up_s=2.44684)
    assert a["disagree"] is True and a["linear_stable"] is False
    assert a["statement"] == (
        "linear slip loop unstable at the slip point; the switching plant engages (locks up, "
        "no stall): they disagree; seen in the run: lock-up at 2.447 s."
    )
    a = _agree(True, [p_ok, p_bad], {**OK, "lockup": False})
    assert a["disagree"] is False and a["linear_stable"] is False
    assert a["statement"] == (
        "linear slip loop unstable later in the slip phase, at t = 1.9 s (slip 32.8 rad/s); "
        "the switching plant does not engage well: they agree."
    )
    a = _agree(True, [], {**OK, "no_stall": False})
    assert a["disagree"] is True and a["causes"] == []
    assert a["statement"].endswith(": they disagree; seen in the run: no mode change.")
    a = cm._agreement({"linear": {"slip": {"stable": None}, "slip_reason": None}}, OK)
    assert a == {
        "disagree": None,
        "causes": [],
        "statement": "no linear prediction: no stability verdict.",
    }


# -- what the run did after the slip point (hand-built runs) ------------------------------------------
class _Res:
    def __init__(self, t: list[float], slip: list[float], modes: list[str], pedal: list[float]):
        self.t = np.asarray(t, dtype=float)
        self._x = {
            "omega_engine": 100.0 + np.asarray(slip),
            "omega_primary": np.full(len(t), 100.0),
        }
        self._modes = modes
        self.u = np.column_stack([np.zeros(len(t)), np.asarray(pedal), np.zeros(len(t))])
        self.model = SimpleNamespace(
            input_names=("throttle", "pedal", "brake"),
            state_names=("omega_engine", "omega_primary", "v_vehicle"),
        )

    def state(self, name: str) -> Any:
        return self._x[name]

    def mode_series(self, element: str) -> list[str]:
        assert element == "clutch"
        return self._modes


def _fake_run(res: _Res, lockup: float | None = None) -> Any:
    act = SimpleNamespace(x_min=0.0, x_max=0.12)
    return SimpleNamespace(
        result=res,
        metrics={"lockup_time_s": lockup},
        drivetrain=SimpleNamespace(params=SimpleNamespace(actuator=act)),
        scenario=SimpleNamespace(start_time=0.5),
    )


T5 = [0.0, 1.0, 1.2, 1.5, 2.0]


def test_observed_drift_is_more_than_a_quarter_within_the_window() -> None:
    """Slip 4 rad/s at the slip point (t = 1 s), 5 rad/s over [1.2, 1.5] s, so 5 at 1.3 s:
    exactly 25 % is no drift ("more than"); 5.2 is 30 %."""
    modes = ["stuck", "slip+", "slip+", "slip+", "slip+"]
    res = _Res(T5, [0.0, 4.0, 5.0, 5.0, 1.0], modes, [0.05] * 5)
    o = cm._observed(_fake_run(res, lockup=1.9), 1.0)
    assert o == {
        "lock_up_s": 1.9,
        "sign_switch": False,
        "saturation": False,
        "drift_rel": 0.25,
        "drift": False,
    }
    res = _Res(T5, [0.0, 4.0, 5.2, 5.2, 1.0], modes, [0.05] * 5)
    o = cm._observed(_fake_run(res), 1.0)
    assert o["drift_rel"] == pytest.approx(0.3) and o["drift"] is True
    # the slip falls: the relative change is a magnitude
    res = _Res(T5, [0.0, 4.0, 2.0, 2.0, 1.0], modes, [0.05] * 5)
    assert cm._observed(_fake_run(res), 1.0)["drift_rel"] == pytest.approx(0.5)
    # the window ends at the run's end: t = 1.5 s + 0.3 s is beyond it
    res = _Res([0.0, 1.0, 1.5, 1.6], [0.0, 4.0, 4.5, 6.0], modes[:4], [0.05] * 4)
    assert cm._observed(_fake_run(res), 1.5)["drift_rel"] == pytest.approx(1.5 / 4.5)


def test_observed_sign_switch_and_saturation() -> None:
    res = _Res(
        T5, [5.0, 4.0, -1.0, 0.0, 0.0], ["slip-", "slip+", "slip-", "stuck", "stuck"], [0.05] * 5
    )
    o = cm._observed(_fake_run(res), 1.0)
    assert o["sign_switch"] is True
    # the slip- before the slip point does not count
    res = _Res(
        T5, [5.0, 4.0, 1.0, 0.0, 0.0], ["slip-", "slip+", "slip+", "stuck", "stuck"], [0.05] * 5
    )
    assert cm._observed(_fake_run(res), 1.0)["sign_switch"] is False
    # stuck at the slip point: no slip sign to switch from
    res = _Res(
        T5, [0.0, 0.0, 1.0, -1.0, 0.0], ["stuck", "stuck", "slip+", "slip-", "stuck"], [0.05] * 5
    )
    assert cm._observed(_fake_run(res), 1.0)["sign_switch"] is False
    # the pedal at a stroke limit (within 1e-9 m) after the slip point: saturation
    slip = [5.0, 4.0, 3.0, 2.0, 1.0]
    m = ["slip+"] * 5
    for pedal, sat in (
        ([0.05, 0.05, 0.12, 0.05, 0.05], True),
        ([0.05, 0.05, 0.05, 0.12 - 5e-10, 0.05], True),
        ([0.05, 0.05, 0.05, 0.12 - 1e-6, 0.05], False),
        ([0.05, 0.05, 0.0, 0.05, 0.05], True),
        ([0.05, 0.05, 0.05, 5e-10, 0.05], True),
        ([0.05, 0.05, 0.05, 1e-6, 0.05], False),
        ([0.12, 0.0, 0.05, 0.05, 0.05], False),  # before the slip point
    ):
        assert cm._observed(_fake_run(_Res(T5, slip, m, pedal)), 1.2)["saturation"] is sat, pedal


def test_observed_without_a_slip_point_starts_at_the_controller_start() -> None:
    res = _Res(
        T5,
        [5.0, 4.0, 1.0, 0.0, 0.0],
        ["slip+", "slip-", "slip+", "stuck", "stuck"],
        [0.12] + [0.05] * 4,
    )
    o = cm._observed(_fake_run(res), None)  # from t >= 0.5 s: slip-, slip+
    assert o["sign_switch"] is True and o["saturation"] is False
    assert o["drift_rel"] is None and o["drift"] is False


# -- options -------------------------------------------------------------------------------------
def test_check_weights() -> None:
    assert cm._check_weights(None) == cm.WEIGHTS and cm._check_weights(None) is not cm.WEIGHTS
    w = cm._check_weights({"ms": 2, "jerk_max_m_s3": 0.0})
    assert w == {**cm.WEIGHTS, "ms": 2.0, "jerk_max_m_s3": 0.0}
    assert isinstance(w["ms"], float)
    for bad, needle in (
        ({"ms": True}, "weights['ms'] = True"),
        ({"ms": math.inf}, "weights['ms'] = inf"),
        ({"ms": math.nan}, "weights['ms'] = nan"),
        ({"ms": -0.5}, "weights['ms'] = -0.5"),
        ({"ms": "1"}, "weights['ms'] = '1'"),
        ({"speed": 1.0}, "unknown key 'speed'"),
        ([("ms", 1.0)], "must map score keys to numbers"),
        (dict.fromkeys(cm.WEIGHTS, 0), "at least one must be > 0"),
    ):
        with pytest.raises(CompareError) as exc:
            cm._check_weights(bad)  # type: ignore[arg-type]
        assert needle in str(exc.value), (bad, str(exc.value))
    assert cm._check_weights({"ms": 1e300})["ms"] == 1e300


def test_split() -> None:
    assert cm._split(None, "x") == []
    assert cm._split(" a, b ,,c ", "x") == ["a", "b", "c"]
    assert cm._split(["a", Path("b.toml")], "x") == ["a", Path("b.toml")]
    assert cm._split(("a",), "x") == ["a"]
    with pytest.raises(CompareError, match=r"controllers = \[\]: empty"):
        cm._split([], "controllers")
    with pytest.raises(CompareError, match="scenarios = ' , ': empty"):
        cm._split(" , ", "scenarios")
    with pytest.raises(CompareError, match="give names or files"):
        cm._split(["a", 3], "controllers")  # type: ignore[list-item]
    with pytest.raises(CompareError, match="give names or files"):
        cm._split(5, "controllers")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kw", "needle"),
    [
        ({"n_series": 1}, "n_series = 1:"),
        ({"n_series": 2.5}, "n_series = 2.5:"),
        ({"n_series": True}, "n_series = True:"),
        ({"t_end": True}, "t_end = True:"),
        ({"t_end": 0.0}, "t_end = 0.0:"),
        ({"t_end": math.inf}, "t_end = inf:"),
        ({"t_end": "2"}, "t_end = '2':"),
        ({"client": object(), "workers": 1}, "give a client or workers, not both"),
        ({"design_checks": 1}, "design_checks = 1: must be True or False"),
        ({"certificate": None}, "certificate = None: must be True or False"),
        ({"open_loop": "yes"}, "open_loop = 'yes': must be True or False"),
        ({"params": "/no/such/dir/params.toml"}, "file not found: /no/such/dir/params.toml"),
        ({"params": 3.5}, "params = 3.5: give a parameter set's name, a TOML file or a"),
        ({"params": None}, "params = None: give a parameter set's name"),
        ({"params": "no-such-set"}, "params = 'no-such-set': unknown parameter set"),
        ({"scenarios": ["engage-ramp"], "controllers": "pi"}, "no valid scenario"),
    ],
)
def test_bad_options_are_named_before_anything_runs(kw: dict[str, Any], needle: str) -> None:
    """Each invalid option raises CompareError naming it (an unknown controller beside it: a
    check that let the option through would fail on that instead, with another message)."""
    kw = {"controllers": "no-such-controller", "scenarios": "paper-start", **kw}
    with pytest.raises(CompareError) as exc:
        cm.compare(**kw)
    assert needle in str(exc.value), str(exc.value)


def test_valid_edge_options_pass_the_checks() -> None:
    """n_series = 2, a tiny t_end and no weights get past the checks to the controllers."""
    for kw in ({"n_series": 2}, {"t_end": 1e-3}, {"t_end": 3}, {"weights": None}):
        with pytest.raises(CompareError, match="no valid controller"):
            cm.compare(controllers="no-such-controller", scenarios="paper-start", **kw)


# -- plant sets ------------------------------------------------------------------------------------
def test_plants_of_names_where_the_plant_set_comes_from() -> None:
    from drivetrain_ctrl.control.laws import load_controller
    from drivetrain_ctrl.design.from_spec import load_design_spec

    kw, where = cm._plants_of(load_controller("robust-pi"))
    assert where == "the controller file's design spec ([design.spec.plants])"
    assert kw["scenario"] == "paper-start" and kw["times"] == 3 and "box" in kw
    default = dict(load_design_spec("robust-pi").plants)
    kw, where = cm._plants_of(load_controller("paper"))
    assert kw == default
    assert where == (
        "no design spec in the controller file: the default plant set (the plants of the "
        "built-in design spec 'robust-pi')"
    )
    kw, where = cm._plants_of(load_controller("pi-10ms"))
    assert kw == {**default, "sample_period": 0.01, "delay_samples": 1}
    assert where.endswith(
        "'robust-pi'), sampled every 0.01 s with 1 sample(s) of delay as the controller"
    )


def test_design_check_of_a_plant_set_that_cannot_be_built() -> None:
    from drivetrain_ctrl.control.laws import load_controller

    specs = [load_controller("paper"), load_controller("pi")]
    tic = time.perf_counter()
    out = cm.design_check(specs, {"no_such_keyword": 1})
    elapsed = time.perf_counter() - tic
    assert set(out) == {"paper", "pi"}
    for rec in out.values():
        assert rec["reason"].startswith("plant set not built: TypeError")
        assert 0.0 <= rec["seconds"] <= elapsed / 2
    assert out["paper"]["seconds"] == out["pi"]["seconds"]


def test_design_check_shares_the_build_time_among_its_controllers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The plant set's cost is split evenly: one controller carries all of it, two half each
    (a plant set whose build takes at least 0.2 s and then fails)."""
    import drivetrain_ctrl.design.clutch as dc
    from drivetrain_ctrl.control.laws import load_controller

    def slow_failure(**kw: Any) -> Any:
        time.sleep(0.2)
        raise ValueError("no plants")

    monkeypatch.setattr(dc, "clutch_plant_set", slow_failure)
    tic = time.perf_counter()
    one = cm.design_check([load_controller("pi")], {})
    elapsed = time.perf_counter() - tic
    assert one["pi"]["reason"] == "plant set not built: ValueError: no plants"
    assert 0.2 <= one["pi"]["seconds"] <= elapsed
    tic = time.perf_counter()
    two = cm.design_check([load_controller("paper"), load_controller("pi")], {})
    elapsed = time.perf_counter() - tic
    assert 0.1 <= two["paper"]["seconds"] == two["pi"]["seconds"] <= elapsed / 2


def test_plot_draws_the_figures_or_writes_the_report_with_its_pdf(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """plot(): the figures of the data; plot(out): the report written there, with its PDF
    unless pdf=False (the reporting functions replaced by recorders)."""
    import drivetrain_ctrl.reporting.compare_report as rep

    calls: list[tuple[Any, ...]] = []

    def figures(data: Any) -> int:
        calls.append(("figs", data))
        return 1

    def write(data: Any, out: Any, *, pdf: bool = True) -> int:
        calls.append(("write", data, out, pdf))
        return 2

    monkeypatch.setattr(rep, "compare_figures", figures)
    monkeypatch.setattr(rep, "write_compare_report", write)
    data = {"verdict": {"ranking": []}, "invalid": []}
    c = cm.Comparison(data, 1.0, 1, {})
    assert c.plot() == 1 and c.plot(tmp_path) == 2 and c.plot(tmp_path, pdf=False) == 2
    assert calls == [
        ("figs", data),
        ("write", data, tmp_path, True),
        ("write", data, tmp_path, False),
    ]


# -- the assembly of data by compare(), its Dask step replaced ---------------------------------------
#: made-up metrics and nominal slip-loop figures per controller
_METRICS = {
    "paper": {"engagement_time_s": 2.0, "jerk_max_m_s3": 10.0, "ms": 1.2, "stable": True},
    "pi": {"engagement_time_s": 1.0, "jerk_max_m_s3": 20.0, "ms": 1.5, "stable": True},
    "robust-pi": {"engagement_time_s": 1.5, "jerk_max_m_s3": 12.0, "ms": 1.4, "stable": True},
    "robust-pi-b": {"engagement_time_s": 1.5, "jerk_max_m_s3": 12.0, "ms": 1.4, "stable": True},
    "hinf": {"engagement_time_s": 1.0, "jerk_max_m_s3": 5.0, "ms": 9.0, "stable": False},
    "pi-10ms": {"engagement_time_s": 1.1, "jerk_max_m_s3": 20.0, "ms": 1.6, "stable": True},
}


def _canned_case(
    controller: Any, scenario: Any, params: Any, model: str, **kw: Any
) -> dict[str, Any]:
    name = controller.name if controller is not None else None
    m = _METRICS.get(name or "", {"engagement_time_s": 3.0, "jerk_max_m_s3": 40.0})
    rec: dict[str, Any] = {
        "controller": name,
        "scenario": scenario.name,
        "loop": "closed" if controller is not None else "open",
        "status": "ok",
        "error": None,
        "horizon_s": kw.get("t_end") or scenario.t_end,
        "metrics": {
            "status": "ok",
            "lockup_time_s": 1.0,
            "engine_stalled": False,
            "engagement_time_s": m["engagement_time_s"],
            "jerk_max_m_s3": m["jerk_max_m_s3"],
            "rollback_m": 0.01,
        },
        "series": {"t_s": [0.0, 1.0]},
        "kw": dict(kw),
    }
    if controller is None:
        return rec
    slip = {"stable": m["stable"], "ms": m["ms"], "later_points": [], "operating_point": {}}
    lin: dict[str, Any] = {"slip": slip, "slip_reason": None, "lock": None, "lock_reason": "x"}
    if kw.get("certificate"):
        lin["certificate_s"] = 0.25
    rec["linear"] = lin
    rec["observed"] = {"lock_up_s": 1.0}
    return rec


def _canned_design(specs: Any, plants: Any) -> dict[str, dict[str, Any]]:
    return {s.name: {"plant_set": "canned", "reason": None, "seconds": 0.5} for s in specs}


class _FakeDask:
    """Replaces compare's ``_run_all``: records the tasks, runs canned functions in process."""

    def __init__(self) -> None:
        self.tasks: list[tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]] = []

    def __call__(
        self, tasks: Any, *, client: Any, workers: Any, progress: bool
    ) -> tuple[list[Any], int, dict[str, float]]:
        self.tasks = list(tasks)
        out = []
        for fn, args, kw in tasks:
            if fn is cm.design_check:
                out.append(_canned_design(*args, **kw))
            else:
                assert fn is cm.compare_case
                out.append(_canned_case(*args, **kw))
        return out, 3, {"startup_s": 0.1, "runs_s": 0.2, "shutdown_s": 0.0}


@pytest.fixture
def fake_dask(monkeypatch: pytest.MonkeyPatch) -> _FakeDask:
    fake = _FakeDask()
    monkeypatch.setattr(cm, "_run_all", fake)
    return fake


def test_compare_assembles_data_from_the_task_results(fake_dask: _FakeDask) -> None:
    """Two scenarios without the nominal one: each controller gets one extra nominal-only run
    (Bode data, certificate) whose figures are its nominal ones and which is not in ``runs``;
    an unstable nominal loop is left out of the ranking; the baseline gets its criteria; the
    costs go to the timing and not to data."""
    warned: list[str] = []
    tic = time.perf_counter()
    res = cm.compare(
        controllers="paper,pi,hinf,paper",
        scenarios="hill-start,judder",
        model="reduced",
        weights={"ms": 2.0},
        warn=warned.append,
        design_checks=False,
    )
    assert 0 < res.wall_s <= time.perf_counter() - tic
    cases = [(fn, a, kw) for fn, a, kw in fake_dask.tasks if fn is cm.compare_case]
    assert len(fake_dask.tasks) == len(cases) == 3 * 3 + 2  # no design checks
    closed = [(a[0].name, a[1].name, kw) for _, a, kw in cases if a[0] is not None]
    assert [(c, s) for c, s, _ in closed] == [
        (c, s) for c in ("paper", "pi", "hinf") for s in ("hill-start", "judder", "paper-start")
    ]
    for _, s, kw in closed:
        if s == "paper-start":
            assert kw == {"t_end": None, "bode": True, "certificate": True}
        else:
            assert kw == {
                "t_end": None,
                "n_series": cm.N_SERIES,
                "bode": False,
                "certificate": False,
            }
    opened = [(a[1].name, kw) for _, a, kw in cases if a[0] is None]
    assert opened == [
        (s, {"t_end": None, "n_series": cm.N_SERIES}) for s in ("hill-start", "judder")
    ]
    assert all(a[3] == "reduced" for _, a, _ in cases)
    d = res.data
    assert d["invalid"] == [
        {
            "kind": "controller",
            "name": "paper",
            "reason": "a second controller named 'paper' (names must differ)",
        },
        {
            "kind": "controller",
            "name": "hinf",
            "reason": "unstable on the nominal slip loop (paper-start)",
        },
    ]
    assert warned == [
        "controller 'paper' left out: a second controller named 'paper' (names must differ)",
        "controller 'hinf' left out: unstable on the nominal slip loop (paper-start)",
    ]
    assert res.problems == [f"controller {p['name']!r}: {p['reason']}" for p in d["invalid"]]
    assert d["valid"] == ["paper", "pi"] and d["inputs"]["controllers"] == ["paper", "pi", "hinf"]
    assert d["inputs"]["scenarios"] == ["hill-start", "judder"]
    assert d["inputs"]["weights"] == {**cm.WEIGHTS, "ms": 2.0}
    assert set(d["runs"]["pi"]) == {"hill-start", "judder"}  # the nominal-only run is not a run
    assert d["nominal_linear"]["pi"]["slip"]["ms"] == 1.5
    assert d["nominal_linear"]["pi"]["status"] == "ok"
    assert d["nominal_linear"]["hinf"]["slip"]["stable"] is False
    rec = d["runs"]["paper"]["hill-start"]
    assert rec["criteria"] == {"lockup": True, "no_stall": True, "jerk": True, "rollback": True}
    assert d["runs"]["paper"]["judder"]["criteria"]["rollback"] is None
    assert rec["linear_vs_nonlinear"]["disagree"] is False
    # the baseline: judged, not ranked
    assert set(d["open_loop"]) == {"hill-start", "judder"}
    assert d["open_loop"]["judder"]["criteria"]["jerk"] is False  # 40 m/s^3
    # ratios by hand: paper: engagement 2, energy 3 (undefined for all), jerk 1, tracking 3,
    # ms 1; pi: 1, 3, 2, 3, 1.25; weights 1, 1, 1, 1, 2
    assert res.ranking == ["paper", "pi"]
    rows = {r["controller"]: r for r in d["verdict"]["ranking"]}
    assert rows["paper"]["score"] == pytest.approx((2 + 3 + 1 + 3 + 2 * 1.0) / 6)
    assert rows["pi"]["score"] == pytest.approx((1 + 3 + 2 + 3 + 2 * 1.25) / 6)
    assert res.timing["certificate_s"] == pytest.approx(3 * 0.25)
    assert res.timing["design_checks_s"] == 0.0 and res.workers == 3
    text = json.dumps(d)
    assert '"certificate_s"' not in text and '"seconds"' not in text
    assert d["design"]["pi"] == {
        "method": None,
        "plant_set_source": None,
        "reason": "not checked (design_checks=False)",
        "recorded": None,
    }


def test_compare_with_the_nominal_scenario_runs_it_once(fake_dask: _FakeDask) -> None:
    """The nominal scenario among the scenarios: its run carries the Bode data and the
    certificate (certificate=False: not), no extra run; no baseline with open_loop=False; t_end
    and n_series are passed on."""
    res = cm.compare(
        controllers=["pi"],
        scenarios="judder,paper-start",
        t_end=2.0,
        n_series=7,
        design_checks=False,
        certificate=False,
        open_loop=False,
    )
    kws = {a[1].name: kw for _, a, kw in fake_dask.tasks}
    assert len(fake_dask.tasks) == 2
    assert kws["paper-start"] == {"t_end": 2.0, "n_series": 7, "bode": True, "certificate": False}
    assert kws["judder"] == {"t_end": 2.0, "n_series": 7, "bode": False, "certificate": False}
    assert res.data["open_loop"] == {}
    assert set(res.data["runs"]["pi"]) == {"judder", "paper-start"}
    assert res.data["runs"]["pi"]["paper-start"]["horizon_s"] == 2.0
    assert res.timing["certificate_s"] == 0.0


def test_compare_builds_each_distinct_plant_set_once(fake_dask: _FakeDask, tmp_path: Path) -> None:
    """robust-pi and a copy whose [design.spec.plants] lists the same plants in another order
    share one design-check task; pi-10ms (no design spec, sampled) gets the default set
    sampled as the controller: a task of its own."""
    import tomli_w

    from drivetrain_ctrl.control.laws import load_controller

    d = load_controller("robust-pi").to_dict()
    d["name"] = "robust-pi-b"
    plants = d["design"]["spec"]["plants"]
    d["design"]["spec"]["plants"] = dict(reversed(list(plants.items())))
    f = tmp_path / "robust-pi-b.toml"
    f.write_bytes(tomli_w.dumps(d).encode())
    assert list(load_controller(f).to_dict()["design"]["spec"]["plants"]) != list(plants)
    res = cm.compare(
        controllers=["robust-pi", f, "pi-10ms"],
        scenarios="paper-start",
        open_loop=False,
        certificate=False,
    )
    checks = [a for fn, a, _ in fake_dask.tasks if fn is cm.design_check]
    assert [[s.name for s in group] for group, _ in checks] == [
        ["robust-pi", "robust-pi-b"],
        ["pi-10ms"],
    ]
    assert checks[1][1]["sample_period"] == 0.01
    assert fake_dask.tasks[0][0] is cm.design_check  # the design checks first
    assert res.timing["design_checks_s"] == pytest.approx(3 * 0.5)
    des = res.data["design"]
    assert des["robust-pi"]["reason"] is None and des["robust-pi"]["method"] == "robust-pi"
    assert des["robust-pi"]["recorded"]["ms_max"] == 1.39985
    assert des["robust-pi"]["recorded"]["n_plants"] == 51
    assert des["pi-10ms"]["recorded"] is None
    assert des["pi-10ms"]["plant_set_source"].startswith("no design spec in the controller file")


def test_comparison_properties() -> None:
    data = {
        "verdict": {"ranking": [{"controller": "b"}, {"controller": "a"}]},
        "invalid": [{"kind": "scenario", "name": "x", "reason": "does not load"}],
    }
    c = cm.Comparison(data, 1.0, 2, {})
    assert c.ranking == ["b", "a"] and c.problems == ["scenario 'x': does not load"]


# -- one real run: pi on paper-start, reduced model -------------------------------------------------
@pytest.fixture(scope="module")
def run() -> Any:
    from drivetrain_ctrl.studies.case import Case, simulate_case

    return simulate_case(Case(scenario="paper-start", model="reduced", controller="pi"))


@pytest.fixture(scope="module")
def linear(run: Any) -> tuple[dict[str, Any], float]:
    tic = time.perf_counter()
    lin = cm._linear(run, True, True)
    return lin, time.perf_counter() - tic


def test_series_on_the_common_grid(run: Any) -> None:
    res = run.result
    ser = cm._series(run, 4.0, 9)
    grid = np.linspace(0.0, 4.0, 9)
    assert ser["t_s"] == pytest.approx(grid.tolist(), abs=0)
    s = res.sample(grid)
    assert ser["omega_engine_rpm"] == pytest.approx(s.state("omega_engine") * RPM_PER_RAD_S)
    assert ser["omega_primary_rpm"] == pytest.approx(s.state("omega_primary") * RPM_PER_RAD_S)
    ref = run.scenario.reference
    assert ser["omega_ref_rpm"] == pytest.approx(np.asarray(ref(grid), dtype=float) * RPM_PER_RAD_S)
    ip = res.model.input_names.index("pedal")
    assert ser["pedal_mm"] == pytest.approx(1000.0 * np.asarray(s.u)[:, ip])
    # the vehicle acceleration integrates to the speed's change (trapezoid on a fine grid)
    fine = cm._series(run, 4.0, 801)
    acc, t = np.asarray(fine["vehicle_accel_m_s2"]), np.asarray(fine["t_s"])
    dv = float(np.sum(0.5 * (acc[1:] + acc[:-1]) * np.diff(t)))
    v = res.sample([0.0, 4.0]).state("v_vehicle")
    assert dv == pytest.approx(float(v[1] - v[0]), rel=2e-2) and dv > 0
    # the clutch torque: zero while the clutch is open (before the start), positive when locked
    tq = np.asarray(fine["clutch_torque_Nm"])
    assert np.all(tq[t < 0.4] == 0.0) and tq[-1] > 0
    # beyond the run: the grid is cut at its end
    short = cm._series(run, 5.0, 6)
    assert short["t_s"] == pytest.approx([0.0, 1.0, 2.0, 3.0, 4.0])
    assert len(short["pedal_mm"]) == 5


def test_lock_point_is_half_a_second_after_lock_up(run: Any) -> None:
    lock_t = run.metrics["lockup_time_s"]
    lk, reason = cm._lock(run)
    assert reason == cm._LOCK_REASON and "loop is open" in reason
    assert lk is not None and lk["t_s"] == pytest.approx(lock_t + 0.5, abs=1e-12)
    assert lk["shuffle_modes"] and all(m["natural_frequency_hz"] > 0 for m in lk["shuffle_modes"])
    assert 0 < lk["clutch_breakaway_margin_Nm"] < lk["clutch_capacity_Nm"]
    # no lock-up: no lock point, said so
    nolock = replace(run, metrics={"lockup_time_s": None})
    lk, reason = cm._lock(nolock)
    assert lk is None and reason.endswith("; no lock-up in the run: no lock point")
    # lock-up late in the run: the lock point is the run's end
    late = replace(run, metrics={"lockup_time_s": 3.8})
    lk, _ = cm._lock(late)
    assert lk is not None and lk["t_s"] == float(run.result.t_last) == 4.0
    # the "lock-up" at a time the clutch slips: no lock point, said so
    early = replace(run, metrics={"lockup_time_s": 0.6})
    lk, reason = cm._lock(early)
    assert lk is None and "the clutch slips again at t = 1.1 s: no lock point" in reason


def test_slip_loop_figures_bode_and_certificate(
    run: Any, linear: tuple[dict[str, Any], float]
) -> None:
    from drivetrain_ctrl.linear.clutch import clutch_loop
    from drivetrain_ctrl.linear.operating_point import slip_point_after_start

    lin, elapsed = linear
    slip = lin["slip"]
    assert lin["slip_reason"] is None and slip is not None
    op = slip_point_after_start(run.result, run.drivetrain, 0.5)
    we, wp = op.state("omega_engine"), op.state("omega_primary")
    assert op.t == pytest.approx(0.8)
    assert slip["operating_point"]["t_s"] == pytest.approx(0.8, abs=1e-12)
    assert slip["operating_point"]["clutch_mode"] == "slip+"
    assert slip["operating_point"]["slip_speed_rad_s"] == pytest.approx(we - wp, rel=1e-9)
    assert slip["operating_point"]["omega_engine_rpm"] == pytest.approx(we * RPM_PER_RAD_S)
    assert slip["stable"] is True and slip["ms"] > 1.0
    assert all(p[0] < 0 for p in slip["closed_loop_poles"])
    # Bode: 200 log-spaced points from 0.1 to 10^2.4 rad/s; L and S = 1/(1 + L) evaluated here
    b = slip["bode"]
    w = np.asarray(b["omega_rad_s"])
    assert len(w) == 200 and w[0] == pytest.approx(0.1) and w[-1] == pytest.approx(10**2.4)
    assert np.allclose(np.diff(np.log10(w)), 3.4 / 199)
    L = clutch_loop(op, run.controller).L
    for k in range(0, 200, 33):
        h = complex(L(1j * w[k]))
        assert b["L_db"][k] == pytest.approx(20 * math.log10(abs(h)), abs=1e-9)
        assert b["S_db"][k] == pytest.approx(-20 * math.log10(abs(1 + h)), abs=1e-9)
        ph = math.radians(b["L_deg"][k])
        assert complex(math.cos(ph), math.sin(ph)) == pytest.approx(h / abs(h), abs=1e-9)
    # the certified sector: [0, -k13 mu'] with mu' inside the linear limit; its cost
    cert = slip["certificate"]
    mu = cert["mu_slope_certified"]
    assert cert["reason"] is None and cert["mu_slope_linear"] < mu < 0
    assert cert["sector_N_m_s_rad"] == [0.0, pytest.approx(-cert["k13"] * mu)]
    assert cert["sector_N_m_s_rad"][1] > 0
    assert 0 < lin["certificate_s"] < elapsed


def test_later_slip_points_are_the_first_samples_below_the_fractions(
    run: Any, linear: tuple[dict[str, Any], float]
) -> None:
    """At 0.5, 0.2 and 0.05 of the slip speed at the slip point: the first sample after it at
    which the clutch slips and the slip speed is that low (docs/compare.md)."""
    res = run.result
    slip = linear[0]["slip"]
    t = np.asarray(res.t)
    sl = res.state("omega_engine") - res.state("omega_primary")
    modes = res.mode_series("clutch")
    at = res.sample([slip["operating_point"]["t_s"]])
    s0 = abs(float(at.state("omega_engine")[0] - at.state("omega_primary")[0]))
    later = slip["later_points"]
    assert [p["fraction"] for p in later] == [0.5, 0.2, 0.05]
    for p in later:
        k = next(
            i
            for i in range(len(t))
            if t[i] > 0.8 and modes[i] in ("slip+", "slip-") and abs(sl[i]) <= p["fraction"] * s0
        )
        assert p["t_s"] == t[k]
        assert p["slip_speed_rad_s"] == pytest.approx(sl[k], rel=1e-9)
        assert p["slip_speed_rad_s"] > 0 and p["stable"] is True and p["ms"] >= 1.0
        assert p["max_real_pole"] < 0
    assert later[0]["t_s"] < later[1]["t_s"] < later[2]["t_s"]


def test_no_slip_loop_in_open_loop_and_none_without_certificate_or_bode(run: Any) -> None:
    opened = replace(run, controller=None)
    out = cm._linear(opened, True, True)
    assert out["slip"] is None and out["slip_reason"] == "open loop: no clutch loop"
    assert out["lock"] is not None and "certificate_s" not in out
    plain = cm._linear(run, False)
    assert "bode" not in plain["slip"] and "certificate" not in plain["slip"]
    assert "certificate_s" not in plain


def test_certificate_failure_is_a_reason() -> None:
    tic = time.perf_counter()
    out, cost = cm._certificate(None, None)
    elapsed = time.perf_counter() - tic
    assert out["mu_slope_certified"] is None and out["reason"].startswith("no certificate: ")
    assert 0 <= cost <= elapsed


def test_compare_case_closed_and_open(run: Any) -> None:
    """One case as a worker runs it: the record's fields; t_end sets the horizon and the grid;
    the open loop has no linear figures."""
    from drivetrain_ctrl.plant.params import DEFAULT_SET, load_params

    p = load_params(DEFAULT_SET)
    rec = cm.compare_case(run.spec, run.scenario, p, "reduced", t_end=2.0, n_series=5)
    assert (rec["controller"], rec["scenario"], rec["loop"]) == ("pi", "paper-start", "closed")
    assert rec["status"] == "ok" and rec["error"] is None and rec["horizon_s"] == 2.0
    assert rec["series"]["t_s"] == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert rec["linear"]["slip"]["operating_point"]["t_s"] == pytest.approx(0.8)
    assert rec["observed"]["drift_rel"] is not None
    full = cm.compare_case(run.spec, run.scenario, p, "reduced", n_series=3)
    assert full["horizon_s"] == 4.0 and full["series"]["t_s"] == [0.0, 2.0, 4.0]
    assert "bode" not in full["linear"]["slip"] and "certificate" not in full["linear"]["slip"]
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    sc = load_scenario("paper-start", params=p)
    rec = cm.compare_case(None, sc, p, "reduced", t_end=1.0, n_series=3)
    assert (rec["controller"], rec["loop"], rec["status"]) == (None, "open", "ok")
    assert "linear" not in rec and "observed" not in rec
    assert rec["series"]["t_s"] == [0.0, 0.5, 1.0] and "omega_ref_rpm" not in rec["series"]


# -- the Dask step ---------------------------------------------------------------------------------
def _add(a: int, b: int, *, c: int = 0) -> int:
    return a + b + c


def test_run_all_gives_the_results_in_task_order_with_a_progress_bar(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """On a given client (one in-process worker): the results in the order of the tasks, the
    number of workers, the run time within the elapsed time, and a progress bar counting the
    tasks."""
    from dask.distributed import Client

    tasks: list[tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]] = [
        (_add, (1, 2), {}),
        (_add, (3, 4), {"c": 1}),
        (_add, (0, 0), {}),
    ]
    with Client(
        processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None
    ) as client:
        tic = time.perf_counter()
        out, n, timing = cm._run_all(tasks, client=client, workers=None, progress=True)
        elapsed = time.perf_counter() - tic
        assert client.status == "running"  # a given client is left open
    assert out == [3, 8, 0] and n == 1
    assert 0 <= timing["startup_s"] and 0 <= timing["runs_s"] <= elapsed - timing["startup_s"]
    err = capsys.readouterr().err
    assert "3/3" in err and "6/3" not in err
    with Client(
        processes=False, n_workers=1, threads_per_worker=1, dashboard_address=None
    ) as client:
        cm._run_all(tasks[:1], client=client, workers=None, progress=False)
    assert "1/1" not in capsys.readouterr().err
