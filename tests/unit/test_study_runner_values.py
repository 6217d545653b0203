"""Values of :mod:`drivetrain_ctrl.studies.runner` that its other tests leave open (issue 22
item 4, mutation testing): the row helpers, the cluster options, the chunk names and sizes (the
defaults docs/studies.md states), the study folder's ``study.json``, the timing of
``dask_client`` and the progress bar's counts.

The expected values are written out here (numbers, a SHA-1 of the keys, the JSON text), not
taken from the runner's helpers. The runs use an in-process Dask client and a stand-in for
``run_case`` that returns records at once."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import stat
import sys
from pathlib import Path
from typing import Any

import cloudpickle
import pandas as pd
import pytest

from drivetrain_ctrl.studies import runner
from drivetrain_ctrl.studies.case import Case
from drivetrain_ctrl.studies.runner import (
    _as_number,
    _as_text,
    _chunk_name,
    _ChunkSizer,
    check_cluster_options,
    dask_client,
    read_results,
    run_chunk,
    run_study,
)
from drivetrain_ctrl.studies.study import Study, StudyError, sample_table

cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers need not import tests

STUDY: dict[str, Any] = {
    "study": {
        "name": "fake",
        "model": "reduced",
        "controllers": ["paper", "pi"],
        "scenarios": ["paper-start"],
        "metrics": ["lockup_time_s"],
        "criteria": ["lockup_time_s <= 2.0"],
        "t_end": 2.5,
    },
    "sampling": {"method": "mc", "samples": 5, "seed": 2},
    "parameters": {"vehicle.M_v": {"dist": "uniform", "low": 1000.0, "high": 2000.0}},
}


def _fake_run(case: Case) -> dict[str, Any]:
    """A record at once: the samples of even index fail, the others lock up at M_v / 1000 s."""
    sample = int(case.label[1:7])
    if sample % 2 == 0:
        return {"status": "failed", "error": "made up"}
    return {"status": "ok", "lockup_time_s": case.overrides["vehicle.M_v"] / 1000.0}


def test_numbers_and_texts_of_a_row() -> None:
    assert math.isnan(_as_number(None)) and math.isnan(_as_number("x"))
    assert math.isnan(_as_number(object()))
    assert _as_number(True) == 1.0 and _as_number(False) == 0.0
    assert _as_number(2.5) == 2.5 and _as_number(3) == 3.0 and _as_number("0.25") == 0.25
    assert _as_text(None) is None
    assert _as_text(["a", "b"]) == "a; b" and _as_text(("x",)) == "x"
    assert _as_text(3) == "3" and _as_text("note") == "note"


def test_a_metric_named_status_is_not_overwritten() -> None:
    item = ("s000001|paper|paper-start", 1, "paper", "paper-start", {"vehicle.M_v": 1500.0})
    case = Case(scenario="paper-start", controller="paper", model="reduced")

    def rec(case: Case) -> dict[str, Any]:
        return {"status": "t_max", "lockup_time_s": None, "notes": ["a", "b"]}

    (row,) = run_chunk([item], [case], ("status", "lockup_time_s", "notes"), (), rec)
    assert row["status"] == "t_max" and row["notes"] == "a; b"
    assert math.isnan(row["lockup_time_s"]) and row["error"] is None
    assert row["param:vehicle.M_v"] == 1500.0 and row["pass"] is False
    assert "lin:Ms" not in row and "linear_note" not in row


def test_items_and_cases_must_pair_up() -> None:
    item: tuple[str, int, str, str, dict[str, float]] = (
        "s000000|paper|paper-start",
        0,
        "paper",
        "paper-start",
        {},
    )
    case = Case(scenario="paper-start", controller="paper", model="reduced")
    with pytest.raises(ValueError, match="zip"):
        run_chunk([item, item], [case], (), (), _fake_run)


def test_good_cluster_options_pass() -> None:
    for kw in (
        {"workers": 1},
        {"workers": 2},
        {"scheduler": "tcp://127.0.0.1:8786"},
        {"scheduler": "tcp://127.0.0.1:8786", "workers": 2},
        {"client": object()},
        {},
    ):
        check_cluster_options(**kw)
    with pytest.raises(StudyError, match="workers = 0"):
        check_cluster_options(workers=0)
    with pytest.raises(StudyError, match="scheduler = ' '"):
        check_cluster_options(scheduler=" ")


def test_the_local_workers_start_from_the_fork_server() -> None:
    import multiprocessing

    import dask

    key = "distributed.worker.multiprocessing-method"
    before = dask.config.get(key)
    with runner._fork_server():
        inside = dask.config.get(key)
    if "forkserver" in multiprocessing.get_all_start_methods():
        assert inside == "forkserver"
    assert dask.config.get(key) == before


def test_a_chunk_file_is_named_after_the_sha1_of_its_keys() -> None:
    keys = ["s000000|paper|paper-start", "s000000|pi|paper-start"]
    digest = hashlib.sha1(b"s000000|paper|paper-start\ns000000|pi|paper-start").hexdigest()
    assert _chunk_name(keys) == f"chunk-{digest[:16]}.parquet"
    assert len(_chunk_name(["x"])) == len("chunk-") + 16 + len(".parquet")


def test_the_chunk_sizes_add_up_to_the_runs() -> None:
    s = _ChunkSizer(3, 10, 2)
    assert [s.size() for _ in range(4)] == [3, 3, 3, 1]
    one = _ChunkSizer(None, 1, 4)
    assert one.size() == 1


def test_the_default_chunk_sizes_are_the_documented_ones(monkeypatch: pytest.MonkeyPatch) -> None:
    """docs/studies.md: first chunks of 4 runs, then the runs of about 2 s of one worker's
    time, at most 1,024, at most the remaining runs over twice the workers."""
    now = [10.0]
    monkeypatch.setattr(runner.time, "perf_counter", lambda: now[0])
    s = _ChunkSizer(None, 1_000_000, 2)
    assert [s.size() for _ in range(3)] == [4, 4, 4]
    now[0] += 0.5
    s.finished(12)  # 12 runs by 2 workers in 0.5 s: 1/12 s of one worker per run
    assert s.size() == 24  # 2 s / (1/12 s)
    now[0] += 0.0
    s.finished(100_000)  # very cheap now
    assert s.size() == 1024
    tail = _ChunkSizer(None, 50, 3)
    tail.size()  # 4: 46 remain
    now[0] += 1.0
    tail.finished(1000)
    assert tail.size() == 8  # ceil(46 / 6)


def test_dask_client_times_its_start_and_its_end(local_client: Any) -> None:
    timing: dict[str, float] = {}
    with dask_client(local_client, timing=timing):
        pass
    assert 0.0 <= timing["shutdown_s"] < 60.0
    assert 0.0 <= timing["startup_cluster_s"] <= timing["startup_s"] < 600.0
    assert 0.0 <= timing["startup_warmup_s"] <= timing["startup_s"]
    assert timing["startup_cluster_s"] + timing["startup_warmup_s"] == pytest.approx(
        timing["startup_s"], abs=1e-3
    )


def test_a_run_writes_its_study_and_counts_rows(
    tmp_path: Path, local_client: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    study = Study.from_dict(STUDY)
    out = tmp_path / "new" / "o"  # made with its parents
    done = run_study(study, out=out, client=local_client, chunk_size=3, run=_fake_run)
    # the folder's study.json: the digest and the study, as indented JSON
    text = (out / "study.json").read_text()
    want = {"digest": study.digest, "study": study.to_dict()}
    assert text == json.dumps(want, indent=2, default=str) + "\n"
    df = read_results(out)
    assert list(df.index) == list(range(10))  # one index over the four chunk files
    n_failed = 3 * 2  # samples 0, 2, 4 under both controllers
    assert done.rows == done.expected == done.computed == len(df) == 10
    assert done.failed == n_failed == int((df["status"] == "failed").sum())
    assert done.chunks == 4 and done.skipped == 0 and done.workers == 1
    ok = df[df["status"] == "ok"]
    assert list(ok["lockup_time_s"]) == [v / 1000.0 for v in ok["param:vehicle.M_v"]]
    assert done.passed == int((ok["lockup_time_s"] <= 2.0).sum())
    assert 0.0 < done.wall_s < 600.0
    pd.testing.assert_frame_equal(done.table(), df)
    assert done.summary() == (
        f"10 run(s) computed in {done.wall_s:.1f} s on 1 worker(s) (0 already present); "
        f"10 of 10 rows in {out / 'results'}, 6 failed, {done.passed} passed every criterion"
    )
    # the lock file: readable by all, writable by its owner (less what the umask takes away)
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE((out / runner.LOCK).stat().st_mode) == 0o644 & ~umask
    assert (out / runner.LOCK).read_text().startswith(f"pid {os.getpid()} on host ")
    # the record is frozen; a second run of the complete folder computes nothing on no worker
    with pytest.raises(dataclasses.FrozenInstanceError):
        done.rows = 0  # type: ignore[misc]
    again = run_study(study, out=out, client=local_client, chunk_size=3, run=_fake_run)
    assert (again.computed, again.skipped, again.workers, again.chunks) == (0, 10, 0, 0)
    assert again.rows == 10
    # a chunk file is written where its name says, and reads back as its rows
    rows = [{"key": "k1", "status": "ok"}, {"key": "k2", "status": "failed"}]
    schema = runner._schema(study)
    path = runner._write_chunk(tmp_path, rows, schema)
    assert path == tmp_path / runner._chunk_name(["k1", "k2"]) and path.is_file()
    assert list(pd.read_parquet(path)["key"]) == ["k1", "k2"]
    # the folder's sample table: the study's samples, one row per sample
    samples = pd.read_parquet(out / "samples.parquet")
    pd.testing.assert_frame_equal(samples, sample_table(study))
    assert list(samples.columns) == ["vehicle.M_v"] and len(samples) == 5
    # the progress bar ends with every run done: nothing remaining, the failed ones counted
    err = capsys.readouterr().err
    assert re.findall(r"remaining=(\d+)", err)[-1] == "0"
    assert re.findall(r"failed=(\d+)", err)[-1] == str(n_failed)
    assert "10/10" in err


def test_an_output_folder_that_is_not_a_path_is_named() -> None:
    study = Study.from_dict(STUDY)
    for bad, named in ((None, "out = None"), (True, "out = True"), (3, "out = 3")):
        with pytest.raises(StudyError, match=f"{re.escape(named)}: give an output folder"):
            run_study(study, out=bad, run=_fake_run)  # type: ignore[arg-type]


def test_a_folder_without_results_is_named(tmp_path: Path) -> None:
    (tmp_path / "results").mkdir()
    with pytest.raises(FileNotFoundError, match=r"no results \(run the study first\)"):
        read_results(tmp_path)


def test_four_chunks_per_worker_are_in_flight_at_first(
    tmp_path: Path, local_client: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """docs/studies.md: the driver submits chunks as earlier ones finish, at most four per
    worker in flight. Seen as the chunks submitted before the first result is waited for."""
    import dask.distributed

    real = dask.distributed.as_completed
    first: list[int] = []

    class Spy(real):  # type: ignore[misc, valid-type]
        def __iter__(self) -> Any:
            first.append(self.count())
            return super().__iter__()

    monkeypatch.setattr(dask.distributed, "as_completed", Spy)
    done = run_study(
        Study.from_dict(STUDY),
        out=tmp_path / "w",
        client=local_client,
        chunk_size=1,
        progress=False,
        run=_fake_run,
    )
    assert done.workers == 1 and done.chunks == 10
    assert first == [4]


class _Stop(Exception):
    """Raised by the stand-in LocalCluster: the test only wants its arguments."""


def test_a_local_cluster_has_one_worker_per_core_unless_told(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import dask.distributed

    seen: list[dict[str, Any]] = []

    def cluster(**kw: Any) -> None:
        seen.append(kw)
        raise _Stop

    monkeypatch.setattr(dask.distributed, "LocalCluster", cluster)
    for workers, cores in ((3, 8), (None, 5), (None, None)):
        monkeypatch.setattr(runner.os, "cpu_count", lambda c=cores: c)
        with pytest.raises(_Stop), dask_client(workers=workers):
            pass
    assert [kw["n_workers"] for kw in seen] == [3, 5, 1]
    assert all(kw["threads_per_worker"] == 1 and kw["processes"] is True for kw in seen)


def test_a_second_writer_of_a_folder_is_refused_naming_the_holder(tmp_path: Path) -> None:
    """flock locks of two open files conflict also within one process: the second holder is
    refused with the first one's note (its pid); after the first lets go, the folder is free."""
    import os

    from drivetrain_ctrl.studies.runner import folder_lock

    with folder_lock(tmp_path) as path:
        assert path == tmp_path / ".lock"
        assert (tmp_path / ".lock").read_text().startswith(f"pid {os.getpid()} on host ")
        with (
            pytest.raises(StudyError, match=f"another study run is writing.*pid {os.getpid()}"),
            folder_lock(tmp_path),
        ):
            pass
    with folder_lock(tmp_path):
        pass
    assert (tmp_path / ".lock").exists()  # never removed


