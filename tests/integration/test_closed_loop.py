"""The closed-loop hook against hand-derived cases (one inertia, torque input driven by P/PI)."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from drivetrain_ctrl.control.blocks import Actuator, Controller
from drivetrain_ctrl.core.signals import constant
from drivetrain_ctrl.plant.chain import Body, Chain
from drivetrain_ctrl.plant.model import Model
from drivetrain_ctrl.sim.run import run_scenario
from drivetrain_ctrl.sim.simulator import SimulationOptions, simulate

J = 0.5  # kg m^2
R = 100.0  # rad/s reference
W0 = 20.0  # rad/s initial speed
OPTS = SimulationOptions(rtol=1e-10, atol=1e-10)


def _one_body() -> Model:
    return Model(Chain((Body("b", J, torque_input="torque"),), (), inputs=("torque",)))


def _p(kp: float, **kw: object) -> Controller:
    return Controller(
        lti=kw.pop("lti", control.ss([], [], [], [[kp]])),  # type: ignore[arg-type]
        measurement=((1.0, "ref"), (-1.0, "omega_b")),
        reference=constant(R),
        output="torque",
        **kw,  # type: ignore[arg-type]
    )


def test_proportional_continuous_matches_exponential() -> None:
    kp = 2.0
    res = simulate(_one_body(), np.array([W0]), {}, t_end=1.0, controller=_p(kp), options=OPTS)
    expected = R + (W0 - R) * np.exp(-kp * res.t / J)
    np.testing.assert_allclose(res.state("omega_b"), expected, rtol=1e-8)
    # the input applied is the controller's output
    np.testing.assert_allclose(res.u[:, 0], kp * (R - res.state("omega_b")), rtol=1e-8)


def test_saturation_leaves_at_the_hand_derived_time() -> None:
    kp, umax = 2.0, 40.0
    c = _p(kp, saturation=(-umax, umax))
    res = simulate(_one_body(), np.array([W0]), {}, t_end=2.0, controller=c, options=OPTS)
    # saturated: J w' = umax until kp (R - w) = umax
    t_s = (R - umax / kp - W0) * J / umax
    i = np.searchsorted(res.t, t_s)
    assert abs(res.state("omega_b")[i - 1] - (W0 + umax * res.t[i - 1] / J)) < 1e-7
    # after t_s: exponential from w_s
    w_s = R - umax / kp
    late = res.t > t_s + 1e-9
    expected = R + (w_s - R) * np.exp(-kp * (res.t[late] - t_s) / J)
    np.testing.assert_allclose(res.state("omega_b")[late], expected, rtol=1e-7)
    assert np.all(np.abs(res.u[:, 0]) <= umax + 1e-9)


@pytest.mark.parametrize("delay", [0, 1])
def test_discrete_proportional_with_zoh_and_delay(delay: int) -> None:
    kp, ts = 0.1, 0.01
    lti = control.ss([], [], [], [[kp]], ts)
    c = _p(kp, lti=lti, delay_samples=delay)
    res = simulate(_one_body(), np.array([W0]), {}, t_end=0.5, controller=c, options=OPTS)
    # recursion: w_{k+1} = w_k + ts/J * u_k, u_k = kp (R - w_{k-delay}) (0 before the first sample)
    n = 50
    w = [W0]
    outs: list[float] = []
    for k in range(n):
        outs.append(kp * (R - w[k]))
        u_k = outs[k - delay] if k - delay >= 0 else 0.0
        w.append(w[k] + ts / J * u_k)
    t_grid = ts * np.arange(n + 1)
    got = np.interp(t_grid, res.t, res.state("omega_b"))
    np.testing.assert_allclose(got, w, rtol=1e-9, atol=1e-9)


def test_actuator_step_response_matches_python_control() -> None:
    # constant controller output through the 2nd-order actuator
    act = Actuator(omega=50.0, delta=0.7)
    c = Controller(
        lti=control.ss([], [], [], [[0.0]]),
        measurement=((1.0, "omega_b"),),
        output="torque",
        offset=10.0,
        actuator=act,
    )
    res = simulate(_one_body(), np.array([0.0]), {}, t_end=0.3, controller=c, options=OPTS)
    w, z = act.omega, act.delta
    wd = w * math.sqrt(1 - z * z)
    t = res.t
    y = 1 - np.exp(-z * w * t) * (np.cos(wd * t) + z / math.sqrt(1 - z * z) * np.sin(wd * t))
    np.testing.assert_allclose(res.u[:, 0], 10.0 * y, atol=1e-7)
    # the same actuator as a python-control model has the same final value and damping
    assert abs(control.dcgain(act.lti()) - 1.0) < 1e-12
    # body speed integrates the torque
    w_expected = (
        np.concatenate(([0.0], np.cumsum(np.diff(res.t) * 0.5 * (res.u[1:, 0] + res.u[:-1, 0]))))
        / J
    )
    np.testing.assert_allclose(res.state("omega_b"), w_expected, atol=1e-3)


def test_controller_rejects_a_driven_input_given_as_signal() -> None:
    with pytest.raises(KeyError, match="driven by the controller"):
        simulate(
            _one_body(), np.array([0.0]), {"torque": constant(1.0)}, t_end=0.1, controller=_p(1.0)
        )


def test_controller_validation_names_the_field() -> None:
    with pytest.raises(ValueError, match="saturation"):
        _p(1.0, saturation=(1.0, -1.0))
    with pytest.raises(ValueError, match="delay_samples"):
        _p(1.0, delay_samples=2)
    with pytest.raises(ValueError, match="start_time = True"):
        _p(1.0, start_time=True)
    with pytest.raises(ValueError, match="anti_windup_time = True"):
        _p(1.0, anti_windup_time=True)
    with pytest.raises(ValueError, match="anti_windup_time = 0.0"):
        _p(1.0, anti_windup_time=0.0)
    # NumPy scalars are numbers (one check for the package: loading.is_finite_real)
    assert _p(1.0, start_time=np.float32(0.25)).start_time == pytest.approx(0.25)
    with pytest.raises(ValueError, match="controller_initial = nan"):
        simulate(_one_body(), np.zeros(1), {}, t_end=0.1, controller=_p(1.0),
                 controller_initial=float("nan"))  # fmt: skip
    assert math.isfinite(J)


@pytest.mark.parametrize("discrete", [False, True])
def test_pi_variant_of_law6_runs_on_the_switching_plant(discrete: bool) -> None:
    from drivetrain_ctrl.control.laws import law6_defaults, pi_controller
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    p = default_params()
    k_r = law6_defaults()[0]
    sc = load_scenario("paper-start")
    dt = sc.drivetrain(p, kind="reduced")
    assert sc.reference is not None
    c = pi_controller(
        p,
        reference=sc.reference,
        kp=k_r,
        ki=5 * k_r,
        dt=0.005 if discrete else None,
        delay_samples=1 if discrete else 0,
        driven_state="omega_primary",
    )
    res = simulate(
        dt.model,
        sc.initial_state(dt),
        sc.input_signals(),
        t_end=sc.t_end,
        controller=c,
        controller_initial=sc.pedal0,
    )
    assert res.status == "ok"
    assert res.energy_residual_rel < 1e-6
    w = res.state("omega_engine")
    assert w.min() > 20.0  # no stall
    # the integral state is really used: PI and law (6) differ
    law6 = run_scenario(sc, dt, controller="paper")
    assert abs(np.interp(1.2, res.t, w) - np.interp(1.2, law6.t, law6.state("omega_engine"))) > 1.0


def test_rate_limiter_ramps_at_its_rate_then_follows() -> None:
    rate, gain, target = 20.0, 1000.0, 10.0
    c = Controller(
        lti=control.ss([], [], [], [[0.0]]),
        measurement=((1.0, "omega_b"),),
        output="torque",
        offset=target,
        rate_limit=(rate, gain),
    )
    res = simulate(_one_body(), np.array([0.0]), {}, t_end=1.0, controller=c, options=OPTS)
    # limited: r = rate t until gain (target - r) = rate, i.e. r = target - rate / gain
    t_k = (target - rate / gain) / rate
    early = res.t < t_k
    np.testing.assert_allclose(res.u[early, 0], rate * res.t[early], atol=1e-9)
    late = res.t > t_k
    expected = target - rate / gain * np.exp(-gain * (res.t[late] - t_k))
    np.testing.assert_allclose(res.u[late, 0], expected, atol=1e-8)


def test_lookup_table_shapes_the_output_and_its_knees_are_events() -> None:
    from drivetrain_ctrl.core.tables import PwlTable

    # torque = table(omega): 10 N m below 5 rad/s, falling to 0 at 15 rad/s
    c = Controller(
        lti=control.ss([], [], [], [[1.0]]),
        measurement=((1.0, "omega_b"),),
        output="torque",
        lookup=PwlTable((5.0, 15.0), (10.0, 0.0)),
    )
    res = simulate(_one_body(), np.array([0.0]), {}, t_end=3.0, controller=c, options=OPTS)
    # phase 1: w = 10 t / J until w = 5 at t1 = 0.25 s; phase 2: J w' = (15 - w), w -> 15
    t1 = 5.0 * J / 10.0
    w = res.state("omega_b")
    ph1 = res.t <= t1
    np.testing.assert_allclose(w[ph1], 10.0 * res.t[ph1] / J, atol=1e-9)
    ph2 = res.t > t1
    np.testing.assert_allclose(w[ph2], 15.0 - 10.0 * np.exp(-(res.t[ph2] - t1) / J), atol=1e-7)
    assert np.any(np.isclose(res.t, t1, atol=1e-12))  # the knee is a stop of the integrator


def test_pi_controller_rejects_bad_gains_naming_them() -> None:
    from drivetrain_ctrl.control.laws import pi_controller
    from drivetrain_ctrl.plant.params import default_params

    p = default_params()
    with pytest.raises(ValueError, match="kp"):
        pi_controller(p, reference=constant(100.0), kp=math.nan, ki=1.0)
    with pytest.raises(ValueError, match="dt"):
        pi_controller(p, reference=constant(100.0), kp=1.0, ki=1.0, dt=-0.01)


@pytest.mark.parametrize("rate", [0.0, -0.05, math.nan, 20.0])
def test_shortcuts_reject_a_bad_engage_rate_naming_it(rate: float) -> None:
    """``engage_rate=0`` is an error, not a silent "no latch" (that is ``None``)."""
    from drivetrain_ctrl.control.laws import law6_controller, pi_controller
    from drivetrain_ctrl.plant.params import default_params

    p = default_params()
    with pytest.raises(ValueError, match=r"law6_controller: .*engage_rate \(engage_rate_m_s\)"):
        law6_controller(p, reference=constant(100.0), engage_rate=rate)
    with pytest.raises(ValueError, match=r"pi_controller: .*engage_rate \(engage_rate_m_s\)"):
        pi_controller(p, reference=constant(100.0), kp=1e-3, ki=1e-3, engage_rate=rate)


def test_shortcuts_latch_only_with_an_engage_rate() -> None:
    from drivetrain_ctrl.control.laws import law6_controller, pi_controller
    from drivetrain_ctrl.plant.params import default_params

    p = default_params()
    for make in (
        lambda **kw: law6_controller(p, reference=constant(100.0), **kw),
        lambda **kw: pi_controller(p, reference=constant(100.0), kp=1e-3, ki=1e-3, **kw),
    ):
        assert make(engage_rate=None).latch is None
        latched = make(engage_rate=0.02)
        assert latched.latch is not None
        assert latched.latch.rate == pytest.approx(0.02)


DISCRETE = control.ss([], [], [], [[1.0]], 0.01)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"lti": DISCRETE, "delay_samples": 1.5}, "delay_samples = 1.5: must be a whole number"),
        ({"lti": DISCRETE, "delay_samples": "1"}, "delay_samples = '1'"),
        ({"lti": DISCRETE, "delay_samples": 10**9}, r"delay_samples = 1000000000: .*<= 100000"),
        ({"offset": math.nan}, "offset = nan: must be a finite number"),
        ({"offset": "0.07"}, "offset = '0.07'"),
        ({"saturation": ("0", "1")}, r"saturation = \('0', '1'\): must be a pair"),
        ({"saturation": (0.0, 1.0, 2.0)}, "saturation = .*must be a pair"),
        ({"rate_limit": (math.inf, 1.0)}, "rate_limit = .*must be a pair of finite numbers"),
        ({"initial_lti_state": (0.0, 0.0)}, r"initial_lti_state = \(0.0, 0.0\): must be 0 finite"),
        ({"reference": 100.0}, "reference = 100.0: must be a Signal"),
    ],
)
def test_controller_fields_are_checked_and_named(kw: dict[str, object], match: str) -> None:
    if "reference" in kw:  # _p gives a reference of its own
        with pytest.raises(ValueError, match=match):
            Controller(
                lti=control.ss([], [], [], [[1.0]]),
                measurement=((1.0, "omega_b"),),
                output="torque",
                **kw,  # type: ignore[arg-type]
            )
        return
    with pytest.raises(ValueError, match=match):
        _p(1.0, **kw)
    # numpy integers are whole numbers
    assert _p(1.0, lti=DISCRETE, delay_samples=np.int64(2)).delay_samples == 2


def test_controller_initial_outside_the_input_range_is_rejected() -> None:
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.scenarios.scenario import load_scenario

    p = default_params()
    sc = load_scenario("paper-start", params=p)
    dt = sc.drivetrain(p, kind="reduced")
    ctl = sc.make_controller(dt, "paper")
    with pytest.raises(
        ValueError, match=r"controller_initial = 5.0: outside the range \[0, 0.12\]"
    ):
        simulate(dt.model, sc.initial_state(dt), sc.input_signals(), t_end=0.1, controller=ctl,
                 controller_initial=5.0)  # fmt: skip
