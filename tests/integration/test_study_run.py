"""Running studies on Dask (issue 23 items 2 and 3): every row once, failed runs recorded with
their reason, resume computes exactly the missing rows, a killed worker or a killed command loses
nothing, and the table reads back identical to an uninterrupted run.

The fast tests use an in-process Dask client; the ``slow`` ones a real local cluster of two worker
processes (their start and kernel loading take tens of seconds on a busy two-core machine)."""

from __future__ import annotations

import contextlib
import functools
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cloudpickle
import numpy as np
import pandas as pd
import pytest

from drivetrain_ctrl.cli import main
from drivetrain_ctrl.studies.case import Case, run_case
from drivetrain_ctrl.studies.runner import read_results, run_chunk, run_study
from drivetrain_ctrl.studies.study import Study, StudyError, load_study, sample_table

cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers need not import tests

STUDY = """
[study]
name = "tiny"
model = "reduced"
controllers = ["paper", "pi"]
scenarios = ["paper-start"]
metrics = ["lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm", "notes"]
criteria = ["lockup_time_s <= 2.2", "engine_speed_min_rpm >= 700"]
t_end = 2.5

[sampling]
method = "mc"
samples = {samples}
seed = 3

[parameters."vehicle.M_v"]      # a normal with a huge spread: some samples are negative masses
dist = "normal"
mean = 1300.0
std = 1500.0

[parameters."controller.x_r0"]
values = [0.065, 0.07]
"""


#: the scheduler's HTTP server (started even without the dashboard) on an ephemeral loopback
#: port, not 8787 (runner.dask_client does the same)
_NO_8787 = {"dashboard_address": "127.0.0.1:0"}


def _study(tmp: Path, samples: int = 6) -> Path:
    f = tmp / "tiny.toml"
    f.write_text(STUDY.format(samples=samples))
    return f


def _expected_rows(study: Study) -> dict[str, Mapping[str, Any]]:
    """The records of run_case on every case, computed here in-process: the known answers."""
    df = sample_table(study)
    out: dict[str, Mapping[str, Any]] = {}
    for i in range(study.samples):
        vals = {k: float(v) for k, v in df.iloc[i].items()}
        for c in study.controller_names:
            case = study.case(i, vals, c, 0)
            try:
                out[case.label] = run_case(case)
            except ValueError as exc:
                out[case.label] = {"status": "failed", "error": str(exc)}
    return out


def test_a_study_runs_every_row_once_with_failures_recorded(
    tmp_path: Path, local_client: Any
) -> None:
    study = load_study(_study(tmp_path))
    done = run_study(study, out=tmp_path / "out", client=local_client, progress=False)
    df = read_results(tmp_path / "out")
    assert done.expected == done.rows == done.computed == len(df) == 12 and done.skipped == 0
    assert list(df["key"]) == sorted(study.keys()) and df["key"].is_unique
    expected = _expected_rows(study)
    n_failed = 0
    for _, row in df.iterrows():
        rec = expected[row["key"]]
        assert row["param:vehicle.M_v"] == sample_table(study).loc[row["sample"], "vehicle.M_v"]
        if rec["status"] == "failed":  # a negative mass: recorded with its reason
            n_failed += 1
            assert row["status"] == "failed" and "vehicle.M_v" in row["error"]
            assert not row["pass"] and np.isnan(row["lockup_time_s"])
            continue
        assert row["status"] == rec["status"] == "ok"
        for m in ("lockup_time_s", "jerk_max_m_s3", "engine_speed_min_rpm"):
            if rec[m] is None:  # undefined (e.g. no lock-up within the horizon): NaN
                assert np.isnan(row[m]), m
            else:
                assert row[m] == rec[m], m
        ok = rec["lockup_time_s"] is not None and rec["lockup_time_s"] <= 2.2
        assert row["pass:lockup_time_s <= 2.2"] == ok
        assert row["pass"] == (ok and rec["engine_speed_min_rpm"] >= 700)
    assert 0 < n_failed < len(df) and done.failed == n_failed
    assert 0 < done.passed < len(df) - n_failed  # the criteria separate the runs that finished
    assert (tmp_path / "out" / "study.json").exists()
    assert "12 of 12 rows" in done.summary()


