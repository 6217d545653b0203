"""The plant: the chain of bodies and couplings, its compiled model (modes, dynamics, energy), the
car drivetrain of the paper's Sections II-III and its parameter sets."""

from __future__ import annotations

from .chain import (
    BACKLASH_MODES,
    FRICTION_MODES,
    Body,
    Chain,
    Coupling,
    Friction,
    LaggedSource,
    Spring,
)
from .drivetrain import (
    INPUTS,
    Drivetrain,
    clutch_friction,
    full_model,
    reduced_figures,
    reduced_model,
)
from .model import Mode, Model
from .params import (
    DrivetrainParams,
    ParameterError,
    available_parameter_sets,
    default_params,
    load_params,
    save_params,
)

__all__ = [
    "Body",
    "Chain",
    "Coupling",
    "Friction",
    "LaggedSource",
    "Spring",
    "FRICTION_MODES",
    "BACKLASH_MODES",
    "Model",
    "Mode",
    "Drivetrain",
    "clutch_friction",
    "full_model",
    "reduced_model",
    "reduced_figures",
    "INPUTS",
    "DrivetrainParams",
    "ParameterError",
    "default_params",
    "load_params",
    "save_params",
    "available_parameter_sets",
]
