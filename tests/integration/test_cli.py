"""The ``drivetrain-ctrl`` command line (:func:`drivetrain_ctrl.cli.main`), run in-process."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from drivetrain_ctrl.cli import SIMULATION_FILES, main
from drivetrain_ctrl.plant.params import PARAMETER_SETS_DIR
from drivetrain_ctrl.sim.metrics import METRIC_KEYS

FILES = SIMULATION_FILES
# the outputs the issue names are among them
assert {"trajectory.csv", "events.csv", "metrics.json", "timing.json", "overview.png"} <= set(FILES)


def simulate_reduced(scenario: str, out: Path, *extra: str) -> int:
    return main(
        ["simulate", "--scenario", scenario, "--model", "reduced", "--out", str(out), *extra]
    )


@pytest.mark.parametrize("scenario", ["engage-ramp", "tip-in"])
def test_simulate_reduced_writes_deterministic_outputs(
    scenario: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    assert simulate_reduced(scenario, a) == 0
    out = capsys.readouterr().out
    assert scenario in out and "reduced" in out
    assert simulate_reduced(scenario, b) == 0
    for name in FILES:
        assert (a / name).is_file() and (a / name).stat().st_size > 0, name
    assert (a / "metrics.json").read_bytes() == (b / "metrics.json").read_bytes()
    m = json.loads((a / "metrics.json").read_text())
    assert set(METRIC_KEYS) <= set(m)
    assert m["scenario"] == scenario and m["model"] == "reduced"
    assert m["parameter_set"] == "passenger-car"
    assert m["status"] == "ok"
    assert m["energy_residual_rel"] < 1e-8
    timing = json.loads((a / "timing.json").read_text())
    assert timing["wall_time_s"] > 0 and timing["nfev"] > 0 and timing["steps"] > 0
    # the kernels are loaded by a short run before the timed one
    assert timing["kernel_load_s"] > 0
    assert timing["wall_time_s"] + timing["kernel_load_s"] < timing["total_wall_time_s"]
    traj = pd.read_csv(a / "trajectory.csv")
    assert "t [s]" in traj.columns and "omega_engine [rad/s]" in traj.columns
    assert len(traj) == m["n_samples"]
    events = pd.read_csv(a / "events.csv")
    assert list(events.columns) == ["t [s]", "element", "from_mode", "to_mode"]
    assert len(events) == m["n_events"]
    if scenario == "engage-ramp":
        assert m["lockup_time_s"] is not None and 0.2 < m["lockup_time_s"] < 3.0
        assert m["clutch_energy_J"] > 0
    else:  # clutch locked throughout; the backlash is crossed once (contact- -> contact+)
        assert m["lockup_time_s"] is None
        assert m["clutch_energy_J"] == 0.0
        assert m["n_backlash_crossings"] == 1


def test_simulate_options(tmp_path: Path) -> None:
    assert simulate_reduced("tip-in", tmp_path, "--t-end", "0.8", "--rtol", "1e-6") == 0
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["t_end_s"] == 0.8 and m["rtol"] == 1e-6


def test_misspelt_scenario_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert simulate_reduced("engage-rmap", tmp_path / "x") == 2
    err = capsys.readouterr().err
    assert "engage-rmap" in err and "scenario" in err
    assert "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_scenario_file_with_misspelt_key_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(
        'name = "bad"\nt_ned = 1.0\n[initial]\nengine_speed_rpm = 1000.0\nvehicle_speed_kmh = 0.0\n'
        "throttle = 0.5\n"
    )
    assert simulate_reduced(str(f), tmp_path / "x") == 2
    err = capsys.readouterr().err
    assert "t_ned" in err and "t_end" in err


def test_params_file_with_misspelt_key_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = (PARAMETER_SETS_DIR / "passenger-car.toml").read_text()
    assert "\nJ1 = " in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("\nJ1 = ", "\nJ_1 = ", 1))
    rc = main(
        ["simulate", "--scenario", "tip-in", "--model", "reduced", "--params", str(bad)]
        + ["--out", str(tmp_path / "x")]
    )
    assert rc == 2
    err = capsys.readouterr().err
    assert "engine.J_1" in err and "unknown parameter" in err and "J1" in err
    assert "Traceback" not in err


def test_unknown_params_set_and_missing_file_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["params", "show", "passenger-kar"]) == 2
    assert "passenger-kar" in capsys.readouterr().err
    assert main(["params", "show", str(tmp_path / "none.toml")]) == 2
    assert "none.toml" in capsys.readouterr().err


def test_params_default_alias(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["params", "show", "default"]) == 0
    by_alias = capsys.readouterr().out
    assert main(["params", "show", "passenger-car"]) == 0
    assert capsys.readouterr().out == by_alias
    assert "engine.J1" in by_alias


def test_usage_errors_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--scenario", "tip-in", "--model", "tiny", "--out", "x"]) == 2
    assert "tiny" in capsys.readouterr().err
    assert main([]) == 2
    assert main(["--help"]) == 0


def test_params_and_scenarios_listing(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["params", "list"]) == 0
    assert "passenger-car" in capsys.readouterr().out
    assert main(["params", "show"]) == 0
    out = capsys.readouterr().out
    assert "engine.J1" in out and "kg m^2" in out and "frame: engine" in out
    assert "clutch.pedal_map" in out
    assert main(["scenarios", "list"]) == 0
    out = capsys.readouterr().out
    assert "engage-ramp" in out and "tip-in" in out


def test_demo_quick(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--out", str(tmp_path), "--quick"]) == 0
    summary = (tmp_path / "summary.md").read_text()
    for scenario in ("engage-ramp", "tip-in"):
        d = tmp_path / f"{scenario}-reduced"
        for name in FILES:
            assert (d / name).is_file(), d / name
        assert f"{scenario}-reduced/overview.png" in summary
    assert not (tmp_path / "engage-ramp-full").exists()
    console = capsys.readouterr().out
    assert str(tmp_path / "summary.md") in console
    # summary.md, the console and metrics.json name the same figures, with the same values
    from drivetrain_ctrl.cli import CONSOLE_METRICS, SUMMARY_METRICS, _fmt_metric
    from drivetrain_ctrl.sim.metrics import METRICS

    rows = {}
    for line in summary.splitlines():
        if line.startswith("| `"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            rows[cells[0].strip("`")] = cells[1:]
    assert tuple(rows) == SUMMARY_METRICS
    assert set(SUMMARY_METRICS) <= set(METRICS) and set(CONSOLE_METRICS) <= set(METRICS)
    heads = [c.strip() for c in summary.split("| metric |")[1].splitlines()[0].split("|")[:-1]]
    for col, head in enumerate(heads):
        label, kind = head.split(" / ")
        m = json.loads((tmp_path / f"{label}-{kind}" / "metrics.json").read_text())
        assert [rows[k][col] for k in SUMMARY_METRICS] == [
            _fmt_metric(k, m[k]) for k in SUMMARY_METRICS
        ], head
        # the console quotes "name value" under the same names
        ctl = f", controller {m['controller']['name']}" if m["controller"] else ""
        head_line = f"{m['scenario']} / {kind} model ({m['parameter_set']}{ctl})"
        block = console.split(head_line)[1].split(" model (")[0]
        for k in CONSOLE_METRICS:
            assert f"{k} {_fmt_metric(k, m[k])}" in " ".join(block.split()), (head, k)
    # every name in summary.md has its definition there, from the table
    for k in SUMMARY_METRICS:
        assert f"- `{k}`" in summary and METRICS[k].definition in summary, k
    for old in ("lurch_m_s2", "max_vehicle_jerk_m_s3", "max_engine_speed_rpm"):
        assert old not in summary and old not in console


def test_report_command_writes_the_three_files(tmp_path: Path) -> None:
    from drivetrain_ctrl.cli import main

    assert main(["report", "--controller", "paper", "--out", str(tmp_path / "r")]) == 0
    for f in ("report.html", "report.pdf", "data.json"):
        assert (tmp_path / "r" / f).stat().st_size > 1000
    assert main(["report", "--controller", "papr", "--out", str(tmp_path / "x")]) == 2
    assert not (tmp_path / "x").exists()


def test_simulate_closed_loop_scenario_needs_a_controller(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    from drivetrain_ctrl.cli import main

    assert main(["simulate", "--scenario", "paper-start", "--out", str(tmp_path)]) == 2
    assert "needs a controller" in capsys.readouterr().err
    code = main(
        ["simulate", "--scenario", "paper-start", "--controller", "pi", "--model", "reduced",
         "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["controller"]["name"] == "pi" and m["tracking_rms_rpm"] < 120.0


@pytest.mark.parametrize("command", ["simulate", "report"])
def test_unreadable_controller_file_exits_2(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = tmp_path / "d.toml"
    d.mkdir()  # a directory named like a controller file
    latin = tmp_path / "latin.toml"
    latin.write_bytes('name = "caf\xe9"\nlaw = "paper"\n'.encode("latin-1"))
    extra = ["--scenario", "paper-start", "--model", "reduced"] if command == "simulate" else []
    for f, what in ((d, "cannot read the file"), (latin, "not a UTF-8 text file")):
        out = tmp_path / f"out-{f.stem}"
        rc = main([command, *extra, "--controller", str(f), "--out", str(out)])
        assert rc == 2, (command, f)
        err = capsys.readouterr().err
        assert str(f) in err and what in err, err
        assert "Traceback" not in err
        assert not out.exists()


def test_controller_x_r0_outside_the_stroke_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "far.toml"
    f.write_text('name = "far"\nlaw = "paper"\nx_r0 = 0.5\n', encoding="utf-8")
    rc = main(
        ["simulate", "--scenario", "paper-start", "--model", "reduced", "--controller", str(f)]
        + ["--out", str(tmp_path / "x")]
    )
    assert rc == 2
    err = capsys.readouterr().err
    assert "x_r0 = 0.5" in err and "actuator stroke" in err and "Traceback" not in err


def test_t_end_before_the_start_command_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # engage-ramp's start command (start of the pedal release) is at 0.2 s
    assert simulate_reduced("engage-ramp", tmp_path / "x", "--t-end", "0.1") == 2
    err = capsys.readouterr().err
    assert "--t-end" in err and "0.2 s" in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_help_lists_the_builtin_controllers(capsys: pytest.CaptureFixture[str]) -> None:
    from drivetrain_ctrl.control.laws import builtin_controllers

    for command in ("simulate", "report"):
        assert main([command, "--help"]) == 0
        text = "".join(capsys.readouterr().out.split())  # argparse wraps, also at hyphens
        assert ",".join(builtin_controllers()) in text, command


def test_simulate_builds_the_controller_once(tmp_path: Path) -> None:
    """The kernels are loaded by a short run before the timed one; the controller (and its
    stability warning) is built once for both."""
    import warnings

    from drivetrain_ctrl.control.laws import UnstableLoopWarning

    hot = tmp_path / "hot.toml"
    hot.write_text(
        'name = "hot"\nlaw = "paper"\nk_r = 0.02\nsample_period_s = 0.01\ndelay_samples = 1\n',
        encoding="utf-8",
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = simulate_reduced(
            "paper-start", tmp_path / "o", "--controller", str(hot), "--t-end", "0.5"
        )
    assert code == 0
    unstable = [w for w in caught if issubclass(w.category, UnstableLoopWarning)]
    assert len(unstable) == 1, [str(w.message) for w in unstable]


def _scenario_file(tmp_path: Path, name: str, **inputs: dict[str, list[float]]) -> Path:
    import tomli_w

    from drivetrain_ctrl.scenarios.scenario import load_scenario

    d = load_scenario(name).to_dict()
    d["inputs"].update(inputs)
    path = tmp_path / f"{name}-variant.toml"
    path.write_text(tomli_w.dumps(d), encoding="utf-8")
    return path


def test_out_that_is_a_file_or_empty_fails_before_the_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    afile = tmp_path / "afile"
    afile.write_text("keep me", encoding="utf-8")
    for out, msg in ((afile, "is an existing file"), (afile / "sub", "is an existing file")):
        assert simulate_reduced("tip-in", out) == 2
        err = capsys.readouterr().err
        assert msg in err and str(afile) in err
    assert afile.read_text(encoding="utf-8") == "keep me"
    assert main(["simulate", "--scenario", "tip-in", "--out", ""]) == 2
    assert "give an output directory" in capsys.readouterr().err


def test_rerun_into_the_same_out_says_what_it_replaced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "o"
    assert simulate_reduced("tip-in", out) == 0
    assert "replaced" not in capsys.readouterr().err
    assert simulate_reduced("tip-in", out) == 0
    assert "replaced the earlier trajectory.csv, events.csv" in capsys.readouterr().err


def test_bad_scenario_inputs_exit_2_without_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cases = [
        ({"pedal": {"times": [0.2, 1.2], "values": [5.0, 0.03]}}, "input 'pedal' = 5 m"),
        ({"throttle": {"times": [0.0], "values": [10.0]}}, "input 'throttle' = 10"),
        # the start command after t_end: the message names the file's t_end, not --t-end
        ({"pedal": {"times": [10.0, 20.0], "values": [0.11, 0.03]}}, "t_end = 3.0 s ends before"),
    ]
    for k, (inputs, msg) in enumerate(cases):
        path = _scenario_file(tmp_path, "engage-ramp", **inputs)
        assert simulate_reduced(str(path), tmp_path / f"o{k}") == 2, msg
        err = capsys.readouterr().err
        assert msg in err and "Traceback" not in err and "--t-end" not in err
    # knots before the run: the metrics start at 0 (no traceback, exit 0)
    path = _scenario_file(
        tmp_path, "engage-ramp", pedal={"times": [-5.0, -1.0], "values": [0.11, 0.03]}
    )
    assert simulate_reduced(str(path), tmp_path / "neg", "--t-end", "0.3") == 0
    assert "Traceback" not in capsys.readouterr().err


def test_report_and_demo_failures_and_existing_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A simulation that fails inside ``report`` is a one-line error (exit 1), no traceback; a
    report into a non-empty directory says that outputs are replaced."""
    import drivetrain_ctrl.reporting.controller_report as R

    def boom(**_kw: object) -> None:
        raise RuntimeError("simulation stopped at t = 0.1 s: step_too_small")

    monkeypatch.setattr(R, "build_report", boom)
    out = tmp_path / "rep"
    out.mkdir()
    (out / "old.txt").write_text("x", encoding="utf-8")
    assert main(["report", "--controller", "paper", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "report: simulation stopped at t = 0.1 s" in err and "Traceback" not in err
    assert "writing into the existing" in err and (out / "old.txt").exists()
