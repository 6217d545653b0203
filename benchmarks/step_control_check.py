"""Could the step-size control take longer steps? Two checks on instrumented copies of the kernel.

Usage::

    python benchmarks/step_control_check.py [--repeats N] [--factors 2.0,2.2] [--quick]

``step_limits.py`` finds that most steps sit below the stability bound of the lightly damped
gear-mesh mode. This script asks two questions it cannot answer from outside the kernel:

1. **Which state's error sets the steps?** Every attempted step (accepted or rejected) whose
   weighted RMS error norm is at least 0.1 (where the error control holds the step back) is
   counted under the state with the largest weighted error component ``|err_i| / (atol + rtol
   |y_i|)``.
2. **Does the stability cap cost steps?** The simulator caps each step at ``STABILITY_FACTOR /
   rho`` (2.5 / rho, with ``rho`` a tight bound of the mode's spectral radius), which lies above
   Dormand-Prince's stability limit along the gear-mesh eigenvalue's ray (2.2 / |lambda| in tip-in,
   see ``step_limits.py``), so the error control, not the cap, keeps the steps stable there. Copies
   with the factors of ``--factors`` (below that limit: the cap binds instead) show whether a
   binding cap would let the steps sit closer to the limit.

For each factor a copy of the package is patched (the counter, and the factor), compiled in its own
temporary directory (a few minutes; the copies compile in parallel, then run one after another;
the installed package is not touched) and runs the full-model ``engage-ramp`` and ``tip-in`` at
default options: steps, rejected steps, right-hand-side evaluations, the counts of question 1,
and the event-time and speed errors against the DOP853 reference of ``bench_simulate.py``
(rtol 1e-12, computed once here). Times (median of ``--repeats`` kernel runs) are printed for
information only: the copies run in separate processes on a shared machine. Writes
``benchmarks/results/step_control.json``.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import pickle
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_simulate as BS  # noqa: E402
from profile_kernel import WRAP_KERNEL, patched_copy  # noqa: E402

from drivetrain_ctrl import kernels as K  # noqa: E402

OUT = HERE / "results" / "step_control.json"
ACTIVE_NORM = 0.1  # RMS error norm from which a step counts as held back by the error control

# the counter: ist[8 + i] counts the error-active attempted steps led by component i; returned
# as the kernel's last output (its threshold ACTIVE_SUM: see variant_patches)
_COUNT_PATCHES: list[tuple[str, str, str, int]] = [
    (
        "counter array",
        "    ist = np.zeros(8, dtype=np.int64)\n",
        "    ist = np.zeros(8 + nxs, dtype=np.int64)\n",
        1,
    ),
    (
        "count",
        "        en = np.sqrt(en / nxs)\n",
        "        if en >= ACTIVE_SUM * nxs:\n"
        "            rmx = -1.0\n"
        "            imx = 0\n"
        "            for i in range(nxs):\n"
        "                a = abs(y[i])\n"
        "                b = abs(y1[i])\n"
        "                r = abs(err[i]) / (atol + rtol * (a if a > b else b))\n"
        "                if r > rmx:\n"
        "                    rmx = r\n"
        "                    imx = i\n"
        "            ist[8 + imx] += 1\n"
        "        en = np.sqrt(en / nxs)\n",
        1,
    ),
    (
        "return the counts",
        "        n_knee,\n        n_incons,\n    )",
        "        n_knee,\n        n_incons,\n        ist[8:].copy(),\n    )",
        1,
    ),
]

# the package's warm-up, with the kernel's extra output (the counts) dropped
_WARMUP = WRAP_KERNEL + "from drivetrain_ctrl.warmup import warmup\nwarmup()\n"

_RUNNER = (
    WRAP_KERNEL
    + r"""
import json, pickle, statistics, sys
from pathlib import Path
dest, refdir, repeats, out = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
sys.path.insert(0, sys.argv[5])
import bench_simulate as BS
import drivetrain_ctrl
from drivetrain_ctrl import simulate as SM
assert Path(drivetrain_ctrl.__file__).resolve().is_relative_to(dest.resolve()), drivetrain_ctrl.__file__
result = {"stability_factor": K.STABILITY_FACTOR}
for name in BS.SCENARIOS:
    s = BS.scenario_setup(name)
    ref = pickle.loads((refdir / f"{name}.pkl").read_bytes())
    SM.simulate(s.dt.model, s.x0, s.inputs, t_end=s.sc.t_end)  # compile or load
    times = []
    for _ in range(repeats):
        res = SM.simulate(s.dt.model, s.x0, s.inputs, t_end=s.sc.t_end)
        times.append(res.stats["wall_time_s"])
    names = s.dt.model.state_names
    counts = {names[i]: int(c) for i, c in enumerate(captured["extra"]) if c > 0}
    ev = BS.match_events(ref.events, BS.ours_events(res))
    result[name] = {
        "steps": res.stats["steps"],
        "rejected": res.stats["rejected"],
        "nfev": res.stats["nfev"],
        "n_events": len(res.events),
        "error_active_steps_by_leading_state": counts,
        "event_err_s": ev["max_abs_err_s"],
        "unmatched_events": [ev["unmatched_ref"], ev["unmatched_method"]],
        "speed_err_rad_s": BS.speed_error(ref, res.t, res.x)["max_abs"],
        "kernel_median_s": statistics.median(times),
    }
