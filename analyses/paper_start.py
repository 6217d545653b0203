"""Question: does the paper's law (6) hold the engine on its reference during the start, on the
full switching plant as well as on the reduced model it was designed on?

Runs the built-in ``paper-start`` scenario (Section IV, Fig. 14) under law (6) on the reduced and
the full drivetrain, writes ``reports/paper_start/{reduced,full}.png`` and the numbers behind them
(``metrics.json``), and prints a comparison. ``main(quick=True)`` runs the reduced model only.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from drivetrain_ctrl.metrics import engagement_metrics, json_ready
from drivetrain_ctrl.params import default_params
from drivetrain_ctrl.scenarios import load_scenario

OUT = Path(__file__).resolve().parent.parent / "reports" / "paper_start"


def main(quick: bool = False, out: Path = OUT) -> dict[str, Any]:
    """Run the analysis; returns ``{model: metrics}``."""
    sc = load_scenario("paper-start")
    params = default_params()
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {}
    for kind in ("reduced",) if quick else ("reduced", "full"):
        dt = sc.drivetrain(params, kind=kind)
        res = sc.run(dt)
        results[kind] = json_ready(engagement_metrics(res, dt))
        res.plot(str(out / f"{kind}.png"))
    (out / "metrics.json").write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    for kind, m in results.items():
        print(
            f"{kind:8s} lock-up {m['lockup_time_s']} s, engine {m['min_engine_speed_rpm']}.."
            f"{m['max_engine_speed_rpm']} rpm, clutch energy {m['clutch_energy_J']} J, "
            f"max jerk {m['max_vehicle_jerk_m_s3']} m/s^3"
        )
    return results


if __name__ == "__main__":  # pragma: no cover
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    main(quick=ap.parse_args().quick)
