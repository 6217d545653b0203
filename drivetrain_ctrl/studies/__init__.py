"""Batch work: one picklable :class:`Case` (scenario, parameter set and overrides, model,
controller, tolerance) run by :func:`run_case` to one flat record of metrics; the CLI, the
controller report and the studies all run cases through it."""

from __future__ import annotations

from .case import MODELS, Case, CaseError, CaseRun, run_case, simulate_case

__all__ = ["Case", "CaseError", "CaseRun", "MODELS", "run_case", "simulate_case"]
