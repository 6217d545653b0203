"""Would a higher-order Runge-Kutta method pay? A check on the longest event-free segment.

Usage::

    python benchmarks/order_check.py [--rtols 1e-6,1e-7,1e-8,1e-9] [--out DIR]

For the full-model ``engage-ramp`` and ``tip-in`` it finds the longest interval in which our
simulation holds one mode (friction modes and table segments), then integrates that interval
again in that fixed mode with scipy's RK45 (Dormand-Prince 5(4), our kernel's method) and DOP853
(order 8), with our largest step ``h_max`` as ``max_step``, at each relative tolerance (atol in
the default ratio to rtol). For each run it reports steps, function evaluations and the largest
speed error at the step ends against DOP853 at rtol 1e-13. Two questions:

* at our default tolerances, how many evaluations would a higher-order method save between events
  (the upper bound of what switching the kernel's method would gain);
* do the steps follow the tolerance? A step count that hardly changes over a wide range of
  tolerances, while the error does, means the steps are held at the stability limit of the
  lightly damped gear-mesh mode, not set by accuracy.

Writes ``order_check.json`` (default ``benchmarks/results/``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from results_io import write_json
from scipy.integrate import solve_ivp

from drivetrain_ctrl.model import Mode
from drivetrain_ctrl.params import default_params
from drivetrain_ctrl.scenarios import load_scenario
from drivetrain_ctrl.simulate import SimulationOptions

HERE = Path(__file__).resolve().parent
RTOLS = (1e-6, 1e-7, 1e-8, 1e-9)
METHODS = ("RK45", "DOP853")
REF_TOL = 1e-13


def longest_segment(res: object) -> tuple[int, int]:
    """Sample indices ``(i, j)`` of the longest run of samples in one mode."""
    fm = np.asarray(res.fm)  # type: ignore[attr-defined]
    reg = np.asarray(res.reg)  # type: ignore[attr-defined]
    t = np.asarray(res.t)  # type: ignore[attr-defined]
    keys = [tuple(a) + tuple(b) for a, b in zip(fm.tolist(), reg.tolist(), strict=True)]
    best, i = (0, 0), 0
    while i < len(keys) - 1:
        j = i
        while j + 1 < len(keys) and keys[j + 1] == keys[i]:
            j += 1
        if t[j] - t[i] > t[best[1]] - t[best[0]]:
            best = (i, j)
        i = j + 1
    return best


def speed_error(sol: Any, ref: Any, nspeed: int) -> float:
    """Largest speed deviation [rad/s or m/s] from ``ref`` at the step ends of ``sol``."""
    return float(np.max(np.abs(sol.y[:nspeed] - ref.sol(sol.t)[:nspeed])))


def check_segment(name: str, rtols: Sequence[float]) -> dict[str, Any] | None:
    """Re-integrate ``name``'s longest one-mode segment: RK45 and DOP853 at each rtol."""
    params = default_params()
    opts = SimulationOptions()
    sc = load_scenario(name)
    dt = sc.drivetrain(params)
    res = sc.run(dt)
    i, j = longest_segment(res)
    if np.ptp(res.u[i : j + 1], axis=0).max() > 0.0:
        print(f"{name}: inputs vary on the longest segment; skipped")
        return None
    mode = Mode(tuple(int(v) for v in res.fm[i]), tuple(int(v) for v in res.reg[i]))
    u = np.asarray(res.u[i])
    model = dt.model
    nspeed = model.n_bodies

    def rhs(_t: float, x: np.ndarray, model=model, u=u, mode=mode) -> np.ndarray:  # type: ignore[no-untyped-def]
        return model.rhs(x, u, mode)

    span = (0.0, float(res.t[j] - res.t[i]))
    x0 = np.asarray(res.x[i])
    ref = solve_ivp(rhs, span, x0, method="DOP853", rtol=REF_TOL, atol=REF_TOL, dense_output=True)
    print(
        f"{name}: t = {res.t[i]:.4f} .. {res.t[j]:.4f} s in one mode, ours {j - i} steps "
        f"(rtol {opts.rtol:g}, atol {opts.atol:g}, h_max {opts.h_max:g} s)"
    )
    rows: list[dict[str, Any]] = []
    for rtol in rtols:
        atol = rtol * opts.atol / opts.rtol
        for method in METHODS:
            sol = solve_ivp(rhs, span, x0, method=method, rtol=rtol, atol=atol, max_step=opts.h_max)
            row = {
                "method": method,
                "rtol": rtol,
                "atol": atol,
                "steps": int(sol.t.size - 1),
                "nfev": int(sol.nfev),
                "max_speed_err": speed_error(sol, ref, nspeed),
            }
            rows.append(row)
            print(
                f"  rtol {rtol:7.1e}  {method:7s} steps {row['steps']:5d}  nfev {row['nfev']:6d}  "
                f"max speed error {row['max_speed_err']:.1e}"
            )
    at = {r["method"]: r for r in rows if r["rtol"] == opts.rtol}
    ratio = at["DOP853"]["nfev"] / at["RK45"]["nfev"] if len(at) == 2 else None
    if ratio is not None:
        print(f"  at rtol {opts.rtol:g}: DOP853 / RK45 evaluations {ratio:.2f}")
    rk = [r for r in rows if r["method"] == "RK45"]
    spread = max(r["steps"] for r in rk) / min(r["steps"] for r in rk)
    print(f"  RK45 steps, largest / smallest over the rtols: {spread:.2f}")
    return {
        "t_start": float(res.t[i]),
        "t_stop": float(res.t[j]),
        "ours_steps": int(j - i),
        "reference": {"method": "DOP853", "rtol": REF_TOL, "atol": REF_TOL},
        "runs": rows,
        "dop853_over_rk45_nfev_at_default": ratio,
        "rk45_steps_max_over_min": spread,
    }


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--rtols",
        default=",".join(f"{r:g}" for r in RTOLS),
        help="comma-separated relative tolerances (atol = rtol * default atol / default rtol)",
    )
    ap.add_argument("--out", type=Path, default=HERE / "results", help="output directory")
    a = ap.parse_args(argv)
    try:
        rtols = sorted({float(v) for v in a.rtols.split(",")}, reverse=True)
    except ValueError:
        ap.error(f"--rtols {a.rtols!r}: give comma-separated numbers")
    if not rtols or min(rtols) <= 0.0:
        ap.error(f"--rtols {a.rtols!r}: each tolerance must be > 0")
    out: dict[str, Any] = {
        "what": "longest one-mode segment re-integrated with scipy RK45 and DOP853 "
        "(max_step = h_max) at several tolerances; errors against DOP853 at rtol 1e-13",
        "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
    }
    for name in ("engage-ramp", "tip-in"):
        r = check_segment(name, rtols)
        if r is not None:
            out[name] = r
    write_json(a.out, "order_check.json", out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
