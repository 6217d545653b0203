"""Two versions of the simulator timed in one window: is a kernel change slower?

Usage (each version a checkout with its kernels compiled; the old flat layout before the
package split is understood too)::

    PYTHONPATH=/path/to/old/checkout python benchmarks/bench_versions.py old
    python benchmarks/bench_versions.py new
    # ... alternate the two a few times: the machine's speed drifts, alternation cancels it

Prints, for the full-model ``engage-ramp`` and ``tip-in`` scenarios at the default options, the
median and the best of ``--repeats`` warm ``simulate()`` calls [ms] and the function evaluations
of a run (``nfev``), so that a slowdown splits into more evaluations and dearer ones.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("label", help="a name for this version in the output")
    ap.add_argument("--repeats", type=int, default=25)
    args = ap.parse_args()
    import importlib
    from pathlib import Path

    import drivetrain_ctrl

    # the package layout of this checkout (an editable install elsewhere could otherwise supply
    # a subpackage the checkout does not have: check the folder, not the import)
    split = (Path(drivetrain_ctrl.__file__).parent / "plant").is_dir()
    names = (
        ("plant.params", "scenarios.scenario", "sim.simulator")
        if split
        else ("params", "scenarios", "simulate")  # before the package split
    )
    default_params = importlib.import_module(f"drivetrain_ctrl.{names[0]}").default_params
    load_scenario = importlib.import_module(f"drivetrain_ctrl.{names[1]}").load_scenario
    simulate = importlib.import_module(f"drivetrain_ctrl.{names[2]}").simulate
    print(f"# {args.label}: {drivetrain_ctrl.__file__}")
    out = {}
    for name in ("engage-ramp", "tip-in"):
        sc = load_scenario(name)
        dt = sc.drivetrain(default_params())
        x0 = sc.initial_state(dt)
        inputs = sc.input_signals()
        res = simulate(dt.model, x0, inputs, t_end=sc.t_end)  # warm
        times = []
        for _ in range(args.repeats):
            tic = time.perf_counter()
            res = simulate(dt.model, x0, inputs, t_end=sc.t_end)
            times.append(time.perf_counter() - tic)
        out[name] = {
            "median_ms": round(1e3 * statistics.median(times), 2),
            "best_ms": round(1e3 * min(times), 2),
            "nfev": res.stats.get("nfev"),
        }
    print(args.label, json.dumps(out))


if __name__ == "__main__":
    main()
