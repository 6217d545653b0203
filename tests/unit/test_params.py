"""Tests of drivetrain_ctrl.params: loading, validation, round trip, tables, derived values."""

from __future__ import annotations

import copy
import dataclasses
import math
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomli_w

from drivetrain_ctrl.core.units import GRAVITY
from drivetrain_ctrl.plant.params import (
    DEFAULT_SET,
    FRAMES,
    DrivetrainParams,
    ParameterError,
    ParameterSectionWarning,
    Table,
    available_parameter_sets,
    default_params,
    field_info,
    field_paths,
    load_params,
    params_from_dict,
    params_to_dict,
    save_params,
)


@pytest.fixture(scope="module")
def p() -> DrivetrainParams:
    return default_params()


def _base_dict() -> dict[str, Any]:
    return copy.deepcopy(params_to_dict(default_params()))


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "params.toml"
    path.write_text(tomli_w.dumps(data), encoding="utf-8")
    return path


# --------------------------------------------------------------------------------------------------
# built-in sets, round trip, derived values
# --------------------------------------------------------------------------------------------------


def test_passenger_car_is_available() -> None:
    assert "passenger-car" in available_parameter_sets()


@pytest.mark.parametrize("name", available_parameter_sets())
def test_every_set_loads_and_round_trips(name: str, tmp_path: Path) -> None:
    p = load_params(name)
    assert isinstance(p, DrivetrainParams)
    assert p.name == name
    path = save_params(p, tmp_path / "sub" / f"{name}.toml")
    q = load_params(path)
    assert q == p
    assert params_from_dict(params_to_dict(p)) == p
    assert load_params(str(path)) == p  # a str path works as well


@pytest.mark.parametrize("name", available_parameter_sets())
def test_every_set_has_provenance_for_every_field(name: str) -> None:
    prov = load_params(name).provenance_dict()
    assert set(prov) == set(field_paths())
    assert all(text.strip() for text in prov.values())


def test_default_params_is_the_passenger_car(p: DrivetrainParams) -> None:
    assert p == load_params("passenger-car")
    assert p.engine.J1 == 0.2 and p.clutch.k12_max == 250.0 and p.vehicle.M_v == 1300.0
    assert p.gearbox.gear_ratios == (3.4, 2.2, 1.5, 1.1, 0.9)
    assert p.actuator.omega_a == 200.0


def test_pedal_map_default(p: DrivetrainParams) -> None:
    pm = p.clutch.pedal_map  # the shape k12/k12_max; the capacity is k12_max * pm(x_c)
    assert p.clutch.k12_max * pm(0.07) == 62.5
    assert len(pm.x) == 17
    xs = np.linspace(0.0, 0.15, 61)
    expected = 250.0 * np.clip((0.11 - xs) / 0.08, 0.0, 1.0) ** 2
    # piecewise-linear interpolation of the quadratic: exact at knots, close in between
    np.testing.assert_allclose(p.clutch.k12_max * pm(xs), expected, atol=1.0)
    assert pm(0.0) == 1.0 and pm(0.2) == 0.0  # clamped beyond the ends


def test_derived_ratios_and_backlash(p: DrivetrainParams) -> None:
    assert p.gearbox.tau_r(1) == 3.4
    assert p.gearbox.tau_t(1) == pytest.approx(11.56)
    assert p.gearbox.tau_t(5) == pytest.approx(0.9 * 3.4)
    assert p.gearbox.g34_primary(1) == pytest.approx(0.3468)
    assert p.gearbox.n_gears == 5


def test_road_load_forces(p: DrivetrainParams) -> None:
    assert p.vehicle.k_w(0.0) == pytest.approx(0.8 * 0.6 * 1300.0 * 9.81)
    assert p.vehicle.k_w() == pytest.approx(6121.44)
    assert p.vehicle.k_v(0.0) == pytest.approx(0.015 * 1300.0 * GRAVITY)
    alpha = math.radians(10.0)
    assert p.vehicle.k_v(alpha) == pytest.approx(0.015 * 1300.0 * 9.81 * math.cos(alpha))


@pytest.mark.parametrize("gear", [0, 6, -1, 1.5, "1", True])
def test_invalid_gear_raises(p: DrivetrainParams, gear: Any) -> None:
    for method in (p.gearbox.tau_r, p.gearbox.tau_t, p.gearbox.g34_primary):
        with pytest.raises(ValueError, match=r"gear") as exc:
            method(gear)
        assert repr(gear) in str(exc.value) and "1..5" in str(exc.value)


