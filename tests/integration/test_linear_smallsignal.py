"""The linearisation against the switching plant: small input perturbations while the mode holds.

In slip (constant mu, pedal inside one piece of the pedal map) and in lock the plant is affine up
to the quadratic drag, so the difference perturbed - nominal of two nonlinear simulations must
match ``control.forced_response`` of the linear model from the same operating point.
"""

from __future__ import annotations

import control
import numpy as np
import pytest

from drivetrain_ctrl import linear as L
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.plant.drivetrain import full_model, reduced_model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.sim.simulator import simulate

P = default_params()


def _compare(op, name: str, step: float, outputs: list[str], t_end: float, tol: float):
    m = op.model
    u0 = {n: float(v) for n, v in zip(m.input_names, op.u, strict=True)}
    nominal = simulate(m, np.array(op.x), u0, t_end=t_end)
    pert = dict(u0)
    pert[name] = sg.constant(u0[name]) + sg.step(0.0, step)
    perturbed = simulate(m, np.array(op.x), pert, t_end=t_end)
    for res in (nominal, perturbed):
        for fi in m.frictions:
            series = res.mode_series(fi.name)
            assert len(set(series)) == 1, f"{fi.name} changed mode: the test needs one mode"
    sys = L.linearise(op, inputs=("throttle", "x_c"), outputs=outputs)
    lin_in = "x_c" if name == "pedal" else name
    t = np.linspace(0.0, t_end, 301)
    U = np.zeros((2, t.size))
    U[list(sys.input_labels).index(lin_in)] = step
    lin = control.forced_response(sys, T=t, U=U).outputs
    for k, o in enumerate(outputs):
        a = np.interp(t, nominal.t, nominal.state(o))
        b = np.interp(t, perturbed.t, perturbed.state(o))
        d = b - a
        # outputs the input does not reach (e.g. throttle -> driveline in slip) must stay at 0
        scale = max(float(np.max(np.abs(lin[k]))), 1e-6)
        assert np.max(np.abs(d - lin[k])) < tol * scale, o


def test_slip_pedal_step_reduced():
    op = L.slip_operating_point(
        reduced_model(P), omega_engine=170.0, omega_driven=80.0, x_c=0.0725, throttle=0.5
    )
    _compare(op, "pedal", 2e-4, ["omega_engine", "omega_primary", "v_vehicle"], 0.4, 1e-3)


def test_slip_throttle_step_reduced():
    op = L.slip_operating_point(
        reduced_model(P), omega_engine=170.0, omega_driven=80.0, x_c=0.0725, throttle=0.5
    )
    # with constant mu the throttle does not reach the driveline in slip (decoupling)
    _compare(op, "throttle", 0.01, ["omega_engine", "omega_primary"], 0.4, 1e-3)


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_locked_throttle_step(kind):
    dt = (reduced_model if kind == "reduced" else full_model)(P)
    op = L.locked_trim(dt, vehicle_speed_kmh=30.0)
    _compare(op, "throttle", 0.01, ["omega_engine", "v_vehicle"], 0.6, 2e-3)
