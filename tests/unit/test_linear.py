"""Operating points, linearisation, the clutch loop and the judder threshold (linear.py)."""

from __future__ import annotations

import json
import math

import control
import numpy as np
import pytest

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl import linear as L
from drivetrain_ctrl.control import Actuator, actuator_tf, law6_loop_closed_form
from drivetrain_ctrl.control.laws import law6_controller, law6_defaults, pi_controller
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.linear.clutch import _judder_threshold
from drivetrain_ctrl.linear.operating_point import _reduction
from drivetrain_ctrl.plant.drivetrain import full_model, reduced_figures, reduced_model
from drivetrain_ctrl.plant.params import default_params
from drivetrain_ctrl.sim.run import run_scenario

P = default_params()
K_R = law6_defaults()[0]  # law (6)'s gain: the built-in paper controller's
XC = 0.0725  # inside the pedal-map piece [0.07, 0.075] (a knot has two slopes)
W = np.array([0.1, 1.0, 5.0, 37.0, 200.0, 1500.0])


def _slip(kind: str = "reduced", *, omega_driven: float = 80.0, params=P, **kw):
    mk = reduced_model if kind == "reduced" else full_model
    return L.slip_operating_point(
        mk(params), omega_engine=170.0, omega_driven=omega_driven, x_c=XC, throttle=0.5, **kw
    )


def _law6(kind: str = "reduced", params=P):
    driven = "omega_primary" if kind == "reduced" else "omega_disc"
    return law6_controller(params, reference=sg.constant(170.0), driven_state=driven)


def _resp(sys, w):
    return np.array([complex(sys(1j * x)) for x in w])


def _pedal_slope(params, x_c: float) -> float:
    pm = params.clutch.pedal_map
    k12 = [params.clutch.k12_max * y for y in pm.y]  # capacity [N m] at the knots
    k = int(np.searchsorted(pm.x, x_c)) - 1
    return (k12[k + 1] - k12[k]) / (pm.x[k + 1] - pm.x[k])


# -- operating points -------------------------------------------------------------------------


def test_slip_point_certificate_time_to_lock():
    op = _slip()
    c = op.certificate
    assert op.clutch_mode == "slip+" and c.kind == "slip"
    assert c.slip_speed == pytest.approx(90.0)
    assert c.slip_accel < 0
    assert c.time_to_lock_s == pytest.approx(90.0 / -c.slip_accel, rel=1e-12)
    assert c.valid and c.drift_norm > 1.0  # not an equilibrium


def test_slip_point_diverging_has_no_time_to_lock():
    # nearly open clutch, full throttle: the engine runs away from the driveline
    op = L.slip_operating_point(
        reduced_model(P), omega_engine=170.0, omega_driven=80.0, x_c=0.105, throttle=1.0
    )
    assert op.certificate.time_to_lock_s is None
    assert any("not closing" in n for n in op.certificate.notes)


def test_slip_point_bad_inputs():
    dt = reduced_model(P)
    with pytest.raises(ValueError, match="no slip"):
        L.slip_operating_point(dt, omega_engine=100.0, omega_driven=100.0, x_c=XC, throttle=0.5)
    with pytest.raises(ValueError, match="throttle = 1.5"):
        L.slip_operating_point(dt, omega_engine=150.0, omega_driven=100.0, x_c=XC, throttle=1.5)
    with pytest.raises(ValueError, match="x_c = 0.2"):
        L.slip_operating_point(dt, omega_engine=150.0, omega_driven=100.0, x_c=0.2, throttle=0.5)


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_locked_trim_is_equilibrium_and_clutch_carries_engine_torque(kind):
    dt = (reduced_model if kind == "reduced" else full_model)(P)
    op = L.locked_trim(dt, vehicle_speed_kmh=30.0, slope=0.03)
    c = op.certificate
    assert op.clutch_mode == "stuck" and c.valid and c.kind == "equilibrium"
    assert c.drift_norm < 1e-8
    assert 0.0 < op.input("throttle") < 1.0
    margins = {s.element: s for s in c.stuck_margins}
    cl = margins["clutch"]
    assert cl.capacity == pytest.approx(P.clutch.k12_max)
    assert cl.margin == pytest.approx(cl.capacity - abs(cl.torque))
    # paper, Sec. IV: with the clutch engaged (and no acceleration) tau_13 = C_1
    sysl = L.linearise(op)
    assert sysl.nstates > 0
    e = P.engine
    w1 = op.state("omega_engine")
    C1 = e.K * op.state("lag_engine") - e.b1 * w1 - e.c1
    assert cl.torque == pytest.approx(C1, rel=1e-9)


def test_locked_trim_errors():
    dt = reduced_model(P)
    with pytest.raises(ValueError, match=r"throttle needed is .* outside \[0, 1\]"):
        L.locked_trim(dt, vehicle_speed_kmh=60.0, slope=0.3)
    with pytest.raises(ValueError, match="vehicle_speed_kmh = 0"):
        L.locked_trim(dt, vehicle_speed_kmh=0.0)


