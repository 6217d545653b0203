"""The clutch's slip-mode loop plant set (design/clutch.py): the plants are the linear analysis's
loop plants, and with constant mu equal law (6)'s closed form with k_r = 1 at every vertex."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from drivetrain_ctrl.control import Actuator, law6_loop_closed_form
from drivetrain_ctrl.control.laws import load_controller
from drivetrain_ctrl.core import signals as sg
from drivetrain_ctrl.design.clutch import ClutchPlantSet, clutch_plant_set
from drivetrain_ctrl.design.pi import design_pi
from drivetrain_ctrl.design.plants import PlantSet, as_plant_set
from drivetrain_ctrl.linear import clutch_loop, slip_operating_point
from drivetrain_ctrl.plant.drivetrain import reduced_model
from drivetrain_ctrl.plant.params import default_params

P0 = default_params()
XC = 0.0725  # inside the pedal-map piece [0.07, 0.075]
W = np.array([0.3, 3.0, 30.0, 300.0])


def _op(params=P0):
    return slip_operating_point(
        reduced_model(params), omega_engine=170.0, omega_driven=80.0, x_c=XC, throttle=0.5
    )


def _pedal_slope(params, x_c: float) -> float:
    pm = params.clutch.pedal_map
    k12 = [params.clutch.k12_max * y for y in pm.y]
    k = int(np.searchsorted(pm.x, x_c)) - 1
    return (k12[k + 1] - k12[k]) / (pm.x[k + 1] - pm.x[k])


def _closed(params, *, slope_factor: float = 1.0):
    """|k13'| mu A(s) / (J1 s + b1): law (6)'s loop with k_r = 1 (constant mu, linear engine)."""
    act = params.actuator
    return law6_loop_closed_form(
        k_r=1.0,
        dk13_dxc=slope_factor * _pedal_slope(params, XC),
        mu=1.0,
        J1=params.engine.J1,
        b1_eff=params.engine.b1,
        actuator=Actuator(act.omega_a, act.delta_a),
    )


def _resp(sys, w):
    return np.array([complex(sys(1j * x)) for x in w])


def test_nominal_plant_is_the_linear_analysis_loop_plant():
    ps = clutch_plant_set(operating_points=[_op()])
    assert isinstance(ps, ClutchPlantSet) and isinstance(ps, PlantSet) and len(ps) == 1
    assert ps.names == ("op 0, nominal",)
    c = load_controller("paper").build(P0, reference=sg.constant(170.0))
    ref = clutch_loop(_op(), c).plant
    assert np.allclose(ps[0].freqresp(W), _resp(ref, W), rtol=1e-10)
    assert np.allclose(ps[0].freqresp(W), _resp(_closed(P0), W), rtol=1e-8)
    assert as_plant_set(ps) is not None and ps.sample_period == 0.0
    assert "1 slip-mode loop plants" in ps.summary()


def test_vertices_relative_and_absolute_bounds_match_closed_form():
    box = {"engine.J1": {"factor": (0.8, 1.2)}, "actuator.omega_a": (100.0, 300.0)}
    ps = clutch_plant_set(operating_points=[_op()], box=box)
    assert len(ps) == 5  # nominal + 4 corners
    J1 = P0.engine.J1
    seen = set()
    for plant, pt in zip(ps, ps.points, strict=True):
        vals = pt["box"]
        if pt["vertex"] == "nominal":
            assert vals == {}
            continue
        assert vals["engine.J1"] in (pytest.approx(0.8 * J1), pytest.approx(1.2 * J1))
        assert vals["actuator.omega_a"] in (100.0, 300.0)
        seen.add((round(vals["engine.J1"] / J1, 6), vals["actuator.omega_a"]))
        p = P0.replace(**vals)
        assert np.allclose(plant.freqresp(W), _resp(_closed(p), W), rtol=1e-8), plant.name
        assert "engine.J1 = " in plant.name and "vertex" in plant.name
    assert seen == {(0.8, 100.0), (0.8, 300.0), (1.2, 100.0), (1.2, 300.0)}


def test_friction_coefficient_and_pedal_slope_scale_the_gain():
    """k12_max scales the whole capacity k13(x_c) and its slope; pedal_slope the slope only."""
    box = {"clutch.k12_max": {"factor": (0.6, 1.4)}, "pedal_slope": (0.5, 0.5)}
    ps = clutch_plant_set(operating_points=[_op()], box=box, include_nominal=False)
    assert len(ps) == 2  # a (lo, lo) pair is one value
    for plant, pt in zip(ps, ps.points, strict=True):
        f = pt["box"]["clutch.k12_max"] / P0.clutch.k12_max
        expected = _resp(_closed(P0, slope_factor=f * 0.5), W)
        assert np.allclose(plant.freqresp(W), expected, rtol=1e-8)


def test_mu_slope_couples_the_driveline_in():
    ps = clutch_plant_set(operating_points=[_op()], box={"mu_slope": {"values": [0.0, -2e-3]}})
    flat, falling = ps.freqresp(W)[1:]
    assert np.allclose(flat, _resp(_closed(P0), W), rtol=1e-8)
    assert not np.allclose(falling, flat, rtol=1e-3)


def test_sampled_plants_with_hold_and_delay():
    Ts = 0.01
    ps = clutch_plant_set(operating_points=[_op()], sample_period=Ts, box={"delay_samples": (0, 2)})
    assert len(ps) == 3 and ps.sample_period == Ts and ps.dt == Ts
    Pd = control.sample_system(_closed(P0), Ts, method="zoh")
    z = np.exp(1j * W[W < math.pi / Ts] * Ts)
    for d, plant in enumerate(ps):
        assert plant.delay == pytest.approx(d * Ts) and plant.sys.dt == Ts
        expected = np.array([complex(Pd(zz)) for zz in z]) * z**-d
        # the 7-state plant keeps the driveline modes (uncontrollable with constant mu): their
        # near-cancellation at z ~ 1 costs a few digits at low frequency
        assert np.allclose(plant.freqresp(W[W < math.pi / Ts]), expected, rtol=1e-4)
        assert f"delay {d} sample" in plant.name
    mini = clutch_plant_set(operating_points=[_op()], sample_period=Ts, minimal=True)
    assert mini[0].sys.nstates == 3  # actuator (2) and engine (1)
    assert np.allclose(mini[0].freqresp(W[:3]), ps[0].freqresp(W[:3]), rtol=1e-4)
    # a 10-ms controller gives its period and delay by default
    ps10 = clutch_plant_set(operating_points=[_op()], controller="pi-10ms")
    assert ps10.sample_period == 0.01 and ps10[0].delay == pytest.approx(0.01)


def test_latin_hypercube_samples_stay_in_the_box():
    box = {"engine.J1": (0.15, 0.25), "actuator.delta_a": (0.5, 1.0)}
    ps = clutch_plant_set(operating_points=[_op()], box=box, sampling=4, seed=3)
    assert len(ps) == 5
    vals = [pt["box"] for pt in ps.points[1:]]
    assert all(0.15 <= v["engine.J1"] <= 0.25 and 0.5 <= v["actuator.delta_a"] <= 1 for v in vals)
    assert len({v["engine.J1"] for v in vals}) == 4
    again = clutch_plant_set(operating_points=[_op()], box=box, sampling=4, seed=3)
    assert again.points == ps.points


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"box": {"clutch.k12max": (1.0, 2.0)}}, r"'clutch.k12max'.*did you mean 'clutch.k12_max'"),
        (
            {"box": {"engine.J1": (0.3, 0.1)}},
            r"box\['engine.J1'\] = \(0.3, 0.1\): lo must be <= hi",
        ),
        ({"box": {"engine.J1": {"fact": (1, 2)}}}, r"unknown key 'fact'"),
        ({"box": {"mu_slope": {"factor": (1, 2)}}}, r"'factor' applies to parameter paths only"),
        ({"box": {"clutch.pedal_map": (0, 1)}}, r"'clutch.pedal_map' is not a number parameter"),
        ({"box": {"delay_samples": (0, 1.5)}}, r"whole numbers of samples"),
        ({"box": {"delay_samples": (0, 2)}}, r"needs a sampled design"),
        ({"box": {"engine.J1": (-1.0, 0.2)}}, r"engine.J1"),
        ({"sampling": "corners"}, r"sampling = 'corners'"),
        ({"kind": "medium"}, r"kind = 'medium'"),
        ({"sample_period": -0.01}, r"sample_period = -0.01: must be > 0"),
    ],
)
def test_bad_input_names_the_field(kw, match):
    with pytest.raises(ValueError, match=match):
        clutch_plant_set(operating_points=[_op()], **kw)


def test_operating_points_must_be_slip_points():
    with pytest.raises(ValueError, match=r"operating_points\[0\]"):
        clutch_plant_set(operating_points=["x"])  # type: ignore[list-item]


def test_trajectory_instants_and_a_pi_on_them():
    """Two instants of paper-start's slip phase with law (6); a PI at PM 60 on the first one."""
    ps = clutch_plant_set(times=2)
    assert len(ps) == 2 and all(n.startswith("t = ") for n in ps.names)
    ts = [pt["t"] for pt in ps.points]
    assert 0.5 < ts[0] < ts[1] < 2.8  # between the controller start and lock-up (about 2.7 s)
    d = design_pi(ps[0])
    assert d.feasible and d.stable and d.phase_margin == pytest.approx(60.0, abs=0.5)
    with pytest.raises(ValueError, match=r"t = 0.1 s the clutch is 'open'"):
        clutch_plant_set(times=[0.1])


def test_the_plants_are_of_the_scenarios_car():
    """A scenario with parameter overrides (worn-clutch: clutch capacity x 0.7) gives plants of
    that car: its plant without a box equals the one whose box sets k12_max to 0.7 of the
    default explicitly (and differs from the default car's)."""
    import numpy as np

    from drivetrain_ctrl.design.clutch import clutch_plant_set
    from drivetrain_ctrl.plant.params import default_params

    k_new = default_params().clutch.k12_max
    w = np.array([1.0, 10.0, 50.0])
    kw = {"scenario": "worn-clutch", "times": [1.5], "kind": "reduced"}
    worn = clutch_plant_set(**kw).freqresp(w)
    explicit = clutch_plant_set(
        **kw, box={"clutch.k12_max": {"values": [0.7 * k_new]}}, include_nominal=False
    ).freqresp(w)
    new = clutch_plant_set(
        **kw, box={"clutch.k12_max": {"values": [k_new]}}, include_nominal=False
    ).freqresp(w)
    assert np.allclose(worn[0], explicit[0], rtol=1e-9)
    assert not np.allclose(worn[0], new[0], rtol=1e-3)
