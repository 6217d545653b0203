"""Value tests of drivetrain_ctrl.plant.params (issue 22 item 4): the checks' exact boundaries
and messages, and derived values recomputed by hand, each killing a mutant the older tests let
through (``./dev mutate drivetrain_ctrl/plant/params.py``)."""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any

import pytest

from drivetrain_ctrl.plant.params import (
    ParameterError,
    default_params,
    field_info,
    field_paths,
    params_from_dict,
    params_to_dict,
)


def _base() -> dict[str, Any]:
    return copy.deepcopy(params_to_dict(default_params()))


@pytest.mark.parametrize("bad", ["3.5", b"3", {"x": 1}, 3.5])
def test_a_list_field_given_a_non_sequence_is_named_as_such(bad: object) -> None:
    d = _base()
    d["gearbox"]["gear_ratios"] = bad
    with pytest.raises(ParameterError) as e:
        params_from_dict(d)
    assert str(e.value).startswith("gearbox.gear_ratios = ")
    assert str(e.value).endswith(": must be a sequence of numbers")


def test_road_loads_on_the_flat_and_on_a_slope() -> None:
    v = default_params().vehicle
    g = 9.81  # core.units.GRAVITY
    assert v.k_v() == pytest.approx(v.f_r * v.M_v * g, rel=1e-15)
    assert v.k_w() == pytest.approx(v.mu_tyre * v.drive_axle_load_fraction * v.M_v * g, rel=1e-15)
    a = 0.3
    assert v.k_v(a) == pytest.approx(v.f_r * v.M_v * g * math.cos(a), rel=1e-15)
    assert v.k_w(a) == pytest.approx(
        v.mu_tyre * v.drive_axle_load_fraction * v.M_v * g * math.cos(a), rel=1e-15
    )


#: the documented range of every numeric field: (path, min, min inclusive, max, max inclusive);
#: written out here (not read from the module's metadata) so that a changed bound is noticed
BOUNDS: list[tuple[str, float | None, bool, float | None, bool]] = [
    ("engine.J1", 0.0, False, None, True),
    ("engine.K", 0.0, False, None, True),
    ("engine.tau_p", 0.0, False, None, True),
    ("engine.b1", 0.0, True, None, True),
    ("engine.c1", 0.0, True, None, True),
    ("engine.static_ratio", 1.0, True, 3.0, True),
    ("clutch.J2", 0.0, False, None, True),
    ("clutch.b2", 0.0, True, None, True),
    ("clutch.k12_max", 0.0, False, None, True),
    ("clutch.static_ratio", 1.0, True, 3.0, True),
    ("damper.J3", 0.0, False, None, True),
    ("damper.b3", 0.0, True, None, True),
    ("damper.k23", 0.0, True, None, True),
    ("damper.static_ratio", 1.0, True, 3.0, True),
    ("gearbox.D_c", 0.0, False, None, True),
    ("gearbox.J4", 0.0, False, None, True),
    ("gearbox.b4", 0.0, True, None, True),
    ("gearbox.h34", 0.0, False, None, True),
    ("gearbox.b34", 0.0, True, None, True),
    ("gearbox.g34_wheel", 0.0, True, None, True),
    ("driveline.h45", 0.0, False, None, True),
    ("driveline.b45", 0.0, True, None, True),
    ("driveline.h56", 0.0, False, None, True),
    ("driveline.b56", 0.0, False, None, True),
    ("driveline.J5", 0.0, False, None, True),
    ("driveline.b5", 0.0, True, None, True),
    ("driveline.tread_fraction", 0.0, False, 1.0, False),
    ("driveline.R_p", 0.0, False, None, True),
    ("vehicle.M_v", 0.0, False, None, True),
    ("vehicle.C_x", 0.0, True, None, True),
    ("vehicle.S", 0.0, True, None, True),
    ("vehicle.rho_a", 0.0, True, None, True),
    ("vehicle.f_r", 0.0, True, 1.0, False),
    ("vehicle.b_v", 0.0, True, None, True),
    ("vehicle.mu_tyre", 0.0, False, 2.0, True),
    ("vehicle.drive_axle_load_fraction", 0.0, False, 1.0, True),
    ("vehicle.rolling_static_ratio", 1.0, True, 3.0, True),
    ("vehicle.tyre_static_ratio", 1.0, True, 3.0, True),
    ("brake.capacity_max", 0.0, True, None, True),
    ("brake.static_ratio", 1.0, True, 3.0, True),
    ("actuator.omega_a", 0.0, False, None, True),
    ("actuator.delta_a", 0.0, False, None, True),
]


def _with(path: str, value: object) -> dict[str, Any]:
    d = _base()
    sec, _, key = path.partition(".")
    d[sec][key] = value
    return d


def _accepts(path: str, value: float) -> bool:
    try:
        p = params_from_dict(_with(path, value))
    except ParameterError as exc:
        assert str(exc).startswith(f"{path} = "), str(exc)
        return False
    assert p.get(path) == value
    return True


