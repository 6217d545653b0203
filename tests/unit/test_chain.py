"""Chain building blocks: validation errors and the reference spring/table laws."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivetrain_ctrl import kernels as K
from drivetrain_ctrl.core.tables import PwlTable
from drivetrain_ctrl.plant.chain import (
    Body,
    Chain,
    Coupling,
    Friction,
    LaggedSource,
    Spring,
    two_body_clutch,
)
from drivetrain_ctrl.plant.model import Model


def bodies(n: int, **kw) -> tuple[Body, ...]:
    return tuple(Body(f"b{i}", 1.0, **kw) for i in range(n))


def couplings(n: int) -> tuple[Coupling, ...]:
    return tuple(Coupling(f"c{i}", damper=1.0) for i in range(n))


# -- Chain --------------------------------------------------------------------------------------


def test_a_valid_chain() -> None:
    ch = Chain(bodies(3), couplings(2))
    assert ch.body_index("b2") == 2
    with pytest.raises(KeyError, match="nope"):
        ch.body_index("nope")


@pytest.mark.parametrize(("nb", "nc"), [(3, 1), (3, 3), (1, 1), (2, 0)])
def test_couplings_count(nb: int, nc: int) -> None:
    with pytest.raises(ValueError, match=f"{nb} bodies need {nb - 1} couplings, got {nc}"):
        Chain(bodies(nb), couplings(nc))


def test_no_bodies() -> None:
    with pytest.raises(ValueError, match="at least one body"):
        Chain((), ())


def test_unknown_input_of_a_body() -> None:
    with pytest.raises(ValueError, match="'torque_x'.*not declared"):
        Chain(
            (Body("a", 1.0, torque_input="torque_x"), Body("b", 1.0)), couplings(1), inputs=("u",)
        )


def test_unknown_input_of_a_friction() -> None:
    cp = Coupling("clutch", friction=Friction(capacity_input="pedal", name="clutch"))
    with pytest.raises(ValueError, match="clutch: input 'pedal'"):
        Chain(bodies(2), (cp,), inputs=("throttle",))
    gf = Friction(capacity_input="brake", name="brake")
    with pytest.raises(ValueError, match="'brake'"):
        Chain((Body("a", 1.0, ground_friction=gf),), ())


def test_unknown_input_or_body_of_a_source() -> None:
    src = LaggedSource("eng", "b0", "throttle", 0.1)
    with pytest.raises(ValueError, match="eng: input 'throttle'"):
        Chain(bodies(1), (), (src,), inputs=())
    with pytest.raises(ValueError, match="unknown body 'nope'"):
        Chain(bodies(1), (), (LaggedSource("eng", "nope", "throttle", 0.1),), inputs=("throttle",))


@pytest.mark.parametrize("inertia", [0.0, -1.0, float("nan"), float("inf")])
def test_non_positive_inertia(inertia: float) -> None:
    with pytest.raises(ValueError, match=r"b\.inertia"):
        Body("b", inertia)


def test_inertia_must_be_a_number() -> None:
    with pytest.raises(TypeError, match=r"b\.inertia"):
        Body("b", "1.0")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"b\.inertia"):
        Body("b", True)


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"viscous": -1.0}, "viscous"),
        ({"quadratic": -0.1}, "quadratic"),
        ({"load": float("nan")}, "load"),
        ({"input_gain": float("inf")}, "input_gain"),
        ({"kind": "linear"}, "kind"),
    ],
)
def test_body_fields(kw: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        Body("b", 1.0, **kw)


def test_names_unique() -> None:
    with pytest.raises(ValueError, match="unique"):
        Chain((Body("a", 1.0), Body("a", 2.0)), couplings(1))
    with pytest.raises(ValueError, match="unique"):
        Chain((Body("a", 1.0), Body("b", 2.0)), (Coupling("a", damper=1.0),))


def test_friction_names_unique_in_a_model() -> None:
    with pytest.raises(ValueError, match=r"the names \['f'\] are used by more than one of the fr"):
        Chain(
            (Body("a", 1.0, ground_friction=Friction(name="f")), Body("b", 1.0)),
            (Coupling("c", friction=Friction(name="f")),),
        )


# -- Spring ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("x", "y"),
    [((0.1, 0.2), (0.0, 1.0)), ((0.0, 0.2), (0.5, 1.0)), ((-0.1, 0.2), (0.0, 1.0))],
)
def test_spring_must_start_at_zero(x, y) -> None:
    with pytest.raises(ValueError, match="first knot must be"):
        Spring(x, y, name="phi")


@pytest.mark.parametrize(
    ("x", "y", "match"),
    [
        ((0.0,), (0.0,), "at least two knots"),
        ((0.0, 0.1), (0.0,), "at least two knots"),
        ((0.0, 0.1, 0.1), (0.0, 1.0, 2.0), "strictly increasing"),
        ((0.0, 0.1), (0.0, float("nan")), r"y\[1\]"),
    ],
)
def test_spring_knots(x, y, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Spring(x, y, name="phi")


def test_spring_backlash_and_linear() -> None:
    with pytest.raises(ValueError, match="backlash"):
        Spring((0.0, 1.0), (0.0, 1.0), backlash=-0.1)
    with pytest.raises(ValueError, match="stiffness"):
        Spring.linear(0.0)
    s = Spring.linear(100.0, backlash=0.1)
    assert s.torque(0.05) == 0.0 and s.torque(-0.1) == 0.0
    assert s.torque(0.3) == pytest.approx(20.0) and s.torque(-0.3) == pytest.approx(-20.0)


@settings(max_examples=100, deadline=None)
@given(
    dx=st.lists(st.floats(0.01, 0.3), min_size=1, max_size=3),
    dy=st.lists(st.floats(0.0, 500.0), min_size=3, max_size=3),
    g=st.sampled_from([0.0, 0.05]),
    q=st.floats(-1.5, 1.5),
)
def test_spring_torque_matches_the_model(dx, dy, g, q) -> None:
    """The reference spring law equals the compiled table (odd, gap, last slope continued)."""
    xs = [0.0]
    ys = [0.0]
    for i, d in enumerate(dx):
        xs.append(xs[-1] + d)
        ys.append(ys[-1] + dy[i])
    sp = Spring(tuple(xs), tuple(ys), g, "s")
    m = Model(Chain(bodies(2), (Coupling("c", spring=sp),)))
    x = np.array([0.0, 0.0, q])
    tau = K.forces(
        m.data,
        x,
        np.zeros(0),
        np.zeros(0, np.int64),
        m.mode_from_state(x, np.zeros(0), {}).arrays()[1],
    )
    assert -tau[0] == pytest.approx(sp.torque(q), rel=1e-9, abs=1e-9)
    assert sp.torque(-q) == -sp.torque(q)


def test_spring_torque_with_negative_law() -> None:
    sp = Spring((0.0, 0.125), (0.0, -1.0), name="s")
    m = Model(Chain(bodies(2), (Coupling("c", spring=sp),)))
    x = np.array([0.0, 0.0, 0.065])
    mode = m.mode_from_state(x, np.zeros(0), {})
    tau = K.forces(m.data, x, np.zeros(0), np.zeros(0, np.int64), mode.arrays()[1])
    assert -tau[0] == pytest.approx(-0.52)  # the model: odd extension of the law
    assert sp.torque(0.065) == pytest.approx(-0.52)


# -- PwlTable, Friction, Coupling, LaggedSource ----------------------------------------------------


def test_pwl_table() -> None:
    t = PwlTable((0.0, 1.0, 3.0), (1.0, 3.0, 2.0))
    assert t(-1.0) == 1.0 and t(0.5) == pytest.approx(2.0) and t(2.0) == pytest.approx(2.5)
    assert t(9.0) == 2.0
    assert PwlTable((1.0,), (4.0,))(-3.0) == 4.0
    assert np.isnan(t(float("nan")))  # NaN in, NaN out (not an end value)
    with pytest.raises(ValueError, match="strictly increasing"):
        PwlTable((0.0, 0.0), (1.0, 2.0), "tab")
    with pytest.raises(ValueError, match="non-empty"):
        PwlTable((), ())
    with pytest.raises(ValueError, match=r"tab\.y\[0\]"):
        PwlTable((0.0,), (float("nan"),), "tab")


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"scale": -1.0}, "scale"),
        ({"static_ratio": 0.9}, "static_ratio"),
        ({"capacity_table": PwlTable((0.0, 1.0), (0.0, 1.0))}, "capacity_table needs"),
        ({"mu_table": PwlTable((1.0, 2.0), (1.0, 0.9))}, "mu_table must start"),
        ({"mode_names": ("a", "b", "c")}, "mode_names"),
        ({"mode_names": ("a", "a", "c", "d")}, "mode_names"),
    ],
)
def test_friction_fields(kw: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Friction(**kw)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"ratio": 0.0, "damper": 1.0}, "ratio"),
        ({"ratio": -2.0, "damper": 1.0}, "ratio"),
        ({"damper": -1.0}, "damper"),
        ({}, "needs a spring, a damper or a friction"),
    ],
)
def test_coupling_fields(kw: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Coupling("c", **kw)


def test_lagged_source_tau() -> None:
    with pytest.raises(ValueError, match="tau"):
        LaggedSource("eng", "b0", "thr", 0.0)


def test_two_body_clutch() -> None:
    ch = two_body_clutch(0.2, 0.05, capacity="cap", static_ratio=1.2, load2=-3.0)
    assert ch.inputs == ("cap", "torque1")
    fr = ch.couplings[0].friction
    assert fr.capacity_input == "cap" and fr.static_ratio == 1.2
    assert ch.bodies[1].tracks_position and not ch.bodies[0].tracks_position
    ch2 = two_body_clutch(0.2, 0.05, capacity=80.0)
    assert ch2.inputs == ("torque1",) and ch2.couplings[0].friction.scale == 80.0


def test_input_units_are_checked_and_reach_the_model_and_dataframe() -> None:
    from drivetrain_ctrl.plant.chain import Body, Chain, Coupling, Friction
    from drivetrain_ctrl.plant.model import Model
    from drivetrain_ctrl.sim.simulator import simulate

    bodies = (Body("a", 1.0, torque_input="T"), Body("b", 2.0))
    cps = (Coupling("c", friction=Friction(capacity_input="cap", name="c")),)
    with pytest.raises(ValueError, match=r"input_units: 'torque' is not declared"):
        Chain(bodies, cps, inputs=("T", "cap"), input_units={"torque": "N m"})
    with pytest.raises(TypeError, match=r"input_units\['T'\] = 3: must be a str"):
        Chain(bodies, cps, inputs=("T", "cap"), input_units={"T": 3})  # type: ignore[dict-item]
    with pytest.raises(TypeError, match=r"Chain.input_units = \['N m'\]: must be a mapping"):
        Chain(bodies, cps, inputs=("T", "cap"), input_units=["N m"])  # type: ignore[arg-type]
    m = Model(Chain(bodies, cps, inputs=("T", "cap"), input_units={"T": "N m"}))
    assert m.input_units == ("N m", "")
    df = simulate(m, [1.0, 0.0], {"T": 2.0, "cap": 5.0}, t_end=0.1).to_dataframe()
    assert "input_T [N m]" in df.columns and "input_cap" in df.columns


# -- bad input: construction errors name the field ------------------------------------------------


@pytest.mark.parametrize(
    ("make", "exc", "match"),
    [
        (lambda: Coupling("c", spring=1000.0), TypeError, r"c.spring = 1000.0: must be a Spring"),
        (lambda: Body("a", 1.0, ground_friction=5.0), TypeError, "a.ground_friction = 5.0"),
        (lambda: Friction(mu_table=5), TypeError, "friction.mu_table = 5: must be a PwlTable"),
        (lambda: LaggedSource("s", "a", "u", 0.1, gain_table=3), TypeError, "s.gain_table = 3"),
        (lambda: Chain((1.0, 2.0), ()), TypeError, r"Chain.bodies\[0\] = 1.0: must be a Body"),
        (lambda: Chain(bodies(1), (), inputs="thr"), TypeError, "Chain.inputs = 'thr'"),
        (lambda: Chain(bodies(1), (), inputs=("u", "u")), ValueError, "must not repeat"),
        (lambda: Chain(bodies(1), (), inputs=("",)), ValueError, r"Chain.inputs\[0\] = ''"),
        (lambda: Body("", 1.0), ValueError, "Body.name = ''"),
        (lambda: Body(None, 1.0), ValueError, "Body.name = None"),
        (lambda: PwlTable(None, (1.0,)), TypeError, "table.x = None: must be a tuple"),
        (lambda: PwlTable((0.0, 1.0), (1.0,)), ValueError, "got 2 x and 1 y"),
        (lambda: Spring.linear(100.0, backlash=True), TypeError, "backlash must be a real number"),
        (lambda: Friction(mode_names="abcd"), ValueError, "mode_names = 'abcd'"),
        (
            lambda: Friction(mu_table=PwlTable((0.0, 1.0), (1.0, -2.0))),
            ValueError,
            "1 at zero slip and never negative",
        ),
        (lambda: two_body_clutch(0.1, 0.2, capacity=True), TypeError, "capacity must be a real"),
        (lambda: two_body_clutch(0.1, 0.2, capacity="torque1"), ValueError, "capacity = 'torque1'"),
        (
            lambda: Chain(
                (Body("a", 1.0), Body("b", 1.0)),
                (Coupling("c", damper=1.0),),
                (LaggedSource("s", "a", "u", 0.1), LaggedSource("s", "b", "u", 0.1)),
                inputs=("u",),
            ),
            ValueError,
            r"the names \['s'\] are used by more than one of the sources",
        ),
        (
            lambda: Chain(
                (Body("a", 1.0, ground_friction=Friction(name="gear")), Body("b", 1.0)),
                (Coupling("gear", spring=Spring.linear(100.0, backlash=0.01)),),
            ),
            ValueError,
            r"\['gear'\] are used by more than one of the friction elements and backlashes",
        ),
    ],
)
def test_bad_chain_elements_name_the_field(make: object, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        make()  # type: ignore[operator]


def test_numpy_numbers_are_numbers() -> None:
    assert Body("a", np.int64(2)).inertia == 2
    assert Spring.linear(np.float32(100.0)).y[1] == pytest.approx(100.0)


def test_model_checks_modes_and_shapes() -> None:
    from drivetrain_ctrl.plant.drivetrain import Drivetrain
    from drivetrain_ctrl.plant.model import Mode
    from drivetrain_ctrl.plant.params import default_params

    dt = Drivetrain(default_params())
    m = dt.model
    x = dt.rigid_state(omega_engine=100.0, v_vehicle=3.0, throttle=0.3)
    u = m.inputs(throttle=0.3, pedal=0.05, brake=0.0)
    mode, _ = m.decide(x, u)
    nt = len(mode.reg)
    with pytest.raises(ValueError, match=r"Mode.reg\[0\] = 1000000000 for table"):
        m.rhs(x, u, Mode(mode.fm, (10**9,) * nt))  # was a segmentation fault
    with pytest.raises(ValueError, match="Mode.fm has 1 codes for 6 friction elements"):
        m.powers(x, u, Mode((0,), mode.reg))
    with pytest.raises(ValueError, match=r"Mode.fm code 7 for 'clutch'"):
        m.mode_names(Mode((7, *mode.fm[1:]), mode.reg))
    with pytest.raises(TypeError, match="Mode.fm = .*must be a tuple of integer codes"):
        Mode(("stuck",), ())
    with pytest.raises(TypeError, match="mode = None: must be a Mode"):
        m.jacobian(x, u, None)  # type: ignore[arg-type]
    for fn in (lambda: m.decide(x[:3], u), lambda: m.decide(x, np.zeros(0))):
        with pytest.raises(ValueError, match="must have shape"):
            fn()
    with pytest.raises(ValueError, match=r"state x must have shape \(13,\)"):
        m.stored_energy(np.array([1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="decide: tol = -1"):
        m.decide(x, u, tol=-1)
    with pytest.raises(ValueError, match="input throttle = 'a': must be a finite number"):
        m.inputs(throttle="a", pedal=0.05, brake=0.0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="Model.chain = 'chain'|Model\\(chain = 'chain'\\)"):
        Model("chain")  # type: ignore[arg-type]


def test_drivetrain_arguments_are_checked() -> None:
    from drivetrain_ctrl.plant.drivetrain import Drivetrain
    from drivetrain_ctrl.plant.params import default_params

    p = default_params()
    with pytest.raises(TypeError, match="params = None: must be a DrivetrainParams"):
        Drivetrain(None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="slope = True rad: must be a finite number"):
        Drivetrain(p, slope=True)  # type: ignore[arg-type]
    assert Drivetrain(p, gear=np.int64(2)).gear == 2
    dt = Drivetrain(p)
    with pytest.raises(ValueError, match="rigid_state: omega_engine = None"):
        dt.rigid_state(omega_engine=None, v_vehicle=0.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"rigid_state: throttle = 2.0: must lie in \[0, 1\]"):
        dt.rigid_state(omega_engine=100.0, v_vehicle=0.0, throttle=2.0)
    with pytest.raises(ValueError, match="v = nan"):
        dt.vehicle_speed_to_primary(float("nan"))


def test_arrays_and_numpy_values_still_work_where_they_did() -> None:
    """The input checks keep what worked: knots as arrays, a Mode from a result row, 0-d arrays
    as numbers, vectorised speed conversion."""
    from drivetrain_ctrl.plant.drivetrain import Drivetrain
    from drivetrain_ctrl.plant.model import Mode
    from drivetrain_ctrl.plant.params import default_params
    from drivetrain_ctrl.sim.simulator import SimulationOptions

    sp = Spring(np.array([0.0, 0.1, 0.2]), np.array([0.0, 10.0, 50.0]))
    assert sp == Spring((0.0, 0.1, 0.2), (0.0, 10.0, 50.0))
    assert PwlTable(np.array([0.0, 1.0]), [1.0, 2.0]).x == (0.0, 1.0)
    dt = Drivetrain(default_params())
    m = dt.model
    x = dt.rigid_state(omega_engine=np.array(200.0), v_vehicle=np.array(1.0), throttle=0.3)
    u = m.inputs(throttle=np.array(0.3), pedal=0.05, brake=0.0)
    mode, _ = m.decide(x, u)
    fm, reg = mode.arrays()
    again = Mode(fm, list(reg))  # e.g. a result row res.fm[i], res.reg[i]
    assert again == mode and hash(again) == hash(mode)
    assert all(type(c) is int for c in again.fm)
    v = np.array([1.0, 2.0])
    assert np.allclose(dt.vehicle_speed_to_primary(v), v * dt.vehicle_speed_to_primary(1.0))
    assert SimulationOptions(energy=np.True_).energy is True
