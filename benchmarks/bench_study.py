"""A robustness study's speed: one against two local workers, and a run's cost beyond simulate().

Usage::

    python benchmarks/bench_study.py [--samples 100] [--full-samples 20] [--out DIR]

1. The quick study (``analyses/studies/paper_start_quick.toml``: law (6) and the PI on
   ``paper-start``, reduced model) with ``--samples`` Latin-hypercube samples, run by
   :func:`run_study` on a local cluster of one and then of two worker processes. The cluster's
   start and the kernel loading on its workers (``startup_s_*``) are timed apart from the study
   itself (``wall_s_*``: submitting the chunks to the last Parquet file written).
2. A bare full-model ``simulate()`` of ``paper-start`` under law (6) (``simulate_ms``: the
   median of repeats on the worker itself, before and after the study, the lower of the two)
   against what one full-model row of a study costs: the same study on the full model with
   ``--full-samples`` samples on that one worker (``full_run_ms``: its wall time per row), so ``overhead_vs_simulate = full_run_ms / simulate_ms - 1`` counts everything beyond the
   call: building the case, the metrics, the bookkeeping, Dask and Parquet. In this process:
   ``in_process_simulate_ms``, ``in_process_case_ms`` (:func:`run_case` without the linear
   figures; ``_nocache``: the per-worker caches off; ``_linear``: with them),
   ``in_process_metrics_ms`` (:func:`engagement_metrics`), ``in_process_controller_ms`` (building
   the controller again for the case just run: its stability check found in
   :meth:`ControllerSpec.check_stability`'s cache), ``in_process_controller_fresh_ms`` (the same
   with that cache emptied: the check computed, as in a row whose sample brings new clutch or
   actuator values) and ``in_process_linear_ms``
   (:func:`linear_figures`), each the median over ``--repeats`` samples of the study.
3. The driver's memory: the shipped ``paper_start_mc.toml`` (cut to ``--memory-samples``
   samples, 10,000 by default: 20,000 rows) run by :func:`run_study` on ``--workers`` local
   workers with a stub run (no simulation: the driver's memory does not depend on what a run
   costs), in a fresh process; ``driver_peak_rss_mib`` is its peak resident set
   (``resource.getrusage``, the workers not counted) for the last count, and
   ``driver_memory_runs`` every count's (a smaller one shows whether it grows with the rows).

Writes ``results/study.json`` (``samples``, ``wall_s_1_worker``, ``wall_s_2_workers``,
``samples_per_s``, ``speedup_2_vs_1``, ``simulate_ms``, ``overhead_vs_simulate`` and the parts)
and prints it. ``samples_per_s`` counts rows (sample x controller) per second with two workers;
``extrapolated_10000_s_2_workers`` is the 10,000-sample study's time at that rate (no startup).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def _study(samples: int, model: str) -> Any:
    import tomllib

    from drivetrain_ctrl.studies.study import Study

    d = tomllib.loads((ROOT / "analyses" / "studies" / "paper_start_quick.toml").read_text())
    d["sampling"]["samples"] = samples
    d["study"]["model"] = model
    d["study"]["name"] = f"bench-{model}-{samples}"
    return Study.from_dict(d)


def _bare_simulate_ms(repeats: int) -> float:
    """Median wall time [ms] of a bare full-model ``paper-start`` run under law (6) (run where
    it is called: on a worker, in the conditions of the study's runs)."""
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.run import run_scenario

    sc = load_scenario("paper-start")
    dt = sc.drivetrain(default_params(), kind="full")
    ctrl = sc.make_controller(dt, "paper")
    run_scenario(sc, dt, controller=ctrl)
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        run_scenario(sc, dt, controller=ctrl)
        times.append(time.perf_counter() - tic)
    return 1e3 * statistics.median(times)


def _timed_study(
    study: Any, workers: int, out: Path, simulate_repeats: int = 0
) -> tuple[float, float, int, float]:
    """(startup [s], study wall [s], rows, bare simulate() on a worker [ms] if asked) of
    ``study`` on a fresh local cluster."""
    from dask.distributed import Client, LocalCluster

    from drivetrain_ctrl.studies.runner import KernelWarmup, run_study

    tic = time.perf_counter()
    cluster = LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    )
    client = Client(cluster)
    client.register_plugin(KernelWarmup(), name=KernelWarmup.name)
    startup = time.perf_counter() - tic
    try:
        sim_ms = math.nan
        if simulate_repeats:
            sim_ms = client.submit(_bare_simulate_ms, simulate_repeats, pure=False).result()
        tic = time.perf_counter()
        done = run_study(study, out=out, client=client, progress=False)
        wall = time.perf_counter() - tic
        if simulate_repeats:  # again after the study: the load of a shared machine drifts
            sim_ms = min(
                sim_ms, client.submit(_bare_simulate_ms, simulate_repeats, pure=False).result()
            )
    finally:
        client.close()
        cluster.close()
    assert done.rows == done.expected == done.computed, done.summary()
    return startup, wall, done.rows, sim_ms


