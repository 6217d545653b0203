"""One run as data: a Case is picklable, runs to a flat record, and is the path the CLI takes."""

from __future__ import annotations

import json
import pickle

import pytest

from drivetrain_ctrl.cli import main
from drivetrain_ctrl.sim.simulator import ZenoError
from drivetrain_ctrl.studies import case as case_mod
from drivetrain_ctrl.studies.case import Case, CaseError, run_case, simulate_case


def test_a_case_pickles_and_compares_by_value() -> None:
    c = Case(
        scenario="paper-start", model="reduced", controller="pi", overrides={"vehicle.M_v": 1400.0}
    )
    again = pickle.loads(pickle.dumps(c))
    assert again == c and again.overrides == {"vehicle.M_v": 1400.0}


def test_run_case_gives_a_flat_record_and_overrides_reach_the_run() -> None:
    base = run_case(Case(scenario="engage-ramp", model="reduced", label="base"))
    heavy = run_case(
        Case(scenario="engage-ramp", model="reduced", overrides={"vehicle.M_v": 2000.0}, label="h")
    )
    for rec in (base, heavy):
        assert rec["status"] == "ok" and rec["scenario"] == "engage-ramp"
        assert rec["model"] == "reduced" and rec["controller"] is None
        assert all(not isinstance(v, dict) for v in rec.values()), rec
    assert heavy["param:vehicle.M_v"] == 2000.0 and "param:vehicle.M_v" not in base
    assert base["label"] == "base" and heavy["label"] == "h"
    # a heavier car takes longer to pull up to the engine: the clutch locks later
    assert heavy["lockup_time_s"] > base["lockup_time_s"] + 0.01


def test_closed_loop_case_records_the_controller_name() -> None:
    rec = run_case(Case(scenario="paper-start", model="reduced", controller="paper", t_end=1.0))
    assert rec["controller"] == "paper" and rec["t_end_s"] == 1.0


@pytest.mark.parametrize(
    ("kw", "msg"),
    [
        ({"model": "medium"}, "model = 'medium'"),
        ({"rtol": -1.0}, "rtol = -1.0"),
        ({"overrides": {"vehicle.Mv": 1.0}}, "vehicle.Mv"),
        ({"scenario": "paper-strat"}, "paper-strat"),
        ({"scenario": "paper-start"}, "needs a controller"),
        ({"controller": "paper"}, "open loop"),
        ({"controller": "nope"}, "nope"),
        ({"t_end": 0.05, "scenario": "paper-start", "controller": "paper"}, "t_end = 0.05"),
        ({"loop": "half"}, "loop = 'half'"),
        ({"loop": True}, "loop = True"),
        (
            {"loop": "closed", "controller": "paper"},
            "loop = 'closed': scenario 'engage-ramp' has no",
        ),
        ({"scenario": "paper-start", "loop": "closed"}, "needs a controller"),
        ({"scenario": "paper-start"}, "or loop = 'open' for its open-loop pedal"),
        ({"scenario": "paper-start", "loop": "open", "controller": "pi"}, "loop = 'open' runs"),
    ],
)
def test_bad_cases_are_rejected_naming_the_field(kw: dict, msg: str) -> None:
    args = {"scenario": "engage-ramp", "model": "reduced", **kw}
    with pytest.raises(CaseError, match=msg.replace(".", r"\.").replace("(", r"\(")):
        simulate_case(Case(**args))


def test_a_failed_run_is_a_record_not_an_exception(monkeypatch: pytest.MonkeyPatch) -> None:
    def zeno(case: Case, **kw: object) -> None:
        raise ZenoError("50 mode changes within 1e-06 s at t = 0.1 s")

    monkeypatch.setattr(case_mod, "simulate_case", zeno)
    rec = run_case(Case(scenario="engage-ramp", overrides={"vehicle.M_v": 1.0e3}, label="s7"))
    assert rec["status"] == "failed" and "mode changes" in rec["error"]
    assert rec["label"] == "s7" and rec["param:vehicle.M_v"] == 1.0e3
    # the same identity columns as a record of a run that finished
    ok = run_case(Case(scenario="engage-ramp", model="reduced"))
    assert {"label", "scenario", "parameter_set", "controller", "model"} <= set(rec) & set(ok)
    assert rec["parameter_set"] == "passenger-car" and rec["controller"] is None


def test_the_cli_and_run_case_give_the_same_metrics(tmp_path) -> None:
    assert (
        main(
            ["simulate", "--scenario", "engage-ramp", "--model", "reduced", "--out", str(tmp_path)]
        )
        == 0
    )
    cli = json.loads((tmp_path / "metrics.json").read_text())
    rec = run_case(Case(scenario="engage-ramp", model="reduced"))
    for k in ("lockup_time_s", "clutch_energy_J", "n_events", "n_samples", "energy_residual_rel"):
        assert cli[k] == rec[k], k


def test_the_loop_of_a_case_chooses_the_part_of_the_scenario() -> None:
    """paper-start has both parts: loop "open" runs its pedal signal (no controller, no
    reference), the default its controller; the CLI's --loop is the same case."""
    own = simulate_case(Case(scenario="paper-start", model="reduced", controller="paper"))
    closed = simulate_case(
        Case(scenario="paper-start", model="reduced", controller="paper", loop="closed")
    )
    op = simulate_case(Case(scenario="paper-start", model="reduced", loop="open"))
    assert own.metrics == closed.metrics and own.record()["loop"] == "closed"
    assert op.record()["loop"] == "open" and op.controller is None and op.spec is None
    assert op.scenario.reference is None and op.metrics["tracking_rms_rpm"] is None
    ip = op.result.model.input_names.index("pedal")
    pedal = op.result.u[:, ip]
    sig = op.scenario.input_signals()["pedal"]
    assert pedal == pytest.approx([float(sig(t)) for t in op.result.t], abs=1e-15)
    assert op.metrics["lockup_time_s"] != closed.metrics["lockup_time_s"]
    assert Case(scenario="paper-start", loop="open") != Case(scenario="paper-start")


def test_the_cli_runs_the_open_loop(tmp_path) -> None:  # type: ignore[no-untyped-def]
    args = ["simulate", "--scenario", "hill-start", "--model", "reduced", "--loop", "open"]
    assert main([*args, "--out", str(tmp_path)]) == 0
    cli = json.loads((tmp_path / "metrics.json").read_text())
    rec = run_case(Case(scenario="hill-start", model="reduced", loop="open"))
    assert cli["loop"] == rec["loop"] == "open" and cli["controller"] is None
    for k in ("lockup_time_s", "clutch_energy_J", "rollback_m", "energy_residual_rel"):
        assert cli[k] == rec[k], k
