"""Simulation of the switching plant: the exact event-driven simulator, running a scenario, the
engagement figures of merit and the kernel warm-up."""

from __future__ import annotations

from .metrics import METRIC_KEYS, METRICS, MetricInfo, engagement_metrics, state_accelerations
from .run import run_scenario
from .simulator import (
    Event,
    InputRangeError,
    SimulationOptions,
    SimulationResult,
    ZenoError,
    simulate,
)

__all__ = [
    "SimulationOptions",
    "SimulationResult",
    "Event",
    "ZenoError",
    "InputRangeError",
    "simulate",
    "run_scenario",
    "engagement_metrics",
    "state_accelerations",
    "METRIC_KEYS",
    "METRICS",
    "MetricInfo",
]