def test_operating_point_from_result_holds_mode():
    from drivetrain_ctrl.scenarios.scenario import builtin_scenarios

    sc = builtin_scenarios()["engage-ramp"]
    dt = sc.drivetrain(P, kind="reduced")
    res = run_scenario(sc, dt, t_end=1.2)
    op = L.operating_point_from_result(res, 1.0, drivetrain=dt)
    k = int(np.searchsorted(res.t, 1.0, side="right") - 1)
    assert op.mode.fm == tuple(int(v) for v in res.fm[k])
    assert op.clutch_mode == "slip+" and op.t == 1.0
    json.dumps(op.to_dict())
    with pytest.raises(ValueError, match="t = 5.0"):
        L.operating_point_from_result(res, 5.0)


# -- linearisation ----------------------------------------------------------------------------


def _fd_jacobian(m, x, u, mode, h=1e-6):
    nx, nu = m.nx, len(u)
    A = np.zeros((nx, nx))
    B = np.zeros((nx, nu))
    for j in range(nx):
        e = np.zeros(nx)
        e[j] = h * max(1.0, abs(x[j]))
        A[:, j] = (m.rhs(x + e, u, mode) - m.rhs(x - e, u, mode)) / (2 * e[j])
    for j in range(nu):
        e = np.zeros(nu)
        e[j] = 1e-7
        B[:, j] = (m.rhs(x, u + e, mode) - m.rhs(x, u - e, mode)) / (2 * e[j])
    return A, B


def _clutch_torque(m, x, u, mode):
    fm, reg = mode.arrays()
    _, Lam = K.mode_matrices(m.data, fm)
    return K.coupling_torques(m.data, x, u, fm, reg, Lam)[0]


def _ops():
    red, full = reduced_model(P), full_model(P)
    return {
        "reduced slip+": _slip(),
        "reduced slip-": _slip(omega_driven=250.0),
        "reduced locked": L.locked_trim(red, vehicle_speed_kmh=25.0),
        "full slip+": _slip("full"),
        "full locked": L.locked_trim(full, vehicle_speed_kmh=25.0),
    }


@pytest.mark.parametrize("name", list(_ops()))
def test_analytic_jacobian_matches_finite_differences_inside_the_mode(name):
    op = _ops()[name]
    m, x, u, mode = op.model, np.array(op.x), np.array(op.u), op.mode
    parts = L.linearisation_parts(op)
    A_fd, B_fd = _fd_jacobian(m, x, u, mode)
    scale = np.max(np.abs(A_fd)) + 1.0
    assert np.max(np.abs(parts.A - A_fd)) < 1e-6 * scale
    assert np.max(np.abs(parts.B - B_fd)) < 1e-5 * (np.max(np.abs(B_fd)) + 1.0)
    # clutch torque tau_13 (kinetic in slip, constraint torque when stuck)
    h = 1e-6
    g_fd = np.array(
        [
            (
                _clutch_torque(m, x + h * np.eye(m.nx)[j], u, mode)
                - _clutch_torque(m, x - h * np.eye(m.nx)[j], u, mode)
            )
            / (2 * h)
            for j in range(m.nx)
        ]
    )
    assert np.max(np.abs(parts.clutch_dx - g_fd)) < 1e-5 * (np.max(np.abs(g_fd)) + 1.0)
    # the reduced system in the mode's own coordinates
    sysr = L.linearise(op)
    red = _reduction(m, mode, keep_positions=False)
    Az = np.zeros((sysr.nstates, sysr.nstates))
    for j in range(sysr.nstates):
        dz = red.T[:, j] * 1e-6
        Az[:, j] = red.S @ (m.rhs(x + dz, u, mode) - m.rhs(x - dz, u, mode)) / 2e-6
    assert np.max(np.abs(sysr.A - Az)) < 1e-5 * (np.max(np.abs(Az)) + 1.0)


def test_reduction_removes_constraint_directions():
    op = L.locked_trim(full_model(P), vehicle_speed_kmh=25.0)
    full = L.linearise(op, reduce=False, keep_positions=True)
    red = L.linearise(op)
    n_zero_full = int(np.sum(np.abs(np.linalg.eigvals(full.A)) < 1e-3))
    n_zero_red = int(np.sum(np.abs(np.linalg.eigvals(red.A)) < 1e-3))
    # clutch + damper friction + tyre constraints, frozen damper twist, vehicle position
    assert n_zero_full == 5
    assert n_zero_red == 0
    assert "omega_engine" in red.state_labels and "omega_disc" not in red.state_labels
    assert "q_damper" not in red.state_labels and "pos_vehicle" not in red.state_labels
    assert list(red.input_labels) == ["throttle", "x_c"]
    assert {"tau_13", "C_1", "a_vehicle", "v_vehicle"} <= set(red.output_labels)


