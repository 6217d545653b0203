"""Compile (or load from numba's cache) every kernel once: ``python -m drivetrain_ctrl.sim.warmup``.

The first call in a fresh environment compiles the hybrid integrator (a notice on stderr shows
the expected and the elapsed time); later processes load the cached machine code. ``./dev`` runs this before the tests so that
parallel test workers do not all compile at once.
"""

from __future__ import annotations

import time

import control
import numpy as np

from ..control.blocks import Controller
from ..core.signals import constant
from ..plant.chain import Body, Chain
from ..plant.model import Model
from ..plant.params import default_params
from ..scenarios.scenario import load_scenario
from .compile_notice import compile_progress, kernels_ready
from .simulator import SimulationOptions, simulate


def warmup() -> float:
    """Run tiny open- and closed-loop simulations; returns the wall time [s]."""

    tic = time.perf_counter()
    sc = load_scenario("engage-ramp")
    dt = sc.drivetrain(default_params(), kind="reduced")
    x0 = sc.initial_state(dt)
    simulate(dt.model, x0, sc.input_signals(), t_end=0.05)
    simulate(dt.model, x0, sc.input_signals(), t_end=0.05, options=SimulationOptions(energy=False))
    one = Model(Chain((Body("b", 1.0, torque_input="torque"),), (), inputs=("torque",)))
    c = Controller(
        lti=control.ss([], [], [], [[1.0]]),
        measurement=((1.0, "ref"), (-1.0, "omega_b")),
        reference=constant(1.0),
        output="torque",
    )
    simulate(one, np.zeros(1), {}, t_end=0.01, controller=c)
    dt.model.jacobian(
        x0,
        dt.model.inputs(throttle=0.5, pedal=0.07, brake=0.0),
        dt.model.decide(x0, dt.model.inputs(throttle=0.5, pedal=0.07, brake=0.0))[0],
    )
    return time.perf_counter() - tic


def ensure_compiled() -> None:
    """Compile the kernels now, with the one-line progress notice on stderr, unless they are
    cached (then nothing happens): for the command line, before its first simulation."""
    if not kernels_ready():
        with compile_progress():
            warmup()


if __name__ == "__main__":  # pragma: no cover
    with compile_progress():
        seconds = warmup()
    print(f"kernels ready in {seconds:.1f} s")
