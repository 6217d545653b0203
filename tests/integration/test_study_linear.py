"""Paired linear figures per study row (issue 23 item 4) and the per-case caches (item 6): a
row's ``lin:`` values equal a direct computation at that sample's parameters; a record with the
caches equals one without them."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from drivetrain_ctrl.core.serialize import json_ready
from drivetrain_ctrl.linear.clutch import _judder_threshold, clutch_loop, judder_crossing
from drivetrain_ctrl.linear.margins import _auto_grid, loop_margins
from drivetrain_ctrl.linear.operating_point import (
    SLIP_DELAY_S,
    operating_point_from_result,
    slip_point_after_start,
)
from drivetrain_ctrl.plant.params import load_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.studies import case as case_mod
from drivetrain_ctrl.studies.case import (
    LINEAR_FIGURES,
    LINEAR_GRID_POINTS,
    LINEAR_JUDDER_RTOL,
    Case,
    caching,
    clear_caches,
    linear_figures,
    run_case,
    simulate_case,
)
from drivetrain_ctrl.studies.runner import run_chunk
from drivetrain_ctrl.studies.study import Study, StudyError, sample_table

STUDY: dict[str, Any] = {
    "study": {
        "name": "lin",
        "model": "reduced",
        "params": "passenger-car",
        "controllers": ["paper", "pi"],
        "scenarios": ["paper-start"],
        "metrics": ["lockup_time_s", "jerk_max_m_s3"],
        "criteria": ["lockup_time_s <= 3.0"],
        "t_end": 2.0,
    },
    "sampling": {"method": "lhs", "samples": 2, "seed": 5},
    "parameters": {
        "clutch.k12_max": {"dist": "uniform", "low": 200.0, "high": 300.0},
        "actuator.omega_a": {"dist": "loguniform", "low": 100.0, "high": 400.0},
    },
}


def _rows(study: Study) -> list[dict[str, Any]]:
    df = sample_table(study)
    items, cases = [], []
    for i in range(study.samples):
        vals = {str(k): float(v) for k, v in df.iloc[i].items()}
        for c in study.controller_names:
            case = study.case(i, vals, c, 0)
            items.append((case.label, i, c, study.scenario_names[0], vals))
            cases.append(case)
    return run_chunk(items, cases, study.metrics, study.criteria, run_case, study.linear)


def _direct(values: dict[str, float], controller: str) -> dict[str, float | None]:
    """The linear figures computed here from the library's pieces, not through the case."""
    p = load_params("passenger-car").replace(**values)
    sc = load_scenario("paper-start", params=p)
    dt = sc.drivetrain(p, kind="reduced")
    ctrl = sc.make_controller(dt, controller)
    res = run_scenario(sc, dt, controller=ctrl, t_end=2.0)
    op = slip_point_after_start(res, dt, sc.start_time)
    assert op.t == pytest.approx(sc.start_time + SLIP_DELAY_S)
    cl = clutch_loop(op, ctrl)
    m = loop_margins(cl.L, omega=list(_auto_grid(cl.L, n=LINEAR_GRID_POINTS)))
    jt = _judder_threshold(cl.op, cl.engine, cl.L)
    assert jt.mu_slope_crit < 0  # the closed form applies here (reduced, continuous)
    mu = cl.engine.mu_slope_torque / cl.engine.k13
    # the numeric threshold agrees with the closed form (a check of the pair, not of the row)
    jc = judder_crossing(op, ctrl, rtol=LINEAR_JUDDER_RTOL)
    assert jc.mu_slope_crit == pytest.approx(jt.mu_slope_crit, rel=0.05)
    assert m.gain_margin_db is not None
    return {
        "lin:gain_margin": 10 ** (m.gain_margin_db / 20),
        "lin:phase_margin_deg": m.phase_margin_deg,
        "lin:disk_margin": m.disk_margin,
        "lin:Ms": m.ms,
        "lin:judder_margin": 1.0 - mu / jt.mu_slope_crit,
        "lin:mu_slope_crit": jt.mu_slope_crit,
        "lin:crossover_rad_s": m.crossover_rad_s,
    }


