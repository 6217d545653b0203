"""A fresh environment: the first call compiles, says so once, and gives the warm run's result."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

DIGESTS = """
import hashlib
import drivetrain_ctrl as D

def digests():
    out = []
    p = D.default_params()
    for name, ctl in (("engage-ramp", None), ("paper-start", "paper")):
        sc = D.load_scenario(name)
        r = D.run_scenario(sc, sc.drivetrain(p, kind="reduced"), controller=ctl)
        h = hashlib.sha256()
        for a in (r.t, r.x, r.u, r.fm, r.reg):
            h.update(a.tobytes())
        out.append(f"{name} {h.hexdigest()}")
    return out
"""
#: the same code in a new process: one line per scenario
SCRIPT = DIGESTS + "\nprint('\\n'.join(digests()))\n"


def _digests_here() -> list[str]:
    ns: dict[str, object] = {}
    exec(DIGESTS, ns)
    return ns["digests"]()  # type: ignore[operator,no-any-return]


def _run(cache: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    return subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True
    )


@pytest.mark.slow
def test_a_fresh_cache_first_call_equals_a_warm_run_and_says_it_compiles(tmp_path: Path) -> None:
    fresh = _run(tmp_path)  # empty cache: compiles everything
    assert fresh.stdout.split("\n")[:2] == _digests_here()
    assert fresh.stderr.count("compiling the simulator kernels") == 1, fresh.stderr
    again = _run(tmp_path)  # the cache is filled: loads, says nothing
    assert again.stdout == fresh.stdout
    assert "compiling" not in again.stderr, again.stderr
