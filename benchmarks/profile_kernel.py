"""Where does the simulator's time go? A cycle-counter profile of an instrumented kernel copy.

Usage::

    python benchmarks/profile_kernel.py [--repeats N] [--keep DIR] [--out DIR]

Numba's compiled code has no symbols a sampling profiler could use, so this script copies the
package into a temporary directory, inserts reads of the CPU's cycle counter
(``llvm.readcyclecounter``) around the parts of ``simulate_kernel`` (the step loop ``_advance``,
the event location ``_locate``, the mode decisions ``_redecide``, the first derivative after an
event or a stop, the tight stability bound of a new mode) and counts the Illinois iterations of
the event location, compiles that copy (a few minutes: its own numba cache, the installed package
is not touched) and runs the full-model ``engage-ramp`` and ``tip-in`` in a subprocess. For each
scenario it prints the share of the kernel's time-stamp-counter ticks (cycles at a constant rate)
per part (the repeat with the fewest ticks) and the ticks per step, event location and mode
decision, and writes them to ``profile_kernel.json`` (``--out``, default ``benchmarks/results/``),
with that repeat's kernel wall time (``kernel_wall_s``: seconds per tick) and the median wall
time of the whole ``simulate()`` call (its Python part is the difference).

The patch is a set of exact text replacements in ``kernels.py``; if one does not apply (the
kernel changed), the script stops and names it.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from results_io import write_json  # noqa: E402

_INTRINSIC = """from numba.typed import Dict
from numba.extending import intrinsic as _intrinsic
from numba.core import cgutils as _cgutils
from llvmlite import ir as _ir


@_intrinsic
def rdtsc(typingctx):
    sig = types.float64()

    def codegen(context, builder, signature, args):
        fnty = _ir.FunctionType(_ir.IntType(64), [])
        fn = _cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.uitofp(builder.call(fn, []), _ir.DoubleType())

    return sig, codegen
"""

#: (name, old text, new text, expected count); prof[0..4]: ticks in advance, locate, redecide,
#: rhs after an event, tight stability bound; prof[5]: total; 6, 7, 8: locates, decisions, iters
_PATCHES: list[tuple[str, str, str, int]] = [
    ("imports", "from numba.typed import Dict\n", _INTRINSIC, 1),
    (
        "locate signature",
        '    ys,\n    yhi,\n):  # type: ignore[no-untyped-def]\n    """Locate the event',
        '    ys,\n    yhi,\n    prof,\n):  # type: ignore[no-untyped-def]\n    """Locate the event',
        1,
    ),
    (
        "locate iterations",
        "        dense_eval(rc, s, ys)\n        _guards_step_inl(",
        "        prof[8] += 1.0\n        dense_eval(rc, s, ys)\n        _guards_step_inl(",
        1,
    ),
    (
        "locate start",
        "            hi, j = _locate(",
        "            c0 = rdtsc()\n            hi, j = _locate(",
        1,
    ),
    (
        "locate end",
        "                ys,\n                yhi,\n            )\n            t = t + hi * hh",
        "                ys,\n                yhi,\n                prof,\n            )\n"
        "            prof[1] += rdtsc() - c0\n            prof[6] += 1.0\n            t = t + hi * hh",
        1,
    ),
    (
        "redecide start",
        "            slot, nb, h_stab, stab_exact, n_ev = _redecide(",
        "            c0 = rdtsc()\n            prof[7] += 1.0\n"
        "            slot, nb, h_stab, stab_exact, n_ev = _redecide(",
        1,
    ),
    (
        "redecide end",
        "            )  # fmt: skip\n            if nb == DM_TOO_MANY:",
        "            )  # fmt: skip\n            prof[2] += rdtsc() - c0\n            if nb == DM_TOO_MANY:",
        1,
    ),
    (
        "rhs after event or stop: start",
        "            full_rhs_call(\n                D,",
        "            c0 = rdtsc()\n            full_rhs_call(\n                D,",
        1,
    ),
    (
        "rhs after event or stop: end",
        "            Ks[0, :] = dy\n            nfev += 1\n",
        "            Ks[0, :] = dy\n            prof[3] += rdtsc() - c0\n            nfev += 1\n",
        1,
    ),
    (
        "advance start",
        "        code = _advance(",
        "        c0 = rdtsc()\n        code = _advance(",
        1,
    ),
    (
        "advance end",
        "        t = fs[0]\n        h = fs[1]\n        lerr_old = fs[2]\n        n_steps = ist[1]",
        "        prof[0] += rdtsc() - c0\n"
        "        t = fs[0]\n        h = fs[1]\n        lerr_old = fs[2]\n        n_steps = ist[1]",
        1,
    ),
    (
        "stability bound",
        "            h_stab = stable_step_exact(fm, reg, hcache, jcache)\n",
        "            c0 = rdtsc()\n            h_stab = stable_step_exact(fm, reg, hcache, jcache)\n"
        "            prof[4] += rdtsc() - c0\n",
        1,
    ),
    (
        "counters",
        "    ist = np.zeros(8, dtype=np.int64)\n",
        "    ist = np.zeros(8, dtype=np.int64)\n    prof = np.zeros(10)\n    c_start = rdtsc()\n",
        1,
    ),
    (
        "total",
        "    n_knee = 0\n    for e in range(n_ev):",
        "    prof[5] = rdtsc() - c_start\n    n_knee = 0\n    for e in range(n_ev):",
        1,
    ),
    (
        "return",
        "        n_knee,\n        n_incons,\n    )",
        "        n_knee,\n        n_incons,\n        prof,\n    )",
        1,
    ),
]

