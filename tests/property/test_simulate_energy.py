"""Energy balance of whole simulations: ``E(t_end) - E(0) = W_in - sum(E_diss)`` to 1e-6
(relative, :attr:`SimulationResult.energy_residual_rel`) with the default options, for parameter
sets perturbed by up to +-30 % around the passenger car, with random static/kinetic friction ratios
in [1, 1.5], on the ``engage-ramp`` and ``tip-in`` manoeuvres."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivetrain_ctrl.plant.params import DrivetrainParams, default_params
from drivetrain_ctrl.scenarios.scenario import builtin_scenarios
from drivetrain_ctrl.sim.simulator import SimulationResult, simulate

#: parameters perturbed (multiplicative factors in [0.7, 1.3]); "k12" scales the whole pedal map
FACTORS = (
    "k12",
    "engine.J1",
    "clutch.J2",
    "damper.J3",
    "driveline.J5",
    "engine.K",
    "engine.tau_p",
    "engine.c1",
    "damper.k23",
    "gearbox.h34",
    "driveline.h45",
    "driveline.b45",
    "vehicle.M_v",
)

#: static/kinetic ratios drawn in [1, 1.5] (breakaway above sliding: stick phases hold longer)
STATIC_RATIOS = (
    "engine.static_ratio",
    "clutch.static_ratio",
    "damper.static_ratio",
    "vehicle.rolling_static_ratio",
    "vehicle.tyre_static_ratio",
)

factor = st.floats(0.7, 1.3, allow_nan=False)
factors = st.fixed_dictionaries({k: factor for k in FACTORS})
ratios = st.fixed_dictionaries({k: st.floats(1.0, 1.5, allow_nan=False) for k in STATIC_RATIOS})


def perturbed(f: dict[str, float]) -> DrivetrainParams:
    p = default_params()
    changes: dict[str, object] = {}
    for path, s in f.items():
        if path == "k12":  # the capacity k12_max * pedal_map(x_c), scaled at every x_c
            changes["clutch.k12_max"] = p.clutch.k12_max * s
        else:
            changes[path] = p.get(path) * s
    return p.replace(**changes)


def with_ratios(p: DrivetrainParams, r: dict[str, float]) -> DrivetrainParams:
    return p.replace(**r)


def run_engage(p: DrivetrainParams, kind: str, name: str = "engage-ramp") -> SimulationResult:
    sc = builtin_scenarios()[name]
    dt = sc.drivetrain(p, kind=kind)
    return simulate(dt.model, sc.initial_state(dt), sc.input_signals(), t_end=sc.t_end)


def check(res: SimulationResult) -> None:
    assert res.status == "ok"
    assert res.work_in is not None and res.work_in[-1] > 100.0
    assert res.energy_residual_rel <= 1e-6, res.energy_residual_rel
    # dissipated energies never decrease (within round-off)
    d = res.dissipated
    assert d is not None
    assert (d[-1] >= -1e-9 * res.work_in[-1]).all()


SETTINGS = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow]}


@settings(max_examples=10, **SETTINGS)
@given(f=factors)
def test_energy_residual_reduced_model(f: dict[str, float]) -> None:
    check(run_engage(perturbed(f), "reduced"))


@settings(max_examples=3, **SETTINGS)
@given(f=factors)
def test_energy_residual_full_model(f: dict[str, float]) -> None:
    check(run_engage(perturbed(f), "full"))


@settings(max_examples=3, **SETTINGS)
@given(f=factors, r=ratios)
def test_energy_residual_full_model_static_ratios(f: dict[str, float], r: dict[str, float]) -> None:
    check(run_engage(with_ratios(perturbed(f), r), "full"))


@settings(max_examples=3, **SETTINGS)
@given(f=factors, r=ratios)
def test_energy_residual_full_model_tip_in(f: dict[str, float], r: dict[str, float]) -> None:
    check(run_engage(with_ratios(perturbed(f), r), "full", "tip-in"))


@pytest.mark.slow
@settings(max_examples=25, **SETTINGS)
@given(f=factors)
def test_energy_residual_full_model_many(f: dict[str, float]) -> None:
    check(run_engage(perturbed(f), "full"))


@pytest.mark.parametrize("name", ["engage-ramp", "tip-in"])
def test_builtin_scenarios_full_model_default_params(name: str) -> None:
    sc = builtin_scenarios()[name]
    dt = sc.drivetrain(default_params(), kind="full")
    res = simulate(dt.model, sc.initial_state(dt), sc.input_signals(), t_end=sc.t_end)
    check(res)
    if name == "engage-ramp":
        t_lock = res.lockup_time()
        assert t_lock is not None and 1.0 < t_lock < 3.0
