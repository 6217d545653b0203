"""Manoeuvres as data: initial state, input signals, reference, horizon (built-ins and TOML files)."""

from __future__ import annotations

from .scenario import Scenario, ScenarioError, builtin_scenarios, idle_throttle, load_scenario

__all__ = [
    "Scenario",
    "ScenarioError",
    "builtin_scenarios",
    "load_scenario",
    "idle_throttle",
]