# --------------------------------------------------------------------------------------------------
# tables
# --------------------------------------------------------------------------------------------------


def test_damper_spring_is_odd_and_linear_beyond_last_knot(p: DrivetrainParams) -> None:
    sp = p.damper.spring
    assert sp(0.0) == 0.0
    assert sp(0.035) == pytest.approx(1.75)
    assert sp(0.14) == pytest.approx(159.25)
    assert sp(0.3) == pytest.approx(159.25 + 1e5 * 0.16)  # stop slope continued
    v = np.array([-0.3, -0.1, 0.1, 0.3])
    np.testing.assert_allclose(sp(v), -sp(-v))


def test_mu_table_flat_and_even(p: DrivetrainParams) -> None:
    mu = p.clutch.mu_table
    assert mu(0.0) == 1.0 and mu(123.0) == 1.0 and mu(-50.0) == 1.0
    falling = Table((0.0, 50.0), (1.0, 0.9))
    q = p.replace(**{"clutch.mu_table": falling})
    assert q.clutch.mu_table(25.0) == pytest.approx(0.95)
    assert q.clutch.mu_table(-25.0) == pytest.approx(0.95)
    assert q.clutch.mu_table(500.0) == pytest.approx(0.9)  # clamped
    assert q.clutch.mu_table.x_name == "slip"  # plain table relabelled with the field's axes


def test_table_arrays_and_shapes(p: DrivetrainParams) -> None:
    pm = p.clutch.pedal_map
    xa = pm.x_array()
    assert isinstance(xa, np.ndarray) and xa.shape == (17,)
    xa[0] = 99.0  # a copy: the table is unchanged
    assert pm.x[0] == 0.03
    out = pm(np.full((2, 3), 0.07))
    assert out.shape == (2, 3) and np.all(out == 0.25)
    assert isinstance(pm(0.07), float)


@pytest.mark.parametrize(
    ("x", "y", "match"),
    [
        ((0.0, 0.0), (1.0, 2.0), "strictly increasing"),
        ((0.0, 1.0), (1.0,), "same length"),
        ((), (), "at least one"),
        ((0.0, float("nan")), (1.0, 2.0), "nan"),
        ((0.0, "a"), (1.0, 2.0), "'a'"),
    ],
)
def test_table_rejects_bad_knots(x: Any, y: Any, match: str) -> None:
    with pytest.raises(ParameterError, match=match):
        Table(x, y)


def test_table_with_wrong_labels_is_rejected(p: DrivetrainParams) -> None:
    bad = Table(
        (0.0, 0.1),
        (0.0, 10.0),
        x_name="theta_d",
        x_unit="rad",
        y_name="phi_e",
        y_unit="N m",
        extrapolation="linear",
        symmetry="odd",
    )
    with pytest.raises(ParameterError, match="clutch.pedal_map"):
        p.replace(**{"clutch.pedal_map": bad})


# --------------------------------------------------------------------------------------------------
# bad inputs in files
# --------------------------------------------------------------------------------------------------