#: runner prelude for a patched copy whose kernel returns one extra output (last): ``simulate``
#: gets the usual outputs, the extra one is kept in ``captured["extra"]``
WRAP_KERNEL = """
from drivetrain_ctrl import kernels as K
captured = {}
_orig = K.simulate_kernel


def _wrapped(*args):
    out = _orig(*args)
    captured["extra"] = out[-1]
    return out[:-1]


K.simulate_kernel = _wrapped
"""

_RUNNER = (
    WRAP_KERNEL
    + r"""
import json
import sys
import time
import numpy as np
from drivetrain_ctrl import simulate as SM
from drivetrain_ctrl.params import default_params
from drivetrain_ctrl.scenarios import builtin_scenarios

repeats = int(sys.argv[1])
p = default_params()
labels = ["step loop (_advance)", "event location (_locate)", "mode decisions (_redecide)",
          "derivative after an event or stop", "tight stability bound (new mode)"]
keys = ["step_loop", "event_location", "mode_decisions", "derivative_after_event_or_stop",
        "tight_stability_bound"]
summary = {}
for name in ("engage-ramp", "tip-in"):
    sc = builtin_scenarios(p)[name]
    dt = sc.drivetrain(p, kind="full")
    x0 = sc.initial_state(dt)
    best = None
    walls = []
    for _ in range(repeats):
        tic = time.perf_counter()
        res = SM.simulate(dt.model, x0, sc.input_signals(), t_end=sc.t_end)
        walls.append(time.perf_counter() - tic)
        pr = captured["extra"].copy()
        if best is None or pr[5] < best[0][5]:
            best = (pr, res.stats)
    pr, st = best
    tot = pr[5]
    print(f"{name}: {tot:.3g} time-stamp-counter ticks in the kernel ({st['steps']} steps, {st['rejected']} "
          f"rejected, {len(res.events)} events; fewest of {repeats} runs)")
    for i, lab in enumerate(labels):
        print(f"  {lab:36s} {100 * pr[i] / tot:5.1f} %")
    print(f"  {'the rest':36s} {100 * (tot - pr[:5].sum()) / tot:5.1f} %")
    n_loc, n_dec, n_it = pr[6], pr[7], pr[8]
    print(f"  per accepted or rejected step in the loop: "
          f"{pr[0] / (st['steps'] + st['rejected']):.0f} ticks; per event location "
          f"{pr[1] / max(n_loc, 1):.0f} ticks ({n_it / max(n_loc, 1):.1f} Illinois iterations); "
          f"per mode decision {pr[2] / max(n_dec, 1):.0f} ticks")
    summary[name] = {
        "kernel_ticks": float(tot),
        "kernel_wall_s": float(st["wall_time_s"]),
        "share": {k: float(pr[i] / tot) for i, k in enumerate(keys)}
        | {"rest": float((tot - pr[:5].sum()) / tot)},
        "steps": int(st["steps"]),
        "rejected": int(st["rejected"]),
        "events": len(res.events),
        "event_locations": int(n_loc),
        "mode_decisions": int(n_dec),
        "illinois_iterations_per_location": float(n_it / max(n_loc, 1)),
        "ticks_per_step": float(pr[0] / (st["steps"] + st["rejected"])),
        "ticks_per_location": float(pr[1] / max(n_loc, 1)),
        "ticks_per_decision": float(pr[2] / max(n_dec, 1)),
        "simulate_wall_s_median": float(np.median(walls)),
    }
print("JSON " + json.dumps(summary))
"""
)


