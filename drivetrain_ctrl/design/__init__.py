"""Controller design (PI from specifications, robust fixed-structure tuning, H-infinity, stability
certificates); it sits above :mod:`drivetrain_ctrl.linear` and below reporting.

Every tool takes any python-control LTI plant or a set of them (:mod:`.plants`: an exact input
delay per plant, automatic frequency grids), so it can be checked on textbook plants; the clutch
start loop is its first client.
"""

from __future__ import annotations

from drivetrain_ctrl.design.certificates import (
    ClutchSectorCertificate,
    LyapunovCertificate,
    SectorCertificate,
    clutch_sector_certificate,
    common_lyapunov,
    largest_sector,
    sampled_loop,
    sector_certificate,
    zoh_with_delay,
)
from drivetrain_ctrl.design.checks import LoopCheck, check_grid, check_loop, check_plant_set
from drivetrain_ctrl.design.clutch import ClutchPlantSet, clutch_plant_set
from drivetrain_ctrl.design.controllers import INTEGRATORS, pid_controller
from drivetrain_ctrl.design.hinf import (
    HinfDesign,
    HinfSpec,
    HinfSynthesisError,
    HinfTimeoutError,
    hinf_mixsyn,
    mixsyn_weights,
)
from drivetrain_ctrl.design.pi import PIDesign, design_pi, pi_controller_tf, pi_gains_at
from drivetrain_ctrl.design.plants import Plant, PlantSet, as_plant_set, frequency_grid
from drivetrain_ctrl.design.robust import (
    InfeasibleSpecError,
    RobustSpec,
    RobustTuning,
    UnboundedSpecError,
    robust_pi,
    robust_pid,
)

__all__ = [
    "Plant",
    "PlantSet",
    "as_plant_set",
    "frequency_grid",
    "LoopCheck",
    "check_loop",
    "check_plant_set",
    "check_grid",
    "INTEGRATORS",
    "pid_controller",
    "PIDesign",
    "design_pi",
    "pi_controller_tf",
    "pi_gains_at",
    "ClutchPlantSet",
    "clutch_plant_set",
    "RobustSpec",
    "RobustTuning",
    "InfeasibleSpecError",
    "UnboundedSpecError",
    "robust_pi",
    "robust_pid",
    "HinfSpec",
    "HinfDesign",
    "HinfTimeoutError",
    "HinfSynthesisError",
    "hinf_mixsyn",
    "mixsyn_weights",
    "LyapunovCertificate",
    "SectorCertificate",
    "ClutchSectorCertificate",
    "common_lyapunov",
    "sector_certificate",
    "largest_sector",
    "clutch_sector_certificate",
    "zoh_with_delay",
    "sampled_loop",
]