def test_resume_computes_exactly_the_missing_rows_and_gives_the_same_table(
    tmp_path: Path, local_client: Any
) -> None:
    f = _study(tmp_path)
    full = run_study(f, out=tmp_path / "a", client=local_client, progress=False, chunk_size=2)
    ref = read_results(tmp_path / "a")
    # an interrupted run: some chunks written, others not (and a temporary file left behind)
    run_study(f, out=tmp_path / "b", client=local_client, progress=False, chunk_size=2)
    files = sorted((tmp_path / "b" / "results").glob("chunk-*.parquet"))
    assert len(files) == full.chunks == 6
    lost = sum(len(pd.read_parquet(p)) for p in files[:3])
    for p in files[:3]:
        p.unlink()
    (tmp_path / "b" / "results" / ".chunk-0.parquet.tmp-1").write_bytes(b"half a file")
    again = run_study(f, out=tmp_path / "b", client=local_client, progress=False, chunk_size=3)
    assert again.computed == lost and again.skipped == 12 - lost and again.rows == 12
    pd.testing.assert_frame_equal(read_results(tmp_path / "b"), ref)
    assert not list((tmp_path / "b" / "results").glob(".chunk-*"))
    # nothing missing: nothing computed, nothing written
    n_files = len(list((tmp_path / "b" / "results").glob("chunk-*.parquet")))
    third = run_study(f, out=tmp_path / "b", client=local_client, progress=False)
    assert third.computed == 0 and third.chunks == 0
    assert len(list((tmp_path / "b" / "results").glob("chunk-*.parquet"))) == n_files


def test_a_folder_of_another_study_is_refused(tmp_path: Path, local_client: Any) -> None:
    f = _study(tmp_path, samples=2)
    run_study(f, out=tmp_path / "o", client=local_client, progress=False)
    g = tmp_path / "other.toml"
    g.write_text(STUDY.format(samples=3))
    with pytest.raises(StudyError, match="holds results of another study"):
        run_study(g, out=tmp_path / "o", client=local_client, progress=False)


def test_bad_arguments_are_named(tmp_path: Path) -> None:
    f = _study(tmp_path, samples=2)
    for kw, named in (
        ({"workers": 0}, "workers = 0"),
        ({"chunk_size": -1}, "chunk_size = -1"),
        ({"scheduler": ""}, "scheduler = ''"),
        ({"client": object(), "workers": 2}, "client"),
    ):
        with pytest.raises(StudyError, match=named):
            run_study(f, out=tmp_path / "o", **kw)  # type: ignore[arg-type]
    assert main(["study", "run", str(tmp_path / "nope.toml"), "--out", str(tmp_path)]) == 2
    assert main(["study", "run", str(f), "--out", str(tmp_path), "--workers", "0"]) == 2


def test_a_run_that_raises_is_a_failed_row_with_its_reason() -> None:
    def boom(case: Case) -> dict[str, Any]:
        raise RuntimeError("step size too small at t = 1.2 s")

    item = ("s000000|paper|paper-start", 0, "paper", "paper-start", {"vehicle.M_v": 1.0})
    case = Case(scenario="paper-start", controller="paper", model="reduced")
    (row,) = run_chunk([item], [case], ("lockup_time_s",), (), boom)
    assert row["status"] == "failed" and row["error"].startswith("RuntimeError: step size")
    assert not row["pass"] and np.isnan(row["lockup_time_s"])


def test_each_pass_column_is_its_own_criterion() -> None:
    """A row missing the first criterion but meeting the second shows pass:<second> True
    (the columns are not cumulative); ``pass`` is False; a failed run meets none."""
    from drivetrain_ctrl.studies.study import Criterion

    crit = (Criterion("lockup_time_s", "<=", 2.2), Criterion("engine_speed_min_rpm", ">=", 700.0))
    item = ("s000000|paper|paper-start", 0, "paper", "paper-start", {"vehicle.M_v": 1.0})
    case = Case(scenario="paper-start", controller="paper", model="reduced")
    metrics = ("lockup_time_s", "engine_speed_min_rpm")

    def late(case: Case) -> dict[str, Any]:
        return {"status": "ok", "lockup_time_s": 3.0, "engine_speed_min_rpm": 800.0}

    (row,) = run_chunk([item], [case], metrics, crit, late)
    assert row["pass:lockup_time_s <= 2.2"] is False
    assert row["pass:engine_speed_min_rpm >= 700"] is True
    assert row["pass"] is False

    def good(case: Case) -> dict[str, Any]:
        return {"status": "ok", "lockup_time_s": 2.0, "engine_speed_min_rpm": 800.0}

    (row,) = run_chunk([item], [case], metrics, crit, good)
    assert row["pass"] is True and all(row[f"pass:{c.text}"] for c in crit)

    def stopped(case: Case) -> dict[str, Any]:
        return {"status": "t_max", "lockup_time_s": 2.0, "engine_speed_min_rpm": 800.0}

    (row,) = run_chunk([item], [case], metrics, crit, stopped)
    assert not any(row[f"pass:{c.text}"] for c in crit) and row["pass"] is False


