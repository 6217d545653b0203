"""Figures and reports: the only layer that imports matplotlib."""

from __future__ import annotations

from .controller_report import Report, build_report
from .figures import (
    plot_energy,
    plot_engagement,
    plot_loop,
    plot_nyquist,
    plot_root_locus,
    plot_simulation,
)
from .study_report import StudyReport, build_study_report

__all__ = [
    "plot_simulation",
    "plot_energy",
    "plot_engagement",
    "plot_loop",
    "plot_nyquist",
    "plot_root_locus",
    "Report",
    "build_report",
    "StudyReport",
    "build_study_report",
]
