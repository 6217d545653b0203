"""The compiled kernels are cached on disk: a second process loads them, it does not compile."""

from __future__ import annotations

import os
import subprocess
import sys

RUN = """
import numpy as np
from drivetrain_ctrl.plant.chain import two_body_clutch
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.sim.simulator import simulate
res = simulate(Model(two_body_clutch(0.2, 1.0, capacity=50.0)), [100.0, 0.0], {"torque1": 20.0},
               t_end=1.0)
assert res.status == "ok" and len(res.events) == 1
"""


def _run_with_cache_log() -> str:
    env = {**os.environ, "NUMBA_DEBUG_CACHE": "1"}
    out = subprocess.run(
        [sys.executable, "-c", RUN], env=env, capture_output=True, text=True, check=True
    )
    return out.stdout + out.stderr


def test_second_process_loads_the_kernels_without_compiling() -> None:
    _run_with_cache_log()  # compiles and saves whatever is not cached yet (nothing after warm-up)
    log = _run_with_cache_log()
    loaded = [ln for ln in log.splitlines() if "data loaded from" in ln]
    saved = [ln for ln in log.splitlines() if "data saved to" in ln]
    assert any("simulate_kernel" in ln for ln in loaded), log[-2000:]
    assert saved == [], saved[:5]