def _in_process(repeats: int) -> dict[str, float]:
    """Median in-process timings [ms] of the parts of a full-model row of the quick study under
    law (6): ``simulate`` (a bare run), ``metrics`` (:func:`engagement_metrics` of it),
    ``controller`` (building the closed-loop controller, its stability check cached),
    ``controller_fresh`` (the same with the check computed),
    ``linear`` (:func:`linear_figures` of it), ``case`` (:func:`run_case` of a sample's case
    without the linear figures, the per-worker caches on), ``case_nocache`` (the same with the
    caches off) and ``case_linear`` (with the linear figures). Every repeat is another sample of
    the study (as on a worker), and the sample's second controller (PI) runs before law (6)."""
    import dataclasses

    from drivetrain_ctrl.control.laws import _STABILITY_CACHE
    from drivetrain_ctrl.sim.metrics import engagement_metrics
    from drivetrain_ctrl.sim.run import run_scenario
    from drivetrain_ctrl.studies.case import caching, linear_figures, run_case, simulate_case
    from drivetrain_ctrl.studies.study import sample_table

    study = _study(repeats + 1, "full")
    df = sample_table(study)
    parts: dict[str, list[float]] = {
        k: []
        for k in ("simulate", "metrics", "controller", "controller_fresh", "linear", "case")
        + ("case_nocache", "case_linear")
    }
    for i in range(repeats + 1):
        vals = {str(k): float(v) for k, v in df.iloc[i].items()}
        paper = study.case(i, vals, "paper", 0)
        pi = study.case(i, vals, "pi", 0)
        off = dataclasses.replace(paper, linear=False)
        run_case(dataclasses.replace(pi, linear=False))  # the sample's other controller first
        tic = time.perf_counter()
        run_case(off)
        t_case = time.perf_counter() - tic
        with caching(False):
            tic = time.perf_counter()
            run_case(off)
            t_nocache = time.perf_counter() - tic
        tic = time.perf_counter()
        run_case(dataclasses.replace(paper, linear=True))
        t_lin_case = time.perf_counter() - tic
        run = simulate_case(off)
        sc, dt = run.scenario, run.drivetrain
        tic = time.perf_counter()
        ctrl = sc.make_controller(dt, run.spec)
        t_ctrl = time.perf_counter() - tic
        _STABILITY_CACHE.clear()
        tic = time.perf_counter()
        sc.make_controller(dt, run.spec)
        t_ctrl_fresh = time.perf_counter() - tic
        tic = time.perf_counter()
        res = run_scenario(sc, dt, controller=ctrl, t_end=study.t_end)
        t_sim = time.perf_counter() - tic
        tic = time.perf_counter()
        engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
        t_met = time.perf_counter() - tic
        tic = time.perf_counter()
        linear_figures(res, dt, ctrl, start=sc.start_time)
        t_lin = time.perf_counter() - tic
        if i == 0:
            continue  # the first sample loads what the others find loaded
        for k, v in (
            ("simulate", t_sim),
            ("metrics", t_met),
            ("controller", t_ctrl),
            ("controller_fresh", t_ctrl_fresh),
            ("linear", t_lin),
            ("case", t_case),
            ("case_nocache", t_nocache),
            ("case_linear", t_lin_case),
        ):
            parts[k].append(v)
    return {f"{k}_ms": 1e3 * statistics.median(v) for k, v in parts.items()}


def _stub_run(case: Any) -> dict[str, Any]:
    """A run without a simulation (the driver's memory does not depend on what a run costs):
    a record with every metric of the study (a number from the sample index) and a note."""
    i = int(case.label[1:7])
    return {
        "status": "ok",
        **{m: 1.0 + 1e-4 * i for m in _MC_METRICS},
        "notes": f"stub run {case.label}",
        **{k: 0.5 for k in _LIN},
        "linear_note": "stub",
    }


_MC_METRICS: tuple[str, ...] = ()
_LIN: tuple[str, ...] = ()