Path(out).write_text(json.dumps(result))
"""
)


def variant_patches(factor: float) -> list[tuple[str, str, str, int]]:
    """The counter patches, its threshold ``ACTIVE_SUM`` and ``STABILITY_FACTOR`` = ``factor``."""
    line = f"STABILITY_FACTOR = {K.STABILITY_FACTOR!r}\n"
    consts = f"ACTIVE_SUM = {ACTIVE_NORM**2!r}\nSTABILITY_FACTOR = {factor!r}\n"
    return [*_COUNT_PATCHES, ("constants", line, consts, 1)]


def references(refdir: Path) -> None:
    """The reference of each scenario (``bench_simulate.reference_run``), pickled."""
    for name in BS.SCENARIOS:
        ref = BS.reference_run(BS.scenario_setup(name))
        (refdir / f"{name}.pkl").write_bytes(pickle.dumps(ref))
        print(f"reference {name}: {len(ref.events)} events", flush=True)


def parse_factors(text: str) -> list[float]:
    out = []
    for part in text.split(","):
        try:
            f = float(part)
        except ValueError:
            raise SystemExit(f"--factors: {part!r} is not a number") from None
        if not (0.0 < f < 10.0):
            raise SystemExit(f"--factors: {f!r} must be in (0, 10)")
        out.append(f)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15, help="timed runs per scenario and copy")
    ap.add_argument("--factors", default="2.0,2.2", help="other STABILITY_FACTOR values to try")
    ap.add_argument("--quick", action="store_true", help="3 repeats, the counter copy only")
    a = ap.parse_args(argv)
    if a.repeats < 1:
        ap.error(f"--repeats = {a.repeats}: must be >= 1")
    factors = [K.STABILITY_FACTOR]
    if not a.quick:
        factors += [f for f in dict.fromkeys(parse_factors(a.factors)) if f != factors[0]]
    repeats = 3 if a.quick else a.repeats
    with tempfile.TemporaryDirectory(prefix="dtc-stepctl-") as tmp:
        root = Path(tmp)
        refdir = root / "ref"
        refdir.mkdir()
        dests = []
        for k, f in enumerate(factors):
            dest = root / f"copy{k}"
            dest.mkdir()
            patched_copy(dest, variant_patches(f))
            dests.append(dest)
        print(f"compiling {len(dests)} patched copy(ies) in {root} (a few minutes) ...", flush=True)
        procs = [
            subprocess.Popen(
                [sys.executable, "-c", _WARMUP],
                env=dict(os.environ, PYTHONPATH=str(d)),
                cwd=d,
                stdout=subprocess.DEVNULL,
            )
            for d in dests
        ]
        references(refdir)
        if any(p.wait() != 0 for p in procs):
            raise SystemExit("compiling a patched copy failed")
        per: dict[str, Any] = {}
        for f, dest in zip(factors, dests, strict=True):
            out = dest / "result.json"
            subprocess.run(
                [sys.executable, "-c", _RUNNER, str(dest), str(refdir), str(repeats), str(out),
                 str(HERE)],
                env=dict(os.environ, PYTHONPATH=str(dest)),
                cwd=dest,
                check=True,
            )  # fmt: skip
            per[f"factor_{f:g}"] = json.loads(out.read_text())
    summary = {
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "active_norm": ACTIVE_NORM,
        "repeats": repeats,
        "variants": per,
    }
    for key, r in per.items():
        for name in BS.SCENARIOS:
            v = r[name]
            lead = max(v["error_active_steps_by_leading_state"].items(), key=lambda kv: kv[1])
            tot = sum(v["error_active_steps_by_leading_state"].values())
            print(
                f"{key:11s} {name:12s} steps {v['steps']:5d} rejected {v['rejected']:4d} "
                f"event err {v['event_err_s']:.2e} s speed err {v['speed_err_rad_s']:.2e} rad/s "
                f"kernel {1e3 * v['kernel_median_s']:.1f} ms; error-active steps {tot}, "
                f"{100 * lead[1] / max(tot, 1):.0f} % led by {lead[0]}",
                flush=True,
            )
    if not a.quick:
        OUT.parent.mkdir(exist_ok=True)
        OUT.write_text(json.dumps(summary, indent=1) + "\n")
        print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
