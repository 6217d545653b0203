"""Speed of the robust PI tuner (issue 20 item 8): 50 plants x 200 frequencies in under 10 s.

Usage::

    python benchmarks/bench_design.py [--repeats 3] [--no-clutch] [--out DIR]

Cases (each a :func:`drivetrain_ctrl.design.robust.robust_pi` call, timed as a whole, in this
process, after one small warm-up design that imports and initialises cvxpy and the solver):

* ``textbook``: 50 plants ``k / ((T1 s + 1)(T2 s + 1)) exp(-d s)`` with k in [0.5, 2], T1 in
  [0.5, 2] s, T2 in [0.05, 0.5] s, d in [0.05, 0.4] s (seeded), ``Ms <= 1.4``, the automatic
  200-point grid: **the goal case**, timed ``--repeats`` times (median);
* ``textbook, Mt + |KS|``: the same with ``Mt <= 1.2`` and ``|K S| <= 3``;
* ``textbook, full DPP``: the same as the goal case with ``working_set=False`` (each convex
  step the full problem, built once with cvxpy Parameters and re-solved);
* ``textbook, HIGHS``: the goal case with the HiGHS solver instead of Clarabel;
* ``textbook, sampled``: the 50 plants sampled with a zero-order hold at 0.05 s, the delay
  rounded to whole samples (a discrete PI, forward-Euler integrator);
* ``clutch`` (unless ``--no-clutch``): the clutch start's slip-mode loop plants
  (:func:`~drivetrain_ctrl.design.clutch.clutch_plant_set`, ``pi-10ms``: sampled at 10 ms with one
  sample of delay) at 5 instants of the ``paper-start`` trajectory x 10 points of a parameter box
  (friction capacity +-40 %, J1 +-20 %, omega_a 100-300 rad/s, delta_a 0.5-1; 9 Latin-hypercube
  samples and the nominal point): 7-state plants, a grid that the lightly damped driveline modes
  make denser. Its first run may compile the simulator's kernels (minutes); only the design is
  timed.

For each: the wall and CPU (``time.process_time``, all threads) time of the call, its phases (``RobustTuning.timings``: grid, start,
iterations of which solver, dense re-check), iterations, grid points (start -> after the
refinement around the active cells), ki and the largest re-checked Ms. Writes
``results/design.json`` and prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any

import control
import numpy as np

from drivetrain_ctrl.design.plants import Plant, frequency_grid
from drivetrain_ctrl.design.robust import RobustTuning, robust_pi

HERE = Path(__file__).resolve().parent
GOAL_S = 10.0


def textbook_set(n: int = 50, seed: int = 0) -> list[Plant]:
    """The seeded textbook set of the module docstring."""
    s = control.tf("s")
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        k, t1 = rng.uniform(0.5, 2.0), rng.uniform(0.5, 2.0)
        t2, d = rng.uniform(0.05, 0.5), rng.uniform(0.05, 0.4)
        out.append(Plant(k / ((t1 * s + 1) * (t2 * s + 1)), d, f"p{i}"))
    return out


def sampled(plants: list[Plant], dt: float) -> list[Plant]:
    return [Plant(control.c2d(p.sys, dt, "zoh"), round(p.delay / dt) * dt, p.name) for p in plants]


def clutch_set() -> Any:
    from drivetrain_ctrl.design.clutch import clutch_plant_set

    box = {
        "clutch.k12_max": {"factor": (0.6, 1.4)},
        "engine.J1": {"factor": (0.8, 1.2)},
        "actuator.omega_a": (100.0, 300.0),
        "actuator.delta_a": (0.5, 1.0),
    }
    return clutch_plant_set(times=5, box=box, sampling=9, controller="pi-10ms")


def row(
    name: str, plants: Any, runs: list[RobustTuning], walls: list[float], cpus: list[float]
) -> dict[str, Any]:
    r = runs[-1]
    t = dict(r.timings)
    return {
        "case": name,
        "plants": len(r.plants),
        "grid_start": int(frequency_grid(plants, n=r.spec.n_omega).size)
        if r.spec.omega is None
        else len(r.spec.omega),
        "grid_final": int(r.omega.size),
        "iterations": r.iterations,
        "ki": r.ki,
        "kp": r.kp,
        "ms_max": r.ms,
        "converged": r.converged,
        "wall_s": statistics.median(walls),
        "wall_runs_s": walls,
        "cpu_s": statistics.median(cpus),
        "cpu_runs_s": cpus,
        "timings_s": t,
        "working_set": r.spec.working_set,
        "solver": r.spec.solver,
    }


def run(name: str, plants: Any, repeats: int, **kw: Any) -> dict[str, Any]:
    runs, walls, cpus = [], [], []
    for _ in range(repeats):
        tic, cpu = time.perf_counter(), time.process_time()
        r = robust_pi(plants, **kw)
        walls.append(time.perf_counter() - tic)
        cpus.append(time.process_time() - cpu)
        runs.append(r)
    return row(name, plants, runs, walls, cpus)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="runs of the goal case (median)")
    ap.add_argument("--no-clutch", action="store_true", help="skip the clutch plant set")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    a = ap.parse_args()
    tb = textbook_set()
    robust_pi(tb[:2], ms=1.4)  # warm-up: imports, solver initialisation
    rows = [
        run("textbook", tb, a.repeats, ms=1.4),
        run("textbook, Mt + |KS|", tb, 1, ms=1.4, mt=1.2, ks_max=3.0),
        run("textbook, full DPP", tb, 1, ms=1.4, working_set=False),
        run("textbook, HIGHS", tb, 1, ms=1.4, solver="HIGHS"),
        run("textbook, sampled", sampled(tb, 0.05), 1, ms=1.4),
    ]
    if not a.no_clutch:
        cs = clutch_set()
        rows.append(run("clutch (pi-10ms)", cs, 1, ms=1.4))
    print(
        f"{'case':<22} {'plants':>6} {'grid':>10} {'iter':>4} {'wall s':>7} {'cpu s':>6} "
        f"{'solver s':>8} {'check s':>7} {'max Ms':>7} {'ki':>10}"
    )
    for r in rows:
        t = r["timings_s"]
        print(
            f"{r['case']:<22} {r['plants']:>6} {r['grid_start']:>4}->{r['grid_final']:<5} "
            f"{r['iterations']:>4} {r['wall_s']:>7.2f} {r['cpu_s']:>6.2f} {t['solver']:>8.2f} "
            f"{t['check']:>7.2f} "
            f"{r['ms_max']:>7.4f} {r['ki']:>10.4g}"
        )
    goal = rows[0]["wall_s"]
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    print(f"goal: 50 plants x 200 frequencies < {GOAL_S:g} s: {goal:.2f} s "
          f"({'met' if goal < GOAL_S else 'NOT met'})")  # fmt: skip
    if load:
        print(
            f"load average (1, 5, 15 min) at the end: {load[0]:.1f}, {load[1]:.1f}, {load[2]:.1f}"
        )
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "design.json").write_text(
        json.dumps(
            {
                "goal_s": GOAL_S,
                "goal_met": goal < GOAL_S,
                "machine": {
                    "cpus": os.cpu_count(),
                    "processor": platform.processor() or platform.machine(),
                    "load_average_at_end": load,
                },
                "cases": rows,
            },
            indent=2,
        )
        + "\n"
    )
    print(f"wrote {a.out / 'design.json'}")


if __name__ == "__main__":
    main()