@pytest.mark.parametrize("run", [3, "run_case", None])
def test_a_run_that_is_not_a_function_is_named(tmp_path: Path, run: object) -> None:
    with pytest.raises(StudyError, match=r"^run = .*: must be a function from a Case to a record$"):
        run_study(Study.from_dict(STUDY), out=tmp_path / "o", run=run)  # type: ignore[arg-type]
    assert not (tmp_path / "o").exists()  # refused before anything is written


def test_one_worker_gets_half_the_remaining_runs_at_most() -> None:
    """After the first chunk, at most the remaining runs over twice the workers: one worker."""
    s = _ChunkSizer(None, 10, 1)
    assert s.size() == runner.FIRST_CHUNK == 4
    s.finished(4)  # at once: the target alone would allow a huge chunk
    assert [s.size(), s.size()] == [3, 2]  # ceil(6 / 2), ceil(3 / 2)


@pytest.mark.parametrize("linear", [True, False])
def test_the_linear_columns_are_in_the_schema_iff_the_study_asks(linear: bool) -> None:
    d = {**STUDY, "study": {**STUDY["study"], "linear": linear}}
    names = runner._schema(Study.from_dict(d)).names
    want = {*runner.LINEAR_FIGURES, "linear_note"}
    assert (want <= set(names)) if linear else not (want & set(names))
