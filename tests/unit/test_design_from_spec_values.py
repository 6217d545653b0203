"""Values of :mod:`drivetrain_ctrl.design.from_spec` that the integration tests do not pin: the
spec's TOML form, the provenance's rounding, the controller file's period and delay, the summary
sentences and the switching check's problems (issue 22 item 4: mutation testing). Mostly without
a design; the expected values are written out here."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import control
import numpy as np
import pytest

from drivetrain_ctrl.control.laws import ControllerSpec
from drivetrain_ctrl.design import from_spec
from drivetrain_ctrl.design.from_spec import (
    STALL_SPEED_RPM,
    DesignRun,
    DesignSpec,
    DesignSpecError,
    PlantFigures,
    SwitchingCheck,
    SwitchingRun,
    check_on_switching_plant,
    design_from_spec,
    design_spec_from_dict,
    load_design_spec,
)

SMALL: dict[str, Any] = {
    "plants": {"controller": "pi", "times": 1, "box": {"clutch.k12_max": {"factor": [0.6, 1.4]}}},
    "design": {"ms": 1.4},
    "check": {"models": ["reduced"]},
}


def _row(name: str, ms: float, **kw: Any) -> PlantFigures:
    base: dict[str, Any] = {
        "plant": name,
        "ms": ms,
        "mt": 1.1,
        "ks": 0.5,
        "gain_margin_db": 8.0,
        "phase_margin_deg": 50.0,
        "crossover_rad_s": 3.0,
        "disk_margin_db": 5.0,
        "disk_margin_deg": 30.0,
        "stable": True,
    }
    base.update(kw)
    return PlantFigures(**base)


def _spec(**kw: Any) -> DesignSpec:
    return design_spec_from_dict({**SMALL, **kw})


# -- the spec's TOML form ------------------------------------------------------------------------


def test_to_dict_leaves_out_empty_entries_and_gives_plain_lists() -> None:
    spec = DesignSpec(
        name=None,
        description="",
        method="pi",
        plants={"box": {"x": (0.6, 1.4)}, 3: [(1, 2)]},  # type: ignore[dict-item]
        design={},
        controller={},
        check={"models": ("reduced",)},
    )
    d = spec.to_dict()
    assert d == {
        "method": "pi",
        "plants": {"box": {"x": [0.6, 1.4]}, "3": [[1, 2]]},
        "check": {"models": ["reduced"]},
    }
    assert type(d["plants"]["box"]["x"]) is list
    assert type(d["check"]["models"]) is list
    assert spec.source == "<dict>"
    full = design_spec_from_dict({"name": "n", "description": "d", **SMALL}, source="f.toml")
    assert full.to_dict() == {"name": "n", "description": "d", **SMALL}
    assert full.source == "f.toml"


def test_spec_fields_and_their_errors() -> None:
    spec = design_spec_from_dict({})
    assert spec.name is None and spec.description == "" and spec.method is None
    assert spec.plants == {} and spec.design == {} and spec.check == {}
    # without a method, [design] is not checked here (design_from_spec checks it)
    assert design_spec_from_dict({"design": {"anything": 1}}).design == {"anything": 1}
    with pytest.raises(DesignSpecError, match=r"^design spec = 3: must be a table"):
        design_spec_from_dict(3)  # type: ignore[arg-type]
    with pytest.raises(DesignSpecError, match=r"^name = 3: must be a non-empty string"):
        design_spec_from_dict({"name": 3})
    with pytest.raises(DesignSpecError, match=r"^name = '  ': must be a non-empty string"):
        design_spec_from_dict({"name": "  "})
    with pytest.raises(DesignSpecError, match=r"^description = 1: must be a string"):
        design_spec_from_dict({"description": 1})
    with pytest.raises(DesignSpecError, match=r"^check\.models = 'reduced': a non-empty list"):
        design_spec_from_dict({"check": {"models": "reduced"}})
    with pytest.raises(DesignSpecError, match=r"^check\.models = \[\]: a non-empty list"):
        design_spec_from_dict({"check": {"models": []}})
    with pytest.raises(DesignSpecError, match=r"^check\.models = 3: a non-empty list"):
        design_spec_from_dict({"check": {"models": 3}})
    with pytest.raises(DesignSpecError, match=r"^controller = 'x': must be a table"):
        design_spec_from_dict({"controller": "x"})
    # every method's keys
    for method in ("pi", "robust-pi", "pid", "hinf"):
        assert design_spec_from_dict({"method": method}).method == method
    assert design_spec_from_dict({"method": "pi", "design": {"nominal": 0, "wc": 2.0}}).design == {
        "nominal": 0,
        "wc": 2.0,
    }
    with pytest.raises(DesignSpecError, match=r"design\.plant: unknown key"):
        design_spec_from_dict({"method": "pi", "design": {"plant": 0}})
    with pytest.raises(DesignSpecError, match=r"design\.nominal: unknown key"):
        design_spec_from_dict({"method": "pid", "design": {"nominal": 0}})
    assert design_spec_from_dict({"method": "hinf", "design": {"nominal": 0}}).method == "hinf"
    assert design_spec_from_dict({"plants": {"sample_period": 0.01}}).plants == {
        "sample_period": 0.01
    }
    with pytest.raises(DesignSpecError, match=r"plants\.operating_points: unknown key"):
        design_spec_from_dict({"plants": {"operating_points": []}})


def test_load_design_spec_sources() -> None:
    spec = _spec()
    assert load_design_spec(spec) is spec
    assert load_design_spec(SMALL) == spec
    with pytest.raises(DesignSpecError, match=r"^spec = 3: give a built-in design spec name"):
        load_design_spec(3)  # type: ignore[arg-type]


# -- provenance, controller options, the PI file -------------------------------------------------


def test_provenance_rounds_to_six_digits_and_drops_none() -> None:
    spec = _spec(name="p")
    prov = from_spec._provenance(
        "robust-pi",
        spec,
        {
            "ki": 1.23456789,
            "hist": [0.1234567891, 2],
            "inner": {"a": None, "b": 9.87654321e-5},
            "gm": math.inf,
            "n": 7,
            "none": None,
        },
    )
    assert prov["method"] == "robust-pi" and prov["spec_file"] == "<dict>"
    assert prov["spec"] == spec.to_dict()
    assert prov["achieved"] == {
        "ki": 1.23457,
        "hist": [0.123457, 2],
        "inner": {"b": 9.87654e-5},
        "gm": math.inf,
        "n": 7,
    }


def test_controller_options_period_and_delay() -> None:
    spec = _spec(controller={"x_r0": 0.07, "form": "ss", "delay_samples": 2})
    assert from_spec._controller_options(spec, 0.01) == ({"x_r0": 0.07}, 2)
    with pytest.raises(DesignSpecError, match=r"^controller\.delay_samples = 2: the designed"):
        from_spec._controller_options(spec, 0.0)
    # continuous: no delay (an explicit 0 is fine)
    zero = _spec(controller={"delay_samples": 0})
    assert from_spec._controller_options(zero, 0.0) == ({}, 0)
    assert from_spec._controller_options(_spec(), 0.0) == ({}, 0)
    # sampled: [plants] delay_samples, else the [plants] controller's own, else paper's (0)
    sp = _spec(plants={"controller": "pi-10ms", "delay_samples": 3})
    assert from_spec._controller_options(sp, 0.01) == ({}, 3)
    sp = _spec(plants={"controller": "pi-10ms"})
    assert from_spec._controller_options(sp, 0.01) == ({}, 1)  # pi-10ms.toml: delay_samples = 1
    sp = _spec(plants={})
    assert from_spec._controller_options(sp, 0.01) == ({}, 0)  # paper: no delay
    # the spec's table is not changed
    assert spec.controller == {"x_r0": 0.07, "form": "ss", "delay_samples": 2}


def test_pi_controller_law() -> None:
    C = control.tf([0.02, 0.03], [1.0, 0.0])
    c = from_spec._pi_controller("a", 0.02, 0.03, 0.0, "continuous", C, None)
    assert (c.name, c.law, c.kp, c.ki, c.sample_period_s) == ("a", "pi", 0.02, 0.03, None)
    Cd = control.tf([0.02, -0.02 + 0.03 * 0.01], [1.0, -1.0], 0.01)
    c = from_spec._pi_controller("b", 0.02, 0.03, 0.01, "forward", Cd, None)
    assert (c.law, c.sample_period_s) == ("pi", 0.01)
    for integ, form, want in (
        ("backward", None, "tf"),
        ("forward", "ss", "ss"),
        ("tustin", "tf", "tf"),
    ):
        c = from_spec._pi_controller("c", 0.02, 0.03, 0.01, integ, Cd, form)
        assert c.law == "lti" and c.sample_period_s == 0.01
        assert (c.A is not None) == (want == "ss")
        w = np.array([0.5, 5.0, 50.0])
        np.testing.assert_allclose(
            c.lti().frequency_response(w).complex.reshape(-1),
            Cd.frequency_response(w).complex.reshape(-1),
            rtol=1e-12,
        )


def test_weights_become_transfer_functions() -> None:
    out = from_spec._weights("design.", {"W1": {"num": [1, 2], "den": [1, 3]}, "ms": 1.4})
    assert out["ms"] == 1.4 and "W2" not in out
    np.testing.assert_allclose(out["W1"].num[0][0], [1.0, 2.0])
    np.testing.assert_allclose(out["W1"].den[0][0], [1.0, 3.0])
    assert out["W1"].dt == 0
    out = from_spec._weights("design.", {"W3": {"num": [0.5], "den": [1.0, 10.0]}, "W2": None})
    np.testing.assert_allclose(out["W3"].num[0][0], [0.5])
    with pytest.raises(DesignSpecError, match=r"^design\.W2 = \{'num': \[1\]\}: give a weight"):
        from_spec._weights("design.", {"W2": {"num": [1]}})
    with pytest.raises(DesignSpecError, match=r"^design\.W1 = .*could not convert"):
        from_spec._weights("design.", {"W1": {"num": ["x"], "den": [1.0]}})


def test_check_method() -> None:
    for m in ("pi", "robust-pi", "pid", "hinf"):
        assert from_spec._check_method(m) == m
    with pytest.raises(DesignSpecError, match=r"^method = 'hinff'.*did you mean 'hinf'"):
        from_spec._check_method("hinff")


# -- the design run's figures and sentences ------------------------------------------------------


def test_mark_worst_ms_marks_the_first_largest() -> None:
    rows = [_row("a", 1.2), _row("b", 1.5), _row("c", 1.5), _row("d", 1.1, limiting=True)]
    out = from_spec._mark_worst_ms(rows)
    assert [r.limiting for r in out] == [False, True, False, False]
    assert [r.plant for r in out] == ["a", "b", "c", "d"]


def _run(rows: list[PlantFigures], met: bool, spec: DesignSpec | None = None) -> DesignRun:
    ctrl = ControllerSpec(name="c1", law="pi", kp=1.0, ki=1.0)
    return DesignRun("pi", spec or _spec(), None, None, ctrl, tuple(rows), met, "msg", 0.0)  # type: ignore[arg-type]


def test_design_run_worst_limiting_and_summary() -> None:
    rows = [
        _row("a", 1.2, ks=0.7, limiting=True),
        _row("b", 1.5, mt=1.3, gain_margin_db=6.25, phase_margin_deg=41.26, disk_margin_db=3.0),
    ]
    run = _run(rows, True)
    assert run.limiting == ("a",)
    w = run.worst()
    assert w["ks_max_m_s_rad"] == 0.7 and "ks_max" not in w
    assert (w["ms_max"], w["mt_max"], w["n_plants"]) == (1.5, 1.3, 2)
    assert run.summary() == (
        "pi design 'c1' on 2 plants: worst Ms 1.5, Mt 1.3, GM 6.2 dB, PM 41.3 deg, disk margin "
        "3.0 dB; all loops stable; limited by a; specification met: msg"
    )
    rows = [_row("a", 1.234, gain_margin_db=None, phase_margin_deg=None, stable=None)]
    assert _run(rows, False).summary() == (
        "pi design 'c1' on 1 plants: worst Ms 1.23, Mt 1.1, GM inf dB, PM - deg, disk margin "
        "5.0 dB; stability unchecked; limited by none; SPECIFICATION NOT MET: msg"
    )
    rows = [_row("a", 1.2, stable=False, limiting=True), _row("b", 1.2, limiting=True)]
    s = _run(rows, True).summary()
    assert "; UNSTABLE loop(s); limited by a, b; specification met" in s


def test_design_run_check_passes_the_spec_check_table(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[dict[str, Any]] = []

    def fake(controller: Any, **kw: Any) -> str:
        seen.append({"controller": controller, **kw})
        return "checked"

    monkeypatch.setattr(from_spec, "check_on_switching_plant", fake)
    run = _run([_row("a", 1.2)], True, _spec(plants={"params": "p1"}, check={}))
    assert run.check() == "checked"  # type: ignore[comparison-overlap]
    assert seen[-1] == {
        "controller": run.controller,
        "params": "p1",
        "scenario": "paper-start",
        "models": ("reduced", "full"),
    }
    sp = _spec(check={"params": "p2", "scenario": "s", "models": ["full"]})
    _run([_row("a", 1.2)], True, sp).check()
    assert seen[-1]["params"] == "p2" and seen[-1]["scenario"] == "s"
    assert seen[-1]["models"] == ("full",)


# -- the switching check's statements ------------------------------------------------------------


def test_problems_say_stall_and_no_lockup() -> None:
    assert from_spec._problems({"engine_speed_min_rpm": 800.0, "lockup_time_s": 2.0}) == []
    assert (
        from_spec._problems({"engine_speed_min_rpm": STALL_SPEED_RPM, "lockup_time_s": 2.0}) == []
    )
    assert from_spec._problems({"engine_speed_min_rpm": 449.6, "lockup_time_s": 2.0}) == [
        "the engine STALLED (lowest engine speed 450 rpm; a stall is below 450 rpm)"
    ]
    assert from_spec._problems(
        {"engine_speed_min_rpm": 900.0, "engine_stalled": True, "lockup_time_s": None}
    ) == [
        "the engine STALLED (lowest engine speed 900 rpm, its friction at standstill; a stall is "
        "below 450 rpm)",
        "the clutch NEVER LOCKED UP within the scenario",
    ]
    assert from_spec._problems({"lockup_time_s": 1.0}) == []
    assert STALL_SPEED_RPM == 450.0


def test_switching_check_ok_and_summary() -> None:
    good = SwitchingRun(
        "reduced",
        {"lockup_time_s": 2.345, "engine_speed_min_rpm": 812.4, "jerk_max_m_s3": 12.34},
        None,
        (),
    )
    bad = SwitchingRun("full", None, "boom", ("p1", "p2"))
    assert good.ok and not bad.ok and good.warnings == ()
    assert SwitchingCheck("c", "s", "p", (good,)).ok
    chk = SwitchingCheck("c", "s", "p", (good, bad))
    assert not chk.ok
    assert chk.summary() == (
        "controller 'c' on the switching plant (s, p): reduced model: locked up at 2.35 s, lowest "
        "engine speed 812 rpm, jerk 12.3 m/s^3; full model: p1; p2."
    )


def test_check_on_switching_plant_rejects_empty_models() -> None:
    with pytest.raises(DesignSpecError, match=r"^models = \[\]: a non-empty list"):
        check_on_switching_plant("pi", models=())
    with pytest.raises(DesignSpecError, match=r"^models = \['reduced', 'x'\]"):
        check_on_switching_plant("pi", models=("reduced", "x"))


# -- a design's nominal plant --------------------------------------------------------------------


@pytest.mark.parametrize("nominal", [True, -1, 3, 1.0])
def test_pi_nominal_must_be_an_index(nominal: Any) -> None:
    with pytest.raises(DesignSpecError, match=r"^design\.nominal = .*: an index of the 3 plants"):
        design_from_spec("pi", {**SMALL, "design": {"nominal": nominal}})


def test_pi_design_on_a_chosen_nominal_plant_is_that_plants_design() -> None:
    run = design_from_spec("pi", {**SMALL, "design": {"nominal": 2, "phase_margin": 60.0}})
    assert run.result.plant is run.plant_set[2]
    assert run.controller.name == "pi" and run.controller.law == "pi"
    assert run.controller.delay_samples == 0 and run.controller.sample_period_s is None
    assert run.met == run.result.feasible
    assert run.controller.design is not None
    ach = run.controller.design["achieved"]
    assert ach["kp"] == float(f"{run.result.kp:.6g}") and ach["met"] is run.met
    assert ach["limiting"] == list(run.limiting) and len(run.limiting) == 1
    assert ach["n_plants"] == 3 and ach["plant_set"] == run.plant_set.summary()
    # the default nominal plant is the first (one instant, continuous: every plant's delay 0)
    run0 = design_from_spec("pi", {**SMALL, "design": {"phase_margin": 60.0}}, name="z")
    assert run0.result.plant is run0.plant_set[0] and run0.controller.name == "z"
    assert run0.wall_time_s > 0.0
    assert dataclasses.replace(run0.controller, design=None).kp == run0.result.kp


def test_results_are_frozen() -> None:
    row = _row("a", 1.2)
    run = _run([row], True)
    srun = SwitchingRun("reduced", None, None, ())
    objs: list[Any] = [row, run, _spec(), srun, SwitchingCheck("c", "s", "p", (srun,))]
    for obj in objs:
        field = dataclasses.fields(obj)[0].name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, field, None)
    assert hash(row) == hash(_row("a", 1.2))


def test_pi_nominal_default_when_no_plant_has_the_files_delay() -> None:
    """A set sampled with 2 samples of delay and a file with 1: no plant has the file's delay,
    the design is made on the first plant (the only one)."""
    spec = {
        "plants": {"controller": "pi-10ms", "times": 1, "delay_samples": 2},
        "design": {"phase_margin": 60.0},
        "controller": {"delay_samples": 1},
    }
    run = design_from_spec("pi", spec)
    assert len(run.plant_set) == 1 and run.result.plant is run.plant_set[0]
    assert run.result.plant.delay == pytest.approx(0.02)
    assert run.controller.delay_samples == 1 and run.controller.sample_period_s == 0.01


def test_pid_provenance_records_kd_and_tf_and_a_pi_does_not() -> None:
    run = design_from_spec("pid", {**SMALL, "design": {"ms": 1.6, "tf": 0.02}})
    assert run.result.structure == "pid" and run.controller.law == "lti"
    assert run.controller.design is not None
    ach = run.controller.design["achieved"]
    assert ach["kd"] == float(f"{run.result.kd:.6g}") and ach["tf"] == pytest.approx(0.02)
    assert ach["converged"] is run.result.converged
    run = design_from_spec("robust-pi", SMALL)
    assert run.controller.design is not None
    ach = run.controller.design["achieved"]
    assert "kd" not in ach and "tf" not in ach and ach["kp"] == float(f"{run.result.kp:.6g}")
