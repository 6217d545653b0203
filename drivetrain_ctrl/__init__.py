"""drivetrain_ctrl: model, simulate and control a dry-clutch car drivetrain.

The public API, re-exported flat (``from drivetrain_ctrl import simulate, default_params``). The
sub-packages are layers, each importing only those below it: :mod:`~drivetrain_ctrl.core`,
:mod:`~drivetrain_ctrl.kernels`, :mod:`~drivetrain_ctrl.plant`, :mod:`~drivetrain_ctrl.control`,
:mod:`~drivetrain_ctrl.scenarios`, :mod:`~drivetrain_ctrl.sim` and :mod:`~drivetrain_ctrl.linear`,
:mod:`~drivetrain_ctrl.design` and :mod:`~drivetrain_ctrl.studies`,
:mod:`~drivetrain_ctrl.reporting` (the only matplotlib importer), :mod:`~drivetrain_ctrl.cli`.
"""

from __future__ import annotations

from .control import (
    Actuator,
    Controller,
    ControllerSpec,
    builtin_controllers,
    load_controller,
    save_controller,
)
from .core import signals
from .core.tables import PwlTable
from .linear import (
    OperatingPoint,
    clutch_loop,
    clutch_loop_margins,
    linearise,
    locked_trim,
    loop_margins,
    operating_point_from_result,
    root_locus,
    slip_operating_point,
)
from .plant import (
    Body,
    Chain,
    Coupling,
    Drivetrain,
    DrivetrainParams,
    Friction,
    Mode,
    Model,
    Spring,
    default_params,
    full_model,
    load_params,
    reduced_model,
)
from .scenarios import Scenario, builtin_scenarios, load_scenario
from .sim import (
    SimulationOptions,
    SimulationResult,
    engagement_metrics,
    run_scenario,
    simulate,
)
from .studies import Case, run_case

__version__ = "0.1.0"

__all__ = [
    "Actuator",
    "Body",
    "Case",
    "Chain",
    "Controller",
    "ControllerSpec",
    "Coupling",
    "Drivetrain",
    "DrivetrainParams",
    "Friction",
    "Mode",
    "Model",
    "OperatingPoint",
    "PwlTable",
    "Scenario",
    "SimulationOptions",
    "SimulationResult",
    "Spring",
    "builtin_controllers",
    "builtin_scenarios",
    "clutch_loop",
    "clutch_loop_margins",
    "default_params",
    "engagement_metrics",
    "full_model",
    "linearise",
    "load_controller",
    "load_params",
    "load_scenario",
    "locked_trim",
    "loop_margins",
    "operating_point_from_result",
    "reduced_model",
    "root_locus",
    "run_case",
    "run_scenario",
    "save_controller",
    "signals",
    "simulate",
    "slip_operating_point",
]
