"""Designs from spec files and the ``drivetrain-ctrl design`` command (issue 20 item 7): the spec
format and its errors, each method's controller file (with provenance), the check on the switching
plant and its loud failures, and the built-in designed controllers (reproducible from their
specs, run on the switching plant)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import control
import numpy as np
import pytest

from drivetrain_ctrl.cli import main
from drivetrain_ctrl.control.laws import (
    ControllerSpec,
    UnstableLoopWarning,
    builtin_controllers,
    load_controller,
)
from drivetrain_ctrl.design import from_spec
from drivetrain_ctrl.design.from_spec import (
    STALL_SPEED_RPM,
    DesignSpecError,
    builtin_design_specs,
    check_on_switching_plant,
    design_from_spec,
    design_spec_from_dict,
    load_design_spec,
)
from drivetrain_ctrl.design.robust import RobustTuning
from drivetrain_ctrl.sim.simulator import ZenoError

#: a small continuous plant set: one instant, the friction coefficient +-40 % (3 plants)
SMALL: dict[str, Any] = {
    "plants": {"controller": "pi", "times": 1, "box": {"clutch.k12_max": {"factor": [0.6, 1.4]}}},
    "design": {"ms": 1.4},
    "check": {"models": ["reduced"]},
}

#: sampled every 10 ms, the delay 0-2 samples (9 plants), the file's delay 1 (pi-10ms's)
SAMPLED: dict[str, Any] = {
    "plants": {
        "controller": "pi-10ms",
        "times": 1,
        "box": {"clutch.k12_max": {"factor": [0.6, 1.4]}, "delay_samples": [0, 2]},
    },
    "design": {"phase_margin": 60.0},
    "check": {"models": ["reduced"]},
}


def _write(path: Path, d: dict[str, Any]) -> Path:
    import tomli_w

    path.write_text(tomli_w.dumps(d), encoding="utf-8")
    return path


# -- the spec format -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    "d,match",
    [
        ({"plant": {}}, r"plant: unknown key; did you mean 'plants'\?"),
        ({"plants": {"tims": 3}}, r"plants\.tims: unknown key; did you mean 'times'\?"),
        ({"plants": {"trajectory": 3}}, r"plants\.trajectory: unknown key"),
        ({"controller": {"frm": "ss"}}, r"controller\.frm: unknown key; did you mean 'form'\?"),
        ({"controller": {"form": "zpk"}}, r"controller\.form = 'zpk'"),
        ({"check": {"modls": []}}, r"check\.modls: unknown key; did you mean 'models'\?"),
        ({"check": {"models": ["fast"]}}, r"check\.models = \['fast'\]"),
        ({"method": "robust", "design": {}}, r"method = 'robust'.*did you mean 'robust-pi'\?"),
        ({"method": "robust-pi", "design": {"mss": 1.3}}, r"design\.mss: unknown key; did you"),
        ({"method": "hinf", "design": {"bandwith": 3.0}}, r"design\.bandwith: unknown key; did"),
        ({"plants": 3}, r"plants = 3: must be a table"),
        ({"name": ""}, r"name = '': must be a non-empty string"),
    ],
)
def test_bad_specs_name_the_key(d: dict[str, Any], match: str) -> None:
    with pytest.raises(DesignSpecError, match=match):
        design_spec_from_dict(d)


def test_design_options_are_checked_against_the_method_and_the_command() -> None:
    spec = design_spec_from_dict({**SMALL, "design": {"phase_margin": 60.0}})
    with pytest.raises(DesignSpecError, match=r"design\.phase_margin: unknown key"):
        design_from_spec("robust-pi", spec)  # a design_pi option, not a RobustSpec field
    with pytest.raises(DesignSpecError, match=r"method = 'hinf' in the spec .* asks for 'pi'"):
        design_from_spec("pi", {**SMALL, "method": "hinf", "design": {}})
    with pytest.raises(DesignSpecError, match=r"method = 'pi-d'.*did you mean 'pid'\?"):
        design_from_spec("pi-d", SMALL)
    with pytest.raises(DesignSpecError, match=r"design\.W1 = .*num = \[\.\.\.\]"):
        design_from_spec("hinf", {**SMALL, "design": {"W1": [1.0]}})
    with pytest.raises(DesignSpecError, match=r"plants: .*clutch\.k12_mx"):
        design_from_spec("robust-pi", {**SMALL, "plants": {"box": {"clutch.k12_mx": [1, 2]}}})


def test_builtin_specs_load_by_name_and_by_path(tmp_path: Path) -> None:
    specs = builtin_design_specs()
    assert set(specs) == {"robust-pi", "hinf"}
    for name, spec in specs.items():
        assert spec.method == name and spec.name == name and spec.source == f"{name}.toml"
        assert load_design_spec(name) is spec
        again = load_design_spec(_write(tmp_path / f"{name}.toml", spec.to_dict()))
        assert again.to_dict() == spec.to_dict()
    with pytest.raises(DesignSpecError, match=r"not a built-in design spec.*did you mean"):
        load_design_spec("robust_pi")


# -- designs from a spec -------------------------------------------------------------------------


def test_robust_pi_from_a_spec_gives_a_pi_file_with_its_provenance(tmp_path: Path) -> None:
    run = design_from_spec("robust-pi", {**SMALL, "controller": {"x_r0": 0.065}}, name="rp")
    assert isinstance(run.result, RobustTuning) and len(run.plant_set) == 3
    c = run.controller
    assert c.name == "rp" and c.law == "pi" and c.x_r0 == 0.065 and c.sample_period_s is None
    assert (c.kp, c.ki) == (run.result.kp, run.result.ki)
    # the rows are the tuner's own re-check; the limiting plants its active ones
    assert [r.plant for r in run.plants] == [p.name for p in run.result.plants]
    assert run.limiting == run.result.limiting and run.limiting
    w = run.worst()
    assert w["ms_max"] == pytest.approx(run.result.ms) and w["ms_max"] <= 1.4 * (1 + 1e-3)
    assert w["all_stable"] is True and run.met
    # provenance: the spec that produced it and what it achieved
    assert c.design is not None
    assert c.design["method"] == "robust-pi" and c.design["spec"] == run.spec.to_dict()
    assert c.design["achieved"]["ki"] == pytest.approx(c.ki, rel=1e-5)
    assert c.design["achieved"]["limiting"] == list(run.limiting)
    ki = c.design["achieved"]["ki_history"]
    assert all(b >= a for a, b in zip(ki, ki[1:], strict=False))  # never decreases
    assert load_controller(c.to_toml(tmp_path / "rp.toml")) == c
    assert "robust-pi design 'rp' on 3 plants" in run.summary()


def test_pi_on_a_sampled_set_designs_on_the_file_delay() -> None:
    """With the delay 0-2 samples in the box, the PI is designed on the nominal plant with the
    controller file's delay (1 sample, pi-10ms's), and checked on all nine."""
    run = design_from_spec("pi", SAMPLED, name="pi-sampled")
    c = run.controller
    assert c.law == "pi" and c.sample_period_s == 0.01 and c.delay_samples == 1
    assert run.result.plant.delay == pytest.approx(0.01)  # designed with one sample of delay
    assert run.result.phase_margin == pytest.approx(60.0, abs=0.5)
    assert len(run.plants) == 9 and len(run.limiting) == 1
    worst = max(run.plants, key=lambda r: r.ms)
    assert run.limiting == (worst.plant,) and "delay 2 samples" in worst.plant
    # an explicit delay for the file and an LTI form
    run2 = design_from_spec(
        "pi", {**SAMPLED, "controller": {"delay_samples": 2, "form": "tf"}}, name="x"
    )
    assert run2.controller.law == "lti" and run2.controller.delay_samples == 2
    assert run2.result.plant.delay == pytest.approx(0.02)
    with pytest.raises(DesignSpecError, match=r"controller\.delay_samples = 1: .*continuous"):
        design_from_spec("pi", {**SMALL, "design": {}, "controller": {"delay_samples": 1}})


def test_hinf_from_a_spec_writes_its_reduced_controller() -> None:
    spec = {
        **SMALL,
        "plants": {**SMALL["plants"], "minimal": True},
        "design": {"bandwidth": 10.0, "ms": 1.6},
    }
    run = design_from_spec("hinf", spec, name="h")
    c = run.controller
    assert c.law == "lti" and c.A is not None and c.sample_period_s is None
    K = run.result.controller_reduced
    w = np.logspace(-2, 3, 30)
    np.testing.assert_allclose(
        c.lti().frequency_response(w).complex.reshape(-1),
        K.frequency_response(w).complex.reshape(-1),
        rtol=1e-12,
    )
    assert [r.plant for r in run.plants] == [k.name for k in run.result.checks_reduced]
    assert run.met and c.design is not None and c.design["achieved"]["gamma"] <= 1.0
    # one integrator (kept by the reduction): the anti-windup rule applies
    assert c.anti_windup_time_s() is not None


# -- the check on the switching plant -------------------------------------------------------------


def test_check_says_when_the_clutch_never_locks_or_the_engine_stalls() -> None:
    never = ControllerSpec(name="open", law="lti", num=[1e-6], den=[1.0], x_r0=0.12)
    chk = check_on_switching_plant(never, models=("reduced",))
    assert not chk.ok and chk.runs[0].metrics is not None
    assert chk.runs[0].problems == ("the clutch NEVER LOCKED UP within the scenario",)
    # positive feedback: the clutch closes at once and drags the engine through zero
    wrong_sign = ControllerSpec(name="neg", law="lti", num=[-1e-3], den=[1.0])
    chk = check_on_switching_plant(wrong_sign, models=("reduced",))
    (run,) = chk.runs
    assert run.metrics is not None and run.metrics["engine_speed_min_rpm"] < STALL_SPEED_RPM
    assert any("the engine STALLED" in p for p in run.problems)
    assert any("unstable" in w for w in run.warnings)  # the build's UnstableLoopWarning, kept
    assert "STALLED" in chk.summary()
    ok = check_on_switching_plant("pi", models=("reduced", "full"))
    assert ok.ok and [r.model for r in ok.runs] == ["reduced", "full"]
    assert "locked up at" in ok.summary()


def test_check_reports_a_zeno_stop_and_a_failed_run(monkeypatch: pytest.MonkeyPatch) -> None:
    def zeno(*a: Any, **k: Any) -> Any:
        raise ZenoError("events accumulate (Zeno) at t = 1.2 s on element 'clutch'")

    monkeypatch.setattr(from_spec, "run_scenario", zeno)
    chk = check_on_switching_plant("pi", models=("reduced",))
    assert not chk.ok and chk.runs[0].metrics is None
    assert chk.runs[0].problems[0].startswith("the simulation TRIPPED THE ZENO GUARD: events")

    def fail(*a: Any, **k: Any) -> Any:
        raise RuntimeError("step size too small")

    monkeypatch.setattr(from_spec, "run_scenario", fail)
    chk = check_on_switching_plant("pi", models=("reduced",))
    assert chk.runs[0].problems == ("the simulation FAILED: step size too small",)
    with pytest.raises(DesignSpecError, match=r"models = \['fast'\]"):
        check_on_switching_plant("pi", models=("fast",))


# -- the command -------------------------------------------------------------------------------


def test_design_command_prints_the_table_writes_the_file_and_checks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = _write(tmp_path / "small.toml", {"name": "small", **SMALL})
    out = tmp_path / "ctl" / "small.toml"
    assert main(["design", "robust-pi", "--spec", str(spec), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "design robust-pi from small.toml: 3 slip-mode loop plants" in text
    assert "  #     Ms     Mt   GM dB  PM deg" in text
    assert text.count("*t = ") == len(load_controller(out).design["achieved"]["limiting"])  # type: ignore[index]
    assert "linear (robust-pi, worst over the plant set)" in text
    assert "switching plant (paper-start, passenger-car)" in text
    assert "lockup_time_s" in text and "!!!" not in text
    ctl = load_controller(out)
    assert ctl.name == "small" and ctl.law == "pi" and ctl.design["spec_file"] == "small.toml"  # type: ignore[index]
    # the file runs by path like any controller
    assert main(["simulate", "--scenario", "paper-start", "--controller", str(out), "--model",
                 "reduced", "--out", str(tmp_path / "run")]) == 0  # fmt: skip


def test_design_command_fails_loudly_when_the_switching_plant_run_fails(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The file is written, the problem is said on stdout (!!!) and stderr, exit code 1."""
    spec = _write(tmp_path / "s.toml", SMALL)
    out = tmp_path / "s-out.toml"
    real = from_spec.check_on_switching_plant

    def stalling(controller: Any, **kw: Any) -> Any:
        # the designed controller with the wrong sign: the engine stalls on the switching plant
        c = load_controller(controller)
        return real(ControllerSpec(name=c.name, law="lti", num=[-1e-3], den=[1.0]), **kw)

    monkeypatch.setattr(from_spec, "check_on_switching_plant", stalling)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableLoopWarning)
        rc = main(["design", "robust-pi", "--spec", str(spec), "--out", str(out), "--name", "n"])
    cap = capsys.readouterr()
    assert rc == 1 and out.is_file()
    assert "!!! design 'n' on the switching plant, reduced model: the engine STALLED" in cap.out
    assert "the design FAILS on the switching plant" in cap.out
    assert "WARNING: design 'n' on the switching plant, reduced model: the engine STALLED" in (
        cap.err
    )


