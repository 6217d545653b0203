"""Batch work: one picklable :class:`Case` (scenario, parameter set and overrides, model,
controller, tolerance) run by :func:`run_case` to one flat record of metrics; the CLI, the
controller report and the studies all run cases through it. Robustness studies:
:mod:`~drivetrain_ctrl.studies.study` (the TOML definition and the samples) and
:mod:`~drivetrain_ctrl.studies.runner` (:func:`run_study` on Dask, Parquet results, resume;
imported on first use, as it loads Dask)."""

from __future__ import annotations

from typing import Any

from .case import MODELS, Case, CaseError, CaseRun, run_case, simulate_case
from .study import Study, StudyError, load_study, sample_table

__all__ = [
    "Case",
    "CaseError",
    "CaseRun",
    "MODELS",
    "Study",
    "StudyError",
    "StudyRun",
    "load_study",
    "read_results",
    "run_case",
    "run_study",
    "sample_table",
    "simulate_case",
]

_LAZY = ("StudyRun", "read_results", "run_study")


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        from . import runner

        return getattr(runner, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
