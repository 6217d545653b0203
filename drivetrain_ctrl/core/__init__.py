"""Core: numpy-only building blocks shared by every layer (units, signals, the one table type,
input validation, JSON-ready numbers, loading built-ins or TOML files)."""

from __future__ import annotations

from .registry import builtin_files, load_builtin_or_toml, load_toml_as, read_toml
from .serialize import json_ready, round_sig
from .signals import Signal, constant, ramp, sine, step, table
from .tables import PwlTable, TableError
from .units import (
    GRAVITY,
    KMH_TO_M_S,
    RPM_TO_RAD_S,
    kmh_to_m_s,
    m_s_to_kmh,
    rad_s_to_rpm,
    rpm_to_rad_s,
)
from .validate import ParameterError, is_finite_real, is_real, real_number, reject_unknown

__all__ = [
    "GRAVITY",
    "RPM_TO_RAD_S",
    "KMH_TO_M_S",
    "rpm_to_rad_s",
    "rad_s_to_rpm",
    "kmh_to_m_s",
    "m_s_to_kmh",
    "PwlTable",
    "TableError",
    "ParameterError",
    "json_ready",
    "round_sig",
    "builtin_files",
    "load_builtin_or_toml",
    "load_toml_as",
    "read_toml",
    "is_real",
    "is_finite_real",
    "real_number",
    "reject_unknown",
    "Signal",
    "constant",
    "step",
    "ramp",
    "table",
    "sine",
]