def test_mu_slope_override_equals_a_falling_mu_table():
    slope = -0.002  # mu ratio per rad/s
    p2 = P.replace(**{"clutch.mu_table": {"x": [0.0, 200.0], "y": [1.0, 1.0 + 200.0 * slope]}})
    op_tab = _slip(params=p2)
    op_flat = _slip()
    a = L.linearisation_parts(op_tab)
    b = L.linearisation_parts(op_flat, mu_slope=slope)
    assert a.mu_slope_torque == pytest.approx(b.mu_slope_torque, rel=1e-12)
    assert np.allclose(a.A, b.A, rtol=1e-12, atol=1e-12)
    assert a.mu == pytest.approx(1.0 + 90.0 * slope)


def test_linearise_bad_arguments():
    op = _slip()
    with pytest.raises(ValueError, match="'pedal'"):
        L.linearise(op, inputs=("pedal",))
    with pytest.raises(ValueError, match="'torque'"):
        L.linearise(op, outputs=("torque",))


# -- the clutch loop ---------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["reduced", "full"])
def test_law6_loop_equals_closed_form(kind):
    op = _slip(kind)
    loop = L.clutch_loop(op, _law6(kind))
    act = P.actuator
    closed = law6_loop_closed_form(
        k_r=K_R,
        dk13_dxc=_pedal_slope(P, XC),
        mu=1.0,
        J1=P.engine.J1,
        b1_eff=P.engine.b1,  # linear engine map: C_G does not depend on omega_1
        actuator=Actuator(act.omega_a, act.delta_a),
    )
    assert np.allclose(_resp(loop.L, W), _resp(closed, W), rtol=1e-8, atol=0)
    # the pieces
    assert loop.engine.dk13_dxc == pytest.approx(_pedal_slope(P, XC))
    assert np.allclose(_resp(loop.tau13_to_omega1, W), -1 / (P.engine.J1 * 1j * W + P.engine.b1))


def test_loop_is_the_same_on_both_sign_branches():
    c = _law6()
    up = L.clutch_loop(_slip(omega_driven=80.0), c)
    down = L.clutch_loop(_slip(omega_driven=250.0), c)
    assert up.engine.sign == 1 and down.engine.sign == -1
    assert np.allclose(_resp(up.L, W), _resp(down.L, W), rtol=1e-10)
    assert np.allclose(_resp(up.S, W), _resp(down.S, W), rtol=1e-8)


def test_b1_eff_includes_engine_map_slope():
    p2 = P.replace(**{"engine.torque_model": "map"})
    op = _slip(params=p2)
    es = L.engine_side(op)
    flc = p2.engine.full_load_curve
    k = int(np.searchsorted(flc.x, 170.0)) - 1
    dC = (flc.y[k + 1] - flc.y[k]) / (flc.x[k + 1] - flc.x[k])
    assert es.b1_eff == pytest.approx(p2.engine.b1 - 0.5 * dC, rel=1e-12)
    assert es.torque_per_throttle == pytest.approx(float(flc(170.0)))


def test_clutch_loop_rejects_locked_point():
    op = L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0)
    with pytest.raises(ValueError, match="'stuck'"):
        L.clutch_loop(op, _law6())


def test_pi_and_sampled_loops():
    op = _slip()
    c = pi_controller(
        P, reference=sg.constant(170.0), kp=3e-4, ki=1e-3, driven_state="omega_primary"
    )
    lc = L.clutch_loop(op, c)
    assert not lc.discrete
    # C(s) = kp + ki/s in front of the law-6 plant
    p6 = L.clutch_loop(op, _law6()).L / K_R
    s = 1j * W
    assert np.allclose(_resp(lc.L, W), (3e-4 + 1e-3 / s) * _resp(p6, W), rtol=1e-7)
    cd = pi_controller(
        P,
        reference=sg.constant(170.0),
        kp=3e-4,
        ki=1e-3,
        dt=0.01,
        delay_samples=1,
        driven_state="omega_primary",
    )
    ld = L.clutch_loop(op, cd)
    assert ld.discrete and ld.dt == 0.01 and ld.L.dt == 0.01


# -- locked: shuffle ---------------------------------------------------------------------------


def _two_mass_hz(params, op):
    fig = reduced_figures(params, 1)
    me = params.vehicle.M_v * (params.driveline.R_p / fig.tau_t) ** 2
    Je = params.engine.J1 + fig.J25
    return math.sqrt(fig.h_t * (1 / Je + 1 / me)) / (2 * math.pi)


def test_locked_shuffle_equals_two_mass_formula_without_ground_damping():
    p0 = P.replace(
        **{
            "engine.b1": 0.0,
            "clutch.b2": 0.0,
            "damper.b3": 0.0,
            "gearbox.b4": 0.0,
            "vehicle.C_x": 0.0,
        }
    )
    op = L.locked_trim(reduced_model(p0), vehicle_speed_kmh=25.0)
    la = L.locked_analysis(op)
    assert len(la.shuffle_modes) == 1
    assert la.shuffle_modes[0].natural_frequency_hz == pytest.approx(_two_mass_hz(p0, op), rel=1e-9)
    # one physical zero eigenvalue (free rigid-body motion, no ground damping), no spurious one
    assert sum(abs(p) < 1e-9 for p in la.poles) == 1


