"""``Model.pog_form``: ``L z' = A z + B u + g(z, u)`` with ``x = T z`` reproduces ``Model.rhs``."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction, Spring
from drivetrain_ctrl.plant.drivetrain import full_model, reduced_model
from drivetrain_ctrl.plant.model import Mode, Model
from drivetrain_ctrl.plant.params import default_params


@functools.cache
def drivetrain_model(kind: str) -> Model:
    build = full_model if kind == "full" else reduced_model
    return build(default_params(), gear=1, slope=0.05).model


def paper_chain(j1: float = 0.2, j2: float = 0.01, j3: float = 0.03) -> Model:
    spring = Spring((0.0, 0.035, 0.14, 0.2), (0.0, 1.75, 159.25, 6159.25), 0.0, "phi_e")
    return Model(
        Chain(
            bodies=(
                Body("b1", j1, viscous=0.03, torque_input="C1"),
                Body("b2", j2, viscous=0.01),
                Body("b3", j3, viscous=0.02, torque_input="C3", input_gain=-1.0),
            ),
            couplings=(
                Coupling("clutch", friction=Friction(scale=120.0, name="clutch")),
                Coupling(
                    "damper", spring=spring, friction=Friction(scale=10.0, name="damper_friction")
                ),
            ),
            inputs=("C1", "C3"),
        )
    )


def random_state(m: Model, rng: np.random.Generator) -> np.ndarray:
    x = np.zeros(m.nx)
    for i, b in enumerate(m.chain.bodies):
        x[i] = rng.uniform(-30, 30) if b.kind == "translational" else rng.uniform(-300, 300)
    for c in range(len(m.chain.couplings)):
        if m.data.c_q[c] >= 0:
            x[m.data.c_q[c]] = rng.uniform(-0.4, 0.4)
    for i in range(m.n_bodies):
        if m.data.b_pos[i] >= 0:
            x[m.data.b_pos[i]] = rng.uniform(-50, 50)
    for j in range(m.data.l_x.shape[0]):
        x[m.data.l_x[j]] = rng.uniform(0, 1)
    return x


def mode_with(m: Model, x: np.ndarray, u: np.ndarray, stuck: tuple[bool, ...]):
    """Project x onto the stuck elements; others slip along their relative speed."""
    fm = np.array([K.STUCK if s else K.SLIP_POS for s in stuck], dtype=np.int64)
    x = x.copy()
    K.project(m.data, x, np.array(stuck, dtype=np.int64))
    for f in range(len(stuck)):
        if not stuck[f] and K.rel_speed(m.data, f, x) < 0:
            fm[f] = K.SLIP_NEG
    reg = np.zeros(len(m.tables), dtype=np.int64)
    K.update_regions(m.data, x, u, reg)
    return x, Mode(tuple(int(v) for v in fm), tuple(int(v) for v in reg))


def drivetrain_inputs(m: Model, rng: np.random.Generator) -> np.ndarray:
    return m.inputs(
        throttle=rng.uniform(0, 1), pedal=rng.uniform(0.03, 0.1), brake=rng.uniform(10, 2000)
    )


def constraint_rows(m: Model, mode: Mode) -> np.ndarray:
    fm = np.array(mode.fm, dtype=np.int64)
    return K.constraint_rows(m.data, fm, (fm == K.STUCK).astype(np.int64))


def check_pog(m: Model, x: np.ndarray, u: np.ndarray, mode: Mode) -> None:
    n = m.n_bodies
    pf = m.pog_form(mode, x, u)
    T, L, A, B = pf.T, pf.L, pf.A, pf.B
    n_stuck = sum(1 for c in mode.fm if c == K.STUCK)
    G = constraint_rows(m, mode)
    N = m.speed_basis(mode)
    # speed basis: allowed speeds, orthonormal, n - (number of stuck elements) of them; where
    # stuck elements are redundant (engine held by its friction and, through a stuck clutch, the
    # disc held too) the rank of the constraints counts
    rank = np.linalg.matrix_rank(G) if G.size else 0
    assert N.shape == (n, n - rank)
    if rank == n_stuck:
        assert N.shape[1] == n - n_stuck
    if G.size:
        np.testing.assert_allclose(G @ N, 0.0, atol=1e-12 * np.max(np.abs(G)))
    np.testing.assert_allclose(N.T @ N, np.eye(N.shape[1]), atol=1e-12)
    # T: speed block N, identity on the other states
    k = N.shape[1]
    assert T.shape == (m.nx, k + m.nx - n)
    np.testing.assert_array_equal(T[:n, :k], N)
    np.testing.assert_array_equal(T[n:, k:], np.eye(m.nx - n))
    assert not T[:n, k:].any() and not T[n:, :k].any()
    # L = T^T diag(M, 1) T, symmetric positive definite
    Lfull = np.diag(np.concatenate([m.data.M, np.ones(m.nx - n)]))
    np.testing.assert_allclose(L, T.T @ Lfull @ T, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(L, L.T, rtol=0, atol=1e-12 * np.max(np.abs(L)))
    assert np.all(np.linalg.eigvalsh(L) > 0.0)
    assert A.shape == L.shape and B.shape == (L.shape[0], len(m.input_names))
    # x on the manifold is T z
    z = T.T @ x
    np.testing.assert_allclose(T @ z, x, rtol=1e-10, atol=1e-9)
    # the POG dynamics reproduce rhs
    xdot = m.rhs(x, u, mode)
    zdot = np.linalg.solve(L, A @ z + B @ u + pf.g(z, u))
    scale = np.abs(xdot) + 1e-6 * np.max(np.abs(xdot)) + 1e-9
    assert np.all(np.abs(T @ zdot - xdot) <= 1e-8 * scale + 1e-9 * np.max(np.abs(xdot)))
    np.testing.assert_allclose(
        T.T @ Lfull @ xdot, L @ zdot, rtol=1e-8, atol=1e-9 * np.max(np.abs(Lfull @ xdot))
    )
    # the constraint torques do no work on allowed motion: L z' = T^T [forces; other rates]
    fm, reg = mode.arrays()
    tau = K.forces(m.data, x, u, fm, reg)
    rhs_free = np.concatenate([tau, xdot[n:]])
    np.testing.assert_allclose(
        T.T @ rhs_free, L @ zdot, rtol=1e-8, atol=1e-9 * np.max(np.abs(rhs_free))
    )


def _stuck_sets(nf: int) -> st.SearchStrategy:
    return st.lists(st.booleans(), min_size=nf, max_size=nf).map(tuple)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["full", "reduced"]), data=st.data())
def test_pog_form_reproduces_rhs(kind: str, data) -> None:
    m = drivetrain_model(kind)
    stuck = data.draw(_stuck_sets(len(m.frictions)), label="stuck")
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1), label="seed"))
    u = drivetrain_inputs(m, rng)
    x, mode = mode_with(m, random_state(m, rng), u, stuck)
    check_pog(m, x, u, mode)


@settings(max_examples=40, deadline=None)
@given(stuck=_stuck_sets(2), seed=st.integers(0, 2**32 - 1))
def test_pog_form_paper_chain(stuck: tuple[bool, bool], seed: int) -> None:
    m = paper_chain()
    rng = np.random.default_rng(seed)
    u = rng.uniform(-150, 150, 2)
    x, mode = mode_with(m, random_state(m, rng), u, stuck)
    check_pog(m, x, u, mode)
    # the speed basis spans the columns of the paper's T that keep the stuck z_i at zero
    j1, j2, j3 = m.data.M
    d = j1 + j2 + j3
    Tp = np.array(
        [
            [1.0, (j2 + j3) / d, j3 / d],
            [1.0, -j1 / d, j3 / d],
            [1.0, -j1 / d, -(j1 + j2) / d],
        ]
    )
    keep = [0] + [1 + i for i in range(2) if not stuck[i]]
    N = m.speed_basis(mode)
    cols = Tp[:, keep]
    np.testing.assert_allclose(N @ (N.T @ cols), cols, atol=1e-12)


def test_all_slip_a_is_the_linear_part() -> None:
    """All slipping: A = L * (analytic Jacobian without the quadratic drag), and the remainder g
    is constant in z except for the quadratic drag -T^T (c w|w|)."""
    m = drivetrain_model("full")
    rng = np.random.default_rng(7)
    u = drivetrain_inputs(m, rng)
    stuck = tuple(False for _ in m.frictions)
    x, mode = mode_with(m, random_state(m, rng), u, stuck)
    pf = m.pog_form(mode, x, u)
    n = m.n_bodies
    np.testing.assert_array_equal(pf.T, np.eye(m.nx))
    J, Bu = m.jacobian(x, u, mode)
    Lfull = np.diag(np.concatenate([m.data.M, np.ones(m.nx - n)]))
    drag = np.zeros((m.nx, m.nx))
    drag[np.arange(n), np.arange(n)] = -2.0 * m.data.quad * np.abs(x[:n])
    assert m.data.quad[-1] > 0.0  # the vehicle has aerodynamic drag
    np.testing.assert_allclose(pf.A, Lfull @ J - drag, rtol=1e-12, atol=1e-9)
    # B leaves out the capacity-vs-input terms of the slipping clutch (pedal) and brake
    it = m.input_names.index("throttle")
    np.testing.assert_allclose(pf.B[:, it], (Lfull @ Bu)[:, it], rtol=1e-12, atol=1e-12)
    assert pf.B[m.state_index("lag_engine"), it] == pytest.approx(1.0 / 0.1)
    for name in ("pedal", "brake"):
        j = m.input_names.index(name)
        assert np.all(pf.B[:, j] == 0.0) and np.any(Bu[:, j] != 0.0)

    def remainder(z: np.ndarray) -> np.ndarray:
        w = z[:n]
        return pf.g(z, u) + np.concatenate([m.data.quad * w * np.abs(w), np.zeros(m.nx - n)])

    r0 = remainder(x)
    for _ in range(5):
        # other states in the same mode (slip directions and regions are taken from the mode)
        x2 = x + rng.uniform(-1, 1, m.nx) * np.concatenate(
            [np.full(n, 5.0), np.full(m.nx - n, 0.01)]
        )
        np.testing.assert_allclose(remainder(x2), r0, rtol=1e-9, atol=1e-7)


def test_all_stuck_basis_of_two_body_clutch() -> None:
    """A stuck two-body clutch moves as one body: N = [1, 1]/sqrt(2), L = (J1 + J2)/2."""
    from drivetrain_ctrl.plant.chain import two_body_clutch

    m = Model(two_body_clutch(0.2, 0.05, capacity=100.0))
    mode = Mode((K.STUCK,), ())
    N = m.speed_basis(mode)
    assert N.shape == (2, 1)
    np.testing.assert_allclose(np.abs(N[:, 0]), [2**-0.5, 2**-0.5], rtol=1e-12)
    pf = m.pog_form(mode, np.array([10.0, 10.0]), np.array([30.0]))
    assert pf.L[0, 0] == pytest.approx(0.125, rel=1e-12)
    zdot = np.linalg.solve(pf.L, pf.A @ (pf.T.T @ [10.0, 10.0]) + pf.B @ [30.0])
    np.testing.assert_allclose(pf.T @ zdot, [30.0 / 0.25, 30.0 / 0.25], rtol=1e-12)


@pytest.mark.parametrize(
    ("kind", "stuck_names", "dim"),
    [
        ("full", (), 7),
        ("full", ("clutch",), 6),
        ("full", ("clutch", "damper_friction"), 5),
        ("full", ("tyre", "vehicle"), 5),
        ("full", ("clutch", "damper_friction", "tyre", "engine", "brake", "vehicle"), 1),
        ("reduced", ("clutch",), 2),
        ("reduced", ("clutch", "engine", "brake"), 1),  # redundant: rank 2
        ("reduced", ("clutch", "engine", "brake", "vehicle"), 0),
    ],
)
def test_speed_basis_dimension(kind: str, stuck_names: tuple[str, ...], dim: int) -> None:
    m = drivetrain_model(kind)
    stuck = tuple(f.name in stuck_names for f in m.frictions)
    mode = Mode(tuple(K.STUCK if s else K.SLIP_POS for s in stuck), (0,) * len(m.tables))
    N = m.speed_basis(mode)
    assert N.shape == (m.n_bodies, dim)
    G = constraint_rows(m, mode)
    assert G.shape == (len(stuck_names), m.n_bodies)
    if dim:
        np.testing.assert_allclose(G @ N, 0.0, atol=1e-12)