def test_a_rows_linear_figures_equal_a_direct_computation_at_its_parameters() -> None:
    study = Study.from_dict(STUDY)
    rows = _rows(study)
    assert len(rows) == 4
    df = sample_table(study)
    seen: dict[str, list[float]] = {k: [] for k in LINEAR_FIGURES}
    for row in rows:
        assert row["status"] == "ok", row["error"]
        assert set(LINEAR_FIGURES) <= set(row) and "judder: closed form" in row["linear_note"]
        vals = {str(k): float(v) for k, v in df.iloc[row["sample"]].items()}
        want = _direct(vals, row["controller"])
        for k, v in want.items():
            assert row[k] == json_ready(v), k  # the record's numbers are rounded so
        assert row["lin:stable"] == 1.0 and 1.0 < row["lin:Ms"] < 2.0
        for k in LINEAR_FIGURES:
            seen[k].append(row[k])
    # the figures depend on the sample (capacity, actuator bandwidth) and the controller
    assert len(set(seen["lin:Ms"])) == 4 and len(set(seen["lin:mu_slope_crit"])) == 4


def test_linear_figures_can_be_switched_off_and_are_in_the_digest() -> None:
    d = {**STUDY, "study": {**STUDY["study"], "linear": False}}
    off = Study.from_dict(d)
    assert not off.linear and Study.from_dict(STUDY).linear
    assert off.digest != Study.from_dict(STUDY).digest
    rows = _rows(dataclasses.replace(off, parameters=off.parameters))
    assert not any(k.startswith("lin:") for k in rows[0]) and "linear_note" not in rows[0]
    bad = {**STUDY, "study": {**STUDY["study"], "linear": "yes"}}
    with pytest.raises(StudyError, match=r"study\.linear = 'yes'"):
        Study.from_dict(bad)


def test_no_slip_point_gives_undefined_figures_with_the_reason() -> None:
    run = simulate_case(Case(scenario="paper-start", model="reduced", controller="paper"))
    # the controller starts at 0.5 s; a start after the run's end leaves no slip sample after it
    figs = linear_figures(run.result, run.drivetrain, run.controller, start=float(run.result.t[-1]))
    assert all(figs[k] is None for k in LINEAR_FIGURES)
    assert "never slips" in figs["linear_note"]
    assert linear_figures(run.result, run.drivetrain, None, start=0.5)["linear_note"].startswith(
        "open loop"
    )


def test_a_rising_closed_form_threshold_is_not_used_as_a_judder_margin(monkeypatch: Any) -> None:
    """The closed form can return a positive critical slope (a real crossing at rising friction);
    the record then carries the numeric falling-side threshold and says so."""
    real = case_mod._judder_threshold

    def rising(op: Any, es: Any, L: Any) -> Any:
        jt = real(op, es, L)
        return dataclasses.replace(jt, c_crit=0.5, mu_slope_crit=0.5 / jt.k13, which="dc")

    monkeypatch.setattr(case_mod, "_judder_threshold", rising)
    run = simulate_case(
        Case(scenario="paper-start", model="reduced", controller="paper", linear=True)
    )
    lin = run.linear
    assert lin is not None
    assert "rising-friction (dc) crossing" in lin["linear_note"] and "numeric" in lin["linear_note"]
    op = slip_point_after_start(run.result, run.drivetrain, run.scenario.start_time)
    jc = judder_crossing(op, run.controller, rtol=LINEAR_JUDDER_RTOL)
    assert jc.mu_slope_crit is not None and jc.mu_slope_crit < 0
    assert lin["lin:mu_slope_crit"] == jc.mu_slope_crit
    assert lin["lin:judder_margin"] == pytest.approx(1.0 - lin["lin:mu_slope"] / jc.mu_slope_crit)


