"""Would a higher-order Runge-Kutta method pay? A check on the longest event-free segment.

Usage::

    python benchmarks/order_check.py

For the full-model ``engage-ramp`` and ``tip-in`` it finds the longest interval in which our
simulation holds one mode (friction modes and table segments), then integrates that interval
again with scipy's RK45 (Dormand-Prince 5(4), our kernel's method) and DOP853 (order 8) in that
fixed mode, at our default tolerances, and prints the function evaluations of each. Between
events a higher-order method saves only what this ratio shows (the ringing gear-mesh mode keeps
both accuracy-limited); it is the upper bound of what switching the kernel's method would gain.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from drivetrain_ctrl.model import Mode
from drivetrain_ctrl.params import default_params
from drivetrain_ctrl.scenarios import load_scenario
from drivetrain_ctrl.simulate import SimulationOptions


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


def main() -> int:
    params = default_params()
    opts = SimulationOptions()
    for name in ("engage-ramp", "tip-in"):
        sc = load_scenario(name)
        dt = sc.drivetrain(params)
        res = sc.run(dt)
        i, j = longest_segment(res)
        if np.ptp(res.u[i : j + 1], axis=0).max() > 0.0:
            print(f"{name}: inputs vary on the longest segment; skipped")
            continue
        mode = Mode(tuple(int(v) for v in res.fm[i]), tuple(int(v) for v in res.reg[i]))
        u = np.asarray(res.u[i])
        model = dt.model

        def rhs(_t: float, x: np.ndarray, model=model, u=u, mode=mode) -> np.ndarray:  # type: ignore[no-untyped-def]
            return model.rhs(x, u, mode)

        span = (0.0, float(res.t[j] - res.t[i]))
        print(
            f"{name}: t = {res.t[i]:.4f} .. {res.t[j]:.4f} s in one mode, ours {j - i} steps "
            f"(rtol {opts.rtol:g}, atol {opts.atol:g})"
        )
        nfev = {}
        for method in ("RK45", "DOP853"):
            sol = solve_ivp(rhs, span, res.x[i], method=method, rtol=opts.rtol, atol=opts.atol)
            nfev[method] = sol.nfev
            err = float(np.max(np.abs(sol.y[:7, -1] - res.x[j, :7])))
            print(
                f"  {method:7s} nfev {sol.nfev:6d}  steps {sol.t.size - 1:5d}  "
                f"end speeds vs ours {err:.1e} rad/s"
            )
        print(f"  DOP853 / RK45 evaluations: {nfev['DOP853'] / nfev['RK45']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