def test_locked_shuffle_default_params_close_to_two_mass_formula():
    op = L.locked_trim(reduced_model(P), vehicle_speed_kmh=25.0)
    la = L.locked_analysis(op)
    sh = la.shuffle_modes[0]
    assert sh.natural_frequency_hz == pytest.approx(_two_mass_hz(P, op), rel=0.01)
    assert 0.0 < sh.damping < 0.2
    d = la.to_dict()
    assert d["margins"] is None and "open" in d["margins_reason"]
    json.dumps(d)
    assert la.breakaway_margins[0].element == "clutch"
    # theta -> vehicle acceleration: DC gain 0 (a step settles at a new speed), non-zero at 1 Hz
    assert abs(complex(la.theta_to_accel(2j * math.pi))) > 0.1


# -- judder ------------------------------------------------------------------------------------


def _max_real(op, ctrl, c):
    k13 = L.engine_side(op).k13
    return float(np.max(L.slip_mode_poles(op, ctrl, mu_slope=c / k13).real))


def test_judder_law6_shuffle_crossing_at_predicted_slope():
    op = _slip()
    ctrl = _law6()
    jt = L.judder_threshold(op, ctrl)
    assert jt.which == "shuffle" and jt.c_crit < 0
    assert _max_real(op, ctrl, 0.99 * jt.c_crit) < 0
    assert _max_real(op, ctrl, 1.01 * jt.c_crit) > 0
    assert 5.0 < jt.shuffle_frequency_hz < 7.0
    # the first-order form: b_p + c + b_t (1 + J25/m_e)^2 + b_e (J25/m_e)^2 = 0
    r = jt.J25 / jt.m_e
    approx = -jt.b_p - jt.b_t * (1 + r) ** 2 - jt.b_e * r**2
    assert jt.c_shuffle_speed_source == pytest.approx(approx, rel=1e-3)


def test_judder_pedal_held_dc_crossing_is_exact():
    op = _slip()
    jt = L.judder_threshold(op, None)
    assert jt.which == "dc"
    b1, bd = P.engine.b1, jt.b_p + jt.b_e
    assert jt.c_crit == pytest.approx(-b1 * bd / (b1 + bd), rel=1e-12)
    assert _max_real(op, None, 0.999 * jt.c_crit) < 0
    assert _max_real(op, None, 1.001 * jt.c_crit) > 0


def _shuffle_max_real(op, ctrl, c):
    k13 = L.engine_side(op).k13
    poles = L.slip_mode_poles(op, ctrl, mu_slope=c / k13)
    return float(np.max(poles[np.abs(poles.imag) > 2 * math.pi].real))


def test_judder_speed_source_limit_heavy_engine():
    # a heavy engine is a speed source: the engine correction vanishes and the Routh-Hurwitz
    # boundary of the driveline is exact for the shuffle pair (a slow engine-vehicle crossing,
    # not covered by the closed form, comes earlier for such an engine: see judder_threshold)
    p2 = P.replace(**{"engine.J1": 50.0})
    op = _slip(params=p2)
    ctrl = _law6(params=p2)
    jt = L.judder_threshold(op, ctrl)
    assert jt.c_shuffle == pytest.approx(jt.c_shuffle_speed_source, rel=2e-3)
    assert _shuffle_max_real(op, ctrl, 0.995 * jt.c_shuffle) < 0
    assert _shuffle_max_real(op, ctrl, 1.005 * jt.c_shuffle) > 0


def test_falling_mu_table_destabilises_slip_mode():
    # a mu table with a falling piece around the operating slip (90 rad/s), level about 1 there
    def point(slope):
        p2 = P.replace(
            **{"clutch.mu_table": {"x": [0.0, 89.0, 91.0], "y": [1.0, 1.0, 1.0 + 2.0 * slope]}}
        )
        return _slip(params=p2), _law6(params=p2)

    op0, c0 = point(-1e-4)
    jt = L.judder_threshold(op0, c0)
    for fac, stable in ((0.97, True), (1.03, False)):
        op, c = point(fac * jt.mu_slope_crit)
        assert L.linearisation_parts(op).mu_slope_torque == pytest.approx(
            fac * jt.mu_slope_crit * L.engine_side(op).k13
        )
        poles = L.slip_mode_poles(op, c)
        assert bool(np.max(poles.real) < 0) == stable


def test_judder_needs_reduced_model():
    with pytest.raises(ValueError, match="reduced model"):
        L.judder_threshold(_slip("full"))


