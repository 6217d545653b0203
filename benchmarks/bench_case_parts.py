"""What one study row costs beyond its ``simulate()`` call, part by part (issue 23 item 6).

Usage::

    python benchmarks/bench_case_parts.py [--samples 12] [--model full|reduced|both]

For ``--samples`` samples of the quick study (``analyses/studies/paper_start_quick.toml``, law
(6)) on each model, in this process, the median wall time [ms] of: ``simulate`` (a bare run),
``run_case`` (the whole row with the linear figures; ``run_case_nolin`` without them), the
drivetrain's construction (``drivetrain``), the controller's (``controller``: its stability
check computed, as for a sample with new clutch or actuator values), ``metrics``
(:func:`engagement_metrics`), and the linear figures (``linear``) with their parts: the slip
operating point (``lin_op``), the loop gain (``lin_loop``: :func:`clutch_loop_gain`), its margins
(``lin_margins``: the frequency grid and :func:`loop_margins`) and the judder threshold
(``lin_judder``). ``beyond_simulate`` is ``run_case / simulate - 1``. ``--clock cpu`` (default)
times the process's CPU time, ``wall`` the wall time (the parts are single-threaded: the CPU
time is the wall time of an idle machine, and much less disturbed on a busy one). Every repeat is another
sample (new parameter values: nothing found in a cache that a study's next sample would miss).
Printed as JSON; nothing is written (the numbers are for before/after comparisons on the same,
possibly busy, machine).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

#: the clock: set by ``--clock`` (``cpu``: this process's CPU time, little disturbed by other
#: jobs on a shared machine; ``wall``: wall time)
CLOCK = time.process_time


def _parts(model: str, samples: int) -> dict[str, float]:
    from bench_study import _study

    from drivetrain_ctrl.control.laws import _STABILITY_CACHE
    from drivetrain_ctrl.linear.clutch import clutch_loop_gain
    from drivetrain_ctrl.linear.margins import _auto_grid, loop_margins
    from drivetrain_ctrl.linear.operating_point import slip_point_after_start
    from drivetrain_ctrl.sim.metrics import engagement_metrics
    from drivetrain_ctrl.sim.run import run_scenario
    from drivetrain_ctrl.studies.case import (
        LINEAR_GRID_POINTS,
        _judder,
        linear_figures,
        run_case,
        simulate_case,
    )
    from drivetrain_ctrl.studies.study import sample_table

    study = _study(2 * samples + 2, model)
    df = sample_table(study)
    t: dict[str, list[float]] = {}

    def clock(name: str, f: Any, *a: Any, **k: Any) -> Any:
        tic = CLOCK()
        out = f(*a, **k)
        t.setdefault(name, []).append(1e3 * (CLOCK() - tic))
        return out

    for i in range(samples + 1):
        # two samples per repeat: the row with the linear figures, and the row without them
        # (each a sample the process has not seen: its parameter set, drivetrain and stability
        # check are not kept from before, the scenario file is, as in a study)
        vals = {str(k): float(v) for k, v in df.iloc[2 * i].items()}
        case = dataclasses.replace(study.case(2 * i, vals, "paper", 0), linear=True)
        clock("run_case", run_case, case)
        vals2 = {str(k): float(v) for k, v in df.iloc[2 * i + 1].items()}
        case2 = dataclasses.replace(study.case(2 * i + 1, vals2, "paper", 0), linear=False)
        clock("run_case_nolin", run_case, case2)
        run = simulate_case(dataclasses.replace(case, linear=False))
        sc = run.scenario
        params = run.drivetrain.params
        dt = clock("drivetrain", sc.drivetrain, params, kind=model)
        _STABILITY_CACHE.clear()
        ctrl = clock("controller", sc.make_controller, dt, run.spec)
        res = clock("simulate", run_scenario, sc, dt, controller=ctrl, t_end=study.t_end)
        clock("metrics", engagement_metrics, res, dt, start=sc.start_time, reference=sc.reference)
        clock("linear", linear_figures, res, dt, ctrl, start=sc.start_time)
        op = clock("lin_op", slip_point_after_start, res, dt, sc.start_time)
        es, L = clock("lin_loop", clutch_loop_gain, op, ctrl)

        def margins(L: Any = L) -> Any:
            return loop_margins(L, omega=_auto_grid(L, n=LINEAR_GRID_POINTS).tolist())

        clock("lin_margins", margins)
        clock("lin_judder", _judder, op, ctrl, es, L)
        if i == 0:  # the first sample loads what the others find loaded
            t = {}
    out: dict[str, float] = {k + "_ms": round(statistics.median(v), 3) for k, v in t.items()}
    out["beyond_simulate"] = round(out["run_case_ms"] / out["simulate_ms"] - 1.0, 3)
    out["beyond_simulate_nolin"] = round(out["run_case_nolin_ms"] / out["simulate_ms"] - 1.0, 3)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=12, help="timed samples (median reported)")
    ap.add_argument("--model", choices=("full", "reduced", "both"), default="both")
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    args = ap.parse_args()
    global CLOCK
    CLOCK = time.process_time if args.clock == "cpu" else time.perf_counter
    if args.samples < 1:
        raise SystemExit(f"--samples = {args.samples}: must be at least 1")
    models = ("full", "reduced") if args.model == "both" else (args.model,)
    out: dict[str, Any] = {"clock": args.clock, "samples": args.samples}
    out.update({m: _parts(m, args.samples) for m in models})
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
