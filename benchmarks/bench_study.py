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
   ``in_process_simulate_ms``, ``in_process_case_ms`` (:func:`run_case`) and
   ``in_process_metrics_ms`` (:func:`engagement_metrics`).

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
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.metrics import engagement_metrics
    from drivetrain_ctrl.sim.run import run_scenario
    from drivetrain_ctrl.studies.case import Case, run_case

    sc = load_scenario("paper-start")
    dt = sc.drivetrain(default_params(), kind="full")
    ctrl = sc.make_controller(dt, "paper")
    run_scenario(sc, dt, controller=ctrl)  # load the kernels
    sim, met, case = [], [], []
    c = Case(scenario="paper-start", model="full", controller="paper")
    for _ in range(repeats):
        tic = time.perf_counter()
        res = run_scenario(sc, dt, controller=ctrl)
        sim.append(time.perf_counter() - tic)
        tic = time.perf_counter()
        engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
        met.append(time.perf_counter() - tic)
        tic = time.perf_counter()
        run_case(c)
        case.append(time.perf_counter() - tic)
    return {
        "simulate_ms": 1e3 * statistics.median(sim),
        "metrics_ms": 1e3 * statistics.median(met),
        "case_ms": 1e3 * statistics.median(case),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=100, help="samples of the reduced-model study")
    ap.add_argument("--full-samples", type=int, default=20, help="samples on the full model")
    ap.add_argument("--repeats", type=int, default=15, help="repeats of the in-process timings")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()

    from drivetrain_ctrl.sim.warmup import ensure_compiled

    ensure_compiled()
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
        "in_process_metrics_ms": round(parts["metrics_ms"], 2),
        "cores": os.cpu_count(),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "study.json").write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
