"""Input checks of controller specs and files (:mod:`drivetrain_ctrl.controllers`) and of the
shared loader (:mod:`drivetrain_ctrl.loading`); no simulation."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path
from typing import Any

import control
import numpy as np
import pytest

from drivetrain_ctrl.control.laws import (
    _KEYS,
    ControllerError,
    ControllerSpec,
    UnstableLoopWarning,
    builtin_controllers,
    controller_from_dict,
    load_controller,
)
from drivetrain_ctrl.core.registry import load_toml_as
from drivetrain_ctrl.core.signals import constant
from drivetrain_ctrl.core.validate import is_finite_real, reject_unknown
from drivetrain_ctrl.plant.params import default_params

P = default_params()


def _build(spec: ControllerSpec) -> Any:
    return spec.build(P, reference=constant(150.0), start_time=0.5)


@pytest.mark.parametrize("name", ["", "   ", None, 3])
def test_name_must_be_a_non_empty_string(name: object) -> None:
    with pytest.raises(ControllerError, match="name"):
        ControllerSpec(name=name, law="paper")  # type: ignore[arg-type]


def test_pi_with_both_gains_zero_is_rejected() -> None:
    with pytest.raises(ControllerError, match=r"kp = 0\.0, ki = 0\.0"):
        ControllerSpec(name="dead", law="pi", kp=0.0, ki=0.0)
    # one zero gain is still a controller: C(s) = kp + ki / s
    for kp, ki in ((1e-3, 0.0), (0.0, 1e-3)):
        with warnings.catch_warnings():  # stable or not is not the point here
            warnings.simplefilter("ignore", UnstableLoopWarning)
            c = _build(ControllerSpec(name="one-gain", law="pi", kp=kp, ki=ki))
        assert complex(control.evalfr(c.lti, 2j)) == pytest.approx(kp + ki / 2j)


def test_x_r0_outside_the_actuator_stroke_is_rejected_at_build() -> None:
    act = P.actuator
    for x in (act.x_max + 0.01, act.x_min - 0.01):
        spec = ControllerSpec(name="off", law="paper", x_r0=x)  # within the spec's own range
        with pytest.raises(ControllerError, match=r"x_r0 = .*actuator stroke"):
            _build(spec)
    # the ends of the stroke are accepted (x_r0 is the law's offset)
    for x in (act.x_min, act.x_max):
        assert _build(ControllerSpec(name="edge", law="paper", x_r0=x)).offset == x


@pytest.mark.parametrize("v", [np.float32(3e-4), np.float64(3e-4), np.int64(0)])
def test_numpy_scalars_are_numbers(v: object) -> None:
    spec = ControllerSpec(name="np", law="pi", kp=v, ki=np.float32(1e-3))  # type: ignore[arg-type]
    assert spec.kp == v
    x_r0 = ControllerSpec(name="np", law="paper", x_r0=np.float32(0.07)).x_r0  # type: ignore[arg-type]
    assert x_r0 == pytest.approx(0.07)


@pytest.mark.parametrize("v", [True, "0.1", np.float32("nan"), float("inf"), None, 10**400])
def test_non_numbers_are_rejected_naming_the_field(v: object) -> None:
    with pytest.raises(ControllerError, match="engage_rate_m_s"):
        ControllerSpec(name="bad", law="paper", engage_rate_m_s=v)  # type: ignore[arg-type]


def test_is_finite_real() -> None:
    for ok in (1, 0.5, np.float32(0.5), np.float16(2), np.int8(3), np.float64(-1e300)):
        assert is_finite_real(ok), ok
    for bad in (True, np.bool_(True), "1", None, float("nan"), np.float32("inf"), 10**400, 1j):
        assert not is_finite_real(bad), bad


def test_keys_are_the_spec_fields_and_unknown_keys_are_named() -> None:
    assert {f.name for f in dataclasses.fields(ControllerSpec)} == _KEYS
    with pytest.raises(ControllerError, match=r"kpp: unknown key; did you mean 'kp'\?"):
        controller_from_dict({"law": "pi", "kpp": 1e-3, "ki": 1e-3})
    with pytest.raises(
        ControllerError, match=r"zzz: unknown key; allowed: \['A', 'B', 'C', 'D', 'anti_windup'"
    ):
        controller_from_dict({"law": "pi", "zzz": 1})
    with pytest.raises(ControllerError, match="law: missing"):
        controller_from_dict({"name": "x"})


def test_reject_unknown_uses_the_given_error_class() -> None:
    class MyError(ValueError):
        pass

    with pytest.raises(MyError, match=r"^sec\.abd: unknown key; did you mean 'abc'\?$"):
        reject_unknown("sec.", {"abc", "abd"}, {"abc"}, error=MyError)
    with pytest.raises(MyError, match=r"^sec\.b: unknown key; allowed: \['a'\]$"):
        reject_unknown("sec.", {"a", "b"}, {"a"}, error=MyError)
    reject_unknown("", {"a"}, {"a", "c"}, error=MyError)  # nothing unknown: no error


def test_load_toml_as_keeps_file_not_found(tmp_path: Path) -> None:
    # load_params documents FileNotFoundError for a missing file; the loader keeps it
    with pytest.raises(FileNotFoundError):
        load_toml_as(tmp_path / "missing.toml", dict, error=ControllerError)


def test_builtin_controllers_build() -> None:
    act = P.actuator
    for spec in builtin_controllers().values():
        c = _build(spec)
        assert c.name == spec.name and c.output == "pedal"
        assert c.saturation == (act.x_min, act.x_max)  # the actuator stroke
        assert c.is_discrete == (spec.sample_period_s is not None)


def test_build_checks_the_reference_and_start_time() -> None:
    spec = load_controller("paper")
    with pytest.raises(ControllerError, match="reference = 100.0: must be a Signal"):
        spec.build(P, reference=100.0)  # type: ignore[arg-type]
    with pytest.raises(ControllerError, match="start_time = 'now'"):
        spec.build(P, reference=constant(100.0), start_time="now")  # type: ignore[arg-type]


def test_spec_delay_samples_takes_numpy_integers() -> None:
    spec = ControllerSpec(
        name="d", law="paper", k_r=0.02, sample_period_s=0.01, delay_samples=np.int64(2)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableLoopWarning)  # stability is not the point here
        assert spec.build(P, reference=constant(100.0)).delay_samples == 2


# -- built-ins as TOML files (package data) ----------------------------------------------------


def test_builtin_controllers_are_the_files_in_control_builtin() -> None:
    from drivetrain_ctrl.control.laws import BUILTIN_ORDER
    from drivetrain_ctrl.core.registry import builtin_files

    files = builtin_files("drivetrain_ctrl.control", order=BUILTIN_ORDER)
    specs = builtin_controllers()
    assert list(specs) == list(files)
    assert list(specs)[: len(BUILTIN_ORDER)] == list(BUILTIN_ORDER)
    for name, f in files.items():
        assert specs[name] == load_controller(Path(str(f)))  # the same file through the loader
        assert specs[name].name == name


def test_law6_gains_live_in_the_paper_controller_file() -> None:
    """Law (6)'s gains are the paper's (Section IV): k_r = 3e-4 m s/rad, x_r0 = 0.07 m, written
    in control/builtin/paper.toml; a spec that leaves them out uses those."""
    from drivetrain_ctrl.control.laws import law6_defaults

    paper = builtin_controllers()["paper"]
    assert law6_defaults() == (paper.k_r, paper.x_r0) == (3e-4, 0.07)
    bare = ControllerSpec(name="bare", law="paper")
    assert bare.k_r is None and bare.x_r0 is None
    assert (bare.gain_k_r, bare.offset_x_r0) == law6_defaults()
    assert _build(bare).offset == 0.07
    assert complex(control.evalfr(_build(bare).lti, 1j)) == pytest.approx(3e-4)
    own = ControllerSpec(name="own", law="paper", k_r=1e-4, x_r0=0.06)
    assert (own.gain_k_r, own.offset_x_r0) == (1e-4, 0.06)
    assert _build(own).offset == 0.06
