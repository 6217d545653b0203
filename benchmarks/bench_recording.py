"""Memory of a long run: full recording against sparse recording and a fixed output grid.

Usage::

    python benchmarks/bench_recording.py [--t-end 60] [--out DIR]

One open-loop run of the full drivetrain for ``--t-end`` seconds (default 60 s): the clutch
engages on a pedal ramp, then the throttle swings (tip-in / tip-out every 10 s), so that the
backlash and the frictions keep switching. Three recordings of the same run, each in its own
Python process (the kernels loaded from the cache):

* ``full``: every accepted step (the default);
* ``every20``: ``SimulationOptions(record_every=20)``;
* ``grid10ms``: ``simulate(..., t_eval=...)`` on a 10-ms grid.

For each: the samples kept, the bytes of the result's arrays, the process's peak resident memory
(``ru_maxrss``) and the wall time of the run; the events, the lock-up time and the integrated
energies, which must equal the full recording's. Writes ``results/recording.json`` and prints a
table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent

CHILD = r"""
import json, resource, sys, time
import numpy as np
from drivetrain_ctrl import signals as sg
from drivetrain_ctrl.plant.drivetrain import full_model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.sim.simulator import SimulationOptions, simulate

mode, t_end = sys.argv[1], float(sys.argv[2])
dt = full_model(default_params())
x0 = dt.rigid_state(omega_engine=200.0, v_vehicle=0.0, throttle=0.3)
inputs = {
    "throttle": sg.constant(0.3) + sg.sine(0.15, 2 * np.pi / 10.0, t_start=5.0),
    "pedal": sg.ramp(0.2, 2.2, 0.11, 0.03),
    "brake": sg.constant(0.0),
}
kw = {}
opts = SimulationOptions()
if mode == "every20":
    opts = SimulationOptions(record_every=20)
elif mode == "grid10ms":
    kw["t_eval"] = np.linspace(0.0, t_end, int(round(t_end / 0.01)) + 1)
simulate(dt.model, x0, inputs, t_end=1.0)  # load the kernels
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
tic = time.perf_counter()
res = simulate(dt.model, x0, inputs, t_end=t_end, options=opts, **kw)
wall = time.perf_counter() - tic
arrays = (res.t, res.x, res.u, res.fm, res.reg, res.work_in, res.dissipated)
print(json.dumps({
    "samples": int(res.t.shape[0]),
    "result_bytes": int(sum(a.nbytes for a in arrays if a is not None)),
    "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    "peak_rss_growth_mb": (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0,
    "wall_s": wall,
    "steps": int(res.stats["steps"]),
    "events": [list(e) for e in res.events],
    "lockup_s": res.lockup_time(),
    "work_in_J": float(res.work_in[-1]),
    "dissipated_J": [float(v) for v in res.dissipated[-1]],
}))
"""

MODES = ("full", "every20", "grid10ms")


def run(mode: str, t_end: float) -> dict[str, Any]:
    out = subprocess.run(
        [sys.executable, "-c", CHILD, mode, str(t_end)],
        check=True,
        capture_output=True,
        text=True,
    )
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t-end", type=float, default=60.0, help="length of the run [s]")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    a = ap.parse_args()
    rows = {m: run(m, a.t_end) for m in MODES}
    full = rows["full"]
    print(f"{a.t_end:g}-s run of the full drivetrain: {full['steps']} steps, "
          f"{len(full['events'])} events")  # fmt: skip
    print(f"{'recording':<10} {'samples':>8} {'result MB':>10} {'peak RSS MB':>12} {'growth MB':>10} "
          f"{'run s':>7}  same events/energies")  # fmt: skip
    for m, r in rows.items():
        same = (
            r["events"] == full["events"]
            and r["lockup_s"] == full["lockup_s"]
            and r["work_in_J"] == full["work_in_J"]
            and r["dissipated_J"] == full["dissipated_J"]
        )
        r["same_as_full"] = same
        print(
            f"{m:<10} {r['samples']:>8} {r['result_bytes'] / 1e6:>10.2f} {r['peak_rss_mb']:>12.1f} "
            f"{r['peak_rss_growth_mb']:>10.1f} {r['wall_s']:>7.2f}  {same}"
        )
    a.out.mkdir(parents=True, exist_ok=True)
    slim = {
        m: {k: v for k, v in r.items() if k not in ("events", "dissipated_J")}
        for m, r in rows.items()
    }
    for m in slim:
        slim[m]["n_events"] = len(rows[m]["events"])
    (a.out / "recording.json").write_text(
        json.dumps({"t_end_s": a.t_end, "runs": slim}, indent=2) + "\n"
    )
    print(f"wrote {a.out / 'recording.json'}")


if __name__ == "__main__":
    main()
