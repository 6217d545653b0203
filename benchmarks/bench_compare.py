"""The default comparison's speed (issue 21 item 3): 4 controllers x 6 scenarios, full model.

Usage::

    python benchmarks/bench_compare.py [--workers N] [--model full|reduced] [--report]

Runs :func:`~drivetrain_ctrl.studies.compare.compare` with its defaults (``paper``, ``pi``,
``robust-pi``, ``hinf`` on every built-in closed-loop scenario) on a local cluster of
``--workers`` processes (default: the cores) and times it end to end: ``wall_s`` from the call
to the result (the cluster's start, the kernels loaded on its workers, the runs, the verdict),
and, with ``--report``, ``report_s`` for writing compare.html, compare.pdf and data.json into a
temporary folder. The machine's load average (``os.getloadavg``) before and after is recorded
beside the times: on a shared machine it explains much of the spread.

``startup_s``, ``runs_s``, ``shutdown_s``: the parts of ``wall_s`` (the set-up: the kernels in
this process, the cluster and the warm-up on its workers, split into ``startup_cluster_s`` up to
a connected client and ``startup_warmup_s`` the workers' kernel loading; the runs, with the
design plant-set checks and the certificates beside them on the workers; the cluster's
shut-down). ``design_checks_s`` and ``certificate_s``: the worker time the plant-set checks and
the certified sectors took in all (part of ``runs_s``'s work, spread over the workers).

Writes ``results/compare.json`` (``wall_s``, the parts, ``cases``, ``workers``, ``model``, ``cores``,
``load_before``, ``load_after``, ``goal_s`` 60 and whether it was met) and prints it.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
GOAL_S = 60.0


def main(*, workers: int | None, model: str, report: bool) -> dict[str, Any]:
    from drivetrain_ctrl.studies.compare import compare

    load0 = os.getloadavg()
    tic = time.perf_counter()
    res = compare(model=model, workers=workers, progress=True)
    wall = time.perf_counter() - tic
    out: dict[str, Any] = {
        "wall_s": round(wall, 2),
        "cases": sum(len(v) for v in res.data["runs"].values()),
        "workers": res.workers,
        **{k: round(v, 2) for k, v in res.timing.items()},
        "model": model,
        "cores": os.cpu_count(),
        "controllers": res.data["inputs"]["controllers"],
        "scenarios": res.data["inputs"]["scenarios"],
        "invalid": res.problems,
        "goal_s": GOAL_S,
        "goal_met": wall < GOAL_S,
    }
    if report:
        tic = time.perf_counter()
        with tempfile.TemporaryDirectory() as d:
            res.plot(d)
        out["report_s"] = round(time.perf_counter() - tic, 2)
    out["load_before"] = [round(v, 2) for v in load0]
    out["load_after"] = [round(v, 2) for v in os.getloadavg()]
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "compare.json").write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--model", choices=("full", "reduced"), default="full")
    ap.add_argument("--report", action="store_true")
    a = ap.parse_args()
    main(workers=a.workers, model=a.model, report=a.report)
