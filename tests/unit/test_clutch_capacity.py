"""The clutch capacity k12(x_c) = clutch.k12_max * clutch.pedal_map(x_c) (paper, eqs. (1), (5)):
k12_max scales it, a pedal map in N m (the older file form) still reads to the same capacity, and
one function (the clutch element's ``capacity`` / ``capacity_slope``) serves the kernel's model,
the linearisation, the controllers and the plots."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomli_w

from drivetrain_ctrl import (
    Drivetrain,
    default_params,
    engagement_metrics,
    load_params,
    run_scenario,
    slip_operating_point,
)
from drivetrain_ctrl.control import builtin_controllers
from drivetrain_ctrl.control.laws import slip_loop
from drivetrain_ctrl.linear.linearisation import linearisation_parts
from drivetrain_ctrl.plant import clutch_friction, save_params
from drivetrain_ctrl.plant.params import ParameterError, params_to_dict
from drivetrain_ctrl.scenarios import load_scenario

P = default_params()


def _old_style(p: Any = P, **clutch: Any) -> dict[str, Any]:
    """The parameter dict of ``p`` with its pedal map written in N m (the older file form)."""
    d = copy.deepcopy(params_to_dict(p))
    pm = d["clutch"]["pedal_map"]
    pm["y"] = [p.clutch.k12_max * y for y in pm["y"]]
    d["clutch"].update(clutch)
    return d


def _write(tmp_path: Path, d: dict[str, Any]) -> Path:
    path = tmp_path / "car.toml"
    path.write_text(tomli_w.dumps(d), encoding="utf-8")
    return path


def _lockup(p: Any, kind: str) -> float:
    dt = Drivetrain(p, kind=kind)
    t = engagement_metrics(run_scenario(load_scenario("engage-ramp"), dt), dt)["lockup_time_s"]
    assert t is not None
    return float(t)


@pytest.mark.parametrize("kind", ["full", "reduced"])
def test_k12_max_scales_the_capacity_and_moves_the_lockup(kind: str) -> None:
    weak = P.replace(**{"clutch.k12_max": 0.8 * P.clutch.k12_max})
    strong = P.replace(**{"clutch.k12_max": 1.2 * P.clutch.k12_max})
    assert weak.clutch.pedal_map == P.clutch.pedal_map  # the shape is kept
    for x_c in (0.03, 0.0525, 0.07, 0.1):
        k = Drivetrain(P, kind=kind).clutch_capacity(x_c)
        assert Drivetrain(weak, kind=kind).clutch_capacity(x_c) == pytest.approx(0.8 * k)
    # engage-ramp releases the pedal at a fixed rate: a weaker clutch locks later
    t0 = _lockup(P, kind)
    assert _lockup(weak, kind) > t0 + 0.1
    assert _lockup(strong, kind) < t0 - 0.1


def test_the_capacity_is_k12_max_times_the_shape() -> None:
    dt = Drivetrain(P)
    pm = P.clutch.pedal_map
    assert pm.y[0] == 1.0 and max(pm.y) == 1.0 and min(pm.y) == 0.0
    assert dt.clutch_capacity(0.03) == P.clutch.k12_max == 250.0
    assert dt.clutch_capacity(0.07) == 62.5  # the paper's x_r0
    assert dt.clutch_capacity(0.0) == 250.0 and dt.clutch_capacity(0.2) == 0.0  # clamped
    xs = np.linspace(0.0, 0.15, 301)
    np.testing.assert_allclose(
        [dt.clutch_capacity(x) for x in xs], P.clutch.k12_max * pm(xs), rtol=1e-14, atol=1e-12
    )
    # vectorised over samples, the same numbers
    fr = dt.model.friction("clutch")
    assert np.array_equal(fr.capacity(xs), [fr.capacity(float(x)) for x in xs])
    # the slope k12'(x_c) [N m/m]: at a knot the piece on the given side
    assert dt.clutch_capacity_slope(0.0725) == pytest.approx((47.8515625 - 62.5) / 0.005)
    assert dt.clutch_capacity_slope(0.07) == pytest.approx((47.8515625 - 62.5) / 0.005)
    assert dt.clutch_capacity_slope(0.07, "left") == pytest.approx((62.5 - 79.1015625) / 0.005)
    with pytest.raises(ValueError, match="side = 'up'"):
        dt.clutch_capacity_slope(0.07, "up")


def test_an_old_style_pedal_map_in_nm_reads_to_the_same_capacity(tmp_path: Path) -> None:
    # the built-in set written the older way: the same parameters, bit for bit
    old = load_params(_write(tmp_path, _old_style()))
    assert old == P
    # a map whose values are not k12_max times binary fractions: the same capacity to rounding
    d = _old_style()
    d["clutch"]["k12_max"] = 300.0
    d["clutch"]["pedal_map"] = {"x": [0.03, 0.05, 0.08, 0.11], "y": [300.0, 123.4, 17.3, 0.0]}
    q = load_params(_write(tmp_path, d))
    assert q.clutch.k12_max == 300.0
    assert q.clutch.pedal_map.y[0] == 1.0 and max(q.clutch.pedal_map.y) <= 1.0
    table = clutch_friction(q).capacity_table  # k12 [N m] at the knots, as the kernel sees it
    assert table is not None and table.x == tuple(d["clutch"]["pedal_map"]["x"])
    np.testing.assert_allclose(table.y, d["clutch"]["pedal_map"]["y"], rtol=1e-15, atol=0.0)
    # written back, the file holds the shape and reads to the same parameters
    back = load_params(save_params(q, tmp_path / "back.toml"))
    assert back == q and max(back.clutch.pedal_map.y) == 1.0


@pytest.mark.parametrize(
    ("clutch", "expected"),
    [
        # N m map (above 1) that does not reach k12_max
        ({"k12_max": 300.0}, ["clutch.pedal_map", "clutch.k12_max = 300", "250"]),
        ({"k12_max": 200.0}, ["clutch.pedal_map", "clutch.k12_max = 200", "250"]),
    ],
)
def test_an_nm_map_must_reach_k12_max(
    clutch: dict[str, Any], expected: list[str], tmp_path: Path
) -> None:
    with pytest.raises(ParameterError) as exc:
        load_params(_write(tmp_path, _old_style(**clutch)))
    for text in expected:
        assert text in str(exc.value)


def test_a_shape_must_be_1_at_full_engagement() -> None:
    with pytest.raises(
        ParameterError, match=r"clutch.pedal_map.*must be 1.*k12/k12_max\(0.03\)=0.8"
    ):
        P.replace(**{"clutch.pedal_map": {"x": [0.03, 0.11], "y": [0.8, 0.0]}})
    with pytest.raises(ParameterError, match=r"clutch.pedal_map: k12/k12_max must be >= 0"):
        P.replace(**{"clutch.pedal_map": {"x": [0.03, 0.11], "y": [1.0, -0.1]}})


def test_one_capacity_function_for_model_linearisation_controllers_and_plots() -> None:
    from drivetrain_ctrl.reporting.figures import _clutch_capacity

    dt = Drivetrain(P, kind="reduced")
    fr = clutch_friction(P)
    assert dt.model.friction("clutch") == fr
    # linearisation: the capacity at the operating point is the element's, in the mode's region
    op = slip_operating_point(dt, omega_engine=180.0, omega_driven=80.0, x_c=0.0725, throttle=0.3)
    assert linearisation_parts(op).capacity == fr.capacity(0.0725) == dt.clutch_capacity(0.0725)
    assert dt.model.capacity("clutch", op.u, op.mode) == fr.capacity(0.0725)
    # controllers: the loop's gain at s = 0 is k_r |k12'(x_r0)| / b1
    spec = builtin_controllers()["paper"]
    L = slip_loop(spec, P)
    dc = float(np.real(L(0.0)))
    assert dc == pytest.approx(
        spec.gain_k_r * abs(fr.capacity_slope(spec.offset_x_r0)) / P.engine.b1, rel=1e-12
    )
    # plots: the capacity curve over the samples
    res = run_scenario(load_scenario("engage-ramp"), dt, t_end=0.5)
    cap = _clutch_capacity(dt.model, res.u)
    assert cap is not None
    assert np.array_equal(cap, [dt.clutch_capacity(float(x)) for x in res.u[:, 1]])
