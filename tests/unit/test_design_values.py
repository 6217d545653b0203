"""Value tests of the design modules' documented defaults and boundaries (issue 22 item 4),
each killing a survivor of ``./dev mutate drivetrain_ctrl/design/<module>.py``."""

from __future__ import annotations

import dataclasses
import math

import control
import pytest

from drivetrain_ctrl.design.clutch import ClutchPlantSet
from drivetrain_ctrl.design.hinf import HinfSpec
from drivetrain_ctrl.design.pi import design_pi
from drivetrain_ctrl.design.plants import Plant


def test_hinf_spec_defaults() -> None:
    defaults = {f.name: f.default for f in dataclasses.fields(HinfSpec)}
    assert {
        k: defaults[k]
        for k in (
            "ms",
            "low_frequency_gain",
            "nominal",
            "reduction_tol",
            "keep_integrators",
            "time_limit",
            "gamma_backoff",
            "pade_order",
            "check_pade_order",
        )
    } == {
        "ms": 2.0,
        "low_frequency_gain": 1e-4,
        "nominal": 0,
        "reduction_tol": 0.05,
        "keep_integrators": True,
        "time_limit": 60.0,
        "gamma_backoff": 0.01,
        "pade_order": 3,
        "check_pade_order": 6,
    }


def test_a_clutch_plant_set_is_continuous_unless_sampled() -> None:
    s = ClutchPlantSet((Plant(control.tf([1.0], [1.0, 1.0])),))
    assert s.sample_period == 0.0 and s.points == ()


def test_a_pi_crossover_at_the_nyquist_frequency_is_rejected() -> None:
    dt = 0.01
    plant = control.tf([0.1], [1.0, -0.9], dt)
    with pytest.raises(ValueError, match="must be below the Nyquist frequency"):
        design_pi(plant, wc=math.pi / dt)
    design_pi(plant, wc=0.5 * math.pi / dt)  # below it: a design (feasible or not)


def test_a_parameter_box_must_be_a_mapping() -> None:
    from drivetrain_ctrl.design.clutch import _dims
    from drivetrain_ctrl.plant.params import default_params

    with pytest.raises(
        TypeError, match=r"^box = \[\('engine.J1', \(0.1, 0.2\)\)\]: must be a mapping"
    ):
        _dims([("engine.J1", (0.1, 0.2))], default_params())  # type: ignore[arg-type]


def test_the_negative_plant_hint_sees_through_a_discrete_integrator() -> None:
    # -0.01 / (z - 1): the gain with the integrator at z = 1 divided out is -0.01 < 0
    d = design_pi(control.tf([-0.01], [1.0, -1.0], 0.01), wc=1.0, phase_margin=60.0)
    assert not d.feasible and "low-frequency gain is negative" in d.message
    # +0.01 / (z - 1): positive, no hint
    pos = design_pi(control.tf([0.01], [1.0, -1.0], 0.01), wc=1.0, phase_margin=60.0)
    assert "negative" not in pos.message
