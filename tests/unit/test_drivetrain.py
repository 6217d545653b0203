"""The drivetrain chains (full, Section II; reduced, Section III) built from the default set."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.core.units import GRAVITY
from drivetrain_ctrl.plant.drivetrain import (
    Drivetrain,
    full_chain,
    full_model,
    reduced_chain,
    reduced_figures,
    reduced_model,
)
from drivetrain_ctrl.plant.params import default_params

P = default_params()

FULL_STATES = (
    "omega_engine",
    "omega_disc",
    "omega_primary",
    "omega_secondary",
    "omega_hub",
    "omega_tread",
    "v_vehicle",
    "q_damper",
    "q_backlash",
    "q_axle",
    "q_tyre_hub",
    "pos_vehicle",
    "lag_engine",
)
REDUCED_STATES = (
    "omega_engine",
    "omega_primary",
    "v_vehicle",
    "q_backlash",
    "pos_vehicle",
    "lag_engine",
)


# -- reduced figures ------------------------------------------------------------------------------


def test_reduced_figures_default_first_gear() -> None:
    fig = reduced_figures(P, 1)
    g, dl = P.gearbox, P.driveline
    assert fig.tau_t == pytest.approx(11.56, rel=1e-12)
    assert round(fig.J25, 4) == 0.0563
    assert fig.J25 == pytest.approx(
        P.clutch.J2 + P.damper.J3 + g.J4 / 3.4**2 + dl.J5 / 11.56**2, rel=1e-12
    )
    assert fig.J25 == pytest.approx(0.01 + 0.03 + 0.05 / 11.56 + 1.6 / 133.6336, rel=1e-12)
    h_t = 1.0 / (1.0 / g.h34 + 11.56**2 * (dl.h45 + dl.h56) / (dl.h45 * dl.h56))
    assert fig.h_t == pytest.approx(h_t, rel=1e-12)
    assert fig.h_t == pytest.approx(1.0 / (1 / 5e4 + 133.6336 / 1e4), rel=1e-12)
    b_t = fig.h_t**2 * (g.b34 / g.h34**2 + 11.56**2 * (dl.b45 / dl.h45**2 + dl.b56 / dl.h56**2))
    assert fig.b_t == pytest.approx(b_t, rel=1e-12)
    assert fig.g_t == pytest.approx(0.03 * 11.56, rel=1e-12)


@pytest.mark.parametrize("gear", [1, 2, 3, 4, 5])
def test_reduced_figures_every_gear(gear: int) -> None:
    fig = reduced_figures(P, gear)
    tau_r = P.gearbox.gear_ratios[gear - 1]
    tau_t = tau_r * P.gearbox.D_c
    assert fig.tau_t == pytest.approx(tau_t, rel=1e-12)
    assert fig.J25 == pytest.approx(0.01 + 0.03 + 0.05 / tau_r**2 + 1.6 / tau_t**2, rel=1e-12)
    # higher gears (smaller ratio) put more of the wheels' inertia on the primary shaft
    if gear > 1:
        assert fig.J25 > reduced_figures(P, gear - 1).J25
        assert fig.h_t > reduced_figures(P, gear - 1).h_t


def test_reduced_chain_uses_the_figures() -> None:
    fig = reduced_figures(P, 2)
    ch = reduced_chain(P, gear=2)
    assert [b.name for b in ch.bodies] == ["engine", "primary", "vehicle"]
    assert ch.bodies[1].inertia == pytest.approx(fig.J25)
    shaft = ch.couplings[1]
    assert shaft.name == "backlash"
    assert shaft.ratio == pytest.approx(fig.tau_t / P.driveline.R_p)
    assert shaft.damper == pytest.approx(fig.b_t)
    assert shaft.spring.backlash == pytest.approx(fig.g_t)
    assert shaft.spring.y[1] / shaft.spring.x[1] == pytest.approx(fig.h_t)
    # brake capacity (wheel frame) referred to the primary shaft
    assert ch.bodies[1].ground_friction.scale == pytest.approx(1.0 / fig.tau_t)


# -- building ------------------------------------------------------------------------------------


@pytest.mark.parametrize("gear", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("kind", ["full", "reduced"])
def test_models_build_for_every_gear(kind: str, gear: int) -> None:
    dt = (full_model if kind == "full" else reduced_model)(P, gear=gear, slope=0.05)
    m = dt.model
    assert dt.kind == kind and dt.gear == gear and dt.slope == 0.05
    assert m.state_names == (FULL_STATES if kind == "full" else REDUCED_STATES)
    assert m.input_names == ("throttle", "pedal", "brake")
    assert dt.tau_t == pytest.approx(P.gearbox.gear_ratios[gear - 1] * P.gearbox.D_c)
    # the gear sets the backlash coupling's ratio and gap
    c = m.chain.couplings[[cp.name for cp in m.chain.couplings].index("backlash")]
    tau_r = P.gearbox.gear_ratios[gear - 1]
    if kind == "full":
        assert c.ratio == pytest.approx(tau_r)
    else:
        assert c.ratio == pytest.approx(tau_r * P.gearbox.D_c / P.driveline.R_p)
    assert c.spring.backlash == pytest.approx(P.gearbox.g34_primary(gear))
    # slope load on the vehicle
    iv = m.chain.body_index("vehicle")
    assert m.data.load[iv] == pytest.approx(-P.vehicle.M_v * GRAVITY * math.sin(0.05))


def test_full_model_layout() -> None:
    m = full_model(P).model
    assert [b.name for b in m.chain.bodies] == [
        "engine",
        "disc",
        "primary",
        "secondary",
        "hub",
        "tread",
        "vehicle",
    ]
    assert [c.name for c in m.chain.couplings] == [
        "clutch",
        "damper",
        "backlash",
        "axle",
        "tyre_hub",
        "tyre",
    ]
    assert [f.name for f in m.frictions] == [
        "clutch",
        "damper_friction",
        "tyre",
        "engine",
        "brake",
        "vehicle",
    ]
    assert m.frictions[2].mode_names == ("grip", "slip+", "slip-", "lifted")
    assert m.chain.bodies[4].inertia + m.chain.bodies[5].inertia == pytest.approx(1.6)
    assert m.state_units[m.state_index("v_vehicle")] == "m/s"
    assert m.state_units[m.state_index("q_backlash")] == "rad"
    assert m.state_units[m.state_index("pos_vehicle")] == "m"


@pytest.mark.parametrize("builder", [full_model, reduced_model, full_chain, reduced_chain])
@pytest.mark.parametrize("gear", [0, 6, -1, 2.0, True, "1"])
def test_bad_gear_raises_naming_it(builder, gear) -> None:
    with pytest.raises(ValueError, match="gear"):
        builder(P, gear=gear)


@pytest.mark.parametrize("gear", [0, 6])
def test_reduced_figures_bad_gear(gear: int) -> None:
    with pytest.raises(ValueError, match="gear"):
        reduced_figures(P, gear)


@pytest.mark.parametrize("builder", [full_model, reduced_model])
@pytest.mark.parametrize("slope", [math.pi / 2, -2.0, float("nan"), float("inf")])
def test_bad_slope_raises_naming_it(builder, slope: float) -> None:
    with pytest.raises(ValueError, match="slope"):
        builder(P, slope=slope)


def test_bad_kind_raises() -> None:
    with pytest.raises(ValueError, match="kind"):
        Drivetrain(P, kind="medium")


# -- rigid_state -----------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["full", "reduced"])
@pytest.mark.parametrize("gear", [1, 3])
def test_rigid_state_coasting(kind: str, gear: int) -> None:
    dt = (full_model if kind == "full" else reduced_model)(P, gear=gear)
    m = dt.model
    x = dt.rigid_state(omega_engine=150.0, v_vehicle=8.0, throttle=0.2, twist_torque=-40.0)
    assert x[m.state_index("omega_engine")] == 150.0
    assert x[m.state_index("v_vehicle")] == 8.0
    assert x[m.state_index("lag_engine")] == 0.2
    assert x[m.state_index("omega_primary")] == pytest.approx(8.0 * dt.tau_t / P.driveline.R_p)
    # every relative speed is zero except the clutch's (engine at its own speed)
    for c, cp in enumerate(m.chain.couplings):
        w = x[c] - cp.ratio * x[c + 1]
        if cp.name == "clutch":
            assert w != pytest.approx(0.0)
        else:
            assert w == pytest.approx(0.0, abs=1e-12), cp.name
    u = m.inputs(throttle=0.2, pedal=0.05, brake=0.0)
    mode = m.mode_from_state(x, u, {})
    assert m.mode_names(mode)["backlash"] == "contact-"
    # the springs carry the twist torque (primary frame): the torque times the ratios above
    _, reg = mode.arrays()
    no_friction = np.full(len(m.frictions), K.OPEN, dtype=np.int64)
    lam0 = np.zeros((len(m.frictions), m.n_bodies))
    tq = K.coupling_torques(m.data, x, u, no_friction, reg, lam0)
    ratio_above = 1.0
    for c, cp in enumerate(m.chain.couplings):
        if cp.spring is not None:
            assert tq[c] == pytest.approx(-40.0 * ratio_above, rel=1e-9), cp.name
        ratio_above *= cp.ratio
    # the backlash gap is taken up
    q = x[m.state_index("q_backlash")]
    assert q < -P.gearbox.g34_primary(gear)


@pytest.mark.parametrize("kind", ["full", "reduced"])
def test_rigid_state_drive_and_zero_torque(kind: str) -> None:
    dt = (full_model if kind == "full" else reduced_model)(P)
    m = dt.model
    u = m.inputs(throttle=0.0, pedal=0.05, brake=0.0)
    x = dt.rigid_state(omega_engine=100.0, v_vehicle=5.0, twist_torque=30.0)
    assert m.mode_names(m.mode_from_state(x, u, {}))["backlash"] == "contact+"
    x0 = dt.rigid_state(omega_engine=100.0, v_vehicle=5.0)
    assert m.mode_names(m.mode_from_state(x0, u, {}))["backlash"] == "gap"
    for c, cp in enumerate(m.chain.couplings):
        if cp.spring is not None:
            assert x0[m.data.c_q[c]] == 0.0


# -- immutability ----------------------------------------------------------------------------------


def test_drivetrain_is_immutable() -> None:
    dt = full_model(P)
    for attr, value in [("gear", 2), ("model", None), ("slope", 0.1), ("new_attr", 1)]:
        with pytest.raises(AttributeError):
            setattr(dt, attr, value)
    assert dt.gear == 1 and dt.slope == 0.0


def test_model_is_immutable() -> None:
    m = reduced_model(P).model
    for attr in ("chain", "data", "state_names", "frictions", "tables"):
        with pytest.raises(AttributeError, match="immutable"):
            setattr(m, attr, None)
    with pytest.raises(AttributeError):
        m.new_attr = 1  # type: ignore[attr-defined]
    # the compiled arrays are read-only
    with pytest.raises(ValueError):
        m.data.M[0] = 1.0
    with pytest.raises(ValueError):
        m.data.t_b[0, 0] = 1.0
    assert m.data.M[0] == P.engine.J1
    # the chain is a frozen dataclass
    with pytest.raises(AttributeError):
        m.chain.bodies = ()  # type: ignore[misc]


def test_attributes_cannot_be_deleted() -> None:
    dt = reduced_model(P)
    with pytest.raises(AttributeError):
        del dt.model
    m = reduced_model(P).model
    with pytest.raises(AttributeError):
        del m._frozen
    with pytest.raises(AttributeError, match="immutable"):
        m.chain = None  # type: ignore[assignment]
