"""Controllers as data: the blocks the simulator runs (LTI + explicit nonlinear blocks) and the clutch
start laws (law (6), PI, any LTI law) declared as :class:`ControllerSpec`, loaded from and saved to
TOML files."""

from __future__ import annotations

from .blocks import Actuator, Controller, LatchRamp, actuator_tf
from .laws import (
    ControllerError,
    ControllerSpec,
    UnstableLoopWarning,
    builtin_controllers,
    law6_controller,
    law6_defaults,
    law6_loop_closed_form,
    load_controller,
    pi_controller,
    save_controller,
    spec_from_lti,
)

__all__ = [
    "Actuator",
    "Controller",
    "LatchRamp",
    "actuator_tf",
    "ControllerSpec",
    "ControllerError",
    "UnstableLoopWarning",
    "builtin_controllers",
    "load_controller",
    "law6_controller",
    "law6_defaults",
    "law6_loop_closed_form",
    "pi_controller",
    "save_controller",
    "spec_from_lti",
]
