"""Scenario fields as uncertain parameters (``scenario.slope``, ...) and one writer per study
folder (``DIR/.lock``) (issue 23)."""

from __future__ import annotations

import functools
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest

from drivetrain_ctrl.studies.case import Case, CaseError, run_case
from drivetrain_ctrl.studies.runner import folder_lock, read_results, run_chunk, run_study
from drivetrain_ctrl.studies.study import Study, StudyError, sample_table

BASE: dict[str, Any] = {
    "study": {
        "name": "slope",
        "model": "reduced",
        "controllers": ["paper"],
        "scenarios": ["paper-start"],
        "metrics": ["lockup_time_s", "clutch_energy_J", "engine_speed_min_rpm"],
        "t_end": 4.0,
        "linear": False,
    },
    "sampling": {"method": "grid"},
    "parameters": {"scenario.slope": {"values": [0.0, math.atan(0.05)]}},
}


def _study(parameters: Mapping[str, Any] | None = None, **study: Any) -> Study:
    d = {**BASE, "study": {**BASE["study"], **study}}
    if parameters is not None:
        d["parameters"] = parameters
    return Study.from_dict(d)


def test_the_road_slope_is_a_study_parameter_and_changes_the_run(tmp_path: Path) -> None:
    study = _study()
    df = sample_table(study)
    items, cases = [], []
    for i in range(study.samples):
        vals = {str(k): float(v) for k, v in df.iloc[i].items()}
        case = study.case(i, vals, "paper", 0)
        assert case.scenario_overrides == {"slope": vals["scenario.slope"]} and not case.overrides
        items.append((case.label, i, "paper", "paper-start", vals))
        cases.append(case)
    flat, hill = run_chunk(items, cases, study.metrics, study.criteria, run_case)
    assert flat["status"] == hill["status"] == "ok"
    assert flat["param:scenario.slope"] == 0.0 and hill["param:scenario.slope"] == math.atan(0.05)
    # uphill the clutch slips longer and dissipates more
    assert hill["lockup_time_s"] > flat["lockup_time_s"]
    assert hill["clutch_energy_J"] > 1.1 * flat["clutch_energy_J"]
    # the same as a scenario file with that grade
    text = (
        Path(__file__).parents[2] / "drivetrain_ctrl/scenarios/builtin/paper-start.toml"
    ).read_text()
    f = tmp_path / "hill.toml"
    f.write_text(
        text.replace('name = "paper-start"', 'name = "hill"').replace(
            "slope_percent = 0.0", "slope_percent = 5.0"
        )
    )
    direct = run_case(Case(scenario=f, model="reduced", controller="paper", t_end=4.0))
    for m in study.metrics:
        assert hill[m] == direct[m], m


def test_scenario_parameters_are_checked_before_any_work() -> None:
    with pytest.raises(StudyError, match=r"parameters\.'scenario\.slop': unknown scenario field "
                       r"'slop'.*did you mean 'slope'"):  # fmt: skip
        _study({"scenario.slop": {"values": [0.0, 0.1]}})
    with pytest.raises(StudyError, match=r"parameters\.'scenario\.t_end': unknown scenario field"):
        _study({"scenario.t_end": {"values": [1.0, 2.0]}})
    with pytest.raises(StudyError, match=r"parameters\.'scenario\.throttle0' = 2\.0: .*throttle0"):
        _study({"scenario.throttle0": {"values": [0.5, 2.0]}})
    with pytest.raises(StudyError, match=r"parameters\.'scenario\.slope' = 2\.0: .*slope"):
        _study({"scenario.slope": {"values": [0.0, 2.0]}})
    with pytest.raises(CaseError, match=r"unknown scenario field 'grade'"):
        Case(scenario="paper-start", controller="paper", scenario_overrides={"grade": 0.1})
    with pytest.raises(CaseError, match=r"scenario_overrides\.slope = 'x'"):
        Case(scenario="paper-start", controller="paper", scenario_overrides={"slope": "x"})  # type: ignore[dict-item]


# -- one writer per folder --------------------------------------------------------------------
def _wait_for(path: Path, timeout: float = 120.0) -> None:
    t0 = time.monotonic()
    while not path.exists():
        if time.monotonic() - t0 > timeout:
            raise TimeoutError(path)
        time.sleep(0.02)


def _held_run(signals: Path, case: Case) -> dict[str, Any]:
    """A run that says it started and waits to be released (the first study is mid-run)."""
    (signals / "started").touch()
    _wait_for(signals / "release")
    return {"status": "ok", "lockup_time_s": 1.0 + int(case.label[1:7])}


@pytest.fixture(scope="module")
def local_client() -> Iterator[Any]:
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    )
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


def test_a_second_writer_is_refused_while_the_first_runs(tmp_path: Path, local_client: Any) -> None:
    study = _study({"vehicle.M_v": {"values": [1200.0, 1300.0, 1400.0]}})
    out = tmp_path / "out"
    sig = tmp_path / "signals"
    sig.mkdir()
    first: dict[str, Any] = {}

    def go() -> None:
        first["run"] = run_study(
            study, out=out, client=local_client, progress=False,
            run=functools.partial(_held_run, sig),
        )  # fmt: skip

    th = threading.Thread(target=go)
    th.start()
    try:
        _wait_for(sig / "started")
        with pytest.raises(StudyError, match=rf"another study run is writing.*pid {os.getpid()}"):
            run_study(study, out=out, client=local_client, progress=False, run=run_case)
    finally:
        (sig / "release").touch()
        th.join(120)
    done = first["run"]
    assert done.rows == done.computed == 3
    df = read_results(out)
    assert len(df) == 3 and df["key"].is_unique
    assert list(df["lockup_time_s"]) == [1.0, 2.0, 3.0]  # only the first writer's rows
    again = run_study(study, out=out, client=local_client, progress=False, run=run_case)
    assert again.computed == 0 and again.rows == 3  # the lock was released at the end


def test_a_killed_holder_leaves_no_stale_lock(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    code = (
        "import sys, time; from pathlib import Path\n"
        "from drivetrain_ctrl.studies.runner import folder_lock\n"
        "with folder_lock(Path(sys.argv[1])):\n"
        "    print('held', flush=True); time.sleep(600)\n"
    )
    p = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout is not None and p.stdout.readline().strip() == "held"
        with pytest.raises(StudyError, match=rf"pid {p.pid} on host"):
            with folder_lock(out):
                pass
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait(60)
    # the operating system released it with the process: no stale lock to clear
    with folder_lock(out) as path:
        assert f"pid {os.getpid()}" in path.read_text()
    assert (out / ".lock").exists()  # the note stays; it does not hold the folder
    with folder_lock(out):
        pass