@pytest.mark.parametrize(("path", "lo", "lo_in", "hi", "hi_in"), BOUNDS, ids=[b[0] for b in BOUNDS])
def test_every_bound_is_checked_at_its_exact_value(
    path: str, lo: float | None, lo_in: bool, hi: float | None, hi_in: bool
) -> None:
    info = field_info(path)
    assert (info["min"], info["min_inclusive"], info["max"], info["max_inclusive"]) == (
        lo,
        lo_in,
        hi,
        hi_in,
    )
    if lo is not None:
        assert _accepts(path, lo) is lo_in
        assert _accepts(path, lo - 1e-6) is False
    if hi is not None:
        assert _accepts(path, hi) is hi_in
        assert _accepts(path, hi + 1e-6) is False


def test_the_table_covers_every_numeric_field() -> None:
    numeric = [p for p in field_paths() if field_info(p)["kind"] == "float"]
    bounded = [p for p in numeric if field_info(p)["min"] is not None or field_info(p)["max"]]
    assert sorted(bounded) == sorted(b[0] for b in BOUNDS)


@pytest.mark.parametrize(
    ("path", "default"),
    [
        ("engine.static_ratio", 1.0),
        ("clutch.static_ratio", 1.0),
        ("damper.static_ratio", 1.0),
        ("driveline.b5", 0.0),
        ("vehicle.rolling_static_ratio", 1.0),
        ("vehicle.tyre_static_ratio", 1.0),
        ("brake.static_ratio", 1.0),
    ],
)
def test_optional_fields_take_their_default(path: str, default: float) -> None:
    d = _base()
    sec, _, key = path.partition(".")
    del d[sec][key]
    assert params_from_dict(d).get(path) == default
    info = field_info(path)
    assert info["optional"] is True and info["default"] == default


def test_a_required_field_is_not_optional() -> None:
    info = field_info("engine.J1")
    assert info["optional"] is False and info["default"] is None
    d = _base()
    del d["engine"]["J1"]
    with pytest.raises(ParameterError, match=r"engine\.J1"):
        params_from_dict(d)


def test_the_sections_are_frozen() -> None:
    p = default_params()
    for sec in (
        "engine",
        "clutch",
        "damper",
        "gearbox",
        "driveline",
        "vehicle",
        "brake",
        "actuator",
    ):
        s = getattr(p, sec)
        name = next(iter(dataclasses.fields(s))).name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(s, name, 1.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.name = "x"  # type: ignore[misc]


def test_a_flat_piece_of_the_damper_spring_is_rejected() -> None:
    d = _base()
    d["damper"]["spring"] = {"x": [0.0, 0.1, 0.2], "y": [0.0, 50.0, 50.0]}
    with pytest.raises(ParameterError, match=r"phi_e must be strictly increasing"):
        params_from_dict(d)
    d["damper"]["spring"] = {"x": [0.0, 0.1, 0.2], "y": [0.0, 50.0, 50.000001]}
    assert params_from_dict(d).damper.spring.y[2] == 50.000001


def test_a_long_offending_value_is_cut_to_80_characters() -> None:
    for n, cut in ((78, False), (79, True), (100, True)):  # repr adds the two quotes
        text = "x" * n
        d = _base()
        d["gearbox"]["gear_ratios"] = text
        with pytest.raises(ParameterError) as e:
            params_from_dict(d)
        shown = repr(text)[:77] + "..." if cut else repr(text)
        assert str(e.value) == f"gearbox.gear_ratios = {shown}: must be a sequence of numbers"
        assert len(shown) == 80  # at most 80 characters shown


def test_a_pedal_map_in_newton_metres_is_stored_as_its_shape() -> None:
    """A map whose values are k12 [N m] (above 1) reaching k12_max is divided by k12_max."""
    d = _base()
    k12 = d["clutch"]["k12_max"]
    shape = list(d["clutch"]["pedal_map"]["y"])
    assert max(shape) == 1.0 and k12 != 1.0
    d["clutch"]["pedal_map"]["y"] = [k12 * y for y in shape]
    pm = params_from_dict(d).clutch.pedal_map
    assert list(pm.y) == pytest.approx(shape, rel=1e-15, abs=1e-15)
    assert tuple(pm.x) == tuple(d["clutch"]["pedal_map"]["x"])


def test_every_section_is_frozen_slotted_and_keyword_only() -> None:
    p = default_params()
    for f in dataclasses.fields(p):
        section = getattr(p, f.name)
        if not dataclasses.is_dataclass(section):
            continue
        first = dataclasses.fields(section)[0].name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(section, first, getattr(section, first))
        assert not hasattr(section, "__dict__"), f.name
        values = [getattr(section, g.name) for g in dataclasses.fields(section)]
        with pytest.raises(TypeError):
            type(section)(*values)
