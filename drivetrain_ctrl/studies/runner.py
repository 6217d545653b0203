"""Running a study on Dask: chunks of cases on worker processes, one Parquet file per chunk, resume.

:func:`run_study` runs every row of a :class:`~drivetrain_ctrl.studies.study.Study` (sample x
controller x scenario) through :func:`~drivetrain_ctrl.studies.case.run_case`, the one function
from a case to a record; Dask (``dask.distributed``) only decides where. By default a local
cluster of worker processes (one per core, one thread each) is started and closed again; give a
``client`` or a ``scheduler`` address to use an existing cluster. Every worker loads the compiled
kernels once, when it joins (a worker plugin running :func:`~drivetrain_ctrl.sim.warmup.warmup`).

Nothing lost, nothing twice. The rows are cut into chunks; the driver writes each finished
chunk as its own Parquet file under ``OUT/results/`` atomically (a temporary file, flushed, then
:func:`os.replace`), named after the keys it holds. A re-run of the same study into the same
folder reads the keys present and runs only the missing ones, so an interrupted run (Ctrl-C,
a killed command) resumes where it stopped, and a chunk whose worker died is retried by Dask
and written once. A run that fails (Zeno, non-finite state, step size, invalid parameter
values) is a row with ``status = "failed"`` and its ``error``; the study goes on.
:func:`read_results` gives the table, sorted by key: the same for a resumed run as for an
uninterrupted one.

The table: one row per ``key`` = ``s<sample>|<controller>|<scenario>`` with ``sample``,
``controller``, ``scenario``, the parameters ``param:<name>`` (SI units), ``status``
(``ok``, ``failed`` or why the run stopped early), ``error``, the study's metrics (numbers as
float64, a flag as 0/1, None as NaN; ``model``, ``status``, ``notes`` as text), with
``study.linear`` the paired linear figures and ``linear_note`` (below), one
``pass:<criterion>`` column per criterion and ``pass`` (status ``ok`` and every criterion met).

The paired linear figures (:data:`~drivetrain_ctrl.studies.case.LINEAR_FIGURES`, float64, NaN
where undefined, the reason in the text column ``linear_note``), of the row's slip-mode clutch
loop ``L = C P`` (controller, sign, rate limiter, actuator, clutch and engine, the driveline coupled
in; :func:`~drivetrain_ctrl.linear.clutch.clutch_loop`) linearised at the row's own run 0.3 s
after the controller start
(:func:`~drivetrain_ctrl.linear.operating_point.slip_point_after_start`), with the row's
parameters and model: ``lin:gain_margin`` (a factor, not dB), ``lin:phase_margin_deg`` [deg],
``lin:crossover_rad_s`` [rad/s], ``lin:disk_margin`` (alpha, skew 0), ``lin:Ms`` (max ``|S|``),
``lin:stable`` (1/0), ``lin:mu_slope`` and ``lin:mu_slope_crit`` [s/rad] (the friction slope of
mu/mu0 at the point and the judder threshold, < 0), ``lin:judder_margin`` = ``1 - mu'/mu'_crit``
[-] and ``lin:t_s`` [s] (see :func:`~drivetrain_ctrl.studies.case.linear_figures`).

One writer per folder: :func:`run_study` holds :func:`folder_lock` on ``OUT/.lock``.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import math
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
from dask.distributed import WorkerPlugin

from .case import LINEAR_FIGURES, Case, CaseError, run_case
from .study import TEXT_METRICS, Criterion, Study, StudyError, load_study, sample_table

__all__ = [
    "KernelWarmup",
    "StudyRun",
    "check_cluster_options",
    "dask_client",
    "folder_lock",
    "read_results",
    "run_chunk",
    "run_study",
]

RESULTS = "results"
#: the columns every table has before the parameters
ID_COLUMNS: tuple[str, ...] = ("key", "sample", "controller", "scenario")

Runner = Callable[[Case], Mapping[str, Any]]


@dataclass(frozen=True)
class StudyRun:
    """What :func:`run_study` did: the folder ``out``, ``rows`` in its table now (of
    ``expected``), ``computed`` by this call, ``skipped`` (present before), ``failed`` rows of
    the table, ``passed`` rows, ``chunks`` written, ``workers`` used and ``wall_s`` [s]."""

    out: Path
    expected: int
    rows: int
    computed: int
    skipped: int
    failed: int
    passed: int
    chunks: int
    workers: int
    wall_s: float

    def table(self) -> pd.DataFrame:
        """The results table (:func:`read_results`)."""
        return read_results(self.out)

    def summary(self) -> str:
        """One sentence: what was run and what the table holds."""
        return (
            f"{self.computed} run(s) computed in {self.wall_s:.1f} s on {self.workers} worker(s) "
            f"({self.skipped} already present); {self.rows} of {self.expected} rows in "
            f"{self.out / RESULTS}, {self.failed} failed, {self.passed} passed every criterion"
        )


# -- on the workers ---------------------------------------------------------------------------
class KernelWarmup(WorkerPlugin):  # type: ignore[misc]
    """Dask worker plugin: load (or compile) the simulator kernels once when a worker starts,
    so no chunk pays for it."""

    name = "drivetrain-ctrl-kernels"

    def setup(self, worker: Any) -> None:  # noqa: ARG002 - the plugin interface
        """Run the tiny warm-up simulations (:func:`~drivetrain_ctrl.sim.warmup.warmup`)."""
        from ..sim.warmup import warmup

        warmup()


#: the local cluster's scheduler HTTP server (health and metrics routes, which Dask starts even
#: without the dashboard): an ephemeral port on the loopback interface, so that it never asks
#: for port 8787 ("Port 8787 is already in use" when another cluster holds it)
_SCHEDULER_HTTP = "127.0.0.1:0"


#: what the local workers' fork server imports once, before it forks them (:func:`_fork_server`)
_PRELOAD: tuple[str, ...] = (
    "distributed",
    "drivetrain_ctrl.studies.runner",
    "drivetrain_ctrl.studies.compare",
)


@contextlib.contextmanager
def _fork_server() -> Iterator[None]:
    """Start the local cluster's worker processes from a fork server that has imported
    :data:`_PRELOAD` once (Dask's documented ``distributed.worker.multiprocessing-method``
    ``forkserver``, with :meth:`multiprocessing.context.ForkServerContext.set_forkserver_preload`):
    the workers begin with the package imported instead of importing it each (``spawn``, the
    default: several seconds per worker, all at once), and they exit faster. The fork server is
    a fresh single-threaded process (not a fork of this one) and lives as long as this process.
    Without ``forkserver`` on the platform, nothing changes."""
    import multiprocessing

    import dask

    if "forkserver" not in multiprocessing.get_all_start_methods():
        yield
        return
    from distributed.utils import get_mp_context

    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        # Dask sets its own preload list on first use; ours replaces it (the fork server reads
        # the list when it starts, at the first worker)
        get_mp_context().set_forkserver_preload(list(_PRELOAD))
        yield


def check_cluster_options(
    *,
    client: Any = None,
    workers: Any = None,
    scheduler: Any = None,
    error: type[ValueError] = StudyError,
) -> None:
    """Raise ``error`` naming the option unless ``workers`` is None or an integer >= 1,
    ``scheduler`` None or a non-empty address, and at most one of ``client`` and
    ``scheduler``/``workers`` is given (the options of :func:`dask_client`)."""
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise error(f"workers = {workers!r}: must be an integer >= 1")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise error(f"scheduler = {scheduler!r}: must be an address like tcp://host:8786")
    if client is not None and (scheduler is not None or workers is not None):
        raise error("client: give a client, or a scheduler address / workers, not both")


@contextlib.contextmanager
def dask_client(
    client: Any = None,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    timing: dict[str, float] | None = None,
) -> Iterator[Any]:
    """A ready ``dask.distributed.Client`` with :class:`KernelWarmup` registered (every worker
    has loaded the kernels when this yields): ``client`` itself (left open), else a client of
    the running scheduler at ``scheduler`` (closed at the end), else a local cluster of
    ``workers`` single-threaded worker processes (default: the number of cores; closed at the
    end; its workers forked from a fork server with the package imported, :func:`_fork_server`),
    without the dashboard. The kernels are first compiled here when numba's cache lacks
    them, so that the local workers do not all compile at once. ``timing``: filled with
    ``startup_s`` (all of the above; of it ``startup_cluster_s`` up to a connected client and
    ``startup_warmup_s`` the workers' kernel loading) and ``shutdown_s`` [s]."""
    check_cluster_options(client=client, workers=workers, scheduler=scheduler)
    from dask.distributed import Client, LocalCluster

    from ..sim.warmup import ensure_compiled

    tic = time.perf_counter()
    ensure_compiled()
    cluster = None
    own = client is None
    if client is None:
        if scheduler is not None:
            client = Client(scheduler)
        else:
            with _fork_server():
                cluster = LocalCluster(
                    n_workers=workers or os.cpu_count() or 1,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    scheduler_kwargs={"dashboard_address": _SCHEDULER_HTTP},
                )
            client = Client(cluster)
    t_warm = time.perf_counter()
    try:
        client.register_plugin(KernelWarmup(), name=KernelWarmup.name)
        if timing is not None:
            timing["startup_s"] = time.perf_counter() - tic
            timing["startup_cluster_s"] = t_warm - tic
            timing["startup_warmup_s"] = time.perf_counter() - t_warm
        yield client
    finally:
        t_close = time.perf_counter()
        if own:
            client.close()
        if cluster is not None:
            cluster.close()
        if timing is not None:
            timing["shutdown_s"] = time.perf_counter() - t_close


def _as_number(v: Any) -> float:
    if v is None:
        return math.nan
    if isinstance(v, bool):
        return 1.0 if v else 0.0
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _as_text(v: Any) -> str | None:
    if v is None:
        return None
    if isinstance(v, list | tuple):
        return "; ".join(str(x) for x in v)
    return str(v)


def _row(
    item: tuple[str, int, str, str, Mapping[str, float]],
    record: Mapping[str, Any],
    metrics: Sequence[str],
    criteria: Sequence[Criterion],
    linear: bool = False,
) -> dict[str, Any]:
    key, sample, controller, scenario, values = item
    status = str(record.get("status") or "failed")
    row: dict[str, Any] = {
        "key": key,
        "sample": sample,
        "controller": controller,
        "scenario": scenario,
        **{f"param:{k}": float(v) for k, v in values.items()},
        "status": status,
        "error": _as_text(record.get("error")),
    }
    for m in metrics:
        if m == "status":
            continue
        v = record.get(m)
        row[m] = _as_text(v) if m in TEXT_METRICS else _as_number(v)
    if linear:
        for k in LINEAR_FIGURES:
            row[k] = _as_number(record.get(k))
        row["linear_note"] = _as_text(record.get("linear_note"))
    ok = status == "ok"
    met = []
    for c in criteria:  # each column its own criterion (not "this and the earlier ones")
        passed = ok and bool(c.check([_as_number(record.get(c.metric))])[0])
        row[f"pass:{c.text}"] = passed
        met.append(passed)
    row["pass"] = ok and all(met)
    return row


def run_chunk(
    items: Sequence[tuple[str, int, str, str, Mapping[str, float]]],
    cases: Sequence[Case],
    metrics: Sequence[str],
    criteria: Sequence[Criterion],
    run: Runner = run_case,
    linear: bool = False,
) -> list[dict[str, Any]]:
    """The rows of one chunk (runs on a worker): ``run`` (:func:`run_case`) on every case; an
    exception of one run (invalid parameter values, a simulator error) becomes a failed row with
    the reason, so one bad sample never stops a chunk. ``linear``: the rows have the
    ``lin:`` columns and ``linear_note``."""
    rows = []
    for item, case in zip(items, cases, strict=True):
        try:
            record: Mapping[str, Any] = run(case)
        except CaseError as exc:
            record = {"status": "failed", "error": f"invalid input: {exc}"}
        except Exception as exc:  # noqa: BLE001 - recorded with its reason, the study goes on
            record = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
        rows.append(_row(item, record, metrics, criteria, linear))
    return rows


# -- the table on disk ------------------------------------------------------------------------
def _schema(study: Study) -> Any:
    import pyarrow as pa

    fields = [
        pa.field("key", pa.string()),
        pa.field("sample", pa.int64()),
        pa.field("controller", pa.string()),
        pa.field("scenario", pa.string()),
        *(pa.field(f"param:{p.name}", pa.float64()) for p in study.parameters),
        pa.field("status", pa.string()),
        pa.field("error", pa.string()),
        *(
            pa.field(m, pa.string() if m in TEXT_METRICS else pa.float64())
            for m in study.metrics
            if m != "status"
        ),
        *(pa.field(k, pa.float64()) for k in (LINEAR_FIGURES if study.linear else ())),
        *([pa.field("linear_note", pa.string())] if study.linear else []),
        *(pa.field(f"pass:{c.text}", pa.bool_()) for c in study.criteria),
        pa.field("pass", pa.bool_()),
    ]
    return pa.schema(fields)


def _atomic_write(path: Path, write: Callable[[Path], object]) -> None:
    """``write`` to a temporary file beside ``path``, flush it to disk, rename it to ``path``."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        write(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _chunk_name(keys: Sequence[str]) -> str:
    h = hashlib.sha1("\n".join(keys).encode()).hexdigest()[:16]
    return f"chunk-{h}.parquet"


def _write_chunk(folder: Path, rows: list[dict[str, Any]], schema: Any) -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols = {f.name: [r.get(f.name) for r in rows] for f in schema}
    table = pa.Table.from_pydict(cols, schema=schema)
    path = folder / _chunk_name([r["key"] for r in rows])
    _atomic_write(path, lambda p: pq.write_table(table, p))
    return path


def _chunk_files(out: Path) -> list[Path]:
    return sorted((out / RESULTS).glob("chunk-*.parquet"))


def _present_keys(out: Path) -> set[str]:
    import pyarrow.parquet as pq

    keys: set[str] = set()
    for f in _chunk_files(out):
        keys.update(pq.read_table(f, columns=["key"]).column("key").to_pylist())
    return keys


def read_results(out: str | Path) -> pd.DataFrame:
    """The results table of study folder ``out``: every chunk file, sorted by ``key``, index
    0..n-1 (see the module docstring for the columns)."""
    import pyarrow.parquet as pq

    files = _chunk_files(Path(out))
    if not files:
        raise FileNotFoundError(f"{Path(out) / RESULTS}: no results (run the study first)")
    df = pd.concat([pq.read_table(f).to_pandas() for f in files], ignore_index=True)
    return df.sort_values("key", kind="stable").reset_index(drop=True)


def _prepare_folder(study: Study, out: Path) -> pd.DataFrame:
    """Create ``out`` (``study.json``, ``samples.parquet``) or check that it holds this study;
    remove temporary files a killed run left behind; the sample table."""
    (out / RESULTS).mkdir(parents=True, exist_ok=True)
    meta = out / "study.json"
    digest = study.digest
    if meta.exists():
        try:
            old = json.loads(meta.read_text()).get("digest")
        except (OSError, ValueError):
            old = None
        if old != digest:
            raise StudyError(
                f"out = {str(out)!r}: the folder holds results of another study (or another "
                "version of it); give a new folder"
            )
    else:
        text = json.dumps({"digest": digest, "study": study.to_dict()}, indent=2, default=str)
        _atomic_write(meta, lambda p: p.write_text(text + "\n"))
    for tmp in (out / RESULTS).glob(".chunk-*.tmp-*"):
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    samples = sample_table(study)
    sp = out / "samples.parquet"
    if not sp.exists():
        _atomic_write(sp, lambda p: samples.to_parquet(p))
    return samples


LOCK = ".lock"


@contextlib.contextmanager
def folder_lock(out: Path) -> Iterator[Path]:
    """Hold the study folder ``out`` for one writer: an exclusive ``flock`` on ``out/.lock``
    (created if missing; it then holds the holder's pid, host and start time). A second
    ``study run`` on the same folder gets a :class:`StudyError` naming the holder instead of
    writing beside it. The operating system releases the lock when its holder exits, however
    it ends (Ctrl-C, killed), so a lock is never stale: the file left behind is only a note of
    the last holder. The file is never removed (a waiting writer could lock a removed file)."""
    import fcntl
    import socket

    path = out / LOCK
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 4096, 0).decode(errors="replace").strip() or "unknown"
            raise StudyError(
                f"out = {str(out)!r}: another study run is writing to this folder ({holder}); "
                "wait for it to finish (a re-run then resumes), or give another folder"
            ) from None
        note = (
            f"pid {os.getpid()} on host {socket.gethostname()}, since "
            f"{time.strftime('%Y-%m-%d %H:%M:%S %Z')}"
        )
        os.ftruncate(fd, 0)
        os.pwrite(fd, note.encode() + b"\n", 0)
        yield path
    finally:
        os.close(fd)  # releases the lock


#: chunks in flight per worker (submitted ahead of the finished ones)
WINDOW = 4
#: the worker time [s] a default-sized chunk aims at: long enough that the per-chunk costs (a Dask
#: task, a Parquet file written and flushed: tens of ms) stay a few per cent of it, short enough
#: that the progress bar moves and an interruption loses little
CHUNK_TARGET_S = 2.0
#: the size of the first chunks, before a run's cost is known
FIRST_CHUNK = 4
#: the largest default chunk [runs]
MAX_CHUNK = 1024


class _ChunkSizer:
    """The size of the next chunk. ``fixed``: always that. Otherwise :data:`FIRST_CHUNK` until a
    chunk has come back, then the runs that take about :data:`CHUNK_TARGET_S` on one worker (the
    cost of a run estimated from the wall time so far times the workers, over the runs done),
    at most :data:`MAX_CHUNK`, and at most the remaining runs over twice the workers, so that the
    last chunks share out evenly."""

    def __init__(self, fixed: int | None, total: int, workers: int) -> None:
        self.fixed, self.remaining, self.workers = fixed, total, max(1, workers)
        self.done = 0
        self.tic = time.perf_counter()

    def finished(self, rows: int) -> None:
        self.done += rows

    def size(self) -> int:
        if self.fixed is not None:
            n = self.fixed
        elif self.done == 0:
            n = FIRST_CHUNK
        else:
            per_run = (time.perf_counter() - self.tic) * self.workers / self.done
            n = round(CHUNK_TARGET_S / max(per_run, 1e-6))
            n = min(n, MAX_CHUNK, math.ceil(self.remaining / (2 * self.workers)))
        n = max(1, min(n, self.remaining))
        self.remaining -= n
        return n


def _chunked(items: Iterator[Any], size: Callable[[], int]) -> Iterator[list[Any]]:
    """``items`` in lists of ``size()`` (asked for each list), made as they are asked for."""
    while True:
        ch = list(itertools.islice(items, size()))
        if not ch:
            return
        yield ch


def _counts(out: Path) -> tuple[int, int, int]:
    """(rows, failed rows, rows that pass) of the table in ``out``, reading only those columns."""
    import pyarrow.parquet as pq

    n = failed = passed = 0
    for f in _chunk_files(out):
        t = pq.read_table(f, columns=["status", "pass"])
        n += t.num_rows
        failed += sum(v == "failed" for v in t.column("status").to_pylist())
        passed += sum(bool(v) for v in t.column("pass").to_pylist())
    return n, failed, passed


def _items(study: Study, samples: pd.DataFrame, missing: set[str]) -> Iterator[Any]:
    names = list(samples.columns)
    values = samples.to_numpy()
    for i in range(study.samples):
        vals = {n: float(v) for n, v in zip(names, values[i], strict=True)}
        for c in study.controller_names:
            for j, s in enumerate(study.scenario_names):
                case = study.case(i, vals, c, j)
                if case.label in missing:
                    yield (case.label, i, c, s, vals), case


def _progress(total: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="run", disable=not enabled, dynamic_ncols=True, smoothing=0.1)


def run_study(
    study: Study | str | Path,
    *,
    out: str | Path,
    client: Any = None,
    workers: int | None = None,
    scheduler: str | None = None,
    chunk_size: int | None = None,
    progress: bool = True,
    run: Runner = run_case,
) -> StudyRun:
    """Run ``study`` (a :class:`Study` or a study file) into folder ``out``; resumes what is there.

    ``client``: a :class:`dask.distributed.Client` to run on (left open); else ``scheduler``: the
    address of a running Dask scheduler to connect to; else a local cluster of ``workers`` worker
    processes (default: the number of cores), one thread each, closed at the end.
    ``chunk_size``: runs per task (default: sized as the study goes to about
    :data:`CHUNK_TARGET_S` of work each, :class:`_ChunkSizer`).
    ``progress``: a progress bar on stderr (runs done, failed, remaining, ETA). ``run``: the
    function from a case to a record (default :func:`run_case`; a picklable replacement serves
    tests). Returns a :class:`StudyRun`; the table is :func:`read_results` of ``out``.
    """
    tic = time.perf_counter()
    if not isinstance(study, Study):
        study = load_study(study)
    if isinstance(out, bool) or not isinstance(out, str | Path) or not str(out).strip():
        raise StudyError(f"out = {out!r}: give an output folder")
    check_cluster_options(client=client, workers=workers, scheduler=scheduler)
    if chunk_size is not None and (
        isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1
    ):
        raise StudyError(f"chunk_size = {chunk_size!r}: must be an integer >= 1")
    if not callable(run):
        raise StudyError(f"run = {run!r}: must be a function from a Case to a record")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with folder_lock(out):
        return _run_locked(study, out, client, workers, scheduler, chunk_size, progress, run, tic)


def _run_locked(
    study: Study,
    out: Path,
    client: Any,
    workers: int | None,
    scheduler: str | None,
    chunk_size: int | None,
    progress: bool,
    run: Runner,
    tic: float,
) -> StudyRun:
    """:func:`run_study` once its arguments are checked and the folder is locked."""
    samples = _prepare_folder(study, out)
    all_keys = study.keys()
    missing = set(all_keys) - _present_keys(out)
    n_todo = len(missing)
    schema = _schema(study)
    n_chunks = 0
    n_workers = 0
    if n_todo:
        from dask.distributed import as_completed

        with dask_client(client, workers=workers, scheduler=scheduler) as client:
            n_workers = max(1, len(client.scheduler_info().get("workers", {})))
            sizer = _ChunkSizer(chunk_size, n_todo, n_workers)
            # the chunks are made and submitted as the earlier ones finish: at most WINDOW per
            # worker in flight, so the driver holds the cases and rows of a few chunks only,
            # however many rows the study has
            chunks = _chunked(_items(study, samples, missing), sizer.size)

            def submit(ch: list[Any]) -> Any:
                return client.submit(
                    run_chunk,
                    [it for it, _ in ch],
                    [c for _, c in ch],
                    study.metrics,
                    study.criteria,
                    run,
                    study.linear,
                    key=_chunk_name([it[0] for it, _ in ch]).removesuffix(".parquet"),
                    pure=False,
                )

            pending = as_completed()
            for ch in itertools.islice(chunks, WINDOW * n_workers):
                pending.add(submit(ch))
            failed = 0
            with _progress(n_todo, progress) as bar:
                for fut in pending:
                    rows = fut.result()
                    fut.release()
                    sizer.finished(len(rows))
                    nxt = next(chunks, None)
                    if nxt is not None:
                        pending.add(submit(nxt))
                    _write_chunk(out / RESULTS, rows, schema)
                    n_chunks += 1
                    failed += sum(r["status"] == "failed" for r in rows)
                    remaining = bar.total - bar.n - len(rows)
                    bar.set_postfix(failed=failed, remaining=remaining, refresh=False)
                    bar.update(len(rows))
                    del rows, fut
    n_rows, n_failed, n_pass = _counts(out)
    return StudyRun(
        out=out,
        expected=len(all_keys),
        rows=n_rows,
        computed=n_todo,
        skipped=len(all_keys) - len(missing),
        failed=n_failed,
        passed=n_pass,
        chunks=n_chunks,
        workers=n_workers,
        wall_s=time.perf_counter() - tic,
    )