def test_no_matplotlib_import_at_module_level():
    # python-control itself imports matplotlib; our modules must not add a module-level import
    import ast
    import inspect

    from drivetrain_ctrl.linear import margins as analysis

    for mod in (L, analysis):
        tree = ast.parse(inspect.getsource(mod))
        for node in tree.body:
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] + [getattr(node, "module", "") or ""]
                assert not any("matplotlib" in n for n in names), mod.__name__


def test_every_visited_mode_is_linearised_inside_its_interval() -> None:
    from drivetrain_ctrl.linear.linearisation import linearise_visited_modes
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    sc = load_scenario("paper-start")
    for kind in ("reduced", "full"):
        dtr = sc.drivetrain(default_params(), kind=kind)
        res = run_scenario(sc, dtr, controller="paper")
        vm = linearise_visited_modes(res, drivetrain=dtr)
        labels = [v.label for v in vm]
        assert len(labels) == len(set(labels)) >= 3
        assert any("clutch=slip+" in lb for lb in labels)
        assert any("clutch=stuck" in lb for lb in labels)
        for v in vm:
            assert np.all(np.isfinite(np.asarray(v.sys.A)))
            # the operating point is strictly inside an interval of that mode
            assert v.op.t is not None and res.t[0] < v.op.t < res.t[-1]
        locked = [v for v in vm if "clutch=stuck" in v.label and "backlash=contact+" in v.label]
        assert locked and locked[0].natural_frequencies_hz[0] == pytest.approx(3.1, abs=0.2)


# -- review: reuse and bad input ---------------------------------------------------------------


@pytest.mark.parametrize("mu_slope", [None, -2e-3])
def test_clutch_loop_pieces_are_the_public_transfer_functions(mu_slope):
    """clutch_loop builds x_c -> tau_13, tau_13 -> omega_1 and theta -> omega_1 with the public
    functions (from its EngineSide); the mu-slope override does not change them."""
    op = _slip()
    loop = L.clutch_loop(op, _law6(), mu_slope=mu_slope)
    for got, ref in (
        (loop.x_c_to_tau13, L.pedal_to_clutch_torque(op)),
        (loop.tau13_to_omega1, L.clutch_torque_to_engine_speed(op)),
        (loop.theta_to_omega1, L.throttle_to_engine_speed(op)),
    ):
        assert np.array_equal(got.num[0][0], ref.num[0][0])
        assert np.array_equal(got.den[0][0], ref.den[0][0])
    assert list(loop.x_c_to_tau13.input_labels) == ["x_c"]
    assert list(loop.tau13_to_omega1.output_labels) == ["omega_engine"]


def test_judder_threshold_from_a_built_loop_is_the_same():
    """The report computes the threshold from the clutch loop it already built (its engine side
    and constant-mu L): the same result as the public function, which builds the loop itself."""
    op, ctrl = _slip(), _law6()
    loop = L.clutch_loop(op, ctrl)
    assert _judder_threshold(loop.op, loop.engine, loop.L) == L.judder_threshold(op, ctrl)
    assert _judder_threshold(op, L.engine_side(op), None) == L.judder_threshold(op, None)
    # a loop with a friction slope is another loop: another threshold
    lf = L.clutch_loop(op, ctrl, mu_slope=-1e-3)
    assert _judder_threshold(op, lf.engine, lf.L) != L.judder_threshold(op, ctrl)


def test_linearise_rejects_a_bare_string():
    op = _slip()
    with pytest.raises(ValueError, match=r"outputs = 'tau_13': a sequence of names"):
        L.linearise(op, outputs="tau_13")
    with pytest.raises(ValueError, match=r"inputs = 'x_c': a sequence of names"):
        L.linearise(op, inputs="x_c")
    assert L.linearise(op, outputs=["tau_13"]).noutputs == 1


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("J", 0.0, "J = 0.0: must be > 0"),
        ("m", -1.0, "m = -1.0: must be > 0"),
        ("h", float("nan"), "h = nan: must be a finite number"),
        ("b", -0.1, "b = -0.1: a damping"),
        ("e", float("inf"), "e = inf: must be a finite number"),
        ("J", "0.1", "J = '0.1': must be a finite number"),
    ],
)
def test_shuffle_speed_source_threshold_bad_fields(field, value, match):
    kw = {"J": 0.1, "m": 10.0, "h": 500.0, "b": 1.0, "e": 0.5}
    L.shuffle_speed_source_threshold(**kw)
    kw[field] = value
    with pytest.raises(ValueError, match=match):
        L.shuffle_speed_source_threshold(**kw)


def test_shuffle_speed_source_threshold_needs_some_damping():
    with pytest.raises(ValueError, match=r"b \+ e must be > 0"):
        L.shuffle_speed_source_threshold(J=0.1, m=10.0, h=500.0, b=0.0, e=0.0)
    d, w = L.shuffle_speed_source_threshold(J=0.1, m=10.0, h=500.0, b=1.0, e=0.0)
    assert math.isfinite(d) and w > 0