def patched_copy(dest: Path, patches: Sequence[tuple[str, str, str, int]] = _PATCHES) -> None:
    """Copy ``drivetrain_ctrl`` to ``dest`` and apply ``patches`` (name, old text, new text,
    expected count; default: this script's instrumentation) to its ``kernels.py``."""
    pkg = dest / "drivetrain_ctrl"
    shutil.copytree(
        ROOT / "drivetrain_ctrl",
        pkg,
        ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"),
    )
    path = pkg / "kernels.py"
    path.write_text(apply_patches(path.read_text(), patches))


def apply_patches(src: str, patches: Sequence[tuple[str, str, str, int]]) -> str:
    """``src`` (the text of ``kernels.py``) with ``patches`` applied in order; stops with an
    error naming the patch whose old text does not occur exactly the expected number of times."""
    for name, old, new, count in patches:
        got = src.count(old)
        if got != count:
            raise SystemExit(
                f"patch {name!r}: expected {count} occurrence(s) in kernels.py, found {got}; "
                "update the patch to the current kernel"
            )
        src = src.replace(old, new)
    return src


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--repeats", type=int, default=15, help="runs per scenario (the fastest counts)"
    )
    ap.add_argument("--keep", type=Path, default=None, help="build the copy here and keep it")
    ap.add_argument("--out", type=Path, default=HERE / "results", help="where the JSON goes")
    a = ap.parse_args(argv)
    if a.repeats < 1:
        ap.error(f"--repeats = {a.repeats}: must be >= 1")
    tmp = None
    if a.keep is None:
        tmp = tempfile.TemporaryDirectory(prefix="dtc-profile-")
        dest = Path(tmp.name)
    else:
        dest = a.keep
        dest.mkdir(parents=True, exist_ok=True)
        if (dest / "drivetrain_ctrl").exists():
            shutil.rmtree(dest / "drivetrain_ctrl")
    try:
        patched_copy(dest)
        print(
            f"instrumented copy in {dest}; compiling it (a few minutes) and running ...", flush=True
        )
        env = dict(os.environ, PYTHONPATH=str(dest))
        r = subprocess.run(
            [sys.executable, "-c", _RUNNER, str(a.repeats)],
            env=env,
            cwd=dest,
            check=False,
            stdout=subprocess.PIPE,
            text=True,
        )
        summary = None
        for line in r.stdout.splitlines():
            if line.startswith("JSON "):
                summary = json.loads(line[5:])
            else:
                print(line)
        if r.returncode != 0 or summary is None:
            return r.returncode or 1
        write_json(a.out, "profile_kernel.json", {"repeats": a.repeats, "scenarios": summary})
        return 0
    finally:
        if tmp is not None:
            tmp.cleanup()


if __name__ == "__main__":
    raise SystemExit(main())