def test_the_slip_point_falls_back_to_the_first_slipping_sample() -> None:
    run = simulate_case(Case(scenario="paper-start", model="reduced", controller="paper"))
    res, start = run.result, run.scenario.start_time
    op = slip_point_after_start(res, run.drivetrain, start, delay=100.0)  # the end: locked
    assert operating_point_from_result(res, float(res.t[-1])).clutch_mode == "stuck"
    first = next(
        float(t)
        for t in res.t
        if t > start
        and operating_point_from_result(res, float(t)).clutch_mode in ("slip+", "slip-")
    )
    assert op.t == first and op.clutch_mode in ("slip+", "slip-")


def _case(**kw: Any) -> Case:
    base: dict[str, Any] = dict(
        scenario="worn-clutch",
        params="passenger-car",
        overrides={"vehicle.M_v": 1350.0, "clutch.k12_max": 240.0},
        model="full",
        controller="pi",
        t_end=2.0,
        linear=True,
    )
    return Case(**{**base, **kw})


def test_a_record_with_the_caches_equals_one_without(tmp_path: Path) -> None:
    f = tmp_path / "s.toml"
    f.write_text(
        (Path(case_mod.__file__).parents[1] / "scenarios" / "builtin" / "paper-start.toml")
        .read_text()
        .replace('name = "paper-start"', 'name = "mine"')
    )
    cases = [
        _case(),
        _case(controller="paper"),  # the same sample's next controller: its drivetrain is kept
        _case(scenario=f, model="reduced", overrides={"vehicle.M_v": 1200.0}),
        _case(scenario=f, model="reduced", overrides={"vehicle.M_v": 1250.0}),
    ]
    with caching(False):
        clear_caches()
        plain = [run_case(c) for c in cases]
    assert not any(c.data for c in case_mod._CACHES.values())
    with caching(True):
        clear_caches()
        first = [run_case(c) for c in cases]
        again = [run_case(c) for c in cases]  # every piece now from the caches
    assert case_mod._CACHES["scenario"].data and case_mod._CACHES["drivetrain"].data
    for a, b, c in zip(plain, first, again, strict=True):
        assert a == b == c
        assert a["status"] == "ok" and a["lin:Ms"] is not None
    # a changed scenario file is read again (its key holds the time of change and the size)
    f.write_text(f.read_text().replace("slope_percent = 0.0", "slope_percent = 8.0"))
    steep = run_case(cases[2])
    with caching(False):
        assert run_case(cases[2]) == steep != first[2]


def test_invalid_input_fails_the_same_with_the_caches_filled() -> None:
    """An invalid parameter value (a negative mass) fails with the same message whether the
    scenario and drivetrain of an earlier case are kept or not."""
    bad = _case(overrides={"vehicle.M_v": -5.0}, linear=False)
    with caching(False):
        with pytest.raises(ValueError) as plain:
            run_case(bad)
    with caching(True):
        run_case(_case(linear=False))
        with pytest.raises(ValueError) as kept:
            run_case(bad)
    assert str(plain.value) == str(kept.value) and "M_v" in str(kept.value)


def test_linear_figure_names_are_documented() -> None:
    doc = (Path(__file__).parents[2] / "docs" / "studies.md").read_text()
    for k in LINEAR_FIGURES:
        assert f"`{k}`" in doc, k
    assert "linear_note" in doc


def test_a_failing_linear_analysis_keeps_the_runs_metrics(monkeypatch: Any) -> None:
    def broken(*a: Any, **k: Any) -> Any:
        raise RuntimeError("no loop today")

    monkeypatch.setattr(case_mod, "clutch_loop_gain", broken)
    rec = run_case(Case(scenario="paper-start", model="reduced", controller="pi", linear=True))
    assert rec["status"] == "ok" and rec["lockup_time_s"] is not None
    assert all(rec[k] is None for k in LINEAR_FIGURES if k != "lin:t_s")
    assert rec["linear_note"] == "no linear figures: RuntimeError: no loop today"
