"""Question: how do the built-in controllers, and a driver's pedal, do on the harder built-in
starts (issue 21 item 1)?

Runs every one of ``hill-start``, ``worn-clutch``, ``judder``, ``heavy-load`` and
``tip-out-reengage`` in closed loop under law (6) (``paper``) and its PI variant (``pi``), and
in open loop (``--loop open``: the driver's pedal of each file, no controller; ``paper-start``'s
open loop beside them, the flat-road reference of the same pedal), on the reduced and the full
model with the default parameter set (plus each scenario's own parameter overrides), and prints
per run the lock-up time and the figure each scenario is about:

- ``hill-start``: ``rollback_m``, the largest backward displacement of the vehicle from its
  position at t = 0 over the run [m] (a :data:`~drivetrain_ctrl.sim.metrics.METRICS` entry);
- ``worn-clutch``: ``clutch_energy_J`` and ``jerk_max_m_s3``;
- ``judder``: ``accel_p2p_after_lock_m_s2`` and ``jerk_max_m_s3``;
- ``heavy-load``: ``clutch_energy_J`` and ``engine_speed_min_rpm``;
- ``tip-out-reengage``: ``engine_speed_min_rpm``, ``engine_stalled`` and ``n_lock_events``;
- ``paper-start`` (open loop only): ``clutch_energy_J`` and ``jerk_max_m_s3``.

Writes ``OUT/metrics.json`` (all engagement metrics of every run, keyed
``scenario/controller/model``, the controller ``open`` for the open loop).
``--quick``: law (6) and the open loop on the reduced model only.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from drivetrain_ctrl import default_params, engagement_metrics, load_scenario, run_scenario
from drivetrain_ctrl.core import json_ready

SCENARIOS = ("hill-start", "worn-clutch", "judder", "heavy-load", "tip-out-reengage")
#: run in open loop only, as the reference of the same driver's pedal on the flat road
OPEN_ONLY = ("paper-start",)
FOCUS = {
    "hill-start": ("rollback_m",),
    "worn-clutch": ("clutch_energy_J", "jerk_max_m_s3"),
    "judder": ("accel_p2p_after_lock_m_s2", "jerk_max_m_s3"),
    "heavy-load": ("clutch_energy_J", "engine_speed_min_rpm"),
    "tip-out-reengage": ("engine_speed_min_rpm", "engine_stalled", "n_lock_events"),
    "paper-start": ("clutch_energy_J", "jerk_max_m_s3"),
}


def main(*, quick: bool = False, out: Path | None = None) -> dict[str, Any]:
    p = default_params()
    kinds = ("reduced",) if quick else ("reduced", "full")
    ctls: tuple[str | None, ...] = ("paper", None) if quick else ("paper", "pi", None)
    runs: dict[str, Any] = {}
    for name in (*SCENARIOS, *OPEN_ONLY):
        own = load_scenario(name, params=p)
        for kind in kinds:
            for ctl in ctls:
                if name in OPEN_ONLY and ctl is not None:
                    continue
                sc = own.for_loop("closed" if ctl is not None else "open")
                dt = sc.drivetrain(p, kind=kind)
                res = run_scenario(sc, dt, controller=ctl)
                m = engagement_metrics(res, dt, start=sc.start_time, reference=sc.reference)
                label = ctl or "open"
                runs[f"{name}/{label}/{kind}"] = m
                focus = ", ".join(f"{k} = {m[k]!r}" for k in FOCUS[name])
                print(
                    f"{name:17s} {label:5s} {kind:7s} lock-up {m['lockup_time_s']!r} s "
                    f"(horizon {sc.t_end:g} s); {focus}"
                )
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(json.dumps(json_ready(runs), indent=1, sort_keys=True))
    return runs


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", type=Path, default=Path("reports/hard_scenarios"))
    a = ap.parse_args()
    main(quick=a.quick, out=a.out)