def _driver_memory(samples: int, workers: int) -> dict[str, float]:
    """Run the shipped 10,000-sample study file cut to ``samples`` samples with the stub run on a
    local cluster of ``workers`` processes; the driver's (this process's) peak resident set
    [MiB] before and after, and the wall time [s]. Run in a fresh process."""
    import resource
    import tomllib

    from drivetrain_ctrl.studies.case import LINEAR_FIGURES
    from drivetrain_ctrl.studies.runner import read_results, run_study
    from drivetrain_ctrl.studies.study import Study

    global _MC_METRICS, _LIN
    d = tomllib.loads((ROOT / "analyses" / "studies" / "paper_start_mc.toml").read_text())
    d["sampling"]["samples"] = samples
    study = Study.from_dict(d, base=ROOT / "analyses" / "studies")
    _MC_METRICS = tuple(m for m in study.metrics if m not in ("model", "status", "notes"))
    _LIN = tuple(LINEAR_FIGURES)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    with tempfile.TemporaryDirectory() as tmp:
        tic = time.perf_counter()
        done = run_study(study, out=Path(tmp), workers=workers, progress=False, run=_stub_run)
        wall = time.perf_counter() - tic
        assert done.rows == done.expected == done.computed == 2 * samples, done.summary()
        peak_run = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        n = len(read_results(tmp))
        assert n == 2 * samples
    return {
        "samples": samples,
        "rows": 2 * samples,
        "rss_before_mib": round(before, 1),
        "peak_rss_mib": round(peak_run, 1),
        "wall_s": round(wall, 1),
    }


def _driver_memory_in_subprocess(samples: int, workers: int) -> dict[str, float]:
    import subprocess
    import sys

    out = subprocess.run(
        [sys.executable, __file__, "--driver-memory", str(samples), "--workers", str(workers)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return dict(json.loads(out.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=100, help="samples of the reduced-model study")
    ap.add_argument("--full-samples", type=int, default=20, help="samples on the full model")
    ap.add_argument("--repeats", type=int, default=15, help="repeats of the in-process timings")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument(
        "--memory-samples",
        type=int,
        nargs="+",
        default=[1000, 10000],
        help="samples of the driver-memory runs (stub runs); the last one is reported",
    )
    ap.add_argument("--workers", type=int, default=2, help="workers of the driver-memory runs")
    ap.add_argument("--driver-memory", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.driver_memory:  # the child process of a driver-memory run
        print(json.dumps(_driver_memory(args.driver_memory, args.workers)))
        return

    from drivetrain_ctrl.sim.warmup import ensure_compiled

    ensure_compiled()
    memory = [_driver_memory_in_subprocess(n, args.workers) for n in args.memory_samples]
    parts = _in_process(args.repeats)
    reduced = _study(args.samples, "reduced")
    full = _study(args.full_samples, "full")
    with tempfile.TemporaryDirectory() as tmp:
        s1, w1, rows, _ = _timed_study(reduced, 1, Path(tmp) / "one")
        s2, w2, _, _ = _timed_study(reduced, 2, Path(tmp) / "two")
        _, wf, rows_full, sim_ms = _timed_study(full, 1, Path(tmp) / "full", args.repeats)
    full_run_ms = 1e3 * wf / rows_full
    out: dict[str, Any] = {
        "samples": args.samples,
        "rows": rows,
        "wall_s_1_worker": round(w1, 3),
        "wall_s_2_workers": round(w2, 3),
        "startup_s_1_worker": round(s1, 3),
        "startup_s_2_workers": round(s2, 3),
        "samples_per_s": round(rows / w2, 2),
        "speedup_2_vs_1": round(w1 / w2, 3),
        "extrapolated_10000_s_2_workers": round(20000 / (rows / w2), 1),
        "simulate_ms": round(sim_ms, 2),
        "full_run_ms": round(full_run_ms, 2),
        "full_rows": rows_full,
        "overhead_vs_simulate": round(full_run_ms / sim_ms - 1.0, 3),
        "in_process_simulate_ms": round(parts["simulate_ms"], 2),
        "in_process_case_ms": round(parts["case_ms"], 2),
        "in_process_case_nocache_ms": round(parts["case_nocache_ms"], 2),
        "in_process_case_linear_ms": round(parts["case_linear_ms"], 2),
        "in_process_metrics_ms": round(parts["metrics_ms"], 2),
        "in_process_controller_ms": round(parts["controller_ms"], 2),
        "in_process_controller_fresh_ms": round(parts["controller_fresh_ms"], 2),
        "in_process_linear_ms": round(parts["linear_ms"], 2),
        "driver_peak_rss_mib": memory[-1]["peak_rss_mib"],
        "driver_memory_runs": memory,
        "cores": os.cpu_count(),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "study.json").write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
