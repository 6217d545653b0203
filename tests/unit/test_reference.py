"""Full drivetrain chain model against the flat reference model (drivetrain_ctrl.reference).

For random states and every friction-mode combination, ``Model.rhs`` and ``Model.stuck_torques``
must equal the hand-written ODE of :mod:`drivetrain_ctrl.reference`. The reference itself is
checked against an energy balance written out here (power in - power dissipated = dE/dt).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from drivetrain_ctrl.core.units import GRAVITY
from drivetrain_ctrl.plant.drivetrain import Drivetrain, full_model
from drivetrain_ctrl.plant.model import Mode
from drivetrain_ctrl.plant.params import DrivetrainParams, default_params
from drivetrain_ctrl.testing.reference import (
    FRICTION_MODE_NAMES,
    full_reference_rhs,
    full_reference_stuck_torques,
)

FALLING_MU = {"x": [0.0, 10.0, 50.0, 200.0], "y": [1.0, 0.95, 0.85, 0.8]}

#: name -> (parameter changes, gear, slope [rad])
CASES: dict[str, tuple[dict[str, object], int, float]] = {
    "default": ({}, 1, 0.0),
    "map": ({"engine.torque_model": "map"}, 1, 0.0),
    "falling_mu": ({"clutch.mu_table": FALLING_MU}, 1, 0.0),
    "uphill": ({}, 1, 0.12),
    "gear3": ({}, 3, 0.0),
    "contact": ({"gearbox.backlash_damping": "contact"}, 2, 0.0),
    "all": (
        {
            "engine.torque_model": "map",
            "gearbox.backlash_damping": "contact",
            "clutch.mu_table": FALLING_MU,
            "clutch.static_ratio": 1.3,
            "driveline.b5": 0.7,
            "vehicle.b_v": 5.0,
            "brake.static_ratio": 1.2,
        },
        3,
        -0.08,
    ),
    "no_c1_k23": ({"engine.c1": 0.0, "damper.k23": 0.0}, 2, 0.05),
}

SPEEDS = slice(0, 7)


@functools.cache
def _case(name: str) -> tuple[DrivetrainParams, Drivetrain]:
    changes, gear, slope = CASES[name]
    p = default_params().replace(**changes) if changes else default_params()
    return p, full_model(p, gear=gear, slope=slope)


def _random_state(rng: np.random.RandomState, d: Drivetrain) -> tuple[np.ndarray, np.ndarray]:
    """A state near the rolling drivetrain (shaft speeds perturbed) with random twists/inputs."""
    p = d.params
    R = p.driveline.R_p
    Dc = p.gearbox.D_c
    tau_r = p.gearbox.tau_r(d.gear)
    g = p.gearbox.g34_primary(d.gear)
    x = np.zeros(d.model.nx)
    v = rng.uniform(-5.0, 40.0)
    x[6] = v
    x[5] = v / R + rng.normal(0.0, 0.5)  # tread
    x[4] = v / R + rng.normal(0.0, 1.0)  # hub
    x[3] = x[4] * Dc + rng.normal(0.0, 1.0)  # secondary
    x[2] = x[3] * tau_r + rng.normal(0.0, 3.0)  # primary
    x[1] = x[2] + rng.normal(0.0, 3.0)  # disc
    x[0] = rng.uniform(-20.0, 650.0)  # engine
    x[7] = rng.uniform(-0.25, 0.25)  # damper: every knee, and beyond the last knot (0.2)
    side = rng.randint(3)  # backlash: contact-, gap, contact+
    x[8] = rng.uniform(-g, g) if side == 1 else (side - 1) * (g + rng.uniform(0.0, 0.02))
    x[9] = rng.uniform(-0.3, 0.3)  # axle (secondary frame)
    x[10] = rng.uniform(-0.1, 0.1)  # tyre/hub
    x[11] = rng.uniform(-10.0, 500.0)  # vehicle position
    x[12] = rng.uniform(0.0, 1.0)  # engine lag
    brake = 0.0 if rng.rand() < 0.3 else rng.uniform(0.0, p.brake.capacity_max)
    u = np.array([rng.uniform(0.0, 1.0), rng.uniform(0.0, 0.13), brake])
    return x, u


def _stick(x: np.ndarray, names: dict[str, str], p: DrivetrainParams) -> np.ndarray:
    """Set the relative speed of every stuck element to zero (by hand, in chain order)."""
    x = x.copy()
    st = {n: FRICTION_MODE_NAMES[n][0] for n in FRICTION_MODE_NAMES}
    if names.get("engine") == st["engine"]:
        x[0] = 0.0
    if names.get("clutch") == st["clutch"]:
        x[1] = x[0]
    if names.get("damper_friction") == st["damper_friction"]:
        x[2] = x[1]
    if names.get("brake") == st["brake"]:
        x[4] = 0.0
    if names.get("vehicle") == st["vehicle"]:
        x[6] = 0.0
    if names.get("tyre") == st["tyre"]:
        x[5] = x[6] / p.driveline.R_p
    return x


def _assert_close(got: object, ref: object, rtol: float, atol: float, msg: str) -> None:
    """np.testing.assert_allclose, with a fast path (it is slow) when the check passes."""
    a, b = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    if not np.all(np.abs(a - b) <= atol + rtol * np.abs(b)):
        np.testing.assert_allclose(a, b, rtol=rtol, atol=atol, err_msg=msg)


def _assert_same(d: Drivetrain, x: np.ndarray, u: np.ndarray, names: dict[str, str]) -> Mode:
    """Model.rhs / stuck_torques against the reference at one state and mode (returned)."""
    m = d.model
    mode = m.mode_from_state(x, u, names)
    got = m.rhs(x, u, mode)
    ref = full_reference_rhs(d.params, d.gear, d.slope, x, u, names)
    lam_got = m.stuck_torques(x, u, mode)
    lam_ref = full_reference_stuck_torques(d.params, d.gear, d.slope, x, u, names)
    msg = f"modes {names}, x = {x.tolist()}, u = {u.tolist()}"
    # speeds compared as generalised forces M a, to a tolerance set by the largest force in play
    M = m.data.M
    scale = max(np.max(np.abs(M * ref[SPEEDS])), max(map(abs, lam_ref.values()), default=0.0))
    _assert_close(M * got[SPEEDS], M * ref[SPEEDS], 1e-10, 1e-11 * scale, msg)
    _assert_close(got[7:], ref[7:], 1e-12, 1e-12, msg)
    assert lam_got.keys() == lam_ref.keys(), msg
    for k, val in lam_ref.items():
        _assert_close(lam_got[k], val, 1e-10, 1e-11 * scale, f"{k}: {msg}")
    return mode


# ------------------------------------------------------------------------------------------------
# chain model == reference
# ------------------------------------------------------------------------------------------------

RUNS = [("default", 0), ("default", 1), ("default", 2)] + [
    (c, 10 + i) for i, c in enumerate(CASES) if c != "default"
]


@pytest.mark.parametrize(("case", "seed"), RUNS)
def test_rhs_and_stuck_torques_match_reference(case: str, seed: int) -> None:
    p, d = _case(case)
    m = d.model
    rng = np.random.RandomState(seed)
    regions: dict[str, set[int]] = {t.name: set() for t in m.tables}
    n = 0
    for combo in m.friction_mode_combinations():
        names = {fi.name: fi.mode_names[c] for fi, c in zip(m.frictions, combo, strict=True)}
        x, u = _random_state(rng, d)
        x = _stick(x, names, p)
        mode = _assert_same(d, x, u, names)
        for t, r in zip(m.tables, mode.reg, strict=True):
            regions[t.name].add(r)
        n += 1
    assert n == math.prod(3 if fi.constant_capacity else 4 for fi in m.frictions)
    # the states visited every region of the damper spring, the backlash and the pedal map
    for t in m.tables:
        if t.arg in ("q_damper", "q_backlash", "pedal"):
            assert regions[t.name] == set(range(len(t.bounds) + 1)), t.name


@pytest.mark.parametrize("case", ["default", "all"])
def test_decided_modes_match_reference(case: str) -> None:
    """Consistent states and modes from Model.decide (some relative speeds near zero)."""
    p, d = _case(case)
    m = d.model
    rng = np.random.RandomState(7)
    seen: set[tuple[int, ...]] = set()
    for _ in range(300):
        x, u = _random_state(rng, d)
        want = {n for n in FRICTION_MODE_NAMES if rng.rand() < 0.5}
        x = _stick(x, {n: FRICTION_MODE_NAMES[n][0] for n in want}, p)
        x[:7] += rng.normal(0.0, 1e-12, 7) * (rng.rand(7) < 0.3)
        mode, xp = m.decide(x, u)
        names = {k: v for k, v in m.mode_names(mode).items() if k in FRICTION_MODE_NAMES}
        seen.add(mode.fm)
        _assert_same(d, xp, u, names)
        # the decided stuck elements carry no more than their static capacity (reference torques)
        lam = full_reference_stuck_torques(p, d.gear, d.slope, xp, u, names)
        for k, val in lam.items():
            assert abs(val) <= _static_capacity(p, d.slope, u, k) * (1 + 1e-9) + 1e-9, (k, names)
    assert len(seen) > 20


def _static_capacity(p: DrivetrainParams, slope: float, u: np.ndarray, name: str) -> float:
    """Static capacity of a friction element in the units of its stuck torque."""
    v = p.vehicle
    return {
        "clutch": p.clutch.k12_max * p.clutch.pedal_map(u[1]) * p.clutch.static_ratio,
        "damper_friction": p.damper.k23 * p.damper.static_ratio,
        "tyre": float(v.k_w(slope)) * p.driveline.R_p * v.tyre_static_ratio,
        "engine": p.engine.c1 * p.engine.static_ratio,
        "brake": u[2] * p.brake.static_ratio,
        "vehicle": float(v.k_v(slope)) * v.rolling_static_ratio,
    }[name]


# ------------------------------------------------------------------------------------------------
# the reference on its own: energy balance and constraints
# ------------------------------------------------------------------------------------------------


def _energy_balance(
    p: DrivetrainParams, gear: int, slope: float, x: np.ndarray, u: np.ndarray, names: dict
) -> tuple[float, float, float]:
    """(dE/dt from the reference, power in - power dissipated, scale) written out by hand."""
    xd = full_reference_rhs(p, gear, slope, x, u, names)
    e, c, dm, gb, dl, vh = p.engine, p.clutch, p.damper, p.gearbox, p.driveline, p.vehicle
    tr, Dc, R = gb.tau_r(gear), gb.D_c, dl.R_p
    w1, w2, w3, ws, wh, wt, v = x[:7]
    qd, qb, qa, qt = x[7:11]
    M = [e.J1, c.J2, dm.J3, gb.J4, (1 - dl.tread_fraction) * dl.J5, dl.tread_fraction * dl.J5]
    M.append(vh.M_v)
    g = gb.g34_primary(gear)
    gap = max(abs(qb) - g, 0.0) * np.sign(qb)
    b34 = gb.b34 if gb.backlash_damping == "always" or abs(qb) > g else 0.0
    dE = [M[i] * x[i] * xd[i] for i in range(7)] + [
        dm.spring(qd) * xd[7],
        gb.h34 * gap * xd[8],
        dl.h45 / Dc**2 * qa * xd[9],
        dl.h56 * qt * xd[10],
        vh.M_v * GRAVITY * math.sin(slope) * v,
    ]
    lag = x[12]
    curve = e.full_load_curve
    C_G = (curve(w1) if e.torque_model == "map" and curve is not None else e.K) * lag
    sgn = {"stuck": 0.0, "slip+": 1.0, "slip-": -1.0, "open": 0.0}

    def s(name: str) -> float:
        return sgn[
            ("stuck", "slip+", "slip-", "open")[FRICTION_MODE_NAMES[name].index(names[name])]
        ]

    k12 = c.k12_max * c.pedal_map(u[1]) * c.mu_table(w1 - w2)
    k_v = vh.f_r * vh.M_v * GRAVITY * math.cos(slope)
    k_w = vh.mu_tyre * vh.drive_axle_load_fraction * vh.M_v * GRAVITY * math.cos(slope)
    diss = [
        e.b1 * w1**2,
        c.b2 * w2**2,
        dm.b3 * w3**2,
        gb.b4 * ws**2,
        dl.b5 * wh**2,
        vh.b_v * v**2,
        0.5 * vh.rho_a * vh.C_x * vh.S * abs(v) ** 3,
        b34 * (w3 - tr * ws) ** 2,
        dl.b45 * (ws / Dc - wh) ** 2,
        dl.b56 * (wh - wt) ** 2,
        k12 * s("clutch") * (w1 - w2),
        dm.k23 * s("damper_friction") * (w2 - w3),
        k_w * s("tyre") * (R * wt - v),
        e.c1 * s("engine") * w1,
        u[2] * s("brake") * wh,
        k_v * s("vehicle") * v,
    ]
    scale = sum(map(abs, dE)) + sum(map(abs, diss)) + abs(C_G * w1)
    return sum(dE), C_G * w1 - sum(diss), scale


@pytest.mark.parametrize("case", ["default", "all"])
def test_reference_energy_balance_and_constraints(case: str) -> None:
    """dE/dt = P_in - P_diss, and stuck elements keep their relative speed at zero."""
    p, d = _case(case)
    gear, slope = d.gear, d.slope
    R = p.driveline.R_p
    rng = np.random.RandomState(3)
    for _ in range(400):
        names = {n: FRICTION_MODE_NAMES[n][rng.randint(4)] for n in FRICTION_MODE_NAMES}
        x, u = _random_state(rng, d)
        x = _stick(x, names, p)
        dE, balance, scale = _energy_balance(p, gear, slope, x, u, names)
        assert dE == pytest.approx(balance, rel=0, abs=1e-12 * scale), names
        a = full_reference_rhs(p, gear, slope, x, u, names)[SPEEDS]
        tol = 1e-12 * np.max(np.abs(a))
        rel = {
            "engine": a[0],
            "clutch": a[0] - a[1],
            "damper_friction": a[1] - a[2],
            "brake": a[4],
            "vehicle": a[6],
            "tyre": a[5] - a[6] / R,
        }
        for n, dw in rel.items():
            if names[n] == FRICTION_MODE_NAMES[n][0]:
                assert abs(dw) <= tol, (n, names)


def test_reference_hand_values() -> None:
    """All slipping, no constraint: a few body equations evaluated by hand."""
    p = default_params()
    e, c = p.engine, p.clutch
    names = {
        "clutch": "slip+",
        "damper_friction": "slip-",
        "tyre": "slip+",
        "engine": "turning+",
        "brake": "released",
        "vehicle": "moving+",
    }
    x = np.zeros(13)
    x[0], x[1], x[2], x[6] = 200.0, 100.0, 101.0, 10.0
    x[7] = 0.1  # damper in the second stage: 1.75 + 1500 (0.1 - 0.035)
    x[12] = 0.5
    u = np.array([0.5, 0.07, 0.0])  # k12(0.07) = 62.5 N m
    xd = full_reference_rhs(p, 1, 0.0, x, u, names)
    phi = 1.75 + 1500.0 * (0.1 - 0.035)
    assert xd[0] == pytest.approx((e.K * 0.5 - e.b1 * 200.0 - e.c1 - 62.5) / e.J1, rel=1e-13)
    assert xd[1] == pytest.approx((-c.b2 * 100.0 + 62.5 - phi + p.damper.k23) / c.J2, rel=1e-13)
    k_w = p.vehicle.mu_tyre * p.vehicle.drive_axle_load_fraction * p.vehicle.M_v * GRAVITY
    k_v = p.vehicle.f_r * p.vehicle.M_v * GRAVITY
    drag = 0.5 * 1.2 * 0.3 * 2.0 * 100.0
    assert xd[6] == pytest.approx((k_w - k_v - drag) / p.vehicle.M_v, rel=1e-13)
    assert xd[12] == pytest.approx(0.0)
    assert full_reference_stuck_torques(p, 1, 0.0, x, u, names) == {}


def test_reference_rejects_bad_modes() -> None:
    p = default_params()
    x, u = np.zeros(13), np.zeros(3)
    names = {n: FRICTION_MODE_NAMES[n][0] for n in FRICTION_MODE_NAMES}
    with pytest.raises(ValueError, match="clutch"):
        full_reference_rhs(p, 1, 0.0, x, u, {**names, "clutch": "grip"})
    del names["tyre"]
    with pytest.raises(KeyError, match="tyre"):
        full_reference_rhs(p, 1, 0.0, x, u, names)