def test_dask_client_leaves_a_given_client_open(local_client: Any) -> None:
    """A given client is used as it is (the warm-up plugin registered) and left open."""
    from drivetrain_ctrl.studies.runner import KernelWarmup, dask_client

    timing: dict[str, float] = {}
    with dask_client(local_client, timing=timing) as c:
        assert c is local_client
        assert c.submit(lambda: 1 + 1, pure=False).result() == 2
    assert local_client.status == "running"
    assert KernelWarmup.name in local_client.run_on_scheduler(
        lambda dask_scheduler: list(dask_scheduler.worker_plugins)
    )
    assert set(timing) >= {"startup_s", "startup_cluster_s", "startup_warmup_s", "shutdown_s"}


@pytest.mark.slow
def test_dask_client_local_cluster_without_port_8787_and_closed() -> None:
    """The local cluster: worker processes forked from the fork server, ready when it yields,
    no 'Port 8787 is already in use' warning even with port 8787 taken, closed at the end."""
    import socket
    import warnings

    from drivetrain_ctrl.studies.runner import dask_client

    with socket.socket() as held:  # port 8787 taken (or already taken by someone else)
        with contextlib.suppress(OSError):
            held.bind(("127.0.0.1", 8787))
            held.listen()
        with warnings.catch_warnings():
            warnings.simplefilter("error", UserWarning)
            with dask_client(workers=1) as c:
                assert len(c.scheduler_info()["workers"]) == 1
                assert c.submit(os.getpid, pure=False).result() != os.getpid()
    assert c.status == "closed"


# -- on a real local cluster of two worker processes -------------------------------------------
def _kill_once(case: Case, *, marker: str, victim: str) -> Mapping[str, Any]:
    """run_case, but the worker running ``victim`` kills its own process the first time."""
    if case.label == victim and not os.path.exists(marker):
        Path(marker).write_text(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    return run_case(case)


@pytest.mark.slow
def test_two_worker_processes_a_killed_worker_loses_nothing(tmp_path: Path) -> None:
    from dask.distributed import Client, LocalCluster

    f = _study(tmp_path, samples=8)
    study = load_study(f)
    marker = tmp_path / "killed"
    victim = study.keys()[5]
    run = functools.partial(_kill_once, marker=str(marker), victim=victim)
    cluster = LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        scheduler_kwargs=_NO_8787,
    )
    client = Client(cluster)
    try:
        pids = set(client.run(os.getpid).values())
        done = run_study(
            study, out=tmp_path / "k", client=client, progress=False, run=run, chunk_size=2
        )
    finally:
        client.close()
        cluster.close()
    assert marker.exists() and int(marker.read_text()) in pids  # a worker process did die
    assert done.rows == done.computed == 16
    df = read_results(tmp_path / "k")
    assert df["key"].is_unique and list(df["key"]) == sorted(study.keys())
    # the same table as an uninterrupted in-process run of the same study
    from dask.distributed import Client as C

    with C(
        processes=False,
        n_workers=1,
        threads_per_worker=1,
        dashboard_address=None,
        scheduler_kwargs=_NO_8787,
    ) as c:
        run_study(study, out=tmp_path / "ref", client=c, progress=False)
    pd.testing.assert_frame_equal(df, read_results(tmp_path / "ref"))


@pytest.mark.slow
def test_the_command_killed_mid_study_resumes_to_the_same_table(tmp_path: Path) -> None:
    f = _study(tmp_path, samples=16)
    out = tmp_path / "cli"
    cmd = [sys.executable, "-m", "drivetrain_ctrl.cli", "study", "run", str(f), "--out", str(out)]
    cmd += ["--workers", "2", "--chunk-size", "2", "--no-progress"]
    proc = subprocess.Popen(
        cmd, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and proc.poll() is None:
            if len(list((out / "results").glob("chunk-*.parquet"))) >= 2:
                break
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()
    finally:
        with __import__("contextlib").suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # the command and its workers, at once
        proc.wait()
    present = len(read_results(out))
    assert 0 < present < 32
    resumed = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{32 - present} run(s) computed" in resumed.stdout
    assert f"({present} already present)" in resumed.stdout
    from dask.distributed import Client

    with Client(
        processes=False,
        n_workers=1,
        threads_per_worker=1,
        dashboard_address=None,
        scheduler_kwargs=_NO_8787,
    ) as c:
        run_study(f, out=tmp_path / "ref", client=c, progress=False)
    pd.testing.assert_frame_equal(read_results(out), read_results(tmp_path / "ref"))


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"workers": 0}, "workers = 0"),
        ({"workers": True}, "workers = True"),
        ({"scheduler": ""}, "scheduler = ''"),
        ({"client": object(), "workers": 2}, "client: "),
    ],
)
def test_dask_client_rejects_bad_options_naming_them(kw: dict[str, Any], field: str) -> None:
    """Checked before any cluster starts (the same check as run_study's)."""
    from drivetrain_ctrl.studies.runner import dask_client

    with pytest.raises(StudyError, match=re.escape(field)), dask_client(**kw):
        pass
