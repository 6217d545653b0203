"""The cost of :func:`engagement_metrics` against a bare ``simulate()`` of the same run.

One full-model ``paper-start`` run under law (6) (the study's full-model row); the run and its
figures of merit are timed ``--repeats`` times in this process and the medians printed as JSON
(``simulate_ms``, ``metrics_ms``, ``metrics_vs_simulate``, ``n_samples``). Nothing is written:
the numbers are for a before/after comparison on the same (shared, noisy) machine.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats (median reported)")
    args = ap.parse_args()
    if args.repeats < 1:
        raise SystemExit(f"--repeats = {args.repeats}: must be at least 1")

    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario
    from drivetrain_ctrl.sim.metrics import engagement_metrics
    from drivetrain_ctrl.sim.run import run_scenario

    sc = load_scenario("paper-start")
    dt = sc.drivetrain(default_params(), kind="full")
    ctrl = sc.make_controller(dt, "paper")
    res = run_scenario(sc, dt, controller=ctrl)  # compile / warm up
    engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
    t_sim: list[float] = []
    t_met: list[float] = []
    for _ in range(args.repeats):
        tic = time.perf_counter()
        res = run_scenario(sc, dt, controller=ctrl)
        t_sim.append(time.perf_counter() - tic)
        tic = time.perf_counter()
        engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
        t_met.append(time.perf_counter() - tic)
    sim_ms = 1e3 * statistics.median(t_sim)
    met_ms = 1e3 * statistics.median(t_met)
    print(
        json.dumps(
            {
                "n_samples": int(res.t.shape[0]),
                "repeats": args.repeats,
                "simulate_ms": round(sim_ms, 2),
                "metrics_ms": round(met_ms, 2),
                "metrics_vs_simulate": round(met_ms / sim_ms, 3),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