@pytest.mark.parametrize("bad", ["x", None, float("nan"), True])
def test_linearise_visited_modes_rejects_a_non_number(bad):
    import types

    res = types.SimpleNamespace(t=np.array([0.0, 1.0]))
    with pytest.raises(ValueError, match="min_duration = "):
        L.linearise_visited_modes(res, min_duration=bad)
    with pytest.raises(ValueError, match="min_duration = -1.0"):
        L.linearise_visited_modes(res, min_duration=-1.0)


def test_actuator_none_is_a_type_error():
    with pytest.raises(TypeError, match="actuator: an Actuator is needed, got NoneType"):
        actuator_tf(None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="actuator: an Actuator is needed, got NoneType"):
        law6_loop_closed_form(k_r=1e-3, dk13_dxc=-3000.0, mu=1.0, J1=0.2, b1_eff=0.1, actuator=None)  # type: ignore[arg-type]


def test_rebuild_operating_point_needs_params():
    op = _slip()
    with pytest.raises(TypeError, match="params: a DrivetrainParams is needed, got dict"):
        L.rebuild_operating_point(op, {"engine.J1": 0.3})
    assert L.rebuild_operating_point(op, P).state("omega_engine") == op.state("omega_engine")


def test_operating_points_reject_negative_brake_and_pedal_outside_the_map():
    dt = reduced_model(P)
    lo, hi = P.clutch.pedal_map.x[0], P.clutch.pedal_map.x[-1]
    kw = {"omega_engine": 150.0, "omega_driven": 100.0, "throttle": 0.5}
    with pytest.raises(ValueError, match="brake = -1.0"):
        L.slip_operating_point(dt, x_c=XC, brake=-1.0, **kw)
    with pytest.raises(ValueError, match="brake = -1.0"):
        L.locked_trim(dt, vehicle_speed_kmh=25.0, brake=-1.0)
    for xc in (lo - 1e-3, hi + 1e-3, -0.5):
        with pytest.raises(ValueError, match=rf"x_c = {xc!r} m: outside the pedal map's range"):
            L.slip_operating_point(dt, x_c=xc, **kw)
        with pytest.raises(ValueError, match=rf"x_c = {xc!r} m: outside the pedal map's range"):
            L.locked_trim(dt, vehicle_speed_kmh=25.0, x_c=xc)
    # the ends of the map are inside
    assert L.locked_trim(dt, vehicle_speed_kmh=25.0, x_c=lo).clutch_mode == "stuck"


def test_natural_frequency_damping_and_oscillatory_poles() -> None:
    from drivetrain_ctrl.linear.linearisation import natural_frequency_damping, oscillatory_poles

    wn, zeta = 2 * math.pi * 50.0, 0.1
    p = complex(-zeta * wn, wn * math.sqrt(1 - zeta**2))
    f, z = natural_frequency_damping(p)
    assert f == pytest.approx(50.0) and z == pytest.approx(0.1)
    assert natural_frequency_damping(0j) == (0.0, 1.0)
    assert natural_frequency_damping(complex(3.0, 4.0))[1] == pytest.approx(-0.6)  # unstable
    # one of each pair, sorted by |p|; real poles and round-off imaginary parts are not modes
    poles = [p, p.conjugate(), -1.0, complex(-3.0, 1.0), complex(-5000.0, 1e-8)]
    assert oscillatory_poles(np.array(poles)) == [complex(-3.0, 1.0), p]


@pytest.mark.parametrize("sampled", [False, True])
def test_gang_of_four_is_consistent(sampled):
    """S + T = 1, PS = P S, CS = C S, L = C P, on the continuous and the sampled PI loop."""
    dt = 0.01 if sampled else None
    c = pi_controller(
        P, reference=sg.constant(170.0), kp=3e-4, ki=1e-3, dt=dt, driven_state="omega_primary"
    )
    lp = L.clutch_loop(_slip(), c)
    w = np.logspace(-1, np.log10(0.9 * np.pi / dt), 30) if sampled else W

    def f(sys):
        return np.asarray(control.frequency_response(sys, w).complex).ravel()

    Pw, Cw, Lw, Sw = f(lp.plant), f(lp.controller), f(lp.L), f(lp.S)
    # the sampled loop's transfer function L has the integrator's pole z = 1 moved by round-off
    # (to 0.99999958: the conversion to a transfer function, minreal): at 0.1 rad/s, where
    # |z - 1| = 1e-3, that is a relative difference of about 1e-4, falling with w
    rtol = 1e-3 if sampled else 1e-6
    assert np.allclose(Lw, Cw * Pw, rtol=rtol)
    assert np.allclose(Sw, 1 / (1 + Lw), rtol=1e-6)
    assert np.allclose(Sw + f(lp.T), 1.0, rtol=0, atol=1e-8)
    assert np.allclose(f(lp.PS), Pw * Sw, rtol=rtol)
    assert np.allclose(f(lp.CS), Cw * Sw, rtol=rtol)