@pytest.mark.parametrize(
    "args,match",
    [
        (["--out", "x.txt"], r"--out x\.txt: a controller file must end in \.toml"),
        (["--spec", "nope.toml"], r"design spec 'nope\.toml': not a built-in design spec"),
        (["--spec", "robust-pi"], r"method = 'robust-pi' in the spec \(robust-pi\.toml\) but"),
    ],
)
def test_design_command_input_errors_exit_2(
    args: list[str], match: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = {"--spec": "hinf", "--out": str(tmp_path / "c.toml")}
    for k, v in zip(args[::2], args[1::2], strict=True):
        base[k] = v
    argv = ["design", "pi"] + [x for kv in base.items() for x in kv]
    assert main(argv) == 2
    import re

    assert re.search(match, capsys.readouterr().err)


def test_design_command_unknown_key_and_infeasible_spec_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _write(tmp_path / "bad.toml", {**SMALL, "plants": {"tims": 1}})
    assert main(["design", "pi", "--spec", str(bad), "--out", str(tmp_path / "c.toml")]) == 2
    assert "plants.tims: unknown key; did you mean 'times'?" in capsys.readouterr().err
    # an effort bound below what integral action needs at DC on some plant
    inf = _write(tmp_path / "inf.toml", {**SMALL, "design": {"ms": 1.4, "ks_max": 1e-9}})
    assert main(["design", "robust-pi", "--spec", str(inf), "--out", str(tmp_path / "c.toml")]) == 2
    err = capsys.readouterr().err
    assert "ks_max = 1e-09" in err and "raise ks_max" in err


# -- the built-in designed controllers ----------------------------------------------------------


@pytest.mark.parametrize("name", ["robust-pi", "hinf"])
def test_builtin_design_carries_its_spec_and_runs_on_the_switching_plant(name: str) -> None:
    ctl = builtin_controllers()[name]
    spec = builtin_design_specs()[name]
    assert ctl.design is not None and ctl.design["method"] == name
    assert ctl.design["spec"] == spec.to_dict()  # the spec that produced it, as shipped
    assert ctl.design["achieved"]["all_stable"] is True and ctl.design["achieved"]["met"] is True
    chk = check_on_switching_plant(ctl, models=("reduced", "full"))
    assert chk.ok, chk.summary()
    for run in chk.runs:
        assert run.metrics is not None and run.metrics["energy_residual_rel"] <= 1e-6
        assert 2.0 < run.metrics["lockup_time_s"] < 3.0


@pytest.mark.slow
@pytest.mark.parametrize("name", ["robust-pi", "hinf"])
def test_builtin_design_is_reproducible_from_its_spec(name: str) -> None:
    """Re-run the design from the shipped spec: the same controller, to a tolerance (the
    optimisation's and the synthesis' round-off; a state-space realisation is compared by its
    frequency response, which does not depend on the basis)."""
    shipped = builtin_controllers()[name]
    run = design_from_spec(name, name)
    again = run.controller
    assert again.law == shipped.law and again.sample_period_s == shipped.sample_period_s
    if shipped.law == "pi":
        assert again.kp == pytest.approx(shipped.kp, rel=1e-3)
        assert again.ki == pytest.approx(shipped.ki, rel=1e-3)
    w = np.logspace(-2, 3, 60)
    a = again.lti().frequency_response(w).complex.reshape(-1)
    b = shipped.lti().frequency_response(w).complex.reshape(-1)
    assert np.max(np.abs(a - b) / np.abs(b)) <= 1e-3
    # the numbers the file records are the ones achieved again
    rec = shipped.design["achieved"]  # type: ignore[index]
    assert run.worst()["ms_max"] == pytest.approx(rec["ms_max"], rel=1e-3)
    assert run.worst()["gain_margin_db_min"] == pytest.approx(rec["gain_margin_db_min"], abs=0.05)
    assert math.isfinite(control.poles(again.lti()).real.max())
