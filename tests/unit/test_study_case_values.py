"""Values of :mod:`drivetrain_ctrl.studies.case` that its other tests leave open (issue 22 item
4, mutation testing): what a record says about the run (tolerances, scenario fields, kernel load
time), the scenario cache's keys, the checks of a case's fields and of ``simulate_case``'s
arguments, a simulator failure inside ``simulate_case``, and the linear note.

The expected values are written out here or computed from the library's lower layers (the
parameter set, the scenario, the simulator), not through the case module's helpers."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from drivetrain_ctrl.linear.clutch import clutch_loop_gain
from drivetrain_ctrl.linear.margins import loop_margins
from drivetrain_ctrl.linear.operating_point import slip_point_after_start
from drivetrain_ctrl.plant.params import load_params
from drivetrain_ctrl.scenarios.scenario import load_scenario
from drivetrain_ctrl.sim.simulator import SimulationOptions, ZenoError
from drivetrain_ctrl.studies import case as case_mod
from drivetrain_ctrl.studies.case import (
    Case,
    CaseError,
    caching,
    clear_caches,
    linear_figures_at,
    run_case,
    simulate_case,
)

BUILTIN = Path(case_mod.__file__).parents[1] / "scenarios" / "builtin"


def _ramp(**kw: Any) -> Case:
    return Case(**{"scenario": "engage-ramp", "model": "reduced", **kw})


def test_the_record_carries_the_integrator_tolerances() -> None:
    default = run_case(_ramp())
    assert default["rtol"] == SimulationOptions().rtol == 1e-8
    assert default["atol"] == SimulationOptions().atol
    tight = run_case(_ramp(rtol=1e-9))
    assert tight["rtol"] == 1e-9 and tight["atol"] == default["atol"]
    assert tight["status"] == "ok"


def test_small_positive_tolerances_and_horizons_are_accepted() -> None:
    """``rtol`` and ``t_end`` must be > 0: values below 1 are the usual ones."""
    c = Case(scenario="engage-ramp", rtol=0.5e-8, t_end=0.9)
    assert c.rtol == 0.5e-8 and c.t_end == 0.9
    for bad in (0.0, -1e-9):
        with pytest.raises(CaseError, match=f"rtol = {bad!r}"):
            Case(scenario="engage-ramp", rtol=bad)


def test_a_scenario_override_reaches_the_run_and_the_record() -> None:
    base = simulate_case(_ramp())
    run = simulate_case(_ramp(scenario_overrides={"slope": 0.05}))
    assert run.scenario.slope == 0.05 and base.scenario.slope == 0.0
    rec = run.record()
    assert rec["param:scenario.slope"] == 0.05 and "param:scenario.slope" not in base.record()
    # uphill: the car needs more torque to move, it locks up later
    assert rec["lockup_time_s"] > base.record()["lockup_time_s"]
    with pytest.raises(CaseError, match="unknown scenario field 'slop'"):
        Case(scenario="engage-ramp", scenario_overrides={"slop": 0.05})
    with pytest.raises(CaseError, match=r"scenario_overrides = \[\('slope', 0\.05\)\]: must map"):
        Case(scenario="engage-ramp", scenario_overrides=[("slope", 0.05)])  # type: ignore[arg-type]
    with pytest.raises(CaseError, match=r"scenario_overrides\.slope = 'x'"):
        Case(scenario="engage-ramp", scenario_overrides={"slope": "x"})  # type: ignore[dict-item]


def test_a_label_must_be_text() -> None:
    with pytest.raises(CaseError, match="label = 3: must be a string"):
        Case(scenario="engage-ramp", label=3)  # type: ignore[arg-type]
    assert Case(scenario="engage-ramp", label="s1").label == "s1"


def test_from_dict_is_the_case_of_its_fields() -> None:
    d = {"scenario": "paper-start", "controller": "pi", "model": "reduced", "t_end": 1.0}
    assert Case.from_dict(d) == Case(
        scenario="paper-start", controller="pi", model="reduced", t_end=1.0
    )
    with pytest.raises(CaseError, match="modle"):
        Case.from_dict({"scenario": "paper-start", "modle": "reduced"})


def test_simulate_case_wants_a_case() -> None:
    with pytest.raises(TypeError, match="a Case is needed, got str"):
        simulate_case("engage-ramp")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="preload = 1"):
        simulate_case(_ramp(), preload=1)  # type: ignore[arg-type]


def test_kernel_load_time_is_zero_unless_preloaded() -> None:
    plain = simulate_case(_ramp())
    assert plain.kernel_load_s == 0.0
    pre = simulate_case(_ramp(), preload=True)
    assert 0.0 < pre.kernel_load_s < 600.0  # the kernels are loaded: a 1-ms run
    assert pre.metrics == plain.metrics  # the preload changes nothing of the run


def test_a_scenario_object_runs_like_its_name() -> None:
    p = load_params("passenger-car")
    sc = load_scenario("engage-ramp", params=p)
    with caching(True):
        by_obj = run_case(_ramp(scenario=sc))
        by_name = run_case(_ramp())
    assert by_obj == by_name and by_obj["scenario"] == "engage-ramp"


def test_two_scenario_files_are_kept_apart(tmp_path: Path) -> None:
    """The scenario cache's key of a file is the file (path, time of change, size): two files
    with different contents give their own scenarios, also with the cache filled."""
    text = (BUILTIN / "engage-ramp.toml").read_text()
    assert 'name = "engage-ramp"' in text
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(text.replace('name = "engage-ramp"', 'name = "ramp-a"'))
    b.write_text(text.replace('name = "engage-ramp"', 'name = "ramp-bb"'))
    with caching(True):
        clear_caches()
        ra = simulate_case(_ramp(scenario=a))
        rb = simulate_case(_ramp(scenario=b))
        again = simulate_case(_ramp(scenario=a))
    assert (ra.scenario.name, rb.scenario.name, again.scenario.name) == (
        "ramp-a",
        "ramp-bb",
        "ramp-a",
    )


def test_a_simulator_failure_inside_simulate_case_is_a_failed_record(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """simulate_case lets the simulator's ZenoError and RuntimeError through as they are;
    run_case turns them into a failed record."""

    def zeno(*a: Any, **k: Any) -> None:
        raise ZenoError("60 mode changes within 1e-06 s at t = 0.2 s")

    monkeypatch.setattr(case_mod, "run_scenario", zeno)
    with pytest.raises(ZenoError, match="60 mode changes"):
        simulate_case(_ramp())
    rec = run_case(_ramp(label="z"))
    assert rec["status"] == "failed" and rec["error"].startswith("60 mode changes")
    assert rec["label"] == "z" and rec["scenario"] == "engage-ramp"

    def step(*a: Any, **k: Any) -> None:
        raise RuntimeError("step size too small")

    monkeypatch.setattr(case_mod, "run_scenario", step)
    assert run_case(_ramp())["error"] == "step size too small"


def test_the_linear_note_keeps_the_margin_reasons_and_the_judder_tolerance() -> None:
    """The note names why a gain or phase margin or the disk margin is undefined (and no other
    figure's reason) and how the judder threshold was found, with its tolerance 1e-4."""
    run = simulate_case(Case(scenario="paper-start", model="reduced", controller="paper"))
    op = slip_point_after_start(run.result, run.drivetrain, run.scenario.start_time)
    assert run.controller is not None
    es, L = clutch_loop_gain(op, run.controller)
    m = loop_margins(L)
    m = dataclasses.replace(
        m,
        reasons=(
            ("gain_margin_db", "no phase crossover"),
            ("bandwidth_rad_s", "no bandwidth here"),
            ("disk_margin", "not on this grid"),
        ),
    )
    out = linear_figures_at(op, run.controller, es, L, m)
    note = out["linear_note"]
    assert note.startswith("gain_margin_db: no phase crossover; disk_margin: not on this grid; ")
    assert "bandwidth" not in note
    assert out["lin:t_s"] == op.t
    assert out["lin:mu_slope"] == es.mu_slope_torque / es.k13
    # the numeric threshold, forced by making the closed form unusable, names its tolerance
    full = simulate_case(Case(scenario="paper-start", model="full", controller="paper"))
    assert full.controller is not None
    op_f = slip_point_after_start(full.result, full.drivetrain, full.scenario.start_time)
    es_f, L_f = clutch_loop_gain(op_f, full.controller)
    out_f = linear_figures_at(op_f, full.controller, es_f, L_f, loop_margins(L_f))
    assert "numeric (judder_crossing, rtol 0.0001)" in out_f["linear_note"]
    assert "closed form" not in out_f["linear_note"]


def test_a_controller_on_an_open_loop_scenario_is_named() -> None:
    """The error names the ``controller`` field and its value, and says what to do instead."""
    with pytest.raises(CaseError) as exc:
        simulate_case(_ramp(controller="paper"))
    msg = str(exc.value)
    assert msg.startswith("controller = 'paper': scenario 'engage-ramp' is open loop")
    assert "drop the controller or use a closed-loop scenario (paper-start)" in msg


def test_a_loop_that_is_not_one_of_the_loops_is_refused_when_the_case_is_made() -> None:
    for bad in ("half", "Open", ""):
        with pytest.raises(CaseError, match=f"loop = {bad!r}: must be one of"):
            Case(scenario="paper-start", loop=bad)
    assert Case(scenario="paper-start", loop="open").loop == "open"


def test_a_table_override_and_the_judder_margin_of_a_falling_friction() -> None:
    """A friction table as an override (a dict: not hashable, so not kept in the parameter
    cache) reaches the run; with mu/mu0 falling at -0.001 s/rad the judder margin is
    1 - mu'/mu'_crit of the record's own slope and threshold."""
    table = {"x": [0.0, 500.0], "y": [1.0, 0.5]}
    case = Case(
        scenario="paper-start",
        model="reduced",
        controller="paper",
        overrides={"clutch.mu_table": table},
        linear=True,
    )
    with caching(True):
        run = simulate_case(case)
    assert run.drivetrain.params.clutch.mu_table.y[-1] == 0.5
    lin = run.linear
    assert lin is not None
    mu, crit = lin["lin:mu_slope"], lin["lin:mu_slope_crit"]
    assert mu == pytest.approx(-0.001, rel=1e-9)
    assert crit is not None and crit < 0.0
    assert lin["lin:judder_margin"] == 1.0 - mu / crit
    flat = simulate_case(Case(scenario="paper-start", model="reduced", controller="paper"))
    assert flat.drivetrain.params.clutch.mu_table.y[-1] == 1.0