@pytest.mark.parametrize(
    ("field", "value", "msg"),
    [("k_r", 0.0, "k_r = 0.0: must be > 0"), ("J1", -0.2, "J1 = -0.2: must be > 0"),
     ("mu", float("nan"), "mu = nan")],
)  # fmt: skip
def test_law6_closed_form_names_a_bad_argument(field, value, msg):
    kw = dict(k_r=1e-3, dk13_dxc=-3000.0, mu=1.0, J1=0.2, b1_eff=0.1,
              actuator=Actuator(P.actuator.omega_a, P.actuator.delta_a))  # fmt: skip
    with pytest.raises(ValueError, match=msg):
        law6_loop_closed_form(**{**kw, field: value})


# ------------------------------------------------------------------------------------------------
# bad arguments
# ------------------------------------------------------------------------------------------------


def test_wrong_op_and_controller_types_are_named() -> None:
    from drivetrain_ctrl.linear import margins as A

    op = _slip()
    for fn in (L.clutch_loop, A.clutch_loop_margins):
        with pytest.raises(
            TypeError, match=r"controller = 'paper': must be a closedloop.Controller"
        ):
            fn(op, "paper")  # type: ignore[operator]
    for fn in (L.slip_mode_poles, L.judder_threshold):
        with pytest.raises(TypeError, match=r"controller = 'paper': .*or None"):
            fn(op, "paper")  # type: ignore[operator]
    with pytest.raises(TypeError, match=r"root_locus: controller = 'paper'"):
        A.root_locus(op, "paper", parameter="k_r", values=[1e-3])  # type: ignore[arg-type]
    for fn in (L.linearise, L.slip_mode_poles, L.engine_side):
        with pytest.raises(TypeError, match=r"op = None: must be an OperatingPoint"):
            fn(None)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kw", "exc", "match"),
    [
        ({"reduce": "no"}, TypeError, "reduce = 'no': must be True or False"),
        ({"keep_positions": 1}, TypeError, "keep_positions = 1"),
        ({"inputs": 5}, TypeError, "inputs = 5: must be a non-empty sequence"),
        ({"inputs": ()}, TypeError, r"inputs = \(\)"),
        ({"inputs": ("x_c", "x_c")}, ValueError, "must not repeat"),
        ({"outputs": ("tau_13", "tau_13")}, ValueError, "must not repeat"),
    ],
)
def test_linearise_checks_its_options(kw: dict[str, object], exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        L.linearise(_slip(), **kw)  # type: ignore[arg-type]


def test_locked_trim_that_goes_non_finite_is_an_error() -> None:
    from drivetrain_ctrl.plant.drivetrain import Drivetrain

    for kind in ("full", "reduced"):
        with pytest.raises(ValueError, match=r"vehicle_speed_kmh = 1e\+300: no locked steady"):
            L.locked_trim(Drivetrain(P, kind=kind), vehicle_speed_kmh=1e300)


def test_operating_point_from_result_rejects_another_drivetrain() -> None:
    from drivetrain_ctrl.plant.drivetrain import Drivetrain
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    sc = load_scenario("engage-ramp")
    dt = Drivetrain(P, kind="reduced")
    res = run_scenario(sc, dt, t_end=0.5)
    assert L.operating_point_from_result(res, 0.3, drivetrain=dt).kind == "reduced"
    for other in (Drivetrain(P, kind="full"), Drivetrain(P, kind="reduced", gear=2)):
        with pytest.raises(ValueError, match=r"not the drivetrain of the result"):
            L.operating_point_from_result(res, 0.3, drivetrain=other)
    with pytest.raises(ValueError, match=r"t = 9.0 s: outside the trajectory \[0.0, 0.5\] s"):
        L.operating_point_from_result(res, 9.0)


def test_slip_operating_point_checks_the_physical_ranges() -> None:
    with pytest.raises(ValueError, match=r"omega_engine = -100.0 rad/s: must be >= 0"):
        L.slip_operating_point(
            reduced_model(P), omega_engine=-100.0, omega_driven=80.0, x_c=XC, throttle=0.5
        )
    with pytest.raises(
        ValueError,
        match=r"brake = 1000000000.0 \[N m\]: must lie in \[0, brake.capacity_max = 3000.0\]",
    ):
        _slip(brake=1e9)
    with pytest.raises(TypeError, match="drivetrain = 'reduced': must be a Drivetrain"):
        L.slip_operating_point(
            "reduced",
            omega_engine=170.0,
            omega_driven=80.0,
            x_c=XC,
            throttle=0.5,  # type: ignore[arg-type]
        )


# -- the judder threshold on any model (issue 19, item 6) --------------------------------------


def _straddles(op, ctrl, jc) -> None:
    """The poles at the two ends of the final bracket lie on either side of the boundary."""
    lo = L.slip_mode_poles(op, ctrl, mu_slope=jc.stable_side)
    hi = L.slip_mode_poles(op, ctrl, mu_slope=jc.unstable_side)
    assert np.max(lo.real) < 0 <= np.max(hi.real) + 1e-9 * np.max(np.abs(hi))
    assert jc.stable_side == pytest.approx(jc.mu_slope_crit + jc.tolerance, rel=1e-12)
    assert jc.unstable_side == pytest.approx(jc.mu_slope_crit - jc.tolerance, rel=1e-12)
    assert jc.tolerance <= 1.01 * L.clutch.JUDDER_RTOL * abs(jc.mu_slope_crit)


def test_judder_crossing_agrees_with_the_closed_form_on_the_reduced_model():
    op = _slip()
    # pedal held: the closed form's DC crossing is exact
    jc, jt = L.judder_crossing(op, None), L.judder_threshold(op, None)
    assert jt.which == "dc" and jc.frequency_hz == 0.0
    assert jc.mu_slope_crit == pytest.approx(jt.mu_slope_crit, rel=2e-6)
    assert jc.c_crit == pytest.approx(jt.c_crit, rel=2e-6)
    _straddles(op, None, jc)
    # law (6): the closed form approximates the shuffle crossing (engine side a near speed source)
    ctrl = _law6()
    jc, jt = L.judder_crossing(op, ctrl), L.judder_threshold(op, ctrl)
    assert jt.which == "shuffle"
    assert jc.mu_slope_crit == pytest.approx(jt.mu_slope_crit, rel=5e-3)
    assert jc.frequency_hz == pytest.approx(jt.shuffle_frequency_hz, rel=0.03)
    _straddles(op, ctrl, jc)
    d = jc.to_dict()
    json.dumps(d)
    assert d["reason"] is None and d["crossing_pole"][0] >= 0


def test_judder_crossing_on_the_full_model_against_its_root_locus():
    """The full model has no closed form; the numeric threshold is the first crossing of the
    root locus over mu' (here, with the damper friction stuck, the shuffle mode; the report's
    test covers a point where the disc on the damper spring crosses first, near 70 Hz)."""
    op = _slip("full")
    ctrl = _law6("full")
    with pytest.raises(ValueError, match="reduced model"):
        L.judder_threshold(op, ctrl)
    jc = L.judder_crossing(op, ctrl)
    assert jc.available and jc.mu_slope_crit < 0 and jc.frequency_hz > 1.0
    _straddles(op, ctrl, jc)
    # an independent grid (no point on the threshold): the first unstable grid value lies beyond
    # the threshold, the stable one before it on the near side
    from drivetrain_ctrl.linear.margins import root_locus

    vals = np.linspace(0.0, 2.0, 37)[1:] * jc.mu_slope_crit * 1.0001
    rl = root_locus(op, ctrl, parameter="mu_slope", values=list(vals))
    k = next(i for i, p in enumerate(rl.points) if not p.stable)
    assert k > 0 and all(p.stable for p in rl.points[:k])
    assert rl.points[k].value <= jc.mu_slope_crit - jc.tolerance
    assert rl.points[k - 1].value >= jc.mu_slope_crit + jc.tolerance
    # the mode that crosses on the grid is the one named
    p = max(rl.points[k].poles, key=lambda q: q.real)
    assert abs(p.imag) / (2 * math.pi) == pytest.approx(jc.frequency_hz, rel=0.05)


def test_judder_crossing_of_a_sampled_loop():
    op = _slip()
    c = pi_controller(
        P, kp=1e-3, ki=5e-3, reference=sg.constant(170.0), driven_state="omega_primary",
        dt=0.01, delay_samples=1,
    )  # fmt: skip
    jc = L.judder_crossing(op, c)
    assert jc.available and jc.dt == 0.01 and jc.mu_slope_crit < 0
    from drivetrain_ctrl.linear.clutch import _sampled_loop_poles

    def radius(mu):
        return np.max(np.abs(_sampled_loop_poles(L.linearise(op, inputs=("x_c",), mu_slope=mu),
                                                 op, c)))  # fmt: skip

    assert radius(jc.stable_side) < 1.0 <= radius(jc.unstable_side) + 1e-9
    assert jc.frequency_note


def test_judder_crossing_not_available_says_why():
    import dataclasses

    op = _slip()
    ctrl = _law6()
    # positive feedback: unstable already with constant friction
    bad = dataclasses.replace(ctrl, lti=control.ss([], [], [], [[-K_R]]))
    jc = L.judder_crossing(op, bad)
    assert not jc.available and jc.mu_slope_crit is None and jc.c_crit is None
    assert "not stable with constant friction" in jc.reason
    assert jc.summary().startswith("not available: ")
    # a search that stops before the crossing
    jc = L.judder_crossing(op, ctrl, search_limit=1e-5)
    assert not jc.available and "stays stable" in jc.reason and "1e-05" in jc.reason
    json.dumps(jc.to_dict())
    with pytest.raises(ValueError, match="rtol"):
        L.judder_crossing(op, ctrl, rtol=0.0)
