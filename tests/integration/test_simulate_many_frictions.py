"""Mode decisions with many friction elements at zero relative speed at once: they end (with the
consistent combination, or with a clear error beyond ``kernels.DM_MAX_CANDIDATES``), never hang."""

from __future__ import annotations

import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.sim.simulator import simulate


def chain_at_rest(n_bodies: int) -> tuple[Model, dict[str, float]]:
    """Unit bodies coupled by unit-capacity clutches, all at rest, torque inputs +-1000 N m
    alternating: every clutch must slip, coupling i in the direction of (-1)^i (the relative
    acceleration of bodies i and i+1 is about +-2000 rad/s^2)."""
    bodies = tuple(Body(f"b{i}", 1.0, torque_input=f"T{i}") for i in range(n_bodies))
    cps = tuple(
        Coupling(f"c{i}", friction=Friction(scale=1.0, name=f"c{i}")) for i in range(n_bodies - 1)
    )
    m = Model(Chain(bodies, cps, inputs=tuple(f"T{i}" for i in range(n_bodies))))
    return m, {f"T{i}": 1000.0 * (-1) ** i for i in range(n_bodies)}


@pytest.mark.parametrize("n_frictions", [3, 11])
def test_all_candidates_decided_together(n_frictions: int) -> None:
    """11 candidates: 3^11 combinations whose 2^11 stuck sets outnumber the 1024 slots of the
    mode-matrix cache (the search used to restart after each miss and, with evictions, never
    ended); the only consistent one, all slipping, comes last in the search (most stuck first)."""
    m, u = chain_at_rest(n_frictions + 1)
    res = simulate(m, np.zeros(m.nx), u, t_end=1e-3)
    expected = [K.SLIP_POS if i % 2 == 0 else K.SLIP_NEG for i in range(n_frictions)]
    assert res.fm[0].tolist() == expected
    assert res.stats["inconsistent_decisions"] == 0
    mode, _ = m.decide(np.zeros(m.nx), np.array(list(u.values())))
    assert list(mode.fm) == expected


def test_more_candidates_than_the_limit_is_a_clear_error() -> None:
    n = K.DM_MAX_CANDIDATES + 1
    m, u = chain_at_rest(n + 1)
    with pytest.raises(RuntimeError, match=rf"t = 0 s: more than {K.DM_MAX_CANDIDATES} friction"):
        simulate(m, np.zeros(m.nx), u, t_end=1e-3)
    with pytest.raises(ValueError, match=rf"more than {K.DM_MAX_CANDIDATES} friction elements"):
        m.decide(np.zeros(m.nx), np.array(list(u.values())))
    # one element moving: 12 candidates, within the limit
    x0 = np.zeros(m.nx)
    x0[0] = 5.0
    res = simulate(m, x0, u, t_end=1e-3)
    assert res.status == "ok"