def _set(section: str, key: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def mutate(d: dict[str, Any]) -> None:
        d[section][key] = value

    return mutate


def _rename(section: str, old: str, new: str) -> Callable[[dict[str, Any]], None]:
    def mutate(d: dict[str, Any]) -> None:
        d[section][new] = d[section].pop(old)

    return mutate


def _delete(section: str, key: str) -> Callable[[dict[str, Any]], None]:
    def mutate(d: dict[str, Any]) -> None:
        del d[section][key]

    return mutate


def _pedal_increasing(d: dict[str, Any]) -> None:
    d["clutch"]["pedal_map"] = {"x": [0.03, 0.05, 0.06, 0.11], "y": [250.0, 10.0, 20.0, 0.0]}


def _pedal_in_nm_above_k12_max(d: dict[str, Any]) -> None:
    """The older form, k12 [N m] at the knots, reaching 250 N m with k12_max = 200 N m."""
    d["clutch"]["pedal_map"]["y"] = [250.0 * y for y in d["clutch"]["pedal_map"]["y"]]
    d["clutch"]["k12_max"] = 200.0


def _unknown_section(d: dict[str, Any]) -> None:
    d["enigne"] = {"J1": 0.2}


def _bad_provenance(d: dict[str, Any]) -> None:
    d["provenance"]["engine.J7"] = "made up"


def _table_key(d: dict[str, Any]) -> None:
    d["clutch"]["pedal_map"]["z"] = [1.0]


BAD_FILES = {
    "misspelt key": (_rename("engine", "J1", "J_1"), ["engine.J_1", "did you mean 'J1'"]),
    "misspelt key case": (_rename("vehicle", "M_v", "m_v"), ["vehicle.m_v", "'M_v'"]),
    "unknown section": (_unknown_section, ["enigne", "unknown section", "'engine'"]),
    "missing key": (_delete("clutch", "k12_max"), ["clutch.k12_max", "missing"]),
    "missing required table": (_delete("damper", "spring"), ["damper.spring", "missing"]),
    "nan": (_set("engine", "K", float("nan")), ["engine.K", "nan"]),
    "inf": (_set("vehicle", "M_v", float("inf")), ["vehicle.M_v", "inf"]),
    "negative inertia": (_set("engine", "J1", -0.2), ["engine.J1 = -0.2", "> 0", "kg m^2"]),
    "zero inertia": (_set("driveline", "J5", 0.0), ["driveline.J5 = 0", "> 0"]),
    "string for number": (_set("driveline", "R_p", "0.3"), ["driveline.R_p", "'0.3'"]),
    "bool for number": (_set("vehicle", "f_r", True), ["vehicle.f_r", "True"]),
    "pedal map increasing": (
        _pedal_increasing,
        ["clutch.pedal_map", "non-increasing", "k12(0.05)=10 < k12(0.06)=20"],
    ),
    "pedal map in N m above k12_max": (
        _pedal_in_nm_above_k12_max,
        ["clutch.pedal_map", "clutch.k12_max = 200", "250"],
    ),
    "pedal map unknown column": (_table_key, ["clutch.pedal_map.z", "unknown key"]),
    "spring not starting at 0": (
        _set("damper", "spring", {"x": [0.01, 0.1], "y": [0.0, 100.0]}),
        ["damper.spring", "0.01"],
    ),
    "spring not monotone": (
        _set("damper", "spring", {"x": [0.0, 0.1, 0.2], "y": [0.0, 100.0, 90.0]}),
        ["damper.spring", "phi_e(0.2)=90"],
    ),
    "mu first y not 1": (
        _set("clutch", "mu_table", {"x": [0.0, 50.0], "y": [0.9, 0.8]}),
        ["clutch.mu_table", "0.9"],
    ),
    "mu first x not 0": (
        _set("clutch", "mu_table", {"x": [5.0], "y": [1.0]}),
        ["clutch.mu_table", "5"],
    ),
    "mu not positive": (
        _set("clutch", "mu_table", {"x": [0.0, 50.0], "y": [1.0, 0.0]}),
        ["clutch.mu_table", "mu_ratio(50)=0"],
    ),
    "provenance names no field": (_bad_provenance, ["engine.J7", "names no parameter"]),
    "negative gear ratio": (
        _set("gearbox", "gear_ratios", [3.4, 2.2, -1.5]),
        ["gearbox.gear_ratios[2] = -1.5"],
    ),
    "no gears": (_set("gearbox", "gear_ratios", []), ["gearbox.gear_ratios"]),
    "static ratio too large": (_set("clutch", "static_ratio", 3.5), ["clutch.static_ratio = 3.5"]),
    "static ratio below 1": (
        _set("vehicle", "tyre_static_ratio", 0.9),
        ["vehicle.tyre_static_ratio = 0.9", ">= 1"],
    ),
    "tread fraction 1": (
        _set("driveline", "tread_fraction", 1.0),
        ["driveline.tread_fraction = 1"],
    ),
    "b56 zero": (_set("driveline", "b56", 0.0), ["driveline.b56 = 0"]),
    "f_r 1": (_set("vehicle", "f_r", 1.0), ["vehicle.f_r = 1", "< 1"]),
    "mu_tyre above 2": (_set("vehicle", "mu_tyre", 2.5), ["vehicle.mu_tyre = 2.5"]),
    "bad torque model": (_set("engine", "torque_model", "mapp"), ["engine.torque_model", "'mapp'"]),
    "map without curve": (
        lambda d: (d["engine"].pop("full_load_curve"), d["engine"].update(torque_model="map")),
        ["engine.full_load_curve", "map"],
    ),
    "stroke reversed": (_set("actuator", "x_max", -0.1), ["actuator.x_max = -0.1"]),
    "section not a table": (_set("meta", "name", 3), ["meta.name = 3"]),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_bad_file_raises_naming_field_and_value(case: str, tmp_path: Path) -> None:
    mutate, fragments = BAD_FILES[case]
    data = _base_dict()
    mutate(data)
    path = _write(tmp_path, data)
    with pytest.raises(ParameterError) as exc:
        load_params(path)
    message = str(exc.value)
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"
    assert str(path) in message  # the file is named too
    with pytest.raises(ParameterError):  # the same error without the file layer
        params_from_dict(data)


def test_missing_section_raises(tmp_path: Path) -> None:
    data = _base_dict()
    del data["actuator"]
    with pytest.raises(ParameterError, match=r"actuator: missing section"):
        load_params(_write(tmp_path, data))


def test_law6_is_not_a_plant_parameter() -> None:
    assert not any(path.startswith("law6.") for path in field_paths())
    assert "law6" not in params_to_dict(default_params())
    with pytest.raises(ParameterError, match=r"law6\.k_r: unknown parameter"):
        default_params().replace(**{"law6.k_r": 1e-4})


def test_an_old_file_with_a_law6_section_loads_with_a_warning_naming_it(tmp_path: Path) -> None:
    """Law (6)'s gains are controller settings (k_r, x_r0 of a controller file): an older
    parameter file's [law6] section and its provenance entries are ignored, with a warning that
    names the section, its values and where they belong now."""
    data = _base_dict()
    data["law6"] = {"x_r0": 0.06, "k_r": 5e-4}
    data["provenance"]["law6.k_r"] = "the paper, Section IV"
    with pytest.warns(
        ParameterSectionWarning,
        match=r"law6: section \[law6\] \(x_r0 = 0\.06, k_r = 0\.0005\) ignored.*controller file",
    ) as rec:
        p = load_params(_write(tmp_path, data))
    assert len(rec) == 1 and issubclass(ParameterSectionWarning, FutureWarning)
    assert p == default_params()
    # without the section: no warning
    del data["law6"], data["provenance"]["law6.k_r"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert load_params(_write(tmp_path, data)) == default_params()


def test_invalid_toml_raises(tmp_path: Path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text("[engine\nJ1 = ", encoding="utf-8")
    with pytest.raises(ParameterError, match="invalid TOML"):
        load_params(path)


def test_unknown_set_name_lists_available() -> None:
    with pytest.raises(ValueError, match="passenger-car") as exc:
        load_params("passenger-cra")
    assert not isinstance(exc.value, ParameterError)
    assert "did you mean 'passenger-car'" in str(exc.value)


def test_default_names_the_default_set() -> None:
    # "default" is an alias of DEFAULT_SET (the set default_params() loads), not a set of its own
    assert "default" not in available_parameter_sets()
    assert DEFAULT_SET in available_parameter_sets()
    p = load_params("default")
    assert p == load_params(DEFAULT_SET) == default_params()
    assert p.name == DEFAULT_SET
    with pytest.raises(ValueError, match=r"'default' = 'passenger-car'"):
        load_params("defualt")


def test_missing_file_raises(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        load_params(tmp_path / "nope.toml")


def test_optional_fields_may_be_omitted(tmp_path: Path, p: DrivetrainParams) -> None:
    data = _base_dict()
    for section in ("engine", "clutch", "damper", "brake"):
        del data[section]["static_ratio"]
    del data["vehicle"]["rolling_static_ratio"]
    del data["vehicle"]["tyre_static_ratio"]
    del data["clutch"]["mu_table"]
    del data["driveline"]["b5"]
    del data["engine"]["full_load_curve"]  # allowed with torque_model = "linear"
    del data["provenance"]
    q = load_params(_write(tmp_path, data))
    assert q.clutch.static_ratio == 1.0 and q.vehicle.tyre_static_ratio == 1.0
    assert q.clutch.mu_table == p.clutch.mu_table
    assert q.driveline.b5 == 0.0
    assert q.engine.full_load_curve is None
    assert q.provenance == ()
    assert q == p.replace(**{"engine.full_load_curve": None, "provenance": ()})
    path = save_params(q, tmp_path / "q.toml")  # None is left out of the file
    assert load_params(path) == q


def test_integers_in_file_become_floats(tmp_path: Path, p: DrivetrainParams) -> None:
    data = _base_dict()
    data["engine"]["K"] = 150
    data["gearbox"]["gear_ratios"] = [3, 2]
    q = load_params(_write(tmp_path, data))
    assert isinstance(q.engine.K, float) and q.engine.K == 150.0
    assert q.gearbox.gear_ratios == (3.0, 2.0)
    assert all(isinstance(g, float) for g in q.gearbox.gear_ratios)


# --------------------------------------------------------------------------------------------------
# immutability, replace, metadata
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("target", "attribute"),
    [
        (lambda p: p, "name"),
        (lambda p: p.engine, "J1"),
        (lambda p: p.clutch.pedal_map, "x"),
        (lambda p: p.gearbox, "new_attribute"),
    ],
)
def test_objects_are_immutable(p: DrivetrainParams, target: Any, attribute: str) -> None:
    obj = target(p)
    # FrozenInstanceError is an AttributeError; for a name that is not a field CPython 3.11 raises
    # TypeError from the frozen, slotted __setattr__ (a known CPython quirk): either way it fails.
    with pytest.raises((AttributeError, TypeError)):
        setattr(obj, attribute, 1.0)
    assert getattr(obj, attribute, None) != 1.0
    assert not hasattr(obj, "__dict__")  # slotted


def test_replace_returns_new_validated_object(p: DrivetrainParams) -> None:
    q = p.replace(**{"clutch.k12_max": 300.0, "engine.J1": 0.25, "name": "variant"})
    assert q.clutch.k12_max == 300.0 and q.engine.J1 == 0.25 and q.name == "variant"
    assert p.clutch.k12_max == 250.0 and p.engine.J1 == 0.2  # original untouched
    assert q.damper == p.damper
    assert p.with_values({"clutch.k12_max": 300.0}) == p.replace(**{"clutch.k12_max": 300.0})
    assert q.get("clutch.k12_max") == 300.0
    with pytest.raises(ParameterError, match=r"engine.J1 = -1"):
        p.replace(**{"engine.J1": -1.0})
    with pytest.raises(ParameterError, match=r"clutch.k12max.*did you mean 'clutch.k12_max'"):
        p.replace(**{"clutch.k12max": 300.0})
    with pytest.raises(ParameterError, match="nonsense"):
        p.replace(nonsense=1.0)


def test_direct_construction_validates(p: DrivetrainParams) -> None:
    with pytest.raises(ParameterError, match=r"engine.tau_p = 0: must be > 0 \[s\]"):
        dataclasses.replace(p.engine, tau_p=0.0)
    with pytest.raises(ParameterError, match=r"provenance.*engine.J_1"):
        dataclasses.replace(p, provenance={"engine.J_1": "x"})
    with pytest.raises(ParameterError, match="engine"):
        dataclasses.replace(p, engine=p.clutch)


def test_provenance_is_canonical(p: DrivetrainParams) -> None:
    shuffled = dict(reversed(p.provenance))
    q = p.replace(provenance=shuffled)
    assert q == p
    assert q.provenance_dict()["engine.J1"].startswith("Glielmo & Vasca")


def test_field_info_metadata() -> None:
    info = field_info("engine.J1")
    assert info["unit"] == "kg m^2" and info["frame"] == "engine"
    assert info["min"] == 0.0 and info["min_inclusive"] is False and info["max"] is None
    assert field_info("gearbox.g34_wheel")["frame"] == "wheel"
    assert field_info("gearbox.J4")["frame"] == "secondary"
    assert field_info("damper.spring")["extrapolation"] == "linear"
    for path in field_paths():
        info = field_info(path)
        assert info["frame"] in FRAMES, path
        assert info["unit"] and info["description"], path
    with pytest.raises(ParameterError, match="did you mean 'engine.J1'"):
        field_info("engine.j1")


def test_outside_stroke_names_the_field_and_the_stroke() -> None:
    act = default_params().actuator
    assert act.outside_stroke("x", act.x_min) is None
    assert act.outside_stroke("x", act.x_max) is None
    msg = act.outside_stroke("controller.pedal0", act.x_max + 0.01)
    assert msg is not None and msg.startswith("controller.pedal0 = ")
    assert "actuator stroke" in msg and str(act.x_max) in msg
    assert act.outside_stroke("x", float("nan")) is not None


@pytest.mark.parametrize("source", [3.5, None, ["default"]])
def test_a_source_that_is_neither_a_name_nor_a_path_is_named(source: object) -> None:
    with pytest.raises(TypeError, match=r"^source = .*: a parameter set name or a path"):
        load_params(source)  # type: ignore[arg-type]
