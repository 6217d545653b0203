"""Energy residual of a run with many events against rtol and h_max (issue 19, finding a).

Usage::

    python benchmarks/bench_event_energy.py [--out DIR]

The shrunk fuzz case of ``tests/property/test_fuzz_chains.py::test_energy_floor_at_events``
(five unit bodies, two clutches, a soft and a piecewise stiff spring, one body spinning: 91
events in 1 s). For each ``h_max`` and tolerance pair (the defaults rtol 1e-8, atol 1e-7, then
rtol 1e-6 .. 1e-10 with atol = 1e-2 rtol) it prints the number of events, steps and right-hand-side
evaluations, the energy residual ``|E(t_end) - E(0) - W_in + E_diss|`` relative to the run's
energy (0.5 J), and the part of it made in the steps that end at an event (the sum of the
residual's absolute changes over those steps): the error of the states at the events, which came
from the steps' continuous extension before they were integrated (issue 19, finding a).
Writes ``results/event_energy.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction, Spring  # noqa: E402
from drivetrain_ctrl.plant.model import Model  # noqa: E402
from drivetrain_ctrl.sim.simulator import SimulationOptions, simulate  # noqa: E402

H_MAXS = (1e-3, 5e-4, 1e-4)
TOLS = ((1e-8, 1e-7), (1e-6, 1e-8), (1e-8, 1e-10), (1e-10, 1e-12))  # (rtol, atol)
E_RUN = 0.5  # [J] the run's energy (body b3 at 1 rad/s, inertia 1)


def shrunk_case() -> tuple[Model, np.ndarray, dict[str, float]]:
    """The model, initial state and (zero) inputs of the shrunk fuzz case."""
    bodies = tuple(Body(f"b{i}", 1.0, torque_input=f"T{i}") for i in range(5))
    couplings = (
        Coupling("c0", friction=Friction(scale=1.0, name="f0")),
        Coupling("c1", spring=Spring.linear(1.0, name="k1")),
        Coupling(
            "c2",
            ratio=2.0,
            spring=Spring((0.0, 0.0078125, 1.0078125), (0.0, 4.8359375, 4337.8359375), name="k2"),
        ),
        Coupling("c3", friction=Friction(scale=1.0, name="f3")),
    )
    m = Model(Chain(bodies, couplings, inputs=tuple(f"T{i}" for i in range(5))))
    x0 = np.zeros(m.nx)
    x0[3] = 1.0
    return m, x0, {f"T{i}": 0.0 for i in range(5)}


def run(h_max: float, rtol: float, atol: float) -> dict[str, float]:
    """One run: events, steps, nfev and the relative energy residual."""
    m, x0, u = shrunk_case()
    opts = SimulationOptions(h_max=h_max, rtol=rtol, atol=atol)
    r = simulate(m, x0, u, t_end=1.0, options=opts)
    E = r.stored_energy()
    res = (E - E[0] - r.work_in + r.dissipated.sum(axis=1)) / E_RUN
    ev_t = {e.t for e in r.events}
    at_ev = np.array([t in ev_t for t in r.t[1:]])
    return {
        "h_max": h_max,
        "rtol": rtol,
        "atol": atol,
        "events": len(r.events),
        "steps": int(r.stats["steps"]),
        "nfev": int(r.stats["nfev"]),
        "residual_rel": float(abs(res[-1])),
        "residual_at_events_rel": float(np.abs(np.diff(res)[at_ev]).sum()),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    rows = []
    print(
        f"{'h_max':>8s} {'rtol':>8s} {'atol':>8s} {'events':>7s} {'steps':>7s} {'nfev':>8s} "
        f"{'residual':>10s} {'at events':>10s}"
    )
    for h_max in H_MAXS:
        for rtol, atol in TOLS:
            row = run(h_max, rtol, atol)
            rows.append(row)
            print(
                f"{h_max:8.0e} {rtol:8.0e} {atol:8.0e} {row['events']:7d} {row['steps']:7d} "
                f"{row['nfev']:8d} {row['residual_rel']:10.2e} {row['residual_at_events_rel']:10.2e}"
            )
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "event_energy.json").write_text(json.dumps({"runs": rows}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
