"""The study driver keeps a bounded number of chunks in flight (issue 23 item 7): it makes and
submits chunks as earlier ones finish, so its memory does not grow with the rows (measured in
``benchmarks/bench_study.py``: ``driver_peak_rss_mib``)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from drivetrain_ctrl.studies import runner
from drivetrain_ctrl.studies.case import Case
from drivetrain_ctrl.studies.runner import RESULTS, read_results, run_study
from drivetrain_ctrl.studies.study import Study

STUDY: dict[str, Any] = {
    "study": {
        "name": "window",
        "model": "reduced",
        "controllers": ["paper", "pi"],
        "scenarios": ["paper-start"],
        "metrics": ["lockup_time_s"],
        "linear": False,
    },
    "sampling": {"method": "mc", "samples": 60, "seed": 1},
    "parameters": {"vehicle.M_v": {"dist": "uniform", "low": 1200.0, "high": 1400.0}},
}


def _stub(case: Case) -> dict[str, Any]:
    return {"status": "ok", "lockup_time_s": float(int(case.label[1:7]))}


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


class _Counting:
    """A client whose submit records how many chunks were in flight (submitted, not yet
    written) at each submission."""

    def __init__(self, client: Any, out: Path) -> None:
        self.client, self.out = client, out
        self.submitted = 0
        self.in_flight: list[int] = []

    def submit(self, *a: Any, **k: Any) -> Any:
        self.submitted += 1
        written = len(list((self.out / RESULTS).glob("chunk-*.parquet")))
        self.in_flight.append(self.submitted - written)
        return self.client.submit(*a, **k)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.client, name)


def test_the_driver_keeps_a_bounded_window_of_chunks(tmp_path: Path, local_client: Any) -> None:
    study = Study.from_dict(STUDY)
    out = tmp_path / "out"
    spy = _Counting(local_client, out)
    done = run_study(study, out=out, client=spy, chunk_size=2, progress=False, run=_stub)
    assert done.rows == done.computed == 120 and done.chunks == 60 == spy.submitted
    # the window, plus the finished chunk whose successor is submitted before it is written
    assert max(spy.in_flight) == runner.WINDOW * done.workers + 1 < 60
    df = read_results(out)
    assert df["key"].is_unique and len(df) == 120
    assert list(df["lockup_time_s"]) == [float(i) for i in range(60) for _ in range(2)]
    assert done.failed == 0 and done.passed == 120
