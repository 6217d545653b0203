"""The paper's congruent transformation T (Section II-B, eq. (2)-(4)) and the model against it.

The printed T has ``J2/Delta`` in row 2, column 3; the correct entry is ``J3/Delta`` (see
/work/shared/guides/switching.md). These tests check the corrected T algebraically, show that the
printed one does not invert to the paper's ``z``, and then check a three-inertia chain built
from :mod:`drivetrain_ctrl.chain` against eq. (4) and the stuck-torque formulas derived from it.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction, Spring
from drivetrain_ctrl.plant.model import Model

# -- the paper's matrices ------------------------------------------------------------------------


def t_matrix(j1: float, j2: float, j3: float, *, printed: bool = False) -> np.ndarray:
    """T of Section II-B; ``printed=True`` keeps the misprint J2/Delta in row 2, column 3."""
    d = j1 + j2 + j3
    e23 = j2 / d if printed else j3 / d
    return np.array(
        [
            [1.0, (j2 + j3) / d, j3 / d],
            [1.0, -j1 / d, e23],
            [1.0, -j1 / d, -(j1 + j2) / d],
        ]
    )


def z_paper(j: tuple[float, float, float], w: np.ndarray) -> np.ndarray:
    j1, j2, j3 = j
    return np.array(
        [(j1 * w[0] + j2 * w[1] + j3 * w[2]) / (j1 + j2 + j3), w[0] - w[1], w[1] - w[2]]
    )


def eq4_matrix(j1: float, j2: float, j3: float) -> np.ndarray:
    """The 2x2 matrix of eq. (4) (J_r^{-1})."""
    return np.array([[(j1 + j2) / (j1 * j2), -1.0 / j2], [-1.0 / j2, (j2 + j3) / (j2 * j3)]])


D_MAT = np.array([[1.0, -1.0, 0.0], [0.0, 1.0, -1.0]])

inertia = st.floats(0.005, 2.0)
speed = st.floats(-400.0, 400.0)
inertias = st.tuples(inertia, inertia, inertia)
speeds3 = st.tuples(speed, speed, speed).map(np.array)


@settings(max_examples=200, deadline=None)
@given(j=inertias, w=speeds3)
def test_corrected_t_inverts_to_z(j: tuple[float, float, float], w: np.ndarray) -> None:
    T = t_matrix(*j)
    z = np.linalg.solve(T, w)
    scale = 1.0 + np.max(np.abs(w))
    np.testing.assert_allclose(z, z_paper(j, w), rtol=0, atol=1e-11 * scale)
    # and back: omega = T z
    np.testing.assert_allclose(T @ z_paper(j, w), w, rtol=0, atol=1e-11 * scale)


@settings(max_examples=200, deadline=None)
@given(j=inertias)
def test_corrected_t_block_diagonalises_j(j: tuple[float, float, float]) -> None:
    j1, j2, j3 = j
    T = t_matrix(*j)
    JT = T.T @ np.diag(j) @ T
    s = max(j)
    np.testing.assert_allclose(JT, JT.T, atol=1e-13 * s)
    assert JT[0, 0] == pytest.approx(j1 + j2 + j3, rel=1e-12)
    np.testing.assert_allclose(JT[0, 1:], 0.0, atol=1e-13 * s)
    np.testing.assert_allclose(JT[1:, 0], 0.0, atol=1e-13 * s)
    Jr = JT[1:, 1:]
    np.testing.assert_allclose(np.linalg.inv(Jr), eq4_matrix(*j), rtol=1e-9)
    # D T selects the relative speeds
    np.testing.assert_allclose(D_MAT @ T, [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], atol=1e-14)


@settings(max_examples=100, deadline=None)
@given(j=inertias, w=speeds3)
def test_printed_t_does_not_invert_to_z(j: tuple[float, float, float], w: np.ndarray) -> None:
    j1, j2, j3 = j
    assume(abs(j2 - j3) > 0.05 * max(j2, j3))
    z = z_paper(j, w)
    assume(abs(z[2]) > 1.0)  # the misprint only shows through z3 = omega2 - omega3
    Tp = t_matrix(*j, printed=True)
    # the printed T maps z to the wrong speeds: omega2 is off by (J2 - J3)/Delta * z3
    err = Tp @ z - w
    assert abs(err[1]) > 1e-3 * abs(z[2]) * abs(j2 - j3) / (j1 + j2 + j3)
    assert err[1] == pytest.approx((j2 - j3) / (j1 + j2 + j3) * z[2], rel=1e-6, abs=1e-9)
    assert not np.allclose(np.linalg.solve(Tp, w), z, rtol=1e-6, atol=1e-9)
    # nor does it block-diagonalise J or select the relative speeds
    assert not np.allclose(D_MAT @ Tp, [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], atol=1e-9)


# -- the three-inertia clutch + damper chain -------------------------------------------------------

SPRING = Spring((0.0, 0.035, 0.14, 0.2), (0.0, 1.75, 159.25, 6159.25), 0.0, "phi_e")


def three_inertia(j, b, k12: float, k23: float) -> Model:
    j1, j2, j3 = j
    b1, b2, b3 = b
    chain = Chain(
        bodies=(
            Body("b1", j1, viscous=b1, torque_input="C1"),
            Body("b2", j2, viscous=b2),
            Body("b3", j3, viscous=b3, torque_input="C3", input_gain=-1.0),
        ),
        couplings=(
            Coupling("clutch", friction=Friction(scale=k12, name="clutch")),
            Coupling("damper", spring=SPRING, friction=Friction(scale=k23, name="damper_friction")),
        ),
        inputs=("C1", "C3"),
        name="clutch with torsional damper",
    )
    return Model(chain)


def c_torques(j, b, w: np.ndarray, theta_d: float, c1: float, c3: float) -> np.ndarray:
    """C of eq. (2): C_e - B omega - D^T phi_e(D theta)."""
    phi = SPRING.torque(theta_d)
    ce = np.array([c1, 0.0, -c3])
    return ce - np.asarray(b) * w - D_MAT.T @ np.array([0.0, phi])


case = st.fixed_dictionaries(
    {
        "j": inertias,
        "b": st.tuples(st.floats(0.0, 0.1), st.floats(0.0, 0.1), st.floats(0.0, 0.1)),
        "k12": st.floats(1.0, 300.0),
        "k23": st.floats(1.0, 50.0),
        "w": speeds3,
        "theta": st.floats(-0.25, 0.25),
        "c1": st.floats(-200.0, 200.0),
        "c3": st.floats(-200.0, 200.0),
        "s12": st.sampled_from([1.0, -1.0]),
        "s23": st.sampled_from([1.0, -1.0]),
    }
)

SLIP = {1.0: "slip+", -1.0: "slip-"}


def _state(cs: dict, w: np.ndarray) -> np.ndarray:
    return np.array([w[0], w[1], w[2], cs["theta"]])


def _ct(cs: dict, w: np.ndarray) -> np.ndarray:
    T = t_matrix(*cs["j"])
    return T.T @ c_torques(cs["j"], cs["b"], w, cs["theta"], cs["c1"], cs["c3"])


def _tol(cs: dict, ct: np.ndarray) -> float:
    return 1e-9 * (1.0 + np.max(np.abs(ct)) + cs["k12"] + cs["k23"] + SPRING.torque(0.25))


def test_three_inertia_chain_layout() -> None:
    m = three_inertia((0.2, 0.01, 0.03), (0.0, 0.0, 0.0), 100.0, 10.0)
    assert m.state_names == ("omega_b1", "omega_b2", "omega_b3", "q_damper")
    assert [f.name for f in m.frictions] == ["clutch", "damper_friction"]
    assert m.input_names == ("C1", "C3")


@settings(max_examples=150, deadline=None)
@given(cs=case)
def test_stuck_torques_both_stuck(cs: dict) -> None:
    m = three_inertia(cs["j"], cs["b"], cs["k12"], cs["k23"])
    w = np.full(3, cs["w"][0])
    x = _state(cs, w)
    u = m.inputs(C1=cs["c1"], C3=cs["c3"])
    mode = m.mode_from_state(x, u, {"clutch": "stuck", "damper_friction": "stuck"})
    lam = m.stuck_torques(x, u, mode)
    ct = _ct(cs, w)
    tol = _tol(cs, ct)
    assert set(lam) == {"clutch", "damper_friction"}
    assert lam["clutch"] == pytest.approx(ct[1], abs=tol)
    assert lam["damper_friction"] == pytest.approx(ct[2], abs=tol)
    # the mean speed follows z1' = C_T1 / Delta, the relative speeds stay at zero
    a = m.rhs(x, u, mode)[:3]
    zdot = np.linalg.solve(t_matrix(*cs["j"]), a)
    assert zdot[0] == pytest.approx(ct[0] / sum(cs["j"]), abs=tol / min(cs["j"]))
    np.testing.assert_allclose(zdot[1:], 0.0, atol=tol / min(cs["j"]))


@settings(max_examples=150, deadline=None)
@given(cs=case)
def test_stuck_torque_only_clutch_stuck(cs: dict) -> None:
    j1, j2, j3 = cs["j"]
    m = three_inertia(cs["j"], cs["b"], cs["k12"], cs["k23"])
    s23 = cs["s23"]
    w = np.array([cs["w"][0], cs["w"][0], cs["w"][0] - s23 * (1.0 + abs(cs["w"][1]))])
    x = _state(cs, w)
    u = m.inputs(C1=cs["c1"], C3=cs["c3"])
    mode = m.mode_from_state(x, u, {"clutch": "stuck", "damper_friction": SLIP[s23]})
    lam = m.stuck_torques(x, u, mode)
    ct = _ct(cs, w)
    f12 = ct[1] - j1 / (j1 + j2) * (ct[2] - cs["k23"] * s23)
    assert set(lam) == {"clutch"}
    assert lam["clutch"] == pytest.approx(f12, abs=_tol(cs, ct))


@settings(max_examples=150, deadline=None)
@given(cs=case)
def test_stuck_torque_only_damper_stuck(cs: dict) -> None:
    j1, j2, j3 = cs["j"]
    m = three_inertia(cs["j"], cs["b"], cs["k12"], cs["k23"])
    s12 = cs["s12"]
    w = np.array([cs["w"][1] + s12 * (1.0 + abs(cs["w"][0])), cs["w"][1], cs["w"][1]])
    x = _state(cs, w)
    u = m.inputs(C1=cs["c1"], C3=cs["c3"])
    mode = m.mode_from_state(x, u, {"clutch": SLIP[s12], "damper_friction": "stuck"})
    lam = m.stuck_torques(x, u, mode)
    ct = _ct(cs, w)
    f23 = ct[2] - j3 / (j2 + j3) * (ct[1] - cs["k12"] * s12)
    assert set(lam) == {"damper_friction"}
    assert lam["damper_friction"] == pytest.approx(f23, abs=_tol(cs, ct))


@settings(max_examples=150, deadline=None)
@given(cs=case)
def test_both_slip_relative_accelerations_follow_eq4(cs: dict) -> None:
    j = cs["j"]
    m = three_inertia(j, cs["b"], cs["k12"], cs["k23"])
    s12, s23 = cs["s12"], cs["s23"]
    w0 = cs["w"][0]
    w = np.array([w0, w0 - s12 * 2.0, w0 - s12 * 2.0 - s23 * 3.0])
    x = _state(cs, w)
    u = m.inputs(C1=cs["c1"], C3=cs["c3"])
    mode = m.mode_from_state(x, u, {})
    assert m.mode_names(mode) == {"clutch": SLIP[s12], "damper_friction": SLIP[s23]}
    assert m.stuck_torques(x, u, mode) == {}
    xdot = m.rhs(x, u, mode)
    zdot = np.linalg.solve(t_matrix(*j), xdot[:3])
    ct = _ct(cs, w)
    expected_r = eq4_matrix(*j) @ (ct[1:] - np.array([cs["k12"] * s12, cs["k23"] * s23]))
    tol = _tol(cs, ct) / min(j)
    np.testing.assert_allclose(zdot[1:], expected_r, rtol=1e-9, atol=tol)
    assert zdot[0] == pytest.approx(ct[0] / sum(j), abs=tol)
    # and the damper twist rate is z3
    assert xdot[3] == pytest.approx(w[1] - w[2], abs=1e-12)
