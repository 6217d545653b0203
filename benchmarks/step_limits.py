"""What limits our step size, and how fast could a step-bounded simulator be at best?

Usage::

    python benchmarks/step_limits.py [--repeats N] [--out DIR]

For the full-model ``engage-ramp`` and ``tip-in`` at the default options it measures, in one run:

* the accepted steps by size, and the share of simulated time spent in each size class;
* the fastest eigenvalue of the modes whose stability bound is below ``h_max`` (frequency and
  damping ratio: the gear mesh);
* each step against its mode's stability bound ``h_stab = STABILITY_FACTOR / |lambda_max|``
  (eigenvalues of the mode's Jacobian, numpy), and Dormand-Prince 5(4)'s true stability limit
  along the ray of the fastest eigenvalue (``|R(z)| <= 1``; on the imaginary axis the method is
  not stable beyond ``|z|`` of about 1, so a lightly damped mode is the worst case);
* the wall time per accepted step of our simulator and the time of the smoothed baseline
  (``bench_simulate.run_tanh``: scipy LSODA, tanh friction), interleaved, medians;
* the consequence: with ``h_max`` bounding every step (the simulator does not step over stick
  episodes longer than ``h_max``), a run takes at least ``t_end / h_max`` steps; at today's cost
  per step that is the fastest a run of this design can be, and ``tanh time / that`` is the
  largest speedup over the smoothed baseline it can reach.

Writes ``step_limits.json`` (default ``benchmarks/results/``) and prints a summary.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_simulate import run_tanh, scenario_setup  # noqa: E402
from results_io import write_json  # noqa: E402

from drivetrain_ctrl import kernels as K  # noqa: E402
from drivetrain_ctrl.linear import natural_frequency_damping  # noqa: E402
from drivetrain_ctrl.simulate import SimulationOptions, SimulationResult, simulate  # noqa: E402

#: Dormand-Prince 5(4) tableau (the fifth-order solution's weights are the last row)
_DP5_A = np.zeros((7, 7))
_DP5_A[1, 0] = 1 / 5
_DP5_A[2, :2] = [3 / 40, 9 / 40]
_DP5_A[3, :3] = [44 / 45, -56 / 15, 32 / 9]
_DP5_A[4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
_DP5_A[5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
_DP5_A[6, :6] = [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]


def dp5_stability(z: complex) -> float:
    """|R(z)| of Dormand-Prince 5(4) (``R(z) = 1 + z b^T (I - z A)^-1 1``)."""
    b = _DP5_A[6]
    r = 1.0 + z * (b @ np.linalg.solve(np.eye(7) - z * _DP5_A, np.ones(7)))
    return float(abs(r))


def dp5_limit_along(lam: complex) -> float:
    """Largest ``|z|`` with ``|R(t z / |z|)| <= 1`` for all ``t <= |z|``, z on the ray of
    ``lam`` (bisection after a scan in steps of 0.01)."""
    d = lam / abs(lam)
    r = 0.01
    while r < 6.0 and dp5_stability(r * d) <= 1.0 + 1e-12:
        r += 0.01
    lo, hi = r - 0.01, r
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if dp5_stability(mid * d) <= 1.0 + 1e-12:
            lo = mid
        else:
            hi = mid
    return lo


def mode_eigs(res: SimulationResult) -> list[complex]:
    """Fastest eigenvalue of the Jacobian of the mode each step starts in (cached per mode)."""
    D = res.model.data
    cache: dict[tuple[int, ...], complex] = {}
    out = []
    for i in range(len(res.t) - 1):
        fm = res.fm[i].astype(np.int64)
        reg = res.reg[i].astype(np.int64)
        key = tuple(fm.tolist()) + tuple(reg.tolist())
        if key not in cache:
            P, _PT = K.mode_matrices(D, fm)
            J, _B = K.jacobians(D, res.x[i], res.u[i], fm, reg, P, False)
            ev = np.linalg.eigvals(J)
            cache[key] = complex(ev[int(np.argmax(np.abs(ev)))])
        out.append(cache[key])
    return out


def analyse(name: str, repeats: int) -> dict[str, Any]:
    setup = scenario_setup(name)
    sc, dt, x0, inputs = setup.sc, setup.dt, setup.x0, setup.inputs
    opts = SimulationOptions()

    res = simulate(dt.model, x0, inputs, t_end=sc.t_end, options=opts)  # warm-up, and the steps
    t_ours: list[float] = []
    t_tanh: list[float] = []
    for _ in range(repeats):  # interleaved: the machine is shared and its load drifts
        tic = time.perf_counter()
        run_tanh(setup)
        t_tanh.append(time.perf_counter() - tic)
        for _ in range(5):
            tic = time.perf_counter()
            simulate(dt.model, x0, inputs, t_end=sc.t_end, options=opts)
            t_ours.append(time.perf_counter() - tic)
    ours_s = statistics.median(t_ours)
    tanh_s = statistics.median(t_tanh)

    h = np.diff(res.t)
    steps = int(res.stats["steps"])
    classes = [0.0, 1e-5, 1e-4, 2e-4, 4e-4, 7e-4, opts.h_max * (1 + 1e-9)]
    by_size = []
    for lo, hi in zip(classes[:-1], classes[1:], strict=True):
        m = (h >= lo) & (h < hi)
        by_size.append(
            {
                "h_from_s": lo,
                "h_to_s": min(hi, opts.h_max),
                "steps": int(m.sum()),
                "simulated_time_s": float(h[m].sum()),
            }
        )
    lams = mode_eigs(res)
    absl = np.array([abs(v) for v in lams])
    h_stab = K.STABILITY_FACTOR / absl
    ratio = h / h_stab
    # the mode with the fastest eigenvalue in which most time is spent
    fast_lams: dict[complex, float] = {}
    for lam, hi in zip(lams, h, strict=True):
        fast_lams[lam] = fast_lams.get(lam, 0.0) + float(hi)
    lam_main = max(fast_lams, key=lambda v: fast_lams[v])
    # the fastest eigenvalues of the visited modes where the stability bound is below h_max
    stiff = [v for v in fast_lams if K.STABILITY_FACTOR / abs(v) < opts.h_max]
    fz = [natural_frequency_damping(v) for v in stiff]
    limit = dp5_limit_along(lam_main)
    min_steps = int(np.ceil((sc.t_end - 0.0) / opts.h_max))
    per_step = ours_s / steps
    best_s = min_steps * per_step
    return {
        "t_end_s": sc.t_end,
        "steps": steps,
        "rejected": int(res.stats["rejected"]),
        "nfev": int(res.stats["nfev"]),
        "n_events": len(res.events),
        "steps_by_size": by_size,
        "steps_at_h_max": int(np.sum(h >= opts.h_max * (1 - 1e-9))),
        "h_over_h_stab_quantiles": {
            q: float(np.quantile(ratio, float(q))) for q in ("0.1", "0.25", "0.5", "0.75", "0.9")
        },
        "steps_at_h_stab": int(np.sum(ratio >= 0.99)),
        "stability_factor": K.STABILITY_FACTOR,
        "dominant_fast_eigenvalue": [lam_main.real, lam_main.imag],
        "dominant_fast_eigenvalue_time_s": fast_lams[lam_main],
        "damping_ratio_of_it": natural_frequency_damping(lam_main)[1],
        "stiff_modes": len(stiff),
        "stiff_damping_ratio_range": [min(z for _, z in fz), max(z for _, z in fz)] if fz else None,
        "stiff_abs_lambda_hz_range": [min(f for f, _ in fz), max(f for f, _ in fz)] if fz else None,
        "dp5_stability_limit_along_its_ray": limit,
        "dp5_stability_limit_imaginary_axis": dp5_limit_along(1j),
        "ours_median_s": ours_s,
        "tanh_lsoda_median_s": tanh_s,
        "speedup_vs_tanh": tanh_s / ours_s,
        "ours_s_per_step": per_step,
        "min_steps_at_h_max": min_steps,
        "best_time_at_h_max_s": best_s,
        "speedup_vs_tanh_bound_at_h_max": tanh_s / best_s,
        "repeats": {"ours": len(t_ours), "tanh": len(t_tanh)},
    }


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="rounds of timing (tanh once, ours 5x)")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    a = ap.parse_args(argv)
    if a.repeats < 1:
        ap.error(f"--repeats = {a.repeats}: must be >= 1")
    out: dict[str, Any] = {"h_max_s": SimulationOptions().h_max, "scenarios": {}}
    for name in ("engage-ramp", "tip-in"):
        r = analyse(name, a.repeats)
        out["scenarios"][name] = r
        lam = complex(*r["dominant_fast_eigenvalue"])
        q = r["h_over_h_stab_quantiles"]
        print(
            f"{name}: {r['steps']} steps ({r['steps_at_h_max']} at h_max, {r['steps_at_h_stab']} "
            f"at the stability bound), h/h_stab median {q['0.5']:.2f} (10-90 %: {q['0.1']:.2f}-"
            f"{q['0.9']:.2f})"
        )
        for c in r["steps_by_size"]:
            print(
                f"  h in [{c['h_from_s']:.0e}, {c['h_to_s']:.0e}) s: {c['steps']:5d} steps, "
                f"{c['simulated_time_s']:.3f} s simulated"
            )
        print(
            f"  fastest eigenvalue where most time is spent: {lam.real:.1f}{lam.imag:+.1f}j "
            f"(damping ratio {r['damping_ratio_of_it']:.3f}); DP5 stable along its ray up to "
            f"|z| = {r['dp5_stability_limit_along_its_ray']:.2f} (imaginary axis "
            f"{r['dp5_stability_limit_imaginary_axis']:.2f}), bound used "
            f"{r['stability_factor']}"
        )
        if r["stiff_modes"]:
            zr = r["stiff_damping_ratio_range"]
            fr = r["stiff_abs_lambda_hz_range"]
            print(
                f"  {r['stiff_modes']} visited modes have a stability bound below h_max: their "
                f"fastest eigenvalue {fr[0]:.0f}-{fr[1]:.0f} Hz (|lambda| / 2 pi), damping ratio "
                f"{zr[0]:.3f}-{zr[1]:.3f}"
            )
        print(
            f"  ours {1e3 * r['ours_median_s']:.2f} ms ({1e6 * r['ours_s_per_step']:.2f} us a step)"
            f", tanh LSODA {1e3 * r['tanh_lsoda_median_s']:.0f} ms: {r['speedup_vs_tanh']:.0f}x; "
            f"at h_max on every step ({r['min_steps_at_h_max']} steps) "
            f"{1e3 * r['best_time_at_h_max_s']:.2f} ms: at most "
            f"{r['speedup_vs_tanh_bound_at_h_max']:.0f}x"
        )
    write_json(a.out, "step_limits.json", out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
